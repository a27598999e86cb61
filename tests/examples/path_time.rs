//! Path time of G-code programs against the acceleration-only optimum
//! (issue 9), with the default configuration.
//!
//! ```text
//! cargo run --release -p interpd-tests --example path_time -- [--feed MM_PER_MIN] FILE.ngc...
//! cargo run --release -p interpd-tests --example path_time            # the corpus set below
//! ```
//!
//! With no file it runs the butterfly and three other curves of
//! `../shared/corpus/nurbs-linuxcnc/g6` (skipped with a note when the corpus
//! is absent; the butterfly is also in `gcode/tests/programs`). `--feed`
//! replaces every programmed feed (rapids stay at the machine's top speed).
//! Prints two lines per program, times in s and the ratios to the optimum:
//! `curve`, the program's first NURBS curve (its contiguous run of NURBS
//! blocks, from rest to rest), and `program`, every motion block including
//! the rapids and lead-ins.
//!
//! Every program runs as the drivers run it: through the `G64 P` stage
//! (`interp_core::smooth`), so `G64 P` programs are smoothed; `--g64 P`
//! sets `G64 P` on every move (as a `G64 P` line after the header would),
//! `--policy auto|blend|compress` picks the stage's corner policy (the
//! choice is measured in `docs/interp-core.md`). The last two columns are
//! the largest distance of a setpoint, and of a chord between consecutive
//! setpoints, from the programmed path (µm), and the optimum is that of the
//! smoothed path.
//!
//! ```text
//! cargo run --release -p interpd-tests --example path_time -- --feed 6000 --g64 0.001 RASTER.ngc
//! ```
//!
//! `--rotate DEG[,X,Y,Z]` runs each program as the same part turned on the
//! table by `DEG` degrees about the axis `(X, Y, Z)` through the origin
//! (about Z without an axis): the same path, its laws on other axes.
//!
//! `--set KEY=VALUE` (any number; keys of `[interp]` in the service's
//! configuration, values in TOML) measures another machine than the
//! defaults: `--set max-path-jerk=1e7 --set axis-max-jerk=[2e7,2e7,2e7]`.
//!
//! `--no-deviation` skips the two deviation columns (printed NaN): on NURBS
//! curves at production feed the reference search takes minutes per program.
//!
//! Then come the lower bound of any jerk-limited schedule
//! (`path_time::jerk_aware_bound`: the optimum with the jerk-limited ramps at
//! rests and slow points and the curvature steps' caps) and our time over it,
//! and the setpoints' check: the largest path or axis jerk as a share of its
//! limit, and how many checks of every limit on every tick failed (0 when
//! all held). `retries / crawls`: the look-ahead's solves that failed and
//! were tried again with other rows (`PlanTotals::warm_failed` plus
//! `kept_rows`), and those that fell back to a rest point or to the crawl
//! (`fell_back` plus `crawled`; a crawl rests at every knot of its stretch).
//! `--bound-parts` adds two columns: the bound without the curvature
//! steps' caps, and with the ramps at rests and slow points alone (no
//! jerk-down before top speeds either), to see what each part costs.

use std::path::{Path, PathBuf};

use interp_core::smooth::Policy;
use interpd_tests::cli::{take_config, take_rotation, take_value};
use interpd_tests::path_time::{
    BoundTerms, first_curve, jerk_aware_bound_with, load_turned, program_run, smoothed,
};

const CORPUS: &str = "../shared/corpus/nurbs-linuxcnc/g6";
const DEFAULT_SET: [&str; 4] = [
    "curva_farfalla-q1.ngc",
    "curva_stella-q1.ngc",
    "curva_delfino-q1.ngc",
    "homer-q1.ngc",
];

fn main() {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let deviation = match args.iter().position(|a| a == "--no-deviation") {
        Some(i) => {
            args.remove(i);
            false
        }
        None => true,
    };
    let parts = match args.iter().position(|a| a == "--bound-parts") {
        Some(i) => {
            args.remove(i);
            true
        }
        None => false,
    };
    let rotation = take_rotation(&mut args, "--rotate");
    let cfg = take_config(&mut args);
    let mut flag = |name: &str| take_value(&mut args, name);
    let feed = flag("--feed").and_then(|v| v.parse::<f64>().ok());
    let g64 = flag("--g64").and_then(|v| v.parse::<f64>().ok());
    let policy = match flag("--policy").as_deref() {
        None | Some("auto") => Policy::Auto,
        Some("blend") => Policy::BlendOnly,
        Some("compress") => Policy::CompressOnly,
        Some(other) => {
            eprintln!("--policy {other}: auto, blend or compress");
            std::process::exit(2);
        }
    };
    // Run from the workspace root or from tests/.
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let files: Vec<PathBuf> = if args.is_empty() {
        let dir = root.join(CORPUS);
        if !dir.is_dir() {
            eprintln!("note: {} not found; pass files explicitly", dir.display());
            return;
        }
        DEFAULT_SET.iter().map(|f| dir.join(f)).collect()
    } else {
        args.iter().map(PathBuf::from).collect()
    };
    println!(
        "program | part | blocks in | out | length mm | ours s | trapezoid s | optimum s | ours/opt | trap/opt | setpoint dev um | chord dev um | bound s | ours/bound | jerk use | failed checks | retries / crawls{}",
        if parts {
            " | bound w/o steps s | bound rests s"
        } else {
            ""
        }
    );
    for f in files {
        let blocks = match load_turned(&f, feed, g64, rotation.as_ref()) {
            Ok(b) => b,
            Err(e) => {
                eprintln!("{e}");
                std::process::exit(1);
            }
        };
        let curve = first_curve(&blocks);
        let name = f.file_name().unwrap().to_string_lossy().to_string();
        for (part, set) in [("curve", &curve), ("program", &blocks)] {
            if set.is_empty() {
                continue;
            }
            let length: f64 = set.iter().map(|b| b.path.length()).sum();
            match program_run(set, &cfg, policy, deviation) {
                Ok(r) => {
                    let t = r.times;
                    let v = r.violations;
                    if v.total() > 0 {
                        eprintln!(
                            "{name} {part}: {} (first at seq {:?})",
                            v.breakdown(),
                            v.first_seq
                        );
                    }
                    let extra = if parts {
                        let out = smoothed(set, &cfg, policy).0;
                        let without = |tops| {
                            let terms = BoundTerms { tops, steps: false };
                            jerk_aware_bound_with(&out, &cfg, terms)
                        };
                        format!(" | {:.3} | {:.3}", without(true), without(false))
                    } else {
                        String::new()
                    };
                    println!(
                        "{name} | {part} | {} | {} | {:.1} | {:.3} | {:.3} | {:.3} | {:.4} | {:.4} | {:.3} | {:.3} | {:.3} | {:.4} | {:.3} | {} | {} / {}{extra}",
                        r.blocks_in,
                        r.blocks_out,
                        length,
                        t.ours,
                        t.trapezoid,
                        t.optimum,
                        t.ours / t.optimum,
                        t.trapezoid / t.optimum,
                        r.max_point_deviation * 1e3,
                        r.max_chord_deviation * 1e3,
                        t.bound,
                        t.ours / t.bound,
                        r.jerk_use,
                        r.violations.total(),
                        r.plan.retries(),
                        r.plan.added_stops(),
                    )
                }
                Err(e) => {
                    eprintln!("{}: {e}", f.display());
                    std::process::exit(1);
                }
            }
        }
    }
}
