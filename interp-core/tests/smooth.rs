//! The G64 P stage (`smooth::Smoother`): pass-through, merges, drops,
//! compression and blends, checked against the programmed polyline by a
//! brute-force distance independent of the stage's own check.

use interp_core::geom::Curve;
use interp_core::path::{Blending, Block, Line, Path};
use interp_core::smooth::{Policy, SmoothError, Smoother};
use interp_core::{InterpConfig, Interpolator, RunState, Vec3};

fn line(id: u32, a: Vec3, b: Vec3, feed: f64, blending: Blending) -> Block {
    Block::new(id, Path::Line(Line::new(a, b).unwrap()), feed).with_blending(blending)
}

/// Lines through `pts`, ids from 1.
fn polyline(pts: &[Vec3], feed: f64, blending: Blending) -> Vec<Block> {
    pts.windows(2)
        .enumerate()
        .map(|(i, w)| line(i as u32 + 1, w[0], w[1], feed, blending))
        .collect()
}

/// `G64 P tol`.
fn within(tol: f64) -> Blending {
    Blending::Within {
        tolerance: Some(tol),
    }
}

/// Everything through the stage, popping after each push (as the drivers do).
fn smooth_all(blocks: &[Block], cfg: &InterpConfig, policy: Policy) -> Vec<Block> {
    let mut st: Box<Smoother> = Box::new(Smoother::with_policy(cfg, 1, policy).unwrap());
    let mut out = Vec::new();
    for b in blocks {
        loop {
            match st.push(b) {
                Ok(()) => break,
                Err(SmoothError::Full) => out.push(st.pop().expect("a full window pops")),
                Err(e) => panic!("{e}"),
            }
        }
        while let Some(o) = st.pop() {
            out.push(o);
        }
    }
    st.finish();
    while let Some(o) = st.pop() {
        out.push(o);
    }
    out
}

fn seg_dist(x: &Vec3, a: &Vec3, b: &Vec3) -> f64 {
    let ab = b - a;
    let l2 = ab.norm_squared();
    let t = if l2 > 0.0 {
        ((x - a).dot(&ab) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (x - (a + ab * t)).norm()
}

/// Largest distance of densely sampled output from the polyline (brute force
/// over every segment).
fn max_dev(out: &[Block], pts: &[Vec3], per_block: usize) -> f64 {
    let mut worst = 0.0f64;
    for b in out {
        let (ua, ub) = (b.path.u_start(), b.path.u_end());
        for i in 0..=per_block {
            let p = b
                .path
                .eval(ua + (ub - ua) * i as f64 / per_block as f64, 0)
                .p;
            let d = pts
                .windows(2)
                .map(|w| seg_dist(&p, &w[0], &w[1]))
                .fold(f64::INFINITY, f64::min);
            worst = worst.max(d);
        }
    }
    worst
}

fn arc_points(n: usize, r: f64, sweep: f64) -> Vec<Vec3> {
    (0..=n)
        .map(|i| {
            let a = sweep * i as f64 / n as f64;
            Vec3::new(r * a.cos(), r * a.sin(), 0.1 * a)
        })
        .collect()
}

#[test]
fn dense_arc_is_compressed_within_the_tolerance() {
    let cfg = InterpConfig::default();
    let pts = arc_points(2000, 5.0, 1.5);
    let tol = 0.001;
    let blocks = polyline(&pts, 100.0, within(tol));
    let out = smooth_all(&blocks, &cfg, Policy::Auto);
    eprintln!("{} blocks out", out.len());
    assert!(out.len() < 40, "{} blocks", out.len());
    assert!(out.iter().all(|b| matches!(b.path, Path::Nurbs(_))));
    let dev = max_dev(&out, &pts, 2000);
    assert!(dev <= tol, "{dev}");
    assert_eq!(out[0].path.start_point(), pts[0]);
    assert_eq!(out.last().unwrap().path.end_point(), *pts.last().unwrap());
}

#[test]
fn nanometre_jogs_in_a_dense_run_stay_in_its_fit() {
    // CAM output samples one point twice now and then: the same X Y, Z off
    // by round-off. Such a jog of nanometres turns by 90° at both ends; it
    // must not cut the run into pieces with two exact corners each.
    let cfg = InterpConfig::default();
    let tol = 0.001;
    let clean = arc_points(2000, 5.0, 1.5);
    let mut pts = Vec::new();
    for (i, p) in clean.iter().enumerate() {
        pts.push(*p);
        if i % 50 == 25 {
            pts.push(p + Vec3::new(0.0, 0.0, 6e-6 * (1 + i % 7) as f64));
        }
    }
    let within = Blending::Within {
        tolerance: Some(tol),
    };
    let out = smooth_all(&polyline(&pts, 100.0, within), &cfg, Policy::Auto);
    let out_clean = smooth_all(&polyline(&clean, 100.0, within), &cfg, Policy::Auto);
    assert!(
        out.iter().all(|b| matches!(b.path, Path::Nurbs(_))),
        "a jog left a line (an exact corner)"
    );
    assert!(
        out.len() <= out_clean.len() + 2,
        "{} blocks against {} without the jogs",
        out.len(),
        out_clean.len()
    );
    let dev = max_dev(&out, &pts, 2000);
    assert!(dev <= tol, "{dev}");
    assert_eq!(out.last().unwrap().path.end_point(), *pts.last().unwrap());
}

/// Runs blocks through the stage and the interpolator to the end; returns
/// the setpoints' X Y Z.
fn run(blocks: &[Block], cfg: &InterpConfig, max_ticks: u64) -> Result<Vec<Vec3>, String> {
    let out = smooth_all(blocks, cfg, Policy::Auto);
    let p = out[0].path.start_point();
    let mut ip: Box<Interpolator> =
        Box::new(Interpolator::new(*cfg, [p.x, p.y, p.z, 0.0, 0.0, 0.0]).unwrap());
    let mut next = 0;
    let mut pts = Vec::new();
    for _ in 0..max_ticks {
        while next < out.len() && ip.push(&out[next]).is_ok() {
            next += 1;
        }
        if next == out.len() {
            ip.finish();
        }
        let sp = ip.tick();
        pts.push(Vec3::new(sp.axes[0], sp.axes[1], sp.axes[2]));
        if sp.state == RunState::Done {
            return Ok(pts);
        }
    }
    Err(format!(
        "not done after {max_ticks} ticks ({next} of {} blocks queued)",
        out.len()
    ))
}

#[test]
fn seventy_collinear_micron_moves_then_a_long_one_are_one_line_under_g64_and_finish() {
    // Issue 15's minimal stall: 70 collinear 1 µm moves, then G1 X10.
    let cfg = InterpConfig::default();
    let mut pts: Vec<Vec3> = (0..=70)
        .map(|i| Vec3::new(i as f64 * 0.001, 0.0, 0.0))
        .collect();
    pts.push(Vec3::new(10.0, 0.0, 0.0));
    let g64 = Blending::Within {
        tolerance: Some(0.001),
    };
    let blocks = polyline(&pts, 100.0, g64);
    let out = smooth_all(&blocks, &cfg, Policy::Auto);
    assert_eq!(out.len(), 1, "{out:?}");
    assert_eq!(out[0].path.start_point(), pts[0]);
    assert_eq!(out[0].path.end_point(), pts[71]);
    let sp = run(&blocks, &cfg, 100_000).unwrap();
    assert_eq!(*sp.last().unwrap(), pts[71]);
    // Exact path keeps every move (it is the planner's to run them).
    let exact = polyline(&pts, 100.0, Blending::ExactPath);
    assert_eq!(smooth_all(&exact, &cfg, Policy::Auto), exact);
}

#[test]
fn exact_path_blocks_are_released_as_soon_as_they_are_pushed() {
    // A streaming client's last exact-path line must move before `end`:
    // nothing can change it, so the stage holds nothing back.
    let cfg = InterpConfig::default();
    let pts = [
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(2.0, 0.0, 0.0),
    ];
    for blending in [Blending::ExactPath, Blending::ExactStop] {
        let blocks = polyline(&pts, 100.0, blending);
        let mut s: Box<Smoother> = Box::new(Smoother::new(&cfg, 1).unwrap());
        for b in &blocks {
            s.push(b).unwrap();
            assert_eq!(s.pop(), Some(*b), "{blending:?}");
            assert_eq!(s.held(), 0);
        }
    }
    // Under G64 the last line waits: the next one may continue it.
    let g64 = polyline(&pts, 100.0, Blending::Within { tolerance: None });
    let mut s: Box<Smoother> = Box::new(Smoother::new(&cfg, 1).unwrap());
    s.push(&g64[0]).unwrap();
    assert_eq!(s.pop(), None);
    s.push(&g64[1]).unwrap();
    assert_eq!(s.pop(), None, "the two collinear lines are one, still open");
    s.finish();
    let merged = s.pop().unwrap();
    assert_eq!(merged.path.end_point(), pts[2]);
}

#[test]
fn exact_path_programs_pass_through_unchanged_and_round_off_moves_are_dropped() {
    let cfg = InterpConfig::default();
    let pts = [
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(10.0, 0.0, 0.0),
        Vec3::new(10.0, 5.0, 0.0),
        Vec3::new(3.0, 7.0, 1.0),
    ];
    for blending in [Blending::ExactPath, Blending::ExactStop] {
        let blocks = polyline(&pts, 50.0, blending);
        assert_eq!(smooth_all(&blocks, &cfg, Policy::Auto), blocks);
    }
    // A round-off move (as plan raster writes, 5.6e-17 mm) disappears; the
    // next line starts where the path is, and the ids stay consecutive.
    let tiny = Vec3::new(10.0, 5.6e-17, 0.0);
    let mut blocks = polyline(&pts[..2], 50.0, Blending::ExactPath);
    blocks.push(line(2, pts[1], tiny, 50.0, Blending::ExactPath));
    blocks.push(line(3, tiny, pts[2], 50.0, Blending::ExactPath));
    let out = smooth_all(&blocks, &cfg, Policy::Auto);
    assert_eq!(out.len(), 2);
    assert_eq!(out[1].path.start_point(), pts[1]);
    assert_eq!(out[1].path.end_point(), pts[2]);
    assert_eq!((out[0].id, out[1].id), (1, 2));
}

#[test]
fn output_does_not_depend_on_when_pop_is_called() {
    let cfg = InterpConfig::default();
    let mut pts = arc_points(300, 4.0, 2.0);
    // A long move and a sharp corner after the dense part.
    let last = *pts.last().unwrap();
    pts.push(last + Vec3::new(20.0, 0.0, 0.0));
    pts.push(last + Vec3::new(20.0, 15.0, 0.0));
    let blocks = polyline(
        &pts,
        100.0,
        Blending::Within {
            tolerance: Some(0.005),
        },
    );
    let eager = smooth_all(&blocks, &cfg, Policy::Auto);
    // Push everything first (popping only when refused), then pop.
    let mut st: Box<Smoother<64>> = Box::new(Smoother::new(&cfg, 1).unwrap());
    let mut lazy = Vec::new();
    for b in &blocks {
        while st.push(b) == Err(SmoothError::Full) {
            lazy.push(st.pop().unwrap());
        }
    }
    st.finish();
    while let Some(o) = st.pop() {
        lazy.push(o);
    }
    // Different windows may cut pieces elsewhere; the same window may not.
    let mut st: Box<Smoother<64>> = Box::new(Smoother::new(&cfg, 1).unwrap());
    let mut eager64 = Vec::new();
    for b in &blocks {
        while st.push(b) == Err(SmoothError::Full) {
            eager64.push(st.pop().unwrap());
        }
        while let Some(o) = st.pop() {
            eager64.push(o);
        }
    }
    st.finish();
    while let Some(o) = st.pop() {
        eager64.push(o);
    }
    assert_eq!(lazy, eager64);
    assert!(max_dev(&eager, &pts, 400) <= 0.005);
    assert!(max_dev(&lazy, &pts, 400) <= 0.005);
    // A window never holds more than it may: a push is refused when full and
    // the pop that follows always has a block.
    assert!(st.push(&blocks[0]).is_err());
}

#[test]
fn long_moves_get_curvature_continuous_corner_blends_within_the_tolerance() {
    let cfg = InterpConfig::default();
    let pts = [
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(20.0, 0.0, 0.0),
        Vec3::new(20.0, 20.0, 0.0),
        Vec3::new(0.0, 20.0, 5.0),
        Vec3::new(10.0, 5.0, 5.0),
    ];
    let tol = 0.01;
    let blocks = polyline(&pts, 100.0, within(tol));
    let out = smooth_all(&blocks, &cfg, Policy::Auto);
    // Every corner blended: the two 90° corners and the last one, which
    // turns by 123°. Its blend within 0.01 mm is tight, but at constant
    // speed its axis jerk (C‴·v³) allows more than `junction-min-speed`
    // there, so it is faster than a stop; the schedule holds the whole axis
    // jerk along its profile (the run at the end checks every limit).
    assert_eq!(out.len(), 7, "{out:?}");
    let kinds: Vec<bool> = out
        .iter()
        .map(|b| matches!(b.path, Path::Nurbs(_)))
        .collect();
    assert_eq!(kinds, [false, true, false, true, false, true, false]);
    assert_eq!(out[6].path.end_point(), pts[4]);
    assert!(max_dev(&out, &pts, 1000) <= tol);
    for w in out.windows(2) {
        let (a, b) = (&w[0].path, &w[1].path);
        assert_eq!(a.end_point(), b.start_point());
        if matches!((a, b), (Path::Line(_), Path::Line(_))) {
            continue;
        }
        let l = a.eval(a.u_end(), 3);
        let r = b.eval(b.u_start(), 3);
        // Same direction, same (zero) curvature on both sides.
        assert!((l.d1.normalize() - r.d1.normalize()).norm() < 1e-12);
        assert!(l.curvature() < 1e-9 && r.curvature() < 1e-9);
    }
    run(&blocks, &cfg, 1_000_000).unwrap();
}

#[test]
fn a_corner_blend_slower_than_a_stop_is_an_exact_corner_and_costs_no_more_than_the_stop() {
    // The rapids of a raster under `G64 P0.001`: up 10 mm, then 16 mm
    // across. A blend within 1 µm of a 90° corner passes at 0.7 mm/s (more
    // than `junction-min-speed`), but charged to its law sub-range it took
    // ~100 ms more than stopping there.
    let cfg = InterpConfig::default();
    let pts = [
        Vec3::new(13.0, 0.0, -3.0),
        Vec3::new(13.0, 0.0, 7.0),
        Vec3::new(-3.0, 2.0, 7.0),
    ];
    let g64 = Blending::Within {
        tolerance: Some(0.001),
    };
    let blocks = polyline(&pts, 250.0, g64);
    let out = smooth_all(&blocks, &cfg, Policy::Auto);
    assert!(
        out.iter().all(|b| matches!(b.path, Path::Line(_))),
        "{out:?}"
    );
    let corner = run(&blocks, &cfg, 100_000).unwrap().len();
    let alone: usize = blocks
        .iter()
        .map(|b| run(std::slice::from_ref(b), &cfg, 100_000).unwrap().len())
        .sum();
    assert!(corner <= alone + 2, "{corner} ticks, {alone} stopping");
}

/// A run one window long and a little more (as `plan raster` gives on a
/// smooth slope before a crease): the first piece ends where the window
/// did, and the rest, a few tens of points, is fitted joined to it. Fitted
/// with as many control points as points, the joined piece (its start's
/// curvature fixed) swung through a bend of a few µm radius, 2 mm/s, and
/// the piece after it met it at a corner of up to 17°, a stop. Fitted by
/// least squares first, the whole run is one curvature-continuous curve
/// as fast as the circle it samples.
#[test]
fn the_short_rest_of_a_long_run_joins_it_smoothly() {
    use interp_core::feed::machine_limit;
    use interp_core::geom::Derivs;
    let cfg = InterpConfig::default();
    let tol = 0.001;
    let step = 0.0065;
    let n = 280;
    for r in [1.0, 2.9, 10.0] {
        let on_circle = |a: f64| Vec3::new(r * a.sin(), 0.0, r * a.cos());
        let mut pts: Vec<Vec3> = (0..=n).map(|i| on_circle(step * i as f64 / r)).collect();
        // A crease of 84°, then a line.
        let a = step * n as f64 / r + 84f64.to_radians();
        pts.push(pts[n] + Vec3::new(a.cos(), 0.0, -a.sin()) * 3.0);
        let blocks = polyline(&pts, 100.0, within(tol));
        let out = smooth_all(&blocks, &cfg, Policy::Auto);
        let fitted = out
            .iter()
            .take_while(|b| matches!(b.path, Path::Nurbs(_)))
            .count();
        assert!(fitted >= 2, "r {r}: {fitted} fitted pieces");
        for w in out[..fitted].windows(2) {
            let t0 = w[0].path.eval(w[0].path.u_end(), 1).d1.normalize();
            let t1 = w[1].path.eval(w[1].path.u_start(), 1).d1.normalize();
            let turn = t0.dot(&t1).clamp(-1.0, 1.0).acos().to_degrees();
            assert!(
                turn < 0.01,
                "r {r}: pieces {} and {} meet at {turn}°",
                w[0].id,
                w[1].id
            );
        }
        // The machine laws on the circle itself (unit speed: C'' = κ·n).
        let exact = (0..=50)
            .map(|i| {
                let a = step * n as f64 / r * i as f64 / 50.0;
                let t = Vec3::new(a.cos(), 0.0, -a.sin());
                let d = Derivs {
                    p: on_circle(a),
                    d1: t,
                    d2: -on_circle(a) / (r * r),
                    d3: -t / (r * r),
                };
                machine_limit(&d, &cfg, 1.0)
            })
            .fold(f64::INFINITY, f64::min);
        for b in &out[..fitted] {
            let (ua, ub) = (b.path.u_start(), b.path.u_end());
            let slowest = (0..=400)
                .map(|i| {
                    machine_limit(
                        &b.path.eval(ua + (ub - ua) * i as f64 / 400.0, 3),
                        &cfg,
                        1.0,
                    )
                })
                .fold(f64::INFINITY, f64::min);
            assert!(
                slowest >= 0.8 * exact,
                "r {r}: piece {} is limited to {slowest} mm/s, the circle to {exact}",
                b.id
            );
        }
        assert!(max_dev(&out, &pts, 2000) <= tol);
    }
}

/// A ball's path over a mesh edge: a nearly flat stretch, then an arc of
/// the ball's radius (the curvature steps to 1/3 mm⁻¹), sampled every
/// 17 µm as a raster samples it. Within 1 µm the step can be spread over a
/// few tenths of a millimetre, a `C‴` near 1/mm²; the axes' jerk passes a
/// piece no faster than `(Jᵢ/|C‴ᵢ|)^⅓`. The smoothing fit gives 0.92/mm²;
/// plain least-squares pieces followed the samples with 2.7/mm².
#[test]
fn a_ball_path_over_a_mesh_edge_is_fitted_with_a_low_third_derivative() {
    use interp_core::feed::ArcLengthDerivs;
    let cfg = InterpConfig::default();
    let tol = 0.001;
    let (r, step) = (3.0, 0.017);
    // The flat stretch bends a little (radius 500 mm, as facets at slight
    // angles do), so it is not merged into one line.
    let flat = 500.0;
    let mut pts: Vec<Vec3> = (0..=120)
        .rev()
        .map(|i| {
            let a = step * i as f64 / flat;
            Vec3::new(-flat * a.sin(), 0.0, -flat * (1.0 - a.cos()))
        })
        .collect();
    pts.extend((1..=120).map(|i| {
        let a = step * i as f64 / r;
        Vec3::new(r * a.sin(), 0.0, -r * (1.0 - a.cos()))
    }));
    let blocks = polyline(&pts, 100.0, within(tol));
    let out = smooth_all(&blocks, &cfg, Policy::Auto);
    assert!(out.iter().any(|b| matches!(b.path, Path::Nurbs(_))));
    assert!(max_dev(&out, &pts, 2000) <= tol);
    let c3 = out
        .iter()
        .flat_map(|b| {
            let (ua, ub) = (b.path.u_start(), b.path.u_end());
            (0..=2000).map(move |i| b.path.eval(ua + (ub - ua) * i as f64 / 2000.0, 3))
        })
        .filter_map(|d| ArcLengthDerivs::new(&d))
        .map(|a| a.c_sss.norm())
        .fold(0.0, f64::max);
    eprintln!("{} pieces, largest C''' {c3}", out.len());
    assert!(c3 < 1.5, "largest C''' {c3} /mm²");
}
