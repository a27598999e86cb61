//! The control plane's line protocol (see `docs/daemon.md`): one request per
//! line, exactly one reply line per request.
//!
//! Requests ([`Request`]): a JSON block (`{"feed": …, "kind":
//! "line"|"arc"|"nurbs", …}`, the JSON block form of `traces`, see
//! `docs/traces.md`), or one of `begin`, `start`, `hold`, `resume`,
//! `override X`, `end`, `abort`, `status`, `auth TOKEN`. Replies
//! ([`Reply`]): `ok …`, `status {json}` or `err LINE PROBLEM`. Both parse
//! from their line and print back to it.

use interp_core::nurbs::MAX_CTRL;
use interp_core::{Block, InterpConfig};
use traces::{InputBlock, PathSpec, Pipeline};

/// Longest request line, bytes (newline excluded). Longer lines are refused
/// with an error and skipped up to their newline. It fits the largest block
/// the protocol takes: [`MAX_BLOCK_CTRL`] control points, weights and knots
/// at full precision (shortest round-trip floats of up to 24 characters:
/// about 85 bytes per control point, 340 KiB in all) with room to spare.
pub const MAX_LINE_BYTES: usize = 1024 * 1024;
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
    /// Claim a new program for this connection; the reply names it and
    /// where it starts (where the machine will be when it runs).
    Begin,
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
        "begin" => no_arg(Request::Begin),
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
            "unknown request {cmd:?} (expected a JSON block or one of begin, start, hold, \
             resume, override, end, abort, status, auth)"
        )),
    }
}

impl core::fmt::Display for Request {
    /// The request's line (without its newline); [`parse`] reads it back.
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Request::Block(b) => f.write_str(&block_json(b)),
            Request::Begin => f.write_str("begin"),
            Request::Start => f.write_str("start"),
            Request::Hold => f.write_str("hold"),
            Request::Resume => f.write_str("resume"),
            Request::Override(x) => write!(f, "override {x}"),
            Request::End => f.write_str("end"),
            Request::Abort => f.write_str("abort"),
            Request::Status => f.write_str("status"),
            Request::Auth(t) => write!(f, "auth {t}"),
            Request::Nothing => Ok(()),
        }
    }
}

/// One reply line.
#[derive(Debug, Clone, PartialEq)]
pub enum Reply {
    /// `ok`: an empty line or a comment.
    Ok,
    /// `ok block K segments A..=B`: the K-th block of the program was
    /// accepted, and interpolator segments A to B were queued meanwhile
    /// (`B = A - 1`: none; the program's `G64 P` stage holds blocks back
    /// until it can decide them, and releases the rest at `end`).
    Block {
        /// Position of the block in its program, from 1.
        index: u32,
        /// First segment id.
        first: u32,
        /// Last segment id.
        last: u32,
    },
    /// `ok begin program N at X Y Z A B C`: program N belongs to this
    /// connection and starts with the machine's joints there (a reply with
    /// X Y Z only, from an older server, reads as A B C = 0).
    Begin {
        /// The program's number.
        program: u32,
        /// Where it starts: the joints X Y Z (mm) A B C (degrees).
        at: [f64; 6],
    },
    /// `ok start`.
    Start,
    /// `ok hold`.
    Hold,
    /// `ok resume`.
    Resume,
    /// `ok override X`.
    Override(f64),
    /// `ok end`.
    End,
    /// `ok abort`: the machine is at rest, the queue flushed.
    Abort,
    /// `ok auth`.
    Auth,
    /// `status {json}`.
    Status(Box<crate::service::control::StatusReply>),
    /// `err LINE PROBLEM`: request LINE of the connection was refused.
    Err {
        /// The request's line number on its connection, from 1.
        line: u64,
        /// What is wrong.
        problem: String,
    },
}

impl Reply {
    /// Whether the request was carried out.
    pub fn is_ok(&self) -> bool {
        !matches!(self, Reply::Err { .. })
    }
}

impl core::fmt::Display for Reply {
    /// The reply's line (without its newline); [`Reply::parse`] reads it back.
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Reply::Ok => f.write_str("ok"),
            Reply::Block { index, first, last } => {
                write!(f, "ok block {index} segments {first}..={last}")
            }
            Reply::Begin { program, at } => {
                write!(
                    f,
                    "ok begin program {program} at {} {} {} {} {} {}",
                    at[0], at[1], at[2], at[3], at[4], at[5]
                )
            }
            Reply::Start => f.write_str("ok start"),
            Reply::Hold => f.write_str("ok hold"),
            Reply::Resume => f.write_str("ok resume"),
            Reply::Override(x) => write!(f, "ok override {x}"),
            Reply::End => f.write_str("ok end"),
            Reply::Abort => f.write_str("ok abort"),
            Reply::Auth => f.write_str("ok auth"),
            Reply::Status(s) => write!(
                f,
                "status {}",
                serde_json::to_string(s).map_err(|_| core::fmt::Error)?
            ),
            Reply::Err { line, problem } => write!(f, "err {line} {problem}"),
        }
    }
}

impl Reply {
    /// Parses one reply line (without its newline).
    pub fn parse(line: &str) -> Result<Reply, String> {
        let bad = || format!("unexpected reply {line:?}");
        if let Some(json) = line.strip_prefix("status ") {
            return serde_json::from_str(json)
                .map(|s| Reply::Status(Box::new(s)))
                .map_err(|e| format!("reading the status {json:?}: {e}"));
        }
        if let Some(rest) = line.strip_prefix("err ") {
            let (n, problem) = rest.split_once(' ').unwrap_or((rest, ""));
            let line = n.parse().map_err(|_| bad())?;
            return Ok(Reply::Err {
                line,
                problem: problem.to_owned(),
            });
        }
        let words: Vec<&str> = line.split_whitespace().collect();
        let num = |w: &str| w.parse::<f64>().map_err(|_| bad());
        Ok(match words.as_slice() {
            ["ok"] => Reply::Ok,
            ["ok", "start"] => Reply::Start,
            ["ok", "hold"] => Reply::Hold,
            ["ok", "resume"] => Reply::Resume,
            ["ok", "end"] => Reply::End,
            ["ok", "abort"] => Reply::Abort,
            ["ok", "auth"] => Reply::Auth,
            ["ok", "override", x] => Reply::Override(num(x)?),
            ["ok", "block", k, "segments", range] => {
                let (a, b) = range.split_once("..=").ok_or_else(bad)?;
                Reply::Block {
                    index: k.parse().map_err(|_| bad())?,
                    first: a.parse().map_err(|_| bad())?,
                    last: b.parse().map_err(|_| bad())?,
                }
            }
            ["ok", "begin", "program", n, "at", x, y, z] => Reply::Begin {
                program: n.parse().map_err(|_| bad())?,
                at: [num(x)?, num(y)?, num(z)?, 0.0, 0.0, 0.0],
            },
            ["ok", "begin", "program", n, "at", x, y, z, a, b, c] => Reply::Begin {
                program: n.parse().map_err(|_| bad())?,
                at: [num(x)?, num(y)?, num(z)?, num(a)?, num(b)?, num(c)?],
            },
            _ => return Err(bad()),
        })
    }
}

/// Expands one JSON block (the `traces` JSON block form) as the next block
/// of the program `pipeline` carries (a NURBS is split into pieces of at
/// most [`PIECE_CTRL`] control points, and the pieces go through the `G64 P`
/// stage, exactly as `interpd simulate` and `interpd replay` do). Returns
/// the interpolator blocks the stage released (maybe none yet: it holds
/// blocks back until it can decide them) and the block's segment info, as
/// recorded with it.
pub fn expand(
    block: &InputBlock,
    pipeline: &mut Pipeline,
) -> Result<(Vec<Block>, Vec<traces::messages::SegmentInfo>), String> {
    if let PathSpec::Nurbs { points, .. } = &block.path
        && points.len() > MAX_BLOCK_CTRL
    {
        return Err(format!(
            "nurbs has {} control points, at most {MAX_BLOCK_CTRL} per block",
            points.len()
        ));
    }
    let mut released = Vec::new();
    let b = pipeline
        .push(block, &mut released)
        .map_err(|e| e.kind.to_string())?;
    Ok((released, b.info))
}

/// The interpolator blocks of a one-block program at `start` under `cfg`,
/// with ids from `first_id` ([`expand`], then the program's end), and the
/// block's segment info.
pub fn expand_from(
    block: &InputBlock,
    start: [f64; 3],
    first_id: u32,
    cfg: &InterpConfig,
) -> Result<(Vec<Block>, Vec<traces::messages::SegmentInfo>), String> {
    let mut pipeline = Pipeline::new(start, false, first_id, PIECE_CTRL, cfg)
        .map_err(|e| format!("config: {e}"))?;
    let (mut blocks, info) = expand(block, &mut pipeline)?;
    blocks.extend(pipeline.finish());
    Ok((blocks, info))
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
        start: None,
        orientation: None,
        path: PathSpec::Nurbs {
            degree,
            points: points.to_vec(),
            weights: Some(weights.to_vec()),
            knots: knots.to_vec(),
            rotary: None,
            tool_axes: None,
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg() -> InterpConfig {
        InterpConfig::default()
    }

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
    fn requests_and_replies_print_and_parse_back() {
        for line in [
            "begin",
            "start",
            "hold",
            "resume",
            "override 0.25",
            "end",
            "abort",
            "status",
            "auth s3cret",
            r#"{"feed":600.0,"kind":"line","end":[10.0,0.0,0.0]}"#,
        ] {
            let r = parse(line).unwrap();
            assert_eq!(r.to_string(), line);
            assert_eq!(parse(&r.to_string()), Ok(r));
        }
        for r in [
            Reply::Ok,
            Reply::Block {
                index: 3,
                first: 4,
                last: 5,
            },
            Reply::Begin {
                program: 7,
                at: [20.0, -0.1, 1e-17, 0.0, -30.5, 1e300],
            },
            Reply::Start,
            Reply::Hold,
            Reply::Resume,
            Reply::Override(1.5),
            Reply::End,
            Reply::Abort,
            Reply::Auth,
            Reply::Err {
                line: 12,
                problem: "busy: program 3 belongs to connection 1 (tcp 127.0.0.1:4)".into(),
            },
        ] {
            let line = r.to_string();
            assert_eq!(Reply::parse(&line), Ok(r), "{line}");
        }
        assert_eq!(
            Reply::Block {
                index: 1,
                first: 1,
                last: 1
            }
            .to_string(),
            "ok block 1 segments 1..=1"
        );
        assert!(Reply::parse("ok sure").is_err());
        assert!(Reply::parse("err x y").is_err());
        // A begin with X Y Z only (an older server): the rotary axes at 0.
        assert_eq!(
            Reply::parse("ok begin program 2 at 1 2 3"),
            Ok(Reply::Begin {
                program: 2,
                at: [1.0, 2.0, 3.0, 0.0, 0.0, 0.0]
            })
        );
        assert!(Reply::parse("ok begin program 2 at 1 2 3 4").is_err());
        // A five-axis block, its frame's start and its tool axis, both ways.
        let line = r#"{"feed":600.0,"start":[1.0,2.0,-50.0],"orientation":{"tool-axis":{"start":[0.0,0.0,1.0],"end":[0.5,0.0,0.866]}},"kind":"line","end":[10.0,0.0,0.0]}"#;
        let r = parse(line).unwrap();
        assert_eq!(r.to_string(), line);
    }

    #[test]
    fn blocks_expand_and_check_their_geometry() {
        let b = block(r#"{"feed": 600, "kind": "line", "end": [10, 0, 0]}"#);
        let (bs, info) = expand_from(&b, [0.0; 3], 3, &cfg()).unwrap();
        assert_eq!(bs.len(), 1);
        assert_eq!((bs[0].id, info[0].block_id), (3, 3));
        assert_eq!(bs[0].feed, 10.0);
        assert!((bs[0].path.length() - 10.0).abs() < 1e-12);
        // Zero length, bad feed.
        assert!(expand_from(&b, [10.0, 0.0, 0.0], 1, &cfg()).is_err());
        let bad = block(r#"{"feed": -1, "kind": "line", "end": [1, 0, 0]}"#);
        assert!(
            expand_from(&bad, [0.0; 3], 1, &cfg())
                .unwrap_err()
                .contains("feed")
        );
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
        let (pieces, _) = expand_from(&b, START, 1, &cfg()).unwrap();
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
        assert!(expand_from(&b, [0.0; 3], 1, &cfg()).is_err());
    }
}
