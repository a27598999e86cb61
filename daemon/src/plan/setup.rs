//! `interpd plan setup`: 5-axis machinability and setup orientation of a part
//! (seed `000_…`, `planner::setup`).
//!
//! Reads an STL, builds the binary spherical map, searches the setup for the
//! given machine (`W/…/T`) and rotary ranges, and prints whether one setup
//! machines the part, the setup orientation and the ranges it needs, or for
//! an infeasible part the minimum axis ranges (MAR) to ask for; with each,
//! how far from optimal it can be, how many other setups are as good, and the
//! rotary axis positions that turn the part to it for 3+2 machining. A
//! progress bar goes to stderr when it is a terminal.

use std::io::IsTerminal;
use std::path::PathBuf;
use std::sync::Mutex;

use anyhow::{Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use planner::mesh::{TriMesh, WeldOptions};
use planner::setup::{
    AxisRanges, MachineConfig, MachineType, Phase, SetupConfig, SetupOrientation, SetupPlan,
    plan_setup,
};
use serde::Serialize;

/// Options of `interpd plan setup`.
#[derive(Clone, Debug)]
pub struct SetupOptions {
    /// The part, binary or ASCII STL (mm). Each triangle is one surface patch.
    pub stl: PathBuf,
    /// Machine configuration in W/…/T notation, e.g. W/caxyBz/T (C,A) or W/baxzBy/T (A,B).
    pub machine: MachineConfig,
    /// Rotary ranges in degrees: PHI_L,PHI_S (C,A: tilt axis; A,B: R1),
    /// THETA_L,THETA_S (C,A: C axis; A,B: R2).
    pub ranges: AxisRanges,
    /// Minimum number of sphere cells (rounded up to 20·f²).
    pub cells: usize,
    /// Print JSON instead of text.
    pub json: bool,
}

/// Ranges in degrees, as printed.
#[derive(Debug, Serialize)]
struct RangesDeg {
    phi_l: f64,
    phi_s: f64,
    theta_l: f64,
    theta_s: f64,
}

impl From<&AxisRanges> for RangesDeg {
    fn from(r: &AxisRanges) -> Self {
        let [phi_l, phi_s, theta_l, theta_s] = r.degrees();
        Self {
            phi_l,
            phi_s,
            theta_l,
            theta_s,
        }
    }
}

/// Other setups within the equivalence tolerance of the best (a flat
/// optimum), as printed.
#[derive(Debug, Serialize)]
struct EquivalentOut {
    /// How many other tool axes are within the tolerance.
    count: usize,
    /// The largest angle from the reported tool axis to theirs, degrees.
    max_axis_angle_deg: f64,
    /// The area tolerance, deg².
    area_tolerance_deg2: f64,
}

/// One rotary axis position for 3+2 machining, as printed.
#[derive(Debug, Serialize)]
struct AxisPositionOut {
    /// The machine's axis letter (A, B or C).
    axis: String,
    deg: f64,
}

/// One placement, as printed.
#[derive(Debug, Serialize)]
struct OrientationOut {
    tool_axis: [f64; 3],
    /// C,A: "C"; A,B: the machine axis playing R1.
    axis_1_name: String,
    axis_1: [f64; 3],
    /// C,A: the tilt axis (A or B); A,B: the machine axis playing R2.
    axis_2_name: String,
    axis_2: [f64; 3],
    required_deg: RangesDeg,
    area_deg2: f64,
    /// No setup on this map has a smaller area (the certificate).
    lower_bound_deg2: f64,
    /// `area_deg2 − lower_bound_deg2`: how far from optimal it can be.
    gap_deg2: f64,
    /// Other setups as good (`null` when not searched: the MAR of a part
    /// that fits).
    equivalent: Option<EquivalentOut>,
    /// The rotary axes (nearer the part first) at which the tool axis, seen
    /// from the part as it lies in the STL's frame, is `tool_axis`: position
    /// them so, then cut what that direction reaches with 3 axes.
    rotary_positions: [AxisPositionOut; 2],
    /// Whether those positions lie within the machine's ranges.
    rotary_positions_within_ranges: bool,
    one_sided_fan: bool,
    group_ii_classes: usize,
    md_points: usize,
}

#[derive(Debug, Serialize)]
struct PlanOut {
    machine: String,
    rotary_order: String,
    machine_type: &'static str,
    ranges_deg: RangesDeg,
    cells: usize,
    patches: usize,
    pvc_classes: usize,
    unreachable_patches: usize,
    /// Patches whose cone is about a cell wide or narrower.
    narrow_patches: usize,
    /// Tool axes evaluated exactly (the others were ruled out by bounds).
    evaluated_cells: usize,
    three_axis: bool,
    feasible: bool,
    setup: Option<OrientationOut>,
    minimum_axis_ranges: OrientationOut,
}

fn orientation(
    machine: &MachineConfig,
    ranges: &AxisRanges,
    o: &SetupOrientation,
) -> OrientationOut {
    let (r1, r2) = machine.roles();
    let name = |a| format!("{a:?}");
    let p = &o.placement;
    let deg2 = |a: f64| a.to_degrees().to_degrees();
    let positions = machine.rotary_positions(ranges, &p.tool_axis);
    let position = |(axis, q): (_, f64)| AxisPositionOut {
        axis: name(axis),
        deg: q.to_degrees(),
    };
    OrientationOut {
        tool_axis: p.tool_axis.into(),
        axis_1_name: name(r1),
        axis_1: p.axis_1.into(),
        axis_2_name: name(r2),
        axis_2: p.axis_2.into(),
        required_deg: (&p.required).into(),
        area_deg2: deg2(p.area),
        lower_bound_deg2: deg2(o.lower_bound.0),
        gap_deg2: deg2(p.area - o.lower_bound.0),
        equivalent: o.equivalent.map(|(count, angle)| EquivalentOut {
            count,
            max_axis_angle_deg: angle.to_degrees(),
            area_tolerance_deg2: deg2(o.equivalent_tolerance),
        }),
        rotary_positions: [position(positions.first), position(positions.second)],
        rotary_positions_within_ranges: positions.within_ranges,
        one_sided_fan: p.one_sided,
        group_ii_classes: o.group_ii_classes,
        md_points: o.md_points,
    }
}

fn output(args: &SetupOptions, plan: &SetupPlan) -> PlanOut {
    let m = &args.machine;
    PlanOut {
        machine: m.notation().to_string(),
        rotary_order: m.key().to_string(),
        machine_type: match plan.machine_type {
            MachineType::CA => "C,A",
            MachineType::AB => "A,B",
        },
        ranges_deg: (&args.ranges).into(),
        cells: plan.cells,
        patches: plan.patches,
        pvc_classes: plan.pvc_classes,
        unreachable_patches: plan.unreachable_patches.len(),
        narrow_patches: plan.narrow_patches.len(),
        evaluated_cells: plan.evaluated,
        three_axis: plan.three_axis,
        feasible: plan.feasible,
        setup: plan.setup.as_ref().map(|o| orientation(m, &args.ranges, o)),
        minimum_axis_ranges: orientation(m, &args.ranges, &plan.mar),
    }
}

fn print_text(out: &PlanOut) {
    println!(
        "part: {} patches ({} distinct visibility cones, {} unreachable, {} narrower than a cell), sphere: {} cells",
        out.patches, out.pvc_classes, out.unreachable_patches, out.narrow_patches, out.cells
    );
    println!(
        "machine: {} (rotary order {}, {} type), ranges φL {} φS {} θL {} θS {} deg",
        out.machine,
        out.rotary_order,
        out.machine_type,
        out.ranges_deg.phi_l,
        out.ranges_deg.phi_s,
        out.ranges_deg.theta_l,
        out.ranges_deg.theta_s
    );
    println!(
        "3-axis (one direction reaches every patch): {}",
        out.three_axis
    );
    let show = |label: &str, o: &OrientationOut| {
        let v = |a: [f64; 3]| format!("({:+.4}, {:+.4}, {:+.4})", a[0], a[1], a[2]);
        println!("{label}:");
        println!("  tool axis      {}", v(o.tool_axis));
        println!("  {} axis {:>6}{}", o.axis_1_name, "", v(o.axis_1));
        println!("  {} axis {:>6}{}", o.axis_2_name, "", v(o.axis_2));
        let r = &o.required_deg;
        println!(
            "  needs φL {:.2} φS {:.2} θL {:.2} θS {:.2} deg (area {:.1} deg², {} MD points{})",
            r.phi_l,
            r.phi_s,
            r.theta_l,
            r.theta_s,
            o.area_deg2,
            o.md_points,
            if o.one_sided_fan { ", one fan" } else { "" }
        );
        println!(
            "  optimal to within {:.3} deg² (no setup needs less than {:.1} deg²)",
            o.gap_deg2, o.lower_bound_deg2
        );
        if let Some(e) = &o.equivalent {
            println!(
                "  {} other tool axes as good (within {:.1} deg²), up to {:.1}° away{}",
                e.count,
                e.area_tolerance_deg2,
                e.max_axis_angle_deg,
                if e.count > 0 { ": a flat optimum" } else { "" }
            );
        }
        let [a, b] = &o.rotary_positions;
        println!(
            "  3+2: {} {:.3}° {} {:.3}° turns the part to this tool axis{}",
            a.axis,
            a.deg,
            b.axis,
            b.deg,
            if o.rotary_positions_within_ranges {
                ""
            } else {
                " (outside the machine's ranges)"
            }
        );
    };
    if let Some(setup) = &out.setup {
        println!("FEASIBLE in one setup");
        show("setup orientation (least rotary motion)", setup);
    } else {
        println!("INFEASIBLE on this machine");
        show(
            "minimum axis ranges (MAR) to ask for",
            &out.minimum_axis_ranges,
        );
    }
}

/// Runs `interpd plan setup`.
pub fn main(args: &SetupOptions) -> Result<()> {
    let out = compute(args)?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        print_text(&out);
    }
    Ok(())
}

/// Reads the part and plans its setup.
fn compute(args: &SetupOptions) -> Result<PlanOut> {
    let mesh = TriMesh::from_stl_path(&args.stl, WeldOptions::default())
        .with_context(|| format!("reading {}", args.stl.display()))?;
    let config = SetupConfig {
        cells: args.cells,
        ..SetupConfig::default()
    };
    let bar: Mutex<Option<(Phase, ProgressBar)>> = Mutex::new(None);
    let show_bar = std::io::stderr().is_terminal();
    let progress = |phase: Phase, done: usize, total: usize| {
        if !show_bar {
            return;
        }
        let Ok(mut slot) = bar.lock() else { return };
        if slot.as_ref().is_none_or(|(p, _)| *p != phase) {
            if let Some((_, old)) = slot.take() {
                old.finish();
            }
            let pb = ProgressBar::new(total as u64);
            let label = match phase {
                Phase::Visibility => "map     ",
                Phase::Search => "search  ",
                Phase::Refine => "refine  ",
            };
            if let Ok(style) =
                ProgressStyle::with_template("{prefix} [{bar:40}] {pos}/{len} {elapsed_precise}")
            {
                pb.set_style(style.progress_chars("=> "));
            }
            pb.set_prefix(label);
            *slot = Some((phase, pb));
        }
        if let Some((_, pb)) = slot.as_ref() {
            // Refinement rounds differ in size.
            pb.set_length(total as u64);
            pb.set_position(done as u64);
        }
    };
    let plan = plan_setup(&mesh, &args.machine, &args.ranges, &config, &progress)
        .context("planning the setup")?;
    if let Ok(mut slot) = bar.lock()
        && let Some((_, pb)) = slot.take()
    {
        pb.finish_and_clear();
    }
    Ok(output(args, &plan))
}

#[cfg(test)]
mod tests {
    use super::*;
    use planner::mesh::ascii_stl;
    use planner::setup::samples::teapot;

    fn args(stl: PathBuf, machine: &str, ranges: &str) -> SetupOptions {
        SetupOptions {
            stl,
            machine: machine.parse().unwrap(),
            ranges: ranges.parse().unwrap(),
            cells: 1200,
            json: true,
        }
    }

    #[test]
    fn teapot_stl_plans_end_to_end_and_bad_stl_is_an_error() {
        let dir = std::env::temp_dir().join(format!("interpd-plan-setup-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let stl = dir.join("teapot.stl");
        std::fs::write(&stl, ascii_stl("teapot", &teapot(10, 12, 5, 6))).unwrap();
        let out = compute(&args(stl.clone(), "W/caxyBz/T", "90,90,180,180")).unwrap();
        assert!(out.feasible && !out.three_axis);
        assert_eq!(
            (out.patches, out.cells, out.rotary_order.as_str()),
            (288, 1280, "caB")
        );
        let setup = out.setup.as_ref().unwrap();
        assert!(setup.tool_axis[0] > 0.0, "tilts toward the spout");
        let json = serde_json::to_value(&out).unwrap();
        assert_eq!(json["machine_type"], "C,A");
        // Too little tilt: infeasible, with MAR.
        let out = compute(&args(stl, "W/baxzBy/T", "5,5,5,5")).unwrap();
        assert!(!out.feasible && out.setup.is_none());
        assert!(out.minimum_axis_ranges.required_deg.phi_l > 5.0);
        let bad = dir.join("bad.stl");
        std::fs::write(
            &bad,
            "solid x\nfacet normal 0 0 0\nouter loop\nvertex 0 0 nan\n",
        )
        .unwrap();
        let err = compute(&args(bad, "W/caxyBz/T", "1,1,1,1")).unwrap_err();
        assert!(format!("{err:#}").contains("bad.stl"), "{err:#}");
        std::fs::remove_dir_all(&dir).ok();
    }
}
