//! Quantities derived from setpoints and the exact blocks: curvature, chord
//! error, MRR, tangential acceleration and jerk, centripetal acceleration, and
//! the run summary that `interpd simulate` and `interpd trace summary` print.
//!
//! Both compute it with the same [`Analyzer`] (simulate as the run goes,
//! trace summary from the file), so the two agree exactly.

use std::collections::BTreeMap;
use std::fmt;

use interp_core::feed::{relative_mrr, signed_curvature};
use interp_core::metrics::chord_error_between;
use interp_core::plan::PlanTotals;
use interp_core::{Block, Curve, RunState, Setpoint, Vec3};
use serde::Serialize;

use crate::blocks::{BlockError, Program};
use crate::messages::{BlockMsg, ConfigMsg, EventKind};
use crate::reader::Trace;

/// Samples per tick in the chord-error search (then golden section), as `interpd demo`.
pub const CHORD_SAMPLES: usize = 16;

/// Fraction of the path jerk limit a tangential jerk must pass to count as
/// signed in [`Summary::jerk_sign_changes`] (a dead band, so that rounding
/// and grid effects about zero are not counted as sign changes).
pub const JERK_SIGN_THRESHOLD: f64 = 0.01;

/// Derived values at one setpoint.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Sample {
    /// The setpoint's `seq`.
    pub seq: u64,
    /// Machine time, s.
    pub time: f64,
    /// Commanded feed, mm/s.
    pub feed: f64,
    /// Curvature of the path at the setpoint, 1/mm.
    pub curvature: f64,
    /// Largest distance between the exact path and the chord from the previous setpoint, mm.
    pub chord_error: f64,
    /// `Δfeed/Ts`, mm/s².
    pub tangential_accel: f64,
    /// `Δ(tangential accel)/Ts`, mm/s³.
    pub jerk: f64,
    /// `feed²·curvature`, mm/s².
    pub centripetal_accel: f64,
    /// MRR relative to straight cutting at the programmed feed (eq. 18–22),
    /// for blocks with MRR parameters.
    pub mrr: Option<f64>,
}

/// What a run did, from its setpoints and blocks.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Summary {
    /// Where the program came from.
    pub source: String,
    /// Input blocks.
    pub input_blocks: usize,
    /// Interpolator blocks (segments) they became.
    pub segments: usize,
    /// Setpoints.
    pub setpoints: u64,
    /// Setpoints missing from the sequence (dropped by a full queue).
    pub missing_setpoints: u64,
    /// Machine time of the last setpoint, s.
    pub duration_s: f64,
    /// Path length travelled, mm.
    pub length_mm: f64,
    /// Largest commanded feed on a path, mm/s (turns in place, whose speed
    /// is in deg/s, are in [`Summary::max_turn_speed_deg_s`]).
    pub max_feed_mm_s: f64,
    /// The same, mm/min.
    pub max_feed_mm_min: f64,
    /// Largest chord error, mm.
    pub max_chord_error_mm: f64,
    /// `seq` of the setpoint ending that tick.
    pub max_chord_error_seq: u64,
    /// The configured chord tolerance, mm.
    pub chord_tolerance_mm: f64,
    /// Largest turning speed of a turn in place (its path is the turn's
    /// measure in degrees), deg/s; absent when the run has none.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_turn_speed_deg_s: Option<f64>,
    /// Largest |tangential acceleration| on a path, mm/s².
    pub max_tangential_accel_mm_s2: f64,
    /// Largest |tangential jerk| on a path, mm/s³.
    pub max_tangential_jerk_mm_s3: f64,
    /// Times the tangential jerk changed sign: from above
    /// [`JERK_SIGN_THRESHOLD`] × the path jerk limit to below minus that, or
    /// back (a jerk that rests at 0 between two phases of opposite sign counts
    /// once, rounding noise about 0 not at all). A jerk-limited schedule
    /// changes sign a few times per speed change; chatter shows as hundreds.
    pub jerk_sign_changes: u64,
    /// Machine time with the path moving (feed > 0), s.
    pub motion_time_s: f64,
    /// `jerk_sign_changes / motion_time_s`, 1/s (0 without motion).
    pub jerk_sign_changes_per_s: f64,
    /// Largest centripetal acceleration, mm/s².
    pub max_centripetal_accel_mm_s2: f64,
    /// Times the path came to rest while running and then moved on: every
    /// stop before the end that no hold asked for (a corner or exact stop
    /// of the program, a queue that ran dry, or a stop the look-ahead added;
    /// [`Summary::planner`] says which, where the run is simulated).
    pub rests: u64,
    /// Smallest and largest relative MRR while cutting (feed > 0) on blocks
    /// with MRR parameters, if any.
    pub relative_mrr_range: Option<[f64; 2]>,
    /// State of the last setpoint.
    pub final_state: String,
    /// X Y Z of the last setpoint, mm.
    pub final_point: [f64; 3],
    /// Events by kind.
    pub events: BTreeMap<String, u64>,
    /// Largest wake lateness, µs (real-time runs only).
    pub max_wake_lateness_us: Option<f64>,
    /// Why the path came to rest, from the interpolator's and the
    /// look-ahead's counters (simulated runs only: a trace holds the
    /// setpoints, not the planner's work).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub planner: Option<PlannerReport>,
}

/// What the look-ahead did over a run, and the stops it planned by reason.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PlannerReport {
    /// Joins between segments planned as rest points: corners slower to
    /// pass than to stop at, exact stops (`G61`), cusps.
    pub junction_stops: u64,
    /// Joins passed without a stop.
    pub junctions_blended: u64,
    /// Ticks at rest at the end of what was queued before the program ended
    /// (the queue ran dry).
    pub starved_ticks: u64,
    /// Linear programs solved (first passes).
    pub solves: u64,
    /// Refinement passes that improved a plan.
    pub refinements: u64,
    /// Solves that failed and were tried again with other rows (a warm
    /// first pass, then the rows of the kept plan): slower planning, the
    /// same motion.
    pub retries: u64,
    /// Re-solves that failed every pass and kept a rest point at the old
    /// end of the queue: a stop the program does not ask for.
    pub kept_rests: u64,
    /// Re-solves that failed every pass and kept the plan whole up to a
    /// rest point it comes to (a corner), planning from rest there: slower
    /// planning, no stop added.
    pub kept_to_corner: u64,
    /// Re-solves that fell back to the crawl (a rest at every knot of the
    /// stretch): stops the program does not ask for.
    pub crawls: u64,
    /// Rebuilds that left pieces uncut for lack of room in one linear
    /// program (slower there, never over a limit).
    pub uncut: u64,
    /// Linear programs whose per-axis jerk rows did not all fit: the
    /// farthest pieces' were aggregated (slower there until planned again).
    pub aggregated: u64,
    /// The last solver failure (retried, or behind a kept rest or a crawl), if any.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub last_failure: Option<String>,
}

impl PlannerReport {
    /// From the interpolator's counters and the look-ahead's totals.
    pub fn new(stats: &interp_core::interp::Stats, plan: &PlanTotals) -> Self {
        PlannerReport {
            junction_stops: stats.junctions_stopped,
            junctions_blended: stats.junctions_blended,
            starved_ticks: stats.starved_ticks,
            solves: plan.solves,
            refinements: plan.passes,
            retries: plan.retries(),
            kept_rests: plan.fell_back,
            kept_to_corner: plan.kept_to_rest,
            crawls: plan.crawled,
            uncut: plan.uncut,
            aggregated: plan.aggregated,
            last_failure: plan.last_failure.map(|e| e.to_string()),
        }
    }

    /// Stops the look-ahead added that the program does not ask for.
    pub fn added_stops(&self) -> u64 {
        self.kept_rests + self.crawls
    }
}

/// Computes [`Sample`]s tick by tick and keeps the [`Summary`] maxima.
#[derive(Debug)]
pub struct Analyzer {
    period: f64,
    segments: BTreeMap<u32, Block>,
    prev: Setpoint,
    prev_accel: f64,
    /// Sign of the last tangential jerk outside the dead band (0: none yet).
    jerk_sign: i8,
    /// The path came to rest while running; a rest once it moves on (the
    /// rest at the end of a run is no stop).
    resting: bool,
    /// The dead band's half width, mm/s³.
    jerk_dead_band: f64,
    summary: Summary,
    mrr_range: Option<[f64; 2]>,
    /// A segment id was reused since the last setpoint: a new program of a
    /// session, which starts where the last one stopped.
    new_program: bool,
    /// The run's machine: under tool-centre-point control the path is the
    /// tool tip, which its forward transform gives.
    machine: Option<interp_core::kinematics::Machine>,
}

fn p3(sp: &Setpoint) -> Vec3 {
    Vec3::new(sp.axes[0], sp.axes[1], sp.axes[2])
}

impl Analyzer {
    /// For a run under `config` over `segments` (the interpolator blocks).
    pub fn new<'a>(
        config: &ConfigMsg,
        input_blocks: usize,
        segments: impl IntoIterator<Item = &'a Block>,
    ) -> Self {
        let segments: BTreeMap<u32, Block> = segments.into_iter().map(|b| (b.id, *b)).collect();
        let prev = Setpoint {
            axes: config.start,
            ..Setpoint::default()
        };
        Analyzer {
            period: config.interp.period,
            summary: Summary {
                source: config.source.clone(),
                input_blocks,
                segments: segments.len(),
                setpoints: 0,
                missing_setpoints: 0,
                duration_s: 0.0,
                length_mm: 0.0,
                max_feed_mm_s: 0.0,
                max_feed_mm_min: 0.0,
                max_chord_error_mm: 0.0,
                max_chord_error_seq: 0,
                chord_tolerance_mm: config.interp.chord_tolerance,
                max_turn_speed_deg_s: None,
                max_tangential_accel_mm_s2: 0.0,
                max_tangential_jerk_mm_s3: 0.0,
                jerk_sign_changes: 0,
                motion_time_s: 0.0,
                jerk_sign_changes_per_s: 0.0,
                max_centripetal_accel_mm_s2: 0.0,
                rests: 0,
                relative_mrr_range: None,
                final_state: "idle".into(),
                final_point: [config.start[0], config.start[1], config.start[2]],
                events: BTreeMap::new(),
                max_wake_lateness_us: None,
                planner: None,
            },
            segments,
            prev,
            prev_accel: 0.0,
            jerk_sign: 0,
            resting: false,
            jerk_dead_band: JERK_SIGN_THRESHOLD * config.interp.max_path_jerk,
            mrr_range: None,
            new_program: false,
            machine: crate::messages::run_machine(config),
        }
    }

    /// Whether the path of `sp`'s block is the tool tip (tool-centre-point control).
    fn tcp_at(&self, sp: &Setpoint) -> bool {
        self.segments.get(&sp.block_id).is_some_and(Block::is_tcp)
    }

    /// The point of `sp` on the path, in the frame of a block under
    /// tool-centre-point control (`tcp`: the tool tip in the workpiece
    /// frame) or not (X Y Z of the machine).
    fn path_point(&self, sp: &Setpoint, tcp: bool) -> Vec3 {
        match (&self.machine, tcp) {
            (Some(m), true) => m.forward(&sp.axes).tip,
            _ => p3(sp),
        }
    }

    /// Adds a segment committed during the run. Segment ids restart with
    /// each program of a live session: a reused id replaces the old segment
    /// from here on.
    pub fn add_segment(&mut self, seg: &Block) {
        if self.segments.insert(seg.id, *seg).is_some() {
            self.new_program = true;
        }
        self.summary.segments += 1;
    }

    /// Chord error of the tick from `a` to `b` over the blocks between.
    fn chord_error(&self, a: &Setpoint, b: &Setpoint) -> f64 {
        let tcp = self.tcp_at(b);
        let (pa, pb) = (self.path_point(a, tcp), self.path_point(b, tcp));
        let mut worst = 0.0f64;
        let first = a.block_id.max(1);
        if b.block_id < first {
            return 0.0;
        }
        for (&id, seg) in self.segments.range(first..=b.block_id) {
            let u0 = if id == a.block_id {
                a.u
            } else {
                seg.path.u_start()
            };
            let u1 = if id == b.block_id {
                b.u
            } else {
                seg.path.u_end()
            };
            if let Some(at) = seg.orientation.and_then(|o| o.fixed()) {
                // A turn in place: the path is the point the tool stands
                // on (the block's own path is the turn's measure).
                worst = worst.max((pa - at).norm()).max((pb - at).norm());
                continue;
            }
            worst = worst.max(chord_error_between(
                &seg.path,
                u0,
                u1,
                pa,
                pb,
                CHORD_SAMPLES,
            ));
        }
        worst
    }

    /// Derived values at `sp`, the setpoint after the last one pushed.
    pub fn push(&mut self, sp: &Setpoint) -> Sample {
        let ts = self.period;
        // A gap (dropped setpoints) spans several ticks.
        let ticks = sp.seq.saturating_sub(self.prev.seq).max(1);
        let dt = ts * ticks as f64;
        let accel = (sp.feed - self.prev.feed) / dt;
        let jerk = (accel - self.prev_accel) / dt;
        let (curvature, mrr) = match self.segments.get(&sp.block_id) {
            Some(seg) => {
                let d = seg.path.eval(sp.u, 2);
                let mrr = seg.mrr.map(|m| {
                    let ks = signed_curvature(&d, m.tool_side);
                    relative_mrr(sp.feed, seg.feed, ks, m.tool_radius, m.depth_of_cut)
                });
                (d.curvature(), mrr)
            }
            None => (0.0, None),
        };
        let chord_error = if ticks == 1 {
            let mut from = self.prev;
            if core::mem::take(&mut self.new_program) {
                // The old program's segment ids mean the new program's now:
                // the tick starts at the new program's first segment.
                from.block_id = 0;
            }
            self.chord_error(&from, sp)
        } else {
            0.0
        };
        let s = Sample {
            seq: sp.seq,
            time: sp.time,
            feed: sp.feed,
            curvature,
            chord_error,
            tangential_accel: accel,
            jerk,
            centripetal_accel: sp.feed * sp.feed * curvature,
            mrr,
        };
        let tcp = self.tcp_at(sp);
        let step = (self.path_point(sp, tcp) - self.path_point(&self.prev, tcp)).norm();
        let turning = self
            .segments
            .get(&sp.block_id)
            .and_then(|b| b.orientation)
            .is_some_and(|o| o.fixed().is_some());
        let m = &mut self.summary;
        m.setpoints += 1;
        m.missing_setpoints += ticks - 1;
        m.duration_s = sp.time;
        m.length_mm += step;
        if turning {
            // Degrees, not millimetres: kept apart from the path's maxima.
            let t = m.max_turn_speed_deg_s.get_or_insert(0.0);
            *t = t.max(sp.feed);
        } else {
            m.max_feed_mm_s = m.max_feed_mm_s.max(sp.feed);
            m.max_feed_mm_min = m.max_feed_mm_s * 60.0;
        }
        if chord_error > m.max_chord_error_mm {
            m.max_chord_error_mm = chord_error;
            m.max_chord_error_seq = sp.seq;
        }
        if !turning {
            m.max_tangential_accel_mm_s2 = m.max_tangential_accel_mm_s2.max(accel.abs());
            m.max_tangential_jerk_mm_s3 = m.max_tangential_jerk_mm_s3.max(jerk.abs());
        }
        if sp.feed > 0.0 || self.prev.feed > 0.0 {
            m.motion_time_s += dt;
        }
        if sp.feed > 0.0 {
            m.rests += u64::from(core::mem::take(&mut self.resting));
        } else if self.prev.feed > 0.0 && sp.state == RunState::Running {
            self.resting = true;
        }
        // Only consecutive ticks give a jerk (a gap's is a difference over
        // several periods, not the schedule's); a turn's is in deg/s³.
        if !turning && ticks == 1 && jerk.abs() > self.jerk_dead_band {
            let sign = if jerk > 0.0 { 1 } else { -1 };
            if self.jerk_sign != 0 && sign != self.jerk_sign {
                m.jerk_sign_changes += 1;
            }
            self.jerk_sign = sign;
        }
        m.max_centripetal_accel_mm_s2 = m.max_centripetal_accel_mm_s2.max(s.centripetal_accel);
        if let (Some(r), true) = (mrr, sp.feed > 0.0) {
            let range = self.mrr_range.get_or_insert([r, r]);
            range[0] = range[0].min(r);
            range[1] = range[1].max(r);
        }
        m.final_state = state_name(sp.state).into();
        m.final_point = [sp.axes[0], sp.axes[1], sp.axes[2]];
        self.prev = *sp;
        self.prev_accel = accel;
        s
    }

    /// Counts an event.
    pub fn event(&mut self, kind: EventKind) {
        let name = serde_json::to_value(kind)
            .ok()
            .and_then(|v| v.as_str().map(str::to_owned))
            .unwrap_or_default();
        *self.summary.events.entry(name).or_insert(0) += 1;
    }

    /// Notes why the path came to rest, from a simulated run's counters.
    pub fn planner(&mut self, stats: &interp_core::interp::Stats, plan: &PlanTotals) {
        self.summary.planner = Some(PlannerReport::new(stats, plan));
    }

    /// Notes a wake lateness, ns.
    pub fn lateness(&mut self, ns: i64) {
        let us = ns as f64 / 1e3;
        let m = &mut self.summary.max_wake_lateness_us;
        *m = Some(m.map_or(us, |x| x.max(us)));
    }

    /// The summary so far.
    pub fn summary(&self) -> Summary {
        let m = &self.summary;
        Summary {
            relative_mrr_range: self.mrr_range,
            jerk_sign_changes_per_s: if m.motion_time_s > 0.0 {
                m.jerk_sign_changes as f64 / m.motion_time_s
            } else {
                0.0
            },
            ..m.clone()
        }
    }
}

/// Lower-case name of a state, as in the setpoint channel's JSON but lower case.
pub fn state_name(s: RunState) -> &'static str {
    match s {
        RunState::Idle => "idle",
        RunState::Running => "running",
        RunState::Holding => "holding",
        RunState::Stopping => "stopping",
        RunState::Done => "done",
        RunState::Fault => "fault",
    }
}

/// Why a trace cannot be analysed or replayed.
#[derive(Debug, thiserror::Error)]
pub enum TraceProgramError {
    /// The trace has no `/interpd/config` message.
    #[error("the trace has no /interpd/config message")]
    NoConfig,
    /// The blocks are not numbered 0, 1, 2, … in order.
    #[error("/interpd/blocks message {found} where block {expected} was expected")]
    BlockOrder {
        /// Index expected.
        expected: usize,
        /// Index found.
        found: u32,
    },
    /// A recorded block no longer expands.
    #[error(transparent)]
    Block(#[from] BlockError),
    /// The recorded split differs from today's split of the same block.
    #[error("block {index} splits into {today:?} today but {recorded:?} in the trace")]
    Split {
        /// The block.
        index: usize,
        /// Segment ids and parameter ranges now.
        today: Vec<(u32, f64, f64)>,
        /// As recorded.
        recorded: Vec<(u32, f64, f64)>,
    },
    /// A live recording's schedule could not be followed to its segments.
    #[error("following the recorded schedule: {0}")]
    Schedule(String),
}

/// The program a trace ran (from its config and block messages).
pub fn program_of(trace: &Trace) -> Result<(ConfigMsg, Program), TraceProgramError> {
    let config = trace.config.clone().ok_or(TraceProgramError::NoConfig)?;
    for (k, b) in trace.blocks.iter().enumerate() {
        if b.index as usize != k {
            return Err(TraceProgramError::BlockOrder {
                expected: k,
                found: b.index,
            });
        }
    }
    let [x, y, z, a, b, c] = config.start;
    let program = Program {
        start: Some([x, y, z]),
        rotary: Some([a, b, c]),
        blocks: trace.blocks.iter().map(|b| b.block.clone()).collect(),
    };
    Ok((config, program))
}

fn split_key(b: &BlockMsg) -> Vec<(u32, f64, f64)> {
    b.segments
        .iter()
        .map(|s| (s.block_id, s.u_start, s.u_end))
        .collect()
}

/// Derived samples and the summary of a recorded run.
pub fn analyse(trace: &Trace) -> Result<(Summary, Vec<Sample>), TraceProgramError> {
    if crate::replay::has_schedule(trace) {
        // A live session (`serve --record`): programs after the first start
        // where the last one ended or was aborted, so only the replay of its
        // schedule knows where each block was expanded from.
        let config = trace.config.clone().ok_or(TraceProgramError::NoConfig)?;
        let segments = crate::replay::schedule_segments(trace)
            .map_err(|e| TraceProgramError::Schedule(e.to_string()))?;
        let mut an = Analyzer::new(&config, trace.blocks.len(), &[]);
        let mut next = segments.iter().peekable();
        let mut samples = Vec::with_capacity(trace.setpoints.len());
        for m in &trace.setpoints {
            // Segments expanded by a commit before this tick.
            while let Some((_, seg)) = next.next_if(|(tick, _)| *tick < m.seq) {
                an.add_segment(seg);
            }
            samples.push(an.push(&m.to_setpoint()));
        }
        return Ok(finish_analysis(an, trace, samples));
    }
    let (config, program) = program_of(trace)?;
    let expanded = program.expand(config.max_ctrl_per_block, crate::sim::FIRST_BLOCK_ID)?;
    for (eb, rec) in expanded.blocks.iter().zip(&trace.blocks) {
        let today: Vec<_> = eb
            .info
            .iter()
            .map(|s| (s.block_id, s.u_start, s.u_end))
            .collect();
        let recorded = split_key(rec);
        if today != recorded {
            return Err(TraceProgramError::Split {
                index: eb.index,
                today,
                recorded,
            });
        }
    }
    // The interpolator ran the segments the `G64 P` stage released.
    let segments = crate::sim::smoothed_segments(&expanded, &config.interp)
        .map_err(TraceProgramError::Schedule)?;
    let an = Analyzer::new(&config, expanded.blocks.len(), &segments);
    Ok(run_analysis(an, trace))
}

/// Feeds the trace's setpoints, events and loop timing through `an`.
fn run_analysis(mut an: Analyzer, trace: &Trace) -> (Summary, Vec<Sample>) {
    let samples = trace
        .setpoints
        .iter()
        .map(|m| an.push(&m.to_setpoint()))
        .collect();
    finish_analysis(an, trace, samples)
}

/// Adds the trace's events and loop timing to `an`'s summary.
fn finish_analysis(
    mut an: Analyzer,
    trace: &Trace,
    samples: Vec<Sample>,
) -> (Summary, Vec<Sample>) {
    for e in &trace.events {
        an.event(e.kind);
    }
    for t in &trace.loop_timing {
        if let Some(ns) = t.wake_lateness_ns {
            an.lateness(ns);
        }
    }
    (an.summary(), samples)
}

impl fmt::Display for Summary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "run of {}", self.source)?;
        writeln!(
            f,
            "  program       {} input blocks, {} segments",
            self.input_blocks, self.segments
        )?;
        writeln!(
            f,
            "  setpoints     {} ({} missing), {:.6} s, {:.6} mm travelled",
            self.setpoints, self.missing_setpoints, self.duration_s, self.length_mm
        )?;
        writeln!(
            f,
            "  feed          max {:.6} mm/s ({:.3} mm/min)",
            self.max_feed_mm_s, self.max_feed_mm_min
        )?;
        if let Some(t) = self.max_turn_speed_deg_s {
            writeln!(
                f,
                "  turns         max {t:.6} deg/s ({:.3} deg/min) turning in place",
                t * 60.0
            )?;
        }
        writeln!(
            f,
            "  chord error   max {:.6e} mm at seq {} (tolerance {} mm)",
            self.max_chord_error_mm, self.max_chord_error_seq, self.chord_tolerance_mm
        )?;
        writeln!(
            f,
            "  tangential    max |accel| {:.3} mm/s², max |jerk| {:.6e} mm/s³",
            self.max_tangential_accel_mm_s2, self.max_tangential_jerk_mm_s3
        )?;
        writeln!(
            f,
            "  jerk sign     {} changes in {:.3} s of motion ({:.2}/s)",
            self.jerk_sign_changes, self.motion_time_s, self.jerk_sign_changes_per_s
        )?;
        writeln!(
            f,
            "  centripetal   max accel {:.3} mm/s²",
            self.max_centripetal_accel_mm_s2
        )?;
        match &self.planner {
            Some(p) => {
                writeln!(
                    f,
                    "  rests         {} before the end: {} at junction stops (corners, exact stops, cusps), {} added by the look-ahead",
                    self.rests,
                    p.junction_stops,
                    p.added_stops(),
                )?;
                writeln!(
                    f,
                    "  look-ahead    {} solves, {} refinements, {} retries, {} uncut, {} aggregated, {} plans kept to a corner; {} rests kept at a queue end, {} crawls; {} ticks with the queue dry",
                    p.solves,
                    p.refinements,
                    p.retries,
                    p.uncut,
                    p.aggregated,
                    p.kept_to_corner,
                    p.kept_rests,
                    p.crawls,
                    p.starved_ticks
                )?;
                if let Some(e) = &p.last_failure {
                    writeln!(f, "  last failure  {e}")?;
                }
            }
            None => writeln!(f, "  rests         {} before the end", self.rests)?,
        }
        match self.relative_mrr_range {
            Some([lo, hi]) => writeln!(f, "  MRR           relative {lo:.4} .. {hi:.4}")?,
            None => writeln!(f, "  MRR           no block carries MRR parameters")?,
        }
        writeln!(
            f,
            "  final         {} at ({}, {}, {})",
            self.final_state, self.final_point[0], self.final_point[1], self.final_point[2]
        )?;
        let ev: Vec<String> = self
            .events
            .iter()
            .map(|(k, n)| format!("{k} {n}"))
            .collect();
        writeln!(f, "  events        {}", ev.join(", "))?;
        if let Some(l) = self.max_wake_lateness_us {
            writeln!(f, "  wake lateness max {l:.1} µs")?;
        }
        Ok(())
    }
}
