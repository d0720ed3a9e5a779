//! Benchmarks: request build + reply parse (target: 20 million per second, no allocation), and polling S1
//! of 31 drives over the in-memory link paced at 115200 baud (target: 95 % of the wire-limited rate).

use std::hint::black_box;
use std::time::{Duration, Instant};

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use motionlink_compax::client::{Bus, BusConfig};
use motionlink_compax::model::{Command, CommandStyle, CommandText, StatusId, StatusValue};
use motionlink_compax::sim::{CompaxBus, SimConfig};
use motionlink_compax::wire::{Address, Body, Flags, Frame, Mode, ReplyDecoder, ReplyEventRef, Request};
use motionlink_link::link::{char_time, Parity};
use motionlink_link::pipe::{EmulatorHost, PipeConfig};
use motionlink_link::RealClock;

fn build_and_parse(c: &mut Criterion) {
    let mode = Mode::default();
    let address = Address::drive(17).unwrap();
    let reply: &[u8] = b"S001: -360.125\r\n>";
    let mut decoder = ReplyDecoder::new(&mode);
    let mut g = c.benchmark_group("codec");
    g.throughput(Throughput::Elements(1));
    g.bench_function("request build + reply parse (S1)", |b| {
        b.iter(|| {
            let cmd = Command::ReadStatus(StatusId::ACTUAL_POSITION);
            let mut text = CommandText::new();
            cmd.write_ascii_into(CommandStyle::Long, &mut text).unwrap();
            let mut frame = Frame::default();
            Request { address, body: Body::Command(text.as_bytes()), flags: Flags::NONE }
                .encode_into(&mode, &mut frame)
                .unwrap();
            black_box(frame.as_bytes());
            let mut value = 0.0;
            let mut rest = black_box(reply);
            while !rest.is_empty() {
                let (used, event) = decoder.decode(rest);
                rest = &rest[used..];
                if let Some(ReplyEventRef::Reply(r)) = event {
                    if let Ok(StatusValue::Position(p)) = StatusValue::parse(StatusId::ACTUAL_POSITION, r.text()) {
                        value = p.units();
                    }
                }
            }
            black_box(value)
        })
    });
    g.finish();
}

const BAUD: u32 = 115_200;

fn poll_31(c: &mut Criterion) {
    let addrs: Vec<u8> = (1..=31).collect();
    let clock = RealClock::shared();
    let sim = CompaxBus::new(SimConfig::bus(&addrs, 0, BAUD)).unwrap();
    let host = EmulatorHost::new(sim, clock.clone(), PipeConfig::paced(BAUD));
    let mut bus = Bus::new(Box::new(host.connect().0), clock, BusConfig::new(Mode::default(), BAUD));
    let drives: Vec<Address> = addrs.iter().map(|&a| Address::drive(a).unwrap()).collect();
    // Wire time of one sweep: each request ("NS1\r" or "NNS1\r") and reply ("S001: 0.000\r\n>", 14 bytes).
    let bytes: u32 = drives.iter().map(|a| if a.get() >= 10 { 5 } else { 4 } + 14).sum();
    let wire = char_time(BAUD, Parity::None) * bytes;
    let mut sweep = || {
        for &a in &drives {
            black_box(bus.read_position(a).unwrap());
        }
    };
    // Report the ratio to the wire-limited rate over a longer run as well.
    let t0 = Instant::now();
    let rounds = 40;
    for _ in 0..rounds {
        sweep();
    }
    let took = t0.elapsed() / rounds;
    eprintln!(
        "poll S1 of 31 drives at {BAUD} baud: {:.2} ms per sweep, wire-limited {:.2} ms: {:.1} % of the wire rate",
        took.as_secs_f64() * 1e3,
        wire.as_secs_f64() * 1e3,
        wire.as_secs_f64() / took.as_secs_f64() * 100.0
    );
    let mut g = c.benchmark_group("bus");
    g.throughput(Throughput::Elements(31));
    g.sample_size(20).measurement_time(Duration::from_secs(5));
    g.bench_function("poll S1 of 31 drives, 115200 baud, paced in-memory link", |b| b.iter(&mut sweep));
    g.finish();
}

criterion_group!(benches, build_and_parse, poll_31);
criterion_main!(benches);
