//! Parse throughput outside criterion, reporting wall and CPU time (the
//! build machine is shared, so CPU time is the fairer figure).
//!
//! `cargo run --release -p gcode --example parse_speed -- [MB] [repeats]`

use std::time::Instant;

fn cpu_seconds() -> f64 {
    // /proc/self/stat fields 14 and 15: user and system time in clock ticks.
    let stat = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    let after = stat.rsplit(')').next().unwrap_or("");
    let f: Vec<&str> = after.split_whitespace().collect();
    let ticks = |i: usize| {
        f.get(i)
            .and_then(|v| v.parse::<f64>().ok())
            .unwrap_or(f64::NAN)
    };
    // Fields after the ')' start at field 3 (state): utime is field 14 → index 11.
    (ticks(11) + ticks(12)) / 100.0
}

fn main() {
    let mut args = std::env::args().skip(1);
    let mb: usize = args.next().and_then(|a| a.parse().ok()).unwrap_or(32);
    let repeats: usize = args.next().and_then(|a| a.parse().ok()).unwrap_or(5);
    let text = gcode::generate::g1_heavy_program(mb << 20);
    let mut best_wall = f64::INFINITY;
    let mut best_cpu = f64::INFINITY;
    for _ in 0..repeats {
        let (t, c) = (Instant::now(), cpu_seconds());
        let p = gcode::parse(&text).expect("generated program parses");
        let (wall, cpu) = (t.elapsed().as_secs_f64(), cpu_seconds() - c);
        std::hint::black_box(p.blocks.len());
        drop(p);
        best_wall = best_wall.min(wall);
        best_cpu = best_cpu.min(cpu);
    }
    let mbytes = text.len() as f64 / 1e6;
    println!(
        "{:.1} MB, {} lines: best of {repeats}: wall {:.3} s = {:.0} MB/s, CPU {:.3} s = {:.0} MB/s",
        mbytes,
        text.lines().count(),
        best_wall,
        mbytes / best_wall,
        best_cpu,
        mbytes / best_cpu
    );
}
