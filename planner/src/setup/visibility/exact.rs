//! The exact cell test of the binary spherical map: cell `i` is in `PVC_j`
//! when **some** direction of the cell (the spherical triangle, not only its
//! centre) reaches patch `j`.
//!
//! The centre test of [`super::compute`] is exact for the cell centres. A
//! cell whose centre is blocked can still hold visible directions only where
//! the boundary of the visible set crosses it: the horizon of the patch, or
//! the outline of the occluders seen from the patch. So, per patch:
//!
//! 1. The occluders the rasteriser processed (their union `U_p` holds every
//!    blocked centre) have an outline made of their edges whose neighbour
//!    across is missing, not processed, or on the same side of the edge as
//!    seen from the patch (a silhouette). A blocked cell that no such edge
//!    crosses lies wholly inside `U_p`, so wholly blocked: only the cells
//!    those edges cross, and the cells the horizon crosses, are candidates.
//! 2. Most candidates are settled without the hierarchy
//!    ([`Exact::certify`]): closed when the occluders flooded over the
//!    mesh from one covering a point of the cell have no outline edge
//!    crossing it, open when a ray at one of its test points reaches the
//!    patch.
//! 3. A candidate left is tested against every occluder whose cone meets it
//!    (found through the hierarchy, whatever the rasteriser skipped): first
//!    at nine points (corners, edge midpoints, half-way to the corners); if
//!    all are blocked, the occluders' outline edges and the horizon inside
//!    the cell are cut at their crossings with each other and with the
//!    cell's edges, and a point just off the open side of every piece is
//!    tested. A visible part of the cell is bounded by such a piece, and the
//!    open side of a piece is all visible or all blocked (coverage only
//!    changes across an outline edge), so this decides the cell, down to
//!    slivers thinner than [`WITNESS_OFFSET`] radians.
//!
//! A cell found visible this way is "upgraded"; a patch whose cone holds no
//! cell centre, only upgraded cells, is narrower than the cell spacing (see
//! `VisibilityMap::narrow`).

use std::f64::consts::{PI, TAU};

use bvh::bvh::BvhNode;
use nalgebra::{Point3, Vector3};

use super::{CAP_MARGIN, CellGrid, RayCaster, is_open};
use crate::setup::sphere::{CellChunks, GeodesicSphere};

mod contour;

pub(super) use contour::ContourTree;

type V3 = Vector3<f64>;

/// A visible piece of a cell thinner than this (radians) may be missed: the
/// test points sit this far off the outline edges.
pub const WITNESS_OFFSET: f64 = 1e-10;
/// Pieces of outline shorter than this (radians) get no test point of
/// their own (their neighbours' points are within round-off of them).
const MIN_PIECE: f64 = 1e-8;
/// [`Curve::cuts_with`] drops a point whose turn past an arc's end has a
/// sine above this (relative to its distance from the arc's axis).
const PAST_END: f64 = 1e-9;
/// Arcs longer than this many cell spacings are marked in pieces.
const ARC_PIECE_SPACINGS: f64 = 2.0;
/// [`Exact::mark_arc`] rules out a cell by its direction alone when the
/// piece of arc's `|pa × pb|` exceeds this and the direction lies this
/// much (as a sine) beyond the cell's radius from the piece's circle: then
/// every corner is at least `1e-13` off that circle in the products
/// `arc_meets_cell` takes, far above their round-off (`1e-16`).
const CLEAR_MIN_SIN: f64 = 1e-6;
const CLEAR_MARGIN: f64 = 1e-7;
/// Candidate cells per chunk of the gather's walk.
const GATHER_CHUNK: usize = 4;
/// No triangle on this side of an edge: [`RayCaster::across`].
pub(super) const NONE: u32 = u32::MAX;

/// The cells as spherical triangles.
#[derive(Debug)]
pub(super) struct CellShapes {
    corners: Vec<[V3; 3]>,
    /// Inward normals of the edges (corner `k` to `k + 1`): a direction is
    /// in the cell when its dot products with all three are `≥ 0`.
    edges: Vec<[V3; 3]>,
    dirs: Vec<V3>,
    /// Largest angle from a cell's direction to its corners (radians),
    /// widened for round-off, and its sine and cosine.
    radius: f64,
    cos_radius: f64,
    sin_radius: f64,
    spacing: f64,
}

impl CellShapes {
    pub(super) fn cos_radius(&self) -> f64 {
        self.cos_radius
    }

    pub(super) fn sin_radius(&self) -> f64 {
        self.sin_radius
    }

    pub(super) fn new(sphere: &GeodesicSphere) -> Self {
        let corners: Vec<[V3; 3]> = (0..sphere.len()).map(|i| sphere.corners(i)).collect();
        let edges = corners
            .iter()
            .map(|c| [0, 1, 2].map(|k| c[k].cross(&c[(k + 1) % 3]).normalize()))
            .collect();
        let radius = sphere.cell_radius() * (1.0 + 1e-6) + CAP_MARGIN;
        Self {
            corners,
            edges,
            dirs: sphere.cells().to_vec(),
            radius,
            cos_radius: radius.cos(),
            sin_radius: radius.sin(),
            spacing: sphere.spacing(),
        }
    }

    fn inside(&self, cell: usize, d: &V3) -> bool {
        self.edges[cell].iter().all(|e| e.dot(d) >= 0.0)
    }

    /// Largest `d·n` over the cell, and where.
    fn max_dot(&self, cell: usize, n: &V3) -> (f64, V3) {
        if self.inside(cell, n) {
            return (1.0, *n);
        }
        let c = &self.corners[cell];
        let mut best = (f64::NEG_INFINITY, c[0]);
        for p in c {
            if p.dot(n) > best.0 {
                best = (p.dot(n), *p);
            }
        }
        for k in 0..3 {
            // The maximum on the edge's great circle is at n projected onto
            // its plane; it counts if it lies within the edge.
            let e = &self.edges[cell][k];
            let p = n - e * e.dot(n);
            let norm = p.norm();
            if norm > 0.0 {
                let x = p / norm;
                let (a, b) = (c[k], c[(k + 1) % 3]);
                if a.cross(&x).dot(e) >= 0.0 && x.cross(&b).dot(e) >= 0.0 && x.dot(n) > best.0 {
                    best = (x.dot(n), x);
                }
            }
        }
        best
    }
}

/// The cone of directions from the patch's centroid through a triangle:
/// `d` is in it when `d·planes[k] ≥ 0` for `k = 0, 1, 2` (closed, as the ray
/// test counts edges as hits). `planes[k]` belongs to the triangle's edge
/// from corner `k` to corner `k + 1`.
#[derive(Debug, Clone, Copy)]
pub(super) struct Cone {
    planes: [V3; 3],
    /// Corner directions (not unit).
    dirs: [V3; 3],
    /// A cap around the cone: centre (unit) and cosine of its radius
    /// (`-1`: the cone may reach anywhere).
    pub(super) centre: V3,
    pub(super) cos_r: f64,
    triangle: u32,
    /// Bit `k`: edge `k` is on the outline seen from the patch (no
    /// triangle across it covers its other side); [`OUTLINE_KNOWN`]: the
    /// bits are computed.
    outline: u8,
}

/// [`Cone::outline`] is computed.
const OUTLINE_KNOWN: u8 = 0x80;

/// Why a triangle has no [`Cone`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum NoCone {
    /// The centroid lies in the triangle's plane, or the triangle is
    /// degenerate: no ray from the centroid crosses it.
    InPlane,
    /// The centroid lies within `t_min` of the plane: the ray test ignores
    /// hits that near, so it must be applied ray by ray.
    Near,
}

/// Whether the triangle has a [`Cone`] (blocks an open set of directions
/// from `origin`).
fn blocks(origin: &Point3<f64>, tri: &[Point3<f64>; 3], t_min: f64) -> bool {
    let [a, b, c] = tri.map(|p| p - origin);
    let det = a.dot(&b.cross(&c));
    let twice_area = (b - a).cross(&(c - a)).norm();
    det != 0.0 && twice_area != 0.0 && det.abs() / twice_area > t_min
}

/// The first of a cell's nine test points (its corners, the midpoints of
/// its edges, the points half-way from its centre to its corners) that is
/// in front of the patch (`d·n > min_dot`) and that `reaches` accepts.
pub(super) fn nine_point_witness(
    corners: &[V3; 3],
    centre: V3,
    n: &V3,
    min_dot: f64,
    mut reaches: impl FnMut(&V3) -> bool,
) -> Option<V3> {
    (0..3)
        .flat_map(|k| {
            let (a, b) = (corners[k], corners[(k + 1) % 3]);
            [a, (a + b).normalize(), (a + centre).normalize()]
        })
        .find(|d| d.dot(n) > min_dot && reaches(d))
}

/// A cap holding the directions of `dirs` (corners seen from the origin):
/// centre and cosine of the radius. A cap wider than a hemisphere is not
/// convex and may miss part of the triangle between its corners: then the
/// cosine is `-1` (anywhere).
pub(super) fn cap_of(dirs: &[V3; 3]) -> (V3, f64) {
    let units = dirs.map(|d| d.normalize());
    let sum = units[0] + units[1] + units[2];
    let norm = sum.norm();
    if norm > 1e-12 {
        let centre = sum / norm;
        let cos_r = units.iter().map(|d| d.dot(&centre)).fold(1.0, f64::min);
        (centre, if cos_r < 0.0 { -1.0 } else { cos_r })
    } else {
        (units[0], -1.0)
    }
}

impl Cone {
    pub(super) fn new(
        origin: &Point3<f64>,
        tri: &[Point3<f64>; 3],
        t_min: f64,
        triangle: usize,
    ) -> Result<Self, NoCone> {
        let [a, b, c] = tri.map(|p| p - origin);
        let (nab, nbc, nca) = (a.cross(&b), b.cross(&c), c.cross(&a));
        let det = a.dot(&nbc);
        let twice_area = (b - a).cross(&(c - a)).norm();
        if det == 0.0 || twice_area == 0.0 {
            return Err(NoCone::InPlane);
        }
        if det.abs() / twice_area <= t_min {
            return Err(NoCone::Near);
        }
        let s = det.signum();
        let dirs = [a, b, c];
        let (centre, cos_r) = cap_of(&dirs);
        Ok(Self {
            planes: [nab * s, nbc * s, nca * s],
            dirs,
            centre,
            cos_r,
            triangle: triangle as u32,
            outline: 0,
        })
    }

    pub(super) fn contains(&self, d: &V3) -> bool {
        self.planes.iter().all(|p| d.dot(p) >= 0.0)
    }

    /// Whether the whole cell lies in the cone.
    fn holds(&self, cells: &CellShapes, cell: usize) -> bool {
        cells.corners[cell].iter().all(|c| self.contains(c))
    }

    /// Whether the cone may meet the cell (false only when a plane of one
    /// separates them).
    fn may_meet(&self, cells: &CellShapes, cell: usize) -> bool {
        // Cones are mostly smaller than cells: a cell edge separates them
        // more often than a cone plane does.
        if cells.edges[cell]
            .iter()
            .any(|e| self.dirs.iter().all(|d| d.dot(e) < 0.0))
        {
            return false;
        }
        let corners = &cells.corners[cell];
        !self
            .planes
            .iter()
            .any(|p| corners.iter().all(|c| c.dot(p) < 0.0))
    }
}

/// A circle on the unit sphere, `{d : d·m = h}`, parameterised by the angle
/// `θ ∈ [0, len]` as `h·m + ρ·(cos θ·e1 + sin θ·e2)`.
#[derive(Debug, Clone, Copy)]
struct Curve {
    m: V3,
    h: f64,
    rho: f64,
    e1: V3,
    e2: V3,
    len: f64,
    /// `(cos len, sin len)` up to a common factor within round-off of 1
    /// (arcs only; [`Curve::cuts_with`]).
    end: (f64, f64),
    /// Direction of the open side (the visible side, if any).
    open: OpenSide,
}

#[derive(Debug, Clone, Copy)]
enum OpenSide {
    /// Toward `+m` (the horizon: toward the patch's normal).
    Plus,
    /// Toward `−σ·m` off a great-circle arc, `σ = ±1`.
    Away(f64),
}

impl Curve {
    /// The great-circle arc from `ua` to `ub` (unit, less than π apart),
    /// open on the side where `d·plane < 0`.
    fn arc(ua: V3, ub: V3, plane: &V3) -> Option<Self> {
        let m = ua.cross(&ub);
        let norm = m.norm();
        if norm <= 1e-15 {
            return None;
        }
        let m = m / norm;
        let e2 = m.cross(&ua);
        Some(Self {
            m,
            h: 0.0,
            rho: 1.0,
            e1: ua,
            e2,
            len: norm.atan2(ua.dot(&ub)),
            end: (ua.dot(&ub), norm),
            open: OpenSide::Away(plane.dot(&m).signum()),
        })
    }

    /// The small (or great) circle `d·n = s`, open toward `n`.
    fn horizon(n: &V3, s: f64) -> Self {
        let helper = if n.x.abs() < 0.6 { V3::x() } else { V3::y() };
        let e1 = (helper - n * n.dot(&helper)).normalize();
        Self {
            m: *n,
            h: s,
            rho: (1.0 - s * s).max(0.0).sqrt(),
            e1,
            e2: n.cross(&e1),
            len: TAU,
            end: (1.0, 0.0),
            open: OpenSide::Plus,
        }
    }

    fn point(&self, theta: f64) -> V3 {
        self.m * self.h + (self.e1 * theta.cos() + self.e2 * theta.sin()) * self.rho
    }

    fn angle(&self, x: &V3) -> f64 {
        x.dot(&self.e2).atan2(x.dot(&self.e1)).rem_euclid(TAU)
    }

    /// The point `WITNESS_OFFSET` off the curve at `p` on its open side.
    fn witness(&self, p: &V3) -> V3 {
        let toward = match self.open {
            OpenSide::Plus => self.m - p * p.dot(&self.m),
            OpenSide::Away(sigma) => -self.m * sigma,
        };
        let norm = toward.norm();
        if norm == 0.0 {
            return *p;
        }
        (p + toward * (WITNESS_OFFSET / norm)).normalize()
    }

    /// The two points where this curve's circle meets `{d : d·m = h}`.
    fn meets(&self, m: &V3, h: f64) -> Option<[V3; 2]> {
        let g = self.m.dot(m);
        let det = 1.0 - g * g;
        if det <= 1e-24 {
            return None;
        }
        let alpha = (self.h - h * g) / det;
        let beta = (h - self.h * g) / det;
        let base = self.m * alpha + m * beta;
        let cross = self.m.cross(m);
        let gamma2 = (1.0 - base.norm_squared()) / cross.norm_squared();
        if gamma2 < 0.0 {
            return None;
        }
        let gamma = gamma2.sqrt();
        Some([-1.0, 1.0].map(|sign| base + cross * (sign * gamma)))
    }

    /// Angles on this curve where it meets the circle `{d : d·m = h}`;
    /// on an arc, not those certainly past its end (both callers keep
    /// only the angles up to `len`): their atan2 is not taken.
    fn cuts_with(&self, m: &V3, h: f64, out: &mut Vec<f64>) {
        for x in self.meets(m, h).into_iter().flatten() {
            if self.len < PI {
                // On an arc (shorter than π): with `y < 0` (the product
                // `angle` takes, so the same sign) the angle is π or
                // more; with `y ≥ 0` and the turn from the arc's end
                // to `x` positive by far more than round-off, it exceeds
                // `len` by about 1e-9 at least, far above the error of
                // either atan2. Both are past the end.
                let (y, along) = (x.dot(&self.e2), x.dot(&self.e1));
                if y < 0.0 {
                    continue;
                }
                let (c, s) = self.end;
                if y * c - along * s > PAST_END * (y + along.abs()) {
                    continue;
                }
            }
            out.push(self.angle(&x));
        }
    }
}

/// Per-thread memory of the exact test.
#[derive(Debug, Default)]
pub(super) struct ExactScratch {
    /// `stamp[t] == generation`: triangle `t` was processed for this patch.
    stamp: Vec<u32>,
    generation: u32,
    /// The cones the rasteriser closed cells with (the first `processed`
    /// of `cones`), then those the gather adds.
    cones: Vec<Cone>,
    processed: usize,
    /// Subtrees the rasteriser did not enter though they are in front.
    skipped: Vec<usize>,
    /// Cells the rasteriser closed ray by ray (triangles within `t_min` of
    /// the centroid's plane): always candidates.
    forced: Vec<u32>,
    /// Whether any triangle in front of the patch may exist.
    any_front: bool,
    /// Cells with blocked centres within a cell radius of the horizon.
    pub(super) band: Vec<u32>,
    candidate: Vec<u64>,
    list: Vec<u32>,
    /// `list` in compact chunks.
    chunks: CellChunks,
    /// The gather's walk: node and the candidate chunk groups it may meet.
    walk: Vec<(usize, u64)>,
    caps: Vec<(V3, f64, f64)>,
    /// `seen[t] == generation`: `cone_at[t]` is the index in `cones` of
    /// triangle `t`'s cone, or [`NONE`] (not in front, or no cone).
    seen: Vec<u32>,
    cone_at: Vec<u32>,
    /// (cell, cone) for each candidate cell a cone may meet.
    pairs: Vec<(u32, u32)>,
    /// The cones (indices into `cones`) of the candidate being tested.
    local: Vec<u32>,
    curves: Vec<Curve>,
    cuts: Vec<f64>,
    /// Per cell opened: a direction of it that reaches the patch.
    pub(super) witnesses: Vec<(u32, V3)>,
    /// The flood of [`Exact::flood_covers`]: `flooded[t] ==
    /// flood_generation` once triangle `t` was looked at for this cell;
    /// its stack of cones.
    flooded: Vec<u32>,
    flood_generation: u32,
    flood: Vec<u32>,
    /// Per cell the rasteriser closed: the triangle that closed it
    /// ([`NONE`] when closed by a ray test).
    blocker: Vec<u32>,
    /// Candidates certified closed by the flood (counted for the docs'
    /// figures; see [`ExactScratch::certified`]).
    pub(super) certified: usize,
    /// Face of the sphere last located ([`GeodesicSphere::locate`]).
    face_hint: usize,
    /// Stack of the ray tests.
    rays: Vec<usize>,
    /// `occ[t].0 == generation`: `occ[t].1` says whether triangle `t` is
    /// an occluder of the patch (the contour method's test). Stamp and
    /// answer side by side: one cache line per look-up.
    occ: Vec<(u32, bool)>,
    /// The contour method's cells: centres in front, cells of runs closed
    /// by a flood, cells across the horizon with a point of them in front,
    /// the flood's stack, and boundary cells left to rays.
    front: Vec<u64>,
    todo: Vec<u64>,
    band_at: Vec<(u32, V3)>,
    dfs: Vec<u32>,
    pending: Vec<u32>,
    /// The contour's arcs, the (cell, arc) pairs of the cells they cross,
    /// and the arc being marked ([`NONE`]: none).
    arcs: Vec<contour::Arc>,
    arc_of: Vec<(u32, u32)>,
    recording: u32,
    /// Per cell: the patch it was last seen for and its state in the count
    /// propagation; its point of known count; the propagation's queue; the
    /// cells of runs known open.
    settled: Vec<(u32, contour::Settled)>,
    refs: Vec<(V3, i32)>,
    queue: Vec<u32>,
    known_open: Vec<u64>,
    /// Non-boundary cells next to a counted one that no count reached.
    unsure: Vec<u32>,
    /// The arcs of the cell being visited.
    ids: Vec<u32>,
    /// Boundary cells the contour method decided by counts, and by rays
    /// (for the tests and the docs' figures).
    pub(super) counted: usize,
    pub(super) by_rays: usize,
    /// Whether the contour method lists the highest point of each band
    /// cell it opens in `witnesses` (the tests check them; others only
    /// count them).
    pub(super) keep_witnesses: bool,
}

impl ExactScratch {
    /// Starts a patch on a mesh of `triangles` and a sphere of `cells`.
    pub(super) fn begin(&mut self, triangles: usize, cells: usize) {
        self.generation = self.generation.wrapping_add(1);
        if self.generation == 0 || self.stamp.len() != triangles {
            self.stamp.clear();
            self.stamp.resize(triangles, 0);
            self.seen.clear();
            self.seen.resize(triangles, 0);
            self.cone_at.clear();
            self.cone_at.resize(triangles, NONE);
            self.flooded.clear();
            self.flooded.resize(triangles, 0);
            self.flood_generation = 0;
            self.occ.clear();
            self.occ.resize(triangles, (0, false));
            self.settled.iter_mut().for_each(|s| s.0 = 0);
            self.generation = 1;
        }
        if self.blocker.len() != cells {
            self.blocker.clear();
            self.blocker.resize(cells, NONE);
            self.settled.clear();
            self.settled.resize(cells, (0, contour::Settled::No));
            self.refs.clear();
            self.refs.resize(cells, (V3::zeros(), 0));
        }
        self.recording = NONE;
        self.cones.clear();
        self.processed = 0;
        self.skipped.clear();
        self.forced.clear();
        self.band.clear();
        self.any_front = false;
        self.candidate.clear();
        self.candidate.resize(cells.div_ceil(64), 0);
        self.list.clear();
        self.witnesses.clear();
        self.certified = 0;
        self.counted = 0;
        self.by_rays = 0;
    }

    /// The rasteriser met a triangle in front of the patch.
    pub(super) fn front(&mut self) {
        self.any_front = true;
    }

    /// The rasteriser did not enter subtree `node`, which is in front.
    pub(super) fn skipped(&mut self, node: usize) {
        self.any_front = true;
        self.skipped.push(node);
    }

    /// The rasteriser closed cells through `cone`.
    pub(super) fn processed(&mut self, cone: Cone) {
        self.any_front = true;
        let t = cone.triangle as usize;
        if self.stamp[t] != self.generation {
            self.stamp[t] = self.generation;
            self.cones.push(cone);
            self.processed += 1;
        }
    }

    /// The rasteriser closed `cell` by a ray test.
    pub(super) fn forced(&mut self, cell: usize) {
        self.forced.push(cell as u32);
        self.blocker[cell] = NONE;
    }

    /// The rasteriser closed `cell` with triangle `t`'s cone.
    pub(super) fn blocked(&mut self, cell: usize, t: usize) {
        self.blocker[cell] = t as u32;
    }

    fn mark(&mut self, cell: usize) {
        if self.recording != NONE {
            self.arc_of.push((cell as u32, self.recording));
        }
        let (w, b) = (cell / 64, cell % 64);
        if self.candidate[w] >> b & 1 == 0 {
            self.candidate[w] |= 1 << b;
            self.list.push(cell as u32);
        }
    }
}

/// What the exact test works with.
pub(super) struct Exact<'a> {
    pub caster: &'a RayCaster,
    pub grid: &'a CellGrid,
    pub cells: &'a CellShapes,
    pub sphere: &'a GeodesicSphere,
    /// Certify candidates by flooding the mesh ([`Exact::certify`]) before
    /// the gather; off, every candidate goes through the gather and the
    /// exact test (the reference the tests compare it with).
    pub flood: bool,
}

/// One patch: its centroid, normal, `sin` of the grazing margin and index.
pub(super) struct PatchFrame<'a> {
    pub origin: &'a Point3<f64>,
    pub normal: &'a V3,
    pub min_dot: f64,
    pub skip: usize,
}

impl Exact<'_> {
    /// Opens the cells of `row` whose centre is blocked but some direction
    /// of which reaches the patch; returns how many it opened.
    pub(super) fn upgrade(&self, p: &PatchFrame, row: &mut [u64], w: &mut ExactScratch) -> u32 {
        let o = p.origin;
        let n = p.normal;
        if !w.any_front {
            // No occluder at all: a cell near the horizon is visible when
            // part of it is in front.
            let mut added = 0;
            for k in 0..w.band.len() {
                let c = w.band[k] as usize;
                let (top, at) = self.cells.max_dot(c, n);
                if top > p.min_dot {
                    row[c / 64] |= 1 << (c % 64);
                    w.witnesses.push((c as u32, at));
                    added += 1;
                }
            }
            return added;
        }
        // 1. Candidates: blocked cells crossed by the outline of the
        // processed occluders, by the horizon, or closed ray by ray.
        let caster = self.caster;
        for idx in 0..w.processed {
            let cone = w.cones[idx];
            let t = cone.triangle as usize;
            for k in 0..3 {
                let (a, b) = (cone.dirs[k], cone.dirs[(k + 1) % 3]);
                if a.dot(n) <= 0.0 && b.dot(n) <= 0.0 {
                    // Behind the patch's plane: the arc stays out of its
                    // front half.
                    continue;
                }
                let (t2, corner) = caster.across(t, k);
                let outline = if t2 == NONE
                    || t2 as usize == p.skip
                    || w.stamp[t2 as usize] != w.generation
                {
                    true
                } else if (t2 as usize) < t {
                    // A pair of processed triangles: judged once.
                    continue;
                } else {
                    let c2 = caster.shapes[t2 as usize].corners[corner] - o;
                    let m = a.cross(&b);
                    m.dot(&cone.dirs[(k + 2) % 3]) * m.dot(&c2) >= 0.0
                };
                if outline {
                    self.mark_arc(a.normalize(), b.normalize(), n, |c| !is_open(row, c), w);
                }
            }
        }
        for k in 0..w.forced.len() {
            let c = w.forced[k] as usize;
            w.mark(c);
        }
        for k in 0..w.band.len() {
            let c = w.band[k] as usize;
            w.mark(c);
        }
        // 2. Candidates the occluding surface covers whole, proved without
        // the hierarchy; the rest against every occluder that meets them.
        let added = if self.flood {
            self.certify(p, row, w)
        } else {
            0
        };
        added + self.decide(p, row, w)
    }

    /// Tests the candidates left in `w.list` exactly against every occluder
    /// that may meet them (the gather); opens those some direction of which
    /// reaches the patch and returns how many.
    fn decide(&self, p: &PatchFrame, row: &mut [u64], w: &mut ExactScratch) -> u32 {
        let mut added = 0;
        self.gather(p, w);
        w.list.sort_unstable();
        w.pairs.sort_unstable();
        let mut next = 0;
        for k in 0..w.list.len() {
            let c = w.list[k];
            w.local.clear();
            while next < w.pairs.len() && w.pairs[next].0 <= c {
                if w.pairs[next].0 == c {
                    w.local.push(w.pairs[next].1);
                }
                next += 1;
            }
            let c = c as usize;
            if is_open(row, c) {
                continue;
            }
            if let Some(at) = self.cell_visible(p, c, w) {
                row[c / 64] |= 1 << (c % 64);
                w.witnesses.push((c as u32, at));
                added += 1;
            }
        }
        added
    }

    /// Marks the cells the arc from `ua` to `ub` crosses (its part in front
    /// of the plane with normal `n`) that `wanted` accepts.
    fn mark_arc(
        &self,
        mut ua: V3,
        mut ub: V3,
        n: &V3,
        wanted: impl Fn(usize) -> bool,
        w: &mut ExactScratch,
    ) {
        // Clip to the front half: the crossing of the arc with the plane.
        let (da, db) = (ua.dot(n), ub.dot(n));
        if da < 0.0 {
            ua = (ua * db - ub * da).normalize();
        } else if db < 0.0 {
            ub = (ub * da - ua * db).normalize();
        }
        // An arc with both ends inside one (convex) cell crosses it alone.
        if let Some(c) = self.sphere.locate(&ua, &mut w.face_hint)
            && self.sphere.locate(&ub, &mut w.face_hint) == Some(c)
        {
            if wanted(c) {
                w.mark(c);
            }
            return;
        }
        let m = ua.cross(&ub);
        let len = m.norm().atan2(ua.dot(&ub));
        let pieces = ((len / (ARC_PIECE_SPACINGS * self.cells.spacing)).ceil() as usize).max(1);
        let e2 = if m.norm() > 0.0 {
            m.normalize().cross(&ua)
        } else {
            V3::zeros()
        };
        let at = |f: f64| {
            let a = len * f;
            ua * a.cos() + e2 * a.sin()
        };
        for piece in 0..pieces {
            let (pa, pb) = (
                at(piece as f64 / pieces as f64),
                at((piece + 1) as f64 / pieces as f64),
            );
            let sum = pa + pb;
            let centre = if sum.norm() > 0.0 {
                sum.normalize()
            } else {
                pa
            };
            let half = (pa - pb).norm().min(2.0) * 0.5;
            let r = half.asin() + self.cells.radius + CAP_MARGIN;
            let pm = pa.cross(&pb);
            // A cell whose direction lies farther than its radius from the
            // piece's great circle cannot meet the piece: one product rules
            // out most of the cap's cells before `arc_meets_cell`. Only
            // when the piece is long enough (and that far clear) for the
            // signs `arc_meets_cell` takes to be certain, so it would say
            // no too.
            let pm_norm = pm.norm();
            let clear = if pm_norm > CLEAR_MIN_SIN {
                pm_norm * (self.cells.sin_radius + CLEAR_MARGIN)
            } else {
                f64::INFINITY
            };
            let grid = self.grid;
            grid.any_in_cap(&centre, r.cos().max(0.0), r.sin(), |i, d| {
                if d.dot(&pm).abs() <= clear && wanted(i) && self.arc_meets_cell(&pa, &pb, &pm, i) {
                    w.mark(i);
                }
                false
            });
        }
    }

    /// Whether the arc from `pa` to `pb` (plane normal `m = pa × pb`) may
    /// meet the cell (ties count as meeting).
    fn arc_meets_cell(&self, pa: &V3, pb: &V3, m: &V3, cell: usize) -> bool {
        let cells = self.cells;
        if cells.inside(cell, pa) || cells.inside(cell, pb) {
            return true;
        }
        let c = &cells.corners[cell];
        let s = c.map(|x| x.dot(m));
        if s.iter().all(|&v| v > 0.0) || s.iter().all(|&v| v < 0.0) {
            return false;
        }
        for k in 0..3 {
            let (si, sj) = (s[k], s[(k + 1) % 3]);
            if si * sj > 0.0 {
                continue;
            }
            // The point of the cell's edge on the arc's great circle.
            let x = c[k] * sj.abs() + c[(k + 1) % 3] * si.abs();
            if pa.cross(&x).dot(m) >= 0.0 && x.cross(pb).dot(m) >= 0.0 {
                return true;
            }
        }
        false
    }

    /// The index in `w.cones` of triangle `t`'s cone seen from the patch,
    /// made once per patch; [`NONE`] when the triangle is the patch, lies
    /// behind its plane or has no cone.
    fn cone_of(&self, p: &PatchFrame, t: usize, w: &mut ExactScratch) -> u32 {
        if w.seen[t] == w.generation {
            return w.cone_at[t];
        }
        w.seen[t] = w.generation;
        let caster = self.caster;
        let level = p.normal.dot(&p.origin.coords) + caster.t_min;
        let tri = &caster.shapes[t].corners;
        let id = if w.stamp[t] == w.generation {
            w.cone_at[t]
        } else if t == p.skip || !tri.iter().any(|c| p.normal.dot(&c.coords) > level) {
            NONE
        } else if let Ok(cone) = Cone::new(p.origin, tri, caster.t_min, t) {
            w.cones.push(cone);
            (w.cones.len() - 1) as u32
        } else {
            NONE
        };
        w.cone_at[t] = id;
        id
    }

    /// Whether the cone `id` may meet `cell` (false only when it certainly
    /// does not).
    fn cone_meets(&self, id: u32, cell: usize, w: &ExactScratch) -> bool {
        w.cones[id as usize].may_meet(self.cells, cell)
    }

    /// Drops from `w.list` the candidates that the occluding surface
    /// provably covers whole, found by walking the mesh instead of the
    /// hierarchy, and opens those whose test point reaches the patch by a
    /// ray; returns how many it opened.
    ///
    /// Per candidate cell `C` (`H` the open front half, `d·n > min_dot`,
    /// convex, so `C ∩ H` is connected): take a point `x` of `C ∩ H` (the
    /// centre, or the point of the cell nearest the normal) and a
    /// triangle whose cone holds it (the rasteriser's, or the first a ray
    /// along `x` meets; none: `x` reaches the patch and the cell is open).
    /// From it, flood the triangles whose cone may meet `C`, across every
    /// edge whose neighbour is in front with a cone on the other side of
    /// the edge seen from the patch. If no other edge of the flood (a
    /// border, a silhouette, a neighbour behind or without a cone) crosses
    /// `C ∩ H`, the union `U` of the flooded cones holds `C ∩ H`: a
    /// boundary point of `U` inside `C ∩ H` would lie on an edge of a
    /// flooded cone whose neighbour covers the other side there and meets
    /// `C`, so is flooded too, and the two cover a neighbourhood of the
    /// point (at a corner, the fan around it does, each meeting `C`). `U`
    /// has no boundary in the connected `C ∩ H` and holds `x`: the cell is
    /// closed. Edges shared with the patch itself lie in its plane (the
    /// horizon) and never cross `H`. A cell not certified this way goes to
    /// the gather and the exact test.
    fn certify(&self, p: &PatchFrame, row: &mut [u64], w: &mut ExactScratch) -> u32 {
        if w.list.is_empty() {
            return 0;
        }
        for id in 0..w.processed {
            let t = w.cones[id].triangle as usize;
            w.cone_at[t] = id as u32;
        }
        let n = p.normal;
        let caster = self.caster;
        let mut keep = 0;
        let mut opened = 0;
        for k in 0..w.list.len() {
            let c = w.list[k];
            let ci = c as usize;
            let centre = self.cells.dirs[ci];
            let (x, blocker) = if centre.dot(n) > p.min_dot {
                (centre, w.blocker[ci])
            } else {
                let (top, at) = self.cells.max_dot(ci, n);
                if top <= p.min_dot {
                    // No part in front: closed whatever covers it.
                    w.certified += 1;
                    continue;
                }
                match caster.first_hit(p.origin, &at, p.skip, &mut w.rays) {
                    None => {
                        row[ci / 64] |= 1 << (ci % 64);
                        w.witnesses.push((c, at));
                        opened += 1;
                        continue;
                    }
                    Some(t) => (at, t as u32),
                }
            };
            if self.flood_covers(p, ci, &x, blocker, w) {
                w.certified += 1;
                continue;
            }
            // An outline crosses the cell: nearly always part of it is
            // open, and one of the nine points of the exact test shows it.
            let reached = nine_point_witness(&self.cells.corners[ci], centre, n, p.min_dot, |d| {
                caster.first_hit(p.origin, d, p.skip, &mut w.rays).is_none()
            });
            if let Some(d) = reached {
                row[ci / 64] |= 1 << (ci % 64);
                w.witnesses.push((c, d));
                opened += 1;
            } else {
                w.list[keep] = c;
                keep += 1;
            }
        }
        w.list.truncate(keep);
        opened
    }

    /// Whether the flood from triangle `seed` (see [`Exact::certify`])
    /// covers the whole of `cell` in front, `x` a point of it in `seed`'s
    /// cone.
    fn flood_covers(
        &self,
        p: &PatchFrame,
        cell: usize,
        x: &V3,
        seed: u32,
        w: &mut ExactScratch,
    ) -> bool {
        if seed == NONE {
            return false;
        }
        let seed_cone = self.cone_of(p, seed as usize, w);
        if seed_cone == NONE || !w.cones[seed_cone as usize].contains(x) {
            return false;
        }
        w.flood_generation = w.flood_generation.wrapping_add(1);
        if w.flood_generation == 0 {
            w.flooded.iter_mut().for_each(|g| *g = 0);
            w.flood_generation = 1;
        }
        let generation = w.flood_generation;
        let caster = self.caster;
        let n = p.normal;
        w.flood.clear();
        w.flood.push(seed_cone);
        w.flooded[seed as usize] = generation;
        while let Some(id) = w.flood.pop() {
            let cone = w.cones[id as usize];
            let t = cone.triangle as usize;
            for k in 0..3 {
                let (t2, corner) = caster.across(t, k);
                if t2 as usize == p.skip {
                    continue;
                }
                let (a, b) = (cone.dirs[k], cone.dirs[(k + 1) % 3]);
                let m = a.cross(&b);
                let id2 = if t2 == NONE {
                    NONE
                } else {
                    self.cone_of(p, t2 as usize, w)
                };
                let interior = id2 != NONE && {
                    let c2 = caster.shapes[t2 as usize].corners[corner] - p.origin;
                    m.dot(&cone.dirs[(k + 2) % 3]) * m.dot(&c2) < 0.0
                };
                if interior {
                    if w.flooded[t2 as usize] != generation {
                        w.flooded[t2 as usize] = generation;
                        if self.cone_meets(id2, cell, w) {
                            w.flood.push(id2);
                        }
                    }
                    continue;
                }
                // An outline edge: it must not cross the cell in front.
                let (mut ua, mut ub) = (a.normalize(), b.normalize());
                let (da, db) = (ua.dot(n), ub.dot(n));
                if da <= 0.0 && db <= 0.0 {
                    continue;
                }
                if da < 0.0 {
                    ua = (ua * db - ub * da).normalize();
                } else if db < 0.0 {
                    ub = (ub * da - ua * db).normalize();
                }
                if self.arc_meets_cell(&ua, &ub, &ua.cross(&ub), cell) {
                    return false;
                }
            }
        }
        true
    }

    /// Pairs each candidate cell with the cones that may meet it: the
    /// rasteriser's cones, and those of the triangles in the subtrees it
    /// did not enter (appended to `w.cones`). Fills `w.pairs` (cell, cone).
    fn gather(&self, p: &PatchFrame, w: &mut ExactScratch) {
        let caster = self.caster;
        w.pairs.clear();
        if w.list.is_empty() || caster.bvh.nodes.is_empty() {
            return;
        }
        let mut chunks = std::mem::take(&mut w.chunks);
        if chunks.chunks().next().is_none() {
            chunks = CellChunks::with_chunk(GATHER_CHUNK);
        }
        chunks.rebuild(&w.list, &self.cells.dirs);
        // The rasteriser's cones, by triangle.
        for id in 0..w.processed {
            let t = w.cones[id].triangle as usize;
            w.cone_at[t] = id as u32;
        }
        let o = p.origin;
        let n = p.normal;
        let level = n.dot(&o.coords) + caster.t_min;
        let (cos_c, sin_c) = (self.cells.cos_radius, self.cells.sin_radius);
        // Whether caps (cos, sin of the radii) around unit `u` and `v`
        // meet once the second is widened by a cell radius.
        let meet = |u: &V3, (cu, su): (f64, f64), v: &V3, (cv, sv): (f64, f64)| {
            // Radii adding up to π or more: they meet.
            if cv <= -cos_c {
                return true;
            }
            let (cw, sw) = (cv * cos_c - sv * sin_c, sv * cos_c + cv * sin_c);
            cu <= -cw || u.dot(v) >= cu * cw - su * sw - CAP_MARGIN
        };
        let dirs = &self.cells.dirs;
        let mut caps = std::mem::take(&mut w.caps);
        caps.clear();
        caps.extend(chunks.chunks().map(|(cap, _)| *cap));
        let members: Vec<&[u32]> = chunks.chunks().map(|(_, cells)| cells).collect();
        // One walk per 64 chunks, each node carrying the chunks it may meet.
        for group in (0..caps.len()).step_by(64) {
            let count = (caps.len() - group).min(64);
            let full = if count == 64 {
                u64::MAX
            } else {
                (1u64 << count) - 1
            };
            let select = |mask: u64, u: &V3, cap: (f64, f64)| {
                let mut out = 0u64;
                let mut bits = mask;
                while bits != 0 {
                    let k = bits.trailing_zeros() as usize;
                    bits &= bits - 1;
                    let (centre, cos_k, sin_k) = caps[group + k];
                    if meet(&centre, (cos_k, sin_k), u, cap) {
                        out |= 1 << k;
                    }
                }
                out
            };
            w.walk.clear();
            w.walk.push((0, full));
            while let Some((index, mask)) = w.walk.pop() {
                match &caster.bvh.nodes[index] {
                    BvhNode::Leaf { shape_index, .. } => {
                        let t = *shape_index;
                        if t == p.skip {
                            continue;
                        }
                        let id = self.cone_of(p, t, w);
                        if id == NONE {
                            continue;
                        }
                        let cone = &w.cones[id as usize];
                        let cone_cap = if cone.cos_r < 0.0 {
                            (-1.0, 0.0)
                        } else {
                            (cone.cos_r, (1.0 - cone.cos_r * cone.cos_r).max(0.0).sqrt())
                        };
                        let hit = select(mask, &cone.centre, cone_cap);
                        let cw = cone_cap.0 * cos_c - cone_cap.1 * sin_c;
                        let wide = cone_cap.0 <= -cos_c;
                        let mut bits = hit;
                        while bits != 0 {
                            let k = bits.trailing_zeros() as usize;
                            bits &= bits - 1;
                            for &c in members[group + k] {
                                if (wide || dirs[c as usize].dot(&cone.centre) >= cw - CAP_MARGIN)
                                    && cone.may_meet(self.cells, c as usize)
                                {
                                    w.pairs.push((c, id));
                                }
                            }
                        }
                    }
                    BvhNode::Node {
                        child_l_index,
                        child_l_aabb,
                        child_r_index,
                        child_r_aabb,
                        ..
                    } => {
                        for (b, child) in
                            [(child_l_aabb, child_l_index), (child_r_aabb, child_r_index)]
                        {
                            let mut far = 0.0;
                            for k in 0..3 {
                                far += n[k] * if n[k] > 0.0 { b.max[k] } else { b.min[k] };
                            }
                            if far <= level {
                                continue;
                            }
                            let bc = Point3::from((b.min.coords + b.max.coords) * 0.5);
                            let radius = (b.max - b.min).norm() * 0.5;
                            let to = bc - o;
                            let dist = to.norm();
                            let sub = if dist <= radius * (1.0 + CAP_MARGIN) + caster.t_min {
                                mask
                            } else {
                                let sin_b = radius / dist;
                                let cos_b = (1.0 - sin_b * sin_b).max(0.0).sqrt();
                                select(mask, &(to / dist), (cos_b, sin_b))
                            };
                            if sub != 0 {
                                w.walk.push((*child, sub));
                            }
                        }
                    }
                }
            }
        }
        w.chunks = chunks;
        w.caps = caps;
    }

    /// The outline edges of `cone` seen from the patch: those with no
    /// triangle across, or whose neighbour lies on the same side of the
    /// edge, or blocks nothing (in the centroid's plane).
    fn outline(&self, p: &PatchFrame, cone: &Cone) -> u8 {
        let caster = self.caster;
        let mut mask = 0;
        for k in 0..3 {
            let (t2, corner) = caster.across(cone.triangle as usize, k);
            let outline = t2 == NONE || t2 as usize == p.skip || {
                let tri2 = &caster.shapes[t2 as usize].corners;
                let c2 = tri2[corner] - p.origin;
                let m = cone.dirs[k].cross(&cone.dirs[(k + 1) % 3]);
                !blocks(p.origin, tri2, caster.t_min)
                    || m.dot(&cone.dirs[(k + 2) % 3]) * m.dot(&c2) >= 0.0
            };
            if outline {
                mask |= 1 << k;
            }
        }
        mask
    }

    /// Whether some direction of `cell` reaches the patch.
    /// A direction of `cell` that reaches the patch, if any.
    fn cell_visible(&self, p: &PatchFrame, cell: usize, w: &mut ExactScratch) -> Option<V3> {
        let n = p.normal;
        let (top, at) = self.cells.max_dot(cell, n);
        if top <= p.min_dot {
            return None;
        }
        if w.local.is_empty() {
            // Nothing in front of this cell: its part in front is visible.
            return Some(at);
        }
        let all = &w.cones;
        let cones = || w.local.iter().map(|&i| &all[i as usize]);
        if cones().any(|c| c.holds(self.cells, cell)) {
            return None;
        }
        let visible = |d: &V3| d.dot(n) > p.min_dot && !cones().any(|c| c.contains(d));
        // Nine points first: most partly visible cells show it there.
        let c = &self.cells.corners[cell];
        let centre = self.cells.dirs[cell];
        for k in 0..3 {
            let mid = (c[k] + c[(k + 1) % 3]).normalize();
            let half = (c[k] + centre).normalize();
            for x in [c[k], mid, half] {
                if visible(&x) {
                    return Some(x);
                }
            }
        }
        // The outline inside the cell, cut into pieces at every crossing.
        for k in 0..w.local.len() {
            let i = w.local[k] as usize;
            if w.cones[i].outline & OUTLINE_KNOWN == 0 {
                w.cones[i].outline = self.outline(p, &w.cones[i]) | OUTLINE_KNOWN;
            }
        }
        let all = &w.cones;
        let cones = || w.local.iter().map(|&i| &all[i as usize]);
        let visible = |d: &V3| d.dot(n) > p.min_dot && !cones().any(|c| c.contains(d));
        w.curves.clear();
        if -self.cells.max_dot(cell, &-n).0 < p.min_dot {
            w.curves.push(Curve::horizon(n, p.min_dot));
        }
        for cone in cones() {
            for k in 0..3 {
                if cone.outline >> k & 1 == 0 {
                    continue;
                }
                let (ua, ub) = (cone.dirs[k].normalize(), cone.dirs[(k + 1) % 3].normalize());
                if !self.arc_meets_cell(&ua, &ub, &ua.cross(&ub), cell) {
                    continue;
                }
                if let Some(curve) = Curve::arc(ua, ub, &cone.planes[k]) {
                    w.curves.push(curve);
                }
            }
        }
        let edges = &self.cells.edges[cell];
        for i in 0..w.curves.len() {
            let curve = w.curves[i];
            w.cuts.clear();
            w.cuts.push(0.0);
            w.cuts.push(curve.len);
            for e in edges {
                curve.cuts_with(e, 0.0, &mut w.cuts);
            }
            for (j, other) in w.curves.iter().enumerate() {
                if j != i {
                    curve.cuts_with(&other.m, other.h, &mut w.cuts);
                }
            }
            w.cuts.retain(|&a| a <= curve.len);
            w.cuts.sort_unstable_by(f64::total_cmp);
            for pair in w.cuts.windows(2) {
                if pair[1] - pair[0] < MIN_PIECE {
                    continue;
                }
                let mid = curve.point(0.5 * (pair[0] + pair[1]));
                if !self.cells.inside(cell, &mid) {
                    continue;
                }
                let x = curve.witness(&mid);
                if self.cells.inside(cell, &x) && visible(&x) {
                    return Some(x);
                }
            }
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::setup::samples::random_rotation;

    /// The cuts an arc keeps (angles up to `len`) are those of both meeting
    /// points, bit for bit, though the points past its end are dropped
    /// before their angle is taken: random arcs against random circles,
    /// great circles and circles through the arc's ends.
    #[test]
    fn arc_cuts_are_those_of_every_meeting_point() {
        let (mut kept, mut dropped) = (0, 0);
        for seed in 0..400u64 {
            let r = random_rotation(seed);
            let ua = r * V3::x();
            let turn = 0.001 + 3.1 * (seed % 97) as f64 / 97.0;
            let ub = r * V3::new(turn.cos(), turn.sin(), 0.0);
            let Some(curve) = Curve::arc(ua, ub, &(r * V3::z())) else {
                continue;
            };
            let q = random_rotation(seed + 1000);
            let circles = [
                (q * V3::z(), 0.0),
                (q * V3::x(), 0.3),
                (ua.cross(&(q * V3::y())).normalize(), 0.0),
                (ub.cross(&(q * V3::y())).normalize(), 0.0),
                (ub.cross(&curve.m).normalize(), 0.0),
            ];
            for (m, h) in circles {
                let mut fast = Vec::new();
                curve.cuts_with(&m, h, &mut fast);
                let all: Vec<f64> = curve
                    .meets(&m, h)
                    .into_iter()
                    .flatten()
                    .map(|x| curve.angle(&x))
                    .collect();
                let on = |v: &[f64]| -> Vec<u64> {
                    v.iter()
                        .filter(|&&t| t <= curve.len)
                        .map(|t| t.to_bits())
                        .collect()
                };
                assert_eq!(on(&fast), on(&all), "seed {seed}, circle {m:?} {h}");
                kept += on(&all).len();
                dropped += all.len() - fast.len();
            }
        }
        assert!(
            kept > 300 && dropped > 1000,
            "{kept} kept, {dropped} dropped"
        );
    }
}
