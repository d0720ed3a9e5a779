//! The command-line conventions (issue 12) for the SCU, through the binary.

use super::*;

// ----- the command-line conventions (issue 12), through the binary

/// Options before or after the action, negative numbers without `--`, JSON errors on stderr.
#[test]
pub(super) fn options_go_anywhere_and_errors_come_as_json() {
    let sim = sim_tcp();
    let p = sim.address.as_str();
    let run = |args: &[&str]| common::run_with(args, &[], "");
    let after = json(&run(&["scu", "get", "actual_position_a1", "--json", "--port", p, "--baud", "38400"]));
    let before = json(&run(&["--json", "scu", "--port", p, "get", "actual_position_a1"]));
    assert_eq!(after, before);
    assert_eq!(
        (&after["family"], &after["port"], &after["name"], &after["id"], &after["unit"], &after["access"]),
        (&"scu".into(), &p.into(), &"actual_position_a1".into(), &0x11.into(), &"counts".into(), &"r".into())
    );
    // -3 is a number, not an option: refused by the stroke check (exit 2, naming it), not by the parser.
    let out = run(&["scu", "move", "1", "-3", "--port", p, "--json"]);
    let e = common::json_error(&out);
    assert_eq!((e["kind"].as_str(), e["exit_code"].as_i64(), out.status.code()), (Some("usage"), Some(2), Some(2)));
    assert!(e["message"].as_str().unwrap().contains("target -3 counts"), "{e}");
    // A parse error with --json anywhere is the same object.
    let e = common::json_error(&run(&["scu", "get", "--port", p, "--json"]));
    assert_eq!((e["kind"].as_str(), e["exit_code"].as_i64()), (Some("usage"), Some(2)), "{e}");
    // A transport error: kind and exit code of its class.
    let e = common::json_error(&run(&["scu", "--port", "tcp://127.0.0.1:1", "info", "--json"]));
    // A refused connection is an I/O failure of the opening (a unit that stops answering is "timeout", a
    // link that goes away "disconnected": python/tests/test_errors.py).
    assert_eq!((e["kind"].as_str(), e["exit_code"].as_i64()), (Some("io"), Some(3)), "{e}");
    assert!(e["message"].as_str().unwrap().starts_with("cannot open tcp://127.0.0.1:1"), "{e}");
}

/// `--json` on run, stop and decode; several names in one `get`; `names`; `send`; `watch --count --csv`.
#[test]
pub(super) fn every_action_speaks_json_and_send_names_get_watch_csv() {
    let sim = sim_tcp();
    let p = sim.address.as_str();
    let lines = |o: &Output| -> Vec<serde_json::Value> {
        assert!(o.status.success(), "{o:?}");
        stdout(o).lines().map(|l| serde_json::from_str(l).expect("a JSON line")).collect()
    };
    let run = lines(&scu(p, &["run", "F11", "on", "--seconds", "0.2", "--json"]));
    assert_eq!((run.len(), &run[0]["running"], &run[1]["stopped"]), (2, &true.into(), &true.into()), "{run:?}");
    assert_eq!(run[1]["function"], 11);
    // Its status read back after the RE and after the RS.
    assert_eq!((&run[0]["verified"], &run[1]["verified"]), (&true.into(), &true.into()), "{run:?}");
    assert_eq!(run[1]["not_verifiable"], serde_json::json!([]), "{run:?}");
    let follow = lines(&common::run_with(&["scu", "--port", p, "follow", "1", "--json"], &[], "120\n"));
    assert_eq!((&follow[0]["following"], &follow[1]["targets"][0]["target_counts"]), (&true.into(), &120.into()));
    assert_eq!(follow.last().unwrap()["stopped"], true, "{follow:?}");
    let stop = lines(&scu(p, &["stop", "F1", "--soft", "--json"]));
    assert_eq!((&stop[0]["function"], &stop[0]["mode"]), (&1.into(), &"soft".into()));
    let out =
        common::run_with(&["decode", "scu", "--json"], &[], "52 47 11 00 2C 30\n52 47 06 04 00 90 01 00 00 A3 AD\n");
    let decoded = lines(&out);
    assert_eq!((&decoded[0]["direction"], &decoded[1]["direction"]), (&"->".into(), &"<-".into()));
    assert!(decoded[1]["meaning"].as_str().unwrap().contains("400 counts"), "{decoded:?}");
    // A stray `R` and a letter no command has, then two whole telegrams at the end of the capture: the stray
    // bytes are bad, the telegrams after them are found.
    let out = common::run_with(&["decode", "scu", "--json"], &[], "52 58 52 47 11 00 2C 30 52 47 11 00 2C 30\n");
    let decoded = lines(&out);
    let shown: Vec<(bool, &str)> =
        decoded.iter().map(|d| (d["bad"].as_bool().unwrap(), d["bytes"].as_str().unwrap())).collect();
    assert_eq!(shown, [(true, "52 58"), (false, "52 47 11 00 2C 30"), (false, "52 47 11 00 2C 30")], "{decoded:?}");

    let got = lines(&scu(p, &["get", "actual_position_a1", "remote_speed_f1", "0x0012", "--json"]));
    let names: Vec<&str> = got.iter().map(|v| v["name"].as_str().unwrap()).collect();
    assert_eq!(names, ["actual_position_a1", "remote_speed_f1", "actual_position_a2"]);
    assert_eq!(got[1]["access"], "rw");
    let text = stdout(&scu(p, &["get", "actual_position_a1", "actual_position_a2"]));
    assert_eq!(text.lines().count(), 2, "{text}");

    let names = stdout(&common::run_with(&["scu", "names"], &[], ""));
    assert!(names.lines().any(|l| l.starts_with("actual_position_a1") && l.contains("0x0011")), "{names}");
    assert!(names.lines().any(|l| l.starts_with("remote_positions")), "{names}");

    // send: typed, and the same telegram as hex; each line the telegram and its meaning.
    let typed = stdout(&scu(p, &["send", "RG", "actual_position_a1"]));
    let hex = stdout(&scu(p, &["send", "52 47 11 00 2C 30"]));
    assert_eq!(typed, hex);
    assert!(typed.starts_with("-> 52 47 11 00 2C 30"), "{typed}");
    // `follow` above went to its last target, 120, before it ended.
    assert!(
        typed.lines().nth(1).unwrap().starts_with("<- 52 47 06 04 00") && typed.contains("= 120 counts"),
        "{typed}"
    );
    let sent = lines(&scu(p, &["send", "RT", "remote_speed_f1", "55", "--json"]));
    assert_eq!((&sent[0]["command"], &sent[0]["ok"]), (&"RT".into(), &true.into()), "{sent:?}");
    assert_eq!(json(&scu(p, &["get", "remote_speed_f1", "--json"]))["value"], 55);
    // A function an RE of `send` starts is stopped (RS) when the command ends.
    let t0 = unix_now();
    let re = stdout(&scu(p, &["send", "RE", "F1", "out"]));
    assert!(re.starts_with("-> 52 45 00 02 FF") && re.contains("RE ACK"), "{re}");
    assert!(
        sim.wait_event_after(t0, Duration::from_secs(5), |e| e == "F1 stopped (RS fast)").is_some(),
        "{:?}",
        sim.events()
    );
    for refused in [&["send", "RO", "0"][..], &["send", "52 47 11 00 2C 31"], &["send", "RG", "nope"]] {
        assert_eq!(scu(p, refused).status.code(), Some(2), "{refused:?}");
    }

    let csv = stdout(&scu(p, &["watch", "--count", "2", "--csv", "--interval-ms", "10"]));
    let rows: Vec<&str> = csv.lines().collect();
    assert_eq!(rows[0], "t_s,actuator,position_counts,moving,current_amps,last_error_code");
    assert_eq!(rows.len(), 1 + 2 * 2, "two samples of two actuators: {csv}");
    assert!(rows[1].split(',').nth(1) == Some("1") && rows[2].split(',').nth(1) == Some("2"), "{csv}");
}

/// `-v` prints each telegram live with time, direction, hex and meaning; `-q` only errors; `--capture` writes
/// a file that `decode` reads back with its time stamps and direction marks; bad frames are labelled plainly.
#[test]
pub(super) fn wire_trace_quiet_and_capture_read_back_by_decode() {
    let sim = sim_tcp();
    let p = sim.address.as_str();
    let out = common::run_with(&["scu", "get", "actual_position_a1", "-v", "--port", p], &[], "");
    let trace = String::from_utf8_lossy(&out.stderr).into_owned();
    let line = trace.lines().find(|l| l.contains("-> 52 47 11 00 2C 30")).unwrap_or_else(|| panic!("{trace}"));
    let stamp = line.split_whitespace().next().unwrap();
    assert!(stamp.len() == 15 && stamp.as_bytes()[2] == b':' && stamp.as_bytes()[8] == b'.', "{line}");
    assert!(line.contains("RG") && line.contains("actual_position_a1"), "{line}");
    assert!(trace.lines().any(|l| l.contains("<- 52 4F 06") && l.contains("RO ACK")), "{trace}");
    // With --json, stderr is JSON lines too: the trace one telegram per line (an error would come last).
    let out = common::run_with(&["-v", "scu", "--port", p, "--json", "get", "actual_position_a1"], &[], "");
    let err: Vec<serde_json::Value> = String::from_utf8_lossy(&out.stderr)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("{e}: {l}")))
        .collect();
    assert!(err.iter().any(|v| v["trace"]["bytes"] == "52 47 11 00 2C 30" && v["trace"]["time_s"].is_f64()), "{err:?}");
    assert!(err.iter().all(|v| v["trace"]["direction"].is_string()), "{err:?}");
    let out = common::run_with(&["-q", "scu", "--port", p, "get", "actual_position_a1"], &[], "");
    assert!(out.status.success() && out.stderr.is_empty() && !out.stdout.is_empty(), "{out:?}");
    let out = common::run_with(&["-q", "scu", "--port", p, "get", "nope"], &[], "");
    assert!(String::from_utf8_lossy(&out.stderr).contains("nope"), "an error still shows with -q: {out:?}");

    let file = common::temp_path("scu.capture");
    let path = file.to_str().unwrap();
    let out = scu(p, &["--capture", path, "get", "actual_position_a1"]);
    assert!(out.status.success(), "{out:?}");
    let captured = std::fs::read_to_string(&file).unwrap();
    let _ = std::fs::remove_file(&file);
    assert!(captured.starts_with(&format!("# motionlink capture: scu on {p}\n")), "{captured}");
    let now = common::unix_now();
    let first = captured.lines().nth(1).unwrap();
    let t: f64 = first[1..first.find(')').unwrap()].parse().unwrap();
    assert!((now - t).abs() < 60.0 && first.contains(") -> 52 4F 00"), "{first}");
    // Read back: every line keeps its stamp and mark and gains its meaning; a corrupted reply is labelled.
    let input = format!("{captured}(1732470000.000001) <- 52 47 06 04 00 90 01 00 00 A3 AE\n");
    let out = common::run_with(&["decode", "scu"], &[], &input);
    let text = stdout(&out);
    assert!(text.lines().any(|l| l.starts_with(first) && l.contains("RO")), "{text}");
    assert!(text.lines().any(|l| l.contains(") -> 52 47 11 00 2C 30") && l.contains("actual_position_a1")), "{text}");
    let bad = text.lines().last().unwrap();
    assert!(bad.starts_with("(1732470000.000001) !! 52 47 06"), "{bad}");
    common::assert_no_debug_text("decode scu", &text);
}

/// The port from `--device` (the configuration file) or MOTIONLINK_PORT; `--port` wins over both.
#[test]
pub(super) fn the_port_comes_from_device_or_environment() {
    let sim = sim_tcp();
    let config = common::temp_path("scu-devices.toml");
    std::fs::write(&config, format!("[device.lift]\nfamily = \"scu\"\nport = \"{}\"\n", sim.address)).unwrap();
    let cfg = config.to_str().unwrap();
    let get = ["scu", "get", "firmware_info"];
    let by_device = common::run_with(&[&get[..], &["--device", "lift"]].concat(), &[("MOTIONLINK_CONFIG", cfg)], "");
    assert!(stdout(&by_device).contains("SCU"), "{by_device:?}");
    let by_env = common::run_with(&get, &[("MOTIONLINK_PORT", &sim.address)], "");
    assert!(stdout(&by_env).contains("SCU"), "{by_env:?}");
    let port_wins =
        common::run_with(&[&get[..], &["--port", &sim.address]].concat(), &[("MOTIONLINK_PORT", "nowhere")], "");
    assert!(port_wins.status.success(), "{port_wins:?}");
    let unknown = common::run_with(&[&get[..], &["--device", "arm"]].concat(), &[("MOTIONLINK_CONFIG", cfg)], "");
    assert_eq!(unknown.status.code(), Some(2), "{unknown:?}");
    assert!(String::from_utf8_lossy(&unknown.stderr).contains("arm"), "{unknown:?}");
    let none = common::run_with(&get, &[], "");
    assert_eq!(none.status.code(), Some(2), "{none:?}");
    let _ = std::fs::remove_file(&config);
}

/// `motionlink scu watch | head -1`: the watch ends quietly with exit 0 when its reader goes away, and the
/// session is closed (RA) first.
#[test]
pub(super) fn watch_into_a_closed_pipe_ends_quietly_with_0() {
    let sim = sim_tcp();
    let t0 = unix_now();
    let (line, ended) = common::head_1(&["scu", "--port", &sim.address, "watch", "--interval-ms", "10"]);
    assert!(line.contains("A1:"), "{line}");
    assert_eq!(ended.code(), 0, "{ended:?}");
    assert!(ended.stderr.is_empty(), "{ended:?}");
    assert!(
        sim.wait_event_after(t0, Duration::from_secs(5), |e| e == "remote mode closed by RA").is_some(),
        "{:?}",
        sim.events()
    );
}

/// Every `--json` result of the SCU, key for key (nested objects too; a list by its first element): the
/// library's reports serialise with the names the command line has always printed.
#[test]
pub(super) fn every_json_result_keeps_its_keys() {
    use serde_json::json;
    use std::collections::BTreeMap;
    /// The keys of a JSON value, recursively.
    fn shape(v: &serde_json::Value) -> serde_json::Value {
        match v {
            serde_json::Value::Object(m) => {
                serde_json::to_value(m.iter().map(|(k, v)| (k.clone(), shape(v))).collect::<BTreeMap<_, _>>()).unwrap()
            }
            serde_json::Value::Array(a) if a.first().is_some_and(|x| x.is_object()) => json!([shape(&a[0])]),
            _ => json!(null),
        }
    }
    let lines = |args: &[&str], stdin: &str| -> Vec<serde_json::Value> {
        let mut all = vec!["scu", "--port", "sim", "--json"];
        all.extend_from_slice(args);
        let o = common::run_with(&all, &[], stdin);
        assert!(o.status.success(), "{args:?}: {o:?}");
        stdout(&o).lines().map(|l| shape(&serde_json::from_str(l).expect("a JSON line"))).collect()
    };
    let keys = |spec: &str| -> serde_json::Value {
        // "a b{c d} e[f]": a, b an object of c and d, e a list of objects of f.
        fn parse(words: &mut std::iter::Peekable<std::str::Chars<'_>>) -> serde_json::Value {
            let mut map = BTreeMap::new();
            let mut name = String::new();
            while let Some(c) = words.next() {
                match c {
                    '{' | '[' => {
                        let inner = parse(words);
                        map.insert(std::mem::take(&mut name), if c == '[' { json!([inner]) } else { inner });
                    }
                    '}' | ']' => break,
                    ' ' => {
                        if !name.is_empty() {
                            map.insert(std::mem::take(&mut name), json!(null));
                        }
                    }
                    c => name.push(c),
                }
            }
            if !name.is_empty() {
                map.insert(name, json!(null));
            }
            serde_json::to_value(map).unwrap()
        }
        parse(&mut spec.chars().peekable())
    };
    let state = "actuator position_counts word flags moving";
    let error_code = "code bits";
    assert_eq!(
        lines(&["info"], ""),
        [keys(&format!(
            "family port profile firmware configuration battery_mains{{word flags}} last_error{{{error_code}}} actuators[{state}]"
        ))]
    );
    let entry = "family port profile name id value unit access";
    assert_eq!(
        lines(&["get", "actual_position_a1", "actual_positions", "battery_mains"], ""),
        [keys(entry), keys(&format!("{entry} value{{actual_position_a1 actual_position_a2 actual_position_a3 actual_position_a4 actual_position_a5 actual_position_a6}}")), keys(&format!("{entry} value{{word flags}}"))]
    );
    assert_eq!(
        lines(&["set", "remote_speed_f1", "80"], ""),
        [keys("family port profile name id value unit access read_back verified not_verifiable")]
    );
    let outcome = "actuator target_counts reached_counts difference_counts moved";
    assert_eq!(
        lines(&["move", "1", "30"], ""),
        [keys(&format!(
            "family port profile actuator function reached_counts target_counts difference_counts time_s verified \
             not_verifiable actuators[{outcome}]"
        ))]
    );
    assert_eq!(
        lines(&["run", "2", "out", "--seconds", "0.1"], ""),
        [
            keys("family port profile function running"),
            keys("family port profile function stopped interrupted actuators[actuator reached_counts]")
        ]
    );
    let stop = "family port profile action stopped holder functions mode refused at_rest[actuator position_counts]";
    assert_eq!(lines(&["stop"], ""), [keys(stop)]);
    assert_eq!(lines(&["stop", "F1", "--soft"], ""), [keys(&format!("{stop} function"))]);
    assert_eq!(
        lines(&["stop", "F11"], ""),
        [keys("family port profile action stopped holder function mode verified not_verifiable")]
    );
    assert_eq!(
        lines(&["run", "F11", "on", "--seconds", "0.1"], ""),
        [
            keys("family port profile function running verified"),
            keys(
                "family port profile function stopped interrupted actuators[actuator reached_counts] verified \
                 not_verifiable"
            )
        ]
    );
    assert_eq!(
        lines(&["watch", "--count", "1"], ""),
        [keys(&format!("family port profile t_s last_error{{{error_code}}} actuators[{state} current_amps]"))]
    );
    assert_eq!(lines(&["errors"], ""), [keys(&format!("family port profile errors[{error_code}]"))]);
    let telegram = "bad bytes direction meaning time_s";
    assert_eq!(
        lines(&["send", "RG", "actual_position_a1"], ""),
        [keys(&format!("family port profile command data ok request{{{telegram}}} reply{{{telegram}}}"))]
    );
    let names = lines(&["names"], "");
    let name = keys("family name id unit access title size");
    assert!(names.len() > 100 && names.iter().all(|n| *n == name), "{:?}", names.first());
    assert_eq!(
        lines(&["--functions", "tlt", "--sim-preset", "tlt", "follow", "1"], "200 210\n"),
        [
            keys("family port profile function following actuators"),
            keys("family port profile targets[actuator target_counts]"),
            keys("family port profile stopped updates actuators[actuator reached_counts]"),
        ]
    );
}

/// A device error carries what the unit reported, as data: `--json` gives its Error_Code (`code`) and the
/// bits set with the manual's names (`bits`), as Python's `to_dict()`, the console and the gateway do. The
/// emulated unit raises error bit 12 (over-temperature) 2 s after power-on, while A1 moves slowly.
#[test]
pub(super) fn a_device_error_s_code_and_bits_come_in_the_json_error() {
    let path = common::temp_path("scu-error-bit.toml");
    std::fs::write(&path, "preset = \"scp11\"\n[[error]]\nbit = 12\nat_ms = 2000\n").expect("write the unit");
    let config = path.to_str().expect("a UTF-8 temporary path");
    let args = ["--json", "--sim-config", config, "--functions", "scp11", "move", "1", "800", "--speed", "5"];
    let out = scu("sim", &args);
    let e = common::json_error(&out);
    assert_eq!((e["kind"].as_str(), e["exit_code"].as_i64(), out.status.code()), (Some("device"), Some(1), Some(1)));
    assert_eq!(e["code"], 0x800, "{e}");
    let bit =
        serde_json::json!({"bit": 12, "name": "over_temperature", "cause": "overtemperature at rectifier or FET"});
    assert_eq!(e["bits"], serde_json::json!([bit]), "{e}");
    assert!(e["message"].as_str().unwrap().contains("A1 ended at"), "{e}");
}
