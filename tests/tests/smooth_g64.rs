//! Issue 15, corners and dense G1 under `G64 P`: programs written as G-code
//! text run as the drivers run them (the `G64 P` stage, then the
//! interpolator), and every setpoint, and every chord between consecutive
//! setpoints, is measured against the polyline the text programs, by a grid
//! search of its own (`interpd_tests::polyline`), never from what the stage
//! made of it. Metamorphic variants (translated, rotated, reversed) and
//! random dense programs hold the same bound.

use gcode::CoreOptions;
use interp_core::smooth::Policy;
use interp_core::{InterpConfig, Vec3};
use interpd_tests::path_time::{interpolated_run, smoothed};
use interpd_tests::polyline::Polyline;
use proptest::prelude::*;

/// G-code text of `G64 P<tol>` then G1 moves through `pts` at `feed` mm/min,
/// starting with a G0 to the first point.
fn program_text(pts: &[Vec3], tol: f64, feed: f64) -> String {
    let mut s = format!(
        "G21 G90 G94 G17\nG64 P{tol}\nG0 X{} Y{} Z{}\n",
        pts[0].x, pts[0].y, pts[0].z
    );
    for (i, p) in pts[1..].iter().enumerate() {
        s += &format!("G1 X{} Y{} Z{}", p.x, p.y, p.z);
        if i == 0 {
            s += &format!(" F{feed}");
        }
        s += "\n";
    }
    s
}

/// What a run of `text` did: setpoint and chord deviation from `pts`, path
/// time, blocks out of the stage.
struct Outcome {
    point_dev: f64,
    chord_dev: f64,
    time: f64,
    blocks_out: usize,
    last: Vec3,
}

fn run(text: &str, pts: &[Vec3], cfg: &InterpConfig) -> Outcome {
    let program = gcode::parse(text).expect("parses");
    let blocks = program
        .to_core_blocks(&CoreOptions::default())
        .expect("converts");
    // The machine starts at the first point: the G0 that gets there is not
    // part of the measured path.
    let rapid = CoreOptions::default().rapid_speed;
    let blocks: Vec<_> = blocks.into_iter().filter(|b| b.feed != rapid).collect();
    let (out, _) = smoothed(&blocks, cfg, Policy::Auto);
    let run = interpolated_run(&out, cfg, true).expect("finishes");
    // Every limit on every tick, by finite differences of the setpoints.
    let v = run.violations;
    assert_eq!(
        v.total(),
        0,
        "{} (first at seq {:?})",
        v.breakdown(),
        v.first_seq
    );
    let (time, setpoints) = (run.time, run.points);
    // The programmed polyline, from the numbers the text was written from.
    let (point_dev, chord_dev) = Polyline::new(pts).deviation(&setpoints);
    Outcome {
        point_dev,
        chord_dev,
        time,
        blocks_out: out.len(),
        last: *setpoints.last().unwrap(),
    }
}

fn check(o: &Outcome, pts: &[Vec3], tol: f64, cfg: &InterpConfig, what: &str) {
    // Setpoints lie on the curves (1e-9 mm); chords add the chord tolerance.
    assert!(
        o.point_dev <= tol + 1e-9,
        "{what}: setpoint {} mm off",
        o.point_dev
    );
    assert!(
        o.chord_dev <= tol + cfg.chord_tolerance + 1e-9,
        "{what}: chord {} mm off",
        o.chord_dev
    );
    assert!(
        (o.last - pts[pts.len() - 1]).norm() < 1e-9,
        "{what}: ends at {:?}",
        o.last
    );
}

/// A finishing-like path: a dense wavy row (steps of `step` mm), a long move,
/// two sharp corners, and a dense arc back.
fn finishing_path(step: f64) -> Vec<Vec3> {
    let mut pts = Vec::new();
    let n = (20.0 / step) as usize;
    for i in 0..=n {
        let x = i as f64 * step;
        pts.push(Vec3::new(
            x,
            0.0,
            2.0 * (x / 3.0).sin() - 0.01 * x * x / 20.0,
        ));
    }
    let last = *pts.last().unwrap();
    pts.push(last + Vec3::new(15.0, 0.0, 0.0));
    pts.push(last + Vec3::new(15.0, 10.0, 0.0));
    let c = last + Vec3::new(7.5, 10.0, 0.0);
    for i in 0..=600 {
        let a = std::f64::consts::PI * i as f64 / 600.0;
        pts.push(c + Vec3::new(7.5 * a.cos(), 7.5 * a.sin() * 0.6, 0.0));
    }
    pts
}

#[test]
fn every_setpoint_and_chord_is_within_p_of_the_programmed_polyline() {
    let cfg = InterpConfig::default();
    let pts = finishing_path(0.017);
    for tol in [0.001, 0.01] {
        let text = program_text(&pts, tol, 6000.0);
        let o = run(&text, &pts, &cfg);
        eprintln!(
            "P{tol}: {} moves -> {} blocks, {:.3} s, setpoint {:.3} um, chord {:.3} um",
            pts.len() - 1,
            o.blocks_out,
            o.time,
            o.point_dev * 1e3,
            o.chord_dev * 1e3
        );
        check(&o, &pts, tol, &cfg, &format!("P{tol}"));
        // Compressed: far fewer blocks than moves.
        assert!(o.blocks_out * 20 < pts.len(), "{} blocks", o.blocks_out);
    }
}

#[test]
fn translated_rotated_and_reversed_programs_hold_the_same_bound() {
    let cfg = InterpConfig::default();
    let tol = 0.001;
    let base = finishing_path(0.02);
    let o = run(&program_text(&base, tol, 6000.0), &base, &cfg);
    check(&o, &base, tol, &cfg, "base");
    // Rodrigues' rotation about `axis` by `angle`.
    let rot = |axis: Vec3, angle: f64| {
        let k = axis.normalize();
        let (s, c) = angle.sin_cos();
        base.iter()
            .map(|p| p * c + k.cross(p) * s + k * (k.dot(p) * (1.0 - c)))
            .collect::<Vec<_>>()
    };
    let variants: Vec<(&str, Vec<Vec3>)> = vec![
        (
            "translated",
            base.iter()
                .map(|p| p + Vec3::new(120.0, -45.5, 7.25))
                .collect(),
        ),
        ("rotated about Z", rot(Vec3::z(), 0.6457)),
        (
            "rotated about an oblique axis",
            rot(Vec3::new(1.0, 2.0, 3.0), 1.1),
        ),
        ("reversed", base.iter().rev().copied().collect()),
    ];
    for (what, pts) in &variants {
        let v = run(&program_text(pts, tol, 6000.0), pts, &cfg);
        check(&v, pts, tol, &cfg, what);
        // The same path: about the same pieces and time.
        let ratio = v.time / o.time;
        eprintln!("{what}: {} blocks, time ratio {ratio:.4}", v.blocks_out);
        assert!(
            (0.9..=1.1).contains(&ratio),
            "{what}: time {} vs {}",
            v.time,
            o.time
        );
        assert!(
            v.blocks_out.abs_diff(o.blocks_out) * 3 <= o.blocks_out,
            "{what}: {} vs {} blocks",
            v.blocks_out,
            o.blocks_out
        );
    }
}

/// A dense program's points: `n` moves of 1 µm to 1 mm (log-uniform), random
/// small turns and now and then a sharp corner, from `seed`.
fn dense_program(seed: u64, n: usize) -> Vec<Vec3> {
    let mut rng = seed | 1;
    let mut next = move || {
        rng ^= rng << 13;
        rng ^= rng >> 7;
        rng ^= rng << 17;
        (rng >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut pts = vec![Vec3::zeros()];
    let mut dir = Vec3::new(1.0, 0.0, 0.0);
    for _ in 0..n {
        let len = 10f64.powf(-3.0 + 3.0 * next());
        let turn = if next() < 0.02 {
            2.5 * next()
        } else {
            0.05 * (next() - 0.5)
        };
        let lift = 0.05 * (next() - 0.5);
        let (s, c) = turn.sin_cos();
        dir = Vec3::new(c * dir.x - s * dir.y, s * dir.x + c * dir.y, dir.z + lift).normalize();
        let p = *pts.last().unwrap() + dir * len;
        pts.push(p);
    }
    pts
}

/// Found by checking every tick of [`dense_program`]s: the `G64 P` stage's
/// fit of seed 17 has a knot span of 8 µm with `C‴` of 510/mm² in Z, between
/// two grid samples of the laws (31 µm apart). Its limit (7.3 mm/s) was
/// not seen and the machine passed at 12.8 mm/s: Z jerk 2.24× its limit on
/// a tick. Knot spans narrower than the law spacing are now sampled at
/// their worst point.
#[test]
fn narrow_knot_spans_of_a_fit_hold_every_axis_limit() {
    let cfg = InterpConfig::default();
    let pts = dense_program(17, 600);
    // (`run` checks every limit on every tick.)
    let o = run(&program_text(&pts, 10f64.powf(-2.3), 6000.0), &pts, &cfg);
    check(&o, &pts, 10f64.powf(-2.3), &cfg, "seed 17");
}

proptest! {
    // Fixed seed: CI must be reproducible; change the seed to explore.
    #![proptest_config(ProptestConfig {
        cases: 6,
        rng_seed: proptest::test_runner::RngSeed::Fixed(0x64_5e_ed),
        ..ProptestConfig::default()
    })]

    /// Random dense programs: moves of 1 µm to 1 mm (log-uniform), random
    /// small turns and now and then a sharp corner, random tolerance.
    #[test]
    fn random_dense_programs_finish_within_p(
        seed in any::<u64>(),
        n in 200usize..1200,
        tol_exp in -3.3f64..-1.3,
    ) {
        let cfg = InterpConfig::default();
        let tol = 10f64.powf(tol_exp);
        let pts = dense_program(seed, n);
        let o = run(&program_text(&pts, tol, 6000.0), &pts, &cfg);
        check(&o, &pts, tol, &cfg, "random");
    }
}
