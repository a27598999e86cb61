//! The setpoint checker: every setpoint against the ones before it, by
//! finite differences as a drive sees its position commands (speed, chord
//! speed, acceleration, path jerk, per-joint velocity, acceleration and jerk
//! of X Y Z and of the rotary joints A B C, gapless `seq`, finite values, no
//! fault), the end of the run (`done`, exactly at the program's end), with a
//! digest of every field's bits. For a five-axis machine
//! ([`Checker::five_axis`]) the path of a block under tool-centre-point
//! control is the tool tip in the workpiece frame (the forward transform of
//! the joints), which the speed and chord checks measure.
//! `interpd demo` runs it on its direct loop and on the setpoints the
//! service publishes, `interpd jitter`'s subscriber on every published tick,
//! and the workspace tests on their runs; `docs/daemon.md` gives the checks
//! and their slack.

use interp_core::kinematics::{Joints, Machine};
use interp_core::{InterpConfig, RunState, Setpoint, Vec3};
use serde::{Deserialize, Serialize};

/// Absolute slack on the speed check, mm/s (plus the round-off of the arc
/// length the feed is a difference of: [`CHORD_ULPS`] of it per tick).
pub const SPEED_TOL: f64 = 1e-9;
/// The chord between two setpoints (the motion actually commanded) may exceed
/// the feed limit by this fraction: the corrected parameter update resolves the
/// chord only to the round-off of the coordinates and of `u` (about 1e-10 of a
/// 10 µs step), and the check is after jumps and wrong roots, not fluctuation.
pub const CHORD_REL_TOL: f64 = 1e-6;
/// ... plus this many ulps of the largest coordinate per tick, for tiny steps.
pub const CHORD_ULPS: f64 = 16.0;
/// Relative slack on the acceleration check.
pub const ACCEL_REL_TOL: f64 = 1e-6;
/// Relative slack on the jerk and per-axis checks: the one the core's own
/// tests use (`interp-core/tests/common`, `LIMIT_REL_TOL`).
pub const LIMIT_REL_TOL: f64 = 1e-6;
/// Round-off allowance of an n-th finite difference of coordinates of size
/// `scale`, in ulps of `scale` (|1| + |3| + |3| + |1| = 8 for the third
/// difference, times a margin of 2).
pub const DIFF_ULPS: f64 = 16.0;

/// Checks that failed, by kind.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Violations {
    /// Setpoints whose `seq` is not the previous one plus one (the first must be 1).
    pub seq_gaps: u64,
    /// Setpoints with a NaN or infinite time, axis, feed, `u` or `s`.
    pub non_finite: u64,
    /// Ticks whose commanded feed exceeds the feed limit (+1e-9 mm/s).
    pub over_speed: u64,
    /// Ticks whose chord speed |Δp|/Ts exceeds the feed limit (+1 ppm, +1e-9 mm/s
    /// and 16 ulps of the coordinates per tick).
    pub over_chord_speed: u64,
    /// Ticks whose |Δfeed|/Ts exceeds the acceleration limit.
    pub over_accel: u64,
    /// Ticks whose path jerk |Δ³s|/Ts³ exceeds `max_path_jerk` (+1 ppm).
    pub over_jerk: u64,
    /// Ticks where some joint's |Δq|/Ts exceeds its limit (+1 ppm):
    /// `axis_max_velocity` for X Y Z, `rotary_max_velocity` for A B C.
    pub over_axis_velocity: u64,
    /// Ticks where some joint's |Δ²q|/Ts² exceeds its limit (+1 ppm):
    /// `axis_max_accel`, `rotary_max_accel`.
    pub over_axis_accel: u64,
    /// Ticks where some joint's |Δ³q|/Ts³ exceeds its limit (+1 ppm):
    /// `axis_max_jerk`, `rotary_max_jerk`.
    pub over_axis_jerk: u64,
    /// Setpoints in the `Fault` state.
    pub faults: u64,
    /// 1 when the run ended without reaching `Done`.
    pub not_done: u64,
    /// 1 when the last point is not exactly the curve's end.
    pub end_mismatch: u64,
    /// `seq` of the first setpoint that failed a check.
    pub first_seq: Option<u64>,
}

impl Violations {
    /// All failed checks.
    pub fn total(&self) -> u64 {
        self.seq_gaps
            + self.non_finite
            + self.over_speed
            + self.over_chord_speed
            + self.over_accel
            + self.over_jerk
            + self.over_axis_velocity
            + self.over_axis_accel
            + self.over_axis_jerk
            + self.faults
            + self.not_done
            + self.end_mismatch
    }

    /// Every count by name, for a message.
    pub fn breakdown(&self) -> String {
        format!(
            "seq gaps {}, non-finite {}, over speed {}, over chord speed {}, over accel {}, \
             over jerk {}, over axis velocity {}, over axis accel {}, over axis jerk {}, \
             faults {}, not done {}, end mismatch {}",
            self.seq_gaps,
            self.non_finite,
            self.over_speed,
            self.over_chord_speed,
            self.over_accel,
            self.over_jerk,
            self.over_axis_velocity,
            self.over_axis_accel,
            self.over_axis_jerk,
            self.faults,
            self.not_done,
            self.end_mismatch
        )
    }
}

/// The limits every setpoint is checked against, from the run's configuration.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Limits {
    /// Path speed: the programmed feed capped at `max_path_speed`, mm/s.
    pub feed_mm_s: f64,
    /// Tangential acceleration `max_path_accel`, mm/s².
    pub accel_mm_s2: f64,
    /// Path jerk `max_path_jerk`, mm/s³.
    pub jerk_mm_s3: f64,
    /// `axis_max_velocity` X Y Z, mm/s.
    pub axis_velocity_mm_s: [f64; 3],
    /// `axis_max_accel` X Y Z, mm/s².
    pub axis_accel_mm_s2: [f64; 3],
    /// `axis_max_jerk` X Y Z, mm/s³.
    pub axis_jerk_mm_s3: [f64; 3],
    /// `rotary_max_velocity` A B C, deg/s.
    pub rotary_velocity_deg_s: [f64; 3],
    /// `rotary_max_accel` A B C, deg/s².
    pub rotary_accel_deg_s2: [f64; 3],
    /// `rotary_max_jerk` A B C, deg/s³.
    pub rotary_jerk_deg_s3: [f64; 3],
}

impl Limits {
    /// The limits of `cfg` for a program at `feed_mm_s`.
    pub fn new(cfg: &InterpConfig, feed_mm_s: f64) -> Self {
        Limits {
            feed_mm_s: feed_mm_s.min(cfg.max_path_speed),
            accel_mm_s2: cfg.max_path_accel,
            jerk_mm_s3: cfg.max_path_jerk,
            axis_velocity_mm_s: cfg.axis_max_velocity,
            axis_accel_mm_s2: cfg.axis_max_accel,
            axis_jerk_mm_s3: cfg.axis_max_jerk,
            rotary_velocity_deg_s: cfg.rotary_max_velocity,
            rotary_accel_deg_s2: cfg.rotary_max_accel,
            rotary_jerk_deg_s3: cfg.rotary_max_jerk,
        }
    }

    /// Velocity, acceleration and jerk limits of joint `j` (X Y Z A B C).
    fn joint(&self, j: usize) -> (f64, f64, f64) {
        if j < 3 {
            (
                self.axis_velocity_mm_s[j],
                self.axis_accel_mm_s2[j],
                self.axis_jerk_mm_s3[j],
            )
        } else {
            (
                self.rotary_velocity_deg_s[j - 3],
                self.rotary_accel_deg_s2[j - 3],
                self.rotary_jerk_deg_s3[j - 3],
            )
        }
    }
}

/// Largest values measured by finite differences of the setpoints, as a drive sees them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Measured {
    /// Largest |Δ³s|/Ts³, mm/s³.
    pub path_jerk_mm_s3: f64,
    /// Largest |Δp|/Ts per axis X Y Z, mm/s.
    pub axis_velocity_mm_s: [f64; 3],
    /// Largest |Δ²p|/Ts² per axis, mm/s².
    pub axis_accel_mm_s2: [f64; 3],
    /// Largest |Δ³p|/Ts³ per axis, mm/s³.
    pub axis_jerk_mm_s3: [f64; 3],
    /// Largest |Δq|/Ts per rotary joint A B C, deg/s.
    pub rotary_velocity_deg_s: [f64; 3],
    /// Largest |Δ²q|/Ts² per rotary joint, deg/s².
    pub rotary_accel_deg_s2: [f64; 3],
    /// Largest |Δ³q|/Ts³ per rotary joint, deg/s³.
    pub rotary_jerk_deg_s3: [f64; 3],
}

/// Checks each setpoint against the previous ones and keeps the running
/// maxima and digest: the demo loop's own subscriber, the demo's iceoryx2
/// subscriber of the service run, and the end-to-end tests. Fixed size;
/// `check` never allocates.
///
/// Before the first setpoint the machine is at rest at `start` (arc length 0),
/// so the differences of the first ticks see the start as it was.
#[derive(Clone, Debug)]
pub struct Checker {
    ts: f64,
    limits: Limits,
    /// The five-axis machine: the path under tool-centre-point control is
    /// the tool tip of the joints.
    machine: Option<Machine>,
    prev_seq: u64,
    prev_feed: f64,
    /// The last three setpoints' joints, newest first.
    prev_joints: [Joints; 3],
    /// The path point of the last setpoint checked (the run's end).
    last_point: [f64; 3],
    /// The last three arc lengths, newest first.
    prev_s: [f64; 3],
    /// Largest commanded feed, mm/s.
    pub max_feed: f64,
    /// Largest chord between consecutive setpoints over Ts, mm/s.
    pub max_chord_speed: f64,
    /// Largest |Δfeed|/Ts, mm/s².
    pub max_accel: f64,
    /// Path jerk and per-axis maxima.
    pub measured: Measured,
    /// FNV-1a of every field of every setpoint checked ([`digest_setpoint`]).
    pub digest: u64,
    /// The checks that failed.
    pub violations: Violations,
    /// The last setpoint checked.
    last: Setpoint,
}

/// `v ≤ limit` within the relative tolerance and `slack` of round-off.
fn within(v: f64, limit: f64, slack: f64) -> bool {
    v <= limit * (1.0 + LIMIT_REL_TOL) + slack
}

/// FNV-1a, 64 bit.
pub const FNV_OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
const FNV_PRIME: u64 = 0x0000_0100_0000_01b3;

fn fnv1a(mut h: u64, bytes: &[u8]) -> u64 {
    for &b in bytes {
        h = (h ^ u64::from(b)).wrapping_mul(FNV_PRIME);
    }
    h
}

/// Folds every field of `sp` (floats by their bits) into `h` (from [`FNV_OFFSET`]).
pub fn digest_setpoint(mut h: u64, sp: &Setpoint) -> u64 {
    h = fnv1a(h, &sp.seq.to_le_bytes());
    h = fnv1a(h, &sp.time.to_bits().to_le_bytes());
    for a in sp.axes {
        h = fnv1a(h, &a.to_bits().to_le_bytes());
    }
    for v in [sp.feed, sp.u, sp.s] {
        h = fnv1a(h, &v.to_bits().to_le_bytes());
    }
    h = fnv1a(h, &sp.block_id.to_le_bytes());
    fnv1a(h, &[sp.state as u8])
}

impl Checker {
    /// A checker for a period of `ts` s, with the machine at rest at `start`
    /// (X Y Z, the rotary joints at 0) before the first setpoint.
    pub fn new(ts: f64, limits: Limits, start: [f64; 3]) -> Self {
        Self::at_joints(
            ts,
            limits,
            None,
            [start[0], start[1], start[2], 0.0, 0.0, 0.0],
        )
    }

    /// A checker for a five-axis `machine` at rest at the joints `start`
    /// before the first setpoint: blocks under tool-centre-point control
    /// are checked with [`Checker::check_in_frame`].
    pub fn five_axis(ts: f64, limits: Limits, machine: Machine, start: Joints) -> Self {
        Self::at_joints(ts, limits, Some(machine), start)
    }

    fn at_joints(ts: f64, limits: Limits, machine: Option<Machine>, start: Joints) -> Self {
        Checker {
            ts,
            limits,
            machine,
            prev_seq: 0,
            prev_feed: 0.0, // the machine starts at rest
            prev_joints: [start; 3],
            last_point: [start[0], start[1], start[2]],
            prev_s: [0.0; 3],
            max_feed: 0.0,
            max_chord_speed: 0.0,
            max_accel: 0.0,
            measured: Measured::default(),
            digest: FNV_OFFSET,
            violations: Violations::default(),
            last: Setpoint {
                axes: start,
                ..Setpoint::default()
            },
        }
    }

    /// The point on the path of joints `q`: the tool tip in the workpiece
    /// frame under tool-centre-point control (`tcp`, with a machine), else
    /// X Y Z.
    fn path_point(&self, q: &Joints, tcp: bool) -> [f64; 3] {
        match (&self.machine, tcp) {
            (Some(m), true) => {
                let p = m.forward(q).tip;
                [p.x, p.y, p.z]
            }
            _ => [q[0], q[1], q[2]],
        }
    }

    /// Checks the next setpoint, its path X Y Z of the machine (allocates nothing).
    #[inline]
    pub fn check(&mut self, sp: &Setpoint) {
        self.check_in_frame(sp, false);
    }

    /// Checks the next setpoint on a block under tool-centre-point control
    /// (`tcp`: its path is the tool tip, with [`Checker::five_axis`]'s
    /// machine) or not; the previous setpoints are seen in the same frame
    /// (allocates nothing).
    #[inline]
    pub fn check_in_frame(&mut self, sp: &Setpoint, tcp: bool) {
        let ts = self.ts;
        let lim = self.limits;
        let [q1, q2, q3] = self.prev_joints;
        let q = sp.axes;
        let p = self.path_point(&q, tcp);
        let p1 = self.path_point(&q1, tcp);
        let v = &mut self.violations;
        let mut bad = false;
        if sp.seq != self.prev_seq.wrapping_add(1) {
            v.seq_gaps += 1;
            bad = true;
        }
        let finite = [sp.time, sp.feed, sp.u, sp.s]
            .iter()
            .chain(&sp.axes)
            .all(|x| x.is_finite());
        if !finite {
            v.non_finite += 1;
            bad = true;
        }
        let chord = Vec3::from(p) - Vec3::from(p1);
        let chord_speed = chord.norm() / ts;
        // (`feed` is the tick's difference of the arc length `s`: its
        // round-off grows with `s`, 0.9e-9 mm/s a tick 4 m into a run.)
        let limit = lim.feed_mm_s + SPEED_TOL + CHORD_ULPS * f64::EPSILON * sp.s.abs() / ts;
        if !(sp.feed <= limit) {
            v.over_speed += 1;
            bad = true;
        }
        // Round-off of the linear and of the rotary joints' differences.
        let scale = |range: core::ops::Range<usize>| {
            [&q, &q1, &q2, &q3]
                .iter()
                .flat_map(|x| x[range.clone()].iter())
                .chain(p.iter().chain(p1.iter()))
                .fold(0.0f64, |m, c| m.max(c.abs()))
        };
        let ulp = f64::EPSILON * scale(0..3);
        let ulp_rotary = f64::EPSILON * scale(3..6);
        let round_off = CHORD_ULPS * ulp / ts;
        if !(chord_speed <= limit + lim.feed_mm_s * CHORD_REL_TOL + round_off) {
            v.over_chord_speed += 1;
            bad = true;
        }
        let accel = (sp.feed - self.prev_feed).abs() / ts;
        if !(accel <= lim.accel_mm_s2 * (1.0 + ACCEL_REL_TOL)) {
            v.over_accel += 1;
            bad = true;
        }
        // Path jerk: third difference of the arc length.
        let [s1, s2, s3] = self.prev_s;
        let ts3 = ts * ts * ts;
        let jerk = ((sp.s - 3.0 * s1) + (3.0 * s2 - s3)).abs() / ts3;
        let s_ulp = f64::EPSILON
            * [sp.s, s1, s2, s3]
                .iter()
                .fold(0.0f64, |m, x| m.max(x.abs()));
        if !within(jerk, lim.jerk_mm_s3, DIFF_ULPS * s_ulp / ts3) {
            v.over_jerk += 1;
            bad = true;
        }
        // Per joint, as a drive sees its own position commands.
        let (mut over_v, mut over_a, mut over_j) = (false, false, false);
        let m = &mut self.measured;
        m.path_jerk_mm_s3 = m.path_jerk_mm_s3.max(jerk);
        for k in 0..6 {
            let vel = (q[k] - q1[k]).abs() / ts;
            let acc = ((q[k] - 2.0 * q1[k]) + q2[k]).abs() / (ts * ts);
            let jrk = ((q[k] - 3.0 * q1[k]) + (3.0 * q2[k] - q3[k])).abs() / ts3;
            let (vl, al, jl) = lim.joint(k);
            let u = if k < 3 { ulp } else { ulp_rotary };
            over_v |= !within(vel, vl, DIFF_ULPS * u / ts);
            over_a |= !within(acc, al, DIFF_ULPS * u / (ts * ts));
            over_j |= !within(jrk, jl, DIFF_ULPS * u / ts3);
            let (mv, ma, mj) = if k < 3 {
                (
                    &mut m.axis_velocity_mm_s[k],
                    &mut m.axis_accel_mm_s2[k],
                    &mut m.axis_jerk_mm_s3[k],
                )
            } else {
                (
                    &mut m.rotary_velocity_deg_s[k - 3],
                    &mut m.rotary_accel_deg_s2[k - 3],
                    &mut m.rotary_jerk_deg_s3[k - 3],
                )
            };
            *mv = mv.max(vel);
            *ma = ma.max(acc);
            *mj = mj.max(jrk);
        }
        v.over_axis_velocity += u64::from(over_v);
        v.over_axis_accel += u64::from(over_a);
        v.over_axis_jerk += u64::from(over_j);
        bad |= over_v || over_a || over_j;
        if sp.state == RunState::Fault {
            v.faults += 1;
            bad = true;
        }
        if bad && v.first_seq.is_none() {
            v.first_seq = Some(sp.seq);
        }
        self.max_feed = self.max_feed.max(sp.feed);
        self.max_chord_speed = self.max_chord_speed.max(chord_speed);
        self.max_accel = self.max_accel.max(accel);
        self.digest = digest_setpoint(self.digest, sp);
        self.prev_seq = sp.seq;
        self.prev_feed = sp.feed;
        self.prev_joints = [q, q1, q2];
        self.last_point = p;
        self.prev_s = [sp.s, s1, s2];
        self.last = *sp;
    }

    /// The end of the run: the last setpoint must be `done` and, when
    /// `end` is given, exactly there (its path point: X Y Z, or the tool
    /// tip under tool-centre-point control). Returns the violations.
    pub fn finish(&mut self, end: Option<[f64; 3]>) -> Violations {
        let last = self.last;
        let last_point = self.last_point;
        let v = &mut self.violations;
        if last.state != RunState::Done {
            v.not_done = 1;
        }
        if end.is_some_and(|e| last_point != e) {
            v.end_mismatch = 1;
        }
        if v.total() > 0 && v.first_seq.is_none() {
            v.first_seq = Some(last.seq);
        }
        *v
    }

    /// The last setpoint checked.
    pub fn last(&self) -> &Setpoint {
        &self.last
    }

    /// Panics naming the checks that failed and the first `seq` (for tests).
    #[track_caller]
    pub fn assert_clean(&self, what: &str) {
        let v = &self.violations;
        assert!(
            v.total() == 0,
            "{what}: {} check(s) failed ({}), first at seq {:?}; measured {:?}",
            v.total(),
            v.breakdown(),
            v.first_seq,
            self.measured
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The default limits at a feed limit of `feed` mm/s.
    fn limits(feed: f64) -> Limits {
        Limits::new(&InterpConfig::default(), feed)
    }

    /// A start from rest along `dir` (a unit axis): the acceleration ramps
    /// up at `jerk` for `ramp` ticks, then stays for `hold` ticks. Setpoints
    /// as the interpolator writes them (`feed` = Δs/Ts).
    fn ramp(ts: f64, jerk: f64, ramp: u32, hold: u32, dir: [f64; 3]) -> Vec<Setpoint> {
        let (mut a, mut v, mut s) = (0.0, 0.0, 0.0);
        (1..=ramp + hold)
            .map(|k| {
                if k <= ramp {
                    a += jerk * ts;
                }
                v += a * ts;
                s += v * ts;
                Setpoint {
                    seq: u64::from(k),
                    time: f64::from(k) * ts,
                    axes: [s * dir[0], s * dir[1], s * dir[2], 0.0, 0.0, 0.0],
                    feed: v,
                    s,
                    state: RunState::Running,
                    ..Setpoint::default()
                }
            })
            .collect()
    }

    fn check_all(lim: Limits, sps: &[Setpoint]) -> Checker {
        let mut sub = Checker::new(1e-3, lim, [0.0; 3]);
        for sp in sps {
            sub.check(sp);
        }
        sub
    }

    #[test]
    fn a_smooth_start_passes_and_its_jerk_is_measured() {
        let lim = limits(100.0);
        // 50 000 mm/s³ for 20 ticks (accel 1000 mm/s²), then constant accel.
        let sps = ramp(1e-3, 50_000.0, 20, 30, [1.0, 0.0, 0.0]);
        let sub = check_all(lim, &sps);
        assert_eq!(sub.violations, Violations::default());
        let m = sub.measured;
        assert!((m.path_jerk_mm_s3 / 50_000.0 - 1.0).abs() < 1e-6, "{m:?}");
        assert!(
            (m.axis_jerk_mm_s3[0] / 50_000.0 - 1.0).abs() < 1e-6,
            "{m:?}"
        );
        assert_eq!((m.axis_jerk_mm_s3[1], m.axis_velocity_mm_s[2]), (0.0, 0.0));
        assert!((m.axis_accel_mm_s2[0] / 1000.0 - 1.0).abs() < 1e-6, "{m:?}");
    }

    #[test]
    fn subscriber_flags_an_injected_jerk_spike() {
        let lim = limits(100.0);
        let mut sps = ramp(1e-3, 50_000.0, 20, 30, [1.0, 0.0, 0.0]);
        // 0.15 µm off the path at one tick: third differences δ, −3δ, 3δ, −δ over
        // Ts³, i.e. 1.5e5, 4.5e5, 4.5e5, 1.5e5 mm/s³ on s and on X, while
        // velocity and acceleration stay within their limits.
        let delta = 1.5e-4;
        let n = 40;
        sps[n - 1].s += delta;
        sps[n - 1].axes[0] += delta;
        let v = check_all(lim, &sps).violations;
        assert_eq!(v.over_jerk, 4, "{v:?}"); // path limit 1e5
        assert_eq!(v.over_axis_jerk, 2, "{v:?}"); // axis limit 2e5
        assert_eq!(v.first_seq, Some(n as u64));
        assert_eq!(v.total(), 6, "{v:?}");
        // The same spike on the arc length alone is a path-jerk failure only.
        let mut sps = ramp(1e-3, 50_000.0, 20, 30, [1.0, 0.0, 0.0]);
        sps[n - 1].s += delta;
        let v = check_all(lim, &sps).violations;
        assert_eq!((v.over_jerk, v.total()), (4, 4), "{v:?}");
    }

    #[test]
    fn the_jerk_limit_holds_to_one_ppm() {
        let lim = limits(100.0);
        // 15 ticks at the jerk limit reach 1500 mm/s² (< 2000).
        let at = |j: f64| check_all(lim, &ramp(1e-3, j, 15, 5, [0.0, 1.0, 0.0])).violations;
        assert_eq!(at(lim.jerk_mm_s3 * (1.0 - 1e-7)).total(), 0);
        let v = at(lim.jerk_mm_s3 * (1.0 + 1e-5));
        assert_eq!((v.over_jerk, v.first_seq), (15, Some(1)), "{v:?}");
        assert_eq!(v.total(), 15, "{v:?}");
    }

    #[test]
    fn axis_limits_apply_per_axis() {
        // 50 ticks reach 40.5 mm/s; X may do 30 mm/s, Y and Z 1000.
        let lim = Limits {
            axis_velocity_mm_s: [30.0, 1000.0, 1000.0],
            axis_accel_mm_s2: [4000.0, 900.0, 4000.0],
            ..limits(100.0)
        };
        let along = |dir| check_all(lim, &ramp(1e-3, 50_000.0, 20, 30, dir)).violations;
        let x = along([1.0, 0.0, 0.0]);
        assert!(x.over_axis_velocity > 0 && x.over_axis_accel == 0, "{x:?}");
        let y = along([0.0, 1.0, 0.0]);
        assert!(y.over_axis_velocity == 0 && y.over_axis_accel > 0, "{y:?}");
        let z = along([0.0, 0.0, 1.0]);
        assert_eq!(z, Violations::default());
    }

    #[test]
    fn the_end_must_be_done_and_exactly_at_the_programs_end() {
        let mut sps = ramp(1e-3, 50_000.0, 20, 30, [1.0, 0.0, 0.0]);
        let end = [sps[49].axes[0], 0.0, 0.0];
        let mut sub = check_all(limits(100.0), &sps);
        let v = sub.finish(Some(end));
        assert_eq!((v.not_done, v.end_mismatch, v.first_seq), (1, 0, Some(50)));
        sps[49].state = RunState::Done;
        let mut sub = check_all(limits(100.0), &sps);
        assert_eq!(sub.finish(Some(end)), Violations::default());
        sub.assert_clean("a run that ends where it should");
        let mut sub = check_all(limits(100.0), &sps);
        let v = sub.finish(Some([end[0] + 1e-12, 0.0, 0.0]));
        assert_eq!((v.not_done, v.end_mismatch, v.total()), (0, 1, 1));
    }

    #[test]
    fn subscriber_catches_gaps_overspeed_overaccel_and_nan() {
        let ts = 1e-3;
        // Steps from rest: no jerk or axis limits here (tested above).
        let lim = Limits {
            jerk_mm_s3: f64::INFINITY,
            axis_velocity_mm_s: [f64::INFINITY; 3],
            axis_accel_mm_s2: [f64::INFINITY; 3],
            axis_jerk_mm_s3: [f64::INFINITY; 3],
            ..limits(100.0)
        };
        let mut sub = Checker::new(ts, lim, [0.0; 3]);
        let mut sp = Setpoint {
            seq: 1,
            time: ts,
            feed: 1.0,
            state: RunState::Running,
            ..Setpoint::default()
        };
        sp.axes[0] = 1e-3;
        sub.check(&sp);
        assert_eq!(sub.violations, Violations::default());
        sp.seq = 3; // gap
        sp.feed = 4.0; // Δfeed/Ts = 3000 > 2000
        sp.axes[0] = 1e-3 + 0.2; // 200 mm/s chord
        sub.check(&sp);
        sp.seq = 4;
        sp.axes[1] = f64::NAN;
        sub.check(&sp);
        let v = sub.violations;
        assert_eq!((v.seq_gaps, v.over_accel, v.non_finite), (1, 1, 1));
        assert_eq!(v.over_speed, 0);
        assert_eq!(v.over_chord_speed, 2); // the jump, then NaN
        assert_eq!(v.first_seq, Some(3));
        // A commanded feed above the limit, reached within the acceleration limit.
        let mut sub = Checker::new(ts, lim, [0.0; 3]);
        let mut x = 0.0;
        for k in 1..=60u32 {
            let feed = (2.0 * f64::from(k)).min(101.0);
            x += feed * ts;
            let sp = Setpoint {
                seq: u64::from(k),
                feed,
                axes: [x, 0.0, 0.0, 0.0, 0.0, 0.0],
                ..Setpoint::default()
            };
            sub.check(&sp);
        }
        let v = sub.violations;
        assert_eq!(
            (v.over_speed, v.over_chord_speed, v.over_accel),
            (10, 10, 0)
        );
    }

    /// The rotary joints have their own limits: C turning on a
    /// jerk-limited ramp within them passes, beyond its jerk limit fails,
    /// and what it did is measured per joint.
    #[test]
    fn rotary_joints_are_checked_against_their_own_limits() {
        let lim = limits(100.0);
        let run = |jerk: f64| {
            // 15 ticks at the jerk: the acceleration stays below 1800 deg/s².
            let sps: Vec<Setpoint> = ramp(1e-3, jerk, 15, 10, [1.0, 0.0, 0.0])
                .into_iter()
                .map(|mut sp| {
                    // The ramp on C alone (degrees), X Y Z at rest.
                    sp.axes = [0.0, 0.0, 0.0, 0.0, 0.0, sp.axes[0]];
                    sp.feed = 0.0;
                    sp.s = 0.0;
                    sp
                })
                .collect();
            check_all(lim, &sps)
        };
        let ok = run(0.9 * lim.rotary_jerk_deg_s3[2]);
        assert_eq!(ok.violations, Violations::default());
        let m = ok.measured;
        assert!(
            (m.rotary_jerk_deg_s3[2] / (0.9 * lim.rotary_jerk_deg_s3[2]) - 1.0).abs() < 1e-6,
            "{m:?}"
        );
        assert_eq!(
            (m.rotary_jerk_deg_s3[0], m.axis_velocity_mm_s[0]),
            (0.0, 0.0)
        );
        let v = run(1.1 * lim.rotary_jerk_deg_s3[2]).violations;
        assert_eq!((v.over_axis_jerk, v.first_seq), (15, Some(1)), "{v:?}");
        assert_eq!(v.total(), 15, "{v:?}");
    }

    /// Under tool-centre-point control the path is the tool tip: the table
    /// of a C,A machine turning under a tool tip that stands still in the
    /// workpiece frame moves X and Y, but commands no path speed.
    #[test]
    fn under_tcp_the_speed_checks_measure_the_tool_tip() {
        use interp_core::kinematics::{MachineSpec, ToolPose};
        let spec = MachineSpec {
            tool_length: 50.0,
            ..MachineSpec::new("W/caxyBz/T".parse().expect("chain"))
        };
        let m = Machine::new(spec).expect("machine");
        let tip = Vec3::new(10.0, 0.0, 0.0);
        let tilt = 20f64.to_radians();
        let pose = |az: f64| ToolPose {
            tip,
            axis: Vec3::new(
                tilt.sin() * az.to_radians().cos(),
                tilt.sin() * az.to_radians().sin(),
                tilt.cos(),
            ),
        };
        let mut q = m.inverse(&pose(0.0), &[0.0; 6]).expect("reach").joints;
        let start = q;
        // The axis' azimuth on a jerk-limited ramp (degrees), the tip still.
        let sps: Vec<Setpoint> = ramp(1e-3, 20_000.0, 20, 10, [1.0, 0.0, 0.0])
            .into_iter()
            .map(|mut sp| {
                q = m.inverse(&pose(sp.axes[0]), &q).expect("reach").joints;
                sp.axes = q;
                sp.feed = 0.0;
                sp.s = 0.0;
                sp
            })
            .collect();
        assert!((sps[29].axes[0] - start[0]).abs() > 1e-3, "X moves");
        // A feed limit of 0.1 mm/s: X Y move faster, the tip does not.
        let lim = Limits {
            feed_mm_s: 0.1,
            ..limits(100.0)
        };
        let mut tcp = Checker::five_axis(1e-3, lim, m, start);
        let mut xyz = Checker::five_axis(1e-3, lim, m, start);
        for sp in &sps {
            tcp.check_in_frame(sp, true);
            xyz.check_in_frame(sp, false);
        }
        assert_eq!(tcp.violations, Violations::default());
        assert!(tcp.max_chord_speed < 1e-6, "{}", tcp.max_chord_speed);
        assert!(xyz.violations.over_chord_speed > 0, "{:?}", xyz.violations);
        assert!(tcp.measured.rotary_velocity_deg_s[2] > 1.0);
    }
}
