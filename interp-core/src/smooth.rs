//! Corners and dense G1 under `G64 P`: the non-real-time stage between the
//! program's blocks and [`BlockPlanner::plan`](crate::BlockPlanner::plan).
//!
//! CAM finishing programs are tens of thousands of line moves of a few µm.
//! Interpolated one by one, every vertex is a corner the machine must crawl
//! through. Under `G64 P tol` ([`Blending::Within`]) this stage rewrites the
//! path within `tol` of the programmed polyline:
//!
//! - **Runs of short moves** (each at most `compress_max_move`, turning by at
//!   most [`FIT_MAX_TURN`] at each vertex) are compressed into cubic B-spline
//!   pieces of at most [`MAX_CTRL`] control points, fitted by least squares
//!   ([`crate::fit`]; one free control point per eight, four, then two data points first, so a
//!   short run is smoothed, not interpolated). Consecutive pieces of a run join with the same first
//!   and second derivative (the next piece's first three control points are
//!   fixed by the previous piece's end), so the schedule sees one
//!   curvature-continuous curve. Every piece is checked against the
//!   polyline before it is emitted ([`Smoother`] docs: the check), and a
//!   piece slower than [`crate::plan::stop_speed`] anywhere (micro-moves
//!   turning sharply fit with a radius of nanometres) is refused as a blend
//!   is below: the run is cut before the turn, which becomes a corner.
//! - **Corners between line moves** that stay lines get a quintic Bézier
//!   blend whose three first and three last control points lie on the two
//!   lines: tangent and curvature (zero) continuous with both. Its size is
//!   the largest that keeps the corner within `tol` and takes at most half of
//!   either line. A blend slower than [`crate::plan::stop_speed`] at its
//!   tightest point (the machine laws at its curvature) is no useful blend:
//!   a stop is faster, and the corner stays exact.
//!
//! Under `G64`, consecutive lines whose joint lies on the line through their
//! outer ends (within round-off, same feed) are merged. Under every mode,
//! lines of round-off length are dropped. Arcs and NURBS pass through
//! unchanged; `ExactPath` and `ExactStop` never change the path, and their
//! blocks are released as soon as they are pushed (nothing can change them),
//! so a streaming client's last exact-path block moves without waiting for
//! the program's end.
//!
//! The stage is streaming and fixed-capacity: [`Smoother::push`] takes the
//! next program block, [`Smoother::pop`] gives the next block for the
//! planner once it is decided, [`Smoother::finish`] marks the program's end.
//! It holds back at most `W` blocks; when its window is full it decides its
//! front with what it has, so a streaming client never waits on it. Output
//! depends only on the blocks pushed (and `finish`), never on when `pop` is
//! called: deterministic.

use heapless::Deque;

use crate::config::{ConfigError, InterpConfig};
use crate::feed::machine_limit;
use crate::fit::{BAND, lsq_fit, place_knots};
use crate::geom::{Curve, Vec3};
use crate::nurbs::{MAX_CTRL, Nurbs};
use crate::path::{Blending, Block, Line, Path};

/// Blocks the stage holds back by default.
pub const DEFAULT_WINDOW: usize = 256;

/// A run of compressed moves ends where the path turns by more than this at
/// a vertex (rad, 30°): such a corner cannot be fitted within a µm tolerance
/// by a few control points; it is blended or kept exact instead.
pub const FIT_MAX_TURN: f64 = core::f64::consts::FRAC_PI_6;

/// Corners turning by more than this (rad, 170°) are never blended: the
/// blend would nearly reverse on itself.
pub const BLEND_MAX_TURN: f64 = 17.0 * core::f64::consts::PI / 18.0;

/// Round-off, relative to the coordinates' magnitude (at least 1 mm): a line
/// shorter than this is dropped, a joint this close to the line through its
/// neighbours is collinear.
pub const ROUND_OFF: f64 = 1e-12;

/// Share of the tolerance the sagitta between two checked samples may take.
const SAG_SHARE: f64 = 0.05;

/// Most samples per data interval in the piece check.
const MAX_SAMPLES_PER_INTERVAL: usize = 512;

/// Segments on either side of a data interval that the check measures against.
const CHECK_REACH: usize = 2;

/// Degree of the compressed pieces.
const DEGREE: usize = 3;

/// Data points per free control point a piece is fitted with, leanest
/// first (least-squares fits, not interpolants): see [`fit_piece`]. A
/// leaner fit within the tolerance is smoother, and its lower `C‴` lets the
/// axes' jerk pass it faster (the steady law `C‴ᵢ·v³ ≤ Jᵢ`).
const LEAN_POINTS: [usize; 3] = [8, 4, 2];

/// Weights of the smoothing fits tried before [`LEAN_POINTS`], largest
/// first, relative to `tol²` times the data points per mm: a piece
/// minimises its squared distances to the data plus
/// `weight·tol²·(points/mm)·∫|C‴|² du` ([`crate::fit::add_cubic_jerk_penalty`]),
/// so at weight 1 a residual of `tol` balances a `C‴` of 1/mm². The first
/// that passes the check is kept: the smoothest piece found within the
/// tolerance. Between a raster's slow points the steady axis-jerk law
/// `C‴ᵢ·v³ ≤ Jᵢ` of the least-squares pieces held the speed (see
/// docs/interp-core.md, "Runs of short moves").
const SMOOTHING: [f64; 6] = [10.0, 3.0, 1.0, 0.3, 0.1, 0.01];

/// Data points per free control point of the smoothing fits.
const SMOOTH_POINTS: usize = 4;

/// Blocks a single decision emits at most (a line and its corner blend).
const OUT: usize = 4;

/// How corners and runs are treated under `G64 P` (the production choice is
/// [`Policy::Auto`]; the others exist to measure it against, see
/// `docs/interp-core.md`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Policy {
    /// Compress runs of short moves, blend corners between the lines left.
    #[default]
    Auto,
    /// Never compress: every corner is blended (or exact when no blend is useful).
    BlendOnly,
    /// Compress runs, never blend: corners between lines are exact.
    CompressOnly,
}

/// Why [`Smoother::push`] refused a block.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SmoothError {
    /// The window is full: [`Smoother::pop`] first (it then returns a block).
    Full,
    /// [`Smoother::finish`] was called: no more blocks in this program.
    Finished,
}

impl core::fmt::Display for SmoothError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            SmoothError::Full => "smoothing window full (pop first)",
            SmoothError::Finished => "program already finished",
        })
    }
}

/// What the stage did, for reports.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SmoothStats {
    /// Blocks pushed.
    pub blocks_in: u64,
    /// Blocks popped.
    pub blocks_out: u64,
    /// Lines of round-off length dropped.
    pub dropped: u64,
    /// Collinear joints removed.
    pub merged: u64,
    /// Line moves compressed into NURBS pieces.
    pub compressed_moves: u64,
    /// NURBS pieces emitted.
    pub pieces: u64,
    /// Corners blended.
    pub blends: u64,
    /// Corners under `G64 P` left exact (no useful blend).
    pub exact_corners: u64,
}

/// A buffered program block.
#[derive(Clone, Copy, Debug)]
struct Seg {
    /// The block as pushed (a merged line: its path replaced).
    block: Block,
    /// Its end point.
    end: Vec3,
    /// Unit direction (lines).
    dir: Vec3,
    /// Length, mm.
    len: f64,
    /// The path differs from what was pushed (merged).
    modified: bool,
    /// The block changes frame (tool-centre-point control on or off): it
    /// starts at its own start, the machine's pose seen in its frame, not
    /// where the last block's path ends.
    restart: bool,
}

impl Seg {
    fn line(&self) -> bool {
        matches!(self.block.path, Path::Line(_))
    }
}

/// The smoothing stage; see the module docs. `W` is the hold-back window
/// (blocks).
///
/// **The check.** A fitted piece `C` over data points `v_0..v_k` (chord-length
/// parameters `t_i`) is emitted only if (a) `|C(t_i) − v_i| ≤ tol` for every
/// data point, and (b) for consecutive samples `A = C(τ_a)`, `B = C(τ_b)`
/// (every data interval cut so that the sagitta bound below is at most 5 % of
/// `tol`), `min_s max(d(A, s), d(B, s)) + M₂·(τ_b − τ_a)²/8 ≤ tol` over the
/// polyline segments `s` near the interval. The distance to one segment is
/// convex, so the chord `AB` is within the first term of `s`; `M₂` bounds
/// `|C''|` (the largest second-difference control point of the cubic), so the
/// curve is within the second term of the chord. Hence every point of the
/// piece is within `tol` of the polyline. Blends pass the same check.
pub struct Smoother<const W: usize = DEFAULT_WINDOW> {
    cfg: InterpConfig,
    policy: Policy,
    segs: Deque<Seg, W>,
    /// Where the front block starts now (moved along it by a corner blend).
    start: Vec3,
    /// `start` is not the front block's own start.
    start_trimmed: bool,
    /// First and second derivative (parameter in mm) of what was emitted
    /// last, at `start`: a fit that continues from here matches them.
    join: Option<(Vec3, Vec3)>,
    /// End of the last block pushed (kept).
    tail: Option<Vec3>,
    /// The last block pushed was under tool-centre-point control (`tail`
    /// is the tool tip).
    tail_tcp: bool,
    out: Deque<Block, OUT>,
    next_id: u32,
    finished: bool,
    stats: SmoothStats,
}

impl<const W: usize> core::fmt::Debug for Smoother<W> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Smoother")
            .field("held", &self.segs.len())
            .field("next_id", &self.next_id)
            .field("stats", &self.stats)
            .finish_non_exhaustive()
    }
}

/// Scratch of one fit attempt.
struct Fit {
    knots: [f64; MAX_CTRL + DEGREE + 1],
    ctrl: [Vec3; MAX_CTRL],
    band: [[f64; BAND]; MAX_CTRL],
    rhs: [[f64; 3]; MAX_CTRL],
}

impl<const W: usize> Smoother<W> {
    /// A stage for one program under `cfg`; the blocks it emits are numbered
    /// from `first_id` (a program run through unchanged keeps its ids when
    /// they were consecutive from `first_id`).
    pub fn new(cfg: &InterpConfig, first_id: u32) -> Result<Self, ConfigError> {
        Self::with_policy(cfg, first_id, Policy::Auto)
    }

    /// [`Smoother::new`] with another corner [`Policy`] (for measurements).
    pub fn with_policy(
        cfg: &InterpConfig,
        first_id: u32,
        policy: Policy,
    ) -> Result<Self, ConfigError> {
        cfg.validate()?;
        assert!(W >= 3, "a smoothing window holds at least 3 blocks");
        Ok(Smoother {
            cfg: *cfg,
            policy,
            segs: Deque::new(),
            start: Vec3::zeros(),
            start_trimmed: false,
            join: None,
            tail: None,
            tail_tcp: false,
            out: Deque::new(),
            next_id: first_id,
            finished: false,
            stats: SmoothStats::default(),
        })
    }

    /// What the stage did so far.
    pub fn stats(&self) -> SmoothStats {
        self.stats
    }

    /// Blocks held back.
    pub fn held(&self) -> usize {
        self.segs.len()
    }

    /// Takes the next program block. `Err(Full)`: call [`Smoother::pop`]
    /// (which then returns a block) and push again.
    pub fn push(&mut self, block: &Block) -> Result<(), SmoothError> {
        if self.finished {
            return Err(SmoothError::Finished);
        }
        let path = &block.path;
        // (A turn in place starts and ends where the tool stands.)
        let (p0, p1) = (block.start_position(), block.end_position());
        if self.tail.is_none() {
            self.start = p0;
        }
        // A change of frame starts where the block says (see `Seg::restart`).
        let restart = self.tail.is_some() && block.is_tcp() != self.tail_tcp;
        let from = if restart { p0 } else { self.tail.unwrap_or(p0) };
        // A five-axis block passes unchanged (its rotary axes or tool axis
        // move with it: never dropped, merged, compressed or blended).
        if let (Path::Line(_), None) = (path, &block.orientation) {
            let len = (p1 - from).norm();
            if len <= round_off(&[from, p1]) {
                // Round-off: the next block starts here as well (within it).
                self.stats.blocks_in += 1;
                self.stats.dropped += 1;
                return Ok(());
            }
            if self.try_merge(block, from, p1) {
                self.stats.blocks_in += 1;
                self.stats.merged += 1;
                self.tail = Some(p1);
                return Ok(());
            }
        }
        if self.segs.is_full() {
            return Err(SmoothError::Full);
        }
        let (dir, len) = match path {
            Path::Line(_) if !block.is_in_place() => {
                let d = p1 - from;
                let l = d.norm();
                (d / l, l)
            }
            _ => (Vec3::zeros(), 0.0),
        };
        // A line after a dropped one starts where the stage's path is. A
        // five-axis line keeps its start (the planner checks it).
        let modified = matches!(path, Path::Line(_)) && block.orientation.is_none() && from != p0;
        let mut b = *block;
        if modified {
            b.path = Path::Line(Line::new(from, p1).map_err(|_| SmoothError::Full)?);
        }
        let _ = self.segs.push_back(Seg {
            block: b,
            end: p1,
            dir,
            len,
            modified,
            restart,
        });
        self.stats.blocks_in += 1;
        self.tail = Some(p1);
        self.tail_tcp = block.is_tcp();
        Ok(())
    }

    /// The program ends: what is held back is released by [`Smoother::pop`].
    pub fn finish(&mut self) {
        self.finished = true;
    }

    /// The next block for the planner, once it is decided (`None`: push more,
    /// or after [`Smoother::finish`], everything was released).
    pub fn pop(&mut self) -> Option<Block> {
        while self.out.is_empty() {
            if !self.step() {
                break;
            }
        }
        let b = self.out.pop_front()?;
        self.stats.blocks_out += 1;
        Some(b)
    }

    /// Merges a line from `from` to `to` into the last held line if their
    /// joint is collinear. Only under `G64` (a merge must wait for the next
    /// block, which exact-path blocks never do), when the last one is still
    /// whole (nothing of it emitted), with the same feed, MRR and mode.
    fn try_merge(&mut self, block: &Block, from: Vec3, to: Vec3) -> bool {
        let Some(last) = self.segs.back() else {
            return false;
        };
        let single = self.segs.len() == 1;
        if !last.line()
            || (single && self.start_trimmed)
            || self.tolerance(&last.block).is_none()
            || last.block.blending != block.blending
            || last.block.feed != block.feed
            || last.block.mrr != block.mrr
        {
            return false;
        }
        let a = last.block.path.start_point();
        let ac = to - a;
        let l = ac.norm();
        let along = (from - a).dot(&ac);
        // The joint strictly between the outer ends, on their line.
        if !(l > 0.0 && along > 0.0 && along < l * l) {
            return false;
        }
        let off = (from - a - ac * (along / (l * l))).norm();
        if off > round_off(&[a, from, to]) {
            return false;
        }
        let Ok(line) = Line::new(a, to) else {
            return false;
        };
        let last = self.segs.back_mut().expect("checked");
        last.block.path = Path::Line(line);
        last.end = to;
        last.dir = ac / l;
        last.len = l;
        last.modified = true;
        true
    }

    /// Held block `i` (from the front); `i` must be below `held()`.
    fn seg(&self, i: usize) -> Seg {
        *self.segs.get(i).expect("held block")
    }

    /// The `G64 P` tolerance of a block, if it may be smoothed.
    fn tolerance(&self, b: &Block) -> Option<f64> {
        if b.orientation.is_some() {
            return None;
        }
        match b.blending {
            Blending::Within { tolerance } => {
                let t = tolerance.unwrap_or(self.cfg.default_blend_tolerance);
                (t.is_finite() && t > 0.0).then_some(t)
            }
            _ => None,
        }
    }

    fn emit(&mut self, mut b: Block) {
        b.id = self.next_id;
        self.next_id = self.next_id.wrapping_add(1);
        let _ = self.out.push_back(b);
    }

    /// Decides the front block if it can be decided now; false: wait.
    ///
    /// Only blocks that can no longer change are looked at: the last block
    /// held, if it is a `G64` line, may still grow by a collinear merge until
    /// another one follows it (or the program ends). So the decision is the
    /// same whenever `pop` is called.
    fn step(&mut self) -> bool {
        let Some(&front) = self.segs.front() else {
            return false;
        };
        if front.restart && !self.start_trimmed && self.start != front.block.path.start_point() {
            // A new frame: the path goes on from the block's own start.
            self.start = front.block.path.start_point();
            self.join = None;
        }
        let may_grow = self
            .segs
            .back()
            .is_some_and(|last| last.line() && self.tolerance(&last.block).is_some());
        let stable = if self.finished || !may_grow {
            self.segs.len()
        } else {
            self.segs.len() - 1
        };
        if stable == 0 {
            return false;
        }
        let known = self.finished || self.segs.is_full();
        let tol = self.tolerance(&front.block).filter(|_| front.line());
        let Some(tol) = tol else {
            // Not smoothed: as it is (the start only moves after a dropped line).
            let mut b = front.block;
            if front.line()
                && b.orientation.is_none()
                && (self.start_trimmed || self.start != b.path.start_point())
                && let Ok(l) = Line::new(self.start, front.end)
            {
                b.path = Path::Line(l);
            }
            self.emit(b);
            self.advance(1, front.end, None);
            return true;
        };
        if self.policy != Policy::BlendOnly {
            let (m, complete) = self.run_len(tol, stable);
            if !complete && !known {
                return false;
            }
            if (m >= 2 || (m >= 1 && self.join.is_some())) && self.emit_fit(m, complete, tol) {
                return true;
            }
        }
        // The front stays a line; its end corner needs the next block, and
        // whether that one starts a compressed run, its next.
        if stable < 3 && !self.finished {
            return false;
        }
        self.emit_line(front, tol);
        true
    }

    /// Drops `n` blocks from the front; the path now is at `at`.
    fn advance(&mut self, n: usize, at: Vec3, join: Option<(Vec3, Vec3)>) {
        for _ in 0..n {
            self.segs.pop_front();
        }
        self.start = at;
        self.start_trimmed = false;
        // A join only helps a fit that continues in nearly the same direction.
        self.join = join.filter(|(d1, _)| match self.segs.front() {
            Some(s) if s.line() => turn(d1, &s.dir) <= FIT_MAX_TURN,
            _ => false,
        });
    }

    /// Whether block `s` continues a compressed run of tolerance `tol` that
    /// `prev` is in, the run going along `dir` (`None`: no direction yet,
    /// see [`run_dir`]).
    fn continues(&self, dir: Option<Vec3>, prev: &Seg, s: &Seg, tol: f64) -> bool {
        s.line()
            && self.tolerance(&s.block) == Some(tol)
            && s.block.feed == prev.block.feed
            && s.block.mrr == prev.block.mrr
            && s.len <= self.cfg.compress_max_move
            && (run_dir(s, tol).is_none() || dir.is_none_or(|d| turn(&d, &s.dir) <= FIT_MAX_TURN))
    }

    /// Blocks of the compressible run at the front, and whether its end is known.
    fn run_len(&self, tol: f64, n: usize) -> (usize, bool) {
        let first = self.seg(0);
        if !(first.len <= self.cfg.compress_max_move) {
            return (0, true);
        }
        let mut dir = run_dir(&first, tol);
        let mut m = 1;
        while m < n {
            let s = self.seg(m);
            if !self.continues(dir, &self.seg(m - 1), &s, tol) {
                return (m, true);
            }
            dir = run_dir(&s, tol).or(dir);
            m += 1;
        }
        (m, self.finished)
    }

    /// Emits the front as a line, with a blend at its end corner when useful.
    fn emit_line(&mut self, front: Seg, tol: f64) {
        let v = front.end;
        let mut blend = None;
        if self.policy != Policy::CompressOnly
            && let Some(&next) = self.segs.get(1)
            && next.line()
            && let Some(t2) = self.tolerance(&next.block)
            && self.next_is_line(&next)
        {
            let th = turn(&front.dir, &next.dir);
            if th > 0.0 && th <= BLEND_MAX_TURN {
                // The front's start may have been taken by the blend before.
                let left = (v - self.start).norm().min(0.5 * front.len);
                blend =
                    self.corner_blend(v, front.dir, next.dir, left, 0.5 * next.len, tol.min(t2));
                if blend.is_none() {
                    self.stats.exact_corners += 1;
                }
            }
        }
        let end = blend.map_or(v, |(_, d)| v - front.dir * d);
        let whole = !front.modified && !self.start_trimmed && blend.is_none();
        if whole {
            self.emit(front.block);
        } else if (end - self.start).norm() > round_off(&[self.start, end])
            && let Ok(l) = Line::new(self.start, end)
        {
            let mut b = front.block;
            b.path = Path::Line(l);
            self.emit(b);
        }
        match blend {
            Some((curve, _)) => {
                let mut b = front.block;
                b.path = Path::Nurbs(curve);
                self.emit(b);
                self.stats.blends += 1;
                let next_dir = self.seg(1).dir;
                let at = curve.end_point();
                self.segs.pop_front();
                self.start = at;
                self.start_trimmed = true;
                self.join = Some((next_dir, Vec3::zeros()));
            }
            None => self.advance(1, v, Some((front.dir, Vec3::zeros()))),
        }
    }

    /// Whether `next` (the block after the front) will be emitted as a line:
    /// it is not the start of a compressed run.
    fn next_is_line(&self, next: &Seg) -> bool {
        if self.policy == Policy::BlendOnly {
            return true;
        }
        let Some(tol) = self.tolerance(&next.block) else {
            return true;
        };
        if !(next.len <= self.cfg.compress_max_move) {
            return true;
        }
        // A run of one short move stays a line unless a fit joins it, which
        // a blend in front of it would allow: only runs of two or more fit.
        match self.segs.get(2) {
            Some(after) => !self.continues(run_dir(next, tol), next, after, tol),
            None => true,
        }
    }

    /// A curvature-continuous blend of the corner at `v` from direction `a`
    /// to `b`, taking at most `left` and `right` of the two lines, within
    /// `tol`; `None` when no useful blend exists. Returns the curve and its
    /// leg length.
    fn corner_blend(
        &self,
        v: Vec3,
        a: Vec3,
        b: Vec3,
        left: f64,
        right: f64,
        tol: f64,
    ) -> Option<(Nurbs, f64)> {
        let th = turn(&a, &b);
        // Control points v − d·a·{1, 2/3, 1/3}, v + d·b·{1/3, 2/3, 1}: the
        // midpoint is v + d·S·(b − a) with S = (1 + 5·2/3 + 10·1/3)/32, at
        // 2·d·S·sin(θ/2) from the corner.
        const S: f64 = (1.0 + 10.0 / 3.0 + 10.0 / 3.0) / 32.0;
        let by_tol = tol * (1.0 - 1e-9) / (2.0 * S * libm::sin(0.5 * th));
        let mut d = by_tol.min(left).min(right);
        for _ in 0..4 {
            if !(d > round_off(&[v]) * 1e3) {
                return None;
            }
            let pts = [
                v - a * d,
                v - a * (2.0 * d / 3.0),
                v - a * (d / 3.0),
                v + b * (d / 3.0),
                v + b * (2.0 * d / 3.0),
                v + b * d,
            ];
            let l = 2.0 * d;
            let knots = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, l, l, l, l, l, l];
            let pts3 = pts.map(|p| [p.x, p.y, p.z]);
            let curve = Nurbs::non_rational(5, &pts3, &knots).ok()?;
            let poly = [pts[0], v, pts[5]];
            let ub = [0.0, d, l];
            if check(&curve, &poly, &ub, tol, blend_m2(&pts, l)) {
                // Useful: faster than a stop at its tightest point.
                if slower_than_a_stop(&curve, &self.cfg) {
                    return None;
                }
                return Some((curve, d));
            }
            d *= 0.9;
        }
        None
    }

    /// Fits the longest piece of the front run (`m` blocks) that passes the
    /// check and emits it; false if none does.
    fn emit_fit(&mut self, m: usize, complete: bool, tol: f64) -> bool {
        let front = self.seg(0);
        // Data: the run's vertices and their chord-length parameters.
        let mut q = [Vec3::zeros(); W];
        let mut t = [0.0f64; W];
        let n_pts = m.min(W - 1) + 1;
        let m = n_pts - 1;
        q[0] = self.start;
        for i in 1..n_pts {
            q[i] = self.seg(i - 1).end;
            t[i] = t[i - 1] + (q[i] - q[i - 1]).norm();
        }
        // A run that ends in a line nearly in line with it ends along it,
        // with zero curvature: the joint is as smooth as a blend.
        let end_dir = match (complete, self.segs.get(m)) {
            (true, Some(s))
                if s.line()
                    && self.tolerance(&s.block).is_some()
                    && turn(&self.seg(m - 1).dir, &s.dir) <= FIT_MAX_TURN =>
            {
                Some(s.dir)
            }
            _ => None,
        };
        let mut scratch = Fit {
            knots: [0.0; MAX_CTRL + DEGREE + 1],
            ctrl: [Vec3::zeros(); MAX_CTRL],
            band: [[0.0; BAND]; MAX_CTRL],
            rhs: [[0.0; 3]; MAX_CTRL],
        };
        let joins = [self.join, None];
        for join in joins.iter().take(if self.join.is_some() { 2 } else { 1 }) {
            let k_min = if join.is_some() { 1 } else { 3 };
            if m < k_min {
                continue;
            }
            let cfg = &self.cfg;
            let mut attempt = |k: usize| {
                let end = if k == m { end_dir } else { None };
                // A piece slower than a stop somewhere (a sharp turn of
                // micro-moves fitted with a tiny radius) is worse than
                // stopping there: its slow point limits a whole law
                // sub-range of the schedule. Shorter runs, ending before
                // the turn, are tried instead.
                fit_piece(&q[..=k], &t[..=k], *join, end, tol, cfg, &mut scratch).or_else(|| {
                    end.and_then(|_| {
                        fit_piece(&q[..=k], &t[..=k], *join, None, tol, cfg, &mut scratch)
                    })
                })
            };
            // The whole run first, then bisection for the longest that passes.
            let mut best = attempt(m).map(|c| (m, c));
            if best.is_none() {
                let (mut lo, mut hi) = (k_min - 1, m);
                while hi - lo > 1 {
                    let mid = lo + (hi - lo) / 2;
                    match attempt(mid) {
                        Some(c) => {
                            lo = mid;
                            best = Some((mid, c));
                        }
                        None => hi = mid,
                    }
                }
            }
            if let Some((k, curve)) = best {
                let mut b = front.block;
                b.path = Path::Nurbs(curve);
                self.emit(b);
                self.stats.pieces += 1;
                self.stats.compressed_moves += k as u64;
                let e = curve.eval(curve.u_end(), 2);
                self.advance(k, q[k], Some((e.d1, e.d2)));
                return true;
            }
        }
        false
    }
}

/// Fits one clamped cubic to `q` (parameters `t`, from 0); `join` fixes the
/// start's first and second derivative, `end` the end's direction (with zero
/// curvature). `None` unless the piece passes the check within `tol` and is
/// nowhere slower than a stop ([`slower_than_a_stop`]).
///
/// First as a smoothing fit with one free control point per
/// [`SMOOTH_POINTS`] data points and each weight of [`SMOOTHING`], heaviest
/// first; then with one free control point per [`LEAN_POINTS`] data points,
/// leanest first (a plain least-squares fit), then with as many as the data
/// supports (at most
/// [`MAX_CTRL`]: an interpolant when the run is short). A short run's
/// interpolant whose start curvature is fixed by a join swings from point to
/// point: on a smooth slope it took a bend of µm radius (2 mm/s) and left
/// the next piece a corner of up to 17°; the least-squares fit follows the
/// slope (`the_short_rest_of_a_long_run_joins_it_smoothly`).
#[allow(clippy::too_many_arguments)]
fn fit_piece(
    q: &[Vec3],
    t: &[f64],
    join: Option<(Vec3, Vec3)>,
    end: Option<Vec3>,
    tol: f64,
    cfg: &InterpConfig,
    s: &mut Fit,
) -> Option<Nurbs> {
    let k = q.len() - 1;
    let fs = if join.is_some() { 3 } else { 1 };
    let fe = if end.is_some() { 3 } else { 1 };
    let full = (k - 1 + fs + fe).min(MAX_CTRL);
    let fast = |c: &Nurbs| !slower_than_a_stop(c, cfg);
    // Control points for one free one per `points` data points.
    let lean = |points: usize| (fs + fe + (k - 1).div_ceil(points)).max(DEGREE + 1);
    let density = k as f64 / (t[k] - t[0]);
    let count = lean(SMOOTH_POINTS).min(full);
    for weight in SMOOTHING {
        let smoothing = weight * tol * tol * density;
        if let Some(c) = fit_count(q, t, join, end, tol, count, smoothing, s).filter(fast) {
            return Some(c);
        }
    }
    let mut tried = usize::MAX;
    for points in LEAN_POINTS {
        let count = lean(points);
        if count < full
            && count < tried
            && let Some(c) = fit_count(q, t, join, end, tol, count, 0.0, s).filter(fast)
        {
            return Some(c);
        }
        tried = count;
    }
    fit_count(q, t, join, end, tol, full, 0.0, s).filter(fast)
}

/// [`fit_piece`] with `count` control points and a `smoothing` weight (0 for
/// a plain least-squares fit).
#[allow(clippy::too_many_arguments)]
fn fit_count(
    q: &[Vec3],
    t: &[f64],
    join: Option<(Vec3, Vec3)>,
    end: Option<Vec3>,
    tol: f64,
    count: usize,
    smoothing: f64,
    s: &mut Fit,
) -> Option<Nurbs> {
    let k = q.len() - 1;
    let p = DEGREE;
    let fs = if join.is_some() { 3 } else { 1 };
    let fe = if end.is_some() { 3 } else { 1 };
    if count < p + 1 || count < fs + fe {
        return None;
    }
    let n = count - 1;
    let knots = &mut s.knots[..count + p + 1];
    let (a, b) = (t[0], t[k]);
    if n <= k {
        place_knots(t, n, p, knots);
    } else {
        knots[..=p].fill(a);
        knots[n + 1..].fill(b);
        for j in 1..=n - p {
            knots[p + j] = a + (b - a) * j as f64 / (n - p + 1) as f64;
        }
    }
    // Strictly increasing interior knots (coincident data parameters would
    // make an empty span).
    if knots[p..=n + 1].windows(2).any(|w| !(w[0] < w[1])) {
        return None;
    }
    let ctrl = &mut s.ctrl[..count];
    ctrl[0] = q[0];
    ctrl[n] = q[k];
    if let Some((d1, d2)) = join {
        ctrl[1] = ctrl[0] + d1 * ((knots[4] - a) / 3.0);
        let q1 = d1 + d2 * ((knots[4] - a) / 2.0);
        ctrl[2] = ctrl[1] + q1 * ((knots[5] - a) / 3.0);
    }
    if let Some(e1) = end {
        ctrl[n - 1] = ctrl[n] - e1 * ((b - knots[n]) / 3.0);
        ctrl[n - 2] = ctrl[n - 1] - e1 * ((b - knots[n - 1]) / 3.0);
    }
    lsq_fit(
        q,
        t,
        p,
        knots,
        ctrl,
        fs,
        fe,
        smoothing,
        &mut s.band,
        &mut s.rhs,
    )
    .ok()?;
    let pts: [[f64; 3]; MAX_CTRL] = core::array::from_fn(|i| {
        let c = if i < count { ctrl[i] } else { Vec3::zeros() };
        [c.x, c.y, c.z]
    });
    let curve = Nurbs::non_rational(p, &pts[..count], knots).ok()?;
    // M₂: the cubic's second-derivative control points (a linear B-spline).
    let mut m2 = 0.0f64;
    let dq = |i: usize| (ctrl[i + 1] - ctrl[i]) * (3.0 / (knots[i + 4] - knots[i + 1]));
    for i in 0..n - 1 {
        let r = (dq(i + 1) - dq(i)) * (2.0 / (knots[i + 4] - knots[i + 2]));
        m2 = m2.max(r.norm());
    }
    check(&curve, q, t, tol, m2).then_some(curve)
}

/// `|C''|` bound of the blend's quintic Bézier: `20·max|Δ²P|/L²`.
fn blend_m2(pts: &[Vec3; 6], l: f64) -> f64 {
    (0..4)
        .map(|i| (pts[i + 2] - pts[i + 1] * 2.0 + pts[i]).norm())
        .fold(0.0, f64::max)
        * 20.0
        / (l * l)
}

/// Samples per knot span in [`slower_than_a_stop`].
const SPEED_SAMPLES: usize = 16;

/// Whether the machine law somewhere on `curve` (sampled per knot span) is
/// below [`crate::plan::stop_speed`]: passing there costs more than an exact
/// stop (see the module docs).
fn slower_than_a_stop(curve: &Nurbs, cfg: &InterpConfig) -> bool {
    let stop = crate::plan::stop_speed(cfg);
    let k = curve.knots();
    k.windows(2).filter(|w| w[1] > w[0]).any(|w| {
        (0..=SPEED_SAMPLES).any(|i| {
            let u = w[0] + (w[1] - w[0]) * i as f64 / SPEED_SAMPLES as f64;
            machine_limit(&curve.eval(u, 3), cfg, 1.0) < stop
        })
    })
}

/// The check of [`Smoother`]: every point of `curve` within `tol` of the
/// polyline `q` (parameters `ub` on the curve), and every vertex within `tol`
/// of the curve point at its parameter. `m2` bounds `|C''|`.
fn check(curve: &Nurbs, q: &[Vec3], ub: &[f64], tol: f64, m2: f64) -> bool {
    let k = q.len() - 1;
    // Parameter step whose sagitta bound is SAG_SHARE of the tolerance.
    let h = if m2 > 0.0 {
        libm::sqrt(8.0 * SAG_SHARE * tol / m2)
    } else {
        f64::INFINITY
    };
    let mut prev = curve.start_point();
    if (prev - q[0]).norm() > tol {
        return false;
    }
    let mut prev_u = ub[0];
    for i in 0..k {
        let (ua, ub1) = (ub[i], ub[i + 1]);
        let ns = libm::ceil((ub1 - ua) / h).clamp(1.0, MAX_SAMPLES_PER_INTERVAL as f64) as usize;
        let lo = i.saturating_sub(CHECK_REACH);
        let hi = (i + CHECK_REACH).min(k - 1);
        for j in 1..=ns {
            let u = if j == ns {
                ub1
            } else {
                ua + (ub1 - ua) * j as f64 / ns as f64
            };
            let pt = curve.eval(u, 0).p;
            if j == ns && (pt - q[i + 1]).norm() > tol {
                return false;
            }
            let du = u - prev_u;
            let sag = m2 * du * du / 8.0;
            let mut best = f64::INFINITY;
            for s in lo..=hi {
                let d = seg_dist(&prev, &q[s], &q[s + 1]).max(seg_dist(&pt, &q[s], &q[s + 1]));
                best = best.min(d);
            }
            if !(best + sag <= tol) {
                return false;
            }
            prev = pt;
            prev_u = u;
        }
    }
    true
}

/// Distance from `x` to the segment `a b`.
fn seg_dist(x: &Vec3, a: &Vec3, b: &Vec3) -> f64 {
    let ab = b - a;
    let l2 = ab.norm_squared();
    let t = if l2 > 0.0 {
        ((x - a).dot(&ab) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (x - (a + ab * t)).norm()
}

/// Share of the tolerance below which a move has no direction a run's turn
/// is measured by: CAM output has moves of nanometres between two samples
/// of one point (the same X Y, Z differing by round-off), which turn by
/// 90° at both ends. Kept in the run, the fit passes within the tolerance
/// of both ends (the check proves it) instead of two exact corners
/// stopping the machine.
const MICRO_MOVE_SHARE: f64 = 0.1;

/// The direction a compressed run goes along at `s` (tolerance `tol`):
/// none for a move shorter than [`MICRO_MOVE_SHARE`] of the tolerance.
fn run_dir(s: &Seg, tol: f64) -> Option<Vec3> {
    (s.len > MICRO_MOVE_SHARE * tol).then_some(s.dir)
}

/// Angle between two directions, rad (π for opposite; 0 for a zero vector).
fn turn(a: &Vec3, b: &Vec3) -> f64 {
    let (na, nb) = (a.norm(), b.norm());
    if !(na > 0.0 && nb > 0.0) {
        return 0.0;
    }
    // atan2 of |a×b| and a·b: accurate for tiny angles too.
    libm::atan2(a.cross(b).norm(), a.dot(b))
}

/// Round-off length at these points: ROUND_OFF × their largest coordinate (≥ 1 mm).
fn round_off(pts: &[Vec3]) -> f64 {
    let scale = pts
        .iter()
        .flat_map(|p| p.iter())
        .fold(1.0f64, |m, c| m.max(libm::fabs(*c)));
    ROUND_OFF * scale
}
