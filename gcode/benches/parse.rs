//! Parse throughput on a large G1-heavy program (target ≥ 100 MB/s).
//!
//! `cargo bench -p gcode --bench parse`

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use std::hint::black_box;

/// Size of the generated program, bytes.
const PROGRAM_BYTES: usize = 32 << 20;

fn parse_throughput(c: &mut Criterion) {
    let text = gcode::generate::g1_heavy_program(PROGRAM_BYTES);
    let lines = text.lines().count();
    let mut g = c.benchmark_group("gcode");
    g.throughput(Throughput::Bytes(text.len() as u64));
    g.sample_size(10);
    g.bench_function(
        format!("parse_g1_heavy_{}MB_{lines}_lines", text.len() >> 20),
        |b| b.iter(|| gcode::parse(black_box(&text)).map(|p| p.blocks.len())),
    );
    let program = gcode::parse(&text).expect("the generated program parses");
    g.bench_function("emit_g1_heavy", |b| {
        b.iter(|| gcode::emit(black_box(&program)).len())
    });
    g.finish();
}

criterion_group!(benches, parse_throughput);
criterion_main!(benches);
