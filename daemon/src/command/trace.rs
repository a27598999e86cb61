//! `interpd trace summary` and `interpd trace plot`: a recorded run's
//! summary, and the seed paper's figures as PNG and SVG.

use std::path::PathBuf;

use anyhow::{Context, Result};
use traces::Trace;
use traces::analysis::analyse;
use traces::plot::plot_trace;

/// `interpd trace`.
#[derive(Clone, Debug, clap::Args)]
pub struct TraceArgs {
    #[command(subcommand)]
    pub command: TraceCommand,
}

/// What to do with a trace.
#[derive(Clone, Debug, clap::Subcommand)]
pub enum TraceCommand {
    /// Print the run's summary (as `interpd simulate` does).
    Summary {
        /// The trace (MCAP).
        trace: PathBuf,
        /// Print it as one JSON object.
        #[arg(long)]
        json: bool,
    },
    /// Write PNG and SVG plots: feed, curvature, chord error, MRR,
    /// acceleration, jerk, XY/XZ path, wake lateness (real-time runs).
    Plot {
        /// The trace (MCAP).
        trace: PathBuf,
        /// Directory for the plots (made if missing).
        #[arg(long, value_name = "DIR")]
        out: PathBuf,
    },
}

/// Opens a trace; one cut short (its recorder died with the service) is
/// taken up to its last complete chunk, with a note saying so.
fn open(path: &PathBuf) -> Result<Trace> {
    let (trace, damage) =
        Trace::open_recovering(path).with_context(|| format!("reading {}", path.display()))?;
    if let Some(note) = damage {
        eprintln!("note: {} is {note}", path.display());
    }
    Ok(trace)
}

/// Runs `interpd trace …`.
pub fn run(args: &TraceArgs) -> Result<()> {
    match &args.command {
        TraceCommand::Summary { trace, json } => {
            let t = open(trace)?;
            let (summary, _) =
                analyse(&t).with_context(|| format!("analysing {}", trace.display()))?;
            if *json {
                println!("{}", serde_json::to_string(&summary)?);
            } else {
                print!("{summary}");
            }
        }
        TraceCommand::Plot { trace, out } => {
            let t = open(trace)?;
            let (summary, samples) =
                analyse(&t).with_context(|| format!("analysing {}", trace.display()))?;
            let report = plot_trace(&t, &samples, &summary, out)?;
            for f in &report.files {
                println!("{}", f.display());
            }
            for n in &report.notes {
                eprintln!("note: {n}");
            }
        }
    }
    Ok(())
}
