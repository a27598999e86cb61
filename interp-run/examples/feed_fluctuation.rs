//! Feed fluctuation of the three parameter-update modes (seed 004, §2.2).
//!
//! Runs the LinuxCNC butterfly (`interp_core::samples::butterfly`) at
//! F = 6000 mm/min (100 mm/s), Ts = 1 ms, ER = 1 µm, once for each of
//! `ParamUpdate::{FirstOrder, SecondOrder, Corrected}`, and reports per mode
//! the feed fluctuation of every tick,
//!
//! ```text
//! f_i = |p_i − p_{i−1}| / Δ_i − 1,     Δ_i = feed_i · Ts
//! ```
//!
//! (`interp_core::metrics::feed_fluctuation`): the chord actually travelled
//! against the displacement the schedule commanded. Ticks with feed 0 are
//! skipped. Printed: max |f|, max |f| without the last moving tick (the one
//! that lands on the program's end point), RMS f, the signed extremes and the
//! tick of the worst one, the number of ticks and the interpolator's
//! `stats()`. The target for `Corrected` is max |f| ≤ 1e-6.
//!
//! ```text
//! cargo run --release -p interp-run --example feed_fluctuation
//! cargo run --release -p interp-run --example feed_fluctuation -- --csv
//! cargo run --release -p interp-run --example feed_fluctuation -- --cubic
//! ```
//!
//! `--csv` prints the same table as CSV; `--cubic` uses the benches' 3-D
//! rational cubic instead of the butterfly.

#[path = "../benches/common/mod.rs"]
mod common;

use common::{MODES, butterfly_blocks, cubic_blocks, loaded, mode_name};
use interp_core::metrics::feed_fluctuation;
use interp_core::{InterpConfig, RunState, Vec3};

/// F6000 mm/min.
const FEED: f64 = 100.0;

struct Row {
    mode: &'static str,
    ticks: u64,
    moving: u64,
    max_abs: f64,
    /// max |f| without the last moving tick (the one that lands on the program end).
    max_abs_inner: f64,
    rms: f64,
    min: f64,
    max: f64,
    worst_seq: u64,
    stats: interp_core::interp::Stats,
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let csv = args.iter().any(|a| a == "--csv");
    let cubic = args.iter().any(|a| a == "--cubic");
    let (curve, blocks) = if cubic {
        ("rational-cubic", cubic_blocks(FEED))
    } else {
        ("butterfly", butterfly_blocks(FEED))
    };
    let mut rows = Vec::new();
    for mode in MODES {
        let cfg = InterpConfig {
            chord_tolerance: 0.001,
            period: 0.001,
            param_update: mode,
            ..Default::default()
        };
        let mut ip = loaded(cfg, &blocks);
        let start = common::start_of(&blocks);
        let mut prev = Vec3::new(start[0], start[1], start[2]);
        let (mut ticks, mut moving) = (0u64, 0u64);
        let (mut sum2, mut max_abs, mut min, mut max) =
            (0.0, 0.0f64, f64::INFINITY, -f64::INFINITY);
        let mut worst_seq = 0;
        let mut max_abs_inner: f64 = 0.0;
        let mut last_f: Option<f64> = None;
        loop {
            let sp = ip.tick();
            ticks += 1;
            let p = Vec3::new(sp.axes[0], sp.axes[1], sp.axes[2]);
            if sp.feed > 0.0 {
                let f = feed_fluctuation(prev, p, sp.feed * cfg.period);
                moving += 1;
                sum2 += f * f;
                min = min.min(f);
                max = max.max(f);
                if let Some(g) = last_f.replace(f) {
                    max_abs_inner = max_abs_inner.max(g.abs());
                }
                if f.abs() > max_abs {
                    max_abs = f.abs();
                    worst_seq = sp.seq;
                }
            }
            prev = p;
            if sp.state == RunState::Done {
                break;
            }
            assert!(ticks < 10_000_000, "run does not end");
        }
        rows.push(Row {
            mode: mode_name(mode),
            ticks,
            moving,
            max_abs,
            max_abs_inner,
            rms: (sum2 / moving.max(1) as f64).sqrt(),
            min,
            max,
            worst_seq,
            stats: ip.stats(),
        });
    }
    if csv {
        println!(
            "curve,mode,ticks,moving_ticks,max_abs_fluct,max_abs_fluct_before_last,rms_fluct,min_fluct,max_fluct,worst_seq,\
             segments_done,newton_unconverged,max_newton_iters"
        );
        for r in &rows {
            println!(
                "{curve},{},{},{},{:e},{:e},{:e},{:e},{:e},{},{},{},{}",
                r.mode,
                r.ticks,
                r.moving,
                r.max_abs,
                r.max_abs_inner,
                r.rms,
                r.min,
                r.max,
                r.worst_seq,
                r.stats.segments_done,
                r.stats.newton_unconverged,
                r.stats.max_newton_iters
            );
        }
        return;
    }
    println!(
        "feed fluctuation |chord|/(feed·Ts) − 1 — {curve}, F = {FEED} mm/s, Ts = 1 ms, ER = 1 µm"
    );
    println!(
        "{:<13} {:>7} {:>7} {:>10} {:>10} {:>10} {:>11} {:>11} {:>7}  stats (segments_done, newton_unconverged, max_newton_iters)",
        "mode", "ticks", "moving", "max|f|", "w/o last", "rms f", "min f", "max f", "at seq"
    );
    for r in &rows {
        println!(
            "{:<13} {:>7} {:>7} {:>10.3e} {:>10.3e} {:>10.3e} {:>11.3e} {:>11.3e} {:>7}  ({}, {}, {})",
            r.mode,
            r.ticks,
            r.moving,
            r.max_abs,
            r.max_abs_inner,
            r.rms,
            r.min,
            r.max,
            r.worst_seq,
            r.stats.segments_done,
            r.stats.newton_unconverged,
            r.stats.max_newton_iters
        );
    }
    if let Some(c) = rows.iter().find(|r| r.mode == "corrected") {
        let ok = c.max_abs <= 1e-6;
        println!(
            "corrected: max |f| = {:.3e} — target ≤ 1e-6 {}",
            c.max_abs,
            if ok { "met" } else { "MISSED" }
        );
    }
}
