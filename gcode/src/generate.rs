//! Synthetic programs for benchmarks and tests.

use core::fmt::Write;

/// A CAM-style finishing program of about `target_bytes` bytes: a raster of
/// short G1 moves (three coordinates with three decimals, as post-processors
/// write them) over a wavy surface, with an occasional arc, feed change and
/// comment. Deterministic for a given size.
pub fn g1_heavy_program(target_bytes: usize) -> String {
    let mut out = String::with_capacity(target_bytes + 256);
    out.push_str("%\n(interpd benchmark: G1-heavy raster)\nG21 G90 G94 G17 G64 P0.01\nT1 M6\nS12000 M3\nG0 X0 Y0 Z5\nG1 Z0 F1200\n");
    let mut i: u64 = 0;
    let step = 0.05;
    let row_len = 2000;
    while out.len() < target_bytes {
        let row = i / row_len;
        let k = i % row_len;
        let x = if row.is_multiple_of(2) {
            k as f64 * step
        } else {
            (row_len - k) as f64 * step
        };
        let y = row as f64 * 0.25;
        // A cheap smooth surface (no trig: the generator should not dominate).
        let t = (k as f64 / row_len as f64) * 2.0 - 1.0;
        let z = -1.0 + 0.5 * t * t - 0.1 * (row % 7) as f64;
        if k == 0 && row > 0 {
            let _ = writeln!(out, "(row {row})");
            let _ = writeln!(out, "G3 X{x:.3} Y{y:.3} R0.2 F900");
        }
        if k % 500 == 250 {
            let _ = writeln!(
                out,
                "G1 X{x:.3} Y{y:.3} Z{z:.3} F{}",
                1000 + (row % 5) * 100
            );
        } else {
            let _ = writeln!(out, "G1 X{x:.3} Y{y:.3} Z{z:.3}");
        }
        i += 1;
    }
    out.push_str("G0 Z5\nM5\nM30\n%\n");
    out
}
