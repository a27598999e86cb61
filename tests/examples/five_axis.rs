//! Runs the five-axis example program (`examples/five_axis/`) on its
//! machine and writes its plots:
//!
//! ```sh
//! cargo run --release -p interpd-tests --example five_axis -- [OUT_DIR]
//! ```
//!
//! OUT_DIR defaults to `examples/five_axis/plots`.

use interp_core::InterpConfig;
use interpd_tests::five_axis::{charts, example_dir, machine_from_toml, run_program};

fn main() -> Result<(), String> {
    // The interpolator is built on the stack before it is boxed (its
    // look-ahead is fixed-capacity, over a MiB): a thread with room for it.
    std::thread::Builder::new()
        .stack_size(interp_run::stack::INTERPOLATOR_STACK_BYTES)
        .spawn(run)
        .map_err(|e| e.to_string())?
        .join()
        .map_err(|_| "the run panicked".to_string())?
}

fn run() -> Result<(), String> {
    let dir = example_dir();
    let read = |f: &str| {
        std::fs::read_to_string(dir.join(f)).map_err(|e| format!("{}: {e}", dir.join(f).display()))
    };
    let spec = machine_from_toml(&read("machine.toml")?)?;
    let cfg = InterpConfig {
        machine: Some(spec),
        ..InterpConfig::default()
    };
    let run = run_program(cfg, &read("frustum.ngc")?)?;
    let last = run.setpoints.last().ok_or("no setpoints")?;
    println!(
        "frustum.ngc: {} blocks, {} setpoints, {:.3} s of machine time, ends at joints {:?}",
        run.blocks.len(),
        run.setpoints.len(),
        last.time,
        last.axes
    );
    let out = std::env::args()
        .nth(1)
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| dir.join("plots"));
    let report =
        traces::plot::plot_charts(&charts(&run)?, &out, false).map_err(|e| e.to_string())?;
    for f in report.files {
        println!("wrote {}", f.display());
    }
    Ok(())
}
