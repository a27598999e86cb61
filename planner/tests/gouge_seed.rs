//! The seed's example (`003_…` §4, Figs. 8–14): a convex surface in the middle
//! of a concave one, a ball end mill of R = 10 mm, tolerance 0.05 mm. A naive
//! path made by offsetting each CC point along its own surface normal gouges
//! at the junction; detection finds it; after correction the predicted overcut
//! is within the tolerance everywhere, and undercut is left at the junction.

use planner::cutter::Cutter;
use planner::fit::{self, FitConfig};
use planner::gouge::{self, CcSurface, GougeConfig, InterferenceCase};
use planner::mesh::{P3, TriMesh, V3, WeldOptions};
use planner::predict::{self, PredictConfig};

/// Radius of the concave bowl `z = r² / (2 BOWL_R)` (a paraboloid), mm.
const BOWL_R: f64 = 60.0;
/// The convex cap: a sphere of this radius, centre at `CAP_Z` on the axis.
const CAP_R: f64 = 20.0;
const CAP_Z: f64 = -8.0;
/// Half the side of the square part, mm.
const HALF: f64 = 30.0;
/// Mesh grid step, mm.
const MESH_STEP: f64 = 1.0;
const TOL: f64 = 0.05;

fn bowl(x: f64, y: f64) -> (f64, V3) {
    let z = (x * x + y * y) / (2.0 * BOWL_R);
    (z, V3::new(-x / BOWL_R, -y / BOWL_R, 1.0).normalize())
}

fn cap(x: f64, y: f64) -> Option<(f64, V3)> {
    let s = CAP_R * CAP_R - x * x - y * y;
    (s > 0.0).then(|| {
        let z = CAP_Z + s.sqrt();
        (z, V3::new(x, y, z - CAP_Z) / CAP_R)
    })
}

/// The compound surface: whichever of the two is on top.
fn surface(x: f64, y: f64) -> (f64, V3) {
    let b = bowl(x, y);
    match cap(x, y) {
        Some(c) if c.0 > b.0 => c,
        _ => b,
    }
}

fn mesh() -> TriMesh {
    let n = (2.0 * HALF / MESH_STEP).round() as usize;
    let p = |i: usize, j: usize| {
        let (x, y) = (-HALF + i as f64 * MESH_STEP, -HALF + j as f64 * MESH_STEP);
        P3::new(x, y, surface(x, y).0)
    };
    let mut soup = Vec::new();
    for i in 0..n {
        for j in 0..n {
            soup.push([p(i, j), p(i + 1, j), p(i + 1, j + 1)]);
            soup.push([p(i, j), p(i + 1, j + 1), p(i, j + 1)]);
        }
    }
    TriMesh::from_triangles(&soup, WeldOptions::default()).unwrap()
}

/// Naive zig-zag raster: CC points on a grid, each offset along its own
/// surface's normal by R (ball centre), then down by R to the tip.
fn naive_path(radius: f64) -> Vec<P3> {
    naive_path_with_cc(radius)
        .into_iter()
        .map(|(p, _)| p)
        .collect()
}

/// The naive path with the CC point each CL point was made from.
fn naive_path_with_cc(radius: f64) -> Vec<(P3, P3)> {
    let mut path = Vec::new();
    let (row_step, point_step, reach) = (1.0, 0.5, HALF - radius);
    let rows = (2.0 * reach / row_step).round() as usize;
    let cols = (2.0 * reach / point_step).round() as usize;
    for j in 0..=rows {
        let y = -reach + j as f64 * row_step;
        for k in 0..=cols {
            let k = if j % 2 == 0 { k } else { cols - k };
            let x = -reach + k as f64 * point_step;
            let (z, n) = surface(x, y);
            let centre = P3::new(x, y, z) + n * radius;
            path.push((centre - V3::z() * radius, P3::new(x, y, z)));
        }
    }
    path
}

#[test]
fn seed_example_gouges_at_the_junction_and_correction_removes_the_overcut() {
    let cutter: Cutter = "ball:20".parse().unwrap();
    assert_eq!(cutter.radius(), 10.0);
    let mesh = mesh();
    let config = GougeConfig {
        tolerance: TOL,
        sample_spacing: 0.4,
        ..GougeConfig::default()
    };
    let cc = CcSurface::from_mesh(&mesh, config.sample_spacing).unwrap();
    let with_cc = naive_path_with_cc(cutter.radius());
    let naive: Vec<P3> = with_cc.iter().map(|(p, _)| *p).collect();
    let t0 = std::time::Instant::now();

    // Detection: deep interference, and only near the junction circle (the
    // cap meets the bowl at r ≈ 17.3 mm): the CL points of every interfering
    // pair come from CC points within a tool radius of it. Both cases of
    // Fig. 3 occur.
    let det = gouge::detect(&cutter, &cc, &naive, TOL);
    eprintln!("detect {:?}", t0.elapsed());
    assert!(det.max_depth() > 1.0, "max depth {}", det.max_depth());
    let junction = 17.3;
    for i in &det.interferences {
        let near = [with_cc[i.pair].1, with_cc[i.pair + 1].1]
            .iter()
            .any(|c| (c.x.hypot(c.y) - junction).abs() < cutter.radius());
        assert!(near, "interference far from the junction: {i:?}");
    }
    let along = det
        .interferences
        .iter()
        .filter(|i| i.case == InterferenceCase::AlongMove)
        .count();
    let at_end = det.interferences.len() - along;
    eprintln!("{along} along the move (Fig. 3a), {at_end} at a CL point (Fig. 3b)");
    assert!(at_end > 0);

    // Prediction of the naive path: overcut well beyond the tolerance (Fig. 10–11).
    let pcfg = PredictConfig {
        grid_step: 0.5,
        tolerance: TOL,
    };
    let before = predict::predict(&cutter, &mesh, &naive, &pcfg).unwrap();
    assert!(before.stats.max_overcut > 1.0, "{:?}", before.stats);

    // Correction, then prediction: no overcut beyond the tolerance (Fig. 13–14).
    eprintln!("predict {:?}", t0.elapsed());
    let fixed = gouge::correct(&cutter, &cc, &naive, &config).unwrap();
    eprintln!(
        "correct {:?} {} inserted",
        t0.elapsed(),
        fixed.inserted_points
    );
    assert!(fixed.max_depth_after <= config.correction_target);
    assert!(fixed.inserted_points > 0 && fixed.lifted_points > 0);
    let after = predict::predict(&cutter, &mesh, &fixed.points(), &pcfg).unwrap();
    assert!(
        after.stats.max_overcut <= TOL,
        "overcut after correction {:?}",
        after.stats
    );
    // Undercut is left at the junction, reported as rest-machining regions.
    assert!(after.stats.undercut_beyond_tolerance > 0);
    assert!(!fixed.rest_regions.is_empty());
    for r in &fixed.rest_regions {
        let cx = 0.5 * (r.xy_box[0] + r.xy_box[2]);
        let cy = 0.5 * (r.xy_box[1] + r.xy_box[3]);
        assert!(cx.hypot(cy) < junction + cutter.radius() + 1.0);
    }
    // Fit into NURBS blocks at 1 µm with the gouge re-check; the milled
    // surface of the fitted curves (sampled) still has no overcut beyond the
    // tolerance, and the blocks are fewer than the CL points.
    let fitted = fit::fit_checked(
        &fixed.points(),
        &FitConfig::default(),
        Some(fit::Recheck {
            cutter: &cutter,
            surface: &cc,
            max_depth: TOL,
        }),
    )
    .unwrap();
    eprintln!(
        "fit {:?}: {} blocks, {} lines, compression {:.1}, max dev {:.2e}, recheck {:?}",
        t0.elapsed(),
        fitted.nurbs_blocks,
        fitted.line_moves,
        fitted.compression,
        fitted.max_deviation,
        fitted.recheck_max_depth
    );
    assert!(fitted.max_deviation <= 1e-3);
    assert!(fitted.recheck_max_depth.unwrap() <= TOL);
    assert!(fitted.compression > 2.0);
    let sampled: Vec<P3> = fitted.pieces.iter().flat_map(fit::sample_piece).collect();
    let milled = predict::predict(&cutter, &mesh, &sampled, &pcfg).unwrap();
    assert!(milled.stats.max_overcut <= TOL, "{:?}", milled.stats);

    // Away from the junction the corrected path is the naive one.
    for (p, &l) in fixed.points().iter().zip(&fixed.lift) {
        if p.x.hypot(p.y) > junction + 2.0 * cutter.radius() {
            assert!(l < 0.01, "lift {l} at {p}");
        }
    }
}

#[test]
fn metamorphic_translation_and_reversal_keep_the_result() {
    let cutter: Cutter = "ball:20".parse().unwrap();
    let mesh = mesh();
    let cc = CcSurface::from_mesh(&mesh, 0.4).unwrap();
    let naive = naive_path(cutter.radius());
    let base = gouge::detect(&cutter, &cc, &naive, TOL);

    // Reversed path: the same pairs interfere, with the same depths.
    let reversed: Vec<P3> = naive.iter().rev().copied().collect();
    let rev = gouge::detect(&cutter, &cc, &reversed, TOL);
    assert_eq!(rev.interferences.len(), base.interferences.len());
    assert!((rev.max_depth() - base.max_depth()).abs() < 1e-9);

    // Translated part and path (a multiple of the check-point step).
    let shift = V3::new(100.0, -50.0, 7.0);
    let moved_cc = CcSurface::from_points(cc.points.iter().map(|p| p + shift).collect(), 1.6);
    let moved: Vec<P3> = naive.iter().map(|p| p + shift).collect();
    let tr = gouge::detect(&cutter, &moved_cc, &moved, TOL);
    assert_eq!(tr.interferences.len(), base.interferences.len());
    assert!((tr.max_depth() - base.max_depth()).abs() < 1e-9);
}
