//! The command-line flags of the examples (`--name VALUE` anywhere among
//! the file arguments).

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
