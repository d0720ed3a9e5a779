//! The RS232 carrier: `STX TELID(2) data BCC ETX`, DLE-escaped between STX and ETX.
//!
//! - TELID byte 1: `0x04` (command to a module, TELID_SENDDAT) or `0x08` (answer, TELID_RECVDAT), with
//!   address bits 4..3 in bits 1..0; byte 2: address bits 2..0 in bits 7..5, the net data length in 3..0.
//! - BCC = `(s + (s >> 8)) & 0xFF`, `s` the 16-bit sum of both TELID bytes and the data, before escaping.
//! - 0x02, 0x03 and 0x10 between STX and ETX (TELID, data and BCC alike) are sent as 0x10 followed by the
//!   byte + 0x80.
//!
//! ```
//! use motionlink_powercube::wire::{rs232, Payload};
//! // The manual's Home to module 17.
//! let mut buf = [0u8; rs232::MAX_FRAME];
//! let n = rs232::encode(rs232::TelKind::Send, 17, &Payload::new(&[0x01]).unwrap(), &mut buf).unwrap();
//! assert_eq!(&buf[..n], &[0x02, 0x06, 0x21, 0x01, 0x28, 0x03]);
//!
//! let mut dec = rs232::Rs232Decoder::new();
//! let frames: Vec<_> = dec.feed(&[0x02, 0x0a, 0x21, 0x01, 0x2c, 0x03]).collect();
//! let ack = frames[0].as_ref().unwrap();
//! assert_eq!((ack.kind, ack.address, ack.payload.as_bytes()), (rs232::TelKind::Recv, 17, &[0x01][..]));
//! assert!(ack.bcc_ok());
//! ```

use super::{Payload, MAX_PAYLOAD};

/// Start of a frame.
pub const STX: u8 = 0x02;
/// End of a frame.
pub const ETX: u8 = 0x03;
/// Escape: the next byte is a special byte + 0x80.
pub const DLE: u8 = 0x10;

/// The longest frame on the line: STX, ETX, and 11 net bytes (TELID, 8 data, BCC) each possibly escaped.
pub const MAX_FRAME: usize = 24;

/// Net bytes between STX and ETX at most: TELID (2), data (8), BCC (1).
const MAX_NET: usize = 2 + MAX_PAYLOAD + 1;

/// Which way a frame goes, from its TELID.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum TelKind {
    /// TELID_SENDDAT: a command to a module.
    Send,
    /// TELID_RECVDAT: an answer from a module.
    Recv,
}

/// A malformed frame (or bytes between frames). The decoder has already resynchronised when it says so.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum Rs232Error {
    /// Bytes outside any frame, skipped up to the next STX.
    #[error("{0} byte(s) outside a frame skipped")]
    Garbage(usize),
    /// A new STX came before the ETX of the frame in progress: that frame is lost.
    #[error("frame cut short by a new STX")]
    Truncated,
    /// A DLE followed by something other than 0x82, 0x83 or 0x90.
    #[error("invalid DLE escape 0x10 0x{0:02X}")]
    BadEscape(u8),
    /// More net bytes than a frame can hold.
    #[error("frame longer than {MAX_FRAME} bytes")]
    TooLong,
    /// Fewer than 3 net bytes (TELID and BCC).
    #[error("frame too short ({0} net bytes)")]
    TooShort(usize),
    /// The TELID is neither a command nor an answer.
    #[error("invalid TELID {0:02X} {1:02X}")]
    BadTelId(u8, u8),
    /// An address outside 0..31 asked of the encoder.
    #[error("module address {0} is outside 0..31")]
    BadAddress(u8),
}

/// One decoded frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Rs232Frame {
    /// Command or answer.
    pub kind: TelKind,
    /// The module address from the TELID (0..31).
    pub address: u8,
    /// The length the TELID claims (0..15).
    pub declared_len: u8,
    /// The data actually received.
    pub payload: Payload,
    /// The BCC on the line.
    pub bcc_received: u8,
    /// The BCC of what was received.
    pub bcc_computed: u8,
}

impl Rs232Frame {
    /// True if the BCC on the line matches the frame.
    pub fn bcc_ok(&self) -> bool {
        self.bcc_received == self.bcc_computed
    }

    /// True if the TELID's length matches the data received.
    pub fn length_ok(&self) -> bool {
        usize::from(self.declared_len) == self.payload.len()
    }

    /// True for the manual's own slip: an acknowledge of 3 data bytes whose TELID says 6 (every RS232
    /// acknowledge example of chapter 9 prints it so). The client accepts it; any other mismatch is
    /// corruption the BCC let through.
    pub fn manual_length_slip(&self) -> bool {
        self.kind == TelKind::Recv && self.declared_len == 6 && self.payload.len() == 3
    }
}

/// The two TELID bytes for `kind`, `address` (0..31) and `len` (0..15).
#[inline]
pub fn telid(kind: TelKind, address: u8, len: u8) -> [u8; 2] {
    let high = match kind {
        TelKind::Send => 0x04,
        TelKind::Recv => 0x08,
    };
    [high | ((address >> 3) & 0x03), ((address & 0x07) << 5) | (len & 0x0F)]
}

/// Parses TELID bytes into (kind, address, declared length).
#[inline]
pub fn parse_telid(b1: u8, b2: u8) -> Result<(TelKind, u8, u8), Rs232Error> {
    let kind = match b1 & 0xFC {
        0x04 => TelKind::Send,
        0x08 => TelKind::Recv,
        _ => return Err(Rs232Error::BadTelId(b1, b2)),
    };
    if b2 & 0x10 != 0 {
        return Err(Rs232Error::BadTelId(b1, b2));
    }
    Ok((kind, ((b1 & 0x03) << 3) | (b2 >> 5), b2 & 0x0F))
}

/// The block check character over `bytes` (TELID and data): `(s + (s >> 8)) & 0xFF`, `s` the 16-bit sum.
#[inline]
pub fn bcc(bytes: &[u8]) -> u8 {
    fold_bcc(bytes.iter().fold(0u16, |s, &b| s.wrapping_add(u16::from(b))))
}

#[inline]
fn fold_bcc(s: u16) -> u8 {
    (s.wrapping_add(s >> 8) & 0xFF) as u8
}

/// Writes `b` at `n`, escaped if it must be; returns the next position. `n` is at most 21 here (STX and at
/// most 10 escaped bytes before), so both writes stay inside the 24 bytes.
#[inline(always)]
fn put_escaped(out: &mut [u8; MAX_FRAME], n: usize, b: u8) -> usize {
    if matches!(b, STX | ETX | DLE) {
        out[n] = DLE;
        out[n + 1] = b + 0x80;
        n + 2
    } else {
        out[n] = b;
        n + 1
    }
}

/// Encodes a frame with the true length and BCC; returns its length in `out`.
#[inline]
pub fn encode(kind: TelKind, address: u8, payload: &Payload, out: &mut [u8; MAX_FRAME]) -> Result<usize, Rs232Error> {
    if address > 31 {
        return Err(Rs232Error::BadAddress(address));
    }
    let id = telid(kind, address, payload.len() as u8);
    let sum = payload.as_bytes().iter().fold(u16::from(id[0]) + u16::from(id[1]), |s, &b| s + u16::from(b));
    Ok(encode_raw(id, payload, fold_bcc(sum), out))
}

/// Encodes a frame with the given TELID bytes and BCC, as they are (for tests and for replaying captures
/// with a wrong BCC or length).
#[inline]
pub fn encode_raw(telid: [u8; 2], payload: &Payload, bcc: u8, out: &mut [u8; MAX_FRAME]) -> usize {
    out[0] = STX;
    let mut n = put_escaped(out, 1, telid[0]);
    n = put_escaped(out, n, telid[1]);
    for &b in payload.as_bytes() {
        n = put_escaped(out, n, b);
    }
    n = put_escaped(out, n, bcc);
    out[n] = ETX;
    n + 1
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum State {
    /// Between frames; counts skipped bytes.
    Idle,
    /// Inside a frame.
    Frame,
    /// After a DLE inside a frame.
    Escape,
    /// Inside a frame that has grown too long; waiting for its end.
    Overflow,
}

/// Decodes frames from a byte stream, one chunk at a time, without allocating. Any garbage or broken frame
/// is reported as an [`Rs232Error`] and the decoder carries on at the next STX.
#[derive(Debug, Clone)]
pub struct Rs232Decoder {
    net: [u8; MAX_NET],
    len: usize,
    /// Sum of the net bytes stored so far (for the BCC).
    sum: u16,
    state: State,
    skipped: usize,
}

impl Default for Rs232Decoder {
    fn default() -> Self {
        Self::new()
    }
}

impl Rs232Decoder {
    /// A decoder waiting for an STX.
    pub fn new() -> Self {
        Rs232Decoder { net: [0; MAX_NET], len: 0, sum: 0, state: State::Idle, skipped: 0 }
    }

    /// Forgets any partial frame.
    pub fn reset(&mut self) {
        *self = Self::new();
    }

    /// Feeds one byte; returns a frame or an error when one completes.
    #[inline]
    pub fn push(&mut self, byte: u8) -> Option<Result<Rs232Frame, Rs232Error>> {
        // The common case first: an ordinary byte inside a frame.
        if self.state == State::Frame && !matches!(byte, STX | ETX | DLE) {
            return self.store(byte);
        }
        if byte == STX {
            let previous = self.state;
            let skipped = self.skipped;
            self.state = State::Frame;
            self.len = 0;
            self.sum = 0;
            self.skipped = 0;
            return match previous {
                State::Idle if skipped > 0 => Some(Err(Rs232Error::Garbage(skipped))),
                State::Idle => None,
                State::Overflow => Some(Err(Rs232Error::TooLong)),
                State::Frame | State::Escape => Some(Err(Rs232Error::Truncated)),
            };
        }
        match self.state {
            State::Idle => {
                self.skipped += 1;
                None
            }
            State::Overflow => {
                if byte == ETX {
                    self.state = State::Idle;
                    Some(Err(Rs232Error::TooLong))
                } else {
                    None
                }
            }
            State::Escape => match byte {
                0x82 | 0x83 | 0x90 => {
                    self.state = State::Frame;
                    self.store(byte - 0x80)
                }
                _ => {
                    // Whatever this byte was, the frame is broken: wait for the next STX.
                    self.state = State::Idle;
                    Some(Err(Rs232Error::BadEscape(byte)))
                }
            },
            State::Frame => match byte {
                DLE => {
                    self.state = State::Escape;
                    None
                }
                ETX => {
                    self.state = State::Idle;
                    Some(self.finish())
                }
                _ => self.store(byte),
            },
        }
    }

    #[inline(always)]
    fn store(&mut self, b: u8) -> Option<Result<Rs232Frame, Rs232Error>> {
        if self.len < MAX_NET {
            self.net[self.len] = b;
            self.len += 1;
            self.sum = self.sum.wrapping_add(u16::from(b));
        } else {
            self.state = State::Overflow;
        }
        None
    }

    #[inline]
    fn finish(&mut self) -> Result<Rs232Frame, Rs232Error> {
        let net = &self.net[..self.len];
        if net.len() < 3 {
            return Err(Rs232Error::TooShort(net.len()));
        }
        let (kind, address, declared_len) = parse_telid(net[0], net[1])?;
        let bcc_received = net[net.len() - 1];
        let payload = Payload::new(&net[2..net.len() - 1]).map_err(|_| Rs232Error::TooLong)?;
        let body_sum = self.sum.wrapping_sub(u16::from(bcc_received));
        Ok(Rs232Frame { kind, address, declared_len, payload, bcc_received, bcc_computed: fold_bcc(body_sum) })
    }

    /// Feeds a chunk; yields every frame or error it completes.
    #[inline]
    pub fn feed<'a>(&'a mut self, chunk: &'a [u8]) -> impl Iterator<Item = Result<Rs232Frame, Rs232Error>> + 'a {
        chunk.iter().filter_map(move |&b| self.push(b))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(kind: TelKind, address: u8, data: &[u8]) -> Vec<u8> {
        let mut buf = [0u8; MAX_FRAME];
        let n = encode(kind, address, &Payload::new(data).unwrap(), &mut buf).unwrap();
        buf[..n].to_vec()
    }

    #[test]
    fn telid_round_trips_every_address() {
        for address in 0..=31 {
            for len in 0..=8 {
                let [a, b] = telid(TelKind::Recv, address, len);
                assert_eq!(parse_telid(a, b), Ok((TelKind::Recv, address, len)));
            }
        }
        assert_eq!(telid(TelKind::Send, 17, 6), [0x06, 0x26]);
        assert!(parse_telid(0x0C, 0x21).is_err());
        assert!(parse_telid(0x06, 0x31).is_err());
    }

    #[test]
    fn escaping_covers_telid_data_and_bcc() {
        // Data with all three special bytes.
        let bytes = frame(TelKind::Send, 1, &[0x02, 0x03, 0x10]);
        assert_eq!(bytes, vec![0x02, 0x04, 0x23, 0x10, 0x82, 0x10, 0x83, 0x10, 0x90, 0x3c, 0x03]);
        let mut d = Rs232Decoder::new();
        let got: Vec<_> = d.feed(&bytes).collect();
        assert_eq!(got.len(), 1);
        let f = got[0].unwrap();
        assert_eq!(f.payload.as_bytes(), &[0x02, 0x03, 0x10]);
        assert!(f.bcc_ok() && f.length_ok());
        // A BCC that needs escaping: 0x04 + 0x21 + 0xEA = 0x10F, folded to 0x10.
        let data = [0xEA];
        let bytes = frame(TelKind::Send, 1, &data);
        assert_eq!(&bytes[bytes.len() - 3..], &[0x10, 0x90, 0x03]);
        assert!(Rs232Decoder::new().feed(&bytes).next().unwrap().unwrap().bcc_ok());
    }

    #[test]
    fn garbage_truncation_and_bad_escapes_resynchronise() {
        let good = frame(TelKind::Recv, 17, &[0x0a, 0x27, 1, 2, 3, 4]);
        let mut input = vec![0xAA, 0xBB];
        input.extend_from_slice(&good);
        input.extend_from_slice(&good[..5]); // cut short
        input.extend_from_slice(&good);
        input.extend_from_slice(&[STX, 0x08, DLE, 0x41, 0x00, ETX]); // bad escape
        input.extend_from_slice(&[STX, 0x08, ETX]); // too short
        input.extend_from_slice(&[STX, 0x0C, 0x21, 0x00, 0x2d, ETX]); // bad TELID
        input.push(STX);
        input.extend_from_slice(&[0x55; 30]); // too long
        input.push(ETX);
        input.extend_from_slice(&good);
        let got: Vec<_> = Rs232Decoder::new().feed(&input).collect();
        let expected_errors = [
            Some(Rs232Error::Garbage(2)),
            None,
            Some(Rs232Error::Truncated),
            None,
            Some(Rs232Error::BadEscape(0x41)),
            Some(Rs232Error::Garbage(2)),
            Some(Rs232Error::TooShort(1)),
            Some(Rs232Error::BadTelId(0x0C, 0x21)),
            Some(Rs232Error::TooLong),
            None,
        ];
        assert_eq!(got.len(), expected_errors.len(), "{got:?}");
        for (g, e) in got.iter().zip(expected_errors) {
            match e {
                Some(err) => assert_eq!(*g, Err(err)),
                None => assert_eq!(g.unwrap().payload.as_bytes(), &[0x0a, 0x27, 1, 2, 3, 4]),
            }
        }
    }

    #[test]
    fn a_wrong_bcc_and_a_wrong_length_are_reported_not_hidden() {
        let mut buf = [0u8; MAX_FRAME];
        // The manual's acknowledge with length 6 in the TELID for 3 bytes of data.
        let n = encode_raw([0x0a, 0x26], &Payload::new(&[0x08, 0x50, 0x64]).unwrap(), 0xec, &mut buf);
        let f = Rs232Decoder::new().feed(&buf[..n]).next().unwrap().unwrap();
        assert!(f.bcc_ok());
        assert!(!f.length_ok());
        assert_eq!(f.declared_len, 6);
        let n = encode_raw([0x06, 0x21], &Payload::new(&[0x01]).unwrap(), 0x00, &mut buf);
        let f = Rs232Decoder::new().feed(&buf[..n]).next().unwrap().unwrap();
        assert!(!f.bcc_ok());
        assert_eq!(f.bcc_computed, 0x28);
    }

    #[test]
    fn the_longest_frame_fits() {
        let mut buf = [0u8; MAX_FRAME];
        let n = encode(TelKind::Send, 16, &Payload::new(&[0x10; 8]).unwrap(), &mut buf).unwrap();
        assert!(n <= MAX_FRAME);
        assert!(encode(TelKind::Send, 32, &Payload::EMPTY, &mut buf).is_err());
    }
}
