//! The message format: JSON round trips bit for bit, the schemas describe
//! exactly the fields written, and the JSON block form reports bad input by
//! block and field.

use interp_core::{RunState, Setpoint};
use traces::blocks::{BlockErrorKind, Program};
use traces::messages::{Channel, EventKind, EventMsg, LoopTimingMsg, SetpointMsg};

/// Deterministic xorshift64* so that a failure reproduces.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }
    fn f64(&mut self) -> f64 {
        loop {
            let v = f64::from_bits(self.next());
            if v.is_finite() {
                return v;
            }
        }
    }
}

fn bits(m: &SetpointMsg) -> Vec<u64> {
    let sp = m.to_setpoint();
    let mut v = vec![
        sp.seq,
        sp.time.to_bits(),
        sp.feed.to_bits(),
        sp.u.to_bits(),
        sp.s.to_bits(),
    ];
    v.extend(sp.axes.iter().map(|a| a.to_bits()));
    v.push(u64::from(sp.block_id));
    v.push(sp.state as u64);
    v
}

#[test]
fn setpoints_round_trip_through_json_bit_for_bit() {
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    let specials = [
        0.0,
        -0.0,
        f64::MIN_POSITIVE,
        5e-324,
        f64::MAX,
        -f64::MAX,
        0.1,
        1.0 / 3.0,
    ];
    for k in 0..20_000u64 {
        let pick = |rng: &mut Rng| {
            if rng.next().is_multiple_of(4) {
                specials[(rng.next() % specials.len() as u64) as usize]
            } else {
                rng.f64()
            }
        };
        let sp = Setpoint {
            seq: rng.next(),
            time: pick(&mut rng),
            axes: [(); 6].map(|()| pick(&mut rng)),
            feed: pick(&mut rng),
            u: pick(&mut rng),
            s: pick(&mut rng),
            block_id: rng.next() as u32,
            state: [
                RunState::Idle,
                RunState::Running,
                RunState::Done,
                RunState::Fault,
            ][(k % 4) as usize],
        };
        let m = SetpointMsg::from(&sp);
        let text = serde_json::to_string(&m).expect("serialises");
        let back: SetpointMsg = serde_json::from_str(&text).expect("parses");
        assert_eq!(bits(&m), bits(&back), "{text}");
    }
}

/// Top-level keys a message serialises to must be the schema's properties.
fn keys_match_schema(ch: Channel, value: serde_json::Value) {
    let schema: serde_json::Value =
        serde_json::from_str(&ch.schema_json()).expect("schema is JSON");
    let props = schema["properties"]
        .as_object()
        .unwrap_or_else(|| panic!("{ch:?}: {schema}"));
    let obj = value.as_object().expect("object");
    let mut a: Vec<_> = obj.keys().cloned().collect();
    let mut b: Vec<_> = props.keys().cloned().collect();
    a.sort();
    b.sort();
    assert_eq!(a, b, "{ch:?}");
    assert_eq!(schema["type"], "object", "{ch:?}");
}

#[test]
fn schemas_describe_exactly_the_fields_written() {
    // With a machine's tool tip and axis, every field is written.
    let sp = SetpointMsg {
        tip: Some([1.0, 2.0, 3.0]),
        tool_axis: Some([0.0, 0.0, 1.0]),
        ..SetpointMsg::from(&Setpoint::default())
    };
    keys_match_schema(Channel::Setpoints, serde_json::to_value(sp).expect("json"));
    let t = LoopTimingMsg {
        wake_lateness_ns: Some(3),
        tick_compute_ns: Some(4),
        ..Default::default()
    };
    keys_match_schema(Channel::LoopTiming, serde_json::to_value(t).expect("json"));
    let e = EventMsg {
        count: Some(1),
        value: Some(0.5),
        detail: Some("x".into()),
        ..EventMsg::new(EventKind::RecorderOverflow, 1, 0.001)
    };
    let v = serde_json::to_value(&e).expect("json");
    assert_eq!(v["kind"], "recorder-overflow");
    keys_match_schema(Channel::Events, v);
    let program: Program =
        serde_json::from_str(include_str!("../../tests/golden/line_arc.json")).expect("program");
    let config =
        traces::sim::config_for(&program, Default::default(), &Default::default(), "t", "s");
    keys_match_schema(
        Channel::Config,
        serde_json::to_value(&config).expect("json"),
    );
    // Every config key is InterpConfig's kebab-case serialisation, so new core
    // fields appear without touching this crate.
    let interp = serde_json::to_value(config.interp).expect("json");
    assert!(interp.get("max-path-accel").is_some() && interp.get("chord-tolerance").is_some());
    for ch in Channel::ALL {
        assert_eq!(Channel::from_topic(ch.topic()), Some(ch));
        assert!(ch.topic().starts_with("/interpd/"));
    }
}

#[test]
fn butterfly_program_splits_into_contiguous_segments() {
    let program: Program =
        serde_json::from_str(include_str!("../programs/butterfly.json")).expect("program");
    let e = program.expand(20, 1).expect("expands");
    assert_eq!(e.blocks.len(), 1);
    let info = &e.blocks[0].info;
    assert!(
        info.len() >= 3,
        "51 control points in pieces of 20: {info:?}"
    );
    assert_eq!(
        info.iter().map(|s| s.block_id).collect::<Vec<_>>(),
        (1..=info.len() as u32).collect::<Vec<_>>()
    );
    for w in info.windows(2) {
        assert_eq!(w[0].u_end, w[1].u_start, "pieces meet");
    }
    assert!(info.iter().all(|s| s.control_points <= 20));
    let total: f64 = info.iter().map(|s| s.length).sum();
    // Splitting is exact: lengths add up to the whole curve's (one piece of 32 max).
    let whole = program.expand(32, 1).expect("expands");
    let total32: f64 = whole.blocks[0].info.iter().map(|s| s.length).sum();
    assert!(
        (total - total32).abs() <= 1e-9 * total,
        "{total} vs {total32}"
    );
    assert_eq!(program.start_point(), [54.493, 52.139, 0.0]);
}

fn expand_err(text: &str) -> traces::blocks::BlockError {
    let p: Program = serde_json::from_str(text).expect("parses");
    p.expand(20, 1).expect_err("refused")
}

#[test]
fn bad_blocks_are_named_by_index_line_and_field() {
    let e = expand_err(
        r#"{"blocks":[{"kind":"line","feed":600,"end":[1,0,0]},{"kind":"line","feed":0,"source_line":7,"end":[2,0,0]}]}"#,
    );
    assert_eq!((e.index, e.source_line), (1, Some(7)));
    assert_eq!(e.kind, BlockErrorKind::Feed(0.0));
    assert!(e.to_string().contains("block 1 (source line 7)"), "{e}");
    let e = expand_err(r#"{"blocks":[{"kind":"line","feed":600,"end":[0,0,0]}]}"#);
    assert!(
        matches!(e.kind, BlockErrorKind::Path(_)),
        "zero length: {e}"
    );
    let e = expand_err(r#"{"blocks":[{"kind":"arc","feed":600,"end":[3,0,0],"centre":[1,0,0]}]}"#);
    assert!(e.to_string().contains("radius"), "{e}");
    let e = expand_err(
        r#"{"start":[1,1,0],"blocks":[{"kind":"nurbs","feed":600,"degree":1,"points":[[0,0,0],[1,0,0]],"knots":[0,0,1,1]}]}"#,
    );
    assert!(
        matches!(e.kind, BlockErrorKind::Discontinuous { .. }),
        "{e}"
    );
    let e = expand_err(
        r#"{"blocks":[{"kind":"nurbs","feed":600,"degree":2,"points":[[0,0,0],[1,0,0],[2,1,0]],"knots":[0,0,0,1,1]}]}"#,
    );
    assert!(
        matches!(e.kind, BlockErrorKind::Nurbs(_)),
        "knot count: {e}"
    );
    let e = expand_err(
        r#"{"blocks":[{"kind":"line","feed":600,"end":[1,0,0],"mrr":{"tool_radius":-1,"depth_of_cut":0.1,"tool_side":{"direction":[0,0,1]}}}]}"#,
    );
    assert_eq!(e.kind, BlockErrorKind::Mrr("tool_radius"));
    // Malformed JSON names the place; unknown kinds and fields are refused.
    let err = serde_json::from_str::<Program>(r#"{"blocks":[{"kind":"spline","feed":1}]}"#)
        .expect_err("unknown kind");
    assert!(err.to_string().contains("spline"), "{err}");
    let err =
        serde_json::from_str::<Program>(r#"{"blocks":[], "speed": 3}"#).expect_err("unknown field");
    assert!(err.to_string().contains("speed"), "{err}");
    let err = serde_json::from_str::<Program>(
        "{\"blocks\":[\n{\"kind\":\"line\",\"feed\":1,\"end\":[1,2]}]}",
    )
    .expect_err("short point");
    assert!(err.to_string().contains("line 2"), "{err}");
}
