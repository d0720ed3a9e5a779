//! `stop` in every family, end to end: what it stops on the device and reads back, at rest and while a move
//! runs; and a stop from another terminal: the command that holds the port (a move over `tcp://`, as over a
//! serial line) is found through its lock file, asked to stop (SIGINT), and the port taken over; other
//! commands name the holder and exit 3; a lock file left by a dead process is taken over.
//!
//! Each test has a runtime directory of its own (`XDG_RUNTIME_DIR`), so that its lock files can be looked at.

use std::path::{Path, PathBuf};
use std::process::Output;
use std::time::Duration;

use serde_json::json;

use crate::common::{self, Running, Sim};

/// A runtime directory of this test's own, removed at the end.
struct Runtime(PathBuf);

impl Runtime {
    fn new(name: &str) -> Runtime {
        let dir = std::env::temp_dir().join(format!("motionlink-stop-test-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        Runtime(dir)
    }

    fn env(&self) -> [(&str, &str); 1] {
        [("XDG_RUNTIME_DIR", self.0.to_str().unwrap())]
    }

    /// The lock files in `$XDG_RUNTIME_DIR/motionlink`.
    fn locks(&self) -> Vec<PathBuf> {
        let dir = self.0.join("motionlink");
        let Ok(entries) = std::fs::read_dir(&dir) else { return Vec::new() };
        entries.map(|e| e.unwrap().path()).filter(|p| p.extension().is_some_and(|e| e == "lock")).collect()
    }

    /// Every file left in `$XDG_RUNTIME_DIR/motionlink`.
    fn leftovers(&self) -> Vec<PathBuf> {
        std::fs::read_dir(self.0.join("motionlink")).map(|d| d.map(|e| e.unwrap().path()).collect()).unwrap_or_default()
    }

    /// `motionlink <args>` to its end, in this runtime directory.
    fn run(&self, args: &[&str]) -> Output {
        common::run_with(args, &self.env(), "")
    }

    /// `motionlink <args>` in the background, in this runtime directory.
    fn start(&self, args: &[&str]) -> Running {
        Running::start_env(args, &self.env())
    }
}

impl Drop for Runtime {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

fn code(o: &Output) -> i32 {
    o.status.code().unwrap_or(-1)
}

fn json(o: &Output) -> serde_json::Value {
    assert_eq!(code(o), 0, "{o:?}");
    serde_json::from_str(text(&o.stdout).trim()).unwrap_or_else(|e| panic!("one JSON object ({e}): {o:?}"))
}

/// The one lock file there is, and the holder it names.
fn only_lock(rt: &Runtime) -> (PathBuf, serde_json::Value) {
    let locks = rt.locks();
    assert_eq!(locks.len(), 1, "{locks:?}");
    let named = serde_json::from_str(&std::fs::read_to_string(&locks[0]).unwrap()).unwrap();
    (locks[0].clone(), named)
}

fn wait_event(sim: &Sim, what: &str) -> common::Event {
    sim.wait_event(Duration::from_secs(10), |e| e.contains(what))
        .unwrap_or_else(|| panic!("no event {what:?}: {}", sim.stderr.text()))
}

/// SCU: no actuator of a `watch --count 1 --json` sample moves.
fn scu_at_rest(rt: &Runtime, port: &str) -> serde_json::Value {
    let sample = json(&rt.run(&["scu", "--port", port, "watch", "--count", "1", "--json"]));
    let actuators = sample["actuators"].as_array().unwrap();
    assert!(actuators.iter().all(|a| a["moving"] == false), "{sample}");
    sample
}

#[test]
fn scu_stop_from_another_terminal_stops_the_move_that_holds_the_port() {
    let rt = Runtime::new("scu-handover");
    let sim = Sim::tcp("scu");
    let p = sim.address.as_str();
    let mover = rt.start(&["scu", "--port", p, "move", "1", "800", "--speed", "20"]);
    wait_event(&sim, "F1 started");
    // The holder is findable: its pid, port, family and command.
    let (lock, named) = only_lock(&rt);
    assert_eq!(named["pid"], mover.pid());
    assert_eq!((named["port"].as_str(), named["command"].as_str()), (Some(p), Some("scu move 1 800 --speed 20")));
    // Any other command names it and the stop that stops it: exit 3.
    let got = rt.run(&["scu", "--port", p, "get", "actual_position_a1"]);
    assert_eq!(code(&got), 3, "{got:?}");
    let said = text(&got.stderr);
    let expected = format!(
        "{p} is in use by motionlink pid {} (scu move 1 800 --speed 20); `motionlink scu --port {p} stop` stops \
         its motion",
        mover.pid()
    );
    assert!(said.contains(&expected), "{said}");
    let e = common::json_error(&rt.run(&["scu", "--port", p, "get", "actual_position_a1", "--json"]));
    assert_eq!((e["kind"].as_str(), e["exit_code"].as_i64()), (Some("io"), Some(3)), "{e}");
    // The stop: the holder stops its move as on Ctrl-C, then this command stops and reads back.
    let stop = rt.run(&["scu", "--port", p, "stop"]);
    assert_eq!(code(&stop), 0, "{stop:?}");
    let out = text(&stop.stdout);
    let who =
        format!("stopped motionlink pid {} (scu move 1 800 --speed 20): it ended with exit code 130", mover.pid());
    assert!(out.contains(&who) && out.contains("A1 stopped at"), "{out}");
    assert!(out.contains("stopped F1..F10 (fast RS); at rest (status read back): A1 "), "{out}");
    let ended = mover.wait(Duration::from_secs(10));
    assert_eq!(ended.code(), 130, "{ended:?}");
    assert!(ended.stderr.contains("SIGINT from `motionlink scu stop`"), "{ended:?}");
    // On the unit: the holder's RS, then the stop's own RS to every motion function; nothing moves.
    let rs = sim.events().iter().filter(|e| e.text.starts_with("F1 stopped (RS fast)")).count();
    assert_eq!(rs, 2, "{}", sim.stderr.text());
    let sample = scu_at_rest(&rt, p);
    let a1 = sample["actuators"][0]["position_counts"].as_i64().unwrap();
    assert!(a1 < 800, "stopped on the way: {sample}");
    assert!(!lock.exists() && rt.leftovers().is_empty(), "{:?}", rt.leftovers());
}

#[test]
fn a_lock_file_left_by_a_dead_process_is_taken_over() {
    let rt = Runtime::new("stale");
    let sim = Sim::tcp("scu");
    let p = sim.address.as_str();
    // Where the port's lock file is: a command holding it shows it.
    let watch = rt.start(&["scu", "--port", p, "watch", "--interval-ms", "50"]);
    watch.stdout.wait_for(Duration::from_secs(10), |_| true).expect("a sample");
    let (lock, _) = only_lock(&rt);
    watch.signal(libc::SIGINT);
    assert_eq!(watch.wait(Duration::from_secs(10)).code(), 130);
    assert!(!lock.exists());
    // A holder killed outright leaves its file behind, naming a pid that no longer runs.
    let mut gone =
        std::process::Command::new(common::BIN).arg("--version").stdout(std::process::Stdio::null()).spawn().unwrap();
    let dead_pid = gone.id();
    gone.wait().unwrap();
    let stale = serde_json::json!({"pid": dead_pid, "port": p, "family": "scu", "command": "scu move 1 400"});
    std::fs::write(&lock, stale.to_string()).unwrap();
    let got = rt.run(&["scu", "--port", p, "get", "actual_position_a1"]);
    assert_eq!(code(&got), 0, "the stale file is no holder: {got:?}");
    assert!(!lock.exists(), "replaced, then removed when the command ended");
    // Replaced by the next holder, which names itself; a stop says who it stopped, in JSON too.
    std::fs::write(&lock, stale.to_string()).unwrap();
    let watch = rt.start(&["scu", "--port", p, "watch", "--interval-ms", "50"]);
    watch.stdout.wait_for(Duration::from_secs(10), |_| true).expect("a sample");
    assert_eq!(only_lock(&rt).1["pid"], watch.pid());
    let stop = json(&rt.run(&["scu", "--port", p, "stop", "--json"]));
    assert_eq!(stop["holder"]["pid"], watch.pid(), "{stop}");
    assert_eq!(stop["holder"]["command"], "scu watch --interval-ms 50", "{stop}");
    assert_eq!(stop["holder"]["outcome"]["exit_code"], 130, "{stop}");
    assert_eq!(watch.wait(Duration::from_secs(10)).code(), 130);
    assert!(rt.leftovers().is_empty(), "{:?}", rt.leftovers());
}

#[test]
fn scu_stop_without_a_holder_stops_every_motion_function_and_reads_back() {
    let rt = Runtime::new("scu-rest");
    let sim = Sim::tcp("scu");
    let p = sim.address.as_str();
    // At rest: RS to F1..F10 all the same, confirmed by the status.
    let stop = json(&rt.run(&["scu", "--port", p, "stop", "--json"]));
    let functions: Vec<i64> = stop["functions"].as_array().unwrap().iter().map(|f| f.as_i64().unwrap()).collect();
    assert_eq!(functions, (1..=10).collect::<Vec<_>>(), "{stop}");
    assert_eq!((&stop["mode"], &stop["stopped"], &stop["holder"]), (&"fast".into(), &true.into(), &json!(null)));
    assert_eq!(stop["at_rest"][0], json!({"actuator": 1, "position_counts": 0}), "{stop}");
    for f in 1..=10 {
        assert!(sim.events().iter().any(|e| e.text.starts_with(&format!("F{f} stopped (RS fast)"))), "F{f}");
    }
    // One function, softly; a switching function is switched off.
    let soft = json(&rt.run(&["scu", "--port", p, "stop", "F2", "--soft", "--json"]));
    assert_eq!((&soft["function"], &soft["functions"], &soft["mode"]), (&json!(2), &json!([2]), &json!("soft")));
    let out = rt.run(&["scu", "--port", p, "stop", "F17"]);
    assert!(text(&out.stdout).contains("F17") && text(&out.stdout).contains("switched off (RS)"), "{out:?}");
    assert!(code(&rt.run(&["scu", "--port", p, "stop", "F23"])) == 2, "a function that does not exist");
}

#[test]
fn powercube_stop_halts_a_move_run_from_another_terminal_and_halt_is_its_alias() {
    let rt = Runtime::new("powercube");
    let sim = Sim::tcp("powercube");
    let p = sim.address.as_str();
    // At rest: halted, confirmed by the state; `halt` is the same action.
    let stop = json(&rt.run(&["powercube", "--port", p, "stop", "--json"]));
    assert_eq!((&stop["action"], &stop["module"], &stop["holder"]), (&json!("halted"), &json!(1), &json!(null)));
    assert_eq!(stop["state"]["flags"], json!(["STATE_HALTED"]), "{stop}");
    let at = stop["position_rad"].as_f64().expect("the position read back");
    let halt = rt.run(&["powercube", "--port", p, "halt"]);
    let said = format!("module 1 halted: at rest (state read back) at {at:.4} rad; it takes no motion until reset");
    assert!(text(&halt.stdout).contains(&said), "{halt:?}");
    assert_eq!(code(&rt.run(&["powercube", "--port", p, "reset"])), 0);
    // A move in another terminal holds the port: stopped through it.
    let mover = rt.start(&["powercube", "--port", p, "move", "2.0", "--vel", "0.3", "--acc", "1"]);
    wait_event(&sim, "module 1 motion started");
    let stop = rt.run(&["powercube", "--port", p, "stop"]);
    assert_eq!(code(&stop), 0, "{stop:?}");
    let out = text(&stop.stdout);
    let who = format!(
        "stopped motionlink pid {} (powercube move 2.0 --vel 0.3 --acc 1): it ended with exit code 130",
        mover.pid()
    );
    assert!(out.contains(&who) && out.contains("module 1 halted: at rest (state read back)"), "{out}");
    assert_eq!(mover.wait(Duration::from_secs(10)).code(), 130);
    let state = json(&rt.run(&["powercube", "--port", p, "state", "--json"]));
    assert!(state["flags"].as_array().unwrap().iter().all(|f| f != "STATE_MOTION"), "{state}");
    assert_eq!(code(&rt.run(&["powercube", "--port", p, "reset"])), 0);
    // A module left moving by a killed command (no watchdog): no holder; the stop halts it.
    let mut killed =
        rt.start(&["powercube", "--port", p, "--no-watchdog", "move", "-2.0", "--vel", "0.3", "--acc", "1"]);
    let started = wait_event(&sim, "motion started: ramp to -2");
    killed.kill();
    killed.wait(Duration::from_secs(5));
    let moving = json(&rt.run(&["powercube", "--port", p, "state", "--json"]));
    assert!(moving["flags"].as_array().unwrap().iter().any(|f| f == "STATE_MOTION"), "left moving: {moving}");
    let stop = json(&rt.run(&["powercube", "--port", p, "stop", "--json"]));
    assert_eq!((&stop["holder"], &stop["state"]["flags"]), (&json!(null), &json!(["STATE_HALTED"])), "{stop}");
    assert!(sim.wait_event_after(started.at, Duration::from_secs(5), |e| e == "module 1 halted").is_some());
    assert!(!sim.events().iter().any(|e| e.text.starts_with("module 1 at rest -2")), "halted on its way");
    assert!(rt.leftovers().is_empty(), "{:?}", rt.leftovers());
}

#[test]
fn compax_stop_switches_off_only_a_drive_that_moves_and_says_how_to_switch_it_on() {
    let rt = Runtime::new("compax");
    let sim = Sim::tcp("compax");
    let p = sim.address.as_str();
    // At rest: nothing is switched off; S17, S1 and S16 read back.
    let stop = json(&rt.run(&["compax", "--port", p, "stop", "--json"]));
    assert_eq!(stop["drives"], json!([{"drive": 1, "outcome": "at_rest"}]), "{stop}");
    assert_eq!((&stop["confirmed"], &stop["o0"], &stop["position_units"]), (&json!(true), &json!(1), &json!(0.0)));
    assert!(!sim.events().iter().any(|e| e.text.contains("switched off")));
    // A move handed over by a command that has ended: stopped by switching the drive off.
    let moved = rt.run(&["compax", "--port", p, "move", "--abs", "500", "--speed", "10", "--no-wait"]);
    assert_eq!(code(&moved), 0, "{moved:?}");
    let stop = rt.run(&["compax", "--port", p, "stop"]);
    assert_eq!(code(&stop), 0, "{stop:?}");
    let out = text(&stop.stdout);
    assert!(out.contains("drive 1 was stopped by switching it off (OUTPUT O0=0, confirmed by the drive)"), "{out}");
    assert!(out.contains("(S17 and S1 read back)"), "{out}");
    assert!(
        out.contains(&format!("to switch it on again: motionlink compax --port {p} --drive 1 output 0 1")),
        "{out}"
    );
    wait_event(&sim, "drive 1 switched off (O0=0)");
    assert_eq!(code(&rt.run(&["compax", "--port", p, "output", "0", "1"])), 0);
    // A move waited for in another terminal: that command stops it (SIGINT), then this one reads back.
    let mover = rt.start(&["compax", "--port", p, "move", "--abs", "900", "--speed", "10"]);
    wait_event(&sim, "drive 1 motion started to 900");
    let stop = json(&rt.run(&["compax", "--port", p, "stop", "--json"]));
    assert_eq!(stop["holder"]["pid"], mover.pid(), "{stop}");
    assert_eq!(stop["holder"]["outcome"]["exit_code"], 130, "{stop}");
    let said = stop["holder"]["outcome"]["message"].as_str().unwrap();
    assert!(said.contains("drive 1 was stopped by switching it off"), "{said}");
    assert_eq!((&stop["drives"][0]["outcome"], &stop["o0"]), (&json!("at_rest"), &json!(0)), "{stop}");
    assert_eq!(mover.wait(Duration::from_secs(10)).code(), 130);
    assert!(rt.leftovers().is_empty(), "{:?}", rt.leftovers());
}

#[test]
fn a_console_holds_its_port_like_any_command() {
    let rt = Runtime::new("console");
    let sim = Sim::tcp("scu");
    let p = sim.address.as_str();
    let console = rt.start(&["console", "scu", "--port", p]);
    console.stdout.wait_for(Duration::from_secs(10), |l| l.starts_with("console on")).expect("the console's line");
    let got = rt.run(&["scu", "--port", p, "info"]);
    assert_eq!(code(&got), 3, "{got:?}");
    assert!(text(&got.stderr).contains(&format!("(console scu); `motionlink scu --port {p} stop`")), "{got:?}");
    let stop = rt.run(&["scu", "--port", p, "stop"]);
    assert_eq!(code(&stop), 0, "{stop:?}");
    assert_eq!(console.wait(Duration::from_secs(10)).code(), 130);
    assert!(rt.leftovers().is_empty(), "{:?}", rt.leftovers());
}

/// The in-process emulator is no port another process could want: no lock file.
#[test]
fn in_process_ports_take_no_lock() {
    let rt = Runtime::new("sim");
    let out = rt.run(&["scu", "--port", "sim", "stop"]);
    assert_eq!(code(&out), 0, "{out:?}");
    assert!(rt.locks().is_empty() && !Path::new(&rt.0.join("motionlink")).exists());
}
