//! One bit flipped anywhere in one telegram, through the real binary: a proxy between `motionlink <family>
//! move` and `motionlink sim` flips one bit of the traffic, one direction at a time, at positions spread over
//! the whole session. Whatever the bit does, the command never exits 0 with the axis somewhere other than
//! where it was asked to go (the libraries' tests flip every bit; this checks the same rule end to end).

use std::io::{Read, Write};
use std::net::{Shutdown, TcpListener, TcpStream};
use std::process::Command;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::thread;

use crate::common::{Sim, BIN};

/// Which bit of the session's traffic to flip: the `bit`-th bit of the bytes going `to_device` (or back).
#[derive(Clone, Copy, Debug)]
struct Flip {
    to_device: bool,
    bit: u64,
}

/// A proxy for one connection to `target`; it flips `flip` (if any) and counts the bytes each way.
struct Proxy {
    address: String,
    to_device: Arc<AtomicU64>,
    to_host: Arc<AtomicU64>,
}

fn pump(mut from: TcpStream, mut to: TcpStream, flip: Option<u64>, count: Arc<AtomicU64>) {
    let mut buf = [0u8; 512];
    loop {
        let n = match from.read(&mut buf) {
            Ok(0) | Err(_) => break,
            Ok(n) => n,
        };
        let start = count.fetch_add(n as u64, Ordering::SeqCst);
        if let Some(bit) = flip {
            let byte = bit / 8;
            if (start..start + n as u64).contains(&byte) {
                buf[(byte - start) as usize] ^= 1 << (bit % 8);
            }
        }
        if to.write_all(&buf[..n]).is_err() {
            break;
        }
    }
    let _ = to.shutdown(Shutdown::Write);
    let _ = from.shutdown(Shutdown::Read);
}

impl Proxy {
    fn start(target: &str, flip: Option<Flip>) -> Proxy {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let address = format!("tcp://{}", listener.local_addr().unwrap());
        let target = target.strip_prefix("tcp://").unwrap().to_string();
        let (to_device, to_host) = (Arc::new(AtomicU64::new(0)), Arc::new(AtomicU64::new(0)));
        let (down, up) = (Arc::clone(&to_device), Arc::clone(&to_host));
        thread::spawn(move || {
            let Ok((host, _)) = listener.accept() else { return };
            let device = TcpStream::connect(target).unwrap();
            let _ = (host.set_nodelay(true), device.set_nodelay(true));
            let (h2, d2) = (host.try_clone().unwrap(), device.try_clone().unwrap());
            let flip_down = flip.filter(|f| f.to_device).map(|f| f.bit);
            let flip_up = flip.filter(|f| !f.to_device).map(|f| f.bit);
            let t = thread::spawn(move || pump(host, device, flip_down, down));
            pump(d2, h2, flip_up, up);
            let _ = t.join();
        });
        Proxy { address, to_device, to_host }
    }
}

struct Case {
    family: &'static str,
    sim_args: &'static [&'static str],
    /// The move, after `--port P`.
    command: &'static [&'static str],
    target: f64,
    tolerance: f64,
    /// Some flips must make the command fail: where no checksum repairs them by a resend (PowerCube, whose
    /// modules ignore the BCC; COMPAX without BCC). The SCU's CRC-16 catches every single flipped bit and the
    /// client asks again, so there every run must reach the target.
    some_fail: bool,
    /// Reads the axis' position from the emulator directly.
    position: fn(&str) -> f64,
}

fn cli_json(args: &[&str]) -> serde_json::Value {
    let out = Command::new(BIN).args(args).arg("--json").output().unwrap();
    assert!(out.status.success(), "{args:?}: {}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).unwrap()
}

fn scu_position(port: &str) -> f64 {
    cli_json(&["scu", "--port", port, "get", "actual_position_a1"])["value"].as_f64().unwrap()
}

fn powercube_position(port: &str) -> f64 {
    cli_json(&["powercube", "--port", port, "get", "ActPos"])["value"].as_f64().unwrap()
}

fn compax_position(port: &str) -> f64 {
    cli_json(&["compax", "--port", port, "status", "S1"])["status"][0]["value"].as_f64().unwrap()
}

/// Runs the move through a proxy flipping `flip`; returns the exit code and the position read afterwards.
/// A command that failed must not have left the axis moving: its position is read twice, 200 ms apart, after
/// any deceleration has ended, and must not change.
fn run(case: &Case, flip: Option<Flip>) -> (i32, f64, u64, u64, String) {
    let sim = Sim::start(case.family, case.sim_args);
    let proxy = Proxy::start(&sim.address, flip);
    let out = Command::new(BIN).arg(case.family).args(["--port", &proxy.address]).args(case.command).output().unwrap();
    let code = out.status.code().unwrap_or(-1);
    // The emulator serves one client at a time: the proxy's connection has closed with the command.
    let mut position = (case.position)(&sim.address);
    if code != 0 {
        std::thread::sleep(std::time::Duration::from_millis(200));
        let settled = (case.position)(&sim.address);
        std::thread::sleep(std::time::Duration::from_millis(200));
        position = (case.position)(&sim.address);
        assert!(
            (position - settled).abs() <= case.tolerance / 10.0,
            "{} with {flip:?}: exit {code}, but the axis still moves ({settled} -> {position})",
            case.family
        );
    }
    let said = String::from_utf8_lossy(&out.stderr).into_owned();
    (code, position, proxy.to_device.load(Ordering::SeqCst), proxy.to_host.load(Ordering::SeqCst), said)
}

fn sweep(case: Case) {
    let _alone = crate::alone();
    let (code, position, to_device, to_host, said) = run(&case, None);
    assert_eq!(code, 0, "the clean run succeeds: {said}");
    assert!((position - case.target).abs() <= case.tolerance, "the clean run reaches {}: {position}", case.target);
    // Bits spread over the whole session each way, a different bit of the byte each time.
    const PER_DIRECTION: u64 = 8;
    let mut flips = Vec::new();
    for (to_device, bytes) in [(true, to_device), (false, to_host)] {
        let bits = bytes * 8;
        for k in 0..PER_DIRECTION {
            flips.push(Flip { to_device, bit: (bits * k / PER_DIRECTION + k * 3) % bits });
        }
    }
    let case = Arc::new(case);
    let refused = Arc::new(AtomicU64::new(0));
    let workers: Vec<_> = flips
        .chunks(flips.len().div_ceil(3))
        .map(|chunk| {
            let (case, chunk, refused) = (Arc::clone(&case), chunk.to_vec(), Arc::clone(&refused));
            thread::spawn(move || {
                for flip in chunk {
                    let (code, position, _, _, said) = run(&case, Some(flip));
                    if code == 0 {
                        assert!(
                            (position - case.target).abs() <= case.tolerance,
                            "{} with {flip:?}: exit 0 but the axis is at {position}, not {}",
                            case.family,
                            case.target
                        );
                    } else {
                        refused.fetch_add(1, Ordering::SeqCst);
                        assert!(!said.is_empty(), "{} with {flip:?}: exit {code} without a word", case.family);
                    }
                }
            })
        })
        .collect();
    for w in workers {
        w.join().unwrap();
    }
    // The flips land where they matter: some of them make the command fail (and say so).
    let refused = refused.load(Ordering::SeqCst);
    if case.some_fail {
        assert!(refused > 0, "{}: no flip made any difference: the sweep tests nothing", case.family);
    } else {
        assert_eq!(refused, 0, "{}: a flip the checksum catches is repaired by a resend", case.family);
    }
    eprintln!("{}: {} of {} flipped runs failed, the rest reached the target", case.family, refused, flips.len());
}

#[test]
fn one_flipped_bit_never_ends_an_scu_move_in_success_elsewhere() {
    sweep(Case {
        family: "scu",
        sim_args: &["--tcp", "127.0.0.1:0"],
        command: &["move", "1", "20", "--speed", "100"],
        target: 20.0,
        tolerance: 5.0,
        some_fail: false,
        position: scu_position,
    });
}

#[test]
fn one_flipped_bit_never_ends_a_powercube_move_in_success_elsewhere() {
    sweep(Case {
        family: "powercube",
        sim_args: &["--tcp", "127.0.0.1:0"],
        command: &["move", "0.05"],
        target: 0.05,
        tolerance: 0.001,
        some_fail: true,
        position: powercube_position,
    });
}

#[test]
fn one_flipped_bit_never_ends_a_compax_move_in_success_elsewhere() {
    sweep(Case {
        family: "compax",
        sim_args: &["--tcp", "127.0.0.1:0"],
        command: &["move", "--abs", "5", "--speed", "100"],
        target: 5.0,
        tolerance: 0.01,
        some_fail: true,
        position: compax_position,
    });
}
