//! `interpd simulate`: a program through the interpolator with no clock.
//!
//! The same `Interpolator` as the real-time loop, driven by
//! `traces::sim::run` (the code `interpd replay` re-runs), writes an MCAP
//! trace if asked and prints the run's summary.
//!
//! Configuration, lowest precedence first: `InterpConfig::default()` and
//! `SimSettings::default()`, the TOML file of `--config` (tables `[interp]`
//! and `[simulate]`, kebab-case keys as the structs serialise; the machine
//! of a five-axis program is `[interp.machine]`), every `--set KEY=VALUE`
//! (any `[interp]` key, TOML value syntax), then the named flags
//! ([`crate::config`]). Unknown keys are refused with their name.

use std::fs::File;
use std::io::BufWriter;
use std::path::PathBuf;

use anyhow::{Context, Result, bail};

use crate::config;
use interp_core::InterpConfig;
use traces::analysis::{Analyzer, Summary};
use traces::sim::{self, SimItem, SimSettings};
use traces::writer::{TraceCompression, TraceWriter};

/// Options of `interpd simulate`.
#[derive(Clone, Debug, PartialEq)]
pub struct SimulateOptions {
    /// The program: G-code (`.ngc`, `.nc`) or the JSON block form (`docs/traces.md`).
    pub program: PathBuf,
    /// TOML configuration (`[interp]`, `[simulate]`).
    pub config: Option<PathBuf>,
    /// Write the trace to this MCAP file.
    pub out: Option<PathBuf>,
    /// Print the summary as one JSON object.
    pub json: bool,
    /// Override any `[interp]` key, e.g. `--set planning-margin=0.05` (repeatable).
    pub set: Vec<String>,
    /// The five-axis machine (TOML, `docs/five-axis.md`), over `[interp.machine]`.
    pub machine: Option<PathBuf>,
    /// Interpolation period, µs (`interp.period`; default 1000).
    pub period_us: Option<f64>,
    /// Chord tolerance, mm (`interp.chord-tolerance`; default 0.001).
    pub chord_tolerance_mm: Option<f64>,
    /// Machine path-speed limit, mm/s (`interp.max-path-speed`; default 250).
    pub max_speed: Option<f64>,
    /// Tangential acceleration limit, mm/s² (`interp.max-path-accel`; default 2000).
    pub max_accel: Option<f64>,
    /// Control points per segment when long NURBS are split (`simulate.max-ctrl-per-block`; default 32, as `serve`).
    pub max_ctrl_per_block: Option<usize>,
    /// Chunk compression of the trace: zstd (default), lz4 or none.
    pub compression: TraceCompression,
}

/// The resolved configuration.
#[derive(Clone, Debug)]
pub struct Resolved {
    /// The interpolator's.
    pub interp: InterpConfig,
    /// The simulation's.
    pub settings: SimSettings,
}

/// Defaults, then `--config`, then `--set`, then flags.
pub fn resolve(args: &SimulateOptions) -> Result<Resolved> {
    let mut tables = [
        ("interp", config::table_of(&InterpConfig::default())?),
        ("simulate", config::table_of(&SimSettings::default())?),
    ];
    config::layer("simulate", args.config.as_deref(), &args.set, &mut tables)?;
    let [(_, interp), (_, simulate)] = tables;
    let mut cfg: InterpConfig = interp
        .try_into()
        .context("the [interp] configuration does not fit InterpConfig")?;
    let mut settings: SimSettings = simulate
        .try_into()
        .context("the [simulate] configuration does not fit")?;
    if let Some(us) = args.period_us {
        cfg.period = us * 1e-6;
    }
    if let Some(v) = args.chord_tolerance_mm {
        cfg.chord_tolerance = v;
    }
    if let Some(v) = args.max_speed {
        cfg.max_path_speed = v;
    }
    if let Some(v) = args.max_accel {
        cfg.max_path_accel = v;
    }
    if let Some(n) = args.max_ctrl_per_block {
        settings.max_ctrl_per_block = n;
    }
    if let Some(path) = &args.machine {
        cfg.machine = Some(config::read_machine(path)?);
    }
    config::check(&cfg)?;
    let max = interp_core::nurbs::MAX_CTRL;
    if !(1..=max).contains(&settings.max_ctrl_per_block) {
        bail!(
            "simulate.max-ctrl-per-block must be in 1..={max}, got {}",
            settings.max_ctrl_per_block
        );
    }
    Ok(Resolved {
        interp: cfg,
        settings,
    })
}

/// What `writer` in the config message says.
pub fn writer_name() -> String {
    format!("interpd simulate {}", env!("CARGO_PKG_VERSION"))
}

/// Runs the simulation; writes the trace to `args.out` if given.
pub fn run(args: &SimulateOptions) -> Result<Summary> {
    let r = resolve(args)?;
    let program = crate::program::load(
        &args.program,
        &crate::program::LoadOptions {
            start: None,
            core: gcode::CoreOptions::for_config(&r.interp),
        },
    )?;
    let source = args.program.display().to_string();
    let config = sim::config_for(&program, r.interp, &r.settings, &writer_name(), &source);
    let expanded = program
        .expand(r.settings.max_ctrl_per_block, sim::FIRST_BLOCK_ID)
        .with_context(|| format!("in {source}"))?;
    // The segments the interpolator runs: the program through the G64 P stage.
    let segments = sim::smoothed_segments(&expanded, &config.interp)
        .map_err(anyhow::Error::msg)
        .with_context(|| format!("smoothing {source}"))?;
    let mut analyzer = Analyzer::new(&config, expanded.blocks.len(), &segments);
    let mut observe = |item: &SimItem<'_>| match item {
        SimItem::Tick { setpoint, .. } => {
            analyzer.push(setpoint);
        }
        SimItem::Event(e) => analyzer.event(e.kind),
        SimItem::Config(_) | SimItem::Block(_) => {}
    };
    let max_time = r.settings.max_machine_time;
    let outcome = match &args.out {
        Some(path) => {
            let f = File::create(path).with_context(|| format!("creating {}", path.display()))?;
            let mut w = TraceWriter::new(BufWriter::new(f), args.compression)
                .with_context(|| format!("starting the trace {}", path.display()))?;
            let outcome = sim::record(&config, &program, max_time, &mut w, observe)
                .with_context(|| format!("simulating {source}"))?;
            w.finish()
                .with_context(|| format!("finishing the trace {}", path.display()))?;
            outcome
        }
        None => sim::run(&config, &program, max_time, |item| {
            observe(&item);
            Ok::<(), std::convert::Infallible>(())
        })
        .with_context(|| format!("simulating {source}"))?,
    };
    analyzer.planner(&outcome.stats, &outcome.plan);
    Ok(analyzer.summary())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `simulate` cuts NURBS as the service does (one program, the same
    /// segments): the default pieces are the service's.
    #[test]
    fn simulate_splits_nurbs_as_serve_does_by_default() {
        let args = SimulateOptions {
            program: PathBuf::from("unused.ngc"),
            config: None,
            out: None,
            json: false,
            set: Vec::new(),
            machine: None,
            period_us: None,
            chord_tolerance_mm: None,
            max_speed: None,
            max_accel: None,
            max_ctrl_per_block: None,
            compression: TraceCompression::default(),
        };
        let r = resolve(&args).unwrap();
        assert_eq!(r.settings.max_ctrl_per_block, crate::protocol::PIECE_CTRL);
    }
}
