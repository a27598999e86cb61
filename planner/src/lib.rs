//! Offline tool-path planning for interpd.
//!
//! Per `DESIGN.md`, this crate will hold the mesh reader (binary and ASCII STL,
//! rejecting NaN and degenerate input), raster finishing by slicing offset
//! triangles (seed `001_…`), gouge detection and correction with milled-surface
//! prediction (seed `003_…`), fitting of corrected CL polylines to NURBS blocks
//! written as G6.2, and 5-axis setup orientation (seed `000_…`). Unlike
//! `interp-core`, it may allocate and use all cores.
//!
//! Empty for now: the later planner issues fill it.
