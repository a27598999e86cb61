//! Program blocks → interp-core blocks.

use gcode::{ConvertError, CoreOptions, FiveAxisReason, parse};
use interp_core::Curve;
use interp_core::kinematics::{Machine, MachineSpec, RotaryRange};
use interp_core::path::{Path, PathError};

fn core(text: &str) -> Vec<interp_core::Block> {
    parse(text)
        .unwrap()
        .to_core_blocks(&CoreOptions::default())
        .unwrap()
}

fn arr(v: interp_core::Vec3) -> [f64; 3] {
    [v.x, v.y, v.z]
}

#[test]
fn feeds_become_mm_per_second_and_rapids_use_the_rapid_speed() {
    let opts = CoreOptions {
        rapid_speed: 123.0,
        ..CoreOptions::default()
    };
    let b = parse("G0 X10\nG1 Y10 F600\nG20 G1 X0 F60\n")
        .unwrap()
        .to_core_blocks(&opts)
        .unwrap();
    assert_eq!(b.len(), 3);
    assert_eq!(b[0].feed, 123.0);
    assert_eq!(b[1].feed, 10.0);
    assert!((b[2].feed - 25.4).abs() < 1e-12);
    assert_eq!(b.iter().map(|b| b.id).collect::<Vec<_>>(), [1, 2, 3]);
    assert!(matches!(b[1].path, Path::Line(_)));
    assert_eq!(arr(b[1].path.end_point()), [10.0, 10.0, 0.0]);
}

#[test]
fn inverse_time_feed_is_length_over_time() {
    // 30 mm in 1/2 min = 60 mm/min = 1 mm/s.
    let b = core("G93 G1 X30 F2\n");
    assert!((b[0].feed - 1.0).abs() < 1e-12);
}

#[test]
fn zero_length_moves_and_aux_blocks_are_dropped() {
    let b = core("G1 X0 F100\nG4 P1\nS100 M3\nT1 M6\nG64 P0.01\nG1 X1\nM2\n");
    assert_eq!(b.len(), 1);
    assert_eq!(b[0].id, 6);
}

#[test]
fn arcs_are_exact_and_turn_the_programmed_way() {
    let b = core("G0 X10\nG3 X0 Y10 I-10 J0 F600\nG2 X10 Y0 I0 J-10\n");
    let Path::Arc(ccw) = &b[1].path else { panic!() };
    assert_eq!(arr(ccw.start_point()), [10.0, 0.0, 0.0]);
    assert_eq!(arr(ccw.end_point()), [0.0, 10.0, 0.0]);
    assert_eq!(ccw.radius(), 10.0);
    assert!((ccw.sweep() - std::f64::consts::FRAC_PI_2).abs() < 1e-15);
    // Counter-clockwise about +Z: the midpoint is at 45° in the first quadrant.
    let mid = ccw.eval(ccw.sweep() / 2.0, 0).p;
    assert!(
        (mid.x - 10.0 / 2f64.sqrt()).abs() < 1e-12 && (mid.y - 10.0 / 2f64.sqrt()).abs() < 1e-12
    );
    let Path::Arc(cw) = &b[2].path else { panic!() };
    assert_eq!(arr(cw.axis()), [0.0, 0.0, -1.0]);
    // Clockwise back along the same quarter.
    let mid = cw.eval(cw.sweep() / 2.0, 0).p;
    assert!(mid.x > 0.0 && mid.y > 0.0);
}

#[test]
fn g18_and_g19_arcs_turn_about_plus_y_and_plus_x() {
    // G18 G3 from X10 Z0 about the origin: counter-clockwise about +Y goes to −Z first
    // (LinuxCNC: the (Z, X) plane, Z first).
    let b = core("G0 X10\nG18 G3 X-10 Z0 I-10 K0 F60\n");
    let Path::Arc(a) = &b[1].path else { panic!() };
    assert_eq!(arr(a.axis()), [0.0, 1.0, 0.0]);
    assert!(a.eval(a.sweep() / 2.0, 0).p.z < -9.99);
    let b = core("G0 Y10\nG19 G3 Y-10 Z0 J-10 K0 F60\n");
    let Path::Arc(a) = &b[1].path else { panic!() };
    assert_eq!(arr(a.axis()), [1.0, 0.0, 0.0]);
    assert!(a.eval(a.sweep() / 2.0, 0).p.z > 9.99);
}

#[test]
fn helix_with_turns_has_the_programmed_length() {
    // Two full turns (P2) of r = 5 plus a rise of 3 mm.
    let b = core("G0 X5\nG3 X5 Y0 Z3 I-5 J0 P2 F60\n");
    let Path::Arc(a) = &b[1].path else { panic!() };
    let expected = (2.0 * 2.0 * std::f64::consts::PI * 5.0f64).hypot(3.0);
    assert!((a.length() - expected).abs() < 1e-12);
    assert_eq!(arr(a.end_point()), [5.0, 0.0, 3.0]);
}

#[test]
fn conversion_errors_name_the_source_line() {
    // Accepted by LinuxCNC's tolerance (0.02 mm over r = 10) but beyond
    // interp-core's stricter 0.002 mm / 0.1 %: the conversion says which line.
    let p = parse("G0 X-10\nG2 X10.02 Y0 I10 J0 F100\n").unwrap();
    let e = p.to_core_blocks(&CoreOptions::default()).unwrap_err();
    assert!(
        matches!(
            e,
            ConvertError::Path {
                line: 2,
                error: PathError::RadiusMismatch { .. }
            }
        ),
        "{e:?}"
    );
    assert!(e.to_string().starts_with("line 2: "));
    // A zero rapid speed is refused with the line.
    let p = parse("\nG0 X1\n").unwrap();
    let e = p
        .to_core_blocks(&CoreOptions {
            rapid_speed: 0.0,
            ..CoreOptions::default()
        })
        .unwrap_err();
    assert_eq!(e, ConvertError::Feed { line: 2, feed: 0.0 });
}

#[test]
fn streaming_conversion_stops_when_the_sink_refuses() {
    let p = parse("G1 X1 F60\nX2\nX3\n").unwrap();
    let mut seen = 0;
    let r = p.for_each_core_block(&CoreOptions::default(), |_| {
        seen += 1;
        if seen == 2 { Err("full") } else { Ok(()) }
    });
    assert_eq!(r, Err(gcode::ConvertOrSinkError::Sink("full")));
    assert_eq!(seen, 2);
}

#[test]
fn the_benchmark_program_parses_and_converts() {
    let text = gcode::generate::g1_heavy_program(300_000);
    let p = parse(&text).unwrap_or_else(|e| panic!("{e}"));
    assert!(p.blocks.len() > 5000);
    let b = p.to_core_blocks(&CoreOptions::default()).unwrap();
    assert!(b.len() > 5000);
}

#[test]
fn g64_p_is_the_programs_path_tolerance_in_mm() {
    let tol = |t: &str| parse(t).unwrap().path_tolerance();
    assert_eq!(tol("G64 P0.01\nG1 X1 F1\nG64 P0.5\nG1 X2\n"), Some(0.01));
    assert_eq!(tol("G20 G64 P0.001\nG1 X1 F1\n"), Some(0.0254));
    assert_eq!(tol("G1 X1 F1\nG64 P0.02\nG1 X2\n"), Some(0.02));
    assert_eq!(tol("G64\nG1 X1 F1\n"), None);
    assert_eq!(tol("G1 X1 F1\n"), None);
}

#[test]
fn the_path_control_mode_in_force_becomes_each_blocks_blending() {
    use interp_core::Blending;
    let p = parse("G1 X1 F60\nG61.1\nG1 X2\nG64 P0.005\nG1 X3\nG64\nG1 X4\nG61\nG1 X5\n").unwrap();
    let modes: Vec<Blending> = p
        .to_core_blocks(&CoreOptions::default())
        .unwrap()
        .iter()
        .map(|b| b.blending)
        .collect();
    assert_eq!(
        modes,
        [
            Blending::ExactPath,
            Blending::ExactStop,
            Blending::Within {
                tolerance: Some(0.005)
            },
            Blending::Within { tolerance: None },
            Blending::ExactPath,
        ]
    );
}

/// What five-axis conversion refuses, naming the line and the reason.
#[test]
fn five_axis_moves_that_cannot_be_converted_are_refused_naming_the_line() {
    let ca = ca_options();
    for (text, opts, line, reason) in [
        // Under TCP at the pole (A = 0) C turns but the tool does not.
        (
            "G0 X0 Y0 Z10 A0 C0\nG43.4\nG1 X0 Y0 Z10 F100\nG1 C90\n",
            ca,
            4,
            FiveAxisReason::RotaryOnly,
        ),
        (
            "G43.4\nG0 X0 Y0 Z10\n",
            CoreOptions::default(),
            2,
            FiveAxisReason::NoMachine,
        ),
        (
            "G43.5\nG1 X1 I0 J0 K1 F100\n",
            CoreOptions::default(),
            2,
            FiveAxisReason::NoMachine,
        ),
        // Under TCP the first move after G43.4 starts where the machine's
        // tool tip is: an arc cannot.
        (
            "G0 X10 Y0 Z0\nG43.4\nG2 X-10 Y0 I-10 J0 F100\n",
            ca,
            3,
            FiveAxisReason::FrameChange,
        ),
        // A C,A table cannot tilt by 120 degrees within A's range.
        (
            "G43.5\nG1 X5 I0 J0.866 K-0.5 F100\n",
            ca,
            2,
            FiveAxisReason::Inverse(interp_core::kinematics::InverseError::OutOfRange {
                axis: interp_core::kinematics::RotaryAxis::A,
                needed: -120.00000000000001,
                range: interp_core::kinematics::RotaryRange {
                    min: -100.0,
                    max: 100.0,
                },
            }),
        ),
    ] {
        let e = parse(text).unwrap().to_core_blocks(&opts).unwrap_err();
        match &e {
            ConvertError::FiveAxisMove { line: l, reason: r } => {
                assert_eq!(*l, line, "{text}: {e}");
                if let (FiveAxisReason::Inverse(_), FiveAxisReason::Inverse(_)) = (r, &reason) {
                } else {
                    assert_eq!(*r, reason, "{text}: {e}");
                }
            }
            other => panic!("{text}: {other}"),
        }
        assert!(e.to_string().starts_with(&format!("line {line}: ")), "{e}");
    }
    // Rotary words that move nothing, and G49, convert as before.
    let b = core("G0 X0 Y0 Z1 A0 C0\nG49 G1 X1 A0 F600\n");
    assert_eq!(b.len(), 2);
    assert!(b.iter().all(|b| b.orientation.is_none()));
}

fn ca_options() -> CoreOptions {
    let mut spec = MachineSpec::new("W/caxyBz/T".parse().unwrap());
    spec.tool_length = 50.0;
    spec.rotary_ranges[0] = RotaryRange {
        min: -100.0,
        max: 100.0,
    };
    CoreOptions {
        machine: Some(spec),
        ..CoreOptions::default()
    }
}

/// A B C without TCP are plain axes along the move (and along a G6.2 as
/// coordinates of the curve); G43.4 turns rotary positions into tool axes
/// through the machine, G43.5 takes I J K; where TCP goes on, the move
/// starts at the tool tip of the machine's joints, and after G49 at their
/// X Y Z.
#[test]
fn five_axis_moves_convert_to_core_orientations() {
    use interp_core::fiveaxis::{Orientation as O, OrientationAt};
    let b = core("G0 X0 Y0 Z1\nG1 X10 A30 C-90 F600\n");
    assert_eq!(b.len(), 2);
    let o = b[1].orientation.expect("axes");
    assert!(!o.is_tcp());
    assert_eq!(o.at(0.0), OrientationAt::Axes([0.0, 0.0, 0.0]));
    assert_eq!(o.at(5.0), OrientationAt::Axes([15.0, 0.0, -45.0]));
    // G6.2 with B coordinates (TCP off): B is a coordinate of the curve
    // (one quadratic span: B = 10 at its middle parameter by symmetry).
    let b = core(
        "G0 X0 Y0\nF600 G6.2 P3 X0 Y0 R1 K0\nX1 Y1 B10 R1 K0\nX2 Y0 B20 R1 K0\nG6.2 K1\nG6.2 K1\nG6.2 K1\n",
    );
    let o = b[0].orientation.expect("rotary curve");
    assert_eq!(o.at(0.0), OrientationAt::Axes([0.0, 0.0, 0.0]));
    assert_eq!(o.at(1.0), OrientationAt::Axes([0.0, 20.0, 0.0]));
    let OrientationAt::Axes(mid) = o.at(0.5) else {
        panic!()
    };
    assert!((mid[1] - 10.0).abs() < 1e-12, "{mid:?}");

    let opts = ca_options();
    let m = Machine::new(opts.machine.unwrap()).unwrap();
    let text = "G0 X10 Y0 Z0 A0 C0\nG43.4\nG1 X10 Y0 Z5 A30 C90 F600\nG43.5\nG1 X20 I0 J0 K1\nG49\nG1 X0 Y0 Z0\n";
    let b = parse(text).unwrap().to_core_blocks(&opts).unwrap();
    assert_eq!(b.len(), 4);
    // Under TCP from the tool tip of the joints (10, 0, 0, A0, C0): z = −50.
    assert_eq!(arr(b[1].path.start_point()), [10.0, 0.0, -50.0]);
    assert_eq!(arr(b[1].path.end_point()), [10.0, 0.0, 5.0]);
    let o = b[1].orientation.unwrap();
    assert!(o.is_tcp());
    let axis = |o: &O, u: f64| match o.at(u) {
        OrientationAt::ToolAxis(a) => a,
        other => panic!("{other:?}"),
    };
    let want = m.forward(&[0.0, 0.0, 0.0, 30.0, 0.0, 90.0]).axis;
    assert!((axis(&o, b[1].path.u_end()) - want).norm() < 1e-15);
    assert!((axis(&o, b[1].path.u_start()) - interp_core::Vec3::z()).norm() < 1e-15);
    // G43.5 I0 J0 K1: the axis turns back to +z.
    let o = b[2].orientation.unwrap();
    assert!((axis(&o, b[2].path.u_end()) - interp_core::Vec3::z()).norm() < 1e-15);
    // After G49: from the joints' X Y Z at the tip (20, 0, 5) with the axis
    // +z: the pole, where C keeps its 90 degrees (the table turned a
    // quarter), so X Y Z = (0, −20, 55).
    assert!(b[3].orientation.is_none());
    let p = b[3].path.start_point();
    assert!(
        (p - interp_core::Vec3::new(0.0, -20.0, 55.0)).norm() < 1e-12,
        "{p:?}"
    );
}

/// A move whose tip (or X Y Z) stands still but whose rotary axes or tool
/// turn is a turn in place: its path is the turn's measure in degrees from
/// where the tool stands, F in deg/min (G93: the turn in 1/F min, G0 at the
/// rapid speed), and the next move starts where the tool stands.
#[test]
fn rotary_only_moves_turn_in_place() {
    use interp_core::fiveaxis::OrientationAt;
    let opts = CoreOptions {
        rapid_speed: 100.0,
        ..ca_options()
    };
    let text = "G0 X10 Y0 Z5\nG0 A30 C40\nG1 A0 F600\nG93 G1 C0 F4\nG94 G1 X12 F600\n";
    let b = parse(text).unwrap().to_core_blocks(&opts).unwrap();
    assert_eq!(b.len(), 5);
    let at = [10.0, 0.0, 5.0];
    for (k, (turn, feed, end)) in [
        (50.0, 100.0, [30.0, 0.0, 40.0]),
        (30.0, 10.0, [0.0, 0.0, 40.0]),
        // 40 degrees in a quarter of a minute: 160 deg/min.
        (40.0, 160.0 / 60.0, [0.0, 0.0, 0.0]),
    ]
    .into_iter()
    .enumerate()
    {
        let t = &b[1 + k];
        assert!(t.is_in_place() && !t.is_tcp(), "block {}", k + 2);
        assert_eq!(arr(t.start_position()), at);
        assert_eq!(arr(t.end_position()), at);
        assert!(
            (t.path.length() - turn).abs() < 1e-12,
            "{}",
            t.path.length()
        );
        assert!((t.feed - feed).abs() < 1e-12, "{} {}", t.feed, feed);
        let o = t.orientation.unwrap();
        assert_eq!(o.at(t.path.u_end()), OrientationAt::Axes(end));
    }
    assert_eq!(arr(b[4].path.start_point()), at);
    assert!(b[4].orientation.is_none());

    // Under G43.4 the tip stands and the tool axis turns (by A's 20 degrees
    // on a C,A table); under G43.5 by the angle between the vectors.
    let text = "G0 X10 Y0 Z5 A0 C0\nG43.4\nG1 X10 Y0 Z5 F600\nG1 A20\nG43.5\nG1 I0 J0 K1\n";
    let b = parse(text).unwrap().to_core_blocks(&opts).unwrap();
    let turns: Vec<_> = b.iter().filter(|b| b.is_in_place()).collect();
    assert_eq!(turns.len(), 2);
    for t in &turns {
        assert!(t.is_tcp());
        assert!((t.path.length() - 20.0).abs() < 1e-9, "{}", t.path.length());
        assert_eq!(t.start_position(), turns[0].start_position());
    }
}

/// A G6.2 program text (order `degree + 1`) of `points` with A and C on
/// every control point, and its knot vector.
fn rotary_nurbs_text(
    degree: usize,
    points: &[[f64; 3]],
    rotary: &[[f64; 3]],
    weights: &[f64],
    knots: &[f64],
) -> String {
    use std::fmt::Write as _;
    let mut text = format!(
        "G0 X{} Y{} Z{}\nF600 G6.2 P{}",
        points[0][0],
        points[0][1],
        points[0][2],
        degree + 1
    );
    for (i, pt) in points.iter().enumerate() {
        if i > 0 {
            text.push('\n');
        }
        write!(
            text,
            " X{} Y{} A{} C{} R{} K{}",
            pt[0], pt[1], rotary[i][0], rotary[i][2], weights[i], knots[i]
        )
        .unwrap();
    }
    text.push('\n');
    for k in &knots[points.len()..] {
        writeln!(text, "G6.2 K{k}").unwrap();
    }
    text
}

/// 40 control points (more than one block holds), rational, cubic, with
/// uneven knots; A and C change along it.
struct RotaryNurbs {
    degree: usize,
    points: Vec<[f64; 3]>,
    rotary: Vec<[f64; 3]>,
    weights: Vec<f64>,
    knots: Vec<f64>,
}

fn rotary_nurbs() -> RotaryNurbs {
    let (n, p) = (40, 3);
    let mut pts = Vec::new();
    let mut rot = Vec::new();
    let mut ws = Vec::new();
    for i in 0..n {
        let t = i as f64;
        pts.push([
            20.0 * (0.3 * t).sin() + 2.0 * t,
            15.0 * (0.2 * t).cos() - 15.0,
            0.0,
        ]);
        rot.push([10.0 * (0.25 * t).sin(), 0.0, 4.0 * t]);
        ws.push(1.0 + 0.5 * (1.7 * t).sin().abs());
    }
    let mut knots = vec![0.0; p + 1];
    let mut u = 0.0;
    for j in 0..n - p - 1 {
        u += 1.0 + 0.3 * (j as f64).sin();
        knots.push(u);
    }
    u += 1.0;
    knots.extend([u; 4]);
    RotaryNurbs {
        degree: p,
        points: pts,
        rotary: rot,
        weights: ws,
        knots,
    }
}

/// The rotary curve by the definition of a NURBS, `Σ Nᵢ·wᵢ·rᵢ / Σ Nᵢ·wᵢ`.
fn rotary_at(p: usize, rot: &[[f64; 3]], ws: &[f64], knots: &[f64], u: f64) -> [f64; 3] {
    let (span, n) = interp_core::nurbs::basis_functions(p, knots, u);
    let (mut num, mut den) = ([0.0; 3], 0.0);
    for k in 0..=p {
        let i = span - p + k;
        for j in 0..3 {
            num[j] += n[k] * ws[i] * rot[i][j];
        }
        den += n[k] * ws[i];
    }
    num.map(|v| v / den)
}

/// G6.2 with A B C on its control points, TCP off: the rotary axes are
/// coordinates of the curve (same weights and knots, as Fanuc allows). The
/// curve is cut into its knot spans, each block with its piece of the
/// rotary curve; at every parameter the blocks give what the program's
/// NURBS gives by its definition within 1e-9 degrees, neighbouring blocks
/// meet bit for bit, and X Y Z are the program's curve.
/// The second curve of a G6.2 cut into one block per knot span: checks
/// that consecutive blocks meet bit for bit, and returns each block's
/// orientation at 21 parameters of its span, and its orientation at the
/// curve's end.
fn span_samples(
    curve: &[&interp_core::Block],
) -> (
    Vec<(interp_core::fiveaxis::OrientationAt, f64)>,
    Option<interp_core::fiveaxis::OrientationAt>,
) {
    let mut samples = Vec::new();
    let mut prev_end = None;
    for blk in curve {
        let o = blk.orientation.expect("a curve's orientation");
        let (ua, ub) = (blk.path.u_start(), blk.path.u_end());
        if let Some(e) = prev_end {
            assert_eq!(o.at(ua), e, "blocks meet bit for bit");
        }
        prev_end = Some(o.at(ub));
        for k in 0..=20 {
            let u = ua + (ub - ua) * k as f64 / 20.0;
            samples.push((o.at(u), u));
        }
    }
    (samples, prev_end)
}

#[test]
fn g6_2_rotary_coordinates_are_coordinates_of_the_curve() {
    use interp_core::fiveaxis::OrientationAt;
    let RotaryNurbs {
        degree: p,
        points: pts,
        rotary: rot,
        weights: ws,
        knots,
    } = rotary_nurbs();
    let text = rotary_nurbs_text(p, &pts, &rot, &ws, &knots);
    let b = core(&text);
    let curve: Vec<_> = b
        .iter()
        .filter(|b| matches!(b.path, Path::Nurbs(_)))
        .collect();
    assert_eq!(curve.len(), pts.len() - p, "one block per knot span");
    assert!(
        curve
            .iter()
            .all(|b| !b.orientation.expect("rotary curve").is_tcp())
    );
    let (samples, prev_end) = span_samples(&curve);
    let mut worst = 0.0f64;
    for (at, u) in samples {
        let OrientationAt::Axes(got) = at else {
            panic!("axes")
        };
        let want = rotary_at(p, &rot, &ws, &knots, u);
        for j in 0..3 {
            worst = worst.max((got[j] - want[j]).abs());
        }
    }
    assert!(worst < 1e-9, "rotary curve off by {worst} degrees");
    assert_eq!(prev_end, Some(OrientationAt::Axes(rot[rot.len() - 1])));
    // The first block starts at the first control point's A B C exactly.
    assert_eq!(
        curve[0].orientation.unwrap().at(curve[0].path.u_start()),
        OrientationAt::Axes(rot[0])
    );
}

/// Under G43.4 a NURBS is the tool tip and its rotary coordinates (given,
/// or the ones in force) the rotary positions: each knot span a block
/// under TCP whose rotary curve is the program's (a G6.2 with A and C on
/// its points) or constant (a G5.2 without them: the tool kept).
#[test]
fn nurbs_under_g43_4_are_tip_paths_with_rotary_curves() {
    use interp_core::fiveaxis::OrientationAt;
    let ca = ca_options();
    let text = "G0 X0 Y0 Z120 A10 C30\nG43.4\nG1 X0 Y0 Z0 F600\n\
                G6.2 P3 X0 Y0 R1 K0\nX5 Y5 A20 C40 R1 K0\nX10 Y0 A10 C50 R1 K0\nG6.2 K1\nG6.2 K1\nG6.2 K1\n\
                G5.2 X10 Y0 P1 L3\nX15 Y-5 P1\nX20 Y0 P1\nG5.3\n";
    let blocks = parse(text).unwrap().to_core_blocks(&ca).unwrap();
    let curves: Vec<_> = blocks
        .iter()
        .filter(|b| matches!(b.path, Path::Nurbs(_)))
        .collect();
    // The G6.2 is one span, the G5.2 two.
    assert_eq!(curves.len(), 3, "{blocks:?}");
    for b in &curves {
        let o = b.orientation.expect("rotary curve");
        assert!(o.is_tcp() && b.is_tcp(), "{o:?}");
    }
    let g6 = curves[0];
    let o6 = g6.orientation.unwrap();
    assert_eq!(
        o6.at(g6.path.u_start()),
        OrientationAt::Axes([10.0, 0.0, 30.0])
    );
    assert_eq!(
        o6.at(g6.path.u_end()),
        OrientationAt::Axes([10.0, 0.0, 50.0])
    );
    for g5 in &curves[1..] {
        let o5 = g5.orientation.unwrap();
        for k in 0..=4 {
            let u = g5.path.u_start() + (g5.path.u_end() - g5.path.u_start()) * k as f64 / 4.0;
            let OrientationAt::Axes(abc) = o5.at(u) else {
                panic!("axes")
            };
            for (got, want) in abc.iter().zip([10.0, 0.0, 50.0]) {
                assert!((got - want).abs() < 1e-12, "{abc:?}");
            }
        }
    }
}

/// G6.2 under G43.5 with a tool vector `U V W` on each control point: a
/// second curve for the tool axis. The 40-point rational cubic of
/// [`rotary_nurbs`] with vectors tilting and turning along it: each knot
/// span a block under TCP whose tool axis is, at 21 parameters, the
/// normalised NURBS of the vectors by its definition within 1e-12 rad;
/// neighbours meet bit for bit; a G1 turns the tool to the curve's first
/// vector before it. A span whose vectors spread over more than a
/// half-space, a zero vector and a vector missing on some points are
/// refused naming their line.
#[test]
fn g6_2_tool_vectors_under_g43_5_are_a_second_curve_for_the_tool_axis() {
    use interp_core::fiveaxis::OrientationAt;
    use std::fmt::Write as _;
    let RotaryNurbs {
        degree: p,
        points: pts,
        weights: ws,
        knots,
        ..
    } = rotary_nurbs();
    let vectors: Vec<[f64; 3]> = (0..pts.len())
        .map(|i| {
            let (tilt, turn) = (
                (10.0 + i as f64).to_radians(),
                (9.0 * i as f64).to_radians(),
            );
            // Lengths vary on purpose: they act as weights of the vector curve.
            let len = 1.0 + 0.1 * (i % 3) as f64;
            [
                len * tilt.sin() * turn.cos(),
                len * tilt.sin() * turn.sin(),
                len * tilt.cos(),
            ]
        })
        .collect();
    let mut text = format!(
        "G0 X{} Y{} Z{} A0 C0\nG43.5\nG1 X{} Y{} Z{} I0 J0 K1 F600\nG6.2 P{}",
        pts[0][0],
        pts[0][1],
        pts[0][2] + 5.0,
        pts[0][0],
        pts[0][1],
        pts[0][2] + 5.0,
        p + 1
    );
    for (i, pt) in pts.iter().enumerate() {
        if i > 0 {
            text.push('\n');
        }
        let v = vectors[i];
        write!(
            text,
            " X{} Y{} Z{} R{} K{} U{} V{} W{}",
            pt[0], pt[1], pt[2], ws[i], knots[i], v[0], v[1], v[2]
        )
        .unwrap();
    }
    text.push('\n');
    for k in &knots[pts.len()..] {
        writeln!(text, "G6.2 K{k}").unwrap();
    }
    let blocks = parse(&text).unwrap().to_core_blocks(&ca_options()).unwrap();
    let curve: Vec<_> = blocks
        .iter()
        .filter(|b| matches!(b.path, Path::Nurbs(_)))
        .collect();
    assert_eq!(curve.len(), pts.len() - p, "one block per knot span");
    // Before the curve: down to its start and a turn to its first vector.
    let unit = |v: [f64; 3]| {
        let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        interp_core::Vec3::new(v[0] / n, v[1] / n, v[2] / n)
    };
    let before = blocks
        .iter()
        .take_while(|b| !matches!(b.path, Path::Nurbs(_)))
        .last()
        .expect("a move before the curve");
    let OrientationAt::ToolAxis(a) = before.orientation.unwrap().at(before.path.u_end()) else {
        panic!("a tool axis")
    };
    assert!((a - unit(vectors[0])).norm() < 1e-12, "{a:?}");
    assert!(
        curve
            .iter()
            .all(|b| b.orientation.expect("tool vector curve").is_tcp() && b.is_tcp())
    );
    let (samples, prev_end) = span_samples(&curve);
    let mut worst = 0.0f64;
    for (at, u) in samples {
        let OrientationAt::ToolAxis(got) = at else {
            panic!("a tool axis")
        };
        let want = unit(rotary_at(p, &vectors, &ws, &knots, u));
        worst = worst.max(got.cross(&want).norm().atan2(got.dot(&want)));
    }
    assert!(worst < 1e-12, "tool axis off its curve by {worst} rad");
    assert_eq!(
        prev_end,
        Some(OrientationAt::ToolAxis(unit(vectors[vectors.len() - 1])))
    );

    // Refused, naming the line: vectors of one span more than a half-space
    // apart (the curve could pass through zero), ...
    let spread = "G0 X0 Y0 Z50\nG43.5\nF600\nG6.2 P2 X0 Y0 Z0 R1 K0 U1 V0 W0\nX10 Y0 Z0 R1 K0 U-1 V0 W0\nG6.2 K1\nG6.2 K1\n";
    let e = parse(spread)
        .unwrap()
        .to_core_blocks(&ca_options())
        .unwrap_err();
    assert!(
        matches!(
            e,
            ConvertError::FiveAxisMove {
                line: 7,
                reason: FiveAxisReason::Orientation(
                    interp_core::fiveaxis::OrientationError::VectorSpread(_)
                )
            }
        ),
        "{e:?}"
    );
    assert!(e.to_string().contains("line 7"), "{e}");
}

/// A second curve (rotary coordinates or tool vectors, as the JSON block
/// form may give them) that is not one per control point is refused, not
/// indexed out of bounds.
#[test]
fn a_second_curve_of_the_wrong_length_is_refused() {
    use gcode::{CutError, Cutter, Move, MoveOrientation, MovePath};
    let points = [[0.0, 0.0, 0.0], [10.0, 0.0, 0.0], [10.0, 10.0, 0.0]];
    let knots = [0.0, 0.0, 0.0, 1.0, 1.0, 1.0];
    let two = [[0.0, 0.0, 1.0]; 2];
    for (rotary, tool_axes, what) in [
        (Some(&two[..]), None, "rotary coordinates"),
        (None, Some(&two[..]), "tool vectors"),
    ] {
        let m = Move {
            line: 3,
            first_line: 3,
            feed: 600.0,
            blending: interp_core::path::Blending::ExactPath,
            start: None,
            path: MovePath::Nurbs {
                degree: 2,
                points: &points,
                weights: None,
                knots: &knots,
                rotary,
                tool_axes,
            },
            orientation: Some(match tool_axes {
                Some(_) => MoveOrientation::ToolAxis {
                    start: [0.0, 0.0, 1.0],
                    end: [0.0, 0.0, 1.0],
                },
                None => MoveOrientation::Axes {
                    start: [0.0; 3],
                    end: [0.0; 3],
                },
            }),
            mrr: None,
        };
        let e = Cutter::new([0.0; 3], tool_axes.is_some(), 1, 32)
            .cut(&m)
            .unwrap_err();
        assert_eq!(
            e,
            CutError::SecondCurveLength {
                what,
                got: 2,
                want: 3
            }
        );
    }
}

/// A G6.2 with U V W printed (`emit`) and read back is the same program.
#[test]
fn g6_2_tool_vectors_print_and_read_back() {
    let text = "G43.5 H1\nG1 X30 Y0 Z-5 I-0.35 J0 K1.2 F1200\n\
                G6.2 P3 X30 Y0 Z-5 U-0.35 V0 W1.2 R1 K0\n\
                X30 Y30 Z-5 U-0.35 V-0.35 W1.2 R0.7071068 K0\n\
                X0 Y30 Z-5 U0 V-0.35 W0.95 R1 K0\nG6.2 K1\nG6.2 K1\nG6.2 K1\nM2\n";
    let p = parse(text).unwrap();
    let n = p
        .blocks
        .iter()
        .find_map(|b| match &b.kind {
            gcode::BlockKind::Nurbs(n) => Some(n),
            _ => None,
        })
        .expect("the curve");
    assert_eq!(n.tool_vectors.len(), 3);
    assert_eq!(n.tool_vectors[1], [-0.35, -0.35, 1.2]);
    let printed = gcode::emit(&p);
    assert!(printed.contains("U-0.35 V-0.35 W1.2"), "{printed}");
    let back = parse(&printed).unwrap();
    let kinds = |p: &gcode::Program| -> Vec<gcode::BlockKind> {
        p.blocks
            .iter()
            .map(|b| match &b.kind {
                gcode::BlockKind::Nurbs(n) => gcode::BlockKind::Nurbs(gcode::NurbsMove {
                    first_line: 0,
                    ..n.clone()
                }),
                k => k.clone(),
            })
            .collect()
    };
    assert_eq!(kinds(&back), kinds(&p));
    // And it converts: the doc's example runs through the machine.
    let blocks = p.to_core_blocks(&ca_options()).unwrap();
    assert_eq!(
        blocks
            .iter()
            .filter(|b| matches!(
                b.orientation,
                Some(interp_core::fiveaxis::Orientation::ToolAxisCurve { .. })
            ))
            .count(),
        1
    );
}
