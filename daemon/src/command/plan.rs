//! `interpd plan raster|setup|gouge|fit`: the offline planners.

use anyhow::Result;
use interpd::plan::{gouge, raster, setup};

use crate::cli::PlanCommand;

/// Runs the command.
pub fn run(cmd: PlanCommand) -> Result<()> {
    match cmd {
        PlanCommand::Raster(args) => raster::main(&args.into()),
        PlanCommand::Setup(args) => setup::main(&args.into()),
        PlanCommand::Gouge(args) => gouge::gouge_main(&args.into()),
        PlanCommand::Fit(args) => gouge::fit_main(&args.into()),
    }
}
