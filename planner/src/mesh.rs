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
