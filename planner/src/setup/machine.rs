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
//!
//! The notation, the keys and their classification live in
//! `interp_core::kinematics` (the interpolator's machine model reads the same
//! chains); this module keeps the notation as given and the paper's ranges.

use std::str::FromStr;

pub use interp_core::kinematics::{Chain, ChainError, MachineType, RotaryAxis, RotaryKey};

/// Why a machine description was refused: the notation as given and the reason.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("machine `{notation}`: {reason}")]
pub struct MachineError {
    /// The notation as given.
    pub notation: String,
    /// What is wrong with it.
    pub reason: ChainError,
}

/// A five-axis machine configuration parsed from `W/…/T`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MachineConfig {
    notation: String,
    chain: Chain,
}

impl MachineConfig {
    /// The notation as given.
    pub fn notation(&self) -> &str {
        &self.notation
    }

    /// The parsed chain.
    pub fn chain(&self) -> &Chain {
        &self.chain
    }

    /// The reduced rotary key, e.g. `caB`.
    pub fn key(&self) -> RotaryKey {
        self.chain.key()
    }

    /// C,A or A,B.
    pub fn machine_type(&self) -> MachineType {
        self.chain.machine_type()
    }

    /// The machine axes that play the roles of the paper's rotary axes: for a
    /// C,A type `(C, tilt axis)`, for an A,B type `(R1, R2)` (§3.3 table).
    pub fn roles(&self) -> (RotaryAxis, RotaryAxis) {
        self.chain.roles()
    }
}

impl FromStr for MachineConfig {
    type Err = MachineError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let notation = s.trim().to_string();
        match notation.parse::<Chain>() {
            Ok(chain) => Ok(MachineConfig { notation, chain }),
            Err(reason) => Err(MachineError { notation, reason }),
        }
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
        let reason = |n: &str| n.parse::<MachineConfig>().unwrap_err().reason;
        assert_eq!(reason("caxyBz"), ChainError::Syntax);
        assert_eq!(
            reason("W/caxyBq/T"),
            ChainError::BadAxis {
                position: 7,
                found: 'q'
            }
        );
        assert_eq!(reason("W/caxxBz/T"), ChainError::Repeated { axis: 'x' });
        assert_eq!(reason("W/cxyBz/T"), ChainError::Axes);
        let err = " W/xyBzac/T".parse::<MachineConfig>().unwrap_err();
        assert!(matches!(err.reason, ChainError::NotFiveAxis { key } if key.to_string() == "Bac"));
        let msg = err.to_string();
        assert!(
            msg.starts_with("machine `W/xyBzac/T`: rotary order `Bac`")
                && msg.ends_with("not a 5-axis machine"),
            "{msg}"
        );
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
