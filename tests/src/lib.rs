//! Workspace-level end-to-end tests for interpd.
//!
//! Per `DESIGN.md`, the tests themselves live in `tests/tests/` (one file per
//! end-to-end scenario, with golden traces beside them) and run with
//! `cargo test --workspace`. This library holds the helpers they share.

pub mod path_time;
