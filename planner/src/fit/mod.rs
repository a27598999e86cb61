//! CL polylines → NURBS blocks for interpd (G6.2).
//!
//! A polyline is cut at sharp corners (the row ends of a raster) into pieces.
//! Each piece becomes one clamped, non-rational B-spline of degree ≤ 5 (cubic
//! by default), fitted by least squares (Piegl & Tiller, *The NURBS Book*,
//! §9.4.1): chord-length parameters, knots placed by averaging the parameters
//! so every knot span holds data (eq. 9.68–9.69), end points interpolated —
//! the core's fitting (`interp_core::fit`, on the core's B-spline basis
//! `interp_core::nurbs::basis_functions`), which the `G64 P` stage uses too. The
//! number of control points is searched (doubling, then bisection) for the
//! fewest that keep every CL point within [`FitConfig::tolerance`] of the curve
//! at its parameter. The normal equations are banded (bandwidth = degree); they
//! are solved by a banded Cholesky factorisation, with nalgebra's SVD as the
//! fallback when the system is singular.
//!
//! After fitting, [`fit_checked`] samples each curve and re-runs the gouge
//! detection; a piece that interferes more than allowed is refitted tighter,
//! and kept as its polyline (G1) if that does not help.
//!
//! Output is valid for `interp_core::nurbs` (degree ≤ 5, clamped knots,
//! weights 1 > 0); a piece may have any number of control points, since the
//! program side splits long curves exactly.

use interp_core::fit::{BAND, banded_cholesky_solve, normal_equations, place_knots};
use interp_core::nurbs::basis_functions;
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::cutter::Cutter;
use crate::gouge::{self, CcSurface};
use crate::mesh::P3;

/// Highest degree interp-core evaluates.
pub const MAX_DEGREE: usize = interp_core::nurbs::MAX_DEGREE;

/// Consecutive CL points closer than this (mm) are merged before fitting.
const DUPLICATE_DISTANCE: f64 = 1e-9;

/// How many times a piece that gouges after fitting is refitted, each time
/// with a tenth of the tolerance, before it is kept as a polyline.
const REFIT_ATTEMPTS: usize = 2;

/// Curve samples per parameter interval between CL points for the gouge
/// re-check (the CL points' own parameters included).
const RECHECK_SAMPLES_PER_SPAN: usize = 4;

/// Fitting settings. Serde field names are kebab-case.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", default, deny_unknown_fields)]
pub struct FitConfig {
    /// Largest distance of a CL point from the fitted curve, mm. Default 0.001.
    pub tolerance: f64,
    /// Curve degree, 1..=5. Default 3.
    pub degree: usize,
    /// The polyline is cut where its direction turns by more than this,
    /// degrees. Default 30.
    pub corner_angle_deg: f64,
    /// Longest piece fitted at once, CL points; longer runs are cut (a guard
    /// on the size of one least-squares system). Default 2000.
    pub max_points_per_piece: usize,
}

impl Default for FitConfig {
    fn default() -> Self {
        Self {
            tolerance: 0.001,
            degree: 3,
            corner_angle_deg: 30.0,
            max_points_per_piece: 2000,
        }
    }
}

/// Why a polyline could not be fitted.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FitError {
    /// A setting is out of range.
    #[error("fit config field `{field}` = {value}: {why}")]
    Config {
        /// The field (kebab-case).
        field: &'static str,
        /// Its value.
        value: f64,
        /// The allowed range.
        why: &'static str,
    },
    /// A CL point is not finite.
    #[error("CL point {0}: coordinate is not finite")]
    NonFinite(usize),
}

impl FitConfig {
    /// Checks every field.
    pub fn validated(self) -> Result<Self, FitError> {
        if !(self.tolerance.is_finite() && self.tolerance > 0.0) {
            return Err(FitError::Config {
                field: "tolerance",
                value: self.tolerance,
                why: "must be finite and > 0",
            });
        }
        if !(1..=MAX_DEGREE).contains(&self.degree) {
            return Err(FitError::Config {
                field: "degree",
                value: self.degree as f64,
                why: "must be 1..=5",
            });
        }
        if !(self.corner_angle_deg.is_finite()
            && self.corner_angle_deg > 0.0
            && self.corner_angle_deg <= 180.0)
        {
            return Err(FitError::Config {
                field: "corner-angle-deg",
                value: self.corner_angle_deg,
                why: "must be in (0, 180]",
            });
        }
        if self.max_points_per_piece < 2 {
            return Err(FitError::Config {
                field: "max-points-per-piece",
                value: self.max_points_per_piece as f64,
                why: "must be >= 2",
            });
        }
        Ok(self)
    }
}

/// One clamped non-rational B-spline block (all weights 1).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NurbsBlock {
    /// Degree p, 1..=5.
    pub degree: usize,
    /// Control points, mm.
    pub control_points: Vec<[f64; 3]>,
    /// Weights (all 1: the fit is polynomial).
    pub weights: Vec<f64>,
    /// Clamped knot vector on [0, 1], `control_points.len() + degree + 1` long.
    pub knots: Vec<f64>,
    /// CL points this block replaces.
    pub cl_points: usize,
    /// Largest distance of those CL points from the curve, mm.
    pub max_deviation: f64,
}

impl NurbsBlock {
    /// The curve point at parameter `u` in [0, 1].
    pub fn point(&self, u: f64) -> P3 {
        let (p, knots, ctrl) = (self.degree, &self.knots, &self.control_points);
        let (span, nb) = basis_functions(p, knots, u);
        let mut pt = [0.0; 3];
        for j in 0..=p {
            let c = ctrl[span - p + j];
            for k in 0..3 {
                pt[k] += c[k] * nb[j];
            }
        }
        P3::new(pt[0], pt[1], pt[2])
    }
}

/// A piece of fitted path.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum FitPiece {
    /// A curve block.
    Nurbs(NurbsBlock),
    /// CL points kept as straight moves (two-point pieces, or pieces whose
    /// fitted curve gouged).
    Lines(Vec<[f64; 3]>),
}

/// The fitted path and its figures.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Fitted {
    /// Pieces in path order; each starts where the previous ended.
    pub pieces: Vec<FitPiece>,
    /// CL points in.
    pub cl_points: usize,
    /// NURBS blocks out.
    pub nurbs_blocks: usize,
    /// Straight moves out.
    pub line_moves: usize,
    /// CL points per output block (NURBS blocks plus straight moves).
    pub compression: f64,
    /// Largest CL-point deviation over all blocks, mm.
    pub max_deviation: f64,
    /// Pieces refitted or kept as lines after the gouge re-check.
    pub refitted_for_gouge: usize,
    /// Deepest interference of the fitted curves (sampled), if re-checked, mm.
    pub recheck_max_depth: Option<f64>,
}

fn eval(p: usize, knots: &[f64], ctrl: &[P3], u: f64) -> P3 {
    let (span, nb) = basis_functions(p, knots, u);
    let mut pt = nalgebra::Vector3::zeros();
    for j in 0..=p {
        pt += ctrl[span - p + j].coords * nb[j];
    }
    P3::from(pt)
}

/// Chord-length parameters on [0, 1].
fn chord_params(q: &[P3]) -> Vec<f64> {
    let mut u = vec![0.0; q.len()];
    for k in 1..q.len() {
        u[k] = u[k - 1] + (q[k] - q[k - 1]).norm();
    }
    let total = u[q.len() - 1];
    for v in &mut u {
        *v /= total;
    }
    let last = q.len() - 1;
    u[last] = 1.0;
    u
}

/// Least-squares curve with `n + 1` control points through the end points
/// (`interp_core::fit`); nalgebra's SVD when the normal equations are
/// singular (a span without data).
fn lsq(q: &[P3], ub: &[f64], n: usize, p: usize) -> (Vec<f64>, Vec<P3>) {
    let m = q.len() - 1;
    let mut knots = vec![0.0; n + p + 2];
    place_knots(ub, n, p, &mut knots);
    let mut ctrl = vec![q[0]; n + 1];
    ctrl[n] = q[m];
    if n < 2 {
        return (knots, ctrl);
    }
    let pts: Vec<interp_core::Vec3> = q.iter().map(|x| x.coords).collect();
    let cps: Vec<interp_core::Vec3> = ctrl.iter().map(|x| x.coords).collect();
    let mut band = vec![[0.0; BAND]; n - 1];
    let mut rhs = vec![[0.0; 3]; n - 1];
    let unknowns = match normal_equations(&pts, ub, p, &knots, &cps, 1, 1, &mut band, &mut rhs) {
        Ok(u) => u,
        // More unknowns than data: nothing better than the chord.
        Err(_) => return (knots, ctrl),
    };
    let mut a = band.clone();
    let mut sol = rhs.clone();
    if !banded_cholesky_solve(&mut a, p, &mut sol) {
        // Singular normal equations (a span without data): least squares by SVD.
        let mut dense = DMatrix::zeros(unknowns, unknowns);
        for i in 0..unknowns {
            for d in 0..=p.min(i) {
                dense[(i, i - d)] = band[i][d];
                dense[(i - d, i)] = band[i][d];
            }
        }
        let svd = dense.svd(true, true);
        for c in 0..3 {
            let b = DVector::from_iterator(unknowns, rhs.iter().map(|r| r[c]));
            let x = svd
                .solve(&b, 1e-12)
                .unwrap_or_else(|_| DVector::zeros(unknowns));
            for i in 0..unknowns {
                sol[i][c] = x[i];
            }
        }
    }
    for i in 0..unknowns {
        ctrl[i + 1] = P3::new(sol[i][0], sol[i][1], sol[i][2]);
    }
    (knots, ctrl)
}

/// Samples per span between two CL points where the fitted curve is checked
/// against the straight move it replaces.
const SPAN_CHECKS: usize = 3;

/// Between two CL points a smooth curve through them may bulge from their
/// chord by the sagitta of the circle through its neighbours (`L·θ/8` for a
/// span of length `L` turning by `θ`); it may stray this many sagittas, plus
/// the tolerance.
pub const SAGITTA_ALLOWANCE: f64 = 2.0;

/// Turning angle of the polyline at each point (0 at the ends), rad.
fn turn_angles(q: &[P3]) -> Vec<f64> {
    let mut a = vec![0.0; q.len()];
    for i in 1..q.len().saturating_sub(1) {
        let (u, v) = (q[i] - q[i - 1], q[i + 1] - q[i]);
        let c = u.dot(&v) / (u.norm() * v.norm());
        a[i] = if c.is_finite() {
            c.clamp(-1.0, 1.0).acos()
        } else {
            0.0
        };
    }
    a
}

/// How far the curve may stray from span `i`'s chord beyond the tolerance.
pub fn span_allowance(q: &[P3], turns: &[f64], i: usize) -> f64 {
    let theta = turns[i].max(turns[i + 1]);
    SAGITTA_ALLOWANCE * (q[i + 1] - q[i]).norm() * theta / 8.0
}

/// The largest distance of the curve from the polyline it replaces: at every
/// CL point, and at [`SPAN_CHECKS`] parameters inside each span from that
/// span's segment, less the span's [`span_allowance`]. Without the second
/// part a least-squares curve may meet every point and swing far away
/// between them.
fn max_deviation(q: &[P3], turns: &[f64], ub: &[f64], knots: &[f64], ctrl: &[P3], p: usize) -> f64 {
    let at_points = q
        .iter()
        .zip(ub)
        .map(|(pt, &u)| (eval(p, knots, ctrl, u) - pt).norm())
        .fold(0.0, f64::max);
    let between = (0..q.len().saturating_sub(1))
        .flat_map(|i| (1..=SPAN_CHECKS).map(move |k| (i, k)))
        .map(|(i, k)| {
            let t = k as f64 / (SPAN_CHECKS + 1) as f64;
            let u = ub[i] + (ub[i + 1] - ub[i]) * t;
            distance_to_segment(&eval(p, knots, ctrl, u), &q[i], &q[i + 1])
                - span_allowance(q, turns, i)
        })
        .fold(0.0, f64::max);
    at_points.max(between)
}

fn distance_to_segment(x: &P3, a: &P3, b: &P3) -> f64 {
    let ab = b - a;
    let len2 = ab.norm_squared();
    let t = if len2 > 0.0 {
        ((x - a).dot(&ab) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (x - (a + ab * t)).norm()
}

/// Fits one piece of at least two distinct points with the fewest control
/// points that keep every point within `tol`.
pub fn fit_piece(q: &[P3], degree: usize, tol: f64) -> NurbsBlock {
    let m = q.len() - 1;
    let p = degree.min(m).max(1);
    let ub = chord_params(q);
    // The polyline's turns do not depend on the attempt: once per piece.
    let turns = turn_angles(q);
    let attempt = |n: usize| {
        let (knots, ctrl) = lsq(q, &ub, n, p);
        let dev = max_deviation(q, &turns, &ub, &knots, &ctrl, p);
        (knots, ctrl, dev)
    };
    // Doubling, then bisection on the control-point count n + 1.
    let mut lo;
    let mut best = attempt(p);
    if best.2 > tol {
        let mut n = p;
        loop {
            lo = n;
            n = (2 * n).min(m);
            let got = attempt(n);
            if got.2 <= tol || n == m {
                best = got;
                break;
            }
        }
        let mut hi = n;
        while hi - lo > 1 {
            let mid = (lo + hi) / 2;
            let got = attempt(mid);
            if got.2 <= tol {
                hi = mid;
                best = got;
            } else {
                lo = mid;
            }
        }
    }
    let (knots, ctrl, dev) = best;
    NurbsBlock {
        degree: p,
        weights: vec![1.0; ctrl.len()],
        control_points: ctrl.iter().map(|c| [c.x, c.y, c.z]).collect(),
        knots,
        cl_points: q.len(),
        max_deviation: dev,
    }
}

/// Cuts the polyline into pieces at sharp corners; consecutive pieces share
/// their corner point.
fn split_at_corners(q: &[P3], cfg: &FitConfig) -> Vec<Vec<P3>> {
    let cos_limit = cfg.corner_angle_deg.to_radians().cos();
    let mut pieces = Vec::new();
    let mut cur: Vec<P3> = vec![q[0]];
    for k in 1..q.len() {
        cur.push(q[k]);
        let corner = k + 1 < q.len() && {
            let (a, b) = ((q[k] - q[k - 1]).normalize(), (q[k + 1] - q[k]).normalize());
            a.dot(&b) < cos_limit
        };
        if corner || cur.len() >= cfg.max_points_per_piece {
            pieces.push(std::mem::replace(&mut cur, vec![q[k]]));
        }
    }
    if cur.len() >= 2 {
        pieces.push(cur);
    }
    pieces
}

fn to_piece(q: &[P3], cfg: &FitConfig, tol: f64) -> FitPiece {
    if q.len() == 2 {
        FitPiece::Lines(q.iter().map(|p| [p.x, p.y, p.z]).collect())
    } else {
        let block = fit_piece(q, cfg.degree, tol);
        if block.max_deviation <= tol {
            FitPiece::Nurbs(block)
        } else {
            // No curve of at most one control point per CL point stays
            // within the tolerance: keep the straight moves.
            FitPiece::Lines(q.iter().map(|p| [p.x, p.y, p.z]).collect())
        }
    }
}

/// Fits a CL polyline without a gouge re-check.
pub fn fit(q: &[P3], cfg: &FitConfig) -> Result<Fitted, FitError> {
    fit_checked(q, cfg, None)
}

/// What the gouge re-check after fitting compares against.
#[derive(Debug, Clone, Copy)]
pub struct Recheck<'a> {
    /// The cutter.
    pub cutter: &'a Cutter,
    /// The design surface's CC points.
    pub surface: &'a CcSurface,
    /// Largest interference allowed on the fitted curves, mm.
    pub max_depth: f64,
}

/// Fits a CL polyline; with `recheck`, samples each fitted curve, re-runs the
/// gouge detection, refits pieces that interfere too much with a tighter
/// tolerance and keeps them as polylines if that does not help.
pub fn fit_checked(
    q: &[P3],
    cfg: &FitConfig,
    recheck: Option<Recheck<'_>>,
) -> Result<Fitted, FitError> {
    let cfg = cfg.validated()?;
    if let Some(i) = q
        .iter()
        .position(|p| !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite()))
    {
        return Err(FitError::NonFinite(i));
    }
    let mut pts: Vec<P3> = Vec::with_capacity(q.len());
    for p in q {
        if pts
            .last()
            .is_none_or(|l: &P3| (p - l).norm() > DUPLICATE_DISTANCE)
        {
            pts.push(*p);
        }
    }
    let raw: Vec<Vec<P3>> = if pts.len() >= 2 {
        split_at_corners(&pts, &cfg)
    } else {
        Vec::new()
    };
    let results: Vec<(FitPiece, bool, f64)> = raw
        .par_iter()
        .map(|piece| {
            let mut tol = cfg.tolerance;
            let mut fitted = to_piece(piece, &cfg, tol);
            let Some(rc) = recheck else {
                return (fitted, false, 0.0);
            };
            let mut depth = sampled_depth(&fitted, &rc);
            let mut refitted = false;
            for _ in 0..REFIT_ATTEMPTS {
                if depth <= rc.max_depth {
                    break;
                }
                refitted = true;
                tol /= 10.0;
                fitted = to_piece(piece, &cfg, tol);
                depth = sampled_depth(&fitted, &rc);
            }
            if depth > rc.max_depth {
                fitted = FitPiece::Lines(piece.iter().map(|p| [p.x, p.y, p.z]).collect());
                depth = sampled_depth(&fitted, &rc);
            }
            (fitted, refitted, depth)
        })
        .collect();
    let nurbs_blocks = results
        .iter()
        .filter(|r| matches!(r.0, FitPiece::Nurbs(_)))
        .count();
    let line_moves: usize = results
        .iter()
        .map(|r| match &r.0 {
            FitPiece::Lines(l) => l.len() - 1,
            FitPiece::Nurbs(_) => 0,
        })
        .sum();
    let max_deviation = results
        .iter()
        .map(|r| match &r.0 {
            FitPiece::Nurbs(b) => b.max_deviation,
            FitPiece::Lines(_) => 0.0,
        })
        .fold(0.0, f64::max);
    let blocks = nurbs_blocks + line_moves;
    Ok(Fitted {
        cl_points: q.len(),
        nurbs_blocks,
        line_moves,
        compression: if blocks > 0 {
            q.len() as f64 / blocks as f64
        } else {
            0.0
        },
        max_deviation,
        refitted_for_gouge: results.iter().filter(|r| r.1).count(),
        recheck_max_depth: recheck.map(|_| results.iter().map(|r| r.2).fold(0.0, f64::max)),
        pieces: results.into_iter().map(|r| r.0).collect(),
    })
}

/// Dense samples of a piece: the curve at each CL point's parameter span cut
/// into [`RECHECK_SAMPLES_PER_SPAN`] parts.
pub fn sample_piece(piece: &FitPiece) -> Vec<P3> {
    match piece {
        FitPiece::Lines(l) => l.iter().map(|p| P3::new(p[0], p[1], p[2])).collect(),
        FitPiece::Nurbs(b) => {
            let steps = (b.cl_points - 1) * RECHECK_SAMPLES_PER_SPAN;
            (0..=steps)
                .map(|i| b.point(i as f64 / steps as f64))
                .collect()
        }
    }
}

fn sampled_depth(piece: &FitPiece, rc: &Recheck<'_>) -> f64 {
    let samples = sample_piece(piece);
    gouge::detect(rc.cutter, rc.surface, &samples, 0.0).max_depth()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cores_banded_cholesky_matches_nalgebra() {
        let n = 12;
        let w = 3;
        let mut dense = DMatrix::<f64>::zeros(n, n);
        let mut band = vec![[0.0; BAND]; n];
        for i in 0..n {
            for d in 0..=w.min(i) {
                let v = if d == 0 {
                    10.0 + i as f64
                } else {
                    1.0 / (1.0 + d as f64 + 0.1 * i as f64)
                };
                band[i][d] = v;
                dense[(i, i - d)] = v;
                dense[(i - d, i)] = v;
            }
        }
        let b: Vec<f64> = (0..n).map(|i| (i as f64).sin()).collect();
        let want = dense
            .cholesky()
            .unwrap()
            .solve(&DVector::from_vec(b.clone()));
        let mut x: Vec<[f64; 3]> = b.iter().map(|&v| [v, 2.0 * v, -v]).collect();
        assert!(banded_cholesky_solve(&mut band, w, &mut x));
        for i in 0..n {
            assert!((x[i][0] - want[i]).abs() < 1e-12);
            assert!((x[i][1] - 2.0 * want[i]).abs() < 1e-12);
            assert!((x[i][2] + want[i]).abs() < 1e-12);
        }
    }

    #[test]
    fn a_sampled_cubic_is_reproduced_with_few_control_points() {
        // Points on a helix-like smooth curve: a handful of control points
        // must do at 1 µm, far fewer than the points.
        let q: Vec<P3> = (0..200)
            .map(|i| {
                let t = i as f64 / 199.0 * 3.0;
                P3::new(20.0 * t, 5.0 * t.sin(), 0.5 * t * t)
            })
            .collect();
        let b = fit_piece(&q, 3, 1e-3);
        assert!(b.max_deviation <= 1e-3);
        assert!(b.control_points.len() < 40, "{}", b.control_points.len());
        assert_eq!(b.knots.len(), b.control_points.len() + 4);
        assert_eq!(b.point(0.0), q[0]);
        assert!((b.point(1.0) - q[199]).norm() < 1e-12);
    }
}
