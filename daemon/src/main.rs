//! `interpd`, the real-time CNC interpolator service.
//!
//! Per `DESIGN.md`, this binary will be the only part of the workspace that owns
//! threads, sockets and files: the tokio control plane, the RT thread that
//! ticks the interpolator and publishes setpoints over iceoryx2, and the
//! recorder thread, behind the subcommands `serve`, `send`, `simulate`,
//! `replay`, `jitter`, `plan` and `trace`, each added by the issue that
//! implements it. For now it only has `demo`, which issue 8 wires to the
//! interpolator.

use anyhow::Result;
use clap::{Parser, Subcommand};

/// Real-time CNC interpolator service.
#[derive(Debug, Parser)]
#[command(name = "interpd", version)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Run the interpolator on a built-in program and print what it did (not wired yet).
    Demo,
}

fn main() -> Result<()> {
    match Cli::parse().command {
        Command::Demo => demo(),
    }
}

fn demo() -> Result<()> {
    // TODO(issue-8-demo): wire the interpolator
    println!("demo: not wired yet");
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    #[test]
    fn cli_definition_is_consistent() {
        Cli::command().debug_assert();
    }

    #[test]
    fn demo_subcommand_parses() {
        let cli = Cli::try_parse_from(["interpd", "demo"]).expect("demo parses");
        assert!(matches!(cli.command, Command::Demo));
    }
}
