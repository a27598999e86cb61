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
//! 3. [`search`], [`fan`], [`rect`]: for a cell `C_i` as the tool axis, the
//!    Group II patches (not reachable from `C_i`, eq. 3) are represented by
//!    their MD points (eq. 4); the C,A fan search (eq. 5–13, exact over every
//!    fan placement) or the A,B spherical-rectangle search (eq. 14–21,
//!    certified over every turn of the rectangle) sizes the least FTM⁵ that
//!    holds them;
//! 4. `optimum`: the least over every cell, with lower bounds that rule
//!    cells out without evaluating them, certified. The least-area placement
//!    that fits the machine is the setup; if none fits, the least-area one
//!    overall gives the minimum axis ranges (MAR) to ask for.
//!
//! See `docs/planner-setup.md`.

pub mod fan;
pub mod machine;
mod optimum;
pub mod rect;
pub mod samples;
pub mod search;
pub mod sphere;
pub mod visibility;

/// Helpers the fan and rectangle searches' unit tests share.
#[cfg(test)]
mod test_support {
    use super::AxisRanges;
    use nalgebra::Vector3;

    /// Axis ranges from degrees.
    pub(crate) fn ranges(deg: [f64; 4]) -> AxisRanges {
        AxisRanges::from_degrees(deg[0], deg[1], deg[2], deg[3]).unwrap()
    }

    /// The unit direction at `tilt_deg` from +Z, `azimuth_deg` from +X.
    pub(crate) fn dir(tilt_deg: f64, azimuth_deg: f64) -> Vector3<f64> {
        let (t, a) = (tilt_deg.to_radians(), azimuth_deg.to_radians());
        Vector3::new(t.sin() * a.cos(), t.sin() * a.sin(), t.cos())
    }
}

pub use machine::{AxisRanges, MachineConfig, MachineType, RotaryAxis, RotaryPositions};
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
    /// A cell is in a patch's cone when any of its directions reaches the
    /// patch, tested exactly (default); off, only its centre direction is
    /// tested, and cones narrower than the cell spacing can fall between
    /// the centres.
    pub exact_cells: bool,
    /// Slack when comparing needed and available ranges, degrees. Default
    /// 1e-9 (round-off only).
    pub fit_tolerance_deg: f64,
    /// Cells of a coarse sphere whose nearest cells are evaluated first to
    /// seed the lower bounds of the search; 0 (or a sphere with at most 4×
    /// as many cells) evaluates every cell exactly. The answer does not
    /// depend on it, only the time. Default 20 (the icosahedron's faces):
    /// the search then evaluates the cells near the best first, and every
    /// sphere size measured ran fastest with it (BENCHMARKS.md).
    pub probe_cells: usize,
    /// Setups whose area is within what `equivalent_cells` cell spacings
    /// more on both range sums of the best would add are reported as
    /// equivalent to it (a flat optimum). Default 1.
    pub equivalent_cells: f64,
}

impl Default for SetupConfig {
    fn default() -> Self {
        Self {
            cells: 1200,
            grazing_margin_deg: 0.0,
            exact_cells: true,
            fit_tolerance_deg: 1e-9,
            probe_cells: 20,
            equivalent_cells: 1.0,
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
    /// Lower bounds of the setup search, counted in the cells of the round.
    Search,
    /// Exact evaluations of the setup search (probes, then the cells the
    /// bounds could not rule out), counted in the cells of the round.
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
    /// Patches whose cone is about as narrow as the cell spacing or
    /// narrower (no cell of it is surrounded by cells of it): reachable,
    /// but the answer places their directions only to a cell or so; a finer
    /// sphere resolves them (`VisibilityMap::narrow`).
    pub narrow_patches: Vec<usize>,
    /// Whether one direction reaches every reachable patch (3-axis, `FTM³`).
    pub three_axis: bool,
    /// Whether the machine's ranges hold every patch in one setup (eq. 1).
    pub feasible: bool,
    /// The least-area placement that fits the machine, if any: the setup.
    pub setup: Option<SetupOrientation>,
    /// The least-area placement overall: its ranges are the minimum axis
    /// ranges (MAR) the part needs on this machine type.
    pub mar: SetupOrientation,
    /// Tool axes (cells) evaluated exactly; the others were ruled out by a
    /// lower bound.
    pub evaluated: usize,
}

/// One placement with the bookkeeping of its candidate and its certificate.
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
    /// No placement on this map has a smaller key (area rad², then sum of
    /// ranges rad): `placement.area − lower_bound.0` is how far from the
    /// optimum the answer can be (0 but for the A,B turn's tolerance).
    pub lower_bound: (f64, f64),
    /// Other tool axes whose area is within `equivalent_tolerance` of this
    /// one's (a flat optimum), and the largest angle from this tool axis to
    /// theirs (radians); `None` when not searched for (the MAR of a part
    /// that fits).
    pub equivalent: Option<(usize, f64)>,
    /// The area tolerance of `equivalent`, rad².
    pub equivalent_tolerance: f64,
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
            exact_cells: config.exact_cells,
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

/// The search of §4 on a computed map: every cell is a candidate tool axis,
/// and the least key over all of them is found and certified (see
/// `optimum`). To search one map for several machines, prepare it once
/// ([`PreparedMap`]).
pub fn search_setup(
    map: &VisibilityMap,
    sphere: &GeodesicSphere,
    kind: MachineType,
    ranges: &AxisRanges,
    config: &SetupConfig,
    progress: &(dyn Fn(Phase, usize, usize) + Sync),
) -> SetupPlan {
    PreparedMap::new(map, sphere).search(kind, ranges, config, progress)
}

/// What the search needs from a map whatever the machine: the patches
/// grouped by identical cones ([`search::PvcClasses`], a pass over the
/// whole map), the unreachable and narrow patches, and the cells in every
/// cone. Made once, it serves any number of searches of that map.
#[derive(Debug)]
pub struct PreparedMap<'a> {
    map: &'a VisibilityMap,
    sphere: &'a GeodesicSphere,
    classes: search::PvcClasses,
    unreachable_patches: Vec<usize>,
    narrow_patches: Vec<usize>,
    common: Vec<usize>,
}

impl<'a> PreparedMap<'a> {
    /// Groups the patches of `map` (computed on `sphere`).
    pub fn new(map: &'a VisibilityMap, sphere: &'a GeodesicSphere) -> Self {
        let classes = search::PvcClasses::new(map, sphere.cells());
        let unreachable_patches = classes
            .class_of
            .iter()
            .enumerate()
            .filter(|(_, c)| c.is_none())
            .map(|(j, _)| j)
            .collect();
        // Whether one direction reaches every reachable patch: the cells in
        // all cones (exact, whatever the search tries).
        let common = classes.common_cells();
        Self {
            map,
            sphere,
            classes,
            unreachable_patches,
            narrow_patches: (0..map.patches())
                .filter(|&j| map.narrow(j, sphere))
                .collect(),
            common,
        }
    }

    /// Number of classes of identical cones.
    pub fn classes(&self) -> usize {
        self.classes.classes
    }

    /// [`search_setup`] on the prepared map.
    pub fn search(
        &self,
        kind: MachineType,
        ranges: &AxisRanges,
        config: &SetupConfig,
        progress: &(dyn Fn(Phase, usize, usize) + Sync),
    ) -> SetupPlan {
        let (map, sphere, classes, common) = (self.map, self.sphere, &self.classes, &self.common);
        let problem = optimum::Problem {
            map,
            classes,
            sphere,
            kind,
            ranges,
            tol: config.fit_tolerance_deg.to_radians(),
            equivalent: config.equivalent_cells.max(0.0) * sphere.spacing(),
            probe_cells: config.probe_cells,
        };
        let out = optimum::search(&problem, common, progress);
        let orientation = |o: &optimum::Optimum| SetupOrientation {
            placement: o.placement,
            cell: o.cell,
            group_ii_classes: o.group_ii,
            md_points: o.md_points,
            lower_bound: o.lower_bound,
            equivalent: o.equivalent,
            equivalent_tolerance: o.tolerance,
        };
        let setup = out.fit.as_ref().map(orientation);
        SetupPlan {
            machine_type: kind,
            cells: sphere.len(),
            patches: map.patches(),
            pvc_classes: classes.classes,
            unreachable_patches: self.unreachable_patches.clone(),
            narrow_patches: self.narrow_patches.clone(),
            three_axis: !common.is_empty(),
            feasible: setup.is_some() && self.unreachable_patches.is_empty(),
            setup,
            mar: orientation(&out.mar),
            evaluated: out.evaluated,
        }
    }
}
