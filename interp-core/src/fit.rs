//! Least-squares B-spline fitting of point sequences (Piegl & Tiller, *The
//! NURBS Book*, §9.4.1), allocation-free: the caller owns every buffer.
//!
//! One home for the fitting that the G1 compression stage
//! ([`crate::smooth`]) and the offline CL-path fitter (`planner::fit`) share:
//! knots by averaging the data parameters (eq. 9.68–9.69, eq. 9.8 when
//! interpolating), the basis of [`crate::nurbs::basis_functions`], normal
//! equations that are banded (half-bandwidth = degree), solved by a banded
//! Cholesky factorisation. The first and last control points (or the first
//! and last three, to join a neighbour with continuous tangent and
//! curvature) may be fixed by the caller.

use crate::geom::Vec3;
use crate::nurbs::{MAX_DEGREE, basis_functions};

/// Row width of the banded normal matrix.
pub const BAND: usize = MAX_DEGREE + 1;

/// Why a fit failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FitError {
    /// Buffers of the wrong length, a degree outside 1..=5, fewer than two
    /// data points, or more free control points than interior data points.
    Shape,
    /// The normal equations are singular (a knot span without data, or
    /// coincident parameters).
    Singular,
}

impl core::fmt::Display for FitError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            FitError::Shape => "fit buffers, degree or free control points do not match the data",
            FitError::Singular => "singular least-squares system",
        })
    }
}

/// Clamped knots for `n + 1` control points of degree `p` over the data
/// parameters `ub` (increasing, `ub[0]` and `ub[m]` the range): eq. 9.8
/// (averaging `p` parameters) when `n == m` (interpolation), else eq. 9.69,
/// which puts at least one parameter in every knot span. `knots` must hold
/// `n + p + 2` entries. Needs `p <= n <= m`.
pub fn place_knots(ub: &[f64], n: usize, p: usize, knots: &mut [f64]) {
    let m = ub.len() - 1;
    debug_assert!(p <= n && n <= m && knots.len() == n + p + 2);
    let (a, b) = (ub[0], ub[m]);
    knots[..=p].fill(a);
    knots[n + 1..].fill(b);
    if n == m {
        for j in 1..=n - p {
            knots[j + p] = ub[j..j + p].iter().sum::<f64>() / p as f64;
        }
    } else {
        let d = (m + 1) as f64 / (n - p + 1) as f64;
        for j in 1..=n - p {
            let jd = j as f64 * d;
            let i = libm::floor(jd) as usize;
            let alpha = jd - i as f64;
            knots[p + j] = (1.0 - alpha) * ub[i - 1] + alpha * ub[i];
        }
    }
}

/// Solves the symmetric positive definite banded system `a·x = b` in place
/// for three right-hand sides at once (`a[i][d]` = A(i, i−d), half-bandwidth
/// `w`; `b[i]` the three right-hand sides, overwritten by the solution).
/// Returns false if the matrix is not positive definite.
pub fn banded_cholesky_solve(a: &mut [[f64; BAND]], w: usize, b: &mut [[f64; 3]]) -> bool {
    let n = b.len();
    for i in 0..n {
        for d in (0..=w.min(i)).rev() {
            let j = i - d;
            let mut sum = a[i][d];
            for k in i.saturating_sub(w)..j {
                sum -= a[i][i - k] * a[j][j - k];
            }
            if d == 0 {
                if !(sum > 0.0) {
                    return false;
                }
                a[i][0] = libm::sqrt(sum);
            } else {
                a[i][d] = sum / a[j][0];
            }
        }
    }
    for c in 0..3 {
        for i in 0..n {
            let mut s = b[i][c];
            for k in i.saturating_sub(w)..i {
                s -= a[i][i - k] * b[k][c];
            }
            b[i][c] = s / a[i][0];
        }
        for i in (0..n).rev() {
            let mut s = b[i][c];
            for k in i + 1..(i + w + 1).min(n) {
                s -= a[k][k - i] * b[k][c];
            }
            b[i][c] = s / a[i][0];
        }
    }
    true
}

/// The normal equations of [`lsq_fit`]: fills `band` (`band[i][d]` =
/// A(i, i−d)) and `rhs` for the free control points and returns how many
/// there are (0: nothing to solve). For callers with their own solver (a
/// dense fallback when the banded one finds the system singular).
#[allow(clippy::too_many_arguments)]
pub fn normal_equations(
    q: &[Vec3],
    ub: &[f64],
    p: usize,
    knots: &[f64],
    ctrl: &[Vec3],
    fixed_start: usize,
    fixed_end: usize,
    band: &mut [[f64; BAND]],
    rhs: &mut [[f64; 3]],
) -> Result<usize, FitError> {
    let m = q.len().wrapping_sub(1);
    let count = ctrl.len();
    if !(1..=MAX_DEGREE).contains(&p)
        || q.len() < 2
        || ub.len() != q.len()
        || knots.len() != count + p + 1
        || fixed_start < 1
        || fixed_end < 1
        || fixed_start + fixed_end > count
    {
        return Err(FitError::Shape);
    }
    let unknowns = count - fixed_start - fixed_end;
    if unknowns == 0 {
        return Ok(0);
    }
    if unknowns > m.saturating_sub(1) || band.len() < unknowns || rhs.len() < unknowns {
        return Err(FitError::Shape);
    }
    let (band, rhs) = (&mut band[..unknowns], &mut rhs[..unknowns]);
    band.fill([0.0; BAND]);
    rhs.fill([0.0; 3]);
    let free = |i: usize| i >= fixed_start && i < count - fixed_end;
    for k in 1..m {
        let (span, nb) = basis_functions(p, knots, ub[k]);
        // R_k = Q_k − Σ N_i·P_i over the fixed control points.
        let mut r = q[k];
        for (j, &nj) in nb.iter().enumerate().take(p + 1) {
            let i = span - p + j;
            if !free(i) {
                r -= ctrl[i] * nj;
            }
        }
        for j in 0..=p {
            let i = span - p + j;
            if !free(i) {
                continue;
            }
            let row = i - fixed_start;
            for c in 0..3 {
                rhs[row][c] += nb[j] * r[c];
            }
            for jj in 0..=j {
                let ii = span - p + jj;
                if free(ii) {
                    band[row][i - ii] += nb[j] * nb[jj];
                }
            }
        }
    }
    Ok(unknowns)
}

/// Least-squares control points of degree `p` over `knots` for the data
/// `q` at parameters `ub`: `ctrl[..fixed_start]` and
/// `ctrl[ctrl.len() − fixed_end..]` are given by the caller and kept; the
/// others minimise `Σ |C(ub_k) − q_k|²` over the interior data (`k` in
/// `1..m`; the end points are the fixed ends' business).
///
/// `band` and `rhs` are scratch of at least the number of free control
/// points. No allocation.
#[allow(clippy::too_many_arguments)]
pub fn lsq_fit(
    q: &[Vec3],
    ub: &[f64],
    p: usize,
    knots: &[f64],
    ctrl: &mut [Vec3],
    fixed_start: usize,
    fixed_end: usize,
    band: &mut [[f64; BAND]],
    rhs: &mut [[f64; 3]],
) -> Result<(), FitError> {
    let unknowns = normal_equations(q, ub, p, knots, ctrl, fixed_start, fixed_end, band, rhs)?;
    if unknowns == 0 {
        return Ok(());
    }
    let (band, rhs) = (&mut band[..unknowns], &mut rhs[..unknowns]);
    if !banded_cholesky_solve(band, p, rhs) {
        return Err(FitError::Singular);
    }
    for (i, x) in rhs.iter().enumerate() {
        if !x.iter().all(|v| v.is_finite()) {
            return Err(FitError::Singular);
        }
        ctrl[fixed_start + i] = Vec3::new(x[0], x[1], x[2]);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cubic_is_reproduced_exactly_by_its_own_space() {
        // Data sampled from a cubic B-spline with the same knots: the fit
        // gives its control points back.
        let knots = [0.0, 0.0, 0.0, 0.0, 0.3, 0.6, 1.0, 1.0, 1.0, 1.0];
        let truth = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 2.0, 0.0),
            Vec3::new(2.0, -1.0, 1.0),
            Vec3::new(3.0, 3.0, 0.0),
            Vec3::new(4.0, 0.0, 2.0),
            Vec3::new(5.0, 1.0, 0.0),
        ];
        let eval = |u: f64| {
            let (s, n) = basis_functions(3, &knots, u);
            (0..4).fold(Vec3::zeros(), |acc, j| acc + truth[s - 3 + j] * n[j])
        };
        let ub: [f64; 40] = core::array::from_fn(|i| i as f64 / 39.0);
        let q: [Vec3; 40] = core::array::from_fn(|i| eval(ub[i]));
        let mut ctrl = [Vec3::zeros(); 6];
        ctrl[0] = q[0];
        ctrl[5] = q[39];
        let mut band = [[0.0; BAND]; 6];
        let mut rhs = [[0.0; 3]; 6];
        lsq_fit(&q, &ub, 3, &knots, &mut ctrl, 1, 1, &mut band, &mut rhs).unwrap();
        for (c, t) in ctrl.iter().zip(&truth) {
            assert!((c - t).norm() < 1e-10, "{c:?} vs {t:?}");
        }
        // Too many unknowns for the data is a shape error, not a panic.
        assert_eq!(
            lsq_fit(
                &q[..3],
                &ub[..3],
                3,
                &knots,
                &mut ctrl,
                1,
                1,
                &mut band,
                &mut rhs
            ),
            Err(FitError::Shape)
        );
    }

    #[test]
    fn knots_by_averaging_are_clamped_and_increasing() {
        let ub: [f64; 11] = core::array::from_fn(|i| (i * i) as f64);
        for n in 3..=10 {
            let mut k = [0.0; 15];
            let k = &mut k[..n + 5];
            place_knots(&ub, n, 3, k);
            assert_eq!(&k[..4], &[0.0; 4]);
            assert!(k[n + 1..].iter().all(|&x| x == 100.0));
            assert!(k.windows(2).all(|w| w[0] <= w[1]), "{k:?}");
        }
    }
}
