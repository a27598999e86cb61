//! `interpd plan raster|setup|gouge|fit`: the offline planners.

use anyhow::Result;
use interpd::plan::{gouge, raster, setup};

/// `interpd plan …` subcommands.
#[derive(Debug, clap::Subcommand)]
pub enum PlanCommand {
    /// Raster finishing over an STL mesh by slicing the offset triangle mesh.
    Raster(raster::RasterArgs),
    /// 5-axis machinability and setup orientation of an STL part.
    Setup(setup::SetupArgs),
    /// Check a G1 path for gouges against an STL part, correct it, and predict the milled surface.
    Gouge(gouge::GougeArgs),
    /// Fit G1 paths into G6.2 NURBS blocks within a tolerance.
    Fit(gouge::FitArgs),
}

/// Runs the command.
pub fn run(cmd: &PlanCommand) -> Result<()> {
    match cmd {
        PlanCommand::Raster(args) => raster::main(args),
        PlanCommand::Setup(args) => setup::main(args),
        PlanCommand::Gouge(args) => gouge::gouge_main(args),
        PlanCommand::Fit(args) => gouge::fit_main(args),
    }
}
