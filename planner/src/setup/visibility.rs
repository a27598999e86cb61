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

use std::sync::atomic::{AtomicUsize, Ordering};

use bvh::aabb::{Aabb, Bounded};
use bvh::bounding_hierarchy::{BHShape, BoundingHierarchy};
use bvh::bvh::{Bvh, BvhNode};
use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

use super::sphere::GeodesicSphere;
use crate::mesh::TriMesh;

/// Bits of the map: patch-major, one bitset of `cells` bits per patch.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct VisibilityMap {
    cells: usize,
    patches: usize,
    words: usize,
    bits: Vec<u64>,
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
        Self { shapes, bvh, t_min }
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
        if self.bvh.nodes.is_empty() {
            return false;
        }
        let inv = dir.map(|c| 1.0 / c);
        stack.clear();
        // The root's box is not stored in a node: test it through its children.
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
                        return true;
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
        false
    }
}

impl RayCaster {
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
}

/// Computes `PVC_j` for every triangle on `sphere`. `progress(done, total)`
/// is called now and then with the number of patches traced.
pub fn compute(
    mesh: &TriMesh,
    sphere: &GeodesicSphere,
    options: VisibilityOptions,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> VisibilityMap {
    let caster = RayCaster::new(mesh);
    let cells = sphere.cells();
    let n = mesh.triangles.len();
    let mut map = VisibilityMap::new(cells.len(), n);
    let words = map.words;
    let min_dot = options.grazing_margin.sin();
    let done = AtomicUsize::new(0);
    /// Patches per progress report.
    const PROGRESS_CHUNK: usize = 64;
    map.bits
        .par_chunks_mut(words * PROGRESS_CHUNK)
        .enumerate()
        .for_each_init(
            || (Vec::new(), Vec::new()),
            |(stack, front), (chunk, bits)| {
                for (k, row) in bits.chunks_mut(words).enumerate() {
                    let t = chunk * PROGRESS_CHUNK + k;
                    let [a, b, c] = mesh.corners(t);
                    let origin = Point3::from((a.coords + b.coords + c.coords) / 3.0);
                    let normal = mesh.normals[t];
                    // Most patches of a part have few triangles in front of them
                    // (none on convex regions): test those directly.
                    caster.in_front(&origin, &normal, t, stack, front);
                    let small = front.len() <= BRUTE_FORCE_MAX;
                    for (i, d) in cells.iter().enumerate() {
                        if d.dot(&normal) > min_dot {
                            let blocked = if small {
                                caster.occluded_by(&origin, d, front)
                            } else {
                                caster.occluded(&origin, d, t, stack)
                            };
                            if !blocked {
                                row[i / 64] |= 1 << (i % 64);
                            }
                        }
                    }
                }
                let now =
                    done.fetch_add(bits.len() / words, Ordering::Relaxed) + bits.len() / words;
                progress(now, n);
            },
        );
    map
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
        let map = compute(
            &mesh,
            &sphere,
            VisibilityOptions {
                grazing_margin: 0.0,
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
