//! An in-memory record of every byte (or CAN frame) sent and received with its time, for the demo and for
//! tests that check what went over the line: a [`Transcript`] is a [`TapSink`](crate::capture::TapSink) of a
//! [`TapLink`] or [`TapCanLink`].

use std::sync::{Arc, Mutex};

use crate::can::CanFrame;
use crate::chunk::{Chunk, Direction};
use crate::clock::{lock, Timestamp};

/// One recorded chunk.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Record {
    /// When it was sent or received.
    pub at: Timestamp,
    /// Which way.
    pub direction: Direction,
    /// The bytes (a frame's data).
    pub bytes: Vec<u8>,
    /// The CAN frame, for a record of a CAN link.
    pub frame: Option<crate::can::CanFrame>,
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
    pub fn bytes(&self, direction: Direction) -> Vec<u8> {
        lock(&self.0).iter().filter(|r| r.direction == direction).flat_map(|r| r.bytes.iter().copied()).collect()
    }

    fn push(&self, at: Timestamp, direction: Direction, bytes: &[u8], frame: Option<crate::can::CanFrame>) {
        let mut log = lock(&self.0);
        // Consecutive chunks the same way are one stream; merge them so a telegram is one record.
        match log.last_mut() {
            Some(last)
                if frame.is_none()
                    && last.frame.is_none()
                    && last.direction == direction
                    && direction == Direction::FromDevice =>
            {
                last.bytes.extend_from_slice(bytes)
            }
            _ => log.push(Record { at, direction, bytes: bytes.to_vec(), frame }),
        }
    }
}

pub use crate::capture::{TapCanLink, TapLink};

impl crate::capture::TapSink for Transcript {
    fn record(&self, at: Timestamp, direction: Direction, data: Chunk<'_>) {
        match data {
            Chunk::Bytes(b) => self.push(at, direction, b, None),
            Chunk::Frame(f) => self.push(at, direction, f.data(), Some(*f)),
        }
    }
}

/// One recorded CAN frame.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FrameRecord {
    /// When it was sent or received.
    pub at: Timestamp,
    /// Which way.
    pub direction: Direction,
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

    fn push(&self, at: Timestamp, direction: Direction, frame: &CanFrame) {
        lock(&self.0).push(FrameRecord { at, direction, frame: *frame });
    }
}

impl crate::capture::TapSink for FrameTranscript {
    /// Keeps CAN frames; bytes of a serial line are not frames and are left out.
    fn record(&self, at: Timestamp, direction: Direction, data: Chunk<'_>) {
        if let Chunk::Frame(f) = data {
            self.push(at, direction, f);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::can::{CanBus, CanBusConfig, CanEmulator, CanLink};
    use crate::clock::{Clock, ManualClock};
    use std::time::Duration;

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
            records.iter().map(|r| (r.direction, r.frame)).collect::<Vec<_>>(),
            vec![(Direction::ToDevice, sent), (Direction::FromDevice, got)]
        );
        assert!(records[1].at > records[0].at, "stamped when they passed");
        assert!(transcript.take().is_empty());
    }
}
