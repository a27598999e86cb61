//! `interpd simulate`, `replay` and `trace` as a user runs them.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn interpd(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_interpd"))
        .args(args)
        .env_remove("RUST_BACKTRACE")
        .output()
        .expect("interpd runs")
}

fn golden(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../tests/golden")
        .join(name)
        .display()
        .to_string()
}

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("interpd-cli-{}", std::process::id()));
    std::fs::create_dir_all(&d).expect("temp dir");
    d.join(name)
}

fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

#[test]
fn simulate_writes_a_trace_that_replays_and_summarises_alike() {
    let out = tmp("line_arc.mcap");
    let o = interpd(&[
        "simulate",
        &golden("line_arc.json"),
        "--out",
        out.to_str().unwrap(),
        "--json",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let sim: serde_json::Value = serde_json::from_slice(&o.stdout).expect("one JSON object");
    assert!(sim["setpoints"].as_u64().unwrap() > 100);
    for k in [
        "duration_s",
        "max_feed_mm_s",
        "max_chord_error_mm",
        "max_tangential_accel_mm_s2",
        "max_tangential_jerk_mm_s3",
        "max_centripetal_accel_mm_s2",
    ] {
        assert!(sim[k].as_f64().is_some_and(|v| v > 0.0), "{k}: {sim}");
    }
    let o = interpd(&["trace", "summary", out.to_str().unwrap(), "--json"]);
    assert!(o.status.success(), "{}", text(&o));
    let summary: serde_json::Value = serde_json::from_slice(&o.stdout).expect("JSON");
    // The same analysis of the same setpoints; the planner's counters are
    // the simulation's own (a trace holds the setpoints, not the solves).
    let mut from_setpoints = sim.clone();
    let planner = from_setpoints.as_object_mut().unwrap().remove("planner");
    assert!(
        planner.is_some_and(|p| p["solves"].as_u64() > Some(0)),
        "{sim}"
    );
    assert_eq!(from_setpoints, summary);
    let o = interpd(&["replay", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("bit-identical"), "{}", text(&o));
    let plots = tmp("plots");
    let o = interpd(&[
        "trace",
        "plot",
        out.to_str().unwrap(),
        "--out",
        plots.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(plots.join("feed.png").is_file() && plots.join("path_xy.svg").is_file());
}

#[test]
fn replay_of_an_altered_trace_exits_non_zero_naming_seq_and_field() {
    let out = tmp("alter.mcap");
    let o = interpd(&[
        "simulate",
        &golden("nurbs_mrr.json"),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let mut t = traces::Trace::open(&out).expect("reads");
    let k = 700;
    t.setpoints[k].feed = f64::from_bits(t.setpoints[k].feed.to_bits() ^ 1);
    let seq = t.setpoints[k].seq;
    let mut w = traces::TraceWriter::new(
        std::io::BufWriter::new(std::fs::File::create(&out).unwrap()),
        Default::default(),
    )
    .unwrap();
    w.config(t.config.as_ref().unwrap()).unwrap();
    for b in &t.blocks {
        w.block(b, 0.0).unwrap();
    }
    for s in &t.setpoints {
        w.setpoint(&s.to_setpoint()).unwrap();
    }
    w.finish().unwrap();
    let o = interpd(&["replay", out.to_str().unwrap()]);
    assert!(!o.status.success());
    let msg = text(&o);
    assert!(
        msg.contains(&format!("seq {seq}")) && msg.contains("field `feed`"),
        "{msg}"
    );
}

#[test]
fn configuration_layers_and_errors() {
    let cfg = tmp("cfg.toml");
    std::fs::write(
        &cfg,
        "[interp]\nmax-path-accel = 500.0\n[simulate]\nmax-ctrl-per-block = 12\n",
    )
    .unwrap();
    let o = interpd(&[
        "simulate",
        &golden("line_arc.json"),
        "--config",
        cfg.to_str().unwrap(),
        "--json",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let s: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let a = s["max_tangential_accel_mm_s2"].as_f64().unwrap();
    assert!(a <= 500.0 * (1.0 + 1e-9) && a > 400.0, "{a}");
    // --set beats the file, flags beat --set.
    let o = interpd(&[
        "simulate",
        &golden("line_arc.json"),
        "--config",
        cfg.to_str().unwrap(),
        "--set",
        "max-path-accel=800",
        "--json",
    ]);
    let s: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(s["max_tangential_accel_mm_s2"].as_f64().unwrap() > 500.0 * 1.01);
    let o = interpd(&[
        "simulate",
        &golden("line_arc.json"),
        "--set",
        "max-path-accel=800",
        "--max-accel",
        "300",
        "--json",
    ]);
    let s: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(s["max_tangential_accel_mm_s2"].as_f64().unwrap() <= 300.0 * (1.0 + 1e-9));
    // Unknown keys and bad values are named.
    std::fs::write(&cfg, "[interp]\nmax-path-acel = 500.0\n").unwrap();
    let o = interpd(&[
        "simulate",
        &golden("line_arc.json"),
        "--config",
        cfg.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    assert!(text(&o).contains("interp.max-path-acel"), "{}", text(&o));
    let o = interpd(&["simulate", &golden("line_arc.json"), "--set", "period=-1"]);
    assert!(!o.status.success());
    assert!(text(&o).contains("period"), "{}", text(&o));
    let bad = tmp("bad.json");
    std::fs::write(&bad, "{\"blocks\": [{\"kind\": \"line\", \"feed\": -5, \"source_line\": 3, \"end\": [1, 0, 0]}]}").unwrap();
    let o = interpd(&["simulate", bad.to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(
        text(&o).contains("source line 3") && text(&o).contains("feed"),
        "{}",
        text(&o)
    );
}

#[test]
fn a_truncated_trace_is_replayed_and_summarised_up_to_its_last_complete_chunk() {
    let out = tmp("cut.mcap");
    let o = interpd(&[
        "simulate",
        &golden("line_arc.json"),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let bytes = std::fs::read(&out).unwrap();
    std::fs::write(&out, &bytes[..bytes.len() / 2]).unwrap();
    let o = interpd(&["replay", out.to_str().unwrap()]);
    let msg = text(&o);
    assert!(o.status.success(), "{msg}");
    assert!(
        msg.contains("truncated or corrupted") && msg.contains("last complete chunk"),
        "{msg}"
    );
    let compared: u64 = msg
        .split("setpoints bit-identical")
        .next()
        .and_then(|h| h.split_whitespace().last())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no count in {msg}"));
    assert!(compared > 100, "{msg}");
    let o = interpd(&["trace", "summary", "--json", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o));
    let s: serde_json::Value = serde_json::from_slice(&o.stdout).expect("summary JSON");
    assert_eq!(s["setpoints"].as_u64(), Some(compared), "{s}");
    // A file with nothing usable is still refused, saying what it recovered.
    std::fs::write(&out, &bytes[..64]).unwrap();
    let o = interpd(&["replay", out.to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(text(&o).contains("recovered"), "{}", text(&o));
}

#[test]
fn gcode_programs_simulate_and_replay_from_the_trace_alone() {
    let ngc = tmp("small.ngc");
    std::fs::write(
        &ngc,
        "G21 G90 G17\nG0 X0 Y0 Z0\nG1 X10 F600\nG2 X20 Y0 I5 J0 F900\nG1 Y5\nG0 Y5\nM2\n",
    )
    .unwrap();
    let out = tmp("small.mcap");
    let o = interpd(&[
        "simulate",
        ngc.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--json",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let s: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    // G0 to where it stands and the zero-length G0 are dropped: three moves.
    assert_eq!(s["input_blocks"], 3, "{s}");
    assert_eq!(s["final_state"], "done");
    assert_eq!(s["final_point"], serde_json::json!([20.0, 5.0, 0.0]));
    let t = traces::Trace::open(&out).expect("reads");
    let lines: Vec<_> = t.blocks.iter().map(|b| b.block.source_line).collect();
    assert_eq!(lines, [Some(3), Some(4), Some(5)]);
    std::fs::remove_file(&ngc).unwrap();
    let o = interpd(&["replay", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o));
    let bad = tmp("bad.ngc");
    std::fs::write(&bad, "G1 X10 F600\nG1 X(1+\n").unwrap();
    let o = interpd(&["simulate", bad.to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(text(&o).contains("bad.ngc"), "{}", text(&o));
}

/// `simulate --json` counts the tangential jerk's sign changes. A
/// jerk-limited schedule changes sign once at each speed extremum and once
/// on arriving at rest: a rest-to-rest move twice (jerk up, down, then up
/// again into the stop), whatever its length, and a `G64` corner once on the
/// way into it and once out of it. Chatter would count hundreds. It also
/// counts the rests before the end, from the setpoints, and says why the
/// path stopped there: every rest of these programs is a junction stop the
/// program asks for, none one the look-ahead added.
#[test]
fn simulate_reports_jerk_sign_changes_as_planned_phases_and_every_rest_with_its_reason() {
    let simulate = |name: &str, program: &str| {
        let ngc = tmp(name);
        std::fs::write(&ngc, program).unwrap();
        let o = interpd(&["simulate", ngc.to_str().unwrap(), "--json"]);
        assert!(o.status.success(), "{}", text(&o));
        let s: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        assert_eq!(s["final_state"], "done", "{s}");
        let changes = s["jerk_sign_changes"].as_u64().expect("a count");
        let per_s = s["jerk_sign_changes_per_s"].as_f64().expect("a rate");
        let motion = s["motion_time_s"].as_f64().expect("a time");
        assert!((per_s * motion - changes as f64).abs() < 1e-9, "{s}");
        let p = &s["planner"];
        assert!(p["solves"].as_u64().expect("a count") > 0, "{s}");
        for added in ["kept_rests", "crawls"] {
            assert_eq!(p[added], 0, "{s}");
        }
        let count = |v: &serde_json::Value| v.as_u64().expect("a count");
        (
            changes,
            count(&s["rests"]),
            count(&p["junction_stops"]),
            count(&p["junctions_blended"]),
        )
    };
    // Exact stops: four rest-to-rest moves at production feed, one of them
    // too short to reach it; three rests between them.
    let stops = "G21 G90 G61\nG1 X100 F6000\nG1 Y5\nG1 X0\nG1 X0.3\nM2\n";
    assert_eq!(simulate("stops.ngc", stops), (8, 3, 3, 0));
    // Three blended corners: four speed maxima, three minima, one stop.
    let corners = "G21 G90 G64 P0.01\nG1 X50 F6000\nG1 Y50\nG1 X0\nG1 Y0.5\nM2\n";
    let (changes, rests, stopped, _) = simulate("corners.ngc", corners);
    assert_eq!((changes, rests, stopped), (8, 0, 0));
}

/// `interpd` as a user runs it, with the main thread's stack limited to
/// `kib` KiB (`ulimit -s`).
fn interpd_with_main_stack(kib: u32, args: &[&str]) -> Output {
    Command::new("sh")
        .arg("-c")
        .arg(format!("ulimit -s {kib} && exec \"$0\" \"$@\""))
        .arg(env!("CARGO_BIN_EXE_interpd"))
        .args(args)
        .env_remove("RUST_BACKTRACE")
        .output()
        .expect("sh runs interpd")
}

/// The commands do not run on the main thread's stack: an unoptimised
/// `interpd simulate`, `replay` or `demo` overflowed the 8 MiB main thread
/// building its `interp_run::Run` (12–14 MiB measured), on any program. The
/// optimised build these tests run needs 4–8 MiB there, so a 1 MiB main
/// stack shows the same dependence: a G43.4 program with A and C moving
/// simulates to its end and replays bit for bit, and the demo runs.
#[test]
fn commands_run_off_the_main_thread_stack() {
    let machine = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../examples/five_axis/machine.toml")
        .display()
        .to_string();
    let ngc = tmp("g43_4_stack.ngc");
    std::fs::write(
        &ngc,
        "G21 G90 G94 G61\nG0 X0 Y0 Z120 A20 C-90\nG43.4 H1\nG1 X20 Y0 Z0 F1200\n\
         G1 X10 Y17.3205 A25 C-60\nG1 X-10 Y17.3205 A30 C-30\nG1 X-20 Y0 A25 C0\n\
         G1 X-10 Y-17.3205 A20 C30\nG49\nG0 X0 Y0 Z150\nM2\n",
    )
    .unwrap();
    let out = tmp("g43_4_stack.mcap");
    let (ngc, out) = (ngc.to_str().unwrap(), out.to_str().unwrap());
    let o = interpd_with_main_stack(
        1024,
        &[
            "simulate",
            "--machine",
            &machine,
            ngc,
            "--out",
            out,
            "--json",
        ],
    );
    assert!(o.status.success(), "{}", text(&o));
    let s: serde_json::Value = serde_json::from_slice(&o.stdout).expect("one JSON object");
    assert_eq!(s["final_state"], "done", "{s}");
    assert_eq!(
        s["final_point"],
        serde_json::json!([0.0, 0.0, 150.0]),
        "{s}"
    );
    let o = interpd_with_main_stack(1024, &["replay", out]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("bit-identical"), "{}", text(&o));
    let demo_out = tmp("demo_stack");
    let o = interpd_with_main_stack(
        1024,
        &[
            "demo",
            "--fast",
            "--no-service",
            "--no-plots",
            "--json",
            "--out",
            demo_out.to_str().unwrap(),
        ],
    );
    assert!(o.status.success(), "{}", text(&o));
}

/// `simulate --json` says when the look-ahead kept a plan whole to a corner
/// because every pass of a re-solve failed (`planner.kept_to_corner`):
/// slower planning, and no stop the program does not ask for. `homer-q2`
/// at F6000 on a soft machine (path jerk 10⁴ mm/s³) brakes into its corners
/// at the jerk limit over the whole look-ahead, where re-solves from the
/// machine have no room. Every rest before the end has its reason: a
/// junction stop, or one the look-ahead added.
#[test]
fn simulate_reports_plans_kept_to_a_corner() {
    let source = Path::new(env!("CARGO_MANIFEST_DIR")).join("../gcode/tests/programs/homer-q2.ngc");
    let text_in = std::fs::read_to_string(source).unwrap();
    // The program's feeds (`#10=290` for the curves, F100 to plunge) at
    // production feed.
    let at_f6000 = text_in
        .replace("#10=290", "#10=6000")
        .replace("F100", "F6000");
    assert_ne!(at_f6000, text_in);
    let ngc = tmp("homer-q2-f6000.ngc");
    std::fs::write(&ngc, at_f6000).unwrap();
    let o = interpd(&[
        "simulate",
        ngc.to_str().unwrap(),
        "--json",
        "--set",
        "max-path-jerk=1e4",
        "--set",
        "axis-max-jerk=[2e4,2e4,2e4]",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let s: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(s["final_state"], "done", "{s}");
    let p = &s["planner"];
    let count = |v: &serde_json::Value| v.as_u64().expect("a count");
    assert!(count(&p["kept_to_corner"]) > 0, "{s}");
    assert_eq!(
        count(&s["rests"]),
        count(&p["junction_stops"]) + count(&p["kept_rests"]) + count(&p["crawls"]),
        "{s}"
    );
}
