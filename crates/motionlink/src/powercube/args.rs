//! Checks of `motionlink powercube`'s arguments that need no port: the rates a line can run at and
//! durations in seconds. Each names the option it refuses (exit 2); the numbers of `move` and `home` are
//! checked as clap parses them ([`crate::numbers`]).

use std::time::Duration;

use crate::common::CliError;
use motionlink_link::can::SlcanBitrate;

/// The RS232 baud rates `--baud` takes: the standard rates of a serial port from 1200 up (the modules run
/// at 9600 unless DefPrimBaud says otherwise).
const BAUD_RATES: [u32; 8] = [1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200];

/// The CAN bit rates an SLCAN adapter offers (`S0` .. `S8`), for `--bitrate`.
const SLCAN_BIT_RATES: [u32; 9] = [10_000, 20_000, 50_000, 100_000, 125_000, 250_000, 500_000, 800_000, 1_000_000];

fn rates(list: &[u32]) -> String {
    list.iter().map(u32::to_string).collect::<Vec<_>>().join(", ")
}

/// `--baud`: one of [`BAUD_RATES`] (clap names the option and exits 2 otherwise, before anything is opened).
pub(super) fn parse_baud(s: &str) -> Result<u32, String> {
    match s.parse::<u32>() {
        Ok(b) if BAUD_RATES.contains(&b) => Ok(b),
        _ => Err(format!("not an RS232 baud rate; give one of {}", rates(&BAUD_RATES))),
    }
}

/// `--bitrate`: one of the rates SLCAN offers.
pub(super) fn parse_bitrate(s: &str) -> Result<u32, String> {
    match s.parse::<u32>() {
        Ok(b) if SlcanBitrate::from_bps(b).is_some() => Ok(b),
        _ => Err(format!("not a CAN bit rate an SLCAN adapter offers; give one of {}", rates(&SLCAN_BIT_RATES))),
    }
}

/// A duration in seconds that must be a number above 0, for `--timeout-s`.
pub(super) fn positive_secs(name: &str, s: f64) -> Result<Duration, CliError> {
    if !(s.is_finite() && s > 0.0) {
        return Err(CliError::usage(format!("{name} must be a number of seconds above 0, not {s}")));
    }
    Duration::try_from_secs_f64(s).map_err(|_| CliError::usage(format!("{name} {s} is not a duration in seconds")))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_bit_rates_offered_are_the_ones_slcan_takes() {
        for b in SLCAN_BIT_RATES {
            assert_eq!(parse_bitrate(&b.to_string()), Ok(b));
        }
        for bad in ["0", "12345", "2000000", "-1", "fast"] {
            let e = parse_bitrate(bad).unwrap_err();
            assert!(e.contains("10000, 20000") && e.contains("1000000"), "{e}");
        }
        assert_eq!(parse_baud("9600"), Ok(9600));
        assert!(parse_baud("7").unwrap_err().contains("9600"));
    }
}
