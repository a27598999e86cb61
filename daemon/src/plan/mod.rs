//! The offline planners' commands over `planner`: raster finishing
//! ([`raster`]), gouge correction and NURBS fitting ([`gouge`]), 5-axis
//! setup ([`setup`]). CL programs are read and paths written as G-code by
//! `planner::io`.

pub mod gouge;
pub mod raster;
pub mod setup;
