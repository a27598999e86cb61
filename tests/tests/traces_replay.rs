//! Golden traces: every `tests/golden/NAME.json` program has a recorded
//! `NAME.mcap` that must replay bit for bit. Regenerate them after a change
//! that moves setpoints on purpose with
//! `INTERPD_BLESS=1 cargo test -p interpd-tests --test traces_replay`.

use std::io::Cursor;

use interpd_tests::{golden_config, golden_dir, golden_programs, golden_trace};
use traces::analysis::{Analyzer, analyse};
use traces::reader::{ReadError, Trace};
use traces::replay::{ReplayError, replay};
use traces::sim::{self, SimItem, SimSettings};
use traces::writer::{TraceCompression, TraceWriter};

fn golden(name: &str) -> (Vec<u8>, Trace) {
    let bytes = golden_trace(name);
    let trace = Trace::from_bytes(&bytes).expect("golden trace reads");
    (bytes, trace)
}

/// Writes `trace` again, with `edit` applied to its setpoints.
fn rewrite(trace: &Trace, edit: impl Fn(&mut Vec<traces::SetpointMsg>)) -> Trace {
    let mut sps = trace.setpoints.clone();
    edit(&mut sps);
    let mut w =
        TraceWriter::new(Cursor::new(Vec::new()), TraceCompression::Zstd).expect("trace starts");
    w.config(trace.config.as_ref().expect("config"))
        .expect("config");
    for b in &trace.blocks {
        w.block(b, 0.0).expect("block");
    }
    for s in &sps {
        w.setpoint(&s.to_setpoint()).expect("setpoint");
    }
    for e in &trace.events {
        w.event(e).expect("event");
    }
    let bytes = w.finish().expect("finish").0.into_inner();
    Trace::from_bytes(&bytes).expect("rewritten trace reads")
}

#[test]
fn golden_traces_replay_bit_for_bit() {
    let programs = golden_programs();
    assert!(programs.len() >= 2, "golden programs missing");
    for (name, program) in programs {
        let (_, trace) = golden(&name);
        // The trace holds this very program (the JSON and the MCAP are in step).
        let recorded: Vec<_> = trace.blocks.iter().map(|b| b.block.clone()).collect();
        assert_eq!(
            recorded, program.blocks,
            "{name}: re-bless the golden trace"
        );
        let r = replay(&trace).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(r.compared as usize, trace.setpoints.len(), "{name}");
        assert!(r.compared > 100, "{name}: {} setpoints", r.compared);
        assert_eq!(r.missing_in_trace, 0);
        let last = trace.setpoints.last().expect("setpoints");
        assert_eq!(last.state, interp_core::RunState::Done, "{name}");
        assert!(trace.setpoints.iter().zip(1..).all(|(s, k)| s.seq == k));
    }
}

#[test]
fn one_ulp_in_one_setpoint_fails_replay_naming_seq_and_field() {
    let (_, trace) = golden("line_arc");
    let k = trace.setpoints.len() / 2;
    let seq = trace.setpoints[k].seq;
    let altered = rewrite(&trace, |s| s[k].y = f64::from_bits(s[k].y.to_bits() + 1));
    match replay(&altered) {
        Err(ReplayError::Mismatch(m)) => {
            assert_eq!((m.seq, m.field.as_str()), (seq, "y"), "{m}");
        }
        other => panic!("expected a mismatch, got {other:?}"),
    }
    // The state field and a missing tail are caught too.
    let altered = rewrite(&trace, |s| s[3].state = interp_core::RunState::Holding);
    match replay(&altered) {
        Err(ReplayError::Mismatch(m)) => assert_eq!((m.seq, m.field.as_str()), (4, "state")),
        other => panic!("expected a mismatch, got {other:?}"),
    }
    let n = trace.setpoints.len();
    let altered = rewrite(&trace, |s| s.truncate(n - 1));
    match replay(&altered) {
        Err(ReplayError::Mismatch(m)) => {
            assert_eq!((m.seq, m.field.as_str()), (n as u64, "setpoints"))
        }
        other => panic!("expected a mismatch, got {other:?}"),
    }
    // And an unaltered rewrite still replays.
    assert!(replay(&rewrite(&trace, |_| {})).is_ok());
}

#[test]
fn a_changed_config_or_block_fails_replay() {
    let (_, trace) = golden("nurbs_mrr");
    let mut t = trace.clone();
    if let Some(c) = &mut t.config {
        // Lower: the planned acceleration is the smaller of this and the axes' share.
        c.interp.max_path_accel *= 1.0 - 1e-12;
    }
    let e = replay(&t).expect_err("a changed accel limit moves setpoints");
    assert!(matches!(e, ReplayError::Mismatch(_)), "{e}");
    let mut t = trace.clone();
    t.blocks[0].block.feed += 1e-9;
    assert!(matches!(replay(&t), Err(ReplayError::Mismatch(_))));
}

#[test]
fn simulate_summary_equals_trace_summary() {
    for (name, program) in golden_programs() {
        let config = golden_config(&program, &name);
        let expanded = program
            .expand(config.max_ctrl_per_block, 1)
            .expect("expands");
        let segments = sim::smoothed_segments(&expanded, &config.interp).expect("smooths");
        let mut live = Analyzer::new(&config, expanded.blocks.len(), &segments);
        let mut w =
            TraceWriter::new(Cursor::new(Vec::new()), TraceCompression::Lz4).expect("trace starts");
        sim::record(
            &config,
            &program,
            SimSettings::default().max_machine_time,
            &mut w,
            |i| match i {
                SimItem::Tick { setpoint, .. } => {
                    live.push(setpoint);
                }
                SimItem::Event(e) => live.event(e.kind),
                _ => {}
            },
        )
        .expect("simulates");
        let bytes = w.finish().expect("finish").0.into_inner();
        let (from_file, samples) =
            analyse(&Trace::from_bytes(&bytes).expect("reads")).expect("analyses");
        assert_eq!(live.summary(), from_file, "{name}");
        assert_eq!(samples.len() as u64, from_file.setpoints);
        // Default limits hold on the golden programs.
        assert!(
            from_file.max_chord_error_mm <= from_file.chord_tolerance_mm,
            "{name}"
        );
        assert!(from_file.max_feed_mm_s <= 50.0 + 1e-9, "{name}");
        assert!(
            from_file.max_tangential_accel_mm_s2 <= 2000.0 * (1.0 + 1e-9),
            "{name}"
        );
    }
}

#[test]
fn truncated_and_corrupted_traces_report_what_they_recovered() {
    let (bytes, full) = golden("line_arc");
    let n = bytes.len();
    let mut last_setpoints = 0;
    for frac in [0.2, 0.5, 0.8, 0.95] {
        let cut = (n as f64 * frac) as usize;
        match Trace::from_bytes(&bytes[..cut]) {
            Err(ReadError::Damaged {
                recovered,
                file_bytes,
                cause,
            }) => {
                assert_eq!(file_bytes, cut);
                assert!(!cause.is_empty());
                let got = recovered.setpoints.len();
                // (Past the last setpoint chunk, at a layout-dependent share
                // of the file, everything is recovered.)
                assert!(got < full.setpoints.len() || frac > 0.5, "cut {cut}: {got}");
                assert!(got >= last_setpoints, "more file, no fewer setpoints");
                last_setpoints = got;
                // What was recovered is the trace's own beginning.
                assert_eq!(&full.setpoints[..got], &recovered.setpoints[..]);
                let msg = ReadError::Damaged {
                    recovered,
                    file_bytes,
                    cause,
                }
                .to_string();
                assert!(
                    msg.contains("recovered") && msg.contains("setpoints"),
                    "{msg}"
                );
            }
            other => panic!("cut at {cut}: expected Damaged, got {other:?}"),
        }
    }
    assert!(last_setpoints > 0, "a long prefix recovers setpoints");
    // A flipped byte is never read silently: either reading fails, or it hit
    // a field that changes nothing read (an index or a time range), and the
    // trace reads back whole.
    // Flips spread over the whole file; most land in chunk data (the rest in
    // indexes and summaries), so most must be caught.
    let (flips, mut damaged) = (40, 0);
    for k in 1..flips {
        let mut bad = bytes.clone();
        bad[n * k / flips] ^= 0x40;
        match Trace::from_bytes(&bad) {
            // Damage found by the CRC or the decompressor, or a message that
            // no longer decodes: both name where.
            Err(e) => {
                assert!(!e.to_string().is_empty());
                damaged += 1;
            }
            Ok(t) => assert_eq!(t.setpoints, full.setpoints, "flip at {}", n * k / flips),
        }
    }
    assert!(
        2 * damaged > flips,
        "only {damaged} of {} flips detected",
        flips - 1
    );
    // Densely inside the first chunk's compressed data, where a flip makes
    // the decompressor emit garbage record lengths: each is caught (the
    // chunk's CRC is checked before any of its records is used, and every
    // length is bounded), never a reservation of up to 2⁶⁴ bytes that aborts
    // the process, never a silent change.
    for at in (64..8192).step_by(13) {
        let mut bad = bytes.clone();
        bad[at] ^= 0x5a;
        match Trace::from_bytes(&bad) {
            Err(e) => assert!(!e.to_string().is_empty()),
            Ok(t) => assert_eq!(t.setpoints, full.setpoints, "flip at {at}"),
        }
    }
    // Not an MCAP at all, and empty.
    assert!(matches!(
        Trace::from_bytes(b"hello, world, not an mcap file"),
        Err(ReadError::Damaged { .. })
    ));
    assert!(matches!(
        Trace::from_bytes(b""),
        Err(ReadError::Damaged { .. })
    ));
    let e = Trace::open(golden_dir().join("no-such.mcap")).expect_err("missing file");
    assert!(e.to_string().contains("no-such.mcap"), "{e}");
}
