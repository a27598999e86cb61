//! `interpd demo`: the bundled butterfly through the loop and the service, checked.

use anyhow::Result;
use interpd::tools::demo::{DemoOptions, main};

/// Runs the command.
pub fn run(args: &DemoOptions) -> Result<()> {
    main(args)
}
