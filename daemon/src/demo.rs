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
use interp_core::{Block, Curve, InterpConfig, Interpolator, RunState, Setpoint, Vec3};
use serde::Serialize;

use crate::clock::{minimise_timer_slack, now_ns, sleep_until_ns};
use crate::histogram::Histogram;

/// Id of the first block.
const FIRST_BLOCK_ID: u32 = 1;
/// Slots of the loop → recorder queue (one is kept free): four seconds at 1 kHz.
const QUEUE_SLOTS: usize = 4096;
/// Samples per tick for the chord-error search (then golden section).
const CHORD_SAMPLES: usize = 16;
/// Absolute slack on the speed check, mm/s.
const SPEED_TOL: f64 = 1e-9;
/// The chord between two setpoints (the motion actually commanded) may exceed
/// the feed limit by this fraction: the corrected parameter update resolves the
/// chord only to the round-off of the coordinates and of `u` (about 1e-10 of a
/// 10 µs step), and the check is after jumps and wrong roots, not fluctuation.
const CHORD_REL_TOL: f64 = 1e-6;
/// ... plus this many ulps of the largest coordinate per tick, for tiny steps.
const CHORD_ULPS: f64 = 16.0;
/// Relative slack on the acceleration check.
const ACCEL_REL_TOL: f64 = 1e-6;
/// Relative slack on the jerk and per-axis checks: the one the core's own
/// tests use (`interp-core/tests/common`, `LIMIT_REL_TOL`).
const LIMIT_REL_TOL: f64 = 1e-6;
/// Round-off allowance of an n-th finite difference of coordinates of size
/// `scale`, in ulps of `scale` (|1| + |3| + |3| + |1| = 8 for the third
/// difference, times a margin of 2).
const DIFF_ULPS: f64 = 16.0;
/// The run is abandoned after this much machine time, s, or ten times the
/// program's length at the feed limit, whichever is longer.
const MAX_MACHINE_TIME_S: f64 = 3600.0;
/// ... or after the path has not moved for this long while running, s.
const STALL_TIME_S: f64 = 1.0;

/// Options of `interpd demo`.
#[derive(Clone, Debug, clap::Args)]
pub struct DemoArgs {
    /// Programmed feed, mm/min.
    #[arg(long, value_name = "MM_PER_MIN", default_value_t = 6000.0)]
    pub feed: f64,
    /// Interpolation period, µs.
    #[arg(
        long,
        value_name = "US",
        default_value_t = 1000,
        value_parser = clap::value_parser!(u32).range(1..=1_000_000)
    )]
    pub period_us: u32,
    /// Chord tolerance of the chord-error feed law, mm.
    #[arg(long, value_name = "MM", default_value_t = InterpConfig::default().chord_tolerance)]
    pub chord_tolerance_mm: f64,
    /// Tangential acceleration limit, mm/s².
    #[arg(long, value_name = "MM_PER_S2", default_value_t = InterpConfig::default().max_path_accel)]
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
    #[arg(long, value_name = "DIR", default_value = DEFAULT_OUT_DIR)]
    pub out: PathBuf,
    /// Do not write the plots.
    #[arg(long)]
    pub no_plots: bool,
}

/// Where `interpd demo` writes its plots and recording unless `--out` says otherwise.
pub const DEFAULT_OUT_DIR: &str = "out/demo";
/// The service run's recording, in the output directory.
pub const RECORDING_FILE: &str = "run.mcap";

/// Runs the demo, prints the summary, and fails if any check failed.
pub fn main(args: &DemoArgs) -> Result<()> {
    let mut setpoints = Vec::new();
    let mut summary = run(args, |sp| {
        if !args.no_plots {
            setpoints.push(*sp);
        }
    })?;
    if !args.no_plots {
        let cfg = config(args);
        let blocks = butterfly_blocks(args.feed)?;
        let inp = crate::demo_plots::PlotInput {
            cfg: &cfg,
            blocks: &blocks,
            start: summary.program.start,
            setpoints: &setpoints,
        };
        summary.plots = crate::demo_plots::write(&inp, &args.out)?;
    }
    if !args.no_service {
        summary.service = Some(crate::demo_service::run(args, &summary)?);
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

/// Checks that failed, by kind.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct Violations {
    /// Setpoints whose `seq` is not the previous one plus one (the first must be 1).
    pub seq_gaps: u64,
    /// Setpoints with a NaN or infinite time, axis, feed, `u` or `s`.
    pub non_finite: u64,
    /// Ticks whose commanded feed exceeds the feed limit (+1e-9 mm/s).
    pub over_speed: u64,
    /// Ticks whose chord speed |Δp|/Ts exceeds the feed limit (+1 ppm, +1e-9 mm/s
    /// and 16 ulps of the coordinates per tick).
    pub over_chord_speed: u64,
    /// Ticks whose |Δfeed|/Ts exceeds the acceleration limit.
    pub over_accel: u64,
    /// Ticks whose path jerk |Δ³s|/Ts³ exceeds `max_path_jerk` (+1 ppm).
    pub over_jerk: u64,
    /// Ticks where some axis's |Δp|/Ts exceeds its `axis_max_velocity` (+1 ppm).
    pub over_axis_velocity: u64,
    /// Ticks where some axis's |Δ²p|/Ts² exceeds its `axis_max_accel` (+1 ppm).
    pub over_axis_accel: u64,
    /// Ticks where some axis's |Δ³p|/Ts³ exceeds its `axis_max_jerk` (+1 ppm).
    pub over_axis_jerk: u64,
    /// Setpoints in the `Fault` state.
    pub faults: u64,
    /// 1 when the run ended without reaching `Done`.
    pub not_done: u64,
    /// 1 when the last point is not exactly the curve's end.
    pub end_mismatch: u64,
    /// `seq` of the first setpoint that failed a check.
    pub first_seq: Option<u64>,
}

impl Violations {
    /// All failed checks.
    pub fn total(&self) -> u64 {
        self.seq_gaps
            + self.non_finite
            + self.over_speed
            + self.over_chord_speed
            + self.over_accel
            + self.over_jerk
            + self.over_axis_velocity
            + self.over_axis_accel
            + self.over_axis_jerk
            + self.faults
            + self.not_done
            + self.end_mismatch
    }

    fn breakdown(&self) -> String {
        format!(
            "seq gaps {}, non-finite {}, over speed {}, over chord speed {}, over accel {}, \
             over jerk {}, over axis velocity {}, over axis accel {}, over axis jerk {}, \
             faults {}, not done {}, end mismatch {}",
            self.seq_gaps,
            self.non_finite,
            self.over_speed,
            self.over_chord_speed,
            self.over_accel,
            self.over_jerk,
            self.over_axis_velocity,
            self.over_axis_accel,
            self.over_axis_jerk,
            self.faults,
            self.not_done,
            self.end_mismatch
        )
    }
}

/// The limits every setpoint is checked against, from the run's configuration.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Limits {
    /// Path speed: the programmed feed capped at `max_path_speed`, mm/s.
    pub feed_mm_s: f64,
    /// Tangential acceleration `max_path_accel`, mm/s².
    pub accel_mm_s2: f64,
    /// Path jerk `max_path_jerk`, mm/s³.
    pub jerk_mm_s3: f64,
    /// `axis_max_velocity` X Y Z, mm/s.
    pub axis_velocity_mm_s: [f64; 3],
    /// `axis_max_accel` X Y Z, mm/s².
    pub axis_accel_mm_s2: [f64; 3],
    /// `axis_max_jerk` X Y Z, mm/s³.
    pub axis_jerk_mm_s3: [f64; 3],
}

impl Limits {
    /// The limits of `cfg` for a program at `feed_mm_s`.
    pub(crate) fn new(cfg: &InterpConfig, feed_mm_s: f64) -> Self {
        Limits {
            feed_mm_s: feed_mm_s.min(cfg.max_path_speed),
            accel_mm_s2: cfg.max_path_accel,
            jerk_mm_s3: cfg.max_path_jerk,
            axis_velocity_mm_s: cfg.axis_max_velocity,
            axis_accel_mm_s2: cfg.axis_max_accel,
            axis_jerk_mm_s3: cfg.axis_max_jerk,
        }
    }
}

/// Largest values measured by finite differences of the setpoints, as a drive sees them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Measured {
    /// Largest |Δ³s|/Ts³, mm/s³.
    pub path_jerk_mm_s3: f64,
    /// Largest |Δp|/Ts per axis X Y Z, mm/s.
    pub axis_velocity_mm_s: [f64; 3],
    /// Largest |Δ²p|/Ts² per axis, mm/s².
    pub axis_accel_mm_s2: [f64; 3],
    /// Largest |Δ³p|/Ts³ per axis, mm/s³.
    pub axis_jerk_mm_s3: [f64; 3],
}

/// The loop's own subscriber: checks each setpoint against the previous ones
/// and keeps the running maxima and digest. Fixed size; `check` never allocates.
///
/// Before the first setpoint the machine is at rest at `start` (arc length 0),
/// so the differences of the first ticks see the start as it was.
#[derive(Clone, Debug)]
pub(crate) struct Subscriber {
    ts: f64,
    limits: Limits,
    prev_seq: u64,
    prev_feed: f64,
    /// The last three points, newest first.
    prev_points: [[f64; 3]; 3],
    /// The last three arc lengths, newest first.
    prev_s: [f64; 3],
    pub(crate) max_feed: f64,
    max_chord_speed: f64,
    pub(crate) max_accel: f64,
    pub(crate) measured: Measured,
    pub(crate) digest: u64,
    pub(crate) violations: Violations,
}

/// `v ≤ limit` within the relative tolerance and `slack` of round-off.
fn within(v: f64, limit: f64, slack: f64) -> bool {
    v <= limit * (1.0 + LIMIT_REL_TOL) + slack
}

/// FNV-1a, 64 bit.
const FNV_OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
const FNV_PRIME: u64 = 0x0000_0100_0000_01b3;

fn fnv1a(mut h: u64, bytes: &[u8]) -> u64 {
    for &b in bytes {
        h = (h ^ u64::from(b)).wrapping_mul(FNV_PRIME);
    }
    h
}

/// Folds every field of `sp` (floats by their bits) into `h`.
fn digest_setpoint(mut h: u64, sp: &Setpoint) -> u64 {
    h = fnv1a(h, &sp.seq.to_le_bytes());
    h = fnv1a(h, &sp.time.to_bits().to_le_bytes());
    for a in sp.axes {
        h = fnv1a(h, &a.to_bits().to_le_bytes());
    }
    for v in [sp.feed, sp.u, sp.s] {
        h = fnv1a(h, &v.to_bits().to_le_bytes());
    }
    h = fnv1a(h, &sp.block_id.to_le_bytes());
    fnv1a(h, &[sp.state as u8])
}

impl Subscriber {
    pub(crate) fn new(ts: f64, limits: Limits, start: [f64; 3]) -> Self {
        Subscriber {
            ts,
            limits,
            prev_seq: 0,
            prev_feed: 0.0, // the machine starts at rest
            prev_points: [start; 3],
            prev_s: [0.0; 3],
            max_feed: 0.0,
            max_chord_speed: 0.0,
            max_accel: 0.0,
            measured: Measured::default(),
            digest: FNV_OFFSET,
            violations: Violations::default(),
        }
    }

    #[inline]
    pub(crate) fn check(&mut self, sp: &Setpoint) {
        let ts = self.ts;
        let lim = self.limits;
        let v = &mut self.violations;
        let mut bad = false;
        if sp.seq != self.prev_seq.wrapping_add(1) {
            v.seq_gaps += 1;
            bad = true;
        }
        let finite = [sp.time, sp.feed, sp.u, sp.s]
            .iter()
            .chain(&sp.axes)
            .all(|x| x.is_finite());
        if !finite {
            v.non_finite += 1;
            bad = true;
        }
        let p = [sp.axes[0], sp.axes[1], sp.axes[2]];
        let [p1, p2, p3] = self.prev_points;
        let chord = Vec3::from(p) - Vec3::from(p1);
        let chord_speed = chord.norm() / ts;
        let limit = lim.feed_mm_s + SPEED_TOL;
        if !(sp.feed <= limit) {
            v.over_speed += 1;
            bad = true;
        }
        let scale = p
            .iter()
            .chain(p1.iter())
            .chain(p2.iter())
            .chain(p3.iter())
            .fold(0.0f64, |m, c| m.max(c.abs()));
        let ulp = f64::EPSILON * scale;
        let round_off = CHORD_ULPS * ulp / ts;
        if !(chord_speed <= limit + lim.feed_mm_s * CHORD_REL_TOL + round_off) {
            v.over_chord_speed += 1;
            bad = true;
        }
        let accel = (sp.feed - self.prev_feed).abs() / ts;
        if !(accel <= lim.accel_mm_s2 * (1.0 + ACCEL_REL_TOL)) {
            v.over_accel += 1;
            bad = true;
        }
        // Path jerk: third difference of the arc length.
        let [s1, s2, s3] = self.prev_s;
        let ts3 = ts * ts * ts;
        let jerk = ((sp.s - 3.0 * s1) + (3.0 * s2 - s3)).abs() / ts3;
        let s_ulp = f64::EPSILON
            * [sp.s, s1, s2, s3]
                .iter()
                .fold(0.0f64, |m, x| m.max(x.abs()));
        if !within(jerk, lim.jerk_mm_s3, DIFF_ULPS * s_ulp / ts3) {
            v.over_jerk += 1;
            bad = true;
        }
        // Per axis, as a drive sees its own position commands.
        let (mut over_v, mut over_a, mut over_j) = (false, false, false);
        let m = &mut self.measured;
        m.path_jerk_mm_s3 = m.path_jerk_mm_s3.max(jerk);
        for k in 0..3 {
            let vel = (p[k] - p1[k]).abs() / ts;
            let acc = ((p[k] - 2.0 * p1[k]) + p2[k]).abs() / (ts * ts);
            let jrk = ((p[k] - 3.0 * p1[k]) + (3.0 * p2[k] - p3[k])).abs() / ts3;
            over_v |= !within(vel, lim.axis_velocity_mm_s[k], DIFF_ULPS * ulp / ts);
            over_a |= !within(acc, lim.axis_accel_mm_s2[k], DIFF_ULPS * ulp / (ts * ts));
            over_j |= !within(jrk, lim.axis_jerk_mm_s3[k], DIFF_ULPS * ulp / ts3);
            m.axis_velocity_mm_s[k] = m.axis_velocity_mm_s[k].max(vel);
            m.axis_accel_mm_s2[k] = m.axis_accel_mm_s2[k].max(acc);
            m.axis_jerk_mm_s3[k] = m.axis_jerk_mm_s3[k].max(jrk);
        }
        v.over_axis_velocity += u64::from(over_v);
        v.over_axis_accel += u64::from(over_a);
        v.over_axis_jerk += u64::from(over_j);
        bad |= over_v || over_a || over_j;
        if sp.state == RunState::Fault {
            v.faults += 1;
            bad = true;
        }
        if bad && v.first_seq.is_none() {
            v.first_seq = Some(sp.seq);
        }
        self.max_feed = self.max_feed.max(sp.feed);
        self.max_chord_speed = self.max_chord_speed.max(chord_speed);
        self.max_accel = self.max_accel.max(accel);
        self.digest = digest_setpoint(self.digest, sp);
        self.prev_seq = sp.seq;
        self.prev_feed = sp.feed;
        self.prev_points = [p, p1, p2];
        self.prev_s = [sp.s, s1, s2];
    }
}

/// What the loop thread reports when it stops.
#[derive(Debug)]
struct LoopOutcome {
    sub: Subscriber,
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

/// The fixed-period loop. Everything it touches is allocated by the caller.
fn run_loop<const Q: usize>(
    ip: &mut Interpolator<Q>,
    mut sub: Subscriber,
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

fn state_name(s: RunState) -> &'static str {
    match s {
        RunState::Idle => "idle",
        RunState::Running => "running",
        RunState::Holding => "holding",
        RunState::Stopping => "stopping",
        RunState::Done => "done",
        RunState::Fault => "fault",
    }
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

/// The butterfly as the service gets it: its protocol line parsed and split
/// exactly as the control plane does, so both runs get the same blocks.
fn butterfly_blocks(feed_mm_min: f64) -> Result<Vec<Block>> {
    let line = butterfly_request(feed_mm_min);
    let crate::protocol::Request::Block(b) =
        crate::protocol::parse(&line).map_err(|e| anyhow!("butterfly request: {e}"))?
    else {
        bail!("the butterfly request is not a block");
    };
    crate::protocol::expand(&b, butterfly::START, FIRST_BLOCK_ID)
        .map(|(blocks, _)| blocks)
        .map_err(|e| anyhow!("splitting the butterfly NURBS into blocks: {e}"))
}

fn point3(p: Vec3) -> [f64; 3] {
    [p.x, p.y, p.z]
}

/// Percentiles of a timing histogram, µs.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Percentiles {
    /// Values recorded.
    pub samples: u64,
    /// Median, µs.
    pub p50: f64,
    /// 99th percentile, µs.
    pub p99: f64,
    /// Maximum, µs.
    pub max: f64,
}

impl Percentiles {
    fn of(h: &Histogram) -> Option<Self> {
        let us = |ns: u64| ns as f64 / 1e3;
        Some(Percentiles {
            samples: h.count(),
            p50: us(h.quantile(0.5)?),
            p99: us(h.quantile(0.99)?),
            max: us(h.max()?),
        })
    }
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
    /// Time spent in `Interpolator::tick`, µs.
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
    /// Ticks where the schedule wanted more deceleration than allowed (0 in a correct plan).
    pub brake_overruns: u64,
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
    pub service: Option<crate::demo_service::ServiceRun>,
}

/// The interpolator configuration of the direct run.
fn config(args: &DemoArgs) -> InterpConfig {
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
    ip: Box<Interpolator>,
    start: Vec3,
    end: Vec3,
    length: f64,
    feed_limit: f64,
    prm: LoopParams,
}

impl Prepared {
    fn new(args: &DemoArgs) -> Result<Self> {
        if !(args.feed.is_finite() && args.feed > 0.0) {
            bail!(
                "--feed must be a positive number of mm/min, got {}",
                args.feed
            );
        }
        let cfg = config(args);
        let feed = args.feed / 60.0;
        let blocks = butterfly_blocks(args.feed)?;
        let (first, last) = match (blocks.first(), blocks.last()) {
            (Some(f), Some(l)) => (f, l),
            _ => bail!("the butterfly gave no blocks"),
        };
        let start = first.path.start_point();
        let end = last.path.end_point();
        let length: f64 = blocks.iter().map(|b| b.path.length()).sum();

        let mut ip: Box<Interpolator> = Box::new(
            Interpolator::new(cfg, [start.x, start.y, start.z, 0.0, 0.0, 0.0])
                .map_err(Error::msg)
                .context("configuring the interpolator")?,
        );
        for (i, b) in blocks.iter().enumerate() {
            ip.push(b).map_err(Error::msg).with_context(|| {
                format!(
                    "queueing butterfly block {} ({} of {}, {:.3} mm) before the loop",
                    b.id,
                    i + 1,
                    blocks.len(),
                    b.path.length()
                )
            })?;
        }
        ip.finish();
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
    fn subscriber(&self) -> Subscriber {
        Subscriber::new(
            self.cfg.period,
            Limits::new(&self.cfg, self.feed_limit),
            point3(self.start),
        )
    }
}

/// Runs the demo and returns its summary; `on_setpoint` sees every setpoint the
/// recorder receives (all of them unless `timing.recorder_drops > 0`).
pub fn run(args: &DemoArgs, on_setpoint: impl FnMut(&Setpoint)) -> Result<Summary> {
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

    let out = std::thread::scope(|s| -> Result<LoopOutcome> {
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
    let mut violations = out.sub.violations;
    if last_sp.state != RunState::Done {
        violations.not_done = 1;
    }
    if final_point != point3(end) {
        violations.end_mismatch = 1;
    }
    if violations.total() > 0 && violations.first_seq.is_none() {
        violations.first_seq = Some(last_sp.seq);
    }
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
            brake_overruns: stats.brake_overruns,
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
            "  interp      {} ticks, {} segments done, {} brake overruns, max {} Newton iterations",
            i.ticks, i.segments_done, i.brake_overruns, i.max_newton_iters
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
    pub(crate) fn fast_args() -> DemoArgs {
        let mut a = tests::args(&["--fast", "--no-service", "--no-plots"]);
        a.out = std::env::temp_dir();
        a
    }

    /// The direct run's configuration.
    pub(crate) fn config(args: &DemoArgs) -> InterpConfig {
        super::config(args)
    }

    /// The butterfly's interpolator blocks.
    pub(crate) fn blocks(args: &DemoArgs) -> Vec<Block> {
        butterfly_blocks(args.feed).expect("the butterfly splits")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Debug, Parser)]
    struct Wrap {
        #[command(flatten)]
        args: DemoArgs,
    }

    pub(super) fn args(extra: &[&str]) -> DemoArgs {
        let argv = ["demo"].iter().chain(extra).copied();
        Wrap::try_parse_from(argv).expect("demo args parse").args
    }

    fn fast_run() -> (Summary, Vec<Setpoint>) {
        let mut sps = Vec::new();
        let summary = run(&args(&["--fast"]), |sp| sps.push(*sp)).expect("demo runs");
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
        let a = args(&[]);
        assert_eq!(a.feed, 6000.0);
        assert_eq!(a.period_us, 1000);
        assert_eq!(a.chord_tolerance_mm, 0.001);
        assert_eq!(a.accel, InterpConfig::default().max_path_accel);
        assert!(!a.fast && !a.json && a.csv.is_none());
        assert!(Wrap::try_parse_from(["demo", "--period-us", "0"]).is_err());
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

    /// The default limits at a feed limit of `feed` mm/s.
    fn limits(feed: f64) -> Limits {
        Limits::new(&InterpConfig::default(), feed)
    }

    /// A start from rest along `dir` (a unit axis): the acceleration ramps
    /// up at `jerk` for `ramp` ticks, then stays for `hold` ticks. Setpoints
    /// as the interpolator writes them (`feed` = Δs/Ts).
    fn ramp(ts: f64, jerk: f64, ramp: u32, hold: u32, dir: [f64; 3]) -> Vec<Setpoint> {
        let (mut a, mut v, mut s) = (0.0, 0.0, 0.0);
        (1..=ramp + hold)
            .map(|k| {
                if k <= ramp {
                    a += jerk * ts;
                }
                v += a * ts;
                s += v * ts;
                Setpoint {
                    seq: u64::from(k),
                    time: f64::from(k) * ts,
                    axes: [s * dir[0], s * dir[1], s * dir[2], 0.0, 0.0, 0.0],
                    feed: v,
                    s,
                    state: RunState::Running,
                    ..Setpoint::default()
                }
            })
            .collect()
    }

    fn check_all(lim: Limits, sps: &[Setpoint]) -> Subscriber {
        let mut sub = Subscriber::new(1e-3, lim, [0.0; 3]);
        for sp in sps {
            sub.check(sp);
        }
        sub
    }

    #[test]
    fn a_smooth_start_passes_and_its_jerk_is_measured() {
        let lim = limits(100.0);
        // 50 000 mm/s³ for 20 ticks (accel 1000 mm/s²), then constant accel.
        let sps = ramp(1e-3, 50_000.0, 20, 30, [1.0, 0.0, 0.0]);
        let sub = check_all(lim, &sps);
        assert_eq!(sub.violations, Violations::default());
        let m = sub.measured;
        assert!((m.path_jerk_mm_s3 / 50_000.0 - 1.0).abs() < 1e-6, "{m:?}");
        assert!(
            (m.axis_jerk_mm_s3[0] / 50_000.0 - 1.0).abs() < 1e-6,
            "{m:?}"
        );
        assert_eq!((m.axis_jerk_mm_s3[1], m.axis_velocity_mm_s[2]), (0.0, 0.0));
        assert!((m.axis_accel_mm_s2[0] / 1000.0 - 1.0).abs() < 1e-6, "{m:?}");
    }

    #[test]
    fn subscriber_flags_an_injected_jerk_spike() {
        let lim = limits(100.0);
        let mut sps = ramp(1e-3, 50_000.0, 20, 30, [1.0, 0.0, 0.0]);
        // 0.15 µm off the path at one tick: third differences δ, −3δ, 3δ, −δ over
        // Ts³, i.e. 1.5e5, 4.5e5, 4.5e5, 1.5e5 mm/s³ on s and on X, while
        // velocity and acceleration stay within their limits.
        let delta = 1.5e-4;
        let n = 40;
        sps[n - 1].s += delta;
        sps[n - 1].axes[0] += delta;
        let v = check_all(lim, &sps).violations;
        assert_eq!(v.over_jerk, 4, "{v:?}"); // path limit 1e5
        assert_eq!(v.over_axis_jerk, 2, "{v:?}"); // axis limit 2e5
        assert_eq!(v.first_seq, Some(n as u64));
        assert_eq!(v.total(), 6, "{v:?}");
        // The same spike on the arc length alone is a path-jerk failure only.
        let mut sps = ramp(1e-3, 50_000.0, 20, 30, [1.0, 0.0, 0.0]);
        sps[n - 1].s += delta;
        let v = check_all(lim, &sps).violations;
        assert_eq!((v.over_jerk, v.total()), (4, 4), "{v:?}");
    }

    #[test]
    fn the_jerk_limit_holds_to_one_ppm() {
        let lim = limits(100.0);
        // 15 ticks at the jerk limit reach 1500 mm/s² (< 2000).
        let at = |j: f64| check_all(lim, &ramp(1e-3, j, 15, 5, [0.0, 1.0, 0.0])).violations;
        assert_eq!(at(lim.jerk_mm_s3 * (1.0 - 1e-7)).total(), 0);
        let v = at(lim.jerk_mm_s3 * (1.0 + 1e-5));
        assert_eq!((v.over_jerk, v.first_seq), (15, Some(1)), "{v:?}");
        assert_eq!(v.total(), 15, "{v:?}");
    }

    #[test]
    fn axis_limits_apply_per_axis() {
        // 50 ticks reach 40.5 mm/s; X may do 30 mm/s, Y and Z 1000.
        let lim = Limits {
            axis_velocity_mm_s: [30.0, 1000.0, 1000.0],
            axis_accel_mm_s2: [4000.0, 900.0, 4000.0],
            ..limits(100.0)
        };
        let along = |dir| check_all(lim, &ramp(1e-3, 50_000.0, 20, 30, dir)).violations;
        let x = along([1.0, 0.0, 0.0]);
        assert!(x.over_axis_velocity > 0 && x.over_axis_accel == 0, "{x:?}");
        let y = along([0.0, 1.0, 0.0]);
        assert!(y.over_axis_velocity == 0 && y.over_axis_accel > 0, "{y:?}");
        let z = along([0.0, 0.0, 1.0]);
        assert_eq!(z, Violations::default());
    }

    #[test]
    fn subscriber_catches_gaps_overspeed_overaccel_and_nan() {
        let ts = 1e-3;
        // Steps from rest: no jerk or axis limits here (tested above).
        let lim = Limits {
            jerk_mm_s3: f64::INFINITY,
            axis_velocity_mm_s: [f64::INFINITY; 3],
            axis_accel_mm_s2: [f64::INFINITY; 3],
            axis_jerk_mm_s3: [f64::INFINITY; 3],
            ..limits(100.0)
        };
        let mut sub = Subscriber::new(ts, lim, [0.0; 3]);
        let mut sp = Setpoint {
            seq: 1,
            time: ts,
            feed: 1.0,
            state: RunState::Running,
            ..Setpoint::default()
        };
        sp.axes[0] = 1e-3;
        sub.check(&sp);
        assert_eq!(sub.violations, Violations::default());
        sp.seq = 3; // gap
        sp.feed = 4.0; // Δfeed/Ts = 3000 > 2000
        sp.axes[0] = 1e-3 + 0.2; // 200 mm/s chord
        sub.check(&sp);
        sp.seq = 4;
        sp.axes[1] = f64::NAN;
        sub.check(&sp);
        let v = sub.violations;
        assert_eq!((v.seq_gaps, v.over_accel, v.non_finite), (1, 1, 1));
        assert_eq!(v.over_speed, 0);
        assert_eq!(v.over_chord_speed, 2); // the jump, then NaN
        assert_eq!(v.first_seq, Some(3));
        // A commanded feed above the limit, reached within the acceleration limit.
        let mut sub = Subscriber::new(ts, lim, [0.0; 3]);
        let mut x = 0.0;
        for k in 1..=60u32 {
            let feed = (2.0 * f64::from(k)).min(101.0);
            x += feed * ts;
            let sp = Setpoint {
                seq: u64::from(k),
                feed,
                axes: [x, 0.0, 0.0, 0.0, 0.0, 0.0],
                ..Setpoint::default()
            };
            sub.check(&sp);
        }
        let v = sub.violations;
        assert_eq!(
            (v.over_speed, v.over_chord_speed, v.over_accel),
            (10, 10, 0)
        );
    }

    #[test]
    fn csv_has_a_header_and_one_row_per_setpoint() {
        let path = std::env::temp_dir().join(format!("interpd-demo-{}.csv", std::process::id()));
        let a = args(&["--fast", "--csv", path.to_str().expect("utf-8 temp path")]);
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

    use traces::alloc_count as counting;

    /// The binary's RT pool in front of the counting allocator: tests count
    /// what reaches the system allocator.
    #[global_allocator]
    static ALLOCATOR: crate::rt_alloc::RtPool<counting::Counting> =
        crate::rt_alloc::RtPool(counting::Counting);

    #[test]
    fn the_loop_does_not_allocate() {
        let mut p = Prepared::new(&args(&["--fast"])).expect("program queues");
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
        let out = dir.to_str().expect("utf-8 temp path");
        main(&args(&["--fast", "--no-service", "--out", out])).expect("demo passes");
        let mut names: Vec<String> = std::fs::read_dir(&dir)
            .expect("out dir made")
            .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        let want =
            ["acceleration", "chord_error", "feed", "jerk", "path_xy"].map(|n| format!("{n}.png"));
        assert_eq!(names, want);
        std::fs::remove_dir_all(&dir).expect("cleanup");
        main(&args(&[
            "--fast",
            "--no-service",
            "--no-plots",
            "--out",
            out,
        ]))
        .expect("demo passes");
        assert!(!dir.exists(), "--no-plots wrote into {out}");
        assert_eq!(args(&[]).out, PathBuf::from(DEFAULT_OUT_DIR));
    }

    #[test]
    fn a_bad_feed_is_refused_with_context() {
        let e = run(&args(&["--feed", "0"]), |_| {}).unwrap_err();
        assert!(e.to_string().contains("--feed"), "{e:#}");
    }
}
