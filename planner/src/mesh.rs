//! Triangle meshes: STL reading (binary and ASCII), vertex welding, face normals.
//!
//! CAD exports write every facet with its own copies of its corners, and
//! triangles of different CAD faces often disagree in the last digits. Welding
//! with a tolerance (seed `001_…` §4.2) gives them shared vertices, which the
//! planners need for topology. Non-finite coordinates are an error naming the
//! facet; triangles that collapse under welding are dropped and counted.

use std::fs::File;
use std::io::{BufReader, Read, Seek};
use std::path::Path;

use nalgebra::{Point3, Vector3};

/// A point in mm.
pub type P3 = Point3<f64>;
/// A vector in mm (or a unit normal).
pub type V3 = Vector3<f64>;

/// How a triangle soup is turned into an indexed mesh.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WeldOptions {
    /// Vertices closer than this (mm, per coordinate cell) become one vertex.
    /// Default 1e-6 mm: far below machining tolerances, above the f32
    /// round-off of STL coordinates up to about 10 m.
    pub weld_tolerance: f64,
}

impl Default for WeldOptions {
    fn default() -> Self {
        Self {
            weld_tolerance: 1e-6,
        }
    }
}

/// Why a mesh could not be read.
#[derive(Debug, thiserror::Error)]
pub enum MeshError {
    /// The file could not be opened or read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// What the OS said.
        source: std::io::Error,
    },
    /// The bytes are not a valid STL file.
    #[error("not a valid STL file: {0}")]
    Stl(std::io::Error),
    /// A facet has a NaN or infinite coordinate.
    #[error("facet {facet}, vertex {vertex}: coordinate is not finite")]
    NonFinite {
        /// Facet index in file order (0-based).
        facet: usize,
        /// Corner 0..3 of that facet.
        vertex: usize,
    },
    /// The weld tolerance is not a finite positive number.
    #[error("weld tolerance {0} must be finite and > 0")]
    BadTolerance(f64),
    /// No triangle with positive area is left.
    #[error("mesh has no triangle with positive area ({dropped} degenerate facets dropped)")]
    Empty {
        /// Facets dropped as degenerate.
        dropped: usize,
    },
}

/// An indexed triangle mesh with welded vertices, in mm.
#[derive(Debug, Clone, PartialEq)]
pub struct TriMesh {
    /// Welded vertex positions.
    pub vertices: Vec<P3>,
    /// Corner indices into `vertices`, counter-clockwise seen from outside
    /// (the orientation the file gave).
    pub triangles: Vec<[u32; 3]>,
    /// Unit normal of each triangle, from its corners (the file's stored
    /// normals are often wrong or zero, so they are ignored).
    pub normals: Vec<V3>,
    /// Facets of the input dropped because they collapsed to zero area.
    pub dropped_degenerate: usize,
}

/// An ASCII STL whose first line is a bare `solid` (no name), and whose size
/// is not that of a binary STL: its text with the first line named, so that
/// `stl_io` reads it as ASCII. `None` for anything else (reader rewound).
fn unnamed_ascii_solid<R: Read + Seek>(reader: &mut R) -> std::io::Result<Option<Vec<u8>>> {
    let mut head = [0u8; 84];
    let n = reader.read(&mut head)?;
    let len = reader.seek(std::io::SeekFrom::End(0))?;
    reader.seek(std::io::SeekFrom::Start(0))?;
    let first_line = head[..n].split(|&c| c == b'\n').next().unwrap_or(&[]);
    if first_line.trim_ascii() != b"solid" {
        return Ok(None);
    }
    if n == 84 {
        let count = u32::from_le_bytes([head[80], head[81], head[82], head[83]]) as u64;
        if 84 + 50 * count == len {
            return Ok(None); // a binary STL whose header happens to say "solid"
        }
    }
    let mut text = Vec::with_capacity(len as usize + 8);
    reader.read_to_end(&mut text)?;
    let eol = text.iter().position(|&c| c == b'\n').unwrap_or(text.len());
    text.splice(..eol, b"solid unnamed".iter().copied());
    Ok(Some(text))
}

/// A triangle soup as ASCII STL text (normals left zero: readers,
/// [`TriMesh::from_stl_reader`] among them, take the corners' order), for
/// tests and tools that hand a generated part to `interpd plan`. STL holds
/// `f32`: the file reads back as the corners rounded to `f32`.
pub fn ascii_stl(name: &str, soup: &[[P3; 3]]) -> String {
    use std::fmt::Write as _;
    let mut text = format!("solid {name}\n");
    for t in soup {
        text.push_str("facet normal 0 0 0\nouter loop\n");
        for p in t {
            let _ = writeln!(text, "vertex {} {} {}", p.x, p.y, p.z);
        }
        text.push_str("endloop\nendfacet\n");
    }
    let _ = writeln!(text, "endsolid {name}");
    text
}

impl TriMesh {
    /// Reads a binary or ASCII STL file.
    pub fn from_stl_path(path: impl AsRef<Path>, options: WeldOptions) -> Result<Self, MeshError> {
        let path = path.as_ref();
        let file = File::open(path).map_err(|source| MeshError::Io {
            path: path.display().to_string(),
            source,
        })?;
        Self::from_stl_reader(&mut BufReader::new(file), options)
    }

    /// Reads a binary or ASCII STL from any seekable reader.
    pub fn from_stl_reader<R: Read + Seek>(
        reader: &mut R,
        options: WeldOptions,
    ) -> Result<Self, MeshError> {
        if let Some(text) = unnamed_ascii_solid(reader).map_err(MeshError::Stl)? {
            // `stl_io` takes ASCII only after "solid " with a space; CAD
            // exporters (and OpenCAMLib's samples) also write a bare "solid".
            return Self::from_stl_reader(&mut std::io::Cursor::new(text), options);
        }
        let facets = stl_io::create_stl_reader(reader).map_err(MeshError::Stl)?;
        let mut soup = Vec::new();
        for facet in facets {
            let facet = facet.map_err(MeshError::Stl)?;
            soup.push(
                facet
                    .vertices
                    .map(|v| P3::new(v[0] as f64, v[1] as f64, v[2] as f64)),
            );
        }
        Self::from_triangles(&soup, options)
    }

    /// Builds a mesh from a triangle soup (three corners per facet).
    pub fn from_triangles(soup: &[[P3; 3]], options: WeldOptions) -> Result<Self, MeshError> {
        let tol = options.weld_tolerance;
        if !(tol.is_finite() && tol > 0.0) {
            return Err(MeshError::BadTolerance(tol));
        }
        let mut welder = Welder::new(tol);
        let mut triangles = Vec::with_capacity(soup.len());
        let mut normals = Vec::with_capacity(soup.len());
        let mut dropped = 0;
        for (facet, corners) in soup.iter().enumerate() {
            for (vertex, p) in corners.iter().enumerate() {
                if !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite()) {
                    return Err(MeshError::NonFinite { facet, vertex });
                }
            }
            let idx = corners.map(|p| welder.index(&p));
            if idx[0] == idx[1] || idx[1] == idx[2] || idx[0] == idx[2] {
                dropped += 1;
                continue;
            }
            let [a, b, c] = idx.map(|i| welder.vertices[i as usize]);
            let n = (b - a).cross(&(c - a));
            let norm = n.norm();
            if !(norm > 0.0) {
                dropped += 1;
                continue;
            }
            triangles.push(idx);
            normals.push(n / norm);
        }
        if triangles.is_empty() {
            return Err(MeshError::Empty { dropped });
        }
        Ok(Self {
            vertices: welder.vertices,
            triangles,
            normals,
            dropped_degenerate: dropped,
        })
    }

    /// The three corners of triangle `t`.
    pub fn corners(&self, t: usize) -> [P3; 3] {
        self.triangles[t].map(|i| self.vertices[i as usize])
    }

    /// Axis-aligned bounds `(min, max)` of the vertices.
    pub fn bounds(&self) -> (P3, P3) {
        let mut lo = P3::new(f64::INFINITY, f64::INFINITY, f64::INFINITY);
        let mut hi = P3::new(f64::NEG_INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY);
        for p in &self.vertices {
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
        (lo, hi)
    }
}

/// How the two triangles on an edge meet (seed `001_…` §4.2, Fig. 3).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum EdgeConvexity {
    /// The material bends away: a ball rolling over the edge touches it.
    Convex,
    /// The two triangles are coplanar within the tolerance.
    Flat,
    /// The material bends towards the cutter; the edge never touches it.
    Concave,
    /// Only one triangle uses the edge (the mesh's border or a gap).
    Boundary,
    /// Three or more triangles use the edge (overlaps, bad topology), or the
    /// two triangles run it the same way (inconsistent orientation).
    NonManifold,
}

/// One undirected edge of a [`TriMesh`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeshEdge {
    /// End vertices, the smaller index first.
    pub vertices: [u32; 2],
    /// The first two triangles using the edge; [`NO_TRIANGLE`] when absent.
    pub triangles: [u32; 2],
    /// Convexity judged with the triangles' own (file-orientation) normals.
    pub convexity: EdgeConvexity,
}

/// Marks a missing neighbour in [`MeshEdge::triangles`] and
/// [`MeshTopology::neighbours`] (the seed's `-1`).
pub const NO_TRIANGLE: u32 = u32::MAX;

/// Options for [`TriMesh::topology`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TopologyOptions {
    /// Two triangles whose far corner lies within this distance (mm) of the
    /// other's plane meet at a [`EdgeConvexity::Flat`] edge. Default 1e-9 mm:
    /// only truly coplanar pairs, so no machining-relevant edge is skipped.
    pub flat_tolerance: f64,
    /// A triangle whose smallest altitude is below this (mm) is counted as a
    /// sliver. Default 1e-4 mm.
    pub sliver_height: f64,
}

impl Default for TopologyOptions {
    fn default() -> Self {
        Self {
            flat_tolerance: 1e-9,
            sliver_height: 1e-4,
        }
    }
}

/// Adjacency of a [`TriMesh`]: edges with convexity, each triangle's edges
/// and neighbours (seed `001_…` Fig. 3), and counts of the defects found.
#[derive(Debug, Clone, PartialEq)]
pub struct MeshTopology {
    /// All undirected edges.
    pub edges: Vec<MeshEdge>,
    /// Edge `k` of triangle `t` (from corner `k` to corner `k+1`) is
    /// `edges[triangle_edges[t][k]]`.
    pub triangle_edges: Vec<[u32; 3]>,
    /// The triangle across edge `k` of triangle `t`, or [`NO_TRIANGLE`].
    pub neighbours: Vec<[u32; 3]>,
    /// Edges with a single triangle.
    pub boundary_edges: usize,
    /// Edges with three or more triangles or inconsistent orientation.
    pub non_manifold_edges: usize,
    /// Triangles with an altitude below [`TopologyOptions::sliver_height`].
    pub slivers: usize,
}

impl TriMesh {
    /// Builds edges, neighbours and per-edge convexity. Edges are found by
    /// sorting (vertex, vertex) keys, so this is O(n log n) and needs no hash map.
    pub fn topology(&self, options: TopologyOptions) -> MeshTopology {
        let n = self.triangles.len();
        // (lo, hi, triangle, local edge, forward?)
        let mut keys: Vec<(u32, u32, u32, u8)> = Vec::with_capacity(3 * n);
        for (t, tri) in self.triangles.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                keys.push((a.min(b), a.max(b), t as u32, k as u8));
            }
        }
        keys.sort_unstable();
        let mut edges = Vec::with_capacity(3 * n / 2 + 1);
        let mut triangle_edges = vec![[0u32; 3]; n];
        let mut neighbours = vec![[NO_TRIANGLE; 3]; n];
        let (mut boundary_edges, mut non_manifold_edges) = (0, 0);
        let mut i = 0;
        while i < keys.len() {
            let mut j = i + 1;
            while j < keys.len() && keys[j].0 == keys[i].0 && keys[j].1 == keys[i].1 {
                j += 1;
            }
            let group = &keys[i..j];
            let id = edges.len() as u32;
            for &(_, _, t, k) in group {
                triangle_edges[t as usize][k as usize] = id;
            }
            let (lo, hi) = (group[0].0, group[0].1);
            let convexity = match group {
                [_] => {
                    boundary_edges += 1;
                    EdgeConvexity::Boundary
                }
                [a, b] => {
                    neighbours[a.2 as usize][a.3 as usize] = b.2;
                    neighbours[b.2 as usize][b.3 as usize] = a.2;
                    let forward =
                        |g: &(u32, u32, u32, u8)| self.triangles[g.2 as usize][g.3 as usize] == lo;
                    if forward(a) == forward(b) {
                        non_manifold_edges += 1;
                        EdgeConvexity::NonManifold
                    } else {
                        self.classify_edge(a.2 as usize, b.2 as usize, lo, hi, options)
                    }
                }
                _ => {
                    non_manifold_edges += 1;
                    EdgeConvexity::NonManifold
                }
            };
            edges.push(MeshEdge {
                vertices: [lo, hi],
                triangles: [group[0].2, group.get(1).map_or(NO_TRIANGLE, |g| g.2)],
                convexity,
            });
            i = j;
        }
        let slivers = (0..n)
            .filter(|&t| self.min_altitude(t) < options.sliver_height)
            .count();
        MeshTopology {
            edges,
            triangle_edges,
            neighbours,
            boundary_edges,
            non_manifold_edges,
            slivers,
        }
    }

    /// Smallest altitude of triangle `t` (twice the area over the longest side).
    pub fn min_altitude(&self, t: usize) -> f64 {
        let [a, b, c] = self.corners(t);
        let area2 = (b - a).cross(&(c - a)).norm();
        let longest = (b - a).norm().max((c - b).norm()).max((a - c).norm());
        area2 / longest
    }

    /// The corner of triangle `t` that is not `lo` or `hi`.
    fn far_corner(&self, t: usize, lo: u32, hi: u32) -> P3 {
        let tri = self.triangles[t];
        let v = tri
            .iter()
            .copied()
            .find(|&v| v != lo && v != hi)
            .unwrap_or(tri[0]);
        self.vertices[v as usize]
    }

    fn classify_edge(
        &self,
        a: usize,
        b: usize,
        lo: u32,
        hi: u32,
        options: TopologyOptions,
    ) -> EdgeConvexity {
        let on_edge = self.vertices[lo as usize];
        // Signed height of b's far corner above a's plane (and vice versa):
        // negative means the surface falls away, i.e. a convex edge.
        let hb = (self.far_corner(b, lo, hi) - on_edge).dot(&self.normals[a]);
        let ha = (self.far_corner(a, lo, hi) - on_edge).dot(&self.normals[b]);
        let tol = options.flat_tolerance;
        if hb < -tol || ha < -tol {
            EdgeConvexity::Convex
        } else if hb > tol || ha > tol {
            EdgeConvexity::Concave
        } else {
            EdgeConvexity::Flat
        }
    }
}

/// Merges points within a tolerance by hashing them into grid cells of that
/// size and looking in the 27 cells around each new point.
struct Welder {
    tol: f64,
    cells: std::collections::HashMap<[i64; 3], Vec<u32>>,
    vertices: Vec<P3>,
}

impl Welder {
    fn new(tol: f64) -> Self {
        Self {
            tol,
            cells: std::collections::HashMap::new(),
            vertices: Vec::new(),
        }
    }

    fn cell(&self, p: &P3) -> [i64; 3] {
        [p.x, p.y, p.z].map(|c| (c / self.tol).floor() as i64)
    }

    fn index(&mut self, p: &P3) -> u32 {
        let c = self.cell(p);
        // STL repeats each corner exactly for every facet around it: an
        // exact copy in its own cell is the closest possible vertex, so the
        // 27-cell search is only needed for new or inexact corners.
        if let Some(list) = self.cells.get(&c)
            && let Some(&i) = list.iter().find(|&&i| self.vertices[i as usize] == *p)
        {
            return i;
        }
        let mut best: Option<(f64, u32)> = None;
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let Some(list) = self.cells.get(&[c[0] + dx, c[1] + dy, c[2] + dz]) else {
                        continue;
                    };
                    for &i in list {
                        let d = (self.vertices[i as usize] - p).norm();
                        if d <= self.tol && best.is_none_or(|(bd, _)| d < bd) {
                            best = Some((d, i));
                        }
                    }
                }
            }
        }
        if let Some((_, i)) = best {
            return i;
        }
        let i = self.vertices.len() as u32;
        self.vertices.push(*p);
        self.cells.entry(c).or_default().push(i);
        i
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(x: f64, y: f64, z: f64) -> P3 {
        P3::new(x, y, z)
    }

    #[test]
    fn welding_joins_near_vertices_and_drops_collapsed_facets() {
        let soup = [
            [p(0.0, 0.0, 0.0), p(1.0, 0.0, 0.0), p(0.0, 1.0, 0.0)],
            // Shares an edge with the first, off by less than the tolerance.
            [
                p(1.0 + 1e-8, 0.0, 0.0),
                p(1.0, 1.0, 0.0),
                p(0.0, 1.0 - 1e-8, 0.0),
            ],
            // Collapses to a segment once welded.
            [p(0.0, 0.0, 0.0), p(1e-8, 0.0, 0.0), p(1.0, 1.0, 0.0)],
        ];
        let mesh = TriMesh::from_triangles(&soup, WeldOptions::default()).unwrap();
        assert_eq!(mesh.vertices.len(), 4);
        assert_eq!(mesh.triangles.len(), 2);
        assert_eq!(mesh.dropped_degenerate, 1);
        for n in &mesh.normals {
            assert!((n - V3::z()).norm() < 1e-12);
        }
    }

    #[test]
    fn non_finite_coordinates_name_the_facet() {
        let soup = [
            [p(0.0, 0.0, 0.0), p(1.0, 0.0, 0.0), p(0.0, 1.0, 0.0)],
            [p(0.0, 0.0, 0.0), p(1.0, f64::NAN, 0.0), p(0.0, 1.0, 0.0)],
        ];
        let err = TriMesh::from_triangles(&soup, WeldOptions::default()).unwrap_err();
        assert!(matches!(
            err,
            MeshError::NonFinite {
                facet: 1,
                vertex: 1
            }
        ));
        assert_eq!(
            err.to_string(),
            "facet 1, vertex 1: coordinate is not finite"
        );
    }

    #[test]
    fn ascii_stl_with_a_bare_solid_line_reads() {
        for eol in ["\n", "\r\n"] {
            let text = format!(
                "solid{eol}facet normal 0 0 0{eol}outer loop{eol}vertex 0 0 0{eol}vertex 1 0 0{eol}\
                 vertex 0 1 0{eol}endloop{eol}endfacet{eol}endsolid{eol}"
            );
            let m = TriMesh::from_stl_reader(
                &mut std::io::Cursor::new(text.into_bytes()),
                WeldOptions::default(),
            )
            .expect("bare solid reads");
            assert_eq!(m.triangles.len(), 1);
        }
    }

    #[test]
    fn ascii_stl_text_reads_back_to_the_same_corners() {
        let soup = [
            [p(0.1, 0.0, 0.0), p(1.0, 1.0 / 3.0, 0.0), p(0.0, 1.0, 1e-7)],
            [p(0.1, 0.0, 0.0), p(0.0, 1.0, 1e-7), p(-2.5, 0.5, 3.0)],
        ];
        let text = ascii_stl("t", &soup);
        let m = TriMesh::from_stl_reader(
            &mut std::io::Cursor::new(text.into_bytes()),
            WeldOptions::default(),
        )
        .unwrap();
        assert_eq!(m.triangles.len(), 2);
        let f32_of = |q: &P3| p(q.x as f32 as f64, q.y as f32 as f64, q.z as f32 as f64);
        for (t, want) in soup.iter().enumerate() {
            assert_eq!(m.corners(t), want.map(|q| f32_of(&q)));
        }
    }

    #[test]
    fn ascii_stl_reads_and_garbage_is_an_error() {
        let text = b"solid t\nfacet normal 0 0 0\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid t\n";
        let mesh =
            TriMesh::from_stl_reader(&mut std::io::Cursor::new(&text[..]), WeldOptions::default())
                .unwrap();
        assert_eq!(mesh.triangles.len(), 1);
        assert_eq!(mesh.bounds(), (p(0.0, 0.0, 0.0), p(1.0, 1.0, 0.0)));
        let err = TriMesh::from_stl_reader(
            &mut std::io::Cursor::new(&b"solid x\nnonsense"[..]),
            WeldOptions::default(),
        );
        assert!(err.is_err());
    }
}
