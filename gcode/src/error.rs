//! Parse errors: every one names the line and column of the offending word.

use interp_core::nurbs::NurbsError;

/// Why a program was refused. Display is `line:column: message`.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{line}:{column}: {kind}")]
pub struct ParseError {
    /// 1-based source line.
    pub line: u32,
    /// 1-based column (in characters) of the word or character at fault.
    pub column: u32,
    /// What is wrong.
    pub kind: ParseErrorKind,
}

/// The classes of parse error.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ParseErrorKind {
    /// A character that starts no word, comment or expression. Shown as
    /// `'x' (U+0078)`, and as its code point alone when it is invisible (a
    /// control character such as NUL, a byte-order mark inside the text, …).
    #[error("unexpected character {}", ShowChar(*.0))]
    UnexpectedChar(char),
    /// A letter that is no RS274/NGC word interpd knows.
    #[error("unknown word '{0}'")]
    UnknownWord(char),
    /// A G or M code that does not exist or that interpd does not support.
    #[error("unknown or unsupported code {0}")]
    UnknownCode(String),
    /// The same word twice on one line.
    #[error("duplicate word '{0}' on one line")]
    DuplicateWord(char),
    /// Two codes of the same modal group on one line.
    #[error("{first} and {second} are in the same modal group ({group})")]
    ModalGroupConflict {
        /// The group's name.
        group: &'static str,
        /// The first code.
        first: String,
        /// The second code.
        second: String,
    },
    /// A required word is absent.
    #[error("missing argument: {0}")]
    MissingArgument(String),
    /// Words that exclude each other, or a word no command on the line uses.
    #[error("conflicting arguments: {0}")]
    ConflictingArguments(String),
    /// A word's value is out of range or not an integer where one is needed.
    #[error("bad value: {0}")]
    BadValue(String),
    /// A number that does not parse.
    #[error("bad number")]
    BadNumber,
    /// A malformed or unevaluable expression.
    #[error("expression: {0}")]
    Expression(String),
    /// A NURBS whose control points, weights or knots are invalid.
    #[error("invalid NURBS: {0}")]
    InvalidNurbs(NurbsError),
    /// A NURBS block sequence that is malformed (not its numbers).
    #[error("NURBS: {0}")]
    NurbsSequence(String),
    /// An arc that cannot be made (radius mismatch, zero radius, unreachable end).
    #[error("bad arc: {0}")]
    BadArc(String),
    /// A feature of RS274/NGC that interpd does not implement.
    #[error("unsupported: {0}")]
    Unsupported(String),
}

/// A character as an error message shows it: never raw when it would be
/// invisible or would upset a terminal.
struct ShowChar(char);

impl core::fmt::Display for ShowChar {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let c = self.0;
        let code = c as u32;
        let invisible = c.is_control()
            || c.is_whitespace()
            || matches!(code, 0x200B..=0x200F | 0x2028..=0x202E | 0x2060..=0x206F | 0xFEFF);
        if invisible {
            write!(f, "U+{code:04X}")
        } else if c.is_ascii() {
            write!(f, "'{c}'")
        } else {
            write!(f, "'{c}' (U+{code:04X})")
        }
    }
}

/// Why [`crate::Program::to_core_blocks`] refused a block.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ConvertError {
    /// A line or arc interp-core refuses.
    #[error("line {line}: {error}")]
    Path {
        /// Source line.
        line: u32,
        /// interp-core's reason.
        error: interp_core::path::PathError,
    },
    /// A NURBS interp-core refuses.
    #[error("line {line}: invalid NURBS: {error}")]
    Nurbs {
        /// Source line.
        line: u32,
        /// interp-core's reason.
        error: NurbsError,
    },
    /// A move the blocks cannot be cut from (it does not start where the
    /// last one ends, or where it starts is not known).
    #[error("line {line}: {error}")]
    Move {
        /// Source line.
        line: u32,
        /// Why.
        error: crate::moves::CutError,
    },
    /// A five-axis move that cannot be converted, and why.
    #[error("line {line}: {reason}")]
    FiveAxisMove {
        /// Source line.
        line: u32,
        /// Why.
        reason: FiveAxisReason,
    },
    /// A feed that is zero, negative or not finite.
    #[error("line {line}: feed {feed} is not positive")]
    Feed {
        /// Source line.
        line: u32,
        /// The feed, mm/s.
        feed: f64,
    },
}

/// Why a five-axis move was refused ([`ConvertError::FiveAxisMove`]).
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum FiveAxisReason {
    /// Tool-centre-point control needs the machine's kinematics.
    #[error(
        "tool-centre-point control (G43.4/G43.5) needs the machine (its W/.../T chain) to find the tool axis and the joints"
    )]
    NoMachine,
    /// Under tool-centre-point control a move whose tip stands still turns
    /// the rotary axes but not the tool axis (C at the pole of a C,A
    /// machine): the tool pose does not change, the move cannot be timed.
    #[error(
        "under tool-centre-point control the rotary axes turn but the tool axis does not (at the pole, where the first rotary axis is undefined): nothing to interpolate"
    )]
    RotaryOnly,
    /// The first move after G43.4/G43.5/G49 is not a straight move.
    #[error(
        "the first move after tool-centre-point control goes on or off must be G0 or G1 (it starts where the machine stands: the tool tip, or X Y Z, of its joints)"
    )]
    FrameChange,
    /// The tool axis or the rotary positions of the move are refused.
    #[error("{0}")]
    Orientation(interp_core::fiveaxis::OrientationError),
    /// The machine given in the options is refused.
    #[error("the machine: {0}")]
    Machine(interp_core::kinematics::MachineError),
    /// The end pose is out of the machine's reach.
    #[error("{0}")]
    Inverse(interp_core::kinematics::InverseError),
}
