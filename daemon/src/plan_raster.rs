//! `interpd plan raster`: 3-axis raster finishing over an STL mesh by slicing
//! the offset triangle mesh (`planner::raster`, seed `001_…`).
//!
//! Writes G-code (`--out`): for each polyline a rapid to the safe height, a
//! rapid over its start, a plunge at the plunge feed, the cut at the feed, and
//! a rapid retract to the safe height. `--json` prints a summary on stdout;
//! `--cl-json` dumps the CL polylines for the accuracy scripts
//! (`scripts/ocl_compare.py`).

use std::fs::File;
use std::io::{BufWriter, IsTerminal, Write};
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result};
use planner::cutter::Cutter;
use planner::mesh::{TriMesh, WeldOptions};
use planner::raster::{RasterConfig, RasterPath, plan_raster_with_progress};
use serde::Serialize;

/// Options of `interpd plan raster`.
#[derive(Clone, Debug, clap::Args)]
pub struct RasterArgs {
    /// The part, binary or ASCII STL (mm).
    #[arg(long)]
    pub stl: PathBuf,
    /// Cutter: ball:D, flat:D or bull:D:r (D the diameter, mm).
    #[arg(long)]
    pub tool: Cutter,
    /// Distance between passes, mm.
    #[arg(long, default_value_t = 0.5)]
    pub stepover: f64,
    /// Pass direction, degrees counter-clockwise from +X.
    #[arg(long, default_value_t = 0.0)]
    pub angle: f64,
    /// Cut both ways (reverse every other pass).
    #[arg(long)]
    pub zigzag: bool,
    /// Chord tolerance of the CL polylines, mm.
    #[arg(long, default_value_t = RasterConfig::default().chord_tolerance)]
    pub chord_tolerance: f64,
    /// G-code output file.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Print a JSON summary on stdout instead of text.
    #[arg(long)]
    pub json: bool,
    /// Also write the CL polylines as JSON (for scripts/ocl_compare.py).
    #[arg(long)]
    pub cl_json: Option<PathBuf>,
    /// Safe height above the part's top for rapids, mm.
    #[arg(long, default_value_t = 5.0)]
    pub clearance: f64,
    /// Cutting feed, mm/min.
    #[arg(long, default_value_t = 1000.0)]
    pub feed: f64,
    /// Plunge feed, mm/min.
    #[arg(long, default_value_t = 300.0)]
    pub plunge_feed: f64,
    /// Weld tolerance for the mesh's vertices, mm.
    #[arg(long, default_value_t = WeldOptions::default().weld_tolerance)]
    pub weld_tolerance: f64,
    /// No progress bar.
    #[arg(long)]
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

/// Digits after the point in the G-code (0.1 µm).
const GCODE_DECIMALS: usize = 4;

/// Runs `interpd plan raster`.
pub fn main(args: &RasterArgs) -> Result<()> {
    let t0 = Instant::now();
    let mesh = TriMesh::from_stl_path(
        &args.stl,
        WeldOptions {
            weld_tolerance: args.weld_tolerance,
        },
    )
    .with_context(|| format!("reading mesh {}", args.stl.display()))?;
    let read_s = t0.elapsed().as_secs_f64();
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
        write_gcode(&path, out, safe_z, args)
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

/// Writes the path as G-code with rapids at `safe_z` between polylines
/// (a small local writer until the `gcode` crate's emitter is merged).
fn write_gcode(path: &RasterPath, out: &PathBuf, safe_z: f64, args: &RasterArgs) -> Result<()> {
    let mut f = BufWriter::new(File::create(out)?);
    let d = GCODE_DECIMALS;
    writeln!(
        f,
        "(interpd plan raster: {} stepover {} angle {})",
        path.cutter, path.config.stepover, path.config.angle_deg
    )?;
    writeln!(f, "G21 G90 G17")?;
    writeln!(f, "G0 Z{safe_z:.d$}")?;
    for pass in &path.passes {
        for line in &pass.polylines {
            let Some(first) = line.first() else { continue };
            writeln!(f, "G0 X{:.d$} Y{:.d$}", first.x, first.y)?;
            writeln!(f, "G1 Z{:.d$} F{:.1}", first.z, args.plunge_feed)?;
            writeln!(f, "F{:.1}", args.feed)?;
            for p in &line[1..] {
                writeln!(f, "G1 X{:.d$} Y{:.d$} Z{:.d$}", p.x, p.y, p.z)?;
            }
            writeln!(f, "G0 Z{safe_z:.d$}")?;
        }
    }
    writeln!(f, "M2")?;
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
