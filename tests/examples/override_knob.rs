//! The feed override turned mid-run, as an operator turns the knob: every
//! `--every` ms (default 113) the override steps through a fixed cycle of
//! 30–200 % (1.0, 0.6, 1.2, 0.8, 1.5, 0.3, 1.0, 0.9, 1.1, 0.5, 2.0, 0.7).
//!
//! ```text
//! cargo run --release -p interpd-tests --example override_knob -- [--feed MM_PER_MIN] [--g64 P] [--every MS] [--hold-every MS] [--resume-after MS] [--rotate DEG[,X,Y,Z]] [--set KEY=VALUE]... FILE.ngc...
//! ```
//!
//! `--every 0` leaves the knob alone; `--hold-every H` also gives a feed
//! hold every `H` ms and resumes `--resume-after` ms after it (default 60:
//! before rest, when the machine was fast).
//!
//! Each program runs as the drivers run it (the `G64 P` stage, then the
//! interpolator; `--feed`, `--g64`, `--rotate` and `--set` as in the `path_time` example), every setpoint checked against every limit (the feed
//! bound at the largest override). Prints per program: the path time with
//! the knob turned and at 100 %, the turns, the look-ahead's solves, its
//! retries (solves tried again with other rows) and the stops it added (a
//! rest kept at the old end of the queue, or a crawl: a stop the program
//! does not ask for), the checks that failed, the largest path or axis
//! jerk as a share of its limit, and the feed holds the look-ahead planned,
//! those of them braking more gently than the tangential limits allow, and
//! those it could not plan (the closed-form stop ran), the longest an
//! override, hold or resume took to plan, and the longest from one setpoint
//! to the next (pushes, commands, plans and the tick; wall time: in the
//! service it must fit in the planning thread's lead, 40 ms by default).

use std::path::PathBuf;

use interpd_tests::cli::{take_config, take_number, take_rotation};
use interpd_tests::path_time::{
    Command, OVERRIDE_KNOB, interpolated_run, interpolated_run_with_commands, load_turned_as_run,
};

fn main() {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let rotation = take_rotation(&mut args, "--rotate");
    let cfg = take_config(&mut args);
    let mut flag = |name: &str| take_number(&mut args, name);
    let feed = flag("--feed");
    let g64 = flag("--g64");
    let every = flag("--every").unwrap_or(113.0);
    let hold_every = flag("--hold-every").unwrap_or(0.0);
    let resume_after = flag("--resume-after").unwrap_or(60.0);
    assert!(
        every == 0.0 || every >= 1.0,
        "--every is 0 (no knob) or at least 1 ms"
    );
    assert!(resume_after >= 1.0, "--resume-after is at least 1 ms");
    assert!(
        hold_every == 0.0 || hold_every > resume_after,
        "--hold-every is 0 (no hold) or over --resume-after"
    );
    let ticks = |ms: f64| (ms * 1e-3 / cfg.period).round() as u64;
    let (every, hold_every, resume_after) = (ticks(every), ticks(hold_every), ticks(resume_after));
    println!(
        "program | knob s | 100 % s | turns | solves | retries | added stops | failed checks | jerk use | holds | softened | unplanned | longest command ms | longest step ms"
    );
    for file in &args {
        let blocks =
            match load_turned_as_run(&PathBuf::from(file), feed, g64, rotation.as_ref(), &cfg) {
                Ok(b) => b,
                Err(e) => {
                    eprintln!("{e}");
                    continue;
                }
            };
        let plain = match interpolated_run(&blocks, &cfg, false) {
            Ok(r) => r,
            Err(e) => {
                eprintln!("{file}: {e}");
                continue;
            }
        };
        // Commands up to four times the plain run's length (the knob's
        // mean is about 100 %; holds add their time).
        let span = 4 * (plain.time / cfg.period) as u64;
        let mut commands: Vec<(u64, Command)> = Vec::new();
        if let Some(n) = span.checked_div(every) {
            commands.extend((1..=n).map(|k| {
                (
                    k * every,
                    Command::Override(OVERRIDE_KNOB[k as usize % OVERRIDE_KNOB.len()]),
                )
            }));
        }
        if let Some(n) = span.checked_div(hold_every) {
            for k in 1..=n {
                commands.push((k * hold_every, Command::Hold));
                commands.push((k * hold_every + resume_after, Command::Resume));
            }
        }
        commands.sort_by_key(|&(at, _)| at);
        match interpolated_run_with_commands(&blocks, &cfg, &commands) {
            Ok(run) => {
                let done = ((run.time / cfg.period) as u64)
                    .checked_div(every)
                    .unwrap_or(0);
                let name = PathBuf::from(file);
                let name = name
                    .file_name()
                    .map_or(file.clone(), |n| n.to_string_lossy().into());
                let t = run.plan;
                if run.violations.total() > 0 {
                    eprintln!(
                        "{name}: {} (first at seq {:?})",
                        run.violations.breakdown(),
                        run.violations.first_seq
                    );
                }
                println!(
                    "{name} | {:.3} | {:.3} | {done} | {} | {} | {} | {} | {:.3} | {} | {} | {} | {:.1} | {:.1}",
                    run.time,
                    plain.time,
                    t.solves,
                    t.retries(),
                    t.added_stops(),
                    run.violations.total(),
                    run.jerk_use(&cfg),
                    t.holds,
                    t.holds_softened,
                    t.holds_unplanned,
                    run.longest_command_s * 1e3,
                    run.longest_step_s * 1e3,
                );
            }
            Err(e) => eprintln!("{file}: {e}"),
        }
    }
}
