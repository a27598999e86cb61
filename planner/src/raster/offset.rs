//! The offset surfaces of a mesh for a cutter, and their sections by one
//! vertical pass plane (seed `001_…` §4.3–4.4).
//!
//! Everything here works in the *pass frame*: the mesh rotated about Z so that
//! passes run along `u` (the frame's x) at constant `w` (its y). Cutters are
//! round, so the rotation changes nothing but the coordinates.
//!
//! A cutter is the Minkowski sum of a flat disk of radius `a = R − r` and a
//! ball of radius `r` (ball: `a = 0`; flat: `r = 0`; bull: both positive). The
//! tool-tip height over a point `q` against a set `S` is
//! `max over p in S of p.z − g(|p.xy − q|)`, with `g` the cutter's profile
//! height at radial distance `d` (`∞` beyond `R`). This is the *generalised
//! offset*: for a ball it is exactly the seed's offset (faces moved along
//! their normals by `R`, edges as cylinders, vertices as spheres, then down
//! by `R` to the tip); for flat and bull cutters the same primitives carry the
//! disk's and torus's offsets, and every formula is exact (closed forms for
//! ball and flat, a converged 1-D maximisation of a concave function for the
//! bull's edge case).
//!
//! Two kinds of section piece cover the offset surface along a pass:
//! * [`PieceKind::Line`]: a face's offset is a translated copy of the
//!   triangle, so its section is a straight segment;
//! * [`PieceKind::Capsule`]: a kept edge's offset (cylinder or its
//!   generalisation) together with its two end vertices' offsets (spheres,
//!   disks or tori). The seed stores these as separate elliptic and circular
//!   arcs; joining each edge with its end caps makes every piece one concave
//!   arc over one interval, which the envelope step relies on. A vertex
//!   shared by several kept edges is then represented several times; the
//!   envelope step recognises the copies by their feature id.

use crate::cutter::Cutter;
use interp_core::geom::GoldenBracket;

/// A point of the pass frame: `u` along the pass, `w` across, `z` up.
pub(crate) type F3 = [f64; 3];

/// The cutter in the generalised-offset form.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct CutterShape {
    /// Cylinder radius `R`.
    pub radius: f64,
    /// Corner radius `r` (R for a ball, 0 for a flat end mill).
    pub corner: f64,
    /// Flat part of the bottom, `a = R − r`.
    pub flat: f64,
    kind: ShapeKind,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum ShapeKind {
    Ball,
    Flat,
    Bull,
}

/// Iterations of the golden-section search for the bull cutter's edge
/// contact: 0.618^80 of the edge is far below f64 resolution of the result.
const GOLDEN_ITERATIONS: usize = 80;

/// The bull cutter's edge contact search stops once the height is known to
/// this (mm): far below the envelope's tolerances, well above round-off.
const BULL_VALUE_TOLERANCE: f64 = 1e-12;

/// Relative slack when a point computed on a domain boundary lands just
/// outside it by rounding.
const DOMAIN_SLACK: f64 = 1e-9;

impl CutterShape {
    pub(crate) fn new(cutter: &Cutter) -> Self {
        let radius = cutter.radius();
        let corner = cutter.corner_radius();
        let kind = match cutter {
            Cutter::Ball { .. } => ShapeKind::Ball,
            Cutter::Flat { .. } => ShapeKind::Flat,
            Cutter::Bull { .. } => ShapeKind::Bull,
        };
        let flat = if kind == ShapeKind::Ball {
            0.0
        } else {
            radius - corner
        };
        Self {
            radius,
            corner,
            flat,
            kind,
        }
    }

    /// Height of the cutter surface above its tip at radial distance `d`
    /// (clamped to the rim).
    #[inline]
    fn profile(&self, d: f64) -> f64 {
        if d <= self.flat {
            0.0
        } else {
            let x = (d - self.flat).min(self.corner);
            self.corner - (self.corner * self.corner - x * x).max(0.0).sqrt()
        }
    }

    /// XY shift and z shift from a face point to the tool tip touching it
    /// there, for an upward unit normal `n` (§4.3 eq. 1, generalised).
    pub(crate) fn face_offset(&self, n: [f64; 3]) -> ([f64; 2], f64) {
        let s = (n[0] * n[0] + n[1] * n[1]).sqrt();
        let mut t = [self.corner * n[0], self.corner * n[1]];
        if s > 0.0 && self.flat > 0.0 {
            t[0] += self.flat * n[0] / s;
            t[1] += self.flat * n[1] / s;
        }
        (t, self.corner * n[2] - self.corner)
    }
}

/// What a section value came from, so copies of one vertex offset in
/// several capsules are known to be the same curve.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(crate) enum Feature {
    Face(u32),
    Edge(u32),
    Vertex(u32),
}

/// An edge kept for the offset (convex seen from above, boundary or
/// non-manifold), in the pass frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct OffsetEdge {
    pub p0: F3,
    pub p1: F3,
    pub v0: u32,
    pub v1: u32,
}

/// One piece of the section of the offset surface by a pass plane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Piece {
    /// Start of the piece along the pass.
    pub u0: f64,
    /// End of the piece along the pass (> `u0`).
    pub u1: f64,
    pub kind: PieceKind,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum PieceKind {
    /// Offset face: tip height linear from `z0` at `u0` to `z1` at `u1`.
    Line { z0: f64, z1: f64, face: u32 },
    /// Offset edge with its end caps: index into the kept edges.
    Capsule { edge: u32 },
}

/// A face in the pass frame, ready to be sliced: the translated triangle
/// (tip positions) with its tip heights.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct OffsetFace {
    pub corners: [F3; 3],
    pub face: u32,
}

impl OffsetFace {
    pub(crate) fn new(
        corners: [F3; 3],
        up_normal: [f64; 3],
        shape: &CutterShape,
        face: u32,
    ) -> Self {
        let (t, dz) = shape.face_offset(up_normal);
        Self {
            corners: corners.map(|c| [c[0] + t[0], c[1] + t[1], c[2] + dz]),
            face,
        }
    }

    /// `w` range covered.
    pub(crate) fn w_range(&self) -> (f64, f64) {
        let w = self.corners.map(|c| c[1]);
        (w[0].min(w[1]).min(w[2]), w[0].max(w[1]).max(w[2]))
    }

    /// Section by the plane `w = w0` (§4.4.1: the triangle's three sides cut
    /// by the plane; a single touching point gives no piece).
    pub(crate) fn slice(&self, w0: f64) -> Option<Piece> {
        let mut lo = (f64::INFINITY, 0.0);
        let mut hi = (f64::NEG_INFINITY, 0.0);
        let mut add = |u: f64, z: f64| {
            if u < lo.0 {
                lo = (u, z);
            }
            if u > hi.0 {
                hi = (u, z);
            }
        };
        for k in 0..3 {
            let a = self.corners[k];
            let b = self.corners[(k + 1) % 3];
            let (da, db) = (a[1] - w0, b[1] - w0);
            if da == 0.0 && db == 0.0 {
                add(a[0], a[2]);
                add(b[0], b[2]);
            } else if (da <= 0.0 && db >= 0.0) || (da >= 0.0 && db <= 0.0) {
                let l = da / (da - db);
                add(a[0] + l * (b[0] - a[0]), a[2] + l * (b[2] - a[2]));
            }
        }
        (hi.0 > lo.0).then_some(Piece {
            u0: lo.0,
            u1: hi.0,
            kind: PieceKind::Line {
                z0: lo.1,
                z1: hi.1,
                face: self.face,
            },
        })
    }
}

impl OffsetEdge {
    /// `w` range where a pass can meet this edge's offset.
    pub(crate) fn w_range(&self, shape: &CutterShape) -> (f64, f64) {
        (
            self.p0[1].min(self.p1[1]) - shape.radius,
            self.p0[1].max(self.p1[1]) + shape.radius,
        )
    }

    /// Interval of `u` on the line `w = w0` within the cutter radius of the
    /// edge's XY shadow (a stadium), or `None`.
    pub(crate) fn slice(&self, w0: f64, shape: &CutterShape, edge: u32) -> Option<Piece> {
        let rc = shape.radius;
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for p in [self.p0, self.p1] {
            let dw = p[1] - w0;
            let h2 = rc * rc - dw * dw;
            if h2 >= 0.0 {
                let h = h2.sqrt();
                lo = lo.min(p[0] - h);
                hi = hi.max(p[0] + h);
            }
        }
        // The rectangle part: projection inside the segment, distance ≤ R.
        let du = self.p1[0] - self.p0[0];
        let dw = self.p1[1] - self.p0[1];
        let len2 = du * du + dw * dw;
        if len2 > 0.0 {
            let len = len2.sqrt();
            let mut a = f64::NEG_INFINITY;
            let mut b = f64::INFINITY;
            // cross(D, X − P0) = du (w0 − w_0) − dw (u − u_0), |·| ≤ R len.
            let c0 = du * (w0 - self.p0[1]);
            if dw != 0.0 {
                let x1 = self.p0[0] + (c0 - rc * len) / dw;
                let x2 = self.p0[0] + (c0 + rc * len) / dw;
                a = a.max(x1.min(x2));
                b = b.min(x1.max(x2));
            } else if c0.abs() > rc * len {
                a = f64::INFINITY;
            }
            // 0 ≤ (X − P0)·D ≤ len²: du (u − u_0) + dw (w0 − w_0) ∈ [0, len2].
            let e0 = dw * (w0 - self.p0[1]);
            if du != 0.0 {
                let x1 = self.p0[0] + (0.0 - e0) / du;
                let x2 = self.p0[0] + (len2 - e0) / du;
                a = a.max(x1.min(x2));
                b = b.min(x1.max(x2));
            } else if e0 < 0.0 || e0 > len2 {
                a = f64::INFINITY;
            }
            if a < b {
                lo = lo.min(a);
                hi = hi.max(b);
            }
        }
        (hi > lo).then_some(Piece {
            u0: lo,
            u1: hi,
            kind: PieceKind::Capsule { edge },
        })
    }

    /// An upper bound of the tip height against this edge over the stretch
    /// `u ∈ [s, t]` of the pass `w`, without solving the contact: the tip is
    /// never above the highest point it touches, lowered by the cutter
    /// profile at the smallest XY distance between the stretch and the edge.
    pub(crate) fn upper_bound(&self, s: f64, t: f64, w: f64, shape: &CutterShape) -> f64 {
        let (a, b) = (self.p0, self.p1);
        // Squared distance from a point to the stretch (a horizontal segment).
        let to_stretch = |p: F3| {
            let du = if p[0] < s {
                s - p[0]
            } else if p[0] > t {
                p[0] - t
            } else {
                0.0
            };
            du * du + (p[1] - w) * (p[1] - w)
        };
        let d = [b[0] - a[0], b[1] - a[1]];
        let dd = d[0] * d[0] + d[1] * d[1];
        // Squared distance from a stretch end to the edge's XY shadow.
        let to_edge = |u: f64| {
            let l = if dd > 0.0 {
                (((u - a[0]) * d[0] + (w - a[1]) * d[1]) / dd).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let (x, y) = (a[0] + l * d[0] - u, a[1] + l * d[1] - w);
            x * x + y * y
        };
        let (da, db) = (a[1] - w, b[1] - w);
        let crosses = (da <= 0.0 && db >= 0.0 || da >= 0.0 && db <= 0.0) && {
            if da == db {
                a[0].min(b[0]) <= t && a[0].max(b[0]) >= s
            } else {
                (s..=t).contains(&(a[0] + da / (da - db) * d[0]))
            }
        };
        let dmin = if crosses {
            0.0
        } else {
            let r2 = shape.radius * shape.radius * (1.0 + DOMAIN_SLACK);
            let d2 = to_stretch(a)
                .min(to_stretch(b))
                .min(to_edge(s))
                .min(to_edge(t));
            if d2 > r2 {
                return f64::NEG_INFINITY;
            }
            d2.sqrt()
        };
        // Slightly below the exact profile so round-off never makes it a
        // lower value than an exact evaluation.
        a[2].max(b[2]) - shape.profile(dmin) * (1.0 - DOMAIN_SLACK)
    }

    /// Tool-tip height at `(u, w)` against the edge and its two ends, and the
    /// feature touched; `NEG_INFINITY` when out of reach.
    pub(crate) fn drop_at(&self, u: f64, w: f64, shape: &CutterShape, edge: u32) -> (f64, Feature) {
        match shape.kind {
            ShapeKind::Ball => self.drop_ball(u, w, shape.radius, edge),
            ShapeKind::Flat => self.drop_flat(u, w, shape.radius, edge),
            ShapeKind::Bull => self.drop_bull(u, w, shape, edge),
        }
    }

    fn drop_ball(&self, u: f64, w: f64, r: f64, edge: u32) -> (f64, Feature) {
        let r2 = r * r;
        let mut best = (f64::NEG_INFINITY, Feature::Edge(edge));
        // Vertex spheres (§4.4.3).
        for (p, v) in [(self.p0, self.v0), (self.p1, self.v1)] {
            let d2 = (u - p[0]).powi(2) + (w - p[1]).powi(2);
            if d2 <= r2 * (1.0 + DOMAIN_SLACK) {
                let z = p[2] + (r2 - d2).max(0.0).sqrt() - r;
                if z > best.0 {
                    best = (z, Feature::Vertex(v));
                }
            }
        }
        // Edge cylinder (§4.4.2): centre C = (u, w, zc) at distance R from the
        // edge's line, contact parameter inside the edge.
        let e = [
            self.p1[0] - self.p0[0],
            self.p1[1] - self.p0[1],
            self.p1[2] - self.p0[2],
        ];
        let len = (e[0] * e[0] + e[1] * e[1] + e[2] * e[2]).sqrt();
        let e = e.map(|c| c / len);
        let alpha = e[0] * e[0] + e[1] * e[1];
        if alpha > 1e-14 {
            let h = [u - self.p0[0], w - self.p0[1]];
            let k = h[0] * e[0] + h[1] * e[1];
            let beta = k * e[2];
            let gamma = h[0] * h[0] + h[1] * h[1] - k * k - r2;
            let mut disc = beta * beta - alpha * gamma;
            // On the tangent boundary of the cylinder's shadow the
            // discriminant is zero up to round-off.
            if disc < 0.0 && disc > -DOMAIN_SLACK * (beta * beta + (alpha * gamma).abs()) {
                disc = 0.0;
            }
            if disc >= 0.0 {
                let sq = disc.sqrt();
                let s = if beta >= 0.0 {
                    (beta + sq) / alpha
                } else {
                    gamma / (beta - sq)
                };
                let tau = k + s * e[2];
                if (0.0..=len).contains(&tau) {
                    let z = self.p0[2] + s - r;
                    if z > best.0 {
                        best = (z, Feature::Edge(edge));
                    }
                }
            }
        }
        best
    }

    /// Parameter range `t ∈ [0, 1]` of the edge's shadow within `rad` of
    /// `(u, w)`, or `None`.
    fn reach(&self, u: f64, w: f64, rad: f64) -> Option<(f64, f64)> {
        let d = [self.p1[0] - self.p0[0], self.p1[1] - self.p0[1]];
        let h = [u - self.p0[0], w - self.p0[1]];
        let dd = d[0] * d[0] + d[1] * d[1];
        let hh = h[0] * h[0] + h[1] * h[1];
        let r2 = rad * rad * (1.0 + DOMAIN_SLACK);
        if dd <= 1e-24 {
            return (hh <= r2).then_some((0.0, 1.0));
        }
        let hd = h[0] * d[0] + h[1] * d[1];
        let mut disc = hd * hd - dd * (hh - r2);
        if disc < 0.0 && disc > -DOMAIN_SLACK * hd * hd {
            disc = 0.0;
        }
        if disc < 0.0 {
            return None;
        }
        let sq = disc.sqrt();
        let (t1, t2) = ((hd - sq) / dd, (hd + sq) / dd);
        if t2 < 0.0 || t1 > 1.0 {
            return None;
        }
        Some((t1.max(0.0), t2.min(1.0)))
    }

    fn z_at(&self, t: f64) -> f64 {
        self.p0[2] + t * (self.p1[2] - self.p0[2])
    }

    fn feature_at(&self, t: f64, edge: u32) -> Feature {
        if t <= 0.0 {
            Feature::Vertex(self.v0)
        } else if t >= 1.0 {
            Feature::Vertex(self.v1)
        } else {
            Feature::Edge(edge)
        }
    }

    fn drop_flat(&self, u: f64, w: f64, rad: f64, edge: u32) -> (f64, Feature) {
        // The flat bottom touches where its rim crosses the edge's shadow (or
        // at an end inside the disk): the higher of the two crossings.
        let Some((t1, t2)) = self.reach(u, w, rad) else {
            return (f64::NEG_INFINITY, Feature::Edge(edge));
        };
        let (z1, z2) = (self.z_at(t1), self.z_at(t2));
        if z1 >= z2 {
            (z1, self.feature_at(t1, edge))
        } else {
            (z2, self.feature_at(t2, edge))
        }
    }

    fn drop_bull(&self, u: f64, w: f64, shape: &CutterShape, edge: u32) -> (f64, Feature) {
        let Some((t1, t2)) = self.reach(u, w, shape.radius) else {
            return (f64::NEG_INFINITY, Feature::Edge(edge));
        };
        // h(t) = z(t) − g(d(t)) is concave (z linear, g∘d convex), so a
        // golden-section search converges to its maximum; the ends are
        // checked exactly because the maximum is often at a vertex.
        let h = |t: f64| {
            let x = self.p0[0] + t * (self.p1[0] - self.p0[0]) - u;
            let y = self.p0[1] + t * (self.p1[1] - self.p0[1]) - w;
            self.z_at(t) - shape.profile((x * x + y * y).sqrt())
        };
        // The one golden-section bracket (interp_core::geom), maximising:
        // c, d its interior points, fa, fb the values at its ends.
        let mut g = GoldenBracket::new(h, t1, t2);
        let (mut fa, mut fb) = (h(t1), h(t2));
        for _ in 0..GOLDEN_ITERATIONS {
            let GoldenBracket {
                a,
                b,
                x1: c,
                x2: d,
                f1: fc,
                f2: fd,
            } = g;
            if b - a <= f64::EPSILON * 4.0 {
                break;
            }
            // A concave h lies below each secant extended beyond it: below
            // the (d, b) secant on [a, d], below the (a, c) secant on [c, b].
            // Stop once that bound on its maximum is within
            // BULL_VALUE_TOLERANCE of the best value found.
            let (s1, s2) = ((fc - fa) / (c - a), (fb - fd) / (b - d));
            let (l1, l2) = (|x: f64| fc + s1 * (x - c), |x: f64| fd + s2 * (x - d));
            let mut bound = l2(a).max(l2(c)).max(l1(d)).max(l1(b));
            if s1 > s2 {
                let x = ((fd - s2 * d) - (fc - s1 * c)) / (s1 - s2);
                if x > c && x < d {
                    bound = bound.max(l1(x));
                }
            } else {
                bound = bound.max(l1(c).min(l2(c))).max(l1(d).min(l2(d)));
            }
            let found = fc.max(fd);
            if bound - found <= BULL_VALUE_TOLERANCE {
                break;
            }
            // Towards the higher value, ties to the left: [a, d] (b = d)
            // or [c, b] (a = c).
            let left = fc >= fd;
            if left {
                fb = fd;
            } else {
                fa = fc;
            }
            g.step(left, h);
        }
        let (c, d, fc, fd) = (g.x1, g.x2, g.f1, g.f2);
        let mut best = if fc >= fd { (fc, c) } else { (fd, d) };
        for t in [t1, t2] {
            let v = h(t);
            if v >= best.0 {
                best = (v, t);
            }
        }
        (best.0, self.feature_at(best.1, edge))
    }
}
