//! PNG and SVG plots of a run: the seed paper's Figs. 6–12 for any trace.
//!
//! Text is drawn with DejaVu Sans compiled into the binary (the `dejavu`
//! crate, through plotters' `ab_glyph` backend), so no system font and no
//! network are needed at run time.

use std::path::{Path, PathBuf};
use std::sync::Once;

use plotters::coord::Shift;
use plotters::prelude::*;

use crate::analysis::{Sample, Summary};
use crate::reader::Trace;

/// Pixel size of every PNG (and the SVG canvas).
pub const PLOT_SIZE: (u32, u32) = (1000, 600);

/// Series longer than this are thinned to this many buckets, keeping each
/// bucket's minimum and maximum (so peaks stay visible).
pub const MAX_POINTS_PER_SERIES: usize = 4000;

/// Bins of the wake-lateness histogram.
pub const LATENESS_BINS: usize = 60;

const FONT: &str = "sans-serif";

/// Why plotting failed.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// The output directory could not be made.
    #[error("creating {path}: {source}")]
    Dir {
        /// The directory.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// Drawing or writing a file failed.
    #[error("drawing {path}: {reason}")]
    Draw {
        /// The file.
        path: String,
        /// Why.
        reason: String,
    },
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Kind {
    Lines,
    /// Equal scales on both axes (paths).
    Path,
    /// Bars of width `.0` centred on each x.
    Bars(f64),
}

#[derive(Clone, Debug)]
struct Series {
    name: String,
    color: RGBColor,
    points: Vec<(f64, f64)>,
}

#[derive(Clone, Debug)]
struct Figure {
    file: &'static str,
    title: String,
    x_label: &'static str,
    y_label: &'static str,
    kind: Kind,
    series: Vec<Series>,
}

fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        // The bundled font is a valid TrueType file; should it not load,
        // text is skipped by plotters rather than failing the plots.
        let _ = plotters::style::register_font(
            FONT,
            plotters::style::FontStyle::Normal,
            dejavu::sans::regular(),
        );
    });
}

/// Keeps at most `MAX_POINTS_PER_SERIES` buckets' min and max (in x order).
fn thin(points: Vec<(f64, f64)>) -> Vec<(f64, f64)> {
    let n = points.len();
    if n <= 2 * MAX_POINTS_PER_SERIES {
        return points;
    }
    let per = n.div_ceil(MAX_POINTS_PER_SERIES);
    let mut out = Vec::with_capacity(2 * MAX_POINTS_PER_SERIES + 1);
    for chunk in points.chunks(per) {
        let (mut lo, mut hi) = (0, 0);
        for (i, p) in chunk.iter().enumerate() {
            if p.1 < chunk[lo].1 {
                lo = i;
            }
            if p.1 > chunk[hi].1 {
                hi = i;
            }
        }
        let (a, b) = if lo <= hi { (lo, hi) } else { (hi, lo) };
        out.push(chunk[a]);
        if b != a {
            out.push(chunk[b]);
        }
    }
    out
}

/// Every `k`-th point (paths are smooth; min/max thinning would zig-zag).
fn stride(points: Vec<(f64, f64)>) -> Vec<(f64, f64)> {
    let n = points.len();
    if n <= 2 * MAX_POINTS_PER_SERIES {
        return points;
    }
    let k = n.div_ceil(2 * MAX_POINTS_PER_SERIES);
    let last = points[n - 1];
    let mut out: Vec<_> = points.into_iter().step_by(k).collect();
    out.push(last);
    out
}

fn bounds(fig: &Figure) -> Option<(f64, f64, f64, f64)> {
    let mut b: Option<(f64, f64, f64, f64)> = None;
    for (x, y) in fig.series.iter().flat_map(|s| s.points.iter().copied()) {
        if !(x.is_finite() && y.is_finite()) {
            continue;
        }
        b = Some(match b {
            None => (x, x, y, y),
            Some((x0, x1, y0, y1)) => (x0.min(x), x1.max(x), y0.min(y), y1.max(y)),
        });
    }
    let (mut x0, mut x1, mut y0, mut y1) = b?;
    if let Kind::Bars(w) = fig.kind {
        x0 -= w / 2.0;
        x1 += w / 2.0;
        y0 = y0.min(0.0);
    }
    let pad = |lo: f64, hi: f64| {
        let d = if hi > lo {
            0.04 * (hi - lo)
        } else {
            0.5 * lo.abs().max(1e-9)
        };
        (lo - d, hi + d)
    };
    (x0, x1) = pad(x0, x1);
    (y0, y1) = pad(y0, y1);
    if fig.kind == Kind::Path {
        // Equal scales: widen the narrower range to the plot area's aspect.
        let (w, h) = (f64::from(PLOT_SIZE.0 - 120), f64::from(PLOT_SIZE.1 - 110));
        let scale = ((x1 - x0) / w).max((y1 - y0) / h);
        let (cx, cy) = ((x0 + x1) / 2.0, (y0 + y1) / 2.0);
        (x0, x1) = (cx - scale * w / 2.0, cx + scale * w / 2.0);
        (y0, y1) = (cy - scale * h / 2.0, cy + scale * h / 2.0);
    }
    Some((x0, x1, y0, y1))
}

fn draw<DB: DrawingBackend>(root: DrawingArea<DB, Shift>, fig: &Figure) -> Result<(), String> {
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    root.fill(&WHITE).map_err(e)?;
    let Some((x0, x1, y0, y1)) = bounds(fig) else {
        root.draw(&Text::new(
            format!("{}: no data", fig.title),
            (40, 40),
            (FONT, 22).into_font(),
        ))
        .map_err(e)?;
        return root.present().map_err(e);
    };
    let mut chart = ChartBuilder::on(&root)
        .caption(&fig.title, (FONT, 24))
        .margin(16)
        .x_label_area_size(50)
        .y_label_area_size(90)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(e)?;
    chart
        .configure_mesh()
        .x_desc(fig.x_label)
        .y_desc(fig.y_label)
        .label_style((FONT, 15))
        .axis_desc_style((FONT, 17))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()
        .map_err(e)?;
    for s in &fig.series {
        let color = s.color;
        let anno = match fig.kind {
            Kind::Bars(w) => chart
                .draw_series(s.points.iter().map(|&(x, y)| {
                    Rectangle::new([(x - w / 2.0, 0.0), (x + w / 2.0, y)], color.filled())
                }))
                .map_err(e)?,
            Kind::Lines | Kind::Path => chart
                .draw_series(LineSeries::new(
                    s.points
                        .iter()
                        .copied()
                        .filter(|p| p.0.is_finite() && p.1.is_finite()),
                    // Wide polylines get miter spikes at the sharp turns of
                    // noisy time series (beyond the data); paths are smooth.
                    color.stroke_width(if fig.kind == Kind::Path { 2 } else { 1 }),
                ))
                .map_err(e)?,
        };
        anno.label(s.name.as_str()).legend(move |(x, y)| {
            PathElement::new(vec![(x, y), (x + 24, y)], color.stroke_width(3))
        });
    }
    if fig.series.len() > 1 {
        chart
            .configure_series_labels()
            .label_font((FONT, 15))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .position(SeriesLabelPosition::UpperRight)
            .draw()
            .map_err(e)?;
    }
    root.present().map_err(e)
}

const BLUE_: RGBColor = RGBColor(31, 119, 180);
const ORANGE_: RGBColor = RGBColor(255, 127, 14);
const RED_: RGBColor = RGBColor(214, 39, 40);
const GREEN_: RGBColor = RGBColor(44, 160, 44);

fn series(name: &str, color: RGBColor, points: Vec<(f64, f64)>) -> Series {
    Series {
        name: name.to_owned(),
        color,
        points,
    }
}

fn figures(trace: &Trace, samples: &[Sample], summary: &Summary) -> (Vec<Figure>, Vec<String>) {
    let mut notes = Vec::new();
    let t = |f: &dyn Fn(&Sample) -> f64| -> Vec<(f64, f64)> {
        thin(samples.iter().map(|s| (s.time, f(s))).collect())
    };
    let mut figs = vec![
        Figure {
            file: "feed",
            title: "Feed vs time (Fig. 8)".into(),
            x_label: "time [s]",
            y_label: "feed [mm/min; deg/min turning in place]",
            kind: Kind::Lines,
            series: vec![series("feed", BLUE_, t(&|s| s.feed * 60.0))],
        },
        Figure {
            file: "curvature",
            title: "Curvature at the setpoints (Fig. 7)".into(),
            x_label: "time [s]",
            y_label: "curvature [1/mm]",
            kind: Kind::Lines,
            series: vec![series("curvature", BLUE_, t(&|s| s.curvature))],
        },
        Figure {
            file: "chord_error",
            title: "Chord error per tick (Fig. 10)".into(),
            x_label: "time [s]",
            y_label: "chord error [µm]",
            kind: Kind::Lines,
            series: vec![
                series("chord error", BLUE_, t(&|s| s.chord_error * 1e3)),
                series(
                    "tolerance",
                    RED_,
                    samples
                        .first()
                        .zip(samples.last())
                        .map(|(a, b)| {
                            let tol = summary.chord_tolerance_mm * 1e3;
                            vec![(a.time, tol), (b.time, tol)]
                        })
                        .unwrap_or_default(),
                ),
            ],
        },
        Figure {
            file: "acceleration",
            title: "Tangential and centripetal acceleration (Fig. 9)".into(),
            x_label: "time [s]",
            y_label: "acceleration [mm/s²]",
            kind: Kind::Lines,
            series: vec![
                series("tangential", BLUE_, t(&|s| s.tangential_accel)),
                series("centripetal", ORANGE_, t(&|s| s.centripetal_accel)),
            ],
        },
        Figure {
            file: "jerk",
            title: "Tangential jerk".into(),
            x_label: "time [s]",
            y_label: "jerk [mm/s³]",
            kind: Kind::Lines,
            series: vec![series("jerk", BLUE_, t(&|s| s.jerk))],
        },
    ];
    let mrr: Vec<(f64, f64)> = samples
        .iter()
        .filter_map(|s| s.mrr.filter(|_| s.feed > 0.0).map(|m| (s.time, m)))
        .collect();
    if mrr.is_empty() {
        notes.push("mrr: no block carries MRR parameters, no MRR plot".to_owned());
    } else {
        figs.push(Figure {
            file: "mrr",
            title: "Relative material removal rate (Fig. 12)".into(),
            x_label: "time [s]",
            y_label: "MRR / MRR of straight cutting at F",
            kind: Kind::Lines,
            series: vec![series("relative MRR", GREEN_, thin(mrr))],
        });
    }
    let path = |i: usize, j: usize| -> Vec<(f64, f64)> {
        let pts = trace.setpoints.iter().map(|s| {
            let p = s.xyz();
            (p[i], p[j])
        });
        stride(pts.collect())
    };
    figs.push(Figure {
        file: "path_xy",
        title: "Tool path, XY (Fig. 6)".into(),
        x_label: "X [mm]",
        y_label: "Y [mm]",
        kind: Kind::Path,
        series: vec![series("path", BLUE_, path(0, 1))],
    });
    figs.push(Figure {
        file: "path_xz",
        title: "Tool path, XZ".into(),
        x_label: "X [mm]",
        y_label: "Z [mm]",
        kind: Kind::Path,
        series: vec![series("path", BLUE_, path(0, 2))],
    });
    five_axis_figures(trace, &mut figs, &mut notes);
    let late: Vec<f64> = trace
        .loop_timing
        .iter()
        .filter_map(|t| t.wake_lateness_ns)
        .map(|ns| ns as f64 / 1e3)
        .collect();
    if late.is_empty() {
        notes.push(
            "wake_lateness: no wake-lateness samples (not a real-time run), no histogram"
                .to_owned(),
        );
    } else {
        let (lo, hi) = late
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
                (a.min(x), b.max(x))
            });
        let w = ((hi - lo) / LATENESS_BINS as f64).max(1e-3);
        let mut counts = vec![0u64; LATENESS_BINS + 1];
        for x in &late {
            let k = (((x - lo) / w) as usize).min(LATENESS_BINS);
            counts[k] += 1;
        }
        let bars = counts
            .iter()
            .enumerate()
            .filter(|(_, c)| **c > 0)
            .map(|(k, &c)| (lo + (k as f64 + 0.5) * w, c as f64))
            .collect();
        figs.push(Figure {
            file: "wake_lateness",
            title: format!("Wake lateness, {} ticks", late.len()),
            x_label: "wake time − deadline [µs]",
            y_label: "ticks",
            kind: Kind::Bars(w),
            series: vec![series("ticks", BLUE_, bars)],
        });
    }
    (figs, notes)
}

/// How far up the tool axis the second line of the tool-tip figure runs, mm.
pub const TOOL_AXIS_MARK_MM: f64 = 10.0;

/// The tool tip and tool axis in the workpiece frame (the setpoints' `tip`
/// and `tool_axis`, recorded when the run has a machine), and the rotary
/// joints when they move.
fn five_axis_figures(trace: &Trace, figs: &mut Vec<Figure>, notes: &mut Vec<String>) {
    let sps = &trace.setpoints;
    let posed: Vec<(f64, [f64; 3], [f64; 3])> = sps
        .iter()
        .filter_map(|s| Some((s.time, s.tip?, s.tool_axis?)))
        .collect();
    if posed.is_empty() {
        notes.push(
            "tool_tip, tool_axis: the run has no machine (no tool tip or axis recorded), no plots"
                .to_owned(),
        );
    } else {
        let up = |(_, p, a): &(f64, [f64; 3], [f64; 3])| {
            (
                p[0] + a[0] * TOOL_AXIS_MARK_MM,
                p[1] + a[1] * TOOL_AXIS_MARK_MM,
            )
        };
        figs.push(Figure {
            file: "tool_tip_xy",
            title: format!(
                "Tool tip and a point {TOOL_AXIS_MARK_MM} mm up the tool axis, workpiece frame, XY"
            ),
            x_label: "x [mm]",
            y_label: "y [mm]",
            kind: Kind::Path,
            series: vec![
                series(
                    "tool tip",
                    BLUE_,
                    stride(posed.iter().map(|(_, p, _)| (p[0], p[1])).collect()),
                ),
                series(
                    &format!("{TOOL_AXIS_MARK_MM} mm up the tool axis"),
                    ORANGE_,
                    stride(posed.iter().map(up).collect()),
                ),
            ],
        });
        let component = |k: usize| thin(posed.iter().map(|(t, _, a)| (*t, a[k])).collect());
        figs.push(Figure {
            file: "tool_axis",
            title: "Tool axis in the workpiece frame".into(),
            x_label: "time [s]",
            y_label: "unit vector component",
            kind: Kind::Lines,
            series: vec![
                series("i", BLUE_, component(0)),
                series("j", ORANGE_, component(1)),
                series("k", GREEN_, component(2)),
            ],
        });
    }
    let first = sps.first().map(|s| [s.a, s.b, s.c]);
    if sps.iter().any(|s| Some([s.a, s.b, s.c]) != first) {
        let joint = |f: fn(&crate::messages::SetpointMsg) -> f64| {
            thin(sps.iter().map(|s| (s.time, f(s))).collect())
        };
        figs.push(Figure {
            file: "rotary_joints",
            title: "Rotary joints".into(),
            x_label: "time [s]",
            y_label: "degrees",
            kind: Kind::Lines,
            series: vec![
                series("A", BLUE_, joint(|s| s.a)),
                series("B", ORANGE_, joint(|s| s.b)),
                series("C", GREEN_, joint(|s| s.c)),
            ],
        });
    }
}

/// What [`plot_trace`] wrote.
#[derive(Clone, Debug, Default)]
pub struct PlotReport {
    /// Files written (PNG and SVG of each figure).
    pub files: Vec<PathBuf>,
    /// Figures left out, and why.
    pub notes: Vec<String>,
}

/// Writes every figure of `trace` (with `samples` and `summary` from
/// [`crate::analysis::analyse`]) as PNG and SVG into `out_dir`.
pub fn plot_trace(
    trace: &Trace,
    samples: &[Sample],
    summary: &Summary,
    out_dir: &Path,
) -> Result<PlotReport, PlotError> {
    register_font();
    std::fs::create_dir_all(out_dir).map_err(|source| PlotError::Dir {
        path: out_dir.display().to_string(),
        source,
    })?;
    let (figs, notes) = figures(trace, samples, summary);
    let mut files = Vec::new();
    for fig in &figs {
        let png = out_dir.join(format!("{}.png", fig.file));
        let err = |p: &Path, reason: String| PlotError::Draw {
            path: p.display().to_string(),
            reason,
        };
        draw(BitMapBackend::new(&png, PLOT_SIZE).into_drawing_area(), fig)
            .map_err(|r| err(&png, r))?;
        files.push(png);
        let svg = out_dir.join(format!("{}.svg", fig.file));
        draw(SVGBackend::new(&svg, PLOT_SIZE).into_drawing_area(), fig)
            .map_err(|r| err(&svg, r))?;
        files.push(svg);
    }
    Ok(PlotReport { files, notes })
}

/// One line of a [`Chart`].
#[derive(Clone, Debug)]
pub struct ChartLine {
    /// Legend text.
    pub name: String,
    /// A limit or tolerance (drawn in red) rather than measured data.
    pub limit: bool,
    /// The points, in x order for time series.
    pub points: Vec<(f64, f64)>,
}

impl ChartLine {
    /// Measured data.
    pub fn data(name: &str, points: Vec<(f64, f64)>) -> Self {
        ChartLine {
            name: name.to_owned(),
            limit: false,
            points,
        }
    }

    /// A limit or tolerance.
    pub fn limit(name: &str, points: Vec<(f64, f64)>) -> Self {
        ChartLine {
            name: name.to_owned(),
            limit: true,
            points,
        }
    }
}

/// A figure built by the caller (for runs that are not a [`Trace`], such as
/// `interpd demo`), drawn as [`plot_trace`] draws its own.
#[derive(Clone, Debug)]
pub struct Chart {
    /// File name without extension.
    pub file: &'static str,
    /// Caption.
    pub title: String,
    /// X axis label.
    pub x_label: &'static str,
    /// Y axis label.
    pub y_label: &'static str,
    /// Equal scales on both axes (a tool path); otherwise a time series.
    pub equal_axes: bool,
    /// The lines, data before limits.
    pub lines: Vec<ChartLine>,
}

/// Writes each chart as `<file>.png` into `out_dir` (made if missing), and as
/// `<file>.svg` too when `svg`. Long series are thinned as in [`plot_trace`]
/// (min and max per bucket for time series, every k-th point for paths).
pub fn plot_charts(charts: &[Chart], out_dir: &Path, svg: bool) -> Result<PlotReport, PlotError> {
    register_font();
    std::fs::create_dir_all(out_dir).map_err(|source| PlotError::Dir {
        path: out_dir.display().to_string(),
        source,
    })?;
    const DATA_COLORS: [RGBColor; 3] = [BLUE_, ORANGE_, GREEN_];
    let mut files = Vec::new();
    for c in charts {
        let mut data = DATA_COLORS.iter().cycle();
        let fig = Figure {
            file: c.file,
            title: c.title.clone(),
            x_label: c.x_label,
            y_label: c.y_label,
            kind: if c.equal_axes {
                Kind::Path
            } else {
                Kind::Lines
            },
            series: c
                .lines
                .iter()
                .map(|l| {
                    let color = if l.limit {
                        RED_
                    } else {
                        *data.next().unwrap_or(&BLUE_)
                    };
                    let points = if c.equal_axes {
                        stride(l.points.clone())
                    } else {
                        thin(l.points.clone())
                    };
                    series(&l.name, color, points)
                })
                .collect(),
        };
        let err = |p: &Path, reason: String| PlotError::Draw {
            path: p.display().to_string(),
            reason,
        };
        let png = out_dir.join(format!("{}.png", fig.file));
        draw(
            BitMapBackend::new(&png, PLOT_SIZE).into_drawing_area(),
            &fig,
        )
        .map_err(|r| err(&png, r))?;
        files.push(png);
        if svg {
            let path = out_dir.join(format!("{}.svg", fig.file));
            draw(SVGBackend::new(&path, PLOT_SIZE).into_drawing_area(), &fig)
                .map_err(|r| err(&path, r))?;
            files.push(path);
        }
    }
    Ok(PlotReport {
        files,
        notes: Vec::new(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thinning_keeps_extremes_and_bounds_the_size() {
        let pts: Vec<(f64, f64)> = (0..100_000)
            .map(|i| (f64::from(i), if i == 51_234 { 9.0 } else { 0.0 }))
            .collect();
        let out = thin(pts);
        assert!(out.len() <= 2 * MAX_POINTS_PER_SERIES);
        assert!(out.iter().any(|p| p == &(51_234.0, 9.0)));
        assert!(out.windows(2).all(|w| w[0].0 < w[1].0));
        let short = vec![(0.0, 1.0), (1.0, 2.0)];
        assert_eq!(thin(short.clone()), short);
    }

    #[test]
    fn charts_are_written_as_png_and_svg() {
        let dir = std::env::temp_dir().join(format!("traces-charts-{}", std::process::id()));
        let sine: Vec<(f64, f64)> = (0..20_000)
            .map(|i| (f64::from(i) * 1e-3, (f64::from(i) * 1e-3).sin()))
            .collect();
        let charts = [
            Chart {
                file: "series",
                title: "a sine and its limit".into(),
                x_label: "t [s]",
                y_label: "y",
                equal_axes: false,
                lines: vec![
                    ChartLine::data("sin", sine.clone()),
                    ChartLine::limit("limit", vec![(0.0, 1.0), (20.0, 1.0)]),
                ],
            },
            Chart {
                file: "path",
                title: "a circle".into(),
                x_label: "x",
                y_label: "y",
                equal_axes: true,
                lines: vec![ChartLine::data(
                    "path",
                    sine.iter().map(|&(t, _)| (t.cos(), t.sin())).collect(),
                )],
            },
        ];
        let report = plot_charts(&charts, &dir, true).expect("charts drawn");
        let names: Vec<String> = report
            .files
            .iter()
            .map(|p| {
                p.file_name()
                    .unwrap_or_default()
                    .to_string_lossy()
                    .into_owned()
            })
            .collect();
        assert_eq!(names, ["series.png", "series.svg", "path.png", "path.svg"]);
        for f in &report.files {
            let bytes = std::fs::read(f).expect("file written");
            if f.extension().is_some_and(|e| e == "png") {
                assert_eq!(&bytes[1..4], b"PNG", "{}", f.display());
            } else {
                assert!(String::from_utf8_lossy(&bytes).contains("<svg"));
            }
        }
        let report = plot_charts(&charts[..1], &dir, false).expect("png only");
        assert_eq!(report.files.len(), 1);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
