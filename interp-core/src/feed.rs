//! The seed's pointwise feed laws (seed 004, §2–3) and their combination.
//!
//! All speeds in mm/s, lengths in mm, times in s.

use crate::config::InterpConfig;
use crate::geom::{Derivs, Vec3};
use crate::path::{MrrParams, ToolSide};

/// Chord-error law, eq. 16–17 without the cap: the speed at which one tick's
/// chord on the osculating circle of radius `r = 1/k` deviates from the
/// circle by exactly `er`:
/// `V = (2/Ts)·sqrt(r² − (r − ER)²) = (2/Ts)·sqrt(ER·(2r − ER))`.
///
/// Written in the second form because `r² − (r − ER)²` cancels badly for
/// `r ≫ ER`. Straight (`k = 0`) gives infinity. Where `r ≤ ER` the whole
/// circle fits in the tolerance and the chord is bounded by the diameter.
#[inline]
pub fn chord_error_speed(k: f64, er: f64, ts: f64) -> f64 {
    let k = libm::fabs(k);
    if k == 0.0 {
        return f64::INFINITY;
    }
    let r = 1.0 / k;
    if er >= r {
        return 2.0 * r / ts;
    }
    2.0 / ts * libm::sqrt(er * (2.0 * r - er))
}

/// Largest chord error of a chord of length `l` on a circle of curvature `k`
/// (eq. 15): `r − sqrt(r² − (l/2)²)`, in a cancellation-free form.
#[inline]
pub fn circle_chord_error(k: f64, l: f64) -> f64 {
    let k = libm::fabs(k);
    let h = 0.5 * l;
    if k == 0.0 {
        return 0.0;
    }
    let r = 1.0 / k;
    if h >= r {
        return r;
    }
    // r − sqrt(r² − h²) = h² / (r + sqrt(r² − h²))
    h * h / (r + libm::sqrt(r * r - h * h))
}

/// Constant material-removal-rate law, eq. 23: `V = F0 / (1 + k·(rt − δ/2))`,
/// `k > 0` concave (centre of curvature on the tool side), `k < 0` convex.
///
/// A non-positive denominator (very convex) puts no limit (infinity); the
/// programmed feed still caps the combined law.
#[inline]
pub fn mrr_speed(f0: f64, k_signed: f64, tool_radius: f64, depth_of_cut: f64) -> f64 {
    let den = 1.0 + k_signed * (tool_radius - 0.5 * depth_of_cut);
    if den <= 0.0 { f64::INFINITY } else { f0 / den }
}

/// Material removal rate relative to straight-line cutting at `f0`
/// (eq. 18–22): `V·(1 + k·(rt − δ/2)) / F0`. Exactly 1 where the MRR law is binding.
#[inline]
pub fn relative_mrr(v: f64, f0: f64, k_signed: f64, tool_radius: f64, depth_of_cut: f64) -> f64 {
    v * (1.0 + k_signed * (tool_radius - 0.5 * depth_of_cut)) / f0
}

/// Curvature signed for the MRR law: `+|k|` when the centre of curvature lies
/// on the tool side (concave), `−|k|` when opposite (convex), 0 when the
/// principal normal is perpendicular to the tool side.
#[inline]
pub fn signed_curvature(d: &Derivs, side: ToolSide) -> f64 {
    let k = d.curvature();
    let Some(n) = d.principal_normal() else {
        return 0.0;
    };
    let to_tool = match side {
        ToolSide::Direction(v) => Vec3::new(v[0], v[1], v[2]),
        ToolSide::LeftOfPath(pn) => Vec3::new(pn[0], pn[1], pn[2]).cross(&d.d1),
        ToolSide::RightOfPath(pn) => d.d1.cross(&Vec3::new(pn[0], pn[1], pn[2])),
    };
    let s = n.dot(&to_tool);
    if s > 0.0 {
        k
    } else if s < 0.0 {
        -k
    } else {
        0.0
    }
}

/// The speed limit at one point of a block: the minimum of the programmed
/// feed, the machine's path-speed limit and every law that is switched on.
#[inline]
pub fn speed_limit(d: &Derivs, feed: f64, mrr: Option<&MrrParams>, cfg: &InterpConfig) -> f64 {
    let mut v = feed.min(cfg.max_path_speed);
    if cfg.chord_error_law {
        v = v.min(chord_error_speed(
            d.curvature(),
            cfg.chord_tolerance,
            cfg.period,
        ));
    }
    if let (true, Some(m)) = (cfg.mrr_law, mrr) {
        let ks = signed_curvature(d, m.tool_side);
        v = v.min(mrr_speed(feed, ks, m.tool_radius, m.depth_of_cut));
    }
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chord_law_gives_exactly_er_on_the_circle() {
        // Property table: (k, ER, Ts)
        for &(k, er, ts) in &[
            (1.0, 1e-3, 1e-3),
            (0.1, 1e-3, 1e-3),
            (10.0, 1e-4, 5e-4),
            (1e-4, 1e-3, 1e-3),
        ] {
            let v = chord_error_speed(k, er, ts);
            let e = circle_chord_error(k, v * ts);
            assert!(
                (e - er).abs() <= 1e-12 * er.max(1e-3),
                "k={k} e={e} er={er}"
            );
        }
        assert_eq!(chord_error_speed(0.0, 1e-3, 1e-3), f64::INFINITY);
        // Tiny radius: chord bounded by the diameter.
        assert_eq!(chord_error_speed(1e4, 1e-3, 1e-3), 2.0 * 1e-4 / 1e-3);
    }

    #[test]
    fn chord_law_scales_with_units() {
        // Metamorphic: lengths ×s (mm → other unit) scale the speed by s.
        let (k, er, ts) = (0.37, 2e-3, 1e-3);
        let s = 1.0 / 25.4;
        let v = chord_error_speed(k, er, ts);
        let vs = chord_error_speed(k / s, er * s, ts);
        assert!((vs - v * s).abs() <= 1e-12 * v);
    }

    #[test]
    fn mrr_law_signs_and_constant_mrr() {
        let (f0, rt, dc) = (100.0, 5.0, 1.0);
        assert_eq!(mrr_speed(f0, 0.0, rt, dc), f0);
        assert!(mrr_speed(f0, 0.05, rt, dc) < f0, "concave slows down");
        assert!(mrr_speed(f0, -0.05, rt, dc) > f0, "convex speeds up");
        for &k in &[-0.2, -0.05, 0.0, 0.01, 0.3] {
            let v = mrr_speed(f0, k, rt, dc);
            assert!((relative_mrr(v, f0, k, rt, dc) - 1.0).abs() < 1e-14);
        }
        assert_eq!(mrr_speed(f0, -1.0, rt, dc), f64::INFINITY);
    }

    #[test]
    fn signed_curvature_follows_tool_side() {
        // CCW unit circle in XY at angle 0: centre at origin, point (1,0).
        let d = Derivs {
            p: Vec3::new(1.0, 0.0, 0.0),
            d1: Vec3::new(0.0, 1.0, 0.0),
            d2: Vec3::new(-1.0, 0.0, 0.0),
            d3: Vec3::zeros(),
        };
        let z = [0.0, 0.0, 1.0];
        // Tool left of a CCW path = inside the circle = concave.
        assert!((signed_curvature(&d, ToolSide::LeftOfPath(z)) - 1.0).abs() < 1e-15);
        assert!((signed_curvature(&d, ToolSide::RightOfPath(z)) + 1.0).abs() < 1e-15);
        assert!((signed_curvature(&d, ToolSide::Direction([-1.0, 0.0, 0.0])) - 1.0).abs() < 1e-15);
        assert_eq!(
            signed_curvature(&d, ToolSide::Direction([0.0, 0.0, 1.0])),
            0.0
        );
    }
}
