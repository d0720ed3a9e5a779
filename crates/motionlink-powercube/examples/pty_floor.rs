//! The floor of a blocking PowerCube read over a pseudo-terminal on this machine: what the kernel and the
//! emulator process cost, with no host library around them. The ActPos request of module 1 is encoded
//! once; each read is then one write of its frame and reads until the answer's ETX, over the same
//! `SerialLink` the client uses (no session, no decoding, no driver). `python/bench/pty_reads.py` runs the
//! library's reads over the same set-up; the difference is the library's share of a read.
//!
//! ```text
//! motionlink sim powercube --pty &     # prints the pty's path
//! cargo run --release -p motionlink-powercube --example pty_floor -- /dev/pts/N [reads] [rounds]
//! ```
//!
//! It prints the best round's reads per second and this thread's CPU time per read (from
//! `/proc/thread-self/schedstat`, in ns, where the system has it).

use std::time::{Duration, Instant};

use motionlink_link::link::{Link, SerialSettings};
use motionlink_link::serial::SerialLink;
use motionlink_powercube::model::Param;
use motionlink_powercube::wire::rs232::{self, TelKind, ETX, MAX_FRAME};
use motionlink_powercube::wire::Request;

/// This thread's CPU time so far, where the system says it.
fn cpu_time() -> Option<Duration> {
    let text = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
    Some(Duration::from_nanos(text.split_whitespace().next()?.parse().ok()?))
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let path = args.next().ok_or("give the pty's path (`motionlink sim powercube --pty` prints it)")?;
    let reads: u32 = args.next().map(|n| n.parse()).transpose()?.unwrap_or(2000);
    let rounds: u32 = args.next().map(|n| n.parse()).transpose()?.unwrap_or(5);
    if reads == 0 || rounds == 0 {
        return Err("reads and rounds: give at least 1".into());
    }
    let mut link = SerialLink::open(&path, SerialSettings::new(9600))?;
    let mut frame = [0u8; MAX_FRAME];
    let len = rs232::encode(TelKind::Send, 1, &Request::Get(Param::ActPos).encode(), &mut frame)?;
    let request = &frame[..len];
    let mut answer = [0u8; 64];
    let mut read_once = |link: &mut SerialLink| -> Result<(), Box<dyn std::error::Error>> {
        link.send(request)?;
        loop {
            let n = link.recv(&mut answer, Duration::from_millis(100))?;
            if n == 0 {
                return Err("the emulator did not answer within 100 ms".into());
            }
            // ETX is escaped inside a frame: a bare one ends it.
            if answer[..n].contains(&ETX) {
                return Ok(());
            }
        }
    };
    read_once(&mut link)?;
    let mut best: Option<(Duration, Option<Duration>)> = None;
    for _ in 0..rounds {
        let (wall0, cpu0) = (Instant::now(), cpu_time());
        for _ in 0..reads {
            read_once(&mut link)?;
        }
        let wall = wall0.elapsed() / reads;
        let cpu = cpu_time().zip(cpu0).map(|(b, a)| (b - a) / reads);
        if best.is_none_or(|(w, _)| wall < w) {
            best = Some((wall, cpu));
        }
    }
    let (wall, cpu) = best.ok_or("no round ran")?;
    let cpu = cpu.map_or("unknown".to_string(), |c| format!("{:.1} us", c.as_secs_f64() * 1e6));
    println!("{reads} ActPos reads over {path}, best of {rounds} rounds, nothing but the line's I/O:");
    println!("{:.1} k reads/s, {cpu} CPU per read", 1e-3 / wall.as_secs_f64());
    Ok(())
}
