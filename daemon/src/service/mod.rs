//! The service (`interpd serve`): the RT thread and its clock, allocator
//! pool and timing histograms ([`rt`], [`clock`], [`rt_alloc`],
//! [`histogram`]), the control plane ([`control`]), the setpoint publisher
//! ([`publish`]), and the wiring of them with the recorder thread
//! ([`serve`]).

pub mod clock;
pub mod control;
pub mod histogram;
pub mod publish;
pub mod rt;
pub mod rt_alloc;
pub mod sequencer;
pub mod serve;
