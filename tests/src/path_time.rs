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

use core::convert::Infallible;

use interp_core::feed::{junction_speed, speed_limit};
use interp_core::geom::Curve;
use interp_core::path::{Block, Path};
use interp_core::smooth::{Policy, SmoothError, SmoothStats, Smoother};
use interp_core::{InterpConfig, RunState, Vec3};
use interp_run::Run;

use crate::polyline::Polyline;

/// Grid spacing of the reference integration, mm.
pub const REFERENCE_STEP: f64 = 0.005;

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
    let laws = InterpConfig {
        planning_margin: 0.0,
        ..without_jerk(cfg)
    };
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
        let len = path.length();
        let n = (len / REFERENCE_STEP).ceil().max(1.0) as usize;
        let (ua, ub) = (path.u_start(), path.u_end());
        let mut u_prev = ua;
        for k in 1..=n {
            // Uniform in u is fine: the grid only needs to be fine, and Δs is exact.
            let u = ua + (ub - ua) * k as f64 / n as f64;
            let ds = path.arc_length(u_prev, u);
            let v = speed_limit(&path.eval(u, 3), b.feed, b.mrr.as_ref(), &laws);
            grid.push((ds, v));
            u_prev = u;
        }
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
    Ok(interpolated_run(blocks, cfg, false)?.0)
}

/// [`interpolated_time`] and, with `keep`, every setpoint's X Y Z.
pub fn interpolated_run(
    blocks: &[Block],
    cfg: &InterpConfig,
    keep: bool,
) -> Result<(f64, Vec<Vec3>), String> {
    interpolated_run_within(blocks, cfg, keep, MAX_TICKS)
}

/// [`interpolated_run`], abandoned as an error after `max_ticks` ticks (a
/// test that bounds the path time fails as soon as the bound is passed).
pub fn interpolated_run_within(
    blocks: &[Block],
    cfg: &InterpConfig,
    keep: bool,
    max_ticks: u64,
) -> Result<(f64, Vec<Vec3>), String> {
    // An Interpolator<1024> is about 1.6 MB: build it on a thread with room for it.
    let (blocks, cfg) = (blocks.to_vec(), *cfg);
    std::thread::Builder::new()
        .stack_size(INTERPOLATOR_STACK)
        .spawn(move || run_to_done(&blocks, &cfg, keep, max_ticks))
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
    let (ours, pts) = interpolated_run(&out, cfg, deviation)?;
    let (max_point_deviation, max_chord_deviation) = if deviation {
        programmed_path(blocks).deviation(&pts)
    } else {
        (f64::NAN, f64::NAN)
    };
    Ok(ProgramRun {
        times: PathTimes {
            ours,
            trapezoid: interpolated_time(&out, &without_jerk(cfg))?,
            optimum: accel_only_optimum(&out, cfg),
        },
        blocks_in: blocks.len(),
        blocks_out: out.len(),
        stats,
        max_point_deviation,
        max_chord_deviation,
    })
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
) -> Result<(f64, Vec<Vec3>), String> {
    let p = blocks[0].path.start_point();
    let mut run: Run<1024> = Run::new(*cfg, [p.x, p.y, p.z, 0.0, 0.0, 0.0])
        .map_err(|e| format!("{e:?}"))?
        .with_tick_limit(max_ticks);
    let mut pts = Vec::new();
    if keep {
        pts.push(p);
    }
    let end = run
        .run_program::<Infallible>(blocks, |sp, _| {
            if keep {
                pts.push(Vec3::new(sp.axes[0], sp.axes[1], sp.axes[2]));
            }
            Ok(())
        })
        .map_err(|(k, e)| match k {
            Some(k) => format!("block {k} of {}: {e}", blocks.len()),
            None => format!("after the last block: {e}"),
        })?;
    if end != RunState::Done {
        return Err(format!("the run ended {end:?}"));
    }
    Ok((run.ticks() as f64 * cfg.period, pts))
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
}

/// All three path times of a program.
pub fn path_times(blocks: &[Block], cfg: &InterpConfig) -> Result<PathTimes, String> {
    Ok(PathTimes {
        ours: interpolated_time(blocks, cfg)?,
        trapezoid: interpolated_time(blocks, &without_jerk(cfg))?,
        optimum: accel_only_optimum(blocks, cfg),
    })
}
