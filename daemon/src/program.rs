//! The program loader: a program file as the JSON block form that the
//! control plane, `simulate` and the traces all take.
//!
//! One loader and one rapid policy for every command: `send` and `simulate`
//! turn the same file into the same blocks. G-code (`.ngc`, `.nc`) is parsed
//! with `gcode::parse_from` from where the machine is when the program is
//! accepted (`send` asks the server, `simulate` starts at the origin), and
//! its rapids (G0) run at the machine's path-speed limit (`max-path-speed`);
//! `.json` is a whole program (`{"start": …, "blocks": […]}`); anything else
//! is JSON blocks, one per line (blank lines and `#` comments skipped).

use std::path::Path;

use anyhow::{Context, Result, bail};
use traces::blocks::{InputBlock, PathSpec, Program};

/// How a program file becomes blocks.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LoadOptions {
    /// Where the machine is when the program starts (`None`: the origin, or
    /// a JSON program's own `start`).
    pub start: Option<[f64; 3]>,
    /// Speed of rapid moves (G0), mm/s: the machine's `max-path-speed`.
    pub rapid_speed: f64,
}

/// Reads a program file (see the module doc).
pub fn load(path: &Path, opts: &LoadOptions) -> Result<Program> {
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    if ext.eq_ignore_ascii_case("ngc") || ext.eq_ignore_ascii_case("nc") {
        let start = opts.start.unwrap_or([0.0; 3]);
        let g = gcode::parse_from(&text, start)
            .with_context(|| format!("parsing {}", path.display()))?;
        let mut p = program_from_gcode(&g, opts.rapid_speed)
            .with_context(|| format!("converting {}", path.display()))?;
        if opts.start.is_some() {
            p.start = Some(start);
        }
        return Ok(p);
    }
    if ext.eq_ignore_ascii_case("json") {
        let mut p: Program = serde_json::from_str(&text)
            .with_context(|| format!("parsing {} as a JSON program", path.display()))?;
        if opts.start.is_some() {
            p.start = opts.start;
        }
        return Ok(p);
    }
    let mut blocks = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let b: InputBlock = serde_json::from_str(line)
            .with_context(|| format!("{} line {}: invalid JSON block", path.display(), i + 1))?;
        blocks.push(b);
    }
    Ok(Program {
        start: opts.start,
        blocks,
    })
}

/// A parsed G-code program in the JSON block form (so that traces record it,
/// and replay re-runs it, without the G-code text). Moves of zero length are
/// dropped and blocks without a path skipped, as `gcode::Program::to_core_blocks` does.
pub fn program_from_gcode(g: &gcode::Program, rapid_speed: f64) -> Result<Program> {
    use gcode::{BlockKind, Feed};
    let per_minute = |f: Feed, line: u32| match f {
        Feed::PerMinute(v) => Ok(v),
        Feed::InverseTime(_) => {
            bail!("line {line}: G93 inverse-time feed is not supported by simulate yet")
        }
    };
    let mut start: Option<[f64; 3]> = None;
    let mut blocks = Vec::new();
    let mut blending = traces::blocks::BlendingSpec::ExactPath;
    for b in &g.blocks {
        if let BlockKind::PathControl(mode) = &b.kind {
            blending = gcode::core_blending(*mode).into();
            continue;
        }
        // Rotary axes and tool-centre-point control are parsed, not yet
        // interpolated: refuse rather than run the program as three-axis.
        if !b
            .kind
            .orientation()
            .is_none_or(gcode::Orientation::is_fixed)
        {
            return Err(gcode::ConvertError::FiveAxis { line: b.line }.into());
        }
        let (from, block) = match &b.kind {
            BlockKind::Rapid(m) => (
                m.start,
                InputBlock {
                    source_line: Some(b.line),
                    feed: rapid_speed * 60.0,
                    mrr: None,
                    blending,
                    path: PathSpec::Line { end: m.end },
                },
            ),
            BlockKind::Linear(m) => (
                m.start,
                InputBlock {
                    source_line: Some(b.line),
                    feed: per_minute(m.feed, b.line)?,
                    mrr: None,
                    blending,
                    path: PathSpec::Line { end: m.end },
                },
            ),
            BlockKind::Arc(m) => (
                m.start,
                InputBlock {
                    source_line: Some(b.line),
                    feed: per_minute(m.feed, b.line)?,
                    mrr: None,
                    blending,
                    path: PathSpec::Arc {
                        end: m.end,
                        centre: m.centre,
                        axis: m.plane.normal(),
                        clockwise: m.clockwise,
                        turns: m.extra_turns,
                    },
                },
            ),
            BlockKind::Nurbs(m) => (
                m.points.first().copied().unwrap_or_default(),
                InputBlock {
                    source_line: Some(m.first_line),
                    feed: per_minute(m.feed, b.line)?,
                    mrr: None,
                    blending,
                    path: PathSpec::Nurbs {
                        degree: m.degree,
                        points: m.points.clone(),
                        weights: Some(m.weights.clone()),
                        knots: m.knots.clone(),
                    },
                },
            ),
            _ => continue,
        };
        if let PathSpec::Line { end } = &block.path
            && *end == from
        {
            continue; // zero length: moves nothing
        }
        start.get_or_insert(from);
        blocks.push(block);
    }
    Ok(Program { start, blocks })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn five_axis_moves_are_refused_naming_the_line_not_run_as_three_axis() {
        let g = gcode::parse("G21 G90\nG1 X10 F600\nG1 X20 A15\n").unwrap();
        let err = program_from_gcode(&g, 100.0).unwrap_err().to_string();
        assert!(
            err.contains("line 3: five-axis motion is not interpolated yet"),
            "{err}"
        );
        let g = gcode::parse("G21 G90\nG1 X10 F600\nG1 X20\n").unwrap();
        assert_eq!(program_from_gcode(&g, 100.0).unwrap().blocks.len(), 2);
    }
}
