//! `motionlink console` end to end: the built binary, its HTTP routes and its WebSocket, against the emulators
//! (`--port sim` in the console's process, or `motionlink sim <family> --tcp` when the test waits for the
//! device's events). Tests wait on lines and events, never after a fixed sleep.

use std::io::{Read, Write};
use std::net::TcpStream;
use std::time::{Duration, Instant};

use serde_json::{json, Value};
use tungstenite::handshake::client::generate_key;
use tungstenite::http::Request;
use tungstenite::{Message, WebSocket};

use crate::common;

use common::{unix_now, Running, Sim};

mod families;
mod ports;

/// A running console and the address it printed.
struct Console {
    running: Running,
    /// `127.0.0.1:PORT`.
    host: String,
    token: String,
}

/// Starts `motionlink console <args>` and reads its one line.
fn console(args: &[&str]) -> Console {
    console_with_env(args, &[])
}

/// Starts `motionlink console <args>` with `env` set ([`Running::start_env`]) and reads its one line.
fn console_with_env(args: &[&str], env: &[(&str, &str)]) -> Console {
    let mut all = vec!["console"];
    all.extend_from_slice(args);
    let running = Running::start_env(&all, env);
    let line = running
        .stdout
        .wait_for(Duration::from_secs(30), |_| true)
        .unwrap_or_else(|| panic!("no line from the console; stderr: {}", running.stderr.text()));
    let rest = line.strip_prefix("console on http://").unwrap_or_else(|| panic!("unexpected line {line:?}"));
    let (host, token) = rest.split_once("/?token=").unwrap_or_else(|| panic!("no token in {line:?}"));
    assert_eq!(token.len(), 32, "{line:?}");
    assert!(token.chars().all(|c| c.is_ascii_hexdigit()), "{line:?}");
    Console { host: host.to_string(), token: token.to_string(), running }
}

/// A plain HTTP/1.1 GET: the status code and the body.
fn get(host: &str, path: &str) -> (u16, String) {
    let mut s = TcpStream::connect(host).expect("connect to the console");
    s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    write!(s, "GET {path} HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n\r\n").unwrap();
    let mut out = Vec::new();
    s.read_to_end(&mut out).expect("read the answer");
    let text = String::from_utf8_lossy(&out).into_owned();
    let status = text.split(' ').nth(1).and_then(|c| c.parse().ok()).unwrap_or_else(|| panic!("no status in {text:?}"));
    let body = text.split_once("\r\n\r\n").map(|(_, b)| b.to_string()).unwrap_or_default();
    (status, body)
}

type Ws = WebSocket<TcpStream>;

/// Opens the console's WebSocket with `token` and `origin`; the HTTP status when it is refused.
fn ws_with(host: &str, token: &str, origin: Option<&str>) -> Result<Ws, u16> {
    let stream = TcpStream::connect(host).expect("connect to the console");
    let mut req = Request::builder()
        .uri(format!("ws://{host}/ws?token={token}"))
        .header("Host", host)
        .header("Connection", "Upgrade")
        .header("Upgrade", "websocket")
        .header("Sec-WebSocket-Version", "13")
        .header("Sec-WebSocket-Key", generate_key());
    if let Some(o) = origin {
        req = req.header("Origin", o);
    }
    match tungstenite::client(req.body(()).unwrap(), stream) {
        Ok((ws, _)) => {
            ws.get_ref().set_read_timeout(Some(Duration::from_millis(50))).unwrap();
            Ok(ws)
        }
        Err(tungstenite::HandshakeError::Failure(tungstenite::Error::Http(r))) => Err(r.status().as_u16()),
        Err(e) => panic!("WebSocket handshake: {e}"),
    }
}

fn ws(c: &Console) -> Ws {
    let origin = format!("http://{}", c.host);
    ws_with(&c.host, &c.token, Some(&origin)).expect("the WebSocket opens")
}

fn send(ws: &mut Ws, v: Value) {
    ws.send(Message::text(v.to_string())).expect("send on the WebSocket");
}

/// Reads messages until one satisfies `pred` (None at the timeout); `seen` gets every message read.
fn recv_until(ws: &mut Ws, timeout: Duration, mut pred: impl FnMut(&Value) -> bool) -> Option<Value> {
    let deadline = Instant::now() + timeout;
    while Instant::now() < deadline {
        match ws.read() {
            Ok(Message::Text(t)) => {
                let v: Value = serde_json::from_str(t.as_str()).expect("JSON from the console");
                if pred(&v) {
                    return Some(v);
                }
            }
            Ok(_) => {}
            // A read timeout, or a signal that interrupted the read (EINTR): read on until the deadline.
            Err(tungstenite::Error::Io(e))
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut | std::io::ErrorKind::Interrupted
                ) => {}
            Err(e) => panic!("WebSocket read: {e}"),
        }
    }
    None
}

fn of_type(t: &'static str) -> impl Fn(&Value) -> bool {
    move |v| v["type"] == t
}

/// Waits for the units found and returns them.
fn units(ws: &mut Ws) -> Vec<Value> {
    let v = recv_until(ws, Duration::from_secs(30), |v| v["type"] == "units" && v["scanning"] == false)
        .expect("the units are found");
    v["units"].as_array().cloned().unwrap_or_default()
}

#[test]
fn prints_one_line_and_every_request_needs_the_token() {
    let c = console(&["compax", "--port", "sim"]);
    let (status, body) = get(&c.host, &format!("/?token={}", c.token));
    assert_eq!(status, 200);
    assert!(body.contains("/app.js?token=") && body.contains(&c.token), "{body}");
    for path in ["/", "/app.js", "/app.css", "/capture", "/ws"] {
        let (status, body) = get(&c.host, path);
        assert_eq!(status, 403, "{path} without a token: {body}");
        assert!(body.contains("wrong or missing token"), "{body}");
        let (status, _) = get(&c.host, &format!("{path}?token=0123456789abcdef0123456789abcdef"));
        assert_eq!(status, 403, "{path} with a wrong token");
    }
    let (status, js) = get(&c.host, &format!("/app.js?token={}", c.token));
    assert_eq!(status, 200);
    assert!(js.contains("jog_hold"), "the page's script is served");
    let (status, capture) = get(&c.host, &format!("/capture?token={}", c.token));
    assert_eq!(status, 200);
    assert!(capture.starts_with("# motionlink capture: compax sim\n"), "{capture}");
    c.running.signal(libc::SIGTERM);
    let ended = c.running.wait(Duration::from_secs(10));
    assert_eq!(ended.stdout.lines().count(), 1, "exactly one line on stdout: {:?}", ended.stdout);
    assert!(ended.stdout.starts_with("console on http://127.0.0.1:"), "{:?}", ended.stdout);
    assert_eq!(ended.code(), 128 + libc::SIGTERM, "{}", ended.stderr);
}

#[test]
fn a_non_loopback_address_needs_listen_any_and_warns() {
    let refused = Running::start(&["console", "compax", "--port", "sim", "--listen", "0.0.0.0:0"]);
    let ended = refused.wait(Duration::from_secs(10));
    assert_eq!(ended.code(), 2, "{}", ended.stderr);
    assert!(ended.stderr.contains("--listen-any"), "{}", ended.stderr);
    assert!(ended.stdout.is_empty(), "{}", ended.stdout);

    let c = console(&["compax", "--port", "sim", "--listen", "0.0.0.0:0", "--listen-any"]);
    // The address printed is this machine's host name, which another machine can open (not 0.0.0.0).
    assert!(!c.host.starts_with("0.0.0.0:") && c.host.contains(':'), "{}", c.host);
    assert!(c.running.stderr.text().contains("warning: serving on 0.0.0.0"), "{}", c.running.stderr.text());

    let c = console(&["compax", "--port", "sim", "--listen", "127.0.0.1:0"]);
    assert!(c.host.starts_with("127.0.0.1:"));
    assert!(!c.running.stderr.text().contains("warning"), "{}", c.running.stderr.text());
}

#[test]
fn the_websocket_needs_the_token_and_an_origin_of_the_console() {
    let c = console(&["compax", "--port", "sim"]);
    let origin = format!("http://{}", c.host);
    assert_eq!(ws_with(&c.host, "0123456789abcdef0123456789abcdef", Some(&origin)).err(), Some(403));
    assert_eq!(ws_with(&c.host, "", Some(&origin)).err(), Some(403));
    assert_eq!(ws_with(&c.host, &c.token, None).err(), Some(403), "no Origin");
    assert_eq!(ws_with(&c.host, &c.token, Some("http://evil.example")).err(), Some(403), "another site");
    assert_eq!(ws_with(&c.host, &c.token, Some("null")).err(), Some(403));
    let mut ws = ws_with(&c.host, &c.token, Some(&origin)).expect("the console's own page");
    let welcome = recv_until(&mut ws, Duration::from_secs(10), of_type("welcome")).expect("welcome");
    assert_eq!(welcome["family"], "compax");
    assert_eq!(welcome["unit_key"], "drive");
    assert_eq!(welcome["dead_man_ms"], 200);
    assert_eq!(welcome["role"]["role"], "control");
}

#[test]
fn one_page_controls_and_the_others_are_read_only_and_told_so() {
    let c = console(&["compax", "--port", "sim"]);
    let mut first = ws(&c);
    let w = recv_until(&mut first, Duration::from_secs(10), of_type("welcome")).unwrap();
    assert_eq!(w["role"]["role"], "control");
    let found = units(&mut first);
    assert_eq!(found.len(), 1, "{found:?}");
    let mut second = ws(&c);
    let w = recv_until(&mut second, Duration::from_secs(10), of_type("welcome")).unwrap();
    assert_eq!(w["role"]["role"], "read_only");
    assert!(w["role"]["message"].as_str().unwrap().contains("another page controls"), "{w}");
    units(&mut second);
    send(&mut second, json!({"type": "move", "drive": 1, "target_units": 5.0}));
    let r = recv_until(&mut second, Duration::from_secs(10), of_type("refused")).expect("the move is refused");
    assert!(r["message"].as_str().unwrap().contains("read-only"), "{r}");
    send(&mut second, json!({"type": "write_param", "drive": 1, "name": "P3", "value": "1"}));
    let r = recv_until(&mut second, Duration::from_secs(10), of_type("refused")).expect("the write is refused");
    assert_eq!(r["request"], "write_param");
    send(&mut second, json!({"type": "take_control"}));
    recv_until(&mut second, Duration::from_secs(10), of_type("refused")).expect("control is taken");
    // The first page goes: control is free, and the second may take it.
    first.close(None).unwrap();
    drop(first);
    recv_until(&mut second, Duration::from_secs(10), |v| v["type"] == "role" && v["control_free"] == true)
        .expect("the read-only page is told control is free");
    send(&mut second, json!({"type": "take_control"}));
    recv_until(&mut second, Duration::from_secs(10), |v| v["type"] == "role" && v["role"] == "control")
        .expect("it controls now");
}

#[test]
fn samples_come_at_20_hz_or_more_for_every_family() {
    // The units named (no scan of all 31 addresses: `one_page_controls...` finds them by a scan).
    for (family, key, position, units_named) in [
        ("scu", "actuator", "position_counts", &[][..]),
        ("powercube", "module", "position_rad", &["--modules", "1"][..]),
        ("compax", "drive", "position_units", &["--drives", "1"][..]),
    ] {
        let mut args = vec![family, "--port", "sim"];
        args.extend_from_slice(units_named);
        let c = console(&args);
        let mut ws = ws(&c);
        let found = units(&mut ws);
        assert!(!found.is_empty(), "{family}: {found:?}");
        assert!(found[0][key].is_u64(), "{family}: {found:?}");
        recv_until(&mut ws, Duration::from_secs(10), of_type("sample")).expect("a first sample");
        let start = Instant::now();
        let mut frames = 0;
        let mut last = Value::Null;
        while start.elapsed() < Duration::from_secs(2) {
            if let Some(v) = recv_until(&mut ws, Duration::from_millis(100), of_type("sample")) {
                frames += 1;
                last = v;
            }
        }
        let rate = f64::from(frames) / start.elapsed().as_secs_f64();
        eprintln!("{family}: {rate:.1} samples/s");
        assert!(rate >= 20.0, "{family}: {rate:.1} samples/s");
        let u = &last["units"][0];
        assert!(u[position].is_number(), "{family}: {last}");
        assert!(u["flags"].is_array(), "{family}: {last}");
    }
}

fn compax_on_sim() -> (Sim, Console) {
    let sim = Sim::start("compax", &["--tcp", "127.0.0.1:0", "--drives", "1"]);
    let c = console(&["compax", "--port", &sim.address, "--drives", "1"]);
    (sim, c)
}

#[test]
fn a_move_runs_and_its_position_is_sampled_then_stop_halts_it() {
    let (sim, c) = compax_on_sim();
    let mut ws = ws(&c);
    units(&mut ws);
    send(&mut ws, json!({"type": "move", "drive": 1, "target_units": 500.0, "speed_percent": 50.0}));
    sim.wait_event(Duration::from_secs(10), |t| t.starts_with("drive 1 motion started to 500.000")).expect("it moves");
    let first = recv_until(&mut ws, Duration::from_secs(5), |v| {
        v["type"] == "sample" && v["units"][0]["position_units"].as_f64().is_some_and(|p| p > 0.0)
    })
    .expect("a sample of the axis on its way");
    let p0 = first["units"][0]["position_units"].as_f64().unwrap();
    recv_until(&mut ws, Duration::from_secs(5), |v| {
        v["type"] == "sample" && v["units"][0]["position_units"].as_f64().is_some_and(|p| p > p0)
    })
    .expect("the position changes during the move");
    let pressed = unix_now();
    send(&mut ws, json!({"type": "stop", "drive": 1}));
    let off = sim
        .wait_event_after(pressed, Duration::from_secs(5), |t| t == "drive 1 switched off (O0=0)")
        .expect("Stop switches the drive off");
    assert!(off.at - pressed < 0.3, "stopped {:.3} s after Stop", off.at - pressed);
    sim.wait_event_after(pressed, Duration::from_secs(5), |t| t.starts_with("drive 1 at rest")).expect("at rest");
    let m = recv_until(&mut ws, Duration::from_secs(5), |v| v["type"] == "motion" && v["state"] == "stopped")
        .expect("the page is told");
    assert_eq!(m["ok"], true, "{m}");
    assert!(m["message"].as_str().unwrap().contains("Stop pressed"), "{m}");
    // The report of the confirmed stop, as `motionlink compax stop --json` prints it.
    let r = &m["report"];
    assert_eq!((&r["action"], &r["o0"]), (&json!("stop"), &json!(0)), "{m}");
    assert!(r["position_units"].is_number(), "{m}");
}

#[test]
fn a_jog_runs_while_renewed_and_stops_within_the_dead_man_time() {
    let (sim, c) = compax_on_sim();
    let mut ws = ws(&c);
    units(&mut ws);
    send(&mut ws, json!({"type": "jog", "drive": 1, "direction": "positive", "speed": 20.0}));
    let started = sim.wait_event(Duration::from_secs(10), |t| t.starts_with("drive 1 motion started")).expect("jogs");
    // Renewed every 50 ms for 0.8 s: it keeps running.
    let mut last_renewal = unix_now();
    while unix_now() - started.at < 0.8 {
        send(&mut ws, json!({"type": "jog_hold"}));
        last_renewal = unix_now();
        recv_until(&mut ws, Duration::from_millis(50), |_| false);
    }
    assert!(
        !sim.events().iter().any(|e| e.text.contains("switched off") || e.text.contains("at rest")),
        "the jog stopped while renewed: {:?}",
        sim.events().iter().map(|e| &e.text).collect::<Vec<_>>()
    );
    // No more renewals: the server stops it after 200 ms.
    let off = sim
        .wait_event_after(last_renewal, Duration::from_secs(5), |t| t == "drive 1 switched off (O0=0)")
        .expect("the dead-man deadline stops the jog");
    let after = off.at - last_renewal;
    assert!((0.195..0.45).contains(&after), "stopped {after:.3} s after the last renewal");
    let m = recv_until(&mut ws, Duration::from_secs(5), |v| v["type"] == "motion" && v["state"] == "stopped")
        .expect("the page is told");
    assert!(m["reason"].as_str().unwrap().contains("dead-man"), "{m}");
}

/// An SCU jog with a speed on a unit that does not read remote data back: the speed is written, not read
/// back, and the jog's result says so (was: dropped, the result said verified).
#[test]
fn an_scu_jog_s_speed_not_read_back_is_said_with_its_result() {
    let c = console(&["scu", "--port", "sim", "--sim-variant", "no-remote-readback"]);
    let mut ws = ws(&c);
    units(&mut ws);
    send(&mut ws, json!({"type": "jog", "actuator": 1, "direction": "positive", "speed": 100.0}));
    // Renewed until the unit reports the end of travel.
    let ended = std::time::Instant::now() + Duration::from_secs(40);
    let m = loop {
        assert!(std::time::Instant::now() < ended, "the jog did not reach the end of travel");
        send(&mut ws, json!({"type": "jog_hold"}));
        if let Some(m) =
            recv_until(&mut ws, Duration::from_millis(50), |v| v["type"] == "motion" && v["state"] != "running")
        {
            break m;
        }
    };
    assert_eq!((&m["state"], &m["ok"]), (&json!("ended"), &json!(true)), "{m}");
    assert_eq!(m["report"]["verified"], false, "{m}");
    let why = m["report"]["not_verifiable"].to_string();
    assert!(why.contains("the jog's speed") && why.contains("not read back"), "{m}");
}

#[test]
fn a_released_jog_stops() {
    let (sim, c) = compax_on_sim();
    let mut ws = ws(&c);
    units(&mut ws);
    send(&mut ws, json!({"type": "jog", "drive": 1, "direction": "negative"}));
    sim.wait_event(Duration::from_secs(10), |t| t.starts_with("drive 1 motion started")).expect("jogs");
    let released = unix_now();
    send(&mut ws, json!({"type": "jog_release"}));
    let off = sim
        .wait_event_after(released, Duration::from_secs(5), |t| t == "drive 1 switched off (O0=0)")
        .expect("releasing stops the jog");
    assert!(off.at - released < 0.3, "stopped {:.3} s after the release", off.at - released);
}

#[test]
fn a_lost_websocket_stops_the_motion_its_page_started() {
    let (sim, c) = compax_on_sim();
    let mut ws = ws(&c);
    units(&mut ws);
    send(&mut ws, json!({"type": "move", "drive": 1, "target_units": 800.0}));
    sim.wait_event(Duration::from_secs(10), |t| t.starts_with("drive 1 motion started")).expect("it moves");
    // The TCP connection goes without a close frame, as when a browser's tab or machine goes.
    let gone = unix_now();
    ws.get_ref().shutdown(std::net::Shutdown::Both).unwrap();
    drop(ws);
    let off = sim
        .wait_event_after(gone, Duration::from_secs(5), |t| t == "drive 1 switched off (O0=0)")
        .expect("the page's motion is stopped");
    assert!(off.at - gone < 0.3, "stopped {:.3} s after the connection went", off.at - gone);
}

#[test]
fn a_stopped_console_stops_the_motion_it_started() {
    let (sim, c) = compax_on_sim();
    let mut ws = ws(&c);
    units(&mut ws);
    send(&mut ws, json!({"type": "move", "drive": 1, "target_units": 900.0}));
    sim.wait_event(Duration::from_secs(10), |t| t.starts_with("drive 1 motion started")).expect("it moves");
    let at = c.running.signal(libc::SIGTERM);
    let off = sim
        .wait_event_after(at, Duration::from_secs(5), |t| t == "drive 1 switched off (O0=0)")
        .expect("the end of the console stops the axis");
    assert!(off.at - at < 0.3, "stopped {:.3} s after SIGTERM", off.at - at);
    // The page is told that the motion was stopped, and why, before it is told to go.
    let mut seen = Vec::new();
    let bye = recv_until(&mut ws, Duration::from_secs(10), |v| {
        seen.push(v.clone());
        v["type"] == "bye"
    });
    assert!(bye.is_some(), "a bye: {seen:?}");
    let stopped = seen.iter().find(|v| v["type"] == "motion" && v["state"] == "stopped");
    let stopped = stopped.unwrap_or_else(|| panic!("the stop before the bye: {seen:?}"));
    assert_eq!(stopped["ok"], true, "{stopped}");
    assert!(stopped["message"].as_str().unwrap().contains("ending"), "{stopped}");
    // Then the WebSocket's own end: a close frame, 1001 (going away), not a connection cut off.
    match ws.read() {
        Ok(Message::Close(Some(frame))) => {
            assert_eq!((u16::from(frame.code), frame.reason.as_str()), (1001, "the console is ending"))
        }
        other => panic!("a close frame after the bye: {other:?}"),
    }
    let ended = c.running.wait(Duration::from_secs(10));
    assert_eq!(ended.code(), 128 + libc::SIGTERM, "{}", ended.stderr);
}

#[test]
fn a_console_whose_stop_at_the_end_is_not_confirmed_says_so_even_quiet_and_exits_3() {
    let sim = Sim::start("compax", &["--tcp", "127.0.0.1:0", "--drives", "1"]);
    let running = Running::start(&["--json", "-q", "console", "compax", "--port", &sim.address, "--drives", "1"]);
    let line = running.stdout.wait_for(Duration::from_secs(30), |l| !l.is_empty()).expect("a line on stdout");
    let value: serde_json::Value = serde_json::from_str(&line).unwrap_or_else(|e| panic!("{line}: {e}"));
    let url = value["console"].as_str().unwrap_or_default().trim_start_matches("http://").to_string();
    let (host, token) = url.split_once("/?token=").unwrap_or_else(|| panic!("{line}"));
    let c = Console { host: host.to_string(), token: token.to_string(), running };
    let mut ws = ws(&c);
    units(&mut ws);
    send(&mut ws, json!({"type": "move", "drive": 1, "target_units": 900.0}));
    sim.wait_event(Duration::from_secs(10), |t| t.starts_with("drive 1 motion started")).expect("it moves");
    // The line carries nothing any more: neither the stop at the end nor the session's close is confirmed.
    let frozen = sim.freeze();
    c.running.signal(libc::SIGTERM);
    let ended = c.running.wait(Duration::from_secs(30));
    drop(frozen);
    assert_eq!(ended.code(), 3, "{}", ended.stderr);
    assert!(ended.stderr.contains("the stop at the end is not confirmed"), "said with -q: {}", ended.stderr);
    let e = ended.json_error();
    assert_eq!(e["stop_unconfirmed"], json!(true), "{e}");
}

#[test]
fn a_parameter_write_shows_its_read_back() {
    let c = console(&["compax", "--port", "sim", "--drives", "1"]);
    let mut ws = ws(&c);
    units(&mut ws);
    send(&mut ws, json!({"type": "write_param", "drive": 1, "name": "P3", "value": "2.5"}));
    let v = recv_until(&mut ws, Duration::from_secs(10), |v| v["type"] == "param" || v["type"] == "failed")
        .expect("an answer");
    assert_eq!(v["type"], "param", "{v}");
    assert_eq!(v["written"], true);
    // The report `motionlink compax set P3 2.5 --json` prints (without the identity fields).
    assert_eq!(
        v["report"],
        json!({"name": "P003", "id": 3, "value": 2.5, "unit": "", "access": "rw", "read_back": 2.5,
               "verified": true, "not_verifiable": []}),
        "{v}"
    );
    assert_eq!(v["drive"], 1, "{v}");
    send(&mut ws, json!({"type": "read_param", "drive": 1, "name": "3"}));
    let v = recv_until(&mut ws, Duration::from_secs(10), of_type("param")).expect("the read");
    assert_eq!(v["report"], json!({"name": "P003", "id": 3, "value": 2.5, "unit": "", "access": "rw"}), "{v}");
    // A bad value is refused with its reason, and nothing is written.
    send(&mut ws, json!({"type": "write_param", "drive": 1, "name": "P3", "value": "abc"}));
    let v = recv_until(&mut ws, Duration::from_secs(10), of_type("refused")).expect("refused");
    // The error as the command line's `--json` gives it (`ErrorReport`).
    assert_eq!((&v["error"]["kind"], &v["error"]["exit_code"]), (&json!("usage"), &json!(2)), "{v}");
    assert_eq!(v["error"]["message"], v["message"], "{v}");
    // A key given twice is refused, naming it, and nothing is written (a map would keep the last value).
    ws.send(Message::text(r#"{"type": "write_param", "drive": 1, "name": "P3", "value": "3.5", "value": "9"}"#))
        .expect("send on the WebSocket");
    let v = recv_until(&mut ws, Duration::from_secs(10), of_type("refused")).expect("refused");
    assert_eq!((&v["request"], &v["error"]["kind"]), (&json!("write_param"), &json!("usage")), "{v}");
    assert!(v["message"].as_str().unwrap().starts_with("key \"value\" given twice"), "{v}");
    send(&mut ws, json!({"type": "read_param", "drive": 1, "name": "3"}));
    let v = recv_until(&mut ws, Duration::from_secs(10), of_type("param")).expect("the read");
    assert_eq!(v["report"]["value"], 2.5, "nothing written: {v}");
    // A read the drive refuses: its Exx number comes as data, as in the command line's `--json` error.
    send(&mut ws, json!({"type": "read_param", "drive": 1, "name": "P13"}));
    let v = recv_until(&mut ws, Duration::from_secs(10), of_type("failed")).expect("refused by the drive");
    assert_eq!(
        (&v["error"]["kind"], &v["error"]["code"], &v["error"]["bits"]),
        (&json!("refused"), &json!(90), &json!([]))
    );
}

#[test]
fn the_error_history_and_the_traffic_log_are_decoded() {
    let c = console(&["compax", "--port", "sim", "--drives", "1"]);
    let mut ws = ws(&c);
    units(&mut ws);
    send(&mut ws, json!({"type": "errors", "drive": 1}));
    let v = recv_until(&mut ws, Duration::from_secs(10), of_type("errors")).expect("the history");
    assert_eq!(v["report"]["errors"].as_array().map(Vec::len), Some(8), "S18's eight entries: {v}");
    let t = recv_until(&mut ws, Duration::from_secs(10), of_type("traffic")).expect("the log");
    let line = &t["lines"][0];
    assert!(line["hex"].is_string() && !line["meaning"].as_str().unwrap().is_empty(), "{t}");
    let (status, capture) = get(&c.host, &format!("/capture?token={}", c.token));
    assert_eq!(status, 200);
    // Every line after the header is a capture line (the format `motionlink_link::capture` reads back)...
    let lines: Vec<&str> = capture.lines().skip(1).collect();
    assert!(lines.len() > 2, "{capture}");
    for l in lines {
        let parsed = motionlink_link::capture::parse_line(l).unwrap_or_else(|e| panic!("{l:?}: {e}"));
        assert!(parsed.is_some(), "{l:?}");
    }
    // ... and `motionlink decode` explains every telegram of it.
    let file = std::env::temp_dir().join(format!("motionlink-console-{}.cap", std::process::id()));
    std::fs::write(&file, &capture).unwrap();
    let decoded = std::process::Command::new(common::BIN)
        .args(["--json", "decode", "compax", "--input"])
        .arg(&file)
        .output()
        .unwrap();
    let _ = std::fs::remove_file(&file);
    assert!(decoded.status.success(), "{}", String::from_utf8_lossy(&decoded.stderr));
    let objects: Vec<Value> =
        String::from_utf8_lossy(&decoded.stdout).lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    assert!(objects.len() > 2, "{objects:?}");
    // The emulated line is paced: the download may end inside a reply, whose start is then all the capture
    // has of it. Every telegram before it is whole.
    let (last, whole) = objects.split_last().unwrap();
    assert!(whole.iter().all(|o| o["bad"] == false && o["direction"] != "??"), "{objects:?}");
    assert!(last["bad"] == false || last["direction"] == "<-", "{last}");
}

/// One family's rules against its emulator over TCP: Stop halts a move, a jog stops by its dead-man
/// deadline, a lost WebSocket stops a move; `rearm` (if any) makes the unit take the next motion after a stop.
struct FamilyCase {
    family: &'static str,
    key: &'static str,
    target_key: &'static str,
    targets: [f64; 2],
    started: fn(&str) -> bool,
    stopped: fn(&str) -> bool,
    rearm: Option<&'static str>,
    /// The console's options naming the units (no scan of all 31 addresses).
    units_named: &'static [&'static str],
    /// The emulator's firmware variants (`motionlink sim <family> --variant`).
    variants: &'static [&'static str],
}

fn family_rules(case: &FamilyCase) {
    let mut sim_args = vec!["--tcp", "127.0.0.1:0"];
    for v in case.variants {
        sim_args.extend(["--variant", v]);
    }
    let sim = Sim::start(case.family, &sim_args);
    let mut args = vec![case.family, "--port", &sim.address];
    args.extend_from_slice(case.units_named);
    let c = console(&args);
    let mut ws = ws(&c);
    let found = units(&mut ws);
    let unit = found[0][case.key].as_u64().expect("a unit number");
    let family = case.family;
    let rearm = |ws: &mut Ws| {
        if let Some(action) = case.rearm {
            send(ws, json!({"type": "action", case.key: unit, "name": action}));
            let v = recv_until(ws, Duration::from_secs(10), |v| v["type"] == "action" || v["type"] == "failed")
                .expect("the action's answer");
            assert_eq!(v["ok"], true, "{family}: {v}");
            assert!(v["report"].is_object(), "{family}: the action's report: {v}");
        }
    };

    // Stop halts a move.
    let begun = unix_now();
    send(&mut ws, json!({"type": "move", case.key: unit, case.target_key: case.targets[0]}));
    sim.wait_event_after(begun, Duration::from_secs(10), case.started).unwrap_or_else(|| {
        panic!("{family}: the move did not start: {:?}", sim.events().iter().map(|e| &e.text).collect::<Vec<_>>())
    });
    let pressed = unix_now();
    send(&mut ws, json!({"type": "stop", case.key: unit}));
    let stopped = sim.wait_event_after(pressed, Duration::from_secs(5), case.stopped).expect("Stop halts the move");
    assert!(stopped.at - pressed < 0.3, "{family}: stopped {:.3} s after Stop", stopped.at - pressed);
    let m = recv_until(&mut ws, Duration::from_secs(5), |v| v["type"] == "motion" && v["state"] == "stopped")
        .expect("the page is told");
    // The report of the stop the device confirmed, as `motionlink <family> stop --json` prints it.
    assert!(m["report"]["action"].is_string(), "{family}: {m}");
    rearm(&mut ws);

    // A jog runs while renewed, then stops by its deadline. (Renewed from the start, as the page does: a
    // module that starts its motion late, `late-motion-start`, shows it after the dead-man time.)
    let begun = unix_now();
    send(&mut ws, json!({"type": "jog", case.key: unit, "direction": "positive"}));
    let started = loop {
        if let Some(e) = sim.events().into_iter().find(|e| e.at >= begun && (case.started)(&e.text)) {
            break e;
        }
        assert!(unix_now() - begun < 10.0, "{family}: the jog starts");
        send(&mut ws, json!({"type": "jog_hold"}));
        recv_until(&mut ws, Duration::from_millis(50), |_| false);
    };
    let mut last_renewal = unix_now();
    while unix_now() - started.at < 0.6 {
        send(&mut ws, json!({"type": "jog_hold"}));
        last_renewal = unix_now();
        recv_until(&mut ws, Duration::from_millis(50), |_| false);
    }
    let early: Vec<_> = sim.events().into_iter().filter(|e| e.at > started.at && (case.stopped)(&e.text)).collect();
    assert!(
        early.is_empty(),
        "{family}: the jog stopped while renewed: {:?}",
        early.iter().map(|e| &e.text).collect::<Vec<_>>()
    );
    let stopped =
        sim.wait_event_after(last_renewal, Duration::from_secs(5), case.stopped).expect("the deadline stops it");
    let after = stopped.at - last_renewal;
    assert!((0.195..0.45).contains(&after), "{family}: stopped {after:.3} s after the last renewal");
    let m = recv_until(&mut ws, Duration::from_secs(5), |v| v["type"] == "motion" && v["state"] == "stopped")
        .expect("the page is told");
    // The report of the stop the device confirmed, as `motionlink <family> stop --json` prints it.
    assert!(m["report"]["action"].is_string(), "{family}: {m}");
    rearm(&mut ws);

    // A lost WebSocket stops the move of its page.
    let begun = unix_now();
    send(&mut ws, json!({"type": "move", case.key: unit, case.target_key: case.targets[1]}));
    sim.wait_event_after(begun, Duration::from_secs(10), case.started).expect("the second move starts");
    let gone = unix_now();
    ws.get_ref().shutdown(std::net::Shutdown::Both).unwrap();
    drop(ws);
    let stopped = sim.wait_event_after(gone, Duration::from_secs(5), case.stopped).expect("a lost page stops it");
    assert!(stopped.at - gone < 0.3, "{family}: stopped {:.3} s after the page went", stopped.at - gone);
}

/// The SCU's case: F1 moves actuator 1.
fn scu_case(variants: &'static [&'static str]) -> FamilyCase {
    FamilyCase {
        family: "scu",
        key: "actuator",
        target_key: "target_counts",
        targets: [800.0, 0.0],
        started: |t| t.starts_with("F1 started"),
        stopped: |t| t == "F1 stopped (RS fast)",
        rearm: None,
        units_named: &[],
        variants,
    }
}

/// The PowerCube's case: module 1, reset after each halt.
fn powercube_case(variants: &'static [&'static str]) -> FamilyCase {
    FamilyCase {
        family: "powercube",
        key: "module",
        target_key: "target_rad",
        targets: [3.0, -3.0],
        started: |t| t.starts_with("module 1 motion started"),
        stopped: |t| t == "module 1 halted",
        rearm: Some("reset"),
        units_named: &["--modules", "1"],
        variants,
    }
}

/// The COMPAX case: drive 1, switched on again after each stop.
fn compax_case(variants: &'static [&'static str]) -> FamilyCase {
    FamilyCase {
        family: "compax",
        key: "drive",
        target_key: "target_units",
        targets: [700.0, -700.0],
        started: |t| t.starts_with("drive 1 motion started"),
        stopped: |t| t == "drive 1 switched off (O0=0)",
        rearm: Some("switch_on"),
        units_named: &["--drives", "1"],
        variants,
    }
}

#[test]
fn scu_stop_jog_dead_man_and_lost_page() {
    family_rules(&scu_case(&[]));
}

#[test]
fn powercube_stop_jog_dead_man_and_lost_page() {
    family_rules(&powercube_case(&[]));
}

#[test]
fn compax_stop_jog_dead_man_and_lost_page() {
    family_rules(&compax_case(&[]));
}

#[test]
fn with_json_the_one_line_is_a_json_object() {
    let running = common::Running::start(&["--json", "console", "scu", "--port", "sim"]);
    let line = running.stdout.wait_for(Duration::from_secs(20), |l| !l.is_empty()).expect("a line on stdout");
    let value: serde_json::Value = serde_json::from_str(&line).unwrap_or_else(|e| panic!("{line}: {e}"));
    let url = value["console"].as_str().unwrap_or_default();
    assert!(url.starts_with("http://127.0.0.1:") && url.contains("/?token="), "{line}");
}

/// The console takes its family command's session options, declared once for both: the same bad value is
/// refused with the same message, an emulator's option is refused on a port that is no emulator, and a
/// firmware variant of the emulated device is run (its units found and sampled as on the plain device).
#[test]
fn the_console_takes_its_family_command_s_options_by_the_same_rules() {
    let refused: [(&[&str], &str); 3] = [
        (&["scu", "--port", "sim", "--timeout-ms", "0"], "info"),
        (&["powercube", "--port", "tcp://127.0.0.1:9", "--sim-variant", "no-twin-mirror"], "state"),
        (&["compax", "--port", "sim", "--baud", "1234"], "status"),
    ];
    for (options, action) in refused {
        let command = common::run_with(&[options, &[action]].concat(), &[], "");
        let said = String::from_utf8_lossy(&command.stderr);
        assert_eq!(command.status.code(), Some(2), "{said}");
        let console = Running::start(&[&["console"], options].concat()).wait(Duration::from_secs(20));
        assert_eq!(console.code(), 2, "{}", console.stderr);
        let first = |text: &str| text.lines().next().unwrap_or_default().to_string();
        assert_eq!(first(&console.stderr), first(&said), "{options:?}");
    }
    for (family, options, key) in [
        ("scu", &["--timeout-ms", "500", "--sim-variant", "no-groups"][..], "position_counts"),
        ("powercube", &["--modules", "1", "--sim-variant", "no-twin-mirror", "--poll-ms", "20"][..], "position_rad"),
        ("powercube", &["--modules", "1", "--sim-variant", "no-pos-state-dio,ack-length-6"][..], "position_rad"),
        ("scu", &["--sim-variant", "no-cyclic-objects,sticky-errors"][..], "position_counts"),
        // A battery unit in low-power mode, woken by the console's break before it opens.
        ("scu", &["--sim-variant", "low-power", "--wake"][..], "position_counts"),
        ("compax", &["--drives", "1", "--sim-variant", "no-echo"][..], "position_units"),
        ("compax", &["--drives", "1", "--sim-variant", "status-value-only"][..], "position_units"),
        ("compax", &["--drives", "1", "--sim-variant", "echo-without-address", "--short"][..], "position_units"),
        // Replies 300 ms late, with the reply timeout such a drive needs.
        ("compax", &["--drives", "1", "--sim-variant", "slow-replies", "--timeout-ms", "600"][..], "position_units"),
    ] {
        let c = console(&[&[family, "--port", "sim"], options].concat());
        let mut ws = ws(&c);
        assert!(!units(&mut ws).is_empty(), "{family}");
        let sample = recv_until(&mut ws, Duration::from_secs(10), of_type("sample")).expect("a sample");
        assert!(sample["units"][0][key].is_number(), "{family}: {sample}");
    }
}

/// The console's rules hold on every firmware variant of each family's emulator that the library takes as
/// it is (Stop, the jog's dead-man deadline, a lost page); on those whose moves the library refuses by
/// design (a watchdog it cannot arm), the page is told why and nothing moves. (A COMPAX drive that echoes
/// without storing gets its moves as commands of their own, so it is run with the others.) A COMPAX drive
/// that answers 300 ms late (`slow-replies`) is not: the rules' times (Stop within 0.3 s, the jog's stop
/// within 0.45 s of its last renewal) are shorter than one of its replies, and the stop reads S17 before it
/// switches the drive off; the console is run against it, with the reply timeout it needs, in
/// `the_console_takes_its_family_command_s_options_by_the_same_rules`.
#[test]
fn the_console_s_rules_hold_on_every_firmware_variant() {
    // Every variant the library knows (a new one is run here as soon as it exists), but those whose moves
    // the library refuses by design, which are told apart below, and the one too slow for the rules' times.
    let refused: [&'static [&'static str]; 2] = [&["life-sign-unacknowledged"], &["no-config-word"]];
    use motionlink_link::emulator::FirmwareVariant;
    let each = |names: Vec<String>| -> Vec<&'static [&'static str]> {
        names
            .into_iter()
            .filter(|v| !refused.iter().any(|r| r[0] == v))
            .map(|v| &*Box::leak(Box::new([&*Box::leak(v.into_boxed_str())])) as &'static [&'static str])
            .collect()
    };
    // A unit in low-power mode cannot be served (no break wakes it over TCP): its console runs on `--port
    // sim` with `--wake` in `the_console_takes_its_family_command_s_options_by_the_same_rules`.
    let served = motionlink_scu::Variant::ALL.iter().filter(|v| **v != motionlink_scu::Variant::LowPower);
    for v in each(served.map(ToString::to_string).collect()) {
        family_rules(&scu_case(v));
    }
    for v in each(motionlink_powercube::sim::Variant::ALL.iter().map(ToString::to_string).collect()) {
        family_rules(&powercube_case(v));
    }
    let too_slow_for_the_rules_times = [motionlink_compax::sim::Variant::SlowReplies];
    let compax = motionlink_compax::sim::Variant::ALL.iter().filter(|v| !too_slow_for_the_rules_times.contains(v));
    for v in each(compax.map(ToString::to_string).collect()) {
        family_rules(&compax_case(v));
    }
    for variant in refused {
        let (case, why) = (powercube_case(variant), "watchdog");
        let sim = Sim::start(case.family, &["--tcp", "127.0.0.1:0", "--variant", case.variants[0]]);
        let c = console(&[&[case.family, "--port", &sim.address], case.units_named].concat());
        let mut ws = ws(&c);
        let unit = units(&mut ws)[0][case.key].as_u64().expect("a unit number");
        send(&mut ws, json!({"type": "move", case.key: unit, case.target_key: case.targets[0]}));
        let told = recv_until(&mut ws, Duration::from_secs(10), |v| {
            v["type"] == "failed" || (v["type"] == "motion" && v["ok"] == false)
        })
        .unwrap_or_else(|| panic!("{}: the page is not told that the move failed", case.variants[0]));
        assert!(told.to_string().contains(why), "{}: {told}", case.variants[0]);
        assert!(!sim.events().iter().any(|e| (case.started)(&e.text)), "{}: something moved", case.variants[0]);
    }
}

#[test]
fn an_scu_move_without_a_speed_takes_every_front_end_s_default_not_the_maximum() {
    // A unit set to absolute speed (counts/s, at most 1000): the default is 100 counts/s, as `scu move`,
    // the gateway and Python take it (was: the maximum, ten times faster from the browser).
    let c = console(&["scu", "--port", "sim", "--speed-mode", "counts-per-second"]);
    let mut ws = ws(&c);
    units(&mut ws);
    // Another speed first: the move writes its own (the unit starts at 100).
    send(&mut ws, json!({"type": "write_param", "actuator": 1, "name": "remote_speed_f1", "value": "500"}));
    let v = recv_until(&mut ws, Duration::from_secs(10), of_type("param")).expect("the write");
    assert_eq!(v["report"]["read_back"], 500, "{v}");
    send(&mut ws, json!({"type": "move", "actuator": 1, "target_counts": 30.0}));
    let m = recv_until(&mut ws, Duration::from_secs(20), |v| v["type"] == "motion" && v["state"] != "running")
        .expect("the move ends");
    assert_eq!(m["ok"], true, "{m}");
    send(&mut ws, json!({"type": "read_param", "actuator": 1, "name": "remote_speed_f1"}));
    let v = recv_until(&mut ws, Duration::from_secs(10), of_type("param")).expect("the read");
    assert_eq!(v["report"]["value"], 100, "{v}");
}

#[test]
fn a_console_move_takes_the_tolerance_of_its_family_s_command() {
    // COMPAX: `--tolerance` and `--poll-ms` (a device's keys, as for `compax move`) are the session's: the
    // move's report names the tolerance it was checked against (was: always the default, 0.01).
    let drive = console(&["compax", "--port", "sim", "--drives", "1", "--tolerance", "0.5", "--poll-ms", "20"]);
    let mut page = ws(&drive);
    units(&mut page);
    send(&mut page, json!({"type": "move", "drive": 1, "target_units": 10.0}));
    let m = recv_until(&mut page, Duration::from_secs(20), |v| v["type"] == "motion" && v["state"] != "running")
        .expect("the move ends");
    assert_eq!((&m["ok"], &m["report"]["tolerance_units"]), (&json!(true), &json!(0.5)), "{m}");
    // PowerCube: its `--tolerance` takes the values, and gives the message, of `powercube move --tolerance`.
    let said = common::run_with(&["powercube", "--port", "sim", "move", "0.1", "--tolerance", "0.5"], &[], "");
    let said = String::from_utf8_lossy(&said.stderr).lines().next().unwrap_or_default().to_string();
    assert!(said.contains("--tolerance") && said.contains("0.5"), "{said}");
    let ended = Running::start(&["console", "powercube", "--port", "sim", "--tolerance", "0.5"]);
    let ended = ended.wait(Duration::from_secs(20));
    assert_eq!(ended.code(), 2, "{}", ended.stderr);
    assert_eq!(ended.stderr.lines().next().unwrap_or_default(), said);
    // (A PowerCube move's report does not name its tolerance, and the emulator ends a ramp on its target:
    // that the console's move takes the value is read in console/powercube.rs, not seen here.)
}

/// The answer to `request`: the first `refused`, `failed`, `stopped`, `param`, `errors` or `action` message,
/// or a `motion` message (a motion started), within 5 s.
fn answer_to(ws: &mut Ws, request: Value) -> Value {
    send(ws, request.clone());
    let kinds = ["refused", "failed", "stopped", "param", "errors", "action", "motion"];
    recv_until(ws, Duration::from_secs(5), |v| kinds.iter().any(|k| v["type"] == *k))
        .unwrap_or_else(|| panic!("no answer to {request}"))
}

#[test]
fn every_request_refuses_a_key_it_does_not_take_naming_it_and_the_keys_it_takes() {
    let c = console(&["scu", "--port", "sim"]);
    let mut ws = ws(&c);
    units(&mut ws);
    // A move's speed under the jog's key: refused, not run at the default 100 % (was: it ran at 100 %).
    let v = answer_to(&mut ws, json!({"type": "move", "actuator": 1, "target_counts": 400, "speed": 10}));
    assert_eq!((&v["type"], &v["request"], &v["error"]["kind"]), (&json!("refused"), &json!("move"), &json!("usage")));
    assert_eq!(
        v["message"],
        "unknown key \"speed\": a move of actuator 1 takes \"type\", \"actuator\", \"target_counts\", \
         \"speed_percent\" only",
        "{v}"
    );
    // Every request type the console handles, each with a key it does not take.
    let takes: [(&str, Value, &str); 10] = [
        ("stop", json!({"actuator": 1}), "\"type\", \"actuator\""),
        (
            "move",
            json!({"actuator": 1, "target_counts": 10}),
            "\"type\", \"actuator\", \"target_counts\", \"speed_percent\"",
        ),
        ("jog", json!({"actuator": 1, "direction": "positive"}), "\"type\", \"actuator\", \"direction\", \"speed\""),
        ("jog_hold", json!({}), "\"type\""),
        ("jog_release", json!({}), "\"type\""),
        ("take_control", json!({}), "\"type\""),
        ("action", json!({"actuator": 1, "name": "x"}), "\"type\", \"actuator\", \"name\""),
        ("read_param", json!({"actuator": 1, "name": "remote_speed_f1"}), "\"type\", \"actuator\", \"name\""),
        (
            "write_param",
            json!({"actuator": 1, "name": "remote_speed_f1", "value": "50"}),
            "\"type\", \"actuator\", \"name\", \"value\"",
        ),
        ("errors", json!({"actuator": 1}), "\"type\", \"actuator\""),
    ];
    for (kind, mut request, keys) in takes {
        request["type"] = json!(kind);
        request["bogus"] = json!(1);
        let v = answer_to(&mut ws, request.clone());
        assert_eq!((&v["type"], &v["request"]), (&json!("refused"), &json!(kind)), "{request}: {v}");
        let message = v["message"].as_str().unwrap_or_default();
        let of = if kind == "move" { "a move of actuator 1".to_string() } else { format!("a {kind} request") };
        assert!(message.starts_with(&format!("unknown key \"bogus\": {of} takes {keys} only")), "{request}: {v}");
    }
    // Two unknown keys are both named.
    let v = answer_to(&mut ws, json!({"type": "errors", "actuator": 1, "drive": 1, "module": 2}));
    assert!(v["message"].as_str().unwrap_or_default().starts_with("unknown keys \"drive\", \"module\": "), "{v}");
    // Nothing of it moved the actuator: the move with its right keys is the first motion, at the speed given.
    let v = answer_to(&mut ws, json!({"type": "move", "actuator": 1, "target_counts": 30, "speed_percent": 100}));
    assert_eq!((&v["type"], &v["state"]), (&json!("motion"), &json!("running")), "{v}");
    let m = recv_until(&mut ws, Duration::from_secs(20), |v| v["type"] == "motion" && v["state"] != "running")
        .expect("the move ends");
    assert_eq!(m["ok"], true, "{m}");
}

#[test]
fn each_unit_says_what_a_move_and_a_jog_given_no_speed_go_at() {
    // SCU: a move with no speed runs at 100 (every front end's default), a jog at the unit's remote speed.
    for (family, move_default, jog_default) in [
        ("scu", "100 %", "the unit's remote_speed_f1 as it is"),
        ("powercube", "the module's TargetVel as it is", "the module's TargetVel as it is"),
        ("compax", "the drive's SPEED setting as it is", "the drive's SPEED setting as it is"),
    ] {
        let c = console(&[family, "--port", "sim"]);
        let mut ws = ws(&c);
        let found = units(&mut ws);
        let u = &found[0];
        assert_eq!(
            (&u["move_speed_when_empty"], &u["jog_speed_when_empty"]),
            (&json!(move_default), &json!(jog_default)),
            "{family}: {u}"
        );
    }
}

#[test]
fn a_unit_not_found_or_no_unit_number_is_refused_before_anything_is_sent() {
    let (sim, c) = compax_on_sim();
    let mut ws = ws(&c);
    units(&mut ws);
    let not_found = "drive 9 was not found: the console found drive 1";
    // Each request that names a unit (was: read_param, write_param, stop, jog and the action went to the
    // wire and ended in a timeout).
    for request in [
        json!({"type": "read_param", "drive": 9, "name": "P194"}),
        json!({"type": "write_param", "drive": 9, "name": "P3", "value": "1"}),
        json!({"type": "stop", "drive": 9}),
        json!({"type": "jog", "drive": 9, "direction": "positive"}),
        json!({"type": "action", "drive": 9, "name": "switch_on"}),
        json!({"type": "move", "drive": 9, "target_units": 5}),
        json!({"type": "errors", "drive": 9}),
    ] {
        let v = answer_to(&mut ws, request.clone());
        assert_eq!((&v["type"], &v["request"]), (&json!("refused"), &request["type"]), "{request}: {v}");
        assert!(v["message"].as_str().unwrap_or_default().starts_with(not_found), "{request}: {v}");
    }
    // A number no drive can have is named with the range (was: "the request names no drive").
    for (given, shown) in
        [(json!(300), "300"), (json!(-1), "-1"), (json!(1.5), "1.5"), (json!(0), "0"), (json!("1"), "\"1\"")]
    {
        for kind in ["move", "read_param", "stop"] {
            let request = match kind {
                "move" => json!({"type": kind, "drive": given, "target_units": 5}),
                "read_param" => json!({"type": kind, "drive": given, "name": "P3"}),
                _ => json!({"type": kind, "drive": given}),
            };
            let v = answer_to(&mut ws, request.clone());
            assert_eq!(v["type"], "refused", "{request}: {v}");
            let message = v["message"].as_str().unwrap_or_default();
            let expected = format!("drive {shown} is not a drive number: give a whole number 1..31");
            assert!(message.starts_with(&expected), "{request}: {v}");
        }
    }
    let v = answer_to(&mut ws, json!({"type": "read_param", "name": "P3"}));
    assert_eq!(v["message"], "the request names no drive: give \"drive\", a number 1..31", "{v}");
    // A Stop naming a unit not found sends nothing to it, and still stops the console's motion under way.
    let begun = unix_now();
    send(&mut ws, json!({"type": "move", "drive": 1, "target_units": 800.0}));
    sim.wait_event_after(begun, Duration::from_secs(10), |t| t.starts_with("drive 1 motion started"))
        .expect("it moves");
    let pressed = unix_now();
    send(&mut ws, json!({"type": "stop", "drive": 9}));
    let v = recv_until(&mut ws, Duration::from_secs(5), |v| {
        ["refused", "failed", "stopped"].contains(&v["type"].as_str().unwrap_or_default())
    })
    .expect("the answer to the stop");
    assert_eq!(v["type"], "refused", "{v}");
    assert_eq!(
        v["message"],
        format!(
            "{not_found}; the motion under way (move of drive 1) is stopped all the same (its motion message \
             reports the stop)"
        ),
        "{v}"
    );
    sim.wait_event_after(pressed, Duration::from_secs(5), |t| t == "drive 1 switched off (O0=0)").expect("stopped");
    let m = recv_until(&mut ws, Duration::from_secs(5), |v| v["type"] == "motion" && v["state"] == "stopped")
        .expect("the page is told");
    assert_eq!(m["ok"], true, "{m}");
    // The Stop without a unit still stops what the console set in motion.
    let v = answer_to(&mut ws, json!({"type": "stop"}));
    assert_eq!(v["type"], "stopped", "{v}");
}
