//! End to end (issue 6): STL → `interpd plan raster` → `interpd plan gouge`
//! → `interpd plan fit` (G6.2) → `interpd simulate --out` (MCAP trace) →
//! the trace read back → an independent z-map of the traced setpoints
//! compared with the design surface.
//!
//! Every stage is the real `interpd` binary, as a user runs it; files pass
//! between them as on disk. The check at the end shares no code with the
//! planner: the design height is a brute-force vertical drop onto the STL's
//! triangles, and the milled height is the lowest point of the ball at every
//! traced setpoint (densified), by the sphere formula.
//!
//! The part is the seed's example (`003_…` §4): a convex spherical cap in a
//! concave bowl, ball end mill R = 10 mm, tolerance 0.05 mm. A second test
//! pushes the seed's naive path (CC points offset along their own normals)
//! through the same chain without the gouge stage and requires the z-map to
//! find its overcut, so the check can fail; with the gouge stage it must pass.

mod serve_support;

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use serve_support::{interpd, temp_dir};
use traces::reader::Trace;

/// Ball end mill radius, mm (`ball:20` is the diameter).
const R: f64 = 10.0;
/// The tool as `interpd plan` spells it.
const TOOL: &str = "ball:20";
/// Allowed overcut (the seed's tolerance), mm.
const TOL: f64 = 0.05;
/// Fit tolerance of `plan fit` (issue 6: within 1 µm), mm.
const FIT_TOL: f64 = 0.001;

/// Concave bowl `z = r² / (2 BOWL_R)`, mm.
const BOWL_R: f64 = 60.0;
/// Convex cap: sphere of radius `CAP_R` centred `CAP_Z` on the axis, mm.
const CAP_R: f64 = 20.0;
const CAP_Z: f64 = -8.0;
/// The part is shifted down so its top is at Z = -1: Z0 at the top of the
/// stock, as CAM programs usually are. The simulator starts at the origin
/// (the G-code parser's initial position) and the emitted programs' first
/// rapid leaves from there, so the origin must be clear of the part.
const PART_Z_SHIFT: f64 = -(CAP_Z + CAP_R) - 1.0;
/// Half the side of the square part, mm.
const HALF: f64 = 25.0;
/// STL grid step, mm (25 × 25 cells, 1250 triangles: small, for CI time).
const MESH_STEP: f64 = 2.0;

/// Raster step-over, mm (coarse: the test is about overcut, and scallops of
/// `s² / 8R` ≈ 0.2 mm are undercut, which is allowed).
const STEPOVER: f64 = 4.0;
/// Raster chord tolerance, mm: coarse for few CL points (the fit's cost
/// grows with them); the chords' dips below the offset surface are what the
/// gouge stage then finds.
const RASTER_CHORD: f64 = 0.01;
/// Feed of every program, mm/min (raster cut and plunge alike: `plan gouge`
/// keeps the first feed word it reads for the whole output).
const FEED: f64 = 3000.0;

/// Z-map grid step over the part, mm.
const ZMAP_STEP: f64 = 0.5;
/// Longest straight step between two tool positions the z-map samples, mm.
/// Between setpoints the machine moves on a straight line; sampling it at
/// spacing `h` misses at most `h² / (8 R cos³θ)` of the swept envelope at a
/// surface slope θ (the envelope is convex along the move; second-order
/// bound at its minimum). For h = 0.02 mm, R = 10 and θ ≤ 70°: < 1.3e-4 mm.
const ZMAP_SAMPLE: f64 = 0.02;
/// What the z-map may overstate overcut by: its sampling (above, 1.3e-4 mm),
/// plus the interpolator's chord tolerance (1 µm: the setpoints are on the
/// G6.2 curve, the straight moves between them within it), plus the fit's
/// 1 µm (the curve may pass that far from the corrected CL points), plus the
/// STL's f32 vertices (≈ 4e-6 mm at |coordinate| ≤ 35). Rounded up.
const OVERCUT_EPS: f64 = 2e-4;
/// A chain that cuts air would "pass": most of the part must come out within
/// this of the design (the junction's rest region excepted), mm. The raster's
/// scallop on level ground is `R − sqrt(R² − (STEPOVER/2)²)` = 0.202 mm and
/// grows on slopes, so the band is 1.5 times that.
const NEAR_DESIGN: f64 = 0.3;
/// The share of z-map points that must be within `NEAR_DESIGN` after the
/// raster: measured 62.9 %; the rest is the ring around the cap where the
/// R = 10 ball cannot reach the concave junction (undercut up to 2.9 mm, the
/// rest-machining region) and the steep flanks. A path that cuts air gives ~0.
const NEAR_DESIGN_SHARE_RASTER: f64 = 0.5;
/// The same for the corrected naive path: it reaches only the middle
/// 30 × 30 mm plus R, rows 2 mm apart, and leaves the junction's rest region
/// (measured 60.7 %).
const NEAR_DESIGN_SHARE_NAIVE: f64 = 0.4;

/// The seed's compound surface, shifted: height and unit normal.
fn surface(x: f64, y: f64) -> (f64, [f64; 3]) {
    let zb = (x * x + y * y) / (2.0 * BOWL_R);
    let s = CAP_R * CAP_R - x * x - y * y;
    let (z, n) = if s > 0.0 && CAP_Z + s.sqrt() > zb {
        let z = CAP_Z + s.sqrt();
        (z, [x / CAP_R, y / CAP_R, (z - CAP_Z) / CAP_R])
    } else {
        let m = (x * x + y * y + BOWL_R * BOWL_R).sqrt();
        (zb, [-x / m, -y / m, BOWL_R / m])
    };
    (z + PART_Z_SHIFT, n)
}

type Tri = [[f64; 3]; 3];

/// The part as triangles on a grid, vertices rounded to f32 (what the STL
/// holds, so the design used by the check is exactly the planner's input).
fn part_triangles() -> Vec<Tri> {
    let n = (2.0 * HALF / MESH_STEP).round() as usize;
    let v = |i: usize, j: usize| {
        let (x, y) = (-HALF + i as f64 * MESH_STEP, -HALF + j as f64 * MESH_STEP);
        [x, y, surface(x, y).0].map(|c| c as f32 as f64)
    };
    let mut tris = Vec::with_capacity(2 * n * n);
    for i in 0..n {
        for j in 0..n {
            tris.push([v(i, j), v(i + 1, j), v(i + 1, j + 1)]);
            tris.push([v(i, j), v(i + 1, j + 1), v(i, j + 1)]);
        }
    }
    tris
}

/// Binary STL (80-byte header, count, 50 bytes per facet).
fn write_stl(path: &Path, tris: &[Tri]) {
    let mut b = vec![0u8; 80];
    b[..18].copy_from_slice(b"interpd gouge e2e ");
    b.extend_from_slice(&(tris.len() as u32).to_le_bytes());
    for t in tris {
        let (u, w) = (sub(t[1], t[0]), sub(t[2], t[0]));
        let n = [
            u[1] * w[2] - u[2] * w[1],
            u[2] * w[0] - u[0] * w[2],
            u[0] * w[1] - u[1] * w[0],
        ];
        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        for c in n.iter().map(|c| c / len).chain(t.iter().flatten().copied()) {
            b.extend_from_slice(&(c as f32).to_le_bytes());
        }
        b.extend_from_slice(&[0, 0]);
    }
    std::fs::write(path, b).expect("STL written");
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// The seed's naive path as G0/G1: a zig-zag over CC points on a grid, each
/// CL point the CC point offset by R along its own surface normal (the ball
/// centre), then down by R to the tip. It gouges the cap-bowl junction.
fn naive_program() -> String {
    let (row_step, point_step, reach) = (2.0, 0.5, HALF - R);
    let rows = (2.0 * reach / row_step).round() as usize;
    let cols = (2.0 * reach / point_step).round() as usize;
    let mut ngc = String::from("G21 G90 G17\n");
    for j in 0..=rows {
        let y = -reach + j as f64 * row_step;
        for k in 0..=cols {
            let k = if j % 2 == 0 { k } else { cols - k };
            let x = -reach + k as f64 * point_step;
            let (z, n) = surface(x, y);
            let tip = [x + R * n[0], y + R * n[1], z + R * n[2] - R];
            if j == 0 && k == 0 {
                let _ = writeln!(ngc, "G0 X{:.6} Y{:.6} Z{:.6}", tip[0], tip[1], 0.0);
            }
            let _ = writeln!(
                ngc,
                "G1 X{:.6} Y{:.6} Z{:.6} F{FEED}",
                tip[0], tip[1], tip[2]
            );
        }
    }
    ngc.push_str("M2\n");
    ngc
}

/// Runs `interpd ARGS…`, requires success and returns its stdout as JSON.
fn interpd_json(args: &[&str]) -> serde_json::Value {
    let out = Command::new(interpd())
        .args(args)
        .output()
        .expect("interpd runs");
    assert!(
        out.status.success(),
        "interpd {}: {}\n{}",
        args.join(" "),
        String::from_utf8_lossy(&out.stderr),
        String::from_utf8_lossy(&out.stdout)
    );
    serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
        panic!(
            "interpd {}: stdout is not JSON ({e}): {}",
            args.join(" "),
            String::from_utf8_lossy(&out.stdout)
        )
    })
}

fn s(p: &Path) -> &str {
    p.to_str().expect("UTF-8 temp path")
}

/// Heights on a square grid over the part; `f64::INFINITY` where no tool
/// position reached.
#[derive(Debug, Clone)]
struct Grid {
    n: usize,
    h: Vec<f64>,
}

impl Grid {
    fn new(fill: f64) -> Grid {
        let n = (2.0 * HALF / ZMAP_STEP).round() as usize + 1;
        Grid {
            n,
            h: vec![fill; n * n],
        }
    }
    fn coord(i: usize) -> f64 {
        -HALF + i as f64 * ZMAP_STEP
    }
}

/// The design height at every grid point: the highest triangle hit by a
/// vertical ray there (brute force over all triangles, XY box first).
fn design_heights(tris: &[Tri]) -> Grid {
    let mut g = Grid::new(f64::NEG_INFINITY);
    // Barycentric slack so grid points on shared edges hit both triangles.
    const ON_EDGE: f64 = 1e-12;
    for i in 0..g.n {
        for j in 0..g.n {
            let (x, y) = (Grid::coord(i), Grid::coord(j));
            for t in tris {
                let (lo_x, hi_x) = (
                    t[0][0].min(t[1][0]).min(t[2][0]),
                    t[0][0].max(t[1][0]).max(t[2][0]),
                );
                let (lo_y, hi_y) = (
                    t[0][1].min(t[1][1]).min(t[2][1]),
                    t[0][1].max(t[1][1]).max(t[2][1]),
                );
                if x < lo_x || x > hi_x || y < lo_y || y > hi_y {
                    continue;
                }
                let (a, b, c) = (t[0], t[1], t[2]);
                let det = (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]);
                if det.abs() < 1e-15 {
                    continue; // vertical facet: a ray along Z does not cross it
                }
                let l1 = ((x - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (y - a[1])) / det;
                let l2 = ((b[0] - a[0]) * (y - a[1]) - (x - a[0]) * (b[1] - a[1])) / det;
                let l0 = 1.0 - l1 - l2;
                if l0 >= -ON_EDGE && l1 >= -ON_EDGE && l2 >= -ON_EDGE {
                    let z = l0 * a[2] + l1 * b[2] + l2 * c[2];
                    let cell = &mut g.h[i * g.n + j];
                    *cell = cell.max(z);
                }
            }
        }
    }
    assert!(
        g.h.iter().all(|h| h.is_finite()),
        "a grid point missed the part"
    );
    g
}

/// The milled heights: for every tool position (setpoints, and points every
/// `ZMAP_SAMPLE` on the straight moves between them), the ball's lower
/// surface `z + R − sqrt(R² − d²)` over each grid point within R in XY; the
/// lowest wins. Positions whose tip is above the part's top cut nothing.
fn milled_heights(tips: &[[f64; 3]], top: f64) -> (Grid, usize) {
    let mut g = Grid::new(f64::INFINITY);
    let mut samples = 0;
    let mut cut = |p: [f64; 3]| {
        if p[2] > top {
            return;
        }
        samples += 1;
        let lo = |c: f64| (((c - R + HALF) / ZMAP_STEP).ceil().max(0.0)) as usize;
        let hi = |c: f64| ((((c + R + HALF) / ZMAP_STEP).floor()) as isize).min(g.n as isize - 1);
        let (i1, j1) = (hi(p[0]), hi(p[1]));
        if i1 < 0 || j1 < 0 {
            return;
        }
        for i in lo(p[0])..=i1 as usize {
            let dx = Grid::coord(i) - p[0];
            for j in lo(p[1])..=j1 as usize {
                let dy = Grid::coord(j) - p[1];
                let d2 = dx * dx + dy * dy;
                if d2 <= R * R {
                    let z = p[2] + R - (R * R - d2).sqrt();
                    let cell = &mut g.h[i * g.n + j];
                    if z < *cell {
                        *cell = z;
                    }
                }
            }
        }
    };
    for (k, b) in tips.iter().enumerate() {
        let Some(a) = k.checked_sub(1).map(|k| tips[k]) else {
            cut(*b);
            continue;
        };
        let d = sub(*b, a);
        let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        let steps = (len / ZMAP_SAMPLE).ceil().max(1.0) as usize;
        for m in 1..=steps {
            let t = m as f64 / steps as f64;
            cut([a[0] + t * d[0], a[1] + t * d[1], a[2] + t * d[2]]);
        }
    }
    (g, samples)
}

/// What one run of the chain measured.
#[derive(Debug)]
struct Outcome {
    cl_points: u64,
    nurbs_blocks: u64,
    line_moves: u64,
    compression: f64,
    fit_max_deviation: f64,
    gouge: Option<serde_json::Value>,
    setpoints: usize,
    zmap_samples: usize,
    max_overcut: f64,
    max_overcut_at: [f64; 2],
    max_undercut: f64,
    near_design_share: f64,
}

/// `[gouge →] fit → simulate → trace → z-map` for the G0/G1 program `cl`.
/// `recheck` runs `plan fit` with `--stl/--tool`: the fitted curves are
/// checked for gouges and refitted (needed: without it `plan fit` can emit
/// wild curves on corrected paths, see docs/planner-gouge.md).
fn mill(
    dir: &Path,
    tag: &str,
    stl: &Path,
    cl: &Path,
    tris: &[Tri],
    gouge: bool,
    recheck: bool,
) -> Outcome {
    let t0 = Instant::now();
    let mut to_fit = cl.to_path_buf();
    let mut gouge_report = None;
    if gouge {
        let fixed = dir.join(format!("{tag}-fixed.ngc"));
        let tol = TOL.to_string();
        let r = interpd_json(&[
            "plan",
            "gouge",
            "--stl",
            s(stl),
            "--path",
            s(cl),
            "--tool",
            TOOL,
            "--tol",
            &tol,
            "--grid-step",
            "0.5",
            "--out",
            s(&fixed),
            "--json",
        ]);
        gouge_report = Some(r);
        to_fit = fixed;
    }
    let nurbs: PathBuf = dir.join(format!("{tag}-nurbs.ngc"));
    let (fit_tol, gouge_tol) = (FIT_TOL.to_string(), TOL.to_string());
    let mut fit_args = vec![
        "plan",
        "fit",
        "--path",
        s(&to_fit),
        "--tol",
        &fit_tol,
        "--out",
        s(&nurbs),
        "--json",
    ];
    if recheck {
        fit_args.extend(["--stl", s(stl), "--tool", TOOL, "--gouge-tol", &gouge_tol]);
    }
    let fit = interpd_json(&fit_args);
    let g62 = std::fs::read_to_string(&nurbs).expect("fit wrote its program");
    let nurbs_blocks = fit["nurbs_blocks"].as_u64().expect("nurbs_blocks");
    let parsed = gcode::parse(&g62).unwrap_or_else(|e| panic!("{tag}: G6.2 parses back: {e}"));
    let curves = parsed
        .blocks
        .iter()
        .filter(|b| matches!(&b.kind, gcode::BlockKind::Nurbs(n) if (1..=3).contains(&n.degree)))
        .count();
    assert_eq!(
        curves as u64, nurbs_blocks,
        "{tag}: one G6.2 block (degree ≤ 3, fewer on short pieces) per fitted curve"
    );
    let trace_path = dir.join(format!("{tag}.mcap"));
    let sim = interpd_json(&["simulate", s(&nurbs), "--out", s(&trace_path), "--json"]);
    assert_eq!(sim["final_state"], "done", "{tag}: {sim}");
    let trace = Trace::open(&trace_path).expect("the trace reads back");
    assert_eq!(
        trace.setpoints.len() as u64,
        sim["setpoints"].as_u64().expect("setpoints"),
        "{tag}: the trace holds every setpoint simulate counted"
    );
    assert!(
        trace.setpoints.iter().zip(1..).all(|(p, k)| p.seq == k),
        "{tag}: setpoints gapless"
    );
    let tips: Vec<[f64; 3]> = trace.setpoints.iter().map(|p| [p.x, p.y, p.z]).collect();

    let design = design_heights(tris);
    let top = design.h.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let (milled, zmap_samples) = milled_heights(&tips, top);
    let (mut max_over, mut at, mut max_under, mut near) = (f64::NEG_INFINITY, [0.0; 2], 0.0f64, 0);
    for i in 0..design.n {
        for j in 0..design.n {
            let k = i * design.n + j;
            let e = design.h[k] - milled.h[k]; // > 0: cut below the design
            if e > max_over {
                (max_over, at) = (e, [Grid::coord(i), Grid::coord(j)]);
            }
            if milled.h[k].is_finite() {
                max_under = max_under.max(-e);
            }
            if e >= -NEAR_DESIGN {
                near += 1;
            }
        }
    }
    let out = Outcome {
        cl_points: fit["cl_points"].as_u64().expect("cl_points"),
        nurbs_blocks,
        line_moves: fit["line_moves"].as_u64().expect("line_moves"),
        compression: fit["compression"].as_f64().expect("compression"),
        fit_max_deviation: fit["max_deviation"].as_f64().expect("max_deviation"),
        gouge: gouge_report,
        setpoints: tips.len(),
        zmap_samples,
        max_overcut: max_over,
        max_overcut_at: at,
        max_undercut: max_under,
        near_design_share: near as f64 / design.h.len() as f64,
    };
    println!(
        "{tag}: {} CL points -> {} G6.2 blocks + {} G1 moves (compression {:.2}, fit max deviation {:.2e} mm); \
         {} setpoints ({} z-map samples) on {}x{} grid; max overcut {:.5} mm at ({:.1}, {:.1}), max undercut {:.4} mm, \
         {:.1} % within {NEAR_DESIGN} mm; {:.2} s",
        out.cl_points,
        out.nurbs_blocks,
        out.line_moves,
        out.compression,
        out.fit_max_deviation,
        out.setpoints,
        out.zmap_samples,
        design.n,
        design.n,
        out.max_overcut,
        at[0],
        at[1],
        out.max_undercut,
        100.0 * out.near_design_share,
        t0.elapsed().as_secs_f64()
    );
    if let Some(g) = &out.gouge {
        println!(
            "{tag}: gouge stage: {} interfering pairs, predicted overcut {} -> {} mm",
            g["paths"]
                .as_array()
                .map(|p| p
                    .iter()
                    .map(|r| r["interfering_pairs"].as_u64().unwrap_or(0))
                    .sum::<u64>())
                .unwrap_or(0),
            g["prediction_before"]["max_overcut"],
            g["prediction_after"]["max_overcut"]
        );
    }
    out
}

fn assert_no_overcut(tag: &str, o: &Outcome, near_share: f64) {
    assert!(
        o.max_overcut <= TOL + OVERCUT_EPS,
        "{tag}: z-map overcut {:.5} mm at {:?} exceeds {TOL} + {OVERCUT_EPS} mm",
        o.max_overcut,
        o.max_overcut_at
    );
    assert!(
        o.near_design_share >= near_share,
        "{tag}: only {:.1} % of the part within {NEAR_DESIGN} mm of the design",
        100.0 * o.near_design_share
    );
    assert!(o.nurbs_blocks > 0, "{tag}: no G6.2 block");
    assert!(o.fit_max_deviation <= FIT_TOL, "{tag}: fit deviation");
}

#[test]
fn raster_gouge_fit_simulate_trace_leaves_no_overcut_beyond_the_tolerance() {
    let t0 = Instant::now();
    let dir = temp_dir("gouge-e2e-raster");
    let tris = part_triangles();
    let stl = dir.join("part.stl");
    write_stl(&stl, &tris);
    let raster = dir.join("raster.ngc");
    let (stepover, feed, chord) = (
        STEPOVER.to_string(),
        FEED.to_string(),
        RASTER_CHORD.to_string(),
    );
    let r = interpd_json(&[
        "plan",
        "raster",
        "--stl",
        s(&stl),
        "--tool",
        TOOL,
        "--stepover",
        &stepover,
        "--zigzag",
        "--feed",
        &feed,
        "--plunge-feed",
        &feed,
        "--chord-tolerance",
        &chord,
        "--out",
        s(&raster),
        "--json",
        "--quiet",
    ]);
    println!(
        "raster: {} passes, {} CL points",
        r["passes"], r["stats"]["points"]
    );
    let o = mill(&dir, "raster", &stl, &raster, &tris, true, true);
    assert_no_overcut("raster", &o, NEAR_DESIGN_SHARE_RASTER);
    println!("raster chain: {:.2} s", t0.elapsed().as_secs_f64());
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn the_seeds_naive_path_overcuts_through_fit_and_simulate() {
    let t0 = Instant::now();
    let dir = temp_dir("gouge-e2e-naive");
    let tris = part_triangles();
    let stl = dir.join("part.stl");
    write_stl(&stl, &tris);
    let naive = dir.join("naive.ngc");
    std::fs::write(&naive, naive_program()).expect("naive path written");
    // Without the gouge stage the independent z-map must see the gouge.
    // No re-check: it would only turn the gouging curves into G1 moves (which
    // still gouge) and the 976 corners make the run 16 times longer.
    let bad = mill(&dir, "naive", &stl, &naive, &tris, false, false);
    assert!(
        bad.max_overcut > 10.0 * TOL,
        "the naive path should gouge the junction, z-map overcut {:.4} mm",
        bad.max_overcut
    );
    println!("naive chain: {:.2} s", t0.elapsed().as_secs_f64());
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn the_seeds_naive_path_after_the_gouge_stage_does_not_overcut() {
    let t0 = Instant::now();
    let dir = temp_dir("gouge-e2e-naive-fixed");
    let tris = part_triangles();
    let stl = dir.join("part.stl");
    write_stl(&stl, &tris);
    let naive = dir.join("naive.ngc");
    std::fs::write(&naive, naive_program()).expect("naive path written");
    let good = mill(&dir, "naive+gouge", &stl, &naive, &tris, true, true);
    assert_no_overcut("naive+gouge", &good, NEAR_DESIGN_SHARE_NAIVE);
    let g = good.gouge.as_ref().expect("gouge report");
    assert!(
        g["paths"][0]["interfering_pairs"].as_u64().unwrap_or(0) > 0,
        "detection found nothing: {g}"
    );
    println!("naive+gouge chain: {:.2} s", t0.elapsed().as_secs_f64());
    std::fs::remove_dir_all(&dir).ok();
}
