//! The typed program: what [`crate::parse`] produces and [`crate::emit`] writes.
//!
//! Every length is in millimetres and every coordinate absolute (G20, G91 and
//! G91.1 are resolved by the parser), so a block means the same thing wherever
//! it stands. Each block keeps the 1-based source line it came from.

/// A point `[x, y, z]`, mm.
pub type Point = [f64; 3];

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
}

/// A rapid move to `end` (G0). It carries no feed: the machine's rapid speed applies.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct RapidMove {
    /// Where the move starts, mm.
    pub start: Point,
    /// Where it ends, mm.
    pub end: Point,
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
