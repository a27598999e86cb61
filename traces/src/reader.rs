//! Reading a trace back: every channel, in file order.
//!
//! The file is read front to back (no index needed), so a trace whose writer
//! died still yields every complete chunk. A truncated or corrupted file
//! gives [`ReadError::Damaged`], which carries what was recovered before the
//! damage and says how much that is.

use std::fmt;
use std::path::Path;

use serde::de::DeserializeOwned;

use crate::messages::{BlockMsg, Channel, ConfigMsg, EventMsg, LoopTimingMsg, SetpointMsg};

/// One message of any channel, undecoded.
#[derive(Clone, Debug, PartialEq)]
pub struct RawMessage {
    /// Its topic.
    pub topic: String,
    /// Its schema name (empty without a schema).
    pub schema: String,
    /// Per-channel sequence number.
    pub sequence: u32,
    /// Log time, ns.
    pub log_time: u64,
    /// The payload (JSON for our channels).
    pub data: Vec<u8>,
}

/// Everything in a trace, decoded.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Trace {
    /// `/interpd/config` (the first one, if there are several).
    pub config: Option<ConfigMsg>,
    /// `/interpd/blocks`.
    pub blocks: Vec<BlockMsg>,
    /// `/interpd/setpoints`.
    pub setpoints: Vec<SetpointMsg>,
    /// `/interpd/loop_timing`.
    pub loop_timing: Vec<LoopTimingMsg>,
    /// `/interpd/events`.
    pub events: Vec<EventMsg>,
    /// Messages on topics that are not ours (kept raw).
    pub other: Vec<RawMessage>,
}

/// How many messages of each kind a read produced.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Recovered {
    /// All messages.
    pub messages: usize,
    /// Config messages.
    pub config: usize,
    /// Blocks.
    pub blocks: usize,
    /// Setpoints.
    pub setpoints: usize,
    /// Loop timing messages.
    pub loop_timing: usize,
    /// Events.
    pub events: usize,
}

impl fmt::Display for Recovered {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} messages ({} config, {} blocks, {} setpoints, {} loop timing, {} events)",
            self.messages, self.config, self.blocks, self.setpoints, self.loop_timing, self.events
        )
    }
}

impl Trace {
    /// Message counts.
    pub fn recovered(&self) -> Recovered {
        let config = usize::from(self.config.is_some());
        Recovered {
            messages: config
                + self.blocks.len()
                + self.setpoints.len()
                + self.loop_timing.len()
                + self.events.len()
                + self.other.len(),
            config,
            blocks: self.blocks.len(),
            setpoints: self.setpoints.len(),
            loop_timing: self.loop_timing.len(),
            events: self.events.len(),
        }
    }

    /// Reads a trace file.
    pub fn open(path: impl AsRef<Path>) -> Result<Trace, ReadError> {
        let path = path.as_ref();
        let bytes = std::fs::read(path).map_err(|source| ReadError::Io {
            path: path.display().to_string(),
            source,
        })?;
        Trace::from_bytes(&bytes)
    }

    /// Reads a trace like [`Trace::open`], but takes a truncated or
    /// corrupted one (a recorder cut off by a crash) as what it holds up to
    /// its last complete chunk: the trace, and the damage as text. Fails
    /// when the file cannot be read, a message does not decode, or nothing
    /// usable (not even the config) was recovered.
    pub fn open_recovering(path: impl AsRef<Path>) -> Result<(Trace, Option<String>), ReadError> {
        match Trace::open(path) {
            Ok(t) => Ok((t, None)),
            Err(ReadError::Damaged {
                recovered,
                file_bytes,
                cause,
            }) if recovered.config.is_some() => {
                let note = format!(
                    "truncated or corrupted ({cause}): using the {} recovered up to its last \
                     complete chunk of a {file_bytes}-byte file",
                    recovered.recovered()
                );
                Ok((*recovered, Some(note)))
            }
            Err(e) => Err(e),
        }
    }

    /// Reads a trace held in memory.
    pub fn from_bytes(bytes: &[u8]) -> Result<Trace, ReadError> {
        let mut trace = Trace::default();
        let res = for_each_message(bytes, |m| {
            trace.add(m)?;
            Ok(())
        });
        match res {
            Ok(()) => Ok(trace),
            Err(Stop::Decode(e)) => Err(e),
            Err(Stop::Damage(cause)) => Err(ReadError::Damaged {
                recovered: Box::new(trace),
                file_bytes: bytes.len(),
                cause,
            }),
        }
    }

    fn add(&mut self, m: RawMessage) -> Result<(), ReadError> {
        match Channel::from_topic(&m.topic) {
            Some(Channel::Config) => {
                let c: ConfigMsg = decode(Channel::Config, &m)?;
                self.config.get_or_insert(c);
            }
            Some(Channel::Blocks) => self.blocks.push(decode(Channel::Blocks, &m)?),
            Some(Channel::Setpoints) => self.setpoints.push(decode(Channel::Setpoints, &m)?),
            Some(Channel::LoopTiming) => self.loop_timing.push(decode(Channel::LoopTiming, &m)?),
            Some(Channel::Events) => self.events.push(decode(Channel::Events, &m)?),
            None => self.other.push(m),
        }
        Ok(())
    }
}

fn decode<T: DeserializeOwned>(channel: Channel, m: &RawMessage) -> Result<T, ReadError> {
    serde_json::from_slice(&m.data).map_err(|source| ReadError::Decode {
        topic: channel.topic(),
        sequence: m.sequence,
        source,
    })
}

/// Why a trace could not be read (whole).
#[derive(Debug, thiserror::Error)]
pub enum ReadError {
    /// The file could not be read.
    #[error("reading {path}: {source}")]
    Io {
        /// The path.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// The file is truncated or corrupted; `recovered` holds every message
    /// before the damage.
    #[error(
        "trace truncated or corrupted ({cause}); recovered {} from a {file_bytes}-byte file",
        recovered.recovered()
    )]
    Damaged {
        /// What was read before the damage.
        recovered: Box<Trace>,
        /// Size of the file.
        file_bytes: usize,
        /// What the MCAP reader reported.
        cause: String,
    },
    /// A message of one of our channels is not what its schema says.
    #[error("message {sequence} on {topic} does not decode: {source}")]
    Decode {
        /// The topic.
        topic: &'static str,
        /// Its per-channel sequence number.
        sequence: u32,
        /// Why.
        source: serde_json::Error,
    },
}

enum Stop {
    Damage(String),
    Decode(ReadError),
}

/// The longest record (or decompressed chunk) a trace may hold: this many
/// times the file's size, and at least [`RECORD_LIMIT_FLOOR`] bytes.
const RECORD_LIMIT_RATIO: usize = 16;
const RECORD_LIMIT_FLOOR: usize = 64 << 20;

fn for_each_message(
    bytes: &[u8],
    mut f: impl FnMut(RawMessage) -> Result<(), ReadError>,
) -> Result<(), Stop> {
    use mcap::records::Record;
    use mcap::sans_io::{LinearReadEvent, LinearReader, LinearReaderOptions};
    use std::collections::HashMap;
    // The reader walks the file itself, every length bounded, and each
    // chunk's CRC checked before any of its records is used: a flipped byte
    // is an error, not bad data. (`MessageStream` trusts the lengths inside
    // a decompressed chunk, and a flip in a compressed chunk made it reserve
    // up to 2⁶⁴ bytes and abort the process.) The bound is a multiple of
    // the file's size, since a record or a decompressed chunk may be larger
    // than the file: our chunks hold 256 KiB of JSON, or one larger
    // message, compressed 3–20×.
    let limit = bytes
        .len()
        .saturating_mul(RECORD_LIMIT_RATIO)
        .max(RECORD_LIMIT_FLOOR);
    let options = LinearReaderOptions::default()
        .with_prevalidate_chunk_crcs(true)
        .with_validate_chunk_crcs(true)
        .with_record_length_limit(limit);
    let mut reader = LinearReader::new_with_options(options);
    let (mut schemas, mut channels) = (HashMap::new(), HashMap::new());
    let mut fed = 0usize;
    let damage = |e: mcap::McapError| Stop::Damage(e.to_string());
    while let Some(event) = reader.next_event() {
        match event.map_err(damage)? {
            LinearReadEvent::ReadRequest(need) => {
                let n = need.min(bytes.len() - fed);
                reader.insert(n).copy_from_slice(&bytes[fed..fed + n]);
                reader.notify_read(n);
                fed += n;
            }
            LinearReadEvent::Record { data, opcode } => match mcap::parse_record(opcode, data) {
                Err(e) => return Err(damage(e)),
                Ok(Record::Schema { header, .. }) => {
                    schemas.insert(header.id, header.name);
                }
                Ok(Record::Channel(c)) => {
                    channels.insert(c.id, (c.topic, c.schema_id));
                }
                Ok(Record::Message { header, data }) => {
                    let Some((topic, schema_id)) = channels.get(&header.channel_id) else {
                        return Err(Stop::Damage(format!(
                            "a message on channel {} before that channel",
                            header.channel_id
                        )));
                    };
                    let raw = RawMessage {
                        topic: topic.clone(),
                        schema: schemas.get(schema_id).cloned().unwrap_or_default(),
                        sequence: header.sequence,
                        log_time: header.log_time,
                        data: data.into_owned(),
                    };
                    f(raw).map_err(Stop::Decode)?;
                }
                Ok(_) => {}
            },
        }
    }
    Ok(())
}

/// Every message of any channel, in file order, undecoded. On damage, the
/// messages before it are returned with the error text.
pub fn raw_messages(bytes: &[u8]) -> (Vec<RawMessage>, Option<String>) {
    let mut out = Vec::new();
    let res = for_each_message(bytes, |m| {
        out.push(m);
        Ok(())
    });
    let err = match res {
        Ok(()) => None,
        Err(Stop::Damage(c)) => Some(c),
        Err(Stop::Decode(e)) => Some(e.to_string()),
    };
    (out, err)
}
