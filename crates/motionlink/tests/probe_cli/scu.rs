//! `motionlink probe scu`.

use super::*;
use crate::common::Sim;

#[test]
fn probe_scu_prints_the_unit_the_link_and_every_check() {
    let sim = Sim::tcp("scu");
    let dir = config_dir("probe-scu-text");
    let out = run_in(&dir, &["probe", "scu", "--port", &sim.address], &[]);
    assert!(out.status.success(), "{out:?}");
    let text = stdout(&out);
    assert!(text.starts_with(&format!("scu on {}\n", sim.address)), "{text}");
    assert!(text.contains("firmware \"SCU V2B3 motionlink-sim\""), "{text}");
    assert!(text.contains("link: tcp, 20 exchanges, 0 errors"), "{text}");
    for line in ["ok           grouping_indices", "ok           cyclic_objects", "skipped      baud"] {
        assert!(text.contains(line), "{line:?} in {text}");
    }
    assert!(!dir.join("profiles.toml").exists(), "nothing saved without --save");

    let out = run_in(&dir, &["probe", "scu", "--port", &sim.address, "--json", "--exchanges", "5"], &[]);
    let v = one_json(&out);
    super::assert_report_shape(&v, "scu", &sim.address);
    assert_eq!(v["link"]["exchanges"], 5);
    assert_eq!(v["devices"][0]["firmware"], "SCU V2B3 motionlink-sim");
    assert_eq!(v["devices"][0]["capabilities"]["grouping_indices"], true);
    assert_eq!(result_of(&v, "baud", None), "skipped");
    assert_eq!(result_of(&v, "remote_read_back", None), "ok");
}

#[test]
fn a_variant_shows_as_unsupported_and_baud_auto_does_not_apply_over_tcp() {
    let sim = Sim::start("scu", &["--tcp", "127.0.0.1:0", "--variant", "no-user-positions"]);
    let dir = config_dir("probe-scu-variant");
    let out = run_in(&dir, &["probe", "scu", "--port", &sim.address, "--json", "--baud", "auto"], &[]);
    let v = one_json(&out);
    assert_eq!(result_of(&v, "user_position_data", None), "unsupported");
    assert_eq!(result_of(&v, "grouping_indices", None), "ok");
    let baud = v["checks"].as_array().unwrap().iter().find(|c| c["name"] == "baud").unwrap();
    assert!(baud["result"] == "skipped" && baud["detail"].as_str().unwrap().contains("tcp://"), "{baud}");
    // --port sim takes the variant too.
    let out = run_in(&dir, &["probe", "scu", "--port", "sim", "--sim-variant", "no-cyclic-objects", "--json"], &[]);
    assert_eq!(result_of(&one_json(&out), "cyclic_objects", None), "unsupported");
    // Bad input is named.
    let out = run_in(&dir, &["probe", "scu", "--port", "sim", "--baud", "4800"], &[]);
    assert_eq!(out.status.code(), Some(2), "{out:?}");
    assert!(stderr(&out).contains("38400, 19200, 9600, or give auto"), "{out:?}");
}

/// Requests of a grouping index (0x0170, 0x0010, 0x00A0, 0x00D0) in a capture.
fn group_reads(capture: &str) -> usize {
    capture
        .lines()
        .filter(|l| {
            ["-> 52 47 70 01", "-> 52 47 10 00", "-> 52 47 A0 00", "-> 52 47 D0 00"].iter().any(|g| l.contains(g))
        })
        .count()
}

#[test]
fn save_writes_a_profile_that_a_later_move_names_and_whose_probes_disappear() {
    let sim = Sim::start("scu", &["--tcp", "127.0.0.1:0", "--variant", "no-groups"]);
    let p = sim.address.as_str();
    let dir = config_dir("probe-scu-save");
    let capture = dir.join("move.capture");
    let cap = capture.to_str().unwrap();
    let moved = |pos: &str| run_in(&dir, &["scu", "--port", p, "--json", "--capture", cap, "move", "1", pos], &[]);

    // Without a profile: the session finds out (RG of a grouping index, refused) and names no profile.
    let out = moved("200");
    let v = one_json(&out);
    assert_eq!(v["profile"], serde_json::Value::Null, "{v}");
    assert!(group_reads(&std::fs::read_to_string(&capture).unwrap()) >= 1);

    let out = run_in(&dir, &["probe", "scu", "--port", p, "--save", "--json"], &[]);
    let report = one_json(&out);
    let saved = report["saved"][0].as_str().unwrap().to_string();
    let file = dir.join("profiles.toml");
    assert!(saved.starts_with(&format!("{}#scu:{p}:", file.display())), "{saved}");
    let toml = std::fs::read_to_string(&file).unwrap();
    assert!(toml.contains("grouping_indices = false") && toml.contains("SCU V2B3 motionlink-sim"), "{toml}");

    // With it: the move names it, and no grouping index is asked for any more.
    let out = moved("300");
    let v = one_json(&out);
    assert_eq!(v["profile"].as_str(), Some(saved.as_str()), "{v}");
    assert_eq!(v["reached_counts"], 300, "{v}");
    assert_eq!(group_reads(&std::fs::read_to_string(&capture).unwrap()), 0);
    assert!(!stderr(&out).contains("grouping index"), "no warning for what the profile says: {out:?}");

    // A profile of another unit on this port (another firmware text): ignored, with a one-line notice.
    std::fs::write(&file, toml.replace("SCU V2B3 motionlink-sim", "SCU V9Z9 elsewhere")).unwrap();
    let out = moved("250");
    let v = one_json(&out);
    assert_eq!(v["profile"], serde_json::Value::Null, "{v}");
    let notice = stderr(&out);
    assert!(notice.contains("not used") && notice.contains("SCU V9Z9 elsewhere"), "{notice}");
    assert!(group_reads(&std::fs::read_to_string(&capture).unwrap()) >= 1, "probed again");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_latency_timer_of_a_usb_adapter_is_reported_with_its_fix_and_low_latency_sets_it() {
    let sim = Sim::start("scu", &["--pty"]);
    let tty = std::path::Path::new(&sim.address).file_name().unwrap().to_str().unwrap().to_string();
    let dir = config_dir("probe-scu-latency");
    let timer_dir = dir.join("sysfs/sys/bus/usb-serial/devices").join(&tty);
    std::fs::create_dir_all(&timer_dir).unwrap();
    let timer = timer_dir.join("latency_timer");
    std::fs::write(&timer, "16\n").unwrap();
    let root = dir.join("sysfs");
    let env = [("MOTIONLINK_SYSFS_ROOT", root.to_str().unwrap())];

    let out = run_in(&dir, &["probe", "scu", "--port", &sim.address, "--json"], &env);
    assert_eq!(out.status.code(), Some(1), "a failed check exits 1: {out:?}");
    let v = one_json(&out);
    assert_eq!(result_of(&v, "latency_timer", None), "failed");
    assert_eq!(v["link"]["latency_timer"]["ms"], 16);
    let fix = format!("echo 1 | sudo tee {}", timer.display());
    assert_eq!(v["link"]["latency_timer"]["fix"].as_str(), Some(fix.as_str()));
    assert_eq!(v["link"]["baud"], 38_400);
    assert!(stderr(&out).contains("latency_timer"), "{out:?}");

    let out = run_in(&dir, &["probe", "scu", "--port", &sim.address, "--low-latency"], &env);
    assert!(out.status.success(), "{out:?}");
    assert!(stdout(&out).contains("was 16 ms, set to 1 ms"), "{out:?}");
    assert_eq!(std::fs::read_to_string(&timer).unwrap().trim(), "1");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A signal while the probe runs ends it with the session's RA (the unit leaves remote mode as asked), not
/// with the process killed and the unit's watchdog ending remote mode (its error bit 22).
#[cfg(unix)]
#[test]
fn a_signal_ends_a_probe_with_the_session_s_ra() {
    let running = common::Running::start(&["-v", "probe", "scu", "--port", "sim", "--sim-variant", "sleepy"]);
    std::thread::sleep(std::time::Duration::from_millis(250));
    running.signal(libc::SIGINT);
    let ended = running.wait(std::time::Duration::from_secs(10));
    assert_eq!(ended.code(), 130, "{}", ended.stderr);
    assert!(ended.stderr.lines().any(|l| l.contains("RA remote mode abort")), "{}", ended.stderr);
}

/// A battery unit in low-power mode is probed once `--wake` woke it (without it, it answers nothing).
#[test]
fn probe_scu_wakes_a_unit_in_low_power_mode_with_wake() {
    let dir = config_dir("probe-scu-wake");
    let asleep = run_in(&dir, &["probe", "scu", "--port", "sim", "--sim-variant", "low-power"], &[]);
    assert_eq!(asleep.status.code(), Some(3), "{asleep:?}");
    let out = run_in(&dir, &["probe", "scu", "--port", "sim", "--sim-variant", "low-power", "--wake", "--json"], &[]);
    let v = one_json(&out);
    assert_eq!(v["devices"][0]["firmware"], "SCU V2B3 motionlink-sim", "{v}");
}
