//! The command line: clap's definition of every subcommand.

use clap::{Parser, Subcommand};
use interpd::client::{send, watch};
use interpd::service::serve;
use interpd::tools::{demo, jitter, simulate};

use crate::command::{plan::PlanCommand, replay, trace};

/// Real-time CNC interpolator service.
#[derive(Debug, Parser)]
#[command(name = "interpd", version)]
pub struct Cli {
    /// The subcommand.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
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
    Trace(trace::TraceArgs),
    /// Offline planners: meshes to tool paths.
    #[command(subcommand)]
    Plan(PlanCommand),
}
