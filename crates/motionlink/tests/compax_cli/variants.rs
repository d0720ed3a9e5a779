//! The core actions through the binary against every firmware variant of `motionlink sim compax --variant
//! X`: each works (saying what it could not verify) or ends with an error that says what the drive did not
//! do; a move that exits 0 ended at its target. The variants run side by side, at 115200 baud. A drive that
//! answers late (`slow-replies`) has a test of its own: with the default reply timeout nothing it says is
//! taken, and a scan of 31 addresses with a timeout long enough for it takes over half a minute.

use super::*;

/// What the core actions did against one variant (`""`: none) in reply mode `mode`.
struct Run {
    what: String,
    moved_with_speed: Output,
    moved_without_speed: Output,
    stderr: String,
}

/// Scan, status, set, move with a speed and a relative move without one, watch, output O0 (stop and
/// switch on), each a session of its own.
fn core_actions(variant: &'static str, mode: &'static str) -> Run {
    let mut args = vec!["--tcp", "127.0.0.1:0", "--mode", mode, "--baud", "115200", "--param", "P12=0"];
    if !variant.is_empty() {
        args.extend(["--variant", variant]);
    }
    let sim = start_sim(&args);
    let what = format!("{variant:?} P196={mode}");
    let mut stderr = String::new();
    let mut go = |extra: &[&str]| {
        let mut v = vec!["--mode", mode, "--baud", "115200", "--timeout-ms", "50"];
        v.extend_from_slice(extra);
        let out = compax(&sim.address, &v);
        stderr.push_str(&String::from_utf8_lossy(&out.stderr));
        out
    };
    let scan = go(&["--json", "scan"]);
    assert!(scan.status.success() && stdout(&scan).lines().count() == 1, "{what}: {scan:?}");
    assert!(go(&["--json", "status", "S1", "S16", "S17"]).status.success(), "{what}");
    assert!(go(&["set", "P12", "2.5"]).status.success(), "{what}");
    let moved_with_speed = go(&["--json", "move", "--abs", "20", "--speed", "100"]);
    let moved_without_speed = go(&["--json", "move", "--rel", "-5"]);
    let watch = go(&["watch", "--count", "2", "--interval-ms", "10"]);
    assert!(watch.status.success() && stdout(&watch).lines().count() == 2, "{what}: {watch:?}");
    assert!(go(&["output", "0", "0"]).status.success(), "{what}");
    assert!(go(&["output", "0", "1"]).status.success(), "{what}");
    for out in [&moved_with_speed, &moved_without_speed] {
        if out.status.success() {
            let j = json(out);
            let (target, reached) = (j["target_units"].as_f64().unwrap(), j["reached_units"].as_f64().unwrap());
            assert!((target - reached).abs() <= 0.01, "{what}: exited 0 at {reached}, not {target}");
        }
    }
    Run { what, moved_with_speed, moved_without_speed, stderr }
}

fn verified(out: &Output) -> (bool, String) {
    let j = json(out);
    let why = j["not_verifiable"].as_array().unwrap_or_else(|| panic!("{j}")).iter();
    (j["verified"].as_bool().unwrap(), why.map(|r| r.as_str().unwrap().to_string()).collect::<Vec<_>>().join("\n"))
}

#[test]
fn every_variant_through_the_binary() {
    let cases = [
        ("", "0"),
        ("echo-without-address", "0"),
        ("echo-without-address", "64"),
        ("echo-bare", "8"),
        ("no-echo", "0"),
        ("status-value-only,echo-bare", "0"),
        ("echo-without-store", "0"),
        // Neither shows in these actions (no '$' asked for, no store sent twice): as the manual's drive.
        ("no-position-message", "0"),
        ("buffer-queues", "0"),
        // S17 never shows the positioning: seen by S1 moving while S17 shows no command, if the move still
        // runs at the first poll; its end is judged by S1 either way.
        ("no-command-bit", "0"),
    ];
    let runs: Vec<Run> = std::thread::scope(|s| {
        let handles: Vec<_> = cases.iter().map(|(v, m)| s.spawn(move || core_actions(v, m))).collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    });
    for (r, (variant, mode)) in runs.iter().zip(cases) {
        let what = &r.what;
        let (a, why_a) = verified(&r.moved_with_speed);
        // A relative move on a drive that refuses the '!' after its echo is not sent again as a command of
        // its own (the drive may hold it after all, and a later '!' would run it twice): exit 1, nothing ran.
        let relative_refused = variant == "echo-without-store";
        if relative_refused {
            assert_eq!(r.moved_without_speed.status.code(), Some(1), "{what}: {:?}", r.moved_without_speed);
            let err = String::from_utf8_lossy(&r.moved_without_speed.stderr);
            assert!(err.contains("a relative move is not sent again"), "{what}: {err}");
        } else if variant == "no-command-bit" {
            // Whether a move is still running at its first poll (and so seen to move without S17 showing
            // it) depends on the timing of two processes: each is checked for itself.
            let (b, why_b) = verified(&r.moved_without_speed);
            assert!(b || why_b.contains("S17 did not show the positioning"), "{what}: {why_b}");
            let warned = r.stderr.lines().filter(|l| l.contains("while its S17 shows no command active")).count();
            assert_eq!(warned, usize::from(!a) + usize::from(!b), "{what}: {}", r.stderr);
        } else {
            let (b, why_b) = verified(&r.moved_without_speed);
            assert_eq!((a, &why_a), (b, &why_b), "{what}");
        }
        match (variant, mode) {
            ("" | "no-position-message" | "buffer-queues", _) | ("echo-without-address", "64") => {
                assert!(a && why_a.is_empty(), "{what}: {why_a}");
                assert!(r.stderr.is_empty(), "{what}: {}", r.stderr);
            }
            ("no-command-bit", _) => {
                assert!(a || why_a.contains("S17 did not show the positioning"), "{what}: {why_a}")
            }
            ("echo-without-address", _) => assert!(!a && why_a.contains("without its address"), "{what}: {why_a}"),
            ("no-echo", _) => assert!(!a && why_a.contains("does not echo"), "{what}: {why_a}"),
            // The '!' after the echo finds nothing stored and is refused: nothing ran (S17, S2), so the move
            // went out as a command of its own, once (it exited 0 at its target, checked above).
            ("echo-without-store", _) => {
                assert!(!a && why_a.contains("refused the '!' after echoing a move sent with ',?'"), "{what}: {why_a}");
                assert!(!why_a.contains("was stored"), "{what}: {why_a}");
            }
            _ => assert!(!a && why_a.contains("without the flag characters"), "{what}: {why_a}"),
        }
        if !a && variant != "no-command-bit" {
            // Said once per session (each move is one): one warning line per move that ran.
            let warnings = r
                .stderr
                .lines()
                .filter(|l| l.contains("warning") && (l.contains("echoes") || l.contains("echoed")))
                .count();
            assert_eq!(warnings, if relative_refused { 1 } else { 2 }, "{what}: {}", r.stderr);
        }
    }
}

#[test]
fn variants_are_named_and_checked() {
    let out = Command::new(BIN).args(["sim", "compax", "--variant", "echo", "--tcp", "127.0.0.1:0"]).output().unwrap();
    assert_eq!(out.status.code(), Some(2), "{out:?}");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("echo-without-address") && err.contains("no-echo"), "{err}");
    // The in-process emulator takes them; a move then says what it could not check.
    let out = compax("sim", &["--sim-variant", "echo-bare", "--baud", "115200", "move", "--abs", "3"]);
    assert!(out.status.success(), "{out:?}");
    let text = stdout(&out);
    assert!(text.contains("not verified: drive 1 echoes without its address"), "{text}");
    let sim = start_sim(&["--tcp", "127.0.0.1:0"]);
    let out = compax(&sim.address, &["--sim-variant", "echo-bare", "status"]);
    assert_eq!(out.status.code(), Some(2), "{out:?}");
}

/// A drive that answers 300 ms late (`slow-replies`), beyond the default reply timeout: each command ends
/// with exit 3 and a message that names how late the replies came; nothing moved, nothing was switched off.
/// With `--timeout-ms 600` the same commands work, and the relative move runs once.
#[test]
fn a_slow_drive_times_out_naming_its_late_replies_and_works_with_a_longer_reply_timeout() {
    let sim = start_sim(&["--tcp", "127.0.0.1:0", "--baud", "115200", "--variant", "slow-replies"]);
    let go = |extra: &[&str]| {
        let mut v = vec!["--baud", "115200"];
        v.extend_from_slice(extra);
        compax(&sim.address, &v)
    };
    for (action, first) in [(&["status", "S1"][..], "S1"), (&["move", "--rel", "5"][..], "S16")] {
        let out = go(action);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(3), "{action:?}: {err}");
        assert!(err.contains(&format!("drive 1: no reply to \"{first}\" within 20")), "{action:?}: {err}");
        assert!(
            err.contains("ms (4 attempts); replies came 30") && err.contains("too late to be taken"),
            "{action:?}: {err}"
        );
    }
    let events: Vec<String> = sim.events().into_iter().map(|e| e.text).collect();
    assert!(!events.iter().any(|e| e.contains("motion started") || e.contains("switched off")), "{events:?}");

    let status = json(&go(&["--timeout-ms", "600", "--json", "status", "S1"]));
    assert_eq!(status["status"][0]["value"], 0.0, "{status}");
    let moved = json(&go(&["--timeout-ms", "600", "--json", "move", "--rel", "5"]));
    assert_eq!((moved["reached_units"].as_f64(), moved["verified"].as_bool()), (Some(5.0), Some(true)), "{moved}");
    let events: Vec<String> = sim.events().into_iter().map(|e| e.text).collect();
    assert_eq!(events.iter().filter(|e| e.contains("motion started")).count(), 1, "{events:?}");
}

/// The binary's one way to send a move with `$` (`raw "POSA 10$" --wait`, as compax.md shows it) on a drive
/// that never sends the `$` message: the wait ends by S17, and the drive is at its target.
#[test]
fn raw_with_a_position_message_waits_by_s17_on_a_drive_that_sends_none() {
    let sim = start_sim(&["--tcp", "127.0.0.1:0", "--baud", "115200", "--variant", "no-position-message"]);
    let r = json(&compax(&sim.address, &["--baud", "115200", "--json", "raw", "POSA 10$", "--wait"]));
    assert_eq!(r["waited"], true, "{r}");
    let s = json(&compax(&sim.address, &["--baud", "115200", "--json", "status", "S1", "S17"]));
    assert_eq!(s["status"][0]["value"], 10.0, "{s}");
    assert_eq!(s["status"][1]["value"]["pattern"], "0000 0010", "at rest: {s}");
}
