//! The control plane (tokio, non-RT): listeners on loopback TCP and a Unix
//! socket, one task per connection speaking the line protocol of
//! [`crate::protocol`]. Blocks are parsed, checked and split here and handed
//! to the planning thread ([`crate::service::sequencer`]) through its SPSC
//! queue; a full queue is back-pressure (the reply waits, so the client's
//! writes stall), never a drop.
//!
//! A program belongs to the connection that sent its first block (or
//! `begin`) until it ends: `done`, an abort, or a fault. Another connection
//! sending blocks or `end` meanwhile is refused as `busy`, naming the owner;
//! every connection may ask for the status, hold, resume, override, start
//! and abort. A connection that leaves mid-program holds the machine if it
//! moves, and its program can be taken over by the next connection that
//! sends a block or `end`.

use core::sync::atomic::{AtomicU8, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use heapless::spsc::{Consumer, Producer};
use interp_core::RunState;
use serde::{Deserialize, Serialize};
use tokio::io::{AsyncBufRead, AsyncBufReadExt, AsyncRead, AsyncWrite, AsyncWriteExt, BufReader};

use crate::protocol::{MAX_LINE_BYTES, Reply, Request, parse};
use crate::service::publish::state_name;
use crate::service::rt::{Command, PushFailure, RtStatus, Segment};

/// How long `abort` waits for the machine to come to rest before replying.
pub const ABORT_WAIT: Duration = Duration::from_secs(30);

/// Shared by every connection.
pub struct Control {
    /// Block producer and the end of what was accepted (held while a block
    /// waits for room in the queue).
    pub stream: tokio::sync::Mutex<Stream>,
    /// The current program and its owner (short critical sections only:
    /// a busy client is told so without waiting for the stream).
    pub programs: Mutex<Programs>,
    /// Command producer (short critical sections only).
    pub commands: Mutex<Producer<'static, Command>>,
    /// Refused blocks reported by the planning thread.
    pub failures: Mutex<Consumer<'static, PushFailure>>,
    /// The RT thread's counters.
    pub status: Arc<RtStatus>,
    /// Interpolation period (poll interval while back-pressured).
    pub period: Duration,
    /// Largest feed override accepted.
    pub max_feed_override: f64,
    /// The machine's path-speed limit, mm/s (what a rapid runs at).
    pub max_path_speed: f64,
    /// The five-axis machine of the configuration, if any (the status reports it).
    pub machine: Option<interp_core::kinematics::MachineSpec>,
    /// Token every connection must present first (`None`: no authentication).
    pub token: Option<String>,
    /// Incremented by every abort: a stream waiting on a full queue drops its block.
    pub abort_epoch: AtomicU64,
    /// The last hold or resume sent for the program that moves
    /// ([`HOLD_SENT`], [`RESUME_SENT`], 0: neither since its start or an
    /// abort): a command acts a planning lead after it is sent, and until
    /// then the machine's state does not show it (`commanded_state`).
    pub motion_command: AtomicU8,
    /// Blocks (protocol lines) accepted.
    pub blocks_accepted: AtomicU64,
    /// Lines refused with an error.
    pub errors: AtomicU64,
    /// Connections accepted (numbers them from 1).
    pub connections: AtomicU64,
    /// Last refused block reported by the RT thread.
    pub last_refusal: Mutex<Option<String>>,
    /// The trace recorder's queue, if recording (taken at shutdown).
    pub recorder: Mutex<Option<traces::RecordTx>>,
}

/// [`Control::motion_command`]: a hold was sent last.
pub const HOLD_SENT: u8 = 1;
/// [`Control::motion_command`]: a resume was sent last.
pub const RESUME_SENT: u8 = 2;

/// Where a program is in its life.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Phase {
    /// No program yet.
    None,
    /// Taking blocks.
    Open,
    /// `end` was sent: it runs to its end.
    Ended,
    /// It reached `done`.
    Done,
    /// It was aborted.
    Aborted,
    /// The interpolator faulted.
    Fault,
}

/// A connection, as ownership and errors name it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Peer {
    /// Its number, from 1 in the order of connecting.
    pub id: u64,
    /// `tcp ADDRESS` or `unix`.
    pub name: String,
}

impl core::fmt::Display for Peer {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "connection {} ({})", self.id, self.name)
    }
}

/// The current program.
#[derive(Clone, Debug, PartialEq)]
pub struct Programs {
    /// Its number (0: none yet).
    pub program: u32,
    /// Its phase as the control plane last set it (see [`Control::phase`]).
    pub phase: Phase,
    /// The connection it belongs to (`None`: its connection left).
    pub owner: Option<Peer>,
    /// `start` was accepted for it.
    pub started: bool,
    /// Blocks accepted into it.
    pub blocks: u32,
    /// When it was claimed (a busy refusal says how long it has held the machine).
    pub since: Option<std::time::Instant>,
    /// The program before it and how it ended (0, `None`: none), so that
    /// its client learns its fate after the next one was claimed.
    pub previous: (u32, Phase),
}

impl Programs {
    /// Before the first program.
    pub fn new() -> Self {
        Programs {
            program: 0,
            phase: Phase::None,
            owner: None,
            started: false,
            blocks: 0,
            since: None,
            previous: (0, Phase::None),
        }
    }
}

impl Default for Programs {
    fn default() -> Self {
        Self::new()
    }
}

/// The streaming side: the planning thread's segment queue and where the
/// next block starts.
pub struct Stream {
    /// Producer of the planning thread's queue of segments.
    pub segments: Producer<'static, Segment>,
    /// End of the last segment queued (after an abort: where the machine
    /// stopped).
    pub queued_to: [f64; 3],
    /// Whether `queued_to` is the tool tip (the last segment queued was under
    /// tool-centre-point control).
    pub queued_tcp: bool,
    /// The machine's joints at the end of the queue (after an abort: where
    /// it stopped), where the next program starts.
    pub queued_joints: [f64; 6],
    /// The five-axis machine of `interp` (the joints of the queue's end are
    /// followed through its inverse).
    pub machine: Option<interp_core::kinematics::Machine>,
    /// End of the last accepted block (`None`: where the machine is).
    pub tail: Option<[f64; 3]>,
    /// Id of the next interpolator segment (from 1 in each program).
    pub next_id: u32,
    /// Blocks accepted in this program.
    pub index: u32,
    /// The program the fields above belong to.
    pub program: u32,
    /// The program's pipeline (input blocks through the `G64 P` stage to
    /// interpolator segments), made at its first block from the end of the
    /// queue with ids from `next_id`.
    pub pipeline: Option<traces::Pipeline>,
    /// The interpolator's configuration (the pipeline's stage runs under it).
    pub interp: interp_core::InterpConfig,
}

/// What [`Control::follow`] replaces when the stream moves on to a new
/// program, kept to put back when the block that claimed it is refused.
struct StreamMark {
    queued_to: [f64; 3],
    queued_tcp: bool,
    queued_joints: [f64; 6],
    tail: Option<[f64; 3]>,
    next_id: u32,
    index: u32,
    program: u32,
    pipeline: Option<traces::Pipeline>,
}

impl StreamMark {
    fn take(s: &mut Stream) -> Self {
        StreamMark {
            queued_to: s.queued_to,
            queued_tcp: s.queued_tcp,
            queued_joints: s.queued_joints,
            tail: s.tail,
            next_id: s.next_id,
            index: s.index,
            program: s.program,
            pipeline: s.pipeline.take(),
        }
    }

    fn restore(self, s: &mut Stream) {
        s.queued_to = self.queued_to;
        s.queued_tcp = self.queued_tcp;
        s.queued_joints = self.queued_joints;
        s.tail = self.tail;
        s.next_id = self.next_id;
        s.index = self.index;
        s.program = self.program;
        s.pipeline = self.pipeline;
    }
}

impl core::fmt::Debug for Control {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Control")
            .field("period", &self.period)
            .field("abort_epoch", &self.abort_epoch)
            .finish_non_exhaustive()
    }
}

impl core::fmt::Debug for Stream {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Stream")
            .field("tail", &self.tail)
            .field("next_id", &self.next_id)
            .field("program", &self.program)
            .finish_non_exhaustive()
    }
}

/// The reply to `status`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StatusReply {
    /// Interpolator state.
    pub state: String,
    /// Whether `start` was given for the program the machine runs.
    pub started: bool,
    /// Whether `end` was applied.
    pub finished: bool,
    /// The current program's number (0: none yet).
    pub program: u32,
    /// Its phase.
    pub program_phase: Phase,
    /// The connection it belongs to, if one does.
    pub program_owner: Option<String>,
    /// The program before it (0: none) ...
    #[serde(default)]
    pub previous_program: u32,
    /// ... and how it ended (`done`, `aborted`, `faulted`).
    #[serde(default = "no_phase")]
    pub previous_phase: Phase,
    /// The program the interpolator runs (its last commit; 0: none yet).
    pub machine_program: u32,
    /// Interpolator ticks.
    pub ticks: u64,
    /// Samples published.
    pub published: u64,
    /// Block id of the last setpoint.
    pub block_id: u32,
    /// X Y Z, mm.
    pub position: [f64; 3],
    /// Path speed, mm/s.
    pub feed: f64,
    /// Arc length of the run, mm.
    pub s: f64,
    /// Applied feed override.
    pub feed_override: f64,
    /// The machine's path-speed limit, mm/s (rapids run at it).
    pub max_path_speed: f64,
    /// The five-axis machine (clients convert G-code for it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub machine: Option<interp_core::kinematics::MachineSpec>,
    /// Segments queued in the interpolator.
    pub queued_segments: u32,
    /// Protocol blocks accepted.
    pub blocks_accepted: u64,
    /// Interpolator blocks (pieces) pushed.
    pub pieces_pushed: u64,
    /// Pieces the interpolator refused.
    pub pieces_refused: u64,
    /// Last refusal.
    pub last_refusal: Option<String>,
    /// Joins planned as rest points in the session: corners slower to pass
    /// than to stop at, exact stops (`G61`), cusps.
    #[serde(default)]
    pub junction_stops: u64,
    /// Stops the look-ahead added that no program asks for (a re-solve
    /// that failed kept a rest at the old end of the queue, or crawled).
    #[serde(default)]
    pub look_ahead_added_stops: u64,
    /// Lines answered with an error.
    pub line_errors: u64,
    /// Missed periods.
    pub overruns: u64,
    /// Periods the RT thread waited for the planning thread (0 while the
    /// planner keeps its lead; see `--plan-lead-ms`).
    pub planner_late: u64,
    /// Holds, resumes and overrides merged with a later one before they
    /// were applied (a hold and its resume cancel out; the last override
    /// counts): commands came faster than the planner applies them.
    #[serde(default)]
    pub commands_merged: u64,
    /// Ticks the recorder had no room for.
    pub recorder_drops: u64,
    /// Failed publishes.
    pub publish_failures: u64,
}

impl Control {
    /// Sends a command to the RT thread (waits while its queue is full).
    pub async fn command(&self, c: Command) {
        loop {
            let ok = self
                .commands
                .lock()
                .map(|mut q| q.enqueue(c).is_ok())
                .unwrap_or(false);
            if ok {
                return;
            }
            tokio::time::sleep(self.period).await;
        }
    }

    /// Aborts and waits until the machine is at rest with the queue flushed.
    pub async fn abort(&self) -> Result<(), String> {
        self.abort_epoch.fetch_add(1, Ordering::AcqRel);
        self.motion_command.store(0, Ordering::Release);
        let before = self.status.aborts.load(Ordering::Acquire);
        self.command(Command::Abort).await;
        let deadline = tokio::time::Instant::now() + ABORT_WAIT;
        loop {
            let acked = self.status.aborts.load(Ordering::Acquire) > before;
            let st = self.status.run_state();
            let at_rest = self.status.feed.load(Ordering::Acquire) == 0f64.to_bits();
            if acked && at_rest && matches!(st, RunState::Idle | RunState::Done | RunState::Fault) {
                break;
            }
            if !self.status.running.load(Ordering::Acquire) && acked {
                break;
            }
            if tokio::time::Instant::now() > deadline {
                return Err("the machine did not come to rest in time".into());
            }
            tokio::time::sleep(self.period).await;
        }
        // Drain what the RT thread flushed; the next program starts where it stopped.
        self.stream.lock().await.tail = None;
        let mut p = self.lock_programs();
        if matches!(p.phase, Phase::Open | Phase::Ended) {
            p.phase = Phase::Aborted;
        }
        p.owner = None;
        Ok(())
    }

    /// The current program's phase: `Open` and `Ended` become `Done` or
    /// `Fault` once the RT thread reports its program so.
    pub fn phase(&self, s: &Programs) -> Phase {
        let on_machine = self.status.program.load(Ordering::Acquire) == s.program;
        match (s.phase, self.status.run_state()) {
            (Phase::Open | Phase::Ended, RunState::Fault) if on_machine => Phase::Fault,
            (Phase::Ended, RunState::Done) if on_machine => Phase::Done,
            (p, _) => p,
        }
    }

    /// Makes `peer` the owner of the program its block (or `begin` or
    /// `end`) belongs to: the current one if it owns it (or the current one
    /// lost its connection), else a new one once the current one is over.
    fn claim(&self, s: &mut Programs, peer: &Peer) -> Result<u32, String> {
        let phase = self.phase(s);
        let mine = s.owner.as_ref() == Some(peer);
        match phase {
            Phase::Open if mine => return Ok(s.program),
            Phase::Open if s.owner.is_none() => {
                eprintln!("interpd: {peer} takes over program {}", s.program);
                s.owner = Some(peer.clone());
                return Ok(s.program);
            }
            // Its own ended program still runs: the next one queues behind it.
            Phase::Ended if mine => {}
            Phase::Open | Phase::Ended => {
                let held = s.since.map_or(0.0, |t| t.elapsed().as_secs_f64());
                let what = match phase {
                    Phase::Open => "open",
                    _ => "running to its end",
                };
                return Err(match &s.owner {
                    Some(o) => format!(
                        "busy: program {} belongs to {o} ({what}, claimed {held:.1} s ago)",
                        s.program
                    ),
                    None => format!(
                        "busy: program {} is {what} (its connection left, claimed {held:.1} s \
                         ago); wait for done or abort it",
                        s.program
                    ),
                });
            }
            Phase::None | Phase::Done | Phase::Aborted | Phase::Fault => {}
        }
        s.previous = (s.program, phase);
        s.program += 1;
        s.phase = Phase::Open;
        s.owner = Some(peer.clone());
        s.started = false;
        s.blocks = 0;
        s.since = Some(std::time::Instant::now());
        Ok(s.program)
    }

    /// The program state (a poisoned lock is taken as it is: it holds plain data).
    fn lock_programs(&self) -> std::sync::MutexGuard<'_, Programs> {
        self.programs
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    /// Moves the stream on to `program` if it is a new one: segment ids from
    /// 1, as `simulate` numbers them, from where the last one ends (or where
    /// the machine is).
    fn follow(&self, s: &mut Stream, program: u32) {
        if s.program == program {
            return;
        }
        if s.tail.is_none() && self.status.published.load(Ordering::Acquire) > 0 {
            // Where the machine is (at rest: start, or after an abort), bit
            // for bit as the interpolator's queue end, in its own X Y Z.
            s.queued_to = self.status.position();
            s.queued_joints = self.status.axes();
            s.queued_tcp = false;
        }
        s.program = program;
        s.next_id = 1;
        s.index = 0;
        s.pipeline = None;
    }

    /// Where the next block of the current program starts: the end of the
    /// last one it accepted, or (a new pipeline) the end of the queue, which
    /// `follow` moved to where the machine is after an abort.
    fn next_start(&self, s: &Stream) -> [f64; 3] {
        match &s.pipeline {
            Some(p) => p.tail(),
            None => s.queued_to,
        }
    }

    /// The current status.
    pub async fn status(&self) -> StatusReply {
        if let Ok(mut f) = self.failures.lock() {
            while let Some(x) = f.dequeue() {
                if let Ok(mut l) = self.last_refusal.lock() {
                    *l = Some(format!("block {}: {}", x.id, x.error));
                }
            }
        }
        let (program, program_phase, program_owner, (previous_program, previous_phase)) = {
            let s = self.lock_programs();
            (
                s.program,
                self.phase(&s),
                s.owner.as_ref().map(ToString::to_string),
                s.previous,
            )
        };
        let s = &self.status;
        let f = |a: &AtomicU64| f64::from_bits(a.load(Ordering::Acquire));
        StatusReply {
            state: state_name(s.run_state()).to_owned(),
            started: s.started.load(Ordering::Acquire),
            finished: s.finished.load(Ordering::Acquire),
            program,
            program_phase,
            program_owner,
            previous_program,
            previous_phase,
            machine_program: s.program.load(Ordering::Acquire),
            ticks: s.ticks.load(Ordering::Acquire),
            published: s.published.load(Ordering::Acquire),
            block_id: s.block_id.load(Ordering::Acquire),
            position: s.position(),
            feed: f(&s.feed),
            s: f(&s.s),
            feed_override: f(&s.feed_override),
            max_path_speed: self.max_path_speed,
            machine: self.machine,
            queued_segments: s.queued_segments.load(Ordering::Acquire),
            blocks_accepted: self.blocks_accepted.load(Ordering::Acquire),
            pieces_pushed: s.blocks_pushed.load(Ordering::Acquire),
            pieces_refused: s.blocks_refused.load(Ordering::Acquire),
            last_refusal: self.last_refusal.lock().ok().and_then(|l| l.clone()),
            junction_stops: s.junction_stops.load(Ordering::Acquire),
            look_ahead_added_stops: s.look_ahead_added_stops.load(Ordering::Acquire),
            line_errors: self.errors.load(Ordering::Acquire),
            overruns: s.overruns.load(Ordering::Acquire),
            planner_late: s.planner_late.load(Ordering::Acquire),
            commands_merged: s.commands_merged.load(Ordering::Acquire),
            recorder_drops: s.recorder_drops.load(Ordering::Acquire),
            publish_failures: s.publish_failures.load(Ordering::Acquire),
        }
    }

    /// Hands an accepted block to the trace recorder, if recording.
    fn record_block(
        &self,
        index: u32,
        b: &traces::InputBlock,
        info: Vec<traces::messages::SegmentInfo>,
    ) {
        if let Ok(rec) = self.recorder.lock()
            && let Some(tx) = rec.as_ref()
        {
            let at = self.status.ticks.load(Ordering::Acquire);
            let msg = traces::messages::BlockMsg {
                index,
                block: b.clone(),
                segments: info,
                accepted_at_seq: at,
            };
            // Non-RT side: a full recorder queue is counted by the recorder.
            let _ = tx.try_push(traces::Record::Block(
                Box::new(msg),
                at as f64 * self.period.as_secs_f64(),
            ));
        }
    }

    /// `begin`: claims a program for `peer`; names it and where it starts.
    async fn begin(&self, peer: &Peer) -> Result<Reply, String> {
        let program = self.claim(&mut self.lock_programs(), peer)?;
        let mut s = self.stream.lock().await;
        self.follow(&mut s, program);
        Ok(Reply::Begin {
            program,
            at: s.queued_joints,
        })
    }

    /// `end`: the owner's program ends after the blocks it sent.
    /// The blocks the program's `G64 P` stage still holds are queued first.
    async fn end(&self, peer: &Peer) -> Result<Reply, String> {
        let epoch = self.abort_epoch.load(Ordering::Acquire);
        let program = self.end_program(&mut self.lock_programs(), peer)?;
        let Some(p) = program else {
            return Ok(Reply::End);
        };
        let mut s = self.stream.lock().await;
        let pipeline = if s.program == p {
            s.pipeline.take()
        } else {
            None
        };
        let flushed = match pipeline {
            Some(mut pipeline) => {
                let rest = pipeline.finish();
                self.queue(&mut s, p, epoch, rest).await
            }
            None => Ok(()),
        };
        drop(s);
        // The program ends after what was queued, even when the rest failed.
        self.command(Command::End(p)).await;
        flushed.map(|()| Reply::End)
    }

    /// The program `end` ends (`None`: it had ended already).
    fn end_program(&self, s: &mut Programs, peer: &Peer) -> Result<Option<u32>, String> {
        match self.phase(s) {
            Phase::Open => {}
            Phase::Ended if s.owner.as_ref() == Some(peer) => return Ok(None),
            Phase::Ended => {}
            p => {
                return Err(format!(
                    "end: no program is open (program {} is {})",
                    s.program,
                    phase_name(p)
                ));
            }
        }
        let before = s.clone();
        self.claim(s, peer)?;
        if s.blocks == 0 {
            // Refused: claims nothing.
            *s = before;
            return Err(format!("end: program {} has no blocks", s.program));
        }
        s.phase = Phase::Ended;
        Ok(Some(s.program))
    }

    /// `start`: lets the current program move; every refusal says why.
    async fn start(&self) -> Result<Reply, String> {
        let p = self.start_program(&mut self.lock_programs())?;
        self.command(Command::Start(p)).await;
        Ok(Reply::Start)
    }

    /// The program `start` starts, or why there is none to start.
    fn start_program(&self, s: &mut Programs) -> Result<u32, String> {
        let phase = self.phase(s);
        let state = self.commanded_state();
        let p = s.program;
        match phase {
            Phase::None => return Err("start: no program (send its blocks first)".into()),
            Phase::Done | Phase::Aborted | Phase::Fault => {
                return Err(format!(
                    "start: program {p} is {} (send a new program first)",
                    phase_name(phase)
                ));
            }
            Phase::Open | Phase::Ended => {}
        }
        if s.blocks == 0 {
            return Err(format!("start: program {p} has no blocks yet"));
        }
        if state == RunState::Holding {
            return Err(format!(
                "start: the machine is holding program {p} (send resume)"
            ));
        }
        if state == RunState::Stopping {
            return Err("start: the machine is stopping (an abort is in progress)".into());
        }
        if s.started {
            return Err(format!("start: program {p} is already started"));
        }
        s.started = true;
        // (A hold sent as the last program ended never acted.)
        self.motion_command.store(0, Ordering::Release);
        Ok(p)
    }

    /// The machine's state as the holds and resumes sent so far leave it:
    /// each acts a planning lead after it is sent (`--plan-lead-ms`), so a
    /// hold sent while the machine still runs is a hold, and a resume sent
    /// while it still holds is a resume. (Judged by the machine's state
    /// alone, a resume sent within the lead of its hold was refused, and the
    /// machine stayed held.)
    fn commanded_state(&self) -> RunState {
        let st = self.status.run_state();
        match (self.motion_command.load(Ordering::Acquire), st) {
            (HOLD_SENT, RunState::Running) => RunState::Holding,
            (RESUME_SENT, RunState::Holding) => RunState::Running,
            _ => st,
        }
    }

    /// `hold`: only while the machine moves a program.
    async fn hold(&self) -> Result<Reply, String> {
        match self.commanded_state() {
            RunState::Running if self.status.started.load(Ordering::Acquire) => {
                self.motion_command.store(HOLD_SENT, Ordering::Release);
                self.command(Command::Hold).await;
                Ok(Reply::Hold)
            }
            RunState::Holding => Err("hold: the machine is already holding".into()),
            st => Err(format!(
                "hold: nothing is moving (state {}{})",
                state_name(st),
                if st == RunState::Running {
                    ", not started"
                } else {
                    ""
                }
            )),
        }
    }

    /// `resume`: only while holding.
    async fn resume(&self) -> Result<Reply, String> {
        match self.commanded_state() {
            RunState::Holding => {
                self.motion_command.store(RESUME_SENT, Ordering::Release);
                self.command(Command::Resume).await;
                Ok(Reply::Resume)
            }
            st => Err(format!(
                "resume: the machine is not holding (state {})",
                state_name(st)
            )),
        }
    }

    /// Parses and checks one block and sends it through the program's
    /// pipeline; plans and queues what the pipeline releases (waits while
    /// the RT queue is full).
    ///
    /// A refused block leaves the service as it was: a program its claim
    /// made (or took over) is given back, so a client whose first block is
    /// refused keeps nobody out.
    async fn block(&self, b: &traces::InputBlock, peer: &Peer) -> Result<Reply, String> {
        let epoch = self.abort_epoch.load(Ordering::Acquire);
        let (program, undo) = {
            let mut p = self.lock_programs();
            let before = p.clone();
            let program = self.claim(&mut p, peer)?;
            let claimed = p.program != before.program || p.owner != before.owner;
            (program, claimed.then_some((before, p.blocks)))
        };
        let mut s = self.stream.lock().await;
        let stream_before = (s.program != program).then(|| StreamMark::take(&mut s));
        self.follow(&mut s, program);
        let r = self.accept_block(&mut s, b, program, epoch).await;
        if r.is_err()
            && let Some((before, blocks)) = undo
        {
            let mut p = self.lock_programs();
            // Unless something changed it meanwhile (an abort, a block
            // accepted), the claim is undone.
            if p.program == program && p.owner.as_ref() == Some(peer) && p.blocks == blocks {
                *p = before;
                if let Some(m) = stream_before {
                    m.restore(&mut s);
                }
            }
        }
        r
    }

    /// [`Self::block`] once claimed: the block through the program's
    /// pipeline, recorded, its segments queued.
    async fn accept_block(
        &self,
        s: &mut Stream,
        b: &traces::InputBlock,
        program: u32,
        epoch: u64,
    ) -> Result<Reply, String> {
        let first = s.next_id;
        // Every block of the program passes through its one pipeline.
        let pipeline = match s.pipeline.take() {
            Some(p) => p,
            None => traces::Pipeline::new(
                self.next_start(s),
                s.queued_tcp,
                first,
                crate::protocol::PIECE_CTRL,
                &s.interp,
            )
            .map_err(|e| format!("config: {e}"))?,
        };
        // The stage may fit NURBS over its whole window: off the runtime's thread.
        let block = b.clone();
        let (pipeline, expanded) = tokio::task::spawn_blocking(move || {
            let mut pipeline = pipeline;
            let r = crate::protocol::expand(&block, &mut pipeline);
            (pipeline, r)
        })
        .await
        .map_err(|e| format!("expanding block {}: {e}", s.index + 1))?;
        s.tail = Some(pipeline.tail());
        s.pipeline = Some(pipeline);
        let (pieces, info) = expanded?;
        // Recorded once accepted, before anything it released is queued: a
        // replay sends the recorded blocks through the same pipeline.
        self.record_block(s.index, b, info);
        s.index += 1;
        self.lock_programs().blocks += 1;
        self.blocks_accepted.fetch_add(1, Ordering::AcqRel);
        self.queue(s, program, epoch, pieces).await?;
        Ok(Reply::Block {
            index: s.index,
            first,
            last: s.next_id.wrapping_sub(1),
        })
    }

    /// Queues `pieces` (released by the program's pipeline, ids from
    /// `s.next_id`) for the planning thread; waits while its queue is full.
    /// A piece the look-ahead refuses is reported in the status
    /// (`last_refusal`); the pieces after it are refused too (they do not
    /// start where the queue ends).
    async fn queue(
        &self,
        s: &mut Stream,
        program: u32,
        epoch: u64,
        pieces: Vec<interp_core::Block>,
    ) -> Result<(), String> {
        let n = pieces.len();
        for (i, piece) in pieces.into_iter().enumerate() {
            let id = piece.id;
            let end = piece.end_position();
            let mut item = Segment {
                program,
                block: piece,
            };
            loop {
                if self.abort_epoch.load(Ordering::Acquire) != epoch {
                    return Err(format!(
                        "aborted while queueing segment {id} ({i} of {n} segments queued, flushed)"
                    ));
                }
                match s.segments.enqueue(item) {
                    Ok(()) => break,
                    Err(back) => {
                        item = back;
                        tokio::time::sleep(self.period).await;
                    }
                }
            }
            s.queued_to = [end.x, end.y, end.z];
            s.queued_tcp = piece.is_tcp();
            // (A piece the machine cannot follow is refused by the planner,
            // which reports it; the joints stay where the walk got to.)
            let _ = gcode::joints_after(&piece, s.machine.as_ref(), &mut s.queued_joints);
            s.next_id = id.wrapping_add(1);
        }
        Ok(())
    }

    /// `peer` left: a program it owns loses its owner (another connection
    /// may take it over); one still open holds the machine if it moves.
    async fn left(&self, peer: &Peer) {
        let open = {
            let mut s = self.lock_programs();
            if s.owner.as_ref() != Some(peer) {
                return;
            }
            s.owner = None;
            self.phase(&s) == Phase::Open
        };
        if open {
            eprintln!("interpd: {peer} left mid-program: feed hold if moving (resume to continue)");
            if self.status.run_state() == RunState::Running {
                self.command(Command::Hold).await;
            }
        }
    }
}

fn no_phase() -> Phase {
    Phase::None
}

/// Lower-case name of a phase, as errors print it.
pub fn phase_name(p: Phase) -> &'static str {
    match p {
        Phase::None => "none",
        Phase::Open => "open",
        Phase::Ended => "ended",
        Phase::Done => "done",
        Phase::Aborted => "aborted",
        Phase::Fault => "faulted",
    }
}

/// Outcome of reading one line.
enum ReadLine {
    Line(String),
    TooLong(usize),
    NotUtf8,
    Eof,
}

/// Reads one line of at most `MAX_LINE_BYTES`; a longer one is consumed up to
/// its newline and reported, so the connection goes on.
async fn read_line<R: AsyncBufRead + Unpin>(r: &mut R) -> std::io::Result<ReadLine> {
    let mut buf = Vec::new();
    let mut len = 0usize;
    loop {
        let avail = r.fill_buf().await?;
        if avail.is_empty() {
            if len == 0 {
                return Ok(ReadLine::Eof);
            }
            break;
        }
        let (take, done) = match avail.iter().position(|&c| c == b'\n') {
            Some(i) => (i + 1, true),
            None => (avail.len(), false),
        };
        if len + take <= MAX_LINE_BYTES + 1 {
            buf.extend_from_slice(&avail[..take]);
        }
        len += take;
        r.consume(take);
        if done {
            break;
        }
    }
    if len > MAX_LINE_BYTES + 1 {
        return Ok(ReadLine::TooLong(len));
    }
    while matches!(buf.last(), Some(b'\n' | b'\r')) {
        buf.pop();
    }
    match String::from_utf8(buf) {
        Ok(s) => Ok(ReadLine::Line(s)),
        Err(_) => Ok(ReadLine::NotUtf8),
    }
}

/// Serves one connection until it closes. A connection that sent blocks and
/// leaves without `end` (or `abort`) holds the machine: what was accepted stays queued.
pub async fn serve_connection<S: AsyncRead + AsyncWrite + Unpin>(
    ctl: Arc<Control>,
    io: S,
    name: String,
) {
    let peer = Peer {
        id: ctl.connections.fetch_add(1, Ordering::AcqRel) + 1,
        name,
    };
    let (rd, mut wr) = tokio::io::split(io);
    let mut rd = BufReader::new(rd);
    let mut authed = ctl.token.is_none();
    let mut line_no = 0u64;
    loop {
        let line = match read_line(&mut rd).await {
            Ok(ReadLine::Eof) | Err(_) => break,
            Ok(l) => l,
        };
        line_no += 1;
        let reply: Result<Reply, String> = match line {
            ReadLine::Eof => unreachable!(),
            ReadLine::TooLong(n) => Err(format!(
                "line of {n} bytes exceeds the limit of {MAX_LINE_BYTES} bytes"
            )),
            ReadLine::NotUtf8 => Err("line is not UTF-8".into()),
            ReadLine::Line(text) => match parse(&text) {
                Err(e) => Err(e),
                Ok(Request::Auth(t)) => {
                    if ctl.token.as_deref().is_none_or(|want| want == t) {
                        authed = true;
                        Ok(Reply::Auth)
                    } else {
                        Err("wrong token".into())
                    }
                }
                Ok(_) if !authed => {
                    let _ = wr
                        .write_all(
                            format!("err {line_no} authentication required (auth TOKEN)\n")
                                .as_bytes(),
                        )
                        .await;
                    break;
                }
                Ok(req) => handle(&ctl, req, &peer).await,
            },
        };
        let out = match reply {
            Ok(r) => r,
            Err(problem) => {
                ctl.errors.fetch_add(1, Ordering::AcqRel);
                Reply::Err {
                    line: line_no,
                    problem,
                }
            }
        };
        let out = format!("{out}\n");
        if wr.write_all(out.as_bytes()).await.is_err() {
            break;
        }
    }
    ctl.left(&peer).await;
}

async fn handle(ctl: &Control, req: Request, peer: &Peer) -> Result<Reply, String> {
    match req {
        Request::Nothing => Ok(Reply::Ok),
        Request::Auth(_) => unreachable!("handled by the caller"),
        Request::Block(b) => ctl.block(&b, peer).await,
        Request::Begin => ctl.begin(peer).await,
        Request::Start => ctl.start().await,
        Request::Hold => ctl.hold().await,
        Request::Resume => ctl.resume().await,
        Request::Override(x) => {
            if !(x >= 0.0 && x <= ctl.max_feed_override) {
                return Err(format!(
                    "override {x} outside 0 ..= {} (max-feed-override)",
                    ctl.max_feed_override
                ));
            }
            ctl.command(Command::Override(x)).await;
            Ok(Reply::Override(x))
        }
        Request::End => ctl.end(peer).await,
        Request::Abort => {
            ctl.abort().await?;
            Ok(Reply::Abort)
        }
        Request::Status => Ok(Reply::Status(Box::new(ctl.status().await))),
    }
}
