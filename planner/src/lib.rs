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
pub mod mesh;
pub mod predict;
pub mod raster;
pub mod setup;
