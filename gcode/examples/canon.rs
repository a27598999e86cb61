//! Prints a program's moves as JSON lines, one per motion, in the terms of
//! LinuxCNC's canonical calls, for `scripts/linuxcnc_conformance.py`.
//!
//! ```text
//! cargo run --release -p gcode --example canon -- FILE.ngc
//! ```
//!
//! Each line: `{"line":N,"kind":"rapid"|"feed"|"arc"|"nurbs","end":[x,y,z],...}`
//! in mm; arcs add `"centre"`, `"plane"` (17/18/19) and `"rotation"` (LinuxCNC's:
//! +turns counter-clockwise, −turns clockwise); feeds add `"feed"` (mm/min) or
//! `"inverse_time"` (1/min); NURBS add `"control_points"` and the curve as read:
//! `"plane"`, `"degree"`, `"points"` (x, y, z each), `"weights"`, `"knots"`
//! (so the script can measure LinuxCNC's approximation against the exact
//! curve). On a parse error it prints `{"error":"line:column: message"}` and
//! exits with status 2.

use std::fmt::Write;

use gcode::{BlockKind, Feed};

fn point(p: &[f64; 3]) -> String {
    format!("[{:?},{:?},{:?}]", p[0], p[1], p[2])
}

fn list(values: impl Iterator<Item = String>) -> String {
    let items: Vec<String> = values.collect();
    format!("[{}]", items.join(","))
}

fn feed(f: Feed) -> String {
    match f {
        Feed::PerMinute(v) => format!("\"feed\":{v:?}"),
        Feed::InverseTime(v) => format!("\"inverse_time\":{v:?}"),
    }
}

fn main() {
    let Some(path) = std::env::args().nth(1) else {
        eprintln!("usage: canon FILE.ngc");
        std::process::exit(1);
    };
    let text = match std::fs::read(&path) {
        Ok(bytes) => String::from_utf8_lossy(&bytes).into_owned(),
        Err(e) => {
            eprintln!("{path}: {e}");
            std::process::exit(1);
        }
    };
    let program = match gcode::parse(&text) {
        Ok(p) => p,
        Err(e) => {
            println!("{{\"error\":{:?}}}", e.to_string());
            std::process::exit(2);
        }
    };
    let mut out = String::new();
    for b in &program.blocks {
        let line = b.line;
        match &b.kind {
            BlockKind::Rapid(m) => {
                let _ = writeln!(
                    out,
                    "{{\"line\":{line},\"kind\":\"rapid\",\"end\":{}}}",
                    point(&m.end)
                );
            }
            BlockKind::Linear(m) => {
                let _ = writeln!(
                    out,
                    "{{\"line\":{line},\"kind\":\"feed\",\"end\":{},{}}}",
                    point(&m.end),
                    feed(m.feed)
                );
            }
            BlockKind::Arc(m) => {
                let turns = i64::from(m.extra_turns) + 1;
                let rotation = if m.clockwise { -turns } else { turns };
                let _ = writeln!(
                    out,
                    "{{\"line\":{line},\"kind\":\"arc\",\"end\":{},\"centre\":{},\"plane\":{},\"rotation\":{rotation},{}}}",
                    point(&m.end),
                    point(&m.centre),
                    m.plane.g_code(),
                    feed(m.feed)
                );
            }
            BlockKind::Nurbs(m) => {
                let end = m.points.last().copied().unwrap_or([f64::NAN; 3]);
                let _ = writeln!(
                    out,
                    "{{\"line\":{line},\"kind\":\"nurbs\",\"end\":{},\"control_points\":{},{},\"plane\":{},\"degree\":{},\"points\":{},\"weights\":{},\"knots\":{}}}",
                    point(&end),
                    m.points.len(),
                    feed(m.feed),
                    m.plane.g_code(),
                    m.degree,
                    list(m.points.iter().map(point)),
                    list(m.weights.iter().map(|w| format!("{w:?}"))),
                    list(m.knots.iter().map(|k| format!("{k:?}")))
                );
            }
            _ => {}
        }
    }
    print!("{out}");
}
