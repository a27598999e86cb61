//! The program loader: a program file as the JSON block form that the
//! control plane, `simulate` and the traces all take.
//!
//! One loader and one rapid policy for every command: `send` and `simulate`
//! turn the same file into the same blocks. G-code (`.ngc`, `.nc`) is parsed
//! with `gcode::parse_from_axes` from where the machine's joints are when
//! the program is accepted (`send` asks the server, `simulate` starts at
//! the origin) and converted by the one conversion
//! (`gcode::Program::for_each_move`, through `traces::Program::from_gcode`)
//! with the run's `gcode::CoreOptions`: rapids (G0) at the machine's
//! path-speed limit (`max-path-speed`), the five-axis machine of the run
//! for tool-centre-point control;
//! `.json` is a whole program (`{"start": …, "blocks": […]}`); anything else
//! is JSON blocks, one per line (blank lines and `#` comments skipped).

use std::path::Path;

use anyhow::{Context, Result};
use traces::blocks::{InputBlock, Program};

/// How a program file becomes blocks.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LoadOptions {
    /// Where the machine's joints X Y Z A B C are when the program starts
    /// (`None`: the origin, or a JSON program's own `start`).
    pub start: Option<[f64; 6]>,
    /// The conversion's options: rapids at the machine's `max-path-speed`,
    /// its five-axis machine (`gcode::CoreOptions::for_config`).
    pub core: gcode::CoreOptions,
}

/// Reads a program file (see the module doc).
pub fn load(path: &Path, opts: &LoadOptions) -> Result<Program> {
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    let xyz = opts.start.map(|q| [q[0], q[1], q[2]]);
    let abc = opts.start.map(|q| [q[3], q[4], q[5]]);
    if ext.eq_ignore_ascii_case("ngc") || ext.eq_ignore_ascii_case("nc") {
        let start = opts.start.unwrap_or([0.0; 6]);
        let g = gcode::parse_from_axes(&text, start)
            .with_context(|| format!("parsing {}", path.display()))?;
        return Program::from_gcode(&g, &opts.core, start)
            .with_context(|| format!("converting {}", path.display()));
    }
    if ext.eq_ignore_ascii_case("json") {
        let mut p: Program = serde_json::from_str(&text)
            .with_context(|| format!("parsing {} as a JSON program", path.display()))?;
        if opts.start.is_some() {
            p.start = xyz;
            p.rotary = abc;
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
        start: xyz,
        rotary: abc,
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

    fn opts(start: Option<[f64; 6]>) -> LoadOptions {
        LoadOptions {
            start,
            core: gcode::CoreOptions {
                rapid_speed: 100.0,
                machine: None,
            },
        }
    }

    /// Rotary axes are converted from where the machine's stand, and carried.
    #[test]
    fn five_axis_moves_are_carried_from_the_machines_joints() {
        let p = write("five.ngc", "G21 G90\nG1 X10 F600\nG1 X20 A15\n");
        let prog = load(&p, &opts(Some([0.0, 0.0, 0.0, 5.0, 0.0, -3.0]))).unwrap();
        assert_eq!(prog.rotary, Some([5.0, 0.0, -3.0]));
        assert_eq!(prog.blocks[0].orientation, None);
        assert_eq!(
            prog.blocks[1].orientation,
            Some(traces::blocks::OrientationSpec::Axes {
                start: [5.0, 0.0, -3.0],
                end: [15.0, 0.0, -3.0]
            })
        );
        // Under tool-centre-point control the conversion needs the machine.
        let p = write("tcp.ngc", "G21 G90\nG43.5\nG1 X10 I0 J0 K1 F600\n");
        let err = format!("{:#}", load(&p, &opts(None)).unwrap_err());
        assert!(err.contains("line 3: tool-centre-point control"), "{err}");
    }

    /// The loader is the one conversion (`gcode::Program::for_each_move`):
    /// G93 inverse time is a feed like any other, rapids run at the
    /// machine's path-speed limit, a move to where the machine is moves
    /// nothing.
    #[test]
    fn g93_rapids_and_zero_length_moves_follow_the_one_conversion() {
        let opts = opts(Some([20.0, 20.0, 0.0, 0.0, 0.0, 0.0]));
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
