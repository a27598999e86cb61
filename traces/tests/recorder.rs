//! The recorder queue: never blocks, never allocates on the producer side,
//! counts what a full queue refused and records it as an event.

use std::io::Cursor;

use interp_core::{RunState, Setpoint};
use traces::Trace;
use traces::messages::{EventKind, LoopTimingMsg};
use traces::recorder::{PushRefused, Record, Recorder};
use traces::writer::{TraceCompression, TraceWriter};

fn setpoint(k: u64) -> Setpoint {
    Setpoint {
        seq: k,
        time: k as f64 * 1e-3,
        axes: [k as f64 * 0.01, 1.0, 2.0, 0.0, 0.0, 0.0],
        feed: 10.0,
        u: k as f64,
        s: k as f64 * 0.01,
        block_id: 1,
        state: RunState::Running,
    }
}

#[global_allocator]
static ALLOCATOR: counting::Counting = counting::Counting;

use alloc_count as counting;

#[test]
fn a_small_queue_overflows_counts_and_records_it_without_allocating() {
    let w = TraceWriter::new(Cursor::new(Vec::new()), TraceCompression::Zstd).expect("writer");
    let (tx, rec) = Recorder::spawn(w, 4).expect("recorder thread");
    const N: u64 = 20_000;
    let (refused, allocations) = counting::count(|| {
        let mut refused = 0u64;
        for k in 1..=N {
            match tx.try_push(Record::Setpoint(setpoint(k))) {
                Ok(()) => {}
                Err(PushRefused::Full(Record::Setpoint(sp))) => {
                    assert_eq!(sp.seq, k, "the refused record comes back");
                    refused += 1;
                }
                Err(other) => panic!("{other:?}"),
            }
            let _ = tx.try_push(Record::LoopTiming(
                LoopTimingMsg {
                    seq: k,
                    queue_depth: 3,
                    ..Default::default()
                },
                k as f64 * 1e-3,
            ));
        }
        refused
    });
    assert_eq!(allocations, 0, "try_push allocated");
    let (_, n) = counting::count(|| std::hint::black_box(Box::new(7u8)));
    assert_eq!(n, 1, "the counter sees allocations");
    let overflows = tx.overflows();
    drop(tx);
    let (sink, report) = rec.join().expect("recorder finishes");
    assert!(
        refused > 0,
        "20,000 pushes into 4 slots while encoding: some must be refused"
    );
    assert_eq!(report.overflows, overflows);
    assert_eq!(report.written.setpoints + refused, N);
    let trace = Trace::from_bytes(&sink.into_inner()).expect("trace reads");
    assert_eq!(trace.setpoints.len() as u64, N - refused);
    assert!(
        trace.setpoints.windows(2).all(|w| w[0].seq < w[1].seq),
        "in order"
    );
    let ev: Vec<_> = trace
        .events
        .iter()
        .filter(|e| e.kind == EventKind::RecorderOverflow)
        .collect();
    assert!(!ev.is_empty(), "overflow recorded as an event");
    assert!(
        ev.windows(2).all(|w| w[0].count < w[1].count),
        "running totals"
    );
    assert_eq!(
        ev.last().and_then(|e| e.count),
        Some(overflows),
        "final total recorded"
    );
}

#[test]
fn a_large_enough_queue_loses_nothing() {
    let w = TraceWriter::new(Cursor::new(Vec::new()), TraceCompression::Lz4).expect("writer");
    let (tx, rec) = Recorder::spawn(w, 1 << 14).expect("recorder thread");
    for k in 1..=5_000 {
        tx.try_push(Record::Setpoint(setpoint(k))).expect("room");
    }
    drop(tx);
    let (sink, report) = rec.join().expect("recorder finishes");
    assert_eq!((report.overflows, report.written.setpoints), (0, 5_000));
    let trace = Trace::from_bytes(&sink.into_inner()).expect("reads");
    assert_eq!(trace.setpoints.len(), 5_000);
    assert_eq!(trace.setpoints[4_321].to_setpoint(), setpoint(4_322));
    assert!(trace.events.is_empty());
}
