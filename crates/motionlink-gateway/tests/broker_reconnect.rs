//! A device whose port fails, against a real broker (mosquitto on a free loopback port): a COMPAX emulator
//! served on TCP by its own process (the emulator and server `motionlink sim compax --tcp` runs), killed
//! mid-move and started again on the same port. The gateway ends the device's motion and says that no
//! stop can reach the drive, publishes its state unavailable (retained), answers its requests
//! `unavailable` while it serves its other device on, and opens the port again with backoff: the drive is
//! served again and its state published. A line cut for a moment (a TCP proxy between the gateway and a
//! COMPAX emulator that runs on) during a move: once the port is open again, the gateway stops the drive
//! before it serves it. Without mosquitto each test says it is skipped, by name (MOTIONLINK_REQUIRE_BROKER=1
//! makes that a failure).

#![cfg(unix)]

use std::io::BufRead;
use std::net::{Shutdown, TcpListener, TcpStream};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use serde_json::json;

#[path = "broker/harness.rs"]
mod harness;

use harness::{broker, gateway, Client};

const S: Duration = Duration::from_secs(1);

/// The variable that makes [`compax_emulator_process`] serve (on the address it holds).
const SIM_ADDRESS: &str = "MOTIONLINK_TEST_SIM_ADDRESS";

/// Not a test: the COMPAX emulator process of the test below (this test binary run again with
/// `--ignored --exact compax_emulator_process` and [`SIM_ADDRESS`] set), serving one drive on TCP, as
/// `motionlink sim compax --tcp ADDRESS` does, until it is killed.
#[test]
#[ignore = "the emulator process of a_failed_port_is_opened_again_and_the_other_devices_are_served_on"]
fn compax_emulator_process() {
    let Ok(address) = std::env::var(SIM_ADDRESS) else { return };
    let bus = motionlink_compax::Emulator::new(motionlink_compax::DriveOptions::default().emulated()).unwrap();
    let server =
        motionlink_link::emulator::serve_tcp(&address, Arc::new(Mutex::new(bus)), motionlink_link::RealClock::shared())
            .unwrap();
    println!("listening on {}", server.address());
    server.wait();
}

/// The emulator process, on `address`.
struct Sim(Child);

impl Sim {
    fn start(address: &str) -> Sim {
        let mut child = Command::new(std::env::current_exe().unwrap())
            .args(["--ignored", "--exact", "compax_emulator_process", "--nocapture", "--test-threads=1"])
            .env(SIM_ADDRESS, address)
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("the emulator process starts");
        let out = std::io::BufReader::new(child.stdout.take().unwrap());
        let mut lines = out.lines();
        loop {
            match lines.next() {
                Some(Ok(line)) if line.contains("listening on tcp://") => break,
                Some(Ok(_)) => continue,
                other => panic!("the emulator process did not listen on {address}: {other:?}"),
            }
        }
        // The rest of its output is drained.
        std::thread::spawn(move || lines.for_each(drop));
        Sim(child)
    }

    /// SIGKILL: its connections end as a vanished serial server's or an unplugged adapter's.
    fn kill(mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

impl Drop for Sim {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_failed_port_is_opened_again_and_the_other_devices_are_served_on() {
    let Some(b) = broker("a_failed_port_is_opened_again_and_the_other_devices_are_served_on") else { return };
    let free = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap();
    let sim = Sim::start(&free.to_string());
    let port = format!("tcp://{free}");
    let devices = format!(
        "[device.axis]\nfamily = \"compax\"\nport = \"{port}\"\n\n[device.lift]\nfamily = \"scu\"\nport = \"sim\"\n"
    );
    let _gw = gateway(&b, "rc", &devices);
    let mut c = Client::connect(&b, "t-rc", &["motionlink/rc/#", "me/#"]).await;
    c.wait("online", 20 * S, |m| m.topic == "motionlink/rc/status" && m.payload == "online").await;

    // A move under a lease; the emulator process is killed while the drive moves.
    let body =
        json!({"id": "m1", "op": "move", "args": {"abs": 1000, "speed": 10}, "reply_to": "me/m", "lease_ms": 10000});
    c.send("motionlink/rc/axis/cmd", body.to_string()).await;
    c.wait("moving", 10 * S, |m| m.topic == "motionlink/rc/axis/state" && m.json()["moving"] == true).await;
    sim.kill();

    // The motion ends with the failure; the event says what that means for the drive.
    let m = c.reply("me/m", "m1", 10 * S).await;
    assert_eq!((m["ok"].as_bool(), m["error"]["kind"].as_str()), (Some(false), Some("disconnected")), "{m}");
    let ev = c
        .wait("port_failed", 10 * S, |m| m.topic == "motionlink/rc/axis/events" && m.payload.contains("port_failed"))
        .await
        .json();
    let said = ev["message"].as_str().unwrap();
    assert!(said.contains(&format!("its port {port} failed")), "{ev}");
    assert!(said.contains("motion move \"m1\"") && said.contains("COMPAX drive has no watchdog"), "{ev}");
    assert_eq!(ev["error"]["kind"], "disconnected", "{ev}");

    // Its state is unavailable, retained: a client that comes now is told so.
    let mut late = Client::connect(&b, "t-rc-late", &["motionlink/rc/axis/state"]).await;
    let st = late.wait("the retained state", 5 * S, |m| m.retain).await.json();
    assert_eq!(
        (st["available"].as_bool(), st["family"].as_str(), st["port"].as_str(), st["drive"].as_u64()),
        (Some(false), Some("compax"), Some(port.as_str()), Some(1)),
        "{st}"
    );
    assert_eq!(st["error"]["kind"], "disconnected", "{st}");

    // Requests to it are answered unavailable; the other device is served on.
    c.send("motionlink/rc/axis/cmd", json!({"id": "s1", "op": "stop", "reply_to": "me/r"}).to_string()).await;
    let r = c.reply("me/r", "s1", 5 * S).await;
    assert_eq!((r["error"]["kind"].as_str(), r["error"]["exit_code"].as_u64()), (Some("unavailable"), Some(3)), "{r}");
    c.send("motionlink/rc/lift/cmd", json!({"id": "i1", "op": "errors", "reply_to": "me/r"}).to_string()).await;
    assert_eq!(c.reply("me/r", "i1", 5 * S).await["ok"], true);

    // The emulator comes back on the same port: the drive is served again, its state published.
    tokio::time::sleep(2 * S).await;
    let _sim = Sim::start(&free.to_string());
    c.wait("port_reopened", 20 * S, |m| m.topic == "motionlink/rc/axis/events" && m.payload.contains("port_reopened"))
        .await;
    let st = c
        .wait("a state again", 5 * S, |m| m.topic == "motionlink/rc/axis/state" && m.json().get("available").is_none())
        .await
        .json();
    assert_eq!((st["moving"].as_bool(), st["drive"].as_u64()), (Some(false), Some(1)), "{st}");
    c.send("motionlink/rc/axis/cmd", json!({"id": "s2", "op": "status", "reply_to": "me/r"}).to_string()).await;
    let r = c.reply("me/r", "s2", 5 * S).await;
    assert_eq!(r["ok"], true, "{r}");
}

/// A line that can be cut: a TCP proxy from its own port to `upstream` (a device's server, which runs on).
/// Cut, its connections end at once and new ones are closed as soon as they come, as a serial server whose
/// line is gone; put back, it carries new connections again.
struct Line {
    address: String,
    cut: Arc<AtomicBool>,
    live: Arc<Mutex<Vec<TcpStream>>>,
}

impl Line {
    fn to(upstream: &str) -> Line {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let address = listener.local_addr().unwrap().to_string();
        let (cut, live) = (Arc::new(AtomicBool::new(false)), Arc::new(Mutex::new(Vec::<TcpStream>::new())));
        let (c, l, upstream) = (Arc::clone(&cut), Arc::clone(&live), upstream.to_string());
        std::thread::spawn(move || {
            for client in listener.incoming() {
                let Ok(client) = client else { continue };
                if c.load(Ordering::SeqCst) {
                    let _ = client.shutdown(Shutdown::Both);
                    continue;
                }
                let Ok(server) = TcpStream::connect(&upstream) else { continue };
                let _ = (client.set_nodelay(true), server.set_nodelay(true));
                let mut live = l.lock().unwrap();
                for (from, to) in [(&client, &server), (&server, &client)] {
                    let (mut from, mut to) = (from.try_clone().unwrap(), to.try_clone().unwrap());
                    std::thread::spawn(move || {
                        let _ = std::io::copy(&mut from, &mut to);
                        let _ = (from.shutdown(Shutdown::Both), to.shutdown(Shutdown::Both));
                    });
                }
                live.extend([client, server]);
            }
        });
        Line { address, cut, live }
    }

    fn cut(&self) {
        self.cut.store(true, Ordering::SeqCst);
        for s in self.live.lock().unwrap().drain(..) {
            let _ = s.shutdown(Shutdown::Both);
        }
    }

    fn put_back(&self) {
        self.cut.store(false, Ordering::SeqCst);
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_drive_whose_line_blipped_mid_move_is_stopped_before_it_is_served_again() {
    let Some(b) = broker("a_drive_whose_line_blipped_mid_move_is_stopped_before_it_is_served_again") else { return };
    let bus = motionlink_compax::Emulator::new(motionlink_compax::DriveOptions::default().emulated()).unwrap();
    let bus = Arc::new(Mutex::new(bus));
    let server =
        motionlink_link::emulator::serve_tcp("127.0.0.1:0", Arc::clone(&bus), motionlink_link::RealClock::shared())
            .unwrap();
    let line = Line::to(server.address().trim_start_matches("tcp://"));
    let port = format!("tcp://{}", line.address);
    let _gw = gateway(&b, "bl", &format!("[device.axis]\nfamily = \"compax\"\nport = \"{port}\"\n"));
    let mut c = Client::connect(&b, "t-bl", &["motionlink/bl/#", "me/#"]).await;
    c.wait("online", 20 * S, |m| m.topic == "motionlink/bl/status" && m.payload == "online").await;
    let events = |m: &harness::Message| m.topic == "motionlink/bl/axis/events";

    // A move under a lease (10 s at speed 10); the line is cut for 300 ms while the drive moves.
    let body =
        json!({"id": "m1", "op": "move", "args": {"abs": 1000, "speed": 10}, "reply_to": "me/m", "lease_ms": 10000});
    c.send("motionlink/bl/axis/cmd", body.to_string()).await;
    c.wait("moving", 10 * S, |m| m.topic == "motionlink/bl/axis/state" && m.json()["moving"] == true).await;
    line.cut();
    let m = c.reply("me/m", "m1", 10 * S).await;
    assert_eq!(m["error"]["kind"], "disconnected", "{m}");
    let failed = c.wait("port_failed", 5 * S, |m| events(m) && m.json()["event"] == "port_failed").await.json();
    assert!(
        failed["message"].as_str().unwrap().ends_with("and stops the device over it before it serves it again"),
        "{failed}"
    );
    tokio::time::sleep(Duration::from_millis(300)).await;
    assert!(bus.lock().unwrap().drive(1).unwrap().is_moving(), "the drive runs on without its host");
    line.put_back();

    // Open again: the drive is stopped over the new session before it is served, and the event says so.
    let ev = c.wait("port_reopened", 20 * S, |m| events(m) && m.json()["event"] == "port_reopened").await.json();
    // At rest short of its target, and it stays there.
    let drive = |bus: &Mutex<motionlink_compax::Emulator>| {
        let bus = bus.lock().unwrap();
        let d = bus.drive(1).unwrap();
        (d.is_moving(), d.position())
    };
    let (moving, at) = drive(&bus);
    assert!(!moving && at > 0.0 && at < 1000.0, "{moving} at {at}");
    let said = ev["message"].as_str().unwrap();
    let first = "its motion move \"m1\" ran when the port failed, so the gateway stopped the device first: the \
                 device's stop: ";
    assert!(said.contains(first), "{ev}");
    assert!(said.contains("\"confirmed\":true"), "{ev}");
    assert_eq!(ev["ok"], true, "{ev}");
    c.send("motionlink/bl/axis/cmd", json!({"id": "p1", "op": "status", "reply_to": "me/r"}).to_string()).await;
    let p1 = c.reply("me/r", "p1", 5 * S).await["result"]["status"][0]["value"].as_f64().unwrap();
    tokio::time::sleep(S).await;
    c.send("motionlink/bl/axis/cmd", json!({"id": "p2", "op": "status", "reply_to": "me/r"}).to_string()).await;
    let p2 = c.reply("me/r", "p2", 5 * S).await["result"]["status"][0]["value"].as_f64().unwrap();
    assert!(p1 == p2 && p1 < 1000.0, "{p1} then {p2}");
    c.drain();
    let st = c
        .wait("a state at rest", 5 * S, |m| m.topic == "motionlink/bl/axis/state" && m.json()["moving"] == false)
        .await
        .json();
    assert_eq!(st["position_units"].as_f64(), Some(p2), "{st}");
    drop(server);
}
