//! Plans the 5-axis setup of a part as given and rotated, and prints one
//! line per rotation: the metamorphic check of `docs/planner-setup.md` on
//! any STL (the corpus runs of BENCHMARKS.md).
//!
//! ```text
//! cargo run --release -p planner --example setup_rotations -- PART.stl MACHINE RANGES CELLS [ROT...]
//! ```
//!
//! `ROT` is `x90`, `y-45`, `z30` (axis and degrees) or `r<seed>` (a random
//! rotation from that seed); without any, the part as given and y90. A
//! `ROT` of `compare` also runs the exhaustive search (every cell evaluated)
//! on each rotation and checks that it gives the same answer.

use std::time::Instant;

use nalgebra::{Point3, Rotation3, Unit, Vector3};
use planner::mesh::{TriMesh, WeldOptions};
use planner::setup::samples::random_rotation;
use planner::setup::{AxisRanges, MachineConfig, SetupConfig, plan_setup};

fn rotation(spec: &str) -> Rotation3<f64> {
    let (axis, rest) = spec.split_at(1);
    if axis == "r" {
        return random_rotation(rest.parse().expect("seed"));
    }
    let deg: f64 = rest.parse().expect("degrees");
    let a = match axis {
        "x" => Vector3::x(),
        "y" => Vector3::y(),
        _ => Vector3::z(),
    };
    Rotation3::from_axis_angle(&Unit::new_normalize(a), deg.to_radians())
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 4 {
        eprintln!("usage: setup_rotations PART.stl MACHINE RANGES CELLS [ROT...]");
        std::process::exit(2);
    }
    let mesh = TriMesh::from_stl_path(&args[0], WeldOptions::default()).expect("mesh");
    let machine: MachineConfig = args[1].parse().expect("machine");
    let ranges: AxisRanges = args[2].parse().expect("ranges");
    let config = SetupConfig {
        cells: args[3].parse().expect("cells"),
        ..SetupConfig::default()
    };
    let compare = args[4..].iter().any(|a| a == "compare");
    let mut rots: Vec<String> = args[4..]
        .iter()
        .filter(|a| *a != "compare")
        .cloned()
        .collect();
    if rots.is_empty() {
        rots = vec!["z0".into(), "y90".into()];
    }
    println!("{} triangles", mesh.triangles.len());
    for spec in &rots {
        let r = rotation(spec);
        let soup: Vec<[Point3<f64>; 3]> = (0..mesh.triangles.len())
            .map(|t| mesh.corners(t).map(|p| r * p))
            .collect();
        let part = TriMesh::from_triangles(&soup, WeldOptions::default()).expect("rotated");
        let t0 = Instant::now();
        let plan = plan_setup(&part, &machine, &ranges, &config, &|_, _, _| {}).expect("plan");
        let secs = t0.elapsed().as_secs_f64();
        let o = plan.setup.as_ref().unwrap_or(&plan.mar);
        let back = r.inverse() * o.placement.tool_axis;
        let d = o.placement.required.degrees();
        let (equivalent, spread) = o.equivalent.unwrap_or((0, 0.0));
        println!(
            "{spec:>6}: feasible {} unreachable {} narrow {} axis(part frame) ({:+.3},{:+.3},{:+.3}) req {:.2}/{:.2} {:.2}/{:.2} area {:.1} deg² (bound {:.1}), {} equivalent within {:.1}°, {} of {} cells evaluated ({:.2} s)",
            plan.feasible,
            plan.unreachable_patches.len(),
            plan.narrow_patches.len(),
            back.x,
            back.y,
            back.z,
            d[0],
            d[1],
            d[2],
            d[3],
            o.placement.area.to_degrees().to_degrees(),
            o.lower_bound.0.to_degrees().to_degrees(),
            equivalent,
            spread.to_degrees(),
            plan.evaluated,
            plan.cells,
            secs
        );
        if compare {
            let exhaustive = SetupConfig {
                probe_cells: 0,
                ..config
            };
            let t0 = Instant::now();
            let e = plan_setup(&part, &machine, &ranges, &exhaustive, &|_, _, _| {}).expect("plan");
            let eo = e.setup.as_ref().unwrap_or(&e.mar);
            let same = (eo.cell, eo.placement.key()) == (o.cell, o.placement.key());
            println!(
                "        exhaustive: same answer {same} ({:.2} s with the map)",
                t0.elapsed().as_secs_f64()
            );
        }
    }
}
