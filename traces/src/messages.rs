//! The channels of a trace and their messages.
//!
//! Every message is JSON (`message_encoding = "json"`) with a JSON Schema
//! (`schema encoding = "jsonschema"`) derived from the struct below by
//! `schemars`, so Foxglove and the Python `mcap` package read a trace without
//! our code. Field names are snake_case; lengths in mm, times in s, speeds in
//! mm/s unless a field says otherwise.

use interp_core::kinematics::Machine;
use interp_core::{InterpConfig, RunState, Setpoint};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::blocks::InputBlock;

/// Version of the message layout below; bumped when a field changes meaning.
pub const FORMAT_VERSION: u32 = 1;

/// MCAP profile string of interpd traces.
pub const PROFILE: &str = "interpd";

/// Message encoding of every channel.
pub const MESSAGE_ENCODING: &str = "json";

/// Schema encoding of every channel.
pub const SCHEMA_ENCODING: &str = "jsonschema";

/// The channels of a trace.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Channel {
    /// The run's configuration, once, first.
    Config,
    /// Every accepted input block, with its source line and how it was split.
    Blocks,
    /// Every setpoint.
    Setpoints,
    /// Loop timing per tick (wake lateness, tick compute time, queue depth).
    LoopTiming,
    /// Start, hold, resume, override, abort, fault, overflow, done.
    Events,
}

impl Channel {
    /// All channels, in the order they are registered.
    pub const ALL: [Channel; 5] = [
        Channel::Config,
        Channel::Blocks,
        Channel::Setpoints,
        Channel::LoopTiming,
        Channel::Events,
    ];

    /// MCAP topic.
    pub fn topic(self) -> &'static str {
        match self {
            Channel::Config => "/interpd/config",
            Channel::Blocks => "/interpd/blocks",
            Channel::Setpoints => "/interpd/setpoints",
            Channel::LoopTiming => "/interpd/loop_timing",
            Channel::Events => "/interpd/events",
        }
    }

    /// Schema name.
    pub fn schema_name(self) -> &'static str {
        match self {
            Channel::Config => "interpd.Config",
            Channel::Blocks => "interpd.Block",
            Channel::Setpoints => "interpd.Setpoint",
            Channel::LoopTiming => "interpd.LoopTiming",
            Channel::Events => "interpd.Event",
        }
    }

    /// The channel of an MCAP topic, if it is one of ours.
    pub fn from_topic(topic: &str) -> Option<Channel> {
        Channel::ALL.into_iter().find(|c| c.topic() == topic)
    }

    /// JSON Schema of the channel's messages, as JSON text.
    pub fn schema_json(self) -> String {
        let schema = match self {
            Channel::Config => schemars::schema_for!(ConfigMsg),
            Channel::Blocks => schemars::schema_for!(BlockMsg),
            Channel::Setpoints => schemars::schema_for!(SetpointMsg),
            Channel::LoopTiming => schemars::schema_for!(LoopTimingMsg),
            Channel::Events => schemars::schema_for!(EventMsg),
        };
        // A derived schema always serialises.
        serde_json::to_string_pretty(&schema).unwrap_or_default()
    }
}

/// `/interpd/config`: everything a replay needs besides the blocks.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct ConfigMsg {
    /// [`FORMAT_VERSION`] of the writer.
    pub format_version: u32,
    /// What wrote the trace (e.g. `interpd simulate 0.1.0`).
    pub writer: String,
    /// Where the program came from (a path or a name).
    pub source: String,
    /// `true` for a run with a clock (the daemon), `false` for `interpd simulate`.
    pub realtime: bool,
    /// The interpolator configuration, as `interp_core::InterpConfig` serialises
    /// it (kebab-case keys; missing keys take their defaults).
    #[schemars(with = "serde_json::Map<String, serde_json::Value>")]
    pub interp: InterpConfig,
    /// Position X Y Z A B C the machine started at.
    pub start: [f64; 6],
    /// Control points per segment when long NURBS were split.
    pub max_ctrl_per_block: usize,
    /// Capacity of the interpolator's segment queue.
    pub segment_queue: usize,
}

/// How one input block was cut into interpolator blocks.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct SegmentInfo {
    /// Id the segment carries in setpoints (`block_id`).
    pub block_id: u32,
    /// First parameter of the segment (the input curve's own parameter).
    pub u_start: f64,
    /// Last parameter of the segment.
    pub u_end: f64,
    /// Control points of the segment (NURBS), 0 for lines and arcs.
    pub control_points: usize,
    /// Arc length of the segment, mm.
    pub length: f64,
}

/// `/interpd/blocks`: one accepted input block.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct BlockMsg {
    /// Position of the block in the program, from 0.
    pub index: u32,
    /// The block as given (the JSON block form, `docs/traces.md`).
    pub block: InputBlock,
    /// The interpolator blocks it became, in order.
    pub segments: Vec<SegmentInfo>,
    /// Tick count when its last segment was accepted.
    pub accepted_at_seq: u64,
}

/// `/interpd/setpoints`: one interpolator output.
///
/// The one place where `interp_core::Setpoint` maps to the channel: if the
/// core's setpoint gains a field, add it here and in the two conversions.
/// `tip` and `tool_axis` are derived from the joints (the setpoint's axes)
/// and the run's machine ([`SetpointMsg::with_pose`]).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct SetpointMsg {
    /// Tick count since start, from 1, gapless.
    pub seq: u64,
    /// Machine time `seq·Ts`, s.
    pub time: f64,
    /// X, mm.
    pub x: f64,
    /// Y, mm.
    pub y: f64,
    /// Z, mm.
    pub z: f64,
    /// A, degrees.
    pub a: f64,
    /// B, degrees.
    pub b: f64,
    /// C, degrees.
    pub c: f64,
    /// Commanded path speed over the tick that ended here, mm/s (deg/s in a
    /// turn in place, whose path is the turn's measure in degrees).
    pub feed: f64,
    /// Path parameter of the block at this point.
    pub u: f64,
    /// Arc length of the run at this point, mm.
    pub s: f64,
    /// Id of the interpolator block the point is on (0 before any block).
    pub block_id: u32,
    /// Interpolator state after this tick.
    #[schemars(with = "RunStateName")]
    pub state: RunState,
    /// The tool tip in the workpiece frame, mm: the machine's forward
    /// transform of the joints (absent when the run has no machine).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tip: Option<[f64; 3]>,
    /// The unit tool axis in the workpiece frame, from the tip into the
    /// spindle (absent when the run has no machine).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tool_axis: Option<[f64; 3]>,
}

/// The names `RunState` serialises to (for the schema only).
#[derive(JsonSchema)]
#[allow(dead_code)]
enum RunStateName {
    Idle,
    Running,
    Holding,
    Stopping,
    Done,
    Fault,
}

impl From<&Setpoint> for SetpointMsg {
    fn from(sp: &Setpoint) -> Self {
        let [x, y, z, a, b, c] = sp.axes;
        SetpointMsg {
            seq: sp.seq,
            time: sp.time,
            x,
            y,
            z,
            a,
            b,
            c,
            feed: sp.feed,
            u: sp.u,
            s: sp.s,
            block_id: sp.block_id,
            state: sp.state,
            tip: None,
            tool_axis: None,
        }
    }
}

/// The machine of a run's configuration, whose forward transform gives each
/// setpoint's tool tip and tool axis (`None`: no machine, or one refused).
pub fn run_machine(config: &ConfigMsg) -> Option<Machine> {
    config
        .interp
        .machine
        .and_then(|spec| Machine::new(spec).ok())
}

impl SetpointMsg {
    /// The message of `sp` with its tool tip and tool axis when there is a
    /// `machine` ([`run_machine`]).
    pub fn with_pose(sp: &Setpoint, machine: Option<&Machine>) -> Self {
        let mut m = SetpointMsg::from(sp);
        if let Some(machine) = machine {
            let pose = machine.forward(&sp.axes);
            m.tip = Some([pose.tip.x, pose.tip.y, pose.tip.z]);
            m.tool_axis = Some([pose.axis.x, pose.axis.y, pose.axis.z]);
        }
        m
    }

    /// Back to the core's setpoint.
    pub fn to_setpoint(&self) -> Setpoint {
        Setpoint {
            seq: self.seq,
            time: self.time,
            axes: [self.x, self.y, self.z, self.a, self.b, self.c],
            feed: self.feed,
            u: self.u,
            s: self.s,
            block_id: self.block_id,
            state: self.state,
        }
    }

    /// X Y Z.
    pub fn xyz(&self) -> [f64; 3] {
        [self.x, self.y, self.z]
    }
}

/// `/interpd/loop_timing`: how one tick of the loop went.
#[derive(Clone, Copy, Debug, PartialEq, Default, Serialize, Deserialize, JsonSchema)]
pub struct LoopTimingMsg {
    /// Tick (the setpoint's `seq`).
    pub seq: u64,
    /// Wake time minus deadline, ns; `null` without a clock (`interpd simulate`).
    pub wake_lateness_ns: Option<i64>,
    /// Time spent in `Interpolator::tick`, ns; `null` when not measured.
    pub tick_compute_ns: Option<u64>,
    /// Interpolator segments queued after the tick.
    pub queue_depth: u32,
}

/// What happened, for `/interpd/events`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "kebab-case")]
pub enum EventKind {
    /// The run started (first block accepted).
    Start,
    /// Feed hold.
    Hold,
    /// Resume after a hold.
    Resume,
    /// Feed override changed (`value` is the new factor).
    Override,
    /// Abort requested.
    Abort,
    /// The interpolator reported a fault.
    Fault,
    /// The program ended (last point reached).
    Done,
    /// An input (block or setpoint) queue was full and something was dropped
    /// or refused (`count`: total so far).
    QueueOverflow,
    /// The recorder's queue was full and records were dropped (`count`: total so far).
    RecorderOverflow,
    /// A segment was queued into the interpolator (`count`: its id). With the
    /// commands, recorded at the tick count they followed, these make a live
    /// run's schedule: replay applies them at the same ticks.
    Commit,
    /// The end of the program was applied (`Interpolator::finish`).
    Finish,
    /// The interpolator left `done` for the next program of a session: the
    /// finished program is cleared as an abort clears it (replay applies
    /// it so), but no operator asked for it, so it is not an `abort`.
    NextProgram,
    /// A block waiting for room in a live run: the due parts of a long
    /// block before it were planned all the same (the planning that goes
    /// before a push), between the commands of that tick. Replay plans them
    /// at the same point: an operator's command in the same tick planned
    /// before them or after them gives different plans.
    Parts,
}

/// `/interpd/events`: one event.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct EventMsg {
    /// Tick at which it happened; for what a live run applies between ticks
    /// (commits, hold, resume, override, abort, finish): the interpolator
    /// ticks done before it, so it acts on tick `seq + 1`.
    pub seq: u64,
    /// Machine time, s.
    pub time: f64,
    /// What happened.
    pub kind: EventKind,
    /// A counter that goes with the event (overflows), if any.
    pub count: Option<u64>,
    /// A value that goes with the event (override factor), if any.
    pub value: Option<f64>,
    /// Free text, if any (never set on the real-time path: it would allocate).
    pub detail: Option<String>,
}

impl EventMsg {
    /// An event with no count, value or detail (allocation-free).
    pub fn new(kind: EventKind, seq: u64, time: f64) -> Self {
        EventMsg {
            seq,
            time,
            kind,
            count: None,
            value: None,
            detail: None,
        }
    }
}
