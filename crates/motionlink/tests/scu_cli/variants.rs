//! The core commands against every firmware variant of `motionlink sim scu --variant X` (a unit that does what
//! the manual leaves open the other plausible way), through the built binary over TCP: each works and says in
//! `verified` / `not_verifiable` what it could not check, or ends with an error naming what the unit did not
//! do. The emulated actuators are fast (2000 counts/s) and the variants run side by side, so the matrix takes
//! a few seconds.

use std::process::Output;
use std::time::Duration;

use super::{scu, stdout};
use crate::common::{self, Sim};

/// Every variant `motionlink sim scu --variant` knows (the library's list: a new one fails this test until
/// it is added here with what it changes).
const VARIANTS: [&str; 14] = [
    "no-groups",
    "no-user-positions",
    "no-cyclic-objects",
    "no-remote-readback",
    "rc-empty-data",
    "sleepy",
    "sticky-errors",
    "in-end-undershoot",
    "re-needs-rs",
    "late-motion-bit",
    "switch-status-unshown",
    // Both show only after a watchdog lapse or with an error standing, which the core commands meet on no
    // unit: they run here as on the plain unit (their own tests: the library's sim and client_moves).
    "ack-without-motion",
    "rc-rearms-watchdog",
    // Served, it could not be woken (no break crosses TCP): refused there, run with `--port sim` below.
    "low-power",
];

const FAST: &str = "[[actuator]]\ncounts_per_second_at_full_speed = 2000.0\nramp_ms = 30\n\
                    [[actuator]]\ncounts_per_second_at_full_speed = 2000.0\nramp_ms = 30\n";

fn fast_config() -> std::path::PathBuf {
    let path = common::temp_path("scu-fast.toml");
    std::fs::write(&path, FAST).expect("write the emulator configuration");
    path
}

/// One JSON object from a command that succeeded.
fn ok_json(what: &str, o: &Output) -> serde_json::Value {
    assert!(o.status.success(), "{what}: {o:?}");
    serde_json::from_str(stdout(o).trim()).unwrap_or_else(|e| panic!("{what}: not one JSON object ({e}): {o:?}"))
}

/// The core commands on a unit of `variant` ("" for none); returns what `move` said it could not verify.
fn core_commands(variant: &str, config: &str) -> Vec<String> {
    let mut args = vec!["--config", config, "--tcp", "127.0.0.1:0"];
    if !variant.is_empty() {
        args.extend(["--variant", variant]);
    }
    let sim = Sim::start("scu", &args);
    let port = sim.address.as_str();
    let run = |words: &[&str]| -> Output {
        let mut all = vec!["--functions", "scp11", "--json"];
        all.extend_from_slice(words);
        scu(port, &all)
    };
    let info = ok_json("info", &run(&["info"]));
    assert_eq!(info["actuators"].as_array().map(Vec::len), Some(2), "{variant}: {info}");
    let got = ok_json("get", &run(&["get", "actual_positions"]));
    assert_eq!(got["value"].as_object().map(|m| m.len()), Some(6), "{variant}: {got}");
    let set = ok_json("set", &run(&["set", "remote_speed_f2", "60"]));
    let readback = variant != "no-remote-readback";
    assert_eq!(set["verified"], readback, "{variant}: {set}");
    assert_eq!(set["read_back"].is_null(), !readback, "{variant}: {set}");
    let moved = ok_json("move", &run(&["move", "1", "400", "--speed", "80"]));
    assert_eq!((moved["reached_counts"].as_i64(), moved["difference_counts"].as_i64()), (Some(400), Some(0)));
    let why: Vec<String> = serde_json::from_value(moved["not_verifiable"].clone()).expect("a list of reasons");
    assert_eq!(moved["verified"], why.is_empty(), "{variant}: {moved}");
    let plain = ok_json("move without --speed", &run(&["move", "2", "300"]));
    assert_eq!(plain["reached_counts"], 300, "{variant}: {plain}");
    assert_eq!(plain["verified"], moved["verified"], "{variant}: {plain}");
    // `run` says that the function runs, then how it ended: the last line.
    let home = run(&["run", "F1", "in"]);
    assert!(home.status.success(), "{variant}: {home:?}");
    let home: serde_json::Value = serde_json::from_str(stdout(&home).lines().last().unwrap_or_default()).expect("JSON");
    let rest = home["actuators"][0]["reached_counts"].as_i64();
    assert_eq!(rest, Some(if variant == "in-end-undershoot" { -3 } else { 0 }), "{variant}: {home}");
    let stopped = ok_json("stop", &run(&["stop", "F1"]));
    assert_eq!(stopped["stopped"], true);
    // A switching function: binary output 2, read back after the RE and the RS where the unit shows it.
    let switched = run(&["run", "F18", "on", "--seconds", "0.1"]);
    assert!(switched.status.success(), "{variant}: {switched:?}");
    let switched: serde_json::Value =
        serde_json::from_str(stdout(&switched).lines().last().unwrap_or_default()).expect("JSON");
    assert_eq!(switched["verified"], variant != "switch-status-unshown", "{variant}: {switched}");
    let watched = run(&["watch", "--count", "2", "--interval-ms", "100"]);
    assert!(watched.status.success(), "{variant}: {watched:?}");
    let samples: Vec<serde_json::Value> =
        stdout(&watched).lines().map(|l| serde_json::from_str(l).expect("one JSON object a line")).collect();
    assert_eq!(samples.len(), 2, "{variant}: {watched:?}");
    assert_eq!(samples[1]["actuators"][1]["position_counts"], 300, "{variant}: {samples:?}");
    // The text of a move ends with one line that says what was verified.
    let text = scu(port, &["--functions", "scp11", "move", "1", "100"]);
    assert!(text.status.success(), "{variant}: {text:?}");
    let last = stdout(&text).lines().last().unwrap_or_default().to_string();
    let expected = if why.is_empty() { "verified  yes".to_string() } else { format!("verified  no: {}", why[0]) };
    assert!(last.starts_with(&expected), "{variant}: {last:?}");
    why
}

#[test]
fn the_core_commands_work_on_every_firmware_variant_and_say_what_they_could_not_verify() {
    let config = fast_config();
    let config = config.to_str().expect("a UTF-8 temporary path").to_string();
    let all: Vec<&str> = std::iter::once("").chain(VARIANTS).filter(|v| *v != "low-power").collect();
    let results: Vec<(String, Vec<String>)> = std::thread::scope(|s| {
        let handles: Vec<_> = all
            .iter()
            .map(|v| {
                let config = config.clone();
                s.spawn(move || (v.to_string(), core_commands(v, &config)))
            })
            .collect();
        handles.into_iter().map(|h| h.join().expect("a variant's commands")).collect()
    });
    for (variant, why) in results {
        let expected: &[&str] = match variant.as_str() {
            "no-user-positions" => &["A1's target was not checked against a stroke: the unit refuses UserPositionData"],
            "no-remote-readback" => &["remote_position_a1 (0x3021), remote_speed_f1 (0x3011) written"],
            _ => &[],
        };
        assert_eq!(why.len(), expected.len(), "{variant}: {why:?}");
        for (w, e) in why.iter().zip(expected) {
            assert!(w.starts_with(e), "{variant}: {w:?}");
        }
    }
}

#[test]
fn variants_combine_in_the_configuration_and_on_the_command_line_and_unknown_names_are_refused() {
    let path = common::temp_path("scu-variants.toml");
    std::fs::write(&path, format!("variants = [\"no-user-positions\"]\n{FAST}")).expect("write the configuration");
    let config = path.to_str().expect("a UTF-8 temporary path");
    let sim =
        Sim::start("scu", &["--config", config, "--variant", "no-remote-readback,no-groups", "--tcp", "127.0.0.1:0"]);
    let moved = ok_json("move", &scu(&sim.address, &["--json", "--functions", "scp11", "move", "1", "200"]));
    assert_eq!(moved["not_verifiable"].as_array().map(Vec::len), Some(2), "{moved}");
    // Unknown names: a usage error that lists the known ones, before anything listens.
    let out = std::process::Command::new(common::BIN)
        .args(["sim", "scu", "--variant", "no-group", "--tcp", "127.0.0.1:0"])
        .output()
        .expect("run motionlink sim scu");
    assert_eq!(out.status.code(), Some(2), "{out:?}");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("\"no-group\"") && VARIANTS.iter().all(|v| err.contains(v)), "{err}");
    let bad = scu("sim", &["--sim-variant", "nope", "info"]);
    assert_eq!(bad.status.code(), Some(2), "{bad:?}");
    let bad = scu("tcp://127.0.0.1:9", &["--sim-variant", "sleepy", "info"]);
    assert_eq!(bad.status.code(), Some(2), "--sim-variant is only for --port sim: {bad:?}");
    // `--help` lists every variant with what it does, from the library's list, in every family.
    use motionlink_link::emulator::FirmwareVariant;
    let help = |family: &str| {
        let out = std::process::Command::new(common::BIN).args(["sim", family, "--help"]).output().expect("run");
        String::from_utf8_lossy(&out.stdout).split_whitespace().collect::<Vec<_>>().join(" ")
    };
    let lists = |text: &str, names: Vec<(&str, &str)>| {
        let said = |d: &str| d.split_whitespace().collect::<Vec<_>>().join(" ");
        names.iter().all(|(n, d)| text.contains(&format!("- {n}:")) && text.contains(&said(d)))
    };
    let text = help("scu");
    assert!(lists(&text, motionlink_scu::Variant::ALL.iter().map(|v| (v.name(), v.description())).collect()), "{text}");
    let text = help("powercube");
    let powercube = motionlink_powercube::sim::Variant::ALL.iter().map(|v| (v.name(), v.description())).collect();
    assert!(lists(&text, powercube), "{text}");
    let text = help("compax");
    let compax = motionlink_compax::sim::Variant::ALL.iter().map(|v| (v.name(), v.description())).collect();
    assert!(lists(&text, compax), "{text}");
}

#[test]
fn the_in_process_emulator_takes_variants_too() {
    let config = fast_config();
    let config = config.to_str().expect("a UTF-8 temporary path");
    let args = ["--json", "--sim-config", config, "--sim-variant", "no-user-positions", "move", "1", "300"];
    let started = std::time::Instant::now();
    let moved = ok_json("move", &scu("sim", &args));
    assert_eq!((moved["reached_counts"].as_i64(), moved["verified"].as_bool()), (Some(300), Some(false)), "{moved}");
    // Without a stroke to check the target against, the unit's own end stops the actuator: the move did not
    // end at its target, and that is exit 1, never 0.
    let args = ["--sim-config", config, "--sim-variant", "no-user-positions", "move", "1", "900"];
    let missed = scu("sim", &args);
    assert_eq!(missed.status.code(), Some(1), "{missed:?}");
    let err = String::from_utf8_lossy(&missed.stderr);
    assert!(err.contains("A1 ended at 865 counts") && err.contains("target 900"), "{err}");
    assert!(started.elapsed() < Duration::from_secs(10));
}

/// A battery unit in low-power mode answers nothing until a break wakes it: without `--wake` the command
/// says the unit does not answer and names `--wake`; with it the command runs. Served on TCP, which carries
/// no break, such a unit is refused; `--wake` on a TCP port is refused naming why.
#[test]
fn a_unit_in_low_power_mode_answers_once_woken_with_wake() {
    let asleep = scu("sim", &["--sim-variant", "low-power", "--timeout-ms", "300", "info"]);
    let err = String::from_utf8_lossy(&asleep.stderr);
    assert_eq!(asleep.status.code(), Some(3), "{err}");
    assert!(err.contains("low-power mode answers only once woken: --wake"), "{err}");
    let woken = scu("sim", &["--sim-variant", "low-power", "--wake", "info"]);
    assert!(woken.status.success(), "{woken:?}");
    assert!(stdout(&woken).contains("SCU V2B3 motionlink-sim"), "{woken:?}");
    let served = common::run_with(&["sim", "scu", "--tcp", "127.0.0.1:0", "--variant", "low-power"], &[], "");
    assert_eq!(served.status.code(), Some(2), "{served:?}");
    assert!(String::from_utf8_lossy(&served.stderr).contains("woken only by a break"), "{served:?}");
    let sim = Sim::start("scu", &["--tcp", "127.0.0.1:0"]);
    let tcp = scu(&sim.address, &["--wake", "info"]);
    assert_eq!(tcp.status.code(), Some(2), "{tcp:?}");
    assert!(String::from_utf8_lossy(&tcp.stderr).contains("can only be sent on a serial device"), "{tcp:?}");
}
