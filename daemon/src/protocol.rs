//! The control plane's line protocol (see `docs/daemon.md`): one request per
//! line, exactly one reply line per request.
//!
//! Requests: a JSON block (`{"feed": …, "line"|"arc"|"nurbs": …}`), or one of
//! `start`, `hold`, `resume`, `override X`, `end`, `abort`, `status`,
//! `auth TOKEN`. Replies: `ok …`, `status {json}` or `err LINE PROBLEM`.

use interp_core::nurbs::{MAX_CTRL, split_program_curve};
use interp_core::{Arc, Block, Line, Path, Vec3};
use serde::Deserialize;

/// Longest request line, bytes (newline excluded). Longer lines are refused
/// with an error and skipped up to their newline.
pub const MAX_LINE_BYTES: usize = 256 * 1024;
/// Most control points in one JSON NURBS (it is split into pieces of at most
/// `MAX_CTRL` for the interpolator).
pub const MAX_BLOCK_CTRL: usize = 4096;
/// Control points per piece of a split NURBS.
pub const PIECE_CTRL: usize = MAX_CTRL;

/// One parsed request.
#[derive(Debug, Clone, PartialEq)]
pub enum Request {
    /// A motion block.
    Block(Box<JsonBlock>),
    /// Cycle start.
    Start,
    /// Feed hold.
    Hold,
    /// Leave a feed hold.
    Resume,
    /// Feed override (1 = 100 %).
    Override(f64),
    /// The program ends after the blocks sent so far.
    End,
    /// Stop on the path and flush.
    Abort,
    /// Report the status.
    Status,
    /// Authenticate (required when the server has a token).
    Auth(String),
    /// An empty line or a comment (`#` …): acknowledged, nothing else.
    Nothing,
}

/// A motion block as JSON. Exactly one of `line`, `arc`, `nurbs`. Its start
/// is the end of the previous block (or where the machine is).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JsonBlock {
    /// Id reported in the setpoints (default: a running count from 1).
    #[serde(default)]
    pub id: Option<u32>,
    /// Programmed feed, mm/min (as G-code `F`).
    pub feed: f64,
    /// A straight line.
    #[serde(default)]
    pub line: Option<JsonLine>,
    /// A circular arc or helix.
    #[serde(default)]
    pub arc: Option<JsonArc>,
    /// A rational NURBS (any number of control points up to [`MAX_BLOCK_CTRL`]).
    #[serde(default)]
    pub nurbs: Option<JsonNurbs>,
}

/// `{"end": [x, y, z]}`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JsonLine {
    /// End point, mm.
    pub end: [f64; 3],
}

/// Counter-clockwise about `axis` (pass `-axis` for clockwise).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JsonArc {
    /// End point, mm.
    pub end: [f64; 3],
    /// Centre, mm.
    pub centre: [f64; 3],
    /// Rotation axis (default +Z).
    #[serde(default = "default_axis")]
    pub axis: [f64; 3],
    /// Extra full turns.
    #[serde(default)]
    pub turns: u32,
}

fn default_axis() -> [f64; 3] {
    [0.0, 0.0, 1.0]
}

/// Degree, control points, optional weights (default all 1), knots.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JsonNurbs {
    /// Degree 1..=5.
    pub degree: usize,
    /// Control points, mm; the first must be the previous block's end.
    pub points: Vec<[f64; 3]>,
    /// Weights (positive), one per point.
    #[serde(default)]
    pub weights: Option<Vec<f64>>,
    /// Knot vector, `points + degree + 1` values, clamped.
    pub knots: Vec<f64>,
}

/// Parses one request line (without its newline).
pub fn parse(line: &str) -> Result<Request, String> {
    let t = line.trim();
    if t.is_empty() || t.starts_with('#') {
        return Ok(Request::Nothing);
    }
    if t.starts_with('{') {
        let b: JsonBlock =
            serde_json::from_str(t).map_err(|e| format!("invalid JSON block: {e}"))?;
        return Ok(Request::Block(Box::new(b)));
    }
    let mut words = t.split_whitespace();
    let cmd = words.next().unwrap_or_default().to_ascii_lowercase();
    let arg = words.next();
    if words.next().is_some() {
        return Err(format!("too many arguments to {cmd:?}"));
    }
    let no_arg = |r: Request| match arg {
        None => Ok(r),
        Some(a) => Err(format!("{cmd:?} takes no argument, got {a:?}")),
    };
    match cmd.as_str() {
        "start" => no_arg(Request::Start),
        "hold" => no_arg(Request::Hold),
        "resume" => no_arg(Request::Resume),
        "end" => no_arg(Request::End),
        "abort" => no_arg(Request::Abort),
        "status" => no_arg(Request::Status),
        "override" => {
            let a = arg.ok_or("override needs a value, e.g. `override 0.5`")?;
            let x: f64 = a
                .parse()
                .map_err(|_| format!("override value {a:?} is not a number"))?;
            Ok(Request::Override(x))
        }
        "auth" => Ok(Request::Auth(arg.ok_or("auth needs a token")?.to_owned())),
        _ => Err(format!(
            "unknown request {cmd:?} (expected a JSON block or one of start, hold, resume, \
             override, end, abort, status, auth)"
        )),
    }
}

fn vec3(p: [f64; 3]) -> Vec3 {
    Vec3::new(p[0], p[1], p[2])
}

fn finite3(p: &[f64; 3]) -> bool {
    p.iter().all(|c| c.is_finite())
}

impl JsonBlock {
    /// The interpolator blocks of this block starting at `start` (pieces of at
    /// most [`PIECE_CTRL`] control points for a NURBS), with id `id`.
    pub fn to_blocks(&self, start: [f64; 3], id: u32, join_tol: f64) -> Result<Vec<Block>, String> {
        if !(self.feed.is_finite() && self.feed > 0.0) {
            return Err(format!(
                "feed must be a positive number of mm/min, got {}",
                self.feed
            ));
        }
        let feed = self.feed / 60.0;
        let kinds = [
            self.line.is_some(),
            self.arc.is_some(),
            self.nurbs.is_some(),
        ];
        if kinds.iter().filter(|k| **k).count() != 1 {
            return Err("a block needs exactly one of \"line\", \"arc\", \"nurbs\"".into());
        }
        let s = vec3(start);
        if let Some(l) = &self.line {
            if !finite3(&l.end) {
                return Err("line.end is not finite".into());
            }
            let line = Line::new(s, vec3(l.end)).map_err(|e| format!("line: {e}"))?;
            return Ok(vec![Block::new(id, Path::Line(line), feed)]);
        }
        if let Some(a) = &self.arc {
            let arc = Arc::from_centre(s, vec3(a.end), vec3(a.centre), vec3(a.axis), a.turns)
                .map_err(|e| format!("arc: {e}"))?;
            return Ok(vec![Block::new(id, Path::Arc(arc), feed)]);
        }
        let n = self.nurbs.as_ref().ok_or("no geometry")?;
        if n.points.len() > MAX_BLOCK_CTRL {
            return Err(format!(
                "nurbs has {} control points, at most {MAX_BLOCK_CTRL} per block",
                n.points.len()
            ));
        }
        let first = n.points.first().ok_or("nurbs.points is empty")?;
        if !finite3(first) {
            return Err("nurbs.points[0] is not finite".into());
        }
        let gap = (vec3(*first) - s).norm();
        if !(gap <= join_tol) {
            return Err(format!(
                "nurbs starts {gap:.6} mm from the previous end {start:?} (tolerance {join_tol} mm)"
            ));
        }
        let ones;
        let weights = match &n.weights {
            Some(w) => w.as_slice(),
            None => {
                ones = vec![1.0; n.points.len()];
                ones.as_slice()
            }
        };
        let mut out = Vec::new();
        split_program_curve(n.degree, &n.points, weights, &n.knots, PIECE_CTRL, |c| {
            out.push(Block::new(id, Path::Nurbs(c), feed));
            Ok::<(), core::convert::Infallible>(())
        })
        .map_err(|e| format!("nurbs: {e}"))?;
        Ok(out)
    }
}

/// JSON of a block for the protocol (used by `send` and `demo` to stream
/// programs built in memory).
pub fn nurbs_json(
    id: u32,
    feed_mm_min: f64,
    degree: usize,
    points: &[[f64; 3]],
    weights: &[f64],
    knots: &[f64],
) -> String {
    serde_json::json!({
        "id": id,
        "feed": feed_mm_min,
        "nurbs": {"degree": degree, "points": points, "weights": weights, "knots": knots},
    })
    .to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn commands_parse_and_bad_lines_name_the_problem() {
        assert_eq!(parse("start"), Ok(Request::Start));
        assert_eq!(parse("  HOLD "), Ok(Request::Hold));
        assert_eq!(parse("override 0.5"), Ok(Request::Override(0.5)));
        assert_eq!(parse(""), Ok(Request::Nothing));
        assert_eq!(parse("# comment"), Ok(Request::Nothing));
        assert!(parse("override").unwrap_err().contains("needs a value"));
        assert!(parse("override x").unwrap_err().contains("not a number"));
        assert!(
            parse("start now")
                .unwrap_err()
                .contains("takes no argument")
        );
        assert!(parse("jump").unwrap_err().contains("unknown request"));
        assert!(parse("{\"feed\": 1").unwrap_err().contains("invalid JSON"));
        assert!(
            parse(r#"{"feed": 1, "line": {"end": [1,2,3]}, "colour": 1}"#)
                .unwrap_err()
                .contains("colour")
        );
    }

    #[test]
    fn blocks_convert_and_check_their_geometry() {
        let Request::Block(b) =
            parse(r#"{"id": 3, "feed": 600, "line": {"end": [10, 0, 0]}}"#).unwrap()
        else {
            panic!("not a block")
        };
        let bs = b.to_blocks([0.0; 3], 3, 1e-6).unwrap();
        assert_eq!(bs.len(), 1);
        assert_eq!(bs[0].feed, 10.0);
        assert!((bs[0].path.length() - 10.0).abs() < 1e-12);
        // Zero length, bad feed, two kinds.
        assert!(b.to_blocks([10.0, 0.0, 0.0], 3, 1e-6).is_err());
        let Request::Block(bad) = parse(r#"{"feed": -1, "line": {"end": [1, 0, 0]}}"#).unwrap()
        else {
            panic!()
        };
        assert!(
            bad.to_blocks([0.0; 3], 1, 1e-6)
                .unwrap_err()
                .contains("feed")
        );
        let Request::Block(two) =
            parse(r#"{"feed": 1, "line": {"end": [1, 0, 0]}, "arc": {"end": [1,0,0], "centre": [0,0,0]}}"#)
                .unwrap()
        else {
            panic!()
        };
        assert!(
            two.to_blocks([0.0; 3], 1, 1e-6)
                .unwrap_err()
                .contains("exactly one")
        );
    }

    #[test]
    fn a_long_nurbs_is_split_into_pieces_of_the_same_curve() {
        use interp_core::Curve;
        use interp_core::samples::butterfly::*;
        let line = nurbs_json(
            1,
            600.0,
            BUTTERFLY_DEGREE,
            &BUTTERFLY_POINTS,
            &BUTTERFLY_WEIGHTS,
            &BUTTERFLY_KNOTS,
        );
        let Request::Block(b) = parse(&line).unwrap() else {
            panic!()
        };
        let pieces = b.to_blocks(START, 1, 1e-6).unwrap();
        assert!(pieces.len() >= 2);
        for w in pieces.windows(2) {
            let gap = (w[0].path.end_point() - w[1].path.start_point()).norm();
            assert!(gap < 1e-9, "{gap}");
        }
        let end = pieces.last().unwrap().path.end_point();
        let want = vec3(BUTTERFLY_POINTS[50]);
        assert!((end - want).norm() < 1e-9);
        // Starting elsewhere is refused with the distance.
        assert!(
            b.to_blocks([0.0; 3], 1, 1e-6)
                .unwrap_err()
                .contains("starts")
        );
    }
}
