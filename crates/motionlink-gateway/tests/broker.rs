//! The gateway against a real broker (mosquitto on a free loopback port): retained status and states,
//! leased motions in every family, lease expiry, stop, bad requests, signals and the broker's loss.
//! Without mosquitto each test says it is skipped, by name (MOTIONLINK_REQUIRE_BROKER=1 makes that a
//! failure).

use std::time::Duration;

use serde_json::{json, Value};

#[path = "broker/harness.rs"]
mod harness;

use harness::{broker, gateway, Client};

const ALL: &str = r#"
[device.lift]
family = "scu"
port = "sim"

[device.arm]
family = "powercube"
port = "sim"

[device.axis]
family = "compax"
port = "sim"
"#;

const S: Duration = Duration::from_secs(1);

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn probe_shapes() {
    let Some(b) = broker("probe_shapes") else { return };
    let gw = gateway(&b, "p1", ALL);
    let mut c = Client::connect(&b, "t-probe", &["motionlink/p1/#", "me/#"]).await;
    c.wait("online", 10 * S, |m| m.topic == "motionlink/p1/status" && m.payload == "online").await;
    for dev in ["lift", "arm", "axis"] {
        let m = c.wait("state", 5 * S, |m| m.topic == format!("motionlink/p1/{dev}/state")).await;
        eprintln!("STATE {dev}: {}", m.payload);
    }
    for (dev, args) in [
        ("lift", json!({"actuator": 1, "position": 300})),
        ("arm", json!({"position": 0.5, "vel": 1.0})),
        ("axis", json!({"abs": 10, "speed": 50})),
    ] {
        let id = format!("m-{dev}");
        c.send(
            &format!("motionlink/p1/{dev}/cmd"),
            json!({"id": id, "op": "move", "args": args, "reply_to": "me/r", "lease_ms": 2000}).to_string(),
        )
        .await;
        let t0 = std::time::Instant::now();
        let r = loop {
            c.send(&format!("motionlink/p1/{dev}/cmd"), json!({"id": id, "op": "keepalive"}).to_string()).await;
            tokio::time::sleep(Duration::from_millis(200)).await;
            let got: Vec<Value> = c.drain().into_iter().filter(|m| m.topic == "me/r").map(|m| m.json()).collect();
            if let Some(r) = got.into_iter().find(|r| r["id"] == id) {
                break r;
            }
            assert!(t0.elapsed() < 60 * S);
        };
        eprintln!("REPLY {dev} after {:?}: {r}", t0.elapsed());
        c.send(&format!("motionlink/p1/{dev}/cmd"), json!({"id": "s", "op": "stop", "reply_to": "me/s"}).to_string())
            .await;
        let r = c.reply("me/s", "s", 10 * S).await;
        eprintln!("STOP {dev}: {r}");
    }
    let (code, err) = gw.signal(libc::SIGTERM);
    eprintln!("EXIT {code:?} {err}");
}
