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
    assert_eq!(can.recv(Duration::from_millis(10)).unwrap(), None);
    assert_eq!(can.refused(), 1);
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
