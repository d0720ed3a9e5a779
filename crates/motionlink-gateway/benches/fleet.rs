//! The gateway at scale, through a real mosquitto on loopback: one gateway with 32 emulated devices (16
//! COMPAX drives moving under leases, so their states run at 10 Hz, and 16 PowerCube modules at rest):
//! state messages delivered per second, the gateway's CPU, the round trip of a command through the broker
//! (a device read, and a keepalive), and a storm of 1,000 requests with nothing lost or duplicated; then
//! four gateways with 16 devices each on the same broker (8 drives of each moving under leases kept alive,
//! 8 modules at rest): states delivered, their CPU, and the round trip to each.
//!
//! `cargo bench -p motionlink-gateway --features bench` (mosquitto installed; without it the benchmark says
//! it is skipped).

use std::collections::HashSet;
use std::time::{Duration, Instant};

use criterion::{criterion_group, criterion_main, Criterion};
use serde_json::json;

#[path = "../tests/broker/harness.rs"]
mod harness;

const GW: &str = "bench";
const DRIVES: usize = 16;
const MODULES: usize = 16;

/// The device tables of a gateway: `drives` COMPAX drives and `modules` PowerCube modules, every one in
/// its own emulator.
fn devices(drives: usize, modules: usize) -> String {
    let mut text = String::from("sample_hz = 10\n\n");
    for i in 0..drives {
        text.push_str(&format!("[device.drive{i}]\nfamily = \"compax\"\nport = \"sim\"\n\n"));
    }
    for i in 0..modules {
        text.push_str(&format!("[device.module{i}]\nfamily = \"powercube\"\nport = \"sim\"\n\n"));
    }
    text
}

/// User and system CPU time of process `pid` so far (Linux /proc), in seconds.
fn cpu_s(pid: u32) -> f64 {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).unwrap_or_default();
    let fields: Vec<&str> = stat.rsplit_once(") ").map(|(_, r)| r.split(' ').collect()).unwrap_or_default();
    let ticks = |i: usize| fields.get(i).and_then(|f| f.parse::<f64>().ok()).unwrap_or(0.0);
    // utime and stime are fields 14 and 15 of stat (11 and 12 after the command's name); 100 ticks a second.
    (ticks(11) + ticks(12)) / 100.0
}

/// CPU time so far of each thread of process `pid`, by thread name (Linux /proc), in seconds.
fn cpu_by_thread(pid: u32) -> std::collections::BTreeMap<String, f64> {
    let mut by_name = std::collections::BTreeMap::new();
    let Ok(tasks) = std::fs::read_dir(format!("/proc/{pid}/task")) else { return by_name };
    for t in tasks.flatten() {
        let stat = std::fs::read_to_string(t.path().join("stat")).unwrap_or_default();
        let Some((head, rest)) = stat.rsplit_once(") ") else { continue };
        let name = head.split_once(" (").map_or("?", |(_, n)| n).to_string();
        let fields: Vec<&str> = rest.split(' ').collect();
        let ticks = |i: usize| fields.get(i).and_then(|f| f.parse::<f64>().ok()).unwrap_or(0.0);
        *by_name.entry(name).or_insert(0.0) += (ticks(11) + ticks(12)) / 100.0;
    }
    by_name
}

/// The `q` quantile of `samples` (sorted here).
fn quantile(samples: &mut [Duration], q: f64) -> Duration {
    samples.sort();
    samples[((samples.len() - 1) as f64 * q).round() as usize]
}

fn fleet(c: &mut Criterion) {
    let Some(b) = harness::broker("bench_fleet") else { return };
    let rt = tokio::runtime::Builder::new_multi_thread().worker_threads(2).enable_all().build().unwrap();
    let file = format!("[gateway]\nname = \"{GW}\"\nbroker = \"{}\"\n{}", b.url(), devices(DRIVES, MODULES));
    let gw = harness::gateway_of(GW, &file, &[]);
    let mut client = rt.block_on(async {
        let mut c = harness::Client::connect(&b, "bench-client", &[&format!("motionlink/{GW}/#"), "me/#"]).await;
        c.wait("online", Duration::from_secs(30), |m| {
            m.topic == format!("motionlink/{GW}/status") && m.payload == "online"
        })
        .await;
        // Every drive moves (a long way, slowly) under a lease kept alive.
        for i in 0..DRIVES {
            let cmd = format!("motionlink/{GW}/drive{i}/cmd");
            let move_ =
                json!({"id": format!("m{i}"), "op": "move", "args": {"abs": 100000, "speed": 1}, "lease_ms": 10000});
            c.send(&cmd, move_.to_string()).await;
        }
        c
    });
    let ids = (0..DRIVES).map(|i| (GW.to_string(), format!("drive{i}"), format!("m{i}"))).collect();
    let keep = keep_alive(&rt, client.mqtt.clone(), ids);
    // States delivered, and the gateway's CPU, over 10 s with the drives moving.
    rt.block_on(async {
        tokio::time::sleep(Duration::from_secs(2)).await;
        client.drain();
        let (cpu0, threads0, t0) = (cpu_s(gw.pid()), cpu_by_thread(gw.pid()), Instant::now());
        tokio::time::sleep(Duration::from_secs(10)).await;
        let (cpu, wall) = (cpu_s(gw.pid()) - cpu0, t0.elapsed().as_secs_f64());
        // Where it goes: the async runtime (MQTT, requests, states, JSON) and the other threads (each
        // device's session driver and, here, its emulator).
        let split: Vec<String> = cpu_by_thread(gw.pid())
            .into_iter()
            .map(|(name, s)| (name.clone(), s - threads0.get(&name).copied().unwrap_or(0.0)))
            .filter(|(_, s)| *s > 0.0)
            .map(|(name, s)| format!("{name} {:.1} %", 100.0 * s / wall))
            .collect();
        println!("fleet: CPU by thread name: {}", split.join(", "));
        let seen = client.drain();
        let states = seen.iter().filter(|m| m.topic.ends_with("/state")).count() as f64;
        let moving = seen.iter().filter(|m| m.topic.ends_with("/state") && m.payload.contains("\"moving\":true")).count();
        println!(
            "fleet: {} devices ({DRIVES} moving): {:.0} state messages/s delivered ({moving} of moving drives in {wall:.1} s); \
             gateway CPU {:.1} % of one core",
            DRIVES + MODULES,
            states / wall,
            100.0 * cpu / wall
        );
    });
    // Round trips, one request at a time: p50 / p99 of 500 each.
    let mut round_trip = |op: &str, device: &str, id_of: &dyn Fn(usize) -> String| {
        let mut samples = Vec::new();
        rt.block_on(async {
            for n in 0..500 {
                let id = id_of(n);
                client.drain();
                let body = json!({"id": id, "op": op, "reply_to": "me/rt"}).to_string();
                let t = Instant::now();
                client.send(&format!("motionlink/{GW}/{device}/cmd"), body).await;
                let r = client.reply("me/rt", &id, Duration::from_secs(10)).await;
                samples.push(t.elapsed());
                assert_eq!(r["ok"], true, "{r}");
            }
            client.drain();
        });
        let (p50, p99) = (quantile(&mut samples, 0.5), quantile(&mut samples, 0.99));
        println!("fleet: {op} on {device}: round trip p50 {p50:?}, p99 {p99:?} (500 requests, one at a time)");
    };
    round_trip("state", "module0", &|n| format!("s{n}"));
    round_trip("keepalive", "drive0", &|_| "m0".to_string());
    // A storm: 1,000 requests at once over the 16 modules; every reply once.
    rt.block_on(async {
        let t = Instant::now();
        for n in 0..1000 {
            let body = json!({"id": format!("storm{n}"), "op": "state", "reply_to": "me/storm"}).to_string();
            client.send(&format!("motionlink/{GW}/module{}/cmd", n % MODULES), body).await;
        }
        let mut ids = Vec::new();
        while ids.len() < 1000 {
            let m = client.wait("the storm's replies", Duration::from_secs(60), |m| m.topic == "me/storm").await;
            let r = m.json();
            assert_eq!(r["ok"], true, "{r}");
            ids.push(r["id"].as_str().unwrap().to_string());
        }
        tokio::time::sleep(Duration::from_millis(500)).await;
        let extra = client.drain().iter().filter(|m| m.topic == "me/storm").count();
        let unique: HashSet<&String> = ids.iter().collect();
        assert_eq!((unique.len(), extra), (1000, 0), "lost or duplicated");
        println!("fleet: a storm of 1000 state requests: every reply once, all within {:?}", t.elapsed());
    });
    // The criterion figure: one device read through broker and gateway.
    let mut n = 0u64;
    c.bench_function("gateway state request round trip (32 devices, 16 moving)", |bench| {
        bench.iter(|| {
            n += 1;
            let id = format!("c{n}");
            client.drain();
            rt.block_on(async {
                client
                    .send(
                        &format!("motionlink/{GW}/module1/cmd"),
                        json!({"id": id, "op": "state", "reply_to": "me/c"}).to_string(),
                    )
                    .await;
                client.reply("me/c", &id, Duration::from_secs(10)).await
            })
        })
    });
    keep.abort();
    let _ = gw.signal(libc::SIGTERM);
    four_gateways(&b, &rt);
}

/// Keeps the motions `ids` (gateway, device, motion id) alive: a keepalive to each every 500 ms.
fn keep_alive(
    rt: &tokio::runtime::Runtime,
    mqtt: rumqttc::v5::AsyncClient,
    ids: Vec<(String, String, String)>,
) -> tokio::task::JoinHandle<()> {
    rt.spawn(async move {
        loop {
            for (gw, device, id) in &ids {
                let body = json!({"id": id, "op": "keepalive"}).to_string();
                let topic = format!("motionlink/{gw}/{device}/cmd");
                let _ = mqtt.publish(topic, rumqttc::v5::mqttbytes::QoS::AtLeastOnce, false, body).await;
            }
            tokio::time::sleep(Duration::from_millis(500)).await;
        }
    })
}

/// The CPU of a gateway's async runtime (its threads `tokio-*`: MQTT, requests, states, JSON) in
/// `by_thread`, in seconds.
fn runtime_cpu_s(by_thread: &std::collections::BTreeMap<String, f64>) -> f64 {
    by_thread.iter().filter(|(name, _)| name.starts_with("tokio-")).map(|(_, s)| s).sum()
}

/// Four gateways of 16 devices each (8 drives moving under leases kept alive, as in the one-gateway case,
/// and 8 modules at rest) on one broker.
fn four_gateways(b: &harness::Broker, rt: &tokio::runtime::Runtime) {
    const DRIVES_EACH: usize = 8;
    let names = ["fleet-a", "fleet-b", "fleet-c", "fleet-d"];
    let gateways: Vec<harness::Gateway> = names
        .iter()
        .map(|n| {
            harness::gateway_of(
                n,
                &format!("[gateway]\nname = \"{n}\"\nbroker = \"{}\"\n{}", b.url(), devices(DRIVES_EACH, 8)),
                &[],
            )
        })
        .collect();
    let mut c = rt.block_on(async {
        let mut c = harness::Client::connect(b, "bench-four", &["motionlink/+/status", "motionlink/+/+/state", "me/#"]).await;
        for n in names {
            c.wait("online", Duration::from_secs(30), |m| m.topic == format!("motionlink/{n}/status") && m.payload == "online")
                .await;
        }
        // Every drive of every gateway moves (a long way, slowly) under a lease kept alive.
        for n in names {
            for i in 0..DRIVES_EACH {
                let move_ = json!({"id": format!("m{i}"), "op": "move", "args": {"abs": 100000, "speed": 1}, "lease_ms": 10000});
                c.send(&format!("motionlink/{n}/drive{i}/cmd"), move_.to_string()).await;
            }
        }
        c
    });
    let ids = names
        .iter()
        .flat_map(|n| (0..DRIVES_EACH).map(move |i| (n.to_string(), format!("drive{i}"), format!("m{i}"))))
        .collect();
    let keep = keep_alive(rt, c.mqtt.clone(), ids);
    rt.block_on(async {
        tokio::time::sleep(Duration::from_secs(2)).await;
        c.drain();
        let cpu0: Vec<(f64, f64)> =
            gateways.iter().map(|g| (cpu_s(g.pid()), runtime_cpu_s(&cpu_by_thread(g.pid())))).collect();
        let t0 = Instant::now();
        tokio::time::sleep(Duration::from_secs(10)).await;
        let wall = t0.elapsed().as_secs_f64();
        let cpu: Vec<String> = gateways
            .iter()
            .zip(&cpu0)
            .map(|(g, (p0, r0))| {
                let process = 100.0 * (cpu_s(g.pid()) - p0) / wall;
                let runtime = 100.0 * (runtime_cpu_s(&cpu_by_thread(g.pid())) - r0) / wall;
                format!("{runtime:.1} ({process:.0})")
            })
            .collect();
        let seen = c.drain();
        let states = seen.iter().filter(|m| m.topic.ends_with("/state")).count() as f64;
        let moving =
            seen.iter().filter(|m| m.topic.ends_with("/state") && m.payload.contains("\"moving\":true")).count();
        println!(
            "fleet: 4 gateways x 16 devices ({DRIVES_EACH} drives moving each): {:.0} state messages/s delivered \
             ({moving} of moving drives in {wall:.1} s); CPU of each gateway's runtime (whole process) {} % of a core",
            states / wall,
            cpu.join(" / ")
        );
        let mut samples = Vec::new();
        for n in 0..400 {
            let gw = names[n % 4];
            let id = format!("f{n}");
            c.drain();
            let t = Instant::now();
            c.send(
                &format!("motionlink/{gw}/module{}/cmd", n % 8),
                json!({"id": id, "op": "state", "reply_to": "me/f"}).to_string(),
            )
            .await;
            let r = c.reply("me/f", &id, Duration::from_secs(10)).await;
            samples.push(t.elapsed());
            assert_eq!(r["ok"], true, "{r}");
        }
        let (p50, p99) = (quantile(&mut samples, 0.5), quantile(&mut samples, 0.99));
        println!(
            "fleet: 4 gateways, drives moving: state round trip p50 {p50:?}, p99 {p99:?} (400 requests over the 4, one \
             at a time)"
        );
    });
    keep.abort();
    for g in gateways {
        let _ = g.signal(libc::SIGTERM);
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(50).measurement_time(Duration::from_secs(10));
    targets = fleet
}
criterion_main!(benches);
