//! Planning cost (non-RT work in `push` and `finish`): per segment, per
//! second of planned motion, and the worst case of one block arriving while
//! 1,000 are queued.
//!
//! ```text
//! cargo bench -p interp-core --bench plan
//! ```
//!
//! Besides criterion's figures it prints the derived per-segment and
//! per-second-of-motion costs and the slowest single `push` with 1,000
//! blocks queued (max over 200 trials).

#[path = "common/mod.rs"]
mod common;

use core::hint::black_box;
use std::time::Instant;

use common::butterfly_blocks;
use criterion::{Criterion, criterion_group, criterion_main};
use interp_core::geom::{Curve, Vec3};
use interp_core::path::{Block, Line, Path};
use interp_core::{InterpConfig, Interpolator, PlannedBlock, RunState};

/// 1,001 short lines zig-zagging by 2° (a CAM polyline), 0.5 mm each.
fn polyline(n: usize) -> Vec<Block> {
    let mut p = Vec3::zeros();
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        let a: f64 = if i % 2 == 0 { 0.0175 } else { -0.0175 };
        let q = p + Vec3::new(a.cos(), a.sin(), 0.0) * 0.5;
        out.push(Block::new(
            i as u32 + 1,
            Path::Line(Line::new(p, q).unwrap()),
            100.0,
        ));
        p = q;
    }
    out
}

/// Seconds of motion the butterfly takes at 100 mm/s.
fn motion_seconds(blocks: &[Block]) -> f64 {
    let cfg = InterpConfig::default();
    let s = blocks[0].path.start_point();
    let mut ip: Box<Interpolator> =
        Box::new(Interpolator::new(cfg, [s.x, s.y, s.z, 0.0, 0.0, 0.0]).unwrap());
    for b in blocks {
        ip.push(b).unwrap();
    }
    ip.finish();
    let mut n = 0u64;
    while ip.tick().state != RunState::Done {
        n += 1;
    }
    n as f64 * cfg.period
}

fn bench(c: &mut Criterion) {
    let cfg = InterpConfig::default();
    let butterfly = butterfly_blocks(100.0);
    let start = butterfly[0].path.start_point();
    let segs = butterfly.len();
    let seconds = motion_seconds(&butterfly);
    let mut group = c.benchmark_group("plan");
    group.bench_function("butterfly_push_all_and_finish", |b| {
        b.iter(|| {
            let mut ip: Box<Interpolator> = Box::new(
                Interpolator::new(cfg, [start.x, start.y, start.z, 0.0, 0.0, 0.0]).unwrap(),
            );
            for blk in &butterfly {
                ip.push(blk).unwrap();
            }
            ip.finish();
            black_box(ip.queued_length())
        })
    });
    group.finish();
    // Derived figures, one timed pass of 20 repetitions.
    let t0 = Instant::now();
    for _ in 0..20 {
        let mut ip: Box<Interpolator> =
            Box::new(Interpolator::new(cfg, [start.x, start.y, start.z, 0.0, 0.0, 0.0]).unwrap());
        for blk in &butterfly {
            ip.push(blk).unwrap();
        }
        ip.finish();
        black_box(ip.queued_length());
    }
    let per_run = t0.elapsed().as_secs_f64() / 20.0;
    println!(
        "butterfly: {segs} segments, {seconds:.3} s of motion; planning {:.1} µs per segment, {:.2} ms per second of motion",
        per_run / segs as f64 * 1e6,
        per_run / seconds * 1e3
    );
    // Worst-case latency: one block arriving while 1,000 are queued.
    one_block_with_1000_queued("push", |ip, b| {
        let t = Instant::now();
        ip.push(b).unwrap();
        t.elapsed().as_secs_f64()
    });
}

/// Mean and max over 200 trials of `op` (which times itself, in seconds) on
/// the 1,001st line of [`polyline`] with the first 1,000 queued.
fn one_block_with_1000_queued(
    what: &str,
    mut op: impl FnMut(&mut Interpolator<1024>, &Block) -> f64,
) {
    let cfg = InterpConfig::default();
    let lines = polyline(1_001);
    let mut worst = 0.0f64;
    let mut total = 0.0;
    for _ in 0..200 {
        let mut ip: Box<Interpolator<1024>> = Box::new(Interpolator::new(cfg, [0.0; 6]).unwrap());
        for b in &lines[..1000] {
            ip.push(b).unwrap();
        }
        let dt = op(&mut ip, &lines[1000]);
        worst = worst.max(dt);
        total += dt;
        black_box(ip.queued_length());
    }
    println!(
        "{what} with 1,000 blocks queued: mean {:.2} µs, max {:.2} µs (200 trials)",
        total / 200.0 * 1e6,
        worst * 1e6
    );
}

/// The two halves of `push` apart: planning (any thread) and commit (the RT
/// thread in the daemon), per butterfly segment and with 1,000 blocks queued.
fn plan_and_commit() {
    let cfg = InterpConfig::default();
    let butterfly = butterfly_blocks(100.0);
    let start = butterfly[0].path.start_point();
    let at = [start.x, start.y, start.z, 0.0, 0.0, 0.0];
    let (mut plan_worst, mut commit_worst, mut plan_total, mut commit_total) =
        (0.0f64, 0.0f64, 0.0, 0.0);
    let reps = 20;
    for _ in 0..reps {
        let mut ip: Box<Interpolator> = Box::new(Interpolator::new(cfg, at).unwrap());
        let mut planner = ip.planner();
        let mut plan = Box::new(PlannedBlock::new());
        for blk in &butterfly {
            let t = Instant::now();
            planner.plan(blk, &mut plan).unwrap();
            let dt = t.elapsed().as_secs_f64();
            plan_worst = plan_worst.max(dt);
            plan_total += dt;
            let t = Instant::now();
            ip.commit(&plan).unwrap();
            let dt = t.elapsed().as_secs_f64();
            commit_worst = commit_worst.max(dt);
            commit_total += dt;
        }
        black_box(ip.queued_length());
    }
    let n = (reps * butterfly.len()) as f64;
    println!(
        "butterfly per segment: plan mean {:.1} µs max {:.1} µs; commit mean {:.2} µs max {:.2} µs",
        plan_total / n * 1e6,
        plan_worst * 1e6,
        commit_total / n * 1e6,
        commit_worst * 1e6
    );
    one_block_with_1000_queued("commit", |ip, b| {
        let mut plan = Box::new(PlannedBlock::new());
        ip.planner().plan(b, &mut plan).unwrap();
        let t = Instant::now();
        ip.commit(&plan).unwrap();
        t.elapsed().as_secs_f64()
    });
}

fn bench_split(_: &mut Criterion) {
    plan_and_commit();
}

criterion_group!(benches, bench, bench_split);
criterion_main!(benches);
