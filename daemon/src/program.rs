//! The program loader: a program file as the JSON block form that the
//! control plane, `simulate` and the traces all take.
//!
//! One loader and one rapid policy for every command: `send` and `simulate`
//! turn the same file into the same blocks. G-code (`.ngc`, `.nc`) is parsed
//! with `gcode::parse_from` from where the machine is when the program is
//! accepted (`send` asks the server, `simulate` starts at the origin) and
//! converted by the one conversion (`gcode::Program::for_each_move`, through
//! `traces::Program::from_gcode`); its rapids (G0) run at the machine's
//! path-speed limit (`max-path-speed`);
//! `.json` is a whole program (`{"start": …, "blocks": […]}`); anything else
//! is JSON blocks, one per line (blank lines and `#` comments skipped).

use std::path::Path;

use anyhow::{Context, Result};
use traces::blocks::{InputBlock, Program};

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
        let core = gcode::CoreOptions {
            rapid_speed: opts.rapid_speed,
            machine: None,
        };
        let mut p = Program::from_gcode(&g, &core)
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

#[cfg(test)]
mod tests {
    use super::*;

    fn write(name: &str, text: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("interpd-program-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p
    }

    #[test]
    fn five_axis_moves_are_refused_naming_the_line_not_run_as_three_axis() {
        let opts = LoadOptions {
            start: None,
            rapid_speed: 100.0,
        };
        let p = write("five.ngc", "G21 G90\nG1 X10 F600\nG1 X20 A15\n");
        let err = format!("{:#}", load(&p, &opts).unwrap_err());
        assert!(err.contains("line 3: five-axis motion"), "{err}");
        let p = write("three.ngc", "G21 G90\nG1 X10 F600\nG1 X20\n");
        assert_eq!(load(&p, &opts).unwrap().blocks.len(), 2);
    }

    /// The loader is the one conversion (`gcode::Program::for_each_move`):
    /// G93 inverse time is a feed like any other, rapids run at the
    /// machine's path-speed limit, a move to where the machine is moves
    /// nothing.
    #[test]
    fn g93_rapids_and_zero_length_moves_follow_the_one_conversion() {
        let opts = LoadOptions {
            start: Some([20.0, 20.0, 0.0]),
            rapid_speed: 100.0,
        };
        let p = write(
            "g93.ngc",
            "G21 G90\nG1 X20 Y20 F600\nG93 G1 X30 F2\nG94 G0 X0\n",
        );
        let prog = load(&p, &opts).unwrap();
        assert_eq!(prog.start, Some([20.0, 20.0, 0.0]));
        let feeds: Vec<f64> = prog.blocks.iter().map(|b| b.feed).collect();
        // 10 mm in half a minute: 20 mm/min; the rapid at 100 mm/s.
        assert_eq!(feeds, [20.0, 6000.0]);
    }
}
