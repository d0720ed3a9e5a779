//! `motionlink probe compax`.

use super::*;
use crate::common::Sim;

/// Echo probes (`S1` sent with `?`: "53 31 3F") sent in a capture.
fn echo_probes(capture: &str) -> usize {
    capture.lines().filter(|l| l.contains(" -> ") && l.contains("53 31 3F")).count()
}

#[test]
fn probe_compax_finds_the_drives_and_save_makes_the_echo_probe_disappear() {
    let sim = Sim::start("compax", &["--tcp", "127.0.0.1:0", "--drives", "1,2", "--variant", "echo-without-address"]);
    let p = sim.address.as_str();
    let dir = config_dir("probe-compax");

    let out = run_in(&dir, &["probe", "compax", "--port", p, "--drives", "1-3"], &[]);
    assert!(out.status.success(), "{out:?}");
    let text = stdout(&out);
    assert!(text.contains("drive 1: S31 COMPAX EMULATOR | S32 MOTIONLINK; P194 1, P195 9600, P196 0"), "{text}");
    assert!(text.contains("unsupported  echo_form @2"), "{text}");
    assert!(!text.contains("drive 3"), "{text}");

    let capture = dir.join("move.capture");
    let cap = capture.to_str().unwrap();
    let moved = |to: &str| {
        run_in(&dir, &["compax", "--port", p, "--drive", "2", "--json", "--capture", cap, "move", "--abs", to], &[])
    };
    let out = moved("1.5");
    assert!(out.status.success(), "{out:?}");
    assert_eq!(one_json(&out)["profile"], serde_json::Value::Null);
    assert_eq!(echo_probes(&std::fs::read_to_string(&capture).unwrap()), 1);

    let out = run_in(&dir, &["probe", "compax", "--port", p, "--drives", "1,2", "--json", "--save"], &[]);
    let v = one_json(&out);
    super::assert_report_shape(&v, "compax", p);
    assert_eq!(v["devices"].as_array().unwrap().len(), 2);
    assert_eq!(result_of(&v, "echo_form", Some(1)), "unsupported");
    assert_eq!(result_of(&v, "p196_mode", Some(2)), "ok");
    assert_eq!(v["devices"][1]["capabilities"]["echo_form"], "without_address");
    let saved2 = v["saved"][1].as_str().unwrap();
    assert!(saved2.contains(&format!("#compax:{p}:2:")), "{saved2}");

    let out = moved("2.5");
    assert!(out.status.success(), "{out:?}");
    let m = one_json(&out);
    assert_eq!(m["profile"].as_str(), Some(saved2));
    assert_eq!(m["reached_units"], 2.5);
    assert_eq!(echo_probes(&std::fs::read_to_string(&capture).unwrap()), 0, "known from the profile");
    assert!(m["not_verifiable"]
        .as_array()
        .unwrap()
        .iter()
        .any(|w| w.as_str().unwrap().contains("without its address")));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_drive_in_another_mode_is_not_found_and_the_report_says_why() {
    let sim = Sim::start("compax", &["--tcp", "127.0.0.1:0", "--mode", "8"]);
    let dir = config_dir("probe-compax-mode");
    let out = run_in(&dir, &["probe", "compax", "--port", &sim.address, "--drives", "1", "--json"], &[]);
    assert_eq!(out.status.code(), Some(1), "{out:?}");
    let v = one_json(&out);
    assert_eq!(v["devices"].as_array().unwrap().len(), 0);
    assert_eq!(result_of(&v, "drives", None), "failed");
    let out = run_in(&dir, &["probe", "compax", "--port", &sim.address, "--drives", "1", "--mode", "8", "--json"], &[]);
    assert!(out.status.success(), "{out:?}");
    assert_eq!(one_json(&out)["devices"][0]["p196_mode"], 8.0);
}

#[test]
fn a_profile_the_drive_then_contradicts_is_not_used_and_the_move_runs_in_the_form_that_fits() {
    // Saved from a drive that echoes in full; then the same port is served by a drive of each variant (the
    // identity, S31 and S32, cannot tell them apart).
    let dir = config_dir("probe-compax-contradicted");
    let port = {
        let sim = Sim::start("compax", &["--tcp", "127.0.0.1:0"]);
        let out = run_in(&dir, &["probe", "compax", "--port", &sim.address, "--drives", "1", "--json", "--save"], &[]);
        assert_eq!(one_json(&out)["devices"][0]["capabilities"]["echo_form"], "full", "{out:?}");
        sim.address.clone()
    };
    let listen = port.strip_prefix("tcp://").unwrap();
    for variant in ["no-echo", "echo-bare", "echo-without-address"] {
        let sim = Sim::start("compax", &["--tcp", listen, "--variant", variant]);
        assert_eq!(sim.address, port);
        let moved = |args: &[&str]| {
            let mut all = vec!["compax", "--port", &port, "--drive", "1", "--json", "move"];
            all.extend_from_slice(args);
            run_in(&dir, &all, &[])
        };
        for (args, target) in [(&["20"][..], 20.0), (&["--rel", "3"][..], 23.0)] {
            let out = moved(args);
            assert!(out.status.success(), "{variant} {args:?}: {out:?}");
            let m = one_json(&out);
            assert_eq!((m["reached_units"].as_f64(), m["verified"].as_bool()), (Some(target), Some(false)), "{m}");
            assert!(m["profile"].as_str().unwrap().contains("#compax:"), "{m}");
            let err = stderr(&out);
            let reference = m["profile"].as_str().unwrap();
            assert!(
                err.contains(&format!("the device profile {reference} says it echoes in full"))
                    && err.contains("the profile's finding is not used this session"),
                "{variant}: {err}"
            );
            assert!(!err.contains("is what the drive that answered received"), "{variant}: {err}");
        }
        // Each move ran once: 20, then 3 more.
        let rest = sim.stderr.wait_for(std::time::Duration::from_secs(5), |l| l.contains("at rest 23.000"));
        let events = sim.stderr.text();
        assert!(rest.is_some(), "{variant}: {events}");
        assert_eq!(events.lines().filter(|l| l.contains("motion started")).count(), 2, "{variant}: {events}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn an_echo_without_the_address_under_the_address_prefix_is_ok_with_its_reason() {
    let sim = Sim::start("compax", &["--tcp", "127.0.0.1:0", "--mode", "64", "--variant", "echo-without-address"]);
    let dir = config_dir("probe-compax-prefix");
    let out = run_in(&dir, &["probe", "compax", "--port", &sim.address, "--drives", "1", "--mode", "64"], &[]);
    assert!(out.status.success(), "{out:?}");
    let text = stdout(&out);
    let line = text.lines().find(|l| l.contains("echo_form @1")).unwrap_or_else(|| panic!("{text}"));
    assert!(line.trim_start().starts_with("ok "), "{line}");
    assert!(
        line.contains("echoes without its address digits, but every reply starts with the drive's address"),
        "{line}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
