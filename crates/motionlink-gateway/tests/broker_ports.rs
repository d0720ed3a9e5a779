//! The port locks of the gateway against a real broker (mosquitto on a free loopback port) and a COMPAX
//! emulator on a TCP port: the gateway holds the lock of the port it serves (a second process is refused,
//! naming it), and a `stop` through the lock (what `motionlink compax --port PORT stop` does) stops that
//! device's motion, gets its port and what was stopped, while the gateway serves on and takes the port back
//! once it is free. Without mosquitto each test says it is skipped, by name (MOTIONLINK_REQUIRE_BROKER=1
//! makes that a failure).

#![cfg(unix)]

use std::sync::{Arc, Mutex};
use std::time::Duration;

use motionlink_link::portlock;
use serde_json::json;

#[path = "broker/harness.rs"]
mod harness;

use harness::{broker, gateway, Client};

const S: Duration = Duration::from_secs(1);

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_stop_through_the_port_lock_stops_the_device_s_motion_and_the_gateway_serves_on() {
    let Some(b) = broker("a_stop_through_the_port_lock_stops_the_device_s_motion_and_the_gateway_serves_on") else {
        return;
    };
    let bus = motionlink_compax::Emulator::new(motionlink_compax::DriveOptions::default().emulated()).unwrap();
    let server = motionlink_link::emulator::serve_tcp(
        "127.0.0.1:0",
        Arc::new(Mutex::new(bus)),
        motionlink_link::RealClock::shared(),
    )
    .unwrap();
    let port = server.address().to_string();
    let devices = format!(
        "[device.axis]\nfamily = \"compax\"\nport = \"{port}\"\n\n[device.lift]\nfamily = \"scu\"\nport = \"sim\"\n"
    );
    let gw = gateway(&b, "pl", &devices);
    let mut c = Client::connect(&b, "t-pl", &["motionlink/pl/#", "me/#"]).await;
    c.wait("online", 20 * S, |m| m.topic == "motionlink/pl/status" && m.payload == "online").await;

    // The port is the gateway's: another process is refused, told who holds it and how to stop it.
    let e = portlock::claim("compax", &port, "compax status").unwrap_err().0;
    assert!(
        e.contains(&format!("in use by motionlink pid {}", gw.pid())) && e.contains("gateway pl: device axis"),
        "{e}"
    );
    assert!(e.contains(&format!("motionlink compax --port {port} stop")), "{e}");
    // So is a second gateway on it: exit 3, naming the holder.
    let second = gateway(&b, "pl2", &devices);
    let (code, err) = second.signal(0);
    assert_eq!(code, Some(3), "{err}");
    assert!(err.contains(&format!("in use by motionlink pid {}", gw.pid())), "{err}");

    // A move under a lease; a stop through the lock stops it and takes the port.
    let body =
        json!({"id": "m1", "op": "move", "args": {"abs": 1000, "speed": 10}, "reply_to": "me/m", "lease_ms": 10000});
    c.send("motionlink/pl/axis/cmd", body.to_string()).await;
    c.wait("moving", 10 * S, |m| m.topic == "motionlink/pl/axis/state" && m.json()["moving"] == true).await;
    let p = port.clone();
    let (lock, stopped) =
        tokio::task::spawn_blocking(move || portlock::claim_for_stop("compax", &p, "compax stop", |_| {}))
            .await
            .unwrap()
            .unwrap();
    let stopped = stopped.expect("the gateway was the holder");
    assert_eq!(stopped.holder.pid, gw.pid());
    let outcome = stopped.outcome.expect("the gateway said what it stopped");
    assert!(
        outcome.message.contains("gateway pl: axis: ") && outcome.message.contains("\"confirmed\":true"),
        "{outcome:?}"
    );
    let m = c.reply("me/m", "m1", 5 * S).await;
    assert_eq!((m["ok"].as_bool(), m["error"]["kind"].as_str()), (Some(false), Some("cancelled")), "{m}");
    let said = m["error"]["message"].as_str().unwrap();
    assert!(said.starts_with("a stop from motionlink pid "), "{m}");
    assert!(
        said.contains(" through the port's lock asks the gateway to stop the motion; the device's stop then"),
        "{m}"
    );
    let ev = c
        .wait("released", 5 * S, |m| m.topic == "motionlink/pl/axis/events" && m.payload.contains("port_released"))
        .await;
    assert!(ev.json()["message"].as_str().unwrap().contains("let go of"), "{}", ev.payload);

    // The gateway serves on: the other device answers, this one says where its port went.
    c.send("motionlink/pl/lift/cmd", json!({"id": "i1", "op": "errors", "reply_to": "me/r"}).to_string()).await;
    assert_eq!(c.reply("me/r", "i1", 5 * S).await["ok"], true);
    c.send("motionlink/pl/axis/cmd", json!({"id": "s1", "op": "status", "reply_to": "me/r"}).to_string()).await;
    let r = c.reply("me/r", "s1", 5 * S).await;
    assert!(r["error"]["message"].as_str().unwrap().contains("took its port"), "{r}");

    // The stop lets go of the port: the gateway takes it back and serves the drive again, at rest.
    drop(lock);
    c.wait("taken", 10 * S, |m| m.topic == "motionlink/pl/axis/events" && m.payload.contains("port_taken")).await;
    c.send("motionlink/pl/axis/cmd", json!({"id": "s2", "op": "status", "reply_to": "me/r"}).to_string()).await;
    let r = c.reply("me/r", "s2", 5 * S).await;
    assert_eq!(r["ok"], true, "{r}");
    let s1 = r["result"]["status"][0]["value"].as_f64().unwrap();
    assert!(s1 > 0.0 && s1 < 1000.0, "{r}");
    let e = portlock::claim("compax", &port, "compax status").unwrap_err().0;
    assert!(e.contains(&format!("pid {}", gw.pid())), "{e}");
}

/// A COMPAX bus that stops answering while its port stays open (a drive switched off behind a serial
/// server), or refuses every request (with E92), as `mode` says:
/// [`ANSWERS`], [`SILENT`] or [`REFUSES`].
struct Silenceable {
    bus: motionlink_compax::Emulator,
    mode: Arc<std::sync::atomic::AtomicU8>,
}

const ANSWERS: u8 = 0;
const SILENT: u8 = 1;
const REFUSES: u8 = 2;

impl Silenceable {
    /// What the bus said, as `mode` lets it through.
    fn pass(&self, said: Vec<u8>, out: &mut Vec<u8>) {
        match self.mode.load(std::sync::atomic::Ordering::SeqCst) {
            ANSWERS => out.extend(said),
            REFUSES if !said.is_empty() => out.extend_from_slice(b"E92\r\n>"),
            _ => {}
        }
    }
}

impl motionlink_link::emulator::Emulator for Silenceable {
    fn receive(&mut self, now: motionlink_link::Timestamp, bytes: &[u8], out: &mut Vec<u8>) {
        let mut said = Vec::new();
        self.bus.receive(now, bytes, &mut said);
        self.pass(said, out);
    }
    fn advance(&mut self, now: motionlink_link::Timestamp, out: &mut Vec<u8>) {
        let mut said = Vec::new();
        self.bus.advance(now, &mut said);
        self.pass(said, out);
    }
    fn next_wakeup(&self) -> Option<motionlink_link::Timestamp> {
        self.bus.next_wakeup()
    }
    fn connection_closed(&mut self, now: motionlink_link::Timestamp) {
        self.bus.connection_closed(now);
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_device_that_stops_answering_or_refuses_its_reads_is_published_unavailable_until_it_answers_again() {
    let Some(b) =
        broker("a_device_that_stops_answering_or_refuses_its_reads_is_published_unavailable_until_it_answers_again")
    else {
        return;
    };
    let mode = Arc::new(std::sync::atomic::AtomicU8::new(ANSWERS));
    let bus = motionlink_compax::Emulator::new(motionlink_compax::DriveOptions::default().emulated()).unwrap();
    let device = Silenceable { bus, mode: Arc::clone(&mode) };
    let server = motionlink_link::emulator::serve_tcp(
        "127.0.0.1:0",
        Arc::new(Mutex::new(device)),
        motionlink_link::RealClock::shared(),
    )
    .unwrap();
    let port = server.address().to_string();
    let gw = gateway(&b, "sl", &format!("[device.axis]\nfamily = \"compax\"\nport = \"{port}\"\n"));
    let mut c = Client::connect(&b, "t-sl", &["motionlink/sl/#"]).await;
    let state = |m: &harness::Message| m.topic == "motionlink/sl/axis/state";
    c.wait("a state", 20 * S, |m| state(m) && m.json()["position_units"].is_number()).await;

    // Silent: the retained state says so (not the last position, as if at rest), and an event.
    mode.store(SILENT, std::sync::atomic::Ordering::SeqCst);
    let m = c.wait("unavailable", 10 * S, |m| state(m) && m.json()["available"] == false).await.json();
    assert_eq!((m["family"].as_str(), m["drive"].as_u64()), (Some("compax"), Some(1)), "{m}");
    assert_eq!(m["error"]["kind"], "timeout", "{m}");
    let ev = c.wait("silent", 5 * S, |m| m.topic == "motionlink/sl/axis/events" && m.payload.contains("device_silent"));
    let ev = ev.await.json();
    assert!(ev["message"].as_str().unwrap().contains("does not answer"), "{ev}");
    assert_eq!(ev["error"]["kind"], "timeout", "{ev}");
    // A late subscriber sees the unavailable state, retained.
    let mut late = Client::connect(&b, "t-sl2", &["motionlink/sl/axis/state"]).await;
    let r = late.wait("retained", 5 * S, state).await.json();
    assert_eq!(r["available"], false, "{r}");

    // Answering again: the state is published again, and an event says so.
    mode.store(ANSWERS, std::sync::atomic::Ordering::SeqCst);
    c.wait("back", 10 * S, |m| state(m) && m.json()["position_units"].is_number()).await;
    c.wait("answers", 5 * S, |m| m.topic == "motionlink/sl/axis/events" && m.payload.contains("device_answers")).await;

    // Refusing the reads: unavailable again, said as a state that could not be read (not as a device that
    // does not answer).
    mode.store(REFUSES, std::sync::atomic::Ordering::SeqCst);
    let m = c.wait("unreadable", 10 * S, |m| state(m) && m.json()["available"] == false).await.json();
    assert_eq!(m["error"]["kind"], "refused", "{m}");
    assert!(m["error"]["message"].as_str().unwrap().contains("E92"), "{m}");
    let ev = c.wait("failed", 5 * S, |m| m.topic == "motionlink/sl/axis/events" && m.payload.contains("state_failed"));
    let ev = ev.await.json();
    assert!(ev["message"].as_str().unwrap().contains("its state could not be read"), "{ev}");
    assert_eq!(ev["error"]["kind"], m["error"]["kind"], "{ev}");
    mode.store(ANSWERS, std::sync::atomic::Ordering::SeqCst);
    c.wait("back again", 10 * S, |m| state(m) && m.json()["position_units"].is_number()).await;
    let (code, err) = gw.signal(libc::SIGTERM);
    assert_eq!(code, Some(143), "{err}");
    assert!(err.contains("axis: does not answer") && err.contains("axis: its state is read again"), "{err}");
    assert!(err.contains("axis: its state could not be read"), "{err}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_signal_whose_stop_the_device_does_not_confirm_ends_the_gateway_with_exit_3() {
    let Some(b) = broker("a_signal_whose_stop_the_device_does_not_confirm_ends_the_gateway_with_exit_3") else {
        return;
    };
    let bus = motionlink_compax::Emulator::new(motionlink_compax::DriveOptions::default().emulated()).unwrap();
    let bus = Arc::new(Mutex::new(bus));
    let server =
        motionlink_link::emulator::serve_tcp("127.0.0.1:0", Arc::clone(&bus), motionlink_link::RealClock::shared())
            .unwrap();
    let devices = format!("[device.axis]\nfamily = \"compax\"\nport = \"{}\"\n", server.address());
    let gw = gateway(&b, "pu", &devices);
    let mut c = Client::connect(&b, "t-pu", &["motionlink/pu/#", "me/#"]).await;
    c.wait("online", 20 * S, |m| m.topic == "motionlink/pu/status" && m.payload == "online").await;
    let body =
        json!({"id": "m1", "op": "move", "args": {"abs": 1000, "speed": 10}, "reply_to": "me/m", "lease_ms": 10000});
    c.send("motionlink/pu/axis/cmd", body.to_string()).await;
    c.wait("moving", 10 * S, |m| m.topic == "motionlink/pu/axis/state" && m.json()["moving"] == true).await;
    // The drive answers nothing from now on (its emulator held): the stop the signal makes is not confirmed.
    let frozen = bus.lock().unwrap();
    let (code, stderr) = tokio::task::block_in_place(|| gw.signal(libc::SIGTERM));
    drop(frozen);
    assert_eq!(code, Some(3), "not 143, which says the motions were stopped: {stderr}");
    assert!(stderr.contains("a stop was not confirmed: what was moving may still be moving"), "{stderr}");
    drop(server);
}
