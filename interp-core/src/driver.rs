//! When to plan what: the planning side's decisions, in one place for every
//! caller of the look-ahead.
//!
//! The speed plan is made off the real-time path ([`BlockPlanner`], whose
//! solves take milliseconds) and committed on it ([`Executor::commit`]).
//! Besides planning each block, the planning side must plan the later parts
//! of a long block as the queue makes room, the end of the program, the move
//! from a resumed feed hold, a new feed override, and the rest of the queue
//! when the machine is about to run short of plan (the guard). [`Driver`]
//! takes those decisions from an [`ExecStatus`], a copy of what the executor
//! reports, and hands out one [`PlannedBlock`] at a time to commit.
//!
//! The single-threaded [`Interpolator`](crate::Interpolator) asks it between
//! ticks with the executor's status of that moment; the tests check that an
//! [`Executor`] and a `Driver` used that way on their own give the
//! interpolator's setpoints bit for bit. A driver given the same statuses in
//! the same order makes the same plans. While a plan it handed out is not
//! committed yet (`ExecStatus::commits` behind), it decides nothing more: the
//! status it has does not show that plan's effect.
//!
//! For the service (real-time thread and control plane), a status that lags
//! the machine would make plans that `simulate` does not make. The way there
//! keeps the decisions on ticks: the control plane runs its own copy of the
//! executor a lead of ticks ahead of the real-time thread (the executor is
//! deterministic, so the copy knows the machine's status at any future tick
//! exactly), asks the driver with the copy's status, and sends each plan and
//! each operator command with the tick it is for; the real-time thread
//! applies them at that tick. That is the same sequence `simulate` runs, and
//! a recording of it replays bit for bit.

use crate::config::{ConfigError, InterpConfig};
use crate::geom::Vec3;
use crate::interp::{Executor, MAX_PIECES, OverrideError, PushError, RunState, guard_distance};
use crate::path::Block;
use crate::prepare::{BlockPlanner, PlannedBlock, split_at_tangent_breaks};

/// What the planning side needs to know of the executor (see
/// [`Executor::status`]): small and `Copy`, so a real-time thread can
/// publish it every period.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ExecStatus {
    /// Where the machine is on its plan (arc length of the run, mm), and
    /// whether it rests there.
    pub plan_position: f64,
    /// The machine rests at `plan_position` (not moving and not about to).
    pub at_rest: bool,
    /// The machine's point (X Y Z) and arc length of the run.
    pub point: [f64; 3],
    /// Arc length of the run at the machine's point, mm.
    pub s: f64,
    /// Path speed, mm/s.
    pub v: f64,
    /// Planned distance ahead of the machine, mm.
    pub planned_ahead: f64,
    /// Free and used slots of the segment queue.
    pub free_segments: usize,
    /// Segments queued, the one being run included.
    pub queued_segments: usize,
    /// A feed hold or abort stop is running or done (the plan is left).
    pub stopping: bool,
    /// Holding at rest after a resume: waits for a plan from where it stands.
    pub needs_plan: bool,
    /// A feed hold's or abort's closed-form stop has not moved the machine
    /// yet: a plan to rest may replace it ([`Driver::plan_to_rest`]).
    pub stop_unplanned: bool,
    /// A feed hold is in force: given and not resumed.
    pub held: bool,
    /// The program's end was committed.
    pub finished: bool,
    /// An abort is braking.
    pub aborting: bool,
    /// Idle with nothing queued (after an abort the planner restarts here).
    pub idle_empty: bool,
    /// Plans offered to [`Executor::commit`] so far (accepted or not).
    pub commits: u64,
    /// Where the rotary joints A B C stand, degrees.
    pub rotary: [f64; 3],
}

/// The planning side of the look-ahead: a [`BlockPlanner`] and the decisions
/// of when to use it (see the module docs). About 5.2 MiB: box it.
#[derive(Clone, Debug)]
pub struct Driver {
    planner: BlockPlanner,
    plan: PlannedBlock,
    ovr: f64,
    /// The program's end was asked for (its plan may be due still).
    finish_requested: bool,
    /// The plan of the program's end was handed out (once per program).
    finish_sent: bool,
    /// Plans handed out (compared with `ExecStatus::commits`).
    emitted: u64,
    /// The last error of planning done on the caller's behalf.
    last_error: Option<PushError>,
    /// The last block pushed and the segments it needs: a block refused
    /// for room is offered again every tick, and finding a NURBS's tangent
    /// breaks measures it.
    split_memo: Option<(Block, usize)>,
    /// An abort was given (or seen braking) since the planner last started
    /// again: once the executor is idle and empty, the old queue is gone
    /// even where the machine stopped on its end.
    aborted: bool,
}

impl Driver {
    /// A driver for a queue that ends at `tail` (X Y Z), arc length `tail_s`
    /// of the run, with the machine at rest there.
    pub fn new(cfg: InterpConfig, tail: Vec3, tail_s: f64) -> Result<Self, ConfigError> {
        Ok(Driver {
            planner: BlockPlanner::new(cfg, tail, tail_s)?,
            plan: PlannedBlock::new(),
            ovr: 1.0,
            finish_requested: false,
            finish_sent: false,
            emitted: 0,
            last_error: None,
            split_memo: None,
            aborted: false,
        })
    }

    /// Set where the rotary axes stand at the end of the queue (where the
    /// machine starts), degrees.
    pub fn set_rotary(&mut self, abc: [f64; 3]) {
        self.planner.set_rotary(abc);
    }

    /// The planner.
    pub fn planner(&self) -> &BlockPlanner {
        &self.planner
    }
    /// The planner's look-ahead window, to set its diagnostics
    /// ([`crate::plan::Window::trace`]).
    pub fn window_mut(&mut self) -> &mut crate::plan::Window {
        self.planner.window_mut()
    }
    /// The feed override in force (1 = 100 %).
    pub fn feed_override(&self) -> f64 {
        self.ovr
    }
    /// The last error of planning done on the caller's behalf (the later
    /// parts of a long block, the end of the program, a resumed hold, an
    /// override); `None` when all went through.
    pub fn last_error(&self) -> Option<PushError> {
        self.last_error
    }
    /// A plan handed out is not committed yet (by `st`).
    fn in_flight(&self, st: &ExecStatus) -> bool {
        st.commits < self.emitted
    }

    /// Before each plan: where the machine is. (A plan is the program's
    /// end only when the caller marks it so.)
    fn sync(&mut self, st: &ExecStatus) {
        self.planner.set_machine(st.plan_position, st.at_rest);
        self.plan.finish = false;
    }

    fn emit(&mut self) -> &PlannedBlock {
        self.emitted += 1;
        &self.plan
    }

    /// The plan just made, to hand out; or, if planning failed, none (the
    /// error kept as [`Self::last_error`]).
    fn emit_planned<T>(&mut self, r: Result<T, PushError>) -> Option<&PlannedBlock> {
        match r {
            Ok(_) => Some(self.emit()),
            Err(e) => {
                self.last_error = Some(e);
                None
            }
        }
    }

    /// Plan a block to commit next. All or nothing: on error nothing was
    /// planned. A block longer than the look-ahead's part is accepted whole;
    /// its later parts come from [`Self::next`] as the machine moves on.
    pub fn push(&mut self, st: &ExecStatus, block: &Block) -> Result<&PlannedBlock, PushError> {
        if st.finished {
            return Err(PushError::Finished);
        }
        if self.finish_requested {
            if self.planner.has_pending() || !st.idle_empty {
                return Err(PushError::Finished);
            }
            // Finished, then aborted: a new program may follow.
            self.finish_requested = false;
            self.finish_sent = false;
        }
        if st.aborting {
            self.aborted = true;
            return Err(PushError::Aborting);
        }
        if self.in_flight(st) {
            return Err(PushError::Pending);
        }
        if st.idle_empty {
            self.resync_to(st);
            // The rotary axes stand where the machine has them (at the
            // start, after an abort): the next block's joints start there.
            self.planner.set_rotary(st.rotary);
        }
        if self.planner.has_pending() {
            return Err(PushError::Pending);
        }
        // Room for its segments, checked before planning.
        let needed = self.segments_needed(block)?;
        if needed > st.free_segments {
            return Err(PushError::Full {
                needed,
                free: st.free_segments,
            });
        }
        self.sync(st);
        self.planner.plan(block, &mut self.plan)?;
        Ok(self.emit())
    }

    /// After an abort (the executor idle with nothing queued), the planner
    /// starts again where the machine stands: the old queue's long block,
    /// hold's rest and plans are forgotten. (An abort that stops exactly on
    /// the end of what was queued, as a soft machine's long stop does,
    /// leaves the planner's tail where the machine stands: the rest of a
    /// long block ran on after it.)
    fn resync_to(&mut self, st: &ExecStatus) {
        let p = Vec3::new(st.point[0], st.point[1], st.point[2]);
        if self.aborted || self.planner.tail_s() != st.s || self.planner.tail() != p {
            self.planner.resync(p, st.s);
        }
        self.aborted = false;
    }

    /// How many queue segments `block` takes (memoised: a block refused for
    /// room is offered again every tick).
    fn segments_needed(&mut self, block: &Block) -> Result<usize, PushError> {
        if let Some((b, n)) = &self.split_memo
            && b == block
        {
            return Ok(*n);
        }
        let cfg = self.planner.config();
        let mut paths = [block.path; MAX_PIECES];
        let mut singular = [false; MAX_PIECES + 1];
        let n = split_at_tangent_breaks(
            &block.path,
            &mut paths,
            cfg.tangent_tolerance,
            cfg.chord_tolerance,
            &mut singular,
        )?;
        self.split_memo = Some((*block, n));
        Ok(n)
    }

    /// The program ends with what is pushed: its last plan comes from
    /// [`Self::next`] (once the parts of a long block are planned).
    pub fn finish(&mut self) {
        self.finish_requested = true;
    }

    /// Set the feed override (1 = 100 %, up to `max_feed_override`). It
    /// scales the programmed feed and the MRR law, never the machine's
    /// limits. Returns the plan from the machine on to commit, if one is due
    /// now (idle, holding or stopping: the next plan takes it).
    pub fn set_feed_override(
        &mut self,
        st: &ExecStatus,
        value: f64,
    ) -> Result<Option<&PlannedBlock>, OverrideError> {
        if !(value >= 0.0 && value <= self.planner.config().max_feed_override) {
            return Err(OverrideError::OutOfRange);
        }
        self.ovr = value;
        if st.queued_segments == 0 || st.stopping {
            self.planner.set_feed_override(value);
            return Ok(None);
        }
        self.sync(st);
        let r = self.planner.replan(value, &mut self.plan);
        Ok(self.emit_planned(r))
    }

    /// Plan a feed hold or an abort given to the executor whose status is
    /// `st` (after [`Executor::feed_hold`] or [`Executor::abort`], before
    /// its next tick): the plan to commit, which brings the machine to rest
    /// with every limit of the look-ahead held and replaces the executor's
    /// closed-form stop ([`BlockPlanner::hold`]). `None` when none is to be
    /// planned, or it could not be (the closed-form stop then brakes).
    pub fn plan_to_rest(&mut self, st: &ExecStatus) -> Option<&PlannedBlock> {
        if !st.stop_unplanned || st.queued_segments == 0 || self.in_flight(st) {
            return None;
        }
        self.sync(st);
        let r = self.planner.hold(&mut self.plan);
        self.emit_planned(r)
    }

    /// The next plan due on the planning side's own account, if any (call
    /// until `None`, committing each): the next part of a long block when the
    /// queue has room, the program's end, the move from a resumed hold, and
    /// the guard (the machine is about to run short of plan while more is
    /// queued: plan to the end of what is queued).
    pub fn next(&mut self, st: &ExecStatus) -> Option<&PlannedBlock> {
        self.due(st, false)
    }

    /// The next part of a long block, if one is due (call until `None`,
    /// committing each): what must be planned before another block is pushed.
    pub fn next_part(&mut self, st: &ExecStatus) -> Option<&PlannedBlock> {
        self.due(st, true)
    }

    fn due(&mut self, st: &ExecStatus, parts_only: bool) -> Option<&PlannedBlock> {
        // Nothing more goes in while an abort brakes.
        self.aborted |= st.aborting;
        if self.in_flight(st) || st.aborting {
            return None;
        }
        if st.idle_empty {
            // After an abort: nothing of the old queue is to be planned.
            self.resync_to(st);
        }
        // A hold's plan ends at its rest: nothing is planned while the
        // machine brakes to it (so the hold's tick plans nothing big), the
        // rest of the look-ahead once it is there. Resumed while it brakes,
        // the speed is planned again through the rest point (once).
        if let Some(rest) = self.planner.hold_rest() {
            // (At the plan's end, `x0 + h` may fall an ulp short of it.)
            let at_end = st.v == 0.0 && st.planned_ahead <= 0.0;
            if st.plan_position < rest && !at_end {
                if st.held {
                    return None;
                }
                self.sync(st);
                let r = self.planner.resume_hold(&mut self.plan);
                // (`Ok(false)`: not planned through; it brakes on.)
                return if r == Ok(false) {
                    None
                } else {
                    self.emit_planned(r)
                };
            }
            self.sync(st);
            let r = self.planner.plan_after_hold(&mut self.plan);
            return self.emit_planned(r);
        }
        let pending = self.planner.has_pending();
        // Room for the rest of the block's segments (a queue shorter than
        // the most a block can have still takes a line's next part).
        let room = match self.planner.pending().copied() {
            Some(b) => self
                .segments_needed(&b)
                .is_ok_and(|n| n <= st.free_segments),
            None => false,
        };
        if room {
            self.sync(st);
            match self.planner.plan_pending(&mut self.plan) {
                Ok(()) => return Some(self.emit()),
                // Not yet: the look-ahead reaches far enough for now.
                Err(e) => self.last_error = Some(e),
            }
        }
        if parts_only {
            return None;
        }
        // A resumed hold waits for nothing: the machine rests until it is
        // planned again.
        if st.needs_plan {
            self.sync(st);
            let r = self.planner.replan(self.ovr, &mut self.plan);
            return self.emit_planned(r);
        }
        // A crawl, the look-ahead's last resort after a failed solve, is
        // planned again once the machine gets to it.
        if self.planner.take_crawl_retry(st.plan_position) {
            self.sync(st);
            let r = self.planner.replan(self.ovr, &mut self.plan);
            return self.emit_planned(r);
        }
        // The end and the guard wait for the rest of a long block.
        if pending {
            return None;
        }
        if self.finish_requested && !self.finish_sent && !st.finished {
            self.sync(st);
            if let Err(e) = self.planner.finish(&mut self.plan) {
                // The end is committed all the same; the machine rests where
                // its plan ends.
                self.last_error = Some(e);
                self.planner.speed_only(&mut self.plan);
            }
            self.plan.finish = true;
            self.finish_sent = true;
            return Some(self.emit());
        }
        if self.planner.has_unplanned()
            && !st.stopping
            && st.planned_ahead < guard_distance(self.planner.config(), st.v)
        {
            self.sync(st);
            let r = self.planner.plan_ahead(&mut self.plan);
            return self.emit_planned(r);
        }
        None
    }

    /// Commit everything due into `exec` (once a tick, before it), having
    /// forgotten what the machine left behind since the last tick
    /// ([`BlockPlanner::release_behind`]). Every plan offered to `exec` is
    /// shown to `sink` first (see [`PlanSink`]).
    pub fn drive<const Q: usize>(&mut self, exec: &mut Executor<Q>, sink: PlanSink<'_>) {
        self.planner.release_behind(exec.plan_position().0);
        self.drive_due(exec, false, sink);
    }

    /// Queue `block` into `exec`: the due parts of a long block first, then
    /// its plan (see [`Self::push`]). All or nothing for `block`.
    pub fn push_into<const Q: usize>(
        &mut self,
        exec: &mut Executor<Q>,
        block: &Block,
        sink: PlanSink<'_>,
    ) -> Result<(), PushError> {
        self.parts_into(exec, sink);
        let plan = self.push(&exec.status(), block)?;
        sink(plan);
        exec.commit(plan)
    }

    /// Commit the due parts of a long block into `exec` (see
    /// [`Self::next_part`]): what [`Self::push_into`] plans before its block.
    pub fn parts_into<const Q: usize>(&mut self, exec: &mut Executor<Q>, sink: PlanSink<'_>) {
        if !exec.status().finished {
            self.drive_due(exec, true, sink);
        }
    }

    /// The program ends with what is pushed into `exec` (see [`Self::finish`]).
    pub fn finish_into<const Q: usize>(&mut self, exec: &mut Executor<Q>, sink: PlanSink<'_>) {
        self.finish();
        self.drive_due(exec, false, sink);
    }

    /// Leave a feed hold in `exec`: the speed is planned again, through the
    /// hold's rest point while the machine still brakes fast
    /// ([`BlockPlanner::resume_hold`]), else from where it rests.
    pub fn resume_into<const Q: usize>(&mut self, exec: &mut Executor<Q>, sink: PlanSink<'_>) {
        exec.resume();
        self.drive_due(exec, false, sink);
    }

    /// Feed hold in `exec` ([`Executor::feed_hold`]), planned through the
    /// look-ahead ([`Self::plan_to_rest`]).
    pub fn feed_hold_into<const Q: usize>(&mut self, exec: &mut Executor<Q>, sink: PlanSink<'_>) {
        exec.feed_hold();
        self.plan_stop_into(exec, sink);
    }

    /// Abort in `exec` ([`Executor::abort`]): the machine comes to rest as
    /// under a feed hold ([`Self::plan_to_rest`]), then the queue is flushed.
    pub fn abort_into<const Q: usize>(&mut self, exec: &mut Executor<Q>, sink: PlanSink<'_>) {
        exec.abort();
        self.aborted = true;
        self.plan_stop_into(exec, sink);
    }

    fn plan_stop_into<const Q: usize>(&mut self, exec: &mut Executor<Q>, sink: PlanSink<'_>) {
        if let Some(plan) = self.plan_to_rest(&exec.status()) {
            sink(plan);
            if let Err(e) = exec.commit(plan) {
                self.last_error = Some(e);
            }
        }
    }

    /// Set the feed override (see [`Self::set_feed_override`]) and commit
    /// the plan it makes into `exec`.
    pub fn set_feed_override_into<const Q: usize>(
        &mut self,
        exec: &mut Executor<Q>,
        value: f64,
        sink: PlanSink<'_>,
    ) -> Result<(), OverrideError> {
        let st = exec.status();
        if let Some(plan) = self.set_feed_override(&st, value)? {
            sink(plan);
            let _ = exec.commit(plan);
        }
        Ok(())
    }

    fn drive_due<const Q: usize>(
        &mut self,
        exec: &mut Executor<Q>,
        parts_only: bool,
        sink: PlanSink<'_>,
    ) {
        while let Some(plan) = self.due(&exec.status(), parts_only) {
            sink(plan);
            if let Err(e) = exec.commit(plan) {
                self.last_error = Some(e);
                break;
            }
        }
    }
}

/// Shown every plan a [`Driver`] offers its executor, in order, before the
/// executor gets it. An executor elsewhere (the service's real-time thread)
/// that is offered the same plans and commands at the same ticks gives the
/// same setpoints bit for bit. `&mut |_| {}` when there is no such copy.
pub type PlanSink<'a> = &'a mut dyn FnMut(&PlannedBlock);

impl<const Q: usize> Executor<Q> {
    /// What the planning side needs to know (see [`ExecStatus`]).
    pub fn status(&self) -> ExecStatus {
        let (plan_position, at_rest) = self.plan_position();
        let (p, s) = self.position();
        ExecStatus {
            plan_position,
            at_rest,
            point: [p.x, p.y, p.z],
            s,
            v: self.speed(),
            planned_ahead: self.planned_ahead(),
            free_segments: self.free_segments(),
            queued_segments: self.queued_segments(),
            stopping: self.is_stopping(),
            needs_plan: self.needs_plan(),
            stop_unplanned: self.stop_unplanned(),
            held: self.is_held(),
            finished: self.is_finished(),
            aborting: self.is_aborting(),
            idle_empty: self.state() == RunState::Idle && self.queued_segments() == 0,
            commits: self.stats().commits,
            rotary: {
                let q = self.axes();
                [q[3], q[4], q[5]]
            },
        }
    }
}
