//! How the planners write their paths as G-code (`plan raster`, `plan
//! gouge`, `plan fit`): each path is entered and left the same way, so that
//! the tool never moves sideways below the safe height between paths.

use planner::fit::NurbsBlock;

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
}

/// Builds a program path by path: a rapid across at the safe height, a rapid
/// down to the approach clearance above the first point, a plunge at the
/// plunge feed, the cut at the feed, and a rapid retract straight up.
#[derive(Debug)]
pub struct PathWriter {
    blocks: Vec<gcode::ProgramBlock>,
    /// Where the tool is (`None` before the first move: wherever the machine is).
    at: Option<[f64; 3]>,
    moves: Moves,
}

impl PathWriter {
    /// An empty program moving as `moves` says.
    pub fn new(moves: Moves) -> Self {
        PathWriter {
            blocks: Vec::new(),
            at: None,
            moves,
        }
    }

    fn push(&mut self, kind: gcode::BlockKind) {
        let line = self.blocks.len() as u32 + 1;
        self.blocks.push(gcode::ProgramBlock { line, kind });
    }

    fn rapid_to(&mut self, end: [f64; 3]) {
        // The first move starts wherever the machine is: the emitter writes
        // it as one rapid to the point above the first path.
        let start = self.at.unwrap_or(end);
        if start != end {
            self.push(gcode::BlockKind::Rapid(gcode::RapidMove { start, end }));
        }
        self.at = Some(end);
    }

    fn line_to(&mut self, end: [f64; 3], feed: f64) {
        let start = self.at.unwrap_or(end);
        self.push(gcode::BlockKind::Linear(gcode::LinearMove {
            start,
            end,
            feed: gcode::Feed::PerMinute(feed),
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
    pub fn nurbs(&mut self, b: &NurbsBlock) {
        let first_line = self.blocks.len() as u32 + 1;
        let feed = gcode::Feed::PerMinute(self.moves.feed);
        self.push(gcode::BlockKind::Nurbs(gcode::NurbsMove {
            first_line,
            plane: gcode::Plane::Xy,
            degree: b.degree,
            points: b.control_points.clone(),
            weights: b.weights.clone(),
            knots: b.knots.clone(),
            feed,
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
