//! Issue 15, long moves: a move longer than the look-ahead's reach (metres
//! of travel, ordinary on large machines) runs to its end at the programmed
//! feed, as `simulate`, `replay` and the daemon run it (the look-ahead plans
//! it in parts of `CHUNK` grid intervals as the machine advances).

use interp_core::interp::grid_step;
use interp_core::plan::{CHUNK, SUB};
use interp_core::{BlockPlanner, Curve, InterpConfig, Path, PlannedBlock, RunState, Setpoint};
use interp_run::check::{Checker, Limits};
use interpd_tests::path_time::{first_curve, load_program};
use traces::Program;
use traces::sim::{self, SimItem, SimSettings};

fn run(program: &Program, cfg: InterpConfig) -> Vec<Setpoint> {
    let config = sim::config_for(program, cfg, &SimSettings::default(), "test", "long_moves");
    let mut sps = Vec::new();
    let outcome = sim::run(&config, program, 600.0, |item| -> Result<(), ()> {
        if let SimItem::Tick { setpoint, .. } = item {
            sps.push(*setpoint);
        }
        Ok(())
    })
    .expect("runs");
    assert_eq!(outcome.last.state, RunState::Done, "{outcome:?}");
    sps
}

#[test]
fn moves_of_metres_run_to_their_end_at_the_programmed_feed() {
    let cfg = InterpConfig::default();
    // 2 m along X, a corner, 1.5 m diagonally back, and a half circle of
    // radius 700 mm (2.2 m): each longer than the look-ahead's reach alone.
    let program: Program = serde_json::from_str(
        r#"{"start": [0, 0, 0], "blocks": [
            {"feed": 6000, "kind": "line", "end": [2000, 0, 0]},
            {"feed": 6000, "kind": "line", "end": [800, 900, 10]},
            {"feed": 6000, "kind": "arc", "end": [800, 2300, 10], "centre": [800, 1600, 10]}
        ]}"#,
    )
    .unwrap();
    assert!(
        2000.0 > 4.0 * CHUNK as f64 * grid_step(&cfg),
        "the case is long enough"
    );
    let sps = run(&program, cfg);
    let last = sps.last().unwrap();
    assert_eq!(last.state, RunState::Done);
    assert_eq!(last.axes[..3], [800.0, 2300.0, 10.0]);
    // Through the cuts the feed stays at 100 mm/s: along the first line,
    // away from its ends, every tick moves at the programmed feed.
    let v = 6000.0 / 60.0;
    let cruise: Vec<_> = sps.iter().filter(|s| s.s > 100.0 && s.s < 1900.0).collect();
    assert!(cruise.len() > 17_000);
    for s in &cruise {
        assert!(
            (s.feed - v).abs() < 1e-6 * v,
            "seq {} feed {}",
            s.seq,
            s.feed
        );
    }
    // Whole run: every limit of the configuration at every tick (the
    // setpoint checker: finite differences of the setpoints, as a drive sees
    // them), ending exactly at the program's end; and the only rests
    // between start and end are the two programmed corners (none at a cut).
    let mut check = Checker::new(cfg.period, Limits::new(&cfg, v), [0.0; 3]);
    for sp in &sps {
        check.check(sp);
    }
    check.finish(Some([800.0, 2300.0, 10.0]));
    check.assert_clean("long moves");
    let rests: Vec<[f64; 3]> = sps
        .windows(2)
        .filter(|w| w[1].feed == 0.0 && w[0].feed > 0.0 && w[1].state != RunState::Done)
        .map(|w| [w[1].axes[0], w[1].axes[1], w[1].axes[2]])
        .collect();
    assert_eq!(rests, [[2000.0, 0.0, 0.0], [800.0, 900.0, 10.0]]);
}

/// A long curve is planned in parts cut at fixed arc lengths (chunk marks).
/// Cut a sliver past one of its knots, the first part's last span is 6·10⁻⁵
/// of the knot span's width: its control points nearly coincide, and its
/// derivatives there lose their digits. The scroll's (`curva_scrool_f`,
/// order 6) machine law sampled around such a cut fell to 8.7 mm/s over
/// 60 µm where the curve allows 60–71 mm/s (a run whose mark fell there
/// took 1.127× the optimum, 1.117× elsewhere). The cut now moves onto the
/// knot: the laws around it are those of the same stretch planned uncut.
#[test]
fn a_curve_cut_a_sliver_past_one_of_its_knots_keeps_its_laws_at_the_cut() {
    let cfg = InterpConfig::default();
    let file = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../gcode/tests/programs/curva_scrool_f-q1.ngc");
    // The knot at u = 117, 16 mm into the curve (where the look-ahead cut it
    // at its first mark), in the block (the loader's piece) that holds it.
    let knot = 117.0;
    let block = first_curve(&load_program(&file, Some(6000.0), None).unwrap())
        .into_iter()
        .find(|b| b.path.u_start() < knot && knot < b.path.u_end())
        .unwrap();
    let Path::Nurbs(n) = &block.path else {
        panic!("a G6.2 curve");
    };
    let u0 = n.u_start();
    let tol = 1e-9;
    let knots = n.knots();
    let k = knots.iter().position(|&u| u == knot).unwrap();
    let u_cut = knots[k] + 6e-5 * (knots[k + 1] - knots[k]);
    let s_cut = n.arc_length(u0, u_cut, tol);
    let h = grid_step(&cfg);
    let chunk = CHUNK as f64 * h;
    // The machine law of each sub-range within 0.1 mm of the curve's point
    // `s_cut`, planned with the queue's end at `tail_s` (the first two parts).
    let laws = |tail_s: f64| -> Vec<f64> {
        let p = block.path.start_point();
        let mut planner = Box::new(BlockPlanner::new(cfg, p, tail_s).unwrap());
        let mut out = Box::new(PlannedBlock::new());
        planner.plan(&block, &mut out).unwrap();
        planner.plan_pending(&mut out).unwrap();
        let hs = h / SUB as f64;
        let x = tail_s + s_cut;
        let k0 = ((x - 0.1) / hs).floor() as i64;
        (k0..k0 + (0.2 / hs) as i64)
            .map(|k| {
                let it = planner.window().interval_at((k as f64 + 0.5) * hs).unwrap();
                it.machine[k.rem_euclid(SUB as i64) as usize]
            })
            .collect()
    };
    // Cut there: the first mark of the run at the curve's `s_cut`.
    let cut = laws(chunk - s_cut);
    // Uncut there: half a chunk later (whole grid steps: the same sub-ranges).
    let uncut = laws(chunk - s_cut + 0.5 * chunk);
    assert_eq!(cut.len(), uncut.len());
    for (i, (a, b)) in cut.iter().zip(&uncut).enumerate() {
        assert!(
            (a - b).abs() <= 1e-6 * b,
            "sub-range {i} around the cut: {a} mm/s, uncut {b} mm/s\n{cut:?}\n{uncut:?}"
        );
    }
}
