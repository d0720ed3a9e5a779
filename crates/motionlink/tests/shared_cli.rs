//! What the three families share, checked across them through the binary: the JSON names of naming.md
//! (move results, flag words, `set` results), no debug text in what the user reads, `send`'s reply, and the
//! emulators' events as JSON.

use std::time::Duration;

use crate::common;

use common::{assert_no_debug_text, run_with, Sim};

/// The JSON objects (one per line) a command printed on stdout; it must have succeeded.
fn objects(args: &[&str]) -> Vec<serde_json::Value> {
    let o = run_with(args, &[], "");
    assert!(o.status.success(), "{args:?}: {o:?}");
    String::from_utf8_lossy(&o.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("{args:?}: not a JSON line ({e}): {l}")))
        .collect()
}

/// Every object (at any depth) of `v` for which `pred` holds.
fn nested<'a>(
    v: &'a serde_json::Value,
    pred: &dyn Fn(&serde_json::Map<String, serde_json::Value>) -> bool,
) -> Vec<&'a serde_json::Value> {
    let mut found = Vec::new();
    match v {
        serde_json::Value::Object(m) => {
            if pred(m) {
                found.push(v);
            }
            for x in m.values() {
                found.extend(nested(x, pred));
            }
        }
        serde_json::Value::Array(a) => a.iter().for_each(|x| found.extend(nested(x, pred))),
        _ => {}
    }
    found
}

/// Asserts that no object of `v` shows a flag word otherwise than naming.md says: `flags` goes with `word`,
/// and `set` / `bits` never name a flag word's parts. Returns how many flag words it saw.
fn flag_words_are_word_and_flags(what: &str, v: &serde_json::Value) -> usize {
    let words = nested(v, &|m| m.contains_key("flags"));
    for w in &words {
        assert!(w["word"].is_u64(), "{what}: a flag word without its word: {w}");
        assert!(w["flags"].is_array(), "{what}: flags is a list of names: {w}");
        assert!(w.get("set").is_none() && !w["bits"].is_string(), "{what}: no set / bits in a flag word: {w}");
    }
    assert!(nested(v, &|m| m.contains_key("set")).is_empty(), "{what}: `set` is no JSON name: {v}");
    words.len()
}

/// Move results of every family name target, reached and difference with the same unit suffix; flag words
/// are `{word, flags, unknown_bits?}` everywhere (SCU info and watch, PowerCube state, COMPAX status and
/// watch); `set` gives `value`, `read_back` and `verified`.
#[test]
fn the_three_families_share_their_json_names() {
    let scu = Sim::tcp("scu");
    let pc = Sim::tcp("powercube");
    let cx = Sim::tcp("compax");
    let moves = [
        (objects(&["--json", "scu", "--port", &scu.address, "move", "1", "40"]), "counts"),
        (objects(&["--json", "powercube", "--port", &pc.address, "move", "0.1"]), "rad"),
        (objects(&["--json", "compax", "--port", &cx.address, "move", "--abs", "2"]), "units"),
    ];
    for (out, unit) in &moves {
        let m = &out[0];
        for stem in ["target", "reached", "difference"] {
            assert!(m[format!("{stem}_{unit}")].is_number(), "{stem}_{unit} missing: {m}");
        }
        assert!(m["family"].is_string() && m["port"].is_string(), "{m}");
        assert!(m[format!("difference_{unit}")].as_f64().unwrap().abs() < 1.0, "{m}");
    }

    let mut seen = 0;
    for (what, args) in [
        ("scu info", vec!["scu", "--port", &scu.address, "info"]),
        ("scu watch", vec!["scu", "--port", &scu.address, "watch", "--count", "1"]),
        ("scu get", vec!["scu", "--port", &scu.address, "get", "actuator_status1", "battery_mains"]),
        ("powercube state", vec!["powercube", "--port", &pc.address, "state"]),
        ("powercube info", vec!["powercube", "--port", &pc.address, "info"]),
        ("powercube get", vec!["powercube", "--port", &pc.address, "get", "ActFPosStateDio"]),
        ("powercube watch", vec!["powercube", "--port", &pc.address, "watch", "--count", "1"]),
        ("compax status", vec!["compax", "--port", &cx.address, "status"]),
        ("compax watch", vec!["compax", "--port", &cx.address, "watch", "--count", "1"]),
    ] {
        let args: Vec<&str> = std::iter::once("--json").chain(args.iter().copied()).collect();
        for v in objects(&args) {
            let n = flag_words_are_word_and_flags(what, &v);
            assert!(n > 0, "{what}: no flag word: {v}");
            seen += n;
        }
    }
    assert!(seen >= 8);
    // The SCU's battery/mains word, and COMPAX S17 with the drive's own bit string.
    let info = &objects(&["--json", "scu", "--port", &scu.address, "info"])[0];
    assert!(info["battery_mains"]["word"].is_u64() && info["battery_mains"]["flags"].is_array(), "{info}");
    let watch = &objects(&["--json", "compax", "--port", &cx.address, "watch", "--count", "1"])[0];
    assert_eq!(watch["s17"]["pattern"].as_str().map(str::len), Some(9), "{watch}");

    for (what, args) in [
        ("scu", vec!["scu", "--port", &scu.address, "set", "remote_speed_f1", "80"]),
        ("powercube", vec!["powercube", "--port", &pc.address, "set", "TargetVel", "0.5"]),
        ("compax", vec!["compax", "--port", &cx.address, "set", "P194", "1"]),
    ] {
        let args: Vec<&str> = std::iter::once("--json").chain(args.iter().copied()).collect();
        let v = &objects(&args)[0];
        assert_eq!(v["verified"], true, "{what}: {v}");
        // The value read, in the unit of the value (PowerCube TargetVel: its tick twin converted back).
        let (read, value) = (v["read_back"].as_f64().unwrap(), v["value"].as_f64().unwrap());
        assert!((read - value).abs() <= value.abs() * 1e-3, "{what}: the value read back: {v}");
    }
}

/// `send` and `decode` name commands and bad frames in words: no `Get(ActPos)`, `CanFrame(...)` or `\u{1}`.
#[test]
fn send_and_decode_print_no_debug_text() {
    let pc = Sim::tcp("powercube");
    let sent = &objects(&["--json", "powercube", "--port", &pc.address, "send", "get", "ActPos"])[0];
    assert_eq!(sent["command"], "GetExtended ActPos", "{sent}");
    assert!(sent["reply"]["meaning"].as_str().unwrap().ends_with(" rad"), "the module's unit, not rad|m: {sent}");
    let text = String::from_utf8_lossy(
        &run_with(&["powercube", "--port", &pc.address, "send", "get", "ActPos"], &[], "").stdout,
    )
    .into_owned();
    assert_no_debug_text("powercube send", &text);
    assert_no_debug_text("powercube send --json", &sent.to_string());
    let scu = Sim::tcp("scu");
    let cx = Sim::tcp("compax");
    for args in [
        vec!["scu", "--port", &scu.address, "send", "RG", "actual_position_a1"],
        vec!["scu", "--port", &scu.address, "send", "52", "47", "11", "00", "2C", "30"],
        vec!["compax", "--port", &cx.address, "send", "S1"],
        vec!["compax", "--port", &cx.address, "send", "Q"],
        vec!["powercube", "--port", &pc.address, "send", "set", "TargetVel", "0.5"],
    ] {
        for json in [false, true] {
            let args: Vec<&str> = if json { [&["--json"][..], &args].concat() } else { args.clone() };
            let o = run_with(&args, &[], "");
            let text = format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
            assert_no_debug_text(&format!("{args:?}"), &text);
        }
    }

    for (family, input, expected) in [
        ("scu", "(1700000000.000000) can0 123#0102\n", "a CAN frame (123#0102)"),
        ("compax", "(1.0) -> 31 51 01 58 0D\n", "\"Q<01>X\" (not a known command)"),
    ] {
        let o = run_with(&["decode", family], &[], input);
        let text = String::from_utf8_lossy(&o.stdout).into_owned();
        assert!(text.contains(expected), "{family}: {text}");
        assert_no_debug_text(family, &text);
        let o = run_with(&["--json", "decode", family], &[], input);
        assert_no_debug_text(family, &String::from_utf8_lossy(&o.stdout));
    }
}

/// `compax send POSA 1` prints the drive's reply to POSA (acknowledged), not the S1 poll of the wait that
/// follows it; the polls are counted apart.
#[test]
fn compax_send_prints_the_reply_to_the_telegram_sent() {
    let cx = Sim::tcp("compax");
    let text = run_with(&["compax", "--port", &cx.address, "send", "POSA", "1"], &[], "");
    assert!(text.status.success(), "{text:?}");
    let text = String::from_utf8_lossy(&text.stdout).into_owned();
    let lines: Vec<&str> = text.lines().collect();
    assert!(lines[0].starts_with("-> 31 50 4F 53 41 20 31 0D") && lines[0].contains("POSA"), "{text}");
    assert!(lines[1].starts_with("<- 0D 0A 3E") && lines[1].contains("acknowledged"), "{text}");
    assert!(!lines[1].contains("S1"), "{text}");
    assert!(lines.get(2).is_none_or(|l| l.starts_with("then ") && l.contains("status polls")), "{text}");
    let sent = &objects(&["--json", "compax", "--port", &cx.address, "send", "POSA", "0"])[0];
    assert_eq!(sent["reply"]["bytes"], "0D 0A 3E", "{sent}");
    assert_eq!((&sent["command"], &sent["reply_text"], &sent["ok"]), (&"POSA 0".into(), &"".into(), &true.into()));
    assert!(sent["request"]["meaning"].as_str().unwrap().contains("POSA"), "{sent}");
    assert!(sent["polls"].as_u64().unwrap() >= 1, "the wait polled S1: {sent}");
    // A command that asks for no reply (`/`) has none: the poll's reply is not shown as its reply.
    let o = run_with(&["compax", "--port", &cx.address, "send", "POSA", "2/"], &[], "");
    let text = String::from_utf8_lossy(&o.stdout).into_owned();
    assert_eq!(text.lines().nth(1), Some("reply: none"), "{text}");
}

/// `sim --events --json` prints its events as JSON objects on stderr.
#[test]
fn sim_events_are_json_with_json() {
    let sim = Sim::start("scu", &["--tcp", "127.0.0.1:0", "--json"]);
    let o = run_with(&["scu", "--port", &sim.address, "info"], &[], "");
    assert!(o.status.success(), "{o:?}");
    let line = sim
        .stderr
        .wait_for(Duration::from_secs(10), |l| l.contains("remote mode opened"))
        .unwrap_or_else(|| panic!("no event: {}", sim.stderr.text()));
    let v: serde_json::Value = serde_json::from_str(&line).unwrap_or_else(|e| panic!("{e}: {line}"));
    assert!(v["event"].as_str().unwrap().starts_with("remote mode opened"), "{v}");
    assert!((v["time_s"].as_f64().unwrap() - common::unix_now()).abs() < 60.0, "{v}");
}

/// `send` takes one telegram given as hex on every family: PowerCube a whole RS232 telegram (its BCC
/// checked, its address --module's) as well as a payload; `home` is refused, as its help says.
#[test]
fn powercube_send_takes_a_whole_rs232_telegram() {
    let pc = Sim::tcp("powercube");
    let p = pc.address.as_str();
    let whole = run_with(&["powercube", "--port", p, "send", "02", "04", "22", "0A", "3C", "6C", "03"], &[], "");
    let payload = run_with(&["powercube", "--port", p, "send", "0A", "3C"], &[], "");
    assert!(whole.status.success() && payload.status.success(), "{whole:?} {payload:?}");
    assert_eq!(whole.stdout, payload.stdout);
    let text = String::from_utf8_lossy(&whole.stdout).into_owned();
    assert!(text.starts_with("-> 02 04 22 0A 3C 6C 03") && text.contains("ActPos = 0.050000 rad\n"), "{text}");
    for (args, expected) in [
        (&["02", "04", "22", "0A", "3C", "6D", "03"][..], "wrong BCC 0x6D"),
        (&["02", "0C", "22", "0A", "3C", "6C", "03"][..], "not an RS232 telegram"),
        // An answer's TELID (TELID_RECVDAT: 0x08, address bits in 1..0), named as the manual has it.
        (&["02", "08", "21", "01", "2A", "03"][..], "an answer of a module (first TELID byte 0x08..0x0B"),
        (&["home"][..], "powercube home"),
    ] {
        let o = run_with(&[&["powercube", "--port", p, "send"][..], args].concat(), &[], "");
        assert_eq!(o.status.code(), Some(2), "{args:?}: {o:?}");
        assert!(String::from_utf8_lossy(&o.stderr).contains(expected), "{args:?}: {o:?}");
    }
    // A telegram for another module than --module names both.
    let o = run_with(&["powercube", "--port", p, "--module", "2", "send", "02 04 22 0A 3C 6C 03"], &[], "");
    assert!(String::from_utf8_lossy(&o.stderr).contains("for module 1, not 2"), "{o:?}");
    let help = String::from_utf8_lossy(&run_with(&["powercube", "send", "--help"], &[], "").stdout).into_owned();
    assert!(help.contains("whole RS232 telegram") && help.contains("home or move"), "{help}");
    assert!(!help.contains("reset, home"), "home is not listed as typed: {help}");
}

/// The options shared by the families have the same unit-named spelling everywhere (`--interval-ms`,
/// `--poll-ms`, `--timeout-ms`); the SCU's old spellings still work but are not shown.
#[test]
fn option_names_are_the_same_in_every_family() {
    let help = |args: &[&str]| String::from_utf8_lossy(&run_with(args, &[], "").stdout).into_owned();
    for family in ["scu", "powercube", "compax"] {
        let top = help(&[family, "--help"]);
        assert!(top.contains("--timeout-ms"), "{family}: {top}");
        assert!(help(&[family, "watch", "--help"]).contains("--interval-ms"), "{family} watch");
        let poll = if family == "compax" { help(&[family, "move", "--help"]) } else { top.clone() };
        assert!(poll.contains("--poll-ms"), "{family}: --poll-ms");
        for old in ["--reply-timeout", "--poll-interval"] {
            assert!(!top.contains(old), "{family}: the old name {old} is hidden: {top}");
        }
    }
    let scu = Sim::tcp("scu");
    let old = run_with(
        &[
            "scu",
            "--port",
            &scu.address,
            "--reply-timeout",
            "500",
            "--poll-interval",
            "20",
            "watch",
            "--interval",
            "10",
            "--count",
            "1",
        ],
        &[],
        "",
    );
    assert!(old.status.success(), "the old spellings: {old:?}");
}

/// Negative numbers in every form a number takes are values, not options: `-1e-1`, `-.3`; `-5e` is no number.
#[test]
fn negative_numbers_in_every_form_are_values() {
    let pc = Sim::tcp("powercube");
    for (arg, expected) in [("-1e-1", -0.1), ("-.3", -0.3)] {
        let m = &objects(&["--json", "powercube", "--port", &pc.address, "move", arg])[0];
        assert!((m["target_rad"].as_f64().unwrap() - expected).abs() < 1e-6, "{arg}: {m}");
    }
    let cx = Sim::tcp("compax");
    let m = &objects(&["compax", "--port", &cx.address, "move", "--abs", "-.5", "--json"])[0];
    assert_eq!(m["reached_units"], -0.5, "{m}");
    let o = run_with(&["compax", "--port", &cx.address, "set", "P003", "-1.5e-1"], &[], "");
    assert!(o.status.success(), "{o:?}");
    // An option that only looks like one stays an option: refused, named.
    let o = run_with(&["compax", "--port", &cx.address, "move", "-abs"], &[], "");
    assert_eq!(o.status.code(), Some(2), "{o:?}");
    // A negative number in a form no number takes is named whole (clap would split it into options).
    for bad in ["-5e", "-inf"] {
        let o = run_with(&["powercube", "--port", &pc.address, "move", bad], &[], "");
        assert_eq!(o.status.code(), Some(2), "{o:?}");
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(stderr.contains(&format!("invalid value '{bad}': not a number")), "{stderr}");
    }
}
