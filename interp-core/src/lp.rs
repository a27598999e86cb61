//! A primal–dual interior-point solver for the linear programs of the feed
//! schedule (non-real-time).
//!
//! The problem is: maximise `c·x` subject to rows `lo ≤ a·x ≤ hi` and
//! bounds `lo_j ≤ x_j ≤ hi_j`, where every row touches at most three
//! consecutive variables (`x_k, x_{k+1}, x_{k+2}`). That is the shape of
//! every constraint on a quadratic spline written with one unknown per piece
//! (a piece's value, slope and curvature depend on its own and its two
//! neighbours' unknowns), so the normal equations of a Newton step are
//! pentadiagonal and one step costs O(n).
//!
//! The method is Mehrotra's predictor–corrector on the standard primal–dual
//! system (Nocedal & Wright, *Numerical Optimization*, §14.2), started from an
//! infeasible point, so no feasible start has to be constructed. Variables
//! and rows are scaled to unit size first. Everything works in caller-owned
//! scratch ([`LpWork`]) of fixed capacity: no allocation.

/// One constraint `lo ≤ a[0]·x[k] + a[1]·x[k+1] + a[2]·x[k+2] ≤ hi`
/// (either side may be infinite; coefficients past the last variable must be 0).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Row {
    /// First variable the row touches.
    pub k: u32,
    /// Coefficients of `x[k]`, `x[k+1]`, `x[k+2]`.
    pub a: [f64; 3],
    /// Lower bound (`-inf`: none).
    pub lo: f64,
    /// Upper bound (`+inf`: none).
    pub hi: f64,
}

/// Why [`solve`] gave no solution.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LpError {
    /// More variables or rows than the scratch holds, or mismatched lengths.
    Capacity,
    /// A bound or coefficient is NaN, or a lower bound exceeds an upper one.
    Invalid,
    /// The iteration limit was reached before the residuals and the duality
    /// gap fell below the tolerance (in practice: the problem is infeasible).
    NotConverged,
}

impl core::fmt::Display for LpError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            LpError::Capacity => write!(f, "linear program larger than its scratch space"),
            LpError::Invalid => write!(f, "linear program with NaN or crossed bounds"),
            LpError::NotConverged => write!(f, "linear program did not converge (infeasible?)"),
        }
    }
}

/// The problem: objective `c` (maximised) and variable bounds; the rows
/// are in the [`LpWork`] ([`LpWork::push_row`]).
#[derive(Clone, Copy, Debug)]
pub struct Problem<'a> {
    /// Objective coefficients, one per variable.
    pub c: &'a [f64],
    /// Lower bound of each variable (`-inf`: none).
    pub lo: &'a [f64],
    /// Upper bound of each variable (`+inf`: none).
    pub hi: &'a [f64],
}

/// Solver settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LpOptions {
    /// Largest scaled primal and dual residual and mean complementarity at
    /// which the iteration stops. Default 1e-11 (a plan then does not depend
    /// on how its program was cut into blocks by more than ~1e-9 relative).
    pub tolerance: f64,
    /// Iteration cap. Default 200.
    pub max_iter: u32,
    /// Weight of a small concave term `−(pull/2)·Σ (x̂_j − 1)²` on each
    /// bounded variable scaled to its upper bound (`x̂ = x/hi`): it makes the
    /// optimum unique where the linear objective is flat, towards the upper
    /// bounds, so that problems differing in a row that does not bind (or in
    /// round-off) give the same solution. 0: a plain linear program. Default 0.
    pub pull: f64,
}

impl Default for LpOptions {
    fn default() -> Self {
        LpOptions {
            tolerance: 1e-11,
            max_iter: 200,
            pull: 0.0,
        }
    }
}

/// What [`solve`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LpStats {
    /// Newton iterations.
    pub iterations: u32,
    /// Objective `c·x` at the solution (unscaled).
    pub objective: f64,
    /// Largest violation of a row or bound at the solution, in the units of
    /// that row (unscaled).
    pub max_violation: f64,
}

/// Per-bound state: slack `s`, dual `z`, and the predictor's steps.
#[derive(Clone, Copy, Debug, Default)]
struct Bound {
    s: f64,
    z: f64,
    ds: f64,
    dz: f64,
}

/// Scratch space for up to `N` variables and `M` rows, which also holds the
/// rows (written with [`LpWork::push_row`], scaled in place by [`solve`]).
#[derive(Clone, Debug)]
pub struct LpWork<const N: usize, const M: usize> {
    x: [f64; N],
    /// The best iterate so far (by its worst residual).
    xbest: [f64; N],
    /// Scale of each variable.
    vs: [f64; N],
    dx: [f64; N],
    rd: [f64; N],
    rhs: [f64; N],
    c: [f64; N],
    vlo: [f64; N],
    vhi: [f64; N],
    // Pentadiagonal normal matrix and its LDLᵀ factors.
    h0: [f64; N],
    h1: [f64; N],
    h2: [f64; N],
    vu: [Bound; N],
    vl: [Bound; N],
    // The rows, scaled in place by `solve` (`rscale`: the factor divided out).
    m: usize,
    ra: [[f64; 3]; M],
    rk: [u32; M],
    rlo: [f64; M],
    rhi: [f64; M],
    rscale: [f64; M],
    ru: [Bound; M],
    rl: [Bound; M],
    /// Each row's value `a·x` at the current iterate (computed once per
    /// iteration, read by both Newton directions).
    rv: [f64; M],
    /// Scaled primal and dual residuals and mean complementarity at the last iteration.
    pub residuals: (f64, f64, f64),
}

impl<const N: usize, const M: usize> Default for LpWork<N, M> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize, const M: usize> LpWork<N, M> {
    /// Empty scratch space.
    pub fn new() -> Self {
        let b = Bound::default();
        LpWork {
            x: [0.0; N],
            xbest: [0.0; N],
            vs: [1.0; N],
            dx: [0.0; N],
            rd: [0.0; N],
            rhs: [0.0; N],
            c: [0.0; N],
            vlo: [0.0; N],
            vhi: [0.0; N],
            h0: [0.0; N],
            h1: [0.0; N],
            h2: [0.0; N],
            vu: [b; N],
            vl: [b; N],
            m: 0,
            ra: [[0.0; 3]; M],
            rk: [0; M],
            rlo: [0.0; M],
            rhi: [0.0; M],
            rscale: [1.0; M],
            ru: [b; M],
            rl: [b; M],
            rv: [0.0; M],
            residuals: (0.0, 0.0, 0.0),
        }
    }

    /// Forget the rows.
    pub fn clear_rows(&mut self) {
        self.m = 0;
    }

    /// Add a row. False (and nothing added) when the scratch is full.
    pub fn push_row(&mut self, r: Row) -> bool {
        if self.m >= M {
            return false;
        }
        self.rk[self.m] = r.k;
        self.ra[self.m] = r.a;
        self.rlo[self.m] = r.lo;
        self.rhi[self.m] = r.hi;
        self.rscale[self.m] = 1.0;
        self.m += 1;
        true
    }

    /// Rows held.
    pub fn rows(&self) -> usize {
        self.m
    }

    /// Row `r` as held (after [`solve`]: scaled, with its scale factor).
    pub fn row(&self, r: usize) -> (Row, f64) {
        (
            Row {
                k: self.rk[r],
                a: self.ra[r],
                lo: self.rlo[r],
                hi: self.rhi[r],
            },
            self.rscale[r],
        )
    }

    /// The row value `a·x` of row `r` (scaled units). Every row spans
    /// three variables (see [`solve_traced`]'s shift), zeros included: a
    /// zero coefficient adds `±0`, which changes no sum.
    #[inline]
    fn row_value(&self, r: usize) -> f64 {
        let k = self.rk[r] as usize;
        let (a, x) = (&self.ra[r], &self.x[k..k + 3]);
        let mut v = 0.0;
        v += a[0] * x[0];
        v += a[1] * x[1];
        v += a[2] * x[2];
        v
    }
}

/// Solve `p` into `x` (one value per variable). On error `x` is unspecified.
pub fn solve<const N: usize, const M: usize>(
    p: &Problem<'_>,
    opts: &LpOptions,
    w: &mut LpWork<N, M>,
    x: &mut [f64],
) -> Result<LpStats, LpError> {
    solve_traced(p, opts, w, x, &mut |_| {})
}

/// One iteration of [`solve_traced`]: scaled primal and dual residuals, mean
/// complementarity, and the primal and dual step lengths taken.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Iteration {
    /// Iteration number, from 1.
    pub k: u32,
    /// Largest primal residual (scaled).
    pub primal: f64,
    /// Largest dual residual (scaled).
    pub dual: f64,
    /// Mean complementarity `s·z`.
    pub mu: f64,
    /// Primal step length.
    pub step_primal: f64,
    /// Dual step length.
    pub step_dual: f64,
}

/// [`solve`], calling `trace` after every iteration (diagnostics).
pub fn solve_traced<const N: usize, const M: usize>(
    p: &Problem<'_>,
    opts: &LpOptions,
    w: &mut LpWork<N, M>,
    x: &mut [f64],
    trace: &mut dyn FnMut(Iteration),
) -> Result<LpStats, LpError> {
    let n = p.c.len();
    if n > N || p.lo.len() != n || p.hi.len() != n || x.len() != n {
        return Err(LpError::Capacity);
    }
    if n == 0 {
        return Ok(LpStats::default());
    }
    // Scale: each variable by its largest finite bound (variables of very
    // different ranges otherwise stall the iteration), rows to unit
    // coefficients, the objective to unit size.
    let mut top: f64 = 0.0;
    for j in 0..n {
        let (lo, hi) = (p.lo[j], p.hi[j]);
        if lo.is_nan() || hi.is_nan() || lo > hi || p.c[j].is_nan() {
            return Err(LpError::Invalid);
        }
        let mut sj: f64 = 0.0;
        for v in [lo, hi] {
            if v.is_finite() {
                sj = sj.max(libm::fabs(v));
            }
        }
        w.vs[j] = sj;
        top = top.max(sj);
    }
    let top = if top > 0.0 { top } else { 1.0 };
    for j in 0..n {
        if !(w.vs[j] > 0.0) {
            w.vs[j] = top;
        }
    }
    let mut cs: f64 = 0.0;
    for j in 0..n {
        cs = cs.max(libm::fabs(p.c[j]) * w.vs[j]);
    }
    let cs = if cs > 0.0 { cs } else { 1.0 };
    for j in 0..n {
        let sj = w.vs[j];
        w.c[j] = p.c[j] * sj / cs;
        w.vlo[j] = p.lo[j] / sj;
        w.vhi[j] = p.hi[j] / sj;
    }
    // Scale the rows in place, dropping constant ones.
    let mut mm = 0;
    for r in 0..w.m {
        let (k, a, lo, hi) = (w.rk[r] as usize, w.ra[r], w.rlo[r], w.rhi[r]);
        if lo.is_nan() || hi.is_nan() || lo > hi || a.iter().any(|v| v.is_nan()) {
            return Err(LpError::Invalid);
        }
        let mut scale: f64 = 0.0;
        for (i, &ai) in a.iter().enumerate() {
            if ai != 0.0 {
                if k + i >= n {
                    return Err(LpError::Invalid);
                }
                scale = scale.max(libm::fabs(ai) * w.vs[k + i]);
            }
        }
        if scale == 0.0 {
            // A constant row: it holds or the problem is infeasible.
            if lo > 0.0 || hi < 0.0 {
                return Err(LpError::NotConverged);
            }
            continue;
        }
        w.rk[mm] = k as u32;
        for i in 0..3 {
            w.ra[mm][i] = if a[i] != 0.0 {
                a[i] * w.vs[k + i] / scale
            } else {
                0.0
            };
        }
        w.rlo[mm] = lo / scale;
        w.rhi[mm] = hi / scale;
        w.rscale[mm] = scale;
        mm += 1;
    }
    w.m = mm;
    let m = mm;
    // Every row spans three variables `k..k + 3` with its zeros, so the
    // loops over rows need no branch on a coefficient: a row whose last
    // coefficients are zero and lie past the last variable is moved back
    // (its nonzero ones lie before `n`). With fewer than three variables
    // the span reaches past them: those slots are held at zero.
    const { assert!(N >= 3, "an LpWork holds at least three variables") };
    for r in 0..m {
        while w.rk[r] as usize + 2 >= n && w.rk[r] > 0 {
            let a = w.ra[r];
            debug_assert_eq!(a[2], 0.0);
            w.ra[r] = [0.0, a[0], a[1]];
            w.rk[r] -= 1;
        }
    }
    for j in n..3 {
        (w.x[j], w.dx[j], w.rd[j], w.rhs[j]) = (0.0, 0.0, 0.0, 0.0);
    }
    // Start: inside the variable bounds, slacks and duals of unit size.
    for j in 0..n {
        let (lo, hi) = (w.vlo[j], w.vhi[j]);
        w.x[j] = match (lo.is_finite(), hi.is_finite()) {
            (true, true) => 0.5 * (lo + hi),
            (true, false) => lo + 1.0,
            (false, true) => hi - 1.0,
            (false, false) => 0.0,
        };
    }
    let start = Bound {
        s: 1.0,
        z: 1.0,
        ds: 0.0,
        dz: 0.0,
    };
    let absent = Bound::default();
    for j in 0..n {
        w.vu[j] = if w.vhi[j].is_finite() {
            Bound {
                s: (w.vhi[j] - w.x[j]).max(1.0),
                ..start
            }
        } else {
            absent
        };
        w.vl[j] = if w.vlo[j].is_finite() {
            Bound {
                s: (w.x[j] - w.vlo[j]).max(1.0),
                ..start
            }
        } else {
            absent
        };
    }
    for r in 0..m {
        let v = w.row_value(r);
        w.ru[r] = if w.rhi[r].is_finite() {
            Bound {
                s: (w.rhi[r] - v).max(1.0),
                ..start
            }
        } else {
            absent
        };
        w.rl[r] = if w.rlo[r].is_finite() {
            Bound {
                s: (v - w.rlo[r]).max(1.0),
                ..start
            }
        } else {
            absent
        };
    }
    let nb = {
        let mut c = 0usize;
        for j in 0..n {
            c += usize::from(w.vhi[j].is_finite()) + usize::from(w.vlo[j].is_finite());
        }
        for r in 0..m {
            c += usize::from(w.rhi[r].is_finite()) + usize::from(w.rlo[r].is_finite());
        }
        c.max(1)
    } as f64;

    let mut iterations = 0;
    let (mut best, mut since_best) = (f64::INFINITY, 0);
    loop {
        // Dual residual of min −c·x: r_d = −c + Σ a (z_u − z_l) + (z_vu − z_vl).
        for j in 0..n {
            w.rd[j] = -w.c[j] + w.vu[j].z - w.vl[j].z + pull_gradient(w, j, opts.pull);
        }
        let mut rp_max: f64 = 0.0;
        let mut sz = 0.0;
        for r in 0..m {
            let k = w.rk[r] as usize;
            let dz = w.ru[r].z - w.rl[r].z;
            let a = &w.ra[r];
            for (rd, ai) in w.rd[k..k + 3].iter_mut().zip(a) {
                *rd += ai * dz;
            }
            let v = w.row_value(r);
            w.rv[r] = v;
            if w.rhi[r].is_finite() {
                rp_max = rp_max.max(libm::fabs(v + w.ru[r].s - w.rhi[r]));
                sz += w.ru[r].s * w.ru[r].z;
            }
            if w.rlo[r].is_finite() {
                rp_max = rp_max.max(libm::fabs(-v + w.rl[r].s + w.rlo[r]));
                sz += w.rl[r].s * w.rl[r].z;
            }
        }
        for j in 0..n {
            if w.vhi[j].is_finite() {
                rp_max = rp_max.max(libm::fabs(w.x[j] + w.vu[j].s - w.vhi[j]));
                sz += w.vu[j].s * w.vu[j].z;
            }
            if w.vlo[j].is_finite() {
                rp_max = rp_max.max(libm::fabs(-w.x[j] + w.vl[j].s + w.vlo[j]));
                sz += w.vl[j].s * w.vl[j].z;
            }
        }
        let rd_max = w.rd[..n].iter().fold(0.0f64, |a, &v| a.max(libm::fabs(v)));
        let mu = sz / nb;
        w.residuals = (rp_max, rd_max, mu);
        let worst = rp_max.max(rd_max).max(mu);
        // (f64::max skips NaN: look at each, and at the iterate itself.)
        let finite = rp_max.is_finite()
            && rd_max.is_finite()
            && mu.is_finite()
            && w.x[..n].iter().all(|v| v.is_finite());
        if !finite {
            // Fallen apart on round-off: the best iterate, if close enough.
            if best <= ACCEPTABLE {
                let (xb, xc) = (&w.xbest[..n], &mut w.x[..n]);
                xc.copy_from_slice(xb);
                break;
            }
            return Err(LpError::NotConverged);
        }
        if worst <= opts.tolerance {
            break;
        }
        // Primal feasible and complementary: the plan is right. Near the
        // optimum of a degenerate problem the normal matrix loses the dual
        // residual's last digits; more iterations only make it worse.
        if rp_max <= opts.tolerance && mu <= opts.tolerance && rd_max <= DUAL_FLOOR {
            break;
        }
        // Round-off puts a floor under the residuals of an ill-conditioned
        // problem, and past it the iteration can fall apart (steps collapse,
        // duals blow up): keep the best iterate, and stop with it when the
        // residuals no longer fall or grow again, if it is close enough.
        if worst < best {
            if worst < 0.5 * best {
                since_best = 0;
            }
            best = worst;
            w.xbest[..n].copy_from_slice(&w.x[..n]);
        } else {
            since_best += 1;
        }
        let diverging = worst > DIVERGENCE * best;
        if iterations >= opts.max_iter || since_best >= STALL_ITERATIONS || diverging {
            if best <= ACCEPTABLE {
                let (xb, xc) = (&w.xbest[..n], &mut w.x[..n]);
                xc.copy_from_slice(xb);
                break;
            }
            return Err(LpError::NotConverged);
        }
        iterations += 1;
        normal_matrix(w, n, m);
        if opts.pull > 0.0 {
            for j in 0..n {
                if w.vhi[j].is_finite() {
                    w.h0[j] += opts.pull;
                }
            }
        }
        factor(w, n);
        // Predictor (affine scaling): rc = −s·z.
        newton_direction(w, n, m, |b: &Bound| -b.s * b.z);
        let (ap, ad) = step_lengths(w, n, m, 1.0);
        let mut sz_aff = 0.0;
        for_each_bound(w, n, m, |b| {
            sz_aff += (b.s + ap * b.ds) * (b.z + ad * b.dz);
        });
        let mu_aff = sz_aff / nb;
        let sigma = {
            let r = mu_aff / mu;
            (r * r * r).clamp(0.0, 1.0)
        };
        // Keep the predictor's products for the corrector.
        for_each_bound_mut(w, n, m, |b| {
            // Stash Δs_aff·Δz_aff in `ds` (the corrector overwrites both).
            b.ds *= b.dz;
        });
        let target = sigma * mu;
        newton_direction(w, n, m, |b: &Bound| target - b.s * b.z - b.ds);
        let (ap, ad) = step_lengths(w, n, m, STEP_FRACTION);
        trace(Iteration {
            k: iterations,
            primal: rp_max,
            dual: rd_max,
            mu,
            step_primal: ap,
            step_dual: ad,
        });
        for j in 0..n {
            w.x[j] += ap * w.dx[j];
        }
        for_each_bound_mut(w, n, m, |b| {
            b.s += ap * b.ds;
            b.z += ad * b.dz;
        });
    }
    // Unscale, and measure the violation in the caller's units.
    for j in 0..n {
        x[j] = w.x[j] * w.vs[j];
    }
    let mut objective = 0.0;
    let mut max_violation: f64 = 0.0;
    for j in 0..n {
        objective += p.c[j] * x[j];
        max_violation = max_violation.max(p.lo[j] - x[j]).max(x[j] - p.hi[j]);
    }
    for r in 0..m {
        let v = w.row_value(r);
        let viol = (w.rlo[r] - v).max(v - w.rhi[r]);
        max_violation = max_violation.max(viol * w.rscale[r]);
    }
    Ok(LpStats {
        iterations,
        objective,
        max_violation: max_violation.max(0.0),
    })
}

/// Iterations without halving the worst residual after which the
/// iteration stops (stalled on round-off).
const STALL_ITERATIONS: u32 = 25;

/// Dual residual accepted once the primal residual and the complementarity
/// are at the tolerance (the objective is then within this of optimal, relative).
const DUAL_FLOOR: f64 = 1e-2;

/// Worst scaled residual accepted from a stalled iteration (the caller
/// checks the violation in its own units, [`LpStats::max_violation`]).
const ACCEPTABLE: f64 = 1e-6;

/// Growth of the worst residual over the best one that counts as falling apart.
const DIVERGENCE: f64 = 1e3;

/// Fraction of the largest step to the boundary taken by the corrector.
const STEP_FRACTION: f64 = 0.995;

fn for_each_bound<const N: usize, const M: usize>(
    w: &LpWork<N, M>,
    n: usize,
    m: usize,
    mut f: impl FnMut(&Bound),
) {
    for j in 0..n {
        if w.vhi[j].is_finite() {
            f(&w.vu[j]);
        }
        if w.vlo[j].is_finite() {
            f(&w.vl[j]);
        }
    }
    for r in 0..m {
        if w.rhi[r].is_finite() {
            f(&w.ru[r]);
        }
        if w.rlo[r].is_finite() {
            f(&w.rl[r]);
        }
    }
}

fn for_each_bound_mut<const N: usize, const M: usize>(
    w: &mut LpWork<N, M>,
    n: usize,
    m: usize,
    mut f: impl FnMut(&mut Bound),
) {
    for j in 0..n {
        if w.vhi[j].is_finite() {
            f(&mut w.vu[j]);
        }
        if w.vlo[j].is_finite() {
            f(&mut w.vl[j]);
        }
    }
    for r in 0..m {
        if w.rhi[r].is_finite() {
            f(&mut w.ru[r]);
        }
        if w.rlo[r].is_finite() {
            f(&mut w.rl[r]);
        }
    }
}

/// Gradient of the pull term (see [`LpOptions::pull`]) for variable `j`.
#[inline]
fn pull_gradient<const N: usize, const M: usize>(w: &LpWork<N, M>, j: usize, pull: f64) -> f64 {
    if pull > 0.0 && w.vhi[j].is_finite() {
        pull * (w.x[j] - w.vhi[j])
    } else {
        0.0
    }
}

/// `H = Σ_rows (z_u/s_u + z_l/s_l)·a·aᵀ + diag(z_vu/s_vu + z_vl/s_vl)`, banded.
fn normal_matrix<const N: usize, const M: usize>(w: &mut LpWork<N, M>, n: usize, m: usize) {
    for j in 0..n {
        let mut d = 0.0;
        if w.vhi[j].is_finite() {
            d += w.vu[j].z / w.vu[j].s;
        }
        if w.vlo[j].is_finite() {
            d += w.vl[j].z / w.vl[j].s;
        }
        w.h0[j] = d;
        w.h1[j] = 0.0;
        w.h2[j] = 0.0;
    }
    for r in 0..m {
        let mut d = 0.0;
        if w.rhi[r].is_finite() {
            d += w.ru[r].z / w.ru[r].s;
        }
        if w.rlo[r].is_finite() {
            d += w.rl[r].z / w.rl[r].s;
        }
        // (The span's zeros add `±0`; past the last variable, slots no
        // one reads.)
        let k = w.rk[r] as usize;
        let a = w.ra[r];
        w.h0[k] += d * a[0] * a[0];
        w.h0[k + 1] += d * a[1] * a[1];
        w.h0[k + 2] += d * a[2] * a[2];
        w.h1[k] += d * a[0] * a[1];
        w.h1[k + 1] += d * a[1] * a[2];
        w.h2[k] += d * a[0] * a[2];
    }
}

/// In-place LDLᵀ of the pentadiagonal `H`: `h0` becomes D, `h1`/`h2` the
/// first and second subdiagonals of L. A vanishing pivot is regularised.
fn factor<const N: usize, const M: usize>(w: &mut LpWork<N, M>, n: usize) {
    let scale = w.h0[..n].iter().fold(0.0f64, |a, &v| a.max(v));
    let tiny = 1e-14 * scale.max(1e-300);
    for j in 0..n {
        let mut d = w.h0[j];
        if j >= 1 {
            d -= w.h1[j - 1] * w.h1[j - 1] * w.h0[j - 1];
        }
        if j >= 2 {
            d -= w.h2[j - 2] * w.h2[j - 2] * w.h0[j - 2];
        }
        if !(d > tiny) {
            d = tiny;
        }
        w.h0[j] = d;
        // l1[j] = (H[j+1][j] − l2[j−1]·D[j−1]·l1[j−1]) / D[j]
        if j + 1 < n {
            let mut e = w.h1[j];
            if j >= 1 {
                e -= w.h2[j - 1] * w.h0[j - 1] * w.h1[j - 1];
            }
            w.h1[j] = e / d;
        }
        if j + 2 < n {
            w.h2[j] /= d;
        }
    }
}

/// Solve `LDLᵀ·dx = rhs` (factors from [`factor`]).
fn back_substitute<const N: usize, const M: usize>(w: &mut LpWork<N, M>, n: usize) {
    for j in 0..n {
        let mut y = w.rhs[j];
        if j >= 1 {
            y -= w.h1[j - 1] * w.dx[j - 1];
        }
        if j >= 2 {
            y -= w.h2[j - 2] * w.dx[j - 2];
        }
        w.dx[j] = y;
    }
    for j in 0..n {
        w.dx[j] /= w.h0[j];
    }
    for j in (0..n).rev() {
        let mut v = w.dx[j];
        if j + 1 < n {
            v -= w.h1[j] * w.dx[j + 1];
        }
        if j + 2 < n {
            v -= w.h2[j] * w.dx[j + 2];
        }
        w.dx[j] = v;
    }
}

/// The Newton direction for complementarity targets `rc(b)` (`z·Δs + s·Δz =
/// rc`): `H·Δx = −r_d − Σ σ·a·(rc + z·r)/s`, then `Δs = −r − σ·aᵀΔx`,
/// `Δz = (rc − z·Δs)/s` for every bound (σ = +1 upper, −1 lower).
fn newton_direction<const N: usize, const M: usize>(
    w: &mut LpWork<N, M>,
    n: usize,
    m: usize,
    rc: impl Fn(&Bound) -> f64,
) {
    for j in 0..n {
        let mut v = -w.rd[j];
        if w.vhi[j].is_finite() {
            let b = &w.vu[j];
            let r = w.x[j] + b.s - w.vhi[j];
            v -= (rc(b) + b.z * r) / b.s;
        }
        if w.vlo[j].is_finite() {
            let b = &w.vl[j];
            let r = -w.x[j] + b.s + w.vlo[j];
            v += (rc(b) + b.z * r) / b.s;
        }
        w.rhs[j] = v;
    }
    for r in 0..m {
        let mut t = 0.0;
        let rv = w.rv[r];
        if w.rhi[r].is_finite() {
            let b = &w.ru[r];
            let res = rv + b.s - w.rhi[r];
            t -= (rc(b) + b.z * res) / b.s;
        }
        if w.rlo[r].is_finite() {
            let b = &w.rl[r];
            let res = -rv + b.s + w.rlo[r];
            t += (rc(b) + b.z * res) / b.s;
        }
        let k = w.rk[r] as usize;
        for (rhs, ai) in w.rhs[k..k + 3].iter_mut().zip(&w.ra[r]) {
            *rhs += ai * t;
        }
    }
    back_substitute(w, n);
    for j in 0..n {
        let dx = w.dx[j];
        if w.vhi[j].is_finite() {
            let r = w.x[j] + w.vu[j].s - w.vhi[j];
            let c = rc(&w.vu[j]);
            let b = &mut w.vu[j];
            b.ds = -r - dx;
            b.dz = (c - b.z * b.ds) / b.s;
        }
        if w.vlo[j].is_finite() {
            let r = -w.x[j] + w.vl[j].s + w.vlo[j];
            let c = rc(&w.vl[j]);
            let b = &mut w.vl[j];
            b.ds = -r + dx;
            b.dz = (c - b.z * b.ds) / b.s;
        }
    }
    for r in 0..m {
        let k = w.rk[r] as usize;
        let (a, dx) = (&w.ra[r], &w.dx[k..k + 3]);
        let mut adx = 0.0;
        adx += a[0] * dx[0];
        adx += a[1] * dx[1];
        adx += a[2] * dx[2];
        let rv = w.rv[r];
        if w.rhi[r].is_finite() {
            let res = rv + w.ru[r].s - w.rhi[r];
            let c = rc(&w.ru[r]);
            let b = &mut w.ru[r];
            b.ds = -res - adx;
            b.dz = (c - b.z * b.ds) / b.s;
        }
        if w.rlo[r].is_finite() {
            let res = -rv + w.rl[r].s + w.rlo[r];
            let c = rc(&w.rl[r]);
            let b = &mut w.rl[r];
            b.ds = -res + adx;
            b.dz = (c - b.z * b.ds) / b.s;
        }
    }
}

/// Largest primal and dual steps (≤ 1) keeping slacks and duals positive,
/// times `fraction`.
fn step_lengths<const N: usize, const M: usize>(
    w: &LpWork<N, M>,
    n: usize,
    m: usize,
    fraction: f64,
) -> (f64, f64) {
    let (mut ap, mut ad) = (1.0f64, 1.0f64);
    for_each_bound(w, n, m, |b| {
        if b.ds < 0.0 {
            ap = ap.min(-b.s / b.ds);
        }
        if b.dz < 0.0 {
            ad = ad.min(-b.z / b.dz);
        }
    });
    ((ap * fraction).min(1.0), (ad * fraction).min(1.0))
}

#[cfg(test)]
mod tests {
    extern crate alloc;
    use super::*;
    use alloc::boxed::Box;
    use alloc::vec::Vec;

    type Work = LpWork<512, 4096>;

    /// Maximise Σ b subject to b ≤ U and |b_{k+1} − b_k| ≤ δ: the forward and
    /// backward passes of the acceleration-only schedule give the optimum.
    #[test]
    fn slope_limited_maximum_equals_the_forward_backward_passes() {
        let mut seed = 0x9e37_79b9_7f4a_7c15u64;
        let mut rnd = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut w: Box<Work> = Box::default();
        for case in 0..20 {
            let n = 5 + (rnd() * 200.0) as usize;
            let delta = 0.5 + rnd() * 20.0;
            let u: Vec<f64> = (0..n)
                .map(|_| {
                    if rnd() < 0.1 {
                        rnd() * 5.0
                    } else {
                        10.0 + rnd() * 900.0
                    }
                })
                .collect();
            let mut want = u.clone();
            want[0] = 0.0;
            want[n - 1] = 0.0;
            for k in 1..n {
                want[k] = want[k].min(want[k - 1] + delta);
            }
            for k in (0..n - 1).rev() {
                want[k] = want[k].min(want[k + 1] + delta);
            }
            let mut hi = u.clone();
            hi[0] = 0.0;
            hi[n - 1] = 0.0;
            let lo = alloc::vec![0.0; n];
            let c = alloc::vec![1.0; n];
            let rows: Vec<Row> = (0..n - 1)
                .map(|k| Row {
                    k: k as u32,
                    a: [-1.0, 1.0, 0.0],
                    lo: -delta,
                    hi: delta,
                })
                .collect();
            let mut x = alloc::vec![0.0; n];
            w.clear_rows();
            for r in &rows {
                assert!(w.push_row(*r));
            }
            let p = Problem {
                c: &c,
                lo: &lo,
                hi: &hi,
            };
            let st = solve(&p, &LpOptions::default(), &mut w, &mut x).unwrap();
            assert!(st.max_violation <= 1e-6, "case {case}: {st:?}");
            for k in 0..n {
                assert!(
                    (x[k] - want[k]).abs() <= 1e-5 * (1.0 + want[k]),
                    "case {case} k={k}: {} vs {}",
                    x[k],
                    want[k]
                );
            }
        }
    }

    /// A second-difference (curvature) bound: the optimum of maximising Σ x
    /// under `x ≤ U` with `x_{k−1} − 2x_k + x_{k+1} ≥ −c` and zero ends is
    /// the largest function below U whose second difference is at least −c:
    /// check optimality against every feasible perturbation direction by
    /// verifying feasibility and that no single coordinate can be raised.
    #[test]
    fn curvature_bounded_solution_is_feasible_and_maximal_per_coordinate() {
        let n = 60;
        let u: Vec<f64> = (0..n)
            .map(|k| 50.0 + 40.0 * libm::sin(k as f64 * 0.3))
            .collect();
        let c = 3.0;
        let mut hi = u.clone();
        hi[0] = 0.0;
        hi[n - 1] = 0.0;
        let lo = alloc::vec![0.0; n];
        let obj = alloc::vec![1.0; n];
        let rows: Vec<Row> = (0..n - 2)
            .map(|k| Row {
                k: k as u32,
                a: [1.0, -2.0, 1.0],
                lo: -c,
                hi: f64::INFINITY,
            })
            .collect();
        let mut w: Box<Work> = Box::default();
        let mut x = alloc::vec![0.0; n];
        for r in &rows {
            assert!(w.push_row(*r));
        }
        let p = Problem {
            c: &obj,
            lo: &lo,
            hi: &hi,
        };
        let st = solve(&p, &LpOptions::default(), &mut w, &mut x).unwrap();
        assert!(st.max_violation <= 1e-6, "{st:?}");
        // This constraint set is closed under the componentwise maximum, so the
        // optimum is the greatest feasible point: iterating x_k ← min(U_k,
        // (x_{k−1} + x_{k+1} + c)/2) from above converges to it.
        let mut g = hi.clone();
        for _ in 0..200_000 {
            let mut changed = false;
            for k in 1..n - 1 {
                let v = g[k].min(0.5 * (g[k - 1] + g[k + 1] + c));
                if v < g[k] {
                    g[k] = v;
                    changed = true;
                }
            }
            if !changed {
                break;
            }
        }
        for k in 0..n {
            assert!(
                (x[k] - g[k]).abs() <= 1e-4 * (1.0 + g[k]),
                "k={k}: {} vs {}",
                x[k],
                g[k]
            );
        }
    }

    #[test]
    fn infeasible_and_malformed_problems_are_refused() {
        let mut w: Box<LpWork<8, 8>> = Box::default();
        let mut x = [0.0; 2];
        // x0 + x1 ≥ 5 with both in [0, 1].
        let rows = [Row {
            k: 0,
            a: [1.0, 1.0, 0.0],
            lo: 5.0,
            hi: f64::INFINITY,
        }];
        assert!(w.push_row(rows[0]));
        let p = Problem {
            c: &[1.0, 1.0],
            lo: &[0.0, 0.0],
            hi: &[1.0, 1.0],
        };
        assert_eq!(
            solve(&p, &LpOptions::default(), &mut w, &mut x),
            Err(LpError::NotConverged)
        );
        w.clear_rows();
        let p = Problem {
            c: &[1.0, f64::NAN],
            lo: &[0.0, 0.0],
            hi: &[1.0, 1.0],
        };
        assert_eq!(
            solve(&p, &LpOptions::default(), &mut w, &mut x),
            Err(LpError::Invalid)
        );
        let mut big = [0.0; 9];
        let p = Problem {
            c: &[1.0; 9],
            lo: &[0.0; 9],
            hi: &[1.0; 9],
        };
        assert_eq!(
            solve(&p, &LpOptions::default(), &mut w, &mut big),
            Err(LpError::Capacity)
        );
    }

    /// Rows at the last variables (their three-wide span moved back inside
    /// the problem) and problems of one and two variables (the span's slots
    /// past them held at zero, whatever the scratch held) solve to their
    /// optimum.
    #[test]
    fn rows_at_the_last_variables_and_tiny_problems_solve() {
        let mut w: Box<LpWork<8, 8>> = Box::default();
        for n in 1..=5usize {
            (w.x, w.dx, w.rd, w.rhs) = ([f64::NAN; 8], [f64::NAN; 8], [f64::NAN; 8], [f64::NAN; 8]);
            w.clear_rows();
            // Maximise Σ c·x, x in [0, 10], the last x ≤ 2 and the last two ≤ 7 together.
            let free = f64::NEG_INFINITY;
            assert!(w.push_row(Row {
                k: n as u32 - 1,
                a: [1.0, 0.0, 0.0],
                lo: free,
                hi: 2.0
            }));
            if n >= 2 {
                assert!(w.push_row(Row {
                    k: n as u32 - 2,
                    a: [1.0, 1.0, 0.0],
                    lo: free,
                    hi: 7.0
                }));
            }
            // (The last one counts twice: one optimum.)
            let (mut c, lo, hi) = ([1.0; 5], [0.0; 5], [10.0; 5]);
            c[n - 1] = 2.0;
            let p = Problem {
                c: &c[..n],
                lo: &lo[..n],
                hi: &hi[..n],
            };
            let mut x = [0.0; 5];
            let st = solve(&p, &LpOptions::default(), &mut w, &mut x[..n]).unwrap();
            let best = if n == 1 {
                4.0
            } else {
                9.0 + 10.0 * (n - 2) as f64
            };
            assert!(
                (st.objective - best).abs() < 1e-6,
                "{n} variables: {st:?} {x:?}"
            );
            assert!((x[n - 1] - 2.0).abs() < 1e-6, "{n} variables: {x:?}");
        }
    }
}
