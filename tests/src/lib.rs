//! Workspace-level tests of interpd's traces.
//!
//! The tests live in `tests/tests/` (golden traces, MCAP interop, path
//! time) and run with `cargo test --workspace`; the end-to-end tests of the
//! service and its commands live with the `interpd` package
//! (`daemon/tests/`), which builds the binary for them. This library holds
//! the helpers the tests here share.

pub mod cli;
pub mod five_axis;
pub mod path_time;
pub mod polyline;
#[cfg(feature = "scp")]
pub mod scp;

use std::io::Cursor;
use std::path::{Path, PathBuf};

use traces::Program;
use traces::messages::ConfigMsg;
use traces::sim::{self, SimSettings};
use traces::writer::{TraceCompression, TraceWriter};

/// Environment variable that makes golden tests rewrite their files.
pub const BLESS_ENV: &str = "INTERPD_BLESS";

/// What golden traces say wrote them.
pub const GOLDEN_WRITER: &str = "interpd-tests golden";

/// `tests/golden/`.
pub fn golden_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("golden")
}

/// Whether golden files are to be rewritten (`INTERPD_BLESS=1`).
pub fn blessing() -> bool {
    std::env::var(BLESS_ENV).is_ok_and(|v| v == "1")
}

/// The golden programs: `(name, program)` for every `tests/golden/*.json`, by name.
pub fn golden_programs() -> Vec<(String, Program)> {
    let mut out = Vec::new();
    let dir = golden_dir();
    let entries = std::fs::read_dir(&dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
    for e in entries {
        let path = e.expect("directory entry").path();
        if path.extension().is_some_and(|x| x == "json") {
            let text = std::fs::read_to_string(&path).expect("golden program readable");
            let p: Program =
                serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            let name = path
                .file_stem()
                .expect("stem")
                .to_string_lossy()
                .into_owned();
            out.push((name, p));
        }
    }
    out.sort_by(|a, b| a.0.cmp(&b.0));
    out
}

/// Control points per segment of the golden traces: they were recorded
/// when `simulate` split NURBS at 20 (its default now is `MAX_CTRL`, as
/// `serve` splits them); kept so that they stay as blessed.
pub const GOLDEN_MAX_CTRL: usize = 20;

/// The config every golden trace is recorded with: all defaults but
/// [`GOLDEN_MAX_CTRL`].
pub fn golden_config(program: &Program, name: &str) -> ConfigMsg {
    sim::config_for(
        program,
        interp_core::InterpConfig::default(),
        &SimSettings {
            max_ctrl_per_block: GOLDEN_MAX_CTRL,
            ..SimSettings::default()
        },
        GOLDEN_WRITER,
        &format!("tests/golden/{name}.json"),
    )
}

/// Simulates `program` under `config` into an in-memory trace.
pub fn record(config: &ConfigMsg, program: &Program, compression: TraceCompression) -> Vec<u8> {
    let mut w = TraceWriter::new(Cursor::new(Vec::new()), compression).expect("trace starts");
    sim::record(
        config,
        program,
        SimSettings::default().max_machine_time,
        &mut w,
        |_| {},
    )
    .expect("program simulates");
    w.finish().expect("trace finishes").0.into_inner()
}

/// Rewrites every golden trace from its program, once per test process, when
/// [`blessing`]; every test reads golden traces through [`golden_trace`], so
/// none reads a half-written file.
fn bless_once() {
    static BLESSED: std::sync::Once = std::sync::Once::new();
    BLESSED.call_once(|| {
        if !blessing() {
            return;
        }
        for (name, program) in golden_programs() {
            let path = golden_dir().join(format!("{name}.mcap"));
            let bytes = record(
                &golden_config(&program, &name),
                &program,
                TraceCompression::Zstd,
            );
            std::fs::write(&path, bytes).expect("golden trace written");
            eprintln!("blessed {}", path.display());
        }
    });
}

/// The bytes of `tests/golden/NAME.mcap` (rewritten first under `INTERPD_BLESS=1`).
pub fn golden_trace(name: &str) -> Vec<u8> {
    bless_once();
    let path = golden_dir().join(format!("{name}.mcap"));
    std::fs::read(&path)
        .unwrap_or_else(|e| panic!("{}: {e} (bless with {BLESS_ENV}=1)", path.display()))
}
