//! The typed program: what [`crate::parse`] produces and [`crate::emit`] writes.
//!
//! Every length is in millimetres and every coordinate absolute (G20, G91 and
//! G91.1 are resolved by the parser), so a block means the same thing wherever
//! it stands. Each block keeps the 1-based source line it came from.

/// A point `[x, y, z]`, mm.
pub type Point = [f64; 3];

/// Positions of the rotary axes `[A, B, C]`, degrees; `None` for an axis
/// whose position the program does not know (after G43.5 steered the rotary
/// axes, until a word sets it again).
pub type Rotary = [Option<f64>; 3];

/// Tool-centre-point control, modal group 8 (G43.4, G43.5, G49).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum ToolControl {
    /// G49 (and the start): X Y Z are the machine's linear axes and A B C
    /// plain rotary axes.
    #[default]
    Off,
    /// G43.4: X Y Z are the tool tip in the workpiece frame, A B C the
    /// rotary positions.
    RotaryAngles {
        /// The tool length offset number `H`, if given.
        offset: Option<u32>,
    },
    /// G43.5: X Y Z are the tool tip in the workpiece frame, I J K the tool
    /// axis (from the tip into the spindle).
    ToolVector {
        /// The tool length offset number `H`, if given.
        offset: Option<u32>,
    },
}

/// What a move does with the rotary axes and the tool axis, beside X Y Z.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum Orientation {
    /// A three-axis move: tool-centre-point control is off and no rotary
    /// axis moves (they stay where they are).
    #[default]
    Fixed,
    /// TCP off (G49): A B C move as plain axes from `start` to `end`
    /// together with X Y Z (the joints move in proportion).
    Axes {
        /// Rotary positions where the move starts.
        start: Rotary,
        /// Rotary positions where it ends.
        end: Rotary,
    },
    /// G43.4: X Y Z are the tool tip in the workpiece frame; the rotary
    /// positions go from `start` to `end`.
    TcpRotary {
        /// Rotary positions where the move starts.
        start: Rotary,
        /// Rotary positions where it ends.
        end: Rotary,
    },
    /// G43.5: X Y Z are the tool tip; the tool axis goes from `start` to
    /// `end` (directions as programmed, not normalised; `None`: the
    /// machine's tool axis, when no I J K has been given since G43.5).
    TcpVector {
        /// Tool axis where the move starts.
        start: Option<[f64; 3]>,
        /// Tool axis where it ends.
        end: Option<[f64; 3]>,
    },
}

impl Orientation {
    /// A three-axis move (neither rotary motion nor tool-centre-point control).
    pub fn is_fixed(&self) -> bool {
        matches!(self, Orientation::Fixed)
    }
}

/// A parsed program: its blocks in order.
#[derive(Debug, Clone, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Program {
    /// Blocks in program order.
    pub blocks: Vec<ProgramBlock>,
}

/// One block and the source line it came from.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct ProgramBlock {
    /// 1-based line of the source text (for a NURBS, the line that ended it;
    /// the first line is in [`NurbsMove::first_line`]).
    pub line: u32,
    /// What the block does.
    pub kind: BlockKind,
}

/// The working plane (G17, G18, G19): arcs turn about its normal, G5.2/G6.2
/// control points lie in it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum Plane {
    /// G17: X, Y; normal +Z.
    #[default]
    Xy,
    /// G18: Z, X; normal +Y.
    Zx,
    /// G19: Y, Z; normal +X.
    Yz,
}

impl Plane {
    /// Indices of the plane's first and second axis and of its normal axis
    /// (X = 0, Y = 1, Z = 2), in RS274/NGC order (G18 is Z then X).
    pub fn axes(self) -> (usize, usize, usize) {
        match self {
            Plane::Xy => (0, 1, 2),
            Plane::Zx => (2, 0, 1),
            Plane::Yz => (1, 2, 0),
        }
    }

    /// The unit normal: counter-clockwise arcs (G3) turn about it.
    pub fn normal(self) -> Point {
        let mut n = [0.0; 3];
        n[self.axes().2] = 1.0;
        n
    }

    /// The G code that selects the plane (17, 18 or 19).
    pub fn g_code(self) -> u32 {
        match self {
            Plane::Xy => 17,
            Plane::Zx => 18,
            Plane::Yz => 19,
        }
    }
}

/// Programmed feed of a move.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum Feed {
    /// G94: path speed, mm/min.
    PerMinute(f64),
    /// G93: the move takes `1 / value` minutes.
    InverseTime(f64),
}

/// A feed move to `end` (G1).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct LinearMove {
    /// Where the move starts (the previous position), mm.
    pub start: Point,
    /// Where it ends, mm.
    pub end: Point,
    /// Programmed feed.
    pub feed: Feed,
    /// Rotary axes and tool axis.
    pub orientation: Orientation,
}

/// A rapid move to `end` (G0). It carries no feed: the machine's rapid speed applies.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct RapidMove {
    /// Where the move starts, mm.
    pub start: Point,
    /// Where it ends, mm.
    pub end: Point,
    /// Rotary axes and tool axis.
    pub orientation: Orientation,
}

/// A circular or helical arc (G2/G3), centre form (radius-form arcs are
/// resolved to their centre by the parser, as LinuxCNC does).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct ArcMove {
    /// Start point, mm.
    pub start: Point,
    /// End point, mm; its coordinate along the plane normal is the helix end.
    pub end: Point,
    /// Centre, mm (its normal coordinate equals the start's).
    pub centre: Point,
    /// Plane the arc turns in.
    pub plane: Plane,
    /// G2 (true) or G3 (false).
    pub clockwise: bool,
    /// Extra full turns before the end (`P` − 1; 0 for a plain arc).
    pub extra_turns: u32,
    /// Programmed feed.
    pub feed: Feed,
    /// Rotary axes and tool axis (arcs carry no A B C words: constant).
    pub orientation: Orientation,
}

/// A rational B-spline move (G5.2/G5.3 or G6.2), exactly as programmed.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct NurbsMove {
    /// 1-based line of the first block of the curve.
    pub first_line: u32,
    /// Plane of the program block (LinuxCNC NURBS are planar; a control point
    /// line may also give the normal coordinate, an interpd extension).
    pub plane: Plane,
    /// Degree (order − 1).
    pub degree: usize,
    /// Control points, mm; the first is where the curve starts.
    pub points: Vec<Point>,
    /// One positive weight per control point.
    pub weights: Vec<f64>,
    /// `points.len() + degree + 1` knots.
    pub knots: Vec<f64>,
    /// Programmed feed.
    pub feed: Feed,
    /// Rotary axes and tool axis; for [`Orientation::Axes`] and
    /// [`Orientation::TcpRotary`] its start and end are the first and last
    /// entry of `rotary`.
    pub orientation: Orientation,
    /// Rotary coordinates of each control point (G6.2 `A B C`, a NURBS in
    /// the rotary axes with the same weights and knots); empty unless
    /// `orientation` is [`Orientation::Axes`] or [`Orientation::TcpRotary`].
    pub rotary: Vec<Rotary>,
    /// The tool vector of each control point (G6.2 `U V W` under G43.5: a
    /// second curve for the tool axis, the NURBS of these vectors with the
    /// same weights and knots, normalised); empty unless `orientation` is
    /// [`Orientation::TcpVector`], whose start and end are then the first
    /// and last entry.
    #[cfg_attr(feature = "serde", serde(default))]
    pub tool_vectors: Vec<[f64; 3]>,
}

/// Spindle rotation (M3, M4, M5).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum SpindleRotation {
    /// M3.
    Clockwise,
    /// M4.
    CounterClockwise,
    /// M5.
    Stopped,
}

/// Path control mode (G61, G61.1, G64).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum PathControl {
    /// G61: exact path.
    ExactPath,
    /// G61.1: exact stop at every block end.
    ExactStop,
    /// G64 with the path tolerance `P` (mm; `None`: best speed) and the
    /// naive-CAM tolerance `Q` (mm). The interpolator takes `P` as its chord tolerance.
    Blend {
        /// G64 `P`, mm.
        path_tolerance: Option<f64>,
        /// G64 `Q`, mm.
        naive_cam_tolerance: Option<f64>,
    },
}

/// What a block does.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum BlockKind {
    /// G0.
    Rapid(RapidMove),
    /// G1.
    Linear(LinearMove),
    /// G2/G3.
    Arc(ArcMove),
    /// G5.2/G5.3, G6.2 (and G5/G5.1 Béziers, which are NURBS with Bézier knots).
    Nurbs(NurbsMove),
    /// G4 dwell, s.
    Dwell {
        /// Seconds.
        seconds: f64,
    },
    /// S with M3/M4/M5, or a change of either: the spindle state from here on.
    Spindle {
        /// Programmed speed `S` (rev/min, or m/min surface speed with G96).
        speed: f64,
        /// Direction or stopped.
        rotation: SpindleRotation,
        /// G96 constant surface speed is on.
        constant_surface_speed: bool,
    },
    /// M6 with the tool selected by T.
    ToolChange {
        /// Tool number.
        tool: u32,
    },
    /// G61/G61.1/G64.
    PathControl(PathControl),
    /// G43.4, G43.5 or G49: tool-centre-point control from here on (only
    /// where the mode changes). The machine does not move: the first move
    /// after it starts from where the machine is, which its `start` gives in
    /// the new mode's terms only as far as the program knows them.
    ToolControl(ToolControl),
    /// M2 or M30: the program ends here.
    ProgramEnd,
}

impl BlockKind {
    /// End point of a motion block (`None` for the others).
    pub fn end_point(&self) -> Option<Point> {
        match self {
            BlockKind::Rapid(m) => Some(m.end),
            BlockKind::Linear(m) => Some(m.end),
            BlockKind::Arc(m) => Some(m.end),
            BlockKind::Nurbs(m) => m.points.last().copied(),
            _ => None,
        }
    }

    /// Orientation of a motion block (`None` for the others).
    pub fn orientation(&self) -> Option<&Orientation> {
        match self {
            BlockKind::Rapid(m) => Some(&m.orientation),
            BlockKind::Linear(m) => Some(&m.orientation),
            BlockKind::Arc(m) => Some(&m.orientation),
            BlockKind::Nurbs(m) => Some(&m.orientation),
            _ => None,
        }
    }
}

impl Program {
    /// The path tolerance (G64 `P`, mm) in force at the first motion block,
    /// or, if none is set there, the first one the program sets. interp-core
    /// takes a chord tolerance per run (`InterpConfig::chord_tolerance`), not
    /// per block, so this is the figure to give it; `None` when the program
    /// never gives G64 P (keep the configured default).
    pub fn path_tolerance(&self) -> Option<f64> {
        let mut current = None;
        for b in &self.blocks {
            match &b.kind {
                BlockKind::PathControl(PathControl::Blend { path_tolerance, .. }) => {
                    current = *path_tolerance;
                }
                BlockKind::PathControl(_) => current = None,
                k if k.end_point().is_some() && current.is_some() => return current,
                _ => {}
            }
        }
        self.blocks.iter().find_map(|b| match &b.kind {
            BlockKind::PathControl(PathControl::Blend { path_tolerance, .. }) => *path_tolerance,
            _ => None,
        })
    }

    /// The motion blocks' end points in order (a quick summary for tests and tools).
    pub fn end_points(&self) -> impl Iterator<Item = Point> + '_ {
        self.blocks.iter().filter_map(|b| b.kind.end_point())
    }
}
