//! Criterion bench: the cost of one `Executor::tick()` in steady running (the
//! plans made beforehand and committed at their ticks, as on the RT thread).
//!
//! Curves: the 3-D rational cubic of `common::rational_cubic` (30 control
//! points, weights in [0.5, 2], ≈ 330 mm) and the LinuxCNC butterfly, both at
//! 100 mm/s with the default configuration, for each `ParamUpdate` mode.
//! `iter_custom` times runs of ticks; when a run reaches `Done` the program is
//! queued again (planning, non-RT) outside the timed region.
//!
//! ```text
//! cargo bench -p interp-run --bench tick
//! ```
//!
//! For the per-tick distribution (p99, max) see `benches/tick_latency.rs`.

#[path = "common/mod.rs"]
mod common;

use core::time::Duration;

use common::{
    MODES, butterfly_blocks, config_with, cubic_blocks, loaded, mode_name, reload, time_ticks,
};
use criterion::{Criterion, criterion_group};
use interp_core::Block;

fn bench_curve(c: &mut Criterion, curve: &str, blocks: &[Block]) {
    let mut group = c.benchmark_group(format!("tick/{curve}"));
    for mode in MODES {
        let cfg = config_with(mode);
        let mut ip = loaded(cfg, blocks);
        group.bench_function(mode_name(mode), |b| {
            b.iter_custom(|iters| time_ticks(iters, &mut ip, |ip| reload(ip, cfg, blocks)));
        });
    }
    group.finish();
}

fn ticks(c: &mut Criterion) {
    bench_curve(c, "rational-cubic", &cubic_blocks(100.0));
    bench_curve(c, "butterfly", &butterfly_blocks(100.0));
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(5))
        .sample_size(50);
    targets = ticks
}
fn main() {
    interp_run::stack::on_interpolator_stack(|| {
        benches();
        Criterion::default().configure_from_args().final_summary();
    });
}
