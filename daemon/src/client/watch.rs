//! `interpd watch`: a Rust subscriber of the setpoint service. Reports gaps in
//! the sequence numbers, a restart of the publisher (its sequence starts
//! again, with the jump of position across it) and a dead publisher (no
//! sample for `--liveness` seconds: the service publishes every period, idle
//! or not); optionally writes every setpoint to CSV and stops when the
//! program is done. Any of the three makes it exit non-zero.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};
use interp_core::{InterpConfig, RunState};
use serde::Serialize;

use crate::check::{Checker, Limits, Measured, Violations};

use crate::service::publish::{SETPOINT_TYPE_NAME, SetpointSubscriber, run_state, state_name};

/// How long one wait for samples lasts.
const POLL: Duration = Duration::from_millis(2);
/// Default `--liveness`, s: well beyond a restart of `serve`, far beyond a period.
pub const DEFAULT_LIVENESS_S: f64 = 5.0;

/// Options of `interpd watch`.
#[derive(Clone, Debug, PartialEq)]
pub struct WatchOptions {
    /// iceoryx2 service name.
    pub service: String,
    /// Stop after this many samples.
    pub count: Option<u64>,
    /// Stop after this many seconds.
    pub seconds: Option<f64>,
    /// Stop at the first sample in state `done` after one that was moving.
    pub until_done: bool,
    /// Give up when no sample arrives for this many seconds: the publisher
    /// is dead (or was never there).
    pub liveness: f64,
    /// Write every sample (seq,tick,time,x,y,z,feed,u,s,block_id,state) to this CSV.
    pub csv: Option<PathBuf>,
    /// Print a line per this many samples (0: none).
    pub every: u64,
    /// Print the summary as JSON.
    pub json: bool,
    /// Check every tick against the default machine limits for a program
    /// at this feed, mm/min (the setpoint checker, `interp_run::check`),
    /// from the first sample at rest before tick 1; a failed check makes
    /// it exit non-zero.
    pub check_feed: Option<f64>,
    /// The service's interpolation period, µs (for `--check-feed`).
    pub check_period_us: u32,
}

/// The checker of `--check-feed`: every tick once (a point published again
/// unticked is skipped), from the rest point before tick 1.
#[derive(Debug)]
struct TickCheck {
    ts: f64,
    limits: Limits,
    checker: Option<Checker>,
    ticks: u64,
}

impl TickCheck {
    fn new(args: &WatchOptions) -> Option<Self> {
        let feed = args.check_feed?;
        let cfg = InterpConfig {
            period: f64::from(args.check_period_us) * 1e-6,
            ..InterpConfig::default()
        };
        Some(TickCheck {
            ts: cfg.period,
            limits: Limits::new(&cfg, feed / 60.0),
            checker: None,
            ticks: 0,
        })
    }

    fn take(&mut self, m: &crate::service::publish::SetpointMsg) {
        let sp = m.setpoint();
        if m.tick == 0 {
            // The rest point before the first tick.
            if self.checker.is_none() {
                let start = [sp.axes[0], sp.axes[1], sp.axes[2]];
                self.checker = Some(Checker::new(self.ts, self.limits, start));
            }
            return;
        }
        if let Some(c) = &mut self.checker
            && m.tick > c.last().seq
        {
            c.check(&sp);
            self.ticks += 1;
        }
    }
}

/// What `watch` saw.
#[derive(Debug, Serialize)]
pub struct WatchSummary {
    /// Samples received.
    pub received: u64,
    /// Samples missing between received ones.
    pub gaps: u64,
    /// First and last sequence numbers seen.
    pub first_seq: Option<u64>,
    /// Last sequence number seen.
    pub last_seq: Option<u64>,
    /// State of the last sample.
    pub final_state: Option<&'static str>,
    /// X Y Z of the last sample.
    pub final_position: Option<[f64; 3]>,
    /// Times the publisher restarted (its sequence started again).
    pub restarts: u64,
    /// Largest jump of position across a restart, mm.
    pub restart_jump_mm: f64,
    /// Seconds without a sample when it gave up (the publisher is dead),
    /// `None` when samples kept coming.
    pub silent_s: Option<f64>,
    /// Ticks checked (`--check-feed`).
    pub checked_ticks: u64,
    /// Checks that failed (`--check-feed`; `None`: not asked, or no sample
    /// at rest before tick 1 was seen).
    pub violations: Option<Violations>,
    /// Largest values measured on the checked ticks.
    pub measured: Option<Measured>,
}

/// Runs `watch`; fails when samples were missed.
pub fn main(args: &WatchOptions) -> Result<()> {
    crate::flags::LIVENESS.check("--liveness", args.liveness)?;
    if let Some(s) = args.seconds {
        crate::flags::SECONDS.check("--seconds", s)?;
    }
    if let Some(f) = args.check_feed {
        crate::flags::FEED.check("--check-feed", f)?;
    }
    let node_name = format!("interpd_watch_{}", std::process::id());
    let mut sub = SetpointSubscriber::new(&node_name, &args.service)?;
    let mut csv = match &args.csv {
        Some(p) => {
            let mut w = BufWriter::new(
                File::create(p).with_context(|| format!("creating {}", p.display()))?,
            );
            writeln!(w, "seq,tick,time,x,y,z,feed,u,s,block_id,state")?;
            Some(w)
        }
        None => None,
    };
    eprintln!(
        "interpd watch: subscribed to {:?} (type {SETPOINT_TYPE_NAME})",
        args.service
    );
    let t0 = Instant::now();
    let mut summary = WatchSummary {
        received: 0,
        gaps: 0,
        first_seq: None,
        last_seq: None,
        final_state: None,
        final_position: None,
        restarts: 0,
        restart_jump_mm: 0.0,
        silent_s: None,
        checked_ticks: 0,
        violations: None,
        measured: None,
    };
    let mut check = TickCheck::new(args);
    let mut moved = false;
    let mut last_rx = Instant::now();
    'outer: loop {
        while let Some(m) = sub.try_next()? {
            last_rx = Instant::now();
            summary.first_seq.get_or_insert(m.seq);
            summary.last_seq = Some(m.seq);
            let st = run_state(m.state);
            if let Some(c) = check.as_mut() {
                c.take(&m);
            }
            summary.final_state = Some(state_name(st));
            summary.final_position = Some([m.axes[0], m.axes[1], m.axes[2]]);
            if let Some(w) = csv.as_mut() {
                writeln!(
                    w,
                    "{},{},{},{},{},{},{},{},{},{},{}",
                    m.seq,
                    m.tick,
                    m.time,
                    m.axes[0],
                    m.axes[1],
                    m.axes[2],
                    m.feed,
                    m.u,
                    m.s,
                    m.block_id,
                    state_name(st)
                )?;
            }
            if args.every > 0 && sub.received % args.every == 0 {
                println!(
                    "seq {} tick {} {} x {:.4} y {:.4} z {:.4} feed {:.3}",
                    m.seq,
                    m.tick,
                    state_name(st),
                    m.axes[0],
                    m.axes[1],
                    m.axes[2],
                    m.feed
                );
            }
            moved |= matches!(
                st,
                RunState::Running | RunState::Holding | RunState::Stopping
            );
            if args.until_done && moved && st == RunState::Done {
                break 'outer;
            }
            if args.count.is_some_and(|c| sub.received >= c) {
                break 'outer;
            }
        }
        if args
            .seconds
            .is_some_and(|s| t0.elapsed().as_secs_f64() >= s)
        {
            break;
        }
        let silent = last_rx.elapsed().as_secs_f64();
        if silent >= args.liveness {
            summary.silent_s = Some(silent);
            break;
        }
        if !sub.wait(POLL) {
            break;
        }
    }
    summary.received = sub.received;
    summary.gaps = sub.gaps;
    summary.restarts = sub.restarts;
    summary.restart_jump_mm = sub.restart_jump_mm;
    if let Some(c) = &check {
        summary.checked_ticks = c.ticks;
        summary.violations = c.checker.as_ref().map(|c| c.violations);
        summary.measured = c.checker.as_ref().map(|c| c.measured);
    }
    if let Some(mut w) = csv {
        w.flush().context("writing the CSV")?;
    }
    if args.json {
        println!("{}", serde_json::to_string(&summary)?);
    } else {
        println!(
            "interpd watch: {} samples, {} missing (gaps), {} restarts, seq {:?}..{:?}, final {:?} at {:?}",
            summary.received,
            summary.gaps,
            summary.restarts,
            summary.first_seq,
            summary.last_seq,
            summary.final_state,
            summary.final_position
        );
    }
    let mut problems = Vec::new();
    if summary.gaps > 0 {
        problems.push(format!("{} samples were missed", summary.gaps));
    }
    if summary.restarts > 0 {
        problems.push(format!(
            "the publisher restarted {} time(s): its sequence started again, the position jumped {:.6} mm",
            summary.restarts, summary.restart_jump_mm
        ));
    }
    if let Some(v) = summary.violations
        && v.total() > 0
    {
        problems.push(format!(
            "{} check(s) failed ({}), first at tick {:?}",
            v.total(),
            v.breakdown(),
            v.first_seq
        ));
    }
    if check.is_some() && summary.violations.is_none() {
        problems.push("--check-feed: no sample at rest before tick 1, nothing checked".into());
    }
    if let Some(s) = summary.silent_s {
        problems.push(if summary.received == 0 {
            format!(
                "no sample in {s:.1} s: no publisher on {:?} (is interpd serve running?)",
                args.service
            )
        } else {
            format!("the publisher went silent for {s:.1} s: it is dead or stalled")
        });
    }
    if !problems.is_empty() {
        bail!("{}", problems.join("; "));
    }
    Ok(())
}
