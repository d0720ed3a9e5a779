//! `motionlink decode powercube`: RS232 bytes (hex or raw), `--capture` files or candump lines, each
//! telegram explained by the library's describer.

use motionlink_link::chunk::Direction;
use motionlink_powercube::describe::Describer;

use crate::common::CliError;
use crate::decode::CaptureArgs;

/// `motionlink decode powercube` arguments.
#[derive(clap::Args, Debug)]
pub struct DecodeArgs {
    #[command(flatten)]
    pub capture: CaptureArgs,
}

/// `motionlink decode powercube`: capture lines (a `--capture` file, candump logs, hex) or raw bytes, each
/// telegram explained by the library's describer.
pub fn decode(args: DecodeArgs, json: bool) -> Result<(), CliError> {
    crate::decode::run(&args.capture, json, &mut Describer::new(), Direction::Unknown)
}
