//! `interpd simulate`: runs a program with no clock and prints its summary.

use anyhow::Result;
use interpd::tools::simulate::{self, SimulateOptions};

/// `interpd simulate`.
pub fn run(args: &SimulateOptions) -> Result<()> {
    let summary = simulate::run(args)?;
    if args.json {
        println!("{}", serde_json::to_string(&summary)?);
    } else {
        print!("{summary}");
        if let Some(p) = &args.out {
            println!("  trace         {}", p.display());
        }
    }
    Ok(())
}
