//! The sans-IO codec of the COMPAX RS485 / RS232 protocol: bytes in, typed telegrams out, and back.
//!
//! Nothing here does I/O, reads a clock or allocates on the hot path: requests are built into a fixed
//! [`Frame`] (returned, or in place with [`Request::encode_into`]), replies are decoded by a
//! [`ReplyDecoder`] into a fixed [`Reply`], a slice at a time with the reply lent by the decoder
//! ([`ReplyDecoder::decode`]) or a byte at a time with the reply copied out ([`ReplyDecoder::push`]). Every
//! decoder takes any chunk of bytes, reports garbage and checksum errors as values and finds the next
//! telegram.
//!
//! - [`Mode`]: parameter P196 (XON/XOFF, parity, BCC, timeout supervision, reply end, reply address).
//! - [`request`]: `address + command [$][,][/][?] CR [BCC]`, the execute character `!`, and binary telegrams.
//! - [`reply`]: `[address] text CR LF > [BCC]` or `... CR [BCC]`, `Exx` errors, the `$` message.
//! - [`binary`]: the binary commands of the manual's table, every row.
//! - [`number`]: the 24.24 fixed-point and 16-bit number formats, decimal text.

pub mod binary;
pub mod number;
pub mod reply;
pub mod request;

use std::fmt;

pub use motionlink_link::link::Parity;

pub use binary::BinaryCommand;
pub use number::{Fixed24, NumberError};
pub use reply::{Reply, ReplyDecoder, ReplyEvent, ReplyEventRef, ReplyKind};
pub use request::{Body, Flags, Request, RequestDecoder, RequestEvent, RequestFrame};

/// Carriage return: the end of a request (and of a reply's text).
pub const CR: u8 = 0x0D;
/// Line feed, second character of the reply end `CR LF >`.
pub const LF: u8 = 0x0A;
/// The prompt `>` that ends a reply (unless P196 has 32).
pub const PROMPT: u8 = b'>';
/// XON (DC1): resume sending, when P196 has 1.
pub const XON: u8 = 0x11;
/// XOFF (DC3): pause sending, when P196 has 1.
pub const XOFF: u8 = 0x13;
/// The execute character: runs the command stored in the drive's buffer.
pub const EXECUTE: u8 = b'!';
/// Appended to a command: store it in the buffer, do not execute it.
pub const BUFFER: u8 = b',';
/// Appended to a command: the drive sends no reply (the manual prints a quote mark, its hex code is 2F).
pub const NO_REPLY: u8 = b'/';
/// Appended to a command: the drive sends the telegram back instead of executing it.
pub const ECHO: u8 = b'?';
/// Appended to POSA / POSR: the drive sends the `$` message when the position is reached.
pub const POSITION_MESSAGE: u8 = b'$';
/// The most characters of a command string the drive's input buffer holds (more: E71).
pub const MAX_COMMAND_LEN: usize = 40;
/// The broadcast address: every drive executes, none replies.
pub const BROADCAST: u8 = 32;
/// Capacity of a [`Frame`]: an address, a full command string, CR and BCC fit with room to spare.
pub const FRAME_CAPACITY: usize = 64;

/// The block-check character: XOR of every byte given (the manual: every character up to, not including,
/// the CR; for a binary telegram every byte from the address on).
///
/// ```
/// use motionlink_compax::wire::bcc;
/// assert_eq!(bcc(b"1S1"), b'S'); // the manual's chapter 4.5.1 example, device 1
/// ```
#[inline]
pub const fn bcc(bytes: &[u8]) -> u8 {
    let mut x = 0u8;
    let mut i = 0;
    while i < bytes.len() {
        x ^= bytes[i];
        i += 1;
    }
    x
}

/// An error of the codec: a value or telegram that cannot be encoded or decoded.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum WireError {
    /// An address outside 1..=32 (or 1..=31 where a drive's own address is meant).
    #[error("address {0} is out of range (drives 1..=31, broadcast 32)")]
    Address(u16),
    /// A P196 value that is not an ASCII operating mode.
    #[error("P196 = {value}: {reason}")]
    Mode {
        /// The value given.
        value: u32,
        /// Why it is refused.
        reason: &'static str,
    },
    /// The command string is longer than the drive's 40-character input buffer.
    #[error("command string of {0} characters is longer than the drive's input buffer (40)")]
    TooLong(usize),
    /// A character that cannot be sent inside an ASCII command.
    #[error("character 0x{0:02X} cannot be sent in a command (printable ASCII only)")]
    BadChar(u8),
    /// A number that does not fit its wire format.
    #[error(transparent)]
    Number(#[from] NumberError),
    /// The flags cannot be combined (such as buffering the execute character).
    #[error("{0}")]
    Flags(&'static str),
    /// A binary telegram that is not one of the manual's commands.
    #[error("binary telegram: {0}")]
    Binary(&'static str),
}

/// A device address on the bus: 1..=31 for one drive, 32 for all of them (broadcast).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Address(u8);

impl Address {
    /// The broadcast address 32.
    pub const BROADCAST: Address = Address(BROADCAST);

    /// Any address the wire allows: 1..=32.
    pub fn new(n: u8) -> Result<Self, WireError> {
        if (1..=BROADCAST).contains(&n) {
            Ok(Address(n))
        } else {
            Err(WireError::Address(n.into()))
        }
    }

    /// The address of one drive: 1..=31.
    pub fn drive(n: u8) -> Result<Self, WireError> {
        if (1..BROADCAST).contains(&n) {
            Ok(Address(n))
        } else {
            Err(WireError::Address(n.into()))
        }
    }

    /// The address of drive `n` (1..=31) as a constant, for tables and patterns
    /// (`const D5: Address = Address::drive_const(5);`): out of range, it fails to compile where it is
    /// evaluated as a constant, and panics elsewhere. [`Address::drive`] is the checked form for input.
    pub const fn drive_const(n: u8) -> Address {
        assert!(n >= 1 && n < BROADCAST, "a drive address is 1..=31");
        Address(n)
    }

    /// The number.
    #[inline]
    pub const fn get(self) -> u8 {
        self.0
    }

    /// True for 32.
    pub const fn is_broadcast(self) -> bool {
        self.0 == BROADCAST
    }

    /// The ASCII digits of the address, as sent: (bytes, count).
    #[inline]
    pub fn digits(self) -> ([u8; 2], usize) {
        // A table of all 33 (0 never occurs): a load instead of a division.
        const DIGITS: [([u8; 2], usize); BROADCAST as usize + 1] = {
            let mut t = [([0u8; 2], 0usize); BROADCAST as usize + 1];
            let mut a = 0;
            while a <= BROADCAST {
                t[a as usize] = if a >= 10 { ([b'0' + a / 10, b'0' + a % 10], 2) } else { ([b'0' + a, 0], 1) };
                a += 1;
            }
            t
        };
        DIGITS[usize::from(self.0.min(BROADCAST))]
    }
}

/// The number.
impl serde::Serialize for Address {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_u8(self.0)
    }
}

impl fmt::Display for Address {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.0)
    }
}

/// How a reply ends (P196 valence 32).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ReplyEnd {
    /// `CR LF >` (valence 0, the default).
    CrLfPrompt,
    /// `CR` alone (valence 32).
    Cr,
}

/// The RS485 operating mode, parameter P196, as one typed setting.
///
/// P196 is a sum of valences: 1 XON/XOFF, 2 parity on, 4 even parity (odd without it), 8 BCC, 16 timeout
/// supervision, 32 reply ends with CR alone, 64 reply starts with the drive's address.
///
/// ```
/// use motionlink_compax::wire::{Mode, ReplyEnd, Parity};
/// let m = Mode::from_p196(8 + 64).unwrap();
/// assert!(m.bcc && m.reply_address && !m.xon_xoff);
/// assert_eq!(m.parity, Parity::None);
/// assert_eq!(m.reply_end, ReplyEnd::CrLfPrompt);
/// assert_eq!(m.to_p196(), 72);
/// assert!(Mode::from_p196(164).is_err()); // the COMTAC fieldbus protocol, not ASCII
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Mode {
    /// Software handshake XON/XOFF (valence 1).
    pub xon_xoff: bool,
    /// Parity bit (valences 2 and 4).
    pub parity: Parity,
    /// Block-check character after each telegram, both directions (valence 8).
    pub bcc: bool,
    /// The drive answers E73 after five character times of silence inside a telegram (valence 16).
    pub timeout_supervision: bool,
    /// How replies end (valence 32).
    pub reply_end: ReplyEnd,
    /// Replies start with the drive's address (valence 64).
    pub reply_address: bool,
}

impl Default for Mode {
    /// P196 = 0: no handshake, no parity, no BCC, no supervision, replies end `CR LF >`, no address.
    fn default() -> Self {
        Mode {
            xon_xoff: false,
            parity: Parity::None,
            bcc: false,
            timeout_supervision: false,
            reply_end: ReplyEnd::CrLfPrompt,
            reply_address: false,
        }
    }
}

impl Mode {
    /// The largest ASCII operating mode: every valence set.
    pub const MAX_P196: u32 = 127;

    /// The P196 values that select the COMTAC fieldbus protocol (option F5, manual 3.3.2): no ASCII mode.
    pub const FIELDBUS_P196: &'static [u32] = &[164, 165];

    /// Decodes P196. 0..=127 are ASCII modes; 164 and 165 select the COMTAC fieldbus protocol, which this
    /// crate does not speak. The valence 4 (even) without 2 (parity on) means no parity.
    pub fn from_p196(value: u32) -> Result<Mode, WireError> {
        if Self::FIELDBUS_P196.contains(&value) {
            return Err(WireError::Mode { value, reason: "the COMTAC fieldbus protocol (option F5) is not ASCII" });
        }
        if value > Self::MAX_P196 {
            return Err(WireError::Mode { value, reason: "not a sum of the valences 1, 2, 4, 8, 16, 32, 64" });
        }
        let parity = match (value & 2 != 0, value & 4 != 0) {
            (false, _) => Parity::None,
            (true, false) => Parity::Odd,
            (true, true) => Parity::Even,
        };
        Ok(Mode {
            xon_xoff: value & 1 != 0,
            parity,
            bcc: value & 8 != 0,
            timeout_supervision: value & 16 != 0,
            reply_end: if value & 32 != 0 { ReplyEnd::Cr } else { ReplyEnd::CrLfPrompt },
            reply_address: value & 64 != 0,
        })
    }

    /// The P196 value of this mode (the even valence only with parity on).
    pub fn to_p196(&self) -> u32 {
        let mut v = 0;
        if self.xon_xoff {
            v += 1;
        }
        match self.parity {
            Parity::None => {}
            Parity::Odd => v += 2,
            Parity::Even => v += 6,
        }
        if self.bcc {
            v += 8;
        }
        if self.timeout_supervision {
            v += 16;
        }
        if self.reply_end == ReplyEnd::Cr {
            v += 32;
        }
        if self.reply_address {
            v += 64;
        }
        v
    }
}

impl fmt::Display for Mode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "P196={} (", self.to_p196())?;
        let mut parts: [&str; 6] = [""; 6];
        let mut n = 0;
        let mut push = |s: &'static str| {
            parts[n] = s;
            n += 1;
        };
        if self.xon_xoff {
            push("XON/XOFF");
        }
        match self.parity {
            Parity::None => {}
            Parity::Odd => push("odd parity"),
            Parity::Even => push("even parity"),
        }
        if self.bcc {
            push("BCC");
        }
        if self.timeout_supervision {
            push("timeout supervision");
        }
        push(if self.reply_end == ReplyEnd::Cr { "reply ends CR" } else { "reply ends CR LF >" });
        if self.reply_address {
            push("reply with address");
        }
        write!(f, "{})", parts[..n].join(", "))
    }
}

/// Bytes of one telegram, built without allocation.
#[derive(Clone, Copy)]
pub struct Frame {
    buf: [u8; FRAME_CAPACITY],
    len: usize,
}

impl PartialEq for Frame {
    /// Equal bytes (the buffer after them does not count).
    fn eq(&self, other: &Self) -> bool {
        self.as_bytes() == other.as_bytes()
    }
}

impl Eq for Frame {}

impl Default for Frame {
    fn default() -> Self {
        Frame { buf: [0; FRAME_CAPACITY], len: 0 }
    }
}

impl fmt::Debug for Frame {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Frame({:?})", EscapedBytes(self.as_bytes()))
    }
}

impl Frame {
    /// The telegram's bytes.
    #[inline]
    pub fn as_bytes(&self) -> &[u8] {
        &self.buf[..self.len]
    }

    /// Number of bytes.
    #[inline]
    pub fn len(&self) -> usize {
        self.len
    }

    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    #[inline]
    pub(crate) fn push(&mut self, b: u8) -> Result<(), WireError> {
        if self.len >= FRAME_CAPACITY {
            return Err(WireError::TooLong(self.len));
        }
        self.buf[self.len] = b;
        self.len += 1;
        Ok(())
    }

    #[inline]
    pub(crate) fn extend(&mut self, bytes: &[u8]) -> Result<(), WireError> {
        bytes.iter().try_for_each(|&b| self.push(b))
    }
}

/// A small fixed-capacity text buffer for command strings and values, usable with `write!`.
#[derive(Clone, Copy)]
pub struct TextBuf<const N: usize> {
    buf: [u8; N],
    len: usize,
    overflow: bool,
}

impl<const N: usize> Default for TextBuf<N> {
    fn default() -> Self {
        TextBuf { buf: [0; N], len: 0, overflow: false }
    }
}

impl<const N: usize> TextBuf<N> {
    /// An empty buffer.
    pub fn new() -> Self {
        Self::default()
    }

    /// Sets the text to the first `len` of `bytes`, which must be ASCII (as `str` they are UTF-8) and fit.
    #[inline]
    pub(crate) fn set_ascii<const M: usize>(&mut self, bytes: [u8; M], len: usize) {
        debug_assert!(bytes.is_ascii() && M <= N);
        self.buf[..M].copy_from_slice(&bytes);
        self.len = len.min(M);
        self.overflow = false;
    }

    /// The bytes written so far.
    #[inline]
    pub fn as_bytes(&self) -> &[u8] {
        &self.buf[..self.len]
    }

    /// The text written so far (always valid UTF-8: only `str` is written into it).
    #[inline]
    pub fn as_str(&self) -> &str {
        std::str::from_utf8(self.as_bytes()).unwrap_or("")
    }

    /// True if a write did not fit.
    pub fn overflowed(&self) -> bool {
        self.overflow
    }

    /// Forgets the text.
    pub fn clear(&mut self) {
        self.len = 0;
        self.overflow = false;
    }

    /// Shortens the text to `len` bytes.
    pub fn truncate(&mut self, len: usize) {
        self.len = self.len.min(len);
    }
}

impl<const N: usize> fmt::Write for TextBuf<N> {
    #[inline]
    fn write_str(&mut self, s: &str) -> fmt::Result {
        let b = s.as_bytes();
        if self.len + b.len() > N {
            self.overflow = true;
            return Err(fmt::Error);
        }
        self.buf[self.len..self.len + b.len()].copy_from_slice(b);
        self.len += b.len();
        Ok(())
    }
}

impl<const N: usize> PartialEq for TextBuf<N> {
    fn eq(&self, other: &Self) -> bool {
        self.as_bytes() == other.as_bytes()
    }
}

impl<const N: usize> fmt::Debug for TextBuf<N> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Debug::fmt(self.as_str(), f)
    }
}

impl<const N: usize> fmt::Display for TextBuf<N> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// Shows bytes as text with control and non-ASCII bytes escaped (`<CR>`, `<LF>`, `<0x53>`).
pub struct EscapedBytes<'a>(pub &'a [u8]);

impl fmt::Display for EscapedBytes<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for &b in self.0 {
            match b {
                CR => f.write_str("<CR>")?,
                LF => f.write_str("<LF>")?,
                XON => f.write_str("<XON>")?,
                XOFF => f.write_str("<XOFF>")?,
                0x20..=0x7E => fmt::Write::write_char(f, b as char)?,
                _ => write!(f, "<0x{b:02X}>")?,
            }
        }
        Ok(())
    }
}

impl fmt::Debug for EscapedBytes<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "\"{self}\"")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bcc_of_the_manuals_example() {
        // Chapter 4.5.1: text$ = "1S1" and "5S1", BCC = XOR of the characters.
        assert_eq!(bcc(b"1S1"), 0x31 ^ 0x53 ^ 0x31);
        assert_eq!(bcc(b"1S1"), 0x53);
        assert_eq!(bcc(b"5S1"), 0x57);
        assert_eq!(bcc(b""), 0);
    }

    #[test]
    fn every_p196_combination_round_trips() {
        for v in 0..=Mode::MAX_P196 {
            let m = Mode::from_p196(v).unwrap();
            assert_eq!(m.xon_xoff, v & 1 != 0, "{v}");
            assert_eq!(m.bcc, v & 8 != 0, "{v}");
            assert_eq!(m.timeout_supervision, v & 16 != 0, "{v}");
            assert_eq!(m.reply_end == ReplyEnd::Cr, v & 32 != 0, "{v}");
            assert_eq!(m.reply_address, v & 64 != 0, "{v}");
            let want_parity = match v & 6 {
                0 | 4 => Parity::None,
                2 => Parity::Odd,
                _ => Parity::Even,
            };
            assert_eq!(m.parity, want_parity, "{v}");
            // Decision: "even" (4) without "parity on" (2) means no parity and is normalised away.
            let normal = if v & 6 == 4 { v - 4 } else { v };
            assert_eq!(m.to_p196(), normal, "{v}");
            assert_eq!(Mode::from_p196(m.to_p196()).unwrap(), m);
        }
    }

    #[test]
    fn fieldbus_and_out_of_range_modes_are_refused() {
        for v in [128, 164, 165, 200, 1000] {
            assert!(matches!(Mode::from_p196(v), Err(WireError::Mode { .. })), "{v}");
        }
    }

    #[test]
    fn addresses() {
        assert!(Address::new(0).is_err());
        assert!(Address::new(33).is_err());
        assert!(Address::drive(32).is_err());
        assert!(Address::new(32).unwrap().is_broadcast());
        assert_eq!(Address::new(5).unwrap().digits(), ([b'5', 0], 1));
        assert_eq!(Address::new(31).unwrap().digits(), ([b'3', b'1'], 2));
    }
}
