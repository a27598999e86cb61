//! The command line: clap's definition of every subcommand.

use std::net::{IpAddr, SocketAddr};
use std::path::PathBuf;

use clap::{Parser, Subcommand};
use interpd::client::send::SendOptions;
use interpd::client::watch::{DEFAULT_LIVENESS_S, WatchOptions};
use interpd::service::publish::DEFAULT_SERVICE;
use interpd::service::rt::{DEFAULT_PERIOD_US, DEFAULT_PLAN_LEAD_MS, DEFAULT_PRIORITY, RtSettings};
use interpd::service::serve::{DEFAULT_PORT, ServeOptions};
use interpd::tools::jitter::JitterOptions;
use interpd::tools::{demo, simulate};

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
    Serve(ServeArgs),
    /// Stream a program to a running `interpd serve` with back-pressure.
    Send(SendArgs),
    /// Subscribe to the setpoints (iceoryx2) and report gaps.
    Watch(WatchArgs),
    /// Measure wake lateness and tick+publish time: the full pipeline vs a bare loop.
    Jitter(JitterArgs),
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
    /// Stop after this many seconds.
    #[arg(long)]
    pub seconds: Option<f64>,
    /// Stop at the first sample in state `done` after one that was moving.
    #[arg(long)]
    pub until_done: bool,
    /// Give up when no sample arrives for this many seconds: the publisher
    /// is dead (or was never there).
    #[arg(long, value_name = "SECONDS", default_value_t = DEFAULT_LIVENESS_S)]
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
    #[arg(long, value_name = "MM_PER_MIN")]
    pub check_feed: Option<f64>,
    /// The service's interpolation period, µs (for `--check-feed`).
    #[arg(long, value_name = "US", default_value_t = 1000)]
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
    /// SCHED_FIFO priority of the RT thread (1..=99).
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
    /// Start position X Y Z, mm.
    #[arg(long, num_args = 3, value_names = ["X", "Y", "Z"], allow_negative_numbers = true)]
    pub position: Option<Vec<f64>>,
    /// Record the run to this MCAP trace (config, blocks, setpoints, loop
    /// timing, events) through the `traces` recorder; `interpd replay` of it
    /// reproduces the setpoints of the first program bit for bit when that
    /// program was queued before `start`.
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
            record: a.record,
            json: a.json,
        }
    }
}

/// Options of `interpd jitter`.
#[derive(Clone, Debug, clap::Args)]
pub struct JitterArgs {
    /// Seconds for each of the two loops.
    #[arg(long, default_value_t = 10.0)]
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
