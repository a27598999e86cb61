//! Criterion bench: the cost of one `Executor::tick()` on a five-axis block
//! under tool-centre-point control (the tip along a helix, the tool axis
//! turning, joints from the inverse transform every tick) against the same
//! helix as a three-axis block, on a C,A table-table, 50 mm/s.
//!
//! ```text
//! cargo bench -p interp-core --bench five_axis
//! ```

#[path = "common/mod.rs"]
mod common;

use core::hint::black_box;
use core::time::Duration;
use std::time::Instant;

use common::{Loaded, loaded_at};
use criterion::{Criterion, criterion_group};
use interp_core::fiveaxis::Orientation;
use interp_core::kinematics::{Machine, MachineSpec, ToolPose};
use interp_core::path::{Arc, Block, Path};
use interp_core::{Curve, InterpConfig, RunState, Vec3};

fn tilted(deg: f64, towards: Vec3) -> Vec3 {
    let r = deg.to_radians();
    Vec3::z() * r.cos() + towards * r.sin()
}

/// A named program and the joints it starts at.
type Program = (&'static str, [f64; 6], Vec<Block>);

/// The helix of `tests/fiveaxis.rs`, with and without its tool axis, and
/// where each starts.
fn programs() -> (InterpConfig, [Program; 2]) {
    let mut spec = MachineSpec::new("W/caxyBz/T".parse().expect("chain"));
    spec.tool_length = 80.0;
    spec.rotary_centres[0] = [0.0, 0.0, -40.0];
    let cfg = InterpConfig {
        machine: Some(spec),
        ..InterpConfig::default()
    };
    let m = Machine::new(spec).expect("machine");
    let sweep = 1.5 * core::f64::consts::PI;
    let p = |t: f64| Vec3::new(30.0 * t.cos(), 30.0 * t.sin(), -5.0 + 12.0 * t / sweep);
    let path = Path::Arc(
        Arc::from_centre(p(0.0), p(sweep), Vec3::new(0.0, 0.0, -5.0), Vec3::z(), 0).expect("arc"),
    );
    let (a0, a1) = (tilted(20.0, Vec3::x()), tilted(35.0, -Vec3::y()));
    let three = Block::new(1, path, 50.0);
    let five = three.with_orientation(Orientation::tool_axis(&path, a0, a1).expect("axis"));
    let s = path.start_point();
    let joints = m
        .inverse(&ToolPose { tip: s, axis: a0 }, &[0.0; 6])
        .expect("reachable")
        .joints;
    (
        cfg,
        [
            ("three-axis", [s.x, s.y, s.z, 0.0, 0.0, 0.0], vec![three]),
            ("tcp", joints, vec![five]),
        ],
    )
}

fn time_ticks(ip: &mut Loaded, iters: u64) -> Duration {
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
            ip.restart();
        }
    }
    total
}

fn ticks(c: &mut Criterion) {
    let (cfg, runs) = programs();
    let mut group = c.benchmark_group("tick/helix");
    for (name, start, blocks) in runs {
        let mut ip = loaded_at(cfg, start, &blocks);
        group.bench_function(name, |b| b.iter_custom(|iters| time_ticks(&mut ip, iters)));
    }
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(5))
        .sample_size(50);
    targets = ticks
}
fn main() {
    common::on_big_stack(|| {
        benches();
        Criterion::default().configure_from_args().final_summary();
    });
}
