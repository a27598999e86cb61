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
//!
//! A piece that leaves a rest point (or reaches one) but does not rest at
//! both ends has the form [`Form::FromRest`] ([`Form::ToRest`]) instead:
//! `S = 3d·u^{4/3} + (e1 − 3d)·u²`, `u` the distance from the rest over
//! `h`. It has the quadratic's end value and end slope (so the spline stays
//! C¹ with the same knot equations), but `S' = 0` at the rest and a finite
//! jerk there, `(2/9)·(3d)^{3/2}/h²`: with `e1 = 3d` it is the jerk-limited
//! start `x = j·t³/6` exactly, where a quadratic's jerk `α·v` vanishes at
//! rest and leaves the jerk limit unused all the way up (a short move's
//! ramps took 1.4× the jerk-limited time). In `w = u^{1/3}` the motion
//! obeys `ẇ² = (3d + (e1 − 3d)·w²)/(9h²)`, a quadratic in `w`, so the same
//! closed form moves along it exactly.

/// How `S` runs between a piece's knot values.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Form {
    /// The quadratic with Bernstein coefficients `(e0, d, e1)`.
    #[default]
    Quadratic,
    /// Leaves a rest point at its start (`e0 = 0`):
    /// `S = 3d·u^{4/3} + (e1 − 3d)·u²`.
    FromRest,
    /// Reaches a rest point at its end (`e1 = 0`): the mirror image,
    /// `S = 3d·u'^{4/3} + (e0 − 3d)·u'²` with `u' = 1 − u`.
    ToRest,
}

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
    /// How `S` runs between the ends.
    pub form: Form,
}

impl Piece {
    /// Arc length where the piece ends.
    #[inline]
    pub fn x1(&self) -> f64 {
        self.x0 + self.h
    }
    /// `α = S''/2` of the quadratic form, 1/s².
    #[inline]
    pub fn alpha(&self) -> f64 {
        (self.e0 - 2.0 * self.d + self.e1) / (self.h * self.h)
    }
    /// `β = S'(x0)` of the quadratic form, mm/s².
    #[inline]
    pub fn beta(&self) -> f64 {
        2.0 * (self.d - self.e0) / self.h
    }
    /// For a ramp form: `w = u'^{1/3}`, `u'` the distance from the rest over
    /// `h`, and `S` at the far end.
    #[inline]
    fn ramp_w(&self, x: f64) -> (f64, f64) {
        let u = (x / self.h).clamp(0.0, 1.0);
        match self.form {
            Form::ToRest => (libm::cbrt(1.0 - u), self.e0),
            _ => (libm::cbrt(u), self.e1),
        }
    }
    /// `S` at local coordinate `x` (mm from the piece start).
    #[inline]
    pub fn s2(&self, x: f64) -> f64 {
        if self.form == Form::Quadratic {
            let u = x / self.h;
            let w = 1.0 - u;
            return self.e0 * w * w + 2.0 * self.d * u * w + self.e1 * u * u;
        }
        let (w, far) = self.ramp_w(x);
        let w2 = w * w;
        w2 * w2 * (3.0 * self.d + (far - 3.0 * self.d) * w2)
    }
    /// Planned speed at local coordinate `x`, mm/s.
    #[inline]
    pub fn speed(&self, x: f64) -> f64 {
        libm::sqrt(self.s2(x).max(0.0))
    }
    /// Planned tangential acceleration `S'/2` at local coordinate `x`, mm/s².
    #[inline]
    pub fn accel(&self, x: f64) -> f64 {
        if self.form == Form::Quadratic {
            return self.alpha() * x + 0.5 * self.beta();
        }
        // dS/du' = 4d·w + 2(far − 3d)·w³; u' runs against x on ToRest.
        let (w, far) = self.ramp_w(x);
        let ds = (4.0 * self.d * w + 2.0 * (far - 3.0 * self.d) * w * w * w) / (2.0 * self.h);
        if self.form == Form::ToRest { -ds } else { ds }
    }
    /// An upper bound of the acceleration anywhere on the piece, mm/s².
    pub fn accel_max(&self) -> f64 {
        let ends = self.accel(0.0).max(self.accel(self.h));
        match self.form {
            // Concave in w when e1 < 3d: the peak 4d·w/3 /h lies inside.
            Form::FromRest => ends.max(4.0 * self.d / (3.0 * self.h)),
            // Its acceleration is monotone or concave in w the other way:
            // extremes at the ends (see `accel`).
            _ => ends,
        }
    }
    /// The motion of a ramp form as a quadratic piece of length 1 in `z`
    /// (`z = w` on FromRest, `1 − w` on ToRest, both running from the start
    /// to the end): `ż² = Q(z)` with `Q = (3d + (far − 3d)·w²)/(9h²)`.
    fn ramp_aux(&self) -> Piece {
        let k = 1.0 / (9.0 * self.h * self.h);
        let at_rest = 3.0 * self.d * k;
        match self.form {
            Form::ToRest => Piece {
                x0: 0.0,
                h: 1.0,
                e0: self.e0 * k,
                d: at_rest,
                e1: at_rest,
                form: Form::Quadratic,
            },
            _ => Piece {
                x0: 0.0,
                h: 1.0,
                e0: at_rest,
                d: at_rest,
                e1: self.e1 * k,
                form: Form::Quadratic,
            },
        }
    }
    /// `z` and `ż` of the motion on the plan at local `x` (ramp forms).
    fn ramp_state(&self, aux: &Piece, x: f64) -> (f64, f64) {
        let (w, _) = self.ramp_w(x);
        let z = if self.form == Form::ToRest {
            1.0 - w
        } else {
            w
        };
        (z, aux.speed(z))
    }
    /// Local `x` and speed from `z`, `ż` (ramp forms): `x = h·w³`, `ẋ = 3h·w²·ẇ`.
    fn ramp_place(&self, z: f64, zd: f64) -> (f64, f64) {
        let z = z.clamp(0.0, 1.0);
        if self.form == Form::ToRest {
            let w = 1.0 - z;
            (self.h * (1.0 - w * w * w), 3.0 * self.h * w * w * zd)
        } else {
            (self.h * z * z * z, 3.0 * self.h * z * z * zd)
        }
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
        // On a concave piece the closed form swings back past the rest at
        // its end: its first turn is that rest. (At rest a round-off short
        // of the end, the turn is now: without it the machine waited there
        // for good.)
        return turn_time(piece, x, v, t);
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
    if piece.form == Form::Quadratic {
        return advance_quadratic(piece, x, v, t);
    }
    let aux = piece.ramp_aux();
    let (z, zd) = piece.ramp_state(&aux, x);
    let (z, zd) = advance_quadratic(&aux, z, zd, t);
    piece.ramp_place(z, zd)
}

#[inline]
fn advance_quadratic(piece: &Piece, x: f64, v: f64, t: f64) -> (f64, f64) {
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
    if piece.form == Form::Quadratic {
        return time_to_end_quadratic(piece, x, v, t_max);
    }
    // (At or past the end, z = 1: the aux piece's end.)
    let aux = piece.ramp_aux();
    let (z, zd) = piece.ramp_state(&aux, x);
    time_to_end_quadratic(&aux, z, zd, t_max)
}

fn time_to_end_quadratic(piece: &Piece, x: f64, v: f64, t_max: f64) -> Option<f64> {
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
                form: Form::Quadratic,
            },
            Piece {
                x0: 3.0,
                h: 0.25,
                e0: 9000.0,
                d: 9800.0,
                e1: 9100.0,
                form: Form::Quadratic,
            },
            Piece {
                x0: 1.0,
                h: 0.5,
                e0: 2500.0,
                d: 2400.0,
                e1: 2600.0,
                form: Form::Quadratic,
            },
            Piece {
                x0: 0.0,
                h: 0.25,
                e0: 0.0,
                d: 20.0,
                e1: 400.0,
                form: Form::Quadratic,
            },
            Piece {
                x0: 0.0,
                h: 2.0,
                e0: 50.0,
                d: 50.0,
                e1: 50.0,
                form: Form::Quadratic,
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
            form: Form::Quadratic,
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
            form: Form::Quadratic,
        };
        let t = time_to_end(&q, 0.0, 20.0, 10.0).unwrap();
        assert!(t.is_finite() && t > 0.0);
        let (xe, ve) = advance(&q, 0.0, 20.0, t);
        assert!((xe - q.h).abs() < 1e-12 && ve < 1e-3, "{xe} {ve}");
        assert!(time_to_end(&q, 0.0, 20.0, 1e-3).is_none());
    }

    /// The ramp forms: `S` from rest as `3d·u^{4/3} + (e1 − 3d)·u²`.
    fn ramps() -> [Piece; 6] {
        let r = |form, e0, d, e1| Piece {
            x0: 2.0,
            h: 0.0625,
            e0,
            d,
            e1,
            form,
        };
        [
            // The pure jerk-limited start (e1 = 3d), one with a longer
            // constant-acceleration tail (e1 < 3d) and one that bends up.
            r(Form::FromRest, 0.0, 50.0, 150.0),
            r(Form::FromRest, 0.0, 50.0, 90.0),
            r(Form::FromRest, 0.0, 20.0, 150.0),
            r(Form::ToRest, 150.0, 50.0, 0.0),
            r(Form::ToRest, 90.0, 50.0, 0.0),
            r(Form::ToRest, 150.0, 20.0, 0.0),
        ]
    }

    #[test]
    fn ramp_forms_keep_the_quadratic_s_end_value_and_slope() {
        for p in ramps() {
            let q = Piece {
                form: Form::Quadratic,
                ..p
            };
            for x in [0.0, p.h] {
                assert!(
                    (p.s2(x) - q.s2(x)).abs() < 1e-12 * (1.0 + q.s2(x)),
                    "{p:?} {x}"
                );
            }
            // The slope at the far end is the quadratic's; at the rest it is 0.
            let (far, rest) = if p.form == Form::FromRest {
                (p.h, 0.0)
            } else {
                (0.0, p.h)
            };
            assert!((p.accel(far) - q.accel(far)).abs() < 1e-9, "{p:?}");
            assert_eq!(p.accel(rest), 0.0, "{p:?}");
            // S stays within the larger of d and the far value (the hull).
            let top = p.d.max(p.e0).max(p.e1);
            for k in 0..=1000 {
                let x = p.h * k as f64 / 1000.0;
                assert!(
                    p.s2(x) >= 0.0 && p.s2(x) <= top * (1.0 + 1e-12),
                    "{p:?} {x}"
                );
                assert!(p.accel(x) <= p.accel_max() + 1e-9, "{p:?} {x}");
            }
        }
    }

    #[test]
    fn ramp_motion_matches_integration_and_leaves_the_rest_with_finite_jerk() {
        for p in ramps() {
            // Inside: the closed form against RK4 on s̈ = S'/2.
            let x = 0.3 * p.h;
            let v = p.speed(x);
            for &t in &[1e-4, 1e-3] {
                let (xe, ve) = advance(&p, x, v, t);
                let (xr, vr) = rk4(&p, x, v, t, 20_000);
                assert!((xe - xr).abs() < 1e-11, "{p:?} t={t}: {xe} vs {xr}");
                assert!(
                    (ve - vr).abs() < 1e-8 * (1.0 + vr),
                    "{p:?} t={t}: {ve} vs {vr}"
                );
                assert!((ve * ve - p.s2(xe)).abs() < 1e-9 * (1.0 + ve * ve), "{p:?}");
            }
            // The time across, from the start, is ∫ dx/√S = 3h·∫ dw/√(3d + (far − 3d)·w²).
            let v0 = p.speed(0.0);
            let t = time_to_end(&p, 0.0, v0, 10.0).expect("finite");
            let far = p.e0.max(p.e1);
            let n = 100_000;
            let mut want = 0.0;
            for k in 0..n {
                let w = (k as f64 + 0.5) / n as f64;
                want += 3.0 * p.h / n as f64 / libm::sqrt(3.0 * p.d + (far - 3.0 * p.d) * w * w);
            }
            assert!((t - want).abs() < 1e-8 * want, "{p:?}: {t} vs {want}");
            let (xe, _) = advance(&p, 0.0, v0, t);
            assert!((xe - p.h).abs() < 1e-12, "{p:?}: {xe}");
            assert!(time_to_end(&p, 0.0, v0, 0.5 * t).is_none());
            // The jerk, by third differences of the motion from the start,
            // within the bound the planner's rows keep, (2/9)·(3d)^{3/2}/h²
            // at the rest and |S''|·v/2 ≤ |(2/3)d + (far − 3d)·w²|·√max(3d, far)/h².
            let dt = t / 400.0;
            let xs: [f64; 401] = core::array::from_fn(|k| advance(&p, 0.0, v0, dt * k as f64).0);
            let bound = |w: f64| {
                libm::fabs(2.0 / 3.0 * p.d + (far - 3.0 * p.d) * w * w)
                    * libm::sqrt((3.0 * p.d).max(far))
                    / (p.h * p.h)
            };
            let top = bound(0.0).max(bound(1.0));
            for k in 0..397 {
                let j = (xs[k + 3] - 3.0 * xs[k + 2] + 3.0 * xs[k + 1] - xs[k]) / (dt * dt * dt);
                assert!(
                    libm::fabs(j) <= top * 1.001 + 1e-6,
                    "{p:?} k={k}: {j} > {top}"
                );
            }
            if p.form == Form::FromRest && p.e1 == 3.0 * p.d {
                // The pure ramp: jerk (2/9)·(3d)^{3/2}/h² throughout.
                let want = 2.0 / 9.0 * libm::pow(3.0 * p.d, 1.5) / (p.h * p.h);
                let j = (xs[4] - 3.0 * xs[3] + 3.0 * xs[2] - xs[1]) / (dt * dt * dt);
                assert!((j - want).abs() < 1e-3 * want, "{j} vs {want}");
            }
        }
    }

    /// Ticks of `ts` until the motion from `(x, v)` reaches the end of
    /// `p`, as the executor takes them (`None` after `most`).
    fn ticks_to_end(p: &Piece, mut x: f64, mut v: f64, ts: f64, most: usize) -> Option<usize> {
        for k in 0..most {
            if time_to_end(p, x, v, ts).is_some() {
                return Some(k);
            }
            (x, v) = advance(p, x, v, ts);
        }
        None
    }

    #[test]
    fn a_piece_ending_at_rest_is_reached_from_a_round_off_short_of_its_end() {
        // A steep 0.29 µm drop to a rest point (jerk limits of 10⁹ mm/s³):
        // the motion came to rest an ulp short of its end. The closed form
        // from there swings back up within the tick; the end is reached now.
        let p = Piece {
            x0: 939.250_289_775_601_9,
            h: 0.000_289_775_601_913_788_7,
            e0: 1.402_513_913_258_517_4,
            d: 1.402_513_913_142_467_8,
            e1: 0.0,
            form: Form::Quadratic,
        };
        let x = 0.000_289_775_601_913_632;
        assert!(x < p.h);
        assert_eq!(ticks_to_end(&p, x, 0.0, 1e-3, 3), Some(0));
        // Concave pieces that end at rest, from their start at speed: each
        // is reached within the time its closed form takes, plus a tick.
        for h in [1e-6, 3e-4, 0.01, 0.25] {
            for (e0, d) in [(1.4, 1.4), (0.0, 10.0), (100.0, 60.0), (2500.0, 2400.0)] {
                let p = Piece {
                    h,
                    e0,
                    d,
                    e1: 0.0,
                    ..p
                };
                assert!(p.alpha() < 0.0);
                let v0 = libm::sqrt(e0);
                // (From rest the closed form's half period, π/ω, crosses it.)
                let most = 2 + (core::f64::consts::PI / libm::sqrt(-p.alpha()) / 1e-3) as usize;
                let k = ticks_to_end(&p, 0.0, v0, 1e-3, most);
                assert!(
                    k.is_some(),
                    "h {h} e0 {e0} d {d}: not reached in {most} ticks"
                );
            }
        }
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
            form: Form::Quadratic,
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
