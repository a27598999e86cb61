//! Bit-exact replay: re-simulate a trace's blocks under its config and
//! compare every setpoint, field by field, bit for bit.

use std::fmt;

use serde::de::{Deserialize, Deserializer, MapAccess, Visitor};
use serde_json::Value;

use crate::analysis::{TraceProgramError, program_of};
use crate::messages::SetpointMsg;
use crate::reader::Trace;
use crate::sim::{self, SimError, SimItem};

/// Extra machine time a replay may run past the trace's last setpoint, s,
/// before it is called a runaway (the trace's run would have ended by then).
pub const REPLAY_TIME_MARGIN_S: f64 = 60.0;

/// The first difference between a trace and its replay.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Mismatch {
    /// Sequence number of the setpoint (for block differences: the block index).
    pub seq: u64,
    /// The field that differs (`setpoints` or `blocks[i]` for a count or split difference).
    pub field: String,
    /// The recorded value, as JSON.
    pub recorded: String,
    /// The replayed value, as JSON.
    pub replayed: String,
}

impl fmt::Display for Mismatch {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "first difference at seq {}, field `{}`: recorded {}, replayed {}",
            self.seq, self.field, self.recorded, self.replayed
        )
    }
}

impl std::error::Error for Mismatch {}

/// Why a replay failed.
#[derive(Debug, thiserror::Error)]
pub enum ReplayError {
    /// The trace does not hold a runnable program.
    #[error(transparent)]
    Program(#[from] TraceProgramError),
    /// The re-simulation itself failed.
    #[error("re-simulating the recorded blocks: {0}")]
    Sim(String),
    /// A setpoint (or block split) differs.
    #[error("{0}")]
    Mismatch(Mismatch),
}

/// A successful replay.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ReplayReport {
    /// Setpoints compared bit for bit.
    pub compared: u64,
    /// Setpoints the replay produced that the trace lacks (dropped on recording).
    pub missing_in_trace: u64,
    /// Input blocks re-simulated.
    pub blocks: usize,
}

/// Top-level fields of a JSON object, in order.
struct Fields(Vec<(String, Value)>);

impl<'de> Deserialize<'de> for Fields {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = Fields;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("a JSON object")
            }
            fn visit_map<A: MapAccess<'de>>(self, mut m: A) -> Result<Fields, A::Error> {
                let mut v = Vec::new();
                while let Some(e) = m.next_entry()? {
                    v.push(e);
                }
                Ok(Fields(v))
            }
        }
        d.deserialize_map(V)
    }
}

/// The first field (in declaration order) whose JSON differs: `None` when
/// the two serialise identically, which for our writer means equal bits
/// (shortest round-trip floats; `-0.0` prints as such).
pub fn first_difference(recorded: &SetpointMsg, replayed: &SetpointMsg) -> Option<Mismatch> {
    let a = serde_json::to_string(recorded).unwrap_or_default();
    let b = serde_json::to_string(replayed).unwrap_or_default();
    if a == b {
        return None;
    }
    let fa: Fields = serde_json::from_str(&a).unwrap_or(Fields(Vec::new()));
    let fb: Fields = serde_json::from_str(&b).unwrap_or(Fields(Vec::new()));
    let diff =
        fa.0.iter()
            .zip(&fb.0)
            .find(|((ka, va), (kb, vb))| ka != kb || va.to_string() != vb.to_string());
    let (field, r, p) = match diff {
        Some(((k, va), (_, vb))) => (k.clone(), va.to_string(), vb.to_string()),
        None => ("(record)".to_owned(), a, b),
    };
    Some(Mismatch {
        seq: recorded.seq,
        field,
        recorded: r,
        replayed: p,
    })
}

/// Re-simulates `trace` and compares every setpoint bit for bit.
pub fn replay(trace: &Trace) -> Result<ReplayReport, ReplayError> {
    let (config, program) = program_of(trace)?;
    let recorded = &trace.setpoints;
    let last_time = recorded.last().map_or(0.0, |s| s.time);
    let max_time = last_time + REPLAY_TIME_MARGIN_S;
    let mut next = 0usize; // index of the next recorded setpoint to match
    let mut compared = 0u64;
    let mut missing = 0u64;
    let mut block_k = 0usize;
    let res = sim::run(
        &config,
        &program,
        max_time,
        |item| -> Result<(), Mismatch> {
            match item {
                SimItem::Tick { setpoint, .. } => {
                    let replayed = SetpointMsg::from(setpoint);
                    match recorded.get(next) {
                        Some(r) if r.seq == replayed.seq => {
                            next += 1;
                            compared += 1;
                            if let Some(m) = first_difference(r, &replayed) {
                                return Err(m);
                            }
                        }
                        Some(r) if r.seq > replayed.seq => missing += 1,
                        Some(r) => {
                            return Err(Mismatch {
                                seq: r.seq,
                                field: "seq".into(),
                                recorded: r.seq.to_string(),
                                replayed: replayed.seq.to_string(),
                            });
                        }
                        None => {
                            return Err(Mismatch {
                                seq: replayed.seq,
                                field: "setpoints".into(),
                                recorded: format!("{} setpoints (trace ends)", recorded.len()),
                                replayed: "more setpoints".into(),
                            });
                        }
                    }
                }
                SimItem::Block(b) => {
                    let rec = trace.blocks.get(block_k);
                    block_k += 1;
                    let same = rec.is_some_and(|r| r.segments == b.segments);
                    if !same {
                        return Err(Mismatch {
                            seq: u64::from(b.index),
                            field: format!("blocks[{}].segments", b.index),
                            recorded: rec
                                .map(|r| serde_json::to_string(&r.segments).unwrap_or_default())
                                .unwrap_or_else(|| "(absent)".into()),
                            replayed: serde_json::to_string(&b.segments).unwrap_or_default(),
                        });
                    }
                }
                SimItem::Config(_) | SimItem::Event(_) => {}
            }
            Ok(())
        },
    );
    match res {
        Ok(_) => {}
        Err(SimError::Sink(m)) => return Err(ReplayError::Mismatch(m)),
        Err(e) => return Err(ReplayError::Sim(e.to_string())),
    }
    if let Some(r) = recorded.get(next) {
        return Err(ReplayError::Mismatch(Mismatch {
            seq: r.seq,
            field: "setpoints".into(),
            recorded: format!("{} setpoints", recorded.len()),
            replayed: format!("the run ended after {} setpoints", compared + missing),
        }));
    }
    Ok(ReplayReport {
        compared,
        missing_in_trace: missing,
        blocks: program.blocks.len(),
    })
}
