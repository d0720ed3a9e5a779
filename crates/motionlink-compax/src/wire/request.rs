//! Requests, host to drive: building them, and decoding them incrementally (the emulator's and the capture
//! decoder's side).
//!
//! ASCII: `address + (command | "!") [$] [,] [/] [?] CR [BCC]`. Binary: `address + 0x8n ... [BCC]`, no CR.
//!
//! ```
//! use motionlink_compax::wire::{Address, Body, Flags, Mode, Request};
//! let req = Request { address: Address::new(1).unwrap(), body: Body::Command(b"S1"), flags: Flags::NONE };
//! assert_eq!(req.encode(&Mode::default()).unwrap().as_bytes(), b"1S1\r");
//! let bcc = Mode::from_p196(8).unwrap();
//! assert_eq!(req.encode(&bcc).unwrap().as_bytes(), b"1S1\rS"); // BCC 0x53 = 'S'
//! ```

use std::fmt;

use super::binary::{announced_len, BinaryCommand, MAX_BINARY_LEN};
use super::{
    bcc, Address, EscapedBytes, Frame, Mode, WireError, BROADCAST, BUFFER, CR, ECHO, EXECUTE, MAX_COMMAND_LEN,
    NO_REPLY, POSITION_MESSAGE, XOFF, XON,
};

/// The optional characters after a command.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
pub struct Flags {
    /// `$`: send the position-reached message (POSA / POSR only).
    pub position_message: bool,
    /// `,`: store the command in the buffer; `!` executes it later.
    pub buffer: bool,
    /// `/`: the drive sends no reply.
    pub no_reply: bool,
    /// `?`: the drive sends the telegram back (and does not execute it; with `,` it stores it).
    pub echo: bool,
}

impl Flags {
    /// No optional character.
    pub const NONE: Flags = Flags { position_message: false, buffer: false, no_reply: false, echo: false };

    #[inline]
    fn count(&self) -> usize {
        usize::from(self.position_message)
            + usize::from(self.buffer)
            + usize::from(self.no_reply)
            + usize::from(self.echo)
    }

    /// Each flag with its character, in the order they are sent.
    #[inline]
    fn chars(&self) -> [(bool, u8); 4] {
        [(self.position_message, POSITION_MESSAGE), (self.buffer, BUFFER), (self.no_reply, NO_REPLY), (self.echo, ECHO)]
    }

    #[inline]
    fn is_none(&self) -> bool {
        self.count() == 0
    }

    /// Splits the flag characters off the end of a command string: `POSA 100$,` is `POSA 100` with `$` and `,`.
    /// Each may appear once, in any order.
    #[inline]
    pub fn split(text: &[u8]) -> (&[u8], Flags) {
        let mut flags = Flags::NONE;
        let mut end = text.len();
        while end > 0 {
            let f = match text[end - 1] {
                POSITION_MESSAGE if !flags.position_message => &mut flags.position_message,
                BUFFER if !flags.buffer => &mut flags.buffer,
                NO_REPLY if !flags.no_reply => &mut flags.no_reply,
                ECHO if !flags.echo => &mut flags.echo,
                _ => break,
            };
            *f = true;
            end -= 1;
        }
        (&text[..end], flags)
    }
}

impl fmt::Display for Flags {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (on, c) in [(self.position_message, "$"), (self.buffer, ","), (self.no_reply, "/"), (self.echo, "?")] {
            if on {
                f.write_str(c)?;
            }
        }
        Ok(())
    }
}

/// What a request carries.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Body<'a> {
    /// An ASCII command string without the flag characters, such as `S1`, `POSA 360`, `P194=5`.
    Command(&'a [u8]),
    /// The execute character `!`: run the buffered command.
    Execute,
    /// A binary command.
    Binary(BinaryCommand),
}

/// One request telegram.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Request<'a> {
    /// The drive (1..=31) or every drive (32).
    pub address: Address,
    /// The command.
    pub body: Body<'a>,
    /// Optional characters (ASCII only).
    pub flags: Flags,
}

impl<'a> Request<'a> {
    /// The request for a command as typed (`S1`, `POSA 10$`, `!`, `OUTPUT O9=1/`): flag characters at its
    /// end are its flags, `!` alone the execute character; blanks around it are dropped. What the clients'
    /// `raw` sends.
    ///
    /// ```
    /// use motionlink_compax::wire::{Address, Body, Mode, Request};
    /// let r = Request::raw(Address::new(1).unwrap(), " POSA 10$ ");
    /// assert_eq!((r.body, r.flags.position_message), (Body::Command(b"POSA 10"), true));
    /// assert_eq!(Request::raw(Address::new(1).unwrap(), "").encode(&Mode::default()).unwrap_err().to_string(),
    ///            "empty command");
    /// ```
    pub fn raw(address: Address, text: &'a str) -> Request<'a> {
        let (body, flags) = Flags::split(text.trim().as_bytes());
        let body = if body == [EXECUTE] { Body::Execute } else { Body::Command(body) };
        Request { address, body, flags }
    }
}

/// Checks a command as typed for `raw` ([`Request::raw`]): the reason the telegram cannot be built (an empty
/// command, a character that cannot be sent, a leading digit, more than the drive's input buffer holds,
/// flags that do not go together), found before anything is sent.
pub fn check_raw(text: &str) -> Result<(), WireError> {
    Request::raw(Address::BROADCAST, text).encode(&Mode::default()).map(|_| ())
}

impl Request<'_> {
    /// True when a drive will answer: not a broadcast and not `/`.
    #[inline]
    pub fn expects_reply(&self) -> bool {
        !self.address.is_broadcast() && !self.flags.no_reply
    }

    /// Builds the telegram in `mode` (only the BCC depends on it). Refuses command strings longer than the
    /// drive's input buffer, characters that are not printable ASCII, and flags on binary commands.
    #[inline]
    pub fn encode(&self, mode: &Mode) -> Result<Frame, WireError> {
        let mut f = Frame::default();
        self.encode_into(mode, &mut f)?;
        Ok(f)
    }

    /// [`encode`](Self::encode) into `frame`, replacing what it held (left empty on an error). Building in
    /// place spares the copy of a returned frame; a client can keep one frame for all its requests.
    ///
    /// ```
    /// use motionlink_compax::wire::{Address, Body, Flags, Frame, Mode, Request};
    /// let mut frame = Frame::default();
    /// let req = Request { address: Address::new(1).unwrap(), body: Body::Command(b"S1"), flags: Flags::NONE };
    /// req.encode_into(&Mode::default(), &mut frame).unwrap();
    /// assert_eq!(frame.as_bytes(), b"1S1\r");
    /// ```
    #[inline]
    pub fn encode_into(&self, mode: &Mode, frame: &mut Frame) -> Result<(), WireError> {
        let r = self.build(mode, frame);
        if r.is_err() {
            frame.len = 0;
        }
        r
    }

    #[inline]
    fn build(&self, mode: &Mode, f: &mut Frame) -> Result<(), WireError> {
        let (digits, n) = self.address.digits();
        f.buf[..2].copy_from_slice(&digits);
        f.len = n;
        match self.body {
            Body::Command(text) => {
                let len = text.len() + self.flags.count();
                let (&first, &last) = match (text.first(), text.last()) {
                    (Some(first), Some(last)) => (first, last),
                    _ => return Err(command_error(text, len)),
                };
                if len > MAX_COMMAND_LEN || first.is_ascii_digit() || is_flag_char(last) {
                    return Err(command_error(text, len));
                }
                // Copied and checked in one pass. Address, 40 characters with the flags, CR and BCC fit the
                // frame: no more checks of its room.
                let mut at = n + text.len();
                let mut printable = true;
                for (slot, &c) in f.buf[n..at].iter_mut().zip(text) {
                    *slot = c;
                    printable &= (0x20..=0x7E).contains(&c);
                }
                if !printable {
                    return Err(command_error(text, len));
                }
                for (on, c) in self.flags.chars() {
                    f.buf[at] = c;
                    at += usize::from(on);
                }
                f.buf[at] = CR;
                if mode.bcc {
                    f.buf[at + 1] = bcc(&f.buf[..at]);
                    at += 1;
                }
                f.len = at + 1;
            }
            Body::Execute => {
                if self.flags.buffer {
                    return Err(WireError::Flags("the execute character cannot be buffered"));
                }
                if self.flags.position_message {
                    return Err(WireError::Flags("'$' belongs to the POSA / POSR command, not to '!'"));
                }
                f.push(EXECUTE)?;
                self.push_flags(f)?;
                f.push(CR)?;
                if mode.bcc {
                    f.push(bcc(&f.as_bytes()[..f.len() - 1]))?;
                }
            }
            Body::Binary(cmd) => {
                if !self.flags.is_none() {
                    return Err(WireError::Flags("binary commands take no optional characters"));
                }
                let (b, n) = cmd.encode();
                f.extend(&b[..n])?;
                if mode.bcc {
                    f.push(bcc(f.as_bytes()))?;
                }
            }
        }
        Ok(())
    }

    #[inline]
    fn push_flags(&self, f: &mut Frame) -> Result<(), WireError> {
        for (on, c) in self.flags.chars() {
            if on {
                f.push(c)?;
            }
        }
        Ok(())
    }
}

/// True for the characters that are flags at the end of a command (`$`, `,`, `/`, `?`).
#[inline]
fn is_flag_char(c: u8) -> bool {
    matches!(c, POSITION_MESSAGE | BUFFER | NO_REPLY | ECHO)
}

/// Why a command string of `len` characters (flags included) cannot be sent, the first reason in this
/// order: empty, a character that is not printable ASCII, a leading digit, a flag character at its end,
/// too long. Called only for a string that fails one of them.
#[cold]
fn command_error(text: &[u8], len: usize) -> WireError {
    if text.is_empty() {
        return WireError::Flags("empty command");
    }
    if let Some(&c) = text.iter().find(|&&c| !(0x20..=0x7E).contains(&c)) {
        return WireError::BadChar(c);
    }
    if text[0].is_ascii_digit() {
        return WireError::Flags("a command cannot start with a digit (it would extend the address)");
    }
    if is_flag_char(text[text.len() - 1]) {
        return WireError::Flags("the command text ends with a flag character; use the flags");
    }
    WireError::TooLong(len)
}

/// The most digits of a valid address (1..=32).
pub const MAX_ADDRESS_DIGITS: usize = 2;

/// A request telegram as received, before interpretation.
#[derive(Clone, Copy, PartialEq, Eq)]
pub struct RequestFrame {
    raw: [u8; 64],
    len: usize,
    /// Digits of the address part kept in `raw` (at most [`MAX_ADDRESS_DIGITS`]).
    address_len: usize,
    /// Digits of the address part received (they may be more than were kept).
    address_digits: usize,
    /// Command characters received (they may be more than were kept).
    command_count: usize,
    binary: bool,
    /// XOR of every byte of the telegram received so far (kept or not): the BCC it should have.
    xor: u8,
    /// Received and computed BCC, when the mode has BCC.
    bcc: Option<(u8, u8)>,
}

impl fmt::Debug for RequestFrame {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "RequestFrame({:?}, bcc {:?})", EscapedBytes(self.bytes()), self.bcc)
    }
}

/// A request, interpreted.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParsedRequest<'a> {
    /// The address number as received (1..=32).
    pub address: u8,
    /// The command.
    pub body: Body<'a>,
    /// The optional characters.
    pub flags: Flags,
}

/// Why a received request cannot be interpreted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum RequestError {
    /// The address is not 1..=32.
    #[error("address {0} is not 1..=32")]
    Address(u8),
    /// The address has more digits than any address (1..=32): no drive is addressed.
    #[error("an address of {0} digits (a drive's address has one or two)")]
    AddressTooLong(usize),
    /// More than 40 characters (the drive answers E71).
    #[error("command string of {0} characters overflows the 40-character buffer")]
    Overflow(usize),
    /// The BCC does not match (the drive answers E72).
    #[error("BCC received 0x{received:02X}, computed 0x{computed:02X}")]
    Bcc {
        /// As received.
        received: u8,
        /// As computed over the telegram.
        computed: u8,
    },
    /// No command after the address.
    #[error("no command after the address")]
    Empty,
    /// A binary telegram that is not in the table.
    #[error("{0}")]
    Binary(&'static str),
}

impl RequestFrame {
    /// The telegram as received, without CR and BCC (at most the first 60 bytes; of an address longer than
    /// two digits, the first two).
    pub fn bytes(&self) -> &[u8] {
        &self.raw[..self.len]
    }

    /// The address number (0..=99; only 1..=32 are valid). An address of more than two digits, which no
    /// drive has, is 0 (as no address at all).
    pub fn address(&self) -> u8 {
        if self.address_digits > MAX_ADDRESS_DIGITS {
            return 0;
        }
        self.raw[..self.address_len]
            .iter()
            .fold(0u8, |a, d| a.saturating_mul(10).saturating_add(d.saturating_sub(b'0')))
    }

    /// The number of address digits received.
    pub fn address_digits(&self) -> usize {
        self.address_digits
    }

    /// True for a binary telegram.
    pub fn is_binary(&self) -> bool {
        self.binary
    }

    /// Received and computed BCC, if the decoder expected one.
    pub fn bcc(&self) -> Option<(u8, u8)> {
        self.bcc
    }

    /// The command part: after the address, before CR.
    pub fn command_bytes(&self) -> &[u8] {
        &self.raw[self.address_len..self.len]
    }

    /// Interprets the telegram. Errors are checked in the order a drive meets them: address, BCC,
    /// overflow, syntax.
    pub fn parse(&self) -> Result<ParsedRequest<'_>, RequestError> {
        self.parse_checking(true)
    }

    /// [`RequestFrame::parse`] without the BCC check: what the telegram says even though its BCC is wrong
    /// (a drive answers such a telegram with E72 and executes nothing). For reading captures.
    pub fn parse_ignoring_bcc(&self) -> Result<ParsedRequest<'_>, RequestError> {
        self.parse_checking(false)
    }

    fn parse_checking(&self, check_bcc: bool) -> Result<ParsedRequest<'_>, RequestError> {
        if self.address_digits > MAX_ADDRESS_DIGITS {
            return Err(RequestError::AddressTooLong(self.address_digits));
        }
        let address = self.address();
        if self.address_len > 2 || !(1..=BROADCAST).contains(&address) {
            return Err(RequestError::Address(address));
        }
        if let Some((received, computed)) = self.bcc.filter(|_| check_bcc) {
            if received != computed {
                return Err(RequestError::Bcc { received, computed });
            }
        }
        if self.command_count > MAX_COMMAND_LEN {
            return Err(RequestError::Overflow(self.command_count));
        }
        let cmd = self.command_bytes();
        if self.binary {
            let c = BinaryCommand::decode(cmd).map_err(|e| match e {
                WireError::Binary(m) => RequestError::Binary(m),
                _ => RequestError::Binary("not a binary command"),
            })?;
            return Ok(ParsedRequest { address, body: Body::Binary(c), flags: Flags::NONE });
        }
        let (text, flags) = Flags::split(cmd);
        let text = trim(text);
        if text == [EXECUTE] {
            return Ok(ParsedRequest { address, body: Body::Execute, flags });
        }
        if text.is_empty() {
            return Err(RequestError::Empty);
        }
        Ok(ParsedRequest { address, body: Body::Command(text), flags })
    }
}

fn trim(mut s: &[u8]) -> &[u8] {
    while let [b' ', rest @ ..] = s {
        s = rest;
    }
    while let [rest @ .., b' '] = s {
        s = rest;
    }
    s
}

/// What a [`RequestDecoder`] found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RequestEvent {
    /// A complete telegram.
    Frame(RequestFrame),
    /// XOFF (true) or XON (false) from the host, with XON/XOFF on.
    Flow(bool),
    /// A byte outside any telegram (not an address digit): skipped.
    Garbage(u8),
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum RxState {
    Idle,
    Address,
    Text,
    Binary {
        remaining: usize,
    },
    Bcc,
    /// A telegram addressed to no drive (a drive's framing): skipped up to its CR.
    Skip,
    /// The BCC after such a telegram's CR: skipped too.
    SkipBcc,
}

/// Splits the host's byte stream into request telegrams, one byte at a time (what a drive does).
///
/// A telegram starts with an address digit; bytes before one are skipped as garbage. ASCII telegrams end at
/// CR (plus the BCC when the mode has it), binary ones after the length their first byte announces.
///
/// Nothing that arrives can make it keep more than a fixed number of bytes: of the address it keeps two
/// digits and counts the rest (a telegram whose address has more digits addresses no drive: its
/// [`RequestFrame::parse`] is [`RequestError::AddressTooLong`] and its [`RequestFrame::address`] 0), of the
/// command 48 characters (more than 40 is [`RequestError::Overflow`], E71). Such a telegram ends at its CR
/// like any other, and the next one is decoded normally. The BCC is checked against every byte received,
/// kept or not.
#[derive(Debug, Clone)]
pub struct RequestDecoder {
    bcc: bool,
    xon_xoff: bool,
    /// A drive's framing ([`RequestDecoder::for_drive`]).
    drive: bool,
    state: RxState,
    frame: RequestFrame,
}

impl RequestDecoder {
    /// A decoder for telegrams in `mode`, as a reader of a capture frames them: a byte that starts no
    /// telegram is skipped by itself, and the next address digit starts one (it finds the next telegram
    /// after any garbage).
    pub fn new(mode: &Mode) -> Self {
        RequestDecoder {
            bcc: mode.bcc,
            xon_xoff: mode.xon_xoff,
            drive: false,
            state: RxState::Idle,
            frame: RequestFrame {
                raw: [0; 64],
                len: 0,
                address_len: 0,
                address_digits: 0,
                command_count: 0,
                binary: false,
                xor: 0,
                bcc: None,
            },
        }
    }

    /// A decoder for telegrams in `mode`, as a drive frames them (the emulator's): a telegram begins with
    /// the first byte after the previous one ended, and one that begins with a printable character other
    /// than an address digit is addressed to no drive. It is skipped up to its CR, and with a BCC the byte
    /// after it, and never read as a telegram to the drive whose address digit it holds further on (such as
    /// the `1` of `S1` in the rest of a telegram whose address digit a drive took for the BCC of the one
    /// before, when host and drives disagree on P196). Control characters and blanks between telegrams (an
    /// LF after the CR, a NUL of noise) are skipped one at a time, as [`RequestDecoder::new`] does.
    ///
    /// ```
    /// use motionlink_compax::wire::{Mode, RequestDecoder, RequestEvent};
    /// let mut d = RequestDecoder::for_drive(&Mode::default());
    /// let frames = b"S1\r\n1S1\r".iter().filter(|&&b| matches!(d.push(b), Some(RequestEvent::Frame(_)))).count();
    /// assert_eq!(frames, 1); // "S1" addressed nobody; "1S1" is drive 1's
    /// ```
    pub fn for_drive(mode: &Mode) -> Self {
        RequestDecoder { drive: true, ..RequestDecoder::new(mode) }
    }

    /// True between telegrams.
    pub fn is_idle(&self) -> bool {
        self.state == RxState::Idle
    }

    /// The address digits received so far of the telegram in progress, as a number (0 if none).
    pub fn partial_address(&self) -> u8 {
        if self.state == RxState::Idle {
            0
        } else {
            self.frame.address()
        }
    }

    /// True once the telegram in progress has passed its address (a command byte has arrived).
    pub fn past_address(&self) -> bool {
        matches!(self.state, RxState::Text | RxState::Binary { .. } | RxState::Bcc)
    }

    /// Drops the telegram in progress.
    pub fn reset(&mut self) {
        self.state = RxState::Idle;
        self.frame.len = 0;
        self.frame.address_len = 0;
        self.frame.address_digits = 0;
        self.frame.command_count = 0;
        self.frame.binary = false;
        self.frame.xor = 0;
        self.frame.bcc = None;
    }

    /// Keeps `b` if there is room (the BCC counts it either way).
    fn store(&mut self, b: u8) {
        self.frame.xor ^= b;
        if self.frame.len < 60 {
            self.frame.raw[self.frame.len] = b;
            self.frame.len += 1;
        }
    }

    /// An address digit: kept while the address is not longer than any valid one, counted always.
    fn address_digit(&mut self, b: u8) {
        self.frame.address_digits = self.frame.address_digits.saturating_add(1);
        if self.frame.address_digits <= MAX_ADDRESS_DIGITS {
            self.store(b);
            self.frame.address_len += 1;
        } else {
            self.frame.xor ^= b;
        }
    }

    fn finish(&mut self) -> RequestEvent {
        let frame = self.frame;
        self.reset();
        RequestEvent::Frame(frame)
    }

    fn end_of_body(&mut self) -> Option<RequestEvent> {
        if self.bcc {
            self.state = RxState::Bcc;
            None
        } else {
            Some(self.finish())
        }
    }

    /// Feeds one byte.
    pub fn push(&mut self, b: u8) -> Option<RequestEvent> {
        let flow = self.xon_xoff && (b == XON || b == XOFF);
        match self.state {
            RxState::Idle => {
                if flow {
                    return Some(RequestEvent::Flow(b == XOFF));
                }
                if b.is_ascii_digit() {
                    self.address_digit(b);
                    self.state = RxState::Address;
                } else if self.drive && b.is_ascii_graphic() {
                    self.state = RxState::Skip;
                }
                (!b.is_ascii_digit()).then_some(RequestEvent::Garbage(b))
            }
            RxState::Skip => {
                if flow {
                    return Some(RequestEvent::Flow(b == XOFF));
                }
                if b == CR {
                    self.state = if self.bcc { RxState::SkipBcc } else { RxState::Idle };
                }
                Some(RequestEvent::Garbage(b))
            }
            RxState::SkipBcc => {
                self.state = RxState::Idle;
                Some(RequestEvent::Garbage(b))
            }
            RxState::Address => {
                if flow {
                    return Some(RequestEvent::Flow(b == XOFF));
                }
                if b.is_ascii_digit() {
                    self.address_digit(b);
                    return None;
                }
                if b == CR {
                    // An address alone: no command.
                    return self.end_of_body();
                }
                if let Some(len) = announced_len(b) {
                    self.frame.binary = true;
                    self.store(b);
                    self.frame.command_count = 1;
                    let remaining = len.clamp(1, MAX_BINARY_LEN) - 1;
                    if remaining == 0 {
                        return self.end_of_body();
                    }
                    self.state = RxState::Binary { remaining };
                    return None;
                }
                self.state = RxState::Text;
                self.frame.command_count = 1;
                self.store(b);
                None
            }
            RxState::Text => {
                if flow {
                    return Some(RequestEvent::Flow(b == XOFF));
                }
                if b == CR {
                    return self.end_of_body();
                }
                self.frame.command_count = self.frame.command_count.saturating_add(1);
                if self.frame.command_count <= MAX_COMMAND_LEN + 8 {
                    self.store(b);
                } else {
                    self.frame.xor ^= b;
                }
                None
            }
            RxState::Binary { remaining } => {
                self.store(b);
                self.frame.command_count += 1;
                if remaining <= 1 {
                    self.end_of_body()
                } else {
                    self.state = RxState::Binary { remaining: remaining - 1 };
                    None
                }
            }
            RxState::Bcc => {
                self.frame.bcc = Some((b, self.frame.xor));
                Some(self.finish())
            }
        }
    }
}

#[cfg(test)]
mod tests;
