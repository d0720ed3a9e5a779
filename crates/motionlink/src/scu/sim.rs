//! `motionlink sim scu`, and the emulated unit of `--port sim` (the command's own process, and the
//! console's): a preset, a configuration file, and for `--port sim` the unit the command names, whose
//! functions drive what `--functions` says they drive.

use std::path::PathBuf;

use motionlink_scu::model::SpeedMode;
use motionlink_scu::{Emulator, SimConfig, Variant};

use crate::common::{self, CliError, ServeArgs};

/// The emulator's configuration: `preset` (scp11, tlt, liftkit), then the file at `path` over it (a file
/// naming no preset of its own starts from `preset`), then the firmware `variants`, added to the file's.
pub(crate) fn load_sim_config(
    path: Option<&PathBuf>,
    preset: Option<&str>,
    variants: &[Variant],
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
            config.add_variants(variants.iter().copied());
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
    pub variants: &'a [Variant],
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
    config.add_variants(unit.variants.iter().copied());
    Ok(config)
}

/// `motionlink sim scu` arguments.
#[derive(clap::Args, Debug)]
pub struct SimArgs {
    #[command(flatten)]
    pub serve: ServeArgs,
    /// Parameterisation (TOML): actuators, function mapping, stroke, speed, variants. See docs/scu.md (Emulator).
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Start from a preset: scp11 (default; actuator n on Fn), tlt (F1 drives both columns, F2 and F3 one each)
    /// or liftkit (F1 actuator 1, F2 actuator 2, F8 both, as the public LIFTKIT/TLT drivers assume).
    #[arg(long, value_parser = ["scp11", "tlt", "liftkit"])]
    pub preset: Option<String>,
    #[command(flatten)]
    pub variants: crate::common::Variants<Variant>,
}

/// `motionlink sim scu`
pub fn sim(args: SimArgs) -> Result<(), CliError> {
    let config = load_sim_config(args.config.as_ref(), args.preset.as_deref(), &args.variants.list)?;
    config.check_servable().map_err(|e| CliError::usage(e.to_string()))?;
    let device = Emulator::new(config).map_err(|e| CliError::usage(e.to_string()))?;
    common::serve(&args.serve, device)
}
