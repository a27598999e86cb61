//! The five-axis example program (`examples/five_axis/frustum.ngc`, the
//! flank of a cone frustum under G43.5 on a C,A table) from G-code text to
//! joints, checked against the program text itself: every setpoint's tool
//! tip (forward transform of its joints) on the programmed move, its tool
//! axis on the great circle between the move's I J K vectors, every joint
//! within its limits (`interp_run::check`, the one setpoint checker), the
//! program finished.

use gcode::{BlockKind, Orientation};
use interp_core::InterpConfig;
use interp_core::kinematics::Machine;
use interp_core::{RunState, Vec3};
use interp_run::check::{Checker, Limits};
use interpd_tests::five_axis::{example_dir, machine_from_toml, run_program};

#[test]
fn the_frustum_example_runs_on_its_machine_within_its_program_and_limits() {
    let dir = example_dir();
    let spec = machine_from_toml(&std::fs::read_to_string(dir.join("machine.toml")).unwrap())
        .expect("machine");
    let text = std::fs::read_to_string(dir.join("frustum.ngc")).unwrap();
    let cfg = InterpConfig {
        machine: Some(spec),
        ..InterpConfig::default()
    };
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
    let mut moves = std::collections::HashMap::new();
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
    let tcp: std::collections::HashMap<u32, bool> =
        run.blocks.iter().map(|b| (b.id, b.is_tcp())).collect();
    let mut check = Checker::five_axis(
        cfg.period,
        Limits::new(&cfg, cfg.max_path_speed),
        m,
        run.start,
    );
    for sp in &run.setpoints {
        check.check_in_frame(sp, tcp.get(&sp.block_id).copied().unwrap_or(false));
    }
    check.finish(Some([0.0, 0.0, 150.0]));
    check.assert_clean("the frustum example");
    // The rotary joints moved: C round the whole circle, A to the lean.
    assert!(
        check.measured.rotary_velocity_deg_s[2] > 10.0,
        "{:?}",
        check.measured
    );
    assert!(
        check.measured.rotary_velocity_deg_s[0] > 1.0,
        "{:?}",
        check.measured
    );
}
