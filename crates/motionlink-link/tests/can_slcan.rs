//! SLCAN end to end: a CAN emulator behind an emulated serial adapter, reached through `SlcanLink`, in
//! process (manual clock) and over a real pseudo-terminal.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use motionlink_link::can::{CanEmulator, CanFrame, CanLink, SlcanAdapter, SlcanBitrate, SlcanLink};
use motionlink_link::clock::{Clock, ManualClock, RealClock, Timestamp};
use motionlink_link::pipe::{EmulatorHost, PipeConfig};

/// Answers id X with id X + 0x10 and the data reversed.
struct Mirror;

impl CanEmulator for Mirror {
    fn receive(&mut self, _now: Timestamp, frame: &CanFrame, out: &mut Vec<CanFrame>) {
        let mut data = frame.data().to_vec();
        data.reverse();
        let id = frame.id() + 0x10;
        out.push(
            if frame.is_extended() { CanFrame::new_extended(id, &data) } else { CanFrame::new(id, &data) }.unwrap(),
        );
    }
    fn advance(&mut self, _now: Timestamp, _out: &mut Vec<CanFrame>) {}
    fn next_wakeup(&self) -> Option<Timestamp> {
        None
    }
}

#[test]
fn slcan_link_through_an_emulated_adapter_in_process() {
    let clock = ManualClock::new_auto();
    let _me = clock.reserve_participant().enter();
    let host = EmulatorHost::new(SlcanAdapter::new(Mirror), clock.shared(), PipeConfig::paced(115_200));
    let (link, _) = host.connect();
    let mut can = SlcanLink::open(link, clock.shared(), SlcanBitrate::K500).unwrap();
    assert!(host.with_device(|a| a.is_open() && a.bitrate() == Some(SlcanBitrate::K500)));
    for i in 0..20u32 {
        can.send(&CanFrame::new(0x0D1, &[1, 2, i as u8]).unwrap()).unwrap();
        let got = can.recv(Duration::from_millis(100)).unwrap().unwrap();
        assert_eq!((got.id(), got.data()), (0x0E1, &[i as u8, 2, 1][..]));
    }
    assert_eq!(can.recv(Duration::from_millis(10)).unwrap(), None);
    assert_eq!(can.refused(), 0);
}

#[test]
fn an_adapter_with_its_channel_closed_rings_the_bell() {
    let clock = ManualClock::new_auto();
    let _me = clock.reserve_participant().enter();
    let host = EmulatorHost::new(SlcanAdapter::new(Mirror), clock.shared(), PipeConfig::instant());
    let (link, _) = host.connect();
    let mut can = SlcanLink::wrap(link, clock.shared());
    can.send(&CanFrame::new(0x10, &[]).unwrap()).unwrap();
    // The refusal is an error of the exchange, not a silence that looks like a device that does not answer.
    let t0 = clock.now();
    let err = can.recv(Duration::from_millis(100)).unwrap_err();
    assert!(err.to_string().contains("refused to send 010#"), "{err}");
    assert!(!err.is_disconnect());
    assert!(clock.now() - t0 < Duration::from_millis(100), "reported at once, not after the timeout");
    assert_eq!(can.refused(), 1);
    // Reported once; the link goes on.
    assert_eq!(can.recv(Duration::from_millis(10)).unwrap(), None);
}

#[test]
fn a_refused_frame_is_an_error_of_the_exchange_and_the_others_are_matched_in_order() {
    let clock = ManualClock::new_auto();
    let _me = clock.reserve_participant().enter();
    let host = EmulatorHost::new(SlcanAdapter::new(Mirror), clock.shared(), PipeConfig::paced(115_200));
    let (link, _) = host.connect();
    let mut can = SlcanLink::open(link, clock.shared(), SlcanBitrate::M1).unwrap();
    let frames = [1u8, 2, 3].map(|i| CanFrame::new(0x0D0 + u32::from(i), &[i]).unwrap());
    can.send(&frames[0]).unwrap();
    assert_eq!(can.recv(Duration::from_millis(20)).unwrap().map(|f| f.id()), Some(0x0E1));
    // A full transmit queue: the first of the next three frames is refused, the others go out. The answers
    // come in the order the frames were sent, so the bell is the second frame's.
    host.with_device(|a| a.refuse_next(1));
    for f in [&frames[1], &frames[2], &frames[0]] {
        can.send(f).unwrap();
    }
    let t0 = clock.now();
    let mut events = Vec::new();
    let mut error_after = None;
    loop {
        match can.recv(Duration::from_millis(100)) {
            Ok(Some(f)) => events.push(format!("{:03X}", f.id())),
            Ok(None) => break,
            Err(e) => {
                error_after.get_or_insert(clock.now() - t0);
                events.push(e.to_string());
            }
        }
    }
    // The frames that went out are answered as usual; the refusal is reported where the bell came, naming
    // the frame refused.
    assert_eq!(events.len(), 3, "{events:?}");
    let err = events.iter().position(|e| e.contains("refused")).expect("the refusal is reported");
    assert!(events[err].contains("refused to send 0D2#02"), "{events:?}");
    assert_eq!(err, 0, "the bell comes before the other answers: {events:?}");
    events.remove(err);
    assert_eq!(events, vec!["0E3", "0E1"]);
    let error_after = error_after.unwrap();
    assert!(error_after < Duration::from_millis(10), "at once, not after a timeout: {error_after:?}");
    assert_eq!(can.refused(), 1);
    // And later frames are accepted again.
    can.send(&frames[1]).unwrap();
    assert_eq!(can.recv(Duration::from_millis(20)).unwrap().map(|f| f.id()), Some(0x0E2));
}

#[test]
fn something_that_is_not_an_adapter_fails_to_open() {
    let clock = ManualClock::new_auto();
    let _me = clock.reserve_participant().enter();
    let (host_end, _device_end, _) = motionlink_link::pipe::pipe(clock.shared(), PipeConfig::instant());
    let err = SlcanLink::open(host_end, clock.shared(), SlcanBitrate::M1).err().expect("silence is an error");
    assert!(err.to_string().contains("did not answer"), "{err}");
}

#[cfg(unix)]
#[test]
fn slcan_over_a_real_pty() {
    let server =
        motionlink_link::emulator::serve_pty(Arc::new(Mutex::new(SlcanAdapter::new(Mirror))), RealClock::shared())
            .unwrap();
    let clock = RealClock::shared();
    let serial = motionlink_link::serial::SerialLink::open(
        server.address(),
        motionlink_link::SerialSettings { dtr_rts_on: false, ..motionlink_link::SerialSettings::new(115_200) },
    )
    .unwrap();
    let mut can = SlcanLink::open(serial, Arc::clone(&clock), SlcanBitrate::M1).unwrap();
    let ext = CanFrame::new_extended(0x1234, &[9, 8]).unwrap();
    can.send(&ext).unwrap();
    let got = can.recv(Duration::from_secs(2)).unwrap().unwrap();
    assert_eq!((got.id(), got.is_extended(), got.data()), (0x1244, true, &[8, 9][..]));
    let t0 = clock.now();
    assert_eq!(can.recv(Duration::from_millis(50)).unwrap(), None);
    assert!(clock.now() - t0 >= Duration::from_millis(50));
}
