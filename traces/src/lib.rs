//! MCAP traces of interpd runs.
//!
//! Per `DESIGN.md`, this crate will hold the MCAP channels and schemas (input
//! blocks, config, setpoints, loop timing, events), the recorder that the
//! recorder thread drives (a full queue is counted and reported, never waited
//! on, so the RT thread never blocks), the reader, bit-for-bit replay and plots.
//! Traces must be readable without our code (Python `mcap`, Foxglove).
//!
//! Empty for now: the later record/replay issue fills it.
