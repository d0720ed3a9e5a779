//! Reading the position of 31 modules over the in-memory CAN bus paced at 1 Mbit/s, with the real clock,
//! quiet and with two CPU-bound threads running beside the session: the sweep must reach at least 97 % of
//! the rate the bus itself allows, in both cases.
//!
//! A sweep is 31 GetExtended(ActPos) frames (DLC 2) and 31 acknowledges (DLC 6). Without stuff bits a
//! standard frame is 47 + 8 × DLC bits (31 × (63 + 95) = 4898 bits per sweep), but a real bus also carries
//! the stuff bits that each frame's own bits call for: the limit is computed from the very frames of the
//! sweep (the requests the client sends and the acknowledges the emulator gives) with
//! `CanFrame::bit_length_stuffed`, and the worst case (`bit_length_worst_case`, one stuff bit per four bits)
//! is printed beside it. The in-memory bus times every frame with its stuffed length too, so the ratio
//! compares like with like.
//!
//! `cargo bench -p motionlink-powercube --features bench --bench can_sweep -- --warm-up-time 1 --measurement-time 3` is
//! a quick run.

use std::hint::black_box;
use std::time::{Duration, Instant};

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use motionlink_link::can::{CanBus, CanBusConfig, CanEmulator, CanFrame};
use motionlink_link::{RealClock, Timestamp};
use motionlink_powercube::client::{Client, Config, PortLink};
use motionlink_powercube::model::{Address, Param};
use motionlink_powercube::sim::SimConfig;
use motionlink_powercube::wire::can::{to_frame, Role};
use motionlink_powercube::wire::Request;
use motionlink_powercube::Emulator;
use motionlink_testkit::load::Load;

const BITRATE: u32 = 1_000_000;
const MODULES: u8 = 31;
const TARGET: f64 = 0.97;

/// The frames of one sweep: every request and the acknowledge the emulated module gives to it.
fn sweep_frames() -> Vec<CanFrame> {
    let addresses: Vec<u8> = (1..=MODULES).collect();
    let mut sim = Emulator::new_can(&SimConfig::with_addresses(&addresses).expect("31 addresses"));
    let mut frames = Vec::new();
    for a in addresses {
        let get = to_frame(Role::Get(a), &Request::Get(Param::ActPos).encode());
        let mut out = Vec::new();
        CanEmulator::receive(&mut sim, Timestamp::ZERO, &get, &mut out);
        assert_eq!(out.len(), 1, "module {a} answers once");
        frames.push(get);
        frames.extend(out);
    }
    frames
}

/// Bits per sweep: without stuff bits, with the frames' real stuff bits, at worst.
fn bits_per_sweep() -> (u32, u32, u32) {
    let frames = sweep_frames();
    let sum = |f: fn(&CanFrame) -> u32| frames.iter().map(f).sum::<u32>();
    (sum(CanFrame::bit_length), sum(CanFrame::bit_length_stuffed), sum(CanFrame::bit_length_worst_case))
}

fn setup() -> (Client, Vec<Address>) {
    let addresses: Vec<u8> = (1..=MODULES).collect();
    let clock = RealClock::shared();
    let sim = Emulator::new_can(&SimConfig::with_addresses(&addresses).expect("31 addresses"));
    let can = CanBus::with_emulator(sim, clock.clone(), CanBusConfig::paced(BITRATE));
    let bus =
        Client::with_link(PortLink::Can(Box::new(can.connect())), clock, Config::can()).expect("the session starts");
    (bus, addresses.iter().map(|&a| Address::new(a).expect("1..31")).collect())
}

fn sweep(bus: &Client, addresses: &[Address]) {
    for p in bus.positions(addresses) {
        black_box(p.expect("every module answers"));
    }
}

fn measured_rate(bus: &Client, addresses: &[Address]) -> f64 {
    let sweeps = 300;
    let start = Instant::now();
    for _ in 0..sweeps {
        sweep(bus, addresses);
    }
    f64::from(sweeps) / start.elapsed().as_secs_f64()
}

fn bench(c: &mut Criterion) {
    let (bus, addresses) = setup();
    let mut group = c.benchmark_group("can");
    group.throughput(Throughput::Elements(u64::from(MODULES)));
    group.sample_size(30).measurement_time(Duration::from_secs(4));
    group.bench_function("sweep ActPos of 31 modules at 1 Mbit/s, quiet", |b| b.iter(|| sweep(&bus, &addresses)));
    {
        let _load = Load::start(2);
        group.bench_function("sweep ActPos of 31 modules at 1 Mbit/s, two CPU-bound threads beside", |b| {
            b.iter(|| sweep(&bus, &addresses))
        });
    }
    group.finish();

    let quiet = measured_rate(&bus, &addresses);
    let loaded = {
        let _load = Load::start(2);
        measured_rate(&bus, &addresses)
    };
    let (plain, stuffed, worst) = bits_per_sweep();
    let limit = f64::from(BITRATE) / f64::from(stuffed);
    println!("bus-limited sweep rate = bit rate / bits per sweep (31 requests, 31 acknowledges)");
    println!("  bits per sweep without stuff bits       = 31 x ((47 + 8 x 2) + (47 + 8 x 6)) = {plain}");
    println!("  bits per sweep with its real stuff bits = {stuffed} -> {limit:.1} sweeps/s (the limit)");
    println!(
        "  bits per sweep at worst-case stuffing   = {worst} -> {:.1} sweeps/s",
        f64::from(BITRATE) / f64::from(worst)
    );
    for (name, rate) in [("quiet", quiet), ("loaded (two CPU-bound threads)", loaded)] {
        println!(
            "  measured, {name}: {rate:.1} sweeps/s = {:.1} % of the limit (target: at least {:.0} %) -> {}",
            100.0 * rate / limit,
            100.0 * TARGET,
            if rate >= TARGET * limit { "met" } else { "NOT met" }
        );
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
