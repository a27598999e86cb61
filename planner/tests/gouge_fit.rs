//! NURBS fitting of CL polylines: the blocks are valid interp-core curves
//! that interp-core evaluates to the same points, within the tolerance of the
//! CL points; metamorphic checks (translated, scaled, reversed, split).

use interp_core::Curve;
use interp_core::nurbs::{split_program_curve, validate_program_curve};
use planner::fit::{self, FitConfig, FitPiece, NurbsBlock};
use planner::mesh::{P3, V3};

/// A zig-zag raster over a wavy surface: rows along X, stepping over in Y.
fn raster() -> Vec<P3> {
    let mut path = Vec::new();
    for j in 0..6 {
        let y = j as f64 * 2.0;
        for i in 0..=120 {
            let i = if j % 2 == 0 { i } else { 120 - i };
            let x = i as f64 * 0.25;
            path.push(P3::new(x, y, 2.0 * (x / 5.0).sin() * (y / 7.0).cos()));
        }
    }
    path
}

fn blocks(f: &fit::Fitted) -> Vec<&NurbsBlock> {
    f.pieces
        .iter()
        .filter_map(|p| match p {
            FitPiece::Nurbs(b) => Some(b),
            FitPiece::Lines(_) => None,
        })
        .collect()
}

#[test]
fn blocks_are_valid_interp_core_curves_within_tolerance() {
    let q = raster();
    let cfg = FitConfig::default();
    let f = fit::fit(&q, &cfg).unwrap();
    // Six rows, joined by five step-over moves kept as lines.
    assert_eq!(f.nurbs_blocks, 6);
    assert_eq!(f.line_moves, 5);
    assert!(f.max_deviation <= cfg.tolerance);
    assert!(f.compression > 20.0, "compression {}", f.compression);
    for b in blocks(&f) {
        assert!(b.degree <= 5 && b.weights.iter().all(|&w| w > 0.0));
        validate_program_curve(b.degree, &b.control_points, &b.weights, &b.knots).unwrap();
        // interp-core's own evaluation (after its exact split into
        // capacity-sized segments) gives the same points as ours.
        let mut segs = Vec::new();
        split_program_curve::<()>(b.degree, &b.control_points, &b.weights, &b.knots, 12, |s| {
            segs.push(s);
            Ok(())
        })
        .unwrap();
        for s in &segs {
            for k in 0..=10 {
                let u = s.u_start() + (s.u_end() - s.u_start()) * k as f64 / 10.0;
                let theirs = s.eval(u, 0).p;
                let ours = b.point(u);
                assert!((theirs - ours.coords).norm() < 1e-9, "u = {u}");
            }
        }
    }
    // Every CL point is within the tolerance of the fitted path: distance to
    // the curve by a dense search refined by golden section on the parameter
    // (independent of the parameters the fit used).
    const SAMPLES: usize = 2000;
    let bs = blocks(&f);
    for p in &q {
        let mut best = f64::INFINITY;
        for b in &bs {
            let d = |u: f64| (b.point(u.clamp(0.0, 1.0)) - p).norm();
            let i = (0..=SAMPLES)
                .min_by(|&a, &c| {
                    d(a as f64 / SAMPLES as f64).total_cmp(&d(c as f64 / SAMPLES as f64))
                })
                .unwrap();
            let (lo, hi) = (
                (i as f64 - 1.0) / SAMPLES as f64,
                (i as f64 + 1.0) / SAMPLES as f64,
            );
            best = best.min(interp_core::geom::golden_section_min(d, lo, hi, 60, 0.0));
        }
        assert!(best <= cfg.tolerance, "{p}: {best}");
    }
}

#[test]
fn translated_and_scaled_inputs_give_transformed_blocks() {
    let q = raster();
    let cfg = FitConfig::default();
    let base = fit::fit(&q, &cfg).unwrap();
    let shift = V3::new(-40.0, 13.0, 5.0);
    let moved = fit::fit(&q.iter().map(|p| p + shift).collect::<Vec<_>>(), &cfg).unwrap();
    for (a, b) in blocks(&base).iter().zip(blocks(&moved)) {
        assert_eq!(a.control_points.len(), b.control_points.len());
        for (pa, pb) in a.control_points.iter().zip(&b.control_points) {
            let d = (V3::from(*pb) - V3::from(*pa) - shift).norm();
            assert!(d < 1e-7, "{d}");
        }
    }
    // Scaling the path and the tolerance by 2 gives the same knots.
    let scaled = fit::fit(
        &q.iter()
            .map(|p| P3::from(p.coords * 2.0))
            .collect::<Vec<_>>(),
        &FitConfig {
            tolerance: 2.0 * cfg.tolerance,
            ..cfg
        },
    )
    .unwrap();
    for (a, b) in blocks(&base).iter().zip(blocks(&scaled)) {
        assert_eq!(a.knots.len(), b.knots.len());
        for (ka, kb) in a.knots.iter().zip(&b.knots) {
            assert!((ka - kb).abs() < 1e-12);
        }
    }
    // Reversed: same block count, still within tolerance.
    let rev: Vec<P3> = q.iter().rev().copied().collect();
    let r = fit::fit(&rev, &cfg).unwrap();
    assert_eq!(r.nurbs_blocks, base.nurbs_blocks);
    assert!(r.max_deviation <= cfg.tolerance);
}

#[test]
fn bad_input_is_named() {
    let q = vec![P3::new(0.0, 0.0, 0.0), P3::new(1.0, f64::NAN, 0.0)];
    assert_eq!(
        fit::fit(&q, &FitConfig::default()).unwrap_err(),
        fit::FitError::NonFinite(1)
    );
    let bad = FitConfig {
        degree: 7,
        ..FitConfig::default()
    };
    let e = fit::fit(&raster(), &bad).unwrap_err();
    assert!(e.to_string().contains("degree"));
    // Duplicates and a single point are not an error.
    let dup = vec![P3::origin(), P3::origin(), P3::new(1.0, 0.0, 0.0)];
    let f = fit::fit(&dup, &FitConfig::default()).unwrap();
    assert_eq!(f.line_moves, 1);
    assert!(
        fit::fit(&[P3::origin()], &FitConfig::default())
            .unwrap()
            .pieces
            .is_empty()
    );
}

/// A corrected row: uneven spacing (a 4.4 µm first span, as gouge correction
/// leaves them), a lifted stretch and a step. A least-squares curve that only
/// meets the points may swing far away between them; the fit must stay near
/// the straight moves it replaces everywhere, not only at the CL points.
#[test]
fn fitted_curves_stay_near_the_polyline_between_cl_points() {
    let mut q = vec![P3::new(0.0, 0.0, 0.0), P3::new(0.0044, 0.0, 0.0)];
    let mut x = 0.0044;
    let mut i = 0;
    while x < 40.0 {
        i += 1;
        x += if i % 7 == 0 {
            0.05
        } else {
            0.4 + 0.3 * ((i as f64) * 1.3).sin().abs()
        };
        let lift = if (12.0..18.0).contains(&x) { 0.8 } else { 0.0 };
        let step = if x > 30.0 { -0.3 } else { 0.0 };
        q.push(P3::new(x, 0.01 * x, 0.2 * (x / 3.0).sin() + lift + step));
    }
    let cfg = FitConfig::default();
    let f = fit::fit(&q, &cfg).unwrap();
    assert!(f.max_deviation <= cfg.tolerance);
    // Between CL points: within the tolerance plus the span's sagitta
    // allowance of its chord (dense samples; the fit checks three per span).
    let turn = |i: usize| {
        if i == 0 || i + 1 >= q.len() {
            return 0.0;
        }
        let (u, v) = (q[i] - q[i - 1], q[i + 1] - q[i]);
        (u.dot(&v) / (u.norm() * v.norm())).clamp(-1.0, 1.0).acos()
    };
    let mut worst = 0.0f64;
    for b in blocks(&f) {
        // The CL points this block replaces (its ends are CL points), and
        // chord-length parameters over them.
        let (u0, u1) = (b.knots[b.degree], b.knots[b.knots.len() - b.degree - 1]);
        let near = |p: P3| {
            (0..q.len())
                .min_by(|&x, &y| (q[x] - p).norm().total_cmp(&(q[y] - p).norm()))
                .unwrap()
        };
        let (first, last) = (near(b.point(u0)), near(b.point(u1)));
        assert!(first < last);
        let total: f64 = q[first..=last]
            .windows(2)
            .map(|s| (s[1] - s[0]).norm())
            .sum();
        let mut acc = 0.0;
        for i in first..last {
            let len = (q[i + 1] - q[i]).norm();
            let allowed =
                cfg.tolerance + fit::SAGITTA_ALLOWANCE * len * turn(i).max(turn(i + 1)) / 8.0;
            for k in 1..16 {
                let u = u0 + (u1 - u0) * (acc + len * k as f64 / 16.0) / total;
                let p = b.point(u);
                let ab = q[i + 1] - q[i];
                let t = ((p - q[i]).dot(&ab) / ab.norm_squared()).clamp(0.0, 1.0);
                let d = (p - (q[i] + ab * t)).norm();
                worst = worst.max(d / allowed);
            }
            acc += len;
        }
    }
    // Checked at three points per span; between them a cubic cannot stray far.
    assert!(
        worst <= 2.0,
        "curve strays {worst} × the allowance from a span"
    );
}
