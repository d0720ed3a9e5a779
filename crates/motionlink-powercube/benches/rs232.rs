//! RS232 frame encode + decode with DLE escaping: target at least 20 million frames per second, without
//! allocation (the allocation-free property is asserted by tests/no_alloc.rs); measured quiet and with two
//! CPU-bound threads running beside it.
//!
//! `cargo bench -p motionlink-powercube --features bench --bench rs232 -- --warm-up-time 1 --measurement-time 3` is a quick
//! run.

use std::hint::black_box;
use std::time::{Duration, Instant};

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use motionlink_powercube::wire::rs232::{self, Rs232Decoder, TelKind};
use motionlink_powercube::wire::Payload;
use motionlink_testkit::load::Load;

const BATCH: u64 = 1_000;

fn round_trip(decoder: &mut Rs232Decoder, payload: &Payload, address: u8) -> usize {
    let mut buf = [0u8; rs232::MAX_FRAME];
    let n = rs232::encode(TelKind::Send, address, payload, &mut buf).unwrap_or(0);
    let mut len = 0;
    for &b in &buf[..n] {
        if let Some(Ok(f)) = decoder.push(b) {
            len += f.payload.len();
        }
    }
    len
}

/// Frames per second over 5 million round trips (alternating the two frames).
fn rate(halt: &Payload, set: &Payload) -> f64 {
    let mut decoder = Rs232Decoder::new();
    let frames = 5_000_000u64;
    let start = Instant::now();
    let mut total = 0;
    for i in 0..frames {
        let p = if i % 2 == 0 { halt } else { set };
        total += round_trip(&mut decoder, black_box(p), black_box(17));
    }
    let took = start.elapsed().max(Duration::from_nanos(1));
    black_box(total);
    frames as f64 / took.as_secs_f64()
}

fn bench(c: &mut Criterion) {
    // The manual's Halt (0x02 escaped) and a SetExtended whose data needs escaping: worst realistic cases.
    let halt = Payload::new(&[0x02]).unwrap();
    let set = Payload::new(&[0x08, 0x4f, 0x02, 0x03, 0x10, 0x3d]).unwrap();
    let mut group = c.benchmark_group("rs232");
    group.throughput(Throughput::Elements(BATCH));
    group.bench_function("encode+decode 1000 escaped frames", |b| {
        let mut decoder = Rs232Decoder::new();
        b.iter(|| {
            let mut total = 0;
            for i in 0..BATCH {
                let p = if i % 2 == 0 { &halt } else { &set };
                total += round_trip(&mut decoder, black_box(p), black_box(17));
            }
            black_box(total)
        })
    });
    {
        let _load = Load::start(2);
        group.bench_function("encode+decode 1000 escaped frames, two CPU-bound threads beside", |b| {
            let mut decoder = Rs232Decoder::new();
            b.iter(|| {
                let mut total = 0;
                for i in 0..BATCH {
                    let p = if i % 2 == 0 { &halt } else { &set };
                    total += round_trip(&mut decoder, black_box(p), black_box(17));
                }
                black_box(total)
            })
        });
    }
    group.finish();

    // The numbers the issue asks for, printed plainly.
    let quiet = rate(&halt, &set);
    let loaded = {
        let _load = Load::start(2);
        rate(&halt, &set)
    };
    for (name, r) in [("quiet", quiet), ("loaded (two CPU-bound threads)", loaded)] {
        println!(
            "rs232 encode+decode with escaping, {name}: {:.1} million frames/s (target: at least 20 million frames/s) -> {}",
            r / 1e6,
            if r >= 20e6 { "met" } else { "NOT met" }
        );
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
