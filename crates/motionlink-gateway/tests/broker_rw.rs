//! Reads, writes and SCU `run` through the gateway against a real broker (mosquitto on a free loopback
//! port): SCU `get`/`set` and a leased `run`, PowerCube `get`/`set`, COMPAX `status`/`get`/`set`/`output`,
//! each answered with the `--json` object of the command line's same action; a write refused while a motion
//! of the device runs.
//! Without mosquitto each test says it is skipped, by name (MOTIONLINK_REQUIRE_BROKER=1 makes that a
//! failure).

#![cfg(unix)]

use std::time::Duration;

use serde_json::{json, Value};

#[path = "broker/harness.rs"]
mod harness;

use harness::{broker, gateway, Client, ALL};

const S: Duration = Duration::from_secs(1);

/// The reply to `op` with `args` on `device` of gateway `gw`.
async fn ask(c: &mut Client, gw: &str, device: &str, id: &str, op: &str, args: Value) -> Value {
    ask_within(c, gw, device, id, op, args, 10 * S).await
}

/// [`ask`], the reply awaited for `within`.
async fn ask_within(
    c: &mut Client,
    gw: &str,
    device: &str,
    id: &str,
    op: &str,
    args: Value,
    within: Duration,
) -> Value {
    let body = json!({"id": id, "op": op, "args": args, "reply_to": "me/r"});
    c.send(&format!("motionlink/{gw}/{device}/cmd"), body.to_string()).await;
    c.reply("me/r", id, within).await
}

/// The reply's result without its identity (`family`, `port`, `profile`, `module`, `drive`), checked to be the
/// device's (no device profile: null, as the command line's `--json` names it).
fn result(r: &Value, family: &str) -> Value {
    assert_eq!((r["ok"].as_bool(), r["result"]["family"].as_str()), (Some(true), Some(family)), "{r}");
    let mut m = r["result"].as_object().expect("an object").clone();
    assert_eq!(m.remove("port"), Some(json!("sim")), "{r}");
    assert_eq!(m.remove("profile"), Some(Value::Null), "{r}");
    for k in ["family", "module", "drive"] {
        m.remove(k);
    }
    Value::Object(m)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn reads_and_writes_answer_with_the_cli_s_json() {
    let Some(b) = broker("reads_and_writes_answer_with_the_cli_s_json") else { return };
    let _gw = gateway(&b, "rw", ALL);
    let mut c = Client::connect(&b, "t-rw", &["motionlink/rw/status", "me/#"]).await;
    c.wait("online", 20 * S, |m| m.topic == "motionlink/rw/status" && m.payload == "online").await;

    // SCU: a data-list entry by name, written (read back by the library) and read again.
    let r = ask(&mut c, "rw", "lift", "g1", "get", json!({"item": "remote_speed_f1"})).await;
    let read = json!({"access": "rw", "id": 0x3011, "name": "remote_speed_f1", "unit": "%", "value": 100});
    assert_eq!(result(&r, "scu"), read);
    let r = ask(&mut c, "rw", "lift", "s1", "set", json!({"item": "remote_speed_f1", "value": 80})).await;
    let w = result(&r, "scu");
    assert_eq!(
        (w["value"].as_i64(), w["read_back"].as_i64(), w["verified"].as_bool()),
        (Some(80), Some(80), Some(true))
    );
    let r = ask(&mut c, "rw", "lift", "g2", "get", json!({"item": "0x3011"})).await;
    assert_eq!(result(&r, "scu")["value"], 80, "{r}");

    // PowerCube: a parameter by name, in the module's unit; a write read back.
    let r = ask(&mut c, "rw", "arm", "g3", "get", json!({"param": "ActPos"})).await;
    let p = result(&r, "powercube");
    assert_eq!(
        (p["name"].as_str(), p["id"].as_u64(), p["unit"].as_str()),
        (Some("ActPos"), Some(60), Some("rad")),
        "{r}"
    );
    assert!(p["value"].is_f64(), "{r}");
    let r = ask(&mut c, "rw", "arm", "s2", "set", json!({"param": "TargetVel", "value": 0.2})).await;
    let w = result(&r, "powercube");
    assert_eq!((w["name"].as_str(), w["verified"].as_bool()), (Some("TargetVel"), Some(true)), "{r}");
    assert!((w["read_back"].as_f64().unwrap() - 0.2).abs() < 1e-4, "{r}");

    // COMPAX: status values (named, and the default overview), a parameter read and written, an output.
    let r = ask(&mut c, "rw", "axis", "st1", "status", json!({"values": ["S1", "S17"]})).await;
    let st = result(&r, "compax");
    let ids: Vec<&str> = st["status"].as_array().unwrap().iter().map(|v| v["status"].as_str().unwrap()).collect();
    assert_eq!(ids, ["S1", "S17"], "{r}");
    assert_eq!(st["status"][0]["value"], 0.0, "{r}");
    let r = ask(&mut c, "rw", "axis", "st2", "status", json!({})).await;
    let ids: Vec<String> =
        result(&r, "compax")["status"].as_array().unwrap().iter().map(|v| v["status"].to_string()).collect();
    assert_eq!(ids.join(" "), r#""S1" "S2" "S3" "S16" "S17" "S18""#, "{r}");
    let r = ask(&mut c, "rw", "axis", "s3", "set", json!({"param": "P196", "value": 8})).await;
    let w = result(&r, "compax");
    assert_eq!(
        (w["name"].as_str(), w["read_back"].as_f64(), w["verified"].as_bool()),
        (Some("P196"), Some(8.0), Some(true))
    );
    let r = ask(&mut c, "rw", "axis", "g4", "get", json!({"param": "P196"})).await;
    assert_eq!(result(&r, "compax")["value"], 8.0, "{r}");
    let r = ask(&mut c, "rw", "axis", "o1", "output", json!({"number": 0, "state": 1})).await;
    assert_eq!(
        result(&r, "compax"),
        json!({"output": 0, "state": 1, "read_back": 1, "verified": true, "not_verifiable": []})
    );
    // A read the drive refuses: its Exx number as data, as the command line's `--json` error gives it.
    let r = ask(&mut c, "rw", "axis", "g5", "get", json!({"param": "P13"})).await;
    let e = &r["error"];
    assert_eq!((e["kind"].as_str(), e["exit_code"].as_i64(), e["code"].as_u64()), (Some("refused"), Some(1), Some(90)));
    assert_eq!(e["bits"], json!([]), "{r}");

    // Bad arguments: the family's rule and message, nothing sent.
    for (device, op, args, says) in [
        ("lift", "get", json!({"item": "remote_sped_f1"}), "not in the data list"),
        ("lift", "set", json!({"item": "actual_position_a1", "value": 3}), "read-only"),
        ("lift", "set", json!({"item": "remote_speed_f1"}), "\"value\" is missing"),
        ("arm", "get", json!({"param": "NoSuch"}), "param"),
        ("axis", "status", json!({"values": ["S1", "X9"]}), "values"),
        ("axis", "output", json!({"number": 0, "state": 7}), "state"),
        ("axis", "set", json!({"param": "P196", "value": "NaN"}), "parameter value"),
    ] {
        let r = ask(&mut c, "rw", device, "bad", op, args.clone()).await;
        assert_eq!((r["ok"].as_bool(), r["error"]["exit_code"].as_u64()), (Some(false), Some(2)), "{args}: {r}");
        assert!(r["error"]["message"].as_str().unwrap().contains(says), "{args}: {r}");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_write_is_refused_while_the_device_s_motion_runs() {
    let Some(b) = broker("a_write_is_refused_while_the_device_s_motion_runs") else { return };
    let _gw = gateway(&b, "wm", ALL);
    let mut c = Client::connect(&b, "t-wm", &["motionlink/wm/#", "me/#"]).await;
    c.wait("online", 20 * S, |m| m.topic == "motionlink/wm/status" && m.payload == "online").await;
    let body =
        json!({"id": "m1", "op": "move", "args": {"abs": 1000, "speed": 10}, "reply_to": "me/m", "lease_ms": 5000});
    c.send("motionlink/wm/axis/cmd", body.to_string()).await;
    c.wait("moving", 5 * S, |m| m.topic == "motionlink/wm/axis/state" && m.json()["moving"] == true).await;
    let r = ask(&mut c, "wm", "axis", "w1", "set", json!({"param": "P196", "value": 8})).await;
    assert_eq!((r["ok"].as_bool(), r["error"]["kind"].as_str()), (Some(false), Some("busy")), "{r}");
    assert!(r["error"]["message"].as_str().unwrap().contains("running move \"m1\""), "{r}");
    // A read is served meanwhile; the motion goes on until stopped.
    let r = ask(&mut c, "wm", "axis", "g1", "get", json!({"param": "P196"})).await;
    assert_eq!(r["ok"], true, "{r}");
    let r = ask(&mut c, "wm", "axis", "s1", "stop", json!({})).await;
    assert_eq!(r["ok"], true, "{r}");
    let m = c.reply("me/m", "m1", 10 * S).await;
    assert_eq!(m["error"]["kind"], "cancelled", "{m}");
    // Once it has ended the write is served.
    let r = ask(&mut c, "wm", "axis", "w2", "set", json!({"param": "P196", "value": 8})).await;
    assert_eq!(r["ok"], true, "{r}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_scu_run_is_held_by_its_lease_and_kept_alive_ends_at_its_end_of_travel() {
    let Some(b) = broker("an_scu_run_is_held_by_its_lease_and_kept_alive_ends_at_its_end_of_travel") else { return };
    let _gw = gateway(&b, "rn", ALL);
    let mut c = Client::connect(&b, "t-rn", &["motionlink/rn/#", "me/#"]).await;
    c.wait("online", 20 * S, |m| m.topic == "motionlink/rn/status" && m.payload == "online").await;
    let run = |id: &str| json!({"id": id, "op": "run", "args": {"function": "F1", "direction": "out"}, "reply_to": "me/r", "lease_ms": 300});
    // No keepalive: the lease lapses and the run is stopped short of the end of travel (865 counts).
    c.send("motionlink/rn/lift/cmd", run("r0").to_string()).await;
    let r = c.reply("me/r", "r0", 10 * S).await;
    assert_eq!((r["ok"].as_bool(), r["error"]["kind"].as_str()), (Some(false), Some("lease_expired")), "{r}");
    c.drain();
    let m = c.wait("at rest", 3 * S, |m| m.topic == "motionlink/rn/lift/state").await.json();
    let stopped_at = m["actuators"][0]["position_counts"].as_i64().unwrap();
    assert!((0..865).contains(&stopped_at) && m["actuators"][0]["moving"] == false, "{m}");
    // Kept alive: to the end of travel, the CLI's `run --json` object.
    c.send("motionlink/rn/lift/cmd", run("r1").to_string()).await;
    let keep = {
        let (mqtt, body) = (c.mqtt.clone(), json!({"id": "r1", "op": "keepalive"}).to_string());
        tokio::spawn(async move {
            loop {
                let q = rumqttc::v5::mqttbytes::QoS::AtLeastOnce;
                let _ = mqtt.publish("motionlink/rn/lift/cmd", q, false, body.clone()).await;
                tokio::time::sleep(Duration::from_millis(100)).await;
            }
        })
    };
    let r = c.reply("me/r", "r1", 120 * S).await;
    keep.abort();
    assert_eq!(
        result(&r, "scu"),
        json!({"actuators": [{"actuator": 1, "reached_counts": 865}, {"actuator": 2, "reached_counts": 0}],
               "function": 1, "interrupted": false, "stopped": true})
    );
    let events: Vec<Value> =
        c.drain().iter().filter(|m| m.topic == "motionlink/rn/lift/events").map(|m| m.json()).collect();
    let said: Vec<(&str, &str)> =
        events.iter().map(|e| (e["event"].as_str().unwrap(), e["op"].as_str().unwrap_or(""))).collect();
    assert_eq!(said, [("motion_started", "run"), ("motion_ended", "run")], "{events:?}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_device_table_s_action_options_are_the_device_s_defaults() {
    let Some(b) = broker("a_device_table_s_action_options_are_the_device_s_defaults") else { return };
    // Keys of devices.toml: options of the device, of its actions (defaults), and of watch and the
    // console (accepted, ignored).
    let devices = r#"
[device.axis]
family = "compax"
port = "sim"
max_pos = 50
speed = 100
csv = true
jog_range = 5

[device.lift]
family = "scu"
port = "sim"
speed = 100
soft = true
capture = "ignored.cap"
"#;
    let _gw = gateway(&b, "df", devices);
    let mut c = Client::connect(&b, "t-df", &["motionlink/df/status", "me/#"]).await;
    c.wait("online", 20 * S, |m| m.topic == "motionlink/df/status" && m.payload == "online").await;
    // The device's max_pos refuses a target beyond it, before anything moves...
    let r = ask(&mut c, "df", "axis", "m1", "move", json!({"abs": 100})).await;
    assert_eq!((r["ok"].as_bool(), r["error"]["kind"].as_str()), (Some(false), Some("usage")), "{r}");
    assert!(r["error"]["message"].as_str().unwrap().contains("50"), "{r}");
    let r = ask(&mut c, "df", "axis", "p1", "status", json!({"values": "S1"})).await;
    assert_eq!(result(&r, "compax")["status"][0]["value"], 0.0, "{r}");
    // ...and a request's own max_pos overrides it.
    let body =
        json!({"id": "m2", "op": "move", "args": {"abs": 100, "max_pos": 200}, "reply_to": "me/r", "lease_ms": 10000});
    c.send("motionlink/df/axis/cmd", body.to_string()).await;
    let r = c.reply("me/r", "m2", 30 * S).await;
    assert_eq!(result(&r, "compax")["verified"], true, "{r}");
    // The SCU's soft stop is its stop's default.
    let r = ask(&mut c, "df", "lift", "s1", "stop", json!({})).await;
    assert_eq!(result(&r, "scu")["mode"], "soft", "{r}");
    let r = ask(&mut c, "df", "lift", "s2", "stop", json!({"soft": false})).await;
    assert_eq!(result(&r, "scu")["mode"], "fast", "{r}");
}

#[test]
fn a_device_table_key_no_command_takes_is_refused_naming_it() {
    let Some(b) = broker("a_device_table_key_no_command_takes_is_refused_naming_it") else { return };
    let gw = gateway(&b, "uk", "[device.axis]\nfamily = \"compax\"\nport = \"sim\"\nmax_poss = 50\n");
    let (code, err) = gw.signal(0);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("[device.axis]: unknown key `max_poss`") && err.contains("max_pos"), "{err}");
}

#[test]
fn two_device_tables_on_one_port_are_refused_at_start_naming_both_and_the_port() {
    // Two drives of one COMPAX bus, one table each: not "another process" holding the port (the gateway's
    // own lock), but a usage error before anything is opened, naming both tables and the port.
    let Some(b) = broker("two_device_tables_on_one_port_are_refused_at_start_naming_both_and_the_port") else {
        return;
    };
    let port = format!("tcp://127.0.0.1:{}", b.port);
    let devices = format!(
        "[device.d]\nfamily = \"compax\"\nport = \"{port}\"\n\n\
         [device.e]\nfamily = \"compax\"\nport = \"{port}\"\ndrive = 2\n"
    );
    let gw = gateway(&b, "dp", &devices);
    let pid = gw.pid();
    let (code, err) = gw.signal(0);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains(&format!("[device.d] and [device.e] both name the port \"{port}\"")), "{err}");
    assert!(err.contains("a gateway serves one device per port"), "{err}");
    assert!(!err.contains(&format!("pid {pid}")) && !err.contains("stop"), "{err}");
}

/// The objects of a list result, each without its `port` (checked to be `sim`).
fn listed(r: &Value) -> Vec<Value> {
    assert_eq!(r["ok"], true, "{r}");
    let items = r["result"].as_array().unwrap_or_else(|| panic!("a list: {r}"));
    items
        .iter()
        .map(|o| {
            let mut m = o.as_object().expect("an object").clone();
            assert_eq!(m.remove("port"), Some(json!("sim")), "{r}");
            Value::Object(m)
        })
        .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn several_items_in_one_get_and_a_scan_answer_with_the_cli_s_json_lines() {
    let Some(b) = broker("several_items_in_one_get_and_a_scan_answer_with_the_cli_s_json_lines") else { return };
    let _gw = gateway(&b, "sc", ALL);
    let mut c = Client::connect(&b, "t-sc", &["motionlink/sc/status", "me/#"]).await;
    c.wait("online", 20 * S, |m| m.topic == "motionlink/sc/status" && m.payload == "online").await;

    // `get` of several names: one reply, the list of the objects the command line prints one per line.
    let r = ask(&mut c, "sc", "lift", "g1", "get", json!({"items": ["actual_position_a1", "remote_speed_f1"]})).await;
    let got = listed(&r);
    let names: Vec<&str> = got.iter().map(|o| o["name"].as_str().unwrap()).collect();
    assert_eq!(names, ["actual_position_a1", "remote_speed_f1"], "{r}");
    assert_eq!((got[0]["family"].as_str(), got[1]["value"].as_i64()), (Some("scu"), Some(100)), "{r}");
    let r = ask(&mut c, "sc", "arm", "g2", "get", json!({"params": ["ActPos", "MaxPos"]})).await;
    let got = listed(&r);
    assert_eq!((got[0]["name"].as_str(), got[1]["name"].as_str()), (Some("ActPos"), Some("MaxPos")), "{r}");
    assert_eq!((got[1]["module"].as_u64(), got[1]["unit"].as_str()), (Some(1), Some("rad")), "{r}");
    let r = ask(&mut c, "sc", "axis", "g3", "get", json!({"params": ["P194", "P196"]})).await;
    let got = listed(&r);
    assert_eq!(
        got.iter().map(|o| (o["name"].as_str().unwrap(), o["value"].as_f64().unwrap())).collect::<Vec<_>>(),
        [("P194", 1.0), ("P196", 0.0)],
        "{r}"
    );
    // Every name checked before anything is read; one name and a list at once is refused.
    let r = ask(&mut c, "sc", "arm", "g4", "get", json!({"params": ["ActPos", "NoSuch"]})).await;
    assert_eq!(r["error"]["kind"], "usage", "{r}");
    assert!(r["error"]["message"].as_str().unwrap().contains("NoSuch"), "{r}");
    let r = ask(&mut c, "sc", "axis", "g5", "get", json!({"param": "P194", "params": ["P196"]})).await;
    assert!(r["error"]["message"].as_str().unwrap().contains("not both"), "{r}");
    // A read that fails ends the reply with its error, as the command line's exit.
    let r = ask(&mut c, "sc", "arm", "g6", "get", json!({"params": ["ActPos", "TargetVel"]})).await;
    assert!(r["error"]["message"].as_str().unwrap().contains("write-only"), "{r}");

    // `scan`: the modules and drives on the bus, as `scan --json` lists them.
    let r = ask(&mut c, "sc", "arm", "sc1", "scan", json!({})).await;
    let found = listed(&r);
    assert_eq!(found.len(), 1, "{r}");
    assert_eq!(
        (found[0]["family"].as_str(), found[0]["module"].as_u64(), found[0]["kind"].as_str()),
        (Some("powercube"), Some(1), Some("rotary")),
        "{r}"
    );
    assert!(found[0]["serial"].is_u64() && found[0]["state"]["flags"].is_array(), "{r}");
    // 30 addresses without a drive, each the reply timeout and as long again for a late reply (9600 baud):
    // about 14 s.
    let r = ask_within(&mut c, "sc", "axis", "sc2", "scan", json!({}), 25 * S).await;
    assert_eq!(listed(&r), [json!({"drive": 1, "family": "compax", "position_units": 0.0})], "{r}");
    let r = ask(&mut c, "sc", "lift", "sc3", "scan", json!({})).await;
    assert!(r["error"]["message"].as_str().unwrap().contains("not an action of a scu device"), "{r}");
}
