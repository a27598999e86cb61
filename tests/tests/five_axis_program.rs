//! The five-axis example program (`examples/five_axis/frustum.ngc`, the
//! flank of a cone frustum under G43.5 on a C,A table) from G-code text to
//! joints, checked against the program text itself: every setpoint's tool
//! tip (forward transform of its joints) on the programmed move, its tool
//! axis on the great circle between the move's I J K vectors, every joint
//! within its limits (`interp_run::check`, the one setpoint checker), the
//! program finished.

use gcode::{BlockKind, Orientation};
use std::collections::HashMap;

use interp_core::kinematics::Machine;
use interp_core::{InterpConfig, RunState, Setpoint, Vec3};
use interp_run::check::{Checker, Limits, Measured};
use interpd_tests::five_axis::{
    SimulatedRun, example_config, example_dir, run_program, simulate_program,
};

#[test]
fn the_frustum_example_runs_on_its_machine_within_its_program_and_limits() {
    let dir = example_dir();
    let cfg = example_config();
    let spec = cfg.machine.expect("machine");
    let text = std::fs::read_to_string(dir.join("frustum.ngc")).unwrap();
    let run = run_program(cfg, &text).expect("runs");
    let m = Machine::new(spec).unwrap();
    let last = run.setpoints.last().unwrap();
    assert_eq!(last.state, RunState::Done);
    // The last move (after G49) ends at machine X0 Y0 Z150.
    assert!(
        (Vec3::new(last.axes[0], last.axes[1], last.axes[2]) - Vec3::new(0.0, 0.0, 150.0)).norm()
            < 1e-9
    );

    // The program's own moves under G43.5, by line: start, end, tool vectors.
    let program = gcode::parse(&text).unwrap();
    let mut moves = HashMap::new();
    let mut prev_tcp = false;
    for b in &program.blocks {
        let (start, end, o) = match &b.kind {
            BlockKind::Linear(l) => (l.start, l.end, l.orientation),
            BlockKind::Rapid(r) => (r.start, r.end, r.orientation),
            _ => continue,
        };
        let Orientation::TcpVector { start: a0, end: a1 } = o else {
            prev_tcp = false;
            continue;
        };
        // The first move under TCP starts where the machine's tip is, not
        // at the programmed start: its axis is checked, not its line.
        let from_tip = !prev_tcp;
        prev_tcp = true;
        let v = |p: [f64; 3]| Vec3::new(p[0], p[1], p[2]);
        moves.insert(b.line, (v(start), v(end), a0.map(v), a1.map(v), from_tip));
    }
    assert!(moves.len() >= 74, "{} moves under TCP", moves.len());
    let mut checked = 0;
    let mut last_axis = None;
    for sp in &run.setpoints {
        let Some(&(p0, p1, a0, a1, from_tip)) = moves.get(&sp.block_id) else {
            continue;
        };
        if from_tip {
            last_axis = a1;
            continue;
        }
        let pose = m.forward(&sp.axes);
        let a0 = a0.or(last_axis).expect("a tool vector before");
        let a1 = a1.unwrap_or(a0);
        let d = p1 - p0;
        let t = ((pose.tip - p0).dot(&d) / d.norm_squared()).clamp(0.0, 1.0);
        assert!(
            (p0 + d * t - pose.tip).norm() < 1e-9,
            "line {}: tip off its move",
            sp.block_id
        );
        let (u0, u1) = (a0.normalize(), a1.normalize());
        // (atan2, not acos: acos loses half the digits near 0.)
        let theta = u0.cross(&u1).norm().atan2(u0.dot(&u1));
        let want = if theta > 0.0 {
            let w = (u1 - u0 * u0.dot(&u1)).normalize();
            u0 * (theta * t).cos() + w * (theta * t).sin()
        } else {
            u0
        };
        assert!(
            (pose.axis - want).norm() < 1e-9,
            "line {}: axis {:?} off its program {want:?} ({a0:?} to {a1:?} at {t})",
            sp.block_id,
            pose.axis
        );
        last_axis = Some(a1);
        checked += 1;
    }
    assert!(checked > 1000, "{checked} setpoints checked");

    // Every setpoint through the one setpoint checker: every joint's
    // velocity, acceleration and jerk within its limit (X Y Z and A B C),
    // the path speed, acceleration and jerk, the chord speed of the tool
    // tip under TCP (of X Y Z off it), and the end exactly at X0 Y0 Z150.
    let tcp: HashMap<u32, bool> = run.blocks.iter().map(|b| (b.id, b.is_tcp())).collect();
    let measured = check_setpoints(
        &cfg,
        m,
        run.start,
        &run.setpoints,
        &tcp,
        [0.0, 0.0, 150.0],
        "the frustum example",
    );
    // The rotary joints moved: C round the whole circle, A to the lean.
    assert!(measured.rotary_velocity_deg_s[2] > 10.0, "{measured:?}");
    assert!(measured.rotary_velocity_deg_s[0] > 1.0, "{measured:?}");
}

/// Rotary-only moves end to end (G-code text → `traces::Program` →
/// `traces::sim::run`, the `interpd simulate` pipeline with its `G64 P`
/// stage): without TCP `G0 A.. C..` and `G1 A.. F..` turn the rotary axes
/// with X Y Z standing bit for bit, F in deg/min; under G43.4 `G1 A..`
/// alone keeps the tool tip on its point while the table tilts and X Y Z
/// follow; every setpoint through the setpoint checker (every joint's
/// velocity, acceleration and jerk), and the rotary axes end where the
/// program puts them.
#[test]
fn rotary_only_moves_turn_in_place_through_simulate() {
    let cfg = example_config();
    let spec = cfg.machine.expect("machine");
    let text = "G21 G90 G94 G61\n\
        G0 X20 Y0 Z60 A0 C0\n\
        G0 A30 C-60\n\
        G1 C-30 F1800\n\
        G1 X25\n\
        G43.4\n\
        G1 X25 Y0 Z10 F600\n\
        G1 A10\n\
        G1 X30\n\
        G49\n\
        G0 X0 Y0 Z100\n\
        M2\n";
    let SimulatedRun {
        program,
        config,
        setpoints: sps,
    } = simulate_program(cfg, text, "rotary-only").expect("runs");
    let m = Machine::new(spec).unwrap();
    let last = sps.last().unwrap();
    assert_eq!(last.state, RunState::Done);
    assert_eq!(&last.axes[..3], &[0.0, 0.0, 100.0]);

    // Setpoints name segments; their source lines (G61: the `G64 P` stage
    // passes every block, numbered as cut).
    let expanded = expand(&program);
    let mut line_of = HashMap::new();
    let mut tcp = HashMap::new();
    for b in &expanded.blocks {
        for seg in &b.segments {
            line_of.insert(seg.id, b.input.source_line.unwrap());
            tcp.insert(seg.id, seg.is_tcp());
        }
    }
    let line_of = &line_of;
    let on = |line: u32| {
        sps.iter()
            .filter(move |s| line_of.get(&s.block_id) == Some(&line))
    };
    // Line 3, G0 A30 C-60: X Y Z stand; A and C in proportion.
    assert!(on(3).count() > 10);
    for sp in on(3) {
        assert_eq!(&sp.axes[..3], &[20.0, 0.0, 60.0]);
        assert!(
            (sp.axes[3] / 30.0 - sp.axes[5] / -60.0).abs() < 1e-12,
            "{:?}",
            sp.axes
        );
    }
    // Line 4, G1 C-30 F1800: 30 deg/s at most, and C ends at -30.
    let mut prev = None;
    for sp in on(4) {
        assert_eq!(&sp.axes[..4], &[20.0, 0.0, 60.0, 30.0]);
        if let Some(p) = prev {
            let rate = (sp.axes[5] - p) / cfg.period;
            assert!(rate <= 30.0 * (1.0 + 1e-9), "C at {rate} deg/s");
        }
        prev = Some(sp.axes[5]);
    }
    assert_eq!(prev, Some(-30.0));
    // Line 8, G1 A10 under G43.4: the tip stands where line 7 left it
    // while A tilts from 30 to 10 (and X Y Z follow the table).
    let tip = Vec3::new(25.0, 0.0, 10.0);
    assert!(on(8).count() > 10);
    let mut moved = 0.0f64;
    for sp in on(8) {
        let pose = m.forward(&sp.axes);
        assert!((pose.tip - tip).norm() < 1e-9, "tip {:?}", pose.tip);
        moved = moved.max((sp.axes[2] - on(8).next().unwrap().axes[2]).abs());
    }
    assert!(moved > 1.0, "Z followed the table by {moved} mm");
    let end8 = on(8).next_back().unwrap().axes;
    assert!(
        (end8[3] - 10.0).abs() < 1e-9 && (end8[5] + 30.0).abs() < 1e-9,
        "{end8:?}"
    );

    check_setpoints(
        &cfg,
        m,
        [0.0; 6],
        &sps,
        &tcp,
        [0.0, 0.0, 100.0],
        "rotary-only moves",
    );
    // The trace summary measures a turn's chord error on the point the
    // tool stands on (not on the turn's measure, degrees away).
    let segments = traces::sim::smoothed_segments(&expanded, &config.interp).unwrap();
    let mut analyzer = traces::analysis::Analyzer::new(&config, expanded.blocks.len(), &segments);
    for sp in &sps {
        analyzer.push(sp);
    }
    let summary = analyzer.summary();
    assert!(
        summary.max_chord_error_mm <= cfg.chord_tolerance,
        "chord error {} mm at tick {}",
        summary.max_chord_error_mm,
        summary.max_chord_error_seq
    );
    // A turn's speed is deg/s: the summary keeps it apart from the paths'
    // mm/s (each the largest of its own setpoints' feeds).
    let in_place: std::collections::HashSet<u32> = segments
        .iter()
        .filter(|b| b.is_in_place())
        .map(|b| b.id)
        .collect();
    let largest = |turns: bool| {
        sps.iter()
            .filter(|s| in_place.contains(&s.block_id) == turns)
            .map(|s| s.feed)
            .fold(0.0, f64::max)
    };
    assert_eq!(summary.max_feed_mm_s, largest(false));
    assert_eq!(summary.max_turn_speed_deg_s, Some(largest(true)));
    // (The G0 turn runs at C's speed limit, well above the G1 paths' feeds.)
    assert!(largest(true) > 100.0, "{summary:?}");
    assert!(summary.to_string().contains("deg/s"), "{summary}");
}

/// A G6.2 with A and C on its control points: 12 control points in the XY
/// plane at Z0, rational, cubic, uneven knots, A and C changing along it,
/// starting at X0 Y0 A0 C0. Its program lines (`G6.2 … K…`) and data.
struct RotaryCurve {
    p: usize,
    pts: Vec<[f64; 2]>,
    rot: Vec<[f64; 2]>,
    ws: Vec<f64>,
    knots: Vec<f64>,
}

impl RotaryCurve {
    fn new() -> Self {
        let (n, p) = (12, 3);
        let pts: Vec<[f64; 2]> = (0..n)
            .map(|i| {
                let t = i as f64;
                [6.0 * t, 10.0 * (0.5 * t).sin()]
            })
            .collect();
        let rot: Vec<[f64; 2]> = (0..n)
            .map(|i| {
                let t = i as f64;
                [8.0 * (0.4 * t).sin(), 5.0 * t]
            })
            .collect();
        let ws: Vec<f64> = (0..n)
            .map(|i| 1.0 + 0.4 * (1.3 * i as f64).cos().abs())
            .collect();
        let mut knots = vec![0.0; p + 1];
        for j in 0..n - p - 1 {
            knots.push(j as f64 + 1.0 + 0.25 * (j % 3) as f64);
        }
        let end = knots[knots.len() - 1] + 1.0;
        knots.extend([end; 4]);
        RotaryCurve {
            p,
            pts,
            rot,
            ws,
            knots,
        }
    }

    fn text(&self) -> String {
        use std::fmt::Write as _;
        let n = self.pts.len();
        let mut text = format!("G6.2 P{}", self.p + 1);
        for i in 0..n {
            if i > 0 {
                text.push('\n');
            }
            write!(
                text,
                " X{} Y{} A{} C{} R{} K{}",
                self.pts[i][0],
                self.pts[i][1],
                self.rot[i][0],
                self.rot[i][1],
                self.ws[i],
                self.knots[i]
            )
            .unwrap();
        }
        text.push('\n');
        for k in &self.knots[n..] {
            writeln!(text, "G6.2 K{k}").unwrap();
        }
        text
    }

    /// X Y and A C of the program's curves at `u`, by the definition of a
    /// NURBS (`Σ Nᵢ·wᵢ·Pᵢ / Σ Nᵢ·wᵢ`).
    fn at(&self, u: f64) -> ([f64; 2], [f64; 2]) {
        let p = self.p;
        let (span, nb) = interp_core::nurbs::basis_functions(p, &self.knots, u);
        let (mut rot, mut den, mut xy) = ([0.0; 2], 0.0, [0.0; 2]);
        for k in 0..=p {
            let i = span - p + k;
            let wn = nb[k] * self.ws[i];
            for j in 0..2 {
                rot[j] += wn * self.rot[i][j];
                xy[j] += wn * self.pts[i][j];
            }
            den += wn;
        }
        (xy.map(|v| v / den), rot.map(|v| v / den))
    }
}

/// `program` cut into the segments the setpoints name, as
/// `traces::sim::run` cuts it.
fn expand(program: &traces::Program) -> traces::blocks::Expanded {
    program
        .expand(
            traces::sim::SimSettings::default().max_ctrl_per_block,
            traces::sim::FIRST_BLOCK_ID,
        )
        .unwrap()
}

/// The ids of the blocks of `program` that are pieces of its NURBS.
fn curve_ids(program: &traces::Program) -> std::collections::HashSet<u32> {
    expand(program)
        .segments()
        .filter(|b| matches!(b.path, interp_core::Path::Nurbs(_)))
        .map(|b| b.id)
        .collect()
}

/// Whether each segment of `program` is under tool-centre-point control.
fn tcp_blocks(program: &traces::Program) -> HashMap<u32, bool> {
    expand(program)
        .segments()
        .map(|b| (b.id, b.is_tcp()))
        .collect()
}

/// Every setpoint through the one setpoint checker, each in its segment's
/// frame (the tool tip where `tcp` says the segment is under TCP, X Y Z
/// elsewhere), from `start` to the end at `end`: panics naming `what` on
/// any breach; returns what the checker measured.
fn check_setpoints(
    cfg: &InterpConfig,
    m: Machine,
    start: [f64; 6],
    sps: &[Setpoint],
    tcp: &HashMap<u32, bool>,
    end: [f64; 3],
    what: &str,
) -> Measured {
    let mut check = Checker::five_axis(cfg.period, Limits::new(cfg, cfg.max_path_speed), m, start);
    for sp in sps {
        check.check_in_frame(sp, tcp.get(&sp.block_id).copied().unwrap_or(false));
    }
    check.finish(Some(end));
    check.assert_clean(what);
    check.measured
}

/// G6.2 with A and C on its control points (TCP off) from G-code text
/// through `traces::sim::run` (the JSON block form and the `simulate`
/// pipeline): at every setpoint the rotary joints are the program's
/// rotary NURBS at the setpoint's parameter (`Σ Nᵢ·wᵢ·rᵢ / Σ Nᵢ·wᵢ`,
/// within 1e-9°), X Y Z its curve, every joint within its limits (the
/// setpoint checker), and the axes end on the last control point.
#[test]
fn g6_2_rotary_coordinates_run_as_coordinates_of_the_curve() {
    let c = RotaryCurve::new();
    let (n, p) = (c.pts.len(), c.p);
    let (pts, rot) = (&c.pts, &c.rot);
    let text = format!(
        "G21 G90 G94 G61\nG0 X0 Y0 Z20\nG1 Z0 F600\n{}M2\n",
        c.text()
    );
    let cfg = example_config();
    let spec = cfg.machine.expect("machine");
    let SimulatedRun {
        program,
        setpoints: sps,
        ..
    } = simulate_program(cfg, &text, "g6.2 rotary").expect("runs");
    let curve_ids = curve_ids(&program);
    assert_eq!(curve_ids.len(), n - p, "one block per knot span");
    let (mut worst, mut on_curve) = (0.0f64, 0);
    for sp in sps.iter().filter(|s| curve_ids.contains(&s.block_id)) {
        let (xy, r) = c.at(sp.u);
        worst = worst
            .max((sp.axes[3] - r[0]).abs())
            .max((sp.axes[5] - r[1]).abs())
            .max((sp.axes[0] - xy[0]).abs())
            .max((sp.axes[1] - xy[1]).abs());
        on_curve += 1;
    }
    assert!(on_curve > 500, "{on_curve}");
    assert!(worst < 1e-9, "joints off the program's curves by {worst}");
    let last = sps.last().unwrap();
    assert_eq!(last.state, RunState::Done);
    assert_eq!(
        [last.axes[3], last.axes[5]],
        rot[n - 1],
        "the axes end on the last control point"
    );
    let measured = check_setpoints(
        &cfg,
        Machine::new(spec).unwrap(),
        [0.0; 6],
        &sps,
        &HashMap::new(),
        [pts[n - 1][0], pts[n - 1][1], 0.0],
        "G6.2 with rotary coordinates",
    );
    assert!(measured.rotary_velocity_deg_s[2] > 1.0, "{measured:?}");
}

/// The same G6.2 under G43.4 (issue 19): X Y Z are the tool tip in the
/// workpiece frame and A C the rotary positions, both coordinates of the
/// one NURBS. Through `traces::sim::run`, at every setpoint on the curve
/// the tip (the forward transform of the joints) is the program's curve at
/// the setpoint's parameter and A C its rotary curve there (within 1e-9),
/// every joint within its limits and the tip's chord speed within the
/// path's (the setpoint checker, in the tip's frame), the run done.
#[test]
fn g6_2_rotary_coordinates_under_g43_4_move_the_tip_on_the_curve() {
    let c = RotaryCurve::new();
    let (n, p) = (c.pts.len(), c.p);
    let text = format!(
        "G21 G90 G94 G61\nG0 X0 Y0 Z120 A0 C0\nG43.4 H1\nG1 X0 Y0 Z0 F600\n{}G49\nG0 X0 Y0 Z150\nM2\n",
        c.text()
    );
    let cfg = example_config();
    let spec = cfg.machine.expect("machine");
    let SimulatedRun {
        program,
        setpoints: sps,
        ..
    } = simulate_program(cfg, &text, "g6.2 rotary under G43.4").expect("runs");
    let m = Machine::new(spec).unwrap();
    let curve_ids = curve_ids(&program);
    assert_eq!(curve_ids.len(), n - p, "one block per knot span");
    let (mut tip_off, mut rot_off, mut on_curve) = (0.0f64, 0.0f64, 0);
    for sp in sps.iter().filter(|s| curve_ids.contains(&s.block_id)) {
        let (xy, r) = c.at(sp.u);
        let tip = m.forward(&sp.axes).tip;
        tip_off = tip_off.max((tip - Vec3::new(xy[0], xy[1], 0.0)).norm());
        rot_off = rot_off
            .max((sp.axes[3] - r[0]).abs())
            .max((sp.axes[5] - r[1]).abs());
        on_curve += 1;
    }
    assert!(on_curve > 500, "{on_curve}");
    assert!(
        tip_off < 1e-9,
        "tip off the program's curve by {tip_off} mm"
    );
    assert!(
        rot_off < 1e-9,
        "A C off the rotary curve by {rot_off} degrees"
    );
    assert_eq!(sps.last().unwrap().state, RunState::Done);
    let tcp = tcp_blocks(&program);
    assert!(curve_ids.iter().all(|id| tcp[id]), "the curve is under TCP");
    let measured = check_setpoints(
        &cfg,
        m,
        [0.0; 6],
        &sps,
        &tcp,
        [0.0, 0.0, 150.0],
        "G6.2 with rotary coordinates under G43.4",
    );
    assert!(measured.rotary_velocity_deg_s[2] > 1.0, "{measured:?}");
}

/// The same curve under G43.5 with a tool vector `U V W` on each control
/// point (issue 19: a second curve for the tool axis), each the direction
/// tilted `12 + A` degrees from +z towards azimuth `C` of the curve's
/// rotary values, 1.2 long where the index is odd. Through the JSON block
/// form (written and read back) and `traces::sim::run`: at every setpoint
/// on the curve the tip is the program's curve at the setpoint's
/// parameter and the tool axis the vectors' NURBS there, normalised
/// (within 1e-9), every joint within its limits, the run done.
#[test]
fn g6_2_tool_vectors_under_g43_5_turn_the_axis_on_their_curve() {
    use std::fmt::Write as _;
    let c = RotaryCurve::new();
    let (n, p) = (c.pts.len(), c.p);
    let vectors: Vec<[f64; 3]> = c
        .rot
        .iter()
        .enumerate()
        .map(|(i, r)| {
            let (tilt, azimuth) = ((12.0 + r[0]).to_radians(), r[1].to_radians());
            let len = if i % 2 == 1 { 1.2 } else { 1.0 };
            [
                len * tilt.sin() * azimuth.cos(),
                len * tilt.sin() * azimuth.sin(),
                len * tilt.cos(),
            ]
        })
        .collect();
    let mut text = format!(
        "G21 G90 G94 G61\nG0 X0 Y0 Z120 A0 C-90\nG43.5 H1\nG1 X0 Y0 Z5 I{} J{} K{} F600\nG6.2 P{}",
        vectors[0][0],
        vectors[0][1],
        vectors[0][2],
        p + 1
    );
    for i in 0..n {
        if i > 0 {
            text.push('\n');
        }
        let v = vectors[i];
        write!(
            text,
            " X{} Y{} Z0 U{} V{} W{} R{} K{}",
            c.pts[i][0], c.pts[i][1], v[0], v[1], v[2], c.ws[i], c.knots[i]
        )
        .unwrap();
    }
    text.push('\n');
    for k in &c.knots[n..] {
        writeln!(text, "G6.2 K{k}").unwrap();
    }
    text.push_str("G49\nG0 X0 Y0 Z150\nM2\n");
    let cfg = example_config();
    let spec = cfg.machine.expect("machine");
    let SimulatedRun {
        program,
        setpoints: sps,
        ..
    } = simulate_program(cfg, &text, "g6.2 tool vectors under G43.5").expect("runs");
    // The block form carries the vectors through its JSON.
    let json = serde_json::to_string(&program).unwrap();
    assert!(json.contains("tool_axes"), "{json}");
    assert_eq!(
        serde_json::from_str::<traces::Program>(&json).unwrap(),
        program
    );
    let m = Machine::new(spec).unwrap();
    let curve_ids = curve_ids(&program);
    assert_eq!(curve_ids.len(), n - p, "one block per knot span");
    let axis_at = |u: f64| {
        let (span, nb) = interp_core::nurbs::basis_functions(p, &c.knots, u);
        let mut v = Vec3::zeros();
        for k in 0..=p {
            let i = span - p + k;
            v += Vec3::from(vectors[i]) * (nb[k] * c.ws[i]);
        }
        v.normalize()
    };
    let (mut tip_off, mut axis_off, mut on_curve) = (0.0f64, 0.0f64, 0);
    for sp in sps.iter().filter(|s| curve_ids.contains(&s.block_id)) {
        let (xy, _) = c.at(sp.u);
        let pose = m.forward(&sp.axes);
        tip_off = tip_off.max((pose.tip - Vec3::new(xy[0], xy[1], 0.0)).norm());
        let want = axis_at(sp.u);
        axis_off = axis_off.max(pose.axis.cross(&want).norm().atan2(pose.axis.dot(&want)));
        on_curve += 1;
    }
    assert!(on_curve > 500, "{on_curve}");
    assert!(
        tip_off < 1e-9,
        "tip off the program's curve by {tip_off} mm"
    );
    assert!(
        axis_off < 1e-9,
        "axis off the vector curve by {axis_off} rad"
    );
    assert_eq!(sps.last().unwrap().state, RunState::Done);
    let tcp = tcp_blocks(&program);
    assert!(curve_ids.iter().all(|id| tcp[id]), "the curve is under TCP");
    let measured = check_setpoints(
        &cfg,
        m,
        [0.0; 6],
        &sps,
        &tcp,
        [0.0, 0.0, 150.0],
        "G6.2 with tool vectors under G43.5",
    );
    // The tool really turns: A (tilt) and C (azimuth) both move.
    assert!(
        measured.rotary_velocity_deg_s[0] > 1.0 && measured.rotary_velocity_deg_s[2] > 1.0,
        "{measured:?}"
    );
}
