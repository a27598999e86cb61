//! RS274/NGC G-code for interpd.
//!
//! [`parse`] turns program text into a [`Program`] of typed blocks (mm,
//! absolute, each with its source line); [`emit`] writes a program back as
//! text; [`Program::for_each_move`] is the one conversion into moves for the
//! interpolator (rapid speed, feed units, G93, zero-length moves, five-axis
//! frames decided once), which a [`Cutter`] turns into interp-core blocks
//! ([`Program::to_core_blocks`]: NURBS exactly as written, cut into pieces of
//! at most `MAX_CTRL` control points; arcs exact). The parser never panics on any input: every defect is a
//! [`ParseError`] with `line:column: message`.
//!
//! The dialect is LinuxCNC's: see `docs/gcode.md` for what is covered.

mod convert;
mod emit;
mod error;
mod expr;
pub mod generate;
mod moves;
mod parser;
mod program;

pub use convert::{ConvertOrSinkError, CoreOptions, core_blending};
pub use emit::{EMIT_HEADER, Emit, emit};
pub use error::{ConvertError, FiveAxisReason, ParseError, ParseErrorKind};
pub use expr::{MAX_EXPRESSION_DEPTH, NEAR_INT_TOL, PARAMETER_COUNT};
pub use moves::{
    CutError, Cutter, JOINT_WALK_MIN_SAMPLES, JOINT_WALK_STEP, Move, MoveOrientation, MovePath,
    SECONDS_PER_MINUTE, joints_after,
};
pub use parser::{
    ARC_R_TINY, CENTER_ARC_RADIUS_TOLERANCE_INCH, CENTER_ARC_RADIUS_TOLERANCE_MM,
    G5_2_DEFAULT_ORDER, RADIUS_TOLERANCE_INCH, SPIRAL_ABS_HARD_FACTOR, SPIRAL_RELATIVE_TOLERANCE,
    g5_2_knots, parse, parse_from, parse_from_axes,
};
pub use program::{
    ArcMove, BlockKind, Feed, LinearMove, NurbsMove, Orientation, PathControl, Plane, Point,
    Program, ProgramBlock, RapidMove, Rotary, SpindleRotation, ToolControl,
};

/// A G-code number that is not a units mode (only G20 and G21 are).
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("G{0} is not a units mode (expected G20 or G21)")]
pub struct NotAUnitsCode(pub u32);

/// Length units of a program, the modal state set by G20 (inches) and G21
/// (millimetres). interpd works in millimetres internally.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Units {
    /// G21.
    #[default]
    Millimetres,
    /// G20.
    Inches,
}

impl Units {
    /// Millimetres per inch, exact by definition.
    pub const MM_PER_INCH: f64 = 25.4;

    /// The units mode selected by the G-code number `code` (`20` or `21`).
    pub fn from_g_code(code: u32) -> Result<Self, NotAUnitsCode> {
        match code {
            20 => Ok(Self::Inches),
            21 => Ok(Self::Millimetres),
            other => Err(NotAUnitsCode(other)),
        }
    }

    /// The G-code number that selects this mode.
    pub fn g_code(self) -> u32 {
        match self {
            Self::Inches => 20,
            Self::Millimetres => 21,
        }
    }

    /// Converts a length (or a feed, per minute or per second) given in these
    /// units to millimetres.
    pub fn to_mm(self, value: f64) -> f64 {
        match self {
            Self::Millimetres => value,
            Self::Inches => value * Self::MM_PER_INCH,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn to_mm_converts_inches_and_keeps_millimetres() {
        assert_eq!(Units::Millimetres.to_mm(12.5), 12.5);
        assert_eq!(Units::Inches.to_mm(1.0), 25.4);
        assert_eq!(Units::Inches.to_mm(-2.0), -50.8);
        assert!(Units::Inches.to_mm(f64::NAN).is_nan());
    }

    #[test]
    fn g_codes_round_trip_and_others_are_rejected() {
        for units in [Units::Millimetres, Units::Inches] {
            assert_eq!(Units::from_g_code(units.g_code()), Ok(units));
        }
        assert_eq!(Units::from_g_code(1), Err(NotAUnitsCode(1)));
        assert_eq!(
            NotAUnitsCode(90).to_string(),
            "G90 is not a units mode (expected G20 or G21)"
        );
    }

    #[test]
    fn default_is_millimetres() {
        assert_eq!(Units::default(), Units::Millimetres);
    }
}
