//! Every numeric option and argument of every family, given a negative number, a zero where none is taken,
//! and something that is no number: exit 2 before anything is opened, with a message that names the
//! option and says why (never clap's "unexpected argument '-5'" or a bare "invalid digit found in string").

use super::{ml, stderr};

/// A port where nothing listens: an option that slipped through would end with exit 3, not 2.
const NOWHERE: &str = "tcp://127.0.0.1:1";

/// One numeric option: the command line with `V` where the value goes, the name the message must give, and
/// which of the bad values apply (a negative number, zero, a word).
struct Case {
    args: &'static [&'static str],
    names: &'static str,
    negative: bool,
    zero: bool,
}

const fn case(args: &'static [&'static str], names: &'static str, negative: bool, zero: bool) -> Case {
    Case { args, names, negative, zero }
}

/// Options whose value must be positive (negative and zero refused) or at least 0 (negative refused).
const SCU: &[Case] = &[
    case(&["--baud", "V", "info"], "--baud", true, true),
    case(&["--safety", "V", "info"], "--safety", true, false),
    case(&["--timeout-ms", "V", "info"], "--timeout-ms", true, true),
    case(&["--tolerance", "V", "info"], "--tolerance", true, false),
    case(&["--poll-ms", "V", "info"], "--poll-ms", true, true),
    case(&["move", "V", "100"], "ACTUATOR", true, true),
    case(&["move", "1", "V"], "POSITION", false, false),
    case(&["move", "1", "100", "--speed", "V"], "--speed", true, true),
    case(&["move", "1", "100", "--function", "V"], "--function", true, true),
    case(&["follow", "1", "--speed", "V"], "--speed", true, true),
    case(&["follow", "1", "--rate", "V"], "--rate", true, true),
    case(&["follow", "V"], "ACTUATOR", true, true),
    case(&["run", "F1", "out", "--seconds", "V"], "--seconds", true, false),
    case(&["watch", "--interval-ms", "V"], "--interval-ms", true, true),
    case(&["watch", "--count", "V"], "--count", true, true),
];

const POWERCUBE: &[Case] = &[
    case(&["--module", "V", "info"], "--module", true, true),
    case(&["--baud", "V", "info"], "--baud", true, true),
    case(&["--bitrate", "V", "info"], "--bitrate", true, true),
    case(&["--timeout-ms", "V", "info"], "--timeout-ms", true, true),
    case(&["--poll-ms", "V", "info"], "--poll-ms", true, true),
    case(&["move", "V"], "POSITION", false, false),
    case(&["move", "1", "--vel", "V"], "--vel", true, true),
    case(&["move", "1", "--acc", "V"], "--acc", true, true),
    case(&["move", "1", "--timeout-s", "V"], "--timeout-s", true, true),
    case(&["move", "1", "--tolerance", "V"], "--tolerance", true, true),
    case(&["home", "--timeout-s", "V"], "--timeout-s", true, true),
    case(&["watch", "--interval-ms", "V"], "--interval-ms", true, true),
    case(&["watch", "--count", "V"], "--count", true, true),
];

const COMPAX: &[Case] = &[
    case(&["--drive", "V", "status"], "--drive", true, true),
    case(&["--mode", "V", "status"], "--mode", true, false),
    case(&["--baud", "V", "status"], "--baud", true, true),
    case(&["--timeout-ms", "V", "status"], "--timeout-ms", true, true),
    case(&["move", "V"], "POSITION", false, false),
    case(&["move", "--abs", "V"], "--abs", false, false),
    case(&["move", "--rel", "V"], "--rel", false, false),
    case(&["move", "1", "--speed", "V"], "--speed", true, true),
    case(&["move", "1", "--accel", "V"], "--accel", true, true),
    case(&["move", "1", "--timeout-s", "V"], "--timeout-s", true, true),
    case(&["move", "1", "--tolerance", "V"], "--tolerance", true, true),
    case(&["move", "1", "--min-pos", "V"], "--min-pos", false, false),
    case(&["move", "1", "--max-pos", "V"], "--max-pos", false, false),
    case(&["move", "1", "--poll-ms", "V"], "--poll-ms", true, true),
    case(&["watch", "--interval-ms", "V"], "--interval-ms", true, true),
    case(&["watch", "--count", "V"], "--count", true, true),
    case(&["raw", "S1", "--wait", "--timeout-s", "V"], "--timeout-s", true, true),
    case(&["raw", "S1", "--wait", "--poll-ms", "V"], "--poll-ms", true, true),
    case(&["output", "V", "1"], "NUMBER", true, false),
    case(&["output", "1", "V"], "STATE", true, false),
    case(&["set", "P12", "V"], "VALUE", false, false),
];

/// What a refusal must not be: clap taking the number for an option, or a parser's bare complaint.
const NOT_A_REASON: &[&str] =
    &["unexpected argument", "invalid digit", "invalid float literal", "is not in ", "tip: to pass"];

fn refuses(family: &str, cases: &[Case]) {
    for c in cases {
        let bad = [("-5", c.negative), ("0", c.zero), ("abc", true)];
        for (value, applies) in bad {
            if !applies {
                continue;
            }
            let mut args = vec![family, "--port", NOWHERE];
            args.extend(c.args.iter().map(|a| if *a == "V" { value } else { a }));
            let out = ml(&args);
            let err = stderr(&out);
            assert_eq!(out.status.code(), Some(2), "{args:?}: exit 2 before anything is opened: {err}");
            let first = err.lines().next().unwrap_or_default();
            assert!(first.contains(c.names), "{args:?}: the message names {}: {err}", c.names);
            assert!(first.contains(value), "{args:?}: the message gives the value: {err}");
            assert!(!NOT_A_REASON.iter().any(|n| err.contains(n)), "{args:?}: say why: {err}");
        }
    }
}

#[test]
fn every_numeric_option_of_the_scu_names_itself_and_why() {
    refuses("scu", SCU);
    // As the issue asks: a negative velocity is the velocity below 0, with its unit.
    let err = stderr(&ml(&["powercube", "--port", NOWHERE, "move", "1.0", "--vel", "-5"]));
    assert!(err.contains("'-5' for '--vel <VEL>': the velocity must be a number above 0 (rad/s or m/s"), "{err}");
}

#[test]
fn every_numeric_option_of_the_powercube_names_itself_and_why() {
    refuses("powercube", POWERCUBE);
}

#[test]
fn every_numeric_option_of_the_compax_names_itself_and_why() {
    refuses("compax", COMPAX);
}

#[test]
fn the_numeric_options_of_the_emulators_and_the_decoder_name_themselves_and_why() {
    let cases: &[(&[&str], &str)] = &[
        (&["sim", "compax", "--tcp", "127.0.0.1:0", "--mode", "V"], "--mode"),
        (&["sim", "compax", "--tcp", "127.0.0.1:0", "--baud", "V"], "--baud"),
        (&["sim", "compax", "--tcp", "127.0.0.1:0", "--drives", "1,V"], "--drives"),
        (&["sim", "powercube", "--tcp", "127.0.0.1:0", "--modules", "V"], "--modules"),
        (&["decode", "compax", "--mode", "V", "31 0D"], "--mode"),
    ];
    for (args, names) in cases {
        for value in ["-5", "abc"] {
            let args: Vec<String> = args.iter().map(|a| a.replace('V', value)).collect();
            let args: Vec<&str> = args.iter().map(String::as_str).collect();
            // An emulator that took the value would serve until killed: the wait ends it and fails.
            let ended = crate::common::Running::start(&args).wait(std::time::Duration::from_secs(10));
            assert_eq!(ended.code(), 2, "{args:?}: {}", ended.stderr);
            assert!(ended.stderr.contains(names) && ended.stderr.contains(value), "{args:?}: {}", ended.stderr);
            assert!(!NOT_A_REASON.iter().any(|n| ended.stderr.contains(n)), "{args:?}: say why: {}", ended.stderr);
        }
    }
}
