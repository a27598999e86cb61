//! Offline tool-path planning for interpd.
//!
//! Per `DESIGN.md`, this crate holds the mesh reader ([`mesh`]: binary and
//! ASCII STL, welded, rejecting NaN), raster finishing by slicing offset
//! triangles (seed `001_…`), gouge detection and correction with milled-surface
//! prediction (seed `003_…`), fitting of corrected CL polylines to NURBS blocks
//! written as G6.2, and 5-axis setup orientation (seed `000_…`). Unlike
//! `interp-core`, it may allocate and use all cores.

pub mod cutter;
pub mod fit;
pub mod gouge;
#[cfg(feature = "gcode")]
pub mod io;
pub mod mesh;
pub mod predict;
pub mod raster;
pub mod setup;

/// The smallest tolerance that means something for a part whose coordinates
/// reach `extent` mm: an f64 coordinate there is resolved to about
/// `extent · ε`, and a tolerance within 64 of those steps is round-off (and
/// asks a planner for more points than memory holds).
pub fn min_tolerance(extent: f64) -> f64 {
    64.0 * f64::EPSILON * extent.abs().max(1.0)
}
