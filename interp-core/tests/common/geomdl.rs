//! The geomdl reference fixture (`fixtures/geomdl_curves.json`, written by
//! `fixtures/make_geomdl_fixtures.py`): curves, samples of their derivatives,
//! lengths, and where they stop.

use interp_core::geom::{Curve, Vec3};
use interp_core::nurbs::{MAX_CTRL, Nurbs};
use serde_json::Value;

const FIXTURE: &str = include_str!("../fixtures/geomdl_curves.json");

/// Longest program curve handed to `Nurbs::new` directly.
pub const MAX_SEGMENT_CTRL: usize = MAX_CTRL - 6;

pub struct Sample {
    pub u: f64,
    pub p: Vec3,
    pub d: [Vec3; 3],
    /// `None` where C' = 0.
    pub curvature: Option<f64>,
}

/// A parameter where C' = 0, with geomdl's one-sided unit tangents there.
pub struct Stationary {
    pub u: f64,
    pub before: Option<Vec3>,
    pub after: Option<Vec3>,
}

pub struct RefCurve {
    pub name: String,
    pub degree: usize,
    pub points: Vec<[f64; 3]>,
    pub weights: Vec<f64>,
    pub knots: Vec<f64>,
    pub length: f64,
    /// `(ua, ub, length)`
    pub partial_lengths: Vec<(f64, f64, f64)>,
    pub samples: Vec<Sample>,
    pub stationary: Vec<Stationary>,
    /// `(ua, ub)` over which the control points coincide.
    pub still_spans: Vec<(f64, f64)>,
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

fn opt_vec3(v: &Value) -> Option<Vec3> {
    (!v.is_null()).then(|| vec3(v))
}

fn list<T>(v: &Value, f: impl Fn(&Value) -> T) -> Vec<T> {
    v.as_array()
        .unwrap_or_else(|| panic!("fixture: expected an array, found {v}"))
        .iter()
        .map(f)
        .collect()
}

pub fn load() -> Vec<RefCurve> {
    let doc: Value = serde_json::from_str(FIXTURE).expect("fixture is valid JSON");
    assert_eq!(doc["geomdl_version"], "5.4.0");
    list(&doc["curves"], |c| RefCurve {
        name: c["name"].as_str().expect("name").to_owned(),
        degree: c["degree"].as_u64().expect("degree") as usize,
        points: list(&c["points"], |p| {
            let v = vec3(p);
            [v.x, v.y, v.z]
        }),
        weights: nums(&c["weights"]),
        knots: nums(&c["knots"]),
        length: num(&c["length"]),
        partial_lengths: list(&c["partial_lengths"], |r| {
            let r = nums(r);
            (r[0], r[1], r[2])
        }),
        samples: list(&c["samples"], |s| Sample {
            u: num(&s["u"]),
            p: vec3(&s["p"]),
            d: [vec3(&s["d1"]), vec3(&s["d2"]), vec3(&s["d3"])],
            curvature: s["curvature"].as_f64(),
        }),
        stationary: list(&c["stationary"], |s| Stationary {
            u: num(&s["u"]),
            before: opt_vec3(&s["before"]),
            after: opt_vec3(&s["after"]),
        }),
        still_spans: list(&c["still_spans"], |r| {
            let r = nums(r);
            (r[0], r[1])
        }),
    })
}

impl RefCurve {
    pub fn u_start(&self) -> f64 {
        self.knots[self.degree]
    }

    pub fn u_end(&self) -> f64 {
        self.knots[self.knots.len() - self.degree - 1]
    }

    /// Where the curve starts moving: after the spans that stand still at its start.
    pub fn moving_start(&self) -> f64 {
        let mut u = self.u_start();
        while let Some(&(_, b)) = self.still_spans.iter().find(|&&(a, _)| a == u) {
            u = b;
        }
        u
    }

    /// Where the curve stops moving: before the spans that stand still at its end.
    pub fn moving_end(&self) -> f64 {
        let mut u = self.u_end();
        while let Some(&(a, _)) = self.still_spans.iter().find(|&&(_, b)| b == u) {
            u = a;
        }
        u
    }

    /// The curve as interp-core segments: one, unless it is long or has spans
    /// that stand still (those only a program curve may have; the split leaves
    /// them out).
    pub fn segments(&self) -> Vec<Nurbs> {
        if self.points.len() > MAX_SEGMENT_CTRL || !self.still_spans.is_empty() {
            super::split_segments(
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

    /// Largest coordinate of a control point.
    pub fn big(&self) -> f64 {
        self.points
            .iter()
            .flatten()
            .fold(0.0, |m, x| m.max(x.abs()))
    }

    /// Length of the non-empty knot span holding `u` (right-sided, the last at the end).
    pub fn span_length(&self, u: f64) -> f64 {
        let k = &self.knots;
        (self.degree..k.len() - self.degree - 1)
            .rfind(|&i| k[i] < k[i + 1] && k[i] <= u)
            .map(|i| k[i + 1] - k[i])
            .expect("u in the range")
    }

    /// Multiplicity of `u` if it is a knot strictly inside the range, else 0.
    pub fn interior_multiplicity(&self, u: f64) -> usize {
        if u <= self.u_start() || u >= self.u_end() {
            return 0;
        }
        self.knots.iter().filter(|&&k| k == u).count()
    }

    /// Does the curve stop anywhere (C' = 0 or a span that stands still)?
    pub fn stops(&self) -> bool {
        !self.stationary.is_empty() || !self.still_spans.is_empty()
    }
}

/// The segment that evaluates `u`: the one with `u_start <= u < u_end`, the last
/// at the end; `None` inside a span that stands still (left out by the split).
pub fn segment_for(segments: &[Nurbs], u: f64) -> Option<&Nurbs> {
    let last = segments.last().expect("at least one segment");
    if u >= last.u_start() {
        return (u <= last.u_end()).then_some(last);
    }
    segments.iter().find(|s| s.u_start() <= u && u < s.u_end())
}
