//! Writing a trace: an MCAP file with the five channels of [`Channel`].

use std::collections::BTreeMap;
use std::io::{Seek, Write};

use interp_core::Setpoint;
use mcap::records::MessageHeader;
use mcap::{Compression, WriteOptions, Writer};
use serde::Serialize;

use crate::messages::{
    BlockMsg, Channel, ConfigMsg, EventMsg, LoopTimingMsg, MESSAGE_ENCODING, PROFILE,
    SCHEMA_ENCODING, SetpointMsg,
};

/// Uncompressed bytes per MCAP chunk. A truncated file loses at most its last
/// chunk; 256 KiB is ~1,000 setpoints and compresses as well as larger chunks.
pub const CHUNK_SIZE: u64 = 256 * 1024;

/// Compression level of [`TraceWriter::new`]: zstd level 1, the fastest
/// (level 3, zstd's default, halves the writer's throughput for ~10 % smaller
/// files; `BENCHMARKS.md`).
pub const COMPRESSION_LEVEL: u32 = 1;

/// Chunk compression. Measured in `BENCHMARKS.md` (`## traces`): zstd makes
/// setpoint traces ~5× smaller than none at a small fraction of the writer's
/// time, and every MCAP reader (Python `mcap`, Foxglove) decodes it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum TraceCompression {
    /// zstd (level 3, single-threaded). The default.
    #[default]
    Zstd,
    /// lz4.
    Lz4,
    /// No compression.
    None,
}

impl TraceCompression {
    fn mcap(self) -> Option<Compression> {
        match self {
            TraceCompression::Zstd => Some(Compression::Zstd),
            TraceCompression::Lz4 => Some(Compression::Lz4),
            TraceCompression::None => None,
        }
    }
}

impl std::str::FromStr for TraceCompression {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "zstd" => Ok(TraceCompression::Zstd),
            "lz4" => Ok(TraceCompression::Lz4),
            "none" => Ok(TraceCompression::None),
            _ => Err(format!("unknown compression `{s}` (zstd, lz4, none)")),
        }
    }
}

/// Why writing failed.
#[derive(Debug, thiserror::Error)]
pub enum WriteError {
    /// The MCAP layer (including I/O) failed.
    #[error("writing MCAP: {0}")]
    Mcap(#[from] mcap::McapError),
    /// A message did not serialise (a non-finite number in a config, say).
    #[error("encoding a {channel:?} message: {source}")]
    Encode {
        /// The channel.
        channel: Channel,
        /// Why.
        source: serde_json::Error,
    },
}

/// Messages written per channel.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct WriteCounts {
    /// Config messages.
    pub config: u64,
    /// Block messages.
    pub blocks: u64,
    /// Setpoints.
    pub setpoints: u64,
    /// Loop timing messages.
    pub loop_timing: u64,
    /// Events.
    pub events: u64,
}

/// An open trace. Call [`TraceWriter::finish`] at the end: without it the file
/// has no summary (readers still recover every complete chunk).
pub struct TraceWriter<W: Write + Seek> {
    mcap: Writer<W>,
    ids: [u16; Channel::ALL.len()],
    seq: [u32; Channel::ALL.len()],
    buf: Vec<u8>,
    counts: WriteCounts,
    /// The run's machine, from its config: setpoints get their tool tip and axis.
    machine: Option<interp_core::kinematics::Machine>,
}

impl<W: Write + Seek> std::fmt::Debug for TraceWriter<W> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TraceWriter")
            .field("counts", &self.counts)
            .finish_non_exhaustive()
    }
}

/// Machine time in s as an MCAP log time in ns (negative and NaN give 0).
fn log_time(t: f64) -> u64 {
    let ns = (t * 1e9).round();
    if ns >= 0.0 { ns as u64 } else { 0 }
}

impl<W: Write + Seek> TraceWriter<W> {
    /// Starts a trace on `w` and registers the channels.
    pub fn new(w: W, compression: TraceCompression) -> Result<Self, WriteError> {
        Self::with_level(w, compression, COMPRESSION_LEVEL)
    }

    /// [`TraceWriter::new`] with a compression level (0: the codec's default).
    pub fn with_level(w: W, compression: TraceCompression, level: u32) -> Result<Self, WriteError> {
        let opts = WriteOptions::new()
            .profile(PROFILE)
            .compression(compression.mcap())
            .compression_level(level)
            .chunk_size(Some(CHUNK_SIZE))
            // The recorder is one thread on one core: no compression pool.
            .compression_threads(0);
        let mut mcap = opts.create(w)?;
        let mut ids = [0u16; Channel::ALL.len()];
        for (id, ch) in ids.iter_mut().zip(Channel::ALL) {
            let schema = mcap.add_schema(
                ch.schema_name(),
                SCHEMA_ENCODING,
                ch.schema_json().as_bytes(),
            )?;
            *id = mcap.add_channel(schema, ch.topic(), MESSAGE_ENCODING, &BTreeMap::new())?;
        }
        Ok(TraceWriter {
            mcap,
            ids,
            seq: [0; Channel::ALL.len()],
            buf: Vec::with_capacity(1024),
            counts: WriteCounts::default(),
            machine: None,
        })
    }

    fn put<T: Serialize>(&mut self, ch: Channel, time: f64, msg: &T) -> Result<(), WriteError> {
        let k = ch as usize;
        self.buf.clear();
        serde_json::to_writer(&mut self.buf, msg).map_err(|source| WriteError::Encode {
            channel: ch,
            source,
        })?;
        self.seq[k] = self.seq[k].wrapping_add(1);
        let t = log_time(time);
        let header = MessageHeader {
            channel_id: self.ids[k],
            sequence: self.seq[k],
            log_time: t,
            publish_time: t,
        };
        self.mcap.write_to_known_channel(&header, &self.buf)?;
        Ok(())
    }

    /// The configuration (write it first). With a machine in it, every
    /// setpoint after it records its tool tip and tool axis.
    pub fn config(&mut self, msg: &ConfigMsg) -> Result<(), WriteError> {
        self.machine = crate::messages::run_machine(msg);
        self.put(Channel::Config, 0.0, msg)?;
        self.counts.config += 1;
        Ok(())
    }

    /// An accepted input block, logged at machine time `time`.
    pub fn block(&mut self, msg: &BlockMsg, time: f64) -> Result<(), WriteError> {
        self.put(Channel::Blocks, time, msg)?;
        self.counts.blocks += 1;
        Ok(())
    }

    /// A setpoint, logged at its machine time.
    pub fn setpoint(&mut self, sp: &Setpoint) -> Result<(), WriteError> {
        let msg = SetpointMsg::with_pose(sp, self.machine.as_ref());
        self.put(Channel::Setpoints, sp.time, &msg)?;
        self.counts.setpoints += 1;
        Ok(())
    }

    /// Loop timing of a tick, logged at machine time `time`.
    pub fn loop_timing(&mut self, msg: &LoopTimingMsg, time: f64) -> Result<(), WriteError> {
        self.put(Channel::LoopTiming, time, msg)?;
        self.counts.loop_timing += 1;
        Ok(())
    }

    /// An event, logged at its machine time.
    pub fn event(&mut self, msg: &EventMsg) -> Result<(), WriteError> {
        self.put(Channel::Events, msg.time, msg)?;
        self.counts.events += 1;
        Ok(())
    }

    /// Messages written so far.
    pub fn counts(&self) -> WriteCounts {
        self.counts
    }

    /// Writes the summary and footer and hands back the sink.
    pub fn finish(mut self) -> Result<(W, WriteCounts), WriteError> {
        self.mcap.finish()?;
        Ok((self.mcap.into_inner(), self.counts))
    }
}
