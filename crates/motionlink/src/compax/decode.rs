//! `motionlink decode compax`.

use motionlink_link::chunk::Direction as Way;
use motionlink_link::describe::Annotation;

use super::*;

/// `motionlink decode compax` arguments.
#[derive(clap::Args, Debug)]
pub struct DecodeArgs {
    #[command(flatten)]
    pub capture: CaptureArgs,
    /// P196 of the capture (BCC, reply end, address prefix).
    #[arg(long, default_value = "0")]
    pub mode: Mode,
    /// Which way the bytes went: auto (guess each telegram), host (requests only), drive (replies only).
    #[arg(long, value_enum, default_value_t = Direction::Auto)]
    pub direction: Direction,
}

/// One annotation as `decode` and the demo print it: the bytes in hex, then what they mean.
pub(super) fn line(a: &Annotation) -> String {
    format!("{:<40} {}", motionlink_link::hex::hex(&a.bytes), a.meaning)
}

/// Runs `motionlink decode compax`: lines without a direction mark went the way `--direction` says.
pub fn decode(args: DecodeArgs, json: bool) -> Result<(), CliError> {
    let mode = args.mode;
    let way = match args.direction {
        Direction::Auto => Way::Unknown,
        Direction::Host => Way::ToDevice,
        Direction::Drive => Way::FromDevice,
    };
    crate::decode::run(&args.capture, json, &mut Describer::new(mode), way)
}
