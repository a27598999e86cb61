//! `interpd plan gouge` and `interpd plan fit`: the offline gouge check,
//! correction and NURBS fitting of `planner` on G-code paths.
//!
//! Input paths are read with `gcode::parse`; every run of G1 moves between
//! rapids is one CL polyline of tool-tip points. Output goes through
//! `gcode::emit`: G1 (gouge) or G6.2 NURBS (fit).

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use planner::cutter::Cutter;
use planner::fit::{self, FitConfig};
use planner::gouge::{self, CcSurface, GougeConfig};
use planner::mesh::{P3, TriMesh, WeldOptions};
use planner::predict::{self, PredictConfig};

use planner::io::{ClProgram, read_cl_program, write_g1, write_g62};

/// Pixels per check point in the heat maps.
const HEAT_MAP_PIXELS: u32 = 2;

/// Arguments of `interpd plan gouge`.
#[derive(Debug)]
pub struct GougeOptions {
    /// The design part (binary or ASCII STL, mm, Z up).
    pub stl: PathBuf,
    /// The CL path: G0/G1 program of tool-tip positions.
    pub path: PathBuf,
    /// Cutter: ball:D, flat:D or bull:D:r (D the diameter, mm).
    pub tool: String,
    /// Allowed overcut, mm.
    pub tol: f64,
    /// Corrected path (G1).
    pub out: PathBuf,
    /// Write before.png and after.png error heat maps into this directory.
    pub plot: Option<PathBuf>,
    /// Spacing of the CC points sampled on the mesh, mm.
    pub sample_spacing: f64,
    /// Check-point grid step of the milled-surface prediction, mm.
    pub grid_step: f64,
    /// Print the report as JSON.
    pub json: bool,
}

/// Arguments of `interpd plan fit`.
#[derive(Debug)]
pub struct FitOptions {
    /// The CL path: G0/G1 program.
    pub path: PathBuf,
    /// Largest distance of a CL point from its curve, mm.
    pub tol: f64,
    /// Curve degree (1..=5).
    pub degree: usize,
    /// G6.2 program out.
    pub out: PathBuf,
    /// Re-check the fitted curves for gouges against this part (needs --tool).
    pub stl: Option<PathBuf>,
    /// Cutter for the re-check.
    pub tool: Option<String>,
    /// Allowed interference of the fitted curves in the re-check, mm.
    pub gouge_tol: f64,
    /// Print the report as JSON.
    pub json: bool,
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

/// `interpd plan gouge`.
pub fn gouge_main(a: &GougeOptions) -> Result<()> {
    use crate::flags::{PLAN_TOLERANCE, STEP};
    PLAN_TOLERANCE.check("--tol", a.tol)?;
    STEP.check("--sample-spacing", a.sample_spacing)?;
    STEP.check("--grid-step", a.grid_step)?;
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
    let lift = hi.z + 10.0 * cutter.radius() + planner::io::APPROACH_CLEARANCE;
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
pub fn fit_main(a: &FitOptions) -> Result<()> {
    use crate::flags::{PLAN_TOLERANCE, PLAN_TOLERANCE_OR_ZERO};
    PLAN_TOLERANCE.check("--tol", a.tol)?;
    PLAN_TOLERANCE_OR_ZERO.check("--gouge-tol", a.gouge_tol)?;
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
        gouge_main(&GougeOptions {
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
        fit_main(&FitOptions {
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
