//! The JSON block form of a program: lines, arcs and NURBS with their feed
//! (mm/min) and optional constant-MRR parameters.
//!
//! An [`InputBlock`] is a `gcode::Move` field for field: G-code becomes
//! this form through the one conversion ([`Program::from_gcode`]), `interpd
//! simulate` and `interpd send` read it, the `/interpd/blocks` channel
//! records each block in it, and the daemon's control plane takes it for
//! JSON blocks. See `docs/traces.md` for the format. [`Program::expand`]
//! and [`Pipeline`] cut it into interpolator blocks with `gcode::Cutter`
//! (long NURBS split with `interp_core::nurbs::split_program_curve`),
//! recording how.

use gcode::{CutError, Move, MovePath};
use interp_core::InterpConfig;
use interp_core::config::ConfigError;
use interp_core::path::{MrrParams, PathError, ToolSide};
use interp_core::smooth::{SmoothError, SmoothStats, Smoother};
use interp_core::{Blending, Block, Curve, NurbsError, Path};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::messages::SegmentInfo;

/// A program in the JSON block form.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Program {
    /// Start point X Y Z, mm. Default: the first point of the first block if it
    /// is a NURBS, else the origin.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub start: Option<[f64; 3]>,
    /// Where the rotary joints A B C stand at the start, degrees (default
    /// 0 0 0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rotary: Option<[f64; 3]>,
    /// The blocks, in order; each starts where the previous one ends.
    pub blocks: Vec<InputBlock>,
}

/// One block as given.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct InputBlock {
    /// Line of the source program this block came from, if known (1-based).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub source_line: Option<u32>,
    /// Programmed feed, mm/min.
    pub feed: f64,
    /// Constant-MRR law parameters (seed eq. 23); absent: the law is off for this block.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mrr: Option<MrrSpec>,
    /// How the path may pass the block's end (G61.1 `exact-stop`, G61
    /// `exact-path`, G64 P `{"within": {"tolerance": P}}`); absent: exact path.
    #[serde(default, skip_serializing_if = "BlendingSpec::is_exact_path")]
    pub blending: BlendingSpec,
    /// Where the block starts, mm, when it is not the previous block's end:
    /// required on the first block after tool-centre-point control goes on
    /// or off (the machine's pose seen in the new frame: the tool tip of its
    /// joints, or their X Y Z); elsewhere it must be the previous end
    /// (within 1e-6 mm).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub start: Option<[f64; 3]>,
    /// The rotary axes or the tool axis along the block (absent: a
    /// three-axis block, the rotary axes stay where they are).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub orientation: Option<OrientationSpec>,
    /// The geometry.
    #[serde(flatten)]
    pub path: PathSpec,
}

/// What a block does beside its path (`docs/five-axis.md`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
pub enum OrientationSpec {
    /// Tool-centre-point control off: the path is X Y Z of the machine and
    /// the rotary joints A B C (degrees) move from `start` to `end` with it.
    Axes {
        /// A B C where the block starts, degrees.
        start: [f64; 3],
        /// A B C where it ends, degrees.
        end: [f64; 3],
    },
    /// Tool-centre-point control on (G43.4, G43.5): the path is the tool
    /// tip in the workpiece frame and the tool axis (from the tip into the
    /// spindle, any length) turns from `start` to `end` on the great circle.
    ToolAxis {
        /// Tool axis where the block starts.
        start: [f64; 3],
        /// Tool axis where it ends.
        end: [f64; 3],
    },
}

impl From<gcode::MoveOrientation> for OrientationSpec {
    fn from(o: gcode::MoveOrientation) -> Self {
        match o {
            gcode::MoveOrientation::Axes { start, end } => OrientationSpec::Axes { start, end },
            gcode::MoveOrientation::ToolAxis { start, end } => {
                OrientationSpec::ToolAxis { start, end }
            }
        }
    }
}

impl From<OrientationSpec> for gcode::MoveOrientation {
    fn from(o: OrientationSpec) -> Self {
        match o {
            OrientationSpec::Axes { start, end } => gcode::MoveOrientation::Axes { start, end },
            OrientationSpec::ToolAxis { start, end } => {
                gcode::MoveOrientation::ToolAxis { start, end }
            }
        }
    }
}

/// How the path may pass a block's end (`interp_core::Blending`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "kebab-case")]
pub enum BlendingSpec {
    /// G61.1: come to rest at the block's end.
    ExactStop,
    /// G61: the programmed path exactly (the default).
    #[default]
    ExactPath,
    /// G64 P: within `tolerance` mm of the programmed path (absent: the
    /// configured default).
    Within {
        /// G64 `P`, mm.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        tolerance: Option<f64>,
    },
}

impl BlendingSpec {
    fn is_exact_path(&self) -> bool {
        *self == BlendingSpec::ExactPath
    }
}

impl From<BlendingSpec> for Blending {
    fn from(b: BlendingSpec) -> Self {
        match b {
            BlendingSpec::ExactStop => Blending::ExactStop,
            BlendingSpec::ExactPath => Blending::ExactPath,
            BlendingSpec::Within { tolerance } => Blending::Within { tolerance },
        }
    }
}

impl From<Blending> for BlendingSpec {
    fn from(b: Blending) -> Self {
        match b {
            Blending::ExactStop => BlendingSpec::ExactStop,
            Blending::ExactPath => BlendingSpec::ExactPath,
            Blending::Within { tolerance } => BlendingSpec::Within { tolerance },
        }
    }
}

/// Geometry of a block; it starts where the previous block ends.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum PathSpec {
    /// Straight line to `end`.
    Line {
        /// End point X Y Z, mm.
        end: [f64; 3],
    },
    /// Circular (or helical) arc to `end` about `centre`.
    Arc {
        /// End point X Y Z, mm.
        end: [f64; 3],
        /// Centre X Y Z, mm (its component along `axis` is ignored).
        centre: [f64; 3],
        /// Axis of the arc's plane (default +Z, the G17 plane).
        #[serde(default = "default_axis")]
        axis: [f64; 3],
        /// Clockwise about `axis` (G2) instead of counter-clockwise (G3).
        #[serde(default)]
        clockwise: bool,
        /// Extra full turns.
        #[serde(default)]
        turns: u32,
    },
    /// Rational NURBS of degree 1..=5 with a clamped knot vector. Its first
    /// control point must be the previous block's end.
    Nurbs {
        /// Degree.
        degree: usize,
        /// Control points X Y Z, mm.
        points: Vec<[f64; 3]>,
        /// One positive weight per control point (default all 1).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        weights: Option<Vec<f64>>,
        /// `points.len() + degree + 1` knots, clamped at both ends.
        knots: Vec<f64>,
        /// A B C (degrees) of each control point: the rotary axes as
        /// coordinates of the curve (G6.2 with A B C, tool-centre-point
        /// control off), with its weights and knots.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        rotary: Option<Vec<[f64; 3]>>,
        /// The tool vector of each control point (G6.2 with U V W under
        /// G43.5): a second curve for the tool axis, these vectors' NURBS
        /// with the curve's weights and knots, normalised; the block's
        /// `orientation` is then the tool axis from the first to the last.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        tool_axes: Option<Vec<[f64; 3]>>,
    },
}

fn default_axis() -> [f64; 3] {
    [0.0, 0.0, 1.0]
}

/// Constant-MRR parameters of a block.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct MrrSpec {
    /// Tool radius `rt`, mm.
    pub tool_radius: f64,
    /// Depth of cut `δ`, mm.
    pub depth_of_cut: f64,
    /// Where the tool is relative to the material.
    pub tool_side: ToolSideSpec,
}

/// Which side the tool is on (sign of the curvature in the MRR law).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "kebab-case")]
pub enum ToolSideSpec {
    /// A fixed direction from the material towards the tool (e.g. `[0, 0, 1]`).
    Direction([f64; 3]),
    /// Tool left of the path in the plane with this normal (G41).
    LeftOfPath([f64; 3]),
    /// Tool right of the path in the plane with this normal (G42).
    RightOfPath([f64; 3]),
}

impl From<MrrSpec> for MrrParams {
    fn from(m: MrrSpec) -> Self {
        MrrParams {
            tool_radius: m.tool_radius,
            depth_of_cut: m.depth_of_cut,
            tool_side: match m.tool_side {
                ToolSideSpec::Direction(v) => ToolSide::Direction(v),
                ToolSideSpec::LeftOfPath(v) => ToolSide::LeftOfPath(v),
                ToolSideSpec::RightOfPath(v) => ToolSide::RightOfPath(v),
            },
        }
    }
}

impl From<MrrParams> for MrrSpec {
    fn from(m: MrrParams) -> Self {
        MrrSpec {
            tool_radius: m.tool_radius,
            depth_of_cut: m.depth_of_cut,
            tool_side: match m.tool_side {
                ToolSide::Direction(v) => ToolSideSpec::Direction(v),
                ToolSide::LeftOfPath(v) => ToolSideSpec::LeftOfPath(v),
                ToolSide::RightOfPath(v) => ToolSideSpec::RightOfPath(v),
            },
        }
    }
}

/// What is wrong with one block.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum BlockErrorKind {
    /// `feed` is not a positive finite number.
    #[error("feed must be a positive number of mm/min, got {0}")]
    Feed(f64),
    /// A field of the MRR parameters is not usable.
    #[error("mrr.{0} must be a finite number (tool_radius > 0, depth_of_cut >= 0)")]
    Mrr(&'static str),
    /// The line or arc is invalid.
    #[error("{0}")]
    Path(PathError),
    /// The NURBS is invalid.
    #[error("invalid NURBS: {0}")]
    Nurbs(NurbsError),
    /// The block does not start where the previous one ends.
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
    /// Another refusal of the cutter (`gcode::CutError`).
    #[error("{0}")]
    Cut(CutError),
}

impl From<CutError> for BlockErrorKind {
    fn from(e: CutError) -> Self {
        match e {
            CutError::Feed(f) => BlockErrorKind::Feed(f),
            CutError::Path(p) => BlockErrorKind::Path(p),
            CutError::Nurbs(n) => BlockErrorKind::Nurbs(n),
            CutError::Discontinuous {
                start,
                previous_end,
                gap,
            } => BlockErrorKind::Discontinuous {
                start,
                previous_end,
                gap,
            },
            e => BlockErrorKind::Cut(e),
        }
    }
}

/// A block of a program that cannot be used.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("block {index}{}: {kind}", source_line.map(|l| format!(" (source line {l})")).unwrap_or_default())]
pub struct BlockError {
    /// Position in the program, from 0.
    pub index: usize,
    /// Its source line, if known.
    pub source_line: Option<u32>,
    /// What is wrong.
    pub kind: BlockErrorKind,
}

/// One input block and the interpolator blocks it became.
#[derive(Clone, Debug)]
pub struct ExpandedBlock {
    /// Position in the program, from 0.
    pub index: usize,
    /// The block as given.
    pub input: InputBlock,
    /// Interpolator blocks, in order (consecutive ids).
    pub segments: Vec<Block>,
    /// How it was split.
    pub info: Vec<SegmentInfo>,
}

/// A program ready for the interpolator.
#[derive(Clone, Debug)]
pub struct Expanded {
    /// Start point, mm.
    pub start: [f64; 3],
    /// The blocks.
    pub blocks: Vec<ExpandedBlock>,
}

impl Expanded {
    /// Every interpolator block, in order.
    pub fn segments(&self) -> impl Iterator<Item = &Block> {
        self.blocks.iter().flat_map(|b| b.segments.iter())
    }
}

impl Program {
    /// The machine's joints X Y Z A B C at the start.
    pub fn start_joints(&self) -> [f64; 6] {
        let [x, y, z] = self.start_point();
        let [a, b, c] = self.rotary.unwrap_or_default();
        [x, y, z, a, b, c]
    }

    /// The start point ([`Program::start`] or its default).
    pub fn start_point(&self) -> [f64; 3] {
        if let Some(s) = self.start {
            return s;
        }
        match self.blocks.first().map(|b| &b.path) {
            Some(PathSpec::Nurbs { points, .. }) if !points.is_empty() => points[0],
            _ => [0.0; 3],
        }
    }

    /// Checks every block and cuts it into interpolator blocks with ids from
    /// `first_id`; NURBS longer than `max_ctrl` control points are split.
    /// These are the program's own segments (what a trace records per
    /// block); a run sends them through the `G64 P` stage as [`Pipeline`]
    /// does.
    pub fn expand(&self, max_ctrl: usize, first_id: u32) -> Result<Expanded, BlockError> {
        let start = self.start_point();
        let mut cutter = Cutter::new(start, false, first_id, max_ctrl);
        let mut out = Vec::with_capacity(self.blocks.len());
        for input in &self.blocks {
            out.push(cutter.push(input)?);
        }
        Ok(Expanded { start, blocks: out })
    }
}

/// Cuts a program's blocks, in order, into interpolator segments
/// (`gcode::Cutter`: long NURBS split into pieces of at most `max_ctrl`
/// control points, the same curve), each from the end of the one before.
#[derive(Clone, Debug)]
struct Cutter {
    cut: gcode::Cutter,
    index: usize,
}

impl Cutter {
    fn new(start: [f64; 3], tcp: bool, first_id: u32, max_ctrl: usize) -> Self {
        Cutter {
            cut: gcode::Cutter::new(start, tcp, first_id, max_ctrl),
            index: 0,
        }
    }

    fn push(&mut self, input: &InputBlock) -> Result<ExpandedBlock, BlockError> {
        let index = self.index;
        let err = |kind| BlockError {
            index,
            source_line: input.source_line,
            kind,
        };
        let m = input.as_move().map_err(err)?;
        let segments = self.cut.cut(&m).map_err(|e| err(e.into()))?;
        let info = segments
            .iter()
            .map(|b| SegmentInfo {
                block_id: b.id,
                u_start: b.path.u_start(),
                u_end: b.path.u_end(),
                control_points: match &b.path {
                    Path::Nurbs(n) => n.control_count(),
                    _ => 0,
                },
                length: b.path.length(),
            })
            .collect();
        self.index += 1;
        Ok(ExpandedBlock {
            index,
            input: input.clone(),
            segments,
            info,
        })
    }
}

/// The non-real-time path of one program's blocks, in order: each input
/// block is checked and cut into segments ([`Program::expand`] does the
/// same), and the segments go through the `G64 P` stage
/// (`interp_core::smooth::Smoother`: round-off drop; under `G64`, collinear
/// merge, compression of runs of short moves into NURBS, corner blends) whose
/// output is what `BlockPlanner::plan` gets. The daemon's control plane
/// sends each program's blocks through one of these; `interpd simulate`
/// and replay run the same stage over the same segments (`traces::sim`),
/// so both give the same interpolator blocks.
///
/// The stage holds blocks back until it can decide them:
/// [`Pipeline::push`] releases what is decided, [`Pipeline::finish`] the
/// rest at the program's end. The released blocks are numbered from
/// `first_id` on their own (they are not the program's segments).
pub struct Pipeline {
    cutter: Cutter,
    stage: Box<Smoother>,
    next_out: u32,
}

impl core::fmt::Debug for Pipeline {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Pipeline")
            .field("cutter", &self.cutter)
            .field("stage", &self.stage)
            .field("next_out", &self.next_out)
            .finish()
    }
}

impl Pipeline {
    /// A program that starts at `start` (mm; the tool tip when `tcp`, the
    /// queue's end under tool-centre-point control), run under `cfg`, with
    /// segment ids (and released block ids) from `first_id`.
    pub fn new(
        start: [f64; 3],
        tcp: bool,
        first_id: u32,
        max_ctrl: usize,
        cfg: &InterpConfig,
    ) -> Result<Self, ConfigError> {
        Ok(Pipeline {
            cutter: Cutter::new(start, tcp, first_id, max_ctrl),
            stage: Box::new(Smoother::new(cfg, first_id)?),
            next_out: first_id,
        })
    }

    /// Where the next input block starts (the end of the last one), mm.
    pub fn tail(&self) -> [f64; 3] {
        self.cutter.cut.tail()
    }

    /// Whether [`Pipeline::tail`] is the tool tip (tool-centre-point control).
    pub fn tail_is_tcp(&self) -> bool {
        self.cutter.cut.is_tcp()
    }

    /// The id the next released block gets.
    pub fn next_id(&self) -> u32 {
        self.next_out
    }

    /// Input blocks pushed.
    pub fn blocks(&self) -> usize {
        self.cutter.index
    }

    /// What the `G64 P` stage did so far.
    pub fn stats(&self) -> SmoothStats {
        self.stage.stats()
    }

    /// The next input block of the program: its segments and how it was
    /// split; the blocks the stage now releases are appended to `released`.
    /// A refused block changes nothing.
    pub fn push(
        &mut self,
        input: &InputBlock,
        released: &mut Vec<Block>,
    ) -> Result<ExpandedBlock, BlockError> {
        let b = self.cutter.push(input)?;
        self.smooth(&b.segments, released);
        Ok(b)
    }

    /// [`Pipeline::push`] of a block already cut: the next block of
    /// [`Program::expand`] run from this pipeline's start and first id.
    pub fn push_expanded(&mut self, b: &ExpandedBlock, released: &mut Vec<Block>) {
        debug_assert_eq!(b.index, self.cutter.index, "blocks in order");
        if let Some(last) = b.segments.last() {
            self.cutter.cut.follow(last);
        }
        self.cutter.index += 1;
        self.smooth(&b.segments, released);
    }

    fn smooth(&mut self, segments: &[Block], released: &mut Vec<Block>) {
        for seg in segments {
            while self.stage.push(seg) == Err(SmoothError::Full) {
                self.release(released);
            }
            self.release(released);
        }
    }

    /// The program ends: the blocks the stage still holds back.
    pub fn finish(&mut self) -> Vec<Block> {
        self.stage.finish();
        let mut out = Vec::new();
        self.release(&mut out);
        out
    }

    fn release(&mut self, out: &mut Vec<Block>) {
        while let Some(b) = self.stage.pop() {
            // Long moves need no cutting: the look-ahead plans them in parts.
            out.push(Block {
                id: self.next_out,
                ..b
            });
            self.next_out = self.next_out.wrapping_add(1);
        }
    }
}

impl InputBlock {
    /// The block of a move (`gcode::Move`, field for field).
    pub fn from_move(m: &Move<'_>) -> Self {
        InputBlock {
            source_line: Some(m.first_line),
            feed: m.feed,
            mrr: m.mrr.map(MrrSpec::from),
            blending: m.blending.into(),
            start: m.start,
            orientation: m.orientation.map(OrientationSpec::from),
            path: match m.path {
                MovePath::Line { end } => PathSpec::Line { end },
                MovePath::Arc {
                    end,
                    centre,
                    axis,
                    clockwise,
                    turns,
                } => PathSpec::Arc {
                    end,
                    centre,
                    axis,
                    clockwise,
                    turns,
                },
                MovePath::Nurbs {
                    degree,
                    points,
                    weights,
                    knots,
                    rotary,
                    tool_axes,
                } => PathSpec::Nurbs {
                    degree,
                    points: points.to_vec(),
                    weights: weights.map(<[f64]>::to_vec),
                    knots: knots.to_vec(),
                    rotary: rotary.map(<[[f64; 3]]>::to_vec),
                    tool_axes: tool_axes.map(<[[f64; 3]]>::to_vec),
                },
            },
        }
    }

    /// The move this block is, for `gcode::Cutter` (its MRR parameters checked).
    pub fn as_move(&self) -> Result<Move<'_>, BlockErrorKind> {
        let mrr = match self.mrr {
            None => None,
            Some(m) => {
                if !(m.tool_radius.is_finite() && m.tool_radius > 0.0) {
                    return Err(BlockErrorKind::Mrr("tool_radius"));
                }
                if !(m.depth_of_cut.is_finite() && m.depth_of_cut >= 0.0) {
                    return Err(BlockErrorKind::Mrr("depth_of_cut"));
                }
                let dir = match m.tool_side {
                    ToolSideSpec::Direction(v)
                    | ToolSideSpec::LeftOfPath(v)
                    | ToolSideSpec::RightOfPath(v) => v,
                };
                let norm = interp_core::Vec3::from(dir).norm();
                if !(dir.iter().all(|c| c.is_finite()) && norm > 0.0) {
                    return Err(BlockErrorKind::Mrr("tool_side"));
                }
                Some(MrrParams::from(m))
            }
        };
        let line = self.source_line.unwrap_or(0);
        Ok(Move {
            line,
            first_line: line,
            feed: self.feed,
            blending: self.blending.into(),
            start: self.start,
            path: match &self.path {
                PathSpec::Line { end } => MovePath::Line { end: *end },
                PathSpec::Arc {
                    end,
                    centre,
                    axis,
                    clockwise,
                    turns,
                } => MovePath::Arc {
                    end: *end,
                    centre: *centre,
                    axis: *axis,
                    clockwise: *clockwise,
                    turns: *turns,
                },
                PathSpec::Nurbs {
                    degree,
                    points,
                    weights,
                    knots,
                    rotary,
                    tool_axes,
                } => MovePath::Nurbs {
                    degree: *degree,
                    points,
                    weights: weights.as_deref(),
                    knots,
                    rotary: rotary.as_deref(),
                    tool_axes: tool_axes.as_deref(),
                },
            },
            orientation: self.orientation.map(gcode::MoveOrientation::from),
            mrr,
        })
    }
}

impl Program {
    /// A G-code program in the JSON block form: its moves
    /// (`gcode::Program::for_each_move`, the one conversion), from the
    /// machine's joints `start` (those it was parsed from). The first move
    /// keeps its start (a first move under tool-centre-point control starts
    /// at the tool tip, not at the program's X Y Z).
    pub fn from_gcode(
        g: &gcode::Program,
        opts: &gcode::CoreOptions,
        start: [f64; 6],
    ) -> Result<Self, gcode::ConvertError> {
        let mut blocks = Vec::new();
        g.for_each_move(opts, |m| {
            blocks.push(InputBlock::from_move(m));
            Ok::<(), core::convert::Infallible>(())
        })
        .map_err(|e| match e {
            gcode::ConvertOrSinkError::Convert(c) => c,
            gcode::ConvertOrSinkError::Sink(never) => match never {},
        })?;
        let [x, y, z, a, b, c] = start;
        Ok(Program {
            start: Some([x, y, z]),
            rotary: start[3..]
                .iter()
                .any(|v| v.to_bits() != 0)
                .then_some([a, b, c]),
            blocks,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The joints `gcode::joints_after` follows to the end of a program (where the
    /// next program's `begin` says it starts) are where the machine stands
    /// when it has run: a tool axis turning on a C,A table, ending under
    /// tool-centre-point control, or after it with a plain rotary move.
    #[test]
    fn joints_after_a_program_are_where_the_machine_stands_at_its_end() {
        let machine: interp_core::kinematics::MachineSpec = serde_json::from_str(
            r#"{"chain": "W/caxyBz/T", "tool-length": 100, "rotary-centres": [[0, 0, -50], [0, 0, 0], [0, 0, 0]]}"#,
        )
        .expect("machine");
        let cfg = InterpConfig {
            machine: Some(machine),
            ..InterpConfig::default()
        };
        let m = interp_core::kinematics::Machine::new(machine).expect("machine");
        let tcp = "G21 G90 G61\nG0 Z10 C-90\nG43.5 H1\nG1 X20 Y0 Z-90 I-0.5 J0 K0.866025 F3000\n\
                   G1 X20 Y20 Z-90 I0.3 J0.4 K0.866025\n";
        for (text, abc) in [
            (tcp.to_owned(), None),
            (
                format!("{tcp}G49\nG1 X0 Y0 Z0 A10 C20\n"),
                Some([10.0, 0.0, 20.0]),
            ),
        ] {
            let g = gcode::parse(&text).expect("parses");
            let program = Program::from_gcode(&g, &gcode::CoreOptions::for_config(&cfg), [0.0; 6])
                .expect("converts");
            let mut run: interp_run::Run = interp_run::Run::new(cfg, [0.0; 6]).expect("run");
            let mut q = [0.0; 6];
            let mut last = interp_core::Setpoint::default();
            for b in program.expand(32, 1).expect("expands").segments() {
                run.push_waiting(b, |sp, _| {
                    last = *sp;
                    Ok::<(), ()>(())
                })
                .expect("pushed");
                gcode::joints_after(b, Some(&m), &mut q).expect("within reach");
            }
            run.run_to_end(|sp, _| {
                last = *sp;
                Ok::<(), ()>(())
            })
            .expect("runs");
            assert_eq!(last.state, interp_core::RunState::Done);
            for j in 0..6 {
                assert!((q[j] - last.axes[j]).abs() < 1e-9, "{q:?} {:?}", last.axes);
            }
            if let Some(abc) = abc {
                assert_eq!([q[3], q[4], q[5]], abc);
            } else {
                // Under TCP the tool axis leans 30° (A, to the program's 6 digits) and C
                // turned past −180.
                assert!((q[3] - 30.0).abs() < 1e-4 && q[5] < -180.0, "{q:?}");
            }
        }
    }
}
