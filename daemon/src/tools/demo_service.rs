//! The second half of `interpd demo`: the butterfly through the service as a
//! user runs it (RT thread, iceoryx2, TCP control plane), checked by an
//! iceoryx2 subscriber against the direct run.

use std::fmt::Write as _;
use std::time::{Duration, Instant};

use anyhow::{Context, Result, anyhow};
use interp_core::samples::butterfly;
use interp_core::{InterpConfig, RunState};
use serde::Serialize;

use crate::check::{Checker, Violations};
use crate::service::histogram::Percentiles;
use crate::service::publish::SetpointSubscriber;
use crate::service::serve::ServeOptions;
use crate::tools::demo::{DemoOptions, Summary, butterfly_request};

/// The subscriber gives up when no sample arrives for this long.
const SAMPLE_TIMEOUT: Duration = Duration::from_secs(10);

/// What the run through the service showed.
#[derive(Debug, Clone, Serialize)]
pub struct ServiceRun {
    /// iceoryx2 service name used (private to this demo).
    pub service: String,
    /// Samples the subscriber received.
    pub received: u64,
    /// Samples missing between received ones (publisher `seq`).
    pub gaps: u64,
    /// Ticks checked (from the first tick to the first `done`).
    pub ticks: u64,
    /// Whether a `done` sample was seen.
    pub reached_done: bool,
    /// Checks that failed on the published setpoints.
    pub violations: Violations,
    /// Digest of the published ticks (compare with the direct run's).
    pub setpoint_digest: String,
    /// Final X Y Z.
    pub final_point: [f64; 3],
    /// Wake lateness of the RT thread, µs.
    pub lateness_us: Option<Percentiles>,
    /// Tick + publish, µs.
    pub tick_publish_us: Option<Percentiles>,
    /// Push + tick + publish (ticks with a push), µs.
    pub tick_publish_with_push_us: Option<Percentiles>,
    /// Missed periods.
    pub overruns: u64,
    /// Scheduling refused (normal scheduling was used).
    pub scheduling_warnings: Vec<String>,
    /// Wall time of the run, s.
    pub wall_s: f64,
    /// The MCAP recording of the run (`interpd replay` / `interpd trace plot` read it).
    pub recording: Option<std::path::PathBuf>,
    /// Messages written to it.
    pub recording_messages: u64,
    /// Ticks or records the recorder had no room for (the recording is then incomplete).
    pub recording_drops: u64,
}

impl ServiceRun {
    /// Why the run failed, if it did.
    pub fn failure(&self, direct_digest: &str) -> Option<String> {
        if self.gaps > 0 {
            return Some(format!("{} samples missed by the subscriber", self.gaps));
        }
        if !self.reached_done {
            return Some("the program did not reach `done`".into());
        }
        if self.violations.total() > 0 {
            return Some(format!("{} check(s) failed", self.violations.total()));
        }
        if self.setpoint_digest != direct_digest {
            return Some(format!(
                "published setpoints differ from the direct run (digest {} vs {direct_digest})",
                self.setpoint_digest
            ));
        }
        None
    }

    /// Summary lines.
    pub fn display(&self, direct_digest: &str) -> String {
        let mut s = String::new();
        let pct = |p: &Option<Percentiles>| {
            p.map_or_else(
                || "-".to_owned(),
                |p| {
                    format!(
                        "p50 {:.1}  p99 {:.1}  p99.9 {:.1}  max {:.1} µs",
                        p.p50, p.p99, p.p999, p.max
                    )
                },
            )
        };
        let _ = writeln!(
            s,
            "interpd demo: the same program through the service (serve, TCP, iceoryx2 {:?})",
            self.service
        );
        let _ = writeln!(
            s,
            "  subscriber  {} samples, {} missing, {} ticks checked, {} failed, done {}",
            self.received,
            self.gaps,
            self.ticks,
            self.violations.total(),
            self.reached_done
        );
        let _ = writeln!(
            s,
            "  digest      {} ({})",
            self.setpoint_digest,
            if self.setpoint_digest == direct_digest {
                "bit-identical to the direct run"
            } else {
                "DIFFERS from the direct run"
            }
        );
        let _ = writeln!(s, "  lateness    {}", pct(&self.lateness_us));
        let _ = writeln!(s, "  tick+pub    {}", pct(&self.tick_publish_us));
        let _ = writeln!(s, "  push+tick   {}", pct(&self.tick_publish_with_push_us));
        let _ = writeln!(
            s,
            "  loop        {} overruns, {:.3} s wall",
            self.overruns, self.wall_s
        );
        if let Some(path) = &self.recording {
            let _ = writeln!(
                s,
                "  recording   {} ({} messages, {} dropped); check it with `interpd replay {}`",
                path.display(),
                self.recording_messages,
                self.recording_drops,
                path.display()
            );
        }
        for w in &self.scheduling_warnings {
            let _ = writeln!(s, "  warning     {w}");
        }
        s
    }
}

/// Runs the butterfly through an in-process service and checks every published setpoint.
pub fn run(args: &DemoOptions, direct: &Summary) -> Result<ServiceRun> {
    let t0 = Instant::now();
    let service = format!("interpd/demo/{}", std::process::id());
    let cfg = InterpConfig {
        chord_tolerance: args.chord_tolerance_mm,
        max_path_accel: args.accel,
        ..InterpConfig::default()
    };
    let mut sargs = ServeOptions::in_process(&service);
    sargs.rt.period_us = args.period_us.clamp(250, 10_000);
    sargs.rt.no_rt = args.no_rt;
    sargs.position = Some(butterfly::START.to_vec());
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating the output directory {}", args.out.display()))?;
    sargs.record = Some(args.out.join(crate::tools::demo::RECORDING_FILE));
    // Subscribe before the service publishes, so no sample is missed.
    let (sub_tx, sub_rx) = std::sync::mpsc::channel();
    let st = direct.settings.clone();
    let start = butterfly::START;
    let svc_name = service.clone();
    let subscriber = std::thread::Builder::new()
        .name("demo-subscriber".into())
        .spawn(
            move || -> Result<(Checker, u64, u64, u64, bool, [f64; 3])> {
                let mut sub = SetpointSubscriber::new("interpd_demo_subscriber", &svc_name)?;
                let _ = sub_tx.send(());
                let mut check = Checker::new(f64::from(st.period_us) * 1e-6, st.limits, start);
                let (mut ticks, mut done, mut last_rx) = (0u64, false, Instant::now());
                let mut last = start;
                while !done {
                    while let Some(m) = sub.try_next()? {
                        last_rx = Instant::now();
                        // Samples before `start` repeat the rest point unticked (tick 0).
                        if m.tick == 0 {
                            continue;
                        }
                        let sp = m.setpoint();
                        check.check(&sp);
                        ticks += 1;
                        last = [sp.axes[0], sp.axes[1], sp.axes[2]];
                        if sp.state == RunState::Done || sp.state == RunState::Fault {
                            done = sp.state == RunState::Done;
                            break;
                        }
                    }
                    if done || last_rx.elapsed() > SAMPLE_TIMEOUT {
                        break;
                    }
                    sub.wait(Duration::from_millis(1));
                }
                Ok((check, sub.received, sub.gaps, ticks, done, last))
            },
        )
        .context("spawning the demo subscriber")?;
    sub_rx
        .recv_timeout(SAMPLE_TIMEOUT)
        .map_err(|_| anyhow!("the demo subscriber did not start"))?;
    let svc = crate::service::serve::start(&sargs, cfg, false, None)?;
    let addr = svc.addr;
    let line = butterfly_request(args.feed);
    let send_args = crate::client::send::SendOptions {
        program: "butterfly".into(),
        addr,
        socket: None,
        token: None,
        no_wait: false,
        wait_turn: false,
        json: false,
        quiet: true,
    };
    let streamed = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?
        .block_on(async {
            let conn = crate::client::conn::connect(&send_args.endpoint())
                .await
                .context("connecting to the service")?;
            let load =
                |_: [f64; 6], _: &crate::service::control::StatusReply| Ok(vec![line.clone()]);
            crate::client::send::stream(conn, &load, &send_args).await
        });
    let sub = subscriber
        .join()
        .map_err(|_| anyhow!("the demo subscriber panicked"))?;
    let summary = svc.shutdown()?;
    let (outcome, _status) = streamed?;
    if !matches!(outcome, crate::client::send::Outcome::Done) {
        return Err(anyhow!("streaming the butterfly failed: {outcome:?}"));
    }
    let (check, received, gaps, ticks, reached_done, final_point) = sub?;
    Ok(ServiceRun {
        service,
        received,
        gaps,
        ticks,
        reached_done,
        violations: check.violations,
        setpoint_digest: format!("{:016x}", check.digest),
        final_point,
        lateness_us: summary.lateness_us,
        tick_publish_us: summary.tick_publish_us,
        tick_publish_with_push_us: summary.tick_publish_with_push_us,
        overruns: summary.overruns,
        scheduling_warnings: summary.scheduling_warnings,
        wall_s: t0.elapsed().as_secs_f64(),
        recording: summary.trace,
        recording_messages: summary.trace_messages,
        recording_drops: summary.recorder_drops + summary.trace_overflows,
    })
}
