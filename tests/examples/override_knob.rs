//! The feed override turned mid-run, as an operator turns the knob: every
//! `--every` ms (default 113) the override steps through a fixed cycle of
//! 30–200 % (1.0, 0.6, 1.2, 0.8, 1.5, 0.3, 1.0, 0.9, 1.1, 0.5, 2.0, 0.7).
//!
//! ```text
//! cargo run --release -p interpd-tests --example override_knob -- [--feed MM_PER_MIN] [--g64 P] [--every MS] FILE.ngc...
//! ```
//!
//! Each program runs as the drivers run it (the `G64 P` stage, then the
//! interpolator; `--feed` and `--g64` as in the `path_time` example), every setpoint checked against every limit (the feed
//! bound at the largest override). Prints per program: the path time with
//! the knob turned and at 100 %, the turns, the look-ahead's solves, its
//! retries (solves tried again with other rows) and the stops it added (a
//! rest kept at the old end of the queue, or a crawl: a stop the program
//! does not ask for), and the checks that failed.

use std::path::PathBuf;

use interp_core::InterpConfig;
use interp_core::smooth::Policy;
use interpd_tests::path_time::{
    interpolated_run, interpolated_run_with_overrides, load_program, smoothed,
};

/// The override values the knob steps through.
const KNOB: [f64; 12] = [1.0, 0.6, 1.2, 0.8, 1.5, 0.3, 1.0, 0.9, 1.1, 0.5, 2.0, 0.7];

fn main() {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let mut flag = |name: &str| {
        let i = args.iter().position(|a| a == name)?;
        let v = args
            .get(i + 1)
            .and_then(|v| v.parse::<f64>().ok())
            .unwrap_or_else(|| panic!("{name} takes a number"));
        args.drain(i..=i + 1);
        Some(v)
    };
    let feed = flag("--feed");
    let g64 = flag("--g64");
    let every = flag("--every").unwrap_or(113.0);
    assert!(every >= 1.0, "--every is at least 1 ms");
    let cfg = InterpConfig::default();
    let every = (every * 1e-3 / cfg.period).round() as u64;
    println!("program | knob s | 100 % s | turns | solves | retries | added stops | failed checks");
    for file in &args {
        let blocks = match load_program(&PathBuf::from(file), feed, g64) {
            Ok(b) => b,
            Err(e) => {
                eprintln!("{e}");
                continue;
            }
        };
        let (blocks, _) = smoothed(&blocks, &cfg, Policy::Auto);
        let plain = match interpolated_run(&blocks, &cfg, false) {
            Ok(r) => r,
            Err(e) => {
                eprintln!("{file}: {e}");
                continue;
            }
        };
        // Turns up to twice the plain run's length (the knob's mean is
        // about 100 %).
        let n = 2 * (plain.time / cfg.period) as u64 / every + 1;
        let turns: Vec<(u64, f64)> = (1..=n)
            .map(|k| (k * every, KNOB[k as usize % KNOB.len()]))
            .collect();
        match interpolated_run_with_overrides(&blocks, &cfg, &turns) {
            Ok(run) => {
                let done = (run.time / cfg.period) as u64 / every;
                let name = PathBuf::from(file);
                let name = name
                    .file_name()
                    .map_or(file.clone(), |n| n.to_string_lossy().into());
                println!(
                    "{name} | {:.3} | {:.3} | {done} | {} | {} | {} | {}",
                    run.time,
                    plain.time,
                    run.plan.solves,
                    run.plan.retries(),
                    run.plan.added_stops(),
                    run.violations.total()
                );
            }
            Err(e) => eprintln!("{file}: {e}"),
        }
    }
}
