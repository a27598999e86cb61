//! The control plane (tokio, non-RT): listeners on loopback TCP and a Unix
//! socket, one task per connection speaking the line protocol of
//! [`crate::protocol`]. Blocks are parsed, checked and split here and handed
//! to the RT thread through its SPSC queue; a full queue is back-pressure (the
//! reply waits, so the client's writes stall), never a drop.

use core::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use heapless::spsc::{Consumer, Producer};
use interp_core::{BlockPlanner, PlannedBlock, RunState, Vec3};
use serde::Serialize;
use tokio::io::{AsyncBufRead, AsyncBufReadExt, AsyncRead, AsyncWrite, AsyncWriteExt, BufReader};

use crate::protocol::{MAX_LINE_BYTES, Request, parse};
use crate::publish::state_name;
use crate::rt::{Command, PushFailure, RtStatus};

/// How long `abort` waits for the machine to come to rest before replying.
pub const ABORT_WAIT: Duration = Duration::from_secs(30);

/// Shared by every connection.
pub struct Control {
    /// Block producer and the end of what was accepted (one streamer at a time).
    pub stream: tokio::sync::Mutex<Stream>,
    /// Command producer (short critical sections only).
    pub commands: Mutex<Producer<'static, Command>>,
    /// Refused blocks reported by the RT thread.
    pub failures: Mutex<Consumer<'static, PushFailure>>,
    /// The RT thread's counters.
    pub status: Arc<RtStatus>,
    /// Interpolation period (poll interval while back-pressured).
    pub period: Duration,
    /// Largest feed override accepted.
    pub max_feed_override: f64,
    /// Token every connection must present first (`None`: no authentication).
    pub token: Option<String>,
    /// Incremented by every abort: a stream waiting on a full queue drops its block.
    pub abort_epoch: AtomicU64,
    /// Blocks (protocol lines) accepted.
    pub blocks_accepted: AtomicU64,
    /// Lines refused with an error.
    pub errors: AtomicU64,
    /// Last refused block reported by the RT thread.
    pub last_refusal: Mutex<Option<String>>,
    /// The trace recorder's queue, if recording (taken at shutdown).
    pub recorder: Mutex<Option<traces::RecordTx>>,
}

/// The streaming side: the RT thread's plan queue and where the next block starts.
pub struct Stream {
    /// Producer of the RT thread's queue of planned blocks.
    pub blocks: Producer<'static, Box<PlannedBlock>>,
    /// Plan buffers the RT thread handed back.
    pub spent: Consumer<'static, Box<PlannedBlock>>,
    /// Plans blocks against the end of what was accepted (the costly half of
    /// `Interpolator::push`, kept off the RT thread).
    pub planner: BlockPlanner,
    /// End of the last accepted block (`None`: where the machine is).
    pub tail: Option<[f64; 3]>,
    /// Id of the next interpolator segment (from 1 in each program).
    pub next_id: u32,
    /// Blocks accepted in this program.
    pub index: u32,
    /// `end` was sent: the next block starts a new program.
    pub ended: bool,
}

impl core::fmt::Debug for Control {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Control")
            .field("period", &self.period)
            .field("abort_epoch", &self.abort_epoch)
            .finish_non_exhaustive()
    }
}

impl core::fmt::Debug for Stream {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Stream")
            .field("tail", &self.tail)
            .field("next_id", &self.next_id)
            .finish_non_exhaustive()
    }
}

/// The reply to `status`.
#[derive(Debug, Serialize)]
pub struct StatusReply {
    /// Interpolator state.
    pub state: &'static str,
    /// Whether `start` was given for this program.
    pub started: bool,
    /// Whether `end` was applied.
    pub finished: bool,
    /// Interpolator ticks.
    pub ticks: u64,
    /// Samples published.
    pub published: u64,
    /// Block id of the last setpoint.
    pub block_id: u32,
    /// X Y Z, mm.
    pub position: [f64; 3],
    /// Path speed, mm/s.
    pub feed: f64,
    /// Arc length of the run, mm.
    pub s: f64,
    /// Applied feed override.
    pub feed_override: f64,
    /// Segments queued in the interpolator.
    pub queued_segments: u32,
    /// Protocol blocks accepted.
    pub blocks_accepted: u64,
    /// Interpolator blocks (pieces) pushed.
    pub pieces_pushed: u64,
    /// Pieces the interpolator refused.
    pub pieces_refused: u64,
    /// Last refusal.
    pub last_refusal: Option<String>,
    /// Lines answered with an error.
    pub line_errors: u64,
    /// Missed periods.
    pub overruns: u64,
    /// Ticks the recorder had no room for.
    pub recorder_drops: u64,
    /// Failed publishes.
    pub publish_failures: u64,
}

impl Control {
    /// Sends a command to the RT thread (waits while its queue is full).
    pub async fn command(&self, c: Command) {
        loop {
            let ok = self
                .commands
                .lock()
                .map(|mut q| q.enqueue(c).is_ok())
                .unwrap_or(false);
            if ok {
                return;
            }
            tokio::time::sleep(self.period).await;
        }
    }

    /// Aborts and waits until the machine is at rest with the queue flushed.
    pub async fn abort(&self) -> Result<(), String> {
        self.abort_epoch.fetch_add(1, Ordering::AcqRel);
        let before = self.status.aborts.load(Ordering::Acquire);
        self.command(Command::Abort).await;
        let deadline = tokio::time::Instant::now() + ABORT_WAIT;
        loop {
            let acked = self.status.aborts.load(Ordering::Acquire) > before;
            let st = self.status.run_state();
            let at_rest = self.status.feed.load(Ordering::Acquire) == 0f64.to_bits();
            if acked && at_rest && matches!(st, RunState::Idle | RunState::Done | RunState::Fault) {
                break;
            }
            if !self.status.running.load(Ordering::Acquire) && acked {
                break;
            }
            if tokio::time::Instant::now() > deadline {
                return Err("the machine did not come to rest in time".into());
            }
            tokio::time::sleep(self.period).await;
        }
        // Drain what the RT thread flushed; the next program starts where it stopped.
        let mut s = self.stream.lock().await;
        s.tail = None;
        Ok(())
    }

    /// The current status.
    pub fn status(&self) -> StatusReply {
        if let Ok(mut f) = self.failures.lock() {
            while let Some(x) = f.dequeue() {
                if let Ok(mut l) = self.last_refusal.lock() {
                    *l = Some(format!("block {}: {}", x.id, x.error));
                }
            }
        }
        let s = &self.status;
        let f = |a: &AtomicU64| f64::from_bits(a.load(Ordering::Acquire));
        StatusReply {
            state: state_name(s.run_state()),
            started: s.started.load(Ordering::Acquire),
            finished: s.finished.load(Ordering::Acquire),
            ticks: s.ticks.load(Ordering::Acquire),
            published: s.published.load(Ordering::Acquire),
            block_id: s.block_id.load(Ordering::Acquire),
            position: s.position(),
            feed: f(&s.feed),
            s: f(&s.s),
            feed_override: f(&s.feed_override),
            queued_segments: s.queued_segments.load(Ordering::Acquire),
            blocks_accepted: self.blocks_accepted.load(Ordering::Acquire),
            pieces_pushed: s.blocks_pushed.load(Ordering::Acquire),
            pieces_refused: s.blocks_refused.load(Ordering::Acquire),
            last_refusal: self.last_refusal.lock().ok().and_then(|l| l.clone()),
            line_errors: self.errors.load(Ordering::Acquire),
            overruns: s.overruns.load(Ordering::Acquire),
            recorder_drops: s.recorder_drops.load(Ordering::Acquire),
            publish_failures: s.publish_failures.load(Ordering::Acquire),
        }
    }

    /// Hands an accepted block to the trace recorder, if recording.
    fn record_block(
        &self,
        index: u32,
        b: &traces::InputBlock,
        info: Vec<traces::messages::SegmentInfo>,
    ) {
        if let Ok(rec) = self.recorder.lock()
            && let Some(tx) = rec.as_ref()
        {
            let at = self.status.ticks.load(Ordering::Acquire);
            let msg = traces::messages::BlockMsg {
                index,
                block: b.clone(),
                segments: info,
                accepted_at_seq: at,
            };
            // Non-RT side: a full recorder queue is counted by the recorder.
            let _ = tx.try_push(traces::Record::Block(
                Box::new(msg),
                at as f64 * self.period.as_secs_f64(),
            ));
        }
    }

    /// Parses, checks, plans and queues one block; waits while the RT queue is full.
    async fn block(&self, b: &traces::InputBlock) -> Result<String, String> {
        let epoch = self.abort_epoch.load(Ordering::Acquire);
        let mut s = self.stream.lock().await;
        if s.tail.is_none() || s.ended {
            // A new program: segment ids from 1, as `simulate` numbers them.
            s.next_id = 1;
            s.index = 0;
            s.ended = false;
        }
        if s.tail.is_none() && self.status.published.load(Ordering::Acquire) > 0 {
            // Where the machine is (at rest: start, or after an abort), bit
            // for bit as the interpolator's queue end.
            let p = self.status.position();
            let at = f64::from_bits(self.status.s.load(Ordering::Acquire));
            s.planner.resync(Vec3::new(p[0], p[1], p[2]), at);
        }
        let start = s.tail.unwrap_or_else(|| self.status.position());
        let id = s.next_id;
        let (pieces, info) = crate::protocol::expand(b, start, id)?;
        let n = pieces.len();
        let end = pieces.last().map(|p| {
            let e = interp_core::Curve::end_point(&p.path);
            [e.x, e.y, e.z]
        });
        let mut info = Some(info);
        for (i, piece) in pieces.into_iter().enumerate() {
            let buf = s
                .spent
                .dequeue()
                .unwrap_or_else(|| Box::new(PlannedBlock::new()));
            let planner = s.planner;
            // Law sampling takes milliseconds for a long NURBS: off the
            // runtime's thread, so status and hold are answered meanwhile.
            let (planner, mut item, planned) = tokio::task::spawn_blocking(move || {
                let (mut planner, mut buf) = (planner, buf);
                let r = planner.plan(&piece, &mut buf);
                (planner, buf, r)
            })
            .await
            .map_err(|e| format!("planning block {id}: {e}"))?;
            if let Err(e) = planned {
                if i > 0 {
                    // The pieces before it are queued: the program goes on from there.
                    let t = s.planner.tail();
                    s.tail = Some([t.x, t.y, t.z]);
                    s.next_id = id + i as u32;
                }
                return Err(format!(
                    "block {id}: segment {} of {n}: {e} ({i} of {n} segments queued)",
                    i + 1
                ));
            }
            s.planner = planner;
            if let Some(info) = info.take() {
                // Recorded once its first segment is planned, before any of it
                // is queued: a replay takes each block's segments from here as
                // their commits come (an abort may flush some).
                self.record_block(s.index, b, info);
            }
            loop {
                if self.abort_epoch.load(Ordering::Acquire) != epoch {
                    return Err(format!(
                        "aborted while queueing block {id} ({i} of {n} pieces queued, flushed)"
                    ));
                }
                match s.blocks.enqueue(item) {
                    Ok(()) => break,
                    Err(back) => {
                        item = back;
                        tokio::time::sleep(self.period).await;
                    }
                }
            }
        }
        s.tail = end;
        s.next_id = id + n as u32;
        s.index += 1;
        self.blocks_accepted.fetch_add(1, Ordering::AcqRel);
        Ok(format!(
            "ok block {} segments {id}..={}",
            s.index,
            id + n as u32 - 1
        ))
    }
}

/// Outcome of reading one line.
enum ReadLine {
    Line(String),
    TooLong(usize),
    NotUtf8,
    Eof,
}

/// Reads one line of at most `MAX_LINE_BYTES`; a longer one is consumed up to
/// its newline and reported, so the connection goes on.
async fn read_line<R: AsyncBufRead + Unpin>(r: &mut R) -> std::io::Result<ReadLine> {
    let mut buf = Vec::new();
    let mut len = 0usize;
    loop {
        let avail = r.fill_buf().await?;
        if avail.is_empty() {
            if len == 0 {
                return Ok(ReadLine::Eof);
            }
            break;
        }
        let (take, done) = match avail.iter().position(|&c| c == b'\n') {
            Some(i) => (i + 1, true),
            None => (avail.len(), false),
        };
        if len + take <= MAX_LINE_BYTES + 1 {
            buf.extend_from_slice(&avail[..take]);
        }
        len += take;
        r.consume(take);
        if done {
            break;
        }
    }
    if len > MAX_LINE_BYTES + 1 {
        return Ok(ReadLine::TooLong(len));
    }
    while matches!(buf.last(), Some(b'\n' | b'\r')) {
        buf.pop();
    }
    match String::from_utf8(buf) {
        Ok(s) => Ok(ReadLine::Line(s)),
        Err(_) => Ok(ReadLine::NotUtf8),
    }
}

/// Serves one connection until it closes. A connection that sent blocks and
/// leaves without `end` (or `abort`) holds the machine: what was accepted stays queued.
pub async fn serve_connection<S: AsyncRead + AsyncWrite + Unpin>(ctl: Arc<Control>, io: S) {
    let (rd, mut wr) = tokio::io::split(io);
    let mut rd = BufReader::new(rd);
    let mut authed = ctl.token.is_none();
    let mut mid_program = false;
    let mut line_no = 0u64;
    loop {
        let line = match read_line(&mut rd).await {
            Ok(ReadLine::Eof) | Err(_) => break,
            Ok(l) => l,
        };
        line_no += 1;
        let reply: Result<String, String> = match line {
            ReadLine::Eof => unreachable!(),
            ReadLine::TooLong(n) => Err(format!(
                "line of {n} bytes exceeds the limit of {MAX_LINE_BYTES} bytes"
            )),
            ReadLine::NotUtf8 => Err("line is not UTF-8".into()),
            ReadLine::Line(text) => match parse(&text) {
                Err(e) => Err(e),
                Ok(Request::Auth(t)) => {
                    if ctl.token.as_deref().is_none_or(|want| want == t) {
                        authed = true;
                        Ok("ok auth".into())
                    } else {
                        Err("wrong token".into())
                    }
                }
                Ok(_) if !authed => {
                    let _ = wr
                        .write_all(
                            format!("err {line_no} authentication required (auth TOKEN)\n")
                                .as_bytes(),
                        )
                        .await;
                    break;
                }
                Ok(req) => handle(&ctl, req, &mut mid_program).await,
            },
        };
        let out = match reply {
            Ok(s) => s,
            Err(e) => {
                ctl.errors.fetch_add(1, Ordering::AcqRel);
                format!("err {line_no} {e}")
            }
        };
        if wr.write_all(out.as_bytes()).await.is_err() || wr.write_all(b"\n").await.is_err() {
            break;
        }
    }
    if mid_program {
        // Disconnected mid-stream: hold; keep everything accepted.
        ctl.command(Command::Hold).await;
        eprintln!("interpd: a client left mid-program: feed hold (resume to continue)");
    }
}

async fn handle(ctl: &Control, req: Request, mid_program: &mut bool) -> Result<String, String> {
    match req {
        Request::Nothing => Ok("ok".into()),
        Request::Auth(_) => unreachable!("handled by the caller"),
        Request::Block(b) => {
            let r = ctl.block(&b).await;
            if r.is_ok() {
                *mid_program = true;
            }
            r
        }
        Request::Start => {
            ctl.command(Command::Start).await;
            Ok("ok start".into())
        }
        Request::Hold => {
            ctl.command(Command::Hold).await;
            Ok("ok hold".into())
        }
        Request::Resume => {
            ctl.command(Command::Resume).await;
            Ok("ok resume".into())
        }
        Request::Override(x) => {
            if !(x >= 0.0 && x <= ctl.max_feed_override) {
                return Err(format!(
                    "override {x} outside 0 ..= {} (max-feed-override)",
                    ctl.max_feed_override
                ));
            }
            ctl.command(Command::Override(x)).await;
            Ok(format!("ok override {x}"))
        }
        Request::End => {
            ctl.command(Command::End).await;
            ctl.stream.lock().await.ended = true;
            *mid_program = false;
            Ok("ok end".into())
        }
        Request::Abort => {
            *mid_program = false;
            ctl.abort().await?;
            Ok("ok abort".into())
        }
        Request::Status => serde_json::to_string(&ctl.status())
            .map(|j| format!("status {j}"))
            .map_err(|e| e.to_string()),
    }
}
