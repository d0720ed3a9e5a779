//! Building a request and parsing a reply allocate nothing: proven with a counting global allocator (counting
//! the test's own thread only: the test harness allocates on its thread while the test starts).

use motionlink_compax::model::{Command, CommandStyle, CommandText, Position, StatusId, StatusValue};
use motionlink_compax::wire::{Address, Body, Flags, Frame, Mode, ReplyDecoder, ReplyEvent, ReplyEventRef, Request};
use motionlink_testkit::alloc_count::CountingAllocator;

#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator::new();

#[test]
fn request_build_and_reply_parse_do_not_allocate() {
    let mode = Mode::from_p196(8 + 64).unwrap();
    let mut decoder = ReplyDecoder::new(&mode);
    let reply: &[u8] = b"17S001: -360.125\r\n>";
    let mut wire = reply.to_vec();
    wire.push(motionlink_compax::wire::bcc(b"17S001: -360.125"));
    let address = Address::drive(17).unwrap();
    let mut text = CommandText::new();
    let mut frame = Frame::default();
    let before = CountingAllocator::allocations_on_this_thread();
    let mut sum = 0.0;
    for i in 0..10_000u32 {
        let cmd = if i % 2 == 0 {
            Command::ReadStatus(StatusId::ACTUAL_POSITION)
        } else {
            Command::PosA(Position::new(f64::from(i) * 0.5).unwrap())
        };
        // By value, byte by byte.
        let text_owned = cmd.to_ascii(CommandStyle::Long).unwrap();
        let frame_owned =
            Request { address, body: Body::Command(text_owned.as_bytes()), flags: Flags::NONE }.encode(&mode).unwrap();
        sum += frame_owned.len() as f64;
        decoder.expect_from(Some(17));
        for &b in &wire {
            if let Some(ReplyEvent::Reply(r)) = decoder.push(b) {
                if let StatusValue::Position(p) = StatusValue::parse(StatusId::ACTUAL_POSITION, r.text()).unwrap() {
                    sum += p.units();
                }
            }
        }
        // In place, a slice at a time.
        cmd.write_ascii_into(CommandStyle::Long, &mut text).unwrap();
        Request { address, body: Body::Command(text.as_bytes()), flags: Flags::NONE }
            .encode_into(&mode, &mut frame)
            .unwrap();
        sum += frame.len() as f64;
        let mut rest = &wire[..];
        while !rest.is_empty() {
            let (used, event) = decoder.decode(rest);
            rest = &rest[used..];
            if let Some(ReplyEventRef::Reply(r)) = event {
                if let StatusValue::Position(p) = StatusValue::parse(StatusId::ACTUAL_POSITION, r.text()).unwrap() {
                    sum += p.units();
                }
            }
        }
    }
    let after = CountingAllocator::allocations_on_this_thread();
    assert_eq!(after - before, 0, "allocations during 10000 build + parse rounds");
    assert!(sum != 0.0);
    // The counter does count this thread's allocations.
    drop(std::hint::black_box(Box::new(sum)));
    assert_eq!(CountingAllocator::allocations_on_this_thread() - after, 1);
}
