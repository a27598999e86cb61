//! # interp-core
//!
//! The real-time heart of interpd: exact evaluation of line, arc and NURBS
//! blocks, the seed paper's feed laws (chord error, constant material removal
//! rate), a look-ahead feed schedule, and the fixed-period [`Interpolator`]
//! whose `tick` never allocates, locks or blocks.
//!
//! Everything is `no_std` and fixed-capacity: queues report `Full` instead of
//! growing. Same blocks + same config give bit-identical setpoints.
#![no_std]
#![warn(missing_docs)]
// iceoryx2's habit: the no_std core must not reach for std/alloc by accident.
#![warn(clippy::std_instead_of_core, clippy::alloc_instead_of_core)]

pub mod config;
pub mod driver;
pub mod feed;
pub mod fit;
pub mod fiveaxis;
pub mod geom;
pub mod interp;
pub mod kinematics;
pub mod lp;
pub mod metrics;
pub mod nurbs;
pub mod path;
pub mod plan;
pub mod prepare;
pub mod samples;
pub mod smooth;
pub mod spline;
pub mod stop;

pub use config::{InterpConfig, ParamUpdate};
pub use driver::{Driver, ExecStatus, PlanSink};
pub use geom::{Curve, Derivs, Vec3};
pub use interp::{Executor, Interpolator, RunState, Setpoint};
pub use nurbs::{Nurbs, NurbsError};
pub use path::{Arc, Blending, Block, Line, Path};
pub use prepare::{BlockPlanner, PlannedBlock};
pub use smooth::Smoother;
