//! Signals, a closed stdout, a killed command and dead links during SCU moves, runs and watches: what the
//! command stops, and what the unit's watchdog stops when the command cannot.

use std::time::Duration;

use super::{json, scu, sim_tcp};
use crate::common::{self, unix_now, Running, Sim};

/// Waits for the emulator to report that `function` started.
pub(super) fn wait_started(sim: &Sim, function: &str) -> common::Event {
    sim.wait_event(Duration::from_secs(10), |e| e.starts_with(&format!("{function} started")))
        .unwrap_or_else(|| panic!("{function} did not start: {}", sim.stderr.text()))
}

/// Waits for `actuator` to come to rest after `after`; returns the event and the position it reports.
pub(super) fn wait_at_rest(sim: &Sim, actuator: &str, after: f64) -> (common::Event, i64) {
    let prefix = format!("{actuator} at rest ");
    let e = sim
        .wait_event_after(after, Duration::from_secs(10), |e| e.starts_with(&prefix))
        .unwrap_or_else(|| panic!("{actuator} did not come to rest: {}", sim.stderr.text()));
    let p = e.text[prefix.len()..].trim_end_matches(" counts").parse().unwrap();
    (e, p)
}

/// A long move, interrupted by `signal` once the unit reports it started: the actuator is at rest within
/// 100 ms of the signal, and the command exits with 128 + the signal's number.
fn a_signal_stops_a_move(signal: i32) {
    let sim = sim_tcp();
    let running = Running::start(&["scu", "--port", &sim.address, "move", "1", "800", "--speed", "100"]);
    let started = wait_started(&sim, "F1");
    let sent = running.signal(signal);
    let (rest, position) = wait_at_rest(&sim, "A1", sent);
    let ended = running.wait(Duration::from_secs(10));
    assert_eq!(ended.code(), 128 + signal, "{ended:?}");
    assert!(rest.at - sent < 0.100, "at rest {:.0} ms after the signal", (rest.at - sent) * 1e3);
    assert!(rest.at >= started.at);
    assert!(position < 800, "stopped on the way: {position}");
    assert!(ended.stderr.contains("stopped"), "{ended:?}");
    // It stays where it stopped; RS and RA were sent.
    let p = json(&scu(&sim.address, &["get", "actual_position_a1", "--json"]))["value"].as_i64().unwrap();
    assert_eq!(p, position);
    assert!(sim.events().iter().any(|e| e.text == "remote mode closed by RA"));
    assert!(sim.events().iter().any(|e| e.text.starts_with("F1 stopped (RS fast)")));
}

#[test]
fn sigint_stops_a_move_within_100_ms_and_exits_130() {
    a_signal_stops_a_move(libc::SIGINT);
}

#[test]
fn sigterm_stops_a_move_within_100_ms_and_exits_143() {
    a_signal_stops_a_move(libc::SIGTERM);
}

#[test]
fn sighup_stops_a_move_within_100_ms_and_exits_129() {
    a_signal_stops_a_move(libc::SIGHUP);
}

#[test]
fn sigquit_stops_a_move_within_100_ms_and_exits_131() {
    a_signal_stops_a_move(libc::SIGQUIT);
}

fn a_signal_stops_run(signal: i32) {
    let sim = sim_tcp();
    let running = Running::start(&["scu", "--port", &sim.address, "run", "F2", "out"]);
    wait_started(&sim, "F2");
    running.stdout.wait_for(Duration::from_secs(5), |l| l.contains("running")).expect("run says it runs");
    let sent = running.signal(signal);
    let (rest, _) = wait_at_rest(&sim, "A2", sent);
    let ended = running.wait(Duration::from_secs(10));
    assert_eq!(ended.code(), 128 + signal, "{ended:?}");
    assert!(rest.at - sent < 0.100, "signal {signal}: at rest {:.0} ms after it", (rest.at - sent) * 1e3);
    assert!(ended.stdout.contains("stopped"), "{ended:?}");
}

#[test]
fn sigterm_stops_run_within_100_ms_and_exits_143() {
    a_signal_stops_run(libc::SIGTERM);
}

#[test]
fn sigint_sighup_and_sigquit_stop_run_within_100_ms_too() {
    for signal in [libc::SIGINT, libc::SIGHUP, libc::SIGQUIT] {
        a_signal_stops_run(signal);
    }
}

#[test]
fn a_closed_stdout_stops_run() {
    let sim = sim_tcp();
    let (running, stdout) = Running::start_with_stdout(&["scu", "--port", &sim.address, "run", "F2", "out"]);
    wait_started(&sim, "F2");
    let closed = unix_now();
    drop(stdout);
    let (rest, _) = wait_at_rest(&sim, "A2", closed);
    let ended = running.wait(Duration::from_secs(10));
    assert_eq!(ended.code(), 0, "{ended:?}");
    assert!(rest.at - closed < 0.100, "at rest {:.0} ms after stdout closed", (rest.at - closed) * 1e3);
    assert!(ended.stderr.is_empty(), "{ended:?}");
    assert!(sim.events().iter().any(|e| e.text.starts_with("F2 stopped")), "{:?}", sim.events());
}

#[test]
fn a_closed_stdout_stops_a_move() {
    let sim = sim_tcp();
    let (running, stdout) =
        Running::start_with_stdout(&["scu", "--port", &sim.address, "move", "1", "800", "--speed", "100"]);
    wait_started(&sim, "F1");
    let closed_at = unix_now();
    drop(stdout); // the reader goes away (`motionlink ... | head`)
    let (rest, position) = wait_at_rest(&sim, "A1", closed_at);
    let ended = running.wait(Duration::from_secs(10));
    assert!(position < 800, "{position}");
    assert!(rest.at - closed_at < 0.100, "at rest {:.0} ms after stdout closed", (rest.at - closed_at) * 1e3);
    assert_eq!(ended.code(), 0, "a closed pipe ends quietly: {ended:?}");
    assert!(ended.stderr.is_empty(), "{ended:?}");
}

#[test]
fn watch_interrupted_exits_130() {
    let sim = sim_tcp();
    let running = Running::start(&["scu", "--port", &sim.address, "watch", "--interval", "50"]);
    running.stdout.wait_for(Duration::from_secs(5), |l| l.contains("A1:")).expect("a first sample");
    running.signal(libc::SIGINT);
    let ended = running.wait(Duration::from_secs(5));
    assert_eq!(ended.code(), 130, "{ended:?}");
    assert!(sim.wait_event(Duration::from_secs(5), |e| e == "remote mode closed by RA").is_some());
}

#[test]
fn a_killed_command_leaves_the_unit_to_stop_by_its_own_watchdog_within_500_ms() {
    for safety in ["0", "1", "2"] {
        let sim = sim_tcp();
        let mut running =
            Running::start(&["scu", "--port", &sim.address, "--safety", safety, "move", "1", "800", "--speed", "100"]);
        wait_started(&sim, "F1");
        let killed = running.kill();
        let expiry = sim
            .wait_event_after(killed, Duration::from_secs(5), |e| e.starts_with("remote mode ended by watchdog"))
            .unwrap_or_else(|| panic!("{}", sim.stderr.text()));
        assert!(expiry.text.contains(&format!("(Safety_ID {safety})")), "{}", expiry.text);
        let (rest, _) = wait_at_rest(&sim, "A1", killed);
        // The last RC went out at most 200 ms before the kill; the watchdog is 500 ms.
        assert!(
            rest.at - killed < 0.550,
            "Safety_ID {safety}: at rest {:.0} ms after SIGKILL",
            (rest.at - killed) * 1e3
        );
        assert!(rest.at - killed > 0.250, "stopped by the watchdog, not by the command");
    }
}

#[test]
fn a_dead_link_during_a_move_ends_the_command_within_3_s_saying_the_axis_may_still_move() {
    let sim = sim_tcp();
    let running = Running::start(&["scu", "--port", &sim.address, "move", "1", "800", "--speed", "100"]);
    wait_started(&sim, "F1");
    // The emulator stops answering (the TCP connection stays up): as a cut cable behind a serial gateway.
    let frozen = sim.freeze();
    let cut = std::time::Instant::now();
    let ended = running.wait(Duration::from_secs(10));
    let took = cut.elapsed();
    drop(frozen);
    assert!(took < Duration::from_secs(3), "the command took {took:?} to give up");
    assert_eq!(ended.code(), 3, "{ended:?}");
    assert!(ended.stderr.contains("may still be moving"), "{}", ended.stderr);
    // What really happened: the unit's watchdog stopped the drive.
    assert!(sim.wait_event(Duration::from_secs(5), |e| e.starts_with("remote mode ended by watchdog")).is_some());
    assert!(sim.wait_event(Duration::from_secs(5), |e| e.starts_with("A1 at rest")).is_some());
}

#[test]
fn a_dead_link_during_watch_is_reported_as_a_silent_unit() {
    let sim = sim_tcp();
    let running = Running::start(&["scu", "--port", &sim.address, "watch", "--interval", "100"]);
    running.stdout.wait_for(Duration::from_secs(5), |l| l.contains("A1")).expect("a first sample");
    let frozen = sim.freeze();
    let ended = running.wait(Duration::from_secs(10));
    drop(frozen);
    assert_eq!(ended.code(), 3, "{ended:?}");
    // Either the request on the line timed out, or one queued behind an unanswered keepalive was not sent:
    // both say that the unit does not answer.
    let said = &ended.stderr;
    assert!(said.contains("no reply to") || said.contains("has not answered"), "{said}");
    assert!(!ended.stderr.contains("round trips of"), "not a round-trip problem: {}", ended.stderr);
}

#[test]
fn a_dead_link_before_the_session_opens_ends_the_command_within_3_s() {
    let sim = sim_tcp();
    let frozen = sim.freeze();
    let started = std::time::Instant::now();
    let out = scu(&sim.address, &["info"]);
    let took = started.elapsed();
    drop(frozen);
    assert!(took < Duration::from_secs(3), "{took:?}");
    assert_eq!(out.status.code(), Some(3), "{out:?}");
}

/// Ctrl-C while the line is silent: the RS the command sends is not acknowledged, so the command does not
/// end as a clean interruption (128 + n promises that what it started was stopped) but with exit 3 and the
/// message that the actuators may still be moving. (The unit's watchdog then stops them.)
#[cfg(unix)]
#[test]
fn ctrl_c_whose_stop_the_unit_does_not_confirm_exits_3_not_130() {
    let sim = sim_tcp();
    let running = Running::start(&["--json", "scu", "--port", &sim.address, "move", "1", "800", "--speed", "100"]);
    wait_started(&sim, "F1");
    // The emulator stops answering (the TCP connection stays up), and at once the command is interrupted.
    let frozen = sim.freeze();
    running.signal(libc::SIGINT);
    let ended = running.wait(Duration::from_secs(10));
    drop(frozen);
    assert_eq!(ended.code(), 3, "{ended:?}");
    assert!(ended.stderr.contains("NOT confirmed") && ended.stderr.contains("may still be moving"), "{}", ended.stderr);
    // The error names where the actuator was last seen, not that it stopped there (also when the RE was
    // still unanswered at the signal: it is not sent again, and its lost reply is the cancel's).
    assert!(ended.stderr.contains("cancelled while A1 was moving (last seen at "), "{}", ended.stderr);
    assert!(!ended.stderr.contains("stopped at"), "{}", ended.stderr);
    // The close tried the RS again: said once, with the watchdog's sentence once.
    assert_eq!(ended.stderr.matches("its watchdog").count(), 1, "{}", ended.stderr);
    assert!(
        ended.stderr.contains("the end of the session tried RS to F1 again: not confirmed either"),
        "{}",
        ended.stderr
    );
    // The error says so as data too.
    let e = ended.json_error();
    assert_eq!((&e["stop_unconfirmed"], &e["exit_code"]), (&serde_json::json!(true), &serde_json::json!(3)), "{e}");
}

#[test]
fn a_third_signal_exits_at_once_saying_the_stop_was_not_confirmed() {
    let sim = sim_tcp();
    let running = Running::start(&["--json", "scu", "--port", &sim.address, "move", "1", "800", "--speed", "100"]);
    wait_started(&sim, "F1");
    // The line carries nothing any more: the stop that the first signal starts cannot be confirmed.
    let frozen = sim.freeze();
    for _ in 0..3 {
        running.signal(libc::SIGINT);
        std::thread::sleep(Duration::from_millis(50));
    }
    let ended = running.wait(Duration::from_secs(5));
    drop(frozen);
    assert_eq!(ended.code(), 3, "{ended:?}");
    let last = ended.stderr.lines().last().unwrap_or_default();
    let e: serde_json::Value = serde_json::from_str(last).expect("the error object last");
    assert_eq!((&e["exit_code"], &e["stop_unconfirmed"]), (&serde_json::json!(3), &serde_json::json!(true)), "{e}");
    assert!(e["message"].as_str().unwrap().contains("may still be moving"), "{e}");
}

#[test]
fn a_signal_while_the_session_opens_keeps_a_raw_request_unsent() {
    // The sleepy unit wakes slowly: the signal comes while the session is opened, before `send` could go.
    let running = Running::start(&["-v", "scu", "--port", "sim", "--sim-variant", "sleepy", "send", "RE", "F1", "out"]);
    std::thread::sleep(Duration::from_millis(50));
    running.signal(libc::SIGINT);
    let ended = running.wait(Duration::from_secs(10));
    assert_eq!(ended.code(), 130, "{ended:?}");
    assert!(ended.stderr.contains("interrupted before the request was sent"), "{}", ended.stderr);
    assert!(!ended.stderr.lines().any(|l| l.contains("-> 52 45")), "no RE went out: {}", ended.stderr);
    assert!(ended.stderr.lines().any(|l| l.contains("RA remote mode abort")), "the session closed: {}", ended.stderr);
}
