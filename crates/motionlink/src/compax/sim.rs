//! `motionlink sim compax`.

use motionlink_compax::sim::SimConfig;

use super::*;

/// `motionlink sim compax` arguments.
#[derive(clap::Args, Debug)]
pub struct SimArgs {
    #[command(flatten)]
    pub serve: ServeArgs,
    /// Addresses of the emulated drives, such as 1,5 (default 1).
    #[arg(long, value_delimiter = ',')]
    pub drives: Option<Vec<Address>>,
    /// P196 of every drive (default 0).
    #[arg(long)]
    pub mode: Option<Mode>,
    /// The line's and the drives' baud rate (default 9600).
    #[arg(long)]
    pub baud: Option<BaudRate>,
    /// A TOML file describing the bus (see the motionlink-compax README); the options above override it.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// A parameter besides P194..P196 that every drive models, with its value at power-on, such as P12=0
    /// (repeatable). The drives refuse (E90) every other parameter.
    #[arg(long = "param", value_name = "PNNN=VALUE")]
    pub params: Vec<String>,
    #[command(flatten)]
    pub variants: crate::common::Variants<Variant>,
}

/// Runs `motionlink sim compax`.
pub fn sim(args: SimArgs) -> Result<(), CliError> {
    let mut cfg = match &args.config {
        Some(path) => SimConfig::from_toml(&common::config_text(path)?).map_err(CliError::usage)?,
        None => SimConfig::default(),
    };
    let addresses: Option<Vec<u8>> = args.drives.as_ref().map(|d| d.iter().map(|a| a.get()).collect());
    cfg = cfg.overridden(addresses.as_deref(), args.mode.map(|m| m.to_p196()), args.baud.map(|b| b.bits_per_s()));
    for p in &args.params {
        let (name, value) =
            p.split_once('=').ok_or_else(|| CliError::usage(format!("--param {p}: expected PNNN=VALUE")))?;
        let id = ParamId::parse(name).map_err(|e| CliError::usage(format!("--param {p}: {e}")))?;
        let value: f64 =
            value.trim().parse().map_err(|_| CliError::usage(format!("--param {p}: {value:?} is not a number")))?;
        cfg = cfg.with_param(id, value);
    }
    cfg.add_variants(args.variants.list.iter().copied());
    let bus = Emulator::new(cfg).map_err(CliError::usage)?;
    common::serve(&args.serve, bus)
}
