//! The command-line conventions (issue 12) for COMPAX, through the binary.

use super::*;

// ----- the command-line conventions (issue 12), through the binary

/// Options before or after the action, a negative number as a value (the README's `set P003 -1055.88`), JSON
/// names with the unit, several parameters in one `get`, `send` as text or hex, `watch --count --csv`, JSON
/// errors on stderr.
#[test]
pub(super) fn options_anywhere_json_send_get_and_watch_csv() {
    let sim = start_sim(&["--tcp", "127.0.0.1:0", "--drives", "1,5"]);
    let p = sim.address.as_str();
    let run = |args: &[&str]| common::run_with(args, &[], "");
    let o = run(&["compax", "set", "P003", "-1055.88", "--drive", "5", "--port", p]);
    assert!(o.status.success(), "{o:?}");
    let got: Vec<serde_json::Value> =
        stdout(&run(&["compax", "get", "P003", "P194", "--port", p, "--json", "--drive", "5"]))
            .lines()
            .map(|l| serde_json::from_str(l).unwrap())
            .collect();
    assert_eq!((&got[0]["name"], &got[0]["value"], &got[0]["drive"]), (&"P003".into(), &(-1055.88).into(), &5.into()));
    assert_eq!((&got[1]["name"], &got[1]["value"], &got[1]["family"]), (&"P194".into(), &5.0.into(), &"compax".into()));
    let m = json(&run(&["compax", "move", "--rel", "-0.5", "--port", p, "--json"]));
    assert_eq!((&m["target_units"], &m["reached_units"]), (&(-0.5).into(), &(-0.5).into()), "{m}");

    let text = stdout(&run(&["compax", "send", "S1", "--port", p]));
    let hex = stdout(&run(&["compax", "send", "53", "31", "--port", p]));
    assert_eq!(text, hex);
    let lines: Vec<&str> = text.lines().collect();
    assert!(lines[0].starts_with("-> 31 53 31 0D") && lines[0].contains("S1"), "{text}");
    assert!(lines[1].starts_with("<- ") && lines[1].contains("S1 (actual position) = -0.5"), "{text}");
    let sent = json(&run(&["compax", "send", "P194", "--json", "--drive", "5", "--port", p]));
    assert_eq!((&sent["command"], &sent["reply_text"]), (&"P194".into(), &"P194=5".into()), "{sent}");

    let csv = stdout(&run(&["compax", "watch", "--count", "3", "--csv", "--interval-ms", "10", "--port", p]));
    let rows: Vec<&str> = csv.lines().collect();
    assert_eq!(rows.len(), 4, "{csv}");
    assert_eq!(rows[0], "t_s,drive,position_units,moving,s17");
    assert!(rows[1].starts_with("0.") && rows[1].contains(",1,-0.5,false,"), "{csv}");
    let o = run(&["compax", "watch", "--count", "1", "--json", "--port", p]);
    assert_eq!(json(&o)["position_units"], -0.5);

    let o = run(&["compax", "get", "P13", "--port", p, "--json"]);
    let e = common::json_error(&o);
    assert_eq!(
        (e["kind"].as_str(), e["exit_code"].as_i64(), o.status.code()),
        (Some("refused"), Some(1), Some(1)),
        "{e}"
    );
    assert!(e["message"].as_str().unwrap().contains("E90"), "{e}");
    // The drive's number as data: a number, not a word of bits.
    assert_eq!((&e["code"], &e["bits"]), (&90.into(), &serde_json::json!([])), "{e}");
}

/// `-v` traces each telegram live; `--capture` writes a file `decode compax` reads back; `--device` and
/// MOTIONLINK_PORT give the port.
#[test]
pub(super) fn trace_capture_and_where_the_port_comes_from() {
    let sim = start_sim(&["--tcp", "127.0.0.1:0"]);
    let p = sim.address.as_str();
    let o = common::run_with(&["-v", "compax", "get", "P194", "--port", p], &[], "");
    let trace = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(trace.lines().any(|l| l.contains("-> 31 50 31 39 34 0D") && l.contains("P194")), "{trace}");
    assert!(trace.lines().any(|l| l.contains("<- ") && l.contains("P194=1")), "{trace}");
    let o = common::run_with(&["-q", "compax", "get", "P194", "--port", p], &[], "");
    assert!(o.status.success() && o.stderr.is_empty(), "{o:?}");

    let file = common::temp_path("compax.capture");
    let o = compax(p, &["get", "P194", "--capture", file.to_str().unwrap()]);
    assert!(o.status.success(), "{o:?}");
    let captured = std::fs::read_to_string(&file).unwrap();
    let _ = std::fs::remove_file(&file);
    assert!(captured.lines().nth(1).unwrap().contains(") -> 31 50 31 39 34 0D"), "{captured}");
    let text = stdout(&common::run_with(&["decode", "compax"], &[], &captured));
    std::fs::write(&file, &captured).unwrap();
    let from_file = stdout(&common::run_with(&["decode", "compax", "--input", file.to_str().unwrap()], &[], ""));
    let _ = std::fs::remove_file(&file);
    assert_eq!(from_file, text);
    assert!(text.lines().any(|l| l.starts_with('(') && l.contains(" -> ") && l.contains("P194")), "{text}");
    assert!(text.lines().any(|l| l.starts_with('(') && l.contains(" <- ") && l.contains("P194=1")), "{text}");
    common::assert_no_debug_text("decode compax", &text);

    let config = common::temp_path("compax-devices.toml");
    std::fs::write(&config, format!("[device.axis]\nfamily = \"compax\"\nport = \"{p}\"\n")).unwrap();
    let o = common::run_with(
        &["compax", "--device", "axis", "get", "P194"],
        &[("MOTIONLINK_CONFIG", config.to_str().unwrap())],
        "",
    );
    assert!(stdout(&o).contains("P194"), "{o:?}");
    let o = common::run_with(&["compax", "get", "P194"], &[("MOTIONLINK_PORT", p)], "");
    assert!(stdout(&o).contains("P194"), "{o:?}");
    // A device of another family is refused, naming it.
    std::fs::write(&config, format!("[device.lift]\nfamily = \"scu\"\nport = \"{p}\"\n")).unwrap();
    let o = common::run_with(
        &["compax", "--device", "lift", "get", "P194"],
        &[("MOTIONLINK_CONFIG", config.to_str().unwrap())],
        "",
    );
    assert_eq!(o.status.code(), Some(2), "{o:?}");
    let _ = std::fs::remove_file(&config);
}

/// `motionlink compax watch | head -1` ends quietly with exit 0.
#[cfg(unix)]
#[test]
pub(super) fn watch_into_a_closed_pipe_ends_quietly_with_0() {
    let sim = start_sim(&["--tcp", "127.0.0.1:0"]);
    let (line, ended) = common::head_1(&["compax", "--port", &sim.address, "watch", "--interval-ms", "10"]);
    assert!(line.contains("S1 = 0"), "{line}");
    assert_eq!(ended.code(), 0, "{ended:?}");
    assert!(ended.stderr.is_empty(), "{ended:?}");
}
