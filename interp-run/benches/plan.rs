//! Planning cost (non-RT work in `push` and `finish`): per segment, per
//! second of planned motion, and the two halves apart (plan, commit).
//!
//! ```text
//! cargo bench -p interp-run --bench plan
//! ```
//!
//! Besides criterion's figures it prints the derived per-segment and
//! per-second-of-motion costs, and plan and commit times (mean, max).

#[path = "common/mod.rs"]
mod common;

use core::convert::Infallible;
use core::hint::black_box;
use std::time::Instant;

use common::butterfly_blocks;
use criterion::{Criterion, criterion_group};
use interp_core::geom::{Curve, Vec3};
use interp_core::path::{Block, Line, Path};
use interp_core::{BlockPlanner, InterpConfig, Interpolator, PlannedBlock, RunState};
use interp_run::Run;

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

/// Runs `blocks` to the end from `start` as `simulate` does (each block
/// pushed as soon as it is taken, ticking while it waits); returns the ticks.
fn run_all(cfg: InterpConfig, start: Vec3, blocks: &[Block]) -> u64 {
    let mut run: Run = Run::new(cfg, [start.x, start.y, start.z, 0.0, 0.0, 0.0]).unwrap();
    let end = run
        .run_program::<Infallible>(blocks, |sp, _| {
            black_box(sp);
            Ok(())
        })
        .unwrap();
    assert_eq!(end, RunState::Done);
    run.ticks()
}

/// Seconds of motion the butterfly takes at 100 mm/s.
fn motion_seconds(blocks: &[Block]) -> f64 {
    let cfg = InterpConfig::default();
    run_all(cfg, blocks[0].path.start_point(), blocks) as f64 * cfg.period
}

fn bench(c: &mut Criterion) {
    let cfg = InterpConfig::default();
    let butterfly = butterfly_blocks(100.0);
    let start = butterfly[0].path.start_point();
    let segs = butterfly.len();
    let seconds = motion_seconds(&butterfly);
    let mut group = c.benchmark_group("plan");
    group.sample_size(10);
    group.bench_function("butterfly_run_to_the_end", |b| {
        b.iter(|| black_box(run_all(cfg, start, &butterfly)))
    });
    group.finish();
    // Derived figures, one timed pass of 20 repetitions.
    let t0 = Instant::now();
    for _ in 0..20 {
        black_box(run_all(cfg, start, &butterfly));
    }
    let per_run = t0.elapsed().as_secs_f64() / 20.0;
    println!(
        "butterfly: {segs} segments, {seconds:.3} s of motion; planning and ticking {:.1} µs per segment, {:.2} ms per second of motion",
        per_run / segs as f64 * 1e6,
        per_run / seconds * 1e3
    );
    plan_and_commit();
}

/// The two halves of `push` apart: planning (the control plane in the
/// daemon: law sampling and the speed's linear program) and commit (the RT
/// thread: copying the plan in), per part of the butterfly and per line of
/// a dense polyline.
fn plan_and_commit() {
    let cfg = InterpConfig::default();
    let butterfly = butterfly_blocks(100.0);
    let start = butterfly[0].path.start_point();
    let at = [start.x, start.y, start.z, 0.0, 0.0, 0.0];
    let mut plans = Timing::default();
    let mut commits = Timing::default();
    for _ in 0..20 {
        let mut ip: Box<Interpolator> = Box::new(Interpolator::new(cfg, at).unwrap());
        let mut planner = Box::new(BlockPlanner::new(cfg, start, 0.0).unwrap());
        let mut plan = Box::new(PlannedBlock::new());
        for blk in &butterfly {
            let mut first = true;
            while first || planner.has_pending() {
                let (s, rest) = ip.executor().plan_position();
                // (As the driver does once a tick.)
                planner.release_behind(s);
                planner.set_machine(s, rest);
                let t = Instant::now();
                let r = if first {
                    planner.plan(blk, &mut plan)
                } else {
                    planner.plan_pending(&mut plan)
                };
                if r.is_err() {
                    // The look-ahead reaches far enough for now.
                    black_box(ip.tick());
                    continue;
                }
                plans.add(t.elapsed().as_secs_f64());
                first = false;
                let t = Instant::now();
                ip.commit(&plan).unwrap();
                commits.add(t.elapsed().as_secs_f64());
                // Let the machine move on.
                for _ in 0..50 {
                    black_box(ip.tick());
                }
            }
        }
    }
    println!(
        "butterfly per part: plan mean {:.0} µs max {:.0} µs; commit mean {:.2} µs max {:.2} µs",
        plans.mean() * 1e6,
        plans.max * 1e6,
        commits.mean() * 1e6,
        commits.max * 1e6
    );
    let lines = polyline(1_001);
    let mut plans = Timing::default();
    let mut commits = Timing::default();
    let mut ip: Box<Interpolator<1024>> = Box::new(Interpolator::new(cfg, [0.0; 6]).unwrap());
    let mut planner = Box::new(BlockPlanner::new(cfg, Vec3::zeros(), 0.0).unwrap());
    let mut plan = Box::new(PlannedBlock::new());
    for b in &lines {
        loop {
            let (s, rest) = ip.executor().plan_position();
            planner.release_behind(s);
            planner.set_machine(s, rest);
            let t = Instant::now();
            match planner.plan(b, &mut plan) {
                Ok(()) => {
                    plans.add(t.elapsed().as_secs_f64());
                    break;
                }
                Err(_) => {
                    black_box(ip.tick());
                }
            }
        }
        let t = Instant::now();
        ip.commit(&plan).unwrap();
        commits.add(t.elapsed().as_secs_f64());
    }
    println!(
        "polyline of 0.5 mm lines: plan mean {:.0} µs max {:.0} µs; commit mean {:.2} µs max {:.2} µs ({} lines)",
        plans.mean() * 1e6,
        plans.max * 1e6,
        commits.mean() * 1e6,
        commits.max * 1e6,
        plans.n
    );
}

#[derive(Default)]
struct Timing {
    n: usize,
    total: f64,
    max: f64,
}

impl Timing {
    fn add(&mut self, dt: f64) {
        self.n += 1;
        self.total += dt;
        self.max = self.max.max(dt);
    }
    fn mean(&self) -> f64 {
        self.total / self.n.max(1) as f64
    }
}

criterion_group!(benches, bench);
fn main() {
    interp_run::stack::on_interpolator_stack(|| {
        benches();
        Criterion::default().configure_from_args().final_summary();
    });
}
