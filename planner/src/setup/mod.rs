//! Five-axis machinability and setup orientation (seed `000_…`).
//!
//! Given a part (a triangle mesh, each triangle one surface patch), a machine
//! configuration in `W/…/T` notation and its rotary ranges (Φᴸ, Φˢ, Θᴸ, Θˢ),
//! [`plan_setup`] decides whether the part can be machined in one setup and
//! finds the setup orientation that needs the least rotary motion:
//!
//! 1. [`sphere`]: a triangulated sphere of `m` cells (tool-axis directions);
//! 2. [`visibility`]: the point visibility cone `PVC_j` of every patch as a
//!    set of cells — the binary spherical map — by ray casting through a BVH
//!    (the tool's own volume is ignored, as in the paper);
//! 3. [`search`]: every cell `C_i` is tried as the tool axis; Group II patches
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
}

impl Default for SetupConfig {
    fn default() -> Self {
        Self {
            cells: 1200,
            grazing_margin_deg: 0.0,
            fit_tolerance_deg: 1e-9,
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
    /// Setup search, counted in candidate tool axes (cells).
    Search,
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

/// The search of §4 on a computed map (every cell tried as the tool axis,
/// in parallel).
pub fn search_setup(
    map: &VisibilityMap,
    sphere: &GeodesicSphere,
    kind: MachineType,
    ranges: &AxisRanges,
    config: &SetupConfig,
    progress: &(dyn Fn(Phase, usize, usize) + Sync),
) -> SetupPlan {
    let classes = search::PvcClasses::new(map);
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
    let done = AtomicUsize::new(0);
    /// Candidates per progress report.
    const PROGRESS_EVERY: usize = 256;
    type Best = (Option<SetupOrientation>, Option<SetupOrientation>, bool);
    let better =
        |a: &Option<SetupOrientation>, b: &Option<SetupOrientation>| -> Option<SetupOrientation> {
            match (a, b) {
                (Some(x), Some(y)) => {
                    // Ties go to the lower cell index, so the answer does not
                    // depend on the thread schedule.
                    if (y.placement.key(), y.cell) < (x.placement.key(), x.cell) {
                        Some(*y)
                    } else {
                        Some(*x)
                    }
                }
                (x, None) => *x,
                (None, y) => *y,
            }
        };
    let (mar, setup, three_axis): Best = (0..cells.len())
        .into_par_iter()
        .map_init(
            || {
                (
                    search::Scratch::default(),
                    search::FanScratch::default(),
                    search::RectScratch::default(),
                    Vec::<Vector3<f64>>::new(),
                )
            },
            |(scratch, fan, rect, md), i| {
                let group_ii = search::md_cells(&classes, cells, i, scratch);
                md.clear();
                md.extend(scratch.md.iter().map(|&c| cells[c as usize]));
                let p = &cells[i];
                let (best, fit) = match kind {
                    MachineType::CA => search::fan_search(p, md, ranges, tol, fan),
                    MachineType::AB => search::rect_search(p, md, ranges, tol, resolution, rect),
                };
                let wrap = |placement: Placement| SetupOrientation {
                    placement,
                    cell: i,
                    group_ii_classes: group_ii,
                    md_points: md.len(),
                };
                let n = done.fetch_add(1, Ordering::Relaxed) + 1;
                if n.is_multiple_of(PROGRESS_EVERY) || n == cells.len() {
                    progress(Phase::Search, n, cells.len());
                }
                (Some(wrap(best)), fit.map(wrap), group_ii == 0)
            },
        )
        .reduce(
            || (None, None, false),
            |a, b| (better(&a.0, &b.0), better(&a.1, &b.1), a.2 || b.2),
        );
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
