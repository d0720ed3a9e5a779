//! Request decoding (the unit's side), and the framing both decoders share.

use std::fmt;

use super::crc::{crc16, crc16_update};
use super::*;

/// `R?` with an unknown letter, an error status and a matching CRC: the unit's answer to an unknown command.
pub(super) fn unknown_command_reply(b: &[u8]) -> Option<Telegram<'_>> {
    let t = b.get(..5)?;
    if t[0] != b'R' || Command::from_code(t[0], t[1]).is_some() {
        return None;
    }
    let status = Status::from_code(t[2]).filter(|s| *s != Status::Ack)?;
    check_crc(t).ok()?;
    Some(Telegram::UnknownCommandReply { code: [t[0], t[1]], status })
}

/// A decoded request, or an unknown command that arrived intact.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Incoming<'a> {
    /// A request of a known command.
    Request(Request<'a>),
    /// A telegram of an unknown command `R?` whose CRC is right: the unit answers ICE.
    UnknownCommand {
        /// The command letters.
        code: [u8; 2],
    },
}

/// An event of the request decoder.
pub type RequestEvent<'a> = Result<Incoming<'a>, WireError>;

/// Incremental decoder of requests: feed it any chunk of bytes, get telegrams out.
///
/// Resynchronisation: bytes that cannot start a telegram (anything but `R` followed by an upper-case letter)
/// are skipped and reported as [`WireError::Garbage`]. A known command's length follows from its fixed fields
/// or its ctp; a CRC mismatch is reported with the command ([`WireError::Checksum`], answered with CSE) and
/// scanning resumes one byte after the bad telegram's start. A telegram with an unknown command ends where its
/// CRC matches, within [`MAX_UNKNOWN_LEN`] bytes; failing that, its first byte is garbage.
///
/// The decoder does not know time: the unit calls [`RequestDecoder::reset`] when the line was silent too long
/// inside a telegram (1000 ms).
///
/// ```
/// use motionlink_scu::wire::{Incoming, Request, RequestDecoder};
/// let mut dec = RequestDecoder::new();
/// let bytes = [b'x', b'R', b'A', 0x38, 0x30]; // garbage, then RA (CRC 0x3038)
/// let (n, ev) = dec.decode(&bytes);
/// assert!(ev.unwrap().is_err()); // the 'x'
/// let (_, ev) = dec.decode(&bytes[n..]);
/// assert_eq!(ev, Some(Ok(Incoming::Request(Request::Abort))));
/// ```
#[derive(Clone)]
pub struct RequestDecoder {
    framer: Framer<REQUEST_BUF_LEN>,
}

impl fmt::Debug for RequestDecoder {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("RequestDecoder").field("buffered", &self.framer.buffered()).finish()
    }
}

impl Default for RequestDecoder {
    fn default() -> Self {
        Self::new()
    }
}

/// The receive buffer both decoders frame telegrams in: bytes of a telegram that has not come whole yet.
#[derive(Clone)]
pub(super) struct Framer<const N: usize> {
    buf: [u8; N],
    len: usize,
    /// Bytes at the front of `buf` already emitted as part of an event; dropped on the next call.
    consumed_front: usize,
}

impl<const N: usize> Framer<N> {
    pub(super) const fn new() -> Self {
        Framer { buf: [0; N], len: 0, consumed_front: 0 }
    }

    pub(super) fn reset(&mut self) {
        self.len = 0;
        self.consumed_front = 0;
    }

    pub(super) fn buffered(&self) -> &[u8] {
        &self.buf[self.consumed_front..self.len]
    }

    pub(super) fn compact(&mut self) {
        if self.consumed_front > 0 {
            self.buf.copy_within(self.consumed_front..self.len, 0);
            self.len -= self.consumed_front;
            self.consumed_front = 0;
        }
    }

    /// Takes bytes from `input` and returns how many it used and at most one complete telegram (or error), as
    /// `scan` delimits them. A telegram that lies whole in `input` while nothing is buffered is returned in
    /// place, without copying.
    pub(super) fn next<'a>(
        &'a mut self,
        input: &'a [u8],
        scan: impl Fn(&[u8]) -> Scan,
    ) -> (usize, Option<Result<&'a [u8], WireError>>) {
        self.compact();
        if self.len == 0 && !input.is_empty() {
            match scan(input) {
                Scan::NeedMore => {}
                Scan::Complete(n) => return (n, Some(Ok(&input[..n]))),
                other => {
                    let (n, e) = scan_error(other);
                    return (n, Some(Err(e)));
                }
            }
        }
        let mut used = 0;
        loop {
            match scan(&self.buf[..self.len]) {
                Scan::NeedMore => {
                    let take = (N - self.len).min(input.len() - used);
                    if take == 0 {
                        return (used, None);
                    }
                    self.buf[self.len..self.len + take].copy_from_slice(&input[used..used + take]);
                    self.len += take;
                    used += take;
                }
                Scan::Complete(n) => {
                    self.consumed_front = n;
                    return (used, Some(Ok(&self.buf[..n])));
                }
                other => {
                    let (n, e) = scan_error(other);
                    self.consumed_front = n;
                    return (used, Some(Err(e)));
                }
            }
        }
    }
}

/// What the bytes at the start of a buffer are.
pub(super) enum Scan {
    /// Not enough bytes yet to know.
    NeedMore,
    /// A complete telegram of this many bytes.
    Complete(usize),
    /// The first `n` bytes are garbage.
    Garbage(usize),
    /// A telegram with a wrong CRC, `len` bytes long.
    BadCrc { command: Option<Command>, received: u16, computed: u16 },
    /// A telegram whose length field is impossible.
    BadLength(WireError),
}

pub(super) fn check_crc(frame: &[u8]) -> Result<(), (u16, u16)> {
    let n = frame.len();
    let received = u16::from_le_bytes([frame[n - 2], frame[n - 1]]);
    let computed = crc16(&frame[..n - 2]);
    if received == computed {
        Ok(())
    } else {
        Err((received, computed))
    }
}

/// The bytes to skip and the error for a scan that found no telegram.
pub(super) fn scan_error(scan: Scan) -> (usize, WireError) {
    match scan {
        Scan::Garbage(n) => (n, WireError::Garbage { count: n }),
        Scan::BadCrc { command, received, computed } => (1, WireError::Checksum { command, received, computed }),
        Scan::BadLength(e) => (1, e),
        // Not errors; never passed here.
        Scan::NeedMore | Scan::Complete(_) => (1, WireError::Garbage { count: 1 }),
    }
}

pub(super) fn known_or_crc(frame: &[u8], command: Option<Command>) -> Scan {
    match check_crc(frame) {
        Ok(()) => Scan::Complete(frame.len()),
        Err((received, computed)) => Scan::BadCrc { command, received, computed },
    }
}

pub(super) fn scan_request(b: &[u8]) -> Scan {
    let Some(&x) = b.first() else { return Scan::NeedMore };
    if x != b'R' {
        let n = b.iter().position(|&c| c == b'R').unwrap_or(b.len());
        return Scan::Garbage(n);
    }
    let Some(&y) = b.get(1) else { return Scan::NeedMore };
    let Some(command) = Command::from_code(x, y) else {
        if !y.is_ascii_uppercase() {
            return Scan::Garbage(1);
        }
        // An unknown command: it ends where its CRC matches.
        let mut crc = crc16_update(0, &b[..2]);
        for end in 4..=b.len().min(MAX_UNKNOWN_LEN) {
            // crc holds the CRC of b[..end - 2].
            if u16::from_le_bytes([b[end - 2], b[end - 1]]) == crc {
                return Scan::Complete(end);
            }
            crc = crc16_update(crc, &b[end - 2..end - 1]);
        }
        return if b.len() >= MAX_UNKNOWN_LEN { Scan::Garbage(1) } else { Scan::NeedMore };
    };
    let fixed = match command {
        Command::Open => Some(5),
        Command::Abort => Some(4),
        Command::Get => Some(6),
        Command::Execute => Some(7),
        Command::Stop => Some(6),
        Command::Cyclic | Command::Transfer => None,
    };
    let len = match fixed {
        Some(n) => n,
        None => {
            if b.len() < 4 {
                return Scan::NeedMore;
            }
            let ctp = u16::from_le_bytes([b[2], b[3]]);
            let min = if command == Command::Cyclic { 1 } else { 2 };
            if usize::from(ctp) > MAX_REQUEST_DATA {
                return Scan::BadLength(WireError::Oversized { command, ctp, max: MAX_REQUEST_DATA });
            }
            if ctp < min {
                return Scan::BadLength(WireError::Undersized { command, ctp });
            }
            4 + usize::from(ctp) + 2
        }
    };
    if b.len() < len {
        return Scan::NeedMore;
    }
    known_or_crc(&b[..len], Some(command))
}

pub(super) fn parse_request(frame: &[u8]) -> Incoming<'_> {
    let body = &frame[..frame.len() - 2];
    let Some(command) = Command::from_code(body[0], body[1]) else {
        return Incoming::UnknownCommand { code: [body[0], body[1]] };
    };
    Incoming::Request(match command {
        Command::Open => Request::Open { safety_id: body[2] },
        Command::Abort => Request::Abort,
        Command::Get => Request::Get { index: u16::from_le_bytes([body[2], body[3]]) },
        Command::Execute => Request::Execute { function: body[2], params: [body[3], body[4]] },
        Command::Stop => Request::Stop { function: body[2], param: body[3] },
        Command::Cyclic => Request::Cyclic { object: body[4], write: &body[5..] },
        Command::Transfer => Request::Transfer { index: u16::from_le_bytes([body[4], body[5]]), data: &body[6..] },
    })
}

impl RequestDecoder {
    /// An empty decoder.
    pub const fn new() -> Self {
        RequestDecoder { framer: Framer::new() }
    }

    /// Drops a partly received telegram (the line was silent too long).
    pub fn reset(&mut self) {
        self.framer.reset();
    }

    /// True while part of a telegram is buffered.
    pub fn is_mid_telegram(&self) -> bool {
        !self.framer.buffered().is_empty()
    }

    /// Takes bytes from `input` and returns how many it used and at most one event. Call it again with the rest
    /// of the input (and with an empty input, to drain events of bytes already buffered) until it returns
    /// `(0, None)`. A telegram that lies whole in `input` is decoded in place, without copying.
    pub fn decode<'a>(&'a mut self, input: &'a [u8]) -> (usize, Option<RequestEvent<'a>>) {
        let (used, event) = self.framer.next(input, scan_request);
        (used, event.map(|e| e.map(parse_request)))
    }
}
