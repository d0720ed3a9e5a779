//! `motionlink powercube motion`: the manual's motion modes through the binary, each checked before
//! anything is sent and ended as its kind is ended.

use super::{code, number, ok, run};
use crate::common::Sim;

/// `--json` output as a value.
fn json(port: &str, args: &[&str]) -> serde_json::Value {
    let mut full = vec!["--json"];
    full.extend_from_slice(args);
    serde_json::from_str(&ok(port, &full)).unwrap()
}

#[test]
fn each_kind_of_mode_runs_to_its_end_over_tcp() {
    let sim = Sim::tcp("powercube");
    let port = sim.address.as_str();
    ok(port, &["home"]);
    // A velocity held, then ended with velocity 0: at rest where it went, not halted.
    let v = json(port, &["motion", "fvel", "0.2", "--for-s", "0.3"]);
    assert_eq!(
        (v["action"].as_str(), v["mode"].as_str(), v["ended"].as_str()),
        (Some("ran"), Some("FVEL_MODE"), Some("velocity_zero")),
        "{v}"
    );
    let (start, reached) = (v["start_rad"].as_f64().unwrap(), v["reached_rad"].as_f64().unwrap());
    assert!(reached - start > 0.04, "moved its way: {v}");
    assert!(v["held_s"].as_f64().unwrap() >= 0.3, "{v}");
    assert_eq!(v["verified"], false, "a velocity command cannot be read back: {v}");
    assert!(!v["state"]["flags"].as_array().unwrap().iter().any(|f| f == "STATE_HALTED" || f == "STATE_MOTION"), "{v}");
    assert!((number(port, "ActPos") - reached).abs() < 1e-4, "at rest where it said");
    // A step to its target in a time, in text.
    let step = ok(port, &["motion", "fstep_ack", "0.3", "--time-ms", "400"]);
    assert!(step.starts_with("FSTEP_ACK reached: position 0.3000 rad"), "{step}");
    // A ramp in encoder ticks.
    let ticks = (0.1 * number(port, "IncRatio")).round().to_string();
    assert!(ok(port, &["motion", "IRAMP_MODE", &ticks]).starts_with("IRAMP_MODE reached: position 0.1000 rad"));
    // A current held, then halted: confirmed by the state, and the module takes no motion until a reset.
    let cur = ok(port, &["motion", "fcur", "-0.5", "--for-s", "0.2"]);
    assert!(cur.starts_with("FCUR_MODE halted (it takes no motion until reset)"), "{cur}");
    assert!(cur.contains("STATE_HALTED"), "{cur}");
    let refused = run(port, &["motion", "fvel", "0.1", "--for-s", "0.1"]);
    assert_eq!(code(&refused), 1, "{refused:?}");
    ok(port, &["reset"]);
    assert!(ok(port, &["motion", "framploop", "0.2", "--for-s", "0.2"]).starts_with("FRAMPLOOP halted"));
}

#[test]
fn a_mode_s_arguments_are_checked_before_the_port_is_opened() {
    // Nothing listens there: an argument that got as far as the port would fail to connect (exit 3).
    let port = "tcp://127.0.0.1:1";
    for (args, named) in [
        (&["motion", "fstep", "0.3"][..], "FSTEP_MODE takes a target position (rad or m) and a time in ms"),
        (&["motion", "fvel", "0.1", "--time-ms", "5"], "a time of 5 ms was given (only FSTEP, ISTEP and FCOSLOOP"),
        (&["motion", "velocity", "1"], "unknown motion mode \"velocity\": one of FRAMP, FSTEP"),
        (&["motion", "fvel", "nan"], "not a finite number"),
        (&["motion", "icur", "600"], "600 is outside -500..500"),
        (&["motion", "iramp", "0.5"], "0.5 is not a whole number"),
        (&["motion", "fvel", "0.1", "--tolerance", "0.01"], "the tolerance"),
        (&["motion", "fstep", "0.1", "--time-ms", "100", "--for-s", "1"], "hold"),
        (&["motion", "fcosloop_ack", "0.1", "--time-ms", "100"], "unknown motion mode"),
        (&["motion", "fstep", "0.1", "--time-ms", "0"], "a time of 0 ms"),
        (&["motion", "fvel", "0.1", "--for-s", "0"], "--for-s"),
    ] {
        let out = run(port, args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(code(&out), 2, "{args:?}: {err}");
        assert!(err.contains(named), "{args:?} names {named}: {err}");
    }
}

#[test]
fn beyond_the_module_s_limits_a_mode_is_refused_and_nothing_moves() {
    let sim = Sim::tcp("powercube");
    let port = sim.address.as_str();
    for (args, named) in [
        (&["motion", "fvel", "1.5", "--for-s", "1"][..], "MaxVel"),
        (&["motion", "fvel", "-1.5", "--for-s", "1"], "MaxVel"),
        (&["motion", "fcur", "100", "--for-s", "1"], "MaxCur"),
        (&["motion", "fstep", "3.5", "--time-ms", "60000"], "MaxPos"),
        (&["motion", "framploop", "-3.5", "--for-s", "1"], "MinPos"),
        (&["motion", "fstep", "1", "--time-ms", "10"], "the speed the step needs"),
    ] {
        let out = run(port, args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(code(&out), 2, "{args:?}: {err}");
        assert!(err.contains(named), "{args:?} names {named}: {err}");
    }
    assert_eq!(number(port, "ActPos"), f64::from(0.05f32), "nothing moved");
}

#[test]
fn a_device_table_s_tolerance_is_move_s_and_leaves_a_velocity_alone() {
    let config = crate::common::temp_path("powercube-modes-devices.toml");
    std::fs::write(&config, "[device.arm]\nfamily = \"powercube\"\nport = \"sim\"\ntolerance = 0.01\n").unwrap();
    let env = [("MOTIONLINK_CONFIG", config.to_str().unwrap())];
    let o =
        crate::common::run_with(&["powercube", "--device", "arm", "motion", "fvel", "0.1", "--for-s", "0.1"], &env, "");
    assert_eq!(code(&o), 0, "{o:?}");
    assert!(String::from_utf8_lossy(&o.stdout).starts_with("FVEL_MODE ended with velocity 0"), "{o:?}");
    // A position mode's tolerance is said on the command line.
    let o = crate::common::run_with(
        &["powercube", "--device", "arm", "motion", "fstep", "0.1", "--time-ms", "500", "--tolerance", "0.01"],
        &env,
        "",
    );
    assert_eq!(code(&o), 0, "{o:?}");
    let _ = std::fs::remove_file(&config);
}
