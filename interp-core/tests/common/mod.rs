//! Shared data and helpers for interp-core's integration tests and benches.
#![allow(dead_code)]

pub use interp_core::samples::butterfly;

use interp_core::nurbs::{Nurbs, split_program_curve};
use interp_core::path::Block;

/// Cuts a program curve into segments of at most `max_ctrl` control points
/// (`max_ctrl <= MAX_CTRL - 6`) with `split_program_curve` and collects them.
///
/// Panics if the curve is refused.
pub fn split_segments(
    degree: usize,
    points: &[[f64; 3]],
    weights: &[f64],
    knots: &[f64],
    max_ctrl: usize,
) -> Vec<Nurbs> {
    let mut segments = Vec::new();
    split_program_curve::<core::convert::Infallible>(
        degree,
        points,
        weights,
        knots,
        max_ctrl,
        |segment| {
            segments.push(segment);
            Ok(())
        },
    )
    .unwrap_or_else(|e| panic!("split_program_curve refused the curve: {e:?}"));
    segments
}

/// The LinuxCNC butterfly ([`butterfly`]) as consecutive segments of at most
/// `max_ctrl` control points.
pub fn butterfly_segments(max_ctrl: usize) -> Vec<Nurbs> {
    split_segments(
        butterfly::BUTTERFLY_DEGREE,
        &butterfly::BUTTERFLY_POINTS,
        &butterfly::BUTTERFLY_WEIGHTS,
        &butterfly::BUTTERFLY_KNOTS,
        max_ctrl,
    )
}

/// The butterfly as consecutive NURBS blocks (ids from 1), cut like
/// [`butterfly_segments`]`(20)`, at `feed` mm/s.
pub fn butterfly_blocks(feed: f64) -> Vec<Block> {
    let mut blocks = Vec::new();
    butterfly::for_each_block::<core::convert::Infallible>(feed, 1, 20, |b| {
        blocks.push(b);
        Ok(())
    })
    .unwrap_or_else(|e| panic!("the butterfly did not split: {e:?}"));
    blocks
}
