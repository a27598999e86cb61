//! Planner I/O as G-code (with the `gcode` feature): CL programs in (every
//! run of G1 moves between rapids is one polyline of tool-tip points) and
//! paths out through `gcode::emit`, each path entered and left the same way
//! so that the tool never moves sideways below the safe height between
//! paths (`interpd plan raster`, `plan gouge`, `plan fit`).

use crate::mesh::P3;

/// Clearance above the first point of a path for the approach rapid of a
/// rewritten CL program (`plan gouge`, `plan fit`), mm.
pub const APPROACH_CLEARANCE: f64 = 5.0;
/// Feed written when the input program has none, mm/min.
pub const DEFAULT_FEED: f64 = 1000.0;

/// Why a CL program cannot be read.
#[derive(Debug, thiserror::Error)]
pub enum ClReadError {
    /// The G-code does not parse.
    #[error(transparent)]
    Parse(#[from] gcode::ParseError),
    /// A block a CL path cannot hold.
    #[error("line {line}: {what} is not supported in a CL path")]
    Unsupported {
        /// Its line.
        line: u32,
        /// What it is.
        what: &'static str,
    },
}

/// A G0/G1 program read as CL polylines.
#[derive(Debug, Clone, PartialEq)]
pub struct ClProgram {
    /// One polyline per run of G1 moves (a rapid starts a new one), without
    /// the vertical plunge a run may start with.
    pub paths: Vec<Vec<P3>>,
    /// The first cutting feed (of a G1 move that is not a plunge), mm/min.
    pub feed: Option<f64>,
    /// The first plunge feed (a run's leading straight-down G1), mm/min.
    pub plunge_feed: Option<f64>,
    /// Highest Z any move of the input reaches (its safe height, when it
    /// retracts between runs), mm.
    pub top_z: Option<f64>,
}

/// A G1 move straight down (same X and Y): a plunge to a run's first point.
fn is_plunge(m: &gcode::LinearMove) -> bool {
    m.start[0] == m.end[0] && m.start[1] == m.end[1] && m.end[2] < m.start[2]
}

/// Reads a program with the `gcode` parser and takes its G0/G1 moves as CL
/// polylines. Arcs and NURBS are refused, naming the line (a CL path for the
/// gouge check is a polyline).
pub fn read_cl_program(text: &str) -> Result<ClProgram, ClReadError> {
    use gcode::BlockKind;
    let program = gcode::parse(text)?;
    let mut paths: Vec<Vec<P3>> = Vec::new();
    let mut current: Vec<P3> = Vec::new();
    let (mut feed, mut plunge_feed, mut top_z) = (None, None, None::<f64>);
    let p3 = |p: [f64; 3]| P3::new(p[0], p[1], p[2]);
    let mut top = |z: f64| top_z = Some(top_z.map_or(z, |t| t.max(z)));
    for block in &program.blocks {
        if !block
            .kind
            .orientation()
            .is_none_or(gcode::Orientation::is_fixed)
        {
            return Err(ClReadError::Unsupported {
                line: block.line,
                what: "five-axis motion (A/B/C words or G43.4/G43.5)",
            });
        }
        match &block.kind {
            BlockKind::Linear(m) => {
                top(m.start[2]);
                top(m.end[2]);
                let gcode::Feed::PerMinute(f) = m.feed else {
                    return Err(ClReadError::Unsupported {
                        line: block.line,
                        what: "inverse-time feed (G93)",
                    });
                };
                if current.is_empty() && is_plunge(m) {
                    // The approach, not part of the CL path: written again
                    // above the (possibly corrected) first point.
                    plunge_feed.get_or_insert(f);
                    current.push(p3(m.end));
                    continue;
                }
                feed.get_or_insert(f);
                if current.is_empty() {
                    current.push(p3(m.start));
                }
                current.push(p3(m.end));
            }
            BlockKind::Rapid(m) => {
                top(m.start[2]);
                top(m.end[2]);
                if current.len() >= 2 {
                    paths.push(std::mem::take(&mut current));
                }
                current.clear();
            }
            BlockKind::Arc(_) | BlockKind::Nurbs(_) => {
                return Err(ClReadError::Unsupported {
                    line: block.line,
                    what: "an arc or NURBS (G0/G1 polylines only)",
                });
            }
            _ => {}
        }
    }
    if current.len() >= 2 {
        paths.push(current);
    }
    Ok(ClProgram {
        paths,
        feed,
        plunge_feed,
        top_z,
    })
}

impl ClProgram {
    /// The input's feeds, and a safe height at least `APPROACH_CLEARANCE`
    /// above every point of `paths` (the paths written, which a correction
    /// may have raised) and no lower than the input's own highest move.
    pub fn moves_for<'a>(&self, paths: impl IntoIterator<Item = &'a P3>) -> Moves {
        let feed = self.feed.or(self.plunge_feed).unwrap_or(DEFAULT_FEED);
        let path_top = paths
            .into_iter()
            .map(|p| p.z)
            .fold(f64::NEG_INFINITY, f64::max);
        Moves {
            safe_z: (path_top + APPROACH_CLEARANCE).max(self.top_z.unwrap_or(f64::NEG_INFINITY)),
            approach_clearance: APPROACH_CLEARANCE,
            plunge_feed: self.plunge_feed.unwrap_or(feed),
            feed,
            blend_tolerance: None,
        }
    }
}

/// Writes CL polylines as G1 moves through the `gcode` emitter.
pub fn write_g1(paths: &[Vec<P3>], moves: Moves) -> String {
    let mut w = PathWriter::new(moves);
    for path in paths {
        w.enter([path[0].x, path[0].y, path[0].z]);
        for p in &path[1..] {
            w.cut_to([p.x, p.y, p.z]);
        }
        w.leave();
    }
    gcode::emit(&w.into_program())
}

/// Writes fitted paths through the `gcode` emitter: curves as G6.2 NURBS
/// (with Z on the control-point lines, interpd's 3-D extension), straight
/// pieces as G1.
pub fn write_g62(fitted: &[(P3, crate::fit::Fitted)], moves: Moves) -> String {
    let mut w = PathWriter::new(moves);
    for (start, f) in fitted {
        w.enter([start.x, start.y, start.z]);
        for piece in &f.pieces {
            match piece {
                crate::fit::FitPiece::Lines(pts) => {
                    for p in &pts[1..] {
                        w.cut_to(*p);
                    }
                }
                crate::fit::FitPiece::Nurbs(b) => w.nurbs(b),
            }
        }
        w.leave();
    }
    gcode::emit(&w.into_program())
}

/// Heights and feeds of a written program.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Moves {
    /// Rapids between paths go across at this height, mm.
    pub safe_z: f64,
    /// The rapid descent stops this far above a path's first point, before
    /// the plunge, mm.
    pub approach_clearance: f64,
    /// Feed of the plunge to each path's first point, mm/min.
    pub plunge_feed: f64,
    /// Feed along the paths, mm/min.
    pub feed: f64,
    /// `G64 P` written at the start: the controller may leave the written
    /// polylines by this much (mm) to run dense moves at speed; `None`: no
    /// path-control word (the controller's own mode).
    pub blend_tolerance: Option<f64>,
}

/// Builds a program path by path: a rapid across at the safe height, a rapid
/// down to the approach clearance above the first point, a plunge at the
/// plunge feed, the cut at the feed, and a rapid retract straight up.
///
/// The blocks wait in the writer until [`PathWriter::drain`] hands them on
/// (a program written as it is made never holds more than one path) or
/// [`PathWriter::into_program`] makes the program of those not drained.
#[derive(Debug)]
pub struct PathWriter {
    blocks: Vec<gcode::ProgramBlock>,
    /// Blocks handed on by `drain` (line numbers go on after them).
    drained: u32,
    /// Where the tool is (`None` before the first move: wherever the machine is).
    at: Option<[f64; 3]>,
    moves: Moves,
}

impl PathWriter {
    /// An empty program moving as `moves` says.
    pub fn new(moves: Moves) -> Self {
        let mut w = PathWriter {
            blocks: Vec::new(),
            drained: 0,
            at: None,
            moves,
        };
        if let Some(p) = moves.blend_tolerance {
            w.push(gcode::BlockKind::PathControl(gcode::PathControl::Blend {
                path_tolerance: Some(p),
                naive_cam_tolerance: None,
            }));
        }
        w
    }

    /// The line number of the next block.
    fn next_line(&self) -> u32 {
        self.drained + self.blocks.len() as u32 + 1
    }

    fn push(&mut self, kind: gcode::BlockKind) {
        let line = self.next_line();
        self.blocks.push(gcode::ProgramBlock { line, kind });
    }

    /// Hands on the blocks written since the last call, in order.
    pub fn drain(&mut self) -> std::vec::Drain<'_, gcode::ProgramBlock> {
        self.drained += self.blocks.len() as u32;
        self.blocks.drain(..)
    }

    /// Ends the program (M2) and hands on the blocks not drained yet.
    pub fn finish(&mut self) -> std::vec::Drain<'_, gcode::ProgramBlock> {
        self.push(gcode::BlockKind::ProgramEnd);
        self.drain()
    }

    fn rapid_to(&mut self, end: [f64; 3]) {
        // The first move starts wherever the machine is: the emitter writes
        // it as one rapid to the point above the first path.
        let start = self.at.unwrap_or(end);
        if start != end {
            self.push(gcode::BlockKind::Rapid(gcode::RapidMove {
                start,
                end,
                orientation: gcode::Orientation::Fixed,
            }));
        }
        self.at = Some(end);
    }

    fn line_to(&mut self, end: [f64; 3], feed: f64) {
        let start = self.at.unwrap_or(end);
        self.push(gcode::BlockKind::Linear(gcode::LinearMove {
            start,
            end,
            feed: gcode::Feed::PerMinute(feed),
            orientation: gcode::Orientation::Fixed,
        }));
        self.at = Some(end);
    }

    /// Over to `p` at the safe height, down, and plunge onto it.
    pub fn enter(&mut self, [x, y, z]: [f64; 3]) {
        let safe = self.moves.safe_z;
        self.rapid_to([x, y, safe]);
        self.rapid_to([x, y, safe.min(z + self.moves.approach_clearance)]);
        self.line_to([x, y, z], self.moves.plunge_feed);
    }

    /// A cutting move to `p`.
    pub fn cut_to(&mut self, p: [f64; 3]) {
        self.line_to(p, self.moves.feed);
    }

    /// A NURBS curve (G6.2) at the cutting feed.
    pub fn nurbs(&mut self, b: &crate::fit::NurbsBlock) {
        let first_line = self.next_line();
        let feed = gcode::Feed::PerMinute(self.moves.feed);
        self.push(gcode::BlockKind::Nurbs(gcode::NurbsMove {
            first_line,
            plane: gcode::Plane::Xy,
            degree: b.degree,
            points: b.control_points.clone(),
            weights: b.weights.clone(),
            knots: b.knots.clone(),
            feed,
            orientation: gcode::Orientation::Fixed,
            rotary: Vec::new(),
            tool_vectors: Vec::new(),
        }));
        self.at = b.control_points.last().copied();
    }

    /// Straight up to the safe height.
    pub fn leave(&mut self) {
        if let Some([x, y, _]) = self.at {
            self.rapid_to([x, y, self.moves.safe_z]);
        }
    }

    /// The program, ended with M2.
    pub fn into_program(mut self) -> gcode::Program {
        self.push(gcode::BlockKind::ProgramEnd);
        gcode::Program {
            blocks: self.blocks,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_drained_writer_hands_on_the_program_it_would_make() {
        let moves = Moves {
            safe_z: 5.0,
            approach_clearance: 1.0,
            plunge_feed: 300.0,
            feed: 1200.0,
            blend_tolerance: Some(0.001),
        };
        let paths = [
            [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]],
            [[3.0, 1.0, 0.5], [4.0, 2.0, 0.0]],
        ];
        let write = |w: &mut PathWriter, drained: &mut Vec<gcode::ProgramBlock>, drain: bool| {
            for p in &paths {
                w.enter(p[0]);
                w.cut_to(p[1]);
                w.leave();
                if drain {
                    drained.extend(w.drain());
                }
            }
        };
        let mut whole = PathWriter::new(moves);
        write(&mut whole, &mut Vec::new(), false);
        let whole = whole.into_program().blocks;
        let mut w = PathWriter::new(moves);
        let mut drained = Vec::new();
        write(&mut w, &mut drained, true);
        drained.extend(w.finish());
        // Same blocks, same line numbers, whether drained or not.
        assert_eq!(drained, whole);
        // G64 P; a path from wherever the machine is (down, plunge, cut, up); one
        // from the last (across, down, plunge, cut, up); M2.
        assert_eq!(whole.len(), 11);
    }

    #[test]
    fn reads_g1_runs_without_their_plunge_and_refuses_arcs_naming_the_line() {
        let prog = read_cl_program(
            "%\n(t)\nG21 G90\nG0 X0 Y0 Z5\nG1 Z0 F500\nX1 Y0 F900\nX2 Y1 Z-0.5 ; c\nG0 Z5\nX10\nG1 Z1\nY3\n%\n",
        )
        .unwrap();
        assert_eq!(prog.plunge_feed, Some(500.0));
        assert_eq!(prog.feed, Some(900.0));
        assert_eq!(prog.top_z, Some(5.0));
        assert_eq!(
            prog.paths,
            vec![
                vec![
                    P3::new(0.0, 0.0, 0.0),
                    P3::new(1.0, 0.0, 0.0),
                    P3::new(2.0, 1.0, -0.5)
                ],
                vec![P3::new(10.0, 1.0, 1.0), P3::new(10.0, 3.0, 1.0)],
            ]
        );
        let e = read_cl_program("G0 X0 Y0 Z0\nG2 X1 Y1 I1 J0 F100\n").unwrap_err();
        assert!(e.to_string().contains("line 2"), "{e}");
        assert!(read_cl_program("G1 X0 Y0 Z0 F1\nX1 Y$\n").is_err());
        let e = read_cl_program("G0 X0 Y0 Z1\nG93 G1 X1 F2\n").unwrap_err();
        assert!(e.to_string().contains("line 2"), "{e}");
        // A CL path is three-axis: a rotary move or TCP is not dropped silently.
        for text in [
            "G0 X0 Y0 Z1\nG1 X1 A30 F100\n",
            "G0 X0 Y0 Z1\nG43.4\nG1 X1 F100\n",
        ] {
            let e = read_cl_program(text).unwrap_err();
            assert!(e.to_string().contains("five-axis"), "{e}");
        }
        // A B C that stay where they are change nothing.
        assert!(read_cl_program("G0 X0 Y0 Z1 A0 C0\nG1 X1 F100\nX2\n").is_ok());
    }

    /// Between paths the tool rises straight up to the safe height, crosses
    /// there and comes straight down: no move below the safe height has a
    /// sideways component except the cut itself. The cut keeps the input's
    /// cutting feed and the plunge its plunge feed; the program reads back
    /// to the same paths.
    #[test]
    fn written_programs_cross_at_the_safe_height_with_the_input_feeds() {
        // A one-way raster: the second row starts back at X0, so a direct
        // move from the end of the first would cross the part at cut depth.
        let input = "G0 X0 Y0 Z20\nG1 Z-1 F300\nX50 Z-2 F1200\nG0 Z20\nX0 Y5\nG1 Z-1 F300\nX50 Z-3 F1200\nG0 Z20\nM2\n";
        let prog = read_cl_program(input).unwrap();
        let moves = prog.moves_for(prog.paths.iter().flatten());
        assert_eq!(
            moves,
            Moves {
                safe_z: 20.0,
                approach_clearance: APPROACH_CLEARANCE,
                plunge_feed: 300.0,
                blend_tolerance: None,
                feed: 1200.0
            }
        );
        let fitted: Vec<(P3, crate::fit::Fitted)> = prog
            .paths
            .iter()
            .map(|p| {
                (
                    p[0],
                    crate::fit::fit(p, &crate::fit::FitConfig::default()).unwrap(),
                )
            })
            .collect();
        for text in [write_g1(&prog.paths, moves), write_g62(&fitted, moves)] {
            let out = gcode::parse(&text).unwrap();
            let mut plunges = 0;
            for b in &out.blocks {
                match &b.kind {
                    gcode::BlockKind::Rapid(m) if m.start != [0.0; 3] => {
                        let sideways = m.start[0] != m.end[0] || m.start[1] != m.end[1];
                        assert!(
                            !sideways || (m.start[2] == 20.0 && m.end[2] == 20.0),
                            "line {}: rapid {:?} -> {:?} moves sideways below the safe height\n{text}",
                            b.line,
                            m.start,
                            m.end
                        );
                    }
                    gcode::BlockKind::Linear(m) => {
                        let f = match m.feed {
                            gcode::Feed::PerMinute(f) => f,
                            gcode::Feed::InverseTime(_) => panic!("per-minute feed"),
                        };
                        if is_plunge(m) {
                            plunges += 1;
                            assert_eq!(f, 300.0, "line {}", b.line);
                        } else {
                            assert_eq!(f, 1200.0, "line {}", b.line);
                        }
                    }
                    gcode::BlockKind::Nurbs(n) => {
                        assert_eq!(n.feed, gcode::Feed::PerMinute(1200.0));
                    }
                    _ => {}
                }
            }
            assert_eq!(plunges, 2, "{text}");
            let back = read_cl_program(&text).unwrap();
            assert_eq!(back.paths.len(), 2);
            assert_eq!((back.feed, back.plunge_feed), (Some(1200.0), Some(300.0)));
            for (a, b) in back.paths.iter().zip(&prog.paths) {
                assert_eq!(a.first(), b.first());
                assert_eq!(a.last(), b.last());
            }
        }
    }

    #[test]
    fn g62_output_parses_back_to_the_same_curves_and_converts_to_core_blocks() {
        let pts: Vec<P3> = (0..50)
            .map(|i| P3::new(i as f64, (i as f64 / 7.0).sin(), 0.1 * i as f64))
            .collect();
        let f = crate::fit::fit(&pts, &crate::fit::FitConfig::default()).unwrap();
        let moves = Moves {
            safe_z: 20.0,
            approach_clearance: APPROACH_CLEARANCE,
            plunge_feed: 300.0,
            blend_tolerance: None,
            feed: 800.0,
        };
        let text = write_g62(&[(pts[0], f.clone())], moves);
        let crate::fit::FitPiece::Nurbs(b) = &f.pieces[0] else {
            panic!("expected a curve");
        };
        let prog = gcode::parse(&text).unwrap();
        let nurbs: Vec<&gcode::NurbsMove> = prog
            .blocks
            .iter()
            .filter_map(|bl| match &bl.kind {
                gcode::BlockKind::Nurbs(n) => Some(n),
                _ => None,
            })
            .collect();
        assert_eq!(nurbs.len(), 1);
        let n = nurbs[0];
        assert_eq!(n.degree, b.degree);
        assert_eq!(n.knots.len(), b.knots.len());
        for (p, q) in n.points.iter().zip(&b.control_points) {
            for k in 0..3 {
                assert!((p[k] - q[k]).abs() < 1e-6, "{p:?} vs {q:?}");
            }
        }
        for (u, v) in n.knots.iter().zip(&b.knots) {
            assert!((u - v).abs() < 1e-9);
        }
        prog.to_core_blocks(&gcode::CoreOptions::default()).unwrap();
    }
}
