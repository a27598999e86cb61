//! Shared data and helpers for interp-core's integration tests and benches.
#![allow(dead_code)]

pub use interp_core::samples::butterfly;

pub mod geomdl;

use interp_core::geom::Vec3;
use interp_core::nurbs::{Nurbs, split_program_curve};
use interp_core::path::Block;
use interp_core::{InterpConfig, Interpolator, Setpoint};

/// Relative slack on every limit (issue 9: +1e-6).
pub const LIMIT_REL_TOL: f64 = 1e-6;

fn v3(p: &[f64; 6]) -> Vec3 {
    Vec3::new(p[0], p[1], p[2])
}

/// Cuts a program curve into segments of at most `max_ctrl` control points
/// (`max_ctrl <= MAX_CTRL - 6`) with `split_program_curve` and collects them.
///
/// Panics if the curve is refused.
pub fn split_segments(
    degree: usize,
    points: &[[f64; 3]],
    weights: &[f64],
    knots: &[f64],
    max_ctrl: usize,
) -> Vec<Nurbs> {
    let mut segments = Vec::new();
    split_program_curve::<core::convert::Infallible>(
        degree,
        points,
        weights,
        knots,
        max_ctrl,
        |segment| {
            segments.push(segment);
            Ok(())
        },
    )
    .unwrap_or_else(|e| panic!("split_program_curve refused the curve: {e:?}"));
    segments
}

/// The LinuxCNC butterfly ([`butterfly`]) as consecutive segments of at most
/// `max_ctrl` control points.
pub fn butterfly_segments(max_ctrl: usize) -> Vec<Nurbs> {
    split_segments(
        butterfly::BUTTERFLY_DEGREE,
        &butterfly::BUTTERFLY_POINTS,
        &butterfly::BUTTERFLY_WEIGHTS,
        &butterfly::BUTTERFLY_KNOTS,
        max_ctrl,
    )
}

/// The butterfly as consecutive NURBS blocks (ids from 1), cut like
/// [`butterfly_segments`]`(20)`, at `feed` mm/s.
pub fn butterfly_blocks(feed: f64) -> Vec<Block> {
    let mut blocks = Vec::new();
    butterfly::for_each_block::<core::convert::Infallible>(feed, 1, 20, |b| {
        blocks.push(b);
        Ok(())
    })
    .unwrap_or_else(|e| panic!("the butterfly did not split: {e:?}"));
    blocks
}

/// Kinematics measured from the setpoints alone (finite differences), as a
/// drive would see them.
#[derive(Default, Debug, Clone, Copy)]
pub struct Measured {
    pub max_accel: f64,
    pub max_jerk: f64,
    pub max_centripetal: f64,
    pub axis_vel: [f64; 3],
    pub axis_acc: [f64; 3],
    pub axis_jerk: [f64; 3],
}

pub fn measure(ts: f64, start: Vec3, sps: &[Setpoint]) -> Measured {
    let mut m = Measured::default();
    // Positions with two copies of the start before (at rest before tick 1).
    let mut pts = vec![start, start, start];
    pts.extend(sps.iter().map(|s| v3(&s.axes)));
    let mut feeds = vec![0.0, 0.0];
    feeds.extend(sps.iter().map(|s| s.feed));
    for i in 2..feeds.len() {
        let a = (feeds[i] - feeds[i - 1]) / ts;
        let a0 = (feeds[i - 1] - feeds[i - 2]) / ts;
        m.max_accel = m.max_accel.max(a.abs());
        m.max_jerk = m.max_jerk.max(((a - a0) / ts).abs());
    }
    for i in 3..pts.len() {
        let v = (pts[i] - pts[i - 1]) / ts;
        let acc = (pts[i] - 2.0 * pts[i - 1] + pts[i - 2]) / (ts * ts);
        let acc0 = (pts[i - 1] - 2.0 * pts[i - 2] + pts[i - 3]) / (ts * ts);
        let jerk = (acc - acc0) / ts;
        for k in 0..3 {
            m.axis_vel[k] = m.axis_vel[k].max(v[k].abs());
            m.axis_acc[k] = m.axis_acc[k].max(acc[k].abs());
            m.axis_jerk[k] = m.axis_jerk[k].max(jerk[k].abs());
        }
        let chord = pts[i] - pts[i - 2];
        if chord.norm() > 0.0 {
            let t = chord / chord.norm();
            m.max_centripetal = m.max_centripetal.max((acc - t * acc.dot(&t)).norm());
        }
    }
    m
}

/// Every limit of the configuration holds on the measured kinematics (+1e-6 relative).
pub fn check_kinematics(cfg: &InterpConfig, start: Vec3, sps: &[Setpoint]) -> Measured {
    let m = measure(cfg.period, start, sps);
    let ok = |v: f64, lim: f64| v <= lim * (1.0 + LIMIT_REL_TOL);
    assert!(
        ok(m.max_accel, cfg.max_path_accel),
        "tangential accel {m:?}"
    );
    assert!(ok(m.max_jerk, cfg.max_path_jerk), "tangential jerk {m:?}");
    assert!(
        ok(m.max_centripetal, cfg.max_centripetal_accel),
        "centripetal accel {m:?}"
    );
    for k in 0..3 {
        assert!(
            ok(m.axis_vel[k], cfg.axis_max_velocity[k]),
            "axis {k} velocity {m:?}"
        );
        assert!(
            ok(m.axis_acc[k], cfg.axis_max_accel[k]),
            "axis {k} accel {m:?}"
        );
        assert!(
            ok(m.axis_jerk[k], cfg.axis_max_jerk[k]),
            "axis {k} jerk {m:?}"
        );
    }
    m
}

/// Pushes blocks until one does not fit yet (the look-ahead reaches far
/// enough for now); returns how many were queued. Panics on any other error.
pub fn push_what_fits<const Q: usize>(ip: &mut Interpolator<Q>, blocks: &[Block]) -> usize {
    for (i, b) in blocks.iter().enumerate() {
        match ip.push(b) {
            Ok(()) => {}
            Err(e) if e.is_wait() => return i,
            Err(e) => panic!("block {}: {e}", b.id),
        }
    }
    blocks.len()
}

/// Small deterministic generator (the test must not depend on rand's versions).
pub struct Lcg(pub u64);
impl Lcg {
    pub fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
    pub fn range(&mut self, a: f64, b: f64) -> f64 {
        a + (b - a) * self.next()
    }
}
