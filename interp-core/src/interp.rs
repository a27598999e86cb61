//! The fixed-period interpolator: `tick()` turns the queued segments and
//! their planned speed into one setpoint per period. No allocation, lock or
//! system call in [`Executor::tick`].
//!
//! Two halves:
//!
//! - [`Executor`] (real time): the segment queue, a ring of pieces of the
//!   planned speed spline `v(s)² = S(s)` ([`crate::spline`]), and the tick.
//!   Each tick moves the arc length along the spline by exactly one period
//!   (closed form, [`crate::spline::advance`]); the parameter update
//!   ([`ParamUpdate`]) then finds the next `u` whose chord from the last point
//!   reaches that arc length, carrying the rest of a step across segment
//!   ends in the same tick. Feed hold and abort leave the plan for the
//!   fastest jerk-limited stop ([`crate::stop::Stop`]).
//! - [`BlockPlanner`] (non-real-time): law sampling, junctions and the
//!   speed's linear program ([`crate::plan`]); it hands the executor
//!   [`PlannedBlock`]s.
//!
//! [`Interpolator`] puts both in one value for single-threaded use
//! (`simulate`, tests, benches): `push` is plan then commit.

use heapless::Deque;

use crate::config::{ConfigError, InterpConfig, ParamUpdate};
use crate::driver::Driver;
use crate::fiveaxis::{JointError, Orientation};
use crate::geom::{Curve, Vec3};
use crate::kinematics::{Joints, Machine};
use crate::path::{Block, Path, SplitAtError};
use crate::prepare::{BlockPlanner, PlannedBlock, Segment};
use crate::spline::{self, Piece};
use crate::stop::Stop;

/// Default segment-queue capacity.
pub const DEFAULT_QUEUE: usize = 64;

/// Pieces of the speed spline the executor holds (from the machine to the
/// end of the plan): room for everything the planner's window can plan, and
/// the pieces the machine is still on.
pub const RING: usize = crate::plan::WINDOW + 64;

/// At rest this close to a stop (mm), the point is set on the stop exactly:
/// arc length and parameter reach the end together only up to round-off.
pub const END_SNAP_TOL: f64 = 1e-9;

/// Arc left in a segment, in chords of the tick's step, within which its end
/// point counts as reachable by the chord (π/2 is a half circle's arc per chord).
const CHORD_ARC_REACH: f64 = 2.0;

/// Largest gap accepted between one block's end and the next block's start, mm.
pub const JOIN_TOLERANCE: f64 = 1e-6;

/// What the interpolator is doing.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[repr(u8)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum RunState {
    /// At rest with nothing (more) queued; the program is not marked finished.
    #[default]
    Idle = 0,
    /// Moving along the path, or waiting on the path for more blocks.
    Running = 1,
    /// Feed hold: decelerating to rest on the path, or at rest until resumed.
    Holding = 2,
    /// Abort: decelerating to rest on the path; then the queue is flushed.
    Stopping = 3,
    /// The program was marked finished and its last point reached.
    Done = 4,
    /// A numerical fault stopped motion.
    Fault = 5,
}

/// One output sample. `#[repr(C)]` so it can be shared with other processes as is.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
#[repr(C)]
pub struct Setpoint {
    /// Tick count since start, from 1, gapless.
    pub seq: u64,
    /// `seq · Ts`, s.
    pub time: f64,
    /// X Y Z A B C (mm; rotary axes in degrees).
    pub axes: [f64; 6],
    /// Commanded path speed over the tick that ended here, `Δ/Ts`, mm/s;
    /// deg/s in a turn in place, whose path is the turn's measure in degrees.
    pub feed: f64,
    /// Path parameter of the block at this point.
    pub u: f64,
    /// Arc length of the run at this point, mm (a turn in place adds its
    /// measure, degrees).
    pub s: f64,
    /// Id of the block the point is on (0 before any block).
    pub block_id: u32,
    /// State after this tick.
    pub state: RunState,
}

/// Why a block was not queued. Nothing was queued when this is returned.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PushError {
    /// The segment queue lacks room: `needed` segments, `free` left.
    Full {
        /// Segments this block needs.
        needed: usize,
        /// Segments free.
        free: usize,
    },
    /// The look-ahead (window or speed ring) reaches far enough ahead for
    /// now: push again once the machine has moved on.
    ProfileFull,
    /// The block does not start where the previous one ends (gap in mm).
    Discontinuous {
        /// Distance between the previous end and this start, mm.
        gap: f64,
    },
    /// The programmed feed is not a positive finite number.
    Feed,
    /// The path has no length.
    Empty,
    /// `finish()` was already called.
    Finished,
    /// Splitting the path at a tangent break failed.
    Split(SplitAtError),
    /// A NURBS with more tangent breaks (C0 corners) than `MAX_PIECES − 1`.
    TooManyCorners,
    /// An abort is under way; push again once the interpolator is idle.
    Aborting,
    /// The plan was made against another end of the queue, or for a part of
    /// the speed the machine has reached already: plan it again.
    Stale,
    /// The rest of a long block is still being planned: plan it
    /// ([`BlockPlanner::plan_pending`]) before the next block.
    Pending,
    /// The speed's linear program failed even with a rest point at the old
    /// end of the queue (a bug: please report the program).
    Schedule,
    /// A five-axis block's joints cannot be had along it (no machine for
    /// tool-centre-point control, or a pose out of the rotary ranges).
    Kinematics(JointError),
}

impl PushError {
    /// Refused for now, not for what the block is: the queue, the
    /// look-ahead window or the parts of a long block before it need the
    /// machine to move on. Offer the block again after a tick.
    pub fn is_wait(&self) -> bool {
        matches!(
            self,
            PushError::Full { .. } | PushError::ProfileFull | PushError::Pending
        )
    }
}

impl core::fmt::Display for PushError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            PushError::Full { needed, free } => {
                write!(f, "queue full: block needs {needed} segments, {free} free")
            }
            PushError::ProfileFull => write!(f, "look-ahead full"),
            PushError::Discontinuous { gap } => {
                write!(f, "block does not start at the previous end (gap {gap} mm)")
            }
            PushError::Feed => write!(f, "feed must be a positive finite number"),
            PushError::Empty => write!(f, "path of zero length"),
            PushError::Finished => write!(f, "program already finished"),
            PushError::Split(e) => write!(f, "cannot split block: {e:?}"),
            PushError::TooManyCorners => {
                write!(f, "NURBS has more than {} corners", MAX_PIECES - 1)
            }
            PushError::Aborting => write!(f, "abort under way"),
            PushError::Stale => write!(f, "planned against another state of the queue"),
            PushError::Pending => write!(f, "the rest of a long block is still being planned"),
            PushError::Schedule => write!(f, "the feed schedule could not be solved"),
            PushError::Kinematics(e) => write!(f, "five-axis block: {e}"),
        }
    }
}

/// Why a feed override was refused.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum OverrideError {
    /// Not a finite number in `0 ..= max_feed_override`.
    OutOfRange,
}

impl core::fmt::Display for OverrideError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "feed override must be between 0 and max-feed-override")
    }
}

/// Counters the caller can read at any time.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Stats {
    /// Ticks run.
    pub ticks: u64,
    /// Segments completed.
    pub segments_done: u64,
    /// Largest Newton iteration count used in one tick.
    pub max_newton_iters: u32,
    /// Ticks whose chord missed `Δ` by more than the Newton tolerance (the
    /// best iterate was used).
    pub newton_unconverged: u64,
    /// Joins between segments planned without a stop.
    pub junctions_blended: u64,
    /// Joins planned as rest points (corners, exact stops).
    pub junctions_stopped: u64,
    /// Ticks spent at rest at the end of what was queued while the program
    /// was not finished (the queue starved).
    pub starved_ticks: u64,
    /// Plans refused because the machine had reached their freeze point.
    pub stale_plans: u64,
    /// Plans offered to [`Executor::commit`] (accepted or not).
    pub commits: u64,
}

/// Upper bound on the pieces one block is cut into at tangent breaks (a
/// degree-1 NURBS of `MAX_CTRL` points has `MAX_CTRL − 2` corners).
pub const MAX_PIECES: usize = crate::nurbs::MAX_CTRL;

/// Planned distance ahead of a machine at speed `v` below which the rest of
/// the queue is planned (see [`BlockPlanner::plan_ahead`]): more than it
/// needs to come to rest, so the plan has not begun to brake for its end.
pub fn guard_distance(cfg: &InterpConfig, v: f64) -> f64 {
    let (a, j) = (cfg.planned_accel(), cfg.max_path_jerk);
    1.25 * Stop::new(v, a, a, j).distance() + 4.0 * grid_step(cfg)
}

/// Profile grid spacing: the smallest whole multiple of `profile_step` not
/// below one tick's travel at the machine's top speed.
pub fn grid_step(cfg: &InterpConfig) -> f64 {
    cfg.profile_step * grid_multiple(cfg) as f64
}

/// The real-time half of the interpolator, with a segment queue of capacity `Q`.
#[derive(Clone, Debug)]
pub struct Executor<const Q: usize = DEFAULT_QUEUE> {
    cfg: InterpConfig,
    queue: Deque<Segment, Q>,
    /// The speed spline from the machine's piece on (a ring; `ring[head]`
    /// is the piece the machine is on).
    ring: [Piece; RING],
    rest: [bool; RING],
    head: usize,
    len: usize,
    /// Position on the current piece (mm from its start) and speed.
    x: f64,
    v: f64,
    /// Feed hold or abort: the stop, the time into it, and where it began.
    stop: Option<(Stop, f64, f64)>,
    /// Arrived at a rest point in the last tick: stay there one tick (a
    /// setpoint at rest on the corner; the acceleration's steps on either
    /// side of it then stay one tick of jerk apart).
    dwell: bool,
    /// Parameter in the front segment.
    u: f64,
    /// Arc length of the run at the current point, mm.
    s: f64,
    /// Kahan compensation of `s`.
    s_comp: f64,
    /// Current position (X Y Z), in the path's frame: the tool tip in the
    /// workpiece frame under tool-centre-point control (`tcp`), else X Y Z
    /// of the machine.
    point: Vec3,
    abc: [f64; 3],
    /// The five-axis machine (`InterpConfig::machine`), the path's frame,
    /// and the joints under tool-centre-point control.
    machine: Option<Machine>,
    tcp: bool,
    joints: Joints,
    /// The front segment turns in place (`Orientation::in_place`): `point`
    /// is on the turn's measure, and the machine stands at `joints`.
    turn: Option<Orientation>,
    /// End of everything queued so far (where the next block must start).
    tail: Vec3,
    tail_s: f64,
    seq: u64,
    block_id: u32,
    finished: bool,
    hold: bool,
    abort: bool,
    state: RunState,
    stats: Stats,
}

impl<const Q: usize> Executor<Q> {
    /// A new executor at rest at `position` (X Y Z A B C), arc length 0.
    pub fn new(cfg: InterpConfig, position: [f64; 6]) -> Result<Self, ConfigError> {
        cfg.validate()?;
        let p = Vec3::new(position[0], position[1], position[2]);
        if !p.iter().all(|c| c.is_finite()) {
            return Err(ConfigError::OutOfRange("position"));
        }
        let machine = cfg.machine.and_then(|m| Machine::new(m).ok());
        Ok(Executor {
            cfg,
            queue: Deque::new(),
            ring: [Piece::default(); RING],
            rest: [false; RING],
            head: 0,
            len: 0,
            x: 0.0,
            v: 0.0,
            stop: None,
            dwell: false,
            u: 0.0,
            s: 0.0,
            s_comp: 0.0,
            point: p,
            abc: [position[3], position[4], position[5]],
            machine,
            tcp: false,
            joints: position,
            turn: None,
            tail: p,
            tail_s: 0.0,
            seq: 0,
            block_id: 0,
            finished: false,
            hold: false,
            abort: false,
            state: RunState::Idle,
            stats: Stats::default(),
        })
    }

    /// The configuration in force.
    pub fn config(&self) -> &InterpConfig {
        &self.cfg
    }
    /// Counters.
    pub fn stats(&self) -> Stats {
        self.stats
    }
    /// Current state.
    pub fn state(&self) -> RunState {
        self.state
    }
    /// Free segment slots.
    pub fn free_segments(&self) -> usize {
        Q - self.queue.len()
    }
    /// Queued segments (including the one being executed).
    pub fn queued_segments(&self) -> usize {
        self.queue.len()
    }
    /// Arc length queued but not yet travelled, mm.
    pub fn queued_length(&self) -> f64 {
        self.tail_s - self.s
    }
    /// Free pieces in the speed ring.
    pub fn free_pieces(&self) -> usize {
        RING - self.len
    }
    /// End of the queue (X Y Z) and its arc length.
    pub fn tail(&self) -> (Vec3, f64) {
        (self.tail, self.tail_s)
    }
    /// Path speed, mm/s.
    pub fn speed(&self) -> f64 {
        match &self.stop {
            Some((stop, t, _)) => stop.at(*t).1,
            None => self.v,
        }
    }
    /// A feed hold or abort stop is running or done (the plan is left).
    pub fn is_stopping(&self) -> bool {
        self.stop.is_some()
    }
    /// The program's end was committed.
    pub fn is_finished(&self) -> bool {
        self.finished
    }
    /// An abort is braking.
    pub fn is_aborting(&self) -> bool {
        self.abort
    }
    /// Where the machine is on the plan (arc length of the run), and whether
    /// it is at rest (not moving and not about to).
    pub fn plan_position(&self) -> (f64, bool) {
        if let Some((stop, t, s0)) = &self.stop {
            let (ds, v, _) = stop.at(*t);
            return (s0 + ds, v == 0.0);
        }
        match self.current() {
            Some(p) => (p.x0 + self.x, self.v == 0.0 && self.x == 0.0),
            // No plan (yet, or any more): at rest where it stands.
            None => (self.s, true),
        }
    }
    /// The point (X Y Z) and its arc length.
    pub fn position(&self) -> (Vec3, f64) {
        (self.point, self.s)
    }

    #[inline]
    fn current(&self) -> Option<&Piece> {
        (self.len > 0).then(|| &self.ring[self.head])
    }

    #[inline]
    fn ring_at(&self, i: usize) -> usize {
        (self.head + i) % RING
    }

    /// Marks the end of the program: reaching the end of the queue then means `Done`.
    pub fn finish(&mut self) {
        if self.finished {
            return;
        }
        self.finished = true;
        // Idle, or run to the end of the queue and resting there (a starved
        // program whose end comes after its last move): done.
        if self.queue.is_empty() && matches!(self.state, RunState::Idle | RunState::Running) {
            self.state = RunState::Done;
        }
    }

    /// Feed hold: stop on the path, then rest until [`resume`](Self::resume).
    /// Takes effect at the next tick. Begins the closed-form stop (the
    /// fastest with the tangential limits), which a hold's plan committed
    /// before the next tick replaces ([`crate::Driver::plan_to_rest`]: every
    /// limit held, the axes' jerk included); without one the stop runs.
    pub fn feed_hold(&mut self) {
        if matches!(self.state, RunState::Running | RunState::Idle) && !self.abort {
            self.hold = true;
            if self.state == RunState::Running {
                self.begin_stop();
                self.state = RunState::Holding;
            }
        }
    }

    /// Leave a feed hold. On a hold's plan, motion goes on along the plan
    /// made through its rest point while the machine still brakes fast
    /// ([`BlockPlanner::resume_hold`]), else along the one made from its
    /// rest point once there ([`BlockPlanner::plan_after_hold`]); after the
    /// closed-form stop, at rest, once a plan from there is committed
    /// ([`BlockPlanner::replan`] with the machine at rest).
    pub fn resume(&mut self) {
        if self.hold && !self.abort {
            self.hold = false;
            if self.state == RunState::Holding {
                self.state = RunState::Running;
            }
        }
    }

    /// A feed hold is in force: given and not resumed (the machine brakes,
    /// or rests, on it).
    pub fn is_held(&self) -> bool {
        self.hold
    }

    /// Does the machine wait at rest, off its plan, for a plan from where it
    /// stands (after a hold was resumed)?
    pub fn needs_plan(&self) -> bool {
        !self.hold && !self.abort && self.stop.is_some() && self.stop_done()
    }

    /// A feed hold's or abort's closed-form stop has not moved the machine
    /// yet: a plan to rest may replace it (the plan's state is still the
    /// machine's; [`crate::Driver::plan_to_rest`]).
    pub fn stop_unplanned(&self) -> bool {
        (self.hold || self.abort) && matches!(self.stop, Some((_, t, _)) if t == 0.0)
    }

    /// At rest where the plan rests: on a rest point, at the plan's end, or
    /// with no plan.
    fn resting_on_plan(&self) -> bool {
        self.v == 0.0
            && match self.current() {
                None => true,
                Some(p) => {
                    (self.x == 0.0 && self.rest[self.head]) || (self.len == 1 && self.x >= p.h)
                }
            }
    }

    fn stop_done(&self) -> bool {
        matches!(self.stop, Some((st, t, _)) if t >= st.duration())
    }

    /// Abort: stop on the path, then the queue is flushed and the executor
    /// is idle where it stopped. A finished program may be followed by a
    /// new one. Begins the closed-form stop, which a plan to rest replaces
    /// as for [`Self::feed_hold`] ([`crate::Driver::abort_into`]); held on
    /// a hold's plan, it rests where the hold does.
    pub fn abort(&mut self) {
        if matches!(self.state, RunState::Running | RunState::Holding) {
            // (Held on a hold's plan: the abort rests where the hold does.)
            let held_on_plan = self.hold && self.stop.is_none();
            self.abort = true;
            if self.stop.is_none() && !held_on_plan {
                self.begin_stop();
            }
            self.state = RunState::Stopping;
        } else if self.state == RunState::Done {
            self.finished = false;
            self.state = RunState::Idle;
        }
    }

    fn begin_stop(&mut self) {
        if self.stop.is_some() {
            return;
        }
        let (v, a, s) = match self.current() {
            Some(p) => (self.v, p.accel(self.x), p.x0 + self.x),
            // No plan: at rest where the machine stands (not where the queue ends).
            None => (0.0, 0.0, self.s),
        };
        let (am, jm) = self.stop_rates();
        self.stop = Some((Stop::new(v, a, am, jm), 0.0, s));
    }

    /// The acceleration and jerk a feed hold or abort brakes with: the
    /// planned ones, lowered where a queued five-axis segment's joints need
    /// it (`Segment::stop_limits`; at most the queue's length to look at).
    fn stop_rates(&self) -> (f64, f64) {
        let (mut am, mut jm) = (self.cfg.planned_accel(), self.cfg.planned_jerk());
        for seg in self.queue.iter() {
            am = am.min(seg.stop_limits.0);
            jm = jm.min(seg.stop_limits.1);
        }
        (am, jm)
    }

    /// Arc length at which a feed hold comes to rest (the run's arc
    /// length, mm): once given, where its stop or its plan rests; before,
    /// the nearest point the tangential limits allow (a hold's plan rests
    /// there or, where an axis needs gentler braking, farther).
    pub fn hold_stop_position(&self) -> f64 {
        if let Some((st, _, s0)) = &self.stop {
            return s0 + st.distance();
        }
        if self.hold || self.abort {
            // A hold or abort on the plan: its next rest point.
            return self.next_rest_on_plan();
        }
        match self.current() {
            Some(p) => {
                let (am, jm) = self.stop_rates();
                p.x0 + self.x + Stop::new(self.v, p.accel(self.x), am, jm).distance()
            }
            None => self.s,
        }
    }

    /// Where the plan next comes to rest: the start of the first piece ahead
    /// that starts at rest (the current one if the machine rests on it), or
    /// the plan's end.
    fn next_rest_on_plan(&self) -> f64 {
        let at_rest = self.x == 0.0 && self.v == 0.0;
        (0..self.len)
            .map(|i| self.ring_at(i))
            .find(|&k| self.rest[k] && (k != self.head || at_rest))
            .map_or_else(|| self.ring_end(), |k| self.ring[k].x0)
    }

    /// Queue a plan: its segments (if any) and its speed-spline update. All
    /// or nothing; a plan for another end of the queue, or one whose first
    /// changed piece the machine has reached, is refused with
    /// [`PushError::Stale`]. Linear in the plan's pieces, no allocation.
    pub fn commit(&mut self, plan: &PlannedBlock) -> Result<(), PushError> {
        self.stats.commits += 1;
        let r = self.commit_inner(plan);
        if plan.finish {
            // The end holds even if the speed update could not go in: the
            // machine then rests where its plan ends, and the guard plans on.
            self.finish();
        }
        r
    }

    fn commit_inner(&mut self, plan: &PlannedBlock) -> Result<(), PushError> {
        if plan.hold {
            // A hold or abort planned through the look-ahead: it replaces
            // the closed-form stop begun for it, if the machine has not
            // moved on that yet (else the stop goes on).
            if !self.stop_unplanned() {
                self.stats.stale_plans += 1;
                return Err(PushError::Stale);
            }
            self.stop = None;
        } else if self.abort {
            return Err(PushError::Aborting);
        }
        if plan.n_segments > 0 {
            if self.finished {
                return Err(PushError::Finished);
            }
            if plan.s0.to_bits() != self.tail_s.to_bits() || plan.tail != self.tail {
                self.stats.stale_plans += 1;
                return Err(PushError::Stale);
            }
            if plan.n_segments > self.free_segments() {
                return Err(PushError::Full {
                    needed: plan.n_segments,
                    free: self.free_segments(),
                });
            }
        }
        if plan.n_pieces == 0 {
            // Segments only: their speed is planned later.
            if plan.n_segments > 0 {
                self.queue_segments(plan);
            }
            self.wake();
            return Ok(());
        }
        // Where the update goes in the ring.
        let at = if plan.rest_start && self.at_rest_on(plan.from_x) {
            // From where the machine rests: replace its piece and the rest.
            Some(0)
        } else {
            (1..self.len).find(|&i| self.ring[self.ring_at(i)].x0 == plan.from_x)
        };
        let at = match at {
            Some(i) => i,
            None if self.len == 0 && plan.rest_start => 0,
            None if plan.rest_start && plan.from_x == self.ring_end() => self.len,
            None => {
                self.stats.stale_plans += 1;
                return Err(PushError::Stale);
            }
        };
        if at + plan.n_pieces > RING {
            return Err(PushError::ProfileFull);
        }
        // From here on nothing fails.
        if plan.n_segments > 0 {
            self.queue_segments(plan);
        }
        if at == 0 {
            // Restart on the new plan from rest.
            self.x = 0.0;
            self.v = 0.0;
            self.stop = None;
        }
        for k in 0..plan.n_pieces {
            let i = self.ring_at(at + k);
            self.ring[i] = plan.pieces[k];
            self.rest[i] = plan.rests[k];
        }
        self.len = at + plan.n_pieces;
        self.wake();
        Ok(())
    }

    /// Queue a plan's segments (room checked by the caller).
    fn queue_segments(&mut self, plan: &PlannedBlock) {
        let was_empty = self.queue.is_empty();
        if let Some(last) = self.queue.back_mut() {
            last.stop_at_end = plan.stop_at_join;
            if !plan.continues {
                self.count_junction(plan.stop_at_join);
            }
        }
        for seg in plan.pieces_geometry() {
            if seg.s1() < plan.s1 {
                self.count_junction(seg.stop_at_end);
            }
            let _ = self.queue.push_back(*seg);
        }
        self.tail = plan.end;
        self.tail_s = plan.s1;
        if let (true, Some(front)) = (was_empty, self.queue.front()) {
            self.u = front.path.u_start();
            self.enter_frame();
        }
    }

    /// Idle with something to do: running (or holding, if held).
    fn wake(&mut self) {
        match self.state {
            RunState::Idle if self.hold => self.state = RunState::Holding,
            RunState::Idle if !self.queue.is_empty() => self.state = RunState::Running,
            _ => {}
        }
    }

    /// Distance the machine has planned ahead of it (to where its plan rests), mm.
    pub fn planned_ahead(&self) -> f64 {
        let (s, _) = self.plan_position();
        (self.ring_end() - s).max(0.0)
    }

    fn count_junction(&mut self, stop: bool) {
        if stop {
            self.stats.junctions_stopped += 1;
        } else {
            self.stats.junctions_blended += 1;
        }
    }

    /// Is the machine at rest exactly at arc length `x` (on its plan or after a stop)?
    fn at_rest_on(&self, x: f64) -> bool {
        let (s, rest) = self.plan_position();
        rest && s == x
    }

    fn ring_end(&self) -> f64 {
        if self.len == 0 {
            self.s
        } else {
            self.ring[self.ring_at(self.len - 1)].x1()
        }
    }

    /// One period: advance along the path and return the setpoint. Never
    /// allocates, locks or blocks.
    pub fn tick(&mut self) -> Setpoint {
        self.stats.ticks += 1;
        self.seq += 1;
        let ts = self.cfg.period;
        let mut delta = 0.0;
        let active = matches!(
            self.state,
            RunState::Running | RunState::Holding | RunState::Stopping
        );
        if active && !self.queue.is_empty() {
            if let Some(front) = self.queue.front() {
                self.block_id = front.block_id;
            }
            let target = self.next_target(ts);
            let c = target - self.s;
            if c > 0.0 {
                delta = self.advance(c);
            }
            if delta <= 0.0 {
                // At rest on a stop: continue past a corner, or end.
                self.settle_at_end();
            }
            if (self.hold || self.abort) && self.stop_done() {
                if self.abort {
                    self.flush();
                } else {
                    self.state = RunState::Holding;
                }
            } else if self.abort && self.stop.is_none() && self.resting_on_plan() {
                // An abort planned through the look-ahead, at rest.
                self.flush();
            }
        } else if active && self.abort {
            self.flush();
        }
        if active {
            self.update_joints();
        }
        Setpoint {
            seq: self.seq,
            time: self.seq as f64 * ts,
            axes: self.axes(),
            feed: delta / ts,
            u: self.u,
            s: self.s,
            block_id: self.block_id,
            state: self.state,
        }
    }

    /// The planned arc length one period from now; moves along the spline
    /// (or the stop).
    #[inline]
    fn next_target(&mut self, ts: f64) -> f64 {
        if let Some((stop, t, s0)) = &mut self.stop {
            *t = (*t + ts).min(stop.duration());
            return *s0 + stop.at(*t).0;
        }
        let mut left = ts;
        if self.dwell {
            self.dwell = false;
            if let Some(p) = self.current() {
                return p.x0 + self.x;
            }
        }
        if (self.hold || self.abort) && self.resting_on_plan() {
            // Held where the plan rests (where a hold's plan brought the
            // machine, before it starts, or with no plan yet): stay until
            // resumed.
            return self.plan_position().0;
        }
        loop {
            let Some(p) = self.current().copied() else {
                return self.tail_s;
            };
            match spline::time_to_end(&p, self.x, self.v, left) {
                None => {
                    let (x, v) = spline::advance(&p, self.x, self.v, left);
                    self.x = x.min(p.h);
                    self.v = v;
                    return p.x0 + self.x;
                }
                Some(t) => {
                    let (_, v) = spline::advance(&p, self.x, self.v, t);
                    left -= t;
                    let next_rest = self.len < 2 || self.rest[self.ring_at(1)];
                    if self.len < 2 {
                        // The end of the plan: rest there.
                        self.x = p.h;
                        self.v = 0.0;
                        // (A hold's or abort's plan ends where it rests.)
                        if !self.finished && !self.hold && !self.abort {
                            self.stats.starved_ticks += 1;
                        }
                        return p.x1();
                    }
                    self.head = self.ring_at(1);
                    self.len -= 1;
                    self.x = 0.0;
                    if next_rest {
                        // A rest point: the rest of this tick and the next one there.
                        self.v = 0.0;
                        self.dwell = true;
                        return p.x1();
                    }
                    self.v = v;
                    if left <= 0.0 {
                        return p.x1();
                    }
                }
            }
        }
    }

    /// The machine's joints X Y Z A B C.
    #[inline]
    pub fn axes(&self) -> Joints {
        if self.tcp || self.turn.is_some() {
            self.joints
        } else {
            let p = self.point;
            [p.x, p.y, p.z, self.abc[0], self.abc[1], self.abc[2]]
        }
    }

    /// The five-axis part of a tick: the rotary axes (plain axes) or the
    /// joints (tool-centre-point control) at the point and parameter reached.
    #[inline]
    fn update_joints(&mut self) {
        let Some(seg) = self.queue.front() else {
            return;
        };
        let Some(o) = &seg.orientation else {
            return;
        };
        match o.joints(self.machine.as_ref(), self.point, self.u, &self.axes()) {
            Ok(q) => {
                self.joints = q;
                self.abc = [q[3], q[4], q[5]];
            }
            // The planner walked the block's joints; a tick off its reach
            // (a branch the planner did not take) stops the machine.
            Err(_) => self.state = RunState::Fault,
        }
    }

    /// The front segment was entered at rest: if it is in the other frame
    /// (tool-centre-point control goes on or off), the point is the same
    /// machine pose seen in it, its start. Entering or leaving a turn in
    /// place moves the point between the turn's measure and the path.
    #[inline]
    fn enter_frame(&mut self) -> bool {
        let Some(seg) = self.queue.front() else {
            return false;
        };
        let turn = seg.orientation.filter(|o| o.fixed().is_some());
        // (The parts of one long turn are one measure: nothing to enter.)
        if seg.is_tcp() == self.tcp && turn == self.turn {
            return false;
        }
        if !self.tcp && self.turn.is_none() {
            self.joints = self.axes();
        }
        self.tcp = seg.is_tcp();
        self.turn = turn;
        self.point = seg.path.start_point();
        true
    }

    /// Abort finished: drop everything queued; idle where the machine stands.
    fn flush(&mut self) {
        if self.tcp || self.turn.is_some() {
            // Idle in the machine's own X Y Z (where a new program starts).
            let q = self.joints;
            self.point = Vec3::new(q[0], q[1], q[2]);
            self.abc = [q[3], q[4], q[5]];
            self.tcp = false;
            self.turn = None;
        }
        self.queue.clear();
        self.abort = false;
        self.hold = false;
        self.finished = false;
        self.stop = None;
        // (An abort's plan came to rest on a rest point: no dwell there
        // for the next program.)
        self.dwell = false;
        self.tail = self.point;
        self.tail_s = self.s;
        self.len = 0;
        self.x = 0.0;
        self.v = 0.0;
        self.state = RunState::Idle;
    }

    /// Move the point by `delta` along the path, across segment ends. Returns
    /// the displacement actually made: `delta`, or less when landing on a stop
    /// (the chord to a stop can be shorter than the arc the schedule counted).
    fn advance(&mut self, mut delta: f64) -> f64 {
        let mut from = self.point;
        let commanded = delta;
        let s_start = self.s;
        let update = self.cfg.param_update;
        let mut crossed = false;
        loop {
            let Some(seg) = self.queue.front() else {
                return 0.0;
            };
            let end = seg.path.end_point();
            let arc_left = seg.s1() - self.s;
            let to_end = match update {
                ParamUpdate::Corrected => (end - from).norm(),
                _ => arc_left,
            };
            // The chord to the end can be short while the arc is long (a
            // closed curve starts at its end): the end counts as within reach
            // only when the arc left is too (a chord of Δ spans an arc of at
            // most πΔ/2 on any curve the chord law lets through).
            let reachable = arc_left <= CHORD_ARC_REACH * delta + END_SNAP_TOL;
            // A stop within reach (by the chord, or by the arc the schedule
            // counts from where the tick started, with the resolution of the
            // coordinates) is landed on exactly. (Past a segment's end the
            // corrected update keeps the whole Δ: the arc left of this
            // segment alone would land a stop the schedule reaches ticks later.)
            let lands = seg.stop_at_end && seg.s1() - s_start <= commanded + END_SNAP_TOL;
            // Sitting on a rest point the plan has left: go on past it.
            let leaving = seg.stop_at_end
                && arc_left <= END_SNAP_TOL
                && (end - from).norm() <= END_SNAP_TOL
                && self.queue.len() > 1;
            if (to_end <= delta && reachable) || lands {
                if seg.stop_at_end && !leaving {
                    // Land exactly on the end point.
                    self.u = seg.path.u_end();
                    self.s = seg.s1();
                    self.s_comp = 0.0;
                    self.point = end;
                    return (end - from).norm();
                }
                // Carry the rest into the next segment in this tick.
                if update != ParamUpdate::Corrected {
                    delta -= to_end;
                }
                let _ = self.queue.pop_front();
                self.stats.segments_done += 1;
                let Some(next) = self.queue.front() else {
                    return commanded;
                };
                self.u = next.path.u_start();
                self.s = next.s0;
                self.block_id = next.block_id;
                if update != ParamUpdate::Corrected {
                    self.point = next.path.start_point();
                }
                if self.enter_frame() {
                    from = self.point;
                }
                crossed = true;
                continue;
            }
            // Borrow, never copy, the path: a NURBS segment is over a kilobyte.
            let path = &seg.path;
            let u_end = path.u_end();
            let u_old = self.u;
            let (u_new, point) = match update {
                ParamUpdate::FirstOrder => {
                    let speed = path.eval(u_old, 1).d1.norm();
                    // Eq. 10 is undefined where C' = 0: take the second-order step there.
                    let step = if speed > 0.0 {
                        delta / speed
                    } else {
                        taylor2(path, u_old, delta)
                    };
                    let u = (u_old + step).min(u_end);
                    (u, path.eval(u, 0).p)
                }
                ParamUpdate::SecondOrder => {
                    let u = (u_old + taylor2(path, u_old, delta)).min(u_end);
                    (u, path.eval(u, 0).p)
                }
                ParamUpdate::Corrected => {
                    // After a segment end, only part of Δ is left from this segment's start.
                    let left = if crossed {
                        delta - (path.start_point() - from).norm()
                    } else {
                        delta
                    };
                    let guess = taylor2(path, u_old, left);
                    newton_chord(path, from, delta, u_old, guess, &self.cfg, &mut self.stats)
                }
            };
            let travelled = path.short_arc_length(u_old, u_new);
            if crossed {
                self.s = seg.s0;
                self.s_comp = 0.0;
            }
            // Kahan summation.
            let y = travelled - self.s_comp;
            let t = self.s + y;
            self.s_comp = (t - self.s) - y;
            self.s = t;
            self.u = u_new;
            self.point = point;
            return commanded;
        }
    }

    /// At rest at a stop: continue past a corner, or report the end of the queue.
    fn settle_at_end(&mut self) {
        let Some(seg) = self.queue.front() else {
            if self.finished {
                self.state = RunState::Done;
            }
            return;
        };
        if self.u < seg.path.u_end() {
            // Arc length says the stop is reached; the parameter may trail by
            // round-off. Land on the exact end point.
            let left = (seg.path.end_point() - self.point).norm();
            if seg.s1() - self.s > END_SNAP_TOL || left > END_SNAP_TOL {
                return; // not at the end yet (waiting on the schedule)
            }
            self.u = seg.path.u_end();
            self.s = seg.s1();
            self.s_comp = 0.0;
            self.point = seg.path.end_point();
        }
        if seg.stop_at_end {
            let _ = self.queue.pop_front();
            self.stats.segments_done += 1;
            if let Some(next) = self.queue.front() {
                self.u = next.path.u_start();
                self.block_id = next.block_id;
                self.enter_frame();
            } else {
                // At the end of the queue: done, or waiting on the path for
                // more. A turn in place ends where the tool stands (the
                // point, the queue's end and a new program's start, is the
                // tip or X Y Z again, not the end of the turn's measure).
                if let Some(at) = self.turn.and_then(|o| o.fixed()) {
                    self.point = at;
                    self.turn = None;
                }
                self.len = 0;
                if self.finished {
                    self.state = RunState::Done;
                }
            }
        }
    }
}

/// The planning side and the executor in one value, for single-threaded use
/// (`simulate`, tests, benches): `push` plans and commits at once, and
/// between ticks whatever the [`Driver`] finds due is planned and committed.
/// Real-time callers run the [`Executor`] on one thread and a [`Driver`] on
/// another instead.
///
/// About 1.6 MiB: box it.
#[derive(Debug)]
pub struct Interpolator<const Q: usize = DEFAULT_QUEUE> {
    exec: Executor<Q>,
    driver: Driver,
}

impl<const Q: usize> Interpolator<Q> {
    /// A new interpolator at rest at `position` (X Y Z A B C).
    pub fn new(cfg: InterpConfig, position: [f64; 6]) -> Result<Self, ConfigError> {
        let exec = Executor::new(cfg, position)?;
        let p = Vec3::new(position[0], position[1], position[2]);
        Ok(Interpolator {
            exec,
            driver: Driver::new(cfg, p, 0.0)?,
        })
    }

    /// Profile grid spacing (see [`grid_step`]).
    pub fn grid_step(cfg: &InterpConfig) -> f64 {
        grid_step(cfg)
    }
    /// The configuration in force.
    pub fn config(&self) -> &InterpConfig {
        self.exec.config()
    }
    /// Counters.
    pub fn stats(&self) -> Stats {
        self.exec.stats()
    }
    /// Current state.
    pub fn state(&self) -> RunState {
        self.exec.state()
    }
    /// Free segment slots.
    pub fn free_segments(&self) -> usize {
        self.exec.free_segments()
    }
    /// Queued segments (including the one being executed).
    pub fn queued_segments(&self) -> usize {
        self.exec.queued_segments()
    }
    /// Arc length queued but not yet travelled, mm.
    pub fn queued_length(&self) -> f64 {
        self.exec.queued_length()
    }
    /// The feed override in force (1 = 100 %).
    pub fn feed_override(&self) -> f64 {
        self.driver.feed_override()
    }
    /// The last error of planning done on the caller's behalf (`finish`,
    /// `resume`, `set_feed_override`, the later parts of a long block);
    /// `None` when all went through.
    pub fn last_error(&self) -> Option<PushError> {
        self.driver.last_error()
    }
    /// The executor (real-time half).
    pub fn executor(&self) -> &Executor<Q> {
        &self.exec
    }
    /// The planner (non-real-time half).
    pub fn planner(&self) -> &BlockPlanner {
        self.driver.planner()
    }
    /// The planner's look-ahead window, to set its diagnostics
    /// ([`crate::plan::Window::trace`]).
    pub fn window_mut(&mut self) -> &mut crate::plan::Window {
        self.driver.window_mut()
    }

    /// Marks the end of the program: reaching the end of the queue then means `Done`.
    pub fn finish(&mut self) {
        self.driver.finish_into(&mut self.exec, &mut |_| {});
    }

    /// Feed hold (see [`Driver::feed_hold_into`]): the machine comes to rest on
    /// its path with every limit held, then waits for [`Self::resume`].
    pub fn feed_hold(&mut self) {
        self.driver.feed_hold_into(&mut self.exec, &mut |_| {});
    }

    /// Leave a feed hold: once at rest, the speed is planned again from there.
    pub fn resume(&mut self) {
        self.driver.resume_into(&mut self.exec, &mut |_| {});
    }

    /// Abort (see [`Driver::abort_into`]); the planner follows once the
    /// machine is idle.
    pub fn abort(&mut self) {
        self.driver.abort_into(&mut self.exec, &mut |_| {});
    }

    /// Set the feed override (see [`Driver::set_feed_override`]); the speed
    /// is planned again from the next piece on.
    pub fn set_feed_override(&mut self, value: f64) -> Result<(), OverrideError> {
        self.driver
            .set_feed_override_into(&mut self.exec, value, &mut |_| {})
    }

    /// Arc length at which a feed hold comes to rest (see
    /// [`Executor::hold_stop_position`]).
    pub fn hold_stop_position(&self) -> f64 {
        self.exec.hold_stop_position()
    }

    /// Queue a block: plan it (non-real-time work) and commit it. All or
    /// nothing: on error nothing was queued. A block longer than the
    /// look-ahead's part is accepted whole; its later parts are planned as
    /// the machine moves on (in `push`, `finish` and `tick`).
    pub fn push(&mut self, block: &Block) -> Result<(), PushError> {
        self.driver.push_into(&mut self.exec, block, &mut |_| {})
    }

    /// Queue a plan made by another planner (see [`Executor::commit`]).
    pub fn commit(&mut self, plan: &PlannedBlock) -> Result<(), PushError> {
        self.exec.commit(plan)
    }

    /// One period (see [`Executor::tick`]). Before it, whatever planning is
    /// due is done and committed (non-real-time work: real-time callers drive
    /// [`Executor`] instead).
    pub fn tick(&mut self) -> Setpoint {
        self.driver.drive(&mut self.exec, &mut |_| {});
        self.exec.tick()
    }
}

/// Second-order Taylor step in arc length: `Δ/|C'| − Δ²·(C'·C'')/(2|C'|⁴)`.
///
/// Near a stationary point (`|C'|² ≤ |C''|·Δ`, where that series does not
/// converge; at the point itself it divides by zero) the step is the positive
/// root of `|C''|·e²/2 + |C'|·e = Δ` instead: `√(2Δ/|C''|)` at the point.
#[inline]
fn taylor2(path: &Path, u: f64, delta: f64) -> f64 {
    let d = path.eval(u, 2);
    let sp2 = d.d1.norm_squared();
    let sp = libm::sqrt(sp2);
    let bend = d.d2.norm();
    if sp2 <= bend * delta {
        if !(sp > 0.0 || bend > 0.0) {
            return 0.0; // nothing to go by: the chord search brackets from u
        }
        return 2.0 * delta / (sp + libm::sqrt(sp2 + 2.0 * bend * delta));
    }
    delta / sp - delta * delta * d.d1.dot(&d.d2) / (2.0 * sp2 * sp2)
}

/// Grid spacing in units of `profile_step`.
pub(crate) fn grid_multiple(cfg: &InterpConfig) -> i64 {
    libm::ceil(cfg.max_path_speed * cfg.period / cfg.profile_step).max(1.0) as i64
}

/// Solve `|C(u) − from| = delta` for `u` in `(u_lo, u_end)` by Newton with a bracket.
#[inline]
fn newton_chord(
    path: &Path,
    from: Vec3,
    delta: f64,
    u_lo: f64,
    guess: f64,
    cfg: &InterpConfig,
    stats: &mut Stats,
) -> (f64, Vec3) {
    let u_end = path.u_end();
    // The chord cannot be resolved below the round-off of the coordinates,
    // nor below what one ulp of u moves the point (|C'|·ulp(u)).
    let resolution = |u: f64, speed: f64| {
        8.0 * f64::EPSILON * (from.amax() + delta)
            + 4.0 * speed * f64::EPSILON * libm::fabs(u).max(1.0)
    };
    let mut tol = cfg.newton_rel_tol * delta;
    // A local bracket: the chord equation has other roots wherever the
    // curve comes back within Δ of this point (loops, cusps), so never
    // search the whole segment. Widen from twice the estimate until the
    // chord exceeds Δ.
    let est = if guess > 0.0 {
        guess
    } else {
        (u_end - u_lo) * 1e-9
    };
    let mut hi = u_end;
    let mut width = 2.0 * est;
    let mut iters = 0;
    while u_lo + width < u_end {
        if (path.eval(u_lo + width, 0).p - from).norm() > delta {
            hi = u_lo + width;
            break;
        }
        width *= 2.0;
    }
    let mut lo = u_lo;
    let mut u = (u_lo + est).clamp(lo, hi);
    let (mut best_u, mut best_p, mut best_f) = (u, from, f64::INFINITY);
    for _ in 0..cfg.newton_max_iter {
        iters += 1;
        let d = path.eval(u, 1);
        let v = d.p - from;
        let chord = v.norm();
        let f = chord - delta;
        tol = tol.max(resolution(u, d.d1.norm()));
        if libm::fabs(f) < best_f {
            best_f = libm::fabs(f);
            best_u = u;
            best_p = d.p;
        }
        if libm::fabs(f) <= tol {
            break;
        }
        if f > 0.0 {
            hi = u;
        } else {
            lo = u;
        }
        // d|v|/du = v·C'/|v|
        let df = if chord > 0.0 {
            v.dot(&d.d1) / chord
        } else {
            d.d1.norm()
        };
        let next = u - f / df;
        if next == u {
            break; // converged to the last bit
        }
        u = if next > lo && next < hi {
            next
        } else {
            0.5 * (lo + hi)
        };
    }
    if iters > stats.max_newton_iters {
        stats.max_newton_iters = iters;
    }
    if best_f > tol {
        stats.newton_unconverged += 1;
    }
    (best_u, best_p)
}
