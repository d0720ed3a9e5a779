//! Benchmarks: request build + reply parse (target: 20 million per second, no allocation); polling S1
//! of 31 drives over the in-memory link paced at 115200 and at 9600 baud, quiet (target: 95 % of the
//! wire-limited rate) and loaded: the benchmark starts two CPU-bound threads beside the session (target:
//! 97 %); the host overhead of one S1 read above its wire time at 115200 baud, through the blocking
//! client and through the async one (tokio), side by side; and `decode` of a capture without a COMPAX
//! telegram (another family's bytes, read in 4 kB pieces), 120 kB and 1.2 MB (target: time linear in the
//! length: the longer at most 3 times the shorter's time per byte; it was quadratic, 1.2 MB took 7.6 s).
//!
//! `COMPAX_BENCH_QUICK=1` shortens the extra measurements (the ratio and overhead runs) for a smoke run.
//!
//! Besides criterion's report, each benchmark prints its target and whether it was met (on stderr). The codec
//! rate is the fastest of many short trials: on a shared virtual machine the host takes the processor away
//! now and then, which a mean counts and the fastest trial does not. The polling ratio is over a longer run
//! of whole sweeps.

use std::hint::black_box;
use std::time::{Duration, Instant};

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use motionlink_compax::client::Config;
use motionlink_compax::describe::Describer;
use motionlink_compax::model::{Command, CommandStyle, CommandText, StatusId, StatusValue};
use motionlink_compax::sim::SimConfig;
use motionlink_compax::wire::{Address, Body, Flags, Frame, Mode, ReplyDecoder, ReplyEventRef, Request};
use motionlink_compax::{AsyncClient, Client, Emulator};
use motionlink_link::chunk::{Chunk, Direction};
use motionlink_link::describe::Describe;
use motionlink_link::link::{char_time, Parity};
use motionlink_link::pipe::{EmulatorHost, PipeConfig};
use motionlink_link::RealClock;
use motionlink_testkit::load::Load;

/// Build + parse rounds per second the codec should reach.
const CODEC_TARGET_PER_S: f64 = 20e6;
/// The share of the wire-limited sweep rate the client should reach.
const POLL_TARGET_PERCENT: f64 = 95.0;
/// The same with two CPU-bound threads running beside the session.
const POLL_TARGET_LOADED_PERCENT: f64 = 97.0;

fn met(ok: bool) -> &'static str {
    if ok {
        "met"
    } else {
        "NOT met"
    }
}

/// Builds `S1` to drive 17 and parses the reply `S001: -360.125`; returns the position read.
fn build_and_parse_once(mode: &Mode, address: Address, reply: &[u8], decoder: &mut ReplyDecoder) -> f64 {
    let cmd = Command::ReadStatus(StatusId::ACTUAL_POSITION);
    let mut text = CommandText::new();
    cmd.write_ascii_into(CommandStyle::Long, &mut text).unwrap();
    let mut frame = Frame::default();
    Request { address, body: Body::Command(text.as_bytes()), flags: Flags::NONE }
        .encode_into(mode, &mut frame)
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
    value
}

fn build_and_parse(c: &mut Criterion) {
    let mode = Mode::default();
    let address = Address::drive(17).unwrap();
    let reply: &[u8] = b"S001: -360.125\r\n>";
    let mut decoder = ReplyDecoder::new(&mode);
    assert_eq!(build_and_parse_once(&mode, address, reply, &mut decoder), -360.125);
    let mut g = c.benchmark_group("codec");
    g.throughput(Throughput::Elements(1));
    g.bench_function("request build + reply parse (S1)", |b| {
        b.iter(|| black_box(build_and_parse_once(&mode, address, reply, &mut decoder)))
    });
    g.finish();
    const ROUNDS: u32 = 10_000;
    let fastest = (0..300)
        .map(|_| {
            let t = Instant::now();
            for _ in 0..ROUNDS {
                black_box(build_and_parse_once(&mode, address, reply, &mut decoder));
            }
            t.elapsed()
        })
        .min()
        .unwrap_or_default();
    let per_round = fastest.as_secs_f64() / f64::from(ROUNDS);
    let rate = 1.0 / per_round.max(1e-12);
    eprintln!(
        "request build + reply parse (S1): fastest trial {:.1} ns per round = {:.1} million/s \
         (target: at least {:.0} million/s: {})",
        per_round * 1e9,
        rate / 1e6,
        CODEC_TARGET_PER_S / 1e6,
        met(rate >= CODEC_TARGET_PER_S)
    );
}

fn poll_31_with(c: &mut Criterion, baud: u32, loaded: bool) {
    let addrs: Vec<u8> = (1..=31).collect();
    let clock = RealClock::shared();
    let sim = Emulator::new(SimConfig::bus(&addrs, 0, baud)).unwrap();
    let host = EmulatorHost::new(sim, clock.clone(), PipeConfig::paced(baud));
    let bus = Client::with_link(Box::new(host.connect().0), clock, Config::new(Mode::default(), baud)).unwrap();
    let drives: Vec<Address> = addrs.iter().map(|&a| Address::drive(a).unwrap()).collect();
    // Wire time of one sweep: each request ("NS1\r" or "NNS1\r") and reply ("S001: 0.000\r\n>", 14 bytes).
    let bytes: u32 = drives.iter().map(|a| if a.get() >= 10 { 5 } else { 4 } + 14).sum();
    let wire = char_time(baud, Parity::None) * bytes;
    let mut sweep = || {
        for &a in &drives {
            black_box(bus.read_position(a).unwrap());
        }
    };
    let load = loaded.then(|| Load::start(2));
    let what = if loaded { "loaded: two CPU-bound threads beside it" } else { "quiet" };
    let mut g = c.benchmark_group("bus");
    g.throughput(Throughput::Elements(31));
    g.sample_size(if baud < 38_400 { 10 } else { 20 }).measurement_time(Duration::from_secs(5));
    g.bench_function(format!("poll S1 of 31 drives, {baud} baud, paced in-memory link, {what}"), |b| {
        b.iter(&mut sweep)
    });
    g.finish();
    // The ratio to the wire-limited rate over a longer run (about 2 s at 115200 baud, 5 s at 9600).
    let t0 = Instant::now();
    let rounds = match (quick(), baud < 38_400) {
        (true, _) => 2,
        (false, true) => 8,
        (false, false) => 40,
    };
    for _ in 0..rounds {
        sweep();
    }
    let took = t0.elapsed() / rounds;
    drop(load);
    let percent = wire.as_secs_f64() / took.as_secs_f64().max(1e-12) * 100.0;
    let target = if loaded { POLL_TARGET_LOADED_PERCENT } else { POLL_TARGET_PERCENT };
    eprintln!(
        "poll S1 of 31 drives at {baud} baud ({what}): {:.2} ms per sweep, wire-limited {:.2} ms: {percent:.1} % \
         of the wire rate (target: at least {target:.0} %: {})",
        took.as_secs_f64() * 1e3,
        wire.as_secs_f64() * 1e3,
        met(percent >= target)
    );
}

/// At 115200 baud the paced in-memory link hands the session each byte at its own time, 87 us apart, and
/// the real clock spins the last 100 us of every wait: during an exchange the session keeps a core busy,
/// so beside two CPU-bound threads on a two-core machine it gets about two thirds of one. At 9600 baud it
/// sleeps between bytes.
fn poll_31(c: &mut Criterion) {
    poll_31_with(c, 115_200, false);
}

fn poll_31_loaded(c: &mut Criterion) {
    poll_31_with(c, 115_200, true);
}

fn poll_31_9600(c: &mut Criterion) {
    poll_31_with(c, 9600, false);
}

fn poll_31_9600_loaded(c: &mut Criterion) {
    poll_31_with(c, 9600, true);
}

/// True when `COMPAX_BENCH_QUICK` asks for short extra measurements.
fn quick() -> bool {
    std::env::var_os("COMPAX_BENCH_QUICK").is_some()
}

/// Median and 90th percentile of `overheads`.
fn median_p90(mut overheads: Vec<Duration>) -> (Duration, Duration) {
    overheads.sort();
    (overheads[overheads.len() / 2], overheads[overheads.len() * 9 / 10])
}

/// The host overhead of single S1 reads (the time of the call minus the wire time of request and reply)
/// at 115200 baud over the paced in-memory link, through the blocking client and the async one, quiet and
/// loaded. The async client's operations run on the driver's thread and wake the task: one thread hand-off
/// more each way than the blocking client, which drives the port from the calling thread.
fn host_overhead(c: &mut Criterion) {
    const BAUD: u32 = 115_200;
    let clock = RealClock::shared();
    let sim = Emulator::new(SimConfig::bus(&[17], 0, BAUD)).unwrap();
    let host = EmulatorHost::new(sim, clock.clone(), PipeConfig::paced(BAUD));
    let cfg = Config::new(Mode::default(), BAUD);
    let blocking = Client::with_link(Box::new(host.connect().0), clock.clone(), cfg.clone()).unwrap();
    let drive = Address::drive(17).unwrap();
    // "17S1\r" and "S001: 0.000\r\n>".
    let wire = char_time(BAUD, Parity::None) * (5 + 14);
    let runtime = tokio::runtime::Builder::new_current_thread().enable_all().build().unwrap();
    let n = if quick() { 200 } else { 2000 };
    let mut g = c.benchmark_group("host overhead");
    g.sample_size(20).measurement_time(Duration::from_secs(3));
    for loaded in [false, true] {
        let _load = loaded.then(|| Load::start(2));
        let what = if loaded { ", two busy threads beside it" } else { "" };
        g.bench_function(format!("blocking client, S1 at 115200 baud{what}"), |b| {
            b.iter_custom(|iters| {
                let mut overhead = Duration::ZERO;
                for _ in 0..iters {
                    let t = Instant::now();
                    black_box(blocking.read_position(drive).unwrap());
                    overhead += t.elapsed().saturating_sub(wire);
                }
                overhead
            })
        });
        let single: Vec<Duration> = (0..n)
            .map(|_| {
                let t = Instant::now();
                black_box(blocking.read_position(drive).unwrap());
                t.elapsed().saturating_sub(wire)
            })
            .collect();
        let (b_median, b_p90) = median_p90(single);
        // A second connection to the same emulated bus, driven by the async client (the blocking client
        // stays idle meanwhile).
        let async_client = runtime.block_on(async {
            AsyncClient::with_link(Box::new(host.connect().0), clock.clone(), cfg.clone()).await.unwrap()
        });
        g.bench_function(format!("async client (tokio), S1 at 115200 baud{what}"), |b| {
            b.iter_custom(|iters| {
                runtime.block_on(async {
                    let mut overhead = Duration::ZERO;
                    for _ in 0..iters {
                        let t = Instant::now();
                        black_box(async_client.read_position(drive).await.unwrap());
                        overhead += t.elapsed().saturating_sub(wire);
                    }
                    overhead
                })
            })
        });
        let single: Vec<Duration> = runtime.block_on(async {
            let mut v = Vec::with_capacity(n);
            for _ in 0..n {
                let t = Instant::now();
                black_box(async_client.read_position(drive).await.unwrap());
                v.push(t.elapsed().saturating_sub(wire));
            }
            v
        });
        let (a_median, a_p90) = median_p90(single);
        runtime.block_on(async_client.close()).unwrap();
        eprintln!(
            "host overhead above the wire time ({wire:?}) of one S1 read at 115200 baud, {n} single reads{what}: \
             blocking client median {b_median:?}, 90th percentile {b_p90:?}; async client (tokio) median \
             {a_median:?}, 90th percentile {a_p90:?}"
        );
    }
    g.finish();
}

/// Decodes `bytes` as `motionlink decode compax` reads a file: in 4 kB pieces, direction unknown; the
/// number of annotations.
fn decode_capture(bytes: &[u8]) -> usize {
    let mut d = Describer::new(Mode::default());
    let mut out = Vec::new();
    for piece in bytes.chunks(4096) {
        d.describe(Chunk::Bytes(piece), Direction::Unknown, None, &mut out);
    }
    d.finish(&mut out);
    out.len()
}

fn decode_without_telegrams(c: &mut Criterion) {
    let capture = |n: usize| [0x52u8, 0x47, 0x11, 0x00, 0x2C, 0x30].repeat(n / 6);
    let (short, long) = (capture(120_000), capture(1_200_000));
    let mut g = c.benchmark_group("decode");
    g.sample_size(10);
    g.throughput(Throughput::Bytes(short.len() as u64));
    g.bench_function("a capture without a COMPAX telegram, 120 kB", |b| b.iter(|| decode_capture(black_box(&short))));
    g.finish();
    let per_byte = |bytes: &[u8]| {
        let fastest = (0..3)
            .map(|_| {
                let t = Instant::now();
                black_box(decode_capture(bytes));
                t.elapsed()
            })
            .min()
            .unwrap_or_default();
        fastest.as_secs_f64() / bytes.len() as f64
    };
    let (a, b) = (per_byte(&short), per_byte(&long));
    eprintln!(
        "decode of a capture without a telegram: {:.0} ns per byte at 120 kB, {:.0} ns at 1.2 MB (target: at most \
         3 times as much per byte at 1.2 MB: {})",
        a * 1e9,
        b * 1e9,
        met(b <= 3.0 * a)
    );
}

criterion_group!(
    benches,
    build_and_parse,
    poll_31,
    poll_31_loaded,
    poll_31_9600,
    poll_31_9600_loaded,
    host_overhead,
    decode_without_telegrams
);
criterion_main!(benches);
