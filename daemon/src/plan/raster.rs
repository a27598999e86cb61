//! `interpd plan raster`: 3-axis raster finishing over an STL mesh by slicing
//! the offset triangle mesh (`planner::raster`, seed `001_…`).
//!
//! Writes G-code (`--out`) through the `gcode` emitter as it is made, path by
//! path (`gcode::Emit`; never the whole program in memory): for each polyline a rapid
//! across at the safe height, a rapid down to just above its start, a plunge
//! at the plunge feed, the cut at the feed, and a rapid retract straight up to
//! the safe height. `--json` prints a summary on stdout;
//! `--cl-json` dumps the CL polylines for the accuracy scripts
//! (`scripts/ocl_compare.py`).

use std::fs::File;
use std::io::{BufWriter, IsTerminal, Write};
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use planner::cutter::Cutter;
use planner::mesh::{TriMesh, WeldOptions};
use planner::raster::{RasterConfig, RasterPath, plan_raster_with_progress};
use serde::Serialize;

use planner::io::{Moves, PathWriter};

/// `G64 P` of a written raster program, mm: 1 µm, far below a finishing
/// pass's scallop and the CL path's own chord tolerance, yet enough for the
/// controller to run 17 µm moves at the feed instead of crawling through
/// each vertex.
pub const DEFAULT_BLEND_TOLERANCE: f64 = 0.001;

/// Options of `interpd plan raster`.
#[derive(Clone, Debug)]
pub struct RasterOptions {
    /// The part, binary or ASCII STL (mm).
    pub stl: PathBuf,
    /// Cutter: ball:D, flat:D or bull:D:r (D the diameter, mm).
    pub tool: Cutter,
    /// Distance between passes, mm.
    pub stepover: f64,
    /// Pass direction, degrees counter-clockwise from +X.
    pub angle: f64,
    /// Cut both ways (reverse every other pass).
    pub zigzag: bool,
    /// Chord tolerance of the CL polylines, mm.
    pub chord_tolerance: f64,
    /// G-code output file.
    pub out: Option<PathBuf>,
    /// Print a JSON summary on stdout instead of text.
    pub json: bool,
    /// Also write the CL polylines as JSON (for scripts/ocl_compare.py).
    pub cl_json: Option<PathBuf>,
    /// Safe height above the part's top for rapids, mm.
    pub clearance: f64,
    /// Cutting feed, mm/min.
    pub feed: f64,
    /// Plunge feed, mm/min.
    pub plunge_feed: f64,
    /// `G64 P` written at the program's start, mm: the controller may leave
    /// the polylines by this much to run their dense moves at speed (the
    /// moves are a few µm long). 0: no G64 (the controller's exact path).
    pub blend_tolerance: f64,
    /// Weld tolerance for the mesh's vertices, mm.
    pub weld_tolerance: f64,
    /// No progress bar.
    pub quiet: bool,
}

#[derive(Debug, Serialize)]
#[serde(rename_all = "kebab-case")]
struct Summary {
    stl: String,
    tool: String,
    config: RasterConfig,
    stats: planner::raster::RasterStats,
    passes: usize,
    polylines: usize,
    dropped_degenerate: usize,
    read_s: f64,
    plan_s: f64,
    safe_z: f64,
    out: Option<String>,
}

/// Refuses a flag out of its range (`crate::flags`): rapids cross at the
/// part's top plus `--clearance`, never below it; `--blend-tolerance` 0 is
/// no G64.
fn check_ranges(args: &RasterOptions) -> Result<()> {
    use crate::flags::{CLEARANCE, FEED, PASS_ANGLE, PLAN_TOLERANCE, PLAN_TOLERANCE_OR_ZERO, STEP};
    FEED.check("--feed", args.feed)?;
    FEED.check("--plunge-feed", args.plunge_feed)?;
    PLAN_TOLERANCE_OR_ZERO.check("--blend-tolerance", args.blend_tolerance)?;
    PLAN_TOLERANCE_OR_ZERO.check("--weld-tolerance", args.weld_tolerance)?;
    CLEARANCE.check("--clearance", args.clearance)?;
    STEP.check("--stepover", args.stepover)?;
    PASS_ANGLE.check("--angle", args.angle)?;
    PLAN_TOLERANCE.check("--chord-tolerance", args.chord_tolerance)?;
    Ok(())
}

/// Runs `interpd plan raster`.
pub fn main(args: &RasterOptions) -> Result<()> {
    check_ranges(args)?;
    let t0 = Instant::now();
    let mesh = TriMesh::from_stl_path(
        &args.stl,
        WeldOptions {
            weld_tolerance: args.weld_tolerance,
        },
    )
    .with_context(|| format!("reading mesh {}", args.stl.display()))?;
    let read_s = t0.elapsed().as_secs_f64();
    let (lo, hi) = mesh.bounds();
    let extent = [lo.x, lo.y, lo.z, hi.x, hi.y, hi.z]
        .iter()
        .fold(0.0f64, |m, c| m.max(c.abs()));
    let min_tol = planner::min_tolerance(extent);
    if !(args.chord_tolerance >= min_tol) {
        bail!(
            "--chord-tolerance {} mm is below what f64 resolves at this part's size \
             (coordinates up to {extent} mm): at least {min_tol:e} mm",
            args.chord_tolerance
        );
    }
    let config = RasterConfig {
        stepover: args.stepover,
        angle_deg: args.angle,
        zigzag: args.zigzag,
        chord_tolerance: args.chord_tolerance,
        ..RasterConfig::default()
    };
    let show = !args.quiet && !args.json && std::io::stderr().is_terminal();
    let bar = |done: usize, total: usize| {
        // Redraw about 50 times per run.
        if show && (done == total || done.is_multiple_of((total / 50).max(1))) {
            let filled = done * 40 / total.max(1);
            eprint!(
                "\r[{}{}] {done}/{total} passes",
                "#".repeat(filled),
                " ".repeat(40 - filled)
            );
            if done == total {
                eprintln!();
            }
        }
    };
    let t1 = Instant::now();
    let path = plan_raster_with_progress(&mesh, &args.tool, &config, &bar)
        .with_context(|| format!("planning the raster path over {}", args.stl.display()))?;
    let plan_s = t1.elapsed().as_secs_f64();
    let (_, hi) = mesh.bounds();
    let safe_z = hi.z + args.clearance;
    if let Some(out) = &args.out {
        let moves = Moves {
            safe_z,
            approach_clearance: APPROACH_CLEARANCE,
            feed: args.feed,
            plunge_feed: args.plunge_feed,
            blend_tolerance: (args.blend_tolerance > 0.0).then_some(args.blend_tolerance),
        };
        write_gcode(&path, out, &moves)
            .with_context(|| format!("writing G-code to {}", out.display()))?;
    }
    if let Some(out) = &args.cl_json {
        write_cl_json(&path, out).with_context(|| format!("writing {}", out.display()))?;
    }
    let summary = Summary {
        stl: args.stl.display().to_string(),
        tool: args.tool.to_string(),
        config,
        stats: path.stats,
        passes: path.passes.len(),
        polylines: path.passes.iter().map(|p| p.polylines.len()).sum(),
        dropped_degenerate: mesh.dropped_degenerate,
        read_s,
        plan_s,
        safe_z,
        out: args.out.as_ref().map(|p| p.display().to_string()),
    };
    if args.json {
        println!("{}", serde_json::to_string(&summary)?);
    } else {
        println!(
            "{} triangles, {} passes, {} CL points in {:.3} s (read {:.3} s)",
            summary.stats.triangles, summary.passes, summary.stats.points, plan_s, read_s
        );
    }
    Ok(())
}

/// How far above a polyline's first point the rapid descent stops before the
/// plunge at the plunge feed, mm. The tool may drop vertically onto a CL point
/// without gouging (the CL height is the lowest it can go there).
const APPROACH_CLEARANCE: f64 = 1.0;

/// Writes the path as G-code (a comment naming it, then `gcode::emit`'s
/// text) through the `gcode` emitter as it is made ([`PathWriter`] then
/// `gcode::Emit`, path by path): per polyline a rapid across at the safe
/// height, a rapid down to `APPROACH_CLEARANCE` above its first point, a
/// plunge at the plunge feed, G1 moves at the feed, and a rapid retract
/// straight up. Only one polyline's blocks and text are held at a time,
/// not the whole program (a dense path has millions of moves).
fn write_raster_gcode(path: &RasterPath, moves: &Moves, out: &mut impl Write) -> Result<()> {
    writeln!(
        out,
        "(interpd plan raster: {} stepover {} angle {})",
        path.cutter, path.config.stepover, path.config.angle_deg
    )?;
    let mut w = PathWriter::new(*moves);
    let mut e = gcode::Emit::default();
    for line in path.passes.iter().flat_map(|p| &p.polylines) {
        cut_polyline(&mut w, line);
        for b in w.drain() {
            e.block(&b.kind);
        }
        out.write_all(e.take().as_bytes())?;
    }
    for b in w.finish() {
        e.block(&b.kind);
    }
    out.write_all(e.take().as_bytes())?;
    Ok(())
}

/// One polyline of the path into `w`: in at its first point, a cut
/// through the rest, out (an empty one writes nothing).
fn cut_polyline(w: &mut PathWriter, line: &[planner::mesh::P3]) {
    let Some(first) = line.first() else { return };
    w.enter([first.x, first.y, first.z]);
    for q in &line[1..] {
        w.cut_to([q.x, q.y, q.z]);
    }
    w.leave();
}

fn write_gcode(path: &RasterPath, out: &PathBuf, moves: &Moves) -> Result<()> {
    let mut f = BufWriter::new(File::create(out)?);
    write_raster_gcode(path, moves, &mut f)?;
    f.flush()?;
    Ok(())
}

#[derive(Serialize)]
struct ClJson<'a> {
    tool: String,
    stepover: f64,
    angle_deg: f64,
    /// Per pass, per polyline, `[x, y, z]` points.
    passes: Vec<Vec<Vec<[f64; 3]>>>,
    #[serde(skip)]
    _p: std::marker::PhantomData<&'a ()>,
}

fn write_cl_json(path: &RasterPath, out: &PathBuf) -> Result<()> {
    let doc = ClJson {
        tool: path.cutter.to_string(),
        stepover: path.config.stepover,
        angle_deg: path.config.angle_deg,
        passes: path
            .passes
            .iter()
            .map(|p| {
                p.polylines
                    .iter()
                    .map(|l| l.iter().map(|q| [q.x, q.y, q.z]).collect())
                    .collect()
            })
            .collect(),
        _p: std::marker::PhantomData,
    };
    let mut f = BufWriter::new(File::create(out)?);
    serde_json::to_writer(&mut f, &doc)?;
    f.flush()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use gcode::BlockKind;
    use planner::mesh::P3;

    /// A small path over a step (floor, wall, top) with a gap, so passes
    /// have several polylines.
    fn sample_path() -> RasterPath {
        let p = P3::new;
        let quad = |a: P3, b: P3, c: P3, d: P3| [[a, b, c], [a, c, d]];
        let mut soup = Vec::new();
        soup.extend(quad(
            p(-10.0, -4.0, 0.0),
            p(0.0, -4.0, 0.0),
            p(0.0, 4.0, 0.0),
            p(-10.0, 4.0, 0.0),
        ));
        soup.extend(quad(
            p(0.0, -4.0, 0.0),
            p(0.0, -4.0, 3.0),
            p(0.0, 4.0, 3.0),
            p(0.0, 4.0, 0.0),
        ));
        soup.extend(quad(
            p(0.0, -4.0, 3.0),
            p(8.0, -4.0, 3.0),
            p(8.0, 4.0, 3.0),
            p(0.0, 4.0, 3.0),
        ));
        // A separate island 10 mm beyond, so each pass has two polylines.
        soup.extend(quad(
            p(18.0, -4.0, 1.0),
            p(24.0, -4.0, 1.0),
            p(24.0, 4.0, 1.0),
            p(18.0, 4.0, 1.0),
        ));
        let mesh = TriMesh::from_triangles(&soup, WeldOptions::default()).unwrap();
        let config = RasterConfig {
            stepover: 1.0,
            zigzag: true,
            ..RasterConfig::default()
        };
        planner::raster::plan_raster(&mesh, &"ball:4".parse().unwrap(), &config).unwrap()
    }

    /// The program built whole and emitted at once (what `plan raster`
    /// wrote before it streamed).
    fn whole_program_text(path: &RasterPath, moves: &Moves) -> String {
        let mut w = PathWriter::new(*moves);
        for line in path.passes.iter().flat_map(|p| &p.polylines) {
            cut_polyline(&mut w, line);
        }
        format!(
            "(interpd plan raster: {} stepover {} angle {})\n{}",
            path.cutter,
            path.config.stepover,
            path.config.angle_deg,
            gcode::emit(&w.into_program())
        )
    }

    #[test]
    fn gcode_parses_back_to_the_same_points_with_safe_retracts() {
        let path = sample_path();
        let moves = Moves {
            safe_z: 8.0,
            approach_clearance: APPROACH_CLEARANCE,
            feed: 1200.0,
            plunge_feed: 250.0,
            blend_tolerance: Some(0.001),
        };
        let mut text = Vec::new();
        write_raster_gcode(&path, &moves, &mut text).unwrap();
        let text = String::from_utf8(text).unwrap();
        // Written path by path, byte for byte the text of the whole
        // program emitted at once.
        assert_eq!(text, whole_program_text(&path, &moves));
        let program = gcode::parse(&text).expect("emitted G-code parses");
        let lines: Vec<&Vec<P3>> = path.passes.iter().flat_map(|p| &p.polylines).collect();
        assert!(lines.len() >= 2 * path.passes.len(), "expected gaps");
        // Feed moves, split at rapids, are exactly the polylines.
        let mut got: Vec<Vec<[f64; 3]>> = Vec::new();
        let mut cutting = false;
        let mut at = None::<[f64; 3]>;
        let mut blend_first = false;
        for b in &program.blocks {
            match &b.kind {
                BlockKind::Rapid(m) => {
                    // Sideways rapids only at the safe height; vertical ones
                    // never below the polyline start they lead to.
                    if m.start[0] != m.end[0] || m.start[1] != m.end[1] {
                        assert!(
                            at.is_none() || (m.start[2] == 8.0 && m.end[2] == 8.0),
                            "line {}: sideways rapid below the safe height",
                            b.line
                        );
                    }
                    cutting = false;
                    at = Some(m.end);
                }
                BlockKind::Linear(m) => {
                    let gcode::Feed::PerMinute(f) = m.feed else {
                        panic!("feed mode")
                    };
                    if !cutting {
                        // The plunge: straight down at the plunge feed.
                        assert_eq!(f, 250.0);
                        assert_eq!((m.start[0], m.start[1]), (m.end[0], m.end[1]));
                        assert!(m.start[2] > m.end[2]);
                        got.push(vec![m.end]);
                        cutting = true;
                    } else {
                        assert_eq!(f, 1200.0);
                        got.last_mut().unwrap().push(m.end);
                    }
                    at = Some(m.end);
                }
                BlockKind::ProgramEnd => {}
                // The G64 P of `moves`, first: dense moves run at speed.
                BlockKind::PathControl(gcode::PathControl::Blend {
                    path_tolerance: Some(p),
                    ..
                }) if at.is_none() && *p == 0.001 => blend_first = true,
                other => panic!("unexpected block {other:?}"),
            }
        }
        assert!(blend_first, "G64 P0.001 before the first move");
        assert_eq!(got.len(), lines.len());
        for (g, l) in got.iter().zip(&lines) {
            let want: Vec<[f64; 3]> = l.iter().map(|q| [q.x, q.y, q.z]).collect();
            // Shortest round-trip numbers: bit for bit.
            assert_eq!(g, &want);
        }
        assert!(matches!(
            program.blocks.last().map(|b| &b.kind),
            Some(BlockKind::ProgramEnd)
        ));
    }
}
