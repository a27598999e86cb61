//! The RT path never allocates, and the same blocks + config give
//! bit-identical setpoints: 200,000 ticks (the operator schedule below once
//! through, 3.3 minutes of machine time), twice, with blocks pushed as the
//! queue frees up (push is non-RT but allocation-free too).
//!
//! A counting global allocator (`alloc-count`) counts allocations made on
//! this test's thread while counting is switched on (copper-rs's habit).

mod common;

use interp_core::geom::{Curve, Vec3};
use interp_core::path::{Arc, Block, Path};
use interp_core::{InterpConfig, Interpolator, RunState};

#[global_allocator]
static GLOBAL: alloc_count::Counting = alloc_count::Counting;

const TICKS: u64 = 200_000;

/// FNV-1a over the bits of every field of every setpoint.
fn fold(hash: &mut u64, words: &[u64]) {
    for w in words {
        for b in w.to_le_bytes() {
            *hash ^= b as u64;
            *hash = hash.wrapping_mul(0x100_0000_01b3);
        }
    }
}

/// Runs `TICKS` ticks; returns (hash of setpoints, allocations while ticking, ticks moving).
fn run() -> (u64, u64, u64) {
    let cfg = InterpConfig::default();
    let lap = common::butterfly_blocks(100.0);
    let lap_start = lap[0].path.start_point();
    // Everything that may allocate happens before counting starts.
    let mut ip: Box<Interpolator> = Box::new(
        Interpolator::new(cfg, [lap_start.x, lap_start.y, lap_start.z, 0.0, 0.0, 0.0]).unwrap(),
    );
    let mut tail = lap_start;
    let mut next = 0usize; // index into the lap; lap.len() means the helix
    let mut shift = Vec3::zeros();
    let mut hash = 0xcbf2_9ce4_8422_2325u64;
    let mut moving = 0u64;
    alloc_count::start();
    for t in 0..TICKS {
        // Operator commands through the schedule (RT-side calls, allocation-free).
        match t % 200_000 {
            50_000 => ip.set_feed_override(1.6).unwrap(),
            90_000 => ip.feed_hold(),
            91_000 => ip.resume(),
            120_000 => ip.set_feed_override(0.5).unwrap(),
            150_000 => ip.set_feed_override(1.0).unwrap(),
            _ => {}
        }
        // Refill (non-RT work, but allocation-free too).
        while ip.free_segments() > 0 && ip.queued_length() < 500.0 {
            if next == 0 {
                shift = tail - lap_start;
            }
            let block = if next < lap.len() {
                let mut b = lap[next];
                if let Path::Nurbs(n) = b.path {
                    b.path = Path::Nurbs(n.translated(shift));
                }
                b
            } else {
                // A full helix turn rising 2 mm (a corner at both ends).
                let helix = Arc::from_centre(
                    tail,
                    tail + Vec3::new(0.0, 0.0, 2.0),
                    tail + Vec3::new(-5.0, 0.0, 0.0),
                    Vec3::z(),
                    0,
                )
                .unwrap();
                Block::new(99, Path::Arc(helix), 60.0)
            };
            match ip.push(&block) {
                Ok(()) => {}
                // The look-ahead reaches far enough for now.
                Err(e) if e.is_wait() => break,
                Err(e) => panic!("{e}"),
            }
            tail = block.path.end_point();
            next = (next + 1) % (lap.len() + 1);
        }
        let sp = ip.tick();
        assert_ne!(sp.state, RunState::Fault);
        if sp.feed > 0.0 {
            moving += 1;
        }
        let mut words = [0u64; 12];
        words[0] = sp.seq;
        words[1] = sp.time.to_bits();
        for (w, a) in words[2..8].iter_mut().zip(sp.axes) {
            *w = a.to_bits();
        }
        words[8] = sp.feed.to_bits();
        words[9] = sp.u.to_bits();
        words[10] = sp.s.to_bits();
        words[11] = ((sp.block_id as u64) << 8) | sp.state as u64;
        fold(&mut hash, &words);
    }
    let allocations = alloc_count::stop();
    (hash, allocations, moving)
}

#[test]
fn two_hundred_thousand_ticks_allocate_nothing_and_repeat_bit_for_bit() {
    let (h1, a1, m1) = run();
    let (h2, a2, m2) = run();
    assert_eq!(a1, 0, "allocations during the first run");
    assert_eq!(a2, 0, "allocations during the second run");
    // The machine really moved for almost all of it (not a run stuck at rest).
    assert!(m1 > TICKS * 8 / 10, "moving ticks {m1}");
    assert_eq!(m1, m2);
    assert_eq!(h1, h2, "two runs differ");
}

/// The kinematic transforms the tick will call per setpoint allocate nothing
/// either (a C,A table-table and an A,B head-head machine, through the pole).
#[test]
fn kinematics_allocate_nothing() {
    use interp_core::kinematics::{Machine, MachineSpec};
    let machines = ["W/caxyBz/T", "W/xyzBab/T"].map(|n| {
        let mut spec = MachineSpec::new(n.parse().unwrap());
        spec.tool_length = 120.0;
        spec.rotary_centres = [[0.0, 10.0, -80.0], [5.0, 0.0, -60.0], [1.0, 2.0, 0.0]];
        Machine::new(spec).unwrap()
    });
    alloc_count::start();
    let mut checked = 0;
    for m in &machines {
        let mut joints = [10.0, -5.0, 40.0, 0.0, 0.0, 0.0];
        for k in 0..1000 {
            let t = f64::from(k) * 1e-3;
            let target = [
                5.0 * t,
                3.0 - t,
                40.0 + t,
                30.0 - 60.0 * t,
                20.0 * t,
                200.0 * t,
            ];
            let pose = m.forward(&target);
            joints = m.inverse(&pose, &joints).unwrap().joints;
            if let Ok(r) = m.joint_rates(&joints, &Vec3::x(), &pose.axis.cross(&Vec3::z())) {
                checked += usize::from(r.iter().all(|v| v.is_finite()));
            }
        }
    }
    assert_eq!(
        alloc_count::stop(),
        0,
        "allocations in forward/inverse/joint_rates"
    );
    assert!(checked > 1900, "{checked}");
}

/// A five-axis program under tool-centre-point control (push, plan, every
/// tick through the inverse transform, a hold and a resume) allocates
/// nothing, and runs the same twice.
#[test]
fn five_axis_ticks_allocate_nothing() {
    use interp_core::fiveaxis::Orientation;
    use interp_core::kinematics::{Machine, MachineSpec, ToolPose};
    let mut spec = MachineSpec::new("W/caxyBz/T".parse().unwrap());
    spec.tool_length = 80.0;
    spec.rotary_centres[0] = [0.0, 0.0, -40.0];
    let cfg = InterpConfig {
        machine: Some(spec),
        ..InterpConfig::default()
    };
    let m = Machine::new(spec).unwrap();
    let tilt = |deg: f64, y: f64| Vec3::new(deg.to_radians().sin(), y, deg.to_radians().cos());
    let arc = Arc::from_centre(
        Vec3::new(30.0, 0.0, 0.0),
        Vec3::new(-30.0, 0.0, 8.0),
        Vec3::zeros(),
        Vec3::z(),
        0,
    )
    .unwrap();
    let path = Path::Arc(arc);
    let (a0, a1) = (tilt(20.0, 0.0), tilt(-30.0, 0.3));
    let block =
        Block::new(1, path, 60.0).with_orientation(Orientation::tool_axis(&path, a0, a1).unwrap());
    let start = m
        .inverse(
            &ToolPose {
                tip: path.start_point(),
                axis: a0,
            },
            &[0.0; 6],
        )
        .unwrap()
        .joints;
    let run = || {
        let mut ip: Box<Interpolator> = Box::new(Interpolator::new(cfg, start).unwrap());
        let mut hash = 0xcbf2_9ce4_8422_2325u64;
        alloc_count::start();
        ip.push(&block).unwrap();
        ip.finish();
        let mut ticks = 0u64;
        loop {
            ticks += 1;
            match ticks {
                800 => ip.feed_hold(),
                1600 => ip.resume(),
                _ => {}
            }
            let sp = ip.tick();
            fold(&mut hash, &sp.axes.map(f64::to_bits));
            if sp.state == RunState::Done || ticks > 100_000 {
                break;
            }
        }
        (alloc_count::stop(), hash, ticks)
    };
    let (a1, h1, t1) = run();
    let (a2, h2, t2) = run();
    assert_eq!((a1, a2), (0, 0), "allocations");
    assert!(t1 > 1600 && t1 < 100_000, "{t1} ticks");
    assert_eq!((h1, t1), (h2, t2), "two runs differ");
}
