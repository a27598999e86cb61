//! Programs and helpers shared by the loop's benches and examples
//! (`benches/tick.rs`, `benches/tick_latency.rs`, `examples/feed_fluctuation.rs`,
//! `examples/seed_figures.rs`, which include this file with `#[path]`).
//!
//! Everything here is deterministic: no random numbers, no clock, so two runs
//! on any machine drive the interpolator through exactly the same ticks.
#![allow(dead_code)]

use core::hint::black_box;
use core::time::Duration;
use std::time::Instant;

use interp_core::nurbs::{MAX_CTRL, MAX_DEGREE};
use interp_core::samples::butterfly;
use interp_core::{Block, InterpConfig, ParamUpdate, Path, RunState};
use interp_run::Replay;

pub use interp_core::samples::rational_cubic::rational_cubic;

/// The rational cubic as one block (id 1) at `feed` mm/s.
pub fn cubic_blocks(feed: f64) -> Vec<Block> {
    vec![Block::new(1, Path::Nurbs(rational_cubic()), feed)]
}

/// Largest segment handed to the interpolator when a program curve is split.
pub const SPLIT_MAX_CTRL: usize = MAX_CTRL - MAX_DEGREE - 1;

/// The LinuxCNC butterfly as consecutive NURBS blocks (ids from 1) at `feed` mm/s.
pub fn butterfly_blocks(feed: f64) -> Vec<Block> {
    let mut out = Vec::new();
    butterfly::for_each_block::<core::convert::Infallible>(feed, 1, SPLIT_MAX_CTRL, |b| {
        out.push(b);
        Ok(())
    })
    .expect("butterfly splits");
    out
}

/// Start position (X Y Z A B C) of a program.
pub fn start_of(blocks: &[Block]) -> [f64; 6] {
    use interp_core::Curve;
    let p = blocks[0].path.start_point();
    [p.x, p.y, p.z, 0.0, 0.0, 0.0]
}

/// The default configuration with `param_update` set.
pub fn config_with(update: ParamUpdate) -> InterpConfig {
    InterpConfig {
        param_update: update,
        ..InterpConfig::default()
    }
}

/// `blocks` planned to the end (`interp_run::plan`), ready to tick from the
/// start as the service's RT thread ticks: each plan committed at the tick
/// it was made for, so `tick` costs what the RT thread's tick costs, with no
/// planning in it (the commits, microseconds, are in the ticks they precede).
pub fn loaded(cfg: InterpConfig, blocks: &[Block]) -> Box<Replay> {
    Box::new(interp_run::plan(cfg, start_of(blocks), blocks, 50_000_000).expect("program plans"))
}

/// Back to the start of the program `ip` was loaded with (`cfg` and
/// `blocks` must be the ones it was loaded with).
pub fn reload(ip: &mut Replay, cfg: InterpConfig, blocks: &[Block]) {
    assert!(
        cfg == *ip.config() && start_of(blocks) == ip.start(),
        "reload of another program"
    );
    ip.rewind();
}

/// Runs `ip` to the end and returns how many ticks that took.
pub fn run_to_end(ip: &mut Replay) -> u64 {
    let mut n = 0;
    loop {
        n += 1;
        if ip.tick().state == RunState::Done {
            return n;
        }
        assert!(n < 50_000_000, "run does not end");
    }
}

/// Time of `iters` ticks of `ip` (criterion's `iter_custom`), restarting
/// it with `restart` whenever it reaches the end; the restarts are not
/// timed.
pub fn time_ticks(iters: u64, ip: &mut Replay, mut restart: impl FnMut(&mut Replay)) -> Duration {
    let mut total = Duration::ZERO;
    let mut left = iters;
    while left > 0 {
        let t0 = Instant::now();
        let mut done = false;
        while left > 0 {
            left -= 1;
            if black_box(ip.tick()).state == RunState::Done {
                done = true;
                break;
            }
        }
        total += t0.elapsed();
        if done {
            restart(ip);
        }
    }
    total
}

/// Short human name of an update mode.
pub fn mode_name(m: ParamUpdate) -> &'static str {
    match m {
        ParamUpdate::FirstOrder => "first-order",
        ParamUpdate::SecondOrder => "second-order",
        ParamUpdate::Corrected => "corrected",
    }
}

/// All three update modes, in the order the seed presents them.
pub const MODES: [ParamUpdate; 3] = [
    ParamUpdate::FirstOrder,
    ParamUpdate::SecondOrder,
    ParamUpdate::Corrected,
];
