//! What the command says, through the built binary: one plain message per error at the default verbosity
//! (logs only with `-v`), a misspelt name answered with the nearest real one, units in text output, an
//! absent device named as absent, COMPAX's plain move target, and (in `numbers`) every numeric option that
//! refuses a value saying which and why.

mod numbers;

use std::net::TcpListener;
use std::process::Output;
use std::time::Duration;

use crate::common;

use common::{run_with, Running, Sim};

const TEN_S: Duration = Duration::from_secs(10);

/// A TCP port that accepts connections and never answers (a serial gateway with nothing on its line).
fn silent_port() -> String {
    let listener = TcpListener::bind("127.0.0.1:0").expect("bind");
    let address = format!("tcp://{}", listener.local_addr().unwrap());
    std::thread::spawn(move || {
        let mut held = Vec::new();
        for stream in listener.incoming().map_while(Result::ok) {
            held.push(stream);
        }
    });
    address
}

fn ml(args: &[&str]) -> Output {
    run_with(args, &[], "")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// True if `line` looks like a log line of the tracing formatter: a timestamp or a level column.
fn is_log_line(line: &str) -> bool {
    let stamped = line.len() > 20 && line.as_bytes()[..4].iter().all(u8::is_ascii_digit) && line[4..].starts_with('-');
    stamped || [" WARN ", " ERROR ", " INFO ", " DEBUG "].iter().any(|l| line.contains(l))
}

#[test]
fn an_scu_that_does_not_answer_is_one_plain_message_naming_port_cable_baud_and_power() {
    let port = silent_port();
    let out = ml(&["scu", "--port", &port, "--timeout-ms", "300", "info"]);
    assert_eq!(out.status.code(), Some(3), "{out:?}");
    let err = stderr(&out);
    assert_eq!(err.lines().count(), 1, "one message, no log lines: {err}");
    assert!(!is_log_line(&err), "{err}");
    assert!(err.starts_with(&format!("motionlink: the SCU on {port} does not answer")), "{err}");
    for said in ["cable", "--baud 38400", "powered"] {
        assert!(err.contains(said), "{said}: {err}");
    }
    // The JSON kind stays what it was: a timeout.
    let out = ml(&["--json", "scu", "--port", &port, "--timeout-ms", "300", "info"]);
    let e = common::json_error(&out);
    assert_eq!((e["kind"].as_str(), e["exit_code"].as_i64()), (Some("timeout"), Some(3)), "{e}");
    // With -vv the logs are there, as log lines.
    let out = ml(&["-vv", "scu", "--port", &port, "--timeout-ms", "300", "info"]);
    assert!(stderr(&out).lines().any(|l| is_log_line(l) && l.contains("DEBUG")), "{}", stderr(&out));
}

#[test]
fn a_module_or_drive_that_does_not_answer_is_named_with_the_scan_that_lists_what_is_there() {
    let sim = Sim::tcp("powercube");
    let port = sim.address.as_str();
    let out = ml(&["powercube", "--port", port, "--module", "9", "info"]);
    assert_eq!(out.status.code(), Some(3), "{out:?}");
    let expected = format!(
        "motionlink: no module answers at address 9 on {port}; `motionlink powercube --port {port} scan` lists the \
         modules there\n"
    );
    assert_eq!(stderr(&out), expected);
    assert_eq!(
        common::json_error(&ml(&["--json", "powercube", "--port", port, "--module", "9", "info"]))["kind"],
        "timeout"
    );
    // The scan it names does list the module that is there.
    let scan = ml(&["powercube", "--port", port, "scan"]);
    assert!(scan.status.success() && stdout(&scan).lines().any(|l| l.starts_with("1 ")), "{scan:?}");

    let sim = Sim::tcp("compax");
    let port = sim.address.as_str();
    let out = ml(&["compax", "--port", port, "--drive", "9", "--timeout-ms", "50", "status"]);
    assert_eq!(out.status.code(), Some(3), "{out:?}");
    let expected = format!(
        "motionlink: drive 9 does not answer on {port}; `motionlink compax --port {port} scan` lists the drives there\n"
    );
    assert_eq!(stderr(&out), expected);
    let scan = ml(&["compax", "--port", port, "scan"]);
    assert!(scan.status.success() && stdout(&scan).contains("drive 1"), "{scan:?}");
}

/// `stop` of a device that does not answer first says what the stop did, then names the device as absent:
/// a PowerCube's Halt, sent three times (it may be repeated), not acknowledged; a COMPAX drive's stop not
/// confirmed; for the SCU, that no RS went out (it needs the remote mode that RO opens). Each may leave an
/// axis moving, and the message must not read as a mere wrong address.
#[test]
fn a_stop_that_nobody_answers_says_what_it_did_before_naming_the_device_absent() {
    let sim = Sim::tcp("powercube");
    let port = sim.address.as_str();
    let out = ml(&["powercube", "--port", port, "--module", "9", "--timeout-ms", "50", "stop"]);
    assert_eq!(out.status.code(), Some(3), "{out:?}");
    let err = stderr(&out);
    assert!(err.starts_with("motionlink: module 9: Halt not acknowledged (3 sent): "), "{err}");
    assert!(err.contains("; the axis may still be moving; no module answers at address 9 on"), "{err}");

    let sim = Sim::tcp("compax");
    let port = sim.address.as_str();
    let out = ml(&["compax", "--port", port, "--drive", "9", "--timeout-ms", "50", "stop"]);
    assert_eq!(out.status.code(), Some(3), "{out:?}");
    let err = stderr(&out);
    assert!(err.starts_with("motionlink: drive 9: the stop was NOT confirmed by the drive"), "{err}");
    assert!(err.contains("the axis may still be moving; drive 9 does not answer on"), "{err}");
    // Both say it as data too: a stop sent and not confirmed.
    let ps = Sim::tcp("powercube");
    for (family, unit, port) in [("powercube", "--module", ps.address.as_str()), ("compax", "--drive", port)] {
        let e = common::json_error(&ml(&["--json", family, "--port", port, unit, "9", "--timeout-ms", "50", "stop"]));
        assert_eq!(
            (&e["kind"], &e["stop_unconfirmed"]),
            (&serde_json::json!("timeout"), &serde_json::json!(true)),
            "{e}"
        );
    }

    let port = silent_port();
    let out = ml(&["scu", "--port", &port, "--timeout-ms", "300", "stop"]);
    assert_eq!(out.status.code(), Some(3), "{out:?}");
    let err = stderr(&out);
    let said = format!(
        "motionlink: this command sent no RS (RS needs the remote mode RO opens): the SCU on {port} does not answer"
    );
    assert!(err.starts_with(&said), "{err}");
    // The SCU's stop that sent nothing is a stop not confirmed too.
    let e = common::json_error(&ml(&["--json", "scu", "--port", &port, "--timeout-ms", "300", "stop"]));
    assert_eq!((&e["kind"], &e["stop_unconfirmed"]), (&serde_json::json!("timeout"), &serde_json::json!(true)), "{e}");
}

#[cfg(unix)]
#[test]
fn ctrl_c_during_a_compax_move_prints_no_log_lines() {
    let sim = Sim::tcp("compax");
    let run = Running::start(&["compax", "--port", &sim.address, "move", "1000", "--speed", "10"]);
    sim.wait_event(TEN_S, |t| t.starts_with("drive 1 motion started")).expect("the move started");
    run.signal(libc::SIGINT);
    let ended = run.wait(TEN_S);
    assert_eq!(ended.code(), 130, "{}", ended.stderr);
    assert!(!ended.stderr.lines().any(is_log_line), "no log lines at the default verbosity: {}", ended.stderr);
    assert!(ended.stderr.contains("SIGINT received") && ended.stderr.contains("switched off"), "{}", ended.stderr);
}

#[test]
fn a_warning_meant_for_the_user_is_one_plain_line() {
    // No lock file can be made: another motionlink would not see this one. Said once, plainly.
    let sim = Sim::tcp("scu");
    let out =
        run_with(&["scu", "--port", &sim.address, "get", "remote_speed_f1"], &[("XDG_RUNTIME_DIR", "/dev/null")], "");
    assert!(out.status.success(), "{out:?}");
    let err = stderr(&out);
    let warnings: Vec<&str> = err.lines().filter(|l| l.contains("no lock file")).collect();
    assert_eq!(warnings.len(), 1, "{err}");
    assert!(warnings[0].starts_with("motionlink: warning: no lock file for "), "{err}");
    assert!(!is_log_line(warnings[0]), "{err}");
}

#[test]
fn a_misspelt_name_suggests_the_nearest_real_one() {
    let cases: &[(&[&str], &str)] = &[
        (&["scu", "--port", "sim", "set", "remote_sped_f1", "80"], "did you mean remote_speed_f1?"),
        (&["scu", "--port", "sim", "get", "actual_positons"], "did you mean actual_positions?"),
        (&["scu", "--port", "sim", "run", "F1", "otu"], "did you mean out?"),
        (&["scu", "--port", "sim", "send", "GR", "remote_speed_f1"], "did you mean RG?"),
        (&["powercube", "--port", "sim", "get", "ActPoss"], "did you mean ActPos?"),
        (&["powercube", "--port", "sim", "send", "hlat"], "did you mean halt?"),
        (&["compax", "--port", "sim", "status", "actual_postion"], "did you mean actual_position?"),
        (&["compax", "--port", "sim", "get", "devce_address"], "did you mean device_address?"),
        (&["powercube", "--port", "sim", "stpo"], "a similar subcommand exists: 'stop'"),
        (&["scu", "--port", "sim", "inof"], "a similar subcommand exists: 'info'"),
        (&["powercube", "--port", "sim", "move", "1", "--vell", "0.5"], "a similar argument exists: '--vel'"),
        (&["compax", "--port", "sim", "move", "1", "--sped", "50"], "a similar argument exists: '--speed'"),
    ];
    for (args, hint) in cases {
        let out = ml(args);
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(hint), "{args:?}: {err}");
    }
    // Only the nearest: `stpo` is one swap from stop, three edits from set.
    let err = stderr(&ml(&["powercube", "--port", "sim", "stpo"]));
    assert!(!err.contains("'set'"), "{err}");
    let err = stderr(&ml(&["powercube", "--port", "sim", "get", "ActPoss"]));
    assert!(!err.contains("ActPos_"), "{err}");
    // Nothing near: no guess.
    let err = stderr(&ml(&["scu", "--port", "sim", "get", "banana"]));
    assert!(!err.contains("did you mean") && err.contains("`motionlink scu names` lists them"), "{err}");
}

#[test]
fn compax_move_takes_a_plain_target_as_an_absolute_one() {
    let sim = Sim::tcp("compax");
    let port = sim.address.as_str();
    let moved = |args: &[&str]| {
        let out = ml(&[&["--json", "compax", "--port", port, "move"], args].concat());
        assert!(out.status.success(), "{args:?}: {out:?}");
        serde_json::from_str::<serde_json::Value>(stdout(&out).trim()).unwrap()
    };
    assert_eq!(moved(&["20"])["reached_units"], 20.0);
    assert_eq!(moved(&["--abs", "25"])["reached_units"], 25.0);
    assert_eq!(moved(&["--rel", "-5"])["reached_units"], 20.0);
    assert_eq!(moved(&["-10"])["reached_units"], -10.0, "a negative plain target");
    for (args, other) in [(&["30", "--abs", "40"], "--abs"), (&["30", "--rel", "5"], "--rel")] {
        let out = ml(&[&["compax", "--port", port, "move"], &args[..]].concat());
        assert_eq!(out.status.code(), Some(2), "{args:?}: {out:?}");
        let err = stderr(&out);
        assert!(err.contains("[POSITION]") && err.contains(other), "names both: {err}");
    }
    let out = ml(&["compax", "--port", port, "move"]);
    assert_eq!(out.status.code(), Some(2), "{out:?}");
    let text = stdout(&ml(&["compax", "--port", port, "move", "22"]));
    assert_eq!(text, "drive 1: target 22 units, position 22 units\n");
}

#[test]
fn text_output_gives_units() {
    let sim = Sim::tcp("powercube");
    let port = sim.address.as_str();
    // The module watchdog (50 ms) is no part of this: a loaded test machine may miss it.
    let out = ml(&["powercube", "--port", port, "--no-watchdog", "move", "1.2"]);
    assert!(out.status.success(), "{out:?}");
    assert!(stdout(&out).starts_with("reached: position 1.2000 rad, state "), "{}", stdout(&out));
    let out = ml(&["powercube", "--port", port, "move", "90"]);
    assert_eq!(out.status.code(), Some(2), "{out:?}");
    assert_eq!(
        stderr(&out),
        "motionlink: module 1: the target position 90 rad is outside MinPos..MaxPos = -3.14..3.14 rad (90 degrees is \
         1.5708 rad)\n"
    );
    let out = ml(&["powercube", "--port", port, "move", "1", "--vel", "30"]);
    assert!(stderr(&out).contains("30 rad/s is outside the module's limit MaxVel = 1 rad/s"), "{out:?}");

    let sim = Sim::tcp("scu");
    let port = sim.address.as_str();
    let text = stdout(&ml(&["scu", "--port", port, "get", "remote_speed_f1"]));
    assert_eq!(text, "remote_speed_f1 (0x3011)  100 %\n");
    let text = stdout(&ml(&["scu", "--port", port, "set", "remote_speed_f1", "80"]));
    assert_eq!(text, "remote_speed_f1 (0x3011)  80 % (written, read back)\n");
    let out = ml(&["scu", "--port", port, "--speed-mode", "counts-per-second", "get", "remote_speed_f2"]);
    assert!(stdout(&out).ends_with(" counts/s\n"), "{out:?}");
    let out = ml(&["scu", "--port", port, "--functions", "scp11", "move", "1", "200"]);
    assert!(stdout(&out).contains("200 counts (target 200 counts, difference 0 counts)"), "{out:?}");
}

#[test]
fn a_short_scu_reply_timeout_brings_a_short_retry_with_it() {
    let sim = Sim::tcp("scu");
    let out = ml(&["scu", "--port", &sim.address, "--timeout-ms", "100", "get", "remote_speed_f1"]);
    assert!(out.status.success(), "{out:?}");
    assert_eq!(stdout(&out), "remote_speed_f1 (0x3011)  100 %\n");
}
