//! `motionlink scu`: to be built (see the scu issue).

use crate::common::{CaptureArgs, CliError, ServeArgs};

/// `motionlink scu` arguments.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The port: a device path, tcp://HOST:PORT, or sim.
    #[arg(long)]
    pub port: String,
}

/// `motionlink sim scu` arguments.
#[derive(clap::Args, Debug)]
pub struct SimArgs {
    #[command(flatten)]
    pub serve: ServeArgs,
}

/// `motionlink decode scu` arguments.
#[derive(clap::Args, Debug)]
pub struct DecodeArgs {
    #[command(flatten)]
    pub capture: CaptureArgs,
}

pub fn run(_args: Args) -> Result<(), CliError> {
    Err(CliError::usage("the scu family is not built yet"))
}

pub fn sim(_args: SimArgs) -> Result<(), CliError> {
    Err(CliError::usage("the scu family is not built yet"))
}

pub fn decode(_args: DecodeArgs) -> Result<(), CliError> {
    Err(CliError::usage("the scu family is not built yet"))
}

pub fn demo(_out: &mut dyn std::io::Write) -> Result<(), CliError> {
    Ok(())
}
