//! Lexing, modal state, arcs, parameters, units and errors.

use gcode::{
    ArcMove, BlockKind, Feed, LinearMove, ParseErrorKind, PathControl, Plane, Program, parse,
};

fn blocks(text: &str) -> Vec<BlockKind> {
    parse(text)
        .unwrap_or_else(|e| panic!("{e}"))
        .blocks
        .into_iter()
        .map(|b| b.kind)
        .collect()
}

fn ends(text: &str) -> Vec<[f64; 3]> {
    parse(text)
        .unwrap_or_else(|e| panic!("{e}"))
        .end_points()
        .collect()
}

fn arcs(text: &str) -> Vec<ArcMove> {
    blocks(text)
        .into_iter()
        .filter_map(|b| match b {
            BlockKind::Arc(a) => Some(a),
            _ => None,
        })
        .collect()
}

/// (line, column, kind) of the error `text` gives.
fn error(text: &str) -> (u32, u32, ParseErrorKind) {
    let e = parse(text).expect_err("should be refused");
    (e.line, e.column, e.kind)
}

fn close(a: [f64; 3], b: [f64; 3]) -> bool {
    a.iter().zip(&b).all(|(x, y)| (x - y).abs() < 1e-12)
}

#[test]
fn words_are_case_insensitive_with_comments_line_numbers_and_blanks() {
    let text = "%\n\n   \t\nn10 g1 x1 y2 z3 f100 (comment) ; rest\nN20 G1 X 1 0 Y.5 Z-.25\n/G1 X99\nG1X+1.Y-0.5Z0.\n%\nG1 X500\n";
    assert_eq!(
        ends(text),
        [[1.0, 2.0, 3.0], [10.0, 0.5, -0.25], [1.0, -0.5, 0.0]]
    );
    let p = parse(text).unwrap();
    assert_eq!(
        p.blocks.iter().map(|b| b.line).collect::<Vec<_>>(),
        [4, 5, 7]
    );
}

#[test]
fn crlf_line_ends_are_accepted() {
    assert_eq!(
        ends("G1 X1 F1\r\nX2\r\n"),
        [[1.0, 0.0, 0.0], [2.0, 0.0, 0.0]]
    );
}

#[test]
fn windows_cam_files_a_byte_order_mark_and_cr_only_line_ends() {
    let want = [[1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [2.0, 3.0, 0.0]];
    // A UTF-8 byte-order mark, CR-only ends (old Mac), and every end mixed.
    for text in [
        "\u{FEFF}G1 X1 F1\r\nX2\r\nY3\r\n",
        "G1 X1 F1\rX2\rY3\r",
        "\u{FEFF}G1 X1 F1\rX2\nY3\r\n",
    ] {
        assert_eq!(ends(text), want, "{text:?}");
        let p = parse(text).unwrap();
        assert_eq!(
            p.blocks.iter().map(|b| b.line).collect::<Vec<_>>(),
            [1, 2, 3],
            "{text:?}"
        );
    }
    // Lines and columns still count from the first visible character.
    let (line, col, _) = error("\u{FEFF}G1 X1 F1\rX2\rG1 X1 X2\r");
    assert_eq!((line, col), (3, 7));
}

#[test]
fn control_characters_are_named_by_code_point_and_column_never_printed() {
    for (text, line, col, shown) in [
        ("G1 X1 F1\nG1 X2\0\n", 2, 6, "U+0000"),
        ("G1 X1\u{7}F1", 1, 6, "U+0007"),
        ("G1 X1 F1\n\u{1b}[2J", 2, 1, "U+001B"),
        ("G1 X1 F1\u{FEFF}", 1, 9, "U+FEFF"),
        ("G1 X1 F1\u{a0}X2", 1, 9, "U+00A0"),
        ("G0 X1 é", 1, 7, "'é' (U+00E9)"),
    ] {
        let e = parse(text).expect_err(text);
        assert!(matches!(e.kind, ParseErrorKind::UnexpectedChar(_)), "{e}");
        assert_eq!((e.line, e.column), (line, col), "{text:?}: {e}");
        let msg = e.to_string();
        assert_eq!(
            msg,
            format!("{line}:{col}: unexpected character {shown}"),
            "{text:?}"
        );
        assert!(
            msg.chars().all(|c| !c.is_control()),
            "{msg:?} prints a control character"
        );
    }
}

#[test]
fn expressions_nest_to_the_documented_limit() {
    let max = gcode::MAX_EXPRESSION_DEPTH as usize;
    let nested = |n: usize| format!("G0 X{}1{}", "[".repeat(n), "]".repeat(n));
    assert_eq!(ends(&nested(max))[0][0], 1.0);
    let (_, col, kind) = error(&nested(max + 1));
    assert!(matches!(kind, ParseErrorKind::Expression(_)), "{kind}");
    assert_eq!(col as usize, 5 + max, "the bracket one level too deep");
    // Functions, unary signs and indirection count one level each.
    let funcs = format!("G0 X{}1{}", "ABS[".repeat(max), "]".repeat(max));
    assert_eq!(ends(&funcs)[0][0], 1.0);
    let funcs = format!("G0 X{}1{}", "ABS[".repeat(max + 1), "]".repeat(max + 1));
    assert!(parse(&funcs).is_err());
    let signs = format!("G0 X{}[1]", "-".repeat(max - 1));
    assert_eq!(
        ends(&signs)[0][0],
        if max.is_multiple_of(2) { -1.0 } else { 1.0 }
    );
    // Long operator chains are not nesting.
    let chain = format!("G0 X[{}1]", "1+".repeat(1000));
    assert_eq!(ends(&chain)[0][0], 1001.0);
}

#[test]
fn tool_length_offsets_and_cutter_compensation_are_unsupported_codes() {
    for (text, col, code) in [
        ("G43 H1", 1, "G43"),
        ("G0 X1\nG43 Z5 H12", 1, "G43"),
        ("G41 D3", 1, "G41"),
        ("G1 X1 F1 G42 D3", 10, "G42"),
        ("G43.1 Z1", 1, "G43.1"),
        ("G81 X1 Y1 Z-1 R1", 1, "G81"),
    ] {
        let e = parse(text).expect_err(text);
        let ParseErrorKind::Unsupported(what) = &e.kind else {
            panic!("{text}: {e}");
        };
        assert!(what.starts_with(code), "{text}: {e}");
        assert_eq!(e.column, col, "{text}: {e}");
    }
    // H and D with nothing that uses them are stray words, named.
    let (_, col, kind) = error("G1 X1 F1 H2");
    assert_eq!(col, 10);
    assert!(
        matches!(kind, ParseErrorKind::ConflictingArguments(_)),
        "{kind}"
    );
    assert!(blocks("G49\nG40\n").is_empty());
}

#[test]
fn program_stops_at_m2_and_m30() {
    let b = blocks("G1 X1 F10\nM2\nG1 X2 ( never read )\n");
    assert_eq!(b.len(), 2);
    assert_eq!(b[1], BlockKind::ProgramEnd);
    assert_eq!(blocks("M30\nthis is not g-code").len(), 1);
}

#[test]
fn modal_motion_and_distance_modes() {
    let text = "G0 X1 Y1\nX2\nG1 F60 Y3\nG91 X1 Y1\nZ-1\nG90 X0\n";
    assert_eq!(
        ends(text),
        [
            [1.0, 1.0, 0.0],
            [2.0, 1.0, 0.0],
            [2.0, 3.0, 0.0],
            [3.0, 4.0, 0.0],
            [3.0, 4.0, -1.0],
            [0.0, 4.0, -1.0]
        ]
    );
    let b = blocks(text);
    assert!(matches!(b[0], BlockKind::Rapid(_)));
    assert!(matches!(
        b[2],
        BlockKind::Linear(LinearMove {
            feed: Feed::PerMinute(60.0),
            ..
        })
    ));
}

#[test]
fn inches_are_converted_to_millimetres() {
    let b = blocks("G20 G1 X1 Y-2 F10\nG2 X2 Y-1 I0.5 J0.5\nG21 G1 X1\n");
    assert_eq!(
        b[0],
        BlockKind::Linear(LinearMove {
            start: [0.0; 3],
            end: [25.4, -50.8, 0.0],
            feed: Feed::PerMinute(254.0),
            orientation: gcode::Orientation::Fixed,
        })
    );
    let BlockKind::Arc(a) = &b[1] else { panic!() };
    assert!(close(a.centre, [38.1, -38.1, 0.0]));
    assert_eq!(a.end, [50.8, -25.4, 0.0]);
    // The feed stays what it was physically after G21.
    assert!(
        matches!(b[2], BlockKind::Linear(LinearMove { feed: Feed::PerMinute(f), .. }) if f == 254.0)
    );
}

#[test]
fn metamorphic_inch_program_is_the_mm_program_scaled() {
    let prog = "G0 X1 Y2\nG1 Z-0.5 F12\nG2 X3 Y2 I1 J0\nG3 X1 Y2 R1\nG1 X0.5 Y0.25\n";
    let mm = parse(&format!("G21\n{prog}")).unwrap();
    let inch = parse(&format!("G20\n{prog}")).unwrap();
    for (a, b) in mm.end_points().zip(inch.end_points()) {
        for i in 0..3 {
            assert!((a[i] * 25.4 - b[i]).abs() < 1e-12);
        }
    }
}

#[test]
fn metamorphic_incremental_equals_absolute() {
    let abs = ends("G90 G0 X1 Y1\nG1 X4 Y5 F100\nG2 X8 Y5 I2 J0\nG1 Z-2\n");
    let inc = ends("G91 G0 X1 Y1\nG1 X3 Y4 F100\nG2 X4 Y0 I2 J0\nG1 Z-2\n");
    assert_eq!(abs, inc);
}

#[test]
fn centre_format_arcs_in_three_planes() {
    let a = arcs("G17 G2 X10 Y0 I5 J0 F100\nG18 G3 Z10 X10 K5 I0\nG19 G2 Y10 Z10 J5 K0\n");
    assert_eq!(a[0].centre, [5.0, 0.0, 0.0]);
    assert!(a[0].clockwise);
    assert_eq!(a[0].plane, Plane::Xy);
    assert_eq!(a[1].start, [10.0, 0.0, 0.0]);
    assert_eq!(a[1].centre, [10.0, 0.0, 5.0]);
    assert_eq!(a[1].plane, Plane::Zx);
    assert_eq!(a[2].centre, [10.0, 5.0, 10.0]);
}

#[test]
fn radius_format_picks_the_short_or_long_arc_by_sign() {
    // From (0,0) to (10,0) with R5: the centre is the midpoint either way.
    let a = arcs("G2 X10 R5 F100\n");
    assert!(close(a[0].centre, [5.0, 0.0, 0.0]));
    // R ±10 to (10,0): centre on the perpendicular bisector, below for G2 R+.
    let h = (100.0f64 - 25.0).sqrt();
    let a = arcs("G2 X10 R10 F100\nG0 X0\nG2 X10 R-10\nG0 X0\nG3 X10 R10\n");
    assert!(close(a[0].centre, [5.0, -h, 0.0]));
    assert!(close(a[1].centre, [5.0, h, 0.0]));
    assert!(close(a[2].centre, [5.0, h, 0.0]));
}

#[test]
fn full_circles_helices_and_turns() {
    let a = arcs("G0 X1 Y0\nG3 I-1 J0 F100\nG2 X1 Y0 Z-3 I-1 J0 P3\n");
    assert_eq!(a[0].end, a[0].start);
    assert_eq!(a[0].extra_turns, 0);
    assert_eq!(a[1].end, [1.0, 0.0, -3.0]);
    assert_eq!(a[1].extra_turns, 2);
    assert_eq!(a[1].centre, [0.0, 0.0, 0.0]);
}

#[test]
fn absolute_arc_centres_with_g90_1() {
    let a = arcs("G0 X10 Y10\nG90.1 G2 X20 Y10 I15 J10 F100\nG91.1 G2 X30 Y10 I5 J0\n");
    assert_eq!(a[0].centre, [15.0, 10.0, 0.0]);
    assert_eq!(a[1].centre, [25.0, 10.0, 0.0]);
}

#[test]
fn radius_mismatch_follows_linuxcncs_tolerance() {
    // r = 10 vs 10.02: 0.2 % relative but under 0.0283 mm absolute — accepted.
    assert_eq!(arcs("G0 X-10\nG2 X10.02 Y0 I10 J0 F100\n").len(), 1);
    // r = 10 vs 10.05: 0.5 % and 0.05 mm — refused.
    let (line, col, kind) = error("G0 X-10\nG2 X10.05 Y0 I10 J0 F100\n");
    assert_eq!((line, col), (2, 1));
    assert!(matches!(kind, ParseErrorKind::BadArc(_)), "{kind:?}");
    // A big arc may differ by 0.1 %: r = 1000 vs 1000.9 is accepted.
    assert_eq!(arcs("G0 X-1000\nG2 X1000.9 Y0 I1000 J0 F100\n").len(), 1);
    // In inches the absolute tolerance is 0.00283 in: 0.002 in over 1 in accepted.
    assert_eq!(arcs("G20 G0 X-1\nG2 X1.002 Y0 I1 J0 F10\n").len(), 1);
}

#[test]
fn arc_radius_too_small_to_reach_is_refused() {
    let (l, c, k) = error("G2 X10 R4 F100\n");
    assert_eq!((l, c), (1, 8));
    assert!(matches!(k, ParseErrorKind::BadArc(_)));
}

#[test]
fn parameters_are_set_at_the_end_of_the_line() {
    // "#1=5 G1 X#1" reads the old #1 (RS274/NGC); the next line sees 5.
    assert_eq!(
        ends("#1=2\n#1=5 G1 X#1 F1\nX#1\n"),
        [[2.0, 0.0, 0.0], [5.0, 0.0, 0.0]]
    );
}

#[test]
fn expressions_operators_and_functions() {
    let v = |e: &str| ends(&format!("G0 X[{e}]\n"))[0][0];
    assert_eq!(v("1 + 2 * 3"), 7.0);
    assert_eq!(v("2 ** 3 * 2"), 16.0);
    assert_eq!(v("10 - 4 - 3"), 3.0);
    assert_eq!(v("7 MOD 3"), 1.0);
    assert_eq!(v("-7 MOD 3"), 2.0);
    assert_eq!(v("[1 + 2] * 3"), 9.0);
    assert_eq!(v("2 GT 1"), 1.0);
    assert_eq!(v("2 LE 1"), 0.0);
    assert_eq!(v("1 EQ 1 AND 0"), 0.0);
    assert_eq!(v("1 EQ 1 OR 0"), 1.0);
    assert_eq!(v("1 XOR 1"), 0.0);
    assert!((v("SIN[30]") - 0.5).abs() < 1e-15);
    assert!((v("COS[60]") - 0.5).abs() < 1e-15);
    assert!((v("TAN[45]") - 1.0).abs() < 1e-15);
    assert!((v("ASIN[1]") - 90.0).abs() < 1e-12);
    assert!((v("ACOS[0]") - 90.0).abs() < 1e-12);
    assert!((v("ATAN[1]/[-1]") - 135.0).abs() < 1e-12);
    assert_eq!(v("SQRT[16]"), 4.0);
    assert_eq!(v("ABS[-3]"), 3.0);
    assert!((v("EXP[LN[5]]") - 5.0).abs() < 1e-14);
    assert_eq!(v("ROUND[2.5]"), 3.0);
    assert_eq!(v("FIX[-2.5]"), -3.0);
    assert_eq!(v("FUP[2.1]"), 3.0);
    assert_eq!(
        ends("#<Depth>=-2\n#<depth>=[#<DEPTH>*2]\nG0 Z#<depth>\n")[0][2],
        -4.0
    );
    assert_eq!(ends("#3=7\n#2=3\nG0 X##2 Y-#3\n")[0], [7.0, -7.0, 0.0]);
}

#[test]
fn modal_and_aux_blocks() {
    let b = blocks("G64 P0.01 Q0.02\nG61\nG61.1\nT3 M6\nS1000 M3\nM5\nG4 P0.5\nG96 S200 M4\n");
    assert_eq!(
        b[0],
        BlockKind::PathControl(PathControl::Blend {
            path_tolerance: Some(0.01),
            naive_cam_tolerance: Some(0.02)
        })
    );
    assert_eq!(b[1], BlockKind::PathControl(PathControl::ExactPath));
    assert_eq!(b[2], BlockKind::PathControl(PathControl::ExactStop));
    assert_eq!(b[3], BlockKind::ToolChange { tool: 3 });
    assert_eq!(
        b[4],
        BlockKind::Spindle {
            speed: 1000.0,
            rotation: gcode::SpindleRotation::Clockwise,
            constant_surface_speed: false
        }
    );
    assert!(matches!(
        b[5],
        BlockKind::Spindle {
            rotation: gcode::SpindleRotation::Stopped,
            ..
        }
    ));
    assert_eq!(b[6], BlockKind::Dwell { seconds: 0.5 });
    assert!(matches!(
        b[7],
        BlockKind::Spindle {
            constant_surface_speed: true,
            speed: 200.0,
            ..
        }
    ));
    // G64 P in inches is converted.
    assert_eq!(
        blocks("G20 G64 P0.001\n")[0],
        BlockKind::PathControl(PathControl::Blend {
            path_tolerance: Some(0.0254),
            naive_cam_tolerance: None
        })
    );
}

#[test]
fn inverse_time_feed() {
    let b = blocks("G93 G1 X10 F2\nG94 F600 G1 X0\n");
    assert!(matches!(
        b[0],
        BlockKind::Linear(LinearMove {
            feed: Feed::InverseTime(2.0),
            ..
        })
    ));
    assert!(matches!(
        b[1],
        BlockKind::Linear(LinearMove {
            feed: Feed::PerMinute(600.0),
            ..
        })
    ));
    let (l, _, k) = error("G93 G1 X10 F2\nX20\n");
    assert_eq!(l, 2);
    assert!(matches!(k, ParseErrorKind::MissingArgument(_)));
}

#[test]
fn bezier_g5_and_g5_1() {
    let b = blocks("F100\nG5 X10 Y0 I2 J2 P-2 Q2\nG5 X20 Y0 P-2 Q-2\nG5.1 X30 Y0 I5 J5\n");
    let BlockKind::Nurbs(c) = &b[0] else {
        panic!("{b:?}")
    };
    assert_eq!(c.degree, 3);
    assert_eq!(
        c.points,
        [
            [0.0, 0.0, 0.0],
            [2.0, 2.0, 0.0],
            [8.0, 2.0, 0.0],
            [10.0, 0.0, 0.0]
        ]
    );
    assert_eq!(c.knots, [0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0]);
    // The second G5 without I J continues tangentially: I J = −(previous P Q).
    let BlockKind::Nurbs(c) = &b[1] else { panic!() };
    assert_eq!(c.points[1], [12.0, -2.0, 0.0]);
    let BlockKind::Nurbs(c) = &b[2] else { panic!() };
    assert_eq!(c.degree, 2);
    assert_eq!(
        c.points,
        [[20.0, 0.0, 0.0], [25.0, 5.0, 0.0], [30.0, 0.0, 0.0]]
    );
}

#[test]
fn g6_2_with_real_knots_and_start_away_from_the_curve() {
    // The curve starts at (1,0); LinuxCNC feeds there in a straight line first.
    let b = blocks(
        "G1 X0 F100\nG6.2 X1 Y0 R1 K0 P3 Q1\nX2 Y1 R2 K0\nX3 Y0 R1 K0\nG6.2 K0.5\nG6.2 K0.5\nG6.2 K0.5\n",
    );
    assert!(matches!(
        b[1],
        BlockKind::Linear(LinearMove {
            start: [0.0, 0.0, 0.0],
            end: [1.0, 0.0, 0.0],
            ..
        })
    ));
    let BlockKind::Nurbs(c) = &b[2] else { panic!() };
    assert_eq!(c.knots, [0.0, 0.0, 0.0, 0.5, 0.5, 0.5]);
    assert_eq!(c.weights, [1.0, 2.0, 1.0]);
}

#[test]
fn every_error_class_names_line_and_column() {
    use ParseErrorKind as K;
    type Case = (&'static str, u32, u32, fn(&K) -> bool);
    let cases: Vec<Case> = vec![
        ("G1 X1 E5", 1, 7, |k| matches!(k, K::UnknownWord('E'))),
        ("G0 X1\nG7 X2", 2, 1, |k| matches!(k, K::UnknownCode(_))),
        ("M123", 1, 1, |k| matches!(k, K::UnknownCode(_))),
        ("G0 X1 X2", 1, 7, |k| matches!(k, K::DuplicateWord('X'))),
        ("G0 G1 X2 F1", 1, 4, |k| {
            matches!(k, K::ModalGroupConflict { .. })
        }),
        ("G20 G21", 1, 5, |k| {
            matches!(k, K::ModalGroupConflict { .. })
        }),
        ("M3 M5", 1, 4, |k| matches!(k, K::ModalGroupConflict { .. })),
        ("G2 X10 F1", 1, 1, |k| matches!(k, K::MissingArgument(_))),
        ("G2 X10 R5 I5 F1", 1, 8, |k| {
            matches!(k, K::ConflictingArguments(_))
        }),
        ("G1 X10 I5 F1", 1, 8, |k| {
            matches!(k, K::ConflictingArguments(_))
        }),
        ("G17 G2 X10 K5 F1", 1, 12, |k| {
            matches!(k, K::ConflictingArguments(_))
        }),
        ("X10", 1, 1, |k| matches!(k, K::MissingArgument(_))),
        ("G1 X10", 1, 1, |k| matches!(k, K::MissingArgument(_))),
        ("G4", 1, 1, |k| matches!(k, K::MissingArgument(_))),
        ("G0 X1 (open", 1, 7, |k| matches!(k, K::Expression(_))),
        ("G0 X[1/0]", 1, 7, |k| matches!(k, K::Expression(_))),
        ("G0 X[1+2", 1, 5, |k| matches!(k, K::Expression(_))),
        ("G0 X#<nope>", 1, 5, |k| matches!(k, K::Expression(_))),
        ("G0 X[SQRT[-1]]", 1, 6, |k| matches!(k, K::Expression(_))),
        ("G0 X1.2.3", 1, 8, |k| matches!(k, K::UnexpectedChar('.'))),
        ("G0 X-", 1, 6, |k| matches!(k, K::BadNumber)),
        ("G0 X1 é", 1, 7, |k| matches!(k, K::UnexpectedChar('é'))),
        ("O100 sub", 1, 1, |k| matches!(k, K::Unsupported(_))),
        ("G0 U10", 1, 4, |k| matches!(k, K::Unsupported(_))),
        ("G1 X0 F-1", 1, 7, |k| matches!(k, K::BadValue(_))),
        ("G2 X0 Y0 I1 P0 F1", 1, 13, |k| matches!(k, K::BadValue(_))),
        ("G1 F10\nG0 X1\n%", 3, 1, |k| {
            matches!(k, K::UnexpectedChar('%'))
        }),
        // NURBS: knot count (P4 needs 4 trailing knots after 4 points: here the
        // curve ends early with too few points), decreasing knots, weight <= 0.
        (
            "F1\nG6.2 X0 Y0 R1 K0 P3 Q1\nX1 Y1 R1 K2\nX2 Y0 R1 K1\nG6.2 K3\nG6.2 K3\nG6.2 K3",
            4,
            10,
            |k| {
                matches!(
                    k,
                    K::InvalidNurbs(interp_core::NurbsError::DecreasingKnot { .. })
                )
            },
        ),
        ("F1\nG6.2 X0 Y0 R1 K0 P3 Q1\nX1 Y1 R0 K0", 3, 7, |k| {
            matches!(k, K::BadValue(_))
        }),
        (
            "F1\nG6.2 X0 Y0 R1 K0 P7 Q1\nX1 Y1 R1 K0\nX2 Y0 R1 K0\nX3 Y1 R1 K0\nX4 Y0 R1 K0\nX5 Y1 R1 K0\nX6 Y0 R1 K0\nG6.2 K1\nG6.2 K1\nG6.2 K1\nG6.2 K1\nG6.2 K1\nG6.2 K1\nG6.2 K1\n",
            2,
            1,
            |k| {
                matches!(
                    k,
                    K::InvalidNurbs(interp_core::NurbsError::Degree { degree: 6 })
                )
            },
        ),
        (
            "F1\nG6.2 X0 Y0 R1 K0 P3 Q1\nX1 Y1 R1 K0\nX2 Y0 R1",
            4,
            1,
            |k| matches!(k, K::MissingArgument(_)),
        ),
        ("F1\nG6.2 X0 Y0 R1 K0 Q1", 2, 1, |k| {
            matches!(k, K::MissingArgument(_))
        }),
        ("F1\nG6.2 X0 Y0 R1 K0 P3 Q1\nG1 X3", 3, 1, |k| {
            matches!(k, K::NurbsSequence(_))
        }),
        ("F1\nG6.2 X0 Y0 R1 K0 P3 Q1\nX1 Y1 R1 K0", 2, 1, |k| {
            matches!(k, K::NurbsSequence(_))
        }),
        ("F1\nG5.2 X1 Y1 P0\n", 2, 12, |k| {
            matches!(k, K::BadValue(_))
        }),
        ("F1\nG5.2 X1 P1\n", 2, 1, |k| {
            matches!(k, K::MissingArgument(_))
        }),
        ("F1\nG5.3", 2, 1, |k| matches!(k, K::NurbsSequence(_))),
        ("F1\nG5.2 X1 Y1 P1 L4\nX2 Y0 P1\nG5.3", 4, 1, |k| {
            matches!(k, K::NurbsSequence(_))
        }),
        ("F1\nG5.2 X1 Y1 P1\nX2 Y0 P1\nM2", 4, 1, |k| {
            matches!(k, K::NurbsSequence(_))
        }),
        // Five-axis: I J K is a tool vector only under G43.5; no TCP change
        // inside a curve; no A B C on G5.2, G5, arcs, under G43.5, on a
        // knot line, or incremental while unknown; H as an offset number.
        (
            "G1 X1 J1 F100",
            1,
            7,
            |k| matches!(k, K::ConflictingArguments(m) if m.contains("G43.5")),
        ),
        (
            "G0 X1 K2",
            1,
            7,
            |k| matches!(k, K::ConflictingArguments(m) if m.contains("G43.5")),
        ),
        (
            "F1\nG6.2 X0 Y0 R1 K0 P3\nG43.4\n",
            3,
            1,
            |k| matches!(k, K::NurbsSequence(m) if m.contains("G43.4 inside")),
        ),
        (
            "F1\nG5.2 X1 Y1 P1\nX2 Y0 P1 C5\n",
            3,
            10,
            |k| matches!(k, K::Unsupported(m) if m.contains("C on G5.2")),
        ),
        ("G5 X1 Y1 I1 J0 P1 Q0 A5 F1", 1, 22, |k| {
            matches!(k, K::Unsupported(_))
        }),
        (
            "G2 X1 Y1 I1 B10 F1",
            1,
            13,
            |k| matches!(k, K::Unsupported(m) if m.contains("B on G2")),
        ),
        (
            "G43.5\nG1 X1 A10 F1",
            2,
            7,
            |k| matches!(k, K::ConflictingArguments(m) if m.contains("under G43.5")),
        ),
        (
            "G43.5\nG1 X1 I0 J0 K0 F1",
            2,
            7,
            |k| matches!(k, K::BadValue(m) if m.contains("zero")),
        ),
        ("G43.4 H-1", 1, 7, |k| matches!(k, K::BadValue(_))),
        ("G43.4 H1.5", 1, 7, |k| matches!(k, K::BadValue(_))),
        ("G49 H1", 1, 5, |k| matches!(k, K::ConflictingArguments(_))),
        ("G43.4 G49", 1, 7, |k| {
            matches!(k, K::ModalGroupConflict { .. })
        }),
        (
            "G43.5\nG49\nG91 G1 A5 F1",
            3,
            8,
            |k| matches!(k, K::ConflictingArguments(m) if m.contains("unknown")),
        ),
        (
            "F1\nG6.2 X0 Y0 R1 K0 P3\nX1 Y1 R1 K0\nX2 Y0 R1 K0\nG6.2 K1 A5",
            5,
            9,
            |k| matches!(k, K::ConflictingArguments(m) if m.contains("without a control point")),
        ),
        (
            "G43.5\nG49\nF1\nG6.2 X0 Y0 R1 K0 P3\nX1 Y1 R1 K0 A5",
            5,
            13,
            |k| matches!(k, K::ConflictingArguments(m) if m.contains("every control point")),
        ),
        // G6.2 tool vectors U V W: under G43.5 only, on every control
        // point or none, not zero, finite, not on a knot line; U V W as
        // axes elsewhere.
        (
            "G43.5\nF1\nG6.2 P3 X0 Y0 R1 K0 U0 V0 W1\nX1 Y1 R1 K0\n",
            4,
            10,
            |k| matches!(k, K::MissingArgument(m) if m.contains("U V W") && m.contains("line 3")),
        ),
        (
            "G43.5\nF1\nG6.2 P3 X0 Y0 R1 K0\nX1 Y1 R1 K0 W1\n",
            4,
            13,
            |k| matches!(k, K::ConflictingArguments(m) if m.contains("every point or on none")),
        ),
        (
            "G43.5\nF1\nG6.2 P3 X0 Y0 R1 K0 U0 V0 W0\n",
            3,
            21,
            |k| matches!(k, K::BadValue(m) if m.contains("zero")),
        ),
        (
            "G43.5\nF1\nG6.2 P3 X0 Y0 R1 K0 U[10**400] W1\n",
            3,
            21,
            |k| matches!(k, K::BadValue(m) if m.contains("U word is not finite")),
        ),
        (
            "F1\nG6.2 P3 X0 Y0 R1 K0 U1\n",
            2,
            21,
            |k| matches!(k, K::ConflictingArguments(m) if m.contains("outside G43.5")),
        ),
        (
            "G43.5\nF1\nG6.2 P3 X0 Y0 R1 K0 W1\nX1 Y1 R1 K0 W1\nX2 Y0 R1 K0 W1\nG6.2 K1 V1",
            6,
            9,
            |k| matches!(k, K::ConflictingArguments(m) if m.contains("without a control point")),
        ),
        (
            "G1 X1 U1 F1",
            1,
            7,
            |k| matches!(k, K::Unsupported(m) if m.contains("axis word 'U'")),
        ),
        ("G80 A1", 1, 5, |k| matches!(k, K::ConflictingArguments(_))),
        ("A1", 1, 1, |k| matches!(k, K::MissingArgument(_))),
        (
            "G93 G1 A1",
            1,
            1,
            |k| matches!(k, K::MissingArgument(m) if m.contains("inverse time")),
        ),
    ];
    for (text, line, col, check) in cases {
        let e = parse(text).expect_err(text);
        assert!(check(&e.kind), "{text:?}: {e}");
        assert_eq!((e.line, e.column), (line, col), "{text:?}: {e}");
        assert!(e.to_string().starts_with(&format!("{line}:{col}: ")), "{e}");
    }
}

#[test]
fn error_display_is_line_colon_column_colon_message() {
    let e = parse("G0 X1\nG1 X1 X2 F1\n").unwrap_err();
    assert_eq!(e.to_string(), "2:7: duplicate word 'X' on one line");
}

#[test]
fn hostile_inputs_are_errors_not_panics() {
    let deep = format!("G0 X{}1{}", "[".repeat(10_000), "]".repeat(10_000));
    assert!(matches!(
        parse(&deep).unwrap_err().kind,
        ParseErrorKind::Expression(_)
    ));
    let minus = format!("G0 X{}1", "-".repeat(10_000));
    assert!(parse(&minus).is_err());
    assert!(parse("G0 X1e400").is_err());
    assert!(parse("G0 X[10**400]").is_err());
    assert!(parse("#99999=1").is_err());
    assert!(parse("G0 X#-1").is_err());
    assert!(parse("G99999999999999999999").is_err());
    assert_eq!(parse("").unwrap(), Program::default());
}

#[test]
fn numbers_read_exactly_as_rusts_float_parser() {
    // The fast path and the fallback must agree bit for bit.
    for s in [
        "0.1",
        "1.",
        ".5",
        "123456.789",
        "-0.000001",
        "9007199254740991",
        "9007199254740993",
        "0.30000000000000004",
        "1.0000000000000000000000001",
        "123456789012345678901234567890",
        "-.75",
        "+2.5",
        "00001.2500",
        "0.0000000000000000000000123",
    ] {
        let want: f64 = s.parse().unwrap();
        let got = ends(&format!("G0 X{s}"))[0][0];
        assert_eq!(got.to_bits(), want.to_bits(), "{s}");
    }
}

/// Rotary axes, tool-centre-point control and the tool vector as the
/// program representation carries them (docs/gcode.md, "Five-axis").
#[test]
fn five_axis_moves_carry_rotary_positions_and_tool_vectors() {
    use gcode::{Orientation, ToolControl};
    let text = "G21 G90 F600
G1 X10 A30            ; TCP off: A moves as a plain axis
G1 X20 A30            ; A where it is: a three-axis move
G20 G91 G1 A5 C-10    ; incremental, degrees whatever the units
G21 G90
G43.4 H2              ; TCP with rotary positions
G1 X1 Y2 Z3 A10 C20
G43.4 H2              ; no change, no block
G43.5 H2
G1 X1 I0 J0 K1        ; the first vector (before it: the machine's)
G1 X2                 ; keeps it
G1 X3 I1              ; J, K omitted: 0
I0 J1 K0              ; modal G1: the tool turns, the tip stays
G49
G1 X4 A0 B0 C0        ; the rotary axes were steered by G43.5: unknown until set
G93 G1 X5 A90 F2
";
    let b = blocks(text);
    let s = |v: [f64; 3]| v.map(Some);
    let orientation = |k: &BlockKind| k.orientation().copied();
    assert_eq!(
        orientation(&b[0]),
        Some(Orientation::Axes {
            start: s([0.0; 3]),
            end: s([30.0, 0.0, 0.0])
        })
    );
    assert_eq!(orientation(&b[1]), Some(Orientation::Fixed));
    assert_eq!(
        orientation(&b[2]),
        Some(Orientation::Axes {
            start: s([30.0, 0.0, 0.0]),
            end: s([35.0, 0.0, -10.0])
        })
    );
    assert_eq!(
        b[3],
        BlockKind::ToolControl(ToolControl::RotaryAngles { offset: Some(2) })
    );
    assert_eq!(
        orientation(&b[4]),
        Some(Orientation::TcpRotary {
            start: s([35.0, 0.0, -10.0]),
            end: s([10.0, 0.0, 20.0])
        })
    );
    assert_eq!(
        b[5],
        BlockKind::ToolControl(ToolControl::ToolVector { offset: Some(2) })
    );
    assert_eq!(
        orientation(&b[6]),
        Some(Orientation::TcpVector {
            start: None,
            end: Some([0.0, 0.0, 1.0])
        })
    );
    assert_eq!(
        orientation(&b[7]),
        Some(Orientation::TcpVector {
            start: Some([0.0, 0.0, 1.0]),
            end: Some([0.0, 0.0, 1.0])
        })
    );
    assert_eq!(
        orientation(&b[8]),
        Some(Orientation::TcpVector {
            start: Some([0.0, 0.0, 1.0]),
            end: Some([1.0, 0.0, 0.0])
        })
    );
    let BlockKind::Linear(m) = &b[9] else {
        panic!("{:?}", b[9])
    };
    assert_eq!((m.start, m.end), ([3.0, 2.0, 3.0], [3.0, 2.0, 3.0]));
    assert_eq!(
        m.orientation,
        Orientation::TcpVector {
            start: Some([1.0, 0.0, 0.0]),
            end: Some([0.0, 1.0, 0.0])
        }
    );
    assert_eq!(b[10], BlockKind::ToolControl(ToolControl::Off));
    assert_eq!(
        orientation(&b[11]),
        Some(Orientation::Axes {
            start: [None; 3],
            end: s([0.0; 3])
        })
    );
    let BlockKind::Linear(m) = &b[12] else {
        panic!("{:?}", b[12])
    };
    assert_eq!(m.feed, Feed::InverseTime(2.0));
    assert_eq!(
        m.orientation,
        Orientation::Axes {
            start: s([0.0; 3]),
            end: s([90.0, 0.0, 0.0])
        }
    );
    assert_eq!(b.len(), 13);
    // In G93 a tool turn alone needs its F too.
    assert!(matches!(
        parse("G43.5\nG93 G1 X1 I1 F2\nI0 J1").unwrap_err().kind,
        ParseErrorKind::MissingArgument(_)
    ));
    // Programs without rotary words or TCP read as before.
    assert!(
        blocks("G0 X1\nG1 Y2 F100\nG2 X2 Y3 I1 J0\n")
            .iter()
            .all(|k| k.orientation() == Some(&Orientation::Fixed))
    );
}

/// G6.2 control points carry A B C as NURBS coordinates; the start of the
/// machine's rotary axes comes from `parse_from_axes`.
#[test]
fn g6_2_rotary_coordinates_and_the_rotary_start() {
    use gcode::{Orientation, parse_from_axes};
    let text = "G6.2 P3 X0 Y0 A10 R1 K0 F100
X10 Y10 A45 R2 K0
X20 Y0 R1 K0
G6.2 K1
G6.2 K1
G6.2 K1
";
    let p = parse_from_axes(text, [0.0, 0.0, 0.0, 10.0, 0.0, 5.0]).unwrap();
    let [BlockKind::Nurbs(n)] = &p.blocks.iter().map(|b| b.kind.clone()).collect::<Vec<_>>()[..]
    else {
        panic!("{p:?}")
    };
    let r = |a: f64| [Some(a), Some(0.0), Some(5.0)];
    // A missing word on a point is the curve start's value, as for X Y Z.
    assert_eq!(n.rotary, vec![r(10.0), r(45.0), r(10.0)]);
    assert_eq!(
        n.orientation,
        Orientation::Axes {
            start: r(10.0),
            end: r(10.0)
        }
    );
    // From A = 0 the curve's first point is reached by a straight G1 first (LinuxCNC's rule).
    let p = parse(text).unwrap();
    let BlockKind::Linear(m) = &p.blocks[0].kind else {
        panic!("{p:?}")
    };
    assert_eq!((m.start, m.end), ([0.0; 3], [0.0; 3]));
    assert_eq!(
        m.orientation,
        Orientation::Axes {
            start: [Some(0.0); 3],
            end: [Some(10.0), Some(0.0), Some(0.0)]
        }
    );
    // A curve whose rotary coordinates do not change is a three-axis curve.
    let p = parse(
        "G6.2 P3 X0 Y0 R1 K0 F100\nX10 Y10 A0 R2 K0\nX20 Y0 R1 K0\nG6.2 K1\nG6.2 K1\nG6.2 K1\n",
    )
    .unwrap();
    let BlockKind::Nurbs(n) = &p.blocks[0].kind else {
        panic!("{p:?}")
    };
    assert!(n.rotary.is_empty() && n.orientation.is_fixed());
}

/// The five-axis example of docs/gcode.md reads as it says.
#[test]
fn the_documented_five_axis_example() {
    use gcode::{Orientation, ToolControl};
    let text = "G21 G90 G94 F1200
G0 X0 Y0 Z50 A0 C0        ; rotary positioning (TCP off)
G43.4 H1                  ; tool tip in the workpiece frame, A C given
G1 X10 Y0 Z5 A30 C0
G1 X10 Y10 Z5 A30 C90
G43.5 H1                  ; tool tip with a tool vector
G1 X20 Y10 Z5 I0.5 J0 K0.866
G49
G6.2 P3 X20 Y10 Z5 A0 C0 R1 K0   ; rotary coordinates on NURBS control points
     X30 Y20 Z5 A15 C45 R1 K0
     X40 Y10 Z5 A30 C90 R1 K0
G6.2 K1
G6.2 K1
G6.2 K1
M2
";
    let b = blocks(text);
    let kinds: Vec<&str> = b
        .iter()
        .map(|k| match k {
            BlockKind::Rapid(m) if m.orientation.is_fixed() => "G0",
            BlockKind::Linear(m) => match m.orientation {
                Orientation::TcpRotary { .. } => "G1 tcp-rotary",
                Orientation::TcpVector { .. } => "G1 tcp-vector",
                Orientation::Axes { .. } => "G1 axes",
                Orientation::Fixed => "G1",
            },
            BlockKind::Nurbs(n) if matches!(n.orientation, Orientation::Axes { .. }) => "G6.2 axes",
            BlockKind::ToolControl(ToolControl::RotaryAngles { offset: Some(1) }) => "G43.4 H1",
            BlockKind::ToolControl(ToolControl::ToolVector { offset: Some(1) }) => "G43.5 H1",
            BlockKind::ToolControl(ToolControl::Off) => "G49",
            BlockKind::ProgramEnd => "M2",
            other => panic!("{other:?}"),
        })
        .collect();
    // After G43.5 the rotary axes are unknown, so the curve's first point
    // (A0 C0) is reached by LinuxCNC's straight move first.
    assert_eq!(
        kinds,
        [
            "G0",
            "G43.4 H1",
            "G1 tcp-rotary",
            "G1 tcp-rotary",
            "G43.5 H1",
            "G1 tcp-vector",
            "G49",
            "G1 axes",
            "G6.2 axes",
            "M2"
        ]
    );
    let BlockKind::Nurbs(n) = &b[8] else { panic!() };
    assert_eq!(n.rotary[1], [Some(15.0), None, Some(45.0)]);
}
