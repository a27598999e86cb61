//! Running a program through the interpolator with no clock.
//!
//! `interpd simulate` and `interpd replay` both call [`run`]: same program +
//! same [`ConfigMsg`] ⇒ the same setpoints, bit for bit. The driving order is
//! part of that contract, and it is `interp_run::Run`'s: blocks are pushed in
//! order; when the interpolator refuses one because its queue or look-ahead
//! is full, it ticks once and the push is tried again; after the last block,
//! `finish()` and tick until done.
//!
//! Between the program and the interpolator runs the `G64 P` stage
//! (`interp_core::smooth::Smoother`, window `DEFAULT_WINDOW`) of a
//! [`Pipeline`], as in the daemon's control plane: every expanded block is
//! pushed into it, and every block it releases goes to the interpolator at
//! once; at the end, `Pipeline::finish` releases the rest. The trace records
//! the program's own blocks, so a replay re-runs the stage and gets the same
//! segments.

use interp_core::interp::DEFAULT_QUEUE;
use interp_core::smooth::SmoothStats;
use interp_core::{Block, Executor, InterpConfig, RunState, Setpoint};
use interp_run::{Pushed, Run, RunError};
use serde::{Deserialize, Serialize};

use crate::blocks::{BlockError, Expanded, Pipeline, Program};
use crate::messages::{BlockMsg, ConfigMsg, EventKind, EventMsg, FORMAT_VERSION};

/// Id of the first interpolator block.
pub const FIRST_BLOCK_ID: u32 = 1;

/// Settings of a simulation besides `InterpConfig` (TOML section `[simulate]`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, rename_all = "kebab-case", deny_unknown_fields)]
pub struct SimSettings {
    /// Control points per segment when long NURBS are split. Default
    /// `interp_core::nurbs::MAX_CTRL` (32, the most), as `interpd serve`
    /// and `gcode::Program::to_core_blocks` split them, so the same program
    /// gives the same segments everywhere.
    pub max_ctrl_per_block: usize,
    /// The run is abandoned after this much machine time, s. Default 3600.
    pub max_machine_time: f64,
}

impl Default for SimSettings {
    fn default() -> Self {
        SimSettings {
            max_ctrl_per_block: interp_core::nurbs::MAX_CTRL,
            max_machine_time: 3600.0,
        }
    }
}

/// What a simulation hands its sink, in order.
#[derive(Debug)]
pub enum SimItem<'a> {
    /// The configuration (first).
    Config(&'a ConfigMsg),
    /// An input block, once all its segments were accepted.
    Block(&'a BlockMsg),
    /// One tick's setpoint and the segments queued after it.
    Tick {
        /// The setpoint.
        setpoint: &'a Setpoint,
        /// Interpolator segments queued after the tick.
        queue_depth: u32,
    },
    /// An event.
    Event(&'a EventMsg),
}

/// Why a simulation stopped.
#[derive(Debug, thiserror::Error)]
pub enum SimError<E> {
    /// The configuration was refused.
    #[error("configuration refused: {0}")]
    Config(String),
    /// A block of the program is invalid.
    #[error(transparent)]
    Block(#[from] BlockError),
    /// The interpolator refused a block.
    #[error("block {index}{}: segment {block_id} refused by the interpolator: {reason}",
        source_line.map(|l| format!(" (source line {l})")).unwrap_or_default())]
    Push {
        /// Position of the input block.
        index: usize,
        /// Its source line.
        source_line: Option<u32>,
        /// Id of the segment.
        block_id: u32,
        /// Why.
        reason: String,
    },
    /// The run did not end within `max_machine_time`.
    #[error("the run did not end within {seconds} s of machine time ({ticks} ticks)")]
    Timeout {
        /// Ticks run.
        ticks: u64,
        /// The limit, s.
        seconds: f64,
    },
    /// The sink failed.
    #[error(transparent)]
    Sink(E),
}

/// How a simulation ended.
#[derive(Clone, Copy, Debug)]
pub struct SimOutcome {
    /// The last setpoint.
    pub last: Setpoint,
    /// Input blocks run.
    pub blocks: usize,
    /// Interpolator blocks (segments) pushed.
    pub segments: usize,
    /// The interpolator's counters.
    pub stats: interp_core::interp::Stats,
    /// The look-ahead's counters over every solve.
    pub plan: interp_core::plan::PlanTotals,
    /// What the `G64 P` stage did.
    pub smoothing: SmoothStats,
}

/// The interpolator blocks of an expanded program: its segments through the
/// `G64 P` stage of a [`Pipeline`], exactly as [`run`] pushes them (for
/// analysis and replay).
pub fn smoothed_segments(expanded: &Expanded, cfg: &InterpConfig) -> Result<Vec<Block>, String> {
    let mut pipeline = Pipeline::new(expanded.start, false, FIRST_BLOCK_ID, usize::MAX, cfg)
        .map_err(|e| e.to_string())?;
    let mut out = Vec::new();
    for eb in &expanded.blocks {
        pipeline.push_expanded(eb, &mut out);
    }
    out.extend(pipeline.finish());
    Ok(out)
}

/// The configuration message for a program run with `interp` and `settings`.
pub fn config_for(
    program: &Program,
    interp: interp_core::InterpConfig,
    settings: &SimSettings,
    writer: &str,
    source: &str,
) -> ConfigMsg {
    ConfigMsg {
        format_version: FORMAT_VERSION,
        writer: writer.to_owned(),
        source: source.to_owned(),
        realtime: false,
        interp,
        start: program.start_joints(),
        max_ctrl_per_block: settings.max_ctrl_per_block,
        segment_queue: DEFAULT_QUEUE,
    }
}

/// Runs `program` under `config`, handing everything to `sink`.
pub fn run<E>(
    config: &ConfigMsg,
    program: &Program,
    max_machine_time: f64,
    mut sink: impl FnMut(SimItem<'_>) -> Result<(), E>,
) -> Result<SimOutcome, SimError<E>> {
    if config.segment_queue != DEFAULT_QUEUE {
        return Err(SimError::Config(format!(
            "segment-queue {} (this build runs {DEFAULT_QUEUE})",
            config.segment_queue
        )));
    }
    let period = config.interp.period;
    let max_ticks = if max_machine_time.is_finite() && max_machine_time > 0.0 {
        (max_machine_time / period).ceil() as u64
    } else {
        return Err(SimError::Config(format!(
            "max-machine-time must be a positive number of seconds, got {max_machine_time}"
        )));
    };
    let mut ip: Run = Run::new(config.interp, config.start)
        .map_err(|e| SimError::Config(e.to_string()))?
        .with_tick_limit(max_ticks);
    let expanded = program.expand(config.max_ctrl_per_block, FIRST_BLOCK_ID)?;
    sink(SimItem::Config(config)).map_err(SimError::Sink)?;

    let mut last = Setpoint::default();
    // Every tick is handed on.
    let on_tick = |last: &mut Setpoint,
                   sink: &mut dyn FnMut(SimItem<'_>) -> Result<(), E>,
                   sp: &Setpoint,
                   exec: &Executor|
     -> Result<(), E> {
        *last = *sp;
        sink(SimItem::Tick {
            setpoint: sp,
            queue_depth: exec.queued_segments() as u32,
        })
    };
    let run_error = |e: RunError<E>| match e {
        RunError::Timeout { ticks } => SimError::Timeout {
            ticks,
            seconds: max_machine_time,
        },
        RunError::Hook(e) => SimError::Sink(e),
        // Only a push refuses a block, and `push` below names it
        // (`SimError::Push`); the end of the run pushes nothing.
        RunError::Push(e) => SimError::Config(e.to_string()),
    };

    // The program's segments through the `G64 P` stage, as the daemon's
    // control plane sends them.
    let mut pipeline = Pipeline::new(
        expanded.start,
        false,
        FIRST_BLOCK_ID,
        config.max_ctrl_per_block,
        &config.interp,
    )
    .map_err(|e| SimError::Config(e.to_string()))?;
    let mut released = Vec::new();
    let mut segments = 0usize;
    let mut faulted = false;
    // Pushes one released block into the interpolator, ticking while it
    // must wait for room (see `Run::push_waiting`); false: it faulted.
    let push = |ip: &mut Run,
                last: &mut Setpoint,
                sink: &mut dyn FnMut(SimItem<'_>) -> Result<(), E>,
                seg: &Block,
                eb: &crate::blocks::ExpandedBlock|
     -> Result<bool, SimError<E>> {
        match ip.push_waiting(seg, |sp, exec| on_tick(last, sink, sp, exec)) {
            Ok(pushed) => Ok(pushed == Pushed::Queued),
            Err(RunError::Push(e)) => Err(SimError::Push {
                index: eb.index,
                source_line: eb.input.source_line,
                block_id: seg.id,
                reason: e.to_string(),
            }),
            Err(e) => Err(run_error(e)),
        }
    };
    'blocks: for (k, eb) in expanded.blocks.iter().enumerate() {
        if k == 0 {
            let ev = EventMsg::new(EventKind::Start, 0, 0.0);
            sink(SimItem::Event(&ev)).map_err(SimError::Sink)?;
        }
        released.clear();
        pipeline.push_expanded(eb, &mut released);
        for out in &released {
            if !push(&mut ip, &mut last, &mut sink, out, eb)? {
                faulted = true;
                break 'blocks;
            }
            segments += 1;
        }
        let msg = BlockMsg {
            index: eb.index as u32,
            block: eb.input.clone(),
            segments: eb.info.clone(),
            accepted_at_seq: last.seq,
        };
        sink(SimItem::Block(&msg)).map_err(SimError::Sink)?;
    }
    if !faulted {
        let tail = expanded.blocks.last();
        for out in pipeline.finish() {
            let eb = tail.expect("a released block comes from some input block");
            if !push(&mut ip, &mut last, &mut sink, &out, eb)? {
                faulted = true;
                break;
            }
            segments += 1;
        }
    }
    if !faulted {
        ip.run_to_end(|sp, exec| on_tick(&mut last, &mut sink, sp, exec))
            .map_err(run_error)?;
    }
    let kind = if last.state == RunState::Fault {
        EventKind::Fault
    } else {
        EventKind::Done
    };
    let ev = EventMsg::new(kind, last.seq, last.time);
    sink(SimItem::Event(&ev)).map_err(SimError::Sink)?;
    Ok(SimOutcome {
        last,
        blocks: expanded.blocks.len(),
        segments,
        stats: ip.stats(),
        plan: ip.driver().planner().window().totals,
        smoothing: pipeline.stats(),
    })
}

/// Runs `program` like [`run`] and writes everything to `writer` (config,
/// blocks at the time they were accepted, setpoints, loop timing with the
/// queue depth and no clock readings, events). `also` sees every item first.
pub fn record<W: std::io::Write + std::io::Seek>(
    config: &ConfigMsg,
    program: &Program,
    max_machine_time: f64,
    writer: &mut crate::writer::TraceWriter<W>,
    mut also: impl FnMut(&SimItem<'_>),
) -> Result<SimOutcome, SimError<crate::writer::WriteError>> {
    let period = config.interp.period;
    run(config, program, max_machine_time, |item| {
        also(&item);
        match item {
            SimItem::Config(c) => writer.config(c),
            SimItem::Block(b) => writer.block(b, b.accepted_at_seq as f64 * period),
            SimItem::Tick {
                setpoint,
                queue_depth,
            } => {
                writer.setpoint(setpoint)?;
                let timing = crate::messages::LoopTimingMsg {
                    seq: setpoint.seq,
                    queue_depth,
                    ..Default::default()
                };
                writer.loop_timing(&timing, setpoint.time)
            }
            SimItem::Event(e) => writer.event(e),
        }
    })
}
