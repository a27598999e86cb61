//! NURBS programs: G6.2 curves carry exactly the file's control points,
//! weights and knots; G5.2 curves get LinuxCNC's knot vector; the conversion
//! cuts long curves into pieces that are the same curve.

use gcode::{BlockKind, CoreOptions, NurbsMove, Plane, parse};
use interp_core::Curve;
use interp_core::path::Path;
use interp_core::samples::butterfly::{BUTTERFLY_DEGREE, BUTTERFLY_POINTS};

const FARFALLA: &str = include_str!("programs/curva_farfalla-q1.ngc");
const MAZATROL: &str = include_str!("programs/curva_mazatrol-q1-xy-yz-zx.ngc");
const TRIDENT: &str = include_str!("programs/trident-xy-yz-zx.ngc");
const STELLA: &str = include_str!("programs/curva_stella-q1.ngc");

fn nurbs(text: &str) -> Vec<NurbsMove> {
    parse(text)
        .unwrap()
        .blocks
        .into_iter()
        .filter_map(|b| match b.kind {
            BlockKind::Nurbs(n) => Some(n),
            _ => None,
        })
        .collect()
}

/// An independent reading of a G6.2 program's curves: a plain scan of the
/// lines between `G6.2 ... P` and the run of `order` equal trailing knots,
/// taking X/Y/Z/R/K as written (no parameters, absolute mm), in the plane's
/// order. Returns (in-plane coordinates, weights, knots) per curve.
type Scanned = (Vec<[f64; 2]>, Vec<f64>, Vec<f64>);
fn scan_g6(text: &str) -> Vec<Scanned> {
    let mut out = Vec::new();
    let mut cur: Option<(usize, Scanned)> = None;
    let mut axes = ('X', 'Y');
    for line in text.lines() {
        let code = line.split(';').next().unwrap_or("");
        let code: String = code.split('(').next().unwrap_or("").to_uppercase();
        if code.contains("G17") {
            axes = ('X', 'Y');
        }
        if code.contains("G18") {
            axes = ('Z', 'X');
        }
        if code.contains("G19") {
            axes = ('Y', 'Z');
        }
        let word = |c: char| -> Option<f64> {
            let i = code.find(c)?;
            let rest = &code[i + 1..];
            let end = rest
                .find(|ch: char| !(ch.is_ascii_digit() || ch == '.' || ch == '-'))
                .unwrap_or(rest.len());
            rest[..end].parse().ok()
        };
        if code.contains("G6.2") && cur.is_none() {
            cur = Some((word('P').unwrap() as usize, (vec![], vec![], vec![])));
        }
        let Some((order, (pts, ws, ks))) = cur.as_mut() else {
            continue;
        };
        let Some(k) = word('K') else { continue };
        ks.push(k);
        if let (Some(a), Some(b)) = (word(axes.0), word(axes.1)) {
            pts.push([a, b]);
            ws.push(word('R').unwrap());
        }
        let n = ks.len();
        if n > *order && ks[n - 1] == ks[n - *order] {
            out.push(cur.take().unwrap().1);
        }
    }
    out
}

fn check_against_scan(text: &str) -> usize {
    let ours = nurbs(text);
    let scanned = scan_g6(text);
    assert_eq!(ours.len(), scanned.len());
    for (n, (pts, ws, ks)) in ours.iter().zip(&scanned) {
        let (a, b, _) = n.plane.axes();
        let ours_2d: Vec<[f64; 2]> = n.points.iter().map(|p| [p[a], p[b]]).collect();
        assert_eq!(&ours_2d, pts);
        assert_eq!(&n.weights, ws);
        assert_eq!(&n.knots, ks);
        assert_eq!(n.knots.len(), n.points.len() + n.degree + 1);
    }
    ours.len()
}

#[test]
fn butterfly_has_the_files_points_weights_and_knots() {
    let curves = nurbs(FARFALLA);
    assert_eq!(curves.len(), 1);
    let c = &curves[0];
    assert_eq!(c.degree, BUTTERFLY_DEGREE);
    assert_eq!(c.plane, Plane::Xy);
    assert_eq!(c.first_line, 13);
    assert_eq!(c.points.len(), 51);
    for (p, q) in c.points.iter().zip(BUTTERFLY_POINTS.iter()) {
        // interp-core's sample keeps z = 0; the program cuts at Z-1.
        assert_eq!([p[0], p[1]], [q[0], q[1]]);
        assert_eq!(p[2], -1.0);
    }
    let mut knots = vec![0.0; 5];
    knots.extend((1..=46).map(f64::from));
    knots.extend([47.0; 5]);
    assert_eq!(c.knots, knots);
    assert_eq!(c.weights[3], 1.2);
    assert_eq!(c.weights[14], 5.0);
    assert_eq!(c.feed, gcode::Feed::PerMinute(290.0));
    assert_eq!(check_against_scan(FARFALLA), 1);
}

/// A NURBS as Fanuc documents G06.2 and CAM posts write it: no Q, the knot
/// first on every control-point line, the last `order` knots alone on their
/// own lines, knots not normalised, all three axes, `;` block ends.
const FANUC: &str = "%
O1000 (FANUC NURBS)
G90 G17 G21 G94;
G00 X6.5238 Y2.3909 Z4.2421;
G06.2 P4 K0.0 X6.5238 Y2.3909 Z4.2421 R1.0 F3000;
K0.0 X8.1200 Y4.0300 Z4.0000 R0.8;
K0.0 X10.0000 Y4.5000 Z3.5000 R1.2;
K0.0 X12.2000 Y3.1000 Z3.2500 R1.0;
K12.5 X14.0000 Y1.0000 Z3.0000 R0.9;
K25.0 X16.5000 Y0.5000 Z3.0000 R1.0;
K37.5;
K37.5;
K37.5;
K37.5;
G01 X20.0 F3000;
M30;
%
";

#[test]
fn fanuc_g06_2_without_q_reads_as_written() {
    let text = FANUC;
    let curves = nurbs(text);
    assert_eq!(curves.len(), 1);
    let c = &curves[0];
    assert_eq!(c.degree, 3);
    assert_eq!(c.points.len(), 6);
    assert_eq!(c.points[0], [6.5238, 2.3909, 4.2421]);
    assert_eq!(c.points[5], [16.5, 0.5, 3.0]);
    assert_eq!(c.weights, [1.0, 0.8, 1.2, 1.0, 0.9, 1.0]);
    assert_eq!(
        c.knots,
        [0.0, 0.0, 0.0, 0.0, 12.5, 25.0, 37.5, 37.5, 37.5, 37.5]
    );
    assert_eq!(c.feed, gcode::Feed::PerMinute(3000.0));
    // The curve starts where the G00 left the tool: no connecting move, and
    // the G01 after it starts at its end.
    let p = parse(text).unwrap();
    let kinds: Vec<_> = p.blocks.iter().map(|b| &b.kind).collect();
    assert!(matches!(kinds[0], BlockKind::Rapid(_)));
    assert!(matches!(kinds[1], BlockKind::Nurbs(_)));
    let BlockKind::Linear(l) = kinds[2] else {
        panic!("{:?}", kinds[2]);
    };
    assert_eq!(l.start, [16.5, 0.5, 3.0]);
    // Q, where a LinuxCNC program gives it, changes nothing.
    let with_q = text.replace("G06.2 P4 K0.0", "G06.2 P4 Q2 K0.0");
    assert_eq!(parse(&with_q).unwrap(), p);
    // A program-number line is all a program number may be.
    assert!(parse("O1000 G1 X1 F1").is_err());
    assert!(parse("O100 sub").is_err());
    // And it converts into interp-core blocks (the same curve, exactly).
    let core = p.to_core_blocks(&CoreOptions::default()).unwrap();
    let Path::Nurbs(n) = core[1].path else {
        panic!("{:?}", core[1].path);
    };
    assert_eq!(n.knots(), c.knots.as_slice());
    assert_eq!(n.end_point(), interp_core::Vec3::new(16.5, 0.5, 3.0));
}

#[test]
fn mazatrol_curves_in_three_planes_match_the_file() {
    assert_eq!(check_against_scan(MAZATROL), 3);
    let curves = nurbs(MAZATROL);
    assert_eq!(
        curves.iter().map(|c| c.plane).collect::<Vec<_>>(),
        [Plane::Xy, Plane::Yz, Plane::Zx]
    );
    // YZ curve: X stays where the program put it (X0 after `G1 X0`).
    assert!(curves[1].points.iter().all(|p| p[0] == 0.0));
    assert_eq!(curves[1].points[1], [0.0, 10.0, 100.0]);
    // ZX curve: first axis Z, second X.
    assert_eq!(curves[2].points[1], [100.0, 0.0, 10.0]);
    // F#10 with #10=290.
    assert!(
        curves
            .iter()
            .all(|c| c.feed == gcode::Feed::PerMinute(290.0))
    );
}

#[test]
fn g5_2_uses_linuxcncs_knot_vector_and_starts_at_the_current_point() {
    let curves = nurbs(TRIDENT);
    assert_eq!(curves.len(), 3);
    for c in &curves {
        // "G5.2 P1 L4": order 4, the current point with weight P1, then 7 points.
        assert_eq!(c.degree, 3);
        assert_eq!(c.points.len(), 8);
        // n = 7, k = 4: 0 0 0 0 1 2 3 4 5 5 5 5 (nurbs_G5_knot_vector_creator).
        assert_eq!(
            c.knots,
            [0.0, 0.0, 0.0, 0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 5.0, 5.0, 5.0]
        );
        assert_eq!(c.weights, [1.0; 8]);
    }
    assert_eq!(curves[0].points[0], [10.0, 0.0, 0.0]);
    assert_eq!(curves[0].points[2], [20.0, 20.0, 0.0]);
    assert_eq!(curves[1].plane, Plane::Yz);
    assert_eq!(curves[1].points[2], [0.0, 20.0, 20.0]);
    assert_eq!(curves[2].plane, Plane::Zx);
    assert_eq!(curves[2].points[3], [8.0, 0.0, 12.0]);
}

#[test]
fn g5_2_default_order_is_three_and_stella_opens_with_g2_2() {
    let curves = nurbs(STELLA);
    assert_eq!(curves.len(), 1);
    let c = &curves[0];
    assert_eq!(c.degree, 2);
    // #1=1 and "P1" without L: order 3; start point + 16 programmed points.
    assert_eq!(c.points.len(), 17);
    assert_eq!(c.knots, gcode::g5_2_knots(17, 3));
    assert_eq!(&c.knots[..4], [0.0, 0.0, 0.0, 1.0]);
    assert_eq!(&c.knots[c.knots.len() - 4..], [14.0, 15.0, 15.0, 15.0]);
}

#[test]
fn g5_2_knots_follow_linuxcncs_formula() {
    assert_eq!(gcode::g5_2_knots(3, 3), [0.0, 0.0, 0.0, 1.0, 1.0, 1.0]);
    assert_eq!(
        gcode::g5_2_knots(5, 3),
        [0.0, 0.0, 0.0, 1.0, 2.0, 3.0, 3.0, 3.0]
    );
    assert_eq!(gcode::g5_2_knots(4, 2), [0.0, 0.0, 1.0, 2.0, 3.0, 3.0]);
}

#[test]
fn long_curves_are_cut_into_pieces_that_are_the_same_curve() {
    let program = parse(FARFALLA).unwrap();
    let blocks = program.to_core_blocks(&CoreOptions::default()).unwrap();
    let pieces: Vec<_> = blocks
        .iter()
        .filter_map(|b| match &b.path {
            Path::Nurbs(n) => Some((b, n)),
            _ => None,
        })
        .collect();
    assert!(
        pieces.len() >= 2,
        "51 control points need at least two pieces"
    );
    let whole = &nurbs(FARFALLA)[0];
    let mut u_prev = 0.0;
    for (b, n) in &pieces {
        assert!(n.control_count() <= interp_core::nurbs::MAX_CTRL);
        assert_eq!(b.id, 68, "id is the source line that ended the curve");
        assert!((b.feed - 290.0 / 60.0).abs() < 1e-12);
        assert_eq!(n.u_start(), u_prev);
        u_prev = n.u_end();
    }
    assert_eq!(u_prev, 47.0);
    // Pieces chain end to start, and start/end on the file's first/last point.
    let first = pieces[0].1.start_point();
    let last = pieces[pieces.len() - 1].1.end_point();
    assert_eq!([first.x, first.y, first.z], whole.points[0]);
    assert_eq!([last.x, last.y, last.z], whole.points[50]);
    for w in pieces.windows(2) {
        assert_eq!(w[0].1.end_point(), w[1].1.start_point());
    }
    // The same curve: evaluate each piece against a direct de Boor evaluation
    // of the whole program curve (independent of the split).
    for (_, n) in &pieces {
        for k in 0..=20 {
            let u = n.u_start() + (n.u_end() - n.u_start()) * f64::from(k) / 20.0;
            let p = n.eval(u, 0).p;
            let q = de_boor(whole, u);
            for i in 0..3 {
                assert!((p[i] - q[i]).abs() < 1e-9, "u = {u}: {p:?} vs {q:?}");
            }
        }
    }
}

/// Rational de Boor on the whole program curve (Piegl–Tiller A4.1, written
/// here independently of interp-core).
fn de_boor(c: &NurbsMove, u: f64) -> [f64; 3] {
    let p = c.degree;
    let n = c.points.len();
    let k = c.knots.as_slice();
    let mut span = p;
    while span + 1 < n && u >= k[span + 1] {
        span += 1;
    }
    let mut d: Vec<[f64; 4]> = (0..=p)
        .map(|j| {
            let i = span - p + j;
            let w = c.weights[i];
            let q = c.points[i];
            [q[0] * w, q[1] * w, q[2] * w, w]
        })
        .collect();
    for r in 1..=p {
        for j in (r..=p).rev() {
            let i = span - p + j;
            let den = k[i + p + 1 - r] - k[i];
            let a = if den == 0.0 { 0.0 } else { (u - k[i]) / den };
            for t in 0..4 {
                d[j][t] = (1.0 - a) * d[j - 1][t] + a * d[j][t];
            }
        }
    }
    let h = d[p];
    [h[0] / h[3], h[1] / h[3], h[2] / h[3]]
}

#[test]
#[ignore = "needs /work/shared/corpus; run with --ignored"]
fn every_g6_corpus_curve_matches_its_file() {
    let root = std::path::Path::new("/work/shared/corpus/nurbs-linuxcnc/g6");
    if !root.exists() {
        println!("corpus absent; skipped");
        return;
    }
    let mut curves = 0;
    for e in std::fs::read_dir(root).unwrap() {
        let path = e.unwrap().path();
        let text = std::fs::read_to_string(&path).unwrap();
        curves += check_against_scan(&text);
    }
    println!("{curves} G6.2 curves match their files");
    assert!(curves >= 40);
}
