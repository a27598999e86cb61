//! Issue 9: path time against the acceleration-only optimum, on the bundled
//! butterfly (the corpus curves run with the `path_time` example); issue
//! 15: the lower bound of any jerk-limited schedule between the two.

use interp_core::Curve;
use interp_core::path::{Block, Path};
use interp_core::samples::butterfly;
use interp_core::{InterpConfig, nurbs::split_program_curve};
use interpd_tests::path_time::{
    Command, InterpolatedRun, OVERRIDE_KNOB, PathTimes, abort_scan, accel_only_optimum, every,
    first_curve, interpolated_run, interpolated_run_with_commands, interpolated_run_with_overrides,
    jerk_aware_bound, load_as_run, load_program, load_turned_as_run, machine_with_jerk, path_times,
    rest_to_rest, step_cap,
};

/// The target: total path time ≤ 1.10 × the acceleration-only optimum.
const TARGET_RATIO: f64 = 1.10;

fn butterfly_blocks(feed: f64) -> Vec<Block> {
    let mut out = Vec::new();
    split_program_curve::<()>(
        butterfly::BUTTERFLY_DEGREE,
        &butterfly::BUTTERFLY_POINTS,
        &butterfly::BUTTERFLY_WEIGHTS,
        &butterfly::BUTTERFLY_KNOTS,
        20,
        |n| {
            out.push(Block::new(out.len() as u32 + 1, Path::Nurbs(n), feed));
            Ok(())
        },
    )
    .unwrap();
    out
}

#[test]
fn butterfly_at_its_program_feed_is_within_the_target_of_the_optimum() {
    let cfg = InterpConfig::default();
    let feed = butterfly::PROGRAM_FEED_MM_PER_MIN / 60.0;
    let blocks = butterfly_blocks(feed);
    let t = path_times(&blocks, &cfg).unwrap();
    eprintln!(
        "butterfly F={feed:.2} mm/s: {t:?} ratio {:.4}",
        t.ours / t.optimum
    );
    assert!(t.optimum <= t.ours, "the optimum is a lower bound: {t:?}");
    assert!(t.optimum <= t.trapezoid, "{t:?}");
    assert_bound_between(&t);
    assert!(
        t.ours <= TARGET_RATIO * t.optimum,
        "ratio {} {t:?}",
        t.ours / t.optimum
    );
}

#[test]
fn at_high_feed_jerk_limits_cost_time_but_the_order_holds() {
    // 100 mm/s on the butterfly: the per-axis jerk limits bind on its tight
    // turns (see BENCHMARKS.md for the ratios); the optimum stays a lower
    // bound of both schedules and jerk limits only add time.
    let cfg = InterpConfig::default();
    let blocks = butterfly_blocks(100.0);
    let t = path_times(&blocks, &cfg).unwrap();
    eprintln!(
        "butterfly F=100 mm/s: {t:?} ratio {:.4}",
        t.ours / t.optimum
    );
    assert!(t.optimum <= t.trapezoid && t.trapezoid <= t.ours, "{t:?}");
    assert_bound_between(&t);
    // The trapezoidal schedule of the core issue is near the optimum.
    assert!(t.trapezoid <= TARGET_RATIO * t.optimum, "{t:?}");
}

#[test]
fn optimum_of_a_line_is_the_trapezoid_formula() {
    use interp_core::geom::Vec3;
    use interp_core::path::Line;
    let cfg = InterpConfig::default();
    let (l, f, a) = (50.0, 100.0, cfg.max_path_accel);
    let line = Line::new(Vec3::zeros(), Vec3::new(l, 0.0, 0.0)).unwrap();
    let t = accel_only_optimum(&[Block::new(1, Path::Line(line), f)], &cfg);
    // Accelerate to F, cruise, brake: L/F + F/A.
    let want = l / f + f / a;
    assert!((t - want).abs() < 1e-3 * want, "{t} vs {want}");
}

/// The jerk-aware bound lies between the acceleration-only optimum and our
/// jerk-limited time, and above the optimum by at least the ramps of the
/// two rests (a start and an end cost `a/j` each, at least, on any curve
/// fast enough to reach `a`: here the ramps from rest to a few mm/s).
fn assert_bound_between(t: &PathTimes) {
    assert!(t.optimum < t.bound, "{t:?}");
    assert!(t.bound <= t.ours, "the bound is above our time: {t:?}");
}

fn line(from: [f64; 3], to: [f64; 3]) -> interp_core::path::Path {
    use interp_core::geom::Vec3;
    use interp_core::path::Line;
    let v = |p: [f64; 3]| Vec3::new(p[0], p[1], p[2]);
    Path::Line(Line::new(v(from), v(to)).unwrap())
}

#[test]
fn bound_of_a_line_is_the_seven_phase_rest_to_rest_time() {
    let cfg = InterpConfig::default();
    let (a, j) = (cfg.max_path_accel, cfg.max_path_jerk);
    // A cruise at the feed (50 mm): the seven-phase time. A peak below the
    // feed (2 mm), a peak below a²/j, never at full acceleration (0.5 mm),
    // a micro-move: the passes close in on the peak from above, to within
    // a few tenths of a percent (and never past it).
    for (l, f, tol) in [
        (50.0, 100.0, 1e-4),
        (2.0, 100.0, 5e-3),
        (0.5, 100.0, 5e-3),
        (0.001, 100.0, 5e-3),
    ] {
        let blocks = [Block::new(1, line([0.0; 3], [l, 0.0, 0.0]), f)];
        let bound = jerk_aware_bound(&blocks, &cfg);
        let want = rest_to_rest(l, f, a, j);
        let opt = accel_only_optimum(&blocks, &cfg);
        eprintln!("line {l} mm: bound {bound} s, seven-phase {want} s, optimum {opt} s");
        assert!(bound <= want * (1.0 + 1e-6), "{l} mm: {bound} vs {want}");
        assert!(bound >= want * (1.0 - tol), "{l} mm: {bound} vs {want}");
        assert!(opt < bound, "{l} mm: {opt} vs {bound}");
    }
}

#[test]
fn short_moves_from_rest_to_rest_use_the_jerk_from_the_rest_on() {
    // Moves too short to reach the feed are all ramps: their time is set by
    // how the schedule leaves and reaches rest. With quadratic pieces there
    // (jerk α·v, nothing at the rest) a 0.02, 0.14, 1 and 5 mm move took
    // 1.51, 1.46, 1.36 and 1.21× their jerk-limited time; with the ramp
    // form next to a rest point (`spline::Form`), which starts at the jerk
    // limit, 1.24, 1.21, 1.10 and 1.07× (times in whole ticks); with
    // the ramp's jerk held through the tangent at its cap (it took
    // `√G ≤ V_p`: 85 % of the limit), 1.18, 1.13, 1.08 and 1.05× (before:
    // 1.18, 1.15, 1.10, 1.07), and a 20 mm move 1.022× (1.026).
    let cfg = InterpConfig::default();
    let (a, j) = (cfg.max_path_accel, cfg.max_path_jerk);
    for (l, most) in [
        (0.02, 1.2),
        (0.14, 1.14),
        (1.0, 1.09),
        (5.0, 1.06),
        (20.0, 1.025),
    ] {
        let blocks = [Block::new(1, line([0.0; 3], [l, 0.0, 0.0]), 100.0)];
        let t = path_times(&blocks, &cfg).unwrap();
        let want = rest_to_rest(l, 100.0, a, j);
        eprintln!(
            "line {l} mm: ours {} s, seven-phase {want} s, ratio {:.3}",
            t.ours,
            t.ours / want
        );
        assert_bound_between(&t);
        assert!(t.ours <= most * want, "{l} mm: {} vs {want}", t.ours);
    }
}

#[test]
fn bound_of_a_gentle_arc_is_the_seven_phase_time_on_the_fine_grid() {
    // A line is one cell of the bound's grid; an arc is sampled every 5 µm
    // like a curve. Radius 1 m: only the feed binds, as on a line.
    use interp_core::geom::Vec3;
    use interp_core::path::Arc;
    let cfg = InterpConfig::default();
    let r = 1000.0;
    let (s, c) = (50.0f64 / r).sin_cos();
    let arc = Arc::from_centre(
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(r * s, r - r * c, 0.0),
        Vec3::new(0.0, r, 0.0),
        Vec3::z(),
        0,
    )
    .unwrap();
    let blocks = [Block::new(1, Path::Arc(arc), 100.0)];
    let bound = jerk_aware_bound(&blocks, &cfg);
    let want = rest_to_rest(50.0, 100.0, cfg.max_path_accel, cfg.max_path_jerk);
    assert!((bound - want).abs() < 1e-4 * want, "{bound} vs {want}");
}

#[test]
fn rest_to_rest_without_jerk_is_the_trapezoid() {
    // Accelerate to F, cruise, brake: L/F + F/A; and the triangle 2·√(L/A).
    let (a, inf) = (2000.0, f64::INFINITY);
    assert!((rest_to_rest(50.0, 100.0, a, inf) - (0.5 + 0.05)).abs() < 1e-12);
    assert!((rest_to_rest(1.0, 100.0, a, inf) - 2.0 * (1.0 / a).sqrt()).abs() < 1e-12);
    // Jerk adds a/j to a move that cruises.
    let j = 1e5;
    let d = rest_to_rest(50.0, 100.0, a, j) - rest_to_rest(50.0, 100.0, a, inf);
    assert!((d - a / j).abs() < 1e-12, "{d}");
}

/// A line into a tangent arc of radius `r` (along X, turning towards +Y).
fn line_into_arc(r: f64, feed: f64) -> Vec<Block> {
    use interp_core::geom::Vec3;
    use interp_core::path::Arc;
    let arc = Arc::from_centre(
        Vec3::new(10.0, 0.0, 0.0),
        Vec3::new(10.0 + r, r, 0.0),
        Vec3::new(10.0, r, 0.0),
        Vec3::z(),
        0,
    )
    .unwrap();
    vec![
        Block::new(1, line([0.0; 3], [10.0, 0.0, 0.0]), feed),
        Block::new(2, Path::Arc(arc), feed),
    ]
}

#[test]
fn the_step_cap_of_a_line_into_an_arc_is_the_lower_bound_formula() {
    // Y's acceleration steps by v²/r; half of it in one third difference,
    // less what the smooth jerk can cancel there, J + 3·v·A/r (t_y = 0,
    // no C‴ in Y at the joint): v² − 6·A·Ts·v − 2·r·Ts·J = 0.
    let cfg = InterpConfig::default();
    let r = 5.0;
    let blocks = line_into_arc(r, 100.0);
    let (l, rt) = (&blocks[0].path, &blocks[1].path);
    let (dl, dr) = (l.eval(l.u_end(), 3), rt.eval(rt.u_start(), 3));
    let cap = step_cap(&dl, &dr, &cfg);
    let (a, ts, j) = (cfg.max_path_accel, cfg.period, cfg.axis_max_jerk[1]);
    let want = 3.0 * a * ts + (9.0 * a * a * ts * ts + 2.0 * r * ts * j).sqrt();
    assert!((cap - want).abs() < 1e-9 * want, "{cap} vs {want}");
    // The planner's own (conservative) junction is slower.
    let planner = interp_core::feed::junction_speed(&dl, &dr, &cfg);
    assert!(planner < cap, "{planner} vs {cap}");
}

#[test]
fn the_bound_holds_below_our_time_where_steps_and_stops_bind() {
    let cfg = InterpConfig::default();
    // A curvature step passed at speed; corners of G61 lines (stops).
    let mut corners = Vec::new();
    let pts = [
        [0.0, 0.0, 0.0],
        [5.0, 0.0, 0.0],
        [5.0, 3.0, 0.0],
        [1.0, 4.0, 1.0],
        [0.2, 0.1, 0.0],
    ];
    for (k, w) in pts.windows(2).enumerate() {
        corners.push(Block::new(k as u32 + 1, line(w[0], w[1]), 80.0));
    }
    for (name, blocks) in [
        ("line into arc", line_into_arc(5.0, 100.0)),
        ("corners", corners),
    ] {
        let t = path_times(&blocks, &cfg).unwrap();
        eprintln!("{name}: {t:?}");
        assert_bound_between(&t);
    }
}

/// A bundled program's first curve at F6000 through the interpolator (one
/// run gives our time and the checks; the trapezoid is not needed), checked
/// to stay between the jerk-aware bound and `most` × the optimum with every
/// limit held on every tick.
fn assert_first_curve_at_f6000(program: &str, most: f64) {
    let file = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../gcode/tests/programs")
        .join(program);
    let blocks = first_curve(&load_program(&file, Some(6000.0), None).unwrap());
    let cfg = InterpConfig::default();
    let run = interpolated_run(&blocks, &cfg, false).unwrap();
    let (ours, optimum) = (run.time, accel_only_optimum(&blocks, &cfg));
    let bound = jerk_aware_bound(&blocks, &cfg);
    eprintln!("{program} F6000: ours {ours} optimum {optimum} bound {bound}");
    assert!(optimum < bound, "optimum {optimum} bound {bound}");
    assert!(bound <= ours, "the bound {bound} is above our time {ours}");
    assert!(ours <= most * optimum, "ratio {}", ours / optimum);
    assert_eq!(run.violations.total(), 0, "{:?}", run.violations);
}

/// Issue 15's target on a curve with a sharp turn: `homer-q2`'s first curve
/// at F6000 within 1.2× its acceleration-only optimum, every limit held on
/// every tick. Its 1.5 µm turn dips the machine law to 0.6 mm/s over a few
/// µm; charged to a whole law sub-range (31 µm), the run held that speed
/// for 54 ms and took 1.21× (nested spans now describe the dip).
#[test]
fn a_curve_with_a_sharp_turn_is_within_the_target_at_production_feed() {
    assert_first_curve_at_f6000("homer-q2.ngc", 1.2);
}

/// Issue 15 on a curve of repeated tight turns: `ruota_dentata-q1` (a gear
/// wheel, a tooth every 2.4 mm) at F6000. Between its teeth the schedule is
/// jerk-limited all the way (no stretch reaches the tangential acceleration
/// limit), so it shows how much of the jerk limit the linear program's rows
/// let a plan use: with rows at `v ≤ V_p` the plans used 77–93 % of it and
/// took 1.244× the acceleration-only optimum; with tangent rows 1.227×. A
/// sequential-LP reference (`scp_reference`, 0.025 mm grid) reaches 1.194×,
/// so the 1.2× is not excluded here. The threshold, 1.235×, is our
/// measured time with some slack, not the target.
#[test]
fn a_gear_wheel_at_production_feed_uses_the_jerk_limit() {
    assert_first_curve_at_f6000("ruota_dentata-q1.ngc", 1.235);
}

/// A stationary point near a curve's end: `curva_delfino-q1` turns back
/// 17 µm before its end, and the stretch on each side of the point is
/// shorter than a law sub-range (31 µm). Held whole by its lowest law (the
/// point's, 0.18 mm/s) the run crawled over 15 µm each way, 0.2 s of its
/// 2.47 s (1.157× the optimum); described in steps towards the point it
/// takes 2.26 s (1.062×).
#[test]
fn a_stationary_point_near_a_curves_end_is_passed_without_a_crawl() {
    assert_first_curve_at_f6000("curva_delfino-q1.ngc", 1.1);
}

/// The same stationary point on a soft machine (path jerk 10⁴ mm/s³, axes
/// 2·10⁴): there every per-axis sample near the point may bind, and the
/// interval's sample slots fill. A sample that could not be kept lowered
/// the speed until its axis jerk could not bind under the full tangential
/// acceleration (`3·|C″|·A`, with `C″` growing as `1/√s` towards the
/// point): 0.6 µm/s over the last 33 µm, 60.9 s for the curve, 25× the
/// jerk-aware bound. A schedule held to jerk `J` whose speed stays positive
/// cannot accelerate faster than `√(2·J·v)`; bounded with that, the curve
/// takes 4.0 s (1.64× the bound).
#[test]
fn a_soft_machine_passes_a_stationary_point_whose_samples_overflow_without_a_crawl() {
    assert_first_curve_on_a_soft_machine("curva_delfino-q1.ngc", 2.0);
}

/// The first curve of `program` at F6000 on a soft machine (path jerk 10⁴
/// mm/s³, axes 2·10⁴): every limit held on every tick, within `most` times
/// its jerk-aware bound.
fn assert_first_curve_on_a_soft_machine(program: &str, most: f64) {
    let file = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../gcode/tests/programs")
        .join(program);
    let blocks = first_curve(&load_program(&file, Some(6000.0), None).unwrap());
    let cfg = machine_with_jerk(1e4);
    let run = interpolated_run(&blocks, &cfg, false).unwrap();
    let bound = jerk_aware_bound(&blocks, &cfg);
    eprintln!("soft {program} F6000: ours {} bound {bound}", run.time);
    assert_eq!(run.violations.total(), 0, "{:?}", run.violations);
    assert!(bound <= run.time, "the bound {bound} is above our time");
    assert!(run.time <= most * bound, "ours/bound {}", run.time / bound);
}

/// A soft machine on a curve where an axis's jerk binds nearly everywhere:
/// `curva_scrool_f-q1` at F6000 with path jerk 10⁴ mm/s³. Its per-axis rows
/// outgrew the linear program's budget, and the farthest pieces' were
/// aggregated, one row per axis, which holds the speed to a few mm/s; with
/// ten rows a piece that reached the pieces next to the machine, and the
/// curve took 14.3 s (2.85× the jerk-aware bound); with twelve, 10.3 s
/// (2.05×); with 24, 8.0 s (1.59×).
#[test]
fn a_soft_machine_where_every_axis_sample_binds_plans_with_exact_rows_near_the_machine() {
    assert_first_curve_on_a_soft_machine("curva_scrool_f-q1.ngc", 1.8);
}

/// A program of many curves joined at corners (`homer-q2`, 91 blocks, its
/// corners rest points) on a soft machine: braking into a corner takes the
/// whole look-ahead, at the jerk limit all the way. Each push re-solved the
/// plan from the machine up to the corner, where every row bound and the
/// pieces re-cut next to the rest could not follow the kept plan: every
/// pass failed (16,291 retries), 1,042 solves crawled, and planning took
/// 3 minutes for 42.4 s of motion. When the passes fail, the plan up to a
/// rest point it keeps is now kept whole, and the solve starts from rest
/// there (41 times, no crawl, 37.7 s).
#[test]
fn a_soft_machine_keeps_its_plan_up_to_a_corner_where_it_rests() {
    let file = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../gcode/tests/programs/homer-q2.ngc");
    let cfg = machine_with_jerk(1e4);
    let blocks = load_as_run(&file, Some(6000.0), None, &cfg).unwrap();
    let run = interpolated_run(&blocks, &cfg, false).unwrap();
    eprintln!("soft homer-q2 F6000: {} s, {:?}", run.time, run.plan);
    assert_eq!(run.violations.total(), 0, "{:?}", run.violations);
    assert_eq!(run.plan.crawled, 0, "{:?}", run.plan);
    assert!(run.plan.retries() < 500, "{:?}", run.plan);
}

/// A soft machine (path jerk 10⁴ mm/s³, axes 2·10⁴) passes both dolphins'
/// stationary points, each run whole at F6000, without crawling up to them.
/// On the G6.2 curve (s = 406.74 mm) the curvature blows up next to the
/// point, the interval held more per-axis samples than it has room for, and
/// each one left over lowered its whole sub-range (31 µm) to the speed at
/// which its axis jerk cannot bind: 0.039 mm/s for 886 ticks; it now lowers
/// the narrowest span that holds it (there, the point's own steps). On the
/// G5.2 curve (s = 424.23 mm) a long block ends at the point, and its laws'
/// dip at that end lowered the end's sub-range to the point's 0.0059 mm/s:
/// 6,750 ticks; the dip is now described in levels rising from the end. What
/// is left is the approach, slowed by the axis jerk `3·C″·v·a` where the
/// curvature grows (110 and 220 ticks below 0.1 mm/s; a rest at a corner
/// takes about 10).
#[test]
fn a_soft_machine_passes_stationary_points_without_crawling() {
    let cfg = machine_with_jerk(1e4);
    for program in ["curva_delfino-q1.ngc", "curva_delfino-g5-q1.ngc"] {
        let file = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../gcode/tests/programs")
            .join(program);
        let blocks = load_as_run(&file, Some(6000.0), None, &cfg).unwrap();
        let run = interpolated_run(&blocks, &cfg, true).unwrap();
        assert_eq!(run.violations.total(), 0, "{program}: {:?}", run.violations);
        // The longest stretch of ticks below 0.1 mm/s.
        let slow = 0.1 * cfg.period;
        let (mut longest, mut here) = (0, 0);
        for w in run.points.windows(2) {
            if (w[1] - w[0]).norm() < slow {
                here += 1;
                longest = longest.max(here);
            } else {
                here = 0;
            }
        }
        eprintln!(
            "soft {program} F6000: {} s, longest crawl {longest} ticks",
            run.time
        );
        assert!(longest < 300, "{program}: {longest} ticks below 0.1 mm/s");
    }
}

/// A dip of the machine law at a knot where the curvature jumps: the G5.2
/// guitar's law falls from 20 to 2.2 mm/s at a knot 0.1 mm into the curve
/// and rises to 17 mm/s within 25 µm after it. Charged to the knot's law
/// sub-range (the staircase refused a dip whose law jumps at its edge), the
/// run held 0.81 mm/s over 30 µm and took 1.171× the optimum; one-sided
/// levels from the knot take 1.156×.
#[test]
fn a_dip_at_a_knot_where_the_law_jumps_is_held_only_on_its_own_side() {
    assert_first_curve_at_f6000("curva_chitarra-q3.ngc", 1.165);
}

/// A feed override raised after the blocks were queued keeps every limit.
/// `homer-q2` at F6000 is queued at 100 %; at 150 % its curves run at up to
/// 150 mm/s, where an axis's jerk `C‴·v³` binds at points where it could
/// not at 100 mm/s. The per-axis samples were filtered at the programmed
/// feed, so those points had no row and the Y axis reached 1.135× its jerk
/// limit (the planner now keeps every sample that may bind at the largest
/// override). The same run at 100 % is the control: no override, no
/// violation, and the override makes it faster.
#[test]
fn an_override_raised_after_queueing_keeps_every_axis_jerk_limit() {
    let file = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../gcode/tests/programs/homer-q2.ngc");
    let blocks = load_program(&file, Some(6000.0), None).unwrap();
    let cfg = InterpConfig::default();
    let plain = interpolated_run(&blocks, &cfg, false).unwrap();
    assert_eq!(plain.violations.total(), 0, "{:?}", plain.violations);
    let raised = interpolated_run_with_overrides(&blocks, &cfg, &[(2, 1.5)]).unwrap();
    eprintln!(
        "homer-q2 F6000: {:.3} s at 100 %, {:.3} s at 150 %, axis jerk {:?}",
        plain.time, raised.time, raised.measured.axis_jerk_mm_s3
    );
    assert_eq!(
        raised.violations.total(),
        0,
        "{:?} {:?}",
        raised.violations,
        raised.measured
    );
    assert!(
        raised.time < plain.time,
        "{} s against {} s",
        raised.time,
        plain.time
    );
}

/// Every limit held on every tick of `run`, and the look-ahead added no
/// stop (no fall-back to a rest point, no crawl).
fn assert_held_every_limit_and_never_stopped(program: &str, run: &InterpolatedRun) {
    assert_eq!(
        run.violations.total(),
        0,
        "{program}: {:?} {:?}",
        run.violations,
        run.measured
    );
    assert_eq!(run.plan.added_stops(), 0, "{program}: {:?}", run.plan);
}

/// An operator turning the feed override knob mid-run never stops the
/// machine: with the override stepped through 30–200 % every few tenths of
/// a second the program ends at its end, every limit held on every tick,
/// with no stop the program does not ask for. The look-ahead once crawled
/// here: on `homer-q2` (F6000, every 113 ms) six times, as a lowered
/// override's braking curve was forgotten by the next block's solve (the
/// machine still braking, above the new feed) and the softened braking
/// curves started from a clamped acceleration, below the speed a machine
/// still accelerating must reach (`BlockPlanner::replan`); on `trident`
/// (F3000, every 53 ms) twice, where the override fell to 30 % inside a
/// tight turn that the axes' jerk lets the machine take only at a steady
/// speed: the gentlest braking curve still asked it to slow down there.
#[test]
fn turning_the_override_knob_never_stops_the_machine() {
    for (program, feed, every) in [
        ("homer-q2.ngc", 6000.0, 113),
        ("trident-xy-yz-zx.ngc", 3000.0, 53),
    ] {
        let file = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../gcode/tests/programs")
            .join(program);
        let blocks = load_program(&file, Some(feed), None).unwrap();
        let cfg = InterpConfig::default();
        let turns: Vec<(u64, f64)> = (1..1000u64)
            .map(|k| (every * k, OVERRIDE_KNOB[k as usize % OVERRIDE_KNOB.len()]))
            .collect();
        let run = interpolated_run_with_overrides(&blocks, &cfg, &turns).unwrap();
        let t = run.plan;
        eprintln!(
            "{program} F{feed}, override turned every {every} ms: {:.3} s, {t:?}",
            run.time
        );
        assert_held_every_limit_and_never_stopped(program, &run);
        assert!(
            run.time > every as f64 * cfg.period * 50.0,
            "{program}: the knob was turned over 50 times in {} s",
            run.time
        );
    }
}

/// The knob turned while the operator holds and resumes: no stop the
/// program does not ask for either. At F6000, the override stepped every
/// 113 ms, a hold every 97 ms resumed `R` ms later:
///
/// - `homer-q2`, resumed after 30 ms: an override raised while a hold
///   braked found no plan and crawled, once; a raised override leaves the
///   plan within the new feed, so it now keeps the plan it has when no
///   faster one is found.
/// - `ruota_dentata-q1`, resumed after 20 ms: the override lowered to 90 %
///   three ticks after a hold found no plan through the hold's braking and
///   crawled, once; a plan braking to a hold's rest point is kept as well
///   (the machine slows to rest anyway; what follows the rest point is
///   solved with the new feed).
#[test]
fn the_knob_turned_while_holding_never_stops_the_machine() {
    for (program, resume_after) in [("homer-q2", 30), ("ruota_dentata-q1", 20)] {
        let file = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join(format!("../gcode/tests/programs/{program}.ngc"));
        let blocks = load_program(&file, Some(6000.0), None).unwrap();
        let cfg = InterpConfig::default();
        let mut commands: Vec<(u64, Command)> = (1..1000u64)
            .map(|k| {
                (
                    113 * k,
                    Command::Override(OVERRIDE_KNOB[k as usize % OVERRIDE_KNOB.len()]),
                )
            })
            .collect();
        commands.extend((1..1000u64).flat_map(|k| {
            [
                (97 * k, Command::Hold),
                (97 * k + resume_after, Command::Resume),
            ]
        }));
        commands.sort_by_key(|&(at, _)| at);
        let run = interpolated_run_with_commands(&blocks, &cfg, &commands).unwrap();
        let t = run.plan;
        eprintln!("{program} F6000, knob and holds: {:.3} s, {t:?}", run.time);
        assert_held_every_limit_and_never_stopped(program, &run);
        assert!(t.holds > 100, "{program}: {t:?}");
    }
}

/// `file` (a bundled program) at F6000 on machine `cfg` to tick `ticks`, the re-solves of
/// everything ahead tried from up to `later_freezes` later pieces
/// (`Window::later_freezes`) and, frozen inside an interval, keeping the
/// kept plan's pieces there or not (`Window::kept_pieces`); `hook` gives
/// the operator's commands before each tick and notes what it needs in
/// `state`. Returns `state` and the grid interval.
fn under_commands<S: Send + 'static>(
    file: &str,
    cfg: &InterpConfig,
    ticks: u64,
    later_freezes: usize,
    kept_pieces: bool,
    mut state: S,
    hook: fn(&mut interp_run::Run<1024>, &mut S),
) -> (S, f64) {
    let file = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../gcode/tests/programs")
        .join(file);
    let blocks = load_program(&file, Some(6000.0), None).unwrap();
    let cfg = *cfg;
    std::thread::Builder::new()
        .stack_size(interpd_tests::path_time::INTERPOLATOR_STACK)
        .spawn(move || {
            let p = blocks[0].path.start_point();
            let mut run = interp_run::Run::<1024>::new(cfg, [p.x, p.y, p.z, 0.0, 0.0, 0.0])
                .unwrap()
                .with_tick_limit(ticks);
            let w = run.driver_mut().window_mut();
            (w.later_freezes, w.kept_pieces) = (later_freezes, kept_pieces);
            let _ = run.run_program_with::<()>(
                &blocks,
                |r| {
                    hook(r, &mut state);
                    Ok(())
                },
                |_, _| Ok(()),
            );
            (state, run.driver().planner().window().h())
        })
        .unwrap()
        .join()
        .unwrap()
}

/// `homer-q2` under [`under_commands`] to tick 2,500, a knob turned every
/// 23 ms and a hold every 41 ms resumed 7 ms later: the machine's position
/// at each tick a crawl was planned before, with the crawls so far, and
/// the grid interval.
fn crawls_under_a_fast_knob(later_freezes: usize, kept_pieces: bool) -> (Vec<(f64, u64)>, f64) {
    use interp_core::RunState;
    let hook = |r: &mut interp_run::Run<1024>, crawls: &mut Vec<(f64, u64)>| {
        let c = r.driver().planner().window().totals.crawled;
        if c > crawls.last().map_or(0, |l| l.1) {
            crawls.push((r.executor().status().plan_position, c));
        }
        let t = r.ticks();
        if t > 0 && t.is_multiple_of(23) {
            let k = (t / 23) as usize % OVERRIDE_KNOB.len();
            let _ = r.set_feed_override(OVERRIDE_KNOB[k]);
        }
        if t > 0 && t.is_multiple_of(41) && r.state() == RunState::Running {
            r.feed_hold();
        }
        if t > 7 && (t - 7).is_multiple_of(41) && r.state() == RunState::Holding {
            r.resume();
        }
    };
    under_commands(
        "homer-q2.ngc",
        &InterpConfig::default(),
        2500,
        later_freezes,
        kept_pieces,
        Vec::new(),
        hook,
    )
}

/// The overrides of a run whose re-solve failed every pass (the plan kept,
/// or a crawl), by tick, and how many re-solved: `file` under
/// [`under_commands`] to tick `ticks`, the knob turned every 31 ms and a
/// hold every 47 ms resumed 11 ms later, as `override_knob --every 31
/// --hold-every 47 --resume-after 11` gives them, the window's later
/// freezes and kept pieces set.
fn overrides_failed_through(
    file: &str,
    cfg: &InterpConfig,
    ticks: u64,
    later_freezes: usize,
    kept_pieces: bool,
) -> (Vec<u64>, u64) {
    let hook = |r: &mut interp_run::Run<1024>, (failed, solved): &mut (Vec<u64>, u64)| {
        let t = r.ticks();
        if t > 0 && t.is_multiple_of(31) {
            let totals = |r: &interp_run::Run<1024>| r.driver().planner().window().totals;
            let before = totals(r);
            let _ = r.set_feed_override(OVERRIDE_KNOB[(t / 31) as usize % OVERRIDE_KNOB.len()]);
            let after = totals(r);
            if after.solves > before.solves {
                *solved += 1;
            } else if after.warm_failed > before.warm_failed {
                failed.push(t);
            }
        }
        if t > 0 && t.is_multiple_of(47) {
            r.feed_hold();
        }
        if t > 11 && (t - 11).is_multiple_of(47) {
            r.resume();
        }
    };
    under_commands(
        file,
        cfg,
        ticks,
        later_freezes,
        kept_pieces,
        (Vec::new(), 0),
        hook,
    )
    .0
}

/// A raised override on a soft machine (path jerk 10⁴ mm/s³) keeps its plan
/// up to the corner it rests at when every pass fails, and plans from
/// there. `homer-q2` under the fast knob to tick 30,000: braking into a
/// corner at the jerk limit over the whole look-ahead, the re-solve from the
/// machine has no room, and raised overrides failed from every freeze piece
/// and every braking rate (eight tries, 60–220 ms, over the service's 40 ms
/// lead), then kept the plan all the same: 7 of about 950 when the plan was
/// kept to the corner under the override it was solved with only, 1 now (a
/// raise whose plan does not rest before its end).
#[test]
fn a_raised_override_on_a_soft_machine_keeps_its_plan_to_the_corner() {
    let later = interp_core::plan::LATER_FREEZES;
    let cfg = machine_with_jerk(1e4);
    let (failed, solved) = overrides_failed_through("homer-q2.ngc", &cfg, 30_000, later, true);
    eprintln!("failed at {failed:?}, {solved} re-solved");
    assert!(solved > 800, "{solved} overrides re-solved");
    assert!(failed.len() <= 2, "every pass failed at ticks {failed:?}");
}

/// [`overrides_failed_through`] on `ruota_dentata-q1`, the default machine,
/// to tick 4,400.
fn ruota_overrides_failed(later_freezes: usize, kept_pieces: bool) -> (Vec<u64>, u64) {
    let cfg = InterpConfig::default();
    overrides_failed_through(
        "ruota_dentata-q1.ngc",
        &cfg,
        4_400,
        later_freezes,
        kept_pieces,
    )
}

/// A re-solve frozen inside a grid interval continues the pieces the kept
/// plan has there. `ruota_dentata-q1`'s slow stretches are cut into eighths
/// of an interval; a re-solve from the machine on, its freeze point three
/// eighths in, rebuilt the rest of that interval as one piece, held to the
/// slowest of its five eighths: below the speed the kept plan passes the
/// freeze point with. Every pass failed (the knob's override before tick
/// 4,278: eighteen linear programs, 20–50 ms in the service, where the
/// planning thread fell behind the RT thread).
#[test]
fn a_re_solve_frozen_inside_a_finely_cut_interval_keeps_its_cuts() {
    let later = interp_core::plan::LATER_FREEZES;
    let (failed, solved) = ruota_overrides_failed(later, true);
    assert!(solved > 50, "{solved} overrides re-solved");
    assert!(failed.is_empty(), "every pass failed at ticks {failed:?}");
    // (The case: cut afresh, and no later freeze tried, that override
    // fails every pass.)
    let (failed, _) = ruota_overrides_failed(0, false);
    assert!(failed.contains(&4_278), "{failed:?}");
}

/// A raised override whose re-solve from the freeze piece fails is tried
/// from a piece or two later, as a lowered one is, before the plan is
/// kept: each failing freeze costs eighteen linear programs (the
/// service's planning thread fell 50 ms behind, at a ramp into a rest
/// point that its kept neighbour and its own jerk pinned). The override
/// before tick 4,278 of [`overrides_failed_through`] on `ruota_dentata-q1`
/// is raised (30 → 100 %) and fails from its freeze piece when the
/// interval's cuts are not kept (the case above).
#[test]
fn a_raised_override_that_fails_from_its_freeze_piece_is_planned_from_a_later_one() {
    let later = interp_core::plan::LATER_FREEZES;
    let (failed, solved) = ruota_overrides_failed(later, false);
    assert!(solved > 50, "{solved} overrides re-solved");
    assert!(failed.is_empty(), "every pass failed at ticks {failed:?}");
}

/// A re-solve that found no plan and crawled is not planned again from
/// where it was planned: the same solve from the same state fails the same
/// way, and the crawl's retry at the next tick cost a second whole failing
/// solve (20–40 ms in the service) right after the first, past the planning
/// thread's lead. Under [`crawls_under_a_fast_knob`] with no later freeze
/// piece tried (and the kept pieces cut afresh), an override crawled at
/// tick 1771 and again at 1772, 25 µm further on. Now the crawl counts
/// as tried from where the machine was, and its retry waits until it has
/// moved half a grid interval (`Window::take_crawl_retry`).
#[test]
fn a_crawl_is_not_planned_again_from_where_it_was_planned() {
    let (crawls, h) = crawls_under_a_fast_knob(0, false);
    assert!(!crawls.is_empty(), "no crawl to retry: the case is gone");
    let mut last = f64::NEG_INFINITY;
    let mut count = 0;
    for &(x, c) in &crawls {
        assert_eq!(c, count + 1, "two crawls in one tick at {x} mm: {crawls:?}");
        assert!(
            x - last >= 0.5 * h,
            "crawled again {} mm after the last crawl (half a grid interval: {} mm): {crawls:?}",
            x - last,
            0.5 * h
        );
        (last, count) = (x, c);
    }
}

/// An override right after a resume finds a plan: that crawl (above) came
/// where the resume turned the hold's braking around on pieces graded at
/// an eighth of the grid step. Every override, raised or lowered, failed
/// through every braking rate from the first two pieces after the machine
/// and found a plan at once from the third. A re-solve of everything ahead
/// that would crawl now tries from up to two pieces later first
/// (`Window::later_freezes`). The pieces failed because the re-solve cut
/// the rest of the freeze point's interval afresh (see
/// `a_re_solve_frozen_inside_a_finely_cut_interval_keeps_its_cuts`):
/// keeping the kept plan's pieces there, it finds a plan from the first.
#[test]
fn an_override_right_after_a_resume_finds_a_plan_from_a_later_piece() {
    use interp_core::plan::LATER_FREEZES;
    let (crawls, _) = crawls_under_a_fast_knob(LATER_FREEZES, false);
    assert!(crawls.is_empty(), "crawled at {crawls:?}");
    // (The case: from the first piece after the machine only, it crawls.)
    assert!(!crawls_under_a_fast_knob(0, false).0.is_empty());
    // Either answer alone, and both, plan it without a crawl.
    assert!(crawls_under_a_fast_knob(0, true).0.is_empty());
    assert!(crawls_under_a_fast_knob(LATER_FREEZES, true).0.is_empty());
}

/// A feed hold brakes within every limit, an axis's jerk included: on the
/// gear's tight teeth at F6000 an axis's jerk binds at a steady speed, and
/// the closed-form tangential stop passed it (1.44× with a hold every 97
/// ms); the hold is planned through the look-ahead now.
#[test]
fn a_feed_hold_on_a_tight_turn_keeps_every_axis_jerk_limit() {
    let file = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../gcode/tests/programs/ruota_dentata-q1.ngc");
    let blocks = load_program(&file, Some(6000.0), None).unwrap();
    let cfg = InterpConfig::default();
    // A hold every 97 ms to the end, each resumed 60 ms later.
    let commands: Vec<(u64, Command)> = (1..=300u64)
        .flat_map(|k| [(97 * k, Command::Hold), (97 * k + 60, Command::Resume)])
        .collect();
    let plain = interpolated_run(&blocks, &cfg, false).unwrap();
    let run = interpolated_run_with_commands(&blocks, &cfg, &commands).unwrap();
    eprintln!(
        "ruota_dentata-q1 F6000, a hold every 97 ms: {:.3} s (without {:.3} s), jerk use {:.3}, {:?}",
        run.time,
        plain.time,
        run.jerk_use(&cfg),
        run.plan
    );
    assert_held_every_limit_and_never_stopped("ruota_dentata-q1", &run);
    // The holds came to rest and waited: 60 ms each, less for a hold
    // given while the machine still brakes for the last one.
    let holds = commands
        .iter()
        .filter(|(at, c)| matches!(c, Command::Hold) && *at as f64 * cfg.period < run.time)
        .count();
    assert!(
        run.time > plain.time + 0.75 * holds as f64 * 0.060,
        "{} s against {} s without holds",
        run.time,
        plain.time
    );
}

/// An abort brakes within every limit too: an abort every 149 ms through
/// the gear at F6000, each on a copy of the run. The closed-form stop
/// passed an axis's jerk limit (first before tick 2383); the abort is
/// planned as a hold now, and the queue flushed at its rest.
#[test]
fn an_abort_on_a_tight_turn_keeps_every_axis_jerk_limit() {
    let file = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../gcode/tests/programs/ruota_dentata-q1.ngc");
    let blocks = load_program(&file, Some(6000.0), None).unwrap();
    let cfg = InterpConfig::default();
    let tried = abort_scan(&blocks, &cfg, every(149)).unwrap();
    assert!(tried.len() > 60, "{} aborts tried", tried.len());
    for a in &tried {
        assert_eq!(a.violations.total(), 0, "{a:?}");
    }
}

/// An abort braking through a 13 µm cusp of `homer-q1` at F6000, at every
/// tick the machine reaches it from: the rows at the samples of the cusp
/// held, but a knot of the plan between two samples (4 µm apart, where the
/// path jerk turned and `C‴` swings by 6,000 mm⁻²) reached 1.046× the Y
/// axis's jerk, 8 µm before the rest (the aborts before ticks 12,280 and
/// 12,283). The samples around the cusp's peaks are a quarter radius apart
/// now.
#[test]
fn an_abort_in_a_cusp_keeps_every_axis_jerk_limit() {
    let file = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../gcode/tests/programs/homer-q1.ngc");
    let cfg = InterpConfig::default();
    let blocks = load_as_run(&file, Some(6000.0), None, &cfg).unwrap();
    let tried = abort_scan(&blocks, &cfg, |at| (12_260..12_300).contains(&at)).unwrap();
    assert_eq!(tried.len(), 40);
    for a in &tried {
        assert_eq!(a.violations.total(), 0, "{a:?}");
    }
}

/// A program of `gcode/tests/programs` at F6000, its part turned on the
/// table 35° about the axis (1, 2, 0), as the drivers run it.
fn tilted_at_f6000(name: &str, cfg: &InterpConfig) -> Vec<interp_core::Block> {
    use nalgebra::{Rotation3, Unit, Vector3};
    let file = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../gcode/tests/programs")
        .join(name);
    let axis = Unit::new_normalize(Vector3::new(1.0, 2.0, 0.0));
    let turned = Rotation3::from_axis_angle(&axis, 35f64.to_radians());
    load_turned_as_run(&file, Some(6000.0), None, Some(&turned), cfg).unwrap()
}

/// `homer-q1` turned on the table (35° about the axis (1, 2, 0)) under a
/// feed hold every 29 ms resumed 7 ms later: the resume before tick 9,606
/// (the machine at 11 mm/s) re-solved over a piece cut 12.5 µm short that
/// held one per-axis sample, at its start; at its end, 0.6 µm before the
/// next sample, `C‴_y` was 8 % higher, and a tick reached 1.0007× the Y
/// axis's jerk. A short piece with no sample at an end is now checked
/// there against the nearest sample past it.
#[test]
fn a_short_piece_is_checked_at_both_ends_on_a_part_turned_on_the_table() {
    let cfg = InterpConfig::default();
    let blocks = tilted_at_f6000("homer-q1.ngc", &cfg);
    let commands: Vec<(u64, Command)> = (1..=340)
        .flat_map(|k| [(29 * k, Command::Hold), (29 * k + 7, Command::Resume)])
        .collect();
    let run = interpolated_run_with_commands(&blocks, &cfg, &commands).unwrap();
    assert_eq!(
        run.violations.total(),
        0,
        "{} (first at seq {:?})",
        run.violations.breakdown(),
        run.violations.first_seq
    );
    assert_eq!(run.plan.added_stops(), 0);
}

/// The same part turned on the table (35° about the axis (1, 2, 0)): an
/// abort before tick 17,648 brakes `homer-q2` through a turn of 23 µm
/// radius (`C‴` up to 1,800 mm⁻², now on Y and Z too) at 4 mm/s, and the
/// per-axis samples half its length apart (10 µm) missed where the braking
/// jerk and `C‴·v³` added up: 1.018× the Y axis's jerk. They are a quarter
/// of it apart now (up to 16 between two law samples, were 8).
#[test]
fn an_abort_on_a_part_turned_on_the_table_keeps_every_axis_jerk_limit() {
    let cfg = InterpConfig::default();
    let blocks = tilted_at_f6000("homer-q2.ngc", &cfg);
    let tried = abort_scan(&blocks, &cfg, |at| (17_640..17_656).contains(&at)).unwrap();
    assert_eq!(tried.len(), 16);
    for a in &tried {
        assert_eq!(a.violations.total(), 0, "{a:?}");
    }
}

/// On a soft machine (jerk 10⁴ mm/s³) an abort's stop is long: before tick
/// 443 of the butterfly at F6000 it ended exactly on the end of what was
/// queued of the long first curve, the planner's queue end where the
/// machine stood, and the rest of the curve was planned and run after the
/// abort. The queue is forgotten after every abort now.
#[test]
fn an_abort_on_a_soft_machine_drops_the_rest_of_a_long_block() {
    let cfg = machine_with_jerk(1e4);
    let file = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../gcode/tests/programs/curva_farfalla-q1.ngc");
    let blocks = load_as_run(&file, Some(6000.0), None, &cfg).unwrap();
    let tried = abort_scan(&blocks, &cfg, |at| (436..450).contains(&at)).unwrap();
    assert_eq!(tried.len(), 14);
    for a in &tried {
        assert_eq!(a.violations.total(), 0, "{a:?}");
    }
}
