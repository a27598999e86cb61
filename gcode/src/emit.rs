//! Program → G-code text.
//!
//! Numbers are written with Rust's shortest round-trip formatting, so
//! `parse(emit(p))` gives back the same numbers bit for bit. Arc centres are
//! written absolute (G90.1) for the same reason.

use core::fmt::Write;

use crate::program::{
    BlockKind, Feed, Orientation, PathControl, Plane, Point, Program, Rotary, SpindleRotation,
    ToolControl,
};

/// Header every emitted program starts with: millimetres, absolute
/// coordinates and absolute arc centres, feed per minute, XY plane.
pub const EMIT_HEADER: &str = "G21 G90 G90.1 G94 G17";

/// Writes `program` as RS274/NGC text (G21, absolute): G0/G1, G2/G3 (centre
/// form, absolute centres), G6.2 for every NURBS, G4, S/M3/M4/M5, T/M6,
/// G61/G64, G43.4/G43.5/G49, M2. A B C words where a rotary axis moves (on
/// G6.2 control points too), I J K on G0/G1 where the G43.5 tool vector
/// changes.
///
/// A motion whose start differs from where the previous block ended is
/// preceded by a G0 to its start (and a move under another tool-centre-point
/// mode than the one in force by that mode's code). Non-finite numbers
/// cannot be written as G-code; they come out as `NaN`/`inf` and the text
/// will not parse.
pub fn emit(program: &Program) -> String {
    let mut e = Emit::with_capacity(program.blocks.len() * 40 + 64);
    for b in &program.blocks {
        e.block(&b.kind);
    }
    e.take()
}

/// [`emit`] block by block, for a program too large to hold whole: the
/// caller hands each block in order and takes the text written so far
/// whenever it likes; the pieces, joined, are exactly what [`emit`] writes
/// for the same blocks.
#[derive(Debug)]
pub struct Emit(Emitter);

impl Default for Emit {
    fn default() -> Self {
        Self::with_capacity(64)
    }
}

impl Emit {
    /// An emitter whose first text is the header, its buffer of `capacity`
    /// bytes.
    pub fn with_capacity(capacity: usize) -> Self {
        let mut e = Emitter {
            out: String::with_capacity(capacity),
            pos: [0.0; 3],
            plane: Plane::Xy,
            feed: None,
            rotary: [Some(0.0); 3],
            tool: ToolControl::Off,
            vector: None,
        };
        e.out.push_str(EMIT_HEADER);
        e.out.push('\n');
        Emit(e)
    }

    /// Writes the next block.
    pub fn block(&mut self, kind: &BlockKind) {
        self.0.block(kind);
    }

    /// The text written since the last call.
    pub fn take(&mut self) -> String {
        core::mem::take(&mut self.0.out)
    }
}

/// The emitter's view of the parser state it writes for.
#[derive(Debug)]
struct Emitter {
    out: String,
    pos: Point,
    plane: Plane,
    feed: Option<Feed>,
    rotary: Rotary,
    tool: ToolControl,
    vector: Option<[f64; 3]>,
}

const AXES: [char; 3] = ['X', 'Y', 'Z'];
const ROTARY: [char; 3] = ['A', 'B', 'C'];
const OFFSETS: [char; 3] = ['I', 'J', 'K'];
/// The tool vector on G6.2 control points (K is the knot there).
const VECTOR_ON_CURVE: [char; 3] = ['U', 'V', 'W'];

/// Rotary positions of an orientation's start and end, if it has them.
fn rotary_ends(o: &Orientation) -> Option<(Rotary, Rotary)> {
    match *o {
        Orientation::Axes { start, end } | Orientation::TcpRotary { start, end } => {
            Some((start, end))
        }
        _ => None,
    }
}

impl Emitter {
    fn xyz(&mut self, p: &Point) {
        for (a, v) in AXES.iter().zip(p) {
            let _ = write!(self.out, " {a}{v}");
        }
    }

    /// A B C words for the axes of `target` that differ from `base`.
    fn rotary_words(&mut self, target: &Rotary, base: &Rotary) {
        for ((a, t), b) in ROTARY.iter().zip(target).zip(base) {
            if let Some(v) = t
                && *b != Some(*v)
            {
                let _ = write!(self.out, " {a}{v}");
            }
        }
    }

    /// The words that bring the orientation from the emitter's state to
    /// `o`'s end, and the new state.
    fn orientation_words(&mut self, o: &Orientation) {
        match *o {
            Orientation::Axes { end, .. } | Orientation::TcpRotary { end, .. } => {
                let base = self.rotary;
                self.rotary_words(&end, &base);
                self.rotary = end;
            }
            Orientation::TcpVector { end, .. } => {
                if let Some(v) = end
                    && self.vector != end
                {
                    for (a, c) in OFFSETS.iter().zip(v) {
                        let _ = write!(self.out, " {a}{c}");
                    }
                }
                self.vector = end;
            }
            Orientation::Fixed => {}
        }
    }

    /// Switches tool-centre-point control as the parser does.
    fn set_tool(&mut self, mode: ToolControl) {
        let was_vector = matches!(self.tool, ToolControl::ToolVector { .. });
        let is_vector = matches!(mode, ToolControl::ToolVector { .. });
        let _ = match mode {
            ToolControl::Off => writeln!(self.out, "G49"),
            ToolControl::RotaryAngles { offset: None } => writeln!(self.out, "G43.4"),
            ToolControl::RotaryAngles { offset: Some(h) } => writeln!(self.out, "G43.4 H{h}"),
            ToolControl::ToolVector { offset: None } => writeln!(self.out, "G43.5"),
            ToolControl::ToolVector { offset: Some(h) } => writeln!(self.out, "G43.5 H{h}"),
        };
        if is_vector && !was_vector {
            self.rotary = [None; 3];
            self.vector = None;
        }
        if !is_vector {
            self.vector = None;
        }
        self.tool = mode;
    }

    /// A move under another mode than the one in force gets that mode first.
    fn ensure_mode(&mut self, o: &Orientation) {
        let fits = matches!(
            (o, self.tool),
            (
                Orientation::Fixed | Orientation::Axes { .. },
                ToolControl::Off
            ) | (
                Orientation::TcpRotary { .. },
                ToolControl::RotaryAngles { .. }
            ) | (
                Orientation::TcpVector { .. },
                ToolControl::ToolVector { .. }
            )
        );
        if !fits {
            self.set_tool(match o {
                Orientation::Fixed | Orientation::Axes { .. } => ToolControl::Off,
                Orientation::TcpRotary { .. } => ToolControl::RotaryAngles { offset: None },
                Orientation::TcpVector { .. } => ToolControl::ToolVector { offset: None },
            });
        }
    }

    /// A G0 to where a move starts (position, rotary axes, tool vector)
    /// when that is not where the previous block ended.
    fn move_to_start(&mut self, start: &Point, o: &Orientation) {
        self.ensure_mode(o);
        let rotary_start = rotary_ends(o).map(|(s, _)| s);
        let rotary_differs = rotary_start.is_some_and(|r| {
            r.iter()
                .zip(&self.rotary)
                .any(|(a, b)| a.is_some() && a != b)
        });
        let vector_start = match o {
            Orientation::TcpVector { start, .. } => *start,
            _ => None,
        };
        let vector_differs = vector_start.is_some() && vector_start != self.vector;
        if *start != self.pos || rotary_differs || vector_differs {
            self.out.push_str("G0");
            self.xyz(start);
            if let Some(r) = rotary_start {
                let base = self.rotary;
                self.rotary_words(&r, &base);
                self.rotary = r;
            }
            if vector_differs && let Some(v) = vector_start {
                for (a, c) in OFFSETS.iter().zip(v) {
                    let _ = write!(self.out, " {a}{c}");
                }
                self.vector = vector_start;
            }
            self.out.push('\n');
            self.pos = *start;
        }
    }

    fn set_plane(&mut self, plane: Plane) {
        if plane != self.plane {
            let _ = writeln!(self.out, "G{}", plane.g_code());
            self.plane = plane;
        }
    }

    /// Feed words for a move line: the mode when it changes, and F when it
    /// changes (always in inverse time, where every move needs its own F).
    fn feed(&mut self, feed: Feed) {
        let (mode_changed, value) = match (self.feed, feed) {
            (Some(Feed::PerMinute(_)) | None, Feed::PerMinute(v)) => (false, v),
            (Some(Feed::InverseTime(_)), Feed::InverseTime(v)) => (false, v),
            (_, Feed::PerMinute(v)) => (true, v),
            (_, Feed::InverseTime(v)) => (true, v),
        };
        if mode_changed {
            self.out.insert_str(
                self.out.rfind('\n').map_or(0, |i| i + 1),
                if matches!(feed, Feed::InverseTime(_)) {
                    "G93 "
                } else {
                    "G94 "
                },
            );
        }
        let same = !mode_changed
            && matches!((self.feed, feed), (Some(Feed::PerMinute(a)), Feed::PerMinute(b)) if a == b);
        if !same {
            let _ = write!(self.out, " F{value}");
        }
        self.feed = Some(feed);
    }

    fn block(&mut self, kind: &BlockKind) {
        match kind {
            BlockKind::Rapid(m) => {
                self.move_to_start(&m.start, &m.orientation);
                self.out.push_str("G0");
                self.xyz(&m.end);
                self.orientation_words(&m.orientation);
                self.out.push('\n');
                self.pos = m.end;
            }
            BlockKind::Linear(m) => {
                self.move_to_start(&m.start, &m.orientation);
                self.out.push_str("G1");
                self.xyz(&m.end);
                self.orientation_words(&m.orientation);
                self.feed(m.feed);
                self.out.push('\n');
                self.pos = m.end;
            }
            BlockKind::Arc(m) => {
                self.move_to_start(&m.start, &m.orientation);
                self.set_plane(m.plane);
                self.out.push_str(if m.clockwise { "G2" } else { "G3" });
                self.xyz(&m.end);
                let (a, b, _) = m.plane.axes();
                for i in [a, b] {
                    let _ = write!(self.out, " {}{}", OFFSETS[i], m.centre[i]);
                }
                if m.extra_turns > 0 {
                    let _ = write!(self.out, " P{}", u64::from(m.extra_turns) + 1);
                }
                self.feed(m.feed);
                self.out.push('\n');
                self.pos = m.end;
            }
            BlockKind::Nurbs(m) => {
                let Some(first) = m.points.first() else {
                    return;
                };
                self.move_to_start(first, &m.orientation);
                self.set_plane(m.plane);
                let n = m.points.len();
                // Point lines give the rotary axes that differ from where
                // the curve starts (the parser reads the others from there).
                let base = self.rotary;
                for (i, (p, w)) in m.points.iter().zip(&m.weights).enumerate() {
                    if i == 0 {
                        self.out.push_str("G6.2");
                    } else {
                        self.out.push_str("   ");
                    }
                    self.xyz(p);
                    if let Some(r) = m.rotary.get(i) {
                        self.rotary_words(r, &base);
                    }
                    if let Some(v) = m.tool_vectors.get(i) {
                        for (a, c) in VECTOR_ON_CURVE.iter().zip(v) {
                            let _ = write!(self.out, " {a}{c}");
                        }
                    }
                    let k = m.knots.get(i).copied().unwrap_or(f64::NAN);
                    let _ = write!(self.out, " R{w} K{k}");
                    if i == 0 {
                        let _ = write!(self.out, " P{} Q1", m.degree + 1);
                        self.feed(m.feed);
                    }
                    self.out.push('\n');
                }
                for k in m.knots.iter().skip(n) {
                    let _ = writeln!(self.out, "G6.2 K{k}");
                }
                self.pos = m.points[n - 1];
                if let Some(r) = m.rotary.last() {
                    self.rotary = *r;
                }
                if let Some(v) = m.tool_vectors.last() {
                    self.vector = Some(*v);
                }
            }
            BlockKind::Dwell { seconds } => {
                let _ = writeln!(self.out, "G4 P{seconds}");
            }
            BlockKind::Spindle {
                speed,
                rotation,
                constant_surface_speed,
            } => {
                let g = if *constant_surface_speed { 96 } else { 97 };
                let m = match rotation {
                    SpindleRotation::Clockwise => 3,
                    SpindleRotation::CounterClockwise => 4,
                    SpindleRotation::Stopped => 5,
                };
                let _ = writeln!(self.out, "G{g} S{speed} M{m}");
            }
            BlockKind::ToolChange { tool } => {
                let _ = writeln!(self.out, "T{tool} M6");
            }
            BlockKind::PathControl(pc) => match pc {
                PathControl::ExactPath => self.out.push_str("G61\n"),
                PathControl::ExactStop => self.out.push_str("G61.1\n"),
                PathControl::Blend {
                    path_tolerance,
                    naive_cam_tolerance,
                } => {
                    self.out.push_str("G64");
                    if let Some(p) = path_tolerance {
                        let _ = write!(self.out, " P{p}");
                    }
                    if let Some(q) = naive_cam_tolerance {
                        let _ = write!(self.out, " Q{q}");
                    }
                    self.out.push('\n');
                }
            },
            BlockKind::ToolControl(mode) => self.set_tool(*mode),
            BlockKind::ProgramEnd => self.out.push_str("M2\n"),
        }
    }
}
