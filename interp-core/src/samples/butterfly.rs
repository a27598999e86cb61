//! The LinuxCNC "butterfly" NURBS (`curva_farfalla`), as program data.
//!
//! Source: LinuxCNC `nc_files/nurbs/G6/curva_farfalla`, kept in the corpus as
//! `shared/corpus/nurbs-linuxcnc/g6/curva_farfalla-q1.ngc`: one `G6.2 ... P5 Q1`
//! block (order 5, i.e. degree 4) in the XY plane with `R` weights and `K` knots,
//! programmed at F290 (mm/min; G21 G94) at Z-1. The program's knots are
//! 0×5, 1, 2, …, 46, 47×5; z is 0 here (the block moves in XY only).
//!
//! 51 control points: more than [`crate::nurbs::MAX_CTRL`], so the curve has
//! to go through `split_program_curve` (see [`for_each_block`]).

use crate::nurbs::{SplitError, split_program_curve};
use crate::path::{Block, Path};

/// Degree (G6.2 `P5` is the order, degree + 1).
pub const BUTTERFLY_DEGREE: usize = 4;

/// Control points `[x, y, z]` in mm, in program order (`X`, `Y`; z = 0).
pub const BUTTERFLY_POINTS: [[f64; 3]; 51] = [
    [54.493, 52.139, 0.0],
    [55.507, 52.139, 0.0],
    [56.082, 49.615, 0.0],
    [56.78, 44.971, 0.0],
    [69.575, 51.358, 0.0],
    [77.786, 58.573, 0.0],
    [90.526, 67.081, 0.0],
    [105.973, 63.801, 0.0],
    [100.4, 47.326, 0.0],
    [94.567, 39.913, 0.0],
    [92.369, 30.485, 0.0],
    [83.44, 33.757, 0.0],
    [91.892, 28.509, 0.0],
    [89.444, 20.393, 0.0],
    [83.218, 15.446, 0.0],
    [87.621, 4.83, 0.0],
    [80.945, 9.267, 0.0],
    [79.834, 14.535, 0.0],
    [76.074, 8.522, 0.0],
    [70.183, 12.55, 0.0],
    [64.171, 16.865, 0.0],
    [59.993, 22.122, 0.0],
    [55.68, 36.359, 0.0],
    [56.925, 24.995, 0.0],
    [59.765, 19.828, 0.0],
    [54.493, 14.94, 0.0],
    [49.22, 19.828, 0.0],
    [52.06, 24.994, 0.0],
    [53.305, 36.359, 0.0],
    [48.992, 22.122, 0.0],
    [44.814, 16.865, 0.0],
    [38.802, 12.551, 0.0],
    [32.911, 8.521, 0.0],
    [29.152, 14.535, 0.0],
    [28.04, 9.267, 0.0],
    [21.364, 4.83, 0.0],
    [25.768, 15.447, 0.0],
    [19.539, 20.391, 0.0],
    [17.097, 28.512, 0.0],
    [25.537, 33.75, 0.0],
    [16.602, 30.496, 0.0],
    [14.199, 39.803, 0.0],
    [8.668, 47.408, 0.0],
    [3.0, 63.794, 0.0],
    [18.465, 67.084, 0.0],
    [31.197, 58.572, 0.0],
    [39.411, 51.358, 0.0],
    [52.204, 44.971, 0.0],
    [52.904, 49.614, 0.0],
    [53.478, 52.139, 0.0],
    [54.492, 52.139, 0.0],
];

/// Weights (`R` words), one per control point.
pub const BUTTERFLY_WEIGHTS: [f64; 51] = [
    1.0, 1.0, 1.0, 1.2, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 2.0, 1.0, 1.0, 5.0, 3.0, 1.0, 1.0, 1.0,
    1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 3.0, 5.0, 1.0,
    1.0, 2.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0,
];

/// Knot vector (`K` words): 0 ×5, 1..=46, 47 ×5 (56 = 51 + 4 + 1 knots).
pub const BUTTERFLY_KNOTS: [f64; 56] = [
    0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 10.0, 11.0, 12.0, 13.0,
    14.0, 15.0, 16.0, 17.0, 18.0, 19.0, 20.0, 21.0, 22.0, 23.0, 24.0, 25.0, 26.0, 27.0, 28.0, 29.0,
    30.0, 31.0, 32.0, 33.0, 34.0, 35.0, 36.0, 37.0, 38.0, 39.0, 40.0, 41.0, 42.0, 43.0, 44.0, 45.0,
    46.0, 47.0, 47.0, 47.0, 47.0, 47.0,
];

/// Programmed feed of the LinuxCNC program, mm/min (`F290`).
pub const PROGRAM_FEED_MM_PER_MIN: f64 = 290.0;

/// Start point of the curve (its first control point), mm.
pub const START: [f64; 3] = BUTTERFLY_POINTS[0];

/// Hands the butterfly to `sink` as consecutive NURBS blocks (ids from
/// `first_id`) of at most `max_ctrl` control points, at feed `feed` (mm/s).
pub fn for_each_block<E>(
    feed: f64,
    first_id: u32,
    max_ctrl: usize,
    mut sink: impl FnMut(Block) -> Result<(), E>,
) -> Result<(), SplitError<E>> {
    let mut id = first_id;
    split_program_curve(
        BUTTERFLY_DEGREE,
        &BUTTERFLY_POINTS,
        &BUTTERFLY_WEIGHTS,
        &BUTTERFLY_KNOTS,
        max_ctrl,
        |n| {
            let b = Block::new(id, Path::Nurbs(n), feed);
            id += 1;
            sink(b)
        },
    )
}
