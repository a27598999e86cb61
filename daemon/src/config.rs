//! The run's configuration from a TOML file and `--set` flags, one way for
//! every command (`simulate`, `serve`).
//!
//! Lowest precedence first: the defaults of each table (`[interp]`:
//! `InterpConfig::default()`), the tables of the `--config` file (kebab-case
//! keys as the structs serialise), then every `--set KEY=VALUE` (an
//! `[interp]` key, TOML value syntax). Unknown tables and keys are refused
//! with their name and the known ones. The machine of a five-axis run is
//! the `[interp.machine]` table (`docs/five-axis.md`).

use std::path::Path;

use anyhow::{Context, Result, bail};

/// Keys of `[interp]` that its defaults leave out (they are `None`) but a
/// file may give.
const OPTIONAL_INTERP_KEYS: [&str; 1] = ["machine"];

/// The default table of a config struct.
pub fn table_of<T: serde::Serialize>(v: &T) -> Result<toml::Table> {
    toml::Table::try_from(v).context("serialising the default configuration")
}

/// Lays `over` on `base`, refusing keys `base` does not have.
fn merge(base: &mut toml::Table, over: &toml::Table, section: &str, origin: &str) -> Result<()> {
    for (k, v) in over {
        let optional = section == "interp" && OPTIONAL_INTERP_KEYS.contains(&k.as_str());
        if !base.contains_key(k) && !optional {
            let mut known: Vec<&str> = base.keys().map(String::as_str).collect();
            if section == "interp" {
                known.extend(OPTIONAL_INTERP_KEYS);
            }
            bail!(
                "{origin}: unknown key `{section}.{k}` (known: {})",
                known.join(", ")
            );
        }
        base.insert(k.clone(), v.clone());
    }
    Ok(())
}

/// Lays the `--config` file and the `--set` flags over `tables` (name and
/// defaults; the first is the one `--set` addresses). `command` names the
/// command in errors about tables it does not read.
pub fn layer(
    command: &str,
    config: Option<&Path>,
    set: &[String],
    tables: &mut [(&str, toml::Table)],
) -> Result<()> {
    if let Some(path) = config {
        let origin = path.display().to_string();
        let text = std::fs::read_to_string(path).with_context(|| format!("reading {origin}"))?;
        let file: toml::Table =
            toml::from_str(&text).with_context(|| format!("parsing {origin} as TOML"))?;
        for (k, v) in &file {
            let names: Vec<&str> = tables.iter().map(|(n, _)| *n).collect();
            let Some((name, target)) = tables.iter_mut().find(|(n, _)| n == k) else {
                bail!(
                    "{origin}: unknown table `{k}` ({command} reads {})",
                    names.join(", ")
                );
            };
            let Some(t) = v.as_table() else {
                bail!("{origin}: `{k}` must be a table");
            };
            merge(target, t, name, &origin)?;
        }
    }
    for s in set {
        let Some((k, v)) = s.split_once('=') else {
            bail!("--set {s}: expected KEY=VALUE");
        };
        let doc: toml::Table = toml::from_str(&format!("{} = {}", k.trim(), v.trim()))
            .with_context(|| format!("--set {s}: VALUE must be a TOML value"))?;
        let (name, target) = &mut tables[0];
        merge(target, &doc, name, &format!("--set {s}"))?;
    }
    Ok(())
}

/// The `InterpConfig` of `[interp]` in `config` and `set` (`interpd serve`
/// reads no other table), not yet validated.
pub fn interp_config(
    command: &str,
    config: Option<&Path>,
    set: &[String],
) -> Result<interp_core::InterpConfig> {
    let mut tables = [("interp", table_of(&interp_core::InterpConfig::default())?)];
    layer(command, config, set, &mut tables)?;
    let [(_, interp)] = tables;
    interp
        .try_into()
        .context("the [interp] configuration does not fit InterpConfig")
}

/// Checks `cfg`: the interpolator's own rules (`InterpConfig::validate`),
/// then the range of each limit (`crate::flags`), naming the key, so that a
/// typo such as `--set max-path-speed=1e308` is refused, not run.
pub fn check(cfg: &interp_core::InterpConfig) -> Result<()> {
    use crate::flags::{
        ACCEL, CHORD_TOLERANCE, CONFIG_LENGTH, JERK, PATH_SPEED, ROTARY_ACCEL, ROTARY_JERK,
        ROTARY_SPEED, SIM_PERIOD_US,
    };
    cfg.validate()
        .map_err(anyhow::Error::msg)
        .context("checking the configuration")?;
    let one =
        |r: crate::flags::Range, key: &str, v: f64| r.check(&format!("interp.{key}"), v).map(drop);
    let three =
        |r: crate::flags::Range, key: &str, v: [f64; 3]| v.iter().try_for_each(|&x| one(r, key, x));
    one(SIM_PERIOD_US, "period (as µs)", cfg.period * 1e6)?;
    one(CHORD_TOLERANCE, "chord-tolerance", cfg.chord_tolerance)?;
    one(PATH_SPEED, "max-path-speed", cfg.max_path_speed)?;
    one(ACCEL, "max-path-accel", cfg.max_path_accel)?;
    one(JERK, "max-path-jerk", cfg.max_path_jerk)?;
    one(ACCEL, "max-centripetal-accel", cfg.max_centripetal_accel)?;
    three(PATH_SPEED, "axis-max-velocity", cfg.axis_max_velocity)?;
    three(ACCEL, "axis-max-accel", cfg.axis_max_accel)?;
    three(JERK, "axis-max-jerk", cfg.axis_max_jerk)?;
    three(ROTARY_SPEED, "rotary-max-velocity", cfg.rotary_max_velocity)?;
    three(ROTARY_ACCEL, "rotary-max-accel", cfg.rotary_max_accel)?;
    three(ROTARY_JERK, "rotary-max-jerk", cfg.rotary_max_jerk)?;
    one(CONFIG_LENGTH, "profile-step", cfg.profile_step)?;
    one(
        CONFIG_LENGTH,
        "default-blend-tolerance",
        cfg.default_blend_tolerance,
    )?;
    if cfg.compress_max_move != 0.0 {
        one(CONFIG_LENGTH, "compress-max-move", cfg.compress_max_move)?;
    }
    Ok(())
}

/// A machine description file (TOML, `docs/five-axis.md`; e.g.
/// `examples/five_axis/machine.toml`), checked.
pub fn read_machine(path: &Path) -> Result<interp_core::kinematics::MachineSpec> {
    let origin = path.display();
    let text = std::fs::read_to_string(path).with_context(|| format!("reading {origin}"))?;
    let spec: interp_core::kinematics::MachineSpec =
        toml::from_str(&text).with_context(|| format!("parsing {origin} as a machine (TOML)"))?;
    interp_core::kinematics::Machine::new(spec)
        .map_err(|e| anyhow::anyhow!("{origin}: the machine: {e}"))?;
    Ok(spec)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_machine_is_read_from_the_interp_table_and_unknown_keys_are_refused() {
        let dir = std::env::temp_dir().join(format!("interpd-config-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("five.toml");
        std::fs::write(
            &path,
            "[interp]\nangular-tolerance = 0.002\n[interp.machine]\nchain = \"W/caxyBz/T\"\n\
             tool-length = 100.0\nrotary-centres = [[0.0, 0.0, -50.0], [0, 0, 0], [0, 0, 0]]\n\
             rotary-ranges = [{ min = -110, max = 110 }, \
             { min = 0, max = 0 }, { min = -inf, max = inf }]\n",
        )
        .unwrap();
        let cfg = interp_config("serve", Some(&path), &[]).unwrap();
        let m = cfg.machine.expect("a machine");
        // The example's machine file is the same machine.
        let example =
            Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/five_axis/machine.toml");
        assert_eq!(read_machine(&example).unwrap(), m);
        assert_eq!(m.tool_length, 100.0);
        assert_eq!(cfg.angular_tolerance, 0.002);
        assert!(cfg.validate().is_ok());
        let e = interp_config("serve", Some(&path), &["machin = 1".into()]).unwrap_err();
        assert!(
            format!("{e:#}").contains("unknown key `interp.machin`"),
            "{e:#}"
        );
        std::fs::write(&path, "[simulate]\nmax-ctrl-per-block = 12\n").unwrap();
        let e = interp_config("serve", Some(&path), &[]).unwrap_err();
        assert!(
            format!("{e:#}").contains("unknown table `simulate` (serve reads interp)"),
            "{e:#}"
        );
    }
}
