//! Signals, a closed stdout and SIGKILL during PowerCube moves, homing, watches and scans: what the command
//! stops, and what the modules' watchdog stops when the command cannot.

use std::time::Duration;

use std::process::{Command, Stdio};

use super::{code, ok, run};
use crate::common::{unix_now, Running, Sim, BIN};

/// Starts `motionlink powercube --port PORT --module MODULE ARGS...` in the background and returns it once
/// the emulator reports that the module started moving (an event, not a sleep).
#[cfg(unix)]
pub(super) fn start_moving(sim: &Sim, port: &str, module: &str, args: &[&str]) -> Running {
    let t0 = unix_now();
    let mut full = vec!["-v", "powercube", "--port", port, "--module", module];
    full.extend_from_slice(args);
    let running = Running::start(&full);
    let started = format!("module {module} motion started");
    if sim.wait_event_after(t0, Duration::from_secs(10), |e| e.starts_with(&started)).is_none() {
        let ended = running.wait(Duration::from_secs(5));
        panic!("{args:?} did not start moving: {ended:?}\nevents: {:?}", sim.events());
    }
    running
}

/// Sends `sig` to a running move and asserts what must follow: the module at rest within 100 ms of the
/// signal (the emulator's event), the command's exit code 128 + n, a stop the module confirmed.
#[cfg(unix)]
fn interrupt_and_check(sim: &Sim, running: Running, module: &str, sig: i32) -> f64 {
    let at = running.signal(sig);
    let at_rest = format!("module {module} at rest");
    let rest = sim
        .wait_event_after(at, Duration::from_secs(5), |e| e.starts_with(&at_rest))
        .unwrap_or_else(|| panic!("signal {sig}: module {module} not at rest; events: {:?}", sim.events()));
    let ended = running.wait(Duration::from_secs(10));
    assert!(rest.at - at < 0.100, "signal {sig}: at rest {:.1} ms after the signal", (rest.at - at) * 1e3);
    assert_eq!(ended.code(), 128 + sig, "signal {sig}: {ended:?}");
    assert!(
        ended.stderr.contains(
            "the module acknowledged the halt and then reported no motion (STATE_MOTION clear): it is at rest"
        ),
        "signal {sig}: {}",
        ended.stderr
    );
    // Said only once seen: after the Halt's acknowledge, the state was read (the trace of `-v`).
    let lines: Vec<&str> = ended.stderr.lines().collect();
    let acked =
        lines.iter().position(|l| l.contains("Halt acknowledged")).unwrap_or_else(|| panic!("{}", ended.stderr));
    let state_read = format!("to module {module}: GetExtended CubeState");
    assert!(
        lines[acked..].iter().any(|l| l.contains(&state_read)),
        "signal {sig}: no state read after the Halt: {}",
        ended.stderr
    );
    at
}

#[cfg(unix)]
fn state_json(port: &str, module: &str) -> serde_json::Value {
    serde_json::from_str(&ok(port, &["--module", module, "--json", "state"])).unwrap()
}

#[cfg(unix)]
fn flags(state: &serde_json::Value) -> Vec<String> {
    state["flags"].as_array().unwrap().iter().map(|f| f.as_str().unwrap().to_string()).collect()
}

#[cfg(unix)]
fn json_value(port: &str, module: &str, param: &str) -> serde_json::Value {
    let j: serde_json::Value = serde_json::from_str(&ok(port, &["--module", module, "--json", "get", param])).unwrap();
    j["value"].clone()
}

/// After a move ended by a signal: halted by the command (not by its watchdog), the watchdog switched off
/// again (its event after `since`) and the Config word as it was.
#[cfg(unix)]
fn left_halted_as_found(sim: &Sim, port: &str, module: &str, since: f64, config_before: &serde_json::Value) {
    let offline = format!("module {module} watchdog offline");
    assert!(sim.wait_event_after(since, Duration::from_secs(5), |e| e == offline).is_some(), "{:?}", sim.events());
    let state = state_json(port, module);
    let f = flags(&state);
    assert!(f.iter().any(|f| f == "STATE_HALTED"), "{state}");
    assert!(!f.iter().any(|f| f == "STATE_COMM_ERROR" || f == "STATE_MOTION"), "{state}");
    assert_eq!(&json_value(port, module, "Config"), config_before);
}

#[cfg(unix)]
#[test]
fn every_signal_during_a_move_over_tcp_halts_it_within_100_ms() {
    let sim = Sim::start("powercube", &["--tcp", "127.0.0.1:0"]);
    let port = sim.address.clone();
    ok(&port, &["home"]);
    let config_before = json_value(&port, "1", "Config");
    for (sig, target) in
        [(libc::SIGINT, "2.0"), (libc::SIGTERM, "-2.0"), (libc::SIGHUP, "2.0"), (libc::SIGQUIT, "-2.0")]
    {
        let running = start_moving(&sim, &port, "1", &["move", target, "--vel", "0.5", "--acc", "2"]);
        let at = interrupt_and_check(&sim, running, "1", sig);
        left_halted_as_found(&sim, &port, "1", at, &config_before);
        ok(&port, &["reset"]);
    }
}

#[cfg(unix)]
#[test]
fn a_signal_ends_a_velocity_held_until_it_with_a_confirmed_halt() {
    let sim = Sim::start("powercube", &["--tcp", "127.0.0.1:0"]);
    let port = sim.address.clone();
    ok(&port, &["home"]);
    for (sig, velocity) in [(libc::SIGINT, "0.3"), (libc::SIGTERM, "-0.3")] {
        // No --for-s: it runs until a signal.
        let running = start_moving(&sim, &port, "1", &["motion", "fvel", velocity]);
        interrupt_and_check(&sim, running, "1", sig);
        ok(&port, &["reset"]);
    }
}

#[cfg(unix)]
#[test]
fn sigterm_during_homing_halts_it() {
    let dir = std::env::temp_dir().join(format!("motionlink-pc-home-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let far = dir.join("far.toml");
    // Far from the home switch: homing takes seconds.
    std::fs::write(&far, "[[module]]\naddress = 1\nstart_position = 2.5\n").unwrap();
    let sim = Sim::start("powercube", &["--tcp", "127.0.0.1:0", "--config", far.to_str().unwrap()]);
    let running = start_moving(&sim, &sim.address, "1", &["home"]);
    interrupt_and_check(&sim, running, "1", libc::SIGTERM);
    let state = state_json(&sim.address, "1");
    assert!(!flags(&state).iter().any(|f| f == "STATE_HOME_OK" || f == "STATE_MOTION"), "{state}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[cfg(unix)]
#[test]
fn sigint_sighup_and_sigquit_during_homing_halt_it_too() {
    let dir = std::env::temp_dir().join(format!("motionlink-pc-home-signals-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let far = dir.join("far.toml");
    std::fs::write(&far, "[[module]]\naddress = 1\nstart_position = 2.5\n").unwrap();
    for sig in [libc::SIGINT, libc::SIGHUP, libc::SIGQUIT] {
        let sim = Sim::start("powercube", &["--tcp", "127.0.0.1:0", "--config", far.to_str().unwrap()]);
        let running = start_moving(&sim, &sim.address, "1", &["home"]);
        interrupt_and_check(&sim, running, "1", sig);
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[cfg(unix)]
#[test]
fn a_closed_stdout_during_homing_halts_it() {
    let dir = std::env::temp_dir().join(format!("motionlink-pc-home-pipe-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let far = dir.join("far.toml");
    std::fs::write(&far, "[[module]]\naddress = 1\nstart_position = 2.5\n").unwrap();
    let sim = Sim::start("powercube", &["--tcp", "127.0.0.1:0", "--config", far.to_str().unwrap()]);
    let t0 = unix_now();
    let (running, stdout) = Running::start_with_stdout(&["powercube", "--port", &sim.address, "home"]);
    sim.wait_event_after(t0, Duration::from_secs(10), |e| e.starts_with("module 1 motion started")).expect("homing");
    let closed = unix_now();
    drop(stdout);
    let rest = sim.wait_event_after(closed, Duration::from_secs(5), |e| e.starts_with("module 1 at rest"));
    let rest = rest.unwrap_or_else(|| panic!("not at rest: {:?}", sim.events()));
    let ended = running.wait(Duration::from_secs(10));
    assert_eq!(ended.code(), 0, "{ended:?}");
    assert!(rest.at - closed < 0.100, "at rest {:.0} ms after stdout closed", (rest.at - closed) * 1e3);
    assert!(ended.stderr.is_empty(), "{ended:?}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[cfg(unix)]
#[test]
fn a_closed_stdout_during_a_move_stops_it() {
    let sim = Sim::tcp("powercube");
    let t0 = unix_now();
    let mut child = Command::new(BIN)
        .args(["powercube", "--port", &sim.address, "move", "2.0", "--vel", "0.5", "--acc", "2"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    assert!(sim.wait_event_after(t0, Duration::from_secs(10), |e| e.starts_with("module 1 motion started")).is_some());
    let at = unix_now();
    drop(child.stdout.take()); // the reader goes away (`motionlink ... | head` after head exits)
    let rest = sim.wait_event_after(at, Duration::from_secs(5), |e| e.starts_with("module 1 at rest"));
    let out = child.wait_with_output().unwrap();
    let rest = rest.unwrap_or_else(|| panic!("not stopped: {out:?}"));
    assert!(rest.at - at < 0.100, "at rest {:.1} ms after stdout closed", (rest.at - at) * 1e3);
    assert_eq!(code(&out), 0, "a closed pipe ends quietly: {}", String::from_utf8_lossy(&out.stderr));
    assert!(out.stderr.is_empty(), "{}", String::from_utf8_lossy(&out.stderr));
    let state = state_json(&sim.address, "1");
    assert!(flags(&state).iter().any(|f| f == "STATE_HALTED"), "{state}");
}

#[cfg(unix)]
#[test]
fn watch_interrupted_exits_130() {
    let sim = Sim::tcp("powercube");
    let running = Running::start(&["powercube", "--port", &sim.address, "watch", "--interval-ms", "50"]);
    assert!(running.stdout.wait_for(Duration::from_secs(5), |_| true).is_some(), "a first sample");
    running.signal(libc::SIGINT);
    let ended = running.wait(Duration::from_secs(5));
    assert_eq!(ended.code(), 130, "{ended:?}");
}

/// A signal during a scan ends it at once: over RS232 each absent address costs a 60 ms reply timeout, so
/// the rest of a scan of the emulator's module 1 would take about 1.7 s. Exit 130, nothing set in motion.
#[cfg(unix)]
#[test]
fn a_signal_ends_a_scan_at_once() {
    let sim = Sim::tcp("powercube");
    let running = Running::start(&["-v", "powercube", "--port", &sim.address, "scan"]);
    let asking = running.stderr.wait_for(Duration::from_secs(5), |l| l.contains("to module 4: GetExtended"));
    assert!(asking.is_some(), "{}", running.stderr.text());
    let at = running.signal(libc::SIGINT);
    let ended = running.wait(Duration::from_secs(5));
    assert_eq!(ended.code(), 130, "{}", ended.stderr);
    assert!(ended.stderr.contains("the scan cancelled (nothing had been set in motion)"), "{}", ended.stderr);
    // The last address asked is the one in flight when the signal came (module 4 or 5), not module 31.
    let last = ended.stderr.lines().rfind(|l| l.contains("GetExtended DefCubeVersion") && l.contains("to module"));
    let n: u8 = last.and_then(|l| l.split("to module ").nth(1)?.split(':').next()?.parse().ok()).unwrap_or(0);
    assert!((4..=6).contains(&n), "asked up to module {n} after the signal at {at:.3}:\n{}", ended.stderr);
}

/// Ctrl-C during a move on a line that went silent: the halt is not confirmed, so the command says the axis
/// may still be moving and that the module's watchdog, no longer refreshed, halts it; it exits 3 (a
/// transport error), not 130 (which promises a confirmed stop). Once the line carries again, the module is
/// at rest.
#[cfg(unix)]
#[test]
fn ctrl_c_whose_halt_the_module_does_not_confirm_exits_3_not_130() {
    let sim = Sim::start("powercube", &["--tcp", "127.0.0.1:0"]);
    let port = sim.address.clone();
    ok(&port, &["home"]);
    let running = start_moving(&sim, &port, "1", &["--json", "move", "2.0", "--vel", "0.2", "--acc", "1"]);
    let frozen = sim.freeze();
    running.signal(libc::SIGINT);
    let ended = running.wait(Duration::from_secs(10));
    let resumed = unix_now();
    drop(frozen);
    assert_eq!(ended.code(), 3, "{ended:?}");
    let said = &ended.stderr;
    assert!(said.contains("not confirmed") && said.contains("may still be moving"), "{said}");
    assert!(said.contains("halts itself within 50 ms"), "what the watchdog does: {said}");
    // Said once, with how to clear the module; no second line saying the watchdog was left online.
    assert_eq!(said.matches("`reset` clears it").count(), 1, "{said}");
    assert!(!said.contains("is left online"), "{said}");
    assert!(!said.contains("it has stopped"), "{said}");
    // The error says so as data too.
    let e = ended.json_error();
    assert_eq!((&e["stop_unconfirmed"], &e["exit_code"]), (&serde_json::json!(true), &serde_json::json!(3)), "{e}");
    let rest = sim.wait_event_after(resumed - 1.0, Duration::from_secs(5), |e| e.starts_with("module 1 at rest"));
    assert!(rest.is_some(), "{:?}", sim.events());
}

/// SIGKILL of a move: no halt, no goodbye; the module's watchdog halts it with STATE_COMM_ERROR within
/// 100 ms of the kill. `reset` then clears it for good. With `--no-watchdog` it keeps moving.
#[cfg(unix)]
fn a_killed_move_is_stopped_by_the_watchdog(sim: &Sim, port: &str) {
    let config_before = json_value(port, "1", "Config");
    // 2 rad at 0.2 rad/s: ten seconds.
    let mut running = start_moving(sim, port, "1", &["move", "2.0", "--vel", "0.2", "--acc", "1"]);
    let at = running.kill();
    let expired = sim
        .wait_event_after(at, Duration::from_secs(5), |e| e == "module 1 watchdog expired: STATE_COMM_ERROR")
        .unwrap_or_else(|| panic!("no watchdog expiry: {:?}", sim.events()));
    let rest = sim.wait_event_after(at, Duration::from_secs(5), |e| e.starts_with("module 1 at rest")).unwrap();
    running.wait(Duration::from_secs(5));
    assert!(expired.at - at < 0.100, "expired {:.1} ms after the kill", (expired.at - at) * 1e3);
    assert!(rest.at - at < 0.100, "at rest {:.1} ms after the kill", (rest.at - at) * 1e3);
    let state = state_json(port, "1");
    let f = flags(&state);
    assert!(f.iter().any(|f| f == "STATE_COMM_ERROR") && f.iter().any(|f| f == "STATE_HALTED"), "{state}");
    assert!(!f.iter().any(|f| f == "STATE_MOTION"), "{state}");
    // It stays where it stopped: the position of its "at rest" event.
    let stopped_at = json_value(port, "1", "ActPos").as_f64().unwrap();
    assert_eq!(rest.text, format!("module 1 at rest {stopped_at:.4} rad"));
    assert!(stopped_at > 0.0 && stopped_at < 1.0, "it had moved, and not far: {stopped_at}");

    // A move now is refused before anything is touched; `reset` switches the expired watchdog offline.
    let out = run(port, &["move", "0.0"]);
    assert_eq!(code(&out), 1);
    assert!(String::from_utf8_lossy(&out.stderr).contains("`reset` clears it"), "{out:?}");
    let t0 = unix_now();
    let reset: serde_json::Value = serde_json::from_str(&ok(port, &["--json", "reset"])).unwrap();
    assert_eq!(reset["watchdog_released"], true, "{reset}");
    assert!(sim.wait_event_after(t0, Duration::from_secs(5), |e| e == "module 1 watchdog offline").is_some());
    let state = state_json(port, "1");
    assert!(flags(&state).is_empty(), "reset for good: {state}");
    // The dead session could not restore the Config word: only the watchdog flag differs.
    let after = json_value(port, "1", "Config").as_u64().unwrap();
    assert_eq!(after, config_before.as_u64().unwrap() | 0x0100_0000);

    // With --no-watchdog a killed move keeps going: that is what the flag gives up.
    let t0 = unix_now();
    let mut running = start_moving(sim, port, "1", &["--no-watchdog", "move", "-2.0", "--vel", "0.2", "--acc", "1"]);
    running.kill();
    running.wait(Duration::from_secs(5));
    let state = state_json(port, "1");
    assert!(
        flags(&state).iter().any(|f| f == "STATE_MOTION") && state["faults"].as_array().unwrap().is_empty(),
        "{state}"
    );
    assert!(!sim.events().iter().any(|e| e.at >= t0 && e.text.contains("watchdog online")), "never armed");
    ok(port, &["halt"]);
}

#[cfg(unix)]
#[test]
fn a_killed_move_over_slcan_is_stopped_by_the_watchdog() {
    let sim = Sim::start("powercube", &["--pty", "--slcan", "--modules", "1"]);
    a_killed_move_is_stopped_by_the_watchdog(&sim, &sim.address);
}

#[cfg(unix)]
#[test]
fn a_killed_move_over_rs232_is_stopped_by_the_watchdog() {
    let sim = Sim::start("powercube", &["--tcp", "127.0.0.1:0"]);
    a_killed_move_is_stopped_by_the_watchdog(&sim, &sim.address);
}

#[cfg(unix)]
#[test]
fn a_move_over_slcan_leaves_the_module_as_it_found_it() {
    let sim = Sim::start("powercube", &["--pty", "--slcan", "--modules", "4"]);
    let port = sim.address.clone();
    let p = port.as_str();
    let config_before = json_value(p, "4", "Config");
    assert!(ok(p, &["--module", "4", "home"]).starts_with("homed"));
    let t0 = unix_now();
    let moved = ok(p, &["--module", "4", "move", "0.1", "--vel", "1", "--acc", "2"]);
    assert!(moved.contains("reached: position 0.1000"), "{moved}");
    // The watchdog was switched off again by the command (its event), so it cannot halt the module later.
    assert!(sim.wait_event_after(t0, Duration::from_secs(5), |e| e == "module 4 watchdog offline").is_some());
    let state = state_json(p, "4");
    let f = flags(&state);
    assert!(!f.iter().any(|f| f == "STATE_HALTED" || f == "STATE_COMM_ERROR"), "{state}");
    assert_eq!(json_value(p, "4", "Config"), config_before);

    // SIGINT and SIGTERM: the module is halted (by the program, not by its watchdog) within 100 ms, and
    // the Config word restored.
    for (sig, target) in [(libc::SIGINT, "2.0"), (libc::SIGTERM, "-2.0")] {
        let running = start_moving(&sim, p, "4", &["move", target, "--vel", "0.2", "--acc", "1"]);
        assert!(running.stderr.wait_for(Duration::from_secs(5), |l| l.contains("watchdog armed")).is_some());
        let at = interrupt_and_check(&sim, running, "4", sig);
        left_halted_as_found(&sim, p, "4", at, &config_before);
        ok(p, &["--module", "4", "reset"]);
    }
}
