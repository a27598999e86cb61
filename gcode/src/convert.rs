//! Program blocks → interp-core blocks.

use interp_core::Vec3;
use interp_core::nurbs::{MAX_CTRL, SplitError, split_program_curve};
use interp_core::path::{Arc, Blending, Block, Line, Path, PathError};

use interp_core::kinematics::{Joints, Machine, MachineSpec, ToolPose};

use crate::error::{ConvertError, FiveAxisReason};
use crate::moves::{
    CutError, Cutter, Move, MoveOrientation, MovePath, SECONDS_PER_MINUTE, joints_after,
};
use crate::program::{BlockKind, Feed, Orientation, PathControl, Program, Rotary};

/// The interp-core blending mode of a path control mode: G61.1 exact stop,
/// G61 exact path, G64 `P` (G64's `Q` merges nothing here: runs of short
/// moves are the interpolator's to compress within `P`).
pub fn core_blending(mode: PathControl) -> Blending {
    match mode {
        PathControl::ExactStop => Blending::ExactStop,
        PathControl::ExactPath => Blending::ExactPath,
        PathControl::Blend { path_tolerance, .. } => Blending::Within {
            tolerance: path_tolerance,
        },
    }
}

/// How program blocks become interp-core blocks.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(default, rename_all = "kebab-case"))]
pub struct CoreOptions {
    /// Feed given to rapid (G0) moves, mm/s: the machine's maximum path speed.
    /// Default 250, the default `InterpConfig::max_path_speed`.
    pub rapid_speed: f64,
    /// The five-axis machine, for tool-centre-point control (G43.4,
    /// G43.5): it turns rotary positions into tool axes and finds where
    /// each move under TCP starts. Default none (then TCP moves are refused;
    /// A B C as plain axes need no machine).
    #[cfg_attr(feature = "serde", serde(skip_serializing_if = "Option::is_none"))]
    pub machine: Option<MachineSpec>,
}

impl Default for CoreOptions {
    fn default() -> Self {
        CoreOptions {
            rapid_speed: interp_core::InterpConfig::default().max_path_speed,
            machine: None,
        }
    }
}

fn v3(p: [f64; 3]) -> Vec3 {
    Vec3::new(p[0], p[1], p[2])
}

impl CoreOptions {
    /// The options of a run under `cfg`: rapids at its `max_path_speed`
    /// (the one rapid policy), its machine.
    pub fn for_config(cfg: &interp_core::InterpConfig) -> Self {
        CoreOptions {
            rapid_speed: cfg.max_path_speed,
            machine: cfg.machine,
        }
    }
}

/// Feed in mm/min for a move of `length` mm (G93: the move's length × F),
/// refused unless it is positive and finite in mm/s too.
fn feed_mm_min(feed: Feed, length: f64, line: u32) -> Result<f64, ConvertError> {
    let f = match feed {
        Feed::PerMinute(v) => v,
        Feed::InverseTime(v) => length * v,
    };
    let per_second = f / SECONDS_PER_MINUTE;
    if !(per_second > 0.0) || !per_second.is_finite() {
        return Err(ConvertError::Feed {
            line,
            feed: per_second,
        });
    }
    Ok(f)
}

/// The `ConvertError` of a move the [`Cutter`] refused.
fn cut_error(line: u32, e: CutError) -> ConvertError {
    match e {
        CutError::Feed(f) => ConvertError::Feed {
            line,
            feed: f / SECONDS_PER_MINUTE,
        },
        CutError::Path(error) => ConvertError::Path { line, error },
        CutError::Nurbs(error) => ConvertError::Nurbs { line, error },
        CutError::Orientation(e) => ConvertError::FiveAxisMove {
            line,
            reason: FiveAxisReason::Orientation(e),
        },
        error @ (CutError::Discontinuous { .. }
        | CutError::FrameStart
        | CutError::RotaryWhileStill(_)
        | CutError::SecondCurveLength { .. }) => ConvertError::Move { line, error },
    }
}

impl Program {
    /// Converts the motion blocks into [`Move`]s, in order, calling `sink`
    /// with each: the one conversion of a program, whose moves
    /// [`Program::for_each_core_block`] cuts into interp-core blocks and the
    /// `traces` JSON block form carries field for field.
    ///
    /// - G0 runs at `opts.rapid_speed` (the machine's maximum path speed);
    ///   G1, G2/G3 and NURBS at F (G94, mm/min) or in the time G93 gives
    ///   (the move's length × F, for a NURBS the whole curve's);
    /// - a NURBS is passed on exactly as written;
    /// - moves of zero length are dropped (RS274/NGC allows them; they move
    ///   nothing), unless the rotary axes or the tool turn: a turn in place,
    ///   whose length is the turn in degrees and F in deg/min
    ///   ([`MoveOrientation::turn`], `interp_core::fiveaxis::Orientation::in_place`);
    /// - dwell, spindle, tool, path-control and tool-centre-point blocks
    ///   carry no path and are skipped; the path control mode in force (G61.1,
    ///   G61, G64 P; G61 until the program sets one) becomes each move's
    ///   `blending`;
    /// - A B C of a move without tool-centre-point control become
    ///   [`MoveOrientation::Axes`]; under G43.4 the rotary positions become
    ///   tool axes through `opts.machine`'s forward transform, under G43.5
    ///   the I J K are the tool axis ([`MoveOrientation::ToolAxis`]). The
    ///   first move after TCP goes on or off starts where the machine
    ///   stands, seen in its frame (the tool tip of its joints, or their
    ///   X Y Z; the joints are walked along each move as the planner walks
    ///   them, [`joints_after`]), and
    ///   says so in [`Move::start`], as the first move does. What cannot be
    ///   converted yet is refused naming the line
    ///   ([`ConvertError::FiveAxisMove`]).
    pub fn for_each_move<E>(
        &self,
        opts: &CoreOptions,
        mut sink: impl FnMut(&Move<'_>) -> Result<(), E>,
    ) -> Result<(), ConvertOrSinkError<E>> {
        let mut blending = Blending::ExactPath;
        let machine = match opts.machine {
            Some(spec) => Some(Machine::new(spec).map_err(|e| {
                // (Before any line: reported as line 0.)
                ConvertOrSinkError::Convert(ConvertError::FiveAxisMove {
                    line: 0,
                    reason: FiveAxisReason::Machine(e),
                })
            })?),
            None => None,
        };
        let mut pose = Pose {
            machine,
            joints: None,
            tcp: false,
        };
        // The frame of the last move handed out (`None`: none yet). A move
        // in another frame says where it starts.
        let mut emitted_tcp: Option<bool> = None;
        for b in &self.blocks {
            let line = b.line;
            if let BlockKind::PathControl(mode) = &b.kind {
                blending = core_blending(*mode);
                continue;
            }
            let convert = ConvertOrSinkError::Convert;
            let five_err = |reason: FiveAxisReason| {
                ConvertOrSinkError::Convert(ConvertError::FiveAxisMove { line, reason })
            };
            let path_err =
                |error: PathError| ConvertOrSinkError::Convert(ConvertError::Path { line, error });
            let Some(orientation) = b.kind.orientation() else {
                continue;
            };
            let tcp = matches!(
                orientation,
                Orientation::TcpRotary { .. } | Orientation::TcpVector { .. }
            );
            // Where the move starts: as programmed, or, where TCP goes on or
            // off, where the machine stands seen in the move's frame.
            let (programmed_start, programmed_end) = match &b.kind {
                BlockKind::Rapid(m) => (m.start, m.end),
                BlockKind::Linear(m) => (m.start, m.end),
                BlockKind::Arc(m) => (m.start, m.end),
                BlockKind::Nurbs(m) => (m.points[0], *m.points.last().unwrap_or(&m.points[0])),
                _ => continue,
            };
            let start = pose
                .start(programmed_start, orientation, tcp, &b.kind)
                .map_err(five_err)?;
            let rotary_values: Vec<[f64; 3]>;
            let (path, feed, first_line) = match &b.kind {
                BlockKind::Rapid(_) | BlockKind::Linear(_) => {
                    let length = match Line::new(v3(start), v3(programmed_end)) {
                        Ok(l) => l.length(),
                        // The tip (or X Y Z) stands: a turn in place if the
                        // rotary axes or the tool turn (its length the turn
                        // in degrees, F in deg/min), else nothing to do.
                        Err(PathError::ZeroLength) => {
                            let turn = match pose.orientation(orientation).map_err(five_err)? {
                                Some(o) if pose.turns(orientation) => o.turn(),
                                _ => 0.0,
                            };
                            if !(turn > 0.0) {
                                if pose.turns(orientation) {
                                    // (Under TCP at the pole: C turns, the tool does not.)
                                    return Err(five_err(FiveAxisReason::RotaryOnly));
                                }
                                pose.after(programmed_end, orientation, tcp)
                                    .map_err(five_err)?;
                                continue;
                            }
                            turn
                        }
                        Err(e) => return Err(path_err(e)),
                    };
                    let feed = match &b.kind {
                        BlockKind::Linear(m) => feed_mm_min(m.feed, length, line),
                        _ => feed_mm_min(
                            Feed::PerMinute(opts.rapid_speed * SECONDS_PER_MINUTE),
                            0.0,
                            line,
                        ),
                    }
                    .map_err(convert)?;
                    (
                        MovePath::Line {
                            end: programmed_end,
                        },
                        feed,
                        line,
                    )
                }
                BlockKind::Arc(m) => {
                    let path = MovePath::Arc {
                        end: m.end,
                        centre: m.centre,
                        axis: m.plane.normal(),
                        clockwise: m.clockwise,
                        turns: m.extra_turns,
                    };
                    let length = match m.feed {
                        Feed::InverseTime(_) => {
                            let n = m.plane.normal();
                            let s = if m.clockwise { -1.0 } else { 1.0 };
                            let axis = Vec3::new(s * n[0], s * n[1], s * n[2]);
                            Arc::from_centre(
                                v3(start),
                                v3(m.end),
                                v3(m.centre),
                                axis,
                                m.extra_turns,
                            )
                            .map_err(path_err)?
                            .length()
                        }
                        Feed::PerMinute(_) => 0.0,
                    };
                    (
                        path,
                        feed_mm_min(m.feed, length, line).map_err(convert)?,
                        line,
                    )
                }
                BlockKind::Nurbs(m) => {
                    let length = match m.feed {
                        // The whole curve's length (in pieces, as it runs).
                        Feed::InverseTime(_) => {
                            let mut length = 0.0;
                            let r: Result<(), SplitError<core::convert::Infallible>> =
                                split_program_curve(
                                    m.degree,
                                    &m.points,
                                    &m.weights,
                                    &m.knots,
                                    MAX_CTRL,
                                    |seg| {
                                        length += Path::Nurbs(seg).length();
                                        Ok(())
                                    },
                                );
                            match r {
                                Ok(()) => {}
                                Err(SplitError::Invalid(error)) => {
                                    return Err(convert(ConvertError::Nurbs { line, error }));
                                }
                                Err(SplitError::Sink(never)) => match never {},
                            }
                            length
                        }
                        Feed::PerMinute(_) => 0.0,
                    };
                    let feed = feed_mm_min(m.feed, length, line).map_err(convert)?;
                    // A B C of each control point, an axis left out where
                    // the machine has it: coordinates of the curve.
                    rotary_values = m
                        .rotary
                        .iter()
                        .map(|r| {
                            let q = pose.with_rotary(r);
                            [q[3], q[4], q[5]]
                        })
                        .collect();
                    let path = MovePath::Nurbs {
                        degree: m.degree,
                        points: &m.points,
                        weights: Some(&m.weights),
                        knots: &m.knots,
                        rotary: (!rotary_values.is_empty()).then_some(&rotary_values[..]),
                        tool_axes: (!m.tool_vectors.is_empty()).then_some(&m.tool_vectors[..]),
                    };
                    (path, feed, m.first_line)
                }
                _ => continue,
            };
            let mv = Move {
                line,
                first_line,
                feed,
                blending,
                start: (emitted_tcp != Some(tcp)).then_some(start),
                path,
                orientation: pose.orientation(orientation).map_err(five_err)?,
                mrr: None,
            };
            let before = pose.joints;
            // The end within reach (refused naming the line), ...
            pose.after(programmed_end, orientation, tcp)
                .map_err(five_err)?;
            // ... and the joints there as the machine gets to them: walked
            // along the move as the planner walks it (the inverse nearest
            // the last sample), so that the next move's rotary axes and
            // frame start where the machine's are.
            if mv.orientation.is_some()
                && let Ok(blocks) = Cutter::new(start, tcp, 1, MAX_CTRL).cut(&mv)
            {
                let mut q = before.unwrap_or_default();
                // (A move the machine cannot follow keeps the joints of its
                // end: the planner refuses it anyway.)
                if blocks
                    .iter()
                    .try_for_each(|b| joints_after(b, pose.machine.as_ref(), &mut q))
                    .is_ok()
                {
                    pose.joints = Some(q);
                }
            }
            emitted_tcp = Some(tcp);
            sink(&mv).map_err(ConvertOrSinkError::Sink)?;
        }
        Ok(())
    }

    /// Converts the motion blocks into interp-core blocks, in order, calling
    /// `sink` with each: [`Program::for_each_move`], cut by a [`Cutter`]
    /// from the first move's start (NURBS into pieces of at most
    /// [`MAX_CTRL`] control points that are the same curve; G2/G3 exact
    /// arcs, [`Arc::from_centre`]; feeds in mm/s). Each block's `id` is
    /// its source line.
    pub fn for_each_core_block<E>(
        &self,
        opts: &CoreOptions,
        mut sink: impl FnMut(Block) -> Result<(), E>,
    ) -> Result<(), ConvertOrSinkError<E>> {
        let mut cutter: Option<Cutter> = None;
        let r = self.for_each_move(opts, |m| {
            let c = cutter.get_or_insert_with(|| {
                Cutter::new(m.start.unwrap_or_default(), m.is_tcp(), 1, MAX_CTRL)
            });
            let blocks = c
                .cut(m)
                .map_err(|e| ConvertOrSinkError::Convert(cut_error(m.line, e)))?;
            for b in blocks {
                sink(Block { id: m.line, ..b }).map_err(ConvertOrSinkError::Sink)?;
            }
            Ok(())
        });
        match r {
            Ok(()) => Ok(()),
            Err(ConvertOrSinkError::Convert(e))
            | Err(ConvertOrSinkError::Sink(ConvertOrSinkError::Convert(e))) => {
                Err(ConvertOrSinkError::Convert(e))
            }
            Err(ConvertOrSinkError::Sink(ConvertOrSinkError::Sink(e))) => {
                Err(ConvertOrSinkError::Sink(e))
            }
        }
    }

    /// [`Program::for_each_core_block`] collected into a `Vec`.
    pub fn to_core_blocks(&self, opts: &CoreOptions) -> Result<Vec<Block>, ConvertError> {
        let mut out = Vec::new();
        self.for_each_core_block(opts, |b| {
            out.push(b);
            Ok::<(), core::convert::Infallible>(())
        })
        .map_err(|e| match e {
            ConvertOrSinkError::Convert(c) => c,
            ConvertOrSinkError::Sink(never) => match never {},
        })?;
        Ok(out)
    }
}

/// Why [`Program::for_each_core_block`] stopped.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ConvertOrSinkError<E> {
    /// A block could not be converted.
    #[error(transparent)]
    Convert(#[from] ConvertError),
    /// The sink refused a block.
    #[error("sink refused a block")]
    Sink(E),
}

/// The machine's pose as the conversion goes: its joints (from the first
/// move on) and whether the last move was under tool-centre-point control.
struct Pose {
    machine: Option<Machine>,
    joints: Option<Joints>,
    tcp: bool,
}

impl Pose {
    fn machine(&self) -> Result<&Machine, FiveAxisReason> {
        self.machine.as_ref().ok_or(FiveAxisReason::NoMachine)
    }

    /// The joints with `rotary` put in (unknown axes keep theirs).
    fn with_rotary(&self, rotary: &Rotary) -> Joints {
        let mut q = self.joints.unwrap_or([0.0; 6]);
        for (k, r) in rotary.iter().enumerate() {
            if let Some(v) = r {
                q[3 + k] = *v;
            }
        }
        q
    }

    /// Where a move programmed from `start` starts: there, unless TCP went
    /// on or off since the last move (then where the machine stands, which
    /// a straight move can start from and any other move is refused).
    fn start(
        &mut self,
        start: [f64; 3],
        o: &Orientation,
        tcp: bool,
        kind: &BlockKind,
    ) -> Result<[f64; 3], FiveAxisReason> {
        let Some(q) = self.joints else {
            // The first move: the machine stands at its start (TCP off).
            let rotary = match o {
                Orientation::Axes { start, .. } | Orientation::TcpRotary { start, .. } => *start,
                _ => [None; 3],
            };
            let mut q = self.with_rotary(&rotary);
            q[..3].copy_from_slice(&start);
            self.joints = Some(q);
            if !tcp {
                return Ok(start);
            }
            return self.start(start, o, tcp, kind);
        };
        if tcp == self.tcp {
            return Ok(start);
        }
        let at = if tcp {
            let p = self.machine()?.forward(&q).tip;
            [p.x, p.y, p.z]
        } else {
            [q[0], q[1], q[2]]
        };
        self.tcp = tcp;
        let same = (v3(at) - v3(start)).norm() <= interp_core::interp::JOIN_TOLERANCE;
        match kind {
            BlockKind::Rapid(_) | BlockKind::Linear(_) => Ok(at),
            _ if same => Ok(start),
            _ => Err(FiveAxisReason::FrameChange),
        }
    }

    /// Does the move turn a rotary axis or the tool?
    fn turns(&self, o: &Orientation) -> bool {
        match o {
            Orientation::Fixed => false,
            Orientation::Axes { start, end } | Orientation::TcpRotary { start, end } => {
                self.with_rotary(start) != self.with_rotary(end)
            }
            Orientation::TcpVector { start, end } => end.is_some() && start != end,
        }
    }

    /// The tool axis of a move's orientation at its start and end.
    fn tool_axes(&self, o: &Orientation) -> Result<(Vec3, Vec3), FiveAxisReason> {
        let m = self.machine()?;
        let current = m.forward(&self.joints.unwrap_or([0.0; 6])).axis;
        Ok(match o {
            Orientation::TcpRotary { start, end } => (
                m.forward(&self.with_rotary(start)).axis,
                m.forward(&self.with_rotary(end)).axis,
            ),
            Orientation::TcpVector { start, end } => {
                let a = start.map(v3).unwrap_or(current);
                (a, end.map(v3).unwrap_or(a))
            }
            _ => (current, current),
        })
    }

    /// The orientation a move hands on (`None`: a three-axis move, or
    /// rotary axes that do not move).
    fn orientation(&self, o: &Orientation) -> Result<Option<MoveOrientation>, FiveAxisReason> {
        Ok(match o {
            Orientation::Fixed => None,
            Orientation::Axes { start, end } => {
                let (a, b) = (self.with_rotary(start), self.with_rotary(end));
                (a != b).then_some(MoveOrientation::Axes {
                    start: [a[3], a[4], a[5]],
                    end: [b[3], b[4], b[5]],
                })
            }
            Orientation::TcpRotary { .. } | Orientation::TcpVector { .. } => {
                let (a, b) = self.tool_axes(o)?;
                Some(MoveOrientation::ToolAxis {
                    start: [a.x, a.y, a.z],
                    end: [b.x, b.y, b.z],
                })
            }
        })
    }

    /// After a move to `end` (programmed): the joints there.
    fn after(&mut self, end: [f64; 3], o: &Orientation, tcp: bool) -> Result<(), FiveAxisReason> {
        let end_rotary = match o {
            Orientation::Axes { end, .. } | Orientation::TcpRotary { end, .. } => *end,
            _ => [None; 3],
        };
        let mut q = self.with_rotary(&end_rotary);
        if tcp {
            let (_, axis) = self.tool_axes(o)?;
            let m = self.machine()?;
            q = m
                .inverse(
                    &ToolPose { tip: v3(end), axis },
                    &self.joints.unwrap_or([0.0; 6]),
                )
                .map_err(FiveAxisReason::Inverse)?
                .joints;
        } else {
            q[..3].copy_from_slice(&end);
        }
        self.joints = Some(q);
        self.tcp = tcp;
        Ok(())
    }
}
