//! `interpd demo`: the bundled butterfly through the loop and the service, checked.

use anyhow::Result;
use interpd::tools::demo::{DemoArgs, main};

/// Runs the command.
pub fn run(args: &DemoArgs) -> Result<()> {
    main(args)
}
