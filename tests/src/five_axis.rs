//! Running a five-axis G-code program on a described machine, for the
//! example (`cargo run -p interpd-tests --example five_axis`) and its test:
//! parse, convert with the machine, interpolate, and chart what the tool
//! tip, the tool axis and the joints did.

use std::path::{Path, PathBuf};

use gcode::CoreOptions;
use interp_core::kinematics::{Machine, MachineSpec};
use interp_core::path::Block;
use interp_core::{Curve, InterpConfig, Interpolator, RunState, Setpoint};
use traces::plot::{Chart, ChartLine};

/// `examples/five_axis/` of the repository.
pub fn example_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/five_axis")
}

/// A machine description (TOML, `docs/five-axis.md`).
pub fn machine_from_toml(text: &str) -> Result<MachineSpec, String> {
    let spec: MachineSpec = toml::from_str(text).map_err(|e| format!("machine: {e}"))?;
    Machine::new(spec).map_err(|e| format!("machine: {e}"))?;
    Ok(spec)
}

/// The default configuration on the example's machine
/// (`examples/five_axis/machine.toml`).
pub fn example_config() -> InterpConfig {
    let text = std::fs::read_to_string(example_dir().join("machine.toml")).expect("machine.toml");
    InterpConfig {
        machine: Some(machine_from_toml(&text).expect("machine")),
        ..InterpConfig::default()
    }
}

/// A program run to its end.
#[derive(Debug, Clone)]
pub struct FiveAxisRun {
    /// The configuration (with the machine).
    pub cfg: InterpConfig,
    /// Where the machine started (the program's first point, rotary axes at 0).
    pub start: [f64; 6],
    /// The interp-core blocks of the program.
    pub blocks: Vec<Block>,
    /// Every setpoint, to the end.
    pub setpoints: Vec<Setpoint>,
}

/// A program run through `simulate`'s pipeline (`traces::sim::run`): the
/// converted program, the run's configuration record and every setpoint.
#[derive(Debug, Clone)]
pub struct SimulatedRun {
    /// The program as `simulate` converts it (machine at the origin).
    pub program: traces::Program,
    /// The configuration record of the run.
    pub config: traces::ConfigMsg,
    /// Every setpoint, to the end.
    pub setpoints: Vec<Setpoint>,
}

/// Parses `text` and runs it as `interpd simulate` does (for `cfg.machine`,
/// from the origin, at most 600 s); `source` names it in the record.
pub fn simulate_program(
    cfg: InterpConfig,
    text: &str,
    source: &str,
) -> Result<SimulatedRun, String> {
    let g = gcode::parse(text).map_err(|e| e.to_string())?;
    let program = traces::Program::from_gcode(&g, &CoreOptions::for_config(&cfg), [0.0; 6])
        .map_err(|e| e.to_string())?;
    let config = traces::sim::config_for(
        &program,
        cfg,
        &traces::sim::SimSettings::default(),
        "test",
        source,
    );
    let mut setpoints = Vec::new();
    traces::sim::run(&config, &program, 600.0, |item| {
        if let traces::sim::SimItem::Tick { setpoint, .. } = item {
            setpoints.push(*setpoint);
        }
        Ok::<(), std::convert::Infallible>(())
    })
    .map_err(|e| e.to_string())?;
    Ok(SimulatedRun {
        program,
        config,
        setpoints,
    })
}

/// Parses `text`, converts it for `cfg.machine` and interpolates it from
/// its first point to its end.
pub fn run_program(cfg: InterpConfig, text: &str) -> Result<FiveAxisRun, String> {
    let program = gcode::parse(text).map_err(|e| e.to_string())?;
    let opts = CoreOptions {
        rapid_speed: cfg.max_path_speed,
        machine: cfg.machine,
    };
    let blocks = program.to_core_blocks(&opts).map_err(|e| e.to_string())?;
    let first = blocks.first().ok_or("no motion")?.path.start_point();
    let start = [first.x, first.y, first.z, 0.0, 0.0, 0.0];
    let mut ip: Box<Interpolator> =
        Box::new(Interpolator::new(cfg, start).map_err(|e| e.to_string())?);
    let mut setpoints = Vec::new();
    let mut next = 0;
    // A generous cap on machine time: an hour.
    let cap = (3600.0 / cfg.period) as usize;
    for _ in 0..cap {
        while next < blocks.len() {
            match ip.push(&blocks[next]) {
                Ok(()) => next += 1,
                Err(e) if e.is_wait() => break,
                Err(e) => return Err(format!("line {}: {e}", blocks[next].id)),
            }
            if next == blocks.len() {
                ip.finish();
            }
        }
        let sp = ip.tick();
        if sp.state == RunState::Fault {
            return Err(format!("fault at tick {}", sp.seq));
        }
        setpoints.push(sp);
        if sp.state == RunState::Done {
            return Ok(FiveAxisRun {
                cfg,
                start,
                blocks,
                setpoints,
            });
        }
    }
    Err("did not finish within an hour of machine time".into())
}

/// The charts of a run: the tool tip and a point up the tool axis in the
/// workpiece frame (top view), the rotary joints and the linear joints over
/// time.
pub fn charts(run: &FiveAxisRun) -> Result<Vec<Chart>, String> {
    let m = Machine::new(run.cfg.machine.ok_or("no machine")?).map_err(|e| e.to_string())?;
    let sps = &run.setpoints;
    let poses: Vec<_> = sps.iter().map(|s| m.forward(&s.axes)).collect();
    let tip: Vec<(f64, f64)> = poses.iter().map(|p| (p.tip.x, p.tip.y)).collect();
    // A point 10 mm up the tool axis: under TCP it runs round the cone's
    // generatrix at that height (radius 40 − 10·sin 15° on the example).
    let up: Vec<(f64, f64)> = poses
        .iter()
        .map(|p| {
            let q = p.tip + p.axis * 10.0;
            (q.x, q.y)
        })
        .collect();
    let series =
        |j: usize| -> Vec<(f64, f64)> { sps.iter().map(|s| (s.time, s.axes[j])).collect() };
    Ok(vec![
        Chart {
            file: "tip_path",
            title: "Tool tip and a point 10 mm up the tool axis, workpiece frame (top view)".into(),
            x_label: "x (mm)",
            y_label: "y (mm)",
            equal_axes: true,
            lines: vec![
                ChartLine::data("tool tip", tip),
                ChartLine::data("10 mm up the tool axis", up),
            ],
        },
        Chart {
            file: "rotary_joints",
            title: "Rotary joints".into(),
            x_label: "time (s)",
            y_label: "degrees",
            equal_axes: false,
            lines: vec![
                ChartLine::data("A", series(3)),
                ChartLine::data("C", series(5)),
            ],
        },
        Chart {
            file: "linear_joints",
            title: "Linear joints (the table turns: X Y Z follow it)".into(),
            x_label: "time (s)",
            y_label: "mm",
            equal_axes: false,
            lines: vec![
                ChartLine::data("X", series(0)),
                ChartLine::data("Y", series(1)),
                ChartLine::data("Z", series(2)),
            ],
        },
    ])
}
