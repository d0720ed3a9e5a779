//! [`Link`] and [`CanLink`] wrappers that record every byte or frame sent and received with its time, for the
//! demo and for tests that check what went over the line.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use crate::can::{CanFrame, CanLink};
use crate::clock::{lock, SharedClock, Timestamp};
use crate::link::{Link, LinkError};

/// Which way a recorded chunk went.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Way {
    /// Host to device.
    Sent,
    /// Device to host.
    Received,
}

/// One recorded chunk.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Record {
    /// When it was sent or received.
    pub at: Timestamp,
    /// Which way.
    pub way: Way,
    /// The bytes.
    pub bytes: Vec<u8>,
}

/// The shared log a [`TapLink`] writes to.
#[derive(Debug, Clone, Default)]
pub struct Transcript(Arc<Mutex<Vec<Record>>>);

impl Transcript {
    /// An empty transcript.
    pub fn new() -> Self {
        Self::default()
    }

    /// Takes every record so far, leaving the transcript empty.
    pub fn take(&self) -> Vec<Record> {
        std::mem::take(&mut *lock(&self.0))
    }

    /// A copy of every record so far.
    pub fn records(&self) -> Vec<Record> {
        lock(&self.0).clone()
    }

    /// All bytes that went one way, concatenated.
    pub fn bytes(&self, way: Way) -> Vec<u8> {
        lock(&self.0).iter().filter(|r| r.way == way).flat_map(|r| r.bytes.iter().copied()).collect()
    }

    fn push(&self, at: Timestamp, way: Way, bytes: &[u8]) {
        let mut log = lock(&self.0);
        // Consecutive chunks the same way are one stream; merge them so a telegram is one record.
        match log.last_mut() {
            Some(last) if last.way == way && way == Way::Received => last.bytes.extend_from_slice(bytes),
            _ => log.push(Record { at, way, bytes: bytes.to_vec() }),
        }
    }
}

/// Records what passes through the wrapped link into a [`Transcript`].
pub struct TapLink<L> {
    inner: L,
    clock: SharedClock,
    transcript: Transcript,
}

impl<L: Link> TapLink<L> {
    /// Wraps `inner`; records go to `transcript`, stamped by `clock`.
    pub fn new(inner: L, clock: SharedClock, transcript: Transcript) -> Self {
        TapLink { inner, clock, transcript }
    }
}

impl<L: Link> Link for TapLink<L> {
    fn send(&mut self, bytes: &[u8]) -> Result<(), LinkError> {
        self.transcript.push(self.clock.now(), Way::Sent, bytes);
        self.inner.send(bytes)
    }

    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, LinkError> {
        let n = self.inner.recv(buf, timeout)?;
        if n > 0 {
            self.transcript.push(self.clock.now(), Way::Received, &buf[..n]);
        }
        Ok(n)
    }

    fn discard_input(&mut self) -> Result<(), LinkError> {
        self.inner.discard_input()
    }

    fn describe(&self) -> String {
        self.inner.describe()
    }
}

/// One recorded CAN frame.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FrameRecord {
    /// When it was sent or received.
    pub at: Timestamp,
    /// Which way.
    pub way: Way,
    /// The frame.
    pub frame: CanFrame,
}

/// The shared log a [`TapCanLink`] writes to.
#[derive(Debug, Clone, Default)]
pub struct FrameTranscript(Arc<Mutex<Vec<FrameRecord>>>);

impl FrameTranscript {
    /// An empty transcript.
    pub fn new() -> Self {
        Self::default()
    }

    /// Takes every record so far, leaving the transcript empty.
    pub fn take(&self) -> Vec<FrameRecord> {
        std::mem::take(&mut *lock(&self.0))
    }

    fn push(&self, at: Timestamp, way: Way, frame: &CanFrame) {
        lock(&self.0).push(FrameRecord { at, way, frame: *frame });
    }
}

/// Records every frame that passes through the wrapped CAN link into a [`FrameTranscript`]: what
/// [`TapLink`] is for a byte link.
pub struct TapCanLink<L> {
    inner: L,
    clock: SharedClock,
    transcript: FrameTranscript,
}

impl<L: CanLink> TapCanLink<L> {
    /// Wraps `inner`; records go to `transcript`, stamped by `clock`.
    pub fn new(inner: L, clock: SharedClock, transcript: FrameTranscript) -> Self {
        TapCanLink { inner, clock, transcript }
    }
}

impl<L: CanLink> CanLink for TapCanLink<L> {
    fn send(&mut self, frame: &CanFrame) -> Result<(), LinkError> {
        self.transcript.push(self.clock.now(), Way::Sent, frame);
        self.inner.send(frame)
    }

    fn recv(&mut self, timeout: Duration) -> Result<Option<CanFrame>, LinkError> {
        let frame = self.inner.recv(timeout)?;
        if let Some(f) = &frame {
            self.transcript.push(self.clock.now(), Way::Received, f);
        }
        Ok(frame)
    }

    fn discard_input(&mut self) -> Result<(), LinkError> {
        self.inner.discard_input()
    }

    fn describe(&self) -> String {
        self.inner.describe()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::can::{CanBus, CanBusConfig, CanEmulator};
    use crate::clock::{Clock, ManualClock};

    /// Answers every frame with the same frame on identifier + 1.
    struct Echo;
    impl CanEmulator for Echo {
        fn receive(&mut self, _now: Timestamp, frame: &CanFrame, out: &mut Vec<CanFrame>) {
            out.extend(CanFrame::new(frame.id() + 1, frame.data()));
        }
        fn advance(&mut self, _now: Timestamp, _out: &mut Vec<CanFrame>) {}
        fn next_wakeup(&self) -> Option<Timestamp> {
            None
        }
    }

    #[test]
    fn a_tapped_can_link_records_both_ways_in_order() {
        let clock = ManualClock::new_auto();
        let _me = clock.reserve_participant().enter();
        let bus = CanBus::with_emulator(Echo, clock.shared(), CanBusConfig::paced(1_000_000));
        let transcript = FrameTranscript::new();
        let mut link = TapCanLink::new(bus.connect(), clock.shared(), transcript.clone());
        let sent = CanFrame::new(0x0F1, &[0x01]).unwrap();
        link.send(&sent).unwrap();
        let got = link.recv(Duration::from_millis(10)).unwrap().unwrap();
        let records = transcript.take();
        assert_eq!(
            records.iter().map(|r| (r.way, r.frame)).collect::<Vec<_>>(),
            vec![(Way::Sent, sent), (Way::Received, got)]
        );
        assert!(records[1].at > records[0].at, "stamped when they passed");
        assert!(transcript.take().is_empty());
    }
}
