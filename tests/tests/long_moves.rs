//! Issue 15, long moves: a move longer than the look-ahead's reach (metres
//! of travel, ordinary on large machines) runs to its end at the programmed
//! feed, as `simulate`, `replay` and the daemon run it (the look-ahead plans
//! it in parts of `CHUNK` grid intervals as the machine advances).

use interp_core::feed::ArcLengthDerivs;
use interp_core::interp::grid_step;
use interp_core::plan::{AxisSample, CHUNK, SUB};
use interp_core::{
    Block, BlockPlanner, Curve, InterpConfig, Path, PlannedBlock, RunState, Setpoint, Vec3,
};
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

/// The block (the loader's piece) of the first curve of the bundled
/// program `file` at F6000 that holds parameter `u`.
fn block_holding(file: &str, u: f64) -> Block {
    let file = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../gcode/tests/programs")
        .join(file);
    first_curve(&load_program(&file, Some(6000.0), None).unwrap())
        .into_iter()
        .find(|b| b.path.u_start() < u && u < b.path.u_end())
        .unwrap()
}

/// Each sub-range's machine law (mm/s) and whether a junction's step
/// reserves axis jerk there.
type Around = Vec<(f64, bool)>;

/// Around `block`'s point at parameter `u_cut`, within 0.1 mm: each
/// sub-range's machine law, and whether a junction's step reserves axis
/// jerk there. Planned with the run's first chunk mark there (the block cut
/// at `u_cut`), and uncut (the mark half a chunk later, on the same
/// sub-ranges). The per-axis samples at the cut (the axis jerk rows'
/// derivatives, the parts' ends) must be the curve's own there, to 10⁻⁶ of
/// their size.
fn around_a_cut(block: &Block, u_cut: f64) -> (Around, Around) {
    let cfg = InterpConfig::default();
    let s_cut = block.path.arc_length(block.path.u_start(), u_cut);
    let h = grid_step(&cfg);
    let chunk = CHUNK as f64 * h;
    assert!(s_cut < chunk - 0.1, "the first part's cut, {s_cut} mm in");
    let laws = |tail_s: f64| -> Around {
        let p = block.path.start_point();
        let mut planner = Box::new(BlockPlanner::new(cfg, p, tail_s).unwrap());
        let mut out = Box::new(PlannedBlock::new());
        planner.plan(block, &mut out).unwrap();
        // Where the first part ends (the cut), if the block was cut.
        let cut = planner.pending().map(|b| {
            let u = b.path.u_start();
            (tail_s + block.path.arc_length(block.path.u_start(), u), u)
        });
        planner.plan_pending(&mut out).unwrap();
        let hs = h / SUB as f64;
        let x = tail_s + s_cut;
        let k0 = ((x - 0.1) / hs).floor() as i64;
        let subs: Vec<i64> = (k0..k0 + (0.2 / hs) as i64).collect();
        // (The parts' end samples at the cut: elsewhere a sample's place is
        // found to a fraction of a µm, and its derivatives are the curve's
        // there.)
        if let Some((cut_s, u)) = cut {
            let curve = ArcLengthDerivs::new(&block.path.eval(u, 3)).unwrap();
            let at_cut = |smp: &&AxisSample| (smp.s - cut_s).abs() <= 1e-7;
            for &k in subs.iter().step_by(SUB) {
                let it = planner.window().interval_at((k as f64 + 0.5) * hs).unwrap();
                for smp in it.samples[..it.n_samples as usize].iter().filter(at_cut) {
                    for (got, want) in [(smp.css, curve.c_ss), (smp.csss, curve.c_sss)] {
                        let err = (Vec3::from(got) - want).norm();
                        assert!(
                            err <= 1e-6 * want.norm().max(1e-3),
                            "an axis sample at u = {u} (cut at {u_cut}): {got:?}, the curve's {want:?}"
                        );
                    }
                }
            }
        }
        subs.iter()
            .map(|&k| {
                let it = planner.window().interval_at((k as f64 + 0.5) * hs).unwrap();
                let law = it.machine[k.rem_euclid(SUB as i64) as usize];
                (law, !it.jump.reserve.is_none())
            })
            .collect()
    };
    let cut = laws(chunk - s_cut);
    let uncut = laws(chunk - s_cut + 0.5 * chunk);
    assert_eq!(cut.len(), uncut.len());
    (cut, uncut)
}

fn assert_planned_as_uncut(what: &str, (cut, uncut): (Around, Around)) {
    for (i, (a, b)) in cut.iter().zip(&uncut).enumerate() {
        assert!(
            (a.0 == b.0 || (a.0 - b.0).abs() <= 1e-6 * b.0) && a.1 == b.1,
            "{what}: sub-range {i} around the cut (law mm/s, junction step): {a:?}, uncut {b:?}\n{cut:?}\n{uncut:?}"
        );
    }
}

/// A long curve is planned in parts cut at fixed arc lengths (chunk marks).
/// Cut a sliver past one of its knots, the first part's last span is a
/// small share of the knot span's width: its control points nearly
/// coincide, and its derivatives there lose their digits. The scroll's
/// (`curva_scrool_f`, order 6) machine law sampled around a cut 6·10⁻⁵ of
/// a span past its knot at u = 117 fell to 8.7 mm/s over 60 µm where the
/// curve allows 60–71 mm/s (a run whose mark fell there took 1.127× the
/// optimum, 1.117× elsewhere); 1.1·10⁻³ of a span past its knots at 42 and
/// 46 the sub-range at the cut got 27.81 mm/s where the curve allows 27.33
/// (over it), and 41.78 where it allows 42.90. The cut now moves onto the
/// knot (a tenth of a span away at most): the laws around it are those of
/// the same stretch planned uncut.
#[test]
fn a_curve_cut_a_sliver_from_one_of_its_knots_is_cut_on_the_knot() {
    for (knot, share) in [(117.0, 6e-5), (42.0, 1.1e-3), (46.0, 1.1e-3)] {
        let block = block_holding("curva_scrool_f-q1.ngc", knot);
        let Path::Nurbs(n) = &block.path else {
            panic!("a G6.2 curve");
        };
        let knots = n.knots();
        let k = knots.iter().position(|&u| u == knot).unwrap();
        let u_cut = knot + share * (knots[k + 1] - knot);
        let what = format!("cut at u = {u_cut}");
        assert_planned_as_uncut(&what, around_a_cut(&block, u_cut));
    }
}

/// A block that starts a hair before a chunk mark (5 µm: the scroll's
/// second G6.2 block, whose start is near-stationary) is not cut there: the
/// part would be a sliver of its first span. It is cut at the next mark,
/// and the laws at its start are those planned uncut (cut there, the
/// sub-range of the block's start got 38.8 mm/s where the curve allows
/// 6.2).
#[test]
fn a_block_that_starts_a_hair_before_a_chunk_mark_is_cut_at_the_next_one() {
    let u_cut = 28.0014975;
    let block = block_holding("curva_scrool_f-q1.ngc", u_cut);
    let s_cut = block.path.arc_length(block.path.u_start(), u_cut);
    let h = grid_step(&InterpConfig::default());
    assert!(s_cut < 0.25 * h, "a hair: {s_cut} mm");
    assert_planned_as_uncut("the block's start", around_a_cut(&block, u_cut));
}

/// A cut inside a knot span is no junction: the curve is smooth there, as
/// the uncut block is planned. Each part's own derivatives at the cut
/// differ by round-off; taken as a junction they reserved axis jerk around
/// the cut for a curvature step of 10⁻¹⁴/mm or so (and further from a
/// knot's sliver, limited the speed: 86.3 mm/s where the scroll allows
/// 91.1).
#[test]
fn a_curve_cut_inside_a_knot_span_joins_without_a_junction() {
    for (file, knot) in [
        ("curva_scrool_f-q1.ngc", 116.0),
        ("ruota_dentata-q1.ngc", 8.0),
    ] {
        let block = block_holding(file, knot);
        let Path::Nurbs(n) = &block.path else {
            panic!("a curve");
        };
        let knots = n.knots();
        let k = knots.iter().position(|&u| u == knot).unwrap();
        let u_cut = knot + 0.37 * (knots[k + 1] - knot);
        let what = format!("{file} cut at u = {u_cut}");
        assert_planned_as_uncut(&what, around_a_cut(&block, u_cut));
    }
}
