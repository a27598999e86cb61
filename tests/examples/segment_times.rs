use gcode::CoreOptions;
use interp_core::feed::speed_limit;
use interp_core::geom::Curve;
use interp_core::path::Path as CorePath;
use interp_core::smooth::Policy;
use interp_core::{InterpConfig, Interpolator, RunState};
use interpd_tests::path_time::{INTERPOLATOR_STACK, smoothed};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let text = std::fs::read_to_string(&args[0]).unwrap();
    let program = gcode::parse(&text).unwrap();
    let blocks = program.to_core_blocks(&CoreOptions::default()).unwrap();
    let cfg = InterpConfig::default();
    let (out, stats) = smoothed(&blocks, &cfg, Policy::Auto);
    eprintln!("{stats:?}");
    let out2 = out.clone();
    let res = std::thread::Builder::new()
        .stack_size(INTERPOLATOR_STACK)
        .spawn(move || {
            let out = out2;
            let p = out[0].path.start_point();
            let mut ip: Box<Interpolator<1024>> =
                Box::new(Interpolator::new(cfg, [p.x, p.y, p.z, 0.0, 0.0, 0.0]).unwrap());
            if std::env::var("TRACE").is_ok() {
                ip.window_mut().trace = Some(|it| {
                    if true {
                        eprintln!("it {:?}", it);
                    }
                });
            }
            let mut next = 0;
            let mut ticks: Vec<(u32, f64)> = Vec::new();
            loop {
                while next < out.len() && ip.push(&out[next]).is_ok() {
                    next += 1;
                }
                if next == out.len() {
                    ip.finish();
                }
                let sp = ip.tick();
                ticks.push((sp.block_id, sp.feed));
                if sp.state == RunState::Done || ticks.len() > 10_000_000 {
                    break;
                }
            }
            eprintln!("stats {:?}", ip.stats());
            eprintln!("plan {:?}", ip.planner().window().totals);
            if let Ok(f) = std::env::var("DUMP") {
                let txt: String = ticks.iter().map(|t| format!("{} {}\n", t.0, t.1)).collect();
                std::fs::write(f, txt).unwrap();
            }
            ticks
        })
        .unwrap()
        .join()
        .unwrap();
    let mut total = 0.0;
    for (bi, b) in out.iter().enumerate() {
        let (jang, jv) = if bi > 0 {
            let prev = &out[bi - 1].path;
            let l = prev.eval(prev.u_end(), 3);
            let r = b.path.eval(b.path.u_start(), 3);
            let (tl, tr) = (l.d1.normalize(), r.d1.normalize());
            (
                tl.dot(&tr).clamp(-1.0, 1.0).acos().to_degrees(),
                interp_core::feed::junction_speed(&l, &r, &cfg),
            )
        } else {
            (0.0, 0.0)
        };
        let n = res.iter().filter(|t| t.0 == b.id).count();
        let vmax = res
            .iter()
            .filter(|t| t.0 == b.id)
            .map(|t| t.1)
            .fold(0.0, f64::max);
        let len = b.path.length();
        let (kind, ncp) = match &b.path {
            CorePath::Nurbs(nb) => ("nurbs", nb.control_count()),
            CorePath::Line(_) => ("line", 2),
            _ => ("arc", 0),
        };
        // Pointwise-limit time.
        let m = 400;
        let (ua, ub) = (b.path.u_start(), b.path.u_end());
        let mut tl = 0.0;
        let mut vmin = f64::INFINITY;
        let mut up = ua;
        for k in 1..=m {
            let u = ua + (ub - ua) * k as f64 / m as f64;
            let ds = b.path.arc_length(up, u);
            let v = speed_limit(&b.path.eval(u, 3), b.feed, b.mrr.as_ref(), &cfg);
            vmin = vmin.min(v);
            tl += ds / v;
            up = u;
        }
        total += n as f64 * cfg.period;
        println!(
            "J {:7.3}deg v {:8.3} | {:5} {:5} ncp {:4} len {:9.4} t {:7.3} tlim {:7.3} vmin {:8.3} vmax {:8.3} feed {:6.1} cum {:7.3}",
            jang,
            jv,
            b.id,
            kind,
            ncp,
            len,
            n as f64 * cfg.period,
            tl,
            vmin,
            vmax,
            b.feed,
            total
        );
    }
}
