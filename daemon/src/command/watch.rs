//! `interpd watch`: subscribes to the setpoints and reports gaps, restarts and silence.

use anyhow::Result;
use interpd::client::watch::{WatchArgs, main};

/// Runs the command.
pub fn run(args: &WatchArgs) -> Result<()> {
    main(args)
}
