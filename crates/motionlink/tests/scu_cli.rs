//! The built `motionlink` binary, end to end: `motionlink sim scu` serving over TCP and a pty, and
//! `motionlink scu` talking to it.

use std::io::Write;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

mod common;

use common::{Sim, BIN};

fn sim_tcp() -> Sim {
    Sim::tcp("scu")
}

fn scu(port: &str, args: &[&str]) -> Output {
    Command::new(BIN).args(["scu", "--port", port]).args(args).output().expect("run motionlink scu")
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn json(o: &Output) -> serde_json::Value {
    assert!(o.status.success(), "{o:?}");
    serde_json::from_str(stdout(o).trim()).expect("one JSON object")
}

#[test]
fn sim_prints_one_listening_line_and_serves_info() {
    let sim = sim_tcp();
    assert!(sim.address.starts_with("tcp://127.0.0.1:"), "{}", sim.address);
    let out = scu(&sim.address, &["info"]);
    assert!(out.status.success(), "{out:?}");
    let text = stdout(&out);
    assert!(text.contains("SCU V2B3"), "{text}");
    assert!(text.contains("actuator 1") && text.contains("actuator 2"), "{text}");
    let info = json(&scu(&sim.address, &["info", "--json"]));
    assert_eq!(info["actuators"].as_array().unwrap().len(), 2);
}

#[test]
fn get_prints_a_table_or_json_with_a_value_field() {
    let sim = sim_tcp();
    let v = json(&scu(&sim.address, &["get", "0x0011", "--json"]));
    assert_eq!(v["value"], 0);
    assert_eq!(v["name"], "actual_position_a1");
    let v = json(&scu(&sim.address, &["--json", "get", "remote_speed_f1"]));
    assert_eq!(v["value"], 100);
    let group = json(&scu(&sim.address, &["get", "actuator_status1", "--json"]));
    assert_eq!(group["value"]["actuator_status1_a1"]["set"][0], "available");
    let table = stdout(&scu(&sim.address, &["get", "error_codes"]));
    assert_eq!(table.lines().count(), 5, "{table}");
}

#[test]
fn set_then_get_round_trips_and_the_state_persists_between_connections() {
    let sim = sim_tcp();
    assert!(scu(&sim.address, &["set", "remote_speed_f2", "45"]).status.success());
    let v = json(&scu(&sim.address, &["get", "remote_speed_f2", "--json"]));
    assert_eq!(v["value"], 45);
}

#[test]
fn move_reaches_its_target_and_the_unit_keeps_the_position() {
    let sim = sim_tcp();
    let started = Instant::now();
    let out = scu(&sim.address, &["move", "2", "70", "--speed", "100", "--json"]);
    let v = json(&out);
    assert_eq!(v["position"], 70);
    assert_eq!(v["actuator"], 2);
    // 70 counts at 110 counts/s with a 300 ms ramp: under a second and a half.
    assert!(started.elapsed() < Duration::from_secs(5));
    let p = json(&scu(&sim.address, &["get", "actual_position_a2", "--json"]));
    assert_eq!(p["value"], 70);
}

#[test]
fn exit_codes_follow_the_contract() {
    let sim = sim_tcp();
    // 2: usage errors, found before the port is opened or by the client's own checks.
    for args in [
        &["get", "no_such_entry"][..],
        &["set", "actual_position_a1", "5"],
        &["set", "remote_speed_f1", "101"],
        &["move", "7", "10"],
        &["run", "F12", "on"],
        &["frobnicate"],
    ] {
        let out = scu(&sim.address, args);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {out:?}");
        assert!(!out.stderr.is_empty(), "{args:?} says what is wrong");
    }
    // 1: the unit refuses (F6 drives no actuator on a two-actuator SCP11 unit: PE).
    let out = scu(&sim.address, &["run", "F6", "out"]);
    assert_eq!(out.status.code(), Some(1), "{out:?}");
    assert!(String::from_utf8_lossy(&out.stderr).contains("PE"), "{out:?}");
    // 3: transport errors.
    let out = scu("tcp://127.0.0.1:1", &["info"]);
    assert_eq!(out.status.code(), Some(3), "{out:?}");
    let out = Command::new(BIN).args(["scu", "--port", "tcp://nohost", "info"]).output().unwrap();
    assert_eq!(out.status.code(), Some(2), "a malformed port is a usage error: {out:?}");
}

#[test]
fn errors_lists_five_codes() {
    let sim = sim_tcp();
    let v = json(&scu(&sim.address, &["errors", "--json"]));
    assert_eq!(v["errors"].as_array().unwrap().len(), 5);
}

#[test]
fn watch_prints_samples() {
    let sim = sim_tcp();
    let out = scu(&sim.address, &["watch", "--count", "3", "--interval", "50"]);
    assert!(out.status.success(), "{out:?}");
    let text = stdout(&out);
    assert_eq!(text.lines().count(), 3, "{text}");
    assert!(text.contains("A1: 0 counts stopped"), "{text}");
}

#[test]
fn run_switches_a_function_for_a_while_and_stops_it() {
    let sim = sim_tcp();
    let out = scu(&sim.address, &["run", "F1", "out", "--seconds", "0.5"]);
    assert!(out.status.success(), "{out:?}");
    let p = json(&scu(&sim.address, &["get", "actual_position_a1", "--json"]));
    let p = p["value"].as_i64().unwrap();
    assert!((20..70).contains(&p), "moved for half a second: {p}");
    let out = scu(&sim.address, &["run", "F11", "on", "--seconds", "0.2"]);
    assert!(out.status.success(), "{out:?}");
    let buzzer = json(&scu(&sim.address, &["get", "buzzer", "--json"]));
    assert_eq!(buzzer["value"]["bits"], 0, "the buzzer is off again after run");
}

#[test]
fn ctrl_c_stops_a_move() {
    let sim = sim_tcp();
    let child = Command::new(BIN)
        .args(["scu", "--port", &sim.address, "move", "1", "800", "--speed", "100"])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(1200));
    let killed = Command::new("kill").args(["-INT", &child.id().to_string()]).status().unwrap();
    assert!(killed.success());
    let out = child.wait_with_output().unwrap();
    assert_eq!(out.status.code(), Some(130), "{out:?}");
    assert!(String::from_utf8_lossy(&out.stderr).contains("stopped"), "{out:?}");
    let p1 = json(&scu(&sim.address, &["get", "actual_position_a1", "--json"]))["value"].as_i64().unwrap();
    std::thread::sleep(Duration::from_millis(400));
    let p2 = json(&scu(&sim.address, &["get", "actual_position_a1", "--json"]))["value"].as_i64().unwrap();
    assert!(p1 > 30 && p1 < 800, "it moved, and not to the end: {p1}");
    assert_eq!(p1, p2, "it stays stopped");
}

#[test]
fn a_pty_serves_like_a_serial_port() {
    let sim = Sim::start("scu", &["--pty"]);
    assert!(sim.address.starts_with("/dev/"), "{}", sim.address);
    for _ in 0..2 {
        let v = json(&scu(&sim.address, &["get", "firmware_info", "--json"]));
        assert!(v["value"].as_str().unwrap().starts_with("SCU"));
    }
    let v = json(&scu(&sim.address, &["move", "1", "30", "--json"]));
    assert_eq!(v["position"], 30);
    let info = json(&scu(&sim.address, &["info", "--json"]));
    assert_eq!(info["actuators"].as_array().unwrap().len(), 2);
    let sample = json(&scu(&sim.address, &["watch", "--count", "1", "--json"]));
    assert_eq!(sample["actuators"][0]["position"], 30);
}

#[test]
fn sim_with_a_config_file() {
    let dir = std::env::temp_dir().join(format!("motionlink-scu-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("unit.toml");
    std::fs::write(&path, "actuators = 4\nfirmware_info = \"TEST UNIT\"\n").unwrap();
    let sim = Sim::start("scu", &["--tcp", "127.0.0.1:0", "--config", path.to_str().unwrap()]);
    let info = json(&scu(&sim.address, &["info", "--json"]));
    assert_eq!(info["actuators"].as_array().unwrap().len(), 4);
    assert_eq!(info["firmware"], "TEST UNIT");
    drop(sim);
    std::fs::write(&path, "actuators = 9\n").unwrap();
    let out = Command::new(BIN).args(["sim", "scu", "--tcp", "127.0.0.1:0", "--config"]).arg(&path).output().unwrap();
    assert_eq!(out.status.code(), Some(2), "{out:?}");
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn decode_reads_hex_from_arguments_and_stdin() {
    // The manual's chapter 5 RG of actuator 1's position and the reply with 400 counts, and a corrupt byte.
    let out = Command::new(BIN)
        .args(["decode", "scu", "52 47 11 00 2C 30", "52 47 06 04 00 90 01 00 00 A3 AD", "FF"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{out:?}");
    let text = stdout(&out);
    let lines: Vec<_> = text.lines().collect();
    assert_eq!(lines.len(), 3, "{text}");
    assert!(lines[0].starts_with("->") && lines[0].contains("actual_position_a1"), "{text}");
    assert!(lines[1].starts_with("<-") && lines[1].contains("400 counts"), "{text}");
    assert!(lines[2].starts_with("!!"), "{text}");

    let mut child = Command::new(BIN)
        .args(["decode", "scu", "--json"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    child.stdin.take().unwrap().write_all(b"# RO and its ACK\n524F005C2D\n52 4F 06 9A 4D\n").unwrap();
    let out = child.wait_with_output().unwrap();
    let lines: Vec<serde_json::Value> = stdout(&out).lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    assert_eq!(lines.len(), 2);
    assert_eq!(lines[0]["direction"], "->");
    assert_eq!(lines[1]["direction"], "<-");
    assert_eq!(lines[1]["meaning"], "RO ACK");

    let out = Command::new(BIN).args(["decode", "scu", "52 4"]).output().unwrap();
    assert_eq!(out.status.code(), Some(2), "bad hex is a usage error");
}

#[test]
fn decode_reads_raw_bytes_and_names_the_reply_to_an_unknown_command() {
    // An unknown command "RX" and the unit's ICE, which repeats its letters; then the RO example.
    let capture = [0x52, 0x58, 0x20, 0xB3, 0x52, 0x58, 0x83, 0x53, 0x16, 0x52, 0x4F, 0x00, 0x5C, 0x2D];
    let mut child = Command::new(BIN)
        .args(["decode", "scu", "--raw"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    child.stdin.take().unwrap().write_all(&capture).unwrap();
    let out = child.wait_with_output().unwrap();
    assert!(out.status.success(), "{out:?}");
    let text = stdout(&out);
    let lines: Vec<_> = text.lines().collect();
    assert_eq!(lines.len(), 3, "{text}");
    assert!(lines[0].starts_with("->") && lines[0].contains("RX: unknown command"), "{text}");
    assert!(lines[1].starts_with("<-") && lines[1].contains("RX ICE"), "{text}");
    assert!(lines[2].starts_with("->") && lines[2].contains("RO"), "{text}");
}

#[test]
fn a_counts_per_second_unit_takes_speeds_up_to_1000() {
    let out = scu("sim", &["--speed-mode", "counts-per-second", "set", "remote_speed_f1", "500"]);
    assert!(out.status.success(), "{out:?}");
    let out = scu("sim", &["set", "remote_speed_f1", "500"]);
    assert_eq!(out.status.code(), Some(2), "500 % is refused before sending: {out:?}");
    let out = scu("sim", &["--speed-mode", "counts-per-second", "move", "1", "40", "--speed", "400", "--json"]);
    assert_eq!(json(&out)["position"], 40);
    let out = scu("sim", &["move", "1", "40", "--function", "12"]);
    assert_eq!(out.status.code(), Some(2), "F12 is no motion function: {out:?}");
}

#[test]
fn demo_runs_the_manual_routine() {
    let out = Command::new(BIN).args(["demo", "scu"]).output().unwrap();
    assert!(out.status.success(), "{out:?}");
    let text = stdout(&out);
    assert!(text.contains("52 54 04 00 11 30 01 00 B5 F2"), "the manual's RT example, encoded");
    assert!(text.contains("actual_position_a1 = 400 counts"), "{text}");
    assert!(text.contains("RA ACK"), "{text}");
}
