//! `interpd plan raster` refuses flags that would write a wrong program
//! (F0, FNaN, rapids below the part) or exhaust memory (a tolerance below
//! what f64 resolves), naming the flag, and writes nothing; `interpd plan
//! setup --json` prints what a program needs to position the rotary axes.

use std::path::{Path, PathBuf};
use std::process::Command;

/// A 20 × 20 mm plate 2 mm high, as an ASCII STL.
fn plate(dir: &Path) -> PathBuf {
    use planner::mesh::P3;
    let p = |x, y| P3::new(x, y, 2.0);
    let soup = [
        [p(0.0, 0.0), p(20.0, 0.0), p(20.0, 20.0)],
        [p(0.0, 0.0), p(20.0, 20.0), p(0.0, 20.0)],
    ];
    let path = dir.join("plate.stl");
    std::fs::write(&path, planner::mesh::ascii_stl("plate", &soup)).unwrap();
    path
}

/// A fresh directory named `tag` holding the sample teapot as an ASCII STL:
/// `(directory, STL path)`.
fn teapot_stl(tag: &str) -> (PathBuf, PathBuf) {
    let dir = std::env::temp_dir().join(format!("interpd-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let stl = dir.join("teapot.stl");
    let teapot = planner::setup::samples::teapot(10, 12, 5, 6);
    std::fs::write(&stl, planner::mesh::ascii_stl("teapot", &teapot)).unwrap();
    (dir, stl)
}

#[test]
fn plan_raster_refuses_bad_feeds_clearances_and_tolerances_naming_the_flag() {
    let dir = std::env::temp_dir().join(format!("interpd-plan-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let stl = plate(&dir);
    let out = dir.join("out.ngc");
    let run = |extra: &[&str]| {
        let _ = std::fs::remove_file(&out);
        let o = Command::new(env!("CARGO_BIN_EXE_interpd"))
            .args([
                "plan",
                "raster",
                "--quiet",
                "--tool",
                "ball:4",
                "--stepover",
                "2",
            ])
            .arg("--stl")
            .arg(&stl)
            .arg("--out")
            .arg(&out)
            .args(extra)
            .output()
            .unwrap();
        (
            o.status.success(),
            String::from_utf8_lossy(&o.stderr).into_owned(),
        )
    };
    // Refused by the flag's range (`interpd::flags`), named with it.
    let range = |flag: &str, value: &str, range: &str| {
        format!("invalid value '{value}' for '{flag} <")
            + &format!(
                "{}>': {value} is outside {range}",
                flag[2..].to_uppercase().replace('-', "_")
            )
    };
    let feed = "(0, 120000] mm/min";
    let plan_mm = "(0, 10] mm";
    let plan_mm0 = "[0, 10] mm";
    for (flags, says) in [
        (&["--feed", "0"][..], range("--feed", "0", feed)),
        (&["--feed=-5"][..], range("--feed", "-5", feed)),
        (&["--feed", "nan"][..], range("--feed", "nan", feed)),
        (&["--feed", "1e308"][..], range("--feed", "1e308", feed)),
        (
            &["--plunge-feed", "inf"][..],
            range("--plunge-feed", "inf", feed),
        ),
        (
            &["--clearance=-100"][..],
            range("--clearance", "-100", "[0, 1000] mm"),
        ),
        (
            &["--clearance", "1e308"][..],
            range("--clearance", "1e308", "[0, 1000] mm"),
        ),
        (
            &["--angle", "1e9"][..],
            range("--angle", "1e9", "[-360, 360] degrees"),
        ),
        (
            &["--blend-tolerance=-0.001"][..],
            range("--blend-tolerance", "-0.001", plan_mm0),
        ),
        (
            &["--blend-tolerance", "nan"][..],
            range("--blend-tolerance", "nan", plan_mm0),
        ),
        (
            &["--weld-tolerance", "1e308"][..],
            range("--weld-tolerance", "1e308", plan_mm0),
        ),
        (
            &["--chord-tolerance", "1e308"][..],
            range("--chord-tolerance", "1e308", plan_mm),
        ),
        (
            &["--chord-tolerance", "1e-15"][..],
            "--chord-tolerance 0.000000000000001 mm is below what f64 resolves".to_owned(),
        ),
    ] {
        let (ok, err) = run(flags);
        assert!(!ok, "{flags:?} accepted");
        assert!(err.contains(&says), "{flags:?}: {err}");
        assert!(!out.exists(), "{flags:?} wrote {}", out.display());
    }
    // The same run with sane flags writes a program above the part.
    let (ok, err) = run(&["--feed", "1200", "--clearance", "3"]);
    assert!(ok, "{err}");
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(text.contains("F1200"), "{text}");
    // Dense moves run at speed: G64 P (1 µm by default) before any move;
    // `--blend-tolerance 0` leaves the controller's exact path.
    assert!(text.contains("G64 P0.001"), "{text}");
    let (ok, err) = run(&["--blend-tolerance", "0"]);
    assert!(ok, "{err}");
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(!text.contains("G64"), "{text}");
    std::fs::remove_dir_all(&dir).ok();
}

/// `interpd plan setup --json` bridges the setup to the loop: with the
/// setup it prints its certificate (no setup needs less area), how many
/// setups are as good and how far apart, and the rotary axis positions, in
/// the machine's own axes, that turn the part so that the spindle is along
/// the found tool axis (3+2) — checked here through the machine's
/// kinematics (eq. 2), for a C,A and an A,B machine.
#[test]
fn plan_setup_json_prints_the_certificate_equivalents_and_rotary_positions() {
    use interp_core::kinematics::{Machine, MachineSpec};
    use planner::setup::MachineConfig;
    let (dir, stl) = teapot_stl("plan-setup-cli");
    for (machine, names) in [("W/caxyBz/T", ["C", "A"]), ("W/baxzBy/T", ["B", "A"])] {
        let out = Command::new(env!("CARGO_BIN_EXE_interpd"))
            .args([
                "plan",
                "setup",
                "--machine",
                machine,
                "--ranges",
                "90,90,180,180",
            ])
            .arg("--stl")
            .arg(&stl)
            .arg("--json")
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(json["feasible"], true, "{json:#}");
        assert!(json["evaluated_cells"].as_u64().unwrap() > 0);
        assert!(json["narrow_patches"].is_u64());
        let setup = &json["setup"];
        let num = |v: &serde_json::Value| v.as_f64().unwrap();
        let (area, lower, gap) = (
            num(&setup["area_deg2"]),
            num(&setup["lower_bound_deg2"]),
            num(&setup["gap_deg2"]),
        );
        assert!(
            lower <= area && (area - lower - gap).abs() < 1e-9,
            "{setup:#}"
        );
        // C,A answers are exact; A,B ones within the turn's resolution, far
        // below the one-cell equivalence tolerance.
        let tolerance = num(&setup["equivalent"]["area_tolerance_deg2"]);
        assert!(gap <= tolerance / 4.0, "{setup:#}");
        assert!(setup["equivalent"]["count"].is_u64());
        assert!(num(&setup["equivalent"]["max_axis_angle_deg"]) >= 0.0);
        // The rotary positions turn the tool axis onto the found one.
        let positions = setup["rotary_positions"].as_array().unwrap();
        let got: Vec<&str> = positions
            .iter()
            .map(|p| p["axis"].as_str().unwrap())
            .collect();
        assert_eq!(got, names, "{machine}");
        assert_eq!(setup["rotary_positions_within_ranges"], true);
        // Forward through the machine's own chain: the joints at home but
        // the two rotary axes where the JSON says.
        let config = machine.parse::<MachineConfig>().unwrap();
        let kin = Machine::new(MachineSpec::new(*config.chain())).unwrap();
        let mut joints = [0.0; 6];
        let (r1, r2) = config.roles();
        joints[r1.joint()] = num(&positions[0]["deg"]);
        joints[r2.joint()] = num(&positions[1]["deg"]);
        let reached = kin.forward(&joints).axis;
        let q = [joints[r1.joint()], joints[r2.joint()]].map(f64::to_radians);
        let axis: Vec<f64> = setup["tool_axis"]
            .as_array()
            .unwrap()
            .iter()
            .map(num)
            .collect();
        for k in 0..3 {
            assert!(
                (reached[k] - axis[k]).abs() < 1e-9,
                "{machine}: {reached:?} vs {axis:?}"
            );
        }
        // The teapot's setup tilts toward its spout: the rotary axes move.
        assert!(
            q.iter().any(|a| a.abs() > 1f64.to_radians()),
            "{machine}: {q:?}"
        );
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// 3+2 from `plan setup`: the rotary positions its JSON prints, given to
/// the machine as `G0 C.. A..` (a turn in place), then a three-axis
/// program run as `interpd simulate` runs it (`traces::sim::run`, the
/// example's C,A table with its offsets): once the axes stand, the tool
/// axis in the workpiece frame (the forward transform of every setpoint's
/// joints) is the setup's tool axis on every tick, and the tool tip runs
/// on the program's moves as the part, turned by the setup, sees them (the
/// images of the programmed points under the fixed rotary axes: the
/// machine's X Y Z on the programmed line at the same fraction).
#[test]
fn plan_setup_positions_the_rotary_axes_for_a_three_axis_cut() {
    use interp_core::InterpConfig;
    use interp_core::kinematics::{Machine, MachineSpec};
    use interp_core::{RunState, Vec3};
    use std::fmt::Write as _;
    let (dir, stl) = teapot_stl("plan-setup-32");
    let out = Command::new(env!("CARGO_BIN_EXE_interpd"))
        .args(["plan", "setup", "--machine", "W/caxyBz/T"])
        .args(["--ranges", "90,90,180,180", "--json", "--stl"])
        .arg(&stl)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    std::fs::remove_dir_all(&dir).ok();
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let setup = &json["setup"];
    let p: Vec<f64> = setup["tool_axis"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    let p = Vec3::new(p[0], p[1], p[2]);
    let mut words = String::new();
    for pos in setup["rotary_positions"].as_array().unwrap() {
        write!(
            words,
            " {}{}",
            pos["axis"].as_str().unwrap(),
            pos["deg"].as_f64().unwrap()
        )
        .unwrap();
    }
    // The example's machine: a C,A table, A 50 mm below the gauge point.
    let toml_text = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/five_axis/machine.toml"),
    )
    .unwrap();
    let spec: MachineSpec = toml::from_str(&toml_text).unwrap();
    let m = Machine::new(spec).unwrap();
    let cfg = InterpConfig {
        machine: Some(spec),
        ..InterpConfig::default()
    };
    // A pocket outline and a plunge in the setup's frame, machine X Y Z.
    let cut = [
        [10.0, 0.0, 40.0],
        [10.0, 15.0, 40.0],
        [-5.0, 15.0, 38.0],
        [-5.0, 0.0, 38.0],
        [10.0, 0.0, 40.0],
    ];
    let mut program = format!("G21 G90 G94 G61\nG0 X0 Y0 Z60\nG0{words}\nG0 X10 Y0 Z45\n");
    for q in &cut {
        writeln!(program, "G1 X{} Y{} Z{} F1200", q[0], q[1], q[2]).unwrap();
    }
    program.push_str("G0 X0 Y0 Z60\nM2\n");
    let g = gcode::parse(&program).unwrap();
    let opts = gcode::CoreOptions::for_config(&cfg);
    let input = traces::Program::from_gcode(&g, &opts, [0.0; 6]).expect(&program);
    let config = traces::sim::config_for(
        &input,
        cfg,
        &traces::sim::SimSettings::default(),
        "test",
        "3+2",
    );
    let mut sps = Vec::new();
    traces::sim::run(&config, &input, 600.0, |item| {
        if let traces::sim::SimItem::Tick { setpoint, .. } = item {
            sps.push(*setpoint);
        }
        Ok::<(), std::convert::Infallible>(())
    })
    .expect("runs");
    assert_eq!(sps.last().unwrap().state, RunState::Done);
    // From the first setpoint at the setup's rotary positions on, they stand.
    let rotary = |q: &[f64; 6]| [q[3], q[4], q[5]];
    let last = rotary(&sps.last().unwrap().axes);
    let first = sps
        .iter()
        .position(|s| rotary(&s.axes) == last)
        .expect("positioned");
    assert!(first > 10, "the rotary axes turned in {first} ticks");
    let (mut on_axis, mut on_cut, mut ticks_cut) = (0.0f64, 0.0f64, 0);
    let xyz = |q: &[f64; 6]| Vec3::new(q[0], q[1], q[2]);
    let tip_of = |x: Vec3| m.forward(&[x.x, x.y, x.z, last[0], last[1], last[2]]).tip;
    for sp in &sps[first..] {
        assert_eq!(rotary(&sp.axes), last, "tick {}", sp.seq);
        let pose = m.forward(&sp.axes);
        on_axis = on_axis.max((pose.axis - p).norm());
        // On a programmed cut: the tip at the image of the machine point's
        // fraction along it, between the images of its ends.
        let x = xyz(&sp.axes);
        for w in cut.windows(2) {
            let (a, b) = (Vec3::from(w[0]), Vec3::from(w[1]));
            let t = (x - a).dot(&(b - a)) / (b - a).norm_squared();
            if (0.0..=1.0).contains(&t) && (a + (b - a) * t - x).norm() < 1e-9 {
                let want = tip_of(a) + (tip_of(b) - tip_of(a)) * t;
                on_cut = on_cut.max((pose.tip - want).norm());
                ticks_cut += 1;
                break;
            }
        }
    }
    eprintln!(
        "3+2 with{words}: axis off by {on_axis:e}, tip off its cut by {on_cut:e} mm over {ticks_cut} ticks"
    );
    assert!(on_axis < 1e-12, "tool axis {on_axis} off the setup's");
    assert!(on_cut < 1e-9, "tip {on_cut} mm off its cut");
    assert!(ticks_cut > 1000, "{ticks_cut}");
    // The setup tilts: the tool axis is not the machine's +z.
    assert!((p - Vec3::z()).norm() > 0.01, "{p:?}");
}
