//! `motionlink scu` over a link whose replies come back 290 ms late (a serial gateway far away), end to end:
//! a proxy between the binary and `motionlink sim scu` holds back every byte from the unit.

use std::io::{Read, Write};
use std::net::{Shutdown, TcpListener, TcpStream};
use std::sync::mpsc;
use std::thread;
use std::time::{Duration, Instant};

use super::{json, scu, sim_tcp, stdout};

/// How late the unit's bytes reach the host.
const LATE: Duration = Duration::from_millis(290);

/// Serves one connection on `tcp://127.0.0.1:PORT` (returned) and relays it to `target`: requests at once,
/// replies `LATE` after the unit sent them.
fn slow_proxy(target: &str) -> String {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let address = format!("tcp://{}", listener.local_addr().unwrap());
    let target = target.strip_prefix("tcp://").unwrap().to_string();
    thread::spawn(move || {
        let Ok((host, _)) = listener.accept() else { return };
        let device = TcpStream::connect(target).unwrap();
        let _ = (host.set_nodelay(true), device.set_nodelay(true));
        let (mut host_in, mut device_out) = (host.try_clone().unwrap(), device.try_clone().unwrap());
        thread::spawn(move || {
            let _ = std::io::copy(&mut host_in, &mut device_out);
            let _ = device_out.shutdown(Shutdown::Write);
        });
        let (tx, rx) = mpsc::channel::<(Instant, Vec<u8>)>();
        let mut host_out = host;
        let writer = thread::spawn(move || {
            for (at, bytes) in rx {
                thread::sleep((at + LATE).saturating_duration_since(Instant::now()));
                if host_out.write_all(&bytes).is_err() {
                    break;
                }
            }
            let _ = host_out.shutdown(Shutdown::Write);
        });
        let mut device_in = device;
        let mut buf = [0u8; 512];
        while let Ok(n @ 1..) = device_in.read(&mut buf) {
            if tx.send((Instant::now(), buf[..n].to_vec())).is_err() {
                break;
            }
        }
        drop(tx);
        let _ = writer.join();
    });
    address
}

#[test]
fn watch_over_a_290_ms_link_lapses_only_when_allowed_then_gives_its_samples_and_exits_0_and_a_move_there_is_refused_before_anything_moves(
) {
    let sim = sim_tcp();
    // Without the user's leave, nothing lapses: exit 3, and the message says how (and at what cost).
    let out = scu(&slow_proxy(&sim.address), &["watch", "--count", "4", "--interval-ms", "500"]);
    assert_eq!(out.status.code(), Some(3), "{out:?}");
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(err.contains("--allow-watchdog-lapse") && err.contains("stops every motion"), "{err}");
    assert!(!sim.stderr.text().contains("ended by watchdog"), "no lapse: {}", sim.stderr.text());
    let watch = ["watch", "--count", "4", "--interval-ms", "500", "--json", "--allow-watchdog-lapse"];
    let out = scu(&slow_proxy(&sim.address), &watch);
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "{out:?}");
    let lines: Vec<serde_json::Value> =
        stdout(&out).lines().map(|l| serde_json::from_str(l).expect("one JSON object per sample")).collect();
    assert_eq!(lines.len(), 4, "{lines:?}");
    assert!(lines.iter().all(|s| s["actuators"][0]["position_counts"] == 0), "{lines:?}");
    // What it did to the unit is said: the watchdog lapsed once, on purpose.
    assert!(err.contains("lapses once"), "{err}");
    let lapses = sim.stderr.wait_for_nth(Duration::from_secs(2), 1, |l| l.contains("ended by watchdog"));
    assert!(lapses.is_some(), "{}", sim.stderr.text());
    // A move over such a link cannot keep the watchdog fed: refused (exit 3) before anything moves.
    let out = scu(&slow_proxy(&sim.address), &["move", "1", "40", "--speed", "100"]);
    assert_eq!(out.status.code(), Some(3), "{out:?}");
    thread::sleep(Duration::from_millis(500));
    let v = json(&scu(&sim.address, &["get", "actual_position_a1", "--json"]));
    assert_eq!(v["value"], 0, "nothing moved");
    assert!(!sim.stderr.text().contains("started"), "no function was started: {}", sim.stderr.text());
}
