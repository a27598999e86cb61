//! The data behind seed 004's Figs. 7–12, as CSV on stdout.
//!
//! One curve is interpolated twice with Ts = 1 ms, ER = 1 µm, F = 100 mm/s
//! (6000 mm/min) and the default limits (250 mm/s, 2000 mm/s²):
//!
//! * `er`  — the chord-error law only (eq. 16–17), as the seed's thin lines;
//! * `mrr` — chord-error law plus the constant-MRR law (eq. 23) with a 5 mm
//!   tool radius, 1 mm depth of cut, tool left of the path in the XY plane
//!   (`ToolSide::LeftOfPath([0, 0, 1])`), as the seed's thick lines.
//!
//! Sign convention (`interp_core::feed::signed_curvature`): the signed
//! curvature is `+|k|` where the centre of curvature lies on the tool side
//! (concave: the MRR law slows down) and `−|k|` where it lies opposite
//! (convex: the law would allow more than F, but F caps it).
//!
//! One row per tick: `law, seq, time, u, s, x, y, z, curvature,
//! signed_curvature, feed, accel, chord_error, relative_mrr, block`, where
//!
//! * `curvature` = `|C'×C''|/|C'|³` at the setpoint's `u` on its block (Fig. 7);
//! * `feed` = commanded path speed of the tick, mm/s (Fig. 8);
//! * `accel` = tangential acceleration `Δfeed/Ts`, mm/s² (Fig. 9);
//! * `chord_error` = largest distance between the curve and the chord from
//!   the previous setpoint to this one (`metrics::chord_error_between`); when
//!   the tick crosses a block joint it is the max over the pieces (Fig. 10);
//! * `relative_mrr` = `V·(1 + k·(rt − δ/2))/F0` (`feed::relative_mrr`), with
//!   the same tool parameters for both runs so they compare (Fig. 12).
//!
//! The setpoints lie on the curve (the interpolator evaluates it exactly), so
//! the seed's contouring error (Fig. 11, which includes a servo model) is not
//! reproduced; the chord error is the geometric part of it.
//!
//! The curve is the LinuxCNC butterfly (XY) by default; `--cubic` uses the
//! benches' 3-D rational cubic instead (`benches/common/mod.rs`), closer to the
//! seed's 3-D Fig. 6. `--feed V` sets F in mm/s. `--summary` prints, per law,
//! the max chord error, max/min feed, max |accel| and the relative MRR range
//! instead of the rows (min feed and MRR over the ticks at least 5 mm from
//! either end, i.e. outside the start and stop ramps). The relative MRR model
//! (eq. 20–23) only holds where `1 + k·(rt − δ/2) > 0`; on the butterfly's
//! tight convex turns (radius below 4.5 mm) it does not, and the CSV column
//! goes negative there. The summary leaves those ticks out of the MRR range
//! and counts them (`ticks_beyond_mrr_model`); `rel_mrr_*_concave` is the
//! range over the concave ticks, where the MRR law acts, and
//! `concave_within_1pct` the share of those ticks whose relative MRR is
//! within 1 % of 1.
//!
//! ```text
//! cargo run --release -p interp-run --example seed_figures > figs.csv
//! cargo run --release -p interp-run --example seed_figures -- --summary
//! cargo run --release -p interp-run --example seed_figures -- --cubic --summary
//! ```

#[path = "../benches/common/mod.rs"]
mod common;

use common::{butterfly_blocks, cubic_blocks, loaded};
use interp_core::feed::{relative_mrr, signed_curvature};
use interp_core::metrics::chord_error_between;
use interp_core::path::{MrrParams, ToolSide};
use interp_core::{Block, Curve, InterpConfig, RunState, Setpoint, Vec3};

/// Tool and cut of the MRR law (and of the MRR column of both runs).
const TOOL: MrrParams = MrrParams {
    tool_radius: 5.0,
    depth_of_cut: 1.0,
    tool_side: ToolSide::LeftOfPath([0.0, 0.0, 1.0]),
};

/// Samples of the chord-error search per tick.
const CHORD_SAMPLES: usize = 16;

/// Ticks closer than this to either end (mm) are left out of the summary's
/// min feed and MRR range (start and stop ramps).
const END_MARGIN: f64 = 5.0;

/// One tick's derived quantities.
struct Row {
    sp: Setpoint,
    curvature: f64,
    signed: f64,
    accel: f64,
    chord_error: f64,
    rel_mrr: f64,
}

fn block_of(blocks: &[Block], id: u32) -> &Block {
    blocks
        .iter()
        .find(|b| b.id == id)
        .expect("setpoint names a queued block")
}

/// Chord error of the tick from `a` to `b`, over every block piece between them.
fn tick_chord_error(blocks: &[Block], a: &Setpoint, b: &Setpoint) -> f64 {
    let pa = Vec3::new(a.axes[0], a.axes[1], a.axes[2]);
    let pb = Vec3::new(b.axes[0], b.axes[1], b.axes[2]);
    if a.block_id == b.block_id {
        let path = &block_of(blocks, b.block_id).path;
        return chord_error_between(path, a.u, b.u, pa, pb, CHORD_SAMPLES);
    }
    // Blocks are numbered consecutively: every block from a's to b's.
    let mut e: f64 = 0.0;
    for id in a.block_id..=b.block_id {
        let path = &block_of(blocks, id).path;
        let u0 = if id == a.block_id {
            a.u
        } else {
            path.u_start()
        };
        let u1 = if id == b.block_id { b.u } else { path.u_end() };
        e = e.max(chord_error_between(path, u0, u1, pa, pb, CHORD_SAMPLES));
    }
    e
}

fn run(blocks: &[Block], cfg: InterpConfig) -> Vec<Row> {
    let mut ip = loaded(cfg, blocks);
    let first = &blocks[0];
    let start = first.path.start_point();
    let mut prev = Setpoint {
        axes: [start.x, start.y, start.z, 0.0, 0.0, 0.0],
        u: first.path.u_start(),
        block_id: first.id,
        ..Setpoint::default()
    };
    let mut rows = Vec::new();
    loop {
        let sp = ip.tick();
        let block = block_of(blocks, sp.block_id);
        let d = block.path.eval(sp.u, 2);
        let signed = signed_curvature(&d, TOOL.tool_side);
        let chord_error = if sp.seq == 1 && sp.feed == 0.0 {
            0.0
        } else {
            tick_chord_error(blocks, &prev, &sp)
        };
        rows.push(Row {
            sp,
            curvature: d.curvature(),
            signed,
            accel: (sp.feed - prev.feed) / cfg.period,
            chord_error,
            rel_mrr: relative_mrr(
                sp.feed,
                block.feed,
                signed,
                TOOL.tool_radius,
                TOOL.depth_of_cut,
            ),
        });
        prev = sp;
        if sp.state == RunState::Done {
            return rows;
        }
        assert!(rows.len() < 10_000_000, "run does not end");
    }
}

fn print_rows(law: &str, rows: &[Row]) {
    for r in rows {
        let sp = &r.sp;
        println!(
            "{law},{},{:.3},{:.12},{:.9},{:.9},{:.9},{:.9},{:.9e},{:.9e},{:.9},{:.6},{:.6e},{:.9},{}",
            sp.seq,
            sp.time,
            sp.u,
            sp.s,
            sp.axes[0],
            sp.axes[1],
            sp.axes[2],
            r.curvature,
            r.signed,
            sp.feed,
            r.accel,
            r.chord_error,
            r.rel_mrr,
            sp.block_id
        );
    }
}

fn print_summary(law: &str, rows: &[Row]) {
    let length = rows.last().map_or(0.0, |r| r.sp.s);
    let interior = || {
        rows.iter()
            .filter(move |r| r.sp.s >= END_MARGIN && r.sp.s <= length - END_MARGIN)
    };
    let worst = rows
        .iter()
        .max_by(|a, b| a.chord_error.total_cmp(&b.chord_error))
        .expect("rows");
    let max_feed = rows.iter().map(|r| r.sp.feed).fold(0.0, f64::max);
    let min_feed = interior().map(|r| r.sp.feed).fold(f64::INFINITY, f64::min);
    let max_acc = rows.iter().map(|r| r.accel.abs()).fold(0.0, f64::max);
    // Eq. 20–23 only mean something while 1 + k·(rt − δ/2) > 0 (a convex
    // radius larger than rt − δ/2); count the ticks beyond and leave them out.
    let valid = |r: &Row| 1.0 + r.signed * (TOOL.tool_radius - 0.5 * TOOL.depth_of_cut) > 0.0;
    let invalid = interior().filter(|r| !valid(r)).count();
    let mrr_min = interior()
        .filter(|r| valid(r))
        .map(|r| r.rel_mrr)
        .fold(f64::INFINITY, f64::min);
    let mrr_max = interior()
        .filter(|r| valid(r))
        .map(|r| r.rel_mrr)
        .fold(-f64::INFINITY, f64::max);
    let concave = || interior().filter(|r| r.signed > 0.0);
    let cc_min = concave().map(|r| r.rel_mrr).fold(f64::INFINITY, f64::min);
    let cc_max = concave().map(|r| r.rel_mrr).fold(-f64::INFINITY, f64::max);
    let (cc_n, cc_near) = concave().fold((0usize, 0usize), |(n, k), r| {
        (n + 1, k + usize::from((r.rel_mrr - 1.0).abs() <= 0.01))
    });
    let cc_frac = cc_near as f64 / cc_n.max(1) as f64;
    let max_k = rows.iter().map(|r| r.curvature).fold(0.0, f64::max);
    let time = rows.last().map_or(0.0, |r| r.sp.time);
    println!(
        "{law},{},{time:.3},{length:.4},{max_k:.5},{:.4e},{},{max_feed:.4},{min_feed:.4},\
         {max_acc:.2},{mrr_min:.5},{mrr_max:.5},{invalid},{cc_min:.5},{cc_max:.5},{cc_frac:.3}",
        rows.len(),
        worst.chord_error,
        worst.sp.seq
    );
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let summary = args.iter().any(|a| a == "--summary");
    let cubic = args.iter().any(|a| a == "--cubic");
    let feed: f64 = args
        .iter()
        .position(|a| a == "--feed")
        .and_then(|i| args.get(i + 1))
        .and_then(|v| v.parse().ok())
        .unwrap_or(100.0);
    let er_blocks = if cubic {
        cubic_blocks(feed)
    } else {
        butterfly_blocks(feed)
    };
    let mrr_blocks: Vec<Block> = er_blocks
        .iter()
        .map(|b| Block {
            mrr: Some(TOOL),
            ..*b
        })
        .collect();
    let cfg = InterpConfig {
        chord_tolerance: 0.001,
        period: 0.001,
        ..InterpConfig::default()
    };
    let er = run(&er_blocks, cfg);
    let mrr = run(&mrr_blocks, cfg);
    if summary {
        println!(
            "law,ticks,time_s,length_mm,max_curvature,max_chord_error_mm,at_seq,max_feed,\
             min_feed_interior,max_abs_accel,rel_mrr_min,rel_mrr_max,\
             ticks_beyond_mrr_model,rel_mrr_min_concave,rel_mrr_max_concave,\
             concave_within_1pct"
        );
        print_summary("er", &er);
        print_summary("mrr", &mrr);
    } else {
        println!(
            "law,seq,time,u,s,x,y,z,curvature,signed_curvature,feed,accel,chord_error,\
             relative_mrr,block"
        );
        print_rows("er", &er);
        print_rows("mrr", &mrr);
    }
}
