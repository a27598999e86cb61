//! Unit checks of the offset primitives against brute force.

use super::offset::{CutterShape, OffsetEdge};
use crate::cutter::Cutter;

/// Tool-tip height against a segment by dense sampling along it (each
/// sample is the exact drop onto one point), refined around the best.
fn brute_drop(e: &OffsetEdge, u: f64, w: f64, cutter: &Cutter) -> f64 {
    let (rad, r) = (cutter.radius(), cutter.corner_radius());
    let a = rad - r;
    let at = |t: f64| {
        let p = [0, 1, 2].map(|k| e.p0[k] + t * (e.p1[k] - e.p0[k]));
        let d = (p[0] - u).hypot(p[1] - w);
        if d > rad {
            f64::NEG_INFINITY
        } else if d <= a {
            p[2]
        } else {
            p[2] - (r - (r * r - (d - a).powi(2)).max(0.0).sqrt())
        }
    };
    let n = 20_000;
    let (mut best, mut bt) = (f64::NEG_INFINITY, 0.0);
    for i in 0..=n {
        let t = i as f64 / n as f64;
        if at(t) > best {
            (best, bt) = (at(t), t);
        }
    }
    // Refine on the neighbouring samples: the function is concave where the
    // cutter reaches and has no value beyond its rim, where the maximum of a
    // flat cutter often is; the reachable part is an interval around `bt`.
    let (mut lo, mut hi) = (
        (bt - 1.0 / n as f64).max(0.0),
        (bt + 1.0 / n as f64).min(1.0),
    );
    for _ in 0..200 {
        let (c, d) = (lo + (hi - lo) / 3.0, hi - (hi - lo) / 3.0);
        let (fc, fd) = (at(c), at(d));
        match (fc.is_finite(), fd.is_finite()) {
            (true, false) => hi = d,
            (false, true) => lo = c,
            (false, false) if bt <= c => hi = c,
            (false, false) => lo = d,
            _ if fc >= fd => hi = d,
            _ => lo = c,
        }
    }
    best.max(at(lo)).max(at(hi))
}

#[test]
fn edge_drop_matches_brute_force_for_every_cutter() {
    // A small LCG: deterministic edges and points around them.
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut rnd = move || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    for tool in ["ball:6", "flat:6", "bull:6:1", "bull:10:2.5"] {
        let cutter: Cutter = tool.parse().unwrap();
        let shape = CutterShape::new(&cutter);
        let mut checked = 0;
        for _ in 0..400 {
            let e = OffsetEdge {
                p0: [rnd() * 8.0 - 4.0, rnd() * 8.0 - 4.0, rnd() * 4.0],
                p1: [rnd() * 8.0 - 4.0, rnd() * 8.0 - 4.0, rnd() * 4.0],
                v0: 0,
                v1: 1,
            };
            let (u, w) = (rnd() * 12.0 - 6.0, rnd() * 12.0 - 6.0);
            let want = brute_drop(&e, u, w, &cutter);
            let (got, _) = e.drop_at(u, w, &shape, 0);
            if want.is_finite() {
                assert!(
                    (got - want).abs() < 1e-7,
                    "{tool} {e:?} at ({u}, {w}): {got} vs {want}"
                );
                checked += 1;
            }
        }
        assert!(checked > 100, "{tool}: {checked}");
    }
}

/// A path of more CL points than the limit is refused (naming the chord
/// tolerance and the step-over), not built: a tolerance near what f64
/// resolves would otherwise exhaust memory. At the limit it is the path.
#[test]
fn a_path_over_the_point_limit_is_refused() {
    use super::{RasterConfig, RasterError, plan_raster, plan_raster_limited};
    use crate::mesh::{P3, TriMesh, WeldOptions};
    // A 20 × 20 mm plate: the ball rolls over its edges, where the chord
    // tolerance sets the points.
    let p = |x: f64, y: f64| P3::new(x, y, 2.0);
    let soup = [
        [p(0.0, 0.0), p(20.0, 0.0), p(20.0, 20.0)],
        [p(0.0, 0.0), p(20.0, 20.0), p(0.0, 20.0)],
    ];
    let mesh = TriMesh::from_triangles(&soup, WeldOptions::default()).unwrap();
    let cutter = Cutter::Ball { diameter: 4.0 };
    let config = RasterConfig {
        stepover: 2.0,
        ..RasterConfig::default()
    };
    let path = plan_raster(&mesh, &cutter, &config).unwrap();
    let n = path.point_count();
    assert!(n > 100, "{n} points");
    let at = plan_raster_limited(&mesh, &cutter, &config, &|_, _| {}, n).unwrap();
    assert_eq!(at, path);
    let err = plan_raster_limited(&mesh, &cutter, &config, &|_, _| {}, n - 1).unwrap_err();
    let RasterError::TooManyPoints { points, limit, .. } = err else {
        panic!("{err}");
    };
    assert!(points > n - 1 && points <= n, "{points}");
    assert_eq!(limit, n - 1);
    let text = err.to_string();
    assert!(text.contains("chord-tolerance 0.00001 mm"), "{text}");
    assert!(text.contains("stepover 2 mm"), "{text}");
}
