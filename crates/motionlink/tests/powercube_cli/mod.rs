//! `motionlink powercube`, `motionlink sim powercube`, `motionlink decode powercube` and the demo, end to end
//! through the built binary: over TCP, over a pty, and over SLCAN on a pty.

mod conventions;
mod decoding;

use decoding::decode;

use std::io::Write;
use std::process::{Command, Output, Stdio};
use std::time::Duration;

use crate::common;

#[cfg(unix)]
use common::{unix_now, Running};
use common::{Sim, BIN};

fn run(port: &str, args: &[&str]) -> Output {
    Command::new(BIN).args(["powercube", "--port", port]).args(args).output().unwrap()
}

fn ok(port: &str, args: &[&str]) -> String {
    let out = run(port, args);
    assert!(
        out.status.success(),
        "{args:?}: {:?}\n{}{}",
        out.status,
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

fn code(out: &Output) -> i32 {
    out.status.code().unwrap_or(-1)
}

#[test]
fn over_tcp_every_action() {
    let sim = Sim::start("powercube", &["--tcp", "127.0.0.1:0", "--modules", "1,17"]);
    let port = sim.address.as_str();
    let scan = ok(port, &["scan"]);
    assert!(scan.lines().any(|l| l.starts_with("17 ") && l.contains("rotary") && l.contains("4.6.34")), "{scan}");
    // One object per module (JSON Lines), each naming family and port.
    let json: Vec<serde_json::Value> =
        ok(port, &["scan", "--json"]).lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    assert_eq!(json.len(), 2);
    assert_eq!(
        (&json[1]["serial"], &json[1]["family"], &json[1]["port"]),
        (&1017.into(), &"powercube".into(), &port.into())
    );

    let info = ok(port, &["--module", "17", "info"]);
    assert!(info.contains("serial") && info.contains("1017") && info.contains("MaxVel"), "{info}");
    assert!(ok(port, &["--module", "17", "get", "ActPos"]).contains("0.050000 rad"));
    let j: serde_json::Value = serde_json::from_str(&ok(port, &["--module", "17", "--json", "get", "0x1d"])).unwrap();
    assert_eq!(j["value"], 0x4634);
    assert!(ok(port, &["--module", "17", "set", "TargetVel", "1.0"])
        .contains("TargetVel set to 1.000000 rad/s (read back)"));
    assert!(ok(port, &["--module", "17", "set", "TargetAcc", "2"]).contains("TargetAcc set"));

    // Usage errors: unknown parameter, read-only parameter, bad value: exit 2, nothing moved.
    for args in [&["get", "Nope"][..], &["set", "ActPos", "1"], &["set", "MaxVel", "fast"], &["get", "TargetVel"]] {
        let out = run(port, args);
        assert_eq!(code(&out), 2, "{args:?}: {}", String::from_utf8_lossy(&out.stderr));
    }
    // No module at 5: a transport error, exit 3.
    let out = run(port, &["--module", "5", "--timeout-ms", "50", "get", "ActPos"]);
    assert_eq!(code(&out), 3, "{}", String::from_utf8_lossy(&out.stderr));
    assert!(String::from_utf8_lossy(&out.stderr).contains("did not answer"));

    assert!(ok(port, &["--module", "17", "home"]).starts_with("homed"));
    let config_before = ok(port, &["--module", "17", "--json", "get", "Config"]);
    let out = run(port, &["--module", "17", "move", "-0.1", "--vel", "1", "--acc", "2"]);
    let moved = String::from_utf8_lossy(&out.stdout);
    assert!(moved.contains("reached: position -0.1000") && moved.contains("STATE_RAMP_END"), "{moved}");
    // The watchdog was armed on RS232 too (libm5api's serveWatchdogAll form), and switched off after: the
    // emulator saw it, and the Config word is as it was. Nothing is printed about it.
    assert!(out.stderr.is_empty(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(sim.wait_event(Duration::from_secs(5), |e| e == "module 17 watchdog online").is_some());
    assert!(sim.wait_event(Duration::from_secs(5), |e| e == "module 17 watchdog offline").is_some());
    assert_eq!(ok(port, &["--module", "17", "--json", "get", "Config"]), config_before);
    let out = run(port, &["--module", "17", "--no-watchdog", "move", "-0.05", "--vel", "1", "--acc", "2"]);
    assert!(out.status.success() && out.stderr.is_empty(), "{}", String::from_utf8_lossy(&out.stderr));

    let state = ok(port, &["--module", "17", "state"]);
    assert!(state.contains("STATE_HOME_OK") && state.contains("information"), "{state}");
    ok(port, &["--module", "17", "halt"]);
    // Halted: the module would ignore a move; it is refused before anything is sent (a device error, exit 1).
    let out = run(port, &["--module", "17", "move", "0.0"]);
    assert_eq!(code(&out), 1, "{}", String::from_utf8_lossy(&out.stderr));
    assert!(String::from_utf8_lossy(&out.stderr).contains("halted"));
    ok(port, &["--module", "17", "reset"]);
    let j: serde_json::Value = serde_json::from_str(&ok(port, &["--module", "17", "--json", "state"])).unwrap();
    assert!(j["faults"].as_array().unwrap().is_empty());
    let watch = ok(port, &["--module", "17", "watch", "--interval-ms", "10", "--count", "3"]);
    assert_eq!(watch.lines().count(), 3, "{watch}");
    let params = ok(port, &["params"]);
    assert!(params.lines().any(|l| l.starts_with("0x3C") && l.contains("ActPos")));
}

#[test]
fn a_device_error_names_its_flags() {
    let sim = Sim::start("powercube", &["--tcp", "127.0.0.1:0"]);
    let port = sim.address.as_str();
    ok(port, &["home"]);
    ok(port, &["set", "MaxPos", "0.05"]);
    // A target beyond the soft limit would be limited to it by the module and reported as reached: refused
    // before anything moves, naming the limit (exit 2).
    let out = run(port, &["move", "1.0", "--vel", "1", "--acc", "2"]);
    assert_eq!(code(&out), 2, "{out:?}");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("target position 1 is outside the module's limit MaxPos = 0.05"), "{err}");
    assert!(ok(port, &["get", "ActPos"]).contains("0.000000"), "nothing moved");
    // A tow error names its flags.
    ok(port, &["set", "MaxDeltaPos", "0.0001"]);
    let out = run(port, &["move", "0.03", "--vel", "1", "--acc", "2"]);
    assert_eq!(code(&out), 1);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("STATE_TOW_ERROR") && err.contains("STATE_ERROR"), "{err}");
}

#[cfg(unix)]
#[test]
fn over_a_pty() {
    let sim = Sim::start("powercube", &["--pty", "--modules", "2"]);
    assert!(sim.address.starts_with("/dev/"), "{}", sim.address);
    let scan = ok(&sim.address, &["scan"]);
    assert!(scan.lines().any(|l| l.starts_with("2 ")), "{scan}");
    assert!(ok(&sim.address, &["--module", "2", "home"]).starts_with("homed"));
    assert!(ok(&sim.address, &["--module", "2", "move", "0.05", "--vel", "1", "--acc", "2"]).contains("0.0500"));
}

#[cfg(unix)]
#[test]
fn over_slcan_on_a_pty() {
    let sim = Sim::start("powercube", &["--pty", "--slcan", "--modules", "3,9"]);
    let port = format!("slcan://{}", sim.address);
    let scan = ok(&port, &["scan"]);
    assert!(scan.lines().any(|l| l.starts_with("3 ")) && scan.lines().any(|l| l.starts_with("9 ")), "{scan}");
    assert!(ok(&port, &["--module", "9", "home"]).starts_with("homed"));
    assert!(ok(&port, &["--module", "9", "move", "0.08", "--vel", "1", "--acc", "2"]).contains("0.0800"));
    assert!(ok(&port, &["--module", "9", "get", "ActPos"]).contains("0.080000"));
    // On CAN, `--capture` writes candump log lines, and `-v` traces each frame; decode reads the file back.
    let file = common::temp_path("slcan.capture");
    let out = run(&port, &["-v", "--module", "9", "get", "ActPos", "--capture", file.to_str().unwrap()]);
    let trace = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(trace.lines().any(|l| l.contains("0C9#0A3C") && l.contains("GetExtended ActPos")), "{trace}");
    let captured = std::fs::read_to_string(&file).unwrap();
    let _ = std::fs::remove_file(&file);
    let get = captured.lines().nth(1).unwrap();
    assert!(get.starts_with('(') && get.ends_with(") can0 0C9#0A3C"), "{captured}");
    let text = String::from_utf8_lossy(&decode(&captured).stdout).into_owned();
    assert!(text.lines().any(|l| l.starts_with(get) && l.contains("-> get to module 9: GetExtended ActPos")), "{text}");
    assert!(text.lines().any(|l| l.contains("<- ack from module 9: ActPos = 0.08")), "{text}");
}

/// Starts `motionlink powercube --port PORT --module MODULE ARGS...` in the background and returns it once
/// the emulator reports that the module started moving (an event, not a sleep).
#[cfg(unix)]
fn start_moving(sim: &Sim, port: &str, module: &str, args: &[&str]) -> Running {
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
        ended.stderr.contains("the module acknowledged the halt: it has stopped"),
        "signal {sig}: {}",
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
    a_killed_move_is_stopped_by_the_watchdog(&sim, &format!("slcan://{}", sim.address));
}

#[cfg(unix)]
#[test]
fn a_killed_move_over_rs232_is_stopped_by_the_watchdog() {
    let sim = Sim::start("powercube", &["--tcp", "127.0.0.1:0"]);
    a_killed_move_is_stopped_by_the_watchdog(&sim, &sim.address.clone());
}

#[cfg(unix)]
#[test]
fn a_move_over_slcan_leaves_the_module_as_it_found_it() {
    let sim = Sim::start("powercube", &["--pty", "--slcan", "--modules", "4"]);
    let port = format!("slcan://{}", sim.address);
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

#[cfg(unix)]
#[test]
fn a_line_that_dies_during_a_move_is_reported_with_what_that_means() {
    let sim = Sim::tcp("powercube");
    let port = sim.address.clone();
    let running = start_moving(&sim, &port, "1", &["move", "2.0", "--vel", "0.2", "--acc", "1"]);
    drop(sim); // the emulator (and with it the line) is gone
    let ended = running.wait(Duration::from_secs(10));
    assert_eq!(ended.code(), 3, "{ended:?}");
    assert!(ended.stderr.contains("the halt was not confirmed"), "{}", ended.stderr);
    assert!(ended.stderr.contains("the axis may still be moving"), "{}", ended.stderr);
    // Its watchdog was armed: the message says what that does, and that it is left online.
    assert!(ended.stderr.contains("halts itself within 50 ms"), "{}", ended.stderr);
    assert!(ended.stderr.contains("is left online"), "{}", ended.stderr);
}

#[test]
fn sim_configuration_errors_are_usage_errors() {
    let dir = std::env::temp_dir().join(format!("motionlink-pc-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let bad = dir.join("bad.toml");
    for (text, needle) in [
        ("[[module]]\naddress = 40\n", "outside 1..31"),
        // A module without an address is a mistake, not module 1.
        ("[[module]]\nkind = \"linear\"\n", "missing field `address`"),
    ] {
        std::fs::write(&bad, text).unwrap();
        let out = Command::new(BIN)
            .args(["sim", "powercube", "--tcp", "127.0.0.1:0", "--config"])
            .arg(&bad)
            .output()
            .unwrap();
        assert_eq!(code(&out), 2, "{text}");
        assert!(String::from_utf8_lossy(&out.stderr).contains(needle), "{text}: {out:?}");
    }
    let good = dir.join("good.toml");
    std::fs::write(&good, "[[module]]\naddress = 4\nkind = \"linear\"\nmin_pos = 0.0\nmax_pos = 0.2\n").unwrap();
    let sim = Sim::start("powercube", &["--tcp", "127.0.0.1:0", "--config", good.to_str().unwrap()]);
    let scan = ok(&sim.address, &["scan"]);
    assert!(scan.lines().any(|l| l.starts_with("4 ") && l.contains("linear")), "{scan}");
    assert!(ok(&sim.address, &["--module", "4", "get", "ActVel"]).contains("m/s"));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_in_process_sim_port() {
    let out = ok("sim", &["info"]);
    assert!(out.contains("rotary") && out.contains("1001"), "{out}");
}

/// `get PARAM --json` of module 1, as a number.
fn number(port: &str, param: &str) -> f64 {
    let j: serde_json::Value = serde_json::from_str(&ok(port, &["--json", "get", param])).unwrap();
    j["value"].as_f64().unwrap_or_else(|| panic!("{param}: {j}"))
}

#[test]
fn move_writes_only_the_ramp_values_it_is_given() {
    let sim = Sim::tcp("powercube");
    let port = sim.address.as_str();
    ok(port, &["home"]);
    // TargetVel and TargetAcc are write-only; the emulator shows them in ticks (TargetVelInc, TargetAccInc).
    let ratio = number(port, "IncRatio");
    let ticks = |v: f64| (v * ratio).round();
    ok(port, &["set", "TargetVel", "0.5"]);
    ok(port, &["set", "TargetAcc", "1.5"]);
    assert!(ok(port, &["move", "0.1", "--vel", "1"]).contains("reached: position 0.1000"));
    assert_eq!(number(port, "TargetVelInc"), ticks(1.0));
    assert_eq!(number(port, "TargetAccInc"), ticks(1.5), "TargetAcc kept, not replaced by a default");
    assert!(ok(port, &["move", "0.0", "--acc", "2"]).contains("reached: position 0.0000"));
    assert_eq!(number(port, "TargetVelInc"), ticks(1.0), "TargetVel kept");
    assert_eq!(number(port, "TargetAccInc"), ticks(2.0));
    assert!(ok(port, &["move", "0.05"]).contains("reached: position 0.0500"));
    assert_eq!((number(port, "TargetVelInc"), number(port, "TargetAccInc")), (ticks(1.0), ticks(2.0)));
}

#[test]
fn numbers_that_make_no_sense_are_usage_errors_and_nothing_is_sent() {
    let sim = Sim::tcp("powercube");
    let port = sim.address.as_str();
    ok(port, &["set", "TargetVel", "0.5"]);
    let vel = number(port, "TargetVelInc");
    for (args, named) in [
        (&["move", "nan"][..], "position"),
        (&["move", "inf"], "position"),
        (&["move", "1e39"], "position"),
        (&["move", "0.1", "--vel", "inf"], "--vel"),
        (&["move", "0.1", "--vel", "NaN"], "--vel"),
        (&["move", "0.1", "--acc", "nan"], "--acc"),
        (&["move", "0.1", "--vel", "0"], "--vel"),
        (&["move", "0.1", "--vel=-0.5"], "--vel"),
        (&["move", "0.1", "--acc=-1"], "--acc"),
        (&["move", "0.1", "--tolerance", "0"], "--tolerance"),
        (&["move", "0.1", "--tolerance", "nan"], "--tolerance"),
        (&["move", "0.1", "--timeout", "nan"], "--timeout"),
        (&["move", "0.1", "--timeout", "0"], "--timeout"),
        (&["move", "0.1", "--timeout=-3"], "--timeout"),
        (&["home", "--timeout", "0"], "--timeout"),
        (&["home", "--timeout", "inf"], "--timeout"),
        (&["--timeout-ms", "0", "state"], "--timeout-ms"),
        (&["--timeout-ms", "0", "move", "0.1"], "--timeout-ms"),
        (&["--timeout-ms=-5", "state"], "--timeout-ms"),
        (&["--poll-ms", "0", "move", "0.1"], "--poll-ms"),
        (&["--module", "0", "state"], "--module"),
        (&["--module", "32", "move", "0.1"], "--module"),
        (&["--module=-1", "state"], "--module"),
        (&["--baud", "0", "state"], "--baud"),
        (&["--baud", "7", "state"], "--baud"),
        (&["--bitrate", "0", "state"], "--bitrate"),
        (&["--bitrate", "12345", "move", "0.1"], "--bitrate"),
        (&["move", "0.1", "--tolerance", "100"], "--tolerance"),
        (&["move", "0.1", "--tolerance", "0.2"], "--tolerance"),
        (&["move", "0.1", "--timeout-s", "0"], "--timeout-s"),
        (&["home", "--timeout-s=-1"], "--timeout-s"),
        (&["watch", "--interval-ms", "0"], "--interval-ms"),
        (&["watch", "--count", "0"], "--count"),
        // Beyond the module's own limits: refused before anything is written or moved, naming the limit.
        (&["move", "3.5"], "MaxPos"),
        (&["move", "-3.5"], "MinPos"),
        (&["move", "0.1", "--vel", "1.5"], "MaxVel"),
        (&["move", "0.1", "--acc", "2.5"], "MaxAcc"),
        (&["set", "TargetVel", "1.5"], "MaxVel"),
    ] {
        let out = run(port, args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(code(&out), 2, "{args:?}: {err}");
        assert!(err.contains(named), "{args:?} names {named}: {err}");
    }
    // Nothing moved, nothing was written.
    assert_eq!(number(port, "ActPos"), f64::from(0.05f32));
    assert_eq!(number(port, "TargetVelInc"), vel);
    let state: serde_json::Value = serde_json::from_str(&ok(port, &["--json", "state"])).unwrap();
    assert!(!state["flags"].as_array().unwrap().iter().any(|f| f == "STATE_MOTION"), "{state}");
}

#[test]
fn a_move_that_ends_beside_its_target_exits_1_and_says_where() {
    let dir = std::env::temp_dir().join(format!("motionlink-pc-settle-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let config = dir.join("settle.toml");
    // A module that comes to rest 5 mrad beyond its target.
    std::fs::write(&config, "[[module]]\naddress = 1\nsettle_offset = 0.005\n").unwrap();
    let sim = Sim::start("powercube", &["--tcp", "127.0.0.1:0", "--config", config.to_str().unwrap()]);
    let port = sim.address.as_str();
    ok(port, &["home"]);
    let out = run(port, &["move", "0.5", "--vel", "1", "--acc", "2"]);
    assert_eq!(code(&out), 1, "{out:?}");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("target 0.5 not reached: the module stands at 0.505"), "{err}");
    assert!(err.contains("0.005000 away (tolerance 0.001"), "{err}");
    // A tolerance that allows it: success, with the position the module reports.
    assert!(ok(port, &["move", "0.3", "--vel", "1", "--acc", "2", "--tolerance", "0.01"])
        .contains("reached: position 0.3050"));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn set_reads_back_what_it_wrote() {
    let sim = Sim::tcp("powercube");
    let port = sim.address.as_str();
    // The module limits MaxVel to its ROM default (1 rad/s): reported, not a silent success.
    let out = run(port, &["set", "MaxVel", "10"]);
    assert_eq!(code(&out), 1, "{out:?}");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("MaxVel was written as 10.000000 but reads back as 1.000000"), "{err}");
    assert!(ok(port, &["set", "MaxVel", "0.5"]).contains("MaxVel set to 0.500000 rad/s (read back)"));
    let j: serde_json::Value = serde_json::from_str(&ok(port, &["--json", "set", "TargetVel", "0.25"])).unwrap();
    assert!(j["read_back"].is_number() && j["not_verifiable"].is_null() && j["verified"] == true, "{j}");
    // Read back through TargetVelInc (ticks) and shown in the unit written (rad/s), by the library's mapping.
    assert!((j["read_back"].as_f64().unwrap() - 0.25).abs() < 1e-4, "{j}");
    let j: serde_json::Value = serde_json::from_str(&ok(port, &["--json", "set", "TargetPos", "-0.5"])).unwrap();
    assert!((j["read_back"].as_f64().unwrap() + 0.5).abs() < 1e-4, "{j}");
    assert!(ok(port, &["set", "Cur", "1"]).contains("not verified: reading Cur gives the measured current"));
}

#[test]
fn decode_names_libm5api_broadcasts() {
    let out = decode(
        "02 04 10 82 10 82 00 08 03\n02 04 10 82 00 00 06 03\n02 04 10 82 01 00 07 03\n\
         02 04 10 82 07 00 0D 03\n02 04 10 82 0E 00 14 03\n02 04 01 10 82 07 03\n",
    );
    assert!(out.status.success(), "{out:?}");
    let text = String::from_utf8_lossy(&out.stdout);
    let lines: Vec<&str> = text.lines().collect();
    let libm5api = "(command + 0x00, as libm5api sends it)";
    for (line, what) in lines.iter().zip(["Halt all", "Reset all", "Home all", "Watchdog refresh", "Save position"]) {
        assert!(line.contains(&format!("to every module (address 0): broadcast: {what} {libm5api}")), "{line}");
    }
    assert!(lines[5].ends_with("to every module (address 0): broadcast: Halt all"), "{}", lines[5]);
    assert!(!text.contains("not understood") && !text.contains("BCC"), "{text}");
}

#[test]
fn libm5api_broadcasts_over_tcp_reach_every_module() {
    let sim = Sim::start("powercube", &["--tcp", "127.0.0.1:0", "--modules", "1,2"]);
    let addr = sim.address.strip_prefix("tcp://").unwrap();
    let mut line = std::net::TcpStream::connect(addr).unwrap();
    let t0 = common::unix_now();
    let mut replay = |bytes: &[u8], each: &str| {
        let before = common::unix_now();
        line.write_all(bytes).unwrap();
        for a in [1, 2] {
            let want = format!("module {a} {each}");
            assert!(
                sim.wait_event_after(before, Duration::from_secs(5), |e| e.starts_with(&want)).is_some(),
                "{want}: {:?}",
                sim.events()
            );
        }
    };
    replay(&[0x02, 0x04, 0x10, 0x82, 0x01, 0x00, 0x07, 0x03], "motion started: homing"); // homeAll
    replay(&[0x02, 0x04, 0x10, 0x82, 0x10, 0x82, 0x00, 0x08, 0x03], "halted"); // haltAll
    replay(&[0x02, 0x04, 0x10, 0x82, 0x00, 0x00, 0x06, 0x03], "reset"); // resetAll
    replay(&[0x02, 0x04, 0x10, 0x82, 0x0E, 0x00, 0x14, 0x03], "position saved"); // savePosAll
    assert!(sim.events().iter().all(|e| e.at < t0 || !e.text.contains("ignored")), "{:?}", sim.events());
}

#[test]
fn timeout_s_names_its_unit_and_the_old_spelling_still_works() {
    let sim = Sim::tcp("powercube");
    let port = sim.address.as_str();
    assert!(ok(port, &["move", "0.06", "--vel", "1", "--acc", "2", "--timeout-s", "5"]).contains("reached"));
    assert!(ok(port, &["move", "0.07", "--timeout", "5"]).contains("reached"), "the old spelling is an alias");
    assert!(ok(port, &["home", "--timeout-s", "5"]).contains("homed"));
    let help = Command::new(BIN).args(["powercube", "move", "--help"]).output().unwrap();
    let help = String::from_utf8_lossy(&help.stdout);
    assert!(help.contains("--timeout-s <S>") && !help.contains("--timeout <"), "{help}");
    assert!(help.contains("at most 0.1"), "{help}");
}
