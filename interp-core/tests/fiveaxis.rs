//! Five-axis interpolation with tool-centre-point control, against paths
//! whose tool tip and tool axis are known in closed form: every setpoint's
//! tip on the path and axis on its program, the drives' linear joint
//! interpolation between setpoints within the chord and angular
//! tolerances, every joint limit on every tick (finite differences of the
//! setpoints), on C,A and A,B machines, and the pole crossed without a C jump.

mod common;

use common::{LIMIT_REL_TOL, push_what_fits};

use core::f64::consts::PI;
use interp_core::fiveaxis::{JointError, Orientation, OrientationAt};
use interp_core::geom::Vec3;
use interp_core::interp::PushError;
use interp_core::kinematics::{Joints, Machine, MachineSpec, RotaryRange, ToolPose};
use interp_core::path::{Arc, Block, Line, Path};
use interp_core::samples::rational_cubic::rational_cubic;
use interp_core::{Curve, InterpConfig, Interpolator, RunState, Setpoint};

/// Setpoints put the tip on the programmed path within this, mm.
const ON_PATH_TOL: f64 = 1e-9;
/// And the tool axis on its program within this (rad).
const ON_AXIS_TOL: f64 = 1e-9;
/// Points of the drives' linear joint interpolation checked between two setpoints.
const BETWEEN: usize = 8;

/// The poses the drives pass between two setpoints' joints (`BETWEEN − 1`
/// points of their linear interpolation, ends excluded).
fn poses_between(m: &Machine, prev: Joints, next: Joints) -> impl Iterator<Item = ToolPose> + '_ {
    (1..BETWEEN).map(move |k| {
        let l = k as f64 / BETWEEN as f64;
        let mut j = prev;
        for (n, v) in j.iter_mut().enumerate() {
            *v += (next[n] - prev[n]) * l;
        }
        m.forward(&j)
    })
}

fn machine(chain: &str, tool_length: f64, centre: (usize, [f64; 3])) -> MachineSpec {
    let mut spec = MachineSpec::new(chain.parse().expect("chain"));
    spec.tool_length = tool_length;
    spec.rotary_centres[centre.0] = centre.1;
    spec
}

fn config(spec: MachineSpec) -> InterpConfig {
    InterpConfig {
        machine: Some(spec),
        ..InterpConfig::default()
    }
}

/// Runs `blocks` from `start` to the end; every setpoint.
fn run(cfg: &InterpConfig, start: Joints, blocks: &[Block]) -> Vec<Setpoint> {
    run_within(cfg, start, blocks, 2_000_000)
}

/// [`run`], failing if the run takes more than `max_ticks`.
fn run_within(
    cfg: &InterpConfig,
    start: Joints,
    blocks: &[Block],
    max_ticks: u64,
) -> Vec<Setpoint> {
    let mut ip: Box<Interpolator> = Box::new(Interpolator::new(*cfg, start).expect("config"));
    let mut out = Vec::new();
    let mut next = 0;
    for _ in 0..max_ticks {
        if next < blocks.len() {
            next += push_what_fits(&mut ip, &blocks[next..]);
            if next == blocks.len() {
                ip.finish();
            }
        }
        let sp = ip.tick();
        assert_ne!(sp.state, RunState::Fault, "fault at tick {}", sp.seq);
        out.push(sp);
        if sp.state == RunState::Done {
            return out;
        }
    }
    let last = out.last().expect("setpoints");
    panic!(
        "did not finish within {max_ticks} ticks: at s = {} mm, feed {} mm/s, joints {:?}",
        last.s, last.feed, last.axes
    );
}

/// The joints at rest at `pose`, from home.
fn joints_at(m: &Machine, tip: Vec3, axis: Vec3) -> Joints {
    m.inverse(&ToolPose { tip, axis }, &[0.0; 6])
        .expect("reachable")
        .joints
}

/// What a test knows of its path in closed form: for a tip near the path,
/// its distance from the path (an upper bound) and the programmed tool
/// axis there.
trait Reference {
    fn at(&self, tip: Vec3) -> (f64, Vec3);
}

#[derive(Debug, Default)]
struct Report {
    on_path: f64,
    on_axis: f64,
    between_tip: f64,
    between_axis: f64,
    /// Largest velocity, acceleration and jerk of each joint over its limit.
    ratio: [[f64; 3]; 6],
}

/// Checks every setpoint and the drives' motion between them.
fn check(cfg: &InterpConfig, start: Joints, sps: &[Setpoint], r: &dyn Reference) -> Report {
    let m = Machine::new(cfg.machine.expect("machine")).expect("machine");
    let mut rep = Report::default();
    let angle = |a: Vec3, b: Vec3| libm::atan2(a.cross(&b).norm(), a.dot(&b));
    let mut q = vec![start, start, start];
    q.extend(sps.iter().map(|s| s.axes));
    for (i, sp) in sps.iter().enumerate() {
        let pose = m.forward(&sp.axes);
        let (d, axis) = r.at(pose.tip);
        rep.on_path = rep.on_path.max(d);
        rep.on_axis = rep.on_axis.max(angle(pose.axis, axis));
        let prev = q[i + 2];
        for p in poses_between(&m, prev, sp.axes) {
            let (d, axis) = r.at(p.tip);
            rep.between_tip = rep.between_tip.max(d);
            rep.between_axis = rep.between_axis.max(angle(p.axis, axis));
        }
    }
    rep.ratio = joint_ratios(cfg, &q);
    rep
}

/// Per joint, the largest velocity, acceleration and jerk of the drives'
/// commands `q` (three copies of the start first) by finite differences,
/// as fractions of the joint's limits.
fn joint_ratios(cfg: &InterpConfig, q: &[Joints]) -> [[f64; 3]; 6] {
    let ts = cfg.period;
    let mut ratio = [[0.0f64; 3]; 6];
    for i in 3..q.len() {
        for (j, r) in ratio.iter_mut().enumerate() {
            let (vm, am, jm) = cfg.joint_limits(j);
            let v = (q[i][j] - q[i - 1][j]) / ts;
            let a = (q[i][j] - 2.0 * q[i - 1][j] + q[i - 2][j]) / (ts * ts);
            let a0 = (q[i - 1][j] - 2.0 * q[i - 2][j] + q[i - 3][j]) / (ts * ts);
            let jk = (a - a0) / ts;
            r[0] = r[0].max(v.abs() / vm);
            r[1] = r[1].max(a.abs() / am);
            r[2] = r[2].max(jk.abs() / jm);
        }
    }
    ratio
}

fn assert_within(cfg: &InterpConfig, rep: &Report, what: &str) {
    eprintln!("{what}: {rep:?}");
    assert!(
        rep.on_path <= ON_PATH_TOL,
        "{what}: tip off the path {rep:?}"
    );
    assert!(rep.on_axis <= ON_AXIS_TOL, "{what}: axis off {rep:?}");
    assert!(
        rep.between_tip <= cfg.chord_tolerance * (1.0 + LIMIT_REL_TOL),
        "{what}: tip between setpoints {rep:?}"
    );
    assert!(
        rep.between_axis <= cfg.angular_tolerance * (1.0 + LIMIT_REL_TOL),
        "{what}: axis between setpoints {rep:?}"
    );
    assert_joints_within(&rep.ratio, &format!("{what} {rep:?}"));
}

/// Every joint's velocity, acceleration and jerk within its limit
/// ([`joint_ratios`]).
fn assert_joints_within(ratio: &[[f64; 3]; 6], what: &str) {
    for (j, r) in ratio.iter().enumerate() {
        for (k, x) in r.iter().enumerate() {
            assert!(
                *x <= 1.0 + LIMIT_REL_TOL,
                "{what}: joint {j} {} {x} of its limit",
                ["velocity", "acceleration", "jerk"][k]
            );
        }
    }
}

/// A helix about z (radius `r`, from angle 0 over `sweep`, rising `rise`
/// from `z0`) with the tool axis turned on the great circle from `a0` to
/// `a1` in proportion to the angle.
struct Helix {
    r: f64,
    z0: f64,
    rise: f64,
    sweep: f64,
    a0: Vec3,
    a1: Vec3,
}

impl Helix {
    fn point(&self, t: f64) -> Vec3 {
        Vec3::new(
            self.r * libm::cos(t),
            self.r * libm::sin(t),
            self.z0 + self.rise * t / self.sweep,
        )
    }
    fn axis(&self, t: f64) -> Vec3 {
        let theta = libm::acos(self.a0.dot(&self.a1).clamp(-1.0, 1.0));
        let w = (self.a1 - self.a0 * self.a0.dot(&self.a1)).normalize();
        let phi = theta * (t / self.sweep).clamp(0.0, 1.0);
        self.a0 * libm::cos(phi) + w * libm::sin(phi)
    }
    fn block(&self, feed: f64) -> Block {
        let arc = Arc::from_centre(
            self.point(0.0),
            self.point(self.sweep),
            Vec3::new(0.0, 0.0, self.z0),
            Vec3::z(),
            0,
        )
        .expect("arc");
        let path = Path::Arc(arc);
        let o = Orientation::tool_axis(&path, self.a0, self.a1).expect("orientation");
        Block::new(1, path, feed).with_orientation(o)
    }
}

impl Reference for Helix {
    fn at(&self, tip: Vec3) -> (f64, Vec3) {
        // The angle of the tip about z, unwrapped into the sweep (< 2π).
        let mut t = libm::atan2(tip.y, tip.x);
        if t < -1e-9 {
            t += 2.0 * PI;
        }
        // The distance to the helix point at the same angle bounds the
        // distance to the helix.
        ((tip - self.point(t)).norm(), self.axis(t))
    }
}

fn tilted(deg: f64, towards: Vec3) -> Vec3 {
    let r = deg.to_radians();
    Vec3::z() * libm::cos(r) + towards * libm::sin(r)
}

fn helix() -> Helix {
    Helix {
        r: 30.0,
        z0: -5.0,
        rise: 12.0,
        sweep: 1.5 * PI,
        a0: tilted(20.0, Vec3::x()),
        a1: tilted(35.0, -Vec3::y()),
    }
}

#[test]
fn helix_with_a_turning_tool_on_a_ca_table() {
    let spec = machine("W/caxyBz/T", 80.0, (0, [0.0, 0.0, -40.0]));
    let cfg = config(spec);
    let m = Machine::new(spec).expect("machine");
    let h = helix();
    let start = joints_at(&m, h.point(0.0), h.a0);
    let sps = run(&cfg, start, &[h.block(50.0)]);
    let rep = check(&cfg, start, &sps, &h);
    assert_within(&cfg, &rep, "helix C,A");
    // It ends at rest on the end pose.
    let end = m.forward(&sps.last().expect("setpoints").axes);
    assert!((end.tip - h.point(h.sweep)).norm() < ON_PATH_TOL);
    assert!((end.axis - h.a1).norm() < ON_AXIS_TOL);
    // The rotary joints really turn (C sweeps with the tool's azimuth).
    let c: Vec<f64> = sps.iter().map(|s| s.axes[5]).collect();
    let span =
        c.iter().cloned().fold(f64::MIN, f64::max) - c.iter().cloned().fold(f64::MAX, f64::min);
    assert!(span > 60.0, "C spans {span} degrees");
}

/// Regression (issue 19): the rational cubic of the tick benches, the tool
/// turning on its great circle from (A 10°, C 90°) to (A 35°, C 0°), on
/// the example's C,A table stalled at s = 36.906 mm (A 9.71°, C 73.44°):
/// a look-ahead interval there held more per-axis samples (the tip's and
/// the joints') than it can, and the one that did not fit lowered the speed
/// limit where it lies until its worst-case axis jerk fit, but the
/// tangential part of C's jerk, `|q_s|·J` (1.5 of C's limit), does not fall
/// with the speed: the limit became 0, the feed fell to 0, the run never
/// ended. It must end at rest on its end pose, the tip on the curve and the
/// axis on its program at every setpoint, every joint within its limits.
#[test]
fn rational_cubic_with_a_turning_tool_ends() {
    let mut spec = machine("W/caxyBz/T", 100.0, (0, [0.0, 0.0, -50.0]));
    spec.rotary_ranges[0] = RotaryRange {
        min: -110.0,
        max: 110.0,
    };
    let cfg = config(spec);
    let m = Machine::new(spec).expect("machine");
    let path = Path::Nurbs(rational_cubic());
    let axis = |a: f64, c: f64| m.forward(&[0.0, 0.0, 0.0, a, 0.0, c]).axis;
    let (a0, a1) = (axis(10.0, 90.0), axis(35.0, 0.0));
    let o = Orientation::tool_axis(&path, a0, a1).expect("orientation");
    let start = m
        .inverse(
            &ToolPose {
                tip: path.start_point(),
                axis: a0,
            },
            &[0.0, 0.0, 0.0, 10.0, 0.0, 90.0],
        )
        .expect("reachable")
        .joints;
    // ≈ 3700 ticks when it runs; the stall never ends.
    let sps = run_within(
        &cfg,
        start,
        &[Block::new(1, path, 100.0).with_orientation(o)],
        20_000,
    );
    let last = sps.last().expect("setpoints");
    let end = m.forward(&last.axes);
    assert!(
        (end.tip - path.end_point()).norm() < ON_PATH_TOL,
        "{last:?}"
    );
    assert!((end.axis - a1).norm() < ON_AXIS_TOL, "{last:?}");
    assert_eq!(last.feed, 0.0);
    let mut on_path = 0.0f64;
    let mut on_axis = 0.0f64;
    for sp in &sps {
        let pose = m.forward(&sp.axes);
        on_path = on_path.max((pose.tip - path.eval(sp.u, 0).p).norm());
        let OrientationAt::ToolAxis(a) = o.at(sp.u) else {
            unreachable!("a tool axis");
        };
        on_axis = on_axis.max(libm::atan2(pose.axis.cross(&a).norm(), pose.axis.dot(&a)));
    }
    assert!(on_path <= ON_PATH_TOL, "tip off the curve by {on_path} mm");
    assert!(
        on_axis <= ON_AXIS_TOL,
        "axis off its program by {on_axis} rad"
    );
    let mut q = vec![start; 3];
    q.extend(sps.iter().map(|s| s.axes));
    assert_joints_within(&joint_ratios(&cfg, &q), "rational cubic");
}

/// A G6.2 under G43.4: the tip on three quarters of a circle (radius 30 mm
/// at z = −5, an exact rational quadratic, cut into its knot spans as
/// `gcode::Cutter` cuts it) and A C as coordinates of the same NURBS,
/// `A_k = 15 + 0.3·x_k`, `C_k = 20 + 0.9·y_k`: a rational curve keeps an
/// affine map of its control points, so at every tip the programmed rotary
/// positions are `A = 15 + 0.3·x`, `C = 20 + 0.9·y` and the tool axis the
/// machine's there, in closed form.
struct RotaryCircle {
    m: Machine,
}

impl RotaryCircle {
    const R: f64 = 30.0;
    const Z: f64 = -5.0;
    fn rotary(p: [f64; 3]) -> [f64; 3] {
        [15.0 + 0.3 * p[0], 0.0, 20.0 + 0.9 * p[1]]
    }
    fn axis(&self, tip: Vec3) -> Vec3 {
        let [a, b, c] = Self::rotary([tip.x, tip.y, tip.z]);
        self.m.forward(&[0.0, 0.0, 0.0, a, b, c]).axis
    }
    /// The circle's knot spans, as `gcode::Cutter` cuts it.
    fn spans() -> Vec<interp_core::nurbs::Nurbs> {
        let (r, z, w) = (Self::R, Self::Z, core::f64::consts::FRAC_1_SQRT_2);
        let pts = [
            [r, 0.0, z],
            [r, r, z],
            [0.0, r, z],
            [-r, r, z],
            [-r, 0.0, z],
            [-r, -r, z],
            [0.0, -r, z],
        ];
        let ws = [1.0, w, 1.0, w, 1.0, w, 1.0];
        let knots = [0.0, 0.0, 0.0, 1.0, 1.0, 2.0, 2.0, 3.0, 3.0, 3.0];
        common::split_segments(2, &pts, &ws, &knots, 3)
    }
    fn blocks(&self, feed: f64) -> Vec<Block> {
        Self::spans()
            .into_iter()
            .map(|n| {
                let values: Vec<[f64; 3]> = (0..n.control_count())
                    .map(|k| Self::rotary(n.control_point(k)))
                    .collect();
                let w: Vec<f64> = (0..n.control_count()).map(|k| n.weight(k)).collect();
                let o = Orientation::axes_curve(2, &values, &w, n.u_start(), n.u_end())
                    .expect("rotary curve")
                    .under_tcp();
                Block::new(1, Path::Nurbs(n), feed).with_orientation(o)
            })
            .collect()
    }
}

impl Reference for RotaryCircle {
    fn at(&self, tip: Vec3) -> (f64, Vec3) {
        let d = libm::hypot(libm::hypot(tip.x, tip.y) - Self::R, tip.z - Self::Z);
        (d, self.axis(tip))
    }
}

#[test]
fn g6_2_rotary_curve_under_tcp_keeps_the_tip_on_the_nurbs() {
    let spec = machine("W/caxyBz/T", 80.0, (0, [0.0, 0.0, -40.0]));
    let cfg = config(spec);
    let m = Machine::new(spec).expect("machine");
    let c = RotaryCircle { m };
    let blocks = c.blocks(80.0);
    assert_eq!(blocks.len(), 3, "one block per knot span");
    assert!(blocks.iter().all(|b| b.is_tcp()));
    let [a, b, cc] = RotaryCircle::rotary([RotaryCircle::R, 0.0, RotaryCircle::Z]);
    let start = m
        .place_tip(
            &Vec3::new(RotaryCircle::R, 0.0, RotaryCircle::Z),
            [a, b, cc],
            &[0.0; 6],
        )
        .expect("reachable");
    let sps = run_within(&cfg, start, &blocks, 50_000);
    let rep = check(&cfg, start, &sps, &c);
    assert_within(&cfg, &rep, "G6.2 rotary curve under TCP");
    // The rotary joints are the program's curve at every setpoint.
    let mut off = 0.0f64;
    for sp in &sps {
        let tip = m.forward(&sp.axes).tip;
        let want = RotaryCircle::rotary([tip.x, tip.y, tip.z]);
        off = off.max(
            (sp.axes[3] - want[0])
                .abs()
                .max((sp.axes[5] - want[2]).abs()),
        );
    }
    assert!(off < 1e-9, "rotary joints off the curve by {off} degrees");
    let last = sps.last().expect("setpoints");
    let end = m.forward(&last.axes);
    assert!((end.tip - Vec3::new(0.0, -RotaryCircle::R, RotaryCircle::Z)).norm() < ON_PATH_TOL);
    assert_eq!(last.feed, 0.0);
    // A and C really turn: A by 18 degrees, C by 54.
    let span = |j: usize| {
        let v = sps.iter().map(|s| s.axes[j]);
        v.clone().fold(f64::MIN, f64::max) - v.fold(f64::MAX, f64::min)
    };
    assert!(
        span(3) > 17.0 && span(5) > 50.0,
        "A {} C {}",
        span(3),
        span(5)
    );
}

/// A G6.2 under G43.5 with a tool vector on each control point (a second
/// curve for the tool axis): the tip on [`RotaryCircle`]'s three quarters
/// of a circle, and the control vectors the affine image
/// `v = (−0.35·x/R, −0.35·y/R, 0.95 + 0.25·x/R)` of the control points. A
/// rational curve keeps an affine map of its control points, so the vector
/// curve at every tip is that map of the tip, and the programmed axis its
/// direction: on a cone about z whose opening changes with x (16° at
/// x = R, 27° at x = −R), in closed form. The curve is not of unit length
/// between control points, so its normalisation is exercised.
struct VectorCircle;

impl VectorCircle {
    fn vector(p: [f64; 3]) -> [f64; 3] {
        let r = RotaryCircle::R;
        [-0.35 * p[0] / r, -0.35 * p[1] / r, 0.95 + 0.25 * p[0] / r]
    }
    fn axis(tip: Vec3) -> Vec3 {
        let [x, y, z] = Self::vector([tip.x, tip.y, tip.z]);
        Vec3::new(x, y, z).normalize()
    }
    fn blocks(feed: f64) -> Vec<Block> {
        RotaryCircle::spans()
            .into_iter()
            .map(|n| {
                let values: Vec<[f64; 3]> = (0..n.control_count())
                    .map(|k| Self::vector(n.control_point(k)))
                    .collect();
                let w: Vec<f64> = (0..n.control_count()).map(|k| n.weight(k)).collect();
                let o = Orientation::tool_axis_curve(2, &values, &w, n.u_start(), n.u_end())
                    .expect("tool vector curve");
                Block::new(1, Path::Nurbs(n), feed).with_orientation(o)
            })
            .collect()
    }
}

impl Reference for VectorCircle {
    fn at(&self, tip: Vec3) -> (f64, Vec3) {
        let d = libm::hypot(
            libm::hypot(tip.x, tip.y) - RotaryCircle::R,
            tip.z - RotaryCircle::Z,
        );
        // (The programmed axis at the nearest path point: the map of the
        // tip projected onto the circle.)
        let rho = libm::hypot(tip.x, tip.y);
        let on = Vec3::new(
            tip.x * RotaryCircle::R / rho,
            tip.y * RotaryCircle::R / rho,
            RotaryCircle::Z,
        );
        (d, Self::axis(on))
    }
}

#[test]
fn g6_2_tool_vector_curve_under_g43_5_turns_the_axis_on_its_cone() {
    let blocks = VectorCircle::blocks(80.0);
    assert!(blocks.iter().all(|b| b.is_tcp()));
    // (On a C,A and an A,B table alike: one closed-form reference for both.)
    for (chain, centre) in [
        ("W/caxyBz/T", (0, [0.0, 0.0, -40.0])),
        ("W/abxyBz/T", (1, [0.0, 0.0, -40.0])),
    ] {
        let spec = machine(chain, 80.0, centre);
        let cfg = config(spec);
        let m = Machine::new(spec).expect("machine");
        let tip0 = Vec3::new(RotaryCircle::R, 0.0, RotaryCircle::Z);
        let start = joints_at(&m, tip0, VectorCircle::axis(tip0));
        let sps = run_within(&cfg, start, &blocks, 50_000);
        let rep = check(&cfg, start, &sps, &VectorCircle);
        assert_within(&cfg, &rep, chain);
        // The axis at every setpoint is the block's curve at its parameter.
        let mut off = 0.0f64;
        for sp in &sps {
            let b = blocks
                .iter()
                .find(|b| sp.u >= b.path.u_start() && sp.u <= b.path.u_end())
                .expect("a block holds the parameter");
            let OrientationAt::ToolAxis(a) = b.orientation.expect("orientation").at(sp.u) else {
                unreachable!("a tool axis");
            };
            let axis = m.forward(&sp.axes).axis;
            off = off.max(libm::atan2(axis.cross(&a).norm(), axis.dot(&a)));
        }
        assert!(
            off <= ON_AXIS_TOL,
            "{chain}: axis off its curve by {off} rad"
        );
        let last = sps.last().expect("setpoints");
        let end = m.forward(&last.axes);
        let tip1 = Vec3::new(0.0, -RotaryCircle::R, RotaryCircle::Z);
        assert!(
            (end.tip - tip1).norm() < ON_PATH_TOL,
            "{chain}: end {:?}",
            end.tip
        );
        assert!(end.axis.dot(&VectorCircle::axis(tip1)) > 1.0 - 1e-15);
        assert_eq!(last.feed, 0.0);
    }
}

/// The flank of a cone frustum in the manner of NAS 979: the tip runs
/// round the bottom circle (radius `r`) in eight exact arcs, and the tool
/// axis, along the cone's generatrix (leaning `alpha` inwards) at the arcs'
/// ends, turns on the great circle between them: known in closed form at
/// every angle.
struct Frustum {
    r: f64,
    alpha: f64,
}

/// Arcs the frustum's circle is cut into.
const FRUSTUM_ARCS: usize = 8;

impl Frustum {
    fn generatrix(&self, t: f64) -> Vec3 {
        Vec3::new(
            -libm::sin(self.alpha) * libm::cos(t),
            -libm::sin(self.alpha) * libm::sin(t),
            libm::cos(self.alpha),
        )
    }
    fn step(&self) -> f64 {
        2.0 * PI / FRUSTUM_ARCS as f64
    }
    /// The programmed axis at angle `t` (on arc `⌊t/step⌋`).
    fn axis(&self, t: f64) -> Vec3 {
        let k = ((t / self.step()) as usize).min(FRUSTUM_ARCS - 1);
        let (t0, t1) = (k as f64 * self.step(), (k + 1) as f64 * self.step());
        let (a, b) = (self.generatrix(t0), self.generatrix(t1));
        let theta = libm::atan2(a.cross(&b).norm(), a.dot(&b));
        let w = (b - a * a.dot(&b)).normalize();
        let phi = theta * (t - t0) / (t1 - t0);
        a * libm::cos(phi) + w * libm::sin(phi)
    }
    fn blocks(&self, feed: f64) -> Vec<Block> {
        let p = |t: f64| Vec3::new(self.r * libm::cos(t), self.r * libm::sin(t), 0.0);
        (0..FRUSTUM_ARCS)
            .map(|k| {
                let (t0, t1) = (k as f64 * self.step(), (k + 1) as f64 * self.step());
                let arc = Arc::from_centre(p(t0), p(t1), Vec3::zeros(), Vec3::z(), 0).expect("arc");
                let path = Path::Arc(arc);
                let o = Orientation::tool_axis(&path, self.generatrix(t0), self.generatrix(t1))
                    .expect("orientation");
                Block::new(k as u32 + 1, path, feed).with_orientation(o)
            })
            .collect()
    }
}

impl Reference for Frustum {
    fn at(&self, tip: Vec3) -> (f64, Vec3) {
        let mut t = libm::atan2(tip.y, tip.x);
        if t < -1e-9 {
            t += 2.0 * PI;
        }
        let d = libm::hypot(libm::hypot(tip.x, tip.y) - self.r, tip.z);
        (d, self.axis(t.min(2.0 * PI)))
    }
}

/// The same workpiece path on a C,A table and an A,B table: both within
/// every tolerance and limit, and the same tip path (each tip of one run
/// within the chord tolerance of the other's polyline, the axis there the same).
#[test]
fn cone_frustum_flank_on_ca_and_ab_machines_gives_the_same_tip_path() {
    let f = Frustum {
        r: 40.0,
        alpha: 15f64.to_radians(),
    };
    let mut tips = Vec::new();
    for (chain, centre) in [
        ("W/caxyBz/T", (0, [0.0, 0.0, -30.0])),
        ("W/abxyBz/T", (1, [0.0, 0.0, -30.0])),
    ] {
        let spec = machine(chain, 60.0, centre);
        let cfg = config(spec);
        let m = Machine::new(spec).expect("machine");
        let start = joints_at(&m, Vec3::new(f.r, 0.0, 0.0), f.generatrix(0.0));
        let sps = run(&cfg, start, &f.blocks(40.0));
        let rep = check(&cfg, start, &sps, &f);
        assert_within(&cfg, &rep, chain);
        tips.push(sps.iter().map(|s| m.forward(&s.axes)).collect::<Vec<_>>());
    }
    let (a, b) = (&tips[0], &tips[1]);
    let dist = |p: Vec3, poly: &[ToolPose]| {
        poly.windows(2)
            .map(|w| {
                let (s, e) = (w[0].tip, w[1].tip);
                let d = e - s;
                let l = if d.norm_squared() > 0.0 {
                    ((p - s).dot(&d) / d.norm_squared()).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                (s + d * l - p).norm()
            })
            .fold(f64::INFINITY, f64::min)
    };
    let step = (b.len() / 400).max(1);
    for p in b.iter().step_by(step) {
        assert!(dist(p.tip, a) <= 1e-3, "tip {:?} off the other run", p.tip);
    }
}

/// A line under the pole of a C,A table: the tool axis swings from 30°
/// one side to 30° the other through +z (where C is undefined). C stays
/// where it is and A changes sign; a line passing near the pole (C must
/// turn half a revolution there) keeps C's limits.
#[test]
fn the_pole_is_crossed_without_a_c_jump() {
    let spec = machine("W/caxyBz/T", 50.0, (0, [0.0, 0.0, -20.0]));
    let cfg = config(spec);
    let m = Machine::new(spec).expect("machine");
    struct Swing {
        a0: Vec3,
        a1: Vec3,
        len: f64,
    }
    impl Reference for Swing {
        fn at(&self, tip: Vec3) -> (f64, Vec3) {
            let t = ((tip.x + 0.5 * self.len) / self.len).clamp(0.0, 1.0);
            let theta = libm::acos(self.a0.dot(&self.a1));
            let w = (self.a1 - self.a0 * self.a0.dot(&self.a1)).normalize();
            let axis = self.a0 * libm::cos(theta * t) + w * libm::sin(theta * t);
            (libm::hypot(tip.y, tip.z), axis)
        }
    }
    for off in [0.0, 0.02] {
        let s = Swing {
            a0: Vec3::new(0.5, off, 0.75f64.sqrt()).normalize(),
            a1: Vec3::new(-0.5, off, 0.75f64.sqrt()).normalize(),
            len: 40.0,
        };
        let (p0, p1) = (Vec3::new(-20.0, 0.0, 0.0), Vec3::new(20.0, 0.0, 0.0));
        let path = Path::Line(Line::new(p0, p1).expect("line"));
        let o = Orientation::tool_axis(&path, s.a0, s.a1).expect("orientation");
        let block = Block::new(1, path, 40.0).with_orientation(o);
        let start = joints_at(&m, p0, s.a0);
        let sps = run(&cfg, start, &[block]);
        let rep = check(&cfg, start, &sps, &s);
        assert_within(&cfg, &rep, &format!("pole, offset {off}"));
        let c0 = start[5];
        let (a_first, a_last) = (start[3], sps.last().expect("end").axes[3]);
        if off == 0.0 {
            // The tilt changes sign through the pole.
            assert!(a_first * a_last < 0.0, "A {a_first} → {a_last}");
            // Through the pole itself: C never moves.
            for sp in &sps {
                assert!((sp.axes[5] - c0).abs() <= 1e-9, "C moved to {}", sp.axes[5]);
            }
        } else {
            // Near it C turns by about half a revolution, within its limits (above).
            let c_end = sps.last().expect("end").axes[5];
            assert!((c_end - c0).abs() > 150.0, "C {c0} → {c_end}");
        }
    }
}

/// Without tool-centre-point control the rotary axes are plain axes that
/// move in proportion with X Y Z; no machine is needed.
#[test]
fn plain_rotary_axes_move_with_the_line() {
    let cfg = InterpConfig::default();
    let path = Path::Line(Line::new(Vec3::zeros(), Vec3::new(10.0, 0.0, 0.0)).expect("line"));
    let o = Orientation::axes(&path, [0.0, 0.0, 0.0], [30.0, 0.0, -15.0]).expect("axes");
    let after = Block::new(
        2,
        Path::Line(Line::new(Vec3::new(10.0, 0.0, 0.0), Vec3::new(10.0, 5.0, 0.0)).expect("line")),
        50.0,
    );
    let sps = run(
        &cfg,
        [0.0; 6],
        &[Block::new(1, path, 50.0).with_orientation(o), after],
    );
    let mut q = vec![[0.0; 6]; 3];
    q.extend(sps.iter().map(|s| s.axes));
    for sp in &sps {
        let x = sp.axes[0];
        if sp.block_id == 1 {
            assert!((sp.axes[3] - 3.0 * x).abs() < 1e-9 && (sp.axes[5] + 1.5 * x).abs() < 1e-9);
        } else {
            assert_eq!((sp.axes[3], sp.axes[5]), (30.0, -15.0));
        }
    }
    let ratio = joint_ratios(&cfg, &q);
    for j in [3, 5] {
        assert!(
            ratio[j].iter().all(|&x| x <= 1.0 + LIMIT_REL_TOL),
            "joint {j}: velocity, acceleration, jerk {:?} of its limits",
            ratio[j]
        );
    }
}

/// Tool-centre-point control needs the machine, and a pose out of the
/// rotary ranges is refused before anything is queued.
#[test]
fn five_axis_blocks_out_of_reach_are_refused() {
    let line = Path::Line(Line::new(Vec3::zeros(), Vec3::new(10.0, 0.0, 0.0)).expect("line"));
    let o = Orientation::tool_axis(&line, Vec3::z(), tilted(40.0, Vec3::y())).expect("o");
    let block = Block::new(1, line, 20.0).with_orientation(o);
    let mut ip = Box::new(Interpolator::<64>::new(InterpConfig::default(), [0.0; 6]).expect("cfg"));
    assert_eq!(
        ip.push(&block),
        Err(PushError::Kinematics(JointError::NoMachine))
    );
    let mut spec = machine("W/caxyBz/T", 0.0, (0, [0.0; 3]));
    spec.rotary_ranges[0] = RotaryRange {
        min: -30.0,
        max: 30.0,
    };
    let mut ip = Box::new(Interpolator::<64>::new(config(spec), [0.0; 6]).expect("cfg"));
    match ip.push(&block) {
        Err(PushError::Kinematics(JointError::Inverse(e))) => {
            assert!(e.to_string().contains('A'), "{e}")
        }
        other => panic!("expected out of range, got {other:?}"),
    }
    assert_eq!(ip.queued_segments(), 0);
}

/// Where the drives' linear joint interpolation is what limits the speed:
/// a part 300 mm from the C axis of a fast table, the tool axis turning on
/// the way. The tip's deviation between setpoints comes close to the chord
/// tolerance and stays within it; with a tight angular tolerance, the axis
/// deviation does the same. Same blocks and config: the same setpoints.
#[test]
fn the_between_setpoint_tolerances_bind_and_hold() {
    let spec = machine("W/caxyBz/T", 40.0, (0, [0.0, 0.0, -20.0]));
    let fast = InterpConfig {
        machine: Some(spec),
        axis_max_velocity: [2000.0; 3],
        axis_max_accel: [40_000.0; 3],
        axis_max_jerk: [2e6; 3],
        rotary_max_velocity: [3600.0; 3],
        rotary_max_accel: [36_000.0; 3],
        rotary_max_jerk: [2e6; 3],
        ..InterpConfig::default()
    };
    let m = Machine::new(spec).expect("machine");
    struct Straight {
        p0: Vec3,
        p1: Vec3,
        a0: Vec3,
        a1: Vec3,
    }
    impl Reference for Straight {
        fn at(&self, tip: Vec3) -> (f64, Vec3) {
            let d = self.p1 - self.p0;
            let t = ((tip - self.p0).dot(&d) / d.norm_squared()).clamp(0.0, 1.0);
            let theta = libm::acos(self.a0.dot(&self.a1));
            let w = (self.a1 - self.a0 * self.a0.dot(&self.a1)).normalize();
            let axis = self.a0 * libm::cos(theta * t) + w * libm::sin(theta * t);
            ((self.p0 + d * t - tip).norm(), axis)
        }
    }
    let s = Straight {
        p0: Vec3::new(300.0, 0.0, 0.0),
        p1: Vec3::new(300.0, 40.0, 0.0),
        a0: tilted(10.0, Vec3::x()),
        a1: tilted(10.0, Vec3::y()),
    };
    let path = Path::Line(Line::new(s.p0, s.p1).expect("line"));
    let o = Orientation::tool_axis(&path, s.a0, s.a1).expect("orientation");
    let block = Block::new(1, path, 200.0).with_orientation(o);
    let start = joints_at(&m, s.p0, s.a0);
    for (cfg, tip_binds) in [
        (fast, true),
        (
            InterpConfig {
                angular_tolerance: 2e-7,
                ..fast
            },
            false,
        ),
    ] {
        let sps = run(&cfg, start, &[block]);
        let rep = check(&cfg, start, &sps, &s);
        assert_within(&cfg, &rep, "far from C");
        if tip_binds {
            assert!(rep.between_tip > 0.5 * cfg.chord_tolerance, "{rep:?}");
            assert_eq!(run(&cfg, start, &[block]), sps, "deterministic");
        } else {
            assert!(rep.between_axis > 0.5 * cfg.angular_tolerance, "{rep:?}");
        }
    }
}

/// A feed hold in the middle of a five-axis block rests on the path with
/// the tool axis on its program, within every joint limit, and resume
/// finishes; an abort rests likewise, and the machine is idle in its own
/// X Y Z (tool-centre-point control off) where a new program starts.
#[test]
fn hold_and_abort_stay_on_the_path_with_the_axis_on_its_program() {
    let spec = machine("W/caxyBz/T", 80.0, (0, [0.0, 0.0, -40.0]));
    let cfg = config(spec);
    let m = Machine::new(spec).expect("machine");
    let h = helix();
    let start = joints_at(&m, h.point(0.0), h.a0);
    let block = h.block(50.0);
    for abort in [false, true] {
        let mut ip: Box<Interpolator> = Box::new(Interpolator::new(cfg, start).expect("cfg"));
        ip.push(&block).expect("push");
        if !abort {
            ip.finish();
        }
        let mut sps = Vec::new();
        for k in 0..200_000 {
            if k == 700 {
                if abort {
                    ip.abort();
                } else {
                    ip.feed_hold();
                }
            }
            if k == 1500 && !abort {
                ip.resume();
            }
            let sp = ip.tick();
            sps.push(sp);
            if matches!(sp.state, RunState::Done)
                || (abort && k > 700 && sp.state == RunState::Idle)
            {
                break;
            }
        }
        let rep = check(&cfg, start, &sps, &h);
        assert_within(&cfg, &rep, if abort { "abort" } else { "hold" });
        let held = if abort {
            sps.last().expect("end")
        } else {
            &sps[1400]
        };
        assert!(abort || held.feed == 0.0, "at rest while held");
        let pose = m.forward(&held.axes);
        assert!(h.at(pose.tip).0 <= ON_PATH_TOL);
        if abort {
            // Idle in the machine's X Y Z: a three-axis move starts there.
            let q = sps.last().expect("end").axes;
            let from = Vec3::new(q[0], q[1], q[2]);
            let next = Block::new(
                9,
                Path::Line(Line::new(from, from + Vec3::new(0.0, 0.0, 5.0)).expect("line")),
                20.0,
            );
            ip.push(&next)
                .expect("a new program from where the machine stands");
            ip.finish();
            let mut last = ip.tick();
            while last.state != RunState::Done {
                last = ip.tick();
            }
            assert_eq!(&last.axes[3..], &q[3..], "rotary axes stay");
            assert!((last.axes[2] - q[2] - 5.0).abs() < 1e-12);
        } else {
            assert_eq!(sps.last().expect("end").state, RunState::Done);
        }
    }
}

/// A block whose rotary axes do not start where the previous one left
/// them is refused (the joints would jump); the G64 smoothing stage passes
/// five-axis blocks through unchanged.
#[test]
fn rotary_jumps_are_refused_and_smoothing_passes_five_axis_blocks() {
    let cfg = InterpConfig::default();
    let l1 = Path::Line(Line::new(Vec3::zeros(), Vec3::new(1.0, 0.0, 0.0)).expect("line"));
    let l2 =
        Path::Line(Line::new(Vec3::new(1.0, 0.0, 0.0), Vec3::new(2.0, 0.1, 0.0)).expect("line"));
    let b1 = Block::new(1, l1, 20.0)
        .with_orientation(Orientation::axes(&l1, [0.0; 3], [10.0, 0.0, 0.0]).expect("axes"));
    let jump = Block::new(2, l2, 20.0).with_orientation(
        Orientation::axes(&l2, [11.0, 0.0, 0.0], [12.0, 0.0, 0.0]).expect("axes"),
    );
    let mut ip = Box::new(Interpolator::<64>::new(cfg, [0.0; 6]).expect("cfg"));
    ip.push(&b1).expect("first");
    match ip.push(&jump) {
        Err(PushError::Kinematics(JointError::Jump(d))) => assert!((d - 1.0).abs() < 1e-12, "{d}"),
        other => panic!("expected a jump, got {other:?}"),
    }
    // Under G64 two short collinear-ish oriented lines are neither merged
    // nor compressed.
    let within = interp_core::path::Blending::Within {
        tolerance: Some(0.05),
    };
    let mut sm: Box<interp_core::Smoother> =
        Box::new(interp_core::Smoother::new(&cfg, 1).expect("smoother"));
    let b2 = Block::new(2, l2, 20.0).with_orientation(
        Orientation::axes(&l2, [10.0, 0.0, 0.0], [12.0, 0.0, 0.0]).expect("axes"),
    );
    // After a change of frame (TCP on) a line starts at the tool tip of
    // the joints, not where the last path ends: its start is kept.
    let l3 = Path::Line(
        Line::new(Vec3::new(2.0, 0.1, -50.0), Vec3::new(3.0, 0.1, -50.0)).expect("line"),
    );
    let b3 = Block::new(3, l3, 20.0)
        .with_orientation(Orientation::tool_axis(&l3, Vec3::z(), Vec3::z()).expect("axis"));
    for b in [b1, b2, b3] {
        sm.push(&b.with_blending(within)).expect("push");
    }
    sm.finish();
    let out: Vec<Block> = core::iter::from_fn(|| sm.pop()).collect();
    assert_eq!(out.len(), 3);
    assert_eq!((out[0].path, out[0].orientation), (b1.path, b1.orientation));
    assert_eq!((out[1].path, out[1].orientation), (b2.path, b2.orientation));
    assert_eq!((out[2].path, out[2].orientation), (b3.path, b3.orientation));
    // Under G61 too (not smoothed: passed as they are).
    let mut sm: Box<interp_core::Smoother> =
        Box::new(interp_core::Smoother::new(&cfg, 1).expect("smoother"));
    for b in [b1, b2, b3] {
        sm.push(&b).expect("push");
    }
    sm.finish();
    let out: Vec<Block> = core::iter::from_fn(|| sm.pop()).collect();
    assert_eq!(
        out.iter().map(|b| b.path).collect::<Vec<_>>(),
        [b1.path, b2.path, b3.path]
    );
}

/// Leaving the pole of a C,A table towards an azimuth C does not stand at
/// would make C jump: refused, naming the jump; leaving it towards where C
/// stands runs with C continuous.
#[test]
fn leaving_the_pole_needs_c_where_the_axis_goes() {
    let spec = machine("W/caxyBz/T", 50.0, (0, [0.0, 0.0, -20.0]));
    let cfg = config(spec);
    let m = Machine::new(spec).expect("machine");
    let (p0, p1) = (Vec3::new(10.0, 0.0, 0.0), Vec3::new(20.0, 0.0, 0.0));
    let path = Path::Line(Line::new(p0, p1).expect("line"));
    // Tilting towards +x from the pole needs C = ±90 (the axis is
    // (sin C sin A, −cos C sin A, cos A)).
    let o = Orientation::tool_axis(&path, Vec3::z(), tilted(20.0, Vec3::x())).expect("o");
    let block = Block::new(1, path, 20.0).with_orientation(o);
    for (c, ok) in [(0.0, false), (90.0, true), (-90.0, true)] {
        let mut start = m
            .inverse(
                &ToolPose {
                    tip: p0,
                    axis: Vec3::z(),
                },
                &[0.0, 0.0, 0.0, 0.0, 0.0, c],
            )
            .expect("ik")
            .joints;
        start[5] = c;
        let mut ip = Box::new(Interpolator::<64>::new(cfg, start).expect("cfg"));
        match (ip.push(&block), ok) {
            (Err(PushError::Kinematics(JointError::PoleDeparture(d))), false) => {
                assert!((d - 90.0).abs() < 1e-6, "{d}")
            }
            (Ok(()), true) => {
                let sps = run(&cfg, start, &[block]);
                for w in sps.windows(2) {
                    assert!((w[1].axes[5] - w[0].axes[5]).abs() < 1e-9, "C moved");
                }
            }
            (r, _) => panic!("C at {c}: {r:?}"),
        }
    }
}

/// The largest angle (rad) of `a` off the plane of the great circle
/// through `a0` and `a1`.
fn off_great_circle(a0: Vec3, a1: Vec3, a: Vec3) -> f64 {
    let n = a0.cross(&a1);
    libm::asin((a.dot(&n) / (n.norm() * a.norm())).abs())
}

/// `G0 A30 C-45` alone, TCP off: X Y Z stand bit for bit while A and C
/// turn in proportion, at the programmed rate in degrees, within every
/// joint's limits; a fast turn is slowed by the rotary joints, not by the
/// path's axes.
#[test]
fn rotary_axes_turn_in_place_without_tcp() {
    let cfg = InterpConfig::default();
    let at = Vec3::new(10.0, 0.0, 0.0);
    let first = Block::new(
        1,
        Path::Line(Line::new(Vec3::zeros(), at).expect("line")),
        50.0,
    );
    let (a, c) = (30.0, -45.0);
    let turn = libm::hypot(a, c);
    let measure = Path::Line(Line::new(at, at + Vec3::x() * turn).expect("measure"));
    let o = Orientation::axes(&measure, [0.0; 3], [a, 0.0, c])
        .expect("axes")
        .in_place(at);
    let after = Block::new(
        3,
        Path::Line(Line::new(at, Vec3::new(10.0, 5.0, 0.0)).expect("line")),
        50.0,
    );
    for feed in [20.0, 1000.0] {
        let turn_block = Block::new(2, measure, feed).with_orientation(o);
        let sps = run(&cfg, [0.0; 6], &[first, turn_block, after]);
        let mut q = vec![[0.0; 6]; 3];
        q.extend(sps.iter().map(|s| s.axes));
        let mut seen = 0;
        let mut fastest = 0.0f64;
        for (i, sp) in sps.iter().enumerate() {
            if sp.block_id == 2 {
                seen += 1;
                assert_eq!(&sp.axes[..3], &[10.0, 0.0, 0.0], "tick {}", sp.seq);
                assert!(
                    (sp.axes[3] / a - sp.axes[5] / c).abs() < 1e-12,
                    "{:?}",
                    sp.axes
                );
                assert_eq!(sp.axes[4], 0.0);
            }
            let prev = q[i + 2];
            let rate = libm::hypot(sp.axes[3] - prev[3], sp.axes[5] - prev[5]) / cfg.period;
            fastest = fastest.max(rate);
        }
        assert!(seen > 10, "the turn took {seen} ticks");
        let end = sps.last().expect("setpoints").axes;
        assert_eq!(end, [10.0, 5.0, 0.0, a, 0.0, c]);
        // A program that ends with the turn: the executor's point (where a
        // new program starts) is where the tool stands, not on the measure.
        let mut ip: Box<Interpolator> = Box::new(Interpolator::new(cfg, [0.0; 6]).expect("config"));
        for b in [first, turn_block] {
            ip.push(&b).expect("queued");
        }
        ip.finish();
        while ip.tick().state != RunState::Done {}
        let st = ip.executor().status();
        assert_eq!(
            (st.point, ip.executor().axes()),
            ([10.0, 0.0, 0.0], [10.0, 0.0, 0.0, a, 0.0, c])
        );
        let ratio = joint_ratios(&cfg, &q);
        for (j, r) in ratio.iter().enumerate() {
            assert!(
                r.iter().all(|&x| x <= 1.0 + LIMIT_REL_TOL),
                "feed {feed}: joint {j}: velocity, acceleration, jerk {r:?} of its limits"
            );
        }
        eprintln!(
            "feed {feed} deg/s: fastest {fastest} deg/s, C at {:?}",
            ratio[5]
        );
        if feed < 100.0 {
            // The programmed rate binds (F in degrees per second here).
            assert!(
                fastest <= feed * (1.0 + 1e-9) && fastest > 0.9 * feed,
                "{fastest}"
            );
        } else {
            // The rotary joints bind: C turns near its speed limit.
            assert!(ratio[5][0] > 0.9, "{:?}", ratio[5]);
        }
    }
}

/// Under TCP a turn in place keeps the tool tip on its point at every
/// setpoint and, with the drives' linear joint interpolation, between
/// them within the chord tolerance, while the tool axis turns on its great
/// circle within the angular tolerance; every joint (the linear ones too,
/// which swing the table's offset) within its limits; a TCP move goes on
/// from the same point.
#[test]
fn the_tool_turns_about_a_fixed_tip_under_tcp() {
    for (chain, centre) in [
        ("W/caxyBz/T", (0, [0.0, 0.0, -50.0])),
        ("W/abxyBz/T", (1, [0.0, 0.0, -30.0])),
    ] {
        let spec = machine(chain, 100.0, centre);
        let cfg = config(spec);
        let m = Machine::new(spec).expect("machine");
        let at = Vec3::new(30.0, 10.0, 5.0);
        let (a0, a1) = (tilted(10.0, Vec3::x()), tilted(40.0, Vec3::y()));
        let start = joints_at(&m, at, a0);
        let theta = libm::acos(a0.dot(&a1)).to_degrees();
        let measure = Path::Line(Line::new(at, at + Vec3::x() * theta).expect("measure"));
        let o = Orientation::tool_axis(&measure, a0, a1)
            .expect("axis")
            .in_place(at);
        let line = Path::Line(Line::new(at, at + Vec3::new(5.0, 0.0, 0.0)).expect("line"));
        let blocks = [
            Block::new(1, measure, 1000.0).with_orientation(o),
            Block::new(2, line, 20.0)
                .with_orientation(Orientation::tool_axis(&line, a1, a1).expect("axis")),
        ];
        let sps = run(&cfg, start, &blocks);
        let angle = |a: Vec3, b: Vec3| libm::atan2(a.cross(&b).norm(), a.dot(&b));
        let (mut tip, mut axis, mut between_tip, mut between_axis) =
            (0.0f64, 0.0f64, 0.0f64, 0.0f64);
        let mut q = vec![start; 3];
        q.extend(sps.iter().map(|s| s.axes));
        let mut turned = 0.0f64;
        for (i, sp) in sps.iter().enumerate().filter(|(_, s)| s.block_id == 1) {
            let pose = m.forward(&sp.axes);
            tip = tip.max((pose.tip - at).norm());
            axis = axis.max(off_great_circle(a0, a1, pose.axis));
            // Monotone from a0 to a1.
            let t = angle(a0, pose.axis);
            assert!(
                t >= turned - 1e-12,
                "the axis turned back at tick {}",
                sp.seq
            );
            turned = t;
            let prev = q[i + 2];
            for p in poses_between(&m, prev, sp.axes) {
                between_tip = between_tip.max((p.tip - at).norm());
                between_axis = between_axis.max(off_great_circle(a0, a1, p.axis));
            }
        }
        eprintln!(
            "{chain}: tip {tip:e}, axis {axis:e}, between {between_tip:e} mm {between_axis:e} rad"
        );
        assert!((turned - theta.to_radians()).abs() < 1e-9, "{turned}");
        assert!(tip <= ON_PATH_TOL && axis <= ON_AXIS_TOL, "{tip} {axis}");
        assert!(
            between_tip <= cfg.chord_tolerance * (1.0 + LIMIT_REL_TOL),
            "{between_tip}"
        );
        assert!(
            between_axis <= cfg.angular_tolerance * (1.0 + LIMIT_REL_TOL),
            "{between_axis}"
        );
        let ratio = joint_ratios(&cfg, &q);
        for (j, r) in ratio.iter().enumerate() {
            assert!(
                r.iter().all(|&x| x <= 1.0 + LIMIT_REL_TOL),
                "{chain}: joint {j} {r:?} of its limits"
            );
        }
        let end = m.forward(&sps.last().expect("setpoints").axes);
        assert!((end.tip - (at + Vec3::new(5.0, 0.0, 0.0))).norm() < 1e-9);
        assert!(angle(end.axis, a1) < 1e-12);
    }
}
