//! NURBS programs through the interpolator: LinuxCNC's own G5.2 examples,
//! whose first point repeats the start (C'(0) = 0), run to their end; and one
//! curve written in the three NURBS spellings the parser reads gives the same
//! setpoints.

mod common;

use common::{blocks, run, v3};
use interp_core::path::Block;
use interp_core::{Curve, InterpConfig, Setpoint};

const TRIDENT: &str = include_str!("programs/trident-xy-yz-zx.ngc");
const STELLA: &str = include_str!("programs/curva_stella-q1.ngc");

/// Setpoints of the three spellings agree within this, mm (the issue's bound).
const SAME_SETPOINT_TOL: f64 = 1e-9;

#[test]
fn linuxcncs_g5_2_examples_whose_first_point_repeats_the_start_run_to_the_end() {
    for (name, text) in [("trident", TRIDENT), ("stella", STELLA)] {
        let blocks = blocks(text);
        let sps = run(&blocks);
        let last = sps.last().unwrap();
        assert_eq!(
            v3(&last.axes),
            blocks.last().unwrap().path.end_point(),
            "{name}"
        );
        // No curve crawls away from its stationary start: each takes at most
        // twice its length at the programmed feed, plus a second to speed up
        // and slow down.
        let period = InterpConfig::default().period;
        for b in blocks
            .iter()
            .filter(|b| matches!(b.path, interp_core::Path::Nurbs(_)))
        {
            let ticks = sps.iter().filter(|s| s.block_id == b.id).count();
            let bound = 2.0 * b.path.length() / b.feed + 1.0;
            assert!(
                ticks as f64 * period <= bound,
                "{name} block {}: {} s for {} mm at {} mm/s",
                b.id,
                ticks as f64 * period,
                b.path.length(),
                b.feed
            );
        }
    }
}

/// One rational cubic with a uniform clamped knot vector, written three ways.
/// Points and weights are short decimals every spelling carries exactly.
const POINTS: [[f64; 2]; 7] = [
    [0.0, 0.0],
    [10.0, 5.0],
    [20.0, -3.0],
    [28.5, 6.25],
    [35.0, 12.0],
    [48.0, 4.5],
    [55.0, 10.0],
];
const WEIGHTS: [f64; 7] = [1.5, 0.8, 1.25, 1.0, 2.0, 0.75, 1.0];

/// LinuxCNC's G6.2: P order, Q, X Y R K on the first line, then a knot per
/// line, the last `order` alone (integer knots 0 0 0 0 1 2 3 4 4 4 4).
fn linuxcnc_g6_2() -> String {
    let knots = [0, 0, 0, 0, 1, 2, 3, 4, 4, 4, 4];
    let mut s = format!(
        "G21 G90 G17 G94\nG0 X{} Y{}\nG6.2 P4 Q1 X{} Y{} R{} K{} F600\n",
        POINTS[0][0], POINTS[0][1], POINTS[0][0], POINTS[0][1], WEIGHTS[0], knots[0]
    );
    for i in 1..7 {
        s += &format!(
            "X{} Y{} R{} K{}\n",
            POINTS[i][0], POINTS[i][1], WEIGHTS[i], knots[i]
        );
    }
    for k in &knots[7..] {
        s += &format!("G6.2 K{k}\n");
    }
    s + "M2\n"
}

/// Fanuc's G06.2: no Q, the knot first on each point line, the last `order`
/// knots alone, knots not normalised (× 12.5), `;` block ends.
fn fanuc_g06_2() -> String {
    let knots = [0.0, 0.0, 0.0, 0.0, 12.5, 25.0, 37.5, 50.0, 50.0, 50.0, 50.0];
    let mut s = format!(
        "%\nO1000\nG90 G17 G21 G94;\nG00 X{} Y{};\nG06.2 P4 K{:.1} X{} Y{} R{} F600;\n",
        POINTS[0][0], POINTS[0][1], knots[0], POINTS[0][0], POINTS[0][1], WEIGHTS[0]
    );
    for i in 1..7 {
        s += &format!(
            "K{:.1} X{} Y{} R{};\n",
            knots[i], POINTS[i][0], POINTS[i][1], WEIGHTS[i]
        );
    }
    for k in &knots[7..] {
        s += &format!("K{k:.1};\n");
    }
    s + "M30;\n%\n"
}

/// LinuxCNC's G5.2: the current point is the first control point (its
/// weight from a first line with P and no coordinates), order L, LinuxCNC's
/// knot vector (the same uniform clamped one).
fn linuxcnc_g5_2() -> String {
    let mut s = format!(
        "G21 G90 G17 G94\nG0 X{} Y{}\nG1 F600\nG5.2 P{} L4\n",
        POINTS[0][0], POINTS[0][1], WEIGHTS[0]
    );
    for i in 1..7 {
        s += &format!("X{} Y{} P{}\n", POINTS[i][0], POINTS[i][1], WEIGHTS[i]);
    }
    s + "G5.3\nM2\n"
}

#[test]
fn one_curve_in_three_spellings_gives_the_same_setpoints() {
    let runs: Vec<(&str, Vec<Block>)> = [
        ("G6.2", linuxcnc_g6_2()),
        ("G06.2", fanuc_g06_2()),
        ("G5.2", linuxcnc_g5_2()),
    ]
    .into_iter()
    .map(|(name, text)| {
        let b: Vec<Block> = blocks(&text)
            .into_iter()
            .filter(|b| matches!(b.path, interp_core::Path::Nurbs(_)))
            .collect();
        assert_eq!(b.len(), 1, "{name}: {text}");
        (name, b)
    })
    .collect();
    // The same curve: points, weights (as homogeneous control points) and the
    // knots up to their scale.
    let curve = |b: &Block| match b.path {
        interp_core::Path::Nurbs(n) => n,
        _ => unreachable!(),
    };
    let reference = curve(&runs[0].1[0]);
    for (name, b) in &runs[1..] {
        let n = curve(&b[0]);
        assert_eq!(n.control_count(), 7, "{name}");
        for i in 0..7 {
            assert_eq!(
                n.control_point(i),
                reference.control_point(i),
                "{name} point {i}"
            );
            assert_eq!(n.weight(i), reference.weight(i), "{name} weight {i}");
        }
        let scale = n.u_end() / reference.u_end();
        for (k, r) in n.knots().iter().zip(reference.knots()) {
            assert_eq!(*k, r * scale, "{name} knots");
        }
    }
    let sps: Vec<Vec<Setpoint>> = runs.iter().map(|(_, b)| run(b)).collect();
    for (i, (name, _)) in runs.iter().enumerate().skip(1) {
        assert_eq!(sps[i].len(), sps[0].len(), "{name}: tick count");
        for (a, b) in sps[0].iter().zip(&sps[i]) {
            let d = (v3(&a.axes) - v3(&b.axes)).norm();
            assert!(
                d <= SAME_SETPOINT_TOL,
                "{name}: seq {} differs from G6.2 by {d} mm",
                a.seq
            );
        }
    }
}

/// docs/gcode.md's "NURBS forms, minimal" block, read from the doc: every
/// paragraph parses alone into the curves its comment names (degree, control
/// points, weights), so the documented forms cannot drift from the parser.
#[test]
fn every_documented_minimal_nurbs_form_reads_as_its_comment_says() {
    const DOC: &str = include_str!("../../docs/gcode.md");
    let section = &DOC[DOC.find("### NURBS forms, minimal").expect("section")..];
    let fence = "```gcode\n";
    let code = &section[section.find(fence).expect("code block") + fence.len()..];
    let code = &code[..code.find("```").expect("end of the code block")];
    let quadratic = (2, vec![[0.0, 0.0], [10.0, 10.0], [20.0, 0.0]], vec![1.0; 3]);
    type Curve = (usize, Vec<[f64; 2]>, Vec<f64>);
    let expected: [Vec<Curve>; 6] = [
        vec![quadratic.clone()],
        vec![(
            3,
            vec![[0.0, 0.0], [10.0, 10.0], [20.0, 10.0], [30.0, 0.0]],
            vec![2.0, 1.0, 1.0, 1.0],
        )],
        vec![quadratic.clone()],
        vec![quadratic.clone()],
        vec![quadratic],
        vec![
            (
                3,
                vec![[0.0, 0.0], [5.0, 10.0], [15.0, 10.0], [20.0, 0.0]],
                vec![1.0; 4],
            ),
            (
                3,
                vec![[20.0, 0.0], [25.0, -10.0], [35.0, -10.0], [40.0, 0.0]],
                vec![1.0; 4],
            ),
        ],
    ];
    let forms: Vec<&str> = code.split("\n\n").collect();
    assert_eq!(forms.len(), expected.len(), "paragraphs of the block");
    for (text, want) in forms.iter().zip(&expected) {
        let got: Vec<Curve> = blocks(text)
            .into_iter()
            .filter_map(|b| match b.path {
                interp_core::Path::Nurbs(n) => Some(n),
                _ => None,
            })
            .map(|n| {
                let pts = (0..n.control_count())
                    .map(|i| {
                        let p = n.control_point(i);
                        [p[0], p[1]]
                    })
                    .collect();
                let w = (0..n.control_count()).map(|i| n.weight(i)).collect();
                (n.degree(), pts, w)
            })
            .collect();
        assert_eq!(&got, want, "{text}");
    }
}
