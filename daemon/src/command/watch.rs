//! `interpd watch`: subscribes to the setpoints and reports gaps, restarts and silence.

use anyhow::Result;
use interpd::client::watch::{WatchOptions, main};

/// Runs the command.
pub fn run(args: &WatchOptions) -> Result<()> {
    main(args)
}
