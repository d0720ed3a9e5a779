//! A [`Link`] wrapper that records every byte sent and received with its time, for the demo and for tests
//! that check what went over the line.

use std::sync::{Arc, Mutex};
use std::time::Duration;

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
