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

pub use bus::{CanBus, CanBusConfig, CanBusLink, NoDevice, StuffBits};
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

    /// The frame's real length on the wire in bits: [`CanFrame::bit_length`] plus the stuff bits this
    /// frame's own bits call for ([`CanFrame::stuff_bits`]). This is how long it occupies the bus.
    ///
    /// ```
    /// use motionlink_link::can::CanFrame;
    /// let f = CanFrame::new(0x0D1, &[0x0a, 0x3c]).unwrap();
    /// assert_eq!(f.bit_length(), 63);
    /// assert_eq!(f.bit_length_stuffed(), 63 + f.stuff_bits());
    /// assert!(f.bit_length_stuffed() <= f.bit_length_worst_case());
    /// ```
    pub fn bit_length_stuffed(&self) -> u32 {
        self.bit_length() + self.stuff_bits()
    }

    /// How many stuff bits the transmitter inserts into this frame (ISO 11898-1): after five consecutive
    /// bits of the same level, from the start of frame to the end of the CRC sequence, one bit of the
    /// opposite level, which itself counts towards the next run. Computed from the frame's real bit stream:
    /// start of frame, arbitration and control fields (SRR/IDE/r1/r0 for a 29-bit identifier), data, and
    /// the CRC-15 over all of them.
    pub fn stuff_bits(&self) -> u32 {
        let mut bits = BitStream::default();
        bits.push(0, 1); // start of frame
        if self.extended {
            bits.push(self.id >> 18, 11);
            bits.push(1, 1); // SRR
            bits.push(1, 1); // IDE
            bits.push(self.id & 0x3_FFFF, 18);
            bits.push(u32::from(self.remote), 1); // RTR
            bits.push(0, 2); // r1, r0
        } else {
            bits.push(self.id, 11);
            bits.push(u32::from(self.remote), 1); // RTR
            bits.push(0, 2); // IDE, r0
        }
        bits.push(u32::from(self.len), 4);
        for &b in self.data() {
            bits.push(u32::from(b), 8);
        }
        let crc = bits.crc;
        bits.push_unchecked(u32::from(crc), 15);
        bits.stuffed
    }
}

/// The stuffed part of a CAN frame as it is transmitted, bit by bit: the CRC-15 of what was pushed and the
/// stuff bits counted so far.
#[derive(Default)]
struct BitStream {
    crc: u16,
    run_level: u8,
    run_length: u32,
    stuffed: u32,
}

impl BitStream {
    /// CRC-15/CAN: polynomial 0x4599, initial value 0.
    const CRC15_POLY: u16 = 0x4599;

    /// Appends the `count` low bits of `value`, most significant first, and runs them through the CRC.
    fn push(&mut self, value: u32, count: u32) {
        for i in (0..count).rev() {
            let bit = ((value >> i) & 1) as u16;
            let feedback = bit ^ ((self.crc >> 14) & 1);
            self.crc = (self.crc << 1) & 0x7FFF;
            if feedback == 1 {
                self.crc ^= Self::CRC15_POLY;
            }
            self.stuff(bit as u8);
        }
    }

    /// Appends bits that are not part of the CRC (the CRC sequence itself).
    fn push_unchecked(&mut self, value: u32, count: u32) {
        for i in (0..count).rev() {
            self.stuff(((value >> i) & 1) as u8);
        }
    }

    fn stuff(&mut self, bit: u8) {
        if self.run_length > 0 && bit == self.run_level {
            self.run_length += 1;
        } else {
            self.run_level = bit;
            self.run_length = 1;
        }
        if self.run_length == 5 {
            // The stuff bit has the other level and starts a new run of one.
            self.stuffed += 1;
            self.run_level ^= 1;
            self.run_length = 1;
        }
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
    fn the_crc_is_crc15_can() {
        // The catalogued check value of CRC-15/CAN over "123456789".
        let mut bits = BitStream::default();
        for b in b"123456789" {
            bits.push(u32::from(*b), 8);
        }
        assert_eq!(bits.crc, 0x059E);
    }

    #[test]
    fn stuff_bits_follow_the_frames_own_bits() {
        // Identifier 0, DLC 0: 19 dominant bits (SOF, 11 identifier bits, RTR, IDE, r0, 4 DLC bits), then a
        // CRC of 0 (15 more dominant bits). 34 zeros get a recessive stuff bit after every 5 of them (the
        // stuff bit is a run of its own level): 6 stuff bits. The worst case (8) needs runs that continue
        // through the stuff bits: 00000 s=1 1111 s=0 0000 ...
        let zero = CanFrame::new(0x000, &[]).unwrap();
        assert_eq!(zero.stuff_bits(), 6);
        assert_eq!(zero.bit_length_stuffed(), 47 + 6);
        assert_eq!(zero.bit_length_worst_case(), 47 + 8);
        // Alternating bits need no stuffing at all where they alternate: 0x555 keeps SOF 0 then 1010...
        let alt = CanFrame::new(0x555, &[0x55, 0x55]).unwrap();
        assert!(alt.stuff_bits() <= 3, "{}", alt.stuff_bits());
        // Never more than the worst case, for every DLC and some identifiers, both formats.
        for id in [0x000, 0x0A1, 0x0C1, 0x100, 0x3FF, 0x7FF] {
            for n in 0..=8usize {
                for fill in [0x00u8, 0xFF, 0x0F, 0xAA, 0x3C] {
                    let data = vec![fill; n];
                    for f in [CanFrame::new(id, &data).unwrap(), CanFrame::new_extended(id << 10, &data).unwrap()] {
                        assert!(f.bit_length_stuffed() <= f.bit_length_worst_case(), "{f}");
                        assert!(f.bit_length_stuffed() >= f.bit_length(), "{f}");
                    }
                }
            }
        }
        // The CRC-15 of the bit stream is part of the count: two frames that differ in one data bit can
        // differ in their stuffing beyond that bit.
        let a = CanFrame::new(0x0B1, &[0x0a, 0x3c, 0, 0, 0x80, 0x3f]).unwrap();
        assert_eq!(a.bit_length(), 95);
        assert!(a.stuff_bits() > 0 && a.stuff_bits() <= 20, "{}", a.stuff_bits());
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
