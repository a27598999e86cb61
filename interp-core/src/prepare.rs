//! Planning blocks off the real-time path, and what a plan carries to it.
//!
//! [`BlockPlanner`] (non-real-time) cuts each block at tangent breaks,
//! samples the feed laws onto the global arc-length grid of the look-ahead
//! [`Window`], prices the junctions (corners stop or slow the path), and
//! re-solves the planned speed from a freeze point (see [`crate::plan`]).
//! The result is a [`PlannedBlock`]: the block's segments and the new pieces
//! of the speed spline from the freeze point to the end of the queue. The
//! real-time side ([`crate::interp::Executor::commit`]) only copies it in.
//!
//! Blocks longer than [`CHUNK`] grid intervals are planned in parts cut at
//! fixed arc lengths of the run, so the plan never depends on when the parts
//! were made. A plan made against another end of the queue is refused with
//! [`PushError::Stale`].

use core::cell::Cell;

use crate::config::{ConfigError, InterpConfig};
use crate::feed::{
    ArcLengthDerivs, KNOT_JUMP_SHARE, MACHINE_LAW_PARTS, STATIONARY_JUMP_SHARE, feed_limit,
    junction_speed_with, machine_limit, machine_limit_parts, stationary_offset,
};
use crate::fiveaxis::{
    JointSample, Orientation, QueueEnd, joint_junction_speed, sample_joints, walk_joints,
};
use crate::geom::{Curve, Derivs, Vec3, golden_section_argmin};
use crate::interp::{JOIN_TOLERANCE, MAX_PIECES, PushError, grid_multiple};
use crate::kinematics::Machine;
use crate::nurbs::{Nurbs, Side};
use crate::path::{Blending, Block, Path};
use crate::plan::{
    AxisSample, CHUNK, Freeze, JumpReserve, Lift, MachinePlace, PlanError, SLIVER, WINDOW, Window,
    index_of, sample_interval,
};
use crate::spline::{Form, Piece};
use crate::stop::Stop;

/// A piece of a block in the real-time queue.
#[derive(Clone, Copy, Debug)]
pub struct Segment {
    /// Geometry.
    pub path: Path,
    /// Id of the block this piece belongs to.
    pub block_id: u32,
    /// Arc length of the run at the start of this segment, mm.
    pub s0: f64,
    /// Arc length of this segment, mm.
    pub length: f64,
    /// The path comes to rest at the end of this segment (a corner, an exact
    /// stop, or the end of what is queued): the speed spline has a rest
    /// point there.
    pub stop_at_end: bool,
    /// The block's rotary axes or tool axis (`crate::fiveaxis`).
    pub orientation: Option<Orientation>,
    /// Tangential acceleration and jerk (mm/s², mm/s³) a feed hold or
    /// abort may brake with on this segment: where a joint turns several
    /// units per mm, less than the path's (infinite for three-axis blocks).
    pub stop_limits: (f64, f64),
}

impl Segment {
    /// Under tool-centre-point control (the path is the tool tip)?
    #[inline]
    pub fn is_tcp(&self) -> bool {
        self.orientation.is_some_and(|o| o.is_tcp())
    }
    /// Arc length of the run at the end of this segment, mm.
    #[inline]
    pub fn s1(&self) -> f64 {
        self.s0 + self.length
    }
}

/// A plan for the real-time side: segments to queue (none for a re-plan of
/// the speed alone) and the speed spline from `from_x` to the end of the queue.
///
/// About 80 KiB: keep it in a reused buffer (a `Box` recycled through a
/// queue in the daemon), not on a small stack.
#[derive(Clone, Debug)]
pub struct PlannedBlock {
    /// The block's id (0 for a re-plan).
    pub(crate) id: u32,
    /// End of the queue it was planned against (where its segments start),
    /// and the run's arc length there.
    pub(crate) tail: Vec3,
    pub(crate) s0: f64,
    /// Arc length of the run at its end, and its end point.
    pub(crate) s1: f64,
    pub(crate) end: Vec3,
    /// Segments (cut at tangent breaks), in order.
    pub(crate) segments: [Option<Segment>; MAX_PIECES],
    pub(crate) n_segments: usize,
    /// The last queued segment before these comes to rest at its end
    /// (a corner or an exact stop at the join).
    pub(crate) stop_at_join: bool,
    /// The next part of the block before it (a long block is planned in
    /// parts): the join is no junction of the program.
    pub(crate) continues: bool,
    /// The spline update: pieces from `from_x` on, the first starting at rest
    /// when `rest_start`.
    pub(crate) from_x: f64,
    pub(crate) rest_start: bool,
    pub(crate) pieces: [Piece; WINDOW],
    pub(crate) rests: [bool; WINDOW],
    pub(crate) n_pieces: usize,
    /// The program ends with this plan: reaching the end of the queue then
    /// means `Done` ([`crate::driver::Driver::finish`]).
    pub(crate) finish: bool,
    /// A feed hold's plan ([`BlockPlanner::hold`]): the executor leaves the
    /// closed-form stop it began for the hold (if it has not moved on it)
    /// and follows this plan to its rest point.
    pub(crate) hold: bool,
}

impl Default for PlannedBlock {
    fn default() -> Self {
        Self::new()
    }
}

impl PlannedBlock {
    /// An empty plan (a buffer for [`BlockPlanner::plan`]).
    pub fn new() -> Self {
        PlannedBlock {
            id: 0,
            tail: Vec3::zeros(),
            s0: 0.0,
            s1: 0.0,
            end: Vec3::zeros(),
            segments: [None; MAX_PIECES],
            n_segments: 0,
            stop_at_join: false,
            continues: false,
            from_x: 0.0,
            rest_start: true,
            pieces: [Piece::default(); WINDOW],
            rests: [false; WINDOW],
            n_pieces: 0,
            finish: false,
            hold: false,
        }
    }
    /// Id of the planned block (0: a re-plan of the speed only).
    pub fn id(&self) -> u32 {
        self.id
    }
    /// Segments it adds to the queue.
    pub fn segments(&self) -> usize {
        self.n_segments
    }
    /// Arc length of the run at its start and end, mm.
    pub fn arc_range(&self) -> (f64, f64) {
        (self.s0, self.s1)
    }
    /// Pieces of the speed spline it replaces from its freeze point on.
    pub fn intervals(&self) -> usize {
        self.n_pieces
    }
    /// The segments, in order.
    pub(crate) fn pieces_geometry(&self) -> impl Iterator<Item = &Segment> {
        self.segments[..self.n_segments].iter().flatten()
    }
}

/// The planning half of the interpolator: tracks where the queue ends,
/// holds the look-ahead window, and plans each block against it (non-real-time).
///
/// About 5.2 MiB: box it.
#[derive(Clone, Debug)]
pub struct BlockPlanner {
    cfg: InterpConfig,
    h: f64,
    tail: Vec3,
    tail_s: f64,
    /// Derivatives (order 3) at the end of the last planned block.
    tail_derivs: Option<Derivs>,
    /// The last planned block asks to stop at its end (G61.1).
    tail_exact_stop: bool,
    /// The orientation of the last planned block if it turns in place: a
    /// turn is entered and left at rest, but its own parts join smoothly.
    tail_turn: Option<Orientation>,
    window: Window,
    /// The rest of a block longer than a part.
    pending: Option<Block>,
    /// The chunk mark the part being (or last) planned was cut off, onto a
    /// knot of its curve a hair away (see [`cut_at_mark`]): that part's
    /// plan reaches its end, and the next part is cut at the next mark.
    snapped_cut: Option<f64>,
    /// The queue ends at a cut of a long block inside a smooth stretch of
    /// its curve ([`cut_is_smooth`]): the next part, the block's rest, joins
    /// it without a junction, as the uncut curve would. (Each part's own
    /// derivatives at the cut differ by round-off: taken as a junction's
    /// step they reserved axis jerk around every such cut, and next to a
    /// knot's sliver limited the speed, to 86.3 mm/s where the scroll
    /// `curva_scrool_f` allows 91.1.)
    tail_cut_smooth: bool,
    /// Where the machine may be when the next plan is committed, and whether
    /// it is at rest there ([`Self::set_machine`]).
    machine: f64,
    machine_at_rest: bool,
    ovr: f64,
    /// The braking curve a lowered override was planned with (see
    /// [`Self::replan`]): every later solve keeps the feed limits above it
    /// up to where that plan came down to the new feed limit, until the
    /// machine is there, for the machine may still be braking (without it,
    /// the next block's solve found the kept state above the new feed limit
    /// and failed to a crawl; past that point the new feed holds).
    lift: Option<Lift>,
    /// A hold's rest, and where the plan ended before the hold's plan ended
    /// it there ([`Self::hold`]): the rest is planned once the machine is
    /// there ([`Self::plan_after_hold`]), or through it when the hold is
    /// resumed while the machine brakes ([`Self::resume_hold`]).
    after_hold: Option<AfterHold>,
    /// Where the current plan of the speed ends (a rest point): the end of
    /// the queue once the program is finished, else the last chunk mark the
    /// queue has passed (see [`Self::plan`]).
    planned_to: f64,
    /// The program's end was given ([`Self::finish`]): plans reach the end of the queue.
    finished: bool,
    /// The last block measured and its length: a block refused for room is
    /// offered again every tick, and a NURBS's length costs a quadrature.
    length_memo: Option<(Block, f64)>,
    /// The last part refused and what refused it, with everything its
    /// planning depends on (see [`Self::plan_part`]).
    refused: Option<(Refusal, PushError)>,
    /// The five-axis machine, if configured, and the joints, frame and
    /// joint rates at the end of the queue (`crate::fiveaxis`).
    machine_kin: Option<Machine>,
    five: QueueEnd,
}

impl BlockPlanner {
    /// A planner for a queue that ends at `tail` (X Y Z), arc length `tail_s`
    /// of the run, with the machine at rest there.
    pub fn new(cfg: InterpConfig, tail: Vec3, tail_s: f64) -> Result<Self, ConfigError> {
        cfg.validate()?;
        if !(tail.iter().all(|c| c.is_finite()) && tail_s.is_finite()) {
            return Err(ConfigError::OutOfRange("position"));
        }
        let h = crate::interp::grid_step(&cfg);
        // (Computed before the literal, which then builds in place: the
        // planner is over a MiB.)
        let machine_kin = cfg.machine.and_then(|m| Machine::new(m).ok());
        let five = QueueEnd::new([tail.x, tail.y, tail.z, 0.0, 0.0, 0.0]);
        Ok(BlockPlanner {
            cfg,
            h,
            tail,
            tail_s,
            tail_derivs: None,
            tail_exact_stop: false,
            tail_turn: None,
            window: Window::new(cfg, h, tail_s),
            pending: None,
            snapped_cut: None,
            tail_cut_smooth: false,
            machine: tail_s,
            machine_at_rest: true,
            ovr: 1.0,
            lift: None,
            after_hold: None,
            planned_to: tail_s,
            finished: false,
            length_memo: None,
            refused: None,
            machine_kin,
            five,
        })
    }
    /// The configuration it plans for.
    pub fn config(&self) -> &InterpConfig {
        &self.cfg
    }
    /// Where the next block must start.
    pub fn tail(&self) -> Vec3 {
        self.tail
    }
    /// The joints at the end of the queue, where the rotary axes stand
    /// for the next block (`[X, Y, Z, A, B, C]`).
    pub fn tail_joints(&self) -> [f64; 6] {
        self.five.joints
    }
    /// Set where the rotary axes stand at the end of the queue (degrees;
    /// the queue's X Y Z are its tail), e.g. where the machine starts.
    pub fn set_rotary(&mut self, abc: [f64; 3]) {
        self.five.joints[3..].copy_from_slice(&abc);
    }
    /// Arc length of the run where the next block starts, mm.
    pub fn tail_s(&self) -> f64 {
        self.tail_s
    }
    /// The look-ahead window.
    pub fn window(&self) -> &Window {
        &self.window
    }
    /// The look-ahead window, to set its diagnostics.
    pub fn window_mut(&mut self) -> &mut Window {
        &mut self.window
    }
    /// A block longer than one part is still being planned: call
    /// [`Self::plan_pending`] (when the real-time side has room) before the next block.
    pub fn has_pending(&self) -> bool {
        self.pending.is_some()
    }
    /// The rest of a long block still to be planned, if any.
    pub fn pending(&self) -> Option<&Block> {
        self.pending.as_ref()
    }
    /// Feed override the plans are made for.
    pub fn feed_override(&self) -> f64 {
        self.ovr
    }

    /// Set the feed override for the next plans (without re-planning now).
    pub fn set_feed_override(&mut self, ovr: f64) {
        self.ovr = ovr;
    }

    /// Tell the planner where the machine may be (arc length of the run)
    /// when the next plan is committed, and whether it rests there. The
    /// freeze point of a re-solve is always after it.
    pub fn set_machine(&mut self, s: f64, at_rest: bool) {
        self.machine = s;
        self.machine_at_rest = at_rest;
    }

    /// Forget the intervals and rest points behind the machine, at arc
    /// length `machine` (see [`Window::release_before`]). Once a tick,
    /// before its planning ([`crate::Driver::drive`]), and nowhere else:
    /// whether a rest point the machine just passed is still held changes
    /// the next plan (no sample is taken across it), so releasing as a
    /// refused push tried (the service retries one between commands, a
    /// replay does not) would plan differently from the same commands
    /// given at the same ticks.
    pub fn release_behind(&mut self, machine: f64) {
        self.window.release_before(machine);
    }

    /// Whether a crawl ahead of the machine is due to be planned again
    /// (`machine`: where it may be; [`Window::take_crawl_retry`]), to be
    /// planned with [`Self::replan`].
    pub fn take_crawl_retry(&mut self, machine: f64) -> bool {
        self.window.take_crawl_retry(machine)
    }

    /// Move the queue end (after an abort: where the machine stopped, the
    /// last setpoint's X Y Z and `s`). Forgets everything planned.
    pub fn resync(&mut self, tail: Vec3, tail_s: f64) {
        self.tail = tail;
        self.tail_s = tail_s;
        self.tail_derivs = None;
        self.tail_exact_stop = false;
        self.tail_turn = None;
        self.pending = None;
        self.snapped_cut = None;
        self.tail_cut_smooth = false;
        self.machine = tail_s;
        self.machine_at_rest = true;
        self.planned_to = tail_s;
        self.finished = false;
        self.refused = None;
        self.lift = None;
        self.after_hold = None;
        self.window.reset(tail_s);
        let abc = [
            self.five.joints[3],
            self.five.joints[4],
            self.five.joints[5],
        ];
        self.five = QueueEnd::new([tail.x, tail.y, tail.z, abc[0], abc[1], abc[2]]);
    }

    /// Where the current plan of the speed ends, mm.
    pub fn planned_to(&self) -> f64 {
        self.planned_to
    }

    /// Is part of the queue not planned yet (past the last chunk mark)? At
    /// the program's end, even a remnant shorter than a sliver: the machine
    /// would wait short of it for good (the last moves of 115 nm and 1 nm
    /// after a plan to a block's end).
    pub fn has_unplanned(&self) -> bool {
        let sliver = if self.finished { 0.0 } else { SLIVER * self.h };
        self.tail_s > self.planned_to + sliver
    }

    /// The program ends with what is queued: plan the speed to its end.
    /// `out` gets no segments, only the speed (maybe none, if all is planned).
    pub fn finish(&mut self, out: &mut PlannedBlock) -> Result<(), PushError> {
        self.finished = true;
        self.plan_ahead(out)
    }

    /// Plan the speed to the end of what is queued now (the machine would
    /// otherwise run short of plan: the queue starves, or the program ends).
    pub fn plan_ahead(&mut self, out: &mut PlannedBlock) -> Result<(), PushError> {
        self.speed_only(out);
        if !self.has_unplanned() {
            return Ok(());
        }
        let freeze = self.freeze();
        let end = self.tail_s;
        self.solve_into(freeze, end, None, true, out)?;
        self.planned_to = end;
        Ok(())
    }

    /// `out` as a plan without segments.
    pub(crate) fn speed_only(&self, out: &mut PlannedBlock) {
        out.id = 0;
        out.tail = self.tail;
        out.s0 = self.tail_s;
        out.s1 = self.tail_s;
        out.end = self.tail;
        out.n_segments = 0;
        out.stop_at_join = false;
        out.n_pieces = 0;
        out.hold = false;
    }

    /// Plan `block` (or, if it is longer than a part, its first part) into
    /// `out` against the current queue end and move the end past it. On
    /// error `out` is unspecified and nothing moved.
    pub fn plan(&mut self, block: &Block, out: &mut PlannedBlock) -> Result<(), PushError> {
        if self.pending.is_some() {
            return Err(PushError::Pending);
        }
        if !(block.feed.is_finite() && block.feed > 0.0) {
            return Err(PushError::Feed);
        }
        // A block in the other frame (tool tip or machine X Y Z) starts at
        // the same machine pose seen in its frame.
        let tail = self
            .five
            .start_for(self.machine_kin.as_ref(), block.is_tcp(), self.tail)
            .map_err(PushError::Kinematics)?;
        if let Some(o) = &block.orientation {
            self.five
                .check_join(self.machine_kin.as_ref(), o, block.path.u_start())
                .map_err(PushError::Kinematics)?;
        }
        let gap = (block.start_position() - tail).norm();
        if !(gap <= JOIN_TOLERANCE) {
            return Err(PushError::Discontinuous { gap });
        }
        let length = match &self.length_memo {
            Some((b, l)) if b == block => *l,
            _ => {
                let l = block.path.length();
                self.length_memo = Some((*block, l));
                l
            }
        };
        if !(length > 0.0 && length.is_finite()) {
            return Err(PushError::Empty);
        }
        // Cut at the next chunk mark if the block reaches past it.
        let chunk = CHUNK as f64 * self.h;
        // Refuse early (before any splitting) when not even one part fits yet.
        let reach = (length.min(chunk) + self.tail_s) / self.h;
        if !self
            .window
            .has_room(libm::floor(reach) as i64 + 1, 2, self.machine)
        {
            return Err(PushError::ProfileFull);
        }
        // (A part cut at a mark ends there only up to round-off: count it as reached.)
        let mut mark = (libm::floor(self.tail_s / chunk + 1e-6) + 1.0) * chunk;
        // The last cut, at this mark, moved onto a knot just before it; or
        // the block starts a hair before the mark (a quarter grid step or
        // less): cut at the next mark instead, for a part that short would
        // be a sliver of its curve, whose derivatives lose their digits
        // ([`cut_at_mark`]).
        if self.snapped_cut == Some(mark) || mark - self.tail_s <= CUT_SNAP_STEPS * self.h {
            mark += chunk;
        }
        let mut snapped = None;
        let mut cut = None;
        let (part, rest) = if self.tail_s + length > mark + self.h {
            let u = block
                .path
                .param_at_arc_length(block.path.u_start(), mark - self.tail_s);
            let u = match cut_at_mark(&block.path, u, self.h) {
                Some(k) => {
                    snapped = Some(mark);
                    k
                }
                None => u,
            };
            match block.path.split_at(u) {
                Ok((a, b)) => {
                    cut = Some(u);
                    (
                        Block { path: a, ..*block },
                        Some(Block { path: b, ..*block }),
                    )
                }
                Err(_) => (*block, None),
            }
        } else {
            (*block, None)
        };
        let last_cut = core::mem::replace(&mut self.snapped_cut, snapped);
        if let Err(e) = self.plan_part(&part, out) {
            self.snapped_cut = last_cut;
            return Err(e);
        }
        out.continues = false;
        self.tail_cut_smooth = cut.is_some_and(|u| cut_is_smooth(&block.path, u));
        self.pending = rest;
        Ok(())
    }

    /// Plan the next part of a long block (see [`Self::has_pending`]).
    pub fn plan_pending(&mut self, out: &mut PlannedBlock) -> Result<(), PushError> {
        let Some(b) = self.pending.take() else {
            return Ok(());
        };
        match self.plan(&b, out) {
            Ok(()) => {
                out.continues = true;
                Ok(())
            }
            Err(e) => {
                self.pending = Some(b);
                Err(e)
            }
        }
    }

    /// Re-plan the speed from where the machine may be (see
    /// [`Self::set_machine`]) with feed override `ovr`; `state` is the
    /// machine's speed and acceleration at the freeze point's side (for an
    /// override that drops faster than the machine can brake). No segments.
    pub fn replan(&mut self, ovr: f64, out: &mut PlannedBlock) -> Result<(), PushError> {
        self.speed_only(out);
        // If no re-solve finds a plan, the current one stays (rather than
        // crawl) where it is good enough: under a raised override it is
        // within the new feed limits (the later solves, from near its end,
        // take the new feed); braking to a hold's rest point, the machine
        // slows to rest anyway, and what follows the rest point (from rest,
        // or through it on a resume) is solved with the new feed.
        let keep_plan = ovr > self.ovr || self.after_hold.is_some();
        self.ovr = ovr;
        // From the machine on (not only the plan's end): the new feed counts everywhere ahead.
        let freeze = self.window.freeze_after(self.machine, self.machine_at_rest);
        // The speed and acceleration the plan has at the freeze point: the
        // new feed limit may not fall below what braking from there allows.
        let end = self.planned_to;
        let Freeze::At(f) = freeze else {
            // From rest: nothing to brake.
            self.lift = None;
            return self.solve_into(freeze, end, None, true, out);
        };
        // The new feed limit may not fall below what braking allows from
        // where the unknowns start (the end of the kept freeze piece `f`),
        // from the fastest and most accelerating state the kept piece
        // allows there (the knot's value also depends on the next unknown).
        // The spline follows a braking curve only approximately: if the
        // linear program cannot, brake more gently (the override takes a
        // little longer to take effect) rather than keep the old plan.
        // A piece or two later (as planned) at the steepest rate comes
        // before the gentler rates (`plan::LATER_FREEZES`): a freeze piece
        // no rate can continue from cost all six solves before it, and a
        // kept plan cost them too (a raised override at a ramp into a rest
        // point, which its kept neighbour and its own jerk pin to the value
        // it has: a plan through the later freeze found, the service's
        // planning thread 50 ms late).
        let after_f = self.window.n_pieces().saturating_sub(f + 1);
        let later = self.window.later_freezes.min(after_f);
        let tries = core::iter::once((f, LIFT_SOFTENING[0]))
            .chain((1..=later).map(|k| (f + k, 1.0)))
            .chain(LIFT_SOFTENING[1..].iter().map(|&gentle| (f, gentle)));
        let n_tries = LIFT_SOFTENING.len() + later;
        let mut r = Ok(());
        for (k, (g, gentle)) in tries.enumerate() {
            let p = self.window.piece(g);
            let stop = self.braking(&p, gentle);
            let last = k + 1 == n_tries && !keep_plan;
            let lift = Lift {
                at: p.x1(),
                stop,
                until: f64::INFINITY,
            };
            r = self.solve_into(Freeze::At(g), end, Some(lift), last, out);
            if !matches!(r, Err(PushError::Schedule)) {
                break;
            }
        }
        r
    }

    /// The braking from the end of the kept freeze piece `p`, from the
    /// fastest and most accelerating state `p` allows there (the knot's
    /// value also depends on the next unknown), with the planned jerk and
    /// acceleration times `gentle`: gentler in jerk, but from the
    /// acceleration the machine has (clamped to a softened limit, the
    /// curve's speed rose less than the machine's must while its
    /// acceleration ramps down, and every level failed to a crawl when the
    /// override fell as the machine accelerated).
    fn braking(&self, p: &Piece, gentle: f64) -> Stop {
        let v0 = libm::sqrt(p.e0.max(p.d).max(p.e1).max(0.0));
        let a0 = p.accel_max().max(0.0);
        let (a, j) = (self.cfg.planned_accel(), self.cfg.planned_jerk());
        Stop::new(v0, a0, (a * gentle).max(a0), j * gentle)
    }

    /// Plan a feed hold from where the machine may be (see
    /// [`Self::set_machine`]): the speed comes to rest at a new rest point,
    /// planned with every row of the look-ahead, the per-axis jerk ones
    /// included. (The executor's closed-form stop brakes with the
    /// tangential limits alone: on a tight turn where an axis's jerk binds
    /// at a steady speed, braking adds to it and passes its limit.) The
    /// rest point is where the tangential stop from the state at the end of
    /// the kept freeze piece ends, braking more gently (the hold takes a
    /// little longer) where the linear program cannot follow that stop. The
    /// plan ends there; the next plans (the guard's) start from rest there,
    /// as from a corner, and a resume goes on along them. No segments.
    ///
    /// Returns where the machine will rest. `out` has no pieces when it
    /// rests already, or its plan rests before a hold could stop it (at a
    /// corner, or at the plan's end: it holds there). On error nothing
    /// changed: the executor's closed-form stop stays.
    pub fn hold(&mut self, out: &mut PlannedBlock) -> Result<f64, PushError> {
        self.speed_only(out);
        let freeze = self.window.freeze_after(self.machine, self.machine_at_rest);
        let f = match freeze {
            Freeze::At(f) => f,
            Freeze::Rest(x) => {
                out.hold = true;
                return Ok(if self.machine_at_rest {
                    self.machine
                } else {
                    x
                });
            }
        };
        let p = self.window.piece(f);
        let rest = self.window.next_rest(self.machine);
        let mut r = Err(PushError::Schedule);
        for (k, gentle) in LIFT_SOFTENING.into_iter().enumerate() {
            let x = p.x1() + self.braking(&p, gentle).distance();
            if x >= rest {
                self.window.totals.holds += 1;
                out.hold = true;
                return Ok(rest);
            }
            if !self.window.insert_rest_point(x) {
                return Err(PushError::ProfileFull);
            }
            // Solved to the rest point only: a small program (even when
            // softened, tried up to six times), so a hold is planned within
            // the service's lead. The rest of the look-ahead is planned once
            // the machine rests there ([`Self::plan_after_hold`]).
            r = self.solve_into(freeze, x, None, false, out).map(|()| x);
            if r.is_ok() {
                let was = self.after_hold.map_or(self.planned_to, |a| a.end);
                self.after_hold = Some(AfterHold {
                    rest: x,
                    end: was.max(self.planned_to),
                    resume_tried: false,
                });
                self.planned_to = x;
                self.window.totals.holds += 1;
                self.window.totals.holds_softened += u64::from(k > 0);
                break;
            }
            self.window.remove_rest_point(x);
            if !matches!(r, Err(PushError::Schedule)) {
                break;
            }
        }
        if r.is_err() {
            self.window.totals.holds_unplanned += 1;
        }
        out.hold = r.is_ok();
        r
    }

    /// Where a hold's plan ended the plan, short of where it ended before
    /// ([`Self::plan_after_hold`] is due once the machine is there).
    pub fn hold_rest(&self) -> Option<f64> {
        self.after_hold.map(|a| a.rest)
    }

    /// A hold whose plan ends at its rest point was resumed while the
    /// machine brakes to it: the rest point goes, and the speed is planned
    /// again from the first piece after the machine on (as for a new feed
    /// override, [`Self::replan`]) through it, to where the plan ended
    /// before the hold. Tried once per hold: `Ok(false)` when not tried, as
    /// when the machine brakes too near rest to turn its braking around
    /// before the rest point (it rests there first, then
    /// [`Self::plan_after_hold`]). On error nothing changed (it rests there
    /// too).
    pub fn resume_hold(&mut self, out: &mut PlannedBlock) -> Result<bool, PushError> {
        self.speed_only(out);
        let Some(after) = self.after_hold.filter(|a| !a.resume_tried) else {
            return Ok(false);
        };
        self.after_hold = Some(AfterHold {
            resume_tried: true,
            ..after
        });
        // Only where the machine can turn its braking around well above
        // rest, before the rest point: at the end of the kept pieces, the
        // speed the jerk takes to bring its deceleration to zero is at most
        // half its speed. (Nearer the rest, the linear program without the
        // rest point often fails or crawls, and a crawl is slower than the
        // stop.)
        let freeze = self.window.freeze_after(self.machine, self.machine_at_rest);
        let turns = match freeze {
            Freeze::At(f) => {
                let p = self.window.piece(f);
                let (v, a) = (libm::sqrt(p.e1.max(0.0)), p.accel(p.h).min(0.0));
                p.form == Form::Quadratic
                    && p.x1() < after.rest
                    && a * a <= self.cfg.planned_jerk() * v
            }
            Freeze::Rest(_) => false,
        };
        if !turns {
            return Ok(false);
        }
        let planned_to = self.planned_to;
        let end = after.end.max(planned_to);
        self.window.remove_rest_point(after.rest);
        // (No crawl as a last resort: the hold's stop is the fallback.)
        match self.solve_into(freeze, end, None, false, out) {
            Ok(()) => {
                self.planned_to = end;
                self.after_hold = None;
                Ok(true)
            }
            Err(e) => {
                // (Where it was: removed, so there is room.)
                self.window.insert_rest_point(after.rest);
                Err(e)
            }
        }
    }

    /// Plan the speed from a hold's rest point on, to where the plan ended
    /// before the hold (no pieces when a later plan reached it already).
    pub fn plan_after_hold(&mut self, out: &mut PlannedBlock) -> Result<(), PushError> {
        self.speed_only(out);
        let Some(AfterHold { end, .. }) = self.after_hold.take() else {
            return Ok(());
        };
        if end > self.planned_to + SLIVER * self.h {
            let freeze = self.freeze();
            self.solve_into(freeze, end, None, true, out)?;
            self.planned_to = end;
        }
        Ok(())
    }

    /// The braking curve of the last lowered override while the machine may
    /// still be on it (see [`Self::lift`]).
    fn lift_ahead(&mut self) -> Option<Lift> {
        if self.lift.is_some_and(|l| self.machine >= l.until) {
            self.lift = None;
        }
        self.lift
    }

    /// Where a solve of what is queued starts (see [`Window::freeze`]); not
    /// before a hold's rest point while the machine brakes to it: the plan
    /// to it stays (the machine rests there either way), and a steepest
    /// stop planned again under the rows of a longer program can find no
    /// plan at all (a block pushed while `serve` braked for a hold failed
    /// every pass there and crawled).
    fn freeze(&self) -> Freeze {
        let freeze = self.window.freeze(self.machine, self.machine_at_rest);
        let (Some(rest), Freeze::At(f)) = (self.hold_rest(), freeze) else {
            return freeze;
        };
        // The piece that ends at the rest point (pieces are cut there, and
        // none is shorter than a sliver).
        let near = rest - SLIVER * self.h;
        (f..self.window.n_pieces())
            .find(|&k| self.window.piece(k).x1() >= near)
            .map_or(freeze, Freeze::At)
    }

    fn solve_into(
        &mut self,
        freeze: Freeze,
        end: f64,
        lift: Option<Lift>,
        fallback: bool,
        out: &mut PlannedBlock,
    ) -> Result<(), PushError> {
        // A new override's braking curve holds from now on; any other
        // solve keeps the last one's.
        let new_lift = lift.is_some();
        let lift = if new_lift { lift } else { self.lift_ahead() };
        let from = self
            .window
            .solve(freeze, end, self.ovr, lift, self.machine, fallback)
            .map_err(|e| match e {
                PlanError::Full => PushError::ProfileFull,
                PlanError::Solver(_) => PushError::Schedule,
            })?;
        if let (true, Some(l)) = (new_lift, lift) {
            let until = self.window.braking_end(from, self.ovr);
            self.lift = Some(Lift { until, ..l });
        }
        let n = self.window.n_pieces();
        out.n_pieces = 0;
        out.from_x = if from < n {
            self.window.piece(from).x0
        } else {
            self.tail_s
        };
        out.rest_start = from >= n || self.window.rest_start(from);
        for i in from..n {
            out.pieces[out.n_pieces] = self.window.piece(i);
            out.rests[out.n_pieces] = self.window.rest_start(i);
            out.n_pieces += 1;
        }
        Ok(())
    }

    /// Plan `block` (a part of at most a chunk) onto the queue. All or
    /// nothing: a refused block leaves the window as it was, so that the
    /// next attempt (the caller retries every tick while the look-ahead is
    /// full) samples it afresh. Asked for again before anything it depends
    /// on moved, it gets the same answer without planning it again:
    /// planning is a function of the window, the queue end, and where the
    /// machine is among the pieces, intervals and rest points.
    fn plan_part(&mut self, block: &Block, out: &mut PlannedBlock) -> Result<(), PushError> {
        let key = Refusal {
            block: *block,
            tail_s: self.tail_s,
            planned_to: self.planned_to,
            machine: self.window.machine_place(self.machine),
            at_rest: self.machine_at_rest,
            ovr: self.ovr,
            finished: self.finished,
            solves: (self.window.totals.solves, self.window.totals.crawled),
        };
        if let Some((k, e)) = &self.refused
            && *k == key
        {
            return Err(*e);
        }
        let mark = self.window.mark(self.tail_s);
        let r = self.sample_and_plan(block, out);
        match r {
            Ok(()) => self.refused = None,
            Err(e) => {
                self.window.roll_back(&mark);
                self.refused = Some((key, e));
            }
        }
        r
    }

    fn sample_and_plan(&mut self, block: &Block, out: &mut PlannedBlock) -> Result<(), PushError> {
        let cfg = self.cfg;
        let mut pieces = [block.path; MAX_PIECES];
        let mut singular = [false; MAX_PIECES + 1];
        let n_pieces = split_at_tangent_breaks(
            &block.path,
            &mut pieces,
            cfg.tangent_tolerance,
            cfg.chord_tolerance,
            &mut singular,
        )?;
        let mut lengths = [0.0; MAX_PIECES];
        let mut total = 0.0;
        for (len, piece) in lengths.iter_mut().zip(&pieces[..n_pieces]) {
            *len = piece.length();
            if !(*len > 0.0 && len.is_finite()) {
                return Err(PushError::Empty);
            }
            total += *len;
        }
        // Where a piece starts or ends at a stationary point (C' = 0), its laws
        // are taken a tick's distance inside (feed::stationary_offset).
        let mut windows = [(0.0, 0.0); MAX_PIECES];
        for (k, w) in windows.iter_mut().enumerate().take(n_pieces) {
            *w = law_window(
                &pieces[k],
                lengths[k],
                (singular[k], singular[k + 1]),
                block,
                &cfg,
            );
        }
        let h = self.h;
        let hs = h / (cfg.law_samples_per_interval as i64 * grid_multiple(&cfg)) as f64;
        // Five-axis: the whole block within the machine's reach, before the
        // window changes (the joints walked from the end of the queue).
        let switch = self.five.tcp != block.is_tcp();
        if let Some(o) = &block.orientation {
            let mut q = self.five.joints;
            let mut s = self.tail_s;
            for (k, piece) in pieces[..n_pieces].iter().enumerate() {
                walk_joints(
                    self.machine_kin.as_ref(),
                    o,
                    piece,
                    s,
                    lengths[k],
                    hs,
                    &mut q,
                )
                .map_err(PushError::Kinematics)?;
                s += lengths[k];
            }
        }
        let g_last = index_of(self.tail_s + total, h) + 1;
        if !self.window.has_room(g_last, n_pieces + 2, self.machine) {
            return Err(PushError::ProfileFull);
        }
        // From here on nothing fails but the solve (which leaves the window
        // as it was on a fallback, and may only refuse for capacity).
        out.id = block.id;
        out.tail = self.tail;
        out.s0 = self.tail_s;
        out.hold = false;
        self.window.extend_to(g_last);
        // The junction with what is queued before.
        out.stop_at_join = false;
        if let Some(left) = self.tail_derivs.filter(|_| !self.tail_cut_smooth) {
            let entry = block.path.eval(windows[0].0, 3);
            // A turn in place is entered and left at rest (its measure is
            // degrees, not the path's millimetres), but its parts (a long
            // turn is planned in parts) join as one line.
            let turn_join = (self.tail_turn.is_some() || block.is_in_place())
                && self.tail_turn != block.orientation;
            let v = if self.tail_exact_stop || switch || turn_join {
                // (A change of frame is a rest point: the machine stands
                // while tool-centre-point control goes on or off.)
                0.0
            } else {
                junction_speed_with(&left, &entry, &cfg, jump_share(singular[0]))
            };
            let v = v.min(self.joint_junction(block, &left, &entry));
            // (A block starting at a stationary point has its laws taken
            // that far inside: the junction's limit covers the stretch.)
            let slack = pieces[0].arc_length(pieces[0].u_start(), windows[0].0);
            if self.apply_junction(v, self.tail_s, slack) {
                out.stop_at_join = true;
            } else {
                let h = self.h;
                let share = jump_share(singular[0]);
                junction_samples(
                    &mut self.window,
                    self.tail_s,
                    &left,
                    &entry,
                    v,
                    share,
                    h,
                    &cfg,
                );
            }
        }
        out.n_segments = n_pieces;
        let mut s = self.tail_s;
        let mut joints = self.five.joints;
        let mut q_s_end = None;
        for (k, piece) in pieces[..n_pieces].iter().enumerate() {
            if k > 0 {
                // A tangent break inside the block.
                let left = pieces[k - 1].eval(windows[k - 1].1, 3);
                let right = piece.eval(windows[k].0, 3);
                let share = jump_share(singular[k]);
                let v = junction_speed_with(&left, &right, &cfg, share);
                // The laws are not sampled within the windows' offsets of a
                // stationary point: the junction's limit covers them.
                let prev = &pieces[k - 1];
                let slack = prev
                    .arc_length(windows[k - 1].1, prev.u_end())
                    .max(piece.arc_length(piece.u_start(), windows[k].0));
                let stop = self.apply_junction(v, s, slack);
                if !stop {
                    let h = self.h;
                    junction_samples(&mut self.window, s, &left, &right, v, share, h, &cfg);
                }
                if let Some(prev) = out.segments[k - 1].as_mut() {
                    prev.stop_at_end = stop;
                }
            }
            let seg = Segment {
                path: *piece,
                block_id: block.id,
                s0: s,
                length: lengths[k],
                stop_at_end: false,
                orientation: block.orientation,
                stop_limits: (f64::INFINITY, f64::INFINITY),
            };
            sample_laws(&seg, windows[k], block, &cfg, &mut self.window, h);
            let mut seg = seg;
            if let Some(o) = &block.orientation {
                (q_s_end, seg.stop_limits) = sample_joints(
                    self.machine_kin.as_ref(),
                    o,
                    piece,
                    s,
                    seg.length,
                    &cfg,
                    &mut self.window,
                    h,
                    hs,
                    &mut joints,
                );
            }
            s += seg.length;
            out.segments[k] = Some(seg);
        }
        if let Some(last) = out.segments[n_pieces - 1].as_mut() {
            // The end of the queue is a rest point until more comes.
            last.stop_at_end = true;
        }
        let last = &pieces[n_pieces - 1];
        let saved = (
            self.tail,
            self.tail_s,
            self.tail_derivs,
            self.tail_exact_stop,
        );
        let saved_five = (self.five, self.tail_turn);
        if block.orientation.is_none() {
            // A three-axis block: X Y Z of the machine, rotary axes kept.
            let e = block.path.end_point();
            joints[..3].copy_from_slice(&[e.x, e.y, e.z]);
        }
        self.five = QueueEnd {
            joints,
            tcp: block.is_tcp(),
            q_s: q_s_end,
        };
        out.end = block.end_position();
        out.s1 = s;
        self.tail = out.end;
        self.tail_s = s;
        self.tail_derivs = Some(last.eval(windows[n_pieces - 1].1, 3));
        self.tail_exact_stop = block.blending == Blending::ExactStop;
        self.tail_turn = block.orientation.filter(|o| o.fixed().is_some());
        self.window.set_tail(s);
        // The speed is planned when the queue passes a chunk mark (to that
        // mark, a provisional rest point), so the plan depends on the path
        // alone, not on how it was cut into blocks; the program's end and a
        // starving machine have it planned further ([`Self::finish`],
        // [`Self::plan_ahead`]).
        let chunk = CHUNK as f64 * self.h;
        let mark = libm::floor(s / chunk + 1e-9) * chunk;
        out.n_pieces = 0;
        let end = if self.finished || self.snapped_cut.is_some() {
            s
        } else {
            mark.min(s)
        };
        let r = if end > self.planned_to + SLIVER * h {
            let freeze = self.freeze();
            self.solve_into(freeze, end, None, true, out).map(|()| {
                self.planned_to = end;
            })
        } else {
            Ok(())
        };
        if r.is_err() {
            // All or nothing: the queue end stays where it was (and
            // `plan_part` rolls the window back).
            (
                self.tail,
                self.tail_s,
                self.tail_derivs,
                self.tail_exact_stop,
            ) = saved;
            (self.five, self.tail_turn) = saved_five;
            self.window.set_tail(saved.1);
        }
        r
    }

    /// The speed limit of the joints at the join of the queue and `block`
    /// (tip derivatives `left` and `entry` there): the joint rates may jump
    /// where the tool axis's rate does ([`joint_junction_speed`]). Infinite
    /// between three-axis blocks (their join is the axes' junction).
    fn joint_junction(&self, block: &Block, left: &Derivs, entry: &Derivs) -> f64 {
        let (None, None) = (self.five.q_s, &block.orientation) else {
            let tangent = |d: &Derivs| {
                let t = d.d1 / d.d1.norm();
                [t.x, t.y, t.z, 0.0, 0.0, 0.0]
            };
            let before = self.five.q_s.unwrap_or_else(|| tangent(left));
            let after = match &block.orientation {
                Some(o) => {
                    let u = block.path.u_start();
                    match JointSample::new(
                        self.machine_kin.as_ref(),
                        o,
                        &block.path,
                        u,
                        &self.five.joints,
                    ) {
                        Ok(Some(smp)) => smp.q_s,
                        // At rest or out of reach (refused before this): stop.
                        _ => return 0.0,
                    }
                }
                None => tangent(entry),
            };
            let mut jump = [0.0; 6];
            for (j, d) in jump.iter_mut().enumerate() {
                *d = after[j] - before[j];
            }
            return joint_junction_speed(&jump, &self.cfg);
        };
        f64::INFINITY
    }

    /// A junction of speed limit `v` at arc length `s`: a rest point, or a
    /// lower limit there. Returns whether it is a rest point.
    fn apply_junction(&mut self, v: f64, s: f64, slack: f64) -> bool {
        if v < crate::plan::stop_speed(&self.cfg) {
            let _ = self.window.add_stop(s);
            true
        } else {
            self.window.lower_junction(s, slack, v);
            false
        }
    }
}

/// Sample the feed laws of `seg` onto the window's grid: sample `k` sits at
/// arc length `k·h/M` and feeds interval `⌊k/M⌋` (and the one before when it
/// is on a node). A curvature peak can fall between samples, so every local
/// minimum of the sampled law is refined by a golden-section search between
/// its neighbours, and the refined value lowers the intervals it may lie in.
/// Curves also leave per-axis derivative samples (four per interval, the
/// refined minima, and the segment's ends) for the per-axis jerk rows; lines
/// fold their axes' jerk limits into the interval's tangential jerk.
///
/// The laws are evaluated with the parameter clamped into `window` (see
/// [`law_window`]).
fn sample_laws(
    seg: &Segment,
    window: (f64, f64),
    block: &Block,
    cfg: &InterpConfig,
    w: &mut Window,
    h: f64,
) {
    let (u_lo, u_hi) = window;
    let m = cfg.law_samples_per_interval as i64 * grid_multiple(cfg);
    let hs = h / m as f64;
    let path = &seg.path;
    let keep = 1.0 - cfg.planning_margin;
    let law = |d: &Derivs, which: usize| {
        if which == 0 {
            machine_limit(d, cfg, 1.0)
        } else {
            feed_limit(d, block.feed, block.mrr.as_ref(), cfg)
        }
    };
    // A block shorter than a sub-range (a corner blend, a stretch between
    // two stationary points) limits exactly its own extent, by the lowest
    // of its laws (see `plan::Span`); a longer one, the sub-ranges.
    let short = seg.length < h / crate::plan::SUB as f64;
    // A short curve with a stationary end is described in steps towards it
    // instead ([`stepped_laws`]): the laws rise fast away from such a point.
    let stepped_ends = (u_lo > path.u_start(), u_hi < path.u_end());
    let stepped = short && !matches!(path, Path::Line(_)) && (stepped_ends.0 || stepped_ends.1);
    let lower_whole = |w: &mut Window, s0: f64, s1: f64, which: usize, v: f64| {
        if short {
            w.lower_exact(seg.s0, seg.s1(), which, v);
        } else {
            w.lower_range(s0, s1, which, v);
        }
    };
    let lower = |w: &mut Window, s0: f64, s1: f64, which: usize, v: f64| {
        if !stepped {
            lower_whole(w, s0, s1, which, v);
        }
    };
    // The fastest the laws allow at a point under any feed override (the
    // override scales the feed law: `Data::limit2`). The samples are
    // filtered at that speed, not at the programmed feed's: an override
    // raised after the block was queued re-plans it with the samples it
    // has, and one dropped as unable to bind at 100 % then had no row
    // (an axis 1.12× over its jerk limit at 150 %, `homer-q1` at F6000).
    let top_law = |d: &Derivs| {
        law(d, 0)
            .min(cfg.max_feed_override * law(d, 1))
            .min(cfg.max_path_speed)
    };
    // A per-axis sample is kept where the axis jerk could bind at the
    // speed `v` the laws allow there (elsewhere no row is needed).
    let sample_at = |w: &mut Window, s: f64, d: &Derivs, v: f64, side: i8| {
        offer_axis_sample(w, s, d, side, JumpReserve::NONE, v, h, cfg);
    };
    let sample_on = |w: &mut Window, s: f64, d: &Derivs, side: i8| {
        sample_at(w, s, d, top_law(d), side);
    };
    let sample = |w: &mut Window, s: f64, d: &Derivs| sample_on(w, s, d, 0);
    let curve = !matches!(path, Path::Line(_));
    let (g_first, g_last) = (index_of(seg.s0, h), index_of(seg.s1(), h));
    let feed_top = block.feed.min(cfg.max_path_speed);
    lower_whole(w, seg.s0, seg.s1(), 1, feed_top);
    if block.is_in_place() {
        // A turn in place: its path is the turn's measure in degrees, no
        // axis of the machine; the joints' limits come from
        // `fiveaxis::sample_joints`.
        lower_whole(w, seg.s0, seg.s1(), 0, cfg.max_path_speed);
        return;
    }
    if stepped {
        stepped_laws(seg, window, stepped_ends, w, &law, &mut |w, s, d| {
            sample(w, s, d)
        });
    }
    knot_junctions(seg, w, h, cfg);
    if let Path::Line(_) = path {
        // Constant tangent: the axes' jerk limits bound the tangential jerk.
        let t = path.eval(path.u_start(), 1).d1;
        let t = t / t.norm();
        for g in g_first..=g_last {
            if let Some(it) = w.interval_mut(g) {
                for i in 0..3 {
                    let ti = libm::fabs(t[i]);
                    if ti > 0.0 {
                        it.jerk = it.jerk.min(keep * cfg.axis_max_jerk[i] / ti);
                    }
                }
            }
        }
    }
    if curve {
        sample_on(w, seg.s0, &path.eval(u_lo, 3), 1);
        sample_on(w, seg.s1(), &path.eval(u_hi, 3), -1);
    }
    // Around a curvature peak of radius below the sample spacing, the
    // curvature terms of the axis jerk (`3·C″·v·a`) change over the radius,
    // and a ramp's speed and acceleration over a few µm: per-axis samples
    // every quarter radius up to a radius each way of the peak at `s_pk`
    // (searched from `ua` at arc length `xa`), a peak of the curvature or
    // of an axis's `C‴`. An 8 µm turn at the end of a fitted piece, sampled
    // at its peak only, reached 1.12× an axis's jerk as the run stopped
    // there; a 13 µm cusp of `homer-q1`, sampled at its axes' `C‴` peaks
    // only (its curvature's was no sampled minimum of the law), 1.046× as
    // an abort braked through it: the rows at the samples held, not a knot
    // of the plan between them, where the path jerk turned.
    let around_peak = |w: &mut Window, xa: f64, ua: f64, s_pk: f64, d_pk: &Derivs| {
        let r = 1.0 / d_pk.curvature();
        let v_pk = law(d_pk, 0).min(law(d_pk, 1));
        if r < 0.5 * hs && r > 2.0 * v_pk * cfg.period {
            for f in [-1.0, -0.75, -0.5, -0.25, 0.25, 0.5, 0.75, 1.0] {
                let st = s_pk + f * r;
                if st >= xa && st <= seg.s1() {
                    let ut = path.param_at_arc_length(ua, st - xa).clamp(u_lo, u_hi);
                    sample(w, st, &path.eval(ut, 3));
                }
            }
        }
    };
    if curve && seg.length < 2.0 * hs {
        // A curve shorter than the law spacing (a corner blend of a few µm)
        // may hold no grid sample at all: its laws at its ends and at its
        // worst point, and a per-axis sample there.
        for which in 0..2 {
            let at = |uu: f64| law(&path.eval(uu.clamp(u_lo, u_hi), 3), which);
            let (u_min, v_min) = golden_section_argmin(at, u_lo, u_hi, GOLDEN_ITERS, 0.0);
            let v = v_min.min(at(u_lo)).min(at(u_hi));
            lower(w, seg.s0, seg.s1(), which, v);
            if which == 0 && v_min.is_finite() {
                let u_min = u_min.clamp(u_lo, u_hi);
                let (s_min, d_min) = (seg.s0 + path.arc_length(u_lo, u_min), path.eval(u_min, 3));
                sample(w, s_min, &d_min);
                around_peak(w, seg.s0, u_lo, s_min, &d_min);
            }
        }
    }
    let refine = matches!(path, Path::Nurbs(_));
    let k0 = libm::ceil(seg.s0 / hs) as i64;
    let k1 = libm::floor(seg.s1() / hs) as i64;
    if k0 > k1 {
        // No sample falls on the block: its laws at its middle and ends.
        for which in 0..2 {
            let v = [u_lo, 0.5 * (u_lo + u_hi), u_hi]
                .iter()
                .map(|&uu| law(&path.eval(uu, 3), which))
                .fold(f64::INFINITY, f64::min);
            lower(w, seg.s0, seg.s1(), which, v);
        }
    }
    let (mut u_prev, mut x_prev) = (path.u_start(), seg.s0);
    // Per law, the last sample: (k, value).
    let mut last: [Option<(i64, f64)>; 2] = [None; 2];
    // The term `term` (the machine law's, see `machine_limit_parts`, then
    // the feed law) at `d`.
    let term_of = |d: &Derivs, term: usize| {
        if term < MACHINE_LAW_PARTS {
            machine_limit_parts(d, cfg, 1.0)[term]
        } else {
            law(d, 1)
        }
    };
    // The outer extents of the sharp dips described by nested spans so far
    // (see `staircase`): a term's minimum inside one is described already.
    let stairs: Cell<[(f64, f64); MAX_STAIRS]> = Cell::new([(0.0, 0.0); MAX_STAIRS]);
    let n_stairs = Cell::new(0usize);
    // A sharp dip of the machine law at `u_min` (arc length `s_min`, law
    // `v0`), between `ua` (at `xa`) and `ub`: nested spans where the law
    // is below `v0·2^l`, each held at the level below (`v0` for the first,
    // at the lowest law inside it), so the plan follows the dip's V over
    // its exact extent instead of holding its lowest speed over a whole
    // sub-range (a 1.5 µm turn of `homer-q2` held 31 µm at 0.59 mm/s:
    // 54 ms). Returns the law's lower bound outside the outermost span
    // (the law rises away from the dip), or `None` where the dip is not
    // sharp or not one (its first level wider than a sub-range or reaching
    // the segment's end, unless the dip is at a stationary end, a law that
    // jumps at an edge, or one below a level where the walk checks it), or
    // where no level has room for its span.
    let staircase = |w: &mut Window, xa: f64, ua: f64, ub: f64, u_min: f64, v0: f64| {
        let law_u = |uu: f64| law(&path.eval(uu.clamp(u_lo, u_hi), 3), 0);
        let s_of = |uu: f64| xa + path.arc_length(ua, uu);
        let width_max = h / crate::plan::SUB as f64;
        // Around the law's own minimum in the bracket (the term's may lie
        // beside it: the curvature's and an axis's `C‴` peak apart).
        let (u_law, v_law) = argmin_by_knot_spans(path, law_u, ua, ub);
        let (u_min, v0) = if v_law < v0 {
            (u_law.clamp(u_lo, u_hi), v_law)
        } else {
            (u_min, v0)
        };
        // A dip at a knot where the law jumps (the curvature steps there)
        // rises on one side only: the levels go that way from the knot,
        // whose junction prices the knot itself. `Some((knot, true))`
        // where the left side is the knot's (its law jumps above the dip).
        let at_knot = || -> Option<(f64, bool)> {
            let Path::Nurbs(nb) = path else {
                return None;
            };
            let tol = 1e-6 * (ub - ua);
            let k = knots_within(nb, ua, ub).find(|&k| libm::fabs(k - u_min) <= tol)?;
            let (l, r) = (law_u(k - 1e-9 * (ub - ua)), law_u(k));
            let jump = 2.0 * STAIR_EDGE * v0;
            if l > jump && r <= STAIR_EDGE * v0 {
                Some((k, true))
            } else if r > jump && l <= STAIR_EDGE * v0 {
                Some((k, false))
            } else {
                None
            }
        };
        // A dip at a stationary end of the block (its laws are taken a
        // tick inside it, [`law_window`]) rises inwards only: the levels go
        // that way from the end, whose junction prices the point itself (a
        // soft machine's G5.2 dolphin held 0.0059 mm/s over the sub-range,
        // 6.7 s for 34 µm).
        let at_end = || -> Option<(f64, bool)> {
            let low = |uu: f64| law_u(uu) <= STAIR_EDGE * v0;
            let near = |x: f64| libm::fabs(x - s_of(u_min)) < width_max;
            if stepped_ends.1 && low(u_hi) && near(seg.s1()) {
                Some((u_hi, false))
            } else if stepped_ends.0 && low(u_lo) && near(seg.s0) {
                Some((u_lo, true))
            } else {
                None
            }
        };
        let end = at_end();
        let one_sided = end.or_else(at_knot);
        let u_min = one_sided.map_or(u_min, |(k, _)| k);
        let (fixed_l, fixed_r) = match one_sided {
            Some((_, left)) => (left, !left),
            None => (false, false),
        };
        // The knot's own side bounds the levels: its law near the knot,
        // across the sub-range that way (beyond a block's end, the next
        // block's own laws).
        let side_floor = match one_sided {
            _ if end.is_some() => f64::INFINITY,
            Some((k, left)) => (1..=STAIR_CHECKS)
                .map(|j| {
                    let f = j as f64 / STAIR_CHECKS as f64;
                    let e = 1e-9 * (ub - ua);
                    law_u(if left {
                        k - e - f * (k - ua)
                    } else {
                        k + f * (ub - k)
                    })
                })
                .fold(f64::INFINITY, f64::min),
            None => f64::INFINITY,
        };
        // (Only a sub-range or more inside the segment: a dip at a
        // junction is the junction's, priced with both sides.)
        let s_dip = xa + path.arc_length(ua, u_min);
        if (!fixed_l && s_dip - seg.s0 < width_max) || (!fixed_r && seg.s1() - s_dip < width_max) {
            return None;
        }
        let mut ext = [(0.0f64, 0.0f64, 0.0f64); ONE_SIDED_LEVELS];
        let levels = if one_sided.is_some() {
            ONE_SIDED_LEVELS
        } else {
            STAIR_LEVELS
        };
        // The innermost level's edges, in `u`.
        let mut inner = (u_min, u_min);
        let mut n = 0;
        let (mut ul_prev, mut ur_prev) = (u_min, u_min);
        while n < levels {
            let tau = v0 * libm::exp2((n + 1) as f64);
            if tau > side_floor {
                break;
            }
            // A point out of the level each way: from the last level's
            // edge, outwards by half the bracket, doubling the step (within
            // the segment and a sub-range of the dip).
            let out_of = |from: f64, limit: f64| {
                // (From a knot the law rises within µm: a bracket from a
                // block's end is as long as a sample spacing.)
                let mut step = if one_sided.is_some() {
                    ONE_SIDED_STEP * (ub - ua)
                } else {
                    0.5 * (ub - ua)
                };
                let mut u = from;
                loop {
                    u = if limit > from {
                        (u + step).min(limit)
                    } else {
                        (u - step).max(limit)
                    };
                    // (Not up to the segment's end: a dip at a junction is
                    // the junction's, priced with both sides.)
                    if u == limit || path.arc_length(u_min.min(u), u_min.max(u)) >= width_max {
                        return None;
                    }
                    if law_u(u) >= tau {
                        return Some(u);
                    }
                    step *= 2.0;
                }
            };
            let side = |fixed: bool, from: f64, limit: f64| {
                if fixed {
                    Some(u_min)
                } else {
                    out_of(from, limit)
                }
            };
            let (Some(out_l), Some(out_r)) =
                (side(fixed_l, ul_prev, u_lo), side(fixed_r, ur_prev, u_hi))
            else {
                break;
            };
            // The level's edges, each between the last level's and the
            // point out of it (the law below `tau` inside, at or above it out).
            let edge = |mut inside: f64, mut out: f64| {
                for _ in 0..STAIR_BISECTIONS {
                    let m = 0.5 * (inside + out);
                    if law_u(m) < tau {
                        inside = m;
                    } else {
                        out = m;
                    }
                }
                out
            };
            let (ul, ur) = (edge(ul_prev, out_l), edge(ur_prev, out_r));
            // A law that jumps there is at a knot of the curvature, which
            // its junction prices (spans up to one planned a scroll's knot
            // at 1.2 mm/s, not 5.4).
            if (!fixed_l && law_u(ul) > STAIR_EDGE * tau)
                || (!fixed_r && law_u(ur) > STAIR_EDGE * tau)
            {
                return None;
            }
            // (A fixed end's level reaches the block's end: the tick the
            // laws were taken inside it.)
            let x0 = match end {
                Some((_, true)) => seg.s0,
                _ => s_of(ul),
            };
            let x1 = match end {
                Some((_, false)) => seg.s1(),
                _ => s_of(ur),
            };
            if x1 - x0 >= width_max {
                break;
            }
            // Between this level's edges and the last's the law must be at
            // least the last level (it rises away from the dip; the
            // innermost level is held at the lowest law inside it, below).
            let floor = v0 * libm::exp2(n as f64);
            let rises = n == 0
                || (1..STAIR_CHECKS).all(|j| {
                    let f = j as f64 / STAIR_CHECKS as f64;
                    (fixed_l || law_u(ul + f * (ul_prev - ul)) >= floor)
                        && (fixed_r || law_u(ur_prev + f * (ur - ur_prev)) >= floor)
                });
            if !rises {
                return None;
            }
            ext[n] = (x0, x1, floor);
            if n == 0 {
                inner = (ul, ur);
            }
            (ul_prev, ur_prev) = (ul, ur);
            n += 1;
        }
        // Only the levels the intervals have room for, from the innermost:
        // a span with no room lowers its whole sub-range (the innermost
        // level's speed over 31 µm).
        let mut starts = [0.0; ONE_SIDED_LEVELS];
        for (x, e) in starts.iter_mut().zip(&ext[..n]) {
            *x = e.0;
        }
        let n = w.spans_with_room(&starts[..n]);
        if n == 0 || n_stairs.get() >= MAX_STAIRS {
            return None;
        }
        // The innermost level at the lowest law inside it.
        let (_, v_in) = golden_section_argmin(law_u, inner.0, inner.1, GOLDEN_ITERS, 0.0);
        if !(v_in > 0.0) {
            return None;
        }
        ext[0].2 = v0.min(v_in);
        for &(x0, x1, v) in &ext[..n] {
            w.lower_exact(x0, x1, 0, v);
        }
        let mut all = stairs.get();
        all[n_stairs.get()] = (ext[n - 1].0, ext[n - 1].1);
        stairs.set(all);
        n_stairs.set(n_stairs.get() + 1);
        Some(v0 * libm::exp2(n as f64))
    };
    // A term's minimum between `ua` (at arc length `xa`) and `ub`, where its
    // samples show one: the law there, at the sub-range it lies in (both, on
    // a boundary), not over the whole bracket (which sample brackets it may
    // turn on round-off, where it lies does not), and a per-axis sample
    // where a peak of the curvature or of an axis's `C‴` lies. `below`: only
    // a minimum below it counts (a bracket at a block's end, whose own value
    // its junction prices); `fallback`, the bracket's sampled minimum if the
    // search fails.
    let refine_in = |w: &mut Window,
                     term: usize,
                     xa: f64,
                     ua: f64,
                     ub: f64,
                     below: f64,
                     fallback: (f64, f64)| {
        let which = usize::from(term >= MACHINE_LAW_PARTS);
        let at = |uu: f64| term_of(&path.eval(uu.clamp(u_lo, u_hi), 3), term);
        let (u_min, v_min) = argmin_by_knot_spans(path, at, ua, ub);
        if v_min.is_nan() {
            lower(w, xa, fallback.0, which, fallback.1);
        } else if v_min < below {
            // From the bracket's start, not the block's: linear, not
            // quadratic, in the block.
            let u_min = u_min.clamp(u_lo, u_hi);
            let s_min = xa + path.arc_length(ua, u_min);
            let d_min = path.eval(u_min, 3);
            let v = law(&d_min, which).min(v_min);
            let described = stairs.get()[..n_stairs.get()]
                .iter()
                .any(|&(x0, x1)| s_min >= x0 && s_min <= x1);
            if which == 1 || short {
                lower(w, s_min, s_min, which, v);
            } else if !described {
                let top = staircase(w, xa, ua, ub, u_min, v);
                lower(w, s_min, s_min, which, top.unwrap_or(v));
            }
            // The curvature's term and the axes' `C‴` terms dip at their
            // peaks; so does the feed law (its chord-error term dips where
            // the curvature peaks): samples around a tight one.
            let peak = term == 0 || term >= 4;
            if which == 0 && peak {
                sample(w, s_min, &d_min);
            }
            if peak {
                around_peak(w, xa, ua, s_min, &d_min);
            }
        }
    };
    // Below this share of a boundary sample's value a minimum between it and
    // the next sample is a dip of its own, not the boundary's value.
    const DIP: f64 = 1.0 - 1e-6;
    // Per term, the last two samples (arc length, u, value): a term's
    // sampled local minimum is refined between its neighbours. The terms,
    // not their minimum: the minimum of terms that dip a few µm apart dips
    // twice, and a term that dips between samples where another one is
    // lower need not show as a minimum of the law. The block's ends count
    // as samples: a fitted piece of 0.17 mm held a 6 µm turn (`C‴` 29,000
    // mm⁻²) between its start and its first grid sample, where no sample
    // saw it, and a random `G64 P` program passed it at 3.4× an axis's
    // jerk.
    const TERMS: usize = MACHINE_LAW_PARTS + 1;
    let d_start = path.eval(u_lo, 3);
    // Per term: (arc length, u, value) of a sample.
    type Terms = [Option<(f64, f64, f64)>; TERMS];
    let (mut t1, mut t2): (Terms, Terms) = ([None; TERMS], [None; TERMS]);
    // Every term at `d` (one evaluation of the machine law's).
    let terms_at = |d: &Derivs| {
        let mut v = [0.0; TERMS];
        v[..MACHINE_LAW_PARTS].copy_from_slice(&machine_limit_parts(d, cfg, 1.0));
        v[MACHINE_LAW_PARTS] = law(d, 1);
        v
    };
    if refine && k0 <= k1 {
        for (t, v) in t1.iter_mut().zip(terms_at(&d_start)) {
            *t = Some((seg.s0, u_lo, v));
        }
    }
    // Both laws at the last sample.
    let mut prev_both = [law(&d_start, 0), law(&d_start, 1)];
    // The length over which the path's curvature terms change: its radius
    // of curvature or `1/√|C‴|`, the lower. Per-axis samples between two law
    // samples are a quarter of that apart at most (every half spacing at
    // least, up to 16 a spacing): the axis jerk `C‴·v³ + 3·C″·v·a + t·j`
    // changes over it. At a ramp's speeds a fitted 15 µm turn sampled every
    // 16 µm passed 1.01× an axis's jerk between its samples, and an abort
    // braking through a 23 µm turn sampled every 10 µm (half of it) 1.018×;
    // a third of it, up to 8 a spacing, held that abort but let another
    // there reach 1.049×.
    let feature = |d: &Derivs| {
        ArcLengthDerivs::new(d).map_or(f64::INFINITY, |a| {
            (1.0 / a.c_ss.norm()).min(1.0 / libm::sqrt(a.c_sss.norm()))
        })
    };
    let between = |l: f64, gap: f64| -> usize {
        if l < gap {
            (libm::ceil(4.0 * gap / l) as usize).clamp(2, 16)
        } else {
            2
        }
    };
    let mut prev_feature = feature(&d_start);
    // One sample's terms into the refinement: t2, t1, this (at `x`, `u`).
    let step = |w: &mut Window,
                (t1, t2, prev_both): (&mut Terms, &mut Terms, &mut [f64; 2]),
                (x, u): (f64, f64),
                parts: &[f64; MACHINE_LAW_PARTS],
                both: [f64; 2]| {
        for term in 0..TERMS {
            let (which, v) = if term < MACHINE_LAW_PARTS {
                (0, parts[term])
            } else {
                (1, both[1])
            };
            // A local minimum at t1 is refined between t2 and this sample,
            // if the term comes near the law there (a term far above the
            // others cannot dip below them between two samples).
            match (refine, t2[term], t1[term]) {
                (true, Some((xa, ua, va)), Some((_, _, vb)))
                    if vb < va
                        && vb <= v
                        && vb.is_finite()
                        && vb <= TERM_NEAR * prev_both[which] =>
                {
                    refine_in(w, term, xa, ua, u, f64::INFINITY, (x, vb));
                }
                // The block's start, lower than its first sample: a dip
                // between them is searched for.
                (true, None, Some((xa, ua, va)))
                    if va < v && va.is_finite() && va <= TERM_NEAR * prev_both[which] =>
                {
                    refine_in(w, term, xa, ua, u, DIP * va, (x, va));
                }
                _ => {}
            }
            t2[term] = t1[term];
            t1[term] = Some((x, u, v));
        }
        *prev_both = both;
    };
    // A per-axis sample between law samples, at `u` (arc length `x`); where
    // they are denser than every half spacing (a tight turn), also a
    // sample of the terms, so that a dip between them is refined.
    // The machine law's terms at `d`, and both laws (the machine law as
    // `law(d, 0)`, from the terms already at hand).
    let laws_at = |d: &Derivs| {
        let parts = machine_limit_parts(d, cfg, 1.0);
        let both = [
            parts.iter().fold(cfg.max_path_speed, |a, &b| a.min(b)),
            law(d, 1),
        ];
        (parts, both)
    };
    let sub_sample =
        |w: &mut Window, state: (&mut Terms, &mut Terms, &mut [f64; 2]), x: f64, u: f64| {
            let d = path.eval(u, 3);
            sample(w, x, &d);
            let (parts, both) = laws_at(&d);
            step(w, state, (x, u), &parts, both);
        };
    for k in k0..=k1 {
        let x = k as f64 * hs;
        let u = path.param_at_arc_length(u_prev, x - x_prev);
        // One evaluation for both laws at the sample.
        let d = path.eval(u.clamp(u_lo, u_hi), 3);
        let (parts, both) = laws_at(&d);
        let here = feature(&d);
        if curve {
            // Per-axis samples at every law sample and between (the terms
            // change fast near a curvature peak); each kept where its axis
            // jerk may bind. Whether one is looked at must not turn on
            // round-off: a variant of the same path (moved, scaled, split)
            // would be planned differently.
            let on_end = 1e-9 * h;
            let side = if x <= seg.s0 + on_end {
                1
            } else if x >= seg.s1() - on_end {
                -1
            } else {
                0
            };
            sample_at(w, x, &d, both[0].min(cfg.max_feed_override * both[1]), side);
            let state = (&mut t1, &mut t2, &mut prev_both);
            if k > k0 {
                let n = between(prev_feature.min(here), hs);
                if n == 2 {
                    let um = (0.5 * (u_prev + u)).clamp(u_lo, u_hi);
                    sample(w, x - 0.5 * hs, &path.eval(um, 3));
                } else {
                    for j in 1..n {
                        let um = (u_prev + j as f64 / n as f64 * (u - u_prev)).clamp(u_lo, u_hi);
                        let xm = x_prev + path.arc_length(u_prev, um);
                        sub_sample(w, (&mut *state.0, &mut *state.1, &mut *state.2), xm, um);
                    }
                }
            } else if x - seg.s0 > 0.25 * hs {
                // (And between the block's start and its first sample.)
                let n = between(feature(&d_start).min(here), x - seg.s0);
                for j in 1..n {
                    let um = (u_lo + j as f64 / n as f64 * (u - u_lo)).clamp(u_lo, u_hi);
                    let xm = seg.s0 + path.arc_length(u_lo, um);
                    if n == 2 {
                        sample(w, xm, &path.eval(um, 3));
                    } else {
                        sub_sample(w, (&mut *state.0, &mut *state.1, &mut *state.2), xm, um);
                    }
                }
            }
        }
        for which in 0..2 {
            let v = both[which];
            // Between two samples the law is taken as the lower of the two
            // (a minimum between them is refined below); from the block's
            // ends to the nearest sample, as that sample (its junctions
            // price the ends).
            let (xa, va) = match last[which] {
                Some((ka, va)) => (ka as f64 * hs, va.min(v)),
                None => (seg.s0, v),
            };
            lower(w, xa, x, which, va);
            lower(w, x, x, which, v);
            if k == k1 {
                lower(w, x, seg.s1(), which, v);
            }
            last[which] = Some((k, v));
        }
        step(w, (&mut t1, &mut t2, &mut prev_both), (x, u), &parts, both);
        if curve && k == k1 && seg.s1() - x > 0.25 * hs {
            // (And between the last sample and the block's end.)
            let n = between(feature(&path.eval(u_hi, 3)).min(here), seg.s1() - x);
            for j in 1..n {
                let um = (u + j as f64 / n as f64 * (u_hi - u)).clamp(u_lo, u_hi);
                let xm = x + path.arc_length(u, um);
                if n == 2 {
                    sample(w, xm, &path.eval(um, 3));
                } else {
                    sub_sample(w, (&mut t1, &mut t2, &mut prev_both), xm, um);
                }
            }
        }
        prev_feature = here;
        u_prev = u;
        x_prev = x;
    }
    if refine && k0 <= k1 {
        // The block's end as the last sample: a minimum at the last grid
        // sample, or a dip between it and the end.
        let d_end = path.eval(u_hi, 3);
        let end_both = [law(&d_end, 0), law(&d_end, 1)];
        for (term, v) in terms_at(&d_end).into_iter().enumerate() {
            let which = usize::from(term >= MACHINE_LAW_PARTS);
            let near =
                |vb: f64| vb.is_finite() && vb <= TERM_NEAR * prev_both[which].min(end_both[which]);
            if let (Some((xa, ua, va)), Some((_, _, vb))) = (t2[term], t1[term])
                && vb < va
                && vb <= v
                && near(vb)
            {
                refine_in(w, term, xa, ua, u_hi, f64::INFINITY, (seg.s1(), vb));
            }
            if let Some((xb, ub, vb)) = t1[term]
                && v < vb
                && near(v)
            {
                refine_in(w, term, xb, ub, u_hi, DIP * v, (seg.s1(), v));
            }
        }
    }
    if let Path::Nurbs(n) = path {
        // A knot span narrower than twice the law spacing (a fit's tight turn
        // of a few µm between two grid samples) may hold a peak of `C‴` that
        // no grid sample sees: its worst point, and a per-axis sample there.
        let knots = n.knots();
        let p = n.degree();
        let (mut at_u, mut at_s) = (u_lo, seg.s0);
        let mut i = p + 1;
        let mut prev = u_lo;
        while i < knots.len() {
            let u = knots[i].min(u_hi);
            if u > prev {
                let len = path.arc_length(prev, u);
                let mult = knots[i..].iter().take_while(|&&k| k == knots[i]).count();
                // `C‴` steps at a knot of continuity C2 (lower ones are
                // junctions, `knot_junctions`): the axis jerk steps with it
                // (`v³·ΔC‴`), and a grid sample a few µm past the knot sees
                // the right side's jerk already fallen. A random `G64 P`
                // program's cubic fit reached 1.04× an axis's jerk there.
                // Where the step could take more than the planning margin
                // at the laws' speed there, both sides are per-axis samples
                // (every knot's filled the intervals of a raster's fits,
                // a knot every few tens of µm, and the overflow slowed it
                // 2.5 %).
                if u < u_hi && mult + 2 == p {
                    let left = path.eval(u - (u - prev) * 1e-9, 3);
                    let right = path.eval(u, 3);
                    if let (Some(a), Some(b)) =
                        (ArcLengthDerivs::new(&left), ArcLengthDerivs::new(&right))
                    {
                        let v = law(&left, 0)
                            .min(law(&left, 1))
                            .min(law(&right, 0))
                            .min(law(&right, 1))
                            .min(cfg.max_path_speed);
                        let step = (0..3).any(|i| {
                            v * v * v * libm::fabs(a.c_sss[i] - b.c_sss[i])
                                > cfg.planning_margin * cfg.axis_max_jerk[i]
                        });
                        if step {
                            let s_knot = at_s + path.arc_length(at_u, u);
                            sample(w, s_knot, &left);
                            sample(w, s_knot, &right);
                        }
                    }
                }
                // (Between two knots: a segment's ends have their own samples,
                // and a stationary end its laws taken a tick inside.)
                if len < 2.0 * hs && prev > u_lo && u < u_hi {
                    for which in 0..2 {
                        let at = |uu: f64| law(&path.eval(uu.clamp(prev, u), 3), which);
                        let (u_min, v_min) = golden_section_argmin(at, prev, u, GOLDEN_ITERS, 0.0);
                        if !v_min.is_finite() {
                            continue;
                        }
                        let u_min = u_min.clamp(prev, u);
                        let s_min = at_s + path.arc_length(at_u, u_min);
                        lower(w, s_min, s_min, which, v_min);
                        if which == 0 {
                            sample(w, s_min, &path.eval(u_min, 3));
                        }
                    }
                }
                at_s += path.arc_length(at_u, u);
                at_u = u;
                prev = u;
            }
            if u >= u_hi {
                break;
            }
            i += 1;
        }
    }
}

/// Where `f` (a law along `path`) is lowest on `[a, b]`, and its value:
/// golden-section search in each knot span of a NURBS that the bracket
/// overlaps. A law jumps at a C1 knot and may dip just past it (a near-cusp
/// at a knot of the G5.2 guitar, 2.2 mm/s past a law of 15): one search
/// over both sides found the bracket's end when the knot lay off its
/// middle.
fn argmin_by_knot_spans(path: &Path, f: impl Fn(f64) -> f64, a: f64, b: f64) -> (f64, f64) {
    let mut best = (f64::NAN, f64::NAN);
    let mut lo = a;
    let mut search = |lo: f64, hi: f64| {
        let (u, v) = golden_section_argmin(&f, lo, hi, GOLDEN_ITERS, 0.0);
        if v < best.1 || best.1.is_nan() {
            best = (u, v);
        }
    };
    if let Path::Nurbs(n) = path {
        for k in knots_within(n, a, b) {
            if k > lo {
                search(lo, k);
                lo = k;
            }
        }
    }
    search(lo, b);
    best
}

/// The knots of `n` strictly inside `(a, b)`, in order (repeated ones
/// repeated), found from `a`'s span rather than scanned from the first
/// knot: a bracket is a few µm of a curve that may hold thousands.
fn knots_within(n: &Nurbs, a: f64, b: f64) -> impl Iterator<Item = f64> + '_ {
    let knots = n.knots();
    knots[n.find_span(a, 0) + 1..]
        .iter()
        .copied()
        .skip_while(move |&k| k <= a)
        .take_while(move |&k| k < b)
}

/// Steps of [`stepped_laws`] towards each stationary end.
const STATIONARY_STEPS: usize = 3;
/// Each of those steps is this share of the next one's extent.
const STATIONARY_STEP_RATIO: f64 = 0.25;

/// The laws of a curve shorter than a sub-range with a stationary end
/// (`stationary`: start, end; its laws evaluated within `window`, see
/// [`law_window`]), described by [`STATIONARY_STEPS`] spans towards each
/// such end, each a [`STATIONARY_STEP_RATIO`] of the next, each held by the
/// lowest of each law over it, with a per-axis sample at every step's
/// edge. Held whole by its lowest law, as other short curves are, a
/// stretch of 17 µm next to a stationary point of `curva_delfino` ran at
/// 0.18 mm/s, where the law is 1.3 mm/s 2 µm away and 13 at its far end.
fn stepped_laws(
    seg: &Segment,
    window: (f64, f64),
    stationary: (bool, bool),
    w: &mut Window,
    law: &dyn Fn(&Derivs, usize) -> f64,
    sample: &mut dyn FnMut(&mut Window, f64, &Derivs),
) {
    let path = &seg.path;
    let (u_lo, u_hi) = window;
    let len = seg.length;
    // Edges as arc lengths from the start: geometric towards each
    // stationary end (from the middle when both are).
    let mut edges = [0.0f64; 2 * STATIONARY_STEPS + 2];
    let mut n = 0;
    let reach = if stationary.0 && stationary.1 {
        0.5 * len
    } else {
        len
    };
    let mut push = |x: f64| {
        if n == 0 || x > edges[n - 1] {
            edges[n] = x;
            n += 1;
        }
    };
    push(0.0);
    if stationary.0 {
        for k in (1..STATIONARY_STEPS).rev() {
            push(reach * libm::pow(STATIONARY_STEP_RATIO, k as f64));
        }
    }
    if stationary.0 && stationary.1 {
        push(reach);
    }
    if stationary.1 {
        for k in 1..STATIONARY_STEPS {
            push(len - reach * libm::pow(STATIONARY_STEP_RATIO, k as f64));
        }
    }
    push(len);
    let u_of = |x: f64| path.param_at_arc_length(path.u_start(), x);
    let eval = |u: f64| path.eval(u.clamp(u_lo, u_hi), 3);
    // A span an interval has no room for would lower its whole sub-range
    // (`Window::lower_exact`): then the stretch is held whole, as before.
    let mut starts = [0.0; 2 * STATIONARY_STEPS + 2];
    for (x, e) in starts.iter_mut().zip(&edges[..n - 1]) {
        *x = seg.s0 + e;
    }
    if w.spans_with_room(&starts[..n - 1]) < n - 1 {
        edges[1] = len;
        n = 2;
    }
    let mut u_prev = u_of(0.0);
    for k in 1..n {
        let u = u_of(edges[k]);
        for which in 0..2 {
            let at = |uu: f64| law(&eval(uu), which);
            let (u_min, v_min) = golden_section_argmin(at, u_prev, u, GOLDEN_ITERS, 0.0);
            let v = v_min.min(at(u_prev)).min(at(u));
            w.lower_exact(seg.s0 + edges[k - 1], seg.s0 + edges[k], which, v);
            if which == 0 && v_min.is_finite() {
                let u_min = u_min.clamp(u_prev, u);
                sample(
                    w,
                    seg.s0 + path.arc_length(path.u_start(), u_min),
                    &eval(u_min),
                );
            }
        }
        if k + 1 < n {
            sample(w, seg.s0 + edges[k], &eval(u));
        }
        u_prev = u;
    }
}

/// The knots of a NURBS segment where the curvature may jump (continuity C1
/// or less), priced as junctions: each limits the speed and leaves its
/// samples and its reserve ([`junction_samples`]). Before the laws are
/// sampled, so that the samples near a knot, which keep its reserve, are
/// kept where that makes their jerk bind. Tangent breaks were cut into
/// separate segments already.
fn knot_junctions(seg: &Segment, w: &mut Window, h: f64, cfg: &InterpConfig) {
    let Path::Nurbs(n) = &seg.path else {
        return;
    };
    {
        let p = n.degree();
        let knots = n.knots();
        let (ua, ub) = (n.u_start(), n.u_end());
        let mut i = p + 1;
        let mut prev = ua;
        // Arc length at `at_u`, carried from knot to knot.
        let (mut at_u, mut at_s) = (ua, seg.s0);
        while i < knots.len() - p - 1 {
            let u = knots[i];
            let mut mult = 1;
            while i + mult < knots.len() && knots[i + mult] == u {
                mult += 1;
            }
            if u > ua && u < ub && mult + 1 >= p {
                let left = n.eval(u - (u - prev) * 1e-9, 3);
                let right = n.eval(u, 3);
                let v = junction_speed_with(&left, &right, cfg, KNOT_JUMP_SHARE);
                at_s += seg.path.arc_length(at_u, u);
                at_u = u;
                // (Arc length carried from knot to knot, to ~1e-12 mm a
                // knot: a thousandth of a sub-range's slack each way.)
                let slack = 1e-3 * h / crate::plan::SUB as f64;
                w.lower_junction(at_s, slack, v);
                junction_samples(w, at_s, &left, &right, v, KNOT_JUMP_SHARE, h, cfg);
            }
            if u > ua {
                prev = u;
            }
            i += mult;
        }
    }
}

/// The share of the axis jerk a junction's curvature step may take: next to
/// a stationary point (`stationary`) [`STATIONARY_JUMP_SHARE`], whose laws
/// are taken a tick inside, else [`crate::feed::JUMP_SHARE`].
fn jump_share(stationary: bool) -> f64 {
    if stationary {
        STATIONARY_JUMP_SHARE
    } else {
        crate::feed::JUMP_SHARE
    }
}

/// The per-axis samples of a junction at `s` passed at `v` at most: its
/// two sides' derivatives, each with the share of the axes' jerk the
/// curvature's step takes there ([`crate::feed::jump_reserve`]), so the jerk
/// rows at the junction keep to the rest.
#[allow(clippy::too_many_arguments)]
pub(crate) fn junction_samples(
    w: &mut Window,
    s: f64,
    left: &Derivs,
    right: &Derivs,
    v: f64,
    share: f64,
    h: f64,
    cfg: &InterpConfig,
) {
    let v = v.min(cfg.max_path_speed);
    let reserve = crate::feed::jump_reserve(left, right, v, share, cfg);
    if reserve.is_none() {
        return;
    }
    w.reserve_around_jump(s, v, reserve);
    for d in [left, right] {
        offer_axis_sample(w, s, d, 0, reserve, v, h, cfg);
    }
}

/// The per-axis sample of derivatives `d` at `s` (its block `side`, the
/// junction `reserve`: see [`AxisSample`]), kept where its axis jerk could
/// bind at speed `v` ([`keep_axis_sample`]); elsewhere no row is needed.
#[allow(clippy::too_many_arguments)]
fn offer_axis_sample(
    w: &mut Window,
    s: f64,
    d: &Derivs,
    side: i8,
    reserve: JumpReserve,
    v: f64,
    h: f64,
    cfg: &InterpConfig,
) {
    let Some(a) = ArcLengthDerivs::new(d) else {
        return;
    };
    let smp = AxisSample {
        s,
        t: [a.t.x, a.t.y, a.t.z],
        css: [a.c_ss.x, a.c_ss.y, a.c_ss.z],
        csss: [a.c_sss.x, a.c_sss.y, a.c_sss.z],
        side,
        // (A junction's own samples come with its reserve; others near one
        // keep it too.)
        reserve: reserve.max(w.jump_zone_at(s).map_or(JumpReserve::NONE, |z| z.reserve)),
        junction: !reserve.is_none(),
    };
    if (0..3).any(|ax| axis_jerk_may_bind(&smp, ax, v * v, cfg)) {
        keep_axis_sample(w, smp, h, v * v, cfg);
    }
}

/// Could the axis jerk `v·(C‴·S + 1.5·C″·S′ + 0.5·t·S″)` of axis `ax` reach
/// its limit at this sample with `S ≤ l2`, `|S′| ≤ 2A`, `|S″| ≤ 2J/√l2`?
pub(crate) fn axis_jerk_may_bind(smp: &AxisSample, ax: usize, l2: f64, cfg: &InterpConfig) -> bool {
    axis_jerk_load(smp, ax, l2, cfg) > 1.0
}

/// The largest axis jerk of axis `ax` at this sample under the bounds of
/// [`axis_jerk_may_bind`], as a fraction of its limit.
pub(crate) fn axis_jerk_load(smp: &AxisSample, ax: usize, l2: f64, cfg: &InterpConfig) -> f64 {
    axis_jerk_load_at(smp, ax, l2, cfg, cfg.max_path_jerk, cfg.planned_accel())
}

/// [`axis_jerk_load`] with the path's tangential jerk at most `jerk`
/// (before the planning margin) instead of `max_path_jerk`, and its
/// tangential acceleration at most `accel` instead of the planned one.
fn axis_jerk_load_at(
    smp: &AxisSample,
    ax: usize,
    l2: f64,
    cfg: &InterpConfig,
    jerk: f64,
    accel: f64,
) -> f64 {
    let keep = 1.0 - cfg.planning_margin;
    let v = libm::sqrt(l2).max(1e-9);
    let worst = libm::fabs(smp.csss[ax]) * l2
        + 3.0 * libm::fabs(smp.css[ax]) * accel
        + libm::fabs(smp.t[ax]) * jerk * keep / v;
    // (Against the share a junction's step leaves.)
    worst * v / (cfg.axis_max_jerk[ax] * keep * (1.0 - smp.reserve.larger(ax)))
}

/// Put a per-axis sample whose axis jerk may bind at squared speed `l2`
/// into its interval. An interval that holds as many as it can instead
/// lowers the speed limit where the sample lies until its axis jerk cannot
/// bind there (its load at that speed is at most 1): slower, never over a
/// limit, and the same under any choice of units.
pub(crate) fn keep_axis_sample(
    w: &mut Window,
    smp: AxisSample,
    h: f64,
    l2: f64,
    cfg: &InterpConfig,
) {
    if let Some(it) = w.interval_mut(sample_interval(smp.s, h))
        && !it.add_sample(smp)
    {
        // The tangential part of an axis' jerk, `|t|·J`, does not fall with
        // the speed. Where it alone would take more than half an axis' limit
        // (a five-axis joint, whose rate in arc length `|t|` may exceed 1, or
        // a path jerk above half the axis'), no speed bounds the load and a
        // zero limit would stall the run: the interval's tangential jerk is
        // lowered to leave the other half to the speed's terms.
        let mut jerk = cfg.max_path_jerk;
        let room = (0..3)
            .filter(|&ax| smp.t[ax] != 0.0)
            .map(|ax| 0.5 * cfg.axis_max_jerk[ax] / libm::fabs(smp.t[ax]))
            .fold(f64::INFINITY, f64::min);
        if jerk > room {
            jerk = room;
            it.jerk = it.jerk.min(room * (1.0 - cfg.planning_margin));
        }
        // A junction's curvature step takes a share of the jerk that falls
        // with the square of the speed below the junction's own
        // (`feed::jump_reserve`): at the speed sought it may leave more, and
        // some speed is always safe.
        let v2 = w.jump_zone_at(smp.s).map_or(l2, |z| z.v2);
        let load = |v: f64| {
            let at_v = AxisSample {
                reserve: smp.reserve.scaled((v * v / v2).min(1.0)),
                ..smp
            };
            // (Any schedule whose speed stays positive under tangential
            // jerk `J` has `|a| ≤ √(2·J·v)`: slow, it cannot be fast to
            // accelerate.)
            let accel = cfg.planned_accel().min(libm::sqrt(2.0 * jerk * v));
            (0..3)
                .map(|ax| axis_jerk_load_at(&at_v, ax, v * v, cfg, jerk, accel))
                .fold(0.0, f64::max)
        };
        // The load grows with the speed: bisect for the highest safe one.
        let (mut lo, mut hi) = (0.0, libm::sqrt(l2));
        for _ in 0..60 {
            let m = 0.5 * (lo + hi);
            if load(m) <= 1.0 {
                lo = m;
            } else {
                hi = m;
            }
        }
        w.lower_at(smp.s, lo);
    }
}

/// A term of the laws whose sampled local minimum is within this factor of
/// the law there is refined (see `sample_laws`).
const TERM_NEAR: f64 = 1.5;

/// Golden-section steps refining a sampled law minimum (bracket shrinks by 0.618 each).
const GOLDEN_ITERS: usize = 40;

/// Levels of the nested spans describing a sharp dip of the machine law
/// (`sample_laws`' staircase), each at twice the speed of the one inside.
const STAIR_LEVELS: usize = 4;
/// Levels of a one-sided staircase (from a knot the law rises further
/// within a sub-range: 0.6 to 42 mm/s over 15 µm on `curva_delfino`).
const ONE_SIDED_LEVELS: usize = 6;
/// The first step out of a level of a one-sided staircase, as a share of
/// its bracket (doubled until out).
const ONE_SIDED_STEP: f64 = 1.0 / 1024.0;
/// Bisection steps finding a level's edges.
const STAIR_BISECTIONS: usize = 40;
/// A level's edge where the law is above this many times the level is a
/// jump of the law, not a crossing.
const STAIR_EDGE: f64 = 1.01;
/// Points checked between two levels' edges (less one).
const STAIR_CHECKS: usize = 4;
/// Sharp dips described by nested spans in one segment, at most.
const MAX_STAIRS: usize = 16;

/// A hold planned to a rest point short of where the plan ended
/// ([`BlockPlanner::hold`]).
#[derive(Clone, Copy, Debug, PartialEq)]
struct AfterHold {
    /// Where the hold rests.
    rest: f64,
    /// Where the plan ended before the hold.
    end: f64,
    /// A resume while braking was planned for ([`BlockPlanner::resume_hold`]).
    resume_tried: bool,
}

/// Braking rates (fractions of the planned acceleration and jerk) a new
/// override's braking curve, and a feed hold's stop, are tried with,
/// steepest first. Down to 1 %: in
/// a tight turn whose axes' jerk binds at a steady speed the machine cannot
/// slow down at all, and a braking curve at 10 % still asked it to (the
/// override at 30 % inside a turn of `trident`, which crawled).
const LIFT_SOFTENING: [f64; 6] = [1.0, 0.5, 0.25, 0.1, 0.03, 0.01];

/// Where a long block whose chunk mark falls at parameter `u` is cut: on a
/// knot of its curve instead, when one is so near that the cut would leave
/// a sliver of the knot span, a tenth of its width or less (and at most a
/// quarter grid step of arc length away). The sliver's control points
/// nearly coincide, and the part's derivatives in it lose their digits:
/// the machine law sampled there fell to 8.7 mm/s over 60 µm around a cut
/// 6·10⁻⁵ of a span past a knot of `curva_scrool_f` (order 6), where the
/// curve allows 60–71 mm/s. The part's law at a cut a sliver from a knot
/// (the 20 corpus curves, cut at every knot's side at offsets from 10⁻⁵ to
/// 10⁻¹ of the span) is off by up to 220 % within a thousandth of the
/// span, 6 % within a hundredth, 5·10⁻⁵ within a twentieth and 7·10⁻⁸ past
/// the cuts a tenth moves (all on the scroll). `None`: cut at `u`.
fn cut_at_mark(path: &Path, u: f64, h: f64) -> Option<f64> {
    let Path::Nurbs(n) = path else {
        return None;
    };
    let k = n.knots();
    let span = n.find_span(u, 0);
    let (a, b) = (k[span], k[span + 1]);
    let speed = n.eval(u, 1).d1.norm();
    let near = |c: f64| {
        c > n.u_start()
            && c < n.u_end()
            && (u - c).abs() <= snap_share(path, c) * (b - a)
            && speed * (u - c).abs() <= CUT_SNAP_STEPS * h
    };
    [a, b].into_iter().find(|&c| c != u && near(c))
}

/// See [`cut_at_mark`].
const CUT_SNAP_SHARE: f64 = 0.1;

/// [`CUT_SNAP_SHARE`] at a knot where the curvature may jump (continuity
/// C1 or less: the uncut curve prices it as a junction, [`knot_junctions`]).
/// A cut there is priced as a junction between parts, whose curvature step
/// keeps less of the axes' jerk (`feed::JUMP_SHARE` against
/// `KNOT_JUMP_SHARE`): snapped from a tenth of a span, `leto-xy`'s cut
/// (G5.2, one such knot at its mark) took 0.741 s against 0.733. The
/// corpus's cubic G5.2 chains, whose knots these are, keep their digits in
/// slivers: the part's law at a cut more than a thousandth of a span from
/// a knot is off by 10⁻⁷ at most.
const JUNCTION_SNAP_SHARE: f64 = 1e-3;

/// How near a knot `c` of `path` a cut moves onto it ([`cut_at_mark`]).
fn snap_share(path: &Path, c: f64) -> f64 {
    if cut_is_smooth(path, c) {
        CUT_SNAP_SHARE
    } else {
        JUNCTION_SNAP_SHARE
    }
}

/// How far (in grid steps of arc length) a cut may move from its chunk
/// mark ([`cut_at_mark`], [`BlockPlanner::plan`]).
const CUT_SNAP_STEPS: f64 = 0.25;

/// Whether `path` is smooth at parameter `u`, as the uncut block is
/// planned: inside a knot span, or on a knot where the curvature is
/// continuous (only knots of continuity C1 or less are junctions,
/// [`knot_junctions`]). Lines and arcs are smooth everywhere.
fn cut_is_smooth(path: &Path, u: f64) -> bool {
    let Path::Nurbs(n) = path else {
        return true;
    };
    let mult = n.knot_multiplicity(u);
    mult == 0 || mult + 1 < n.degree()
}

/// The parameters between which the laws of `path` (of length `len`, a piece
/// of `block`) are evaluated: its whole range, narrowed by [`stationary_offset`]
/// at an end that is `singular` (the curve stops or turns back there: the
/// curvature is in general infinite, or as good as, and no tick sees it).
fn law_window(
    path: &Path,
    len: f64,
    singular: (bool, bool),
    block: &Block,
    cfg: &InterpConfig,
) -> (f64, f64) {
    let (ua, ub) = (path.u_start(), path.u_end());
    let limit = |u: f64| {
        let d = path.eval(u, 3);
        machine_limit(&d, cfg, 1.0).min(feed_limit(&d, block.feed, block.mrr.as_ref(), cfg))
    };
    let lo = if singular.0 {
        let d = stationary_offset(cfg, 0.5 * len, |x| limit(path.param_at_arc_length(ua, x)));
        path.param_at_arc_length(ua, d)
    } else {
        ua
    };
    let hi = if singular.1 {
        let d = stationary_offset(cfg, 0.5 * len, |x| {
            limit(path.param_at_arc_length(ua, len - x))
        });
        path.param_at_arc_length(ua, len - d)
    } else {
        ub
    };
    (lo, hi)
}

/// Cut a NURBS where the tangent breaks: at interior knots of full
/// multiplicity where it turns by more than `tol` (a corner inside one
/// block), and where the curve stops or turns back
/// ([`Nurbs::for_each_stationary`]: C' = 0, a cusp where the tangent reverses,
/// a corner, or a point where the curvature blows up; or a hairpin that is a
/// cusp to within `near`). Those are marked in `singular` (one flag per piece
/// boundary, the block's ends included, which are marked where the curve is
/// stationary): the pieces' laws are taken a tick inside them
/// ([`law_window`]) and their junction is priced like a corner's. Lines and
/// arcs are one piece. Returns the number of pieces written.
pub(crate) fn split_at_tangent_breaks(
    path: &Path,
    out: &mut [Path; MAX_PIECES],
    tol: f64,
    near: f64,
    singular: &mut [bool; MAX_PIECES + 1],
) -> Result<usize, PushError> {
    out[0] = *path;
    singular.fill(false);
    let Path::Nurbs(n) = path else {
        return Ok(1);
    };
    let (ua, ub) = (n.u_start(), n.u_end());
    singular[0] = n.is_stationary(ua, Side::After);
    // Cut parameters and whether each stops or turns the curve back (more than
    // MAX_PIECES - 1 is an error either way).
    let mut cuts = [(0.0f64, false); 2 * MAX_PIECES];
    let mut n_cuts = 0;
    let mut add = |u: f64, stops: bool| {
        if n_cuts < cuts.len() {
            cuts[n_cuts] = (u, stops);
        }
        n_cuts += 1;
    };
    let p = n.degree();
    let knots = n.knots();
    let mut i = p + 1;
    while i < knots.len() - p - 1 {
        let u = knots[i];
        let mut mult = 1;
        while i + mult < knots.len() && knots[i + mult] == u {
            mult += 1;
        }
        if u > ua && u < ub && mult >= p {
            // The one-sided tangents at a C0 knot.
            let left = n.tangent(u, Side::Before);
            let right = n.tangent(u, Side::After);
            if !(left.dot(&right) >= libm::cos(tol)) {
                add(u, false);
            }
        }
        i += mult;
    }
    n.for_each_stationary(near, |u| add(u, true));
    if n_cuts > cuts.len() {
        return Err(PushError::TooManyCorners);
    }
    let cuts = &mut cuts[..n_cuts];
    cuts.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
    let mut count = 1;
    let mut last = ua;
    for &(u, stops) in cuts.iter() {
        if u <= last {
            // A stationary corner knot, found twice.
            singular[count - 1] |= stops;
            continue;
        }
        if count >= MAX_PIECES {
            return Err(PushError::TooManyCorners);
        }
        let (a, b) = out[count - 1].split_at(u).map_err(PushError::Split)?;
        out[count - 1] = a;
        out[count] = b;
        singular[count] = stops;
        count += 1;
        last = u;
    }
    singular[count] = n.is_stationary(ub, Side::Before);
    Ok(count)
}

/// What planning a part depends on besides the window's contents (which a
/// refusal leaves as they were, and which only a solve changes).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Refusal {
    block: Block,
    tail_s: f64,
    planned_to: f64,
    machine: MachinePlace,
    at_rest: bool,
    ovr: f64,
    finished: bool,
    /// Solves and crawls so far: the window changes only through them.
    solves: (u64, u64),
}
