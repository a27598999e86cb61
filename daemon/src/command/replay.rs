//! `interpd replay`: re-simulate a trace's blocks under its recorded config and
//! compare every setpoint bit for bit (`traces::replay`).

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use traces::Trace;
use traces::replay::{ReplayError, replay, replay_truncated};

/// Options of `interpd replay`.
#[derive(Clone, Debug, clap::Args)]
pub struct ReplayArgs {
    /// The trace (MCAP) to replay.
    pub trace: PathBuf,
}

/// Replays; fails naming the first differing sequence number and field. A
/// trace cut short (its recorder died with the service) is replayed up to
/// its last complete chunk, with a note saying so.
pub fn run(args: &ReplayArgs) -> Result<()> {
    let path = args.trace.display();
    let (trace, damage) =
        Trace::open_recovering(&args.trace).with_context(|| format!("reading {path}"))?;
    let result = match &damage {
        Some(note) => {
            eprintln!("note: {path} is {note}");
            replay_truncated(&trace)
        }
        None => replay(&trace),
    };
    match result {
        Ok(r) => {
            println!(
                "replay of {path}: {} setpoints bit-identical ({} input blocks){}{}",
                r.compared,
                r.blocks,
                if r.missing_in_trace > 0 {
                    format!("; {} setpoints missing from the trace", r.missing_in_trace)
                } else {
                    String::new()
                },
                if damage.is_some() {
                    "; the trace is truncated: compared up to its last complete chunk"
                } else {
                    ""
                }
            );
            Ok(())
        }
        Err(ReplayError::Mismatch(m)) => bail!("replay of {path} differs: {m}"),
        Err(e) => Err(e).with_context(|| format!("replaying {path}")),
    }
}
