//! `interpd send PROGRAM`: streams a program to `interpd serve` with
//! back-pressure (at most [`WINDOW`] requests unanswered; the server answers a
//! block only once it is queued), shows progress, and waits for the end.
//!
//! `start` is sent (on a second connection) as soon as the server stops answering for [`STALL`] (its
//! queue is full: the program is longer than the look-ahead) or after the
//! whole program was accepted, whichever comes first; so a program that fits
//! runs exactly as `simulate` would. Ctrl-C sends `hold`, then `abort`.

use std::collections::VecDeque;
use std::io::{IsTerminal, Write};
use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{Context, Result, anyhow, bail};
use serde::Deserialize;
use tokio::io::{AsyncBufReadExt, AsyncRead, AsyncWrite, AsyncWriteExt, BufReader};

use crate::serve::DEFAULT_PORT;

/// Speed of rapid moves (G0) when a G-code program is converted, mm/s.
const RAPID_SPEED_MM_S: f64 = 100.0;
/// Requests in flight at most.
pub const WINDOW: usize = 8;
/// No reply for this long while requests are in flight means back-pressure.
pub const STALL: Duration = Duration::from_millis(100);
/// Status poll interval while waiting for the end.
const POLL: Duration = Duration::from_millis(50);

/// Options of `interpd send`.
#[derive(Clone, Debug, clap::Args)]
pub struct SendArgs {
    /// The program: G-code (`.ngc`/`.nc`), a JSON program (`.json`), or JSON
    /// blocks one per line (`.jsonl`; blank lines and `#` comments skipped).
    pub program: PathBuf,
    /// TCP address of the server.
    #[arg(long, default_value_t = SocketAddr::from(([127, 0, 0, 1], DEFAULT_PORT)))]
    pub addr: SocketAddr,
    /// Connect to this Unix socket instead of TCP.
    #[arg(long, value_name = "PATH")]
    pub socket: Option<PathBuf>,
    /// Token, if the server wants one.
    #[arg(long)]
    pub token: Option<String>,
    /// Do not wait for the program to finish.
    #[arg(long)]
    pub no_wait: bool,
    /// Print the final status as JSON.
    #[arg(long)]
    pub json: bool,
    /// No progress output.
    #[arg(long)]
    pub quiet: bool,
}

/// The status fields `send` looks at.
#[derive(Debug, Deserialize)]
struct Status {
    state: String,
    s: f64,
    block_id: u32,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Expect {
    Block,
}

/// Reads the program's request lines: G-code (`.ngc`, `.nc`) and JSON
/// programs (`.json`, `{"start": …, "blocks": […]}`) are converted here to the
/// JSON block form, as `interpd simulate` reads them; anything else is taken
/// as JSON blocks, one per line.
pub fn program_lines(path: &PathBuf) -> Result<Vec<String>> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or_default();
    if matches!(ext, "ngc" | "nc" | "json") {
        let program = crate::simulate::load_program(path, RAPID_SPEED_MM_S)?;
        return Ok(program
            .blocks
            .iter()
            .map(crate::protocol::block_json)
            .collect());
    }
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    Ok(text
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with('#'))
        .map(str::to_owned)
        .collect())
}

/// Runs `send`.
pub fn main(args: &SendArgs) -> Result<()> {
    let lines = program_lines(&args.program)?;
    if lines.is_empty() {
        bail!("{} has no blocks", args.program.display());
    }
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?;
    let (code, status) = rt.block_on(async {
        match &args.socket {
            Some(p) => {
                let s = tokio::net::UnixStream::connect(p)
                    .await
                    .with_context(|| format!("connecting to {}", p.display()))?;
                stream(s, &lines, args).await
            }
            None => {
                let s = tokio::net::TcpStream::connect(args.addr)
                    .await
                    .with_context(|| format!("connecting to {}", args.addr))?;
                s.set_nodelay(true).ok();
                stream(s, &lines, args).await
            }
        }
    })?;
    if args.json {
        println!("{status}");
    } else {
        println!("final status: {status}");
    }
    match code {
        Outcome::Done => Ok(()),
        Outcome::Refused(e) => bail!("the server refused the program: {e}"),
        Outcome::Interrupted => bail!("interrupted: held and aborted"),
    }
}

/// Sends `start` on a connection of its own (authenticated like the stream).
async fn start_aside(args: &SendArgs) -> Result<()> {
    async fn ask<S: AsyncRead + AsyncWrite + Unpin>(io: S, args: &SendArgs) -> Result<()> {
        let (rd, mut wr) = tokio::io::split(io);
        let mut rd = BufReader::new(rd).lines();
        if let Some(t) = &args.token {
            wr.write_all(format!("auth {t}\n").as_bytes()).await?;
        }
        wr.write_all(b"start\n").await?;
        let expected = if args.token.is_some() { 2 } else { 1 };
        for _ in 0..expected {
            let r = rd
                .next_line()
                .await?
                .ok_or_else(|| anyhow!("the server closed the start connection"))?;
            if !r.starts_with("ok") {
                bail!("start refused: {r}");
            }
        }
        Ok(())
    }
    match &args.socket {
        Some(p) => {
            ask(
                tokio::net::UnixStream::connect(p)
                    .await
                    .with_context(|| format!("connecting to {} for start", p.display()))?,
                args,
            )
            .await
        }
        None => {
            ask(
                tokio::net::TcpStream::connect(args.addr)
                    .await
                    .with_context(|| format!("connecting to {} for start", args.addr))?,
                args,
            )
            .await
        }
    }
}

/// How a `send` ended.
#[derive(Debug)]
pub enum Outcome {
    /// All accepted (and finished, unless `--no-wait`).
    Done,
    /// A line was refused (the program was aborted).
    Refused(String),
    /// Ctrl-C.
    Interrupted,
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

/// Streams `lines`, then `end` and `start`, then waits for the end. Returns
/// how it ended and the final status line (JSON).
pub async fn stream<S: AsyncRead + AsyncWrite + Unpin>(
    io: S,
    lines: &[String],
    args: &SendArgs,
) -> Result<(Outcome, String)> {
    let (rd, mut wr) = tokio::io::split(io);
    let mut rd = BufReader::new(rd).lines();
    let next_reply = async |rd: &mut tokio::io::Lines<BufReader<_>>| -> Result<String> {
        rd.next_line()
            .await?
            .ok_or_else(|| anyhow!("the server closed the connection"))
    };
    if let Some(t) = &args.token {
        wr.write_all(format!("auth {t}\n").as_bytes()).await?;
        let r = next_reply(&mut rd).await?;
        if !r.starts_with("ok") {
            bail!("authentication failed: {r}");
        }
    }
    let mut sigint = tokio::signal::unix::signal(tokio::signal::unix::SignalKind::interrupt())
        .context("installing the Ctrl-C handler")?;
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
            wr.write_all(lines[sent].as_bytes()).await?;
            wr.write_all(b"\n").await?;
            sent += 1;
            expect.push_back(Expect::Block);
        }
        tokio::select! {
            r = tokio::time::timeout(STALL, next_reply(&mut rd)) => match r {
                Err(_) => {
                    // Back-pressure: the queue is full; let the machine run.
                    // `start` goes over a second connection: on this one it
                    // would wait behind the block the server is holding
                    // until the queue drains, which needs `start`.
                    if !started {
                        start_aside(args).await?;
                        started = true;
                    }
                }
                Ok(line) => {
                    let line = line?;
                    match expect.pop_front() {
                        Some(Expect::Block) => {
                            if line.starts_with("ok") {
                                acked += 1;
                            } else {
                                refused = Some(format!("block {} of {total}: {line}", acked + 1));
                            }
                        }
                        None => bail!("unexpected reply {line:?}"),
                    }
                    progress.show(&format!("{} {acked}/{total} blocks queued", bar(acked, total)), false);
                }
            },
            _ = sigint.recv() => { interrupted = true; break; }
        }
    }
    // Replies still owed are read by `request` below in order.
    let request = async |wr: &mut tokio::io::WriteHalf<S>,
                         rd: &mut tokio::io::Lines<BufReader<tokio::io::ReadHalf<S>>>,
                         expect: &mut VecDeque<Expect>,
                         req: &str|
           -> Result<String> {
        wr.write_all(req.as_bytes()).await?;
        wr.write_all(b"\n").await?;
        while expect.pop_front().is_some() {
            next_reply(rd).await?;
        }
        next_reply(rd).await
    };
    if interrupted || refused.is_some() {
        progress.done();
        if interrupted {
            eprintln!("interpd send: interrupted: hold, then abort");
            request(&mut wr, &mut rd, &mut expect, "hold").await?;
        }
        let r = request(&mut wr, &mut rd, &mut expect, "abort").await?;
        if !r.starts_with("ok") {
            eprintln!("interpd send: abort: {r}");
        }
        let st = request(&mut wr, &mut rd, &mut expect, "status").await?;
        let st = st.strip_prefix("status ").unwrap_or(&st).to_owned();
        return Ok((
            match refused {
                Some(e) => Outcome::Refused(e),
                None => Outcome::Interrupted,
            },
            st,
        ));
    }
    request(&mut wr, &mut rd, &mut expect, "end").await?;
    if !started {
        request(&mut wr, &mut rd, &mut expect, "start").await?;
    }
    let mut moved = false;
    loop {
        let st = request(&mut wr, &mut rd, &mut expect, "status").await?;
        let json = st.strip_prefix("status ").unwrap_or(&st).to_owned();
        let s: Status =
            serde_json::from_str(&json).with_context(|| format!("reading status {json:?}"))?;
        progress.show(
            &format!(
                "{} {total}/{total} blocks queued, {} at {:.3} mm, block {}",
                bar(total, total),
                s.state,
                s.s,
                s.block_id
            ),
            false,
        );
        moved |= matches!(s.state.as_str(), "running" | "holding" | "stopping");
        let ended = matches!(s.state.as_str(), "done" | "fault") || (moved && s.state == "idle");
        if args.no_wait || ended {
            progress.done();
            return Ok((Outcome::Done, json));
        }
        tokio::select! {
            _ = tokio::time::sleep(POLL) => {}
            _ = sigint.recv() => {
                progress.done();
                eprintln!("interpd send: interrupted: hold, then abort");
                request(&mut wr, &mut rd, &mut expect, "hold").await?;
                request(&mut wr, &mut rd, &mut expect, "abort").await?;
                let st = request(&mut wr, &mut rd, &mut expect, "status").await?;
                return Ok((Outcome::Interrupted, st.strip_prefix("status ").unwrap_or(&st).to_owned()));
            }
        }
    }
}
