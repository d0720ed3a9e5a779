//! The built `motionlink` binary, end to end: `motionlink sim scu` serving over TCP and a pty, and
//! `motionlink scu` talking to it.

mod conventions;
mod signals;
mod slow_link;
mod variants;

use signals::{wait_at_rest, wait_started};

use std::io::Write;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use crate::common;

use common::{unix_now, Running, Sim, BIN};

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
    assert_eq!(v["unit"], "%", "the unit in force (--speed-mode percent), not both: {v}");
    let v = json(&scu(&sim.address, &["--json", "--speed-mode", "counts-per-second", "get", "remote_speed_f1"]));
    assert_eq!(v["unit"], "counts/s", "{v}");
    // Currents in amperes, as the library gives them, in `get` and in the names list alike.
    let v = json(&scu(&sim.address, &["--json", "get", "current_a1"]));
    assert_eq!((&v["unit"], &v["value"]), (&"A".into(), &0.0.into()), "{v}");
    let names = stdout(&scu("", &["--json", "names"]));
    let current = names.lines().find(|l| l.contains("\"current_a1\"")).unwrap();
    assert!(current.contains("\"unit\":\"A\""), "{current}");
    let group = json(&scu(&sim.address, &["get", "actuator_status1", "--json"]));
    assert_eq!(group["value"]["actuator_status1_a1"]["flags"][0], "available");
    assert!(group["value"]["actuator_status1_a1"]["word"].is_number(), "a flag word has its word: {group}");
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
    assert_eq!(v["reached_counts"], 70);
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
    let out = scu(&sim.address, &["watch", "--count", "3", "--interval-ms", "50"]);
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
    // Said as a switch: on, then off by the RS, each read back from the entry that shows the buzzer.
    let said = String::from_utf8_lossy(&out.stdout);
    assert!(
        said.contains(
            "F11 (buzzer) switched on (RE acknowledged; read back from buzzer (0x0140, bit 0): on); Ctrl-C switches it \
             off (RS)"
        ),
        "{said}"
    );
    assert!(said.contains("F11 (buzzer) switched off (RS acknowledged)") && !said.contains("stopped"), "{said}");
    assert!(
        said.lines()
            .last()
            .unwrap_or_default()
            .starts_with("verified  yes: read back from buzzer (0x0140, bit 0): on after the RE, off after the RS"),
        "{said}"
    );
    let buzzer = json(&scu(&sim.address, &["get", "buzzer", "--json"]));
    assert_eq!(buzzer["value"]["word"], 0, "the buzzer is off again after run");
    // The emergency stop: engaged while the run runs, released by its RS, each read back from lock_status.
    let out = scu(&sim.address, &["run", "F20", "on", "--seconds", "0.2"]);
    let said = stdout(&out);
    assert!(out.status.success(), "{out:?}");
    assert!(
        said.contains(
            "verified  yes: read back from lock_status (0x0162, bits 0..9): engaged after the RE, released after the RS"
        ),
        "{said}"
    );
    // `stop` of a switching function: RS, read back.
    let out = scu(&sim.address, &["stop", "F17"]);
    assert_eq!(
        stdout(&out),
        "F17 (binary output 1) switched off (RS)\nverified  yes: read back from binary_outputs (0x0110, \
         bit 0): off\n",
        "{out:?}"
    );
}

/// A switching function whose entry the manuals do not tie to it in so many words, on a unit where the entry
/// does not follow it: switched all the same, exit 0, and said to be not verified (never an error, never a
/// claim).
#[test]
fn a_switch_the_unit_does_not_show_is_done_and_said_not_verified() {
    let variant = ["--port", "sim", "--sim-variant", "switch-status-unshown"];
    let run = |words: &[&str]| common::run_with(&[&["scu"][..], &variant, words].concat(), &[], "");
    let out = run(&["run", "F18", "on", "--seconds", "0.1"]);
    assert!(out.status.success(), "{out:?}");
    let said = stdout(&out);
    assert!(said.contains("F18 (binary output 2) switched on (RE acknowledged; not verified by its status)"), "{said}");
    let last = said.lines().last().unwrap_or_default();
    assert!(
        last.starts_with(
            "verified  no: F18 (binary output 2) was not verified by its status: binary_outputs (0x0110, bit 1) did \
             not show binary output 2 on after the acknowledged RE"
        ),
        "{said}"
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(err.matches("warning: F18 (binary output 2) was not verified").count(), 1, "one warning: {err}");
    // The emergency stop, in JSON: the first line says it was not verified, the last why.
    let out = run(&["--json", "run", "F20", "on", "--seconds", "0.1"]);
    assert!(out.status.success(), "{out:?}");
    let lines: Vec<serde_json::Value> =
        stdout(&out).lines().map(|l| serde_json::from_str(l).expect("a JSON line")).collect();
    assert_eq!((&lines[0]["running"], &lines[0]["verified"]), (&true.into(), &false.into()), "{lines:?}");
    assert_eq!(lines[1]["verified"], false, "{lines:?}");
    let why = lines[1]["not_verifiable"][0].as_str().unwrap_or_default();
    assert!(
        why.starts_with(
            "F20 (emergency stop) was not verified by its status: lock_status (0x0162, bits 0..9) did not show the \
             emergency stop engaged after the acknowledged RE"
        ),
        "{why}"
    );
    // A stop alone finds the LED off before the RS as after it: not verified, exit 0.
    let out = run(&["--json", "stop", "F21"]);
    let stopped = json(&out);
    assert_eq!((&stopped["mode"], &stopped["verified"]), (&"off".into(), &false.into()), "{stopped}");
}

/// A unit that acknowledges the RE of binary output 1 but shows it off (its output failed:
/// `failed_switches` in the emulator's configuration): an error naming what was sent and what the status
/// shows, exit 1, and the run switches it off again.
#[test]
fn a_switch_whose_status_shows_the_other_state_is_an_error_naming_it() {
    let path = common::temp_path("scu-failed-switch.toml");
    std::fs::write(&path, "failed_switches = [\"F17\"]\n").expect("write the emulator configuration");
    let config = path.to_str().expect("a UTF-8 temporary path");
    let out = scu("sim", &["--sim-config", config, "run", "F17", "on", "--seconds", "0.1"]);
    assert_eq!(out.status.code(), Some(1), "{out:?}");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains(
            "motionlink: the unit acknowledged RE of F17 (binary output 1), but does not show binary output 1 on: \
             binary_outputs (0x0110, bit 0) is clear (0x00) (last read"
        ) && err.contains("; then switched off (the unit acknowledged the RS)"),
        "{err}"
    );
    assert!(!stdout(&out).contains("switched on"), "nothing said of a switch-on the unit did not show: {out:?}");
    let out = scu("sim", &["--sim-config", config, "--json", "stop", "F17"]);
    assert!(out.status.success(), "an output stuck off is off: {out:?}");
    let out = scu("sim", &["--sim-config", config, "--json", "run", "F17", "on"]);
    let e = common::json_error(&out);
    assert_eq!((e["kind"].as_str(), e["exit_code"].as_i64(), out.status.code()), (Some("device"), Some(1), Some(1)));
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
    assert_eq!(v["reached_counts"], 30);
    let info = json(&scu(&sim.address, &["info", "--json"]));
    assert_eq!(info["actuators"].as_array().unwrap().len(), 2);
    let sample = json(&scu(&sim.address, &["watch", "--count", "1", "--json"]));
    assert_eq!(sample["actuators"][0]["position_counts"], 30);
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
    assert_eq!(json(&out)["reached_counts"], 40);
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

#[test]
fn move_on_a_tlt_moves_both_columns_of_f1_and_reports_each() {
    let sim = Sim::start("scu", &["--tcp", "127.0.0.1:0", "--preset", "tlt"]);
    // Not told the mapping: every connected actuator gets the target; both columns of F1 move.
    let v = json(&scu(&sim.address, &["move", "1", "400", "--json"]));
    assert_eq!(v["reached_counts"], 400);
    let each: Vec<(i64, i64, bool)> = v["actuators"]
        .as_array()
        .unwrap()
        .iter()
        .map(|o| {
            (o["actuator"].as_i64().unwrap(), o["reached_counts"].as_i64().unwrap(), o["moved"].as_bool().unwrap())
        })
        .collect();
    assert_eq!(each, [(1, 400, true), (2, 400, true)]);
    for a in ["actual_position_a1", "actual_position_a2"] {
        assert_eq!(json(&scu(&sim.address, &["get", a, "--json"]))["value"], 400, "{a}");
    }
    // Told the mapping: the same, and F3 moves column 2 alone.
    let out = scu(&sim.address, &["--functions", "tlt", "move", "2", "200", "--function", "3"]);
    assert!(out.status.success(), "{out:?}");
    let text = stdout(&out);
    assert!(text.contains("A2") && text.contains("200 counts (target 200 counts, difference 0 counts)"), "{text}");
    assert!(!text.contains("A1 "), "F3 drives A2 only: {text}");
    assert_eq!(json(&scu(&sim.address, &["get", "actual_position_a1", "--json"]))["value"], 400);
    // A function the map says does not drive the actuator is refused before anything is sent.
    let out = scu(&sim.address, &["--functions", "tlt", "move", "1", "100", "--function", "3"]);
    assert_eq!(out.status.code(), Some(2), "{out:?}");
}

#[test]
fn move_on_liftkit_with_f8_moves_both() {
    let sim = Sim::start("scu", &["--tcp", "127.0.0.1:0", "--preset", "liftkit"]);
    let v = json(&scu(&sim.address, &["--functions", "liftkit", "move", "1", "250", "--function", "8", "--json"]));
    assert_eq!(v["function"], 8);
    assert_eq!(v["actuators"].as_array().unwrap().len(), 2);
    assert_eq!(json(&scu(&sim.address, &["get", "actual_position_a2", "--json"]))["value"], 250);
    assert!(sim.events().iter().any(|e| e.text.starts_with("F8 started direction 9")));
}

#[test]
fn a_target_outside_the_stroke_is_refused_naming_the_limit_and_nothing_moves() {
    let sim = sim_tcp();
    let out = scu(&sim.address, &["--functions", "scp11", "move", "1", "2000"]);
    assert_eq!(out.status.code(), Some(2), "{out:?}");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("0..865") && err.contains("2000"), "{err}");
    assert!(!sim.events().iter().any(|e| e.text.contains("started")), "nothing started: {}", sim.stderr.text());
    // A configured stroke is used instead of the unit's virtual limits.
    let out = scu(&sim.address, &["--functions", "scp11", "--stroke", "1=0:300", "move", "1", "400"]);
    assert_eq!(out.status.code(), Some(2), "{out:?}");
    assert!(String::from_utf8_lossy(&out.stderr).contains("as configured"), "{out:?}");
}

#[test]
fn a_move_that_ends_away_from_its_target_exits_1_naming_target_position_and_difference() {
    let dir = std::env::temp_dir().join(format!("motionlink-scu-obstacle-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("unit.toml");
    std::fs::write(&path, "[[actuator]]\nobstacle_counts = 150\nstall_error_after_ms = 1000\n").unwrap();
    let sim = Sim::start("scu", &["--tcp", "127.0.0.1:0", "--config", path.to_str().unwrap()]);
    let out = scu(&sim.address, &["--functions", "scp11", "move", "1", "300"]);
    assert_eq!(out.status.code(), Some(1), "{out:?}");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("150 counts") && err.contains("300") && err.contains("-150"), "{err}");
    assert!(err.contains("bit 15"), "the drive error is named: {err}");
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn bad_input_is_refused_with_exit_2_before_anything_is_sent() {
    let sim = sim_tcp();
    let cases: &[&[&str]] = &[
        &["move", "1", "100", "--speed", "0"],
        &["move", "1", "100", "--speed", "-5"],
        &["move", "1", "100", "--speed", "NaN"],
        &["move", "1", "100", "--speed", "101"],
        &["move", "1", "100", "--speed", "50.5"],
        &["--speed-mode", "counts-per-second", "move", "1", "100", "--speed", "1001"],
        &["move", "0", "100"],
        &["move", "7", "100"],
        &["move", "1", "100", "--function", "11"],
        &["--tolerance", "-1", "move", "1", "100"],
        &["--tolerance", "10000", "move", "1", "100"],
        &["--poll-ms", "0", "move", "1", "100"],
        &["--poll-ms", "NaN", "move", "1", "100"],
        &["--timeout-ms", "0", "info"],
        &["--safety", "3", "info"],
        &["--functions", "F11=1", "info"],
        &["--functions", "F1=7", "info"],
        &["--stroke", "1=500:100", "info"],
        &["--stroke", "9=0:100", "info"],
        &["run", "F1", "out", "--seconds", "NaN"],
        &["run", "F1", "out", "--seconds", "-1"],
        &["watch", "--interval-ms", "0"],
        &["watch", "--count", "0"],
        &["follow", "1", "--rate", "0"],
        &["follow", "1", "--rate", "101"],
        &["follow", "1", "--speed", "0"],
    ];
    for args in cases {
        let out = scu(&sim.address, args);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {out:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        // The message names the argument (clap names it too, as "--speed <SPEED>" and the like): the last
        // option given, or the actuator.
        let named = args.iter().rev().find(|a| a.starts_with("--")).map_or("actuator", |a| &a[2..]);
        assert!(err.contains(named) || (named == "actuator" && err.contains("actuator")), "{args:?}: {err}");
    }
    assert!(sim.events().is_empty(), "nothing reached the unit: {}", sim.stderr.text());
}

#[test]
fn set_reads_the_value_back() {
    let sim = sim_tcp();
    let out = scu(&sim.address, &["set", "remote_position_a2", "321"]);
    assert!(out.status.success(), "{out:?}");
    assert!(stdout(&out).contains("321 counts (written, read back)"), "{}", stdout(&out));
    let v = json(&scu(&sim.address, &["set", "remote_speed_f1", "33", "--json"]));
    assert_eq!((&v["value"], &v["read_back"], &v["verified"]), (&33.into(), &33.into(), &true.into()), "{v}");
}

#[test]
fn the_safety_id_goes_into_ro() {
    let sim = sim_tcp();
    assert!(scu(&sim.address, &["--safety", "2", "info"]).status.success());
    assert!(sim.wait_event(Duration::from_secs(5), |e| e == "remote mode opened (Safety_ID 2)").is_some());
}

#[test]
fn follow_streams_targets_from_stdin_and_stops_on_eof() {
    let sim = Sim::start("scu", &["--tcp", "127.0.0.1:0", "--preset", "tlt"]);
    let (running, mut stdin) =
        Running::start_with_stdin(&["scu", "--port", &sim.address, "--functions", "tlt", "follow", "1"]);
    running.stdout.wait_for(Duration::from_secs(5), |l| l.starts_with("following F1 (A1, A2)")).expect("ready");
    writeln!(stdin, "# both columns to 200\n200").unwrap();
    running.stdout.wait_for(Duration::from_secs(5), |l| l == "target A1=200 A2=200 counts").expect("applied");
    let (_, p) = wait_at_rest(&sim, "A1", 0.0);
    assert_eq!(p, 200);
    // Each its own target, then a new speed, then named targets.
    writeln!(stdin, "150 160\nspeed 60\na2=120 a1=110").unwrap();
    running.stdout.wait_for(Duration::from_secs(5), |l| l == "target A1=110 A2=120 counts").expect("applied");
    let t = unix_now();
    wait_at_rest(&sim, "A1", t);
    drop(stdin); // EOF: the stream ends, the motion is stopped
    let ended = running.wait(Duration::from_secs(10));
    assert_eq!(ended.code(), 0, "{ended:?}");
    assert!(ended.stdout.contains("stopped after"), "{}", ended.stdout);
    assert!(sim.events().iter().any(|e| e.text == "F1 stopped (RS soft)"), "{}", sim.stderr.text());
    assert_eq!(json(&scu(&sim.address, &["get", "actual_position_a2", "--json"]))["value"], 120);
}

#[test]
fn follow_from_a_file_goes_to_the_newest_target_and_merges_lines_faster_than_its_rate() {
    // The README's `follow 1 < targets.txt`: the whole input arrives at once and ends at once. Lines that
    // come faster than --rate are merged (the newest wins, the last one included), and end of input lets the
    // motion reach that last target before the stream ends.
    let sim = Sim::start("scu", &["--tcp", "127.0.0.1:0", "--preset", "tlt"]);
    let (running, mut stdin) =
        Running::start_with_stdin(&["scu", "--port", &sim.address, "--functions", "tlt", "follow", "1", "--rate", "2"]);
    writeln!(stdin, "100\n200\n300\n400\n500").unwrap();
    drop(stdin);
    let ended = running.wait(Duration::from_secs(20));
    assert_eq!(ended.code(), 0, "{ended:?}");
    let updates: Vec<&str> = ended.stdout.lines().filter(|l| l.starts_with("target ")).collect();
    assert!(updates.len() < 5, "lines faster than the rate are merged: {updates:?}");
    assert_eq!(updates.last(), Some(&"target A1=500 A2=500 counts"), "the newest wins: {}", ended.stdout);
    assert!(ended.stdout.contains("stopped after"), "{}", ended.stdout);
    for a in ["actual_position_a1", "actual_position_a2"] {
        assert_eq!(json(&scu(&sim.address, &["get", a, "--json"]))["value"], 500, "{a}");
    }
}

#[test]
fn follow_stops_on_a_bad_line_and_on_a_signal() {
    let sim = sim_tcp();
    let (running, mut stdin) =
        Running::start_with_stdin(&["scu", "--port", &sim.address, "--functions", "scp11", "follow", "1"]);
    running.stdout.wait_for(Duration::from_secs(5), |l| l.starts_with("following F1 (A1)")).expect("ready");
    writeln!(stdin, "800").unwrap();
    wait_started(&sim, "F1");
    writeln!(stdin, "eight hundred").unwrap();
    let ended = running.wait(Duration::from_secs(10));
    assert_eq!(ended.code(), 2, "{ended:?}");
    assert!(ended.stderr.contains("eight hundred"), "{}", ended.stderr);
    let (_, p) = wait_at_rest(&sim, "A1", 0.0);
    assert!(p < 800, "stopped on the way: {p}");

    // A line that is not text is a bad line (exit 2, named), not a transport error.
    let (running, mut stdin) =
        Running::start_with_stdin(&["scu", "--port", &sim.address, "--functions", "scp11", "follow", "1"]);
    running.stdout.wait_for(Duration::from_secs(5), |l| l.starts_with("following F1 (A1)")).expect("ready");
    stdin.write_all(b"3\xff0\n").unwrap();
    let ended = running.wait(Duration::from_secs(10));
    assert_eq!(ended.code(), 2, "{ended:?}");
    assert!(ended.stderr.contains("stdin line \"3\u{fffd}0\": not UTF-8 text"), "{}", ended.stderr);

    // A target outside the stroke is a bad line too: the motion is stopped, and the message says so.
    let (running, mut stdin) =
        Running::start_with_stdin(&["scu", "--port", &sim.address, "--functions", "scp11", "follow", "1"]);
    running.stdout.wait_for(Duration::from_secs(5), |l| l.starts_with("following F1 (A1)")).expect("ready");
    let t = unix_now();
    writeln!(stdin, "0").unwrap();
    sim.wait_event_after(t, Duration::from_secs(5), |e| e.starts_with("F1 started")).expect("moving");
    writeln!(stdin, "9999").unwrap();
    let ended = running.wait(Duration::from_secs(10));
    assert_eq!(ended.code(), 2, "{ended:?}");
    assert!(
        ended.stderr.contains("target 9999 counts for A1 refused: it lies outside A1's stroke"),
        "{}",
        ended.stderr
    );
    assert!(ended.stderr.trim_end().ends_with("F1 stopped") && !ended.stderr.contains("nothing was moved"));
    assert!(ended.stdout.contains("stopped after"), "{}", ended.stdout);

    let (running, mut stdin) =
        Running::start_with_stdin(&["scu", "--port", &sim.address, "--functions", "scp11", "follow", "1"]);
    running.stdout.wait_for(Duration::from_secs(5), |l| l.starts_with("following")).expect("ready");
    let t = unix_now();
    writeln!(stdin, "400").unwrap();
    running.stdout.wait_for(Duration::from_secs(5), |l| l == "target A1=400 counts").expect("applied");
    sim.wait_event_after(t, Duration::from_secs(5), |e| e.starts_with("F1 started")).expect("moving back");
    let sent = running.signal(libc::SIGTERM);
    let (rest, _) = wait_at_rest(&sim, "A1", sent);
    assert!(rest.at - sent < 0.100, "at rest {:.0} ms after the signal", (rest.at - sent) * 1e3);
    let ended = running.wait(Duration::from_secs(10));
    assert_eq!(ended.code(), 143, "{ended:?}");
    drop(stdin);
}

#[test]
fn probe_reports_the_edition_as_either_with_why_the_protocol_cannot_tell() {
    let sim = sim_tcp();
    let out = Command::new(BIN).args(["probe", "scu", "--port", &sim.address, "--json", "--exchanges", "2"]).output();
    let v = json(&out.expect("run motionlink probe scu"));
    let device = &v["devices"][0];
    assert_eq!(device["edition"], "either: one protocol", "{v}");
    let detail = device["edition_detail"].as_str().unwrap();
    assert!(detail.contains("describe one protocol") && detail.contains("name neither vendor"), "{detail}");
    let out = Command::new(BIN).args(["probe", "scu", "--port", &sim.address, "--exchanges", "2"]).output().unwrap();
    assert!(out.status.success(), "{out:?}");
    assert!(stdout(&out).contains("(edition: either: one protocol: the Ewellix and the Schaeffler manual"), "{out:?}");
}

/// A unit with an error standing after which motions are not performed (bit 25) refuses every RE with PE:
/// `follow` fails with that refusal, and does not claim (was: warned) that the unit needs an RS after every
/// RE while the function runs: it never ran.
#[test]
fn follow_on_a_unit_that_performs_no_motion_fails_without_claiming_a_running_function() {
    let path = common::temp_path("scu-error-25.toml");
    std::fs::write(&path, "[[error]]\nbit = 25\nat_ms = 1\n").expect("write the emulator configuration");
    let config = path.to_str().expect("a UTF-8 temporary path");
    let out = common::run_with(&["scu", "--port", "sim", "--sim-config", config, "follow", "1"], &[], "400\n");
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("RE (remote execute function) refused by the unit: PE"), "{err}");
    assert!(!err.contains("needs the RS") && !err.contains("while it ran"), "{err}");
    // The refusal alone names no cause: the unit's last error is said with it, for `move` as for `follow`.
    assert!(err.contains("its last error is 0x01000000 [bit 25"), "{err}");
    let out = scu("sim", &["--sim-config", config, "move", "1", "400"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("its last error is 0x01000000 [bit 25"), "{err}");
}

/// `run` of a motion function that no actuator is seen to carry out within the start grace (a unit that
/// acknowledges the RE with an error standing, `ack-without-motion`; or actuators already at that end) says
/// so, with the unit's last error (was: "F1 stopped", as if it had run).
#[test]
fn a_run_no_actuator_was_seen_to_carry_out_says_so_with_the_last_error() {
    let path = common::temp_path("scu-error-25-ack.toml");
    std::fs::write(&path, "[[error]]\nbit = 25\nat_ms = 1\n").expect("write the emulator configuration");
    let config = path.to_str().expect("a UTF-8 temporary path");
    let out =
        scu("sim", &["--sim-config", config, "--sim-variant", "ack-without-motion", "--json", "run", "F1", "out"]);
    assert!(out.status.success(), "{out:?}");
    let last: serde_json::Value = serde_json::from_str(stdout(&out).lines().last().unwrap_or_default()).expect("JSON");
    assert_eq!(last["verified"], false, "{last}");
    let why = last["not_verifiable"].to_string();
    assert!(why.contains("no actuator was seen moving") && why.contains("bit 25"), "{last}");
    // A run that moves says nothing of it.
    let out = scu("sim", &["--json", "run", "F1", "out"]);
    let last: serde_json::Value = serde_json::from_str(stdout(&out).lines().last().unwrap_or_default()).expect("JSON");
    assert!(last.get("not_verifiable").is_none(), "{last}");
}
