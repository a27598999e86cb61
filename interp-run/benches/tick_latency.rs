//! Per-tick latency distribution of `Executor::tick()` (the plans made
//! beforehand and committed at their ticks, as on the RT thread).
//!
//! Times every single tick (`Instant` before and after) over at least
//! 1,000,000 ticks per case and prints p50, p90, p99, p99.9 and max in ns, for
//! the benches' 3-D rational cubic and the LinuxCNC butterfly at 100 mm/s with
//! the default configuration, for each `ParamUpdate` mode. When a run reaches
//! `Done` the program is queued again; that (planning, non-RT) happens
//! outside the timed region. One whole run per case is done first as warm-up.
//!
//! The first line gives the cost of the timing itself (two `Instant::now()`
//! with nothing between): every figure includes it once.
//!
//! ```text
//! cargo bench -p interp-run --bench tick_latency            # 1,000,000 ticks per case
//! cargo bench -p interp-run --bench tick_latency -- --ticks 5000000 --csv
//! cargo bench -p interp-run --bench tick_latency -- --ticks 20000 --sleep-us 1000
//! ```
//!
//! `--sleep-us N` sleeps N µs before every tick, as the fixed-period loop
//! does: the tick then runs on caches the sleep let go cold (and, in a VM,
//! after the host ran something else on the core), which is the cost the
//! service sees, not the back-to-back cost.
//!
//! Without `--bench` on the command line (`cargo test --all-targets` runs this
//! binary that way) it only does a quick 10,000-tick smoke run per case.

#[path = "common/mod.rs"]
mod common;

use core::hint::black_box;
use std::time::{Duration, Instant};

use common::{MODES, butterfly_blocks, config_with, cubic_blocks, loaded, mode_name, reload};
use interp_core::{Block, RunState};

const FULL_TICKS: usize = 1_000_000;
const QUICK_TICKS: usize = 10_000;

struct Dist {
    mean: f64,
    p50: u64,
    p90: u64,
    p99: u64,
    p999: u64,
    max: u64,
}

/// Nearest-rank percentiles of `ns` (sorted in place).
fn dist(ns: &mut [u64]) -> Dist {
    ns.sort_unstable();
    let n = ns.len();
    let q = |p: f64| ns[((p * n as f64).ceil() as usize).clamp(1, n) - 1];
    Dist {
        mean: ns.iter().sum::<u64>() as f64 / n as f64,
        p50: q(0.50),
        p90: q(0.90),
        p99: q(0.99),
        p999: q(0.999),
        max: ns[n - 1],
    }
}

/// Latency of `n` ticks on `blocks` with `mode`, ns each.
fn measure(
    blocks: &[Block],
    mode: interp_core::ParamUpdate,
    n: usize,
    sleep: Option<Duration>,
) -> (Vec<u64>, u64) {
    let cfg = config_with(mode);
    let mut ip = loaded(cfg, blocks);
    common::run_to_end(&mut ip); // warm-up
    reload(&mut ip, cfg, blocks);
    let mut ns = Vec::with_capacity(n);
    let mut reloads = 0;
    while ns.len() < n {
        if let Some(d) = sleep {
            std::thread::sleep(d);
        }
        let t0 = Instant::now();
        let sp = ip.tick();
        let dt = t0.elapsed();
        ns.push(dt.as_nanos() as u64);
        if black_box(sp).state == RunState::Done {
            reload(&mut ip, cfg, blocks);
            reloads += 1;
        }
    }
    (ns, reloads)
}

fn main() {
    interp_run::stack::on_interpolator_stack(run);
}

fn run() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let full = args.iter().any(|a| a == "--bench");
    let csv = args.iter().any(|a| a == "--csv");
    let ticks = args
        .iter()
        .position(|a| a == "--ticks")
        .and_then(|i| args.get(i + 1))
        .and_then(|v| v.parse().ok())
        .unwrap_or(if full { FULL_TICKS } else { QUICK_TICKS });
    let sleep = args
        .iter()
        .position(|a| a == "--sleep-us")
        .and_then(|i| args.get(i + 1))
        .and_then(|v| v.parse().ok())
        .map(Duration::from_micros);

    // Cost of the measurement itself.
    let mut empty = Vec::with_capacity(ticks);
    for _ in 0..ticks {
        let t0 = Instant::now();
        empty.push(black_box(t0.elapsed()).as_nanos() as u64);
    }
    let e = dist(&mut empty);

    if csv {
        println!("curve,mode,ticks,runs,mean_ns,p50_ns,p90_ns,p99_ns,p99_9_ns,max_ns");
        println!(
            "timer-only,-,{ticks},-,{:.1},{},{},{},{},{}",
            e.mean, e.p50, e.p90, e.p99, e.p999, e.max
        );
    } else {
        if !full {
            println!("(quick run: {ticks} ticks per case; `cargo bench` runs {FULL_TICKS})");
        }
        if let Some(d) = sleep {
            println!("(sleeping {} µs before every tick)", d.as_micros());
        }
        println!(
            "{:<15} {:<13} {:>9} {:>6} {:>8} {:>7} {:>7} {:>7} {:>8} {:>9}",
            "curve", "mode", "ticks", "runs", "mean ns", "p50", "p90", "p99", "p99.9", "max"
        );
        println!(
            "{:<15} {:<13} {:>9} {:>6} {:>8.1} {:>7} {:>7} {:>7} {:>8} {:>9}",
            "timer-only", "-", ticks, "-", e.mean, e.p50, e.p90, e.p99, e.p999, e.max
        );
    }
    let curves: [(&str, Vec<Block>); 2] = [
        ("rational-cubic", cubic_blocks(100.0)),
        ("butterfly", butterfly_blocks(100.0)),
    ];
    for (name, blocks) in &curves {
        for mode in MODES {
            let (mut ns, reloads) = measure(blocks, mode, ticks, sleep);
            let d = dist(&mut ns);
            if csv {
                println!(
                    "{name},{},{ticks},{},{:.1},{},{},{},{},{}",
                    mode_name(mode),
                    reloads,
                    d.mean,
                    d.p50,
                    d.p90,
                    d.p99,
                    d.p999,
                    d.max
                );
            } else {
                println!(
                    "{:<15} {:<13} {:>9} {:>6} {:>8.1} {:>7} {:>7} {:>7} {:>8} {:>9}",
                    name,
                    mode_name(mode),
                    ticks,
                    reloads,
                    d.mean,
                    d.p50,
                    d.p90,
                    d.p99,
                    d.p999,
                    d.max
                );
            }
        }
    }
}
