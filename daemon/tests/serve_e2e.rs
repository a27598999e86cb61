//! End-to-end: `interpd serve` with `interpd send` and `interpd watch` (an
//! iceoryx2 subscriber) as separate processes, over TCP and the Unix socket.

mod serve_support;

use std::io::{BufRead, BufReader, Read, Write};
use std::os::unix::fs::PermissionsExt;
use std::time::{Duration, Instant};

use serve_support::*;

/// Setpoints must lie on the programmed polyline this closely, mm.
const ON_PATH_TOL: f64 = 1e-9;

/// A polyline with corners (full stops) and a Z move, from the origin.
const POLYLINE: [[f64; 3]; 4] = [
    [0.0, 0.0, 0.0],
    [8.0, 0.0, 0.0],
    [8.0, 4.0, 0.0],
    [0.0, 4.0, 1.5],
];

/// Runs `interpd replay` on `trace`, asserts it is bit-identical and returns
/// how many setpoints it compared and everything it printed.
fn replay_said(trace: &std::path::Path) -> (u64, String) {
    let out = std::process::Command::new(interpd())
        .arg("replay")
        .arg(trace)
        .output()
        .expect("interpd replay");
    let said = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.status.success(), "replay failed: {said}");
    let compared = said
        .split(" setpoints bit-identical")
        .next()
        .and_then(|h| h.split_whitespace().last())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no count in {said:?}"));
    (compared, said)
}

/// [`replay_said`]'s count.
fn replay_bit_identical(trace: &std::path::Path) -> u64 {
    replay_said(trace).0
}

/// `interpd trace summary --json` of `trace`.
fn trace_summary(trace: &std::path::Path) -> serde_json::Value {
    let out = std::process::Command::new(interpd())
        .args(["trace", "summary", "--json"])
        .arg(trace)
        .output()
        .expect("interpd trace summary");
    assert!(
        out.status.success(),
        "trace summary: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("summary JSON")
}

#[test]
fn streamed_program_is_published_gapless_on_the_path_and_ends_at_rest_at_its_end() {
    let dir = temp_dir("e2e");
    let service = service_name("e2e");
    let trace = dir.join("run.mcap");
    let srv = Server::start(
        &service,
        &["--no-socket", "--record", trace.to_str().unwrap()],
    );
    let csv = dir.join("setpoints.csv");
    let watcher = watch(&service, &csv, 3000.0);
    // A second subscriber holds the same ticks to half the feed: the
    // setpoint checker must fail it.
    let strict = watch(&service, &dir.join("strict.csv"), 1500.0);
    std::thread::sleep(Duration::from_millis(300)); // let the subscriber connect
    let program = dir.join("poly.jsonl");
    let mut text = String::from("# a polyline\n");
    for (i, p) in POLYLINE[1..].iter().enumerate() {
        text.push_str(&line_to(*p, 3000.0, i as u32 + 1));
        text.push('\n');
    }
    std::fs::write(&program, text).unwrap();
    let out = std::process::Command::new(interpd())
        .args(["send", "--json", "--addr"])
        .arg(format!("127.0.0.1:{}", srv.port))
        .arg(&program)
        .output()
        .expect("interpd send");
    assert!(
        out.status.success(),
        "send failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let status: serde_json::Value =
        serde_json::from_slice(&out.stdout).expect("send --json prints the status");
    assert_eq!(status["state"], "done", "{status}");
    assert_eq!(status["blocks_accepted"], 3);

    let w = wait_child(watcher, "interpd watch");
    assert!(
        w.status.success(),
        "watch: {}",
        String::from_utf8_lossy(&w.stdout)
    );
    let summary: serde_json::Value = serde_json::from_slice(&w.stdout).unwrap();
    assert_eq!(summary["gaps"], 0);
    // Every tick went through the setpoint checker, and passed.
    assert!(
        summary["checked_ticks"].as_u64().unwrap() > 100,
        "{summary}"
    );
    assert_eq!(summary["violations"]["first_seq"], serde_json::Value::Null);
    let s = wait_child(strict, "interpd watch --check-feed 1500");
    assert!(!s.status.success(), "over speed passed");
    let strict: serde_json::Value = serde_json::from_slice(&s.stdout).unwrap();
    assert!(
        strict["violations"]["over_speed"].as_u64().unwrap() > 100,
        "{strict}"
    );
    let rows = read_csv(&csv);
    assert!(rows.len() > 100, "{} rows", rows.len());
    // Gapless publisher sequence, and ticks that advance by one once moving.
    for w in rows.windows(2) {
        assert_eq!(w[1].seq, w[0].seq + 1, "gap after {:?}", w[0]);
        if w[0].tick > 0 {
            assert_eq!(w[1].tick, w[0].tick + 1);
        }
    }
    // Every point on the polyline.
    let mut max_off = 0.0f64;
    for r in &rows {
        let d = POLYLINE
            .windows(2)
            .map(|s| dist_to_segment(r.p, s[0], s[1]))
            .fold(f64::INFINITY, f64::min);
        max_off = max_off.max(d);
    }
    assert!(
        max_off <= ON_PATH_TOL,
        "a setpoint is {max_off} mm off the path"
    );
    // At rest, exactly at the end, done; it moved through every block.
    let last = rows.last().unwrap();
    assert_eq!(last.state, "done");
    assert_eq!(last.p, POLYLINE[3]);
    assert_eq!(last.feed, 0.0);
    let ids: std::collections::BTreeSet<u32> = rows.iter().map(|r| r.block_id).collect();
    assert!(
        ids.contains(&1) && ids.contains(&2) && ids.contains(&3),
        "{ids:?}"
    );

    let (st, text) = srv.stop();
    assert!(st.success(), "serve exited with {st}: {text}");
    assert!(text.contains("stopped:"), "{text}");
    assert!(text.contains("0 records dropped"), "{text}");

    // The recording replays bit for bit (`interpd replay`).
    let compared = replay_bit_identical(&trace);
    // Every moving tick the subscriber saw is in the trace.
    let moving = rows
        .iter()
        .filter(|r| r.tick > 0)
        .map(|r| r.tick)
        .max()
        .unwrap();
    assert!(
        compared >= moving,
        "{compared} compared, {moving} ticks seen"
    );
}

#[test]
fn bad_lines_get_an_error_naming_the_problem_and_the_connection_stays_up() {
    let dir = temp_dir("badlines");
    let sock = dir.join("interpd.sock");
    let service = service_name("badlines");
    let srv = Server::start(&service, &["--socket", sock.to_str().unwrap()]);
    let mut c = srv.connect();
    let r = c.ask("jump 3");
    assert!(r.starts_with("err 1 unknown request \"jump\""), "{r}");
    let r = c.ask("{\"feed\": 100, \"kind\": ");
    assert!(r.starts_with("err 2 invalid JSON block"), "{r}");
    let long = "#".repeat(1200 * 1024);
    let r = c.ask(&long);
    assert!(
        r.starts_with("err 3 line of") && r.contains("exceeds the limit"),
        "{r}"
    );
    let r = c.ask(&line_to([1.0, 0.0, 0.0], -5.0, 1));
    assert!(r.starts_with("err 4 feed must be a positive"), "{r}");
    let r = c.ask(r#"{"feed": 100, "kind": "nurbs", "degree": 2, "points": [[5,5,5],[6,5,5],[7,6,5]], "knots": [0,0,0,1,1,1]}"#);
    assert!(r.starts_with("err 5 ") && r.contains("start"), "{r}");
    let r = c.ask("override 9");
    assert!(r.starts_with("err 6 override 9 outside"), "{r}");
    // Still up: a good block and a status.
    let r = c.ask(&line_to([1.0, 0.0, 0.0], 600.0, 7));
    assert_eq!(r, "ok block 1 segments 1..=1");
    let s = c.status();
    assert_eq!(s["line_errors"], 6);
    assert_eq!(s["blocks_accepted"], 1);
    assert_eq!(s["state"], "idle"); // no `start` yet

    // The Unix socket: mode 0600, same protocol.
    let mode = std::fs::metadata(&sock).unwrap().permissions().mode() & 0o777;
    assert_eq!(mode, 0o600);
    let line = Conn::unix(&sock).ask("status");
    assert!(line.starts_with("status {"), "{line}");

    // Run it to the end.
    assert_eq!(c.ask("end"), "ok end");
    assert_eq!(c.ask("start"), "ok start");
    let s = c.wait_for("done", |s| s["state"] == "done");
    assert_eq!(s["position"], serde_json::json!([1.0, 0.0, 0.0]));
    let (st, _) = srv.stop();
    assert!(st.success());
    assert!(!sock.exists(), "the socket file is removed at exit");
}

#[test]
fn a_client_leaving_mid_stream_holds_and_the_accepted_blocks_stay() {
    let service = service_name("disconnect");
    let srv = Server::start(&service, &["--no-socket"]);
    let mut c = srv.connect();
    // 40 mm at 1200 mm/min: two seconds of motion.
    assert!(
        c.ask(&line_to([40.0, 0.0, 0.0], 1200.0, 1))
            .starts_with("ok")
    );
    assert!(
        c.ask(&line_to([40.0, 10.0, 0.0], 1200.0, 2))
            .starts_with("ok")
    );
    assert_eq!(c.ask("start"), "ok start");
    c.wait_for("motion", |s| {
        s["state"] == "running" && s["s"].as_f64().unwrap() > 1.0
    });
    drop(c); // gone without `end`
    let mut c2 = srv.connect();
    let s = c2.wait_for("hold at rest", |s| {
        s["state"] == "holding" && s["feed"] == 0.0
    });
    let x = s["position"][0].as_f64().unwrap();
    assert!(x > 1.0 && x < 40.0, "held at {x}");
    assert_eq!(s["position"][1], 0.0);
    // Resume and finish the program with what was accepted.
    assert_eq!(c2.ask("resume"), "ok resume");
    assert_eq!(c2.ask("override 2"), "ok override 2");
    assert_eq!(c2.ask("end"), "ok end");
    let s = c2.wait_for("done", |s| s["state"] == "done");
    assert_eq!(s["position"], serde_json::json!([40.0, 10.0, 0.0]));
    drop(srv);
}

#[test]
fn hold_resume_and_abort_stop_on_the_path_and_a_new_program_starts_there() {
    let service = service_name("commands");
    let dir = temp_dir("commands");
    let trace = dir.join("commands.mcap");
    let srv = Server::start(
        &service,
        &["--no-socket", "--record", trace.to_str().unwrap()],
    );
    let mut c = srv.connect();
    assert!(
        c.ask(&line_to([30.0, 0.0, 0.0], 1800.0, 1))
            .starts_with("ok")
    );
    assert_eq!(c.ask("start"), "ok start");
    c.wait_for("motion", |s| s["s"].as_f64().unwrap() > 2.0);
    // Streamed while moving: committed between ticks of a running program.
    assert!(
        c.ask(&line_to([30.0, 10.0, 0.0], 1800.0, 2))
            .starts_with("ok")
    );
    assert_eq!(c.ask("end"), "ok end");
    assert_eq!(c.ask("override 0.5"), "ok override 0.5");
    assert_eq!(c.ask("hold"), "ok hold");
    let h = c.wait_for("held", |s| s["state"] == "holding" && s["feed"] == 0.0);
    let held_at = h["s"].as_f64().unwrap();
    std::thread::sleep(Duration::from_millis(100));
    let h2 = c.status();
    assert_eq!(h2["s"].as_f64().unwrap(), held_at, "moved while held");
    assert_eq!(c.ask("resume"), "ok resume");
    c.wait_for("moving again", |s| s["s"].as_f64().unwrap() > held_at + 1.0);
    let r = c.ask("abort");
    assert_eq!(r, "ok abort");
    let a = c.status();
    assert_eq!(a["state"], "idle");
    assert_eq!(a["feed"], 0.0);
    let x = a["position"][0].as_f64().unwrap();
    assert!(x > held_at && x < 30.0, "stopped at {x}");
    assert_eq!(a["position"][1], 0.0);
    // A new program starts where the machine stopped.
    assert!(c.ask(&line_to([x, 5.0, 0.0], 1800.0, 2)).starts_with("ok"));
    assert_eq!(c.ask("end"), "ok end");
    assert_eq!(c.ask("start"), "ok start");
    let d = c.wait_for("done", |s| s["state"] == "done");
    assert_eq!(d["position"], serde_json::json!([x, 5.0, 0.0]));
    // And another after that one is done.
    assert!(c.ask(&line_to([x, 8.0, 0.0], 1800.0, 1)).starts_with("ok"));
    assert_eq!(c.ask("end"), "ok end");
    assert_eq!(c.ask("start"), "ok start");
    let d = c.wait_for("done again", |s| {
        s["state"] == "done" && s["position"] == serde_json::json!([x, 8.0, 0.0])
    });
    assert_eq!(d["feed"], 0.0);
    let (st, text) = srv.stop();
    assert!(st.success(), "serve exited with {st}: {text}");
    assert!(text.contains("0 records dropped"), "{text}");

    // The whole session (three programs, blocks committed while moving,
    // override, hold, resume, abort) replays bit for bit by its schedule.
    let compared = replay_bit_identical(&trace);
    let ticks = d["ticks"].as_u64().unwrap();
    assert!(compared >= ticks, "{compared} of {ticks} ticks replayed");

    // `interpd trace summary` analyses the whole session: the segments of
    // the later programs come from following the schedule.
    let sum = trace_summary(&trace);
    assert_eq!(sum["setpoints"].as_u64(), Some(compared), "{sum}");
    assert_eq!(sum["missing_setpoints"], 0, "{sum}");
    assert_eq!(sum["input_blocks"], 4, "{sum}");
    assert_eq!(
        sum["final_point"],
        serde_json::json!([x, 8.0, 0.0]),
        "{sum}"
    );
    // Along X to where the abort stopped, then 5 mm and 3 mm along Y.
    let length = sum["length_mm"].as_f64().unwrap();
    assert!((length - (x + 8.0)).abs() < 1e-6, "{length} mm for {x} + 8");
    assert!(sum["max_chord_error_mm"].as_f64().unwrap() < 1e-9, "{sum}");
    // Two aborts: the operator's and the stop's (SIGTERM aborts on the
    // path); the third program leaving the second's `done` is not one.
    assert_eq!(sum["events"]["abort"], 2, "{sum}");
    assert_eq!(sum["events"]["next-program"], 1, "{sum}");
    // The hold, the abort and the ends of programs are no rests the
    // program or the planner made: none before the end.
    assert_eq!(sum["rests"], 0, "{sum}");
}

#[test]
fn a_full_queue_is_back_pressure_not_loss() {
    let service = service_name("backpressure");
    let srv = Server::start(&service, &["--no-socket"]);
    // 1 mm collinear lines: no corner stops, so the run is short once started.
    let n = 150usize;
    let mut w = std::net::TcpStream::connect(("127.0.0.1", srv.port)).unwrap();
    let mut r = BufReader::new(w.try_clone().unwrap());
    let writer = std::thread::spawn(move || {
        let mut buf = String::new();
        for i in 0..n {
            buf.push_str(&line_to([(i + 1) as f64, 0.0, 0.0], 6000.0, i as u32 + 1));
            buf.push('\n');
        }
        w.write_all(buf.as_bytes()).unwrap();
        w
    });
    // Without `start` nothing moves: replies stop once the queues are full.
    r.get_ref()
        .set_read_timeout(Some(Duration::from_millis(500)))
        .unwrap();
    let mut oks = 0usize;
    let mut line = String::new();
    loop {
        line.clear();
        match r.read_line(&mut line) {
            Ok(0) => panic!("closed"),
            Ok(_) => {
                assert!(line.starts_with("ok block"), "{line}");
                oks += 1;
            }
            Err(_) => break, // stalled: back-pressure
        }
    }
    assert!(oks > 10 && oks < n, "{oks} of {n} accepted before start");
    let mut c = srv.connect();
    assert_eq!(c.ask("start"), "ok start");
    r.get_ref().set_read_timeout(Some(WAIT)).unwrap();
    let t0 = Instant::now();
    while oks < n {
        line.clear();
        r.read_line(&mut line).unwrap();
        assert!(line.starts_with("ok block"), "{line}");
        oks += 1;
        assert!(t0.elapsed() < WAIT);
    }
    let mut w = writer.join().unwrap();
    w.write_all(b"end\n").unwrap();
    line.clear();
    r.read_line(&mut line).unwrap();
    assert_eq!(line.trim(), "ok end");
    let s = c.wait_for("done", |s| s["state"] == "done");
    assert_eq!(s["position"][0], n as f64);
    assert_eq!(s["blocks_accepted"], n as u64);
    assert_eq!(s["pieces_pushed"], n as u64);
    assert_eq!(s["pieces_refused"], 0);
    let mut rest = String::new();
    let _ = r
        .get_mut()
        .set_read_timeout(Some(Duration::from_millis(10)));
    let _ = r.read_to_string(&mut rest);
    drop(srv);
}

#[test]
fn a_restart_after_a_crash_serves_the_same_service_again() {
    let service = service_name("crash");
    let srv = Server::start(&service, &["--no-socket"]);
    let pid = srv.child.id();
    signal(pid, 9); // SIGKILL: no cleanup at all
    drop(srv);
    let srv = Server::start(&service, &["--no-socket"]);
    let mut c = srv.connect();
    assert!(c.ask(&line_to([2.0, 0.0, 0.0], 600.0, 1)).starts_with("ok"));
    assert_eq!(c.ask("end"), "ok end");
    assert_eq!(c.ask("start"), "ok start");
    c.wait_for("done", |s| s["state"] == "done");
    let (st, _) = srv.stop();
    assert!(st.success());
}

#[test]
fn remote_listening_needs_a_flag_and_a_token() {
    let out = std::process::Command::new(interpd())
        .args(["serve", "--no-socket", "--port", "0", "--listen", "0.0.0.0"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--allow-remote"));
    let out = std::process::Command::new(interpd())
        .args([
            "serve",
            "--no-socket",
            "--port",
            "0",
            "--listen",
            "0.0.0.0",
            "--allow-remote",
        ])
        .env_remove("INTERPD_TOKEN")
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--token"));
    // With a token, a connection must authenticate first.
    let service = service_name("token");
    let srv = Server::start(&service, &["--no-socket", "--token", "s3cret"]);
    let mut c = srv.connect();
    let r = c.ask("status");
    assert!(r.starts_with("err 1 authentication required"), "{r}");
    let mut c = srv.connect();
    assert!(c.ask("auth wrong").starts_with("err 1 wrong token"));
    assert_eq!(c.ask("auth s3cret"), "ok auth");
    assert!(c.ask("status").starts_with("status {"));
}

/// `interpd send` of a program longer than the look-ahead: the server holds
/// the block that does not fit until the machine moves, so `start` must not
/// wait behind it on the same connection (it did: a deadlock whenever the
/// server answered every block within the stall time).
#[test]
fn send_streams_a_program_longer_than_the_look_ahead_to_its_end() {
    let service = service_name("long");
    let dir = temp_dir("long");
    let srv = Server::start(&service, &["--no-socket"]);
    // 150 collinear 10 mm lines: 1,500 mm, more than the 1,024 mm profile
    // ring plus the 16 planned blocks the RT queue holds, so the server must
    // hold a block back before the machine has started.
    let n = 150;
    let mut text = String::new();
    for i in 1..=n {
        text.push_str(&line_to([10.0 * i as f64, 0.0, 0.0], 15_000.0, i));
        text.push('\n');
    }
    let program = dir.join("long.jsonl");
    std::fs::write(&program, text).unwrap();
    let child = std::process::Command::new(interpd())
        .args(["send", "--json", "--addr"])
        .arg(format!("127.0.0.1:{}", srv.port))
        .arg(&program)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("interpd send");
    let out = wait_child(child, "interpd send of a long program");
    assert!(
        out.status.success(),
        "send failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let status: serde_json::Value = serde_json::from_slice(&out.stdout).expect("status JSON");
    assert_eq!(status["state"], "done", "{status}");
    assert_eq!(status["blocks_accepted"], n);
    assert_eq!(status["pieces_pushed"], n);
    assert_eq!(
        status["position"],
        serde_json::json!([10.0 * n as f64, 0.0, 0.0])
    );
    drop(srv);
}

/// `interpd watch` tells a restart of the publisher (its sequence starts
/// again, the position jumps) from a gap, and gives up on a dead publisher
/// after `--liveness` seconds instead of waiting forever.
#[test]
fn watch_reports_a_publisher_restart_and_a_dead_publisher() {
    let service = service_name("restart");
    let srv = Server::start(&service, &["--no-socket"]);
    let child = std::process::Command::new(interpd())
        .args(["watch", "--json", "--liveness", "1", "--service", &service])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("interpd watch");
    std::thread::sleep(Duration::from_millis(500));
    crash_and_restart_elsewhere(srv);
    let out = wait_child(child, "interpd watch of a dying publisher");
    assert!(!out.status.success(), "watch exited 0");
    let err = String::from_utf8_lossy(&out.stderr);
    let summary: serde_json::Value = serde_json::from_slice(&out.stdout).expect("summary");
    assert_eq!(summary["restarts"], 1, "{summary}");
    assert_eq!(summary["restart_jump_mm"], 5.0, "{summary}");
    assert_eq!(summary["gaps"], 0, "a restart is not a gap: {summary}");
    assert!(summary["silent_s"].as_f64().unwrap() >= 1.0, "{summary}");
    assert!(err.contains("the publisher restarted 1 time(s)"), "{err}");
    assert!(err.contains("went silent"), "{err}");
    // No publisher at all: not "0 samples, fine".
    let out = std::process::Command::new(interpd())
        .args(["watch", "--liveness", "0.3", "--service"])
        .arg(service_name("nobody"))
        .output()
        .expect("interpd watch");
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("no sample in"), "{err}");
}

/// A recording cut off by a crash (`kill -9` of `serve`) is summarised and
/// replayed bit for bit up to its last complete chunk.
#[test]
fn a_recording_cut_off_by_a_crash_replays_up_to_its_last_complete_chunk() {
    let dir = temp_dir("crash-record");
    let trace = dir.join("run.mcap");
    let srv = Server::start(
        &service_name("crash-record"),
        &["--no-socket", "--record", trace.to_str().unwrap()],
    );
    let mut c = srv.connect();
    // Four seconds of motion; the service dies after about two.
    assert!(
        c.ask(&line_to([80.0, 0.0, 0.0], 1200.0, 1))
            .starts_with("ok")
    );
    assert_eq!(c.ask("start"), "ok start");
    c.wait_for("two seconds of motion", |s| s["s"].as_f64().unwrap() > 35.0);
    signal(srv.child.id(), 9);
    drop(srv);
    let (compared, said) = replay_said(&trace);
    assert!(said.contains("truncated"), "{said}");
    // At least one complete chunk (about 1,000 ticks) of the moving ticks.
    assert!(compared >= 500, "{said}");
    let sum = trace_summary(&trace);
    assert_eq!(sum["setpoints"].as_u64(), Some(compared), "{sum}");
}

/// A `G64 P` program: long lines with corners (blended) and a run of short
/// moves along a wave (compressed into NURBS pieces), from the origin.
fn g64_program() -> String {
    let mut t = String::from("G21 G90 G17\nG64 P0.01\nG1 X10 Y0 F3000\n");
    for i in 1..=200 {
        let x = 10.0 + 0.05 * f64::from(i);
        let y = 0.5 * (0.4 * f64::from(i) * 0.05 * std::f64::consts::TAU).sin();
        t.push_str(&format!("G1 X{x:.4} Y{y:.4}\n"));
    }
    t.push_str("G1 X30 Y10\nG1 X0 Y10\nG1 X0 Y2\nM2\n");
    t
}

/// A short five-axis program for the C,A table of [`FIVE_AXIS_CONFIG`]:
/// tool-centre-point control on from the machine's home (the first move
/// starts at the tool tip of the joints), the tool leaning 5° towards −Y
/// (C stands at 0 at the pole), a move with the axis kept, one turning it
/// back upright, then TCP off.
const FIVE_AXIS_PROGRAM: &str = "G21 G90 G94 G61\nG43.5 H1\n\
    G1 X0 Y0 Z-95 I0 J-0.087156 K0.996195 F6000\nG1 X5 Y0 Z-95\n\
    G1 X5 Y5 Z-95 I0 J0 K1\nG49\nG1 X0 Y0 Z0\nM2\n";

/// The machine of `examples/five_axis/machine.toml` as `serve` and
/// `simulate` read it (`--config`).
const FIVE_AXIS_CONFIG: &str = "[interp.machine]\nchain = \"W/caxyBz/T\"\ntool-length = 100.0\n\
    rotary-centres = [[0.0, 0.0, -50.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]\n\
    rotary-ranges = [{ min = -110.0, max = 110.0 }, { min = 0.0, max = 0.0 }, \
    { min = -inf, max = inf }]\n";

/// The setpoints of a trace from the last one before it moved to the first
/// one `done` (the service publishes before `start` and after the end),
/// without `seq` and `time`.
fn moving_setpoints(trace: &std::path::Path) -> Vec<[u64; 11]> {
    let t = traces::reader::Trace::open(trace).expect("trace reads");
    let first = t
        .setpoints
        .iter()
        .position(|s| s.s > 0.0)
        .expect("the run moved");
    let done = t.setpoints[first..]
        .iter()
        .position(|s| s.state == interp_core::RunState::Done)
        .expect("the run ended")
        + first;
    t.setpoints[first.saturating_sub(1)..=done]
        .iter()
        .map(|s| {
            [
                s.x.to_bits(),
                s.y.to_bits(),
                s.z.to_bits(),
                s.feed.to_bits(),
                s.u.to_bits(),
                s.s.to_bits(),
                u64::from(s.block_id),
                s.a.to_bits(),
                s.b.to_bits(),
                s.c.to_bits(),
                s.state as u64,
            ]
        })
        .collect()
}

/// Serves `program` (with `config`, if any, for both) recorded, simulates
/// it, and checks the motion is the same bit for bit and the recording
/// replays; returns the served and simulated traces' paths.
fn served_as_simulated(
    test: &str,
    program: &str,
    config: Option<&str>,
) -> (std::path::PathBuf, std::path::PathBuf) {
    let dir = temp_dir(test);
    let service = service_name(test);
    let served = dir.join("served.mcap");
    let simulated = dir.join("simulated.mcap");
    let path = dir.join("program.ngc");
    std::fs::write(&path, program).unwrap();
    let mut flags = vec![
        "--no-socket".to_owned(),
        "--record".to_owned(),
        served.display().to_string(),
    ];
    if let Some(c) = config {
        let cp = dir.join("config.toml");
        std::fs::write(&cp, c).unwrap();
        flags.extend(["--config".to_owned(), cp.display().to_string()]);
    }
    let flag_refs: Vec<&str> = flags.iter().map(String::as_str).collect();
    let srv = Server::start(&service, &flag_refs);
    let (st, status, err) = send(srv.port, &path, &[]);
    assert!(st.success(), "send: {err}");
    let status = status.expect("send --json prints the status");
    assert_eq!(status["state"], "done", "{status}");
    let (st, text) = srv.stop();
    assert!(st.success(), "serve exited with {st}: {text}");

    let mut cmd = std::process::Command::new(interpd());
    cmd.args(["simulate", "--json", "--out"]).arg(&simulated);
    if config.is_some() {
        cmd.arg("--config").arg(dir.join("config.toml"));
    }
    let out = cmd.arg(&path).output().expect("interpd simulate");
    assert!(
        out.status.success(),
        "simulate: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    // Both say why the machine stopped where it did, alike: the junction
    // stops the program asks for, and every rest before the end one of them.
    let sim: serde_json::Value = serde_json::from_slice(&out.stdout).expect("summary JSON");
    let planner = &sim["planner"];
    assert_eq!(status["junction_stops"], planner["junction_stops"], "{sim}");
    assert_eq!(sim["rests"], planner["junction_stops"], "{sim}");
    assert_eq!(status["look_ahead_added_stops"], 0, "{status}");
    assert_eq!(
        (&planner["kept_rests"], &planner["crawls"]),
        (&0.into(), &0.into())
    );
    let a = moving_setpoints(&served);
    let b = moving_setpoints(&simulated);
    assert_eq!(
        a.len(),
        b.len(),
        "served {} setpoints, simulated {}",
        a.len(),
        b.len()
    );
    if let Some(k) = (0..a.len()).find(|&k| a[k] != b[k]) {
        panic!(
            "setpoint {k} of the motion differs: served {:?}, simulated {:?}",
            a[k], b[k]
        );
    }
    // The recording replays bit for bit by its schedule, stage included.
    assert!(replay_bit_identical(&served) >= a.len() as u64);
    (served, simulated)
}

#[test]
fn a_g64_program_gives_the_same_setpoints_served_as_simulated() {
    let (_, simulated) = served_as_simulated("g64", &g64_program(), None);
    // The stage reshaped the program: fewer interpolator blocks than moves.
    let last_id = moving_setpoints(&simulated).last().unwrap()[6];
    assert!(last_id > 3 && last_id < 100, "{last_id} blocks");
}

/// A five-axis program through `send`/`serve` and `simulate` with the
/// machine from the config file: the same joints bit for bit, the
/// recording replays, and the trace records the tool tip and tool axis in
/// the workpiece frame (the tip on the program's moves under TCP).
#[test]
fn a_five_axis_program_gives_the_same_setpoints_served_as_simulated() {
    let (served, _) = served_as_simulated("five", FIVE_AXIS_PROGRAM, Some(FIVE_AXIS_CONFIG));
    let t = traces::reader::Trace::open(&served).expect("trace reads");
    let moving: Vec<_> = t.setpoints.iter().filter(|s| s.s > 0.0).collect();
    assert!(moving.iter().all(|s| {
        let a = s.tool_axis.expect("tool axis recorded");
        let n = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
        s.tip.is_some() && (n - 1.0).abs() < 1e-12
    }));
    // The rotary joints moved (the tool leaned and came back upright).
    assert!(moving.iter().any(|s| s.a.abs() > 4.9), "A never tilted");
    // Along `G1 X5 Y0 Z-95` (segment 2) the tip runs on the line z = −95,
    // y = 0 in the workpiece frame, whatever the joints do.
    let on_line: Vec<_> = moving.iter().filter(|s| s.block_id == 2).collect();
    assert!(on_line.len() > 10);
    for s in on_line {
        let p = s.tip.unwrap();
        assert!(p[1].abs() < 1e-9 && (p[2] + 95.0).abs() < 1e-9, "{p:?}");
    }
}

/// A G43.4 G6.2 curve with A and C on its control points (the tool tip in
/// the workpiece frame; the rotary axes coordinates of the same NURBS),
/// sent to `serve`: the program reaches done, the motion is `simulate`'s
/// bit for bit, and the machine stops on the curve's last control point:
/// A and C there, and the forward transform of the final joints puts the
/// tip on its X Y Z.
#[test]
fn a_g43_4_curve_with_rotary_coordinates_is_served_to_its_last_point() {
    // Degree 3, six control points, clamped: it ends on the last one.
    let program = "G21 G90 G94 G61\nG0 X0 Y0 Z120 A0 C0\nG43.4 H1\nG1 X0 Y0 Z0 F6000\n\
        G6.2 P4 X0 Y0 A0 C0 R1 K0\n X6 Y4.794255 A3.115347 C5 R1.2 K0\n\
         X12 Y8.41471 A5.738849 C10 R1 K0\n X18 Y9.97495 A7.456323 C15 R1.3 K0\n\
         X24 Y9.092974 A7.995675 C20 R1 K1\n X30 Y5.984721 A7.274379 C25 R1 K2\n\
        G6.2 K3\nG6.2 K3\nG6.2 K3\nG6.2 K3\nM2\n";
    let (served, _) = served_as_simulated("g43_4_curve", program, Some(FIVE_AXIS_CONFIG));
    let t = traces::reader::Trace::open(&served).expect("trace reads");
    let last = t
        .setpoints
        .iter()
        .find(|s| s.state == interp_core::RunState::Done && s.s > 0.0)
        .expect("the run ended");
    let joints = [last.x, last.y, last.z, last.a, last.b, last.c];
    assert!(
        (joints[3] - 7.274379).abs() < 1e-9 && (joints[5] - 25.0).abs() < 1e-9,
        "{joints:?}"
    );
    let machine =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/five_axis/machine.toml");
    let spec = interpd::config::read_machine(&machine).expect("the example machine");
    let tip = interp_core::kinematics::Machine::new(spec)
        .expect("five-axis")
        .forward(&joints)
        .tip;
    let end = interp_core::Vec3::new(30.0, 5.984721, 0.0);
    assert!((tip - end).norm() < 1e-9, "tip {tip:?}, joints {joints:?}");
    // The rotary axes moved along the curve, not just at its end.
    assert!(t.setpoints.iter().any(|s| s.c > 1.0 && s.c < 24.0));
}

/// An operator's commands coming as fast as a knob turns, while a program
/// with long curves streams: the session replays bit for bit by its
/// schedule. A push that waits for room plans the due parts of a long
/// block before it all the same; with an override or a hold applied in the
/// same tick, the order of the two decides the plans. Unrecorded, replay
/// planned the parts after the command (at the tick), and the butterfly at
/// F6000 under an override every 13 ms and a hold every 47 ms resumed 11 ms
/// later replayed off by a few ulps from a few thousand ticks on; now the
/// trace notes such a push (`parts`) where it came among the commands.
#[test]
fn commands_as_fast_as_a_knob_turns_replay_bit_for_bit() {
    let service = service_name("knob");
    let dir = temp_dir("knob");
    let trace = dir.join("knob.mcap");
    let program = dir.join("butterfly-f6000.ngc");
    let text = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../gcode/tests/programs/curva_farfalla-q1.ngc"),
    )
    .unwrap();
    std::fs::write(
        &program,
        text.replace("F100", "F6000").replace("F290", "F6000"),
    )
    .unwrap();
    let srv = Server::start(
        &service,
        &[
            "--no-socket",
            "--autostart",
            "--record",
            trace.to_str().unwrap(),
        ],
    );
    let sender = spawn_send(srv.port, &program, &[]);
    let mut knob = srv.connect();
    let t0 = Instant::now();
    let ms = |t: Instant| t.elapsed().as_millis() as u64;
    let (mut overrides, mut holds) = (0u64, 0u64);
    let mut next_hold = 47;
    // Until the program is done (or 30 s: the sender then reports it).
    while ms(t0) < 30_000 {
        let x = [1.0, 0.6, 1.2, 0.8, 1.5][overrides as usize % 5];
        assert!(knob.ask(&format!("override {x}")).starts_with("ok"));
        overrides += 1;
        if ms(t0) >= next_hold {
            // Refused while nothing moves (before the first block, after the end).
            if knob.ask("hold").starts_with("ok") {
                holds += 1;
            }
            std::thread::sleep(Duration::from_millis(11));
            let _ = knob.ask("resume");
            next_hold += 47;
        }
        if knob.status()["program_phase"] == "done" {
            break;
        }
        std::thread::sleep(Duration::from_millis(13));
    }
    let out = wait_child(sender, "interpd send");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let s = knob.status();
    assert_eq!(s["state"], "done", "{s}");
    assert!(
        overrides > 100 && holds > 20,
        "{overrides} overrides, {holds} holds"
    );
    let (st, text) = srv.stop();
    assert!(st.success(), "serve exited with {st}: {text}");
    let compared = replay_bit_identical(&trace);
    let ticks = s["ticks"].as_u64().unwrap();
    assert!(compared >= ticks, "{compared} of {ticks} ticks replayed");
}
