//! The gateway against a real broker (mosquitto on a free loopback port): retained status and states,
//! leased motions in every family, lease expiry, stop, bad requests, signals and the broker's loss.
//! Without mosquitto each test says it is skipped, by name (MOTIONLINK_REQUIRE_BROKER=1 makes that a
//! failure).

#![cfg(unix)]

use std::time::Duration;

use serde_json::{json, Value};

#[path = "broker/harness.rs"]
mod harness;

use harness::{broker, gateway, Client, ALL};

const S: Duration = Duration::from_secs(1);

/// A request on `device`'s `cmd` of gateway `gw`.
async fn request(c: &Client, gw: &str, device: &str, body: Value) {
    c.send(&format!("motionlink/{gw}/{device}/cmd"), body.to_string()).await;
}

/// Keepalives for motion `id` every 200 ms until the task is aborted.
fn keep_alive(c: &Client, gw: &str, device: &str, id: &str) -> tokio::task::JoinHandle<()> {
    let (mqtt, topic, body) =
        (c.mqtt.clone(), format!("motionlink/{gw}/{device}/cmd"), json!({"id": id, "op": "keepalive"}).to_string());
    tokio::spawn(async move {
        loop {
            let _ = mqtt.publish(topic.clone(), rumqttc::v5::mqttbytes::QoS::AtLeastOnce, false, body.clone()).await;
            tokio::time::sleep(Duration::from_millis(200)).await;
        }
    })
}

/// A connected client of gateway `gw` once it is online, subscribed to its topics and `me/#`.
async fn online(b: &harness::Broker, gw: &str, client: &str) -> Client {
    let mut c = Client::connect(b, client, &[&format!("motionlink/{gw}/#"), "me/#"]).await;
    // A bound, not a pause: 23 gateways with their emulators and brokers start at once on 2 cores.
    c.wait("online", 60 * S, |m| m.topic == format!("motionlink/{gw}/status") && m.payload == "online").await;
    c
}

/// A motion `op` (`move`, `motion`) of `device` with `args` under a lease kept alive: its reply.
async fn leased(b: &harness::Broker, gw: &str, device: &str, op: &str, args: Value) -> Value {
    let _gw = gateway(b, gw, ALL);
    let mut c = online(b, gw, &format!("t-{gw}")).await;
    c.drain();
    request(&c, gw, device, json!({"id": "m1", "op": op, "args": args, "reply_to": "me/r", "lease_ms": 500})).await;
    let started = std::time::Instant::now();
    let keep = keep_alive(&c, gw, device, "m1");
    let r = c.reply("me/r", "m1", 60 * S).await;
    let took = started.elapsed();
    keep.abort();
    let seen = c.drain();
    let events: Vec<Value> =
        seen.iter().filter(|m| m.topic == format!("motionlink/{gw}/{device}/events")).map(|m| m.json()).collect();
    assert_eq!(events[0]["event"], "motion_started", "{events:?}");
    assert_eq!((events[0]["op"].as_str(), events[0]["lease_ms"].as_u64()), (Some(op), Some(500)), "{events:?}");
    assert_eq!(
        (events[1]["event"].as_str(), events[1]["ok"].as_bool()),
        (Some("motion_ended"), Some(true)),
        "{events:?}"
    );
    // States at sample_hz (10) while it moved, not once a second.
    let states = seen.iter().filter(|m| m.topic == format!("motionlink/{gw}/{device}/state")).count() as f64;
    assert!(states >= took.as_secs_f64() * 5.0, "{states} states in {took:?} of motion");
    r
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn status_and_states_are_retained_and_the_end_is_offline() {
    let Some(b) = broker("status_and_states_are_retained_and_the_end_is_offline") else { return };
    let gw = gateway(&b, "r1", ALL);
    drop(online(&b, "r1", "t-r1-first").await);
    tokio::time::sleep(2 * S).await;
    // A client that comes later gets the status and every state at once, retained.
    let mut c = Client::connect(&b, "t-r1", &["motionlink/r1/#"]).await;
    let status = c.wait("status", 5 * S, |m| m.topic == "motionlink/r1/status").await;
    assert!(status.retain && status.payload == "online", "{status:?}");
    for (dev, keys) in
        [("lift", ["actuators", "last_error"]), ("arm", ["position_rad", "state"]), ("axis", ["position_units", "s17"])]
    {
        let m = c.wait("state", 5 * S, |m| m.topic == format!("motionlink/r1/{dev}/state") && m.retain).await;
        let state = m.json();
        for key in keys.iter().chain(&["family", "port", "t_s"]) {
            assert!(state.get(key).is_some(), "{dev}: no {key} in {state}");
        }
    }
    // At rest: about one state a second.
    c.drain();
    tokio::time::sleep(Duration::from_millis(3100)).await;
    let n = c.drain().iter().filter(|m| m.topic == "motionlink/r1/lift/state").count();
    assert!((2..=5).contains(&n), "{n} states in 3.1 s at rest");
    let (code, stderr) = gw.signal(libc::SIGTERM);
    assert_eq!(code, Some(143), "{stderr}");
    // Nothing moved, so nothing to say but the start; every session was closed.
    assert!(!stderr.contains("closing"), "{stderr}");
    let mut c = Client::connect(&b, "t-r1-after", &["motionlink/r1/status"]).await;
    let status = c.wait("status", 5 * S, |m| m.topic == "motionlink/r1/status").await;
    assert!(status.retain && status.payload == "offline", "{status:?}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_leased_scu_move_kept_alive_ends_at_its_target() {
    let Some(b) = broker("a_leased_scu_move_kept_alive_ends_at_its_target") else { return };
    let r = leased(&b, "l1", "lift", "move", json!({"actuator": 1, "position": 250, "speed": 100})).await;
    assert_eq!(r["ok"], true, "{r}");
    let result = &r["result"];
    assert_eq!((result["family"].as_str(), result["port"].as_str()), (Some("scu"), Some("sim")), "{r}");
    assert_eq!((result["reached_counts"].as_i64(), result["verified"].as_bool()), (Some(250), Some(true)), "{r}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_leased_powercube_move_kept_alive_ends_at_its_target() {
    let Some(b) = broker("a_leased_powercube_move_kept_alive_ends_at_its_target") else { return };
    let r = leased(&b, "l2", "arm", "move", json!({"position": 1.0, "vel": 0.8})).await;
    assert_eq!(r["ok"], true, "{r}");
    let result = &r["result"];
    assert_eq!((result["action"].as_str(), result["module"].as_i64()), (Some("reached"), Some(1)), "{r}");
    assert!((result["reached_rad"].as_f64().unwrap() - 1.0).abs() <= 0.001, "{r}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_leased_powercube_velocity_held_for_its_time_ends_with_velocity_zero() {
    let Some(b) = broker("a_leased_powercube_velocity_held_for_its_time_ends_with_velocity_zero") else { return };
    let r = leased(&b, "l4", "arm", "motion", json!({"mode": "fvel", "value": 0.3, "for_s": 0.6})).await;
    assert_eq!(r["ok"], true, "{r}");
    let result = &r["result"];
    assert_eq!((result["action"].as_str(), result["ended"].as_str()), (Some("ran"), Some("velocity_zero")), "{r}");
    assert!(result["reached_rad"].as_f64().unwrap() - result["start_rad"].as_f64().unwrap() > 0.1, "{r}");
    assert!(result["held_s"].as_f64().unwrap() >= 0.6, "{r}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_leased_compax_move_kept_alive_ends_at_its_target() {
    let Some(b) = broker("a_leased_compax_move_kept_alive_ends_at_its_target") else { return };
    let r = leased(&b, "l3", "axis", "move", json!({"abs": 40, "speed": 50})).await;
    assert_eq!(r["ok"], true, "{r}");
    let result = &r["result"];
    assert_eq!((result["drive"].as_i64(), result["waited"].as_bool()), (Some(1), Some(true)), "{r}");
    assert_eq!((result["reached_units"].as_f64(), result["verified"].as_bool()), (Some(40.0), Some(true)), "{r}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_move_whose_keepalives_stop_is_stopped_within_its_lease() {
    let Some(b) = broker("a_move_whose_keepalives_stop_is_stopped_within_its_lease") else { return };
    let _gw = gateway(&b, "e1", ALL);
    let mut c = online(&b, "e1", "t-e1").await;
    request(&c, "e1", "lift", json!({"id": "m1", "op": "move", "args": {"actuator": 1, "position": 800}, "reply_to": "me/r", "lease_ms": 400})).await;
    let sent = std::time::Instant::now();
    let keep = keep_alive(&c, "e1", "lift", "m1");
    tokio::time::sleep(Duration::from_millis(1000)).await;
    keep.abort();
    let stopped_renewing = std::time::Instant::now();
    let r = c.reply("me/r", "m1", 10 * S).await;
    let after = stopped_renewing.elapsed();
    assert_eq!((r["ok"].as_bool(), r["error"]["kind"].as_str()), (Some(false), Some("lease_expired")), "{r}");
    assert!(r["error"]["message"].as_str().unwrap().contains("400 ms"), "{r}");
    // Stopped one lease after the last keepalive, confirmed (the stop's read back takes part of a second).
    assert!(after < Duration::from_millis(400 + 200 + 1500), "the reply came {after:?} after the last keepalive");
    let m = c
        .wait("lease event", 2 * S, |m| m.topic == "motionlink/e1/lift/events" && m.json()["event"] == "lease_expired")
        .await;
    assert_eq!(m.json()["id"], "m1");
    // At rest short of the target, and staying there.
    let rest =
        |m: &harness::Message| m.topic == "motionlink/e1/lift/state" && m.json()["actuators"][0]["moving"] == false;
    c.drain();
    let first = c.wait("at rest", 3 * S, rest).await.json()["actuators"][0]["position_counts"].as_i64().unwrap();
    tokio::time::sleep(Duration::from_millis(1200)).await;
    c.drain();
    let later = c.wait("still", 3 * S, rest).await.json()["actuators"][0]["position_counts"].as_i64().unwrap();
    assert!(first > 0 && first < 800 && first == later, "{first} then {later} (sent {:?} ago)", sent.elapsed());
    // The lapsed motion's keepalive renews nothing.
    request(&c, "e1", "lift", json!({"id": "m1", "op": "keepalive", "reply_to": "me/k"})).await;
    let k = c.reply("me/k", "m1", 5 * S).await;
    assert_eq!(k["error"]["kind"], "no_lease", "{k}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn stop_during_a_move_stops_it() {
    let Some(b) = broker("stop_during_a_move_stops_it") else { return };
    let _gw = gateway(&b, "s1", ALL);
    let mut c = online(&b, "s1", "t-s1").await;
    request(
        &c,
        "s1",
        "axis",
        json!({"id": "m1", "op": "move", "args": {"abs": 1000, "speed": 10}, "reply_to": "me/r"}),
    )
    .await;
    let keep = keep_alive(&c, "s1", "axis", "m1");
    c.wait("moving", 5 * S, |m| m.topic == "motionlink/s1/axis/state" && m.json()["moving"] == true).await;
    // `stop` needs no lease and no id of the motion.
    request(&c, "s1", "axis", json!({"id": "s1", "op": "stop", "reply_to": "me/s"})).await;
    let stop = c.reply("me/s", "s1", 10 * S).await;
    keep.abort();
    assert_eq!((stop["ok"].as_bool(), stop["result"]["action"].as_str()), (Some(true), Some("stop")), "{stop}");
    assert_eq!(stop["result"]["confirmed"], true, "{stop}");
    let r = c.reply("me/r", "m1", 10 * S).await;
    assert_eq!((r["ok"].as_bool(), r["error"]["kind"].as_str()), (Some(false), Some("cancelled")), "{r}");
    // What the stop request asked for, then what the device's stop found (not a stop claimed before it).
    let said = r["error"]["message"].as_str().unwrap();
    assert!(
        said.starts_with("a stop request \"s1\" asks the gateway to stop the motion; the device's stop then"),
        "{r}"
    );
    let at = stop["result"]["position_units"].as_f64().unwrap();
    assert!(at > 0.0 && at < 1000.0, "{stop}");
    c.drain();
    let m = c.wait("at rest", 3 * S, |m| m.topic == "motionlink/s1/axis/state" && m.json()["moving"] == false).await;
    assert_eq!(m.json()["position_units"].as_f64(), Some(at), "{}", m.payload);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_requests_are_answered_and_nothing_moves() {
    let Some(b) = broker("bad_requests_are_answered_and_nothing_moves") else { return };
    let _gw = gateway(&b, "b1", ALL);
    let mut c = online(&b, "b1", "t-b1").await;
    let cases = [
        ("lift", json!({"id": "b1", "op": "fly", "reply_to": "me/r"}), "usage", "\"fly\" is not an action"),
        (
            "lift",
            json!({"id": "b2", "op": "move", "args": {"actuator": 9, "position": 100}, "reply_to": "me/r"}),
            "usage",
            "actuator",
        ),
        (
            "lift",
            json!({"id": "b3", "op": "move", "args": {"position": 100}, "reply_to": "me/r"}),
            "usage",
            "\"actuator\" is missing",
        ),
        (
            "lift",
            json!({"id": "b4", "op": "move", "args": {"actuator": 1, "position": 100, "speed": 500}, "reply_to": "me/r"}),
            "usage",
            "speed",
        ),
        (
            "lift",
            json!({"id": "b5", "op": "move", "args": {"actuator": 1, "position": 100, "sped": 5}, "reply_to": "me/r"}),
            "usage",
            "unknown argument \"sped\"",
        ),
        (
            "lift",
            json!({"id": "b6", "op": "move", "args": {"actuator": 1, "position": 100}, "reply_to": "me/r", "lease_ms": 20000}),
            "usage",
            "lease_ms",
        ),
        ("lift", json!({"id": "b7", "op": "keepalive", "reply_to": "me/r"}), "no_lease", "no motion \"b7\""),
        (
            "axis",
            json!({"id": "b8", "op": "move", "args": {"abs": 1, "rel": 2}, "reply_to": "me/r"}),
            "usage",
            "both a target position and a relative distance were given",
        ),
        (
            "arm",
            json!({"id": "b9", "op": "move", "args": {"position": 1, "vel": -1}, "reply_to": "me/r"}),
            "usage",
            "velocity",
        ),
        ("nope", json!({"id": "b10", "op": "move", "reply_to": "me/r"}), "usage", "no device \"nope\""),
        (
            "axis",
            json!({"id": "b14", "op": "status", "args": {"values": []}, "reply_to": "me/r"}),
            "usage",
            "empty list",
        ),
    ];
    for (device, body, kind, says) in &cases {
        request(&c, "b1", device, body.clone()).await;
        let id = body["id"].as_str().unwrap();
        let r = c.reply("me/r", id, 5 * S).await;
        assert_eq!((r["ok"].as_bool(), r["error"]["kind"].as_str()), (Some(false), Some(*kind)), "{r}");
        assert!(r["error"]["message"].as_str().unwrap().contains(says), "{body}: {r}");
        assert_eq!(r["error"]["exit_code"], 2, "{r}");
    }
    // Not JSON, with nowhere to reply: an error event.
    c.send("motionlink/b1/lift/cmd", "move please").await;
    let m = c.wait("error event", 5 * S, |m| m.topic == "motionlink/b1/lift/events").await.json();
    assert_eq!((m["event"].as_str(), m["error"]["kind"].as_str()), (Some("error"), Some("usage")), "{m}");
    // A key given twice (which a JSON map would take at its last value): refused.
    c.send(
        "motionlink/b1/lift/cmd",
        r#"{"id": "b11", "op": "move", "args": {"actuator": 1, "position": 10, "position": 300}, "reply_to": "me/r"}"#,
    )
    .await;
    let r = c.reply("me/r", "b11", 5 * S).await;
    assert!(r["error"]["message"].as_str().unwrap().contains("\"args.position\" given twice"), "{r}");
    // A request larger than the gateway takes (64 KiB) on any device's topic: the broker drops it (the
    // gateway told it its maximum packet size), the gateway stays connected and answers the next one.
    let huge = json!({"id": "b12", "op": "info", "reply_to": "me/r", "args": {"pad": "A".repeat(100_000)}});
    Client::connect(&b, "t-b1-big", &[]).await.send("motionlink/b1/axis/cmd", huge.to_string()).await;
    request(&c, "b1", "lift", json!({"id": "b13", "op": "fly", "reply_to": "me/r"})).await;
    c.reply("me/r", "b13", 5 * S).await;
    // Nothing moved, nothing started.
    tokio::time::sleep(1500 * Duration::from_millis(1)).await;
    let seen = c.drain();
    assert!(!seen.iter().any(|m| m.topic == "motionlink/b1/status" && m.payload == "offline"), "{seen:?}");
    assert!(!seen.iter().any(|m| m.topic.ends_with("/events") && m.payload.contains("motion_started")), "{seen:?}");
    let lift = seen.iter().rev().find(|m| m.topic == "motionlink/b1/lift/state").expect("a state").json();
    assert_eq!(
        (lift["actuators"][0]["position_counts"].as_i64(), lift["actuators"][0]["moving"].as_bool()),
        (Some(0), Some(false)),
        "{lift}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_motion_request_delivered_twice_runs_once() {
    let Some(b) = broker("a_motion_request_delivered_twice_runs_once") else { return };
    let _gw = gateway(&b, "q1", ALL);
    let mut c = online(&b, "q1", "t-q1").await;
    // A relative move (QoS 1 delivers at least once): the repeat comes after the first has ended, and while
    // it runs.
    let rel = json!({"id": "r1", "op": "move", "args": {"rel": 5, "speed": 100}, "reply_to": "me/r", "lease_ms": 2000});
    request(&c, "q1", "axis", rel.clone()).await;
    let keep = keep_alive(&c, "q1", "axis", "r1");
    request(&c, "q1", "axis", rel.clone()).await;
    let r = c.reply("me/r", "r1", 30 * S).await;
    keep.abort();
    assert_eq!((r["ok"].as_bool(), r["result"]["reached_units"].as_f64()), (Some(true), Some(5.0)), "{r}");
    request(&c, "q1", "axis", rel).await;
    let repeated = |m: &harness::Message| m.topic == "motionlink/q1/axis/events" && m.json()["event"] == "repeated";
    for _ in 0..2 {
        let e = c.wait("the repeat", 5 * S, repeated).await.json();
        assert_eq!((e["id"].as_str(), e["op"].as_str()), (Some("r1"), Some("move")), "{e}");
        assert!(e["message"].as_str().unwrap().contains("not run again"), "{e}");
    }
    // Nothing answered the repeats, and the axis moved 5 once.
    tokio::time::sleep(Duration::from_millis(300)).await;
    assert!(!c.drain().iter().any(|m| m.topic == "me/r"), "a repeat was answered");
    request(&c, "q1", "axis", json!({"id": "p", "op": "status", "args": {"values": "S1"}, "reply_to": "me/r"})).await;
    let p = c.reply("me/r", "p", 5 * S).await;
    assert_eq!(p["result"]["status"][0]["value"].as_f64(), Some(5.0), "{p}");
}

/// The axis's position (S1) as the drive reports it.
async fn axis_position(c: &mut Client, gw: &str, id: &str) -> f64 {
    request(c, gw, "axis", json!({"id": id, "op": "status", "args": {"values": "S1"}, "reply_to": "me/p"})).await;
    let p = c.reply("me/p", id, 5 * S).await;
    p["result"]["status"][0]["value"].as_f64().unwrap_or_else(|| panic!("{p}"))
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_retained_request_is_never_run_at_a_start_nor_when_it_is_published() {
    let Some(b) = broker("a_retained_request_is_never_run_at_a_start_nor_when_it_is_published") else { return };
    let qos = rumqttc::v5::mqttbytes::QoS::AtLeastOnce;
    // A relative move published retained before the gateway starts: the broker keeps it.
    let c0 = Client::connect(&b, "t-rt0", &[]).await;
    let rel = |id: &str| {
        json!({"id": id, "op": "move", "args": {"rel": 20, "speed": 100}, "reply_to": "me/r", "lease_ms": 5000})
            .to_string()
    };
    c0.mqtt.publish("motionlink/rt/axis/cmd", qos, true, rel("rel-1")).await.unwrap();
    let started = |m: &harness::Message| m.topic == "motionlink/rt/axis/events" && m.payload.contains("motion_started");
    let replied = |m: &harness::Message| m.topic == "me/r";
    for run in 0..2 {
        // At each start (the second: after a restart, with two retained moves kept by now), nothing runs.
        let gw = gateway(&b, "rt", ALL);
        let mut c = online(&b, "rt", &format!("t-rt-{run}")).await;
        tokio::time::sleep(Duration::from_millis(1500)).await;
        assert_eq!(axis_position(&mut c, "rt", &format!("p{run}")).await, 0.0, "run {run}");
        let seen = c.drain();
        assert!(!seen.iter().any(|m| started(m) || replied(m)), "run {run}: {seen:?}");
        if run == 0 {
            // Published retained while the gateway runs: refused, said and answered, and not run either.
            c.mqtt.publish("motionlink/rt/axis/cmd", qos, true, rel("rel-2")).await.unwrap();
            let r = c.reply("me/r", "rel-2", 5 * S).await;
            assert_eq!((r["ok"].as_bool(), r["error"]["kind"].as_str()), (Some(false), Some("usage")), "{r}");
            let said = r["error"]["message"].as_str().unwrap();
            assert!(said.contains("a request delivered as a retained message is not run"), "{r}");
            assert!(said.contains("publishing an empty retained message to motionlink/rt/axis/cmd"), "{r}");
            let e = c
                .wait("the retained event", 5 * S, |m| {
                    m.topic == "motionlink/rt/axis/events" && m.json()["event"] == "retained"
                })
                .await
                .json();
            assert_eq!((e["id"].as_str(), e["op"].as_str()), (Some("rel-2"), Some("move")), "{e}");
            tokio::time::sleep(Duration::from_millis(500)).await;
            assert_eq!(axis_position(&mut c, "rt", "p-after").await, 0.0);
            assert!(!c.drain().iter().any(started));
        }
        let (code, stderr) = gw.signal(libc::SIGTERM);
        assert_eq!(code, Some(143), "{stderr}");
        if run == 0 {
            assert!(stderr.contains("axis: a request delivered as a retained message is not run"), "{stderr}");
        }
    }
    // Cleared (an empty retained message): nothing to say about it.
    let gw = gateway(&b, "rt", ALL);
    let mut c = online(&b, "rt", "t-rt-clear").await;
    c.mqtt.publish("motionlink/rt/axis/cmd", qos, true, "").await.unwrap();
    tokio::time::sleep(Duration::from_millis(500)).await;
    let seen = c.drain();
    assert!(!seen.iter().any(|m| m.topic == "motionlink/rt/axis/events"), "{seen:?}");
    // A request published without the retain flag runs, as ever.
    request(
        &c,
        "rt",
        "axis",
        json!({"id": "r3", "op": "move", "args": {"rel": 5, "speed": 100}, "reply_to": "me/r", "lease_ms": 5000}),
    )
    .await;
    let r = c.reply("me/r", "r3", 20 * S).await;
    assert_eq!((r["ok"].as_bool(), r["result"]["reached_units"].as_f64()), (Some(true), Some(5.0)), "{r}");
    drop(gw);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_reply_topic_in_the_gateways_tree_is_refused_and_nothing_is_published_there() {
    let Some(b) = broker("a_reply_topic_in_the_gateways_tree_is_refused_and_nothing_is_published_there") else {
        return;
    };
    let _gw = gateway(&b, "r5", ALL);
    let mut c = Client::connect(&b, "t-r5", &["motionlink/#", "me/#"]).await;
    c.wait("online", 20 * S, |m| m.topic == "motionlink/r5/status" && m.payload == "online").await;
    let event_of =
        |id: &'static str| move |m: &harness::Message| m.topic == "motionlink/r5/lift/events" && m.json()["id"] == id;
    let cases = [
        ("x1", "motionlink/r5/status"),
        ("x2", "motionlink/r5/lift/state"),
        ("x3", "motionlink/r5/arm/cmd"),
        ("x4", "motionlink/r5/lift/events"),
        ("x5", "motionlink/wing-b/bed/state"),
        ("x6", "motionlink"),
    ];
    for (id, reply_to) in cases {
        request(&c, "r5", "lift", json!({"id": id, "op": "info", "reply_to": reply_to})).await;
        let e = c.wait(&format!("the refusal of {id}"), 5 * S, event_of(id)).await.json();
        assert_eq!((e["event"].as_str(), e["error"]["kind"].as_str()), (Some("error"), Some("usage")), "{e}");
        let said = e["error"]["message"].as_str().unwrap();
        assert!(said.starts_with(&format!("reply_to {reply_to:?} is in the gateways' topic tree")), "{e}");
        assert!(said.contains("refused and not run") && said.contains("motionlink-reply/"), "{e}");
    }
    // A motion request with such a reply topic is not run.
    let body = json!({"id": "m1", "op": "move", "args": {"rel": 5}, "reply_to": "motionlink/r5/axis/state"});
    request(&c, "r5", "axis", body).await;
    let e = c
        .wait("the refused move", 5 * S, |m| m.topic == "motionlink/r5/axis/events" && m.json()["id"] == "m1")
        .await
        .json();
    assert_eq!((e["event"].as_str(), e["error"]["kind"].as_str()), (Some("error"), Some("usage")), "{e}");
    // So is an MQTT 5 response topic there.
    let properties = rumqttc::v5::mqttbytes::v5::PublishProperties {
        response_topic: Some("motionlink/r5/status".into()),
        correlation_data: Some(b"c".to_vec().into()),
        ..Default::default()
    };
    let body = json!({"id": "x7", "op": "info"}).to_string();
    let qos = rumqttc::v5::mqttbytes::QoS::AtLeastOnce;
    c.mqtt.publish_with_properties("motionlink/r5/lift/cmd", qos, false, body, properties).await.unwrap();
    let e = c.wait("the refusal of x7", 5 * S, event_of("x7")).await.json();
    let said = e["error"]["message"].as_str().unwrap();
    assert!(said.starts_with("the response topic \"motionlink/r5/status\" is in the gateways' topic tree"), "{e}");
    // A reply topic outside the tree is answered, as ever.
    request(&c, "r5", "lift", json!({"id": "ok1", "op": "info", "reply_to": "me/r"})).await;
    assert_eq!(c.reply("me/r", "ok1", 5 * S).await["ok"], true);
    tokio::time::sleep(Duration::from_millis(300)).await;
    // Nothing the gateway published in its tree was a reply, nor moved the axis.
    let seen = c.drain();
    let replies: Vec<_> = seen.iter().filter(|m| m.topic != "me/r" && m.payload.contains("\"ok\":true")).collect();
    assert!(replies.is_empty(), "{replies:?}");
    assert!(!seen.iter().any(|m| m.payload.contains("motion_started")), "{seen:?}");
    assert_eq!(axis_position(&mut c, "r5", "p").await, 0.0);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_gateway_whose_stderr_is_gone_still_stops_closes_and_exits_143_on_sigterm() {
    let Some(b) = broker("a_gateway_whose_stderr_is_gone_still_stops_closes_and_exits_143_on_sigterm") else { return };
    let mut gw = gateway(&b, "k2", ALL);
    let mut c = online(&b, "k2", "t-k2").await;
    // Its terminal gone (as after SIGHUP), or the reader of its stderr: every notice now fails to be written.
    gw.close_stderr();
    request(
        &c,
        "k2",
        "arm",
        json!({"id": "m1", "op": "move", "args": {"position": 3.0, "vel": 0.3}, "reply_to": "me/r", "lease_ms": 2000}),
    )
    .await;
    let keep = keep_alive(&c, "k2", "arm", "m1");
    c.wait("started", 5 * S, |m| m.topic == "motionlink/k2/arm/events" && m.payload.contains("motion_started")).await;
    tokio::time::sleep(Duration::from_millis(300)).await;
    let (code, _) = gw.signal(libc::SIGTERM);
    keep.abort();
    assert_eq!(code, Some(143), "not a panic (101)");
    let r = c.reply("me/r", "m1", 5 * S).await;
    assert!(r["error"]["message"].as_str().unwrap().contains("halted"), "{r}");
    c.wait("offline", 5 * S, |m| m.topic == "motionlink/k2/status" && m.payload == "offline").await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sigterm_mid_move_stops_it_says_so_and_exits_143() {
    let Some(b) = broker("sigterm_mid_move_stops_it_says_so_and_exits_143") else { return };
    let gw = gateway(&b, "k1", ALL);
    let mut c = online(&b, "k1", "t-k1").await;
    request(
        &c,
        "k1",
        "arm",
        json!({"id": "m1", "op": "move", "args": {"position": 3.0, "vel": 0.3}, "reply_to": "me/r", "lease_ms": 2000}),
    )
    .await;
    let keep = keep_alive(&c, "k1", "arm", "m1");
    c.wait("started", 5 * S, |m| m.topic == "motionlink/k1/arm/events" && m.payload.contains("motion_started")).await;
    tokio::time::sleep(Duration::from_millis(700)).await;
    let (code, stderr) = gw.signal(libc::SIGTERM);
    keep.abort();
    assert_eq!(code, Some(143), "{stderr}");
    assert!(stderr.contains("SIGTERM") && stderr.contains("arm motion m1"), "{stderr}");
    assert!(!stderr.contains("closing"), "every session closed: {stderr}");
    let r = c.reply("me/r", "m1", 5 * S).await;
    assert_eq!((r["error"]["kind"].as_str(), r["error"]["exit_code"].as_i64()), (Some("cancelled"), Some(143)), "{r}");
    assert!(r["error"]["message"].as_str().unwrap().contains("halted"), "{r}");
    c.wait("offline", 5 * S, |m| m.topic == "motionlink/k1/status" && m.payload == "offline").await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sighup_mid_move_of_a_drive_without_watchdog_stops_it_and_exits_129() {
    // A closed terminal (SIGHUP) must not kill the gateway with a COMPAX move running: the drive has no
    // watchdog, nothing else would stop it.
    let Some(b) = broker("sighup_mid_move_of_a_drive_without_watchdog_stops_it_and_exits_129") else { return };
    let gw = gateway(&b, "h1", ALL);
    let mut c = online(&b, "h1", "t-h1").await;
    let body =
        json!({"id": "m1", "op": "move", "args": {"abs": 500, "speed": 10}, "reply_to": "me/r", "lease_ms": 2000});
    request(&c, "h1", "axis", body).await;
    let keep = keep_alive(&c, "h1", "axis", "m1");
    c.wait("started", 5 * S, |m| m.topic == "motionlink/h1/axis/events" && m.payload.contains("motion_started")).await;
    tokio::time::sleep(Duration::from_millis(500)).await;
    let (code, stderr) = gw.signal(libc::SIGHUP);
    keep.abort();
    assert_eq!(code, Some(129), "{stderr}");
    assert!(stderr.contains("SIGHUP") && stderr.contains("axis motion m1"), "{stderr}");
    let r = c.reply("me/r", "m1", 5 * S).await;
    assert_eq!((r["error"]["kind"].as_str(), r["error"]["exit_code"].as_i64()), (Some("cancelled"), Some(129)), "{r}");
    c.wait("offline", 5 * S, |m| m.topic == "motionlink/h1/status" && m.payload == "offline").await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sigtstp_mid_move_of_a_drive_without_watchdog_stops_it_and_ends_the_gateway_not_suspends_it() {
    // Ctrl-Z must not suspend the gateway with a COMPAX move running: suspended, it would watch no lease, and
    // the drive, which has no watchdog, would run to its target. It ends as on the other signals.
    let Some(b) = broker("sigtstp_mid_move_of_a_drive_without_watchdog_stops_it_and_ends_the_gateway_not_suspends_it")
    else {
        return;
    };
    let gw = gateway(&b, "z1", ALL);
    let mut c = online(&b, "z1", "t-z1").await;
    let body =
        json!({"id": "m1", "op": "move", "args": {"abs": 500, "speed": 10}, "reply_to": "me/r", "lease_ms": 2000});
    request(&c, "z1", "axis", body).await;
    let keep = keep_alive(&c, "z1", "axis", "m1");
    c.wait("started", 5 * S, |m| m.topic == "motionlink/z1/axis/events" && m.payload.contains("motion_started")).await;
    tokio::time::sleep(Duration::from_millis(500)).await;
    let (code, stderr) = gw.signal(libc::SIGTSTP);
    keep.abort();
    // 128 + SIGTSTP's number: 148 on Linux.
    assert_eq!(code, Some(128 + libc::SIGTSTP), "{stderr}");
    assert!(stderr.contains("SIGTSTP (Ctrl-Z) received: the gateway is not suspended"), "{stderr}");
    assert!(stderr.contains("SIGTSTP") && stderr.contains("axis motion m1"), "{stderr}");
    let r = c.reply("me/r", "m1", 5 * S).await;
    assert_eq!(
        (r["error"]["kind"].as_str(), r["error"]["exit_code"].as_i64()),
        (Some("cancelled"), Some(128 + i64::from(libc::SIGTSTP))),
        "{r}"
    );
    let said = r["error"]["message"].as_str().unwrap();
    assert!(said.starts_with("SIGTSTP received: the gateway stops the motion; the device's stop then: "), "{r}");
    assert!(said.contains("\"confirmed\":true"), "{r}");
    c.wait("offline", 5 * S, |m| m.topic == "motionlink/z1/status" && m.payload == "offline").await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_broker_lost_mid_move_stops_it_and_the_gateway_comes_back_online() {
    let Some(mut b) = broker("the_broker_lost_mid_move_stops_it_and_the_gateway_comes_back_online") else { return };
    let _gw = gateway(&b, "x1", ALL);
    let mut c = online(&b, "x1", "t-x1").await;
    request(&c, "x1", "lift", json!({"id": "m1", "op": "move", "args": {"actuator": 1, "position": 800}, "reply_to": "me/r", "lease_ms": 5000})).await;
    let keep = keep_alive(&c, "x1", "lift", "m1");
    // Under way (a little past its start) when the broker dies.
    c.wait("moving", 5 * S, |m| {
        let a1 = &m.json()["actuators"][0];
        m.topic == "motionlink/x1/lift/state" && a1["moving"] == true && a1["position_counts"].as_i64() > Some(20)
    })
    .await;
    b.kill();
    keep.abort();
    tokio::time::sleep(Duration::from_millis(1500)).await;
    b.restart();
    // Back online (the restarted broker kept nothing), with the lift at rest short of its target.
    let mut c = online(&b, "x1", "t-x1-again").await;
    let rest =
        |m: &harness::Message| m.topic == "motionlink/x1/lift/state" && m.json()["actuators"][0]["moving"] == false;
    c.drain();
    let first = c.wait("at rest", 5 * S, rest).await.json()["actuators"][0]["position_counts"].as_i64().unwrap();
    tokio::time::sleep(Duration::from_millis(1200)).await;
    c.drain();
    let later = c.wait("still", 3 * S, rest).await.json()["actuators"][0]["position_counts"].as_i64().unwrap();
    assert!(first > 0 && first < 800 && first == later, "{first} then {later}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn after_a_broker_outage_longer_than_its_queue_the_gateway_is_online_answers_and_sent_no_stale_state() {
    let name = "after_a_broker_outage_longer_than_its_queue_the_gateway_is_online_answers_and_sent_no_stale_state";
    let Some(mut b) = broker(name) else { return };
    // A queue of 8 requests to the broker: while the broker is gone, the three devices' states (one a second
    // each) would fill it within 3 s, before the gateway's subscription and `online` of the reconnection.
    let text = format!("[gateway]\nname = \"o1\"\nbroker = \"{}\"\n\n{ALL}", b.url());
    let gw = harness::gateway_of("o1", &text, &[("MOTIONLINK_GATEWAY_MQTT_QUEUE", "8")]);
    let mut c = online(&b, "o1", "t-o1").await;
    let state = |m: &harness::Message| m.topic.starts_with("motionlink/o1/") && m.topic.ends_with("/state");
    tokio::time::sleep(Duration::from_millis(1200)).await;
    let t_s = |m: &harness::Message| m.json()["t_s"].as_f64().unwrap();
    let before = c.drain().iter().filter(|m| state(m)).map(t_s).fold(0.0, f64::max);
    assert!(before > 0.5, "a state of the gateway's second second: {before}");
    // Gone for 5 s; the gateway's next try (its backoff: 0.25 s doubling) comes at about 7.75 s.
    b.kill();
    tokio::time::sleep(5 * S).await;
    b.restart();
    // On the restarted broker (it kept nothing) before the gateway is back: `online` again, a request answered.
    let mut c = online(&b, "o1", "t-o1-again").await;
    request(&c, "o1", "lift", json!({"id": "e1", "op": "errors", "reply_to": "me/r"})).await;
    assert_eq!(c.reply("me/r", "e1", 10 * S).await["ok"], true);
    request(&c, "o1", "axis", json!({"id": "s1", "op": "status", "reply_to": "me/r"})).await;
    assert_eq!(c.reply("me/r", "s1", 10 * S).await["ok"], true);
    // No state sampled while the broker was gone was queued and sent late: every state is of after the
    // reconnection (t_s more than 5 s after the last state before the outage).
    tokio::time::sleep(Duration::from_millis(1500)).await;
    let stale: Vec<f64> = c.drain().iter().filter(|m| state(m)).map(t_s).filter(|t| *t < before + 5.0).collect();
    assert!(stale.is_empty(), "states of {stale:?} s (the last before the outage: {before} s)");
    let (code, stderr) = gw.signal(libc::SIGTERM);
    assert_eq!(code, Some(143), "{stderr}");
    assert!(stderr.contains("subscribed to motionlink/o1/+/cmd again; `online` published"), "{stderr}");
}

/// No broker needed: the security rule is checked before any connection.
#[test]
fn a_remote_broker_without_tls_is_refused_with_exit_2_before_any_connection() {
    let dir = std::env::temp_dir().join(format!("motionlink-gw-{}-insecure", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("gateway.toml");
    // 192.0.2.1 (TEST-NET-1) answers nothing: a connection attempt would time out, not exit at once.
    std::fs::write(&file, format!("[gateway]\nname = \"n1\"\nbroker = \"mqtt://192.0.2.1:1883\"\n{ALL}")).unwrap();
    let started = std::time::Instant::now();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_motionlink-gateway"))
        .arg("--config")
        .arg(&file)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("no TLS") && stderr.contains("--insecure-broker"), "{stderr}");
    assert!(started.elapsed() < 3 * S, "{:?}", started.elapsed());
    // A password in the file itself is refused too.
    std::fs::write(&file, format!("[gateway]\nbroker = \"mqtt://127.0.0.1:1\"\npassword = \"x\"\n{ALL}")).unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_motionlink-gateway"))
        .arg("--config")
        .arg(&file)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("password_file") && stderr.contains("MOTIONLINK_MQTT_PASSWORD"), "{stderr}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Runs `program` with `args` in `dir`; false if it is not there or fails.
fn run_tool(dir: &std::path::Path, program: &str, args: &[&str]) -> bool {
    std::process::Command::new(program)
        .args(args)
        .current_dir(dir)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

#[test]
fn tls_and_a_password_from_the_environment_connect_and_a_wrong_password_is_refused() {
    let name = "tls_and_a_password_from_the_environment_connect_and_a_wrong_password_is_refused";
    let Some(plain) = broker(name) else { return };
    let dir = harness::dir(name);
    // A CA, and the broker's certificate for localhost signed by it (openssl); the password file
    // (mosquitto_passwd, of Debian's mosquitto package).
    let made = run_tool(
        &dir,
        "openssl",
        &[
            "req",
            "-x509",
            "-newkey",
            "rsa:2048",
            "-nodes",
            "-days",
            "2",
            "-subj",
            "/CN=test-ca",
            "-keyout",
            "ca.key",
            "-out",
            "ca.pem",
        ],
    ) && run_tool(
        &dir,
        "openssl",
        &[
            "req",
            "-newkey",
            "rsa:2048",
            "-nodes",
            "-subj",
            "/CN=localhost",
            "-keyout",
            "broker.key",
            "-out",
            "broker.csr",
        ],
    ) && std::fs::write(dir.join("san.ext"), "subjectAltName=DNS:localhost,IP:127.0.0.1\n").is_ok()
        && run_tool(
            &dir,
            "openssl",
            &[
                "x509",
                "-req",
                "-in",
                "broker.csr",
                "-CA",
                "ca.pem",
                "-CAkey",
                "ca.key",
                "-CAcreateserial",
                "-days",
                "2",
                "-extfile",
                "san.ext",
                "-out",
                "broker.pem",
            ],
        )
        && run_tool(&dir, "mosquitto_passwd", &["-b", "-c", "passwd", "gw-t1", "s3cret"]);
    if !made {
        assert!(
            std::env::var("MOTIONLINK_REQUIRE_BROKER").map_or(true, |v| v != "1"),
            "{name}: openssl and mosquitto_passwd are needed with MOTIONLINK_REQUIRE_BROKER=1"
        );
        eprintln!("SKIPPED broker::{name}: openssl or mosquitto_passwd is missing");
        return;
    }
    // mosquitto started as root reads its files as the user `mosquitto`.
    for f in ["broker.key", "passwd"] {
        let mut p = std::fs::metadata(dir.join(f)).unwrap().permissions();
        std::os::unix::fs::PermissionsExt::set_mode(&mut p, 0o644);
        std::fs::set_permissions(dir.join(f), p).unwrap();
    }
    let d = dir.display();
    let b = plain.another(
        &format!("{name}-tls"),
        &format!(
            "cafile {d}/ca.pem\ncertfile {d}/broker.pem\nkeyfile {d}/broker.key\nallow_anonymous false\npassword_file {d}/passwd"
        ),
    );
    let file = |gw: &str| {
        format!(
            "[gateway]\nname = \"{gw}\"\nbroker = \"mqtts://localhost:{}\"\nca_file = \"{d}/ca.pem\"\nusername = \"gw-t1\"\n{ALL}",
            b.port
        )
    };
    let mut gw = harness::gateway_of("t1", &file("t1"), &[("MOTIONLINK_MQTT_PASSWORD", "s3cret")]);
    let line = gw.first_line();
    assert!(line.contains(&format!("connected to mqtts://localhost:{}", b.port)), "{line}");
    assert_eq!(gw.signal(libc::SIGTERM).0, Some(143));
    // A wrong password: the broker refuses it, the gateway does not start (exit 3).
    let mut gw = harness::gateway_of("t2", &file("t2"), &[("MOTIONLINK_MQTT_PASSWORD", "wrong")]);
    let line = gw.first_line();
    assert!(line.contains("the broker mqtts://localhost"), "{line}");
    assert_eq!(gw.signal(0).0, Some(3), "{line}");
    // Without the CA the broker's certificate is not trusted.
    let untrusted = file("t3").replace(&format!("ca_file = \"{d}/ca.pem\"\n"), "");
    let mut gw = harness::gateway_of("t3", &untrusted, &[("MOTIONLINK_MQTT_PASSWORD", "s3cret")]);
    let line = gw.first_line();
    assert!(line.contains("the broker mqtts://localhost"), "{line}");
    assert_eq!(gw.signal(0).0, Some(3), "{line}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The text of the ```text block of docs/fleet.md that starts with `first`.
fn documented(first: &str) -> String {
    let page = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/fleet.md")).unwrap();
    page.split("```text\n")
        .skip(1)
        .map(|rest| rest.split("```").next().unwrap().to_string())
        .find(|b| b.starts_with(first))
        .unwrap_or_else(|| panic!("no block starting with {first:?} in docs/fleet.md"))
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_documented_acl_lets_a_dashboard_read_states_but_not_command() {
    let name = "the_documented_acl_lets_a_dashboard_read_states_but_not_command";
    let Some(plain) = broker(name) else { return };
    let dir = harness::dir(name);
    let users = [("gw-wing-a", "gw-pass"), ("dashboard", "dash-pass"), ("nurse-station", "nurse-pass")];
    let mut made = true;
    for (i, (user, password)) in users.iter().enumerate() {
        let mut args = vec!["-b"];
        if i == 0 {
            args.push("-c");
        }
        args.extend(["passwd", user, password]);
        made &= run_tool(&dir, "mosquitto_passwd", &args);
    }
    if !made {
        assert!(std::env::var("MOTIONLINK_REQUIRE_BROKER").map_or(true, |v| v != "1"), "{name}: no mosquitto_passwd");
        eprintln!("SKIPPED broker::{name}: mosquitto_passwd is missing");
        return;
    }
    std::fs::write(dir.join("acl"), documented("# /etc/mosquitto/motionlink.acl")).unwrap();
    for f in ["passwd", "acl"] {
        let mut p = std::fs::metadata(dir.join(f)).unwrap().permissions();
        std::os::unix::fs::PermissionsExt::set_mode(&mut p, 0o644);
        std::fs::set_permissions(dir.join(f), p).unwrap();
    }
    let d = dir.display();
    let b = plain
        .another(&format!("{name}-acl"), &format!("allow_anonymous false\npassword_file {d}/passwd\nacl_file {d}/acl"));
    let file = format!(
        "[gateway]\nname = \"wing-a\"\nbroker = \"mqtt://127.0.0.1:{}\"\nusername = \"gw-wing-a\"\n{ALL}",
        b.port
    );
    let _gw = harness::gateway_of("acl", &file, &[("MOTIONLINK_MQTT_PASSWORD", "gw-pass")]);
    // The dashboard sees the status and the states.
    let dashboard = Some(("dashboard", "dash-pass"));
    let mut dash = Client::connect_as(&b, "dash", dashboard, &["motionlink/wing-a/#", "motionlink-reply/#"]).await;
    dash.wait("online", 20 * S, |m| m.topic == "motionlink/wing-a/status" && m.payload == "online").await;
    dash.wait("a state", 5 * S, |m| m.topic == "motionlink/wing-a/lift/state").await;
    // Its command does not reach the gateway: nothing starts, nothing replies.
    let reply_to = "motionlink-reply/dashboard/r";
    let move_ = json!({"id": "d1", "op": "move", "args": {"actuator": 1, "position": 300}, "reply_to": reply_to});
    dash.send("motionlink/wing-a/lift/cmd", move_.to_string()).await;
    // The operator station's command does, and its reply comes back on its own reply topic.
    let nurse = Some(("nurse-station", "nurse-pass"));
    let mut n =
        Client::connect_as(&b, "nurse", nurse, &["motionlink-reply/nurse-station/#", "motionlink/wing-a/#"]).await;
    let move_ = json!({"id": "n1", "op": "move", "args": {"actuator": 2, "position": 30},
                       "reply_to": "motionlink-reply/nurse-station/r", "lease_ms": 3000});
    n.send("motionlink/wing-a/lift/cmd", move_.to_string()).await;
    let r = n.reply("motionlink-reply/nurse-station/r", "n1", 10 * S).await;
    assert_eq!((r["ok"].as_bool(), r["result"]["reached_counts"].as_i64()), (Some(true), Some(30)), "{r}");
    // The operator station reads states and events, but no request (its own stands for another's, which names
    // that client's reply topic and ids), and it cannot write a reply topic itself, not even its own.
    n.send("motionlink-reply/nurse-station/forged", json!({"id": "n1", "ok": true}).to_string()).await;
    tokio::time::sleep(Duration::from_millis(500)).await;
    let heard = n.drain();
    assert!(heard.iter().any(|m| m.topic == "motionlink/wing-a/lift/state"), "{heard:?}");
    assert!(heard.iter().any(|m| m.topic == "motionlink/wing-a/lift/events"), "{heard:?}");
    assert!(!heard.iter().any(|m| m.topic.ends_with("/cmd") || m.topic.ends_with("/forged")), "{heard:?}");
    tokio::time::sleep(S).await;
    let seen = dash.drain();
    let started: Vec<&str> =
        seen.iter().filter(|m| m.payload.contains("motion_started")).map(|m| m.payload.as_str()).collect();
    assert!(started.len() == 1 && started[0].contains("\"n1\""), "{started:?}");
    assert!(!seen.iter().any(|m| m.topic == reply_to), "the dashboard got a reply: {seen:?}");
    let lift = seen.iter().rev().find(|m| m.topic == "motionlink/wing-a/lift/state").expect("a state").json();
    assert_eq!(lift["actuators"][0]["position_counts"], 0, "{lift}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_mqtt5_request_without_reply_to_is_answered_on_its_response_topic_with_its_correlation_data() {
    let name = "an_mqtt5_request_without_reply_to_is_answered_on_its_response_topic_with_its_correlation_data";
    let Some(b) = broker(name) else { return };
    let _gw = gateway(&b, "c1", ALL);
    let mut c = online(&b, "c1", "t-c1").await;
    let properties = rumqttc::v5::mqttbytes::v5::PublishProperties {
        response_topic: Some("me/response".into()),
        correlation_data: Some(b"corr-42".to_vec().into()),
        ..Default::default()
    };
    let body = json!({"id": "q1", "op": "state"}).to_string();
    let qos = rumqttc::v5::mqttbytes::QoS::AtLeastOnce;
    c.mqtt.publish_with_properties("motionlink/c1/arm/cmd", qos, false, body, properties).await.unwrap();
    let m = c.wait("the reply", 5 * S, |m| m.topic == "me/response").await;
    assert_eq!(m.correlation.as_deref(), Some(&b"corr-42"[..]), "{m:?}");
    let r = m.json();
    assert_eq!(
        (r["id"].as_str(), r["ok"].as_bool(), r["result"]["module"].as_i64()),
        (Some("q1"), Some(true), Some(1)),
        "{r}"
    );
    // The object `powercube state --json` prints: the state word with its flags.
    assert!(r["result"]["word"].is_u64() && r["result"]["flags"].is_array(), "{r}");
}

/// Devices whose firmware does what the manuals leave open the other way (emulator variants, given in the
/// device table as `sim_variants`): their states are published and their leased moves end at the target,
/// each saying in `verified` / `not_verifiable` what could not be checked.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn devices_of_other_firmware_variants_are_sampled_and_moved() {
    let Some(b) = broker("devices_of_other_firmware_variants_are_sampled_and_moved") else { return };
    let devices = r#"
[device.lift]
family = "scu"
port = "sim"
sim_variants = ["no-groups", "no-cyclic-objects", "no-remote-readback"]

[device.arm]
family = "powercube"
port = "sim"
sim_variants = ["no-pos-state-dio", "no-twin-mirror"]

[device.axis]
family = "compax"
port = "sim"
sim_variants = ["echo-without-address"]
"#;
    let _gw = gateway(&b, "v1", devices);
    let mut c = online(&b, "v1", "t-v1").await;
    for (dev, key) in [("lift", "actuators"), ("arm", "position_rad"), ("axis", "position_units")] {
        let m = c.wait("state", 20 * S, |m| m.topic == format!("motionlink/v1/{dev}/state")).await;
        assert!(m.json().get(key).is_some(), "{dev}: no {key} in {}", m.payload);
    }
    for (dev, args, reached, target) in [
        ("lift", json!({"actuator": 1, "position": 250, "speed": 100}), "reached_counts", 250.0),
        ("arm", json!({"position": 0.5, "vel": 0.8}), "reached_rad", 0.5),
        ("axis", json!({"abs": 40, "speed": 50}), "reached_units", 40.0),
    ] {
        c.drain();
        let id = format!("m-{dev}");
        request(&c, "v1", dev, json!({"id": id, "op": "move", "args": args, "reply_to": "me/r", "lease_ms": 500}))
            .await;
        let keep = keep_alive(&c, "v1", dev, &id);
        let r = c.reply("me/r", &id, 60 * S).await;
        keep.abort();
        assert_eq!(r["ok"], true, "{dev}: {r}");
        let result = &r["result"];
        assert!((result[reached].as_f64().unwrap() - target).abs() <= 0.001, "{dev}: {r}");
        // What the variant keeps from being checked is said, never claimed verified.
        let verified = result["verified"].as_bool().unwrap_or(false);
        let said = result["not_verifiable"].as_array().is_some_and(|a| !a.is_empty());
        assert!(verified != said, "{dev}: {r}");
    }
}

/// With `--json` every line on stderr is JSON: the notices as `{"log": ...}` (the start, the signal's end),
/// a gateway that cannot start its error object.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn with_json_stderr_carries_json_lines_only() {
    let bad = std::process::Command::new(env!("CARGO_BIN_EXE_motionlink-gateway"))
        .args(["--json", "--config", "/nonexistent/gateway.toml"])
        .output()
        .expect("the gateway runs");
    assert_eq!(bad.status.code(), Some(2), "{bad:?}");
    let line: Value = serde_json::from_slice(&bad.stderr).expect("one JSON object");
    assert_eq!((&line["kind"], &line["exit_code"]), (&json!("usage"), &json!(2)), "{line}");
    assert!(line["message"].as_str().unwrap().contains("/nonexistent/gateway.toml"), "{line}");

    let Some(b) = broker("with_json_stderr_carries_json_lines_only") else { return };
    let text = format!("[gateway]\nname = \"j1\"\nbroker = \"{}\"\n\n{ALL}", b.url());
    let gw = harness::gateway_with("j1", &text, &[], &["--json"]);
    drop(online(&b, "j1", "t-j1").await);
    let (code, stderr) = gw.signal(libc::SIGTERM);
    assert_eq!(code, Some(143), "{stderr}");
    let lines: Vec<Value> = stderr
        .lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("not JSON ({e}): {l:?} in {stderr}")))
        .collect();
    assert!(lines.iter().all(|l| l["log"].is_string()), "{stderr}");
    assert!(lines.iter().any(|l| l["log"].as_str().unwrap().contains("connected to mqtt://")), "{stderr}");
}
