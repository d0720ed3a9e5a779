//! An idle session sleeps between keepalives: two seconds of real time cost almost no CPU time.

#![cfg(target_os = "linux")]

use std::time::Duration;

use motionlink_link::pipe::{EmulatorHost, PipeConfig};
use motionlink_link::RealClock;
use motionlink_scu::{Client, Config};
use motionlink_scu::{Emulator, SimConfig};

/// CPU time this process has used (user + system), from /proc/self/stat, in clock ticks (normally 10 ms).
fn cpu_ticks() -> u64 {
    let stat = std::fs::read_to_string("/proc/self/stat").unwrap();
    // The fields after the command name (which is in parentheses and may contain spaces).
    let rest = &stat[stat.rfind(')').unwrap() + 2..];
    let fields: Vec<&str> = rest.split_whitespace().collect();
    // utime and stime are fields 14 and 15 of the whole line: 11 and 12 after the name.
    fields[11].parse::<u64>().unwrap() + fields[12].parse::<u64>().unwrap()
}

#[test]
fn an_idle_session_costs_no_measurable_cpu() {
    let clock = RealClock::shared();
    let unit = EmulatorHost::new(Emulator::new(SimConfig::default()).unwrap(), clock.clone(), PipeConfig::instant());
    let client = Client::with_connector(unit.connector(), clock, Config::default()).unwrap();
    let before = cpu_ticks();
    std::thread::sleep(Duration::from_secs(2));
    let used = cpu_ticks() - before;
    let keepalives = client.stats().keepalives;
    assert!((8..=11).contains(&keepalives), "{keepalives} keepalives in 2 s");
    // Ten keepalives and their replies; a busy loop would use about 200 ticks here.
    assert!(used <= 3, "{used} ticks of CPU time in 2 s of idle session");
    client.close().unwrap();
}
