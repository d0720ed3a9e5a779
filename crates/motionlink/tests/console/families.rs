//! The console per family: a parameter write and its read-back, the error history with an error the emulator
//! raised, the sample rate over an emulator paced to 9600 baud; and what holds for every family: a request
//! that names another Host is refused (DNS rebinding), a closed page stops its jog at once (not by the
//! dead-man deadline).

use std::io::{Read, Write};
use std::net::TcpStream;
use std::time::{Duration, Instant};

use serde_json::{json, Value};

use super::{console, of_type, recv_until, send, units, ws, ws_with, Ws};
use crate::common::{temp_path, unix_now, Sim};

/// Writes `name` = `value` on unit 1 and returns the `param` answer.
fn write(ws: &mut Ws, key: &str, name: &str, value: &str) -> Value {
    send(ws, json!({"type": "write_param", key: 1, "name": name, "value": value}));
    let v = recv_until(ws, Duration::from_secs(10), |v| v["type"] == "param" || v["type"] == "failed")
        .expect("an answer to the write");
    assert_eq!(v["type"], "param", "{v}");
    assert_eq!(v["written"], true, "{v}");
    v["report"].clone()
}

/// Reads `name` of unit 1 and returns the `param` answer.
fn read(ws: &mut Ws, key: &str, name: &str) -> Value {
    send(ws, json!({"type": "read_param", key: 1, "name": name}));
    let v = recv_until(ws, Duration::from_secs(10), |v| v["type"] == "param" || v["type"] == "failed")
        .expect("an answer to the read");
    assert_eq!(v["type"], "param", "{v}");
    v["report"].clone()
}

/// The error history of unit 1.
fn errors(ws: &mut Ws, key: &str) -> Value {
    send(ws, json!({"type": "errors", key: 1}));
    recv_until(ws, Duration::from_secs(10), of_type("errors")).expect("the error history")
}

#[test]
fn an_scu_write_shows_its_read_back() {
    let c = console(&["scu", "--port", "sim"]);
    let mut ws = ws(&c);
    units(&mut ws);
    let p = write(&mut ws, "actuator", "remote_speed_f1", "40");
    // The report `motionlink scu set remote_speed_f1 40 --json` prints (without the identity fields).
    assert_eq!(
        p,
        json!({"name": "remote_speed_f1", "id": 0x3011, "unit": "%", "access": "rw", "value": 40, "read_back": 40,
               "verified": true, "not_verifiable": []})
    );
    assert_eq!(read(&mut ws, "actuator", "remote_speed_f1")["value"], 40);
}

/// Waits for the end of the motion `what` of module 1 and returns it.
fn ended(ws: &mut Ws, what: &str) -> Value {
    recv_until(ws, Duration::from_secs(20), |v| v["type"] == "motion" && v["state"] == "ended" && v["what"] == what)
        .unwrap_or_else(|| panic!("the end of {what}"))
}

#[test]
fn a_powercube_motion_ends_with_the_report_the_command_line_prints() {
    let c = console(&["powercube", "--port", "sim", "--modules", "1"]);
    let mut ws = ws(&c);
    units(&mut ws);
    send(&mut ws, json!({"type": "action", "module": 1, "name": "home"}));
    let homed = ended(&mut ws, "home");
    assert_eq!(homed["ok"], true, "{homed}");
    let r = &homed["report"];
    assert_eq!(
        (r["reached_rad"].as_f64(), &r["verified"], &r["not_verifiable"]),
        (Some(0.0), &json!(true), &json!([]))
    );
    assert!(r["state"]["flags"].as_array().unwrap().contains(&json!("STATE_HOME_OK")), "{homed}");
    send(&mut ws, json!({"type": "move", "module": 1, "target_rad": 0.2}));
    let moved = ended(&mut ws, "move");
    let r = &moved["report"];
    assert_eq!((r["target_rad"].as_f64(), r["verified"].as_bool()), (Some(0.2f32 as f64), Some(true)), "{moved}");
    assert!((r["reached_rad"].as_f64().unwrap() - 0.2).abs() <= 0.001, "{moved}");
    assert!(r["difference_rad"].is_number() && r["state"]["faults"] == json!([]), "{moved}");
}

#[test]
fn an_scu_and_a_compax_move_end_with_the_report_the_command_line_prints() {
    // `motionlink scu move --json` prints the library's MoveReport; `motionlink compax move --json` its own.
    for (family, key, target_key, target, reached_key) in [
        ("scu", "actuator", "target_counts", 300.0, "reached_counts"),
        ("compax", "drive", "target_units", 5.0, "reached_units"),
    ] {
        let c = console(&[family, "--port", "sim"]);
        let mut ws = ws(&c);
        units(&mut ws);
        send(&mut ws, json!({"type": "move", key: 1, target_key: target}));
        let moved = recv_until(&mut ws, Duration::from_secs(30), |v| v["type"] == "motion" && v["state"] == "ended")
            .unwrap_or_else(|| panic!("{family}: the end of the move"));
        assert_eq!(moved["ok"], true, "{family}: {moved}");
        let r = &moved["report"];
        assert_eq!((r[target_key].as_f64(), &r["verified"]), (Some(target), &json!(true)), "{family}: {moved}");
        assert!((r[reached_key].as_f64().unwrap() - target).abs() <= 1.0, "{family}: {moved}");
    }
}

#[test]
fn an_scu_sample_shows_speed_and_current_while_it_moves() {
    // The emulator's actuator draws 3.0 A at full speed: the speeds (%) and currents (0.1 A) groups decoded
    // by the library, the current in A.
    let c = console(&["scu", "--port", "sim"]);
    let mut ws = ws(&c);
    units(&mut ws);
    send(&mut ws, json!({"type": "move", "actuator": 1, "target_counts": 800}));
    let moving = |v: &Value| v["type"] == "sample" && v["units"][0]["speed_percent"].as_f64().is_some_and(|s| s > 0.0);
    let mut seen = Vec::new();
    let v = recv_until(&mut ws, Duration::from_secs(20), |v| {
        seen.push(v.clone());
        moving(v)
    });
    let v = v.unwrap_or_else(|| {
        panic!(
            "a sample while it moves: {:?}",
            seen.iter().filter(|v| v["type"] != "traffic").take(8).collect::<Vec<_>>()
        )
    });
    let s = &v["units"][0];
    assert!(s["current_amps"].as_f64().is_some_and(|a| a > 0.0 && a <= 6.0), "{v}");
    assert!(s["speed_percent"].as_f64().is_some_and(|p| p <= 100.0), "{v}");
}

#[test]
fn a_powercube_write_reports_what_the_command_line_does() {
    let c = console(&["powercube", "--port", "sim", "--modules", "1"]);
    let mut ws = ws(&c);
    units(&mut ws);
    // The reports of `motionlink powercube set` and `get` (without the identity fields).
    let p = write(&mut ws, "module", "MaxVel", "0.8");
    assert_eq!((&p["name"], &p["verified"], &p["not_verifiable"]), (&json!("MaxVel"), &json!(true), &json!([])));
    assert_eq!((p["value"].as_f64(), p["read_back"].as_f64()), (Some(0.8f32 as f64), Some(0.8f32 as f64)), "{p}");
    let r = read(&mut ws, "module", "MaxVel");
    assert_eq!((r["value"].as_f64(), &r["unit"]), (Some(0.8f32 as f64), &json!("rad/s")), "{r}");
    // TargetVel cannot be read: the library checks it against TargetVelInc and reports it in rad/s.
    let p = write(&mut ws, "module", "TargetVel", "0.5");
    assert_eq!((p["value"].as_f64(), p["verified"].as_bool()), (Some(0.5), Some(true)), "{p}");
    assert!((p["read_back"].as_f64().unwrap() - 0.5).abs() < 1e-3, "{p}");
}

#[test]
fn the_scu_error_history_decodes_an_error_the_unit_raised() {
    let config = temp_path("console-scu-error.toml");
    std::fs::write(&config, "[[error]]\nbit = 12\nat_ms = 0\n").unwrap();
    let sim = Sim::start("scu", &["--tcp", "127.0.0.1:0", "--config", config.to_str().unwrap()]);
    let c = console(&["scu", "--port", &sim.address]);
    let mut ws = ws(&c);
    units(&mut ws);
    sim.wait_event(Duration::from_secs(10), |t| t.starts_with("error bit 12 set")).expect("the unit raised it");
    let v = errors(&mut ws, "actuator");
    let _ = std::fs::remove_file(&config);
    // The report of `motionlink scu errors --json`.
    let newest = &v["report"]["errors"][0];
    assert_eq!(newest["code"], 1 << 11, "{v}");
    assert_eq!(newest["bits"][0]["bit"], 12, "{v}");
    assert_eq!(newest["bits"][0]["name"], "over_temperature", "{v}");
    assert!(newest["bits"][0]["cause"].as_str().unwrap().contains("overtemperature"), "{v}");
    assert_eq!(v["report"]["errors"][1], json!({"code": 0, "bits": []}), "{v}");
}

#[test]
fn the_compax_error_history_decodes_an_error_the_drive_raised() {
    let sim = Sim::start("compax", &["--tcp", "127.0.0.1:0", "--drives", "1"]);
    // A move while the drive moves: E92 (command active), recorded in S18. Sent as raw telegrams before the
    // console connects (the emulator serves one client at a time).
    {
        let addr = sim.address.strip_prefix("tcp://").unwrap();
        let mut raw = TcpStream::connect(addr).unwrap();
        raw.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
        let mut ask = |telegram: &[u8]| {
            raw.write_all(telegram).unwrap();
            let mut got = Vec::new();
            let mut b = [0u8; 1];
            while !got.ends_with(b">") {
                raw.read_exact(&mut b).expect("an answer of the drive");
                got.push(b[0]);
            }
            String::from_utf8_lossy(&got).into_owned()
        };
        assert_eq!(ask(b"1POSA 900\r"), "\r\n>");
        assert!(ask(b"1POSA 20\r").starts_with("E92"));
    }
    sim.wait_event(Duration::from_secs(5), |t| t.starts_with("drive 1 error E92")).expect("the drive raised E92");
    let c = console(&["compax", "--port", &sim.address, "--drives", "1"]);
    let mut ws = ws(&c);
    units(&mut ws);
    let v = errors(&mut ws, "drive");
    let newest = &v["report"]["errors"][0];
    assert_eq!(newest["code"], 92, "{v}");
    assert_eq!(newest["text"], "E92", "the code in the Code column: {v}");
    assert!(newest["meaning"].as_str().unwrap().starts_with("command active"), "the meaning in its own: {v}");
}

#[test]
fn the_powercube_error_history_decodes_a_state_fault() {
    // A module whose following error limit any motion passes: it stops with STATE_TOW_ERROR.
    let config = temp_path("console-powercube-tow.toml");
    std::fs::write(&config, "[[module]]\naddress = 1\nmax_delta_pos = 0.0001\n").unwrap();
    let sim = Sim::start("powercube", &["--tcp", "127.0.0.1:0", "--config", config.to_str().unwrap()]);
    let c = console(&["powercube", "--port", &sim.address, "--modules", "1"]);
    let mut ws = ws(&c);
    units(&mut ws);
    let v = errors(&mut ws, "module");
    // The report of `motionlink powercube state --json`.
    assert_eq!(v["report"]["faults"], json!([]), "{v}");
    send(&mut ws, json!({"type": "move", "module": 1, "target_rad": 1.0}));
    sim.wait_event(Duration::from_secs(10), |t| t == "module 1 error: STATE_TOW_ERROR").expect("the tow error");
    recv_until(&mut ws, Duration::from_secs(10), |v| v["type"] == "motion" && v["state"] != "running")
        .expect("the move ends");
    // The samples show the fault (the state word is read as soon as the short state changes).
    recv_until(&mut ws, Duration::from_secs(5), |v| {
        v["type"] == "sample"
            && v["units"][0]["faults"].as_array().is_some_and(|f| f.iter().any(|n| n == "STATE_TOW_ERROR"))
            && v["units"][0]["moving"] == false
    })
    .expect("a sample shows STATE_TOW_ERROR");
    let v = errors(&mut ws, "module");
    let _ = std::fs::remove_file(&config);
    let now = &v["report"];
    assert!(now["word"].as_u64().unwrap() != 0, "{v}");
    assert!(now["faults"].as_array().unwrap().iter().any(|f| f == "STATE_TOW_ERROR"), "{v}");
}

/// A GET of `path` from `host` naming `host_header` as its Host: the status and the body.
fn get_as(host: &str, host_header: &str, path: &str) -> (u16, String) {
    let mut s = TcpStream::connect(host).expect("connect to the console");
    s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    write!(s, "GET {path} HTTP/1.1\r\nHost: {host_header}\r\nConnection: close\r\n\r\n").unwrap();
    let mut out = Vec::new();
    s.read_to_end(&mut out).expect("read the answer");
    let text = String::from_utf8_lossy(&out).into_owned();
    let status = text.split(' ').nth(1).and_then(|c| c.parse().ok()).unwrap_or_else(|| panic!("{text:?}"));
    (status, text.split_once("\r\n\r\n").map(|(_, b)| b.to_string()).unwrap_or_default())
}

#[test]
fn a_request_for_another_host_is_refused_dns_rebinding() {
    let c = console(&["compax", "--port", "sim", "--drives", "1"]);
    let port = c.host.rsplit(':').next().unwrap().to_string();
    // A page of another site whose name now points at 127.0.0.1: the browser sends that name as Host (and
    // as the WebSocket's Origin). Even with the token, nothing is served.
    let evil = format!("evil.example:{port}");
    for path in ["/", "/app.js", "/capture"] {
        let (status, body) = get_as(&c.host, &evil, &format!("{path}?token={}", c.token));
        assert_eq!(status, 403, "{path}: {body}");
        assert!(body.contains("Host is not the console's address"), "{body}");
    }
    let stream = TcpStream::connect(&c.host).unwrap();
    let req = tungstenite::http::Request::builder()
        .uri(format!("ws://{evil}/ws?token={}", c.token))
        .header("Host", &evil)
        .header("Origin", format!("http://{evil}"))
        .header("Connection", "Upgrade")
        .header("Upgrade", "websocket")
        .header("Sec-WebSocket-Version", "13")
        .header("Sec-WebSocket-Key", tungstenite::handshake::client::generate_key())
        .body(())
        .unwrap();
    match tungstenite::client(req, stream) {
        Err(tungstenite::HandshakeError::Failure(tungstenite::Error::Http(r))) => assert_eq!(r.status(), 403),
        Ok(_) => panic!("the WebSocket opened for another Host"),
        Err(e) => panic!("WebSocket handshake: {e}"),
    }
    // The console's own names are served.
    for own in [c.host.clone(), format!("localhost:{port}")] {
        assert_eq!(get_as(&c.host, &own, &format!("/?token={}", c.token)).0, 200, "{own}");
    }
    let origin = format!("http://{}", c.host);
    assert!(ws_with(&c.host, &c.token, Some(&origin)).is_ok());
}

#[test]
fn a_closed_page_stops_its_jog_at_once_not_by_the_dead_man_deadline() {
    let sim = Sim::start("compax", &["--tcp", "127.0.0.1:0", "--drives", "1"]);
    let c = console(&["compax", "--port", &sim.address, "--drives", "1"]);
    let mut jogging = ws(&c);
    units(&mut jogging);
    // A second page, read-only, is told why the jog stopped.
    let mut watching = ws(&c);
    units(&mut watching);
    send(&mut jogging, json!({"type": "jog", "drive": 1, "direction": "positive", "speed": 20.0}));
    let started = sim.wait_event(Duration::from_secs(10), |t| t.starts_with("drive 1 motion started")).unwrap();
    let mut last_renewal = unix_now();
    while unix_now() - started.at < 0.5 {
        send(&mut jogging, json!({"type": "jog_hold"}));
        last_renewal = unix_now();
        recv_until(&mut jogging, Duration::from_millis(50), |_| false);
    }
    // Renewed just now: the dead-man deadline is 200 ms away. The page closes (a close frame, as a closed tab).
    send(&mut jogging, json!({"type": "jog_hold"}));
    last_renewal = last_renewal.max(unix_now());
    // Taken before the close: under load the stop can come before this thread runs again.
    let closed = unix_now();
    jogging.close(None).unwrap();
    drop(jogging);
    let off = sim
        .wait_event_after(closed, Duration::from_secs(5), |t| t == "drive 1 switched off (O0=0)")
        .expect("closing the page stops the jog");
    let m = recv_until(&mut watching, Duration::from_secs(5), |v| v["type"] == "motion" && v["state"] == "stopped")
        .expect("the other page is told");
    assert_eq!(m["reason"], "the page that started it went away", "{m}");
    assert!(
        off.at - last_renewal < 0.19,
        "stopped {:.3} s after the last renewal: not before the 200 ms dead-man deadline",
        off.at - last_renewal
    );
}

#[test]
fn one_unit_samples_at_20_hz_over_an_emulator_paced_at_9600_baud_an_scu_at_38400() {
    // `--port sim` runs the emulator paced to --baud: every byte takes its time on the line. An SCU's
    // standard rate is 38400 baud; its four group reads a sample (about 105 bytes) allow about 8 samples a
    // second at 9600 (the README says so).
    for (family, args) in [
        ("powercube", &["--modules", "1", "--baud", "9600"][..]),
        ("compax", &["--drives", "1", "--baud", "9600"][..]),
        ("scu", &["--baud", "38400"][..]),
    ] {
        let mut all = vec![family, "--port", "sim"];
        all.extend_from_slice(args);
        let c = console(&all);
        let mut ws = ws(&c);
        assert!(!units(&mut ws).is_empty(), "{family}: a unit");
        recv_until(&mut ws, Duration::from_secs(10), of_type("sample")).expect("a first sample");
        let start = Instant::now();
        let mut frames = 0u32;
        while start.elapsed() < Duration::from_secs(2) {
            if recv_until(&mut ws, Duration::from_millis(100), of_type("sample")).is_some() {
                frames += 1;
            }
        }
        let rate = f64::from(frames) / start.elapsed().as_secs_f64();
        eprintln!("{family} {args:?}: {rate:.1} samples/s");
        assert!(rate >= 20.0, "{family} {args:?}: {rate:.1} samples/s");
    }
}

/// The answer to `request`: the first `refused`, `failed`, `stopped` or `param` message.
fn answer(ws: &mut Ws, request: Value) -> Value {
    send(ws, request);
    let kinds = ["refused", "failed", "stopped", "param"];
    recv_until(ws, Duration::from_secs(10), |v| kinds.iter().any(|k| v["type"] == *k)).expect("an answer")
}

#[test]
fn bad_requests_are_refused_naming_what_was_wrong_and_nothing_is_sent() {
    let c = console(&["compax", "--port", "sim"]);
    let mut ws = ws(&c);
    units(&mut ws);
    send(&mut ws, json!({"type": "take_control"}));
    // A jog's direction as given, not as Rust shows an Option.
    let v = answer(&mut ws, json!({"type": "jog", "drive": 1, "direction": "sideways"}));
    assert_eq!((&v["type"], &v["error"]["kind"]), (&json!("refused"), &json!("usage")), "{v}");
    assert_eq!(v["message"], "direction \"sideways\": give \"positive\" or \"negative\"", "{v}");
    // A parameter that does not exist: refused (nothing was asked of the drive), not failed.
    let v = answer(&mut ws, json!({"type": "read_param", "drive": 1, "name": "nope"}));
    assert_eq!((&v["type"], &v["request"]), (&json!("refused"), &json!("read_param")), "{v}");
    // The error history of a unit the console did not find is not asked on the line.
    let v = answer(&mut ws, json!({"type": "errors", "drive": 7}));
    assert_eq!(
        (&v["type"], &v["message"]),
        (&json!("refused"), &json!("drive 7 was not found: the console found drive 1")),
        "{v}"
    );
    // Stop with nothing running says so.
    let v = answer(&mut ws, json!({"type": "stop"}));
    assert_eq!(v["type"], "stopped", "{v}");
    assert!(!v["message"].as_str().unwrap_or_default().is_empty(), "{v}");
}
