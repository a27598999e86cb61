//! Program blocks → interp-core blocks.

use interp_core::Vec3;
use interp_core::nurbs::{MAX_CTRL, SplitError, split_program_curve};
use interp_core::path::{Arc, Blending, Block, Line, Path, PathError};

use crate::error::ConvertError;
use crate::program::{BlockKind, Feed, Orientation, PathControl, Program};

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

/// Seconds per minute: G-code feeds are per minute, interp-core's per second.
const SECONDS_PER_MINUTE: f64 = 60.0;

/// How program blocks become interp-core blocks.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(default, rename_all = "kebab-case"))]
pub struct CoreOptions {
    /// Feed given to rapid (G0) moves, mm/s: the machine's maximum path speed.
    /// Default 250, the default `InterpConfig::max_path_speed`.
    pub rapid_speed: f64,
}

impl Default for CoreOptions {
    fn default() -> Self {
        CoreOptions {
            rapid_speed: interp_core::InterpConfig::default().max_path_speed,
        }
    }
}

fn v3(p: [f64; 3]) -> Vec3 {
    Vec3::new(p[0], p[1], p[2])
}

/// Feed in mm/s for a move of `length` mm.
fn feed_mm_s(feed: Feed, length: f64, line: u32) -> Result<f64, ConvertError> {
    let f = match feed {
        Feed::PerMinute(v) => v / SECONDS_PER_MINUTE,
        Feed::InverseTime(v) => length * v / SECONDS_PER_MINUTE,
    };
    if !(f > 0.0) || !f.is_finite() {
        return Err(ConvertError::Feed { line, feed: f });
    }
    Ok(f)
}

impl Program {
    /// Converts the motion blocks into interp-core blocks, in order, calling
    /// `sink` with each. Each block's `id` is its source line.
    ///
    /// - G0 becomes a line at `opts.rapid_speed` (the machine's maximum path speed);
    /// - G1 a line, G2/G3 an exact arc ([`Arc::from_centre`]);
    /// - a NURBS is passed on exactly as written, cut by
    ///   [`split_program_curve`] into pieces of at most [`MAX_CTRL`] control
    ///   points that are the same curve;
    /// - moves of zero length are dropped (RS274/NGC allows them; they move nothing);
    /// - dwell, spindle, tool, path-control and tool-centre-point blocks
    ///   carry no path and are skipped; the path control mode in force (G61.1,
    ///   G61, G64 P; G61 until the program sets one) becomes each block's
    ///   `blending`;
    /// - a move that turns a rotary axis or runs under tool-centre-point
    ///   control (G43.4, G43.5) is refused ([`ConvertError::FiveAxis`]):
    ///   interp-core blocks carry X Y Z only.
    ///
    /// Feeds become mm/s (G93 inverse time: the move's length × F / 60).
    pub fn for_each_core_block<E>(
        &self,
        opts: &CoreOptions,
        mut sink: impl FnMut(Block) -> Result<(), E>,
    ) -> Result<(), ConvertOrSinkError<E>> {
        let mut blending = Blending::ExactPath;
        let mut sink = |b: Block, mode: Blending| sink(b.with_blending(mode));
        for b in &self.blocks {
            let line = b.line;
            if let BlockKind::PathControl(mode) = &b.kind {
                blending = core_blending(*mode);
                continue;
            }
            let path_err =
                |error: PathError| ConvertOrSinkError::Convert(ConvertError::Path { line, error });
            if !b.kind.orientation().is_none_or(Orientation::is_fixed) {
                return Err(ConvertOrSinkError::Convert(ConvertError::FiveAxis { line }));
            }
            match &b.kind {
                BlockKind::Rapid(m) => {
                    let path = match Line::new(v3(m.start), v3(m.end)) {
                        Ok(l) => Path::Line(l),
                        Err(PathError::ZeroLength) => continue,
                        Err(e) => return Err(path_err(e)),
                    };
                    let feed = feed_mm_s(
                        Feed::PerMinute(opts.rapid_speed * SECONDS_PER_MINUTE),
                        0.0,
                        line,
                    )?;
                    sink(Block::new(line, path, feed), blending)
                        .map_err(ConvertOrSinkError::Sink)?;
                }
                BlockKind::Linear(m) => {
                    let l = match Line::new(v3(m.start), v3(m.end)) {
                        Ok(l) => l,
                        Err(PathError::ZeroLength) => continue,
                        Err(e) => return Err(path_err(e)),
                    };
                    let feed = feed_mm_s(m.feed, l.length(), line)?;
                    sink(Block::new(line, Path::Line(l), feed), blending)
                        .map_err(ConvertOrSinkError::Sink)?;
                }
                BlockKind::Arc(m) => {
                    let n = m.plane.normal();
                    let s = if m.clockwise { -1.0 } else { 1.0 };
                    let axis = Vec3::new(s * n[0], s * n[1], s * n[2]);
                    let a =
                        Arc::from_centre(v3(m.start), v3(m.end), v3(m.centre), axis, m.extra_turns)
                            .map_err(path_err)?;
                    let feed = feed_mm_s(m.feed, a.length(), line)?;
                    sink(Block::new(line, Path::Arc(a), feed), blending)
                        .map_err(ConvertOrSinkError::Sink)?;
                }
                BlockKind::Nurbs(m) => {
                    let mut pieces = Vec::new();
                    let r: Result<(), SplitError<core::convert::Infallible>> = split_program_curve(
                        m.degree,
                        &m.points,
                        &m.weights,
                        &m.knots,
                        MAX_CTRL,
                        |seg| {
                            pieces.push(seg);
                            Ok(())
                        },
                    );
                    match r {
                        Ok(()) => {}
                        Err(SplitError::Invalid(error)) => {
                            return Err(ConvertOrSinkError::Convert(ConvertError::Nurbs {
                                line,
                                error,
                            }));
                        }
                        Err(SplitError::Sink(never)) => match never {},
                    }
                    let length = match m.feed {
                        Feed::InverseTime(_) => {
                            pieces.iter().map(|p| Path::Nurbs(*p).length()).sum()
                        }
                        Feed::PerMinute(_) => 0.0,
                    };
                    let feed = feed_mm_s(m.feed, length, line)?;
                    for seg in pieces {
                        sink(Block::new(line, Path::Nurbs(seg), feed), blending)
                            .map_err(ConvertOrSinkError::Sink)?;
                    }
                }
                BlockKind::Dwell { .. }
                | BlockKind::Spindle { .. }
                | BlockKind::ToolChange { .. }
                | BlockKind::PathControl(_)
                | BlockKind::ToolControl(_)
                | BlockKind::ProgramEnd => {}
            }
        }
        Ok(())
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
