//! `motionlink probe powercube`.

use crate::common::CliError;

/// `motionlink probe powercube` arguments.
#[derive(clap::Args, Debug)]
pub struct Args {}

/// `motionlink probe powercube ...`
pub fn run(_args: Args, _json: bool) -> Result<(), CliError> {
    Err(CliError::usage("not yet"))
}
