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
