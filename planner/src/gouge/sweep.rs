//! The cutter's lower surface and the lowest point of a swept cutter above a
//! point: the one geometric primitive that detection (§2.1), correction (§2.2)
//! and milled-surface prediction (§3) share.
//!
//! A 3-axis cutter with its tip at `c` occupies every point above its lower
//! surface `z = c.z + h(r)` within radius `R` of its axis, where `r` is the
//! horizontal distance to the axis (the shank is taken as infinitely long).
//! Moving the tip linearly from `a` to `b`, the lowest point of the swept
//! volume above a horizontal position `e` is `min_t z(t) + h(r(t))`. `r(t)` is
//! convex in `t` and `h` is convex and increasing, so that function is convex
//! and a golden-section search finds its minimum.

use interp_core::geom::golden_section_argmin;

use crate::cutter::Cutter;
use crate::mesh::P3;

/// Golden-section iterations: the bracket shrinks by 0.618 each step, so 60
/// steps take a unit interval below 1e-12, beyond any machining resolution.
const GOLDEN_STEPS: usize = 60;

/// Segments whose horizontal length is below this (mm) are plunges: the
/// horizontal distance to the axis does not change along them.
const PLUNGE_XY_LEN: f64 = 1e-12;

/// Height of the cutter's lower surface above its tip at radial distance `r`
/// from the axis, or `None` beyond the cutter's radius (eq. 10 and 11).
#[inline]
pub fn profile_height(cutter: &Cutter, r: f64) -> Option<f64> {
    let big_r = cutter.radius();
    if !(r <= big_r) {
        return None;
    }
    Some(match *cutter {
        Cutter::Ball { .. } => big_r - (big_r * big_r - r * r).max(0.0).sqrt(),
        Cutter::Flat { .. } => 0.0,
        Cutter::Bull { corner_radius, .. } => {
            let inner = big_r - corner_radius;
            if r <= inner {
                0.0
            } else {
                let s = r - inner;
                corner_radius - (corner_radius * corner_radius - s * s).max(0.0).sqrt()
            }
        }
    })
}

/// Height of the tip when the cutter, lowered along its axis at the
/// horizontal position of `tip_xy`, first touches the point `q`; `None` when `q`
/// is outside the cutter's radius (eq. 7 for a ball, generalised).
#[inline]
pub fn touch_height(cutter: &Cutter, tip_x: f64, tip_y: f64, q: &P3) -> Option<f64> {
    let r = (tip_x - q.x).hypot(tip_y - q.y);
    profile_height(cutter, r).map(|h| q.z - h)
}

/// The lowest point of the volume swept by moving the tip from `a` to `b`,
/// above the horizontal position `(x, y)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SweptBottom {
    /// Height of the swept lower surface, mm.
    pub z: f64,
    /// Where along the move (0 at `a`, 1 at `b`) the cutter is lowest there.
    pub t: f64,
}

/// Horizontal distance from `(x, y)` to the segment `a`–`b` projected on XY.
#[inline]
pub fn xy_distance_to_segment(a: &P3, b: &P3, x: f64, y: f64) -> f64 {
    let (ux, uy) = (b.x - a.x, b.y - a.y);
    let (wx, wy) = (x - a.x, y - a.y);
    let uu = ux * ux + uy * uy;
    let t = if uu > 0.0 {
        ((wx * ux + wy * uy) / uu).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (wx - t * ux).hypot(wy - t * uy)
}

/// Lowest point of the swept cutter above `(x, y)` for the move `a → b`, or
/// `None` when the cutter never passes over that position.
pub fn swept_bottom(cutter: &Cutter, a: &P3, b: &P3, x: f64, y: f64) -> Option<SweptBottom> {
    let big_r = cutter.radius();
    let (ux, uy) = (b.x - a.x, b.y - a.y);
    let (wx, wy) = (x - a.x, y - a.y);
    let uu = ux * ux + uy * uy;
    let ww = wx * wx + wy * wy;
    // Parameters where the axis is within R of (x, y): |w - t u|² <= R².
    let (lo, hi) = if uu.sqrt() < PLUNGE_XY_LEN {
        if ww > big_r * big_r {
            return None;
        }
        (0.0, 1.0)
    } else {
        let wu = wx * ux + wy * uy;
        let disc = wu * wu - uu * (ww - big_r * big_r);
        if disc < 0.0 {
            return None;
        }
        let root = disc.sqrt();
        let (t0, t1) = ((wu - root) / uu, (wu + root) / uu);
        let (lo, hi) = (t0.max(0.0), t1.min(1.0));
        if lo > hi {
            return None;
        }
        (lo, hi)
    };
    let dz = b.z - a.z;
    match *cutter {
        // A flat end: the swept bottom is linear in t, lowest at an end.
        Cutter::Flat { .. } => {
            let (zl, zh) = (a.z + lo * dz, a.z + hi * dz);
            return Some(if zl <= zh {
                SweptBottom { z: zl, t: lo }
            } else {
                SweptBottom { z: zh, t: hi }
            });
        }
        Cutter::Ball { .. } => {
            let s = ball_bottom(big_r, a, b, x, y);
            // Within reach, but round-off at the very rim may miss both.
            if s.z.is_finite() {
                return Some(s);
            }
        }
        Cutter::Bull { .. } => {}
    }
    let f = |t: f64| {
        let r = (wx - t * ux).hypot(wy - t * uy);
        // Round-off at the bracket ends may put r a hair beyond R.
        let h = profile_height(cutter, r.min(big_r)).unwrap_or(0.0);
        a.z + t * dz + h
    };
    let (t, z) = golden_min(f, lo, hi);
    Some(SweptBottom { z, t })
}

/// Closed form for a ball: the lowest point of the capsule of radius `r`
/// around the centre segment, above `(x, y)` (which must be within reach). It
/// is on the sphere at an end or on the cylinder between them (eq. 4–5).
fn ball_bottom(r: f64, a: &P3, b: &P3, x: f64, y: f64) -> SweptBottom {
    let sphere = |c: &P3| {
        let s = r * r - (x - c.x).powi(2) - (y - c.y).powi(2);
        if s >= 0.0 {
            c.z + r - s.sqrt()
        } else {
            f64::INFINITY
        }
    };
    let (za, zb) = (sphere(a), sphere(b));
    let mut best = if za <= zb {
        SweptBottom { z: za, t: 0.0 }
    } else {
        SweptBottom { z: zb, t: 1.0 }
    };
    let (dx, dy, dz) = (b.x - a.x, b.y - a.y, b.z - a.z);
    let horiz = dx * dx + dy * dy;
    if horiz.sqrt() < PLUNGE_XY_LEN {
        return best;
    }
    let dd = horiz + dz * dz;
    let (wx, wy) = (x - a.x, y - a.y);
    let k = wx * dx + wy * dy;
    let s = wx * wx + wy * wy;
    // |w|² D − (w·d)² = R² D, a quadratic in the height w_z above a's centre.
    let quarter_disc = (k * dz).powi(2) - horiz * ((s - r * r) * dd - k * k);
    if quarter_disc >= 0.0 {
        let wz = (k * dz - quarter_disc.sqrt()) / horiz;
        let t = (k + wz * dz) / dd;
        if (0.0..=1.0).contains(&t) {
            // Back from the centre frame: a's centre is at a.z + r.
            let z = a.z + r + wz;
            if z < best.z {
                best = SweptBottom { z, t };
            }
        }
    }
    best
}

/// Minimum of a convex function on `[lo, hi]`: the one golden-section
/// search (`interp_core::geom::golden_section_argmin`, to 4 ulps of the unit
/// parameter), then the ends, which win only when strictly lower (the
/// minimum of a flat cutter's sweep is often at an end). On a flat bottom
/// (ties) the first point the search saw is kept.
fn golden_min(f: impl Fn(f64) -> f64, lo: f64, hi: f64) -> (f64, f64) {
    let mut best = golden_section_argmin(&f, lo, hi, GOLDEN_STEPS, f64::EPSILON * 4.0);
    for t in [lo, hi] {
        let v = f(t);
        if v < best.1 {
            best = (t, v);
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ball(r: f64) -> Cutter {
        Cutter::Ball { diameter: 2.0 * r }
    }

    /// Distance from a point to a 3D segment, the ball's own test (eq. 4–5).
    fn dist_to_segment(a: &P3, b: &P3, q: &P3) -> f64 {
        let v1 = b - a;
        let v2 = q - a;
        let t = (v1.dot(&v2) / v1.norm_squared()).clamp(0.0, 1.0);
        (v2 - v1 * t).norm()
    }

    #[test]
    fn horizontal_ball_move_matches_eq_10() {
        let c = ball(10.0);
        let a = P3::new(0.0, 0.0, 1.0);
        let b = P3::new(20.0, 0.0, 1.0);
        // Inside the rectangle: f is the foot of the perpendicular.
        let s = swept_bottom(&c, &a, &b, 7.0, 6.0).unwrap();
        let expect = 1.0 + 10.0 - (100.0f64 - 36.0).sqrt();
        assert!((s.z - expect).abs() < 1e-9, "{} vs {expect}", s.z);
        assert!((s.t - 0.35).abs() < 1e-6);
        // In the end circle: f is replaced by b.
        let s = swept_bottom(&c, &a, &b, 26.0, 0.0).unwrap();
        assert!((s.z - (1.0 + 10.0 - 8.0)).abs() < 1e-9);
        assert_eq!(s.t, 1.0);
        assert!(swept_bottom(&c, &a, &b, 31.0, 0.0).is_none());
        assert!(swept_bottom(&c, &a, &b, 5.0, 10.5).is_none());
    }

    #[test]
    fn sloped_ball_sweep_agrees_with_capsule_distance() {
        // A point touches the swept ball iff its distance to the centre segment
        // is R: check the vertical envelope against that independent test.
        let c = ball(5.0);
        let a = P3::new(-3.0, 1.0, 0.0);
        let b = P3::new(9.0, -2.0, 4.0);
        let lift = nalgebra::Vector3::new(0.0, 0.0, 5.0);
        for i in 0..40 {
            for j in 0..40 {
                let x = -9.0 + 0.55 * i as f64;
                let y = -7.0 + 0.4 * j as f64;
                if let Some(s) = swept_bottom(&c, &a, &b, x, y) {
                    let d = dist_to_segment(&(a + lift), &(b + lift), &P3::new(x, y, s.z));
                    assert!((d - 5.0).abs() < 1e-7, "({x},{y}): d = {d}");
                } else {
                    let d = xy_distance_to_segment(&a, &b, x, y);
                    assert!(d > 5.0 - 1e-9);
                }
            }
        }
    }

    /// A bull cutter moving level has a flat bottom (its flat disc) over a
    /// range of `t`: the search's ties keep the first point it saw there,
    /// which is on the flat (the exact height), and a lower end still wins.
    #[test]
    fn level_bull_sweep_ties_keep_a_point_on_the_flat() {
        let bull = Cutter::Bull {
            diameter: 10.0,
            corner_radius: 2.0,
        };
        let (a, b) = (P3::new(0.0, 0.0, 1.0), P3::new(20.0, 0.0, 1.0));
        // 2 mm off the path: within the flat (radius 3) for t in [0.138, 0.362].
        let s = swept_bottom(&bull, &a, &b, 5.0, 2.0).unwrap();
        assert_eq!(s.z, 1.0);
        let along = (0.0..=1.0).contains(&s.t) && (20.0 * s.t - 5.0).hypot(2.0) <= 3.0;
        assert!(along, "t = {}", s.t);
        // 4 mm past the end only the end's torus reaches the point: t = 1,
        // the ends compared after the search.
        let s = swept_bottom(&bull, &a, &b, 24.0, 0.0).unwrap();
        assert_eq!(s.t, 1.0);
        assert!((s.z - (3.0 - 3f64.sqrt())).abs() < 1e-12, "{}", s.z);
        // The search's tie rule: of equal values the first seen stays.
        let (t, v) = golden_min(|_| 3.0, 0.0, 1.0);
        assert_eq!(v, 3.0);
        assert_eq!(t, 1.0 - 0.618_033_988_749_894_9);
    }

    #[test]
    fn flat_and_bull_profiles() {
        let flat = Cutter::Flat { diameter: 10.0 };
        let bull = Cutter::Bull {
            diameter: 10.0,
            corner_radius: 2.0,
        };
        assert_eq!(profile_height(&flat, 4.99), Some(0.0));
        assert_eq!(profile_height(&flat, 5.01), None);
        assert_eq!(profile_height(&bull, 3.0), Some(0.0));
        assert!((profile_height(&bull, 5.0).unwrap() - 2.0).abs() < 1e-12);
        let h = profile_height(&bull, 4.0).unwrap();
        assert!((h - (2.0 - 3.0f64.sqrt())).abs() < 1e-12);
        // A sloped flat move: the lowest point over a position is where the
        // lower end of the disc passes it.
        let a = P3::new(0.0, 0.0, 0.0);
        let b = P3::new(10.0, 0.0, 10.0);
        let s = swept_bottom(&flat, &a, &b, 3.0, 4.0).unwrap();
        assert!((s.z - 0.0).abs() < 1e-9 && s.t == 0.0);
        let s = swept_bottom(&flat, &a, &b, 12.0, 0.0).unwrap();
        assert!((s.z - 7.0).abs() < 1e-9, "{}", s.z);
    }
}
