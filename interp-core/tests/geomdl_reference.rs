//! NURBS evaluation against an independent reference: geomdl 5.4.0.
//!
//! `fixtures/geomdl_curves.json` is written by `fixtures/make_geomdl_fixtures.py`
//! (`pip install geomdl==5.4.0 numpy scipy && python3 interp-core/tests/fixtures/make_geomdl_fixtures.py`),
//! which also checks geomdl's rational derivatives against finite differences
//! and exact rational arithmetic. Curves: random 3-D curves of degree 1..=5
//! (polynomial and rational, double interior knots, two with > 26 control
//! points), an exact rational-quadratic circle, the LinuxCNC butterfly, and
//! curves that stop: LinuxCNC's G5.2 examples whose first point repeats the
//! start (C'(0) = 0), rational curves of degree 1..=5 with repeated control
//! points at the ends and inside and a span that stands still, a double knot at
//! a join with coincident points, and a cusp inside a span. Where C' = 0 the
//! fixture lists the parameter (exactly) and geomdl's one-sided tangents.
//!
//! Curves with more than `MAX_CTRL - 6` control points, or with a span that
//! stands still, are cut with `split_program_curve`; a parameter is evaluated
//! on the segment whose range contains it, the right one at a split point
//! (geomdl's spans are `knots[i] <= u < knots[i+1]`, so its derivatives at knots
//! are right-sided), the last one at the curve end. Inside a span that stands
//! still (left out by the split) only the point is compared.
//!
//! Tolerances: point `1e-9 * max(1, |p|)` mm; derivative k `1e-9 * max(1, |C^(k)|)`;
//! curvature `1e-9 * max(kappa, 1e-3 * |C''| / |C'|^2)` (the floor only matters on
//! straight pieces, where kappa is rounding noise on both sides; not compared
//! where C' = 0 or, rounding, next to it); arc length `1e-9` relative.

mod common;

use common::geomdl::{MAX_SEGMENT_CTRL, load, segment_for};
use interp_core::geom::{Curve, Derivs, Vec3};
use interp_core::nurbs::{Nurbs, Side};

const POINT_TOL: f64 = 1e-9;
const DERIV_TOL: f64 = 1e-9;
const CURVATURE_TOL: f64 = 1e-9;
const LENGTH_TOL: f64 = 1e-9;
/// One-sided tangents at stationary points: geomdl's come from chords of 1e-7
/// of the span, whose direction is off by about that much.
const TANGENT_TOL: f64 = 1e-5;
/// Curvature is compared where |C'| is above this times the largest
/// coordinate over the knot span's length.
const SPEED_RESOLUTION: f64 = 1e-6;
/// A zero of C' inside a span is found to this fraction of the span.
const STATIONARY_U_TOL: f64 = 1e-9;

/// `|a - b| / max(floor, |b|)`
fn rel(a: Vec3, b: Vec3, floor: f64) -> f64 {
    (a - b).norm() / b.norm().max(floor)
}

fn fmt(v: Vec3) -> String {
    format!("[{:?}, {:?}, {:?}]", v.x, v.y, v.z)
}

#[test]
fn fixture_butterfly_matches_common_constants() {
    use common::butterfly::*;
    let curves = load();
    let b = curves
        .iter()
        .find(|c| c.name == "linuxcnc_butterfly")
        .expect("butterfly in fixture");
    assert_eq!(b.degree, BUTTERFLY_DEGREE);
    assert_eq!(b.points, BUTTERFLY_POINTS);
    assert_eq!(b.weights, BUTTERFLY_WEIGHTS);
    assert_eq!(b.knots, BUTTERFLY_KNOTS);
}

#[test]
fn segments_tile_the_parameter_range() {
    for c in load() {
        let segs = c.segments();
        let n = c.points.len();
        let expected_split = n > MAX_SEGMENT_CTRL || !c.still_spans.is_empty();
        assert_eq!(
            segs.len() > 1,
            expected_split,
            "{}: {} segments",
            c.name,
            segs.len()
        );
        // Spans that stand still at the ends are left out too.
        assert_eq!(segs[0].u_start(), c.moving_start(), "{}: start", c.name);
        assert_eq!(
            segs[segs.len() - 1].u_end(),
            c.moving_end(),
            "{}: end",
            c.name
        );
        for w in segs.windows(2) {
            // Segments meet, except across spans that stand still, at their point.
            if w[0].u_end() != w[1].u_start() {
                let gap = (w[0].u_end(), w[1].u_start());
                assert!(
                    c.still_spans.iter().any(|&(a, b)| a >= gap.0 && b <= gap.1)
                        && c.still_spans
                            .iter()
                            .filter(|&&(a, b)| a >= gap.0 && b <= gap.1)
                            .map(|&(a, b)| b - a)
                            .sum::<f64>()
                            == gap.1 - gap.0,
                    "{}: gap {gap:?} between segments is no still span",
                    c.name
                );
                assert_eq!(w[0].end_point(), w[1].start_point(), "{}", c.name);
            }
            assert!(w[0].u_start() < w[0].u_end(), "{}: empty segment", c.name);
        }
    }
    let b = common::butterfly_segments(MAX_SEGMENT_CTRL);
    assert!(b.len() >= 2);
    assert_eq!(b[0].u_start(), 0.0);
    assert_eq!(b[b.len() - 1].u_end(), 47.0);
}

#[test]
fn points_derivatives_and_curvature_match_geomdl() {
    let mut failures = Vec::new();
    let mut one_sided_notes = Vec::new();
    for c in load() {
        let segs = c.segments();
        // The fixture samples every interior knot of long curves, so each joint is hit.
        for w in segs.windows(2) {
            let joint = w[0].u_end();
            assert!(
                c.samples.iter().any(|s| s.u == joint),
                "{}: the fixture has no sample at the split point u = {joint:?}",
                c.name
            );
        }
        let mut worst = [0.0f64; 5];
        for s in &c.samples {
            let Some(seg) = segment_for(&segs, s.u) else {
                // Inside a span that stands still: the point is where the curve waits.
                let at = match segs.iter().rfind(|g| g.u_end() <= s.u) {
                    Some(g) => g.end_point(),
                    None => segs[0].start_point(),
                };
                let e = (at - s.p).norm() / s.p.norm().max(1.0);
                if e > POINT_TOL {
                    failures.push(format!("{} u={:?}: still point {e:.3e} off", c.name, s.u));
                }
                continue;
            };
            let got: Derivs = seg.eval(s.u, 3);
            let m = c.interior_multiplicity(s.u);
            let where_ = format!(
                "{} (p={}, {} segs) u={:?}",
                c.name,
                c.degree,
                segs.len(),
                s.u
            );

            let e = (got.p - s.p).norm() / s.p.norm().max(1.0);
            worst[0] = worst[0].max(e);
            if e > POINT_TOL {
                failures.push(format!(
                    "{where_}: point {} vs geomdl {} (rel {e:.3e})",
                    fmt(got.p),
                    fmt(s.p)
                ));
            }

            let got_d = [got.d1, got.d2, got.d3];
            for k in 1..=3 {
                let e = rel(got_d[k - 1], s.d[k - 1], 1.0);
                // At an interior knot of multiplicity m the curve is only C^(p-m):
                // higher derivatives are one-sided there and not compared.
                if m > 0 && k + m > c.degree {
                    if e > DERIV_TOL {
                        one_sided_notes.push(format!(
                            "{where_}: knot mult {m}, d{k} {} vs geomdl (right-sided) {}",
                            fmt(got_d[k - 1]),
                            fmt(s.d[k - 1])
                        ));
                    }
                    continue;
                }
                worst[k] = worst[k].max(e);
                if e > DERIV_TOL {
                    failures.push(format!(
                        "{where_}: d{k} {} vs geomdl {} (rel {e:.3e})",
                        fmt(got_d[k - 1]),
                        fmt(s.d[k - 1])
                    ));
                }
            }

            // Curvature uses C' and C'' (and is a limit where C' = 0).
            let Some(want) = s.curvature else {
                continue;
            };
            if m > 0 && 2 + m > c.degree {
                continue;
            }
            // Next to a stationary point C' is a difference of nearly equal
            // terms on both sides, and so is the curvature (~ 1/|C'|): compared
            // only where |C'| is well above the coordinates' rounding per span.
            if s.d[0].norm() < SPEED_RESOLUTION * c.big() / c.span_length(s.u) {
                continue;
            }
            let kappa = got.curvature();
            let scale = s.d[1].norm() / s.d[0].norm_squared();
            let e = (kappa - want).abs() / want.max(1e-3 * scale);
            worst[4] = worst[4].max(e);
            if e > CURVATURE_TOL {
                failures.push(format!(
                    "{where_}: curvature {kappa:?} vs geomdl {want:?} (rel {e:.3e})"
                ));
            }
        }
        eprintln!(
            "{:<26} worst rel: p {:.1e}  d1 {:.1e}  d2 {:.1e}  d3 {:.1e}  kappa {:.1e}",
            c.name, worst[0], worst[1], worst[2], worst[3], worst[4]
        );
    }
    for n in &one_sided_notes {
        eprintln!("note (not compared, one-sided derivative at a knot): {n}");
    }
    assert!(
        failures.is_empty(),
        "{} mismatches against geomdl:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

/// Length over `[ua, ub]` summed over the segments that overlap it.
fn length(segs: &[Nurbs], ua: f64, ub: f64, tol: f64) -> f64 {
    segs.iter()
        .filter(|s| s.u_end() > ua && s.u_start() < ub)
        .map(|s| s.arc_length(ua.max(s.u_start()), ub.min(s.u_end()), tol))
        .sum()
}

#[test]
fn arc_length_matches_reference() {
    let mut failures = Vec::new();
    for c in load() {
        let segs = c.segments();
        let mut ranges = vec![(c.u_start(), c.u_end(), c.length)];
        ranges.extend(c.partial_lengths.iter().copied());
        let mut worst = 0.0f64;
        for (ua, ub, want) in ranges {
            // Absolute quadrature tolerance (mm), well below the comparison tolerance.
            let tol = 1e-3 * LENGTH_TOL * want;
            let got = length(&segs, ua, ub, tol);
            let e = (got - want).abs() / want;
            worst = worst.max(e);
            if e > LENGTH_TOL {
                failures.push(format!(
                    "{}: arc length over [{ua:?}, {ub:?}] {got:?} vs reference {want:?} (rel {e:.3e})",
                    c.name
                ));
            }
        }
        eprintln!(
            "{:<26} L = {:.9} mm, worst rel {worst:.1e}",
            c.name, c.length
        );
    }
    assert!(
        failures.is_empty(),
        "{} arc length mismatches:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

/// Every parameter where the curve stops is found, with its one-sided
/// tangents, and none elsewhere (every fixture curve is asked, the ones that
/// never stop included).
#[test]
fn stationary_points_and_their_tangents_match_geomdl() {
    let mut failures = Vec::new();
    for c in load() {
        let segs = c.segments();
        // Ours: each segment's ends where it stops, and what it finds inside.
        let mut found: Vec<(f64, &Nurbs)> = Vec::new();
        for g in &segs {
            if g.is_stationary(g.u_start(), Side::After) {
                found.push((g.u_start(), g));
            }
            g.for_each_stationary(0.0, |u| found.push((u, g)));
            if g.is_stationary(g.u_end(), Side::Before) {
                found.push((g.u_end(), g));
            }
        }
        // A joint of two segments where the curve stops is found from both.
        found.dedup_by(|a, b| a.0 == b.0);
        let want: Vec<f64> = c.stationary.iter().map(|s| s.u).collect();
        let got: Vec<f64> = found.iter().map(|f| f.0).collect();
        let span = c.u_end() - c.u_start();
        let same = want.len() == got.len()
            && want
                .iter()
                .zip(&got)
                .all(|(a, b)| (a - b).abs() <= STATIONARY_U_TOL * span);
        if !same {
            failures.push(format!("{}: stops at {got:?}, geomdl at {want:?}", c.name));
            continue;
        }
        for (s, &(u, g)) in c.stationary.iter().zip(&found) {
            // At a joint the tangent before belongs to the segment before.
            let before_seg = segs.iter().find(|h| h.u_start() < u && u <= h.u_end());
            for (side, want, seg) in [
                (Side::Before, s.before, before_seg),
                (Side::After, s.after, Some(g)),
            ] {
                let (Some(want), Some(seg)) = (want, seg) else {
                    continue;
                };
                let t = seg.tangent(u, side);
                if (t - want).norm() > TANGENT_TOL {
                    failures.push(format!(
                        "{} u={u:?} {side:?}: tangent {} vs geomdl {}",
                        c.name,
                        fmt(t),
                        fmt(want)
                    ));
                }
            }
        }
        if c.stops() {
            eprintln!("{:<34} stops at {got:?}", c.name);
        }
    }
    assert!(
        failures.is_empty(),
        "{} mismatches:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

#[test]
fn circle_is_exact() {
    let curves = load();
    let c = curves
        .iter()
        .find(|c| c.name == "circle_r50")
        .expect("circle in fixture");
    let seg = &c.segments()[0];
    let centre = Vec3::new(10.0, -20.0, 5.0);
    for i in 0..=400 {
        let u = c.u_start() + (c.u_end() - c.u_start()) * f64::from(i) / 400.0;
        let d = seg.eval(u, 2);
        let r = (d.p - centre).norm();
        assert!((r - 50.0).abs() <= 1e-12 * 50.0, "u={u:?}: radius {r:?}");
        assert!(
            (d.curvature() * 50.0 - 1.0).abs() <= 1e-12,
            "u={u:?}: curvature {:?}",
            d.curvature()
        );
    }
}
