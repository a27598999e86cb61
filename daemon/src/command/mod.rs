//! One thin file per subcommand: it wires the parsed flags to the library
//! and prints what the command reports.

pub mod demo;
pub mod jitter;
pub mod plan;
pub mod replay;
pub mod send;
pub mod serve;
pub mod simulate;
pub mod trace;
pub mod watch;
