//! The C,A fan search for one tool axis (seed `000_…` eq. 5–13), exact over
//! every placement of the two fans.
//!
//! A C,A machine with tilt range `[−Φˢ, Φᴸ]` and C range `[−Θˢ, Θᴸ]` reaches
//! the directions `R_C(c)·R_A(a)·ẑ`: a positive tilt reaches the longitudes
//! `[s, s + θ]` about the tool axis out to `φ₀`, a negative tilt the
//! longitudes `[s + π, s + π + θ]` out to `φ₁`, where `θ = Θᴸ + Θˢ` and
//! `{φ₀, φ₁} = {Φᴸ, Φˢ}`. For one tool axis, the setup must hold every MD
//! point `(α_j, β_j)` (longitude, angle from the axis) in one of the two
//! fans; the criterion is `F∇ = (φᴸ + φˢ)·θ` (eq. 13), ties broken by the
//! sum of ranges.
//!
//! Every placement, whatever its fan start, width and tilts, is no better
//! than one of these, which are all tried:
//!
//! * **Fans narrower than π** (the paper's eq. 6–11). The two fans are
//!   disjoint, so each point's fan is fixed by the fan start; shrinking the
//!   width to the smallest arc holding the points' longitudes folded modulo π
//!   keeps every point in its fan and shrinks every range. That arc leaves
//!   out one gap between consecutive folded longitudes: one candidate per gap.
//! * **Fans π or wider** (an extension: machines whose C range is 180° or
//!   more). The fans overlap and cover every longitude. Giving every point
//!   inside the fan of larger tilt to it is no worse, so that fan holds the
//!   point of largest β, and, if `t` is the other fan's tilt, every point
//!   with `β > t`: its arc is the complement of the largest gap between
//!   their longitudes (widened to π if shorter). One candidate per distinct
//!   `t ∈ {0} ∪ {β_j}`; `t = 0` is the paper's single fan with no negative
//!   tilt.
//!
//! So [`fan_search`] returns the least key over all placements, and the
//! least among those that fit the machine — exactly, not as a heuristic.

use std::f64::consts::{PI, TAU};

use nalgebra::Vector3;

use super::machine::AxisRanges;
use super::search::{Key, Placement, Solved, angle, basis, split_theta};

type V3 = Vector3<f64>;

/// Reusable memory of [`fan_search`].
#[derive(Debug, Default)]
pub struct FanScratch {
    /// Folded longitude, half (true: α ≥ π), β.
    folded: Vec<(f64, bool, f64)>,
    pre: Vec<[f64; 2]>,
    suf: Vec<[f64; 2]>,
    /// Unfolded longitude and β, sorted by longitude.
    unfolded: Vec<(f64, f64)>,
    by_beta: Vec<u32>,
    prev: Vec<u32>,
    next: Vec<u32>,
}

/// The ranges and key of fans `φ₀`, `φ₁` of width `θ` on `machine`: the
/// width split as eq. 9, the key as [`Placement::key`] computes it.
fn fan_ranges(phi0: f64, phi1: f64, width: f64, machine: &AxisRanges) -> AxisRanges {
    let (theta_l, theta_s) = split_theta(width, machine);
    AxisRanges {
        phi_l: phi0.max(phi1),
        phi_s: phi0.min(phi1),
        theta_l,
        theta_s,
    }
}

fn key_of(r: &AxisRanges) -> Key {
    (
        (r.phi_l + r.phi_s) * (r.theta_l + r.theta_s),
        r.phi_l + r.phi_s + r.theta_l + r.theta_s,
    )
}

/// The best placement and the best one that fits, as [`fan_search`] keeps
/// them; a placement is built only when it improves one of them.
struct Best<'a> {
    machine: &'a AxisRanges,
    tol: f64,
    best: Option<(Key, Placement)>,
    fit: Option<(Key, Placement)>,
}

impl Best<'_> {
    fn offer(&mut self, r: AxisRanges, make: impl FnOnce(AxisRanges, Key) -> Placement) {
        let key = key_of(&r);
        let m = self.machine;
        let fits = r.phi_l <= m.phi_l + self.tol
            && r.phi_s <= m.phi_s + self.tol
            && r.theta_l + r.theta_s <= m.theta_l + m.theta_s + self.tol;
        let better = self.best.is_none_or(|b| key < b.0);
        let better_fit = fits && self.fit.is_none_or(|b| key < b.0);
        if better || better_fit {
            let pl = make(r, key);
            debug_assert_eq!(pl.key(), key);
            if better {
                self.best = Some((key, pl));
            }
            if better_fit {
                self.fit = Some((key, pl));
            }
        }
    }

    /// The answer; exact, so the lower bounds are the keys.
    fn solved(&self) -> Solved {
        let (best_key, best) = self.best.expect("at least one placement");
        Solved {
            best,
            fit: self.fit.map(|f| f.1),
            best_lower: best_key,
            fit_lower: self.fit.map(|f| f.0),
        }
    }
}

/// The C,A search for tool axis `p` over the MD points `md` (unit vectors):
/// the placement of least key (area, then sum of ranges) and the least one
/// that fits `machine` (`tol` radians of slack), over every placement of the
/// two fans (see the module doc). O(n log n) in the number of points.
pub fn fan_search(
    p: &V3,
    md: &[V3],
    machine: &AxisRanges,
    tol: f64,
    scratch: &mut FanScratch,
) -> Solved {
    let (e1, e2) = basis(p);
    // A placement whose fan of tilt φᴸ starts at `start` (its width and
    // tilts in `r`); the basis great circle (C at zero) lies θˢ into it.
    let place = |start: f64, r: AxisRanges, one_sided: bool| {
        let zero = start + r.theta_s;
        let u = e1 * zero.cos() + e2 * zero.sin();
        Placement {
            tool_axis: *p,
            axis_1: *p,
            axis_2: p.cross(&u),
            required: r,
            area: (r.phi_l + r.phi_s) * (r.theta_l + r.theta_s),
            one_sided,
        }
    };
    let mut best = Best {
        machine,
        tol,
        best: None,
        fit: None,
    };
    if md.is_empty() {
        best.offer(fan_ranges(0.0, 0.0, 0.0, machine), |r, _| {
            place(0.0, r, false)
        });
        return best.solved();
    }
    scratch.unfolded.clear();
    scratch.folded.clear();
    for v in md {
        let a = v.dot(&e2).atan2(v.dot(&e1)).rem_euclid(TAU);
        let b = angle(p, v);
        scratch.unfolded.push((a, b));
        let (f, h) = if a >= PI { (a - PI, true) } else { (a, false) };
        scratch.folded.push((f.min(PI), h, b));
    }
    narrow_fans(scratch, &place, &mut best);
    wide_fans(scratch, &place, &mut best);
    best.solved()
}

/// Fans narrower than π: one candidate per gap between consecutive folded
/// longitudes (eq. 6–11), each O(1) after a sort with prefix and suffix
/// maxima.
fn narrow_fans(
    scratch: &mut FanScratch,
    place: &dyn Fn(f64, AxisRanges, bool) -> Placement,
    best: &mut Best,
) {
    let pts = &mut scratch.folded;
    pts.sort_unstable_by(|x, y| x.0.total_cmp(&y.0));
    let n = pts.len();
    // Max β of each half over sorted prefixes [0, s) and suffixes [s, n).
    scratch.pre.clear();
    scratch.pre.resize(n + 1, [0.0; 2]);
    scratch.suf.clear();
    scratch.suf.resize(n + 1, [0.0; 2]);
    for s in 0..n {
        let (_, h, b) = pts[s];
        let mut next = scratch.pre[s];
        next[h as usize] = next[h as usize].max(b);
        scratch.pre[s + 1] = next;
    }
    for s in (0..n).rev() {
        let (_, h, b) = pts[s];
        let mut next = scratch.suf[s + 1];
        next[h as usize] = next[h as usize].max(b);
        scratch.suf[s] = next;
    }
    // The fan pair ∇⁰ = [f_s, f_s + θ], ∇¹ = ∇⁰ + π leaves out the gap
    // before f_s. Points at or after f_s lie in ∇⁰ when in the first half;
    // points before it lie in ∇⁰ when in the second half (eq. 10).
    for s in 0..n {
        let width = if s == 0 {
            pts[n - 1].0 - pts[0].0
        } else {
            pts[s - 1].0 + PI - pts[s].0
        };
        let fan0 = scratch.suf[s][0].max(scratch.pre[s][1]);
        let fan1 = scratch.suf[s][1].max(scratch.pre[s][0]);
        // Positive tilt (φᴸ) into the fan that needs more.
        let start = if fan0 >= fan1 {
            pts[s].0
        } else {
            pts[s].0 + PI
        };
        best.offer(fan_ranges(fan0, fan1, width, best.machine), |r, _| {
            place(start, r, false)
        });
    }
}

/// Fans π or wider. The fan of larger tilt holds the point of largest β
/// (`β_max`) and, given the other fan's tilt `t`, must hold every point
/// with `β > t`: its arc is the complement of the largest gap between
/// their longitudes (not below π). So the candidates are `t = 0` and each
/// β below `β_max`: removing the points in increasing β from a cyclic list
/// only merges gaps, so the largest gap is kept in O(1) per point.
fn wide_fans(
    scratch: &mut FanScratch,
    place: &dyn Fn(f64, AxisRanges, bool) -> Placement,
    best: &mut Best,
) {
    let pts = &mut scratch.unfolded;
    pts.sort_unstable_by(|x, y| x.0.total_cmp(&y.0));
    let n = pts.len();
    let gap = |from: usize, to: usize| {
        if from == to {
            TAU
        } else {
            (pts[to].0 - pts[from].0).rem_euclid(TAU)
        }
    };
    scratch.prev.clear();
    scratch.next.clear();
    scratch
        .prev
        .extend((0..n).map(|k| ((k + n - 1) % n) as u32));
    scratch.next.extend((0..n).map(|k| ((k + 1) % n) as u32));
    // Largest gap and the point after it (the larger fan's start).
    let (mut max_gap, mut start) = (0.0f64, 0usize);
    for k in 0..n {
        let g = gap(k, (k + 1) % n);
        if g > max_gap {
            (max_gap, start) = (g, (k + 1) % n);
        }
    }
    scratch.by_beta.clear();
    scratch.by_beta.extend(0..n as u32);
    scratch.by_beta.sort_unstable_by(|&a, &b| {
        pts[a as usize]
            .1
            .total_cmp(&pts[b as usize].1)
            .then(a.cmp(&b))
    });
    let beta_max = pts[scratch.by_beta[n - 1] as usize].1;
    let mut t = 0.0f64;
    let mut k = 0;
    loop {
        let width = (TAU - max_gap).max(PI);
        let from = pts[start].0;
        best.offer(fan_ranges(beta_max, t, width, best.machine), |r, _| {
            place(from, r, t == 0.0)
        });
        // Next level: remove every point with the next β (never those with
        // β_max).
        if k >= n || pts[scratch.by_beta[k] as usize].1 >= beta_max {
            break;
        }
        t = pts[scratch.by_beta[k] as usize].1;
        while k < n && pts[scratch.by_beta[k] as usize].1 == t {
            let x = scratch.by_beta[k] as usize;
            let (a, b) = (scratch.prev[x] as usize, scratch.next[x] as usize);
            scratch.next[a] = b as u32;
            scratch.prev[b] = a as u32;
            let g = gap(a, b);
            if g > max_gap || start == x {
                (max_gap, start) = (g.max(max_gap), b);
            }
            k += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::setup::machine::{RotaryAxis, RotaryKey};
    use crate::setup::test_support::{dir, ranges};

    /// Every MD point is reached by the kinematics of a caB machine set up
    /// as `fit` says, within the ranges it needs: C about the tool axis,
    /// then the tilt.
    fn assert_reached(fit: &Placement, md: &[V3]) {
        let key = RotaryKey {
            first: RotaryAxis::C,
            second: RotaryAxis::A,
            bed_position: 2,
        };
        let r = fit.required;
        // Machine frame: z = tool axis, x = tilt axis.
        let to_part = nalgebra::Matrix3::from_columns(&[
            fit.axis_2.normalize(),
            fit.tool_axis.cross(&fit.axis_2.normalize()),
            fit.tool_axis,
        ]);
        for v in md {
            let mut reached = false;
            for ci in 0..=720 {
                let c = -r.theta_s + (r.theta_l + r.theta_s) * ci as f64 / 720.0;
                for ai in 0..=200 {
                    let a = -r.phi_s + (r.phi_l + r.phi_s) * ai as f64 / 200.0;
                    let u = to_part * key.ftm5(c, a);
                    if angle(&u, v) < 0.6f64.to_radians() {
                        reached = true;
                    }
                }
            }
            assert!(reached, "{v:?} not reached by {fit:?}");
        }
    }

    #[test]
    fn fan_covers_points_it_claims_with_the_kinematics() {
        // MD points in a lopsided pattern around +z.
        let md: Vec<V3> = [
            (20.0, 10.0),
            (35.0, 60.0),
            (10.0, 200.0),
            (25.0, 230.0),
            (5.0, 120.0),
        ]
        .iter()
        .map(|&(t, a)| dir(t, a))
        .collect();
        let machine = ranges([60.0, 60.0, 90.0, 90.0]);
        let Solved { best, fit, .. } =
            fan_search(&V3::z(), &md, &machine, 1e-9, &mut FanScratch::default());
        let fit = fit.expect("fits");
        assert_eq!(best, fit);
        assert_reached(&fit, &md);
        // Known answer: the fold of these longitudes mod 180° is
        // {10, 60, 20, 50, 120}; the largest gap is 120 → 190 (70°), so the
        // fans are 110° wide.
        let r = fit.required;
        assert!(
            (r.theta_l + r.theta_s - 110f64.to_radians()).abs() < 1e-9,
            "{r:?}"
        );
    }

    #[test]
    fn wide_fans_beat_two_narrow_ones_on_a_full_c_axis() {
        // Points at 60° over longitudes 0..200° and at 5° over 200..360°:
        // narrow fans need 180° × (60 + 60)°; one fan of 200° with 60° of
        // tilt and the other with 5° needs 200° × 65°.
        let mut md = Vec::new();
        for k in 0..=20 {
            md.push(dir(60.0, 10.0 * k as f64));
        }
        for k in 1..16 {
            md.push(dir(5.0, 200.0 + 10.0 * k as f64));
        }
        let machine = ranges([90.0, 90.0, 180.0, 180.0]);
        let Solved { best, fit, .. } =
            fan_search(&V3::z(), &md, &machine, 1e-9, &mut FanScratch::default());
        let fit = fit.expect("fits");
        assert_eq!(best, fit);
        let r = fit.required.degrees();
        assert!(
            (r[0] - 60.0).abs() < 1e-9 && (r[1] - 5.0).abs() < 1e-9,
            "{r:?}"
        );
        assert!((r[2] + r[3] - 200.0).abs() < 1e-9, "{r:?}");
        assert!(!fit.one_sided);
        assert_reached(&fit, &md);
        // A C range of 170° cannot hold the wide fans: narrow ones (the
        // folded longitudes leave a 10° gap) fit.
        let short = ranges([90.0, 90.0, 85.0, 85.0]);
        let fit = fan_search(&V3::z(), &md, &short, 1e-9, &mut FanScratch::default()).fit;
        let r = fit.expect("fits").required.degrees();
        assert!(
            (r[2] + r[3] - 170.0).abs() < 1e-9 && r[1] >= 60.0 - 1e-9,
            "{r:?}"
        );
    }

    /// The least key over placements tried by brute force: every fan start
    /// at a point's longitude or its antipode (an optimal fan can be turned
    /// until an edge meets one) and every width from that start to a point,
    /// with the points in the overlap of wide fans given to either fan.
    fn brute_force(md: &[V3], machine: &AxisRanges) -> ((f64, f64), Option<(f64, f64)>) {
        let pts: Vec<(f64, f64)> = md
            .iter()
            .map(|v| (v.y.atan2(v.x).rem_euclid(TAU), angle(&V3::z(), v)))
            .collect();
        let mut starts: Vec<f64> = pts.iter().flat_map(|p| [p.0, p.0 + PI]).collect();
        starts.iter_mut().for_each(|s| *s = s.rem_euclid(TAU));
        let (mut best, mut fit) = ((f64::INFINITY, f64::INFINITY), None::<(f64, f64)>);
        let inside = |a: f64, s: f64, w: f64| (a - s).rem_euclid(TAU) <= w + 1e-12;
        for &s in &starts {
            let mut widths: Vec<f64> = pts.iter().map(|p| (p.0 - s).rem_euclid(TAU)).collect();
            widths.extend(pts.iter().map(|p| (p.0 - s - PI).rem_euclid(TAU)));
            widths.push(0.0);
            for &w in &widths {
                // Points that only one fan holds, and those both hold.
                let (mut f0, mut f1) = (0.0f64, 0.0f64);
                let mut both = Vec::new();
                let mut ok = true;
                for &(a, b) in &pts {
                    match (inside(a, s, w), inside(a, s + PI, w)) {
                        (true, false) => f0 = f0.max(b),
                        (false, true) => f1 = f1.max(b),
                        (true, true) => both.push(b),
                        (false, false) => ok = false,
                    }
                }
                if !ok {
                    continue;
                }
                // Points in both: those above a threshold go to fan 0.
                both.sort_by(f64::total_cmp);
                for cut in 0..=both.len() {
                    let g0 = both[cut..].iter().fold(f0, |m, &b| m.max(b));
                    let g1 = both[..cut].iter().fold(f1, |m, &b| m.max(b));
                    let key = ((g0 + g1) * w, g0 + g1 + w);
                    if key < best {
                        best = key;
                    }
                    let fits = g0.max(g1) <= machine.phi_l + 1e-9
                        && g0.min(g1) <= machine.phi_s + 1e-9
                        && w <= machine.theta_l + machine.theta_s + 1e-9;
                    if fits && fit.is_none_or(|f| key < f) {
                        fit = Some(key);
                    }
                }
            }
        }
        (best, fit)
    }

    #[test]
    fn fan_search_equals_brute_force_on_random_points() {
        // xorshift: deterministic random point sets around +z, some reaching
        // past 90°.
        let mut s = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut tried = 0;
        for case in 0..300 {
            let n = 1 + case % 9;
            let spread = [60.0, 150.0, 360.0][case % 3];
            let base = 360.0 * next();
            let md: Vec<V3> = (0..n)
                .map(|_| dir(5.0 + 110.0 * next() * next(), base + spread * next()))
                .collect();
            let machine = ranges(
                [
                    [40.0, 20.0, 90.0, 45.0],
                    [100.0, 100.0, 180.0, 180.0],
                    [90.0, 10.0, 100.0, 100.0],
                ][case % 3],
            );
            let Solved { best, fit, .. } =
                fan_search(&V3::z(), &md, &machine, 1e-9, &mut FanScratch::default());
            let (bb, bf) = brute_force(&md, &machine);
            let close =
                |a: (f64, f64), b: (f64, f64)| (a.0 - b.0).abs() < 1e-9 && (a.1 - b.1).abs() < 1e-9;
            assert!(
                close(best.key(), bb),
                "case {case}: {:?} vs {bb:?}",
                best.key()
            );
            match (fit, bf) {
                (Some(f), Some(b)) => assert!(close(f.key(), b), "case {case} fit"),
                (None, None) => {}
                other => panic!("case {case}: fit {other:?}"),
            }
            tried += usize::from(fit.is_some());
        }
        assert!(tried > 50, "{tried}");
    }

    #[test]
    fn no_md_points_need_no_motion() {
        let m = ranges([0.0, 0.0, 0.0, 0.0]);
        let s = fan_search(&V3::z(), &[], &m, 0.0, &mut FanScratch::default());
        assert_eq!((s.best.area, s.fit.is_some()), (0.0, true));
    }
}
