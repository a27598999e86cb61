//! NURBS evaluation against an independent reference: geomdl 5.4.0.
//!
//! `fixtures/geomdl_curves.json` is written by `fixtures/make_geomdl_fixtures.py`
//! (`pip install geomdl==5.4.0 numpy scipy && python3 interp-core/tests/fixtures/make_geomdl_fixtures.py`),
//! which also checks geomdl's rational derivatives against finite differences
//! and exact rational arithmetic. Curves: random 3-D curves of degree 1..=5
//! (polynomial and rational, double interior knots, two with > 26 control
//! points), an exact rational-quadratic circle and the LinuxCNC butterfly.
//!
//! Curves with more than `MAX_CTRL - 6` control points are cut with
//! `split_program_curve`; a parameter is evaluated on the segment whose range
//! contains it, the right one at a split point (geomdl's spans are
//! `knots[i] <= u < knots[i+1]`, so its derivatives at knots are right-sided),
//! the last one at the curve end.
//!
//! Tolerances: point `1e-9 * max(1, |p|)` mm; derivative k `1e-9 * max(1, |C^(k)|)`;
//! curvature `1e-9 * max(kappa, 1e-3 * |C''| / |C'|^2)` (the floor only matters on
//! straight pieces, where kappa is rounding noise on both sides); arc length
//! `1e-9` relative.

mod common;

use interp_core::geom::{Curve, Derivs, Vec3};
use interp_core::nurbs::{MAX_CTRL, Nurbs};
use serde_json::Value;

const FIXTURE: &str = include_str!("fixtures/geomdl_curves.json");

const POINT_TOL: f64 = 1e-9;
const DERIV_TOL: f64 = 1e-9;
const CURVATURE_TOL: f64 = 1e-9;
const LENGTH_TOL: f64 = 1e-9;
/// Longest program curve handed to `Nurbs::new` directly.
const MAX_SEGMENT_CTRL: usize = MAX_CTRL - 6;

struct Sample {
    u: f64,
    p: Vec3,
    d: [Vec3; 3],
    curvature: f64,
}

struct RefCurve {
    name: String,
    degree: usize,
    points: Vec<[f64; 3]>,
    weights: Vec<f64>,
    knots: Vec<f64>,
    length: f64,
    /// `(ua, ub, length)`
    partial_lengths: Vec<(f64, f64, f64)>,
    samples: Vec<Sample>,
}

fn num(v: &Value) -> f64 {
    v.as_f64()
        .unwrap_or_else(|| panic!("fixture: expected a number, found {v}"))
}

fn nums(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap_or_else(|| panic!("fixture: expected an array, found {v}"))
        .iter()
        .map(num)
        .collect()
}

fn vec3(v: &Value) -> Vec3 {
    let a = nums(v);
    assert_eq!(a.len(), 3, "fixture: expected 3 coordinates");
    Vec3::new(a[0], a[1], a[2])
}

fn load() -> Vec<RefCurve> {
    let doc: Value = serde_json::from_str(FIXTURE).expect("fixture is valid JSON");
    assert_eq!(doc["geomdl_version"], "5.4.0");
    doc["curves"]
        .as_array()
        .expect("fixture: curves")
        .iter()
        .map(|c| RefCurve {
            name: c["name"].as_str().expect("name").to_owned(),
            degree: c["degree"].as_u64().expect("degree") as usize,
            points: c["points"]
                .as_array()
                .expect("points")
                .iter()
                .map(|p| {
                    let v = vec3(p);
                    [v.x, v.y, v.z]
                })
                .collect(),
            weights: nums(&c["weights"]),
            knots: nums(&c["knots"]),
            length: num(&c["length"]),
            partial_lengths: c["partial_lengths"]
                .as_array()
                .expect("partial_lengths")
                .iter()
                .map(|r| {
                    let r = nums(r);
                    (r[0], r[1], r[2])
                })
                .collect(),
            samples: c["samples"]
                .as_array()
                .expect("samples")
                .iter()
                .map(|s| Sample {
                    u: num(&s["u"]),
                    p: vec3(&s["p"]),
                    d: [vec3(&s["d1"]), vec3(&s["d2"]), vec3(&s["d3"])],
                    curvature: num(&s["curvature"]),
                })
                .collect(),
        })
        .collect()
}

impl RefCurve {
    fn u_start(&self) -> f64 {
        self.knots[self.degree]
    }

    fn u_end(&self) -> f64 {
        self.knots[self.knots.len() - self.degree - 1]
    }

    /// The curve as interp-core segments (one unless it is long).
    fn segments(&self) -> Vec<Nurbs> {
        if self.points.len() > MAX_SEGMENT_CTRL {
            common::split_segments(
                self.degree,
                &self.points,
                &self.weights,
                &self.knots,
                MAX_SEGMENT_CTRL,
            )
        } else {
            vec![
                Nurbs::new(self.degree, &self.points, &self.weights, &self.knots)
                    .unwrap_or_else(|e| panic!("{}: Nurbs::new refused it: {e:?}", self.name)),
            ]
        }
    }

    /// Multiplicity of `u` if it is a knot strictly inside the range, else 0.
    fn interior_multiplicity(&self, u: f64) -> usize {
        if u <= self.u_start() || u >= self.u_end() {
            return 0;
        }
        self.knots.iter().filter(|&&k| k == u).count()
    }
}

/// The segment that evaluates `u`: the one with `u_start <= u < u_end`, the last at the end.
fn segment_for(segments: &[Nurbs], u: f64) -> &Nurbs {
    let last = segments.last().expect("at least one segment");
    if u >= last.u_start() {
        return last;
    }
    segments
        .iter()
        .find(|s| s.u_start() <= u && u < s.u_end())
        .unwrap_or_else(|| panic!("no segment contains u = {u}"))
}

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
        let expected_split = n > MAX_SEGMENT_CTRL;
        assert_eq!(
            segs.len() > 1,
            expected_split,
            "{}: {} segments",
            c.name,
            segs.len()
        );
        assert_eq!(segs[0].u_start(), c.u_start(), "{}: start", c.name);
        assert_eq!(segs[segs.len() - 1].u_end(), c.u_end(), "{}: end", c.name);
        for w in segs.windows(2) {
            assert_eq!(
                w[0].u_end(),
                w[1].u_start(),
                "{}: gap between segments",
                c.name
            );
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
            let seg = segment_for(&segs, s.u);
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

            // Curvature uses C' and C''.
            if m > 0 && 2 + m > c.degree {
                continue;
            }
            let kappa = got.curvature();
            let scale = s.d[1].norm() / s.d[0].norm_squared();
            let e = (kappa - s.curvature).abs() / s.curvature.max(1e-3 * scale);
            worst[4] = worst[4].max(e);
            if e > CURVATURE_TOL {
                failures.push(format!(
                    "{where_}: curvature {kappa:?} vs geomdl {:?} (rel {e:.3e})",
                    s.curvature
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
