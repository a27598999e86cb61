//! Parts built in code whose setups are known, for tests, benchmarks and
//! examples. Each returns a triangle soup (build a mesh with
//! [`TriMesh::from_triangles`](crate::mesh::TriMesh::from_triangles)); the
//! triangles face the side a tool comes from.

use std::f64::consts::{PI, TAU};

use nalgebra::{Point3, Rotation3, Unit, Vector3};

type P3 = Point3<f64>;
type V3 = Vector3<f64>;

/// Turns `tri` so that its normal points along `want`.
fn facing(tri: [P3; 3], want: V3) -> [P3; 3] {
    let n = (tri[1] - tri[0]).cross(&(tri[2] - tri[0]));
    if n.dot(&want) < 0.0 {
        [tri[0], tri[2], tri[1]]
    } else {
        tri
    }
}

fn centroid(t: &[P3; 3]) -> P3 {
    P3::from((t[0].coords + t[1].coords + t[2].coords) / 3.0)
}

/// A unit-sphere point at polar angle `theta` from +z and azimuth `phi`.
fn on_sphere(theta: f64, phi: f64) -> V3 {
    V3::new(
        theta.sin() * phi.cos(),
        theta.sin() * phi.sin(),
        theta.cos(),
    )
}

/// A band of the sphere of radius `r` between polar angles `t0 < t1`
/// (radians from +z), `rings × segments` quads (a fan where `t0 = 0`), facing
/// outward (`outward`) or toward the centre.
fn sphere_band(
    r: f64,
    t0: f64,
    t1: f64,
    rings: usize,
    segments: usize,
    outward: bool,
) -> Vec<[P3; 3]> {
    let mut soup = Vec::new();
    let p = |i: usize, j: usize| {
        let t = t0 + (t1 - t0) * i as f64 / rings as f64;
        P3::from(on_sphere(t, TAU * j as f64 / segments as f64) * r)
    };
    let sign = if outward { 1.0 } else { -1.0 };
    let mut push = |tri: [P3; 3]| {
        let c = centroid(&tri);
        soup.push(facing(tri, c.coords * sign));
    };
    for i in 0..rings {
        for j in 0..segments {
            let (a, b, c, d) = (p(i, j), p(i + 1, j), p(i + 1, j + 1), p(i, j + 1));
            if i == 0 && t0 == 0.0 {
                push([a, b, c]);
            } else {
                push([a, b, c]);
                push([a, c, d]);
            }
        }
    }
    soup
}

/// Rotates every corner of `soup` by `rotation` about the origin.
pub fn rotated(soup: &[[P3; 3]], rotation: &Rotation3<f64>) -> Vec<[P3; 3]> {
    soup.iter().map(|t| t.map(|p| rotation * p)).collect()
}

/// A rotation drawn from `seed` (xorshift): axis uniform on the sphere,
/// angle uniform in `[0, π)`. The same seed gives the same rotation.
pub fn random_rotation(seed: u64) -> Rotation3<f64> {
    let mut s: u64 = seed.wrapping_mul(2_654_435_761).wrapping_add(1);
    let mut next = || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64
    };
    let z = 2.0 * next() - 1.0;
    let t = TAU * next();
    let r = (1.0 - z * z).sqrt();
    let axis = V3::new(r * t.cos(), r * t.sin(), z);
    Rotation3::from_axis_angle(&Unit::new_normalize(axis), PI * next())
}

/// The rotation taking +z to the unit vector `axis` (shortest arc).
pub fn z_to(axis: &V3) -> Rotation3<f64> {
    Rotation3::rotation_between(&V3::z(), axis)
        .unwrap_or_else(|| Rotation3::from_axis_angle(&Unit::new_normalize(V3::x()), PI))
}

/// A convex spherical shell (outer side) of radius `r` around +z, from the
/// pole down to `extent_deg` from it. Beyond 90° it is an undercut: its rim
/// faces away from +z by `extent_deg − 90°`, and every setup must tilt that
/// far all around the axis.
pub fn dome(r: f64, extent_deg: f64, rings: usize, segments: usize) -> Vec<[P3; 3]> {
    sphere_band(r, 0.0, extent_deg.to_radians(), rings, segments, true)
}

/// The inside of a sphere of radius `r` with a round opening of half-angle
/// `opening_deg` around +z (a pocket machined through its mouth). Below 90°
/// the mouth overhangs: the wall just under the lip is reached only by
/// directions tilted at least `90° − opening_deg` from +z.
pub fn cavity(r: f64, opening_deg: f64, rings: usize, segments: usize) -> Vec<[P3; 3]> {
    sphere_band(r, opening_deg.to_radians(), PI, rings, segments, false)
}

/// The inside of a hemispherical bowl of radius `r`, open toward +z.
pub fn bowl(r: f64, rings: usize, segments: usize) -> Vec<[P3; 3]> {
    cavity(r, 90.0, rings, segments)
}

/// A small floor triangle (centroid at the origin, facing +z) at the bottom
/// of a round well of radius `radius` and depth `depth`, with a flat collar
/// out to `3·radius` around its mouth. Seen from the floor's centroid, the
/// open directions form a cone of half-angle `atan(radius / depth)` around +z.
/// Triangle 0 is the floor.
pub fn well(radius: f64, depth: f64, segments: usize) -> Vec<[P3; 3]> {
    /// Floor triangle size as a fraction of the radius (a point, nearly).
    const FLOOR_FRACTION: f64 = 1e-3;
    let s = radius * FLOOR_FRACTION;
    let mut soup = vec![facing(
        [
            P3::new(s, 0.0, 0.0),
            P3::new(-s / 2.0, s * 0.866, 0.0),
            P3::new(-s / 2.0, -s * 0.866, 0.0),
        ],
        V3::z(),
    )];
    let ring = |rad: f64, z: f64, j: usize| {
        let a = TAU * j as f64 / segments as f64;
        P3::new(rad * a.cos(), rad * a.sin(), z)
    };
    for j in 0..segments {
        let (a, b) = (ring(radius, 0.0, j), ring(radius, 0.0, j + 1));
        let (c, d) = (ring(radius, depth, j + 1), ring(radius, depth, j));
        for tri in [[a, b, c], [a, c, d]] {
            let inward = -centroid(&tri).coords.xy().push(0.0);
            soup.push(facing(tri, inward));
        }
        let (e, f) = (
            ring(3.0 * radius, depth, j + 1),
            ring(3.0 * radius, depth, j),
        );
        for tri in [[d, c, e], [d, e, f]] {
            soup.push(facing(tri, V3::z()));
        }
    }
    soup
}

/// A teapot-like body as in the paper's example: a hemispherical shell of
/// radius 50 mm (open at the bottom, `body_rings × body_segments`) with a
/// straight open spout of radius 8 mm and length 45 mm rising at 40° toward
/// +x from the body's side (`spout_rings × spout_segments`). The spout's
/// underside faces down and out, so the best setup tilts toward the spout.
/// `teapot(10, 12, 5, 6)` has the paper's 288 triangles.
pub fn teapot(
    body_rings: usize,
    body_segments: usize,
    spout_rings: usize,
    spout_segments: usize,
) -> Vec<[P3; 3]> {
    const BODY_RADIUS: f64 = 50.0;
    const SPOUT_RADIUS: f64 = 8.0;
    const SPOUT_LENGTH: f64 = 45.0;
    const SPOUT_ELEVATION_DEG: f64 = 40.0;
    const SPOUT_ROOT_ELEVATION_DEG: f64 = 25.0;
    let mut soup = sphere_band(BODY_RADIUS, 0.0, PI / 2.0, body_rings, body_segments, true);
    // The spout's root ring lies on the body: a circle of radius r around the
    // body point at the root elevation.
    let root_dir = on_sphere((90.0 - SPOUT_ROOT_ELEVATION_DEG).to_radians(), 0.0);
    let axis = on_sphere((90.0 - SPOUT_ELEVATION_DEG).to_radians(), 0.0);
    let root = root_dir * (BODY_RADIUS.powi(2) - SPOUT_RADIUS.powi(2)).sqrt();
    let e1 = V3::y();
    let e2 = root_dir.cross(&e1);
    let p = |i: usize, j: usize| {
        let a = TAU * j as f64 / spout_segments as f64;
        let t = SPOUT_LENGTH * i as f64 / spout_rings as f64;
        P3::from(root + (e1 * a.cos() + e2 * a.sin()) * SPOUT_RADIUS + axis * t)
    };
    for i in 0..spout_rings {
        for j in 0..spout_segments {
            let (a, b, c, d) = (p(i, j), p(i + 1, j), p(i + 1, j + 1), p(i, j + 1));
            for tri in [[a, b, c], [a, c, d]] {
                let off = centroid(&tri).coords - root;
                let out = off - axis * off.dot(&axis);
                soup.push(facing(tri, out));
            }
        }
    }
    soup
}

/// A rectangular pocket `width × length`, `depth` deep, in a flat plate: a
/// floor facing +z, four walls facing into the pocket that lean outward by
/// `draft_deg` (at 0 they are vertical, so +z grazes them; a small draft
/// makes +z reach them only just), and a flange `flange` wide around the
/// mouth. The floor and walls are split `steps × steps` (each quad two
/// triangles), the flange in four trapezoids. Centred on the origin, floor
/// at `z = 0`.
pub fn pocket(
    width: f64,
    length: f64,
    depth: f64,
    draft_deg: f64,
    flange: f64,
    steps: usize,
) -> Vec<[P3; 3]> {
    let steps = steps.max(1);
    let spread = depth * draft_deg.to_radians().tan();
    let (hw, hl) = (width / 2.0, length / 2.0);
    let (tw, tl) = (hw + spread, hl + spread);
    let mut soup = Vec::new();
    // A quad a → b → c → d split into steps × steps, facing `want`.
    let mut quad = |a: P3, b: P3, c: P3, d: P3, want: V3| {
        let at = |u: f64, v: f64| {
            let bottom = a + (b - a) * u;
            let top = d + (c - d) * u;
            bottom + (top - bottom) * v
        };
        let s = steps as f64;
        for i in 0..steps {
            for j in 0..steps {
                let (u0, u1) = (i as f64 / s, (i + 1) as f64 / s);
                let (v0, v1) = (j as f64 / s, (j + 1) as f64 / s);
                let (p, q, r, t) = (at(u0, v0), at(u1, v0), at(u1, v1), at(u0, v1));
                soup.push(facing([p, q, r], want));
                soup.push(facing([p, r, t], want));
            }
        }
    };
    let bottom = [
        P3::new(-hw, -hl, 0.0),
        P3::new(hw, -hl, 0.0),
        P3::new(hw, hl, 0.0),
        P3::new(-hw, hl, 0.0),
    ];
    let top = [
        P3::new(-tw, -tl, depth),
        P3::new(tw, -tl, depth),
        P3::new(tw, tl, depth),
        P3::new(-tw, tl, depth),
    ];
    quad(bottom[0], bottom[1], bottom[2], bottom[3], V3::z());
    for k in 0..4 {
        let (a, b) = (bottom[k], bottom[(k + 1) % 4]);
        let (c, d) = (top[(k + 1) % 4], top[k]);
        // Into the pocket: toward the axis, and up by the draft.
        let mid = P3::from((a.coords + b.coords) / 2.0);
        let inward = -mid.coords.xy().push(0.0).normalize();
        quad(a, b, c, d, inward + V3::z() * draft_deg.to_radians().tan());
    }
    if flange > 0.0 {
        let outer = [
            P3::new(-tw - flange, -tl - flange, depth),
            P3::new(tw + flange, -tl - flange, depth),
            P3::new(tw + flange, tl + flange, depth),
            P3::new(-tw - flange, tl + flange, depth),
        ];
        for k in 0..4 {
            let (a, b) = (top[k], top[(k + 1) % 4]);
            let (c, d) = (outer[(k + 1) % 4], outer[k]);
            soup.push(facing([a, b, c], V3::z()));
            soup.push(facing([a, c, d], V3::z()));
        }
    }
    soup
}

/// An L-shaped step, `length` long along y: a lower floor `floor` wide
/// (facing +z, at `z = 0`, `x ≤ 0`), a wall `height` high that leans over
/// the floor by `lean_deg` (an undercut: the tool must tilt at least that
/// far toward −x to reach it; 0 makes it vertical, grazed by +z), and an
/// upper floor `top` wide at `z = height`. Each face is split `steps`
/// along y (two triangles per step); an open sheet.
pub fn step(
    floor: f64,
    top: f64,
    height: f64,
    lean_deg: f64,
    length: f64,
    steps: usize,
) -> Vec<[P3; 3]> {
    let steps = steps.max(1);
    let overhang = height * lean_deg.to_radians().tan();
    // The profile in (x, z), left to right, and the side each face faces.
    let profile = [
        (-floor, 0.0),
        (0.0, 0.0),
        (-overhang, height),
        (top, height),
    ];
    let lean = lean_deg.to_radians();
    let facing_dirs = [V3::z(), V3::new(-lean.cos(), 0.0, -lean.sin()), V3::z()];
    let mut soup = Vec::new();
    for k in 0..3 {
        let (a, b) = (profile[k], profile[k + 1]);
        for s in 0..steps {
            let (y0, y1) = (
                length * s as f64 / steps as f64,
                length * (s + 1) as f64 / steps as f64,
            );
            let p = |(x, z): (f64, f64), y: f64| P3::new(x, y, z);
            let (q0, q1, q2, q3) = (p(a, y0), p(b, y0), p(b, y1), p(a, y1));
            soup.push(facing([q0, q1, q2], facing_dirs[k]));
            soup.push(facing([q0, q2, q3], facing_dirs[k]));
        }
    }
    soup
}
