//! The offline planners' commands over `planner`: raster finishing
//! ([`raster`]), gouge correction and NURBS fitting ([`gouge`]), 5-axis
//! setup ([`setup`]), and how their paths are written as G-code ([`writer`]).

pub mod gouge;
pub mod raster;
pub mod setup;
