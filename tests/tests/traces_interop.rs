//! The Python `mcap` package (no interpd code) reads a trace we wrote:
//! message counts per topic, every message valid against its JSON Schema,
//! and selected setpoints equal field for field (`scripts/mcap_interop.py`).
//!
//! Needs a Python with `mcap` and `jsonschema`: `$INTERPD_PYTHON`, or the
//! virtualenv `.ci/run` makes in `out/venv`. Without one the test prints a
//! note and passes (a fresh clone has none).

use std::path::{Path, PathBuf};
use std::process::Command;

use interpd_tests::{golden_config, golden_programs, record};
use serde_json::json;
use traces::Trace;
use traces::writer::TraceCompression;

fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("workspace root")
        .to_path_buf()
}

fn python() -> Option<PathBuf> {
    let candidates = std::env::var_os("INTERPD_PYTHON")
        .map(PathBuf::from)
        .into_iter()
        .chain([workspace().join("out/venv/bin/python")]);
    for p in candidates {
        let ok = Command::new(&p)
            .args(["-c", "import mcap, jsonschema"])
            .output()
            .is_ok_and(|o| o.status.success());
        if ok {
            return Some(p);
        }
    }
    None
}

#[test]
fn python_mcap_reads_our_traces() {
    let Some(py) = python() else {
        eprintln!(
            "note: skipping the MCAP interop test: no Python with `mcap` and `jsonschema` \
             (set INTERPD_PYTHON or run .ci/run, which makes out/venv)"
        );
        return;
    };
    let dir = std::env::temp_dir().join(format!("interpd-interop-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    for (name, program) in golden_programs() {
        for compression in [
            TraceCompression::Zstd,
            TraceCompression::Lz4,
            TraceCompression::None,
        ] {
            let bytes = record(&golden_config(&program, &name), &program, compression);
            let trace = Trace::from_bytes(&bytes).expect("reads");
            let path = dir.join(format!("{name}-{compression:?}.mcap"));
            std::fs::write(&path, &bytes).expect("trace written");
            let n = trace.setpoints.len();
            let picks: Vec<_> = [0, 1, n / 3, n / 2, n - 2, n - 1]
                .iter()
                .map(|&k| serde_json::to_value(trace.setpoints[k]).expect("json"))
                .collect();
            let expected = json!({
                "counts": {
                    "/interpd/config": 1,
                    "/interpd/blocks": trace.blocks.len(),
                    "/interpd/setpoints": n,
                    "/interpd/loop_timing": trace.loop_timing.len(),
                    "/interpd/events": trace.events.len(),
                },
                "setpoints": picks,
            });
            let exp_path = dir.join(format!("{name}-{compression:?}.json"));
            std::fs::write(&exp_path, expected.to_string()).expect("expectations written");
            let out = Command::new(&py)
                .arg(workspace().join("scripts/mcap_interop.py"))
                .arg(&path)
                .arg(&exp_path)
                .output()
                .expect("python runs");
            let text = String::from_utf8_lossy(&out.stdout);
            assert!(
                out.status.success(),
                "{name} {compression:?}: {}{}",
                text,
                String::from_utf8_lossy(&out.stderr)
            );
            assert!(text.contains("/interpd/setpoints: "), "{text}");
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}
