//! Any embedded-can driver carries a PowerCube session: a "peripheral" of the `embedded_can::nb::Can`
//! trait, with a frame type of its own, wrapped in `EmbeddedCanLink`, runs a scan, a checked move and the
//! close, as the in-memory bus and SocketCAN do.

use motionlink_powercube::PortLink;
use std::collections::VecDeque;
use std::time::Duration;

use embedded_can::{ErrorKind, Frame, Id, StandardId};
use motionlink_link::can::embedded::{from_embedded, EmbeddedCanLink};
use motionlink_link::can::CanEmulator;
use motionlink_link::{RealClock, SharedClock};
use motionlink_powercube::client::{Client, Config, MoveSpec};
use motionlink_powercube::model::{Address, Position, StateFlag, Velocity};
use motionlink_powercube::sim::SimConfig;
use motionlink_powercube::Emulator;

/// A frame type that is not motionlink's: what a microcontroller HAL's driver would have.
#[derive(Debug, Clone)]
struct HalFrame {
    id: StandardId,
    data: Vec<u8>,
}

impl Frame for HalFrame {
    fn new(id: impl Into<Id>, data: &[u8]) -> Option<Self> {
        match id.into() {
            Id::Standard(id) if data.len() <= 8 => Some(HalFrame { id, data: data.to_vec() }),
            _ => None,
        }
    }
    fn new_remote(_id: impl Into<Id>, _dlc: usize) -> Option<Self> {
        None
    }
    fn is_extended(&self) -> bool {
        false
    }
    fn is_remote_frame(&self) -> bool {
        false
    }
    fn id(&self) -> Id {
        Id::Standard(self.id)
    }
    fn dlc(&self) -> usize {
        self.data.len()
    }
    fn data(&self) -> &[u8] {
        &self.data
    }
}

/// A CAN peripheral whose bus has emulated modules on it.
struct Peripheral {
    bus: Emulator,
    clock: SharedClock,
    rx: VecDeque<HalFrame>,
}

impl embedded_can::nb::Can for Peripheral {
    type Frame = HalFrame;
    type Error = ErrorKind;

    fn transmit(&mut self, frame: &HalFrame) -> nb::Result<Option<HalFrame>, ErrorKind> {
        let ours = from_embedded(frame).ok_or(nb::Error::Other(ErrorKind::Other))?;
        let mut answers = Vec::new();
        CanEmulator::receive(&mut self.bus, self.clock.now(), &ours, &mut answers);
        for a in answers {
            let theirs = StandardId::new(a.id() as u16).and_then(|id| HalFrame::new(id, a.data()));
            self.rx.push_back(theirs.ok_or(nb::Error::Other(ErrorKind::Other))?);
        }
        Ok(None)
    }

    fn receive(&mut self) -> nb::Result<HalFrame, ErrorKind> {
        self.rx.pop_front().ok_or(nb::Error::WouldBlock)
    }
}

#[test]
fn a_session_runs_over_any_embedded_can_driver() {
    let clock = RealClock::shared();
    let bus = Emulator::new_can(&SimConfig::with_addresses(&[3, 7]).unwrap());
    let peripheral = Peripheral { bus, clock: clock.clone(), rx: VecDeque::new() };
    let link = EmbeddedCanLink::new(peripheral, clock.clone(), Duration::from_micros(100), "hal can0");
    let client = Client::with_link(PortLink::Can(Box::new(link)), clock, Config::can()).unwrap();
    let found: Vec<u8> = client.scan().unwrap().iter().map(|e| e.address.get()).collect();
    assert_eq!(found, vec![3, 7]);
    let seven = Address::new(7).unwrap();
    // No watchdog here: this test is about the embedded-can adapter, on the real clock; a watchdog armed on
    // it would make the test fail on a host too loaded to refresh it every 50 ms (the refresh and its
    // expiry are tested on the manual clock in the crate's session and client tests).
    let spec = MoveSpec { vel: Some(Velocity::rad_per_s(1.0)), ..MoveSpec::to(Position::rad(0.15)) };
    let report = client.module(seven).move_to(&spec, &mut |_| {}).unwrap();
    assert!((report.reached.value() - 0.15).abs() <= 0.001 && report.state.contains(StateFlag::RampEnd));
    client.close().unwrap();
}
