//! `interpd demo`: the bundled butterfly NURBS through the interpolator loop.
//!
//! The program is split into blocks and queued before the loop starts (it fits
//! the queue). A dedicated thread then ticks the interpolator on a fixed period
//! with absolute deadlines (`clock_nanosleep(TIMER_ABSTIME)`, 1 ns timer
//! slack), measuring wake lateness and tick compute time into histograms
//! allocated up front, and acts as its own subscriber: every setpoint is
//! checked (gapless `seq`, finite values, speed and acceleration limits) and
//! folded into a digest. Setpoints
//! go through a fixed-capacity SPSC queue to the calling thread, which measures
//! the chord error against the exact blocks and writes the optional CSV.
//! Nothing in the loop allocates; a full queue is counted, never waited on
//! (except with `--fast`, which has no deadlines and must not lose setpoints).
//!
//! Then (unless `--no-service`) the same program goes through the service as a
//! user would run it: `interpd serve` started in-process on a private iceoryx2
//! service name, the butterfly streamed over its TCP control plane as one JSON
//! NURBS line, and an iceoryx2 subscriber that runs the same checks on every
//! published setpoint. The served run must be gapless and give the same
//! setpoint digest as the direct run, bit for bit (same blocks and config).

use core::fmt;
use core::sync::atomic::{AtomicBool, Ordering};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::PathBuf;

use anyhow::{Context, Error, Result, anyhow, bail};
use heapless::spsc::{Producer, Queue};
use interp_core::metrics::chord_error_between;
use interp_core::samples::butterfly;
use interp_core::{Block, Curve, InterpConfig, RunState, Setpoint, Vec3};
use interp_run::{PlanError, Replay};
use serde::Serialize;

use crate::check::{Checker, Limits, Measured, Violations};
use crate::service::clock::{minimise_timer_slack, now_ns, sleep_until_ns};
use crate::service::histogram::{Histogram, Percentiles};
use crate::service::publish::state_name;

/// Id of the first block.
const FIRST_BLOCK_ID: u32 = 1;
/// Slots of the loop → recorder queue (one is kept free): four seconds at 1 kHz.
const QUEUE_SLOTS: usize = 4096;
/// Samples per tick for the chord-error search (then golden section).
const CHORD_SAMPLES: usize = 16;
/// The run is abandoned after this much machine time, s, or ten times the
/// program's length at the feed limit, whichever is longer.
const MAX_MACHINE_TIME_S: f64 = 3600.0;
/// ... or after the path has not moved for this long while running, s.
const STALL_TIME_S: f64 = 1.0;
/// Planning gives up after this many ticks: the run does not end.
const MAX_PLAN_TICKS: u64 = 100_000_000;

/// Options of `interpd demo`; [`Default`] holds the documented defaults.
#[derive(Clone, Debug, PartialEq)]
pub struct DemoOptions {
    /// Programmed feed, mm/min (default 6000).
    pub feed: f64,
    /// Interpolation period, µs (default 1000).
    pub period_us: u32,
    /// Chord tolerance of the chord-error feed law, mm (default: `InterpConfig`'s).
    pub chord_tolerance_mm: f64,
    /// Tangential acceleration limit, mm/s² (default: `InterpConfig`'s).
    pub accel: f64,
    /// Do not sleep: tick as fast as possible. Same setpoints; timing is then not meaningful.
    pub fast: bool,
    /// Print the summary as one JSON object.
    pub json: bool,
    /// Write every setpoint to this CSV file (seq,time,x,y,z,feed,u,s,block_id,state).
    pub csv: Option<PathBuf>,
    /// Skip the second run through the service (RT thread, iceoryx2, TCP control plane).
    pub no_service: bool,
    /// Normal scheduling for the service run (no SCHED_FIFO, mlockall or pinning).
    pub no_rt: bool,
    /// Directory for the plots (PNG) and the service run's recording
    /// (`run.mcap`); made if missing (default [`DEFAULT_OUT_DIR`]).
    pub out: PathBuf,
    /// Do not write the plots.
    pub no_plots: bool,
}

impl Default for DemoOptions {
    fn default() -> Self {
        DemoOptions {
            feed: 6000.0,
            period_us: 1000,
            chord_tolerance_mm: InterpConfig::default().chord_tolerance,
            accel: InterpConfig::default().max_path_accel,
            fast: false,
            json: false,
            csv: None,
            no_service: false,
            no_rt: false,
            out: PathBuf::from(DEFAULT_OUT_DIR),
            no_plots: false,
        }
    }
}

/// Where `interpd demo` writes its plots and recording unless `--out` says otherwise.
pub const DEFAULT_OUT_DIR: &str = "out/demo";
/// The service run's recording, in the output directory.
pub const RECORDING_FILE: &str = "run.mcap";

/// Runs the demo, prints the summary, and fails if any check failed.
pub fn main(args: &DemoOptions) -> Result<()> {
    let mut setpoints = Vec::new();
    let mut summary = run(args, |sp| {
        if !args.no_plots {
            setpoints.push(*sp);
        }
    })?;
    if !args.no_plots {
        let cfg = config(args);
        let blocks = butterfly_blocks(args.feed, &cfg)?;
        let inp = crate::tools::demo_plots::PlotInput {
            cfg: &cfg,
            blocks: &blocks,
            start: summary.program.start,
            setpoints: &setpoints,
        };
        summary.plots = crate::tools::demo_plots::write(&inp, &args.out)?;
    }
    if !args.no_service {
        summary.service = Some(crate::tools::demo_service::run(args, &summary)?);
    }
    if args.json {
        println!(
            "{}",
            serde_json::to_string(&summary).context("serialising the summary")?
        );
    } else {
        print!("{summary}");
    }
    if let Some(svc) = &summary.service
        && let Some(why) = svc.failure(&summary.setpoint_digest)
    {
        bail!("the run through the service failed: {why}");
    }
    if !summary.chord_error_within_tolerance {
        bail!(
            "chord error {:.6e} mm at seq {} exceeds the tolerance {} mm",
            summary.max_chord_error_mm,
            summary.max_chord_error_seq,
            summary.settings.chord_tolerance_mm
        );
    }
    let n = summary.violations.total();
    if n > 0 {
        bail!(
            "{n} check(s) failed ({}), first at seq {}",
            summary.violations.breakdown(),
            summary
                .violations
                .first_seq
                .map_or_else(|| "-".to_owned(), |s| s.to_string())
        );
    }
    Ok(())
}

/// What the loop thread reports when it stops.
#[derive(Debug)]
struct LoopOutcome {
    sub: Checker,
    last: Setpoint,
    lateness: Histogram,
    compute: Histogram,
    /// Ticks whose work ended after the next deadline.
    overruns: u64,
    /// Setpoints the recorder queue had no room for (real time only).
    drops: u64,
    /// Why the loop stopped early, if it did.
    abandoned: Option<&'static str>,
    wall_ns: i64,
}

/// Loop parameters.
#[derive(Clone, Copy, Debug)]
struct LoopParams {
    fast: bool,
    period_ns: i64,
    max_ticks: u64,
    stall_ticks: u64,
}

/// Sets the flag when dropped, also when the loop thread unwinds.
struct SetOnDrop<'a>(&'a AtomicBool);

impl Drop for SetOnDrop<'_> {
    fn drop(&mut self) {
        self.0.store(true, Ordering::Release);
    }
}

/// Plans `blocks` from `start` to the end of the program before the loop
/// (`interp_run::plan`, blocks pushed as `simulate` pushes them): the loop
/// then gives each plan to an executor at the tick it was made for, as the
/// service's RT thread does, and its ticks cost what the RT thread's cost.
fn planned(cfg: InterpConfig, start: [f64; 6], blocks: &[Block]) -> Result<Replay> {
    interp_run::plan(cfg, start, blocks, MAX_PLAN_TICKS).map_err(|e| match e {
        PlanError::Run {
            index: Some(k),
            error,
        } => {
            let b = &blocks[k];
            anyhow!(
                "planning butterfly block {} ({} of {}, {:.3} mm): {error}",
                b.id,
                k + 1,
                blocks.len(),
                b.path.length()
            )
        }
        e => anyhow!("planning the butterfly: {e}"),
    })
}

/// The fixed-period loop. Everything it touches is allocated by the caller.
fn run_loop(
    ip: &mut Replay,
    mut sub: Checker,
    mut lateness: Histogram,
    mut compute: Histogram,
    tx: &mut Producer<'_, Setpoint>,
    prm: LoopParams,
    stop: &AtomicBool,
) -> LoopOutcome {
    if !prm.fast {
        minimise_timer_slack();
    }
    let start = now_ns();
    let mut next = start;
    let (mut overruns, mut drops, mut still) = (0u64, 0u64, 0u64);
    let mut last = Setpoint::default();
    let abandoned = loop {
        if !prm.fast {
            next += prm.period_ns;
            sleep_until_ns(next);
            lateness.record((now_ns() - next).max(0) as u64);
        }
        let t0 = now_ns();
        let sp = ip.tick();
        let t1 = now_ns();
        compute.record((t1 - t0).max(0) as u64);
        sub.check(&sp);
        let mut item = sp;
        while let Err(back) = tx.enqueue(item) {
            if !prm.fast {
                drops += 1; // never wait on the recorder in real time
                break;
            }
            if stop.load(Ordering::Relaxed) {
                break;
            }
            item = back;
            std::thread::yield_now();
        }
        if !prm.fast && now_ns() > next + prm.period_ns {
            overruns += 1;
        }
        still = if sp.state == RunState::Running && sp.s == last.s {
            still + 1
        } else {
            0
        };
        last = sp;
        match sp.state {
            RunState::Done => break None,
            RunState::Fault => break Some("the interpolator faulted"),
            RunState::Idle => break Some("the interpolator went idle before the end"),
            _ => {}
        }
        if still >= prm.stall_ticks {
            break Some("the path stopped moving");
        }
        if sp.seq >= prm.max_ticks {
            break Some("the machine-time limit was reached");
        }
        if stop.load(Ordering::Relaxed) {
            break Some("stopped by the recorder");
        }
    };
    LoopOutcome {
        sub,
        last,
        lateness,
        compute,
        overruns,
        drops,
        abandoned,
        wall_ns: now_ns() - start,
    }
}

/// The consumer side: chord error against the exact blocks, the optional CSV,
/// and the caller's hook.
struct Recorder<'a, F> {
    blocks: &'a [Block],
    csv: Option<(BufWriter<File>, PathBuf)>,
    on_setpoint: F,
    prev: Option<Setpoint>,
    max_chord_error: f64,
    max_chord_error_seq: u64,
    error: Option<Error>,
}

impl<F: FnMut(&Setpoint)> Recorder<'_, F> {
    /// The piece of block `id` whose parameter range holds both `u0` and `u1`
    /// (a split NURBS keeps the id and the parameters of the whole curve).
    fn block(&self, id: u32, u0: f64, u1: f64) -> Option<&Block> {
        self.blocks.iter().find(|b| {
            b.id == id
                && match &b.path {
                    interp_core::Path::Nurbs(n) => {
                        let k = n.knots();
                        let (lo, hi) = (k[0], k[k.len() - 1]);
                        (lo..=hi).contains(&u0) && (lo..=hi).contains(&u1)
                    }
                    _ => true,
                }
        })
    }

    /// Takes one setpoint; returns false once it has failed (then the loop should stop).
    fn take(&mut self, sp: Setpoint) -> bool {
        (self.on_setpoint)(&sp);
        if let Some(prev) = self.prev
            && prev.seq + 1 == sp.seq
            && prev.block_id == sp.block_id
            && let Some(block) = self.block(sp.block_id, prev.u, sp.u)
        {
            let a = Vec3::new(prev.axes[0], prev.axes[1], prev.axes[2]);
            let b = Vec3::new(sp.axes[0], sp.axes[1], sp.axes[2]);
            let e = chord_error_between(&block.path, prev.u, sp.u, a, b, CHORD_SAMPLES);
            if !(e <= self.max_chord_error) {
                self.max_chord_error = e;
                self.max_chord_error_seq = sp.seq;
            }
        }
        self.prev = Some(sp);
        if self.error.is_none()
            && let Some((w, path)) = &mut self.csv
        {
            let [x, y, z, ..] = sp.axes;
            let r = writeln!(
                w,
                "{},{},{},{},{},{},{},{},{},{}",
                sp.seq,
                sp.time,
                x,
                y,
                z,
                sp.feed,
                sp.u,
                sp.s,
                sp.block_id,
                state_name(sp.state)
            );
            if let Err(e) = r {
                self.error =
                    Some(Error::new(e).context(format!("writing CSV to {}", path.display())));
            }
        }
        self.error.is_none()
    }

    fn finish(&mut self) -> Result<()> {
        if let Some(e) = self.error.take() {
            return Err(e);
        }
        if let Some((w, path)) = &mut self.csv {
            w.flush()
                .with_context(|| format!("writing CSV to {}", path.display()))?;
        }
        Ok(())
    }
}

/// The butterfly as one protocol line: a JSON NURBS at `feed_mm_min`.
pub(crate) fn butterfly_request(feed_mm_min: f64) -> String {
    crate::protocol::nurbs_json(
        feed_mm_min,
        butterfly::BUTTERFLY_DEGREE,
        &butterfly::BUTTERFLY_POINTS,
        &butterfly::BUTTERFLY_WEIGHTS,
        &butterfly::BUTTERFLY_KNOTS,
    )
}

/// The butterfly as the service gets it: its protocol line parsed, split
/// and sent through the program pipeline (`G64 P` stage included) exactly
/// as the control plane does, so both runs get the same blocks.
fn butterfly_blocks(feed_mm_min: f64, cfg: &InterpConfig) -> Result<Vec<Block>> {
    let line = butterfly_request(feed_mm_min);
    let crate::protocol::Request::Block(b) =
        crate::protocol::parse(&line).map_err(|e| anyhow!("butterfly request: {e}"))?
    else {
        bail!("the butterfly request is not a block");
    };
    crate::protocol::expand_from(&b, butterfly::START, FIRST_BLOCK_ID, cfg)
        .map(|(blocks, _)| blocks)
        .map_err(|e| anyhow!("splitting the butterfly NURBS into blocks: {e}"))
}

fn point3(p: Vec3) -> [f64; 3] {
    [p.x, p.y, p.z]
}

/// The program that was run.
#[derive(Clone, Debug, Serialize)]
pub struct Program {
    /// Its name.
    pub name: &'static str,
    /// Blocks it was split into.
    pub blocks: usize,
    /// Total arc length, mm.
    pub length_mm: f64,
    /// Start point, mm.
    pub start: [f64; 3],
    /// End point of the curve, mm.
    pub end: [f64; 3],
}

/// The settings in force.
#[derive(Clone, Debug, Serialize)]
pub struct Settings {
    /// Programmed feed, mm/min.
    pub feed_mm_per_min: f64,
    /// The speed the checks allow: the programmed feed capped at the machine's, mm/s.
    pub feed_limit_mm_s: f64,
    /// Period, µs.
    pub period_us: u32,
    /// Chord tolerance, mm.
    pub chord_tolerance_mm: f64,
    /// Tangential acceleration limit, mm/s².
    pub accel_mm_s2: f64,
    /// Every limit the setpoints are checked against.
    pub limits: Limits,
    /// No sleeping.
    pub fast: bool,
}

/// Loop timing (meaningful in real time only).
#[derive(Clone, Debug, Serialize)]
pub struct Timing {
    /// Wall-clock time of the loop, s.
    pub wall_s: f64,
    /// Wake time minus deadline, µs (`None` with `--fast`).
    pub wake_lateness_us: Option<Percentiles>,
    /// Time spent in `Executor::tick` (with the commits of its tick), µs.
    pub tick_compute_us: Option<Percentiles>,
    /// Ticks whose work ended after the next deadline.
    pub overruns: u64,
    /// Setpoints dropped because the recorder queue was full.
    pub recorder_drops: u64,
}

/// The interpolator's counters.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct InterpStats {
    /// Ticks run.
    pub ticks: u64,
    /// Segments completed.
    pub segments_done: u64,
    /// Plans refused because the machine had passed where they start (0
    /// when planning and execution are in step).
    pub stale_plans: u64,
    /// Most Newton iterations in one tick.
    pub max_newton_iters: u32,
}

/// What `interpd demo` reports.
#[derive(Clone, Debug, Serialize)]
pub struct Summary {
    /// The program.
    pub program: Program,
    /// The settings.
    pub settings: Settings,
    /// Setpoints produced.
    pub ticks: u64,
    /// Machine time of the last setpoint, s.
    pub duration_s: f64,
    /// Largest commanded feed, mm/s.
    pub max_feed_mm_s: f64,
    /// Largest chord between consecutive setpoints over Ts, mm/s.
    pub max_chord_speed_mm_s: f64,
    /// Largest |Δfeed|/Ts, mm/s².
    pub max_accel_mm_s2: f64,
    /// Path jerk and per-axis velocity, acceleration and jerk from finite differences.
    pub measured: Measured,
    /// Largest distance between the curve and the chord of one tick (ticks within a block), mm.
    pub max_chord_error_mm: f64,
    /// `seq` of the setpoint that ends that tick.
    pub max_chord_error_seq: u64,
    /// Whether that is within the chord tolerance (reported, not a failed check).
    pub chord_error_within_tolerance: bool,
    /// Last setpoint's X Y Z, mm.
    pub final_point: [f64; 3],
    /// Its distance to the curve's end, mm (0 exactly when all is well).
    pub final_distance_mm: f64,
    /// State of the last setpoint.
    pub final_state: &'static str,
    /// Why the loop stopped before `Done`, if it did.
    pub abandoned: Option<&'static str>,
    /// Failed checks.
    pub violations: Violations,
    /// FNV-1a 64 of every setpoint's fields (bits), hex: equal runs give equal digests.
    pub setpoint_digest: String,
    /// Loop timing.
    pub timing: Timing,
    /// Interpolator counters.
    pub interpolator: InterpStats,
    /// Where the setpoints were written.
    pub csv: Option<PathBuf>,
    /// The plots written (PNG), empty with `--no-plots`.
    pub plots: Vec<PathBuf>,
    /// The second run, through the service (`None` with `--no-service`).
    pub service: Option<crate::tools::demo_service::ServiceRun>,
}

/// The interpolator configuration of the direct run.
fn config(args: &DemoOptions) -> InterpConfig {
    InterpConfig {
        period: f64::from(args.period_us) * 1e-6,
        chord_tolerance: args.chord_tolerance_mm,
        max_path_accel: args.accel,
        ..InterpConfig::default()
    }
}

/// The program queued in an interpolator, and everything the loop needs.
#[derive(Debug)]
struct Prepared {
    cfg: InterpConfig,
    blocks: Vec<Block>,
    ip: Box<Replay>,
    start: Vec3,
    end: Vec3,
    length: f64,
    feed_limit: f64,
    prm: LoopParams,
}

impl Prepared {
    fn new(args: &DemoOptions) -> Result<Self> {
        crate::flags::FEED.check("--feed", args.feed)?;
        crate::flags::CHORD_TOLERANCE.check("--chord-tolerance-mm", args.chord_tolerance_mm)?;
        crate::flags::ACCEL.check("--accel", args.accel)?;
        let cfg = config(args);
        let feed = args.feed / 60.0;
        let blocks = butterfly_blocks(args.feed, &cfg)?;
        let (first, last) = match (blocks.first(), blocks.last()) {
            (Some(f), Some(l)) => (f, l),
            _ => bail!("the butterfly gave no blocks"),
        };
        let start = first.path.start_point();
        let end = last.path.end_point();
        let length: f64 = blocks.iter().map(|b| b.path.length()).sum();

        let ip = Box::new(planned(
            cfg,
            [start.x, start.y, start.z, 0.0, 0.0, 0.0],
            &blocks,
        )?);
        let feed_limit = feed.min(cfg.max_path_speed);
        let max_time = MAX_MACHINE_TIME_S.max(10.0 * length / feed_limit);
        let prm = LoopParams {
            fast: args.fast,
            period_ns: i64::from(args.period_us) * 1_000,
            max_ticks: (max_time / cfg.period).ceil() as u64,
            stall_ticks: ((STALL_TIME_S / cfg.period).ceil() as u64).max(10),
        };
        Ok(Prepared {
            cfg,
            blocks,
            ip,
            start,
            end,
            length,
            feed_limit,
            prm,
        })
    }

    /// The loop's subscriber for this program.
    fn subscriber(&self) -> Checker {
        Checker::new(
            self.cfg.period,
            Limits::new(&self.cfg, self.feed_limit),
            point3(self.start),
        )
    }
}

/// Runs the demo and returns its summary; `on_setpoint` sees every setpoint the
/// recorder receives (all of them unless `timing.recorder_drops > 0`).
pub fn run(args: &DemoOptions, on_setpoint: impl FnMut(&Setpoint)) -> Result<Summary> {
    let prepared = Prepared::new(args)?;
    // Everything the loop touches, allocated before it starts.
    let sub = prepared.subscriber();
    let (lateness, compute) = (Histogram::new(), Histogram::new());
    let mut queue: Box<Queue<Setpoint, QUEUE_SLOTS>> = Box::new(Queue::new());
    let (mut tx, mut rx) = queue.split();
    let Prepared {
        cfg,
        blocks,
        mut ip,
        start,
        end,
        length,
        feed_limit,
        prm,
    } = prepared;
    let csv = match &args.csv {
        Some(path) => {
            let file = File::create(path)
                .with_context(|| format!("creating CSV file {}", path.display()))?;
            let mut w = BufWriter::new(file);
            writeln!(w, "seq,time,x,y,z,feed,u,s,block_id,state")
                .with_context(|| format!("writing CSV to {}", path.display()))?;
            Some((w, path.clone()))
        }
        None => None,
    };

    let (stop, done) = (AtomicBool::new(false), AtomicBool::new(false));
    let mut rec = Recorder {
        blocks: &blocks,
        csv,
        on_setpoint,
        prev: None,
        max_chord_error: 0.0,
        max_chord_error_seq: 0,
        error: None,
    };

    let mut out = std::thread::scope(|s| -> Result<LoopOutcome> {
        let (ip, stop, done) = (&mut *ip, &stop, &done);
        let handle = std::thread::Builder::new()
            .name("interp-loop".into())
            .spawn_scoped(s, move || {
                let _done = SetOnDrop(done);
                run_loop(ip, sub, lateness, compute, &mut tx, prm, stop)
            })
            .context("spawning the loop thread")?;
        let idle = core::time::Duration::from_micros(200);
        loop {
            // Read the flag before draining, so nothing enqueued before it is missed.
            let finished = done.load(Ordering::Acquire);
            while let Some(sp) = rx.dequeue() {
                if !rec.take(sp) {
                    stop.store(true, Ordering::Relaxed);
                }
            }
            if finished {
                break;
            }
            std::thread::sleep(idle);
        }
        handle
            .join()
            .map_err(|_| anyhow!("the interpolator loop thread panicked"))
    })?;
    rec.finish()?;

    let stats = ip.stats();
    let last_sp = out.last;
    let final_point = [last_sp.axes[0], last_sp.axes[1], last_sp.axes[2]];
    let violations = out.sub.finish(Some(point3(end)));
    Ok(Summary {
        program: Program {
            name: "butterfly (LinuxCNC curva_farfalla, degree-4 rational NURBS, 51 control points)",
            blocks: blocks.len(),
            length_mm: length,
            start: point3(start),
            end: point3(end),
        },
        settings: Settings {
            feed_mm_per_min: args.feed,
            feed_limit_mm_s: feed_limit,
            period_us: args.period_us,
            chord_tolerance_mm: cfg.chord_tolerance,
            accel_mm_s2: cfg.max_path_accel,
            limits: Limits::new(&cfg, feed_limit),
            fast: args.fast,
        },
        ticks: last_sp.seq,
        duration_s: last_sp.time,
        max_feed_mm_s: out.sub.max_feed,
        max_chord_speed_mm_s: out.sub.max_chord_speed,
        max_accel_mm_s2: out.sub.max_accel,
        measured: out.sub.measured,
        max_chord_error_mm: rec.max_chord_error,
        max_chord_error_seq: rec.max_chord_error_seq,
        chord_error_within_tolerance: rec.max_chord_error <= cfg.chord_tolerance,
        final_point,
        final_distance_mm: (Vec3::from(final_point) - end).norm(),
        final_state: state_name(last_sp.state),
        abandoned: out.abandoned,
        violations,
        setpoint_digest: format!("{:016x}", out.sub.digest),
        timing: Timing {
            wall_s: out.wall_ns as f64 * 1e-9,
            wake_lateness_us: Percentiles::of(&out.lateness),
            tick_compute_us: Percentiles::of(&out.compute),
            overruns: out.overruns,
            recorder_drops: out.drops,
        },
        interpolator: InterpStats {
            ticks: stats.ticks,
            segments_done: stats.segments_done,
            stale_plans: stats.stale_plans,
            max_newton_iters: stats.max_newton_iters,
        },
        csv: args.csv.clone(),
        plots: Vec::new(),
        service: None,
    })
}

fn fmt_percentiles(f: &mut fmt::Formatter<'_>, p: Option<Percentiles>) -> fmt::Result {
    match p {
        Some(p) => write!(f, "p50 {:.1}  p99 {:.1}  max {:.1} µs", p.p50, p.p99, p.max),
        None => write!(f, "-"),
    }
}

impl fmt::Display for Summary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (p, s, v) = (&self.program, &self.settings, &self.violations);
        writeln!(f, "interpd demo: {}", p.name)?;
        writeln!(
            f,
            "  program     {} blocks, {:.3} mm, from ({}, {}, {}) to ({}, {}, {})",
            p.blocks, p.length_mm, p.start[0], p.start[1], p.start[2], p.end[0], p.end[1], p.end[2]
        )?;
        writeln!(
            f,
            "  settings    F{} mm/min (limit {} mm/s), Ts {} µs, chord tolerance {} mm, \
             accel {} mm/s²{}",
            s.feed_mm_per_min,
            s.feed_limit_mm_s,
            s.period_us,
            s.chord_tolerance_mm,
            s.accel_mm_s2,
            if s.fast { ", --fast" } else { "" }
        )?;
        writeln!(
            f,
            "  run         {} ticks, {:.3} s machine time, {:.3} s wall",
            self.ticks, self.duration_s, self.timing.wall_s
        )?;
        writeln!(
            f,
            "  feed        max {:.6} mm/s ({:.1} mm/min); max chord speed {:.6} mm/s",
            self.max_feed_mm_s,
            self.max_feed_mm_s * 60.0,
            self.max_chord_speed_mm_s
        )?;
        writeln!(
            f,
            "  accel       max tangential {:.3} mm/s² (limit {})",
            self.max_accel_mm_s2, s.accel_mm_s2
        )?;
        let (m, l) = (&self.measured, &s.limits);
        writeln!(
            f,
            "  jerk        max path {:.0} mm/s³ (limit {})",
            m.path_jerk_mm_s3, l.jerk_mm_s3
        )?;
        let xyz = |v: [f64; 3]| format!("{:.0} {:.0} {:.0}", v[0], v[1], v[2]);
        writeln!(
            f,
            "  axes X Y Z  max velocity {} mm/s (limits {}), accel {} mm/s² ({}), jerk {} mm/s³ ({})",
            xyz(m.axis_velocity_mm_s),
            xyz(l.axis_velocity_mm_s),
            xyz(m.axis_accel_mm_s2),
            xyz(l.axis_accel_mm_s2),
            xyz(m.axis_jerk_mm_s3),
            xyz(l.axis_jerk_mm_s3)
        )?;
        writeln!(
            f,
            "  chord error max {:.3e} mm (tolerance {} mm) at seq {}",
            self.max_chord_error_mm, s.chord_tolerance_mm, self.max_chord_error_seq
        )?;
        if !self.chord_error_within_tolerance {
            writeln!(
                f,
                "  FAILED      the chord error exceeds the chord tolerance"
            )?;
        }
        writeln!(
            f,
            "  final       ({}, {}, {}), {} mm from the curve end, state {}",
            self.final_point[0],
            self.final_point[1],
            self.final_point[2],
            self.final_distance_mm,
            self.final_state
        )?;
        if let Some(why) = self.abandoned {
            writeln!(f, "  abandoned   {why}")?;
        }
        writeln!(f, "  checks      {} failed: {}", v.total(), v.breakdown())?;
        if s.fast {
            writeln!(
                f,
                "  timing      --fast: no deadlines (tick compute below is indicative)"
            )?;
        }
        write!(f, "  lateness    ")?;
        fmt_percentiles(f, self.timing.wake_lateness_us)?;
        write!(f, "\n  tick        ")?;
        fmt_percentiles(f, self.timing.tick_compute_us)?;
        writeln!(
            f,
            "\n  loop        {} overruns, {} recorder drops",
            self.timing.overruns, self.timing.recorder_drops
        )?;
        let i = &self.interpolator;
        writeln!(
            f,
            "  interp      {} ticks, {} segments done, {} stale plans, max {} Newton iterations",
            i.ticks, i.segments_done, i.stale_plans, i.max_newton_iters
        )?;
        writeln!(f, "  digest      {}", self.setpoint_digest)?;
        if let Some(path) = &self.csv {
            writeln!(f, "  csv         {}", path.display())?;
        }
        if let Some(dir) = self.plots.first().and_then(|p| p.parent()) {
            let names: Vec<_> = self
                .plots
                .iter()
                .filter_map(|p| p.file_name().map(|n| n.to_string_lossy()))
                .collect();
            writeln!(f, "  plots       {}/ {}", dir.display(), names.join(" "))?;
        }
        if let Some(svc) = &self.service {
            write!(f, "{}", svc.display(&self.setpoint_digest))?;
        }
        Ok(())
    }
}

/// What other modules' tests need from the demo.
#[cfg(test)]
pub(crate) mod tests_support {
    use super::*;

    /// `interpd demo --fast --no-service --no-plots`.
    pub(crate) fn fast_args() -> DemoOptions {
        DemoOptions {
            no_service: true,
            no_plots: true,
            out: std::env::temp_dir(),
            ..tests::fast()
        }
    }

    /// The direct run's configuration.
    pub(crate) fn config(args: &DemoOptions) -> InterpConfig {
        super::config(args)
    }

    /// The butterfly's interpolator blocks.
    pub(crate) fn blocks(args: &DemoOptions) -> Vec<Block> {
        butterfly_blocks(args.feed, &config(args)).expect("the butterfly splits")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::check::{ACCEL_REL_TOL, FNV_OFFSET, SPEED_TOL, digest_setpoint};
    /// `interpd demo --fast`.
    pub(super) fn fast() -> DemoOptions {
        DemoOptions {
            fast: true,
            ..DemoOptions::default()
        }
    }

    fn fast_run() -> (Summary, Vec<Setpoint>) {
        let mut sps = Vec::new();
        let summary = run(&fast(), |sp| sps.push(*sp)).expect("demo runs");
        (summary, sps)
    }

    fn bits(sp: &Setpoint) -> [u64; 13] {
        let mut b = [0u64; 13];
        b[0] = sp.seq;
        b[1] = sp.time.to_bits();
        for (d, a) in b[2..8].iter_mut().zip(sp.axes) {
            *d = a.to_bits();
        }
        b[8] = sp.feed.to_bits();
        b[9] = sp.u.to_bits();
        b[10] = sp.s.to_bits();
        b[11] = u64::from(sp.block_id);
        b[12] = sp.state as u64;
        b
    }

    #[test]
    fn defaults_are_the_documented_ones() {
        let a = DemoOptions::default();
        assert_eq!(a.feed, 6000.0);
        assert_eq!(a.period_us, 1000);
        assert_eq!(a.chord_tolerance_mm, 0.001);
        assert_eq!(a.accel, InterpConfig::default().max_path_accel);
        assert!(!a.fast && !a.json && a.csv.is_none());
        assert_eq!(a.out, PathBuf::from(DEFAULT_OUT_DIR));
    }

    #[test]
    fn fast_butterfly_passes_every_check_and_ends_exactly_on_the_curve_end() {
        let (s, sps) = fast_run();
        assert_eq!(s.violations, Violations::default(), "{s}");
        assert_eq!(s.final_state, "done");
        assert_eq!(s.abandoned, None);
        assert_eq!(s.timing.recorder_drops, 0);
        let end = butterfly::BUTTERFLY_POINTS[butterfly::BUTTERFLY_POINTS.len() - 1];
        assert_eq!(s.final_point, end);
        assert_eq!(s.final_distance_mm, 0.0);
        let last = sps.last().expect("setpoints");
        assert_eq!([last.axes[0], last.axes[1], last.axes[2]], end);
        assert_eq!(sps.len() as u64, s.ticks);
        assert!(sps.iter().zip(1..).all(|(sp, k)| sp.seq == k));
        assert!(s.max_feed_mm_s <= 100.0 + SPEED_TOL);
        assert!(s.max_accel_mm_s2 <= s.settings.accel_mm_s2 * (1.0 + ACCEL_REL_TOL));
        assert!(s.max_chord_error_mm > 0.0 && s.chord_error_within_tolerance);
    }

    #[test]
    fn two_fast_runs_are_bit_identical() {
        let (a, sa) = fast_run();
        let (b, sb) = fast_run();
        assert_eq!(sa.len(), sb.len());
        assert!(sa.iter().map(bits).eq(sb.iter().map(bits)));
        assert_eq!(a.setpoint_digest, b.setpoint_digest);
        // The digest is the one of the sequence the recorder saw.
        let d = sa.iter().fold(FNV_OFFSET, digest_setpoint);
        assert_eq!(format!("{d:016x}"), a.setpoint_digest);
    }

    #[test]
    fn csv_has_a_header_and_one_row_per_setpoint() {
        let path = std::env::temp_dir().join(format!("interpd-demo-{}.csv", std::process::id()));
        let a = DemoOptions {
            csv: Some(path.clone()),
            ..fast()
        };
        let s = run(&a, |_| {}).expect("demo runs");
        let text = std::fs::read_to_string(&path).expect("csv written");
        let _ = std::fs::remove_file(&path);
        let mut lines = text.lines();
        assert_eq!(lines.next(), Some("seq,time,x,y,z,feed,u,s,block_id,state"));
        let rows: Vec<&str> = lines.collect();
        assert_eq!(rows.len() as u64, s.ticks);
        let last: Vec<&str> = rows[rows.len() - 1].split(',').collect();
        assert_eq!(last.len(), 10);
        assert_eq!(last[9], "done");
        let x: f64 = last[2].parse().expect("x");
        assert_eq!(x, s.final_point[0]);
    }

    use alloc_count as counting;

    /// The binary's RT pool in front of the counting allocator: tests count
    /// what reaches the system allocator.
    #[global_allocator]
    static ALLOCATOR: crate::service::rt_alloc::RtPool<counting::Counting> =
        crate::service::rt_alloc::RtPool(counting::Counting);

    #[test]
    fn the_loop_does_not_allocate() {
        let mut p = Prepared::new(&fast()).expect("program queues");
        let sub = p.subscriber();
        let (lateness, compute) = (Histogram::new(), Histogram::new());
        let mut queue: Box<Queue<Setpoint, QUEUE_SLOTS>> = Box::new(Queue::new());
        let (mut tx, mut rx) = queue.split();
        let (stop, done) = (AtomicBool::new(false), AtomicBool::new(false));
        let (ip, prm) = (&mut *p.ip, p.prm);
        let mut received = 0u64;
        let (out, allocations) = std::thread::scope(|s| {
            let h = s.spawn(|| {
                let _done = SetOnDrop(&done);
                counting::count(|| run_loop(ip, sub, lateness, compute, &mut tx, prm, &stop))
            });
            while !done.load(Ordering::Acquire) || rx.ready() {
                if rx.dequeue().is_some() {
                    received += 1;
                }
            }
            h.join().expect("loop thread")
        });
        assert_eq!(allocations, 0);
        // The counter does see allocations.
        let (_b, n) = counting::count(|| core::hint::black_box(Box::new(7u8)));
        assert_eq!(n, 1);
        assert_eq!(out.last.state, RunState::Done);
        assert_eq!(received, out.last.seq);
        assert_eq!(out.compute.count(), out.last.seq);
    }

    #[test]
    fn main_writes_the_plots_into_out_unless_told_not_to() {
        let dir = std::env::temp_dir().join(format!("interpd-demo-out-{}", std::process::id()));
        let a = DemoOptions {
            no_service: true,
            out: dir.clone(),
            ..fast()
        };
        main(&a).expect("demo passes");
        let mut names: Vec<String> = std::fs::read_dir(&dir)
            .expect("out dir made")
            .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        let want =
            ["acceleration", "chord_error", "feed", "jerk", "path_xy"].map(|n| format!("{n}.png"));
        assert_eq!(names, want);
        std::fs::remove_dir_all(&dir).expect("cleanup");
        main(&DemoOptions {
            no_plots: true,
            ..a
        })
        .expect("demo passes");
        assert!(!dir.exists(), "--no-plots wrote into {}", dir.display());
    }

    #[test]
    fn a_bad_feed_is_refused_with_context() {
        let e = run(
            &DemoOptions {
                feed: 0.0,
                ..DemoOptions::default()
            },
            |_| {},
        )
        .unwrap_err();
        assert!(e.to_string().contains("--feed"), "{e:#}");
    }
}
