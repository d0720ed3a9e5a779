//! The emulated unit of `motionlink sim scu` and of `--port sim` (the command's own process, and the
//! console's): a preset, a configuration file, and for `--port sim` the unit the command names, whose
//! functions drive what `--functions` says they drive.

use std::path::PathBuf;

use motionlink_scu::model::SpeedMode;
use motionlink_scu::{SimConfig, Variants};

use crate::common::CliError;

/// The emulator's configuration: `preset` (scp11, tlt, liftkit), then the file at `path` over it (a file
/// naming no preset of its own starts from `preset`), then the firmware `variants` named (each may be
/// several names separated by commas), added to the file's.
pub(crate) fn load_sim_config(
    path: Option<&PathBuf>,
    preset: Option<&str>,
    variants: &[String],
) -> Result<SimConfig, CliError> {
    let base = match preset {
        Some(name) => SimConfig::preset(name).ok_or_else(|| unknown_preset(name))?,
        None => SimConfig::default(),
    };
    match path {
        Some(path) => SimConfig::from_toml_over(&crate::common::config_text(path)?, preset, variants)
            .map_err(|e| CliError::usage(format!("{}: {e}", path.display()))),
        None => {
            let mut config = base;
            config.variants.extend(&Variants::parse_all(variants).map_err(|e| CliError::usage(e.to_string()))?);
            Ok(config)
        }
    }
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
/// Otherwise the unit is the one `--sim-preset` and `--functions` describe
/// ([`motionlink_scu::args::emulated_unit`]), with the firmware variants asked for.
pub(crate) fn in_process_config(unit: &InProcess<'_>) -> Result<SimConfig, CliError> {
    if unit.file.is_some() {
        return load_sim_config(unit.file, unit.preset, unit.variants);
    }
    let mut config = motionlink_scu::args::emulated_unit(unit.preset, unit.functions, unit.speed_mode)
        .map_err(|e| CliError::usage(format!("--port sim: {e}")))?;
    let variants = Variants::parse_all(unit.variants).map_err(|e| CliError::usage(e.to_string()))?;
    config.variants.extend(&variants);
    Ok(config)
}
