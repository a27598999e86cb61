//! `interpd`, the real-time CNC interpolator service: the command line over
//! the `interpd` library (`lib.rs`). `cli.rs` holds the flags, and each
//! `command/<verb>.rs` wires one subcommand to the library.

mod cli;
mod command;

use anyhow::{Context, Result};
use clap::Parser;
use interpd::service::rt::RT_STACK_BYTES;
use interpd::service::rt_alloc;

use cli::{Cli, Command};

/// The system allocator behind the RT thread's fixed pool (`rt_alloc`):
/// iceoryx2 allocates a small object per published sample. The library's
/// unit tests install the same pool in front of a counting allocator.
#[global_allocator]
static ALLOCATOR: rt_alloc::RtPool<std::alloc::System> = rt_alloc::RtPool(std::alloc::System);

/// Runs the command on a thread with the RT threads' stack
/// ([`RT_STACK_BYTES`]), so that none depends on the main thread's 8 MiB:
/// `simulate`, `replay` and `demo` build an `interp_run::Run` on the stack
/// before boxing it, which an unoptimised build copies several times
/// (`interpd simulate` needs 12–14 MiB there). Only pages touched are
/// committed.
fn main() -> Result<()> {
    let cli = Cli::parse();
    std::thread::Builder::new()
        .name("interpd".into())
        .stack_size(RT_STACK_BYTES)
        .spawn(move || dispatch(cli))
        .context("spawning the command thread")?
        .join()
        .unwrap_or_else(|panic| std::panic::resume_unwind(panic))
}

fn dispatch(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Demo(args) => command::demo::run(&args.into()),
        Command::Serve(args) => command::serve::run(&args.into()),
        Command::Send(args) => command::send::run(&args.into()),
        Command::Watch(args) => command::watch::run(&args.into()),
        Command::Jitter(args) => command::jitter::run(&args.into()),
        Command::Simulate(args) => command::simulate::run(&args.into()),
        Command::Replay(args) => command::replay::run(&args),
        Command::Trace(args) => command::trace::run(&args),
        Command::Plan(cmd) => command::plan::run(cmd),
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
        // No flags: the library's documented defaults.
        let Command::Demo(args) = Cli::try_parse_from(["interpd", "demo"]).unwrap().command else {
            panic!("expected demo");
        };
        let opts: interpd::tools::demo::DemoOptions = args.into();
        assert_eq!(opts, interpd::tools::demo::DemoOptions::default());
        assert!(Cli::try_parse_from(["interpd", "demo", "--period-us", "0"]).is_err());
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
        let Command::Plan(cli::PlanCommand::Raster(args)) = cli.command else {
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
        let Command::Plan(cli::PlanCommand::Setup(args)) = cli.command else {
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
