//! Measurements on interpolator output, shared by tests, benches and tools.
//!
//! These run outside the RT path; they are exact up to their stated search.

use crate::geom::{Curve, Vec3, golden_section_min};

/// Distance from point `p` to the segment `[a, b]`.
#[inline]
pub fn point_segment_distance(p: Vec3, a: Vec3, b: Vec3) -> f64 {
    let ab = b - a;
    let l2 = ab.norm_squared();
    if l2 == 0.0 {
        return (p - a).norm();
    }
    let t = ((p - a).dot(&ab) / l2).clamp(0.0, 1.0);
    (p - (a + ab * t)).norm()
}

/// Largest distance between the curve piece `C([u0, u1])` and the chord from
/// `C(u0)` to `C(u1)`: the chord error of one tick.
///
/// Dense sampling (`samples` points) brackets the maximum, then a
/// golden-section search refines it to ~1e-12 of the parameter interval.
pub fn chord_error<C: Curve + ?Sized>(curve: &C, u0: f64, u1: f64, samples: usize) -> f64 {
    let a = curve.eval(u0, 0).p;
    let b = curve.eval(u1, 0).p;
    chord_error_between(curve, u0, u1, a, b, samples)
}

/// [`chord_error`] with the chord's end points given (e.g. setpoints).
pub fn chord_error_between<C: Curve + ?Sized>(
    curve: &C,
    u0: f64,
    u1: f64,
    a: Vec3,
    b: Vec3,
    samples: usize,
) -> f64 {
    if u1 <= u0 {
        return 0.0;
    }
    let n = samples.max(2);
    let dist = |u: f64| point_segment_distance(curve.eval(u, 0).p, a, b);
    let mut best = (0.0, u0);
    for i in 0..=n {
        let u = u0 + (u1 - u0) * (i as f64 / n as f64);
        let d = dist(u);
        if d > best.0 {
            best = (d, u);
        }
    }
    // Golden-section refinement around the best sample.
    let h = (u1 - u0) / n as f64;
    let (lo, hi) = ((best.1 - h).max(u0), (best.1 + h).min(u1));
    let refined = -golden_section_min(|u| -dist(u), lo, hi, 80, 1e-12 * (u1 - u0));
    best.0.max(refined)
}

/// Feed fluctuation of one tick (seed 004): `|chord| / Δ − 1`, with `Δ` the
/// commanded displacement.
#[inline]
pub fn feed_fluctuation(a: Vec3, b: Vec3, delta: f64) -> f64 {
    (b - a).norm() / delta - 1.0
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::path::{Arc, Line};

    #[test]
    fn chord_error_of_a_circle_matches_the_sagitta() {
        let arc = Arc::from_centre(
            Vec3::new(10.0, 0.0, 0.0),
            Vec3::new(-10.0, 0.0, 0.0),
            Vec3::zeros(),
            Vec3::z(),
            0,
        )
        .unwrap();
        for &dth in &[1e-3, 1e-2, 0.1, 0.5] {
            let e = chord_error(&arc, 0.3, 0.3 + dth, 16);
            let sagitta = 10.0 * (1.0 - libm::cos(dth / 2.0));
            assert!(
                (e - sagitta).abs() <= 1e-12 * 10.0,
                "dth={dth} e={e} s={sagitta}"
            );
        }
    }

    #[test]
    fn chord_error_of_a_line_is_zero() {
        let l = Line::new(Vec3::zeros(), Vec3::new(3.0, 4.0, 12.0)).unwrap();
        assert!(chord_error(&l, 1.0, 7.0, 8) < 1e-15);
    }
}
