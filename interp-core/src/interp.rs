//! The fixed-period interpolator: `tick()` turns the queued segments and
//! their planned profile into one setpoint per period. No allocation, lock or
//! system call in `tick`.
//!
//! Two layers run each tick:
//!
//! 1. **Reference schedule** (one dimension, arc length). The step is
//!    `Δ = min(Δ_prev + a, limit·Ts, brake_step(node) for every node and stop
//!    within stopping distance)`, never below `Δ_prev − a`, with
//!    `a = A·Ts²`: acceleration-limited and always able to stop within what
//!    is queued. Feed hold and abort lower it by `a` per tick to rest.
//! 2. **Jerk filter**: the machine follows the mean of the last
//!    `N = ceil(2·A/(J·Ts))` reference positions (a moving average, like the
//!    jerk filters of industrial controllers). A mean of acceleration-limited
//!    steps changes its acceleration by at most `2a/N ≤ J·Ts³` per tick, so
//!    jerk is bounded however the reference accelerates or brakes. The limits
//!    the reference follows are eroded ([`Profile::erode`]) so that the mean
//!    still keeps every limit where the machine is.
//!
//! The parameter update ([`ParamUpdate`]) then finds the next `u` whose chord
//! from the last point is the filtered step; a segment end inside the tick
//! carries the rest of the step into the next segment in the same tick.

use heapless::Deque;

use crate::config::{ConfigError, InterpConfig, MAX_FILTER, ParamUpdate};
use crate::feed::junction_speed;
use crate::geom::{Curve, Derivs, Vec3};
use crate::path::{Block, Path, SplitAtError};
use crate::plan::{Erosion, MAX_PROFILE, Profile, Segment, brake_step, stop_distance};
use crate::prepare::{BlockPlanner, PlannedBlock, Room};

/// Default segment-queue capacity.
pub const DEFAULT_QUEUE: usize = 64;

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
    /// Commanded path speed over the tick that ended here, `Δ/Ts`, mm/s.
    pub feed: f64,
    /// Path parameter of the block at this point.
    pub u: f64,
    /// Arc length of the run at this point, mm.
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
    /// The look-ahead profile cannot reach that far ahead yet (`MAX_PROFILE`
    /// grid steps): push again once the machine has moved on.
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
    /// The plan was made against another end of the queue (an abort moved
    /// it, or another block came first): plan it again.
    Stale,
    /// The block is longer than the look-ahead profile can ever hold
    /// (`MAX_PROFILE` grid intervals): cut it into shorter blocks.
    TooLong,
}

impl core::fmt::Display for PushError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            PushError::Full { needed, free } => {
                write!(f, "queue full: block needs {needed} segments, {free} free")
            }
            PushError::ProfileFull => write!(f, "look-ahead profile full"),
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
            PushError::Stale => write!(f, "planned against another end of the queue"),
            PushError::TooLong => write!(
                f,
                "block longer than the look-ahead profile ({MAX_PROFILE} grid intervals)"
            ),
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
    /// Ticks where the schedule asked for more deceleration than the limit
    /// allows (the step was held at `Δ_prev − a`). Zero in a correct plan.
    pub brake_overruns: u64,
    /// Largest Newton iteration count used in one tick.
    pub max_newton_iters: u32,
    /// Ticks whose chord missed `Δ` by more than the Newton tolerance (the
    /// best iterate was used).
    pub newton_unconverged: u64,
    /// Junctions passed without stopping (speed limited by [`junction_speed`]).
    pub junctions_blended: u64,
    /// Junctions that needed a full stop.
    pub junctions_stopped: u64,
}

/// The longest move the look-ahead takes in one block without waiting for
/// an empty profile: a quarter of its reach (`MAX_PROFILE` grid intervals).
/// Longer moves are cut into equal parts before planning
/// (`traces::Pipeline`), so a move of any length runs at speed through them.
pub fn max_move_length(cfg: &InterpConfig) -> f64 {
    MAX_PROFILE as f64 / 4.0 * cfg.profile_step * grid_multiple(cfg) as f64
}

/// Upper bound on the pieces one block is cut into at tangent breaks (a
/// degree-1 NURBS of `MAX_CTRL` points has `MAX_CTRL − 2` corners). `push`
/// keeps this many paths on its stack (~45 KiB).
pub const MAX_PIECES: usize = crate::nurbs::MAX_CTRL;

/// The interpolator with a segment queue of capacity `Q`.
#[derive(Debug)]
pub struct Interpolator<const Q: usize = DEFAULT_QUEUE> {
    cfg: InterpConfig,
    queue: Deque<Segment, Q>,
    profile: Profile,
    /// Displacement of the last tick (the filtered step), mm.
    step: f64,
    /// Reference schedule: arc length and step of the last tick.
    s_ref: f64,
    step_ref: f64,
    /// Jerk filter: the last `filter_len` reference positions (a ring).
    window: [f64; MAX_FILTER],
    filter_len: usize,
    window_head: usize,
    /// Parameter in the front segment.
    u: f64,
    /// Arc length of the run at the current point, mm.
    s: f64,
    /// Kahan compensation of `s`: thousands of ~0.1 mm steps added to ~100 mm
    /// would otherwise drift by round-off from the exact segment starts.
    s_comp: f64,
    /// Current position (X Y Z).
    point: Vec3,
    abc: [f64; 3],
    /// End of everything queued so far (where the next block must start).
    tail: Vec3,
    tail_s: f64,
    /// Derivatives (order 3) at the end of the last queued segment.
    tail_derivs: Option<Derivs>,
    /// The last queued block asks to come to rest at its end (G61.1).
    tail_exact_stop: bool,
    seq: u64,
    block_id: u32,
    finished: bool,
    hold: bool,
    abort: bool,
    /// Feed override: commanded and applied (ramped) values.
    override_cmd: f64,
    override_now: f64,
    state: RunState,
    stats: Stats,
}

impl<const Q: usize> Interpolator<Q> {
    /// A new interpolator at rest at `position` (X Y Z A B C).
    pub fn new(cfg: InterpConfig, position: [f64; 6]) -> Result<Self, ConfigError> {
        cfg.validate()?;
        let p = Vec3::new(position[0], position[1], position[2]);
        if !p.iter().all(|c| c.is_finite()) {
            return Err(ConfigError::OutOfRange("position"));
        }
        Ok(Interpolator {
            cfg,
            queue: Deque::new(),
            profile: Profile::new(Self::grid_step(&cfg)),
            step: 0.0,
            s_ref: 0.0,
            step_ref: 0.0,
            window: [0.0; MAX_FILTER],
            filter_len: cfg.filter_ticks(),
            window_head: 0,
            u: 0.0,
            s: 0.0,
            s_comp: 0.0,
            point: p,
            abc: [position[3], position[4], position[5]],
            tail: p,
            tail_s: 0.0,
            tail_derivs: None,
            tail_exact_stop: false,
            seq: 0,
            block_id: 0,
            finished: false,
            hold: false,
            abort: false,
            override_cmd: 1.0,
            override_now: 1.0,
            state: RunState::Idle,
            stats: Stats::default(),
        })
    }

    /// Profile grid spacing: the smallest whole multiple of `profile_step` not
    /// below one tick's travel at the machine's top speed, so one step spans
    /// at most two intervals.
    pub fn grid_step(cfg: &InterpConfig) -> f64 {
        cfg.profile_step * grid_multiple(cfg) as f64
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
    /// Length of the jerk filter, ticks.
    pub fn filter_ticks(&self) -> usize {
        self.filter_len
    }
    /// The feed override applied in the last tick (1 = 100 %).
    pub fn feed_override(&self) -> f64 {
        self.override_now
    }

    /// Marks the end of the program: reaching the end of the queue then means
    /// `Done`. The end of the queue stops being provisional, so the limits
    /// near it rise (non-RT work, like `push`).
    pub fn finish(&mut self) {
        if self.finished {
            return;
        }
        self.finished = true;
        if self.queue.is_empty() {
            if self.state == RunState::Idle {
                self.state = RunState::Done;
            }
            return;
        }
        let from = self.profile.index_of(self.tail_s) - 2;
        self.replan(from, self.tail_s);
    }

    /// The profile (grid caps and node limits) ahead of the machine.
    pub fn profile(&self) -> &Profile {
        &self.profile
    }

    /// Feed hold: decelerate to rest on the path (within the limits) and stay
    /// there until [`resume`](Self::resume). Takes effect at the next tick.
    pub fn feed_hold(&mut self) {
        if matches!(self.state, RunState::Running | RunState::Idle) && !self.abort {
            self.hold = true;
            if self.state == RunState::Running {
                self.state = RunState::Holding;
            }
        }
    }

    /// Leave a feed hold: accelerate again from where the machine is.
    pub fn resume(&mut self) {
        if self.hold && !self.abort {
            self.hold = false;
            if self.state == RunState::Holding {
                self.state = RunState::Running;
            }
        }
    }

    /// Abort: the fastest stop on the path within the limits, then the queue
    /// is flushed and the interpolator is idle where it stopped (the next
    /// block must start there). A finished program may be followed by a new one.
    pub fn abort(&mut self) {
        if matches!(self.state, RunState::Running | RunState::Holding) {
            self.abort = true;
            self.state = RunState::Stopping;
        } else if self.state == RunState::Done {
            self.finished = false;
            self.state = RunState::Idle;
        }
    }

    /// Set the feed override (1 = 100 %, up to `max_feed_override`). It
    /// scales the programmed feed and the MRR law, never the machine's
    /// limits, and is applied as a ramp of `override_rate` per second.
    pub fn set_feed_override(&mut self, value: f64) -> Result<(), OverrideError> {
        if !(value >= 0.0 && value <= self.cfg.max_feed_override) {
            return Err(OverrideError::OutOfRange);
        }
        self.override_cmd = value;
        Ok(())
    }

    /// Arc length at which the machine would come to rest if a feed hold
    /// were given now (the run's arc length, mm).
    pub fn hold_stop_position(&self) -> f64 {
        let a = self.cfg.planned_accel() * self.cfg.period * self.cfg.period;
        self.s_ref + stop_distance(self.step_ref - a, a)
    }

    /// Queue a block: cut at tangent breaks, sample the feed laws onto the
    /// grid, price the junctions, erode for the jerk filter and run the
    /// backward pass (non-RT work). All or nothing: on error nothing was queued.
    ///
    /// Exactly [`BlockPlanner::plan`] then [`commit`](Self::commit); a caller
    /// with an RT thread plans elsewhere and commits there.
    pub fn push(&mut self, block: &Block) -> Result<(), PushError> {
        self.check_accepting()?;
        let room = Room {
            segments: self.free_segments(),
            last_interval: self.ring_base() + MAX_PROFILE as i64 - 1,
        };
        let mut plan = PlannedBlock::new();
        self.planner().plan_within(block, &mut plan, Some(room))?;
        self.commit(&plan)
    }

    /// A planner for blocks that follow what is queued now.
    pub fn planner(&self) -> BlockPlanner {
        // The config was validated at construction and the tail is finite.
        BlockPlanner::from_parts(self.cfg, self.profile.h(), self.tail, self.tail_s)
    }

    fn check_accepting(&self) -> Result<(), PushError> {
        if self.finished {
            return Err(PushError::Finished);
        }
        if self.abort {
            return Err(PushError::Aborting);
        }
        Ok(())
    }

    /// First grid interval of the profile ring once the next block is queued.
    fn ring_base(&self) -> i64 {
        if self.queue.is_empty() {
            self.profile.index_of(self.s)
        } else {
            self.profile.base()
        }
    }

    /// Queue a block planned by [`BlockPlanner::plan`]: merge its limits into
    /// the profile, price the junction with what is queued, erode and run the
    /// backward pass. Linear in the block's grid intervals, no allocation:
    /// the RT half of [`push`](Self::push). All or nothing; a plan made
    /// against another end of the queue is refused with [`PushError::Stale`].
    pub fn commit(&mut self, plan: &PlannedBlock) -> Result<(), PushError> {
        self.check_accepting()?;
        if plan.s0.to_bits() != self.tail_s.to_bits()
            || plan.tail != self.tail
            || plan.h.to_bits() != self.profile.h().to_bits()
        {
            return Err(PushError::Stale);
        }
        let n_pieces = plan.n_segments;
        if n_pieces > self.free_segments() {
            return Err(PushError::Full {
                needed: n_pieces,
                free: self.free_segments(),
            });
        }
        if self.queue.is_empty() {
            // Nothing ahead: restart the ring where the machine stands.
            let g = self.profile.index_of(self.s);
            self.profile.reset_at(g);
        }
        let g_last = self.profile.index_of(plan.s1);
        if !self.profile.can_extend_to(g_last) {
            return Err(PushError::ProfileFull);
        }
        // From here on nothing can fail.
        let was_empty = self.queue.is_empty();
        let old_tail_s = self.tail_s;
        self.profile.extend_to(g_last);
        // The junction with what is queued (the old tail was a provisional stop).
        if let (Some(left), false) = (self.tail_derivs, was_empty) {
            let v = if self.tail_exact_stop {
                0.0
            } else {
                junction_speed(&left, &plan.entry, &self.cfg)
            };
            let stop = self.apply_junction(v, old_tail_s);
            if let Some(last) = self.queue.back_mut() {
                last.stop_at_end = stop;
            }
        }
        for i in 0..plan.n_caps {
            let g = plan.g0 + i as i64;
            self.profile.lower_cap(g, plan.raw[i]);
            self.profile.lower_feed_cap(g, plan.raw_feed[i]);
        }
        for (k, seg) in plan.pieces().enumerate() {
            if k > 0 {
                // A tangent break inside the block.
                let stop = self.apply_junction(plan.corner[k], seg.s0);
                if let Some(last) = self.queue.back_mut() {
                    last.stop_at_end = stop;
                }
            }
            let _ = self.queue.push_back(*seg); // room checked above
        }
        self.tail = plan.end;
        self.tail_s = plan.s1;
        self.tail_derivs = Some(plan.exit);
        self.tail_exact_stop = plan.exact_stop;
        let from = self.profile.index_of(old_tail_s) - 2;
        self.replan(from, old_tail_s);
        if let (true, Some(front)) = (was_empty, self.queue.front()) {
            self.u = front.path.u_start();
        }
        match self.state {
            RunState::Idle if self.hold => self.state = RunState::Holding,
            RunState::Idle => self.state = RunState::Running,
            _ => {}
        }
        Ok(())
    }

    /// Junction of speed limit `v` at arc length `s`: lower the limits there,
    /// or mark a full stop. Returns whether it stops.
    fn apply_junction(&mut self, v: f64, s: f64) -> bool {
        let g = self.profile.index_of(s);
        if v < self.cfg.junction_min_speed {
            self.stats.junctions_stopped += 1;
            self.profile.mark_stop(g);
            if g as f64 * self.profile.h() == s {
                self.profile.mark_stop(g - 1);
            }
            true
        } else {
            if v.is_finite() {
                self.stats.junctions_blended += 1;
            }
            self.profile.lower_cap(g, v);
            // Only the interval holding the junction: the one before it is in
            // use already and may only be lowered when the junction is its end.
            if g as f64 * self.profile.h() == s {
                self.profile.lower_cap(g - 1, v);
            }
            false
        }
    }

    /// Erode the limits from interval `from` on and run the backward pass.
    fn replan(&mut self, from: i64, changed_from: f64) {
        let h = self.profile.h();
        let window = self.filter_len as f64 * self.cfg.period;
        let erosion = if self.filter_len > 1 {
            Erosion {
                slope: h / window,
                feed_slope: h / (window * self.cfg.max_feed_override),
                cone_from: (!self.finished).then(|| libm::ceil(self.tail_s / h) as i64 - 1),
                // Every law is capped at the machine's top speed.
                top: self.cfg.max_path_speed,
            }
        } else {
            Erosion {
                slope: f64::INFINITY,
                feed_slope: f64::INFINITY,
                cone_from: None,
                top: self.cfg.max_path_speed,
            }
        };
        // Erosion reaches back as far as the cone of the highest limit.
        let back = if self.filter_len > 1 {
            let top = self.cfg.max_path_speed;
            libm::ceil(top / erosion.feed_slope.min(erosion.slope)) as i64 + 2
        } else {
            0
        };
        self.profile.erode(from - back, erosion);
        self.backward_pass(changed_from - back as f64 * h);
    }

    /// Backward pass over the grid nodes from the end of the queue. Stops
    /// early once it reaches nodes before `changed_from` whose limit did not change.
    fn backward_pass(&mut self, changed_from: f64) {
        let h = self.profile.h();
        let accel = self.cfg.planned_accel() * (1.0 - self.cfg.brake_reserve);
        let two_a_h = 2.0 * accel * h;
        let ovr_max = self.cfg.max_feed_override;
        let last = self.profile.index_of(self.tail_s);
        let first = self.profile.base();
        let mut segs = self.queue.iter().rev().peekable();
        let mut nearest_stop = self.tail_s;
        let mut next_v: Option<f64> = None; // limit at node g + 1 when it is before the stop
        let mut g = last;
        while g >= first {
            let x = g as f64 * h;
            // Stops at or after x: the nearest one constrains this node.
            while let Some(seg) = segs.peek() {
                if seg.s1() >= x {
                    if seg.stop_at_end {
                        nearest_stop = seg.s1();
                        next_v = next_v.filter(|_| (g + 1) as f64 * h <= nearest_stop);
                    }
                    segs.next();
                } else {
                    break;
                }
            }
            let mut v = self.profile.raw_node(g, ovr_max);
            v = v.min(libm::sqrt(2.0 * accel * (nearest_stop - x).max(0.0)));
            if let Some(vn) = next_v {
                v = v.min(libm::sqrt(vn * vn + two_a_h));
            }
            let old = self.profile.node(g);
            self.profile.set_node(g, v);
            if x < changed_from - h && old == v {
                break;
            }
            next_v = Some(v);
            g -= 1;
        }
    }

    /// One period: advance along the path and return the setpoint. Never
    /// allocates, locks or blocks.
    pub fn tick(&mut self) -> Setpoint {
        self.stats.ticks += 1;
        self.seq += 1;
        let ts = self.cfg.period;
        self.ramp_override();
        let mut delta = 0.0;
        let active = matches!(
            self.state,
            RunState::Running | RunState::Holding | RunState::Stopping
        );
        if active && !self.queue.is_empty() {
            if let Some(front) = self.queue.front() {
                self.block_id = front.block_id;
            }
            let d = self.reference_step();
            self.step_ref = d;
            self.push_window();
            let target = self.filtered();
            let c = target - self.s;
            if c > 0.0 {
                delta = self.advance(c);
            }
            if delta <= 0.0 {
                // At rest on a stop: continue past a corner, or end.
                self.settle_at_end();
            }
            if (self.hold || self.abort) && self.at_rest() {
                if self.abort {
                    self.flush();
                } else {
                    self.state = RunState::Holding;
                }
            }
        } else if active && self.abort {
            self.flush();
        }
        self.step = delta;
        Setpoint {
            seq: self.seq,
            time: self.seq as f64 * ts,
            axes: [
                self.point.x,
                self.point.y,
                self.point.z,
                self.abc[0],
                self.abc[1],
                self.abc[2],
            ],
            feed: delta / ts,
            u: self.u,
            s: self.s,
            block_id: self.block_id,
            state: self.state,
        }
    }

    #[inline]
    fn ramp_override(&mut self) {
        let step = self.cfg.override_rate * self.cfg.period;
        let d = self.override_cmd - self.override_now;
        self.override_now = if libm::fabs(d) <= step {
            self.override_cmd
        } else {
            self.override_now + step.copysign(d)
        };
    }

    /// The reference has stopped and the filter has drained.
    #[inline]
    fn at_rest(&self) -> bool {
        self.step_ref == 0.0
            && self
                .window
                .iter()
                .take(self.filter_len)
                .all(|&x| x == self.s_ref)
    }

    /// Abort finished: drop everything queued; idle where the machine stands.
    fn flush(&mut self) {
        self.queue.clear();
        self.abort = false;
        self.hold = false;
        self.finished = false;
        self.tail = self.point;
        self.tail_s = self.s;
        self.tail_derivs = None;
        self.s_ref = self.s;
        self.step_ref = 0.0;
        self.window = [self.s; MAX_FILTER];
        let g = self.profile.index_of(self.s);
        self.profile.reset_at(g);
        self.state = RunState::Idle;
    }

    /// Record the new reference position in the filter window.
    #[inline]
    fn push_window(&mut self) {
        self.window_head = (self.window_head + 1) % self.filter_len;
        self.window[self.window_head] = self.s_ref;
    }

    /// Mean of the window, taken relative to the newest position so that a
    /// window of equal positions gives that position exactly.
    #[inline]
    fn filtered(&self) -> f64 {
        let n = self.filter_len;
        let sum: f64 = self.window[..n].iter().map(|&x| x - self.s_ref).sum();
        self.s_ref + sum / n as f64
    }

    /// The reference schedule's step for this tick; moves `s_ref`.
    #[inline]
    fn reference_step(&mut self) -> f64 {
        let ts = self.cfg.period;
        let a = self.cfg.planned_accel() * ts * ts;
        let ab = a * (1.0 - self.cfg.brake_reserve);
        let ovr = self.override_now;
        let h = self.profile.h();
        let g0 = self.profile.index_of(self.s);
        self.profile.drop_before(g0);
        let s = self.s_ref;
        let g = self.profile.index_of(s);
        let mut cand = (self.step_ref + a).min(self.profile.limit(g, ovr) * ts);
        if self.hold || self.abort {
            cand = cand.min(self.step_ref - a);
        }
        let mut reach = stop_distance(cand, ab);
        // Grid nodes ahead within stopping distance.
        let last = self.profile.index_of(self.tail_s);
        let mut k = g + 1;
        while k <= last {
            let r = k as f64 * h - s;
            if r >= reach {
                break;
            }
            let w = self.profile.node(k).min(self.profile.raw_node(k, ovr)) * ts;
            if w < cand {
                cand = cand.min(brake_step(r, w, ab));
                reach = stop_distance(cand, ab);
            }
            k += 1;
        }
        // Stops (corners, end of queue) within stopping distance.
        let mut stop_at = f64::INFINITY;
        for seg in self.queue.iter() {
            let r = seg.s1() - s;
            if r < 0.0 {
                continue; // behind the reference
            }
            if seg.s0 - s >= reach {
                break;
            }
            if seg.stop_at_end {
                cand = cand.min(brake_step(r, 0.0, ab));
                reach = stop_distance(cand, ab);
                stop_at = stop_at.min(seg.s1());
            }
        }
        let lower = self.step_ref - a;
        if cand < lower {
            if !(self.hold || self.abort) {
                self.stats.brake_overruns += 1;
            }
            cand = lower;
        }
        let mut d = cand.max(0.0);
        // Land exactly on a stop within reach of round-off.
        if s + d + END_SNAP_TOL >= stop_at {
            d = stop_at - s;
            self.s_ref = stop_at;
        } else {
            self.s_ref = s + d;
        }
        d
    }

    /// Move the point by `delta` along the path, across segment ends. Returns
    /// the displacement actually made: `delta`, or less when landing on a stop
    /// (the chord to a stop can be shorter than the arc the schedule counted).
    fn advance(&mut self, mut delta: f64) -> f64 {
        let from = self.point;
        let commanded = delta;
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
            // counts, with the resolution of the coordinates) is landed on exactly.
            let lands = seg.stop_at_end && arc_left <= delta + END_SNAP_TOL;
            if (to_end <= delta && reachable) || lands {
                if seg.stop_at_end {
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
            self.state = if self.finished {
                RunState::Done
            } else {
                RunState::Idle
            };
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
            } else {
                self.state = if self.finished {
                    RunState::Done
                } else {
                    RunState::Idle
                };
            }
        }
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
