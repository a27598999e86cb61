//! Shared by the tests that run G-code through the interpolator.
// Each test binary uses a part of this.
#![allow(dead_code)]

use gcode::{CoreOptions, parse};
use interp_core::path::Block;
use interp_core::{Curve, InterpConfig, Interpolator, RunState, Setpoint, Vec3};

pub fn v3(p: &[f64; 6]) -> Vec3 {
    Vec3::new(p[0], p[1], p[2])
}

pub fn blocks(text: &str) -> Vec<Block> {
    parse(text)
        .unwrap()
        .to_core_blocks(&CoreOptions::default())
        .unwrap_or_else(|e| panic!("conversion refused: {e}"))
}

/// Runs `blocks` to the end as a client would (push while there is room),
/// checking every setpoint is finite and on its block's path.
pub fn run(blocks: &[Block]) -> Vec<Setpoint> {
    let cfg = InterpConfig::default();
    let s = blocks[0].path.start_point();
    let mut ip: Box<Interpolator> =
        Box::new(Interpolator::new(cfg, [s.x, s.y, s.z, 0.0, 0.0, 0.0]).unwrap());
    // Generous bound: the whole path at 1/100 of the slowest programmed feed.
    let total: f64 = blocks.iter().map(|b| b.path.length()).sum();
    let slowest = blocks.iter().map(|b| b.feed).fold(f64::INFINITY, f64::min);
    let limit = (total / (0.01 * slowest) / cfg.period) as usize + 10_000;
    let mut next = 0;
    let mut out = Vec::new();
    loop {
        while next < blocks.len() {
            match ip.push(&blocks[next]) {
                Ok(()) => next += 1,
                Err(e) if e.is_wait() => break,
                Err(e) => panic!("block {next}: {e:?}"),
            }
        }
        if next == blocks.len() {
            ip.finish();
        }
        let sp = ip.tick();
        // A long curve is several blocks with one id (its line): the one whose
        // parameters hold u.
        let b = blocks
            .iter()
            .find(|b| b.id == sp.block_id && b.path.u_start() <= sp.u && sp.u <= b.path.u_end())
            .unwrap();
        let off = (b.path.eval(sp.u, 0).p - v3(&sp.axes)).norm();
        assert!(
            sp.axes.iter().all(|a| a.is_finite()) && off <= 1e-9,
            "seq {}: {sp:?} ({off} off its path)",
            sp.seq
        );
        out.push(sp);
        if sp.state == RunState::Done {
            return out;
        }
        assert!(out.len() < limit, "not done after {limit} ticks: {sp:?}");
    }
}
