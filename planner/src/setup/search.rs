//! The setup search of seed `000_…` §4: Group I/II (eq. 3), MD points (eq. 4),
//! the C,A fan search (eq. 5–13) and the A,B spherical-rectangle search over
//! the convex hull of the MD points (eq. 14–21).

use std::collections::HashMap;
use std::f64::consts::{PI, TAU};

use nalgebra::Vector3;
use rayon::prelude::*;

use super::machine::{AxisRanges, MachineType};
use super::visibility::VisibilityMap;

type V3 = Vector3<f64>;

/// Patches with identical point visibility cones, and the map turned
/// cell-major over those classes: `row(c)` has bit `k` set when cell `c` is in
/// the cone of class `k`. Identical cones share their MD point, so the
/// search runs over classes, not triangles.
#[derive(Debug, Clone)]
pub struct PvcClasses {
    /// Class of each patch (`None` when its cone is empty: no direction
    /// reaches it).
    pub class_of: Vec<Option<u32>>,
    /// Number of classes.
    pub classes: usize,
    words: usize,
    rows: Vec<u64>,
    cells: usize,
}

impl PvcClasses {
    /// Groups the patches of `map` (on a sphere with cell directions
    /// `cells`) by identical cones.
    ///
    /// Classes are numbered in the order of their cones' mean directions
    /// along a serpentine latitude–longitude path, so that classes reached at
    /// about the same step of the MD walk ([`md_cells`]) share words of the
    /// bitsets and those words retire early.
    pub fn new(map: &VisibilityMap, cells: &[V3]) -> Self {
        let mut index: HashMap<&[u64], u32> = HashMap::new();
        let mut reps: Vec<usize> = Vec::new();
        let mut first_class = Vec::with_capacity(map.patches());
        for j in 0..map.patches() {
            let pvc = map.pvc(j);
            if pvc.iter().all(|w| *w == 0) {
                first_class.push(None);
                continue;
            }
            let next = reps.len() as u32;
            let k = *index.entry(pvc).or_insert_with(|| {
                reps.push(j);
                next
            });
            first_class.push(Some(k));
        }
        let classes = reps.len();
        // Spatial order of the classes.
        let keys: Vec<(u32, i64)> = reps
            .par_iter()
            .map(|&j| {
                let mut sum = V3::zeros();
                for (w, bits) in map.pvc(j).iter().enumerate() {
                    let mut bits = *bits;
                    while bits != 0 {
                        sum += cells[w * 64 + bits.trailing_zeros() as usize];
                        bits &= bits - 1;
                    }
                }
                /// Rows and columns of the ordering grid.
                const ORDER_ROWS: f64 = 64.0;
                let theta = sum.z.atan2(sum.xy().norm()) + PI / 2.0; // 0..π
                let phi = sum.y.atan2(sum.x) + PI; // 0..2π
                let row = ((theta / PI * ORDER_ROWS) as i64).min(ORDER_ROWS as i64 - 1);
                let col = (phi / TAU * 2.0 * ORDER_ROWS) as i64;
                (row as u32, if row % 2 == 0 { col } else { -col })
            })
            .collect();
        let mut order: Vec<u32> = (0..classes as u32).collect();
        order.sort_by_key(|&k| (keys[k as usize], k));
        let mut renumber = vec![0u32; classes];
        for (new, &old) in order.iter().enumerate() {
            renumber[old as usize] = new as u32;
        }
        let class_of: Vec<Option<u32>> = first_class
            .iter()
            .map(|c| c.map(|k| renumber[k as usize]))
            .collect();
        let words = classes.div_ceil(64);
        let mut rows = vec![0u64; words * map.cells()];
        for (k, &old) in order.iter().enumerate() {
            for (w, bits) in map.pvc(reps[old as usize]).iter().enumerate() {
                let mut bits = *bits;
                while bits != 0 {
                    let c = w * 64 + bits.trailing_zeros() as usize;
                    bits &= bits - 1;
                    rows[c * words + k / 64] |= 1 << (k % 64);
                }
            }
        }
        Self {
            class_of,
            classes,
            words,
            rows,
            cells: map.cells(),
        }
    }

    fn row(&self, cell: usize) -> &[u64] {
        &self.rows[cell * self.words..(cell + 1) * self.words]
    }

    /// The cells in every class's cone: the tool axes that reach all
    /// reachable patches without rotary motion (Group II empty).
    pub fn common_cells(&self) -> Vec<usize> {
        let full = |w: usize| {
            if w + 1 == self.words && !self.classes.is_multiple_of(64) {
                (1u64 << (self.classes % 64)) - 1
            } else {
                u64::MAX
            }
        };
        (0..self.cells)
            .filter(|&c| self.row(c).iter().enumerate().all(|(w, &x)| x == full(w)))
            .collect()
    }
}

/// Reusable memory of one search thread.
#[derive(Debug, Default)]
pub struct Scratch {
    unassigned: Vec<u64>,
    active: Vec<usize>,
    order: Vec<u32>,
    keys: Vec<f64>,
    buckets: Vec<u32>,
    /// The MD cells of the last [`md_cells`] call.
    pub md: Vec<u32>,
}

/// Buckets of the counting sort of cells by distance from the candidate.
const ORDER_BUCKETS: usize = 4096;

/// Group II and MD points for the tool axis `cells[candidate]`.
///
/// Walks the cells in order of angle from the candidate (eq. 4 for all
/// patches at once): the first cell of `PVC_j` met is `MD_j`. The candidate
/// itself comes first, so its classes are Group I (eq. 3) and get no MD
/// point. Fills `scratch.md` with the distinct MD cells of Group II (several
/// patches can share one) and returns the number of Group II classes.
pub fn md_cells(
    classes: &PvcClasses,
    cells: &[V3],
    candidate: usize,
    scratch: &mut Scratch,
) -> usize {
    let words = classes.words;
    scratch.md.clear();
    scratch.unassigned.clear();
    scratch.unassigned.resize(words, u64::MAX);
    if !classes.classes.is_multiple_of(64) {
        scratch.unassigned[words - 1] = (1u64 << (classes.classes % 64)) - 1;
    }
    scratch.active.clear();
    scratch.active.extend(0..words);
    let mut remaining = classes.classes;
    order_by_angle(cells, candidate, scratch);
    let mut group_ii = 0;
    for (step, &c) in scratch.order.iter().enumerate() {
        let row = classes.row(c as usize);
        let mut hit = 0usize;
        let mut k = 0;
        while k < scratch.active.len() {
            let w = scratch.active[k];
            let x = scratch.unassigned[w] & row[w];
            if x != 0 {
                hit += x.count_ones() as usize;
                scratch.unassigned[w] &= !x;
            }
            if scratch.unassigned[w] == 0 {
                scratch.active.swap_remove(k);
            } else {
                k += 1;
            }
        }
        remaining -= hit;
        if step == 0 {
            debug_assert_eq!(c as usize, candidate);
            group_ii = remaining;
        } else if hit > 0 {
            scratch.md.push(c);
        }
        if remaining == 0 {
            break;
        }
    }
    group_ii
}

/// Cell indices in increasing angle from `cells[candidate]`: a counting sort
/// on the chord length, then an exact sort inside each bucket.
fn order_by_angle(cells: &[V3], candidate: usize, scratch: &mut Scratch) {
    let p = cells[candidate];
    let m = cells.len();
    scratch.keys.clear();
    scratch.keys.extend(cells.iter().map(|c| (c - p).norm()));
    scratch.keys[candidate] = -1.0;
    let bucket =
        |key: f64| ((key.max(0.0) * 0.5 * ORDER_BUCKETS as f64) as usize).min(ORDER_BUCKETS - 1);
    scratch.buckets.clear();
    scratch.buckets.resize(ORDER_BUCKETS + 1, 0);
    for &k in &scratch.keys {
        scratch.buckets[bucket(k) + 1] += 1;
    }
    for b in 0..ORDER_BUCKETS {
        scratch.buckets[b + 1] += scratch.buckets[b];
    }
    scratch.order.clear();
    scratch.order.resize(m, 0);
    let mut fill = scratch.buckets.clone();
    for (i, &k) in scratch.keys.iter().enumerate() {
        let b = bucket(k);
        scratch.order[fill[b] as usize] = i as u32;
        fill[b] += 1;
    }
    let keys = &scratch.keys;
    for b in 0..ORDER_BUCKETS {
        let (s, e) = (scratch.buckets[b] as usize, scratch.buckets[b + 1] as usize);
        if e - s > 1 {
            scratch.order[s..e].sort_unstable_by(|x, y| {
                keys[*x as usize]
                    .total_cmp(&keys[*y as usize])
                    .then(x.cmp(y))
            });
        }
    }
}

/// One evaluated FTM placement: a tool axis, the rotary-axis directions and
/// the ranges it needs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Placement {
    /// Tool axis at home, unit vector in part coordinates.
    pub tool_axis: V3,
    /// C,A: the C axis (= tool axis); A,B: `R1`.
    pub axis_1: V3,
    /// C,A: the tilt axis (A or B), normal to the basis great circle; A,B: `R2`.
    pub axis_2: V3,
    /// Ranges needed, radians: φ_L φ_S (C,A tilt / A,B R1), θ_L θ_S (C / R2).
    pub required: AxisRanges,
    /// `F∇` (eq. 13) or `F□` (eq. 21), rad².
    pub area: f64,
    /// C,A only: all MD points in one fan wider than π (needs `Θ^L+Θ^S ≥ θ`
    /// and no negative tilt); an extension of the paper's two fans.
    pub one_sided: bool,
}

impl Placement {
    /// Whether the machine's ranges contain the needed ones (eq. 12 / eq. 20).
    pub fn fits(&self, kind: MachineType, machine: &AxisRanges, tol: f64) -> bool {
        let r = &self.required;
        match kind {
            MachineType::CA => {
                r.phi_l <= machine.phi_l + tol
                    && r.phi_s <= machine.phi_s + tol
                    && r.theta_l + r.theta_s <= machine.theta_l + machine.theta_s + tol
            }
            MachineType::AB => {
                r.phi_l <= machine.phi_l + tol
                    && r.phi_s <= machine.phi_s + tol
                    && r.theta_l <= machine.theta_l + tol
                    && r.theta_s <= machine.theta_s + tol
            }
        }
    }

    /// Sort key: the area, then the sum of ranges (a zero-width FTM has zero
    /// area whatever its length).
    pub fn key(&self) -> (f64, f64) {
        let r = &self.required;
        (self.area, r.phi_l + r.phi_s + r.theta_l + r.theta_s)
    }
}

/// Two unit vectors perpendicular to `p` and to each other (right-handed).
fn basis(p: &V3) -> (V3, V3) {
    let helper = if p.x.abs() < 0.6 { V3::x() } else { V3::y() };
    let e1 = (helper - p * p.dot(&helper)).normalize();
    (e1, p.cross(&e1))
}

/// Angle between unit vectors, robust near 0 and π.
fn angle(a: &V3, b: &V3) -> f64 {
    a.cross(b).norm().atan2(a.dot(b))
}

/// Splits a needed width `θ` in the machine's Θ^L : Θ^S ratio (eq. 9).
fn split_theta(theta: f64, m: &AxisRanges) -> (f64, f64) {
    let total = m.theta_l + m.theta_s;
    if total > 0.0 {
        (theta * m.theta_l / total, theta * m.theta_s / total)
    } else {
        (theta, 0.0)
    }
}

/// Scratch of the C,A fan search.
#[derive(Debug, Default)]
pub struct FanScratch {
    pts: Vec<(f64, bool, f64)>,
    pre: Vec<[f64; 2]>,
    suf: Vec<[f64; 2]>,
    unfolded: Vec<f64>,
}

/// The C,A fan search for tool axis `p` (eq. 5–13) over the MD points `md`.
/// Returns the placements of least area and, when the machine's ranges are
/// given, the least-area one among those that fit (`tol` radians slack).
pub fn fan_search(
    p: &V3,
    md: &[V3],
    machine: &AxisRanges,
    tol: f64,
    scratch: &mut FanScratch,
) -> (Placement, Option<Placement>) {
    let (e1, e2) = basis(p);
    let place =
        |start: f64, width: f64, tilt_l_in_fan0: bool, phi_l: f64, phi_s: f64, one_sided: bool| {
            let (theta_l, theta_s) = split_theta(width, machine);
            // The basis great circle (C at zero) lies θ_S into the fan from its
            // start; positive tilt goes into the fan that needs φ_L.
            let mut zero = start + theta_s;
            if !tilt_l_in_fan0 {
                zero += PI;
            }
            let u = e1 * zero.cos() + e2 * zero.sin();
            Placement {
                tool_axis: *p,
                axis_1: *p,
                axis_2: p.cross(&u),
                required: AxisRanges {
                    phi_l,
                    phi_s,
                    theta_l,
                    theta_s,
                },
                area: (phi_l + phi_s) * (theta_l + theta_s),
                one_sided,
            }
        };
    if md.is_empty() {
        let z = place(0.0, 0.0, true, 0.0, 0.0, false);
        return (z, z.fits(MachineType::CA, machine, tol).then_some(z));
    }
    // α_j (longitude about p, eq. 5) folded modulo π, its half, β_j.
    scratch.pts.clear();
    scratch.unfolded.clear();
    for v in md {
        let a = v.dot(&e2).atan2(v.dot(&e1)).rem_euclid(TAU);
        let b = angle(p, v);
        scratch.unfolded.push(a);
        let (f, h) = if a >= PI { (a - PI, true) } else { (a, false) };
        scratch.pts.push((f.min(PI), h, b));
    }
    scratch.pts.sort_unstable_by(|x, y| x.0.total_cmp(&y.0));
    let n = scratch.pts.len();
    // Max β of each half over sorted prefixes [0, s) and suffixes [s, n).
    scratch.pre.clear();
    scratch.pre.resize(n + 1, [0.0; 2]);
    scratch.suf.clear();
    scratch.suf.resize(n + 1, [0.0; 2]);
    for s in 0..n {
        let (_, h, b) = scratch.pts[s];
        let mut next = scratch.pre[s];
        next[h as usize] = next[h as usize].max(b);
        scratch.pre[s + 1] = next;
    }
    for s in (0..n).rev() {
        let (_, h, b) = scratch.pts[s];
        let mut next = scratch.suf[s + 1];
        next[h as usize] = next[h as usize].max(b);
        scratch.suf[s] = next;
    }
    let mut best: Option<Placement> = None;
    let mut best_fit: Option<Placement> = None;
    let mut consider = |pl: Placement| {
        if best.is_none_or(|b| pl.key() < b.key()) {
            best = Some(pl);
        }
        if pl.fits(MachineType::CA, machine, tol) && best_fit.is_none_or(|b| pl.key() < b.key()) {
            best_fit = Some(pl);
        }
    };
    // CR1 at each point in folded order; CR2 is the previous one (eq. 6–8):
    // the fan pair ∇⁰ = [f_s, f_s + θ], ∇¹ = ∇⁰ + π leaves out the gap
    // before f_s. Points at or after f_s lie in ∇⁰ when in the first half;
    // points before it lie in ∇⁰ when in the second half (eq. 10).
    for s in 0..n {
        let width = if s == 0 {
            scratch.pts[n - 1].0 - scratch.pts[0].0
        } else {
            scratch.pts[s - 1].0 + PI - scratch.pts[s].0
        };
        let fan0 = scratch.suf[s][0].max(scratch.pre[s][1]);
        let fan1 = scratch.suf[s][1].max(scratch.pre[s][0]);
        let (phi_l, phi_s) = (fan0.max(fan1), fan0.min(fan1)); // eq. 11
        consider(place(
            scratch.pts[s].0,
            width,
            fan0 >= fan1,
            phi_l,
            phi_s,
            false,
        ));
    }
    // One fan only (all tilts positive): it must span all longitudes but
    // the largest gap between them.
    scratch.unfolded.sort_unstable_by(f64::total_cmp);
    let (mut gap, mut start) = (
        scratch.unfolded[0] + TAU - scratch.unfolded[n - 1],
        scratch.unfolded[0],
    );
    for w in scratch.unfolded.windows(2) {
        if w[1] - w[0] > gap {
            (gap, start) = (w[1] - w[0], w[1]);
        }
    }
    let phi = scratch.pts.iter().map(|x| x.2).fold(0.0, f64::max);
    consider(place(start, TAU - gap, true, phi, 0.0, true));
    (best.expect("at least one placement"), best_fit)
}

/// Cosine of the largest angle from the tool axis at which MD points still
/// take part in the convex hull (the hull needs an open hemisphere).
const HULL_MIN_DOT: f64 = 1e-6;
/// Extra `R1` directions tried, evenly over 180°, when some MD point is a
/// quarter turn or more from the tool axis and the hull is not defined.
const FALLBACK_R1_DIRECTIONS: usize = 72;

/// Scratch of the A,B search.
#[derive(Debug, Default)]
pub struct RectScratch {
    proj: Vec<(f64, f64, usize)>,
    hull: Vec<usize>,
    r1: Vec<V3>,
    bins: Vec<bool>,
    tan_vec: Vec<V3>,
    cross: Vec<V3>,
    ortho_pts: Vec<(f64, f64, usize)>,
    ortho: Vec<usize>,
}

/// A key that orders points `(x, y)` like `atan2(y, x)` does, in (−2, 2].
fn pseudo_angle(x: f64, y: f64) -> f64 {
    let d = x.abs() + y.abs();
    if d == 0.0 {
        return 0.0;
    }
    let r = y / d; // in [−1, 1]
    if x >= 0.0 {
        r
    } else if y >= 0.0 {
        2.0 - r
    } else {
        -2.0 - r
    }
}

/// The A,B search for tool axis `p` (eq. 14–21) over the MD points `md`.
/// `R1` directions closer than `r1_resolution` (radians; the sphere's cell
/// spacing is a good value) are tried once.
pub fn rect_search(
    p: &V3,
    md: &[V3],
    machine: &AxisRanges,
    tol: f64,
    r1_resolution: f64,
    scratch: &mut RectScratch,
) -> (Placement, Option<Placement>) {
    let (e1, e2) = basis(p);
    // Candidate R1 directions: the hull edges' great circles as EG1 (eq. 15).
    scratch.r1.clear();
    spherical_hull(p, md, &e1, &e2, scratch);
    let mut pts: Vec<V3> = Vec::with_capacity(scratch.hull.len() + 1);
    pts.push(*p);
    pts.extend(scratch.hull.iter().map(|&i| md[i]));
    for k in 0..pts.len() {
        let (a, b) = (pts[k], pts[(k + 1) % pts.len()]);
        let normal = a.cross(&b);
        let r1 = normal.cross(p);
        if r1.norm() > 1e-9 && normal.norm() > 1e-12 {
            scratch.r1.push(r1.normalize());
        }
    }
    let all_in_hull = md.iter().all(|v| v.dot(p) > HULL_MIN_DOT);
    if !all_in_hull || scratch.r1.is_empty() {
        for k in 0..FALLBACK_R1_DIRECTIONS {
            let t = PI * k as f64 / FALLBACK_R1_DIRECTIONS as f64;
            scratch.r1.push(e1 * t.cos() + e2 * t.sin());
        }
    }
    // R1 and −R1 give the same rectangle; directions closer than the
    // resolution give the same one to within it: keep one per bin.
    let bins = ((PI / r1_resolution.max(1e-6)).ceil() as usize).max(1);
    scratch.bins.clear();
    scratch.bins.resize(bins, false);
    scratch.r1.retain(|r| {
        let t = r.dot(&e2).atan2(r.dot(&e1)).rem_euclid(PI);
        let b = ((t / PI * bins as f64) as usize).min(bins - 1);
        !std::mem::replace(&mut scratch.bins[b], true)
    });
    // v·R1 with R1 ⊥ p depends only on v's orthogonal projection onto the
    // tangent plane at p, a linear function there: its extremes over the MD
    // points (and p, at the origin) are on the vertices of the projections'
    // planar hull.
    scratch.ortho_pts.clear();
    scratch.ortho_pts.push((0.0, 0.0, usize::MAX));
    scratch.ortho_pts.extend(
        md.iter()
            .enumerate()
            .map(|(i, v)| (v.dot(&e1), v.dot(&e2), i)),
    );
    let ortho_hull = planar_hull(&mut scratch.ortho_pts);
    scratch.ortho.clear();
    scratch.ortho.extend(
        ortho_hull
            .iter()
            .map(|&k| scratch.ortho_pts[k].2)
            .filter(|&i| i != usize::MAX),
    );
    scratch.tan_vec.clear();
    scratch.cross.clear();
    if !all_in_hull {
        scratch.cross.extend(md.iter().map(|v| p.cross(v)));
    } else {
        scratch.tan_vec.extend(
            scratch
                .hull
                .iter()
                .map(|&i| p.cross(&md[i]) / p.dot(&md[i])),
        );
    }
    let mut best: Option<Placement> = None;
    let mut best_fit: Option<Placement> = None;
    let n_r1 = scratch.r1.len();
    for k in 0..n_r1 {
        // Each hull edge is tried as EG1 and, as an extension, turned a quarter
        // (R1 and R2 swap roles), since the two axes' ranges differ.
        for r1 in [scratch.r1[k], p.cross(&scratch.r1[k])] {
            let r2 = p.cross(&r1); // eq. 16
            // V⁰: v projected onto the basis great circle (eq. 18); α: turn
            // about R1 from p to V⁰, β: latitude off it (eq. 17). The extreme
            // α lie on hull vertices (a half-space through R1 bounds each
            // level); the extreme β are the extreme v·R1 over all points.
            let (amax, amin) = if all_in_hull {
                // Inside the hemisphere tan α = (p×v)·R1 / (p·v), monotone in α.
                let (mut tmax, mut tmin) = (0.0f64, 0.0f64);
                for c in &scratch.tan_vec {
                    let t = c.dot(&r1);
                    tmax = tmax.max(t);
                    tmin = tmin.min(t);
                }
                (tmax.atan(), tmin.atan())
            } else {
                // α = atan2(y, x) with y = (p×v)·R1, x = p·v: compare a cheap
                // angle-monotone key, take atan2 of the two extremes only.
                let (mut kmax, mut kmin) = (0.0f64, 0.0f64);
                let (mut xy_max, mut xy_min) = ((1.0, 0.0), (1.0, 0.0));
                for (v, c) in md.iter().zip(&scratch.cross) {
                    let (x, y) = (p.dot(v), c.dot(&r1));
                    let k = pseudo_angle(x, y);
                    if k > kmax {
                        (kmax, xy_max) = (k, (x, y));
                    }
                    if k < kmin {
                        (kmin, xy_min) = (k, (x, y));
                    }
                }
                (xy_max.1.atan2(xy_max.0), xy_min.1.atan2(xy_min.0))
            };
            let (mut lmax, mut lmin) = (0.0f64, 0.0f64);
            for &i in &scratch.ortho {
                let l = md[i].dot(&r1);
                lmax = lmax.max(l);
                lmin = lmin.min(l);
            }
            let (bmax, bmin) = (lmax.min(1.0).asin(), lmin.max(-1.0).asin());
            // eq. 19 (the tool axis itself, α = β = 0, is always inside).
            let (phi_l, phi_s) = (amax.max(-amin), amax.min(-amin));
            let (theta_l, theta_s) = (bmax.max(-bmin), bmax.min(-bmin));
            let pl = Placement {
                tool_axis: *p,
                axis_1: r1,
                axis_2: r2,
                required: AxisRanges {
                    phi_l,
                    phi_s,
                    theta_l,
                    theta_s,
                },
                area: (phi_l + phi_s) * (theta_l + theta_s), // eq. 21
                one_sided: false,
            };
            if best.is_none_or(|b| pl.key() < b.key()) {
                best = Some(pl);
            }
            if pl.fits(MachineType::AB, machine, tol) && best_fit.is_none_or(|b| pl.key() < b.key())
            {
                best_fit = Some(pl);
            }
        }
    }
    (best.expect("fallback directions are never empty"), best_fit)
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

/// Convex hull (counter-clockwise about `p`) of `p` and the MD points in the
/// open hemisphere around `p`, as indices into `md` (`p` itself left out).
///
/// A great circle through two points of the hemisphere maps to a straight
/// line under the gnomonic (central) projection onto the tangent plane at
/// `p`, so the spherical hull is the planar hull of the projected points;
/// its edges are the great circles whose supporting-vertex test is eq. 14.
fn spherical_hull(p: &V3, md: &[V3], e1: &V3, e2: &V3, scratch: &mut RectScratch) {
    scratch.proj.clear();
    scratch.proj.push((0.0, 0.0, usize::MAX));
    for (i, v) in md.iter().enumerate() {
        let d = v.dot(p);
        if d > HULL_MIN_DOT {
            scratch.proj.push((v.dot(e1) / d, v.dot(e2) / d, i));
        }
    }
    let mut hull = planar_hull(&mut scratch.proj);
    let pts = &scratch.proj;
    scratch.hull.clear();
    // Rotate so that `p` (if it is a hull vertex) is dropped; the caller puts
    // it first, which keeps the cyclic order when it is a vertex.
    if let Some(pos) = hull.iter().position(|&i| pts[i].2 == usize::MAX) {
        hull.rotate_left(pos);
        scratch.hull.extend(hull[1..].iter().map(|&i| pts[i].2));
    } else {
        scratch.hull.extend(hull.iter().map(|&i| pts[i].2));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::setup::machine::RotaryAxis;
    use crate::setup::machine::RotaryKey;

    fn ranges(deg: [f64; 4]) -> AxisRanges {
        AxisRanges::from_degrees(deg[0], deg[1], deg[2], deg[3]).unwrap()
    }

    fn dir(tilt_deg: f64, azimuth_deg: f64) -> V3 {
        let (t, a) = (tilt_deg.to_radians(), azimuth_deg.to_radians());
        V3::new(t.sin() * a.cos(), t.sin() * a.sin(), t.cos())
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
        let (best, fit) = fan_search(&V3::z(), &md, &machine, 1e-9, &mut FanScratch::default());
        let fit = fit.expect("fits");
        assert_eq!(best, fit);
        // Every MD point is reached by the kinematics of a caB machine set up
        // this way within the needed ranges: C about the tool axis, then tilt.
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
        for v in &md {
            let mut reached = false;
            for ci in 0..=360 {
                let c = -r.theta_s + (r.theta_l + r.theta_s) * ci as f64 / 360.0;
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
        // Known answer: the fold of these longitudes mod 180° is
        // {10, 60, 20, 50, 120}; the largest gap is 120 → 190 (70°), so the
        // fans are 110° wide.
        assert!(
            (r.theta_l + r.theta_s - 110f64.to_radians()).abs() < 1e-9,
            "{r:?}"
        );
    }

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
        let (best, fit) = rect_search(
            &V3::z(),
            &md,
            &machine,
            1e-9,
            1e-3,
            &mut RectScratch::default(),
        );
        let fit = fit.expect("fits");
        assert_eq!(best, fit);
        let got = fit.required.degrees();
        // φ (R1) 30 and 20, θ 15 and 10: found exactly from the hull edges
        // on the meridians α = −20° and α = 30°.
        for (g, e) in got.iter().zip([30.0, 20.0, 15.0, 10.0]) {
            assert!((g - e).abs() < 1e-6, "{got:?}");
        }
        assert!(fit.axis_1.cross(&r1).norm() < 1e-9);
    }

    #[test]
    fn pseudo_angle_orders_like_atan2() {
        let mut pts: Vec<(f64, f64)> = (0..360)
            .map(|k| {
                let a = (k as f64 * 1.003 - 179.5).to_radians();
                (a.cos() * 2.0, a.sin() * 2.0)
            })
            .collect();
        pts.sort_by(|a, b| pseudo_angle(a.0, a.1).total_cmp(&pseudo_angle(b.0, b.1)));
        for w in pts.windows(2) {
            assert!(w[0].1.atan2(w[0].0) < w[1].1.atan2(w[1].0));
        }
    }

    #[test]
    fn no_md_points_need_no_motion() {
        let m = ranges([0.0, 0.0, 0.0, 0.0]);
        let (b, f) = fan_search(&V3::z(), &[], &m, 0.0, &mut FanScratch::default());
        assert_eq!((b.area, f.is_some()), (0.0, true));
        let (b, f) = rect_search(&V3::z(), &[], &m, 0.0, 1e-3, &mut RectScratch::default());
        assert_eq!((b.area, f.is_some()), (0.0, true));
    }
}
