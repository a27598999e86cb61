//! The control plane's line protocol (see `docs/daemon.md`): one request per
//! line, exactly one reply line per request.
//!
//! Requests: a JSON block (`{"feed": …, "kind": "line"|"arc"|"nurbs", …}`,
//! the JSON block form of `traces`, see `docs/traces.md`), or one of
//! `start`, `hold`, `resume`, `override X`, `end`, `abort`, `status`,
//! `auth TOKEN`. Replies: `ok …`, `status {json}` or `err LINE PROBLEM`.

use interp_core::Block;
use interp_core::nurbs::MAX_CTRL;
use traces::{InputBlock, PathSpec, Program};

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
    /// A motion block (the `traces` JSON block form).
    Block(Box<InputBlock>),
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

/// Parses one request line (without its newline).
pub fn parse(line: &str) -> Result<Request, String> {
    let t = line.trim();
    if t.is_empty() || t.starts_with('#') {
        return Ok(Request::Nothing);
    }
    if t.starts_with('{') {
        let b: InputBlock =
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

/// Expands one JSON block (the `traces` JSON block form) that starts at
/// `start` into interpolator blocks with ids from `first_id` (a NURBS is split
/// into pieces of at most [`PIECE_CTRL`] control points, exactly as
/// `interpd simulate` and `interpd replay` do). Also returns the segment info
/// recorded with the block.
pub fn expand(
    block: &InputBlock,
    start: [f64; 3],
    first_id: u32,
) -> Result<(Vec<Block>, Vec<traces::messages::SegmentInfo>), String> {
    if let PathSpec::Nurbs { points, .. } = &block.path
        && points.len() > MAX_BLOCK_CTRL
    {
        return Err(format!(
            "nurbs has {} control points, at most {MAX_BLOCK_CTRL} per block",
            points.len()
        ));
    }
    let program = Program {
        start: Some(start),
        blocks: vec![block.clone()],
    };
    let mut e = program
        .expand(PIECE_CTRL, first_id)
        .map_err(|e| e.kind.to_string())?;
    let b = e.blocks.pop().ok_or("the block expanded to nothing")?;
    Ok((b.segments, b.info))
}

/// The JSON line of a block.
pub fn block_json(b: &InputBlock) -> String {
    serde_json::to_string(b).unwrap_or_default()
}

/// The JSON line of a NURBS block (used by `demo` and `jitter`).
pub fn nurbs_json(
    feed_mm_min: f64,
    degree: usize,
    points: &[[f64; 3]],
    weights: &[f64],
    knots: &[f64],
) -> String {
    block_json(&InputBlock {
        source_line: None,
        feed: feed_mm_min,
        mrr: None,
        blending: Default::default(),
        path: PathSpec::Nurbs {
            degree,
            points: points.to_vec(),
            weights: Some(weights.to_vec()),
            knots: knots.to_vec(),
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn block(line: &str) -> InputBlock {
        match parse(line) {
            Ok(Request::Block(b)) => *b,
            other => panic!("not a block: {other:?}"),
        }
    }

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
            parse(r#"{"feed": 1, "kind": "spline", "end": [1,2,3]}"#)
                .unwrap_err()
                .contains("spline")
        );
    }

    #[test]
    fn blocks_expand_and_check_their_geometry() {
        let b = block(r#"{"feed": 600, "kind": "line", "end": [10, 0, 0]}"#);
        let (bs, info) = expand(&b, [0.0; 3], 3).unwrap();
        assert_eq!(bs.len(), 1);
        assert_eq!((bs[0].id, info[0].block_id), (3, 3));
        assert_eq!(bs[0].feed, 10.0);
        assert!((bs[0].path.length() - 10.0).abs() < 1e-12);
        // Zero length, bad feed.
        assert!(expand(&b, [10.0, 0.0, 0.0], 1).is_err());
        let bad = block(r#"{"feed": -1, "kind": "line", "end": [1, 0, 0]}"#);
        assert!(expand(&bad, [0.0; 3], 1).unwrap_err().contains("feed"));
    }

    #[test]
    fn a_long_nurbs_is_split_into_pieces_of_the_same_curve() {
        use interp_core::samples::butterfly::*;
        use interp_core::{Curve, Vec3};
        let line = nurbs_json(
            600.0,
            BUTTERFLY_DEGREE,
            &BUTTERFLY_POINTS,
            &BUTTERFLY_WEIGHTS,
            &BUTTERFLY_KNOTS,
        );
        let b = block(&line);
        let (pieces, _) = expand(&b, START, 1).unwrap();
        assert!(pieces.len() >= 2);
        for (k, w) in pieces.windows(2).enumerate() {
            let gap = (w[0].path.end_point() - w[1].path.start_point()).norm();
            assert!(gap < 1e-9, "{gap}");
            assert_eq!(w[1].id, w[0].id + 1, "piece {k}");
        }
        let end = pieces.last().unwrap().path.end_point();
        let want = Vec3::from(BUTTERFLY_POINTS[50]);
        assert!((end - want).norm() < 1e-9);
        // Starting elsewhere is refused.
        assert!(expand(&b, [0.0; 3], 1).is_err());
    }
}
