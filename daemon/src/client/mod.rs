//! Clients of a running service: the control-plane client that streams a
//! program and follows it ([`send`]; `interpd send`, `demo` and `jitter`
//! use it), and the setpoint subscriber ([`watch`]).

pub mod send;
pub mod watch;
