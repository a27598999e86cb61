//! Interpolator configuration: every tolerance and limit is a named field
//! with a documented default. Read once at start; the RT tick never changes it.

use crate::kinematics::{Machine, MachineSpec};

/// How the parameter `u` advances each tick (seed 004, §2.2).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "kebab-case"))]
pub enum ParamUpdate {
    /// First-order Taylor, eq. 10: `Δu = V·Ts / |C'|`.
    FirstOrder,
    /// Second-order Taylor in time with the feed-rate-change (`dV/du`) term
    /// kept, which eq. 11 omits. With the tick's displacement
    /// `Δ = V·Ts + ½·(dV/dt)·Ts²` it reads
    /// `Δu = Δ/|C'| − Δ²·(C'·C'')/(2|C'|⁴)`. (Eq. 11 prints the curvature term
    /// with a plus sign; `d²u/ds² = −(C'·C'')/|C'|⁴`, so it is a minus.)
    SecondOrder,
    /// Newton iteration on the chord length `|C(u_{i+1}) − C(u_i)| = Δ`,
    /// started from the second-order estimate. Feed fluctuation at the
    /// round-off level. The default.
    #[default]
    Corrected,
}

/// Interpolator configuration (mm, s). `Default` gives the documented values.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(default, rename_all = "kebab-case"))]
pub struct InterpConfig {
    /// Interpolation period `Ts`, s. Default 0.001 (1 kHz).
    pub period: f64,
    /// Chord-error law (eq. 16–17) on or off. Default on.
    pub chord_error_law: bool,
    /// Chord tolerance `ER`, mm. Default 0.001 (1 µm).
    pub chord_tolerance: f64,
    /// Constant-MRR law (eq. 23) on or off for blocks that carry MRR parameters. Default on.
    pub mrr_law: bool,
    /// Machine path-speed limit, mm/s. Default 250 (15 m/min).
    pub max_path_speed: f64,
    /// Tangential acceleration limit, mm/s². Default 2000.
    pub max_path_accel: f64,
    /// Tangential jerk limit, mm/s³. Default 100 000.
    pub max_path_jerk: f64,
    /// Centripetal acceleration limit `v²·|k| ≤ this`, mm/s². Default 2000.
    pub max_centripetal_accel: f64,
    /// Per-axis velocity limits X Y Z, mm/s. Default 250 each.
    pub axis_max_velocity: [f64; 3],
    /// Per-axis acceleration limits X Y Z, mm/s². Default 4000 each.
    pub axis_max_accel: [f64; 3],
    /// Per-axis jerk limits X Y Z, mm/s³. Default 200 000 each.
    pub axis_max_jerk: [f64; 3],
    /// Share of each axis's acceleration given to the path's own tangential
    /// motion (the rest goes to curvature and corners), in (0, 1): the path's
    /// tangential acceleration is at most `min(A, share·A_axis)`. Feed hold
    /// brakes with the same share of the axes' jerk. (The schedule holds
    /// each axis's jerk exactly, along the planned profile.) Default 0.5.
    pub axis_tangential_share: f64,
    /// Every limit is planned at `(1 − planning_margin)` of its value, which
    /// absorbs discrete-time effects (chord versus arc, law sampling). Default 0.02.
    pub planning_margin: f64,
    /// A junction (corner or curvature jump) whose limit-respecting speed is
    /// below this is passed with a full stop instead, mm/s. Default 0.5. (The
    /// planner stops below a higher speed where passing would be slower than
    /// the stop: `plan::stop_speed`.)
    pub junction_min_speed: f64,
    /// Largest feed override accepted (1 = 100 %). Default 2.0.
    pub max_feed_override: f64,
    /// Length of the pieces of the planned speed (the look-ahead grid), mm;
    /// made a whole multiple large enough for one tick's travel at the top
    /// speed. Default 0.25.
    pub profile_step: f64,
    /// Samples of the feed laws per profile interval (the interval's limit is
    /// their minimum). Default 8.
    pub law_samples_per_interval: u32,
    /// A NURBS is cut into separate segments at C0 knots whose tangents turn
    /// by more than this, rad. Default 1e-6 (numerically tangent). Every joint
    /// then gets a junction speed (`feed::junction_speed`).
    pub tangent_tolerance: f64,
    /// How `u` advances.
    pub param_update: ParamUpdate,
    /// Newton (corrected update) stops when `|chord − Δ| ≤ newton_rel_tol · Δ`. Default 1e-13.
    pub newton_rel_tol: f64,
    /// Newton iteration cap (then it keeps its best iterate). Default 10;
    /// two or three are typical.
    pub newton_max_iter: u32,
    /// Path tolerance of `G64` given without `P` (`Blending::Within { tolerance:
    /// None }`), mm. Default 0.01.
    pub default_blend_tolerance: f64,
    /// Under `G64 P`, runs of line moves up to this long (and turning by
    /// less than `smooth::FIT_MAX_TURN` between them) are compressed into
    /// NURBS pieces within the tolerance (`smooth::Smoother`); longer moves
    /// stay lines and their corners are blended. mm. Default 3.0.
    pub compress_max_move: f64,
    /// The five-axis machine (`docs/five-axis.md`): needed by blocks under
    /// tool-centre-point control, whose setpoints are its joints from the
    /// inverse transform. Default none (three-axis blocks and plain rotary
    /// axes need none).
    #[cfg_attr(feature = "serde", serde(skip_serializing_if = "Option::is_none"))]
    pub machine: Option<MachineSpec>,
    /// Largest angle between the programmed tool axis and the tool axis the
    /// drives give between two setpoints (the joints are interpolated
    /// linearly between them), rad. Default 0.001.
    pub angular_tolerance: f64,
    /// Velocity limits of the rotary joints A B C, deg/s. Default 180 each.
    /// (The linear joints X Y Z take `axis-max-*`.)
    pub rotary_max_velocity: [f64; 3],
    /// Acceleration limits of the rotary joints A B C, deg/s². Default 1800 each.
    pub rotary_max_accel: [f64; 3],
    /// Jerk limits of the rotary joints A B C, deg/s³. Default 90 000 each.
    pub rotary_max_jerk: [f64; 3],
}

impl Default for InterpConfig {
    fn default() -> Self {
        InterpConfig {
            period: 0.001,
            chord_error_law: true,
            chord_tolerance: 0.001,
            mrr_law: true,
            max_path_speed: 250.0,
            max_path_accel: 2000.0,
            max_path_jerk: 100_000.0,
            max_centripetal_accel: 2000.0,
            axis_max_velocity: [250.0; 3],
            axis_max_accel: [4000.0; 3],
            axis_max_jerk: [200_000.0; 3],
            axis_tangential_share: 0.5,
            planning_margin: 0.02,
            junction_min_speed: 0.5,
            max_feed_override: 2.0,
            profile_step: 0.25,
            law_samples_per_interval: 8,
            tangent_tolerance: 1e-6,
            param_update: ParamUpdate::Corrected,
            newton_rel_tol: 1e-13,
            newton_max_iter: 10,
            default_blend_tolerance: 0.01,
            compress_max_move: 3.0,
            machine: None,
            angular_tolerance: 0.001,
            rotary_max_velocity: [180.0; 3],
            rotary_max_accel: [1800.0; 3],
            rotary_max_jerk: [90_000.0; 3],
        }
    }
}

/// Why a configuration was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ConfigError {
    /// The named field is out of its range (or not finite).
    OutOfRange(&'static str),
}

impl core::fmt::Display for ConfigError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            ConfigError::OutOfRange(field) => write!(f, "config field `{field}` out of range"),
        }
    }
}

impl InterpConfig {
    /// Check every field.
    /// Tangential acceleration the schedule plans with, mm/s²: the path limit,
    /// the axes' tangential share, and the planning margin.
    pub fn planned_accel(&self) -> f64 {
        let axis = self
            .axis_max_accel
            .iter()
            .fold(f64::INFINITY, |m, &a| m.min(a));
        self.max_path_accel.min(self.axis_tangential_share * axis) * (1.0 - self.planning_margin)
    }

    /// Tangential jerk the schedule plans with, mm/s³ (as [`Self::planned_accel`]).
    pub fn planned_jerk(&self) -> f64 {
        let axis = self
            .axis_max_jerk
            .iter()
            .fold(f64::INFINITY, |m, &a| m.min(a));
        self.max_path_jerk.min(self.axis_tangential_share * axis) * (1.0 - self.planning_margin)
    }

    /// The velocity, acceleration and jerk limits of joint `j` of
    /// `[X, Y, Z, A, B, C]` (mm or degrees, per s, s², s³).
    pub fn joint_limits(&self, j: usize) -> (f64, f64, f64) {
        if j < 3 {
            (
                self.axis_max_velocity[j],
                self.axis_max_accel[j],
                self.axis_max_jerk[j],
            )
        } else {
            (
                self.rotary_max_velocity[j - 3],
                self.rotary_max_accel[j - 3],
                self.rotary_max_jerk[j - 3],
            )
        }
    }

    /// Checks every field; the error names the first one out of range.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let pos = |v: f64| v.is_finite() && v > 0.0;
        if !pos(self.period) || self.period > 1.0 {
            return Err(ConfigError::OutOfRange("period"));
        }
        if !pos(self.chord_tolerance) {
            return Err(ConfigError::OutOfRange("chord-tolerance"));
        }
        if !pos(self.max_path_speed) {
            return Err(ConfigError::OutOfRange("max-path-speed"));
        }
        if !pos(self.max_path_accel) {
            return Err(ConfigError::OutOfRange("max-path-accel"));
        }
        if !pos(self.max_path_jerk) {
            return Err(ConfigError::OutOfRange("max-path-jerk"));
        }
        if !pos(self.max_centripetal_accel) {
            return Err(ConfigError::OutOfRange("max-centripetal-accel"));
        }
        if !self.axis_max_velocity.iter().all(|&v| pos(v)) {
            return Err(ConfigError::OutOfRange("axis-max-velocity"));
        }
        if !self.axis_max_accel.iter().all(|&v| pos(v)) {
            return Err(ConfigError::OutOfRange("axis-max-accel"));
        }
        if !self.axis_max_jerk.iter().all(|&v| pos(v)) {
            return Err(ConfigError::OutOfRange("axis-max-jerk"));
        }
        if !(self.axis_tangential_share > 0.0 && self.axis_tangential_share < 1.0) {
            return Err(ConfigError::OutOfRange("axis-tangential-share"));
        }
        if !(self.planning_margin >= 0.0 && self.planning_margin < 0.5) {
            return Err(ConfigError::OutOfRange("planning-margin"));
        }
        if !(self.junction_min_speed >= 0.0 && self.junction_min_speed.is_finite()) {
            return Err(ConfigError::OutOfRange("junction-min-speed"));
        }
        if !(self.max_feed_override >= 1.0 && self.max_feed_override <= 10.0) {
            return Err(ConfigError::OutOfRange("max-feed-override"));
        }

        if !pos(self.profile_step) {
            return Err(ConfigError::OutOfRange("profile-step"));
        }
        if self.law_samples_per_interval == 0 || self.law_samples_per_interval > 64 {
            return Err(ConfigError::OutOfRange("law-samples-per-interval"));
        }
        if !(self.tangent_tolerance >= 0.0 && self.tangent_tolerance < 1.0) {
            return Err(ConfigError::OutOfRange("tangent-tolerance"));
        }
        if !pos(self.newton_rel_tol) {
            return Err(ConfigError::OutOfRange("newton-rel-tol"));
        }
        if self.newton_max_iter == 0 || self.newton_max_iter > 50 {
            return Err(ConfigError::OutOfRange("newton-max-iter"));
        }
        if !pos(self.default_blend_tolerance) {
            return Err(ConfigError::OutOfRange("default-blend-tolerance"));
        }
        if !(self.compress_max_move >= 0.0 && self.compress_max_move.is_finite()) {
            return Err(ConfigError::OutOfRange("compress-max-move"));
        }
        if let Some(spec) = self.machine
            && Machine::new(spec).is_err()
        {
            return Err(ConfigError::OutOfRange("machine"));
        }
        if !(pos(self.angular_tolerance) && self.angular_tolerance < 0.5) {
            return Err(ConfigError::OutOfRange("angular-tolerance"));
        }
        if !self.rotary_max_velocity.iter().all(|&v| pos(v)) {
            return Err(ConfigError::OutOfRange("rotary-max-velocity"));
        }
        if !self.rotary_max_accel.iter().all(|&v| pos(v)) {
            return Err(ConfigError::OutOfRange("rotary-max-accel"));
        }
        if !self.rotary_max_jerk.iter().all(|&v| pos(v)) {
            return Err(ConfigError::OutOfRange("rotary-max-jerk"));
        }
        Ok(())
    }
}
