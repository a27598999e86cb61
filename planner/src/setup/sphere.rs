//! The triangulated sphere of the binary spherical map (seed `000_…` §4).
//!
//! A geodesic icosahedron of frequency `f`: each of the 20 faces is cut into
//! `f²` triangles whose corners are projected onto the unit sphere, so the
//! sphere has `m = 20·f²` cells of nearly equal size (1,280 for `f = 8`, the
//! nearest to the paper's 1,200; 20,480 for `f = 32`). Each cell stands for
//! one tool-axis direction: the normalised mean of its three corners.

use nalgebra::Vector3;

/// Unit vector.
pub type Dir = Vector3<f64>;

/// Most cells accepted: 2·10⁶ (f = 316); the visibility map of a large part
/// grows as cells × triangles bits.
pub const MAX_CELLS: usize = 2_000_000;

/// Why a sphere could not be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SphereError {
    /// Requested cell count is zero or above [`MAX_CELLS`].
    #[error("cells = {0}: must be within 1..={MAX_CELLS}")]
    Count(usize),
}

/// A triangulated unit sphere.
#[derive(Debug, Clone)]
pub struct GeodesicSphere {
    frequency: usize,
    cells: Vec<Dir>,
}

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
        let mut cells = Vec::with_capacity(20 * f * f);
        let ff = f as f64;
        for [ia, ib, ic] in faces {
            let (a, b, c) = (verts[ia], verts[ib], verts[ic]);
            // Grid point (i, j) on the flat face, projected to the sphere.
            let p = |i: usize, j: usize| -> Dir {
                (a + (b - a) * (i as f64 / ff) + (c - a) * (j as f64 / ff)).normalize()
            };
            for i in 0..f {
                for j in 0..f - i {
                    cells.push((p(i, j) + p(i + 1, j) + p(i, j + 1)).normalize());
                    if i + j + 1 < f {
                        cells.push((p(i + 1, j) + p(i + 1, j + 1) + p(i, j + 1)).normalize());
                    }
                }
            }
        }
        Self {
            frequency: f,
            cells,
        }
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
}
