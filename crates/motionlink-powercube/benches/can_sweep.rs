//! Reading the position of 31 modules over the in-memory CAN bus paced at 1 Mbit/s, with the real clock:
//! the sweep must reach at least 90 % of the rate the bus itself allows.
//!
//! A sweep is 31 GetExtended(ActPos) frames (DLC 2) and 31 acknowledges (DLC 6). Without stuff bits a
//! standard frame is 47 + 8 × DLC bits, so a sweep occupies the bus for
//! 31 × ((47 + 8 × 2) + (47 + 8 × 6)) = 31 × (63 + 95) = 4898 bits = 4.898 ms at 1 Mbit/s:
//! at most 204.2 sweeps per second.

use std::hint::black_box;
use std::time::{Duration, Instant};

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use motionlink_link::can::{CanBus, CanBusConfig};
use motionlink_link::RealClock;
use motionlink_powercube::client::{Bus, BusConfig};
use motionlink_powercube::sim::{SimBus, SimConfig};

const BITRATE: u32 = 1_000_000;
const MODULES: u8 = 31;

fn bus_limited_sweeps_per_second() -> (u32, f64) {
    let bits = u32::from(MODULES) * ((47 + 8 * 2) + (47 + 8 * 6));
    (bits, f64::from(BITRATE) / f64::from(bits))
}

fn setup() -> (Bus, Vec<u8>) {
    let addresses: Vec<u8> = (1..=MODULES).collect();
    let clock = RealClock::shared();
    let sim = SimBus::new_can(&SimConfig::with_addresses(&addresses).unwrap());
    let can = CanBus::with_emulator(sim, clock.clone(), CanBusConfig::paced(BITRATE));
    let bus = Bus::can(Box::new(can.connect()), clock, BusConfig::can());
    (bus, addresses)
}

fn sweep(bus: &Bus, addresses: &[u8]) {
    for p in bus.positions(addresses) {
        black_box(p.expect("every module answers"));
    }
}

fn bench(c: &mut Criterion) {
    let (bus, addresses) = setup();
    let mut group = c.benchmark_group("can");
    group.throughput(Throughput::Elements(u64::from(MODULES)));
    group.sample_size(30).measurement_time(Duration::from_secs(4));
    group.bench_function("sweep ActPos of 31 modules at 1 Mbit/s", |b| b.iter(|| sweep(&bus, &addresses)));
    group.finish();

    let sweeps = 300;
    let start = Instant::now();
    for _ in 0..sweeps {
        sweep(&bus, &addresses);
    }
    let rate = f64::from(sweeps) / start.elapsed().as_secs_f64();
    let (bits, limit) = bus_limited_sweeps_per_second();
    println!("bus-limited sweep rate = bit rate / bits per sweep");
    println!("  bits per sweep = 31 x ((47 + 8 x 2) + (47 + 8 x 6)) = {bits} bits");
    println!("  bus-limited    = {BITRATE} / {bits} = {limit:.1} sweeps/s");
    println!(
        "  measured       = {rate:.1} sweeps/s = {:.1} % of the bus limit (target: at least 90 %) -> {}",
        100.0 * rate / limit,
        if rate >= 0.9 * limit { "met" } else { "NOT met" }
    );
}

criterion_group!(benches, bench);
criterion_main!(benches);
