//! `interpd send PROGRAM`: streams a program to `interpd serve` with
//! back-pressure (at most [`WINDOW`] requests unanswered; the server answers a
//! block only once it is queued), shows progress, and waits for the end.
//!
//! It first claims a program (`begin`): the server names it and where it
//! starts, and a G-code program is converted from there (G91, a first move
//! to where the machine is or to the origin). `start` is sent (on a second
//! connection) as soon as the server stops answering for [`STALL`] (its
//! queue is full: the program is longer than the look-ahead) or after the
//! whole program was accepted, whichever comes first (a `start` refused
//! because no block is in yet is sent again); so a program that fits
//! runs exactly as `simulate` would. It then follows *its* program and exits
//! non-zero unless that program reached `done`. Ctrl-C sends `hold`, then
//! `abort`.

use std::collections::VecDeque;
use std::io::{IsTerminal, Write};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use crate::client::conn::{Connection, Endpoint, connect};
use crate::protocol::Reply;
use crate::service::control::{Phase, StatusReply};
use anyhow::{Context, Result, bail};
use tokio::io::{AsyncRead, AsyncWrite};

/// Requests in flight at most.
pub const WINDOW: usize = 8;
/// No reply for this long while requests are in flight means back-pressure.
pub const STALL: Duration = Duration::from_millis(100);
/// Status poll interval while waiting for the end.
const POLL: Duration = Duration::from_millis(50);
/// How often `--wait-turn` asks for a program again while the server is busy.
pub const TURN_POLL: Duration = Duration::from_millis(100);

/// Options of `interpd send`.
#[derive(Clone, Debug, PartialEq)]
pub struct SendOptions {
    /// The program: G-code (`.ngc`/`.nc`), a JSON program (`.json`), or JSON
    /// blocks one per line (`.jsonl`; blank lines and `#` comments skipped).
    pub program: PathBuf,
    /// TCP address of the server.
    pub addr: SocketAddr,
    /// Connect to this Unix socket instead of TCP.
    pub socket: Option<PathBuf>,
    /// Token, if the server wants one.
    pub token: Option<String>,
    /// Do not wait for the program to finish.
    pub no_wait: bool,
    /// When the server is busy with another connection's program, wait
    /// for it to end and take the next turn (polling `begin` every
    /// [`TURN_POLL`]) instead of failing at once.
    pub wait_turn: bool,
    /// Print the final status as JSON.
    pub json: bool,
    /// No progress output.
    pub quiet: bool,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Expect {
    Block,
}

/// The program's request lines: the file as the program loader reads it
/// ([`crate::program::load`], as `interpd simulate` does), G-code converted
/// from the joints `start` (where the program will start) for the server's
/// machine as its status reports it (rapids at its path-speed limit, its
/// five-axis machine).
pub fn program_lines(path: &Path, start: [f64; 6], server: &StatusReply) -> Result<Vec<String>> {
    let opts = crate::program::LoadOptions {
        start: Some(start),
        core: gcode::CoreOptions {
            rapid_speed: server.max_path_speed,
            machine: server.machine,
        },
    };
    let program = crate::program::load(path, &opts)?;
    Ok(program
        .blocks
        .iter()
        .map(crate::protocol::block_json)
        .collect())
}

/// Turns the program into request lines, given the joints where it starts
/// (the `begin` reply) and the server's status (its path-speed limit and
/// machine): [`program_lines`] for a file.
pub type Loader<'a> = dyn Fn([f64; 6], &StatusReply) -> Result<Vec<String>> + 'a;

impl SendOptions {
    /// Where the server listens: `socket`, else `addr`.
    pub fn endpoint(&self) -> Endpoint {
        match &self.socket {
            Some(p) => Endpoint::Unix(p.clone()),
            None => Endpoint::Tcp(self.addr),
        }
    }
}

/// Sends `start` on a connection of its own (authenticated like the stream).
/// Returns why the server refused it, if it did.
async fn start_aside(args: &SendOptions) -> Result<Option<String>> {
    let mut c = connect(&args.endpoint())
        .await
        .context("connecting for start")?;
    if let Some(t) = &args.token {
        c.auth(t).await?;
    }
    Ok(match c.request("start").await? {
        Reply::Err { problem, .. } => Some(problem),
        _ => None,
    })
}

/// How a `send` ended.
#[derive(Debug, PartialEq)]
pub enum Outcome {
    /// All accepted and its program reached `done` (with `--no-wait`: all
    /// accepted and started).
    Done,
    /// A line was refused (the program was aborted).
    Refused(String),
    /// Ctrl-C.
    Interrupted,
    /// The program ended otherwise than `done` (aborted, faulted).
    Ended {
        /// Its number.
        program: u32,
        /// How it ended.
        phase: Phase,
    },
    /// A later program began before this one was seen to end.
    Overtaken {
        /// This program.
        program: u32,
        /// The current one.
        now: u32,
    },
}

struct Progress {
    tty: bool,
    quiet: bool,
    last: Instant,
}

impl Progress {
    fn show(&mut self, msg: &str, force: bool) {
        if self.quiet {
            return;
        }
        if self.tty {
            eprint!("\r\x1b[2K{msg}");
            let _ = std::io::stderr().flush();
        } else if force || self.last.elapsed() >= Duration::from_secs(2) {
            eprintln!("{msg}");
            self.last = Instant::now();
        }
    }
    fn done(&self) {
        if self.tty && !self.quiet {
            eprintln!();
        }
    }
}

fn bar(done: usize, total: usize) -> String {
    const W: usize = 30;
    let f = (done * W).checked_div(total).unwrap_or(W);
    format!("[{}{}]", "#".repeat(f), ".".repeat(W - f))
}

/// Claims a program (`begin`), streams the lines `load` makes for its start
/// point and the machine's rapid speed, then `end` and `start`, then follows
/// that program to its end. Returns how it ended and the final status line (JSON).
pub async fn stream<S: AsyncRead + AsyncWrite + Unpin>(
    mut conn: Connection<S>,
    load: &Loader<'_>,
    args: &SendOptions,
) -> Result<(Outcome, String)> {
    if let Some(t) = &args.token {
        conn.auth(t).await?;
    }
    let mut sigint = tokio::signal::unix::signal(tokio::signal::unix::SignalKind::interrupt())
        .context("installing the Ctrl-C handler")?;
    // A busy server names the program that holds the machine: without
    // `--wait-turn` that is the answer; with it, ask again until our turn.
    let waiting_since = Instant::now();
    let mut told = false;
    let (program, at) = loop {
        match conn.request("begin").await? {
            Reply::Begin { program, at } => {
                // Said even with --quiet: two lines, not progress.
                if told {
                    eprintln!(
                        "interpd send: our turn after {:.1} s: program {program}",
                        waiting_since.elapsed().as_secs_f64()
                    );
                }
                break (program, at);
            }
            Reply::Err { problem, .. } if problem.starts_with("busy") && args.wait_turn => {
                if !told {
                    eprintln!("interpd send: {problem}; waiting for its end (--wait-turn)");
                }
                told = true;
                tokio::select! {
                    _ = tokio::time::sleep(TURN_POLL) => {}
                    _ = sigint.recv() => bail!(
                        "interrupted while waiting for the turn (nothing was sent)"
                    ),
                }
            }
            Reply::Err { problem, .. } if problem.starts_with("busy") => bail!(
                "the server refused a new program: {problem} \
                 (send --wait-turn waits for it to end)"
            ),
            Reply::Err { problem, .. } => bail!("the server refused a new program: {problem}"),
            other => bail!("unexpected reply to begin: {other}"),
        }
    };
    let st = conn.status().await?;
    let lines = load(at, &st)?;
    if lines.is_empty() {
        bail!("{} has no blocks", args.program.display());
    }
    let mut progress = Progress {
        tty: std::io::stderr().is_terminal(),
        quiet: args.quiet,
        last: Instant::now(),
    };
    let total = lines.len();
    let (mut sent, mut acked) = (0usize, 0usize);
    let mut expect: VecDeque<Expect> = VecDeque::new();
    let mut started = false;
    let mut refused: Option<String> = None;
    let mut interrupted = false;
    while acked < total && refused.is_none() {
        while sent < total && expect.len() < WINDOW {
            conn.send_line(&lines[sent])
                .await
                .with_context(|| format!("sending block {} of {total}", sent + 1))?;
            sent += 1;
            expect.push_back(Expect::Block);
        }
        tokio::select! {
            r = tokio::time::timeout(STALL, conn.reply()) => match r {
                Err(_) => {
                    // Back-pressure: the queue is full; let the machine run.
                    // `start` goes over a second connection: on this one it
                    // would wait behind the block the server is holding
                    // until the queue drains, which needs `start`.
                    // A slow answer to the first block is no full queue:
                    // `start` is refused then (no blocks yet) and tried
                    // again at the next stall or after the last block.
                    if !started {
                        started = start_aside(args).await?.is_none();
                    }
                }
                Ok(reply) => {
                    let reply = reply?;
                    match expect.pop_front() {
                        Some(Expect::Block) => {
                            if reply.is_ok() {
                                acked += 1;
                            } else {
                                refused = Some(format!("block {} of {total}: {reply}", acked + 1));
                            }
                        }
                        None => bail!("unexpected reply {reply}"),
                    }
                    progress.show(&format!("{} {acked}/{total} blocks queued", bar(acked, total)), false);
                }
            },
            _ = sigint.recv() => { interrupted = true; break; }
        }
    }
    // Replies still owed are read by `request` below in order.
    let request = async |conn: &mut Connection<S>,
                         expect: &mut VecDeque<Expect>,
                         req: &str|
           -> Result<Reply> {
        conn.send_line(req).await?;
        while expect.pop_front().is_some() {
            conn.reply().await?;
        }
        conn.reply().await
    };
    let status =
        async |conn: &mut Connection<S>, expect: &mut VecDeque<Expect>| -> Result<StatusReply> {
            match request(conn, expect, "status").await? {
                Reply::Status(s) => Ok(*s),
                other => bail!("unexpected reply to status: {other}"),
            }
        };
    let json = |s: &StatusReply| serde_json::to_string(s).unwrap_or_default();
    if interrupted || refused.is_some() {
        progress.done();
        if interrupted {
            eprintln!("interpd send: interrupted: hold, then abort");
            request(&mut conn, &mut expect, "hold").await?;
        }
        if let Reply::Err { problem, .. } = request(&mut conn, &mut expect, "abort").await? {
            eprintln!("interpd send: abort: {problem}");
        }
        let st = status(&mut conn, &mut expect).await?;
        return Ok((
            match refused {
                Some(e) => Outcome::Refused(e),
                None => Outcome::Interrupted,
            },
            json(&st),
        ));
    }
    if let Reply::Err { problem, .. } = request(&mut conn, &mut expect, "end").await? {
        bail!("end refused: {problem}");
    }
    if !started && let Reply::Err { problem, .. } = request(&mut conn, &mut expect, "start").await?
    {
        eprintln!("interpd send: {problem}");
    }
    loop {
        let st = status(&mut conn, &mut expect).await?;
        // The next program (a `--wait-turn` client's) may be claimed the
        // moment ours is over: the status still says how ours ended.
        if st.program != program && st.previous_program == program {
            progress.done();
            let outcome = match st.previous_phase {
                Phase::Done => Outcome::Done,
                phase => Outcome::Ended { program, phase },
            };
            return Ok((outcome, json(&st)));
        }
        if st.program != program {
            progress.done();
            return Ok((
                Outcome::Overtaken {
                    program,
                    now: st.program,
                },
                json(&st),
            ));
        }
        let msg = if st.machine_program == program {
            format!(
                "program {program}: {} at {:.3} mm, block {}",
                st.state, st.s, st.block_id
            )
        } else {
            format!(
                "program {program}: waiting for the machine (it runs program {})",
                st.machine_program
            )
        };
        progress.show(
            &format!("{} {total}/{total} blocks queued, {msg}", bar(total, total)),
            false,
        );
        let ended = match st.program_phase {
            Phase::Done => Some(Outcome::Done),
            Phase::Aborted | Phase::Fault | Phase::None => Some(Outcome::Ended {
                program,
                phase: st.program_phase,
            }),
            // Accepted and started (committed, or waiting for the program before it).
            Phase::Open | Phase::Ended if args.no_wait => Some(Outcome::Done),
            Phase::Open | Phase::Ended => None,
        };
        if let Some(outcome) = ended {
            progress.done();
            return Ok((outcome, json(&st)));
        }
        tokio::select! {
            _ = tokio::time::sleep(POLL) => {}
            _ = sigint.recv() => {
                progress.done();
                eprintln!("interpd send: interrupted: hold, then abort");
                request(&mut conn, &mut expect, "hold").await?;
                request(&mut conn, &mut expect, "abort").await?;
                let st = status(&mut conn, &mut expect).await?;
                return Ok((Outcome::Interrupted, json(&st)));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::{Arc, Mutex};
    use tokio::io::{AsyncBufReadExt, AsyncWriteExt, BufReader};

    /// What the stand-in server saw.
    #[derive(Default)]
    struct Seen {
        blocks: u32,
        started: bool,
        ended: bool,
        refused_starts: u32,
    }

    fn status(seen: &Seen) -> StatusReply {
        let phase = match (seen.ended, seen.started) {
            (true, true) => "done",
            (true, false) => "ended",
            _ => "open",
        };
        serde_json::from_value(serde_json::json!({
            "state": if seen.started { "done" } else { "idle" },
            "started": seen.started, "finished": seen.ended,
            "program": 1, "program_phase": phase, "program_owner": null,
            "machine_program": 1, "ticks": 0, "published": 0, "block_id": 0,
            "position": [0.0, 0.0, 0.0], "feed": 0.0, "s": 0.0,
            "feed_override": 1.0, "max_path_speed": 100.0, "queued_segments": 0,
            "blocks_accepted": seen.blocks, "pieces_pushed": 0, "pieces_refused": 0,
            "last_refusal": null, "line_errors": 0, "overruns": 0, "planner_late": 0,
            "recorder_drops": 0, "publish_failures": 0,
        }))
        .unwrap()
    }

    /// A server that takes `first_block` to answer the first block and, as
    /// `interpd serve` does, refuses `start` until a block of the program
    /// was accepted.
    async fn slow_first_block_server(first_block: Duration) -> (SocketAddr, Arc<Mutex<Seen>>) {
        let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
        let addr = listener.local_addr().unwrap();
        let seen = Arc::new(Mutex::new(Seen::default()));
        let shared = seen.clone();
        tokio::spawn(async move {
            while let Ok((sock, _)) = listener.accept().await {
                let seen = shared.clone();
                tokio::spawn(async move {
                    let (rd, mut wr) = tokio::io::split(sock);
                    let mut lines = BufReader::new(rd).lines();
                    let mut n = 0;
                    while let Ok(Some(line)) = lines.next_line().await {
                        n += 1;
                        let reply = match line.trim() {
                            "begin" => Reply::Begin {
                                program: 1,
                                at: [0.0; 6],
                            },
                            "status" => Reply::Status(Box::new(status(&seen.lock().unwrap()))),
                            "end" => {
                                seen.lock().unwrap().ended = true;
                                Reply::End
                            }
                            "start" => {
                                let mut s = seen.lock().unwrap();
                                if s.blocks == 0 {
                                    s.refused_starts += 1;
                                    Reply::Err {
                                        line: n,
                                        problem: "start: program 1 has no blocks yet".into(),
                                    }
                                } else {
                                    s.started = true;
                                    Reply::Start
                                }
                            }
                            _ => {
                                if seen.lock().unwrap().blocks == 0 {
                                    tokio::time::sleep(first_block).await;
                                }
                                let mut s = seen.lock().unwrap();
                                s.blocks += 1;
                                Reply::Block {
                                    index: s.blocks,
                                    first: s.blocks,
                                    last: s.blocks,
                                }
                            }
                        };
                        if wr.write_all(format!("{reply}\n").as_bytes()).await.is_err() {
                            break;
                        }
                    }
                });
            }
        });
        (addr, seen)
    }

    #[test]
    fn a_slow_first_block_still_gets_the_program_started() {
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .unwrap();
        rt.block_on(async {
            // Slower than a stall: `start` is first sent, and refused, before
            // the first block is in.
            let (addr, seen) = slow_first_block_server(STALL * 4).await;
            let args = SendOptions {
                program: PathBuf::from("two.jsonl"),
                addr,
                socket: None,
                token: None,
                no_wait: false,
                wait_turn: false,
                json: true,
                quiet: true,
            };
            let load = |_: [f64; 6], _: &StatusReply| -> Result<Vec<String>> {
                Ok(vec!["{}".into(), "{}".into()])
            };
            let conn = connect(&args.endpoint()).await.unwrap();
            let (outcome, _) =
                tokio::time::timeout(Duration::from_secs(10), stream(conn, &load, &args))
                    .await
                    .expect("send waits for a program that nobody started")
                    .unwrap();
            assert_eq!(outcome, Outcome::Done);
            let s = seen.lock().unwrap();
            assert!(s.refused_starts >= 1, "the race was not run");
            assert!(s.started && s.blocks == 2);
        });
    }
}
