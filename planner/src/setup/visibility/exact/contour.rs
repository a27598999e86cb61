//! The exact map from the occluders' contour (the default of `compute`).
//!
//! A direction `d` in front of the patch (`d·n > min_dot`) reaches it when
//! no occluder's cone holds it; the occluders are the triangles with a
//! corner in front of the patch's plane and a cone ([`Cone::new`]), as for
//! the rasteriser and the exact test. The number of cones holding `d` (its
//! **count**) changes only across the **contour**: the arcs of the
//! occluders' edges whose neighbour across is missing, is no occluder, or
//! lies on the same side of the edge seen from the patch (a silhouette).
//! Across any other edge one cone ends where the other begins. Per patch:
//!
//! 1. **Contour.** The edges are found through a hierarchy over the mesh's
//!    edges ([`ContourTree`]): a subtree behind the patch's plane holds no
//!    occluder, and one whose triangles are all occluders facing the patch
//!    the same way (bounded by a cone of normals and a sphere, with a
//!    margin that keeps the signs of the edge tests certain), with no
//!    border and no edge of inconsistent orientation, holds no contour;
//!    when the plane cuts such a subtree, only edges between an occluder
//!    and a triangle wholly behind with an end in front of the plane can
//!    be contour ([`Facing::Cut`]).
//!    Each contour arc (clipped to the front half) carries its weight: how
//!    many cones a path enters when it crosses it.
//! 2. **Boundary cells**: the cells the arcs cross. No arc meets any other
//!    cell, so over a run of such cells (joined across edges with a point
//!    in front) the count is one number; every cell starts open.
//! 3. **Counts.** One any-hit ray at a point of a run next to a boundary
//!    cell gives count 0 on their shared edge when the run is open; from
//!    there counts are carried across boundary cells by adding the weights
//!    of the arcs a path crosses. A boundary cell is open when some point of
//!    it has count 0: the point it was reached at, nine test points, or a
//!    point just off each piece of arc inside it on the side of fewer cones
//!    (a part of count 0 lies on that side of every piece around it). A run
//!    next to a point of positive count is closed by a flood.
//! 4. **The rest** — cells where a path passes within round-off of an arc's
//!    end or circle, cells no count reached and the runs next to them — are
//!    settled by rays, as the exact pass settles its candidates (a ray, the
//!    flood certificate, the nine points, then the gather and the exact
//!    cell test). A patch whose counts disagree (round-off) is mapped by
//!    the rasteriser and the exact pass instead.
//!
//! The map is that of the rasteriser followed by the exact pass (every cell
//! some direction of which reaches the patch); the test
//! `contour_map_equals_the_rasterised_exact_map` compares them bit for bit.
//! The cost is the contour, a few hundred edges on a fine part, instead of
//! every occluder in front.

use bvh::bvh::BvhNode;
use nalgebra::Vector3;

use super::{Curve, Exact, ExactScratch, NONE, PatchFrame, nine_point_witness};
use crate::mesh::TriMesh;
use crate::setup::visibility::{RayCaster, hits_triangle, is_open};

type V3 = Vector3<f64>;

/// Edges per leaf of [`ContourTree`].
const LEAF_EDGES: usize = 4;

/// One node of [`ContourTree`], bounding the triangles of its edges: one
/// cache line, read once per visit (the walk is bound by reading nodes).
/// Every bound is in `f32`, rounded the safe way, so it is looser than the
/// `f64` one by at most an `f32` step: the walk skips a subtree only when
/// that subtree has no contour whatever the rounding.
#[derive(Debug, Clone, Copy)]
#[repr(C, align(64))]
struct Node {
    /// Box of the corners (rounded outward).
    lo: [f32; 3],
    hi: [f32; 3],
    /// The axis `a` of the cone of the triangles' unit normals, rounded
    /// toward zero: its length `s` is at most 1 (and within an `f32` step
    /// of it), which keeps `n·a` no farther from 0 than `n·â` (`â = a/s`).
    axis: [f32; 3],
    /// The cone's half-angle `α` (widened for round-off) as `cos α / s`
    /// (rounded down) and `sin α / s` (rounded up), so that `(a·u)·cos_a`
    /// and `|a × u|·sin_a` bound `(â·u)·cos α` and `|â × u|·sin α`.
    /// `cos_a ≤ 0`: of no use for the facing test (`α ≥ 90°`, a
    /// degenerate triangle, or an edge without a neighbour run the
    /// opposite way: see [`Build::node`]).
    cos_a: f32,
    sin_a: f32,
    /// Least and most `a·(x − mid)/s²` over the corners (`= â·(x − mid)/s`,
    /// rounded outward; [`Node::mid`]), and their largest distance from
    /// the line along `â` through `mid` (rounded up).
    along: [f32; 2],
    across: f32,
    /// The largest distance of a corner from [`Node::mid`] (rounded up).
    /// The smallest twice-area of a triangle, needed only by nodes that
    /// pass the rest of the facing test, is kept apart
    /// ([`ContourTree::min_area2`]).
    radius: f32,
    /// The low [`LINK_BITS`] bits: an inner node (count 0) holds the index
    /// of the first node after its subtree (pre-order; its children are at
    /// `i + 1` and after that child's subtree); a leaf its first edge, of
    /// the count in the high bits ([`Node::edges`]), and the next node is
    /// `i + 1`.
    link: u32,
}

const _: () = assert!(std::mem::size_of::<Node>() == 64);

impl Node {
    /// A placeholder, overwritten by the build.
    const EMPTY: Self = Self {
        lo: [0.0; 3],
        hi: [0.0; 3],
        axis: [0.0; 3],
        cos_a: 0.0,
        sin_a: 0.0,
        along: [0.0; 2],
        across: 0.0,
        radius: 0.0,
        link: 0,
    };
}

/// Bits of [`Node::link`] that hold the index (the rest the leaf's count).
const LINK_BITS: u32 = 29;
const _: () = assert!(LEAF_EDGES < 1 << (32 - LINK_BITS));

/// `x` in `f32`, rounded up (toward +∞).
fn f32_above(x: f64) -> f32 {
    let f = x as f32;
    if f64::from(f) < x { f.next_up() } else { f }
}

/// `x` in `f32`, rounded down (toward −∞).
fn f32_below(x: f64) -> f32 {
    let f = x as f32;
    if f64::from(f) > x { f.next_down() } else { f }
}

/// `x` in `f32`, rounded toward zero.
fn f32_toward_zero(x: f64) -> f32 {
    if x >= 0.0 { f32_below(x) } else { f32_above(x) }
}

fn widen(v: &[f32; 3]) -> V3 {
    V3::new(f64::from(v[0]), f64::from(v[1]), f64::from(v[2]))
}

impl Node {
    fn lo(&self) -> V3 {
        widen(&self.lo)
    }

    fn hi(&self) -> V3 {
        widen(&self.hi)
    }

    fn axis(&self) -> V3 {
        widen(&self.axis)
    }

    /// The centre of the box (exact: a sum of two `f32` halved).
    fn mid(&self) -> V3 {
        (self.lo() + self.hi()) * 0.5
    }

    fn count(&self) -> usize {
        (self.link >> LINK_BITS) as usize
    }

    fn index(&self) -> usize {
        (self.link & ((1 << LINK_BITS) - 1)) as usize
    }

    /// The index of the first node after node `i`'s subtree.
    fn end(&self, i: usize) -> usize {
        if self.count() == 0 {
            self.index()
        } else {
            i + 1
        }
    }

    /// A leaf's edges (indices into [`ContourTree::edges`]).
    fn edges(&self) -> std::ops::Range<usize> {
        self.index()..self.index() + self.count()
    }
}

/// One undirected edge: triangle `t`, its edge `k` (corner `k` to `k + 1`),
/// the triangle across (`NONE` at a border) and that one's corner off the
/// edge.
#[derive(Debug, Clone, Copy)]
struct Edge {
    t: u32,
    t2: u32,
    /// The ends of the edge (corners `k`, `k + 1` of `t`), the third
    /// corner of `t` and that of `t2` (the first end when there is none),
    /// as indices into [`ContourTree::points`].
    corners: [u32; 4],
}

/// A bounding volume hierarchy over the mesh's edges, each bounding the
/// one or two triangles on it, stored in pre-order with skip links so that
/// the walk of [`Exact::mark_contour`] reads it front to back.
#[derive(Debug)]
pub(in crate::setup::visibility) struct ContourTree {
    nodes: Vec<Node>,
    /// Per node, the smallest twice-area of its triangles (rounded down).
    min_area2: Vec<f32>,
    edges: Vec<Edge>,
    /// The mesh's vertices (a compact copy the walk reads), in the order
    /// the edges name them ([`ContourTree::renumber_points`]).
    points: Vec<V3>,
}

/// Whether a subtree may hold a contour edge.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Facing {
    /// Some triangle may be an occluder facing the other way from another.
    Mixed,
    /// Every triangle is an occluder, all facing the patch one way.
    Uniform,
    /// Every triangle faces the patch one way with a cone, and the patch's
    /// plane cuts the subtree: the occluders are those with a corner in
    /// front, and the only contour edges are those between an occluder and
    /// a triangle wholly behind with an end just over the plane
    /// ([`Exact::mark_cut`]).
    Cut,
}

impl ContourTree {
    /// Builds the hierarchy over the edges of `mesh` (adjacency from
    /// `caster`): median splits of the edges' midpoints along the box's
    /// longest side, [`LEAF_EDGES`] edges per leaf. `None` for a mesh
    /// too large for [`Node::link`] (the map is then made without it).
    pub(in crate::setup::visibility) fn new(mesh: &TriMesh, caster: &RayCaster) -> Option<Self> {
        // At most three edges per triangle and fewer nodes than edges (a
        // leaf has two edges or more).
        if 3 * mesh.triangles.len() >= 1 << LINK_BITS {
            return None;
        }
        let mut edges = Vec::new();
        let mut plain = Vec::new();
        let mut mids = Vec::new();
        for (t, tri) in mesh.triangles.iter().enumerate() {
            for k in 0..3 {
                let (t2, corner) = caster.across(t, k);
                if t2 != NONE && (t2 as usize) < t {
                    continue;
                }
                let c = mesh.corners(t);
                let mid = (c[k].coords + c[(k + 1) % 3].coords) * 0.5;
                // Opposite directions along the shared edge.
                let consistent = t2 != NONE && {
                    let other = mesh.triangles[t2 as usize];
                    other[(corner + 1) % 3] == tri[(k + 1) % 3] && other[(corner + 2) % 3] == tri[k]
                };
                let far = if t2 == NONE {
                    tri[k]
                } else {
                    mesh.triangles[t2 as usize][corner]
                };
                edges.push(Edge {
                    t: t as u32,
                    t2,
                    corners: [tri[k], tri[(k + 1) % 3], tri[(k + 2) % 3], far],
                });
                plain.push(consistent);
                mids.push(mid);
            }
        }
        let mut order: Vec<u32> = (0..edges.len() as u32).collect();
        let mut tree = Self {
            nodes: Vec::new(),
            min_area2: Vec::new(),
            edges: Vec::new(),
            points: mesh.vertices.iter().map(|v| v.coords).collect(),
        };
        if !edges.is_empty() {
            // Each triangle's corners, normal and twice-area, read at every
            // level of the build.
            let triangles: Vec<Triangle> = (0..mesh.triangles.len())
                .map(|t| {
                    let c = mesh.corners(t).map(|c| c.coords);
                    Triangle {
                        corners: c,
                        normal: mesh.normals[t],
                        area2: (c[1] - c[0]).cross(&(c[2] - c[0])).norm(),
                    }
                })
                .collect();
            let ctx = Build {
                triangles: &triangles,
                edges: &edges,
                plain: &plain,
                mids: &mids,
            };
            // Every subtree's size follows from its number of edges, so the
            // halves are built side by side into their own parts of the
            // arrays, as the serial pre-order build would lay them out.
            tree.nodes = vec![Node::EMPTY; subtree_nodes(edges.len())];
            tree.min_area2 = vec![0.0; tree.nodes.len()];
            tree.edges = vec![edges[0]; edges.len()];
            let out = Out {
                nodes: &mut tree.nodes,
                min_area2: &mut tree.min_area2,
                edges: &mut tree.edges,
            };
            ctx.fill(&mut order, out, 0, 0);
            tree.renumber_points();
        }
        Some(tree)
    }
}

impl ContourTree {
    /// Numbers the points in the order the leaves' edges first name them,
    /// so that the edges of nearby leaves read nearby points.
    fn renumber_points(&mut self) {
        let mut new = vec![NONE; self.points.len()];
        let mut points = Vec::with_capacity(self.points.len());
        for e in &mut self.edges {
            for v in &mut e.corners {
                let old = *v as usize;
                if new[old] == NONE {
                    new[old] = points.len() as u32;
                    points.push(self.points[old]);
                }
                *v = new[old];
            }
        }
        self.points = points;
    }
}

/// The parts of [`ContourTree`]'s arrays a subtree is written to.
struct Out<'a> {
    nodes: &'a mut [Node],
    min_area2: &'a mut [f32],
    edges: &'a mut [Edge],
}

/// A triangle as building [`ContourTree`] reads it.
struct Triangle {
    corners: [V3; 3],
    normal: V3,
    /// Twice its area.
    area2: f64,
}

/// What building [`ContourTree`] reads.
struct Build<'a> {
    triangles: &'a [Triangle],
    edges: &'a [Edge],
    plain: &'a [bool],
    mids: &'a [V3],
}

impl Build<'_> {
    /// The triangles of edge `e`.
    fn triangles(&self, e: u32) -> impl Iterator<Item = usize> + '_ {
        let e = self.edges[e as usize];
        std::iter::once(e.t as usize).chain((e.t2 != NONE).then_some(e.t2 as usize))
    }

    /// Writes the subtree over `set` (pre-order) into `out`: its nodes
    /// (exactly [`subtree_nodes`] of `set.len()`, the first at index
    /// `first_node` of the tree) and its leaves' edges (`set.len()`, the
    /// first at `first_edge`).
    fn fill(&self, set: &mut [u32], out: Out<'_>, first_node: usize, first_edge: usize) {
        /// Below this many edges a subtree is built on one thread.
        const PARALLEL_EDGES: usize = 4096;
        let Out {
            nodes,
            min_area2,
            edges,
        } = out;
        let (node, area2, extent) = self.bound(set);
        nodes[0] = node;
        min_area2[0] = area2;
        if set.len() <= LEAF_EDGES {
            nodes[0].link = first_edge as u32 | (set.len() as u32) << LINK_BITS;
            for (slot, &e) in edges.iter_mut().zip(set.iter()) {
                *slot = self.edges[e as usize];
            }
            return;
        }
        nodes[0].link = (first_node + nodes.len()) as u32;
        // Median split of the midpoints along the box's longest side.
        let axis = extent.imax();
        let (len, half) = (set.len(), set.len() / 2);
        set.select_nth_unstable_by(half, |&a, &b| {
            self.mids[a as usize][axis].total_cmp(&self.mids[b as usize][axis])
        });
        let (left, right) = set.split_at_mut(half);
        let (left_nodes, right_nodes) = nodes[1..].split_at_mut(subtree_nodes(half));
        let (left_areas, right_areas) = min_area2[1..].split_at_mut(left_nodes.len());
        let (left_edges, right_edges) = edges.split_at_mut(half);
        let right_first = first_node + 1 + left_nodes.len();
        let left_out = Out {
            nodes: left_nodes,
            min_area2: left_areas,
            edges: left_edges,
        };
        let right_out = Out {
            nodes: right_nodes,
            min_area2: right_areas,
            edges: right_edges,
        };
        let build_left = move || self.fill(left, left_out, first_node + 1, first_edge);
        let build_right = move || self.fill(right, right_out, right_first, first_edge + half);
        if len >= PARALLEL_EDGES {
            rayon::join(build_left, build_right);
        } else {
            build_left();
            build_right();
        }
    }

    /// The bounds of the triangles of the edges `set`: the node over them
    /// (its link not set), their least twice-area (rounded down) and the
    /// extent of their box (unrounded).
    fn bound(&self, set: &[u32]) -> (Node, f32, V3) {
        let tri = self.triangles;
        let (mut lo, mut hi) = (V3::repeat(f64::INFINITY), V3::repeat(f64::NEG_INFINITY));
        let mut sum = V3::zeros();
        let mut min_area2 = f64::INFINITY;
        let mut plain = true;
        for &e in set.iter() {
            plain &= self.plain[e as usize];
            for t in self.triangles(e) {
                for c in &tri[t].corners {
                    lo = lo.inf(c);
                    hi = hi.sup(c);
                }
                sum += tri[t].normal;
                min_area2 = min_area2.min(tri[t].area2);
            }
        }
        // The box in f32, and its centre as the walk takes it.
        let (lo32, hi32) = (lo.map(f32_below), hi.map(f32_above));
        let mid = (lo32.map(f64::from) + hi32.map(f64::from)) * 0.5;
        // The cone's axis rounded toward zero, no longer than 1, and the
        // unit `â` along it that the bounds below refer to.
        let (axis, unit, s, cos_a, sin_a) = if sum.norm() < 1e-9 {
            ([0.0, 0.0, 1.0], V3::z(), 1.0, -1.0, 0.0)
        } else {
            let mut axis = sum.normalize();
            let (a, s) = loop {
                let a = axis.map(f32_toward_zero);
                let s = a.map(f64::from).norm();
                if s <= 1.0 {
                    break (a, s);
                }
                axis *= 1.0 - f64::from(f32::EPSILON);
            };
            let unit = a.map(f64::from) / s;
            let mut cos_a: f64 = 1.0;
            for &e in set.iter() {
                for t in self.triangles(e) {
                    cos_a = cos_a.min(unit.dot(&tri[t].normal));
                }
            }
            // Widened a little for round-off.
            let half = cos_a.clamp(-1.0, 1.0).acos() + 1e-12;
            ([a.x, a.y, a.z], unit, s, half.cos(), half.sin())
        };
        let a = widen(&axis);
        let (mut below, mut above, mut across) = (f64::INFINITY, f64::NEG_INFINITY, 0.0f64);
        let mut radius = 0.0f64;
        for &e in set.iter() {
            for t in self.triangles(e) {
                for c in &tri[t].corners {
                    let off = c - mid;
                    let h = a.dot(&off) / (s * s);
                    below = below.min(h);
                    above = above.max(h);
                    // Squared: the root of the largest is the largest root.
                    across = across.max((off - unit * unit.dot(&off)).norm_squared());
                    radius = radius.max(off.norm_squared());
                }
            }
        }
        // Of no use for the facing test: see `Node::cos_a`.
        let cos_a = if plain && min_area2 > 0.0 && cos_a > 0.0 {
            f32_below(cos_a / s)
        } else {
            -1.0
        };
        let node = Node {
            lo: [lo32.x, lo32.y, lo32.z],
            hi: [hi32.x, hi32.y, hi32.z],
            axis,
            cos_a,
            sin_a: f32_above(sin_a / s),
            along: [f32_below(below), f32_above(above)],
            across: f32_above(across.sqrt()),
            radius: f32_above(radius.sqrt()),
            link: 0,
        };
        (node, f32_below(min_area2), hi - lo)
    }
}

/// The number of nodes of a subtree over `edges` edges (median splits,
/// [`LEAF_EDGES`] per leaf).
fn subtree_nodes(edges: usize) -> usize {
    if edges <= LEAF_EDGES {
        1
    } else {
        1 + subtree_nodes(edges / 2) + subtree_nodes(edges - edges / 2)
    }
}

impl ContourTree {
    /// Bounds (least, most) of `n·x` over the corners of node `b` from its
    /// box: looser than [`ContourTree::axis_beyond`] on a curved piece of
    /// surface, but cheap enough to try first. The walk takes the tighter
    /// of the two on each side, the box's alone when it already decides.
    fn box_heights(b: &Node, n: &V3) -> (f64, f64) {
        let (mut box_lo, mut box_hi) = (0.0, 0.0);
        for k in 0..3 {
            let (lo, hi) = (n[k] * f64::from(b.lo[k]), n[k] * f64::from(b.hi[k]));
            box_lo += lo.min(hi);
            box_hi += lo.max(hi);
        }
        (box_lo, box_hi)
    }

    /// Bounds (least, most) of `n·x` over the corners of node `b` from
    /// their extent along the axis of the normals (much tighter than the
    /// box for a curved piece of surface). The walk decides with
    /// [`ContourTree::axis_beyond`], without its root; this form is the
    /// tests' reference.
    #[cfg(test)]
    fn axis_heights(b: &Node, n: &V3) -> (f64, f64) {
        // n = (n·â)·â + perp: n·x = n·mid + (n·â)·(â·(x − mid)) +
        // perp·(x − mid), the last within |perp|·across. With the stored
        // `a = s·â`, (n·a)·along = (n·â)·(â·(x − mid)) exactly, and
        // |perp| = √(1 − (n·â)²) ≤ √(1 − (n·a)²) as s ≤ 1.
        let na = n.dot(&b.axis());
        let base = n.dot(&b.mid());
        let spread = (1.0 - na * na).max(0.0).sqrt() * f64::from(b.across);
        let [lo, hi] = b.along.map(f64::from);
        let (h_far, h_near) = if na >= 0.0 { (hi, lo) } else { (lo, hi) };
        (na * h_near + base - spread, na * h_far + base + spread)
    }

    /// Whether [`ContourTree::axis_heights`] puts node `b` behind `lo`
    /// (most `n·x` at or below it) and whether past `hi` (least `n·x`
    /// above it), decided without the root of `1 − (n·a)²`: the spread
    /// across the axis is compared with the room the rest leaves, squared.
    #[inline(always)]
    fn axis_beyond(b: &Node, n: &V3, lo: f64, hi: f64) -> (bool, bool) {
        let na = n.dot(&b.axis());
        let base = n.dot(&b.mid());
        let across = f64::from(b.across);
        let spread2 = (1.0 - na * na).max(0.0) * (across * across);
        let [low, high] = b.along.map(f64::from);
        let (h_far, h_near) = if na >= 0.0 { (high, low) } else { (low, high) };
        let room_far = lo - (na * h_far + base);
        let room_near = (na * h_near + base) - hi;
        (
            room_far >= 0.0 && spread2 <= room_far * room_far,
            room_near > 0.0 && spread2 < room_near * room_near,
        )
    }

    /// Whether every triangle of node `i` faces the patch the same way,
    /// with a margin that keeps the edge tests' signs and [`Cone::new`]
    /// certain, and whether all are occluders; `None` when the node lies
    /// behind the plane.
    #[cfg(test)]
    fn facing(&self, i: usize, p: &PatchFrame, level: f64, t_min: f64) -> Option<Facing> {
        self.facing_within(i, p, level, t_min, false).map(|f| f.0)
    }

    /// [`ContourTree::facing`], and whether every corner of node `i` lies
    /// in front of the plane (past `level` by the slack); `in_front`: that
    /// is known already (of an ancestor, so of every corner of this node),
    /// and the node's own bounds are not taken.
    #[inline(always)]
    fn facing_within(
        &self,
        i: usize,
        p: &PatchFrame,
        level: f64,
        t_min: f64,
        in_front: bool,
    ) -> Option<(Facing, bool)> {
        let b = &self.nodes[i];
        let in_front = in_front || {
            // The box first: most nodes it puts behind the plane need no
            // more.
            let (box_near, box_far) = Self::box_heights(b, p.normal);
            let (lo, hi) = (level - Self::slack(t_min), level + Self::slack(t_min));
            if box_far <= lo {
                return None;
            }
            let (behind, ahead) = Self::axis_beyond(b, p.normal, lo, hi);
            if behind {
                return None;
            }
            box_near > hi || ahead
        };
        if b.cos_a <= 0.0 {
            return Some((Facing::Mixed, in_front));
        }
        let mid = b.mid();
        let u = p.origin.coords - mid;
        // Each triangle's n̂·(o − x) = n̂·u − n̂·(x − mid): n̂·u is at least
        // |u|·cos(β + α) (β the angle from the cone's axis to u; positive
        // only when β + α < 90°), and n̂·(x − mid) at most the corners' reach
        // along the axis past mid plus sin α times their distance from it
        // (n̂ = cos θ·â + sin θ·e, θ ≤ α), or the radius. The opposite
        // for triangles facing away. |u|·cos β and |u|·sin β are taken
        // as `a·u` and `|a × u|` (no division, no cancellation), s times
        // them, which the stored `cos_a`, `sin_a` (over s) make up for;
        // the stored reach along the axis is over s too (only larger).
        let (axis, cos_a, sin_a) = (b.axis(), f64::from(b.cos_a), f64::from(b.sin_a));
        let radius = f64::from(b.radius);
        let side = sin_a * f64::from(b.across);
        let [below, above] = b.along.map(f64::from);
        let up = radius.min(above.max(0.0) + side);
        let down = radius.min((-below).max(0.0) + side);
        // front = toward − |a × u|·sin_a − up and back = −toward − |a × u|·
        // sin_a − down; front > x when toward − up − x exceeds the term
        // across the axis, compared squared (no roots).
        let toward = axis.dot(&u) * cos_a;
        let (front_room, back_room) = (toward - up, -toward - down);
        // The margin below is at least 2·t_min: a node short of that needs
        // no more, and those short of it without the term across the axis
        // need not even take it.
        if front_room <= 2.0 * t_min && back_room <= 2.0 * t_min {
            return Some((Facing::Mixed, in_front));
        }
        let across2 = axis.cross(&u).norm_squared() * (sin_a * sin_a);
        let beyond = |x: f64| {
            let (f, b) = (front_room - x, back_room - x);
            (f > 0.0 && across2 < f * f) || (b > 0.0 && across2 < b * b)
        };
        if !beyond(2.0 * t_min) {
            return Some((Facing::Mixed, in_front));
        }
        // The edge tests' products and the cone's distance test carry
        // round-off of about ε·|corner − o|³; each triangle's n̂·(o − x) times
        // its twice-area must stay well above it. |u| is taken as the sum
        // of its coordinates' sizes (no smaller, no root).
        let reach = u.abs().sum() + radius;
        let margin = 2.0 * t_min
            + 64.0 * f64::EPSILON * reach * reach * reach / f64::from(self.min_area2[i]);
        if beyond(margin) {
            // Every triangle has a cone; those with a corner in front are
            // the occluders.
            if in_front {
                Some((Facing::Uniform, true))
            } else {
                Some((Facing::Cut, false))
            }
        } else {
            Some((Facing::Mixed, in_front))
        }
    }

    /// Well above the round-off of `n·x`, well below `t_min`.
    fn slack(t_min: f64) -> f64 {
        t_min * 1e-3
    }
}

impl RayCaster {
    /// An occluder of the patch (see the module doc) that the ray
    /// `origin + t·dir`, `t > t_min`, meets, if any; `occluder(t)` says
    /// whether triangle `t` is one. Boxes behind the patch's plane hold
    /// none and are not entered.
    fn first_occluder(
        &self,
        p: &PatchFrame,
        dir: &V3,
        mut occluder: impl FnMut(usize) -> bool,
        stack: &mut Vec<usize>,
    ) -> Option<usize> {
        if self.bvh.nodes.is_empty() {
            return None;
        }
        let (origin, n) = (p.origin, p.normal);
        let level = n.dot(&origin.coords) + self.t_min;
        let inv = dir.map(|c| 1.0 / c);
        let enter = |b: &bvh::aabb::Aabb<f64, 3>| {
            let mut far = 0.0;
            for k in 0..3 {
                far += n[k] * if n[k] > 0.0 { b.max[k] } else { b.min[k] };
            }
            far > level && super::super::hits_box(origin, dir, &inv, b)
        };
        stack.clear();
        stack.push(0);
        while let Some(index) = stack.pop() {
            match &self.bvh.nodes[index] {
                BvhNode::Leaf { shape_index, .. } => {
                    let t = *shape_index;
                    if hits_triangle(origin, dir, &self.shapes[t].corners, self.t_min)
                        && occluder(t)
                    {
                        return Some(t);
                    }
                }
                BvhNode::Node {
                    child_l_index,
                    child_l_aabb,
                    child_r_index,
                    child_r_aabb,
                    ..
                } => {
                    if enter(child_l_aabb) {
                        stack.push(*child_l_index);
                    }
                    if enter(child_r_aabb) {
                        stack.push(*child_r_index);
                    }
                }
            }
        }
        None
    }
}

impl ExactScratch {
    /// Whether triangle `t` is an occluder of the patch: not the patch,
    /// a corner in front of its plane, and a cone. Computed once per patch.
    fn occluder(&mut self, caster: &RayCaster, p: &PatchFrame, level: f64, t: usize) -> bool {
        let (stamp, yes) = self.occ[t];
        if stamp == self.generation {
            return yes;
        }
        let tri = &caster.shapes[t].corners;
        let yes = t != p.skip
            && tri.iter().any(|c| p.normal.dot(&c.coords) > level)
            && super::blocks(p.origin, tri, caster.t_min);
        self.occ[t] = (self.generation, yes);
        yes
    }
}

/// The point of the great-circle arc from `u` to `v` (unit, less than π
/// apart) with the largest `d·n`, and that value.
fn arc_max_dot(u: &V3, v: &V3, n: &V3) -> (f64, V3) {
    let mut best = if u.dot(n) >= v.dot(n) {
        (u.dot(n), *u)
    } else {
        (v.dot(n), *v)
    };
    let m = u.cross(v);
    let norm = m.norm();
    if norm > 0.0 {
        let e = m / norm;
        let q = n - e * e.dot(n);
        let len = q.norm();
        if len > 0.0 {
            let x = q / len;
            if u.cross(&x).dot(&e) >= 0.0 && x.cross(v).dot(&e) >= 0.0 && x.dot(n) > best.0 {
                best = (x.dot(n), x);
            }
        }
    }
    best
}

/// Whether some point of the arc from `u` to `v` (as [`arc_max_dot`]) has
/// `d·n > level`: an end that does answers without the arc's top.
fn arc_rises_above(u: &V3, v: &V3, n: &V3, level: f64) -> bool {
    u.dot(n) > level || v.dot(n) > level || arc_max_dot(u, v, n).0 > level
}

/// Sign tests closer to zero than this (on unit vectors) are not trusted:
/// the count is then not propagated through the cell.
const SIDE_TOL: f64 = 1e-12;

/// One contour arc seen from the patch: its ends (clipped to the front
/// half), the unit normal of its great circle, and how many cones a path
/// enters when it crosses from `d·m < 0` to `d·m > 0`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Arc {
    u: V3,
    v: V3,
    m: V3,
    weight: i32,
}

/// What crossing a set of arcs along a path does to the count.
enum Crossing {
    /// The count changes by this much.
    By(i32),
    /// Too close to an arc's end or circle to tell.
    Unsure,
}

/// The count change from `r` to `x` (a short path) across the arcs `ids`
/// of `arcs`.
fn crossings(r: &V3, x: &V3, ids: &[u32], arcs: &[Arc]) -> Crossing {
    let path = r.cross(x);
    let len = path.norm();
    if len == 0.0 {
        return Crossing::By(0);
    }
    let path = path / len;
    let mut delta = 0;
    for &id in ids {
        let a = &arcs[id as usize];
        let (sr, sx) = (a.m.dot(r), a.m.dot(x));
        // An end of the path on the arc's circle: no crossing when that end
        // is clearly off the arc itself.
        let beside =
            |q: &V3| a.u.cross(q).dot(&a.m) < -SIDE_TOL || q.cross(&a.v).dot(&a.m) < -SIDE_TOL;
        if sr.abs() < SIDE_TOL || sx.abs() < SIDE_TOL {
            let clear = (sr.abs() >= SIDE_TOL || beside(r)) && (sx.abs() >= SIDE_TOL || beside(x));
            if clear {
                continue;
            }
            return Crossing::Unsure;
        }
        if (sr > 0.0) == (sx > 0.0) {
            continue;
        }
        let (su, sv) = (path.dot(&a.u), path.dot(&a.v));
        if su.abs() < SIDE_TOL || sv.abs() < SIDE_TOL {
            return Crossing::Unsure;
        }
        if (su > 0.0) == (sv > 0.0) {
            continue;
        }
        // The two circles meet at ±q: the crossing counts when it is the
        // point on both short arcs.
        let q = path.cross(&a.m);
        let (qa, qb) = (q.dot(&(a.u + a.v)), q.dot(&(r + x)));
        if qa.abs() < SIDE_TOL || qb.abs() < SIDE_TOL {
            return Crossing::Unsure;
        }
        if (qa > 0.0) == (qb > 0.0) {
            delta += if sr < 0.0 { a.weight } else { -a.weight };
        }
    }
    Crossing::By(delta)
}

/// The state of a boundary cell in the count propagation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Settled {
    /// Not reached yet.
    No,
    /// Holds a point of known count (`ExactScratch::refs`), queued.
    Reached,
    /// Decided (open or closed).
    Done,
    /// The count could not be followed through it: settled by rays.
    Rays,
}

impl Exact<'_> {
    /// The row of the patch `p` by the contour method (module doc): `row`
    /// holds on entry the cells whose centre is in front (`d·n >
    /// min_dot`), `w.band` the cells within a cell radius behind the
    /// horizon; on return the cells some direction of which reaches the
    /// patch. Returns how many were decided by a direction other than their
    /// centre (listed in `w.witnesses`), or `None` when the counts met
    /// disagree (round-off): the caller then maps the patch the other way.
    pub(in crate::setup::visibility) fn by_contour(
        &self,
        tree: &ContourTree,
        p: &PatchFrame,
        row: &mut [u64],
        w: &mut ExactScratch,
    ) -> Option<u32> {
        let caster = self.caster;
        let n = p.normal;
        let level = n.dot(&p.origin.coords) + caster.t_min;
        // Cells with a part in front: centres in front (`front`), and cells
        // across the horizon with their highest point (`band_at`).
        w.front.clear();
        w.front.extend_from_slice(row);
        w.band_at.clear();
        for k in 0..w.band.len() {
            let c = w.band[k];
            // A point of the cell in front: a corner, or (when the horizon
            // cuts an edge twice) the highest point.
            let corners = &self.cells.corners[c as usize];
            let at = match corners.iter().find(|x| x.dot(n) > p.min_dot) {
                Some(x) => Some(*x),
                None => {
                    let (top, at) = self.cells.max_dot(c as usize, n);
                    (top > p.min_dot).then_some(at)
                }
            };
            if let Some(at) = at {
                w.band_at.push((c, at));
                row[c as usize / 64] |= 1 << (c % 64);
            }
        }
        // 1–2. The contour, and the boundary cells it crosses.
        w.arcs.clear();
        w.arc_of.clear();
        self.mark_contour(tree, p, level, w);
        let mut added = 0;
        if !w.list.iter().any(|&c| self.has_part(c as usize, w)) {
            // No contour in front (the arcs, if any, lie between the plane
            // and the grazing margin): one count everywhere.
            let seed = (0..row.len()).find(|&k| row[k] != 0);
            if let Some(k) = seed {
                let c = k * 64 + row[k].trailing_zeros() as usize;
                let x = self.part_point(c, w);
                if self.reaches(p, level, &x, w) {
                    for k in 0..w.band_at.len() {
                        let c = w.band_at[k].0;
                        self.witness_top(c as usize, p, w);
                        added += 1;
                    }
                } else {
                    row.iter_mut().for_each(|x| *x = 0);
                }
            }
            return Some(added);
        }
        w.arc_of.sort_unstable();
        w.arc_of.dedup();
        // Every cell with a part in front starts open; the boundary cells
        // are decided one by one, the runs of the others that the counts
        // show covered are closed by a flood.
        let words = row.len();
        w.todo.clear();
        w.todo.resize(words, 0);
        w.known_open.clear();
        w.known_open.resize(words, 0);
        for k in 0..w.list.len() {
            let c = w.list[k] as usize;
            row[c / 64] &= !(1 << (c % 64));
            w.settled[c] = (w.generation, Settled::No);
        }
        w.queue.clear();
        w.pending.clear();
        w.unsure.clear();
        for k in 0..w.list.len() {
            let b = w.list[k] as usize;
            if self.settled(b, w) != Settled::No || !self.has_part(b, w) {
                continue;
            }
            // A seed: a point of known count on an edge shared with a cell
            // of a run, found by one ray into that run.
            let corners = self.cells.corners[b];
            for (j, &c) in self.sphere.across(b).iter().enumerate() {
                let c = c as usize;
                if is_open(&w.candidate, c) || !self.has_part(c, w) || is_open(&w.todo, c) {
                    continue;
                }
                let (top, q) = arc_max_dot(&corners[(j + 1) % 3], &corners[(j + 2) % 3], n);
                if top <= p.min_dot {
                    continue;
                }
                let x = self.part_point(c, w);
                if self.reaches(p, level, &x, w) {
                    w.known_open[c / 64] |= 1 << (c % 64);
                    self.reach(b, q, 0, w);
                    break;
                }
                if !self.flood_closed(c, p, row, w) {
                    return None;
                }
            }
            while let Some(b) = w.queue.pop() {
                added += self.visit(b as usize, p, row, w)?;
            }
        }
        // Cells of runs no count reached: by a ray each, with their run.
        for k in 0..w.unsure.len() {
            let c = w.unsure[k] as usize;
            if is_open(&w.todo, c) || is_open(&w.known_open, c) {
                continue;
            }
            if !self.settle_by_ray(c, p, level, row, w) {
                return None;
            }
        }
        // The cells the counts did not reach: by rays, and so are the runs
        // next to them.
        for k in 0..w.list.len() {
            let b = w.list[k] as usize;
            let s = self.settled(b, w);
            if !(s == Settled::No || s == Settled::Rays) || !self.has_part(b, w) {
                continue;
            }
            w.pending.push(b as u32);
            let corners = self.cells.corners[b];
            for (j, &c) in self.sphere.across(b).iter().enumerate() {
                let c = c as usize;
                if is_open(&w.candidate, c)
                    || !self.has_part(c, w)
                    || is_open(&w.todo, c)
                    || is_open(&w.known_open, c)
                {
                    continue;
                }
                if !arc_rises_above(&corners[(j + 1) % 3], &corners[(j + 2) % 3], n, p.min_dot) {
                    continue;
                }
                if !self.settle_by_ray(c, p, level, row, w) {
                    return None;
                }
            }
        }
        w.by_rays = w.pending.len();
        added += self.settle(p, level, row, w);
        added += self.decide(p, row, w);
        // The cells across the horizon left open are shown by their highest
        // point.
        for k in 0..w.band_at.len() {
            let c = w.band_at[k].0 as usize;
            if is_open(row, c) && !is_open(&w.candidate, c) {
                self.witness_top(c, p, w);
                added += 1;
            }
        }
        Some(added)
    }

    /// Lists the highest point of band cell `c` as its witness, when the
    /// witnesses are kept (the tests').
    fn witness_top(&self, c: usize, p: &PatchFrame, w: &mut ExactScratch) {
        if w.keep_witnesses {
            let (_, at) = self.cells.max_dot(c, p.normal);
            w.witnesses.push((c as u32, at));
        }
    }

    /// Whether cell `c` has a part in front of the patch.
    fn has_part(&self, c: usize, w: &ExactScratch) -> bool {
        is_open(&w.front, c) || w.band_at.binary_search_by_key(&(c as u32), |e| e.0).is_ok()
    }

    /// A point of cell `c` in front: its centre, or the highest point of a
    /// cell across the horizon.
    fn part_point(&self, c: usize, w: &ExactScratch) -> V3 {
        if is_open(&w.front, c) {
            return self.cells.dirs[c];
        }
        match w.band_at.binary_search_by_key(&(c as u32), |e| e.0) {
            Ok(k) => w.band_at[k].1,
            Err(_) => self.cells.dirs[c],
        }
    }

    fn settled(&self, b: usize, w: &ExactScratch) -> Settled {
        let (g, s) = w.settled[b];
        if g == w.generation { s } else { Settled::No }
    }

    /// Gives boundary cell `b` the point `r` of count `count` and queues it.
    fn reach(&self, b: usize, r: V3, count: i32, w: &mut ExactScratch) {
        w.settled[b] = (w.generation, Settled::Reached);
        w.refs[b] = (r, count);
        w.queue.push(b as u32);
    }

    /// The arcs crossing boundary cell `b` (indices into `w.arcs`).
    fn arcs_of(b: usize, w: &ExactScratch) -> std::ops::Range<usize> {
        let b = b as u32;
        let lo = w.arc_of.partition_point(|e| e.0 < b);
        let hi = w.arc_of.partition_point(|e| e.0 <= b);
        lo..hi
    }

    /// Settles cell `c` by one ray to its point: open if it reaches the
    /// patch, else its run is closed by a flood; false when the flood meets
    /// a cell known open (round-off).
    fn settle_by_ray(
        &self,
        c: usize,
        p: &PatchFrame,
        level: f64,
        row: &mut [u64],
        w: &mut ExactScratch,
    ) -> bool {
        let x = self.part_point(c, w);
        if self.reaches(p, level, &x, w) {
            w.known_open[c / 64] |= 1 << (c % 64);
            true
        } else {
            self.flood_closed(c, p, row, w)
        }
    }

    /// Closes the run of non-boundary cells from `c` (covered: its count is
    /// positive); false when it meets a cell known open (round-off).
    fn flood_closed(
        &self,
        c: usize,
        p: &PatchFrame,
        row: &mut [u64],
        w: &mut ExactScratch,
    ) -> bool {
        let n = p.normal;
        w.todo[c / 64] |= 1 << (c % 64);
        w.dfs.clear();
        w.dfs.push(c as u32);
        while let Some(c) = w.dfs.pop() {
            let c = c as usize;
            if is_open(&w.known_open, c) {
                return false;
            }
            row[c / 64] &= !(1 << (c % 64));
            let front_c = is_open(&w.front, c);
            let corners = self.cells.corners[c];
            for (k, &nb) in self.sphere.across(c).iter().enumerate() {
                let nb = nb as usize;
                if is_open(&w.todo, nb) || is_open(&w.candidate, nb) || !self.has_part(nb, w) {
                    continue;
                }
                // Joined when the shared edge has a point in front.
                let joined = (front_c && is_open(&w.front, nb))
                    || arc_rises_above(&corners[(k + 1) % 3], &corners[(k + 2) % 3], n, p.min_dot);
                if joined {
                    w.todo[nb / 64] |= 1 << (nb % 64);
                    w.dfs.push(nb as u32);
                }
            }
        }
        true
    }

    /// A point of the edge of `b` opposite corner `j`, in front and off
    /// every arc of `b` (`ids`), if one of a few tried is.
    fn edge_point(
        &self,
        b: usize,
        j: usize,
        ids: &[u32],
        p: &PatchFrame,
        w: &ExactScratch,
    ) -> Option<V3> {
        let corners = self.cells.corners[b];
        let (e1, e2) = (corners[(j + 1) % 3], corners[(j + 2) % 3]);
        // The highest point of the edge, and points between it and the
        // ends, and the ends' middle.
        let (top, high) = arc_max_dot(&e1, &e2, p.normal);
        if top <= p.min_dot {
            return None;
        }
        let between = |a: &V3, f: f64| (high * (1.0 - f) + a * f).normalize();
        let tries = [
            (e1 + e2).normalize(),
            high,
            between(&e1, 0.5),
            between(&e2, 0.5),
            between(&e1, 0.25),
            between(&e2, 0.25),
        ];
        for q in tries {
            if q.dot(p.normal) <= p.min_dot {
                continue;
            }
            let clear = ids.iter().all(|&a| {
                let a = &w.arcs[a as usize];
                a.m.dot(&q).abs() >= SIDE_TOL
                    || a.u.cross(&q).dot(&a.m) < -SIDE_TOL
                    || q.cross(&a.v).dot(&a.m) < -SIDE_TOL
            });
            if clear {
                return Some(q);
            }
        }
        None
    }

    /// Decides boundary cell `b` from its point of known count, and passes
    /// counts on to the cells around it; returns how many it opened (0 or
    /// 1), or `None` when counts disagree.
    fn visit(
        &self,
        b: usize,
        p: &PatchFrame,
        row: &mut [u64],
        w: &mut ExactScratch,
    ) -> Option<u32> {
        let (r, count) = w.refs[b];
        let range = Self::arcs_of(b, w);
        let mut ids = std::mem::take(&mut w.ids);
        ids.clear();
        ids.extend(w.arc_of[range].iter().map(|e| e.1));
        let verdict = self.visit_with(b, r, count, &ids, p, row, w);
        w.ids = ids;
        verdict
    }

    /// [`Exact::visit`] with the arcs `ids` of `b`.
    #[allow(clippy::too_many_arguments)]
    fn visit_with(
        &self,
        b: usize,
        r: V3,
        count: i32,
        ids: &[u32],
        p: &PatchFrame,
        row: &mut [u64],
        w: &mut ExactScratch,
    ) -> Option<u32> {
        let count_at = |x: &V3, w: &ExactScratch| match crossings(&r, x, ids, &w.arcs) {
            Crossing::By(d) => Some(count + d),
            Crossing::Unsure => None,
        };
        let total: i32 = ids.iter().map(|&a| w.arcs[a as usize].weight.abs()).sum();
        // Decide.
        let verdict = if count == 0 {
            Some(Some(r))
        } else if count > total {
            Some(None)
        } else {
            self.lowest(b, p, ids, &count_at, w)
        };
        let mut opened = 0;
        w.counted += usize::from(verdict.is_some());
        match verdict {
            Some(Some(x)) => {
                row[b / 64] |= 1 << (b % 64);
                w.witnesses.push((b as u32, x));
                opened = 1;
                w.settled[b] = (w.generation, Settled::Done);
            }
            Some(None) => w.settled[b] = (w.generation, Settled::Done),
            None => {
                w.settled[b] = (w.generation, Settled::Rays);
                return Some(0);
            }
        }
        // Pass the count on.
        let corners = self.cells.corners[b];
        for (j, &c) in self.sphere.across(b).iter().enumerate() {
            let c = c as usize;
            if !self.has_part(c, w) {
                continue;
            }
            let boundary = is_open(&w.candidate, c);
            if boundary && self.settled(c, w) != Settled::No {
                continue;
            }
            if !boundary
                && !arc_rises_above(
                    &corners[(j + 1) % 3],
                    &corners[(j + 2) % 3],
                    p.normal,
                    p.min_dot,
                )
            {
                continue;
            }
            let Some(k) = self
                .edge_point(b, j, ids, p, w)
                .and_then(|q| Some((q, count_at(&q, w)?)))
            else {
                // No count to pass on: a ray decides that cell later.
                if !boundary {
                    w.unsure.push(c as u32);
                }
                continue;
            };
            let (q, k) = k;
            if boundary {
                self.reach(c, q, k, w);
            } else if k > 0 {
                if !is_open(&w.todo, c) && !self.flood_closed(c, p, row, w) {
                    return None;
                }
            } else if is_open(&w.todo, c) {
                return None;
            } else {
                w.known_open[c / 64] |= 1 << (c % 64);
            }
        }
        Some(opened)
    }

    /// Whether some point of boundary cell `b` has count 0: `Some(Some(x))`
    /// with such a point, `Some(None)` when every part of the cell is
    /// covered, `None` when round-off leaves it open to doubt. A part of
    /// count 0 lies on the side of lower count of every arc piece around
    /// it, so a point just off each piece on that side is tried (after the
    /// nine points of the exact test).
    fn lowest(
        &self,
        b: usize,
        p: &PatchFrame,
        ids: &[u32],
        count_at: &dyn Fn(&V3, &ExactScratch) -> Option<i32>,
        w: &mut ExactScratch,
    ) -> Option<Option<V3>> {
        let n = p.normal;
        let corners = self.cells.corners[b];
        let centre = self.cells.dirs[b];
        for k in 0..3 {
            let (a, c) = (corners[k], corners[(k + 1) % 3]);
            for x in [a, (a + c).normalize(), (a + centre).normalize()] {
                if x.dot(n) > p.min_dot && count_at(&x, w)? == 0 {
                    return Some(Some(x));
                }
            }
        }
        let edges = self.cells.edges[b];
        for (i, &id) in ids.iter().enumerate() {
            let a = w.arcs[id as usize];
            let Some(curve) = Curve::arc(a.u, a.v, &a.m) else {
                continue;
            };
            w.cuts.clear();
            w.cuts.push(0.0);
            w.cuts.push(curve.len);
            for e in &edges {
                curve.cuts_with(e, 0.0, &mut w.cuts);
            }
            for (j, &other) in ids.iter().enumerate() {
                if j != i {
                    curve.cuts_with(&w.arcs[other as usize].m, 0.0, &mut w.cuts);
                }
            }
            if p.min_dot > 0.0 {
                curve.cuts_with(n, p.min_dot, &mut w.cuts);
            }
            w.cuts.retain(|&t| t <= curve.len);
            w.cuts.sort_unstable_by(f64::total_cmp);
            // Off the piece toward fewer cones.
            let toward = if a.weight > 0 { -a.m } else { a.m };
            for k in 1..w.cuts.len() {
                let (t0, t1) = (w.cuts[k - 1], w.cuts[k]);
                if t1 - t0 < super::MIN_PIECE {
                    continue;
                }
                let mid = curve.point(0.5 * (t0 + t1));
                if !self.cells.inside(b, &mid) || mid.dot(n) <= p.min_dot {
                    continue;
                }
                let x = (mid + toward * super::WITNESS_OFFSET).normalize();
                if !self.cells.inside(b, &x) || x.dot(n) <= p.min_dot {
                    continue;
                }
                if count_at(&x, w)? == 0 {
                    return Some(Some(x));
                }
            }
        }
        Some(None)
    }

    /// Whether direction `d` (in front) reaches the patch: no occluder's
    /// triangle meets the ray.
    fn reaches(&self, p: &PatchFrame, level: f64, d: &V3, w: &mut ExactScratch) -> bool {
        self.occluder_hit(p, level, d, w).is_none()
    }

    /// An occluder the ray along `d` meets, if any.
    fn occluder_hit(
        &self,
        p: &PatchFrame,
        level: f64,
        d: &V3,
        w: &mut ExactScratch,
    ) -> Option<usize> {
        let caster = self.caster;
        let mut stack = std::mem::take(&mut w.rays);
        let hit = caster.first_occluder(p, d, |t| w.occluder(caster, p, level, t), &mut stack);
        w.rays = stack;
        hit
    }

    /// Finds the contour edges of the patch through `tree` and marks the
    /// cells their arcs cross (`w.candidate`, `w.list`).
    fn mark_contour(&self, tree: &ContourTree, p: &PatchFrame, level: f64, w: &mut ExactScratch) {
        let caster = self.caster;
        let mut i = 0;
        // The nodes before this one lie in a subtree wholly in front of the
        // plane (pre-order: a subtree is a run of indices).
        let mut in_front_until = 0;
        while i < tree.nodes.len() {
            let node = &tree.nodes[i];
            match tree.facing_within(i, p, level, caster.t_min, i < in_front_until) {
                // Behind the plane, or every edge interior.
                None | Some((Facing::Uniform, _)) => {
                    i = node.end(i);
                    continue;
                }
                Some((Facing::Cut, _)) => {
                    self.mark_cut(tree, i, p, level, w);
                    i = node.end(i);
                    continue;
                }
                Some((Facing::Mixed, in_front)) => {
                    if in_front {
                        in_front_until = in_front_until.max(node.end(i));
                    }
                }
            }
            i += 1;
            for e in &tree.edges[node.edges()] {
                self.mark_edge(tree, e, p, level, w);
            }
        }
    }

    /// [`Exact::mark_contour`] over the subtree `i`, which is
    /// [`Facing::Cut`]: every triangle has a cone and faces the patch the
    /// same way, so an edge between two occluders is interior, and one
    /// between an occluder and a triangle wholly behind the plane is
    /// contour only when an end lies in front of the patch's plane (though
    /// not past `level`). Only the subtrees the plane cuts are walked, and
    /// only such edges are passed to [`Exact::mark_edge`]: the same arcs,
    /// in the same order, as walking every edge of the subtree.
    fn mark_cut(
        &self,
        tree: &ContourTree,
        i: usize,
        p: &PatchFrame,
        level: f64,
        w: &mut ExactScratch,
    ) {
        let (o, n) = (p.origin, p.normal);
        let slack = ContourTree::slack(self.caster.t_min);
        let end = tree.nodes[i].end(i);
        let mut j = i;
        while j < end {
            let node = &tree.nodes[j];
            if j != i {
                // Wholly behind (no occluder) or wholly in front (all
                // occluders): no contour.
                // The box first (the tighter bound needs no more when it
                // decides).
                let (box_near, box_far) = ContourTree::box_heights(node, n);
                let (lo, hi) = (level - slack, level + slack);
                if box_far <= lo || box_near > hi || {
                    let (behind, ahead) = ContourTree::axis_beyond(node, n, lo, hi);
                    behind || ahead
                } {
                    j = node.end(j);
                    continue;
                }
            }
            j += 1;
            for e in &tree.edges[node.edges()] {
                let [ca, cb, c1, c2] = e.corners.map(|v| &tree.points[v as usize]);
                // An end in front: both triangles are occluders. Every edge
                // of a `Cut` subtree has a triangle on each side.
                if n.dot(ca) > level || n.dot(cb) > level {
                    continue;
                }
                if (n.dot(c1) > level) == (n.dot(c2) > level) {
                    continue;
                }
                if (ca - o.coords).dot(n) <= 0.0 && (cb - o.coords).dot(n) <= 0.0 {
                    continue;
                }
                self.mark_edge(tree, e, p, level, w);
            }
        }
    }

    /// Records edge `e`'s arc and marks the cells it crosses when it is a
    /// contour edge of the patch.
    fn mark_edge(
        &self,
        tree: &ContourTree,
        e: &Edge,
        p: &PatchFrame,
        level: f64,
        w: &mut ExactScratch,
    ) {
        let caster = self.caster;
        let (o, n) = (p.origin, p.normal);
        let (t, t2) = (e.t as usize, e.t2);
        let [ca, cb, c1, c2] = e.corners.map(|v| &tree.points[v as usize]);
        // Occluders have a corner in front (checked here before the
        // cached test that also wants a cone).
        let ends = n.dot(ca) > level || n.dot(cb) > level;
        let q1 = (ends || n.dot(c1) > level) && w.occluder(caster, p, level, t);
        let q2 =
            t2 != NONE && (ends || n.dot(c2) > level) && w.occluder(caster, p, level, t2 as usize);
        if !q1 && !q2 {
            return;
        }
        let (a, b) = (ca - o.coords, cb - o.coords);
        let m = a.cross(&b);
        let s1 = m.dot(&(c1 - o.coords));
        let s2 = if t2 == NONE {
            0.0
        } else {
            m.dot(&(c2 - o.coords))
        };
        if q1 && q2 && s1 * s2 < 0.0 {
            // Interior: the two cones meet along the edge.
            return;
        }
        if a.dot(n) <= 0.0 && b.dot(n) <= 0.0 {
            return;
        }
        // Crossing toward +m enters the cones on that side.
        let side = |s: f64| if s > 0.0 { 1 } else { -1 };
        let weight = if q1 { side(s1) } else { 0 } + if q2 { side(s2) } else { 0 };
        let unit = m.normalize();
        let (ua, ub) = (a.normalize(), b.normalize());
        let (mut cu, mut cv) = (ua, ub);
        let (da, db) = (ua.dot(n), ub.dot(n));
        if da < 0.0 {
            cu = (ua * db - ub * da).normalize();
        } else if db < 0.0 {
            cv = (ub * da - ua * db).normalize();
        }
        w.recording = w.arcs.len() as u32;
        w.arcs.push(Arc {
            u: cu,
            v: cv,
            m: unit,
            weight,
        });
        self.mark_arc(ua, ub, n, |_| true, w);
        w.recording = NONE;
    }

    /// Settles the boundary cells in `w.pending` (no count reached them),
    /// as [`Exact::certify`] settles candidates, with rays that meet
    /// occluders only; leaves the undecided ones in `w.list` for the exact
    /// test and returns how many it opened.
    fn settle(&self, p: &PatchFrame, level: f64, row: &mut [u64], w: &mut ExactScratch) -> u32 {
        let n = p.normal;
        let mut opened = 0;
        w.list.clear();
        for k in 0..w.pending.len() {
            let c = w.pending[k];
            let ci = c as usize;
            let centre = self.cells.dirs[ci];
            let x = if is_open(&w.front, ci) {
                centre
            } else {
                self.part_point(ci, w)
            };
            let Some(blocker) = self.occluder_hit(p, level, &x, w) else {
                row[ci / 64] |= 1 << (ci % 64);
                w.witnesses.push((c, x));
                opened += 1;
                continue;
            };
            if self.flood_covers(p, ci, &x, blocker as u32, w) {
                w.certified += 1;
                continue;
            }
            let reached = nine_point_witness(&self.cells.corners[ci], centre, n, p.min_dot, |d| {
                self.reaches(p, level, d, w)
            });
            if let Some(d) = reached {
                row[ci / 64] |= 1 << (ci % 64);
                w.witnesses.push((c, d));
                opened += 1;
            } else {
                w.list.push(c);
            }
        }
        opened
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::Point3;

    use super::*;
    use crate::mesh::WeldOptions;
    use crate::setup::samples::{pocket, rotated, step, teapot, z_to};
    use crate::setup::sphere::GeodesicSphere;
    use crate::setup::visibility::CellGrid;
    use crate::setup::visibility::exact::CellShapes;

    /// A floor (`z = 0`, 2 triangles) and, beside it, a sheet leaning at
    /// 45° from `z = −5` to `z = 5` with a row of 21 vertices at `z = 0`:
    /// from the floor, the sheet faces one way and its edges along that row
    /// lie in the floor's plane (tilted, some an ulp in front of it).
    fn ramp() -> Vec<[Point3<f64>; 3]> {
        let p = Point3::new;
        let mut soup = vec![
            [
                p(-10.0, -10.0, 0.0),
                p(10.0, -10.0, 0.0),
                p(10.0, 10.0, 0.0),
            ],
            [
                p(-10.0, -10.0, 0.0),
                p(10.0, 10.0, 0.0),
                p(-10.0, 10.0, 0.0),
            ],
        ];
        let at = |i: usize, j: usize| {
            let s = -5.0 + 5.0 * i as f64;
            p(17.0 + s, -10.0 + j as f64, s)
        };
        for i in 0..2 {
            for j in 0..20 {
                let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
                soup.push([a, b, c]);
                soup.push([a, c, d]);
            }
        }
        soup
    }

    /// The hierarchy's walk skips only subtrees without contour: it finds
    /// the arcs that testing every edge of the mesh finds, in the same
    /// order, for every patch of parts whose patches' planes cut uniform
    /// subtrees (the teapot's spout cutting the body; floors with the
    /// walls' lower corners in their plane), as built (those corners
    /// exactly in the plane) and tilted (off it by round-off).
    #[test]
    fn the_walk_finds_the_arcs_of_every_edge() {
        let tilt = z_to(&V3::new(0.3, -0.2, 0.9).normalize());
        let sphere = GeodesicSphere::with_at_least(320).unwrap();
        let (grid, cells) = (CellGrid::new(&sphere), CellShapes::new(&sphere));
        let (mut arcs, mut cut) = (0, 0);
        for (name, soup) in [
            ("ramp through a floor's plane", ramp()),
            ("teapot", teapot(20, 32, 9, 16)),
            ("drafted pocket", pocket(20.0, 30.0, 15.0, 0.5, 5.0, 4)),
            ("overhanging step", step(20.0, 20.0, 15.0, 20.0, 30.0, 3)),
        ] {
            for soup in [soup.clone(), rotated(&soup, &tilt)] {
                let mesh = TriMesh::from_triangles(&soup, WeldOptions::default()).unwrap();
                let caster = RayCaster::new(&mesh);
                let tree = ContourTree::new(&mesh, &caster).unwrap();
                let exact = Exact {
                    caster: &caster,
                    grid: &grid,
                    cells: &cells,
                    sphere: &sphere,
                    flood: true,
                };
                let mut w = ExactScratch::default();
                for t in 0..mesh.triangles.len() {
                    let [a, b, c] = mesh.corners(t);
                    let origin = Point3::from((a.coords + b.coords + c.coords) / 3.0);
                    let p = PatchFrame {
                        origin: &origin,
                        normal: &mesh.normals[t],
                        min_dot: 0.0,
                        skip: t,
                    };
                    let level = p.normal.dot(&origin.coords) + caster.t_min;
                    cut += (0..tree.nodes.len())
                        .filter(|&i| tree.facing(i, &p, level, caster.t_min) == Some(Facing::Cut))
                        .count();
                    let mut found = |walk: bool| {
                        w.begin(mesh.triangles.len(), sphere.len());
                        w.arcs.clear();
                        w.arc_of.clear();
                        if walk {
                            exact.mark_contour(&tree, &p, level, &mut w);
                        } else {
                            for e in &tree.edges {
                                exact.mark_edge(&tree, e, &p, level, &mut w);
                            }
                        }
                        (w.arcs.clone(), w.arc_of.clone())
                    };
                    let (walked, all) = (found(true), found(false));
                    assert!(walked == all, "{name}: patch {t}");
                    arcs += all.0.len();
                }
            }
        }
        assert!(
            arcs > 10_000 && cut > 1_000,
            "{arcs} arcs, {cut} cut subtrees"
        );
    }

    /// A teapot (`teapot`'s rings and segments) tilted off every axis, and
    /// its tree.
    fn tilted_teapot_tree(
        body_rings: usize,
        body_segments: usize,
        spout_rings: usize,
        spout_segments: usize,
    ) -> (TriMesh, ContourTree) {
        let soup = rotated(
            &teapot(body_rings, body_segments, spout_rings, spout_segments),
            &z_to(&V3::new(0.3, -0.2, 0.9).normalize()),
        );
        let mesh = TriMesh::from_triangles(&soup, WeldOptions::default()).unwrap();
        let caster = RayCaster::new(&mesh);
        let tree = ContourTree::new(&mesh, &caster).unwrap();
        (mesh, tree)
    }

    /// The plane bound the walk takes from the axis (`axis_beyond`, no
    /// roots) puts a node behind a level only when every corner of its
    /// subtree is at or below it, and past a level only when every corner
    /// is above it; and it decides as the heights along the axis do
    /// (`axis_heights`, with the root) but for levels within round-off of
    /// them. Levels at and around the corners' own extremes and the
    /// bound's, for normals of every direction.
    #[test]
    fn the_axis_bound_puts_a_node_beyond_a_level_only_with_all_its_corners() {
        let (mesh, tree) = tilted_teapot_tree(20, 32, 9, 16);
        let normals = GeodesicSphere::with_frequency(2);
        let (mut behind, mut ahead) = (0, 0);
        for (i, node) in tree.nodes.iter().enumerate() {
            let leaves = (i..node.end(i)).filter(|&j| tree.nodes[j].count() > 0);
            let corners: Vec<V3> = leaves
                .flat_map(|j| &tree.edges[tree.nodes[j].edges()])
                .flat_map(|e| [e.t, e.t2])
                .filter(|&t| t != NONE)
                .flat_map(|t| mesh.corners(t as usize).map(|c| c.coords))
                .collect();
            for n in normals.cells() {
                let heights = corners.iter().map(|c| n.dot(c));
                let least = heights.clone().fold(f64::INFINITY, f64::min);
                let most = heights.fold(f64::NEG_INFINITY, f64::max);
                let (near, far) = ContourTree::axis_heights(node, n);
                for at in [least, most, near, far] {
                    for d in [0.0, 1e-9, 1e-6, 1e-3, 1.0] {
                        for level in [at - d, at + d] {
                            let (b, a) = ContourTree::axis_beyond(node, n, level, level);
                            if b {
                                assert!(most <= level, "node {i}: behind {level}, {most}");
                                behind += 1;
                            }
                            if a {
                                assert!(least > level, "node {i}: past {level}, {least}");
                                ahead += 1;
                            }
                            let tol = 1e-12 * (1.0 + level.abs());
                            if (far - level).abs() > tol {
                                assert_eq!(b, far <= level, "node {i}: {far} {level}");
                            }
                            if (near - level).abs() > tol {
                                assert_eq!(a, near > level, "node {i}: {near} {level}");
                            }
                        }
                    }
                }
            }
        }
        assert!(behind > 10_000 && ahead > 10_000, "{behind} {ahead}");
    }

    /// Each node's `f32` bounds hold its subtree's triangles: the box, the
    /// reach along and across the axis and the radius every corner, the
    /// cone every normal, with the axis no longer than 1, the least
    /// twice-area every triangle's; and the roundings go the
    /// safe way by at most one step. The walk skips a subtree on these
    /// bounds alone.
    #[test]
    fn each_node_bounds_its_triangles() {
        let (mesh, tree) = tilted_teapot_tree(10, 12, 5, 6);
        let (mut checked, mut coned) = (0, 0);
        for (i, node) in tree.nodes.iter().enumerate() {
            let (a, mid) = (node.axis(), node.mid());
            let s = a.norm();
            assert!(s <= 1.0 && s > 1.0 - 1e-6, "node {i}: |axis| {s}");
            let unit = a / s;
            let leaves = (i..node.end(i)).filter(|&j| tree.nodes[j].count() > 0);
            for e in leaves.flat_map(|j| &tree.edges[tree.nodes[j].edges()]) {
                for t in [e.t, e.t2].into_iter().filter(|&t| t != NONE) {
                    let t = t as usize;
                    let [a0, a1, a2] = mesh.corners(t).map(|c| c.coords);
                    let area2 = (a1 - a0).cross(&(a2 - a0)).norm();
                    assert!(
                        f64::from(tree.min_area2[i]) <= area2,
                        "node {i}: area of {t}"
                    );
                    if node.cos_a > 0.0 {
                        let (cos, sin) = (f64::from(node.cos_a) * s, f64::from(node.sin_a) * s);
                        let n = mesh.normals[t];
                        assert!(unit.dot(&n) >= cos, "node {i}: normal of {t} outside");
                        assert!(
                            unit.cross(&n).norm() <= sin,
                            "node {i}: normal of {t} outside"
                        );
                        coned += 1;
                    }
                    for c in mesh.corners(t) {
                        let (x, off) = (c.coords, c.coords - mid);
                        for k in 0..3 {
                            assert!(f64::from(node.lo[k]) <= x[k] && x[k] <= f64::from(node.hi[k]));
                        }
                        let h = a.dot(&off) / (s * s);
                        assert!(f64::from(node.along[0]) <= h && h <= f64::from(node.along[1]));
                        assert!((off - unit * unit.dot(&off)).norm() <= f64::from(node.across));
                        assert!(off.norm() <= f64::from(node.radius), "node {i}: radius");
                        checked += 1;
                    }
                }
            }
        }
        assert!(checked > 10_000 && coned > 1_000, "{checked} {coned}");
        for x in [0.1, -0.1, 1e-40, 3.0, -7.25, 1e30] {
            let (up, down, zero) = (f32_above(x), f32_below(x), f32_toward_zero(x));
            assert!(f64::from(up) >= x && f64::from(up.next_down()) < x, "{x}");
            assert!(f64::from(down) <= x && f64::from(down.next_up()) > x, "{x}");
            assert!(
                f64::from(zero).abs() <= x.abs() && (zero == up || zero == down),
                "{x}"
            );
        }
    }
}
