//! The emulated unit of `motionlink sim scu` and of `--port sim` (the command's own process, and the
//! console's): a preset, a configuration file, and for `--port sim` the unit the command names, whose
//! functions drive what `--functions` says they drive.

use std::path::PathBuf;

use motionlink_scu::model::{MotionFunction, SpeedMode};
use motionlink_scu::sim::ActuatorConfig;
use motionlink_scu::{FunctionMap, SimConfig, Variants};

use crate::common::CliError;

/// The emulator's configuration: `preset` (scp11, tlt, liftkit), then the file at `path` over it (a file
/// naming no preset of its own starts from `preset`), then the firmware `variants` named (each may be
/// several names separated by commas), added to the file's.
pub(crate) fn load_sim_config(
    path: Option<&PathBuf>,
    preset: Option<&str>,
    variants: &[String],
) -> Result<SimConfig, CliError> {
    let mut config = match preset {
        Some(name) => SimConfig::preset(name).ok_or_else(|| unknown_preset(name))?,
        None => SimConfig::default(),
    };
    if let Some(path) = path {
        let text = std::fs::read_to_string(path)
            .map_err(|e| CliError::usage(format!("cannot read {}: {e}", path.display())))?;
        let text = match preset {
            Some(p) if !text.contains("preset") => format!("preset = \"{p}\"\n{text}"),
            _ => text,
        };
        config = SimConfig::from_toml(&text).map_err(|e| CliError::usage(format!("{}: {e}", path.display())))?;
    }
    let variants = Variants::parse_all(variants).map_err(|e| CliError::usage(e.to_string()))?;
    config.variants.extend(&variants);
    Ok(config)
}

fn unknown_preset(name: &str) -> CliError {
    CliError::usage(format!("--sim-preset {name:?}: the presets are {}", SimConfig::PRESETS.join(", ")))
}

/// What `--port sim` emulates, from the options of the command that names the unit.
pub(crate) struct InProcess<'a> {
    /// `--functions`, in order: presets and `F1=1,2` forms.
    pub functions: &'a [String],
    /// `--sim-preset`.
    pub preset: Option<&'a str>,
    /// `--sim-config` (not with every front end).
    pub file: Option<&'a PathBuf>,
    /// `--speed-mode`.
    pub speed_mode: SpeedMode,
    /// `--sim-variant`: firmware variants of the emulated unit.
    pub variants: &'a [String],
}

/// The unit `--port sim` emulates: the one the command names. A `--sim-config` file is the unit as it
/// stands (`--sim-preset` is then its starting point, and `--functions` only what the command believes).
/// Otherwise the unit starts from `--sim-preset`, else from the last preset `--functions` names (scp11,
/// tlt, liftkit: the emulator's preset of that name, with its columns' behaviour), else from scp11 with
/// two actuators; each `Fn=...` of `--functions` then drives what it says (actuators are added to reach
/// the highest one named), and the unit takes remote speeds as `--speed-mode` says.
pub(crate) fn in_process_config(unit: &InProcess<'_>) -> Result<SimConfig, CliError> {
    if unit.file.is_some() {
        return load_sim_config(unit.file, unit.preset, unit.variants);
    }
    let named = unit
        .functions
        .iter()
        .rev()
        .map(|s| s.trim().to_ascii_lowercase())
        .find(|s| SimConfig::PRESETS.contains(&s.as_str()));
    let mut config = load_sim_config(None, unit.preset.or(named.as_deref()), unit.variants)?;
    for spec in unit.functions {
        if FunctionMap::preset(spec.trim()).is_some() {
            continue;
        }
        let one = FunctionMap::unknown().apply(spec).map_err(|e| CliError::usage(format!("--functions {e}")))?;
        for f in (1..=10).filter_map(MotionFunction::new) {
            let Some(drives) = one.drives(f) else { continue };
            let highest = drives.iter().map(|a| usize::from(a.number())).max().unwrap_or(0);
            if highest > config.actuators.len() {
                config.actuators.resize(highest, ActuatorConfig::default());
            }
            config.functions[usize::from(f.id())] = drives;
        }
    }
    config.speed_mode = unit.speed_mode;
    config.validate().map_err(|e| CliError::usage(format!("--port sim: {e}")))?;
    Ok(config)
}

#[cfg(test)]
mod tests {
    use super::*;
    use motionlink_scu::model::Actuator;

    fn config(functions: &[&str], preset: Option<&str>) -> Result<SimConfig, CliError> {
        let functions: Vec<String> = functions.iter().map(|s| s.to_string()).collect();
        in_process_config(&InProcess {
            functions: &functions,
            preset,
            file: None,
            speed_mode: SpeedMode::Percent,
            variants: &[],
        })
    }

    fn a(n: u8) -> Actuator {
        Actuator::new(n).unwrap()
    }

    #[test]
    fn the_emulated_unit_is_the_one_the_functions_name() {
        assert_eq!(config(&[], None).unwrap(), SimConfig::default());
        assert_eq!(config(&["tlt"], None).unwrap(), SimConfig::tlt());
        assert_eq!(config(&["TLT", "liftkit"], None).unwrap(), SimConfig::liftkit());
        // The preset asked of the emulator wins over the one the functions name.
        assert_eq!(config(&["tlt"], Some("liftkit")).unwrap(), SimConfig::liftkit());
        let c = config(&["F1=1,2", "F7=3"], None).unwrap();
        assert_eq!(c.actuators.len(), 3);
        assert_eq!((c.functions[0].clone(), c.functions[6].clone()), (vec![a(1), a(2)], vec![a(3)]));
        assert_eq!(c.functions[1], vec![a(2)], "the others keep the preset's");
        let c = config(&["tlt", "F8=1,2"], None).unwrap();
        assert_eq!((c.functions[0].clone(), c.functions[7].clone()), (vec![a(1), a(2)], vec![a(1), a(2)]));
        assert!(matches!(config(&["F11=1"], None), Err(CliError::Usage(m)) if m.contains("--functions")));
        assert!(matches!(config(&[], Some("lift")), Err(CliError::Usage(m)) if m.contains("tlt")));
    }
}
