//! Every program of the LinuxCNC NURBS corpus parses, and runs through the
//! interpolator to its end (when the corpus is present).

mod common;

use std::path::{Path, PathBuf};

const CORPUS: &str = "/work/shared/corpus/nurbs-linuxcnc";

/// The corpus programs (G5.2 then G6.2, each sorted by name), or `None` when
/// the corpus is absent (a clean clone).
fn corpus_programs() -> Option<Vec<PathBuf>> {
    let root = Path::new(CORPUS);
    if !root.exists() {
        println!("corpus {CORPUS} absent; skipped");
        return None;
    }
    let mut all = Vec::new();
    for sub in ["g5", "g6"] {
        let mut entries: Vec<_> = std::fs::read_dir(root.join(sub))
            .unwrap()
            .map(|e| e.unwrap().path())
            .collect();
        entries.sort();
        all.extend(entries);
    }
    Some(all)
}

#[test]
#[ignore = "needs /work/shared/corpus; run with --ignored"]
fn every_corpus_file_parses_and_converts() {
    let Some(programs) = corpus_programs() else {
        return;
    };
    let mut files = 0;
    let mut refused = 0;
    for path in programs {
        let text = std::fs::read_to_string(&path).unwrap();
        let program = gcode::parse(&text).unwrap_or_else(|e| panic!("{}:{e}", path.display()));
        let blocks = match program.to_core_blocks(&gcode::CoreOptions::default()) {
            Ok(b) => b.len(),
            Err(e) => {
                println!("{}: conversion refused: {e}", path.display());
                refused += 1;
                0
            }
        };
        let nurbs = program
            .blocks
            .iter()
            .filter(|b| matches!(b.kind, gcode::BlockKind::Nurbs(_)))
            .count();
        println!(
            "{}: {} blocks, {nurbs} NURBS, {blocks} core blocks",
            path.display(),
            program.blocks.len()
        );
        assert!(nurbs > 0, "{}: no NURBS", path.display());
        files += 1;
    }
    println!("{files} files parsed, {refused} refused by the conversion");
    assert_eq!(files, 55, "g5 has 15 programs, g6 40");
}

/// Every program of the corpus runs through the interpolator (default
/// configuration) to its end, every setpoint on its path. Slow in a debug
/// build: `cargo test -p gcode --release --test corpus -- --ignored --nocapture`.
#[test]
#[ignore = "needs /work/shared/corpus; run with --release -- --ignored"]
fn every_corpus_program_simulates_to_its_end() {
    let Some(programs) = corpus_programs() else {
        return;
    };
    let mut files = 0;
    let mut failed = Vec::new();
    for path in programs {
        files += 1;
        let text = std::fs::read_to_string(&path).unwrap();
        let blocks = match gcode::parse(&text)
            .map_err(|e| e.to_string())
            .and_then(|p| {
                p.to_core_blocks(&gcode::CoreOptions::default())
                    .map_err(|e| e.to_string())
            }) {
            Ok(b) => b,
            Err(e) => {
                println!("{}: refused: {e}", path.display());
                failed.push(path);
                continue;
            }
        };
        match std::panic::catch_unwind(|| common::run(&blocks)) {
            Ok(sps) => println!(
                "{}: {} blocks, {} setpoints ({:.1} s)",
                path.display(),
                blocks.len(),
                sps.len(),
                sps.len() as f64 * interp_core::InterpConfig::default().period
            ),
            Err(_) => {
                println!("{}: did not run to its end", path.display());
                failed.push(path);
            }
        }
    }
    println!(
        "{} of {files} programs simulate to their end",
        files - failed.len()
    );
    assert!(failed.is_empty(), "{failed:?}");
}
