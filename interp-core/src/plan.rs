//! Feed scheduling (non-real-time): the look-ahead window and the linear
//! program that gives the planned speed.
//!
//! The planned speed is `v(s)² = S(s)`, a C¹ quadratic spline in arc length
//! ([`crate::spline`]) whose pieces are the global grid intervals
//! `[g·h, (g+1)·h]`, cut where the path must come to rest (a corner, an exact
//! stop, the end of what is queued). A rest point is a C⁰ knot with `S = 0`.
//! Unknowns are the middle Bernstein coefficients `d_p`, one per piece; the
//! value at a C¹ knot is the weighted mean of its neighbours',
//! `e = (h_{p+1}·d_p + h_p·d_{p+1})/(h_p + h_{p+1})`. Every limit is then
//! linear in three consecutive unknowns:
//!
//! | limit | constraint on piece `p` |
//! |---|---|
//! | pointwise laws `V(s)` (feed, chord error, MRR, centripetal, axis velocity and acceleration) | the Bernstein hull `0 ≤ e, d ≤ V_p²` |
//! | tangential acceleration `\|S'/2\| ≤ A` | at the knots, where the linear `S'` peaks |
//! | tangential jerk `\|α·v\| ≤ J`, `α = S''/2` | `±(e_p − 2d_p + e_{p+1}) ≤ (J·h²/V_p)·(1.5 − c/(2V_p²))`, `c` the coefficients that can hold the piece's largest `S` |
//! | axis jerk `v·(C'''_i·S + 1.5·C''_i·S' + 0.5·t_i·S'') ` | at the per-axis samples, `±(…) ≤ (J_i/V_p)·(1.5 − S/(2V_p²))` |
//! | rest points | `\|S'/2\| ≤ min(J·Ts/2, A)` next to them: arriving and leaving, the acceleration steps by at most one tick of jerk |
//!
//! (`C''`, `C'''` are the path's derivatives in arc length, `t` its tangent.
//! A jerk limit `|F(S)| ≤ J/√S` is held through the tangent of its convex
//! right side at the piece's cap `V_p²`, which lies below it for every `S`:
//! linear and safe, and exact at the cap.) The
//! objective is `max ∫S ds`. [`crate::lp`] solves it in O(n) per iteration.
//!
//! Blocks stream in. Each one lifts the provisional rest point at the old
//! end of the queue, so the program is re-solved from a *freeze point* a
//! stopping distance before it: everything before stays as planned (the
//! machine may be executing it), the spline's value and slope at the freeze
//! point are kept, and the rest is solved anew.

use crate::config::InterpConfig;
use crate::lp::{self, LpError, LpOptions, LpWork, Problem, Row};
use crate::spline::{Form, Piece};
use crate::stop::Stop;

/// Grid intervals (and rest points) the queue may span from the machine to
/// its end: the longest look-ahead, 64 mm at the default 0.25 mm grid.
pub const REACH: usize = 256;
/// Pieces one linear program can hold: the grid pieces of the look-ahead
/// (a resumed hold is planned again from where the machine rests), and
/// three times as many again for the cuts next to rest points and slow
/// points: with 384, programs of short moves ran out of room for them and
/// ran 7–9 % slower (a plan only holds the pieces it needs, so curves that
/// had room plan the same).
pub const REGION: usize = 1024;
/// Grid intervals the planner keeps (from the machine to the end of the queue).
pub const INTERVALS: usize = REACH + 8;
/// Pieces the window keeps (before and after the machine).
pub const WINDOW: usize = REGION + 8;
/// Longest stretch of a block planned at once, in grid intervals: longer
/// blocks are planned in parts of this size (at fixed arc lengths, so the
/// parts do not depend on timing).
pub const CHUNK: usize = 128;
/// Per-axis derivative samples kept per grid interval (8 law samples, their
/// midpoints, refined minima, knots and tight turns: with 24, a raster's
/// fits overflowed them and ran 2.5 % slower; 48 add 0.6 MB to the window).
pub const SAMPLES_PER_INTERVAL: usize = 48;
/// Rest points the window can hold.
pub const MAX_STOPS: usize = 256;
/// Rows of one linear program, for the region's pieces and the kept one
/// before them: at least ten per piece, what a piece gives with its
/// per-axis rows aggregated (five tangential jerk rows, a knot's cap and its
/// acceleration, one aggregate row per axis); within the budget the per-axis
/// rows are written one by one (`assemble_and_solve` counts them first,
/// and aggregates the farthest pieces' only, as many as it must).
pub const MAX_ROWS: usize = (REGION + 1) * ROWS_PER_PIECE;
/// Rows budgeted per piece. An aggregate row holds the speed to a few mm/s
/// (it drops the cancellation in `t·S''`); on a soft machine (jerk 10⁴) an
/// axis's jerk may bind at nearly every sample, and with ten rows a piece
/// the aggregation reached the pieces next to the machine on every
/// re-solve: `ruota_dentata-q1` crawled at 0.5 mm/s between its teeth and
/// took 36.2 s, 19.9 s with twelve. With 24 no corpus curve aggregates
/// there (soft `curva_scrool_m-q1` 5.5 → 3.5 s, `curva_scrool_f-q1` 10.3 →
/// 8.0 s against twelve); the scratch is 1.4 MB more than with twelve,
/// which an unoptimised build copies several times on the stack while it
/// builds an interpolator (tests get 64 MiB: `interp_run::stack`). The
/// default machine's curves plan the same with any of these.
const ROWS_PER_PIECE: usize = 24;

/// The path's derivatives in arc length at one point, for the per-axis jerk
/// rows: tangent `t`, `C''` and `C'''`.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct AxisSample {
    /// Arc length of the run, mm.
    pub s: f64,
    /// Unit tangent.
    pub t: [f64; 3],
    /// `d²C/ds²`.
    pub css: [f64; 3],
    /// `d³C/ds³`.
    pub csss: [f64; 3],
    /// Where on its block the sample lies: `1` its start, `-1` its end, `0`
    /// inside. At a rest point between two blocks the end of one is the
    /// start of the other, with other derivatives: each bounds only its own
    /// side (a fillet's curvature does not hold back the line before it).
    pub side: i8,
    /// The share of each axis's jerk a junction's curvature step takes here,
    /// on the side of the jerk it adds (`feed::jump_reserve`; none away from
    /// a junction): the rows keep to the rest. Samples within
    /// [`Window::reserve_around_jump`]'s reach of a junction keep it too.
    pub reserve: JumpReserve,
    /// One of a junction's own two samples (its sides' derivatives).
    pub junction: bool,
}

/// The shares of each axis's jerk that curvature steps nearby take from its
/// jerk rows, by the sign of the jerk they add. A step `v²·ΔC″ᵢ` adds to a
/// third difference of the setpoints a part `θ`-dependent but never of the
/// other sign (`(1−θ)²/2`, `(1+2θ−2θ²)/2`, `θ²/2` of `v²·ΔC″ᵢ/Ts`): a row
/// keeps its share on that side only, and may use the whole limit against
/// the step.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct JumpReserve {
    /// Where the step adds positive jerk to axis `i` (`ΔC″ᵢ > 0` in the
    /// direction of travel): the share of `+J_i` it takes.
    pub up: [f64; 3],
    /// Where it adds negative jerk: the share of `−J_i`.
    pub down: [f64; 3],
}

impl JumpReserve {
    /// No step nearby.
    pub const NONE: JumpReserve = JumpReserve {
        up: [0.0; 3],
        down: [0.0; 3],
    };

    /// True where no step takes anything.
    pub fn is_none(&self) -> bool {
        self.up.iter().chain(self.down.iter()).all(|&r| r <= 0.0)
    }

    /// What both leave, axis by axis and side by side.
    pub fn max(self, other: JumpReserve) -> JumpReserve {
        let mut r = self;
        for i in 0..3 {
            r.up[i] = r.up[i].max(other.up[i]);
            r.down[i] = r.down[i].max(other.down[i]);
        }
        r
    }

    /// Every share times `f` (a step's share falls as the square of the
    /// speed below the junction's).
    pub fn scaled(self, f: f64) -> JumpReserve {
        let mut r = self;
        for i in 0..3 {
            r.up[i] *= f;
            r.down[i] *= f;
        }
        r
    }

    /// The larger side's share on axis `ax` (where a bound must hold both ways).
    pub fn larger(&self, ax: usize) -> f64 {
        self.up[ax].max(self.down[ax])
    }
}

/// Where a junction's curvature step shows in the setpoints' third
/// differences ([`Window::reserve_around_jump`]): the samples over
/// `[x0, x1]` keep `reserve` of each axis's jerk for it.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct JumpZone {
    /// Where it starts, mm.
    pub x0: f64,
    /// Where it ends, mm.
    pub x1: f64,
    /// The shares of each axis's jerk the step takes (none: no zone).
    pub reserve: JumpReserve,
    /// The squared speed the junction is passed at most, mm²/s²: the
    /// step's share falls as the square of the speed below it.
    pub v2: f64,
}

/// Sub-ranges per grid interval the speed limits are kept for: a slow point
/// (a sharp bend, a corner blend, a junction) limits its sub-range, not the
/// whole interval, and the pieces are cut where the limits change.
pub const SUB: usize = 8;

/// Limits over an exact extent an interval holds besides its sub-ranges'
/// (with 8, the G6.2 dolphin's steps towards its stationary point found no
/// room on a machine of path jerk 5·10³, next to a short block's own span
/// and a staircase, and held the block whole at 0.0665 mm/s over 17 µm).
pub const SPANS: usize = 16;

/// A speed limit over an exact extent `[x0, x1]` (a point when equal),
/// narrower than a sub-range: a short block (a corner blend, a stretch
/// between two stationary points) or a junction. It limits only the pieces
/// it overlaps, and the pieces are cut at its ends, so a slow point costs
/// its own length, not its sub-range's.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Span {
    /// Where it starts, mm.
    pub x0: f64,
    /// Where it ends, mm (`x0` for a point).
    pub x1: f64,
    /// Machine-law speed limit over it, mm/s.
    pub machine: f64,
    /// Feed-law speed limit over it at 100 % override, mm/s.
    pub feed: f64,
}

impl Span {
    /// Whether it limits a piece over `[x0, x1]`: a point on the piece (on
    /// its ends too, within round-off), or a span sharing more than
    /// round-off of its length with the piece (one ending where the piece
    /// starts does not: the knot rows hold the limit at the shared end).
    fn overlaps(&self, x0: f64, x1: f64, hs: f64) -> bool {
        if self.x1 > self.x0 {
            let common = self.x1.min(x1) - self.x0.max(x0);
            common > 1e-3 * (self.x1 - self.x0).min(x1 - x0)
        } else {
            let e = SUB_SNAP * hs;
            self.x0 >= x0 - e && self.x0 <= x1 + e
        }
    }
}

/// What the planner knows about one grid interval.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Interval {
    /// Smallest machine-law speed over each sub-range (`SUB` of them, in
    /// order), mm/s.
    pub machine: [f64; SUB],
    /// Smallest feed-law speed at 100 % override over each sub-range, mm/s.
    pub feed: [f64; SUB],
    /// Tangential acceleration limit, mm/s² (lines fold the axes' in).
    pub accel: f64,
    /// Tangential jerk limit, mm/s³ (lines fold the axes' in).
    pub jerk: f64,
    /// Per-axis samples (curves only).
    pub samples: [AxisSample; SAMPLES_PER_INTERVAL],
    /// Samples held.
    pub n_samples: u8,
    /// A sample could not be kept (the interval had more than the capacity):
    /// the speed limit there was lowered until its axis jerk cannot bind.
    pub overflow: bool,
    /// The tangential jerk a five-axis block's joints allow here, mm/s³
    /// (infinite for three-axis blocks): next to a rest point the
    /// acceleration steps by half a tick of it at most (`rest_accel`).
    pub joint_jerk: f64,
    /// Limits over exact extents starting in the interval (see [`Span`]).
    pub spans: [Span; SPANS],
    /// Spans held.
    pub n_spans: u8,
    /// The junctions' steps seen here (their zones' union, the largest
    /// reserve), for samples offered after the junction.
    pub jump: JumpZone,
}

impl Interval {
    fn open(cfg: &InterpConfig) -> Self {
        Interval {
            machine: [f64::INFINITY; SUB],
            feed: [f64::INFINITY; SUB],
            accel: cfg.planned_accel(),
            jerk: cfg.max_path_jerk * (1.0 - cfg.planning_margin),
            samples: [AxisSample::default(); SAMPLES_PER_INTERVAL],
            n_samples: 0,
            overflow: false,
            joint_jerk: f64::INFINITY,
            spans: [Span {
                x0: 0.0,
                x1: 0.0,
                machine: f64::INFINITY,
                feed: f64::INFINITY,
            }; SPANS],
            n_spans: 0,
            jump: JumpZone::default(),
        }
    }
    /// Lower the machine (`which = 0`) or feed (`1`) limit of sub-ranges
    /// `j0..=j1` to `v`.
    pub fn lower(&mut self, j0: usize, j1: usize, which: usize, v: f64) {
        let l = if which == 0 {
            &mut self.machine
        } else {
            &mut self.feed
        };
        for x in &mut l[j0.min(SUB - 1)..=j1.min(SUB - 1)] {
            *x = x.min(v);
        }
    }
    /// Keep a per-axis sample (the first ones; then the worst by curvature).
    /// Keep a per-axis sample; false when the interval holds
    /// [`SAMPLES_PER_INTERVAL`] already (the caller then makes it
    /// unnecessary: see `prepare::keep_axis_sample`).
    #[must_use]
    pub fn add_sample(&mut self, a: AxisSample) -> bool {
        let n = self.n_samples as usize;
        if n < SAMPLES_PER_INTERVAL {
            self.samples[n] = a;
            self.n_samples += 1;
            true
        } else {
            self.overflow = true;
            false
        }
    }
}

/// Why a plan could not be made.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PlanError {
    /// The window or the stop list is full: plan again once the machine has
    /// moved on (the caller's queue frees room as it executes).
    Full,
    /// The linear program failed (it should not: the fallback keeps a rest
    /// point, which is always feasible). The plan was not changed.
    Solver(LpError),
}

impl core::fmt::Display for PlanError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            PlanError::Full => write!(f, "look-ahead window full"),
            PlanError::Solver(e) => write!(f, "feed schedule: {e}"),
        }
    }
}

/// A piece of the window: bounds, its interval, whether it starts at a rest
/// point, and its current solution (the middle Bernstein coefficient).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
struct WPiece {
    x0: f64,
    x1: f64,
    g: i64,
    rest_start: bool,
    d: f64,
    /// Machine-law and feed-law speed limits over the piece, mm/s.
    machine: f64,
    feed: f64,
    /// The squared-speed cap of the rows its coefficient was last solved
    /// under (`None` before any): a re-solve that continues a kept plan
    /// keeps the rows just past it as loose as they were (see
    /// [`kept_caps`]).
    solved_cap: Option<f64>,
    /// Next to a rest point, the last solve gave it the ramp form: it is no
    /// longer than the jerk-limited distance to its cap (see
    /// [`RAMP_REACH`]), on a three-axis interval (a five-axis block's
    /// joints keep the quadratic and the acceleration step at rest,
    /// [`rest_accel`]).
    ramp: bool,
}

impl WPiece {
    #[inline]
    fn h(&self) -> f64 {
        self.x1 - self.x0
    }
}

/// A lowered override's braking curve (see [`Window::solve`]): the feed
/// limits of the pieces before `until` may not fall below the speed of
/// `stop`, started at arc length `at`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lift {
    /// Where the braking starts (the end of the kept freeze piece), mm.
    pub at: f64,
    /// The braking from the machine's state there.
    pub stop: Stop,
    /// Where it no longer lifts the limits, mm (the re-solve's plan is at
    /// the new feed limit there: infinite for that re-solve itself).
    pub until: f64,
}

/// Where a re-solve starts (see [`Window::freeze`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Freeze {
    /// Keep the pieces before this index as they are, and its coefficient.
    At(usize),
    /// Plan from rest at this arc length.
    Rest(f64),
}

/// What the last solve did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SolveStats {
    /// Unknowns.
    pub variables: usize,
    /// Rows.
    pub rows: usize,
    /// Interior-point iterations (all passes).
    pub iterations: u32,
    /// Refinement passes that improved the plan.
    pub passes: u32,
    /// The program could not be planned through the old end of the queue:
    /// the machine comes to rest there.
    pub fell_back: bool,
    /// The linear program failed even so: the new stretch is planned as a
    /// crawl that rests at every knot (feasible by construction; slow).
    pub crawled: bool,
    /// The solved stretch, from the first unknown to the rest point at its end, mm.
    pub range: (f64, f64),
}

/// Counters over every solve of a window (diagnostics and benchmarks).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PlanTotals {
    /// Linear programs solved (first passes).
    pub solves: u64,
    /// Refinement passes that improved a plan.
    pub passes: u64,
    /// Interior-point iterations, all passes.
    pub iterations: u64,
    /// Warm first passes (near a kept plan, see `Pass::Warm`) that failed
    /// and were tried again as a plain first pass.
    pub warm_failed: u64,
    /// First passes that failed and were retried with the rows past the
    /// kept plan as loose as that plan's (see `kept_caps`).
    pub kept_rows: u64,
    /// Solves whose passes from the freeze point all failed and that kept
    /// the plan whole up to its last rest point instead, planned from rest
    /// there (see [`Window::solve`]): no stop added.
    pub kept_to_rest: u64,
    /// Solves that kept a rest point at the old end of the queue.
    pub fell_back: u64,
    /// Solves that fell back to the crawl.
    pub crawled: u64,
    /// Rebuilds that left pieces uncut for lack of room in the program.
    pub uncut: u64,
    /// Linear programs (any pass) whose per-axis jerk rows did not all fit:
    /// the farthest pieces' were aggregated, one row per axis (slower
    /// there until a re-solve plans them again).
    pub aggregated: u64,
    /// Of those, rebuilds that left a rest point ungraded (the grading next
    /// to rest points goes first: only where the rests alone need more
    /// room than there is).
    pub ungraded: u64,
    /// The last solver failure (a fallback or crawl followed).
    pub last_failure: Option<LpError>,
    /// Feed holds planned through the look-ahead (`BlockPlanner::hold`).
    pub holds: u64,
    /// Of those, holds that braked more gently than the tangential limits
    /// allow (the linear program could not follow the fastest stop).
    pub holds_softened: u64,
    /// Holds the linear program could not plan at any softening: the
    /// executor's closed-form stop ran.
    pub holds_unplanned: u64,
}

impl PlanTotals {
    /// Solves that failed and were tried again with other rows (a warm
    /// first pass, then the kept plan's rows): the same motion, more work.
    pub fn retries(&self) -> u64 {
        self.warm_failed + self.kept_rows
    }
    /// Solves that added stops the program does not ask for: a rest kept
    /// at the old end of the queue, or a crawl.
    pub fn added_stops(&self) -> u64 {
        self.fell_back + self.crawled
    }
}

/// The linear program's pull towards the pieces' limits (see
/// [`LpOptions::pull`]): where the time objective is flat (pieces at the
/// same limit), it picks the fastest plan, and one that does not depend on
/// rows that do not bind or on round-off.
const PULL: f64 = 1e-4;

/// Pieces shorter than this fraction of the grid step are merged into their
/// neighbour (round-off between a block end and a grid line).
pub const SLIVER: f64 = 1e-3;

/// Smallest squared speed the objective's weights use, as a fraction of the
/// top speed's square (relative, so the plan does not depend on the units).
const MIN_SPEED2: f64 = 1e-12;

/// The look-ahead data: intervals from the window start to the end of the
/// queue, the rest points in it, and the current solution's pieces.
#[derive(Clone, Debug)]
struct Data {
    cfg: InterpConfig,
    h: f64,
    /// Intervals `g_base ..g_base + n_int` (a ring).
    g_base: i64,
    int_head: usize,
    n_int: usize,
    ints: [Interval; INTERVALS],
    /// Rest points in the window, ascending.
    stops: [f64; MAX_STOPS],
    n_stops: usize,
    /// The solution's pieces from the window start to the tail.
    pieces: [WPiece; WINDOW],
    n_pieces: usize,
    /// Length and coefficient of the piece before the first one (when the
    /// first piece does not start at rest).
    prev: (f64, f64),
    /// End of the queue, mm.
    tail: f64,
    /// Where the window starts at rest while nothing is planned yet.
    origin: f64,
    /// Rebuilds that left pieces uncut (see [`PlanTotals::uncut`]).
    uncut: u64,
    /// Programs with aggregated rows (see [`PlanTotals::aggregated`]).
    aggregated: u64,
    /// The most rows one linear program may hold before the farthest
    /// pieces' per-axis rows are aggregated ([`MAX_ROWS`]; lower in tests).
    max_rows: usize,
    /// Where the last solve's aggregated pieces begin, in any of its passes
    /// (`+inf`: none): the next re-solve starts at or before it (see
    /// [`Window::freeze`]).
    agg_x: f64,
    /// See [`PlanTotals::ungraded`].
    ungraded: u64,
    /// The last rest point dropped from `stops` (behind the machine or the
    /// kept pieces; `-inf`: none): the pieces after it are still graded
    /// from it ([`Self::natural_start`]).
    rest_behind: f64,
}

/// Scratch of the linear program.
#[derive(Clone, Debug)]
struct Scratch {
    lp: LpWork<REGION, MAX_ROWS>,
    c: [f64; REGION],
    lo: [f64; REGION],
    hi: [f64; REGION],
    x: [f64; REGION],
    /// Per piece: the squared speed no plan can exceed there (see [`reach_caps`]).
    cap2: [f64; WINDOW],
    /// The unknowns' caps of the first pass (`cap2` from `first` on), which
    /// every refinement pass's trust region stays within.
    first_cap2: [f64; REGION],
    /// The unknowns before a refinement pass.
    backup_x: [f64; REGION],
    /// The plan before a solve, to fall back on.
    backup: [WPiece; WINDOW],
    /// How many pieces `backup` holds.
    backup_n: usize,
    /// Where its pieces planned under aggregated rows begin (`+inf`: none).
    backup_agg: f64,
}

/// What [`Window::roll_back`] restores: the window's intervals and rest
/// points at the end of the queue before a block was sampled into it (the
/// intervals themselves are kept in the window, one mark at a time).
#[derive(Clone, Copy, Debug)]
pub struct QueueEndMark {
    /// End of the queue, mm.
    s: f64,
    /// One past the last interval held.
    g_end: i64,
    /// The intervals kept: `n` of them from `g0`.
    g0: i64,
    n: usize,
    /// Whether a rest point lay at the end of the queue.
    stop_at_s: bool,
}

/// Intervals a mark keeps, up to the one holding the end of the queue: a
/// junction's limit reaches back two ticks at its speed and a stationary
/// point's law window (each at most a grid step, which is at least a
/// tick's travel at the top speed), its samples lie at the end.
const MARK_INTERVALS: usize = 6;

/// Where the machine is among the window's pieces, intervals and rest
/// points: all a solve or a push depends on its position through.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MachinePlace {
    /// Pieces that start at or before it.
    started: usize,
    /// Pieces that end at or before it.
    ended: usize,
    /// Its grid interval.
    g: i64,
    /// Rest points before it.
    rests_behind: usize,
    /// The window's first interval (moved on as the machine goes).
    g_base: i64,
    /// The window's pieces.
    n_pieces: usize,
}

/// Pieces past the first one after the machine a re-solve of everything
/// ahead (`BlockPlanner::replan`) is tried from at the steepest braking
/// rate, when that rate finds no plan from that one (and before the
/// gentler rates): the plan keeps its pieces a little longer.
/// Right after a resume turned a hold's braking around on pieces graded at
/// an eighth of the grid step, every override (raised or lowered) failed
/// through every rate from the first two pieces after the machine and
/// crawled (`homer-q2` at F6000), and found a plan at once from the third.
/// A re-solve that keeps its plan when every try fails (a raised override,
/// one given while braking to a hold) tries them too: a raised override at
/// a ramp into a rest point, pinned by its kept neighbour and its own jerk,
/// failed through every rate from the first piece (eighteen linear
/// programs, 50–70 ms in the service) and found a plan from the next.
pub const LATER_FREEZES: usize = 2;

/// The look-ahead window and its solver.
#[derive(Clone, Debug)]
pub struct Window {
    data: Data,
    scratch: Scratch,
    /// The feed override the current plan was solved under (set by a
    /// solve that succeeds only).
    ovr: f64,
    /// What the last solve did.
    pub last: SolveStats,
    /// Counters over every solve.
    pub totals: PlanTotals,
    /// Called after every iteration of the linear program (diagnostics).
    pub trace: Option<fn(lp::Iteration)>,
    /// Pieces past the first one after the machine that a re-solve of
    /// everything ahead (`BlockPlanner::replan`) is tried from when the
    /// steepest braking rate finds no plan from that one
    /// ([`LATER_FREEZES`]; 0 to try none, as before 2026-12-07).
    pub later_freezes: usize,
    /// A re-solve frozen inside an interval keeps the kept plan's pieces
    /// to the interval's end (see `Data::rebuild_from`); `false` cuts them
    /// afresh, as before 2026-12-07 (to reproduce what that failed on).
    pub kept_pieces: bool,
    /// The intervals of the last [`Self::mark`].
    saved: [Interval; MARK_INTERVALS],
    /// Where the pieces of the last crawl end (`-inf`: none left): until
    /// the machine passes it, every re-solve starts right after the
    /// machine (see [`Self::freeze`]).
    crawl_end: f64,
    /// Where the machine was when the crawl was last planned again
    /// ([`Self::take_crawl_retry`]).
    crawl_tried: f64,
}

impl Data {
    /// The rest points held, in order.
    fn rests(&self) -> &[f64] {
        &self.stops[..self.n_stops]
    }

    /// Where `x` is or would go among the rest points: the first at or
    /// after it.
    fn rest_slot(&self, x: f64) -> usize {
        self.rests().partition_point(|&s| s < x)
    }

    /// Where the plan ends (at rest): its last piece's end, or where it
    /// starts with no piece.
    fn plan_end(&self) -> f64 {
        if self.n_pieces == 0 {
            self.origin
        } else {
            self.pieces[self.n_pieces - 1].x1
        }
    }

    #[inline]
    fn slot(&self, g: i64) -> usize {
        debug_assert!(g >= self.g_base && g < self.g_base + self.n_int as i64);
        (self.int_head + (g - self.g_base) as usize) % INTERVALS
    }

    fn interval(&self, g: i64) -> &Interval {
        &self.ints[self.slot(g)]
    }

    /// The coefficient of piece `q` (`q = −1`: the fixed neighbour before the window).
    fn coef(&self, q: isize) -> f64 {
        if q < 0 {
            self.prev.1
        } else {
            self.pieces[q as usize].d
        }
    }

    /// Coefficients of the knot value at the start of piece `i` on the
    /// unknowns of pieces `(i−1, i)` (zero at a rest point).
    fn knot(&self, i: usize) -> [f64; 2] {
        let p = &self.pieces[i];
        if p.rest_start {
            return [0.0, 0.0];
        }
        let h = p.h();
        let hq = if i == 0 {
            self.prev.0
        } else {
            self.pieces[i - 1].h()
        };
        [h / (hq + h), hq / (hq + h)]
    }

    /// How piece `i`'s `S` runs ([`Form`]): a ramp next to one rest point,
    /// so that the jerk is used from the rest on, where the solve chose it
    /// ([`WPiece::ramp`]); the quadratic elsewhere, and on a piece that
    /// rests at both ends.
    fn form(&self, i: usize) -> Form {
        let p = &self.pieces[i];
        let rest_end = i + 1 >= self.n_pieces || self.pieces[i + 1].rest_start;
        if p.rest_start == rest_end || !p.ramp {
            Form::Quadratic
        } else if p.rest_start {
            Form::FromRest
        } else {
            Form::ToRest
        }
    }

    /// Piece `i` of the current solution with its knot values.
    fn piece(&self, i: usize) -> Piece {
        let w = &self.pieces[i];
        let k0 = self.knot(i);
        let e0 = k0[0] * self.coef(i as isize - 1) + k0[1] * w.d;
        let e1 = if i + 1 >= self.n_pieces {
            0.0
        } else {
            let k1 = self.knot(i + 1);
            k1[0] * w.d + k1[1] * self.pieces[i + 1].d
        };
        Piece {
            x0: w.x0,
            h: w.h(),
            e0,
            d: w.d,
            e1,
            form: self.form(i),
        }
    }

    /// The per-axis samples on piece `p` (from its interval and, within
    /// round-off of its ends, its neighbours': a sample on a knot belongs to
    /// both pieces, whichever interval it was stored in).
    fn piece_samples<'a>(
        &'a self,
        p: &'a WPiece,
        rest_end: bool,
    ) -> impl Iterator<Item = &'a AxisSample> + 'a {
        // Its own samples, those at its ends included (the jerk jumps at a
        // knot: a sample there bounds both sides). A short piece with no
        // sample at an end (cut next to a rest point, or where a limit
        // changes) is checked there against the nearest sample past that
        // end, at the end, if it lies within the piece's length or a sample
        // spacing; samples lie on a grid of that spacing, so the reach stops
        // a hair short of it (whether a sample counts must not turn on
        // round-off).
        let tol = SLIVER * self.h;
        let reach = if p.h() < 0.5 * self.h {
            p.h().max(self.h / SUB as f64) * (1.0 - SUB_SNAP)
        } else {
            tol
        };
        let held = |g: i64| g >= self.g_base && g < self.g_base + self.n_int as i64;
        let near = move || {
            (p.g - 1..=p.g + 1)
                .filter(move |&g| held(g))
                .flat_map(move |g| {
                    let it = self.interval(g);
                    it.samples[..it.n_samples as usize].iter()
                })
        };
        // A block's end at a rest the piece starts from, or a block's
        // start at a rest it ends at, is the other side's.
        let across = move |smp: &AxisSample| {
            (p.rest_start && smp.side < 0 && smp.s <= p.x0 + tol)
                || (rest_end && smp.side > 0 && smp.s >= p.x1 - tol)
        };
        let own =
            move |smp: &&AxisSample| smp.s >= p.x0 - tol && smp.s <= p.x1 + tol && !across(smp);
        // An end with no sample of its own at it: a piece cut short (next
        // to a rest point, where a limit changes) may hold one sample at one
        // end and none near the other, where `C‴` may be several percent
        // higher (the Y axis of `homer-q1` turned on the table passed
        // 1.0007× its jerk on a 12.5 µm piece sampled at its start only).
        let bare = move |before: bool| {
            let end = if before { p.x0 } else { p.x1 };
            !near().any(|smp| own(&smp) && libm::fabs(smp.s - end) <= tol)
        };
        // Nor across a block junction: past a block's end sample (or a
        // junction's) before the piece, or a block's start sample after it,
        // the derivatives are another block's (a blend's `C‴` held the line
        // after it near zero speed).
        let junction = move |smp: &AxisSample, before: bool| {
            smp.junction || if before { smp.side < 0 } else { smp.side > 0 }
        };
        // The nearest such sample on that side of the piece.
        let wall = move |before: bool| {
            let at = near()
                .filter(move |smp| junction(smp, before))
                .map(|smp| smp.s);
            if before {
                at.filter(|&s| s < p.x0 + tol)
                    .fold(f64::NEG_INFINITY, f64::max)
            } else {
                at.filter(|&s| s > p.x1 - tol).fold(f64::INFINITY, f64::min)
            }
        };
        let closest = move |before: bool| {
            let none = bare(before);
            let wall = if none { wall(before) } else { 0.0 };
            near()
                .filter(move |smp| {
                    let gap = if before { p.x0 - smp.s } else { smp.s - p.x1 };
                    // (Not across a rest point: another block's
                    // derivatives, a fillet's curvature.)
                    let (a, b) = if before {
                        (smp.s, p.x0 + tol)
                    } else {
                        (p.x1 - tol, smp.s)
                    };
                    let past = if before { smp.s < wall } else { smp.s > wall };
                    none && gap > 0.0
                        && gap <= reach
                        && !past
                        && !junction(smp, before)
                        && !self.stop_within(a, b)
                })
                .min_by(move |a, b| {
                    let da = if before { p.x0 - a.s } else { a.s - p.x1 };
                    let db = if before { p.x0 - b.s } else { b.s - p.x1 };
                    da.total_cmp(&db)
                })
        };
        near()
            .filter(own)
            .chain(closest(true))
            .chain(closest(false))
    }

    /// Whether a rest point lies in `[a, b]`.
    fn stop_within(&self, a: f64, b: f64) -> bool {
        self.rests().get(self.rest_slot(a)).is_some_and(|&x| x <= b)
    }

    /// The squared speed limit of piece `i` at override `ovr`.
    fn limit2(&self, i: usize, ovr: f64, lift: &Option<Lift>) -> f64 {
        let p = &self.pieces[i];
        let top = self.cfg.max_path_speed;
        let mut v = p.machine.min(ovr * p.feed).min(top);
        if let Some(l) = lift
            && p.x0 < l.until
        {
            // The feed may not fall faster than the machine can brake.
            // Over the whole piece: the speed still rises at first while
            // an acceleration the machine had ramps down.
            let vb = l.stop.top_speed_over(p.x0 - l.at, p.x1 - l.at);
            v = v.max(vb.min(p.machine).min(top));
        }
        if !v.is_finite() {
            v = top;
        }
        v * v
    }

    /// Drop intervals and rest points before arc length `x`.
    fn drop_before(&mut self, x: f64) {
        let g = index_of(x, self.h);
        while self.n_int > 0 && self.g_base < g {
            self.int_head = (self.int_head + 1) % INTERVALS;
            self.g_base += 1;
            self.n_int -= 1;
        }
        if self.n_int == 0 {
            self.g_base = g;
        }
        self.drop_rests_before(x);
    }

    /// Drop the rest points before arc length `x`, remembering the last
    /// one ([`Data::rest_behind`]).
    fn drop_rests_before(&mut self, x: f64) {
        let k = self.rest_slot(x);
        if k > 0 {
            self.rest_behind = self.rest_behind.max(self.stops[k - 1]);
            self.stops.copy_within(k..self.n_stops, 0);
            self.n_stops -= k;
        }
    }

    /// How far before the end of a plan a re-solve must start for a
    /// machine at up to `v` to be free to brake anew (1.5 stopping
    /// distances and two grid steps).
    fn replan_reach(&self, v: f64) -> f64 {
        let (a, j) = (self.cfg.planned_accel(), self.cfg.max_path_jerk);
        1.5 * Stop::new(v, a, a, j).distance() + 2.0 * self.h
    }

    /// Rebuild pieces `from..` (starting at `x`) up to the tail out of the
    /// intervals and rest points.
    /// Remember the caps the rows of pieces `first..` were solved under.
    fn note_caps(&mut self, cap2: &[f64; WINDOW], first: usize) {
        for i in first..self.n_pieces {
            self.pieces[i].solved_cap = Some(cap2[i]);
        }
    }

    fn rebuild_from(
        &mut self,
        from: usize,
        mut x: f64,
        mut rest: bool,
        end: f64,
        keep: bool,
    ) -> Result<(), PlanError> {
        let mut n = from;
        let mut si = self.rests().partition_point(|&s| s <= x);
        // A cut closer than this to the next one would leave a sliver piece
        // (round-off between a block end and a grid line): merge it.
        let sliver = SLIVER * self.h;
        let first_line = (index_of(x, self.h) + 1) as f64 * self.h;
        // The kept plan's pieces are taken up to here.
        let mut kept_until = x;
        while x < end {
            let g0 = index_of(x, self.h);
            let mut x1 = ((g0 + 1) as f64 * self.h).min(end);
            if x1 - x <= sliver {
                // Just before a grid line (round-off): run to the next one.
                x1 = ((g0 + 2) as f64 * self.h).min(end);
            }
            // The rest of the freeze point's interval keeps the kept plan's
            // pieces as they are (uncut: they were cut when planned). Cut
            // afresh, it could lose cuts the room then gave the kept plan
            // (a slow stretch's eighths come last), and the kept piece,
            // whose end its neighbour's length and coefficient shape, could
            // not be continued: every pass failed (`ruota_dentata-q1` under
            // the knob).
            // The last plan's piece that starts here, if any.
            let prior = (n < self.n_pieces && self.pieces[n].x0 == x).then(|| self.pieces[n]);
            let mut old = false;
            if let Some(p) = prior
                && keep
                && x < first_line - sliver
                && p.x1 > x + sliver
                && p.x1 <= x1 + sliver
            {
                x1 = x1.min(p.x1);
                old = true;
            }
            let mut stop_here = false;
            if si < self.n_stops && self.stops[si] <= x1 + sliver {
                old = old && self.stops[si] == x1;
                x1 = self.stops[si];
                stop_here = true;
                si += 1;
            } else if end - x1 <= sliver {
                old = old && end == x1;
                x1 = end;
            }
            if old && kept_until == x {
                kept_until = x1;
            }
            if x1 > x {
                if n >= WINDOW {
                    return Err(PlanError::Full);
                }
                let (d, ramp) = prior.map_or((0.0, false), |p| (p.d, p.ramp));
                self.pieces[n] = WPiece {
                    x0: x,
                    x1,
                    g: index_of(0.5 * (x + x1), self.h),
                    rest_start: rest,
                    d,
                    machine: f64::INFINITY,
                    feed: f64::INFINITY,
                    solved_cap: None,
                    ramp,
                };
                n += 1;
                rest = false;
            }
            if stop_here {
                rest = true;
            }
            x = x1;
        }
        self.n_pieces = n;
        self.refine_pieces(from, kept_until);
        Ok(())
    }

    /// Smallest machine-law and feed-law speeds over `[x0, x1]` (from the
    /// sub-ranges it overlaps).
    fn range_limits(&self, x0: f64, x1: f64) -> (f64, f64) {
        let (mut m, mut f) = self.sub_range_limits(x0, x1);
        for sp in self.spans_near(x0, x1) {
            if sp.overlaps(x0, x1, self.h / SUB as f64) {
                m = m.min(sp.machine);
                f = f.min(sp.feed);
            }
        }
        (m, f)
    }

    /// [`Self::range_limits`] without the spans.
    fn sub_range_limits(&self, x0: f64, x1: f64) -> (f64, f64) {
        let hs = self.h / SUB as f64;
        let snap = SUB_SNAP;
        let k0 = libm::floor(x0 / hs + snap) as i64;
        let k1 = (libm::ceil(x1 / hs - snap) as i64 - 1).max(k0);
        let (mut m, mut f) = (f64::INFINITY, f64::INFINITY);
        let held = |g: i64| g >= self.g_base && g < self.g_base + self.n_int as i64;
        for k in k0..=k1 {
            let g = k.div_euclid(SUB as i64);
            if held(g) {
                let it = self.interval(g);
                let j = k.rem_euclid(SUB as i64) as usize;
                m = m.min(it.machine[j]);
                f = f.min(it.feed[j]);
            }
        }
        (m, f)
    }

    /// The spans that may touch `[x0, x1]`: those of its intervals and the
    /// one before (a span is narrower than a sub-range and is held where it
    /// starts).
    fn spans_near(&self, x0: f64, x1: f64) -> impl Iterator<Item = &Span> + '_ {
        let held = |g: i64| g >= self.g_base && g < self.g_base + self.n_int as i64;
        (index_of(x0, self.h) - 1..=index_of(x1, self.h))
            .filter(move |&g| held(g))
            .flat_map(move |g| {
                let it = self.interval(g);
                it.spans[..it.n_spans as usize].iter()
            })
    }

    /// Where a piece that starts at `x` would start had no freeze point cut
    /// it: the grid line or rest point at or before `x`, and whether it is
    /// a rest point. The rest point may have been dropped already (behind
    /// the machine, which may be on the piece after it): graded from the
    /// grid line instead, the last piece before the next rest point lost
    /// the cuts the kept plan was solved on, and every pass failed (a
    /// random `G61` program crawled four times).
    fn natural_start(&self, x: f64) -> (f64, bool) {
        let g = index_of(x, self.h) as f64 * self.h;
        let rests = self.rests();
        let k = rests.partition_point(|&r| r <= x);
        let r = match k.checked_sub(1) {
            Some(k) => rests[k],
            None if self.rest_behind <= x => self.rest_behind,
            None => f64::NEG_INFINITY,
        };
        if r >= g { (r, true) } else { (g, false) }
    }

    /// Cuts inside piece `p` (ascending, none within a sliver of another or
    /// of its ends) into `out`; returns how many:
    /// - where the speed limit of its sub-ranges changes by more than
    ///   [`RUN_RATIO`], so a slow point limits only its own stretch;
    /// - next to a rest point, pieces that grow geometrically away from it
    ///   ([`GRADE`], on lines [`LINE_REST_GRADE`]): leaving a rest with
    ///   bounded jerk, `S` grows like `s^(4/3)`, which one quadratic piece
    ///   of the grid's length follows poorly (the plan would creep out of
    ///   every rest).
    ///
    /// `level` says which of them (see [`CutLevel`]).
    fn cuts(
        &self,
        p: &WPiece,
        rest_end: bool,
        level: CutLevel,
        out: &mut [f64; MAX_CUTS],
    ) -> usize {
        let sliver = SLIVER * self.h;
        let mut raw = [0.0; MAX_CUTS];
        let mut k = 0;
        // (Cuts past the capacity are dropped: fewer pieces, each still
        // limited over its whole extent.)
        let mut push = |x: f64| {
            if k < MAX_CUTS && x > p.x0 && x < p.x1 {
                raw[k] = x;
                k += 1;
            }
        };
        let hs = self.h / SUB as f64;
        let sub = |a: f64, b: f64| {
            let (m, f) = self.sub_range_limits(a, b);
            m.min(f)
        };
        // Graded from where the piece would start had no freeze point cut
        // it, so that a re-solve frozen inside a graded stretch keeps its
        // cuts (and the kept plan stays feasible).
        let (x0, rest_before) = self.natural_start(p.x0);
        let (rs, re) = (p.rest_start || rest_before, rest_end);
        let len = p.x1 - x0;
        let scale = |both: bool| self.h.min(if both { 0.5 * len } else { len });
        // Finer where the piece is a line (no per-axis samples: its axes'
        // jerk is the path's, which the tangential rows hold everywhere) and
        // a tick is at most half of its longest part: the jerk phase out of
        // a rest ends `A³/(6J²)` (0.13 mm at the defaults) out. On a curve
        // the graded pieces get shorter than its per-axis samples' spacing,
        // and the jerk between samples passed an axis's limit.
        let grade: &[f64] =
            if 2.0 * self.cfg.period <= SLOW_PIECE_TIME && self.interval(p.g).n_samples == 0 {
                &LINE_REST_GRADE
            } else {
                &GRADE
            };
        if rs {
            let sc = scale(re);
            for f in grade {
                push(x0 + sc * f);
            }
        }
        if re {
            let sc = scale(rs);
            for f in grade.iter().rev() {
                push(p.x1 - sc * f);
            }
        }
        // Spans inside: cut at their ends, graded away from a slow one.
        for sp in self
            .spans_near(p.x0, p.x1)
            .filter(|_| level >= CutLevel::SpanEnds)
        {
            if !sp.overlaps(p.x0, p.x1, hs) {
                continue;
            }
            let v = sp.machine.min(sp.feed);
            push(sp.x0);
            push(sp.x1);
            // A rest point inside the span is slower still, and graded
            // already: grading the span too spends cuts for nothing.
            if level < CutLevel::All || self.stop_within(sp.x0 - sliver, sp.x1 + sliver) {
                continue;
            }
            if RUN_RATIO * v < sub(sp.x0 - hs, sp.x0) {
                for f in GRADE {
                    push(sp.x0 - self.h.min(sp.x0 - x0) * f);
                }
            }
            if RUN_RATIO * v < sub(sp.x1, sp.x1 + hs) {
                for f in GRADE {
                    push(sp.x1 + self.h.min(p.x1 - sp.x1) * f);
                }
            }
        }
        // Sub-range boundaries where the limit changes (not graded: the
        // pieces it would take shorten the look-ahead's reach, measured
        // slower on dense programs). Scanned from where the piece would
        // start had no freeze point cut it, as the grading: from the freeze
        // point, a change was cut elsewhere than in the kept plan, and its
        // speed at the freeze point lay above the new first piece's limit
        // (a crawl with the override turned every 37 ms, ruota_dentata-q2).
        let mut b = (libm::floor(x0 / hs + 1e-9) + 1.0) * hs;
        let (mut lo, mut hi) = {
            let v = sub(x0, b.min(p.x1));
            (v, v)
        };
        while level >= CutLevel::All && b < p.x1 - sliver {
            let v = sub(b, (b + hs).min(p.x1));
            let (nlo, nhi) = (lo.min(v), hi.max(v));
            if nhi > RUN_RATIO * nlo {
                push(b);
                (lo, hi) = (v, v);
            } else {
                (lo, hi) = (nlo, nhi);
            }
            b += hs;
        }
        // (Only where a tick is at most half of it: a tick as long as a
        // part averages the speed over it, and at a 4 ms period the tick
        // into a slow point passed the chord-error law at its end.)
        if level == CutLevel::Slow && 2.0 * self.cfg.period <= SLOW_PIECE_TIME {
            // At fixed places of the grid, from the interval's own limits
            // (not the piece's, whose ends depend on the other cuts): a
            // curve cut into two blocks keeps the same pieces.
            let xg = p.g as f64 * self.h;
            let (m, f) = self.sub_range_limits(xg, xg + self.h);
            let v = m.min(f);
            // Not where a span holds the speed (a junction, a corner's
            // blend): there the plan is flat at the span's speed, and more
            // pieces only let it ripple.
            let (a, b) = (xg - self.h, xg + 2.0 * self.h);
            let in_span = self.spans_near(a, b).any(|sp| sp.overlaps(a, b, hs));
            // And only inside a slow stretch of three intervals or more:
            // cutting an isolated dip (a corner's blend of 0.1 mm) let the
            // plan undershoot the blend's speed before it.
            let slow = |x: f64| {
                let (m, f) = self.sub_range_limits(x, x + self.h);
                RUN_RATIO * m.min(f) < f
            };
            if v > 0.0 && RUN_RATIO * v < f && !in_span && slow(xg - self.h) && slow(xg + self.h) {
                let mut q = 1;
                while q < SLOW_PIECE_PARTS && self.h > q as f64 * v * SLOW_PIECE_TIME {
                    q *= 2;
                }
                for k in 1..q {
                    push(xg + self.h * k as f64 / q as f64);
                }
            }
        }
        // Sort (few), then drop slivers.
        raw[..k].sort_unstable_by(|a, b| a.total_cmp(b));
        let mut m = 0;
        let mut last = p.x0;
        for &c in &raw[..k] {
            if c - last > sliver && p.x1 - c > sliver {
                out[m] = c;
                m += 1;
                last = c;
            }
        }
        m
    }

    /// Cut the pieces `from..` (see [`Self::cuts`]), as many cuts as one
    /// linear program can hold, level by level ([`CutLevel`]), each level
    /// nearest the start first; then give every piece its speed limits.
    /// Pieces that end by `kept_until` are the kept plan's, cut already
    /// (see [`Self::rebuild_from`]): left as they are.
    fn refine_pieces(&mut self, from: usize, kept_until: f64) {
        let n = self.n_pieces;
        if n <= from {
            return;
        }
        let budget = REGION.saturating_sub(n - from + 8).min(WINDOW - n);
        let mut counts = [0u8; WINDOW];
        let mut levels = [CutLevel::Rests; WINDOW];
        let mut cut = [0.0; MAX_CUTS];
        let mut extra = 0usize;
        let rest_end = |d: &Self, i: usize| i + 1 >= n || d.pieces[i + 1].rest_start;
        // Pieces `a..b` take the cuts of `level`, nearest first, while
        // they fit; returns where they stopped.
        let mut claim = |d: &Self, a: usize, b: usize, level: CutLevel| {
            let mut i = a;
            while i < b {
                let p = d.pieces[i];
                if p.x1 <= kept_until {
                    i += 1;
                    continue;
                }
                let m = d.cuts(&p, rest_end(d, i), level, &mut cut);
                let total = extra - counts[i] as usize + m;
                if total > budget {
                    break;
                }
                counts[i] = m as u8;
                levels[i] = level;
                extra = total;
                i += 1;
            }
            i
        };
        // The stretch up to the first rest point joins the kept plan at
        // speed: all its cuts first (a slow span left uncut there holds
        // the whole piece below the speed the kept plan arrives with).
        let head = (from + 1..n)
            .find(|&i| self.pieces[i].rest_start)
            .unwrap_or(n);
        let mut reach = claim(self, from, head, CutLevel::All);
        if reach == head {
            // Pieces `head..reach` hold the cuts of the last level.
            reach = n;
            for level in [CutLevel::Rests, CutLevel::SpanEnds, CutLevel::All] {
                reach = claim(self, head, reach, level);
                if level == CutLevel::Rests && reach < n {
                    self.ungraded += 1;
                }
            }
            // Slow pieces are cut last, with the room every other cut left,
            // nearest the machine first.
            if reach == n {
                claim(self, from, n, CutLevel::Slow);
            }
        } else if head < n {
            self.ungraded += 1;
        }
        self.uncut += u64::from(reach < n);
        let mut w = n + extra;
        for i in (from..n).rev() {
            let p = self.pieces[i];
            let m = counts[i] as usize;
            if m == 0 {
                w -= 1;
                self.pieces[w] = p;
                continue;
            }
            let mm = self.cuts(&p, rest_end(self, i), levels[i], &mut cut);
            debug_assert_eq!(mm, m);
            let mut x1 = p.x1;
            for j in (0..=m).rev() {
                let x0 = if j == 0 { p.x0 } else { cut[j - 1] };
                w -= 1;
                self.pieces[w] = WPiece {
                    x0,
                    x1,
                    g: p.g,
                    rest_start: j == 0 && p.rest_start,
                    d: if j == 0 { p.d } else { 0.0 },
                    machine: f64::INFINITY,
                    feed: f64::INFINITY,
                    solved_cap: None,
                    ramp: j == 0 && p.ramp,
                };
                x1 = x0;
            }
        }
        debug_assert_eq!(w, from);
        self.n_pieces = n + extra;
        for i in from..self.n_pieces {
            let (x0, x1) = (self.pieces[i].x0, self.pieces[i].x1);
            let (m, f) = self.range_limits(x0, x1);
            self.pieces[i].machine = m;
            self.pieces[i].feed = f;
        }
    }
}

impl Window {
    /// An empty window at rest at arc length `s`, grid spacing `h`.
    pub fn new(cfg: InterpConfig, h: f64, s: f64) -> Self {
        let open = Interval::open(&cfg);
        Window {
            data: Data {
                cfg,
                h,
                g_base: index_of(s, h),
                int_head: 0,
                n_int: 0,
                ints: [open; INTERVALS],
                stops: [0.0; MAX_STOPS],
                n_stops: 0,
                pieces: [WPiece::default(); WINDOW],
                n_pieces: 0,
                prev: (0.0, 0.0),
                tail: s,
                origin: s,
                uncut: 0,
                aggregated: 0,
                max_rows: MAX_ROWS,
                agg_x: f64::INFINITY,
                ungraded: 0,
                rest_behind: f64::NEG_INFINITY,
            },
            scratch: Scratch {
                lp: LpWork::new(),
                c: [0.0; REGION],
                lo: [0.0; REGION],
                hi: [0.0; REGION],
                x: [0.0; REGION],
                cap2: [0.0; WINDOW],
                first_cap2: [0.0; REGION],
                backup_x: [0.0; REGION],
                backup: [WPiece::default(); WINDOW],
                backup_n: 0,
                backup_agg: f64::INFINITY,
            },
            ovr: 1.0,
            last: SolveStats::default(),
            totals: PlanTotals::default(),
            trace: None,
            later_freezes: LATER_FREEZES,
            kept_pieces: true,
            saved: [open; MARK_INTERVALS],
            crawl_end: f64::NEG_INFINITY,
            crawl_tried: f64::NEG_INFINITY,
        }
    }

    /// Restart empty, at rest at arc length `s`.
    pub fn reset(&mut self, s: f64) {
        let d = &mut self.data;
        d.g_base = index_of(s, d.h);
        d.int_head = 0;
        d.n_int = 0;
        d.n_stops = 0;
        d.rest_behind = f64::NEG_INFINITY;
        d.n_pieces = 0;
        d.prev = (0.0, 0.0);
        d.tail = s;
        d.origin = s;
        d.agg_x = f64::INFINITY;
        self.crawl_end = f64::NEG_INFINITY;
    }

    /// Grid spacing, mm.
    pub fn h(&self) -> f64 {
        self.data.h
    }
    /// End of the queue, mm.
    pub fn tail(&self) -> f64 {
        self.data.tail
    }
    /// Feed override the current plan was solved under.
    pub fn feed_override(&self) -> f64 {
        self.ovr
    }
    /// Pieces of the current solution.
    pub fn n_pieces(&self) -> usize {
        self.data.n_pieces
    }
    /// Piece `i` of the current solution.
    pub fn piece(&self, i: usize) -> Piece {
        self.data.piece(i)
    }
    /// Where the plan from piece `from` on is last above the feed limit at
    /// override `ovr`: the end of the braking a lowered override made it
    /// follow (`from`'s start when it is nowhere above).
    pub fn braking_end(&self, from: usize, ovr: f64) -> f64 {
        let d = &self.data;
        let mut x = if from < d.n_pieces {
            d.pieces[from].x0
        } else {
            d.origin
        };
        for i in from..d.n_pieces {
            let (p, w) = (d.piece(i), &d.pieces[i]);
            let v = ovr * w.feed;
            if p.e0.max(p.d).max(p.e1) > v * v {
                x = w.x1;
            }
        }
        x
    }
    /// The data of the interval holding arc length `s` (diagnostics).
    pub fn interval_at(&self, s: f64) -> Option<&Interval> {
        let g = index_of(s, self.data.h);
        let d = &self.data;
        (g >= d.g_base && g < d.g_base + d.n_int as i64).then(|| d.interval(g))
    }
    /// The last linear program as held (diagnostics): rows, objective and
    /// bounds of its unknowns.
    pub fn lp_dump(&self) -> (usize, &[f64], &[f64], &[f64], &LpWork<REGION, MAX_ROWS>) {
        let n = self.last.variables;
        (
            n,
            &self.scratch.c[..n],
            &self.scratch.lo[..n],
            &self.scratch.hi[..n],
            &self.scratch.lp,
        )
    }
    /// Residuals of the last linear program (diagnostics).
    pub fn lp_residuals(&self) -> (f64, f64, f64) {
        self.scratch.lp.residuals
    }
    /// Does piece `i` start at a rest point?
    pub fn rest_start(&self, i: usize) -> bool {
        self.data.pieces[i].rest_start
    }

    /// Forget the intervals and rest points behind the machine (at arc
    /// length `machine`): no plan will ever reach back there.
    pub fn release_before(&mut self, machine: f64) {
        let d = &mut self.data;
        let g = index_of(machine, d.h) - 1;
        while d.n_int > 0 && d.g_base < g {
            d.int_head = (d.int_head + 1) % INTERVALS;
            d.g_base += 1;
            d.n_int -= 1;
        }
        d.drop_rests_before(machine);
    }

    /// Room for intervals up to `g` and `stops` more rest points, with the
    /// machine at arc length `machine`: the pieces from there to `g` must fit
    /// one linear program (see [`REGION`]).
    pub fn has_room(&self, g: i64, stops: usize, machine: f64) -> bool {
        let d = &self.data;
        let from = index_of(machine, d.h).max(d.g_base);
        let pieces = (g - from + 2).max(0) as usize + d.n_stops + stops;
        // (Margin: a fallback rest point or two, and the kept pieces before
        // the machine.)
        g < d.g_base + (INTERVALS - 2) as i64
            && d.n_stops + stops <= MAX_STOPS
            && pieces + 8 <= REACH
    }

    /// Make intervals up to `g` present (new ones open). False when full.
    pub fn extend_to(&mut self, g: i64) -> bool {
        if g >= self.data.g_base + (INTERVALS - 2) as i64 {
            return false;
        }
        let d = &mut self.data;
        let open = Interval::open(&d.cfg);
        while d.g_base + (d.n_int as i64) <= g {
            let k = (d.int_head + d.n_int) % INTERVALS;
            d.ints[k] = open;
            d.n_int += 1;
        }
        true
    }

    /// Lower the machine (`which = 0`) or feed (`1`) limit of the sub-ranges
    /// overlapping `(s0, s1)` to `v` (a point `s0 = s1` on a boundary lowers
    /// both sides), in the intervals held.
    pub fn lower_range(&mut self, s0: f64, s1: f64, which: usize, v: f64) {
        let hs = self.data.h / SUB as f64;
        let snap = SUB_SNAP;
        let (q0, q1) = (s0 / hs, s1 / hs);
        let (k0, k1) = if s1 > s0 {
            // The sub-ranges overlapping the open range.
            let k0 = libm::floor(q0 + snap) as i64;
            (k0, (libm::ceil(q1 - snap) as i64 - 1).max(k0))
        } else if libm::fabs(q0 - libm::round(q0)) <= snap {
            // A point on a boundary: both sides.
            let k = libm::round(q0) as i64;
            (k - 1, k)
        } else {
            let k = libm::floor(q0) as i64;
            (k, k)
        };
        let sub = SUB as i64;
        // (Only the intervals held: a range may reach far past them.)
        let d = &self.data;
        let k0 = k0.max(d.g_base * sub);
        let k1 = k1.min((d.g_base + d.n_int as i64) * sub - 1);
        let mut k = k0;
        while k <= k1 {
            let g = k.div_euclid(sub);
            let j0 = k.rem_euclid(sub) as usize;
            let j1 = if k1.div_euclid(sub) == g {
                k1.rem_euclid(sub) as usize
            } else {
                SUB - 1
            };
            if let Some(it) = self.interval_mut(g) {
                it.lower(j0, j1, which, v);
            }
            k = (g + 1) * sub;
        }
    }

    /// Lower the machine (`which = 0`) or feed (`1`) limit over exactly
    /// `[s0, s1]` (a point when equal; see [`Span`]); a range a sub-range
    /// wide or more, or one an interval has no room for, lowers the
    /// sub-ranges it overlaps ([`Self::lower_range`]).
    pub fn lower_exact(&mut self, s0: f64, s1: f64, which: usize, v: f64) {
        // (No limit, or NaN, lowers nothing: `min` keeps the other side.)
        if !(v < f64::INFINITY) {
            return;
        }
        let h = self.data.h;
        if s1 - s0 < h / SUB as f64
            && let Some(it) = self.interval_mut(index_of(s0, h))
        {
            let n = it.n_spans as usize;
            let at = it.spans[..n]
                .iter()
                .position(|sp| sp.x0 == s0 && sp.x1 == s1);
            let slot = match at {
                Some(i) => Some(i),
                None if n < SPANS => {
                    it.spans[n] = Span {
                        x0: s0,
                        x1: s1,
                        machine: f64::INFINITY,
                        feed: f64::INFINITY,
                    };
                    it.n_spans += 1;
                    Some(n)
                }
                None => None,
            };
            if let Some(i) = slot {
                let sp = &mut it.spans[i];
                let l = if which == 0 {
                    &mut sp.machine
                } else {
                    &mut sp.feed
                };
                *l = l.min(v);
                return;
            }
        }
        self.lower_range(s0, s1, which, v);
    }

    /// How many of the new spans starting at `starts` (in order) the
    /// intervals have room for, counting from the first: a span with no
    /// room would lower its whole sub-range ([`Self::lower_exact`]).
    pub fn spans_with_room(&self, starts: &[f64]) -> usize {
        let h = self.data.h;
        (0..starts.len())
            .take_while(|&k| {
                let g = index_of(starts[k], h);
                let here = starts[..k].iter().filter(|&&x| index_of(x, h) == g).count();
                self.interval_at(starts[k])
                    .is_some_and(|it| it.n_spans as usize + here < SPANS)
            })
            .count()
    }

    /// Lower the machine limit at the point `s` to `v` as narrowly as the
    /// window holds it without a new cut: the narrowest span that covers
    /// `s`, over its extent, else the sub-range `s` lies in. For a limit that
    /// must hold at `s` only (a per-axis sample with no room for its row):
    /// the sub-range held a soft machine's dolphin at 0.039 mm/s over 31 µm,
    /// the stationary point's steps hold it over 1 µm. (A point span of its
    /// own would cut the pieces there: tried, the same plans where the limit
    /// does not bind but for the new cuts, `homer-q1` 6 ms slower.)
    pub fn lower_at(&mut self, s: f64, v: f64) {
        if !(v < f64::INFINITY) {
            return;
        }
        let h = self.data.h;
        // The narrowest span over `s` (a stationary point's steps lie inside
        // its short block's span).
        let mut best: Option<(i64, usize, f64)> = None;
        for g in [index_of(s, h) - 1, index_of(s, h)] {
            if let Some(it) = self.interval_mut(g) {
                for (i, sp) in it.spans[..it.n_spans as usize].iter().enumerate() {
                    let width = sp.x1 - sp.x0;
                    if width > 0.0
                        && sp.x0 <= s
                        && s <= sp.x1
                        && best.is_none_or(|(_, _, w)| width < w)
                    {
                        best = Some((g, i, width));
                    }
                }
            }
        }
        if let Some((g, i, _)) = best
            && let Some(it) = self.interval_mut(g)
        {
            let sp = &mut it.spans[i];
            sp.machine = sp.machine.min(v);
            return;
        }
        self.lower_range(s, s, 0, v);
    }

    /// A junction at `s` (within `slack`) passed at `v` at most: the jump
    /// happens within the tick that crosses it, and the finite differences
    /// a drive sees span three, so the limit holds over the two ticks'
    /// travel at `v` each way ([`Self::lower_exact`]).
    pub fn lower_junction(&mut self, s: f64, slack: f64, v: f64) {
        let cfg = &self.data.cfg;
        if !(v < cfg.max_path_speed) {
            // Not slower than the machine goes anywhere: no limit.
            return;
        }
        let w = slack + JUNCTION_TICKS * v * cfg.period;
        self.lower_exact(s - w, s + w, 0, v);
    }

    /// A junction's curvature step at `s`, passed at `v` at most, takes
    /// `reserve` of each axis's jerk ([`crate::feed::jump_reserve`]). A third
    /// difference of the setpoints spans three ticks: one that sees the step
    /// sees the jerk up to three ticks' travel from it, so every sample
    /// there, offered before or after this, keeps the reserve.
    pub fn reserve_around_jump(&mut self, s: f64, v: f64, reserve: JumpReserve) {
        let cfg = &self.data.cfg;
        let ts = cfg.period;
        // (Three ticks at `v`, and what the acceleration adds over them.)
        let reach = JUMP_SEEN_TICKS * ts * (v + 0.5 * JUMP_SEEN_TICKS * cfg.max_path_accel * ts);
        let (x0, x1) = (s - reach, s + reach);
        let h = self.data.h;
        for g in sample_interval(x0, h)..=sample_interval(x1, h) {
            let Some(it) = self.interval_mut(g) else {
                continue;
            };
            let z = &mut it.jump;
            if !z.reserve.is_none() {
                // (The union of two is bounded by the larger reserve, falling
                // from the lower speed.)
                (z.x0, z.x1) = (z.x0.min(x0), z.x1.max(x1));
                z.v2 = z.v2.min(v * v);
            } else {
                (z.x0, z.x1, z.v2) = (x0, x1, v * v);
            }
            z.reserve = z.reserve.max(reserve);
            for smp in &mut it.samples[..it.n_samples as usize] {
                if smp.s >= x0 && smp.s <= x1 {
                    smp.reserve = smp.reserve.max(reserve);
                }
            }
        }
    }

    /// The zone of the junctions a sample at `s` keeps a reserve for
    /// ([`Self::reserve_around_jump`]), if any.
    pub fn jump_zone_at(&self, s: f64) -> Option<JumpZone> {
        let d = &self.data;
        let g = sample_interval(s, d.h);
        if g < d.g_base || g >= d.g_base + d.n_int as i64 {
            return None;
        }
        let z = d.interval(g).jump;
        (!z.reserve.is_none() && s >= z.x0 && s <= z.x1).then_some(z)
    }

    /// The data of interval `g`, if held.
    pub fn interval_mut(&mut self, g: i64) -> Option<&mut Interval> {
        let d = &mut self.data;
        if g >= d.g_base && g < d.g_base + d.n_int as i64 {
            let k = d.slot(g);
            Some(&mut d.ints[k])
        } else {
            None
        }
    }

    /// Remember the intervals and rest points at the end of the queue (at
    /// arc length `s`), to [`Self::roll_back`] to if the next block is
    /// refused.
    pub fn mark(&mut self, s: f64) -> QueueEndMark {
        let d = &self.data;
        let g = index_of(s, d.h);
        let g0 = (g + 1 - MARK_INTERVALS as i64).max(d.g_base);
        let g1 = g.min(d.g_base + d.n_int as i64 - 1);
        let n = (g1 - g0 + 1).max(0) as usize;
        for k in 0..n {
            self.saved[k] = *d.interval(g0 + k as i64);
        }
        QueueEndMark {
            s,
            g_end: d.g_base + d.n_int as i64,
            g0,
            n,
            stop_at_s: d.rests().contains(&s),
        }
    }

    /// Undo what a refused block sampled past `mark` (its intervals, what
    /// it added to those before it: junction limits and samples, its rest
    /// points), so that the next attempt samples it afresh: a sample
    /// appended again at every retry would fill its interval, which then
    /// lowers the speed there.
    pub fn roll_back(&mut self, mark: &QueueEndMark) {
        let d = &mut self.data;
        let held_end = d.g_base + d.n_int as i64;
        if held_end > mark.g_end {
            d.n_int = (mark.g_end - d.g_base).max(0) as usize;
        }
        for k in 0..mark.n {
            let g = mark.g0 + k as i64;
            if g >= d.g_base && g < d.g_base + d.n_int as i64 {
                let slot = d.slot(g);
                d.ints[slot] = self.saved[k];
            }
        }
        let keep = d
            .rests()
            .partition_point(|&x| x < mark.s || (x == mark.s && mark.stop_at_s));
        d.n_stops = keep;
    }

    /// Where the machine, at arc length `machine`, is among the pieces,
    /// intervals and rest points (see [`MachinePlace`]).
    pub fn machine_place(&self, machine: f64) -> MachinePlace {
        let d = &self.data;
        let p = &d.pieces[..d.n_pieces];
        MachinePlace {
            started: p.partition_point(|q| q.x0 <= machine),
            ended: p.partition_point(|q| q.x1 <= machine),
            g: index_of(machine, d.h),
            rests_behind: d.rest_slot(machine),
            g_base: d.g_base,
            n_pieces: d.n_pieces,
        }
    }

    /// The rest points held, in order, mm.
    pub fn rest_points(&self) -> &[f64] {
        self.data.rests()
    }

    /// Add a rest point at `s` (at or after every one held). False when full.
    pub fn add_stop(&mut self, s: f64) -> bool {
        let d = &mut self.data;
        if d.n_stops > 0 && d.stops[d.n_stops - 1] >= s {
            return true;
        }
        if d.n_stops >= MAX_STOPS {
            return false;
        }
        d.stops[d.n_stops] = s;
        d.n_stops += 1;
        true
    }

    /// Move the end of the queue to `s`.
    pub fn set_tail(&mut self, s: f64) {
        self.data.tail = s;
    }

    /// Lowers the most rows one linear program may hold before the
    /// farthest pieces' per-axis jerk rows are aggregated (at most
    /// [`MAX_ROWS`]): a short curve then meets the budget a long raster
    /// meets at [`MAX_ROWS`] (tests and diagnostics).
    pub fn set_max_rows(&mut self, rows: usize) {
        self.data.max_rows = rows.min(MAX_ROWS);
    }

    /// Whether the pieces of a crawl lie ahead of `machine` and were not
    /// planned again from near here yet (then they are due, and this
    /// records it): a crawl is the last resort after a failed solve, and
    /// when the look-ahead is full of it no new block comes to replace it.
    /// Tried again once the machine has moved half a grid interval, so a
    /// solve that keeps failing costs one attempt per half interval.
    /// Pieces planned under aggregated rows are planned again the same way
    /// once the machine is within a stopping distance from the top speed of
    /// them (near a program's end no new block comes to do it).
    pub fn take_crawl_retry(&mut self, machine: f64) -> bool {
        let d = &self.data;
        let crawl = self.crawl_end > machine && machine >= self.crawl_tried + 0.5 * d.h;
        let agg = d.agg_x > machine
            && machine >= self.crawl_tried + AGG_RETRY_STEP * d.h
            && d.agg_x - machine < d.replan_reach(d.cfg.max_path_speed);
        let due = crawl || agg;
        if due {
            self.crawl_tried = machine;
        }
        due
    }

    /// Where a re-solve of everything ahead of the machine starts (a new
    /// feed override, a resumed hold): the first piece strictly after
    /// `machine`, or `machine` itself when the machine rests there.
    pub fn freeze_after(&self, machine: f64, machine_at_rest: bool) -> Freeze {
        let d = &self.data;
        if d.n_pieces == 0 {
            return Freeze::Rest(d.origin);
        }
        if machine_at_rest {
            // At rest (where a hold stopped it, or on a rest point of the
            // plan): planned again from that point.
            return Freeze::Rest(machine.max(d.pieces[0].x0));
        }
        let mut f = 1;
        while f < d.n_pieces && d.pieces[f].x0 <= machine {
            f += 1;
        }
        if f < d.n_pieces {
            Freeze::At(f)
        } else {
            Freeze::Rest(d.pieces[d.n_pieces - 1].x1)
        }
    }

    /// Where a re-solve starts. The freeze piece is the first one at least a
    /// stopping distance (from the fastest planned speed on the way) before
    /// the end of the current plan and strictly after `machine` (where the
    /// machine may be when the plan is committed). A window that starts at
    /// rest where the machine still rests is planned again from that point;
    /// with no piece left, the new plan starts from rest where the current
    /// one ends (the machine will have stopped there).
    ///
    /// After a crawl (the last resort of [`Self::solve`]), the crawl's pieces
    /// ahead of the machine are planned again, from the first piece after
    /// it ([`Self::freeze_after`]): they rest at every knot, so a plan from
    /// any of them starts at rest, and one failed solve does not hold the
    /// machine to a crawl over the whole look-ahead.
    pub fn freeze(&self, machine: f64, machine_at_rest: bool) -> Freeze {
        let d = &self.data;
        if d.n_pieces == 0 {
            return Freeze::Rest(d.origin);
        }
        if self.crawl_end > machine {
            return self.freeze_after(machine, machine_at_rest);
        }
        let mut walked = 0.0;
        let mut top: f64 = 0.0;
        let mut f = d.n_pieces - 1;
        loop {
            let p = d.piece(f);
            top = top.max(libm::sqrt(p.e0.max(p.d).max(p.e1).max(0.0)));
            walked += p.h;
            let need = d.replan_reach(top);
            if walked >= need || f == 0 {
                break;
            }
            f -= 1;
        }
        // Pieces planned under aggregated rows (over the budget) are
        // planned again, with exact rows where they fit now.
        while f > 0 && d.pieces[f].x0 > d.agg_x && d.agg_x > machine {
            f -= 1;
        }
        if f == 0 && d.pieces[0].rest_start && machine_at_rest && machine <= d.pieces[0].x0 {
            return Freeze::Rest(d.pieces[0].x0);
        }
        f = f.max(1);
        while f < d.n_pieces && d.pieces[f].x0 <= machine {
            f += 1;
        }
        if f < d.n_pieces {
            Freeze::At(f)
        } else {
            Freeze::Rest(d.pieces[d.n_pieces - 1].x1)
        }
    }

    /// Re-solve from `freeze` to arc length `end` (a rest point: the end of
    /// the queue, or a provisional one) with feed override `ovr`. `lift`: a braking curve from the state at the freeze point
    /// (its arc length and the stop) that the feed limits may not push below,
    /// for an override that drops faster than the machine can brake. Returns
    /// the index of the first piece that changed: that one and every later
    /// one make the update.
    ///
    /// If the program cannot be planned through the end of the current plan
    /// (the linear program fails), that end is kept as a rest point and the
    /// rest planned from it: always feasible, since the current plan stops
    /// there. Without `fallback`, such a failure is returned instead (and
    /// nothing changes).
    pub fn solve(
        &mut self,
        freeze: Freeze,
        end: f64,
        ovr: f64,
        lift: Option<Lift>,
        keep_from: f64,
        fallback: bool,
    ) -> Result<usize, PlanError> {
        let (n, prev, origin) = (self.data.n_pieces, self.data.prev, self.data.origin);
        // Where this solve's passes aggregate rows (any pass shapes the plan:
        // a refinement stays within its trust region of the first).
        let agg_x = core::mem::replace(&mut self.data.agg_x, f64::INFINITY);
        self.scratch.backup_agg = agg_x;
        let r = self.solve_inner(freeze, end, ovr, lift, keep_from, fallback);
        if r.is_ok() {
            self.ovr = ovr;
        } else {
            // Nothing changed: the plan as it was (the backup holds its pieces).
            self.restore_backup(n, prev);
            self.data.agg_x = agg_x;
            self.data.origin = origin;
        }
        r
    }

    fn solve_inner(
        &mut self,
        freeze: Freeze,
        end: f64,
        ovr: f64,
        lift: Option<Lift>,
        keep_from: f64,
        fallback: bool,
    ) -> Result<usize, PlanError> {
        // The current plan, to fall back on (it comes to rest at its end).
        let backup_n = self.data.n_pieces;
        self.scratch.backup[..backup_n].copy_from_slice(&self.data.pieces[..backup_n]);
        self.scratch.backup_n = backup_n;
        let backup_prev = self.data.prev;
        let old_end = self.data.plan_end();
        let (first, changed, from_x, rest) = match freeze {
            Freeze::At(f) => {
                // Keep pieces f−1 (as is) and f (its coefficient), and the
                // ones from the machine's on: a later re-solve from the
                // machine (a new override) starts from them. Those behind
                // the machine go.
                let d = &mut self.data;
                let mut drop = 0;
                while drop + 1 < f && d.pieces[drop].x1 <= keep_from {
                    drop += 1;
                }
                if drop > 0 {
                    let q = d.pieces[drop - 1];
                    d.prev = (q.h(), q.d);
                    d.pieces.copy_within(drop..d.n_pieces, 0);
                    d.n_pieces -= drop;
                }
                let f = f - drop;
                let x2 = d.pieces[f].x1;
                // (A crawl's knots rest without being rest points.)
                let rest =
                    d.rests().contains(&x2) || (f + 1 < d.n_pieces && d.pieces[f + 1].rest_start);
                (f + 1, f, x2, rest)
            }
            Freeze::Rest(x) => {
                let d = &mut self.data;
                d.n_pieces = 0;
                d.prev = (0.0, 0.0);
                (0, 0, x, true)
            }
        };
        // (A raised override's feed limits are above the ones the current
        // plan keeps.)
        let plan_meets_ovr = ovr >= self.ovr;
        let mut fell_back = false;
        // After a failed first pass: once more with the rows past the kept
        // pieces as loose as the kept plan's were (see [`kept_caps`]).
        let mut keep_rows = false;
        // First near the kept pieces with the caps the kept plan was solved
        // under (see [`kept_caps`]), so the new rows are no tighter there
        // than the ones the kept state was planned with; without them on
        // failure.
        let mut warm = first > 0;
        loop {
            self.data
                .rebuild_from(first, from_x, rest, end, self.kept_pieces)?;
            let n = self.data.n_pieces;
            if n - first > REGION {
                return Err(PlanError::Full);
            }
            if n <= first {
                self.commit_region(freeze, keep_from, from_x);
                return Ok(changed.min(n));
            }
            self.last.variables = n - first;
            let trace = self.trace;
            match assemble_and_solve(
                &mut self.data,
                &mut self.scratch,
                first,
                ovr,
                &lift,
                if keep_rows {
                    Pass::KeptRows
                } else if warm {
                    Pass::Warm
                } else {
                    Pass::First
                },
                &mut |it| {
                    if let Some(t) = trace {
                        t(it)
                    }
                },
            ) {
                Ok(mut st) => {
                    self.data.note_caps(&self.scratch.cap2, first);
                    // Sequential refinement: each pass caps every piece near
                    // the speed the last one planned there, which loosens the
                    // jerk rows; the last plan stays feasible, so a pass can
                    // only gain, and one that fails changes nothing.
                    for _ in 0..REFINE_PASSES {
                        let n = self.data.n_pieces;
                        let sc = &mut self.scratch;
                        for (j, x) in sc.x[..n - first].iter_mut().enumerate() {
                            *x = self.data.pieces[first + j].d;
                        }
                        match assemble_and_solve(
                            &mut self.data,
                            sc,
                            first,
                            ovr,
                            &lift,
                            Pass::Refine,
                            &mut |_| {},
                        ) {
                            Ok(s2) => {
                                self.data.note_caps(&self.scratch.cap2, first);
                                st.iterations += s2.iterations;
                                st.passes += 1;
                            }
                            Err(_) => {
                                let sc = &self.scratch;
                                for j in 0..n - first {
                                    self.data.pieces[first + j].d = sc.backup_x[j];
                                }
                                break;
                            }
                        }
                    }
                    let x0 = self.data.pieces[first].x0;
                    self.last = SolveStats {
                        fell_back,
                        range: (x0, end),
                        ..st
                    };
                    if from_x <= self.crawl_end || matches!(freeze, Freeze::Rest(_)) {
                        self.crawl_end = f64::NEG_INFINITY;
                    }
                    let t = &mut self.totals;
                    t.solves += 1;
                    t.passes += u64::from(st.passes);
                    t.iterations += u64::from(st.iterations);
                    t.fell_back += u64::from(fell_back);
                    t.uncut = self.data.uncut;
                    t.aggregated = self.data.aggregated;
                    t.ungraded = self.data.ungraded;
                    self.commit_region(freeze, keep_from, from_x);
                    return Ok(changed);
                }
                Err(PlanError::Solver(e)) if warm => {
                    self.totals.last_failure = Some(e);
                    self.totals.warm_failed += 1;
                    warm = false;
                }
                Err(PlanError::Solver(e)) if !keep_rows && first > 0 => {
                    self.totals.last_failure = Some(e);
                    self.totals.kept_rows += 1;
                    keep_rows = true;
                }
                Err(PlanError::Solver(e))
                    if plan_meets_ovr && self.rest_kept_whole(from_x, old_end, end).is_some() =>
                {
                    // The plan up to a rest point it comes to (one that
                    // stays: a corner, an exact stop, a hold's rest) cannot
                    // depend on what follows the rest: it is kept whole, and
                    // the new stretch planned from rest there. From the
                    // freeze point, a soft machine braking into a corner at
                    // the jerk limit all the way left the program no room
                    // (every row binding), and the pieces re-cut next to the
                    // rest could not follow the kept plan: every pass failed
                    // and the stretch crawled (`homer-q2` at jerk 10⁴).
                    self.totals.last_failure = Some(e);
                    self.totals.kept_to_rest += 1;
                    let k = self.rest_kept_whole(from_x, old_end, end).unwrap_or(0);
                    let rest = self.scratch.backup[k].x1;
                    self.restore_backup(backup_n, backup_prev);
                    // (The kept plan's mark of aggregated rows before the
                    // rest stays; the failed passes' marks are dropped.)
                    let old_agg = self.scratch.backup_agg;
                    self.data.agg_x = if old_agg < rest {
                        old_agg
                    } else {
                        f64::INFINITY
                    };
                    // (The last such rest: the solve from it cannot come
                    // here again.)
                    return self.solve_inner(Freeze::At(k), end, ovr, lift, keep_from, fallback);
                }
                Err(e @ PlanError::Solver(_)) if !fallback => return Err(e),
                Err(PlanError::Solver(e)) if !fell_back && old_end > from_x => {
                    self.totals.last_failure = Some(e);
                    if !self.insert_rest_point(old_end) {
                        return Err(PlanError::Full);
                    }
                    fell_back = true;
                }
                Err(PlanError::Solver(e)) => {
                    self.totals.last_failure = Some(e);
                    // Last resort, never a stall: keep the current plan to its
                    // end (at rest) and crawl from there, resting at every knot.
                    let kept_pieces = self.kept_pieces;
                    self.restore_backup(backup_n, backup_prev);
                    let d = &mut self.data;
                    let start = backup_n;
                    d.rebuild_from(start, old_end, true, end, kept_pieces)?;
                    crawl(d, start, ovr, &lift);
                    self.last = SolveStats {
                        crawled: true,
                        ..SolveStats::default()
                    };
                    self.totals.crawled += 1;
                    self.crawl_end = self.data.pieces[self.data.n_pieces - 1].x1;
                    // Tried from where the machine is: planned again from
                    // there (the next tick's retry) it would fail the same
                    // way, at the cost of this solve again.
                    self.crawl_tried = keep_from;
                    // The pieces before this plan's start stay as they are.
                    let first_kept = self.data.pieces[0].x0;
                    self.data.drop_before(first_kept.min(keep_from));
                    return Ok(start);
                }
                Err(e) => return Err(e),
            }
        }
    }

    /// The plan as it was before this solve: its `n` pieces (the backup) and
    /// the last dropped piece's `(h, d)` (`Data::prev`).
    fn restore_backup(&mut self, n: usize, prev: (f64, f64)) {
        let d = &mut self.data;
        d.pieces[..n].copy_from_slice(&self.scratch.backup[..n]);
        d.n_pieces = n;
        d.prev = prev;
    }

    /// The piece of the plan before this solve (its backup) that ends on
    /// the last rest point after `from`, at most `old_end` and before the
    /// solve's `end`, if any, where that plan rests (see [`Self::solve`]).
    /// (Not past `end`: a hold's solve ends at its own rest point, short of
    /// the old plan's.)
    fn rest_kept_whole(&self, from: f64, old_end: f64, end: f64) -> Option<usize> {
        let backup = &self.scratch.backup[..self.scratch.backup_n];
        let r = *self
            .data
            .rests()
            .iter()
            .rev()
            .find(|&&r| r > from && r <= old_end && r < end)?;
        let k = backup.iter().position(|p| p.x1 == r)?;
        backup.get(k + 1).is_none_or(|p| p.rest_start).then_some(k)
    }

    /// After a successful solve: forget the intervals and rest points no plan
    /// can reach back to (before the kept pieces and the machine).
    fn commit_region(&mut self, freeze: Freeze, keep_from: f64, from_x: f64) {
        let x = match freeze {
            Freeze::At(_) => self.data.pieces[0].x0,
            Freeze::Rest(_) => {
                self.data.origin = from_x;
                from_x
            }
        };
        self.data.drop_before(x.min(keep_from));
    }

    /// Forget the rest point at `x` (a hold's, which its plan could not
    /// reach, or which a resume plans through).
    pub fn remove_rest_point(&mut self, x: f64) {
        let d = &mut self.data;
        let k = d.rest_slot(x);
        if k < d.n_stops && d.stops[k] == x {
            d.stops.copy_within(k + 1..d.n_stops, k);
            d.n_stops -= 1;
        }
    }

    /// The first rest point of the plan at or after `x`: a held one, or the
    /// plan's end (where it rests), mm.
    pub fn next_rest(&self, x: f64) -> f64 {
        let d = &self.data;
        let end = d.plan_end();
        d.rests().get(d.rest_slot(x)).map_or(end, |&s| s.min(end))
    }

    /// Add a rest point at `x` among those held (in order): where the
    /// current plan ends, kept on a failed solve, or where a feed hold's plan
    /// is to come to rest ([`crate::BlockPlanner::hold`]). False when full.
    pub fn insert_rest_point(&mut self, x: f64) -> bool {
        let d = &mut self.data;
        let k = d.rest_slot(x);
        if k < d.n_stops && d.stops[k] == x {
            return true;
        }
        if d.n_stops >= MAX_STOPS {
            return false;
        }
        d.stops.copy_within(k..d.n_stops, k + 1);
        d.stops[k] = x;
        d.n_stops += 1;
        true
    }
}

/// Rows being written for one linear program.
struct RowSink<'a> {
    lp: &'a mut LpWork<REGION, MAX_ROWS>,
    first: usize,
}

impl RowSink<'_> {
    /// Fold a linear form over the coefficients of pieces `(i−1, i, i+1)`
    /// into a row on the unknowns (pieces `first..`): fixed pieces move into
    /// the bounds.
    fn push(
        &mut self,
        d: &Data,
        i: usize,
        mut a: [f64; 3],
        lo: f64,
        hi: f64,
    ) -> Result<(), PlanError> {
        let mut c = 0.0;
        for (m, coef) in a.iter_mut().enumerate() {
            let q = i as isize + m as isize - 1;
            if *coef == 0.0 {
                continue;
            }
            if q >= d.n_pieces as isize {
                *coef = 0.0;
            } else if q < self.first as isize {
                c += *coef * d.coef(q);
                *coef = 0.0;
            }
        }
        let base = (i as isize - 1).max(self.first as isize);
        let shift = (base - (i as isize - 1)) as usize;
        let mut b = [0.0; 3];
        b[..3 - shift].copy_from_slice(&a[shift..]);
        if b.iter().all(|&v| v == 0.0) {
            return Ok(());
        }
        let row = Row {
            k: (base as usize - self.first) as u32,
            a: b,
            lo: lo - c,
            hi: hi - c,
        };
        if self.lp.push_row(row) {
            Ok(())
        } else {
            Err(PlanError::Full)
        }
    }
}

impl RowSink<'_> {
    /// `f ≤ J/√S` for a form `f` and the form `s` of an `S`, with `bound`
    /// = `J/√s0`, through the tangent of the convex `J/√S` at `s0`:
    /// `f + bound·S/(2·s0) ≤ 1.5·bound`. The tangent lies below `J/√S` for
    /// every `S`, so the row holds the true limit, and exactly at `s0`.
    fn push_tangent(
        &mut self,
        d: &Data,
        i: usize,
        f: [f64; 3],
        s: [f64; 3],
        bound: f64,
        s0: f64,
    ) -> Result<(), PlanError> {
        let k = 0.5 * bound / s0;
        let row = [0, 1, 2].map(|m| f[m] + k * s[m]);
        self.push(d, i, row, f64::NEG_INFINITY, 1.5 * bound)
    }
}

/// Which caps a linear program's rows are written with.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Pass {
    /// The reach caps ([`reach_caps`]).
    First,
    /// The reach caps, and past the kept pieces the caps the kept plan was
    /// solved under ([`kept_caps`]): the retry of a failed first pass.
    KeptRows,
    /// A trust region about the last plan.
    Refine,
    /// The reach caps, and next to the kept pieces the kept plan's, where
    /// its end's rest did not shape it ([`kept_caps`] with `guard`).
    Warm,
}

/// Build the linear program over the unknowns of pieces `first ..n` and
/// solve it into the pieces.
fn assemble_and_solve(
    d: &mut Data,
    sc: &mut Scratch,
    first: usize,
    ovr: f64,
    lift: &Option<Lift>,
    pass: Pass,
    trace: &mut dyn FnMut(lp::Iteration),
) -> Result<SolveStats, PlanError> {
    let n = d.n_pieces;
    let nv = n - first;
    let cfg = d.cfg;
    let keep = 1.0 - cfg.planning_margin;
    // Next to a rest point the acceleration steps by at most half a tick of
    // jerk each way (arriving, then leaving: a full tick's worth together).
    let a_rest = 0.5 * cfg.max_path_jerk * keep * cfg.period;
    sc.c[..nv].fill(0.0);
    // Per-axis rows that could bind: with S ≤ V², |S'| ≤ 2A and |S''| ≤ 2J/V,
    // a sample whose worst case stays below the limit needs no row. If the
    // rest would not fit, each piece gets one conservative row per axis.
    let binds = |smp: &AxisSample, ax: usize, l2: f64| {
        crate::prepare::axis_jerk_may_bind(smp, ax, l2, &cfg)
    };
    let lo_i = first.saturating_sub(1);
    if pass == Pass::Refine {
        // Cap each unknown piece near what the last pass planned there
        // (kept in `backup_x` to restore if this pass fails), within the
        // first pass's caps: not within the last pass's, or no pass after
        // the first could go further than it.
        for i in first..n {
            let p = d.piece(i);
            let smax = p.e0.max(p.d).max(p.e1).max(0.0);
            let floor = MIN_SPEED2 * cfg.max_path_speed * cfg.max_path_speed;
            sc.cap2[i] = sc.first_cap2[i - first].min((REFINE_TRUST * smax).max(floor));
            sc.backup_x[i - first] = p.d;
        }
    } else {
        reach_caps(d, &mut sc.cap2, lo_i, first, ovr, lift);
        // The kept piece before the first unknown gets rows too (its end
        // knot moves): the ones it was solved under, not tighter.
        if lo_i < first
            && let Some(c) = d.pieces[lo_i].solved_cap
        {
            sc.cap2[lo_i] = sc.cap2[lo_i].min(c);
        }
        if pass == Pass::KeptRows || pass == Pass::Warm {
            let guard = pass == Pass::Warm;
            kept_caps(
                d,
                &mut sc.cap2,
                &sc.backup[..sc.backup_n],
                sc.backup_agg,
                first,
                guard,
            );
        }
        sc.first_cap2[..nv].copy_from_slice(&sc.cap2[first..n]);
    }
    if pass != Pass::Refine {
        // A ramp leaves (or reaches) rest with S' = 0, so it must not be
        // much longer than the jerk-limited distance to its speed: a long
        // one creeps (v ∝ distance near the rest when 3d ≪ far). Such a
        // piece keeps the quadratic and its acceleration step at rest, as
        // does one whose jerk a five-axis block's joints bound. The
        // refinement keeps the first pass's forms (its rows continue that
        // plan).
        let j = cfg.max_path_jerk;
        for i in first..n {
            let c = sc.cap2[i].max(0.0);
            let reach = RAMP_REACH * libm::pow(c, 0.75) / libm::sqrt(j);
            let p = d.pieces[i];
            let joint_limited = d.interval(p.g).joint_jerk.is_finite();
            d.pieces[i].ramp = p.h() <= reach && !joint_limited;
        }
    }
    // Piece `i`'s per-axis rows one by one, and aggregated (one per axis).
    let axis_rows = |d: &Data, i: usize| {
        let p = d.pieces[i];
        let l2 = sc.cap2[i];
        let rest_end = i + 1 >= n || d.pieces[i + 1].rest_start;
        let per = if d.form(i) == Form::Quadratic { 2 } else { 1 };
        let (mut exact, mut axes) = (0usize, [false; 3]);
        for smp in d.piece_samples(&p, rest_end) {
            for ax in (0..3).filter(|&ax| binds(smp, ax, l2)) {
                exact += per;
                axes[ax] = true;
            }
        }
        (exact, axes.iter().filter(|&&a| a).count())
    };
    let mut needed = 0usize;
    for i in lo_i..n {
        // A quadratic piece's jerk rows are tangent rows (`push_tangent`):
        // five tangential ones and two per axis sample; a ramp has two
        // tangential ones and one per axis sample.
        needed += if d.form(i) == Form::Quadratic { 7 } else { 4 };
        needed += axis_rows(d, i).0;
    }
    // Where the rows do not all fit, the pieces from `agg_from` on get one
    // aggregated row per axis, the farthest first: the aggregate drops the
    // cancellation of `S''`'s Bernstein form (`t·S''/2` weighs ~t/h² per
    // unit of S, its terms nearly cancel on a smooth plan), so it holds
    // the speed to a few mm/s where an axis' jerk binds, and the kept plan,
    // solved under the exact rows, met it just past the freeze point: the
    // re-solve failed all its passes and crawled (`ocl_mount_rush`, 80 rows
    // over the limit). The next solve plans the far pieces again.
    let mut agg_from = n;
    while needed > d.max_rows && agg_from > lo_i {
        agg_from -= 1;
        let (exact, agg) = axis_rows(d, agg_from);
        needed -= exact - agg.min(exact);
    }
    if agg_from < n {
        d.aggregated += 1;
        d.agg_x = d.agg_x.min(d.pieces[agg_from].x0);
    }
    sc.lp.clear_rows();
    let mut sink = RowSink {
        lp: &mut sc.lp,
        first,
    };
    // The piece before the first unknown gets its rows too: its end moves.
    for i in lo_i..n {
        let p = d.pieces[i];
        let h = p.h();
        let it = *d.interval(p.g);
        let l2 = sc.cap2[i];
        let rest_end = i + 1 >= n || d.pieces[i + 1].rest_start;
        let form = d.form(i);
        let aggregate = i >= agg_from;
        let vmax = libm::sqrt(l2).max(1e-9);
        let jb = it.jerk * h * h / vmax;
        // The middle coefficient's bound: next to a rest point, the
        // acceleration step allowed there; on a ramp (`S' = 0` at the rest)
        // `3d ≤ cap`, so that `v ≤ w²·√cap` on it, its jerk at the rest
        // `(2/3)·d·√(3d)/h² ≤ J` through the tangent of `J/√G` at the cap
        // (`G` = 3d there; the jerk rows below, at w = 0), and its
        // acceleration inside, at most `4d/(3h) ≤ A`.
        let d_hi = match form {
            Form::Quadratic if p.rest_start || rest_end => {
                l2.min(rest_accel(a_rest, &it, &cfg) * h)
            }
            Form::Quadratic => l2,
            _ => (l2 / 3.0)
                .min(0.75 * it.accel * h)
                .min(1.5 * jb / (2.0 / 3.0 + 1.5 * jb / (vmax * vmax))),
        };
        if i >= first {
            let j = i - first;
            sc.lo[j] = 0.0;
            sc.hi[j] = d_hi;
        }
        // Knot values (start, end) and the middle coefficient as forms on
        // the coefficients of pieces (i−1, i, i+1).
        let ks = d.knot(i);
        let e0 = [ks[0], ks[1], 0.0];
        let e1 = if rest_end {
            [0.0; 3]
        } else {
            let kn = d.knot(i + 1);
            [0.0, kn[0], kn[1]]
        };
        let mid = [0.0, 1.0, 0.0];
        let curv = [
            e0[0] + e1[0] - 2.0 * mid[0],
            e0[1] + e1[1] - 2.0 * mid[1],
            e0[2] + e1[2] - 2.0 * mid[2],
        ];
        // Objective: the path time ∫ds/√S, linearised about the limit
        // (d(S^−½)/dS = −½·S^−³ᐟ²): maximise Σ ∫S ds / V_p³, which weighs
        // slow pieces the most, where the time is spent.
        let floor = MIN_SPEED2 * cfg.max_path_speed * cfg.max_path_speed;
        let weigh = |l: f64| h / (3.0 * l.max(floor) * libm::sqrt(l.max(floor)));
        let weight = weigh(l2);
        // Next to a rest point the middle coefficient is bounded far below
        // the piece's limit (the acceleration step at rest), and it alone
        // sets how the motion leaves or reaches the rest: with it at zero
        // the speed there goes like the distance, which takes forever. So
        // it is linearised about its own bound, as the others are about
        // theirs; without that, trading it for the next piece's coefficient
        // looks free and the plan creeps out of every rest point.
        let (w_ends, w_mid) = if form == Form::Quadratic {
            (weight, weigh(d_hi))
        } else {
            // A ramp's time 3h·∫dw/√(3d + (far − 3d)·w²), linearised about
            // the pure ramp at its bound, `3d = far = a`: −∂T/∂d = 3h/a^{3/2},
            // −∂T/∂far = h/(2a^{3/2}) (twice each, as ∫S/V³ is of the time).
            let a = (3.0 * d_hi).max(floor);
            let g = h / (a * libm::sqrt(a));
            (g, 6.0 * g)
        };
        for m in 0..3 {
            let q = i as isize + m as isize - 1;
            if q >= first as isize && (q as usize) < n {
                sc.c[q as usize - first] += (e0[m] + e1[m]) * w_ends + mid[m] * w_mid;
            }
        }
        // Tangential jerk |α|·v ≤ J, α = (e0 − 2d + e1)/h², v ≤ √l2. On a
        // ramp |S''|·v/2 ≤ |(2/3)d + (far − 3d)·w²|·√l2/h², linear in w²:
        // at w = 0 within `d_hi`, at w = 1 this row.
        let far = if form == Form::ToRest { e0 } else { e1 };
        let jerk_form = match form {
            Form::Quadratic => curv,
            _ => [
                far[0] - 7.0 / 3.0 * mid[0],
                far[1] - 7.0 / 3.0 * mid[1],
                far[2] - 7.0 / 3.0 * mid[2],
            ],
        };
        if form == Form::Quadratic {
            // `|S''|/2·v ≤ J` through the tangent of `J/√S` at the cap, as
            // the axis rows below: at most `(1.5 − S/(2·l2))·jb` for the
            // largest `S` on the piece, which is at an end where `S'' > 0`
            // and one of the three coefficients otherwise.
            for c in [e0, e1] {
                sink.push_tangent(d, i, curv, c, jb, l2.max(floor))?;
            }
            for c in [e0, mid, e1] {
                sink.push_tangent(d, i, curv.map(|x| -x), c, jb, l2.max(floor))?;
            }
        } else {
            // A ramp's jerk `|L|·√G/h²`, `L` = (2/3)d + (far − 3d)·w²,
            // `G` = 3d + (far − 3d)·w² (= S/w⁴): through the tangent of
            // `J/√G` at the cap, linear in w², so it holds on the whole
            // ramp when it holds at w = 0 (`d_hi`) and at w = 1 (these).
            sink.push_tangent(d, i, jerk_form, far, jb, vmax * vmax)?;
            sink.push_tangent(d, i, jerk_form.map(|x| -x), far, jb, vmax * vmax)?;
        }
        if !rest_end {
            // The end knot within both pieces' limits, and the acceleration there.
            let l2n = sc.cap2[i + 1];
            sink.push(d, i, e1, 0.0, l2.min(l2n))?;
            let s = h + d.pieces[i + 1].h();
            let acc = it.accel.min(d.interval(d.pieces[i + 1].g).accel);
            sink.push(d, i, [0.0, -1.0 / s, 1.0 / s], -acc, acc)?;
        }
        // Per-axis jerk v·(C‴·S + 1.5·C″·S′ + 0.5·t·S″) at the samples in this piece.
        let mut agg = [[0.0f64; 3]; 3];
        let mut any = [false; 3];
        for smp in d.piece_samples(&p, rest_end) {
            let u = ((smp.s - p.x0) / h).clamp(0.0, 1.0);
            let (b0, b1, b2) = ((1.0 - u) * (1.0 - u), 2.0 * u * (1.0 - u), u * u);
            // On a ramp, w = u'^{1/3} from the rest (u' = u or 1 − u, with
            // the sign of d/dx), and the row is the jerk over w²·√l2 (the
            // speed there at most): finite at the rest, where S'' is not.
            let (w, sgn) = match form {
                Form::Quadratic => (0.0, 0.0),
                Form::ToRest => (libm::cbrt(1.0 - u), -1.0),
                Form::FromRest => (libm::cbrt(u), 1.0),
            };
            let (w2, w3) = (w * w, w * w * w);
            // `S` at the sample as a form on the coefficients (quadratic).
            let s_at = [0, 1, 2].map(|m| e0[m] * b0 + mid[m] * b1 + e1[m] * b2);
            for ax in 0..3 {
                if !binds(smp, ax, l2) {
                    continue;
                }
                let (t, css, csss) = (smp.t[ax], smp.css[ax], smp.csss[ax]);
                let mut a = [0.0; 3];
                if form == Form::Quadratic {
                    for m in 0..3 {
                        let sv = s_at[m];
                        let sd = 2.0 / h * ((mid[m] - e0[m]) * (1.0 - u) + (e1[m] - mid[m]) * u);
                        let sdd = 2.0 / (h * h) * curv[m];
                        a[m] = csss * sv + 1.5 * css * sd + 0.5 * t * sdd;
                    }
                } else {
                    // w²·S = 3(w⁶ − w⁸)·d + w⁸·far, w²·S' = ±((4w³ − 6w⁵)·d + 2w⁵·far)/h,
                    // w²·S'' = ((4/3 − 6w²)·d + 2w²·far)/h².
                    let w6 = w3 * w3;
                    let c_mid = csss * 3.0 * w6 * (1.0 - w2)
                        + sgn * 1.5 * css * (4.0 * w3 - 6.0 * w3 * w2) / h
                        + 0.5 * t * (4.0 / 3.0 - 6.0 * w2) / (h * h);
                    let c_far = csss * w6 * w2 + sgn * 3.0 * css * w3 * w2 / h + t * w2 / (h * h);
                    for m in 0..3 {
                        a[m] = c_mid * mid[m] + c_far * far[m];
                    }
                }
                if aggregate {
                    // |Σ a_m·d_m| ≤ Σ |a_m|·d_m for d ≥ 0: one row bounds
                    // every sample (a junction's scaled to its share).
                    for m in 0..3 {
                        let am = libm::fabs(a[m]) / (1.0 - smp.reserve.larger(ax));
                        agg[ax][m] = agg[ax][m].max(am);
                    }
                    any[ax] = true;
                    continue;
                }
                // (A step nearby takes its share on its own side only.)
                let jb = cfg.axis_max_jerk[ax] * keep / vmax;
                let r = &smp.reserve;
                let (up, down) = (jb * (1.0 - r.up[ax]), jb * (1.0 - r.down[ax]));
                if form == Form::Quadratic {
                    sink.push_tangent(d, i, a, s_at, up, l2.max(floor))?;
                    sink.push_tangent(d, i, a.map(|x| -x), s_at, down, l2.max(floor))?;
                } else {
                    sink.push(d, i, a, -down, up)?;
                }
            }
        }
        for ax in 0..3 {
            if any[ax] {
                let jb = cfg.axis_max_jerk[ax] * keep / vmax;
                sink.push(d, i, agg[ax], f64::NEG_INFINITY, jb)?;
            }
        }
    }
    let nr = sc.lp.rows();
    let problem = Problem {
        c: &sc.c[..nv],
        lo: &sc.lo[..nv],
        hi: &sc.hi[..nv],
    };
    let opts = LpOptions {
        pull: PULL,
        ..LpOptions::default()
    };
    let st = lp::solve_traced(&problem, &opts, &mut sc.lp, &mut sc.x[..nv], trace)
        .map_err(PlanError::Solver)?;
    for j in 0..nv {
        // Interior-point solutions sit a hair inside the bounds; clip the
        // round-off that may step outside.
        d.pieces[first + j].d = sc.x[j].clamp(sc.lo[j], sc.hi[j]);
    }
    Ok(SolveStats {
        variables: nv,
        rows: nr,
        iterations: st.iterations,
        ..SolveStats::default()
    })
}

/// Per piece `lo..n`, the squared speed limit the rows use: the pointwise
/// limit, capped where the machine cannot reach it, being too close to a
/// rest point or to a slower stretch (acceleration `A` from the limits
/// around, both ways, and the jerk from rest points and slower knots,
/// [`reach_from`]).
/// The jerk rows hold `|S''|·v ≤ 2J` through `v ≤ √cap` (and the hull keeps
/// `S ≤ cap`), so a cap near the real speed lets the plan accelerate as
/// fast as the jerk allows, where the pointwise limit alone makes it creep
/// out of every slow point. The caps bound every plan the rows admit, with
/// a margin, so they cost no speed. The sweeps start at `first`: the pieces
/// before, whose coefficients meet the kept plan, take the limit alone.
fn reach_caps(
    d: &Data,
    cap2: &mut [f64; WINDOW],
    lo: usize,
    first: usize,
    ovr: f64,
    lift: &Option<Lift>,
) {
    let n = d.n_pieces;
    let cfg = &d.cfg;
    let a0 = 0.5 * cfg.max_path_jerk * cfg.period;
    let two_a = 2.0 * cfg.max_path_accel;
    let m2 = REACH_MARGIN * REACH_MARGIN;
    for i in lo..n {
        cap2[i] = d.limit2(i, ovr, lift);
    }
    if n <= first {
        return;
    }
    // Forward: `knot` bounds S at the start of piece i; the jerk's reach
    // runs from `anchor` (where, how fast at most): a rest point, or a
    // knot whose bound gives a lower reach than the last anchor's.
    let mut anchor: Option<(f64, f64)> = None;
    let mut knot = f64::INFINITY;
    for i in first..n {
        let p = &d.pieces[i];
        let h = p.x1 - p.x0;
        if p.rest_start {
            anchor = Some((p.x0, 0.0));
            knot = 0.0;
        } else if i > first {
            knot = knot.min(cap2[i - 1]);
        }
        let mut c = (knot + two_a * h) * m2;
        if let Some(v) = jerk_reach(&mut anchor, p.x0, knot, h, a0, cfg) {
            c = c.min(v * v);
        }
        let l2 = cap2[i];
        cap2[i] = l2.min(c);
        knot = (knot + two_a * h).min(l2);
    }
    // Backward, to the rest point at the end.
    let mut anchor = Some((-d.pieces[n - 1].x1, 0.0));
    let mut knot = 0.0;
    for i in (first..n).rev() {
        let p = &d.pieces[i];
        let h = p.x1 - p.x0;
        let l2 = d.limit2(i, ovr, lift);
        let mut c = cap2[i].min((knot + two_a * h) * m2);
        // (Mirrored: the sweep runs towards smaller x.)
        if let Some(v) = jerk_reach(&mut anchor, -p.x1, knot, h, a0, cfg) {
            c = c.min(v * v);
        }
        cap2[i] = c;
        knot = (knot + two_a * h).min(l2);
        if p.rest_start {
            anchor = Some((-p.x0, 0.0));
            knot = 0.0;
        } else if i > 0 {
            knot = knot.min(d.limit2(i - 1, ovr, lift));
        }
    }
}

/// The jerk's reach (with [`REACH_MARGIN`]) at the far end of a piece
/// `h` long that a sweep enters at `x` with `S ≤ knot`: from `anchor`
/// (position along the sweep, speed at most), or from the entry itself,
/// whichever is lower; the entry becomes the anchor where it is. `None`
/// with no bound (no rest point before, and an unbounded entry).
fn jerk_reach(
    anchor: &mut Option<(f64, f64)>,
    x: f64,
    knot: f64,
    h: f64,
    a0: f64,
    cfg: &InterpConfig,
) -> Option<f64> {
    let old = anchor.map(|(xa, va)| reach_from(va, x + h - xa, a0, cfg));
    let entry = (knot < f64::INFINITY).then(|| libm::sqrt(knot.max(0.0)));
    let new = entry.map(|ve| (ve, reach_from(ve, h, a0, cfg)));
    let v = match (old, new) {
        (Some(o), Some((_, nw))) if !(nw < o) => o,
        (Some(o), None) => o,
        (_, Some((ve, nw))) => {
            *anchor = Some((x, ve));
            nw
        }
        (None, None) => return None,
    };
    Some(REACH_MARGIN * v)
}

/// A re-solve continues the kept plan (pieces before `first`), which was
/// solved under its own caps: the jerk rows bound `|S''|` by `2J/√cap`, so
/// a larger cap is a tighter row, and the first pass's caps (the reach, see
/// [`reach_caps`]) are often larger than the trust caps of the refinement
/// that made the kept plan. Just past the kept pieces, where their momentum
/// leaves no choice, new rows tighter than the old ones can make the
/// program infeasible (a kept braking towards a rest point that the new
/// rows cannot finish). So up to the next rest point, or as far as braking
/// from the speed there takes, each piece is capped by the caps the old plan
/// was solved under where it overlaps them: the old plan stays feasible
/// there, and the plan beyond is free.
fn kept_caps(
    d: &Data,
    cap2: &mut [f64; WINDOW],
    old: &[WPiece],
    old_agg: f64,
    first: usize,
    guard: bool,
) {
    let n = d.n_pieces;
    if first == 0 || first >= n || old.is_empty() {
        return;
    }
    let cfg = &d.cfg;
    let xb = d.pieces[first].x0;
    // The old plan's cap where the kept pieces end: its speed there at most.
    let at = old.partition_point(|p| p.x1 <= xb);
    let Some(Some(cb)) = old.get(at).map(|p| p.solved_cap) else {
        return;
    };
    let (a, j) = (cfg.max_path_accel, cfg.max_path_jerk);
    let vb = libm::sqrt(cb.max(0.0));
    // Braking distance with a jerk-limited ramp, doubled.
    let reach = 2.0 * (vb * vb / (2.0 * a) + vb * a / j);
    let old_end = old[old.len() - 1].x1;
    let mut end = (xb + reach).min(old_end);
    let next_rest = d.pieces[first + 1..n]
        .iter()
        .find(|p| p.rest_start)
        .map(|p| p.x0);
    // (Up to a rest point the old plan keeps, the old end's did not shape it.)
    if guard && next_rest.is_none_or(|r| r > old_end) {
        // Within two braking distances from its top speed of the old end
        // the old plan was slowing for the rest there, which is lifted now;
        // but not before its last peak, where it began to (before it, the
        // kept state's momentum holds as much: braking from the kept
        // state towards a slow point, or bending its acceleration down at
        // the speed limit, under the first pass's tighter rows failed as
        // the plain first pass does, on a long move whose provisional rest
        // was lifted).
        let top = old[at..]
            .iter()
            .filter_map(|p| p.solved_cap)
            .fold(cb, f64::max);
        let v = libm::sqrt(top.max(0.0));
        // (Not into pieces planned under aggregated rows, `old_agg` on:
        // slow, and planned again now.)
        let mut peak = old.len() - 1;
        while peak > at && old[peak - 1].d > old[peak].d {
            peak -= 1;
        }
        let peak_x = old[peak].x1.min(old_agg);
        end = end.min((old_end - 2.0 * (v * v / (2.0 * a) + v * a / j)).max(peak_x));
    }
    if let Some(r) = next_rest {
        end = end.min(r);
    }
    for i in first..n {
        let p = &d.pieces[i];
        if p.x0 >= end {
            break;
        }
        // The old pieces overlapping this one: the largest of their caps
        // (the old plan stays below it here).
        let mut k = old.partition_point(|q| q.x1 <= p.x0);
        let mut c: f64 = 0.0;
        while k < old.len() && old[k].x0 < p.x1 {
            match old[k].solved_cap {
                Some(v) => c = c.max(v),
                None => {
                    c = f64::INFINITY;
                    break;
                }
            }
            k += 1;
        }
        if c > 0.0 {
            cap2[i] = cap2[i].min(c);
        }
    }
}

/// Speed below which a junction or a corner blend is passed with a full
/// stop, mm/s: `junction_min_speed`, or more where the plan cannot use the
/// speed. A slow point lowers the limit of a whole law sub-range (`h/SUB`
/// long), which costs about `h/(SUB·v)` to cross, while a stop costs at most
/// the jerk-limited ramps down to rest and back up to `v`, `4·√(v/J)`: the
/// stop is the faster below `v = (h·√J / (4·SUB))^⅔`, 1.8 mm/s at the
/// defaults. (The corner blends of a `G64 P0.001` rapid, passable at
/// 0.7 mm/s, cost 80–110 ms each; stopped, 10 ms.)
pub fn stop_speed(cfg: &InterpConfig) -> f64 {
    let hs = crate::interp::grid_step(cfg) / SUB as f64;
    let v = libm::pow(hs * libm::sqrt(cfg.planned_jerk()) / 4.0, 2.0 / 3.0);
    cfg.junction_min_speed.max(v)
}

/// Within this fraction of a sub-range of its boundary, a point counts as
/// on it (and lowers both sides): law samples fall on boundaries and
/// `k·hs/hs` need not be `k`, and a refined law minimum at a sample or a
/// knot is placed there by an arc-length quadrature, to ~1e-10 mm.
const SUB_SNAP: f64 = 1e-6;

/// Ticks of travel each way a junction's speed limit holds over
/// ([`Window::lower_junction`]).
const JUNCTION_TICKS: f64 = 2.0;

/// Ticks one third difference of the setpoints spans
/// ([`Window::reserve_around_jump`]).
const JUMP_SEEN_TICKS: f64 = 3.0;

/// A piece next to a rest point takes the ramp form when it is no longer
/// than this multiple of `v^{3/2}/√J`, `v` its speed cap (the jerk-limited
/// distance from rest to `v` is about that; a pure ramp reaching `v` spans
/// 0.47 of it).
const RAMP_REACH: f64 = 1.0;

/// Grid steps the machine moves between two re-solves of pieces planned
/// under aggregated rows ([`Window::take_crawl_retry`]): each plans the
/// whole look-ahead again.
const AGG_RETRY_STEP: f64 = 16.0;

/// Where the pieces next to a rest point are cut, as fractions of the grid
/// step (or of the piece, when shorter) from the rest.
const GRADE: [f64; 2] = [1.0 / 16.0, 0.25];
/// The same on a line (no per-axis samples), at periods up to
/// `SLOW_PIECE_TIME / 2`.
const LINE_REST_GRADE: [f64; 3] = [0.125, 0.25, 0.5];

/// A piece is cut where the speed limits of its sub-ranges differ by more
/// than this factor.
const RUN_RATIO: f64 = 1.5;
/// Most cuts inside one piece (grading at both ends, every sub-range
/// boundary, and the spans near it, graded both ways).
const MAX_CUTS: usize =
    2 * LINE_REST_GRADE.len() + SUB + SPANS * (2 + 2 * GRADE.len()) + SLOW_PIECE_PARTS - 1;

/// Which cuts of a piece [`Data::refine_pieces`] makes, in the order they
/// claim room in the linear program: where short moves and slow points
/// crowd the look-ahead, the far pieces get only the first levels, or
/// none. A rest left ungraded creeps out of it, and a piece not cut at a
/// slow span's end is held to the span's speed over its whole length (a
/// 0.25 mm piece of a straight line at 2 mm/s for an 8 µm junction span
/// overlapping it by 1.3 µm), if the machine gets there before a solve
/// plans it again; without the rest, a piece is only held to its slowest
/// sub-range.
#[derive(Clone, Copy, PartialEq, PartialOrd)]
enum CutLevel {
    /// The grading next to rest points.
    Rests,
    /// And the ends of spans.
    SpanEnds,
    /// And the grading away from slow spans, and the sub-range boundaries
    /// where the limit changes.
    All,
    /// And the cuts of slow pieces (see [`SLOW_PIECE_TIME`]).
    Slow,
}

/// An interval that takes longer than this at its speed limit, where that
/// is the machine's limit well below the feed (a slow point), is cut into
/// 2, 4, 8 or 16 equal parts (the fewest that take at most this each at
/// the limit), room permitting: a quadratic piece's jerk `α·v`
/// follows its speed, so one that the machine takes several milliseconds
/// over cannot hold the jerk limit through the phases of a slowdown (a
/// jerk-limited ramp of the acceleration takes `A/J` = 20 ms at the
/// defaults). At 25 mm/s a grid piece of 0.25 mm takes 10 ms. Measured:
/// 1.25 ms and 5 ms are slower on the corpus; 1.8 ms gains under 0.1 %.
const SLOW_PIECE_TIME: f64 = 0.0025;
/// The most parts [`SLOW_PIECE_TIME`] cuts an interval into (a power of
/// two). 16 rather than 4: the corpus at F6000 0.3 % faster (homer-16,
/// ruota_dentata, nurbs-xy 1 %), 8 most of it.
const SLOW_PIECE_PARTS: usize = 16;

/// Refinement passes after the first solve.
const REFINE_PASSES: usize = 1;
/// How far above its last planned square speed a refinement pass may take a
/// piece (the trust region; 1.44 is 20 % in speed).
const REFINE_TRUST: f64 = 1.44;

/// Slack on the reach speed (a bound, not a target).
const REACH_MARGIN: f64 = 1.1;

/// The highest speed the machine can reach within distance `s` of a point
/// it passes at `v0` at most (`0` at a rest point), never faster than
/// `√(v0² + 2·A·s)`: an upper bound of the speed of any plan within the
/// configured limits. Every plan leaves its rests with acceleration `a0`
/// at most and its jerk is at most `J`, so while it accelerates
/// `s̈² − a0² ≤ 2J·v` (the quantity `v − (s̈² − a0²)/(2J)` does not fall):
/// at the point the acceleration is at most `√(a0² + 2J·v0)`.
fn reach_from(v0: f64, s: f64, a0: f64, cfg: &InterpConfig) -> f64 {
    let s = s.max(0.0);
    let j = cfg.max_path_jerk;
    // Time to cover s with jerk J alone from rest is (6s/J)^⅓; from `v0`
    // with an acceleration it is shorter, so this speed is an upper bound.
    let t = libm::cbrt(6.0 * s / j);
    let a = if v0 > 0.0 {
        libm::sqrt(a0 * a0 + 2.0 * j * v0)
    } else {
        a0
    };
    let by_jerk = v0 + a * t + 0.5 * j * t * t;
    by_jerk.min(libm::sqrt(v0 * v0 + 2.0 * cfg.max_path_accel * s))
}

/// The acceleration step allowed next to a rest point on a piece of
/// interval `it`: half a tick of the path's jerk (`a_rest`), or of the
/// jerk a five-axis block's joints allow there, if lower (a rotary joint
/// that turns several degrees per mm; see `crate::fiveaxis`); never more
/// than the acceleration limit (a rest point has no acceleration row of
/// its own, and a stiff machine's half tick of jerk, above 4·10⁶ mm/s³ at
/// the defaults, is more than it).
fn rest_accel(a_rest: f64, it: &Interval, cfg: &InterpConfig) -> f64 {
    let a = a_rest.min(it.accel);
    if it.joint_jerk.is_finite() {
        a.min(0.5 * it.joint_jerk * cfg.period)
    } else {
        a
    }
}

/// The fallback plan of pieces `from..`: each rests at both ends
/// (`S = 2d·u(1−u)`), with the largest `d` that keeps every limit of the
/// linear program's rows, in closed form (each piece depends on its own `d`
/// alone).
fn crawl(d: &mut Data, from: usize, ovr: f64, lift: &Option<Lift>) {
    let cfg = d.cfg;
    let keep = 1.0 - cfg.planning_margin;
    let a_rest = 0.5 * cfg.max_path_jerk * keep * cfg.period;
    for i in from..d.n_pieces {
        d.pieces[i].rest_start = true;
    }
    for i in from..d.n_pieces {
        let p = d.pieces[i];
        let h = p.h();
        let it = *d.interval(p.g);
        let l2 = d.limit2(i, ovr, lift);
        let vmax = libm::sqrt(l2).max(1e-9);
        // Hull, rests (|S'/2| = d/h at the ends), jerk (|S''|/2 = 2d/h²).
        let mut best = l2
            .min(rest_accel(a_rest, &it, &cfg) * h)
            .min(it.jerk * h * h / (2.0 * vmax));
        // (Every piece rests at both ends.)
        for smp in d.piece_samples(&p, true) {
            let u = ((smp.s - p.x0) / h).clamp(0.0, 1.0);
            for ax in 0..3 {
                let coef = smp.csss[ax] * 2.0 * u * (1.0 - u)
                    + 1.5 * smp.css[ax] * 2.0 / h * (1.0 - 2.0 * u)
                    - 0.5 * smp.t[ax] * 4.0 / (h * h);
                if coef != 0.0 {
                    let jb = cfg.axis_max_jerk[ax] * keep * (1.0 - smp.reserve.larger(ax));
                    best = best.min(jb / vmax / libm::fabs(coef));
                }
            }
        }
        d.pieces[i].d = best.max(0.0);
    }
}

/// Grid index of the interval containing arc length `s` on a grid of spacing `h`.
#[inline]
pub fn index_of(s: f64, h: f64) -> i64 {
    libm::floor(s / h) as i64
}

/// The interval a per-axis sample at `s` is kept in: as [`index_of`], with a
/// sample within round-off of an interval's start counted in it (samples
/// fall on boundaries; which interval holds one must not turn on
/// round-off, since an interval holds [`SAMPLES_PER_INTERVAL`] at most).
pub(crate) fn sample_interval(s: f64, h: f64) -> i64 {
    libm::floor(s / h + SUB_SNAP / SUB as f64) as i64
}
