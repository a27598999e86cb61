use interp_core::path::{Block, Path};
use interp_core::samples::butterfly;
use interp_core::{InterpConfig, nurbs::split_program_curve};
use interpd_tests::path_time::{accel_only_optimum, interpolated_time};

fn main() {
    let mut blocks = Vec::new();
    split_program_curve::<()>(butterfly::BUTTERFLY_DEGREE, &butterfly::BUTTERFLY_POINTS, &butterfly::BUTTERFLY_WEIGHTS, &butterfly::BUTTERFLY_KNOTS, 20, |n| {
        blocks.push(Block::new(blocks.len() as u32 + 1, Path::Nurbs(n), 100.0));
        Ok(())
    }).unwrap();
    let d = InterpConfig::default();
    let opt = accel_only_optimum(&blocks, &d);
    for (name, cfg) in [
        ("default", d),
        ("no axis jerk", InterpConfig { axis_max_jerk: [1e18; 3], ..d }),
        ("no path jerk", InterpConfig { max_path_jerk: 1e18, ..d }),
        ("J x4", InterpConfig { max_path_jerk: 4e5, axis_max_jerk: [8e5; 3], ..d }),
    ] {
        let t = interpolated_time(&blocks, &cfg).unwrap();
        println!("{name}: {t:.3} s ratio {:.3} (N = {})", t / opt, cfg.filter_ticks());
    }
}
