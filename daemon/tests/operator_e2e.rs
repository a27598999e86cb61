//! End to end: what an operator meets at the control plane. A program
//! belongs to one connection; `send` follows its own program; programs are
//! converted from where the machine is; `hold` is for motion and `start`
//! says why it refuses; `serve` does not take over a path it should not;
//! a client learns clearly that the server died.

mod serve_support;

use std::time::Duration;

use serve_support::*;

fn write(dir: &std::path::Path, name: &str, text: &str) -> std::path::PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn a_program_belongs_to_one_connection_and_others_may_still_hold_abort_and_ask() {
    let srv = Server::start(&service_name("owner"), &["--no-socket"]);
    let mut a = srv.connect();
    let mut b = srv.connect();
    // 60 mm at 1200 mm/min: three seconds of motion.
    assert_eq!(
        a.ask(&line_to([60.0, 0.0, 0.0], 1200.0, 1)),
        "ok block 1 segments 1..=1"
    );
    // Client B's blocks are not merged into A's program.
    let r = b.ask(&line_to([0.0, 5.0, 0.0], 1200.0, 1));
    assert!(
        r.starts_with("err 1 busy: program 1 belongs to connection 1 (tcp 127.0.0.1:"),
        "{r}"
    );
    assert!(b.ask("end").starts_with("err 2 busy: program 1"), "end");
    assert!(b.ask("begin").starts_with("err 3 busy: program 1"), "begin");
    // B may start it, hold it, ask for the status and abort it.
    assert_eq!(b.ask("start"), "ok start");
    b.wait_for("motion", |s| s["s"].as_f64().unwrap() > 1.0);
    assert_eq!(b.ask("hold"), "ok hold");
    let s = b.wait_for("held", |s| s["state"] == "holding" && s["feed"] == 0.0);
    assert_eq!(s["program"], 1);
    assert_eq!(s["program_phase"], "open");
    assert!(
        s["program_owner"]
            .as_str()
            .unwrap()
            .starts_with("connection 1 (tcp ")
    );
    assert_eq!(b.ask("abort"), "ok abort");
    assert_eq!(b.status()["program_phase"], "aborted");
    // The program is over: the next block starts program 2, B's.
    let x = b.status()["position"][0].as_f64().unwrap();
    assert!(
        b.ask(&line_to([x, 5.0, 0.0], 1200.0, 1))
            .starts_with("ok block 1")
    );
    let r = a.ask(&line_to([x, 9.0, 0.0], 1200.0, 2));
    assert!(
        r.starts_with("err 2 busy: program 2 belongs to connection 2"),
        "{r}"
    );
    assert_eq!(b.ask("end"), "ok end");
    assert_eq!(b.ask("start"), "ok start");
    let s = b.wait_for("done", |s| s["program_phase"] == "done");
    assert_eq!(s["position"], serde_json::json!([x, 5.0, 0.0]));
    assert_eq!(s["blocks_accepted"], 2);
}

/// The program fields of a status: number, phase, owner.
fn program_of(s: &serde_json::Value) -> serde_json::Value {
    serde_json::json!([s["program"], s["program_phase"], s["program_owner"]])
}

#[test]
fn a_refused_block_claims_nothing_and_keeps_nobody_out() {
    let srv = Server::start(&service_name("refused-claim"), &["--no-socket"]);
    let mut a = srv.connect();
    let mut b = srv.connect();
    // A line to where the machine is (the origin) has no length: refused.
    let zero = line_to([0.0, 0.0, 0.0], 1200.0, 1);
    let before = a.status();
    let r = a.ask(&zero);
    assert!(r.starts_with("err 2 "), "{r}");
    // Nothing claimed: no program, no owner; B is not kept out.
    assert_eq!(program_of(&a.status()), program_of(&before));
    assert_eq!(program_of(&before), serde_json::json!([0, "none", null]));
    assert_eq!(
        b.ask(&line_to([5.0, 0.0, 0.0], 1200.0, 1)),
        "ok block 1 segments 1..=1"
    );
    assert_eq!(b.ask("end"), "ok end");
    assert_eq!(b.ask("start"), "ok start");
    let done = b.wait_for("done", |s| s["program_phase"] == "done");
    // After a finished program too: A's refused first block leaves program
    // 1 B's and done.
    let r = a.ask(&line_to([5.0, 0.0, 0.0], 1200.0, 2));
    assert!(r.starts_with("err 4 "), "{r}");
    assert_eq!(program_of(&a.status()), program_of(&done));
    // Nothing lost: B's next program is program 2, from where B's first ended.
    assert_eq!(
        b.ask(&line_to([5.0, 5.0, 0.0], 1200.0, 1)),
        "ok block 1 segments 1..=1"
    );
    assert_eq!(b.ask("end"), "ok end");
    assert_eq!(b.ask("start"), "ok start");
    let s = b.wait_for("done", |s| {
        s["program"] == 2 && s["program_phase"] == "done"
    });
    assert_eq!(s["position"], serde_json::json!([5.0, 5.0, 0.0]));
    assert_eq!(s["blocks_accepted"], 2);
}

#[test]
fn send_follows_its_own_program_and_fails_unless_it_reached_done() {
    let dir = temp_dir("send-own");
    let srv = Server::start(&service_name("send-own"), &["--no-socket"]);
    let a = write(&dir, "a.ngc", "G1 X20 Y20 F3000\n");
    let e = write(&dir, "e.ngc", "G1 X5 Y0 F3000\nG1 X5 Y5\n");
    // A, then E, then A: each send reports its own program, at its own end.
    for (k, (prog, end)) in [(&a, [20.0, 20.0]), (&e, [5.0, 5.0]), (&a, [20.0, 20.0])]
        .into_iter()
        .enumerate()
    {
        let (st, status, err) = send(srv.port, prog, &[]);
        assert!(st.success(), "send {k}: {err}");
        let status = status.expect("status");
        assert_eq!(status["program"], k + 1, "{status}");
        assert_eq!(status["program_phase"], "done", "{status}");
        assert_eq!(
            status["position"],
            serde_json::json!([end[0], end[1], 0.0]),
            "{status}"
        );
        assert_eq!(status["queued_segments"], 0, "{status}");
    }
    // A program aborted by someone else is not a success.
    let long = write(&dir, "long.ngc", "G1 X80 F1200\n");
    let child = spawn_send(srv.port, &long, &[]);
    let mut c = srv.connect();
    // (`s` is the session's arc length: the program moves once the machine runs it.)
    c.wait_for("motion", |s| {
        s["machine_program"] == 4 && s["feed"].as_f64().unwrap() > 0.0
    });
    assert_eq!(c.ask("abort"), "ok abort");
    let out = wait_child(child, "interpd send of an aborted program");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "an aborted program exited 0");
    assert!(
        err.contains("program 4 did not reach done: it was aborted"),
        "{err}"
    );
}

#[test]
fn a_busy_send_is_refused_naming_the_owner_or_waits_its_turn() {
    let dir = temp_dir("send-turn");
    let srv = Server::start(&service_name("send-turn"), &["--no-socket"]);
    // A: 20 mm at 1200 mm/min, a second of motion.
    let a = write(&dir, "a.ngc", "G1 X20 F1200\n");
    let b = write(&dir, "b.ngc", "G1 X20 Y5 F3000\n");
    let first = spawn_send(srv.port, &a, &[]);
    let mut c = srv.connect();
    c.wait_for("A moving", |s| {
        s["program"] == 1 && s["s"].as_f64().unwrap() > 0.5
    });
    // Without --wait-turn: refused at once, naming the owner and how long.
    let (st, _, err) = send(srv.port, &b, &[]);
    assert!(!st.success(), "a busy send succeeded");
    assert!(
        err.contains("busy: program 1 belongs to connection ")
            && err.contains("(running to its end, claimed ")
            && err.contains("send --wait-turn waits for it to end"),
        "{err}"
    );
    // With it: B waits for A's end, then runs as program 2 from A's end.
    let second = spawn_send(srv.port, &b, &["--wait-turn"]);
    let out_a = wait_child(first, "send A");
    let out_b = wait_child(second, "send B --wait-turn");
    let err_b = String::from_utf8_lossy(&out_b.stderr);
    // (`--quiet` sends its reasons to the final status on stdout.)
    assert!(
        out_a.status.success(),
        "send A: {}; stdout: {}; stderr: {}",
        out_a.status,
        String::from_utf8_lossy(&out_a.stdout),
        String::from_utf8_lossy(&out_a.stderr)
    );
    assert!(
        out_b.status.success(),
        "send B: {}; stdout: {}; stderr: {err_b}",
        out_b.status,
        String::from_utf8_lossy(&out_b.stdout)
    );
    assert!(
        err_b.contains("busy: program 1 belongs to connection")
            && err_b.contains("waiting for its end (--wait-turn)")
            && err_b.contains("our turn after "),
        "{err_b}"
    );
    let status: serde_json::Value = serde_json::from_slice(&out_b.stdout).unwrap();
    assert_eq!(status["program"], 2, "{status}");
    assert_eq!(status["program_phase"], "done", "{status}");
    assert_eq!(status["position"], serde_json::json!([20.0, 5.0, 0.0]));
    // Nothing was lost or merged: one block each.
    assert_eq!(status["blocks_accepted"], 2, "{status}");
}

#[test]
fn programs_are_converted_from_where_the_machine_is() {
    let dir = temp_dir("from-here");
    let srv = Server::start(
        &service_name("from-here"),
        &["--no-socket", "--position", "20", "20", "0"],
    );
    let rel = write(&dir, "rel.ngc", "G91 G1 X5 F3000\nG1 Y5\n");
    let (st, status, err) = send(srv.port, &rel, &[]);
    assert!(st.success(), "{err}");
    assert_eq!(
        status.unwrap()["position"],
        serde_json::json!([25.0, 25.0, 0.0])
    );
    // A first move to the origin is a move, not something to skip.
    let origin = write(&dir, "origin.ngc", "G1 X0 Y0 F3000\nG1 X10 Y0\n");
    let (st, status, err) = send(srv.port, &origin, &[]);
    assert!(st.success(), "{err}");
    let status = status.unwrap();
    assert_eq!(status["position"], serde_json::json!([10.0, 0.0, 0.0]));
    assert_eq!(status["blocks_accepted"], 4, "{status}");
    // A first move to where the machine is has no length: it is dropped.
    let here = write(&dir, "here.ngc", "G1 X10 Y0 F3000\nG1 X10 Y5\n");
    let (st, status, err) = send(srv.port, &here, &[]);
    assert!(st.success(), "{err}");
    let status = status.unwrap();
    assert_eq!(status["position"], serde_json::json!([10.0, 5.0, 0.0]));
    assert_eq!(status["blocks_accepted"], 5, "{status}");
}

#[test]
fn hold_is_for_motion_and_every_refused_start_says_why() {
    let srv = Server::start(&service_name("hold-start"), &["--no-socket"]);
    let mut c = srv.connect();
    let r = c.ask("start");
    assert!(r.starts_with("err 1 start: no program"), "{r}");
    let r = c.ask("hold");
    assert!(
        r.starts_with("err 2 hold: nothing is moving (state idle"),
        "{r}"
    );
    assert!(
        c.ask(&line_to([30.0, 0.0, 0.0], 1200.0, 1))
            .starts_with("ok")
    );
    let r = c.ask("hold");
    assert!(r.starts_with("err 4 hold: nothing is moving"), "{r}");
    assert_eq!(c.ask("start"), "ok start");
    let r = c.ask("start");
    assert!(
        r.starts_with("err 6 start: program 1 is already started"),
        "{r}"
    );
    c.wait_for("motion", |s| s["s"].as_f64().unwrap() > 1.0);
    assert_eq!(c.ask("hold"), "ok hold");
    c.wait_for("held", |s| s["state"] == "holding");
    let r = c.ask("start");
    assert!(
        r.contains("start: the machine is holding program 1 (send resume)"),
        "{r}"
    );
    assert_eq!(c.ask("resume"), "ok resume");
    // A command acts a planning lead later: resumed once it moves again.
    c.wait_for("moving again", |s| s["state"] == "running");
    let r = c.ask("resume");
    assert!(r.contains("resume: the machine is not holding"), "{r}");
    assert_eq!(c.ask("end"), "ok end");
    c.wait_for("done", |s| s["program_phase"] == "done");
    let r = c.ask("start");
    assert!(r.contains("start: program 1 is done"), "{r}");
    let r = c.ask("hold");
    assert!(r.contains("hold: nothing is moving (state done"), "{r}");
    // A client that leaves before `start` does not leave a hold behind:
    // whoever starts its program sees it move.
    let mut d = srv.connect();
    assert!(
        d.ask(&line_to([30.0, 8.0, 0.0], 1200.0, 1))
            .starts_with("ok")
    );
    drop(d);
    std::thread::sleep(Duration::from_millis(100));
    assert_eq!(c.ask("start"), "ok start");
    c.wait_for("running", |s| {
        s["state"] == "running" && s["s"].as_f64().unwrap() > 30.5
    });
    // And the next connection takes the orphaned program over to end it.
    assert_eq!(c.ask("end"), "ok end");
    let s = c.wait_for("done", |s| s["program_phase"] == "done");
    assert_eq!(s["position"], serde_json::json!([30.0, 8.0, 0.0]));
}

/// A command acts a planning lead after it is sent (40 ms): an operator's
/// resume right after a hold, or a hold right after a resume, is taken for
/// what it is, not refused because the machine has not acted yet. (The
/// resume was refused, "the machine is not holding (state running)", and
/// the machine then stayed held.)
#[test]
fn a_resume_right_after_a_hold_resumes_and_a_hold_right_after_a_resume_holds() {
    let srv = Server::start(&service_name("hold-resume"), &["--no-socket"]);
    let mut c = srv.connect();
    assert!(
        c.ask(&line_to([60.0, 0.0, 0.0], 6000.0, 1))
            .starts_with("ok")
    );
    assert_eq!(c.ask("end"), "ok end");
    assert_eq!(c.ask("start"), "ok start");
    c.wait_for("motion", |s| s["s"].as_f64().unwrap() > 1.0);
    assert_eq!(c.ask("hold"), "ok hold");
    let r = c.ask("hold");
    assert!(r.contains("hold: the machine is already holding"), "{r}");
    assert_eq!(c.ask("resume"), "ok resume");
    let r = c.ask("resume");
    assert!(r.contains("resume: the machine is not holding"), "{r}");
    assert_eq!(c.ask("hold"), "ok hold");
    c.wait_for("held", |s| s["state"] == "holding" && s["feed"] == 0.0);
    assert_eq!(c.ask("resume"), "ok resume");
    assert_eq!(c.ask("hold"), "ok hold");
    assert_eq!(c.ask("resume"), "ok resume");
    // Resumed last: it runs to its end.
    let s = c.wait_for("done", |s| s["program_phase"] == "done");
    assert_eq!(s["position"], serde_json::json!([60.0, 0.0, 0.0]));
}

#[test]
fn serve_does_not_take_over_a_path_that_is_not_its_socket() {
    let dir = temp_dir("socket-path");
    // A regular file is refused and left alone.
    let file = write(&dir, "notes.txt", "keep me\n");
    let out = std::process::Command::new(interpd())
        .args(["serve", "--port", "0", "--service"])
        .arg(service_name("socket-file"))
        .arg("--socket")
        .arg(&file)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("is not a socket"), "{err}");
    assert_eq!(std::fs::read_to_string(&file).unwrap(), "keep me\n");
    // A live server's socket is refused; that server still answers on it.
    let sock = dir.join("interpd.sock");
    let srv = Server::start(
        &service_name("socket-live"),
        &["--socket", sock.to_str().unwrap()],
    );
    let out = std::process::Command::new(interpd())
        .args(["serve", "--port", "0", "--service"])
        .arg(service_name("socket-second"))
        .arg("--socket")
        .arg(&sock)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("another server answers on"), "{err}");
    let mut c = Conn::unix(&sock);
    assert!(c.ask("status").starts_with("status {"));
    // A stale socket (its server was killed) is taken over.
    signal(srv.child.id(), 9);
    drop(srv);
    let srv = Server::start(
        &service_name("socket-stale"),
        &["--socket", sock.to_str().unwrap()],
    );
    assert!(Conn::unix(&sock).ask("status").starts_with("status {"));
    drop(srv);
}

#[test]
fn send_to_a_server_that_dies_says_the_server_went_away() {
    let dir = temp_dir("dying");
    let srv = Server::start(&service_name("dying"), &["--no-socket"]);
    // Many short blocks: still streaming when the server dies.
    let mut text = String::new();
    for i in 1..=3000 {
        text.push_str(&format!("G1 X{} F600\n", i as f64 * 0.01));
    }
    let prog = write(&dir, "many.ngc", &text);
    let child = std::process::Command::new(interpd())
        .args(["send", "--quiet", "--addr"])
        .arg(format!("127.0.0.1:{}", srv.port))
        .arg(&prog)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut c = srv.connect();
    c.wait_for("motion", |s| s["s"].as_f64().unwrap() > 0.05);
    signal(srv.child.id(), 9);
    let out = wait_child(child, "send to a dead server");
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("the server closed the connection (it stopped or crashed)"),
        "{err}"
    );
    drop(srv);
}

/// The line limit fits the largest block the protocol promises: a NURBS of
/// 4,096 control points written at full precision.
#[test]
fn a_nurbs_of_the_most_control_points_at_full_precision_fits_one_line() {
    let n = 4096usize;
    let degree = 3usize;
    // Along X with a wiggle in Y, every number with 17 significant digits.
    let points: Vec<[f64; 3]> = (0..n)
        .map(|i| {
            let t = i as f64 / (n - 1) as f64;
            [
                40.0 * t + 1e-9 * (i as f64).sin(),
                0.123_456_789_012_345_67 * (7.0 * t).sin(),
                -0.987_654_321_098_765_4 * t * (1.0 - t),
            ]
        })
        .collect();
    let mut points = points;
    points[0] = [0.0; 3]; // where the machine is
    let weights: Vec<f64> = (0..n)
        .map(|i| 1.0 + 0.123_456_789_012_345_6 * ((i as f64) * 0.37).sin().abs())
        .collect();
    let inner = n - degree - 1;
    let mut knots = vec![0.0; degree + 1];
    knots.extend((1..=inner).map(|k| k as f64 / (inner + 1) as f64));
    knots.extend(vec![1.0; degree + 1]);
    let line = serde_json::json!({
        "feed": 6000.0, "kind": "nurbs", "degree": degree,
        "points": points, "weights": weights, "knots": knots,
    })
    .to_string();
    assert!(line.len() > 300_000, "{} bytes", line.len());
    let srv = Server::start(&service_name("big-nurbs"), &["--no-socket", "--autostart"]);
    let mut c = srv.connect();
    let r = c.ask(&line);
    assert!(r.starts_with("ok block 1 segments 1..="), "{r}");
    assert_eq!(c.ask("end"), "ok end");
    let s = c.wait_for("done", |s| s["program_phase"] == "done");
    let end = s["position"][0].as_f64().unwrap();
    assert!((end - points[n - 1][0]).abs() < 1e-9, "{s}");
}

/// The RT thread reaches the system allocator not once in a session of
/// several programs from several connections (streamed, two at once,
/// held, resumed, aborted, refused as busy) with a subscriber joining:
/// `serve` counts what its RT pool could not serve and prints it.
#[test]
fn the_rt_thread_makes_no_system_allocation_in_a_session_of_several_programs() {
    let dir = temp_dir("rt-alloc");
    let srv = Server::start(&service_name("rt-alloc"), &["--no-socket", "--json"]);
    let square = write(&dir, "square.ngc", "G1 X10 F3000\nG1 Y10\nG1 X0\nG1 Y0\n");
    let arcs = write(
        &dir,
        "arcs.ngc",
        "G1 X5 F3000\nG2 X15 Y0 I5 J0\nG3 X5 Y0 I-5 J0\n",
    );
    for prog in [&square, &arcs, &square] {
        let (st, _, err) = send(srv.port, prog, &[]);
        assert!(st.success(), "{err}");
    }
    // A subscriber joins mid-session (iceoryx2 connects it on the RT
    // thread's next publish) while two sends start at once: one runs, the
    // other is refused as busy (or runs after it, on a slow machine).
    let watcher = std::process::Command::new(interpd())
        .args(["watch", "--count", "300", "--service", &srv.service])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let (one, two) = std::thread::scope(|s| {
        let one = s.spawn(|| send(srv.port, &arcs, &[]));
        let two = s.spawn(|| send(srv.port, &square, &[]));
        (one.join().unwrap(), two.join().unwrap())
    });
    assert!(one.0.success() || two.0.success(), "{} / {}", one.2, two.2);
    for (st, _, err) in [&one, &two] {
        assert!(st.success() || err.contains("busy: program"), "{err}");
    }
    let w = wait_child(watcher, "interpd watch --count 300");
    assert!(w.status.success(), "{}", String::from_utf8_lossy(&w.stderr));
    // Two connections: one streams, the other is refused, holds, resumes and aborts.
    let mut a = srv.connect();
    let mut b = srv.connect();
    let x = a.status()["position"][0].as_f64().unwrap();
    assert!(
        a.ask(&line_to([x + 40.0, 0.0, 0.0], 1800.0, 1))
            .starts_with("ok")
    );
    assert!(b.ask(&line_to([0.0, 3.0, 0.0], 1800.0, 1)).contains("busy"));
    assert_eq!(b.ask("start"), "ok start");
    b.wait_for("motion", |s| {
        s["state"] == "running" && s["feed"].as_f64().unwrap() > 0.0
    });
    assert_eq!(b.ask("hold"), "ok hold");
    b.wait_for("held", |s| s["state"] == "holding");
    assert_eq!(b.ask("resume"), "ok resume");
    assert_eq!(b.ask("override 1.5"), "ok override 1.5");
    assert_eq!(b.ask("abort"), "ok abort");
    // And one more program after the abort, from yet another connection.
    let (st, _, err) = send(srv.port, &square, &[]);
    assert!(st.success(), "{err}");
    let (st, text) = srv.stop();
    assert!(st.success(), "{text}");
    let summary: serde_json::Value = serde_json::from_str(
        text.lines()
            .rev()
            .find(|l| l.starts_with('{'))
            .expect("JSON summary"),
    )
    .expect("summary JSON");
    assert!(
        summary["rt_pool_served"].as_u64().unwrap() > 1000,
        "{summary}"
    );
    assert_eq!(summary["rt_pool_fallbacks"], 0, "{summary}");
}

#[test]
fn a_numeric_flag_out_of_range_is_refused_naming_it() {
    let dir = temp_dir("flag-ranges");
    let prog = write(&dir, "p.ngc", "G1 X5 F3000\n");
    let p = prog.to_str().unwrap();
    let stl = write(&dir, "p.stl", "solid p\nendsolid p\n");
    let stl = stl.to_str().unwrap();
    for (args, says) in [
        (
            &["demo", "--no-service", "--feed", "1e308"][..],
            "'--feed <MM_PER_MIN>': 1e308 is outside (0, 120000] mm/min",
        ),
        (
            &["demo", "--no-service", "--accel=-1"][..],
            "'--accel <MM_PER_S2>': -1 is outside (0, 1000000] mm/s²",
        ),
        (
            &["simulate", p, "--max-speed", "inf"][..],
            "'--max-speed <MM_PER_S>': inf is outside (0, 2000] mm/s",
        ),
        (
            &["simulate", p, "--period-us", "1e-300"][..],
            "'--period-us <US>': 1e-300 is outside [1, 1000000] µs",
        ),
        // A configuration key names itself.
        (
            &["simulate", p, "--set", "max-path-speed=1e308"][..],
            "interp.max-path-speed 1e308 is out of range: it must be a number in (0, 2000] mm/s",
        ),
        (
            &["simulate", p, "--set", "axis-max-jerk=[1e300, 1e6, 1e6]"][..],
            "interp.axis-max-jerk 1e300 is out of range: it must be a number in (0, 1000000000] mm/s³",
        ),
        (
            &[
                "serve",
                "--no-socket",
                "--port",
                "0",
                "--set",
                "max-path-accel=1e12",
            ][..],
            "interp.max-path-accel 1e12 is out of range",
        ),
        (
            &[
                "serve",
                "--no-socket",
                "--port",
                "0",
                "--position",
                "0",
                "0",
                "nan",
            ][..],
            "--position Z NaN is out of range: it must be a number in [-1000000, 1000000] mm",
        ),
        (
            &["watch", "--seconds", "inf"][..],
            "'--seconds <SECONDS>': inf is outside (0, 86400] s",
        ),
        (
            &["watch", "--check-feed", "0"][..],
            "'--check-feed <MM_PER_MIN>': 0 is outside (0, 120000] mm/min",
        ),
        (
            &["jitter", "--seconds", "nan"][..],
            "'--seconds <SECONDS>': nan is outside (0, 86400] s",
        ),
        (
            &[
                "plan", "gouge", "--stl", stl, "--path", p, "--tool", "ball:6", "--out", p,
                "--tol", "1e308",
            ][..],
            "'--tol <TOL>': 1e308 is outside (0, 10] mm",
        ),
        (
            &["plan", "fit", "--path", p, "--out", p, "--degree", "9"][..],
            "'--degree <DEGREE>': 9 is not in 1..=5",
        ),
    ] {
        let out = std::process::Command::new(interpd())
            .args(args)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?} accepted");
        assert!(err.contains(says), "{args:?}: {err}");
    }
}

/// The policy and real-time priority of the thread of process `pid` named
/// `name` (`/proc/PID/task/TID/stat`, fields 41 and 40).
#[cfg(target_os = "linux")]
fn thread_scheduling(pid: u32, name: &str) -> Option<(u32, u32)> {
    for task in std::fs::read_dir(format!("/proc/{pid}/task")).ok()? {
        let dir = task.ok()?.path();
        let comm = std::fs::read_to_string(dir.join("comm")).ok()?;
        if comm.trim() != name {
            continue;
        }
        let stat = std::fs::read_to_string(dir.join("stat")).ok()?;
        // Fields after the command's closing parenthesis start at field 3.
        let rest: Vec<&str> = stat.rsplit_once(") ")?.1.split_whitespace().collect();
        return Some((rest[41 - 3].parse().ok()?, rest[40 - 3].parse().ok()?));
    }
    None
}

/// The planning thread runs SCHED_FIFO below the RT thread (half its
/// priority), above every normally scheduled thread: scheduled normally it
/// fell behind on a loaded machine and the RT thread published its last
/// point again (BENCHMARKS.md, stop 45). Where the machine refuses
/// SCHED_FIFO to the RT thread too, both run normally and this says so.
#[cfg(target_os = "linux")]
#[test]
fn the_planning_thread_runs_sched_fifo_below_the_rt_thread() {
    let srv = Server::start(
        &service_name("plan-fifo"),
        &["--no-socket", "--priority", "60"],
    );
    let pid = srv.child.id();
    let rt = thread_scheduling(pid, "interpd-rt").expect("the RT thread");
    let plan = thread_scheduling(pid, "interpd-plan").expect("the planning thread");
    const SCHED_FIFO: u32 = 1;
    if rt.0 != SCHED_FIFO {
        eprintln!(
            "SCHED_FIFO refused here (RT thread policy {}): not checked",
            rt.0
        );
        return;
    }
    assert_eq!(rt, (SCHED_FIFO, 60));
    assert_eq!(plan, (SCHED_FIFO, 30));
}
