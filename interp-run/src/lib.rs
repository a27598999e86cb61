//! Runs a program through the interpolator with no clock, the one way every
//! caller does: plan with an [`interp_core::Driver`] for an
//! [`interp_core::Executor`], keep each step the executor was given with the
//! tick it preceded, tick.
//!
//! - [`Run`] is the planning side: an executor and the driver that plans for
//!   it, fed blocks in the order `simulate` feeds them (each block pushed as
//!   soon as it is taken, ticking while it must wait for room; the program's
//!   end after the last one; ticks until `Done`). Without recording it gives
//!   the setpoints of [`interp_core::Interpolator`] bit for bit; with
//!   recording ([`Run::recording`]) it also keeps every [`Step`] (a plan to
//!   commit, a hold, a resume, an abort) with the tick it precedes.
//! - [`Replay`] is the real-time side: a fresh executor given those steps at
//!   their ticks, then ticked. Its ticks cost what the service's RT thread's
//!   cost (no planning in them) and give the same setpoints bit for bit.
//! - [`plan`] is the two together for a whole program: `interpd demo` and
//!   the tick benches time the replay of a program planned before the loop.
//!
//! `traces::sim` (`interpd simulate` and `replay`) drives a [`Run`]; the
//! service's planning thread sends the same [`Op`]s to its RT thread.
//!
//! [`check`] is the setpoint checker every run is held to (demo, jitter's
//! subscriber, the tests); [`stack`] the thread stack sizes every caller
//! builds one on.
//!
//! `interp-core` stays `#![no_std]` without an allocator; this crate keeps
//! the steps in `Vec`s and boxes, so it is the std side of the loop.
#![forbid(unsafe_code)]

pub mod check;
pub mod stack;

use core::convert::Infallible;

use interp_core::config::ConfigError;
use interp_core::interp::{DEFAULT_QUEUE, OverrideError, PushError, Stats};
use interp_core::{Block, Driver, Executor, InterpConfig, PlannedBlock, RunState, Setpoint, Vec3};

/// What the planning side gives an executor before a tick.
#[derive(Clone, Debug)]
pub enum Op {
    /// [`Executor::commit`]: a plan the driver made.
    Commit(Box<PlannedBlock>),
    /// [`Executor::feed_hold`].
    Hold,
    /// [`Executor::resume`].
    Resume,
    /// [`Executor::abort`].
    Abort,
}

impl Op {
    /// Gives `exec` this step. A refused commit is returned: the planning
    /// side's executor was offered the same plan in the same state, so it
    /// was refused there too.
    pub fn apply<const Q: usize>(&self, exec: &mut Executor<Q>) -> Result<(), PushError> {
        match self {
            Op::Commit(plan) => return exec.commit(plan),
            Op::Hold => exec.feed_hold(),
            Op::Resume => exec.resume(),
            Op::Abort => exec.abort(),
        }
        Ok(())
    }
}

/// An [`Op`] and the tick it precedes.
#[derive(Clone, Debug)]
pub struct Step {
    /// Ticks the executor has done when it is given this step.
    pub at: u64,
    /// What it is given.
    pub op: Op,
}

/// Why a [`Run`] stopped before its program did.
#[derive(Debug, thiserror::Error)]
pub enum RunError<E = Infallible> {
    /// The interpolator refused a block (not for room: for what it is).
    #[error("{0}")]
    Push(PushError),
    /// The run needed more ticks than its limit.
    #[error("the run did not end within {ticks} ticks")]
    Timeout {
        /// The limit, ticks.
        ticks: u64,
    },
    /// The caller's tick hook failed.
    #[error(transparent)]
    Hook(E),
}

/// How a [`Run::push_waiting`] ended without an error.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Pushed {
    /// The block is queued.
    Queued,
    /// The interpolator faulted while the block waited for room.
    Faulted,
}

/// The planning side: an [`Executor`] and the [`Driver`] that plans for it
/// (see the crate docs). About 5.6 MB with the default queue: boxed inside.
/// A clone goes on exactly as the original would (to try what an operator's
/// command would do at this tick).
#[derive(Clone, Debug)]
pub struct Run<const Q: usize = DEFAULT_QUEUE> {
    exec: Box<Executor<Q>>,
    driver: Box<Driver>,
    /// Steps given to `exec`, kept when recording.
    steps: Option<Vec<Step>>,
    /// Plan buffers to reuse (see [`Self::recycle`]).
    spare: Vec<Box<PlannedBlock>>,
    /// The run stops with [`RunError::Timeout`] before tick number `limit + 1`.
    limit: u64,
}

impl<const Q: usize> Run<Q> {
    /// A run at rest at `position` (X Y Z A B C), with no tick limit and no
    /// recording.
    pub fn new(cfg: InterpConfig, position: [f64; 6]) -> Result<Self, ConfigError> {
        let exec = Box::new(Executor::new(cfg, position)?);
        let p = Vec3::new(position[0], position[1], position[2]);
        Ok(Run {
            exec,
            driver: Box::new(Driver::new(cfg, p, 0.0)?),
            steps: None,
            spare: Vec::new(),
            limit: u64::MAX,
        })
    }

    /// Keeps every step given to the executor from now on (see
    /// [`Self::take_steps`]).
    pub fn recording(mut self) -> Self {
        self.steps = Some(Vec::new());
        self
    }

    /// [`Self::push_waiting`] and [`Self::run_to_end`] give up with
    /// [`RunError::Timeout`] rather than run tick number `ticks + 1`.
    pub fn with_tick_limit(mut self, ticks: u64) -> Self {
        self.limit = ticks;
        self
    }

    /// The executor.
    pub fn executor(&self) -> &Executor<Q> {
        &self.exec
    }
    /// The driver.
    pub fn driver(&self) -> &Driver {
        &self.driver
    }
    /// The driver, to set its diagnostics.
    pub fn driver_mut(&mut self) -> &mut Driver {
        &mut self.driver
    }
    /// Current state.
    pub fn state(&self) -> RunState {
        self.exec.state()
    }
    /// Ticks run.
    pub fn ticks(&self) -> u64 {
        self.exec.stats().ticks
    }
    /// The executor's counters.
    pub fn stats(&self) -> Stats {
        self.exec.stats()
    }

    /// The steps recorded since the last call, in order.
    pub fn take_steps(&mut self) -> Vec<Step> {
        self.steps.as_mut().map(std::mem::take).unwrap_or_default()
    }

    /// Gives back a plan buffer of a recorded step, to hold a later plan.
    pub fn recycle(&mut self, plan: Box<PlannedBlock>) {
        self.spare.push(plan);
    }

    /// Runs `f` with a sink that records every plan the driver offers the
    /// executor (when recording).
    fn planning<R>(
        &mut self,
        f: impl FnOnce(&mut Driver, &mut Executor<Q>, &mut dyn FnMut(&PlannedBlock)) -> R,
    ) -> R {
        let at = self.exec.stats().ticks;
        match self.steps.as_mut() {
            None => f(&mut self.driver, &mut self.exec, &mut |_| {}),
            Some(steps) => {
                let spare = &mut self.spare;
                let mut sink = |p: &PlannedBlock| {
                    let plan = match spare.pop() {
                        Some(mut b) => {
                            (*b).clone_from(p);
                            b
                        }
                        None => Box::new(p.clone()),
                    };
                    steps.push(Step {
                        at,
                        op: Op::Commit(plan),
                    });
                };
                f(&mut self.driver, &mut self.exec, &mut sink)
            }
        }
    }

    fn record(&mut self, op: Op) {
        let at = self.exec.stats().ticks;
        if let Some(steps) = self.steps.as_mut() {
            steps.push(Step { at, op });
        }
    }

    /// Queues a block: the due parts of a long block first, then its plan
    /// (see [`Driver::push_into`]). All or nothing.
    pub fn push(&mut self, block: &Block) -> Result<(), PushError> {
        self.planning(|d, e, sink| d.push_into(e, block, sink))
    }

    /// Plans the due parts of a long block, as [`Self::push`] does before
    /// its block (see [`Driver::parts_into`]): what a push that had to wait
    /// for room planned.
    pub fn plan_parts(&mut self) {
        self.planning(|d, e, sink| d.parts_into(e, sink));
    }

    /// Whether steps were recorded since the last [`Self::take_steps`].
    pub fn has_steps(&self) -> bool {
        self.steps.as_ref().is_some_and(|s| !s.is_empty())
    }

    /// The program ends with what is pushed (see [`Driver::finish_into`]).
    pub fn finish(&mut self) {
        self.planning(|d, e, sink| d.finish_into(e, sink));
    }

    /// Feed hold, planned through the look-ahead (see
    /// [`Driver::feed_hold_into`]).
    pub fn feed_hold(&mut self) {
        self.record(Op::Hold);
        self.planning(|d, e, sink| d.feed_hold_into(e, sink));
    }

    /// Leaves a feed hold: the speed is planned again, through the hold's
    /// rest point while the machine still brakes fast, else from where it
    /// rests (see [`Driver::resume_into`]).
    pub fn resume(&mut self) {
        self.record(Op::Resume);
        self.planning(|d, e, sink| d.resume_into(e, sink));
    }

    /// Abort, planned through the look-ahead (see [`Driver::abort_into`]);
    /// the driver follows once the machine is idle.
    pub fn abort(&mut self) {
        self.record(Op::Abort);
        self.planning(|d, e, sink| d.abort_into(e, sink));
    }

    /// Sets the feed override (see [`Driver::set_feed_override_into`]).
    pub fn set_feed_override(&mut self, value: f64) -> Result<(), OverrideError> {
        self.planning(|d, e, sink| d.set_feed_override_into(e, value, sink))
    }

    /// Commits whatever the driver has due (see [`Driver::drive`]), without
    /// ticking.
    pub fn drive(&mut self) {
        self.planning(|d, e, sink| d.drive(e, sink));
    }

    /// One period: what the driver has due, then the executor's tick.
    pub fn tick(&mut self) -> Setpoint {
        self.drive();
        self.exec.tick()
    }

    /// Ticks once, within the tick limit: `before` first (an operator's
    /// commands), then the tick, whose setpoint `hook` sees.
    fn tick_hooked<E>(
        &mut self,
        before: &mut impl FnMut(&mut Self) -> Result<(), E>,
        hook: &mut impl FnMut(&Setpoint, &Executor<Q>) -> Result<(), E>,
    ) -> Result<Setpoint, RunError<E>> {
        let ticks = self.ticks();
        if ticks >= self.limit {
            return Err(RunError::Timeout { ticks });
        }
        before(self).map_err(RunError::Hook)?;
        let sp = self.tick();
        hook(&sp, &self.exec).map_err(RunError::Hook)?;
        Ok(sp)
    }

    /// Queues `block` as `simulate` does: while it must wait for room (the
    /// queue, the look-ahead, the parts of a long block) and something is
    /// queued to make room, ticks and tries again. `hook` sees every tick.
    pub fn push_waiting<E>(
        &mut self,
        block: &Block,
        mut hook: impl FnMut(&Setpoint, &Executor<Q>) -> Result<(), E>,
    ) -> Result<Pushed, RunError<E>> {
        self.push_waiting_with(block, &mut |_: &mut Self| Ok(()), &mut hook)
    }

    fn push_waiting_with<E>(
        &mut self,
        block: &Block,
        before: &mut impl FnMut(&mut Self) -> Result<(), E>,
        hook: &mut impl FnMut(&Setpoint, &Executor<Q>) -> Result<(), E>,
    ) -> Result<Pushed, RunError<E>> {
        loop {
            match self.push(block) {
                Ok(()) => return Ok(Pushed::Queued),
                Err(e) if e.is_wait() && self.exec.queued_segments() > 0 => {
                    if self.tick_hooked(before, hook)?.state == RunState::Fault {
                        return Ok(Pushed::Faulted);
                    }
                }
                Err(e) => return Err(RunError::Push(e)),
            }
        }
    }

    /// Ends the program (unless it faulted) and ticks until `Done` or
    /// `Fault`; returns that state. `hook` sees every tick.
    pub fn run_to_end<E>(
        &mut self,
        mut hook: impl FnMut(&Setpoint, &Executor<Q>) -> Result<(), E>,
    ) -> Result<RunState, RunError<E>> {
        self.run_to_end_with(&mut |_: &mut Self| Ok(()), &mut hook)
    }

    fn run_to_end_with<E>(
        &mut self,
        before: &mut impl FnMut(&mut Self) -> Result<(), E>,
        hook: &mut impl FnMut(&Setpoint, &Executor<Q>) -> Result<(), E>,
    ) -> Result<RunState, RunError<E>> {
        if self.state() != RunState::Fault {
            self.finish();
        }
        loop {
            let state = self.state();
            if matches!(state, RunState::Done | RunState::Fault) {
                return Ok(state);
            }
            self.tick_hooked(before, hook)?;
        }
    }

    /// `blocks` pushed in order (see [`Self::push_waiting`]), then
    /// [`Self::run_to_end`]; returns the last state (`Fault` as soon as it
    /// faults). An error names the index of the block it came with (`None`:
    /// after the last one).
    pub fn run_program<E>(
        &mut self,
        blocks: &[Block],
        hook: impl FnMut(&Setpoint, &Executor<Q>) -> Result<(), E>,
    ) -> Result<RunState, (Option<usize>, RunError<E>)> {
        self.run_program_with(blocks, |_| Ok(()), hook)
    }

    /// [`Self::run_program`] with `before` called before every tick: an
    /// operator's commands (override, hold, resume) at the ticks they come.
    pub fn run_program_with<E>(
        &mut self,
        blocks: &[Block],
        mut before: impl FnMut(&mut Self) -> Result<(), E>,
        mut hook: impl FnMut(&Setpoint, &Executor<Q>) -> Result<(), E>,
    ) -> Result<RunState, (Option<usize>, RunError<E>)> {
        for (k, b) in blocks.iter().enumerate() {
            match self.push_waiting_with(b, &mut before, &mut hook) {
                Ok(Pushed::Queued) => {}
                Ok(Pushed::Faulted) => return Ok(RunState::Fault),
                Err(e) => return Err((Some(k), e)),
            }
        }
        self.run_to_end_with(&mut before, &mut hook)
            .map_err(|e| (None, e))
    }
}

/// A program planned to its end: the steps a [`Run`] gave its executor,
/// given to a fresh executor at the same ticks (see the crate docs).
#[derive(Debug)]
pub struct Replay<const Q: usize = DEFAULT_QUEUE> {
    cfg: InterpConfig,
    start: [f64; 6],
    exec: Box<Executor<Q>>,
    steps: Vec<Step>,
    next: usize,
}

impl<const Q: usize> Replay<Q> {
    /// An executor at rest at `start` that will be given `steps` (from a
    /// [`Run`] that started there with `cfg`).
    pub fn new(cfg: InterpConfig, start: [f64; 6], steps: Vec<Step>) -> Result<Self, ConfigError> {
        Ok(Replay {
            cfg,
            start,
            exec: Box::new(Executor::new(cfg, start)?),
            steps,
            next: 0,
        })
    }

    /// One period: the steps for it, then the executor's tick. Allocates
    /// nothing.
    pub fn tick(&mut self) -> Setpoint {
        let t = self.exec.stats().ticks;
        while let Some(step) = self.steps.get(self.next)
            && step.at <= t
        {
            // A refusal was the planning side's too (see `Op::apply`).
            let _ = step.op.apply(&mut self.exec);
            self.next += 1;
        }
        self.exec.tick()
    }

    /// Back to the start, to run the same steps again (allocates nothing).
    pub fn rewind(&mut self) {
        *self.exec = Executor::new(self.cfg, self.start).expect("the configuration was valid");
        self.next = 0;
    }

    /// The executor.
    pub fn executor(&self) -> &Executor<Q> {
        &self.exec
    }
    /// The executor's counters.
    pub fn stats(&self) -> Stats {
        self.exec.stats()
    }
    /// The steps, in order.
    pub fn steps(&self) -> &[Step] {
        &self.steps
    }
    /// The configuration.
    pub fn config(&self) -> &InterpConfig {
        &self.cfg
    }
    /// Where it starts (X Y Z A B C).
    pub fn start(&self) -> [f64; 6] {
        self.start
    }
}

/// Why [`plan`] failed.
#[derive(Debug, thiserror::Error)]
pub enum PlanError {
    /// The configuration was refused.
    #[error("configuration refused: {0}")]
    Config(ConfigError),
    /// The run stopped at block `index` (`None`: after the last block).
    #[error("{}: {error}", index.map_or_else(|| "the program's end".to_owned(), |i| format!("block {i}")))]
    Run {
        /// Position of the block in the program.
        index: Option<usize>,
        /// Why.
        error: RunError,
    },
}

/// Plans `blocks` from `start` to the end of the program as `simulate` runs
/// them (see [`Run::run_program`], at most `max_ticks`), and returns the
/// replay of it. A program that faults is planned up to its fault: its
/// replay faults at the same tick.
pub fn plan<const Q: usize>(
    cfg: InterpConfig,
    start: [f64; 6],
    blocks: &[Block],
    max_ticks: u64,
) -> Result<Replay<Q>, PlanError> {
    let mut run = Run::<Q>::new(cfg, start)
        .map_err(PlanError::Config)?
        .recording()
        .with_tick_limit(max_ticks);
    run.run_program(blocks, |_, _| Ok(()))
        .map_err(|(index, error)| PlanError::Run { index, error })?;
    Replay::new(cfg, start, run.take_steps()).map_err(PlanError::Config)
}

#[cfg(test)]
mod tests {
    use super::*;
    use interp_core::{Line, Path};

    /// A square of 10 mm lines, a diagonal, then 40 zig-zag lines of 0.5 mm,
    /// at `feed` mm/s.
    fn square(feed: f64) -> Vec<Block> {
        let mut p = vec![
            [0.0, 0.0],
            [10.0, 0.0],
            [10.0, 10.0],
            [0.0, 10.0],
            [0.0, 0.0],
            [5.0, 5.0],
        ];
        for i in 0..40 {
            let y = if i % 2 == 0 { 5.1 } else { 5.0 };
            p.push([5.0 + 0.5 * (i + 1) as f64, y]);
        }
        p.windows(2)
            .enumerate()
            .map(|(i, w)| {
                let a = Vec3::new(w[0][0], w[0][1], 0.0);
                let b = Vec3::new(w[1][0], w[1][1], 0.0);
                Block::new(i as u32 + 1, Path::Line(Line::new(a, b).unwrap()), feed)
            })
            .collect()
    }

    fn bits(sp: &Setpoint) -> ([u64; 6], u64, u64, RunState) {
        (
            sp.axes.map(f64::to_bits),
            sp.feed.to_bits(),
            sp.s.to_bits(),
            sp.state,
        )
    }

    /// Setpoints of the interpolator itself, pushed as `simulate` pushes.
    fn interpolator(cfg: InterpConfig, blocks: &[Block]) -> Vec<Setpoint> {
        let mut ip = Box::new(interp_core::Interpolator::<16>::new(cfg, [0.0; 6]).unwrap());
        let mut out = Vec::new();
        for b in blocks {
            loop {
                match ip.push(b) {
                    Ok(()) => break,
                    Err(e) if e.is_wait() => out.push(ip.tick()),
                    Err(e) => panic!("{e}"),
                }
            }
        }
        ip.finish();
        loop {
            let sp = ip.tick();
            out.push(sp);
            if sp.state == RunState::Done {
                return out;
            }
        }
    }

    #[test]
    fn a_run_and_its_replay_give_the_interpolators_setpoints_bit_for_bit() {
        // A queue of 16 makes the zig-zag's blocks wait for room.
        let cfg = InterpConfig::default();
        let blocks = square(200.0);
        let reference = interpolator(cfg, &blocks);
        let mut run = Run::<16>::new(cfg, [0.0; 6]).unwrap().recording();
        let mut live = Vec::new();
        let last = run
            .run_program::<Infallible>(&blocks, |sp, _| {
                live.push(*sp);
                Ok(())
            })
            .unwrap();
        assert_eq!(last, RunState::Done);
        let steps = run.take_steps();
        assert!(steps.len() >= blocks.len(), "{} steps", steps.len());
        // Blocks waited for room: plans were made after the machine moved.
        assert!(steps.iter().any(|s| s.at > 100), "every plan at the start");
        let mut replay = Replay::<16>::new(cfg, [0.0; 6], steps).unwrap();
        let replayed: Vec<_> = (0..live.len()).map(|_| replay.tick()).collect();
        assert_eq!(live.len(), reference.len());
        for (k, ((a, b), c)) in reference.iter().zip(&live).zip(&replayed).enumerate() {
            assert_eq!(bits(a), bits(b), "run, tick {k}");
            assert_eq!(bits(a), bits(c), "replay, tick {k}");
        }
        // Rewound, the same again.
        replay.rewind();
        let again: Vec<_> = (0..live.len()).map(|_| replay.tick()).collect();
        assert!(again.iter().zip(&replayed).all(|(a, b)| bits(a) == bits(b)));
    }

    #[test]
    fn holds_resumes_and_aborts_are_replayed_at_their_ticks() {
        let cfg = InterpConfig::default();
        let blocks = square(200.0);
        let mut run = Run::<16>::new(cfg, [0.0; 6]).unwrap().recording();
        let mut live = Vec::new();
        for b in &blocks[..3] {
            run.push(b).unwrap();
        }
        // (The abort brakes from about 100 mm/s: 0.1 s and more.)
        for t in 0..500 {
            match t {
                50 => run.feed_hold(),
                150 => run.resume(),
                300 => run.abort(),
                _ => {}
            }
            live.push(run.tick());
        }
        assert_eq!(live.last().unwrap().state, RunState::Idle);
        let steps = run.take_steps();
        assert!(steps.iter().any(|s| s.at == 50 && matches!(s.op, Op::Hold)));
        assert!(
            steps
                .iter()
                .any(|s| s.at == 300 && matches!(s.op, Op::Abort))
        );
        let mut replay = Replay::<16>::new(cfg, [0.0; 6], steps).unwrap();
        for (k, sp) in live.iter().enumerate() {
            assert_eq!(bits(sp), bits(&replay.tick()), "tick {k}");
        }
    }

    #[test]
    fn the_tick_limit_and_a_refused_block_are_errors_naming_the_block() {
        let cfg = InterpConfig::default();
        let mut blocks = square(200.0);
        let e = plan::<16>(cfg, [0.0; 6], &blocks, 10).unwrap_err();
        assert!(
            matches!(
                e,
                PlanError::Run {
                    error: RunError::Timeout { ticks: 10 },
                    ..
                }
            ),
            "{e}"
        );
        // A block that does not start where the last one ended.
        let gap = Line::new(Vec3::new(1.0, 1.0, 0.0), Vec3::new(2.0, 1.0, 0.0)).unwrap();
        blocks[2] = Block::new(3, Path::Line(gap), 200.0);
        let e = plan::<16>(cfg, [0.0; 6], &blocks, u64::MAX).unwrap_err();
        assert!(
            matches!(
                e,
                PlanError::Run {
                    index: Some(2),
                    error: RunError::Push(PushError::Discontinuous { .. })
                }
            ),
            "{e}"
        );
        assert!(e.to_string().starts_with("block 2: "), "{e}");
    }

    #[test]
    fn recycled_buffers_hold_later_plans() {
        let cfg = InterpConfig::default();
        let blocks = square(200.0);
        let mut run = Run::<16>::new(cfg, [0.0; 6]).unwrap().recording();
        run.push(&blocks[0]).unwrap();
        let first = run.take_steps();
        let Some(Step {
            op: Op::Commit(plan),
            ..
        }) = first.into_iter().next()
        else {
            panic!("no plan")
        };
        let addr = &*plan as *const PlannedBlock;
        run.recycle(plan);
        run.push(&blocks[1]).unwrap();
        let second = run.take_steps();
        match &second[0].op {
            Op::Commit(p) => assert_eq!(&**p as *const PlannedBlock, addr),
            op => panic!("{op:?}"),
        }
    }
}
