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

/// Weights of a cubic's third derivative on knot span `j` (`knots[j] <
/// knots[j + 1]`, `3 <= j`): `C‴ = Σ w_l·P_{j−3+l}` there (a cubic's `C‴` is
/// constant on each span; the derivative control points of The NURBS Book
/// eq. 3.8 applied three times).
pub fn cubic_third_derivative_weights(knots: &[f64], j: usize) -> [f64; 4] {
    let i0 = j - 3;
    // Q1_i = 3(P_{i+1} − P_i)/(u_{i+4} − u_{i+1}), as weights on P_{i0..i0+3}.
    let mut q1 = [[0.0; 4]; 3];
    for (r, row) in q1.iter_mut().enumerate() {
        let i = i0 + r;
        let f = 3.0 / (knots[i + 4] - knots[i + 1]);
        row[r] = -f;
        row[r + 1] = f;
    }
    let mut q2 = [[0.0; 4]; 2];
    for (r, row) in q2.iter_mut().enumerate() {
        let i = i0 + r;
        let f = 2.0 / (knots[i + 4] - knots[i + 2]);
        for l in 0..4 {
            row[l] = f * (q1[r + 1][l] - q1[r][l]);
        }
    }
    let f = 1.0 / (knots[j + 1] - knots[j]);
    core::array::from_fn(|l| f * (q2[1][l] - q2[0][l]))
}

/// Adds `weight·∫|C‴|² du` of a cubic to the normal equations of
/// [`normal_equations`] (a smoothing spline's penalty: the fit trades
/// distance to the data for a lower third derivative, which the axes' jerk
/// sees as `C‴·v³`). Same arguments as there.
/// The penalty couples four consecutive control points, within the band.
#[allow(clippy::too_many_arguments)]
pub fn add_cubic_jerk_penalty(
    knots: &[f64],
    ctrl: &[Vec3],
    fixed_start: usize,
    fixed_end: usize,
    weight: f64,
    band: &mut [[f64; BAND]],
    rhs: &mut [[f64; 3]],
) {
    let count = ctrl.len();
    let free = |i: usize| i >= fixed_start && i < count - fixed_end;
    for j in 3..count {
        let du = knots[j + 1] - knots[j];
        if !(du > 0.0) {
            continue;
        }
        let w = cubic_third_derivative_weights(knots, j);
        let s = weight * du;
        // The fixed control points' share of C‴ on this span.
        let mut fixed = Vec3::zeros();
        for (l, &wl) in w.iter().enumerate() {
            if !free(j - 3 + l) {
                fixed += ctrl[j - 3 + l] * wl;
            }
        }
        for (l, &wl) in w.iter().enumerate() {
            let i = j - 3 + l;
            if !free(i) {
                continue;
            }
            let row = i - fixed_start;
            for c in 0..3 {
                rhs[row][c] -= s * wl * fixed[c];
            }
            for (ll, &wll) in w.iter().enumerate().take(l + 1) {
                let ii = j - 3 + ll;
                if free(ii) {
                    band[row][i - ii] += s * wl * wll;
                }
            }
        }
    }
}

/// Least-squares control points of degree `p` over `knots` for the data
/// `q` at parameters `ub`: `ctrl[..fixed_start]` and
/// `ctrl[ctrl.len() − fixed_end..]` are given by the caller and kept; the
/// others minimise `Σ |C(ub_k) − q_k|²` over the interior data (`k` in
/// `1..m`; the end points are the fixed ends' business).
///
/// With `smoothing > 0` (cubics only) the sum gains
/// `smoothing·∫|C‴|² du` ([`add_cubic_jerk_penalty`]).
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
    smoothing: f64,
    band: &mut [[f64; BAND]],
    rhs: &mut [[f64; 3]],
) -> Result<(), FitError> {
    let unknowns = normal_equations(q, ub, p, knots, ctrl, fixed_start, fixed_end, band, rhs)?;
    if unknowns == 0 {
        return Ok(());
    }
    if smoothing > 0.0 {
        if p != 3 {
            return Err(FitError::Shape);
        }
        add_cubic_jerk_penalty(knots, ctrl, fixed_start, fixed_end, smoothing, band, rhs);
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
        lsq_fit(
            &q, &ub, 3, &knots, &mut ctrl, 1, 1, 0.0, &mut band, &mut rhs,
        )
        .unwrap();
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
                0.0,
                &mut band,
                &mut rhs
            ),
            Err(FitError::Shape)
        );
    }

    #[test]
    fn third_derivative_weights_give_the_curve_s_third_derivative() {
        use crate::geom::Curve;
        let knots = [0.0, 0.0, 0.0, 0.0, 0.2, 0.45, 0.5, 1.0, 1.0, 1.0, 1.0];
        let pts: [[f64; 3]; 7] =
            core::array::from_fn(|i| [i as f64, (i * i % 5) as f64, (i as f64 * 1.3).sin()]);
        let curve = crate::nurbs::Nurbs::non_rational(3, &pts, &knots).unwrap();
        for j in 3..7 {
            let w = cubic_third_derivative_weights(&knots, j);
            let mid = 0.5 * (knots[j] + knots[j + 1]);
            let d3 = curve.eval(mid, 3).d3;
            for c in 0..3 {
                let ours: f64 = (0..4).map(|l| w[l] * pts[j - 3 + l][c]).sum();
                assert!(
                    (ours - d3[c]).abs() < 1e-9 * (1.0 + d3[c].abs()),
                    "{ours} vs {}",
                    d3[c]
                );
            }
        }
    }

    /// `N` points on a line that turns into an arc of radius 3 at x = 0
    /// (the path of a ball over a mesh edge: a curvature step), and their
    /// chord-length parameters.
    fn edge_data<const N: usize>() -> ([Vec3; N], [f64; N]) {
        let r = 3.0;
        let q: [Vec3; N] = core::array::from_fn(|i| {
            let x = -1.0 + 2.0 * i as f64 / (N - 1) as f64;
            if x <= 0.0 {
                Vec3::new(x, 0.0, 0.0)
            } else {
                let a = x / r;
                Vec3::new(r * a.sin(), 0.0, -r * (1.0 - a.cos()))
            }
        });
        let mut t = [0.0; N];
        for i in 1..N {
            t[i] = t[i - 1] + (q[i] - q[i - 1]).norm();
        }
        (q, t)
    }

    /// The cubic of `ctrl` over `knots` at `u`.
    fn cubic_at(knots: &[f64], ctrl: &[Vec3], u: f64) -> Vec3 {
        let (sp, nb) = crate::nurbs::basis_functions(3, knots, u);
        (0..4).fold(Vec3::zeros(), |a, j| a + ctrl[sp - 3 + j] * nb[j])
    }

    #[test]
    fn the_jerk_penalty_lowers_the_third_derivative_and_keeps_what_it_cannot_lower() {
        const N: usize = 121;
        let (q, t) = edge_data::<N>();
        let n = 23;
        let mut knots = [0.0; 28];
        place_knots(&t, n, 3, &mut knots);
        let fit = |smoothing: f64| {
            let mut ctrl = [Vec3::zeros(); 24];
            ctrl[0] = q[0];
            ctrl[n] = q[N - 1];
            let (mut band, mut rhs) = ([[0.0; BAND]; 24], [[0.0; 3]; 24]);
            lsq_fit(
                &q, &t, 3, &knots, &mut ctrl, 1, 1, smoothing, &mut band, &mut rhs,
            )
            .unwrap();
            let c3 = (3..=n)
                .filter(|&j| knots[j + 1] > knots[j])
                .map(|j| {
                    let w = cubic_third_derivative_weights(&knots, j);
                    (0..4)
                        .fold(Vec3::zeros(), |a, l| a + ctrl[j - 3 + l] * w[l])
                        .norm()
                })
                .fold(0.0, f64::max);
            let dev = (1..N - 1)
                .map(|k| (cubic_at(&knots, &ctrl, t[k]) - q[k]).norm())
                .fold(0.0, f64::max);
            (c3, dev)
        };
        let (c3_plain, dev_plain) = fit(0.0);
        // Weights as the `G64 P` stage scales them: tol²·(points per mm).
        let (c3_smooth, dev_smooth) = fit(1e-6 * (N - 1) as f64 / t[N - 1]);
        assert!(c3_smooth < 0.5 * c3_plain, "{c3_smooth} vs {c3_plain}");
        assert!(dev_smooth < 2e-3, "{dev_smooth}");
        assert!(dev_plain <= dev_smooth, "{dev_plain} vs {dev_smooth}");
        // A quadratic lies in the cubic space with C‴ = 0: no weight moves it.
        let quad: [Vec3; N] = core::array::from_fn(|i| {
            let x = t[i];
            Vec3::new(x, 0.3 * x * x - x, 0.1 * x * x)
        });
        let mut ctrl = [Vec3::zeros(); 24];
        ctrl[0] = quad[0];
        ctrl[n] = quad[N - 1];
        let (mut band, mut rhs) = ([[0.0; BAND]; 24], [[0.0; 3]; 24]);
        lsq_fit(
            &quad, &t, 3, &knots, &mut ctrl, 1, 1, 1.0, &mut band, &mut rhs,
        )
        .unwrap();
        for k in 0..N {
            let p = cubic_at(&knots, &ctrl, t[k]);
            assert!((p - quad[k]).norm() < 1e-9, "{k}: {p:?} vs {:?}", quad[k]);
        }
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
