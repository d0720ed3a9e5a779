//! Replies, drive to host: `[address] text CR LF > [BCC]`, or `[address] text CR [BCC]` when P196 has 32.
//!
//! The text is empty for a plain acknowledgement, `Exx` for an error, `$` for the position-reached message,
//! and the answer otherwise. The BCC is the XOR of every character before the CR, address included.
//!
//! ```
//! use motionlink_compax::wire::{Mode, ReplyDecoder, ReplyEvent, ReplyKind};
//! let mut d = ReplyDecoder::new(&Mode::default());
//! let mut kinds = Vec::new();
//! d.push_slice(b"S001: 360\r\n>E92\r\n>", |e| if let ReplyEvent::Reply(r) = e {
//!     kinds.push(format!("{:?}", r.kind()));
//! });
//! assert_eq!(kinds, ["Text(\"S001: 360\")", "Error(92)"]);
//! ```

use std::fmt;

use super::{bcc, EscapedBytes, Mode, ReplyEnd, CR, LF, PROMPT, XOFF, XON};

/// The longest reply text the decoder keeps (the drive's output buffer holds 40 characters).
pub const MAX_REPLY_LEN: usize = 60;

// A reply keeps its length in a byte.
const _: () = assert!(MAX_REPLY_LEN <= u8::MAX as usize);

/// One reply, decoded.
#[derive(Clone, Copy)]
pub struct Reply {
    line: [u8; MAX_REPLY_LEN],
    // Both at most MAX_REPLY_LEN: bytes keep the reply (and every event) small to move.
    len: u8,
    prefix: u8,
    address: Option<u8>,
}

impl PartialEq for Reply {
    /// Equal lines, address prefixes and addresses (the buffer after the line does not count).
    fn eq(&self, other: &Self) -> bool {
        self.line() == other.line() && self.prefix == other.prefix && self.address == other.address
    }
}

impl Eq for Reply {}

/// What a reply says.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ReplyKind<'a> {
    /// Empty text: the command was accepted.
    Ack,
    /// `Exx`: the command was refused or failed; the code.
    Error(u8),
    /// `$`: a position was reached (after POSA / POSR with `$`).
    PositionReached,
    /// A bare number: a comparator set by `POSR value OUTPUT` has switched (the user guide's example returns
    /// `2 CR LF >` when the second comparator fires). The form alone cannot tell it from a read answered with
    /// a bare value (`35`): the client takes it as the reply to a request awaiting one when it can be that
    /// reply, and as a comparator message otherwise.
    Comparator(u8),
    /// Any other answer (a status value, a parameter, an echo).
    Text(&'a str),
}

impl Reply {
    /// The address that prefixes the reply (P196 has 64), if any.
    #[inline]
    pub fn address(&self) -> Option<u8> {
        self.address
    }

    /// The reply text after the address, without CR / LF / prompt / BCC.
    #[inline]
    pub fn text(&self) -> &[u8] {
        &self.line[usize::from(self.prefix)..usize::from(self.len)]
    }

    /// The whole line before the CR, address included.
    #[inline]
    pub fn line(&self) -> &[u8] {
        &self.line[..usize::from(self.len)]
    }

    /// The text as `str` (non-ASCII bytes make it `"?"`).
    pub fn text_str(&self) -> &str {
        std::str::from_utf8(self.text()).unwrap_or("?")
    }

    /// Classifies the text.
    pub fn kind(&self) -> ReplyKind<'_> {
        classify(self.text_str())
    }
}

impl fmt::Debug for Reply {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Reply(address {:?}, {:?})", self.address, EscapedBytes(self.text()))
    }
}

fn classify(text: &str) -> ReplyKind<'_> {
    let b = text.as_bytes();
    if b.is_empty() {
        return ReplyKind::Ack;
    }
    if b == b"$" {
        return ReplyKind::PositionReached;
    }
    if b.len() >= 2 && b.len() <= 3 && b[0] == b'E' && b[1..].iter().all(u8::is_ascii_digit) {
        return ReplyKind::Error(b[1..].iter().fold(0u8, |a, d| a * 10 + (d - b'0')));
    }
    if b.len() <= 2 && b.iter().all(u8::is_ascii_digit) {
        return ReplyKind::Comparator(b.iter().fold(0u8, |a, d| a * 10 + (d - b'0')));
    }
    ReplyKind::Text(text)
}

/// Where the address prefix of a line ends, when P196 has 64. The digits are ambiguous with texts that start
/// with digits (an echo, a comparator number), so: a prefix followed by exactly `$` wins (the unsolicited
/// message), then the address the host expects, then the longest valid address.
pub fn split_address(line: &[u8], expected: Option<u8>) -> Option<(u8, usize)> {
    let d = |i: usize| line.get(i).filter(|c| c.is_ascii_digit()).map(|c| c - b'0');
    let one = d(0).filter(|&a| a >= 1).map(|a| (a, 1));
    let two = match (d(0), d(1)) {
        (Some(a), Some(b)) if (10..=31).contains(&(a * 10 + b)) => Some((a * 10 + b, 2)),
        _ => None,
    };
    let candidates = [two, one];
    let rest_is = |c: &(u8, usize), s: &[u8]| &line[c.1..] == s;
    if let Some(c) = candidates.iter().flatten().find(|c| rest_is(c, b"$")) {
        return Some(*c);
    }
    if let Some(c) = candidates.iter().flatten().find(|c| Some(c.0) == expected) {
        return Some(*c);
    }
    candidates.into_iter().flatten().next()
}

/// Something the reply decoder found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ReplyEvent {
    /// A complete reply with a good BCC (or none expected).
    Reply(Reply),
    /// A reply was lost to a line error; the decoder has resynchronised.
    Error(ReplyError),
    /// XOFF (true) or XON (false) from the drive, with XON/XOFF on.
    Flow(bool),
}

/// A [`ReplyEvent`] whose reply is lent by the decoder instead of copied out of it: what
/// [`ReplyDecoder::decode`] returns. [`ReplyEvent::from`] makes it one to keep.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ReplyEventRef<'a> {
    /// A complete reply with a good BCC (or none expected).
    Reply(&'a Reply),
    /// A reply was lost to a line error; the decoder has resynchronised.
    Error(ReplyError),
    /// XOFF (true) or XON (false) from the drive, with XON/XOFF on.
    Flow(bool),
}

impl From<ReplyEventRef<'_>> for ReplyEvent {
    #[inline]
    fn from(e: ReplyEventRef<'_>) -> Self {
        match e {
            ReplyEventRef::Reply(r) => ReplyEvent::Reply(*r),
            ReplyEventRef::Error(e) => ReplyEvent::Error(e),
            ReplyEventRef::Flow(x) => ReplyEvent::Flow(x),
        }
    }
}

/// A corrupt reply.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum ReplyError {
    /// The BCC does not match.
    #[error("reply BCC received 0x{received:02X}, computed 0x{computed:02X}")]
    Bcc {
        /// As received.
        received: u8,
        /// As computed.
        computed: u8,
    },
    /// The reply end was not `CR LF >`: this byte came instead.
    #[error("reply end broken by byte 0x{0:02X}")]
    Framing(u8),
    /// A reply longer than any the drive sends.
    #[error("reply longer than {MAX_REPLY_LEN} characters")]
    TooLong,
    /// P196 has 64 but the reply does not start with an address.
    #[error("reply without the address prefix P196 asks for")]
    NoAddress,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum State {
    Text,
    Discard,
    Lf,
    Prompt,
    Bcc,
}

/// An event without its reply, which is in the decoder.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Found {
    Reply,
    Error(ReplyError),
    Flow(bool),
}

/// Splits the drives' byte stream into replies, incrementally, without allocating.
#[derive(Debug, Clone)]
pub struct ReplyDecoder {
    mode: Mode,
    expected: Option<u8>,
    state: State,
    /// Its line receives the text; once a reply is complete, the reply (length and address set), lent out
    /// until the next call.
    reply: Reply,
    /// Characters of the reply being received.
    len: usize,
}

impl ReplyDecoder {
    /// A decoder for replies in `mode`.
    pub fn new(mode: &Mode) -> Self {
        ReplyDecoder {
            mode: *mode,
            expected: None,
            state: State::Text,
            reply: Reply { line: [0; MAX_REPLY_LEN], len: 0, prefix: 0, address: None },
            len: 0,
        }
    }

    /// The mode it decodes.
    pub fn mode(&self) -> &Mode {
        &self.mode
    }

    /// Tells the decoder which drive should answer next (resolves address prefixes; see [`split_address`]).
    #[inline]
    pub fn expect_from(&mut self, address: Option<u8>) {
        self.expected = address;
    }

    /// Drops a partial reply.
    pub fn reset(&mut self) {
        self.state = State::Text;
        self.len = 0;
    }

    /// True when no reply is partly received.
    pub fn is_idle(&self) -> bool {
        self.state == State::Text && self.len == 0
    }

    /// Feeds one byte. A reply comes out as a copy; [`decode`](Self::decode) lends it instead.
    #[inline]
    pub fn push(&mut self, b: u8) -> Option<ReplyEvent> {
        let found = self.step(b)?;
        Some(self.lend(found).into())
    }

    /// Feeds bytes until the first event: returns how many bytes were used (up to and including the one that
    /// completed the event, or all of them) and the event, its reply lent by the decoder until the next
    /// call (no copy of the reply is made; [`ReplyEvent::from`] makes one). The same as
    /// [`push`](Self::push) on each of those bytes, only faster: the text of a reply is scanned and
    /// stored eight bytes at a time.
    ///
    /// ```
    /// use motionlink_compax::wire::{Mode, ReplyDecoder, ReplyEventRef};
    /// let mut d = ReplyDecoder::new(&Mode::default());
    /// let mut rest: &[u8] = b"S001: 12.5\r\n>E92\r\n>";
    /// let mut texts = Vec::new();
    /// while !rest.is_empty() {
    ///     let (used, event) = d.decode(rest);
    ///     rest = &rest[used..];
    ///     if let Some(ReplyEventRef::Reply(r)) = event {
    ///         texts.push(r.text_str().to_string());
    ///     }
    /// }
    /// assert_eq!(texts, ["S001: 12.5", "E92"]);
    /// ```
    #[inline]
    pub fn decode(&mut self, bytes: &[u8]) -> (usize, Option<ReplyEventRef<'_>>) {
        let (used, found) = self.scan(bytes);
        (used, found.map(|f| self.lend(f)))
    }

    /// Feeds many bytes, handing every event to `f`.
    #[inline]
    pub fn push_slice(&mut self, mut bytes: &[u8], mut f: impl FnMut(ReplyEvent)) {
        while !bytes.is_empty() {
            let (used, event) = self.decode(bytes);
            bytes = &bytes[used..];
            if let Some(e) = event {
                f(e.into());
            }
        }
    }

    #[inline]
    fn lend(&self, found: Found) -> ReplyEventRef<'_> {
        match found {
            Found::Reply => ReplyEventRef::Reply(&self.reply),
            Found::Error(e) => ReplyEventRef::Error(e),
            Found::Flow(x) => ReplyEventRef::Flow(x),
        }
    }

    /// The state machine, one byte.
    #[inline]
    fn step(&mut self, b: u8) -> Option<Found> {
        match self.state {
            State::Text | State::Discard => {
                if self.mode.xon_xoff && (b == XON || b == XOFF) {
                    return Some(Found::Flow(b == XOFF));
                }
                if b == CR {
                    return self.after_cr();
                }
                if self.state == State::Discard {
                    return None;
                }
                if self.len == 0 && (b == LF || b == PROMPT) && self.mode.reply_end == ReplyEnd::CrLfPrompt {
                    // The tail of a reply whose start was lost: not a reply text.
                    return None;
                }
                if self.len >= MAX_REPLY_LEN {
                    self.state = State::Discard;
                    return Some(Found::Error(ReplyError::TooLong));
                }
                self.reply.line[self.len] = b;
                self.len += 1;
                None
            }
            State::Lf => {
                if b == LF {
                    self.state = State::Prompt;
                    None
                } else {
                    self.resync(b)
                }
            }
            State::Prompt => {
                if b == PROMPT {
                    self.after_end()
                } else {
                    self.resync(b)
                }
            }
            State::Bcc => {
                let computed = bcc(&self.reply.line[..self.len]);
                if b == computed {
                    self.emit()
                } else {
                    self.reset();
                    Some(Found::Error(ReplyError::Bcc { received: b, computed }))
                }
            }
        }
    }

    /// [`step`](Self::step) over `bytes` until something is found.
    #[inline]
    fn scan(&mut self, bytes: &[u8]) -> (usize, Option<Found>) {
        // The common case straight through: a reply's text, its end and (without BCC) the reply.
        if self.state == State::Text {
            let i = self.take_text(bytes);
            let end = self.end_len(&bytes[i..]);
            if end > 0 {
                // What `step` does with the end's bytes one by one.
                let i = i + end;
                return match self.after_end() {
                    Some(f) => (i, Some(f)),
                    None => self.scan_from(bytes, i),
                };
            }
            return self.scan_from(bytes, i);
        }
        self.scan_from(bytes, 0)
    }

    /// [`scan`](Self::scan) from `bytes[i..]` on, in any state.
    fn scan_from(&mut self, bytes: &[u8], mut i: usize) -> (usize, Option<Found>) {
        while i < bytes.len() {
            if self.state == State::Text {
                i += self.take_text(&bytes[i..]);
                let end = self.end_len(&bytes[i..]);
                if end > 0 {
                    i += end;
                    match self.after_end() {
                        Some(f) => return (i, Some(f)),
                        None => continue,
                    }
                }
                if i == bytes.len() {
                    break;
                }
            }
            let b = bytes[i];
            i += 1;
            if let Some(f) = self.step(b) {
                return (i, Some(f));
            }
        }
        (i, None)
    }

    /// In the state `Text`, the length of the reply end (`CR LF >`, or `CR` when P196 has 32) if `bytes`
    /// start with all of it, else 0.
    #[inline]
    fn end_len(&self, bytes: &[u8]) -> usize {
        match (self.mode.reply_end, bytes) {
            (ReplyEnd::CrLfPrompt, [CR, LF, PROMPT, ..]) => 3,
            (ReplyEnd::Cr, [CR, ..]) => 1,
            _ => 0,
        }
    }

    /// True for a byte that [`step`](Self::step) treats as more than text in the state `Text`.
    #[inline]
    fn is_special(&self, b: u8) -> bool {
        b == CR || (self.mode.xon_xoff && (b == XON || b == XOFF))
    }

    /// In the state `Text`: takes the bytes that `step` would only append to the line (or skip, for the
    /// tail of a lost reply), stopping before the first byte that does more (CR, flow control, a byte past
    /// the longest line). Returns how many bytes it took.
    #[inline]
    fn take_text(&mut self, bytes: &[u8]) -> usize {
        let mut i = 0;
        let mut len = self.len;
        if len == 0 && self.mode.reply_end == ReplyEnd::CrLfPrompt {
            while let Some(&(LF | PROMPT)) = bytes.get(i) {
                i += 1;
            }
        }
        const ONES: u64 = u64::from_le_bytes([0x01; 8]);
        const HIGH: u64 = u64::from_le_bytes([0x80; 8]);
        // Eight bytes at a time while they fit the line. The lowest byte flagged by the test below is the
        // first control character (< 0x20) of the eight: a borrow only reaches bytes above a flagged one.
        while len <= MAX_REPLY_LEN - 8 {
            let Some(chunk) = bytes.get(i..).and_then(<[u8]>::first_chunk::<8>) else { break };
            let x = u64::from_le_bytes(*chunk);
            self.reply.line[len..len + 8].copy_from_slice(&x.to_le_bytes());
            let control = x.wrapping_sub(ONES * 0x20) & !x & HIGH;
            if control == 0 {
                len += 8;
                i += 8;
                continue;
            }
            let k = (control.trailing_zeros() / 8) as usize;
            if self.is_special((x >> (8 * k)) as u8) {
                self.len = len + k;
                return i + k;
            }
            // A control character that is text: keep it and scan on after it.
            len += k + 1;
            i += k + 1;
        }
        while let Some(&b) = bytes.get(i) {
            if len >= MAX_REPLY_LEN || self.is_special(b) {
                break;
            }
            self.reply.line[len] = b;
            len += 1;
            i += 1;
        }
        self.len = len;
        i
    }

    #[inline]
    fn after_cr(&mut self) -> Option<Found> {
        if self.state == State::Discard {
            self.reset();
            return None;
        }
        match self.mode.reply_end {
            ReplyEnd::CrLfPrompt => {
                self.state = State::Lf;
                None
            }
            ReplyEnd::Cr => self.after_end(),
        }
    }

    #[inline]
    fn after_end(&mut self) -> Option<Found> {
        if self.mode.bcc {
            self.state = State::Bcc;
            None
        } else {
            self.emit()
        }
    }

    fn resync(&mut self, b: u8) -> Option<Found> {
        // The reply end is broken: the reply is lost. The byte may start the next reply.
        self.reset();
        let _ = self.step(b);
        Some(Found::Error(ReplyError::Framing(b)))
    }

    /// Completes the reply in `self.reply` and makes ready for the next.
    #[inline]
    fn emit(&mut self) -> Option<Found> {
        let (address, prefix) = if self.mode.reply_address {
            match split_address(&self.reply.line[..self.len], self.expected) {
                Some((a, n)) => (Some(a), n),
                None => {
                    self.reset();
                    return Some(Found::Error(ReplyError::NoAddress));
                }
            }
        } else {
            (None, 0)
        };
        // Both fit a byte: the line holds at most MAX_REPLY_LEN (60) characters.
        self.reply.len = self.len as u8;
        self.reply.prefix = prefix as u8;
        self.reply.address = address;
        self.reset();
        Some(Found::Reply)
    }
}

/// Appends a reply as a drive at `address` sends it in `mode` (the emulator's side).
pub fn encode_reply(out: &mut Vec<u8>, mode: &Mode, address: u8, text: &[u8]) {
    let start = out.len();
    if mode.reply_address {
        if address >= 10 {
            out.push(b'0' + address / 10);
        }
        out.push(b'0' + address % 10);
    }
    out.extend_from_slice(text);
    let check = bcc(&out[start..]);
    out.push(CR);
    if mode.reply_end == ReplyEnd::CrLfPrompt {
        out.push(LF);
        out.push(PROMPT);
    }
    if mode.bcc {
        out.push(check);
    }
}

#[cfg(test)]
mod tests;
