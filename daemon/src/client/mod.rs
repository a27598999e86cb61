//! Clients of a running service: the control-plane connection ([`conn`],
//! async and blocking: every client and the end-to-end tests use it), the
//! client that streams a program and follows it over it ([`send`];
//! `interpd send`, `demo` and `jitter` use it), and the setpoint
//! subscriber ([`watch`]).

pub mod conn;
pub mod send;
pub mod watch;
