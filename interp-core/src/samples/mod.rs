//! Bundled sample programs for demos, tests and benchmarks.
//!
//! Data only (no I/O): the demo, the benches and the tests all read the same copy.

pub mod butterfly;
pub mod rational_cubic;
