//! The planning thread: decides, tick by tick, everything the RT thread's
//! interpolator is given, a lead of ticks before the RT thread runs them.
//!
//! The look-ahead's plans depend on where the machine is when they are
//! made (each re-solve starts a braking distance ahead of it) and take
//! milliseconds, so they cannot be made on the RT thread, and a plan made
//! from a status that lags the machine would differ from the one
//! `simulate` makes. This thread therefore runs its own copy of the
//! executor (`interp_core::Executor`, deterministic) with the
//! `interp_core::Driver` that plans for it, exactly as
//! `interp_core::Interpolator` does in `simulate`: segments pushed while
//! they fit, the program's end, operator commands, the driver's own plans,
//! then a tick. Every plan and command it gives its copy goes to the RT
//! thread as a [`Step`] tagged with the tick it precedes; the RT thread
//! applies each at that tick and ticks only once this thread has decided
//! the tick. Both executors then get the same plans and commands at the
//! same ticks and give the same setpoints bit for bit, and the recorded
//! steps replay as `simulate` runs.
//!
//! The copy runs at most [`RtOptions::lead_ticks`](crate::service::rt::RtOptions)
//! ahead of the RT thread: a command (hold, override, abort) takes effect
//! that many periods after it is given (a hold, resume or override that
//! comes while the planning is behind waits until it has its lead again:
//! `Deferred`); the RT thread never waits for a plan while this thread
//! keeps within its lead (a wait is counted as `planner_late`).

use core::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use heapless::spsc::{Consumer, Producer};
use interp_core::interp::PushError;
use interp_core::{PlannedBlock, RunState};
use interp_run::{Op, Run};

use crate::service::rt::{Applied, Command, PushFailure, RtStatus, Segment};

/// One thing for the RT thread to do before its tick number `at + 1`.
#[derive(Debug)]
pub struct Step {
    /// Ticks the executor has done when it applies this.
    pub at: u64,
    /// The program it belongs to.
    pub program: u32,
    /// `start` was given for that program.
    pub started: bool,
    /// The program's end was applied.
    pub finished: bool,
    /// What to give the executor (`interp_run::Op::apply`; a plan's buffer
    /// goes back through the spent queue); `None`: a record or a status
    /// change only.
    pub op: Option<Op>,
    /// The op is an operator's abort (counted in `RtStatus::aborts`), not
    /// the one that leaves `done` for a new program.
    pub operator: bool,
    /// What a recording notes (replayed at the same tick).
    pub record: Option<Applied>,
}

/// The planning thread's state (see the module docs).
pub(crate) struct Sequencer {
    /// The executor copy and its driver, recording every step given to the copy.
    pub run: Box<Run>,
    pub segments: Consumer<'static, Segment>,
    pub commands: Consumer<'static, Command>,
    pub failures: Producer<'static, PushFailure>,
    pub steps: Producer<'static, Step>,
    pub spent: Consumer<'static, Box<PlannedBlock>>,
    pub status: Arc<RtStatus>,
    /// Ticks this thread has decided (the RT thread may tick up to it).
    pub decided: Arc<AtomicU64>,
    pub stop: Arc<AtomicBool>,
    pub lead_ticks: u64,
    pub period: Duration,
    pub autostart: bool,
    pub started: bool,
    /// The program of the last segment pushed (0: none yet).
    pub program: u32,
    /// The last program `start` was given for (it may not be pushed yet).
    pub start_for: u32,
    /// An abort is bringing the machine to rest (ticks go on without `start`).
    pub aborting: bool,
    pub finished: bool,
    /// `end` of this program was given.
    pub end_requested: Option<u32>,
    /// A segment that did not fit yet.
    pub pending: Option<Segment>,
    /// Holds, resumes and overrides not applied yet (see [`Deferred`]).
    pub deferred: Deferred,
}

/// The operator's commands that plan the speed again (hold, resume,
/// override: a re-solve of the look-ahead each, 10–40 ms in `serve`),
/// waiting for the planning thread to be its lead ahead of the RT thread
/// again (less a quarter) before each one, so that none starts with less
/// than that to plan in. Applied as they came, a burst (a hold, its resume
/// and two overrides within one lead) outlasted the lead, and the RT thread
/// waited for the planner: its last point published again, a stop of the
/// machine for a period.
///
/// What is still waiting when the next command comes is merged with it,
/// as the machine would end up after both: a hold and then a resume (or a
/// resume and then a hold) cancel out, the machine going on as it was (it
/// never held, or stays held); of several overrides the last value counts.
/// So a backlog never grows, however fast commands come.
#[derive(Debug, Default)]
pub(crate) struct Deferred {
    /// A hold or a resume.
    motion: Option<Command>,
    /// The override to set.
    feed_override: Option<f64>,
    /// When the oldest of them came.
    since: Option<Instant>,
    /// Commands merged away (cancelled or superseded), for the status.
    pub merged: u64,
}

impl Deferred {
    /// Adds `c` (a hold, resume or override), merged with what waits.
    fn add(&mut self, c: Command) {
        match (c, self.motion) {
            (Command::Override(x), _) => {
                if self.feed_override.replace(x).is_some() {
                    self.merged += 1;
                }
            }
            (Command::Hold, Some(Command::Resume)) | (Command::Resume, Some(Command::Hold)) => {
                self.motion = None;
                self.merged += 2;
            }
            (Command::Hold | Command::Resume, Some(_)) => self.merged += 1,
            (Command::Hold | Command::Resume, None) => self.motion = Some(c),
            _ => unreachable!("only holds, resumes and overrides wait"),
        }
        if self.is_empty() {
            self.since = None;
        } else {
            self.since.get_or_insert_with(Instant::now);
        }
    }

    fn is_empty(&self) -> bool {
        self.motion.is_none() && self.feed_override.is_none()
    }

    /// Drops a waiting hold or resume (an abort came).
    fn drop_motion(&mut self) {
        if self.motion.take().is_some() {
            self.merged += 1;
        }
        if self.is_empty() {
            self.since = None;
        }
    }

    /// The next command to apply, in the order that plans least: a hold
    /// before an override, an override before a resume (set while the
    /// machine holds or brakes to a hold, an override plans nothing: the
    /// next plan takes it).
    fn take(&mut self) -> Option<Command> {
        let c = match self.motion {
            Some(Command::Resume) if self.feed_override.is_some() => {
                self.feed_override.take().map(Command::Override)
            }
            _ => self
                .motion
                .take()
                .or_else(|| self.feed_override.take().map(Command::Override)),
        };
        if self.is_empty() {
            self.since = None;
        }
        c
    }
}

impl Sequencer {
    /// Runs until `stop`.
    pub fn run(mut self) {
        while !self.stop.load(Ordering::Acquire) {
            self.feed();
            self.end_if_due();
            self.apply_commands();
            self.apply_deferred();
            let moving = self.started || self.aborting;
            let rt_ticks = self.status.ticks.load(Ordering::Acquire);
            if moving && self.ticks() < rt_ticks + self.lead_ticks {
                self.tick();
            } else {
                std::thread::sleep(self.period / 4);
            }
        }
    }

    fn ticks(&self) -> u64 {
        self.run.ticks()
    }

    /// Sends a step for the current tick (waits while the RT thread's queue
    /// is full: it drains it as it reaches the steps' ticks).
    fn send(&mut self, op: Option<Op>, operator: bool, record: Option<Applied>) {
        self.send_at(self.ticks(), op, operator, record);
    }

    /// [`Self::send`] for the tick `at`.
    fn send_at(&mut self, at: u64, op: Option<Op>, operator: bool, record: Option<Applied>) {
        let mut step = Step {
            at,
            program: self.program,
            started: self.started,
            finished: self.finished,
            op,
            operator,
            record,
        };
        loop {
            match self.steps.enqueue(step) {
                Ok(()) => return,
                Err(back) => {
                    if self.stop.load(Ordering::Acquire) {
                        return;
                    }
                    step = back;
                    std::thread::sleep(self.period / 4);
                }
            }
        }
    }

    /// Sends the steps the copy was given since the last call, in order;
    /// `record` and `operator` go with the first one (a hold, resume or
    /// abort comes before the plans it leads to). Plan buffers the RT thread
    /// has handed back are reused first.
    fn flush(&mut self, record: Option<Applied>, operator: bool) {
        let (mut record, mut operator) = (record, operator);
        for step in self.run.take_steps() {
            self.send_at(step.at, Some(step.op), operator, record.take());
            operator = false;
        }
        if record.is_some() {
            self.send(None, false, record);
        }
        while let Some(b) = self.spent.dequeue() {
            self.run.recycle(b);
        }
        // Why the machine will stop where it does, for the status.
        let plan = self.run.driver().planner().window().totals;
        let s = &self.status;
        s.junction_stops
            .store(self.run.stats().junctions_stopped, Ordering::Release);
        s.look_ahead_added_stops
            .store(plan.added_stops(), Ordering::Release);
    }

    /// Pushes the segments that fit, in order.
    fn feed(&mut self) {
        loop {
            if self.pending.is_none() {
                self.pending = self.segments.dequeue();
            }
            let Some(seg) = self.pending.take() else {
                return;
            };
            if !self.ready_for(&seg) {
                self.pending = Some(seg);
                return;
            }
            let r = self.run.push(&seg.block);
            // A push that must wait may have planned the due parts of a
            // long block before it: recorded, so that replay plans them at
            // the same point among this tick's commands.
            let parts = r.as_ref().is_err_and(|e| e.is_wait()) && self.run.has_steps();
            self.flush(parts.then_some(Applied::Parts), false);
            match r {
                Ok(()) => {
                    self.send(None, false, Some(Applied::Commit(seg.block.id)));
                    self.status.blocks_pushed.fetch_add(1, Ordering::AcqRel);
                }
                Err(e) if e.is_wait() => {
                    // After the next tick.
                    self.pending = Some(seg);
                    return;
                }
                // Cannot happen for a segment of the running program (`end`
                // waits for its segments); kept rather than lost.
                Err(PushError::Aborting | PushError::Finished) => {
                    self.pending = Some(seg);
                    return;
                }
                Err(error) => {
                    self.status.blocks_refused.fetch_add(1, Ordering::AcqRel);
                    let _ = self.failures.enqueue(PushFailure {
                        id: seg.block.id,
                        error,
                    });
                }
            }
        }
    }

    /// Whether `seg` may be pushed now: a segment of the running program
    /// always; the first one of the next program once the last one is over
    /// (`done`, or at rest after an abort), leaving `done` for it.
    fn ready_for(&mut self, seg: &Segment) -> bool {
        if seg.program == self.program {
            return true;
        }
        match self.run.state() {
            RunState::Done => {
                // A new program after a finished one: leave Done.
                self.run.abort();
                self.finished = false;
                self.flush(Some(Applied::NextProgram), false);
            }
            RunState::Idle if !self.aborting => {}
            _ => return false,
        }
        self.program = seg.program;
        self.finished = false;
        self.started = self.autostart || self.start_for == seg.program;
        self.send(None, false, None);
        true
    }

    /// `end`: once every segment of the program is pushed.
    fn end_if_due(&mut self) {
        let ours = |s: Option<&Segment>, p: u32| s.is_some_and(|s| s.program == p);
        if let Some(p) = self.end_requested
            && p == self.program
            && !ours(self.pending.as_ref(), p)
            && !ours(self.segments.peek(), p)
        {
            self.end_requested = None;
            self.finished = true;
            self.run.finish();
            self.flush(None, false);
            self.send(None, false, Some(Applied::Finish));
        }
    }

    /// Applies the deferred commands (see [`Deferred`]), each once the copy
    /// is its lead ahead of the RT thread (less a quarter, the RT thread
    /// ticking on meanwhile), or it has waited a lead already (the planning
    /// is behind on its own: waiting longer would not help), or nothing
    /// moves.
    fn apply_deferred(&mut self) {
        while let Some(since) = self.deferred.since {
            let moving = self.started || self.aborting;
            let rt_ticks = self.status.ticks.load(Ordering::Acquire);
            let lead_full = self.ticks() + self.lead_ticks / 4 >= rt_ticks + self.lead_ticks;
            let waited = since.elapsed() >= self.period * self.lead_ticks as u32;
            if moving && !lead_full && !waited {
                return;
            }
            self.apply_one_deferred();
        }
    }

    fn apply_one_deferred(&mut self) {
        match self.deferred.take() {
            Some(Command::Hold) if self.started && self.run.state() == RunState::Running => {
                self.run.feed_hold();
                self.flush(Some(Applied::Hold), false);
            }
            Some(Command::Resume) if self.run.state() == RunState::Holding => {
                self.run.resume();
                self.flush(Some(Applied::Resume), false);
            }
            Some(Command::Override(x)) => {
                // The control plane checked the range; a refusal leaves the old value.
                let ok = self.run.set_feed_override(x).is_ok();
                self.flush(None, false);
                if ok {
                    self.status
                        .feed_override
                        .store(x.to_bits(), Ordering::Release);
                    self.send(None, false, Some(Applied::Override(x)));
                }
            }
            _ => {}
        }
        self.status
            .commands_merged
            .store(self.deferred.merged, Ordering::Release);
    }

    fn apply_commands(&mut self) {
        while let Some(c) = self.commands.dequeue() {
            match c {
                Command::Start(p) => {
                    self.start_for = p;
                    if p == self.program {
                        self.started = true;
                        self.send(None, false, None);
                    }
                }
                // Only motion is held: a hold while nothing moves is not
                // remembered for the next program (judged when applied).
                Command::Hold | Command::Resume | Command::Override(_) => self.deferred.add(c),
                Command::End(p) => self.end_requested = Some(p),
                Command::Abort => {
                    // A hold or resume waiting is moot; an override stays set.
                    self.deferred.drop_motion();
                    self.run.abort();
                    self.flush(Some(Applied::Abort), true);
                    self.pending = None;
                    while self.segments.dequeue().is_some() {}
                    self.end_requested = None;
                    // Tick until at rest; `start` is needed again after that.
                    self.aborting = true;
                }
            }
        }
    }

    /// Plans what is due, ticks the copy, and lets the RT thread tick too.
    fn tick(&mut self) {
        // The plans due are recorded for this tick and sent before it is
        // decided.
        let sp = self.run.tick();
        self.flush(None, false);
        self.decided.store(self.ticks(), Ordering::Release);
        if self.aborting && sp.state != RunState::Stopping {
            self.aborting = false;
            self.started = self.autostart;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn drain(d: &mut Deferred) -> Vec<String> {
        std::iter::from_fn(|| d.take())
            .map(|c| format!("{c:?}"))
            .collect()
    }

    #[test]
    fn a_hold_and_its_resume_waiting_together_cancel_out() {
        for pair in [
            [Command::Hold, Command::Resume],
            [Command::Resume, Command::Hold],
        ] {
            let mut d = Deferred::default();
            for c in pair {
                d.add(c);
            }
            assert!(d.since.is_none(), "{pair:?}: nothing waits");
            assert_eq!(drain(&mut d), Vec::<String>::new(), "{pair:?}");
            assert_eq!(d.merged, 2);
        }
    }

    #[test]
    fn of_several_overrides_waiting_the_last_one_is_applied() {
        let mut d = Deferred::default();
        for x in [0.5, 1.2, 0.8] {
            d.add(Command::Override(x));
        }
        assert_eq!(drain(&mut d), ["Override(0.8)"]);
        assert_eq!(d.merged, 2);
        assert!(d.since.is_none());
    }

    #[test]
    fn an_override_goes_after_a_hold_and_before_a_resume() {
        // Set while the machine brakes to a hold or rests in it, an override
        // plans nothing; the hold's and the resume's own plans take it.
        let mut d = Deferred::default();
        d.add(Command::Override(0.6));
        d.add(Command::Hold);
        assert_eq!(drain(&mut d), ["Hold", "Override(0.6)"]);
        d.add(Command::Resume);
        d.add(Command::Override(1.5));
        assert_eq!(drain(&mut d), ["Override(1.5)", "Resume"]);
        assert_eq!(d.merged, 0);
    }

    #[test]
    fn an_abort_drops_a_waiting_hold_and_keeps_the_override() {
        let mut d = Deferred::default();
        d.add(Command::Hold);
        d.add(Command::Override(0.7));
        d.drop_motion();
        assert!(d.since.is_some());
        assert_eq!(drain(&mut d), ["Override(0.7)"]);
        d.add(Command::Resume);
        d.drop_motion();
        assert!(d.since.is_none(), "nothing waits");
    }
}
