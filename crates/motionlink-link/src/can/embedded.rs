//! The `embedded-can` traits: [`CanFrame`] is an [`embedded_can::Frame`], and any driver that implements
//! [`embedded_can::nb::Can`] (a microcontroller's CAN peripheral, a USB adapter's crate, SocketCAN) is a
//! [`CanLink`] through [`EmbeddedCanLink`].
//!
//! ```
//! use embedded_can::{Frame, StandardId};
//! use motionlink_link::can::CanFrame;
//! let f = <CanFrame as Frame>::new(StandardId::new(0x0E1).unwrap(), &[0x01]).unwrap();
//! assert_eq!(f.to_string(), "0E1#01");
//! ```

use std::time::Duration;

use embedded_can::{ExtendedId, Id, StandardId};

use super::{CanFrame, CanLink};
use crate::clock::SharedClock;
use crate::link::LinkError;

impl embedded_can::Frame for CanFrame {
    fn new(id: impl Into<Id>, data: &[u8]) -> Option<Self> {
        match id.into() {
            Id::Standard(id) => CanFrame::new(u32::from(id.as_raw()), data).ok(),
            Id::Extended(id) => CanFrame::new_extended(id.as_raw(), data).ok(),
        }
    }

    fn new_remote(id: impl Into<Id>, dlc: usize) -> Option<Self> {
        let dlc = u8::try_from(dlc).ok()?;
        match id.into() {
            Id::Standard(id) => CanFrame::new_remote(u32::from(id.as_raw()), false, dlc).ok(),
            Id::Extended(id) => CanFrame::new_remote(id.as_raw(), true, dlc).ok(),
        }
    }

    fn is_extended(&self) -> bool {
        CanFrame::is_extended(self)
    }

    fn is_remote_frame(&self) -> bool {
        CanFrame::is_remote(self)
    }

    fn id(&self) -> Id {
        if CanFrame::is_extended(self) {
            Id::Extended(ExtendedId::new(CanFrame::id(self)).unwrap_or(ExtendedId::ZERO))
        } else {
            let raw = u16::try_from(CanFrame::id(self)).unwrap_or(0);
            Id::Standard(StandardId::new(raw).unwrap_or(StandardId::ZERO))
        }
    }

    fn dlc(&self) -> usize {
        usize::from(CanFrame::dlc(self))
    }

    fn data(&self) -> &[u8] {
        CanFrame::data(self)
    }
}

/// Converts any `embedded-can` frame into a [`CanFrame`].
pub fn from_embedded<F: embedded_can::Frame>(frame: &F) -> Option<CanFrame> {
    let (id, extended) = match frame.id() {
        Id::Standard(id) => (u32::from(id.as_raw()), false),
        Id::Extended(id) => (id.as_raw(), true),
    };
    if frame.is_remote_frame() {
        return CanFrame::new_remote(id, extended, u8::try_from(frame.dlc()).ok()?).ok();
    }
    if extended {
        CanFrame::new_extended(id, frame.data()).ok()
    } else {
        CanFrame::new(id, frame.data()).ok()
    }
}

/// A [`CanLink`] on any non-blocking `embedded-can` driver. A read polls the driver every `poll_interval`
/// (on the clock) until a frame comes or the timeout passes; a send waits, the same way, for room in the
/// driver's transmit queue.
pub struct EmbeddedCanLink<T: embedded_can::nb::Can> {
    can: T,
    clock: SharedClock,
    poll_interval: Duration,
    name: String,
}

impl<T: embedded_can::nb::Can> EmbeddedCanLink<T> {
    /// Wraps `can`, named `name` in messages; polls every `poll_interval` (such as 200 µs: a frame at
    /// 1 Mbit/s takes at least 47 µs).
    pub fn new(can: T, clock: SharedClock, poll_interval: Duration, name: impl Into<String>) -> Self {
        EmbeddedCanLink { can, clock, poll_interval, name: name.into() }
    }

    fn error(&self, what: &str, e: impl std::fmt::Debug) -> LinkError {
        LinkError::Io {
            port: self.name.clone(),
            source: std::sync::Arc::new(std::io::Error::other(format!("{what}: {e:?}"))),
        }
    }
}

impl<T: embedded_can::nb::Can + Send> CanLink for EmbeddedCanLink<T> {
    fn send(&mut self, frame: &CanFrame) -> Result<(), LinkError> {
        let data = <T::Frame as embedded_can::Frame>::new(embedded_can::Frame::id(frame), frame.data());
        let theirs = if frame.is_remote() {
            <T::Frame as embedded_can::Frame>::new_remote(embedded_can::Frame::id(frame), usize::from(frame.dlc()))
        } else {
            data
        };
        let theirs = theirs.ok_or_else(|| self.error("the driver cannot make this frame", frame))?;
        let give_up = self.clock.now() + Duration::from_secs(1);
        let signal = self.clock.signal();
        loop {
            match self.can.transmit(&theirs) {
                Ok(_) => return Ok(()),
                Err(nb::Error::WouldBlock) if self.clock.now() < give_up => {
                    signal.wait_until(Some(self.clock.now() + self.poll_interval));
                }
                Err(nb::Error::WouldBlock) => return Err(self.error("transmit queue full", "for 1 s")),
                Err(nb::Error::Other(e)) => return Err(self.error("transmit", e)),
            }
        }
    }

    fn recv(&mut self, timeout: Duration) -> Result<Option<CanFrame>, LinkError> {
        let deadline = self.clock.now() + timeout;
        let signal = self.clock.signal();
        loop {
            match self.can.receive() {
                Ok(f) => return Ok(from_embedded(&f)),
                Err(nb::Error::WouldBlock) => {
                    let now = self.clock.now();
                    if now >= deadline {
                        return Ok(None);
                    }
                    signal.wait_until(Some((now + self.poll_interval).min(deadline)));
                }
                Err(nb::Error::Other(e)) => return Err(self.error("receive", e)),
            }
        }
    }

    fn describe(&self) -> String {
        self.name.clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::clock::RealClock;
    use std::collections::VecDeque;

    /// A loopback "peripheral": what is sent comes back with the id plus one.
    #[derive(Default)]
    struct Loop(VecDeque<CanFrame>);

    impl embedded_can::nb::Can for Loop {
        type Frame = CanFrame;
        type Error = embedded_can::ErrorKind;
        fn transmit(&mut self, frame: &CanFrame) -> nb::Result<Option<CanFrame>, Self::Error> {
            self.0.push_back(CanFrame::new(frame.id() + 1, frame.data()).map_err(|_| embedded_can::ErrorKind::Other)?);
            Ok(None)
        }
        fn receive(&mut self) -> nb::Result<CanFrame, Self::Error> {
            self.0.pop_front().ok_or(nb::Error::WouldBlock)
        }
    }

    #[test]
    fn a_driver_of_the_traits_is_a_can_link() {
        let mut link = EmbeddedCanLink::new(Loop::default(), RealClock::shared(), Duration::from_micros(100), "loop");
        link.send(&CanFrame::new(0x0E1, &[0x0A]).unwrap()).unwrap();
        assert_eq!(link.recv(Duration::from_millis(10)).unwrap(), Some(CanFrame::new(0x0E2, &[0x0A]).unwrap()));
        assert_eq!(link.recv(Duration::from_millis(2)).unwrap(), None);
    }

    #[test]
    fn frames_convert_both_ways() {
        for f in [
            CanFrame::new(0x7FF, &[1, 2, 3]).unwrap(),
            CanFrame::new_extended(0x1234_5678, &[]).unwrap(),
            CanFrame::new_remote(0x0D1, false, 2).unwrap(),
        ] {
            assert_eq!(from_embedded(&f), Some(f));
        }
    }
}
