//! The recorder: a thread that drains a bounded queue into a [`TraceWriter`].
//!
//! Producers (the RT loop) call [`RecordTx::try_push`], which never blocks and
//! never allocates: the queue's slots are allocated when it is made
//! (`std::sync::mpsc::sync_channel`, an array queue). A full queue hands the
//! record back and counts it; the recorder thread writes a
//! [`EventKind::RecorderOverflow`] event with the running total as soon as it
//! sees the count grow, and once more at the end.

use std::io::{Seek, Write};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, SyncSender, TrySendError, sync_channel};
use std::thread::JoinHandle;

use interp_core::Setpoint;

use crate::messages::{BlockMsg, ConfigMsg, EventKind, EventMsg, LoopTimingMsg};
use crate::writer::{TraceWriter, WriteCounts, WriteError};

/// One item for the recorder. The real-time variants are `Copy`-sized and
/// never own heap memory; config and blocks come from the non-RT side boxed.
#[derive(Debug)]
pub enum Record {
    /// A setpoint.
    Setpoint(Setpoint),
    /// Loop timing of the tick `seq`, at machine time `time`.
    LoopTiming(LoopTimingMsg, f64),
    /// An event (leave `detail` empty on the RT path).
    Event(EventMsg),
    /// The configuration (non-RT).
    Config(Box<ConfigMsg>),
    /// An accepted block at machine time `time` (non-RT).
    Block(Box<BlockMsg>, f64),
}

/// Why [`RecordTx::try_push`] refused a record; the record is handed back.
#[derive(Debug)]
pub enum PushRefused {
    /// The queue is full (counted as a recorder overflow).
    Full(Record),
    /// The recorder has stopped.
    Closed(Record),
}

/// The producer side of the recorder queue. Cloneable (one per producer).
#[derive(Clone, Debug)]
pub struct RecordTx {
    tx: SyncSender<Record>,
    overflow: Arc<AtomicU64>,
}

impl RecordTx {
    /// Queues `r` if there is room; never blocks or allocates.
    #[inline]
    pub fn try_push(&self, r: Record) -> Result<(), PushRefused> {
        match self.tx.try_send(r) {
            Ok(()) => Ok(()),
            Err(TrySendError::Full(r)) => {
                self.overflow.fetch_add(1, Ordering::Relaxed);
                Err(PushRefused::Full(r))
            }
            Err(TrySendError::Disconnected(r)) => Err(PushRefused::Closed(r)),
        }
    }

    /// Records refused so far because the queue was full.
    pub fn overflows(&self) -> u64 {
        self.overflow.load(Ordering::Relaxed)
    }
}

/// What the recorder thread reports when its producers are gone.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RecorderReport {
    /// Messages written per channel.
    pub written: WriteCounts,
    /// Records dropped because the queue was full.
    pub overflows: u64,
}

/// The running recorder thread.
#[derive(Debug)]
pub struct Recorder<W: Write + Seek + Send + 'static> {
    handle: JoinHandle<Result<(W, RecorderReport), WriteError>>,
}

impl<W: Write + Seek + Send + 'static> Recorder<W> {
    /// Starts the recorder thread writing to `writer` through a queue of
    /// `capacity` records. Drop every [`RecordTx`] to let it finish.
    pub fn spawn(writer: TraceWriter<W>, capacity: usize) -> std::io::Result<(RecordTx, Self)> {
        let (tx, rx) = sync_channel(capacity.max(1));
        let overflow = Arc::new(AtomicU64::new(0));
        let seen = Arc::clone(&overflow);
        let handle = std::thread::Builder::new()
            .name("interpd-recorder".into())
            .spawn(move || drain(writer, &rx, &seen))?;
        Ok((RecordTx { tx, overflow }, Recorder { handle }))
    }

    /// Waits for the thread (after every [`RecordTx`] is dropped) and returns
    /// the finished sink and what was written.
    pub fn join(self) -> Result<(W, RecorderReport), WriteError> {
        match self.handle.join() {
            Ok(r) => r,
            Err(p) => std::panic::resume_unwind(p),
        }
    }
}

fn drain<W: Write + Seek>(
    mut w: TraceWriter<W>,
    rx: &Receiver<Record>,
    overflow: &AtomicU64,
) -> Result<(W, RecorderReport), WriteError> {
    let mut reported = 0u64;
    let mut at = (0u64, 0.0f64); // last tick seen: where an overflow event goes
    let mut first_error: Option<WriteError> = None;
    // Keep draining after an error so producers never see a stuck queue.
    while let Ok(r) = rx.recv() {
        if first_error.is_some() {
            continue;
        }
        let res = match &r {
            Record::Setpoint(sp) => {
                at = (sp.seq, sp.time);
                w.setpoint(sp)
            }
            Record::LoopTiming(m, t) => w.loop_timing(m, *t),
            Record::Event(e) => w.event(e),
            Record::Config(c) => w.config(c),
            Record::Block(b, t) => w.block(b, *t),
        };
        let now = overflow.load(Ordering::Relaxed);
        let res = res.and_then(|()| {
            if now > reported {
                reported = now;
                w.event(&overflow_event(at, now))
            } else {
                Ok(())
            }
        });
        if let Err(e) = res {
            first_error = Some(e);
        }
    }
    let now = overflow.load(Ordering::Relaxed);
    if now > reported && first_error.is_none() {
        if let Err(e) = w.event(&overflow_event(at, now)) {
            first_error = Some(e);
        }
    }
    if let Some(e) = first_error {
        return Err(e);
    }
    let (sink, written) = w.finish()?;
    Ok((
        sink,
        RecorderReport {
            written,
            overflows: now,
        },
    ))
}

fn overflow_event(at: (u64, f64), total: u64) -> EventMsg {
    EventMsg {
        count: Some(total),
        ..EventMsg::new(EventKind::RecorderOverflow, at.0, at.1)
    }
}
