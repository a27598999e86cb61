//! Plots: every figure as PNG and SVG; the wake-lateness histogram only for
//! traces that carry lateness.

use std::io::Cursor;

use traces::analysis::analyse;
use traces::messages::LoopTimingMsg;
use traces::plot::plot_trace;
use traces::sim::{self, SimSettings};
use traces::writer::{TraceCompression, TraceWriter};
use traces::{Program, Trace};

fn trace() -> Trace {
    let program: Program =
        serde_json::from_str(include_str!("../../tests/golden/nurbs_mrr.json")).expect("program");
    let config = sim::config_for(
        &program,
        Default::default(),
        &SimSettings::default(),
        "t",
        "nurbs_mrr",
    );
    let mut w = TraceWriter::new(Cursor::new(Vec::new()), TraceCompression::Zstd).expect("writer");
    sim::record(&config, &program, 3600.0, &mut w, |_| {}).expect("simulates");
    Trace::from_bytes(&w.finish().expect("finish").0.into_inner()).expect("reads")
}

#[test]
fn every_figure_is_written_as_png_and_svg() {
    let mut t = trace();
    let dir = std::env::temp_dir().join(format!("interpd-plots-{}", std::process::id()));
    let (summary, samples) = analyse(&t).expect("analyses");
    let r = plot_trace(&t, &samples, &summary, &dir).expect("plots");
    let names: Vec<String> = r
        .files
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    for stem in [
        "feed",
        "curvature",
        "chord_error",
        "acceleration",
        "jerk",
        "mrr",
        "path_xy",
        "path_xz",
    ] {
        for ext in ["png", "svg"] {
            assert!(
                names.contains(&format!("{stem}.{ext}")),
                "{stem}.{ext} in {names:?}"
            );
        }
    }
    assert!(!names.iter().any(|n| n.starts_with("wake_lateness")));
    assert!(r.notes.iter().any(|n| n.starts_with("wake_lateness")));
    for f in &r.files {
        let bytes = std::fs::read(f).expect("written");
        if f.extension().is_some_and(|e| e == "png") {
            assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "{}", f.display());
        } else {
            let text = String::from_utf8(bytes).expect("svg text");
            assert!(
                text.contains("<svg") && text.contains("<polyline") || text.contains("<path"),
                "{}",
                f.display()
            );
            // Axis labels are text, drawn with the bundled font.
            assert!(
                text.contains("time [s]") || text.contains("[mm]"),
                "{}",
                f.display()
            );
        }
    }
    // A real-time trace gets the lateness histogram.
    t.loop_timing = (1..=500)
        .map(|k| LoopTimingMsg {
            seq: k,
            wake_lateness_ns: Some((k as i64 * 37) % 9000),
            tick_compute_ns: Some(3000),
            queue_depth: 2,
        })
        .collect();
    let (summary, samples) = analyse(&t).expect("analyses");
    assert_eq!(summary.max_wake_lateness_us, Some(8.991));
    let r = plot_trace(&t, &samples, &summary, &dir).expect("plots");
    assert!(r.files.iter().any(|p| p.ends_with("wake_lateness.png")));
    let _ = std::fs::remove_dir_all(&dir);
}
