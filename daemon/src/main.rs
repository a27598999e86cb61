//! `interpd`, the real-time CNC interpolator service.
//!
//! Per `DESIGN.md`, this binary will be the only part of the workspace that owns
//! threads, sockets and files: the tokio control plane, the RT thread that
//! ticks the interpolator and publishes setpoints over iceoryx2, and the
//! recorder thread, behind the subcommands `serve`, `send`, `simulate`,
//! `replay`, `jitter`, `plan` and `trace`, each added by the issue that
//! implements it. For now it has `demo`: the bundled butterfly NURBS through
//! the fixed-period interpolator loop (see [`demo`]).

mod clock;
mod control;
mod demo;
mod demo_service;
mod histogram;
mod jitter;
mod protocol;
mod publish;
mod replay;
mod rt;
mod send;
mod serve;
mod simulate;
mod trace_cmd;
mod watch;

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
    /// Stream the bundled butterfly NURBS through the interpolator loop and print a summary.
    Demo(demo::DemoArgs),
    /// Run the service: RT loop publishing setpoints over iceoryx2, control plane on TCP and a Unix socket.
    Serve(serve::ServeArgs),
    /// Stream a program to a running `interpd serve` with back-pressure.
    Send(send::SendArgs),
    /// Subscribe to the setpoints (iceoryx2) and report gaps.
    Watch(watch::WatchArgs),
    /// Measure wake lateness and tick+publish time: the full pipeline vs a bare loop.
    Jitter(jitter::JitterArgs),
    /// Run a program through the interpolator with no clock; print a summary, write a trace.
    Simulate(simulate::SimulateArgs),
    /// Re-simulate a trace's blocks and compare every setpoint bit for bit.
    Replay(replay::ReplayArgs),
    /// Summarise or plot a recorded trace.
    Trace(trace_cmd::TraceArgs),
}

fn main() -> Result<()> {
    match Cli::parse().command {
        Command::Demo(args) => demo::main(&args),
        Command::Serve(args) => serve::main(&args),
        Command::Send(args) => send::main(&args),
        Command::Watch(args) => watch::main(&args),
        Command::Jitter(args) => jitter::main(&args),
        Command::Simulate(args) => simulate::main(&args),
        Command::Replay(args) => replay::main(&args),
        Command::Trace(args) => trace_cmd::main(&args),
    }
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
        assert!(matches!(cli.command, Command::Demo(_)));
        let cli = Cli::try_parse_from(["interpd", "demo", "--fast", "--json", "--feed", "3000"])
            .expect("demo flags parse");
        let Command::Demo(args) = cli.command else {
            panic!("expected demo");
        };
        assert!(args.fast && args.json);
        assert_eq!(args.feed, 3000.0);
    }
}
