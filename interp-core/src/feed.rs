//! The seed's pointwise feed laws (seed 004, §2–3) and their combination.
//!
//! All speeds in mm/s, lengths in mm, times in s.

use crate::config::InterpConfig;
use crate::geom::{Derivs, Vec3};
use crate::path::{MrrParams, ToolSide};
use crate::plan::JumpReserve;

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

/// The limit of every law at a point: [`feed_limit`] and [`machine_limit`].
pub fn speed_limit(d: &Derivs, feed: f64, mrr: Option<&MrrParams>, cfg: &InterpConfig) -> f64 {
    feed_limit(d, feed, mrr, cfg).min(machine_limit(d, cfg, 1.0))
}

/// The programmed feed and the constant-MRR law (eq. 23), mm/s: the part of
/// the limit that the feed override scales.
pub fn feed_limit(d: &Derivs, feed: f64, mrr: Option<&MrrParams>, cfg: &InterpConfig) -> f64 {
    let mut v = feed;
    if let (true, Some(m)) = (cfg.mrr_law, mrr) {
        let ks = signed_curvature(d, m.tool_side);
        v = v.min(mrr_speed(feed, ks, m.tool_radius, m.depth_of_cut));
    }
    v
}

/// The machine's limits at a point, mm/s: top path speed, the chord-error law
/// (eq. 16–17), centripetal acceleration and the per-axis limits (see
/// [`axis_limit`]). `budget` in (0, 1] is the share of the axes' curvature
/// budget available here (1 on a smooth path, less next to a junction).
/// Needs derivatives up to order 3.
///
/// Where the parametric speed vanishes (`C′ = 0`, a stationary point) the
/// derivatives at the point give no curvature, which is in general infinite
/// there (like `1/√s` at a repeated end control point): the pointwise limit is
/// then 0. Planning takes the laws at such a point from a tick's distance away
/// instead ([`stationary_offset`]).
pub fn machine_limit(d: &Derivs, cfg: &InterpConfig, budget: f64) -> f64 {
    machine_limit_parts(d, cfg, budget)
        .into_iter()
        .fold(cfg.max_path_speed, f64::min)
}

/// How many terms [`machine_limit_parts`] returns.
pub const MACHINE_LAW_PARTS: usize = 7;

/// The terms of [`machine_limit`], each a smooth function along the path
/// with its own peaks: the curvature laws (chord error, centripetal), each
/// axis's velocity and acceleration, and each axis's steady jerk. Their
/// minimum can have two dips a few µm apart (the `C‴` peaks of two axes, or
/// a curvature peak and a `C‴` peak), where a search on the minimum finds
/// one; each term alone is far less likely to.
pub fn machine_limit_parts(
    d: &Derivs,
    cfg: &InterpConfig,
    budget: f64,
) -> [f64; MACHINE_LAW_PARTS] {
    if d.d1.norm_squared() == 0.0 {
        return [0.0; MACHINE_LAW_PARTS];
    }
    let mut v = [f64::INFINITY; MACHINE_LAW_PARTS];
    if cfg.chord_error_law {
        v[0] = chord_error_speed(d.curvature(), cfg.chord_tolerance, cfg.period);
    }
    if let Some(a) = ArcLengthDerivs::new(d) {
        let keep = 1.0 - cfg.planning_margin;
        let k = a.c_ss.norm();
        if k > 0.0 {
            v[0] = v[0].min(libm::sqrt(budget * keep * cfg.max_centripetal_accel / k));
        }
        for i in 0..3 {
            v[1 + i] = axis_limit_of(&a, cfg, budget, i);
            v[4 + i] = steady_jerk_speed_of(&a, cfg, i);
        }
    }
    v
}

/// The speed at which a path followed at constant speed meets an axis's
/// jerk limit, mm/s: `C_sss,i·v³ ≤ J_i`, the axis jerk of the curvature
/// alone. No plan passes a point faster than that (it would have to pass it
/// at constant speed at least), so it is a pointwise machine limit; the
/// schedule's linear program holds the whole axis jerk along its profile.
pub fn steady_jerk_speed(a: &ArcLengthDerivs, cfg: &InterpConfig) -> f64 {
    (0..3).fold(f64::INFINITY, |v, i| v.min(steady_jerk_speed_of(a, cfg, i)))
}

/// [`steady_jerk_speed`] of axis `i` alone.
pub fn steady_jerk_speed_of(a: &ArcLengthDerivs, cfg: &InterpConfig, i: usize) -> f64 {
    let keep = 1.0 - cfg.planning_margin;
    let csss = libm::fabs(a.c_sss[i]);
    if csss > 0.0 {
        libm::cbrt(keep * cfg.axis_max_jerk[i] / csss)
    } else {
        f64::INFINITY
    }
}

/// The share of one tick's step within which the curvature at a stationary
/// point is taken from the step's far end (see [`stationary_offset`]).
pub const STATIONARY_STEP_SHARE: f64 = 0.25;

/// Fixed-point steps of [`stationary_offset`] (it converges like `(1/4)^k` in
/// the logarithm where the curvature blows up like `1/√s`).
const STATIONARY_OFFSET_ITERS: usize = 24;

/// The arc length `δ` from a stationary point of a path (`C′ = 0`, e.g. a
/// repeated control point at a NURBS end) at which the laws stand for the
/// point: the fixed point `δ = STATIONARY_STEP_SHARE · Ts · V(δ)`, reached from
/// above, where `limit_at(δ)` is the speed the laws allow at arc length `δ`
/// from the point; at most `max`.
///
/// A sampled machine does not see the curvature at a point, but what the path
/// does over one tick: at a repeated end control point the curvature blows up
/// like `α/√s`, yet over a step `L` the path leaves its chord by only
/// `≈ 0.2·α·L^{3/2}` and the second and third differences of the setpoints stay
/// finite. The laws taken at `δ ≤ L/4` (curvature `α/√δ ≥ 2α/√L`) bound all of
/// them (chord error up to `δ ≤ 0.4·L`, the second difference up to `0.56·L`),
/// so the point is passed at a positive speed, neither at an infinite
/// curvature (a stall) nor at none (a jump).
pub fn stationary_offset(
    cfg: &InterpConfig,
    max: f64,
    mut limit_at: impl FnMut(f64) -> f64,
) -> f64 {
    let step = STATIONARY_STEP_SHARE * cfg.period;
    let mut d = (step * cfg.max_path_speed).min(max);
    for _ in 0..STATIONARY_OFFSET_ITERS {
        let v = limit_at(d);
        let next = step * v;
        // Only shrink: the law grows with the distance from the point.
        if !(next < d * (1.0 - 1e-6)) || !(next > 0.0) {
            break;
        }
        d = next;
    }
    d
}

/// Derivatives of a path with respect to arc length at one point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ArcLengthDerivs {
    /// Unit tangent `dC/ds`.
    pub t: Vec3,
    /// Curvature vector `d²C/ds² = k·n`.
    pub c_ss: Vec3,
    /// `d³C/ds³`.
    pub c_sss: Vec3,
}

impl ArcLengthDerivs {
    /// From parametric derivatives up to order 3 (`None` where `|C'| = 0`: at a
    /// stationary point the arc-length derivatives are limits that the point's
    /// derivatives do not determine; see [`stationary_offset`]).
    pub fn new(d: &Derivs) -> Option<Self> {
        let s1 = d.d1.norm();
        if !(s1 > 0.0) {
            return None;
        }
        // σ = |C'|, σ' = C'·C''/σ, σ'' = (|C''|² + C'·C''' − σ'²)/σ.
        let sp = d.d1.dot(&d.d2) / s1;
        let spp = (d.d2.norm_squared() + d.d1.dot(&d.d3) - sp * sp) / s1;
        let (s2, s3) = (s1 * s1, s1 * s1 * s1);
        let t = d.d1 / s1;
        let c_ss = d.d2 / s2 - d.d1 * (sp / s3);
        let c_sss = d.d3 / s3 - d.d2 * (3.0 * sp / (s3 * s1)) - d.d1 * (spp / (s3 * s1))
            + d.d1 * (3.0 * sp * sp / (s3 * s2));
        Some(ArcLengthDerivs { t, c_ss, c_sss })
    }
}

/// Per-axis limit on the path speed, mm/s. With path speed `v` and
/// tangential acceleration `a`, axis `i` moves with velocity `t_i·v` and
/// acceleration `C_ss,i·v² + t_i·a`. The schedule holds `|a|` to the planned
/// path acceleration, so each axis keeps `budget` of what is left for the
/// curvature term. (Axis jerk, `C_sss,i·v³ + 3·C_ss,i·v·a + t_i·j`, depends
/// on the planned `a` and `j`: the schedule's linear program holds it
/// exactly, see [`crate::plan`].)
pub fn axis_limit(a: &ArcLengthDerivs, cfg: &InterpConfig, budget: f64) -> f64 {
    (0..3).fold(f64::INFINITY, |v, i| {
        v.min(axis_limit_of(a, cfg, budget, i))
    })
}

/// [`axis_limit`] of axis `i` alone.
pub fn axis_limit_of(a: &ArcLengthDerivs, cfg: &InterpConfig, budget: f64, i: usize) -> f64 {
    let keep = 1.0 - cfg.planning_margin;
    let pa = cfg.planned_accel();
    let mut v = f64::INFINITY;
    let t = libm::fabs(a.t[i]);
    let css = libm::fabs(a.c_ss[i]);
    if t > 0.0 {
        v = v.min(keep * cfg.axis_max_velocity[i] / t);
    }
    let acc = budget * (keep * cfg.axis_max_accel[i] - t * pa);
    if css > 0.0 {
        v = v.min(libm::sqrt(acc.max(0.0) / css));
    }
    v
}

/// Speed at which the path may pass a junction between a piece ending with
/// derivatives `left` and one starting with `right`, mm/s (infinity for a
/// junction with no jump at all).
///
/// A tick that crosses the junction turns the direction by `Δt = t₂ − t₁` and
/// changes the curvature vector by `Δ(k·n)` at once. In sampled setpoints
/// that is an axis acceleration of up to `v·|Δt_i|/Ts` and a jerk of up to
/// `v·|Δt_i|/Ts²` (a direction change) and `v²·|Δ(k·n)_i|/Ts` (a curvature
/// change), and a centripetal acceleration `v·|Δt|/Ts`. Each gets half of the
/// axis's curvature budget; the other half bounds the curvature terms of both
/// pieces at the junction.
pub fn junction_speed(left: &Derivs, right: &Derivs, cfg: &InterpConfig) -> f64 {
    junction_speed_with(left, right, cfg, JUMP_SHARE)
}

/// [`junction_speed`] with the curvature's step taking `jump_share` of an
/// axis's jerk (at a stationary point, whose laws are taken a tick inside
/// and whose curvature grows without bound towards it, the planner keeps
/// [`STATIONARY_JUMP_SHARE`]).
pub fn junction_speed_with(
    left: &Derivs,
    right: &Derivs,
    cfg: &InterpConfig,
    jump_share: f64,
) -> f64 {
    let (Some(l), Some(r)) = (ArcLengthDerivs::new(left), ArcLengthDerivs::new(right)) else {
        return 0.0;
    };
    let keep = 1.0 - cfg.planning_margin;
    let ts = cfg.period;
    let share = 0.5 * (1.0 - cfg.axis_tangential_share);
    let dt = r.t - l.t;
    let dk = r.c_ss - l.c_ss;
    let mut v = f64::INFINITY;
    let dtn = dt.norm();
    if dtn > 0.0 {
        v = v.min(0.5 * keep * cfg.max_centripetal_accel * ts / dtn);
    }
    for i in 0..3 {
        let a = libm::fabs(dt[i]);
        if a > 0.0 {
            v = v.min(share * keep * cfg.axis_max_accel[i] * ts / a);
            v = v.min(share * keep * cfg.axis_max_jerk[i] * ts * ts / a);
        }
        let c = libm::fabs(dk[i]);
        if c > 0.0 {
            // The curvature's step: see [`JUMP_SHARE`].
            v = v.min(libm::sqrt(
                jump_share / JUMP_SEEN * keep * cfg.axis_max_jerk[i] * ts / c,
            ));
        }
    }
    // A jump too small to matter at any speed the machine can reach (split
    // points of one smooth curve) leaves the curvature budget whole; the
    // planning margin absorbs it.
    if v >= NEGLIGIBLE_JUMP * cfg.max_path_speed {
        return f64::INFINITY;
    }
    let budget = curvature_budget(&l, &r, v, cfg);
    v.min(machine_limit(left, cfg, budget))
        .min(machine_limit(right, cfg, budget))
}

/// The share of the centripetal and axis acceleration budgets the
/// curvature of both sides may use at a junction passed at most at `v`:
/// what the tangent's step leaves there. A tick across the joint sees the
/// velocity step `v·|Δtᵢ|/Ts` on top of the curvature's acceleration (see
/// [`junction_speed`]); the junction's caps hold that step to half the
/// centripetal budget and to half of what an axis's acceleration leaves
/// past its tangential share, so the share is at least one half, and where
/// the tangent is continuous (a C1 knot, a curvature step alone) the whole
/// budget.
fn curvature_budget(l: &ArcLengthDerivs, r: &ArcLengthDerivs, v: f64, cfg: &InterpConfig) -> f64 {
    let keep = 1.0 - cfg.planning_margin;
    let ts = cfg.period;
    let dt = r.t - l.t;
    // The share a step takes (an undefined one, all it may).
    let share = |x: f64| if x.is_nan() { 0.5 } else { x.clamp(0.0, 0.5) };
    let mut used: f64 = 0.0;
    let dtn = dt.norm();
    if dtn > 0.0 {
        used = used.max(share(v * dtn / (ts * keep * cfg.max_centripetal_accel)));
    }
    let pa = cfg.planned_accel();
    for i in 0..3 {
        let a = libm::fabs(dt[i]);
        if a > 0.0 {
            let t = libm::fabs(l.t[i]).max(libm::fabs(r.t[i]));
            let room = keep * cfg.axis_max_accel[i] - t * pa;
            used = used.max(share(v * a / (ts * room.max(0.0))));
        }
    }
    1.0 - used
}

/// The share of an axis's jerk a curvature step at a junction may take
/// (`v²·|Δκᵢ|` in one tick). The jerk rows next to the junction keep to the
/// rest ([`jump_reserve`]), so the two add up to the limit.
pub const JUMP_SHARE: f64 = 0.5;

/// [`JUMP_SHARE`] at a junction next to a stationary point (see
/// [`junction_speed_with`]): the share the planner gave every junction
/// before the jerk rows kept to the rest.
pub const STATIONARY_JUMP_SHARE: f64 = 0.25 * JUMP_SEEN;

/// The largest part of an acceleration step `ΔA` that one third difference
/// of the setpoints sees, as a fraction of `ΔA/Ts`: a step at a fraction θ
/// of a tick spreads over three of them as `(1−θ)²/2`, `(1+2θ−2θ²)/2`,
/// `θ²/2`, the middle one at most 3/4.
pub const JUMP_SEEN: f64 = 0.75;

/// [`JUMP_SHARE`] at a knot inside a curve (continuity C1 or less): the
/// knot is priced before the curve's laws are sampled, so every sample
/// within the ticks that see its step keeps the step's reserve
/// (`plan::Window::reserve_around_jump`) and the step may take most of an
/// axis's jerk. Between blocks the samples before the junction were
/// sampled without it; there the step keeps [`JUMP_SHARE`].
pub const KNOT_JUMP_SHARE: f64 = 0.85;

/// The share of each axis's jerk a junction passed at `v` takes with its
/// curvature's step (at most `share`, the one its speed was set with), on
/// the side of the jerk the step adds: the jerk rows at and near the
/// junction keep to the rest there, and may use the whole limit the other
/// way.
pub fn jump_reserve(
    left: &Derivs,
    right: &Derivs,
    v: f64,
    share: f64,
    cfg: &InterpConfig,
) -> JumpReserve {
    let mut out = JumpReserve::NONE;
    let (Some(l), Some(r)) = (ArcLengthDerivs::new(left), ArcLengthDerivs::new(right)) else {
        return out;
    };
    let keep = 1.0 - cfg.planning_margin;
    let dk = r.c_ss - l.c_ss;
    for i in 0..3 {
        let take =
            JUMP_SEEN * v * v * libm::fabs(dk[i]) / (cfg.period * keep * cfg.axis_max_jerk[i]);
        // (Travelled from `left` to `right`: the step adds jerk of its sign.)
        let side = if dk[i] > 0.0 {
            &mut out.up
        } else {
            &mut out.down
        };
        side[i] = take.min(share);
    }
    out
}

/// A junction whose jump would limit the speed only above this many times the
/// machine's top speed is no junction at all (it costs under 0.1 % of the budget).
pub const NEGLIGIBLE_JUMP: f64 = 1e3;

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
