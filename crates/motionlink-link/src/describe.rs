//! The one decoder signature of every family: captured traffic in, annotated telegrams out. `motionlink
//! decode`, the live wire trace (`-v`), the capture writer and the web console's traffic log all call a
//! family's [`Describe`] the same way.
//!
//! A describer keeps state between calls: a telegram may arrive in pieces, and a reply is explained with
//! the request before it.

use std::fmt;

use crate::can::CanFrame;
use crate::clock::Timestamp;

/// Which way a telegram went.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Direction {
    /// From the host to the device (a request).
    ToDevice,
    /// From the device to the host (an answer, or a message of its own).
    FromDevice,
    /// Not known (a capture without direction marks); the describer decides from the bytes.
    Unknown,
}

impl Direction {
    /// `->`, `<-` or `??`, as `motionlink decode` prints it.
    pub fn arrow(self) -> &'static str {
        match self {
            Direction::ToDevice => "->",
            Direction::FromDevice => "<-",
            Direction::Unknown => "??",
        }
    }

    /// `to_device`, `from_device`, `unknown`, for JSON.
    pub fn name(self) -> &'static str {
        match self {
            Direction::ToDevice => "to_device",
            Direction::FromDevice => "from_device",
            Direction::Unknown => "unknown",
        }
    }
}

impl fmt::Display for Direction {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.arrow())
    }
}

/// One piece of captured traffic.
#[derive(Debug, Clone, Copy)]
pub enum Captured<'a> {
    /// Bytes of a serial line, in any chunks.
    Bytes(&'a [u8]),
    /// One CAN frame.
    Frame(&'a CanFrame),
}

/// One telegram (or a stretch of bytes that is none), explained.
#[derive(Debug, Clone, PartialEq)]
pub struct Annotation {
    /// When it was captured, if known.
    pub at: Option<Timestamp>,
    /// Which way it went (decided from the bytes when the capture did not say).
    pub direction: Direction,
    /// The CAN identifier, for a frame.
    pub can_id: Option<u32>,
    /// Its bytes (a frame's data).
    pub bytes: Vec<u8>,
    /// What it means, or what is wrong with it.
    pub meaning: String,
    /// True when it is not a valid telegram (garbage, a bad checksum, a truncated frame).
    pub bad: bool,
}

/// A family's decoder of captured traffic.
pub trait Describe {
    /// Explains `captured`, which went `direction` at `at` (if known), appending one annotation per
    /// telegram completed (none while a telegram is still incomplete).
    fn describe(
        &mut self,
        captured: Captured<'_>,
        direction: Direction,
        at: Option<Timestamp>,
        out: &mut Vec<Annotation>,
    );

    /// The capture ended: reports what is left incomplete.
    fn finish(&mut self, out: &mut Vec<Annotation>);
}
