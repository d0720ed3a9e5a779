//! Reply decoding (the host's side).

use std::fmt;

use super::request_decoder::{check_crc, known_or_crc, Framer, Scan};
use super::*;

/// An event of the reply decoder.
pub type ReplyEvent<'a> = Result<Reply<'a>, WireError>;

/// What the reply decoder waits for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct Expectation {
    command: Command,
    shape: ReplyShape,
    /// The number of data bytes of an ACK with data, when the request fixes it.
    data_len: Option<u16>,
}

/// Incremental decoder of replies: feed it any chunk of bytes, get telegrams out.
///
/// A reply's length depends on the request it answers (an RC reply carries data only when the request named
/// a cyclic object). A client tells the decoder with [`ReplyDecoder::expect`]; then replies of other commands
/// are skipped as garbage. Without an expectation (reading a capture) every command is accepted and an
/// ambiguous RC reply is taken as status-only if its CRC matches that way, else as carrying data.
///
/// ```
/// use motionlink_scu::wire::{Command, Reply, ReplyDecoder, ReplyShape, Status};
/// let mut dec = ReplyDecoder::new();
/// dec.expect(Command::Get, ReplyShape::WithData);
/// let reply = [0x52, 0x47, 0x06, 0x01, 0x00, 0x31, 0xB3, 0xBB]; // RG ACK, 1 data byte (0x31)
/// let (_, ev) = dec.decode(&reply);
/// assert_eq!(ev, Some(Ok(Reply::with_data(Command::Get, &[0x31]))));
/// ```
#[derive(Clone)]
pub struct ReplyDecoder {
    framer: Framer<MAX_REPLY_LEN>,
    expect: Option<Expectation>,
}

impl fmt::Debug for ReplyDecoder {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("ReplyDecoder").field("buffered", &self.framer.buffered()).field("expect", &self.expect).finish()
    }
}

impl Default for ReplyDecoder {
    fn default() -> Self {
        Self::new()
    }
}

impl ReplyDecoder {
    /// An empty decoder that accepts replies of any command.
    pub const fn new() -> Self {
        ReplyDecoder { framer: Framer::new(), expect: None }
    }

    /// Accepts only replies to `command`, of `shape` when ACKed.
    pub fn expect(&mut self, command: Command, shape: ReplyShape) {
        self.expect = Some(Expectation { command, shape, data_len: None });
    }

    /// Like [`ReplyDecoder::expect`], and an ACK with data must carry exactly `data_len` bytes: a reply that
    /// announces another count (its length byte was corrupted) is reported at once as
    /// [`WireError::UnexpectedLength`] instead of being waited for.
    pub fn expect_len(&mut self, command: Command, shape: ReplyShape, data_len: u16) {
        self.expect = Some(Expectation { command, shape, data_len: Some(data_len) });
    }

    /// Accepts replies of any command again.
    pub fn expect_any(&mut self) {
        self.expect = None;
    }

    /// Drops buffered bytes.
    pub fn reset(&mut self) {
        self.framer.reset();
    }

    /// True while the start of an expected reply (its command letters at least) is buffered, after every event
    /// of the input was taken: the unit is answering.
    pub fn is_mid_telegram(&self) -> bool {
        self.framer.buffered().len() >= 2
    }

    /// Takes bytes from `input` and returns how many it used and at most one event. Call it again with the rest
    /// of the input (and with an empty input, to drain events of bytes already buffered) until it returns
    /// `(0, None)`. A telegram that lies whole in `input` is decoded in place, without copying.
    pub fn decode<'a>(&'a mut self, input: &'a [u8]) -> (usize, Option<ReplyEvent<'a>>) {
        let expect = self.expect;
        let (used, event) = self.framer.next(input, |b| scan_reply(b, expect));
        (used, event.map(|e| e.map(parse_reply)))
    }
}

/// A complete reply telegram whose CRC was checked.
pub(super) fn parse_reply(f: &[u8]) -> Reply<'_> {
    let n = f.len();
    let command = Command::from_code(f[0], f[1]).unwrap_or(Command::Get);
    let status = Status::from_code(f[2]).unwrap_or(Status::Ack);
    let data = (n > 5).then(|| &f[5..n - 2]);
    Reply { command, status, data }
}

pub(super) fn scan_reply(b: &[u8], expect: Option<Expectation>) -> Scan {
    let is_start = |x: u8, y: u8| match (Command::from_code(x, y), expect) {
        (Some(c), Some(e)) => c == e.command,
        (Some(_), None) => true,
        (None, _) => false,
    };
    let Some(&x) = b.first() else { return Scan::NeedMore };
    if x != b'R' {
        let n = b.iter().position(|&c| c == b'R').unwrap_or(b.len());
        return Scan::Garbage(n);
    }
    let Some(&y) = b.get(1) else { return Scan::NeedMore };
    if !is_start(x, y) {
        return Scan::Garbage(1);
    }
    let command = Command::from_code(x, y).unwrap_or(Command::Get);
    let Some(&s) = b.get(2) else { return Scan::NeedMore };
    let Some(status) = Status::from_code(s) else { return Scan::Garbage(1) };
    if status != Status::Ack {
        return if b.len() < 5 { Scan::NeedMore } else { known_or_crc(&b[..5], Some(command)) };
    }
    let shape = match (expect, command) {
        (Some(e), _) => e.shape,
        (None, Command::Get) => ReplyShape::WithData,
        // Ambiguous without the request.
        (None, Command::Cyclic) => ReplyShape::StatusOrData,
        (None, _) => ReplyShape::StatusOnly,
    };
    let shape = match shape {
        ReplyShape::StatusOrData => {
            // The status alone if that CRC matches, else with ctp and data.
            if b.len() < 5 {
                return Scan::NeedMore;
            }
            if check_crc(&b[..5]).is_ok() {
                return Scan::Complete(5);
            }
            ReplyShape::WithData
        }
        other => other,
    };
    match shape {
        ReplyShape::StatusOnly | ReplyShape::StatusOrData => {
            if b.len() < 5 {
                Scan::NeedMore
            } else {
                known_or_crc(&b[..5], Some(command))
            }
        }
        ReplyShape::WithData => {
            if b.len() < 5 {
                return Scan::NeedMore;
            }
            let ctp = u16::from_le_bytes([b[3], b[4]]);
            if let Some(expected) = expect.and_then(|e| e.data_len).filter(|&n| n != ctp) {
                return Scan::BadLength(WireError::UnexpectedLength { command, ctp, expected });
            }
            if usize::from(ctp) > MAX_REPLY_DATA {
                return Scan::BadLength(WireError::Oversized { command, ctp, max: MAX_REPLY_DATA });
            }
            let len = 5 + usize::from(ctp) + 2;
            if b.len() < len {
                Scan::NeedMore
            } else {
                known_or_crc(&b[..len], Some(command))
            }
        }
    }
}
