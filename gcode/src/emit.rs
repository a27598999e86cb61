//! Program → G-code text.
//!
//! Numbers are written with Rust's shortest round-trip formatting, so
//! `parse(emit(p))` gives back the same numbers bit for bit. Arc centres are
//! written absolute (G90.1) for the same reason.

use core::fmt::Write;

use crate::program::{BlockKind, Feed, PathControl, Plane, Point, Program, SpindleRotation};

/// Header every emitted program starts with: millimetres, absolute
/// coordinates and absolute arc centres, feed per minute, XY plane.
pub const EMIT_HEADER: &str = "G21 G90 G90.1 G94 G17";

/// Writes `program` as RS274/NGC text (G21, absolute): G0/G1, G2/G3 (centre
/// form, absolute centres), G6.2 for every NURBS, G4, S/M3/M4/M5, T/M6,
/// G61/G64, M2.
///
/// A motion whose start differs from where the previous block ended is
/// preceded by a G0 to its start. Non-finite numbers cannot be written as
/// G-code; they come out as `NaN`/`inf` and the text will not parse.
pub fn emit(program: &Program) -> String {
    let mut e = Emitter {
        out: String::with_capacity(program.blocks.len() * 40 + 64),
        pos: [0.0; 3],
        plane: Plane::Xy,
        feed: None,
    };
    e.out.push_str(EMIT_HEADER);
    e.out.push('\n');
    for b in &program.blocks {
        e.block(&b.kind);
    }
    e.out
}

struct Emitter {
    out: String,
    pos: Point,
    plane: Plane,
    feed: Option<Feed>,
}

const AXES: [char; 3] = ['X', 'Y', 'Z'];
const OFFSETS: [char; 3] = ['I', 'J', 'K'];

impl Emitter {
    fn xyz(&mut self, p: &Point) {
        for (a, v) in AXES.iter().zip(p) {
            let _ = write!(self.out, " {a}{v}");
        }
    }

    fn move_to_start(&mut self, start: &Point) {
        if *start != self.pos {
            self.out.push_str("G0");
            self.xyz(start);
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
                self.move_to_start(&m.start);
                self.out.push_str("G0");
                self.xyz(&m.end);
                self.out.push('\n');
                self.pos = m.end;
            }
            BlockKind::Linear(m) => {
                self.move_to_start(&m.start);
                self.out.push_str("G1");
                self.xyz(&m.end);
                self.feed(m.feed);
                self.out.push('\n');
                self.pos = m.end;
            }
            BlockKind::Arc(m) => {
                self.move_to_start(&m.start);
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
                self.move_to_start(first);
                self.set_plane(m.plane);
                let n = m.points.len();
                for (i, (p, w)) in m.points.iter().zip(&m.weights).enumerate() {
                    if i == 0 {
                        self.out.push_str("G6.2");
                    } else {
                        self.out.push_str("   ");
                    }
                    self.xyz(p);
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
            BlockKind::ProgramEnd => self.out.push_str("M2\n"),
        }
    }
}
