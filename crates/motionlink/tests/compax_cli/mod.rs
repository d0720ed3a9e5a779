//! `motionlink compax` end to end: the built binary against `motionlink sim compax` over TCP and a pty.

mod conventions;
mod variants;

use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use crate::common;

use common::{Event, Running, Sim, BIN};

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
    let scan = stdout(&with(&["--timeout-ms", "30", "--json", "scan"]));
    // One object per drive found (JSON Lines).
    let found: Vec<u64> = scan
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap()["drive"].as_u64().unwrap())
        .collect();
    assert_eq!(found, [1, 5]);

    let st = json(&with(&["--drive", "5", "--json", "status", "S1", "S17"]));
    assert_eq!(st["status"][0]["value"], 0.0);
    let s17 = &st["status"][1]["value"];
    assert_eq!(
        (&s17["pattern"], &s17["word"], &s17["flags"][0]),
        (&"0000 0010".into(), &2.into(), &"RUN".into()),
        "{st}"
    );

    let o = with(&["--drive", "5", "set", "P12", "-3.5"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let g = json(&with(&["--drive", "5", "--json", "get", "P12"]));
    assert_eq!(g["value"], -3.5);
    // A parameter the emulator does not model is refused (E90), not read as 0.
    let o = with(&["--drive", "5", "get", "P13"]);
    assert_eq!(o.status.code(), Some(1), "{}\n{}", stdout(&o), String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stderr).contains("E90"), "{}", String::from_utf8_lossy(&o.stderr));

    let m = json(&with(&["--drive", "5", "--json", "move", "--abs", "1.5", "--speed", "100", "--accel", "10"]));
    assert_eq!(m["reached_units"], 1.5);
    let m = json(&with(&["--drive", "5", "--json", "move", "--rel", "-0.5", "--binary"]));
    assert_eq!(m["reached_units"], 1.0);
    // A binary move takes no echo: nothing was checked before it started, and the result says so.
    assert_eq!(m["verified"], false, "{m}");
    let why = m["not_verifiable"][0].as_str().unwrap_or_default();
    assert!(why.contains("binary") && why.contains("without being checked before it started"), "{m}");

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
    assert_eq!(m["reached_units"], -0.75);
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
    assert_eq!(s["reached_units"], 0.5);
}

/// `status S1 S16 S17` of `drive` as JSON values: (position, S16 bits, S17 bits) with bit 1 first.
fn state(port: &str, drive: &str) -> (f64, String, String) {
    let st = json(&compax(port, &["--drive", drive, "--json", "status", "S1", "S16", "S17"]));
    let bits = |i: usize| st["status"][i]["value"]["pattern"].as_str().unwrap().replace(' ', "");
    (st["status"][0]["value"].as_f64().unwrap(), bits(1), bits(2))
}

/// Bit `n` (1..=8, bit 1 first as transmitted) of a bit word as `state` returns it.
fn bit(bits: &str, n: usize) -> bool {
    bits.as_bytes()[n - 1] == b'1'
}

const COMMAND_ACTIVE: usize = 3; // S17
const SWITCHED_ON: usize = 7; // S16: O0 = 1
const IDLE_AFTER_STOP: usize = 6; // S16

/// `motionlink compax --port PORT ARGS...` running in the background.
fn compax_running(port: &str, args: &[&str]) -> Running {
    let mut v = vec!["compax", "--port", port];
    v.extend_from_slice(args);
    Running::start(&v)
}

const TEN_S: Duration = Duration::from_secs(10);

/// Waits for the emulator's "drive N motion started" event.
fn wait_started(sim: &Sim, drive: u8) -> Event {
    let prefix = format!("drive {drive} motion started");
    sim.wait_event(TEN_S, |t| t.starts_with(&prefix))
        .unwrap_or_else(|| panic!("no {prefix:?} event: {}", sim.stderr.text()))
}

/// Waits for the emulator's "drive N at rest" event after `after`; returns it and the position.
fn wait_at_rest(sim: &Sim, drive: u8, after: f64) -> (Event, f64) {
    let prefix = format!("drive {drive} at rest ");
    let ev = sim
        .wait_event_after(after, TEN_S, |t| t.starts_with(&prefix))
        .unwrap_or_else(|| panic!("no {prefix:?} event after {after}: {}", sim.stderr.text()));
    let p = ev.text[prefix.len()..].parse().unwrap();
    (ev, p)
}

#[test]
fn move_no_wait_hands_the_move_over() {
    let sim = start_sim(&["--tcp", "127.0.0.1:0"]);
    let p = sim.address.as_str();
    // SPEED 50: 50 units/s, 0.6 s for 30 units.
    let m = json(&compax(p, &["--json", "move", "--abs", "30", "--speed", "50", "--no-wait"]));
    assert_eq!(m["waited"], false);
    assert_eq!(m["target_units"], 30.0);
    let exited = common::unix_now();
    assert!(m["position_units"].as_f64().unwrap() < 30.0, "{m}");
    // The command has exited; the drive goes on to its target, and nobody switched it off.
    let (_, at) = wait_at_rest(&sim, 1, exited);
    assert_eq!(at, 30.0);
    assert!(!sim.events().iter().any(|e| e.text.contains("switched off")), "{}", sim.stderr.text());
    let (p1, s16, s17) = state(p, "1");
    assert!(p1 == 30.0 && !bit(&s17, COMMAND_ACTIVE) && bit(&s16, SWITCHED_ON), "{p1} S16 {s16} S17 {s17}");
    // A move sent raw is left running too.
    let sim = start_sim(&["--tcp", "127.0.0.1:0", "--drives", "3"]);
    let o = compax(&sim.address, &["--drive", "3", "raw", "POSA 20"]);
    let said = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{said}");
    // It says so, and how to stop it.
    assert!(said.contains("drive 3 moving on: handed over, not stopped by this command"), "{said}");
    // A command that runs as given: on the same port.
    assert!(said.contains(&format!("`motionlink compax --port {} --drive 3 stop` stops it", sim.address)), "{said}");
    let (_, at) = wait_at_rest(&sim, 3, common::unix_now() - 10.0);
    assert_eq!(at, 20.0);
    // With --json, the drives it set in motion.
    let r = json(&compax(&sim.address, &["--json", "--drive", "3", "raw", "POSA 25"]));
    assert_eq!((&r["started"], &r["waited"]), (&serde_json::json!([3]), &serde_json::json!(false)), "{r}");
    wait_at_rest(&sim, 3, common::unix_now() - 10.0);
    // --no-wait with --timeout-s is a contradiction.
    assert_eq!(compax(p, &["move", "--abs", "1", "--no-wait", "--timeout-s", "5"]).status.code(), Some(2));
    // So are the options of the wait it does not do (they would be taken and ignored).
    for waits in [["--tolerance", "3"], ["--poll-ms", "5"]] {
        let out = compax(p, &["move", "--abs", "1", "--no-wait", waits[0], waits[1]]);
        assert_eq!(out.status.code(), Some(2), "{waits:?}");
        assert!(String::from_utf8_lossy(&out.stderr).contains(waits[0]), "{waits:?}");
    }
}

/// A signal during a move: the emulated axis is at rest within 100 ms of the signal, switched off; the
/// command exits with 128 + the signal's number and says the drive is off and how to switch it on. With
/// `polls`, the signal comes after that many status polls of the wait (between two polls, 50 ms apart),
/// otherwise as soon as the emulator reports the motion started.
fn a_signal_stops_a_move(sim: &Sim, drive: u8, baud: &str, sig: i32, polls: Option<usize>) {
    let d = drive.to_string();
    let port = sim.address.as_str();
    // 1000 units at 10 units/s: 100 s unless stopped.
    let run = Running::start(&[
        "-vvv", "compax", "--port", port, "--drive", &d, "--baud", baud, "move", "--abs", "1000", "--speed", "10",
    ]);
    let started = wait_started(sim, drive);
    if let Some(n) = polls {
        // Each poll reads S17 then S1; the S17 before the move makes one more.
        let s17 = format!("send \"{drive}S17<CR>\"");
        run.stderr.wait_for_nth(TEN_S, n + 1, |l| l.contains(&s17)).expect("polls");
    }
    let at = run.signal(sig);
    let (rest, p) = wait_at_rest(sim, drive, at);
    let ended = run.wait(TEN_S);
    eprintln!("signal {sig}: drive {drive} at rest {:.1} ms after the signal", (rest.at - at) * 1e3);
    assert!(rest.at - at < 0.100, "signal {sig}: at rest {:.1} ms after the signal", (rest.at - at) * 1e3);
    assert!(rest.at >= started.at && (0.0..1000.0).contains(&p), "{p}");
    assert_eq!(ended.code(), 128 + sig, "{}", ended.stderr);
    let err = &ended.stderr;
    assert!(err.contains("drive was stopped") || err.contains(&format!("drive {drive} was stopped")), "{err}");
    assert!(err.contains("now switched off"), "{err}");
    if sig == libc::SIGTSTP {
        assert!(err.contains("SIGTSTP (Ctrl-Z) received: this command is not suspended"), "{err}");
    }
    assert!(err.contains(&format!("--drive {drive} output 0 1")), "how to switch it on: {err}");
    assert!(sim.events().iter().any(|e| e.text == format!("drive {drive} switched off (O0=0)")));
}

#[cfg(unix)]
#[test]
fn every_signal_stops_a_move_within_100_ms_over_tcp() {
    // SIGTSTP (Ctrl-Z) too: suspended, the command would leave the drive moving unwatched (COMPAX has no
    // host watchdog), so it stops the drive and ends instead.
    for (sig, polls) in [
        (libc::SIGINT, None),
        (libc::SIGTERM, Some(3)),
        (libc::SIGHUP, Some(2)),
        (libc::SIGQUIT, Some(5)),
        (libc::SIGTSTP, Some(4)),
    ] {
        let sim = start_sim(&["--tcp", "127.0.0.1:0", "--drives", "2"]);
        a_signal_stops_a_move(&sim, 2, "9600", sig, polls);
        let (p1, s16, s17) = state(&sim.address, "2");
        assert!(!bit(&s17, COMMAND_ACTIVE), "stopped: S17 {s17}");
        assert!(!bit(&s16, SWITCHED_ON) && bit(&s16, IDLE_AFTER_STOP), "switched off by OUTPUT O0=0: S16 {s16}");
        // It stays where it stopped: no motion event since.
        let again = state(&sim.address, "2").0;
        assert_eq!(again, p1);
    }
}

/// Ctrl-C during a move on a line that went silent: the stop (OUTPUT O0=0) is not confirmed, so the command
/// says the axis may still be moving and exits 3 (a transport error), not 130 (which promises a confirmed
/// stop). COMPAX has no host watchdog: nothing is said of one.
#[cfg(unix)]
#[test]
fn ctrl_c_whose_stop_the_drive_does_not_confirm_exits_3_not_130() {
    let sim = start_sim(&["--tcp", "127.0.0.1:0"]);
    let run = Running::start(&["--json", "compax", "--port", &sim.address, "move", "--abs", "1000", "--speed", "10"]);
    wait_started(&sim, 1);
    let frozen = sim.freeze();
    run.signal(libc::SIGINT);
    let ended = run.wait(TEN_S);
    drop(frozen);
    assert_eq!(ended.code(), 3, "{ended:?}");
    let said = &ended.stderr;
    assert!(said.contains("NOT confirmed") && said.contains("may still be moving"), "{said}");
    assert!(!said.contains("watchdog") && !said.contains("was stopped"), "{said}");
    // The close tried the stop again: said once, not the whole message a second time.
    assert_eq!(said.matches("NOT confirmed").count(), 1, "{said}");
    assert!(said.contains("the end of the session tried the stop again: drive 1 not confirmed either"), "{said}");
    // The error says so as data too.
    let e = ended.json_error();
    assert_eq!((&e["stop_unconfirmed"], &e["exit_code"]), (&serde_json::json!(true), &serde_json::json!(3)), "{e}");
}

#[cfg(unix)]
#[test]
fn a_signal_stops_a_move_over_a_pty() {
    let sim = start_sim(&["--pty", "--drives", "4", "--baud", "38400"]);
    a_signal_stops_a_move(&sim, 4, "38400", libc::SIGTERM, Some(2));
}

#[cfg(unix)]
#[test]
fn raw_wait_is_stopped_by_a_signal_too() {
    let sim = start_sim(&["--tcp", "127.0.0.1:0"]);
    let run = compax_running(&sim.address, &["raw", "POSA 1000", "--wait"]);
    wait_started(&sim, 1);
    let at = run.signal(libc::SIGHUP);
    let (rest, _) = wait_at_rest(&sim, 1, at);
    assert!(rest.at - at < 0.100, "{:.1} ms", (rest.at - at) * 1e3);
    let ended = run.wait(TEN_S);
    assert_eq!(ended.code(), 129, "{}", ended.stderr);
    // Without a signal, raw --wait waits for the end of the move.
    let o = compax(&sim.address, &["output", "0", "1"]);
    assert!(o.status.success());
    let r = json(&compax(&sim.address, &["--json", "raw", "POSA 5", "--wait"]));
    assert_eq!(r["waited"], true);
    assert_eq!(state(&sim.address, "1").0, 5.0);
}

#[cfg(unix)]
#[test]
fn a_closed_stdout_stops_a_move() {
    let sim = start_sim(&["--tcp", "127.0.0.1:0"]);
    let mut child = Command::new(BIN)
        .args(["compax", "--port", &sim.address, "move", "--abs", "1000", "--speed", "10"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    wait_started(&sim, 1);
    let at = common::unix_now();
    drop(child.stdout.take()); // the reader goes away (`motionlink ... | head` ending)
    let (rest, _) = wait_at_rest(&sim, 1, at);
    assert!(rest.at - at < 0.100, "{:.1} ms", (rest.at - at) * 1e3);
    let out = child.wait_with_output().unwrap();
    // Stopped, then quietly 0, as for any closed pipe: no warnings, no notes.
    assert_eq!(out.status.code(), Some(0), "a closed pipe ends with 0: {}", String::from_utf8_lossy(&out.stderr));
    assert!(out.stderr.is_empty(), "a closed pipe ends quietly: {}", String::from_utf8_lossy(&out.stderr));
}

/// With `-q` a signal during a move prints only the error: not the note that the signal was received, not
/// the hint how to switch the drive on again.
#[cfg(unix)]
#[test]
fn quiet_prints_only_the_error_of_a_stopped_move() {
    let sim = start_sim(&["--tcp", "127.0.0.1:0"]);
    let run = Running::start(&["-q", "compax", "--port", &sim.address, "move", "--abs", "1000", "--speed", "10"]);
    wait_started(&sim, 1);
    run.signal(libc::SIGINT);
    let ended = run.wait(TEN_S);
    assert_eq!(ended.code(), 130, "{}", ended.stderr);
    let err = &ended.stderr;
    assert!(err.contains("SIGINT received") && err.contains("switched off"), "the error itself: {err}");
    assert!(!err.contains("stopping what this command started"), "a note: {err}");
    assert!(!err.contains("output 0 1"), "the switch-on hint is a note: {err}");
    assert_eq!(err.lines().count(), 1, "{err}");
}

#[cfg(unix)]
#[test]
fn a_killed_command_leaves_the_axis_running_as_the_readme_says() {
    // SIGKILL cannot be caught, and COMPAX has no host watchdog: nothing stops the axis. The README says so.
    let sim = start_sim(&["--tcp", "127.0.0.1:0"]);
    let mut run = compax_running(&sim.address, &["move", "--abs", "40", "--speed", "100"]);
    wait_started(&sim, 1);
    let at = run.kill();
    let (_, p) = wait_at_rest(&sim, 1, at);
    assert_eq!(p, 40.0, "the positioning ran to its end");
    assert!(!sim.events().iter().any(|e| e.text.contains("switched off")));
}

#[cfg(unix)]
#[test]
fn a_dead_link_during_a_move_says_the_axis_may_still_be_moving() {
    let sim = start_sim(&["--tcp", "127.0.0.1:0"]);
    let run = compax_running(&sim.address, &["move", "--abs", "1000", "--speed", "10"]);
    wait_started(&sim, 1);
    drop(sim); // killed: the serial gateway goes away with the drive still moving
    let ended = run.wait(TEN_S);
    assert_eq!(ended.code(), 3, "{}", ended.stderr);
    assert!(ended.stderr.contains("NOT confirmed") && ended.stderr.contains("may still be moving"), "{}", ended.stderr);
}

#[test]
fn a_move_on_a_switched_off_drive_says_so_and_how_to_switch_it_on() {
    let sim = start_sim(&["--tcp", "127.0.0.1:0", "--drives", "6"]);
    let p = sim.address.as_str();
    assert!(compax(p, &["--drive", "6", "output", "0", "0"]).status.success());
    let o = compax(p, &["--drive", "6", "move", "--abs", "10"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("drive 6 is switched off") && !err.contains("E90"), "{err}");
    assert!(err.contains(&format!("motionlink compax --port {p} --drive 6 output 0 1")), "{err}");
    assert!(!sim.events().iter().any(|e| e.text.contains("motion started") || e.text.contains("E90")));
    // Sent raw, the drive's E90 comes with the same explanation.
    let o = compax(p, &["--drive", "6", "raw", "POSA 10"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("switched off") && err.contains("refused the move with E90") && err.contains("output 0 1"));
    // Switched on as the message says, it moves.
    assert!(compax(p, &["--drive", "6", "output", "0", "1"]).status.success());
    let m = json(&compax(p, &["--drive", "6", "--json", "move", "--abs", "10"]));
    assert_eq!(m["reached_units"], 10.0);
}

#[test]
fn limits_and_tolerance_of_a_move() {
    let sim = start_sim(&["--tcp", "127.0.0.1:0"]);
    let p = sim.address.as_str();
    let o = compax(p, &["move", "--abs", "50", "--min-pos", "-10", "--max-pos", "40"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("target 50 is outside the travel limits: it is above the maximum 40"), "{err}");
    let o = compax(p, &["move", "--rel", "-11", "--min-pos", "-10"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("below the minimum -10"));
    assert!(!sim.events().iter().any(|e| e.text.contains("motion started")), "nothing moved");
    let m = json(&compax(p, &["--json", "move", "--abs", "40", "--max-pos", "40", "--tolerance", "0.5"]));
    assert_eq!(
        (m["reached_units"].as_f64(), m["difference_units"].as_f64(), m["tolerance_units"].as_f64()),
        (Some(40.0), Some(0.0), Some(0.5))
    );
}

#[test]
fn set_reads_the_value_back_and_the_readme_example_works() {
    let sim = start_sim(&["--tcp", "127.0.0.1:0", "--drives", "5"]);
    let p = sim.address.as_str();
    let o = compax(p, &["--drive", "5", "set", "P003", "-1055.88"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(stdout(&o), "P003 = -1055.88, read back\n");
    assert_eq!(json(&compax(p, &["--drive", "5", "--json", "get", "P003"]))["value"], -1055.88);
}

#[cfg(unix)]
#[test]
fn watch_prints_until_interrupted() {
    let sim = start_sim(&["--tcp", "127.0.0.1:0"]);
    let run = compax_running(&sim.address, &["watch", "--interval-ms", "20"]);
    run.stdout.wait_for(TEN_S, |l| l.contains("S1 = 0")).expect("a first line");
    run.signal(libc::SIGINT);
    let ended = run.wait(TEN_S);
    assert_eq!(ended.code(), 130, "{}", ended.stderr);
    assert!(ended.stdout.lines().all(|l| l == "drive 1  S1 = 0 units  at rest"), "{}", ended.stdout);
    // Its reader gone, it ends quietly.
    let mut child = Command::new(BIN)
        .args(["compax", "--port", &sim.address, "watch", "--interval-ms", "10"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut first = String::new();
    std::io::BufRead::read_line(&mut std::io::BufReader::new(child.stdout.as_mut().unwrap()), &mut first).unwrap();
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
}

#[cfg(unix)]
#[test]
fn ctrl_c_ends_a_scan_between_drives() {
    let sim = start_sim(&["--tcp", "127.0.0.1:0", "--drives", "31"]);
    // 30 empty addresses at 300 ms each: about 10 s without Ctrl-C.
    let scanning = Running::start(&["-vvv", "compax", "--port", &sim.address, "--timeout-ms", "300", "scan"]);
    scanning.stderr.wait_for(TEN_S, |l| l.contains("send \"3S1")).expect("the scan under way");
    let t0 = Instant::now();
    scanning.signal(libc::SIGINT);
    let ended = scanning.wait(TEN_S);
    assert_eq!(ended.code(), 130, "{}", ended.stderr);
    assert!(t0.elapsed() < Duration::from_secs(3), "ended at the next address, after {:?}", t0.elapsed());
    assert!(!ended.stderr.contains("send \"6S1"), "{}", ended.stderr);
}

#[test]
fn bad_arguments_are_refused_naming_them_before_anything_is_sent() {
    let sim = start_sim(&["--tcp", "127.0.0.1:0"]);
    let p = sim.address.as_str();
    for (args, names) in [
        (&["move", "--abs", "10", "--timeout-s", "-1"][..], "--timeout-s"),
        (&["move", "--abs", "10", "--timeout-s", "0"], "--timeout-s"),
        (&["move", "--abs", "10", "--timeout-s", "NaN"], "--timeout-s"),
        (&["move", "--abs", "10", "--timeout-s", "1e30"], "--timeout-s"),
        (&["move", "--abs", "1e9", "--speed", "50"], "--abs"),
        (&["move", "--abs", "NaN"], "--abs"),
        (&["move", "--rel", "-1e9", "--accel", "100"], "--rel"),
        (&["move", "--abs", "10", "--speed", "0"], "--speed"),
        (&["move", "--abs", "10", "--speed", "-5"], "--speed"),
        (&["move", "--abs", "10", "--speed", "NaN"], "--speed"),
        (&["move", "--abs", "10", "--speed", "150"], "--speed"),
        (&["move", "--abs", "10", "--speed", "inf"], "--speed"),
        (&["move", "--abs", "10", "--speed", "50", "--accel", "40000"], "--accel"),
        (&["move", "--abs", "10", "--accel", "-1"], "--accel"),
        (&["move", "--abs", "10", "--accel", "NaN"], "--accel"),
        (&["move", "--abs", "10", "--accel", "0"], "--accel"),
        (&["move", "--abs", "10", "--tolerance", "0"], "--tolerance"),
        (&["move", "--abs", "10", "--tolerance", "-0.1"], "--tolerance"),
        (&["move", "--abs", "10", "--tolerance", "NaN"], "--tolerance"),
        (&["move", "--abs", "10", "--poll-ms", "0"], "--poll-ms"),
        (&["move", "--abs", "10", "--poll-ms", "100000"], "--poll-ms"),
        (&["move", "--abs", "10", "--min-pos", "5", "--max-pos", "1"], "--min-pos"),
        (&["move", "--abs", "10", "--max-pos", "NaN"], "--max-pos"),
        (&["--drive", "0", "move", "--abs", "10"], "--drive"),
        (&["--drive", "32", "move", "--abs", "10"], "--drive"),
        (&["--drive", "300", "move", "--abs", "10"], "--drive"),
        (&["--drive", "-1", "move", "--abs", "10"], "--drive"),
        (&["--timeout-ms", "0", "move", "--abs", "10"], "--timeout-ms"),
        (&["--timeout-ms", "100000", "move", "--abs", "10"], "--timeout-ms"),
        (&["--timeout-ms", "-5", "status"], "--timeout-ms"),
        (&["--baud", "1234", "move", "--abs", "10"], "--baud"),
        (&["--mode", "164", "move", "--abs", "10"], "--mode"),
        (&["raw", "POSA 10", "--wait", "--timeout-s", "0"], "--timeout-s"),
        (&["raw", "POSA 10", "--wait", "--poll-ms", "0"], "--poll-ms"),
        (&["watch", "--interval-ms", "0"], "--interval-ms"),
        (&["output", "3", "5"], "output state"),
        (&["set", "P196", "1000"], "P196"),
        (&["set", "P003", "NaN"], "the value must be a number"),
        (&["status", "S99"], "S99"),
        // A speed the command would carry as 0 (it went out as SPEED 0, refused by the drive with E90).
        (
            &["move", "--abs", "10", "--speed", "1e-300"],
            "'1e-300' for '--speed <SPEED>': speed 1e-300 % is out of range",
        ),
        (&["move", "--abs", "10", "--speed", "0.0000004"], "speed 0.0000004 % is out of range (0.000001 to 100 %"),
        // A value the command would carry as another number (it went out as P003=0 and "read back wrong").
        (
            &["set", "P003", "0.0000001"],
            "parameter value P003=0.0000001 has more decimals than a command carries (6): it would be sent as P003=0",
        ),
        // Too long for the drive's input buffer, with the command's real length ("P003=" and the digits).
        (&["set", "P003", "1e308"], "command string of 314 characters is longer than the drive's input buffer (40)"),
        (&["set", "P003", "123456789012345678901234567890123456789012"], "command string of 47 characters"),
        (&["send", ""], "empty command"),
        (&["raw", ""], "empty command"),
        (&["send", "POSA 1234567890123456789012345678901234567"], "command string of 42 characters"),
    ] {
        let mut v = vec!["-vvv"];
        v.extend_from_slice(&["compax", "--port", p]);
        v.extend_from_slice(args);
        let o = Command::new(BIN).args(&v).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(names), "{args:?} names {names:?}: {err}");
        assert!(!err.contains("send \""), "{args:?}: something was sent: {err}");
    }
    // Nothing moved, nothing was switched off.
    assert!(sim.events().is_empty(), "{}", sim.stderr.text());
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

/// A usage error prints no result: `send ''` printed a result object (`--json`) or `request: none` /
/// `reply: none` on stdout besides the error on stderr.
#[test]
fn a_command_that_cannot_be_sent_prints_no_result() {
    let sim = start_sim(&["--tcp", "127.0.0.1:0", "--drives", "5"]);
    let p = sim.address.as_str();
    for json_output in [true, false] {
        let mut args = vec!["--drive", "5", "send", ""];
        if json_output {
            args.push("--json");
        }
        let o = compax(p, &args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert_eq!(stdout(&o), "", "no result for a usage error ({args:?}); stderr: {err}");
        if json_output {
            let e = common::json_error(&o);
            assert_eq!((e["kind"].as_str(), e["message"].as_str()), (Some("usage"), Some("empty command")), "{e}");
            assert_eq!(err.lines().count(), 1, "{err}");
        } else {
            assert_eq!(err.trim_end(), "motionlink: empty command");
        }
    }
    assert!(sim.events().is_empty(), "{}", sim.stderr.text());
}

/// A move while the drive still executes another: refused before anything is sent to move, saying what the
/// drive showed (a command active in S17), with no error code the drive never sent (it said `"S17" refused
/// with E92`, `"code":92`, although the drive had answered S17 normally). Exit 1: the drive's state, as for
/// a drive switched off.
#[test]
fn a_move_while_the_drive_still_moves_says_so_without_a_made_up_code() {
    let sim = start_sim(&["--tcp", "127.0.0.1:0", "--drives", "1,5"]);
    let p = sim.address.as_str();
    let o = compax(p, &["--drive", "5", "move", "500", "--no-wait", "--speed", "10"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = compax(p, &["-v", "--drive", "5", "move", "10"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    let said = err.lines().find(|l| l.starts_with("motionlink: ")).unwrap_or_default();
    assert_eq!(
        said,
        "motionlink: drive 5 is still executing a command (S17 shows a command active, such as a positioning that \
         runs): the move was not sent; wait until it has ended, or stop it",
        "{err}"
    );
    assert_eq!(err.lines().filter(|l| l.starts_with("motionlink: ")).count(), 1, "{err}");
    // S16 and S17 were read; nothing was sent to move.
    assert!(!err.lines().any(|l| l.contains("-> ") && (l.contains("POSA") || l.contains("SPEED"))), "{err}");
    let o = compax(p, &["--drive", "5", "--json", "move", "10"]);
    let e = common::json_error(&o);
    assert_eq!((e["kind"].as_str(), e["exit_code"].as_i64()), (Some("device"), Some(1)), "{e}");
    assert!(e.get("code").is_none() && e.get("bits").is_none(), "no code the drive did not report: {e}");
    assert!(!sim.events().iter().any(|e| e.text.contains("E92")), "{}", sim.stderr.text());
}

/// A scan in the wrong mode (no BCC against drives that check one): the one drive (1) answers E72 where
/// it is addressed, late, while the client asks 2, 12 and 22; the drives it does not have answer nothing
/// (the emulator answered for 2..9 and 12, reading the "1" of "S1" as drive 1's address). Said once, with
/// the drive named once (it said "drive 2: drive 2: ..." for each) and the likely cause.
#[test]
fn a_scan_in_the_wrong_mode_says_why_once() {
    let sim = start_sim(&["--tcp", "127.0.0.1:0", "--mode", "8"]);
    let o = compax(&sim.address, &["--timeout-ms", "30", "scan"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(3), "{err}");
    assert!(!err.contains("drive 2: drive 2"), "{err}");
    let warnings: Vec<&str> = err.lines().filter(|l| l.starts_with("motionlink: warning: ")).collect();
    assert_eq!(warnings.len(), 1, "{err}");
    assert!(
        warnings[0].contains("E72 (BCC error) answered S1 at addresses 2, 12, 22, although this client sends no BCC"),
        "{err}"
    );
    assert!(err.lines().last().unwrap().ends_with("no drive answered"), "{err}");
    // The drive's own errors: three E72, all drive 1's.
    let e72: Vec<String> = sim.events().into_iter().map(|e| e.text).filter(|t| t.contains("E72")).collect();
    assert_eq!(e72.len(), 3, "{e72:?}");
    // In its mode, the scan finds it.
    let o = compax(&sim.address, &["--timeout-ms", "30", "--mode", "8", "scan"]);
    assert!(o.status.success() && stdout(&o).starts_with("drive 1 "), "{}", String::from_utf8_lossy(&o.stderr));
}

/// A stderr that nobody reads (a pipe whose reader stalled): the `-vvv` trace of every telegram fills it, and
/// a signal still stops the move at once (COMPAX has no watchdog: a session waiting for stderr would leave
/// the axis running). Lines for stderr are written by a thread of their own and left out when it is full.
#[cfg(target_os = "linux")]
#[test]
fn a_signal_stops_a_move_whose_stderr_is_not_read() {
    use std::os::fd::AsRawFd;
    let sim = start_sim(&["--tcp", "127.0.0.1:0"]);
    let args = ["-vvv", "compax", "--port", &sim.address, "move", "--abs", "1000", "--speed", "10", "--poll-ms", "1"];
    let mut child = Command::new(BIN).args(args).stdout(Stdio::null()).stderr(Stdio::piped()).spawn().unwrap();
    let stderr = child.stderr.take().unwrap();
    // The smallest pipe (one page): it is full after a few dozen trace lines.
    // SAFETY: fcntl(2) on a pipe this process holds.
    unsafe { libc::fcntl(stderr.as_raw_fd(), libc::F_SETPIPE_SZ, 4096) };
    wait_started(&sim, 1);
    std::thread::sleep(Duration::from_millis(1500));
    let at = common::unix_now();
    // SAFETY: kill(2) on our own child's pid.
    assert_eq!(unsafe { libc::kill(child.id() as i32, libc::SIGTERM) }, 0);
    let (rest, p) = wait_at_rest(&sim, 1, at);
    assert!(rest.at - at < 0.100, "at rest {:.1} ms after the signal", (rest.at - at) * 1e3);
    assert!((0.0..1000.0).contains(&p), "{p}");
    // Read now: what was left to say comes out, and the command ends as a signal's stop does.
    let reader = std::thread::spawn(move || std::io::read_to_string(stderr).unwrap_or_default());
    let status = child.wait().unwrap();
    let said = reader.join().unwrap();
    assert_eq!(status.code(), Some(143), "{said}");
    assert!(said.contains("now switched off"), "{said}");
}

/// `set P196 164`, the manual's setting for a drive on the COMTAC fieldbus (3.3.2), is written and read back
/// (was: refused as out of range), and the command says what it does at the next power-on: the drive
/// speaks a protocol motionlink does not. A session's `--mode 164` stays refused (this tool speaks ASCII).
#[test]
fn the_fieldbus_mode_is_written_with_what_it_does_at_power_on() {
    let o = compax("sim", &["set", "P196", "164"]);
    let said = stdout(&o);
    assert!(o.status.success(), "{said}{}", String::from_utf8_lossy(&o.stderr));
    assert!(said.starts_with("P196 = 164, read back (takes effect at the drive's next power-on;"), "{said}");
    assert!(said.contains("COMTAC fieldbus protocol") && said.contains("answer no ASCII telegram"), "{said}");
    let o = compax("sim", &["set", "P195", "345600"]);
    assert!(o.status.success() && stdout(&o).contains("a baud rate of the fieldbus protocol"), "{}", stdout(&o));
    let o = compax("sim", &["--mode", "164", "status"]);
    assert_eq!(o.status.code(), Some(2), "{}", String::from_utf8_lossy(&o.stderr));
}

/// `raw` of a move sent with `?`: the manual does not say whether a drive carries out what it echoes, so the
/// move counts as started and is handed over with words that say it may be moving (was: not counted, so
/// nothing said, and a drive that carries it out, `echo-executes`, ran on unmentioned).
#[test]
fn a_raw_move_with_an_echo_is_handed_over_as_one_that_may_be_moving() {
    for (variant, moved) in [("echo-executes", true), ("echo-without-store", false)] {
        let sim = start_sim(&["--tcp", "127.0.0.1:0", "--variant", variant]);
        let o = compax(&sim.address, &["--json", "raw", "POSA 10?"]);
        let said = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "{said}");
        assert_eq!(json(&o)["started"], serde_json::json!([1]), "{variant}");
        assert!(
            said.contains("drive 1 may be moving on (the manual does not say whether a drive carries out"),
            "{said}"
        );
        let events = sim.events();
        assert_eq!(events.iter().any(|e| e.text.starts_with("drive 1 motion started")), moved, "{variant}: {events:?}");
    }
}

/// `raw --broadcast` sends to address 32 (every drive; none answers), as the manual's broadcast: a move
/// reaches both drives, and the command says that each may be moving on. `--wait` cannot go with it (no
/// drive answers, so none can be waited for).
#[test]
fn raw_broadcast_reaches_every_drive_and_says_they_may_be_moving() {
    let sim = start_sim(&["--tcp", "127.0.0.1:0", "--drives", "1,5"]);
    let o = compax(&sim.address, &["raw", "--broadcast", "POSA 10"]);
    let said = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{said}");
    assert_eq!(stdout(&o).trim(), "(no reply due)");
    assert!(
        said.contains("sent to every drive (address 32, no drive answers): each drive that took it may be moving on"),
        "{said}"
    );
    for d in [1, 5] {
        let started = format!("drive {d} motion started to 10.000");
        sim.wait_event(Duration::from_secs(5), |t| t.starts_with(&started))
            .unwrap_or_else(|| panic!("drive {d} moves"));
    }
    let o = compax(&sim.address, &["raw", "--broadcast", "--wait", "POSA 10"]);
    assert_eq!(o.status.code(), Some(2), "{}", String::from_utf8_lossy(&o.stderr));
}
