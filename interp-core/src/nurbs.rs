//! Rational B-spline curves (NURBS) of degree 1..=5 in fixed-capacity storage.
//!
//! Evaluation follows Piegl & Tiller, *The NURBS Book*: A2.1 (span), A2.2
//! with the derivative recurrence (eq. 2.9, as A2.3), A3.2 on the homogeneous
//! curve and A4.2 for the rational derivatives. Long program curves are cut
//! into bounded segments that are the same curve (knot insertion), outside the
//! real-time path.

use crate::geom::{Curve, Derivs, Vec3};
use nalgebra::Rotation3;

/// Highest degree accepted (order 6).
pub const MAX_DEGREE: usize = 5;
/// Control points one segment can hold. Program curves with more are split.
pub const MAX_CTRL: usize = 32;
/// Knots one segment can hold.
pub const MAX_KNOTS: usize = MAX_CTRL + MAX_DEGREE + 1;

/// Which input field a [`NurbsError::NonFinite`] refers to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum NurbsField {
    /// A control point coordinate.
    ControlPoint,
    /// A weight.
    Weight,
    /// A knot.
    Knot,
}

/// Why a NURBS was refused. Each variant names the offending item.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum NurbsError {
    /// Degree outside 1..=MAX_DEGREE.
    Degree {
        /// The degree asked for.
        degree: usize,
    },
    /// Fewer than degree + 1 control points.
    TooFewControlPoints {
        /// Control points given.
        count: usize,
        /// The degree asked for.
        degree: usize,
    },
    /// More control points than the segment capacity (split first).
    TooManyControlPoints {
        /// Control points given (or that an operation would produce).
        count: usize,
        /// The most one segment holds.
        capacity: usize,
    },
    /// weights.len() differs from the control point count.
    WeightCount {
        /// One weight per control point.
        expected: usize,
        /// Weights given.
        found: usize,
    },
    /// knots.len() != n + p + 2 (n + 1 control points, degree p).
    KnotCount {
        /// Control points + degree + 1.
        expected: usize,
        /// Knots given.
        found: usize,
    },
    /// knots[index] < knots[index - 1].
    DecreasingKnot {
        /// Index of the smaller knot.
        index: usize,
    },
    /// A knot strictly inside has multiplicity above the degree, or the range is empty.
    KnotMultiplicity {
        /// Index of the knot that is one repetition too many (or would be).
        index: usize,
    },
    /// The first p + 1 knots are not equal.
    UnclampedStart,
    /// The last p + 1 knots are not equal.
    UnclampedEnd,
    /// NaN or infinity in a field.
    NonFinite {
        /// Which input slice.
        field: NurbsField,
        /// Index in that slice (the point's index for a coordinate).
        index: usize,
    },
    /// weights[index] <= 0.
    NonPositiveWeight {
        /// Index of the weight.
        index: usize,
    },
    /// The curve stands still over the whole knot span starting at knots[span]:
    /// the span's control points coincide, so it has no length (a segment may not
    /// hold one; [`split_program_curve`] leaves such spans out, and refuses only a
    /// curve that is all one point). Isolated parameters where |C'| = 0 are fine.
    ZeroSpeed {
        /// Index of the knot that starts the span.
        span: usize,
        /// The span's first parameter.
        u: f64,
    },
    /// The speed is not a number in the knot span starting at knots[span]
    /// (coordinates or weights so large that the homogeneous form overflows).
    Overflow {
        /// Index of the knot that starts the span.
        span: usize,
        /// Parameter where it was found.
        u: f64,
    },
    /// A parameter for knot insertion or splitting is not strictly inside the range, or NaN.
    ParameterOutOfRange {
        /// The parameter given.
        u: f64,
    },
}

impl core::fmt::Display for NurbsField {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            NurbsField::ControlPoint => "control point",
            NurbsField::Weight => "weight",
            NurbsField::Knot => "knot",
        })
    }
}

impl core::fmt::Display for NurbsError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            NurbsError::Degree { degree } => {
                write!(f, "NURBS degree {degree} is outside 1..={MAX_DEGREE}")
            }
            NurbsError::TooFewControlPoints { count, degree } => write!(
                f,
                "{count} control points are too few for degree {degree} (at least {} needed)",
                degree.saturating_add(1)
            ),
            NurbsError::TooManyControlPoints { count, capacity } => write!(
                f,
                "{count} control points exceed the segment capacity of {capacity}; \
                 split the curve first"
            ),
            NurbsError::WeightCount { expected, found } => write!(
                f,
                "expected {expected} weights (one per control point), found {found}"
            ),
            NurbsError::KnotCount { expected, found } => write!(
                f,
                "expected {expected} knots (control points + degree + 1), found {found}"
            ),
            NurbsError::DecreasingKnot { index } => write!(
                f,
                "knot {index} is smaller than knot {}",
                index.saturating_sub(1)
            ),
            NurbsError::KnotMultiplicity { index } => write!(
                f,
                "knot {index} repeats an interior knot more often than the degree, \
                 or leaves an empty parameter range"
            ),
            NurbsError::UnclampedStart => f.write_str(
                "the first degree + 1 knots are not equal (curve not clamped at its start)",
            ),
            NurbsError::UnclampedEnd => f.write_str(
                "the last degree + 1 knots are not equal (curve not clamped at its end)",
            ),
            NurbsError::NonFinite { field, index } => write!(f, "{field} {index} is not finite"),
            NurbsError::NonPositiveWeight { index } => write!(f, "weight {index} is not positive"),
            NurbsError::ZeroSpeed { span, u } => write!(
                f,
                "the curve stands still (its control points coincide) over the knot span \
                 starting at knot {span} (u = {u})"
            ),
            NurbsError::Overflow { span, u } => write!(
                f,
                "the curve's speed overflows at u = {u} in the knot span starting at knot {span}"
            ),
            NurbsError::ParameterOutOfRange { u } => write!(
                f,
                "parameter {u} is not strictly inside the curve's parameter range"
            ),
        }
    }
}

impl core::error::Error for NurbsError {}

/// Relative resolution of "the curve stands still here". With `scale` = the
/// diagonal of the bounding box of a span's control points plus twice their
/// largest coordinate (rounding grows with the coordinates), a span whose
/// control points lie within `ZERO_SPEED_REL_TOL · scale` of each other stands
/// still, and the curve is *stationary* at a parameter of the span where
/// `|C'| <= ZERO_SPEED_REL_TOL · scale / (span length)` (see
/// [`Nurbs::for_each_stationary`]).
pub const ZERO_SPEED_REL_TOL: f64 = 1e-12;

/// Rows/columns of the per-span basis tables.
const D1: usize = MAX_DEGREE + 1;
/// Interior samples per span of the overflow check and of the search for
/// stationary points (the span ends are checked too).
const ZERO_SPEED_SAMPLES: usize = 5;
/// Golden-section steps refining a sampled minimum of the speed (the bracket
/// shrinks by 0.618 each: to ~1e-13 of the span).
const STATIONARY_ITERS: usize = 64;

/// Which side of a parameter: the polynomial piece before it or after it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Side {
    /// The curve arriving at the parameter (the span that ends there).
    Before,
    /// The curve leaving the parameter (the span that starts there).
    After,
}

/// `(stands still, speed floor)` of a span of `points` over `[ka, kb]`: see
/// [`ZERO_SPEED_REL_TOL`].
fn span_resolution(points: impl Iterator<Item = [f64; 3]>, ka: f64, kb: f64) -> (bool, f64) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    let mut big = 0.0f64;
    for pt in points {
        for c in 0..3 {
            lo[c] = lo[c].min(pt[c]);
            hi[c] = hi[c].max(pt[c]);
            big = big.max(libm::fabs(pt[c]));
        }
    }
    let (dx, dy, dz) = (hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]);
    let extent = libm::sqrt(dx * dx + dy * dy + dz * dz);
    let scale = extent + 2.0 * big;
    (
        extent.is_finite() && extent <= ZERO_SPEED_REL_TOL * scale,
        ZERO_SPEED_REL_TOL * scale / (kb - ka),
    )
}
/// Working capacity for knot insertion: one segment plus room to clamp both its ends.
const WORK_CTRL: usize = MAX_CTRL + 2 * MAX_DEGREE;
/// Knots of the working capacity.
const WORK_KNOTS: usize = WORK_CTRL + MAX_DEGREE + 1;
/// Spans a hinted span search walks before it falls back to bisection.
const HINT_WALK: usize = 4;
/// Bisection depth limit of [`Nurbs::arc_length`]: bounds the work (and the stack)
/// even when the tolerance cannot be met.
const ARC_MAX_DEPTH: usize = 16;
/// Below this relative difference the Gauss/Kronrod estimates only differ by rounding,
/// so bisecting further cannot help.
const ARC_REL_FLOOR: f64 = 8.0 * f64::EPSILON;

// Gauss–Kronrod 7/15 nodes and weights, as published with QUADPACK (dqk15).
#[allow(clippy::excessive_precision)]
const GK_X: [f64; 8] = [
    0.991455371120812639206854697526329,
    0.949107912342758524526189684047851,
    0.864864423359769072789712788640926,
    0.741531185599394439863864773280788,
    0.586087235467691130294144845693013,
    0.405845151377397166906606412076961,
    0.207784955007898467600689403773245,
    0.0,
];
#[allow(clippy::excessive_precision)]
const GK_WK: [f64; 8] = [
    0.022935322010529224963732008058970,
    0.063092092629978553290700663189204,
    0.104790010322250183839876322541518,
    0.140653259715525918745189590510238,
    0.169004726639267902826583426598550,
    0.190350578064785409913256402421014,
    0.204432940075298892414161999234649,
    0.209482141084727828012999174891714,
];
/// Gauss weights for the nodes GK_X[1], GK_X[3], GK_X[5] and the centre.
#[allow(clippy::excessive_precision)]
const GK_WG: [f64; 4] = [
    0.129484966168869693270611432679082,
    0.279705391489276667901467771423780,
    0.381830050505118944950369775488975,
    0.417959183673469387755102040816327,
];

/// Fixed-capacity rational B-spline curve, clamped, degree 1..=5.
///
/// Invariants (established by [`Nurbs::new`] and kept by every operation): the knot
/// vector is clamped, non-decreasing, interior knots lie strictly inside the range with
/// multiplicity at most the degree, and all weights are positive.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Nurbs {
    degree: u8,
    n_ctrl: u16,
    /// Homogeneous control points (w·x, w·y, w·z, w).
    ctrl: [[f64; 4]; MAX_CTRL],
    knots: [f64; MAX_KNOTS],
    /// The first control point as given: dividing w·P by w may not give P back exactly.
    start: Vec3,
    /// The last control point as given, for the same reason.
    end: Vec3,
}

/// Homogeneous form of a Cartesian point with weight `w`.
#[inline]
fn homog(pt: &[f64; 3], w: f64) -> [f64; 4] {
    [pt[0] * w, pt[1] * w, pt[2] * w, w]
}

/// Cartesian form of a homogeneous point.
#[inline]
fn cartesian(h: &[f64; 4]) -> Vec3 {
    Vec3::new(h[0] / h[3], h[1] / h[3], h[2] / h[3])
}

/// Non-zero basis functions of degree `P` and their first derivatives at `u`: the hot
/// path (position and tangent), with small arrays that stay in registers.
///
/// `kn` holds `knots[span + 1 - P..span + 1 + P]`, so `kn[P - 1] < kn[P]` bound the span;
/// `u` may lie outside it (the span's polynomial is extended), which the one-sided
/// checks use. The triangle is A2.2; the derivative falls out of its last level as
/// `N'_r = P·(t_{r-1} - t_r)`. Reciprocal-then-product as in [`basis_ders`], so both
/// give bit-identical values and first derivatives.
#[inline(always)]
fn basis_d1<const P: usize>(kn: &[f64], u: f64) -> ([f64; D1], [f64; D1]) {
    let kn = &kn[..2 * P];
    // left[j] = u - U[span - j], right[j] = U[span + 1 + j] - u (the book's j + 1).
    let mut left = [0.0f64; P];
    let mut right = [0.0f64; P];
    for j in 0..P {
        left[j] = u - kn[P - 1 - j];
        right[j] = kn[P + j] - u;
    }
    // Degree P - 1 basis.
    let mut nb = [0.0f64; P];
    nb[0] = 1.0;
    for j in 1..P {
        let mut saved = 0.0;
        for r in 0..j {
            // The denominator is a knot difference: it does not wait for u.
            let temp = nb[r] * (1.0 / (kn[P + r] - kn[P - j + r]));
            nb[r] = saved + right[r] * temp;
            saved = left[j - r - 1] * temp;
        }
        nb[j] = saved;
    }
    let mut n0 = [0.0f64; D1];
    let mut n1 = [0.0f64; D1];
    let pf = P as f64;
    let mut saved = 0.0;
    let mut prev = 0.0;
    for r in 0..P {
        let temp = nb[r] * (1.0 / (kn[P + r] - kn[r]));
        n0[r] = saved + right[r] * temp;
        saved = left[P - r - 1] * temp;
        n1[r] = pf * (prev - temp);
        prev = temp;
    }
    n0[P] = saved;
    n1[P] = pf * prev;
    (n0, n1)
}

/// Non-zero basis functions of degree `P` and their derivatives up to `n` (<= P, <= 3)
/// at `u`; `ders[k][j]` is the k-th derivative of `N_{span-P+j,P}`. `kn` as in
/// [`basis_d1`].
///
/// Keeps every level of the A2.2 triangle and differentiates upwards with
/// `N'_{i,j} = j·(N_{i,j-1}/(U_{i+j}-U_i) - N_{i+1,j-1}/(U_{i+j+1}-U_{i+1}))` (the book's
/// eq. 2.9, which A2.3 rearranges). The triangle and the last level's first derivative
/// use exactly the operations of [`basis_d1`].
#[inline(always)]
fn basis_ders<const P: usize>(kn: &[f64], u: f64, n: usize) -> [[f64; D1]; 4] {
    let kn = &kn[..2 * P];
    let mut left = [0.0f64; P];
    let mut right = [0.0f64; P];
    for j in 0..P {
        left[j] = u - kn[P - 1 - j];
        right[j] = kn[P + j] - u;
    }
    // inv[j][r] = 1 / (U_{span+1+r} - U_{span+1-j+r}): the denominators of level j.
    let mut inv = [[0.0f64; D1]; D1];
    // tri[j][r] = N_{span-j+r, j}.
    let mut tri = [[0.0f64; D1]; D1];
    tri[0][0] = 1.0;
    for j in 1..=P {
        let mut saved = 0.0;
        for r in 0..j {
            let iv = 1.0 / (kn[P + r] - kn[P - j + r]);
            inv[j][r] = iv;
            let temp = tri[j - 1][r] * iv;
            tri[j][r] = saved + right[r] * temp;
            saved = left[j - r - 1] * temp;
        }
        tri[j][j] = saved;
    }
    let mut ders = [[0.0f64; D1]; 4];
    ders[0] = tri[P];
    // Constant trip counts let the loops unroll; n <= P keeps P - k in range.
    for k in 1..=3 {
        if k > n {
            break;
        }
        // k-th derivatives climb from level P - k, where they are the plain values.
        let mut d = tri[P - k];
        for j in P - k + 1..=P {
            let jf = j as f64;
            let mut next = [0.0f64; D1];
            let mut prev = 0.0;
            for r in 0..j {
                let cur = d[r] * inv[j][r];
                next[r] = jf * (prev - cur);
                prev = cur;
            }
            next[j] = jf * prev;
            d = next;
        }
        ders[k] = d;
    }
    ders
}

/// Rational derivatives up to `order` (capped at 3) of the span `span`, whose `p + 1`
/// homogeneous control points are `cps` (A3.2 on the homogeneous curve, then A4.2).
#[inline]
fn eval_core(
    p: usize,
    cps: &[[f64; 4]],
    knots: &[f64],
    span: usize,
    u: f64,
    order: usize,
) -> Derivs {
    // One monomorphic copy per degree; p is 1..=MAX_DEGREE by the type's invariant.
    match p {
        1 => eval_core_p::<1>(cps, knots, span, u, order),
        2 => eval_core_p::<2>(cps, knots, span, u, order),
        3 => eval_core_p::<3>(cps, knots, span, u, order),
        4 => eval_core_p::<4>(cps, knots, span, u, order),
        _ => eval_core_p::<5>(cps, knots, span, u, order),
    }
}

/// [`eval_core`] for degree `P`.
#[inline(always)]
fn eval_core_p<const P: usize>(
    cps: &[[f64; 4]],
    knots: &[f64],
    span: usize,
    u: f64,
    order: usize,
) -> Derivs {
    let order = if order > 3 { 3 } else { order };
    let cps = &cps[..=P];
    let kn = &knots[span + 1 - P..span + 1 + P];
    // A^(k) = Σ_j N^(k)_j · P^w_j, summed in the same order on both paths.
    let mut a = [[0.0f64; 4]; 4];
    if order <= 1 {
        let (n0, n1) = basis_d1::<P>(kn, u);
        for j in 0..=P {
            let cp = &cps[j];
            for c in 0..4 {
                a[0][c] += n0[j] * cp[c];
                a[1][c] += n1[j] * cp[c];
            }
        }
    } else {
        // Homogeneous derivatives above the degree vanish.
        let nd = if order < P { order } else { P };
        let ders = basis_ders::<P>(kn, u, nd);
        for k in 0..4 {
            if k > nd {
                break;
            }
            for j in 0..=P {
                let cp = &cps[j];
                for c in 0..4 {
                    a[k][c] += ders[k][j] * cp[c];
                }
            }
        }
    }

    let inv_w = 1.0 / a[0][3];
    let c0 = [a[0][0] * inv_w, a[0][1] * inv_w, a[0][2] * inv_w];
    let mut out = Derivs::ZERO;
    out.p = Vec3::new(c0[0], c0[1], c0[2]);
    if order == 0 {
        return out;
    }
    let w1 = a[1][3];
    let c1 = [
        (a[1][0] - w1 * c0[0]) * inv_w,
        (a[1][1] - w1 * c0[1]) * inv_w,
        (a[1][2] - w1 * c0[2]) * inv_w,
    ];
    out.d1 = Vec3::new(c1[0], c1[1], c1[2]);
    if order == 1 {
        return out;
    }
    let w2 = a[2][3];
    let c2 = [
        (a[2][0] - 2.0 * w1 * c1[0] - w2 * c0[0]) * inv_w,
        (a[2][1] - 2.0 * w1 * c1[1] - w2 * c0[1]) * inv_w,
        (a[2][2] - 2.0 * w1 * c1[2] - w2 * c0[2]) * inv_w,
    ];
    out.d2 = Vec3::new(c2[0], c2[1], c2[2]);
    if order == 2 {
        return out;
    }
    let w3 = a[3][3];
    let c3 = [
        (a[3][0] - 3.0 * w1 * c2[0] - 3.0 * w2 * c1[0] - w3 * c0[0]) * inv_w,
        (a[3][1] - 3.0 * w1 * c2[1] - 3.0 * w2 * c1[1] - w3 * c0[1]) * inv_w,
        (a[3][2] - 3.0 * w1 * c2[2] - 3.0 * w2 * c1[2] - w3 * c0[2]) * inv_w,
    ];
    out.d3 = Vec3::new(c3[0], c3[1], c3[2]);
    out
}

/// The non-zero B-spline basis functions of `degree` at `u` over a clamped,
/// non-decreasing knot vector `knots` (A2.1 span search, A2.2 basis):
/// returns `(span, n)` with `n[j] = N_{span−degree+j, degree}(u)` for
/// `j ∈ 0..=degree`. `u` outside the range is clamped into it (the last span
/// for the end). The same arithmetic as curve evaluation, for callers that
/// build their own systems on these functions (least-squares fitting).
///
/// Panics if `degree` is outside `1..=MAX_DEGREE` or `knots` has fewer than
/// `2·degree + 2` entries.
pub fn basis_functions(degree: usize, knots: &[f64], u: f64) -> (usize, [f64; MAX_DEGREE + 1]) {
    assert!(
        (1..=MAX_DEGREE).contains(&degree) && knots.len() >= 2 * degree + 2,
        "degree {degree} with {} knots",
        knots.len()
    );
    let p = degree;
    let n = knots.len() - p - 1;
    let (a, b) = (knots[p], knots[n]);
    let u = if u.is_nan() { a } else { u.max(a).min(b) };
    let span = if u >= b {
        // Last non-empty span.
        let mut s = n - 1;
        while s > p && knots[s] >= b {
            s -= 1;
        }
        s
    } else {
        Nurbs::bisect(knots, p, n, u)
    };
    let kn = &knots[span + 1 - p..span + 1 + p];
    let n0 = match p {
        1 => basis_d1::<1>(kn, u).0,
        2 => basis_d1::<2>(kn, u).0,
        3 => basis_d1::<3>(kn, u).0,
        4 => basis_d1::<4>(kn, u).0,
        _ => basis_d1::<5>(kn, u).0,
    };
    (span, n0)
}

/// Shared validation of [`Nurbs::new`] and [`validate_program_curve`].
/// `weights == None` means all ones; `capacity == None` means no control point
/// limit, and a program curve: spans that stand still are allowed there (the
/// split leaves them out) unless every span does.
fn validate(
    degree: usize,
    points: &[[f64; 3]],
    weights: Option<&[f64]>,
    knots: &[f64],
    capacity: Option<usize>,
) -> Result<(), NurbsError> {
    if !(1..=MAX_DEGREE).contains(&degree) {
        return Err(NurbsError::Degree { degree });
    }
    let p = degree;
    let count = points.len();
    if let Some(w) = weights
        && w.len() != count
    {
        return Err(NurbsError::WeightCount {
            expected: count,
            found: w.len(),
        });
    }
    if count < p + 1 {
        return Err(NurbsError::TooFewControlPoints { count, degree });
    }
    if let Some(capacity) = capacity
        && count > capacity
    {
        return Err(NurbsError::TooManyControlPoints { count, capacity });
    }
    let expected = count + p + 1;
    if knots.len() != expected {
        return Err(NurbsError::KnotCount {
            expected,
            found: knots.len(),
        });
    }
    if let Some(index) = points
        .iter()
        .position(|pt| !pt.iter().all(|c| c.is_finite()))
    {
        return Err(NurbsError::NonFinite {
            field: NurbsField::ControlPoint,
            index,
        });
    }
    if let Some(w) = weights
        && let Some(index) = w.iter().position(|x| !x.is_finite())
    {
        return Err(NurbsError::NonFinite {
            field: NurbsField::Weight,
            index,
        });
    }
    if let Some(index) = knots.iter().position(|x| !x.is_finite()) {
        return Err(NurbsError::NonFinite {
            field: NurbsField::Knot,
            index,
        });
    }
    if let Some(w) = weights
        && let Some(index) = w.iter().position(|&x| x <= 0.0)
    {
        return Err(NurbsError::NonPositiveWeight { index });
    }
    if let Some(index) = (1..knots.len()).find(|&i| knots[i] < knots[i - 1]) {
        return Err(NurbsError::DecreasingKnot { index });
    }
    let (a, b) = (knots[p], knots[count]);
    if knots[..p].iter().any(|&k| k != a) {
        return Err(NurbsError::UnclampedStart);
    }
    if knots[count + 1..].iter().any(|&k| k != b) {
        return Err(NurbsError::UnclampedEnd);
    }
    if a == b {
        return Err(NurbsError::KnotMultiplicity { index: count });
    }
    // Interior knots: strictly inside (else an end would be repeated more than p + 1
    // times) and repeated at most p times (else the curve may break apart there).
    let mut run = 0usize;
    let mut prev = a;
    for (i, &k) in knots.iter().enumerate().take(count).skip(p + 1) {
        if k <= a || k >= b {
            return Err(NurbsError::KnotMultiplicity { index: i });
        }
        if k == prev {
            run += 1;
        } else {
            run = 1;
            prev = k;
        }
        if run > p {
            return Err(NurbsError::KnotMultiplicity { index: i });
        }
    }
    // Spans that stand still, and speeds that overflow: the span's own
    // polynomial at both its ends and inside.
    let mut moving = 0usize;
    for span in p..count {
        let (ka, kb) = (knots[span], knots[span + 1]);
        if ka >= kb {
            continue;
        }
        let (still, _) = span_resolution(points[span - p..=span].iter().copied(), ka, kb);
        if still {
            if capacity.is_some() {
                return Err(NurbsError::ZeroSpeed { span, u: ka });
            }
            continue;
        }
        moving += 1;
        let mut cps = [[0.0f64; 4]; D1];
        for (j, cp) in cps.iter_mut().enumerate().take(p + 1) {
            let i = span - p + j;
            *cp = homog(&points[i], weights.map_or(1.0, |w| w[i]));
        }
        let steps = ZERO_SPEED_SAMPLES + 1;
        for t in 0..=steps {
            let u = span_sample(ka, kb, t, steps);
            let speed = eval_core(p, &cps[..=p], knots, span, u, 1).d1.norm();
            if !speed.is_finite() {
                return Err(NurbsError::Overflow { span, u });
            }
        }
    }
    if moving == 0 {
        return Err(NurbsError::ZeroSpeed {
            span: p,
            u: knots[p],
        });
    }
    Ok(())
}

/// Sample `t` of `0..=steps` of `[ka, kb]`, the ends exactly.
#[inline]
fn span_sample(ka: f64, kb: f64, t: usize, steps: usize) -> f64 {
    if t == 0 {
        ka
    } else if t == steps {
        kb
    } else {
        ka + (kb - ka) * (t as f64 / steps as f64)
    }
}

/// Checks a program curve of any length with the rules of [`Nurbs::new`], except the
/// segment capacity [`MAX_CTRL`].
pub fn validate_program_curve(
    degree: usize,
    points: &[[f64; 3]],
    weights: &[f64],
    knots: &[f64],
) -> Result<(), NurbsError> {
    validate(degree, points, Some(weights), knots, None)
}

impl Nurbs {
    /// All zero; only a starting value for the constructors.
    const ZEROED: Nurbs = Nurbs {
        degree: 0,
        n_ctrl: 0,
        ctrl: [[0.0; 4]; MAX_CTRL],
        knots: [0.0; MAX_KNOTS],
        start: Vec3::new(0.0, 0.0, 0.0),
        end: Vec3::new(0.0, 0.0, 0.0),
    };

    /// Validated rational curve of `degree` from Cartesian control points, their
    /// positive weights and a clamped knot vector of `points.len() + degree + 1` knots.
    ///
    /// Never panics; every defect is reported as its own [`NurbsError`] variant.
    pub fn new(
        degree: usize,
        points: &[[f64; 3]],
        weights: &[f64],
        knots: &[f64],
    ) -> Result<Self, NurbsError> {
        validate(degree, points, Some(weights), knots, Some(MAX_CTRL))?;
        Ok(Self::build(degree, points, Some(weights), knots))
    }

    /// Non-rational convenience (all weights 1).
    pub fn non_rational(
        degree: usize,
        points: &[[f64; 3]],
        knots: &[f64],
    ) -> Result<Self, NurbsError> {
        validate(degree, points, None, knots, Some(MAX_CTRL))?;
        Ok(Self::build(degree, points, None, knots))
    }

    /// Fills the storage from validated input.
    fn build(degree: usize, points: &[[f64; 3]], weights: Option<&[f64]>, knots: &[f64]) -> Self {
        let mut c = Self::ZEROED;
        let n = points.len();
        c.degree = degree as u8;
        c.n_ctrl = n as u16;
        for (i, (dst, pt)) in c.ctrl.iter_mut().zip(points).enumerate() {
            *dst = homog(pt, weights.map_or(1.0, |w| w[i]));
        }
        c.knots[..knots.len()].copy_from_slice(knots);
        c.start = Vec3::from(points[0]);
        c.end = Vec3::from(points[n - 1]);
        c
    }

    /// Degree p (1..=5).
    #[inline]
    pub fn degree(&self) -> usize {
        self.degree as usize
    }

    /// Number of control points.
    #[inline]
    pub fn control_count(&self) -> usize {
        self.n_ctrl as usize
    }

    /// Cartesian control point `i` (the first and last exactly as given).
    ///
    /// Panics if `i >= self.control_count()`.
    pub fn control_point(&self, i: usize) -> [f64; 3] {
        let n = self.control_count();
        assert!(i < n, "control point index {i} out of range 0..{n}");
        let c = if i == 0 {
            self.start
        } else if i == n - 1 {
            self.end
        } else {
            cartesian(&self.ctrl[i])
        };
        [c.x, c.y, c.z]
    }

    /// Weight of control point `i`.
    ///
    /// Panics if `i >= self.control_count()`.
    pub fn weight(&self, i: usize) -> f64 {
        let n = self.control_count();
        assert!(i < n, "weight index {i} out of range 0..{n}");
        self.ctrl[i][3]
    }

    /// The knot vector (control_count() + degree() + 1 knots).
    #[inline]
    pub fn knots(&self) -> &[f64] {
        &self.knots[..self.control_count() + self.degree() + 1]
    }

    /// A2.1 with a hint: returns the span index i with knots[i] <= u < knots[i+1]
    /// (last non-empty span for u == u_end). `hint` is the previously returned span;
    /// it and its neighbours are tried before a binary search, because the interpolator
    /// walks monotonically. Any `hint` is accepted. `u` outside the range (or NaN)
    /// gives the first or last span.
    #[inline]
    pub fn find_span(&self, u: f64, hint: usize) -> usize {
        let p = self.degree();
        let n = self.control_count();
        let k = self.knots();
        if u >= k[n] || u.is_nan() {
            return n - 1;
        }
        if u <= k[p] {
            return p;
        }
        if hint >= p && hint < n {
            let mut h = hint;
            if k[h] <= u {
                // u < k[n], so this stops at h <= n - 1.
                for _ in 0..HINT_WALK {
                    if u < k[h + 1] {
                        return h;
                    }
                    h += 1;
                }
            } else {
                // k[p] < u, so this stops at h >= p.
                for _ in 0..HINT_WALK {
                    h -= 1;
                    if k[h] <= u {
                        return h;
                    }
                }
            }
        }
        Self::bisect(k, p, n, u)
    }

    /// Span search by bisection; needs k[p] <= u < k[n].
    #[inline]
    fn bisect(k: &[f64], p: usize, n: usize, u: f64) -> usize {
        let (mut low, mut high) = (p, n);
        // Invariant k[low] <= u < k[high]: ends at a non-empty span.
        while high - low > 1 {
            let mid = (low + high) / 2;
            if u < k[mid] {
                high = mid;
            } else {
                low = mid;
            }
        }
        low
    }

    /// Span by bisection for any u (clamped as in [`Nurbs::find_span`]).
    #[inline]
    fn span_of(&self, u: f64) -> usize {
        let p = self.degree();
        let n = self.control_count();
        let k = self.knots();
        if u >= k[n] || u.is_nan() {
            n - 1
        } else if u <= k[p] {
            p
        } else {
            Self::bisect(k, p, n, u)
        }
    }

    /// Clamps u into the parameter range (NaN goes to u_start).
    #[inline]
    fn clamp_u(&self, u: f64) -> f64 {
        u.max(self.u_start()).min(self.u_end())
    }

    /// The polynomial piece of `span` at `u`.
    #[inline]
    fn eval_span(&self, u: f64, span: usize, order: usize) -> Derivs {
        let p = self.degree();
        eval_core(p, &self.ctrl[span - p..=span], &self.knots, span, u, order)
    }

    /// Evaluation at an already clamped u; the end points are returned exactly.
    #[inline]
    fn eval_clamped(&self, u: f64, span: usize, order: usize) -> Derivs {
        let mut d = self.eval_span(u, span, order);
        if u <= self.u_start() {
            d.p = self.start;
        } else if u >= self.u_end() {
            d.p = self.end;
        }
        d
    }

    /// Rational derivatives up to `order` (0..=3) at u using span hint; returns
    /// (Derivs, span). `u` is clamped to the range; pass the returned span as the next
    /// hint. Bit-identical to [`Curve::eval`] whatever the hint.
    #[inline]
    pub fn eval_with_hint(&self, u: f64, order: usize, hint: usize) -> (Derivs, usize) {
        let u = self.clamp_u(u);
        let span = self.find_span(u, hint);
        (self.eval_clamped(u, span, order), span)
    }

    /// The non-empty span whose polynomial is the curve on `side` of `u` (already
    /// clamped): before the first knot and after the last there is only one.
    fn side_span(&self, u: f64, side: Side) -> usize {
        let p = self.degree();
        let k = self.knots();
        let s = self.span_of(u);
        if side == Side::After || u <= k[p] || k[s] < u {
            return s;
        }
        // u is the knot k[s] > k[p]: the last non-empty span before it.
        let mut t = s - 1;
        while t > p && k[t] >= k[t + 1] {
            t -= 1;
        }
        t
    }

    /// Derivatives up to `order` (0..=3) at `u` of the polynomial piece on `side`
    /// of it: at a knot these are the one-sided limits ([`Curve::eval`] takes the
    /// piece after). `u` is clamped to the range.
    pub fn eval_side(&self, u: f64, order: usize, side: Side) -> Derivs {
        let u = self.clamp_u(u);
        self.eval_span(u, self.side_span(u, side), order)
    }

    /// Speed floor of `span` (see [`ZERO_SPEED_REL_TOL`]).
    fn speed_floor(&self, span: usize) -> f64 {
        let p = self.degree();
        let pts = (span - p..=span).map(|i| {
            let c = cartesian(&self.ctrl[i]);
            [c.x, c.y, c.z]
        });
        span_resolution(pts, self.knots[span], self.knots[span + 1]).1
    }

    /// Is the curve stationary (|C'| = 0, to the resolution of
    /// [`ZERO_SPEED_REL_TOL`]) at `u` on `side`? Where it is, the parametric
    /// derivatives give neither the direction nor the curvature directly: see
    /// [`Nurbs::tangent`].
    pub fn is_stationary(&self, u: f64, side: Side) -> bool {
        let u = self.clamp_u(u);
        let span = self.side_span(u, side);
        self.eval_span(u, span, 1).d1.norm() <= self.speed_floor(span)
    }

    /// Unit tangent of the curve at `u` on `side`, in the direction of travel:
    /// `C'/|C'|`, and where the curve is stationary its limit, from the first
    /// derivative that does not vanish (minus the second before a simple zero
    /// of C' and plus it after, the third around a double zero; beyond that
    /// the third a little way off, extrapolated to `u`). Where the two sides of a parameter
    /// differ the curve has a corner there, and where they are opposite, a cusp.
    pub fn tangent(&self, u: f64, side: Side) -> Vec3 {
        let u = self.clamp_u(u);
        let span = self.side_span(u, side);
        let (ka, kb) = (self.knots[span], self.knots[span + 1]);
        let h = kb - ka;
        let floor = self.speed_floor(span);
        let d = self.eval_span(u, span, 3);
        let unit = |v: Vec3| {
            let n = v.norm();
            if n > 0.0 { v / n } else { Vec3::zeros() }
        };
        if d.d1.norm() > floor {
            return unit(d.d1);
        }
        if d.d2.norm() > floor / h {
            return match side {
                Side::Before => -unit(d.d2),
                Side::After => unit(d.d2),
            };
        }
        if d.d3.norm() > floor / (h * h) {
            return unit(d.d3);
        }
        // C' vanishes to order m >= 3: near u, C''' ≈ C^(m+1)·e^(m-2)/(m-2)!
        // points the way of travel on both sides (a chord is rounding there).
        // Richardson over steps e and 2e, with the order from their ratio,
        // removes the O(e) term of the direction.
        let e = 1e-4 * h;
        let at = |x: f64| match side {
            Side::Before => self.eval_span((u - x).max(ka), span, 3).d3,
            Side::After => self.eval_span((u + x).min(kb), span, 3).d3,
        };
        let (v1, v2) = (at(e), at(2.0 * e));
        let (n1, n2) = (v1.norm(), v2.norm());
        if !(n1 > 0.0 && n2 > 0.0) {
            return unit(v2);
        }
        let k = libm::round(libm::log2(n2 / n1)).max(0.0);
        unit(v1 * 2.0 - v2 / libm::pow(2.0, k))
    }

    /// Curvature of the curve at `u` on `side` (1/mm): `|C'×C''|/|C'|³`, and
    /// where the curve is stationary its limit. Leaving a simple zero of C'
    /// (C'' ≠ 0) the curvature grows like `|C''×C'''| / (2|C''|³·|u − u₀|)`:
    /// the limit is infinite (like `1/√s` in arc length: a repeated end control
    /// point) unless C''' is parallel to C'', and then it is the next order's
    /// `|C''×C⁗| / (3|C''|³)` (C⁗ by a difference of C''' across 1e-4 of the
    /// span: the limit to about that). Where C'' vanishes too the curve leaves
    /// the point like `C'''·e³`: infinite unless C''' and C⁗ are parallel, and
    /// then this is the curvature 1e-6 of the span away on `side`.
    pub fn curvature(&self, u: f64, side: Side) -> f64 {
        let u = self.clamp_u(u);
        let span = self.side_span(u, side);
        let (ka, kb) = (self.knots[span], self.knots[span + 1]);
        let h = kb - ka;
        let floor = self.speed_floor(span);
        let d = self.eval_span(u, span, 3);
        if d.d1.norm() > floor {
            return d.curvature();
        }
        // Sines of angles below this are rounding: the vectors are parallel.
        const PARALLEL: f64 = 1e-9;
        let parallel = |a: Vec3, b: Vec3| a.cross(&b).norm() <= PARALLEL * a.norm() * b.norm();
        // A step of `frac` of the span into the piece on `side`.
        let toward = |frac: f64| match side {
            Side::Before => (u - frac * h).max(ka),
            Side::After => (u + frac * h).min(kb),
        };
        let x = toward(1e-4);
        let d4 = (self.eval_span(x, span, 3).d3 - d.d3) / (x - u);
        if d.d2.norm() > floor / h {
            if !parallel(d.d2, d.d3) {
                return f64::INFINITY;
            }
            let s2 = d.d2.norm();
            return d.d2.cross(&d4).norm() / (3.0 * s2 * s2 * s2);
        }
        if d.d3.norm() > floor / (h * h) && !parallel(d.d3, d4) {
            return f64::INFINITY;
        }
        self.eval_span(toward(1e-6), span, 2).curvature()
    }

    /// Calls `f` with every parameter strictly inside the range where the curve
    /// stops or turns back, in increasing order:
    ///
    /// - stationary points (|C'| = 0 on either side, to the resolution of
    ///   [`ZERO_SPEED_REL_TOL`]): knots where a repeated control point or a
    ///   double knot stops it, and zeros of C' inside a span (found from
    ///   samples of the speed, refined by golden-section search);
    /// - when `near > 0`, hairpins: minima of the speed where the tangent at arc
    ///   length `near` before and after points back (turns by more than 90°),
    ///   which to within `near` are cusps.
    ///
    /// The range's own ends are asked with [`Nurbs::is_stationary`].
    pub fn for_each_stationary(&self, near: f64, mut f: impl FnMut(f64)) {
        let p = self.degree();
        let n = self.control_count();
        let ua = self.u_start();
        let steps = ZERO_SPEED_SAMPLES + 1;
        let mut prev_span: Option<usize> = None;
        for span in p..n {
            let (ka, kb) = (self.knots[span], self.knots[span + 1]);
            if ka >= kb {
                continue;
            }
            let h = kb - ka;
            let floor = self.speed_floor(span);
            // The knot that starts the span, from either side, and a hairpin
            // whose tip is the knot.
            if let (true, Some(q)) = (ka > ua, prev_span) {
                let hq = ka - self.knots[q];
                let before = self.eval_span(ka, q, 1).d1.norm();
                let after = self.eval_span(ka, span, 1).d1.norm();
                let (a, b) = (ka - hq / steps as f64, ka + h / steps as f64);
                if before <= self.speed_floor(q)
                    || after <= floor
                    || (near > 0.0
                        && before.min(after) <= self.eval_span(a, q, 1).d1.norm()
                        && before.min(after) <= self.eval_span(b, span, 1).d1.norm()
                        && self.turns_back(a, ka, b, near))
                {
                    f(ka);
                }
            }
            prev_span = Some(span);
            // Zeros inside: refine each sampled local minimum of the speed that
            // could hide one (|C'| changes by at most max|C''| between samples).
            let mut speed = [0.0f64; ZERO_SPEED_SAMPLES + 2];
            let mut bend = 0.0f64;
            for (t, v) in speed.iter_mut().enumerate() {
                let d = self.eval_span(span_sample(ka, kb, t, steps), span, 2);
                *v = d.d1.norm();
                bend = bend.max(d.d2.norm());
            }
            let gap = h / steps as f64;
            let margin = 1e-9 * h;
            // Where C' vanishes to a high order at a span end, the speed stays
            // below the floor some way into the span, and the search below finds
            // "zeros" there: stops closer to a stationary end (or to the last
            // stop found) than the resolution of standing still are that one.
            let still = floor * h;
            let mut stops: [Option<Vec3>; 2] = [None, None];
            for (k, &x) in [ka, kb].iter().enumerate() {
                let d = self.eval_span(x, span, 1);
                if d.d1.norm() <= floor {
                    stops[k] = Some(d.p);
                }
            }
            let mut last = ka;
            for t in 0..=steps {
                let left = if t > 0 { speed[t - 1] } else { f64::INFINITY };
                let right = if t < steps {
                    speed[t + 1]
                } else {
                    f64::INFINITY
                };
                if !(speed[t] <= left && speed[t] <= right && speed[t] <= 2.0 * bend * gap) {
                    continue;
                }
                let a = span_sample(ka, kb, t.saturating_sub(1), steps);
                let b = span_sample(ka, kb, (t + 1).min(steps), steps);
                let (u, v2) = crate::geom::golden_section_argmin(
                    |u| self.eval_span(u, span, 1).d1.norm_squared(),
                    a,
                    b,
                    STATIONARY_ITERS,
                    0.0,
                );
                // Zeros at the span's ends are its knots (above, and the next span's).
                if !(u > ka + margin && u < kb - margin && u > last + margin) {
                    continue;
                }
                let here = self.eval_span(u, span, 0).p;
                if stops.iter().flatten().any(|q| (here - *q).norm() <= still) {
                    continue;
                }
                if libm::sqrt(v2) <= floor || (near > 0.0 && self.turns_back(a, u, b, near)) {
                    f(u);
                    last = u;
                    stops[0] = Some(here);
                }
            }
        }
    }

    /// Does the curve turn back (by more than 90°) between arc length `near`
    /// before `u` and `near` after it, looking no further than `[a, b]`?
    fn turns_back(&self, a: f64, u: f64, b: f64, near: f64) -> bool {
        let dir = |x: f64| self.tangent(x, if x < u { Side::Before } else { Side::After });
        // Cheap first: the bracket's ends point apart.
        if dir(a).dot(&dir(b)) >= 0.0 {
            return false;
        }
        // The parameter at arc length `near` from u towards `end` (or `end`).
        let reach = |end: f64| {
            if self.arc_length(u, end, 0.0).abs() <= near {
                return end;
            }
            let (mut lo, mut hi) = (u, end);
            for _ in 0..STATIONARY_ITERS {
                let mid = 0.5 * (lo + hi);
                if self.arc_length(u, mid, 0.0).abs() <= near {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            lo
        };
        dir(reach(a)).dot(&dir(reach(b))) < 0.0
    }

    /// The parameter `u ≥ u0` at arc length `ds` past `u0` (at most the range's
    /// end), to what the arithmetic resolves, and the quadrature rules spent:
    /// Newton on [`Nurbs::arc_length`] (tolerance `tol`) inside a shrinking
    /// bracket, bisecting where a Newton step leaves it. Where C' vanishes at or
    /// near `u0` (`|C'|² ≤ |C''|·ds`, a stationary point: `ds/|C'|` is infinite
    /// or far off) the first guess is the positive root of
    /// `|C''|·e²/2 + |C'|·e = ds` instead, so the inversion costs there what it
    /// costs elsewhere.
    pub fn param_at_arc_length_counted(&self, u0: f64, ds: f64, tol: f64) -> (f64, usize) {
        let u0 = self.clamp_u(u0);
        if !(ds > 0.0) {
            return (u0, 0);
        }
        let hi = self.u_end();
        let d = self.eval(u0, 2);
        let (sp, bend) = (d.d1.norm(), d.d2.norm());
        let guess = if sp * sp > bend * ds {
            ds / sp
        } else if bend > 0.0 {
            2.0 * ds / (sp + libm::sqrt(sp * sp + 2.0 * bend * ds))
        } else {
            hi - u0
        };
        crate::geom::invert_arc_length(
            u0,
            ds,
            hi,
            u0 + guess,
            |a, b| self.arc_length_counted(a, b, tol),
            |u| self.eval(u, 1).d1.norm(),
        )
    }

    /// Arc length over [ua, ub] (clamped to the range; negative if ub < ua) by adaptive
    /// Gauss–Kronrod 7/15 quadrature of |C'| per knot span, bisecting until the two
    /// rules differ by at most `tol` (absolute, mm, shared out in proportion to the
    /// parameter length). Bisection stops at depth 16 or when the rules agree to
    /// what the arithmetic resolves (see [`Nurbs::arc_length_counted`]), so a
    /// tolerance of 0 is accepted. No allocation.
    pub fn arc_length(&self, ua: f64, ub: f64, tol: f64) -> f64 {
        self.arc_length_counted(ua, ub, tol).0
    }

    /// [`Nurbs::arc_length`] and the number of Gauss–Kronrod rules it applied (15
    /// evaluations of |C'| each): the work, for tests and benchmarks that guard its
    /// growth.
    ///
    /// The two rules cannot agree better than rounding lets them: to a few ulps of
    /// the result, and to what one ulp of the parameter moves the nodes
    /// (`ulp(u)·|C'|` per node, which is what grows on long program curves whose
    /// parameters run to thousands). Bisecting below that floor only multiplies
    /// the work (up to 2^16 rules a span) without changing the result.
    pub fn arc_length_counted(&self, ua: f64, ub: f64, tol: f64) -> (f64, usize) {
        let (ua, ub) = (self.clamp_u(ua), self.clamp_u(ub));
        let (lo, hi, sign) = if ub < ua {
            (ub, ua, -1.0)
        } else {
            (ua, ub, 1.0)
        };
        if lo >= hi {
            return (0.0, 0);
        }
        let tol = if tol > 0.0 { tol } else { 0.0 };
        let total = hi - lo;
        let n = self.control_count();
        let mut sum = 0.0;
        let mut rules = 0;
        for span in self.span_of(lo)..n {
            let (ka, kb) = (self.knots[span], self.knots[span + 1]);
            if ka >= hi {
                break;
            }
            if ka >= kb {
                continue;
            }
            let (a, b) = (lo.max(ka), hi.min(kb));
            if a < b {
                let (l, r) = self.arc_length_span(span, a, b, tol * ((b - a) / total));
                sum += l;
                rules += r;
            }
        }
        (sign * sum, rules)
    }

    /// Adaptive quadrature of |C'| over [a, b] inside one span, with an explicit stack;
    /// returns the integral and the number of rules applied.
    fn arc_length_span(&self, span: usize, a: f64, b: f64, tol: f64) -> (f64, usize) {
        // Depth-first: at most one pending right half per level plus the current one.
        let mut stack = [(0.0f64, 0.0f64, 0.0f64, 0usize); ARC_MAX_DEPTH + 2];
        stack[0] = (a, b, tol, 0);
        let mut top = 1;
        let mut sum = 0.0;
        let mut rules = 0;
        while top > 0 {
            top -= 1;
            let (a, b, tol, depth) = stack[top];
            let (k, g) = self.gauss_kronrod(span, a, b);
            rules += 1;
            let diff = libm::fabs(k - g);
            // Rounding floor: a few ulps of the result, and one ulp of u times the
            // mean speed (the nodes c ± h·x are only placed to ulp(u)).
            let floor = ARC_REL_FLOOR * libm::fabs(k)
                + f64::EPSILON * libm::fabs(a).max(libm::fabs(b)) * libm::fabs(k) / (b - a);
            if diff <= tol || diff <= floor || depth >= ARC_MAX_DEPTH {
                sum += k;
            } else {
                let m = 0.5 * (a + b);
                stack[top] = (m, b, 0.5 * tol, depth + 1);
                stack[top + 1] = (a, m, 0.5 * tol, depth + 1);
                top += 2;
            }
        }
        (sum, rules)
    }

    /// (Kronrod 15-point, Gauss 7-point) estimates of ∫|C'| over [a, b] in `span`.
    fn gauss_kronrod(&self, span: usize, a: f64, b: f64) -> (f64, f64) {
        let c = 0.5 * (a + b);
        let h = 0.5 * (b - a);
        let speed = |u: f64| self.eval_span(u, span, 1).d1.norm();
        let fc = speed(c);
        let mut k = GK_WK[7] * fc;
        let mut g = GK_WG[3] * fc;
        for j in 0..7 {
            let x = h * GK_X[j];
            let f = speed(c - x) + speed(c + x);
            k += GK_WK[j] * f;
            if j % 2 == 1 {
                g += GK_WG[j / 2] * f;
            }
        }
        (k * h, g * h)
    }

    /// How many times the interior parameter `u` occurs in the knot vector
    /// (0: inside a span).
    pub fn knot_multiplicity(&self, u: f64) -> usize {
        self.multiplicity(u, self.span_of(u))
    }

    /// Multiplicity of the knot value `u` ending at index `k` (counting down).
    fn multiplicity(&self, u: f64, k: usize) -> usize {
        self.knots[..=k]
            .iter()
            .rev()
            .take_while(|&&x| x == u)
            .count()
    }

    /// Insert knot u `times` times (A5.1, in homogeneous coordinates); the geometry and
    /// the parametrisation are unchanged.
    ///
    /// `times == 0` returns the curve unchanged. Errors: `u` not strictly inside the
    /// range (or NaN) → [`NurbsError::ParameterOutOfRange`]; the multiplicity of `u`
    /// would exceed the degree (the largest an interior knot may have) →
    /// [`NurbsError::KnotMultiplicity`] with the index the new knot would get; more than
    /// [`MAX_CTRL`] control points → [`NurbsError::TooManyControlPoints`].
    pub fn insert_knot(&self, u: f64, times: usize) -> Result<Nurbs, NurbsError> {
        if !(u > self.u_start() && u < self.u_end()) {
            return Err(NurbsError::ParameterOutOfRange { u });
        }
        if times == 0 {
            return Ok(*self);
        }
        let p = self.degree();
        let n = self.control_count();
        let k = self.span_of(u);
        let s = self.multiplicity(u, k);
        if times > p - s {
            return Err(NurbsError::KnotMultiplicity { index: k + 1 });
        }
        if n + times > MAX_CTRL {
            return Err(NurbsError::TooManyControlPoints {
                count: n + times,
                capacity: MAX_CTRL,
            });
        }
        let mut w = Work::from_nurbs(self);
        w.insert(u, k, s, times)?;
        w.nurbs(self.start, self.end)
    }

    /// Split at interior u (u_start < u < u_end) into two clamped curves that are
    /// exactly the same geometry with unchanged parameters: the first over
    /// [u_start, u], the second over [u, u_end]. `u` is inserted until its
    /// multiplicity is the degree; the shared control point is bit-identical in both
    /// halves. Neither half has more control points than the original, so this only
    /// fails for `u` outside the open range ([`NurbsError::ParameterOutOfRange`]).
    pub fn split_at(&self, u: f64) -> Result<(Nurbs, Nurbs), NurbsError> {
        if !(u > self.u_start() && u < self.u_end()) {
            return Err(NurbsError::ParameterOutOfRange { u });
        }
        let p = self.degree();
        let k = self.span_of(u);
        let s = self.multiplicity(u, k);
        let mut w = Work::from_nurbs(self);
        w.insert(u, k, s, p - s)?;
        // u now occupies knots first..first + p, and C(u) is control point first - 1.
        let first = k - s + 1;
        let mid = cartesian(&w.ctrl[first - 1]);

        let mut left = Work::new(p);
        left.n = first;
        left.ctrl[..first].copy_from_slice(&w.ctrl[..first]);
        left.knots[..first + p].copy_from_slice(&w.knots[..first + p]);
        left.knots[first + p] = u;

        let mut right = Work::new(p);
        let rn = w.n - first + 1;
        right.n = rn;
        right.ctrl[..rn].copy_from_slice(&w.ctrl[first - 1..w.n]);
        right.knots[0] = u;
        right.knots[1..=rn + p].copy_from_slice(&w.knots[first..w.n + p + 1]);

        Ok((left.nurbs(self.start, mid)?, right.nurbs(mid, self.end)?))
    }

    /// Same curve traversed backwards: reversed control points/weights, knots
    /// k -> (a+b) - k reversed, so that the point at u is the original one at a+b-u.
    /// The ends of the range stay exactly a and b.
    pub fn reversed(&self) -> Nurbs {
        let mut r = *self;
        let n = self.control_count();
        let p = self.degree();
        let m = n + p + 1;
        for i in 0..n {
            r.ctrl[i] = self.ctrl[n - 1 - i];
        }
        let (a, b) = (self.u_start(), self.u_end());
        let sum = a + b;
        for i in 0..m {
            // Rounding could push a mirrored knot past an end; keep it inside.
            r.knots[i] = (sum - self.knots[m - 1 - i]).max(a).min(b);
        }
        for i in 0..=p {
            r.knots[i] = a;
            r.knots[m - 1 - i] = b;
        }
        r.start = self.end;
        r.end = self.start;
        r
    }

    /// Scaled by factor about the origin (mm <-> inch); weights and knots unchanged.
    pub fn scaled(&self, factor: f64) -> Nurbs {
        let mut r = *self;
        for h in r.ctrl.iter_mut().take(self.control_count()) {
            h[0] *= factor;
            h[1] *= factor;
            h[2] *= factor;
        }
        r.start *= factor;
        r.end *= factor;
        r
    }

    /// Turned by `rotation` about the origin; weights and knots unchanged
    /// (a rotation is linear, so it turns the homogeneous points as they are).
    pub fn rotated(&self, rotation: &Rotation3<f64>) -> Nurbs {
        let mut r = *self;
        for h in r.ctrl.iter_mut().take(self.control_count()) {
            let p = rotation * Vec3::new(h[0], h[1], h[2]);
            (h[0], h[1], h[2]) = (p.x, p.y, p.z);
        }
        r.start = rotation * self.start;
        r.end = rotation * self.end;
        r
    }

    /// Translated by `by`; weights and knots unchanged.
    pub fn translated(&self, by: Vec3) -> Nurbs {
        let mut r = *self;
        for h in r.ctrl.iter_mut().take(self.control_count()) {
            h[0] += h[3] * by.x;
            h[1] += h[3] * by.y;
            h[2] += h[3] * by.z;
        }
        r.start += by;
        r.end += by;
        r
    }
}

impl Curve for Nurbs {
    #[inline]
    fn u_start(&self) -> f64 {
        self.knots[self.degree as usize]
    }

    #[inline]
    fn u_end(&self) -> f64 {
        self.knots[self.n_ctrl as usize]
    }

    #[inline]
    fn eval(&self, u: f64, order: usize) -> Derivs {
        let u = self.clamp_u(u);
        self.eval_clamped(u, self.span_of(u), order)
    }

    #[inline]
    fn start_point(&self) -> Vec3 {
        self.start
    }

    #[inline]
    fn end_point(&self) -> Vec3 {
        self.end
    }
}

/// Homogeneous B-spline in working storage with room for knot insertion beyond
/// [`MAX_CTRL`]; the knot vector need not be clamped.
#[derive(Clone, Copy)]
struct Work {
    p: usize,
    n: usize,
    ctrl: [[f64; 4]; WORK_CTRL],
    knots: [f64; WORK_KNOTS],
}

impl Work {
    fn new(p: usize) -> Self {
        Work {
            p,
            n: 0,
            ctrl: [[0.0; 4]; WORK_CTRL],
            knots: [0.0; WORK_KNOTS],
        }
    }

    fn from_nurbs(c: &Nurbs) -> Self {
        let mut w = Work::new(c.degree());
        let n = c.control_count();
        w.n = n;
        w.ctrl[..n].copy_from_slice(&c.ctrl[..n]);
        let m = c.knots().len();
        w.knots[..m].copy_from_slice(c.knots());
        w
    }

    /// A5.1: inserts `u` `r` times, where `knots[k] <= u < knots[k + 1]`, `k >= p`,
    /// `u` already has multiplicity `s` and `s + r <= p`.
    fn insert(&mut self, u: f64, k: usize, s: usize, r: usize) -> Result<(), NurbsError> {
        if r == 0 {
            return Ok(());
        }
        let p = self.p;
        let np = self.n - 1;
        let mp = np + p + 1;
        let nq = np + r;
        if nq + 1 > WORK_CTRL {
            return Err(NurbsError::TooManyControlPoints {
                count: nq + 1,
                capacity: WORK_CTRL,
            });
        }
        let old = *self;
        let (up, pw) = (&old.knots, &old.ctrl);
        // Knots and the unaffected control points; 0..=k and 0..=k-p stay in place.
        for i in 1..=r {
            self.knots[k + i] = u;
        }
        self.knots[k + 1 + r..=mp + r].copy_from_slice(&up[k + 1..=mp]);
        self.ctrl[k - s + r..=np + r].copy_from_slice(&pw[k - s..=np]);
        let mut rw = [[0.0f64; 4]; D1];
        rw[..=p - s].copy_from_slice(&pw[k - p..=k - s]);
        let mut l = 0;
        for j in 1..=r {
            l = k - p + j;
            for i in 0..=p - j - s {
                let alpha = (u - up[l + i]) / (up[i + k + 1] - up[l + i]);
                let beta = 1.0 - alpha;
                for c in 0..4 {
                    rw[i][c] = alpha * rw[i + 1][c] + beta * rw[i][c];
                }
            }
            self.ctrl[l] = rw[0];
            self.ctrl[k + r - j - s] = rw[p - j - s];
        }
        if l + 1 < k - s {
            self.ctrl[l + 1..k - s].copy_from_slice(&rw[1..k - s - l]);
        }
        self.n = nq + 1;
        Ok(())
    }

    /// Clamps the start of the domain [knots[p], knots[n]] (needs
    /// knots[p] < knots[p + 1]): inserts knots[p] up to multiplicity p and drops the
    /// control points and knots before it.
    fn clamp_left(&mut self) -> Result<(), NurbsError> {
        let p = self.p;
        let u = self.knots[p];
        let s = self.knots[..=p]
            .iter()
            .rev()
            .take_while(|&&x| x == u)
            .count();
        if s > p {
            return Ok(());
        }
        self.insert(u, p, s, p - s)?;
        // u now sits at p - s + 1 ..= 2p - s; C(u) is control point p - s.
        let drop = p - s;
        let m = self.n + p + 1;
        self.ctrl.copy_within(drop..self.n, 0);
        self.knots.copy_within(drop..m, 0);
        self.n -= drop;
        self.knots[0] = u;
        Ok(())
    }

    /// Reverses the control points and negates and reverses the knots (exact), so
    /// that the end can be clamped like the start.
    fn reverse_negated(&mut self) {
        let m = self.n + self.p + 1;
        self.ctrl[..self.n].reverse();
        self.knots[..m].reverse();
        for k in &mut self.knots[..m] {
            *k = -*k;
        }
    }

    fn nurbs(&self, start: Vec3, end: Vec3) -> Result<Nurbs, NurbsError> {
        if self.n > MAX_CTRL {
            return Err(NurbsError::TooManyControlPoints {
                count: self.n,
                capacity: MAX_CTRL,
            });
        }
        let mut c = Nurbs::ZEROED;
        c.degree = self.p as u8;
        c.n_ctrl = self.n as u16;
        c.ctrl[..self.n].copy_from_slice(&self.ctrl[..self.n]);
        let m = self.n + self.p + 1;
        c.knots[..m].copy_from_slice(&self.knots[..m]);
        c.start = start;
        c.end = end;
        Ok(c)
    }
}

/// Why [`split_program_curve`] stopped.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SplitError<E> {
    /// The program curve is invalid.
    Invalid(NurbsError),
    /// The sink refused a segment.
    Sink(E),
}

impl<E: core::fmt::Display> core::fmt::Display for SplitError<E> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            SplitError::Invalid(e) => write!(f, "invalid NURBS: {e}"),
            SplitError::Sink(e) => write!(f, "NURBS segment refused: {e}"),
        }
    }
}

impl<E: core::fmt::Debug + core::fmt::Display> core::error::Error for SplitError<E> {}

/// Cuts a (possibly long, e.g. 500 control points) clamped NURBS given by slices into
/// consecutive segments of at most `max_ctrl` (<= MAX_CTRL - MAX_DEGREE - 1) control
/// points each, that together are exactly the same curve, calling `sink` with each in
/// order. Validates the whole input first with the same rules/errors as Nurbs::new
/// (except the capacity, and spans that stand still: see below). Cut points are
/// existing distinct interior knots.
///
/// Segments keep the original parameters (each covers [knots[s], knots[e]]), adjacent
/// segments share a bit-identical joint point, and the first and last points are
/// exactly the given ones. `max_ctrl` is clamped to `degree + 1..=MAX_CTRL` (a single
/// span needs degree + 1 points). A curve that fits is passed on as one segment.
///
/// A knot span whose control points coincide (the curve stands still there, e.g.
/// a point repeated `degree + 1` times) has no length: it is left out, the
/// segments before and after it meet at its point, and the parameters jump over
/// it. Only a curve that is all one point is refused ([`NurbsError::ZeroSpeed`]).
pub fn split_program_curve<E>(
    degree: usize,
    points: &[[f64; 3]],
    weights: &[f64],
    knots: &[f64],
    max_ctrl: usize,
    mut sink: impl FnMut(Nurbs) -> Result<(), E>,
) -> Result<(), SplitError<E>> {
    validate_program_curve(degree, points, weights, knots).map_err(SplitError::Invalid)?;
    let p = degree;
    let count = points.len();
    let max_ctrl = max_ctrl.clamp(p + 1, MAX_CTRL);
    // Last index of the run of knots equal to knots[i].
    let run_end = |mut i: usize| {
        while i + 1 < knots.len() && knots[i + 1] == knots[i] {
            i += 1;
        }
        i
    };
    // The span starting at knot index i (the last of its run) stands still.
    let still =
        |i: usize| span_resolution(points[i - p..=i].iter().copied(), knots[i], knots[i + 1]).0;
    // The first span that moves from span start i on (validation found one).
    let moving_from = |mut i: usize| {
        while i < count && still(i) {
            i = run_end(i + 1);
        }
        i
    };
    // A segment from span start s (last index of its knot value) to e (first index
    // of its value) has control points P[s-p..e], i.e. e - s + p of them.
    let mut s = moving_from(p);
    let mut joint: Option<([f64; 4], Vec3, bool)> = None;
    loop {
        let mut e = s + 1;
        while e < count {
            let next = run_end(e) + 1;
            if next - s + p > max_ctrl || still(next - 1) {
                break;
            }
            e = next;
        }
        // Where the rest stands still, the curve ends at this segment's end.
        let rest = if e < count {
            moving_from(run_end(e))
        } else {
            count
        };
        let last = rest >= count;
        let seg = program_segment(p, points, weights, knots, s, e, joint, last)
            .map_err(SplitError::Invalid)?;
        sink(seg).map_err(SplitError::Sink)?;
        if last {
            return Ok(());
        }
        // Across a span that stands still the next segment starts at the same
        // point but with its own weight there.
        let gap = rest != run_end(e);
        joint = Some((seg.ctrl[seg.control_count() - 1], seg.end, gap));
        s = rest;
    }
}

/// The piece of a validated program curve over [knots[s], knots[e]] as a clamped
/// segment: local control points and knots, both ends clamped by Boehm insertion.
/// `joint` is the previous segment's last control point (homogeneous, Cartesian, and
/// whether a span that stands still lies between), reused so that the segments meet
/// bit-identically; the first segment starts at the first given point, and the
/// `last` ends at the last given point.
#[allow(clippy::too_many_arguments)]
fn program_segment(
    p: usize,
    points: &[[f64; 3]],
    weights: &[f64],
    knots: &[f64],
    s: usize,
    e: usize,
    joint: Option<([f64; 4], Vec3, bool)>,
    last: bool,
) -> Result<Nurbs, NurbsError> {
    let count = points.len();
    let c = e - s + p;
    let mut w = Work::new(p);
    w.n = c;
    for (dst, i) in w.ctrl.iter_mut().zip(s - p..e) {
        *dst = homog(&points[i], weights[i]);
    }
    w.knots[..c + p + 1].copy_from_slice(&knots[s - p..=e + p]);
    w.clamp_left()?;
    w.reverse_negated();
    w.clamp_left()?;
    w.reverse_negated();
    let start = match joint {
        Some((h, pt, false)) => {
            w.ctrl[0] = h;
            pt
        }
        Some((_, pt, true)) => {
            w.ctrl[0] = homog(&[pt.x, pt.y, pt.z], w.ctrl[0][3]);
            pt
        }
        None => Vec3::from(points[0]),
    };
    let end = if last {
        Vec3::from(points[count - 1])
    } else {
        cartesian(&w.ctrl[w.n - 1])
    };
    w.nurbs(start, end)
}

#[cfg(test)]
mod tests {
    extern crate std;

    use super::*;
    use core::f64::consts::{FRAC_1_SQRT_2, PI};
    use nalgebra::Vector3;
    use std::string::ToString;
    use std::vec::Vec;

    /// Deterministic xorshift64* so that failures reproduce.
    struct Rng(u64);
    impl Rng {
        fn next_u64(&mut self) -> u64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
        }
        /// True with probability 1/n.
        fn one_in(&mut self, n: u64) -> bool {
            self.next_u64().is_multiple_of(n)
        }
        /// Uniform in [lo, hi).
        fn range(&mut self, lo: f64, hi: f64) -> f64 {
            lo + (hi - lo) * ((self.next_u64() >> 11) as f64 / (1u64 << 53) as f64)
        }
    }

    /// Clamped knots over [0, 1] with well separated random interior knots.
    fn random_knots(rng: &mut Rng, p: usize, count: usize) -> Vec<f64> {
        let interior = count - p - 1;
        let mut k = Vec::new();
        k.extend(core::iter::repeat_n(0.0, p + 1));
        for i in 1..=interior {
            let base = i as f64 / (interior + 1) as f64;
            k.push(base + rng.range(-0.3, 0.3) / (interior + 1) as f64);
        }
        k.extend(core::iter::repeat_n(1.0, p + 1));
        k
    }

    struct Raw {
        p: usize,
        pts: Vec<[f64; 3]>,
        w: Vec<f64>,
        k: Vec<f64>,
    }

    fn random_raw(rng: &mut Rng, p: usize, count: usize) -> Raw {
        let pts = (0..count)
            .map(|_| {
                [
                    rng.range(-10.0, 10.0),
                    rng.range(-10.0, 10.0),
                    rng.range(-10.0, 10.0),
                ]
            })
            .collect();
        let w = (0..count).map(|_| rng.range(0.5, 2.0)).collect();
        let k = random_knots(rng, p, count);
        Raw { p, pts, w, k }
    }

    fn random_curve(rng: &mut Rng, p: usize, count: usize) -> Nurbs {
        let r = random_raw(rng, p, count);
        Nurbs::new(p, &r.pts, &r.w, &r.k).unwrap()
    }

    /// Reference evaluation of a program curve of any length.
    fn eval_raw(r: &Raw, u: f64, order: usize) -> Derivs {
        let (p, n) = (r.p, r.pts.len());
        let span = if u >= r.k[n] {
            n - 1
        } else {
            Nurbs::bisect(&r.k, p, n, u.max(r.k[p]))
        };
        let mut cps = [[0.0; 4]; D1];
        for j in 0..=p {
            cps[j] = homog(&r.pts[span - p + j], r.w[span - p + j]);
        }
        eval_core(p, &cps[..=p], &r.k, span, u, order)
    }

    fn unit_circle() -> Nurbs {
        let h = FRAC_1_SQRT_2;
        let pts = [
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
            [-1.0, 1.0, 0.0],
            [-1.0, 0.0, 0.0],
            [-1.0, -1.0, 0.0],
            [0.0, -1.0, 0.0],
            [1.0, -1.0, 0.0],
            [1.0, 0.0, 0.0],
        ];
        let w = [1.0, h, 1.0, h, 1.0, h, 1.0, h, 1.0];
        let k = [
            0.0, 0.0, 0.0, 0.25, 0.25, 0.5, 0.5, 0.75, 0.75, 1.0, 1.0, 1.0,
        ];
        Nurbs::new(2, &pts, &w, &k).unwrap()
    }

    fn dist(a: Vec3, b: Vec3) -> f64 {
        (a - b).norm()
    }

    const LINE4: [[f64; 3]; 4] = [[0.0; 3], [1.0, 0.0, 0.0], [2.0, 1.0, 0.0], [3.0, 1.0, 1.0]];
    const BEZ3: [f64; 8] = [0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0];
    const ONES4: [f64; 4] = [1.0; 4];

    #[test]
    fn basis_functions_sum_to_one_and_rebuild_the_curve() {
        let pts = [
            [0.0, 0.0, 0.0],
            [1.0, 2.0, 0.0],
            [3.0, 2.5, 1.0],
            [4.0, 0.0, 0.5],
            [6.0, 1.0, 0.0],
        ];
        let knots = [0.0, 0.0, 0.0, 0.0, 0.4, 1.0, 1.0, 1.0, 1.0];
        let c = Nurbs::non_rational(3, &pts, &knots).unwrap();
        for i in 0..=20 {
            let u = i as f64 / 20.0;
            let (span, n) = basis_functions(3, &knots, u);
            assert!((n[..4].iter().sum::<f64>() - 1.0).abs() < 1e-14);
            let mut p = Vec3::zeros();
            for j in 0..=3 {
                p += Vec3::from(pts[span - 3 + j]) * n[j];
            }
            assert!((p - c.eval(u, 0).p).norm() < 1e-14, "u {u}");
        }
        // Outside the range: clamped to the ends.
        assert_eq!(basis_functions(3, &knots, 2.0).1[3], 1.0);
        assert_eq!(basis_functions(3, &knots, -1.0).1[0], 1.0);
    }

    #[test]
    fn every_error_variant() {
        use NurbsError as E;
        let e = |d, p: &[[f64; 3]], w: &[f64], k: &[f64]| Nurbs::new(d, p, w, k).unwrap_err();
        assert_eq!(e(0, &LINE4, &ONES4, &BEZ3), E::Degree { degree: 0 });
        assert_eq!(e(6, &LINE4, &ONES4, &BEZ3), E::Degree { degree: 6 });
        assert_eq!(
            e(3, &[], &[], &[]),
            E::TooFewControlPoints {
                count: 0,
                degree: 3
            }
        );
        assert_eq!(
            e(3, &LINE4[..3], &ONES4[..3], &BEZ3[..7]),
            E::TooFewControlPoints {
                count: 3,
                degree: 3
            }
        );
        let many = [[0.0; 3]; 1000];
        let many_w = [1.0; 1000];
        assert_eq!(
            e(3, &many, &many_w, &[]),
            E::TooManyControlPoints {
                count: 1000,
                capacity: MAX_CTRL
            }
        );
        assert_eq!(
            e(3, &LINE4, &ONES4[..3], &BEZ3),
            E::WeightCount {
                expected: 4,
                found: 3
            }
        );
        assert_eq!(
            e(3, &LINE4, &ONES4, &BEZ3[..7]),
            E::KnotCount {
                expected: 8,
                found: 7
            }
        );

        let mut p = LINE4;
        p[2][1] = f64::NAN;
        let field = NurbsField::ControlPoint;
        assert_eq!(e(3, &p, &ONES4, &BEZ3), E::NonFinite { field, index: 2 });
        let mut w = ONES4;
        w[1] = f64::INFINITY;
        let field = NurbsField::Weight;
        assert_eq!(e(3, &LINE4, &w, &BEZ3), E::NonFinite { field, index: 1 });
        let mut k = BEZ3;
        k[7] = f64::NEG_INFINITY;
        let field = NurbsField::Knot;
        assert_eq!(e(3, &LINE4, &ONES4, &k), E::NonFinite { field, index: 7 });
        w[1] = 0.0;
        assert_eq!(e(3, &LINE4, &w, &BEZ3), E::NonPositiveWeight { index: 1 });
        w[1] = -1.0;
        assert_eq!(e(3, &LINE4, &w, &BEZ3), E::NonPositiveWeight { index: 1 });

        let k = [0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 0.5, 1.0];
        assert_eq!(e(3, &LINE4, &ONES4, &k), E::DecreasingKnot { index: 6 });
        let k = [-1.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0];
        assert_eq!(e(3, &LINE4, &ONES4, &k), E::UnclampedStart);
        let k = [0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 2.0];
        assert_eq!(e(3, &LINE4, &ONES4, &k), E::UnclampedEnd);
        // Empty range.
        let k = [1.0; 8];
        assert_eq!(e(3, &LINE4, &ONES4, &k), E::KnotMultiplicity { index: 4 });
        // Interior knot repeated degree + 1 times (linear: twice).
        let k = [0.0, 0.0, 0.5, 0.5, 1.0, 1.0];
        assert_eq!(e(1, &LINE4, &ONES4, &k), E::KnotMultiplicity { index: 3 });
        // Interior knot equal to the start.
        let k = [0.0, 0.0, 0.0, 0.5, 1.0, 1.0];
        assert_eq!(e(1, &LINE4, &ONES4, &k), E::KnotMultiplicity { index: 2 });

        // Two coincident control points at the clamped start or end: C' = 0 there,
        // a curve like any other.
        for (a, b) in [(1, 0), (2, 3)] {
            let mut p = LINE4;
            p[a] = p[b];
            assert!(Nurbs::new(3, &p, &ONES4, &BEZ3).is_ok());
        }
        // A span whose control points all coincide stands still: no segment may
        // hold one (and a program curve may not be all one).
        let p = [[1.0, 2.0, 3.0]; 4];
        assert_eq!(e(3, &p, &ONES4, &BEZ3), E::ZeroSpeed { span: 3, u: 0.0 });
        assert_eq!(
            validate_program_curve(3, &p, &ONES4, &BEZ3).unwrap_err(),
            E::ZeroSpeed { span: 3, u: 0.0 }
        );
        // A linear span whose two points coincide.
        let p = [[0.0; 3], [1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]];
        let k = [0.0, 0.0, 0.3, 0.6, 1.0, 1.0];
        assert_eq!(e(1, &p, &ONES4, &k), E::ZeroSpeed { span: 2, u: 0.3 });
        assert!(validate_program_curve(1, &p, &ONES4, &k).is_ok());
        // Homogeneous coordinates that overflow.
        let p = [
            [1e300, 0.0, 0.0],
            [-1e300, 1e300, 0.0],
            [1e300, 1.0, 0.0],
            [0.0; 3],
        ];
        let heavy = [1e10; 4];
        assert!(matches!(
            e(3, &p, &heavy, &BEZ3),
            E::Overflow { span: 3, .. }
        ));

        let c = Nurbs::non_rational(3, &LINE4, &BEZ3).unwrap();
        let out = E::ParameterOutOfRange { u: 0.0 };
        assert_eq!(c.split_at(0.0).unwrap_err(), out);
        assert_eq!(c.insert_knot(0.0, 1).unwrap_err(), out);
        assert!(matches!(
            c.split_at(f64::NAN),
            Err(E::ParameterOutOfRange { .. })
        ));
        assert!(matches!(
            c.insert_knot(1.5, 1),
            Err(E::ParameterOutOfRange { .. })
        ));
        assert_eq!(
            c.insert_knot(0.5, 4).unwrap_err(),
            E::KnotMultiplicity { index: 4 }
        );
        let mut rng = Rng(7);
        let full = random_curve(&mut rng, 3, MAX_CTRL);
        assert_eq!(
            full.insert_knot(0.123, 1).unwrap_err(),
            E::TooManyControlPoints {
                count: MAX_CTRL + 1,
                capacity: MAX_CTRL
            }
        );

        // non_rational and validate_program_curve share the rules.
        assert_eq!(
            Nurbs::non_rational(3, &many, &[]).unwrap_err(),
            E::TooManyControlPoints {
                count: 1000,
                capacity: MAX_CTRL
            }
        );
        assert_eq!(
            validate_program_curve(3, &many, &many_w, &[]).unwrap_err(),
            E::KnotCount {
                expected: 1004,
                found: 0
            }
        );
        let r = split_program_curve::<()>(3, &LINE4, &w, &BEZ3, 10, |_| Ok(()));
        assert_eq!(
            r,
            Err(SplitError::Invalid(E::NonPositiveWeight { index: 1 }))
        );
    }

    #[test]
    fn display_names_the_item() {
        let msg = |e: NurbsError| e.to_string();
        assert!(msg(NurbsError::DecreasingKnot { index: 6 }).contains("knot 6"));
        assert!(msg(NurbsError::NonPositiveWeight { index: 3 }).contains("weight 3"));
        let m = msg(NurbsError::NonFinite {
            field: NurbsField::ControlPoint,
            index: 9,
        });
        assert!(m.contains("control point 9"), "{m}");
        let m = msg(NurbsError::ZeroSpeed { span: 4, u: 0.5 });
        assert!(m.contains("knot 4") && m.contains("0.5"), "{m}");
        let m = msg(NurbsError::Overflow { span: 4, u: 0.5 });
        assert!(m.contains("knot 4") && m.contains("0.5"), "{m}");
        let m = msg(NurbsError::KnotCount {
            expected: 8,
            found: 7,
        });
        assert!(m.contains('8') && m.contains('7'), "{m}");
        for e in [
            NurbsError::Degree { degree: 9 },
            NurbsError::TooFewControlPoints {
                count: 1,
                degree: 3,
            },
            NurbsError::TooManyControlPoints {
                count: 40,
                capacity: 32,
            },
            NurbsError::WeightCount {
                expected: 4,
                found: 2,
            },
            NurbsError::KnotMultiplicity { index: 5 },
            NurbsError::UnclampedStart,
            NurbsError::UnclampedEnd,
            NurbsError::ParameterOutOfRange { u: 2.0 },
            NurbsError::DecreasingKnot { index: 0 },
        ] {
            assert!(!msg(e).is_empty());
        }
        let s: SplitError<&str> = SplitError::Sink("full");
        assert!(s.to_string().contains("full"));
    }

    #[test]
    fn never_panics_on_odd_input() {
        let nan = [[f64::NAN; 3]; 4];
        assert!(Nurbs::new(3, &nan, &ONES4, &BEZ3).is_err());
        assert!(Nurbs::new(usize::MAX, &LINE4, &ONES4, &BEZ3).is_err());
        let huge = [
            [1e300, -1e300, 1e300],
            [-1e300, 1e300, 0.0],
            [1e300, 1e300, 1e300],
            [0.0; 3],
        ];
        let _ = Nurbs::new(3, &huge, &[1e300, 1e-300, 1e300, 1.0], &BEZ3);
        let c = Nurbs::non_rational(3, &LINE4, &BEZ3).unwrap();
        for u in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY, -1.0, 2.0] {
            for hint in [0, 3, 4, usize::MAX] {
                let (d, span) = c.eval_with_hint(u, 3, hint);
                assert_eq!(span, 3);
                assert!(d.p.iter().all(|x| x.is_finite()));
            }
            let _ = c.eval(u, 7);
            let _ = c.arc_length(u, 0.5, f64::NAN);
        }
    }

    #[test]
    fn random_malformed_input_never_panics() {
        let mut rng = Rng(0xDEAD_BEEF);
        let palette = [
            0.0,
            1.0,
            -1.0,
            0.5,
            f64::NAN,
            f64::INFINITY,
            1e308,
            -1e-308,
            1e-300,
        ];
        let pick = |rng: &mut Rng| {
            if rng.one_in(4) {
                palette[(rng.next_u64() % palette.len() as u64) as usize]
            } else {
                rng.range(-2.0, 2.0)
            }
        };
        let mut accepted = 0;
        for _ in 0..20_000 {
            let degree = (rng.next_u64() % 7) as usize;
            let count = (rng.next_u64() % 40) as usize;
            let pts: Vec<[f64; 3]> = (0..count)
                .map(|_| [pick(&mut rng), pick(&mut rng), 0.0])
                .collect();
            let wn = if rng.one_in(8) { count + 1 } else { count };
            let w: Vec<f64> = (0..wn).map(|_| libm::fabs(pick(&mut rng))).collect();
            // Mostly well-formed clamped knots, sometimes perturbed.
            let kn = if rng.one_in(8) {
                count + degree
            } else {
                count + degree + 1
            };
            let mut k: Vec<f64> = (0..kn).map(|_| rng.range(0.0, 1.0)).collect();
            k.sort_by(|a, b| a.partial_cmp(b).unwrap());
            if kn > 2 * degree + 2 && rng.one_in(2) {
                for i in 0..=degree {
                    k[i] = 0.0;
                    k[kn - 1 - i] = 1.0;
                }
            }
            if kn > 0 && rng.one_in(6) {
                let i = (rng.next_u64() % kn as u64) as usize;
                k[i] = pick(&mut rng);
            }
            if let Ok(c) = Nurbs::new(degree, &pts, &w, &k) {
                accepted += 1;
                let _ = c.eval(rng.range(-1.0, 2.0), 3);
                let _ = c.split_at(rng.range(0.0, 1.0));
                let _ = c.insert_knot(rng.range(0.0, 1.0), (rng.next_u64() % 4) as usize);
                let _ = c.arc_length(0.0, 1.0, 1e-6);
            }
            let _ = split_program_curve::<()>(degree, &pts, &w, &k, 8, |_| Ok(()));
        }
        assert!(accepted > 20, "{accepted}");
    }

    #[test]
    fn derivatives_match_finite_differences() {
        let mut rng = Rng(0x1234_5678);
        let h = 1e-5;
        for p in 1..=MAX_DEGREE {
            for _ in 0..8 {
                let count = p + 1 + (rng.next_u64() % 6) as usize;
                let c = random_curve(&mut rng, p, count);
                let k = c.knots();
                for _ in 0..40 {
                    let u = rng.range(0.0, 1.0);
                    // Keep the stencil inside one span.
                    if k.iter().any(|&x| libm::fabs(x - u) < 2.0 * h) {
                        continue;
                    }
                    let d = c.eval(u, 3);
                    let (a, b) = (c.eval(u - h, 3), c.eval(u + h, 3));
                    let fd = [
                        (b.p - a.p) / (2.0 * h),
                        (b.d1 - a.d1) / (2.0 * h),
                        (b.d2 - a.d2) / (2.0 * h),
                    ];
                    let ex = [d.d1, d.d2, d.d3];
                    for o in 0..3 {
                        let scale = 1.0 + ex[o].norm() + a.d1.norm();
                        let err = dist(fd[o], ex[o]);
                        assert!(
                            err <= 1e-5 * scale,
                            "p={p} u={u} order {} err {err} scale {scale}",
                            o + 1
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn derivative_order_beyond_degree_is_rational() {
        // A linear rational segment is a straight line with a non-linear parameter:
        // C'' and C''' are non-zero although the homogeneous ones vanish.
        let c = Nurbs::new(
            1,
            &[[0.0; 3], [1.0, 0.0, 0.0]],
            &[1.0, 3.0],
            &[0.0, 0.0, 1.0, 1.0],
        )
        .unwrap();
        let u = 0.4;
        let d = c.eval(u, 3);
        let h = 1e-5;
        let (a, b) = (c.eval(u - h, 3), c.eval(u + h, 3));
        assert!(dist((b.d2 - a.d2) / (2.0 * h), d.d3) < 1e-5 * d.d3.norm());
        assert!(d.d3.norm() > 1.0);
        // x(u) = 3u / (1 + 2u)
        assert!(libm::fabs(d.p.x - 3.0 * u / (1.0 + 2.0 * u)) < 1e-15);
    }

    #[test]
    fn full_circle_is_exact() {
        let c = unit_circle();
        for i in 0..=1000 {
            let u = i as f64 / 1000.0;
            let d = c.eval(u, 2);
            assert!(libm::fabs(d.p.norm() - 1.0) <= 1e-14, "u={u}");
            assert!(
                libm::fabs(d.curvature() - 1.0) <= 1e-12,
                "u={u} k={}",
                d.curvature()
            );
            let n = d.principal_normal().unwrap();
            assert!(dist(n, -d.p) < 1e-12);
        }
        assert_eq!(c.start_point(), Vec3::new(1.0, 0.0, 0.0));
        assert_eq!(c.end_point(), Vec3::new(1.0, 0.0, 0.0));
        assert_eq!(c.eval(1.0, 0).p, Vec3::new(1.0, 0.0, 0.0));
        assert!(dist(c.eval(0.25, 0).p, Vec3::new(0.0, 1.0, 0.0)) < 1e-15);
    }

    #[test]
    fn arc_length_of_the_unit_circle() {
        let c = unit_circle();
        let l = c.arc_length(0.0, 1.0, 1e-13);
        assert!(libm::fabs(l - 2.0 * PI) <= 1e-12, "{l}");
        let q = c.arc_length(0.0, 0.25, 1e-13);
        assert!(libm::fabs(q - 0.5 * PI) <= 1e-12, "{q}");
        // Over a span boundary and backwards.
        let a = c.arc_length(0.1, 0.6, 1e-13);
        let b = c.arc_length(0.6, 0.1, 1e-13);
        assert_eq!(a, -b);
        let exact = |u: f64| {
            let p = c.eval(u, 0).p;
            let t = libm::atan2(p.y, p.x);
            if t < 0.0 { t + 2.0 * PI } else { t }
        };
        assert!(libm::fabs(a - (exact(0.6) - exact(0.1))) < 1e-12);
        assert_eq!(c.arc_length(0.3, 0.3, 1e-9), 0.0);
        // Tolerance 0 still terminates.
        assert!(libm::fabs(c.arc_length(0.0, 1.0, 0.0) - 2.0 * PI) <= 1e-12);
    }

    #[test]
    fn arc_length_of_a_straight_cubic() {
        let dir = Vec3::new(3.0, 4.0, 12.0) / 13.0;
        let ts = [0.0, 0.5, 2.0, 2.5, 6.0, 9.0, 13.0];
        let pts: Vec<[f64; 3]> = ts
            .iter()
            .map(|&t| [dir.x * t, dir.y * t, dir.z * t])
            .collect();
        let k = [0.0, 0.0, 0.0, 0.0, 0.2, 0.3, 0.7, 1.0, 1.0, 1.0, 1.0];
        let c = Nurbs::non_rational(3, &pts, &k).unwrap();
        let l = c.arc_length(0.0, 1.0, 1e-12);
        assert!(libm::fabs(l - 13.0) < 1e-11, "{l}");
        let part = c.arc_length(0.25, 0.8, 1e-12);
        let want = dist(c.eval(0.8, 0).p, c.eval(0.25, 0).p);
        assert!(libm::fabs(part - want) < 1e-11);
    }

    #[test]
    fn gauss_kronrod_integrates_polynomials_exactly() {
        // ∫_{-1}^{1} x^k: the Kronrod rule is exact to degree 22, Gauss to 13.
        let rule = |k: i32| {
            let f = |x: f64| libm::pow(x, k as f64);
            let mut kr = GK_WK[7] * f(0.0);
            let mut g = GK_WG[3] * f(0.0);
            for j in 0..7 {
                let s = f(GK_X[j]) + f(-GK_X[j]);
                kr += GK_WK[j] * s;
                if j % 2 == 1 {
                    g += GK_WG[j / 2] * s;
                }
            }
            (kr, g)
        };
        for k in (0..=22).step_by(2) {
            let exact = 2.0 / (k as f64 + 1.0);
            let (kr, g) = rule(k);
            assert!(libm::fabs(kr - exact) < 1e-15, "K15 x^{k}");
            if k <= 13 {
                assert!(libm::fabs(g - exact) < 1e-15, "G7 x^{k}");
            }
        }
    }

    #[test]
    fn find_span_with_any_hint_matches_bisection() {
        let mut rng = Rng(99);
        let pts = [
            [0.0; 3],
            [1.0, 0.0, 0.0],
            [2.0, 1.0, 0.0],
            [3.0, 1.0, 1.0],
            [4.0, 0.0, 1.0],
            [5.0, 2.0, 0.0],
        ];
        // Double interior knot: an empty span in the middle.
        let k = [0.0, 0.0, 0.0, 0.4, 0.4, 0.7, 1.0, 1.0, 1.0];
        let c = Nurbs::new(2, &pts, &[1.0; 6], &k).unwrap();
        for _ in 0..2000 {
            let u = rng.range(-0.1, 1.1);
            let want = c.span_of(u);
            let kk = c.knots();
            let uc = c.clamp_u(u);
            assert!(kk[want] < kk[want + 1]);
            assert!(kk[want] <= uc && (uc < kk[want + 1] || uc == 1.0));
            for hint in [0, 1, 2, 3, 4, 5, 6, 100, (rng.next_u64() % 10) as usize] {
                assert_eq!(c.find_span(u, hint), want, "u={u} hint={hint}");
            }
        }
        assert_eq!(c.find_span(1.0, 2), 5);
        assert_eq!(c.find_span(0.4, 2), 4);
    }

    #[test]
    fn eval_is_deterministic_and_hint_independent() {
        let mut rng = Rng(5);
        for p in 1..=MAX_DEGREE {
            eval_bits_agree(&random_curve(&mut rng, p, 20));
        }
    }

    fn eval_bits_agree(c: &Nurbs) {
        let mut hint = 0;
        for i in 0..=500 {
            let u = i as f64 / 500.0;
            let (d, span) = c.eval_with_hint(u, 3, hint);
            hint = span;
            let e = c.eval(u, 3);
            assert_eq!(d.p.map(f64::to_bits), e.p.map(f64::to_bits));
            assert_eq!(d.d1.map(f64::to_bits), e.d1.map(f64::to_bits));
            assert_eq!(d.d3.map(f64::to_bits), e.d3.map(f64::to_bits));
            // Asking for less gives the same leading entries (the order <= 1 fast
            // path agrees with A2.3 to the bit) and zeros after.
            let lo = c.eval(u, 1);
            assert_eq!(lo.p.map(f64::to_bits), e.p.map(f64::to_bits));
            assert_eq!(lo.d1.map(f64::to_bits), e.d1.map(f64::to_bits));
            assert_eq!(lo.d2, Vec3::zeros());
            let p0 = c.eval(u, 0);
            assert_eq!(p0.p.map(f64::to_bits), e.p.map(f64::to_bits));
            assert_eq!(p0.d1, Vec3::zeros());
            assert_eq!(c.eval(u, 2).d2.map(f64::to_bits), e.d2.map(f64::to_bits));
        }
    }

    #[test]
    fn end_points_are_exact_and_accessors_round_trip() {
        let pts = [
            [0.1, 0.2, 0.3],
            [1.7, 0.0, 2.0],
            [2.0, 1.3, 0.0],
            [0.3, 0.7, 0.1],
        ];
        let w = [0.3, 1.7, 0.9, 0.7];
        let c = Nurbs::new(3, &pts, &w, &BEZ3).unwrap();
        assert_eq!(c.start_point(), Vec3::from(pts[0]));
        assert_eq!(c.end_point(), Vec3::from(pts[3]));
        assert_eq!(c.eval(0.0, 1).p, Vec3::from(pts[0]));
        assert_eq!(c.eval(1.0, 1).p, Vec3::from(pts[3]));
        assert_eq!(c.degree(), 3);
        assert_eq!(c.control_count(), 4);
        assert_eq!(c.knots(), &BEZ3);
        for i in 0..4 {
            assert_eq!(c.weight(i), w[i]);
            assert!(dist(Vec3::from(c.control_point(i)), Vec3::from(pts[i])) < 1e-15);
        }
        assert_eq!(c.control_point(3), pts[3]);
    }

    #[test]
    fn knot_insertion_keeps_the_curve() {
        let mut rng = Rng(11);
        for p in 1..=MAX_DEGREE {
            let c = random_curve(&mut rng, p, p + 4);
            let u = c.knots()[p + 1]; // an existing knot
            for (v, times) in [(0.37, p), (u, p - 1), (0.5, 1)] {
                if times == 0 {
                    continue;
                }
                let q = c.insert_knot(v, times).unwrap();
                assert_eq!(q.control_count(), c.control_count() + times);
                assert_eq!(q.start_point(), c.start_point());
                assert_eq!(q.end_point(), c.end_point());
                for i in 0..=200 {
                    let t = i as f64 / 200.0;
                    assert!(dist(q.eval(t, 0).p, c.eval(t, 0).p) < 1e-12, "p={p} v={v}");
                }
            }
            assert_eq!(c.insert_knot(0.37, 0).unwrap(), c);
        }
    }

    #[test]
    fn split_halves_are_the_same_curve() {
        let mut rng = Rng(21);
        let mut curves = Vec::new();
        curves.push(unit_circle());
        for p in 1..=MAX_DEGREE {
            curves.push(random_curve(&mut rng, p, p + 5));
            // Full capacity: splitting must not overflow.
            curves.push(random_curve(&mut rng, p, MAX_CTRL));
        }
        for c in &curves {
            let p = c.degree();
            let mut params = Vec::from([0.3, 0.5, 0.77, 1e-9, 1.0 - 1e-9]);
            params.extend_from_slice(&c.knots()[p + 1..c.control_count()]);
            for &u in &params {
                let (a, b) = c.split_at(u).unwrap();
                assert!(a.control_count() <= c.control_count());
                assert!(b.control_count() <= c.control_count());
                assert_eq!((a.u_start(), a.u_end()), (c.u_start(), u));
                assert_eq!((b.u_start(), b.u_end()), (u, c.u_end()));
                assert_eq!(a.end_point(), b.start_point());
                assert_eq!(a.start_point(), c.start_point());
                assert_eq!(b.end_point(), c.end_point());
                for i in 0..=100 {
                    let t = i as f64 / 100.0;
                    let (ua, ub) = (u * t, u + (1.0 - u) * t);
                    assert!(
                        dist(a.eval(ua, 0).p, c.eval(ua, 0).p) <= 1e-12,
                        "p={p} u={u}"
                    );
                    assert!(
                        dist(b.eval(ub, 0).p, c.eval(ub, 0).p) <= 1e-12,
                        "p={p} u={u}"
                    );
                }
                // The halves are themselves valid curves.
                let re = |h: &Nurbs| {
                    let pts: Vec<[f64; 3]> =
                        (0..h.control_count()).map(|i| h.control_point(i)).collect();
                    let w: Vec<f64> = (0..h.control_count()).map(|i| h.weight(i)).collect();
                    Nurbs::new(h.degree(), &pts, &w, h.knots()).map(|_| ())
                };
                assert_eq!(re(&a), Ok(()));
                assert_eq!(re(&b), Ok(()));
            }
        }
    }

    #[test]
    fn reversed_runs_backwards() {
        let mut rng = Rng(31);
        for p in 1..=MAX_DEGREE {
            let r = random_raw(&mut rng, p, p + 6);
            let k: Vec<f64> = r.k.iter().map(|x| 0.3 + 1.7 * x).collect();
            let c = Nurbs::new(p, &r.pts, &r.w, &k).unwrap();
            let rev = c.reversed();
            let (a, b) = (c.u_start(), c.u_end());
            assert_eq!((rev.u_start(), rev.u_end()), (a, b));
            assert_eq!(rev.start_point(), c.end_point());
            assert_eq!(rev.end_point(), c.start_point());
            for i in 0..=100 {
                let u = a + (b - a) * (i as f64 / 100.0);
                let (x, y) = (rev.eval(u, 1), c.eval(a + b - u, 1));
                assert!(dist(x.p, y.p) <= 1e-12);
                assert!(dist(x.d1, -y.d1) <= 1e-9 * (1.0 + y.d1.norm()));
            }
            // Mirroring the knots twice may round them, hence not bit-identical.
            assert!(dist(rev.reversed().eval(0.9, 0).p, c.eval(0.9, 0).p) <= 1e-12);
        }
    }

    #[test]
    fn scaled_and_translated() {
        let c = unit_circle();
        let inch = c.scaled(25.4);
        let moved = c.translated(Vec3::new(1.0, -2.0, 3.0));
        for i in 0..=50 {
            let u = i as f64 / 50.0;
            let d = c.eval(u, 2);
            let s = inch.eval(u, 2);
            assert!(dist(s.p, d.p * 25.4) < 1e-13);
            assert!(libm::fabs(s.curvature() - 1.0 / 25.4) < 1e-13);
            let m = moved.eval(u, 2);
            assert!(dist(m.p, d.p + Vec3::new(1.0, -2.0, 3.0)) < 1e-14);
            assert!(dist(m.d1, d.d1) < 1e-13);
        }
        assert_eq!(inch.start_point(), Vec3::new(25.4, 0.0, 0.0));
        assert_eq!(moved.end_point(), Vec3::new(2.0, -2.0, 3.0));
    }

    #[test]
    fn rotated_turns_every_derivative_and_keeps_the_parameter() {
        let c = unit_circle().translated(Vec3::new(3.0, -1.0, 0.5));
        let rot = Rotation3::from_axis_angle(&Vector3::y_axis(), 0.7)
            * Rotation3::from_axis_angle(&Vector3::z_axis(), -1.9);
        let r = c.rotated(&rot);
        for i in 0..=50 {
            let u = i as f64 / 50.0;
            let (d, e) = (c.eval(u, 3), r.eval(u, 3));
            assert!(dist(e.p, rot * d.p) < 1e-13);
            assert!(dist(e.d1, rot * d.d1) < 1e-12);
            assert!(dist(e.d2, rot * d.d2) < 1e-11);
            assert!(dist(e.d3, rot * d.d3) < 1e-10);
        }
        assert!(dist(r.start_point(), rot * c.start_point()) < 1e-15);
        assert!(dist(r.end_point(), rot * c.end_point()) < 1e-15);
        assert!(libm::fabs(r.arc_length(0.1, 0.8, 1e-12) - c.arc_length(0.1, 0.8, 1e-12)) < 1e-11);
    }

    fn split_all(r: &Raw, max_ctrl: usize) -> Vec<Nurbs> {
        let mut segs = Vec::new();
        split_program_curve::<()>(r.p, &r.pts, &r.w, &r.k, max_ctrl, |s| {
            segs.push(s);
            Ok(())
        })
        .unwrap();
        segs
    }

    #[test]
    fn program_curve_splits_into_the_same_curve() {
        let mut rng = Rng(41);
        let r = random_raw(&mut rng, 3, 200);
        let max_ctrl = MAX_CTRL - MAX_DEGREE - 1;
        let segs = split_all(&r, max_ctrl);
        assert!(segs.len() >= 200 / max_ctrl);
        assert_eq!(segs[0].u_start(), 0.0);
        assert_eq!(segs.last().unwrap().u_end(), 1.0);
        assert_eq!(segs[0].start_point(), Vec3::from(r.pts[0]));
        assert_eq!(segs.last().unwrap().end_point(), Vec3::from(r.pts[199]));
        for (i, s) in segs.iter().enumerate() {
            assert!(s.control_count() <= max_ctrl);
            if i + 1 < segs.len() {
                let t = &segs[i + 1];
                assert_eq!(s.u_end(), t.u_start());
                assert!(r.k.contains(&s.u_end()));
                assert_eq!(s.end_point(), t.start_point());
                assert_eq!(s.eval(s.u_end(), 0).p, t.eval(t.u_start(), 0).p);
            }
            for j in 0..=200 {
                let u = s.u_start() + (s.u_end() - s.u_start()) * (j as f64 / 200.0);
                let (x, y) = (s.eval(u, 1), eval_raw(&r, u, 1));
                assert!(dist(x.p, y.p) <= 1e-11, "segment {i} u={u}");
                assert!(
                    dist(x.d1, y.d1) <= 1e-9 * (1.0 + y.d1.norm()),
                    "segment {i} u={u}"
                );
            }
        }
    }

    #[test]
    fn program_curve_splitting_other_cases() {
        let mut rng = Rng(51);
        // Every degree, repeated interior knots, tiny and odd segment limits.
        for p in 1..=MAX_DEGREE {
            let mut r = random_raw(&mut rng, p, 60);
            // Make some interior knots repeat up to the degree.
            for i in (p + 2..60).step_by(7) {
                for j in 0..p.min(3) - 1 {
                    if i + j < 60 {
                        r.k[i + j] = r.k[i - 1];
                    }
                }
            }
            r.k[p + 1..60].sort_by(|a, b| a.partial_cmp(b).unwrap());
            if validate_program_curve(p, &r.pts, &r.w, &r.k).is_err() {
                continue;
            }
            for max_ctrl in [0, p + 1, p + 2, 13, MAX_CTRL, 1000] {
                let segs = split_all(&r, max_ctrl);
                let cap = max_ctrl.clamp(p + 1, MAX_CTRL);
                assert_eq!(segs[0].u_start(), 0.0);
                assert_eq!(segs.last().unwrap().u_end(), 1.0);
                for (i, s) in segs.iter().enumerate() {
                    assert!(s.control_count() <= cap);
                    if i + 1 < segs.len() {
                        assert_eq!(s.u_end(), segs[i + 1].u_start());
                    }
                    for j in 0..=40 {
                        let u = s.u_start() + (s.u_end() - s.u_start()) * (j as f64 / 40.0);
                        assert!(
                            dist(s.eval(u, 0).p, eval_raw(&r, u, 0).p) <= 1e-11,
                            "p={p} max={max_ctrl}"
                        );
                    }
                }
            }
        }
        // A curve that fits is passed on unchanged.
        let r = random_raw(&mut rng, 3, 20);
        let segs = split_all(&r, 26);
        assert_eq!(segs.len(), 1);
        assert_eq!(segs[0], Nurbs::new(3, &r.pts, &r.w, &r.k).unwrap());
        // The sink's error comes back and stops the splitting.
        let r = random_raw(&mut rng, 3, 100);
        let mut calls = 0;
        let res = split_program_curve(3, &r.pts, &r.w, &r.k, 10, |_| {
            calls += 1;
            if calls == 2 { Err("full") } else { Ok(()) }
        });
        assert_eq!(res, Err(SplitError::Sink("full")));
        assert_eq!(calls, 2);
    }

    /// A long program curve (10,000 control points, parameters 0..9,997 as G6.2
    /// programs number their knots): measuring it and finding parameters by arc
    /// length must cost the same per segment at its end as at its start. Before
    /// the rounding floors, the end cost several times more (2^16 rules a span in
    /// the worst case): planning grew superlinearly with the curve.
    #[test]
    fn long_curves_cost_the_same_per_segment_at_both_ends() {
        let (p, count) = (3, 10_000);
        let pts: Vec<[f64; 3]> = (0..count)
            .map(|i| {
                let t = i as f64;
                [0.5 * t, 5.0 * libm::sin(0.3 * t), 0.1 * libm::cos(0.7 * t)]
            })
            .collect();
        let w: Vec<f64> = (0..count)
            .map(|i| 1.0 + 0.3 * libm::sin(i as f64))
            .collect();
        let mut k = std::vec![0.0; p + 1];
        k.extend((1..count - p).map(|i| i as f64));
        k.extend(std::vec![(count - p) as f64; p + 1]);
        let mut segs = Vec::new();
        split_program_curve::<()>(p, &pts, &w, &k, 20, |s| {
            segs.push(s);
            Ok(())
        })
        .unwrap();
        // Work of measuring a segment whole and of stepping along it by 0.03 mm
        // (a law sample spacing) from a few places, as the planner does.
        let work = |s: &Nurbs| {
            let path = crate::path::Path::Nurbs(*s);
            let (_, mut rules) = s.arc_length_counted(s.u_start(), s.u_end(), 1e-12);
            for j in 0..8 {
                let u = s.u_start() + (s.u_end() - s.u_start()) * (j as f64 / 8.0);
                rules += path.param_at_arc_length_counted(u, 0.03).1;
            }
            rules
        };
        let n = segs.len();
        let first: usize = segs[..20].iter().map(work).sum();
        let last: usize = segs[n - 20..].iter().map(work).sum();
        assert!(
            (last as f64) <= 1.25 * first as f64,
            "rules for the last 20 segments {last}, for the first 20 {first}"
        );
        // And the length is still resolved: the last segment against its copy
        // moved to parameters near 0 (same geometry, exact knot shift).
        let s = segs[n - 1];
        let shift = s.u_start();
        let moved: Vec<f64> = s.knots().iter().map(|x| x - shift).collect();
        let pts: Vec<[f64; 3]> = (0..s.control_count()).map(|i| s.control_point(i)).collect();
        let ws: Vec<f64> = (0..s.control_count()).map(|i| s.weight(i)).collect();
        let t = Nurbs::new(p, &pts, &ws, &moved).unwrap();
        let (a, b) = (
            s.arc_length(s.u_start(), s.u_end(), 1e-12),
            t.arc_length(t.u_start(), t.u_end(), 1e-12),
        );
        assert!(libm::fabs(a - b) <= 1e-10 * b, "{a} vs {b}");
    }

    #[test]
    fn curvature_where_the_speed_vanishes_is_its_limit() {
        // A repeated end control point: the curvature grows like 1/√s, and the
        // limit is infinite.
        let p = [[0.0; 3], [0.0; 3], [10.0, 0.0, 0.0], [10.0, 10.0, 0.0]];
        let c = Nurbs::non_rational(3, &p, &BEZ3).unwrap();
        assert!(c.is_stationary(0.0, Side::After));
        assert_eq!(c.curvature(0.0, Side::After), f64::INFINITY);
        assert!(c.eval(1e-6, 3).curvature() > 10.0 * c.eval(1e-4, 3).curvature());
        // Where it moves, the ordinary value.
        assert_eq!(c.curvature(0.5, Side::After), c.eval(0.5, 3).curvature());
        // Degree 4, C'' ∥ C''' at the stationary start: a finite limit, which
        // the curvature nearby approaches linearly.
        let p = [
            [0.0; 3],
            [0.0; 3],
            [1.0, 0.0, 0.0],
            [2.5, 0.0, 0.0],
            [3.0, 1.0, 0.0],
        ];
        let k = [0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0, 1.0];
        let c = Nurbs::non_rational(4, &p, &k).unwrap();
        assert!(c.is_stationary(0.0, Side::After));
        // C'' = 12·(1, 0, 0), C = 24·(-1, 1, 0): |C×C| / (3|C''|³) = 1/18.
        let lim = c.curvature(0.0, Side::After);
        assert!((lim - 1.0 / 18.0).abs() <= 1e-6 / 18.0, "{lim}");
        let near = |e: f64| (c.eval(e, 3).curvature() - lim).abs();
        assert!(near(1e-5) <= 1e-3 * lim && near(1e-5) < near(1e-3), "{lim}");
        // The same curve backwards, from before its end.
        let back = c.reversed();
        assert!(back.is_stationary(1.0, Side::Before));
        let b = back.curvature(1.0, Side::Before);
        assert!((b - lim).abs() <= 1e-6 * lim, "{b} vs {lim}");
    }

    #[test]
    fn arc_length_inverts_from_a_stationary_point_at_the_usual_cost() {
        // LinuxCNC's trident: the first control point repeats the start, C'(0) = 0.
        let p = [
            [10.0, 0.0, 0.0],
            [10.0, 0.0, 0.0],
            [20.0, 20.0, 0.0],
            [12.0, 8.0, 0.0],
            [10.0, 20.0, 0.0],
            [8.0, 8.0, 0.0],
            [0.0, 20.0, 0.0],
            [10.0, 0.0, 0.0],
        ];
        let k = [0.0, 0.0, 0.0, 0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 5.0, 5.0, 5.0];
        let c = Nurbs::non_rational(3, &p, &k).unwrap();
        assert!(c.is_stationary(0.0, Side::After));
        for ds in [1e-9, 1e-6, 1e-3, 0.1, 5.0] {
            let (u, rules) = c.param_at_arc_length_counted(0.0, ds, 1e-12);
            let back = c.arc_length(0.0, u, 1e-13);
            assert!(
                libm::fabs(back - ds) <= 1e-12 * (1.0 + ds),
                "ds {ds}: {back}"
            );
            // A first guess from C'' lands close: a few Newton steps (bisecting
            // from the range's end would take dozens).
            let (_, one) = c.arc_length_counted(0.0, u, 1e-12);
            assert!(
                rules <= 6 * one.max(1),
                "ds {ds}: {rules} rules, one length {one}"
            );
        }
        // From an interior cusp (C' = 0 at u = 0.5 of a Bézier), past it.
        let q = [
            [0.0; 3],
            [10.0, 10.0, 1.0],
            [0.0, 10.0, 0.0],
            [10.0, 0.0, 1.0],
        ];
        let c = Nurbs::non_rational(3, &q, &BEZ3).unwrap();
        assert!(c.is_stationary(0.5, Side::After));
        for ds in [1e-6, 0.5] {
            let (u, _) = c.param_at_arc_length_counted(0.5, ds, 1e-12);
            let back = c.arc_length(0.5, u, 1e-13);
            assert!(
                libm::fabs(back - ds) <= 1e-12 * (1.0 + ds),
                "ds {ds}: {back}"
            );
        }
    }
}
