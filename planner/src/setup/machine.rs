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
