//! `interpd serve`: the RT thread, the recorder thread and the tokio control
//! plane, wired together; graceful shutdown on SIGINT/SIGTERM (abort on the
//! path within the limits, drain the recorder, release the iceoryx2 ports).

use core::sync::atomic::{AtomicBool, AtomicU8, AtomicU64, Ordering};
use std::net::{IpAddr, SocketAddr};
use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use anyhow::{Context, Result, anyhow, bail};
use heapless::spsc::Consumer;
use interp_core::{InterpConfig, Setpoint};
use serde::Serialize;

use crate::service::control::{Control, Stream, serve_connection};
use crate::service::histogram::Percentiles;
use crate::service::publish::{remove_dead_nodes, state_name};
use crate::service::rt::{Applied, RtRecord, RtReport, RtSettings};

/// What the recorder thread calls for every tick the RT thread handed it.
pub type TickSink = Box<dyn FnMut(&RtRecord) + Send>;

/// Default TCP port of the control plane.
pub const DEFAULT_PORT: u16 = 47_110;
// (The control-plane thread's stack: `interp_run::stack`.)
use interp_run::stack::CONTROL_STACK_BYTES;
/// The recorder drains its queue this often.
const RECORDER_POLL: Duration = Duration::from_millis(5);

/// Options of `interpd serve`.
#[derive(Clone, Debug, PartialEq)]
pub struct ServeOptions {
    /// The RT thread's period and scheduling.
    pub rt: RtSettings,
    /// TCP address to listen on (loopback unless --allow-remote).
    pub listen: IpAddr,
    /// TCP port (0: any free port, printed at start).
    pub port: u16,
    /// Allow listening beyond loopback (needs --token).
    pub allow_remote: bool,
    /// Token every connection must send first (`auth TOKEN`).
    pub token: Option<String>,
    /// Unix socket path (mode 0600); default `$XDG_RUNTIME_DIR/interpd.sock` or `/tmp/interpd-UID.sock`.
    pub socket: Option<PathBuf>,
    /// Do not listen on a Unix socket.
    pub no_socket: bool,
    /// iceoryx2 service name of the setpoints.
    pub service: String,
    /// The first program moves without waiting for `start`.
    pub autostart: bool,
    /// Start position X Y Z (mm) and optionally A B C (degrees, default 0).
    pub position: Option<Vec<f64>>,
    /// TOML configuration: the `[interp]` table (`InterpConfig`, the
    /// five-axis machine as `[interp.machine]`).
    pub config: Option<PathBuf>,
    /// Override any `[interp]` key (repeatable), as `simulate --set`.
    pub set: Vec<String>,
    /// The five-axis machine (TOML, `docs/five-axis.md`), over `[interp.machine]`.
    pub machine: Option<PathBuf>,
    /// Record the run to this MCAP trace (config, blocks, setpoints, loop
    /// timing, events) through the `traces` recorder; `interpd replay` of it
    /// reproduces the setpoints of the first program bit for bit when that
    /// program was queued before `start`.
    pub record: Option<PathBuf>,
    /// Print the final summary as JSON.
    pub json: bool,
}

impl ServeOptions {
    /// Defaults as `interpd serve` with no flags, on `service`, any free port, no socket.
    pub fn in_process(service: &str) -> Self {
        ServeOptions {
            rt: RtSettings::default(),
            listen: IpAddr::from([127, 0, 0, 1]),
            port: 0,
            allow_remote: false,
            token: None,
            socket: None,
            no_socket: true,
            service: service.to_owned(),
            autostart: false,
            position: None,
            config: None,
            set: Vec::new(),
            machine: None,
            record: None,
            json: false,
        }
    }

    /// The interpolator's configuration: `--config` and `--set` over the
    /// defaults ([`crate::config`]), checked; the period is `--period-us`'s.
    pub fn interp_config(&self) -> Result<InterpConfig> {
        let mut cfg = crate::config::interp_config("serve", self.config.as_deref(), &self.set)?;
        if let Some(path) = &self.machine {
            cfg.machine = Some(crate::config::read_machine(path)?);
        }
        let cfg = InterpConfig {
            period: f64::from(self.rt.period_us) * 1e-6,
            ..cfg
        };
        crate::config::check(&cfg)?;
        Ok(cfg)
    }
}

/// The joints the machine starts at: `--position X Y Z [A B C]`, or the origin.
fn start_position(p: Option<&[f64]>) -> Result<[f64; 6]> {
    let mut q = [0.0; 6];
    match p {
        None => {}
        Some(p) if p.len() == 3 || p.len() == 6 => {
            for (i, &c) in p.iter().enumerate() {
                let (axis, range) = (
                    ["X", "Y", "Z", "A", "B", "C"][i],
                    if i < 3 {
                        crate::flags::POSITION
                    } else {
                        crate::flags::ANGLE_POSITION
                    },
                );
                range.check(&format!("--position {axis}"), c)?;
            }
            q[..p.len()].copy_from_slice(p);
        }
        Some(p) => bail!("--position takes X Y Z or X Y Z A B C, finite numbers; got {p:?}"),
    }
    Ok(q)
}

/// What `serve` reports when it stops.
#[derive(Debug, Serialize)]
pub struct ServeSummary {
    /// Samples published.
    pub published: u64,
    /// Interpolator ticks.
    pub ticks: u64,
    /// Final state.
    pub final_state: &'static str,
    /// Final X Y Z.
    pub final_position: [f64; 3],
    /// Wake lateness, µs.
    pub lateness_us: Option<Percentiles>,
    /// Tick + publish, µs (ticks without a push).
    pub tick_publish_us: Option<Percentiles>,
    /// Commit + tick + publish, µs (ticks with a commit).
    pub tick_publish_with_push_us: Option<Percentiles>,
    /// Missed periods.
    pub overruns: u64,
    /// Ticks the recorder had no room for.
    pub recorder_drops: u64,
    /// Periods the RT thread found the planning thread behind it and
    /// published its last point again, unticked (0 expected: see
    /// `--plan-lead-ms`).
    pub planner_late: u64,
    /// Ticks the recorder took.
    pub recorded: u64,
    /// Failed publishes.
    pub publish_failures: u64,
    /// Small allocations on the RT thread served by its fixed pool (iceoryx2's per-sample object).
    pub rt_pool_served: u64,
    /// RT-thread allocations the pool could not serve (went to the system allocator; 0 expected).
    pub rt_pool_fallbacks: u64,
    /// Of those, the requests that found the pool empty (the rest were larger than a slot).
    pub rt_pool_exhausted: u64,
    /// The largest RT-thread request that fell back, bytes (0: none).
    pub rt_pool_largest_fallback: usize,
    /// Scheduling refused (normal scheduling was used).
    pub scheduling_warnings: Vec<String>,
    /// The MCAP trace written, if any.
    pub trace: Option<PathBuf>,
    /// Messages written to it (setpoints, loop timing, blocks, events, config).
    pub trace_messages: u64,
    /// Records the trace recorder had no room for.
    pub trace_overflows: u64,
}

/// A running service.
#[derive(Debug)]
pub struct Service {
    /// TCP address of the control plane.
    pub addr: SocketAddr,
    /// Unix socket, if any.
    pub socket: Option<PathBuf>,
    shutdown: Option<tokio::sync::oneshot::Sender<()>>,
    thread: Option<JoinHandle<Result<ServeSummary>>>,
    /// The RT thread's live status.
    pub status: Arc<crate::service::rt::RtStatus>,
}

impl Service {
    /// Stops the service (abort on the path, drain, release) and returns its summary.
    pub fn shutdown(mut self) -> Result<ServeSummary> {
        if let Some(tx) = self.shutdown.take() {
            let _ = tx.send(());
        }
        self.join()
    }

    /// Waits until the service stops by itself (SIGINT/SIGTERM).
    pub fn join(mut self) -> Result<ServeSummary> {
        self.thread
            .take()
            .ok_or_else(|| anyhow!("already joined"))?
            .join()
            .map_err(|_| anyhow!("the control plane thread panicked"))?
    }
}

fn default_socket() -> PathBuf {
    if let Some(dir) = std::env::var_os("XDG_RUNTIME_DIR") {
        return PathBuf::from(dir).join("interpd.sock");
    }
    // SAFETY: getuid cannot fail.
    let uid = unsafe { libc::getuid() };
    PathBuf::from(format!("/tmp/interpd-{uid}.sock"))
}

/// Makes `path` free for our socket: nothing there, or a stale socket (its
/// server died) which is removed. Anything else is refused: a file that is
/// not a socket, or a socket a live server answers on.
fn claim_socket_path(path: &std::path::Path) -> Result<()> {
    use std::os::unix::fs::FileTypeExt;
    let shown = path.display();
    match std::fs::symlink_metadata(path) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
        Err(e) => Err(e).with_context(|| format!("--socket {shown}")),
        Ok(m) if !m.file_type().is_socket() => {
            bail!("--socket {shown}: the path exists and is not a socket (refusing to replace it)")
        }
        Ok(_) => {
            if std::os::unix::net::UnixStream::connect(path).is_ok() {
                bail!("--socket {shown}: another server answers on {shown}");
            }
            std::fs::remove_file(path).with_context(|| format!("removing the stale socket {shown}"))
        }
    }
}

/// The recorder thread: drains the RT thread's record queue until the RT
/// thread stopped and the queue is empty. Returns how many ticks it took.
fn spawn_recorder(
    mut rx: Consumer<'static, RtRecord>,
    rt_done: Arc<AtomicBool>,
    sink: Option<TickSink>,
) -> Result<JoinHandle<u64>> {
    std::thread::Builder::new()
        .name("interpd-recorder".into())
        .spawn(move || {
            let mut sink = sink;
            let mut n = 0u64;
            loop {
                let done = rt_done.load(Ordering::Acquire);
                while let Some(r) = rx.dequeue() {
                    n += 1;
                    if let Some(f) = sink.as_mut() {
                        f(&r);
                    }
                }
                if done {
                    return n;
                }
                std::thread::sleep(RECORDER_POLL);
            }
        })
        .context("spawning the recorder thread")
}

/// Starts the service. `handle_signals`: SIGINT/SIGTERM stop it (the CLI);
/// otherwise only [`Service::shutdown`] does. `on_tick` sees every recorded tick
/// on the recorder thread.
pub fn start(
    args: &ServeOptions,
    cfg: InterpConfig,
    handle_signals: bool,
    on_tick: Option<TickSink>,
) -> Result<Service> {
    if !args.listen.is_loopback() {
        if !args.allow_remote {
            bail!(
                "--listen {} is not a loopback address: pass --allow-remote and --token",
                args.listen
            );
        }
        if args.token.as_deref().is_none_or(str::is_empty) {
            bail!("listening on {} needs --token", args.listen);
        }
    }
    let cfg = InterpConfig {
        period: f64::from(args.rt.period_us) * 1e-6,
        ..cfg
    };
    let position = start_position(args.position.as_deref())?;
    let cleaned = remove_dead_nodes();
    if cleaned > 0 {
        eprintln!("interpd: removed the iceoryx2 resources of {cleaned} dead node(s)");
    }
    let opts = args.rt.options(&args.service, args.autostart)?;
    // The trace recorder (traces crate): its own thread and bounded queue.
    let (trace_tx, trace_rec) = match &args.record {
        Some(path) => {
            let file = std::fs::File::create(path)
                .with_context(|| format!("creating the trace {}", path.display()))?;
            let writer = traces::TraceWriter::new(
                std::io::BufWriter::new(file),
                traces::TraceCompression::default(),
            )
            .map_err(|e| anyhow!("starting the trace {}: {e}", path.display()))?;
            let (tx, rec) = traces::Recorder::spawn(writer, TRACE_QUEUE)
                .context("starting the trace recorder")?;
            let config = traces::messages::ConfigMsg {
                format_version: traces::messages::FORMAT_VERSION,
                writer: format!("interpd serve {}", env!("CARGO_PKG_VERSION")),
                source: "interpd serve".into(),
                realtime: true,
                interp: cfg,
                start: position,
                max_ctrl_per_block: crate::protocol::PIECE_CTRL,
                segment_queue: interp_core::interp::DEFAULT_QUEUE,
            };
            let _ = tx.try_push(traces::Record::Config(Box::new(config)));
            (Some(tx), Some(rec))
        }
        None => (None, None),
    };
    let on_tick = match (&trace_tx, on_tick) {
        (Some(tx), None) => Some(trace_sink(tx.clone(), cfg.period)),
        (_, f) => f,
    };
    let rt = crate::service::rt::spawn(cfg, position, opts)?;
    let rt_status = Arc::clone(&rt.status);
    let control = Arc::new(Control {
        stream: tokio::sync::Mutex::new(Stream {
            segments: rt.segments,
            queued_to: [position[0], position[1], position[2]],
            queued_tcp: false,
            queued_joints: position,
            machine: cfg
                .machine
                .map(interp_core::kinematics::Machine::new)
                .transpose()
                .map_err(|e| anyhow!("the machine: {e}"))?,
            tail: None,
            next_id: 1,
            index: 0,
            program: 0,
            pipeline: None,
            interp: cfg,
        }),
        programs: Mutex::new(crate::service::control::Programs::new()),
        commands: Mutex::new(rt.commands),
        failures: Mutex::new(rt.failures),
        status: Arc::clone(&rt.status),
        period: Duration::from_micros(u64::from(args.rt.period_us)),
        max_feed_override: cfg.max_feed_override,
        max_path_speed: cfg.max_path_speed,
        machine: cfg.machine,
        token: args.token.clone(),
        abort_epoch: AtomicU64::new(0),
        motion_command: AtomicU8::new(0),
        blocks_accepted: AtomicU64::new(0),
        errors: AtomicU64::new(0),
        connections: AtomicU64::new(0),
        last_refusal: Mutex::new(None),
        recorder: Mutex::new(trace_tx.clone()),
    });
    let rt_done = Arc::new(AtomicBool::new(false));
    let recorder = spawn_recorder(rt.records, Arc::clone(&rt_done), on_tick)?;
    drop(trace_tx);

    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .context("building the tokio runtime")?;
    let addr = SocketAddr::new(args.listen, args.port);
    let tcp = runtime
        .block_on(tokio::net::TcpListener::bind(addr))
        .with_context(|| format!("listening on {addr}"))?;
    let addr = tcp.local_addr().context("reading the bound address")?;
    let socket = (!args.no_socket).then(|| args.socket.clone().unwrap_or_else(default_socket));
    let unix = match &socket {
        Some(path) => {
            claim_socket_path(path)?;
            let l = runtime
                .block_on(async { tokio::net::UnixListener::bind(path) })
                .with_context(|| format!("listening on {}", path.display()))?;
            use std::os::unix::fs::PermissionsExt;
            std::fs::set_permissions(path, std::fs::Permissions::from_mode(0o600))
                .with_context(|| format!("setting mode 0600 on {}", path.display()))?;
            Some(l)
        }
        None => None,
    };
    let (tx, rx) = tokio::sync::oneshot::channel::<()>();
    let ctl = Arc::clone(&control);
    let stop = Arc::clone(&rt.stop);
    let status = Arc::clone(&rt.status);
    let rt_thread = rt.thread;
    let planner_thread = rt.planner;
    let sock = socket.clone();
    let json = args.json;
    let record_path = args.record.clone();
    let thread = std::thread::Builder::new()
        .name("interpd-control".into())
        .stack_size(CONTROL_STACK_BYTES)
        .spawn(move || -> Result<ServeSummary> {
            runtime.block_on(async {
                let accept_tcp = {
                    let ctl = Arc::clone(&ctl);
                    async move {
                        loop {
                            if let Ok((s, peer)) = tcp.accept().await {
                                let _ = s.set_nodelay(true);
                                let name = format!("tcp {peer}");
                                tokio::spawn(serve_connection(Arc::clone(&ctl), s, name));
                            }
                        }
                    }
                };
                let accept_unix = {
                    let ctl = Arc::clone(&ctl);
                    async move {
                        match unix {
                            Some(l) => loop {
                                if let Ok((s, _)) = l.accept().await {
                                    let name = "unix".to_owned();
                                    tokio::spawn(serve_connection(Arc::clone(&ctl), s, name));
                                }
                            },
                            None => std::future::pending::<()>().await,
                        }
                    }
                };
                tokio::select! {
                    _ = accept_tcp => {}
                    _ = accept_unix => {}
                    _ = rx => {}
                    _ = signal(handle_signals) => {
                        eprintln!("interpd: stopping: abort on the path");
                    }
                }
                if let Err(e) = ctl.abort().await {
                    eprintln!("interpd: warning: {e}");
                }
            });
            stop.store(true, Ordering::Release);
            let report: RtReport = rt_thread
                .join()
                .map_err(|_| anyhow!("the RT thread panicked"))?;
            planner_thread
                .join()
                .map_err(|_| anyhow!("the planning thread panicked"))?;
            rt_done.store(true, Ordering::Release);
            let recorded = recorder
                .join()
                .map_err(|_| anyhow!("the recorder thread panicked"))?;
            // The last producer of the trace queue; then the trace is finished.
            if let Ok(mut tx) = ctl.recorder.lock() {
                tx.take();
            }
            let (trace_messages, trace_overflows) = match trace_rec {
                Some(rec) => {
                    let (w, report) = rec.join().map_err(|e| anyhow!("writing the trace: {e}"))?;
                    let mut f = w
                        .into_inner()
                        .map_err(|e| anyhow!("writing the trace: {e}"))?;
                    use std::io::Write;
                    f.flush().context("writing the trace")?;
                    (report_messages(&report), report.overflows)
                }
                None => (0, 0),
            };
            if let Some(p) = &sock {
                let _ = std::fs::remove_file(p);
            }
            let last: Setpoint = report.last;
            let summary = ServeSummary {
                published: report.published,
                ticks: last.seq,
                final_state: state_name(last.state),
                final_position: [last.axes[0], last.axes[1], last.axes[2]],
                lateness_us: Percentiles::of(&report.lateness),
                tick_publish_us: Percentiles::of(&report.compute),
                tick_publish_with_push_us: Percentiles::of(&report.compute_with_push),
                overruns: report.overruns,
                recorder_drops: status.recorder_drops.load(Ordering::Acquire),
                planner_late: status.planner_late.load(Ordering::Acquire),
                recorded,
                publish_failures: status.publish_failures.load(Ordering::Acquire),
                rt_pool_served: crate::service::rt_alloc::served(),
                rt_pool_fallbacks: crate::service::rt_alloc::fallbacks(),
                rt_pool_exhausted: crate::service::rt_alloc::exhausted(),
                rt_pool_largest_fallback: crate::service::rt_alloc::largest_fallback(),
                scheduling_warnings: report.scheduling_warnings,
                trace: record_path,
                trace_messages,
                trace_overflows,
            };
            let _ = json;
            Ok(summary)
        })
        .context("spawning the control plane thread")?;
    Ok(Service {
        addr,
        socket,
        shutdown: Some(tx),
        thread: Some(thread),
        status: rt_status,
    })
}

fn report_messages(r: &traces::recorder::RecorderReport) -> u64 {
    let w = &r.written;
    w.config + w.blocks + w.setpoints + w.loop_timing + w.events
}

/// Records the trace queue holds (about two seconds at 1 kHz of setpoints and timing).
const TRACE_QUEUE: usize = 4096;

/// The recorder thread's hand-off to the trace: every tick of the first
/// program (up to its first `done`) as a setpoint and its loop timing.
fn trace_sink(tx: traces::RecordTx, period: f64) -> TickSink {
    use traces::messages::{EventKind, EventMsg};
    Box::new(move |r: &RtRecord| match *r {
        RtRecord::Tick(r) => {
            if !r.ticked {
                return; // waiting for `start`: the interpolator did not move
            }
            let sp = r.setpoint;
            let timing = traces::LoopTimingMsg {
                seq: sp.seq,
                wake_lateness_ns: Some(r.lateness_ns as i64),
                tick_compute_ns: Some(r.compute_ns),
                queue_depth: r.queue_depth,
            };
            // Full: counted by the traces recorder and written as an overflow event.
            let _ = tx.try_push(traces::Record::Setpoint(sp));
            let _ = tx.try_push(traces::Record::LoopTiming(timing, sp.time));
        }
        RtRecord::Applied { tick, what } => {
            let ev = |kind| EventMsg::new(kind, tick, tick as f64 * period);
            let ev = match what {
                Applied::Commit(id) => EventMsg {
                    count: Some(u64::from(id)),
                    ..ev(EventKind::Commit)
                },
                Applied::Hold => ev(EventKind::Hold),
                Applied::Resume => ev(EventKind::Resume),
                Applied::Override(x) => EventMsg {
                    value: Some(x),
                    ..ev(EventKind::Override)
                },
                Applied::Abort => ev(EventKind::Abort),
                Applied::NextProgram => ev(EventKind::NextProgram),
                Applied::Finish => ev(EventKind::Finish),
                Applied::Parts => ev(EventKind::Parts),
            };
            let _ = tx.try_push(traces::Record::Event(ev));
        }
    })
}

async fn signal(enabled: bool) {
    if !enabled {
        return std::future::pending().await;
    }
    use tokio::signal::unix::{SignalKind, signal};
    match (
        signal(SignalKind::interrupt()),
        signal(SignalKind::terminate()),
    ) {
        (Ok(mut i), Ok(mut t)) => {
            tokio::select! {
                _ = i.recv() => {}
                _ = t.recv() => {}
            }
        }
        _ => std::future::pending().await,
    }
}
