//! `motionlink powercube`, `motionlink sim powercube`, `motionlink decode powercube` and the demo, end to end
//! through the built binary: over TCP, over a pty, and over SLCAN on a pty.

use std::io::{BufRead, BufReader, Write};
use std::process::{Child, Command, Output, Stdio};
use std::time::Duration;

const BIN: &str = env!("CARGO_BIN_EXE_motionlink");

/// A running `motionlink sim powercube`, killed when dropped.
struct Sim {
    child: Child,
    address: String,
}

impl Sim {
    fn start(args: &[&str]) -> Sim {
        let mut child = Command::new(BIN)
            .args(["sim", "powercube"])
            .args(args)
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("start the emulator");
        let mut line = String::new();
        BufReader::new(child.stdout.take().unwrap()).read_line(&mut line).unwrap();
        let address = line
            .trim()
            .strip_prefix("listening on pty ")
            .or_else(|| line.trim().strip_prefix("listening on "))
            .unwrap_or_else(|| panic!("unexpected first line {line:?}"))
            .to_string();
        Sim { child, address }
    }
}

impl Drop for Sim {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

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
    let sim = Sim::start(&["--tcp", "127.0.0.1:0", "--modules", "1,17"]);
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
    let moved = ok(port, &["--module", "17", "move", "-0.1", "--vel", "1", "--acc", "4"]);
    assert!(moved.contains("reached: position -0.1000") && moved.contains("STATE_RAMP_END"), "{moved}");

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
    let sim = Sim::start(&["--tcp", "127.0.0.1:0"]);
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
    let sim = Sim::start(&["--tcp", "127.0.0.1:0"]);
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
    assert_eq!(code(&out), 1, "{}", String::from_utf8_lossy(&out.stderr));
    assert!(String::from_utf8_lossy(&out.stderr).contains("cancelled"));
    let state = ok(&port, &["state"]);
    assert!(state.contains("STATE_HALTED") && !state.contains("STATE_MOTION"), "{state}");
}

#[cfg(unix)]
#[test]
fn over_a_pty() {
    let sim = Sim::start(&["--pty", "--modules", "2"]);
    assert!(sim.address.starts_with("/dev/"), "{}", sim.address);
    let scan = ok(&sim.address, &["scan"]);
    assert!(scan.lines().any(|l| l.starts_with("2 ")), "{scan}");
    assert!(ok(&sim.address, &["--module", "2", "home"]).starts_with("homed"));
    assert!(ok(&sim.address, &["--module", "2", "move", "0.05", "--vel", "1", "--acc", "4"]).contains("0.0500"));
}

#[cfg(unix)]
#[test]
fn over_slcan_on_a_pty() {
    let sim = Sim::start(&["--pty", "--slcan", "--modules", "3,9"]);
    let port = format!("slcan://{}", sim.address);
    let scan = ok(&port, &["scan"]);
    assert!(scan.lines().any(|l| l.starts_with("3 ")) && scan.lines().any(|l| l.starts_with("9 ")), "{scan}");
    assert!(ok(&port, &["--module", "9", "home"]).starts_with("homed"));
    assert!(ok(&port, &["--module", "9", "move", "0.08", "--vel", "1", "--acc", "4"]).contains("0.0800"));
    assert!(ok(&port, &["--module", "9", "get", "ActPos"]).contains("0.080000"));
}

#[test]
fn sim_configuration_errors_are_usage_errors() {
    let dir = std::env::temp_dir().join(format!("motionlink-pc-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let bad = dir.join("bad.toml");
    std::fs::write(&bad, "[[module]]\naddress = 40\n").unwrap();
    let out =
        Command::new(BIN).args(["sim", "powercube", "--tcp", "127.0.0.1:0", "--config"]).arg(&bad).output().unwrap();
    assert_eq!(code(&out), 2);
    assert!(String::from_utf8_lossy(&out.stderr).contains("outside 1..31"));
    let good = dir.join("good.toml");
    std::fs::write(&good, "[[module]]\naddress = 4\nkind = \"linear\"\nmin_pos = 0.0\nmax_pos = 0.2\n").unwrap();
    let sim = Sim::start(&["--tcp", "127.0.0.1:0", "--config", good.to_str().unwrap()]);
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
