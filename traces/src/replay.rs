//! Bit-exact replay: re-simulate a trace's blocks under its config and
//! compare every setpoint, field by field, bit for bit.

use std::fmt;

use serde::de::{Deserialize, Deserializer, MapAccess, Visitor};
use serde_json::Value;

use crate::analysis::{TraceProgramError, program_of};
use crate::blocks::Pipeline;
use crate::messages::{EventKind, SetpointMsg};
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
    /// The recorded schedule cannot be followed (names the event).
    #[error("schedule: {0}")]
    Schedule(String),
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

/// A value's JSON text: equal text is equal bits (`Value`'s own `==` takes
/// `-0.0` for `0.0`).
fn json_text(v: &Value) -> String {
    v.to_string()
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
            .find(|((ka, va), (kb, vb))| ka != kb || json_text(va) != json_text(vb));
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

/// Why a replay's run stops early.
#[derive(Debug)]
enum Stop {
    /// A setpoint or block split differs.
    Differs(Mismatch),
    /// The recording of a truncated trace ends here.
    RecordingEnds,
}

impl fmt::Display for Stop {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Stop::Differs(m) => m.fmt(f),
            Stop::RecordingEnds => f.write_str("the recording ends"),
        }
    }
}

impl std::error::Error for Stop {}

/// Whether `trace` holds a live run's schedule (commit events from `interpd
/// serve`): replay then follows it tick by tick ([`replay_schedule`]).
pub fn has_schedule(trace: &Trace) -> bool {
    trace.events.iter().any(|e| e.kind == EventKind::Commit)
}

/// Re-simulates `trace` and compares every setpoint bit for bit. A live
/// recording is replayed by its schedule ([`replay_schedule`]); a simulated
/// one by running its program.
pub fn replay(trace: &Trace) -> Result<ReplayReport, ReplayError> {
    replay_with(trace, false)
}

/// [`replay`] of a trace cut short (read with
/// [`Trace::open_recovering`](crate::reader::Trace::open_recovering)):
/// every recorded setpoint is compared, and the run stops where the
/// recording stops instead of calling the rest missing.
pub fn replay_truncated(trace: &Trace) -> Result<ReplayReport, ReplayError> {
    replay_with(trace, true)
}

fn replay_with(trace: &Trace, truncated: bool) -> Result<ReplayReport, ReplayError> {
    if has_schedule(trace) {
        // Follows the recorded setpoints: it stops where they stop.
        return replay_schedule(trace);
    }
    let (config, program) = program_of(trace)?;
    let machine = crate::messages::run_machine(&config);
    let recorded = &trace.setpoints;
    let last_time = recorded.last().map_or(0.0, |s| s.time);
    let max_time = last_time + REPLAY_TIME_MARGIN_S;
    let mut next = 0usize; // index of the next recorded setpoint to match
    let mut compared = 0u64;
    let mut missing = 0u64;
    let mut block_k = 0usize;
    let res = sim::run(&config, &program, max_time, |item| -> Result<(), Stop> {
        match item {
            SimItem::Tick { setpoint, .. } => {
                let replayed = SetpointMsg::with_pose(setpoint, machine.as_ref());
                match recorded.get(next) {
                    Some(r) if r.seq == replayed.seq => {
                        next += 1;
                        compared += 1;
                        if let Some(m) = first_difference(r, &replayed) {
                            return Err(Stop::Differs(m));
                        }
                    }
                    Some(r) if r.seq > replayed.seq => missing += 1,
                    Some(r) => {
                        return Err(Stop::Differs(Mismatch {
                            seq: r.seq,
                            field: "seq".into(),
                            recorded: r.seq.to_string(),
                            replayed: replayed.seq.to_string(),
                        }));
                    }
                    None if truncated => return Err(Stop::RecordingEnds),
                    None => {
                        return Err(Stop::Differs(Mismatch {
                            seq: replayed.seq,
                            field: "setpoints".into(),
                            recorded: format!("{} setpoints (trace ends)", recorded.len()),
                            replayed: "more setpoints".into(),
                        }));
                    }
                }
            }
            SimItem::Block(b) => {
                let rec = trace.blocks.get(block_k);
                block_k += 1;
                if rec.is_none() && truncated {
                    return Ok(()); // recorded after the cut
                }
                if rec.is_none_or(|r| r.segments != b.segments) {
                    return Err(Stop::Differs(split_mismatch(
                        b.index,
                        rec.map(|r| r.segments.as_slice()),
                        &b.segments,
                    )));
                }
            }
            SimItem::Config(_) | SimItem::Event(_) => {}
        }
        Ok(())
    });
    match res {
        Ok(_) | Err(SimError::Sink(Stop::RecordingEnds)) => {}
        Err(SimError::Sink(Stop::Differs(m))) => return Err(ReplayError::Mismatch(m)),
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

/// Replays a live recording by its schedule: the interpolator of the run,
/// built from the recorded config, gets every recorded commit and command
/// after the same number of ticks as in the run (events with `seq = n` act
/// before tick `n + 1`), and every recorded setpoint is compared bit for bit.
///
/// Segments come from the recorded blocks, in order, sent through one
/// [`Pipeline`] per program (the `G64 P` stage included) from the end of
/// what the interpolator has queued when the program's first segment is
/// committed, exactly as the control plane sent them; a program's pipeline
/// is finished once all its recorded blocks are in and a commit still needs
/// a segment (its `end`). Segments an abort flushed before their commit are
/// skipped, and so are the rest of an aborted program's blocks.
pub fn replay_schedule(trace: &Trace) -> Result<ReplayReport, ReplayError> {
    follow_schedule(trace, None)
}

/// The interpolator segments a live recording ran, each with the ticks done
/// before the commit that expanded its block: each block is expanded from
/// the queue end at its first commit as [`replay_schedule`] does (which needs
/// the replay: after an abort the queue ends where the machine stopped).
/// Segment ids restart with each program. The setpoints are compared on the
/// way, so a trace that does not replay bit for bit gives no segments.
pub fn schedule_segments(trace: &Trace) -> Result<Vec<(u64, interp_core::Block)>, ReplayError> {
    let mut segments = Vec::new();
    follow_schedule(trace, Some(&mut segments))?;
    Ok(segments)
}

/// [`replay_schedule`], also collecting every expanded segment into `segments`.
fn follow_schedule(
    trace: &Trace,
    mut segments: Option<&mut Vec<(u64, interp_core::Block)>>,
) -> Result<ReplayReport, ReplayError> {
    use interp_core::Block;
    use interp_core::interp::DEFAULT_QUEUE;
    let config = trace.config.clone().ok_or(TraceProgramError::NoConfig)?;
    if config.segment_queue != DEFAULT_QUEUE {
        return Err(ReplayError::Schedule(format!(
            "recorded with a segment queue of {}, this build has {DEFAULT_QUEUE}",
            config.segment_queue
        )));
    }
    let machine = crate::messages::run_machine(&config);
    let mut ip: interp_run::Run = interp_run::Run::new(config.interp, config.start)
        .map_err(|e| ReplayError::Sim(format!("config: {e:?}")))?;
    let mut events = trace.events.iter().filter(|e| {
        matches!(
            e.kind,
            EventKind::Commit
                | EventKind::Hold
                | EventKind::Resume
                | EventKind::Override
                | EventKind::Abort
                | EventKind::NextProgram
                | EventKind::Parts
                | EventKind::Finish
        )
    });
    let mut next_event = events.next();
    let mut blocks = trace.blocks.iter().peekable();
    let mut pending: std::collections::VecDeque<Block> = Default::default();
    // The current program's pipeline, and whether its end was applied.
    let mut pipe: Option<(Pipeline, bool)> = None;
    // Whether the last segment pushed was under tool-centre-point control
    // (the frame of the queue's end).
    let mut queue_tcp = false;
    let mut used_blocks = 0usize;
    let mut compared = 0u64;
    let mut missing = 0u64;
    let mut ticks = 0u64;
    let bad = |e: &crate::messages::EventMsg, why: String| {
        ReplayError::Schedule(format!("event {:?} at tick {}: {why}", e.kind, e.seq))
    };
    for rec in &trace.setpoints {
        if rec.seq <= ticks {
            return Err(ReplayError::Mismatch(Mismatch {
                seq: rec.seq,
                field: "seq".into(),
                recorded: rec.seq.to_string(),
                replayed: format!("after {ticks}"),
            }));
        }
        while ticks < rec.seq {
            while let Some(e) = next_event.filter(|e| e.seq <= ticks) {
                if e.seq < ticks {
                    return Err(bad(e, format!("out of order (replay is at tick {ticks})")));
                }
                match e.kind {
                    EventKind::Commit => {
                        let id = e.count.unwrap_or(0) as u32;
                        let mut fresh = false;
                        while pending.front().is_none_or(|b| b.id != id) {
                            let released = match pipe.as_mut() {
                                // The current program's next segment: its next
                                // recorded block, or its end.
                                Some((p, finished)) if pending.is_empty() && p.next_id() == id => {
                                    let mut out = Vec::new();
                                    match blocks.next_if(|b| b.index as usize == p.blocks()) {
                                        Some(b) => {
                                            push_recorded(p, b, &mut out)?;
                                            used_blocks += 1;
                                        }
                                        None if !*finished => {
                                            *finished = true;
                                            out = p.finish();
                                        }
                                        None => return Err(bad(e, "no segment".into())),
                                    }
                                    out
                                }
                                _ if fresh => {
                                    return Err(bad(
                                        e,
                                        format!("segment {id} is not the next one"),
                                    ));
                                }
                                // A new program: its first recorded block, from
                                // where the queue ends.
                                _ => {
                                    pending.clear();
                                    while blocks.next_if(|b| b.index != 0).is_some() {}
                                    if blocks.peek().is_none() {
                                        return Err(bad(
                                            e,
                                            format!("no recorded program has segment {id}"),
                                        ));
                                    }
                                    // After an abort the program starts
                                    // where the machine stopped (the planner
                                    // moves there at its first push).
                                    let st = ip.executor().status();
                                    let (tail, tcp) = if st.idle_empty {
                                        (st.point, false)
                                    } else {
                                        let t = ip.driver().planner().tail();
                                        ([t.x, t.y, t.z], queue_tcp)
                                    };
                                    let p = Pipeline::new(
                                        tail,
                                        tcp,
                                        id,
                                        config.max_ctrl_per_block,
                                        &config.interp,
                                    )
                                    .map_err(|err| bad(e, format!("config: {err}")))?;
                                    pipe = Some((p, false));
                                    fresh = true;
                                    continue;
                                }
                            };
                            if let Some(out) = segments.as_deref_mut() {
                                out.extend(released.iter().map(|seg| (ticks, *seg)));
                            }
                            pending.extend(released);
                        }
                        let seg = pending
                            .pop_front()
                            .ok_or_else(|| bad(e, "no segment".into()))?;
                        ip.push(&seg)
                            .map_err(|err| bad(e, format!("segment {id}: {err}")))?;
                        queue_tcp = seg.is_tcp();
                    }
                    EventKind::Hold => ip.feed_hold(),
                    EventKind::Resume => ip.resume(),
                    EventKind::Override => {
                        let v = e.value.unwrap_or(f64::NAN);
                        ip.set_feed_override(v)
                            .map_err(|err| bad(e, err.to_string()))?;
                    }
                    // Leaving `done` for the next program clears as an abort does.
                    EventKind::Abort | EventKind::NextProgram => {
                        ip.abort();
                        pending.clear();
                        pipe = None;
                    }
                    EventKind::Finish => ip.finish(),
                    EventKind::Parts => ip.plan_parts(),
                    _ => {}
                }
                next_event = events.next();
            }
            let sp = ip.tick();
            ticks += 1;
            if ticks < rec.seq {
                missing += 1; // dropped on recording
                continue;
            }
            compared += 1;
            if let Some(m) = first_difference(rec, &SetpointMsg::with_pose(&sp, machine.as_ref())) {
                return Err(ReplayError::Mismatch(m));
            }
        }
    }
    Ok(ReplayReport {
        compared,
        missing_in_trace: missing,
        blocks: used_blocks,
    })
}

/// A block split differently on replay than on recording (`recorded` absent:
/// the trace has no such block).
fn split_mismatch(
    index: u32,
    recorded: Option<&[crate::messages::SegmentInfo]>,
    replayed: &[crate::messages::SegmentInfo],
) -> Mismatch {
    Mismatch {
        seq: u64::from(index),
        field: format!("blocks[{index}].segments"),
        recorded: recorded
            .map(|r| serde_json::to_string(r).unwrap_or_default())
            .unwrap_or_else(|| "(absent)".into()),
        replayed: serde_json::to_string(replayed).unwrap_or_default(),
    }
}

/// Sends recorded block `b` through the program's pipeline `p` (released
/// blocks into `out`); its split must be the recorded one.
fn push_recorded(
    p: &mut Pipeline,
    b: &crate::messages::BlockMsg,
    out: &mut Vec<interp_core::Block>,
) -> Result<(), ReplayError> {
    let eb = p
        .push(&b.block, out)
        .map_err(|err| ReplayError::Schedule(format!("expanding block {}: {err}", b.index)))?;
    if eb.info != b.segments {
        return Err(ReplayError::Mismatch(split_mismatch(
            b.index,
            Some(&b.segments),
            &eb.info,
        )));
    }
    Ok(())
}
