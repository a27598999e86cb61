//! `interpd plan gouge` and `interpd plan fit`: the offline gouge check,
//! correction and NURBS fitting of `planner` on G-code paths.
//!
//! Input paths are read with `gcode::parse`; every run of G1 moves between
//! rapids is one CL polyline of tool-tip points. Output goes through
//! `gcode::emit`: G1 (gouge) or G6.2 NURBS (fit).

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::Args;
use planner::cutter::Cutter;
use planner::fit::{self, FitConfig, FitPiece};
use planner::gouge::{self, CcSurface, GougeConfig};
use planner::mesh::{P3, TriMesh, WeldOptions};
use planner::predict::{self, PredictConfig};

use crate::plan::writer::{Moves, PathWriter};

/// Clearance above the first point of a path for the approach rapid, mm.
const APPROACH_CLEARANCE: f64 = 5.0;
/// Feed written when the input program has none, mm/min.
const DEFAULT_FEED: f64 = 1000.0;
/// Pixels per check point in the heat maps.
const HEAT_MAP_PIXELS: u32 = 2;

/// Arguments of `interpd plan gouge`.
#[derive(Debug, Args)]
pub struct GougeArgs {
    /// The design part (binary or ASCII STL, mm, Z up).
    #[arg(long)]
    pub stl: PathBuf,
    /// The CL path: G0/G1 program of tool-tip positions.
    #[arg(long)]
    pub path: PathBuf,
    /// Cutter: ball:D, flat:D or bull:D:r (D the diameter, mm).
    #[arg(long)]
    pub tool: String,
    /// Allowed overcut, mm.
    #[arg(long, default_value_t = 0.05)]
    pub tol: f64,
    /// Corrected path (G1).
    #[arg(long)]
    pub out: PathBuf,
    /// Write before.png and after.png error heat maps into this directory.
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Spacing of the CC points sampled on the mesh, mm.
    #[arg(long, default_value_t = GougeConfig::default().sample_spacing)]
    pub sample_spacing: f64,
    /// Check-point grid step of the milled-surface prediction, mm.
    #[arg(long, default_value_t = PredictConfig::default().grid_step)]
    pub grid_step: f64,
    /// Print the report as JSON.
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `interpd plan fit`.
#[derive(Debug, Args)]
pub struct FitArgs {
    /// The CL path: G0/G1 program.
    #[arg(long)]
    pub path: PathBuf,
    /// Largest distance of a CL point from its curve, mm.
    #[arg(long, default_value_t = FitConfig::default().tolerance)]
    pub tol: f64,
    /// Curve degree (1..=5).
    #[arg(long, default_value_t = FitConfig::default().degree)]
    pub degree: usize,
    /// G6.2 program out.
    #[arg(long)]
    pub out: PathBuf,
    /// Re-check the fitted curves for gouges against this part (needs --tool).
    #[arg(long, requires = "tool")]
    pub stl: Option<PathBuf>,
    /// Cutter for the re-check.
    #[arg(long, requires = "stl")]
    pub tool: Option<String>,
    /// Allowed interference of the fitted curves in the re-check, mm.
    #[arg(long, default_value_t = GougeConfig::default().tolerance)]
    pub gouge_tol: f64,
    /// Print the report as JSON.
    #[arg(long)]
    pub json: bool,
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
pub fn read_cl_program(text: &str) -> Result<ClProgram> {
    use gcode::BlockKind;
    let program = gcode::parse(text).map_err(|e| anyhow::anyhow!("{e}"))?;
    let mut paths: Vec<Vec<P3>> = Vec::new();
    let mut current: Vec<P3> = Vec::new();
    let (mut feed, mut plunge_feed, mut top_z) = (None, None, None::<f64>);
    let p3 = |p: [f64; 3]| P3::new(p[0], p[1], p[2]);
    let mut top = |z: f64| top_z = Some(top_z.map_or(z, |t| t.max(z)));
    for block in &program.blocks {
        match &block.kind {
            BlockKind::Linear(m) => {
                top(m.start[2]);
                top(m.end[2]);
                let gcode::Feed::PerMinute(f) = m.feed else {
                    bail!(
                        "line {}: inverse-time feed (G93) is not supported in a CL path",
                        block.line
                    );
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
            BlockKind::Arc(_) | BlockKind::Nurbs(_) => bail!(
                "line {}: arcs and NURBS are not supported in a CL path (G0/G1 polylines only)",
                block.line
            ),
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

fn read_program(path: &Path) -> Result<ClProgram> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    let prog = read_cl_program(&text).with_context(|| format!("{}", path.display()))?;
    if prog.paths.is_empty() {
        bail!("{}: no G1 path found", path.display());
    }
    for (what, f) in [("feed", prog.feed), ("plunge feed", prog.plunge_feed)] {
        if let Some(f) = f
            && !(f.is_finite() && f > 0.0)
        {
            bail!(
                "{}: the {what} F{f} is not a positive number of mm/min",
                path.display()
            );
        }
    }
    Ok(prog)
}

/// Refuses a tolerance `flag` below what f64 resolves at the size of `paths`.
fn check_tolerance<'a>(
    flag: &str,
    tol: f64,
    paths: impl IntoIterator<Item = &'a P3>,
) -> Result<()> {
    let extent = paths.into_iter().fold(0.0f64, |m, p| {
        m.max(p.x.abs()).max(p.y.abs()).max(p.z.abs())
    });
    let min = planner::min_tolerance(extent);
    if !(tol >= min) {
        bail!(
            "{flag} {tol} mm is below what f64 resolves at this path's size \
             (coordinates up to {extent} mm): at least {min:e} mm"
        );
    }
    Ok(())
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
pub fn write_g62(fitted: &[(P3, fit::Fitted)], moves: Moves) -> String {
    let mut w = PathWriter::new(moves);
    for (start, f) in fitted {
        w.enter([start.x, start.y, start.z]);
        for piece in &f.pieces {
            match piece {
                FitPiece::Lines(pts) => {
                    for p in &pts[1..] {
                        w.cut_to(*p);
                    }
                }
                FitPiece::Nurbs(b) => w.nurbs(b),
            }
        }
        w.leave();
    }
    gcode::emit(&w.into_program())
}

/// `interpd plan gouge`.
pub fn gouge_main(a: &GougeArgs) -> Result<()> {
    let cutter: Cutter = a.tool.parse()?;
    let config = GougeConfig {
        tolerance: a.tol,
        sample_spacing: a.sample_spacing,
        correction_target: GougeConfig::default().correction_target.min(a.tol),
        ..GougeConfig::default()
    }
    .validated()?;
    let mesh = TriMesh::from_stl_path(&a.stl, WeldOptions::default())
        .with_context(|| format!("reading {}", a.stl.display()))?;
    let prog = read_program(&a.path)?;
    check_tolerance("--tol", a.tol, prog.paths.iter().flatten())?;
    let cc = CcSurface::from_mesh(&mesh, config.sample_spacing)?;
    let pcfg = PredictConfig {
        grid_step: a.grid_step,
        tolerance: a.tol,
    };
    let mut reports = Vec::new();
    let mut fixed_paths = Vec::new();
    let mut all_before = Vec::new();
    let mut all_after = Vec::new();
    for path in &prog.paths {
        let det = gouge::detect(&cutter, &cc, path, config.contact_epsilon);
        let fixed = gouge::correct(&cutter, &cc, path, &config)?;
        all_before.extend_from_slice(path);
        all_after.extend(fixed.points());
        reports.push(serde_json::json!({
            "cl_points": path.len(),
            "pairs_checked": det.pairs_checked,
            "interfering_pairs": det.interferences.len(),
            "max_depth_before": det.max_depth(),
            "lifted_points": fixed.lifted_points,
            "inserted_points": fixed.inserted_points,
            "max_depth_after": fixed.max_depth_after,
            "rest_regions": fixed.rest_regions,
        }));
        fixed_paths.push(fixed.points());
    }
    // One prediction over all runs (rapids between runs are not cutting moves,
    // so each run is predicted on its own and the results merged by taking
    // the lowest milled height would be exact; runs rarely overlap, and
    // predicting the concatenation would count the joins as cuts).
    let before = predict_runs(&cutter, &mesh, &prog.paths, &pcfg)?;
    let after = predict_runs(&cutter, &mesh, &fixed_paths, &pcfg)?;
    std::fs::write(
        &a.out,
        write_g1(&fixed_paths, prog.moves_for(fixed_paths.iter().flatten())),
    )
    .with_context(|| format!("writing {}", a.out.display()))?;
    let mut plots = Vec::new();
    if let Some(dir) = &a.plot {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        for (name, pr) in [("before.png", &before), ("after.png", &after)] {
            let file = dir.join(name);
            predict::write_heat_map(pr, &file, HEAT_MAP_PIXELS)?;
            plots.push(file.display().to_string());
        }
    }
    let report = serde_json::json!({
        "tool": cutter.to_string(),
        "tolerance": a.tol,
        "cc_points": cc.points.len(),
        "paths": reports,
        "prediction_before": before.stats,
        "prediction_after": after.stats,
        "out": a.out.display().to_string(),
        "plots": plots,
        "heat_map_colours": "grey: not machined; green: |E| <= tol; blue: overcut, red: undercut, saturating at 10 tol",
    });
    if a.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        println!(
            "{} runs, {} interfering pairs (max depth {:.4} mm) -> corrected: max depth {:.5} mm; predicted overcut {:.4} -> {:.4} mm, undercut beyond tol at {} check points; wrote {}",
            prog.paths.len(),
            reports
                .iter()
                .map(|r| r["interfering_pairs"].as_u64().unwrap_or(0))
                .sum::<u64>(),
            reports
                .iter()
                .map(|r| r["max_depth_before"].as_f64().unwrap_or(0.0))
                .fold(0.0, f64::max),
            reports
                .iter()
                .map(|r| r["max_depth_after"].as_f64().unwrap_or(0.0))
                .fold(0.0, f64::max),
            before.stats.max_overcut,
            after.stats.max_overcut,
            after.stats.undercut_beyond_tolerance,
            a.out.display()
        );
    }
    if after.stats.max_overcut > a.tol {
        bail!(
            "predicted overcut {:.4} mm after correction exceeds the tolerance {} mm",
            after.stats.max_overcut,
            a.tol
        );
    }
    Ok(())
}

/// Predicts each run and merges them: the milled height is the lowest of the
/// runs' at each check point, on the first run's grid extended to all.
fn predict_runs(
    cutter: &Cutter,
    mesh: &TriMesh,
    runs: &[Vec<P3>],
    cfg: &PredictConfig,
) -> Result<predict::Prediction> {
    if runs.len() == 1 {
        return Ok(predict::predict(cutter, mesh, &runs[0], cfg)?);
    }
    // Join runs through points far above the part so that the joins cut nothing.
    let (_, hi) = mesh.bounds();
    let lift = hi.z + 10.0 * cutter.radius() + APPROACH_CLEARANCE;
    let mut joined = Vec::new();
    for run in runs {
        if let (Some(last), Some(first)) = (joined.last().copied(), run.first()) {
            let last: P3 = last;
            joined.push(P3::new(last.x, last.y, lift));
            joined.push(P3::new(first.x, first.y, lift));
        }
        joined.extend_from_slice(run);
    }
    Ok(predict::predict(cutter, mesh, &joined, cfg)?)
}

/// `interpd plan fit`.
pub fn fit_main(a: &FitArgs) -> Result<()> {
    let cfg = FitConfig {
        tolerance: a.tol,
        degree: a.degree,
        ..FitConfig::default()
    }
    .validated()?;
    let prog = read_program(&a.path)?;
    check_tolerance("--tol", a.tol, prog.paths.iter().flatten())?;
    let check = match (&a.stl, &a.tool) {
        (Some(stl), Some(tool)) => {
            let cutter: Cutter = tool.parse()?;
            let mesh = TriMesh::from_stl_path(stl, WeldOptions::default())
                .with_context(|| format!("reading {}", stl.display()))?;
            let cc = CcSurface::from_mesh(&mesh, GougeConfig::default().sample_spacing)?;
            Some((cutter, cc))
        }
        _ => None,
    };
    let t = std::time::Instant::now();
    let mut fitted = Vec::new();
    for path in &prog.paths {
        let rc = check.as_ref().map(|(cutter, cc)| fit::Recheck {
            cutter,
            surface: cc,
            max_depth: a.gouge_tol,
        });
        fitted.push((path[0], fit::fit_checked(path, &cfg, rc)?));
    }
    let secs = t.elapsed().as_secs_f64();
    std::fs::write(
        &a.out,
        write_g62(&fitted, prog.moves_for(prog.paths.iter().flatten())),
    )
    .with_context(|| format!("writing {}", a.out.display()))?;
    let cl: usize = fitted.iter().map(|f| f.1.cl_points).sum();
    let blocks: usize = fitted
        .iter()
        .map(|f| f.1.nurbs_blocks + f.1.line_moves)
        .sum();
    let nurbs: usize = fitted.iter().map(|f| f.1.nurbs_blocks).sum();
    let report = serde_json::json!({
        "cl_points": cl,
        "nurbs_blocks": nurbs,
        "line_moves": blocks - nurbs,
        "compression": if blocks > 0 { cl as f64 / blocks as f64 } else { 0.0 },
        "max_deviation": fitted.iter().map(|f| f.1.max_deviation).fold(0.0, f64::max),
        "recheck_max_depth": fitted.iter().filter_map(|f| f.1.recheck_max_depth).reduce(f64::max),
        "refitted_for_gouge": fitted.iter().map(|f| f.1.refitted_for_gouge).sum::<usize>(),
        "fit_seconds": secs,
        "out": a.out.display().to_string(),
    });
    if a.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        println!(
            "{cl} CL points -> {nurbs} G6.2 blocks + {} G1 moves (compression {:.2}), max deviation {:.2e} mm, {secs:.3} s; wrote {}",
            blocks - nurbs,
            report["compression"].as_f64().unwrap_or(0.0),
            report["max_deviation"].as_f64().unwrap_or(0.0),
            a.out.display()
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::fmt::Write as _;

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
                feed: 1200.0
            }
        );
        let fitted: Vec<(P3, fit::Fitted)> = prog
            .paths
            .iter()
            .map(|p| (p[0], fit::fit(p, &FitConfig::default()).unwrap()))
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
        let f = fit::fit(&pts, &FitConfig::default()).unwrap();
        let moves = Moves {
            safe_z: 20.0,
            approach_clearance: APPROACH_CLEARANCE,
            plunge_feed: 300.0,
            feed: 800.0,
        };
        let text = write_g62(&[(pts[0], f.clone())], moves);
        let FitPiece::Nurbs(b) = &f.pieces[0] else {
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

    /// The seed's compound surface (convex cap in a concave bowl) as an ASCII
    /// STL, and a naive path offset along each CC point's own normal.
    fn seed_files(dir: &Path) -> (PathBuf, PathBuf) {
        let surf = |x: f64, y: f64| -> (f64, [f64; 3]) {
            let zb = (x * x + y * y) / 120.0;
            let s = 400.0 - x * x - y * y;
            if s > 0.0 && -8.0 + s.sqrt() > zb {
                let z = -8.0 + s.sqrt();
                (z, [x / 20.0, y / 20.0, (z + 8.0) / 20.0])
            } else {
                let n = (x * x / 3600.0 + y * y / 3600.0 + 1.0).sqrt();
                (zb, [-x / 60.0 / n, -y / 60.0 / n, 1.0 / n])
            }
        };
        let mut stl = String::from("solid seed\n");
        let step = 1.0;
        for i in 0..50 {
            for j in 0..50 {
                let p = |a: usize, b: usize| {
                    let (x, y) = (-25.0 + a as f64 * step, -25.0 + b as f64 * step);
                    (x, y, surf(x, y).0)
                };
                for tri in [
                    [p(i, j), p(i + 1, j), p(i + 1, j + 1)],
                    [p(i, j), p(i + 1, j + 1), p(i, j + 1)],
                ] {
                    stl.push_str("facet normal 0 0 1\nouter loop\n");
                    for v in tri {
                        let _ = writeln!(stl, "vertex {} {} {}", v.0, v.1, v.2);
                    }
                    stl.push_str("endloop\nendfacet\n");
                }
            }
        }
        stl.push_str("endsolid seed\n");
        let mut ngc = String::from("G21 G90\n");
        for (r, jy) in (0..=30).enumerate() {
            let y = -15.0 + jy as f64;
            for k in 0..=60 {
                let k = if r % 2 == 0 { k } else { 60 - k };
                let x = -15.0 + k as f64 * 0.5;
                let (z, n) = surf(x, y);
                let tip = [x + 10.0 * n[0], y + 10.0 * n[1], z + 10.0 * n[2] - 10.0];
                let g = if r == 0 && k == 0 { "G0" } else { "G1" };
                let _ = writeln!(
                    ngc,
                    "{g} X{:.6} Y{:.6} Z{:.6} F1000",
                    tip[0], tip[1], tip[2]
                );
            }
        }
        let (stl_path, ngc_path) = (dir.join("seed.stl"), dir.join("naive.ngc"));
        std::fs::write(&stl_path, stl).unwrap();
        std::fs::write(&ngc_path, ngc).unwrap();
        (stl_path, ngc_path)
    }

    #[test]
    fn plan_gouge_then_fit_on_the_seed_example() {
        let dir = std::env::temp_dir().join(format!("interpd-plan-gouge-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let (stl, naive) = seed_files(&dir);
        let fixed = dir.join("fixed.ngc");
        let plots = dir.join("plots");
        gouge_main(&GougeArgs {
            stl: stl.clone(),
            path: naive.clone(),
            tool: "ball:20".into(),
            tol: 0.05,
            out: fixed.clone(),
            plot: Some(plots.clone()),
            sample_spacing: 0.5,
            grid_step: 0.5,
            json: true,
        })
        .unwrap();
        assert!(plots.join("before.png").exists() && plots.join("after.png").exists());
        // Independent check of the written program: read it back and predict.
        let mesh = TriMesh::from_stl_path(&stl, WeldOptions::default()).unwrap();
        let prog = read_program(&fixed).unwrap();
        let cutter: Cutter = "ball:20".parse().unwrap();
        let cfg = PredictConfig {
            grid_step: 0.5,
            tolerance: 0.05,
        };
        let naive_prog = read_program(&naive).unwrap();
        let before = predict::predict(&cutter, &mesh, &naive_prog.paths[0], &cfg).unwrap();
        assert!(before.stats.max_overcut > 0.5, "{:?}", before.stats);
        let after = predict_runs(&cutter, &mesh, &prog.paths, &cfg).unwrap();
        assert!(after.stats.max_overcut <= 0.05, "{:?}", after.stats);

        let nurbs = dir.join("nurbs.ngc");
        fit_main(&FitArgs {
            path: fixed,
            tol: 0.001,
            degree: 3,
            out: nurbs.clone(),
            stl: Some(stl),
            tool: Some("ball:20".into()),
            gouge_tol: 0.05,
            json: true,
        })
        .unwrap();
        let text = std::fs::read_to_string(&nurbs).unwrap();
        let prog = gcode::parse(&text).unwrap();
        let curves = prog
            .blocks
            .iter()
            .filter(|b| matches!(&b.kind, gcode::BlockKind::Nurbs(n) if n.degree == 3))
            .count();
        assert!(curves > 0, "no G6.2 curve in {text:.300}");
        prog.to_core_blocks(&gcode::CoreOptions::default()).unwrap();
        std::fs::remove_dir_all(&dir).ok();
    }
}
