//! `motionlink compax` end to end: the built binary against `motionlink sim compax` over TCP and a pty.

use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

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
    let sim =
        start_sim(&["--tcp", "127.0.0.1:0", "--drives", "1,5", "--mode", "72", "--baud", "115200", "--param", "P12=0"]);
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
    // A parameter the emulator does not model is refused (E90), not read as 0.
    let o = with(&["--drive", "5", "get", "P13"]);
    assert_eq!(o.status.code(), Some(1), "{}\n{}", stdout(&o), String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stderr).contains("E90"), "{}", String::from_utf8_lossy(&o.stderr));

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

/// `status S1 S16 S17` of `drive` as JSON values: (position, S16 bits, S17 bits) with bit 1 first.
fn state(port: &str, drive: &str) -> (f64, String, String) {
    let st = json(&compax(port, &["--drive", drive, "--json", "status", "S1", "S16", "S17"]));
    let bits = |i: usize| st["status"][i]["value"]["bits"].as_str().unwrap().replace(' ', "");
    (st["status"][0]["value"].as_f64().unwrap(), bits(1), bits(2))
}

/// Bit `n` (1..=8, bit 1 first as transmitted) of a bit word as `state` returns it.
fn bit(bits: &str, n: usize) -> bool {
    bits.as_bytes()[n - 1] == b'1'
}

const COMMAND_ACTIVE: usize = 3; // S17
const SWITCHED_ON: usize = 7; // S16: O0 = 1
const IDLE_AFTER_STOP: usize = 6; // S16

#[test]
fn move_no_wait_hands_the_move_over() {
    let sim = start_sim(&["--tcp", "127.0.0.1:0"]);
    let p = sim.address.as_str();
    // SPEED 10: 10 units/s, 100 s for 1000 units.
    let m = json(&compax(p, &["--json", "move", "--abs", "1000", "--speed", "10", "--no-wait"]));
    assert_eq!(m["waited"], false);
    let p0 = m["position"].as_f64().unwrap();
    assert!(p0 < 1000.0, "{m}");
    // Later invocations find the axis still moving: the first one's exit did not stop it.
    let mut last = p0;
    for _ in 0..2 {
        std::thread::sleep(Duration::from_millis(300));
        let (p1, s16, s17) = state(p, "1");
        assert!(p1 > last && p1 < 1000.0, "moved on from {last} to {p1}");
        assert!(bit(&s17, COMMAND_ACTIVE), "S17 {s17}");
        assert!(bit(&s16, SWITCHED_ON), "not switched off: S16 {s16}");
        last = p1;
    }
    // A move sent raw is left running too.
    let sim = start_sim(&["--tcp", "127.0.0.1:0", "--drives", "3"]);
    let o = compax(&sim.address, &["--drive", "3", "raw", "POSA 1000"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    std::thread::sleep(Duration::from_millis(200));
    let (p3, s16, s17) = state(&sim.address, "3");
    assert!(p3 > 0.0 && bit(&s17, COMMAND_ACTIVE) && bit(&s16, SWITCHED_ON), "{p3} S16 {s16} S17 {s17}");
    // --no-wait with --timeout-s is a contradiction.
    assert_eq!(compax(p, &["move", "--abs", "1", "--no-wait", "--timeout-s", "5"]).status.code(), Some(2));
}

/// `motionlink -vvv compax --port PORT ARGS...` with its stderr read line by line: returns once a line
/// contains `marker` (the telegram log shows the action is under way, and the Ctrl-C handler installed).
struct Traced {
    child: std::process::Child,
    lines: std::sync::mpsc::Receiver<String>,
    seen: String,
}

impl Traced {
    fn start(port: &str, args: &[&str], marker: &str) -> Traced {
        use std::io::BufRead;
        let mut child = Command::new(BIN)
            .args(["-vvv", "compax", "--port", port])
            .args(args)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let stderr = child.stderr.take().unwrap();
        let (tx, lines) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            for line in std::io::BufReader::new(stderr).lines().map_while(Result::ok) {
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        let mut t = Traced { child, lines, seen: String::new() };
        let deadline = Instant::now() + Duration::from_secs(30);
        while !t.seen.contains(marker) {
            let left = deadline.saturating_duration_since(Instant::now());
            let line = t.lines.recv_timeout(left).unwrap_or_else(|_| panic!("no {marker:?} in {}", t.seen));
            t.seen.push_str(&line);
            t.seen.push('\n');
        }
        t
    }

    /// Sends SIGINT (Ctrl-C); returns the exit code and everything on stderr.
    fn interrupt(mut self) -> (Option<i32>, String) {
        let status = Command::new("kill").args(["-INT", &self.child.id().to_string()]).status().unwrap();
        assert!(status.success());
        let code = self.child.wait().unwrap().code();
        self.seen.extend(self.lines.iter().map(|l| l + "\n"));
        (code, self.seen)
    }
}

#[test]
fn ctrl_c_stops_a_move() {
    let sim = start_sim(&["--tcp", "127.0.0.1:0", "--drives", "2"]);
    let port = sim.address.clone();
    // 1000 units at 10 units/s: 100 s, interrupted a moment after the move went out.
    let moving = Traced::start(&port, &["--drive", "2", "move", "--abs", "1000", "--speed", "10"], "send \"2POSA 1000");
    std::thread::sleep(Duration::from_millis(300));
    let (code, err) = moving.interrupt();
    assert_eq!(code, Some(130), "Ctrl-C exits with 130 after stopping: {err}");
    assert!(err.contains("cancelled") && err.contains("2OUTPUT O0=0"), "{err}");
    let (p1, s16, s17) = state(&port, "2");
    assert!(p1 > 0.0 && p1 < 100.0, "{p1}");
    assert!(!bit(&s17, COMMAND_ACTIVE), "stopped: S17 {s17}");
    assert!(!bit(&s16, SWITCHED_ON) && bit(&s16, IDLE_AFTER_STOP), "switched off by OUTPUT O0=0: S16 {s16}");
    std::thread::sleep(Duration::from_millis(300));
    assert_eq!(state(&port, "2").0, p1, "and stays where it stopped");
}

#[test]
fn ctrl_c_ends_a_scan_between_drives() {
    let sim = start_sim(&["--tcp", "127.0.0.1:0", "--drives", "31"]);
    // 30 empty addresses at 300 ms each: about 10 s without Ctrl-C.
    let scanning = Traced::start(&sim.address, &["--timeout-ms", "300", "scan"], "send \"3S1");
    let t0 = Instant::now();
    let (code, err) = scanning.interrupt();
    assert_eq!(code, Some(130), "{err}");
    assert!(t0.elapsed() < Duration::from_secs(3), "ended at the next address, after {:?}", t0.elapsed());
    assert!(!err.contains("send \"6S1"), "{err}");
}

#[test]
fn move_arguments_are_checked_before_anything_is_sent() {
    let sim = start_sim(&["--tcp", "127.0.0.1:0"]);
    let p = sim.address.as_str();
    for args in [
        &["--abs", "10", "--timeout-s", "-1"][..],
        &["--abs", "10", "--timeout-s", "0"],
        &["--abs", "10", "--timeout-s", "NaN"],
        &["--abs", "10", "--timeout-s", "1e30"],
        &["--abs", "1e9", "--speed", "50"],
        &["--rel", "-1e9", "--accel", "100"],
        &["--abs", "10", "--speed", "0"],
        &["--abs", "10", "--speed", "50", "--accel", "40000"],
    ] {
        let mut v = vec!["move"];
        v.extend_from_slice(args);
        let o = compax(p, &v);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(!err.is_empty());
    }
    // Nothing moved, nothing was switched off.
    let (p1, s16, s17) = state(p, "1");
    assert_eq!(p1, 0.0);
    assert!(!bit(&s17, COMMAND_ACTIVE) && bit(&s16, SWITCHED_ON), "S16 {s16} S17 {s17}");
}

#[test]
fn sim_config_file() {
    let path = std::env::temp_dir().join(format!("motionlink-compax-sim-{}.toml", std::process::id()));
    std::fs::write(
        &path,
        "baud_rate = 19200\np196 = 8\n\n[[drive]]\naddress = 1\n\n[[drive]]\naddress = 5\nposition = 12.5\np196 = 72\n\n\
         [[drive]]\naddress = 9\nbaud_rate = 9600\n",
    )
    .unwrap();
    let sim = start_sim(&["--tcp", "127.0.0.1:0", "--config", path.to_str().unwrap()]);
    let p = sim.address.as_str();
    let at = |mode: &str, drive: &str| {
        let s = json(&compax(p, &["--baud", "19200", "--mode", mode, "--drive", drive, "--json", "status", "S1"]));
        s["status"][0]["value"].as_f64().unwrap()
    };
    assert_eq!(at("8", "1"), 0.0);
    // Drive 5 has its own mode (BCC and the address in front of each reply) and position.
    assert_eq!(at("72", "5"), 12.5);
    let g = json(&compax(p, &["--baud", "19200", "--mode", "72", "--drive", "5", "--json", "get", "P196"]));
    assert_eq!(g["value"], 72.0);
    let g = json(&compax(p, &["--baud", "19200", "--mode", "8", "--json", "get", "P195"]));
    assert_eq!(g["value"], 19200.0);
    // Drive 9 listens at another baud rate than the line: it hears only noise.
    let o = compax(p, &["--baud", "19200", "--mode", "8", "--drive", "9", "--timeout-ms", "30", "status", "S1"]);
    assert_eq!(o.status.code(), Some(3));
    drop(sim);

    // A bad file is a usage error, named.
    std::fs::write(&path, "[[drive]]\naddress = 32\n").unwrap();
    let o = Command::new(BIN)
        .args(["sim", "compax", "--tcp", "127.0.0.1:0", "--config", path.to_str().unwrap()])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("address 32"), "{}", String::from_utf8_lossy(&o.stderr));
    let _ = std::fs::remove_file(&path);
}
