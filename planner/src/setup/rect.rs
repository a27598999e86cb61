//! The A,B rectangle search for one tool axis (seed `000_…` eq. 14–21),
//! certified over every turn of the rectangle about the axis.
//!
//! With `R1 ⟂ p` at angle `ψ` in the tangent plane at the tool axis `p`, a
//! point `v` needs the turn `α = atan2((p×v)·R1, p·v)` about `R1` and the
//! latitude `β = asin(v·R1)` (eq. 17–18); the rectangle needs the extremes
//! of both over the MD points (eq. 19) and its size is
//! `F□ = (φᴸ + φˢ)·(θᴸ + θˢ)` (eq. 21). The paper tries `EG1` along each edge
//! of the MD points' convex hull, a near-optimal heuristic (its own words).
//! Here the least key over all `ψ ∈ [0, π)` is found by branch and bound:
//!
//! * with `u = (cos ψ, sin ψ)`, `u⊥ = (sin ψ, −cos ψ)` and a point's tangent
//!   components `y`, `(p×v)·R1 = ⟨y, u⊥⟩` and `v·R1 = ⟨y, u⟩`: each is
//!   `|y|·cos(ψ − c)`, whose extremes over an interval of `ψ` are exact
//!   (at an end, or at `c` or `c + π` when inside). `atan` and `asin` are
//!   monotone, so each interval gets a lower bound on all four ranges, hence
//!   on the key, and on whether anything in it can fit the machine.
//! * the `α` extremes of points in the open hemisphere around `p` lie on the
//!   vertices of the planar hull of their gnomonic projections (and `p`), the
//!   `β` extremes on those of the hull of the orthographic ones: only those
//!   vertices (and the points beyond the hemisphere) are kept.
//! * every hull edge's direction (the paper's candidates, and the same turned
//!   a quarter) is evaluated first; intervals whose bound cannot beat the
//!   best by more than the tolerance are dropped, the others halved.
//!
//! The answer is within [`RECT_REL_TOL`] (relative) of the least key over
//! `ψ`, or intervals of `ψ` narrower than the caller's `turn_resolution`
//! are not split further (turning `R1` by less moves no MD point by more);
//! either way the least bound of the dropped intervals is returned with it,
//! so the answer says how far from the least it can be.

use std::cmp::Ordering;
use std::collections::BinaryHeap;
use std::f64::consts::{FRAC_PI_2, PI};

use nalgebra::Vector3;

use super::machine::{AxisRanges, MachineType};
use super::search::{Key, Placement, Solved, basis, can_beat, key_min};

type V3 = Vector3<f64>;

/// Relative tolerance of the branch and bound on the key (area, then sum of
/// ranges): the placement returned is within this of the least over `ψ`.
pub const RECT_REL_TOL: f64 = 1e-7;
/// Cosine of the largest angle from the tool axis at which MD points still
/// go through the gnomonic hull (beyond, each point is kept as is).
const HULL_MIN_DOT: f64 = 1e-6;
/// Most intervals examined per tool axis; beyond, the bound of those left is
/// returned as the certificate (never reached on the tests' parts).
const MAX_INTERVALS: usize = 20_000;
/// Relative margin of [`rect_search_above`]'s stop over the bounds'
/// round-off (a few units in the last place).
const ABOVE_REL_MARGIN: f64 = 1e-9;
/// Initial intervals are at most this wide (radians).
const MAX_INITIAL_WIDTH: f64 = PI / 32.0;

/// A vector `(x, y)` of the tangent plane, its length `r = |(x, y)|`.
/// `⟨(x, y), (cos ψ, sin ψ)⟩ = r·cos(ψ − c)` with `c` its angle: the turn
/// enters only through the unit vector of `ψ`, computed once per turn.
#[derive(Debug, Clone, Copy)]
struct Polar {
    x: f64,
    y: f64,
    r: f64,
}

/// The unit vector `(cos ψ, sin ψ)`.
fn unit(psi: f64) -> (f64, f64) {
    let (s, c) = psi.sin_cos();
    (c, s)
}

/// A turn `ψ` with the unit vectors of `ψ` and `ψ − π/2`, computed once
/// and shared by the evaluation at `ψ` and the bounds of the intervals
/// that end there (the same values, so the same answers, as computing them
/// where used).
#[derive(Debug, Clone, Copy)]
struct Turn {
    psi: f64,
    u: (f64, f64),
    perp: (f64, f64),
}

impl Turn {
    fn new(psi: f64) -> Self {
        Self {
            psi,
            u: unit(psi),
            perp: unit(psi - FRAC_PI_2),
        }
    }
}

impl Polar {
    fn new(x: f64, y: f64) -> Self {
        Self {
            x,
            y,
            r: x.hypot(y),
        }
    }

    /// `r·cos(ψ − c)` for `u = (cos ψ, sin ψ)`.
    fn at(&self, u: (f64, f64)) -> f64 {
        self.x * u.0 + self.y * u.1
    }

    /// Min and max of `r·cos(ψ − c)` over `ψ ∈ [a, b]`, `b − a ≤ π`, given
    /// `ua`, `ub` the unit vectors of `a` and `b`: the ends, or `±r` when
    /// the vector (or its opposite) lies between them.
    fn range(&self, ua: (f64, f64), ub: (f64, f64)) -> (f64, f64) {
        let (fa, fb) = (self.at(ua), self.at(ub));
        // (x, y) between a and b: at or left of a, at or right of b.
        let left_of_a = ua.0 * self.y - ua.1 * self.x;
        let right_of_b = self.x * ub.1 - self.y * ub.0;
        let hi = if left_of_a >= 0.0 && right_of_b >= 0.0 {
            self.r
        } else {
            fa.max(fb)
        };
        let lo = if left_of_a <= 0.0 && right_of_b <= 0.0 {
            -self.r
        } else {
            fa.min(fb)
        };
        (lo, hi)
    }
}

/// The points of one tool axis that decide the ranges.
#[derive(Debug, Default)]
struct Geometry {
    /// Gnomonic hull vertices (α of points in the hemisphere).
    near: Vec<Polar>,
    /// Points beyond the hemisphere: `x = p·v` and `y` polar.
    far: Vec<(f64, Polar)>,
    /// Orthographic hull vertices (β of every point).
    ortho: Vec<Polar>,
}

/// Reusable memory of [`rect_search`].
#[derive(Debug, Default)]
pub struct RectScratch {
    pts: Vec<(f64, f64, usize)>,
    geom: Geometry,
    special: Vec<f64>,
    ends: Vec<f64>,
    heap: BinaryHeap<Interval>,
}

/// An interval of `ψ` with its lower bound, ordered for a min-heap.
#[derive(Debug, Clone, Copy)]
struct Interval {
    a: Turn,
    b: Turn,
    lower: Key,
    may_fit: bool,
    /// Its midpoint was evaluated when it was made (an initial interval):
    /// evaluating it again changes nothing.
    mid_done: bool,
}

impl PartialEq for Interval {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}
impl Eq for Interval {}
impl PartialOrd for Interval {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Interval {
    fn cmp(&self, other: &Self) -> Ordering {
        // Reversed: the heap pops the least bound first.
        other
            .lower
            .0
            .total_cmp(&self.lower.0)
            .then(other.lower.1.total_cmp(&self.lower.1))
            .then(other.a.psi.total_cmp(&self.a.psi))
    }
}

/// The four needed ranges at one `ψ`: α⁺, |α⁻|, β⁺, |β⁻| (radians).
#[cfg(test)]
fn ranges_at(s: &Geometry, psi: f64) -> [f64; 4] {
    ranges_at_turn(s, &Turn::new(psi))
}

/// [`ranges_at`] for a turn whose unit vectors are known.
fn ranges_at_turn(s: &Geometry, t: &Turn) -> [f64; 4] {
    let (u, perp) = (t.u, t.perp);
    let (mut ap, mut am) = (0.0f64, 0.0f64);
    for g in &s.near {
        let t = g.at(perp);
        ap = ap.max(t);
        am = am.max(-t);
    }
    let (mut ap, mut am) = (ap.atan(), am.atan());
    for (x, y) in &s.far {
        let alpha = y.at(perp).atan2(*x);
        if alpha > 0.0 {
            ap = ap.max(alpha);
        } else {
            am = am.max(-alpha);
        }
    }
    let (mut bp, mut bm) = (0.0f64, 0.0f64);
    for y in &s.ortho {
        let t = y.at(u);
        bp = bp.max(t);
        bm = bm.max(-t);
    }
    [ap, am, bp.min(1.0).asin(), bm.min(1.0).asin()]
}

/// Lower bounds over `ψ ∈ [a, b]`: the key, and (φᴸ, φˢ, θᴸ, θˢ) sorted.
fn bounds_over(s: &Geometry, a: &Turn, b: &Turn) -> (Key, [f64; 4]) {
    let (pa, pb) = (a.perp, b.perp);
    let (ua, ub) = (a.u, b.u);
    let (mut ap, mut am) = (0.0f64, 0.0f64);
    for g in &s.near {
        let (lo, hi) = g.range(pa, pb);
        ap = ap.max(lo);
        am = am.max(-hi);
    }
    let (mut ap, mut am) = (ap.atan(), am.atan());
    // A point behind the tool axis whose side flips in the interval needs
    // at least this turn on one side or the other.
    let mut either = 0.0f64;
    for (x, y) in &s.far {
        let (lo, hi) = y.range(pa, pb);
        let (at_lo, at_hi) = (lo.atan2(*x), hi.atan2(*x));
        if lo > 0.0 {
            ap = ap.max(at_lo.min(at_hi));
        } else if hi < 0.0 {
            am = am.max((-at_lo).min(-at_hi));
        } else if *x <= 0.0 {
            either = either.max(at_lo.abs().min(at_hi.abs()));
        }
    }
    let (mut bp, mut bm) = (0.0f64, 0.0f64);
    for y in &s.ortho {
        let (lo, hi) = y.range(ua, ub);
        bp = bp.max(lo);
        bm = bm.max(-hi);
    }
    let (bp, bm) = (bp.min(1.0).asin(), bm.min(1.0).asin());
    let width_a = (ap + am).max(either);
    let width_b = bp + bm;
    (
        (width_a * width_b, width_a + width_b),
        [ap.max(am).max(either), ap.min(am), bp.max(bm), bp.min(bm)],
    )
}

/// The A,B search for tool axis `p` over the MD points `md`: the placement of
/// least key over every turn `ψ` of `R1` about `p` and the least one that
/// fits `machine` (`tol` radians of slack), each within [`RECT_REL_TOL`] or
/// found to `turn_resolution` radians of turn (0: to the tolerance only),
/// with certified lower bounds.
pub fn rect_search(
    p: &V3,
    md: &[V3],
    machine: &AxisRanges,
    tol: f64,
    turn_resolution: f64,
    scratch: &mut RectScratch,
) -> Solved {
    rect_search_above(p, md, machine, tol, turn_resolution, None, scratch)
}

/// Areas above which a caller only needs to know that the lower bounds lie
/// above them: `best_lower.0 > best` and `fit_lower` `None` or above `fit`
/// (a tool axis ruled out for good by its bound in the search over axes).
#[derive(Debug, Clone, Copy)]
pub(super) struct Above {
    pub best: f64,
    pub fit: f64,
}

/// [`rect_search`], which with `above` stops as soon as the bounds of what
/// is left (every interval still to split, the dropped ones, the best
/// placements) lie above those areas by a margin. The lower bounds it then
/// returns are the least of those: still certified, above the areas (so is
/// the full search's answer, every bound of a part of an interval being at
/// least the interval's, but for round-off, far below the margin), but
/// not the full search's values; the placements are the best so far.
/// Without `above`, or when it does not stop, the answer is
/// [`rect_search`]'s, bit for bit.
pub(super) fn rect_search_above(
    p: &V3,
    md: &[V3],
    machine: &AxisRanges,
    tol: f64,
    turn_resolution: f64,
    above: Option<Above>,
    scratch: &mut RectScratch,
) -> Solved {
    let (e1, e2) = basis(p);
    // `psi: None` leaves the axes zero (enough for the key and the fit).
    let place = |psi: Option<f64>, r: [f64; 4]| {
        let r1 = psi.map_or(V3::zeros(), |psi| e1 * psi.cos() + e2 * psi.sin());
        let [ap, am, bp, bm] = r;
        let required = AxisRanges {
            phi_l: ap.max(am),
            phi_s: ap.min(am),
            theta_l: bp.max(bm),
            theta_s: bp.min(bm),
        };
        Placement {
            tool_axis: *p,
            axis_1: r1,
            axis_2: p.cross(&r1), // eq. 16
            required,
            area: (ap + am) * (bp + bm), // eq. 21
            one_sided: false,
        }
    };
    // Points: gnomonic hull (hemisphere), far points, orthographic hull.
    scratch.pts.clear();
    scratch.pts.push((0.0, 0.0, usize::MAX));
    scratch.geom.far.clear();
    for (i, v) in md.iter().enumerate() {
        let (x, y1, y2) = (v.dot(p), v.dot(&e1), v.dot(&e2));
        if x > HULL_MIN_DOT {
            scratch.pts.push((y1 / x, y2 / x, i));
        } else {
            scratch.geom.far.push((x, Polar::new(y1, y2)));
        }
    }
    let hull = planar_hull(&mut scratch.pts);
    scratch.geom.near.clear();
    scratch.special.clear();
    for (k, &h) in hull.iter().enumerate() {
        let (x, y, _) = scratch.pts[h];
        scratch.geom.near.push(Polar::new(x, y));
        let (nx, ny, _) = scratch.pts[hull[(k + 1) % hull.len()]];
        scratch.special.push((ny - y).atan2(nx - x));
    }
    scratch.pts.clear();
    scratch.pts.push((0.0, 0.0, usize::MAX));
    scratch
        .pts
        .extend(md.iter().map(|v| (v.dot(&e1), v.dot(&e2), 0)));
    let hull = planar_hull(&mut scratch.pts);
    scratch.geom.ortho.clear();
    for (k, &h) in hull.iter().enumerate() {
        let (x, y, _) = scratch.pts[h];
        scratch.geom.ortho.push(Polar::new(x, y));
        let (nx, ny, _) = scratch.pts[hull[(k + 1) % hull.len()]];
        scratch.special.push((ny - y).atan2(nx - x));
    }
    // Edge directions and the same turned a quarter, in [0, π).
    let n_edges = scratch.special.len();
    for k in 0..n_edges {
        scratch.special.push(scratch.special[k] + FRAC_PI_2);
    }
    scratch.special.push(0.0);
    for s in scratch.special.iter_mut() {
        *s = s.rem_euclid(PI);
    }
    scratch.special.sort_unstable_by(f64::total_cmp);
    scratch.special.dedup_by(|a, b| (*a - *b).abs() < 1e-12);
    let fits = |r: &[f64; 4]| {
        r[0] <= machine.phi_l + tol
            && r[1] <= machine.phi_s + tol
            && r[2] <= machine.theta_l + tol
            && r[3] <= machine.theta_s + tol
    };
    let mut best: Option<Placement> = None;
    let mut fit: Option<Placement> = None;
    let geom = &scratch.geom;
    let evaluate = |t: &Turn, best: &mut Option<Placement>, fit: &mut Option<Placement>| {
        // The axes only for a placement kept (most are not).
        let r = ranges_at_turn(geom, t);
        let mut pl = place(None, r);
        let better = best.is_none_or(|b| pl.key() < b.key());
        let better_fit =
            pl.fits(MachineType::AB, machine, tol) && fit.is_none_or(|b| pl.key() < b.key());
        if better || better_fit {
            pl = place(Some(t.psi), r);
        }
        if better {
            *best = Some(pl);
        }
        if better_fit {
            *fit = Some(pl);
        }
    };
    for k in 0..scratch.special.len() {
        evaluate(&Turn::new(scratch.special[k]), &mut best, &mut fit);
    }
    // Initial intervals between the special angles, none wider than
    // MAX_INITIAL_WIDTH.
    let heap = &mut scratch.heap;
    heap.clear();
    scratch.ends.clear();
    scratch.ends.extend_from_slice(&scratch.special);
    scratch.ends.push(PI);
    // The turn at `psi`, the last one's again when it is the same.
    let mut last = Turn::new(f64::NAN);
    let mut turn = |psi: f64| {
        if psi.to_bits() != last.psi.to_bits() {
            last = Turn::new(psi);
        }
        last
    };
    for w in scratch.ends.windows(2) {
        let pieces = ((w[1] - w[0]) / MAX_INITIAL_WIDTH).ceil().max(1.0) as usize;
        for k in 0..pieces {
            let a = w[0] + (w[1] - w[0]) * k as f64 / pieces as f64;
            let b = w[0] + (w[1] - w[0]) * (k + 1) as f64 / pieces as f64;
            if b <= a {
                continue;
            }
            let (a, b) = (turn(a), turn(b));
            evaluate(&Turn::new(0.5 * (a.psi + b.psi)), &mut best, &mut fit);
            let (lower, r) = bounds_over(geom, &a, &b);
            heap.push(Interval {
                a,
                b,
                lower,
                may_fit: fits(&r),
                mid_done: true,
            });
        }
    }
    let mut best_lower = best.expect("ψ = 0 was evaluated").key();
    let mut fit_lower: Option<Key> = fit.map(|f| f.key());
    let mut examined = 0;
    // The next `examined` at which the fit's side is looked at again (it
    // scans the heap; doubled after each look that does not stop).
    let mut next_fit_look = 0;
    // Above `x` by the margin that covers the bounds' round-off.
    let clear_of = |v: f64, x: f64| v > x + ABOVE_REL_MARGIN * x.abs() + 1e-12;
    while let Some(iv) = heap.pop() {
        examined += 1;
        if let Some(above) = above {
            let b = best.expect("evaluated").key();
            let least = key_min(key_min(best_lower, b), iv.lower);
            if clear_of(least.0, above.best) && examined >= next_fit_look {
                let mut fit_least = fit_lower;
                for x in fit.map(|f| f.key()).into_iter().chain(
                    std::iter::once(&iv)
                        .chain(heap.iter())
                        .filter(|x| x.may_fit)
                        .map(|x| x.lower),
                ) {
                    fit_least = Some(fit_least.map_or(x, |f| key_min(f, x)));
                }
                // Nothing left may fit: any fitting key is still above
                // `least` (reported so, not as "none fits").
                let fit_least = fit_least.unwrap_or(least);
                if clear_of(fit_least.0, above.fit) {
                    return Solved {
                        best: best.expect("evaluated"),
                        fit,
                        best_lower: least,
                        fit_lower: Some(fit_least),
                    };
                }
                next_fit_look = 2 * examined;
            }
        }
        let b = best.expect("evaluated").key();
        let useful_mar = can_beat(iv.lower, b, RECT_REL_TOL);
        let useful_fit =
            iv.may_fit && fit.is_none_or(|f| can_beat(iv.lower, f.key(), RECT_REL_TOL));
        if (!useful_mar && !useful_fit)
            || examined > MAX_INTERVALS
            || iv.b.psi - iv.a.psi < turn_resolution.max(1e-12)
        {
            best_lower = key_min(best_lower, iv.lower);
            if iv.may_fit {
                fit_lower = Some(fit_lower.map_or(iv.lower, |f| key_min(f, iv.lower)));
            }
            continue;
        }
        let m = Turn::new(0.5 * (iv.a.psi + iv.b.psi));
        if !iv.mid_done {
            evaluate(&m, &mut best, &mut fit);
        }
        for (a, b) in [(iv.a, m), (m, iv.b)] {
            let (lower, r) = bounds_over(geom, &a, &b);
            heap.push(Interval {
                a,
                b,
                lower,
                may_fit: fits(&r),
                mid_done: false,
            });
        }
    }
    let best = best.expect("evaluated");
    Solved {
        best,
        fit,
        best_lower: key_min(best_lower, best.key()),
        fit_lower: match (fit_lower, fit) {
            (Some(l), Some(f)) => Some(key_min(l, f.key())),
            (l, None) => l,
            (None, Some(f)) => Some(f.key()),
        },
    }
}

/// Convex hull of the points `pts` (`(x, y, tag)`), counter-clockwise, as
/// indices into `pts` after it has been sorted and deduplicated (Andrew's
/// monotone chain).
fn planar_hull(pts: &mut Vec<(f64, f64, usize)>) -> Vec<usize> {
    pts.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
    pts.dedup_by(|a, b| a.0 == b.0 && a.1 == b.1);
    let pts = &*pts;
    let cross = |o: &(f64, f64, usize), a: &(f64, f64, usize), b: &(f64, f64, usize)| {
        (a.0 - o.0) * (b.1 - o.1) - (a.1 - o.1) * (b.0 - o.0)
    };
    if pts.len() < 3 {
        return (0..pts.len()).collect();
    }
    let mut hull: Vec<usize> = Vec::with_capacity(pts.len() * 2);
    for pass in 0..2 {
        let start = hull.len();
        let iter: Box<dyn Iterator<Item = usize>> = if pass == 0 {
            Box::new(0..pts.len())
        } else {
            Box::new((0..pts.len()).rev())
        };
        for i in iter {
            while hull.len() >= start + 2
                && cross(
                    &pts[hull[hull.len() - 2]],
                    &pts[hull[hull.len() - 1]],
                    &pts[i],
                ) <= 0.0
            {
                hull.pop();
            }
            hull.push(i);
        }
        hull.pop();
    }
    hull
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::setup::test_support::{dir, ranges};

    #[test]
    fn rectangle_of_points_on_a_grid_is_found() {
        // Points at longitude α about x (R1) and latitude β: a rectangle
        // α ∈ [−20, 30], β ∈ [−10, 15] around +z.
        let r1 = V3::x();
        let mut md = Vec::new();
        for &(a, b) in &[
            (-20.0f64, -10.0f64),
            (30.0, -10.0),
            (30.0, 15.0),
            (-20.0, 15.0),
            (5.0, 2.0),
        ] {
            // Turn about x by α, then lift toward x by β.
            let (a, b) = (a.to_radians(), b.to_radians());
            let on_circle = V3::new(0.0, -a.sin(), a.cos());
            md.push(on_circle * b.cos() + r1 * b.sin());
        }
        let machine = ranges([40.0, 30.0, 20.0, 20.0]);
        let s = rect_search(
            &V3::z(),
            &md,
            &machine,
            1e-9,
            0.0,
            &mut RectScratch::default(),
        );
        let fit = s.fit.expect("fits");
        assert_eq!(s.best, fit);
        let got = fit.required.degrees();
        // φ (R1) 30 and 20, θ 15 and 10.
        for (g, e) in got.iter().zip([30.0, 20.0, 15.0, 10.0]) {
            assert!((g - e).abs() < 1e-6, "{got:?}");
        }
        assert!(fit.axis_1.cross(&r1).norm() < 1e-6);
    }

    #[test]
    fn rect_search_is_the_least_over_every_turn_on_random_points() {
        let mut s = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut scratch = RectScratch::default();
        let mut beaten_paper = 0;
        for case in 0..120 {
            let n = 2 + case % 7;
            let far = if case % 4 == 0 { 130.0 } else { 70.0 };
            let md: Vec<V3> = (0..n)
                .map(|_| dir(3.0 + far * next() * next(), 360.0 * next()))
                .collect();
            let machine = ranges([50.0, 30.0, 40.0, 20.0]);
            let solved = rect_search(&V3::z(), &md, &machine, 1e-9, 0.0, &mut scratch);
            // Brute force over 20,000 turns: never better than the answer,
            // and the certified bound is below all of them.
            let mut brute = (f64::INFINITY, f64::INFINITY);
            let mut brute_fit: Option<Key> = None;
            for k in 0..20_000 {
                let psi = PI * k as f64 / 20_000.0;
                let r = ranges_at(&scratch.geom, psi);
                let key = ((r[0] + r[1]) * (r[2] + r[3]), r.iter().sum::<f64>());
                brute = key_min(brute, key);
                let fits = r[0].max(r[1]) <= machine.phi_l + 1e-9
                    && r[0].min(r[1]) <= machine.phi_s + 1e-9
                    && r[2].max(r[3]) <= machine.theta_l + 1e-9
                    && r[2].min(r[3]) <= machine.theta_s + 1e-9;
                if fits {
                    brute_fit = Some(brute_fit.map_or(key, |f| key_min(f, key)));
                }
            }
            let best = solved.best.key();
            let slack = |k: Key| k.0 * RECT_REL_TOL + 1e-12;
            assert!(
                best.0 <= brute.0 + slack(best),
                "case {case}: {best:?} vs {brute:?}"
            );
            assert!(solved.best_lower.0 <= brute.0 + 1e-12, "case {case}");
            assert!(
                best.0 - solved.best_lower.0 <= 2.0 * slack(best),
                "case {case}"
            );
            if let Some(bf) = brute_fit {
                let f = solved.fit.expect("brute force found a fit").key();
                assert!(f.0 <= bf.0 + slack(f), "case {case} fit");
            }
            // How often the paper's hull-edge candidates alone are beaten.
            let paper = scratch
                .special
                .iter()
                .map(|&psi| {
                    let r = ranges_at(&scratch.geom, psi);
                    (r[0] + r[1]) * (r[2] + r[3])
                })
                .fold(f64::INFINITY, f64::min);
            beaten_paper += usize::from(best.0 < paper * (1.0 - 1e-6));
        }
        // Not a property of the code, but a reason for it: record that the
        // hull edges alone are not always optimal on these sets.
        eprintln!("hull-edge candidates beaten in {beaten_paper} of 120 cases");
    }

    /// The search that stops once its bounds are above given areas: it
    /// says "above" exactly when the full search's bounds are, its bounds
    /// are still lower bounds (at most the full search's), and when it
    /// does not stop its answer is the full search's bit for bit.
    #[test]
    fn a_search_stopped_above_areas_agrees_with_the_full_search() {
        let mut s = 0x5DEE_CE66_D1CE_4E5Bu64;
        let mut next = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut scratch = RectScratch::default();
        let (mut stopped, mut both_above) = (0, 0);
        for case in 0..150 {
            let n = 2 + case % 9;
            let far = if case % 4 == 0 { 130.0 } else { 70.0 };
            let md: Vec<V3> = (0..n)
                .map(|_| dir(3.0 + far * next() * next(), 360.0 * next()))
                .collect();
            let machine = if case % 3 == 0 {
                ranges([20.0, 10.0, 10.0, 5.0])
            } else {
                ranges([50.0, 30.0, 40.0, 20.0])
            };
            let res = PI / 64.0 / 16.0 * (case % 2) as f64;
            let full = rect_search(&V3::z(), &md, &machine, 1e-9, res, &mut scratch);
            let fit_ref = full.fit_lower.unwrap_or(full.best_lower).0;
            // Areas well below, just below, between the bound and the key
            // (the B&B's tolerance), and above the full search's bounds.
            for f in [-0.5, -1e-3, -1e-6, -2e-8, 5e-8, 1e-6, 1e-3] {
                for g in [-0.5, -2e-8, 5e-8, 1e-3] {
                    let above = Above {
                        best: full.best_lower.0 * (1.0 + f),
                        fit: fit_ref * (1.0 + g),
                    };
                    let out = |x: &Solved| {
                        x.best_lower.0 > above.best && x.fit_lower.is_none_or(|l| l.0 > above.fit)
                    };
                    let early = rect_search_above(
                        &V3::z(),
                        &md,
                        &machine,
                        1e-9,
                        res,
                        Some(above),
                        &mut scratch,
                    );
                    assert_eq!(out(&early), out(&full), "case {case} {f} {g}");
                    assert!(early.best_lower <= full.best_lower, "case {case}");
                    if let Some(l) = full.fit_lower {
                        assert!(early.fit_lower.expect("a bound") <= l, "case {case}");
                    }
                    if early != full {
                        assert!(out(&early), "case {case}: changed without stopping");
                        stopped += 1;
                    }
                    both_above += usize::from(out(&full));
                }
            }
        }
        // The stop is taken (and not only where nothing was left to do).
        assert!(
            stopped > 100 && both_above > stopped / 2,
            "{stopped} {both_above}"
        );
    }

    #[test]
    fn no_md_points_need_no_motion() {
        let m = ranges([0.0, 0.0, 0.0, 0.0]);
        let s = rect_search(&V3::z(), &[], &m, 0.0, 0.0, &mut RectScratch::default());
        assert_eq!((s.best.area, s.fit.is_some()), (0.0, true));
    }
}
