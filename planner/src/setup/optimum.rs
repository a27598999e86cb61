//! The search over tool axes (the paper's loop over the cells `C_i`) with a
//! certificate of optimality.
//!
//! The key of a tool axis (the least key of its placements, eq. 13 or 21)
//! can only grow when MD points are added: a placement that holds every MD
//! point holds any subset of them. So the key computed from the MD points of
//! a subset `S` of the classes is a **lower bound** of the tool axis's key,
//! and so is "no placement fits" for the fitting objective. The search:
//!
//! 1. evaluates exactly (every class, [`md_cells`] then the fan or rectangle
//!    search) the cells nearest those of a coarse sphere, and the cells
//!    that see every patch;
//! 2. puts into `S` the classes whose MD points bind the placements found
//!    (on a fan edge or at a fan's full tilt, on a rectangle edge);
//! 3. bounds every other cell from `S` (MD points found on each class's
//!    boundary cells, see [`Boundary`]), then evaluates exactly, least
//!    bound first, every cell whose bound does not rule it out, growing `S`
//!    and re-bounding as it goes.
//!
//! It stops when every cell is either evaluated exactly or bounded above the
//! threshold: above the best key for the objective not shown, and above the
//! best area plus the equivalence tolerance for the one shown, so that the
//! setups equivalent to the best are all known. The answer is then the least
//! over every cell (ties to the lower index); the least bound over all cells
//! is returned as the certificate.

use std::sync::atomic::{AtomicUsize, Ordering};

use nalgebra::Vector3;
use rayon::prelude::*;

use super::Phase;
use super::fan::{FanScratch, fan_search};
use super::machine::{AxisRanges, MachineType};
use super::rect::{Above, RectScratch, rect_search_above};
use super::search::{Key, Placement, PvcClasses, Scratch, Solved, angle, can_beat, md_cells};
use super::sphere::{CellChunks, GeodesicSphere};
use super::visibility::VisibilityMap;

type V3 = Vector3<f64>;

/// MD points within this many cell spacings of binding a placement are
/// kept as its binding points.
const BINDING_SLACK: f64 = 1.0;
/// The bound of a cell uses the binding classes of this many exactly
/// evaluated cells nearest it.
const NEAREST_SOURCES: usize = 6;
/// The A,B search stops splitting turns of `R1` narrower than the cell
/// spacing over this: the MD points are only known to a cell, and the key's
/// loss is then at most about `2·spacing/16·(Φ + Θ)`, an eighth of the
/// equivalence tolerance of one cell.
const TURN_DIVISOR: f64 = 16.0;
/// Relative tolerance when ruling a cell out against the best key.
const RULE_OUT_REL_TOL: f64 = 1e-9;

/// The exact result for one tool axis.
#[derive(Debug, Clone)]
pub(super) struct Evaluation {
    pub solved: Solved,
    pub group_ii: usize,
    pub md_points: usize,
    /// Classes whose MD points bind `solved.best` or `solved.fit`.
    binding: Vec<u32>,
}

/// The boundary of one class's cone: its cells that touch a cell outside
/// it, chunked under bounding caps ([`CellChunks`]). The cone cell nearest
/// a direction outside the cone is one of them (the sphere has no other
/// local nearest cells: `sphere::tests`), so MD points can be found here
/// alone.
#[derive(Debug)]
struct Boundary(CellChunks);

impl Boundary {
    fn new(map: &VisibilityMap, patch: usize, sphere: &GeodesicSphere) -> Self {
        let row = map.pvc(patch);
        let open = |c: usize| row[c / 64] >> (c % 64) & 1 == 1;
        // The open cells by their bits (a cone is a fraction of the
        // sphere), in cell order.
        let mut cells: Vec<u32> = Vec::new();
        for (w, &bits) in row.iter().enumerate() {
            let mut bits = bits;
            while bits != 0 {
                let c = w * 64 + bits.trailing_zeros() as usize;
                bits &= bits - 1;
                if sphere.touching(c).iter().any(|&n| !open(n as usize)) {
                    cells.push(c as u32);
                }
            }
        }
        let mut chunks = CellChunks::default();
        chunks.rebuild(&cells, sphere.cells());
        Self(chunks)
    }

    /// The boundary cell first in the order of [`nearer`] from `p`.
    fn nearest(&self, p: &V3, dirs: &[V3], bounds: &mut Vec<f64>) -> u32 {
        self.0.nearest(p, dirs, bounds)
    }
}

/// Per-thread memory.
#[derive(Debug, Default)]
struct Work {
    walk: Scratch,
    fan: FanScratch,
    rect: RectScratch,
    md: Vec<V3>,
    cells: Vec<u32>,
    sorted: Vec<u32>,
    bounds: Vec<f64>,
    /// `seen[k] == generation`: class `k` is in the bound's subset.
    seen: Vec<u32>,
    generation: u32,
}

/// What the search needs to know about the problem.
pub(super) struct Problem<'a> {
    pub map: &'a VisibilityMap,
    pub classes: &'a PvcClasses,
    pub sphere: &'a GeodesicSphere,
    pub kind: MachineType,
    pub ranges: &'a AxisRanges,
    /// Fit slack, radians.
    pub tol: f64,
    /// Equivalence tolerance: ranges within this (radians) of the best's.
    pub equivalent: f64,
    /// Cells of the coarse sphere whose nearest cells are evaluated first;
    /// 0: evaluate every cell exactly.
    pub probe_cells: usize,
}

/// The best tool axis for one objective, with its certificate.
#[derive(Debug, Clone)]
pub(super) struct Optimum {
    pub cell: usize,
    pub placement: Placement,
    pub group_ii: usize,
    pub md_points: usize,
    /// No tool axis of the map has a key below this.
    pub lower_bound: Key,
    /// Other tool axes whose key's area is within `tolerance` of the best's
    /// and the largest angle from the best's tool axis to theirs; `None`
    /// when not searched for (the MAR of a part that fits).
    pub equivalent: Option<(usize, f64)>,
    pub tolerance: f64,
}

/// The answer of [`search`].
#[derive(Debug, Clone)]
pub(super) struct Outcome {
    pub mar: Optimum,
    pub fit: Option<Optimum>,
    pub evaluated: usize,
}

impl Problem<'_> {
    /// The fan or rectangle search over `w.md`.
    /// With `above` (a bound, not an evaluation), the rectangle search may
    /// stop once its bounds are certainly above those areas
    /// ([`rect_search_above`]): the caller then only asks whether they are.
    fn solve(&self, p: &V3, w: &mut Work, above: Option<Above>) -> Solved {
        match self.kind {
            MachineType::CA => fan_search(p, &w.md, self.ranges, self.tol, &mut w.fan),
            MachineType::AB => rect_search_above(
                p,
                &w.md,
                self.ranges,
                self.tol,
                self.sphere.spacing() / TURN_DIVISOR,
                above,
                &mut w.rect,
            ),
        }
    }

    /// Every class, exactly; with the classes that bind the placements
    /// when `binding` (only bounds use them).
    fn evaluate(&self, i: usize, w: &mut Work, binding: bool) -> Evaluation {
        let dirs = self.sphere.cells();
        let group_ii = md_cells(self.classes, dirs, i, &mut w.walk);
        w.md.clear();
        w.md.extend(w.walk.md.iter().map(|&c| dirs[c as usize]));
        let p = &dirs[i];
        let solved = self.solve(p, w, None);
        let mut binding_classes = Vec::new();
        let placements = if binding {
            [Some(solved.best), solved.fit]
        } else {
            [None, None]
        };
        for pl in placements.into_iter().flatten() {
            for k in binding_points(self.kind, &pl, &w.md, BINDING_SLACK * self.sphere.spacing()) {
                binding_classes.push(w.walk.md_class[k]);
            }
        }
        binding_classes.sort_unstable();
        binding_classes.dedup();
        Evaluation {
            solved,
            group_ii,
            md_points: w.md.len(),
            binding: binding_classes,
        }
    }

    /// Lower bounds of the keys of cell `i` from the classes that bind at
    /// the sources `near` (nearest first), their boundaries built on first
    /// use: the classes of one source after the other, until the bound
    /// rules the cell out for good (`out`) or every source is in. With all
    /// of them the bound is that of their union; stopping early only ever
    /// leaves a cell ruled out that the whole union rules out too.
    /// `above`, when given, are the areas above which `out` holds (see
    /// [`Problem::solve`]); a cell so ruled out keeps a lower bound that may
    /// be below the full search's, but above those areas all the same.
    #[allow(clippy::too_many_arguments)]
    fn bound(
        &self,
        i: usize,
        near: &[usize],
        exact: &[Option<Evaluation>],
        boundaries: &Boundaries,
        out: &dyn Fn(&Bounds) -> bool,
        above: Option<Above>,
        w: &mut Work,
    ) -> Bounds {
        let dirs = self.sphere.cells();
        let p = &dirs[i];
        w.cells.clear();
        w.generation = w.generation.wrapping_add(1);
        if w.generation == 0 || w.seen.len() != self.classes.classes {
            w.seen.clear();
            w.seen.resize(self.classes.classes, 0);
            w.generation = 1;
        }
        let mut result = ((0.0, 0.0), Some((0.0, 0.0)));
        for (n, &s) in near.iter().enumerate() {
            let before = w.cells.len();
            let binding = &exact[s].as_ref().expect("sources are evaluated").binding;
            for &k in binding {
                if w.seen[k as usize] == w.generation {
                    continue;
                }
                w.seen[k as usize] = w.generation;
                if !self.map.visible(self.classes.reps[k as usize], i) {
                    let b = boundaries.get(k, self);
                    w.cells.push(b.nearest(p, dirs, &mut w.bounds));
                }
            }
            if w.cells.len() == before && n > 0 {
                // No new MD point: the same bound.
                continue;
            }
            w.sorted.clear();
            w.sorted.extend_from_slice(&w.cells);
            w.sorted.sort_unstable();
            w.sorted.dedup();
            w.md.clear();
            w.md.extend(w.sorted.iter().map(|&c| dirs[c as usize]));
            let solved = self.solve(p, w, above);
            result = (solved.best_lower, solved.fit_lower);
            if out(&result) {
                break;
            }
        }
        result
    }
}

/// Lower bounds of a cell's keys: the least key, and the least that fits
/// (`None`: nothing fits).
type Bounds = (Key, Option<Key>);

/// The boundaries of the classes' cones, each built the first time a
/// bound needs it (by whichever thread gets there first).
struct Boundaries {
    cells: Vec<std::sync::OnceLock<Boundary>>,
    built: AtomicUsize,
}

impl Boundaries {
    fn new(classes: usize) -> Self {
        Self {
            cells: (0..classes).map(|_| std::sync::OnceLock::new()).collect(),
            built: AtomicUsize::new(0),
        }
    }

    fn get(&self, k: u32, prob: &Problem) -> &Boundary {
        self.cells[k as usize].get_or_init(|| {
            self.built.fetch_add(1, Ordering::Relaxed);
            Boundary::new(prob.map, prob.classes.reps[k as usize], prob.sphere)
        })
    }
}

/// The MD points (indices into `md`) on the edge of the FTM of `pl`: at a
/// fan's full tilt or on its side (C,A), at an extreme turn or latitude
/// (A,B). Growing the subset of the bounds with their classes makes the
/// bounds tight near this tool axis.
fn binding_points(kind: MachineType, pl: &Placement, md: &[V3], slack: f64) -> Vec<usize> {
    // Angles within this of an edge count as on it (radians): a little more
    // than round-off, so that the points that bind at nearby tool axes are
    // taken too.
    let on_edge = slack.max(1e-7);
    let p = pl.tool_axis;
    let r = &pl.required;
    let mut out = Vec::new();
    match kind {
        MachineType::CA => {
            use std::f64::consts::{PI, TAU};
            // Longitude from the basis great circle (C at zero); the fan of
            // positive tilt (φᴸ) spans [−θˢ, θᴸ], the other (φˢ) the same
            // turned by π.
            let u = pl.axis_2.cross(&p);
            let wrap = |a: f64| (a + PI).rem_euclid(TAU) - PI;
            let in_fan = |l: f64| l >= -r.theta_s - on_edge && l <= r.theta_l + on_edge;
            let edge = |l: f64| (l + r.theta_s).abs() < on_edge || (l - r.theta_l).abs() < on_edge;
            for (k, v) in md.iter().enumerate() {
                let l = v.dot(&pl.axis_2).atan2(v.dot(&u));
                let b = angle(&p, v);
                let (pos, neg) = (wrap(l), wrap(l - PI));
                // A point both fans reach is the larger tilt's.
                let at_tilt = (in_fan(pos) && b >= r.phi_l - on_edge)
                    || (in_fan(neg) && !in_fan(pos) && b >= r.phi_s - on_edge);
                if at_tilt || edge(pos) || edge(neg) {
                    out.push(k);
                }
            }
        }
        MachineType::AB => {
            let r1 = pl.axis_1;
            let (mut a, mut b) = ([0.0f64; 2], [0.0f64; 2]);
            let turns: Vec<(f64, f64)> = md
                .iter()
                .map(|v| {
                    let alpha = p.cross(v).dot(&r1).atan2(p.dot(v));
                    let beta = v.dot(&r1).clamp(-1.0, 1.0).asin();
                    a = [a[0].max(alpha), a[1].max(-alpha)];
                    b = [b[0].max(beta), b[1].max(-beta)];
                    (alpha, beta)
                })
                .collect();
            for (k, &(alpha, beta)) in turns.iter().enumerate() {
                if alpha >= a[0] - on_edge
                    || -alpha >= a[1] - on_edge
                    || beta >= b[0] - on_edge
                    || -beta >= b[1] - on_edge
                {
                    out.push(k);
                }
            }
        }
    }
    out
}

/// Calls `f` on every cell of `which` in parallel with per-thread memory,
/// reporting progress.
fn par_map<T: Send>(
    which: &[usize],
    f: &(dyn Fn(usize, &mut Work) -> T + Sync),
    phase: Phase,
    progress: &(dyn Fn(Phase, usize, usize) + Sync),
) -> Vec<T> {
    /// Cells per progress report.
    const PROGRESS_EVERY: usize = 64;
    let done = AtomicUsize::new(0);
    which
        .par_iter()
        .map_init(Work::default, |w, &i| {
            let out = f(i, w);
            let n = done.fetch_add(1, Ordering::Relaxed) + 1;
            if n.is_multiple_of(PROGRESS_EVERY) || n == which.len() {
                progress(phase, n, which.len());
            }
            out
        })
        .collect()
}

/// `δ·(Φ + Θ) + δ²`: how much the area grows when both range sums of the
/// key's placement grow by `δ` — the area tolerance of "equivalent".
fn tolerance(key: Key, delta: f64) -> f64 {
    // key.1 = Φ + Θ, the two range sums; their product is at most area.
    delta * key.1 + delta * delta
}

/// The least key of each objective over every cell of the sphere, with a
/// certificate (see the module doc).
pub(super) fn search(
    prob: &Problem,
    common: &[usize],
    progress: &(dyn Fn(Phase, usize, usize) + Sync),
) -> Outcome {
    let dirs = prob.sphere.cells();
    let m = dirs.len();
    let trace = std::env::var_os("INTERPD_SETUP_TRACE").is_some();
    let mut exact: Vec<Option<Evaluation>> = vec![None; m];
    // Lower bounds (trivial before any bound is computed), and the angle
    // (as a cosine) to the farthest source each bound used: a new source
    // nearer than that can tighten it.
    let mut lower: Vec<(Key, Option<Key>)> = vec![((0.0, 0.0), Some((0.0, 0.0))); m];
    let mut reach: Vec<f64> = vec![2.0; m];
    let mut sources: Vec<usize> = Vec::new();
    let boundaries = Boundaries::new(prob.classes.classes);
    // Every cell evaluated at once: no bounds, so no binding classes.
    let everything = prob.probe_cells == 0 || prob.probe_cells * 4 >= m;
    let evaluate = |i: usize, w: &mut Work| prob.evaluate(i, w, !everything);
    let run_exact = |which: &[usize], exact: &mut Vec<Option<Evaluation>>| {
        for (&i, e) in which
            .iter()
            .zip(par_map(which, &evaluate, Phase::Refine, progress))
        {
            exact[i] = Some(e);
        }
    };
    // 1. Probes (or everything).
    let probes: Vec<usize> = if everything {
        (0..m).collect()
    } else {
        let coarse = GeodesicSphere::with_at_least(prob.probe_cells).expect("valid count");
        let mut first: Vec<usize> = coarse
            .cells()
            .par_iter()
            .map(|d| {
                (0..m)
                    .max_by(|&a, &b| dirs[a].dot(d).total_cmp(&dirs[b].dot(d)).then(b.cmp(&a)))
                    .expect("a sphere has cells")
            })
            .collect();
        first.extend_from_slice(common);
        first.sort_unstable();
        first.dedup();
        first
    };
    run_exact(&probes, &mut exact);
    sources.extend_from_slice(&probes);
    let best_of = |exact: &[Option<Evaluation>], fit: bool| -> Option<(usize, Key)> {
        exact
            .iter()
            .enumerate()
            .filter_map(|(i, e)| {
                let e = e.as_ref()?;
                let pl = if fit { e.solved.fit? } else { e.solved.best };
                Some((i, pl.key()))
            })
            .min_by(|a, b| {
                a.1.partial_cmp(&b.1)
                    .expect("finite keys")
                    .then(a.0.cmp(&b.0))
            })
    };
    // The classes a cell's bound uses: those binding at its nearest
    // sources; and the cosine of the angle to the farthest of them.
    // The sources whose binding classes bound a cell (nearest first), and
    // the cosine of the angle to the farthest of them.
    let sources_of = |i: usize, sources: &[usize]| -> (Vec<usize>, f64) {
        let mut near: Vec<(f64, usize)> = sources
            .iter()
            .map(|&s| (dirs[s].dot(&dirs[i]), s))
            .collect();
        let order = |a: &(f64, usize), b: &(f64, usize)| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1));
        let k = NEAREST_SOURCES.min(near.len());
        if k < near.len() {
            near.select_nth_unstable_by(k, order);
        }
        near.truncate(k);
        near.sort_unstable_by(order);
        let far = near.iter().map(|x| x.0).fold(1.0, f64::min);
        (near.into_iter().map(|x| x.1).collect(), far)
    };
    // Whether a cell is ruled out for the objective shown with equivalents
    // (`wide`) or only for the optimum.
    let thresholds = |exact: &[Option<Evaluation>], mar_wide: bool| {
        let mar = best_of(exact, false).map(|(_, k)| k);
        let fit = best_of(exact, true).map(|(_, k)| k);
        (mar, fit, mar_wide)
    };
    let open = |i: usize, lower: &[(Key, Option<Key>)], t: &(Option<Key>, Option<Key>, bool)| {
        let (lm, lf) = lower[i];
        let mar_open = match t.0 {
            None => true,
            Some(k) if t.2 => lm.0 <= k.0 + tolerance(k, prob.equivalent),
            Some(k) => can_beat(lm, k, RULE_OUT_REL_TOL),
        };
        let fit_open = match (lf, t.1) {
            (None, _) => false,
            (Some(_), None) => true,
            (Some(l), Some(k)) => l.0 <= k.0 + tolerance(k, prob.equivalent),
        };
        mar_open || fit_open
    };
    // Cells whose bound a new source may tighten.
    let mut stale: Vec<bool> = vec![true; m];
    let mut rounds = 0;
    // Two phases: equivalents of the fitting setup (and the MAR optimum);
    // then, if nothing fits, equivalents of the MAR.
    for mar_wide in [false, true] {
        if mar_wide && best_of(&exact, true).is_some() {
            break;
        }
        let mut batch = 2 * rayon::current_num_threads().max(1);
        loop {
            rounds += 1;
            let t = thresholds(&exact, mar_wide);
            let mut cand: Vec<usize> = (0..m)
                .filter(|&i| exact[i].is_none() && open(i, &lower, &t))
                .collect();
            if cand.is_empty() {
                break;
            }
            // Re-bound the open cells a new source is near.
            let rebound: Vec<usize> = cand.iter().copied().filter(|&i| stale[i]).collect();
            if !rebound.is_empty() {
                let before = boundaries.built.load(Ordering::Relaxed);
                // Ruled out whatever the final thresholds: above the best
                // (plus the equivalence tolerance) for both objectives.
                let out = |l: &Bounds| {
                    let mar_out =
                        t.0.is_some_and(|k| l.0.0 > k.0 + tolerance(k, prob.equivalent));
                    let fit_out = match (l.1, t.1) {
                        (None, _) => true,
                        (Some(_), None) => false,
                        (Some(f), Some(k)) => f.0 > k.0 + tolerance(k, prob.equivalent),
                    };
                    mar_out && fit_out
                };
                // The same thresholds as areas, for the rectangle search to
                // stop at once it is certainly above them.
                let above = match (t.0, t.1) {
                    (Some(k), Some(f)) => Some(Above {
                        best: k.0 + tolerance(k, prob.equivalent),
                        fit: f.0 + tolerance(f, prob.equivalent),
                    }),
                    _ => None,
                };
                let f = |n: usize, w: &mut Work| {
                    let i = rebound[n];
                    let (near, far) = sources_of(i, &sources);
                    (
                        prob.bound(i, &near, &exact, &boundaries, &out, above, w),
                        far,
                    )
                };
                let idx: Vec<usize> = (0..rebound.len()).collect();
                for (n, (l, far)) in par_map(&idx, &f, Phase::Search, progress)
                    .into_iter()
                    .enumerate()
                {
                    let i = rebound[n];
                    lower[i] = l;
                    reach[i] = far;
                    stale[i] = false;
                }
                if trace {
                    eprintln!(
                        "  bounded {} cells, built {} boundaries",
                        rebound.len(),
                        boundaries.built.load(Ordering::Relaxed) - before
                    );
                }
                cand.retain(|&i| open(i, &lower, &t));
                if cand.is_empty() {
                    continue;
                }
            }
            // Least bound first.
            let key_of = |i: usize| {
                let (lm, lf) = lower[i];
                lf.map_or(lm, |f| if f < lm { f } else { lm })
            };
            cand.sort_by(|&a, &b| {
                key_of(a)
                    .partial_cmp(&key_of(b))
                    .expect("finite")
                    .then(a.cmp(&b))
            });
            if trace {
                eprintln!(
                    "round {rounds}: open {} sources {} batch {batch} best {:?} fit {:?}",
                    cand.len(),
                    sources.len(),
                    t.0,
                    t.1
                );
            }
            cand.truncate(batch);
            run_exact(&cand, &mut exact);
            // The new sources may tighten the bounds of cells nearer them
            // than those cells' farthest source.
            sources.extend_from_slice(&cand);
            let new = &cand;
            stale
                .par_iter_mut()
                .enumerate()
                .filter(|(i, _)| exact[*i].is_none())
                .for_each(|(i, s)| {
                    if !*s && new.iter().any(|&c| dirs[c].dot(&dirs[i]) > reach[i]) {
                        *s = true;
                    }
                });
            batch = (batch * 3 / 2).min(512);
        }
    }
    let evaluated = exact.iter().filter(|e| e.is_some()).count();
    if trace {
        eprintln!("evaluated {evaluated} of {m} in {rounds} rounds");
    }
    let complete_mar = best_of(&exact, true).is_none();
    let optimum = |fit: bool| -> Option<Optimum> {
        let (cell, key) = best_of(&exact, fit)?;
        let e = exact[cell].as_ref().expect("evaluated");
        let placement = if fit {
            e.solved.fit.expect("fits")
        } else {
            e.solved.best
        };
        let tol = tolerance(key, prob.equivalent);
        let mut equivalent = 0;
        let mut spread = 0.0f64;
        let mut lower_bound = key;
        for (i, x) in exact.iter().enumerate() {
            let l = match x {
                Some(x) => {
                    let (pl, l) = if fit {
                        (x.solved.fit, x.solved.fit_lower)
                    } else {
                        (Some(x.solved.best), Some(x.solved.best_lower))
                    };
                    if let Some(pl) = pl
                        && i != cell
                        && pl.area <= key.0 + tol
                    {
                        equivalent += 1;
                        spread = spread.max(angle(&dirs[cell], &dirs[i]));
                    }
                    l
                }
                None => {
                    if fit {
                        lower[i].1
                    } else {
                        Some(lower[i].0)
                    }
                }
            };
            if let Some(l) = l
                && l < lower_bound
            {
                lower_bound = l;
            }
        }
        Some(Optimum {
            cell,
            placement,
            group_ii: e.group_ii,
            md_points: e.md_points,
            lower_bound,
            equivalent: (fit || complete_mar).then_some((equivalent, spread)),
            tolerance: tol,
        })
    };
    Outcome {
        mar: optimum(false).expect("every sphere has cells"),
        fit: optimum(true),
        evaluated,
    }
}
