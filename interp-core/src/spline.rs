//! The planned speed: `v(s)² = S(s)`, a C¹ quadratic spline in arc length,
//! and its exact motion in time.
//!
//! On a piece `[x0, x0 + h]` the spline is the quadratic with Bernstein
//! coefficients `(e0, d, e1)`: `S = e0·(1−u)² + 2d·u(1−u) + e1·u²`,
//! `u = (s − x0)/h`. Written as `S = α·x² + β·x + γ` in the piece's own
//! coordinate `x = s − x0`, a motion that keeps `ṡ² = S(s)` obeys
//! `s̈ = S'(s)/2 = α·x + β/2`: a linear ODE with the closed-form solution
//!
//! ```text
//! x(t) = x0 + v0·C1(t) + a0·C2(t),   v(t) = v0·C0(t) + a0·C1(t)
//! C0 = cosh ωt, C1 = sinh ωt / ω, C2 = (cosh ωt − 1)/ω²   (α = ω² > 0; cos/sin for α < 0)
//! ```
//!
//! so the tick moves along the plan exactly, with no integration error. The
//! acceleration `a = α·x + β/2` is continuous (the spline is C¹ at its
//! knots, C⁰ at rest points), and the jerk `ȧ = α·v` is bounded piecewise:
//! the schedule's jerk limits are limits on `α` ([`crate::plan`]).

/// One piece of the planned speed profile.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Piece {
    /// Arc length of the run where the piece starts, mm.
    pub x0: f64,
    /// Length, mm (> 0).
    pub h: f64,
    /// `S` at the start, (mm/s)².
    pub e0: f64,
    /// Middle Bernstein coefficient, (mm/s)².
    pub d: f64,
    /// `S` at the end, (mm/s)².
    pub e1: f64,
}

impl Piece {
    /// Arc length where the piece ends.
    #[inline]
    pub fn x1(&self) -> f64 {
        self.x0 + self.h
    }
    /// `α = S''/2`, 1/s².
    #[inline]
    pub fn alpha(&self) -> f64 {
        (self.e0 - 2.0 * self.d + self.e1) / (self.h * self.h)
    }
    /// `β = S'(x0)`, mm/s².
    #[inline]
    pub fn beta(&self) -> f64 {
        2.0 * (self.d - self.e0) / self.h
    }
    /// `S` at local coordinate `x` (mm from the piece start).
    #[inline]
    pub fn s2(&self, x: f64) -> f64 {
        let u = x / self.h;
        let w = 1.0 - u;
        self.e0 * w * w + 2.0 * self.d * u * w + self.e1 * u * u
    }
    /// Planned speed at local coordinate `x`, mm/s.
    #[inline]
    pub fn speed(&self, x: f64) -> f64 {
        libm::sqrt(self.s2(x).max(0.0))
    }
    /// Planned tangential acceleration `S'/2` at local coordinate `x`, mm/s².
    #[inline]
    pub fn accel(&self, x: f64) -> f64 {
        self.alpha() * x + 0.5 * self.beta()
    }
}

/// `(C0, C1, C2)` at time `t` for `α` (see the module docs).
#[inline]
fn c_functions(alpha: f64, t: f64) -> (f64, f64, f64) {
    let z = alpha * t * t;
    if libm::fabs(z) < 0.5 {
        // Series in z = αt²: C0 = Σ zⁿ/(2n)!, C1 = t·Σ zⁿ/(2n+1)!, C2 = t²·Σ zⁿ/(2n+2)!.
        let (mut c0, mut c1, mut c2) = (1.0, 1.0, 0.5);
        let (mut t0, mut t1, mut t2) = (1.0, 1.0, 0.5);
        let mut k = 0.0;
        for _ in 0..12 {
            t0 *= z / ((2.0 * k + 1.0) * (2.0 * k + 2.0));
            t1 *= z / ((2.0 * k + 2.0) * (2.0 * k + 3.0));
            t2 *= z / ((2.0 * k + 3.0) * (2.0 * k + 4.0));
            c0 += t0;
            c1 += t1;
            c2 += t2;
            k += 1.0;
        }
        (c0, c1 * t, c2 * t * t)
    } else if alpha > 0.0 {
        let w = libm::sqrt(alpha);
        let (sh, ch) = (libm::sinh(w * t), libm::cosh(w * t));
        (ch, sh / w, (ch - 1.0) / alpha)
    } else {
        let w = libm::sqrt(-alpha);
        let (sn, cs) = (libm::sin(w * t), libm::cos(w * t));
        (cs, sn / w, (1.0 - cs) / (-alpha))
    }
}

/// Position and speed after time `t` on the closed form, the speed unclamped.
#[inline]
fn state_after(piece: &Piece, x: f64, v: f64, t: f64) -> (f64, f64) {
    let alpha = piece.alpha();
    let a0 = alpha * x + 0.5 * piece.beta();
    let (c0, c1, c2) = c_functions(alpha, t);
    (x + v * c1 + a0 * c2, v * c0 + a0 * c1)
}

/// On a concave piece (`α < 0`, where the closed form oscillates), the
/// first time in `[0, t)` at which the speed reaches zero, if it does:
/// `v(t) = v·cos ωt + (a0/ω)·sin ωt` first vanishes at
/// `atan2(v·ω, −a0)/ω`. (Elsewhere the speed changes sign once at most, and
/// [`rest_time`] finds it.)
fn turn_time(piece: &Piece, x: f64, v: f64, t: f64) -> Option<f64> {
    let alpha = piece.alpha();
    if alpha >= 0.0 {
        return None;
    }
    let w = libm::sqrt(-alpha);
    let a0 = piece.accel(x);
    let tr = libm::atan2(v * w, -a0) / w;
    (tr < t).then_some(tr)
}

/// First time in `(0, t]` at which the speed reaches zero (the motion
/// arrives at a rest point), if it does.
fn rest_time(piece: &Piece, x: f64, v: f64, t: f64) -> Option<f64> {
    let (_, vt) = state_after(piece, x, v, t);
    if vt > 0.0 {
        return None;
    }
    // The speed falls monotonically to zero here (it is √S on a piece that
    // ends at rest): bisect.
    let (mut lo, mut hi) = (0.0, t);
    for _ in 0..80 {
        let m = 0.5 * (lo + hi);
        if state_after(piece, x, v, m).1 > 0.0 {
            lo = m;
        } else {
            hi = m;
        }
    }
    Some(hi)
}

/// Where the motion on `piece`, at local coordinate `x` with speed `v`, is
/// after time `t` (if it stays on the piece): `(x, v)`. A motion that comes
/// to rest within `t` stays at rest.
#[inline]
pub fn advance(piece: &Piece, x: f64, v: f64, t: f64) -> (f64, f64) {
    if let Some(tr) = turn_time(piece, x, v, t) {
        return (state_after(piece, x, v, tr).0, 0.0);
    }
    let (xt, vt) = state_after(piece, x, v, t);
    if vt >= 0.0 {
        return (xt, vt);
    }
    match rest_time(piece, x, v, t) {
        Some(tr) => (state_after(piece, x, v, tr).0, 0.0),
        None => (xt, 0.0),
    }
}

/// Time for the motion on `piece` from local `x` (speed `v`) to reach the
/// piece's end, if it does within `t_max`: `Some(t)`, else `None`. A piece
/// that ends at rest is reached when the speed reaches zero.
pub fn time_to_end(piece: &Piece, x: f64, v: f64, t_max: f64) -> Option<f64> {
    let h = piece.h;
    if x >= h {
        return Some(0.0);
    }
    if piece.e1 <= 0.0 {
        // Ends at rest: the speed reaches zero at the end (a double root of
        // x(t) = h, which Newton would find only slowly).
        return rest_time(piece, x, v, t_max);
    }
    // x(t) increases until the speed turns (on a concave piece the closed
    // form swings back: past the piece's end, where its quadratic falls to
    // zero, within a tick when the piece is short next to the tick's travel).
    let t_max = turn_time(piece, x, v, t_max).unwrap_or(t_max);
    let (x_max, _) = state_after(piece, x, v, t_max);
    if x_max < h {
        return None;
    }
    // Bracketed Newton on x(t) = h; x(t) is increasing while v > 0.
    let (mut lo, mut hi) = (0.0, t_max);
    let a0 = piece.accel(x);
    let mut t = if v > 0.0 {
        ((h - x) / v).min(t_max)
    } else if a0 > 0.0 {
        libm::sqrt(2.0 * (h - x) / a0).min(t_max)
    } else {
        0.5 * t_max
    };
    for _ in 0..100 {
        let (xt, vt) = state_after(piece, x, v, t);
        let f = xt - h;
        if f >= 0.0 {
            hi = t;
        } else {
            lo = t;
        }
        if hi - lo <= 1e-15 * t_max.max(1e-300) {
            break;
        }
        let next = if vt > 0.0 { t - f / vt } else { f64::NAN };
        t = if next > lo && next < hi {
            next
        } else {
            0.5 * (lo + hi)
        };
        if libm::fabs(f) <= 1e-15 * h.max(1.0) && f >= 0.0 {
            break;
        }
    }
    Some(hi)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Fine explicit integration of s̈ = S'(s)/2 (RK4) as the reference.
    fn rk4(p: &Piece, mut x: f64, mut v: f64, t: f64, steps: usize) -> (f64, f64) {
        let dt = t / steps as f64;
        let acc = |x: f64| p.accel(x);
        for _ in 0..steps {
            let (k1x, k1v) = (v, acc(x));
            let (k2x, k2v) = (v + 0.5 * dt * k1v, acc(x + 0.5 * dt * k1x));
            let (k3x, k3v) = (v + 0.5 * dt * k2v, acc(x + 0.5 * dt * k2x));
            let (k4x, k4v) = (v + dt * k3v, acc(x + dt * k3x));
            x += dt / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x);
            v += dt / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v);
        }
        (x, v)
    }

    #[test]
    fn closed_form_motion_matches_integration_and_stays_on_the_spline() {
        // Convex, concave and straight pieces, slow and fast.
        let pieces = [
            Piece {
                x0: 0.0,
                h: 0.25,
                e0: 100.0,
                d: 400.0,
                e1: 900.0,
            },
            Piece {
                x0: 3.0,
                h: 0.25,
                e0: 9000.0,
                d: 9800.0,
                e1: 9100.0,
            },
            Piece {
                x0: 1.0,
                h: 0.5,
                e0: 2500.0,
                d: 2400.0,
                e1: 2600.0,
            },
            Piece {
                x0: 0.0,
                h: 0.25,
                e0: 0.0,
                d: 20.0,
                e1: 400.0,
            },
            Piece {
                x0: 0.0,
                h: 2.0,
                e0: 50.0,
                d: 50.0,
                e1: 50.0,
            },
        ];
        for p in &pieces {
            let x = 0.01;
            let v = p.speed(x);
            for &t in &[1e-4, 1e-3, 2e-3] {
                let (xe, ve) = advance(p, x, v, t);
                let (xr, vr) = rk4(p, x, v, t, 20_000);
                assert!((xe - xr).abs() < 1e-12, "{p:?} t={t}: {xe} vs {xr}");
                assert!(
                    (ve - vr).abs() < 1e-9 * (1.0 + vr),
                    "{p:?} t={t}: {ve} vs {vr}"
                );
                if xe <= p.h {
                    // ṡ² = S(s) is a first integral of the motion.
                    assert!((ve * ve - p.s2(xe)).abs() < 1e-9 * (1.0 + ve * ve), "{p:?}");
                }
            }
        }
    }

    #[test]
    fn leaves_a_rest_point_and_reaches_a_piece_end_in_the_right_time() {
        // From rest with S = β·x + α·x² (e0 = 0): leaves at once.
        let p = Piece {
            x0: 0.0,
            h: 0.25,
            e0: 0.0,
            d: 30.0,
            e1: 500.0,
        };
        let (x, v) = advance(&p, 0.0, 0.0, 1e-3);
        assert!(x > 0.0 && v > 0.0);
        let t = time_to_end(&p, 0.0, 0.0, 10.0).unwrap();
        let (xe, _) = advance(&p, 0.0, 0.0, t);
        assert!((xe - p.h).abs() < 1e-13);
        // The time to the end agrees with ∫ ds/√S.
        let n = 200_000;
        let mut want = 0.0;
        for k in 0..n {
            let (a, b) = (k as f64 * p.h / n as f64, (k + 1) as f64 * p.h / n as f64);
            want += (b - a) * 2.0 / (p.speed(a) + p.speed(b));
        }
        assert!((t - want).abs() < 1e-4 * want, "{t} vs {want}");
        // Arriving at a rest point (e1 = 0) takes a finite time.
        let q = Piece {
            x0: 0.0,
            h: 0.25,
            e0: 400.0,
            d: 30.0,
            e1: 0.0,
        };
        let t = time_to_end(&q, 0.0, 20.0, 10.0).unwrap();
        assert!(t.is_finite() && t > 0.0);
        let (xe, ve) = advance(&q, 0.0, 20.0, t);
        assert!((xe - q.h).abs() < 1e-12 && ve < 1e-3, "{xe} {ve}");
        assert!(time_to_end(&q, 0.0, 20.0, 1e-3).is_none());
    }

    #[test]
    fn a_short_concave_piece_is_left_within_a_long_tick() {
        // 73 µm on which S falls from 65.8 to 18.7 (mm/s)²: the motion crosses
        // it in about 10 ms. Within a 50 ms tick the closed form, taken past
        // the piece's end, turns back and ends below it: the end must be
        // found all the same (the machine stopped there for good).
        let p = Piece {
            x0: 126.464_843_75,
            h: 0.073_242_187_5,
            e0: 65.7638,
            d: 51.7423,
            e1: 18.7134,
        };
        let v0 = libm::sqrt(p.e0);
        let t = time_to_end(&p, 0.0, v0, 0.05).expect("the end within the tick");
        assert!(t > 0.0 && t < 0.02, "t = {t}");
        let (x, v) = state_after(&p, 0.0, v0, t);
        assert!((x - p.h).abs() <= 1e-12, "x = {x}");
        assert!((v - libm::sqrt(p.e1)).abs() <= 1e-9, "v = {v}");
        // Short of the end, the motion stays on the piece at its planned speed.
        let (x, v) = advance(&p, 0.0, v0, 0.5 * t);
        assert!(x > 0.0 && x < p.h);
        assert!(
            (v * v - p.s2(x)).abs() <= 1e-9 * p.e0,
            "v² = {}, S = {}",
            v * v,
            p.s2(x)
        );
    }
}
