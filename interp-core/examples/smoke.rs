#[path = "../tests/common/mod.rs"]
mod common;
use common::butterfly::*;
use interp_core::*;

fn main() {
    let segs = common::split_segments(
        BUTTERFLY_DEGREE,
        &BUTTERFLY_POINTS,
        &BUTTERFLY_WEIGHTS,
        &BUTTERFLY_KNOTS,
        20,
    );
    let cfg = InterpConfig::default();
    let mut ip: Interpolator =
        Interpolator::new(cfg, [54.493, 52.139, 0.0, 0.0, 0.0, 0.0]).unwrap();
    for (i, s) in segs.iter().enumerate() {
        ip.push(&Block::new(i as u32 + 1, Path::Nurbs(*s), 100.0))
            .unwrap();
    }
    ip.finish();
    let mut n = 0;
    let mut last = Setpoint::default();
    let mut maxa: f64 = 0.0;
    let mut prevf = 0.0;
    let mut maxf: f64 = 0.0;
    loop {
        let before = ip.stats();
        if (2515..2537).contains(&n) {
            let pr = ip.profile();
            let g = pr.index_of(last.s);
            let ab = 2000.0e-6 * 0.95;
            let mut best = (f64::INFINITY, 0i64);
            for k in g + 1..g + 30 {
                let b = interp_core::plan::brake_step(
                    k as f64 * pr.h() - last.s,
                    pr.node(k) * 1e-3,
                    ab,
                );
                if b < best.0 {
                    best = (b, k);
                }
            }
            println!(
                "tick {n} s {:.4} feed {:.3} best brake {:.5} at node {} (v {:.3})",
                last.s,
                last.feed,
                best.0,
                best.1,
                pr.node(best.1)
            );
        }
        let sp = ip.tick();
        n += 1;
        let after = ip.stats();
        if after.brake_overruns > before.brake_overruns && after.brake_overruns < 20 {
            println!(
                "overrun at seq {} s {:.6} feed {:.6} prev {:.6} block {}",
                sp.seq, sp.s, sp.feed, prevf, sp.block_id
            );
            let pr = ip.profile();
            let g = pr.index_of(sp.s);
            for k in g - 2..g + 4 {
                println!(
                    "   g {k} x {:.3} cap {:.3} node {:.3} raw {:.3}",
                    k as f64 * pr.h(),
                    pr.cap(k),
                    pr.node(k),
                    pr.raw_node(k)
                );
            }
        }
        if after.max_newton_iters > before.max_newton_iters {
            println!(
                "newton {} at seq {} s {:.6} feed {:.6} block {}",
                after.max_newton_iters, sp.seq, sp.s, sp.feed, sp.block_id
            );
        }
        if (2515..2522).contains(&n) {
            let seg = &segs[sp.block_id as usize - 1];
            let chord =
                ((sp.axes[0] - last.axes[0]).powi(2) + (sp.axes[1] - last.axes[1]).powi(2)).sqrt();
            let arc = seg.arc_length(last.u, sp.u, 1e-13);
            let p = interp_core::Curve::eval(seg, sp.u, 0).p;
            println!(
                "  chk {n} u {:.9} chord {:.9} arc {:.9} ds {:.9} onc {:.2e}",
                sp.u,
                chord,
                arc,
                sp.s - last.s,
                (p.x - sp.axes[0]).abs()
            );
        }
        maxa = maxa.max((sp.feed - prevf).abs() / cfg.period);
        maxf = maxf.max(sp.feed);
        prevf = sp.feed;
        last = sp;
        if sp.state == RunState::Done || n > 2_000_000 {
            break;
        }
    }
    println!(
        "ticks {n} state {:?} end {:?} s {} maxf {maxf} maxa {maxa} stats {:?}",
        last.state,
        last.axes,
        last.s,
        ip.stats()
    );
}
