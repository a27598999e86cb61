//! interpd, the real-time CNC interpolator service, as a library.
//!
//! Per `DESIGN.md`, this crate is the only part of the workspace that owns
//! threads, sockets and files: the tokio control plane, the RT thread that
//! ticks the interpolator and publishes setpoints over iceoryx2, and the
//! recorder thread. The `interpd` binary (`main.rs`) is a thin command line
//! over it; the end-to-end tests drive it too.

pub mod check;
pub mod clock;
pub mod control;
pub mod demo;
pub mod demo_plots;
pub mod demo_service;
pub mod histogram;
pub mod jitter;
pub mod plan_gouge;
pub mod plan_raster;
pub mod plan_setup;
pub mod plan_writer;
pub mod program;
pub mod protocol;
pub mod publish;
pub mod replay;
pub mod rt;
pub mod rt_alloc;
pub mod send;
pub mod serve;
pub mod simulate;
pub mod trace_cmd;
pub mod watch;
