//! What passes on a link, in one vocabulary for every user of it: which way it went ([`Direction`]) and what
//! it is ([`Chunk`]: bytes of a serial line or one CAN frame). A session is handed it
//! ([`Session::handle_input`](crate::session::Session::handle_input)), a tap sees it
//! ([`TapSink`](crate::capture::TapSink)), a transcript records it and a describer explains it
//! ([`Describe`](crate::describe::Describe)).

use std::fmt;

use crate::can::CanFrame;

/// Which way traffic went.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Direction {
    /// From the host to the device (a request).
    ToDevice,
    /// From the device to the host (an answer, or a message of its own).
    FromDevice,
    /// Not known (a capture without direction marks); a describer decides from the bytes.
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

/// One piece of traffic: what arrived on a link, what a tap saw, what a capture holds.
#[derive(Debug, Clone, Copy)]
pub enum Chunk<'a> {
    /// Bytes of a serial line (any chunk: a telegram may arrive in pieces, or several in one).
    Bytes(&'a [u8]),
    /// One CAN frame.
    Frame(&'a CanFrame),
}
