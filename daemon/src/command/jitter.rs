//! `interpd jitter`: wake lateness and tick time, the pipeline against bare loops.

use anyhow::Result;
use interpd::tools::jitter::{JitterOptions, main};

/// Runs the command.
pub fn run(args: &JitterOptions) -> Result<()> {
    main(args)
}
