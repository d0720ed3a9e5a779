//! `motionlink probe compax`.

use crate::common::CliError;

/// `motionlink probe compax` arguments.
#[derive(clap::Args, Debug)]
pub struct Args {}

/// `motionlink probe compax ...`
pub fn run(_args: Args, _json: bool) -> Result<(), CliError> {
    Err(CliError::usage("not yet"))
}
