//! Gouge detection throughput, correction, and fit time/compression on the
//! corpus terrain with a 112,500-point raster (375 rows × 300 points) made by
//! dropping the cutter onto the mesh's CC points.
//!
//! Run: `cargo bench -p planner --bench gouge` (needs `../shared/corpus`;
//! set `INTERPD_CORPUS` to point elsewhere). Prints one line per figure.

use std::path::PathBuf;

use rayon::prelude::*;
use std::time::Instant;

use planner::cutter::Cutter;
use planner::fit::{self, FitConfig};
use planner::gouge::{self, CcSurface, GougeConfig};
use planner::mesh::{P3, TriMesh, WeldOptions};

const ROWS: usize = 375;
const COLS: usize = 300;
const REPEATS: usize = 3;

fn corpus() -> PathBuf {
    std::env::var_os("INTERPD_CORPUS")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/corpus"))
}

fn best_of<T>(mut f: impl FnMut() -> T) -> (f64, T) {
    let mut best = f64::INFINITY;
    let mut out = None;
    for _ in 0..REPEATS {
        let t = Instant::now();
        let v = f();
        best = best.min(t.elapsed().as_secs_f64());
        out = Some(v);
    }
    (best, out.expect("REPEATS > 0"))
}

fn main() {
    // `cargo bench` passes `--bench`; `cargo test --all-targets` runs this
    // binary without it, and the full run takes minutes: skip then.
    if !std::env::args().any(|a| a == "--bench") {
        eprintln!(
            "gouge bench: not run under `cargo test` (use `cargo bench -p planner --bench gouge`)"
        );
        return;
    }
    let stl = corpus().join("meshes/terrain.stl");
    if !stl.exists() {
        eprintln!("skipping gouge bench: {} not found", stl.display());
        return;
    }
    let mesh = TriMesh::from_stl_path(&stl, WeldOptions::default()).expect("terrain reads");
    let cutter: Cutter = "ball:10".parse().expect("cutter");
    let cfg = GougeConfig::default();
    let t = Instant::now();
    let cc = CcSurface::from_mesh(&mesh, cfg.sample_spacing).expect("sampling");
    println!(
        "cc_sampling: {} triangles -> {} CC points at {} mm in {:.3} s",
        mesh.triangles.len(),
        cc.points.len(),
        cfg.sample_spacing,
        t.elapsed().as_secs_f64()
    );
    let (lo, hi) = mesh.bounds();
    let r = cutter.radius();
    let t = Instant::now();
    let raster: Vec<P3> = (0..ROWS * COLS)
        .into_par_iter()
        .map(|k| {
            let (j, i) = (k / COLS, k % COLS);
            let i = if j % 2 == 0 { i } else { COLS - 1 - i };
            let y = lo.y + r + (hi.y - lo.y - 2.0 * r) * j as f64 / (ROWS - 1) as f64;
            let x = lo.x + r + (hi.x - lo.x - 2.0 * r) * i as f64 / (COLS - 1) as f64;
            let z = cc.drop_height(&cutter, x, y).unwrap_or(lo.z);
            P3::new(x, y, z)
        })
        .collect();
    println!(
        "naive_raster: {} CL points by drop-cutter in {:.3} s",
        raster.len(),
        t.elapsed().as_secs_f64()
    );
    let pairs = raster.len() - 1;
    let (secs, det) = best_of(|| gouge::detect(&cutter, &cc, &raster, cfg.contact_epsilon));
    println!(
        "detect: {pairs} CL pairs in {secs:.3} s = {:.0} pairs/s ({} CC tests, {} pairs interfere, max depth {:.4} mm, threads {})",
        pairs as f64 / secs,
        det.cc_tests,
        det.interferences.len(),
        det.max_depth(),
        rayon::current_num_threads()
    );
    let t = Instant::now();
    let fixed = gouge::correct(&cutter, &cc, &raster, &cfg).expect("correct");
    println!(
        "correct: {:.3} s, {} inserted, {} lifted, max depth after {:.5} mm, {} rest regions",
        t.elapsed().as_secs_f64(),
        fixed.inserted_points,
        fixed.lifted_points,
        fixed.max_depth_after,
        fixed.rest_regions.len()
    );
    let path = fixed.points();
    let fcfg = FitConfig::default();
    let (secs, fitted) = best_of(|| fit::fit(&path, &fcfg).expect("fit"));
    println!(
        "fit: {} CL points in {secs:.3} s, {} NURBS blocks + {} lines, compression {:.2} CL points/block, max deviation {:.2e} mm",
        path.len(),
        fitted.nurbs_blocks,
        fitted.line_moves,
        fitted.compression,
        fitted.max_deviation
    );
    let t = Instant::now();
    let checked = fit::fit_checked(
        &path,
        &fcfg,
        Some(fit::Recheck {
            cutter: &cutter,
            surface: &cc,
            max_depth: cfg.tolerance,
        }),
    )
    .expect("fit");
    println!(
        "fit_checked: {:.3} s, recheck max depth {:.5} mm, {} pieces refitted",
        t.elapsed().as_secs_f64(),
        checked.recheck_max_depth.unwrap_or(0.0),
        checked.refitted_for_gouge
    );
}
