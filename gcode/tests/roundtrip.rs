//! `parse(emit(p)) == p` on random programs, and on the fixture programs;
//! `gcode::Emit` block by block writes what `emit` writes.
//! Numbers are written in shortest round-trip form, so equality is exact.

use gcode::{
    ArcMove, BlockKind, Feed, LinearMove, NurbsMove, Orientation, PathControl, Plane, Point,
    Program, ProgramBlock, RapidMove, Rotary, SpindleRotation, ToolControl, emit, parse,
};
use proptest::prelude::*;

/// Program with line numbers cleared (they are not what emit preserves).
fn without_lines(p: &Program) -> Vec<BlockKind> {
    p.blocks
        .iter()
        .map(|b| match &b.kind {
            BlockKind::Nurbs(n) => BlockKind::Nurbs(NurbsMove {
                first_line: 0,
                ..n.clone()
            }),
            k => k.clone(),
        })
        .collect()
}

fn coord() -> impl Strategy<Value = f64> {
    prop_oneof![
        -1000.0..1000.0f64,
        (-100_000i32..100_000).prop_map(|i| f64::from(i) / 1000.0)
    ]
}

fn point() -> impl Strategy<Value = Point> {
    (coord(), coord(), coord()).prop_map(|(x, y, z)| [x, y, z])
}

fn feed() -> impl Strategy<Value = Feed> {
    prop_oneof![
        4 => (1.0..20_000.0f64).prop_map(Feed::PerMinute),
        1 => (0.01..100.0f64).prop_map(Feed::InverseTime),
    ]
}

/// A B C words a move may give (degrees).
fn rotary_words() -> impl Strategy<Value = [Option<f64>; 3]> {
    prop::array::uniform3(prop_oneof![
        2 => Just(None),
        1 => (-720.0..720.0f64).prop_map(Some),
        1 => (-7200i32..7200).prop_map(|i| Some(f64::from(i) / 10.0)),
    ])
}

/// A G43.5 tool vector a move may give.
fn tool_vector() -> impl Strategy<Value = Option<[f64; 3]>> {
    proptest::option::of(prop::array::uniform3(0.01..1.0f64).prop_flat_map(|v| {
        prop::array::uniform3(any::<bool>())
            .prop_map(move |neg| [0, 1, 2].map(|i| if neg[i] { -v[i] } else { v[i] }))
    }))
}

fn plane() -> impl Strategy<Value = Plane> {
    prop_oneof![Just(Plane::Xy), Just(Plane::Zx), Just(Plane::Yz)]
}

/// One step of a random program, resolved against the current position.
#[derive(Debug, Clone)]
enum Step {
    Rapid(Point, [Option<f64>; 3], Option<[f64; 3]>),
    Linear(Point, Feed, [Option<f64>; 3], Option<[f64; 3]>),
    Mode(u8, Option<u32>),
    Arc {
        plane: Plane,
        radius: f64,
        a0: f64,
        a1: f64,
        rise: f64,
        clockwise: bool,
        turns: u32,
        feed: Feed,
    },
    Nurbs {
        plane: Plane,
        degree: usize,
        pts: Vec<Point>,
        weights: Vec<f64>,
        interior: Vec<f64>,
        feed: Feed,
        rotary: Option<Vec<[f64; 3]>>,
    },
    Dwell(f64),
    Spindle(f64, u8, bool),
    Tool(u32),
    Path(u8, Option<f64>, Option<f64>),
}

fn step() -> impl Strategy<Value = Step> {
    prop_oneof![
        2 => (point(), rotary_words(), tool_vector()).prop_map(|(p, r, v)| Step::Rapid(p, r, v)),
        4 => (point(), feed(), rotary_words(), tool_vector()).prop_map(|(p, f, r, v)| Step::Linear(p, f, r, v)),
        1 => (0u8..3, proptest::option::of(0u32..100)).prop_map(|(m, h)| Step::Mode(m, h)),
        3 => (plane(), 0.1..500.0f64, -7.0..7.0f64, -7.0..7.0f64, prop_oneof![Just(0.0), -50.0..50.0f64], any::<bool>(), 0u32..3, feed())
            .prop_map(|(plane, radius, a0, a1, rise, clockwise, turns, feed)| Step::Arc { plane, radius, a0, a1, rise, clockwise, turns, feed }),
        2 => (plane(), 1usize..=5).prop_flat_map(|(plane, degree)| {
            ((degree + 1)..40usize).prop_flat_map(move |n| {
                (
                    proptest::collection::vec(point(), n),
                    proptest::collection::vec(0.05..20.0f64, n + 1),
                    proptest::collection::btree_set(1u32..100_000, n - degree - 1),
                    feed(),
                    proptest::option::of(proptest::collection::vec(
                        prop::array::uniform3(-400.0..400.0f64),
                        n,
                    )),
                )
                    .prop_map(move |(pts, weights, interior, feed, rotary)| Step::Nurbs {
                        plane,
                        degree,
                        pts,
                        weights,
                        interior: interior.into_iter().map(|k| f64::from(k) / 997.0).collect(),
                        feed,
                        rotary,
                    })
            })
        }),
        1 => (0.0..100.0f64).prop_map(Step::Dwell),
        1 => (0.0..30_000.0f64, 0u8..3, any::<bool>()).prop_map(|(s, r, c)| Step::Spindle(s, r, c)),
        1 => (0u32..1000).prop_map(Step::Tool),
        1 => (0u8..3, proptest::option::of(0.0..1.0f64), proptest::option::of(0.0..1.0f64)).prop_map(|(m, p, q)| Step::Path(m, p, q)),
    ]
}

/// The tool-centre-point state of the program being built, following the
/// parser's rules (docs/gcode.md, "Five-axis").
struct Tcp {
    mode: ToolControl,
    rotary: Rotary,
    vector: Option<[f64; 3]>,
}

impl Tcp {
    fn vector_mode(&self) -> bool {
        matches!(self.mode, ToolControl::ToolVector { .. })
    }

    fn set(&mut self, mode: ToolControl) -> bool {
        if mode == self.mode {
            return false;
        }
        let is_vector = matches!(mode, ToolControl::ToolVector { .. });
        if !(is_vector && self.vector_mode()) {
            self.vector = None;
        }
        if is_vector && !self.vector_mode() {
            self.rotary = [None; 3];
        }
        self.mode = mode;
        true
    }

    fn steady(&self) -> Orientation {
        match self.mode {
            ToolControl::Off => Orientation::Fixed,
            ToolControl::RotaryAngles { .. } => Orientation::TcpRotary {
                start: self.rotary,
                end: self.rotary,
            },
            ToolControl::ToolVector { .. } => Orientation::TcpVector {
                start: self.vector,
                end: self.vector,
            },
        }
    }

    /// A G0/G1 with these A B C words (ignored under G43.5) or this vector
    /// (only under G43.5).
    fn step(&mut self, words: [Option<f64>; 3], vector: Option<[f64; 3]>) -> Orientation {
        if self.vector_mode() {
            let start = self.vector;
            self.vector = vector.or(start);
            return Orientation::TcpVector {
                start,
                end: self.vector,
            };
        }
        let start = self.rotary;
        let mut end = start;
        for i in 0..3 {
            if let Some(v) = words[i] {
                end[i] = Some(v);
            }
        }
        self.to(end)
    }

    fn to(&mut self, end: Rotary) -> Orientation {
        let start = std::mem::replace(&mut self.rotary, end);
        match self.mode {
            ToolControl::Off if start == end => Orientation::Fixed,
            ToolControl::Off => Orientation::Axes { start, end },
            _ => Orientation::TcpRotary { start, end },
        }
    }
}

fn build(steps: &[Step], end: bool) -> Program {
    let mut pos = [0.0; 3];
    let mut tcp = Tcp {
        mode: ToolControl::Off,
        rotary: [Some(0.0); 3],
        vector: None,
    };
    let mut blocks = Vec::new();
    let mut push = |kind| blocks.push(ProgramBlock { line: 0, kind });
    for s in steps {
        match s.clone() {
            Step::Rapid(p, words, vector) => {
                let orientation = tcp.step(words, vector);
                push(BlockKind::Rapid(RapidMove {
                    start: pos,
                    end: p,
                    orientation,
                }));
                pos = p;
            }
            Step::Linear(p, feed, words, vector) => {
                let orientation = tcp.step(words, vector);
                push(BlockKind::Linear(LinearMove {
                    start: pos,
                    end: p,
                    feed,
                    orientation,
                }));
                pos = p;
            }
            Step::Mode(m, offset) => {
                let mode = match m {
                    0 => ToolControl::Off,
                    1 => ToolControl::RotaryAngles { offset },
                    _ => ToolControl::ToolVector { offset },
                };
                if tcp.set(mode) {
                    push(BlockKind::ToolControl(mode));
                }
            }
            Step::Arc {
                plane,
                radius,
                a0,
                a1,
                rise,
                clockwise,
                turns,
                feed,
            } => {
                let (a, b, n) = plane.axes();
                let mut centre = pos;
                centre[a] = pos[a] - radius * a0.cos();
                centre[b] = pos[b] - radius * a0.sin();
                let mut end = centre;
                end[a] = centre[a] + radius * a1.cos();
                end[b] = centre[b] + radius * a1.sin();
                end[n] = pos[n] + rise;
                push(BlockKind::Arc(ArcMove {
                    start: pos,
                    end,
                    centre,
                    plane,
                    clockwise,
                    extra_turns: turns,
                    feed,
                    orientation: tcp.steady(),
                }));
                pos = end;
            }
            Step::Nurbs {
                plane,
                degree,
                mut pts,
                weights,
                interior,
                feed,
                rotary,
            } => {
                pts[0] = pos;
                // Rotary coordinates only where every axis is known (the
                // parser wants an axis on every point or on none).
                let known = tcp.rotary.iter().all(Option::is_some) && !tcp.vector_mode();
                let mut rot: Vec<Rotary> = match rotary.as_ref().filter(|_| known) {
                    Some(r) => r.iter().map(|p| p.map(Some)).collect(),
                    None => vec![tcp.rotary; pts.len()],
                };
                rot[0] = tcp.rotary;
                // Under G43.5 the same values as tool vectors (U V W), the
                // first the current one (else a move to it comes first).
                let mut vecs: Vec<[f64; 3]> = match (tcp.vector_mode(), tcp.vector, &rotary) {
                    (true, Some(_), Some(r)) => r.clone(),
                    _ => Vec::new(),
                };
                if let (Some(first), Some(v)) = (vecs.first_mut(), tcp.vector) {
                    *first = v;
                }
                let (orientation, rot) = match tcp.mode {
                    ToolControl::ToolVector { .. } if !vecs.is_empty() => {
                        let start = tcp.vector;
                        tcp.vector = vecs.last().copied();
                        (
                            Orientation::TcpVector {
                                start,
                                end: tcp.vector,
                            },
                            Vec::new(),
                        )
                    }
                    ToolControl::ToolVector { .. } => (tcp.steady(), Vec::new()),
                    ToolControl::Off if rot.iter().all(|r| *r == rot[0]) => {
                        (Orientation::Fixed, Vec::new())
                    }
                    _ => {
                        let first = tcp.rotary;
                        tcp.to(rot[rot.len() - 1]);
                        let o = match tcp.mode {
                            ToolControl::Off => Orientation::Axes {
                                start: first,
                                end: tcp.rotary,
                            },
                            _ => Orientation::TcpRotary {
                                start: first,
                                end: tcp.rotary,
                            },
                        };
                        (o, rot)
                    }
                };
                let mut knots = vec![0.0; degree + 1];
                knots.extend(interior);
                knots.extend(vec![interior_end(&knots); degree + 1]);
                let weights = weights[..pts.len()].to_vec();
                pos = pts[pts.len() - 1];
                push(BlockKind::Nurbs(NurbsMove {
                    first_line: 0,
                    plane,
                    degree,
                    points: pts,
                    weights,
                    knots,
                    feed,
                    orientation,
                    rotary: rot,
                    tool_vectors: vecs,
                }));
            }
            Step::Dwell(s) => push(BlockKind::Dwell { seconds: s }),
            Step::Spindle(speed, r, css) => push(BlockKind::Spindle {
                speed,
                rotation: [
                    SpindleRotation::Clockwise,
                    SpindleRotation::CounterClockwise,
                    SpindleRotation::Stopped,
                ][r as usize],
                constant_surface_speed: css,
            }),
            Step::Tool(t) => push(BlockKind::ToolChange { tool: t }),
            Step::Path(m, p, q) => push(BlockKind::PathControl(match m {
                0 => PathControl::ExactPath,
                1 => PathControl::ExactStop,
                _ => PathControl::Blend {
                    path_tolerance: p.or(q.map(|_| 0.5)),
                    naive_cam_tolerance: q,
                },
            })),
        }
    }
    if end {
        push(BlockKind::ProgramEnd);
    }
    Program { blocks }
}

/// A knot past every interior knot (the end of the clamped vector).
fn interior_end(knots: &[f64]) -> f64 {
    knots.last().copied().unwrap_or(0.0).max(0.0) + 1.0
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    #[test]
    fn emitted_programs_parse_back_to_the_same_blocks(steps in proptest::collection::vec(step(), 0..25), end in any::<bool>()) {
        let program = build(&steps, end);
        let text = emit(&program);
        let back = parse(&text).map_err(|e| TestCaseError::fail(format!("{e}\n{text}")))?;
        prop_assert_eq!(without_lines(&back), without_lines(&program), "{}", text);
        // Block by block, taken after each: the same text.
        let mut e = gcode::Emit::default();
        let mut streamed = e.take();
        for b in &program.blocks {
            e.block(&b.kind);
            streamed += &e.take();
        }
        prop_assert_eq!(streamed, text);
    }

    /// Arbitrary text never panics the parser (the fuzzer does this at length).
    #[test]
    fn random_text_never_panics(text in "[GgMmXYZABCHIJKRPQLFST#\\[\\]()=+*/ .;%0-9\n-]{0,200}") {
        if let Ok(p) = parse(&text) {
            let _ = p.to_core_blocks(&gcode::CoreOptions::default());
            let _ = parse(&emit(&p));
        }
    }
}

#[test]
fn fixture_programs_round_trip() {
    for text in [
        include_str!("programs/curva_farfalla-q1.ngc"),
        include_str!("programs/curva_mazatrol-q1-xy-yz-zx.ngc"),
        include_str!("programs/trident-xy-yz-zx.ngc"),
        include_str!("programs/cam-arcs.ngc"),
        include_str!("programs/cam-inch-incremental.ngc"),
        include_str!("programs/cam-params.ngc"),
        include_str!("programs/cam-pocket.ngc"),
    ] {
        let p = parse(text).unwrap();
        let text2 = emit(&p);
        let q = parse(&text2).unwrap_or_else(|e| panic!("{e}\n{text2}"));
        assert_eq!(without_lines(&q), without_lines(&p), "{text2}");
    }
}

#[test]
fn emitted_g6_2_reads_as_linuxcnc_does() {
    let p = parse(include_str!("programs/curva_farfalla-q1.ngc")).unwrap();
    let text = emit(&p);
    // Order 5: five trailing knot lines, P5 on the first G6.2 line.
    assert_eq!(text.matches("G6.2 K47\n").count(), 5);
    assert!(
        text.contains("G6.2 X54.493 Y52.139 Z-1 R1 K0 P5 Q1 F290\n"),
        "{text}"
    );
}
