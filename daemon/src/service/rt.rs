//! The RT thread: one `interp_core::Executor`, a fixed period with
//! absolute deadlines, one iceoryx2 sample per tick, and nothing else.
//!
//! What its executor is given is decided by the planning thread
//! ([`crate::service::sequencer`]), which runs a copy of the executor a lead
//! of ticks ahead and sends every plan and command as a step tagged with the
//! tick it precedes. The RT thread talks to the rest of the process only
//! through fixed-capacity SPSC queues (`heapless::spsc`) and atomics:
//!
//! - steps in ([`STEP_SLOTS`]): plans to commit (`Executor::commit`: a splice
//!   of the speed plan and the segments, microseconds) and hold, resume and
//!   abort, each applied before the tick it is tagged with; the executor
//!   ticks only once the planning thread has decided that tick;
//! - spent plan buffers out ([`SPENT_SLOTS`]): the RT thread never frees memory,
//!   it hands each `Box<PlannedBlock>` back for reuse;
//! - records out to the recorder thread ([`RECORD_SLOTS`]): every tick's
//!   setpoint and timing, and everything applied to the interpolator between
//!   ticks (pushes and commands, with the tick they preceded) so that a
//!   recording replays bit for bit; a full queue is counted, never waited on;
//! - [`RtStatus`]: atomics the control plane reads for `status`.
//!
//! The control plane's segments and commands go to the planning thread
//! ([`SEGMENT_SLOTS`], [`CMD_SLOTS`]); blocks it refuses come back
//! ([`EVENT_SLOTS`]). A commit's cost is measured apart from the tick's
//! (`compute_with_push`), see `docs/daemon.md`.

use core::sync::atomic::{AtomicBool, AtomicI64, AtomicU32, AtomicU64, Ordering};
use std::sync::Arc;
use std::sync::mpsc;
use std::thread::JoinHandle;

use anyhow::{Context, Result, anyhow, bail};
use heapless::spsc::{Consumer, Producer, Queue};
use interp_core::interp::PushError;
use interp_core::{Block, Executor, InterpConfig, PlannedBlock, RunState, Setpoint};
use interp_run::{Op, Run};

use crate::service::clock::{minimise_timer_slack, now_ns, wait_until_ns};
use crate::service::histogram::Histogram;
use crate::service::publish::SetpointPublisher;
use crate::service::sequencer::{Sequencer, Step};

/// Segments queued between the control plane and the planning thread (one slot is kept free).
pub const SEGMENT_SLOTS: usize = 16;
/// Steps queued between the planning thread and the RT thread.
pub const STEP_SLOTS: usize = 64;
/// Spent plan buffers handed back: room for every buffer that can be in
/// flight (the step queue, the one the RT thread holds and the planning
/// thread's), so handing back never fails.
pub const SPENT_SLOTS: usize = STEP_SLOTS + 4;
/// Commands queued towards the planning thread.
pub const CMD_SLOTS: usize = 64;
/// Refused blocks reported back.
pub const EVENT_SLOTS: usize = 64;
/// Setpoints queued for the recorder: four seconds at 1 kHz.
pub const RECORD_SLOTS: usize = 4096;
/// Stack of the RT and planning threads, and of the thread every CLI command
/// runs on (`main.rs`): the executor and the driver are built on them before
/// they are boxed (an unoptimised `interpd simulate` needs 12–14 MiB).
pub use interp_run::stack::RT_STACK_BYTES;
/// Default lead of the planning thread over the RT thread, ms: what a
/// command waits before it takes effect, and the planning time that can
/// pass without the RT thread waiting for a plan.
pub const DEFAULT_PLAN_LEAD_MS: u32 = 40;
/// Stack prefaulted after `mlockall`, so the first deep `push` does not page-fault.
const PREFAULT_STACK_BYTES: usize = 512 << 10;

/// One segment of a program, queued for the planning thread.
#[derive(Clone, Copy, Debug)]
pub struct Segment {
    /// The program it belongs to (numbered by the control plane from 1).
    pub program: u32,
    /// The segment.
    pub block: Block,
}

/// An operator command, applied by the planning thread between two ticks
/// (and by the RT thread at the same tick).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Command {
    /// Cycle start of a program: it moves once its first segment is pushed.
    Start(u32),
    /// Feed hold (applied only while the machine moves a program).
    Hold,
    /// Leave a feed hold (applied only while holding).
    Resume,
    /// Feed override, 1 = 100 % (validated by the sender).
    Override(f64),
    /// The program ends after the blocks already sent.
    End(u32),
    /// Stop on the path within the limits, flush everything queued.
    Abort,
}

/// A block the interpolator refused (all its parts before it were queued).
#[derive(Clone, Copy, Debug)]
pub struct PushFailure {
    /// The block's id.
    pub id: u32,
    /// Why.
    pub error: PushError,
}

/// What the RT thread hands the recorder thread.
#[derive(Clone, Copy, Debug)]
pub enum RtRecord {
    /// One period.
    Tick(TickRecord),
    /// Applied to the interpolator after `tick` ticks (so before tick `tick + 1`).
    Applied {
        /// Interpolator ticks done when it was applied.
        tick: u64,
        /// What.
        what: Applied,
    },
}

/// A change to the interpolator between two ticks.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Applied {
    /// A segment was pushed (its id).
    Commit(u32),
    /// `feed_hold`.
    Hold,
    /// `resume`.
    Resume,
    /// `set_feed_override` (accepted).
    Override(f64),
    /// `abort`: an operator's.
    Abort,
    /// `abort` of a finished program, leaving `Done` for the next one
    /// (recorded apart: no operator asked for it).
    NextProgram,
    /// `finish`: the program ends after what is queued.
    Finish,
    /// A segment's push waited for room, and the due parts of a long
    /// block were planned before it (`interp_run::Run::plan_parts`).
    Parts,
}

/// One tick for the recorder.
#[derive(Clone, Copy, Debug)]
pub struct TickRecord {
    /// The setpoint.
    pub setpoint: Setpoint,
    /// Wake time minus deadline, ns.
    pub lateness_ns: u64,
    /// Tick + publish time, ns.
    pub compute_ns: u64,
    /// Interpolator segments queued after the tick.
    pub queue_depth: u32,
    /// Whether the interpolator ticked (false while waiting for `start`).
    pub ticked: bool,
}

/// Live counters of the RT thread (written by it, read by anyone).
#[derive(Debug, Default)]
pub struct RtStatus {
    /// `RunState as u8` of the last setpoint.
    pub state: AtomicU32,
    /// Samples published.
    pub published: AtomicU64,
    /// Interpolator ticks.
    pub ticks: AtomicU64,
    /// Block id of the last setpoint.
    pub block_id: AtomicU32,
    /// Last joints X Y Z A B C (f64 bits).
    pub position: [AtomicU64; 6],
    /// Last feed (f64 bits), mm/s.
    pub feed: AtomicU64,
    /// Last arc length (f64 bits), mm.
    pub s: AtomicU64,
    /// Applied feed override (f64 bits).
    pub feed_override: AtomicU64,
    /// Blocks (pieces) pushed into the interpolator.
    pub blocks_pushed: AtomicU64,
    /// Periods the RT thread waited for the planning thread to decide its
    /// tick while a program ran (0 while the planner keeps its lead).
    pub planner_late: AtomicU64,
    /// Holds, resumes and overrides the planning thread merged with a later
    /// one before applying them (see `sequencer::Deferred`).
    pub commands_merged: AtomicU64,
    /// Blocks refused by the interpolator.
    pub blocks_refused: AtomicU64,
    /// Joins planned as rest points in the session (corners slower to pass
    /// than to stop at, exact stops, cusps; from the planning thread).
    pub junction_stops: AtomicU64,
    /// Stops the look-ahead added that no program asks for (a rest kept at
    /// the old end of the queue, a crawl; from the planning thread).
    pub look_ahead_added_stops: AtomicU64,
    /// Segments queued in the interpolator.
    pub queued_segments: AtomicU32,
    /// Missed periods.
    pub overruns: AtomicU64,
    /// Ticks not handed to the recorder (its queue was full).
    pub recorder_drops: AtomicU64,
    /// Samples whose publish failed.
    pub publish_failures: AtomicU64,
    /// Aborts fully applied (queue flushed).
    pub aborts: AtomicU64,
    /// Whether `start` was given for the current program.
    pub started: AtomicBool,
    /// The program the machine runs (0: none yet).
    pub program: AtomicU32,
    /// Whether `end` was given and applied (`Driver::finish`).
    pub finished: AtomicBool,
    /// The RT thread is in its loop.
    pub running: AtomicBool,
    /// Tick k of the loop is due at this + k · period (ns on the monotonic
    /// clock); set before `running`. A missed period is skipped, so the
    /// deadlines stay on this grid.
    pub epoch_ns: AtomicI64,
}

impl RtStatus {
    /// Last published state.
    pub fn run_state(&self) -> RunState {
        crate::service::publish::run_state(self.state.load(Ordering::Acquire))
    }
    /// Last X Y Z.
    pub fn position(&self) -> [f64; 3] {
        [0, 1, 2].map(|i| f64::from_bits(self.position[i].load(Ordering::Acquire)))
    }
    /// Last joints X Y Z A B C.
    pub fn axes(&self) -> [f64; 6] {
        [0, 1, 2, 3, 4, 5].map(|i| f64::from_bits(self.position[i].load(Ordering::Acquire)))
    }
}

/// Default period of the loop, µs.
pub const DEFAULT_PERIOD_US: u32 = 1000;
/// Default SCHED_FIFO priority of the RT thread.
pub const DEFAULT_PRIORITY: i32 = 80;

/// The RT thread's scheduling flags, shared by `interpd serve` and
/// `interpd jitter` so that both loops of a jitter run are scheduled as
/// `serve` would be.
#[derive(Clone, Debug, PartialEq)]
pub struct RtSettings {
    /// Interpolation period, µs (250..=10000).
    pub period_us: u32,
    /// SCHED_FIFO priority of the RT thread (1..=99).
    pub priority: i32,
    /// Normal scheduling: no SCHED_FIFO, no mlockall, no pinning.
    pub no_rt: bool,
    /// CPU to pin the RT thread to (default: the last one).
    pub cpu: Option<usize>,
    /// Wake this many µs before each deadline and spin on the clock to it
    /// (at most half the period). Keeps the core awake so that the setpoint
    /// goes out on time, at the cost of that much CPU per period; 0 sleeps
    /// to the deadline.
    pub spin_us: u32,
    /// How far the planning thread runs ahead of the RT thread, ms
    /// (2..=1000): a hold, override or abort takes effect this much later;
    /// planning may take this long without the RT thread waiting for it.
    pub plan_lead_ms: u32,
}

impl Default for RtSettings {
    /// The defaults of `interpd serve` with no flags.
    fn default() -> Self {
        RtSettings {
            period_us: DEFAULT_PERIOD_US,
            priority: DEFAULT_PRIORITY,
            no_rt: false,
            cpu: None,
            spin_us: 0,
            plan_lead_ms: DEFAULT_PLAN_LEAD_MS,
        }
    }
}

impl RtSettings {
    /// The RT thread's options for these flags (the last CPU unless `--cpu`
    /// or `--no-rt`), publishing on `service`.
    pub fn options(&self, service: &str, autostart: bool) -> Result<RtOptions> {
        if u64::from(self.spin_us) * 2 > u64::from(self.period_us) {
            bail!(
                "--spin-us {} is more than half the period ({} µs)",
                self.spin_us,
                self.period_us
            );
        }
        let cpus = std::thread::available_parallelism().map_or(1, |n| n.get());
        let lead_ticks = (u64::from(self.plan_lead_ms) * 1000).div_ceil(u64::from(self.period_us));
        Ok(RtOptions {
            lead_ticks,
            period_ns: i64::from(self.period_us) * 1000,
            spin_ns: i64::from(self.spin_us) * 1000,
            fifo_priority: (!self.no_rt).then_some(self.priority),
            cpu: (!self.no_rt).then(|| self.cpu.unwrap_or(cpus - 1)),
            lock_memory: !self.no_rt,
            service: service.to_owned(),
            autostart,
        })
    }
}

/// How the RT thread is scheduled.
#[derive(Clone, Debug)]
pub struct RtOptions {
    /// Ticks the planning thread runs ahead of the RT thread.
    pub lead_ticks: u64,
    /// Period, ns.
    pub period_ns: i64,
    /// Spin on the clock for this long before each deadline instead of sleeping, ns.
    pub spin_ns: i64,
    /// SCHED_FIFO priority (1..=99); `None` keeps normal scheduling.
    pub fifo_priority: Option<i32>,
    /// CPU to pin the thread to; `None` leaves affinity alone.
    pub cpu: Option<usize>,
    /// Lock all memory (`mlockall`).
    pub lock_memory: bool,
    /// iceoryx2 service name.
    pub service: String,
    /// Start with `start` already given (the first program moves at once).
    pub autostart: bool,
}

/// What the RT thread hands back when it stops.
#[derive(Debug)]
pub struct RtReport {
    /// Wake lateness, ns.
    pub lateness: Histogram,
    /// Tick + publish compute, ns (ticks without a push).
    pub compute: Histogram,
    /// Push + tick + publish, ns (ticks with a push).
    pub compute_with_push: Histogram,
    /// Missed periods.
    pub overruns: u64,
    /// Scheduling that was asked for but refused (warnings already printed).
    pub scheduling_warnings: Vec<String>,
    /// The last setpoint.
    pub last: Setpoint,
    /// Samples published.
    pub published: u64,
    /// Allocations the loop made on the RT thread (counted in tests only).
    #[cfg_attr(not(test), allow(dead_code))]
    pub loop_allocations: Option<u64>,
}

/// Runs `f`, counting its allocations on this thread when the counting
/// allocator is installed (the daemon's unit tests).
#[cfg(test)]
fn count_allocations<R>(f: impl FnOnce() -> R) -> (R, Option<u64>) {
    let (r, n) = alloc_count::count(f);
    (r, Some(n))
}

#[cfg(not(test))]
fn count_allocations<R>(f: impl FnOnce() -> R) -> (R, Option<u64>) {
    (f(), None)
}

/// The control plane's ends of the planning and RT threads' queues.
pub struct RtHandles {
    /// Segments to push.
    pub segments: Producer<'static, Segment>,
    /// Commands.
    pub commands: Producer<'static, Command>,
    /// Refused blocks.
    pub failures: Consumer<'static, PushFailure>,
    /// Recorder feed.
    pub records: Consumer<'static, RtRecord>,
    /// Live counters.
    pub status: Arc<RtStatus>,
    /// Set to stop the loop (after an abort has brought the machine to rest).
    pub stop: Arc<AtomicBool>,
    /// The RT thread.
    pub thread: JoinHandle<RtReport>,
    /// The planning thread (stops with `stop`).
    pub planner: JoinHandle<()>,
}

impl core::fmt::Debug for RtHandles {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("RtHandles")
            .field("status", &self.status)
            .finish_non_exhaustive()
    }
}

/// Queues live for the whole process: leaked once per RT thread (a few MB).
fn leak<T, const N: usize>() -> &'static mut Queue<T, N> {
    Box::leak(Box::new(Queue::new()))
}

/// Starts the RT thread (an executor at rest at `position` and the
/// publisher on it) and the planning thread that decides its steps; both
/// run until `stop`.
pub fn spawn(cfg: InterpConfig, position: [f64; 6], opts: RtOptions) -> Result<RtHandles> {
    let (seg_tx, seg_rx) = leak::<Segment, SEGMENT_SLOTS>().split();
    let (step_tx, step_rx) = leak::<Step, STEP_SLOTS>().split();
    let (spent_tx, spent_rx) = leak::<Box<PlannedBlock>, SPENT_SLOTS>().split();
    let (cmd_tx, cmd_rx) = leak::<Command, CMD_SLOTS>().split();
    let (fail_tx, fail_rx) = leak::<PushFailure, EVENT_SLOTS>().split();
    let (rec_tx, rec_rx) = leak::<RtRecord, RECORD_SLOTS>().split();
    let status = Arc::new(RtStatus::default());
    status
        .feed_override
        .store(1f64.to_bits(), Ordering::Release);
    let stop = Arc::new(AtomicBool::new(false));
    let decided = Arc::new(AtomicU64::new(0));
    let config_error = |e: interp_core::config::ConfigError| anyhow!("{e:?}");
    let (ready_tx, ready_rx) = mpsc::channel::<Result<()>>();
    let period = std::time::Duration::from_nanos(opts.period_ns as u64);
    let (lead_ticks, autostart) = (opts.lead_ticks, opts.autostart);
    let plan_priority = opts.fifo_priority.map(planning_priority);
    let st = Arc::clone(&status);
    let sp = Arc::clone(&stop);
    let dec = Arc::clone(&decided);
    let thread = std::thread::Builder::new()
        .name("interpd-rt".into())
        .stack_size(RT_STACK_BYTES)
        .spawn(move || {
            let mut warnings = apply_scheduling(&opts);
            let setup = (|| -> Result<(Box<Executor>, SetpointPublisher)> {
                let exec = Box::new(
                    Executor::new(cfg, position)
                        .map_err(config_error)
                        .context("configuring the interpolator")?,
                );
                let publisher = SetpointPublisher::new(&opts.service)?;
                Ok((exec, publisher))
            })();
            let (exec, publisher) = match setup {
                Ok(x) => {
                    let _ = ready_tx.send(Ok(()));
                    x
                }
                Err(e) => {
                    let _ = ready_tx.send(Err(e));
                    return RtReport {
                        lateness: Histogram::new(),
                        compute: Histogram::new(),
                        compute_with_push: Histogram::new(),
                        overruns: 0,
                        scheduling_warnings: core::mem::take(&mut warnings),
                        last: Setpoint::default(),
                        published: 0,
                        loop_allocations: None,
                    };
                }
            };
            let ctx = Loop {
                exec,
                publisher,
                steps: step_rx,
                spent: spent_tx,
                records: rec_tx,
                status: st,
                stop: sp,
                decided: dec,
                period_ns: opts.period_ns,
                spin_ns: opts.spin_ns,
                position,
            };
            let mut report = ctx.run();
            report.scheduling_warnings = warnings;
            report
        })
        .context("spawning the RT thread")?;
    match ready_rx.recv() {
        Ok(Ok(())) => {}
        Ok(Err(e)) => {
            let _ = thread.join();
            return Err(e);
        }
        Err(_) => {
            let _ = thread.join();
            return Err(anyhow!("the RT thread died while starting"));
        }
    }
    let st = Arc::clone(&status);
    let sp = Arc::clone(&stop);
    let planner = std::thread::Builder::new()
        .name("interpd-plan".into())
        .stack_size(RT_STACK_BYTES)
        .spawn(move || {
            if let Some(prio) = plan_priority {
                set_planning_scheduling(prio);
            }
            let run = match Run::new(cfg, position) {
                Ok(r) => Box::new(r.recording()),
                // The RT thread built the same executor from the same
                // config: this cannot fail once it started.
                Err(_) => return,
            };
            Sequencer {
                run,
                segments: seg_rx,
                commands: cmd_rx,
                failures: fail_tx,
                steps: step_tx,
                spent: spent_rx,
                status: st,
                decided,
                stop: sp,
                lead_ticks,
                period,
                autostart,
                started: autostart,
                program: 0,
                start_for: 0,
                aborting: false,
                finished: false,
                end_requested: None,
                pending: None,
                deferred: Default::default(),
            }
            .run();
        })
        .context("spawning the planning thread")?;
    Ok(RtHandles {
        segments: seg_tx,
        commands: cmd_tx,
        failures: fail_rx,
        records: rec_rx,
        status,
        stop,
        thread,
        planner,
    })
}

/// The SCHED_FIFO priority of the planning thread when the RT thread runs at
/// `rt` (half of it, at least 1): above every normally scheduled thread, so
/// that its planning keeps its lead on a loaded machine, and below the RT
/// thread, which preempts it. Scheduled normally, it fell behind the RT
/// thread (which then published its last point again): `ruota_dentata-q1`
/// at F6000 with an override every 113 ms and a hold every 97 ms resumed
/// after 20 ms, with four busy loops beside it on a 2-core machine,
/// 162–327 periods a run; at SCHED_FIFO 40, none. (Bursts of commands
/// that outlast the lead on an idle machine are the sequencer's to pace:
/// `sequencer::Deferred`.)
pub fn planning_priority(rt: i32) -> i32 {
    (rt / 2).max(1)
}

/// The calling (planning) thread to SCHED_FIFO `prio`; a refusal is a
/// warning (it plans with normal scheduling, as it did before).
fn set_planning_scheduling(prio: i32) {
    #[cfg(target_os = "linux")]
    if let Err(e) = set_fifo(prio) {
        eprintln!(
            "interpd: warning: SCHED_FIFO priority {prio} refused for the planning thread ({e}): \
             it plans with normal scheduling and may fall behind on a loaded machine"
        );
    }
    #[cfg(not(target_os = "linux"))]
    let _ = prio;
}

/// The calling thread to SCHED_FIFO `prio`.
#[cfg(target_os = "linux")]
fn set_fifo(prio: i32) -> std::io::Result<()> {
    let param = libc::sched_param {
        sched_priority: prio,
    };
    // SAFETY: `param` is a valid sched_param; pthread_self is this thread.
    let rc = unsafe { libc::pthread_setschedparam(libc::pthread_self(), libc::SCHED_FIFO, &param) };
    if rc == 0 {
        Ok(())
    } else {
        Err(std::io::Error::from_raw_os_error(rc))
    }
}

/// SCHED_FIFO, affinity and `mlockall` as asked; returns a warning per refusal
/// (also printed: the loop then runs with normal scheduling).
pub(crate) fn apply_scheduling(opts: &RtOptions) -> Vec<String> {
    let mut warnings = Vec::new();
    let mut warn = |w: String| {
        eprintln!("interpd: warning: {w}");
        warnings.push(w);
    };
    if !minimise_timer_slack() {
        warn("could not set the RT thread's timer slack to 1 ns".into());
    }
    #[cfg(target_os = "linux")]
    {
        if opts.lock_memory {
            // SAFETY: mlockall takes flags only.
            let rc = unsafe { libc::mlockall(libc::MCL_CURRENT | libc::MCL_FUTURE) };
            if rc != 0 {
                warn(format!(
                    "mlockall failed ({}): pages may fault in the RT loop",
                    std::io::Error::last_os_error()
                ));
            } else {
                prefault_stack();
            }
        }
        if let Some(cpu) = opts.cpu {
            // SAFETY: a zeroed cpu_set_t is an empty set; CPU_SET writes inside it;
            // pid 0 is the calling thread.
            let rc = unsafe {
                let mut set: libc::cpu_set_t = core::mem::zeroed();
                libc::CPU_SET(cpu, &mut set);
                libc::sched_setaffinity(0, core::mem::size_of::<libc::cpu_set_t>(), &set)
            };
            if rc != 0 {
                warn(format!(
                    "cannot pin the RT thread to CPU {cpu} ({})",
                    std::io::Error::last_os_error()
                ));
            }
        }
        if let Some(prio) = opts.fifo_priority
            && let Err(e) = set_fifo(prio)
        {
            warn(format!(
                "SCHED_FIFO priority {prio} refused ({e}): running with normal scheduling \
                 (give the binary CAP_SYS_NICE or raise RLIMIT_RTPRIO)"
            ));
        }
    }
    #[cfg(not(target_os = "linux"))]
    {
        let _ = opts;
        warn("SCHED_FIFO, mlockall and affinity are only implemented on Linux".into());
    }
    warnings
}

#[cfg(target_os = "linux")]
#[inline(never)]
fn prefault_stack() {
    let mut buf = [0u8; PREFAULT_STACK_BYTES];
    // Touch every page; black_box keeps the writes.
    for i in (0..buf.len()).step_by(4096) {
        buf[i] = 1;
    }
    core::hint::black_box(&buf);
}

struct Loop {
    exec: Box<Executor>,
    publisher: SetpointPublisher,
    steps: Consumer<'static, Step>,
    spent: Producer<'static, Box<PlannedBlock>>,
    records: Producer<'static, RtRecord>,
    status: Arc<RtStatus>,
    stop: Arc<AtomicBool>,
    /// Ticks the planning thread has decided.
    decided: Arc<AtomicU64>,
    period_ns: i64,
    spin_ns: i64,
    position: [f64; 6],
}

impl Loop {
    /// Hands a plan buffer back to the planning thread: freeing it here would
    /// call the allocator on the RT thread.
    fn recycle(&mut self, plan: Box<PlannedBlock>) {
        if let Err(plan) = self.spent.enqueue(plan) {
            // Cannot happen (SPENT_SLOTS covers every buffer in flight); leak
            // rather than free on this thread.
            core::mem::forget(plan);
        }
    }

    /// Hands a record to the recorder; a full queue is counted, never waited on.
    fn record(&mut self, r: RtRecord) {
        if self.records.enqueue(r).is_err() {
            self.status.recorder_drops.fetch_add(1, Ordering::Relaxed);
        }
    }

    /// Applies the steps for the coming tick; returns the time spent in
    /// commits, ns.
    fn apply_steps(&mut self) -> u64 {
        let ticks = self.exec.stats().ticks;
        let mut commit_ns = 0u64;
        while self.steps.peek().is_some_and(|s| s.at <= ticks) {
            let Some(step) = self.steps.dequeue() else {
                break;
            };
            // A step applied after its tick: replay would not follow (see
            // `run_loop`).
            debug_assert_eq!(step.at, ticks, "a step for tick {} applied late", step.at);
            if let Some(op) = step.op {
                let t0 = now_ns();
                // A refusal is the planning thread's too: its copy was
                // offered the same plan in the same state.
                let _ = op.apply(&mut self.exec);
                match op {
                    Op::Commit(plan) => {
                        commit_ns += (now_ns() - t0).max(0) as u64;
                        self.recycle(plan);
                    }
                    Op::Abort if step.operator => {
                        self.status.aborts.fetch_add(1, Ordering::AcqRel);
                    }
                    _ => {}
                }
            }
            if let Some(what) = step.record {
                self.record(RtRecord::Applied { tick: ticks, what });
            }
            if step.program != self.status.program.load(Ordering::Relaxed) {
                // The state first: a reader that sees the new program
                // (Acquire) must not see the last one's `done` as its own.
                self.status
                    .state
                    .store(self.exec.state() as u32, Ordering::Release);
            }
            // The program first: a reader that sees its `started` or
            // `finished` (Acquire) sees which program they are for.
            self.status.program.store(step.program, Ordering::Release);
            self.status.started.store(step.started, Ordering::Release);
            self.status.finished.store(step.finished, Ordering::Release);
        }
        commit_ns
    }

    fn run(mut self) -> RtReport {
        // Allocated before the loop; the loop itself must not allocate (counted in tests).
        let mut hist = [Histogram::new(), Histogram::new(), Histogram::new()];
        // iceoryx2 allocates a small object per loan: from the fixed pool on this thread.
        crate::service::rt_alloc::enter_rt();
        let ((overruns, last), loop_allocations) = count_allocations(|| self.run_loop(&mut hist));
        // The loop is over: dropping the publisher and node (iceoryx2 builds
        // paths and lists to release its shared memory) is not RT work.
        crate::service::rt_alloc::leave_rt();
        let [lateness, compute, compute_with_push] = hist;
        self.status.running.store(false, Ordering::Release);
        self.status
            .publish_failures
            .store(self.publisher.failures(), Ordering::Release);
        RtReport {
            lateness,
            compute,
            compute_with_push,
            overruns,
            scheduling_warnings: Vec::new(),
            last,
            published: self.status.published.load(Ordering::Acquire),
            loop_allocations,
        }
    }

    /// The loop until `stop`; returns the overruns and the last setpoint.
    fn run_loop(&mut self, hist: &mut [Histogram; 3]) -> (u64, Setpoint) {
        let [lateness, compute, compute_with_push] = hist;
        let mut overruns = 0u64;
        // The setpoint published while nothing moves: where the machine is.
        let mut last = Setpoint {
            axes: self.position,
            ..Setpoint::default()
        };
        let mut next = now_ns();
        self.status.epoch_ns.store(next, Ordering::Release);
        self.status.running.store(true, Ordering::Release);
        // One period, in the phases of docs/daemon.md › One tick.
        loop {
            next += self.period_ns;
            let late_ns = self.wait(next, lateness);
            if self.stop.load(Ordering::Acquire) {
                break;
            }
            // Whether this tick is decided, read before its steps are taken:
            // every step for it was queued before it was decided, so none
            // is left behind to be applied a tick late.
            let decided = self.decided.load(Ordering::Acquire) > self.exec.stats().ticks;
            let push_ns = self.apply_steps();
            let t0 = now_ns();
            let ticked = self.tick(&mut last, decided);
            let seq = self.publisher.publish(&last);
            let tick_ns = (now_ns() - t0).max(0) as u64;
            if push_ns > 0 {
                compute_with_push.record(push_ns + tick_ns);
            } else {
                compute.record(tick_ns);
            }
            self.record_tick(last, late_ns, tick_ns, ticked);
            self.publish_status(&last, seq);
            next = self.skip_missed(next, &mut overruns);
        }
        self.drain_steps();
        (overruns, last)
    }

    /// Phase 1: sleeps (or spins) to the deadline `next`; returns the wake
    /// lateness, ns, also recorded in `lateness`.
    fn wait(&self, next: i64, lateness: &mut Histogram) -> u64 {
        wait_until_ns(next, self.spin_ns);
        let late_ns = (now_ns() - next).max(0) as u64;
        lateness.record(late_ns);
        late_ns
    }

    /// Phase 3: ticks if the planning thread had `decided` this tick when
    /// its steps were taken (it sent every step before it); otherwise `last`
    /// again, unticked (waiting for `start`, or a late planner). Returns
    /// whether it ticked.
    fn tick(&mut self, last: &mut Setpoint, decided: bool) -> bool {
        if decided {
            *last = self.exec.tick();
        } else {
            if matches!(self.exec.state(), RunState::Running | RunState::Stopping)
                && self.status.started.load(Ordering::Relaxed)
            {
                self.status.planner_late.fetch_add(1, Ordering::Relaxed);
            }
            last.feed = 0.0;
            // A step may have left `done` for a new program (queued,
            // not started: it stays idle until it ticks).
            let st = self.exec.state();
            if st == RunState::Idle || (last.state == RunState::Done && st != RunState::Done) {
                last.state = RunState::Idle;
            }
        }
        decided
    }

    /// Phase 5: the setpoint and its timing to the recorder.
    fn record_tick(&mut self, setpoint: Setpoint, lateness_ns: u64, compute_ns: u64, ticked: bool) {
        let rec = TickRecord {
            setpoint,
            lateness_ns,
            compute_ns,
            queue_depth: self.exec.queued_segments() as u32,
            ticked,
        };
        self.record(RtRecord::Tick(rec));
    }

    /// Phase 6: a missed period is counted and skipped, never hidden: the
    /// next deadline is the first one still ahead. Returns the deadline
    /// the next period starts from.
    fn skip_missed(&self, next: i64, overruns: &mut u64) -> i64 {
        let end = now_ns();
        if end > next + self.period_ns {
            let missed = (end - next) / self.period_ns;
            *overruns += missed as u64;
            self.status.overruns.store(*overruns, Ordering::Release);
            return next + (missed - 1).max(0) * self.period_ns;
        }
        next
    }

    /// After the loop: plan buffers still queued go back to the planning
    /// thread, not freed here.
    fn drain_steps(&mut self) {
        while let Some(step) = self.steps.dequeue() {
            if let Some(Op::Commit(plan)) = step.op {
                self.recycle(plan);
            }
        }
    }

    /// The state is stored last: a reader that sees it (Acquire) sees the
    /// position, feed and counters of the same tick.
    fn publish_status(&self, sp: &Setpoint, seq: u64) {
        let s = &self.status;
        s.ticks.store(sp.seq, Ordering::Release);
        s.block_id.store(sp.block_id, Ordering::Release);
        for i in 0..6 {
            s.position[i].store(sp.axes[i].to_bits(), Ordering::Release);
        }
        s.feed.store(sp.feed.to_bits(), Ordering::Release);
        s.s.store(sp.s.to_bits(), Ordering::Release);
        s.queued_segments
            .store(self.exec.queued_segments() as u32, Ordering::Release);
        s.publish_failures
            .store(self.publisher.failures(), Ordering::Relaxed);
        s.published.store(seq, Ordering::Release);
        s.state.store(sp.state as u32, Ordering::Release);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use interp_core::samples::butterfly;
    use interp_core::{Curve, Vec3};

    /// The RT loop (steps from the planning thread: commits and commands;
    /// ticks, publishing, records) over thousands of ticks makes no
    /// allocation; the counting allocator is installed for this test binary
    /// (`demo.rs`).
    #[test]
    fn the_rt_loop_commits_ticks_and_publishes_without_allocating() {
        let cfg = InterpConfig {
            period: 250e-6,
            ..InterpConfig::default()
        };
        let start = butterfly::START;
        let opts = RtOptions {
            period_ns: 250_000,
            // The spinning wait is on the path under test too.
            spin_ns: 50_000,
            fifo_priority: None,
            cpu: None,
            lock_memory: false,
            service: format!("interpd-test/{}/rt-alloc", std::process::id()),
            autostart: true,
            lead_ticks: 160,
        };
        let position = [start[0], start[1], start[2], 0.0, 0.0, 0.0];
        let mut rt = spawn(cfg, position, opts).expect("RT thread starts");
        let mut blocks = Vec::new();
        butterfly::for_each_block::<()>(100.0, 1, 32, |b| {
            blocks.push(b);
            Ok(())
        })
        .expect("butterfly blocks");
        let end = blocks.last().map(|b| b.path.end_point()).expect("blocks");
        let wait = std::time::Instant::now() + std::time::Duration::from_secs(60);
        let drain = |rt: &mut RtHandles| while rt.records.dequeue().is_some() {};
        for b in &blocks {
            let mut seg = Segment {
                program: 1,
                block: *b,
            };
            while let Err(back) = rt.segments.enqueue(seg) {
                seg = back;
                drain(&mut rt);
                std::thread::sleep(std::time::Duration::from_millis(1));
            }
        }
        for c in [
            Command::Override(1.5),
            Command::Hold,
            Command::Resume,
            Command::End(1),
        ] {
            rt.commands.enqueue(c).expect("room for commands");
            std::thread::sleep(std::time::Duration::from_millis(300));
            drain(&mut rt);
        }
        while rt.status.run_state() != RunState::Done {
            assert!(
                std::time::Instant::now() < wait,
                "the program did not finish"
            );
            drain(&mut rt);
            std::thread::sleep(std::time::Duration::from_millis(5));
        }
        rt.stop.store(true, Ordering::Release);
        let report = rt.thread.join().expect("RT thread");
        assert_eq!(report.last.state, RunState::Done);
        assert_eq!(
            Vec3::new(
                report.last.axes[0],
                report.last.axes[1],
                report.last.axes[2]
            ),
            end
        );
        assert_eq!(
            rt.status.blocks_pushed.load(Ordering::Acquire),
            blocks.len() as u64
        );
        assert!(report.last.seq > 4000, "{} ticks", report.last.seq);
        // Every push committed a plan on the RT thread, in some period.
        assert!(report.compute_with_push.count() > 0);
        // Nothing reached the system allocator; iceoryx2's one small object
        // per published sample came from the RT pool.
        assert_eq!(report.loop_allocations, Some(0));
        assert!(crate::service::rt_alloc::served() >= report.published);
    }

    #[test]
    fn rt_flags_become_the_loop_options_and_a_spin_over_half_the_period_is_refused() {
        let rt = RtSettings {
            period_us: 500,
            priority: 70,
            cpu: Some(0),
            spin_us: 250,
            ..RtSettings::default()
        };
        let o = rt.options("svc", true).expect("half the period is allowed");
        assert_eq!((o.period_ns, o.spin_ns), (500_000, 250_000));
        assert_eq!(
            (o.fifo_priority, o.cpu, o.lock_memory),
            (Some(70), Some(0), true)
        );
        assert_eq!((o.service.as_str(), o.autostart), ("svc", true));
        let plain = RtSettings {
            no_rt: true,
            ..rt.clone()
        }
        .options("svc", false)
        .expect("valid");
        assert_eq!(
            (plain.fifo_priority, plain.cpu, plain.lock_memory),
            (None, None, false)
        );
        let err = RtSettings { spin_us: 251, ..rt }
            .options("svc", false)
            .expect_err("more than half the period");
        assert!(err.to_string().contains("--spin-us 251"), "{err}");
    }
}
