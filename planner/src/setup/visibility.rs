//! Point visibility cones by ray casting: the binary spherical map (BSM).
//!
//! Patch `j` is mesh triangle `j`, sampled at its centroid. Cell `i` belongs to
//! `PVC_j` when the direction `d_i` points to the outside of the triangle
//! (`d_i·n_j > sin(grazing margin)`) and the ray `centroid + t·d_i`, `t > 0`,
//! meets no other triangle of the part. The tool's own volume is ignored (as
//! in the paper): a direction is accessible when a line, not a cutter, gets
//! through. Triangles block from both sides, so open surfaces work.
//!
//! The rays are traced through a bounding volume hierarchy built by the `bvh`
//! crate (SAH); the traversal is our own so that it can stop at the first hit
//! and never overflow a fixed stack. Patches are traced in parallel (rayon).
//!
//! [`compute`] then tests the cells whose centre is blocked against the cone
//! exactly ([`exact`]): a cell is in the cone when any of its directions is,
//! so a cone narrower than the cell spacing is never lost between centres.

mod exact;

pub use exact::WITNESS_OFFSET;

use std::f64::consts::{PI, TAU};
use std::sync::atomic::{AtomicUsize, Ordering};

use bvh::aabb::{Aabb, Bounded};
use bvh::bounding_hierarchy::{BHShape, BoundingHierarchy};
use bvh::bvh::{Bvh, BvhNode};
use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

use super::sphere::GeodesicSphere;
use crate::mesh::{NO_TRIANGLE, TopologyOptions, TriMesh};

/// Bits of the map: patch-major, one bitset of `cells` bits per patch.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct VisibilityMap {
    cells: usize,
    patches: usize,
    words: usize,
    bits: Vec<u64>,
    /// Per patch: cells in the cone shown by a direction other than their
    /// centre (see [`VisibilityMap::upgraded`]).
    upgraded: Vec<u32>,
}

impl VisibilityMap {
    /// An empty map (no cell visible from any patch).
    pub fn new(cells: usize, patches: usize) -> Self {
        let words = cells.div_ceil(64);
        Self {
            cells,
            patches,
            words,
            bits: vec![0; words * patches],
            upgraded: vec![0; patches],
        }
    }

    /// Number of sphere cells `m`.
    pub fn cells(&self) -> usize {
        self.cells
    }

    /// Number of patches `n`.
    pub fn patches(&self) -> usize {
        self.patches
    }

    /// Whether cell `cell` is in `PVC_patch` (the paper's `BSM(j,i) = 0`).
    pub fn visible(&self, patch: usize, cell: usize) -> bool {
        self.bits[patch * self.words + cell / 64] >> (cell % 64) & 1 == 1
    }

    /// Marks cell `cell` as in `PVC_patch`.
    pub fn set(&mut self, patch: usize, cell: usize) {
        self.bits[patch * self.words + cell / 64] |= 1 << (cell % 64);
    }

    /// The bitset of `PVC_patch` (`cells` bits, 64 per word).
    pub fn pvc(&self, patch: usize) -> &[u64] {
        &self.bits[patch * self.words..(patch + 1) * self.words]
    }

    /// Number of cells in `PVC_patch` (`I_PVC_j`).
    pub fn pvc_len(&self, patch: usize) -> usize {
        self.pvc(patch)
            .iter()
            .map(|w| w.count_ones() as usize)
            .sum()
    }

    /// Cells of `PVC_patch` that the exact cell test opened by a direction
    /// other than their centre: by the occluders' contour (the default),
    /// the cells the contour or the horizon crosses that some direction of
    /// reaches the patch (their centre may reach it too); by the rasteriser
    /// and the exact pass, the cells whose centre is blocked. 0 with
    /// `exact_cells` off.
    pub fn upgraded(&self, patch: usize) -> usize {
        self.upgraded[patch] as usize
    }

    /// Whether the patch's cone (on `sphere`, the map's) is about as narrow
    /// as the cell spacing or narrower: not empty, but none of its cells
    /// has all its neighbours in it. Where such a patch is reached from is
    /// known only to a cell or so; a finer sphere resolves it.
    pub fn narrow(&self, patch: usize, sphere: &GeodesicSphere) -> bool {
        let row = self.pvc(patch);
        let mut any = false;
        let interior = any_open(row, |i| {
            any = true;
            sphere.touching(i).iter().all(|&n| is_open(row, n as usize))
        });
        any && !interior
    }
}

/// One triangle in the hierarchy.
#[derive(Debug, Clone, Copy)]
struct TriShape {
    corners: [Point3<f64>; 3],
    node: usize,
}

impl Bounded<f64, 3> for TriShape {
    fn aabb(&self) -> Aabb<f64, 3> {
        let [a, b, c] = self.corners;
        Aabb::with_bounds(a.inf(&b).inf(&c), a.sup(&b).sup(&c))
    }
}

impl BHShape<f64, 3> for TriShape {
    fn set_bh_node_index(&mut self, index: usize) {
        self.node = index;
    }

    fn bh_node_index(&self) -> usize {
        self.node
    }
}

/// Any-hit ray queries against a triangle mesh.
#[derive(Debug)]
pub struct RayCaster {
    shapes: Vec<TriShape>,
    bvh: Bvh<f64, 3>,
    /// Hits closer than this to the ray origin are ignored (mm).
    t_min: f64,
    /// Per triangle and edge (corner `k` to `k + 1`): the triangle across
    /// it and the index of that triangle's corner off the edge, packed as
    /// `triangle << 2 | corner`; `exact::NONE` at a border or a
    /// non-manifold edge.
    across: Vec<[u32; 3]>,
}

/// Hits nearer than this fraction of the part's bounding-box diagonal are the
/// ray's own start (round-off), not occlusion.
pub const RAY_T_MIN_REL: f64 = 1e-9;

impl RayCaster {
    /// Builds the hierarchy over all triangles of `mesh` (in parallel).
    pub fn new(mesh: &TriMesh) -> Self {
        let mut shapes: Vec<TriShape> = (0..mesh.triangles.len())
            .map(|t| TriShape {
                corners: mesh.corners(t),
                node: 0,
            })
            .collect();
        let bvh = Bvh::build_par(&mut shapes);
        let (lo, hi) = mesh.bounds();
        let t_min = (hi - lo).norm().max(f64::MIN_POSITIVE) * RAY_T_MIN_REL;
        let topology = mesh.topology(TopologyOptions::default());
        let across = (0..mesh.triangles.len())
            .map(|t| {
                let tri = mesh.triangles[t];
                [0, 1, 2].map(|k| {
                    let t2 = topology.neighbours[t][k];
                    if t2 == NO_TRIANGLE || t2 >= 1 << 30 {
                        return exact::NONE;
                    }
                    let (a, b) = (tri[k], tri[(k + 1) % 3]);
                    mesh.triangles[t2 as usize]
                        .iter()
                        .position(|&v| v != a && v != b)
                        .map_or(exact::NONE, |c| t2 << 2 | c as u32)
                })
            })
            .collect();
        Self {
            shapes,
            bvh,
            t_min,
            across,
        }
    }

    /// The triangle across edge `k` (corner `k` to `k + 1`) of triangle `t`
    /// and the index of its corner off that edge; `(exact::NONE, 0)` when
    /// there is none.
    fn across(&self, t: usize, k: usize) -> (u32, usize) {
        let packed = self.across[t][k];
        if packed == exact::NONE {
            (exact::NONE, 0)
        } else {
            (packed >> 2, (packed & 3) as usize)
        }
    }

    /// Whether the ray `origin + t·dir`, `t > t_min`, meets a triangle other
    /// than `skip`. `stack` is reusable scratch.
    pub fn occluded(
        &self,
        origin: &Point3<f64>,
        dir: &Vector3<f64>,
        skip: usize,
        stack: &mut Vec<usize>,
    ) -> bool {
        self.first_hit(origin, dir, skip, stack).is_some()
    }
}

impl RayCaster {
    /// A triangle other than `skip` that the ray `origin + t·dir`,
    /// `t > t_min`, meets (the first found, not the nearest), if any.
    fn first_hit(
        &self,
        origin: &Point3<f64>,
        dir: &Vector3<f64>,
        skip: usize,
        stack: &mut Vec<usize>,
    ) -> Option<usize> {
        if self.bvh.nodes.is_empty() {
            return None;
        }
        let inv = dir.map(|c| 1.0 / c);
        stack.clear();
        stack.push(0);
        while let Some(index) = stack.pop() {
            match &self.bvh.nodes[index] {
                BvhNode::Leaf { shape_index, .. } => {
                    if *shape_index != skip
                        && hits_triangle(
                            origin,
                            dir,
                            &self.shapes[*shape_index].corners,
                            self.t_min,
                        )
                    {
                        return Some(*shape_index);
                    }
                }
                BvhNode::Node {
                    child_l_index,
                    child_l_aabb,
                    child_r_index,
                    child_r_aabb,
                    ..
                } => {
                    if hits_box(origin, dir, &inv, child_l_aabb) {
                        stack.push(*child_l_index);
                    }
                    if hits_box(origin, dir, &inv, child_r_aabb) {
                        stack.push(*child_r_index);
                    }
                }
            }
        }
        None
    }

    /// Triangles (other than `skip`) with a corner strictly in front of the
    /// plane through `origin` with normal `normal`: only these can block a
    /// ray leaving that plane on its front side. Found through the hierarchy
    /// (a box is entered when its farthest corner is in front).
    pub fn in_front(
        &self,
        origin: &Point3<f64>,
        normal: &Vector3<f64>,
        skip: usize,
        stack: &mut Vec<usize>,
        out: &mut Vec<usize>,
    ) {
        out.clear();
        if self.bvh.nodes.is_empty() {
            return;
        }
        let level = normal.dot(&origin.coords) + self.t_min;
        let box_front = |b: &Aabb<f64, 3>| {
            let mut far = 0.0;
            for k in 0..3 {
                far += normal[k] * if normal[k] > 0.0 { b.max[k] } else { b.min[k] };
            }
            far > level
        };
        stack.clear();
        stack.push(0);
        while let Some(index) = stack.pop() {
            match &self.bvh.nodes[index] {
                BvhNode::Leaf { shape_index, .. } => {
                    if *shape_index != skip
                        && self.shapes[*shape_index]
                            .corners
                            .iter()
                            .any(|c| normal.dot(&c.coords) > level)
                    {
                        out.push(*shape_index);
                    }
                }
                BvhNode::Node {
                    child_l_index,
                    child_l_aabb,
                    child_r_index,
                    child_r_aabb,
                    ..
                } => {
                    if box_front(child_l_aabb) {
                        stack.push(*child_l_index);
                    }
                    if box_front(child_r_aabb) {
                        stack.push(*child_r_index);
                    }
                }
            }
        }
    }

    /// Whether the ray meets one of the triangles `candidates`.
    fn occluded_by(&self, origin: &Point3<f64>, dir: &Vector3<f64>, candidates: &[usize]) -> bool {
        candidates
            .iter()
            .any(|&t| hits_triangle(origin, dir, &self.shapes[t].corners, self.t_min))
    }
}

/// Up to this many triangles in front of a patch are tested one by one;
/// beyond, each ray goes through the hierarchy.
const BRUTE_FORCE_MAX: usize = 24;

/// Slab test for `t ≥ 0`; a zero direction component keeps the ray inside the
/// slab only if the origin is (closed bounds, so a ray in a box face counts).
fn hits_box(o: &Point3<f64>, d: &Vector3<f64>, inv: &Vector3<f64>, b: &Aabb<f64, 3>) -> bool {
    let mut t0 = 0.0f64;
    let mut t1 = f64::INFINITY;
    for k in 0..3 {
        if d[k] == 0.0 {
            if o[k] < b.min[k] || o[k] > b.max[k] {
                return false;
            }
            continue;
        }
        let (mut a, mut c) = ((b.min[k] - o[k]) * inv[k], (b.max[k] - o[k]) * inv[k]);
        if a > c {
            std::mem::swap(&mut a, &mut c);
        }
        t0 = t0.max(a);
        t1 = t1.min(c);
        if t0 > t1 {
            return false;
        }
    }
    true
}

/// Two-sided Möller–Trumbore: the triangle blocks the ray beyond `t_min`.
/// Edges and corners count as hits (closed triangle), so a ray cannot slip
/// through the seam between two triangles.
fn hits_triangle(o: &Point3<f64>, d: &Vector3<f64>, tri: &[Point3<f64>; 3], t_min: f64) -> bool {
    let e1 = tri[1] - tri[0];
    let e2 = tri[2] - tri[0];
    let p = d.cross(&e2);
    let det = e1.dot(&p);
    if det == 0.0 {
        // The ray is parallel to the plane: it cannot cross the face.
        return false;
    }
    let inv = 1.0 / det;
    let s = o - tri[0];
    let u = s.dot(&p) * inv;
    if !(0.0..=1.0).contains(&u) {
        return false;
    }
    let q = s.cross(&e1);
    let v = d.dot(&q) * inv;
    if v < 0.0 || u + v > 1.0 {
        return false;
    }
    e2.dot(&q) * inv > t_min
}

/// Options of the visibility computation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VisibilityOptions {
    /// Directions closer than this to a patch's tangent plane (radians) are
    /// not accessible. 0 keeps every direction strictly outside the patch.
    pub grazing_margin: f64,
    /// Test the cells whose centre is blocked against the cone exactly
    /// ([`exact`]): a cell is then in `PVC_j` when any of its directions
    /// reaches the patch. Off: the cell centres only (the ray-cast map).
    pub exact_cells: bool,
}

impl Default for VisibilityOptions {
    fn default() -> Self {
        Self {
            grazing_margin: 0.0,
            exact_cells: true,
        }
    }
}

/// Computes `PVC_j` for every triangle on `sphere` by rasterising the
/// occluders onto the sphere of directions around each patch's centroid:
/// every triangle in front of the patch's plane closes the still-open cells
/// whose direction lies in the triangle's cone as seen from the centroid.
///
/// This is exactly the ray test of [`compute_by_rays`] (a direction is in the
/// cone of a triangle iff the ray along it meets the closed triangle), up to
/// round-off on the triangle's edges, but costs
/// `O(occluders visited × cells they cover)` instead of one hierarchy
/// traversal per cell. The hierarchy is walked front to back and a subtree is
/// skipped when every cell its bounding sphere covers is already closed (or
/// it lies behind the patch's plane), so a patch stops paying for the part
/// once its cone is settled. `progress(done, total)` is called now and then
/// with the number of patches done.
pub fn compute(
    mesh: &TriMesh,
    sphere: &GeodesicSphere,
    options: VisibilityOptions,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> VisibilityMap {
    compute_sampled(mesh, sphere, options, 1, progress)
}

/// [`compute`] for every `every`-th patch only (patches `0, every, 2·every,
/// …`); the other rows stay empty. Each row computed is the one [`compute`]
/// gives (every triangle still occludes): a sample of a large part's map,
/// to time or check it at a fraction of the cost.
pub fn compute_sampled(
    mesh: &TriMesh,
    sphere: &GeodesicSphere,
    options: VisibilityOptions,
    every: usize,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> VisibilityMap {
    let caster = RayCaster::new(mesh);
    let grid = CellGrid::new(sphere);
    let shapes = exact::CellShapes::new(sphere);
    let tree = options
        .exact_cells
        .then(|| exact::ContourTree::new(mesh, &caster))
        .flatten();
    let mut ctx = Rasteriser::new(&caster, &grid, &shapes, sphere, options);
    ctx.contour = tree.as_ref();
    fill_rows(
        mesh,
        sphere.len(),
        every,
        progress,
        PatchScratch::default,
        |scratch, t, origin, normal, row| ctx.patch(scratch, t, origin, normal, row),
    )
}

/// What [`compute`] shares between patches.
struct Rasteriser<'a> {
    exact: exact::Exact<'a>,
    exact_cells: bool,
    /// `sin` of the grazing margin: directions need `d·n >` this.
    min_dot: f64,
    /// Cells whose centre has `d·n` above this (and not above `min_dot`)
    /// are at most a cell radius behind the horizon: part of them may be
    /// in front.
    band_dot: f64,
    /// Cells tested whole by the occluders' contour (the default; see
    /// `exact::contour`) instead of the rasteriser and the exact pass.
    contour: Option<&'a exact::ContourTree>,
    /// The cells in front of, and across the horizon of, nearby normals.
    fronts: Fronts,
}

/// Per cell of a coarse sphere: the cells certainly in front of every
/// patch whose normal lies in that coarse cell, and the cells to test one
/// by one (the others are certainly neither in front nor within a cell
/// radius behind the horizon). A patch then computes `d·n` for a few
/// hundred cells instead of all of them.
struct Fronts {
    coarse: GeodesicSphere,
    /// `words` per coarse cell.
    sure: Vec<u64>,
    /// Cells to test, per coarse cell: `test[start[k]..start[k + 1]]`
    /// (increasing).
    start: Vec<u32>,
    test: Vec<u32>,
}

impl Fronts {
    /// Coarse cells per fine one: about one in 16.
    const COARSE_FREQUENCY_DIVISOR: usize = 4;

    fn new(grid: &CellGrid, sphere: &GeodesicSphere, min_dot: f64, band_dot: f64) -> Self {
        let coarse = GeodesicSphere::with_frequency(
            (sphere.frequency() / Self::COARSE_FREQUENCY_DIVISOR).max(1),
        );
        // A normal in coarse cell k is within `radius` of its direction, so
        // d·n is within `radius` of d·direction (a little more for
        // round-off).
        let radius = coarse.cell_radius() * (1.0 + 1e-9) + 1e-12;
        let words = grid.cells.div_ceil(64);
        let mut sure = vec![0u64; words * coarse.len()];
        let mut start = Vec::with_capacity(coarse.len() + 1);
        let mut test = Vec::new();
        for (k, r) in coarse.cells().iter().enumerate() {
            start.push(test.len() as u32);
            for (i, d) in grid.dirs.iter().enumerate() {
                let dot = d.dot(r);
                if dot - radius > min_dot {
                    sure[k * words + i / 64] |= 1 << (i % 64);
                } else if dot + radius > band_dot {
                    test.push(i as u32);
                }
            }
        }
        start.push(test.len() as u32);
        Self {
            coarse,
            sure,
            start,
            test,
        }
    }
}

/// Per-thread memory of [`compute`].
#[derive(Debug, Default)]
struct PatchScratch {
    stack: Vec<usize>,
    exact: exact::ExactScratch,
    /// Face of the coarse sphere last located.
    face_hint: usize,
}

impl<'a> Rasteriser<'a> {
    fn new(
        caster: &'a RayCaster,
        grid: &'a CellGrid,
        cells: &'a exact::CellShapes,
        sphere: &'a GeodesicSphere,
        options: VisibilityOptions,
    ) -> Self {
        let min_dot = options.grazing_margin.sin();
        let band_dot = min_dot * cells.cos_radius()
            - options.grazing_margin.cos() * cells.sin_radius()
            - CAP_MARGIN;
        Self {
            exact: exact::Exact {
                caster,
                grid,
                cells,
                sphere,
                flood: true,
            },
            exact_cells: options.exact_cells,
            min_dot,
            band_dot,
            contour: None,
            fronts: Fronts::new(grid, sphere, min_dot, band_dot),
        }
    }

    /// Fills `row` with the cone of triangle `t` (centroid `origin`, unit
    /// `normal`); returns the cells the exact test opened.
    fn patch(
        &self,
        w: &mut PatchScratch,
        t: usize,
        origin: &Point3<f64>,
        normal: &Vector3<f64>,
        row: &mut [u64],
    ) -> u32 {
        let frame = exact::PatchFrame {
            origin,
            normal,
            min_dot: self.min_dot,
            skip: t,
        };
        let open = self.start(w, normal, row);
        if self.exact_cells
            && let Some(tree) = self.contour
        {
            if let Some(added) = self.exact.by_contour(tree, &frame, row, &mut w.exact) {
                return added;
            }
            // Counts that disagree (round-off): the rasteriser decides.
            row.iter_mut().for_each(|x| *x = 0);
            self.start(w, normal, row);
        }
        let caster = self.exact.caster;
        caster.rasterise(
            origin,
            normal,
            t,
            self.exact.grid,
            row,
            open,
            &mut w.stack,
            &mut w.exact,
        );
        if !self.exact_cells {
            return 0;
        }
        self.exact.upgrade(&frame, row, &mut w.exact)
    }

    /// Starts a patch: sets in `row` the cells whose centre is in front of
    /// the patch (returns how many), lists in `w.exact.band` those within a
    /// cell radius behind its horizon.
    fn start(&self, w: &mut PatchScratch, normal: &Vector3<f64>, row: &mut [u64]) -> usize {
        let caster = self.exact.caster;
        let grid = self.exact.grid;
        w.exact.begin(caster.shapes.len(), grid.cells);
        let words = row.len();
        let fronts = &self.fronts;
        if let Some(k) = fronts.coarse.locate(normal, &mut w.face_hint) {
            // The cells certainly in front, then the others near the
            // horizon one by one (`d·n` as for every cell below).
            row.copy_from_slice(&fronts.sure[k * words..(k + 1) * words]);
            let mut open = row.iter().map(|x| x.count_ones() as usize).sum();
            for &i in &fronts.test[fronts.start[k] as usize..fronts.start[k + 1] as usize] {
                let dot = grid.dirs[i as usize].dot(normal);
                if dot > self.min_dot {
                    row[i as usize / 64] |= 1 << (i % 64);
                    open += 1;
                } else if dot > self.band_dot {
                    w.exact.band.push(i);
                }
            }
            return open;
        }
        let mut open = 0usize;
        for (i, d) in grid.dirs.iter().enumerate() {
            let dot = d.dot(normal);
            if dot > self.min_dot {
                row[i / 64] |= 1 << (i % 64);
                open += 1;
            } else if dot > self.band_dot {
                w.exact.band.push(i as u32);
            }
        }
        open
    }
}

/// The map of `cells` cells over `mesh`'s patches, filled one patch row at a
/// time in parallel: `patch(state, t, origin, normal, row)` sets the cells
/// open from triangle `t` (centroid `origin`) in `row`, with `state` made by
/// `init` once per worker; only every `every`-th row is filled.
/// `progress(done, total)` is called every `PROGRESS_CHUNK` patches.
fn fill_rows<S>(
    mesh: &TriMesh,
    cells: usize,
    every: usize,
    progress: &(dyn Fn(usize, usize) + Sync),
    init: impl Fn() -> S + Sync + Send,
    patch: impl Fn(&mut S, usize, &Point3<f64>, &Vector3<f64>, &mut [u64]) -> u32 + Sync + Send,
) -> VisibilityMap {
    /// Patches per progress report.
    const PROGRESS_CHUNK: usize = 64;
    let n = mesh.triangles.len();
    let mut map = VisibilityMap::new(cells, n);
    let words = map.words;
    let done = AtomicUsize::new(0);
    map.bits
        .par_chunks_mut(words * PROGRESS_CHUNK)
        .zip(map.upgraded.par_chunks_mut(PROGRESS_CHUNK))
        .enumerate()
        .for_each_init(init, |state, (chunk, (bits, upgraded))| {
            for (k, row) in bits.chunks_mut(words).enumerate() {
                let t = chunk * PROGRESS_CHUNK + k;
                if !t.is_multiple_of(every.max(1)) {
                    continue;
                }
                let [a, b, c] = mesh.corners(t);
                let origin = Point3::from((a.coords + b.coords + c.coords) / 3.0);
                upgraded[k] = patch(state, t, &origin, &mesh.normals[t], row);
            }
            let now = done.fetch_add(bits.len() / words, Ordering::Relaxed) + bits.len() / words;
            progress(now, n);
        });
    map
}

/// Widening of every cap (radians) so that round-off never culls a cell on
/// its rim.
const CAP_MARGIN: f64 = 1e-9;
/// A leaf triangle whose bounding cap reaches closer than this cosine to a
/// half-sphere is tested against every open cell instead of through the grid.
const CAP_MIN_COS: f64 = 0.05;

/// A subtree is checked for open cells under its bounding cap only when the
/// cap holds about this many cells or fewer.
const CULL_MAX_CELLS: f64 = 16.0;

/// The cell directions bucketed in rows of equal height along a pole in
/// general position (so that the axes of a part do not meet the crowded
/// polar rows) and in longitude within each row, to list the cells inside a
/// spherical cap without inverse trigonometry per row.
#[derive(Debug)]
struct CellGrid {
    /// `e1`, `e2`, pole.
    frame: [Vector3<f64>; 3],
    /// Row height in `1 − z` (z along the pole): rows have equal area.
    dz: f64,
    /// Per row: first bucket and number of buckets (longitudes).
    rows: Vec<(usize, usize)>,
    /// Bucket `k` holds `entries[starts[k]..starts[k + 1]]`.
    starts: Vec<u32>,
    /// Cell index and direction.
    entries: Vec<(u32, Vector3<f64>)>,
    /// Direction of each cell, by index.
    dirs: Vec<Vector3<f64>>,
    cells: usize,
}

impl CellGrid {
    /// Rows about 1.5 cell spacings tall at the equator, buckets as wide, so
    /// that a bucket holds about two cells.
    fn new(sphere: &GeodesicSphere) -> Self {
        /// Bucket size in cell spacings.
        const BUCKET_SPACINGS: f64 = 1.5;
        let pole = Vector3::new(0.37, -0.52, 0.77).normalize();
        let e1 = pole.cross(&Vector3::x()).normalize();
        let e2 = pole.cross(&e1);
        let step = sphere.spacing() * BUCKET_SPACINGS;
        let n_rows = ((2.0 / step).ceil() as usize).max(1);
        let dz = 2.0 / n_rows as f64;
        let mut rows = Vec::with_capacity(n_rows);
        let mut buckets = 0;
        for r in 0..n_rows {
            let z = 1.0 - (r as f64 + 0.5) * dz;
            let n_phi = ((TAU * (1.0 - z * z).max(0.0).sqrt() / step).ceil() as usize).max(1);
            rows.push((buckets, n_phi));
            buckets += n_phi;
        }
        let mut grid = Self {
            frame: [e1, e2, pole],
            dz,
            rows,
            starts: vec![0; buckets + 1],
            entries: Vec::new(),
            dirs: sphere.cells().to_vec(),
            cells: sphere.len(),
        };
        let keys: Vec<usize> = sphere.cells().iter().map(|d| grid.bucket(d)).collect();
        for &k in &keys {
            grid.starts[k + 1] += 1;
        }
        for k in 0..buckets {
            grid.starts[k + 1] += grid.starts[k];
        }
        let mut fill: Vec<u32> = grid.starts[..buckets].to_vec();
        grid.entries = vec![(0, Vector3::zeros()); sphere.len()];
        for (i, (&k, d)) in keys.iter().zip(sphere.cells()).enumerate() {
            grid.entries[fill[k] as usize] = (i as u32, *d);
            fill[k] += 1;
        }
        grid
    }

    /// Height along the pole and longitude (in `[0, 2π)`) of `d`.
    fn polar(&self, d: &Vector3<f64>) -> (f64, f64) {
        let [e1, e2, pole] = &self.frame;
        let phi = d.dot(e2).atan2(d.dot(e1)).rem_euclid(TAU);
        (d.dot(pole).clamp(-1.0, 1.0), phi)
    }

    fn row_of(&self, z: f64) -> usize {
        (((1.0 - z) / self.dz).max(0.0) as usize).min(self.rows.len() - 1)
    }

    fn bucket(&self, d: &Vector3<f64>) -> usize {
        let (z, phi) = self.polar(d);
        let (first, n_phi) = self.rows[self.row_of(z)];
        first + ((phi / TAU * n_phi as f64) as usize).min(n_phi - 1)
    }

    /// Expected number of cells in a cap of angular radius with cosine
    /// `cos_r`.
    fn cells_in_cap(&self, cos_r: f64) -> f64 {
        (1.0 - cos_r) * 0.5 * self.cells as f64
    }

    /// Calls `f(cell, direction)` for every cell in the cap around the unit
    /// vector `centre` of angular radius `r` (given as `cos r ≥ 0` and
    /// `sin r`), and maybe a few more; stops when `f` returns `true`, and
    /// returns whether it did.
    fn any_in_cap(
        &self,
        centre: &Vector3<f64>,
        cos_r: f64,
        sin_r: f64,
        mut f: impl FnMut(usize, &Vector3<f64>) -> bool,
    ) -> bool {
        let (z, phi) = self.polar(centre);
        let s = (1.0 - z * z).max(0.0).sqrt();
        // Heights of the cap's rim nearest and farthest from the pole, or
        // the pole itself when the cap holds it.
        let holds_north = z >= cos_r - CAP_MARGIN;
        let holds_south = -z >= cos_r - CAP_MARGIN;
        let z_hi = if holds_north {
            1.0
        } else {
            z * cos_r + s * sin_r + CAP_MARGIN
        };
        let z_lo = if holds_south {
            -1.0
        } else {
            z * cos_r - s * sin_r - CAP_MARGIN
        };
        // Longitude half-width of a cap clear of the poles.
        let dphi = if holds_north || holds_south || sin_r >= s {
            PI
        } else {
            (sin_r / s).asin() + CAP_MARGIN
        };
        for &(first, n_phi) in &self.rows[self.row_of(z_hi)..=self.row_of(z_lo)] {
            let (k0, count) = if dphi >= PI {
                (0, n_phi)
            } else {
                let scale = n_phi as f64 / TAU;
                let k0 = ((phi - dphi) * scale).floor() as i64;
                let k1 = ((phi + dphi) * scale).floor() as i64;
                (k0, ((k1 - k0 + 1) as usize).min(n_phi))
            };
            for t in 0..count {
                let k = first + (k0 + t as i64).rem_euclid(n_phi as i64) as usize;
                for (i, d) in &self.entries[self.starts[k] as usize..self.starts[k + 1] as usize] {
                    if f(*i as usize, d) {
                        return true;
                    }
                }
            }
        }
        false
    }
}

/// Calls `f(cell)` for every set bit of `row`; stops when `f` returns `true`,
/// and returns whether it did.
fn any_open(row: &[u64], mut f: impl FnMut(usize) -> bool) -> bool {
    for (w, &bits) in row.iter().enumerate() {
        let mut bits = bits;
        while bits != 0 {
            let i = w * 64 + bits.trailing_zeros() as usize;
            bits &= bits - 1;
            if f(i) {
                return true;
            }
        }
    }
    false
}

fn is_open(row: &[u64], i: usize) -> bool {
    row[i / 64] >> (i % 64) & 1 == 1
}

impl RayCaster {
    /// Closes the cells of `row` (`open` of them set) whose rays from
    /// `origin` meet a triangle other than `skip` in front of the plane
    /// `(origin, normal)`. See [`compute`].
    #[allow(clippy::too_many_arguments)]
    fn rasterise(
        &self,
        origin: &Point3<f64>,
        normal: &Vector3<f64>,
        skip: usize,
        grid: &CellGrid,
        row: &mut [u64],
        mut open: usize,
        stack: &mut Vec<usize>,
        rec: &mut exact::ExactScratch,
    ) {
        if self.bvh.nodes.is_empty() {
            return;
        }
        if open == 0 {
            // Nothing to close; whatever is in front is not looked at.
            rec.skipped(0);
            return;
        }
        let level = normal.dot(&origin.coords) + self.t_min;
        let box_front = |b: &Aabb<f64, 3>| {
            let mut far = 0.0;
            for k in 0..3 {
                far += normal[k] * if normal[k] > 0.0 { b.max[k] } else { b.min[k] };
            }
            far > level
        };
        // Whether some open cell may look at the box: false when it lies
        // behind the plane (`Behind`) or its bounding sphere, seen from the
        // origin, covers closed cells only (`Culled`).
        let box_matters = |b: &Aabb<f64, 3>, row: &[u64], open: usize| -> Visit {
            if !box_front(b) {
                return Visit::Behind;
            }
            let keep = |yes: bool| if yes { Visit::Enter } else { Visit::Culled };
            let centre = Point3::from((b.min.coords + b.max.coords) * 0.5);
            let radius = (b.max - b.min).norm() * 0.5;
            let to = centre - origin;
            let dist = to.norm();
            if dist <= radius * (1.0 + CAP_MARGIN) + self.t_min {
                return Visit::Enter;
            }
            let sin_r = radius / dist;
            let cos_r = (1.0 - sin_r * sin_r).sqrt();
            if cos_r < CAP_MIN_COS {
                return Visit::Enter;
            }
            let in_cap = grid.cells_in_cap(cos_r);
            if in_cap > CULL_MAX_CELLS {
                // Checking would cost more than descending usually does.
                return Visit::Enter;
            }
            let u = to / dist;
            let cos_test = cos_r - CAP_MARGIN;
            keep(if in_cap > open as f64 {
                any_open(row, |i| grid.dirs[i].dot(&u) >= cos_test)
            } else {
                grid.any_in_cap(&u, cos_r, sin_r, |i, d| {
                    is_open(row, i) && d.dot(&u) >= cos_test
                })
            })
        };
        stack.clear();
        stack.push(0);
        while let Some(index) = stack.pop() {
            match &self.bvh.nodes[index] {
                BvhNode::Leaf { shape_index, .. } => {
                    if *shape_index == skip {
                        continue;
                    }
                    let corners = &self.shapes[*shape_index].corners;
                    if !corners.iter().any(|c| normal.dot(&c.coords) > level) {
                        continue;
                    }
                    rec.front();
                    match exact::Cone::new(origin, corners, self.t_min, *shape_index) {
                        Ok(cone) => {
                            open -= close_cells(
                                grid,
                                row,
                                open,
                                (&cone.centre, cone.cos_r),
                                |d| cone.contains(d),
                                |cell| rec.blocked(cell, *shape_index),
                            );
                            rec.processed(cone);
                        }
                        Err(exact::NoCone::Near) => {
                            // Within t_min of the plane the cone test would
                            // count hits the ray test ignores as its own
                            // start: test those rays exactly.
                            let dirs = corners.map(|c| c - origin);
                            let (centre, cos_r) = exact::cap_of(&dirs);
                            open -= close_cells(
                                grid,
                                row,
                                open,
                                (&centre, cos_r),
                                |d| hits_triangle(origin, d, corners, self.t_min),
                                |cell| rec.forced(cell),
                            );
                        }
                        Err(exact::NoCone::InPlane) => {}
                    }
                    if open == 0 {
                        for &node in stack.iter() {
                            rec.skipped(node);
                        }
                        return;
                    }
                }
                BvhNode::Node {
                    child_l_index,
                    child_l_aabb,
                    child_r_index,
                    child_r_aabb,
                    ..
                } => {
                    let l = box_matters(child_l_aabb, row, open);
                    let r = box_matters(child_r_aabb, row, open);
                    if l == Visit::Culled {
                        rec.skipped(*child_l_index);
                    }
                    if r == Visit::Culled {
                        rec.skipped(*child_r_index);
                    }
                    let (l, r) = (l == Visit::Enter, r == Visit::Enter);
                    // Front to back: the nearer child is popped first, so
                    // the farther one is often culled by then.
                    let dist = |b: &Aabb<f64, 3>| (b.center() - origin).norm_squared();
                    let near_left = dist(child_l_aabb) <= dist(child_r_aabb);
                    let (first, second) = if near_left {
                        ((r, *child_r_index), (l, *child_l_index))
                    } else {
                        ((l, *child_l_index), (r, *child_r_index))
                    };
                    for (keep, i) in [first, second] {
                        if keep {
                            stack.push(i);
                        }
                    }
                }
            }
        }
    }
}

/// What the rasteriser does with a child box.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Visit {
    /// Descend.
    Enter,
    /// Behind the patch's plane: nothing in it blocks a front direction.
    Behind,
    /// In front, but every cell centre it may cover is already closed.
    Culled,
}

/// Closes the open cells of `row` (`open` of them) whose direction is
/// `inside` a triangle's cone, looking only within its bounding cap
/// (`centre`, `cos` of the radius; `-1`: anywhere); returns how many it
/// closed, telling each to `closed`.
fn close_cells(
    grid: &CellGrid,
    row: &mut [u64],
    open: usize,
    (centre, cos_r): (&Vector3<f64>, f64),
    inside: impl Fn(&Vector3<f64>) -> bool,
    mut closed_one: impl FnMut(usize),
) -> usize {
    let mut closed = 0;
    if cos_r < CAP_MIN_COS || grid.cells_in_cap(cos_r) > open as f64 {
        // A wide cone, or few cells left: test the open cells themselves.
        for w in 0..row.len() {
            let mut bits = row[w];
            while bits != 0 {
                let j = bits.trailing_zeros();
                bits &= bits - 1;
                if inside(&grid.dirs[w * 64 + j as usize]) {
                    row[w] &= !(1 << j);
                    closed += 1;
                    closed_one(w * 64 + j as usize);
                }
            }
        }
    } else {
        let sin_r = (1.0 - cos_r * cos_r).max(0.0).sqrt();
        grid.any_in_cap(centre, cos_r, sin_r, |i, d| {
            if is_open(row, i) && inside(d) {
                row[i / 64] &= !(1 << (i % 64));
                closed += 1;
                closed_one(i);
            }
            false
        });
    }
    closed
}

/// Computes `PVC_j` for every triangle on `sphere` by casting one ray per
/// patch and front-facing cell through the hierarchy (any-hit, early exit).
/// The reference for [`compute`], which gives the same map faster;
/// `progress(done, total)` is called now and then with the number of patches
/// traced.
pub fn compute_by_rays(
    mesh: &TriMesh,
    sphere: &GeodesicSphere,
    options: VisibilityOptions,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> VisibilityMap {
    let caster = RayCaster::new(mesh);
    let cells = sphere.cells();
    let min_dot = options.grazing_margin.sin();
    fill_rows(
        mesh,
        cells.len(),
        1,
        progress,
        || (Vec::new(), Vec::new()),
        |(stack, front), t, origin, normal, row| {
            // Most patches of a part have few triangles in front of them
            // (none on convex regions): test those directly.
            caster.in_front(origin, normal, t, stack, front);
            let small = front.len() <= BRUTE_FORCE_MAX;
            for (i, d) in cells.iter().enumerate() {
                if d.dot(normal) > min_dot {
                    let blocked = if small {
                        caster.occluded_by(origin, d, front)
                    } else {
                        caster.occluded(origin, d, t, stack)
                    };
                    if !blocked {
                        row[i / 64] |= 1 << (i % 64);
                    }
                }
            }
            0
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::WeldOptions;

    type P = Point3<f64>;

    #[test]
    fn a_lid_blocks_the_floor_from_above_only() {
        // Floor triangle at z = 0 (normal +z), a lid at z = 1 covering it.
        let soup = [
            [
                P::new(0.0, 0.0, 0.0),
                P::new(1.0, 0.0, 0.0),
                P::new(0.0, 1.0, 0.0),
            ],
            [
                P::new(-5.0, -5.0, 1.0),
                P::new(5.0, -5.0, 1.0),
                P::new(0.0, 5.0, 1.0),
            ],
        ];
        let mesh = TriMesh::from_triangles(&soup, WeldOptions::default()).unwrap();
        let caster = RayCaster::new(&mesh);
        let mut stack = Vec::new();
        let o = P::new(0.3, 0.3, 0.0);
        assert!(caster.occluded(&o, &Vector3::z(), 0, &mut stack));
        // Steep enough sideways, the ray leaves under the lid's edge.
        let side = Vector3::new(1.0, 0.0, 0.1).normalize();
        assert!(!caster.occluded(&o, &side, 0, &mut stack));
        // Its own triangle never blocks it.
        assert!(!caster.occluded(&o, &(-Vector3::z()), 0, &mut stack));
        let sphere = GeodesicSphere::with_frequency(4);
        // The ray test's semantics: cell centres only.
        let map = compute(
            &mesh,
            &sphere,
            VisibilityOptions {
                exact_cells: false,
                ..VisibilityOptions::default()
            },
            &|_, _| {},
        );
        for (i, d) in sphere.cells().iter().enumerate() {
            // Upward cells reach the floor only under the lid's rim, at least
            // atan(1/~4.7) off the horizon; the lid sees upward cells only.
            if map.visible(0, i) {
                assert!(d.z > 0.0 && d.z < 0.5, "cell {i} {d:?}");
            }
            assert_eq!(map.visible(1, i), d.z > 0.0, "lid cell {i}");
        }
    }
}

#[cfg(test)]
mod raster_tests {
    use super::*;
    use crate::mesh::WeldOptions;
    use crate::setup::samples::{bowl, cavity, dome, pocket, rotated, teapot, well, z_to};

    /// The rasterised map equals the ray-cast one, cell for cell, on the
    /// sample parts (tilted, so nothing lines up with the grid's frame).
    #[test]
    fn rasterised_map_equals_ray_casting_on_the_sample_parts() {
        let axis = Vector3::new(0.3, -0.2, 0.9).normalize();
        let tilt = z_to(&axis);
        let options = VisibilityOptions {
            exact_cells: false,
            ..VisibilityOptions::default()
        };
        for (name, soup, cells) in [
            ("well", well(10.0, 20.0, 24), 1280),
            ("bowl", bowl(30.0, 4, 24), 1280),
            ("cavity", cavity(30.0, 60.0, 6, 18), 1280),
            ("dome", dome(40.0, 115.0, 6, 18), 720),
            ("teapot", teapot(10, 12, 5, 6), 1280),
        ] {
            let mesh = TriMesh::from_triangles(&rotated(&soup, &tilt), WeldOptions::default())
                .expect("valid sample");
            let sphere = GeodesicSphere::with_at_least(cells).unwrap();
            let fast = compute(&mesh, &sphere, options, &|_, _| {});
            let rays = compute_by_rays(&mesh, &sphere, options, &|_, _| {});
            let mut differ = 0;
            let mut visible = 0;
            for j in 0..mesh.triangles.len() {
                visible += rays.pvc_len(j);
                for i in 0..sphere.len() {
                    differ += usize::from(fast.visible(j, i) != rays.visible(j, i));
                }
            }
            assert_eq!(
                differ, 0,
                "{name}: {differ} of {visible} visible pairs differ"
            );
            // Something is hidden and something visible: the test has teeth.
            let front = (0..mesh.triangles.len())
                .map(|j| {
                    sphere
                        .cells()
                        .iter()
                        .filter(|d| d.dot(&mesh.normals[j]) > 0.0)
                        .count()
                })
                .sum::<usize>();
            assert!(visible > 0 && (visible < front || name == "dome"), "{name}");
        }
    }

    /// The exact cell test against independent references, on tilted
    /// sample parts with narrow and grazing cones: every cell it opens has
    /// a direction (its witness) inside the cell that reaches the patch by
    /// ray casting, and every centre of a 16 times finer sphere that
    /// reaches a patch lies in a cell of the patch's cone (nothing visible
    /// is lost between the centres).
    #[test]
    fn exact_cells_are_those_some_direction_of_which_reaches_the_patch() {
        let tilt = z_to(&Vector3::new(0.3, -0.2, 0.9).normalize());
        let sphere = GeodesicSphere::with_frequency(4);
        let middle = GeodesicSphere::with_frequency(8);
        let fine = GeodesicSphere::with_frequency(16);
        // The cell of `sphere` holding each cell centre of `fine`.
        let mut parent = vec![0; fine.len()];
        for i in 0..sphere.len() {
            for c in sphere.children(i) {
                for g in middle.children(c) {
                    parent[g] = i;
                }
            }
        }
        let centres = VisibilityOptions {
            exact_cells: false,
            ..VisibilityOptions::default()
        };
        let (mut opened, mut beyond_centres) = (0, 0);
        for (name, soup) in [
            ("narrow well", well(1.0, 30.0, 24)),
            ("drafted pocket", pocket(20.0, 30.0, 15.0, 0.5, 5.0, 2)),
            ("cavity", cavity(30.0, 60.0, 6, 18)),
            ("teapot", teapot(10, 12, 5, 6)),
        ] {
            let mesh = TriMesh::from_triangles(&rotated(&soup, &tilt), WeldOptions::default())
                .expect("valid sample");
            let exact = compute(&mesh, &sphere, VisibilityOptions::default(), &|_, _| {});
            let centre = compute(&mesh, &sphere, centres, &|_, _| {});
            let dense = compute(&mesh, &fine, centres, &|_, _| {});
            let caster = RayCaster::new(&mesh);
            let grid = CellGrid::new(&sphere);
            let shapes = exact::CellShapes::new(&sphere);
            let tree = exact::ContourTree::new(&mesh, &caster).unwrap();
            let mut ctx = Rasteriser::new(
                &caster,
                &grid,
                &shapes,
                &sphere,
                VisibilityOptions::default(),
            );
            ctx.contour = Some(&tree);
            let (mut w, mut stack) = (PatchScratch::default(), Vec::new());
            w.exact.keep_witnesses = true;
            let mut row = vec![0u64; sphere.len().div_ceil(64)];
            for j in 0..mesh.triangles.len() {
                let [a, b, c] = mesh.corners(j);
                let origin = Point3::from((a.coords + b.coords + c.coords) / 3.0);
                let normal = mesh.normals[j];
                row.iter_mut().for_each(|x| *x = 0);
                let added = ctx.patch(&mut w, j, &origin, &normal, &mut row);
                assert_eq!(added as usize, exact.upgraded(j), "{name} patch {j}");
                assert_eq!(row.as_slice(), exact.pvc(j), "{name} patch {j}");
                assert_eq!(w.exact.witnesses.len(), exact.upgraded(j));
                for &(cell, x) in &w.exact.witnesses {
                    let cell = cell as usize;
                    assert!(exact.visible(j, cell));
                    let inside = (0..3).all(|k| {
                        let cs = sphere.corners(cell);
                        cs[k].cross(&cs[(k + 1) % 3]).dot(&x) >= -1e-12
                    });
                    assert!(inside, "{name} patch {j}: witness outside cell {cell}");
                    assert!(
                        x.dot(&normal) > 0.0 && !caster.occluded(&origin, &x, j, &mut stack),
                        "{name} patch {j} cell {cell}: witness {x:?} does not reach the patch"
                    );
                    opened += usize::from(!centre.visible(j, cell));
                }
                for i in 0..sphere.len() {
                    if centre.visible(j, i) {
                        assert!(exact.visible(j, i), "{name} patch {j} cell {i}");
                    }
                }
                for (g, &i) in parent.iter().enumerate() {
                    if dense.visible(j, g) {
                        assert!(
                            exact.visible(j, i),
                            "{name} patch {j}: fine centre {g} reaches it, cell {i} closed"
                        );
                        beyond_centres += usize::from(!centre.visible(j, i));
                    }
                }
            }
        }
        // The test has teeth: cells were opened, and the finer sphere saw
        // directions the centres missed.
        assert!(
            opened > 100 && beyond_centres > 100,
            "{opened} {beyond_centres}"
        );
    }

    /// Maps `mesh` on `sphere` three ways (every `every`-th patch): by the
    /// occluders' contour (the default), and by the rasteriser and the
    /// exact pass with and without the flood certificate; asserts the rows
    /// are the same, bit for bit. Returns how many candidates the flood
    /// certified, the cells the rays before the gather opened, and the
    /// boundary cells the contour method decided by counts and by rays.
    fn assert_methods_agree(
        name: &str,
        mesh: &TriMesh,
        sphere: &GeodesicSphere,
        every: usize,
    ) -> [usize; 4] {
        assert_methods_agree_with(name, mesh, sphere, every, VisibilityOptions::default())
    }

    /// [`assert_methods_agree`] with `options`.
    fn assert_methods_agree_with(
        name: &str,
        mesh: &TriMesh,
        sphere: &GeodesicSphere,
        every: usize,
        options: VisibilityOptions,
    ) -> [usize; 4] {
        let caster = RayCaster::new(mesh);
        let grid = CellGrid::new(sphere);
        let shapes = exact::CellShapes::new(sphere);
        let tree = exact::ContourTree::new(mesh, &caster).unwrap();
        let mut contour = Rasteriser::new(&caster, &grid, &shapes, sphere, options);
        contour.contour = Some(&tree);
        let flood = Rasteriser::new(&caster, &grid, &shapes, sphere, options);
        let mut slow = Rasteriser::new(&caster, &grid, &shapes, sphere, options);
        slow.exact.flood = false;
        let mut counts = [0; 4];
        let mut scratch = PatchScratch::default();
        let mut rows = [Vec::new(), Vec::new(), Vec::new()];
        for t in (0..mesh.triangles.len()).step_by(every) {
            let [a, b, c] = mesh.corners(t);
            let origin = Point3::from((a.coords + b.coords + c.coords) / 3.0);
            let normal = &mesh.normals[t];
            for (k, ctx) in [&contour, &flood, &slow].into_iter().enumerate() {
                let out = &mut rows[k];
                out.clear();
                out.resize(sphere.len().div_ceil(64), 0u64);
                ctx.patch(&mut scratch, t, &origin, normal, out);
                match k {
                    0 => {
                        counts[2] += scratch.exact.counted;
                        counts[3] += scratch.exact.by_rays;
                    }
                    1 => {
                        counts[0] += scratch.exact.certified;
                        counts[1] += scratch.exact.witnesses.len();
                    }
                    _ => {}
                }
            }
            assert_eq!(rows[0], rows[2], "{name}: patch {t}, contour");
            assert_eq!(rows[1], rows[2], "{name}: patch {t}, flood certificate");
        }
        counts
    }

    /// The contour method, and the flood certificate and the rays before
    /// the gather (the exact pass's fast path), give the map that the
    /// gather and the exact test give for every candidate, bit for bit, on
    /// tilted parts whose triangles are smaller than the cells (where the
    /// fast paths decide nearly every cell) and on ones as coarse as the
    /// cells.
    #[test]
    fn contour_map_equals_the_rasterised_exact_map() {
        let tilt = z_to(&Vector3::new(0.3, -0.2, 0.9).normalize());
        let mut counts = [0; 4];
        for (name, soup, cells) in [
            ("fine teapot", teapot(20, 32, 9, 16), 80),
            ("cavity", cavity(30.0, 60.0, 8, 24), 320),
            ("drafted pocket", pocket(20.0, 30.0, 15.0, 0.5, 5.0, 4), 320),
            ("dome", dome(40.0, 115.0, 8, 24), 80),
            ("narrow well", well(1.0, 30.0, 24), 720),
        ] {
            let mesh = TriMesh::from_triangles(&rotated(&soup, &tilt), WeldOptions::default())
                .expect("valid sample");
            let sphere = GeodesicSphere::with_at_least(cells).unwrap();
            let c = assert_methods_agree(name, &mesh, &sphere, 1);
            for k in 0..4 {
                counts[k] += c[k];
            }
            // And with a grazing margin (the front half is then a smaller
            // cap than the contour's clip).
            if matches!(name, "cavity" | "drafted pocket") {
                let margin = VisibilityOptions {
                    grazing_margin: 5f64.to_radians(),
                    exact_cells: true,
                };
                assert_methods_agree_with(name, &mesh, &sphere, 1, margin);
            }
        }
        // The fast paths did decide cells both ways, and the counts decided
        // most boundary cells.
        let [certified, opened, counted, by_rays] = counts;
        assert!(certified > 1000 && opened > 1000, "{counts:?}");
        assert!(counted > 1000 && counted > 2 * by_rays, "{counts:?}");
    }

    /// A floor in a box whose walls stop 0.01 short of it, seen with a
    /// grazing margin of 30° (more than a cell across, at 320 cells): the
    /// only contour in front of the floor (the walls' lower borders) lies
    /// between its plane and the margin, so no boundary cell has a part in
    /// front, and the lid and walls cover every direction the margin lets
    /// through: the floor sees nothing. (Taking "no boundary cell in front"
    /// for "nothing to decide" left it all open.)
    #[test]
    fn a_contour_below_the_grazing_margin_leaves_one_count_in_front() {
        type P = Point3<f64>;
        let (gap, top) = (0.01, 1.0);
        let corner = |x: f64, y: f64, z: f64| P::new(x, y, z);
        let mut soup = vec![
            [
                corner(-1.0, -1.0, 0.0),
                corner(1.0, -1.0, 0.0),
                corner(1.0, 1.0, 0.0),
            ],
            [
                corner(-1.0, -1.0, 0.0),
                corner(1.0, 1.0, 0.0),
                corner(-1.0, 1.0, 0.0),
            ],
            [
                corner(-1.0, -1.0, top),
                corner(1.0, 1.0, top),
                corner(1.0, -1.0, top),
            ],
            [
                corner(-1.0, -1.0, top),
                corner(-1.0, 1.0, top),
                corner(1.0, 1.0, top),
            ],
        ];
        let ring = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)];
        for k in 0..4 {
            let ((x0, y0), (x1, y1)) = (ring[k], ring[(k + 1) % 4]);
            let (a, b) = (corner(x0, y0, gap), corner(x1, y1, gap));
            let (c, d) = (corner(x1, y1, top), corner(x0, y0, top));
            soup.push([a, c, b]);
            soup.push([a, d, c]);
        }
        let tilt = z_to(&Vector3::new(0.3, -0.2, 0.9).normalize());
        let mesh = TriMesh::from_triangles(&rotated(&soup, &tilt), WeldOptions::default())
            .expect("valid box");
        let sphere = GeodesicSphere::with_at_least(320).unwrap();
        let options = VisibilityOptions {
            grazing_margin: 30f64.to_radians(),
            exact_cells: true,
        };
        assert_methods_agree_with("box", &mesh, &sphere, 1, options);
        let map = compute(&mesh, &sphere, options, &|_, _| {});
        // Without the margin the floor sees out under the walls: the test
        // has teeth.
        let open = compute(&mesh, &sphere, VisibilityOptions::default(), &|_, _| {});
        for floor in [0, 1] {
            assert_eq!(map.pvc_len(floor), 0, "floor triangle {floor}");
            assert!(open.pvc_len(floor) > 0, "floor triangle {floor}");
        }
    }

    /// The same on corpus meshes turned a random way, at the 5,000
    /// cells (every tenth patch). Needs the corpus (`INTERPD_CORPUS`, or
    /// `../shared/corpus` next to the checkout); skipped without it.
    #[test]
    fn contour_map_equals_the_rasterised_exact_map_on_corpus_meshes() {
        let corpus = std::env::var_os("INTERPD_CORPUS")
            .map(std::path::PathBuf::from)
            .unwrap_or_else(|| {
                std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/corpus")
            });
        let sphere = GeodesicSphere::with_at_least(5000).unwrap();
        for (k, file) in [
            "ocl_demo.stl",
            "ocl_ktoolcav.stl",
            "ocl_sphere_on_plate.stl",
        ]
        .iter()
        .enumerate()
        {
            let path = corpus.join("meshes").join(file);
            if !path.exists() {
                eprintln!("skipped: {} not found (set INTERPD_CORPUS)", path.display());
                return;
            }
            let mesh = TriMesh::from_stl_path(&path, WeldOptions::default()).expect("corpus mesh");
            let soup: Vec<_> = (0..mesh.triangles.len()).map(|t| mesh.corners(t)).collect();
            let turned = rotated(&soup, &crate::setup::samples::random_rotation(k as u64 + 7));
            let mesh = TriMesh::from_triangles(&turned, WeldOptions::default()).expect("turned");
            let [certified, opened, counted, _] = assert_methods_agree(file, &mesh, &sphere, 10);
            assert!(
                certified + opened > 0 && counted > 0,
                "{file}: nothing decided by the fast paths"
            );
        }
    }

    #[test]
    fn grid_lists_every_cell_of_a_cap() {
        let sphere = GeodesicSphere::with_frequency(12);
        let grid = CellGrid::new(&sphere);
        let probe = GeodesicSphere::with_frequency(5);
        // Also caps around, and grazing, the grid's poles.
        let pole = grid.frame[2];
        let near_pole = (pole + grid.frame[0] * 0.02).normalize();
        let extra = [pole, -pole, near_pole, -near_pole];
        for u in probe.cells().iter().chain(&extra) {
            for r in [0.01f64, 0.05, 0.2, 0.7, 1.4] {
                let mut listed = vec![false; sphere.len()];
                grid.any_in_cap(u, r.cos(), r.sin(), |i, _| {
                    listed[i] = true;
                    false
                });
                for (i, d) in sphere.cells().iter().enumerate() {
                    if d.dot(u) >= r.cos() {
                        assert!(listed[i], "cell {i} missed, cap {u:?} r {r}");
                    }
                }
            }
        }
    }
}
