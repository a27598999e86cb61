//! The triangulated sphere of the binary spherical map (seed `000_…` §4).
//!
//! A geodesic icosahedron of frequency `f`: each of the 20 faces is cut into
//! `f²` triangles whose corners are projected onto the unit sphere, so the
//! sphere has `m = 20·f²` cells of nearly equal size (1,280 for `f = 8`, the
//! nearest to the paper's 1,200; 20,480 for `f = 32`). Each cell stands for
//! one tool-axis direction: the normalised mean of its three corners.
//!
//! The icosahedron is turned to a general position ([`ORIENTATION`]): in
//! its usual position the coordinate axes are corners of six cells at every
//! even frequency, so the direction an axis-aligned part most often wants
//! (+z, past vertical walls) would touch six cells and lie inside none.

use nalgebra::Vector3;

/// Unit vector.
pub type Dir = Vector3<f64>;

/// Most cells accepted: 2·10⁶ (f = 316); the visibility map of a large part
/// grows as cells × triangles bits.
pub const MAX_CELLS: usize = 2_000_000;

/// The turn of the icosahedron (axis, angle in radians): a general
/// position, so that no coordinate axis falls on a cell's corner or edge.
pub const ORIENTATION: ([f64; 3], f64) = ([0.2645, 0.5831, 0.7683], 0.5372);

/// Why a sphere could not be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SphereError {
    /// Requested cell count is zero or above [`MAX_CELLS`].
    #[error("cells = {0}: must be within 1..={MAX_CELLS}")]
    Count(usize),
}

/// A triangulated unit sphere.
///
/// Cell `i` is the spherical triangle `corners(i)` (great-circle edges: the
/// central projection of a flat triangle of the subdivided icosahedron), and
/// its direction `cells()[i]` is the normalised mean of the three corners.
/// The sphere of frequency `2f` subdivides each cell of frequency `f` into
/// four ([`GeodesicSphere::children`]).
#[derive(Debug, Clone)]
pub struct GeodesicSphere {
    frequency: usize,
    cells: Vec<Dir>,
    /// Unit vertices of the triangulation.
    vertices: Vec<Dir>,
    /// Corner vertices of each cell, counter-clockwise seen from outside.
    corners: Vec<[u32; 3]>,
    /// Cells sharing a vertex with cell `i`: `touching[touch_start[i]..touch_start[i + 1]]`.
    touch_start: Vec<u32>,
    touching: Vec<u32>,
    /// Cells sharing an edge with each cell (the one across the edge
    /// opposite corner `k`, for `k = 0, 1, 2`).
    across: Vec<[u32; 3]>,
    /// The flat faces of the turned icosahedron, for [`GeodesicSphere::locate`].
    faces: Vec<Face>,
}

/// One flat face of the icosahedron: corner `a`, its plane `d·normal =
/// level`, the dual vectors giving a point's coordinates along the edges
/// `b − a` and `c − a`, and its unit centre.
#[derive(Debug, Clone, Copy)]
struct Face {
    a: Dir,
    normal: Dir,
    level: f64,
    du: Dir,
    dv: Dir,
    centre: Dir,
}

/// [`GeodesicSphere::locate`] answers only for directions at least this
/// far (in grid steps of the flat face) from every cell edge.
const LOCATE_MARGIN: f64 = 1e-7;

impl GeodesicSphere {
    /// The smallest geodesic sphere with at least `min_cells` cells.
    pub fn with_at_least(min_cells: usize) -> Result<Self, SphereError> {
        if min_cells == 0 || min_cells > MAX_CELLS {
            return Err(SphereError::Count(min_cells));
        }
        let mut f = 1;
        while 20 * f * f < min_cells {
            f += 1;
        }
        Ok(Self::with_frequency(f))
    }

    /// The geodesic sphere of frequency `f ≥ 1` (`20·f²` cells).
    pub fn with_frequency(f: usize) -> Self {
        let f = f.max(1);
        let (verts, faces) = icosahedron();
        let turn = nalgebra::Rotation3::from_axis_angle(
            &nalgebra::Unit::new_normalize(Dir::from(ORIENTATION.0)),
            ORIENTATION.1,
        );
        let verts = verts.map(|v| turn * v);
        let flat = faces
            .iter()
            .map(|&[ia, ib, ic]| {
                let (a, b, c) = (verts[ia], verts[ib], verts[ic]);
                let (e1, e2) = (b - a, c - a);
                let normal = e1.cross(&e2);
                let du = e2.cross(&normal);
                let dv = normal.cross(&e1);
                Face {
                    a,
                    normal,
                    level: normal.dot(&a),
                    du: du / e1.dot(&du),
                    dv: dv / e2.dot(&dv),
                    centre: (a + b + c).normalize(),
                }
            })
            .collect();
        let mut cells = Vec::with_capacity(20 * f * f);
        let mut corners = Vec::with_capacity(20 * f * f);
        let mut vertices: Vec<Dir> = Vec::new();
        // Vertices on the icosahedron's edges are shared by two faces: weld
        // them by their grid position, quantised well below the spacing.
        let mut index: std::collections::HashMap<[i64; 3], u32> = std::collections::HashMap::new();
        let mut vertex = |d: Dir| -> u32 {
            let q = d.map(|x| (x * 1e9).round() as i64);
            *index.entry([q.x, q.y, q.z]).or_insert_with(|| {
                vertices.push(d);
                (vertices.len() - 1) as u32
            })
        };
        let ff = f as f64;
        for [ia, ib, ic] in faces {
            let (a, b, c) = (verts[ia], verts[ib], verts[ic]);
            // Grid point (i, j) on the flat face, projected to the sphere.
            let p = |i: usize, j: usize| -> Dir {
                (a + (b - a) * (i as f64 / ff) + (c - a) * (j as f64 / ff)).normalize()
            };
            for i in 0..f {
                for j in 0..f - i {
                    let tri = [p(i, j), p(i + 1, j), p(i, j + 1)];
                    cells.push((tri[0] + tri[1] + tri[2]).normalize());
                    corners.push(tri.map(&mut vertex));
                    if i + j + 1 < f {
                        let tri = [p(i + 1, j), p(i + 1, j + 1), p(i, j + 1)];
                        cells.push((tri[0] + tri[1] + tri[2]).normalize());
                        corners.push(tri.map(&mut vertex));
                    }
                }
            }
        }
        // Vertex → cells, then each cell's neighbours.
        let mut at_vertex: Vec<Vec<u32>> = vec![Vec::new(); vertices.len()];
        for (i, c) in corners.iter().enumerate() {
            for &v in c {
                at_vertex[v as usize].push(i as u32);
            }
        }
        let mut touch_start = Vec::with_capacity(cells.len() + 1);
        let mut touching = Vec::with_capacity(cells.len() * 12);
        let mut across = Vec::with_capacity(cells.len());
        for (i, c) in corners.iter().enumerate() {
            touch_start.push(touching.len() as u32);
            let start = touching.len();
            for &v in c {
                touching.extend(at_vertex[v as usize].iter().filter(|&&n| n as usize != i));
            }
            touching[start..].sort_unstable();
            let mut k = start;
            for r in start..touching.len() {
                if r == start || touching[r] != touching[k - 1] {
                    touching[k] = touching[r];
                    k += 1;
                }
            }
            touching.truncate(k);
            let mut edge = [u32::MAX; 3];
            for (k, slot) in edge.iter_mut().enumerate() {
                let (v1, v2) = (c[(k + 1) % 3], c[(k + 2) % 3]);
                *slot = at_vertex[v1 as usize]
                    .iter()
                    .copied()
                    .find(|&n| n as usize != i && corners[n as usize].contains(&v2))
                    .expect("a closed triangulation: every edge has two cells");
            }
            across.push(edge);
        }
        touch_start.push(touching.len() as u32);
        Self {
            frequency: f,
            cells,
            vertices,
            corners,
            touch_start,
            touching,
            across,
            faces: flat,
        }
    }

    /// The cell holding direction `d` (any length), or `None` when `d` lies
    /// within round-off of a cell's edge (then ask the cells themselves).
    /// `hint` is a face to try first (a direction's neighbours usually lie
    /// on the same face); the face used is written back to it.
    pub fn locate(&self, d: &Dir, hint: &mut usize) -> Option<usize> {
        let f = self.frequency;
        let in_face = |k: usize| -> Option<usize> {
            let face = &self.faces[k];
            let h = face.normal.dot(d);
            if h <= 0.0 {
                return None;
            }
            // The central projection onto the face's plane: cells are the
            // projections of the flat grid's triangles.
            let w = d * (face.level / h) - face.a;
            let (x, y) = (w.dot(&face.du) * f as f64, w.dot(&face.dv) * f as f64);
            if x < 0.0 || y < 0.0 || x + y > f as f64 {
                return None;
            }
            let (i, j) = (x.floor(), y.floor());
            let (r, s) = (x - i, y - j);
            let (i, j) = (i as usize, j as usize);
            // Up cell: r, s ≥ 0 and r + s ≤ 1; down cell: r, s ≤ 1 and
            // r + s ≥ 1.
            let down = r + s > 1.0;
            let (r, s) = if down { (1.0 - r, 1.0 - s) } else { (r, s) };
            if r < LOCATE_MARGIN
                || s < LOCATE_MARGIN
                || (r + s - 1.0).abs() < LOCATE_MARGIN
                || i + j + usize::from(down) >= f
            {
                return None;
            }
            Some(k * f * f + 2 * f * i - i * i + 2 * j + usize::from(down))
        };
        if let Some(c) = in_face(*hint) {
            return Some(c);
        }
        let mut best = 0;
        for (k, face) in self.faces.iter().enumerate() {
            if face.centre.dot(d) > self.faces[best].centre.dot(d) {
                best = k;
            }
        }
        *hint = best;
        in_face(best)
    }

    /// The three corners of cell `i` (unit vectors, counter-clockwise seen
    /// from outside).
    pub fn corners(&self, i: usize) -> [Dir; 3] {
        self.corners[i].map(|v| self.vertices[v as usize])
    }

    /// The cells sharing at least a vertex with cell `i` (9 to 12 of them).
    pub fn touching(&self, i: usize) -> &[u32] {
        &self.touching[self.touch_start[i] as usize..self.touch_start[i + 1] as usize]
    }

    /// The three cells sharing an edge with cell `i`.
    pub fn across(&self, i: usize) -> [u32; 3] {
        self.across[i]
    }

    /// The four cells of the sphere of frequency `2f` that tile cell `i` of
    /// this one (frequency `f`).
    pub fn children(&self, i: usize) -> [usize; 4] {
        let f = self.frequency;
        let per_face = f * f;
        let (face, mut k) = (i / per_face, i % per_face);
        // Cells of a face run over rows i = 0..f, each with an up cell per
        // j and a down cell after each up cell but the last.
        let mut row = 0;
        while k >= 2 * (f - row) - 1 {
            k -= 2 * (f - row) - 1;
            row += 1;
        }
        let (j, down) = (k / 2, k % 2 == 1);
        // Index of the up (or down) cell (a, b) on a face of frequency g.
        let index = |g: usize, a: usize, b: usize, dn: bool| {
            let before: usize = (0..a).map(|r| 2 * (g - r) - 1).sum();
            face * g * g + before + 2 * b + usize::from(dn)
        };
        let g = 2 * f;
        let (a, b) = (2 * row, 2 * j);
        if down {
            [
                index(g, a + 1, b, true),
                index(g, a + 1, b + 1, true),
                index(g, a, b + 1, true),
                index(g, a + 1, b + 1, false),
            ]
        } else {
            [
                index(g, a, b, false),
                index(g, a + 1, b, false),
                index(g, a, b + 1, false),
                index(g, a, b, true),
            ]
        }
    }

    /// The largest angle from a cell's direction to its corners, radians: a
    /// cap of this radius around a cell's direction holds the whole cell.
    pub fn cell_radius(&self) -> f64 {
        (0..self.cells.len())
            .map(|i| {
                let d = self.cells[i];
                self.corners(i)
                    .iter()
                    .map(|c| c.cross(&d).norm().atan2(c.dot(&d)))
                    .fold(0.0, f64::max)
            })
            .fold(0.0, f64::max)
    }

    /// Subdivision frequency `f`.
    pub fn frequency(&self) -> usize {
        self.frequency
    }

    /// Number of cells `m`.
    pub fn len(&self) -> usize {
        self.cells.len()
    }

    /// Never true: a sphere has at least 20 cells.
    pub fn is_empty(&self) -> bool {
        self.cells.is_empty()
    }

    /// The direction of each cell.
    pub fn cells(&self) -> &[Dir] {
        &self.cells
    }

    /// Mean angular spacing of the cells, radians: `sqrt(4π/m)`. Results on
    /// this sphere are exact to about this angle.
    pub fn spacing(&self) -> f64 {
        (4.0 * std::f64::consts::PI / self.cells.len() as f64).sqrt()
    }
}

/// Cells of one chunk of [`CellChunks`].
const CHUNK: usize = 16;

/// A set of cells in compact chunks (of [`CHUNK`] cells unless told)
/// under bounding caps, to find the cells of the set near a direction
/// without scanning them all.
#[derive(Debug, Clone, Default)]
pub(crate) struct CellChunks {
    /// Cells per chunk (0: [`CHUNK`]).
    size: usize,
    cells: Vec<u32>,
    /// Per chunk: cap centre, cos and sin of its radius.
    caps: Vec<(Dir, f64, f64)>,
}

impl CellChunks {
    /// An empty set chunked `size` cells at a time.
    pub(crate) fn with_chunk(size: usize) -> Self {
        Self {
            size: size.max(1),
            ..Self::default()
        }
    }

    fn size(&self) -> usize {
        if self.size == 0 { CHUNK } else { self.size }
    }

    /// Replaces the set by `cells` (directions `dirs`), keeping the memory.
    pub(crate) fn rebuild(&mut self, cells: &[u32], dirs: &[Dir]) {
        let size = self.size();
        self.cells.clear();
        self.cells.extend_from_slice(cells);
        split_compact(&mut self.cells, dirs, size);
        self.caps.clear();
        for chunk in self.cells.chunks(size) {
            let sum: Dir = chunk.iter().map(|&c| dirs[c as usize]).sum();
            let centre = if sum.norm() > 1e-12 {
                sum.normalize()
            } else {
                dirs[chunk[0] as usize]
            };
            let cos_r = chunk
                .iter()
                .map(|&c| dirs[c as usize].dot(&centre))
                .fold(1.0, f64::min);
            // Widened a little so that round-off never drops a cell.
            let r = cos_r.clamp(-1.0, 1.0).acos() + 1e-9;
            self.caps.push((centre, r.cos(), r.sin()));
        }
    }

    /// The chunks: cap (centre, cos and sin of the radius) and cells.
    pub(crate) fn chunks(&self) -> impl Iterator<Item = (&(Dir, f64, f64), &[u32])> {
        self.caps.iter().zip(self.cells.chunks(self.size()))
    }

    /// The cell of the set first in the order of `search::nearer` from
    /// `p`: larger `p·d` first, then the lower index. `bounds` is scratch.
    pub(crate) fn nearest(&self, p: &Dir, dirs: &[Dir], bounds: &mut Vec<f64>) -> u32 {
        // Upper bound of p·d over each chunk's cap.
        bounds.clear();
        let mut first = 0;
        for (k, (centre, cos_r, sin_r)) in self.caps.iter().enumerate() {
            let c = p.dot(centre);
            let b = if c >= *cos_r {
                1.0
            } else {
                c * cos_r + (1.0 - c * c).max(0.0).sqrt() * sin_r
            };
            bounds.push(b + 1e-12);
            if b > bounds[first] - 1e-12 {
                first = k;
            }
        }
        let size = self.size();
        // The best cell so far and its `p·d`, kept rather than computed
        // again at every comparison (the same value).
        let mut best = self.cells[first * size];
        let mut top = dirs[best as usize].dot(p);
        let scan = |k: usize, best: &mut u32, top: &mut f64| {
            for &c in &self.cells[k * size..((k + 1) * size).min(self.cells.len())] {
                let d = dirs[c as usize].dot(p);
                if d > *top || (d == *top && c < *best) {
                    (*best, *top) = (c, d);
                }
            }
        };
        scan(first, &mut best, &mut top);
        for k in 0..self.caps.len() {
            if k != first && bounds[k] >= top {
                scan(k, &mut best, &mut top);
            }
        }
        best
    }
}

/// Orders `cells` so that runs of `size` are compact: sorted along the
/// coordinate of widest spread, halved (at a multiple of `size`), and each
/// half ordered the same way.
fn split_compact(cells: &mut [u32], dirs: &[Dir], size: usize) {
    if cells.len() <= size {
        return;
    }
    let (mut lo, mut hi) = (Dir::repeat(f64::INFINITY), Dir::repeat(f64::NEG_INFINITY));
    for &c in cells.iter() {
        lo = lo.inf(&dirs[c as usize]);
        hi = hi.sup(&dirs[c as usize]);
    }
    let axis = (hi - lo).imax();
    cells.sort_unstable_by(|&a, &b| {
        dirs[a as usize][axis]
            .total_cmp(&dirs[b as usize][axis])
            .then(a.cmp(&b))
    });
    let half = (cells.len() / 2).div_ceil(size) * size;
    let (a, b) = cells.split_at_mut(half.min(cells.len()));
    split_compact(a, dirs, size);
    split_compact(b, dirs, size);
}

/// The regular icosahedron: 12 unit vertices, 20 faces counter-clockwise seen
/// from outside.
fn icosahedron() -> ([Dir; 12], [[usize; 3]; 20]) {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let v = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .map(|[x, y, z]| Dir::new(x, y, z).normalize());
    let faces = [
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    (v, faces)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cell_counts_and_coverage() {
        let s = GeodesicSphere::with_at_least(1200).unwrap();
        assert_eq!((s.frequency(), s.len()), (8, 1280));
        assert_eq!(GeodesicSphere::with_at_least(20_000).unwrap().len(), 20_480);
        assert!(GeodesicSphere::with_at_least(0).is_err());
        // Cells are unit vectors whose mean is the origin (a symmetric cover),
        // and every direction has a cell within about one spacing.
        let mean: Dir = s.cells().iter().sum::<Dir>() / s.len() as f64;
        assert!(mean.norm() < 1e-12);
        let probe = GeodesicSphere::with_frequency(13);
        for d in probe.cells() {
            let best = s
                .cells()
                .iter()
                .map(|c| c.dot(d).clamp(-1.0, 1.0).acos())
                .fold(f64::INFINITY, f64::min);
            assert!(best < s.spacing(), "gap {best} ≥ spacing {}", s.spacing());
        }
    }

    #[test]
    fn no_coordinate_axis_lies_on_a_cell_edge() {
        // Each of ±x, ±y, ±z is well inside one cell (not on a corner or
        // an edge shared by several), at the frequencies in use.
        for f in [1, 2, 3, 8, 10, 16, 20, 32] {
            let s = GeodesicSphere::with_frequency(f);
            for axis in [
                Dir::x(),
                Dir::y(),
                Dir::z(),
                -Dir::x(),
                -Dir::y(),
                -Dir::z(),
            ] {
                let holding: Vec<f64> = (0..s.len())
                    .filter_map(|i| {
                        let c = s.corners(i);
                        (0..3)
                            .map(|k| c[k].cross(&c[(k + 1) % 3]).normalize().dot(&axis))
                            .reduce(f64::min)
                            .filter(|&m| m >= 0.0)
                    })
                    .collect();
                assert_eq!(holding.len(), 1, "f {f}: {axis:?} in {holding:?}");
                // Clear of the edges by a fair part of the cell's size.
                assert!(
                    holding[0] > 0.02 * s.spacing(),
                    "f {f}: {axis:?} {holding:?}"
                );
            }
        }
    }

    #[test]
    fn locate_finds_the_cell_holding_a_direction() {
        for f in [1, 3, 8] {
            let s = GeodesicSphere::with_frequency(f);
            let probe = GeodesicSphere::with_frequency(3 * f + 1);
            let mut hint = 0;
            let mut found = 0;
            // Cell centres, corners of a finer sphere (some on this one's
            // edges), and scaled directions.
            let dirs = probe.cells().iter().chain(&probe.vertices);
            for (k, d) in dirs.enumerate() {
                let d = d * (0.5 + (k % 7) as f64);
                let inside: Vec<usize> = (0..s.len())
                    .filter(|&i| {
                        let c = s.corners(i);
                        (0..3).all(|e| c[e].cross(&c[(e + 1) % 3]).dot(&d) >= 0.0)
                    })
                    .collect();
                match s.locate(&d, &mut hint) {
                    Some(i) => {
                        assert_eq!(inside, [i], "f {f}: {d:?}");
                        found += 1;
                    }
                    None => assert!(!inside.is_empty(), "f {f}: {d:?} in no cell"),
                }
            }
            assert!(found > probe.len() * 9 / 10, "f {f}: {found}");
        }
    }

    #[test]
    fn cells_tile_the_sphere_with_neighbours_and_children() {
        for f in [1, 3, 8] {
            let s = GeodesicSphere::with_frequency(f);
            let m = s.len();
            // Euler: V − E + F = 2 with E = 3F/2.
            assert_eq!(s.vertices.len() + m - 3 * m / 2, 2, "f = {f}");
            let radius = s.cell_radius();
            for i in 0..m {
                let c = s.corners(i);
                // Counter-clockwise seen from outside, direction inside.
                assert!(c[0].dot(&c[1].cross(&c[2])) > 0.0);
                for k in 0..3 {
                    let e = c[k].cross(&c[(k + 1) % 3]);
                    assert!(e.dot(&s.cells()[i]) > 0.0);
                }
                // Edge neighbours share two corners and are mutual.
                for (k, n) in s.across(i).iter().enumerate() {
                    let n = *n as usize;
                    assert!(s.across(n).contains(&(i as u32)));
                    assert!(s.corners[n].contains(&s.corners[i][(k + 1) % 3]));
                    assert!(s.corners[n].contains(&s.corners[i][(k + 2) % 3]));
                }
                let t = s.touching(i);
                assert!((9..=12).contains(&t.len()), "{}", t.len());
                for n in t {
                    let d = s.cells()[*n as usize]
                        .dot(&s.cells()[i])
                        .clamp(-1.0, 1.0)
                        .acos();
                    assert!(d < 4.0 * radius);
                }
            }
            // Children: the four cells of frequency 2f inside each cell.
            let fine = GeodesicSphere::with_frequency(2 * f);
            let mut seen = vec![false; fine.len()];
            for i in 0..m {
                let c = s.corners(i);
                for k in s.children(i) {
                    assert!(!std::mem::replace(&mut seen[k], true));
                    let d = fine.cells()[k];
                    for e in 0..3 {
                        assert!(
                            c[e].cross(&c[(e + 1) % 3]).dot(&d) > 0.0,
                            "f {f} cell {i} child {k}"
                        );
                    }
                }
            }
            assert!(seen.iter().all(|&x| x));
        }
    }

    #[test]
    fn the_cell_nearest_a_direction_outside_a_set_has_a_neighbour_outside_it() {
        // For any cell c and any cell p that is neither c nor touches it, some
        // cell touching c is strictly nearer p: so the cell of a set nearest
        // a cell outside it always touches a cell outside the set (the MD
        // point of eq. 4 lies on its cone's boundary).
        for f in [2, 5, 8] {
            let s = GeodesicSphere::with_frequency(f);
            let d = s.cells();
            for c in 0..s.len() {
                let t = s.touching(c);
                for p in 0..s.len() {
                    if p == c || t.contains(&(p as u32)) {
                        continue;
                    }
                    let own = d[c].dot(&d[p]);
                    assert!(
                        t.iter().any(|&n| d[n as usize].dot(&d[p]) > own),
                        "f {f}: cell {c} is a local nearest to {p}"
                    );
                }
            }
        }
    }

    /// The chunked search finds the cell a scan of the whole set finds, in
    /// the order of `search::nearer` (ties to the lower index), for sets of
    /// many shapes and directions both on and off the cells.
    #[test]
    fn chunks_find_the_nearest_cell_of_the_set() {
        let sphere = GeodesicSphere::with_frequency(12);
        let dirs = sphere.cells();
        let mut state = 0x2545_F491_4F6C_DD1Du64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        let mut chunks = CellChunks::default();
        let mut bounds = Vec::new();
        for case in 0..200 {
            // A cap, a band or a scatter of cells.
            let centre = dirs[next() as usize % dirs.len()];
            let cells: Vec<u32> = (0..dirs.len() as u32)
                .filter(|&c| match case % 3 {
                    0 => dirs[c as usize].dot(&centre) > 0.3,
                    1 => dirs[c as usize].dot(&centre).abs() < 0.2,
                    _ => next() % 7 == 0,
                })
                .collect();
            if cells.is_empty() {
                continue;
            }
            chunks.rebuild(&cells, dirs);
            for k in 0..8 {
                let p = if k % 2 == 0 {
                    dirs[next() as usize % dirs.len()]
                } else {
                    let v = Dir::new(
                        (next() >> 11) as f64 - (1u64 << 52) as f64,
                        (next() >> 11) as f64 - (1u64 << 52) as f64,
                        (next() >> 11) as f64 - (1u64 << 52) as f64,
                    );
                    v.normalize()
                };
                let scan = cells
                    .iter()
                    .copied()
                    .reduce(|a, b| {
                        let (da, db) = (dirs[a as usize].dot(&p), dirs[b as usize].dot(&p));
                        if db > da || (db == da && b < a) { b } else { a }
                    })
                    .expect("not empty");
                assert_eq!(chunks.nearest(&p, dirs, &mut bounds), scan, "case {case}");
            }
        }
    }
}
