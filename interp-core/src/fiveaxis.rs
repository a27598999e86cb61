//! Five-axis blocks: what a block does beside its path (the rotary axes as
//! plain axes, or the tool axis under tool-centre-point control), the
//! machine's joints along it, and the limits the joints put on the path
//! speed (`docs/five-axis.md`).
//!
//! A block's [`Orientation`] is a function of the path parameter `u`, so
//! the tick evaluates it at the very parameter it reached on the path.
//! Under tool-centre-point control the path is the tool tip in the
//! workpiece frame and the tool axis turns on the sphere (a great-circle
//! arc at a constant angle per unit of `u`, not angle by angle of the
//! joints); the setpoints are the joints from [`Machine::inverse`] nearest
//! the previous ones. Without it the path is X Y Z of the machine and the
//! rotary joints move in proportion to `u`.
//!
//! The planner samples the joints' derivatives in arc length
//! ([`JointSample`]) and turns them into speed limits
//! ([`JointSample::speed_limit`]): per-joint velocity, the curvature share
//! of the acceleration, the steady jerk, and the two tolerances that hold
//! *between* setpoints, where the drives interpolate the joints linearly
//! and so bend the tip path and turn the tool axis off its program.

use crate::config::InterpConfig;
use crate::geom::{Curve, Vec3};
use crate::kinematics::{Degrees, InverseError, Joints, Machine, ToolPose};
use crate::path::Path;
use crate::plan::{AxisSample, Window, index_of};
use crate::prepare::{axis_jerk_may_bind, keep_axis_sample};

/// Beyond this angle (rad) from its start a tool axis cannot be turned to
/// its end on a unique great circle (the two are nearly opposite).
pub const MAX_TURN: f64 = core::f64::consts::PI - 1e-6;

/// Arc-length step of the joint derivative stencil ([`JointSample`]), mm:
/// small against any curvature the path may have at speed, large enough
/// that the third difference is not round-off (`ε·|q|/h³ ≈ 1e-7` per mm³).
pub const JOINT_STEP: f64 = 0.01;

/// Control values of a rational Bézier piece of the highest degree a
/// NURBS may have ([`Orientation::AxesCurve`]).
pub const BEZIER: usize = crate::nurbs::MAX_DEGREE + 1;

/// What a block does beside the path.
///
/// Small on purpose: every block and queued segment carries one, and the
/// interpolator is built on the stack. (A second NURBS for the tool axis or
/// the rotary coordinates inline would double a block's size: a program
/// curve's rotary coordinates or tool vectors travel as one rational Bézier
/// piece per knot span, [`Orientation::AxesCurve`] and
/// [`Orientation::ToolAxisCurve`].)
///
/// **A turn in place** (`fixed: Some(p)`): the tool tip (under
/// tool-centre-point control) or X Y Z stands at `p` while the rotary axes
/// or the tool axis turn, as in `G0 A30 C45` alone. The block's path is
/// then no position but the turn's own measure: a line from `p` whose
/// length is the turn in degrees (the rotary axes' `|Δ(A, B, C)|`, or the
/// tool axis' angle), so that the planner schedules the turn as it
/// schedules a path, its speed in degrees per second (`F` in deg/min, as
/// Fanuc and Siemens take it for rotary-only moves), within the joints'
/// limits. See [`TurnInPlace`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Orientation {
    /// Tool-centre-point control off: the path is X Y Z of the machine, and
    /// the rotary joints A B C (degrees) go from `start` to `end` in
    /// proportion to the path parameter between `u0` and `u1`.
    Axes {
        /// A B C at `u0`, degrees.
        start: [f64; 3],
        /// A B C at `u1`, degrees.
        end: [f64; 3],
        /// Parameter range of the whole block.
        u0: f64,
        /// See `u0`.
        u1: f64,
        /// X Y Z stand here while the axes turn (a turn in place).
        fixed: Option<Vec3>,
    },
    /// Tool-centre-point control on: the path is the tool tip in the
    /// workpiece frame, and the unit tool axis turns from `start` towards
    /// `end` on the great circle through them, by an angle in proportion to
    /// the parameter (`a = cos φ·start + sin φ·w`, `φ = θ·(u − u0)/(u1 − u0)`).
    ToolAxis {
        /// Unit tool axis at `u0` (from the tip into the spindle).
        start: Vec3,
        /// The unit vector across `start` towards `end` (zero when `θ = 0`).
        w: Vec3,
        /// The angle from `start` to `end`, rad, `0 ≤ θ < π`.
        theta: f64,
        /// Parameter range of the whole block.
        u0: f64,
        /// See `u0`.
        u1: f64,
        /// The tool tip stands here while the tool turns (a turn in place).
        fixed: Option<Vec3>,
    },
    /// The rotary joints A B C (degrees) are coordinates of the path's
    /// NURBS (G6.2 with A B C on its control points, as Fanuc allows: the
    /// same weights and knots), over one knot span of it: a rational Bézier
    /// curve in `t = (u − u0)/(u1 − u0)` with these control values and the
    /// weights the path has on that span ([`Orientation::axes_curve`]). A
    /// program curve is cut into its spans (`gcode::Cutter`), each a block
    /// with its own piece of the curve. With `tcp` off the path is X Y Z of
    /// the machine; with it on (G43.4, [`Orientation::under_tcp`]) the path
    /// is the tool tip in the workpiece frame, the rotary joints are the
    /// curve's and the linear ones put the tip on the path
    /// ([`Machine::place_tip`]): the tool axis is the machine's at those
    /// rotary positions ([`Orientation::axis_at`]).
    AxesCurve {
        /// A B C of the control points, degrees, with their weights.
        curve: BezierSpan,
        /// Under tool-centre-point control (G43.4): the path is the tool tip.
        tcp: bool,
    },
    /// Tool-centre-point control with a second curve for the tool axis
    /// (G43.5, a G6.2 with a tool vector on each control point): the path
    /// is the tool tip in the workpiece frame and the tool axis is the
    /// programmed vectors' NURBS (the path's weights and knots) normalised,
    /// over one knot span: the rational Bézier in `t = (u − u0)/(u1 − u0)`
    /// of these vectors and weights, divided by its length
    /// ([`Orientation::tool_axis_curve`]). A vector path on the sphere, not
    /// angle by angle; the joints are the inverse nearest the previous ones.
    ToolAxisCurve {
        /// Tool vectors of the control points (any length; their lengths
        /// act as weights of the vector curve), with the path's weights.
        curve: BezierSpan,
    },
}

/// One knot span of a second curve beside a NURBS path, with the path's
/// weights and knots: the rational Bézier in `t = (u − u0)/(u1 − u0)` of
/// three values per control point (A B C, or a tool vector).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BezierSpan {
    /// The control points' values.
    pub values: [[f64; 3]; BEZIER],
    /// Their weights.
    pub w: [f64; BEZIER],
    /// Degree (`degree + 1` control points are used).
    pub degree: u8,
    /// The span's parameter range.
    pub u0: f64,
    /// See `u0`.
    pub u1: f64,
}

impl BezierSpan {
    /// The span `u0..u1` of `degree` with `values[k]` and weights `w[k]`
    /// on its `degree + 1` control points; refused unless all are finite,
    /// the weights positive and the range increasing.
    pub fn new(
        degree: usize,
        values: &[[f64; 3]],
        w: &[f64],
        u0: f64,
        u1: f64,
    ) -> Result<Self, OrientationError> {
        let n = degree + 1;
        if !(1..BEZIER).contains(&degree)
            || values.len() != n
            || w.len() != n
            || !(u0 < u1 && u0.is_finite() && u1.is_finite())
            || !values.iter().flatten().all(|v| v.is_finite())
            || !w.iter().all(|w| *w > 0.0 && w.is_finite())
        {
            return Err(OrientationError::BadValue);
        }
        let mut vs = [[0.0; 3]; BEZIER];
        let mut ws = [1.0; BEZIER];
        vs[..n].copy_from_slice(values);
        ws[..n].copy_from_slice(w);
        Ok(BezierSpan {
            values: vs,
            w: ws,
            degree: degree as u8,
            u0,
            u1,
        })
    }

    /// The curve's value at parameter `u` of the block.
    #[inline]
    pub fn at(&self, u: f64) -> [f64; 3] {
        rational_bezier(
            &self.values,
            &self.w,
            self.degree as usize,
            Orientation::fraction(u, self.u0, self.u1),
        )
    }
}

/// Why an [`Orientation`] was refused.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum OrientationError {
    /// A value is not finite, or a tool axis is zero.
    BadValue,
    /// The tool axis would turn by nearly 180° (its great circle is not
    /// unique); the angle in degrees.
    HalfTurn(f64),
    /// A tool-vector curve's control vectors on one span do not lie on one
    /// side of a plane through the origin, so the curve might pass through
    /// the zero vector (no tool axis there); the largest angle, degrees,
    /// between a control vector and their mean direction.
    VectorSpread(f64),
}

impl core::fmt::Display for OrientationError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            OrientationError::BadValue => write!(f, "non-finite rotary position or tool axis"),
            OrientationError::HalfTurn(d) => write!(
                f,
                "the tool axis turns by {} degrees in one move: split it (the way round is not unique)",
                Degrees(*d)
            ),
            OrientationError::VectorSpread(d) => write!(
                f,
                "the tool vectors of one knot span of the curve spread {} degrees from their mean direction (90 at most, or the vector curve may pass through zero): add control points",
                Degrees(*d)
            ),
        }
    }
}

/// Where a block's orientation stands at one parameter.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum OrientationAt {
    /// Rotary joints A B C, degrees.
    Axes([f64; 3]),
    /// Unit tool axis in the workpiece frame.
    ToolAxis(Vec3),
}

impl Orientation {
    /// Rotary axes moved as plain axes along `path` from `start` to `end` (degrees).
    pub fn axes(path: &Path, start: [f64; 3], end: [f64; 3]) -> Result<Self, OrientationError> {
        if !start.iter().chain(&end).all(|v| v.is_finite()) {
            return Err(OrientationError::BadValue);
        }
        Ok(Orientation::Axes {
            start,
            end,
            u0: path.u_start(),
            u1: path.u_end(),
            fixed: None,
        })
    }

    /// The tool axis turned along `path` from `start` to `end` (any length,
    /// normalised here) under tool-centre-point control.
    pub fn tool_axis(path: &Path, start: Vec3, end: Vec3) -> Result<Self, OrientationError> {
        let (ns, ne) = (start.norm(), end.norm());
        if !(ns > 0.0 && ns.is_finite() && ne > 0.0 && ne.is_finite()) {
            return Err(OrientationError::BadValue);
        }
        let (a, b) = (start / ns, end / ne);
        let across = b - a * a.dot(&b);
        let theta = libm::atan2(across.norm(), a.dot(&b));
        if theta > MAX_TURN {
            return Err(OrientationError::HalfTurn(theta.to_degrees()));
        }
        let w = if across.norm() > 0.0 {
            across / across.norm()
        } else {
            Vec3::zeros()
        };
        Ok(Orientation::ToolAxis {
            start: a,
            w,
            theta,
            u0: path.u_start(),
            u1: path.u_end(),
            fixed: None,
        })
    }

    /// The rotary axes as coordinates of a NURBS path over one of its knot
    /// spans `u0..u1`, a rational Bézier piece of `degree`: `values[k]` the
    /// A B C (degrees) and `w[k]` the weight of its `degree + 1` control
    /// points (the path's own weights on the span).
    pub fn axes_curve(
        degree: usize,
        values: &[[f64; 3]],
        w: &[f64],
        u0: f64,
        u1: f64,
    ) -> Result<Self, OrientationError> {
        Ok(Orientation::AxesCurve {
            curve: BezierSpan::new(degree, values, w, u0, u1)?,
            tcp: false,
        })
    }

    /// The tool axis as a second curve of a NURBS tool-tip path over one of
    /// its knot spans `u0..u1`, a rational Bézier piece of `degree`:
    /// `values[k]` the tool vector (any length, not zero) and `w[k]` the
    /// weight of its `degree + 1` control points (the path's own weights on
    /// the span); the axis at `u` is that curve normalised. Refused where
    /// the vectors do not lie within 90° of their mean direction (the curve
    /// could pass through zero): [`OrientationError::VectorSpread`].
    pub fn tool_axis_curve(
        degree: usize,
        values: &[[f64; 3]],
        w: &[f64],
        u0: f64,
        u1: f64,
    ) -> Result<Self, OrientationError> {
        let curve = BezierSpan::new(degree, values, w, u0, u1)?;
        // With positive weights the curve is a positive combination of the
        // control vectors: strictly on the side of a plane through the
        // origin where they all are, so never zero.
        let mut mean = Vec3::zeros();
        for v in values {
            let v = Vec3::new(v[0], v[1], v[2]);
            let n = v.norm();
            if !(n > 0.0) {
                return Err(OrientationError::BadValue);
            }
            mean += v / n;
        }
        if !(mean.norm() > 1e-9) {
            return Err(OrientationError::VectorSpread(180.0));
        }
        let mut spread: f64 = 0.0;
        for v in values {
            let v = Vec3::new(v[0], v[1], v[2]);
            spread = spread.max(libm::atan2(v.cross(&mean).norm(), v.dot(&mean)));
        }
        if !(spread < core::f64::consts::FRAC_PI_2) {
            return Err(OrientationError::VectorSpread(spread.to_degrees()));
        }
        Ok(Orientation::ToolAxisCurve { curve })
    }

    /// The same rotary curve under tool-centre-point control (G43.4): the
    /// path is the tool tip and the rotary joints follow the curve (see
    /// [`Orientation::AxesCurve`]). Other orientations are returned as they are.
    pub fn under_tcp(mut self) -> Self {
        if let Orientation::AxesCurve { tcp, .. } = &mut self {
            *tcp = true;
        }
        self
    }

    /// The same turn with the tool tip (or X Y Z) standing at `at`: a turn
    /// in place, whose path is its measure ([`TurnInPlace`]).
    pub fn in_place(self, at: Vec3) -> Self {
        self.with_fixed(Some(at))
    }

    fn with_fixed(mut self, at: Option<Vec3>) -> Self {
        match &mut self {
            Orientation::Axes { fixed, .. } | Orientation::ToolAxis { fixed, .. } => *fixed = at,
            // (A NURBS always moves the tip.)
            Orientation::AxesCurve { .. } | Orientation::ToolAxisCurve { .. } => {}
        }
        self
    }

    /// Where the tool tip (or X Y Z) stands during a turn in place.
    #[inline]
    pub fn fixed(&self) -> Option<Vec3> {
        match self {
            Orientation::Axes { fixed, .. } | Orientation::ToolAxis { fixed, .. } => *fixed,
            Orientation::AxesCurve { .. } | Orientation::ToolAxisCurve { .. } => None,
        }
    }

    /// The same orientation over the parameter range `u0..u1` (a block cut
    /// or joined keeps one orientation over its whole range).
    pub fn with_range(mut self, from: f64, to: f64) -> Self {
        match &mut self {
            Orientation::Axes { u0, u1, .. } | Orientation::ToolAxis { u0, u1, .. } => {
                (*u0, *u1) = (from, to)
            }
            Orientation::AxesCurve { curve, .. } | Orientation::ToolAxisCurve { curve } => {
                (curve.u0, curve.u1) = (from, to)
            }
        }
        self
    }

    /// Under tool-centre-point control (the path is the tool tip)?
    pub fn is_tcp(&self) -> bool {
        matches!(
            self,
            Orientation::ToolAxis { .. }
                | Orientation::AxesCurve { tcp: true, .. }
                | Orientation::ToolAxisCurve { .. }
        )
    }

    /// The tool axis in the workpiece frame at parameter `u` under
    /// tool-centre-point control: the programmed one, or, for a rotary
    /// curve, the machine's at the curve's rotary positions (which needs
    /// `machine`). `None` without tool-centre-point control.
    pub fn axis_at(&self, machine: Option<&Machine>, u: f64) -> Option<Vec3> {
        match (self.at(u), self) {
            (OrientationAt::ToolAxis(a), _) => Some(a),
            (OrientationAt::Axes(abc), Orientation::AxesCurve { tcp: true, .. }) => {
                // (The linear joints do not turn the tool.)
                machine.map(|m| m.forward(&[0.0, 0.0, 0.0, abc[0], abc[1], abc[2]]).axis)
            }
            _ => None,
        }
    }

    fn fraction(u: f64, u0: f64, u1: f64) -> f64 {
        ((u - u0) / (u1 - u0)).clamp(0.0, 1.0)
    }

    /// The orientation at parameter `u` of the block.
    #[inline]
    pub fn at(&self, u: f64) -> OrientationAt {
        match *self {
            Orientation::Axes {
                start, end, u0, u1, ..
            } => {
                let f = Self::fraction(u, u0, u1);
                let mut q = [0.0; 3];
                for (k, q) in q.iter_mut().enumerate() {
                    // Exact at both ends.
                    *q = if f == 1.0 {
                        end[k]
                    } else {
                        start[k] + (end[k] - start[k]) * f
                    };
                }
                OrientationAt::Axes(q)
            }
            Orientation::ToolAxis {
                start,
                w,
                theta,
                u0,
                u1,
                ..
            } => {
                let phi = theta * Self::fraction(u, u0, u1);
                OrientationAt::ToolAxis(start * libm::cos(phi) + w * libm::sin(phi))
            }
            Orientation::AxesCurve { curve, .. } => OrientationAt::Axes(curve.at(u)),
            Orientation::ToolAxisCurve { curve } => {
                let [x, y, z] = curve.at(u);
                let v = Vec3::new(x, y, z);
                OrientationAt::ToolAxis(v / v.norm())
            }
        }
    }

    /// The joints at tip (or X Y Z) `p` and parameter `u`, nearest `prev`.
    /// Under tool-centre-point control `machine` is required.
    #[inline]
    pub fn joints(
        &self,
        machine: Option<&Machine>,
        p: Vec3,
        u: f64,
        prev: &Joints,
    ) -> Result<Joints, JointError> {
        self.solve(machine, p, u, prev).map(|(q, _)| q)
    }

    /// [`Self::joints`], and whether the tool axis is at the pole (the
    /// first rotary joint kept its value). In a turn in place `p` (a point
    /// of the turn's measure) is not looked at: the tip stands still.
    pub fn solve(
        &self,
        machine: Option<&Machine>,
        p: Vec3,
        u: f64,
        prev: &Joints,
    ) -> Result<(Joints, bool), JointError> {
        let p = self.fixed().unwrap_or(p);
        match self.at(u) {
            OrientationAt::Axes(abc) if self.is_tcp() => {
                let m = machine.ok_or(JointError::NoMachine)?;
                m.place_tip(&p, abc, prev)
                    .map(|q| (q, false))
                    .map_err(JointError::Inverse)
            }
            OrientationAt::Axes(abc) => Ok(([p.x, p.y, p.z, abc[0], abc[1], abc[2]], false)),
            OrientationAt::ToolAxis(axis) => {
                let m = machine.ok_or(JointError::NoMachine)?;
                m.inverse(&ToolPose { tip: p, axis }, prev)
                    .map(|s| (s.joints, s.at_pole))
                    .map_err(JointError::Inverse)
            }
        }
    }
}

/// The rational Bézier curve of `values` with weights `w` (the first
/// `degree + 1` of each) at `t ∈ [0, 1]`: exactly the end values at the
/// ends (where the next span starts, so neighbours meet bit for bit).
fn rational_bezier(values: &[[f64; 3]; BEZIER], w: &[f64; BEZIER], p: usize, t: f64) -> [f64; 3] {
    if t == 0.0 {
        return values[0];
    }
    if t == 1.0 {
        return values[p];
    }
    // De Casteljau on the homogeneous values (w·x, w·y, w·z, w).
    let mut h = [[0.0; 4]; BEZIER];
    for k in 0..=p {
        let v = values[k];
        h[k] = [w[k] * v[0], w[k] * v[1], w[k] * v[2], w[k]];
    }
    for r in 1..=p {
        for k in 0..=p - r {
            for j in 0..4 {
                h[k][j] = (1.0 - t) * h[k][j] + t * h[k + 1][j];
            }
        }
    }
    let [a, b, c, ww] = h[0];
    [a / ww, b / ww, c / ww]
}

/// Why the joints of a five-axis block could not be had.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum JointError {
    /// Tool-centre-point control needs `InterpConfig::machine`.
    NoMachine,
    /// The inverse transform failed (out of the rotary ranges, …).
    Inverse(InverseError),
    /// The block's rotary axes or tool axis do not start where the queue's
    /// end has them: by this much (degrees of a rotary joint, or of the
    /// tool axis).
    Jump(f64),
    /// The tool axis leaves the pole (where the first rotary joint is kept)
    /// in a direction that needs that joint elsewhere: it would jump by
    /// this much, degrees. Program the move so that the axis leaves the
    /// pole towards where that joint stands, or turn it first.
    PoleDeparture(f64),
}

impl core::fmt::Display for JointError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            JointError::NoMachine => write!(
                f,
                "tool-centre-point control needs a machine in the configuration"
            ),
            JointError::Inverse(e) => write!(f, "{e}"),
            JointError::PoleDeparture(d) => write!(
                f,
                "the tool axis leaves the pole where the first rotary axis would have to jump by {} degrees: turn it first, or leave the pole towards where it stands",
                Degrees(*d)
            ),
            JointError::Jump(d) => write!(
                f,
                "the rotary axes or the tool axis do not start where the previous move left them ({} degrees off)",
                Degrees(*d)
            ),
        }
    }
}

/// The joints and their derivatives in arc length at one point of a block,
/// and the second-order terms that decide how far the drives' linear joint
/// interpolation leaves the programmed path between two setpoints.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointSample {
    /// The joints at the sampled parameter (the derivatives are taken
    /// [`JOINT_STEP`]s inside the block where it is nearer an end).
    pub q: Joints,
    /// `dq/ds` (per mm of path).
    pub q_s: [f64; 6],
    /// `d²q/ds²`.
    pub q_ss: [f64; 6],
    /// `d³q/ds³`.
    pub q_sss: [f64; 6],
    /// The part across the path of `J·q_ss` (1/mm): the path's curvature
    /// vector less what linear motion of the joints along `q_s` bends the
    /// tip by. Two setpoints `Δs` apart are joined by the drives on a curve
    /// that leaves the path by `Δs²·tip_bend/8` (to leading order).
    pub tip_bend: f64,
    /// The same for the tool axis (rad/mm²): the angle between the axis
    /// between two setpoints and the programmed axis at the path point
    /// nearest the tip is `Δs²·axis_bend/8`.
    pub axis_bend: f64,
}

impl JointSample {
    /// Samples the joints of `path` with `orientation` at parameter `u`,
    /// nearest `prev`: a five-point stencil of [`Orientation::joints`]
    /// [`JOINT_STEP`] apart in arc length (moved inside the block at its
    /// ends), carried to arc length by the chain rule. `None` where the path
    /// does not move (`C' = 0`).
    pub fn new(
        machine: Option<&Machine>,
        orientation: &Orientation,
        path: &Path,
        u: f64,
        prev: &Joints,
    ) -> Result<Option<Self>, JointError> {
        let (ua, ub) = (path.u_start(), path.u_end());
        let d = path.eval(u, 3);
        let sigma = d.d1.norm();
        if !(sigma > 0.0) {
            return Ok(None);
        }
        let du = (JOINT_STEP / sigma).min(0.25 * (ub - ua));
        let uc = u.clamp(ua + 2.0 * du, ub - 2.0 * du);
        let d = path.eval(uc, 3);
        let sigma = d.d1.norm();
        if !(sigma > 0.0) {
            return Ok(None);
        }
        let q0 = orientation.joints(machine, d.p, uc, prev)?;
        let mut q = [q0; 5];
        let mut axes = [Vec3::zeros(); 5];
        for k in [-2i32, -1, 1, 2] {
            let uk = uc + k as f64 * du;
            let p = path.eval(uk, 0).p;
            q[(k + 2) as usize] = orientation.joints(machine, p, uk, &q0)?;
        }
        for (k, a) in axes.iter_mut().enumerate() {
            if let Some(v) = orientation.axis_at(machine, uc + (k as f64 - 2.0) * du) {
                *a = v;
            }
        }
        // σ' and σ'' of the tip speed in u, for the chain rule.
        let sp = d.d1.dot(&d.d2) / sigma;
        let spp = (d.d2.norm_squared() + d.d1.dot(&d.d3) - sp * sp) / sigma;
        let to_s = |fu: f64, fuu: f64, fuuu: f64| {
            let s2 = sigma * sigma;
            let f_s = fu / sigma;
            let f_ss = (fuu * sigma - fu * sp) / (s2 * sigma);
            let f_sss = (fuuu * sigma - fu * spp) / (s2 * s2)
                - 3.0 * sp * (fuu * sigma - fu * sp) / (s2 * s2 * sigma);
            (f_s, f_ss, f_sss)
        };
        let (h, h2, h3) = (du, du * du, du * du * du);
        // The joints at `u` itself (the stencil may sit inside the block).
        let q_u = if uc == u {
            q0
        } else {
            orientation.joints(machine, path.eval(u, 0).p, u, &q0)?
        };
        let mut out = JointSample {
            q: q_u,
            q_s: [0.0; 6],
            q_ss: [0.0; 6],
            q_sss: [0.0; 6],
            tip_bend: 0.0,
            axis_bend: 0.0,
        };
        for j in 0..6 {
            let [m2, m1, c, p1, p2] = [q[0][j], q[1][j], q[2][j], q[3][j], q[4][j]];
            let fu = (m2 - 8.0 * m1 + 8.0 * p1 - p2) / (12.0 * h);
            let fuu = (-m2 + 16.0 * m1 - 30.0 * c + 16.0 * p1 - p2) / (12.0 * h2);
            let fuuu = (-m2 + 2.0 * m1 - 2.0 * p1 + p2) / (2.0 * h3);
            (out.q_s[j], out.q_ss[j], out.q_sss[j]) = to_s(fu, fuu, fuuu);
        }
        if let (Some(m), true) = (machine, orientation.is_tcp()) {
            // The programmed second derivatives in arc length.
            let c_ss = (d.d2 * sigma - d.d1 * sp) / (sigma * sigma * sigma);
            let a_u = (axes[0] - axes[1] * 8.0 + axes[3] * 8.0 - axes[4]) / (12.0 * h);
            let a_uu = (-axes[0] + axes[1] * 16.0 - axes[2] * 30.0 + axes[3] * 16.0 - axes[4])
                / (12.0 * h2);
            let a_ss = (a_uu * sigma - a_u * sp) / (sigma * sigma * sigma);
            // What linear joint motion along q_s does to tip and axis.
            let e = JOINT_STEP;
            let shifted = |sign: f64| {
                let mut j = q0;
                for (k, v) in j.iter_mut().enumerate() {
                    *v += sign * e * out.q_s[k];
                }
                m.forward(&j)
            };
            let (lo, mid, hi) = (shifted(-1.0), m.forward(&q0), shifted(1.0));
            let tip_lin = (lo.tip - mid.tip * 2.0 + hi.tip) / (e * e);
            let axis_lin = (lo.axis - mid.axis * 2.0 + hi.axis) / (e * e);
            // The drives' curve leaves the path by Δs²/8 of `e_tip`: its part
            // across the path is the tip's distance from it, its part along
            // the path moves the nearest path point, and so the programmed
            // axis the actual one is measured against.
            let t = d.d1 / sigma;
            let e_tip = c_ss - tip_lin;
            // (In a turn in place there is no path for the tip to slide
            // along: all of the bend is off the program.)
            let along = if orientation.fixed().is_some() {
                0.0
            } else {
                t.dot(&e_tip)
            };
            out.tip_bend = (e_tip - t * along).norm();
            out.axis_bend = (a_ss - axis_lin - (a_u / sigma) * along).norm();
        }
        Ok(Some(out))
    }

    /// The largest path speed (mm/s) at which every joint keeps its
    /// velocity, the curvature share of its acceleration and its steady
    /// jerk (`|q_sss|·v³`) within the limits of `cfg` (at `1 −
    /// planning_margin`), and, under tool-centre-point control, the drives'
    /// linear joint interpolation keeps the tip within `chord_tolerance`
    /// and the tool axis within `angular_tolerance` of their program
    /// between setpoints.
    pub fn speed_limit(&self, cfg: &InterpConfig) -> f64 {
        let keep = 1.0 - cfg.planning_margin;
        let mut v = f64::INFINITY;
        for j in 0..6 {
            let (vmax, amax, jmax) = cfg.joint_limits(j);
            let (qs, qss, qsss) = (
                libm::fabs(self.q_s[j]),
                libm::fabs(self.q_ss[j]),
                libm::fabs(self.q_sss[j]),
            );
            if qs > 0.0 {
                v = v.min(keep * vmax / qs);
            }
            if qss > 0.0 {
                // The tangential part is held to `tangential_accel` (below).
                let tangential = qs * self.tangential_accel_for(j, cfg);
                let acc = (keep * amax - tangential).max(0.0);
                v = v.min(libm::sqrt(acc / qss));
            }
            if qsss > 0.0 {
                v = v.min(libm::cbrt(keep * jmax / qsss));
            }
        }
        let ts = cfg.period;
        if self.tip_bend > 0.0 {
            v = v.min(libm::sqrt(8.0 * keep * cfg.chord_tolerance / self.tip_bend) / ts);
        }
        if self.axis_bend > 0.0 {
            v = v.min(libm::sqrt(8.0 * keep * cfg.angular_tolerance / self.axis_bend) / ts);
        }
        v
    }

    fn tangential_accel_for(&self, j: usize, cfg: &InterpConfig) -> f64 {
        let (_, amax, _) = cfg.joint_limits(j);
        let qs = libm::fabs(self.q_s[j]);
        let share = cfg.axis_tangential_share * (1.0 - cfg.planning_margin) * amax;
        if qs > 0.0 {
            cfg.planned_accel().min(share / qs)
        } else {
            cfg.planned_accel()
        }
    }

    /// The tangential acceleration and jerk (mm/s², mm/s³) a feed hold may
    /// brake with here: each joint's tangential share of its acceleration
    /// and jerk (as [`InterpConfig::planned_accel`] and
    /// [`InterpConfig::planned_jerk`] for the axes).
    pub fn stop_limits(&self, cfg: &InterpConfig) -> (f64, f64) {
        let share = cfg.axis_tangential_share * (1.0 - cfg.planning_margin);
        self.joint_bounded(cfg, share, share)
    }

    /// The path's tangential acceleration and jerk limits (mm/s², mm/s³)
    /// that keep every joint's tangential share: `|q_s|·a` within
    /// `axis_tangential_share` of its acceleration, `|q_s|·j` within its jerk.
    pub fn tangential_limits(&self, cfg: &InterpConfig) -> (f64, f64) {
        let keep = 1.0 - cfg.planning_margin;
        self.joint_bounded(cfg, cfg.axis_tangential_share * keep, keep)
    }

    /// The smallest `ka·a_max/|q_s|` and `kj·j_max/|q_s|` over the joints
    /// that move: the path's acceleration and jerk that keep each joint
    /// within those fractions of its limits.
    fn joint_bounded(&self, cfg: &InterpConfig, ka: f64, kj: f64) -> (f64, f64) {
        let mut a = f64::INFINITY;
        let mut jerk = f64::INFINITY;
        for j in 0..6 {
            let qs = libm::fabs(self.q_s[j]);
            if qs > 0.0 {
                let (_, amax, jmax) = cfg.joint_limits(j);
                a = a.min(ka * amax / qs);
                jerk = jerk.min(kj * jmax / qs);
            }
        }
        (a, jerk)
    }
}

/// The speed at which a junction whose joint rates in arc length jump by
/// `jump` (per mm) keeps every joint's sampled jerk `v·|Δq_s|/Ts²` within
/// half its limit (the other half bounds the curvature on both sides, as
/// [`crate::feed::junction_speed`] does for the axes), mm/s.
pub fn joint_junction_speed(jump: &[f64; 6], cfg: &InterpConfig) -> f64 {
    let keep = 1.0 - cfg.planning_margin;
    let ts = cfg.period;
    let mut v = f64::INFINITY;
    for (j, d) in jump.iter().enumerate() {
        let d = libm::fabs(*d);
        if d > 0.0 {
            let (_, amax, jmax) = cfg.joint_limits(j);
            v = v.min(0.5 * keep * (jmax * ts * ts).min(amax * ts) / d);
        }
    }
    v
}

/// What the planner keeps of the end of the queue for five-axis blocks:
/// the joints there, the frame of the path coordinates (tool tip under
/// tool-centre-point control, X Y Z of the machine otherwise), and the
/// joint rates in arc length at the end of the last block that had an
/// orientation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QueueEnd {
    /// The joints at the end of the queue.
    pub joints: Joints,
    /// The path coordinates there are the tool tip.
    pub tcp: bool,
    /// `dq/ds` at the end of the last block, if it had an orientation.
    pub q_s: Option<[f64; 6]>,
}

impl QueueEnd {
    /// At rest at `joints`, tool-centre-point control off.
    pub fn new(joints: Joints) -> Self {
        QueueEnd {
            joints,
            tcp: false,
            q_s: None,
        }
    }

    /// Where a block under tool-centre-point control (`tcp`) or not must
    /// start, given the queue ends at `tail` in the queue's own frame: the
    /// same point, or the same machine pose seen in the other frame (the
    /// tool tip of the joints, or the joints' X Y Z).
    pub fn start_for(
        &self,
        machine: Option<&Machine>,
        tcp: bool,
        tail: Vec3,
    ) -> Result<Vec3, JointError> {
        match (self.tcp, tcp) {
            (a, b) if a == b => Ok(tail),
            (false, true) => Ok(machine
                .ok_or(JointError::NoMachine)?
                .forward(&self.joints)
                .tip),
            _ => Ok(Vec3::new(self.joints[0], self.joints[1], self.joints[2])),
        }
    }
}

/// Largest jump of a rotary joint accepted where the tool axis leaves the
/// pole (measured a ten-thousandth of a law sample's step off it), degrees.
pub const POLE_DEPARTURE_TOLERANCE: f64 = 1e-3;

/// Largest jump accepted between where the queue's end leaves the rotary
/// joints (or the tool axis) and where a block starts them, degrees.
pub const JOIN_ANGLE_TOLERANCE: f64 = 1e-7;

impl QueueEnd {
    /// Does `o` start where the queue ends (rotary joints, or tool axis)?
    pub fn check_join(
        &self,
        machine: Option<&Machine>,
        o: &Orientation,
        u: f64,
    ) -> Result<(), JointError> {
        let off = match o.at(u) {
            OrientationAt::Axes(abc) => (0..3)
                .map(|k| libm::fabs(abc[k] - self.joints[3 + k]))
                .fold(0.0, f64::max),
            OrientationAt::ToolAxis(a) => {
                let have = machine
                    .ok_or(JointError::NoMachine)?
                    .forward(&self.joints)
                    .axis;
                libm::atan2(have.cross(&a).norm(), have.dot(&a)).to_degrees()
            }
        };
        if off <= JOIN_ANGLE_TOLERANCE {
            Ok(())
        } else {
            Err(JointError::Jump(off))
        }
    }
}

/// Calls `f(s, u)` at the law sample positions of a segment (arc length `s`
/// of the run a multiple of `hs`, from `s0` over `length`), with `u` its
/// parameter in `path`.
fn for_each_sample(path: &Path, s0: f64, length: f64, hs: f64, mut f: impl FnMut(f64, f64)) {
    let k0 = libm::ceil(s0 / hs) as i64;
    let k1 = libm::floor((s0 + length) / hs) as i64;
    let (mut u_prev, mut x_prev) = (path.u_start(), s0);
    f(s0, u_prev);
    for k in k0..=k1 {
        let x = k as f64 * hs;
        let u = path.param_at_arc_length(u_prev, x - x_prev);
        f(x, u);
        u_prev = u;
        x_prev = x;
    }
    f(s0 + length, path.u_end());
}

/// Walks the joints of a segment at its law samples (nearest each other,
/// from `joints`) and leaves the joints at its end in `joints`: the check,
/// before the planner touches its window, that the whole block is within
/// the machine's reach.
pub fn walk_joints(
    machine: Option<&Machine>,
    orientation: &Orientation,
    path: &Path,
    s0: f64,
    length: f64,
    hs: f64,
    joints: &mut Joints,
) -> Result<(), JointError> {
    let mut r = Ok(());
    // The last sample at the pole (its parameter), if the last was.
    let mut pole: Option<f64> = None;
    for_each_sample(path, s0, length, hs, |_, u| {
        if r.is_err() {
            return;
        }
        let solved = orientation.solve(machine, path.eval(u, 0).p, u, joints);
        let (q, at_pole) = match solved {
            Ok(v) => v,
            Err(e) => {
                r = Err(e);
                return;
            }
        };
        if let (Some(u_pole), false) = (pole, at_pole) {
            // Leaving the pole: just off it, the joints must be where they
            // stand (a continuous departure), not elsewhere (a jump).
            let near = u_pole + (u - u_pole) * 1e-4;
            match orientation.solve(machine, path.eval(near, 0).p, near, joints) {
                Ok((qn, false)) => {
                    let jump = (3..6)
                        .map(|k| libm::fabs(qn[k] - joints[k]))
                        .fold(0.0, f64::max);
                    if jump > POLE_DEPARTURE_TOLERANCE {
                        r = Err(JointError::PoleDeparture(jump));
                        return;
                    }
                }
                Ok((_, true)) => {}
                Err(e) => {
                    r = Err(e);
                    return;
                }
            }
        }
        pole = at_pole.then_some(u);
        *joints = q;
    });
    r
}

/// Puts the joints' limits of a segment into the planner's window: at each
/// law sample a [`JointSample`]'s [`speed_limit`](JointSample::speed_limit)
/// lowers the interval's machine limit, its
/// [`tangential_limits`](JointSample::tangential_limits) the interval's
/// acceleration and jerk, and where a joint's jerk may bind, per-axis
/// samples go to the linear program's jerk rows (two per point, the linear
/// and the rotary joints, each scaled by `axis_max_jerk / joint jerk limit`
/// so that the rows' axis limits stand for the joint's). Returns the joint
/// rates at the segment's end (`None` if it ends at rest) and the
/// segment's braking limits ([`JointSample::stop_limits`], their minimum),
/// and moves `joints` there.
#[allow(clippy::too_many_arguments)]
pub(crate) fn sample_joints(
    machine: Option<&Machine>,
    orientation: &Orientation,
    path: &Path,
    s0: f64,
    length: f64,
    cfg: &InterpConfig,
    w: &mut Window,
    h: f64,
    hs: f64,
    joints: &mut Joints,
) -> (Option<[f64; 6]>, (f64, f64)) {
    let mut last = None;
    let mut stop = (f64::INFINITY, f64::INFINITY);
    // The previous sample's arc length and speed limit: between two samples
    // the lower of the two holds, as for the feed laws.
    let mut prev: Option<(f64, f64)> = None;
    for_each_sample(path, s0, length, hs, |s, u| {
        let Ok(Some(smp)) = JointSample::new(machine, orientation, path, u, joints) else {
            return;
        };
        *joints = smp.q;
        last = Some(smp.q_s);
        let (sa, sj) = smp.stop_limits(cfg);
        stop = (stop.0.min(sa), stop.1.min(sj));
        let v = smp.speed_limit(cfg);
        let (a, j) = smp.tangential_limits(cfg);
        match prev {
            Some((sp, vp)) => w.lower_range(sp, s, 0, vp.min(v)),
            None => w.lower_range(s, s, 0, v),
        }
        prev = Some((s, v));
        let g = index_of(s, h);
        let on_node = g as f64 * h == s;
        for gi in [g - 1, g] {
            if (gi == g || on_node)
                && let Some(it) = w.interval_mut(gi)
            {
                it.accel = it.accel.min(a);
                it.jerk = it.jerk.min(j);
                it.joint_jerk = it.joint_jerk.min(j);
            }
        }
        let l2 = v.min(cfg.max_path_speed) * v.min(cfg.max_path_speed);
        for group in 0..2 {
            let mut smp_ax = AxisSample {
                s,
                ..AxisSample::default()
            };
            for ax in 0..3 {
                let jt = 3 * group + ax;
                let scale = cfg.axis_max_jerk[ax] / cfg.joint_limits(jt).2;
                smp_ax.t[ax] = smp.q_s[jt] * scale;
                smp_ax.css[ax] = smp.q_ss[jt] * scale;
                smp_ax.csss[ax] = smp.q_sss[jt] * scale;
            }
            if (0..3).any(|ax| axis_jerk_may_bind(&smp_ax, ax, l2, cfg)) {
                keep_axis_sample(w, smp_ax, h, l2, cfg);
            }
        }
    });
    (last, stop)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kinematics::MachineSpec;
    use crate::path::{Arc, Line};

    fn ca_machine() -> Machine {
        let mut spec = MachineSpec::new("W/caxyBz/T".parse().expect("chain"));
        spec.tool_length = 100.0;
        spec.rotary_centres[0] = [0.0, 0.0, -50.0];
        Machine::new(spec).expect("machine")
    }

    #[test]
    fn tool_axis_turns_on_the_great_circle_at_a_constant_rate() {
        let path = Path::Line(
            Line::new(Vec3::new(0.0, 0.0, 0.0), Vec3::new(10.0, 0.0, 0.0)).expect("line"),
        );
        let (a, b) = (Vec3::new(0.0, 0.0, 2.0), Vec3::new(1.0, 0.0, 1.0));
        let o = Orientation::tool_axis(&path, a, b).expect("orientation");
        for k in 0..=10 {
            let OrientationAt::ToolAxis(v) = o.at(k as f64) else {
                panic!("tool axis")
            };
            let angle = libm::atan2(v.x, v.z);
            assert!((v.norm() - 1.0).abs() < 1e-15);
            assert!((angle - 0.25 * core::f64::consts::PI * k as f64 / 10.0).abs() < 1e-15);
            assert!(v.y.abs() < 1e-16);
        }
        assert!(matches!(
            Orientation::tool_axis(&path, a, -a),
            Err(OrientationError::HalfTurn(_))
        ));
        assert!(matches!(
            Orientation::tool_axis(&path, Vec3::zeros(), a),
            Err(OrientationError::BadValue)
        ));
    }

    /// A helix with the tool axis turning about z with the tip: every
    /// derivative of the joints is known in closed form on a C,A table.
    #[test]
    fn joint_derivatives_match_the_closed_form() {
        let m = ca_machine();
        let r = 20.0;
        // Quarter turn of a circle of radius r about z, in the plane z = 5.
        let arc = Arc::from_centre(
            Vec3::new(r, 0.0, 5.0),
            Vec3::new(0.0, r, 5.0),
            Vec3::new(0.0, 0.0, 5.0),
            Vec3::z(),
            0,
        )
        .expect("arc");
        let path = Path::Arc(arc);
        // The tool axis tilted by 30 degrees towards +x at the start, turned
        // a quarter about z with the tip: it stays radial.
        let tilt = 30f64.to_radians();
        let a0 = Vec3::new(libm::sin(tilt), 0.0, libm::cos(tilt));
        let a1 = Vec3::new(0.0, libm::sin(tilt), libm::cos(tilt));
        let o = Orientation::tool_axis(&path, a0, a1).expect("orientation");
        let prev = [0.0, 0.0, 0.0, 30.0, 0.0, 90.0];
        let u = 0.3;
        let smp = JointSample::new(Some(&m), &o, &path, u, &prev)
            .expect("joints")
            .expect("moving");
        // The slerp from a0 to a1 is not the small circle a radial axis
        // follows, but its rates are: the axis turns by θ over the arc.
        let theta = libm::acos(a0.dot(&a1));
        let len = path.length();
        // Axis angular rate per mm: θ / L; A stays near 30°, C turns at a rate
        // that makes the axis sweep its great-circle angle.
        let pose = m.forward(&smp.q);
        let OrientationAt::ToolAxis(want) = o.at(u) else {
            panic!()
        };
        assert!((pose.axis - want).norm() < 1e-12);
        assert!((pose.tip - path.eval(u, 0).p).norm() < 1e-9);
        // Joint rates from the Jacobian at the same point.
        let d = path.eval(u, 1);
        let tip_v = d.d1 / d.d1.norm();
        let axis_v = {
            let OrientationAt::ToolAxis(a2) = o.at(u + 1e-6) else {
                panic!()
            };
            let OrientationAt::ToolAxis(a1) = o.at(u - 1e-6) else {
                panic!()
            };
            (a2 - a1) / (2e-6 * d.d1.norm())
        };
        assert!((axis_v.norm() - theta / len).abs() < 1e-6 * theta / len);
        let rates = m.joint_rates(&smp.q, &tip_v, &axis_v).expect("rates");
        for j in 0..6 {
            assert!(
                (rates[j] - smp.q_s[j]).abs() < 1e-6 * (1.0 + rates[j].abs()),
                "joint {j}: {} vs {}",
                rates[j],
                smp.q_s[j]
            );
        }
        // The second derivative by differences of the Jacobian's rates.
        let at = |uu: f64| {
            let d = path.eval(uu, 1);
            let OrientationAt::ToolAxis(a) = o.at(uu) else {
                panic!()
            };
            let q = m
                .inverse(&ToolPose { tip: d.p, axis: a }, &smp.q)
                .expect("ik")
                .joints;
            let e = 1e-6;
            let (OrientationAt::ToolAxis(ap), OrientationAt::ToolAxis(am)) =
                (o.at(uu + e), o.at(uu - e))
            else {
                panic!()
            };
            let sig = d.d1.norm();
            m.joint_rates(&q, &(d.d1 / sig), &((ap - am) / (2.0 * e * sig)))
                .expect("rates")
        };
        let h = 1e-3;
        let (qp, qm) = (at(u + h), at(u - h));
        let ds = 2.0 * h * path.eval(u, 1).d1.norm();
        for j in 0..6 {
            let qss = (qp[j] - qm[j]) / ds;
            assert!(
                (qss - smp.q_ss[j]).abs() < 1e-4 * (1.0 + qss.abs()),
                "joint {j}: {qss} vs {}",
                smp.q_ss[j]
            );
        }
    }

    #[test]
    fn error_angles_are_rounded_to_a_millionth_of_a_degree() {
        extern crate std;
        use std::format;
        assert_eq!(format!("{}", Degrees(0.5999999999999943)), "0.6");
        assert_eq!(format!("{}", Degrees(90.00000000001)), "90");
        assert_eq!(format!("{}", Degrees(-12.3456789)), "-12.345679");
        assert_eq!(format!("{}", Degrees(2.345e-7)), "2.3e-7");
        assert_eq!(format!("{}", Degrees(0.0)), "0");
        let e = JointError::PoleDeparture(0.5999999999999943);
        assert!(format!("{e}").contains("jump by 0.6 degrees"), "{e}");
    }

    #[test]
    fn a_tool_vector_curve_is_its_normalised_rational_bezier() {
        // A quarter circle of vectors as an exact rational quadratic (the
        // middle vector √2 long, weight 1/√2): unit length throughout, at
        // the angle its rational parametrisation gives.
        let h = core::f64::consts::FRAC_1_SQRT_2;
        let vs = [[1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]];
        let o = Orientation::tool_axis_curve(2, &vs, &[1.0, h, 1.0], 2.0, 4.0).expect("curve");
        assert!(o.is_tcp() && o.fixed().is_none());
        for k in 0..=8 {
            let t = k as f64 / 8.0;
            let OrientationAt::ToolAxis(a) = o.at(2.0 + 2.0 * t) else {
                panic!("a tool axis")
            };
            // The rational quadratic's angle: tan(φ/2) = t·w/((1−t) + t·w)·…
            // here simply atan2 of the unnormalised curve.
            let (b0, b1, b2) = ((1.0 - t) * (1.0 - t), 2.0 * t * (1.0 - t) * h, t * t);
            let phi = libm::atan2(b1 + b2, b0 + b1);
            assert!((a - Vec3::new(libm::cos(phi), libm::sin(phi), 0.0)).norm() < 1e-15);
        }
        // Ends exactly the end vectors, normalised; lengths do not matter there.
        let o2 = Orientation::tool_axis_curve(
            1,
            &[[0.0, 0.0, 3.0], [0.0, 4.0, 4.0]],
            &[1.0, 1.0],
            0.0,
            1.0,
        )
        .expect("curve");
        assert_eq!(o2.at(0.0), OrientationAt::ToolAxis(Vec3::z()));
        assert_eq!(
            o2.at(1.0),
            OrientationAt::ToolAxis(Vec3::new(0.0, 4.0, 4.0).normalize())
        );
        // Refused: a zero or non-finite vector, a bad weight, vectors that
        // spread over more than a half-space (the curve may pass zero).
        let bad = |vs: &[[f64; 3]], w: &[f64]| Orientation::tool_axis_curve(1, vs, w, 0.0, 1.0);
        assert_eq!(
            bad(&[[0.0; 3], [0.0, 0.0, 1.0]], &[1.0; 2]),
            Err(OrientationError::BadValue)
        );
        assert_eq!(
            bad(&[[f64::NAN, 0.0, 1.0], [0.0, 0.0, 1.0]], &[1.0; 2]),
            Err(OrientationError::BadValue)
        );
        assert_eq!(
            bad(&[[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]], &[1.0, 0.0]),
            Err(OrientationError::BadValue)
        );
        // Three vectors 120° apart in the xy plane: no mean direction
        // (their curve passes through zero at some weights).
        let (c, sn) = (-0.5, 0.75f64.sqrt());
        let three = |z: f64| [[1.0, 0.0, z], [c, sn, z], [c, -sn, z]];
        let curve = |vs: &[[f64; 3]]| Orientation::tool_axis_curve(2, vs, &[1.0; 3], 0.0, 1.0);
        assert_eq!(
            curve(&three(0.0)),
            Err(OrientationError::VectorSpread(180.0))
        );
        assert!(curve(&three(0.01)).is_ok());
        // With +z besides: the mean is +z, 90° from the three.
        let mut four = three(0.0).to_vec();
        four.push([0.0, 0.0, 1.0]);
        let Err(OrientationError::VectorSpread(d)) =
            Orientation::tool_axis_curve(3, &four, &[1.0; 4], 0.0, 1.0)
        else {
            panic!("spread accepted")
        };
        assert!((d - 90.0).abs() < 1e-9, "{d}");
        // 170° apart is still one side of a plane (85° from the mean).
        let a = tilted(85.0);
        let b = tilted(-85.0);
        assert!(bad(&[a, b], &[1.0; 2]).is_ok());
    }

    fn tilted(deg: f64) -> [f64; 3] {
        let r = deg.to_radians();
        [libm::sin(r), 0.0, libm::cos(r)]
    }

    #[test]
    fn plain_axes_move_in_proportion_and_need_no_machine() {
        let path = Path::Line(
            Line::new(Vec3::new(0.0, 0.0, 0.0), Vec3::new(10.0, 0.0, 0.0)).expect("line"),
        );
        let o = Orientation::axes(&path, [0.0, 0.0, 0.0], [20.0, 0.0, -40.0]).expect("axes");
        let q = o
            .joints(None, Vec3::new(5.0, 0.0, 0.0), 5.0, &[0.0; 6])
            .expect("joints");
        assert_eq!(q, [5.0, 0.0, 0.0, 10.0, 0.0, -20.0]);
        let smp = JointSample::new(None, &o, &path, 5.0, &[0.0; 6])
            .expect("ok")
            .expect("moving");
        assert!((smp.q_s[3] - 2.0).abs() < 1e-9 && (smp.q_s[5] + 4.0).abs() < 1e-9);
        assert!(smp.q_ss.iter().all(|v| v.abs() < 1e-6));
        assert_eq!((smp.tip_bend, smp.axis_bend), (0.0, 0.0));
        // Rotary velocity 180 deg/s at 4 deg/mm: 45 mm/s (less the margin).
        let cfg = InterpConfig::default();
        let v = smp.speed_limit(&cfg);
        assert!((v - 0.98 * 180.0 / 4.0).abs() < 1e-6, "{v}");
        let tcp = Orientation::tool_axis(&path, Vec3::z(), Vec3::x()).expect("tcp");
        assert_eq!(
            tcp.joints(None, Vec3::zeros(), 0.0, &[0.0; 6]),
            Err(JointError::NoMachine)
        );
    }
}
