//! The command line: clap's definition of every subcommand.

use std::net::{IpAddr, SocketAddr};
use std::path::PathBuf;

use clap::builder::TypedValueParser;
use clap::{Parser, Subcommand};
use interpd::client::send::SendOptions;
use interpd::client::watch::{DEFAULT_LIVENESS_S, WatchOptions};
use interpd::plan::gouge::{FitOptions, GougeOptions};
use interpd::plan::raster::{DEFAULT_BLEND_TOLERANCE, RasterOptions};
use interpd::plan::setup::SetupOptions;
use interpd::service::publish::DEFAULT_SERVICE;
use interpd::service::rt::{DEFAULT_PERIOD_US, DEFAULT_PLAN_LEAD_MS, DEFAULT_PRIORITY, RtSettings};
use interpd::service::serve::{DEFAULT_PORT, ServeOptions};
use interpd::tools::demo;
use interpd::tools::demo::DemoOptions;
use interpd::tools::jitter::JitterOptions;
use interpd::tools::simulate::SimulateOptions;
use planner::cutter::Cutter;
use planner::fit::FitConfig;
use planner::gouge::GougeConfig;
use planner::mesh::WeldOptions;
use planner::predict::PredictConfig;
use planner::raster::RasterConfig;
use planner::setup::{AxisRanges, MachineConfig, SetupConfig};
use traces::writer::TraceCompression;

use crate::command::{replay, trace};
use interpd::flags;

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
    Demo(DemoArgs),
    /// Run the service: RT loop publishing setpoints over iceoryx2, control plane on TCP and a Unix socket.
    Serve(ServeArgs),
    /// Stream a program to a running `interpd serve` with back-pressure.
    Send(SendArgs),
    /// Subscribe to the setpoints (iceoryx2) and report gaps.
    Watch(WatchArgs),
    /// Measure wake lateness and tick+publish time: the full pipeline vs a bare loop.
    Jitter(JitterArgs),
    /// Run a program through the interpolator with no clock; print a summary, write a trace.
    Simulate(SimulateArgs),
    /// Re-simulate a trace's blocks and compare every setpoint bit for bit.
    Replay(replay::ReplayArgs),
    /// Summarise or plot a recorded trace.
    Trace(trace::TraceArgs),
    /// Offline planners: meshes to tool paths.
    #[command(subcommand)]
    Plan(PlanCommand),
}

/// Options of `interpd send`.
#[derive(Clone, Debug, clap::Args)]
pub struct SendArgs {
    /// The program: G-code (`.ngc`/`.nc`), a JSON program (`.json`), or JSON
    /// blocks one per line (`.jsonl`; blank lines and `#` comments skipped).
    pub program: PathBuf,
    /// TCP address of the server.
    #[arg(long, default_value_t = SocketAddr::from(([127, 0, 0, 1], DEFAULT_PORT)))]
    pub addr: SocketAddr,
    /// Connect to this Unix socket instead of TCP.
    #[arg(long, value_name = "PATH")]
    pub socket: Option<PathBuf>,
    /// Token, if the server wants one.
    #[arg(long)]
    pub token: Option<String>,
    /// Do not wait for the program to finish.
    #[arg(long)]
    pub no_wait: bool,
    /// When another connection's program holds the machine, wait for it to
    /// end and take the next turn (without it, `send` is refused at once,
    /// naming the program's owner and how long it has held it).
    #[arg(long)]
    pub wait_turn: bool,
    /// Print the final status as JSON.
    #[arg(long)]
    pub json: bool,
    /// No progress output.
    #[arg(long)]
    pub quiet: bool,
}

impl From<SendArgs> for SendOptions {
    fn from(a: SendArgs) -> Self {
        SendOptions {
            program: a.program,
            addr: a.addr,
            socket: a.socket,
            token: a.token,
            no_wait: a.no_wait,
            wait_turn: a.wait_turn,
            json: a.json,
            quiet: a.quiet,
        }
    }
}

/// Options of `interpd watch`.
#[derive(Clone, Debug, clap::Args)]
pub struct WatchArgs {
    /// iceoryx2 service name.
    #[arg(long, default_value = DEFAULT_SERVICE)]
    pub service: String,
    /// Stop after this many samples.
    #[arg(long)]
    pub count: Option<u64>,
    /// Stop after this many seconds (0 < S ≤ 86400).
    #[arg(long, value_parser = flags::SECONDS.parser())]
    pub seconds: Option<f64>,
    /// Stop at the first sample in state `done` after one that was moving.
    #[arg(long)]
    pub until_done: bool,
    /// Give up when no sample arrives for this many seconds: the publisher
    /// is dead (or was never there).
    #[arg(long, value_name = "SECONDS", default_value_t = DEFAULT_LIVENESS_S,
          value_parser = flags::LIVENESS.parser())]
    pub liveness: f64,
    /// Write every sample (seq,tick,time,x,y,z,feed,u,s,block_id,state) to this CSV.
    #[arg(long, value_name = "PATH")]
    pub csv: Option<PathBuf>,
    /// Print a line per this many samples (0: none).
    #[arg(long, default_value_t = 0)]
    pub every: u64,
    /// Print the summary as JSON.
    #[arg(long)]
    pub json: bool,
    /// Check every tick against the default machine limits for a program
    /// at this feed, mm/min (the setpoint checker, `interp_run::check`),
    /// from the first sample at rest before tick 1; a failed check makes
    /// it exit non-zero.
    #[arg(long, value_name = "MM_PER_MIN", value_parser = flags::FEED.parser())]
    pub check_feed: Option<f64>,
    /// The service's interpolation period, µs (for `--check-feed`; 250..=10000, as `serve`).
    #[arg(long, value_name = "US", default_value_t = 1000,
          value_parser = clap::value_parser!(u32).range(250..=10_000))]
    pub check_period_us: u32,
}

impl From<WatchArgs> for WatchOptions {
    fn from(a: WatchArgs) -> Self {
        WatchOptions {
            service: a.service,
            count: a.count,
            seconds: a.seconds,
            until_done: a.until_done,
            liveness: a.liveness,
            csv: a.csv,
            every: a.every,
            json: a.json,
            check_feed: a.check_feed,
            check_period_us: a.check_period_us,
        }
    }
}

/// The RT thread's scheduling flags, shared by `interpd serve` and
/// `interpd jitter` so that both loops of a jitter run are scheduled as
/// `serve` would be.
#[derive(Clone, Debug, clap::Args)]
pub struct RtArgs {
    /// Interpolation period, µs (250..=10000).
    #[arg(long, value_name = "US", default_value_t = DEFAULT_PERIOD_US,
          value_parser = clap::value_parser!(u32).range(250..=10_000))]
    pub period_us: u32,
    /// SCHED_FIFO priority of the RT thread (1..=99); the planning thread
    /// runs at half of it.
    #[arg(long, default_value_t = DEFAULT_PRIORITY,
          value_parser = clap::value_parser!(i32).range(1..=99))]
    pub priority: i32,
    /// Normal scheduling: no SCHED_FIFO, no mlockall, no pinning.
    #[arg(long)]
    pub no_rt: bool,
    /// CPU to pin the RT thread to (default: the last one).
    #[arg(long)]
    pub cpu: Option<usize>,
    /// Wake this many µs before each deadline and spin on the clock to it
    /// (at most half the period). Keeps the core awake so that the setpoint
    /// goes out on time, at the cost of that much CPU per period; 0 sleeps
    /// to the deadline.
    #[arg(long, value_name = "US", default_value_t = 0)]
    pub spin_us: u32,
    /// How far the planning thread runs ahead of the RT thread, ms
    /// (2..=1000): a hold, override or abort takes effect this much later;
    /// planning may take this long without the RT thread waiting for it.
    #[arg(long, value_name = "MS", default_value_t = DEFAULT_PLAN_LEAD_MS,
          value_parser = clap::value_parser!(u32).range(2..=1000))]
    pub plan_lead_ms: u32,
}

impl From<RtArgs> for RtSettings {
    fn from(a: RtArgs) -> Self {
        RtSettings {
            period_us: a.period_us,
            priority: a.priority,
            no_rt: a.no_rt,
            cpu: a.cpu,
            spin_us: a.spin_us,
            plan_lead_ms: a.plan_lead_ms,
        }
    }
}

/// Options of `interpd serve`.
#[derive(Clone, Debug, clap::Args)]
pub struct ServeArgs {
    /// The RT thread's period and scheduling.
    #[command(flatten)]
    pub rt: RtArgs,
    /// TCP address to listen on (loopback unless --allow-remote).
    #[arg(long, default_value = "127.0.0.1")]
    pub listen: IpAddr,
    /// TCP port (0: any free port, printed at start).
    #[arg(long, default_value_t = DEFAULT_PORT)]
    pub port: u16,
    /// Allow listening beyond loopback (needs --token).
    #[arg(long)]
    pub allow_remote: bool,
    /// Token every connection must send first (`auth TOKEN`).
    #[arg(long)]
    pub token: Option<String>,
    /// Unix socket path (mode 0600); default `$XDG_RUNTIME_DIR/interpd.sock` or `/tmp/interpd-UID.sock`.
    #[arg(long, value_name = "PATH")]
    pub socket: Option<PathBuf>,
    /// Do not listen on a Unix socket.
    #[arg(long)]
    pub no_socket: bool,
    /// iceoryx2 service name of the setpoints.
    #[arg(long, default_value = DEFAULT_SERVICE)]
    pub service: String,
    /// The first program moves without waiting for `start`.
    #[arg(long)]
    pub autostart: bool,
    /// Start position X Y Z (mm), and A B C (degrees, default 0).
    #[arg(long, num_args = 3..=6, value_names = ["X", "Y", "Z", "A", "B", "C"], allow_negative_numbers = true)]
    pub position: Option<Vec<f64>>,
    /// TOML configuration: the `[interp]` table, as `simulate --config`
    /// reads it (the five-axis machine is `[interp.machine]`).
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Override any `[interp]` key, e.g. `--set planning-margin=0.05` (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// The five-axis machine description (TOML, docs/five-axis.md; e.g.
    /// examples/five_axis/machine.toml), over `[interp.machine]`.
    #[arg(long, value_name = "FILE")]
    pub machine: Option<PathBuf>,
    /// Record the run to this MCAP trace (config, blocks, setpoints, loop
    /// timing, events, the schedule of pushes and commands) through the
    /// `traces` recorder; `interpd replay` of it reproduces every setpoint of
    /// the session bit for bit (several programs, hold, resume, override,
    /// abort; not yet past a look-ahead refusal mid-program), up to its last
    /// complete chunk if `serve` was killed.
    #[arg(long, value_name = "PATH")]
    pub record: Option<PathBuf>,
    /// Print the final summary as JSON.
    #[arg(long)]
    pub json: bool,
}

impl From<ServeArgs> for ServeOptions {
    fn from(a: ServeArgs) -> Self {
        ServeOptions {
            rt: a.rt.into(),
            listen: a.listen,
            port: a.port,
            allow_remote: a.allow_remote,
            token: a.token,
            socket: a.socket,
            no_socket: a.no_socket,
            service: a.service,
            autostart: a.autostart,
            position: a.position,
            config: a.config,
            set: a.set,
            machine: a.machine,
            record: a.record,
            json: a.json,
        }
    }
}

/// Options of `interpd jitter`.
#[derive(Clone, Debug, clap::Args)]
pub struct JitterArgs {
    /// Seconds for each of the two loops.
    #[arg(long, default_value_t = 10.0, value_parser = flags::SECONDS.parser())]
    pub seconds: f64,
    /// Period and scheduling of both loops, as `interpd serve` takes them.
    #[command(flatten)]
    pub rt: RtArgs,
    /// Print the result as JSON.
    #[arg(long)]
    pub json: bool,
}

impl From<JitterArgs> for JitterOptions {
    fn from(a: JitterArgs) -> Self {
        JitterOptions {
            seconds: a.seconds,
            rt: a.rt.into(),
            json: a.json,
        }
    }
}

/// Options of `interpd demo`.
#[derive(Clone, Debug, clap::Args)]
pub struct DemoArgs {
    /// Programmed feed, mm/min.
    #[arg(long, value_name = "MM_PER_MIN", default_value_t = DemoOptions::default().feed,
          value_parser = flags::FEED.parser())]
    pub feed: f64,
    /// Interpolation period, µs.
    #[arg(
        long,
        value_name = "US",
        default_value_t = DemoOptions::default().period_us,
        value_parser = clap::value_parser!(u32).range(1..=1_000_000)
    )]
    pub period_us: u32,
    /// Chord tolerance of the chord-error feed law, mm.
    #[arg(long, value_name = "MM", default_value_t = DemoOptions::default().chord_tolerance_mm,
          value_parser = flags::CHORD_TOLERANCE.parser())]
    pub chord_tolerance_mm: f64,
    /// Tangential acceleration limit, mm/s².
    #[arg(long, value_name = "MM_PER_S2", default_value_t = DemoOptions::default().accel,
          value_parser = flags::ACCEL.parser())]
    pub accel: f64,
    /// Do not sleep: tick as fast as possible. Same setpoints; timing is then not meaningful.
    #[arg(long)]
    pub fast: bool,
    /// Print the summary as one JSON object.
    #[arg(long)]
    pub json: bool,
    /// Write every setpoint to this CSV file (seq,time,x,y,z,feed,u,s,block_id,state).
    #[arg(long, value_name = "PATH")]
    pub csv: Option<PathBuf>,
    /// Skip the second run through the service (RT thread, iceoryx2, TCP control plane).
    #[arg(long)]
    pub no_service: bool,
    /// Normal scheduling for the service run (no SCHED_FIFO, mlockall or pinning).
    #[arg(long)]
    pub no_rt: bool,
    /// Directory for the plots (PNG) and the service run's recording (`run.mcap`); made if missing.
    #[arg(long, value_name = "DIR", default_value = demo::DEFAULT_OUT_DIR)]
    pub out: PathBuf,
    /// Do not write the plots.
    #[arg(long)]
    pub no_plots: bool,
}

impl From<DemoArgs> for DemoOptions {
    fn from(a: DemoArgs) -> Self {
        DemoOptions {
            feed: a.feed,
            period_us: a.period_us,
            chord_tolerance_mm: a.chord_tolerance_mm,
            accel: a.accel,
            fast: a.fast,
            json: a.json,
            csv: a.csv,
            no_service: a.no_service,
            no_rt: a.no_rt,
            out: a.out,
            no_plots: a.no_plots,
        }
    }
}

/// Options of `interpd simulate`.
#[derive(Clone, Debug, clap::Args)]
pub struct SimulateArgs {
    /// The program: G-code (`.ngc`, `.nc`) or the JSON block form (`docs/traces.md`).
    pub program: PathBuf,
    /// TOML configuration (`[interp]`, `[simulate]`).
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Write the trace to this MCAP file.
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
    /// Print the summary as one JSON object.
    #[arg(long)]
    pub json: bool,
    /// Override any `[interp]` key, e.g. `--set planning-margin=0.05` (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// The five-axis machine description (TOML, docs/five-axis.md; e.g.
    /// examples/five_axis/machine.toml), over `[interp.machine]`.
    #[arg(long, value_name = "FILE")]
    pub machine: Option<PathBuf>,
    /// Interpolation period, µs (`interp.period`; default 1000).
    #[arg(long, value_name = "US", value_parser = flags::SIM_PERIOD_US.parser())]
    pub period_us: Option<f64>,
    /// Chord tolerance, mm (`interp.chord-tolerance`; default 0.001).
    #[arg(long, value_name = "MM", value_parser = flags::CHORD_TOLERANCE.parser())]
    pub chord_tolerance_mm: Option<f64>,
    /// Machine path-speed limit, mm/s (`interp.max-path-speed`; default 250).
    #[arg(long, value_name = "MM_PER_S", value_parser = flags::PATH_SPEED.parser())]
    pub max_speed: Option<f64>,
    /// Tangential acceleration limit, mm/s² (`interp.max-path-accel`; default 2000).
    #[arg(long, value_name = "MM_PER_S2", value_parser = flags::ACCEL.parser())]
    pub max_accel: Option<f64>,
    /// Control points per segment when long NURBS are split (`simulate.max-ctrl-per-block`; default 32, as `serve`).
    #[arg(long, value_name = "N")]
    pub max_ctrl_per_block: Option<usize>,
    /// Chunk compression of the trace: zstd (default), lz4 or none.
    #[arg(long, value_name = "KIND", default_value = "zstd")]
    pub compression: TraceCompression,
}

impl From<SimulateArgs> for SimulateOptions {
    fn from(a: SimulateArgs) -> Self {
        SimulateOptions {
            program: a.program,
            config: a.config,
            out: a.out,
            json: a.json,
            set: a.set,
            machine: a.machine,
            period_us: a.period_us,
            chord_tolerance_mm: a.chord_tolerance_mm,
            max_speed: a.max_speed,
            max_accel: a.max_accel,
            max_ctrl_per_block: a.max_ctrl_per_block,
            compression: a.compression,
        }
    }
}

/// `interpd plan …` subcommands.
#[derive(Debug, clap::Subcommand)]
pub enum PlanCommand {
    /// Raster finishing over an STL mesh by slicing the offset triangle mesh.
    Raster(RasterArgs),
    /// 5-axis machinability and setup orientation of an STL part.
    Setup(SetupArgs),
    /// Check a G1 path for gouges against an STL part, correct it, and predict the milled surface.
    Gouge(GougeArgs),
    /// Fit G1 paths into G6.2 NURBS blocks within a tolerance.
    Fit(FitArgs),
}

/// Options of `interpd plan raster`.
#[derive(Debug, clap::Args)]
pub struct RasterArgs {
    /// The part, binary or ASCII STL (mm).
    #[arg(long)]
    pub stl: PathBuf,
    /// Cutter: ball:D, flat:D or bull:D:r (D the diameter, mm).
    #[arg(long)]
    pub tool: Cutter,
    /// Distance between passes, mm.
    #[arg(long, default_value_t = 0.5, value_parser = flags::STEP.parser())]
    pub stepover: f64,
    /// Pass direction, degrees counter-clockwise from +X.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true,
          value_parser = flags::PASS_ANGLE.parser())]
    pub angle: f64,
    /// Cut both ways (reverse every other pass).
    #[arg(long)]
    pub zigzag: bool,
    /// Chord tolerance of the CL polylines, mm.
    #[arg(long, default_value_t = RasterConfig::default().chord_tolerance,
          value_parser = flags::PLAN_TOLERANCE.parser())]
    pub chord_tolerance: f64,
    /// G-code output file.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Print a JSON summary on stdout instead of text.
    #[arg(long)]
    pub json: bool,
    /// Also write the CL polylines as JSON (for scripts/ocl_compare.py).
    #[arg(long)]
    pub cl_json: Option<PathBuf>,
    /// Safe height above the part's top for rapids, mm.
    #[arg(long, default_value_t = 5.0, value_parser = flags::CLEARANCE.parser())]
    pub clearance: f64,
    /// Cutting feed, mm/min.
    #[arg(long, default_value_t = 1000.0, value_parser = flags::FEED.parser())]
    pub feed: f64,
    /// Plunge feed, mm/min.
    #[arg(long, default_value_t = 300.0, value_parser = flags::FEED.parser())]
    pub plunge_feed: f64,
    /// `G64 P` written at the program's start, mm: the controller may leave
    /// the polylines by this much to run their dense moves at speed (the
    /// moves are a few µm long). 0: no G64 (the controller's exact path).
    #[arg(long, default_value_t = DEFAULT_BLEND_TOLERANCE,
          value_parser = flags::PLAN_TOLERANCE_OR_ZERO.parser())]
    pub blend_tolerance: f64,
    /// Weld tolerance for the mesh's vertices, mm.
    #[arg(long, default_value_t = WeldOptions::default().weld_tolerance,
          value_parser = flags::PLAN_TOLERANCE_OR_ZERO.parser())]
    pub weld_tolerance: f64,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

impl From<RasterArgs> for RasterOptions {
    fn from(a: RasterArgs) -> Self {
        RasterOptions {
            stl: a.stl,
            tool: a.tool,
            stepover: a.stepover,
            angle: a.angle,
            zigzag: a.zigzag,
            chord_tolerance: a.chord_tolerance,
            out: a.out,
            json: a.json,
            cl_json: a.cl_json,
            clearance: a.clearance,
            feed: a.feed,
            plunge_feed: a.plunge_feed,
            blend_tolerance: a.blend_tolerance,
            weld_tolerance: a.weld_tolerance,
            quiet: a.quiet,
        }
    }
}

/// Options of `interpd plan setup`.
#[derive(Debug, clap::Args)]
pub struct SetupArgs {
    /// The part, binary or ASCII STL (mm). Each triangle is one surface patch.
    #[arg(long, value_name = "PART.stl")]
    pub stl: PathBuf,
    /// Machine configuration in W/…/T notation, e.g. W/caxyBz/T (C,A) or W/baxzBy/T (A,B).
    #[arg(long, value_name = "W/…/T")]
    pub machine: MachineConfig,
    /// Rotary ranges in degrees: PHI_L,PHI_S (C,A: tilt axis; A,B: R1),
    /// THETA_L,THETA_S (C,A: C axis; A,B: R2).
    #[arg(
        long,
        value_name = "PHI_L,PHI_S,THETA_L,THETA_S",
        allow_hyphen_values = true
    )]
    pub ranges: AxisRanges,
    /// Minimum number of sphere cells (rounded up to 20·f²).
    #[arg(long, value_name = "N", default_value_t = SetupConfig::default().cells)]
    pub cells: usize,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

impl From<SetupArgs> for SetupOptions {
    fn from(a: SetupArgs) -> Self {
        SetupOptions {
            stl: a.stl,
            machine: a.machine,
            ranges: a.ranges,
            cells: a.cells,
            json: a.json,
        }
    }
}

/// Arguments of `interpd plan gouge`.
#[derive(Debug, clap::Args)]
pub struct GougeArgs {
    /// The design part (binary or ASCII STL, mm, Z up).
    #[arg(long)]
    pub stl: PathBuf,
    /// The CL path: G0/G1 program of tool-tip positions.
    #[arg(long)]
    pub path: PathBuf,
    /// Cutter: ball:D, flat:D or bull:D:r (D the diameter, mm).
    #[arg(long)]
    pub tool: String,
    /// Allowed overcut, mm.
    #[arg(long, default_value_t = 0.05, value_parser = flags::PLAN_TOLERANCE.parser())]
    pub tol: f64,
    /// Corrected path (G1).
    #[arg(long)]
    pub out: PathBuf,
    /// Write before.png and after.png error heat maps into this directory.
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Spacing of the CC points sampled on the mesh, mm.
    #[arg(long, default_value_t = GougeConfig::default().sample_spacing,
          value_parser = flags::STEP.parser())]
    pub sample_spacing: f64,
    /// Check-point grid step of the milled-surface prediction, mm.
    #[arg(long, default_value_t = PredictConfig::default().grid_step,
          value_parser = flags::STEP.parser())]
    pub grid_step: f64,
    /// Print the report as JSON.
    #[arg(long)]
    pub json: bool,
}

impl From<GougeArgs> for GougeOptions {
    fn from(a: GougeArgs) -> Self {
        GougeOptions {
            stl: a.stl,
            path: a.path,
            tool: a.tool,
            tol: a.tol,
            out: a.out,
            plot: a.plot,
            sample_spacing: a.sample_spacing,
            grid_step: a.grid_step,
            json: a.json,
        }
    }
}

/// Arguments of `interpd plan fit`.
#[derive(Debug, clap::Args)]
pub struct FitArgs {
    /// The CL path: G0/G1 program.
    #[arg(long)]
    pub path: PathBuf,
    /// Largest distance of a CL point from its curve, mm.
    #[arg(long, default_value_t = FitConfig::default().tolerance,
          value_parser = flags::PLAN_TOLERANCE.parser())]
    pub tol: f64,
    /// Curve degree (1..=5).
    #[arg(long, default_value_t = FitConfig::default().degree,
          value_parser = clap::value_parser!(u16).range(1..=planner::fit::MAX_DEGREE as i64).map(usize::from))]
    pub degree: usize,
    /// G6.2 program out.
    #[arg(long)]
    pub out: PathBuf,
    /// Re-check the fitted curves for gouges against this part (needs --tool).
    #[arg(long, requires = "tool")]
    pub stl: Option<PathBuf>,
    /// Cutter for the re-check.
    #[arg(long, requires = "stl")]
    pub tool: Option<String>,
    /// Allowed interference of the fitted curves in the re-check, mm.
    #[arg(long, default_value_t = GougeConfig::default().tolerance,
          value_parser = flags::PLAN_TOLERANCE_OR_ZERO.parser())]
    pub gouge_tol: f64,
    /// Print the report as JSON.
    #[arg(long)]
    pub json: bool,
}

impl From<FitArgs> for FitOptions {
    fn from(a: FitArgs) -> Self {
        FitOptions {
            path: a.path,
            tol: a.tol,
            degree: a.degree,
            out: a.out,
            stl: a.stl,
            tool: a.tool,
            gouge_tol: a.gouge_tol,
            json: a.json,
        }
    }
}
