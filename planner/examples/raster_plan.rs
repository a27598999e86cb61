//! Plans a raster path over an STL and prints its size and timing: a small
//! driver for profiling the planner without the CLI.
//!
//! ```text
//! cargo run --release -p planner --example raster_plan -- PART.stl [TOOL] [STEPOVER] [REPEAT]
//! ```
//!
//! Defaults: `ball:6`, 0.5 mm, 1 run. Prints one line per run.

use std::time::Instant;

use planner::cutter::Cutter;
use planner::mesh::{TriMesh, WeldOptions};
use planner::raster::{RasterConfig, plan_raster};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(stl) = args.first() else {
        eprintln!("usage: raster_plan PART.stl [TOOL] [STEPOVER] [REPEAT]");
        std::process::exit(2);
    };
    let tool: Cutter = args
        .get(1)
        .map_or("ball:6", String::as_str)
        .parse()
        .expect("tool");
    let stepover: f64 = args
        .get(2)
        .map_or(Ok(0.5), |s| s.parse())
        .expect("stepover");
    let repeat: usize = args.get(3).map_or(Ok(1), |s| s.parse()).expect("repeat");
    let t0 = Instant::now();
    let mesh = TriMesh::from_stl_path(stl, WeldOptions::default()).expect("mesh");
    println!(
        "{} triangles read in {:.3} s",
        mesh.triangles.len(),
        t0.elapsed().as_secs_f64()
    );
    let config = RasterConfig {
        stepover,
        ..RasterConfig::default()
    };
    for _ in 0..repeat {
        let t = Instant::now();
        let path = plan_raster(&mesh, &tool, &config).expect("plan");
        println!(
            "{tool}: {} passes, {} pieces, {} points, {:.3} s",
            path.passes.len(),
            path.stats.pieces,
            path.stats.points,
            t.elapsed().as_secs_f64()
        );
    }
}
