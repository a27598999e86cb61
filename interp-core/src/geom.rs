//! Small geometric vocabulary shared by every path kind.

use nalgebra::Vector3;

/// A point or vector in machine coordinates, mm.
pub type Vec3 = Vector3<f64>;

/// Position and derivatives 1..=3 of a curve with respect to its own parameter.
///
/// Entries beyond the order that was asked for are zero.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Derivs {
    /// `C(u)`
    pub p: Vec3,
    /// `C'(u)`
    pub d1: Vec3,
    /// `C''(u)`
    pub d2: Vec3,
    /// `C'''(u)`
    pub d3: Vec3,
}

impl Derivs {
    /// All zero.
    pub const ZERO: Derivs = Derivs {
        p: Vec3::new(0.0, 0.0, 0.0),
        d1: Vec3::new(0.0, 0.0, 0.0),
        d2: Vec3::new(0.0, 0.0, 0.0),
        d3: Vec3::new(0.0, 0.0, 0.0),
    };

    /// Unsigned curvature `|C'×C''| / |C'|³` (1/mm); zero where the speed vanishes.
    #[inline]
    pub fn curvature(&self) -> f64 {
        let s = self.d1.norm();
        if s == 0.0 {
            return 0.0;
        }
        self.d1.cross(&self.d2).norm() / (s * s * s)
    }

    /// Unit principal normal (towards the centre of curvature), if the curve bends here.
    #[inline]
    pub fn principal_normal(&self) -> Option<Vec3> {
        let s2 = self.d1.norm_squared();
        if s2 == 0.0 {
            return None;
        }
        // Component of C'' perpendicular to C'.
        let n = self.d2 - self.d1 * (self.d1.dot(&self.d2) / s2);
        let len = n.norm();
        if len <= f64::EPSILON * self.d2.norm().max(1.0) {
            None
        } else {
            Some(n / len)
        }
    }
}

/// What every path kind offers the planner and the interpolator.
///
/// Parameters run over `[u_start, u_end]`; `eval` must be exact (no tessellation).
pub trait Curve {
    /// First parameter value.
    fn u_start(&self) -> f64;
    /// Last parameter value.
    fn u_end(&self) -> f64;
    /// Position and derivatives up to `order` (0..=3) at `u`, which is clamped to the range.
    fn eval(&self, u: f64, order: usize) -> Derivs;
    /// Exact start point.
    fn start_point(&self) -> Vec3 {
        self.eval(self.u_start(), 0).p
    }
    /// Exact end point (the interpolator copies it into the last setpoint).
    fn end_point(&self) -> Vec3 {
        self.eval(self.u_end(), 0).p
    }
}

/// Smallest value of `f` seen while narrowing `[a, b]` by golden-section
/// search for `iters` steps (or until the bracket is below `min_width`).
/// For a unimodal `f` that is its minimum on `[a, b]`; used to refine a
/// sampled extremum (maximise by passing `−f`).
pub fn golden_section_min(
    f: impl Fn(f64) -> f64,
    a: f64,
    b: f64,
    iters: usize,
    min_width: f64,
) -> f64 {
    golden_section_argmin(f, a, b, iters, min_width).1
}

/// [`golden_section_min`] with where it was seen: `(x, f(x))`.
pub fn golden_section_argmin(
    f: impl Fn(f64) -> f64,
    a: f64,
    b: f64,
    iters: usize,
    min_width: f64,
) -> (f64, f64) {
    let mut g = GoldenBracket::new(&f, a, b);
    // As f64::min: a NaN value never wins over a number.
    let better = |v: f64, best: f64| v < best || (best.is_nan() && !v.is_nan());
    let mut best = if better(g.f2, g.f1) {
        (g.x2, g.f2)
    } else {
        (g.x1, g.f1)
    };
    for _ in 0..iters {
        if g.b - g.a <= min_width {
            break;
        }
        let (x, v) = g.step(g.f1 < g.f2, &f);
        if better(v, best.1) {
            best = (x, v);
        }
    }
    best
}

/// A golden-section bracket `[a, b]` with its interior points `x1 < x2`
/// and their values: the one golden-section search of the workspace, which
/// [`golden_section_argmin`] runs and a caller with its own stopping rule
/// (a bound on the remaining optimum, a maximum) steps itself.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GoldenBracket {
    /// Left end.
    pub a: f64,
    /// Right end.
    pub b: f64,
    /// Left interior point, `b − 0.618…·(b − a)`.
    pub x1: f64,
    /// Right interior point, `a + 0.618…·(b − a)`.
    pub x2: f64,
    /// `f(x1)`.
    pub f1: f64,
    /// `f(x2)`.
    pub f2: f64,
}

impl GoldenBracket {
    /// `1/φ`: each step keeps this share of the bracket.
    pub const RATIO: f64 = 0.618_033_988_749_894_9;

    /// The bracket `[a, b]`, evaluating `f` at its two interior points.
    pub fn new(f: impl Fn(f64) -> f64, a: f64, b: f64) -> Self {
        let x1 = b - Self::RATIO * (b - a);
        let x2 = a + Self::RATIO * (b - a);
        Self {
            a,
            b,
            x1,
            x2,
            f1: f(x1),
            f2: f(x2),
        }
    }

    /// Keeps `[a, x2]` when `left`, else `[x1, b]`, and evaluates `f` at
    /// the one new interior point, which it returns with its value. A
    /// minimum is searched with `left = f1 < f2`, a maximum with
    /// `left = f1 > f2` (the tie is the caller's choice).
    pub fn step(&mut self, left: bool, f: impl Fn(f64) -> f64) -> (f64, f64) {
        if left {
            self.b = self.x2;
            self.x2 = self.x1;
            self.f2 = self.f1;
            self.x1 = self.b - Self::RATIO * (self.b - self.a);
            self.f1 = f(self.x1);
            (self.x1, self.f1)
        } else {
            self.a = self.x1;
            self.x1 = self.x2;
            self.f1 = self.f2;
            self.x2 = self.a + Self::RATIO * (self.b - self.a);
            self.f2 = f(self.x2);
            (self.x2, self.f2)
        }
    }
}

/// The parameter `u` in `[u0, hi]` at arc length `ds` past `u0`, to what the
/// arithmetic resolves: Newton on `length(u0, u)` (which also returns the
/// quadrature rules it spent, summed in the result) with `speed(u) = |C'(u)|`,
/// inside a shrinking bracket, bisecting where a step leaves it. `first` is
/// the first guess of `u`. The one inversion of arc length for every path kind.
pub fn invert_arc_length(
    u0: f64,
    ds: f64,
    hi: f64,
    first: f64,
    mut length: impl FnMut(f64, f64) -> (f64, usize),
    speed: impl Fn(f64) -> f64,
) -> (f64, usize) {
    let (mut lo, mut hi) = (u0, hi);
    let mut u = first.clamp(lo, hi);
    let mut rules = 0;
    for _ in 0..60 {
        let (l, r) = length(u0, u);
        rules += r;
        let f = l - ds;
        let speed = speed(u);
        // Nothing resolves the arc length better than one ulp of u moves the
        // point: on long program curves (parameters in the thousands) that is
        // above 1e-13 mm, and asking for more spent all 60 iterations.
        let floor = 1e-13 * (1.0 + ds) + 4.0 * f64::EPSILON * libm::fabs(u) * speed;
        if libm::fabs(f) <= floor {
            break;
        }
        if f > 0.0 {
            hi = u;
        } else {
            lo = u;
        }
        // At a zero of C' the step is not finite: bisect.
        let mut next = u - f / speed;
        if !(next > lo && next < hi) {
            next = 0.5 * (lo + hi);
        }
        u = next;
    }
    (u, rules)
}

#[cfg(test)]
mod golden_section_tests {
    use super::*;

    /// A parabola's minimum to the bracket's width; the maximum of a sine
    /// through `-f`.
    #[test]
    fn finds_the_minimum_of_a_unimodal_function() {
        let (x, v) = golden_section_argmin(|x| (x - 0.3) * (x - 0.3) + 2.0, -1.0, 2.0, 200, 1e-12);
        assert!((x - 0.3).abs() < 1e-6 && (v - 2.0).abs() < 1e-12, "{x} {v}");
        let top = -golden_section_min(|x| -libm::sin(x), 0.0, 3.0, 200, 1e-12);
        assert!((top - 1.0).abs() < 1e-12, "{top}");
    }

    /// Ties: an equal value never replaces the best, so a flat function
    /// keeps the first interior point (`b − 0.618…·(b − a)`); and a NaN never
    /// wins over a number.
    #[test]
    fn ties_keep_the_first_point_seen_and_nan_never_wins() {
        let (x, v) = golden_section_argmin(|_| 1.5, 2.0, 4.0, 50, 0.0);
        assert_eq!((x, v), (4.0 - 0.618_033_988_749_894_9 * 2.0, 1.5));
        // Flat on [0, 0.5], rising after: the best is on the flat, the first
        // point seen there.
        let f = |x: f64| if x <= 0.5 { 0.0 } else { x - 0.5 };
        let (x, v) = golden_section_argmin(f, 0.0, 1.0, 60, 0.0);
        assert_eq!((x, v), (1.0 - 0.618_033_988_749_894_9, 0.0));
        let (x, v) =
            golden_section_argmin(|x| if x < 0.5 { f64::NAN } else { x }, 0.0, 1.0, 60, 1e-12);
        assert!(!v.is_nan() && x >= 0.5 && (v - 0.5).abs() < 1e-9, "{x} {v}");
    }

    /// Stepped by hand, the bracket finds a maximum (`left = f1 > f2`), each
    /// step keeps 0.618… of it and always holds the optimum; ties go where
    /// the caller says.
    #[test]
    fn a_bracket_stepped_by_hand_maximises_and_shrinks_by_the_ratio() {
        // A kink, not a parabola: its top resolves to the ulp.
        let f = |x: f64| 1.0 - libm::fabs(x - 0.7);
        let mut g = GoldenBracket::new(f, 0.0, 2.0);
        for _ in 0..60 {
            let w = g.b - g.a;
            g.step(g.f1 > g.f2, f);
            assert!((g.b - g.a - GoldenBracket::RATIO * w).abs() <= 1e-12 * w + 1e-15);
            assert!(g.a <= 0.7 && 0.7 <= g.b && g.x1 <= g.x2, "{g:?}");
        }
        assert!(
            (g.x1 - 0.7).abs() < 1e-11 && (g.f1 - 1.0).abs() < 1e-11,
            "{g:?}"
        );
        let flat = |_: f64| 3.0;
        let mut left = GoldenBracket::new(flat, 0.0, 1.0);
        let mut right = left;
        left.step(true, flat);
        right.step(false, flat);
        assert_eq!((left.a, left.b), (0.0, 0.618_033_988_749_894_9));
        assert_eq!(right.b, 1.0);
        assert!((right.a - (1.0 - 0.618_033_988_749_894_9)).abs() < 1e-16);
    }
}
