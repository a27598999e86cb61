//! The Python subscriber (`examples/python_subscriber/subscriber.py`, iceoryx2's
//! PyPI package) reads every setpoint of a streamed program.
//!
//! Needs a Python with `iceoryx2` installed: `$INTERPD_PYTHON`, else `python3`.
//! Without one the test prints a note and passes (a fresh clone has none;
//! `.ci/run` makes a virtualenv and sets `INTERPD_PYTHON`).

mod serve_support;

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Duration;

use serve_support::*;

fn python() -> Option<String> {
    let py = std::env::var("INTERPD_PYTHON").unwrap_or_else(|_| "python3".into());
    let ok = Command::new(&py)
        .args(["-c", "import iceoryx2"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    ok.then_some(py)
}

/// The Python and the subscriber script, or `None` (with a note) when no
/// Python has the iceoryx2 package: the test is then skipped.
fn python_subscriber() -> Option<(String, PathBuf)> {
    let Some(py) = python() else {
        eprintln!(
            "note: skipped: no Python with the iceoryx2 package (set INTERPD_PYTHON; .ci/run does)"
        );
        return None;
    };
    let script =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/python_subscriber/subscriber.py");
    Some((py, script))
}

#[test]
fn the_python_subscriber_reads_every_setpoint() {
    let Some((py, script)) = python_subscriber() else {
        return;
    };
    let service = service_name("python");
    let sub = Command::new(&py)
        .arg(&script)
        .args([
            "--service",
            &service,
            "--until-done",
            "--json",
            "--timeout",
            "20",
        ])
        .stdout(Stdio::piped())
        .spawn()
        .expect("python subscriber");
    std::thread::sleep(Duration::from_millis(500));
    let srv = Server::start(&service, &["--no-socket"]);
    let mut c = srv.connect();
    assert!(
        c.ask(&line_to([6.0, 0.0, 0.0], 1800.0, 1))
            .starts_with("ok")
    );
    assert!(
        c.ask(&line_to([6.0, 3.0, 0.0], 1800.0, 2))
            .starts_with("ok")
    );
    assert_eq!(c.ask("end"), "ok end");
    assert_eq!(c.ask("start"), "ok start");
    let s = c.wait_for("done", |s| s["state"] == "done");
    let out = wait_child(sub, "the Python subscriber");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stdout)
    );
    let r: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON summary");
    assert_eq!(r["gaps"], 0, "{r}");
    assert_eq!(r["non_finite"], 0);
    assert_eq!(r["reached_done"], true);
    assert_eq!(r["final_position"], serde_json::json!([6.0, 3.0, 0.0]));
    // It saw every sample from the first one published to the first `done`.
    assert_eq!(r["first_seq"], 1, "{r}");
    assert_eq!(r["last_seq"], r["received"], "{r}");
    assert!(r["last_seq"].as_u64().unwrap() <= s["published"].as_u64().unwrap());
    drop(srv);
}

/// The Python subscriber, like `interpd watch`, tells a restarted publisher
/// (its sequence starts again, the position jumps) from a gap, and a dead
/// one (no sample for `--timeout` seconds) from a quiet one.
#[test]
fn the_python_subscriber_reports_a_restart_and_a_dead_publisher() {
    let Some((py, script)) = python_subscriber() else {
        return;
    };
    let service = service_name("python-restart");
    let srv = Server::start(&service, &["--no-socket"]);
    let sub = Command::new(&py)
        .arg(&script)
        .args(["--service", &service, "--json", "--timeout", "1"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("python subscriber");
    std::thread::sleep(Duration::from_millis(800));
    crash_and_restart_elsewhere(srv);
    let out = wait_child(sub, "the Python subscriber of a dying publisher");
    assert!(!out.status.success(), "exited 0");
    let r: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON summary");
    assert_eq!(r["restarts"], 1, "{r}");
    assert_eq!(r["restart_jump_mm"], 5.0, "{r}");
    assert_eq!(r["gaps"], 0, "{r}");
    assert!(r["silent_s"].as_f64().unwrap() >= 1.0, "{r}");
}
