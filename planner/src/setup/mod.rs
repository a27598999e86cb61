//! Five-axis machinability and setup orientation (seed `000_…`).
//!
//! Given a part (a triangle mesh, each triangle one surface patch), a machine
//! configuration in `W/…/T` notation and its rotary ranges (Φᴸ, Φˢ, Θᴸ, Θˢ),
//! [`plan_setup`] decides whether the part can be machined in one setup and
//! finds the setup orientation that needs the least rotary motion:
//!
//! 1. [`sphere`]: a triangulated sphere of `m` cells (tool-axis directions);
//! 2. [`visibility`]: the point visibility cone `PVC_j` of every patch as a
//!    set of cells — the binary spherical map — by rasterising the occluding
//!    triangles (found through a BVH) onto the cells around the patch, which
//!    gives exactly the ray-cast map (the tool's own volume is ignored, as in
//!    the paper);
//! 3. [`search`]: every cell `C_i` is tried as the tool axis (coarse to fine
//!    on spheres finer than `4 ×` [`SetupConfig::coarse_cells`]); Group II patches
//!    (not reachable from `C_i`, eq. 3) are represented by their MD points
//!    (eq. 4); the C,A fan search (eq. 5–13) or the A,B spherical-rectangle
//!    search over their convex hull (eq. 14–21) sizes the FTM⁵ that holds
//!    them. The least-area placement that fits the machine is the setup; if
//!    none fits, the least-area one overall gives the minimum axis ranges
//!    (MAR) to ask for.
//!
//! See `docs/planner-setup.md`.

pub mod machine;
pub mod samples;
pub mod search;
pub mod sphere;
pub mod visibility;

use std::sync::atomic::{AtomicUsize, Ordering};

use nalgebra::Vector3;
use rayon::prelude::*;

pub use machine::{AxisRanges, MachineConfig, MachineType, RotaryAxis};
pub use search::Placement;
pub use sphere::GeodesicSphere;
pub use visibility::VisibilityMap;

use crate::mesh::TriMesh;

/// Options of the setup planner (serde, kebab-case; defaults below).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, rename_all = "kebab-case")]
pub struct SetupConfig {
    /// Minimum number of sphere cells; the geodesic sphere rounds up to
    /// `20·f²`. Default 1,200 (the paper's), giving 1,280 cells.
    pub cells: usize,
    /// Directions within this angle of a patch's tangent plane do not reach
    /// it, degrees. Default 0: any direction strictly outside the patch.
    pub grazing_margin_deg: f64,
    /// Slack when comparing needed and available ranges, degrees. Default
    /// 1e-9 (round-off only).
    pub fit_tolerance_deg: f64,
    /// Cells of the coarse sphere of the coarse-to-fine search, used when
    /// the sphere has more than 4× as many; 0 tries every cell. Default
    /// 1,280 (f = 8): the paper's size is searched exhaustively.
    pub coarse_cells: usize,
}

impl Default for SetupConfig {
    fn default() -> Self {
        Self {
            cells: 1200,
            grazing_margin_deg: 0.0,
            fit_tolerance_deg: 1e-9,
            coarse_cells: 1280,
        }
    }
}

/// Why the setup could not be planned.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SetupError {
    /// Bad cell count.
    #[error(transparent)]
    Sphere(#[from] sphere::SphereError),
    /// A config value is not finite or out of range.
    #[error("setup config: {field} = {value} is out of range ({expected})")]
    Config {
        /// Field name.
        field: &'static str,
        /// The value.
        value: f64,
        /// What is accepted.
        expected: &'static str,
    },
}

/// Which phase a progress report is about.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Phase {
    /// Ray casting, counted in patches.
    Visibility,
    /// Setup search, counted in candidate tool axes (cells): every cell,
    /// or the coarse candidates of a coarse-to-fine search.
    Search,
    /// Refinement rounds of a coarse-to-fine search, counted in the cells
    /// of the round.
    Refine,
}

/// The answer of [`plan_setup`].
#[derive(Debug, Clone, PartialEq)]
pub struct SetupPlan {
    /// C,A or A,B.
    pub machine_type: MachineType,
    /// Cells of the sphere used.
    pub cells: usize,
    /// Patches (triangles) of the part.
    pub patches: usize,
    /// Patches with distinct visibility cones (the search works on these).
    pub pvc_classes: usize,
    /// Patches that no direction reaches (empty cone): hidden faces, closed
    /// cavities. Any such patch makes the part infeasible.
    pub unreachable_patches: Vec<usize>,
    /// Whether one direction reaches every reachable patch (3-axis, `FTM³`).
    pub three_axis: bool,
    /// Whether the machine's ranges hold every patch in one setup (eq. 1).
    pub feasible: bool,
    /// The least-area placement that fits the machine, if any: the setup.
    pub setup: Option<SetupOrientation>,
    /// The least-area placement overall: its ranges are the minimum axis
    /// ranges (MAR) the part needs on this machine type.
    pub mar: SetupOrientation,
}

/// One placement with the bookkeeping of its candidate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SetupOrientation {
    /// The placement (tool axis, rotary-axis directions, ranges, area).
    pub placement: Placement,
    /// Index of the cell used as the tool axis.
    pub cell: usize,
    /// Patch classes in Group II for this tool axis.
    pub group_ii_classes: usize,
    /// Distinct MD points.
    pub md_points: usize,
}

fn check(
    field: &'static str,
    value: f64,
    ok: bool,
    expected: &'static str,
) -> Result<(), SetupError> {
    if value.is_finite() && ok {
        Ok(())
    } else {
        Err(SetupError::Config {
            field,
            value,
            expected,
        })
    }
}

/// Computes the binary spherical map of `mesh` on `sphere`.
pub fn visibility_map(
    mesh: &TriMesh,
    sphere: &GeodesicSphere,
    config: &SetupConfig,
    progress: &(dyn Fn(Phase, usize, usize) + Sync),
) -> Result<VisibilityMap, SetupError> {
    check(
        "grazing-margin-deg",
        config.grazing_margin_deg,
        (0.0..90.0).contains(&config.grazing_margin_deg),
        "0 ≤ value < 90",
    )?;
    Ok(visibility::compute(
        mesh,
        sphere,
        visibility::VisibilityOptions {
            grazing_margin: config.grazing_margin_deg.to_radians(),
        },
        &|done, total| progress(Phase::Visibility, done, total),
    ))
}

/// Plans the setup of `mesh` on `machine` with rotary ranges `ranges`.
pub fn plan_setup(
    mesh: &TriMesh,
    machine: &MachineConfig,
    ranges: &AxisRanges,
    config: &SetupConfig,
    progress: &(dyn Fn(Phase, usize, usize) + Sync),
) -> Result<SetupPlan, SetupError> {
    check(
        "fit-tolerance-deg",
        config.fit_tolerance_deg,
        config.fit_tolerance_deg >= 0.0,
        "value ≥ 0",
    )?;
    let sphere = GeodesicSphere::with_at_least(config.cells)?;
    let map = visibility_map(mesh, &sphere, config, progress)?;
    Ok(search_setup(
        &map,
        &sphere,
        machine.machine_type(),
        ranges,
        config,
        progress,
    ))
}

/// The result of trying one cell as the tool axis.
#[derive(Debug, Clone, Copy)]
struct Candidate {
    /// Least-area placement.
    best: SetupOrientation,
    /// Least-area placement that fits the machine.
    fit: Option<SetupOrientation>,
}

/// The better of two optional placements: smaller key, ties to the lower
/// cell index, so the answer does not depend on the thread schedule or on
/// the order candidates are tried in.
fn better(a: Option<SetupOrientation>, b: Option<SetupOrientation>) -> Option<SetupOrientation> {
    match (a, b) {
        (Some(x), Some(y)) => {
            if (y.placement.key(), y.cell) < (x.placement.key(), x.cell) {
                Some(y)
            } else {
                Some(x)
            }
        }
        (x, None) => x,
        (None, y) => y,
    }
}

/// The search of §4 on a computed map. Every cell is tried as the tool axis
/// when the sphere has at most `4 ×` [`SetupConfig::coarse_cells`] cells
/// (or `coarse_cells` is 0); on finer spheres the search is coarse to fine
/// (see [`SetupConfig::coarse_cells`]).
pub fn search_setup(
    map: &VisibilityMap,
    sphere: &GeodesicSphere,
    kind: MachineType,
    ranges: &AxisRanges,
    config: &SetupConfig,
    progress: &(dyn Fn(Phase, usize, usize) + Sync),
) -> SetupPlan {
    let classes = search::PvcClasses::new(map, sphere.cells());
    let unreachable_patches: Vec<usize> = classes
        .class_of
        .iter()
        .enumerate()
        .filter(|(_, c)| c.is_none())
        .map(|(j, _)| j)
        .collect();
    let cells = sphere.cells();
    let tol = config.fit_tolerance_deg.to_radians();
    let resolution = sphere.spacing() / 2.0;
    let evaluate = |i: usize, s: &mut SearchScratch| -> Candidate {
        let group_ii = search::md_cells(&classes, cells, i, &mut s.md_walk);
        s.md.clear();
        s.md.extend(s.md_walk.md.iter().map(|&c| cells[c as usize]));
        let p = &cells[i];
        let (best, fit) = match kind {
            MachineType::CA => search::fan_search(p, &s.md, ranges, tol, &mut s.fan),
            MachineType::AB => search::rect_search(p, &s.md, ranges, tol, resolution, &mut s.rect),
        };
        let wrap = |placement: Placement| SetupOrientation {
            placement,
            cell: i,
            group_ii_classes: group_ii,
            md_points: s.md.len(),
        };
        Candidate {
            best: wrap(best),
            fit: fit.map(wrap),
        }
    };
    // Whether one direction reaches every reachable patch: the cells in all
    // cones (exact, whatever the search tries).
    let common = classes.common_cells();
    let three_axis = !common.is_empty();
    let coarse = (config.coarse_cells > 0 && cells.len() > COARSE_FACTOR * config.coarse_cells)
        .then(|| GeodesicSphere::with_at_least(config.coarse_cells).ok())
        .flatten();
    let (mar, setup) = match coarse {
        None => {
            let all: Vec<usize> = (0..cells.len()).collect();
            let found = evaluate_all(&all, &evaluate, Phase::Search, progress);
            found.iter().fold((None, None), |(m, f), c| {
                (better(m, Some(c.best)), better(f, c.fit))
            })
        }
        Some(coarse) => coarse_to_fine(sphere, &coarse, &common, &evaluate, progress),
    };
    let feasible = setup.is_some() && unreachable_patches.is_empty();
    SetupPlan {
        machine_type: kind,
        cells: cells.len(),
        patches: map.patches(),
        pvc_classes: classes.classes,
        unreachable_patches,
        three_axis,
        feasible,
        setup,
        mar: mar.expect("a sphere has cells"),
    }
}

/// The coarse-to-fine search is used when the sphere has more than this
/// many times [`SetupConfig::coarse_cells`] cells.
const COARSE_FACTOR: usize = 4;
/// Best coarse candidates refined, per objective (MAR and fitting setup).
const REFINE_SEEDS: usize = 6;
/// Radius of the first refinement around a coarse seed, in coarse spacings.
const SEED_RADIUS_COARSE: f64 = 1.0;
/// Radius of each hill-climbing step around the current best, in fine
/// spacings.
const CLIMB_RADIUS_FINE: f64 = 2.0;

/// Per-thread memory of the search.
#[derive(Debug, Default)]
struct SearchScratch {
    md_walk: search::Scratch,
    fan: search::FanScratch,
    rect: search::RectScratch,
    md: Vec<Vector3<f64>>,
}

/// Tries the cells `which` in parallel.
fn evaluate_all(
    which: &[usize],
    evaluate: &(dyn Fn(usize, &mut SearchScratch) -> Candidate + Sync),
    phase: Phase,
    progress: &(dyn Fn(Phase, usize, usize) + Sync),
) -> Vec<Candidate> {
    /// Candidates per progress report.
    const PROGRESS_EVERY: usize = 64;
    let done = AtomicUsize::new(0);
    which
        .par_iter()
        .map_init(SearchScratch::default, |s, &i| {
            let c = evaluate(i, s);
            let n = done.fetch_add(1, Ordering::Relaxed) + 1;
            if n.is_multiple_of(PROGRESS_EVERY) || n == which.len() {
                progress(phase, n, which.len());
            }
            c
        })
        .collect()
}

/// Coarse to fine: the fine cells nearest to the `coarse` sphere's cells
/// (and every cell that alone reaches all patches, `common`) are tried
/// first; then, for the least-area placement overall (MAR) and the
/// least-area one that fits, every fine cell within a coarse spacing of the
/// best [`REFINE_SEEDS`] coarse candidates, then hill climbing: all cells
/// within [`CLIMB_RADIUS_FINE`] fine spacings of the best so far, until the
/// best stays. Each cell is evaluated exactly as the exhaustive search
/// does, so the answer is the exhaustive one whenever the optimum lies in
/// the basin of a seed (checked against the exhaustive search in the tests).
fn coarse_to_fine(
    sphere: &GeodesicSphere,
    coarse: &GeodesicSphere,
    common: &[usize],
    evaluate: &(dyn Fn(usize, &mut SearchScratch) -> Candidate + Sync),
    progress: &(dyn Fn(Phase, usize, usize) + Sync),
) -> (Option<SetupOrientation>, Option<SetupOrientation>) {
    let cells = sphere.cells();
    let mut tried: Vec<Option<Candidate>> = vec![None; cells.len()];
    let mut first: Vec<usize> = coarse
        .cells()
        .par_iter()
        .map(|d| {
            (0..cells.len())
                .max_by(|&a, &b| cells[a].dot(d).total_cmp(&cells[b].dot(d)))
                .expect("a sphere has cells")
        })
        .collect();
    first.extend_from_slice(common);
    first.sort_unstable();
    first.dedup();
    let run = |which: &[usize], phase: Phase, tried: &mut Vec<Option<Candidate>>| {
        let todo: Vec<usize> = which
            .iter()
            .copied()
            .filter(|&i| tried[i].is_none())
            .collect();
        for (i, c) in todo
            .iter()
            .zip(evaluate_all(&todo, evaluate, phase, progress))
        {
            tried[*i] = Some(c);
        }
    };
    run(&first, Phase::Search, &mut tried);
    let within = |centre: usize, radius: f64| -> Vec<usize> {
        let cos_r = radius.cos();
        let c = cells[centre];
        (0..cells.len())
            .filter(|&i| cells[i].dot(&c) >= cos_r)
            .collect()
    };
    type Pick = fn(&Candidate) -> Option<SetupOrientation>;
    let objectives: [Pick; 2] = [|c| Some(c.best), |c| c.fit];
    for pick in objectives {
        // Seeds: the best coarse candidates for this objective.
        let mut ranked: Vec<SetupOrientation> = first
            .iter()
            .filter_map(|&i| tried[i].as_ref().and_then(pick))
            .collect();
        ranked.sort_by(|a, b| {
            (a.placement.key(), a.cell)
                .partial_cmp(&(b.placement.key(), b.cell))
                .expect("keys are finite")
        });
        let mut near: Vec<usize> = ranked
            .iter()
            .take(REFINE_SEEDS)
            .flat_map(|s| within(s.cell, SEED_RADIUS_COARSE * coarse.spacing()))
            .collect();
        near.sort_unstable();
        near.dedup();
        run(&near, Phase::Refine, &mut tried);
        // Hill climbing from the best so far.
        let best_of = |tried: &[Option<Candidate>]| {
            tried
                .iter()
                .flatten()
                .filter_map(pick)
                .fold(None, |b, c| better(b, Some(c)))
        };
        let mut best = best_of(&tried);
        while let Some(b) = best {
            run(
                &within(b.cell, CLIMB_RADIUS_FINE * sphere.spacing()),
                Phase::Refine,
                &mut tried,
            );
            let next = best_of(&tried);
            if next.map(|n| n.cell) == Some(b.cell) {
                break;
            }
            best = next;
        }
    }
    tried.iter().flatten().fold((None, None), |(m, f), c| {
        (better(m, Some(c.best)), better(f, c.fit))
    })
}
