//! `parse_from`: a program read with the machine somewhere else than the
//! origin (the daemon converts each program from where the machine is).

use gcode::{BlockKind, parse, parse_from};

fn moves(text: &str, start: [f64; 3]) -> Vec<([f64; 3], [f64; 3])> {
    parse_from(text, start)
        .expect("parses")
        .blocks
        .iter()
        .filter_map(|b| match &b.kind {
            BlockKind::Linear(m) => Some((m.start, m.end)),
            BlockKind::Rapid(m) => Some((m.start, m.end)),
            _ => None,
        })
        .collect()
}

#[test]
fn relative_moves_start_where_the_machine_is() {
    let m = moves("G91 G1 X5 F600\nG1 Y5\n", [20.0, 20.0, 0.0]);
    assert_eq!(
        m,
        vec![
            ([20.0, 20.0, 0.0], [25.0, 20.0, 0.0]),
            ([25.0, 20.0, 0.0], [25.0, 25.0, 0.0])
        ]
    );
}

#[test]
fn a_first_move_to_the_origin_or_to_where_the_machine_is() {
    let m = moves("G1 X0 Y0 F600\nG1 X10 Y0\n", [20.0, 20.0, 0.0]);
    assert_eq!(m[0], ([20.0, 20.0, 0.0], [0.0, 0.0, 0.0]));
    assert_eq!(m[1], ([0.0, 0.0, 0.0], [10.0, 0.0, 0.0]));
    // A move to where the machine already is has no length.
    let m = moves("G1 X20 Y20 F600\n", [20.0, 20.0, 0.0]);
    assert_eq!(m, vec![([20.0, 20.0, 0.0], [20.0, 20.0, 0.0])]);
}

#[test]
fn parse_is_parse_from_the_origin() {
    let text = "G0 X1 Y2 Z3\nG91 G1 X1 F100\nG2 X2 Y0 I1 J0\n";
    assert_eq!(parse(text), parse_from(text, [0.0; 3]));
}
