//! `interpd jitter --seconds N`: the full pipeline (a long program
//! interpolating, publishing to a subscriber process, the recorder thread
//! draining) and, in the same run, bare loops with the same scheduling that
//! only wait for their deadlines: one before the pipeline, one alongside it
//! (half a period out of phase). Prints p50/p99/p99.9/max of wake lateness
//! and of tick+publish compute.

use core::sync::atomic::{AtomicBool, Ordering};
use std::process::{Command, Stdio};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use anyhow::{Context, Result, anyhow, bail};
use interp_core::InterpConfig;
use interp_core::samples::butterfly;
use serde::Serialize;

use crate::check::Violations;
use crate::service::clock::{now_ns, wait_until_ns};
use crate::service::histogram::Histogram;
use crate::service::histogram::Percentiles;
use crate::service::rt::{RtOptions, RtSettings};
use crate::service::serve::ServeOptions;

/// Programmed feed of the jitter program, mm/min.
const FEED_MM_MIN: f64 = 6000.0;
/// Repetitions of the butterfly per second of run (it takes well over 0.2 s each).
const LOOPS_PER_SECOND: f64 = 5.0;
/// Extra time the subscriber process listens, s.
const SUBSCRIBER_GRACE_S: f64 = 3.0;

/// Options of `interpd jitter`.
#[derive(Clone, Debug, PartialEq)]
pub struct JitterOptions {
    /// Seconds for each of the two loops.
    pub seconds: f64,
    /// Period and scheduling of both loops, as `interpd serve` takes them.
    pub rt: RtSettings,
    /// Print the result as JSON.
    pub json: bool,
}

/// One loop's figures.
#[derive(Debug, Serialize)]
pub struct LoopFigures {
    /// Wake lateness, µs.
    pub lateness_us: Option<Percentiles>,
    /// Tick + publish (bare: two clock reads), µs.
    pub compute_us: Option<Percentiles>,
    /// Push + tick + publish on ticks with a push, µs (full pipeline only).
    pub compute_with_push_us: Option<Percentiles>,
    /// Missed periods.
    pub overruns: u64,
}

/// What `jitter` reports.
#[derive(Debug, Serialize)]
pub struct JitterReport {
    /// Seconds per loop.
    pub seconds: f64,
    /// Period, µs.
    pub period_us: u32,
    /// Spin before each deadline (`--spin-us`), µs.
    pub spin_us: u32,
    /// The bare loop, run before the pipeline.
    pub bare: LoopFigures,
    /// A bare loop run alongside the pipeline, on the same CPU with the same
    /// scheduling, its deadlines half a period after the RT thread's.
    pub bare_alongside: LoopFigures,
    /// The full pipeline.
    pub full: LoopFigures,
    /// Samples the subscriber process received.
    pub subscriber_received: u64,
    /// Samples it missed.
    pub subscriber_gaps: u64,
    /// Ticks it checked against the machine's limits (`interp_run::check`).
    pub subscriber_checked_ticks: u64,
    /// Checks that failed there (`None`: the subscriber checked nothing).
    pub subscriber_violations: Option<Violations>,
    /// Ticks the recorder had no room for.
    pub recorder_drops: u64,
    /// Periods the full pipeline's RT thread waited for its planning thread
    /// (its last point published again, unticked).
    pub planner_late: u64,
    /// Full-pipeline p99 lateness / bare-loop p99 lateness.
    pub p99_lateness_ratio: Option<f64>,
    /// Full-pipeline p99 lateness / p99 lateness of the bare loop alongside.
    pub p99_lateness_ratio_alongside: Option<f64>,
    /// Scheduling refused.
    pub scheduling_warnings: Vec<String>,
    /// 1-, 5- and 15-minute load averages (`/proc/loadavg`) when the run
    /// started and when it ended, so that figures from a busy machine say so.
    pub load_average: [Option<[f64; 3]>; 2],
}

/// The load averages of `/proc/loadavg` (`None` where it is not there or not understood).
fn load_average() -> Option<[f64; 3]> {
    parse_loadavg(&std::fs::read_to_string("/proc/loadavg").ok()?)
}

fn parse_loadavg(text: &str) -> Option<[f64; 3]> {
    let mut it = text.split_whitespace().map(str::parse::<f64>);
    Some([it.next()?.ok()?, it.next()?.ok()?, it.next()?.ok()?])
}

/// A bare loop: wait for each deadline as the RT thread does, read the clock,
/// nothing else. Deadlines are `first`, `first + period`, … until `end` or
/// `stop`.
fn spawn_bare_loop(
    opts: RtOptions,
    first: i64,
    end: i64,
    stop: Arc<AtomicBool>,
) -> Result<JoinHandle<(LoopFigures, Vec<String>)>> {
    std::thread::Builder::new()
        .name("interpd-bare".into())
        .spawn(move || {
            let warnings = crate::service::rt::apply_scheduling(&opts);
            let (mut late, mut comp) = (Histogram::new(), Histogram::new());
            let mut overruns = 0u64;
            let mut next = first - opts.period_ns;
            while next + opts.period_ns < end && !stop.load(Ordering::Relaxed) {
                next += opts.period_ns;
                wait_until_ns(next, opts.spin_ns);
                let wake = now_ns();
                late.record((wake - next).max(0) as u64);
                let t1 = now_ns();
                comp.record((t1 - wake).max(0) as u64);
                if t1 > next + opts.period_ns {
                    let missed = (t1 - next) / opts.period_ns;
                    overruns += missed as u64;
                    next += (missed - 1).max(0) * opts.period_ns;
                }
            }
            (
                LoopFigures {
                    lateness_us: Percentiles::of(&late),
                    compute_us: Percentiles::of(&comp),
                    compute_with_push_us: None,
                    overruns,
                },
                warnings,
            )
        })
        .context("spawning the bare loop")
}

fn join_bare(h: JoinHandle<(LoopFigures, Vec<String>)>) -> Result<(LoopFigures, Vec<String>)> {
    h.join().map_err(|_| anyhow!("the bare loop panicked"))
}

/// The first deadline half a period after one of the RT loop's (whose
/// deadlines are `epoch + k · period`) and at least a period from now.
fn alongside_first_deadline(epoch: i64, period: i64, now: i64) -> i64 {
    let half = epoch + period / 2;
    // The smallest k with half + k · period ≥ now + period (a ceiling division).
    let k = -(half - now - period).div_euclid(period);
    half + k * period
}

/// The jitter program: the butterfly and a line back to its start, `loops` times.
fn program(loops: usize) -> Vec<String> {
    let back = serde_json::json!({"feed": FEED_MM_MIN, "kind": "line", "end": butterfly::START})
        .to_string();
    let fly = crate::tools::demo::butterfly_request(FEED_MM_MIN);
    (0..loops)
        .flat_map(|_| [fly.clone(), back.clone()])
        .collect()
}

/// Runs `jitter`.
pub fn main(args: &JitterOptions) -> Result<()> {
    crate::flags::SECONDS.check("--seconds", args.seconds)?;
    let load_before = load_average();
    let opts = args.rt.options("", false)?;
    let never = Arc::new(AtomicBool::new(false));
    let (bare, mut warnings) = join_bare(spawn_bare_loop(
        opts.clone(),
        now_ns() + opts.period_ns,
        now_ns() + (args.seconds * 1e9) as i64,
        never,
    )?)?;

    let service = format!("interpd/jitter/{}", std::process::id());
    let exe = std::env::current_exe().context("locating the interpd binary")?;
    let child = Command::new(exe)
        .args(["watch", "--service", &service, "--json", "--seconds"])
        .arg(format!("{}", args.seconds + SUBSCRIBER_GRACE_S))
        // Every published tick through the setpoint checker.
        .arg("--check-feed")
        .arg(format!("{FEED_MM_MIN}"))
        .arg("--check-period-us")
        .arg(format!("{}", args.rt.period_us))
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .context("starting the subscriber process (interpd watch)")?;
    // Let the subscriber open the service before the first sample.
    std::thread::sleep(Duration::from_millis(500));

    let mut sargs = ServeOptions::in_process(&service);
    sargs.rt = args.rt.clone();
    sargs.position = Some(butterfly::START.to_vec());
    let svc = crate::service::serve::start(&sargs, InterpConfig::default(), false, None)?;
    let addr = svc.addr;
    let lines = program((args.seconds * LOOPS_PER_SECOND).ceil() as usize + 1);
    let send_args = crate::client::send::SendOptions {
        program: "jitter".into(),
        addr,
        socket: None,
        token: None,
        no_wait: false,
        wait_turn: false,
        json: false,
        quiet: true,
    };
    let streamer = std::thread::spawn(move || -> Result<()> {
        tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()?
            .block_on(async {
                let conn = crate::client::conn::connect(&send_args.endpoint()).await?;
                // Aborted at shutdown: the outcome does not matter here.
                let load =
                    |_: [f64; 6], _: &crate::service::control::StatusReply| Ok(lines.clone());
                let _ = crate::client::send::stream(conn, &load, &send_args).await;
                Ok(())
            })
    });
    let t0 = Instant::now();
    // The second bare loop runs alongside the pipeline, on the RT thread's
    // CPU with its scheduling, half a period out of phase: both see the
    // same moments of the machine.
    while !svc.status.running.load(Ordering::Acquire) {
        std::thread::sleep(Duration::from_millis(1));
    }
    let epoch = svc.status.epoch_ns.load(Ordering::Acquire);
    let stop = Arc::new(AtomicBool::new(false));
    let alongside = spawn_bare_loop(
        opts.clone(),
        alongside_first_deadline(epoch, opts.period_ns, now_ns()),
        i64::MAX,
        Arc::clone(&stop),
    )?;
    while t0.elapsed().as_secs_f64() < args.seconds {
        std::thread::sleep(Duration::from_millis(50));
    }
    stop.store(true, Ordering::Relaxed);
    let (bare_alongside, _) = join_bare(alongside)?;
    let summary = svc.shutdown()?;
    let _ = streamer.join();
    let out = child
        .wait_with_output()
        .context("waiting for the subscriber")?;
    let sub: serde_json::Value = serde_json::from_slice(&out.stdout)
        .map_err(|e| anyhow!("reading the subscriber's summary: {e}"))?;
    warnings.extend(summary.scheduling_warnings.iter().cloned());
    warnings.dedup();
    let ratio = |bare: &LoopFigures| match (bare.lateness_us, summary.lateness_us) {
        (Some(b), Some(f)) if b.p99 > 0.0 => Some(f.p99 / b.p99),
        _ => None,
    };
    let (p99_lateness_ratio, p99_lateness_ratio_alongside) = (ratio(&bare), ratio(&bare_alongside));
    let report = JitterReport {
        seconds: args.seconds,
        period_us: args.rt.period_us,
        spin_us: args.rt.spin_us,
        bare,
        full: LoopFigures {
            lateness_us: summary.lateness_us,
            compute_us: summary.tick_publish_us,
            compute_with_push_us: summary.tick_publish_with_push_us,
            overruns: summary.overruns,
        },
        subscriber_received: sub["received"].as_u64().unwrap_or(0),
        subscriber_gaps: sub["gaps"].as_u64().unwrap_or(u64::MAX),
        subscriber_checked_ticks: sub["checked_ticks"].as_u64().unwrap_or(0),
        subscriber_violations: serde_json::from_value(sub["violations"].clone())
            .ok()
            .flatten(),
        recorder_drops: summary.recorder_drops,
        planner_late: summary.planner_late,
        p99_lateness_ratio,
        bare_alongside,
        p99_lateness_ratio_alongside,
        scheduling_warnings: warnings,
        load_average: [load_before, load_average()],
    };
    if args.json {
        println!("{}", serde_json::to_string(&report)?);
    } else {
        print_report(&report);
    }
    match report.subscriber_violations {
        None => bail!("the subscriber checked no setpoint"),
        Some(v) if v.total() > 0 => bail!(
            "{} check(s) failed on the published setpoints ({}), first at tick {:?}",
            v.total(),
            v.breakdown(),
            v.first_seq
        ),
        Some(_) => Ok(()),
    }
}

fn print_report(r: &JitterReport) {
    println!(
        "interpd jitter: {} s per loop, period {} µs, spin {} µs before each deadline",
        r.seconds, r.period_us, r.spin_us
    );
    let row = |name: &str, p: &Option<Percentiles>| match p {
        Some(p) => println!(
            "  {name:<32} p50 {:8.1}  p99 {:8.1}  p99.9 {:8.1}  max {:8.1} µs  ({} samples)",
            p.p50, p.p99, p.p999, p.max, p.samples
        ),
        None => println!("  {name:<32} -"),
    };
    row("bare loop: wake lateness", &r.bare.lateness_us);
    row("bare loop: compute (clock reads)", &r.bare.compute_us);
    row(
        "bare loop alongside: lateness",
        &r.bare_alongside.lateness_us,
    );
    row("full pipeline: wake lateness", &r.full.lateness_us);
    row("full pipeline: tick+publish", &r.full.compute_us);
    row(
        "full pipeline: push+tick+publish",
        &r.full.compute_with_push_us,
    );
    println!(
        "  overruns: bare {}, full {}; planner late {}; recorder drops {}; subscriber {} samples, {} missing",
        r.bare.overruns,
        r.full.overruns,
        r.planner_late,
        r.recorder_drops,
        r.subscriber_received,
        r.subscriber_gaps
    );
    println!(
        "  setpoint checks: {} ticks checked, {}",
        r.subscriber_checked_ticks,
        r.subscriber_violations.map_or_else(
            || "none (no sample at rest before tick 1)".to_owned(),
            |v| format!("{} failed", v.total())
        )
    );
    if let Some(x) = r.p99_lateness_ratio {
        println!("  p99 lateness full / bare: {x:.2}");
    }
    if let Some(x) = r.p99_lateness_ratio_alongside {
        println!("  p99 lateness full / bare alongside: {x:.2}");
    }
    let fmt = |l: &Option<[f64; 3]>| {
        l.map_or_else(
            || "-".to_owned(),
            |[a, b, c]| format!("{a:.2} {b:.2} {c:.2}"),
        )
    };
    println!(
        "  load average (1/5/15 min): {} at the start, {} at the end",
        fmt(&r.load_average[0]),
        fmt(&r.load_average[1])
    );
    for w in &r.scheduling_warnings {
        println!("  warning: {w}");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_loop_alongside_is_half_a_period_out_of_phase_and_a_period_ahead() {
        let period = 1_000_000;
        for (epoch, now) in [
            (0, 0),
            (5, 123_456_789),
            (-7_300_001, 42),
            (1_000, 1_500_000),
        ] {
            let d = alongside_first_deadline(epoch, period, now);
            assert_eq!((d - epoch).rem_euclid(period), period / 2, "{epoch} {now}");
            assert!(
                d >= now + period && d < now + 2 * period,
                "{epoch} {now} -> {d}"
            );
        }
    }

    #[test]
    fn load_averages_are_read_from_proc_loadavg_text() {
        assert_eq!(
            parse_loadavg("10.53 11.20 7.81 3/812 43110\n"),
            Some([10.53, 11.2, 7.81])
        );
        assert_eq!(parse_loadavg("0.5 x 1"), None);
        assert_eq!(parse_loadavg(""), None);
    }
}
