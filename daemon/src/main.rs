//! `interpd`, the real-time CNC interpolator service: the command line over
//! the `interpd` library (`lib.rs`).

use interpd::{
    demo, jitter, plan_gouge, plan_raster, plan_setup, replay, rt_alloc, send, serve, simulate,
    trace_cmd, watch,
};

/// The system allocator behind the RT thread's fixed pool (`rt_alloc`):
/// iceoryx2 allocates a small object per published sample. The library's
/// unit tests install the same pool in front of a counting allocator.
#[global_allocator]
static ALLOCATOR: rt_alloc::RtPool<std::alloc::System> = rt_alloc::RtPool(std::alloc::System);

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
    /// Offline planners: meshes to tool paths.
    #[command(subcommand)]
    Plan(PlanCommand),
}

/// `interpd plan …` subcommands.
#[derive(Debug, Subcommand)]
enum PlanCommand {
    /// Raster finishing over an STL mesh by slicing the offset triangle mesh.
    Raster(plan_raster::RasterArgs),
    /// 5-axis machinability and setup orientation of an STL part.
    Setup(plan_setup::SetupArgs),
    /// Check a G1 path for gouges against an STL part, correct it, and predict the milled surface.
    Gouge(plan_gouge::GougeArgs),
    /// Fit G1 paths into G6.2 NURBS blocks within a tolerance.
    Fit(plan_gouge::FitArgs),
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
        Command::Plan(PlanCommand::Raster(args)) => plan_raster::main(&args),
        Command::Plan(PlanCommand::Setup(args)) => plan_setup::main(&args),
        Command::Plan(PlanCommand::Gouge(args)) => plan_gouge::gouge_main(&args),
        Command::Plan(PlanCommand::Fit(args)) => plan_gouge::fit_main(&args),
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

    #[test]
    fn plan_raster_subcommand_parses() {
        let cli = Cli::try_parse_from([
            "interpd",
            "plan",
            "raster",
            "--stl",
            "part.stl",
            "--tool",
            "ball:6",
            "--stepover",
            "0.5",
            "--angle",
            "30",
            "--zigzag",
            "--out",
            "part.ngc",
            "--json",
        ])
        .expect("plan raster parses");
        let Command::Plan(PlanCommand::Raster(args)) = cli.command else {
            panic!("plan raster parsed as another command");
        };
        assert_eq!(args.tool, planner::cutter::Cutter::Ball { diameter: 6.0 });
        assert!(args.zigzag && args.json);
        assert_eq!((args.stepover, args.angle), (0.5, 30.0));
        assert!(
            Cli::try_parse_from([
                "interpd", "plan", "raster", "--stl", "a.stl", "--tool", "cone:6"
            ])
            .is_err()
        );
    }

    #[test]
    fn plan_setup_parses_and_refuses_bad_machines() {
        let cli = Cli::try_parse_from([
            "interpd",
            "plan",
            "setup",
            "--stl",
            "p.stl",
            "--machine",
            "W/caxyBz/T",
            "--ranges",
            "30,20,180,180",
            "--cells",
            "5000",
            "--json",
        ])
        .expect("plan setup parses");
        let Command::Plan(PlanCommand::Setup(args)) = cli.command else {
            panic!("expected plan setup");
        };
        assert_eq!((args.cells, args.json), (5000, true));
        assert_eq!(args.machine.key().to_string(), "caB");
        assert!((args.ranges.degrees()[1] - 20.0).abs() < 1e-12);
        for bad in [
            ["--machine", "W/xyBzac/T", "--ranges", "1,1,1,1"],
            ["--machine", "W/caxyBz/T", "--ranges", "1,2,1,1"],
        ] {
            let mut argv = vec!["interpd", "plan", "setup", "--stl", "p.stl"];
            argv.extend(bad);
            assert!(Cli::try_parse_from(argv).is_err(), "{bad:?}");
        }
    }
}
