//! The host's own time per request, blocking and async side by side: one ActPos read of one module over the
//! in-memory CAN bus paced at 1 Mbit/s (real clock), minus the time the two frames take on the bus (their
//! real stuff bits counted). The blocking client drives the link on the caller's thread; the async client
//! hands each operation to the driver's thread and is woken by it: the difference is what that costs. A
//! third figure, "host's own", has the reader spin until each frame is there: what is left is the work of
//! the client, the session and the driver, without the operating system's wake-up latency (about 20 µs on the
//! development machine's virtual CPUs, which a sleeping reader pays once per read on any bus).
//!
//! `cargo bench -p motionlink-powercube --features bench --bench host_overhead -- --warm-up-time 1 --measurement-time 3` is
//! a quick run.

use std::hint::black_box;
use std::time::{Duration, Instant};

use criterion::{criterion_group, criterion_main, Criterion};
use motionlink_link::can::{CanBus, CanBusConfig, CanEmulator, CanFrame};
use motionlink_link::{RealClock, Timestamp};
use motionlink_powercube::client::{AsyncClient, Client, Config, PortLink};
use motionlink_powercube::model::{Address, Param};
use motionlink_powercube::sim::SimConfig;
use motionlink_powercube::wire::can::{to_frame, Role};
use motionlink_powercube::wire::Request;
use motionlink_powercube::Emulator;

const BITRATE: u32 = 1_000_000;

fn bus() -> CanBus<Emulator> {
    bus_with(CanBusConfig::paced(BITRATE))
}

fn bus_with(config: CanBusConfig) -> CanBus<Emulator> {
    let sim = Emulator::new_can(&SimConfig::with_addresses(&[1]).expect("one module"));
    CanBus::with_emulator(sim, RealClock::shared(), config)
}

/// The time one read takes on the bus: the request and the acknowledge, with their stuff bits.
fn wire_time() -> Duration {
    let mut sim = Emulator::new_can(&SimConfig::with_addresses(&[1]).expect("one module"));
    let get = to_frame(Role::Get(1), &Request::Get(Param::ActPos).encode());
    let mut out = Vec::new();
    CanEmulator::receive(&mut sim, Timestamp::ZERO, &get, &mut out);
    let bits: u32 = std::iter::once(&get).chain(&out).map(CanFrame::bit_length_stuffed).sum();
    Duration::from_secs_f64(f64::from(bits) / f64::from(BITRATE))
}

fn mean(n: u32, mut read: impl FnMut()) -> Duration {
    let start = Instant::now();
    for _ in 0..n {
        read();
    }
    start.elapsed() / n
}

fn bench(c: &mut Criterion) {
    let blocking_bus = bus();
    let blocking =
        Client::with_link(PortLink::Can(Box::new(blocking_bus.connect())), RealClock::shared(), Config::can())
            .expect("the session starts");
    let one = Address::new(1).expect("address 1");
    let module = blocking.module(one);

    let runtime = tokio::runtime::Builder::new_current_thread().enable_time().build().expect("a tokio runtime");
    let async_bus = bus();
    let asynchronous = runtime
        .block_on(AsyncClient::with_link(
            PortLink::Can(Box::new(async_bus.connect())),
            RealClock::shared(),
            Config::can(),
        ))
        .expect("the session starts");
    let async_module = asynchronous.module(one);

    let mut group = c.benchmark_group("host overhead");
    group.sample_size(50).measurement_time(Duration::from_secs(4));
    group.bench_function("ActPos read at 1 Mbit/s, blocking client", |b| {
        b.iter(|| black_box(module.position().expect("answers")))
    });
    group.bench_function("ActPos read at 1 Mbit/s, async client (tokio)", |b| {
        b.iter(|| black_box(runtime.block_on(async_module.position()).expect("answers")))
    });
    group.finish();

    let n = 2_000;
    let blocking_mean = mean(n, || {
        black_box(module.position().expect("answers"));
    });
    let async_mean = runtime.block_on(async {
        let start = Instant::now();
        for _ in 0..n {
            black_box(async_module.position().await.expect("answers"));
        }
        start.elapsed() / n
    });
    // The host's own time: the same reads where the client's thread spins until each frame is there, so that
    // no wake-up latency of the operating system counts (a sleeping reader's wake-up by a timer, here, or by
    // a frame's interrupt, on a real bus, is the operating system's time, the same for any library).
    let spin_bus = bus_with(CanBusConfig { reader_spins: true, ..CanBusConfig::paced(BITRATE) });
    let spinning = Client::with_link(PortLink::Can(Box::new(spin_bus.connect())), RealClock::shared(), Config::can())
        .expect("the session starts");
    let spin_module = spinning.module(one);
    let spin_mean = mean(n, || {
        black_box(spin_module.position().expect("answers"));
    });
    spinning.close().expect("closes");
    let wire = wire_time();
    println!("one ActPos read of one module on the in-memory CAN bus at 1 Mbit/s (request + acknowledge)");
    println!("  on the bus (stuff bits counted):  {:>7.1} us", wire.as_secs_f64() * 1e6);
    for (name, m) in
        [("blocking client", blocking_mean), ("async client (tokio)", async_mean), ("blocking, host's own", spin_mean)]
    {
        println!(
            "  {name:<22} {:>7.1} us per read, host overhead {:>6.1} us",
            m.as_secs_f64() * 1e6,
            m.saturating_sub(wire).as_secs_f64() * 1e6
        );
    }
    runtime.block_on(asynchronous.close()).expect("closes");
    blocking.close().expect("closes");
}

criterion_group!(benches, bench);
criterion_main!(benches);
