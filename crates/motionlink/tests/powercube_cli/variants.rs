//! The core actions through the binary against every firmware variant of `motionlink sim powercube
//! --variant X`: each works (saying what it could not verify) or ends with an error that says what the
//! module did not do; a move that exits 0 ended at its target. The variants run side by side.

use super::*;

/// One line of JSON from `out`'s stdout.
fn json_of(out: &Output) -> serde_json::Value {
    let text = String::from_utf8_lossy(&out.stdout);
    serde_json::from_str(text.lines().last().unwrap_or("")).unwrap_or_else(|e| panic!("{e}: {out:?}"))
}

/// What the core actions did against one variant.
struct Run {
    variant: &'static str,
    set: Output,
    home: Output,
    moved_with_speed: Output,
    moved_without_speed: Output,
    /// A move to 100 rad, beyond MaxPos.
    beyond: Output,
    /// The stderr of every action, joined.
    stderr: String,
}

/// Scan, get, set, home, move with and without a speed, watch, halt, reset (each a session of its own,
/// closed by the command) against `motionlink sim powercube --variant <variant>` (`""`: none).
fn core_actions(variant: &'static str) -> Run {
    let mut args = vec!["--tcp", "127.0.0.1:0"];
    if !variant.is_empty() {
        args.extend(["--variant", variant]);
    }
    let sim = Sim::start("powercube", &args);
    let port = sim.address.as_str();
    let mut stderr = String::new();
    let mut go = |args: &[&str]| {
        let out = run(port, args);
        stderr.push_str(&String::from_utf8_lossy(&out.stderr));
        out
    };
    let scan = go(&["scan", "--json"]);
    assert!(scan.status.success() && json_of(&scan)["serial"] == 1001, "{variant}: {scan:?}");
    assert!(go(&["get", "ActPos", "--json"]).status.success(), "{variant}");
    let set = go(&["set", "TargetVel", "0.8", "--json"]);
    let home = go(&["home", "--json"]);
    let moved_with_speed = go(&["move", "0.3", "--vel", "0.7", "--acc", "1.5", "--json"]);
    let moved_without_speed = go(&["move", "0.2", "--json"]);
    // Refused (exit 2) before anything is sent that changes the module: its stderr is checked alone.
    let beyond = run(port, &["move", "100", "--json"]);
    let watch = go(&["watch", "--count", "2", "--interval-ms", "10"]);
    assert!(watch.status.success() && String::from_utf8_lossy(&watch.stdout).lines().count() == 2, "{variant}");
    assert!(go(&["halt"]).status.success(), "{variant}");
    assert!(go(&["reset"]).status.success(), "{variant}");
    for (what, out) in [("move", &moved_with_speed), ("move", &moved_without_speed)] {
        if out.status.success() {
            let j = json_of(out);
            let (target, reached) = (j["target_rad"].as_f64().unwrap(), j["reached_rad"].as_f64().unwrap());
            assert!((target - reached).abs() <= 0.001, "{variant}: {what} exited 0 at {reached}, not {target}");
        }
    }
    Run { variant, set, home, moved_with_speed, moved_without_speed, beyond, stderr }
}

fn verified(out: &Output) -> (bool, String) {
    let j = json_of(out);
    let reasons = j["not_verifiable"].as_array().unwrap_or_else(|| panic!("{j}")).iter();
    (j["verified"].as_bool().unwrap(), reasons.map(|r| r.as_str().unwrap().to_string()).collect::<Vec<_>>().join("\n"))
}

#[test]
fn every_variant_through_the_binary() {
    let variants = [
        "",
        "no-twin-mirror",
        "no-broadcast-pair",
        "ack-length-6,ext-ack-on-put-id",
        "no-pos-state-dio",
        "life-sign-unacknowledged",
        "no-config-word",
        "reset-clears-watchdog,no-extended-ack",
        "late-motion-start",
    ];
    let runs: Vec<Run> = std::thread::scope(|s| {
        let handles: Vec<_> = variants.iter().map(|v| s.spawn(move || core_actions(v))).collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    });
    for r in &runs {
        let v = r.variant;
        // The limits come first, whatever the guard would do (a module whose watchdog cannot be armed too).
        let beyond = String::from_utf8_lossy(&r.beyond.stderr);
        assert_eq!(code(&r.beyond), 2, "{v}: {beyond}");
        assert!(beyond.contains("the target position 100 rad is outside MinPos..MaxPos"), "{v}: {beyond}");
        assert!(!beyond.contains("watchdog"), "{v}: {beyond}");
        match v {
            "life-sign-unacknowledged" => {
                assert!(verified(&r.set).0, "{v}");
                for out in [&r.home, &r.moved_with_speed, &r.moved_without_speed] {
                    assert_eq!(code(out), 1, "{v}: {out:?}");
                    let err = String::from_utf8_lossy(&out.stderr);
                    assert!(err.contains("cannot arm the watchdog of module 1"), "{v}: {err}");
                }
                assert!(r.stderr.contains("not acknowledged"), "{v}: {}", r.stderr);
                continue;
            }
            "no-config-word" => {
                // Its type read from DefConfig (the scan, the set, the limits); the arming's read of the
                // Config word fails with its timeout (exit 3), which is named and explained.
                assert!(verified(&r.set).0, "{v}");
                for out in [&r.home, &r.moved_with_speed, &r.moved_without_speed] {
                    assert_eq!(code(out), 3, "{v}: {out:?}");
                    let err = String::from_utf8_lossy(&out.stderr);
                    assert!(err.contains("cannot arm the watchdog of module 1: module 1 did not answer"), "{v}: {err}");
                    assert!(err.contains("a module before version 3.5.00 has no Config word"), "{v}: {err}");
                }
                assert!(r.stderr.contains("its type is read from DefConfig"), "{v}: {}", r.stderr);
                continue;
            }
            _ => {
                for out in [&r.set, &r.home, &r.moved_with_speed, &r.moved_without_speed] {
                    assert!(out.status.success(), "{v}: {out:?}");
                }
            }
        }
        let (set, set_why) = verified(&r.set);
        let (home, home_why) = verified(&r.home);
        let (with_speed, with_why) = verified(&r.moved_with_speed);
        let (without_speed, without_why) = verified(&r.moved_without_speed);
        match v {
            "no-twin-mirror" => {
                assert!(!set && set_why.contains("keeps TargetVelInc apart"), "{v}: {set_why}");
                assert!(!with_speed && with_why.lines().count() == 3, "{v}: {with_why}");
                assert!(!without_speed && without_why.contains("the motion's target"), "{v}: {without_why}");
                // Said once per session: the set, the first move (the second finds TargetPos apart, in
                // another session, and says it once too).
                let warnings = r.stderr.lines().filter(|l| l.contains("keeps") && l.contains("apart")).count();
                assert_eq!(warnings, 3, "{v}: {}", r.stderr);
            }
            "no-broadcast-pair" => {
                assert!(set, "{v}");
                // Homing ran without the watchdog as the moves did, and says so.
                for (ok, why) in [(home, &home_why), (with_speed, &with_why), (without_speed, &without_why)] {
                    assert!(!ok && why.contains("ignores the watchdog refresh broadcast on RS232"), "{v}: {why}");
                }
                assert!(r.stderr.contains("ignores the watchdog refresh broadcast"), "{v}: {}", r.stderr);
            }
            _ => {
                assert!(
                    set && home && with_speed && without_speed,
                    "{v}: {set_why} {home_why} {with_why} {without_why}"
                );
                if v == "no-pos-state-dio" {
                    assert!(r.stderr.contains("does not answer ActFPosStateDio"), "{v}: {}", r.stderr);
                } else {
                    assert!(r.stderr.is_empty(), "{v}: {}", r.stderr);
                }
            }
        }
    }
}

#[test]
fn a_move_without_vel_on_a_module_whose_tick_twins_are_apart_moves_at_its_own_speed() {
    // The module keeps TargetVelInc apart from TargetVel: TargetVelInc 0 says nothing of the 0.5 rad/s the
    // ramp uses, and is set to 0 here as a user would.
    let sim = Sim::start("powercube", &["--tcp", "127.0.0.1:0", "--variant", "no-twin-mirror"]);
    let port = sim.address.as_str();
    for param in ["TargetVelInc", "TargetAccInc"] {
        let out = run(port, &["--module", "1", "send", "set", param, "0"]);
        assert!(out.status.success(), "{out:?}");
    }
    let out = run(port, &["--module", "1", "--json", "move", "0.3"]);
    assert_eq!(code(&out), 0, "{out:?}");
    let j = json_of(&out);
    assert!((j["reached"].as_f64().or(j["reached_rad"].as_f64()).unwrap_or(f64::NAN) - 0.3).abs() < 1e-3, "{j}");
    assert_eq!(j["verified"], false, "the target's twin is kept apart: {j}");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("TargetVelInc reads 0, but whether it shows the module's own TargetVel is not known"),
        "{err}"
    );
}

#[test]
fn a_tick_target_is_set_within_its_int32_limit_and_refused_beyond_it() {
    for (param, value) in [("TargetVelInc", "100"), ("TargetAccInc", "100"), ("TargetPosInc", "-100")] {
        let out = run("sim", &["--module", "1", "set", param, value]);
        assert!(out.status.success(), "{param}: {out:?}");
        let said = String::from_utf8_lossy(&out.stdout);
        assert!(said.contains(&format!("{param} set to {value}")) && said.contains("read back"), "{param}: {said}");
    }
    for (param, value, limit) in [
        ("TargetVelInc", "100000000", "ActIMaxVel"),
        ("TargetAccInc", "100000000", "ActIMaxAcc"),
        ("TargetPosInc", "100000000", "ActIMinPos..ActIMaxPos"),
    ] {
        let out = run("sim", &["--module", "1", "set", param, value]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(code(&out), 2, "{param}: {err}");
        assert!(err.contains(limit) && !err.contains("corrupt"), "{param}: {err}");
    }
}

#[test]
fn a_refused_arming_leaves_the_module_able_to_move_and_says_so() {
    let sim = Sim::start("powercube", &["--tcp", "127.0.0.1:0", "--variant", "life-sign-unacknowledged"]);
    let port = sim.address.as_str();
    for attempt in 0..2 {
        let out = run(port, &["--module", "1", "--json", "move", "0.5", "--vel", "0.5", "--acc", "1"]);
        assert_eq!(code(&out), 1, "{attempt}: {out:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains("cannot arm the watchdog of module 1"), "{attempt}: {err}");
        assert!(!err.contains("reports an error"), "{attempt}: not left in error: {err}");
        assert!(err.contains("module 1 is left as it was"), "{attempt}: {err}");
    }
    let state: serde_json::Value =
        serde_json::from_slice(&run(port, &["--module", "1", "--json", "state"]).stdout).unwrap();
    let flags = state["flags"].as_array().unwrap();
    assert!(!flags.iter().any(|f| f == "STATE_COMM_ERROR" || f == "STATE_HALTED" || f == "STATE_ERROR"), "{state}");
    // The module moves when the watchdog is not asked for.
    let out = run(port, &["--module", "1", "--no-watchdog", "move", "0.5", "--vel", "0.5", "--acc", "1"]);
    assert!(out.status.success(), "{out:?}");
}

#[test]
fn a_module_without_the_config_word_is_refused_its_watchdog_before_anything_moves() {
    let sim = Sim::start("powercube", &["--tcp", "127.0.0.1:0", "--variant", "no-config-word"]);
    let port = sim.address.as_str();
    for action in [&["move", "0.5", "--vel", "0.5", "--acc", "1"][..], &["home"][..]] {
        let out = run(port, &[&["-v", "--json", "--module", "1"][..], action].concat());
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(code(&out), 3, "{action:?}: {err}");
        let lines: Vec<serde_json::Value> = err.lines().map(|l| serde_json::from_str(l).unwrap()).collect();
        let e = lines.last().unwrap();
        assert_eq!((e["kind"].as_str(), e["exit_code"].as_i64()), (Some("timeout"), Some(3)), "{e}");
        let message = e["message"].as_str().unwrap_or_default();
        assert!(message.starts_with("cannot arm the watchdog of module 1: module 1 did not answer GetExtended Config"));
        assert!(message.contains("no Config word, manual 7.2") && message.contains("`--no-watchdog`"), "{e}");
        // The trace: the Config word asked, never written; no life sign, no motion command, no Home.
        let sent: Vec<&str> = lines
            .iter()
            .filter(|l| l["trace"]["direction"] == "->")
            .filter_map(|l| l["trace"]["meaning"].as_str())
            .collect();
        assert!(sent.contains(&"to module 1: GetExtended Config"), "{action:?}: {err}");
        for never in ["SetExtended", "LifeSign", "SetMotion", ": Home", "Halt"] {
            assert!(!sent.iter().any(|l| l.contains(never)), "{action:?}: {never} sent: {err}");
        }
    }
    let events = sim.events();
    assert!(!events.iter().any(|e| e.text.contains("motion started") || e.text.contains("watchdog")), "{events:?}");
    // Without the watchdog it moves, its type (rad) read from DefConfig.
    let out = run(port, &["--module", "1", "--json", "--no-watchdog", "move", "0.3"]);
    assert!(out.status.success(), "{out:?}");
    let j = json_of(&out);
    assert!((j["reached_rad"].as_f64().unwrap() - 0.3).abs() < 1e-3 && j["verified"] == true, "{j}");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("module 1 does not answer the Config word (parameter 57"), "{err}");
}

/// A host killed during a move leaves the module halted by its watchdog (STATE_COMM_ERROR, the watchdog
/// online). On a module whose Reset switches the watchdog offline, `reset` sees no expiry 100 ms after its
/// Reset and sends nothing more; on the default one the expiry comes back and a life sign and a second
/// Reset release it.
#[cfg(unix)]
#[test]
fn reset_observes_whether_its_reset_left_the_expired_watchdog_online() {
    let both = |variant: &'static str| {
        let mut args = vec!["--tcp", "127.0.0.1:0"];
        if !variant.is_empty() {
            args.extend(["--variant", variant]);
        }
        let sim = Sim::start("powercube", &args);
        let port = sim.address.clone();
        let mut running = super::start_moving(&sim, &port, "1", &["move", "2.0", "--vel", "0.2", "--acc", "1"]);
        let at = running.kill();
        sim.wait_event_after(at, Duration::from_secs(5), |e| e == "module 1 watchdog expired: STATE_COMM_ERROR")
            .unwrap_or_else(|| panic!("{variant}: no expiry: {:?}", sim.events()));
        // The halt the expiry made ramps the module down: at rest before the reset, so that the events
        // after it are the reset's alone.
        sim.wait_event_after(at, Duration::from_secs(5), |e| e.starts_with("module 1 at rest"))
            .unwrap_or_else(|| panic!("{variant}: not at rest: {:?}", sim.events()));
        running.wait(Duration::from_secs(5));
        let t0 = common::unix_now();
        let out = run(&port, &["-v", "--module", "1", "reset"]);
        assert!(out.status.success(), "{variant}: {out:?}");
        let err = String::from_utf8_lossy(&out.stderr).into_owned();
        let sent: Vec<String> = err
            .lines()
            .filter(|l| l.contains(" -> "))
            .filter_map(|l| l.split("to module 1: ").nth(1).map(str::to_string))
            .collect();
        let state = run(&port, &["--module", "1", "--json", "state"]);
        let state: serde_json::Value = serde_json::from_slice(&state.stdout).unwrap();
        let after: Vec<String> = sim.events().into_iter().filter(|e| e.at >= t0).map(|e| e.text).collect();
        (String::from_utf8_lossy(&out.stdout).into_owned(), sent, state, after)
    };
    let ((said, sent, state, events), (said_default, sent_default, state_default, events_default)) =
        std::thread::scope(|s| {
            let variant = s.spawn(|| both("reset-clears-watchdog"));
            let default = s.spawn(|| both(""));
            (variant.join().unwrap(), default.join().unwrap())
        });
    assert_eq!(said, "reset\n");
    assert_eq!(sent, ["GetExtended CubeState", "Reset", "GetExtended CubeState"], "nothing more");
    assert_eq!(events, ["module 1 reset", "module 1 watchdog offline"], "no second expiry");
    assert!(state["flags"].as_array().unwrap().is_empty(), "{state}");
    // The default: released.
    assert_eq!(said_default, "reset (the watchdog had expired with no host serving it: switched it offline)\n");
    // The state read after the last Reset confirms it (STATE_ERROR clear), and once more 100 ms later (no
    // expiry back: the watchdog is offline).
    let released = ["GetExtended CubeState", "Reset", "GetExtended CubeState", "LifeSign (watchdog on/off)", "Reset"];
    assert_eq!(sent_default, [&released[..], &["GetExtended CubeState", "GetExtended CubeState"]].concat());
    assert!(events_default.iter().any(|e| e == "module 1 watchdog expired: STATE_COMM_ERROR"), "{events_default:?}");
    assert!(state_default["flags"].as_array().unwrap().is_empty(), "{state_default}");
}

#[test]
fn homing_without_the_watchdog_asked_for_says_so_in_words() {
    let sim = Sim::start("powercube", &["--tcp", "127.0.0.1:0", "--variant", "no-broadcast-pair"]);
    let out = run(&sim.address, &["home"]);
    assert!(out.status.success(), "{out:?}");
    let text = String::from_utf8_lossy(&out.stdout);
    let mut lines = text.lines();
    assert!(lines.next().is_some_and(|l| l.starts_with("homed: position 0.0000 rad")), "{text}");
    let why = lines.next().unwrap_or_default();
    assert!(
        why.starts_with("not verified: ") && why.contains("ignores the watchdog refresh broadcast on RS232"),
        "{text}"
    );
    // The default firmware takes the watchdog: nothing to say.
    let sim = Sim::tcp("powercube");
    let out = run(&sim.address, &["home"]);
    assert_eq!(String::from_utf8_lossy(&out.stdout).lines().count(), 1, "{out:?}");
}

#[test]
fn variants_are_named_and_checked() {
    // Unknown names are refused with the list (exit 2), on `sim` and on `--sim-variant`.
    let out =
        Command::new(BIN).args(["sim", "powercube", "--variant", "nope", "--tcp", "127.0.0.1:0"]).output().unwrap();
    assert_eq!(code(&out), 2, "{out:?}");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("nope") && err.contains("no-twin-mirror") && err.contains("ack-length-6"), "{err}");
    let out = run("sim", &["--sim-variant", "no-twin-mirro", "get", "ActPos"]);
    assert_eq!(code(&out), 2, "{out:?}");
    // The in-process emulator takes them too; a served one is told with `sim --variant`.
    let out = run("sim", &["--sim-variant", "no-twin-mirror", "set", "TargetVel", "0.8", "--json"]);
    assert!(out.status.success(), "{out:?}");
    let (ok, why) = verified(&out);
    assert!(!ok && why.contains("keeps TargetVelInc apart"), "{why}");
    let text = run("sim", &["--sim-variant", "no-twin-mirror", "set", "TargetVel", "0.8"]);
    let text = String::from_utf8_lossy(&text.stdout);
    assert!(
        text.starts_with("TargetVel set to 0.800000 rad/s (not verified: TargetVel could not be read back"),
        "{text}"
    );
    let sim = Sim::tcp("powercube");
    let out = run(&sim.address, &["--sim-variant", "no-twin-mirror", "get", "ActPos"]);
    assert_eq!(code(&out), 2, "{out:?}");
}
