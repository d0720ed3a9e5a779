//! Tests of the COMPAX command line's argument checks and error messages.

use super::*;
use clap::Parser;

const D3: motionlink_compax::wire::Address = motionlink_compax::wire::Address::drive_const(3);

/// A position in the drive's unit.
fn p(units: f64) -> motionlink_compax::model::Position {
    motionlink_compax::model::Position::new(units).unwrap()
}

#[derive(clap::Parser, Debug)]
struct TestCli {
    #[command(flatten)]
    args: Args,
}

fn args(line: &[&str]) -> Args {
    TestCli::parse_from(std::iter::once("compax").chain(line.iter().copied())).args
}

#[test]
fn errors_map_to_exit_codes_and_say_how_to_switch_a_drive_on() {
    let a = args(&["--port", "tcp://gw:4001", "--mode", "8", "--drive", "3", "status"]);
    let not_reached =
        Error::NotReached { address: D3, target: p(100.0), reached: p(37.5), difference: p(-62.5), tolerance: p(0.01) };
    let e = error_for(&a, not_reached);
    assert_eq!(e.exit_code(), 1);
    assert!(e.to_string().contains("target 100, reached 37.5, difference -62.500"), "{e}");
    let stop = motionlink_compax::error::StopReport {
        drives: vec![(Address::drive(3).unwrap(), motionlink_compax::error::StopOutcome::SwitchedOff)],
    };
    let mismatch = Error::FailedDuringMotion {
        cause: Box::new(Error::TargetMismatch { address: D3, requested: p(15.0), taken: p(14.0) }),
        stop,
    };
    let e = error_for(&a, mismatch);
    assert_eq!(e.exit_code(), 1);
    let text = e.to_string();
    assert!(text.contains("took target 14 instead of 15"), "{text}");
    assert!(text.contains("motionlink compax --port tcp://gw:4001 --mode 8 --drive 3 output 0 1"), "{text}");
    let lost = Error::FailedDuringMotion {
        cause: Box::new(Error::Timeout {
            address: D3,
            command: "S17".into(),
            attempts: 4,
            waited: std::time::Duration::from_millis(210),
            round_trips: None,
            late: None,
        }),
        stop: motionlink_compax::error::StopReport {
            drives: vec![(
                Address::drive(3).unwrap(),
                motionlink_compax::error::StopOutcome::NotConfirmed { reason: "no reply".into() },
            )],
        },
    };
    let e = error_for(&a, lost);
    assert_eq!(e.exit_code(), 3);
    assert!(e.to_string().contains("may still be moving") && !e.to_string().contains("output 0 1"), "{e}");
    let limits = Error::OutsideLimits { address: D3, target: p(50.0), side: "above the maximum", limit: p(40.0) };
    assert_eq!(error_for(&a, limits).exit_code(), 2);
    let off = Error::SwitchedOff { address: D3, o0: 0, refused: None };
    let e = error_for(&a, off);
    assert_eq!(e.exit_code(), 1);
    assert!(e.to_string().contains("--drive 3 output 0 1"), "{e}");
    let read_back = Error::ReadBack { address: D3, param: ParamId::new(3).unwrap(), wrote: -1055.88, read: -1055.89 };
    assert_eq!(error_for(&a, read_back).exit_code(), 1);
}
