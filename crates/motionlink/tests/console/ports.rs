//! Where the console's port comes from, as for every command (`--port`, `--device`, `MOTIONLINK_PORT`), the
//! options of a named device, and a console of several PowerCube modules (issue 20).

use std::time::Duration;

use serde_json::{json, Value};

use super::{console, console_with_env, of_type, recv_until, send, units};
use crate::common::temp_path;

const DEVICES: &str = r#"
[device.lift]
family = "scu"
port = "sim"
functions = "tlt"
tolerance = 3              # an option of `motionlink scu`: the console has none and leaves it

[device.arm]
family = "powercube"
port = "sim"
modules = [2, 5]
"#;

fn welcome(ws: &mut super::Ws) -> Value {
    recv_until(ws, Duration::from_secs(10), of_type("welcome")).expect("the welcome")
}

#[test]
fn the_console_takes_device_and_motionlink_port() {
    let path = temp_path("console-devices.toml");
    std::fs::write(&path, DEVICES).unwrap();
    let cfg = path.to_str().unwrap();
    // --device: its port (the TLT unit of `functions`: A1 alone is moved with F2), its options.
    let c = console_with_env(&["scu", "--device", "lift"], &[("MOTIONLINK_CONFIG", cfg)]);
    let mut ws = super::ws(&c);
    assert_eq!(welcome(&mut ws)["port"], "sim");
    let found = units(&mut ws);
    let details: Vec<&str> = found.iter().map(|u| u["detail"].as_str().unwrap()).collect();
    assert_eq!(details, ["moved and jogged with F2", "moved and jogged with F3"], "{found:?}");
    drop(c);
    // The file's modules, and the emulated bus has them.
    let c = console_with_env(&["powercube", "--device", "arm"], &[("MOTIONLINK_CONFIG", cfg)]);
    let mut ws = super::ws(&c);
    let found: Vec<u64> = units(&mut ws).iter().map(|u| u["module"].as_u64().unwrap()).collect();
    assert_eq!(found, [2, 5]);
    drop(c);
    // MOTIONLINK_PORT, without --port or --device.
    let c = console_with_env(&["compax"], &[("MOTIONLINK_PORT", "sim")]);
    let mut ws = super::ws(&c);
    assert_eq!(welcome(&mut ws)["port"], "sim");
    assert_eq!(units(&mut ws)[0]["drive"], 1);
    let _ = std::fs::remove_file(&path);
}

#[test]
fn the_console_of_three_modules_shows_and_moves_each() {
    // With the command line's --poll-ms (the session's settings by the same ModuleOptions).
    let c = console(&["powercube", "--port", "sim", "--modules", "1,2,3", "--poll-ms", "20"]);
    let mut ws = super::ws(&c);
    let found = units(&mut ws);
    let labels: Vec<&str> = found.iter().map(|u| u["label"].as_str().unwrap()).collect();
    assert_eq!(labels, ["module 1", "module 2", "module 3"], "{found:?}");
    // Every sample has the three.
    let s = recv_until(&mut ws, Duration::from_secs(10), of_type("sample")).expect("a sample");
    let sampled: Vec<u64> = s["units"].as_array().unwrap().iter().map(|u| u["module"].as_u64().unwrap()).collect();
    assert_eq!(sampled, [1, 2, 3], "{s}");
    // A move of module 2 moves module 2 alone.
    send(&mut ws, json!({"type": "move", "module": 2, "target_rad": 0.4, "velocity_rad_per_s": 1.0}));
    let done = recv_until(&mut ws, Duration::from_secs(20), |v| v["type"] == "motion" && v["state"] != "running")
        .expect("the move ends");
    assert_eq!((done["module"].as_u64(), done["ok"].as_bool()), (Some(2), Some(true)), "{done}");
    let s = recv_until(&mut ws, Duration::from_secs(5), of_type("sample")).expect("a sample after the move");
    let at = |m: u64| {
        s["units"].as_array().unwrap().iter().find(|u| u["module"] == m).unwrap()["position_rad"].as_f64().unwrap()
    };
    assert!((at(2) - 0.4).abs() < 0.01, "{s}");
    assert!((at(1) - 0.4).abs() > 0.1 && (at(3) - 0.4).abs() > 0.1, "the others stay: {s}");
}

#[test]
fn a_powercube_console_takes_poll_ms_by_its_rule() {
    let ended = crate::common::Running::start(&["console", "powercube", "--port", "sim", "--poll-ms", "0"])
        .wait(Duration::from_secs(10));
    assert_eq!(ended.code(), 2, "{ended:?}");
    assert!(ended.stderr.contains("--poll-ms") && !ended.stderr.contains("unexpected argument"), "{ended:?}");
}

#[test]
fn a_console_refused_by_a_busy_emulator_ends_with_one_line_and_exit_code_3() {
    use std::io::{Read, Write};
    // Each family with a request its emulator answers: the first client is served.
    let cases: [(&str, &[u8]); 3] = [
        ("scu", &[0x52, 0x4F, 0x00, 0x5C, 0x2D]),
        ("powercube", &[0x02, 0x04, 0x22, 0x0A, 0x1D, 0x4D, 0x03]),
        ("compax", b"1S1\r"),
    ];
    for (family, hello) in cases {
        let sim = crate::common::Sim::tcp(family);
        let mut first = std::net::TcpStream::connect(sim.address.strip_prefix("tcp://").unwrap()).unwrap();
        first.write_all(hello).unwrap();
        first.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
        first.read_exact(&mut [0u8; 1]).expect("the first client is served");
        // The console ends (a PowerCube or COMPAX console after printing its address: its scan is refused).
        let ended =
            crate::common::Running::start(&["console", family, "--port", &sim.address]).wait(Duration::from_secs(30));
        assert_eq!(ended.code(), 3, "{family}: {ended:?}");
        assert_eq!(
            ended.stderr,
            format!("motionlink: {} is busy: another client is connected", sim.address),
            "{family}: one line"
        );
    }
}

/// A console of a PowerCube module or a COMPAX drive takes the device profile `motionlink probe --save` wrote for
/// its port (issue 21: the console loads profiles as every command does), and says which on stderr.
#[test]
fn the_console_takes_the_saved_device_profile_in_every_family() {
    for (family, sim_args) in [("powercube", &["--modules", "1"][..]), ("compax", &["--drives", "1"][..])] {
        let mut args = vec!["--tcp", "127.0.0.1:0"];
        args.extend_from_slice(sim_args);
        let sim = crate::common::Sim::start(family, &args);
        let dir = temp_path(&format!("console-profile-{family}"));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let config = dir.join("devices.toml");
        let env = [("MOTIONLINK_CONFIG", config.to_str().unwrap())];
        let mut probe = vec!["probe", family, "--port", sim.address.as_str(), "--json", "--save"];
        if family == "compax" {
            probe.extend_from_slice(&["--drives", "1"]);
        }
        let out = crate::common::run_with(&probe, &env, "");
        assert!(out.status.success(), "{out:?}");
        let report: Value = serde_json::from_slice(&out.stdout).expect("the probe's JSON");
        let saved = report["saved"][0].as_str().expect("a saved profile").to_string();

        let c = console_with_env(&[family, "--port", sim.address.as_str()], &env);
        let line = c.running.stderr.wait_for(Duration::from_secs(20), |l| l.contains("profile: "));
        assert_eq!(line.as_deref(), Some(format!("profile: {saved}").as_str()), "{}", c.running.stderr.text());
        drop(c);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
