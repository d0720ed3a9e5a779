//! `motionlink decode scu`.

use motionlink_link::chunk::Direction;
use motionlink_scu::describe::Describer;

use crate::common::CliError;
use crate::decode::CaptureArgs;

/// `motionlink decode scu` arguments.
#[derive(clap::Args, Debug)]
pub struct DecodeArgs {
    #[command(flatten)]
    pub capture: CaptureArgs,
}

/// `motionlink decode scu`: the library's describer over the capture; lines without a direction mark are
/// told apart by their bytes.
pub fn decode(args: DecodeArgs, json: bool) -> Result<(), CliError> {
    crate::decode::run(&args.capture, json, &mut Describer::new(), Direction::Unknown)
}
