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
/// class-major over the cells: `column(w)[c]` has bit `k` set when cell `c`
/// is in the cone of class `64·w + k`. Identical cones share their MD
/// point, so the search runs over classes, not triangles.
#[derive(Debug, Clone)]
pub struct PvcClasses {
    /// Class of each patch (`None` when its cone is empty: no direction
    /// reaches it).
    pub class_of: Vec<Option<u32>>,
    /// Number of classes.
    pub classes: usize,
    /// A patch of each class (its cone is the class's).
    pub reps: Vec<usize>,
    words: usize,
    /// `words` columns of `cells` words each.
    columns: Vec<u64>,
    cells: usize,
}

/// A fast hash of a row of the map (the classes are then checked bit for
/// bit).
fn row_hash(row: &[u64]) -> u64 {
    const K: u64 = 0x9E37_79B9_7F4A_7C15;
    row.iter().fold(row.len() as u64, |h, &w| {
        (h.rotate_left(23) ^ w).wrapping_mul(K)
    })
}

/// The 64×64 bit matrix `m` transposed: bit `j` of `m[i]` becomes bit `i`
/// of `m[j]`.
fn transpose64(m: &mut [u64; 64]) {
    let mut width = 32;
    let mut mask: u64 = 0x0000_0000_FFFF_FFFF;
    while width != 0 {
        let mut k = 0;
        while k < 64 {
            for i in k..k + width {
                let t = ((m[i] >> width) ^ m[i + width]) & mask;
                m[i] ^= t << width;
                m[i + width] ^= t;
            }
            k += 2 * width;
        }
        width >>= 1;
        mask ^= mask << width;
    }
}

/// Rows and columns of the classes' ordering grid.
const ORDER_ROWS: f64 = 64.0;

/// The cell of the ordering grid (row, serpentine column) of a sum of cell
/// directions, and the same as reals before truncation.
fn grid_cell(sum: &V3) -> ((u32, i64), [f64; 2]) {
    let theta = sum.z.atan2(sum.xy().norm()) + PI / 2.0; // 0..π
    let phi = sum.y.atan2(sum.x) + PI; // 0..2π
    let (row_f, col_f) = (theta / PI * ORDER_ROWS, phi / TAU * 2.0 * ORDER_ROWS);
    let row = (row_f as i64).min(ORDER_ROWS as i64 - 1);
    let col = col_f as i64;
    (
        (row as u32, if row % 2 == 0 { col } else { -col }),
        [row_f, col_f],
    )
}

/// The sum of the directions of the cells of `row`, one by one in cell
/// order: the mean direction the classes are ordered by.
fn row_sum(row: &[u64], cells: &[V3]) -> V3 {
    let mut sum = V3::zeros();
    for (w, bits) in row.iter().enumerate() {
        let mut bits = *bits;
        while bits != 0 {
            sum += cells[w * 64 + bits.trailing_zeros() as usize];
            bits &= bits - 1;
        }
    }
    sum
}

/// Sums of the directions of each whole byte of cells (8 cells), to add a
/// full byte of a row at once.
struct WordSums {
    bytes: Vec<V3>,
}

impl WordSums {
    fn new(cells: &[V3]) -> Self {
        let bytes = (0..cells.len().div_ceil(8))
            .map(|b| cells[b * 8..(b * 8 + 8).min(cells.len())].iter().sum())
            .collect();
        Self { bytes }
    }
}

/// The ordering grid cell of `row`: that of [`row_sum`], found from a sum
/// taken a byte of cells at a time where the row is full (most of a cone).
/// Both sums are of the same at most `n` unit vectors in another order, so
/// each differs from the exact sum by at most `γ_{n−1}·n` per coordinate;
/// when the quick sum's direction lies farther than twice that (turned
/// into an angle, plus a margin for the round-off of the angles) from every
/// edge of the grid, both fall in the same grid cell. Otherwise the cell
/// is that of [`row_sum`] itself.
fn order_key(row: &[u64], cells: &[V3], sums: &WordSums) -> (u32, i64) {
    let (sum, n) = quick_sum(row, cells, sums);
    let (key, [row_f, col_f]) = grid_cell(&sum);
    let n = n as f64;
    // γ_{n−1}·n per coordinate for each sum (unit vectors: coordinates at
    // most 1), both sums: a Euclidean distance of at most `gap`.
    let u = f64::EPSILON / 2.0;
    let gamma = n * u / (1.0 - n * u);
    let gap = 2.0 * 3f64.sqrt() * gamma * n * (1.0 + 1e-6);
    // The direction turns by at most `gap / (|sum| − gap)` (latitude), the
    // longitude by at most `gap / (|xy| − gap)`; the angles' own round-off
    // is far below the margin.
    const MARGIN: f64 = 1e-9;
    let (norm, flat) = (sum.norm(), sum.xy().norm());
    let safe = |f: f64, turn: f64| {
        let frac = f - f.floor();
        turn.is_finite() && turn >= 0.0 && frac.min(1.0 - frac) > turn + MARGIN
    };
    let turn_row = gap / (norm - gap) * ORDER_ROWS / PI;
    let turn_col = gap / (flat - gap) * 2.0 * ORDER_ROWS / TAU;
    if norm > gap && flat > gap && safe(row_f, turn_row) && safe(col_f, turn_col) {
        key
    } else {
        grid_cell(&row_sum(row, cells)).0
    }
}

/// The sum of [`row_sum`] taken a whole byte of cells at a time where the
/// row is full, and the number of cells summed.
fn quick_sum(row: &[u64], cells: &[V3], sums: &WordSums) -> (V3, u64) {
    let (mut sum, mut n) = (V3::zeros(), 0u64);
    for (w, &bits) in row.iter().enumerate() {
        if bits == 0 {
            continue;
        }
        n += u64::from(bits.count_ones());
        for byte in 0..8 {
            let b = bits >> (8 * byte) & 0xFF;
            if b == 0xFF {
                sum += sums.bytes[w * 8 + byte];
            } else {
                let mut b = b;
                while b != 0 {
                    sum += cells[w * 64 + byte * 8 + b.trailing_zeros() as usize];
                    b &= b - 1;
                }
            }
        }
    }
    (sum, n)
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
        let hashes: Vec<u64> = (0..map.patches())
            .into_par_iter()
            .map(|j| row_hash(map.pvc(j)))
            .collect();
        // Classes in the order of their first patch.
        let mut index: HashMap<u64, Vec<u32>> = HashMap::new();
        let mut reps: Vec<usize> = Vec::new();
        let mut first_class = Vec::with_capacity(map.patches());
        for (j, &h) in hashes.iter().enumerate() {
            let pvc = map.pvc(j);
            if pvc.iter().all(|w| *w == 0) {
                first_class.push(None);
                continue;
            }
            let same = index.entry(h).or_default();
            let k = match same.iter().find(|&&k| map.pvc(reps[k as usize]) == pvc) {
                Some(&k) => k,
                None => {
                    reps.push(j);
                    same.push((reps.len() - 1) as u32);
                    (reps.len() - 1) as u32
                }
            };
            first_class.push(Some(k));
        }
        let classes = reps.len();
        // Spatial order of the classes.
        let sums = WordSums::new(cells);
        let keys: Vec<(u32, i64)> = reps
            .par_iter()
            .map(|&j| order_key(map.pvc(j), cells, &sums))
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
        let reps: Vec<usize> = order.iter().map(|&old| reps[old as usize]).collect();
        // Each column: 64 classes' rows, transposed 64 cells at a time.
        let words = classes.div_ceil(64);
        let m = map.cells();
        let mut columns = vec![0u64; words * m];
        columns
            .par_chunks_mut(m)
            .enumerate()
            .for_each(|(w, column)| {
                let mut block = [0u64; 64];
                for cw in 0..m.div_ceil(64) {
                    for (i, b) in block.iter_mut().enumerate() {
                        let k = w * 64 + i;
                        *b = if k < classes { map.pvc(reps[k])[cw] } else { 0 };
                    }
                    transpose64(&mut block);
                    let n = (m - cw * 64).min(64);
                    column[cw * 64..cw * 64 + n].copy_from_slice(&block[..n]);
                }
            });
        Self {
            class_of,
            classes,
            reps,
            words,
            columns,
            cells: m,
        }
    }

    /// Bits of classes `64·w ..` per cell.
    fn column(&self, w: usize) -> &[u64] {
        &self.columns[w * self.cells..(w + 1) * self.cells]
    }

    /// Bits of the classes `64·w ..` that exist.
    fn full(&self, w: usize) -> u64 {
        if w + 1 == self.words && !self.classes.is_multiple_of(64) {
            (1u64 << (self.classes % 64)) - 1
        } else {
            u64::MAX
        }
    }

    /// The cells in every class's cone: the tool axes that reach all
    /// reachable patches without rotary motion (Group II empty).
    pub fn common_cells(&self) -> Vec<usize> {
        let mut all = vec![true; self.cells];
        for w in 0..self.words {
            let full = self.full(w);
            for (ok, &x) in all.iter_mut().zip(self.column(w)) {
                *ok &= x == full;
            }
        }
        (0..self.cells).filter(|&c| all[c]).collect()
    }
}

/// Reusable memory of one search thread.
#[derive(Debug, Default)]
pub struct Scratch {
    order: Vec<u32>,
    keys: Vec<f64>,
    /// Bucket of each cell, and where each bucket starts in `order`.
    bucket_of: Vec<u32>,
    buckets: Vec<u32>,
    fill: Vec<u32>,
    /// The MD cells of the last [`md_cells`] call.
    pub md: Vec<u32>,
    /// For each of `md`, one class whose MD point it is.
    pub md_class: Vec<u32>,
    /// Per step of the walk, the least class first reached there.
    step_first: Vec<u32>,
}

/// Most buckets of the counting sort of cells by distance from the
/// candidate (about one cell per bucket on smaller spheres).
const ORDER_BUCKETS: usize = 4096;

/// Group II and MD points for the tool axis `cells[candidate]`.
///
/// Walks the cells in order of angle from the candidate (eq. 4 for all
/// patches at once): the first cell of `PVC_j` met is `MD_j`. The candidate
/// itself comes first, so its classes are Group I (eq. 3) and get no MD
/// point. Cells at the same angle are taken in index order (the order of
/// [`nearer`]). Fills `scratch.md` with the distinct MD cells of Group II
/// (several patches can share one), `scratch.md_class` with one class of
/// each, and returns the number of Group II classes.
pub fn md_cells(
    classes: &PvcClasses,
    cells: &[V3],
    candidate: usize,
    scratch: &mut Scratch,
) -> usize {
    scratch.md.clear();
    scratch.md_class.clear();
    order_by_angle(cells, candidate, scratch);
    // Per step of the walk: the least class first reached there, and how
    // many. Each word of classes walks on its own until all of its classes
    // are reached (its column stays in cache); buckets are put in exact
    // order only when some word reaches them, and the walk usually stops
    // well before the far side of the sphere.
    scratch.step_first.clear();
    scratch.step_first.resize(cells.len(), u32::MAX);
    let mut sorted_to = 0usize;
    let mut last = 0;
    let mut group_ii = classes.classes;
    for w in 0..classes.words {
        let column = classes.column(w);
        let mut unassigned = classes.full(w);
        let mut step = 0;
        while unassigned != 0 {
            if step == sorted_to {
                sorted_to = sort_bucket_at(step, scratch) as usize;
            }
            let x = unassigned & column[scratch.order[step] as usize];
            if x != 0 {
                unassigned &= !x;
                let first = &mut scratch.step_first[step];
                *first = (*first).min((w * 64) as u32 + x.trailing_zeros());
                if step == 0 {
                    group_ii -= x.count_ones() as usize;
                }
            }
            step += 1;
        }
        last = last.max(step);
    }

    debug_assert!(
        scratch
            .order
            .first()
            .is_none_or(|&c| c as usize == candidate)
    );
    for step in 1..last {
        let first = scratch.step_first[step];
        if first != u32::MAX {
            scratch.md.push(scratch.order[step]);
            scratch.md_class.push(first);
        }
    }
    group_ii
}

/// Whether cell `a` comes before cell `b` in the walk from the direction
/// `p`: larger `p·d` first, then the lower index. The MD point of a class is
/// its first cell in this order, whichever way it is found.
pub fn nearer(p: &V3, cells: &[V3], a: u32, b: u32) -> bool {
    let (da, db) = (cells[a as usize].dot(p), cells[b as usize].dot(p));
    da > db || (da == db && a < b)
}

/// Cell indices in `scratch.order` by their bucket of angle from
/// `cells[candidate]` (a counting sort on the chord length, the candidate
/// first); [`sort_bucket_at`] puts a bucket in the exact order of
/// [`nearer`].
fn order_by_angle(cells: &[V3], candidate: usize, scratch: &mut Scratch) {
    let p = cells[candidate];
    let m = cells.len();
    let n_buckets = m.clamp(1, ORDER_BUCKETS);
    scratch.keys.clear();
    scratch.keys.extend(cells.iter().map(|c| -c.dot(&p)));
    scratch.keys[candidate] = f64::NEG_INFINITY;
    scratch.bucket_of.clear();
    scratch.bucket_of.extend(scratch.keys.iter().map(|&key| {
        // Chord length 0..2 from −p·d.
        let chord = (2.0 * (1.0 + key).max(0.0)).sqrt();
        ((chord * 0.5 * n_buckets as f64) as usize).min(n_buckets - 1) as u32
    }));
    scratch.buckets.clear();
    scratch.buckets.resize(n_buckets + 1, 0);
    for &b in &scratch.bucket_of {
        scratch.buckets[b as usize + 1] += 1;
    }
    for b in 0..n_buckets {
        scratch.buckets[b + 1] += scratch.buckets[b];
    }
    scratch.order.clear();
    scratch.order.resize(m, 0);
    scratch.fill.clear();
    scratch
        .fill
        .extend_from_slice(&scratch.buckets[..n_buckets]);
    for (i, &b) in scratch.bucket_of.iter().enumerate() {
        let slot = &mut scratch.fill[b as usize];
        scratch.order[*slot as usize] = i as u32;
        *slot += 1;
    }
}

/// Sorts the bucket that starts at position `at` of `scratch.order` into
/// the exact order of [`nearer`]; returns where the next bucket starts.
fn sort_bucket_at(at: usize, scratch: &mut Scratch) -> u32 {
    let b = scratch.bucket_of[scratch.order[at] as usize] as usize;
    let (s, e) = (scratch.buckets[b] as usize, scratch.buckets[b + 1] as usize);
    debug_assert_eq!(s, at);
    if e - s > 1 {
        let keys = &scratch.keys;
        scratch.order[s..e].sort_unstable_by(|x, y| {
            keys[*x as usize]
                .total_cmp(&keys[*y as usize])
                .then(x.cmp(y))
        });
    }
    e as u32
}

/// A placement's sort key: the area (eq. 13 / eq. 21, rad²), then the sum of
/// ranges (a zero-width FTM has zero area whatever its length).
pub type Key = (f64, f64);

/// Absolute slack of [`can_beat`] (rad² and rad).
const KEY_ABS_TOL: f64 = 1e-12;

/// Whether a key whose lower bound is `lower` can beat `incumbent` by more
/// than `rel` (relative) in area, or tie it in area and beat it by more than
/// `rel` in the sum of ranges.
pub fn can_beat(lower: Key, incumbent: Key, rel: f64) -> bool {
    let tol_a = incumbent.0.abs() * rel + KEY_ABS_TOL;
    let tol_s = incumbent.1.abs() * rel + KEY_ABS_TOL;
    lower.0 < incumbent.0 - tol_a
        || (lower.0 < incumbent.0 + tol_a && lower.1 < incumbent.1 - tol_s)
}

/// The lexicographically smaller key.
pub fn key_min(a: Key, b: Key) -> Key {
    if b < a { b } else { a }
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

    /// Sort key: the area, then the sum of ranges.
    pub fn key(&self) -> Key {
        let r = &self.required;
        (self.area, r.phi_l + r.phi_s + r.theta_l + r.theta_s)
    }
}

/// The answer of the search for one tool axis: the placement of least key,
/// the least that fits the machine, and certified lower bounds of both keys
/// (equal to the keys when the search is exact). `fit_lower` is `None` when
/// no placement fits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Solved {
    /// Least key.
    pub best: Placement,
    /// Least key among those that fit.
    pub fit: Option<Placement>,
    /// No placement for this tool axis has a smaller key.
    pub best_lower: Key,
    /// No fitting placement has a smaller key; `None`: none fits.
    pub fit_lower: Option<Key>,
}

/// Two unit vectors perpendicular to `p` and to each other (right-handed).
pub(super) fn basis(p: &V3) -> (V3, V3) {
    let helper = if p.x.abs() < 0.6 { V3::x() } else { V3::y() };
    let e1 = (helper - p * p.dot(&helper)).normalize();
    (e1, p.cross(&e1))
}

/// Angle between unit vectors, robust near 0 and π.
pub(super) fn angle(a: &V3, b: &V3) -> f64 {
    a.cross(b).norm().atan2(a.dot(b))
}

/// Splits a needed width `θ` in the machine's Θ^L : Θ^S ratio (eq. 9).
pub(super) fn split_theta(theta: f64, m: &AxisRanges) -> (f64, f64) {
    let total = m.theta_l + m.theta_s;
    if total > 0.0 {
        (theta * m.theta_l / total, theta * m.theta_s / total)
    } else {
        (theta, 0.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{TriMesh, WeldOptions};
    use crate::setup::samples::{rotated, teapot, z_to};
    use crate::setup::sphere::GeodesicSphere;
    use crate::setup::visibility::{VisibilityOptions, compute};

    #[test]
    fn transpose64_moves_bit_j_of_row_i_to_bit_i_of_row_j() {
        let mut state = 0x2545_F491_4F6C_DD1Du64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        for _ in 0..8 {
            let m: [u64; 64] = std::array::from_fn(|_| next());
            let mut t = m;
            transpose64(&mut t);
            for i in 0..64 {
                for j in 0..64 {
                    assert_eq!(m[i] >> j & 1, t[j] >> i & 1, "bit ({i}, {j})");
                }
            }
        }
    }

    /// The classes' ordering grid cell from the sum taken a byte at a time
    /// is that of the sum taken cell by cell, also for rows whose mean
    /// direction lies on an edge of the grid (there the two sums' round-off
    /// differ, and the quick sum alone puts some rows in the next cell).
    #[test]
    fn order_key_is_that_of_the_sum_cell_by_cell() {
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        // Half the directions random, the other half their mirror images
        // (y and z negated, then also x for some rows' halves): symmetric
        // rows sum to a direction on the edges `y = 0` and `z = 0`.
        const HALF: usize = 512;
        let mut cells: Vec<V3> = (0..HALF)
            .map(|_| {
                let z = 2.0 * next() - 1.0;
                let a = TAU * next();
                let r = (1.0 - z * z).sqrt();
                V3::new(r * a.cos(), r * a.sin(), z)
            })
            .collect();
        let mirrored: Vec<V3> = cells.iter().map(|c| V3::new(c.x, -c.y, -c.z)).collect();
        cells.extend(mirrored);
        let sums = WordSums::new(&cells);
        let words = 2 * HALF / 64;
        let (mut quick_wrong, mut edges) = (0, 0);
        for case in 0..4000 {
            let mut row = vec![0u64; words];
            let density = [0.3, 0.7, 0.95, 1.0][case % 4];
            for c in 0..HALF {
                // Whole bytes on or off often, so that both paths run.
                let on = if case % 3 == 0 {
                    next() < density
                } else {
                    (c / 8 + case) % 3 != 0 || next() < 0.2
                };
                if on {
                    row[c / 64] |= 1 << (c % 64);
                    if case % 5 != 4 {
                        // The mirror image too: the sum lies on the edges.
                        let m = c + HALF;
                        row[m / 64] |= 1 << (m % 64);
                    }
                }
            }
            let exact = grid_cell(&row_sum(&row, &cells)).0;
            assert_eq!(order_key(&row, &cells, &sums), exact, "case {case}");
            let (quick, _) = quick_sum(&row, &cells, &sums);
            quick_wrong += usize::from(grid_cell(&quick).0 != exact);
            edges += usize::from(case % 5 != 4);
        }
        assert!(edges > 3000);
        // The guard is needed: without it some rows change cells.
        assert!(quick_wrong > 0, "no row tested the guard");
    }

    /// The MD walk (one word of classes at a time, over the class-major
    /// columns) against the definition: each class not holding the
    /// candidate has its MD point at the first cell of its cone in the
    /// order of [`nearer`]; the walk lists each such cell once, in that
    /// order, with the least class whose MD point it is.
    #[test]
    fn md_cells_are_the_nearest_cells_of_each_cone() {
        let tilt = z_to(&V3::new(0.3, -0.2, 0.9).normalize());
        let mesh = TriMesh::from_triangles(
            &rotated(&teapot(10, 12, 5, 6), &tilt),
            WeldOptions::default(),
        )
        .expect("valid sample");
        let sphere = GeodesicSphere::with_frequency(6);
        let map = compute(&mesh, &sphere, VisibilityOptions::default(), &|_, _| {});
        let classes = PvcClasses::new(&map, sphere.cells());
        assert!(classes.classes > 64, "several words of classes");
        let dirs = sphere.cells();
        let mut scratch = Scratch::default();
        let mut points = 0;
        for candidate in (0..sphere.len()).step_by(7) {
            let p = dirs[candidate];
            let group_ii = md_cells(&classes, dirs, candidate, &mut scratch);
            let mut expected: Vec<(u32, u32)> = Vec::new();
            let mut outside = 0;
            for (k, &rep) in classes.reps.iter().enumerate() {
                if map.visible(rep, candidate) {
                    continue;
                }
                outside += 1;
                let md = (0..sphere.len() as u32)
                    .filter(|&c| map.visible(rep, c as usize))
                    .reduce(|a, b| if nearer(&p, dirs, b, a) { b } else { a })
                    .expect("a class's cone is not empty");
                match expected.iter_mut().find(|e| e.0 == md) {
                    Some(e) => e.1 = e.1.min(k as u32),
                    None => expected.push((md, k as u32)),
                }
            }
            expected.sort_by(|a, b| {
                if nearer(&p, dirs, a.0, b.0) {
                    std::cmp::Ordering::Less
                } else {
                    std::cmp::Ordering::Greater
                }
            });
            let got: Vec<(u32, u32)> = scratch
                .md
                .iter()
                .copied()
                .zip(scratch.md_class.iter().copied())
                .collect();
            assert_eq!(group_ii, outside, "candidate {candidate}");
            assert_eq!(got, expected, "candidate {candidate}");
            points += got.len();
        }
        assert!(points > 1000, "{points} MD points");
    }
}
