//! Five-axis machine kinematics (seed `000_…` §3): the machine's `W/…/T`
//! chain, forward and inverse transforms between the joints X Y Z A B C and
//! the tool tip and tool axis in the workpiece frame, and the joint rates a
//! planner needs for per-joint limits.
//!
//! **Notation.** A machine is written `W/K1…Kn/T`: the chain of axes from
//! the workpiece `W` to the tool `T`, `x y z` linear, `a b c` rotary about x,
//! y and z, `B` the bed (the stationary element). Axes left of `B` carry the
//! workpiece (table), axes right of it carry the tool (head). The order of
//! the two rotary axes and the bed reduces every chain to one of 18 keys
//! ([`RotaryKey`], e.g. `caB` for `W/caxyBz/T`); six of them are not
//! five-axis machines (the rotary axis next to the tool is `c`, which only
//! spins the tool about itself), the other twelve are of C,A or A,B type.
//!
//! **Joint convention.** Every joint value is the motion of the tool
//! relative to the workpiece (ISO 841's rule for programs), whether the axis
//! moves the table or the head; so the transform is the product of the chain's
//! elements in order from `W` to `T` (the seed's eq. 2), and where the bed
//! stands changes nothing but the names. LinuxCNC's `xyzac-trt-kins` turns
//! the table by `+A`, `+C` instead: its A and C are the negatives of ours.
//!
//! **Geometry.** Home is every joint at 0; the workpiece frame then
//! coincides with the machine frame, whose origin is the spindle's gauge
//! point. The tool tip is `tool_length` below the gauge point along the tool
//! axis, which points from the tip into the spindle (`+z` at home). Each
//! rotary axis turns about the line through its centre (a point given at
//! home) along x, y or z. With `M_k` a translation `q·e` or a rotation by `q`
//! about its line, the tool's pose in the workpiece frame is
//! `M_1(q_1)·…·M_5(q_5)` applied to the home tip `(0, 0, −L)` and axis `ẑ`.
//!
//! **Inverse.** The tool axis fixes the two rotary joints up to two branches
//! and turns of 2π; the solution kept is the one nearest the current joints
//! that lies within the rotary ranges. Where the tool axis is within
//! `pole_tolerance` of the first rotary axis (the tilt axis at 0 on a C,A
//! machine) the first rotary joint is undefined: it keeps its current value
//! ([`Solution::at_pole`]). The linear joints then follow from the tip.
//!
//! Everything here is `no_std` and allocation-free.

use core::fmt;
use core::str::FromStr;

use nalgebra::Matrix3;

use crate::geom::Vec3;

/// A rotary axis: rotation about x (A), y (B) or z (C).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum RotaryAxis {
    /// Rotation about x.
    A,
    /// Rotation about y.
    B,
    /// Rotation about z (the tool axis at home).
    C,
}

impl RotaryAxis {
    /// A, B, C.
    pub const ALL: [RotaryAxis; 3] = [RotaryAxis::A, RotaryAxis::B, RotaryAxis::C];

    /// The axis direction (x, y or z).
    pub fn direction(self) -> Vec3 {
        let mut d = Vec3::zeros();
        d[self.index()] = 1.0;
        d
    }

    /// 0, 1, 2 for A, B, C: the axis about x, y, z.
    pub fn index(self) -> usize {
        match self {
            RotaryAxis::A => 0,
            RotaryAxis::B => 1,
            RotaryAxis::C => 2,
        }
    }

    /// The joint slot in `[X, Y, Z, A, B, C]` (3, 4 or 5).
    pub fn joint(self) -> usize {
        3 + self.index()
    }

    /// Lower-case letter of the chain notation.
    pub fn letter(self) -> char {
        match self {
            RotaryAxis::A => 'a',
            RotaryAxis::B => 'b',
            RotaryAxis::C => 'c',
        }
    }

    /// The axis of a lower-case chain letter.
    pub fn from_letter(c: char) -> Option<Self> {
        match c {
            'a' => Some(RotaryAxis::A),
            'b' => Some(RotaryAxis::B),
            'c' => Some(RotaryAxis::C),
            _ => None,
        }
    }
}

/// The shape of the feasible tool motion FTM⁵ on the sphere (§3.2).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum MachineType {
    /// C,A (or C,B): the first rotary axis is C, the tool axis at home; two
    /// fans symmetric about it.
    CA,
    /// A,B: two tilt axes; a spherical rectangle.
    AB,
}

/// The order of the two rotary axes and the bed from workpiece to tool, e.g.
/// `caB`: one of the 18 keys of §3.2.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct RotaryKey {
    /// The rotary axis nearer the workpiece (`r1`).
    pub first: RotaryAxis,
    /// The rotary axis nearer the tool (`r2`).
    pub second: RotaryAxis,
    /// Where the bed stands among the three symbols (0, 1 or 2).
    pub bed_position: u8,
}

/// Where the rotary axes sit relative to the bed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Mounting {
    /// Both rotary axes carry the workpiece (`caB`).
    TableTable,
    /// The first carries the workpiece, the second the tool (`cBa`).
    TableHead,
    /// Both carry the tool (`Bca`).
    HeadHead,
}

impl RotaryKey {
    /// All 18 orderings of two distinct rotary axes and the bed.
    pub fn all() -> [RotaryKey; 18] {
        use RotaryAxis::*;
        let pairs = [(A, B), (B, A), (B, C), (C, B), (C, A), (A, C)];
        core::array::from_fn(|i| RotaryKey {
            first: pairs[i / 3].0,
            second: pairs[i / 3].1,
            bed_position: (i % 3) as u8,
        })
    }

    /// The machine type, or `None` for the six orderings that are not
    /// five-axis machines (the rotary axis next to the tool is `c`).
    pub fn machine_type(&self) -> Option<MachineType> {
        if self.second == RotaryAxis::C {
            None
        } else if self.first == RotaryAxis::C {
            Some(MachineType::CA)
        } else {
            Some(MachineType::AB)
        }
    }

    /// Table-table, table-head or head-head.
    pub fn mounting(&self) -> Mounting {
        match self.bed_position {
            0 => Mounting::HeadHead,
            1 => Mounting::TableHead,
            _ => Mounting::TableTable,
        }
    }

    /// The tool axis in the workpiece frame for joint angles `q1` (of
    /// `first`) and `q2` (of `second`), radians: `R_{r1}(q1)·R_{r2}(q2)·ẑ` (eq. 2).
    pub fn ftm5(&self, q1: f64, q2: f64) -> Vec3 {
        rotation(self.first, q1) * rotation(self.second, q2) * Vec3::z()
    }
}

impl fmt::Display for RotaryKey {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut rot = [self.first.letter(), self.second.letter()].into_iter();
        for i in 0..3u8 {
            if i == self.bed_position {
                f.write_str("B")?;
            } else if let Some(c) = rot.next() {
                write!(f, "{c}")?;
            }
        }
        Ok(())
    }
}

/// One symbol of a chain.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Element {
    /// A linear axis: 0, 1, 2 for x, y, z.
    Linear(u8),
    /// A rotary axis.
    Rotary(RotaryAxis),
    /// The bed (stationary element).
    Bed,
}

impl Element {
    fn letter(self) -> char {
        match self {
            Element::Linear(i) => ['x', 'y', 'z'][usize::from(i)],
            Element::Rotary(r) => r.letter(),
            Element::Bed => 'B',
        }
    }
}

/// Why a `W/…/T` chain was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ChainError {
    /// Not of the form `W/…/T`.
    Syntax,
    /// A character that is not one of `x y z a b c B`.
    BadAxis {
        /// The character.
        found: char,
        /// 0-based position in the notation (after leading blanks).
        position: usize,
    },
    /// An axis occurs twice.
    Repeated {
        /// The repeated axis.
        axis: char,
    },
    /// Not exactly x, y, z, two rotary axes and the bed.
    Axes,
    /// The rotary axis next to the tool is `c`: the seed's six orderings
    /// that are not five-axis machines.
    NotFiveAxis {
        /// The reduced key, e.g. `Bac`.
        key: RotaryKey,
    },
}

impl fmt::Display for ChainError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ChainError::Syntax => write!(f, "expected W/<axes>/T, e.g. W/caxyBz/T"),
            ChainError::BadAxis { found, position } => write!(
                f,
                "character `{found}` at position {position} is not one of x y z a b c B"
            ),
            ChainError::Repeated { axis } => write!(f, "axis `{axis}` occurs more than once"),
            ChainError::Axes => write!(
                f,
                "a 5-axis machine needs x, y, z, exactly two of a b c, and the bed B"
            ),
            ChainError::NotFiveAxis { key } => write!(
                f,
                "rotary order `{key}`: the rotary axis next to the tool is c, which turns the tool about its own axis (the tool axis sweeps one circle, it cannot move across it), so this is not a 5-axis machine"
            ),
        }
    }
}

impl core::error::Error for ChainError {}

/// A five-axis machine's chain in the seed's `W/K1…Kn/T` notation: three
/// linear axes, two rotary axes and the bed, in order from workpiece to tool.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Chain {
    elements: [Element; 6],
    key: RotaryKey,
}

impl Chain {
    /// The six symbols from workpiece to tool.
    pub fn elements(&self) -> &[Element; 6] {
        &self.elements
    }

    /// The reduced rotary key, e.g. `caB`.
    pub fn key(&self) -> RotaryKey {
        self.key
    }

    /// C,A or A,B.
    pub fn machine_type(&self) -> MachineType {
        match self.key.machine_type() {
            Some(t) => t,
            // A Chain is only built for five-axis keys.
            None => MachineType::AB,
        }
    }

    /// The machine axes that play the roles of the paper's rotary axes: for a
    /// C,A type `(C, tilt axis)`, for an A,B type `(R1, R2)` (§3.3 table);
    /// always `(first, second)` from the workpiece.
    pub fn roles(&self) -> (RotaryAxis, RotaryAxis) {
        (self.key.first, self.key.second)
    }

    /// Whether `axis` is one of the chain's two rotary axes.
    pub fn has(&self, axis: RotaryAxis) -> bool {
        self.key.first == axis || self.key.second == axis
    }
}

impl fmt::Display for Chain {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("W/")?;
        for e in self.elements {
            write!(f, "{}", e.letter())?;
        }
        f.write_str("/T")
    }
}

impl FromStr for Chain {
    type Err = ChainError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let notation = s.trim();
        let inner = notation
            .strip_prefix("W/")
            .and_then(|r| r.strip_suffix("/T"))
            .ok_or(ChainError::Syntax)?;
        let mut elements = [Element::Bed; 6];
        let mut seen = [false; 7];
        let (mut rotary, mut n_rotary) = ([RotaryAxis::A; 2], 0usize);
        let (mut bed, mut linear) = (None, 0usize);
        for (i, ch) in inner.chars().enumerate() {
            let element = match ch {
                'x' => Element::Linear(0),
                'y' => Element::Linear(1),
                'z' => Element::Linear(2),
                'B' => Element::Bed,
                c => match RotaryAxis::from_letter(c) {
                    Some(r) => Element::Rotary(r),
                    None => {
                        return Err(ChainError::BadAxis {
                            found: ch,
                            position: i + 2,
                        });
                    }
                },
            };
            let slot = match element {
                Element::Linear(k) => usize::from(k),
                Element::Rotary(r) => 3 + r.index(),
                Element::Bed => 6,
            };
            if seen[slot] {
                return Err(ChainError::Repeated { axis: ch });
            }
            seen[slot] = true;
            match element {
                Element::Bed => bed = Some(n_rotary as u8),
                Element::Rotary(r) => {
                    // Three distinct rotary letters: more than two.
                    if n_rotary == 2 {
                        return Err(ChainError::Axes);
                    }
                    rotary[n_rotary] = r;
                    n_rotary += 1;
                }
                Element::Linear(_) => linear += 1,
            }
            // A seventh symbol cannot get here: of the seven valid ones it
            // would be a repeat or a third rotary letter, refused above.
            if let Some(e) = elements.get_mut(i) {
                *e = element;
            }
        }
        let (Some(bed_position), 2, 3) = (bed, n_rotary, linear) else {
            return Err(ChainError::Axes);
        };
        let key = RotaryKey {
            first: rotary[0],
            second: rotary[1],
            bed_position,
        };
        if key.machine_type().is_none() {
            return Err(ChainError::NotFiveAxis { key });
        }
        Ok(Chain { elements, key })
    }
}

#[cfg(feature = "serde")]
impl serde::Serialize for Chain {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

#[cfg(feature = "serde")]
impl<'de> serde::Deserialize<'de> for Chain {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl serde::de::Visitor<'_> for V {
            type Value = Chain;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("a five-axis machine chain such as \"W/caxyBz/T\"")
            }
            fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<Chain, E> {
                v.parse().map_err(E::custom)
            }
        }
        d.deserialize_str(V)
    }
}

/// The joint range of one rotary axis, degrees. Infinite bounds: endless
/// (TOML writes them `-inf`/`inf`; JSON has no infinity and writes `null`,
/// which reads back as the endless bound).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct RotaryRange {
    /// Lowest joint value, degrees.
    #[cfg_attr(feature = "serde", serde(deserialize_with = "endless_below"))]
    pub min: f64,
    /// Highest joint value, degrees.
    #[cfg_attr(feature = "serde", serde(deserialize_with = "endless_above"))]
    pub max: f64,
}

/// A lower bound; `null` (JSON's infinity) is endless.
#[cfg(feature = "serde")]
fn endless_below<'de, D: serde::Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    use serde::Deserialize;
    Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::NEG_INFINITY))
}

/// An upper bound; `null` (JSON's infinity) is endless.
#[cfg(feature = "serde")]
fn endless_above<'de, D: serde::Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    use serde::Deserialize;
    Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::INFINITY))
}

impl RotaryRange {
    /// No limit (an endless rotary table).
    pub const UNLIMITED: RotaryRange = RotaryRange {
        min: f64::NEG_INFINITY,
        max: f64::INFINITY,
    };
}

impl Default for RotaryRange {
    fn default() -> Self {
        Self::UNLIMITED
    }
}

/// Default [`MachineSpec::pole_tolerance`], rad.
pub const DEFAULT_POLE_TOLERANCE: f64 = 1e-9;

/// A five-axis machine as configured: its chain and the offsets and limits
/// a real machine has. Lengths in mm in the machine frame at home (every
/// joint 0), angles in degrees. [`Machine::new`] checks it.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "kebab-case"))]
pub struct MachineSpec {
    /// The `W/…/T` chain.
    pub chain: Chain,
    /// Gauge point to tool tip along the tool axis, mm. Default 0.
    #[cfg_attr(feature = "serde", serde(default))]
    pub tool_length: f64,
    /// A point on each rotary axis at home, `[A, B, C]`, mm (the entry of
    /// the axis the machine lacks is ignored). Default: the origin.
    #[cfg_attr(feature = "serde", serde(default))]
    pub rotary_centres: [[f64; 3]; 3],
    /// Joint range of each rotary axis `[A, B, C]`, degrees. Default endless.
    #[cfg_attr(feature = "serde", serde(default))]
    pub rotary_ranges: [RotaryRange; 3],
    /// Within this angle (rad) of the first rotary axis the tool axis is at
    /// the pole, where the first rotary joint is undefined and is kept.
    /// Default [`DEFAULT_POLE_TOLERANCE`].
    #[cfg_attr(feature = "serde", serde(default = "default_pole_tolerance"))]
    pub pole_tolerance: f64,
}

#[cfg(feature = "serde")]
fn default_pole_tolerance() -> f64 {
    DEFAULT_POLE_TOLERANCE
}

impl MachineSpec {
    /// A machine with `chain`, its rotary axes through the origin, no tool
    /// length, endless ranges and the default pole tolerance.
    pub fn new(chain: Chain) -> Self {
        MachineSpec {
            chain,
            tool_length: 0.0,
            rotary_centres: [[0.0; 3]; 3],
            rotary_ranges: [RotaryRange::UNLIMITED; 3],
            pole_tolerance: DEFAULT_POLE_TOLERANCE,
        }
    }
}

/// Why a [`MachineSpec`] was refused.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MachineError {
    /// The tool length is not finite.
    ToolLength(f64),
    /// A coordinate of a rotary centre is not finite.
    Centre {
        /// The axis.
        axis: RotaryAxis,
    },
    /// A range is NaN or empty (`min > max`).
    Range {
        /// The axis.
        axis: RotaryAxis,
        /// Its range.
        range: RotaryRange,
    },
    /// The pole tolerance is not in `[0, 0.1]` rad.
    PoleTolerance(f64),
}

impl fmt::Display for MachineError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            MachineError::ToolLength(v) => write!(f, "tool-length {v} mm is not finite"),
            MachineError::Centre { axis } => {
                write!(f, "rotary-centres: the centre of {axis:?} is not finite")
            }
            MachineError::Range { axis, range } => write!(
                f,
                "rotary-ranges: {axis:?} range [{}, {}] degrees is empty or NaN",
                range.min, range.max
            ),
            MachineError::PoleTolerance(v) => {
                write!(f, "pole-tolerance {v} rad must be within 0..=0.1")
            }
        }
    }
}

impl core::error::Error for MachineError {}

/// Largest accepted [`MachineSpec::pole_tolerance`], rad.
pub const MAX_POLE_TOLERANCE: f64 = 0.1;

/// Joint positions `[X, Y, Z, A, B, C]`: mm, and degrees for the rotary
/// axes (as [`crate::Setpoint::axes`]). The rotary axis a machine lacks is
/// carried unchanged.
pub type Joints = [f64; 6];

/// The tool in the workpiece frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ToolPose {
    /// Tool tip, mm.
    pub tip: Vec3,
    /// Unit tool axis, from the tip into the spindle.
    pub axis: Vec3,
}

/// A solution of [`Machine::inverse`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Solution {
    /// The joints.
    pub joints: Joints,
    /// The tool axis was within the pole tolerance of the first rotary axis:
    /// that joint kept its current value and the axis reached is the nearest
    /// one with it (off by at most the pole tolerance).
    pub at_pole: bool,
}

/// An angle in degrees as an error message shows it: to a millionth of a
/// degree (a jump of 0.5999999999999943° reads 0.6), and a smaller one in
/// two significant digits (a join's 2.3e-7° is not 0).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Degrees(pub f64);

impl core::fmt::Display for Degrees {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let d = self.0;
        if d.abs() >= 1e-3 || d == 0.0 || !d.is_finite() {
            // The nearest double to the rounded value prints in its
            // shortest form, so no trailing digits.
            write!(f, "{}", libm::round(d * 1e6) / 1e6)
        } else {
            write!(f, "{d:.1e}")
        }
    }
}

/// Why [`Machine::inverse`] found no joints.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum InverseError {
    /// The tip or the axis is not finite, or the axis is zero.
    BadPose,
    /// A current joint value is not finite.
    BadJoints,
    /// No solution keeps both rotary joints within their ranges. `needed` is
    /// the value of `axis` in the solution nearest the current joints
    /// (ignoring the ranges), degrees.
    OutOfRange {
        /// The axis that cannot follow.
        axis: RotaryAxis,
        /// What it would need, degrees.
        needed: f64,
        /// Its range.
        range: RotaryRange,
    },
    /// The linear axes cannot reach the tip: at these rotary positions two of
    /// them are parallel (only chains with a rotary axis between linear axes
    /// have such positions).
    LinearSingular,
}

impl fmt::Display for InverseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            InverseError::BadPose => write!(f, "tool pose is not finite or its axis is zero"),
            InverseError::BadJoints => write!(f, "current joints are not finite"),
            InverseError::OutOfRange {
                axis,
                needed,
                range,
            } => write!(
                f,
                "tool axis out of reach: {axis:?} would need {}°, outside its range [{}°, {}°]",
                Degrees(*needed),
                Degrees(range.min),
                Degrees(range.max)
            ),
            InverseError::LinearSingular => {
                write!(f, "linear axes are parallel at these rotary positions")
            }
        }
    }
}

impl core::error::Error for InverseError {}

/// Why [`Machine::joint_rates`] found no rates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RateError {
    /// Input not finite.
    NonFinite,
    /// The tool axis is at the pole (within the pole tolerance of the first
    /// rotary axis): the first rotary joint's rate is unbounded there.
    AtPole {
        /// [`Machine::pole_distance`] here.
        pole_distance: f64,
    },
    /// The linear axes are parallel at these rotary positions.
    LinearSingular,
}

impl fmt::Display for RateError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RateError::NonFinite => write!(f, "joints or velocities are not finite"),
            RateError::AtPole { pole_distance } => write!(
                f,
                "tool axis at the pole (distance {pole_distance}): the first rotary axis's rate is unbounded"
            ),
            RateError::LinearSingular => {
                write!(f, "linear axes are parallel at these rotary positions")
            }
        }
    }
}

impl core::error::Error for RateError {}

/// One moving element of the chain, in the machine frame at home.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Link {
    /// Slot in `[X, Y, Z, A, B, C]`.
    joint: usize,
    /// Unit direction of the translation or of the rotation axis.
    dir: Vec3,
    /// A point on the rotation axis (zero for a linear axis).
    centre: Vec3,
    /// The rotary axis, or `None` for a linear one.
    rotary: Option<RotaryAxis>,
}

/// A checked five-axis machine: forward and inverse transforms and joint rates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Machine {
    spec: MachineSpec,
    /// The five moving elements from workpiece to tool.
    links: [Link; 5],
    /// Ranges of the first and second rotary joint, radians.
    ranges: [(f64, f64); 2],
}

/// Slack on the rotary ranges for round-off (a joint exactly at a limit
/// comes back through degrees ↔ radians), rad.
const RANGE_SLACK: f64 = 1e-12;

/// Below this `|det|` the linear axes' directions are taken as dependent.
const LINEAR_DET_MIN: f64 = 1e-9;

/// Rotation by `q` (rad) about a coordinate axis.
fn rotation(axis: RotaryAxis, q: f64) -> Matrix3<f64> {
    let (s, c) = (libm::sin(q), libm::cos(q));
    match axis {
        RotaryAxis::A => Matrix3::new(1.0, 0.0, 0.0, 0.0, c, -s, 0.0, s, c),
        RotaryAxis::B => Matrix3::new(c, 0.0, s, 0.0, 1.0, 0.0, -s, 0.0, c),
        RotaryAxis::C => Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0),
    }
}

/// The value `q + 2πk` within `[lo, hi]` nearest `current`, if any.
fn nearest_turn(q: f64, current: f64, lo: f64, hi: f64) -> Option<f64> {
    const TAU: f64 = core::f64::consts::TAU;
    let mut v = q + TAU * libm::round((current - q) / TAU);
    if v < lo - RANGE_SLACK {
        v = q + TAU * libm::ceil((lo - RANGE_SLACK - q) / TAU);
    } else if v > hi + RANGE_SLACK {
        v = q + TAU * libm::floor((hi + RANGE_SLACK - q) / TAU);
    }
    (v >= lo - RANGE_SLACK && v <= hi + RANGE_SLACK).then_some(v)
}

fn sq(x: f64) -> f64 {
    x * x
}

/// `(a × b)·n`: the signed area of `a`, `b` seen along `n`.
fn cross_along(a: &Vec3, b: &Vec3, n: &Vec3) -> f64 {
    a.cross(b).dot(n)
}

impl Machine {
    /// Checks `spec` and prepares the transforms.
    pub fn new(spec: MachineSpec) -> Result<Self, MachineError> {
        if !spec.tool_length.is_finite() {
            return Err(MachineError::ToolLength(spec.tool_length));
        }
        if !(spec.pole_tolerance >= 0.0 && spec.pole_tolerance <= MAX_POLE_TOLERANCE) {
            return Err(MachineError::PoleTolerance(spec.pole_tolerance));
        }
        let (first, second) = spec.chain.roles();
        for axis in [first, second] {
            let range = spec.rotary_ranges[axis.index()];
            if !(range.min <= range.max) {
                return Err(MachineError::Range { axis, range });
            }
            if !spec.rotary_centres[axis.index()]
                .iter()
                .all(|c| c.is_finite())
            {
                return Err(MachineError::Centre { axis });
            }
        }
        let mut links = [Link {
            joint: 0,
            dir: Vec3::zeros(),
            centre: Vec3::zeros(),
            rotary: None,
        }; 5];
        let mut n = 0;
        for e in spec.chain.elements() {
            let link = match *e {
                Element::Bed => continue,
                Element::Linear(i) => {
                    let mut dir = Vec3::zeros();
                    dir[usize::from(i)] = 1.0;
                    Link {
                        joint: usize::from(i),
                        dir,
                        centre: Vec3::zeros(),
                        rotary: None,
                    }
                }
                Element::Rotary(r) => {
                    let c = spec.rotary_centres[r.index()];
                    Link {
                        joint: r.joint(),
                        dir: r.direction(),
                        centre: Vec3::new(c[0], c[1], c[2]),
                        rotary: Some(r),
                    }
                }
            };
            links[n] = link;
            n += 1;
        }
        let range = |axis: RotaryAxis| {
            let r = spec.rotary_ranges[axis.index()];
            (r.min.to_radians(), r.max.to_radians())
        };
        Ok(Machine {
            spec,
            links,
            ranges: [range(first), range(second)],
        })
    }

    /// The configuration this machine was built from.
    pub fn spec(&self) -> &MachineSpec {
        &self.spec
    }

    /// The chain.
    pub fn chain(&self) -> &Chain {
        &self.spec.chain
    }

    /// Joint value of `link` in its working unit (mm or rad).
    fn q(link: &Link, joints: &Joints) -> f64 {
        let v = joints[link.joint];
        if link.rotary.is_some() {
            v.to_radians()
        } else {
            v
        }
    }

    /// Walks the chain at `joints`, calling `visit(link, R, t)` with the
    /// transform `x ↦ R·x + t` of the elements before `link`; returns the
    /// transform of the whole chain.
    fn walk(
        &self,
        joints: &Joints,
        mut visit: impl FnMut(&Link, &Matrix3<f64>, &Vec3),
    ) -> (Matrix3<f64>, Vec3) {
        let (mut r, mut t) = (Matrix3::identity(), Vec3::zeros());
        for link in &self.links {
            visit(link, &r, &t);
            let q = Self::q(link, joints);
            match link.rotary {
                None => t += r * (link.dir * q),
                Some(axis) => {
                    // x ↦ c + Rot·(x − c), after what came before.
                    let rot = rotation(axis, q);
                    t += r * (link.centre - rot * link.centre);
                    r *= rot;
                }
            }
        }
        (r, t)
    }

    /// The home tool tip `(0, 0, −L)`.
    fn home_tip(&self) -> Vec3 {
        Vec3::new(0.0, 0.0, -self.spec.tool_length)
    }

    /// Tool tip and tool axis in the workpiece frame at `joints`.
    pub fn forward(&self, joints: &Joints) -> ToolPose {
        let (r, t) = self.walk(joints, |_, _, _| {});
        ToolPose {
            tip: r * self.home_tip() + t,
            axis: r * Vec3::z(),
        }
    }

    /// `sin` of the angle between `axis` (unit) and the first rotary axis
    /// (C on a C,A machine), or between it and its opposite, whichever is
    /// nearer: 0 at the pole. Near the pole a tool-axis angular speed `ω`
    /// needs up to `ω / pole_distance` on the first rotary joint and at most
    /// `ω` on the second (see [`Machine::max_axis_rate`]).
    pub fn pole_distance(&self, axis: &Vec3) -> f64 {
        self.spec.chain.key.first.direction().cross(axis).norm()
    }

    /// The largest tool-axis angular speed (rad/s) with which both rotary
    /// joints stay within their speed limits `first_max`, `second_max`
    /// (deg/s, of the chain's first and second rotary axis) at tool axis
    /// `axis`: `min(second_max, first_max · pole_distance)` in rad/s. Zero at
    /// the pole, where the axis has to wait for the first joint.
    pub fn max_axis_rate(&self, axis: &Vec3, first_max: f64, second_max: f64) -> f64 {
        let d = self.pole_distance(axis);
        (first_max.to_radians() * d).min(second_max.to_radians())
    }

    /// The joints that put the tool tip at `pose.tip` with the tool along
    /// `pose.axis` (normalised here), nearest `current` within the rotary
    /// ranges. At the pole the first rotary joint keeps its current value.
    /// The rotary axis the machine lacks keeps its current value.
    pub fn inverse(&self, pose: &ToolPose, current: &Joints) -> Result<Solution, InverseError> {
        if !current.iter().all(|v| v.is_finite()) {
            return Err(InverseError::BadJoints);
        }
        let n = pose.axis.norm();
        if !(n > 0.0 && n.is_finite() && pose.tip.iter().all(|v| v.is_finite())) {
            return Err(InverseError::BadPose);
        }
        let a = pose.axis / n;
        let (first, second) = self.spec.chain.roles();
        let (q1, q2, at_pole) = self.orientation(&a, current)?;
        let mut joints = *current;
        // At the pole the first joint keeps its value to the bit.
        if !at_pole {
            joints[first.joint()] = q1.to_degrees();
        }
        joints[second.joint()] = q2.to_degrees();
        self.place_linear(&mut joints, &pose.tip)?;
        Ok(Solution { joints, at_pole })
    }

    /// The joints with the machine's rotary joints at `rotary` (A B C,
    /// degrees; the axis the machine lacks keeps its `current` value) and
    /// the linear joints that put the tool tip at `tip`: tool-centre-point
    /// control with the rotary positions given (G43.4), not a tool axis.
    pub fn place_tip(
        &self,
        tip: &Vec3,
        rotary: [f64; 3],
        current: &Joints,
    ) -> Result<Joints, InverseError> {
        if !current.iter().all(|v| v.is_finite()) {
            return Err(InverseError::BadJoints);
        }
        if !(tip.iter().all(|v| v.is_finite()) && rotary.iter().all(|v| v.is_finite())) {
            return Err(InverseError::BadPose);
        }
        let (first, second) = self.spec.chain.roles();
        let mut joints = *current;
        for (axis, (lo, hi)) in [first, second].into_iter().zip(self.ranges) {
            let q = rotary[axis.index()];
            let r = q.to_radians();
            if !(r >= lo - RANGE_SLACK && r <= hi + RANGE_SLACK) {
                return Err(InverseError::OutOfRange {
                    axis,
                    needed: q,
                    range: self.spec.rotary_ranges[axis.index()],
                });
            }
            joints[axis.joint()] = q;
        }
        self.place_linear(&mut joints, tip)?;
        Ok(joints)
    }

    /// Sets the linear joints of `joints` (its rotary ones kept) so that the
    /// tool tip is at `tip`.
    fn place_linear(&self, joints: &mut Joints, tip: &Vec3) -> Result<(), InverseError> {
        // The tip is affine in the linear joints: p = p0 + D·(x, y, z).
        for j in joints.iter_mut().take(3) {
            *j = 0.0;
        }
        let mut d = Matrix3::zeros();
        let (r, t) = self.walk(joints, |link, r, _| {
            if link.rotary.is_none() {
                d.set_column(link.joint, &(r * link.dir));
            }
        });
        let p0 = r * self.home_tip() + t;
        if libm::fabs(d.determinant()) < LINEAR_DET_MIN {
            return Err(InverseError::LinearSingular);
        }
        let xyz = d.try_inverse().ok_or(InverseError::LinearSingular)? * (tip - p0);
        joints[..3].copy_from_slice(xyz.as_slice());
        Ok(())
    }

    /// The rotary joints (rad) for unit tool axis `a`: `(first, second, at_pole)`.
    fn orientation(&self, a: &Vec3, current: &Joints) -> Result<(f64, f64, bool), InverseError> {
        let (first, second) = self.spec.chain.roles();
        let (e1, e2, z) = (first.direction(), second.direction(), Vec3::z());
        // The second joint swings ẑ on the circle w(q) = cos q·ẑ + sin q·n2.
        let n2 = e2.cross(&z);
        let cur = [
            current[first.joint()].to_radians(),
            current[second.joint()].to_radians(),
        ];
        let [(lo1, hi1), (lo2, hi2)] = self.ranges;
        let range_err = |axis: RotaryAxis, needed: f64| InverseError::OutOfRange {
            axis,
            needed: needed.to_degrees(),
            range: self.spec.rotary_ranges[axis.index()],
        };
        let along = e1.dot(a);
        let perp = a - e1 * along;
        let s = perp.norm();
        if s <= self.spec.pole_tolerance {
            // C is undefined: keep it, and take the second joint that brings
            // the axis nearest `a` with it.
            let q1 = cur[0];
            if !(q1 >= lo1 - RANGE_SLACK && q1 <= hi1 + RANGE_SLACK) {
                return Err(range_err(first, q1));
            }
            let b = rotation(first, -q1) * a;
            let q2 = libm::atan2(b.dot(&n2), b.dot(&z));
            let q2 = nearest_turn(q2, cur[1], lo2, hi2).ok_or_else(|| {
                range_err(
                    second,
                    nearest_turn(q2, cur[1], f64::MIN, f64::MAX).unwrap_or(q2),
                )
            })?;
            return Ok((q1, q2, true));
        }
        // e1·w(q2) = cos(q2 − φ), so q2 = φ ± δ with cos δ = e1·a.
        let phi = libm::atan2(e1.dot(&n2), e1.dot(&z));
        let delta = libm::atan2(s, along);
        let mut best: Option<(f64, f64, f64)> = None;
        let mut nearest_free: Option<(f64, f64, f64)> = None;
        for sign in [1.0, -1.0] {
            let q2 = phi + sign * delta;
            let w = z * libm::cos(q2) + n2 * libm::sin(q2);
            let w_perp = w - e1 * e1.dot(&w);
            let q1 = libm::atan2(cross_along(&w_perp, &perp, &e1), w_perp.dot(&perp));
            let free1 = nearest_turn(q1, cur[0], f64::MIN, f64::MAX).unwrap_or(q1);
            let free2 = nearest_turn(q2, cur[1], f64::MIN, f64::MAX).unwrap_or(q2);
            let cost = sq(free1 - cur[0]) + sq(free2 - cur[1]);
            if nearest_free.is_none_or(|b| cost < b.2) {
                nearest_free = Some((free1, free2, cost));
            }
            let (Some(r1), Some(r2)) = (
                nearest_turn(q1, cur[0], lo1, hi1),
                nearest_turn(q2, cur[1], lo2, hi2),
            ) else {
                continue;
            };
            let cost = sq(r1 - cur[0]) + sq(r2 - cur[1]);
            if best.is_none_or(|b| cost < b.2) {
                best = Some((r1, r2, cost));
            }
        }
        match best {
            Some((q1, q2, _)) => Ok((q1, q2, false)),
            None => {
                let (f1, f2, _) = nearest_free.unwrap_or((cur[0], cur[1], 0.0));
                let in1 = f1 >= lo1 - RANGE_SLACK && f1 <= hi1 + RANGE_SLACK;
                Err(if in1 {
                    range_err(second, f2)
                } else {
                    range_err(first, f1)
                })
            }
        }
    }

    /// Joint velocities (mm/s and deg/s, `[X, Y, Z, A, B, C]`; 0 for the
    /// rotary axis the machine lacks) that move the tool tip at
    /// `tip_velocity` (mm/s) and turn the tool axis at `axis_velocity`
    /// (`d(axis)/dt`, 1/s; only its part perpendicular to the axis counts),
    /// both in the workpiece frame, at `joints`. This is the inverse of the
    /// machine's Jacobian; at the pole it does not exist.
    pub fn joint_rates(
        &self,
        joints: &Joints,
        tip_velocity: &Vec3,
        axis_velocity: &Vec3,
    ) -> Result<Joints, RateError> {
        let finite = |v: &Vec3| v.iter().all(|c| c.is_finite());
        if !joints.iter().all(|v| v.is_finite()) || !finite(tip_velocity) || !finite(axis_velocity)
        {
            return Err(RateError::NonFinite);
        }
        let pose = self.forward(joints);
        let (p, a) = (pose.tip, pose.axis);
        // Columns of the Jacobian: ∂tip/∂q and ∂axis/∂q for each link.
        let mut tip_cols = [Vec3::zeros(); 6];
        let mut axis_cols = [Vec3::zeros(); 6];
        let mut d = Matrix3::zeros();
        self.walk(joints, |link, r, t| {
            let dir = r * link.dir;
            if link.rotary.is_some() {
                let c = r * link.centre + t;
                tip_cols[link.joint] = dir.cross(&(p - c));
                axis_cols[link.joint] = dir.cross(&a);
            } else {
                tip_cols[link.joint] = dir;
                d.set_column(link.joint, &dir);
            }
        });
        let (first, second) = self.spec.chain.roles();
        let (u1, u2) = (axis_cols[first.joint()], axis_cols[second.joint()]);
        // Cramer in the plane perpendicular to the axis.
        let det = cross_along(&u1, &u2, &a);
        if libm::fabs(det) <= self.spec.pole_tolerance {
            return Err(RateError::AtPole {
                pole_distance: self.pole_distance(&a),
            });
        }
        let w = axis_velocity - a * a.dot(axis_velocity);
        let r1 = cross_along(&w, &u2, &a) / det;
        let r2 = cross_along(&u1, &w, &a) / det;
        let rest = tip_velocity - tip_cols[first.joint()] * r1 - tip_cols[second.joint()] * r2;
        if libm::fabs(d.determinant()) < LINEAR_DET_MIN {
            return Err(RateError::LinearSingular);
        }
        let lin = d.try_inverse().ok_or(RateError::LinearSingular)? * rest;
        let mut out = [0.0; 6];
        out[..3].copy_from_slice(lin.as_slice());
        out[first.joint()] = r1.to_degrees();
        out[second.joint()] = r2.to_degrees();
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    extern crate std;

    use super::*;
    use nalgebra::{Isometry3, Point3, Translation3, Unit, UnitQuaternion, Vector3};
    use proptest::prelude::*;
    use std::string::{String, ToString};
    use std::vec::Vec;

    /// The twelve five-axis keys.
    fn five_axis_keys() -> Vec<RotaryKey> {
        RotaryKey::all()
            .into_iter()
            .filter(|k| k.machine_type().is_some())
            .collect()
    }

    /// A chain notation for `key` with the linear axes `xyz` (in the order
    /// `perm`) inserted at the positions `at` (0..=3 among the three
    /// rotary/bed symbols, non-decreasing after sorting).
    fn notation(key: RotaryKey, perm: [usize; 3], mut at: [usize; 3]) -> String {
        at.sort_unstable();
        let key = key.to_string();
        let mut out = String::from("W/");
        let mut li = 0;
        for (i, ch) in key.chars().chain(core::iter::once('/')).enumerate() {
            while li < 3 && at[li] == i {
                out.push(['x', 'y', 'z'][perm[li]]);
                li += 1;
            }
            if ch != '/' {
                out.push(ch);
            }
        }
        out.push_str("/T");
        out
    }

    const PERMS: [[usize; 3]; 6] = [
        [0, 1, 2],
        [0, 2, 1],
        [1, 0, 2],
        [1, 2, 0],
        [2, 0, 1],
        [2, 1, 0],
    ];

    /// A machine of a random five-axis key with random layout, offsets and
    /// ranges around `joints` (the ranges always contain its rotary joints).
    #[derive(Debug)]
    struct Case {
        machine: Machine,
        joints: Joints,
    }

    fn case_strategy() -> impl Strategy<Value = Case> {
        (
            0..12usize,
            0..6usize,
            [0..4usize, 0..4usize, 0..4usize],
            prop::array::uniform3(prop::array::uniform3(-200.0..200.0f64)),
            0.0..200.0f64,
            prop::array::uniform3(-300.0..300.0f64),
            prop::array::uniform3(-400.0..400.0f64),
            prop::array::uniform3(prop_oneof![
                Just(None),
                (1.0..200.0f64, 1.0..200.0f64).prop_map(Some)
            ]),
        )
            .prop_map(|(k, perm, at, centres, tool, lin, rot, margins)| {
                let key = five_axis_keys()[k];
                let chain: Chain = notation(key, PERMS[perm], at).parse().unwrap();
                let mut spec = MachineSpec::new(chain);
                spec.tool_length = tool;
                spec.rotary_centres = centres;
                let mut joints = [lin[0], lin[1], lin[2], rot[0], rot[1], rot[2]];
                for axis in RotaryAxis::ALL {
                    if !chain.has(axis) {
                        joints[axis.joint()] = 0.0;
                    }
                }
                for (i, m) in margins.iter().enumerate() {
                    if let Some((below, above)) = m {
                        let q = joints[3 + i];
                        spec.rotary_ranges[i] = RotaryRange {
                            min: q - below,
                            max: q + above,
                        };
                    }
                }
                Case {
                    machine: Machine::new(spec).unwrap(),
                    joints,
                }
            })
    }

    /// The tool pose by composing the chain as isometries (quaternions, in
    /// chain order): a second computation, written apart from `walk`.
    fn composed(m: &Machine, joints: &Joints) -> ToolPose {
        let spec = m.spec();
        let mut iso = Isometry3::identity();
        for e in spec.chain.elements() {
            match *e {
                Element::Bed => {}
                Element::Linear(i) => {
                    let mut v = Vector3::zeros();
                    v[usize::from(i)] = joints[usize::from(i)];
                    iso *= Translation3::from(v);
                }
                Element::Rotary(r) => {
                    let c = Vector3::from(spec.rotary_centres[r.index()]);
                    let dir = Unit::new_normalize(r.direction());
                    let q = UnitQuaternion::from_axis_angle(&dir, joints[r.joint()].to_radians());
                    iso = iso
                        * Translation3::from(c)
                        * Isometry3::from_parts(Translation3::identity(), q)
                        * Translation3::from(-c);
                }
            }
        }
        ToolPose {
            tip: (iso * Point3::new(0.0, 0.0, -spec.tool_length)).coords,
            axis: iso * Vector3::z(),
        }
    }

    fn away_from_pole(m: &Machine, j: &Joints) -> bool {
        m.pole_distance(&m.forward(j).axis) > 1e-3
    }

    /// `|det|` of the linear axes' directions in the workpiece frame at `j`
    /// (1 unless a rotary axis sits between two linear ones): errors in the
    /// linear joints grow as its inverse.
    fn linear_det(m: &Machine, j: &Joints) -> f64 {
        let p = m.forward(j).tip;
        let col = |i: usize| {
            let mut k = *j;
            k[i] += 1.0;
            m.forward(&k).tip - p
        };
        Matrix3::from_columns(&[col(0), col(1), col(2)])
            .determinant()
            .abs()
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 768, ..ProptestConfig::default() })]

        #[test]
        fn forward_equals_composed_isometries(c in case_strategy()) {
            let f = c.machine.forward(&c.joints);
            let g = composed(&c.machine, &c.joints);
            prop_assert!((f.tip - g.tip).norm() <= 1e-11, "{} {:?} {:?}", c.machine.chain(), f, g);
            prop_assert!((f.axis - g.axis).norm() <= 1e-14);
            prop_assert!((f.axis.norm() - 1.0).abs() <= 1e-15);
        }

        /// forward(inverse(p)) = p for every ordering, layout, offset and
        /// range; and from near the joints that made p, inverse gives them back.
        #[test]
        fn inverse_round_trips(c in case_strategy(), nudge in prop::array::uniform3(-5.0..5.0f64)) {
            let m = &c.machine;
            let pose = m.forward(&c.joints);
            let mut current = c.joints;
            for i in 0..3 {
                current[3 + i] += nudge[i];
                current[i] += 10.0 * nudge[i];
            }
            let sol = m.inverse(&pose, &current).unwrap();
            let back = m.forward(&sol.joints);
            let tol = 1e-12 / linear_det(m, &c.joints).min(1.0);
            prop_assert!((back.tip - pose.tip).norm() <= tol,
                "{}: tip off by {:e}", m.chain(), (back.tip - pose.tip).norm());
            prop_assert!((back.axis - pose.axis).norm() <= 1e-13);
            if away_from_pole(m, &c.joints) {
                prop_assert!(!sol.at_pole);
                for i in 0..6 {
                    // The axis the machine lacks keeps its current value.
                    let lacks = i >= 3 && !m.chain().has(RotaryAxis::ALL[i - 3]);
                    let expect = if lacks { current[i] } else { c.joints[i] };
                    prop_assert!((sol.joints[i] - expect).abs() <= 1e-8,
                        "{}: joint {i} {} vs {}", m.chain(), sol.joints[i], expect);
                }
            }
            let lo = m.spec().rotary_ranges;
            for axis in RotaryAxis::ALL.into_iter().filter(|a| m.chain().has(*a)) {
                let v = sol.joints[axis.joint()];
                let r = lo[axis.index()];
                prop_assert!(v >= r.min - 1e-9 && v <= r.max + 1e-9);
            }
        }

        /// `place_tip` with the rotary joints of a pose gives back its
        /// linear joints (the tip to the inverse's precision), for every
        /// ordering, layout, offset and range; the axis the machine lacks
        /// keeps its current value.
        #[test]
        fn place_tip_round_trips(c in case_strategy(), nudge in prop::array::uniform3(-5.0..5.0f64)) {
            let m = &c.machine;
            let pose = m.forward(&c.joints);
            let mut current = c.joints;
            for i in 0..3 {
                current[i] += 10.0 * nudge[i];
                current[3 + i] += nudge[i];
            }
            let rotary = [c.joints[3], c.joints[4], c.joints[5]];
            let q = m.place_tip(&pose.tip, rotary, &current).unwrap();
            let back = m.forward(&q);
            let tol = 1e-12 / linear_det(m, &c.joints).min(1.0);
            prop_assert!((back.tip - pose.tip).norm() <= tol,
                "{}: tip off by {:e}", m.chain(), (back.tip - pose.tip).norm());
            prop_assert!((back.axis - pose.axis).norm() <= 1e-13);
            for axis in RotaryAxis::ALL {
                let expect = if m.chain().has(axis) { rotary[axis.index()] } else { current[axis.joint()] };
                prop_assert_eq!(q[axis.joint()], expect);
            }
        }

        /// The joint rates invert the Jacobian: rates from central
        /// differences of `forward` come back.
        #[test]
        fn joint_rates_invert_finite_differences(
            c in case_strategy(),
            rates in prop::array::uniform6(-1.0..1.0f64),
        ) {
            let m = &c.machine;
            let pole = m.pole_distance(&m.forward(&c.joints).axis);
            let det = linear_det(m, &c.joints);
            prop_assume!(pole > 1e-3 && det > 1e-3);
            let h = 1e-6;
            let step = |s: f64| {
                let mut j = c.joints;
                for i in 0..6 {
                    j[i] += s * h * rates[i];
                }
                m.forward(&j)
            };
            let (p, n) = (step(1.0), step(-1.0));
            let tip_v = (p.tip - n.tip) / (2.0 * h);
            let axis_v = (p.axis - n.axis) / (2.0 * h);
            let got = m.joint_rates(&c.joints, &tip_v, &axis_v).unwrap();
            for axis in RotaryAxis::ALL {
                if !m.chain().has(axis) {
                    prop_assert_eq!(got[axis.joint()], 0.0);
                }
            }
            for i in 0..6 {
                let expect = if i >= 3 && !m.chain().has(RotaryAxis::ALL[i - 3]) { 0.0 } else { rates[i] };
                // Central differences: O(h²) and round-off eps·|tip|/h,
                // amplified near the pole and by skewed linear axes.
                let tol = 1e-7 * (1.0 + tip_v.norm()) / (pole * det);
                prop_assert!((got[i] - expect).abs() <= tol,
                    "{}: rate {i} {} vs {}", m.chain(), got[i], expect);
            }
        }
    }

    #[test]
    fn eighteen_orderings_six_excluded_twelve_classified() {
        let names = |t: Option<MachineType>| -> std::collections::BTreeSet<String> {
            RotaryKey::all()
                .iter()
                .filter(|k| k.machine_type() == t)
                .map(|k| k.to_string())
                .collect()
        };
        let all: std::collections::BTreeSet<String> =
            RotaryKey::all().iter().map(|k| k.to_string()).collect();
        assert_eq!(all.len(), 18);
        let set = |v: [&str; 6]| v.map(String::from).into();
        assert_eq!(names(None), set(["bcB", "bBc", "Bbc", "acB", "aBc", "Bac"]));
        // The paper's C,A list repeats `caB`; the sixth member is `cbB`.
        assert_eq!(
            names(Some(MachineType::CA)),
            set(["caB", "cbB", "cBb", "cBa", "Bca", "Bcb"])
        );
        assert_eq!(
            names(Some(MachineType::AB)),
            set(["abB", "baB", "aBb", "bBa", "Bab", "Bba"])
        );
        // The seed's Fig. 4: (a) spindle tilting, (b) spindle and table, (c), (d) table tilting.
        for (n, key, mounting) in [
            ("W/xyBzca/T", "Bca", Mounting::HeadHead),
            ("W/cxyBza/T", "cBa", Mounting::TableHead),
            ("W/caxyBz/T", "caB", Mounting::TableTable),
            ("W/baxzBy/T", "baB", Mounting::TableTable),
        ] {
            let c: Chain = n.parse().unwrap();
            assert_eq!(
                (c.key().to_string().as_str(), c.key().mounting()),
                (key, mounting)
            );
            assert_eq!(c.to_string(), n);
        }
    }

    #[test]
    fn excluded_orderings_are_refused_with_the_seed_reason() {
        // The seed's worked example: Bac gives (0, −sΦ, cΦ) whatever C does.
        let bac = RotaryKey {
            first: RotaryAxis::A,
            second: RotaryAxis::C,
            bed_position: 0,
        };
        let phi: f64 = 0.4;
        for q2 in [-2.5, 0.7, 1.4] {
            let v = bac.ftm5(phi, q2);
            assert!((v - Vec3::new(0.0, -phi.sin(), phi.cos())).norm() < 1e-15);
        }
        for key in RotaryKey::all()
            .into_iter()
            .filter(|k| k.machine_type().is_none())
        {
            let n = notation(key, [0, 1, 2], [3, 3, 3]);
            let err = n.parse::<Chain>().unwrap_err();
            assert_eq!(err, ChainError::NotFiveAxis { key }, "{n}");
            let msg = err.to_string();
            assert!(
                msg.contains("not a 5-axis machine") && msg.contains(&key.to_string()),
                "{msg}"
            );
        }
    }

    #[test]
    fn bad_notation_is_named() {
        assert_eq!("caxyBz".parse::<Chain>(), Err(ChainError::Syntax));
        assert_eq!(
            "W/caxyBq/T".parse::<Chain>(),
            Err(ChainError::BadAxis {
                found: 'q',
                position: 7
            })
        );
        assert_eq!(
            "W/caxxBz/T".parse::<Chain>(),
            Err(ChainError::Repeated { axis: 'x' })
        );
        assert_eq!("W/cxyBz/T".parse::<Chain>(), Err(ChainError::Axes));
        assert_eq!("W/cabxyBz/T".parse::<Chain>(), Err(ChainError::Axes));
        assert_eq!("W/caxyz/T".parse::<Chain>(), Err(ChainError::Axes));
    }

    #[test]
    fn machine_spec_is_checked() {
        let chain: Chain = "W/caxyBz/T".parse().unwrap();
        let mut s = MachineSpec::new(chain);
        s.tool_length = f64::NAN;
        assert!(matches!(Machine::new(s), Err(MachineError::ToolLength(_))));
        let mut s = MachineSpec::new(chain);
        s.rotary_ranges[0] = RotaryRange {
            min: 10.0,
            max: -10.0,
        };
        assert!(matches!(
            Machine::new(s),
            Err(MachineError::Range {
                axis: RotaryAxis::A,
                ..
            })
        ));
        // The axis the machine lacks is not checked.
        let mut s = MachineSpec::new(chain);
        s.rotary_ranges[1] = RotaryRange {
            min: f64::NAN,
            max: 0.0,
        };
        s.rotary_centres[1] = [f64::NAN; 3];
        assert!(Machine::new(s).is_ok());
        let mut s = MachineSpec::new(chain);
        s.rotary_centres[2][1] = f64::INFINITY;
        assert!(matches!(
            Machine::new(s),
            Err(MachineError::Centre {
                axis: RotaryAxis::C
            })
        ));
        let mut s = MachineSpec::new(chain);
        s.pole_tolerance = -1.0;
        assert!(matches!(
            Machine::new(s),
            Err(MachineError::PoleTolerance(_))
        ));
    }

    /// LinuxCNC's `xyzac-trt-kins` and `xyzbc-trt-kins` (trtfuncs.c, the
    /// forward equations as documented there), with its table turning by
    /// `+A`/`+B`, `+C` and its world point the tip raised by the tool length:
    /// our joints with the rotary signs flipped give its pose.
    #[test]
    fn linuxcnc_trt_forward_equations() {
        let (xr, yr, zr) = (12.5, -40.0, -75.0);
        let (dx, dy, dz, dt) = (3.0, 7.0, -20.0, 110.0);
        let (s, c) = (f64::sin, f64::cos);
        for (i, (x, y, z, r1, r2)) in [
            (10.0, 20.0, 30.0, 15.0, 40.0),
            (-150.0, 75.0, 210.0, -95.0, 280.0),
            (0.0, 0.0, 0.0, 0.0, 0.0),
            (33.0, -12.0, 5.0, 60.0, -170.0),
        ]
        .into_iter()
        .enumerate()
        {
            // xyzac: A tilts the table, C turns on it (W/caxyzB/T).
            let (a, cc) = (f64::to_radians(r1), f64::to_radians(r2));
            let zz = dz + dt;
            let lc = Vec3::new(
                c(cc) * (x - xr)
                    + s(cc) * c(a) * (y - dy - yr)
                    + s(cc) * s(a) * (z - zz - zr)
                    + s(cc) * dy
                    + xr,
                -s(cc) * (x - xr)
                    + c(cc) * c(a) * (y - dy - yr)
                    + c(cc) * s(a) * (z - zz - zr)
                    + c(cc) * dy
                    + yr,
                -s(a) * (y - dy - yr) + c(a) * (z - zz - zr) + zz + zr,
            );
            let mut spec = MachineSpec::new("W/caxyzB/T".parse().unwrap());
            spec.tool_length = dt;
            spec.rotary_centres[2] = [xr, yr, zr];
            spec.rotary_centres[0] = [xr, yr + dy, zr + dz];
            let m = Machine::new(spec).unwrap();
            let ours = m.forward(&[x, y, z, -r1, 0.0, -r2]);
            assert!(
                (ours.tip + Vec3::new(0.0, 0.0, dt) - lc).norm() < 1e-12,
                "xyzac case {i}"
            );
            assert!((ours.axis - Vec3::new(s(cc) * s(a), c(cc) * s(a), c(a))).norm() < 1e-15);

            // xyzbc: B tilts the table, C turns on it (W/cbxyzB/T).
            let b = a;
            let lc = Vec3::new(
                c(cc) * c(b) * (x - dx - xr) + s(cc) * (y - yr) - c(cc) * s(b) * (z - zz - zr)
                    + c(cc) * dx
                    + xr,
                -s(cc) * c(b) * (x - dx - xr) + c(cc) * (y - yr) + s(cc) * s(b) * (z - zz - zr)
                    - s(cc) * dx
                    + yr,
                s(b) * (x - dx - xr) + c(b) * (z - zz - zr) + zz + zr,
            );
            let mut spec = MachineSpec::new("W/cbxyzB/T".parse().unwrap());
            spec.tool_length = dt;
            spec.rotary_centres[2] = [xr, yr, zr];
            spec.rotary_centres[1] = [xr + dx, yr, zr + dz];
            let m = Machine::new(spec).unwrap();
            let ours = m.forward(&[x, y, z, 0.0, -r1, -r2]);
            assert!(
                (ours.tip + Vec3::new(0.0, 0.0, dt) - lc).norm() < 1e-12,
                "xyzbc case {i}"
            );
        }
    }

    fn ca_machine(a_range: RotaryRange, c_range: RotaryRange) -> Machine {
        let mut spec = MachineSpec::new("W/caxyBz/T".parse().unwrap());
        spec.tool_length = 100.0;
        spec.rotary_centres[0] = [0.0, 0.0, -150.0];
        spec.rotary_centres[2] = [5.0, -3.0, 0.0];
        spec.rotary_ranges[0] = a_range;
        spec.rotary_ranges[2] = c_range;
        Machine::new(spec).unwrap()
    }

    fn ac(a: f64, c: f64) -> Joints {
        [10.0, -20.0, 30.0, a, 0.0, c]
    }

    #[test]
    fn nearest_solution_of_the_two_branches_and_the_turns() {
        let m = ca_machine(RotaryRange::UNLIMITED, RotaryRange::UNLIMITED);
        let pose = m.forward(&ac(30.0, 0.0));
        // The same pose is reached by (A, C) = (30, 0) and (−30, 180), ±360° on either.
        let other = m.inverse(&pose, &ac(-25.0, 170.0)).unwrap().joints;
        assert!(
            (other[3] + 30.0).abs() < 1e-9 && (other[5] - 180.0).abs() < 1e-9,
            "{other:?}"
        );
        assert!((m.forward(&other).tip - pose.tip).norm() < 1e-12);
        let near = m.inverse(&pose, &ac(-25.0, 10.0)).unwrap().joints;
        assert!(
            (near[3] - 30.0).abs() < 1e-9 && near[5].abs() < 1e-9,
            "{near:?}"
        );
        // Turns: from C = 350 the pose at C = 10 is reached at 370 …
        let pose = m.forward(&ac(20.0, 10.0));
        let j = m.inverse(&pose, &ac(20.0, 350.0)).unwrap().joints;
        assert!((j[5] - 370.0).abs() < 1e-9, "{j:?}");
        // … unless C stops at 360: then the other branch (−20, 190) is nearer
        // than (20, 10) …
        let m = ca_machine(
            RotaryRange::UNLIMITED,
            RotaryRange {
                min: -360.0,
                max: 360.0,
            },
        );
        let j = m.inverse(&pose, &ac(20.0, 350.0)).unwrap().joints;
        assert!(
            (j[3] + 20.0).abs() < 1e-9 && (j[5] - 190.0).abs() < 1e-9,
            "{j:?}"
        );
        // … and if A cannot go negative, (20, 10) it is.
        let m = ca_machine(
            RotaryRange {
                min: 0.0,
                max: 90.0,
            },
            RotaryRange {
                min: -360.0,
                max: 360.0,
            },
        );
        let j = m.inverse(&pose, &ac(20.0, 350.0)).unwrap().joints;
        assert!(
            (j[3] - 20.0).abs() < 1e-9 && (j[5] - 10.0).abs() < 1e-9,
            "{j:?}"
        );
        // A range on the tilt picks the branch even when the other is nearer.
        let m = ca_machine(
            RotaryRange {
                min: -10.0,
                max: 110.0,
            },
            RotaryRange::UNLIMITED,
        );
        let pose = m.forward(&ac(30.0, 0.0));
        let j = m.inverse(&pose, &ac(-29.0, 179.0)).unwrap().joints;
        assert!(
            (j[3] - 30.0).abs() < 1e-9 && (j[5] - 0.0).abs() < 1e-9,
            "{j:?}"
        );
    }

    #[test]
    fn out_of_range_is_refused_naming_the_axis() {
        let m = ca_machine(
            RotaryRange {
                min: -20.0,
                max: 20.0,
            },
            RotaryRange::UNLIMITED,
        );
        let pose =
            ca_machine(RotaryRange::UNLIMITED, RotaryRange::UNLIMITED).forward(&ac(45.0, 60.0));
        let err = m.inverse(&pose, &ac(0.0, 50.0)).unwrap_err();
        match err {
            InverseError::OutOfRange { axis, needed, .. } => {
                assert_eq!(axis, RotaryAxis::A);
                assert!((needed - 45.0).abs() < 1e-9, "{needed}");
            }
            e => panic!("{e:?}"),
        }
        assert!(err.to_string().contains("A would need 45"), "{err}");
        // Rotary positions given (G43.4) out of range: refused the same way.
        assert_eq!(
            m.place_tip(&pose.tip, [45.0, 0.0, 60.0], &ac(0.0, 50.0)),
            Err(InverseError::OutOfRange {
                axis: RotaryAxis::A,
                needed: 45.0,
                range: RotaryRange {
                    min: -20.0,
                    max: 20.0
                },
            })
        );
        assert_eq!(
            m.place_tip(&pose.tip, [f64::NAN, 0.0, 60.0], &ac(0.0, 50.0)),
            Err(InverseError::BadPose)
        );
        // C limited to [0, 90] and A to [0, 90]: (45, 240) and (−45, 60) both fail.
        let m = ca_machine(
            RotaryRange {
                min: 0.0,
                max: 90.0,
            },
            RotaryRange {
                min: 0.0,
                max: 90.0,
            },
        );
        let full = ca_machine(RotaryRange::UNLIMITED, RotaryRange::UNLIMITED);
        let pose = full.forward(&ac(45.0, 240.0));
        assert!(matches!(
            m.inverse(&pose, &ac(10.0, 10.0)),
            Err(InverseError::OutOfRange { .. })
        ));
        // Non-finite input.
        let bad = ToolPose {
            tip: Vec3::new(f64::NAN, 0.0, 0.0),
            axis: Vec3::z(),
        };
        assert_eq!(m.inverse(&bad, &ac(0.0, 0.0)), Err(InverseError::BadPose));
        let zero = ToolPose {
            tip: Vec3::zeros(),
            axis: Vec3::zeros(),
        };
        assert_eq!(m.inverse(&zero, &ac(0.0, 0.0)), Err(InverseError::BadPose));
        assert_eq!(
            m.inverse(&pose, &ac(f64::NAN, 0.0)),
            Err(InverseError::BadJoints)
        );
    }

    #[test]
    fn at_the_pole_c_is_kept_and_crossing_it_does_not_jump() {
        let m = ca_machine(RotaryRange::UNLIMITED, RotaryRange::UNLIMITED);
        let pose = m.forward(&ac(0.0, 123.0));
        let sol = m.inverse(&pose, &ac(3.0, 37.5)).unwrap();
        assert!(sol.at_pole);
        assert_eq!(sol.joints[5], 37.5);
        assert!(sol.joints[3].abs() < 1e-12);
        assert!((m.forward(&sol.joints).tip - pose.tip).norm() < 1e-12);
        // Within the tolerance of the pole: C kept, the axis reached within it.
        let tilt = 0.5 * DEFAULT_POLE_TOLERANCE;
        let pose = m.forward(&ac(tilt.to_degrees(), 80.0));
        let sol = m.inverse(&pose, &ac(0.0, -15.0)).unwrap();
        assert!(sol.at_pole && sol.joints[5] == -15.0);
        let back = m.forward(&sol.joints);
        assert!((back.axis - pose.axis).norm() <= DEFAULT_POLE_TOLERANCE);
        assert!((back.tip - pose.tip).norm() < 1e-12);
        // A tool axis swinging through the pole in the plane of C = 90°: A
        // passes through 0 and changes sign, C never moves.
        let mut j = ac(20.0, 90.0);
        let mut max_step: f64 = 0.0;
        for k in 0..=400 {
            let a = 20.0 - 0.1 * f64::from(k);
            let pose = m.forward(&ac(a, 90.0));
            let next = m.inverse(&pose, &j).unwrap().joints;
            assert!((next[5] - 90.0).abs() < 1e-9, "step {k}: C = {}", next[5]);
            max_step = max_step.max((next[3] - j[3]).abs());
            j = next;
        }
        assert!(
            (j[3] + 20.0).abs() < 1e-9 && max_step < 0.1 + 1e-9,
            "{j:?} {max_step}"
        );
        // Rates: none at the pole; near it C needs ω / pole_distance at most.
        let at = ac(0.0, 10.0);
        assert!(matches!(
            m.joint_rates(&at, &Vec3::zeros(), &Vec3::x()),
            Err(RateError::AtPole { .. })
        ));
        let near = ac(0.01, 10.0);
        let axis = m.forward(&near).axis;
        let d = m.pole_distance(&axis);
        assert!((d - 0.01f64.to_radians().sin()).abs() < 1e-15);
        for k in 0..16 {
            let t = f64::from(k) * core::f64::consts::PI / 8.0;
            // A unit angular velocity in a direction perpendicular to the axis.
            let u = axis.cross(&Vec3::new(t.cos(), t.sin(), 0.0)).normalize();
            let r = m.joint_rates(&near, &Vec3::zeros(), &u).unwrap();
            let c_rate = r[5].to_radians().abs();
            assert!(c_rate <= 1.0 / d * (1.0 + 1e-9));
            assert!(r[3].to_radians().abs() <= 1.0 + 1e-9);
        }
        // Reached when the axis moves the way C alone moves it.
        let u = Vec3::z().cross(&axis).normalize();
        let r = m.joint_rates(&near, &Vec3::zeros(), &u).unwrap();
        assert!((r[5].to_radians().abs() * d - 1.0).abs() < 1e-9, "{r:?}");
        assert!(r[3].abs() < 1e-9, "{r:?}");
        let lim = m.max_axis_rate(&axis, 360.0, 90.0);
        assert!(
            (lim - (2.0 * core::f64::consts::PI * d).min(0.5 * core::f64::consts::PI)).abs()
                < 1e-15
        );
    }

    #[test]
    fn a_rotary_between_linear_axes_can_make_them_parallel() {
        // x on the workpiece side of c, y on the tool side: at C = 90° both
        // move the tool along x relative to the workpiece.
        let m = Machine::new(MachineSpec::new("W/xcyzBa/T".parse().unwrap())).unwrap();
        let j = [1.0, 2.0, 3.0, 10.0, 0.0, 90.0];
        let pose = m.forward(&j);
        assert_eq!(m.inverse(&pose, &j), Err(InverseError::LinearSingular));
        assert_eq!(
            m.joint_rates(&j, &Vec3::x(), &Vec3::zeros()),
            Err(RateError::LinearSingular)
        );
        let j = [1.0, 2.0, 3.0, 10.0, 0.0, 60.0];
        let sol = m.inverse(&m.forward(&j), &j).unwrap();
        assert!((sol.joints[0] - 1.0).abs() < 1e-12 && (sol.joints[1] - 2.0).abs() < 1e-12);
    }

    #[cfg(feature = "serde")]
    #[test]
    fn spec_reads_from_json_with_defaults() {
        let s: MachineSpec = serde_json::from_str(
            r#"{"chain": "W/caxyBz/T", "tool-length": 80, "rotary-ranges": [{"min": -30, "max": 110}, {"min": 0, "max": 0}, {"min": -1e9, "max": 1e9}]}"#,
        )
        .unwrap();
        assert_eq!(s.chain.key().to_string(), "caB");
        assert_eq!(s.pole_tolerance, DEFAULT_POLE_TOLERANCE);
        assert_eq!(s.rotary_centres, [[0.0; 3]; 3]);
        assert!(Machine::new(s).is_ok());
        let bad = serde_json::from_str::<MachineSpec>(r#"{"chain": "W/xyBzac/T"}"#).unwrap_err();
        assert!(bad.to_string().contains("not a 5-axis machine"), "{bad}");
        let text = serde_json::to_string(&s).unwrap();
        assert!(text.contains("\"W/caxyBz/T\""), "{text}");
        // The TOML example of docs/kinematics.md.
        let s: MachineSpec = toml::from_str(
            r#"
chain = "W/caxyBz/T"          # table-table C,A
tool-length = 120.0           # mm, default 0
rotary-centres = [[0, 0, -150], [0, 0, 0], [0, 0, 0]]   # A, B, C at home, mm; default origin
rotary-ranges = [{ min = -30, max = 120 }, { min = 0, max = 0 }, { min = -inf, max = inf }]
pole-tolerance = 1e-9         # rad, default 1e-9
"#,
        )
        .unwrap();
        assert_eq!(s.rotary_centres[0], [0.0, 0.0, -150.0]);
        assert_eq!(s.rotary_ranges[2], RotaryRange::UNLIMITED);
        assert_eq!(s.tool_length, 120.0);
        assert!(Machine::new(s).is_ok());
        // An endless range through JSON (a trace's config): null both ways.
        let text = serde_json::to_string(&s).unwrap();
        assert!(text.contains(r#"{"min":null,"max":null}"#), "{text}");
        assert_eq!(serde_json::from_str::<MachineSpec>(&text).unwrap(), s);
    }
}
