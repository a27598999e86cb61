//! `interpd plan raster` refuses flags that would write a wrong program
//! (F0, FNaN, rapids below the part) or exhaust memory (a tolerance below
//! what f64 resolves), naming the flag, and writes nothing; `interpd plan
//! setup --json` prints what a program needs to position the rotary axes.

use std::path::Path;
use std::process::Command;

/// A 20 × 20 mm plate 2 mm high, as an ASCII STL.
fn plate(dir: &Path) -> std::path::PathBuf {
    let p = dir.join("plate.stl");
    let tri = |a: [f64; 3], b: [f64; 3], c: [f64; 3]| {
        format!(
            "facet normal 0 0 1\nouter loop\nvertex {} {} {}\nvertex {} {} {}\nvertex {} {} {}\nendloop\nendfacet\n",
            a[0], a[1], a[2], b[0], b[1], b[2], c[0], c[1], c[2]
        )
    };
    let mut s = String::from("solid plate\n");
    s += &tri([0.0, 0.0, 2.0], [20.0, 0.0, 2.0], [20.0, 20.0, 2.0]);
    s += &tri([0.0, 0.0, 2.0], [20.0, 20.0, 2.0], [0.0, 20.0, 2.0]);
    s += "endsolid plate\n";
    std::fs::write(&p, s).unwrap();
    p
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
    for (flags, says) in [
        (&["--feed", "0"][..], "--feed must be a positive"),
        (&["--feed=-5"][..], "--feed must be a positive"),
        (&["--feed", "nan"][..], "--feed must be a positive"),
        (
            &["--plunge-feed", "inf"][..],
            "--plunge-feed must be a positive",
        ),
        (
            &["--clearance=-100"][..],
            "--clearance must be a finite number >= 0",
        ),
        (
            &["--blend-tolerance=-0.001"][..],
            "--blend-tolerance must be a finite number of mm >= 0",
        ),
        (
            &["--blend-tolerance", "nan"][..],
            "--blend-tolerance must be a finite number of mm >= 0",
        ),
        (
            &["--chord-tolerance", "1e-15"][..],
            "--chord-tolerance 0.000000000000001 mm is below what f64 resolves",
        ),
    ] {
        let (ok, err) = run(flags);
        assert!(!ok, "{flags:?} accepted");
        assert!(err.contains(says), "{flags:?}: {err}");
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
    use std::fmt::Write as _;
    let dir = std::env::temp_dir().join(format!("interpd-plan-setup-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let stl = dir.join("teapot.stl");
    let mut text = String::from("solid teapot\n");
    for t in planner::setup::samples::teapot(10, 12, 5, 6) {
        text.push_str("facet normal 0 0 0\nouter loop\n");
        for p in t {
            writeln!(text, "vertex {} {} {}", p.x, p.y, p.z).unwrap();
        }
        text.push_str("endloop\nendfacet\n");
    }
    text.push_str("endsolid teapot\n");
    std::fs::write(&stl, text).unwrap();
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
