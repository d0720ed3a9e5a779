//! The command-line conventions (issue 12) for PowerCube, through the binary.

use super::*;

// ----- the command-line conventions (issue 12), through the binary

/// Options before or after the action, negative numbers, JSON with the unit in the names, several parameters
/// in one `get`, `send` typed or as hex, `watch --count --csv`, JSON errors.
#[test]
pub(super) fn options_anywhere_json_send_get_and_watch_csv() {
    let sim = Sim::tcp("powercube");
    let p = sim.address.as_str();
    let run = |args: &[&str]| common::run_with(args, &[], "");
    let lines = |o: &Output| -> Vec<serde_json::Value> {
        assert!(o.status.success(), "{o:?}");
        String::from_utf8_lossy(&o.stdout).lines().map(|l| serde_json::from_str(l).unwrap()).collect()
    };
    assert!(run(&["powercube", "home", "--port", p]).status.success());
    let m =
        lines(&run(&["powercube", "move", "-0.1", "--vel", "1", "--acc", "2", "--json", "--port", p, "--no-watchdog"]));
    assert_eq!(
        (&m[0]["family"], &m[0]["module"], &m[0]["target_rad"]),
        (&"powercube".into(), &1.into(), &(-0.1f32 as f64).into())
    );
    assert!((m[0]["reached_rad"].as_f64().unwrap() + 0.1).abs() < 0.001, "{m:?}");
    let got = lines(&run(&["powercube", "get", "ActPos", "0x1d", "--port", p, "--json"]));
    assert_eq!((&got[0]["name"], &got[0]["unit"], &got[0]["access"]), (&"ActPos".into(), &"rad".into(), &"r".into()));
    assert_eq!(got[1]["id"], 0x1d);
    let set = lines(&run(&["powercube", "set", "TargetVel", "0.5", "--json", "--port", p]));
    assert_eq!(set[0]["name"], "TargetVel");

    let typed = String::from_utf8_lossy(&run(&["powercube", "send", "get", "ActPos", "--port", p]).stdout).into_owned();
    let hex = String::from_utf8_lossy(&run(&["powercube", "send", "0A", "3C", "--port", p]).stdout).into_owned();
    assert_eq!(typed, hex);
    assert!(typed.starts_with("-> 02 04 22 0A 3C 6C 03") && typed.contains("GetExtended ActPos"), "{typed}");
    assert!(
        typed.lines().nth(1).unwrap().starts_with("<- 02 08 26 0A 3C") && typed.contains("ActPos = -0.1"),
        "{typed}"
    );
    for refused in [&["send", "home"][..], &["send", "0B", "01"], &["send", "get", "Nope"]] {
        let o = run(&[&["powercube", "--port", p][..], refused].concat());
        assert_eq!(code(&o), 2, "{refused:?}: {o:?}");
    }
    // A telegram without its ETX: the message says what it lacks.
    let o = run(&["powercube", "--port", p, "send", "02", "04", "22", "0A", "3C", "6C"]);
    assert_eq!(code(&o), 2, "{o:?}");
    assert!(String::from_utf8_lossy(&o.stderr).contains("lacks its ETX (03)"), "{o:?}");

    let csv = String::from_utf8_lossy(
        &run(&["powercube", "watch", "--count", "2", "--csv", "--interval-ms", "10", "--port", p]).stdout,
    )
    .into_owned();
    let rows: Vec<&str> = csv.lines().collect();
    assert_eq!(rows[0], "t_s,module,position_rad,flags");
    assert_eq!(rows.len(), 3, "{csv}");
    assert!(rows[2].contains(",1,-0.1") && rows[2].contains("STATE_HOME_OK"), "{csv}");

    let o = run(&["powercube", "--port", p, "--json", "--module", "5", "--timeout-ms", "50", "get", "ActPos"]);
    let e = common::json_error(&o);
    assert_eq!((e["kind"].as_str(), e["exit_code"].as_i64(), code(&o)), (Some("timeout"), Some(3), 3), "{e}");
}

/// `-v` traces each telegram live; `--capture` writes a file `decode powercube` reads back; a candump log's
/// time stamps are kept; `--device` and MOTIONLINK_PORT give the port.
#[test]
pub(super) fn trace_capture_candump_and_where_the_port_comes_from() {
    let sim = Sim::tcp("powercube");
    let p = sim.address.as_str();
    let o = common::run_with(&["-v", "powercube", "get", "ActPos", "--port", p], &[], "");
    let trace = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(
        trace.lines().any(|l| l.contains("-> 02 04 22 0A 3C 6C 03") && l.contains("GetExtended ActPos")),
        "{trace}"
    );
    let o = common::run_with(&["-q", "powercube", "get", "ActPos", "--port", p], &[], "");
    assert!(o.status.success() && o.stderr.is_empty(), "{o:?}");

    let file = common::temp_path("powercube.capture");
    assert!(run(p, &["get", "ActPos", "--capture", file.to_str().unwrap()]).status.success());
    let captured = std::fs::read_to_string(&file).unwrap();
    let _ = std::fs::remove_file(&file);
    let first = captured.lines().nth(1).unwrap().to_string();
    assert!(first.ends_with(" -> 02 04 22 0A 3C 6C 03"), "{captured}");
    let text = String::from_utf8_lossy(&decode(&captured).stdout).into_owned();
    assert!(text.lines().any(|l| l.starts_with(&first) && l.contains("GetExtended ActPos")), "{text}");

    // candump: time stamps and interface kept; a frame that breaks the protocol is labelled in words.
    let text =
        String::from_utf8_lossy(&decode("(1700000000.000000) can0 0F1#01\n(1700000000.000100) can0 0B1#FF\n").stdout)
            .into_owned();
    let lines: Vec<&str> = text.lines().collect();
    assert!(lines[0].starts_with("(1700000000.000000) can0 0F1#01") && lines[0].contains("Home"), "{text}");
    assert!(lines[1].starts_with("(1700000000.000100) can0 0B1#FF") && lines[1].contains("!!"), "{text}");
    common::assert_no_debug_text("decode powercube", &text);

    let config = common::temp_path("powercube-devices.toml");
    std::fs::write(&config, format!("[device.arm]\nfamily = \"powercube\"\nport = \"{p}\"\n")).unwrap();
    let o = common::run_with(
        &["powercube", "get", "ActPos", "--device", "arm"],
        &[("MOTIONLINK_CONFIG", config.to_str().unwrap())],
        "",
    );
    assert!(String::from_utf8_lossy(&o.stdout).contains("ActPos"), "{o:?}");
    let _ = std::fs::remove_file(&config);
    let o = common::run_with(&["powercube", "get", "ActPos"], &[("MOTIONLINK_PORT", p)], "");
    assert!(String::from_utf8_lossy(&o.stdout).contains("ActPos"), "{o:?}");
}

/// `motionlink powercube watch | head -1` ends quietly with exit 0.
#[cfg(unix)]
#[test]
pub(super) fn watch_into_a_closed_pipe_ends_quietly_with_0() {
    let sim = Sim::tcp("powercube");
    let (line, ended) = common::head_1(&["powercube", "--port", &sim.address, "watch", "--interval-ms", "10"]);
    assert!(line.contains("0.0500"), "{line}");
    assert_eq!(ended.code(), 0, "{ended:?}");
    assert!(ended.stderr.is_empty(), "{ended:?}");
}

#[test]
pub(super) fn an_slcan_adapter_behind_a_tcp_port_is_reached_by_slcan_tcp() {
    // The emulated modules on CAN behind an emulated SLCAN adapter, served on TCP: `slcan://tcp://HOST:PORT`.
    let sim = Sim::start("powercube", &["--slcan", "--tcp", "127.0.0.1:0", "--modules", "1,17"]);
    let port = sim.address.clone();
    let found = ok(&port, &["scan"]);
    assert!(
        found.lines().filter(|l| l.trim_start().starts_with("1 ") || l.trim_start().starts_with("17 ")).count() == 2,
        "modules 1 and 17 found over CAN: {found}"
    );
    let moved = ok(&port, &["--module", "17", "move", "0.2"]);
    assert!(moved.contains("reached: position 0.2000"), "{moved}");
    // Never homed: the move says what that means.
    assert!(moved.contains("note: the module is not homed (STATE_HOME_OK clear)"), "{moved}");
    // A port behind slcan:// that is neither a device nor tcp:// is refused, saying why.
    let out = run("slcan://socketcan://can0", &["scan"]);
    assert_eq!(code(&out), 2, "a usage error: {out:?}");
    assert!(String::from_utf8_lossy(&out.stderr).contains("SLCAN adapter is on a serial device"), "{out:?}");
}

/// Every action's `--json` object has the keys it had before results were the library's reports (and
/// `home` the `verified` / `not_verifiable` a move has), nested the same way: a test against a served
/// emulator, the session of each command its own.
#[test]
fn every_json_result_keeps_its_keys() {
    let sim = Sim::tcp("powercube");
    let p = sim.address.as_str();
    let keys = |args: &[&str]| -> Vec<std::collections::BTreeSet<String>> {
        let out = ok(p, &[args, &["--json"]].concat());
        let objects = out.lines().map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap());
        objects.map(|o| o.as_object().unwrap().keys().cloned().collect()).collect()
    };
    let set = |names: &str| -> std::collections::BTreeSet<String> {
        names.split_whitespace().map(str::to_string).chain(["family".to_string()]).collect()
    };
    // `profile`: every command that opens a port says which device profile it took (null: none).
    let with_port = |names: &str| set(&format!("port profile module {names}"));
    let identity = "kind version serial state";
    let limits = "min_position_rad max_position_rad max_velocity_rad_per_s max_acceleration_rad_per_s2 position_rad";
    // A scan names no module, so it looks for no module's profile.
    assert_eq!(keys(&["scan"]), [set(&format!("port module {identity}"))]);
    assert_eq!(keys(&["info"]), [with_port(&format!("{identity} {limits}"))]);
    assert_eq!(keys(&["state"]), [with_port("word flags faults")]);
    assert_eq!(keys(&["get", "ActPos", "ActFPosStateDio"]), vec![with_port("name id value unit access"); 2]);
    let written = with_port("name id value ok read_back verified not_verifiable");
    assert_eq!(keys(&["set", "TargetVel", "0.5"]), [written]);
    let verified = "state verified not_verifiable";
    assert_eq!(keys(&["home"]), [with_port(&format!("action reached_rad {verified}"))]);
    // `homed`: whether the module showed STATE_HOME_OK at the end (its coordinates hold only after homing).
    let moved = format!("action target_rad reached_rad difference_rad homed {verified}");
    assert_eq!(keys(&["move", "0.1"]), [with_port(&moved)]);
    assert_eq!(keys(&["watch", "--count", "1"]), [with_port("t_s position_rad state")]);
    assert_eq!(keys(&["send", "get", "ActPos"]), [with_port("command request reply ok")]);
    assert_eq!(keys(&["stop"]), [with_port("ok action position_rad state holder")]);
    assert_eq!(keys(&["reset"]), [with_port("ok action watchdog_released")]);
    assert!(keys(&["params"]).iter().all(|k| *k == set("id name type unit access class description")));
    // Nested: the state word with its faults, the combined read's flag words.
    let state = ok(p, &["state", "--json"]);
    let moved: serde_json::Value = serde_json::from_str(ok(p, &["move", "0.2", "--json"]).trim()).unwrap();
    let nested: std::collections::BTreeSet<String> = moved["state"].as_object().unwrap().keys().cloned().collect();
    assert_eq!(nested, set("word flags faults").into_iter().filter(|k| k != "family").collect(), "{state}");
    let got: serde_json::Value = serde_json::from_str(ok(p, &["get", "ActFPosStateDio", "--json"]).trim()).unwrap();
    assert_eq!(got["value"]["short_state"]["flags"], serde_json::json!(["SHORT_RAMP_END"]), "{got}");
    assert!(got["value"]["dio"]["word"].is_number() && got["value"]["position"].is_number(), "{got}");
}
