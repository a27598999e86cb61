//! Recorder throughput and the encoding choice.
//!
//! `cargo bench -p traces --bench recorder`. Setpoints come from a real run
//! (the golden NURBS+MRR program). Groups:
//! - `encode`: one setpoint as JSON (what we write) vs protobuf wire format
//!   (hand-encoded here only to measure the alternative);
//! - `write`: `TraceWriter::setpoint` into memory, zstd / lz4 / none, and the
//!   same MCAP layout with protobuf payloads;
//! - `recorder`: the whole path: `try_push` into the bounded queue, the
//!   recorder thread encodes, compresses and writes.
//!
//! Sizes (bytes per setpoint) are printed once at start.

use std::collections::BTreeMap;
use std::hint::black_box;
use std::io::Cursor;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use interp_core::Setpoint;
use traces::Program;
use traces::messages::SetpointMsg;
use traces::recorder::{Record, Recorder};
use traces::sim::{self, SimItem, SimSettings};
use traces::writer::{CHUNK_SIZE, TraceCompression, TraceWriter};

/// Compression and level pairs measured (0: the codec's default, zstd 3).
const LEVELS: [(TraceCompression, u32); 4] = [
    (TraceCompression::Zstd, 1),
    (TraceCompression::Zstd, 0),
    (TraceCompression::Lz4, 0),
    (TraceCompression::None, 0),
];

fn setpoints() -> Vec<Setpoint> {
    let program: Program =
        serde_json::from_str(include_str!("../../tests/golden/nurbs_mrr.json")).expect("program");
    let config = sim::config_for(
        &program,
        Default::default(),
        &SimSettings::default(),
        "bench",
        "nurbs_mrr",
    );
    // The bench's main thread has the system's 8 MiB, too little to build a
    // run in an unoptimised build.
    let out = interp_run::stack::on_interpolator_stack(move || {
        let mut out = Vec::new();
        sim::run(&config, &program, 3600.0, |i| {
            if let SimItem::Tick { setpoint, .. } = i {
                out.push(*setpoint);
            }
            Ok::<(), ()>(())
        })
        .expect("simulates");
        out
    });
    // Sixteen copies (seq and time continued) so that per-trace costs (schemas,
    // compressor set-up, summary) are amortised as over a real run.
    let n = out.len() as u64;
    let ts = 1e-3;
    (0..16u64)
        .flat_map(|r| {
            out.iter().map(move |sp| Setpoint {
                seq: sp.seq + r * n,
                time: sp.time + (r * n) as f64 * ts,
                ..*sp
            })
        })
        .collect()
}

fn varint(buf: &mut Vec<u8>, mut v: u64) {
    while v >= 0x80 {
        buf.push((v as u8) | 0x80);
        v >>= 7;
    }
    buf.push(v as u8);
}

/// Protobuf wire format of a setpoint (fields 1..13 in `SetpointMsg` order).
fn protobuf(buf: &mut Vec<u8>, sp: &Setpoint) {
    buf.clear();
    varint(buf, 1 << 3);
    varint(buf, sp.seq);
    let doubles = [
        sp.time, sp.axes[0], sp.axes[1], sp.axes[2], sp.axes[3], sp.axes[4], sp.axes[5], sp.feed,
        sp.u, sp.s,
    ];
    for (k, d) in doubles.iter().enumerate() {
        // proto3 omits zero scalars
        if *d != 0.0 {
            varint(buf, ((k as u64 + 2) << 3) | 1);
            buf.extend_from_slice(&d.to_le_bytes());
        }
    }
    varint(buf, 12 << 3);
    varint(buf, u64::from(sp.block_id));
    varint(buf, 13 << 3);
    varint(buf, sp.state as u64);
}

fn write_json(sps: &[Setpoint], c: TraceCompression, level: u32) -> usize {
    let mut w = TraceWriter::with_level(Cursor::new(Vec::new()), c, level).expect("writer");
    for sp in sps {
        w.setpoint(sp).expect("write");
    }
    w.finish().expect("finish").0.into_inner().len()
}

fn write_protobuf(sps: &[Setpoint]) -> usize {
    let mut w = mcap::WriteOptions::new()
        .compression(Some(mcap::Compression::Zstd))
        .compression_level(1)
        .chunk_size(Some(CHUNK_SIZE))
        .compression_threads(0)
        .create(Cursor::new(Vec::new()))
        .expect("writer");
    let schema = w
        .add_schema("interpd.Setpoint", "protobuf", b"")
        .expect("schema");
    let ch = w
        .add_channel(schema, "/interpd/setpoints", "protobuf", &BTreeMap::new())
        .expect("channel");
    let mut buf = Vec::with_capacity(256);
    for (k, sp) in sps.iter().enumerate() {
        protobuf(&mut buf, sp);
        let t = (sp.time * 1e9) as u64;
        let h = mcap::records::MessageHeader {
            channel_id: ch,
            sequence: k as u32,
            log_time: t,
            publish_time: t,
        };
        w.write_to_known_channel(&h, &buf).expect("write");
    }
    w.finish().expect("finish");
    w.into_inner().into_inner().len()
}

fn bench(c: &mut Criterion) {
    let sps = setpoints();
    let n = sps.len();
    let json_bytes: usize = sps
        .iter()
        .map(|s| serde_json::to_vec(&SetpointMsg::from(s)).unwrap().len())
        .sum();
    let mut pb = Vec::new();
    let pb_bytes: usize = sps
        .iter()
        .map(|s| {
            protobuf(&mut pb, s);
            pb.len()
        })
        .sum();
    eprintln!(
        "{n} setpoints; payload bytes/setpoint: JSON {:.1}, protobuf {:.1}",
        json_bytes as f64 / n as f64,
        pb_bytes as f64 / n as f64
    );
    for (cmp, level) in LEVELS {
        eprintln!(
            "file bytes/setpoint, JSON {cmp:?} level {level}: {:.1}",
            write_json(&sps, cmp, level) as f64 / n as f64
        );
    }
    eprintln!(
        "file bytes/setpoint, protobuf Zstd level 1: {:.1}",
        write_protobuf(&sps) as f64 / n as f64
    );

    let mut g = c.benchmark_group("encode");
    g.throughput(Throughput::Elements(n as u64));
    g.bench_function("json", |b| {
        let mut buf = Vec::with_capacity(512);
        b.iter(|| {
            for sp in &sps {
                buf.clear();
                serde_json::to_writer(&mut buf, &SetpointMsg::from(sp)).unwrap();
                black_box(&buf);
            }
        })
    });
    g.bench_function("protobuf", |b| {
        let mut buf = Vec::with_capacity(512);
        b.iter(|| {
            for sp in &sps {
                protobuf(&mut buf, sp);
                black_box(&buf);
            }
        })
    });
    g.finish();

    let mut g = c.benchmark_group("write");
    g.throughput(Throughput::Elements(n as u64));
    for (cmp, level) in LEVELS {
        g.bench_with_input(
            BenchmarkId::new("json", format!("{cmp:?}-{level}")),
            &(cmp, level),
            |b, &(cmp, level)| b.iter(|| black_box(write_json(&sps, cmp, level))),
        );
    }
    g.bench_function("protobuf/Zstd-1", |b| {
        b.iter(|| black_box(write_protobuf(&sps)))
    });
    g.finish();

    let mut g = c.benchmark_group("recorder");
    g.throughput(Throughput::Elements(n as u64));
    g.bench_function("try_push+thread/Zstd", |b| {
        b.iter(|| {
            let w = TraceWriter::new(Cursor::new(Vec::new()), TraceCompression::Zstd).unwrap();
            let (tx, rec) = Recorder::spawn(w, 1 << 13).unwrap();
            let mut spins = 0u64;
            for sp in &sps {
                // The bench must not lose setpoints: retry (counted) instead of dropping.
                let mut r = Record::Setpoint(*sp);
                loop {
                    match tx.try_push(r) {
                        Ok(()) => break,
                        Err(traces::recorder::PushRefused::Full(back)) => {
                            spins += 1;
                            r = back;
                            std::thread::yield_now();
                        }
                        Err(e) => panic!("{e:?}"),
                    }
                }
            }
            drop(tx);
            let (_, report) = rec.join().unwrap();
            assert_eq!(report.written.setpoints as usize, n);
            black_box(spins)
        })
    });
    g.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10).measurement_time(std::time::Duration::from_secs(3)).warm_up_time(std::time::Duration::from_secs(1));
    targets = bench
}
criterion_main!(benches);
