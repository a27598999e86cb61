//! Tool interference (gouge) detection and tool-path correction, seed `003_…` §2.
//!
//! The design surface is given by its cutter-contact (CC) candidates: the
//! mesh's vertices plus points sampled on its edges and faces at
//! [`GougeConfig::sample_spacing`] ([`CcSurface`]). A CL path is a polyline of
//! **tool-tip** positions (the lowest point of the cutter on its axis).
//!
//! **Detection (§2.1).** For each CL pair `p^m → p^{m+1}` only the CC points
//! inside the detection range (eq. 1: the pair's XY box grown by the cutter
//! radius) are looked at, through an XY grid ([`index::Grid2`]). A CC point
//! interferes when it lies inside the volume the cutter sweeps along the pair.
//! Its *interference depth* is how far the pair would have to be lifted along
//! the tool axis to clear it; for a ball this is zero exactly when the
//! distance `d` of eq. 4–5 equals `R`. The two cases of Fig. 3 are reported:
//! [`InterferenceCase::AlongMove`] (the cutter is deepest between the two CL
//! points, Fig. 3a) and [`InterferenceCase::AtEndpoint`] (deepest at a CL point,
//! which catches CC points beside or beyond the move, Fig. 3b).
//!
//! **Correction (§2.2).** CL points are first lifted until they touch the
//! surface (eq. 7 at the CL point, eq. 8's case). Then every pair that still
//! interferes gets a new CL point where the cutter passes deepest under the
//! interfering CC point (eq. 6, the foot of the perpendicular), lifted along Z
//! until it touches the surface (eq. 7), and the two halves are checked again.
//! Lifting a 3-axis CL point never creates interference, so the loop only
//! removes material from the cut. What is left above the design surface is
//! reported as [`RestRegion`]s (the rest-machining regions).

pub mod index;
pub mod sweep;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::cutter::Cutter;
use crate::mesh::{P3, TriMesh};
use index::Grid2;
use sweep::{profile_height, swept_bottom, touch_height, xy_distance_to_segment};

/// Refuse to sample a surface into more CC points than this (memory guard:
/// 40 M points are about 1 GB).
pub const MAX_CC_POINTS: usize = 40_000_000;

/// Where along a move the interference is deepest closer to an end than this
/// (as a fraction of the move) counts as the endpoint case of Fig. 3b.
const ENDPOINT_FRACTION: f64 = 1e-9;

/// Nested splits of one CL pair beyond this fall back to lifting the pair as a
/// whole (a guard; a real surface needs far fewer).
const MAX_SPLITS_PER_PAIR: usize = 4096;

/// Gouge check and correction settings. Serde field names are kebab-case.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", default, deny_unknown_fields)]
pub struct GougeConfig {
    /// Allowed overcut, mm. Default 0.05 (the seed's example).
    pub tolerance: f64,
    /// Spacing of CC points sampled on the mesh's edges and faces, mm.
    /// Default 0.2. With a ball of radius `R`, material between samples can
    /// hide an interference of about `spacing² / (8R)` (0.0005 mm at R = 10).
    pub sample_spacing: f64,
    /// The correction lifts until no pair interferes by more than this, mm;
    /// must be below `tolerance` (room for sampling and fitting). Default 0.005.
    pub correction_target: f64,
    /// Moves shorter than this (XY, mm) are lifted whole instead of split.
    /// Default 0.01.
    pub min_move: f64,
    /// Depths at or below this count as touching, not interfering, mm
    /// (round-off of a path computed on the same surface). Default 1e-6.
    pub contact_epsilon: f64,
}

impl Default for GougeConfig {
    fn default() -> Self {
        Self {
            tolerance: 0.05,
            sample_spacing: 0.2,
            correction_target: 0.005,
            min_move: 0.01,
            contact_epsilon: 1e-6,
        }
    }
}

/// Why a gouge check could not run.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GougeError {
    /// A setting is not finite and positive, or the target exceeds the tolerance.
    #[error("gouge config field `{field}` = {value}: {why}")]
    Config {
        /// The field name (kebab-case, as in the config file).
        field: &'static str,
        /// Its value.
        value: f64,
        /// What is wrong.
        why: &'static str,
    },
    /// The mesh would need too many CC points at this spacing.
    #[error(
        "sampling the surface every {spacing} mm needs about {needed} CC points (limit {MAX_CC_POINTS}); use a larger sample spacing"
    )]
    TooManySamples {
        /// Points needed.
        needed: usize,
        /// The spacing asked for, mm.
        spacing: f64,
    },
    /// A CL point has a NaN or infinite coordinate.
    #[error("CL point {index}: coordinate is not finite")]
    NonFinitePath {
        /// Index in the path (0-based).
        index: usize,
    },
}

impl GougeConfig {
    /// Checks every field.
    pub fn validated(self) -> Result<Self, GougeError> {
        let pos = |field, value: f64| {
            if value.is_finite() && value > 0.0 {
                Ok(())
            } else {
                Err(GougeError::Config {
                    field,
                    value,
                    why: "must be finite and > 0",
                })
            }
        };
        pos("tolerance", self.tolerance)?;
        pos("sample-spacing", self.sample_spacing)?;
        pos("correction-target", self.correction_target)?;
        pos("min-move", self.min_move)?;
        pos("contact-epsilon", self.contact_epsilon)?;
        if self.correction_target > self.tolerance {
            return Err(GougeError::Config {
                field: "correction-target",
                value: self.correction_target,
                why: "must not exceed the tolerance",
            });
        }
        Ok(self)
    }
}

/// Checks that every CL point is finite.
pub fn check_path(path: &[P3]) -> Result<(), GougeError> {
    match path
        .iter()
        .position(|p| !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite()))
    {
        Some(index) => Err(GougeError::NonFinitePath { index }),
        None => Ok(()),
    }
}

/// The design surface as cutter-contact candidates with an XY index.
#[derive(Debug, Clone)]
pub struct CcSurface {
    /// The CC points, mm.
    pub points: Vec<P3>,
    grid: Grid2,
    /// Highest CC point per grid cell, to skip cells the cutter cannot reach.
    cell_max_z: Vec<f64>,
}

impl CcSurface {
    /// CC points of a mesh: its vertices, points every `spacing` mm along each
    /// edge (once per edge) and on rows `spacing` apart inside each face that
    /// does not face down (the number of points follows the area, so slivers
    /// cost little). A downward face of a closed part lies under an upward one
    /// everywhere, so a cutter coming from above meets the upward one first;
    /// its edges and corners are still sampled.
    pub fn from_mesh(mesh: &TriMesh, spacing: f64) -> Result<Self, GougeError> {
        if !(spacing.is_finite() && spacing > 0.0) {
            return Err(GougeError::Config {
                field: "sample-spacing",
                value: spacing,
                why: "must be finite and > 0",
            });
        }
        let mut needed = mesh.vertices.len() as f64;
        for t in 0..mesh.triangles.len() {
            let [a, b, c] = mesh.corners(t);
            let area = 0.5 * (b - a).cross(&(c - a)).norm();
            let perimeter = (b - a).norm() + (c - b).norm() + (a - c).norm();
            needed += 2.0 * area / (spacing * spacing) + perimeter / spacing + 3.0;
        }
        if needed > MAX_CC_POINTS as f64 {
            return Err(GougeError::TooManySamples {
                needed: needed.min(usize::MAX as f64) as usize,
                spacing,
            });
        }
        let mut points = mesh.vertices.clone();
        let mut edges = std::collections::HashSet::new();
        for (t, tri) in mesh.triangles.iter().enumerate() {
            for (i, j) in [(0, 1), (1, 2), (2, 0)] {
                let key = (tri[i].min(tri[j]), tri[i].max(tri[j]));
                if edges.insert(key) {
                    let (p, q) = (mesh.vertices[key.0 as usize], mesh.vertices[key.1 as usize]);
                    let n = ((q - p).norm() / spacing).ceil().max(1.0) as usize;
                    for k in 1..n {
                        points.push(p + (q - p) * (k as f64 / n as f64));
                    }
                }
            }
            if mesh.normals[t].z < 0.0 {
                continue;
            }
            // Rows parallel to the longest edge a–b, `spacing` apart towards c.
            let [a0, b0, c0] = mesh.corners(t);
            let (a, b, c) = [(a0, b0, c0), (b0, c0, a0), (c0, a0, b0)]
                .into_iter()
                .max_by(|x, y| (x.1 - x.0).norm().total_cmp(&(y.1 - y.0).norm()))
                .expect("three edges");
            let base = (b - a).norm();
            let height = 2.0 * 0.5 * (b - a).cross(&(c - a)).norm() / base;
            let rows = (height / spacing).ceil() as usize;
            for i in 1..rows {
                let v = i as f64 / rows as f64;
                let (left, right) = (a + (c - a) * v, b + (c - b) * v);
                let cols = ((right - left).norm() / spacing).ceil() as usize;
                for k in 1..cols {
                    points.push(left + (right - left) * (k as f64 / cols as f64));
                }
            }
        }
        Ok(Self::from_points(points, spacing.max(1e-3) * 8.0))
    }

    /// Uses the given points as CC points, indexed in cells of about `cell` mm.
    pub fn from_points(points: Vec<P3>, cell: f64) -> Self {
        let grid = Grid2::of_points(points.iter().map(|p| [p.x, p.y]), cell);
        let cell_max_z = (0..grid.cell_count())
            .map(|c| {
                grid.cell_items(c)
                    .iter()
                    .map(|&i| points[i as usize].z)
                    .fold(f64::NEG_INFINITY, f64::max)
            })
            .collect();
        Self {
            points,
            grid,
            cell_max_z,
        }
    }

    /// Calls `visit` with every CC point in the XY rectangle's cells whose
    /// highest point is above `skip_below(cell_rect)`.
    fn near_pruned(
        &self,
        rect: [f64; 4],
        skip_below: impl Fn(&[f64; 4]) -> f64,
        mut visit: impl FnMut(&P3),
    ) {
        self.grid.query_cells(rect, |c, cell_rect, ids| {
            if self.cell_max_z[c] <= skip_below(&cell_rect) {
                return;
            }
            for &i in ids {
                visit(&self.points[i as usize]);
            }
        });
    }

    /// Tip height at which the cutter, lowered along Z at `(x, y)`, first
    /// touches a CC point (drop-cutter); `None` if no CC point is within reach.
    pub fn drop_height(&self, cutter: &Cutter, x: f64, y: f64) -> Option<f64> {
        let r = cutter.radius();
        let mut best: Option<f64> = None;
        self.grid
            .query_cells([x - r, y - r, x + r, y + r], |c, cell, ids| {
                // No point of this cell can hold the cutter higher than its
                // highest point minus the profile at the cell's nearest place.
                let (cx, cy) = (0.5 * (cell[0] + cell[2]), 0.5 * (cell[1] + cell[3]));
                let half_diag = 0.5 * (cell[2] - cell[0]).hypot(cell[3] - cell[1]);
                let rmin = ((cx - x).hypot(cy - y) - half_diag).max(0.0);
                let Some(h) = profile_height(cutter, rmin) else {
                    return;
                };
                if best.is_some_and(|b| self.cell_max_z[c] - h <= b) {
                    return;
                }
                for &i in ids {
                    if let Some(z) = touch_height(cutter, x, y, &self.points[i as usize])
                        && best.is_none_or(|b| z > b)
                    {
                        best = Some(z);
                    }
                }
            });
        best
    }
}

/// Which case of Fig. 3 an interference is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum InterferenceCase {
    /// Fig. 3a: the cutter is deepest under the CC point between the two CL
    /// points (`‖v1‖ > ‖v2‖ cos θ`, `d < R`).
    AlongMove,
    /// Fig. 3b: deepest at a CL point itself; the CC point lies beside or
    /// beyond the move (`d` measured from the CL point, eq. 5).
    AtEndpoint,
}

/// The deepest interference of one CL pair.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PairInterference {
    /// Index `m` of the pair `p^m → p^{m+1}`.
    pub pair: usize,
    /// Interference depth along the tool axis, mm (> 0).
    pub depth: f64,
    /// The CC point most interfered with.
    pub cc: [f64; 3],
    /// Where along the move the cutter is deepest under it (0..1).
    pub t: f64,
    /// Fig. 3a or 3b.
    pub case: InterferenceCase,
}

/// Result of checking a whole path.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Detection {
    /// CL pairs checked.
    pub pairs_checked: usize,
    /// CC points compared with a swept cutter (after the detection range).
    pub cc_tests: u64,
    /// Every pair that interferes by more than the threshold, in path order.
    pub interferences: Vec<PairInterference>,
}

impl Detection {
    /// Largest interference depth, 0 when none.
    pub fn max_depth(&self) -> f64 {
        self.interferences
            .iter()
            .map(|i| i.depth)
            .fold(0.0, f64::max)
    }
}

/// The deepest interference of the move `a → b` with the surface deeper than
/// `threshold`, and the number of CC points tested.
pub fn pair_interference(
    cutter: &Cutter,
    surface: &CcSurface,
    a: &P3,
    b: &P3,
    threshold: f64,
) -> (Option<(f64, P3, f64)>, u64) {
    let r = cutter.radius();
    // Eq. 1: the detection range.
    let rect = [
        a.x.min(b.x) - r,
        a.y.min(b.y) - r,
        a.x.max(b.x) + r,
        a.y.max(b.y) + r,
    ];
    let z_low = a.z.min(b.z);
    let mut best: Option<(f64, P3, f64)> = None;
    let mut tests = 0u64;
    // A cell is skipped when even its highest point is below the cutter's
    // lowest possible surface over it: the lowest tip plus the profile at
    // the cell's smallest distance from the move.
    let skip_below = |cell: &[f64; 4]| {
        let (cx, cy) = (0.5 * (cell[0] + cell[2]), 0.5 * (cell[1] + cell[3]));
        let half_diag = 0.5 * (cell[2] - cell[0]).hypot(cell[3] - cell[1]);
        let rmin = (xy_distance_to_segment(a, b, cx, cy) - half_diag).max(0.0);
        z_low + profile_height(cutter, rmin).unwrap_or(0.0) + threshold
    };
    surface.near_pruned(rect, skip_below, |q| {
        let floor = best.map_or(threshold, |(d, _, _)| d);
        // Cheap bound: the cutter is never lower than its lowest tip plus the
        // profile at the smallest horizontal distance.
        if q.z - z_low <= floor {
            return;
        }
        let rmin = xy_distance_to_segment(a, b, q.x, q.y);
        let Some(hmin) = profile_height(cutter, rmin) else {
            return;
        };
        if q.z - (z_low + hmin) <= floor {
            return;
        }
        tests += 1;
        if let Some(s) = swept_bottom(cutter, a, b, q.x, q.y) {
            let depth = q.z - s.z;
            if depth > floor {
                best = Some((depth, *q, s.t));
            }
        }
    });
    (best, tests)
}

/// Checks every CL pair of `path` (in parallel) and reports those that
/// interfere by more than `threshold` mm.
pub fn detect(cutter: &Cutter, surface: &CcSurface, path: &[P3], threshold: f64) -> Detection {
    let pairs = path.len().saturating_sub(1);
    let found: Vec<(Option<PairInterference>, u64)> = (0..pairs)
        .into_par_iter()
        .map(|m| {
            let (hit, tests) =
                pair_interference(cutter, surface, &path[m], &path[m + 1], threshold);
            let hit = hit.map(|(depth, q, t)| PairInterference {
                pair: m,
                depth,
                cc: [q.x, q.y, q.z],
                t,
                case: if t <= ENDPOINT_FRACTION || t >= 1.0 - ENDPOINT_FRACTION {
                    InterferenceCase::AtEndpoint
                } else {
                    InterferenceCase::AlongMove
                },
            });
            (hit, tests)
        })
        .collect();
    Detection {
        pairs_checked: pairs,
        cc_tests: found.iter().map(|f| f.1).sum(),
        interferences: found.into_iter().filter_map(|f| f.0).collect(),
    }
}

/// A run of consecutive corrected CL points lifted above the naive path by
/// more than the tolerance: material the corrected path leaves (rest machining).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RestRegion {
    /// First corrected CL point of the run.
    pub first: usize,
    /// Last corrected CL point of the run.
    pub last: usize,
    /// Largest lift in the run, mm.
    pub max_lift: f64,
    /// XY box of the run `[xmin, ymin, xmax, ymax]`.
    pub xy_box: [f64; 4],
}

/// A corrected path and what the correction did.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Correction {
    /// Corrected CL points (tool tip).
    pub path: Vec<[f64; 3]>,
    /// Per corrected point, its height above the naive path at the same place, mm.
    pub lift: Vec<f64>,
    /// Original CL points that were lifted.
    pub lifted_points: usize,
    /// CL points inserted (eq. 6–7).
    pub inserted_points: usize,
    /// Pairs that interfered before correction (depth > contact epsilon).
    pub interfering_pairs_before: usize,
    /// Deepest interference before correction, mm.
    pub max_depth_before: f64,
    /// Deepest interference left on the CC points after correction, mm.
    pub max_depth_after: f64,
    /// Where the corrected path leaves more than the tolerance of material.
    pub rest_regions: Vec<RestRegion>,
}

impl Correction {
    /// The corrected path as points.
    pub fn points(&self) -> Vec<P3> {
        self.path
            .iter()
            .map(|p| P3::new(p[0], p[1], p[2]))
            .collect()
    }
}

/// One CL point of the corrected path with the naive height at its place.
#[derive(Debug, Clone, Copy)]
struct Cl {
    p: P3,
    naive_z: f64,
}

/// Corrects `path` so that no CL pair interferes with the surface by more than
/// `config.correction_target` (eq. 6–8), and reports what is left uncut.
pub fn correct(
    cutter: &Cutter,
    surface: &CcSurface,
    path: &[P3],
    config: &GougeConfig,
) -> Result<Correction, GougeError> {
    let config = config.validated()?;
    check_path(path)?;
    // Eq. 7 at the CL points themselves (also eq. 8's case: a CC point
    // beyond the end of a move is cleared by lifting that end).
    let lifted: Vec<Cl> = path
        .par_iter()
        .map(|p| {
            let z = surface.drop_height(cutter, p.x, p.y).map_or(p.z, |d| {
                if d > p.z + config.contact_epsilon {
                    d
                } else {
                    p.z
                }
            });
            Cl {
                p: P3::new(p.x, p.y, z),
                naive_z: p.z,
            }
        })
        .collect();
    let lifted_points = lifted.iter().filter(|c| c.p.z != c.naive_z).count();
    // Pairs that still interfere after the lift, found in parallel; the
    // others are copied as they are.
    let lifted_points_only: Vec<P3> = lifted.iter().map(|c| c.p).collect();
    let after_lift = detect(cutter, surface, &lifted_points_only, config.contact_epsilon);
    // With nothing lifted the naive path is the lifted one: no second check.
    let before = if lifted_points == 0 {
        after_lift.clone()
    } else {
        detect(cutter, surface, path, config.contact_epsilon)
    };
    let flagged: Vec<usize> = after_lift
        .interferences
        .iter()
        .filter(|i| i.depth > config.correction_target)
        .map(|i| i.pair)
        .collect();
    // Each flagged pair is refined on its own, in parallel; its chain starts
    // and ends with the pair's (possibly further lifted) end points.
    let chains: std::collections::HashMap<usize, Vec<Cl>> = flagged
        .par_iter()
        .map(|&m| {
            let chain = refine_pair(
                cutter,
                surface,
                lifted[m],
                lifted[m + 1],
                (&path[m], &path[m + 1]),
                &config,
            );
            (m, chain)
        })
        .collect();
    let mut out: Vec<Cl> = Vec::with_capacity(path.len() + chains.len());
    let mut inserted = 0;
    for m in 0..lifted.len() {
        // A shared end point takes the highest lift any of its pairs asked
        // for (lifting is always safe).
        let mut point = lifted[m];
        if let Some(c) = m.checked_sub(1).and_then(|k| chains.get(&k)) {
            point.p.z = point.p.z.max(c[c.len() - 1].p.z);
        }
        if let Some(c) = chains.get(&m) {
            point.p.z = point.p.z.max(c[0].p.z);
        }
        out.push(point);
        if let Some(c) = chains.get(&m) {
            out.extend_from_slice(&c[1..c.len() - 1]);
            inserted += c.len() - 2;
        }
    }
    let corrected: Vec<P3> = out.iter().map(|c| c.p).collect();
    let after = detect(cutter, surface, &corrected, config.contact_epsilon);
    let lift: Vec<f64> = out.iter().map(|c| c.p.z - c.naive_z).collect();
    Ok(Correction {
        rest_regions: rest_regions(&corrected, &lift, config.tolerance),
        path: corrected.iter().map(|p| [p.x, p.y, p.z]).collect(),
        lift,
        lifted_points,
        inserted_points: inserted,
        interfering_pairs_before: before.interferences.len(),
        max_depth_before: before.max_depth(),
        max_depth_after: after.max_depth(),
    })
}

/// Splits and lifts one interfering pair until no part of it interferes by
/// more than the correction target (eq. 6–7, recursively). Returns the chain
/// from the (possibly lifted) start to the (possibly lifted) end.
fn refine_pair(
    cutter: &Cutter,
    surface: &CcSurface,
    start: Cl,
    end: Cl,
    naive: (&P3, &P3),
    config: &GougeConfig,
) -> Vec<Cl> {
    let mut out = vec![start];
    let mut stack = vec![end];
    let mut splits = 0;
    while let Some(&next) = stack.last() {
        let cur = *out.last().expect("out starts with the first point");
        let (hit, _) =
            pair_interference(cutter, surface, &cur.p, &next.p, config.correction_target);
        let Some((depth, _, t)) = hit else {
            out.push(next);
            stack.pop();
            continue;
        };
        let xy_len = (next.p.x - cur.p.x).hypot(next.p.y - cur.p.y);
        if xy_len <= config.min_move || splits >= MAX_SPLITS_PER_PAIR {
            // Lifting both ends by the depth clears every CC point of this
            // move; lifting never makes another move interfere.
            out.last_mut().expect("non-empty").p.z += depth;
            let mut lifted_next = next;
            lifted_next.p.z += depth;
            out.push(lifted_next);
            stack.pop();
            continue;
        }
        splits += 1;
        // Eq. 6: the new CL point where the cutter passes deepest; eq. 7:
        // lifted along Z until it touches the surface.
        let c_xy = cur.p + (next.p - cur.p) * t;
        let line_z = c_xy.z;
        let z = surface
            .drop_height(cutter, c_xy.x, c_xy.y)
            .map_or(line_z, |d| d.max(line_z));
        // The naive height at this place, on the original move.
        let naive_z = naive_at(naive.0, naive.1, c_xy.x, c_xy.y);
        stack.push(Cl {
            p: P3::new(c_xy.x, c_xy.y, z),
            naive_z,
        });
    }
    out
}

/// Height of the naive move `a → b` at the XY place nearest `(x, y)`.
fn naive_at(a: &P3, b: &P3, x: f64, y: f64) -> f64 {
    let (ux, uy) = (b.x - a.x, b.y - a.y);
    let uu = ux * ux + uy * uy;
    let t = if uu > 0.0 {
        (((x - a.x) * ux + (y - a.y) * uy) / uu).clamp(0.0, 1.0)
    } else {
        0.0
    };
    a.z + t * (b.z - a.z)
}

/// Groups consecutive points lifted by more than `tolerance`.
fn rest_regions(path: &[P3], lift: &[f64], tolerance: f64) -> Vec<RestRegion> {
    let mut regions: Vec<RestRegion> = Vec::new();
    for (i, (p, &l)) in path.iter().zip(lift).enumerate() {
        if !(l > tolerance) {
            continue;
        }
        match regions.last_mut() {
            Some(r) if r.last + 1 == i => {
                r.last = i;
                r.max_lift = r.max_lift.max(l);
                r.xy_box = [
                    r.xy_box[0].min(p.x),
                    r.xy_box[1].min(p.y),
                    r.xy_box[2].max(p.x),
                    r.xy_box[3].max(p.y),
                ];
            }
            _ => regions.push(RestRegion {
                first: i,
                last: i,
                max_lift: l,
                xy_box: [p.x, p.y, p.x, p.y],
            }),
        }
    }
    regions
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plane_points(z: f64) -> CcSurface {
        let mut pts = Vec::new();
        for i in 0..=40 {
            for j in 0..=40 {
                pts.push(P3::new(i as f64 * 0.5, j as f64 * 0.5, z));
            }
        }
        CcSurface::from_points(pts, 2.0)
    }

    #[test]
    fn ball_depth_is_r_minus_d_for_a_point_beside_a_horizontal_move() {
        // One CC point beside the move (lateral distance 3) and above the tip.
        let cutter = Cutter::Ball { diameter: 10.0 };
        let q = P3::new(5.0, 3.0, 2.0);
        let s = CcSurface::from_points(vec![q], 1.0);
        let a = P3::new(0.0, 0.0, 0.0);
        let b = P3::new(10.0, 0.0, 0.0);
        let det = detect(&cutter, &s, &[a, b], 1e-9);
        assert_eq!(det.interferences.len(), 1);
        let i = det.interferences[0];
        assert_eq!(i.case, InterferenceCase::AlongMove);
        // Vertical depth: q.z minus the ball's lower surface at r = 3.
        let want = 2.0 - (5.0 - (25.0f64 - 9.0).sqrt());
        assert!((i.depth - want).abs() < 1e-9);
        // Eq. 4: d from the ball centre line; d < R exactly when depth > 0.
        let d = ((q.y - 0.0).powi(2) + (q.z - 5.0).powi(2)).sqrt();
        assert!(d < 5.0);
        // Beyond the end (Fig. 3b).
        let q2 = P3::new(12.0, 0.0, 1.0);
        let s2 = CcSurface::from_points(vec![q2], 1.0);
        let i2 = detect(&cutter, &s2, &[a, b], 1e-9).interferences[0];
        assert_eq!(i2.case, InterferenceCase::AtEndpoint);
        assert!((i2.t - 1.0).abs() < 1e-12);
        let d5 = (q2 - (b + nalgebra::Vector3::new(0.0, 0.0, 5.0))).norm(); // eq. 5
        assert!(d5 < 5.0);
    }

    #[test]
    fn a_path_on_a_plane_does_not_interfere_and_a_low_one_does() {
        let s = plane_points(1.0);
        for cutter in [
            Cutter::Ball { diameter: 6.0 },
            Cutter::Flat { diameter: 6.0 },
            Cutter::Bull {
                diameter: 6.0,
                corner_radius: 1.0,
            },
        ] {
            let on: Vec<P3> = (0..10).map(|i| P3::new(5.0 + i as f64, 7.0, 1.0)).collect();
            assert!(detect(&cutter, &s, &on, 1e-9).interferences.is_empty());
            let low: Vec<P3> = on.iter().map(|p| P3::new(p.x, p.y, 0.7)).collect();
            let det = detect(&cutter, &s, &low, 1e-9);
            assert_eq!(det.interferences.len(), 9, "{cutter}");
            assert!((det.max_depth() - 0.3).abs() < 1e-9);
            let fixed = correct(&cutter, &s, &low, &GougeConfig::default()).unwrap();
            assert!(fixed.max_depth_after <= GougeConfig::default().correction_target);
            assert!(fixed.path.iter().all(|p| (p[2] - 1.0).abs() < 1e-9));
        }
    }

    #[test]
    fn bad_config_and_path_are_named() {
        let s = plane_points(0.0);
        let cutter = Cutter::Ball { diameter: 6.0 };
        let bad = GougeConfig {
            correction_target: 1.0,
            ..GougeConfig::default()
        };
        let e = correct(&cutter, &s, &[P3::origin()], &bad).unwrap_err();
        assert!(e.to_string().contains("correction-target"));
        let e = correct(
            &cutter,
            &s,
            &[P3::origin(), P3::new(f64::NAN, 0.0, 0.0)],
            &GougeConfig::default(),
        )
        .unwrap_err();
        assert_eq!(e, GougeError::NonFinitePath { index: 1 });
    }
}
