//! Five-axis machine configurations (seed `000_…` §3).
//!
//! A machine is written `W/K1…Kn/T`: the chain of axes from the workpiece `W`
//! to the tool `T`, with `x y z` the linear axes, `a b c` the rotary axes about
//! x, y and z, and `B` the bed (the stationary element). Only the order of the
//! two rotary axes and the bed matters for the tool-axis directions, so each
//! configuration reduces to one of 18 keys such as `caB` (`W/caxyBz/T`).
//!
//! The feasible tool motion is `FTM⁵ = R_{r1}(q1)·R_{r2}(q2)·ẑ` (eq. 2), `r1`
//! the rotary axis nearer the workpiece. When `r2` is `c` (the key's last
//! rotary is `c`), it turns the tool about its own axis and the machine is not
//! a 5-axis machine (six keys). The twelve others are either **C,A type**
//! (`r1 = c`: two symmetric fans around the C axis) or **A,B type** (two tilt
//! axes: a spherical rectangle; `R1 = r1`, `R2 = r2`, the table of §3.3).

use std::fmt;
use std::str::FromStr;

use nalgebra::{Rotation3, Unit, Vector3};

/// A rotary axis: rotation about x (A), y (B) or z (C) of the machine frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize)]
pub enum RotaryAxis {
    /// Rotation about x.
    A,
    /// Rotation about y.
    B,
    /// Rotation about z (the tool axis at home).
    C,
}

impl RotaryAxis {
    /// The axis direction in the machine's home frame.
    pub fn direction(self) -> Vector3<f64> {
        match self {
            RotaryAxis::A => Vector3::x(),
            RotaryAxis::B => Vector3::y(),
            RotaryAxis::C => Vector3::z(),
        }
    }

    fn letter(self) -> char {
        match self {
            RotaryAxis::A => 'a',
            RotaryAxis::B => 'b',
            RotaryAxis::C => 'c',
        }
    }

    fn from_letter(c: char) -> Option<Self> {
        match c {
            'a' => Some(RotaryAxis::A),
            'b' => Some(RotaryAxis::B),
            'c' => Some(RotaryAxis::C),
            _ => None,
        }
    }
}

/// The shape of FTM⁵ on the sphere (§3.2).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize)]
pub enum MachineType {
    /// C,A (or C,B): two fans symmetric about the C axis, which is the tool
    /// axis at home. Φ is the tilt (A or B) range, Θ the C range.
    CA,
    /// A,B: a spherical rectangle; Φ is the range of `R1`, Θ that of `R2`.
    AB,
}

/// Why a machine description was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MachineError {
    /// Not of the form `W/…/T`.
    #[error("machine `{0}`: expected W/<axes>/T, e.g. W/caxyBz/T")]
    Syntax(String),
    /// A character that is not one of `x y z a b c B`.
    #[error(
        "machine `{notation}`: character `{found}` at position {position} is not one of x y z a b c B"
    )]
    BadAxis {
        /// The whole notation.
        notation: String,
        /// The character.
        found: char,
        /// 0-based position in the notation.
        position: usize,
    },
    /// An axis occurs twice.
    #[error("machine `{notation}`: axis `{axis}` occurs more than once")]
    Repeated {
        /// The whole notation.
        notation: String,
        /// The repeated axis.
        axis: char,
    },
    /// Not exactly x, y, z, two rotary axes and the bed.
    #[error("machine `{0}`: a 5-axis machine needs x, y, z, exactly two of a b c, and the bed B")]
    Axes(String),
    /// The last rotary axis is `c`: it only spins the tool about its own axis.
    #[error(
        "machine `{notation}` (rotary order `{key}`): the rotary axis next to the tool is c, which turns the tool about its own axis, so this is not a 5-axis machine"
    )]
    NotFiveAxis {
        /// The whole notation.
        notation: String,
        /// The reduced key, e.g. `Bac`.
        key: String,
    },
}

/// A five-axis machine configuration parsed from `W/…/T`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MachineConfig {
    notation: String,
    key: RotaryKey,
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

impl RotaryKey {
    /// All 18 orderings of two distinct rotary axes and the bed.
    pub fn all() -> Vec<RotaryKey> {
        use RotaryAxis::*;
        let mut keys = Vec::with_capacity(18);
        for (first, second) in [(A, B), (B, A), (B, C), (C, B), (C, A), (A, C)] {
            for bed_position in 0..3 {
                keys.push(RotaryKey {
                    first,
                    second,
                    bed_position,
                });
            }
        }
        keys
    }

    /// The machine type, or `None` for the six orderings that are not 5-axis
    /// machines (the rotary axis next to the tool is `c`).
    pub fn machine_type(&self) -> Option<MachineType> {
        if self.second == RotaryAxis::C {
            None
        } else if self.first == RotaryAxis::C {
            Some(MachineType::CA)
        } else {
            Some(MachineType::AB)
        }
    }

    /// The tool axis in the machine's home frame for joint angles `q1` (of
    /// `first`) and `q2` (of `second`), radians: `R_{r1}(q1)·R_{r2}(q2)·ẑ` (eq. 2).
    pub fn ftm5(&self, q1: f64, q2: f64) -> Vector3<f64> {
        let r1 = Rotation3::from_axis_angle(&Unit::new_unchecked(self.first.direction()), q1);
        let r2 = Rotation3::from_axis_angle(&Unit::new_unchecked(self.second.direction()), q2);
        r1 * r2 * Vector3::z()
    }

    /// The joint angles `(q1, q2)` (radians, in `(−π, π]`) at which the tool
    /// axis is `p`: `ftm5(q1, q2) = p̂`, the inverse of eq. 2. Two solutions
    /// in general (one when `p` lies on the `first` axis, where `q1` is free
    /// and taken as 0). Empty for the keys that are not 5-axis.
    pub fn positions_for(&self, p: &Vector3<f64>) -> Vec<(f64, f64)> {
        if self.machine_type().is_none() || p.norm() == 0.0 {
            return Vec::new();
        }
        let p = p.normalize();
        let (e1, z) = (self.first.direction(), Vector3::z());
        // R_{r2}(q2)·ẑ = cos q2·ẑ + sin q2·w (ẑ ⟂ r2, which is a or b), and
        // its component along r1 must be p's (R_{r1} keeps it):
        // cos q2·(ẑ·e1) + sin q2·(w·e1) = p·e1, with e1 in the plane of ẑ, w.
        let w = self.second.direction().cross(&z);
        let base = (w.dot(&e1)).atan2(z.dot(&e1));
        let spread = p.dot(&e1).clamp(-1.0, 1.0).acos();
        let wrap = |a: f64| {
            let a = a.rem_euclid(std::f64::consts::TAU);
            if a > std::f64::consts::PI {
                a - std::f64::consts::TAU
            } else {
                a
            }
        };
        let mut out: Vec<(f64, f64)> = Vec::with_capacity(2);
        for q2 in [base + spread, base - spread] {
            let v = z * q2.cos() + w * q2.sin();
            // q1 turns v about r1 onto p.
            let (vp, pp) = (v - e1 * v.dot(&e1), p - e1 * p.dot(&e1));
            let q1 = if vp.norm() < 1e-12 || pp.norm() < 1e-12 {
                0.0
            } else {
                e1.dot(&vp.cross(&pp)).atan2(vp.dot(&pp))
            };
            let q = (wrap(q1), wrap(q2));
            if !out
                .iter()
                .any(|o| (o.0 - q.0).abs() < 1e-12 && (o.1 - q.1).abs() < 1e-12)
            {
                out.push(q);
            }
        }
        out
    }
}

/// Rotary axis positions for 3+2 machining: where to put the machine's two
/// rotary axes so that the tool axis, seen from the part, is a given
/// direction ([`MachineConfig::rotary_positions`]).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct RotaryPositions {
    /// The axis nearer the workpiece (`r1`) and its angle, radians.
    pub first: (RotaryAxis, f64),
    /// The axis nearer the tool (`r2`) and its angle, radians.
    pub second: (RotaryAxis, f64),
    /// Whether both angles lie within the machine's ranges (C,A: C in
    /// `[−Θˢ, Θᴸ]`, tilt in `[−Φˢ, Φᴸ]`; A,B: R1 in `[−Φˢ, Φᴸ]`, R2 in
    /// `[−Θˢ, Θᴸ]`); if no solution does, the one with the least motion.
    pub within_ranges: bool,
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

impl MachineConfig {
    /// The notation as given.
    pub fn notation(&self) -> &str {
        &self.notation
    }

    /// The reduced rotary key, e.g. `caB`.
    pub fn key(&self) -> RotaryKey {
        self.key
    }

    /// C,A or A,B.
    pub fn machine_type(&self) -> MachineType {
        self.key
            .machine_type()
            .expect("checked when parsed: only 5-axis keys are stored")
    }

    /// The machine axes that play the roles of the paper's rotary axes: for a
    /// C,A type `(C, tilt axis)`, for an A,B type `(R1, R2)` (§3.3 table).
    pub fn roles(&self) -> (RotaryAxis, RotaryAxis) {
        (self.key.first, self.key.second)
    }

    /// The rotary axis positions at which the tool axis, seen from the part
    /// as it lies with the axes at zero, is `tool_axis` (part coordinates):
    /// with the axes there, a 3-axis program machines what that direction
    /// reaches (3+2). Of the solutions of [`RotaryKey::positions_for`], the
    /// one within `ranges` with the least motion `|q1| + |q2|` (angles
    /// taken modulo 360° into the range when that fits), else the least
    /// motion overall.
    pub fn rotary_positions(
        &self,
        ranges: &AxisRanges,
        tool_axis: &Vector3<f64>,
    ) -> RotaryPositions {
        use std::f64::consts::TAU;
        // (−low, high) of the first and second axis.
        let (first, second) = match self.machine_type() {
            MachineType::CA => (
                (ranges.theta_s, ranges.theta_l),
                (ranges.phi_s, ranges.phi_l),
            ),
            MachineType::AB => (
                (ranges.phi_s, ranges.phi_l),
                (ranges.theta_s, ranges.theta_l),
            ),
        };
        /// Slack on the range ends, radians.
        const SLACK: f64 = 1e-9;
        let fit = |q: f64, (low, high): (f64, f64)| {
            [q, q - TAU, q + TAU]
                .into_iter()
                .find(|&a| a >= -low - SLACK && a <= high + SLACK)
        };
        let mut best: Option<(bool, f64, f64, f64)> = None;
        for (q1, q2) in self.key.positions_for(tool_axis) {
            let (a, b) = match (fit(q1, first), fit(q2, second)) {
                (Some(a), Some(b)) => (a, b),
                _ => (q1, q2),
            };
            let within = fit(q1, first).is_some() && fit(q2, second).is_some();
            let cost = a.abs() + b.abs();
            let better = match best {
                None => true,
                Some((w, c, _, _)) => (within && !w) || (within == w && cost < c - 1e-12),
            };
            if better {
                best = Some((within, cost, a, b));
            }
        }
        let (within_ranges, _, q1, q2) = best.unwrap_or((true, 0.0, 0.0, 0.0));
        RotaryPositions {
            first: (self.key.first, q1),
            second: (self.key.second, q2),
            within_ranges,
        }
    }
}

impl FromStr for MachineConfig {
    type Err = MachineError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let notation = s.trim().to_string();
        let inner = notation
            .strip_prefix("W/")
            .and_then(|r| r.strip_suffix("/T"))
            .ok_or_else(|| MachineError::Syntax(notation.clone()))?;
        let mut seen = Vec::new();
        let mut rotary = Vec::new();
        let mut bed = None;
        let mut linear = 0;
        for (i, ch) in inner.chars().enumerate() {
            let position = i + 2;
            if !matches!(ch, 'x' | 'y' | 'z' | 'a' | 'b' | 'c' | 'B') {
                return Err(MachineError::BadAxis {
                    notation: notation.clone(),
                    found: ch,
                    position,
                });
            }
            if seen.contains(&ch) {
                return Err(MachineError::Repeated {
                    notation: notation.clone(),
                    axis: ch,
                });
            }
            seen.push(ch);
            if ch == 'B' {
                bed = Some((rotary.len()) as u8);
            } else if let Some(r) = RotaryAxis::from_letter(ch) {
                rotary.push(r);
            } else {
                linear += 1;
            }
        }
        let (Some(bed_position), [first, second], 3) = (bed, rotary.as_slice(), linear) else {
            return Err(MachineError::Axes(notation));
        };
        let key = RotaryKey {
            first: *first,
            second: *second,
            bed_position,
        };
        if key.machine_type().is_none() {
            return Err(MachineError::NotFiveAxis {
                notation,
                key: key.to_string(),
            });
        }
        Ok(MachineConfig { notation, key })
    }
}

/// The rotary ranges of a machine, radians, all ≥ 0 (§3.3): the larger and
/// smaller side of the Φ axis and of the Θ axis.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct AxisRanges {
    /// Larger side of Φ (C,A: tilt axis; A,B: R1).
    pub phi_l: f64,
    /// Smaller side of Φ.
    pub phi_s: f64,
    /// Larger side of Θ (C,A: C axis; A,B: R2).
    pub theta_l: f64,
    /// Smaller side of Θ.
    pub theta_s: f64,
}

/// Why axis ranges were refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RangesError {
    /// Not four comma-separated numbers.
    #[error("ranges `{0}`: expected PHI_L,PHI_S,THETA_L,THETA_S in degrees")]
    Syntax(String),
    /// A value is not finite, negative, or above 360°.
    #[error("ranges: {field} = {value}° must be finite and within 0..=360")]
    Value {
        /// The field name.
        field: &'static str,
        /// The value, degrees.
        value: f64,
    },
    /// A "larger" side is smaller than its "smaller" side.
    #[error("ranges: {large} ({l}°) must be ≥ {small} ({s}°)")]
    Order {
        /// Name of the larger side.
        large: &'static str,
        /// Its value, degrees.
        l: f64,
        /// Name of the smaller side.
        small: &'static str,
        /// Its value, degrees.
        s: f64,
    },
}

/// Largest accepted range of one side, degrees.
const MAX_RANGE_DEG: f64 = 360.0;

impl AxisRanges {
    /// Ranges from degrees, checked.
    pub fn from_degrees(
        phi_l: f64,
        phi_s: f64,
        theta_l: f64,
        theta_s: f64,
    ) -> Result<Self, RangesError> {
        let fields = [
            ("PHI_L", phi_l),
            ("PHI_S", phi_s),
            ("THETA_L", theta_l),
            ("THETA_S", theta_s),
        ];
        for (field, value) in fields {
            if !(value.is_finite() && (0.0..=MAX_RANGE_DEG).contains(&value)) {
                return Err(RangesError::Value { field, value });
            }
        }
        for (large, l, small, s) in [
            ("PHI_L", phi_l, "PHI_S", phi_s),
            ("THETA_L", theta_l, "THETA_S", theta_s),
        ] {
            if l < s {
                return Err(RangesError::Order { large, l, small, s });
            }
        }
        Ok(Self {
            phi_l: phi_l.to_radians(),
            phi_s: phi_s.to_radians(),
            theta_l: theta_l.to_radians(),
            theta_s: theta_s.to_radians(),
        })
    }

    /// Ranges in degrees `[phi_l, phi_s, theta_l, theta_s]`.
    pub fn degrees(&self) -> [f64; 4] {
        [self.phi_l, self.phi_s, self.theta_l, self.theta_s].map(f64::to_degrees)
    }
}

impl FromStr for AxisRanges {
    type Err = RangesError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let parts: Vec<&str> = s.split(',').collect();
        let [a, b, c, d] = parts.as_slice() else {
            return Err(RangesError::Syntax(s.to_string()));
        };
        let num = |t: &str| {
            t.trim()
                .parse::<f64>()
                .map_err(|_| RangesError::Syntax(s.to_string()))
        };
        Self::from_degrees(num(a)?, num(b)?, num(c)?, num(d)?)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eighteen_orderings_six_excluded_twelve_classified() {
        let keys = RotaryKey::all();
        let names: std::collections::BTreeSet<String> =
            keys.iter().map(|k| k.to_string()).collect();
        assert_eq!(names.len(), 18);
        let excluded: std::collections::BTreeSet<String> = keys
            .iter()
            .filter(|k| k.machine_type().is_none())
            .map(|k| k.to_string())
            .collect();
        let expect_excluded: std::collections::BTreeSet<String> =
            ["bcB", "bBc", "Bbc", "acB", "aBc", "Bac"]
                .map(String::from)
                .into();
        assert_eq!(excluded, expect_excluded);
        let of_type = |t| -> std::collections::BTreeSet<String> {
            keys.iter()
                .filter(|k| k.machine_type() == Some(t))
                .map(|k| k.to_string())
                .collect()
        };
        // The paper's C,A list repeats `caB`; the sixth member is `cbB`.
        assert_eq!(
            of_type(MachineType::CA),
            ["caB", "cbB", "cBb", "cBa", "Bca", "Bcb"]
                .map(String::from)
                .into()
        );
        assert_eq!(
            of_type(MachineType::AB),
            ["abB", "baB", "aBb", "bBa", "Bab", "Bba"]
                .map(String::from)
                .into()
        );
    }

    #[test]
    fn excluded_orderings_cannot_move_the_tool_with_the_c_joint() {
        for key in RotaryKey::all()
            .into_iter()
            .filter(|k| k.machine_type().is_none())
        {
            for q1 in [-1.0, 0.3, 2.0] {
                let base = key.ftm5(q1, 0.0);
                for q2 in [-2.5, 0.7, 1.4] {
                    assert!((key.ftm5(q1, q2) - base).norm() < 1e-12, "{key}");
                }
            }
        }
        // The paper's worked example: Bac gives (0, −sΦ, cΦ).
        let bac: RotaryKey = RotaryKey {
            first: RotaryAxis::A,
            second: RotaryAxis::C,
            bed_position: 0,
        };
        let phi: f64 = 0.4;
        let v = bac.ftm5(phi, 1.1);
        assert!((v - Vector3::new(0.0, -phi.sin(), phi.cos())).norm() < 1e-12);
    }

    #[test]
    fn r1_r2_table_of_section_3_3() {
        for (notation, r1) in [
            ("W/abxyzB/T", RotaryAxis::A),
            ("W/baxyzB/T", RotaryAxis::B),
            ("W/axyBzb/T", RotaryAxis::A),
            ("W/bxyBza/T", RotaryAxis::B),
            ("W/xyzBab/T", RotaryAxis::A),
            ("W/baxzBy/T", RotaryAxis::B),
        ] {
            let m: MachineConfig = notation.parse().unwrap();
            assert_eq!(m.machine_type(), MachineType::AB, "{notation}");
            assert_eq!(m.roles().0, r1, "{notation}");
        }
        for (notation, key) in [
            ("W/caxyBz/T", "caB"),
            ("W/xyBzca/T", "Bca"),
            ("W/cxyBza/T", "cBa"),
        ] {
            let m: MachineConfig = notation.parse().unwrap();
            assert_eq!(m.key().to_string(), key);
            assert_eq!(m.machine_type(), MachineType::CA);
        }
    }

    #[test]
    fn rotary_positions_invert_the_tool_axis_kinematics() {
        // Every 5-axis key, directions all over the sphere (poles included):
        // each solution turns the tool axis to the direction (eq. 2).
        let dirs: Vec<Vector3<f64>> = (0..40)
            .map(|k| {
                let (t, a) = (0.37 * k as f64, 1.3 * k as f64);
                Vector3::new(t.sin() * a.cos(), t.sin() * a.sin(), t.cos())
            })
            .chain([Vector3::z(), -Vector3::z(), Vector3::x(), -Vector3::y()])
            .collect();
        for key in RotaryKey::all()
            .into_iter()
            .filter(|k| k.machine_type().is_some())
        {
            for p in &dirs {
                let sols = key.positions_for(p);
                assert!(!sols.is_empty(), "{key} {p:?}");
                for (q1, q2) in sols {
                    assert!((key.ftm5(q1, q2) - p).norm() < 1e-12, "{key} {p:?}");
                }
            }
        }
        // A caB machine: the tool tilted 30° toward −y from the part's z
        // is A = 30° with C = 0 (R_x(30°)·ẑ = (0, −sin 30°, cos 30°)).
        let m: MachineConfig = "W/caxyBz/T".parse().unwrap();
        let r: AxisRanges = "110,30,180,180".parse().unwrap();
        let p = Vector3::new(0.0, -0.5, 3f64.sqrt() / 2.0);
        let pos = m.rotary_positions(&r, &p);
        assert!(pos.within_ranges);
        assert_eq!((pos.first.0, pos.second.0), (RotaryAxis::C, RotaryAxis::A));
        assert!(pos.first.1.abs() < 1e-12 && (pos.second.1 - 30f64.to_radians()).abs() < 1e-12);
        // Tilting the other way: A = −30° (the end of A's range) moves less
        // than C = 180°, A = 30°.
        let other = Vector3::new(0.0, 0.5, 3f64.sqrt() / 2.0);
        let q = m.rotary_positions(&r, &other);
        assert!(q.within_ranges && q.first.1.abs() < 1e-12);
        assert!((q.second.1 + 30f64.to_radians()).abs() < 1e-12);
        assert!((m.key().ftm5(q.first.1, q.second.1) - other).norm() < 1e-12);
        // A tilt beyond both sides of A's range is reported as such.
        let tight: AxisRanges = "10,10,180,180".parse().unwrap();
        assert!(!m.rotary_positions(&tight, &p).within_ranges);
    }

    #[test]
    fn bad_notation_is_named() {
        assert!(matches!(
            "caxyBz".parse::<MachineConfig>(),
            Err(MachineError::Syntax(_))
        ));
        assert!(matches!(
            "W/caxyBq/T".parse::<MachineConfig>(),
            Err(MachineError::BadAxis {
                position: 7,
                found: 'q',
                ..
            })
        ));
        assert!(matches!(
            "W/caxxBz/T".parse::<MachineConfig>(),
            Err(MachineError::Repeated { axis: 'x', .. })
        ));
        assert!(matches!(
            "W/cxyBz/T".parse::<MachineConfig>(),
            Err(MachineError::Axes(_))
        ));
        let err = "W/xyBzac/T".parse::<MachineConfig>().unwrap_err();
        assert!(matches!(err, MachineError::NotFiveAxis { ref key, .. } if key == "Bac"));
    }

    #[test]
    fn ranges_parse_and_refuse() {
        let r: AxisRanges = "30, 20, 180,180".parse().unwrap();
        assert!((r.phi_l - 30f64.to_radians()).abs() < 1e-15);
        assert_eq!(r.degrees()[3], 180.0);
        assert!("30,20,180".parse::<AxisRanges>().is_err());
        assert!(matches!(
            "30,NaN,1,1".parse::<AxisRanges>(),
            Err(RangesError::Value { field: "PHI_S", .. })
        ));
        assert!(matches!(
            "10,20,1,1".parse::<AxisRanges>(),
            Err(RangesError::Order { .. })
        ));
    }
}
