//! Our path time on each program's first NURBS curve next to the
//! acceleration-only optimum, the jerk-aware lower bound and a feasible
//! jerk-limited reference schedule by sequential linear programming
//! (`interpd_tests::scp`): an upper reference of what a planner can reach.
//!
//! ```text
//! cargo run --release -p interpd-tests --features scp --example scp_reference -- \
//!     [--feed MM_PER_MIN] [--g64 P] [--step MM] [--iterations N] [--scale F] [--set KEY=VALUE]... FILE.ngc...
//! ```
//!
//! `--step` is the reference's grid (0.1 mm), `--iterations` the most
//! linear programs (30; it stops once one gains under 1e-5), `--scale F`
//! scales the reference's acceleration and jerk limits (not ours), `--set` sets
//! a key of `[interp]` for both (as `path_time`'s). Prints,
//! times in s: ours, optimum, bound, the first and the last iterate of the
//! reference, the number of programs and grid nodes, ours over each, and
//! the reference sampled every servo period as the loop samples a plan
//! (`scp::sampled_jerk_use`, the real limits, the first and last mm of the
//! curve left out): its largest path or axis jerk over the limit, where,
//! and how many ticks were over. The reference holds its limits on its own
//! grid in continuous time; a drive sees the samples.

use std::path::PathBuf;

use interp_core::smooth::Policy;
use interpd_tests::cli::{take_config, take_value};
use interpd_tests::path_time::{
    accel_only_optimum, first_curve, interpolated_time, jerk_aware_bound, load_program, smoothed,
};
use interpd_tests::scp::{sampled_jerk_use, scp_reference};

/// Ticks this near either end of a curve are left out of the sampled
/// check, mm ([`sampled_jerk_use`]).
const SAMPLED_EDGE: f64 = 1.0;

fn main() {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let cfg = take_config(&mut args);
    let mut flag = |name: &str| take_value(&mut args, name);
    let feed = flag("--feed").and_then(|v| v.parse::<f64>().ok());
    let step = flag("--step")
        .and_then(|v| v.parse::<f64>().ok())
        .unwrap_or(0.1);
    let g64 = flag("--g64").and_then(|v| v.parse::<f64>().ok());
    let iterations = flag("--iterations")
        .and_then(|v| v.parse::<usize>().ok())
        .unwrap_or(30);
    // `--scale F`: the reference's acceleration and jerk limits times F
    // (ours keep theirs), to find the fastest reference whose setpoints
    // hold the real limits.
    let scale = flag("--scale")
        .and_then(|v| v.parse::<f64>().ok())
        .unwrap_or(1.0);
    let mut ref_cfg = cfg;
    ref_cfg.max_path_accel *= scale;
    ref_cfg.max_path_jerk *= scale;
    ref_cfg.max_centripetal_accel *= scale;
    for i in 0..3 {
        ref_cfg.axis_max_accel[i] *= scale;
        ref_cfg.axis_max_jerk[i] *= scale;
    }
    println!(
        "program | ours s | optimum s | bound s | scp first s | scp s | programs | nodes | ours/opt | ours/bound | ours/scp | scp/opt | scp sampled jerk use | at mm | ticks over"
    );
    for f in args.iter().map(PathBuf::from) {
        let name = f
            .file_name()
            .unwrap_or_default()
            .to_string_lossy()
            .to_string();
        let run = || -> Result<String, String> {
            // `--g64 P`: the whole program through the `G64 P` stage;
            // otherwise its first NURBS curve.
            let program = load_program(&f, feed, g64)?;
            let curve = if g64.is_some() {
                program
            } else {
                first_curve(&program)
            };
            if curve.is_empty() {
                return Err("no NURBS curve".into());
            }
            let (out, _) = smoothed(&curve, &cfg, Policy::Auto);
            let ours = interpolated_time(&out, &cfg)?;
            let opt = accel_only_optimum(&out, &cfg);
            let bound = jerk_aware_bound(&out, &cfg);
            let r = scp_reference(&out, &ref_cfg, step, iterations)?;
            let (first, last) = (r.times[0], *r.times.last().unwrap_or(&f64::NAN));
            let used = sampled_jerk_use(&out, &cfg, &r, SAMPLED_EDGE);
            Ok(format!(
                "{name} | {ours:.3} | {opt:.3} | {bound:.3} | {first:.3} | {last:.3} | {} | {} | {:.4} | {:.4} | {:.4} | {:.4} | {:.3} | {:.3} | {} of {}",
                r.times.len(),
                r.nodes,
                ours / opt,
                ours / bound,
                ours / last,
                last / opt,
                used.largest,
                used.at,
                used.over,
                used.ticks,
            ))
        };
        match run() {
            Ok(line) => println!("{line}"),
            // (The others still run: a linear program the solver cannot
            // finish is a fact about that curve and grid.)
            Err(e) => println!("{name} | failed: {e}"),
        }
    }
}
