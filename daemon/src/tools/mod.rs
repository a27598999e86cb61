//! Tools around the service: the demo ([`demo`], its plots and its run
//! through the service), the jitter measurement ([`jitter`]) and the
//! clock-less simulation ([`simulate`]).

pub mod demo;
pub mod demo_plots;
pub mod demo_service;
pub mod jitter;
pub mod simulate;
