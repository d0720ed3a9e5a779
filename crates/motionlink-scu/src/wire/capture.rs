//! Captures: both directions in one stream.

use super::reply_decoder::{parse_reply, scan_reply};
use super::request_decoder::{parse_request, scan_request, unknown_command_reply, Scan};
use super::*;

/// A telegram found in a capture.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Telegram<'a> {
    /// Host to unit.
    Request(Incoming<'a>),
    /// Unit to host.
    Reply(Reply<'a>),
    /// Unit to host: the error reply (ICE) to a command it does not know, which repeats the unknown letters.
    UnknownCommandReply {
        /// The letters of the unknown command.
        code: [u8; 2],
        /// The error status (ICE).
        status: Status,
    },
}

/// What [`capture_step`] found at the start of its input.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum CaptureItem<'a> {
    /// A telegram with a valid CRC.
    Telegram(Telegram<'a>),
    /// Bytes that belong to no telegram, or a telegram with a wrong CRC.
    Error(WireError),
    /// The input ends inside a telegram.
    Truncated,
}

/// Which way the bytes of a capture went, if known.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CaptureDirection {
    /// Host to unit: requests.
    FromHost,
    /// Unit to host: replies.
    FromUnit,
    /// Both directions mixed in one stream.
    Unknown,
}

/// Finds the telegram at the start of `bytes` in a capture and returns its length and what it is.
///
/// In a capture that mixes both directions ([`CaptureDirection::Unknown`]) a request and a reply can start
/// alike: the reading with a valid CRC wins, and when both are valid (an RO ACK is byte for byte an RO with
/// Safety_ID 6, which no unit accepts) the reply does.
///
/// ```
/// use motionlink_scu::wire::{capture_step, CaptureDirection, CaptureItem, Telegram};
/// let capture = [0x52, 0x4F, 0x00, 0x5C, 0x2D, 0x52, 0x4F, 0x06, 0x9A, 0x4D]; // RO 00, then its ACK
/// let (n, first) = capture_step(&capture, CaptureDirection::Unknown);
/// assert!(matches!(first, CaptureItem::Telegram(Telegram::Request(_))));
/// let (_, second) = capture_step(&capture[n..], CaptureDirection::Unknown);
/// assert!(matches!(second, CaptureItem::Telegram(Telegram::Reply(_))));
/// ```
pub fn capture_step(bytes: &[u8], direction: CaptureDirection) -> (usize, CaptureItem<'_>) {
    if bytes.is_empty() {
        return (0, CaptureItem::Truncated);
    }
    if direction != CaptureDirection::FromHost {
        if let Some(t) = unknown_command_reply(bytes) {
            return (5, CaptureItem::Telegram(t));
        }
    }
    let as_request = if direction == CaptureDirection::FromUnit { Scan::Garbage(1) } else { scan_request(bytes) };
    let as_reply = if direction == CaptureDirection::FromHost { Scan::Garbage(1) } else { scan_reply(bytes, None) };
    let reply = |n: usize| (n, CaptureItem::Telegram(Telegram::Reply(parse_reply(&bytes[..n]))));
    match (&as_request, &as_reply) {
        (_, Scan::Complete(n)) => reply(*n),
        (Scan::Complete(n), _) => (*n, CaptureItem::Telegram(Telegram::Request(parse_request(&bytes[..*n])))),
        (Scan::NeedMore, _) | (_, Scan::NeedMore) => (bytes.len(), CaptureItem::Truncated),
        (Scan::BadCrc { command, received, computed }, _) | (_, Scan::BadCrc { command, received, computed }) => {
            (1, CaptureItem::Error(WireError::Checksum { command: *command, received: *received, computed: *computed }))
        }
        (Scan::BadLength(e), _) | (_, Scan::BadLength(e)) => (1, CaptureItem::Error(*e)),
        (Scan::Garbage(a), Scan::Garbage(b)) => {
            let n = (*a).min(*b).max(1);
            (n, CaptureItem::Error(WireError::Garbage { count: n }))
        }
    }
}
