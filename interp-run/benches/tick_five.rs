//! Criterion bench: the cost of one `Executor::tick()` on a five-axis
//! program against the very same path as a three-axis one (plans made
//! beforehand and committed at their ticks, as on the RT thread; see
//! `benches/tick.rs`).
//!
//! The path is a helical arc (radius 30 mm, three quarters of a turn,
//! rising 12 mm: ≈ 142 mm, the helix of `interp-core/tests/fiveaxis.rs`)
//! at 100 mm/s, corrected update, on the example's C,A table
//! (`examples/five_axis/machine.toml`: tool 100 mm, A 50 mm below the gauge
//! point, A within ±110°), the same configuration in every case:
//!
//! - `three-axis`: no orientation (the rotary axes stand);
//! - `plain-rotary`: A and C move with the path as plain axes (TCP off);
//! - `tcp`: the path is the tool tip and the tool axis turns on its great
//!   circle from 20° towards +x to 35° towards −y (G43.5), the joints from
//!   the inverse transform every tick (C follows the tool's azimuth).
//!
//! A second group runs the tick benches' rational cubic (`benches/tick.rs`,
//! 30 control points, ≈ 330 mm) at 100 mm/s on the same machine:
//!
//! - `three-axis`: no orientation;
//! - `tcp`: the tool axis on its great circle from (A 10°, C 90°) to
//!   (A 35°, C 0°) (the case that stalled, `interp-core/tests/fiveaxis.rs`);
//! - `tcp-curve`: a second curve for the tool axis (G6.2 with U V W under
//!   G43.5): the cubic cut into its knot spans, each a block whose tool
//!   axis is its piece of the vectors' NURBS, the vectors the affine image
//!   `(−0.3·x/20, −0.3·y/20, 1)` of the control points (leaning towards z
//!   by up to 21°), normalised every tick.
//!
//! Each case is measured twice, interleaved (A B C A B C), so that a change
//! of the machine's load shows as a difference between the two rounds.
//!
//! ```text
//! cargo bench -p interp-run --bench tick_five
//! ```

#[path = "common/mod.rs"]
mod common;

use core::time::Duration;

use common::{rational_cubic, run_to_end, start_of, time_ticks};
use criterion::{Criterion, criterion_group};
use interp_core::fiveaxis::Orientation;
use interp_core::kinematics::{Machine, MachineSpec, RotaryRange, ToolPose};
use interp_core::nurbs::split_program_curve;
use interp_core::path::Arc;
use interp_core::{Block, Curve, InterpConfig, Path, Vec3};
use interp_run::Replay;

/// The example's C,A table-table.
fn machine() -> MachineSpec {
    let mut spec = MachineSpec::new("W/caxyBz/T".parse().expect("chain"));
    spec.tool_length = 100.0;
    spec.rotary_centres[0] = [0.0, 0.0, -50.0];
    spec.rotary_ranges[0] = RotaryRange {
        min: -110.0,
        max: 110.0,
    };
    spec
}

fn tilted(deg: f64, towards: Vec3) -> Vec3 {
    let t = deg.to_radians();
    Vec3::z() * t.cos() + towards * t.sin()
}

/// A program and where it starts.
type Case = (&'static str, [f64; 6], Vec<Block>);

/// The three programs on the rational cubic, with where each starts.
fn cubic_cases(cfg: &InterpConfig) -> Vec<Case> {
    let m = Machine::new(cfg.machine.expect("machine")).expect("machine");
    let n = rational_cubic();
    let path = Path::Nurbs(n);
    let three = vec![Block::new(1, path, 100.0)];
    let axis = |a: f64, c: f64| m.forward(&[0.0, 0.0, 0.0, a, 0.0, c]).axis;
    let (a0, a1) = (axis(10.0, 90.0), axis(35.0, 0.0));
    let tcp = Orientation::tool_axis(&path, a0, a1).expect("tool axis");
    let start = |axis: Vec3, near: [f64; 6]| {
        m.inverse(
            &ToolPose {
                tip: path.start_point(),
                axis,
            },
            &near,
        )
        .expect("reachable")
        .joints
    };
    // The tool-vector curve: an affine image of the control points, so a
    // span's piece is that image of the span's own control points.
    let vector = |p: [f64; 3]| [-0.3 * p[0] / 20.0, -0.3 * p[1] / 20.0, 1.0];
    let count = n.control_count();
    let points: Vec<[f64; 3]> = (0..count).map(|k| n.control_point(k)).collect();
    let weights: Vec<f64> = (0..count).map(|k| n.weight(k)).collect();
    let mut spans = Vec::new();
    split_program_curve::<core::convert::Infallible>(
        n.degree(),
        &points,
        &weights,
        n.knots(),
        n.degree() + 1,
        |s| {
            let vs: Vec<[f64; 3]> = (0..s.control_count())
                .map(|k| vector(s.control_point(k)))
                .collect();
            let ws: Vec<f64> = (0..s.control_count()).map(|k| s.weight(k)).collect();
            let o = Orientation::tool_axis_curve(s.degree(), &vs, &ws, s.u_start(), s.u_end())
                .expect("tool vector curve");
            spans.push(
                Block::new(spans.len() as u32 + 1, Path::Nurbs(s), 100.0).with_orientation(o),
            );
            Ok(())
        },
    )
    .expect("cubic splits");
    let v0 = vector(points[0]);
    vec![
        ("three-axis", start_of(&three), three.clone()),
        (
            "tcp",
            start(a0, [0.0, 0.0, 0.0, 10.0, 0.0, 90.0]),
            vec![three[0].with_orientation(tcp)],
        ),
        (
            "tcp-curve",
            start(Vec3::new(v0[0], v0[1], v0[2]).normalize(), [0.0; 6]),
            spans,
        ),
    ]
}

/// The three programs on the same path, with where each starts.
fn cases(cfg: &InterpConfig) -> Vec<Case> {
    let (r, z0, rise, sweep) = (30.0, -5.0, 12.0, 1.5 * core::f64::consts::PI);
    let at = |t: f64| Vec3::new(r * t.cos(), r * t.sin(), z0 + rise * t / sweep);
    let arc =
        Arc::from_centre(at(0.0), at(sweep), Vec3::new(0.0, 0.0, z0), Vec3::z(), 0).expect("helix");
    let path = Path::Arc(arc);
    let three = vec![Block::new(1, path, 100.0)];
    let plain = Orientation::axes(&path, [0.0; 3], [20.0, 0.0, 90.0]).expect("axes");
    let (a0, a1) = (tilted(20.0, Vec3::x()), tilted(35.0, -Vec3::y()));
    let tcp = Orientation::tool_axis(&path, a0, a1).expect("tool axis");
    let m = Machine::new(cfg.machine.expect("machine")).expect("machine");
    let tcp_start = m
        .inverse(
            &ToolPose {
                tip: path.start_point(),
                axis: a0,
            },
            &[0.0; 6],
        )
        .expect("reachable")
        .joints;
    vec![
        ("three-axis", start_of(&three), three.clone()),
        (
            "plain-rotary",
            start_of(&three),
            vec![three[0].with_orientation(plain)],
        ),
        ("tcp", tcp_start, vec![three[0].with_orientation(tcp)]),
    ]
}

fn ticks(c: &mut Criterion) {
    let cfg = InterpConfig {
        machine: Some(machine()),
        ..InterpConfig::default()
    };
    for (group_name, cases) in [
        ("tick-five/helix", cases(&cfg)),
        ("tick-five/rational-cubic", cubic_cases(&cfg)),
    ] {
        let mut loaded: Vec<(&str, Box<Replay>)> = cases
            .into_iter()
            .map(|(name, start, blocks)| {
                let mut ip = Box::new(
                    interp_run::plan(cfg, start, &blocks, 50_000_000).expect("program plans"),
                );
                eprintln!(
                    "{group_name} {name}: {} ticks to the end",
                    run_to_end(&mut ip)
                );
                ip.rewind();
                (name, ip)
            })
            .collect();
        let mut group = c.benchmark_group(group_name);
        for round in 1..=2 {
            for (name, ip) in loaded.iter_mut() {
                group.bench_function(format!("{name}/{round}"), |b| {
                    b.iter_custom(|iters| time_ticks(iters, ip, |ip| ip.rewind()));
                });
            }
        }
        group.finish();
    }
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
    interp_run::stack::on_interpolator_stack(|| {
        benches();
        Criterion::default().configure_from_args().final_summary();
    });
}
