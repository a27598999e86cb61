//! The command-line flags of the examples (`--name VALUE` anywhere among
//! the file arguments).

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
    #[should_panic(expected = "--rotate takes DEG or DEG,X,Y,Z")]
    fn a_rotation_about_no_axis_is_refused_naming_the_flag() {
        take_rotation(&mut args(&["--rotate", "30,0,0,0"]), "--rotate");
    }
}
