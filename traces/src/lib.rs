//! MCAP traces of interpd runs.
//!
//! A trace is an MCAP file with five channels (`/interpd/config`,
//! `/interpd/blocks`, `/interpd/setpoints`, `/interpd/loop_timing`,
//! `/interpd/events`), each JSON with a JSON Schema so that Foxglove, the
//! `mcap` CLI and the Python `mcap` package read it without our code
//! ([`messages`]). This crate writes them ([`writer`], and the [`recorder`]
//! thread behind a bounded queue that never blocks its producer), reads them
//! back ([`reader`], with recovery from truncated files), runs programs with
//! no clock ([`sim`], the code behind `interpd simulate`), replays them bit
//! for bit ([`replay`]), derives the seed paper's quantities ([`analysis`])
//! and plots them ([`plot`]). Programs come in the JSON block form
//! ([`blocks`]). `docs/traces.md` describes the format.

pub mod analysis;
pub mod blocks;
pub mod messages;
pub mod plot;
pub mod reader;
pub mod recorder;
pub mod replay;
pub mod sim;
pub mod writer;

pub use blocks::{InputBlock, PathSpec, Pipeline, Program};
pub use messages::{BlockMsg, Channel, ConfigMsg, EventKind, EventMsg, LoopTimingMsg, SetpointMsg};
pub use reader::{ReadError, Trace};
pub use recorder::{Record, RecordTx, Recorder};
pub use writer::{TraceCompression, TraceWriter};
