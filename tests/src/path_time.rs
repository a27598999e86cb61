//! Path time of a program against the acceleration-only optimum (issue 9).
//!
//! Under acceleration-only limits the minimum path time is the classic
//! forward/backward integration on a fine arc-length grid: the speed limit
//! `V(s)` of every pointwise law, then `v² ≤ v_prev² + 2·A·Δs` forwards and
//! backwards, time `Σ 2Δs/(v_i + v_{i+1})`. Jerk limits can only lengthen it,
//! so `ours / optimum ≥ 1` and the target is `≤ 1.10`.
//!
//! The optimum uses the same laws as the interpolator (programmed feed,
//! chord error, MRR, centripetal acceleration, per-axis velocity and
//! acceleration with the same tangential/curvature shares) at the machine's
//! real limits (no planning margin), with jerk switched off.
//!
//! [`jerk_aware_bound`] adds what the jerk limits make every schedule pay
//! (issue 15): the ramps at every rest and slow point, the jerk-down before
//! a local top speed, and the speed caps of the curvature steps at C1
//! joints. It is a lower bound of any jerk-limited schedule on the same
//! laws, so `ours / bound` is the part of our time the planner could win.

use std::cell::RefCell;

use interp_core::feed::{ArcLengthDerivs, junction_speed, speed_limit};
use interp_core::geom::{Curve, Derivs};
use interp_core::interp::OverrideError;
use interp_core::nurbs::Side;
use interp_core::path::{Blending, Block, Path};
use interp_core::plan::PlanTotals;
use interp_core::smooth::{Policy, SmoothError, SmoothStats, Smoother};
use interp_core::{InterpConfig, RunState, Vec3};
use interp_run::Run;
use interp_run::check::{Checker, Limits, Measured, Violations};
use nalgebra::Rotation3;

use crate::polyline::Polyline;

/// Grid spacing of the reference integration, mm.
pub const REFERENCE_STEP: f64 = 0.005;

/// The machine's real limits: `cfg` without its planning margin.
pub fn real_limits(cfg: &InterpConfig) -> InterpConfig {
    InterpConfig {
        planning_margin: 0.0,
        ..*cfg
    }
}

/// The pointwise laws of the references: the real limits with jerk
/// switched off.
pub fn reference_laws(cfg: &InterpConfig) -> InterpConfig {
    real_limits(&without_jerk(cfg))
}

/// The default machine with path jerk `jerk` and the axes' jerk twice that
/// (the defaults' ratio): a soft machine at 10⁴ mm/s³ (a heavy gantry), a
/// stiff one at 10⁷ (linear motors).
pub fn machine_with_jerk(jerk: f64) -> InterpConfig {
    InterpConfig {
        max_path_jerk: jerk,
        axis_max_jerk: [2.0 * jerk; 3],
        ..InterpConfig::default()
    }
}

/// The configuration with jerk limits switched off (acceleration only).
pub fn without_jerk(cfg: &InterpConfig) -> InterpConfig {
    InterpConfig {
        // Far above any jerk these programs need, yet small enough to keep
        // the look-ahead's linear program well scaled (1e18 made it crawl).
        max_path_jerk: 1e9,
        axis_max_jerk: [1e9; 3],
        ..*cfg
    }
}

/// Minimum path time (s) of `blocks` under the acceleration-only limits of
/// `cfg` (jerk ignored, no planning margin).
pub fn accel_only_optimum(blocks: &[Block], cfg: &InterpConfig) -> f64 {
    let laws = reference_laws(cfg);
    // (Δs from the previous point, speed limit) along the whole program.
    let mut grid: Vec<(f64, f64)> = vec![(0.0, 0.0)];
    for (i, b) in blocks.iter().enumerate() {
        let path = &b.path;
        if i > 0 {
            let prev = &blocks[i - 1].path;
            let v = junction_speed(
                &prev.eval(prev.u_end(), 3),
                &path.eval(path.u_start(), 3),
                &laws,
            );
            let v = if v < laws.junction_min_speed { 0.0 } else { v };
            let last = grid.last_mut().unwrap();
            last.1 = last.1.min(v);
        }
        walk_grid(path, &[], |ds, node| {
            if let GridNode::Node(d) = node {
                grid.push((ds, speed_limit(&d, b.feed, b.mrr.as_ref(), &laws)));
            }
        });
    }
    let last = grid.len() - 1;
    grid[last].1 = 0.0;
    let a = cfg.max_path_accel;
    let mut v: Vec<f64> = grid.iter().map(|g| g.1).collect();
    v[0] = 0.0;
    for i in 1..v.len() {
        v[i] = v[i].min((v[i - 1] * v[i - 1] + 2.0 * a * grid[i].0).sqrt());
    }
    for i in (0..v.len() - 1).rev() {
        v[i] = v[i].min((v[i + 1] * v[i + 1] + 2.0 * a * grid[i + 1].0).sqrt());
    }
    (1..v.len())
        .map(|i| {
            let s = v[i - 1] + v[i];
            if s > 0.0 { 2.0 * grid[i].0 / s } else { 0.0 }
        })
        .sum()
}

/// Path time (s) of `blocks` through the interpolator with `cfg`: ticks from
/// the first setpoint until the program is done.
pub fn interpolated_time(blocks: &[Block], cfg: &InterpConfig) -> Result<f64, String> {
    Ok(interpolated_run(blocks, cfg, false)?.time)
}

/// What a run through the interpolator gave: its path time, with `keep`
/// every setpoint's X Y Z, and every setpoint checked against every limit
/// of its configuration (finite differences, as a drive sees them).
#[derive(Debug, Clone)]
pub struct InterpolatedRun {
    /// Ticks from the first setpoint until done, s.
    pub time: f64,
    /// The start and every setpoint's X Y Z (empty without `keep`).
    pub points: Vec<Vec3>,
    /// The checks that failed (speed against the program's fastest feed).
    pub violations: Violations,
    /// The largest jerks and accelerations measured.
    pub measured: Measured,
    /// What the look-ahead's solves did (how many failed and fell back).
    pub plan: PlanTotals,
    /// The longest an operator's command took to plan (wall time, s): in
    /// the service, what must fit in the planning thread's lead.
    pub longest_command_s: f64,
    /// The longest from one setpoint to the next (wall time, s): the blocks
    /// pushed, the commands, every plan due, and the tick, as the service's
    /// planning thread does them between two ticks. It must fit in the lead.
    pub longest_step_s: f64,
}

impl InterpolatedRun {
    /// The largest path or axis jerk measured, as a share of its limit.
    pub fn jerk_use(&self, cfg: &InterpConfig) -> f64 {
        jerk_use(&self.measured, cfg)
    }
}

/// The largest path or axis jerk in `m`, as a share of its limit.
pub fn jerk_use(m: &Measured, cfg: &InterpConfig) -> f64 {
    (0..3)
        .map(|i| m.axis_jerk_mm_s3[i] / cfg.axis_max_jerk[i])
        .fold(m.path_jerk_mm_s3 / cfg.max_path_jerk, f64::max)
}

/// [`interpolated_time`] with the setpoints checked and, with `keep`, kept.
pub fn interpolated_run(
    blocks: &[Block],
    cfg: &InterpConfig,
    keep: bool,
) -> Result<InterpolatedRun, String> {
    interpolated_run_within(blocks, cfg, keep, MAX_TICKS)
}

/// [`interpolated_run`], abandoned as an error after `max_ticks` ticks (a
/// test that bounds the path time fails as soon as the bound is passed).
pub fn interpolated_run_within(
    blocks: &[Block],
    cfg: &InterpConfig,
    keep: bool,
    max_ticks: u64,
) -> Result<InterpolatedRun, String> {
    // An Interpolator<1024> is about 7.2 MB: build it on a thread with room for it.
    let (blocks, cfg) = (blocks.to_vec(), *cfg);
    std::thread::Builder::new()
        .stack_size(INTERPOLATOR_STACK)
        .spawn(move || run_to_done(&blocks, &cfg, keep, max_ticks, None))
        .map_err(|e| e.to_string())?
        .join()
        .map_err(|_| "interpolator thread panicked".to_string())?
}

/// The override values an operator's knob steps through, 30–200 % (the
/// `override_knob` example and the knob test).
pub const OVERRIDE_KNOB: [f64; 12] = [1.0, 0.6, 1.2, 0.8, 1.5, 0.3, 1.0, 0.9, 1.1, 0.5, 2.0, 0.7];

/// What an operator does during a run ([`interpolated_run_with_commands`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Command {
    /// Sets the feed override (1 = 100 %).
    Override(f64),
    /// Feed hold.
    Hold,
    /// Leaves a feed hold.
    Resume,
}

/// [`interpolated_run`] with the feed override set as an operator turns the
/// knob: to `value` before tick `at`, for each `(at, value)` (in order).
pub fn interpolated_run_with_overrides(
    blocks: &[Block],
    cfg: &InterpConfig,
    overrides: &[(u64, f64)],
) -> Result<InterpolatedRun, String> {
    let commands: Vec<(u64, Command)> = overrides
        .iter()
        .map(|&(at, v)| (at, Command::Override(v)))
        .collect();
    interpolated_run_with_commands(blocks, cfg, &commands)
}

/// One abort of [`abort_scan`]: the tick it was given before, what its
/// stop measured (the run up to it included), the checks that failed.
#[derive(Clone, Copy, Debug)]
pub struct AbortTried {
    /// Ticks done when the abort was given.
    pub at: u64,
    /// Ticks from the abort to idle.
    pub ticks: u64,
    /// The largest jerks and accelerations of the run to idle.
    pub measured: Measured,
    /// Its failed checks (not counting "not done": it was aborted).
    pub violations: Violations,
    /// What the look-ahead's solves did, the abort's included.
    pub plan: PlanTotals,
    /// The abort's planning (wall time, s).
    pub planning_s: f64,
}

/// The program run to its end, and an abort given to a copy of the run
/// before every tick `at` (ticks done) for which `abort_at(at)` (each
/// braked to idle on its own, every setpoint checked): an abort's stop at
/// every stage of the program ([`every`]), or around one place.
pub fn abort_scan(
    blocks: &[Block],
    cfg: &InterpConfig,
    abort_at: impl Fn(u64) -> bool + Send + 'static,
) -> Result<Vec<AbortTried>, String> {
    let (blocks, cfg) = (blocks.to_vec(), *cfg);
    // (A copy of the run takes another interpolator's stack.)
    std::thread::Builder::new()
        .stack_size(4 * INTERPOLATOR_STACK)
        .spawn(move || abort_scan_here(&blocks, &cfg, abort_at))
        .map_err(|e| e.to_string())?
        .join()
        .map_err(|_| "the scan panicked".to_string())?
}

/// Every `n`-th tick, for [`abort_scan`]: before ticks `n`, `2n`, …
pub fn every(n: u64) -> impl Fn(u64) -> bool + Send + 'static {
    move |at| at % n == n - 1
}

fn abort_scan_here(
    blocks: &[Block],
    cfg: &InterpConfig,
    abort_at: impl Fn(u64) -> bool,
) -> Result<Vec<AbortTried>, String> {
    let p = blocks[0].path.start_point();
    let mut run: Run<1024> = Run::new(*cfg, [p.x, p.y, p.z, 0.0, 0.0, 0.0])
        .map_err(|e| format!("{e:?}"))?
        .with_tick_limit(MAX_TICKS);
    let fastest = blocks.iter().map(|b| b.feed).fold(0.0, f64::max);
    // (The run's checker, copied for each abort.)
    let check = RefCell::new(Checker::new(
        cfg.period,
        Limits::new(cfg, fastest),
        [p.x, p.y, p.z],
    ));
    let mut tried = Vec::new();
    let end = run
        .run_program_with::<String>(
            blocks,
            |run| {
                if abort_at(run.ticks()) {
                    tried.push(abort_copy(run, check.borrow().clone())?);
                }
                Ok(())
            },
            |sp, _| {
                check.borrow_mut().check(sp);
                Ok(())
            },
        )
        .map_err(|(k, e)| match k {
            Some(k) => format!("block {k} of {}: {e}", blocks.len()),
            None => format!("after the last block: {e}"),
        })?;
    match end {
        RunState::Done => Ok(tried),
        other => Err(format!("the run ended {other:?}")),
    }
}

/// An abort given to a copy of `run`, braked to idle, every setpoint
/// checked by `check` (the run's checker so far).
fn abort_copy(run: &Run<1024>, mut check: Checker) -> Result<AbortTried, String> {
    let at = run.ticks();
    let mut a = run.clone();
    let t0 = std::time::Instant::now();
    a.abort();
    let planning_s = t0.elapsed().as_secs_f64();
    let mut last = a.tick();
    check.check(&last);
    while last.state != RunState::Idle {
        if a.ticks() > at + MAX_STOP_TICKS {
            return Err(format!("the abort before tick {at} never came to rest"));
        }
        last = a.tick();
        check.check(&last);
    }
    // Idle, it stays where it stopped.
    let after = a.tick();
    check.check(&after);
    if (after.feed, after.axes) != (0.0, last.axes) {
        return Err(format!("moved after the abort before tick {at}"));
    }
    // (And the planner made nothing the flushed executor refused.)
    let stale = |r: &Run<1024>| r.executor().stats().stale_plans;
    if stale(&a) != stale(run) {
        return Err(format!("a plan refused after the abort before tick {at}"));
    }
    Ok(AbortTried {
        at,
        ticks: a.ticks() - at,
        measured: check.measured,
        violations: Violations {
            not_done: 0,
            ..check.finish(None)
        },
        plan: a.driver_mut().window_mut().totals,
        planning_s,
    })
}

/// An abort's stop is abandoned after this many ticks.
const MAX_STOP_TICKS: u64 = 100_000;

/// [`interpolated_run`] with an operator's commands: each given before its
/// tick `at`, for each `(at, command)` (in order).
pub fn interpolated_run_with_commands(
    blocks: &[Block],
    cfg: &InterpConfig,
    commands: &[(u64, Command)],
) -> Result<InterpolatedRun, String> {
    let (blocks, cfg, commands) = (blocks.to_vec(), *cfg, commands.to_vec());
    std::thread::Builder::new()
        .stack_size(INTERPOLATOR_STACK)
        .spawn(move || run_to_done(&blocks, &cfg, false, MAX_TICKS, Some(&commands)))
        .map_err(|e| e.to_string())?
        .join()
        .map_err(|_| "interpolator thread panicked".to_string())?
}

/// The program's blocks through the `G64 P` stage (`Within` honoured), as
/// the drivers run them; also what the stage did.
pub fn smoothed(blocks: &[Block], cfg: &InterpConfig, policy: Policy) -> (Vec<Block>, SmoothStats) {
    let first = blocks.first().map_or(1, |b| b.id);
    let mut st: Box<Smoother> =
        Box::new(Smoother::with_policy(cfg, first, policy).expect("valid config"));
    let mut out = Vec::with_capacity(blocks.len());
    for b in blocks {
        while st.push(b) == Err(SmoothError::Full) {
            out.extend(st.pop());
        }
        out.extend(std::iter::from_fn(|| st.pop()));
    }
    st.finish();
    out.extend(std::iter::from_fn(|| st.pop()));
    (out, st.stats())
}

/// The programmed path of `blocks` as segments: lines as they are, arcs and
/// NURBS as chords no more than 1e-7 mm from them.
pub fn programmed_path(blocks: &[Block]) -> Polyline {
    let mut segs = Vec::new();
    for b in blocks {
        match &b.path {
            Path::Line(_) => segs.push((b.path.start_point(), b.path.end_point())),
            p => {
                let (ua, ub) = (p.u_start(), p.u_end());
                // 0.5 µm chords: sagitta below 1e-7 mm for radii above 0.3 mm.
                let n = ((p.length() / 5e-4).ceil() as usize).max(1);
                let mut prev = p.start_point();
                for k in 1..=n {
                    let q = p.eval(ua + (ub - ua) * k as f64 / n as f64, 0).p;
                    segs.push((prev, q));
                    prev = q;
                }
            }
        }
    }
    Polyline::from_segments(segs)
}

/// A program as given, through the `G64 P` stage and the interpolator.
#[derive(Debug, Clone, Copy)]
pub struct ProgramRun {
    /// Path times of the smoothed program (the optimum is that of the
    /// smoothed path: the path the machine runs).
    pub times: PathTimes,
    /// Program blocks in.
    pub blocks_in: usize,
    /// Interpolator blocks out of the stage.
    pub blocks_out: usize,
    /// What the stage did.
    pub stats: SmoothStats,
    /// Largest distance of a setpoint from the programmed path, mm.
    pub max_point_deviation: f64,
    /// Largest distance of a chord between consecutive setpoints, mm.
    pub max_chord_deviation: f64,
    /// The setpoints' checks that failed (none when every limit held).
    pub violations: Violations,
    /// The largest path or axis jerk of the setpoints, as a share of its limit.
    pub jerk_use: f64,
    /// What the look-ahead's solves did.
    pub plan: PlanTotals,
}

/// Runs `blocks` as a driver does (stage, then interpolator) and, with
/// `deviation`, measures the setpoints against the programmed path (NaN
/// without: on curves at high feed the reference search halves every chord
/// down to its resolution, minutes per program).
pub fn program_run(
    blocks: &[Block],
    cfg: &InterpConfig,
    policy: Policy,
    deviation: bool,
) -> Result<ProgramRun, String> {
    let (out, stats) = smoothed(blocks, cfg, policy);
    let run = interpolated_run(&out, cfg, deviation)?;
    let (max_point_deviation, max_chord_deviation) = if deviation {
        programmed_path(blocks).deviation(&run.points)
    } else {
        (f64::NAN, f64::NAN)
    };
    Ok(ProgramRun {
        times: PathTimes {
            ours: run.time,
            trapezoid: interpolated_time(&out, &without_jerk(cfg))?,
            optimum: accel_only_optimum(&out, cfg),
            bound: jerk_aware_bound(&out, cfg),
        },
        blocks_in: blocks.len(),
        blocks_out: out.len(),
        stats,
        max_point_deviation,
        max_chord_deviation,
        violations: run.violations,
        jerk_use: run.jerk_use(cfg),
        plan: run.plan,
    })
}

/// The blocks of a G-code file as the drivers take them, with `feed`
/// (mm/min) replacing every programmed feed (rapids stay at the machine's
/// top speed) and `g64` (mm) setting `G64 P` on every move.
pub fn load_program(
    path: &std::path::Path,
    feed: Option<f64>,
    g64: Option<f64>,
) -> Result<Vec<Block>, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let program = gcode::parse(&text).map_err(|e| format!("{}:{e}", path.display()))?;
    let opts = gcode::CoreOptions::default();
    let mut blocks = program
        .to_core_blocks(&opts)
        .map_err(|e| format!("{}: {e}", path.display()))?;
    if let Some(f) = feed {
        for b in &mut blocks {
            if b.feed < opts.rapid_speed {
                b.feed = f / 60.0;
            }
        }
    }
    if let Some(p) = g64 {
        for b in &mut blocks {
            b.blending = Blending::Within { tolerance: Some(p) };
        }
    }
    Ok(blocks)
}

/// [`load_program`] as the drivers run it: through the `G64 P` stage
/// ([`smoothed`], `Within` honoured).
pub fn load_as_run(
    path: &std::path::Path,
    feed: Option<f64>,
    g64: Option<f64>,
    cfg: &InterpConfig,
) -> Result<Vec<Block>, String> {
    load_turned_as_run(path, feed, g64, None, cfg)
}

/// [`load_as_run`] with the part turned on the table first ([`load_turned`]).
pub fn load_turned_as_run(
    path: &std::path::Path,
    feed: Option<f64>,
    g64: Option<f64>,
    rotation: Option<&Rotation3<f64>>,
    cfg: &InterpConfig,
) -> Result<Vec<Block>, String> {
    let blocks = load_turned(path, feed, g64, rotation)?;
    Ok(smoothed(&blocks, cfg, Policy::Auto).0)
}

/// [`load_program`], its part turned on the table by `rotation` if any
/// ([`turned`]).
pub fn load_turned(
    path: &std::path::Path,
    feed: Option<f64>,
    g64: Option<f64>,
    rotation: Option<&Rotation3<f64>>,
) -> Result<Vec<Block>, String> {
    let blocks = load_program(path, feed, g64)?;
    match rotation {
        Some(r) => turned(&blocks, r).map_err(|e| format!("{}: {e}", path.display())),
        None => Ok(blocks),
    }
}

/// `blocks` as the program of the same part turned on the table by
/// `rotation` (about the origin): each path turned, feeds and blending
/// kept. A five-axis block is refused, naming it (its tool axis would turn
/// too, through the machine's kinematics).
pub fn turned(blocks: &[Block], rotation: &Rotation3<f64>) -> Result<Vec<Block>, String> {
    blocks
        .iter()
        .map(|b| match b.orientation {
            None => Ok(Block {
                path: b.path.rotated(rotation),
                ..*b
            }),
            Some(_) => Err(format!(
                "block {}: a five-axis block is not turned with the part",
                b.id
            )),
        })
        .collect()
}

/// A program's first NURBS curve: its contiguous run of NURBS blocks (empty
/// without one).
pub fn first_curve(blocks: &[Block]) -> Vec<Block> {
    let is_curve = |b: &Block| matches!(b.path, Path::Nurbs(_));
    match blocks.iter().position(is_curve) {
        Some(i) => blocks[i..]
            .iter()
            .take_while(|b| is_curve(b))
            .copied()
            .collect(),
        None => Vec::new(),
    }
}

/// A run is abandoned after this many ticks (5.6 h at 1 kHz): a stall.
pub const MAX_TICKS: u64 = 20_000_000;

/// Stack for a thread that owns an `Interpolator<1024>`, bytes.
pub use interp_run::stack::INTERPOLATOR_STACK_BYTES as INTERPOLATOR_STACK;

fn run_to_done(
    blocks: &[Block],
    cfg: &InterpConfig,
    keep: bool,
    max_ticks: u64,
    commands: Option<&[(u64, Command)]>,
) -> Result<InterpolatedRun, String> {
    let p = blocks[0].path.start_point();
    let mut run: Run<1024> = Run::new(*cfg, [p.x, p.y, p.z, 0.0, 0.0, 0.0])
        .map_err(|e| format!("{e:?}"))?
        .with_tick_limit(max_ticks);
    let mut points = Vec::new();
    if keep {
        points.push(p);
    }
    // (The feed bound: the fastest feed at the largest override.)
    let top_override = commands
        .unwrap_or(&[])
        .iter()
        .fold(1.0, |m, &(_, c)| match c {
            Command::Override(v) => v.max(m),
            _ => m,
        });
    let fastest = blocks.iter().map(|b| b.feed).fold(0.0, f64::max) * top_override;
    let mut check = Checker::new(cfg.period, Limits::new(cfg, fastest), [p.x, p.y, p.z]);
    // Each command before its tick (in order).
    let mut next = 0;
    let mut longest_command_s: f64 = 0.0;
    let mut longest_step_s: f64 = 0.0;
    // (From the end of one setpoint's check: the check is not planning.)
    let mut checked = std::time::Instant::now();
    let commands = commands.unwrap_or(&[]);
    let end = run
        .run_program_with::<OverrideError>(
            blocks,
            |run| {
                while let Some(&(at, command)) = commands.get(next)
                    && at <= run.ticks()
                {
                    let t0 = std::time::Instant::now();
                    match command {
                        Command::Override(v) => run.set_feed_override(v)?,
                        Command::Hold => run.feed_hold(),
                        Command::Resume => run.resume(),
                    }
                    longest_command_s = longest_command_s.max(t0.elapsed().as_secs_f64());
                    next += 1;
                }
                Ok(())
            },
            |sp, _| {
                longest_step_s = longest_step_s.max(checked.elapsed().as_secs_f64());
                check.check(sp);
                if keep {
                    points.push(Vec3::new(sp.axes[0], sp.axes[1], sp.axes[2]));
                }
                checked = std::time::Instant::now();
                Ok(())
            },
        )
        .map_err(|(k, e)| match k {
            Some(k) => format!("block {k} of {}: {e}", blocks.len()),
            None => format!("after the last block: {e}"),
        })?;
    if end != RunState::Done {
        return Err(format!("the run ended {end:?}"));
    }
    let end = blocks[blocks.len() - 1].path.end_point();
    Ok(InterpolatedRun {
        time: run.ticks() as f64 * cfg.period,
        points,
        violations: check.finish(Some([end.x, end.y, end.z])),
        measured: check.measured,
        plan: run.driver_mut().window_mut().totals,
        longest_command_s,
        longest_step_s,
    })
}

/// Our time, the trapezoidal (jerk-free) schedule's time and the optimum, s.
#[derive(Debug, Clone, Copy)]
pub struct PathTimes {
    /// The interpolator with every limit (jerk filter on).
    pub ours: f64,
    /// The same interpolator with jerk switched off: the core issue's
    /// acceleration-limited (trapezoidal) schedule.
    pub trapezoid: f64,
    /// Acceleration-only optimum.
    pub optimum: f64,
    /// Lower bound of any jerk-limited schedule ([`jerk_aware_bound`]).
    pub bound: f64,
}

/// All four path times of a program.
pub fn path_times(blocks: &[Block], cfg: &InterpConfig) -> Result<PathTimes, String> {
    Ok(PathTimes {
        ours: interpolated_time(blocks, cfg)?,
        trapezoid: interpolated_time(blocks, &without_jerk(cfg))?,
        optimum: accel_only_optimum(blocks, cfg),
        bound: jerk_aware_bound(blocks, cfg),
    })
}

/// Shortest time of a rest-to-rest move of `d` mm along a line at speed,
/// acceleration and jerk limits `v`, `a`, `j` (the symmetric seven-phase
/// profile; `j = ∞` gives the trapezoid). Each half accelerates from rest to
/// the peak speed `w` in `w/a + a/j` (or `2·√(w/j)` below `a²/j`), covering
/// `w·t/2`.
pub fn rest_to_rest(d: f64, v: f64, a: f64, j: f64) -> f64 {
    let ramp = |w: f64| {
        if w * j >= a * a {
            w / a + a / j
        } else {
            2.0 * (w / j).sqrt()
        }
    };
    if v * ramp(v) <= d {
        return 2.0 * ramp(v) + (d - v * ramp(v)) / v;
    }
    // The peak speed where the two halves meet: bisection on w·ramp(w) = d.
    let (mut lo, mut hi) = (0.0, v);
    for _ in 0..100 {
        let w = 0.5 * (lo + hi);
        if w * ramp(w) < d {
            lo = w;
        } else {
            hi = w;
        }
    }
    2.0 * ramp(0.5 * (lo + hi))
}

/// Whether the program comes to rest after block `k` of `blocks`, as the
/// planner treats it: the last block, a `G61.1` block, or a junction slower
/// than a stop (`plan::stop_speed`, from the planner's own junction speed).
pub fn stops_after(blocks: &[Block], k: usize, cfg: &InterpConfig) -> bool {
    let Some(next) = blocks.get(k + 1) else {
        return true;
    };
    let (a, b) = (&blocks[k].path, &next.path);
    blocks[k].blending == Blending::ExactStop
        || junction_speed(&a.eval(a.u_end(), 3), &b.eval(b.u_start(), 3), cfg)
            < interp_core::plan::stop_speed(cfg)
}

/// An allowance for the jerk limits at the stops of a program of lines
/// (the random programs' reference, with [`accel_only_optimum`]): each
/// stretch between two stops ([`stops_after`], or every block with
/// `every_block`) run rest to rest at its top feed, jerk-limited against
/// acceleration-only, plus a tick at each stop (a stop lands on a
/// setpoint). Returns the allowance (s) and the number of stops. A yardstick,
/// not a lower bound: on a stretch whose laws hold the speed below its feed
/// the ramps cost less ([`jerk_aware_bound`] is the bound).
pub fn stop_allowance(blocks: &[Block], cfg: &InterpConfig, every_block: bool) -> (f64, usize) {
    let (a, j) = (cfg.max_path_accel, cfg.max_path_jerk);
    let mut allowance = 0.0;
    let (mut stretch, mut top, mut stops) = (0.0, 0.0f64, 0);
    for (k, b) in blocks.iter().enumerate() {
        stretch += b.path.length();
        top = top.max(b.feed.min(cfg.max_path_speed));
        if every_block || stops_after(blocks, k, cfg) {
            allowance += rest_to_rest(stretch, top, a, j)
                - rest_to_rest(stretch, top, a, f64::INFINITY)
                + cfg.period;
            stops += 1;
            (stretch, top) = (0.0, 0.0);
        }
    }
    (allowance, stops)
}

/// A lower bound (s) of the path time of any schedule of `blocks` that
/// holds the limits of `cfg` (no planning margin), tangential jerk and the
/// per-axis jerk of the setpoints included: the acceleration-only optimum's
/// grid and laws, tightened three ways, each a condition every feasible
/// schedule meets.
///
/// - **Rests and slow points.** With `|s⃛| ≤ J` and the acceleration zero
///   at rest, while `s̈ > 0` the quantity `v − s̈²/(2J)` never decreases
///   (its rate is `s̈·(1 − s⃛/J) ≥ 0`), so `s̈ ≤ √(2J·v)` everywhere, and
///   `−s̈ ≤ √(2J·v)` likewise towards the end. The forward and backward
///   passes integrate `dv/dt ≤ min(A, √(2Jv), …)` exactly: from a rest this
///   is the seven-phase profile's ramp.
/// - **Local top speeds.** Where `s̈ > 0` the speed still rises by `s̈²/(2J)`
///   before the acceleration can reach zero, within `s̈/J` s; so `v + s̈²/(2J)`
///   is at most `W`, the largest speed an earlier pass allows within the
///   distance `(s̈/J)·W` ahead (behind, for braking). Each pass is a bound
///   and tightens the last; they close in on a top speed below the feed
///   slowly, and stop after [`MAX_PASSES`]: on a line that cruises this is
///   the seven-phase time, on one too short to reach its feed within 0.4 %
///   below it.
/// - **Curvature steps.** At a C1 joint (block junctions and knots of
///   multiplicity `p − 1`) the axis acceleration steps by `v²·Δκᵢ`; one of
///   the third differences of the setpoints sees at least half of it,
///   `v²·|Δκᵢ|/(2·Ts)`, whatever the phase of the joint within a tick. The
///   smooth part of the axis jerk in that difference may cancel some of it,
///   at most `Jᵢ + |tᵢ|·J + 3·|κᵢ|·v·A + |C‴ᵢ|·v³` (the limit, the
///   tangential jerk and acceleration terms, the curvature's own), so the
///   joint is passed no faster than the largest `v` where the step fits in
///   that ([`step_cap`]; a tangent break likewise, on the second and third
///   differences).
///
/// The stops are those the program makes: a cusp inside a curve, where the
/// tangent reverses, and those of [`stops_after`] (a junction the planner
/// stops at, below `plan::stop_speed`, might be passed at a few mm/s: a
/// few ms per such stop are the planner's rule, not the limits'). The laws
/// are sampled on the optimum's grid as [`accel_only_optimum`] samples
/// them (the bound holds to that sampling), so the bound is at least the
/// optimum.
pub fn jerk_aware_bound(blocks: &[Block], cfg: &InterpConfig) -> f64 {
    jerk_aware_bound_with(blocks, cfg, BoundTerms::ALL)
}

/// Which of [`jerk_aware_bound`]'s tightenings to apply (the ramps at rests
/// and slow points always): to see what each costs.
#[derive(Debug, Clone, Copy)]
pub struct BoundTerms {
    /// The jerk-down before local top speeds (the passes after the first).
    pub tops: bool,
    /// The curvature steps' caps at C1 joints.
    pub steps: bool,
}

impl BoundTerms {
    /// All of them: [`jerk_aware_bound`].
    pub const ALL: BoundTerms = BoundTerms {
        tops: true,
        steps: true,
    };
}

/// [`jerk_aware_bound`] with only the tightenings of `terms`.
pub fn jerk_aware_bound_with(blocks: &[Block], cfg: &InterpConfig, terms: BoundTerms) -> f64 {
    let grid = bound_grid(blocks, cfg, terms.steps);
    let passes = if terms.tops { MAX_PASSES } else { 1 };
    envelope_time(&grid, cfg.max_path_accel, cfg.max_path_jerk, passes)
}

/// The optimum's grid (Δs, speed limit) with the nodes and caps of
/// [`jerk_aware_bound`]: curvature-step caps at C1 joints, rests at the
/// program's stops and cusps; and the limit inside each cell, where it is
/// known. A line's laws are the same all along: it is at most
/// [`LINE_CELLS`] cells with its limit inside (the flows are exact over any
/// length), not the optimum's million for a move of metres.
fn bound_grid(blocks: &[Block], cfg: &InterpConfig, steps: bool) -> Vec<(f64, f64, f64)> {
    let laws = reference_laws(cfg);
    let real = real_limits(cfg);
    let step_cap = |l: &Derivs, r: &Derivs| {
        if steps {
            step_cap(l, r, &real)
        } else {
            f64::INFINITY
        }
    };
    let mut grid: Vec<(f64, f64, f64)> = vec![(0.0, 0.0, f64::INFINITY)];
    for (i, b) in blocks.iter().enumerate() {
        let path = &b.path;
        if i > 0 {
            let prev = &blocks[i - 1].path;
            let (l, r) = (prev.eval(prev.u_end(), 3), path.eval(path.u_start(), 3));
            let v = if stops_after(blocks, i - 1, cfg) {
                0.0
            } else {
                // The optimum's junction, and the step's cap.
                let v = junction_speed(&l, &r, &laws);
                let v = if v < laws.junction_min_speed { 0.0 } else { v };
                v.min(step_cap(&l, &r))
            };
            let last = grid.last_mut().unwrap();
            last.1 = last.1.min(v);
        }
        let limit = |d: &Derivs| speed_limit(d, b.feed, b.mrr.as_ref(), &laws);
        if let Path::Line(_) = path {
            let v = limit(&path.eval(path.u_end(), 3));
            let len = path.length();
            let n = (len / REFERENCE_STEP).ceil().clamp(1.0, LINE_CELLS as f64) as usize;
            grid.extend(std::iter::repeat_n((len / n as f64, v, v), n));
            continue;
        }
        let marks = joint_marks(path, &real, limit, step_cap);
        walk_grid(path, &marks, |ds, node| {
            let cap = match node {
                GridNode::Joint(cap) => cap,
                GridNode::Node(d) => limit(&d),
            };
            grid.push((ds, cap, f64::INFINITY));
        });
    }
    let last = grid.len() - 1;
    grid[last].1 = 0.0;
    grid
}

/// A point of [`walk_grid`].
pub(crate) enum GridNode {
    /// A joint of [`joint_marks`], with its cap.
    Joint(f64),
    /// A grid node, with the path's derivatives there (order 3).
    Node(Derivs),
}

/// Walk `path` on the references' grid: [`REFERENCE_STEP`] apart, uniform
/// in `u` (the grid only needs to be fine, and `Δs` is exact), with the
/// joints `marks` (`(u, cap)`, in order) between the nodes they fall
/// between. `visit` gets each point's arc length from the previous one
/// (from the path's start for the first). Returns the path's length.
pub(crate) fn walk_grid(
    path: &Path,
    marks: &[(f64, f64)],
    mut visit: impl FnMut(f64, GridNode),
) -> f64 {
    let len = path.length();
    let n = (len / REFERENCE_STEP).ceil().max(1.0) as usize;
    let (ua, ub) = (path.u_start(), path.u_end());
    let mut u_prev = ua;
    let mut m = 0;
    for k in 1..=n {
        let u = ua + (ub - ua) * k as f64 / n as f64;
        while m < marks.len() && marks[m].0 < u {
            let (um, cap) = marks[m];
            visit(path.arc_length(u_prev, um), GridNode::Joint(cap));
            u_prev = um;
            m += 1;
        }
        visit(path.arc_length(u_prev, u), GridNode::Node(path.eval(u, 3)));
        u_prev = u;
    }
    len
}

/// The joints inside a path where [`jerk_aware_bound`] caps the speed, in
/// order: `(u, cap)`. Knots of a NURBS of continuity C1 or less (the laws
/// of both sides, the step's cap, a rest where the planner stops at a
/// tangent break) and its cusps (rests).
pub(crate) fn joint_marks(
    path: &Path,
    cfg: &InterpConfig,
    limit: impl Fn(&Derivs) -> f64,
    step_cap: impl Fn(&Derivs, &Derivs) -> f64,
) -> Vec<(f64, f64)> {
    let Path::Nurbs(n) = path else {
        return Vec::new();
    };
    let mut marks = Vec::new();
    let (ua, ub) = (n.u_start(), n.u_end());
    let stationary = |u: f64| n.is_stationary(u, Side::Before) || n.is_stationary(u, Side::After);
    let p = n.degree();
    let knots = n.knots();
    let mut i = p + 1;
    while i + p + 1 < knots.len() {
        let u = knots[i];
        let mut mult = 1;
        while i + mult < knots.len() && knots[i + mult] == u {
            mult += 1;
        }
        if u > ua && u < ub && mult + 1 >= p && !stationary(u) {
            let (l, r) = (
                n.eval_side(u, 3, Side::Before),
                n.eval_side(u, 3, Side::After),
            );
            let stop = l.d1.normalize().dot(&r.d1.normalize()) < 1.0 - 1e-12
                && junction_speed(&l, &r, cfg) < interp_core::plan::stop_speed(cfg);
            let cap = if stop {
                0.0
            } else {
                limit(&l).min(limit(&r)).min(step_cap(&l, &r))
            };
            marks.push((u, cap));
        }
        i += mult;
    }
    // A cusp (the tangent turns back) is a rest: the velocity is continuous.
    n.for_each_stationary(0.0, |u| {
        if n.tangent(u, Side::Before).dot(&n.tangent(u, Side::After)) < 0.0 {
            marks.push((u, 0.0));
        }
    });
    marks.sort_by(|a, b| a.0.total_cmp(&b.0));
    marks
}

/// The fastest a joint from `left` to `right` derivatives may be passed
/// by any schedule whose setpoints hold the axis limits of `cfg`, mm/s
/// (infinity where no step binds below the top speed; see
/// [`jerk_aware_bound`]). Each condition is `f(v) ≥ 0` with `f(0) > 0` and
/// at most two positive roots, so where it fails at the top speed, the cap
/// is its first root.
pub fn step_cap(left: &Derivs, right: &Derivs, cfg: &InterpConfig) -> f64 {
    let (Some(l), Some(r)) = (ArcLengthDerivs::new(left), ArcLengthDerivs::new(right)) else {
        // At a stationary point the curvature is unbounded: no cap.
        return f64::INFINITY;
    };
    let (ts, a, j) = (cfg.period, cfg.max_path_accel, cfg.max_path_jerk);
    let top = cfg.max_path_speed;
    let mut cap = f64::INFINITY;
    for i in 0..3 {
        let t = l.t[i].abs().max(r.t[i].abs());
        let k = l.c_ss[i].abs().max(r.c_ss[i].abs());
        let c = l.c_sss[i].abs().max(r.c_sss[i].abs());
        let dt = (r.t[i] - l.t[i]).abs();
        let dk = (r.c_ss[i] - l.c_ss[i]).abs();
        let (ai, ji) = (cfg.axis_max_accel[i], cfg.axis_max_jerk[i]);
        // The smooth jerk that may cancel part of a step in one difference.
        let smooth = |v: f64| ji + t * j + 3.0 * k * v * a + c * v * v * v;
        if dt > 0.0 {
            // A velocity step `v·Δtᵢ`: at least half of it in one second
            // difference (a step at a fraction φ of a tick splits φ, 1 − φ),
            // and in one third difference (φ, 1 − 2φ, φ − 1).
            cap = cap.min(first_root(
                |v| ai + t * a + k * v * v - v * dt / (2.0 * ts),
                top,
            ));
            cap = cap.min(first_root(
                |v| smooth(v) + 0.75 * dk * v * v / ts - v * dt / (2.0 * ts * ts),
                top,
            ));
        }
        if dk > 0.0 {
            // The curvature's step (its velocity step, if any, may cancel
            // up to `v·Δtᵢ/Ts²` of it).
            cap = cap.min(first_root(
                |v| smooth(v) + v * dt / (ts * ts) - v * v * dk / (2.0 * ts),
                top,
            ));
        }
    }
    cap
}

/// The root of `f` in `(0, top)` where `f(0) > 0 > f(top)`, else infinity.
fn first_root(f: impl Fn(f64) -> f64, top: f64) -> f64 {
    if f(top) >= 0.0 {
        return f64::INFINITY;
    }
    let (mut lo, mut hi) = (0.0, top);
    for _ in 0..100 {
        let m = 0.5 * (lo + hi);
        if f(m) >= 0.0 {
            lo = m;
        } else {
            hi = m;
        }
    }
    lo
}

/// A line is cut into at most this many cells of the bound's grid: the
/// passes close in on its top speed faster than on one cell.
const LINE_CELLS: usize = 64;

/// Whether a cell with limit `inner` inside is long enough that the speed
/// may rise well above both its ends (its time is then that of the flows
/// to their meeting; the grid's short cells take the faster estimates).
fn long_cell(inner: f64, d: f64) -> bool {
    inner.is_finite() && d > 4.0 * REFERENCE_STEP
}

/// At most this many passes of [`envelope_time`] (it settles in a few on
/// the corpus; a lone short line takes the most).
const MAX_PASSES: usize = 64;

/// The time of the speed envelope of `grid` (Δs, cap) under the tangential
/// limits `a`, `j`: see [`jerk_aware_bound`].
fn envelope_time(grid: &[(f64, f64, f64)], a: f64, j: f64, passes: usize) -> f64 {
    let n = grid.len();
    let ds: Vec<f64> = grid.iter().map(|g| g.0).collect();
    let mut s = vec![0.0; n];
    for i in 1..n {
        s[i] = s[i - 1] + ds[i];
    }
    let caps: Vec<f64> = grid.iter().map(|g| g.1).collect();
    let inner: Vec<f64> = grid.iter().map(|g| g.2).collect();
    let mut w_fwd = vec![f64::INFINITY; n];
    let mut w_bwd = vec![f64::INFINITY; n];
    let mut best = 0.0f64;
    let mut prev = f64::NAN;
    for _ in 0..passes {
        let v = sweep(&caps, &ds, &w_fwd, &w_bwd, a, j);
        let t = cells_time(&v, &caps, &ds, &inner, &w_fwd, &w_bwd, a, j);
        best = best.max(t);
        if (t - prev).abs() <= 1e-7 * t {
            break;
        }
        prev = t;
        (w_fwd, w_bwd) = tops(&v, &s, &inner, (&w_fwd, &w_bwd), a, j);
    }
    best
}

/// Forward then backward: each node's speed at most its cap and what the
/// flow allows from its neighbour.
fn sweep(caps: &[f64], ds: &[f64], w_fwd: &[f64], w_bwd: &[f64], a: f64, j: f64) -> Vec<f64> {
    let mut v = caps.to_vec();
    for i in 0..v.len() - 1 {
        v[i + 1] = v[i + 1].min(reach(v[i], v[i + 1], ds[i + 1], w_fwd[i], a, j));
    }
    for i in (0..v.len() - 1).rev() {
        v[i] = v[i].min(reach(v[i + 1], v[i], ds[i + 1], w_bwd[i + 1], a, j));
    }
    v
}

/// Each cell's time from its end speeds: the larger of the trapezoid (as
/// the optimum counts it) and the flow's time between them (exact where the
/// flow binds: near a rest the trapezoid undercounts the ramp).
#[allow(clippy::too_many_arguments)]
fn cells_time(
    v: &[f64],
    caps: &[f64],
    ds: &[f64],
    inner: &[f64],
    w_fwd: &[f64],
    w_bwd: &[f64],
    a: f64,
    j: f64,
) -> f64 {
    (1..v.len())
        .map(|i| {
            let (v0, v1, d) = (v[i - 1], v[i], ds[i]);
            if d == 0.0 {
                return 0.0;
            }
            if long_cell(inner[i], d) {
                // A long cell with its limit inside: the flows to their
                // meeting or to a cruise at the limit.
                return crossing(v0, v1, d, inner[i], w_fwd[i - 1], w_bwd[i], a, j).1;
            }
            if v0 == 0.0 || v1 == 0.0 {
                // From or to a rest: the flows' own time, to their meeting,
                // and the trapezoid where the moving end is held by its law
                // (the optimum's sampling). Below its law, that end's speed
                // is what a flow allows there (a rest nanometres away): the
                // speed may rise above it inside the cell, and the trapezoid
                // is no bound (a rest, a 1 nm move, then 4.2 µm to a rest:
                // 0.96 s for what takes 11 ms rest to rest).
                let t = crossing(v0, v1, d, f64::INFINITY, w_fwd[i - 1], w_bwd[i], a, j).1;
                let held = if v0 > 0.0 {
                    v0 >= caps[i - 1]
                } else {
                    v1 >= caps[i]
                };
                return if v0 + v1 > 0.0 && held {
                    t.max(2.0 * d / (v0 + v1))
                } else {
                    t
                };
            }
            let trapezoid = 2.0 * d / (v0 + v1);
            let flow = if v1 > v0 {
                let (x, t) = flow(v0, v1, w_fwd[i - 1], a, j);
                t + (d - x).max(0.0) / v1
            } else if v0 > v1 {
                let (x, t) = flow(v1, v0, w_bwd[i], a, j);
                t + (d - x).max(0.0) / v0
            } else {
                d / v0
            };
            trapezoid.max(flow)
        })
        .sum()
}

/// Where the forward flow from `v0` (top `wf`) meets the backward flow
/// from `v1` (top `wb`) over a cell of `d` mm with the limit `inner`
/// inside: the highest speed between them (s) and the time along the
/// lower of the two (s).
#[allow(clippy::too_many_arguments)]
fn crossing(v0: f64, v1: f64, d: f64, inner: f64, wf: f64, wb: f64, a: f64, j: f64) -> (f64, f64) {
    let lo = v0.max(v1);
    let hi = wf
        .min(wb)
        .min(inner)
        .min((0.5 * (v0 * v0 + v1 * v1) + a * d).sqrt())
        .max(lo);
    let both = |p: f64| {
        let (xf, tf) = flow(v0, p, wf, a, j);
        let (xb, tb) = flow(v1, p, wb, a, j);
        (xf + xb, tf + tb)
    };
    let (x, t) = both(hi);
    if x <= d {
        // The flows reach the top before they meet: a plateau.
        return (hi, if hi > 0.0 { t + (d - x) / hi } else { t });
    }
    let (mut lo, mut hi) = (lo, hi);
    for _ in 0..200 {
        let m = 0.5 * (lo + hi);
        if m <= lo || m >= hi {
            break;
        }
        if both(m).0 <= d {
            lo = m;
        } else {
            hi = m;
        }
    }
    (hi, both(hi).1)
}

/// The speed after `d` mm of the flow from `v0` (at most `cap`, which is
/// returned when the flow reaches it).
pub(crate) fn reach(v0: f64, cap: f64, d: f64, w: f64, a: f64, j: f64) -> f64 {
    if cap <= v0 {
        return cap;
    }
    // The flow's acceleration is at most `a`.
    let hi = cap.min(w).min((v0 * v0 + 2.0 * a * d).sqrt());
    if hi <= v0 {
        return v0;
    }
    if flow(v0, hi, w, a, j).0 <= d {
        return hi;
    }
    let (mut lo, mut hi) = (v0, hi);
    for _ in 0..200 {
        let m = 0.5 * (lo + hi);
        if m <= lo || m >= hi {
            break;
        }
        if flow(v0, m, w, a, j).0 <= d {
            lo = m;
        } else {
            hi = m;
        }
    }
    lo
}

/// Distance (mm) and time (s) of the flow `dv/dt = min(a, √(2jv), √(2j(w − v)))`
/// from `v0` to `v1` (`v0 ≤ v1 ≤ w`): the ramp from rest, the constant
/// acceleration, the ramp down to the top speed `w`.
fn flow(v0: f64, v1: f64, w: f64, a: f64, j: f64) -> (f64, f64) {
    let b = a * a / (2.0 * j);
    let (p1, p2) = if w.is_finite() {
        (b.min(0.5 * w), (w - b).max(0.5 * w))
    } else {
        (b, f64::INFINITY)
    };
    let (r2j, r2oj) = ((2.0 * j).sqrt(), (2.0 / j).sqrt());
    let (mut x, mut t) = (0.0, 0.0);
    // Ramp from rest: v = j·τ²/2.
    let (x0, x1) = (v0.min(p1), v1.min(p1));
    if x1 > x0 {
        x += 2.0 / 3.0 * (x1 * x1.sqrt() - x0 * x0.sqrt()) / r2j;
        t += r2oj * (x1.sqrt() - x0.sqrt());
    }
    // Constant acceleration.
    let (x0, x1) = (v0.clamp(p1, p2), v1.clamp(p1, p2));
    if x1 > x0 {
        x += (x1 * x1 - x0 * x0) / (2.0 * a);
        t += (x1 - x0) / a;
    }
    // Ramp down to `w`, in `q = w − v`.
    if w.is_finite() {
        let (x0, x1) = (v0.max(p2), v1.max(p2));
        if x1 > x0 {
            let (q0, q1) = ((w - x0).max(0.0), (w - x1).max(0.0));
            let (r0, r1) = (q0.sqrt(), q1.sqrt());
            x += (2.0 * w * (r0 - r1) - 2.0 / 3.0 * (q0 * r0 - q1 * r1)) / r2j;
            t += r2oj * (r0 - r1);
        }
    }
    (x, t)
}

/// The top speeds `W` of the next pass for each cell `(i, i + 1)`, indexed
/// forward by `i` (the cell and the distance after it within which the
/// acceleration can reach zero) and backward by `i + 1` (the cell and
/// behind), from the node speeds `v` of the last pass and its tops. Between
/// two nodes the speed may rise above both: as `dv/ds = g(v)/v` of the flow
/// falls with `v` in each of its three parts, the flows from the two ends
/// lie below their tangent lines, and the speed below where those meet (and
/// below `√((v_i² + v_{i+1}²)/2 + a·Δs)`, where parabolas of acceleration `a`
/// meet).
fn tops(
    v: &[f64],
    s: &[f64],
    inner: &[f64],
    tops: (&[f64], &[f64]),
    a: f64,
    j: f64,
) -> (Vec<f64>, Vec<f64>) {
    let n = v.len();
    let mut w_fwd = vec![f64::INFINITY; n];
    let mut w_bwd = vec![f64::INFINITY; n];
    if n < 2 {
        return (w_fwd, w_bwd);
    }
    let peak: Vec<f64> = (0..n - 1)
        .map(|c| {
            let (v0, v1, d) = (v[c], v[c + 1], s[c + 1] - s[c]);
            let parabolas = (0.5 * (v0 * v0 + v1 * v1) + a * d).sqrt();
            // Slopes of the two flows at the ends, dv/ds.
            let slope = |v: f64, w: f64| {
                let g = a
                    .min((2.0 * j * v).sqrt())
                    .min((2.0 * j * (w - v).max(0.0)).sqrt());
                g / v
            };
            let (k0, k1) = (slope(v0, tops.0[c]), slope(v1, tops.1[c + 1]));
            let (wf, wb) = (tops.0[c], tops.1[c + 1]);
            if long_cell(inner[c + 1], d) {
                return crossing(v0, v1, d, inner[c + 1], wf, wb, a, j).0;
            }
            let lines = if k0.is_finite() && k1.is_finite() {
                let x = ((v1 - v0 + k1 * d) / (k0 + k1)).clamp(0.0, d);
                (v0 + k0 * x).max(v1 + k1 * (d - x))
            } else {
                // From a rest the slope is infinite: the flows' meeting.
                crossing(v0, v1, d, f64::INFINITY, wf, wb, a, j).0
            };
            parabolas.min(lines).min(inner[c + 1]).max(v0).max(v1)
        })
        .collect();
    let table = RangeMax::new(&peak);
    let last = n - 2;
    for i in 0..n - 1 {
        // The acceleration reaches zero within `τ` s at most.
        let tau = a.min((2.0 * j * peak[i]).sqrt()) / j;
        // Forward: cells i..=hi, those within `τ·W` after the cell.
        let mut hi = i;
        loop {
            let m = table.max(i, hi);
            let end = s[i + 1] + tau * m;
            let next = (s.partition_point(|&x| x < end).max(1) - 1).clamp(i, last);
            if next <= hi {
                w_fwd[i] = m;
                break;
            }
            hi = next;
        }
        // Backward: cells lo..=i, those within `τ·W` before the cell.
        let mut lo = i;
        loop {
            let m = table.max(lo, i);
            let start = s[i] - tau * m;
            let next = (s.partition_point(|&x| x <= start).max(1) - 1).min(i);
            if next >= lo {
                w_bwd[i + 1] = m;
                break;
            }
            lo = next;
        }
    }
    (w_fwd, w_bwd)
}

/// Maxima of index ranges of a slice (a segment tree: two words a value,
/// as the grid of a move of metres has millions of nodes).
struct RangeMax {
    n: usize,
    tree: Vec<f64>,
}

impl RangeMax {
    fn new(v: &[f64]) -> Self {
        let n = v.len();
        let mut tree = vec![f64::NEG_INFINITY; 2 * n];
        tree[n..].copy_from_slice(v);
        for i in (1..n).rev() {
            tree[i] = tree[2 * i].max(tree[2 * i + 1]);
        }
        RangeMax { n, tree }
    }

    /// The largest of `v[lo..=hi]`.
    fn max(&self, lo: usize, hi: usize) -> f64 {
        let (mut l, mut r) = (lo + self.n, hi + self.n + 1);
        let mut m = f64::NEG_INFINITY;
        while l < r {
            if l & 1 == 1 {
                m = m.max(self.tree[l]);
                l += 1;
            }
            if r & 1 == 1 {
                r -= 1;
                m = m.max(self.tree[r]);
            }
            l /= 2;
            r /= 2;
        }
        m
    }
}
