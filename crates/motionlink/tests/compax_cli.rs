//! `motionlink compax` end to end: the built binary against `motionlink sim compax` over TCP and a pty.

use std::process::{Command, Output};

mod common;

use common::{Sim, BIN};

fn start_sim(args: &[&str]) -> Sim {
    Sim::start("compax", args)
}

fn compax(port: &str, args: &[&str]) -> Output {
    Command::new(BIN).args(["compax", "--port", port]).args(args).output().expect("run motionlink")
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn json(o: &Output) -> serde_json::Value {
    assert!(o.status.success(), "{}\n{}", stdout(o), String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout).expect("json")
}

#[test]
fn over_tcp_every_action() {
    let sim = start_sim(&["--tcp", "127.0.0.1:0", "--drives", "1,5", "--mode", "72", "--baud", "115200"]);
    let p = sim.address.as_str();
    let base = ["--mode", "72", "--baud", "115200"];
    let with = |extra: &[&str]| {
        let mut v: Vec<&str> = base.to_vec();
        v.extend_from_slice(extra);
        compax(p, &v)
    };
    let scan = json(&with(&["--timeout-ms", "30", "--json", "scan"]));
    let found: Vec<u64> = scan["drives"].as_array().unwrap().iter().map(|d| d["address"].as_u64().unwrap()).collect();
    assert_eq!(found, [1, 5]);

    let st = json(&with(&["--drive", "5", "--json", "status", "S1", "S17"]));
    assert_eq!(st["status"][0]["value"], 0.0);
    assert_eq!(st["status"][1]["value"]["bits"], "0000 0010");

    let o = with(&["--drive", "5", "set", "P12", "-3.5"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let g = json(&with(&["--drive", "5", "--json", "get", "P12"]));
    assert_eq!(g["value"], -3.5);

    let m = json(&with(&["--drive", "5", "--json", "move", "--abs", "1.5", "--speed", "100", "--accel", "10"]));
    assert_eq!(m["position"], 1.5);
    let m = json(&with(&["--drive", "5", "--json", "move", "--rel", "-0.5", "--binary"]));
    assert_eq!(m["position"], 1.0);

    let o = with(&["--drive", "1", "output", "9", "1"]);
    assert!(o.status.success());
    let r = json(&with(&["--drive", "1", "--json", "raw", "S2"]));
    assert_eq!(r["reply"], "S002: 0.000");

    // A refused command: exit code 1; a usage error: 2; nobody there: 3.
    let o = with(&["--drive", "1", "raw", "NOPE"]);
    assert_eq!(o.status.code(), Some(1), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stderr).contains("E90"));
    let o = with(&["--drive", "1", "move", "--abs", "1", "--speed", "150"]);
    assert_eq!(o.status.code(), Some(2));
    let o = with(&["--drive", "9", "--timeout-ms", "20", "status", "S1"]);
    assert_eq!(o.status.code(), Some(3), "{}", String::from_utf8_lossy(&o.stderr));
    let o = compax(p, &["--mode", "164", "scan"]);
    assert_eq!(o.status.code(), Some(2));
}

#[cfg(unix)]
#[test]
fn over_a_pty() {
    let sim = start_sim(&["--pty", "--drives", "3", "--baud", "38400"]);
    let p = sim.address.as_str();
    let s = json(&compax(p, &["--drive", "3", "--baud", "38400", "--json", "status", "S1"]));
    assert_eq!(s["drive"], 3);
    let m = json(&compax(p, &["--drive", "3", "--baud", "38400", "--json", "move", "--abs", "-0.75", "--binary"]));
    assert_eq!(m["position"], -0.75);
}

#[test]
fn decode_both_directions() {
    let o = Command::new(BIN)
        .args(["decode", "compax", "--mode", "8", "31 53 31 0D 53", "53 30 30 31 3A 20 30 2E 30 30 30 0D 0A 3E 56"])
        .output()
        .unwrap();
    assert!(o.status.success());
    let s = stdout(&o);
    assert!(s.contains("request to drive 1: S1 read actual position"), "{s}");
    assert!(s.contains("reply: S1 (actual position) = 0"), "{s}");
    let o = Command::new(BIN).args(["decode", "compax", "31 88 41 00 00 00 68 01 00"]).output().unwrap();
    assert!(stdout(&o).contains("binary POSA 360"), "{}", stdout(&o));
}

#[test]
fn demo_shows_the_manuals_example() {
    let o = Command::new(BIN).args(["demo", "compax"]).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let s = stdout(&o);
    assert!(s.contains("31 53 31 0D 53"), "1S1 with BCC 53: {s}");
    assert!(s.contains("35 53 31 0D 57"), "5S1 with BCC 57: {s}");
    assert!(s.contains("drive 5 reached 25"), "{s}");
}

#[test]
fn port_sim_in_process() {
    let s = json(&compax("sim", &["--drive", "4", "--baud", "115200", "--json", "move", "--rel", "0.5"]));
    assert_eq!(s["position"], 0.5);
}
