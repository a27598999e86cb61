//! Milled-surface prediction, seed `003_…` §3 (eq. 9–12).
//!
//! Check points lie on an XY grid. Above each, a vertical line meets the volume
//! swept by every move of the path; the lowest meeting point is the milled
//! surface there (eq. 9–11, for ball, flat and fillet/bull cutters). The paper
//! takes the cutter position `f` at the foot of the XY perpendicular, exact for
//! level moves; here the lowest point over the whole move is found
//! ([`crate::gouge::sweep::swept_bottom`]), which is the same for level moves
//! and exact for sloped ones. The error `E` (eq. 12) is the distance from the
//! milled point to the nearest point of the design mesh, negative where the
//! milled point lies below the design surface (overcut, gouge) and positive
//! above it (undercut, material left).

use std::path::Path;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::cutter::Cutter;
use crate::gouge::index::Grid2;
use crate::gouge::sweep::swept_bottom;
use crate::mesh::{P3, TriMesh, V3};

/// Refuse grids with more check points than this (memory and time guard).
pub const MAX_CHECK_POINTS: usize = 16_000_000;

/// Heat-map colour scale saturates at this many tolerances of error.
const HEAT_SCALE_TOLERANCES: f64 = 10.0;

/// Settings of the prediction. Serde field names are kebab-case.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", default, deny_unknown_fields)]
pub struct PredictConfig {
    /// Check-point spacing, mm. Default 0.25.
    pub grid_step: f64,
    /// Errors within ±tolerance count as in tolerance, mm. Default 0.05.
    pub tolerance: f64,
}

impl Default for PredictConfig {
    fn default() -> Self {
        Self {
            grid_step: 0.25,
            tolerance: 0.05,
        }
    }
}

/// Why a prediction could not be made or drawn.
#[derive(Debug, thiserror::Error)]
pub enum PredictError {
    /// A setting is not finite and positive.
    #[error("predict config field `{field}` = {value}: must be finite and > 0")]
    Config {
        /// The field (kebab-case).
        field: &'static str,
        /// Its value.
        value: f64,
    },
    /// The grid would be too large.
    #[error(
        "{needed} check points at step {step} mm exceed the limit {MAX_CHECK_POINTS}; use a larger grid step"
    )]
    TooManyCheckPoints {
        /// Points needed.
        needed: f64,
        /// The step asked for.
        step: f64,
    },
    /// The path and the mesh do not overlap in XY, or the path is empty.
    #[error("the path does not pass over the mesh")]
    NoOverlap,
    /// A CL point is not finite.
    #[error("CL point {0}: coordinate is not finite")]
    NonFinitePath(usize),
    /// Drawing or writing the PNG failed.
    #[error("heat map {path}: {why}")]
    Plot {
        /// The file.
        path: String,
        /// What went wrong.
        why: String,
    },
}

/// Overcut and undercut statistics over the machined check points.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ErrorStats {
    /// Check points on the grid.
    pub check_points: usize,
    /// Check points both over the design surface and reached by the cutter.
    pub machined: usize,
    /// Largest overcut (depth below the design surface, ≥ 0), mm.
    pub max_overcut: f64,
    /// Largest undercut (material left, ≥ 0), mm.
    pub max_undercut: f64,
    /// Mean of |E|, mm.
    pub mean_abs: f64,
    /// Root mean square of E, mm.
    pub rms: f64,
    /// Check points overcut by more than the tolerance.
    pub overcut_beyond_tolerance: usize,
    /// Check points undercut by more than the tolerance.
    pub undercut_beyond_tolerance: usize,
    /// The tolerance used, mm.
    pub tolerance: f64,
}

/// The predicted error on the check-point grid.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Prediction {
    /// XY of check point (0, 0), mm.
    pub origin: [f64; 2],
    /// Grid step, mm.
    pub step: f64,
    /// Columns (X) and rows (Y).
    pub dims: [usize; 2],
    /// Milled height per check point, row-major from `origin`; NaN where no
    /// move reaches or no design surface lies below.
    pub milled_z: Vec<f64>,
    /// Signed error E per check point (eq. 12), NaN where not machined.
    pub error: Vec<f64>,
    /// Summary.
    pub stats: ErrorStats,
}

/// The design mesh with an XY index of its triangles.
#[derive(Debug, Clone)]
pub struct DesignSurface<'a> {
    mesh: &'a TriMesh,
    grid: Grid2,
}

impl<'a> DesignSurface<'a> {
    /// Indexes the mesh's triangles in XY.
    pub fn new(mesh: &'a TriMesh) -> Self {
        let boxes: Vec<[f64; 4]> = (0..mesh.triangles.len())
            .map(|t| {
                let [a, b, c] = mesh.corners(t);
                [
                    a.x.min(b.x).min(c.x),
                    a.y.min(b.y).min(c.y),
                    a.x.max(b.x).max(c.x),
                    a.y.max(b.y).max(c.y),
                ]
            })
            .collect();
        let (lo, hi) = mesh.bounds();
        let area = (hi.x - lo.x).max(1e-9) * (hi.y - lo.y).max(1e-9);
        // About two triangles per cell.
        let cell = (2.0 * area / mesh.triangles.len() as f64).sqrt();
        Self {
            mesh,
            grid: Grid2::build(&boxes, cell),
        }
    }

    /// Highest point of the mesh above `(x, y)`, if any triangle covers it.
    pub fn top_z(&self, x: f64, y: f64) -> Option<f64> {
        let mut best: Option<f64> = None;
        self.grid.query([x, y, x, y], |t| {
            let [a, b, c] = self.mesh.corners(t as usize);
            if let Some(z) = z_in_triangle(&a, &b, &c, x, y)
                && best.is_none_or(|bz| z > bz)
            {
                best = Some(z);
            }
        });
        best
    }

    /// Distance from `p` to the mesh, looking only within `radius` in XY.
    pub fn distance(&self, p: &P3, radius: f64) -> Option<f64> {
        let mut best: Option<f64> = None;
        self.grid.query(
            [p.x - radius, p.y - radius, p.x + radius, p.y + radius],
            |t| {
                let [a, b, c] = self.mesh.corners(t as usize);
                let d = (closest_on_triangle(p, &a, &b, &c) - p).norm();
                if best.is_none_or(|bd| d < bd) {
                    best = Some(d);
                }
            },
        );
        best
    }
}

/// Height of the triangle's plane at `(x, y)` if the point projects inside it.
fn z_in_triangle(a: &P3, b: &P3, c: &P3, x: f64, y: f64) -> Option<f64> {
    let det = (b.x - a.x) * (c.y - a.y) - (c.x - a.x) * (b.y - a.y);
    if det.abs() < 1e-300 {
        return None; // vertical face
    }
    let u = ((x - a.x) * (c.y - a.y) - (c.x - a.x) * (y - a.y)) / det;
    let v = ((b.x - a.x) * (y - a.y) - (x - a.x) * (b.y - a.y)) / det;
    const EDGE: f64 = -1e-12;
    if u < EDGE || v < EDGE || u + v > 1.0 - EDGE {
        return None;
    }
    Some(a.z + u * (b.z - a.z) + v * (c.z - a.z))
}

/// Closest point of triangle `abc` to `p` (Ericson, Real-Time Collision
/// Detection, §5.1.5).
pub fn closest_on_triangle(p: &P3, a: &P3, b: &P3, c: &P3) -> P3 {
    let ab: V3 = b - a;
    let ac: V3 = c - a;
    let ap: V3 = p - a;
    let d1 = ab.dot(&ap);
    let d2 = ac.dot(&ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return *a;
    }
    let bp = p - b;
    let d3 = ab.dot(&bp);
    let d4 = ac.dot(&bp);
    if d3 >= 0.0 && d4 <= d3 {
        return *b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let d5 = ab.dot(&cp);
    let d6 = ac.dot(&cp);
    if d6 >= 0.0 && d5 <= d6 {
        return *c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denom = 1.0 / (va + vb + vc);
    a + ab * (vb * denom) + ac * (vc * denom)
}

/// Milled surface of `path` (tool-tip CL points) over the design mesh and its
/// error against the mesh.
pub fn predict(
    cutter: &Cutter,
    mesh: &TriMesh,
    path: &[P3],
    config: &PredictConfig,
) -> Result<Prediction, PredictError> {
    for (field, value) in [
        ("grid-step", config.grid_step),
        ("tolerance", config.tolerance),
    ] {
        if !(value.is_finite() && value > 0.0) {
            return Err(PredictError::Config { field, value });
        }
    }
    if let Some(i) = path
        .iter()
        .position(|p| !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite()))
    {
        return Err(PredictError::NonFinitePath(i));
    }
    let r = cutter.radius();
    let (mlo, mhi) = mesh.bounds();
    let mut plo = [f64::INFINITY; 2];
    let mut phi = [f64::NEG_INFINITY; 2];
    for p in path {
        plo = [plo[0].min(p.x - r), plo[1].min(p.y - r)];
        phi = [phi[0].max(p.x + r), phi[1].max(p.y + r)];
    }
    let lo = [mlo.x.max(plo[0]), mlo.y.max(plo[1])];
    let hi = [mhi.x.min(phi[0]), mhi.y.min(phi[1])];
    if path.is_empty() || !(lo[0] <= hi[0] && lo[1] <= hi[1]) {
        return Err(PredictError::NoOverlap);
    }
    let step = config.grid_step;
    let nx = ((hi[0] - lo[0]) / step).floor() + 1.0;
    let ny = ((hi[1] - lo[1]) / step).floor() + 1.0;
    if nx * ny > MAX_CHECK_POINTS as f64 {
        return Err(PredictError::TooManyCheckPoints {
            needed: nx * ny,
            step,
        });
    }
    let dims = [nx as usize, ny as usize];
    // Moves indexed by their swept XY box.
    let boxes: Vec<[f64; 4]> = path
        .windows(2)
        .map(|w| {
            [
                w[0].x.min(w[1].x) - r,
                w[0].y.min(w[1].y) - r,
                w[0].x.max(w[1].x) + r,
                w[0].y.max(w[1].y) + r,
            ]
        })
        .collect();
    // Small cells: a check point then visits few moves that cannot reach it.
    let moves = Grid2::build(&boxes, (r / 4.0).max(step));
    let single = path.len() == 1;
    let design = DesignSurface::new(mesh);
    let cells: Vec<(f64, f64)> = (0..dims[0] * dims[1])
        .into_par_iter()
        .map(|k| {
            let x = lo[0] + step * (k % dims[0]) as f64;
            let y = lo[1] + step * (k / dims[0]) as f64;
            let mut milled = f64::INFINITY;
            if single {
                let a = &path[0];
                if let Some(s) = swept_bottom(cutter, a, a, x, y) {
                    milled = s.z;
                }
            }
            moves.query([x, y, x, y], |m| {
                let (a, b) = (&path[m as usize], &path[m as usize + 1]);
                if let Some(s) = swept_bottom(cutter, a, b, x, y) {
                    milled = milled.min(s.z);
                }
            });
            let Some(top) = design.top_z(x, y) else {
                return (f64::NAN, f64::NAN);
            };
            if !milled.is_finite() {
                return (f64::NAN, f64::NAN);
            }
            // The vertical gap bounds the distance to the mesh (eq. 12).
            let gap = (milled - top).abs();
            let m = P3::new(x, y, milled);
            let dist = design.distance(&m, gap + step).unwrap_or(gap).min(gap);
            (milled, if milled < top { -dist } else { dist })
        })
        .collect();
    let (milled_z, error): (Vec<f64>, Vec<f64>) = cells.into_iter().unzip();
    let stats = error_stats(&error, config.tolerance);
    Ok(Prediction {
        origin: lo,
        step,
        dims,
        milled_z,
        error,
        stats,
    })
}

/// Statistics of the finite entries of `error`.
pub fn error_stats(error: &[f64], tolerance: f64) -> ErrorStats {
    let mut s = ErrorStats {
        check_points: error.len(),
        machined: 0,
        max_overcut: 0.0,
        max_undercut: 0.0,
        mean_abs: 0.0,
        rms: 0.0,
        overcut_beyond_tolerance: 0,
        undercut_beyond_tolerance: 0,
        tolerance,
    };
    let (mut sum_abs, mut sum_sq) = (0.0, 0.0);
    for &e in error.iter().filter(|e| e.is_finite()) {
        s.machined += 1;
        sum_abs += e.abs();
        sum_sq += e * e;
        s.max_overcut = s.max_overcut.max(-e);
        s.max_undercut = s.max_undercut.max(e);
        if e < -tolerance {
            s.overcut_beyond_tolerance += 1;
        }
        if e > tolerance {
            s.undercut_beyond_tolerance += 1;
        }
    }
    if s.machined > 0 {
        s.mean_abs = sum_abs / s.machined as f64;
        s.rms = (sum_sq / s.machined as f64).sqrt();
    }
    s
}

/// The colour of an error value: grey where not machined, green within the
/// tolerance, blue shades for overcut and red shades for undercut, saturating
/// at [`HEAT_SCALE_TOLERANCES`] tolerances. The PNG carries no text (no font is
/// needed); the numbers go to the JSON report.
pub fn heat_color(e: f64, tolerance: f64) -> [u8; 3] {
    if !e.is_finite() {
        return [200, 200, 200];
    }
    if e.abs() <= tolerance {
        return [60, 170, 80];
    }
    let s = ((e.abs() - tolerance) / (tolerance * (HEAT_SCALE_TOLERANCES - 1.0))).min(1.0);
    let fade = (230.0 * (1.0 - s)) as u8;
    if e < 0.0 {
        [fade, fade, 255]
    } else {
        [255, fade, fade]
    }
}

/// Writes the error map as a PNG, +Y up, `pixels` per check point.
pub fn write_heat_map(
    prediction: &Prediction,
    path: &Path,
    pixels: u32,
) -> Result<(), PredictError> {
    use plotters::prelude::*;
    let err = |why: String| PredictError::Plot {
        path: path.display().to_string(),
        why,
    };
    let px = pixels.max(1);
    let [nx, ny] = prediction.dims;
    let size = (nx as u32 * px, ny as u32 * px);
    let root = BitMapBackend::new(path, size).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(e.to_string()))?;
    let tol = prediction.stats.tolerance;
    for j in 0..ny {
        for i in 0..nx {
            let [r, g, b] = heat_color(prediction.error[j * nx + i], tol);
            let x0 = (i as u32 * px) as i32;
            let y0 = ((ny - 1 - j) as u32 * px) as i32;
            root.draw(&Rectangle::new(
                [(x0, y0), (x0 + px as i32, y0 + px as i32)],
                RGBColor(r, g, b).filled(),
            ))
            .map_err(|e| err(e.to_string()))?;
        }
    }
    root.present().map_err(|e| err(e.to_string()))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::WeldOptions;

    fn plate(z: f64) -> TriMesh {
        let p = |x: f64, y: f64| P3::new(x, y, z);
        TriMesh::from_triangles(
            &[
                [p(0.0, 0.0), p(20.0, 0.0), p(20.0, 20.0)],
                [p(0.0, 0.0), p(20.0, 20.0), p(0.0, 20.0)],
            ],
            WeldOptions::default(),
        )
        .unwrap()
    }

    #[test]
    fn level_ball_pass_over_a_plate_predicts_the_cusp() {
        // Two parallel passes 4 mm apart at the plate's height: the cusp
        // between them is R - sqrt(R² - 2²) high (the scallop formula).
        let mesh = plate(1.0);
        let cutter = Cutter::Ball { diameter: 10.0 };
        let path = vec![
            P3::new(2.0, 8.0, 1.0),
            P3::new(18.0, 8.0, 1.0),
            P3::new(18.0, 12.0, 1.0),
            P3::new(2.0, 12.0, 1.0),
        ];
        let cfg = PredictConfig {
            grid_step: 0.5,
            tolerance: 0.05,
        };
        let pr = predict(&cutter, &mesh, &path, &cfg).unwrap();
        let cusp = 5.0 - (25.0f64 - 4.0).sqrt();
        let at = |x: f64, y: f64| {
            let i = ((x - pr.origin[0]) / pr.step).round() as usize;
            let j = ((y - pr.origin[1]) / pr.step).round() as usize;
            pr.error[j * pr.dims[0] + i]
        };
        assert!((at(10.0, 10.0) - cusp).abs() < 1e-9, "{}", at(10.0, 10.0));
        assert!(at(10.0, 8.0).abs() < 1e-9);
        assert_eq!(pr.stats.max_overcut, 0.0);
        // The same path 0.1 low overcuts by 0.1 exactly on the passes.
        let low: Vec<P3> = path.iter().map(|p| P3::new(p.x, p.y, 0.9)).collect();
        let pr = predict(&cutter, &mesh, &low, &cfg).unwrap();
        assert!((pr.stats.max_overcut - 0.1).abs() < 1e-9);
        assert!(pr.stats.overcut_beyond_tolerance > 0);
    }

    #[test]
    fn closest_point_on_triangle_regions() {
        let a = P3::new(0.0, 0.0, 0.0);
        let b = P3::new(4.0, 0.0, 0.0);
        let c = P3::new(0.0, 4.0, 0.0);
        let cases = [
            (P3::new(1.0, 1.0, 3.0), P3::new(1.0, 1.0, 0.0)),
            (P3::new(-1.0, -1.0, 0.0), a),
            (P3::new(6.0, -1.0, 1.0), b),
            (P3::new(2.0, -3.0, 0.0), P3::new(2.0, 0.0, 0.0)),
            (P3::new(3.0, 3.0, 0.0), P3::new(2.0, 2.0, 0.0)),
        ];
        for (p, want) in cases {
            assert!((closest_on_triangle(&p, &a, &b, &c) - want).norm() < 1e-12);
        }
    }
}
