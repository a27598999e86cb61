//! A long 3-D rational cubic, made by formula: the curve of the loop's tick
//! benches, and a five-axis regression test that runs it with a turning tool.
//!
//! 30 control points on a helix of varying radius (20 ± 6 mm, 0.55 rad and
//! 1.5 mm of rise per control point, ≈ 2.5 turns), weights
//! `1.25 + 0.75·sin(2.3·i + 0.4)` ∈ [0.5, 2], a clamped knot vector with
//! non-uniform interior spacing. About 330 mm long; its curvature varies
//! along it, and so does its parametric speed (weights and knots).
//! Deterministic: no random numbers, the same curve on any machine.

use crate::nurbs::Nurbs;

/// Control points of [`rational_cubic`].
pub const CUBIC_CTRL: usize = 30;
/// Degree of [`rational_cubic`].
pub const CUBIC_DEGREE: usize = 3;

/// The curve (see the module docs).
pub fn rational_cubic() -> Nurbs {
    let mut pts = [[0.0; 3]; CUBIC_CTRL];
    let mut w = [0.0; CUBIC_CTRL];
    for i in 0..CUBIC_CTRL {
        let t = i as f64;
        let th = 0.55 * t;
        let r = 20.0 + 6.0 * libm::sin(0.9 * t);
        pts[i] = [r * libm::cos(th), r * libm::sin(th), 1.5 * t];
        w[i] = 1.25 + 0.75 * libm::sin(2.3 * t + 0.4);
    }
    let n_knots = CUBIC_CTRL + CUBIC_DEGREE + 1;
    let mut knots = [0.0; CUBIC_CTRL + CUBIC_DEGREE + 1];
    let interior = n_knots - 2 * (CUBIC_DEGREE + 1);
    let mut acc = 0.0;
    for j in 0..interior {
        acc += 1.0 + 0.3 * libm::sin(1.3 * j as f64);
        knots[CUBIC_DEGREE + 1 + j] = acc;
    }
    acc += 1.0;
    for k in knots.iter_mut().skip(n_knots - CUBIC_DEGREE - 1) {
        *k = acc;
    }
    Nurbs::new(CUBIC_DEGREE, &pts, &w, &knots).expect("rational cubic is valid")
}
