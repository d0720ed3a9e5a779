//! CAN frames and CAN links: SocketCAN, SLCAN serial adapters, and an in-memory bus with bit-time pacing.
//! (Built with the PowerCube family.)
//!
//! - [`CanFrame`]: one classic CAN 2.0 frame (11- or 29-bit identifier, 0..8 data bytes), its length on the
//!   wire in bits, and the `candump` text forms.
//! - [`CanLink`]: a frame link: send a frame, wait for a frame with a timeout.
//! - [`CanEmulator`]: a sans-IO device on a CAN bus (frames in, time passing, frames out).
//! - [`bus`]: an in-memory bus, paced at a bit rate, with an optional emulated device on it.
//! - [`slcan`]: the ASCII protocol of serial CAN adapters, as a codec, as a [`CanLink`] over any byte
//!   [`Link`](crate::link::Link), and as an adapter that serves a [`CanEmulator`] on a byte stream.
//! - [`embedded`]: the `embedded-can` traits, so any embedded-can driver is a [`CanLink`].
//! - `socketcan` (Linux): a [`CanLink`] on a SocketCAN interface such as `can0`.
//!
//! ```
//! use motionlink_link::can::CanFrame;
//! let f = CanFrame::new(0x0F1, &[0x01]).unwrap();
//! assert_eq!(f.to_string(), "0F1#01");
//! assert_eq!("0F1#01".parse::<CanFrame>().unwrap(), f);
//! // 47 bits of frame overhead plus 8 per data byte, before bit stuffing.
//! assert_eq!(f.bit_length(), 55);
//! ```

pub mod bus;
pub mod embedded;
pub mod slcan;
#[cfg(target_os = "linux")]
pub mod socketcan;

use std::fmt;
use std::str::FromStr;
use std::time::Duration;

use crate::clock::Timestamp;
use crate::link::LinkError;

pub use bus::{CanBus, CanBusConfig, CanBusLink, NoDevice};
pub use slcan::{SlcanAdapter, SlcanBitrate, SlcanLink};

/// The largest 11-bit identifier.
pub const MAX_STANDARD_ID: u32 = 0x7FF;
/// The largest 29-bit identifier.
pub const MAX_EXTENDED_ID: u32 = 0x1FFF_FFFF;

/// Why a [`CanFrame`] could not be made or parsed.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum CanFrameError {
    /// The identifier does not fit 11 (or 29) bits.
    #[error("CAN identifier {id:#X} does not fit {bits} bits")]
    IdTooLarge {
        /// The identifier given.
        id: u32,
        /// 11 or 29.
        bits: u8,
    },
    /// More than 8 data bytes.
    #[error("a CAN frame carries at most 8 data bytes, not {0}")]
    TooLong(usize),
    /// Text that is not a frame.
    #[error("not a CAN frame: {0}")]
    Syntax(String),
}

/// One classic CAN 2.0 frame: an 11-bit (standard) or 29-bit (extended) identifier, a data length code
/// 0..8 and up to 8 data bytes; or a remote frame (a request, no data).
///
/// `Copy` and without allocation: it is what every CAN link sends and receives.
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
pub struct CanFrame {
    id: u32,
    extended: bool,
    remote: bool,
    len: u8,
    data: [u8; 8],
}

impl CanFrame {
    /// A data frame with an 11-bit identifier.
    pub fn new(id: u32, data: &[u8]) -> Result<Self, CanFrameError> {
        Self::build(id, false, false, data.len(), data)
    }

    /// A data frame with a 29-bit identifier.
    pub fn new_extended(id: u32, data: &[u8]) -> Result<Self, CanFrameError> {
        Self::build(id, true, false, data.len(), data)
    }

    /// A remote (request) frame with data length code `dlc` and no data.
    pub fn new_remote(id: u32, extended: bool, dlc: u8) -> Result<Self, CanFrameError> {
        Self::build(id, extended, true, usize::from(dlc), &[])
    }

    fn build(id: u32, extended: bool, remote: bool, len: usize, data: &[u8]) -> Result<Self, CanFrameError> {
        let (max, bits) = if extended { (MAX_EXTENDED_ID, 29) } else { (MAX_STANDARD_ID, 11) };
        if id > max {
            return Err(CanFrameError::IdTooLarge { id, bits });
        }
        if len > 8 {
            return Err(CanFrameError::TooLong(len));
        }
        let mut buf = [0u8; 8];
        buf[..data.len()].copy_from_slice(data);
        Ok(CanFrame { id, extended, remote, len: len as u8, data: buf })
    }

    /// The identifier (11 or 29 bits).
    pub fn id(&self) -> u32 {
        self.id
    }

    /// True for a 29-bit identifier.
    pub fn is_extended(&self) -> bool {
        self.extended
    }

    /// True for a remote (request) frame.
    pub fn is_remote(&self) -> bool {
        self.remote
    }

    /// The data length code, 0..8.
    pub fn dlc(&self) -> u8 {
        self.len
    }

    /// The data bytes (empty for a remote frame).
    pub fn data(&self) -> &[u8] {
        if self.remote {
            &[]
        } else {
            &self.data[..usize::from(self.len)]
        }
    }

    /// The frame's length on the wire in bits, without stuff bits: start of frame, arbitration field,
    /// control field, data, CRC field, acknowledge field, end of frame and the 3-bit intermission. That is
    /// 47 + 8 × DLC for an 11-bit identifier and 67 + 8 × DLC for a 29-bit one (a remote frame carries no
    /// data bits).
    pub fn bit_length(&self) -> u32 {
        let overhead = if self.extended { 67 } else { 47 };
        overhead + 8 * self.data().len() as u32
    }

    /// The longest the frame can be with bit stuffing: one stuff bit per 4 bits of the stuffed part
    /// (start of frame up to the CRC sequence), at worst.
    pub fn bit_length_worst_case(&self) -> u32 {
        let stuffed = if self.extended { 54 } else { 34 } + 8 * self.data().len() as u32;
        self.bit_length() + (stuffed - 1) / 4
    }
}

impl fmt::Debug for CanFrame {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "CanFrame({self})")
    }
}

/// The compact `candump`/`cansend` form: `0F1#01020304`, `12345678#` (extended), `0D1#R2` (remote).
impl fmt::Display for CanFrame {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.extended {
            write!(f, "{:08X}#", self.id)?;
        } else {
            write!(f, "{:03X}#", self.id)?;
        }
        if self.remote {
            return write!(f, "R{}", self.len);
        }
        for b in self.data() {
            write!(f, "{b:02X}")?;
        }
        Ok(())
    }
}

impl FromStr for CanFrame {
    type Err = CanFrameError;

    /// Parses the compact form `ID#DATA` (`0F1#01`, `0F1#01.02`, `1ABCDEF0#`, `0D1#R`, `0D1#R2`). Three hex
    /// digits or fewer make an 11-bit identifier, more make a 29-bit one.
    fn from_str(s: &str) -> Result<Self, CanFrameError> {
        let bad = |why: &str| CanFrameError::Syntax(format!("{s:?}: {why}"));
        let (id_text, data_text) = s.trim().split_once('#').ok_or_else(|| bad("expected ID#DATA"))?;
        if id_text.is_empty() || id_text.len() > 8 || !id_text.chars().all(|c| c.is_ascii_hexdigit()) {
            return Err(bad("the identifier must be 1 to 8 hex digits"));
        }
        let id = u32::from_str_radix(id_text, 16).map_err(|_| bad("bad identifier"))?;
        let extended = id_text.len() > 3;
        if let Some(rest) = data_text.strip_prefix('R').or_else(|| data_text.strip_prefix('r')) {
            let dlc = if rest.is_empty() {
                0
            } else {
                rest.parse::<u8>().map_err(|_| bad("a remote frame's length must be a digit 0..8"))?
            };
            return Self::new_remote(id, extended, dlc);
        }
        let digits: Vec<u8> = data_text.bytes().filter(|&b| b != b'.').collect();
        if digits.len() % 2 != 0 || !digits.iter().all(u8::is_ascii_hexdigit) {
            return Err(bad("the data must be pairs of hex digits"));
        }
        if digits.len() > 16 {
            return Err(CanFrameError::TooLong(digits.len() / 2));
        }
        let mut data = [0u8; 8];
        for (i, pair) in digits.chunks(2).enumerate() {
            data[i] = (hex_val(pair[0]) << 4) | hex_val(pair[1]);
        }
        Self::build(id, extended, false, digits.len() / 2, &data[..digits.len() / 2])
    }
}

/// The value of one ASCII hex digit (0 for anything else; callers check first).
pub(crate) fn hex_val(c: u8) -> u8 {
    match c {
        b'0'..=b'9' => c - b'0',
        b'a'..=b'f' => c - b'a' + 10,
        b'A'..=b'F' => c - b'A' + 10,
        _ => 0,
    }
}

/// One line of a `candump` capture, in either of its usual forms:
///
/// - log form (`candump -l`, `candump -L`): `(1700000000.000000) can0 0F1#01`
/// - screen form (`candump can0`): `  can0  0F1   [1]  01`
///
/// ```
/// use motionlink_link::can::CandumpLine;
/// let line: CandumpLine = "(1700000000.250000) can0 0B1#0A3C0000803F".parse().unwrap();
/// assert_eq!(line.interface.as_deref(), Some("can0"));
/// assert_eq!(line.timestamp.unwrap().as_millis(), 1_700_000_000_250);
/// assert_eq!(line.frame.id(), 0x0B1);
/// let screen: CandumpLine = "  can0  0F1   [1]  01".parse().unwrap();
/// assert_eq!(screen.frame.data(), &[0x01]);
/// ```
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CandumpLine {
    /// The capture time (since the Unix epoch in a log), if the line has one.
    pub timestamp: Option<Duration>,
    /// The interface, if the line names one.
    pub interface: Option<String>,
    /// The frame.
    pub frame: CanFrame,
}

impl FromStr for CandumpLine {
    type Err = CanFrameError;

    fn from_str(s: &str) -> Result<Self, CanFrameError> {
        let bad = |why: &str| CanFrameError::Syntax(format!("{:?}: {why}", s.trim()));
        let mut words = s.split_whitespace().peekable();
        let mut timestamp = None;
        if let Some(first) = words.peek() {
            if let Some(inner) = first.strip_prefix('(').and_then(|w| w.strip_suffix(')')) {
                timestamp = Some(parse_seconds(inner).ok_or_else(|| bad("bad timestamp"))?);
                words.next();
            }
        }
        let rest: Vec<&str> = words.collect();
        match rest.as_slice() {
            [frame] if frame.contains('#') => Ok(CandumpLine { timestamp, interface: None, frame: frame.parse()? }),
            [iface, frame, ..] if frame.contains('#') => {
                Ok(CandumpLine { timestamp, interface: Some(iface.to_string()), frame: frame.parse()? })
            }
            [iface, id, len, data @ ..] if len.starts_with('[') && len.ends_with(']') => {
                let dlc: usize = len[1..len.len() - 1].parse().map_err(|_| bad("bad length in [ ]"))?;
                let compact = if data.first().is_some_and(|d| d.eq_ignore_ascii_case("remote")) {
                    format!("{id}#R{dlc}")
                } else {
                    if data.len() != dlc {
                        return Err(bad("the number of data bytes differs from the length in [ ]"));
                    }
                    format!("{id}#{}", data.concat())
                };
                Ok(CandumpLine { timestamp, interface: Some(iface.to_string()), frame: compact.parse()? })
            }
            _ => Err(bad("expected a candump line such as \"(1700000000.000000) can0 0F1#01\"")),
        }
    }
}

fn parse_seconds(text: &str) -> Option<Duration> {
    let (secs, frac) = text.split_once('.').unwrap_or((text, ""));
    let secs: u64 = secs.parse().ok()?;
    if frac.len() > 9 || !frac.chars().all(|c| c.is_ascii_digit()) {
        return None;
    }
    let nanos: u32 = if frac.is_empty() { 0 } else { format!("{frac:0<9}").parse().ok()? };
    Some(Duration::new(secs, nanos))
}

/// A link that carries CAN frames: a SocketCAN interface, a serial SLCAN adapter, an in-memory bus.
pub trait CanLink: Send {
    /// Puts `frame` on the bus.
    fn send(&mut self, frame: &CanFrame) -> Result<(), LinkError>;

    /// Waits up to `timeout` for a frame from the bus; `Ok(None)` on timeout.
    fn recv(&mut self, timeout: Duration) -> Result<Option<CanFrame>, LinkError>;

    /// Drops every frame received but not yet read.
    fn discard_input(&mut self) -> Result<(), LinkError> {
        while self.recv(Duration::ZERO)?.is_some() {}
        Ok(())
    }

    /// The port as a user would name it, for messages.
    fn describe(&self) -> String;
}

impl<L: CanLink + ?Sized> CanLink for Box<L> {
    fn send(&mut self, frame: &CanFrame) -> Result<(), LinkError> {
        (**self).send(frame)
    }
    fn recv(&mut self, timeout: Duration) -> Result<Option<CanFrame>, LinkError> {
        (**self).recv(timeout)
    }
    fn discard_input(&mut self) -> Result<(), LinkError> {
        (**self).discard_input()
    }
    fn describe(&self) -> String {
        (**self).describe()
    }
}

/// A device emulator on a CAN bus, sans-IO: frames in, time passing, frames out. It never reads a clock or
/// sleeps; the host that runs it ([`CanBus`], [`SlcanAdapter`]) tells it the time.
pub trait CanEmulator: Send {
    /// `frame` arrived at `now` (never earlier than a previous call's time). Append the answer to `out`.
    fn receive(&mut self, now: Timestamp, frame: &CanFrame, out: &mut Vec<CanFrame>);

    /// Time has reached `now` with nothing received. Append anything the device sends unasked to `out`.
    fn advance(&mut self, now: Timestamp, out: &mut Vec<CanFrame>);

    /// The next time at which [`CanEmulator::advance`] would do something observable, or `None`.
    fn next_wakeup(&self) -> Option<Timestamp>;

    /// What the device did since the last call, as [`Emulator::take_events`](crate::emulator::Emulator::take_events)
    /// describes; nothing by default.
    fn take_events(&mut self) -> Vec<String> {
        Vec::new()
    }
}

impl<E: CanEmulator + ?Sized> CanEmulator for Box<E> {
    fn receive(&mut self, now: Timestamp, frame: &CanFrame, out: &mut Vec<CanFrame>) {
        (**self).receive(now, frame, out)
    }
    fn advance(&mut self, now: Timestamp, out: &mut Vec<CanFrame>) {
        (**self).advance(now, out)
    }
    fn next_wakeup(&self) -> Option<Timestamp> {
        (**self).next_wakeup()
    }
    fn take_events(&mut self) -> Vec<String> {
        (**self).take_events()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_limits_are_checked() {
        assert!(matches!(CanFrame::new(0x800, &[]), Err(CanFrameError::IdTooLarge { bits: 11, .. })));
        assert!(CanFrame::new_extended(0x1FFF_FFFF, &[]).is_ok());
        assert!(matches!(CanFrame::new_extended(0x2000_0000, &[]), Err(CanFrameError::IdTooLarge { .. })));
        assert!(matches!(CanFrame::new(1, &[0; 9]), Err(CanFrameError::TooLong(9))));
        assert!(CanFrame::new_remote(1, false, 9).is_err());
    }

    #[test]
    fn bit_lengths_follow_the_dlc() {
        let get = CanFrame::new(0x0D1, &[0x0a, 0x3c]).unwrap();
        assert_eq!(get.bit_length(), 63);
        let ack = CanFrame::new(0x0B1, &[0; 6]).unwrap();
        assert_eq!(ack.bit_length(), 95);
        let ext = CanFrame::new_extended(0x100, &[0; 8]).unwrap();
        assert_eq!(ext.bit_length(), 131);
        // 8 data bytes, standard: 34 + 64 = 98 stuffed bits, at most 24 stuff bits.
        assert_eq!(CanFrame::new(1, &[0; 8]).unwrap().bit_length_worst_case(), 111 + 24);
        let remote = CanFrame::new_remote(0x0D1, false, 2).unwrap();
        assert_eq!(remote.bit_length(), 47);
    }

    #[test]
    fn compact_text_round_trips() {
        for text in ["0F1#01", "100#07", "0B1#0B0E0000803F0110", "12345678#", "0D1#R2", "7FF#R0"] {
            let f: CanFrame = text.parse().unwrap();
            assert_eq!(f.to_string(), text, "{text}");
        }
        assert_eq!("f1#0a.3c".parse::<CanFrame>().unwrap().to_string(), "0F1#0A3C");
        for bad in ["", "0F1", "#01", "0F1#0", "0F1#zz", "0F1#000000000000000000", "800#", "G00#"] {
            assert!(bad.parse::<CanFrame>().is_err(), "{bad}");
        }
    }

    #[test]
    fn candump_lines_in_both_forms() {
        let l: CandumpLine = "(1700000000.000000) can0 0F1#01".parse().unwrap();
        assert_eq!(l.timestamp, Some(Duration::from_secs(1_700_000_000)));
        assert_eq!(l.frame, CanFrame::new(0xF1, &[1]).unwrap());
        let l: CandumpLine = "  vcan0  0B1   [3]  08 50 64".parse().unwrap();
        assert_eq!(l.interface.as_deref(), Some("vcan0"));
        assert_eq!(l.frame.data(), &[0x08, 0x50, 0x64]);
        let l: CandumpLine = "  can0  0D1   [2]  remote request".parse().unwrap();
        assert!(l.frame.is_remote());
        assert!("  can0  0B1   [3]  08 50".parse::<CandumpLine>().is_err());
        assert!("(abc) can0 0F1#01".parse::<CandumpLine>().is_err());
        assert!("hello".parse::<CandumpLine>().is_err());
    }
}
