//! An abort at every stage of a program: the program runs to its end (as
//! the drivers run it: the `G64 P` stage, then the interpolator), and
//! before every `--every`-th tick (default 7) a copy of the run is aborted
//! and braked to idle, every setpoint checked against every limit
//! (`--rotate` turns the part on the table first, and `--set KEY=VALUE`
//! runs another machine, as in `path_time`).
//!
//! ```text
//! cargo run --release -p interpd-tests --example abort_scan -- [--feed MM_PER_MIN] [--every TICKS] [--rotate DEG[,X,Y,Z]] [--set KEY=VALUE]... FILE.ngc...
//! ```
//!
//! Prints per program: the aborts tried, those with a failed check, the
//! largest path or axis jerk over all the stops as a share of its limit
//! (and the tick of the abort it came with), the longest stop in ticks, and
//! the longest an abort took to plan (wall time: in the service it must fit
//! in the planning thread's lead, 40 ms by default).

use std::path::PathBuf;

use interpd_tests::cli::{take_config, take_number, take_rotation};
use interpd_tests::path_time::{abort_scan, every, jerk_use, load_turned_as_run};

fn main() {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let rotation = take_rotation(&mut args, "--rotate");
    let cfg = take_config(&mut args);
    let mut flag = |name: &str| take_number(&mut args, name);
    let feed = flag("--feed");
    let n = flag("--every").unwrap_or(7.0);
    assert!(
        n >= 1.0 && n.fract() == 0.0,
        "--every: a whole number of ticks, at least 1"
    );
    let n = n as u64;
    println!(
        "program | aborts | failed | jerk use | at tick | longest stop (ticks) | longest plan ms"
    );
    for file in &args {
        let blocks =
            match load_turned_as_run(&PathBuf::from(file), feed, None, rotation.as_ref(), &cfg) {
                Ok(b) => b,
                Err(e) => {
                    eprintln!("{e}");
                    continue;
                }
            };
        match abort_scan(&blocks, &cfg, every(n)) {
            Ok(tried) => {
                let worst = tried
                    .iter()
                    .map(|a| (jerk_use(&a.measured, &cfg), a.at))
                    .fold((0.0, 0), |m, x| if x.0 > m.0 { x } else { m });
                let name = PathBuf::from(file);
                let name = name
                    .file_name()
                    .map_or(file.clone(), |n| n.to_string_lossy().into());
                println!(
                    "{name} | {} | {} | {:.3} | {} | {} | {:.1}",
                    tried.len(),
                    tried.iter().filter(|a| a.violations.total() > 0).count(),
                    worst.0,
                    worst.1,
                    tried.iter().map(|a| a.ticks).max().unwrap_or(0),
                    tried.iter().map(|a| a.planning_s).fold(0.0, f64::max) * 1e3
                );
            }
            Err(e) => eprintln!("{file}: {e}"),
        }
    }
}
