//! The plots `interpd demo` writes: the path, and feed, acceleration, jerk and
//! chord error against time, each with the limit it must stay under.
//!
//! Everything is derived from the setpoints as a drive sees them (finite
//! differences, the same ones the demo's checks use) and from the exact
//! blocks (the feed-law limit at each setpoint, the chord error per tick
//! through `traces::analysis::Analyzer`, as `interpd trace plot` computes it).
//! Drawing is the `traces` crate's ([`traces::plot::plot_charts`]).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use interp_core::feed::speed_limit;
use interp_core::{Block, Curve, InterpConfig, Setpoint};
use traces::analysis::Analyzer;
use traces::messages::{ConfigMsg, FORMAT_VERSION};
use traces::plot::{Chart, ChartLine, plot_charts};

/// Derivative order the feed laws need at a point (curvature and its rate).
const LAW_DERIVS: usize = 3;

/// What the plots are made of.
#[derive(Debug)]
pub struct PlotInput<'a> {
    /// The run's configuration.
    pub cfg: &'a InterpConfig,
    /// The interpolator blocks (unique ids).
    pub blocks: &'a [Block],
    /// Machine position before the first setpoint.
    pub start: [f64; 3],
    /// Every setpoint of the run, in order from `seq` 1.
    pub setpoints: &'a [Setpoint],
}

/// Time series derived from the setpoints, one value per setpoint.
#[derive(Debug, Default)]
pub(crate) struct Series {
    pub(crate) time: Vec<f64>,
    /// Commanded feed, mm/min.
    pub(crate) feed: Vec<f64>,
    /// The pointwise feed-law limit at the setpoint (programmed feed, chord-error
    /// law, centripetal and axis limits), mm/min; NaN off every block.
    pub(crate) feed_limit: Vec<f64>,
    /// Δfeed/Ts, mm/s².
    pub(crate) accel: Vec<f64>,
    /// Δ³s/Ts³, mm/s³.
    pub(crate) jerk: Vec<f64>,
    /// Chord error of the tick that ends here, µm.
    pub(crate) chord_error_um: Vec<f64>,
}

fn series_of(inp: &PlotInput<'_>) -> Series {
    let cfg = inp.cfg;
    let ts = cfg.period;
    let by_id: BTreeMap<u32, &Block> = inp.blocks.iter().map(|b| (b.id, b)).collect();
    let config = ConfigMsg {
        format_version: FORMAT_VERSION,
        writer: "interpd demo".into(),
        source: "butterfly".into(),
        realtime: false,
        interp: *cfg,
        start: [inp.start[0], inp.start[1], inp.start[2], 0.0, 0.0, 0.0],
        max_ctrl_per_block: crate::protocol::PIECE_CTRL,
        segment_queue: 0,
    };
    let mut an = Analyzer::new(&config, inp.blocks.len(), inp.blocks.iter());
    let mut out = Series::default();
    // At rest before the first setpoint.
    let (mut f1, mut s1, mut s2, mut s3) = (0.0, 0.0, 0.0, 0.0);
    for sp in inp.setpoints {
        out.time.push(sp.time);
        out.feed.push(sp.feed * 60.0);
        let limit = by_id.get(&sp.block_id).map_or(f64::NAN, |b| {
            let d = b.path.eval(sp.u, LAW_DERIVS);
            speed_limit(&d, b.feed, b.mrr.as_ref(), cfg)
        });
        out.feed_limit.push(limit * 60.0);
        out.accel.push((sp.feed - f1) / ts);
        out.jerk
            .push(((sp.s - 3.0 * s1) + (3.0 * s2 - s3)) / (ts * ts * ts));
        out.chord_error_um.push(an.push(sp).chord_error * 1e3);
        (f1, s1, s2, s3) = (sp.feed, sp.s, s1, s2);
    }
    out
}

fn zip(x: &[f64], y: &[f64]) -> Vec<(f64, f64)> {
    x.iter().copied().zip(y.iter().copied()).collect()
}

/// A horizontal line at `y` across the run.
fn level(time: &[f64], y: f64) -> Vec<(f64, f64)> {
    match (time.first(), time.last()) {
        (Some(&a), Some(&b)) => vec![(a, y), (b, y)],
        _ => Vec::new(),
    }
}

/// Writes the demo's plots into `out_dir` (PNG) and returns the files.
pub fn write(inp: &PlotInput<'_>, out_dir: &Path) -> Result<Vec<PathBuf>> {
    let cfg = inp.cfg;
    let s = series_of(inp);
    let t = &s.time;
    let xy: Vec<(f64, f64)> = std::iter::once((inp.start[0], inp.start[1]))
        .chain(inp.setpoints.iter().map(|sp| (sp.axes[0], sp.axes[1])))
        .collect();
    let charts = [
        Chart {
            file: "path_xy",
            title: "Tool path, XY (the setpoints)".into(),
            x_label: "X [mm]",
            y_label: "Y [mm]",
            equal_axes: true,
            lines: vec![ChartLine::data("path", xy)],
        },
        Chart {
            file: "feed",
            title: "Feed and the feed-law limit at each setpoint".into(),
            x_label: "time [s]",
            y_label: "feed [mm/min]",
            equal_axes: false,
            lines: vec![
                ChartLine::data("feed", zip(t, &s.feed)),
                ChartLine::limit(
                    "limit: min(F, chord-error law, centripetal, axes)",
                    zip(t, &s.feed_limit),
                ),
            ],
        },
        Chart {
            file: "acceleration",
            title: format!(
                "Tangential acceleration Δfeed/Ts (limit ±{} mm/s²)",
                cfg.max_path_accel
            ),
            x_label: "time [s]",
            y_label: "acceleration [mm/s²]",
            equal_axes: false,
            lines: vec![
                ChartLine::data("tangential", zip(t, &s.accel)),
                ChartLine::limit("+limit", level(t, cfg.max_path_accel)),
                ChartLine::limit("−limit", level(t, -cfg.max_path_accel)),
            ],
        },
        Chart {
            file: "jerk",
            title: format!("Path jerk Δ³s/Ts³ (limit ±{} mm/s³)", cfg.max_path_jerk),
            x_label: "time [s]",
            y_label: "jerk [mm/s³]",
            equal_axes: false,
            lines: vec![
                ChartLine::data("jerk", zip(t, &s.jerk)),
                ChartLine::limit("+limit", level(t, cfg.max_path_jerk)),
                ChartLine::limit("−limit", level(t, -cfg.max_path_jerk)),
            ],
        },
        Chart {
            file: "chord_error",
            title: format!(
                "Chord error per tick (tolerance {} µm)",
                cfg.chord_tolerance * 1e3
            ),
            x_label: "time [s]",
            y_label: "chord error [µm]",
            equal_axes: false,
            lines: vec![
                ChartLine::data("chord error", zip(t, &s.chord_error_um)),
                ChartLine::limit("tolerance", level(t, cfg.chord_tolerance * 1e3)),
            ],
        },
    ];
    let report = plot_charts(&charts, out_dir, false)
        .with_context(|| format!("writing the demo's plots into {}", out_dir.display()))?;
    Ok(report.files)
}

#[cfg(test)]
mod tests {
    use super::*;
    use interp_core::{Line, Path, RunState, Vec3};
    use interp_run::Run;

    /// A straight line from rest to rest: its feed limit is the programmed feed,
    /// its chord error 0, and the series match the setpoints' own differences.
    #[test]
    fn series_of_a_line_follow_the_setpoints() {
        let cfg = InterpConfig::default();
        let line = Line::new(Vec3::new(0.0, 0.0, 0.0), Vec3::new(20.0, 0.0, 0.0)).expect("a line");
        let block = Block::new(1, Path::Line(line), 50.0);
        let blocks = [block];
        let mut run: Run = Run::new(cfg, [0.0; 6])
            .expect("default config")
            .with_tick_limit(100_000);
        let mut sps = Vec::new();
        let end = run.run_program::<core::convert::Infallible>(&blocks, |sp, _| {
            sps.push(*sp);
            Ok(())
        });
        assert_eq!(end.expect("the line runs"), RunState::Done);
        let inp = PlotInput {
            cfg: &cfg,
            blocks: &blocks,
            start: [0.0; 3],
            setpoints: &sps,
        };
        let s = series_of(&inp);
        assert_eq!(s.time.len(), sps.len());
        assert!(
            s.feed_limit.iter().all(|&l| l == 50.0 * 60.0),
            "{:?}",
            &s.feed_limit[..4]
        );
        assert!(s.chord_error_um.iter().all(|&e| e.abs() < 1e-9));
        let peak = s.feed.iter().fold(0.0f64, |m, &f| m.max(f));
        assert!((peak - 3000.0).abs() < 1e-6, "{peak}");
        let amax = s.accel.iter().fold(0.0f64, |m, a| m.max(a.abs()));
        let jmax = s.jerk.iter().fold(0.0f64, |m, j| m.max(j.abs()));
        assert!(amax > 0.5 * cfg.max_path_accel && amax <= cfg.max_path_accel * (1.0 + 1e-6));
        assert!(
            jmax > 0.0 && jmax <= cfg.max_path_jerk * (1.0 + 1e-6),
            "{jmax}"
        );
        // The jerk from the arc length agrees with the one from the feed.
        let jfeed = s
            .accel
            .windows(2)
            .fold(s.accel[0].abs(), |m, w| m.max((w[1] - w[0]).abs()))
            / cfg.period;
        assert!((jmax / jfeed - 1.0).abs() < 1e-6, "{jmax} {jfeed}");
        let dir = std::env::temp_dir().join(format!("interpd-demo-plots-{}", std::process::id()));
        let files = write(&inp, &dir).expect("plots written");
        assert_eq!(files.len(), 5);
        assert!(files.iter().all(|f| f.exists()));
        let _ = std::fs::remove_dir_all(&dir);
    }
}

#[cfg(test)]
mod butterfly_tests {
    use super::*;
    use crate::tools::demo;

    /// The plotted series are the ones the demo's checks measured.
    #[test]
    fn plotted_maxima_are_the_checked_ones() {
        let args = demo::tests_support::fast_args();
        let mut sps = Vec::new();
        let summary = demo::run(&args, |sp| sps.push(*sp)).expect("demo runs");
        let cfg = demo::tests_support::config(&args);
        let blocks = demo::tests_support::blocks(&args);
        let inp = PlotInput {
            cfg: &cfg,
            blocks: &blocks,
            start: summary.program.start,
            setpoints: &sps,
        };
        let s = series_of(&inp);
        let max_abs = |v: &[f64]| v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        assert_eq!(max_abs(&s.jerk), summary.measured.path_jerk_mm_s3);
        assert_eq!(max_abs(&s.accel), summary.max_accel_mm_s2);
        let ce = s.chord_error_um.iter().fold(0.0f64, |m, &x| m.max(x));
        assert!(
            (ce * 1e-3 / summary.max_chord_error_mm - 1.0).abs() < 1e-9,
            "{ce} µm vs {} mm",
            summary.max_chord_error_mm
        );
        let peak = s.feed.iter().fold(0.0f64, |m, &x| m.max(x));
        assert_eq!(peak, summary.max_feed_mm_s * 60.0);
        // The feed stays under the pointwise law (the plan uses 98 % of it).
        let over = s
            .feed
            .iter()
            .zip(&s.feed_limit)
            .filter(|(f, l)| f > l)
            .count();
        assert_eq!(over, 0);
    }
}
