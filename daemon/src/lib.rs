//! interpd, the real-time CNC interpolator service, as a library.
//!
//! Per `DESIGN.md`, this crate is the only part of the workspace that owns
//! threads, sockets and files: the tokio control plane, the RT thread that
//! ticks the interpolator and publishes setpoints over iceoryx2, and the
//! recorder thread. The `interpd` binary (`main.rs`) is a thin command line
//! over it; the end-to-end tests drive it too.

/// The setpoint checker (`interp_run::check`), shared with the workspace tests.
pub use interp_run::check;
pub mod client;
pub mod config;
pub mod flags;
pub mod plan;
pub mod program;
pub mod protocol;
pub mod service;
pub mod tools;
