//! The command-line flags of the examples (`--name VALUE` anywhere among
//! the file arguments).

use interp_core::InterpConfig;
use nalgebra::{Rotation3, Unit, Vector3};

/// Removes `name VALUE` from `args` and returns `VALUE` (`None` when the
/// flag is absent; a flag last with no value is removed).
pub fn take_value(args: &mut Vec<String>, name: &str) -> Option<String> {
    let i = args.iter().position(|a| a == name)?;
    let v = args.get(i + 1).cloned();
    args.drain(i..(i + 2).min(args.len()));
    v
}

/// [`take_value`] as a number; panics naming the flag when its value is
/// missing or not a number.
pub fn take_number(args: &mut Vec<String>, name: &str) -> Option<f64> {
    let present = args.iter().any(|a| a == name);
    let v = take_value(args, name);
    if !present {
        return None;
    }
    let n = v.as_deref().and_then(|v| v.parse::<f64>().ok());
    Some(n.unwrap_or_else(|| panic!("{name} takes a number")))
}

/// `--rotate DEG[,X,Y,Z]`: a part turned on the table by `DEG` degrees about
/// the axis `(X, Y, Z)` through the origin (about Z when no axis is given).
/// Removed from `args`; panics naming the flag on a malformed value.
pub fn take_rotation(args: &mut Vec<String>, name: &str) -> Option<Rotation3<f64>> {
    let present = args.iter().any(|a| a == name);
    let v = take_value(args, name);
    if !present {
        return None;
    }
    let usage = || -> ! { panic!("{name} takes DEG or DEG,X,Y,Z (an axis not zero)") };
    let n: Vec<f64> = v
        .unwrap_or_else(|| usage())
        .split(',')
        .map(|x| x.trim().parse::<f64>().unwrap_or_else(|_| usage()))
        .collect();
    let axis = match n[..] {
        [_] => Vector3::z(),
        [_, x, y, z] => Vector3::new(x, y, z),
        _ => usage(),
    };
    let axis = Unit::try_new(axis, 1e-12).unwrap_or_else(|| usage());
    Some(Rotation3::from_axis_angle(&axis, n[0].to_radians()))
}

/// Every `--set KEY=VALUE` (a key of `[interp]` in the service's
/// configuration, a TOML value: `--set max-path-jerk=1e9`, `--set
/// axis-max-jerk=[2e9,2e9,2e9]`) laid over the default configuration, to
/// measure another machine. Removed from `args`; panics naming the flag on
/// an unknown key, a malformed value or a configuration the interpolator
/// refuses.
pub fn take_config(args: &mut Vec<String>) -> InterpConfig {
    let mut table = toml::Table::try_from(InterpConfig::default()).expect("the defaults serialise");
    while args.iter().any(|a| a == "--set") {
        let v = take_value(args, "--set").unwrap_or_else(|| panic!("--set takes KEY=VALUE"));
        let Some((k, value)) = v.split_once('=') else {
            panic!("--set {v}: expected KEY=VALUE");
        };
        let k = k.trim();
        assert!(
            table.contains_key(k),
            "--set {v}: unknown key `{k}` (known: {})",
            table.keys().cloned().collect::<Vec<_>>().join(", ")
        );
        let doc: toml::Table = toml::from_str(&format!("{k} = {}", value.trim()))
            .unwrap_or_else(|e| panic!("--set {v}: VALUE must be a TOML value ({e})"));
        table.extend(doc);
    }
    let cfg: InterpConfig = table
        .try_into()
        .unwrap_or_else(|e| panic!("--set: the configuration does not fit ({e})"));
    cfg.validate()
        .unwrap_or_else(|e| panic!("--set: the configuration is refused ({e:?})"));
    cfg
}

#[cfg(test)]
mod tests {
    use super::*;

    fn args(v: &[&str]) -> Vec<String> {
        v.iter().map(|s| s.to_string()).collect()
    }

    #[test]
    fn a_rotation_is_taken_about_z_or_the_axis_given() {
        let mut a = args(&["a.ngc", "--rotate", "90", "b.ngc"]);
        let r = take_rotation(&mut a, "--rotate").unwrap();
        assert_eq!(a, args(&["a.ngc", "b.ngc"]));
        assert!((r * Vector3::x() - Vector3::y()).norm() < 1e-15);
        let mut a = args(&["--rotate", "90,2,0,0"]);
        let r = take_rotation(&mut a, "--rotate").unwrap();
        assert!((r * Vector3::y() - Vector3::z()).norm() < 1e-15);
        assert!(take_rotation(&mut args(&["a.ngc"]), "--rotate").is_none());
    }

    #[test]
    fn settings_are_laid_over_the_defaults_and_taken_out_of_the_files() {
        let mut a = args(&[
            "--set",
            "max-path-jerk=1e9",
            "a.ngc",
            "--set",
            "axis-max-jerk = [2e9, 2e9, 3e9]",
        ]);
        let cfg = take_config(&mut a);
        assert_eq!(a, args(&["a.ngc"]));
        assert_eq!(cfg.max_path_jerk, 1e9);
        assert_eq!(cfg.axis_max_jerk, [2e9, 2e9, 3e9]);
        let d = InterpConfig::default();
        assert_eq!(cfg.max_path_accel, d.max_path_accel);
        assert_eq!(take_config(&mut args(&["a.ngc"])), d);
    }

    #[test]
    #[should_panic(expected = "unknown key `max-path-jrk`")]
    fn a_misspelt_setting_is_refused_by_name() {
        take_config(&mut args(&["--set", "max-path-jrk=1e9"]));
    }

    #[test]
    #[should_panic(expected = "the configuration is refused")]
    fn a_setting_out_of_range_is_refused() {
        take_config(&mut args(&["--set", "max-path-jerk=-1"]));
    }

    #[test]
    #[should_panic(expected = "--rotate takes DEG or DEG,X,Y,Z")]
    fn a_rotation_about_no_axis_is_refused_naming_the_flag() {
        take_rotation(&mut args(&["--rotate", "30,0,0,0"]), "--rotate");
    }
}
