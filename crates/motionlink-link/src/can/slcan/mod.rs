//! SLCAN (the Lawicel "CAN232" ASCII protocol) spoken by serial CAN adapters: CANable, USBtin, CAN232 and
//! their clones.
//!
//! Every message is one line of ASCII ended by a carriage return:
//!
//! | host to adapter | meaning | adapter answers |
//! |---|---|---|
//! | `S0`..`S8` | bit rate 10k, 20k, 50k, 100k, 125k, 250k, 500k, 800k, 1M | `\r` |
//! | `O` / `L` / `C` | open the channel / open listen-only / close it | `\r` |
//! | `tIIILDD..` | send a data frame, 11-bit id, length L, data | `z\r` |
//! | `TIIIIIIIILDD..` | send a data frame, 29-bit id | `Z\r` |
//! | `rIIIL` / `RIIIIIIIIL` | send a remote frame | `z\r` / `Z\r` |
//! | `V` / `N` / `F` | version / serial number / status flags | `Vhhss\r` / `Nxxxx\r` / `Fxx\r` |
//! | `Z0` / `Z1` | time stamps off / on | `\r` |
//!
//! A refused command is answered by a bell (0x07). Received frames come as `t`/`T`/`r`/`R` lines, with four
//! more hex digits (a millisecond time stamp, 0..59999) when time stamps are on.
//!
//! Three things live here: the codec ([`encode_frame`], [`SlcanDecoder`]), a [`CanLink`] over any byte
//! [`Link`] ([`SlcanLink`]) and an [`Emulator`](crate::emulator::Emulator) that serves a [`CanEmulator`](crate::can::CanEmulator) as if it sat behind a serial
//! adapter ([`SlcanAdapter`]), so the CAN path can run end to end over a pty.

use std::collections::VecDeque;
use std::time::Duration;

use super::{hex_val, CanFrame, CanLink};
use crate::clock::SharedClock;
use crate::link::{Link, LinkError};

/// The longest SLCAN line: `T`, 8 id digits, 1 length digit, 16 data digits, 4 time-stamp digits, `\r`.
pub const MAX_LINE: usize = 31;

/// The carriage return that ends every line.
pub const CR: u8 = b'\r';
/// The bell that answers a refused command.
pub const BELL: u8 = 0x07;

/// The standard bit rates of the `Sn` command.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SlcanBitrate {
    /// `S0`: 10 kbit/s.
    K10,
    /// `S1`: 20 kbit/s.
    K20,
    /// `S2`: 50 kbit/s.
    K50,
    /// `S3`: 100 kbit/s.
    K100,
    /// `S4`: 125 kbit/s.
    K125,
    /// `S5`: 250 kbit/s.
    K250,
    /// `S6`: 500 kbit/s.
    K500,
    /// `S7`: 800 kbit/s.
    K800,
    /// `S8`: 1 Mbit/s.
    M1,
}

impl SlcanBitrate {
    const ALL: [(SlcanBitrate, u32); 9] = [
        (SlcanBitrate::K10, 10_000),
        (SlcanBitrate::K20, 20_000),
        (SlcanBitrate::K50, 50_000),
        (SlcanBitrate::K100, 100_000),
        (SlcanBitrate::K125, 125_000),
        (SlcanBitrate::K250, 250_000),
        (SlcanBitrate::K500, 500_000),
        (SlcanBitrate::K800, 800_000),
        (SlcanBitrate::M1, 1_000_000),
    ];

    /// The setting for `bits_per_second`, if it is one of the standard rates.
    pub fn from_bps(bits_per_second: u32) -> Option<Self> {
        Self::ALL.iter().find(|(_, b)| *b == bits_per_second).map(|(r, _)| *r)
    }

    /// Bits per second.
    pub fn bps(self) -> u32 {
        Self::ALL.iter().find(|(r, _)| *r == self).map_or(0, |(_, b)| *b)
    }

    /// The digit of the `Sn` command.
    pub fn digit(self) -> u8 {
        Self::ALL.iter().position(|(r, _)| *r == self).unwrap_or(0) as u8
    }

    fn from_digit(d: u8) -> Option<Self> {
        Self::ALL.get(usize::from(d)).map(|(r, _)| *r)
    }
}

/// One SLCAN line (or bell), decoded. Host commands and adapter answers share the syntax, so both
/// directions decode to this.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SlcanMessage {
    /// A frame (`t`, `T`, `r`, `R`), with the adapter's time stamp in ms if it sent one.
    Frame {
        /// The frame.
        frame: CanFrame,
        /// Milliseconds 0..59999, when time stamps are on.
        timestamp_ms: Option<u16>,
    },
    /// An empty line: the adapter's "OK".
    Ok,
    /// A bell: the adapter refused the last command.
    Bell,
    /// `z` or `Z`: the adapter has queued a frame for sending.
    Sent {
        /// `Z`: an extended frame.
        extended: bool,
    },
    /// `Sn`: set the bit rate.
    Bitrate(SlcanBitrate),
    /// `O`: open the channel.
    Open,
    /// `L`: open the channel listen-only.
    ListenOnly,
    /// `C`: close the channel.
    Close,
    /// `Z0` / `Z1`: time stamps off / on.
    Timestamps(bool),
    /// `V` (a question, `None`) or `Vhhss` (the answer).
    Version(Option<[u8; 4]>),
    /// `N` (a question) or `Nxxxx` (the answer).
    Serial(Option<[u8; 4]>),
    /// `F` (a question) or `Fxx` (the status flags).
    Status(Option<u8>),
    /// Any other command the adapter may know (`s`, `M`, `m`, `X`, ...), its letter kept; arguments dropped.
    Other(u8),
}

/// A malformed SLCAN line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum SlcanError {
    /// A line longer than any SLCAN message; skipped up to the next carriage return.
    #[error("SLCAN line longer than {MAX_LINE} characters (skipped)")]
    TooLong,
    /// A frame line whose digits or length do not add up.
    #[error("malformed SLCAN frame line starting with {0:?}")]
    BadFrame(char),
    /// A command line with arguments that make no sense.
    #[error("malformed SLCAN command {0:?}")]
    BadCommand(char),
}

/// Writes `frame` as an SLCAN line (with its carriage return) into `out`; returns the number of bytes.
///
/// ```
/// use motionlink_link::can::{slcan, CanFrame};
/// let mut buf = [0u8; slcan::MAX_LINE];
/// let n = slcan::encode_frame(&CanFrame::new(0x0F1, &[0x01]).unwrap(), &mut buf);
/// assert_eq!(&buf[..n], b"t0F1101\r");
/// ```
pub fn encode_frame(frame: &CanFrame, out: &mut [u8; MAX_LINE]) -> usize {
    const HEX: &[u8; 16] = b"0123456789ABCDEF";
    let mut n = 0;
    let (letter, digits) = match (frame.is_extended(), frame.is_remote()) {
        (false, false) => (b't', 3),
        (true, false) => (b'T', 8),
        (false, true) => (b'r', 3),
        (true, true) => (b'R', 8),
    };
    out[n] = letter;
    n += 1;
    for i in (0..digits).rev() {
        out[n] = HEX[((frame.id() >> (4 * i)) & 0xF) as usize];
        n += 1;
    }
    out[n] = b'0' + frame.dlc();
    n += 1;
    for b in frame.data() {
        out[n] = HEX[usize::from(b >> 4)];
        out[n + 1] = HEX[usize::from(b & 0xF)];
        n += 2;
    }
    out[n] = CR;
    n + 1
}

/// Decodes SLCAN lines from a byte stream, chunk by chunk, without allocating. Resynchronises at the next
/// carriage return after anything malformed.
#[derive(Debug, Clone)]
pub struct SlcanDecoder {
    line: [u8; MAX_LINE],
    len: usize,
    overflow: bool,
}

impl Default for SlcanDecoder {
    fn default() -> Self {
        Self::new()
    }
}

impl SlcanDecoder {
    /// A decoder at the start of a line.
    pub fn new() -> Self {
        SlcanDecoder { line: [0; MAX_LINE], len: 0, overflow: false }
    }

    /// Feeds one byte; returns a message or an error when a line (or a bell) is complete.
    pub fn push(&mut self, byte: u8) -> Option<Result<SlcanMessage, SlcanError>> {
        match byte {
            BELL => {
                self.len = 0;
                self.overflow = false;
                Some(Ok(SlcanMessage::Bell))
            }
            CR => {
                let result = if self.overflow { Err(SlcanError::TooLong) } else { parse_line(&self.line[..self.len]) };
                self.len = 0;
                self.overflow = false;
                Some(result)
            }
            b'\n' if self.len == 0 => None, // a terminal's line feed after CR
            _ => {
                if self.len < self.line.len() {
                    self.line[self.len] = byte;
                    self.len += 1;
                } else {
                    self.overflow = true;
                }
                None
            }
        }
    }

    /// Forgets a line received in part.
    pub fn reset(&mut self) {
        self.len = 0;
        self.overflow = false;
    }

    /// Feeds a chunk; yields every message or error it completes.
    pub fn feed<'a>(&'a mut self, chunk: &'a [u8]) -> impl Iterator<Item = Result<SlcanMessage, SlcanError>> + 'a {
        chunk.iter().filter_map(move |&b| self.push(b))
    }
}

fn hex_digits(text: &[u8]) -> Option<u32> {
    if text.is_empty() || !text.iter().all(u8::is_ascii_hexdigit) {
        return None;
    }
    Some(text.iter().fold(0u32, |acc, &c| (acc << 4) | u32::from(hex_val(c))))
}

fn parse_line(line: &[u8]) -> Result<SlcanMessage, SlcanError> {
    let Some((&letter, args)) = line.split_first() else { return Ok(SlcanMessage::Ok) };
    let bad_cmd = || SlcanError::BadCommand(char::from(letter));
    match letter {
        b't' | b'T' | b'r' | b'R' => parse_frame(letter, args),
        b'z' | b'Z' if args.is_empty() => Ok(SlcanMessage::Sent { extended: letter == b'Z' }),
        b'Z' => match args {
            b"0" => Ok(SlcanMessage::Timestamps(false)),
            b"1" => Ok(SlcanMessage::Timestamps(true)),
            _ => Err(bad_cmd()),
        },
        b'S' => match args {
            [d @ b'0'..=b'8'] => SlcanBitrate::from_digit(d - b'0').map(SlcanMessage::Bitrate).ok_or_else(bad_cmd),
            _ => Err(bad_cmd()),
        },
        b'O' if args.is_empty() => Ok(SlcanMessage::Open),
        b'L' if args.is_empty() => Ok(SlcanMessage::ListenOnly),
        b'C' if args.is_empty() => Ok(SlcanMessage::Close),
        b'V' | b'N' => {
            let value = match args {
                [] => None,
                [a, b, c, d] => Some([*a, *b, *c, *d]),
                _ => return Err(bad_cmd()),
            };
            Ok(if letter == b'V' { SlcanMessage::Version(value) } else { SlcanMessage::Serial(value) })
        }
        b'F' => match args {
            [] => Ok(SlcanMessage::Status(None)),
            [_, _] => hex_digits(args).map(|v| SlcanMessage::Status(Some(v as u8))).ok_or_else(bad_cmd),
            _ => Err(bad_cmd()),
        },
        c if c.is_ascii_alphabetic() => Ok(SlcanMessage::Other(c)),
        _ => Err(bad_cmd()),
    }
}

fn parse_frame(letter: u8, args: &[u8]) -> Result<SlcanMessage, SlcanError> {
    let bad = || SlcanError::BadFrame(char::from(letter));
    let extended = letter.is_ascii_uppercase();
    let remote = letter == b'r' || letter == b'R';
    let id_len = if extended { 8 } else { 3 };
    if args.len() < id_len + 1 {
        return Err(bad());
    }
    let id = hex_digits(&args[..id_len]).ok_or_else(bad)?;
    let dlc = match args[id_len] {
        d @ b'0'..=b'8' => d - b'0',
        _ => return Err(bad()),
    };
    let rest = &args[id_len + 1..];
    let data_digits = if remote { 0 } else { 2 * usize::from(dlc) };
    let timestamp_ms = match rest.len().checked_sub(data_digits) {
        Some(0) => None,
        Some(4) => Some(hex_digits(&rest[data_digits..]).ok_or_else(bad)? as u16),
        _ => return Err(bad()),
    };
    let frame = if remote {
        CanFrame::new_remote(id, extended, dlc).map_err(|_| bad())?
    } else {
        let mut data = [0u8; 8];
        for (i, pair) in rest[..data_digits].chunks(2).enumerate() {
            if !pair.iter().all(u8::is_ascii_hexdigit) {
                return Err(bad());
            }
            data[i] = (hex_val(pair[0]) << 4) | hex_val(pair[1]);
        }
        let data = &data[..usize::from(dlc)];
        if extended { CanFrame::new_extended(id, data) } else { CanFrame::new(id, data) }.map_err(|_| bad())?
    };
    Ok(SlcanMessage::Frame { frame, timestamp_ms })
}

// ---------------------------------------------------------------------------------------------------------
// Host side: a CAN link over a serial adapter

/// How long [`SlcanLink::open`] waits for the adapter to answer each setup command.
pub const SETUP_TIMEOUT: Duration = Duration::from_millis(500);

/// How many sent frames [`SlcanLink`] remembers while their answer (`z`, `Z`, an empty line or a bell) is
/// on its way; an adapter that never answers sends only makes it forget the oldest.
const MAX_AWAITING: usize = 64;

/// A [`CanLink`] through a serial SLCAN adapter on any byte [`Link`] (a serial port, a pty, TCP).
///
/// The adapter answers every frame it is given: `z` (`Z` for an extended frame; some firmware sends an
/// empty line) once queued, a bell (0x07) if it refuses it (channel closed, transmit queue full, bus off).
/// [`CanLink::send`] does not wait for that answer (waiting would cost a serial round trip per frame, up
/// to 16 ms on an FTDI-based adapter, and serialise a batch of requests); the answers are matched to the
/// frames in order, and a refusal is returned as a [`LinkError`] naming the refused frame by the next
/// [`CanLink::recv`], before any frame received: within the same exchange, so a caller waiting for an answer
/// learns at once that its frame never went out instead of waiting for a timeout.
pub struct SlcanLink<L> {
    inner: L,
    clock: SharedClock,
    decoder: SlcanDecoder,
    frames: VecDeque<CanFrame>,
    /// Frames sent whose answer has not come yet, oldest first.
    awaiting: VecDeque<CanFrame>,
    /// A refusal not reported yet: the refused frame, if known.
    refusal: Option<Option<CanFrame>>,
    /// Bells seen (refused frames).
    refused: u64,
    name: String,
}

impl<L: Link> SlcanLink<L> {
    /// Sets the adapter up: closes the channel (in case it was left open), sets the bit rate and opens the
    /// channel. Each command must be answered within [`SETUP_TIMEOUT`]; a bell or silence is an error.
    pub fn open(inner: L, clock: SharedClock, bitrate: SlcanBitrate) -> Result<Self, LinkError> {
        let mut link = Self::wrap(inner, clock);
        // A channel left open refuses the bit rate; a closed one may ring the bell at "C": both are fine.
        link.inner.send(b"C\r")?;
        if let Err(e @ LinkError::Busy { .. }) = link.expect_ok("C") {
            // A busy `motionlink sim powercube --slcan` refused the connection: no adapter to set up.
            return Err(e);
        }
        link.inner.discard_input()?;
        let cmd = [b'S', b'0' + bitrate.digit(), CR];
        link.inner.send(&cmd)?;
        link.expect_ok("S")?;
        link.inner.send(b"O\r")?;
        link.expect_ok("O")?;
        Ok(link)
    }

    /// Wraps an adapter whose channel is already open (no setup commands are sent).
    pub fn wrap(inner: L, clock: SharedClock) -> Self {
        let name = format!("slcan://{}", inner.describe());
        SlcanLink {
            inner,
            clock,
            decoder: SlcanDecoder::new(),
            frames: VecDeque::new(),
            awaiting: VecDeque::new(),
            refusal: None,
            refused: 0,
            name,
        }
    }

    /// Number of bells (refused frames) seen so far.
    pub fn refused(&self) -> u64 {
        self.refused
    }

    /// The underlying byte link.
    pub fn into_inner(self) -> L {
        self.inner
    }

    fn expect_ok(&mut self, what: &str) -> Result<(), LinkError> {
        let deadline = self.clock.now() + SETUP_TIMEOUT;
        let mut buf = [0u8; 64];
        loop {
            let now = self.clock.now();
            if now >= deadline {
                return Err(LinkError::Open {
                    port: self.name.clone(),
                    reason: format!("the adapter did not answer the {what} command (is it an SLCAN adapter?)"),
                });
            }
            let n = self.inner.recv(&mut buf, deadline - now)?;
            for &b in &buf[..n] {
                match self.decoder.push(b) {
                    Some(Ok(SlcanMessage::Ok)) => return Ok(()),
                    Some(Ok(SlcanMessage::Bell)) => {
                        return Err(LinkError::Open {
                            port: self.name.clone(),
                            reason: format!("the adapter refused the {what} command"),
                        })
                    }
                    Some(Ok(SlcanMessage::Frame { frame, .. })) => self.frames.push_back(frame),
                    _ => {}
                }
            }
        }
    }

    fn take_bytes(&mut self, bytes: &[u8]) {
        for &b in bytes {
            match self.decoder.push(b) {
                Some(Ok(SlcanMessage::Frame { frame, .. })) => self.frames.push_back(frame),
                Some(Ok(SlcanMessage::Sent { .. } | SlcanMessage::Ok)) => {
                    self.awaiting.pop_front();
                }
                Some(Ok(SlcanMessage::Bell)) => {
                    self.refused += 1;
                    let frame = self.awaiting.pop_front();
                    tracing::debug!("{}: the adapter refused {frame:?}", self.name);
                    // The first refusal is reported; later ones are counted.
                    self.refusal.get_or_insert(frame);
                }
                Some(Ok(_)) => {}
                Some(Err(e)) => tracing::debug!("{}: {e}", self.name),
                None => {}
            }
        }
    }

    fn refusal_error(&self, frame: Option<CanFrame>) -> LinkError {
        let what = frame.map_or_else(|| "a frame".to_string(), |f| f.to_string());
        LinkError::Io {
            port: self.name.clone(),
            source: std::sync::Arc::new(std::io::Error::other(format!(
                "the adapter refused to send {what} (it rang the bell: channel closed, transmit queue full or \
                 bus off)"
            ))),
        }
    }
}

impl<L: Link> CanLink for SlcanLink<L> {
    fn send(&mut self, frame: &CanFrame) -> Result<(), LinkError> {
        let mut line = [0u8; MAX_LINE];
        let n = encode_frame(frame, &mut line);
        self.inner.send(&line[..n])?;
        if self.awaiting.len() >= MAX_AWAITING {
            self.awaiting.pop_front();
        }
        self.awaiting.push_back(*frame);
        Ok(())
    }

    /// The next frame received; first, a [`LinkError`] if the adapter refused a frame sent earlier.
    fn recv(&mut self, timeout: Duration) -> Result<Option<CanFrame>, LinkError> {
        let deadline = self.clock.now() + timeout;
        let mut buf = [0u8; 256];
        loop {
            if let Some(frame) = self.refusal.take() {
                return Err(self.refusal_error(frame));
            }
            if let Some(f) = self.frames.pop_front() {
                return Ok(Some(f));
            }
            let now = self.clock.now();
            let wait = deadline.saturating_since(now);
            let n = self.inner.recv(&mut buf, wait)?;
            self.take_bytes(&buf[..n]);
            if n == 0 && self.clock.now() >= deadline && self.frames.is_empty() {
                return Ok(None);
            }
        }
    }

    /// Drops the frames received and not read. The answers to frames sent may be among the bytes dropped,
    /// so they are no longer expected; a refusal already seen is still reported.
    fn discard_input(&mut self) -> Result<(), LinkError> {
        self.frames.clear();
        self.awaiting.clear();
        self.inner.discard_input()
    }

    fn describe(&self) -> String {
        self.name.clone()
    }
}

// ---------------------------------------------------------------------------------------------------------
// Adapter side: a CAN emulator behind an emulated serial adapter

mod adapter;
pub use adapter::SlcanAdapter;

#[cfg(test)]
mod tests;
