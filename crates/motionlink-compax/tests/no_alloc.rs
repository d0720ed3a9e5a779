//! Building a request and parsing a reply allocate nothing: proven with a counting global allocator.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

use motionlink_compax::model::{Command, CommandStyle, Position, StatusId, StatusValue};
use motionlink_compax::wire::{Address, Body, Flags, Mode, ReplyDecoder, ReplyEvent, Request};

struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::SeqCst);
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn request_build_and_reply_parse_do_not_allocate() {
    let mode = Mode::from_p196(8 + 64).unwrap();
    let mut decoder = ReplyDecoder::new(&mode);
    let reply: &[u8] = b"17S001: -360.125\r\n>";
    let mut wire = reply.to_vec();
    wire.push(motionlink_compax::wire::bcc(b"17S001: -360.125"));
    let address = Address::drive(17).unwrap();
    let before = ALLOCATIONS.load(Ordering::SeqCst);
    let mut sum = 0.0;
    for i in 0..10_000u32 {
        let cmd = if i % 2 == 0 {
            Command::ReadStatus(StatusId::ACTUAL_POSITION)
        } else {
            Command::PosA(Position::new(f64::from(i) * 0.5).unwrap())
        };
        let text = cmd.to_ascii(CommandStyle::Long).unwrap();
        let frame =
            Request { address, body: Body::Command(text.as_bytes()), flags: Flags::NONE }.encode(&mode).unwrap();
        sum += frame.len() as f64;
        decoder.expect_from(Some(17));
        for &b in &wire {
            if let Some(ReplyEvent::Reply(r)) = decoder.push(b) {
                if let StatusValue::Position(p) = StatusValue::parse(StatusId::ACTUAL_POSITION, r.text()).unwrap() {
                    sum += p.units();
                }
            }
        }
    }
    let after = ALLOCATIONS.load(Ordering::SeqCst);
    assert_eq!(after - before, 0, "allocations during 10000 build + parse rounds");
    assert!(sum != 0.0);
}
