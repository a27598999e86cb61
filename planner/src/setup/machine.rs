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
use interp_core::kinematics::{InverseError, Machine, MachineSpec, RotaryRange, ToolPose};
use nalgebra::Vector3;

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

    /// The rotary axis positions at which the tool axis, seen from the part
    /// as it lies with the axes at zero, is `tool_axis` (part coordinates):
    /// with the axes there, a 3-axis program machines what that direction
    /// reaches (3+2). The kinematics' inverse ([`Machine::inverse`]) nearest
    /// home within `ranges` (C,A: C in `[−Θˢ, Θᴸ]`, tilt in `[−Φˢ, Φᴸ]`;
    /// A,B: R1 in `[−Φˢ, Φᴸ]`, R2 in `[−Θˢ, Θᴸ]`), else the one nearest home
    /// with no ranges, flagged. On the first rotary axis (the pole) the
    /// first joint stays at 0. A zero or non-finite `tool_axis` gives home.
    pub fn rotary_positions(
        &self,
        ranges: &AxisRanges,
        tool_axis: &Vector3<f64>,
    ) -> RotaryPositions {
        let (first, second) = self.roles();
        let span = |low: f64, high: f64| RotaryRange {
            min: -low.to_degrees(),
            max: high.to_degrees(),
        };
        let (r1, r2) = match self.machine_type() {
            MachineType::CA => (
                span(ranges.theta_s, ranges.theta_l),
                span(ranges.phi_s, ranges.phi_l),
            ),
            MachineType::AB => (
                span(ranges.phi_s, ranges.phi_l),
                span(ranges.theta_s, ranges.theta_l),
            ),
        };
        // The tool axis depends on the rotary key alone; the same key with
        // the linear axes after both rotaries (`W/caBxyz/T` for `caB`) has
        // no rotary position where two linear axes line up, so the inverse
        // never fails on the tip, which 3+2 does not use.
        let chain: Chain = format!("W/{}xyz/T", self.key())
            .parse()
            .expect("a five-axis key with the linear axes last is a chain");
        let solve = |limits: Option<(RotaryRange, RotaryRange)>| {
            let mut spec = MachineSpec::new(chain);
            if let Some((a, b)) = limits {
                spec.rotary_ranges[first.index()] = a;
                spec.rotary_ranges[second.index()] = b;
            }
            let machine = Machine::new(spec).ok()?;
            let pose = ToolPose {
                tip: Vector3::zeros(),
                axis: *tool_axis,
            };
            match machine.inverse(&pose, &[0.0; 6]) {
                Ok(s) => Some(s.joints),
                Err(InverseError::OutOfRange { .. }) => None,
                Err(_) => Some([0.0; 6]),
            }
        };
        let (joints, within_ranges) = match solve(Some((r1, r2))) {
            Some(j) => (j, true),
            None => (solve(None).unwrap_or([0.0; 6]), false),
        };
        RotaryPositions {
            first: (first, joints[first.joint()].to_radians()),
            second: (second, joints[second.joint()].to_radians()),
            within_ranges,
        }
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
    /// Whether both angles lie within the machine's ranges; if no solution
    /// does, the one nearest home.
    pub within_ranges: bool,
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
    fn rotary_positions_turn_the_tool_axis_onto_the_setup_axis() {
        // Every 5-axis key, directions all over the sphere (poles included):
        // the positions turn the tool axis to the direction (eq. 2), within
        // generous ranges.
        let dirs: Vec<Vector3<f64>> = (0..40)
            .map(|k| {
                let (t, a) = (0.37 * k as f64, 1.3 * k as f64);
                Vector3::new(t.sin() * a.cos(), t.sin() * a.sin(), t.cos())
            })
            .chain([Vector3::z(), -Vector3::z(), Vector3::x(), -Vector3::y()])
            .collect();
        let wide: AxisRanges = "180,180,180,180".parse().unwrap();
        for key in RotaryKey::all()
            .into_iter()
            .filter(|k| k.machine_type().is_some())
        {
            let chain = format!("W/{key}xyz/T");
            let m: MachineConfig = chain.parse().unwrap();
            for p in &dirs {
                let pos = m.rotary_positions(&wide, p);
                assert!(pos.within_ranges, "{key} {p:?}");
                assert_eq!((pos.first.0, pos.second.0), m.roles());
                let reached = key.ftm5(pos.first.1, pos.second.1);
                assert!((reached - p).norm() < 1e-9, "{key} {p:?}: {reached:?}");
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
        // Tilting the other way: A = −30° (the end of A's range), nearer
        // home than C = 180°, A = 30°.
        let other = Vector3::new(0.0, 0.5, 3f64.sqrt() / 2.0);
        let q = m.rotary_positions(&r, &other);
        assert!(q.within_ranges && q.first.1.abs() < 1e-12);
        assert!((q.second.1 + 30f64.to_radians()).abs() < 1e-12);
        // With A's negative side closed, C turns half a turn instead.
        let one_sided: AxisRanges = "110,0,180,180".parse().unwrap();
        let h = m.rotary_positions(&one_sided, &other);
        assert!(h.within_ranges && (h.first.1.abs() - 180f64.to_radians()).abs() < 1e-9);
        assert!((h.second.1 - 30f64.to_radians()).abs() < 1e-9);
        // A tilt beyond both sides of A's range is reported as such, with
        // the positions nearest home that reach it.
        let tight: AxisRanges = "10,10,180,180".parse().unwrap();
        let out = m.rotary_positions(&tight, &p);
        assert!(!out.within_ranges);
        assert!((m.key().ftm5(out.first.1, out.second.1) - p).norm() < 1e-9);
        // An A,B machine (R1 = B, R2 = A): R1 takes the Φ ranges. A tool
        // axis needing B = 25° is out of reach when Φ allows 20° only.
        let ab: MachineConfig = "W/baxzBy/T".parse().unwrap();
        let v = ab.key().ftm5(25f64.to_radians(), 5f64.to_radians());
        let fits = ab.rotary_positions(&"30,30,20,20".parse().unwrap(), &v);
        assert!(fits.within_ranges);
        assert!((fits.first.1 - 25f64.to_radians()).abs() < 1e-9);
        assert!(
            !ab.rotary_positions(&"20,20,30,30".parse().unwrap(), &v)
                .within_ranges
        );
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
