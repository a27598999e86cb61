//! Moves ready for the interpolator, and the one way they become
//! interp-core blocks.
//!
//! [`Program::for_each_move`](crate::Program::for_each_move) decides
//! everything a G-code program leaves open (rapid speed, feed units, G93,
//! moves of zero length, the path control mode, where a move starts after
//! tool-centre-point control goes on or off, rotary positions turned into
//! tool axes) and hands out [`Move`]s; the `traces` JSON block form is a
//! [`Move`] field for field. A [`Cutter`] turns moves, in order, into
//! interp-core blocks: `to_core_blocks`, `interpd simulate`, the service's
//! control plane and `interpd replay` all cut with it, so one program gives
//! the same blocks everywhere.

use interp_core::fiveaxis::{
    JointError, Orientation as CoreOrientation, OrientationError, walk_joints,
};
use interp_core::interp::JOIN_TOLERANCE;
use interp_core::kinematics::{Joints, Machine};
use interp_core::nurbs::{SplitError, split_program_curve};
use interp_core::path::{Arc, Blending, Block, Line, MrrParams, Path, PathError};
use interp_core::{Curve, NurbsError, Vec3};

/// Seconds per minute: feeds are per minute, interp-core's per second.
pub const SECONDS_PER_MINUTE: f64 = 60.0;

/// A move as the interpolator takes it: the conversion's decisions made.
#[derive(Debug, Clone, PartialEq)]
pub struct Move<'a> {
    /// Source line of the program block (the line errors name; a NURBS's
    /// last line).
    pub line: u32,
    /// Source line where the move begins (a NURBS's first line).
    pub first_line: u32,
    /// Feed, mm/min: G94's F, G93's F times the move's length, rapids at the
    /// rapid speed × 60.
    pub feed: f64,
    /// How the path may pass the move's end (the path control mode).
    pub blending: Blending,
    /// Where the move starts when it is not where the last one ended: the
    /// first move of a program, and the first after tool-centre-point
    /// control goes on or off (the machine's pose seen in the new frame).
    /// `None`: where the last move ended.
    pub start: Option<[f64; 3]>,
    /// The geometry.
    pub path: MovePath<'a>,
    /// Rotary axes or tool axis along the move (`None`: a three-axis move).
    pub orientation: Option<MoveOrientation>,
    /// Constant-MRR law parameters (not in G-code; the JSON block form has them).
    pub mrr: Option<MrrParams>,
}

/// The geometry of a [`Move`], from where it starts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MovePath<'a> {
    /// Straight line to `end`.
    Line {
        /// End point, mm.
        end: [f64; 3],
    },
    /// Circular (or helical) arc to `end` about `centre`.
    Arc {
        /// End point, mm.
        end: [f64; 3],
        /// Centre, mm (its component along `axis` is ignored).
        centre: [f64; 3],
        /// Normal of the arc's plane (G17: +Z).
        axis: [f64; 3],
        /// Clockwise about `axis` (G2).
        clockwise: bool,
        /// Extra full turns.
        turns: u32,
    },
    /// Rational NURBS, exactly as written; its first control point is where
    /// it starts.
    Nurbs {
        /// Degree.
        degree: usize,
        /// Control points, mm.
        points: &'a [[f64; 3]],
        /// One positive weight per control point (`None`: all 1).
        weights: Option<&'a [f64]>,
        /// `points.len() + degree + 1` knots, clamped.
        knots: &'a [f64],
        /// A B C of each control point (G6.2 with rotary coordinates,
        /// tool-centre-point control off): the rotary axes are coordinates
        /// of the curve, with its weights and knots. `None`: the move's
        /// orientation, if any, is in proportion to the parameter.
        rotary: Option<&'a [[f64; 3]]>,
        /// The tool vector of each control point (G6.2 with `U V W` under
        /// G43.5): a second curve for the tool axis, these vectors'
        /// NURBS with the curve's weights and knots, normalised. `None`:
        /// the move's tool axis turns on its great circle.
        tool_axes: Option<&'a [[f64; 3]]>,
    },
}

/// What a [`Move`] does beside its path.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MoveOrientation {
    /// Tool-centre-point control off: A B C (degrees) go from `start` to
    /// `end` as plain axes with X Y Z.
    Axes {
        /// A B C where the move starts.
        start: [f64; 3],
        /// A B C where it ends.
        end: [f64; 3],
    },
    /// Tool-centre-point control on: the path is the tool tip in the
    /// workpiece frame and the tool axis turns from `start` to `end` on the
    /// great circle (any length; normalised when cut).
    ToolAxis {
        /// Tool axis where the move starts.
        start: [f64; 3],
        /// Tool axis where it ends.
        end: [f64; 3],
    },
}

impl MoveOrientation {
    /// Under tool-centre-point control (the path is the tool tip)?
    pub fn is_tcp(&self) -> bool {
        matches!(self, MoveOrientation::ToolAxis { .. })
    }

    /// How far the move turns, degrees: `|Δ(A, B, C)|` of the rotary axes,
    /// or the angle the tool axis turns by. A move whose path stands still
    /// (`G0 A30 C45` alone) is a turn in place of this length, and its feed
    /// is in degrees per minute (`interp_core::fiveaxis::Orientation::in_place`).
    pub fn turn(&self) -> f64 {
        match self {
            MoveOrientation::Axes { start, end } => (0..3)
                .map(|k| (end[k] - start[k]) * (end[k] - start[k]))
                .sum::<f64>()
                .sqrt(),
            MoveOrientation::ToolAxis { start, end } => {
                let (a, b) = (v3(*start), v3(*end));
                a.cross(&b).norm().atan2(a.dot(&b)).to_degrees()
            }
        }
    }
}

impl Move<'_> {
    /// Under tool-centre-point control (the path is the tool tip)?
    pub fn is_tcp(&self) -> bool {
        self.orientation.is_some_and(|o| o.is_tcp())
    }
}

/// Why a [`Move`] could not be cut into blocks.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum CutError {
    /// The feed is not a positive finite number of mm/min.
    #[error("feed must be a positive number of mm/min, got {0}")]
    Feed(f64),
    /// The line or arc is invalid.
    #[error("{0}")]
    Path(PathError),
    /// The NURBS is invalid.
    #[error("invalid NURBS: {0}")]
    Nurbs(NurbsError),
    /// The move does not start where the last one ends.
    #[error(
        "starts at {start:?}, but the previous block ends at {previous_end:?} ({gap:e} mm apart)"
    )]
    Discontinuous {
        /// Its start, mm.
        start: [f64; 3],
        /// The previous end, mm.
        previous_end: [f64; 3],
        /// Distance, mm.
        gap: f64,
    },
    /// The move changes frame (tool-centre-point control on or off) but
    /// does not say where it starts.
    #[error(
        "the first block after tool-centre-point control goes on or off must give its start (where the machine stands, seen in the new frame)"
    )]
    FrameStart,
    /// The rotary positions or tool axis are refused.
    #[error("{0}")]
    Orientation(OrientationError),
    /// A NURBS with rotary coordinates (or tool vectors) that turn where
    /// its tool tip stands still (a knot span left out of the path).
    #[error(
        "the rotary coordinates or tool vectors of the NURBS turn where its X Y Z stand still (at parameter {0}): split the move there"
    )]
    RotaryWhileStill(f64),
    /// A NURBS's rotary coordinates or tool vectors are not one per
    /// control point.
    #[error("{what}: {got} given for {want} control points (one per control point)")]
    SecondCurveLength {
        /// `"rotary coordinates"` or `"tool vectors"`.
        what: &'static str,
        /// How many were given.
        got: usize,
        /// How many control points the curve has.
        want: usize,
    },
}

fn v3(p: [f64; 3]) -> Vec3 {
    Vec3::new(p[0], p[1], p[2])
}

fn a3(p: Vec3) -> [f64; 3] {
    [p.x, p.y, p.z]
}

/// Cuts a program's moves, in order, into interp-core blocks: each from the
/// end of the one before (or, where the frame changes, from the start the
/// move gives), feeds in mm/s, NURBS longer than `max_ctrl` control points
/// split into pieces that are the same curve, ids counted up.
#[derive(Debug, Clone, PartialEq)]
pub struct Cutter {
    at: Vec3,
    tcp: bool,
    next_id: u32,
    max_ctrl: usize,
}

impl Cutter {
    /// A program that starts at `start` (mm; the tool tip when `tcp`, else
    /// the machine's X Y Z), with block ids from `first_id` and NURBS pieces
    /// of at most `max_ctrl` control points.
    pub fn new(start: [f64; 3], tcp: bool, first_id: u32, max_ctrl: usize) -> Self {
        Cutter {
            at: v3(start),
            tcp,
            next_id: first_id,
            max_ctrl,
        }
    }

    /// Where the next move starts (the end of the last one), mm.
    pub fn tail(&self) -> [f64; 3] {
        a3(self.at)
    }

    /// Whether the tail is the tool tip (tool-centre-point control).
    pub fn is_tcp(&self) -> bool {
        self.tcp
    }

    /// The id the next block gets.
    pub fn next_id(&self) -> u32 {
        self.next_id
    }

    /// Moves on past `last`, a block cut before (the last of a move's blocks).
    pub fn follow(&mut self, last: &Block) {
        self.at = last.end_position();
        self.tcp = last.is_tcp();
        self.next_id = last.id.wrapping_add(1);
    }

    /// The blocks of the next move. A refused move changes nothing.
    pub fn cut(&mut self, m: &Move<'_>) -> Result<Vec<Block>, CutError> {
        if !(m.feed.is_finite() && m.feed > 0.0) {
            return Err(CutError::Feed(m.feed));
        }
        let feed = m.feed / SECONDS_PER_MINUTE;
        let tcp = m.is_tcp();
        let start = if tcp != self.tcp {
            v3(m.start.ok_or(CutError::FrameStart)?)
        } else {
            if let Some(s) = m.start {
                check_start(v3(s), self.at)?;
            }
            self.at
        };
        let mut id = self.next_id;
        let mut block = |path: Path| {
            let b = Block {
                id,
                path,
                feed,
                mrr: m.mrr,
                blending: m.blending,
                orientation: None,
            };
            id = id.wrapping_add(1);
            b
        };
        let mut out = Vec::new();
        // A straight move whose end is its start but that turns: a turn in
        // place, its path the turn's measure in degrees from where it stands.
        let in_place = match (m.path, m.orientation) {
            (MovePath::Line { end }, Some(o)) if v3(end) == start => Some(o.turn()),
            _ => None,
        };
        match m.path {
            MovePath::Line { end } => {
                let end = match in_place {
                    Some(turn) => start + Vec3::x() * turn,
                    None => v3(end),
                };
                let l = Line::new(start, end).map_err(CutError::Path)?;
                out.push(block(Path::Line(l)));
            }
            MovePath::Arc {
                end,
                centre,
                axis,
                clockwise,
                turns,
            } => {
                let axis = if clockwise { -v3(axis) } else { v3(axis) };
                let a = Arc::from_centre(start, v3(end), v3(centre), axis, turns)
                    .map_err(CutError::Path)?;
                out.push(block(Path::Arc(a)));
            }
            MovePath::Nurbs {
                degree,
                points,
                weights,
                knots,
                rotary,
                tool_axes,
            } => {
                let ones;
                let w: &[f64] = match weights {
                    Some(w) => w,
                    None => {
                        ones = vec![1.0; points.len()];
                        &ones
                    }
                };
                for (what, c) in [("rotary coordinates", rotary), ("tool vectors", tool_axes)] {
                    if let Some(c) = c
                        && c.len() != points.len()
                    {
                        return Err(CutError::SecondCurveLength {
                            what,
                            got: c.len(),
                            want: points.len(),
                        });
                    }
                }
                let mut first = true;
                // Rotary coordinates or tool vectors: one block per knot
                // span, each with its piece of that curve (a rational Bézier).
                let max_ctrl = match (rotary, tool_axes) {
                    (None, None) => self.max_ctrl,
                    _ => degree + 1,
                };
                split_program_curve(degree, points, w, knots, max_ctrl, |n| {
                    if first {
                        first = false;
                        check_start(n.start_point(), start)?;
                    }
                    out.push(block(Path::Nurbs(n)));
                    Ok(())
                })
                .map_err(|e| match e {
                    SplitError::Invalid(n) => CutError::Nurbs(n),
                    SplitError::Sink(k) => k,
                })?;
                if let Some(rotary) = rotary {
                    curve_pieces(degree, w, knots, rotary, &mut out, |p, v, w, ua, ub| {
                        let o = CoreOrientation::axes_curve(p, v, w, ua, ub)?;
                        Ok(if tcp { o.under_tcp() } else { o })
                    })?;
                } else if let Some(vectors) = tool_axes {
                    curve_pieces(degree, w, knots, vectors, &mut out, |p, v, w, ua, ub| {
                        CoreOrientation::tool_axis_curve(p, v, w, ua, ub)
                    })?;
                }
            }
        }
        // A NURBS with rotary coordinates or tool vectors carries its
        // orientation per piece.
        let per_piece = matches!(
            m.path,
            MovePath::Nurbs {
                rotary: Some(_),
                ..
            } | MovePath::Nurbs {
                tool_axes: Some(_),
                ..
            }
        );
        if !per_piece
            && let (Some(o), Some(first), Some(last)) = (m.orientation, out.first(), out.last())
        {
            // One orientation over the whole move: a split NURBS keeps its
            // parameter, so every piece evaluates it at its own `u`.
            let core = match o {
                MoveOrientation::Axes { start, end } => {
                    CoreOrientation::axes(&first.path, start, end)
                }
                MoveOrientation::ToolAxis { start, end } => {
                    CoreOrientation::tool_axis(&first.path, v3(start), v3(end))
                }
            }
            .map_err(CutError::Orientation)?;
            let mut core = with_end_parameter(core, last.path.u_end());
            if in_place.is_some() {
                core = core.in_place(start);
            }
            for b in &mut out {
                b.orientation = Some(core);
            }
        }
        if let Some(last) = out.last() {
            self.follow(last);
        }
        Ok(out)
    }
}

/// Gives each block of a NURBS with rotary coordinates or tool vectors
/// (cut into its knot spans, the original parameter kept) its piece of that
/// second curve: the rational Bézier with the block's own weights `w_k`
/// whose homogeneous values `w_k·v_k` give `r(u)·Σ B_k(t)·w_k` (`r` the
/// program's second curve, `Σ Nᵢ·wᵢ·vᵢ / Σ Nᵢ·wᵢ`) at `degree + 1`
/// parameters of the span: the block's weight function is the program
/// curve's there (up to a constant factor), so that is a polynomial of the
/// degree, matched exactly up to round-off; its ends are the program
/// curve's values there, shared bit for bit by neighbouring spans, the
/// first and last the given ones. `make` turns a piece (degree, values,
/// weights, parameter range) into the block's orientation: rotary
/// coordinates (under G43.4 the rotary joints follow them,
/// [`CoreOrientation::under_tcp`]) or tool vectors
/// ([`CoreOrientation::tool_axis_curve`]).
fn curve_pieces(
    degree: usize,
    weights: &[f64],
    knots: &[f64],
    second: &[[f64; 3]],
    out: &mut [Block],
    make: impl Fn(usize, &[[f64; 3]], &[f64], f64, f64) -> Result<CoreOrientation, OrientationError>,
) -> Result<(), CutError> {
    let p = degree;
    let (first_u, last_u) = (knots[0], knots[knots.len() - 1]);
    // The program's second curve at `u`.
    let at = |u: f64| {
        if u == first_u {
            return second[0];
        }
        if u == last_u {
            return second[second.len() - 1];
        }
        let (span, n) = interp_core::nurbs::basis_functions(p, knots, u);
        let (mut num, mut den) = ([0.0; 3], 0.0);
        for (k, nk) in n.iter().enumerate().take(p + 1) {
            let i = span - p + k;
            let wn = nk * weights[i];
            for j in 0..3 {
                num[j] += wn * second[i][j];
            }
            den += wn;
        }
        [num[0] / den, num[1] / den, num[2] / den]
    };
    let mut prev_end: Option<(f64, [f64; 3])> = None;
    for b in out.iter_mut() {
        let Path::Nurbs(n) = &b.path else {
            continue;
        };
        if n.control_count() != p + 1 {
            // (Cut into single spans above: a Bézier piece each.)
            return Err(CutError::Orientation(OrientationError::BadValue));
        }
        let (ua, ub) = (n.u_start(), n.u_end());
        let w: Vec<f64> = (0..=p).map(|k| n.weight(k)).collect();
        let (ra, rb) = (at(ua), at(ub));
        if let Some((u, r)) = prev_end
            && r != ra
        {
            // A span the path left out (it stands still) turned the axes or tool.
            return Err(CutError::RotaryWhileStill(u));
        }
        // Bernstein collocation at t_j = j/p for the homogeneous values.
        let mut m = vec![[0.0; interp_core::fiveaxis::BEZIER + 3]; p + 1];
        for (j, row) in m.iter_mut().enumerate() {
            let t = j as f64 / p as f64;
            let r = at(ua + (ub - ua) * t);
            let mut den = 0.0;
            for k in 0..=p {
                row[k] = bernstein(p, k, t);
                den += row[k] * w[k];
            }
            for c in 0..3 {
                row[p + 1 + c] = r[c] * den;
            }
        }
        let h = solve(&mut m, p + 1);
        let mut values: Vec<[f64; 3]> = (0..=p)
            .map(|k| [h[k][0] / w[k], h[k][1] / w[k], h[k][2] / w[k]])
            .collect();
        values[0] = ra;
        values[p] = rb;
        b.orientation = Some(make(p, &values, &w, ua, ub).map_err(CutError::Orientation)?);
        prev_end = Some((ub, rb));
    }
    Ok(())
}

/// The Bernstein polynomial `B_{k,p}(t)`.
fn bernstein(p: usize, k: usize, t: f64) -> f64 {
    let mut binom = 1.0;
    for i in 0..k {
        binom = binom * (p - i) as f64 / (i + 1) as f64;
    }
    binom * t.powi(k as i32) * (1.0 - t).powi((p - k) as i32)
}

/// Solves the `n × n` system in the first `n` columns of `m` for the three
/// right-hand sides after them (Gaussian elimination, partial pivoting;
/// the Bernstein collocation matrix at distinct points is regular).
fn solve(m: &mut [[f64; interp_core::fiveaxis::BEZIER + 3]], n: usize) -> Vec<[f64; 3]> {
    for c in 0..n {
        let piv = (c..n)
            .max_by(|&a, &b| m[a][c].abs().total_cmp(&m[b][c].abs()))
            .unwrap_or(c);
        m.swap(c, piv);
        for r in c + 1..n {
            let f = m[r][c] / m[c][c];
            for k in c..n + 3 {
                m[r][k] -= f * m[c][k];
            }
        }
    }
    let mut x = vec![[0.0; 3]; n];
    for r in (0..n).rev() {
        for c in 0..3 {
            let mut v = m[r][n + c];
            for k in r + 1..n {
                v -= m[r][k] * x[k][c];
            }
            x[r][c] = v / m[r][r];
        }
    }
    x
}

/// `o` over a parameter range that ends at `u1`.
fn with_end_parameter(o: CoreOrientation, u1: f64) -> CoreOrientation {
    match o {
        CoreOrientation::Axes { u0, .. } | CoreOrientation::ToolAxis { u0, .. } => {
            o.with_range(u0, u1)
        }
        CoreOrientation::AxesCurve { curve, .. } | CoreOrientation::ToolAxisCurve { curve } => {
            o.with_range(curve.u0, u1)
        }
    }
}

fn check_start(start: Vec3, at: Vec3) -> Result<(), CutError> {
    let gap = (start - at).norm();
    if gap <= JOIN_TOLERANCE {
        Ok(())
    } else {
        Err(CutError::Discontinuous {
            start: a3(start),
            previous_end: a3(at),
            gap,
        })
    }
}

/// Largest arc-length step at which [`joints_after`] follows the joints, mm.
pub const JOINT_WALK_STEP: f64 = 0.25;
/// Fewest samples [`joints_after`] takes along a block.
pub const JOINT_WALK_MIN_SAMPLES: f64 = 16.0;

/// Moves the machine's joints `q` from the start of `block` to its end: its
/// orientation walked along it (`interp_core::fiveaxis::walk_joints`, the
/// inverse nearest the last sample, as the planner walks a block: so the
/// branch and the turns of each rotary joint are the machine's), or, for a
/// three-axis block, its end as X Y Z with the rotary axes kept. A block
/// the machine cannot follow (which the planner refuses too) is an error,
/// and the joints are left where the walk got to.
pub fn joints_after(
    block: &Block,
    machine: Option<&Machine>,
    q: &mut Joints,
) -> Result<(), JointError> {
    let end = block.path.end_point();
    match &block.orientation {
        None => {
            q[..3].copy_from_slice(&[end.x, end.y, end.z]);
            Ok(())
        }
        Some(o) => {
            let length = block.path.length();
            let hs = JOINT_WALK_STEP.min(length / JOINT_WALK_MIN_SAMPLES);
            walk_joints(machine, o, &block.path, 0.0, length, hs, q)
        }
    }
}
