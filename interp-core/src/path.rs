//! Path kinds of a block: straight line, circular/helical arc, NURBS.
//!
//! All are exact: the interpolator evaluates them analytically at every tick.

use crate::fiveaxis::Orientation;
use crate::geom::{Curve, Derivs, Vec3};
use crate::nurbs::{Nurbs, NurbsError};
use nalgebra::Rotation3;

/// Relative tolerance on the two radii of an arc given by its centre
/// (start–centre vs end–centre), as a fraction of the radius. LinuxCNC allows
/// 0.002 mm absolute or 0.1 % relative; we accept the larger of the two.
pub const ARC_RADIUS_REL_TOL: f64 = 0.001;
/// Absolute part of the arc radius tolerance, mm.
pub const ARC_RADIUS_ABS_TOL: f64 = 0.002;

/// Why a line or an arc was refused.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum PathError {
    /// NaN or infinity in an input coordinate.
    NonFinite,
    /// Start and end coincide (a line of zero length).
    ZeroLength,
    /// Radius zero, or the axis has zero length.
    DegenerateArc,
    /// |start − centre| and |end − centre| differ beyond tolerance (mm).
    RadiusMismatch {
        /// |start − centre| in the arc plane, mm.
        start_radius: f64,
        /// |end − centre| in the arc plane, mm.
        end_radius: f64,
    },
}

impl core::fmt::Display for PathError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            PathError::NonFinite => write!(f, "non-finite coordinate"),
            PathError::ZeroLength => write!(f, "line of zero length"),
            PathError::DegenerateArc => write!(f, "arc with zero radius or zero axis"),
            PathError::RadiusMismatch {
                start_radius,
                end_radius,
            } => write!(
                f,
                "arc radius mismatch: start radius {start_radius} mm, end radius {end_radius} mm"
            ),
        }
    }
}

fn finite(v: &Vec3) -> bool {
    v.iter().all(|c| c.is_finite())
}

/// Straight segment, parametrised by arc length `u ∈ [u0, u0 + length]`
/// (`u0 = 0` but for the second half of a split line, which keeps the
/// whole line's parameter).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Line {
    start: Vec3,
    end: Vec3,
    dir: Vec3,
    length: f64,
    u0: f64,
}

impl Line {
    /// A line from `start` to `end`.
    pub fn new(start: Vec3, end: Vec3) -> Result<Self, PathError> {
        if !finite(&start) || !finite(&end) {
            return Err(PathError::NonFinite);
        }
        let d = end - start;
        let length = d.norm();
        if length == 0.0 || !length.is_finite() {
            return Err(PathError::ZeroLength);
        }
        Ok(Line {
            start,
            end,
            dir: d / length,
            length,
            u0: 0.0,
        })
    }
    /// Length, mm.
    pub fn length(&self) -> f64 {
        self.length
    }
}

impl Curve for Line {
    fn u_start(&self) -> f64 {
        self.u0
    }
    fn u_end(&self) -> f64 {
        self.u0 + self.length
    }
    fn eval(&self, u: f64, _order: usize) -> Derivs {
        let u = (u - self.u0).clamp(0.0, self.length);
        Derivs {
            p: self.start + self.dir * u,
            d1: self.dir,
            ..Derivs::ZERO
        }
    }
    fn start_point(&self) -> Vec3 {
        self.start
    }
    fn end_point(&self) -> Vec3 {
        self.end
    }
}

/// Circular arc, optionally helical, parametrised by the swept angle `u ∈
/// [ua, ub]` (`[0, sweep]` but for the parts of a split arc, which keep the
/// whole arc's parameter).
///
/// `p(u) = c + r(cos u·e1 + sin u·e2) + axis·(rise·u/sweep)`, counter-clockwise
/// about `axis` (right-hand rule). A clockwise arc is the same with `axis` negated.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Arc {
    centre: Vec3,
    axis: Vec3,
    e1: Vec3,
    e2: Vec3,
    radius: f64,
    sweep: f64,
    rise: f64,
    ua: f64,
    ub: f64,
    start: Vec3,
    end: Vec3,
}

impl Arc {
    /// Arc from `start` to `end` about `centre`, turning counter-clockwise about
    /// `axis` (pass `-axis` for clockwise), plus `full_turns` extra whole turns.
    /// The component of `end − start` along `axis` is the helix rise. A start
    /// equal to the end (in the plane) is a full circle.
    pub fn from_centre(
        start: Vec3,
        end: Vec3,
        centre: Vec3,
        axis: Vec3,
        full_turns: u32,
    ) -> Result<Self, PathError> {
        if !finite(&start) || !finite(&end) || !finite(&centre) || !finite(&axis) {
            return Err(PathError::NonFinite);
        }
        let an = axis.norm();
        if an == 0.0 {
            return Err(PathError::DegenerateArc);
        }
        let axis = axis / an;
        // Project the centre into the start point's plane so that only the rise is axial.
        let rs = start - centre;
        let rs = rs - axis * rs.dot(&axis);
        let re = end - centre;
        let rise = (end - start).dot(&axis);
        let re = re - axis * re.dot(&axis);
        let r0 = rs.norm();
        let r1 = re.norm();
        if r0 == 0.0 || r1 == 0.0 {
            return Err(PathError::DegenerateArc);
        }
        let tol = ARC_RADIUS_ABS_TOL.max(ARC_RADIUS_REL_TOL * r0);
        if libm::fabs(r0 - r1) > tol {
            return Err(PathError::RadiusMismatch {
                start_radius: r0,
                end_radius: r1,
            });
        }
        let e1 = rs / r0;
        let e2 = axis.cross(&e1);
        let mut sweep = libm::atan2(re.dot(&e2), re.dot(&e1));
        // Same point (to the radius tolerance) means a full circle, as in RS274/NGC.
        if sweep <= 0.0 || (re / r1 - e1).norm() * r0 <= tol * 1e-3 {
            sweep += 2.0 * core::f64::consts::PI;
        }
        sweep += 2.0 * core::f64::consts::PI * full_turns as f64;
        Ok(Arc {
            centre: centre + axis * (start - centre).dot(&axis),
            axis,
            e1,
            e2,
            radius: r0,
            sweep,
            rise,
            ua: 0.0,
            ub: sweep,
            start,
            end,
        })
    }

    /// Radius, mm.
    pub fn radius(&self) -> f64 {
        self.radius
    }
    /// Swept angle, rad (> 0).
    pub fn sweep(&self) -> f64 {
        self.ub - self.ua
    }
    /// Length per radian of sweep (the helix's slant radius), mm.
    pub fn length_per_radian(&self) -> f64 {
        libm::hypot(self.radius, self.rise / self.sweep)
    }
    /// Length of the (helical) arc, mm.
    pub fn length(&self) -> f64 {
        self.length_per_radian() * (self.ub - self.ua)
    }
    /// Unit axis (counter-clockwise about it).
    pub fn axis(&self) -> Vec3 {
        self.axis
    }
}

impl Curve for Arc {
    fn u_start(&self) -> f64 {
        self.ua
    }
    fn u_end(&self) -> f64 {
        self.ub
    }
    fn eval(&self, u: f64, order: usize) -> Derivs {
        let u = u.clamp(self.ua, self.ub);
        let (s, c) = (libm::sin(u), libm::cos(u));
        let radial = self.e1 * c + self.e2 * s;
        let tangential = self.e2 * c - self.e1 * s;
        let mut d = Derivs {
            p: self.centre + radial * self.radius + self.axis * (self.rise * u / self.sweep),
            d1: tangential * self.radius + self.axis * (self.rise / self.sweep),
            ..Derivs::ZERO
        };
        if order >= 2 {
            d.d2 = -radial * self.radius;
        }
        if order >= 3 {
            d.d3 = -tangential * self.radius;
        }
        d
    }
    fn start_point(&self) -> Vec3 {
        self.start
    }
    fn end_point(&self) -> Vec3 {
        self.end
    }
}

/// The geometry of one block.
#[derive(Clone, Copy, Debug, PartialEq)]
#[allow(clippy::large_enum_variant)] // fixed-capacity by design: no boxing in a no_std core
pub enum Path {
    /// Straight line.
    Line(Line),
    /// Circular or helical arc.
    Arc(Arc),
    /// Rational B-spline.
    Nurbs(Nurbs),
}

impl Path {
    /// Arc length between two parameters `ua <= ub`, mm.
    ///
    /// Lines and arcs are closed-form; NURBS uses Gauss–Legendre per knot span
    /// (speed is only piecewise smooth across knots).
    pub fn arc_length(&self, ua: f64, ub: f64) -> f64 {
        match self {
            Path::Line(_) => ub - ua,
            Path::Arc(a) => (ub - ua) * a.length_per_radian(),
            Path::Nurbs(n) => n.arc_length(ua, ub, ARC_LENGTH_TOL),
        }
    }

    /// Arc length of a short piece `[ua, ub]` (one tick) with a fixed 5-point
    /// Gauss–Legendre rule per knot span: no recursion, bounded cost for `tick`.
    #[inline]
    pub fn short_arc_length(&self, ua: f64, ub: f64) -> f64 {
        match self {
            Path::Line(_) | Path::Arc(_) => self.arc_length(ua, ub),
            Path::Nurbs(n) => {
                let knots = n.knots();
                let mut total = 0.0;
                let mut a = ua;
                // Split at interior knots inside (ua, ub) so each piece is polynomial-smooth.
                let i0 = n.find_span(ua, 0);
                let mut i = i0 + 1;
                while i < knots.len() && knots[i] < ub {
                    if knots[i] > a {
                        total += gauss5(n, a, knots[i]);
                        a = knots[i];
                    }
                    i += 1;
                }
                total + gauss5(n, a, ub)
            }
        }
    }

    /// Total length, mm.
    pub fn length(&self) -> f64 {
        self.arc_length(self.u_start(), self.u_end())
    }

    /// The parameter `u ≥ u0` at arc length `ds` past `u0` (at most `u_end`):
    /// Newton on [`Path::arc_length`] inside a shrinking bracket, to what the
    /// arithmetic resolves.
    pub fn param_at_arc_length(&self, u0: f64, ds: f64) -> f64 {
        self.param_at_arc_length_counted(u0, ds).0
    }

    /// [`Path::param_at_arc_length`] and the quadrature rules it spent (see
    /// [`Nurbs::arc_length_counted`]; 0 for lines and arcs): the work, for
    /// tests that guard its growth. A NURBS inverts itself
    /// ([`Nurbs::param_at_arc_length_counted`], which also starts well where
    /// C' vanishes).
    pub fn param_at_arc_length_counted(&self, u0: f64, ds: f64) -> (f64, usize) {
        if let Path::Nurbs(n) = self {
            return n.param_at_arc_length_counted(u0, ds, ARC_LENGTH_TOL);
        }
        if ds <= 0.0 {
            return (u0, 0);
        }
        // Lines and arcs: their lengths are closed forms.
        crate::geom::invert_arc_length(
            u0,
            ds,
            self.u_end(),
            u0 + ds / self.eval(u0, 1).d1.norm(),
            |ua, ub| (self.arc_length(ua, ub), 0),
            |u| self.eval(u, 1).d1.norm(),
        )
    }

    /// Split at interior parameter `u` into two paths that are exactly the same geometry.
    pub fn split_at(&self, u: f64) -> Result<(Path, Path), SplitAtError> {
        if !(u > self.u_start() && u < self.u_end()) {
            return Err(SplitAtError::NotInterior);
        }
        match self {
            Path::Line(l) => {
                // Both halves keep the whole line's parameter and direction,
                // and the second ends where the whole does: a length taken
                // from the new end points put its `u_end` an ulp past the
                // whole line's, and setpoints named parameters of neither.
                let mid = l.eval(u, 0).p;
                let a = Line {
                    start: l.start,
                    end: mid,
                    dir: l.dir,
                    length: u - l.u0,
                    u0: l.u0,
                };
                let b = Line {
                    start: mid,
                    end: l.end,
                    dir: l.dir,
                    length: l.u_end() - u,
                    u0: u,
                };
                if !(a.length > 0.0 && b.length > 0.0) {
                    return Err(SplitAtError::NotInterior);
                }
                Ok((Path::Line(a), Path::Line(b)))
            }
            Path::Arc(a) => {
                // Both parts keep the whole arc's frame and parameter.
                let mid = a.eval(u, 0).p;
                let mut first = *a;
                first.ub = u;
                first.end = mid;
                let mut second = *a;
                second.ua = u;
                second.start = mid;
                Ok((Path::Arc(first), Path::Arc(second)))
            }
            Path::Nurbs(n) => {
                let (a, b) = n.split_at(u).map_err(SplitAtError::Nurbs)?;
                Ok((Path::Nurbs(a), Path::Nurbs(b)))
            }
        }
    }

    /// The same path turned by `rotation` about the origin, as a part turned
    /// on the table: the parameter, length and laws' geometry are unchanged
    /// but for the axes each derivative falls on.
    pub fn rotated(&self, rotation: &Rotation3<f64>) -> Path {
        let r = |v: Vec3| rotation * v;
        match self {
            Path::Line(l) => Path::Line(Line {
                start: r(l.start),
                end: r(l.end),
                dir: r(l.dir),
                ..*l
            }),
            Path::Arc(a) => Path::Arc(Arc {
                centre: r(a.centre),
                axis: r(a.axis),
                e1: r(a.e1),
                e2: r(a.e2),
                start: r(a.start),
                end: r(a.end),
                ..*a
            }),
            Path::Nurbs(n) => Path::Nurbs(n.rotated(rotation)),
        }
    }

    /// Unit tangent at the start.
    pub fn start_tangent(&self) -> Vec3 {
        self.eval(self.u_start(), 1).d1.normalize()
    }
    /// Unit tangent at the end.
    pub fn end_tangent(&self) -> Vec3 {
        self.eval(self.u_end(), 1).d1.normalize()
    }
}

/// Why a path could not be split.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SplitAtError {
    /// The parameter is not strictly inside the path's range (or gives a zero-length piece).
    NotInterior,
    /// Knot insertion failed (capacity).
    Nurbs(NurbsError),
}

/// Tolerance of the adaptive arc-length quadrature used for planning, mm.
pub const ARC_LENGTH_TOL: f64 = 1e-12;

/// Gauss–Legendre nodes and weights on [-1, 1], 5 points (exact for degree
/// 9). Three points are not enough: on rational curves with uneven weights the
/// speed varies fast, and a 3-point rule drifts by ~1e-11 mm a tick (measured),
/// which the schedule would integrate.
const GL5: [(f64, f64); 5] = [
    (0.0, 128.0 / 225.0),
    (-0.538_469_310_105_683_1, 0.478_628_670_499_366_47),
    (0.538_469_310_105_683_1, 0.478_628_670_499_366_47),
    (-0.906_179_845_938_664, 0.236_926_885_056_189_08),
    (0.906_179_845_938_664, 0.236_926_885_056_189_08),
];

#[inline]
fn gauss5(c: &Nurbs, a: f64, b: f64) -> f64 {
    if b <= a {
        return 0.0;
    }
    let h = 0.5 * (b - a);
    let m = 0.5 * (a + b);
    let mut sum = 0.0;
    for (x, w) in GL5 {
        sum += w * c.eval(m + h * x, 1).d1.norm();
    }
    sum * h
}

impl Curve for Path {
    fn u_start(&self) -> f64 {
        match self {
            Path::Line(c) => c.u_start(),
            Path::Arc(c) => c.u_start(),
            Path::Nurbs(c) => c.u_start(),
        }
    }
    fn u_end(&self) -> f64 {
        match self {
            Path::Line(c) => c.u_end(),
            Path::Arc(c) => c.u_end(),
            Path::Nurbs(c) => c.u_end(),
        }
    }
    #[inline]
    fn eval(&self, u: f64, order: usize) -> Derivs {
        match self {
            Path::Line(c) => c.eval(u, order),
            Path::Arc(c) => c.eval(u, order),
            Path::Nurbs(c) => c.eval(u, order),
        }
    }
    fn start_point(&self) -> Vec3 {
        match self {
            Path::Line(c) => c.start_point(),
            Path::Arc(c) => c.start_point(),
            Path::Nurbs(c) => c.start_point(),
        }
    }
    fn end_point(&self) -> Vec3 {
        match self {
            Path::Line(c) => c.end_point(),
            Path::Arc(c) => c.end_point(),
            Path::Nurbs(c) => c.end_point(),
        }
    }
}

/// Which side of the path the tool is on, for the sign of curvature in the
/// constant-MRR law (concave k > 0: centre of curvature on the tool side).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum ToolSide {
    /// A fixed direction from the workpiece towards the tool, e.g. +Z for a
    /// ball end mill finishing a surface from above.
    Direction([f64; 3]),
    /// Contouring with the tool left of the path in the plane with this normal (G41).
    LeftOfPath([f64; 3]),
    /// Contouring with the tool right of the path in the plane with this normal (G42).
    RightOfPath([f64; 3]),
}

/// Cutting parameters that switch on the constant-MRR law for a block (seed eq. 23).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct MrrParams {
    /// Tool radius `rt`, mm.
    pub tool_radius: f64,
    /// Depth of cut `δ`, mm.
    pub depth_of_cut: f64,
    /// Where the tool is relative to the material.
    pub tool_side: ToolSide,
}

/// How the path may pass the end of a block: the RS274/NGC path control
/// mode in force when the block was programmed (G61.1, G61, G64 P).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "kebab-case"))]
pub enum Blending {
    /// G61.1: come to rest at the end of the block.
    ExactStop,
    /// G61: follow the programmed path exactly. A corner is a stop; a
    /// tangent join (or one within `tangent_tolerance`) is passed.
    #[default]
    ExactPath,
    /// G64 P: corners and the facets of runs of short moves may be passed
    /// within `tolerance` mm of the programmed path; `None` (G64 without P)
    /// takes `InterpConfig::default_blend_tolerance`.
    Within {
        /// G64 `P`, mm.
        tolerance: Option<f64>,
    },
}

/// One motion block as the interpolator receives it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Block {
    /// Caller's id (reported in every setpoint of this block).
    pub id: u32,
    /// Geometry.
    pub path: Path,
    /// Programmed feed `F`, mm/s.
    pub feed: f64,
    /// Constant-MRR law parameters; `None` leaves that law off for this block.
    pub mrr: Option<MrrParams>,
    /// How the path may pass this block's end (G61.1, G61, G64 P).
    pub blending: Blending,
    /// Rotary axes or tool axis along the block (`crate::fiveaxis`);
    /// `None` for a three-axis block (the rotary axes stay where they are).
    pub orientation: Option<Orientation>,
}

impl Block {
    /// A block with programmed feed `feed` (mm/s), no MRR law and exact path (G61).
    pub fn new(id: u32, path: Path, feed: f64) -> Self {
        Block {
            id,
            path,
            feed,
            mrr: None,
            blending: Blending::ExactPath,
            orientation: None,
        }
    }

    /// The same block with rotary axes or a tool axis along it.
    pub fn with_orientation(self, orientation: Orientation) -> Self {
        Block {
            orientation: Some(orientation),
            ..self
        }
    }

    /// Under tool-centre-point control (its path is the tool tip in the
    /// workpiece frame, not X Y Z of the machine)?
    pub fn is_tcp(&self) -> bool {
        self.orientation.is_some_and(|o| o.is_tcp())
    }

    /// A turn in place: the tool tip (or X Y Z) stands still while the
    /// rotary axes or the tool axis turn; the path is the turn's measure
    /// (`crate::fiveaxis::Orientation::in_place`).
    pub fn is_in_place(&self) -> bool {
        self.orientation.is_some_and(|o| o.fixed().is_some())
    }

    /// Where the block starts in its frame (the tool tip, or X Y Z).
    pub fn start_position(&self) -> Vec3 {
        self.orientation
            .and_then(|o| o.fixed())
            .unwrap_or_else(|| self.path.start_point())
    }

    /// Where the block ends in its frame (the tool tip, or X Y Z): where
    /// the next block starts.
    pub fn end_position(&self) -> Vec3 {
        self.orientation
            .and_then(|o| o.fixed())
            .unwrap_or_else(|| self.path.end_point())
    }

    /// The same block with another blending mode.
    pub fn with_blending(self, blending: Blending) -> Self {
        Block { blending, ..self }
    }
}
