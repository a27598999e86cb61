//! Issue 15: every valid program finishes. Random G-code programs, written
//! as text and run as the drivers run them (parser, `G64 P` stage,
//! interpolator): moves from 1 nm to 10 mm (seven decades, log-uniform), now
//! and then a move of metres, zero-length moves, corners of every angle,
//! random feeds, exact stops (`G61`) or a blend tolerance (`G64 P`). Each
//! must end at rest exactly on its last point, within [`RATIO_BOUND`] times
//! its reference: the acceleration-only optimum (`interpd_tests::path_time`)
//! plus what jerk limits must cost at the stops the program makes (a
//! rest-to-rest move of 1 µm takes 6.8 ms jerk-limited, 1.4 ms with
//! acceleration alone: no multiple of the optimum bounds that).
//!
//! The default run takes programs of hundreds of moves; the issue's size
//! (10⁵ moves) is ignored by default, run it in release:
//!
//! ```text
//! cargo test --release -p interpd-tests --test random_programs -- --ignored --nocapture
//! ```

use gcode::CoreOptions;
use interp_core::smooth::Policy;
use interp_core::{InterpConfig, Vec3};
use interpd_tests::path_time::{
    accel_only_optimum, interpolated_run_within, jerk_aware_bound, machine_with_jerk, smoothed,
    stop_allowance,
};
use proptest::prelude::*;

/// Bound on path time / reference (below).
const RATIO_BOUND: f64 = 2.0;

struct Rng(u64);

impl Rng {
    fn unit(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// A random program of `n` moves from `seed`: its G-code text, its points
/// (the start first), whether it stops exactly at every corner (`exact`,
/// else chosen by the seed, 30 % of programs), and how
/// many of its moves have zero length.
fn random_program(seed: u64, n: usize, exact: Option<bool>) -> (String, Vec<Vec3>, bool, usize) {
    let mut rng = Rng(seed | 1);
    let exact = exact.unwrap_or(rng.unit() < 0.3);
    let mut text = String::from("G21 G90 G94 G17\n");
    text += &if exact {
        "G61\n".to_string()
    } else {
        format!("G64 P{}\n", 10f64.powf(-4.0 + 3.0 * rng.unit()))
    };
    let mut pts = vec![Vec3::zeros()];
    let mut dir = Vec3::x();
    let mut long_moves = 0;
    let mut zero = 0;
    for i in 0..n {
        let p = *pts.last().unwrap();
        let r = rng.unit();
        let len = if r < 0.005 {
            zero += 1;
            0.0
        } else if r < 0.01 && long_moves < 2 {
            long_moves += 1;
            10f64.powf(3.0 + rng.unit())
        } else {
            10f64.powf(-6.0 + 7.0 * rng.unit())
        };
        // Mostly gentle turns (a finishing pass), sometimes any corner.
        let turn = if rng.unit() < 0.2 {
            std::f64::consts::PI * rng.unit()
        } else {
            0.05 * (rng.unit() - 0.5)
        };
        let (s, c) = turn.sin_cos();
        let lift = 0.2 * (rng.unit() - 0.5);
        dir = Vec3::new(c * dir.x - s * dir.y, s * dir.x + c * dir.y, dir.z + lift).normalize();
        let q = p + dir * len;
        text += &format!("G1 X{} Y{} Z{}", q.x, q.y, q.z);
        if len > 100.0 {
            // Metres at production feed (the run's machine time stays short).
            text += &format!(" F{}", 6000.0 + 9000.0 * rng.unit());
        } else if i == 0 || rng.unit() < 0.05 {
            text += &format!(" F{}", 60.0 + 14_940.0 * rng.unit());
        }
        text += "\n";
        // The machine goes where the text says: the parsed numbers.
        pts.push(q);
    }
    text += "M2\n";
    (text, pts, exact, zero)
}

/// Runs one random program and checks it ends on its last point within the
/// bound; returns (ours, reference, moves run, stops): the reference is the
/// acceleration-only optimum plus the jerk allowance at the stops.
fn check(seed: u64, n: usize, exact: Option<bool>) -> (f64, f64, usize, usize) {
    check_on(&InterpConfig::default(), seed, n, exact)
}

/// [`check`] on the machine of `cfg`.
fn check_on(
    cfg: &InterpConfig,
    seed: u64,
    n: usize,
    exact: Option<bool>,
) -> (f64, f64, usize, usize) {
    let (text, pts, exact, zero) = random_program(seed, n, exact);
    check_text(cfg, &text, &pts, exact, n - zero, &format!("seed {seed}"))
}

/// [`check`] of a program's text: `pts` its points, `moves` how many of its
/// moves have a length.
fn check_text(
    cfg: &InterpConfig,
    text: &str,
    pts: &[Vec3],
    exact: bool,
    moves: usize,
    what: &str,
) -> (f64, f64, usize, usize) {
    let cfg = *cfg;
    let program = gcode::parse(text).expect("parses");
    let blocks = program
        .to_core_blocks(&CoreOptions::default())
        .expect("converts");
    assert_eq!(blocks.len(), moves, "{what}: zero-length moves are skipped");
    let (out, _) = smoothed(&blocks, &cfg, Policy::Auto);
    let optimum = accel_only_optimum(&out, &cfg);
    // What jerk limits cost at the stops the schedule must make (every
    // block under G61; else a junction slower than a stop, as the planner
    // treats it): `path_time::stop_allowance`.
    let (allowance, stops) = stop_allowance(&out, &cfg, exact);
    let bound = RATIO_BOUND * (optimum + allowance);
    // Ticks past the bound fail the run (an error) instead of running on.
    let max_ticks = (bound / cfg.period).ceil() as u64 + 2;
    let run = interpolated_run_within(&out, &cfg, true, max_ticks)
        .unwrap_or_else(|e| panic!("{what}: {e} (bound {bound} s)"));
    // Every limit on every tick, by finite differences of the setpoints.
    let v = run.violations;
    assert_eq!(
        v.total(),
        0,
        "{what}: {} (first at seq {:?}); path jerk {:.0}, axis jerk {:?} mm/s³",
        v.breakdown(),
        v.first_seq,
        run.measured.path_jerk_mm_s3,
        run.measured.axis_jerk_mm_s3
    );
    let ours = run.time;
    let p = run.plan;
    eprintln!(
        "{what}: look-ahead {} solves, {} aggregated, {} retries, {} crawls",
        p.solves,
        p.aggregated,
        p.retries(),
        p.added_stops()
    );
    let last = *run.points.last().unwrap();
    assert_eq!(last, *pts.last().unwrap(), "{what}: ends on its last point");
    assert!(ours <= bound, "{what}: {ours} s against bound {bound} s");
    // And no faster than any jerk-limited schedule can be (up to 10⁴
    // moves: the bound's passes take ten minutes on 10⁵, 30× the run).
    if out.len() <= 20_000 {
        let lower = jerk_aware_bound(&out, &cfg);
        assert!(
            lower <= ours,
            "{what}: {ours} s below the lower bound {lower} s"
        );
        eprintln!("{what}: ours/lower bound {:.3}", ours / lower);
    }
    (ours, optimum + allowance, out.len(), stops)
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 6,
        rng_seed: proptest::test_runner::RngSeed::Fixed(0x15_c0de),
        ..ProptestConfig::default()
    })]

    #[test]
    fn random_programs_end_at_rest_on_their_last_point_near_the_optimum(
        seed in any::<u64>(),
        n in 20usize..300,
    ) {
        let (ours, reference, moves, stops) = check(seed, n, None);
        eprintln!("seed {seed}: {moves} moves, {stops} stops, {ours:.3} s, reference {reference:.3} s, {:.3}×", ours / reference);
    }
}

/// A machine with jerk limits `jerk` (the axes' twice that) and
/// acceleration `accel` (the axes' `axis_accel`), the rest as the defaults.
fn machine(jerk: f64, accel: f64, axis_accel: f64) -> InterpConfig {
    InterpConfig {
        max_path_accel: accel,
        axis_max_accel: [axis_accel; 3],
        ..machine_with_jerk(jerk)
    }
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 4,
        rng_seed: proptest::test_runner::RngSeed::Fixed(0x50f7_571f),
        ..ProptestConfig::default()
    })]

    /// The same on machines from soft to stiff: jerk limits from 10⁴ to
    /// 10⁹ mm/s³, accelerations from 300 to 10⁴ mm/s² (the axes' at least
    /// twice the path's, as the defaults' share assumes).
    #[test]
    fn random_programs_end_near_the_optimum_on_soft_and_stiff_machines(
        seed in any::<u64>(),
        n in 20usize..300,
        jerk_exp in 4.0f64..9.0,
        accel_exp in 2.5f64..4.0,
        axis_share in 0.0f64..0.3,
    ) {
        let accel = 10f64.powf(accel_exp);
        let cfg = machine(10f64.powf(jerk_exp), accel, 2.0 * accel * 10f64.powf(axis_share));
        let (ours, reference, moves, _) = check_on(&cfg, seed, n, None);
        eprintln!("seed {seed}: {moves} moves, {:.3}× on J {:.3e} A {accel:.0}", ours / reference, cfg.max_path_jerk);
    }
}

/// Found on a stiff machine (jerk 10⁷ mm/s³): half a tick of jerk is more
/// than the acceleration limit, and the plan left each rest point of a
/// `G61` program at up to 1.9× it (the rest rows had no bound by it).
#[test]
fn a_stiff_machine_leaves_its_rest_points_within_its_acceleration_limit() {
    check_on(&machine(1e7, 2000.0, 4000.0), 10549479219436498, 299, None);
}

/// Found on a soft machine (jerk 10⁴ mm/s³): the program's last two moves
/// (115 nm and 1 nm) came after a plan to a block's end and were shorter
/// than the smallest piece the look-ahead plans; the machine waited short
/// of them for good.
#[test]
fn the_last_moves_of_a_program_run_however_short_they_are() {
    check_on(
        &machine(1e4, 2000.0, 4000.0),
        9456108982048456704,
        299,
        None,
    );
}

/// Found by the property test: fitted pieces with turns of a few µm
/// radius. A cubic C2 knot's step of `C‴` (the axis jerk steps with it) was
/// seen by no sample a few µm past it (1.04× an axis's jerk); a turn between
/// a piece's start and its first law sample by none at all (3.4×); a turn
/// at a piece's end, where the run stops, at its peak only (1.12×); and a
/// 15 µm turn between samples 16 µm apart (1.01×). The first 60 moves of
/// this seed hold the third; the property test's fixed seed holds the
/// first, `interpolator.rs` the second (BENCHMARKS.md has the fourth).
#[test]
fn tight_turns_of_fitted_pieces_hold_every_axis_limit() {
    let (ours, reference, moves, _) = check(8181703606750537106, 60, None);
    eprintln!("{moves} moves, {ours:.3} s, {:.3}×", ours / reference);
}

/// Found by the property test: micro-moves (20 nm to 2 mm) turning sharply
/// under `G64 P0.0008`. The stage fitted them with pieces of nanometre radius,
/// slower than 0.06 mm/s at their tightest (against a stop's 1.8 mm/s), and
/// the schedule crossed each slow point's law sub-range (31 µm) at that
/// speed: 1.6 s for 6 mm, 8.2× the optimum. Fits slower than a stop are
/// now refused like such blends, and the turns become corners.
#[test]
fn micro_moves_turning_sharply_become_corners_not_slow_pieces() {
    let pts: Vec<Vec3> = [
        [0.0, 0.0, 0.0],
        [
            1.7650315385253634e-05,
            -1.943887610877937e-06,
            -3.1266450832845294e-06,
        ],
        [
            7.109555872375495e-05,
            -7.379077942459844e-06,
            -7.906780183475348e-06,
        ],
        [
            3.5567652780177923,
            -0.43229443315533445,
            -0.3744045162839029,
        ],
        [4.188486700293197, -0.5035704833363468, -0.44707440738307014],
        [4.189997954907994, -0.5037245630026064, -0.4471139753893567],
        [5.9446190999160535, -0.646011864630907, -0.5945873873392884],
        [5.944747551415276, -0.6460211475598783, -0.594593386819156],
        [5.9510903522013905, -0.6465999637391633, -0.5951157069722512],
        [5.951097003845916, -0.6465796244500837, -0.5951182089070244],
        [5.951161286810475, -0.646380663974071, -0.595154805823654],
        [5.951149560012709, -0.6463773610791463, -0.5951578872102345],
    ]
    .map(|p| Vec3::new(p[0], p[1], p[2]))
    .to_vec();
    let mut text = String::from("G21 G90 G94 G17\nG64 P0.0008171162989557099\nF2327.17\n");
    for p in &pts[1..] {
        text += &format!("G1 X{} Y{} Z{}\n", p.x, p.y, p.z);
    }
    let (ours, reference, _, _) = check_text(
        &InterpConfig::default(),
        &text,
        &pts,
        false,
        pts.len() - 1,
        "micro-moves",
    );
    // 1.599 s before; 0.394 s now.
    assert!(ours < 0.5, "{ours} s (reference {reference} s)");
}

/// Where junctions and rest points crowd the look-ahead, the cut pieces
/// next to them did not all fit one linear program, and a piece left uncut
/// crept out of its rest point. A junction's span that holds a rest point
/// is now not graded (the rest point is, and is slower): seed 5's programs
/// of 600 moves took 1.92× (`G64 P`) and 1.64× (`G61`) their reference.
#[test]
fn junctions_next_to_rest_points_leave_room_for_the_cuts_ahead() {
    for (exact, bound) in [(false, 1.8), (true, 1.55)] {
        let (ours, reference, moves, _) = check(5, 600, Some(exact));
        let ratio = ours / reference;
        eprintln!("seed 5, exact {exact}: {moves} moves, {ratio:.3}×");
        assert!(ratio < bound, "exact {exact}: {ratio:.3}× the reference");
    }
}

/// Where the look-ahead holds more cuts than one linear program, the cuts
/// claim the room by kind, each kind nearest first: the grading next to
/// rest points, then the ends of slow spans, then the rest (they took it
/// nearest first, all kinds of a piece at once). A rest left ungraded
/// creeps out of it, and a piece not cut at a span's end is held to the
/// span's speed over its whole length, if the machine gets there before
/// the next solve. Seed 1's `G64 P` program of 600 moves.
#[test]
fn the_cuts_that_matter_most_claim_the_room_first() {
    let (ours, reference, moves, _) = check(1, 600, Some(false));
    let ratio = ours / reference;
    eprintln!("seed 1: {moves} moves, {ours:.3} s, {ratio:.4}×");
    // 1.2116× before (77.6 s), 1.1561× now (74.0 s).
    assert!(ratio < 1.19, "{ratio:.4}× the reference");
}

/// Found measuring the issue's sizes (seed 1's `G64 P` program of 10⁴
/// moves): a line of 0.6 mm after a 33 µm blend took 35 s. A short piece
/// of the line, with no derivative samples of its own, borrowed the
/// blend's end sample (`C‴` ≈ 400 mm⁻²) across the junction, and the
/// plan held the line near zero speed. The first 5,300 moves of that
/// program show it (release: a few seconds).
#[test]
#[ignore]
fn a_blend_s_derivatives_do_not_hold_back_the_line_after_it() {
    let (ours, reference, moves, _) = check(1, 5300, Some(false));
    eprintln!(
        "seed 1: {moves} moves, {ours:.3} s, {:.3}×",
        ours / reference
    );
    // 379.7 s before (1.78× the reference), 320.3 s now (1.50×).
    assert!(ours < 350.0, "{ours} s (reference {reference} s)");
}

/// Eighty programs of 299 moves (seeds drawn from two fixed streams), each
/// held to every limit on every tick: the property test's six cases, and
/// more (release: four minutes).
#[test]
#[ignore]
fn eighty_random_programs_hold_every_limit_on_every_tick() {
    for stream in [777, 4242] {
        let mut r = Rng(stream);
        for _ in 0..40 {
            let seed = (r.unit() * 1.8e19) as u64;
            let (ours, reference, moves, _) = check(seed, 299, None);
            eprintln!("seed {seed}: {moves} moves, {:.3}×", ours / reference);
        }
    }
}

/// The issue's size: programs of 10⁴ and 10⁵ moves, `G64 P` and `G61`
/// (release: a minute).
#[test]
#[ignore]
fn random_programs_of_a_hundred_thousand_moves_end_near_the_optimum() {
    for (seed, n, exact) in [
        (1, 10_000, false),
        (2, 10_000, true),
        (3, 100_000, false),
        (4, 100_000, true),
    ] {
        let t = std::time::Instant::now();
        let (ours, reference, moves, stops) = check(seed, n, Some(exact));
        eprintln!(
            "seed {seed}: {moves} moves, {stops} stops, {ours:.3} s, reference {reference:.3} s, {:.3}× ({:.1} s wall)",
            ours / reference,
            t.elapsed().as_secs_f64()
        );
    }
}
