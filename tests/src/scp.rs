//! A feasible near time-optimal jerk-limited reference schedule (issue 15),
//! by sequential linear programming in the pseudo-jerk form (Fan et al.;
//! Ji et al. solve the same problem by sequential convex programming).
//!
//! The unknowns are `S_k = v²` on a uniform arc-length grid of step `h`.
//! Speed laws, tangential and per-axis acceleration are linear in `S`
//! (`a = S'/2`, axis acceleration `C_ss,i·S + t_i·S'/2`). The jerks are `v`
//! times a linear form, `v·S''/2` and `v·(C_sss,i·S + 1.5·C_ss,i·S' +
//! 0.5·t_i·S'')`, so a jerk limit is `|F(S)| ≤ J/√S`. The right side is
//! convex in `S`: its tangent at the last iterate, `J/r − J·(S − S_prev)/(2r³)`
//! with `r = √S_prev`, lies below it, and the linear program that holds `F`
//! to the tangent holds the true limit (a convex-concave step). So every
//! iterate is feasible, and the last one is feasible for the next program.
//! Each program minimises the time's linearisation; the next iterate is the
//! fastest point between the last and the program's solution (both
//! feasible for it, so is the segment), so the time never grows. The first
//! linearises around the acceleration-only profile.
//!
//! Laws are those of [`crate::path_time::accel_only_optimum`] (no planning
//! margin), each node's cap the lowest of the 5 µm samples within a step of
//! it; junctions and C1 knots keep the planner's own junction speed
//! (`feed::junction_speed`, no margin: the curvature step's share of the
//! axis jerk) at their nearest node, stops are the planner's, and the
//! ramps from and to each rest cap the nodes near it. Derivatives are
//! finite differences on the grid, the schedule continuous in time: no
//! tick rounding, no sampled differences. "Feasible" is to that
//! discretisation: on a line it comes out 0.5–2 % above the seven-phase
//! optimum (the test below).

use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettingsBuilder, DefaultSolver, IPSolver, NonnegativeConeT, SolverStatus,
};
use interp_core::InterpConfig;
use interp_core::feed::{ArcLengthDerivs, junction_speed, speed_limit};
use interp_core::geom::{Curve, Derivs};
use interp_core::path::Block;

use crate::path_time::{
    GridNode, joint_marks, reach, real_limits, reference_laws, stops_after, walk_grid,
};

/// The reference's path time, s, after each linear program (the first
/// entry is the first feasible iterate; the last the reference).
#[derive(Debug, Clone)]
pub struct ScpReference {
    /// Path time of each iterate, s.
    pub times: Vec<f64>,
    /// Grid nodes.
    pub nodes: usize,
    /// The grid's step, mm.
    pub step: f64,
    /// The last iterate's speed at each node, mm/s.
    pub speeds: Vec<f64>,
}

/// The speed below which a node's jerk rows are linearised as at this
/// speed, mm/s.
const MIN_SPEED: f64 = 1e-3;

/// The speed below which the objective's weight of a node is that of this
/// speed, mm/s.
const WEIGHT_SPEED: f64 = 2.0;

/// One sample of the path on the fine grid.
#[derive(Clone, Copy)]
struct Sample {
    s: f64,
    cap: f64,
    d: Option<ArcLengthDerivs>,
    /// A rest (a stop or a cusp): a point constraint, not a law.
    rest: bool,
    /// A junction or a knot: its cap holds at its nearest node alone (the
    /// planner holds it over two ticks' travel, far less than a step).
    point: bool,
}

/// The reference schedule of `blocks` with the limits of `cfg` on a grid
/// of `step` mm, after at most `iterations` linear programs (it stops
/// earlier once an iterate gains under 1e-5 of the time).
pub fn scp_reference(
    blocks: &[Block],
    cfg: &InterpConfig,
    step: f64,
    iterations: usize,
) -> Result<ScpReference, String> {
    let samples = sample(blocks, cfg);
    let total = samples.last().map_or(0.0, |x| x.s);
    let n = ((total / step).ceil() as usize).max(2) + 1;
    let h = total / (n - 1) as f64;
    // Each node: the lowest cap within a step, the nearest sample's
    // derivatives; rests at their nearest node.
    let mut cap = vec![f64::INFINITY; n];
    let mut geo: Vec<Option<ArcLengthDerivs>> = vec![None; n];
    let mut best = vec![f64::INFINITY; n];
    for x in &samples {
        let k = x.s / h;
        let near = (k.round() as usize).min(n - 1);
        if x.rest {
            cap[near] = 0.0;
            continue;
        }
        if x.point {
            cap[near] = cap[near].min(x.cap);
            continue;
        }
        let lo = (k.floor() as usize).saturating_sub(1).min(n - 1);
        let hi = ((k.ceil() as usize) + 1).min(n - 1);
        for c in &mut cap[lo..=hi] {
            *c = c.min(x.cap);
        }
        let dist = (x.s - near as f64 * h).abs();
        if x.d.is_some() && dist < best[near] {
            best[near] = dist;
            geo[near] = x.d;
        }
    }
    cap[0] = 0.0;
    cap[n - 1] = 0.0;
    // The ramps from and to each rest, as caps: the grid's differences do
    // not see that the acceleration starts from zero there (on a line the
    // programs came out 5 % under the seven-phase time without them).
    let (a, jt) = (cfg.max_path_accel, cfg.max_path_jerk);
    let ramp = |d: f64| reach(0.0, f64::INFINITY, d, f64::INFINITY, a, jt);
    let mut last = 0.0;
    for k in 0..n {
        if cap[k] == 0.0 {
            last = k as f64 * h;
        }
        cap[k] = cap[k].min(ramp(k as f64 * h - last));
    }
    let mut next = (n - 1) as f64 * h;
    for k in (0..n).rev() {
        if cap[k] == 0.0 {
            next = k as f64 * h;
        }
        cap[k] = cap[k].min(ramp(next - k as f64 * h));
    }
    // The acceleration-only profile on this grid: the first linearisation.
    let mut v: Vec<f64> = cap.iter().map(|c| c.min(cfg.max_path_speed)).collect();
    for k in 1..n {
        v[k] = v[k].min((v[k - 1] * v[k - 1] + 2.0 * a * h).sqrt());
    }
    for k in (0..n - 1).rev() {
        v[k] = v[k].min((v[k + 1] * v[k + 1] + 2.0 * a * h).sqrt());
    }
    let mut prev: Vec<f64> = v.iter().map(|x| x * x).collect();
    let mut times = Vec::new();
    for it in 0..iterations {
        let mut next = match solve(&prev, &cap, &geo, h, cfg) {
            Ok(x) => x,
            // A later program that the solver cannot finish leaves the last
            // iterate (feasible) as the reference.
            Err(_) if it > 0 => break,
            Err(e) => return Err(e),
        };
        if it > 0 {
            // Both ends are feasible for this program (the last iterate
            // and its solution), so is the segment between them: the time,
            // convex along it, at its minimum there.
            let at = |th: f64| -> Vec<f64> {
                prev.iter()
                    .zip(&next)
                    .map(|(p, x)| p + th * (x - p))
                    .collect()
            };
            let (mut lo, mut hi) = (0.0f64, 1.0f64);
            let g = 0.5 * (5f64.sqrt() - 1.0);
            for _ in 0..40 {
                let (a, b) = (hi - g * (hi - lo), lo + g * (hi - lo));
                if path_time(&at(a), h) <= path_time(&at(b), h) {
                    hi = b;
                } else {
                    lo = a;
                }
            }
            let th = 0.5 * (lo + hi);
            if path_time(&at(th), h) < path_time(&prev, h) {
                next = at(th);
            } else {
                next = prev.clone();
            }
        }
        let t = path_time(&next, h);
        let done = times
            .last()
            .is_some_and(|&last: &f64| (last - t).abs() < 1e-5 * t);
        times.push(t);
        prev = next;
        if done {
            break;
        }
    }
    Ok(ScpReference {
        times,
        nodes: n,
        step: h,
        speeds: prev.iter().map(|x| x.max(0.0).sqrt()).collect(),
    })
}

/// How the reference's setpoints would use the jerk limits
/// ([`sampled_jerk_use`]).
#[derive(Debug, Clone, Copy)]
pub struct SampledUse {
    /// The largest path or axis jerk (third difference of the setpoints)
    /// as a share of its limit.
    pub largest: f64,
    /// Where, mm along the path.
    pub at: f64,
    /// Ticks over the limit, and ticks looked at.
    pub over: usize,
    pub ticks: usize,
}

/// The reference sampled as the loop samples a plan: its speed profile
/// timed node to node, `s(t)` a natural cubic spline through the nodes'
/// times (C²: its jerk is piecewise constant, as a continuous schedule's
/// may be), a setpoint on `blocks` every period of `cfg`, and each
/// setpoint's third difference (the path's, each axis's) over its limit
/// in `cfg`. The reference holds its limits on its grid, in continuous
/// time; this is what a drive would see. Ticks within `edge` mm of either
/// end are left out: there the spline's natural ends are not the
/// reference's ramps from rest.
pub fn sampled_jerk_use(
    blocks: &[Block],
    cfg: &InterpConfig,
    r: &ScpReference,
    edge: f64,
) -> SampledUse {
    let (v, h) = (&r.speeds, r.step);
    let n = v.len();
    let node_s = |k: usize| k as f64 * h;
    // Node times, as `path_time` counts them.
    let mut t = vec![0.0; n];
    for k in 1..n {
        t[k] = t[k - 1] + step_time(v[k - 1], v[k], h);
    }
    // Second derivatives of the natural spline (tridiagonal, Thomas).
    let mut m = vec![0.0; n];
    let (mut c, mut d) = (vec![0.0; n], vec![0.0; n]);
    for i in 1..n - 1 {
        let (h0, h1) = (t[i] - t[i - 1], t[i + 1] - t[i]);
        let rhs = (node_s(i + 1) - node_s(i)) / h1 - (node_s(i) - node_s(i - 1)) / h0;
        let den = (h0 + h1) / 3.0 - h0 / 6.0 * c[i - 1];
        c[i] = h1 / 6.0 / den;
        d[i] = (rhs - h0 / 6.0 * d[i - 1]) / den;
    }
    for i in (1..n - 1).rev() {
        m[i] = d[i] - c[i] * m[i + 1];
    }
    let total = node_s(n - 1);
    let mut starts = vec![0.0];
    for b in blocks {
        starts.push(starts[starts.len() - 1] + b.path.length());
    }
    let position = |s: f64| {
        let i = starts[1..]
            .partition_point(|&x| x < s)
            .min(blocks.len() - 1);
        let path = &blocks[i].path;
        let along = (s - starts[i]).clamp(0.0, path.length());
        path.eval(path.param_at_arc_length(path.u_start(), along), 0)
            .p
    };
    let ts = cfg.period;
    let mut out = SampledUse {
        largest: 0.0,
        at: 0.0,
        over: 0,
        ticks: 0,
    };
    let mut last: Vec<(f64, interp_core::Vec3)> = Vec::with_capacity(4);
    let mut k = 0;
    let ticks = (t[n - 1] / ts).ceil() as usize;
    for i in 0..=ticks {
        let at = (i as f64 * ts).min(t[n - 1]);
        while k + 2 < n && t[k + 1] < at {
            k += 1;
        }
        let hk = t[k + 1] - t[k];
        let (a, b) = ((t[k + 1] - at) / hk, (at - t[k]) / hk);
        let s = a * node_s(k)
            + b * node_s(k + 1)
            + ((a * a * a - a) * m[k] + (b * b * b - b) * m[k + 1]) * hk * hk / 6.0;
        if last.len() == 4 {
            last.remove(0);
        }
        last.push((s, position(s)));
        if last.len() < 4 || s < edge || s > total - edge {
            continue;
        }
        let third = |f: &dyn Fn(usize) -> f64| {
            (f(3) - 3.0 * f(2) + 3.0 * f(1) - f(0)).abs() / (ts * ts * ts)
        };
        let mut used = third(&|j| last[j].0) / cfg.max_path_jerk;
        for ax in 0..3 {
            used = used.max(third(&|j| last[j].1[ax]) / cfg.axis_max_jerk[ax]);
        }
        out.ticks += 1;
        out.over += usize::from(used > 1.0);
        if used > out.largest {
            out.largest = used;
            out.at = s;
        }
    }
    out
}

/// Time of the profile `S` on a grid of step `h`: the sum of its steps'
/// [`step_time`].
fn path_time(s: &[f64], h: f64) -> f64 {
    s.windows(2)
        .map(|w| step_time(w[0].max(0.0).sqrt(), w[1].max(0.0).sqrt(), h))
        .sum()
}

/// Time of a step `h` of the grid between nodes at speeds `a` and `b`:
/// `2h/(a + b)`, but `3h/v` next to a rest (from rest the speed grows like
/// `s^⅔` at most, and the trapezoid would count a third less).
fn step_time(a: f64, b: f64, h: f64) -> f64 {
    if a == 0.0 || b == 0.0 {
        if a + b > 0.0 { 3.0 * h / (a + b) } else { 0.0 }
    } else {
        2.0 * h / (a + b)
    }
}

/// The laws on the optimum's 5 µm grid, with the planner's junctions.
fn sample(blocks: &[Block], cfg: &InterpConfig) -> Vec<Sample> {
    let laws = reference_laws(cfg);
    let real = real_limits(cfg);
    let mut out = vec![Sample {
        s: 0.0,
        cap: 0.0,
        d: None,
        rest: true,
        point: true,
    }];
    let mut s0 = 0.0;
    for (i, b) in blocks.iter().enumerate() {
        let path = &b.path;
        if i > 0 {
            let prev = &blocks[i - 1].path;
            let (l, r) = (prev.eval(prev.u_end(), 3), path.eval(path.u_start(), 3));
            let rest = stops_after(blocks, i - 1, cfg);
            let v = if rest {
                0.0
            } else {
                junction_speed(&l, &r, &real)
            };
            out.push(Sample {
                s: s0,
                cap: v,
                d: None,
                rest,
                point: true,
            });
        }
        let limit = |d: &Derivs| speed_limit(d, b.feed, b.mrr.as_ref(), &laws);
        let marks = joint_marks(path, &real, limit, |l, r| junction_speed(l, r, &real));
        let mut s = s0;
        s0 += walk_grid(path, &marks, |ds, node| {
            s += ds;
            out.push(match node {
                GridNode::Joint(c) => Sample {
                    s,
                    cap: c,
                    d: None,
                    rest: c == 0.0,
                    point: true,
                },
                GridNode::Node(d) => Sample {
                    s,
                    cap: limit(&d),
                    d: ArcLengthDerivs::new(&d),
                    rest: false,
                    point: false,
                },
            });
        });
    }
    out
}

/// Rows `A·S ≤ b` of one linear program, built as triplets.
struct Rows {
    i: Vec<usize>,
    j: Vec<usize>,
    v: Vec<f64>,
    b: Vec<f64>,
}

impl Rows {
    /// `±Σ c·S + w·S_k ≤ lim`, as two rows (a jerk row: `w·S_k` is the
    /// tangent's slope).
    fn jerk(&mut self, terms: &[(usize, f64)], k: usize, w: f64, lim: f64) {
        for sign in [1.0, -1.0] {
            let r = self.b.len();
            for &(j, c) in terms {
                let c = sign * c + if j == k { w } else { 0.0 };
                if c != 0.0 {
                    self.i.push(r);
                    self.j.push(j);
                    self.v.push(c);
                }
            }
            self.b.push(lim);
        }
    }

    /// `−lim ≤ Σ c·S ≤ lim`, as two rows.
    fn within(&mut self, terms: &[(usize, f64)], lim: f64) {
        for sign in [1.0, -1.0] {
            let r = self.b.len();
            for &(j, c) in terms {
                if c != 0.0 {
                    self.i.push(r);
                    self.j.push(j);
                    self.v.push(sign * c);
                }
            }
            self.b.push(lim);
        }
    }
}

/// One linear program: the most time saved to first order within the
/// linearised limits.
fn solve(
    prev: &[f64],
    cap: &[f64],
    geo: &[Option<ArcLengthDerivs>],
    h: f64,
    cfg: &InterpConfig,
) -> Result<Vec<f64>, String> {
    let n = prev.len();
    let mut rows = Rows {
        i: Vec::new(),
        j: Vec::new(),
        v: Vec::new(),
        b: Vec::new(),
    };
    let (a, jt) = (cfg.max_path_accel, cfg.max_path_jerk);
    for k in 0..n {
        // 0 ≤ S_k ≤ cap².
        let top = cap[k] * cap[k];
        rows.i.push(rows.b.len());
        rows.j.push(k);
        rows.v.push(1.0);
        rows.b.push(top);
        rows.i.push(rows.b.len());
        rows.j.push(k);
        rows.v.push(-1.0);
        rows.b.push(0.0);
        if k + 1 < n {
            // Tangential acceleration S'/2.
            let c = 1.0 / (2.0 * h);
            rows.within(&[(k + 1, c), (k, -c)], a);
        }
        if k == 0 || k + 1 == n {
            continue;
        }
        // The tangent of J/√S at S_prev: J/r − J·(S − S_prev)/(2r³), as
        // `F + w·S_k ≤ 1.5·J/r` with `w = J/(2r³)` (a floor keeps a node
        // once at rest from dividing by zero: it may then grow threefold a
        // step).
        let r = prev[k].max(MIN_SPEED * MIN_SPEED).sqrt();
        let tangent = |lim: f64| (lim / (2.0 * r * r * r), 1.5 * lim / r);
        // S' and S'' by central differences, as coefficients of S.
        let d1 = [(k + 1, 0.5 / h), (k - 1, -0.5 / h)];
        let d2 = [
            (k + 1, 1.0 / (h * h)),
            (k, -2.0 / (h * h)),
            (k - 1, 1.0 / (h * h)),
        ];
        let (w, lim) = tangent(jt);
        let half = d2.map(|(j, c)| (j, 0.5 * c));
        rows.jerk(&half, k, w, lim);
        let Some(g) = geo[k] else {
            continue;
        };
        for i in 0..3 {
            let (t, css, csss) = (g.t[i], g.c_ss[i], g.c_sss[i]);
            rows.within(
                &[
                    (k, css),
                    (d1[0].0, 0.5 * t * d1[0].1),
                    (d1[1].0, 0.5 * t * d1[1].1),
                ],
                cfg.axis_max_accel[i],
            );
            // v·(C_sss·S + 1.5·C_ss·S' + 0.5·t·S''), S'' and S' merged per node.
            let mut terms = [(k - 1, 0.0), (k, 0.0), (k + 1, 0.0)];
            terms[1].1 += csss;
            terms[2].1 += 1.5 * css * d1[0].1;
            terms[0].1 += 1.5 * css * d1[1].1;
            for &(j, c) in &d2 {
                terms[j + 1 - k].1 += 0.5 * t * c;
            }
            let (w, lim) = tangent(cfg.axis_max_jerk[i]);
            rows.jerk(&terms, k, w, lim);
        }
    }
    let m = rows.b.len();
    let amat = CscMatrix::new_from_triplets(m, n, rows.i, rows.j, rows.v);
    let p = CscMatrix::<f64>::zeros((n, n));
    // Scaled so the objective is of order one.
    // The objective: the time's gradient at the last iterate (a larger
    // `S_k` saves `h/(r_k·(r_k + r_j)²)` for each neighbour `j`), scaled to
    // a largest weight of one.
    // (Below `WEIGHT_SPEED` the weight stops growing: near a rest it grows
    // like 1/v³ and would drown the rest of the path in the solver's
    // tolerance.)
    let r: Vec<f64> = prev.iter().map(|&x| x.sqrt().max(WEIGHT_SPEED)).collect();
    let mut q = vec![0.0; n];
    for k in 0..n - 1 {
        let c = h / ((r[k] + r[k + 1]) * (r[k] + r[k + 1]));
        q[k] -= c / r[k];
        q[k + 1] -= c / r[k + 1];
    }
    let scale = 1.0 / q.iter().fold(f64::MIN_POSITIVE, |m, &x| m.max(-x));
    for x in &mut q {
        *x *= scale;
    }
    let cones = [NonnegativeConeT(m)];
    let settings = DefaultSettingsBuilder::default()
        .verbose(false)
        .equilibrate_enable(true)
        .max_iter(200)
        .build()
        .map_err(|e| format!("{e:?}"))?;
    let mut solver = DefaultSolver::new(&p, &q, &amat, &rows.b, &cones, settings)
        .map_err(|e| format!("{e:?}"))?;
    solver.solve();
    match solver.solution.status {
        SolverStatus::Solved | SolverStatus::AlmostSolved => {}
        s => {
            return Err(format!(
                "linear program ({n} nodes, max S_prev {:.3e}): {s:?}",
                prev.iter().fold(0.0f64, |m, &x| m.max(x))
            ));
        }
    }
    // Interior-point solutions sit a hair inside or outside the bounds.
    Ok(solver
        .solution
        .x
        .iter()
        .enumerate()
        .map(|(k, &x)| x.clamp(0.0, cap[k] * cap[k]))
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::path_time::{jerk_aware_bound, rest_to_rest};
    use interp_core::geom::Vec3;
    use interp_core::path::{Line, Path};

    fn line(l: f64, feed: f64) -> Vec<Block> {
        let p = Path::Line(Line::new(Vec3::zeros(), Vec3::new(l, 0.0, 0.0)).unwrap());
        vec![Block::new(1, p, feed)]
    }

    #[test]
    fn on_a_line_the_reference_is_feasible_and_near_the_seven_phase_time() {
        // The seven-phase profile is the optimum of a line: a reference
        // below it would break a limit; far above it, it is no reference.
        let cfg = InterpConfig::default();
        for (l, f) in [(20.0, 100.0), (2.0, 100.0)] {
            let r =
                scp_reference(&line(l, f), &cfg, 0.02, 20).unwrap_or_else(|e| panic!("{l}: {e}"));
            let t = *r.times.last().unwrap();
            let want = rest_to_rest(l, f, cfg.max_path_accel, cfg.max_path_jerk);
            eprintln!(
                "{l} mm: reference {t} s, seven-phase {want} s, {:?}",
                r.times
            );
            assert!(t >= want * (1.0 - 1e-3), "{l} mm: {t} s below {want} s");
            assert!(t <= want * 1.05, "{l} mm: {t} s against {want} s");
            assert!(r.times.windows(2).all(|w| w[1] <= w[0]), "{:?}", r.times);
            assert!(jerk_aware_bound(&line(l, f), &cfg) <= t);
        }
    }

    #[test]
    fn sampled_every_tick_a_line_s_reference_uses_its_path_jerk() {
        // On a line the reference is near the seven-phase profile, which
        // runs at the path's jerk limit in its ramps: sampled as the loop
        // samples a plan, its third differences see that limit, and not
        // much more (the spline through the node times adds little).
        let cfg = InterpConfig::default();
        let blocks = line(20.0, 100.0);
        let r = scp_reference(&blocks, &cfg, 0.02, 20).unwrap();
        let used = sampled_jerk_use(&blocks, &cfg, &r, 1.0);
        eprintln!("{used:?}");
        assert!(used.ticks > 150, "{used:?}");
        assert!(used.largest > 0.9 && used.largest < 1.05, "{used:?}");
    }
}
