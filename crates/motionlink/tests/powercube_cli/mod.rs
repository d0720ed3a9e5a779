//! `motionlink powercube`, `motionlink sim powercube`, `motionlink decode powercube` and the demo, end to end
//! through the built binary: over TCP, over a pty, and over SLCAN on a pty.

mod conventions;
mod decoding;
mod modes;
#[cfg(unix)]
mod signals;
mod variants;

use decoding::decode;
#[cfg(unix)]
use signals::start_moving;

use std::io::Write;
use std::process::{Command, Output, Stdio};
use std::time::Duration;

use crate::common;

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
    assert!(String::from_utf8_lossy(&out.stderr).contains("no module answers at address 5"));

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
    assert!(err.contains("target position 1 rad is outside MinPos..MaxPos = -3.14..0.05 rad"), "{err}");
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
    let port = sim.address.clone();
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
    // Its watchdog was armed: the message says what that does, that it is left online, and how to clear the
    // module afterwards; once.
    assert!(ended.stderr.contains("its watchdog is online and no longer refreshed"), "{}", ended.stderr);
    assert!(ended.stderr.contains("halts itself within 50 ms"), "{}", ended.stderr);
    assert_eq!(ended.stderr.matches("`reset` clears it").count(), 1, "{}", ended.stderr);
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

/// The `-v` trace's time of day of the first line that contains `what`, in seconds.
fn traced_at(trace: &str, what: &str) -> f64 {
    let line = trace.lines().find(|l| l.contains(what)).unwrap_or_else(|| panic!("no {what:?} in:\n{trace}"));
    let stamp = line.split_whitespace().next().unwrap();
    stamp.split(':').fold(0.0, |total, part| total * 60.0 + part.parse::<f64>().unwrap())
}

/// `--port sim`'s line is paced to `--baud`: at 9600 baud a GetExtended ActPos (7 bytes) and its reply (11
/// bytes) take 18.75 ms on the wire, and the reply is traced no sooner.
#[test]
fn the_in_process_sim_port_is_paced_to_the_baud_rate() {
    let out = run("sim", &["-v", "--baud", "9600", "get", "ActPos"]);
    assert!(out.status.success(), "{out:?}");
    let trace = String::from_utf8_lossy(&out.stderr);
    let sent = traced_at(&trace, "to module 1: GetExtended ActPos");
    let answered = traced_at(&trace, "from module 1: ActPos =");
    // (A trace across midnight starts the day again.)
    let took_ms = (answered - sent).rem_euclid(86_400.0) * 1e3;
    assert!(took_ms >= 18.0, "the reply came {took_ms:.1} ms after the request:\n{trace}");
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
    assert!(j["read_back"].is_number() && j["not_verifiable"] == serde_json::json!([]) && j["verified"] == true, "{j}");
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
