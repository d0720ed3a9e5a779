//! `motionlink sim powercube`.

use super::*;

/// `motionlink sim powercube` arguments.
#[derive(clap::Args, Debug)]
pub struct SimArgs {
    #[command(flatten)]
    pub serve: ServeArgs,
    /// Module addresses, such as 1,17 (default: one module at 1).
    #[arg(long, value_delimiter = ',', conflicts_with = "config")]
    pub modules: Vec<Address>,
    /// A TOML file describing the modules (see crates/motionlink-powercube/README.md).
    #[arg(long, value_name = "FILE")]
    pub config: Option<std::path::PathBuf>,
    /// Serve the modules on CAN through an emulated SLCAN serial adapter instead of RS232 framing.
    #[arg(long)]
    pub slcan: bool,
    /// Drop RS232 frames with a wrong BCC (the modules accept them).
    #[arg(long)]
    pub strict: bool,
    #[command(flatten)]
    pub variants: crate::common::Variants<Variant>,
}

/// `motionlink sim powercube ...`
pub fn sim(args: SimArgs) -> Result<(), CliError> {
    let mut config = match (&args.config, args.modules.is_empty()) {
        (Some(path), _) => SimConfig::from_toml(&common::config_text(path)?).map_err(CliError::usage)?,
        (None, true) => SimConfig::default(),
        (None, false) => SimConfig::with_addresses(&args.modules.iter().map(|a| a.get()).collect::<Vec<_>>())
            .map_err(CliError::usage)?,
    };
    config.add_variants(args.variants.list.iter().copied());
    if args.slcan {
        if args.strict {
            return Err(CliError::usage("--strict is about RS232 BCCs; it has no meaning with --slcan"));
        }
        common::serve_behind(&args.serve, SlcanAdapter::new(Emulator::new_can(&config)), "slcan://")
    } else {
        let mut bus = Emulator::new(&config);
        bus.set_strict_bcc(args.strict);
        common::serve(&args.serve, bus)
    }
}
