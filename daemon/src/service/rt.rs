//! The RT thread: one `Interpolator`, a fixed period with absolute deadlines,
//! one iceoryx2 sample per tick, and nothing else.
//!
//! It talks to the rest of the process only through fixed-capacity SPSC
//! queues (`heapless::spsc`) and atomics:
//!
//! - plans in ([`BLOCK_SLOTS`]): blocks already parsed, split and *planned*
//!   by the control plane (`interp_core::BlockPlanner`: law sampling, the
//!   costly half of `push`); at most one is committed per tick
//!   (`Interpolator::commit`: merge, erosion, backward pass, microseconds),
//!   and only when the interpolator has room (a refusal waits for the next tick);
//! - spent plan buffers out ([`SPENT_SLOTS`]): the RT thread never frees memory,
//!   it hands each `Box<PlannedBlock>` back for reuse;
//! - commands in ([`CMD_SLOTS`]): start, hold, resume, override, end, abort,
//!   applied between ticks;
//! - push errors out ([`EVENT_SLOTS`]): a block the interpolator refused;
//! - records out to the recorder thread ([`RECORD_SLOTS`]): every tick's
//!   setpoint and timing, and everything applied to the interpolator between
//!   ticks (commits and commands, with the tick they preceded) so that a
//!   recording replays bit for bit; a full queue is counted, never waited on;
//! - [`RtStatus`]: atomics the control plane reads for `status`.
//!
//! A commit's cost is measured apart from the tick's (`compute_with_push`),
//! see `docs/daemon.md`.

use core::sync::atomic::{AtomicBool, AtomicI64, AtomicU32, AtomicU64, Ordering};
use std::sync::Arc;
use std::sync::mpsc;
use std::thread::JoinHandle;

use anyhow::{Context, Result, anyhow, bail};
use heapless::spsc::{Consumer, Producer, Queue};
use interp_core::interp::PushError;
use interp_core::{InterpConfig, Interpolator, PlannedBlock, RunState, Setpoint};

use crate::service::clock::{minimise_timer_slack, now_ns, wait_until_ns};
use crate::service::histogram::Histogram;
use crate::service::publish::SetpointPublisher;

/// Planned blocks queued between the control plane and the RT thread (one slot is kept free).
pub const BLOCK_SLOTS: usize = 16;
/// Spent plan buffers handed back: room for every buffer that can be in
/// flight (the plan queue and the one the RT thread holds), so handing back
/// never fails.
pub const SPENT_SLOTS: usize = BLOCK_SLOTS + 2;
/// Commands queued towards the RT thread.
pub const CMD_SLOTS: usize = 64;
/// Refused blocks reported back.
pub const EVENT_SLOTS: usize = 64;
/// Setpoints queued for the recorder: four seconds at 1 kHz.
pub const RECORD_SLOTS: usize = 4096;
/// Stack of the RT thread: the interpolator is built on it before it is boxed.
pub const RT_STACK_BYTES: usize = 32 << 20;
/// Stack prefaulted after `mlockall`, so the first deep `push` does not page-fault.
const PREFAULT_STACK_BYTES: usize = 512 << 10;

/// One planned segment of a program, queued for the RT thread.
#[derive(Debug)]
pub struct Plan {
    /// The program it belongs to (numbered by the control plane from 1).
    pub program: u32,
    /// The plan (handed back through the spent queue once committed).
    pub block: Box<PlannedBlock>,
}

/// An operator command, applied between two ticks.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Command {
    /// Cycle start of a program: it moves once its first segment is committed.
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
    /// A planned segment was committed (its id).
    Commit(u32),
    /// `feed_hold`.
    Hold,
    /// `resume`.
    Resume,
    /// `set_feed_override` (accepted).
    Override(f64),
    /// `abort` (an operator abort, or leaving `Done` for a new program).
    Abort,
    /// `finish`: the program ends after what is queued.
    Finish,
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
    /// Last X Y Z (f64 bits).
    pub position: [AtomicU64; 3],
    /// Last feed (f64 bits), mm/s.
    pub feed: AtomicU64,
    /// Last arc length (f64 bits), mm.
    pub s: AtomicU64,
    /// Applied feed override (f64 bits).
    pub feed_override: AtomicU64,
    /// Blocks (pieces) pushed into the interpolator.
    pub blocks_pushed: AtomicU64,
    /// Blocks refused by the interpolator.
    pub blocks_refused: AtomicU64,
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
    /// The program of the last commit (0: none yet).
    pub program: AtomicU32,
    /// Whether `end` was given and applied (`Interpolator::finish`).
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
}

/// Default period of the loop, µs.
pub const DEFAULT_PERIOD_US: u32 = 1000;
/// Default SCHED_FIFO priority of the RT thread.
pub const DEFAULT_PRIORITY: i32 = 80;

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
}

impl Default for RtArgs {
    /// The defaults of `interpd serve` with no flags.
    fn default() -> Self {
        RtArgs {
            period_us: DEFAULT_PERIOD_US,
            priority: DEFAULT_PRIORITY,
            no_rt: false,
            cpu: None,
            spin_us: 0,
        }
    }
}

impl RtArgs {
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
        Ok(RtOptions {
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

/// The non-RT ends of the RT thread's queues.
pub struct RtHandles {
    /// Planned blocks to commit.
    pub blocks: Producer<'static, Plan>,
    /// Plan buffers the RT thread is done with (reuse them).
    pub spent: Consumer<'static, Box<PlannedBlock>>,
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
    /// The thread.
    pub thread: JoinHandle<RtReport>,
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

/// Starts the RT thread: builds the interpolator (at rest at `position`) and
/// the publisher on it, then runs the loop until `stop`.
pub fn spawn(cfg: InterpConfig, position: [f64; 6], opts: RtOptions) -> Result<RtHandles> {
    let (blocks_tx, blocks_rx) = leak::<Plan, BLOCK_SLOTS>().split();
    let (spent_tx, spent_rx) = leak::<Box<PlannedBlock>, SPENT_SLOTS>().split();
    let (cmd_tx, cmd_rx) = leak::<Command, CMD_SLOTS>().split();
    let (fail_tx, fail_rx) = leak::<PushFailure, EVENT_SLOTS>().split();
    let (rec_tx, rec_rx) = leak::<RtRecord, RECORD_SLOTS>().split();
    let status = Arc::new(RtStatus::default());
    let stop = Arc::new(AtomicBool::new(false));
    let (ready_tx, ready_rx) = mpsc::channel::<Result<()>>();
    let st = Arc::clone(&status);
    let sp = Arc::clone(&stop);
    let thread = std::thread::Builder::new()
        .name("interpd-rt".into())
        .stack_size(RT_STACK_BYTES)
        .spawn(move || {
            let mut warnings = apply_scheduling(&opts);
            let setup = (|| -> Result<(Box<Interpolator>, SetpointPublisher)> {
                let ip = Box::new(
                    Interpolator::new(cfg, position)
                        .map_err(|e| anyhow!("{e:?}"))
                        .context("configuring the interpolator")?,
                );
                let publisher = SetpointPublisher::new(&opts.service)?;
                Ok((ip, publisher))
            })();
            let (ip, publisher) = match setup {
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
                ip,
                publisher,
                blocks: blocks_rx,
                spent: spent_tx,
                commands: cmd_rx,
                failures: fail_tx,
                records: rec_tx,
                status: st,
                stop: sp,
                period_ns: opts.period_ns,
                spin_ns: opts.spin_ns,
                started: opts.autostart,
                autostart: opts.autostart,
                program: 0,
                start_for: 0,
                position,
                aborting: false,
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
    Ok(RtHandles {
        blocks: blocks_tx,
        spent: spent_rx,
        commands: cmd_tx,
        failures: fail_rx,
        records: rec_rx,
        status,
        stop,
        thread,
    })
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
        if let Some(prio) = opts.fifo_priority {
            let param = libc::sched_param {
                sched_priority: prio,
            };
            // SAFETY: `param` is a valid sched_param; pthread_self is this thread.
            let rc = unsafe {
                libc::pthread_setschedparam(libc::pthread_self(), libc::SCHED_FIFO, &param)
            };
            if rc != 0 {
                warn(format!(
                    "SCHED_FIFO priority {prio} refused ({}): running with normal scheduling \
                     (give the binary CAP_SYS_NICE or raise RLIMIT_RTPRIO)",
                    std::io::Error::from_raw_os_error(rc)
                ));
            }
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
    ip: Box<Interpolator>,
    publisher: SetpointPublisher,
    blocks: Consumer<'static, Plan>,
    spent: Producer<'static, Box<PlannedBlock>>,
    commands: Consumer<'static, Command>,
    failures: Producer<'static, PushFailure>,
    records: Producer<'static, RtRecord>,
    status: Arc<RtStatus>,
    stop: Arc<AtomicBool>,
    period_ns: i64,
    spin_ns: i64,
    started: bool,
    autostart: bool,
    /// The program of the last commit (0: none yet).
    program: u32,
    /// The last program `start` was given for (it may not be committed yet).
    start_for: u32,
    position: [f64; 6],
    /// An abort is bringing the machine to rest (ticks go on without `start`).
    aborting: bool,
}

impl Loop {
    /// Applies the queued commands. Returns nothing; an abort flushes the blocks.
    /// Hands a plan buffer back to the control plane: freeing it here would
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

    /// Records a change applied to the interpolator before its next tick.
    fn applied(&mut self, what: Applied) {
        let tick = self.ip.stats().ticks;
        self.record(RtRecord::Applied { tick, what });
    }

    fn apply_commands(&mut self, end_requested: &mut Option<u32>, pending: &mut Option<Plan>) {
        while let Some(c) = self.commands.dequeue() {
            match c {
                Command::Start(p) => {
                    self.start_for = p;
                    if p == self.program {
                        self.started = true;
                    }
                }
                // Only motion is held: a hold while nothing moves is not
                // remembered for the next program.
                Command::Hold => {
                    if self.started && self.ip.state() == RunState::Running {
                        self.ip.feed_hold();
                        self.applied(Applied::Hold);
                    }
                }
                Command::Resume => {
                    if self.ip.state() == RunState::Holding {
                        self.ip.resume();
                        self.applied(Applied::Resume);
                    }
                }
                Command::Override(x) => {
                    // The control plane checked the range; a refusal leaves the old value.
                    if self.ip.set_feed_override(x).is_ok() {
                        self.applied(Applied::Override(x));
                    }
                }
                Command::End(p) => *end_requested = Some(p),
                Command::Abort => {
                    self.ip.abort();
                    self.applied(Applied::Abort);
                    if let Some(p) = pending.take() {
                        self.recycle(p.block);
                    }
                    while let Some(p) = self.blocks.dequeue() {
                        self.recycle(p.block);
                    }
                    *end_requested = None;
                    // Tick until at rest; `start` is needed again after that.
                    self.aborting = true;
                    self.status.aborts.fetch_add(1, Ordering::AcqRel);
                }
            }
        }
    }

    /// Whether `plan` may be committed now: a plan of the running program
    /// always; the first plan of the next one once the last one is over
    /// (`done`, or at rest after an abort), leaving `done` for it.
    fn ready_for(&mut self, plan: &Plan, last: &mut Setpoint) -> bool {
        if plan.program == self.program {
            return true;
        }
        match self.ip.state() {
            RunState::Done => {
                // A new program after a finished one: leave Done.
                self.ip.abort();
                self.applied(Applied::Abort);
                last.state = self.ip.state();
                self.status.finished.store(false, Ordering::Release);
            }
            RunState::Idle if !self.aborting => {}
            _ => return false,
        }
        self.program = plan.program;
        self.started = self.autostart || self.start_for == plan.program;
        // The state first: a reader that sees the new program (Acquire)
        // must not see the last one's `done` as its own.
        self.status
            .state
            .store(self.ip.state() as u32, Ordering::Release);
        self.status.program.store(plan.program, Ordering::Release);
        true
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
        let mut pending: Option<Plan> = None;
        // `end` of this program was given.
        let mut end_requested: Option<u32> = None;
        // Segments completed when the interpolator last refused `pending` for room.
        let mut refused_at: Option<u64> = None;
        // The setpoint published while nothing moves: where the machine is.
        let mut last = Setpoint {
            axes: self.position,
            ..Setpoint::default()
        };
        let mut next = now_ns();
        self.status.epoch_ns.store(next, Ordering::Release);
        self.status.running.store(true, Ordering::Release);
        loop {
            next += self.period_ns;
            wait_until_ns(next, self.spin_ns);
            let wake = now_ns();
            lateness.record((wake - next).max(0) as u64);
            if self.stop.load(Ordering::Acquire) {
                break;
            }
            self.apply_commands(&mut end_requested, &mut pending);
            if pending.is_none() {
                refused_at = None; // an abort dropped the refused block
            }

            // At most one commit per tick, only when there is room.
            let mut push_ns = 0u64;
            if pending.is_none() {
                pending = self.blocks.dequeue();
            }
            // After a refusal for room, retry only once a segment was completed.
            let room_maybe = refused_at.is_none_or(|n| self.ip.stats().segments_done > n);
            let ready = match pending.take() {
                Some(p) if room_maybe && self.ready_for(&p, &mut last) => Some(p),
                other => {
                    pending = other;
                    None
                }
            };
            if let Some(p) = ready {
                let t0 = now_ns();
                let r = self.ip.commit(&p.block);
                push_ns = (now_ns() - t0).max(0) as u64;
                match r {
                    Ok(()) => {
                        self.applied(Applied::Commit(p.block.id()));
                        refused_at = None;
                        self.status.blocks_pushed.fetch_add(1, Ordering::AcqRel);
                        self.recycle(p.block);
                    }
                    Err(PushError::Full { .. } | PushError::ProfileFull) => {
                        refused_at = Some(self.ip.stats().segments_done);
                        pending = Some(p);
                    }
                    // Cannot happen for a plan of the running program (`end`
                    // waits for its plans); kept rather than lost.
                    Err(PushError::Aborting | PushError::Finished) => pending = Some(p),
                    Err(error) => {
                        refused_at = None;
                        self.status.blocks_refused.fetch_add(1, Ordering::AcqRel);
                        let _ = self.failures.enqueue(PushFailure {
                            id: p.block.id(),
                            error,
                        });
                        self.recycle(p.block);
                    }
                }
            }
            // `end`: once every plan of the program is committed.
            let queued = |p: Option<&Plan>| p.is_some_and(|p| p.program == self.program);
            if end_requested == Some(self.program)
                && !queued(pending.as_ref())
                && !queued(self.blocks.peek())
            {
                self.ip.finish();
                self.applied(Applied::Finish);
                end_requested = None;
                self.status.finished.store(true, Ordering::Release);
            }

            let t0 = now_ns();
            let ticked = self.started || self.aborting;
            if ticked {
                last = self.ip.tick();
                if self.aborting && last.state != RunState::Stopping {
                    self.aborting = false;
                    self.started = self.autostart;
                }
            } else {
                // Waiting for `start`: the last point again, unticked, so that
                // a program queued before `start` runs as it would in simulate.
                last.feed = 0.0;
            }
            let seq = self.publisher.publish(&last);
            let t1 = now_ns();
            let tick_ns = (t1 - t0).max(0) as u64;
            if push_ns > 0 {
                compute_with_push.record(push_ns + tick_ns);
            } else {
                compute.record(tick_ns);
            }
            let rec = TickRecord {
                setpoint: last,
                lateness_ns: (wake - next).max(0) as u64,
                compute_ns: tick_ns,
                queue_depth: self.ip.queued_segments() as u32,
                ticked,
            };
            self.record(RtRecord::Tick(rec));
            self.publish_status(&last, seq);

            // A missed period is counted and skipped, never hidden: the next
            // deadline is the first one still ahead.
            let end = now_ns();
            if end > next + self.period_ns {
                let missed = (end - next) / self.period_ns;
                overruns += missed as u64;
                next += (missed - 1).max(0) * self.period_ns;
                self.status.overruns.store(overruns, Ordering::Release);
            }
        }
        if let Some(p) = pending {
            self.recycle(p.block);
        }
        (overruns, last)
    }

    /// The state is stored last: a reader that sees it (Acquire) sees the
    /// position, feed and counters of the same tick.
    fn publish_status(&self, sp: &Setpoint, seq: u64) {
        let s = &self.status;
        s.ticks.store(sp.seq, Ordering::Release);
        s.block_id.store(sp.block_id, Ordering::Release);
        for i in 0..3 {
            s.position[i].store(sp.axes[i].to_bits(), Ordering::Release);
        }
        s.feed.store(sp.feed.to_bits(), Ordering::Release);
        s.s.store(sp.s.to_bits(), Ordering::Release);
        s.feed_override
            .store(self.ip.feed_override().to_bits(), Ordering::Release);
        s.queued_segments
            .store(self.ip.queued_segments() as u32, Ordering::Release);
        s.started.store(self.started, Ordering::Release);
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
    use interp_core::{BlockPlanner, Curve, Vec3};

    /// The RT loop (commits, commands, ticks, publishing, records) over
    /// thousands of ticks makes no allocation; the counting allocator is
    /// installed for this test binary (`demo.rs`).
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
        let mut planner =
            BlockPlanner::new(cfg, Vec3::new(start[0], start[1], start[2]), 0.0).expect("planner");
        let wait = std::time::Instant::now() + std::time::Duration::from_secs(60);
        let drain = |rt: &mut RtHandles| while rt.records.dequeue().is_some() {};
        for b in &blocks {
            let mut plan = rt
                .spent
                .dequeue()
                .unwrap_or_else(|| Box::new(PlannedBlock::new()));
            planner.plan(b, &mut plan).expect("plans");
            let mut plan = Plan {
                program: 1,
                block: plan,
            };
            while let Err(back) = rt.blocks.enqueue(plan) {
                plan = back;
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
        assert_eq!(report.compute_with_push.count(), blocks.len() as u64);
        // Nothing reached the system allocator; iceoryx2's one small object
        // per published sample came from the RT pool.
        assert_eq!(report.loop_allocations, Some(0));
        assert!(crate::service::rt_alloc::served() >= report.published);
    }

    #[test]
    fn rt_flags_become_the_loop_options_and_a_spin_over_half_the_period_is_refused() {
        let rt = RtArgs {
            period_us: 500,
            priority: 70,
            cpu: Some(0),
            spin_us: 250,
            ..RtArgs::default()
        };
        let o = rt.options("svc", true).expect("half the period is allowed");
        assert_eq!((o.period_ns, o.spin_ns), (500_000, 250_000));
        assert_eq!(
            (o.fifo_priority, o.cpu, o.lock_memory),
            (Some(70), Some(0), true)
        );
        assert_eq!((o.service.as_str(), o.autostart), ("svc", true));
        let plain = RtArgs {
            no_rt: true,
            ..rt.clone()
        }
        .options("svc", false)
        .expect("valid");
        assert_eq!(
            (plain.fifo_priority, plain.cpu, plain.lock_memory),
            (None, None, false)
        );
        let err = RtArgs { spin_us: 251, ..rt }
            .options("svc", false)
            .expect_err("more than half the period");
        assert!(err.to_string().contains("--spin-us 251"), "{err}");
    }
}
