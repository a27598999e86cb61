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

/// A five-axis run (G43.5 on a C,A table, the tool leaning 5°): every
/// setpoint records the tool tip and tool axis, the analysis measures the
/// path on the tip (the joints' X Y Z are tens of mm off it), and the plots
/// draw tip, axis and rotary joints.
#[test]
fn a_five_axis_trace_records_the_tool_tip_and_axis_and_plots_them() {
    let machine: interp_core::kinematics::MachineSpec = serde_json::from_str(
        r#"{"chain": "W/caxyBz/T", "tool-length": 100, "rotary-centres": [[0, 0, -50], [0, 0, 0], [0, 0, 0]],
            "rotary-ranges": [{"min": -110, "max": 110}, {"min": 0, "max": 0}, {"min": null, "max": null}]}"#,
    )
    .expect("machine");
    let interp = interp_core::InterpConfig {
        machine: Some(machine),
        ..Default::default()
    };
    let g = gcode::parse(
        "G21 G90 G61\nG43.5 H1\nG1 X0 Y0 Z-95 I0 J-0.087156 K0.996195 F6000\n\
         G1 X5 Y0 Z-95\nG1 X5 Y5 Z-95 I0 J0 K1\nG49\nG1 X0 Y0 Z0\n",
    )
    .expect("parses");
    let program = Program::from_gcode(&g, &gcode::CoreOptions::for_config(&interp), [0.0; 6])
        .expect("converts");
    let config = sim::config_for(&program, interp, &SimSettings::default(), "t", "five");
    let mut w = TraceWriter::new(Cursor::new(Vec::new()), TraceCompression::Zstd).expect("writer");
    sim::record(&config, &program, 3600.0, &mut w, |_| {}).expect("simulates");
    let t = Trace::from_bytes(&w.finish().expect("finish").0.into_inner()).expect("reads");
    let m = interp_core::kinematics::Machine::new(machine).expect("machine");
    assert!(t.setpoints.iter().all(|s| {
        let pose = m.forward(&s.to_setpoint().axes);
        s.tip == Some([pose.tip.x, pose.tip.y, pose.tip.z])
            && s.tool_axis == Some([pose.axis.x, pose.axis.y, pose.axis.z])
    }));
    // The joints' X Y Z are far from the tip (the tool is 100 mm long).
    assert!(
        t.setpoints
            .iter()
            .any(|s| (s.z - s.tip.unwrap()[2]).abs() > 50.0)
    );
    let (summary, samples) = analyse(&t).expect("analyses");
    assert!(
        summary.max_chord_error_mm < summary.chord_tolerance_mm,
        "{summary}"
    );
    let dir = std::env::temp_dir().join(format!("interpd-plots-five-{}", std::process::id()));
    let r = plot_trace(&t, &samples, &summary, &dir).expect("plots");
    for stem in ["tool_tip_xy", "tool_axis", "rotary_joints"] {
        assert!(
            r.files.iter().any(|p| p.ends_with(format!("{stem}.png"))),
            "{stem}: {:?}",
            r.files
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
    // A three-axis trace has no tip: no such plots, and a note says why.
    let three = trace();
    assert!(three.setpoints.iter().all(|s| s.tip.is_none()));
}
