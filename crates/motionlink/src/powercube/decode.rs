//! `motionlink decode powercube`: RS232 bytes (hex or raw) or candump lines, each telegram explained by the
//! library's describer.

use motionlink_link::describe::{Annotation, Direction};
use motionlink_powercube::describe::Describer;

use crate::common::{self, CliError};
use crate::decode::CaptureArgs;

/// `motionlink decode powercube` arguments.
#[derive(clap::Args, Debug)]
pub struct DecodeArgs {
    #[command(flatten)]
    pub capture: CaptureArgs,
}

/// One annotated RS232 telegram as `decode` and the demo print it: its bytes, then what they mean.
pub fn rs232_line(a: &Annotation) -> String {
    format!("{:<36}  {}", common::hex(&a.bytes), a.meaning)
}

/// `motionlink decode powercube`: capture lines (a `--capture` file, candump logs, hex) or raw bytes, each
/// telegram explained by the library's describer.
pub fn decode(args: DecodeArgs, json: bool) -> Result<(), CliError> {
    crate::decode::run(&args.capture, json, &mut Describer::new(), Direction::Unknown)
}

#[cfg(test)]
mod tests {
    use motionlink_link::describe::Annotation;

    #[test]
    fn an_rs232_line_is_bytes_then_meaning() {
        let a = Annotation {
            at: None,
            direction: motionlink_link::describe::Direction::ToDevice,
            can_id: None,
            bytes: vec![0x02, 0x06],
            meaning: "x".into(),
            bad: false,
        };
        assert!(super::rs232_line(&a).starts_with("02 06 ") && super::rs232_line(&a).ends_with("  x"));
    }
}
