//! Issue 15, long moves: a move longer than the look-ahead's reach (metres
//! of travel, ordinary on large machines) runs to its end at the programmed
//! feed, as `simulate`, `replay` and the daemon run it (the look-ahead plans
//! it in parts of `CHUNK` grid intervals as the machine advances).

use interp_core::interp::grid_step;
use interp_core::plan::CHUNK;
use interp_core::{InterpConfig, RunState, Setpoint};
use interp_run::check::{Checker, Limits};
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
