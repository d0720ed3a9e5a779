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
