//! `motionlink powercube`, `motionlink sim powercube`, `motionlink decode powercube` and the demo, end to end
//! through the built binary: over TCP, over a pty, and over SLCAN on a pty.

use std::io::{BufRead, BufReader, Write};
use std::process::{Child, Command, Output, Stdio};
use std::time::Duration;

mod common;

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
    let json: serde_json::Value = serde_json::from_str(&ok(port, &["scan", "--json"])).unwrap();
    assert_eq!(json.as_array().unwrap().len(), 2);
    assert_eq!(json[1]["serial"], 1017);

    let info = ok(port, &["--module", "17", "info"]);
    assert!(info.contains("serial") && info.contains("1017") && info.contains("MaxVel"), "{info}");
    assert!(ok(port, &["--module", "17", "get", "ActPos"]).contains("0.050000 rad"));
    let j: serde_json::Value = serde_json::from_str(&ok(port, &["--module", "17", "--json", "get", "0x1d"])).unwrap();
    assert_eq!(j["value"], 0x4634);
    assert!(ok(port, &["--module", "17", "set", "TargetVel", "1.0"]).contains("TargetVel set"));
    assert!(ok(port, &["--module", "17", "set", "TargetAcc", "4"]).contains("TargetAcc set"));

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
    let out = run(port, &["--module", "17", "move", "-0.1", "--vel", "1", "--acc", "4"]);
    let moved = String::from_utf8_lossy(&out.stdout);
    assert!(moved.contains("reached: position -0.1000") && moved.contains("STATE_RAMP_END"), "{moved}");
    // RS232 has no broadcast to refresh the watchdog with: the module is not armed, and the user is told.
    let warning = String::from_utf8_lossy(&out.stderr);
    assert_eq!(warning.lines().filter(|l| l.contains("no watchdog on RS232")).count(), 1, "{warning}");
    let j: serde_json::Value = serde_json::from_str(&ok(port, &["--module", "17", "--json", "get", "Config"])).unwrap();
    assert_eq!(j["value"].as_u64().unwrap() & 0x0100_0000, 0, "the Config word is not touched on RS232");
    let out = run(port, &["--module", "17", "--no-watchdog", "move", "-0.05", "--vel", "1", "--acc", "4"]);
    assert!(out.status.success() && out.stderr.is_empty(), "{}", String::from_utf8_lossy(&out.stderr));

    let state = ok(port, &["--module", "17", "state"]);
    assert!(state.contains("STATE_HOME_OK") && state.contains("information"), "{state}");
    ok(port, &["--module", "17", "halt"]);
    // Halted: a move is refused by the module and reported as a device error (exit 1).
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
    // The ramp target is limited to the soft limit, so this move ends at 0.05 without error...
    assert!(ok(port, &["move", "1.0", "--vel", "1", "--acc", "4"]).contains("0.0500"));
    // ...a tow error is another matter.
    ok(port, &["set", "MaxDeltaPos", "0.0001"]);
    let out = run(port, &["move", "0.0", "--vel", "1", "--acc", "4"]);
    assert_eq!(code(&out), 1);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("STATE_TOW_ERROR") && err.contains("STATE_ERROR"), "{err}");
}

#[test]
fn ctrl_c_halts_a_move() {
    let sim = Sim::start("powercube", &["--tcp", "127.0.0.1:0"]);
    let port = sim.address.clone();
    let child = Command::new(BIN)
        .args(["powercube", "--port", &port, "move", "2.0", "--vel", "0.2", "--acc", "1"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(600));
    let status = Command::new("kill").args(["-INT", &child.id().to_string()]).status().unwrap();
    assert!(status.success());
    let out = child.wait_with_output().unwrap();
    assert_eq!(code(&out), 130, "Ctrl-C exits with 130 after halting: {}", String::from_utf8_lossy(&out.stderr));
    assert!(String::from_utf8_lossy(&out.stderr).contains("cancelled"));
    let state = ok(&port, &["state"]);
    assert!(state.contains("STATE_HALTED") && !state.contains("STATE_MOTION"), "{state}");
}

#[cfg(unix)]
#[test]
fn over_a_pty() {
    let sim = Sim::start("powercube", &["--pty", "--modules", "2"]);
    assert!(sim.address.starts_with("/dev/"), "{}", sim.address);
    let scan = ok(&sim.address, &["scan"]);
    assert!(scan.lines().any(|l| l.starts_with("2 ")), "{scan}");
    assert!(ok(&sim.address, &["--module", "2", "home"]).starts_with("homed"));
    assert!(ok(&sim.address, &["--module", "2", "move", "0.05", "--vel", "1", "--acc", "4"]).contains("0.0500"));
}

#[cfg(unix)]
#[test]
fn over_slcan_on_a_pty() {
    let sim = Sim::start("powercube", &["--pty", "--slcan", "--modules", "3,9"]);
    let port = format!("slcan://{}", sim.address);
    let scan = ok(&port, &["scan"]);
    assert!(scan.lines().any(|l| l.starts_with("3 ")) && scan.lines().any(|l| l.starts_with("9 ")), "{scan}");
    assert!(ok(&port, &["--module", "9", "home"]).starts_with("homed"));
    assert!(ok(&port, &["--module", "9", "move", "0.08", "--vel", "1", "--acc", "4"]).contains("0.0800"));
    assert!(ok(&port, &["--module", "9", "get", "ActPos"]).contains("0.080000"));
}

/// Starts `motionlink -v powercube --port PORT ARGS...` (a long motion) and returns once it logs that the
/// module is moving (the log line comes after the motion command was acknowledged), with a thread that
/// collects its stderr.
#[cfg(unix)]
fn start_moving(port: &str, args: &[&str]) -> (Child, std::thread::JoinHandle<String>) {
    let mut child = Command::new(BIN)
        .args(["-v", "powercube", "--port", port])
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let (tx, rx) = std::sync::mpsc::channel();
    let stderr = child.stderr.take().unwrap();
    let log = std::thread::spawn(move || {
        let mut all = String::new();
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            if line.contains("moving from") {
                let _ = tx.send(());
            }
            all.push_str(&line);
            all.push('\n');
        }
        all
    });
    if rx.recv_timeout(Duration::from_secs(5)).is_err() {
        let _ = child.kill();
        let _ = child.wait();
        panic!("{args:?} did not start moving:\n{}", log.join().unwrap());
    }
    (child, log)
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

#[cfg(unix)]
#[test]
fn a_killed_move_over_slcan_is_stopped_by_the_watchdog() {
    let sim = Sim::start("powercube", &["--pty", "--slcan", "--modules", "1"]);
    let port = format!("slcan://{}", sim.address);
    let config_before = json_value(&port, "1", "Config");
    // 2 rad at 0.2 rad/s: ten seconds, killed a few hundred ms in.
    let (mut child, _) = start_moving(&port, &["move", "2.0", "--vel", "0.2", "--acc", "1"]);
    std::thread::sleep(Duration::from_millis(300));
    child.kill().unwrap(); // SIGKILL: no halt, no goodbye, no more watchdog refresh
    child.wait().unwrap();
    // The watchdog waits 50 ms for a refresh; look a little later.
    std::thread::sleep(Duration::from_millis(100));
    let state = state_json(&port, "1");
    let f = flags(&state);
    assert!(f.iter().any(|f| f == "STATE_COMM_ERROR") && f.iter().any(|f| f == "STATE_HALTED"), "{state}");
    assert!(!f.iter().any(|f| f == "STATE_MOTION"), "{state}");
    let stopped_at = json_value(&port, "1", "ActPos").as_f64().unwrap();
    assert!(stopped_at > 0.06 && stopped_at < 1.0, "it had moved, and not far: {stopped_at}");
    std::thread::sleep(Duration::from_millis(300));
    assert_eq!(json_value(&port, "1", "ActPos").as_f64().unwrap(), stopped_at, "it stays where it stopped");

    // A move now is refused before anything is touched; `reset` switches the expired watchdog offline.
    let out = run(&port, &["move", "0.0"]);
    assert_eq!(code(&out), 1);
    assert!(String::from_utf8_lossy(&out.stderr).contains("`reset` clears it"), "{out:?}");
    let reset: serde_json::Value = serde_json::from_str(&ok(&port, &["--json", "reset"])).unwrap();
    assert_eq!(reset["watchdog_released"], true, "{reset}");
    std::thread::sleep(Duration::from_millis(200));
    let state = state_json(&port, "1");
    assert!(flags(&state).is_empty(), "reset for good: {state}");
    // The dead session could not restore the Config word: only the watchdog flag differs.
    let after = json_value(&port, "1", "Config").as_u64().unwrap();
    assert_eq!(after, config_before.as_u64().unwrap() | 0x0100_0000);

    // With --no-watchdog a killed move keeps going: that is what the flag gives up.
    let (mut child, _) = start_moving(&port, &["--no-watchdog", "move", "-2.0", "--vel", "0.2", "--acc", "1"]);
    child.kill().unwrap();
    child.wait().unwrap();
    std::thread::sleep(Duration::from_millis(100));
    let state = state_json(&port, "1");
    assert!(
        flags(&state).iter().any(|f| f == "STATE_MOTION") && state["faults"].as_array().unwrap().is_empty(),
        "{state}"
    );
    ok(&port, &["halt"]);
}

#[cfg(unix)]
#[test]
fn a_move_over_slcan_leaves_the_module_as_it_found_it() {
    let sim = Sim::start("powercube", &["--pty", "--slcan", "--modules", "4"]);
    let port = format!("slcan://{}", sim.address);
    let p = port.as_str();
    let config_before = json_value(p, "4", "Config");
    assert!(ok(p, &["--module", "4", "home"]).starts_with("homed"));
    let moved = ok(p, &["--module", "4", "move", "0.1", "--vel", "1", "--acc", "4"]);
    assert!(moved.contains("reached: position 0.1000"), "{moved}");
    // Longer than the watchdog's 50 ms: a watchdog left online would have halted the module by now.
    std::thread::sleep(Duration::from_millis(150));
    let state = state_json(p, "4");
    let f = flags(&state);
    assert!(!f.iter().any(|f| f == "STATE_HALTED" || f == "STATE_COMM_ERROR"), "{state}");
    assert_eq!(json_value(p, "4", "Config"), config_before);

    // Ctrl-C: the module is halted (by the program, not by its watchdog) and the Config word restored.
    let (mut child, log) = start_moving(p, &["--module", "4", "move", "2.0", "--vel", "0.2", "--acc", "1"]);
    std::thread::sleep(Duration::from_millis(100));
    assert!(Command::new("kill").args(["-INT", &child.id().to_string()]).status().unwrap().success());
    let status = child.wait().unwrap();
    let err = log.join().unwrap();
    assert_eq!(status.code(), Some(130), "Ctrl-C exits with 130 after halting: {err}");
    assert!(err.contains("watchdog armed") && err.contains("cancelled"), "{err}");
    std::thread::sleep(Duration::from_millis(150));
    let state = state_json(p, "4");
    let f = flags(&state);
    assert!(f.iter().any(|f| f == "STATE_HALTED") && !f.iter().any(|f| f == "STATE_COMM_ERROR"), "{state}");
    assert_eq!(json_value(p, "4", "Config"), config_before);
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

fn decode(input: &str) -> Output {
    let mut child = Command::new(BIN)
        .args(["decode", "powercube"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    child.stdin.take().unwrap().write_all(input.as_bytes()).unwrap();
    child.wait_with_output().unwrap()
}

#[test]
fn a_hex_capture_with_comment_lines_is_not_taken_for_candump() {
    let out = decode("# Home to module 17, and its acknowledge\n02 06 21 01 28 03\n# ack:\n02 0a 21 01 2c 03\n");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("to module 17: Home"), "{text}");
    assert!(text.contains("from module 17: Home acknowledged"), "{text}");
    // And a candump log may have comment lines too.
    let out = decode("# candump -l can0\n(1700000000.000000) can0 0F1#01\n// ack\n(1700000000.000100) can0 0B1#01\n");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("put to module 17: Home") && text.contains("ack from module 17: Home acknowledged"),
        "{text}"
    );
    // One frame given as an argument.
    let out = Command::new(BIN).args(["decode", "powercube", "0D1#0A3C"]).output().unwrap();
    assert!(String::from_utf8_lossy(&out.stdout).contains("get to module 17: GetExtended ActPos"), "{out:?}");
}

#[test]
fn decode_rs232_and_candump() {
    let out = decode("02 06 21 10 82 29 03\n02 0a 26 08 50 64 ec 03 ff 02 06 21 01 00 03\n");
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("to module 17: Halt"), "{text}");
    assert!(text.contains("from module 17: TargetAcc set [TELID length 6 for 3 bytes]"), "{text}");
    assert!(text.contains("error: 1 byte(s) outside a frame skipped"), "{text}");
    assert!(text.contains("Home [BCC 0x00 wrong, expected 0x28]"), "{text}");

    let out = decode("(1700000000.000000) can0 0F1#01\n(1700000000.000100) can0 0B1#01\n  can0  0D1   [2]  0A 3C\n(1.0) can0 100#07\n");
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("put to module 17: Home"), "{text}");
    assert!(text.contains("ack from module 17: Home acknowledged"), "{text}");
    assert!(text.contains("get to module 17: GetExtended ActPos"), "{text}");
    assert!(text.contains("broadcast: Watchdog refresh"), "{text}");

    let out = decode("(1.0) can0 0F1#0\n");
    assert_eq!(code(&out), 2);
    let out = Command::new(BIN).args(["decode", "powercube", "02", "06", "21", "01", "28", "03"]).output().unwrap();
    assert!(String::from_utf8_lossy(&out.stdout).contains("to module 17: Home"));
}

#[test]
fn demo_shows_the_manuals_examples() {
    let out = Command::new(BIN).args(["demo", "powercube"]).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8_lossy(&out.stdout);
    for needle in [
        "0F1#01",
        "0B1#01",
        "0F1#08500000003F",
        "0B1#085064",
        "0D1#0A27",
        "0F1#0B0E0000403F",
        "02 06 21 01 28 03",
        "02 0A 21 01 2C 03",
        "02 06 21 10 82 29 03",
    ] {
        assert!(text.contains(needle), "{needle} missing in\n{text}");
    }
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
    ok(port, &["set", "TargetAcc", "4"]);
    assert!(ok(port, &["move", "0.1", "--vel", "1"]).contains("reached: position 0.1000"));
    assert_eq!(number(port, "TargetVelInc"), ticks(1.0));
    assert_eq!(number(port, "TargetAccInc"), ticks(4.0), "TargetAcc kept, not replaced by a default");
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
    for args in [
        &["move", "nan"][..],
        &["move", "inf"],
        &["move", "0.1", "--vel", "inf"],
        &["move", "0.1", "--vel", "NaN"],
        &["move", "0.1", "--acc", "nan"],
        &["move", "0.1", "--vel", "0"],
        &["move", "0.1", "--acc=-1"],
        &["move", "0.1", "--timeout", "nan"],
        &["--timeout-ms", "0", "state"],
        &["--timeout-ms", "0", "move", "0.1"],
    ] {
        let out = run(port, args);
        assert_eq!(code(&out), 2, "{args:?}: {}", String::from_utf8_lossy(&out.stderr));
    }
    // Nothing moved, nothing was written.
    assert_eq!(number(port, "ActPos"), f64::from(0.05f32));
    assert_eq!(number(port, "TargetVelInc"), vel);
    let state: serde_json::Value = serde_json::from_str(&ok(port, &["--json", "state"])).unwrap();
    assert!(!state["flags"].as_array().unwrap().iter().any(|f| f == "STATE_MOTION"), "{state}");
}
