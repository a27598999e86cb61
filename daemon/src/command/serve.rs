//! `interpd serve`: starts the service, prints where it listens, waits for
//! SIGINT/SIGTERM and prints the summary.

use anyhow::Result;
use interpd::service::histogram::Percentiles;
use interpd::service::serve::{ServeOptions, ServeSummary, start};

/// `interpd serve`.
pub fn run(args: &ServeOptions) -> Result<()> {
    let svc = start(args, args.interp_config()?, true, None)?;
    println!("interpd: listening on tcp {}", svc.addr);
    if let Some(p) = &svc.socket {
        println!("interpd: listening on unix {}", p.display());
    }
    println!(
        "interpd: publishing setpoints on iceoryx2 service {:?} every {} us",
        args.service, args.rt.period_us
    );
    use std::io::Write;
    std::io::stdout().flush().ok();
    let summary = svc.join()?;
    if args.json {
        println!("{}", serde_json::to_string(&summary)?);
    } else {
        print_summary(&summary);
    }
    Ok(())
}

/// The summary as text.
pub fn print_summary(s: &ServeSummary) {
    println!(
        "interpd: stopped: {} samples published, {} ticks, final state {}, at {:?}",
        s.published, s.ticks, s.final_state, s.final_position
    );
    let show = |name: &str, p: &Option<Percentiles>| {
        if let Some(p) = p {
            println!(
                "  {name:<28} p50 {:8.1} µs  p99 {:8.1} µs  p99.9 {:8.1} µs  max {:8.1} µs  ({} samples)",
                p.p50, p.p99, p.p999, p.max, p.samples
            );
        }
    };
    show("wake lateness", &s.lateness_us);
    show("tick+publish", &s.tick_publish_us);
    show("commit+tick+publish", &s.tick_publish_with_push_us);
    println!(
        "  overruns {}, planner late {}, recorder drops {}, recorded {}, publish failures {}, RT pool {} served / {} fallbacks",
        s.overruns,
        s.planner_late,
        s.recorder_drops,
        s.recorded,
        s.publish_failures,
        s.rt_pool_served,
        s.rt_pool_fallbacks
    );
    if s.rt_pool_fallbacks > 0 {
        println!(
            "  warning: {} RT-thread allocations reached the system allocator ({} with the pool empty, largest {} bytes)",
            s.rt_pool_fallbacks, s.rt_pool_exhausted, s.rt_pool_largest_fallback
        );
    }
    if let Some(t) = &s.trace {
        println!(
            "  trace {}: {} messages, {} records dropped (queue full)",
            t.display(),
            s.trace_messages,
            s.trace_overflows
        );
    }
    for w in &s.scheduling_warnings {
        println!("  warning: {w}");
    }
}
