//! Benchmark of the 5-axis setup planner (seed `000_…`): the binary
//! spherical map (ray casting) and the setup search, timed separately.
//!
//! `cargo bench -p planner --bench setup` runs the paper's size (the
//! 288-triangle teapot on 1,280 cells, best of 5). Add `-- large` for 20,480
//! cells × ~100,000 triangles (one run, minutes), or `-- cavity` for the
//! overhanging spherical pocket of the tests, `-- medium` for the 6,208-
//! triangle teapot on 5,120 cells; add `compare` to run the exhaustive
//! search (every cell evaluated) alternately with the bounded one and check
//! they agree; add `centres` to test the cells at their centres only (no
//! exact cell test). All cores are used (rayon).

use std::time::Instant;

use planner::mesh::{TriMesh, WeldOptions};
use planner::setup::samples::{cavity, teapot};
use planner::setup::{
    AxisRanges, GeodesicSphere, MachineType, Phase, SetupConfig, search_setup, visibility_map,
};

/// Prints to stderr each tenth of a phase done (the large case runs for
/// minutes).
fn report(phase: Phase, done: usize, total: usize) {
    let tenth = |n: usize| n * 10 / total.max(1);
    let before = done.saturating_sub(64);
    if tenth(done) != tenth(before) || done == total {
        eprintln!("    {phase:?} {done}/{total}");
    }
}

fn run(name: &str, part: &TriMesh, cells: usize, repeats: usize) {
    let sphere = GeodesicSphere::with_at_least(cells).expect("valid cell count");
    let config = SetupConfig {
        cells,
        exact_cells: !std::env::args().any(|a| a == "centres"),
        ..SetupConfig::default()
    };
    let ranges = AxisRanges::from_degrees(90.0, 90.0, 180.0, 180.0).expect("valid ranges");
    let best = |v: &[f64]| v.iter().copied().fold(f64::INFINITY, f64::min);
    let rays = (sphere.len() * part.triangles.len()) as f64;
    println!(
        "{name}: {} cells × {} triangles, {} threads, best of {repeats}",
        sphere.len(),
        part.triangles.len(),
        rayon::current_num_threads()
    );
    // Each phase prints as soon as it is done (the large case takes minutes).
    let mut vis = Vec::new();
    let mut map = None;
    for _ in 0..repeats {
        let t = Instant::now();
        map = Some(visibility_map(part, &sphere, &config, &report).expect("valid config"));
        vis.push(t.elapsed().as_secs_f64());
    }
    let map = map.expect("at least one run");
    println!(
        "  visibility map : {:9.3} s  ({:.2} M patch-cell pairs/s)",
        best(&vis),
        rays / best(&vis) / 1e6
    );
    if std::env::args().any(|a| a == "map-only") {
        return;
    }
    // `compare`: the bounded search and the exhaustive one (every cell
    // evaluated) side by side, alternating (A B A B), same answer asserted.
    let compare = std::env::args().any(|a| a == "compare");
    let exhaustive = SetupConfig {
        probe_cells: 0,
        ..config
    };
    for (label, kind) in [
        ("C,A search", MachineType::CA),
        ("A,B search", MachineType::AB),
    ] {
        let (mut times, mut times_ex) = (Vec::new(), Vec::new());
        let mut last = None;
        for _ in 0..repeats {
            let t = Instant::now();
            let p = search_setup(&map, &sphere, kind, &ranges, &config, &report);
            times.push(t.elapsed().as_secs_f64());
            if compare {
                let t = Instant::now();
                let e = search_setup(&map, &sphere, kind, &ranges, &exhaustive, &report);
                times_ex.push(t.elapsed().as_secs_f64());
                assert_eq!(
                    (p.mar.cell, p.mar.placement.key()),
                    (e.mar.cell, e.mar.placement.key()),
                    "{label}: bounded and exhaustive MAR differ"
                );
                assert_eq!(
                    p.setup.map(|s| (s.cell, s.placement.key())),
                    e.setup.map(|s| (s.cell, s.placement.key())),
                    "{label}: bounded and exhaustive setups differ"
                );
            }
            last = Some(p);
        }
        let p = last.expect("at least one run");
        let o = p.setup.as_ref().unwrap_or(&p.mar);
        println!(
            "  {label}     : {:9.3} s  ({} PVC classes, {} of {} cells evaluated, feasible {}, MAR {:.1?}°, gap to bound {:.2e} rad², {:?} equivalent)",
            best(&times),
            p.pvc_classes,
            p.evaluated,
            p.cells,
            p.feasible,
            p.mar.placement.required.degrees(),
            o.placement.area - o.lower_bound.0,
            o.equivalent,
        );
        if compare {
            println!(
                "  {label} exhaustive: {:9.3} s  (times {times:.3?} vs {times_ex:.3?}; ratio {:.2})",
                best(&times_ex),
                best(&times_ex) / best(&times)
            );
        }
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let mesh =
        |soup: Vec<_>| TriMesh::from_triangles(&soup, WeldOptions::default()).expect("valid");
    if args.iter().any(|a| a == "cavity") {
        run(
            "cavity (test part)",
            &mesh(cavity(30.0, 60.0, 12, 36)),
            5000,
            3,
        );
    }
    if args.iter().any(|a| a == "medium") {
        run("medium teapot", &mesh(teapot(40, 64, 18, 32)), 5000, 1);
    }
    if args.iter().any(|a| a == "large") {
        run("large teapot", &mesh(teapot(160, 256, 72, 128)), 20_000, 1);
    } else if !args.iter().any(|a| a == "cavity" || a == "medium") {
        run("paper teapot", &mesh(teapot(10, 12, 5, 6)), 1200, 5);
    }
}
