//! RS232 encode and decode (with escaping) allocate nothing: counted by a global allocator.

use motionlink_powercube::wire::rs232::{self, Rs232Decoder, TelKind};
use motionlink_powercube::wire::Payload;
use motionlink_testkit::alloc_count::CountingAllocator;

#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator::new();

#[test]
fn rs232_encode_and_decode_never_allocate() {
    // Data full of bytes that need escaping, every address, every length.
    let payloads: Vec<Payload> =
        (0..=8).map(|n| Payload::new(&[0x02, 0x03, 0x10, 0x0b, 0x10, 0x02, 0x03, 0x0e][..n]).unwrap()).collect();
    let mut decoder = Rs232Decoder::new();
    let mut buf = [0u8; rs232::MAX_FRAME];
    let mut frames = 0u64;
    let before = CountingAllocator::allocations_on_this_thread();
    for round in 0..20_000u32 {
        let p = &payloads[(round % 9) as usize];
        let address = (round % 32) as u8;
        let n = rs232::encode(TelKind::Send, address, p, &mut buf).unwrap();
        for result in decoder.feed(&buf[..n]) {
            match result {
                Ok(f) => {
                    assert_eq!(f.payload, *p);
                    frames += 1;
                }
                Err(e) => assert_eq!(e, rs232::Rs232Error::Garbage(2)),
            }
        }
        // Garbage between frames is decoded (as an error) without allocating too.
        let _ = decoder.feed(&[0xAA, 0x55]).count();
    }
    let after = CountingAllocator::allocations_on_this_thread();
    assert_eq!(frames, 20_000);
    assert_eq!(after - before, 0, "allocations during 20000 encode/decode rounds");
}
