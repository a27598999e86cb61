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
//! exact cell test). All cores are used (rayon). `repeat=N` sets the runs
//! per phase; `every=K` maps every K-th patch only (a sample of a large part,
//! for profiling the map; the search is skipped). Each phase prints its wall
//! time and the process's CPU time (all threads), best of the runs; the
//! search's classes of identical cones are built once (`PreparedMap`) and
//! timed as a phase of their own.

use std::time::Instant;

use planner::mesh::{TriMesh, WeldOptions};
use planner::setup::samples::{cavity, teapot};
use planner::setup::visibility::{self, VisibilityOptions};
use planner::setup::{
    AxisRanges, GeodesicSphere, MachineType, Phase, PreparedMap, SetupConfig, visibility_map,
};

/// CPU time of the whole process (all threads) so far, seconds.
fn cpu_now() -> f64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid timespec for the call to fill.
    unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut ts) };
    ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9
}

/// The value of a `name=value` argument.
fn arg_value(name: &str) -> Option<usize> {
    std::env::args().find_map(|a| a.strip_prefix(name)?.strip_prefix('=')?.parse().ok())
}

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
    let repeats = arg_value("repeat").unwrap_or(repeats).max(1);
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
    let every = arg_value("every").unwrap_or(1).max(1);
    let (mut vis, mut vis_cpu) = (Vec::new(), Vec::new());
    let mut map = None;
    for _ in 0..repeats {
        let (t, cpu) = (Instant::now(), cpu_now());
        map = Some(if every > 1 {
            let options = VisibilityOptions {
                exact_cells: config.exact_cells,
                ..VisibilityOptions::default()
            };
            visibility::compute_sampled(part, &sphere, options, every, &|d, n| {
                report(Phase::Visibility, d, n)
            })
        } else {
            visibility_map(part, &sphere, &config, &report).expect("valid config")
        });
        vis.push(t.elapsed().as_secs_f64());
        vis_cpu.push(cpu_now() - cpu);
    }
    let map = map.expect("at least one run");
    let patches = part.triangles.len().div_ceil(every) as f64;
    println!(
        "  visibility map : {:9.3} s  cpu {:9.3} s  ({:.2} M patch-cell pairs/s; every {every}th patch)",
        best(&vis),
        best(&vis_cpu),
        rays * patches / part.triangles.len() as f64 / best(&vis) / 1e6
    );
    // Two builds map alike when their checksums agree.
    {
        use std::hash::{Hash, Hasher};
        let mut h = std::collections::hash_map::DefaultHasher::new();
        let mut open = 0;
        for j in 0..map.patches() {
            map.pvc(j).hash(&mut h);
            open += map.pvc_len(j);
        }
        println!("  map checksum {:016x}, {open} open pairs", h.finish());
    }
    if every > 1 || std::env::args().any(|a| a == "map-only") {
        return;
    }
    // `compare`: the bounded search and the exhaustive one (every cell
    // evaluated) side by side, alternating (A B A B), same answer asserted.
    let compare = std::env::args().any(|a| a == "compare");
    let exhaustive = SetupConfig {
        probe_cells: 0,
        ..config
    };
    // The classes of identical cones, once for both searches (as
    // `PreparedMap` serves any number of searches of one map).
    let (t, c) = (Instant::now(), cpu_now());
    let prepared = PreparedMap::new(&map, &sphere);
    println!(
        "  search classes :{:10.3} s  cpu {:9.3} s  ({} PVC classes, once for both searches)",
        t.elapsed().as_secs_f64(),
        cpu_now() - c,
        prepared.classes()
    );
    for (label, kind) in [
        ("C,A search", MachineType::CA),
        ("A,B search", MachineType::AB),
    ] {
        let (mut times, mut times_ex, mut cpu) = (Vec::new(), Vec::new(), Vec::new());
        let mut last = None;
        for _ in 0..repeats {
            let (t, c) = (Instant::now(), cpu_now());
            let p = prepared.search(kind, &ranges, &config, &report);
            times.push(t.elapsed().as_secs_f64());
            cpu.push(cpu_now() - c);
            if compare {
                let t = Instant::now();
                let e = prepared.search(kind, &ranges, &exhaustive, &report);
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
        // The answer in full, to check that two builds agree.
        println!(
            "  {label} answer: cell {}, area {:e} rad², required {:?} rad, lower bound {:?}",
            o.cell, o.placement.area, o.placement.required, o.lower_bound
        );
        println!(
            "  {label}     : {:9.3} s  cpu {:9.3} s  ({} PVC classes, {} of {} cells evaluated, feasible {}, MAR {:.1?}°, gap to bound {:.2e} rad², {:?} equivalent)",
            best(&times),
            best(&cpu),
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
