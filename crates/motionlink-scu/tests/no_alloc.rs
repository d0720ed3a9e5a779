//! The codec builds and parses telegrams without touching the heap. A counting global allocator proves it.

use motionlink_scu::wire::*;
use motionlink_testkit::alloc_count::CountingAllocator;

#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator::new();

#[test]
fn encoding_and_decoding_allocate_nothing() {
    // Everything is set up before counting starts.
    let mut req_dec = RequestDecoder::new();
    let mut rep_dec = ReplyDecoder::new();
    let mut buf = [0u8; 64];
    let write = [0x11u8; 24];
    let read = [0x22u8; 24];
    let position = 400i32.to_le_bytes();
    let mut checksum = 0usize;

    let before = CountingAllocator::allocations_on_this_thread();
    for i in 0..10_000u32 {
        let (request, reply, shape) = if i % 2 == 0 {
            (Request::Get { index: 0x0011 }, Reply::with_data(Command::Get, &position), ReplyShape::WithData)
        } else {
            (
                Request::Cyclic { object: 0, write: &write },
                Reply::with_data(Command::Cyclic, &read),
                ReplyShape::WithData,
            )
        };
        let n = encode_request(&request, &mut buf).unwrap();
        // Split delivery exercises the buffered path as well as the in-place one.
        let split = (i as usize) % n;
        let (used, ev) = req_dec.decode(&buf[..split]);
        assert!(ev.is_none() && used == split);
        let (_, ev) = req_dec.decode(&buf[split..n]);
        checksum += usize::from(matches!(ev, Some(Ok(Incoming::Request(r))) if r == request));
        let m = encode_reply(&reply, &mut buf).unwrap();
        rep_dec.expect(request.command(), shape);
        let (_, ev) = rep_dec.decode(&buf[..m]);
        checksum += usize::from(matches!(ev, Some(Ok(r)) if r == reply));
    }
    let allocated = CountingAllocator::allocations_on_this_thread() - before;
    assert_eq!(checksum, 20_000, "every telegram round-tripped");
    assert_eq!(allocated, 0, "heap allocations while encoding and decoding");
}
