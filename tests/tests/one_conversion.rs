//! One conversion of G-code into interpolator blocks: `gcode`'s own
//! `to_core_blocks` (the tests, the examples) and the JSON block form that
//! `interpd simulate`, `send`, the service and `replay` run
//! (`traces::Program::from_gcode`, through JSON text and back, then cut by
//! the program's pipeline) give the same blocks bit for bit: rapids, feeds
//! per minute and in inverse time, arcs and helices, inches, NURBS longer
//! than a piece, moves of zero length, path control modes.

use gcode::CoreOptions;
use interp_core::nurbs::MAX_CTRL;
use interp_core::{Block, InterpConfig};

/// A program with every kind of move the conversion decides something for.
fn program() -> String {
    let mut t = String::from(
        "G21 G90 G17\nG0 X1 Y2 Z3\nG1 X10 F600\nG1 X10\nG2 X20 Y2 I5 J0\n\
         G93 G1 X25 Y7 F3\nG3 X25 Y7 Z-1 I-2.5 J0 P1 F0.5\nG94 G64 P0.01\nG1 X30 F1500\n\
         G61.1 G1 Y10\nG20 G1 X1.5 F40\nG21 G61\n",
    );
    // A degree-3 NURBS of 47 control points from the machine's position
    // (60 mm along X), more than one piece, with weights, in inverse time.
    let (n, p) = (47usize, 3usize);
    t.push_str("G93 F0.25 G6.2 P4 X38.1 Y10 Z-1 R1 K0\n");
    for i in 1..n {
        let x = 38.1 + 60.0 * i as f64 / (n - 1) as f64;
        let y = 10.0 + 4.0 * (0.4 * i as f64).sin();
        let w = 1.0 + 0.3 * (0.7 * i as f64).cos();
        let k = if i < p + 1 {
            0.0
        } else {
            (i - p) as f64 / (n - p) as f64
        };
        t.push_str(&format!("X{x:.6} Y{y:.6} R{w:.6} K{k:.6}\n"));
    }
    for _ in 0..=p {
        t.push_str("G6.2 K1\n");
    }
    t.push_str("G94 G0 X0 Y0 Z10\nM2\n");
    t
}

/// A block without its id (the two number them differently: `to_core_blocks`
/// by source line, a pipeline from 1).
fn unnumbered(b: &Block) -> Block {
    Block { id: 0, ..*b }
}

#[test]
fn to_core_blocks_and_the_json_block_form_give_the_same_blocks_bit_for_bit() {
    let cfg = InterpConfig::default();
    let opts = CoreOptions::for_config(&cfg);
    let g = gcode::parse(&program()).expect("parses");
    let direct: Vec<Block> = g
        .to_core_blocks(&opts)
        .expect("converts")
        .iter()
        .map(unnumbered)
        .collect();
    // What a trace records and `send` streams: JSON text, every bit.
    let json =
        serde_json::to_string(&traces::Program::from_gcode(&g, &opts, [0.0; 6]).expect("converts"))
            .expect("serialises");
    let program: traces::Program = serde_json::from_str(&json).expect("reads back");
    let expanded = program.expand(MAX_CTRL, 1).expect("expands");
    let cut: Vec<Block> = expanded.segments().map(unnumbered).collect();
    assert!(direct.len() >= 12, "{} blocks", direct.len());
    // The NURBS is more than one piece; the zero-length G1 X10 is dropped.
    assert!(
        direct
            .iter()
            .filter(|b| matches!(b.path, interp_core::path::Path::Nurbs(_)))
            .count()
            >= 2
    );
    assert_eq!(program.blocks.len() + 1, expanded.segments().count());
    assert_eq!(direct.len(), cut.len());
    for (k, (a, b)) in direct.iter().zip(&cut).enumerate() {
        assert_eq!(a, b, "block {k}");
    }
    // Rapids at the machine's path-speed limit; G93 as a feed like any other.
    assert_eq!(direct[0].feed, cfg.max_path_speed);
    assert_eq!(direct.last().unwrap().feed, cfg.max_path_speed);
}
