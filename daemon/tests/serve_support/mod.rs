//! Shared helpers of the `serve_*` end-to-end tests: locate the `interpd`
//! binary cargo built for them, start `interpd serve` on a private iceoryx2 service and a
//! free port, talk the line protocol through the library's client (every
//! reply read through the library's typed [`Reply`], which must print it
//! back to the same line), read
//! `interpd watch` CSV files.
#![allow(dead_code)] // each test file uses a subset

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use interpd::client::conn::{BlockingConnection, Endpoint};
use interpd::protocol::Reply;
use interpd::service::publish::{run_state, state_name};

/// How long a test waits for any one thing before failing.
pub const WAIT: Duration = Duration::from_secs(20);

/// The `interpd` binary cargo built for these tests (the test profile).
pub fn interpd() -> &'static Path {
    Path::new(env!("CARGO_BIN_EXE_interpd"))
}

/// A unique name for this test's iceoryx2 service.
pub fn service_name(test: &str) -> String {
    format!("interpd-test/{}/{test}", std::process::id())
}

/// A temporary directory for one test.
pub fn temp_dir(test: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("interpd-test-{}-{test}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("temp dir");
    d
}

/// A running `interpd serve`.
pub struct Server {
    pub child: Child,
    pub port: u16,
    pub service: String,
    pub stdout: BufReader<std::process::ChildStdout>,
}

impl Server {
    /// Starts `interpd serve --port 0` on `service` with `extra` flags, and
    /// waits for its "listening on tcp" line.
    pub fn start(service: &str, extra: &[&str]) -> Server {
        let mut child = Command::new(interpd())
            .args(["serve", "--port", "0", "--service", service])
            .args(extra)
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("starting interpd serve");
        let mut stdout = BufReader::new(child.stdout.take().expect("stdout"));
        let mut port = None;
        let mut line = String::new();
        while port.is_none() {
            line.clear();
            let n = stdout.read_line(&mut line).expect("reading serve's stdout");
            assert!(n > 0, "interpd serve exited before listening");
            if let Some(rest) = line.trim().strip_prefix("interpd: listening on tcp ") {
                let addr: std::net::SocketAddr = rest.parse().expect("address");
                port = Some(addr.port());
            }
        }
        // Read the other start lines (unix socket, service).
        Server {
            child,
            port: port.expect("port"),
            service: service.to_owned(),
            stdout,
        }
    }

    /// A protocol connection (the library's client, over TCP).
    pub fn connect(&self) -> Conn {
        Conn::tcp(self.port)
    }

    /// SIGTERM, then the exit status and everything it printed after starting.
    pub fn stop(mut self) -> (std::process::ExitStatus, String) {
        // SAFETY: kill with a valid pid and signal.
        unsafe { libc_kill(self.child.id() as i32, 15) };
        let mut rest = String::new();
        let _ = std::io::Read::read_to_string(&mut self.stdout, &mut rest);
        let st = self.child.wait().expect("wait");
        (st, rest)
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

unsafe extern "C" {
    #[link_name = "kill"]
    fn libc_kill(pid: i32, sig: i32) -> i32;
}

/// Sends a signal to a process.
pub fn signal(pid: u32, sig: i32) {
    // SAFETY: kill takes a pid and a signal number.
    unsafe { libc_kill(pid as i32, sig) };
}

/// One line-protocol connection: the library's blocking client
/// ([`BlockingConnection`], what `interpd send` runs on, async), with the
/// test's checks on every reply.
pub struct Conn(pub BlockingConnection);

impl Conn {
    /// Over TCP to the loopback `port`.
    pub fn tcp(port: u16) -> Conn {
        let at = Endpoint::Tcp(std::net::SocketAddr::from(([127, 0, 0, 1], port)));
        Conn(BlockingConnection::connect(&at, WAIT).expect("connect"))
    }

    /// Over the Unix socket at `path`.
    pub fn unix(path: &Path) -> Conn {
        let at = Endpoint::Unix(path.to_owned());
        Conn(BlockingConnection::connect(&at, WAIT).expect("connect"))
    }

    /// Sends one line, returns the reply.
    pub fn ask(&mut self, line: &str) -> String {
        self.send(line);
        self.reply()
    }

    /// Sends one line.
    pub fn send(&mut self, line: &str) {
        self.0.send_line(line).expect("write");
    }

    /// Reads one reply line. It must parse as the library's [`Reply`] and
    /// print back to the same line.
    pub fn reply(&mut self) -> String {
        let line = self.0.reply_line().expect("reply");
        let typed = Reply::parse(&line).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(typed.to_string(), line, "the reply does not print back");
        line
    }

    /// The typed reply to one request.
    pub fn ask_typed(&mut self, line: &str) -> Reply {
        Reply::parse(&self.ask(line)).expect("checked by reply")
    }

    /// The status as JSON (read through the library's typed status).
    pub fn status(&mut self) -> serde_json::Value {
        match self.ask_typed("status") {
            Reply::Status(s) => serde_json::to_value(&*s).expect("status JSON"),
            other => panic!("not a status: {other}"),
        }
    }

    /// Polls the status until `pred` holds.
    pub fn wait_for(
        &mut self,
        what: &str,
        pred: impl Fn(&serde_json::Value) -> bool,
    ) -> serde_json::Value {
        let t0 = Instant::now();
        loop {
            let s = self.status();
            if pred(&s) {
                return s;
            }
            assert!(t0.elapsed() < WAIT, "timed out waiting for {what}: {s}");
            std::thread::sleep(Duration::from_millis(5));
        }
    }
}

/// One row of `interpd watch --csv`.
#[derive(Debug, Clone, Copy)]
pub struct Row {
    pub seq: u64,
    pub tick: u64,
    pub p: [f64; 3],
    pub feed: f64,
    pub block_id: u32,
    pub state: &'static str,
}

/// Reads a `watch` CSV.
pub fn read_csv(path: &Path) -> Vec<Row> {
    let text = std::fs::read_to_string(path).expect("csv");
    text.lines()
        .skip(1)
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            let num = |i: usize| f[i].parse::<f64>().expect("number");
            Row {
                seq: f[0].parse().expect("seq"),
                tick: f[1].parse().expect("tick"),
                p: [num(3), num(4), num(5)],
                feed: num(6),
                block_id: f[9].parse().expect("block id"),
                state: (0..6)
                    .map(|c| state_name(run_state(c)))
                    .find(|s| *s == f[10])
                    .expect("state"),
            }
        })
        .collect()
}

/// Starts `interpd watch --until-done --csv PATH` on `service`, checking
/// every tick against the default limits at `check_feed` mm/min.
pub fn watch(service: &str, csv: &Path, check_feed: f64) -> Child {
    Command::new(interpd())
        .args([
            "watch",
            "--until-done",
            "--json",
            "--service",
            service,
            "--check-feed",
            &check_feed.to_string(),
            "--csv",
        ])
        .arg(csv)
        .stdout(Stdio::piped())
        .spawn()
        .expect("starting interpd watch")
}

/// Waits for a child with a deadline; kills it on timeout.
pub fn wait_child(mut c: Child, what: &str) -> std::process::Output {
    let t0 = Instant::now();
    loop {
        if c.try_wait().expect("try_wait").is_some() {
            return c.wait_with_output().expect("output");
        }
        if t0.elapsed() > WAIT {
            let _ = c.kill();
            let out = c.wait_with_output().expect("output");
            panic!(
                "{what} did not finish in {WAIT:?}; stdout: {}; stderr: {}",
                String::from_utf8_lossy(&out.stdout),
                String::from_utf8_lossy(&out.stderr)
            );
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// A JSON line block (the `traces` JSON block form). `_n` is the block's
/// number in the test, for the reader only.
pub fn line_to(end: [f64; 3], feed_mm_min: f64, _n: u32) -> String {
    serde_json::json!({"feed": feed_mm_min, "kind": "line", "end": end}).to_string()
}

/// Distance from `p` to the segment `a`–`b`.
pub fn dist_to_segment(p: [f64; 3], a: [f64; 3], b: [f64; 3]) -> f64 {
    let ab = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let ap = [p[0] - a[0], p[1] - a[1], p[2] - a[2]];
    let l2: f64 = ab.iter().map(|x| x * x).sum();
    let t = if l2 > 0.0 {
        (ap.iter().zip(&ab).map(|(x, y)| x * y).sum::<f64>() / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (0..3)
        .map(|i| (a[i] + t * ab[i] - p[i]).powi(2))
        .sum::<f64>()
        .sqrt()
}

/// Starts `interpd send --json --quiet` of `program` to `port` (with `extra`
/// flags), its output piped.
pub fn spawn_send(port: u16, program: &Path, extra: &[&str]) -> Child {
    Command::new(interpd())
        .args(["send", "--json", "--quiet", "--addr"])
        .arg(format!("127.0.0.1:{port}"))
        .args(extra)
        .arg(program)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("interpd send")
}

/// Runs `interpd send --json` of `program` to `port` (with `extra` flags) and
/// returns its exit status, its final status (JSON, if it printed one) and
/// its standard error.
pub fn send(
    port: u16,
    program: &Path,
    extra: &[&str],
) -> (std::process::ExitStatus, Option<serde_json::Value>, String) {
    let out = wait_child(spawn_send(port, program, extra), "interpd send");
    let status = serde_json::from_slice(&out.stdout).ok();
    (
        out.status,
        status,
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// Kills `srv` (SIGKILL), starts it again on the same service 5 mm away (at
/// 3 4 0: its first point is 5 mm from the origin), lets it publish a
/// moment and kills it too: a subscriber sees a restart, then silence.
pub fn crash_and_restart_elsewhere(srv: Server) {
    let service = srv.service.clone();
    signal(srv.child.id(), 9);
    drop(srv);
    let srv = Server::start(&service, &["--no-socket", "--position", "3", "4", "0"]);
    std::thread::sleep(Duration::from_millis(300));
    signal(srv.child.id(), 9);
    drop(srv);
}
