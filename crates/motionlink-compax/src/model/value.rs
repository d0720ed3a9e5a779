//! Status values as read: positions, numbers, the bit words, the error history, text.

use std::fmt::{self, Write as _};

use super::bits::parse_bits;
use super::{syntax, ErrorCode, ModelError, Position, S16Bits, S17Bits, StatusId, StatusKind};
use crate::wire::number::{parse_decimal_trimmed, write_decimal};
use crate::wire::TextBuf;

/// One entry of the error history S18.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum HistoryEntry {
    /// An error occurred.
    Error(ErrorCode),
    /// 99: the error before was acknowledged.
    Acknowledged,
    /// 98: power-on acknowledgement (switched off while an error was present).
    PowerOn,
}

impl HistoryEntry {
    /// From the number in S18.
    pub fn from_number(n: u8) -> Self {
        match n {
            99 => HistoryEntry::Acknowledged,
            98 => HistoryEntry::PowerOn,
            c => HistoryEntry::Error(ErrorCode(c)),
        }
    }

    /// The number in S18.
    pub fn number(self) -> u8 {
        match self {
            HistoryEntry::Acknowledged => 99,
            HistoryEntry::PowerOn => 98,
            HistoryEntry::Error(c) => c.0,
        }
    }
}

/// A status value as read.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum StatusValue {
    /// A position in the drive's unit.
    Position(Position),
    /// Another number (see the status value's unit).
    Number(f64),
    /// S16.
    S16(S16Bits),
    /// S17.
    S17(S17Bits),
    /// S18, newest first.
    History([HistoryEntry; 8]),
    /// Text (unknown status values, identification).
    Text(TextBuf<48>),
}

impl fmt::Display for StatusValue {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            StatusValue::Position(p) => write_decimal(f, p.units(), 3),
            StatusValue::Number(n) => write_decimal(f, *n, 3),
            StatusValue::S16(b) => write!(f, "{}", b.pattern()),
            StatusValue::S17(b) => write!(f, "{}", b.pattern()),
            StatusValue::History(h) => {
                for (i, e) in h.iter().enumerate() {
                    if i > 0 {
                        f.write_char(' ')?;
                    }
                    write!(f, "{:02}", e.number())?;
                }
                Ok(())
            }
            StatusValue::Text(t) => f.write_str(t.as_str()),
        }
    }
}

/// Removes an echo of the value's name from a reply: `S001: 12`, `S1=12`, `S16 1000 0000` → the value.
#[inline]
pub(crate) fn strip_name(text: &[u8], letter: u8, number: u16) -> &[u8] {
    let three = [b'0' + (number / 100 % 10) as u8, b'0' + (number / 10 % 10) as u8, b'0' + (number % 10) as u8];
    // The form the drives send, `S001: 12` or `P194=5` with no space around it, straight through.
    if let [l, x, y, z, b':' | b'=', rest @ ..] = text {
        if *l == letter && number < 1000 && [*x, *y, *z] == three && text.last() != Some(&b' ') {
            let mut rest = rest;
            while let [b' ', r @ ..] = rest {
                rest = r;
            }
            return rest;
        }
    }
    let t = trim(text);
    let [first, after_letter @ ..] = t else { return t };
    if !first.eq_ignore_ascii_case(&letter) {
        return t;
    }
    // Three digits compared at once; any other number of them by value.
    let mut rest = match after_letter {
        [x, y, z, r @ ..] if number < 1000 && [*x, *y, *z] == three && !r.first().is_some_and(u8::is_ascii_digit) => r,
        _ => match name_digits(after_letter, number) {
            Some(n) => &after_letter[n..],
            None => return t,
        },
    };
    if let [b':' | b'=', r @ ..] = rest {
        rest = r;
    }
    // The end is trimmed already.
    while let [b' ', r @ ..] = rest {
        rest = r;
    }
    rest
}

/// How many digits `rest` starts with, when they are at least one and their value (leading zeros allowed) is
/// `number`.
fn name_digits(rest: &[u8], number: u16) -> Option<usize> {
    // Held at 2^20 from above, far from any u16.
    let mut n = 0u32;
    let mut digits = 0;
    while let Some(c @ b'0'..=b'9') = rest.get(digits) {
        n = (n * 10 + u32::from(c - b'0')).min(1 << 20);
        digits += 1;
    }
    (digits > 0 && n == u32::from(number)).then_some(digits)
}

#[inline]
pub(crate) fn trim(mut s: &[u8]) -> &[u8] {
    while let [b' ', rest @ ..] = s {
        s = rest;
    }
    while let [rest @ .., b' '] = s {
        s = rest;
    }
    s
}

/// As much of `s` as fits a text value (48 bytes), cut between characters, never inside one.
fn text_prefix(s: &str) -> TextBuf<48> {
    let mut end = s.len().min(48);
    while !s.is_char_boundary(end) {
        end -= 1;
    }
    let mut t = TextBuf::new();
    // Fits: at most 48 bytes.
    let _ = t.write_str(&s[..end]);
    t
}

impl StatusValue {
    /// Reads the reply text to `S<id>`. A text value keeps its first 48 bytes (whole characters). Accepts the value alone or after its name (`S001: `, `S1=`).
    #[inline]
    pub fn parse(id: StatusId, text: &[u8]) -> Result<StatusValue, ModelError> {
        let v = strip_name(text, b'S', id.get().into());
        // Without spaces around it already.
        let number = || parse_decimal_trimmed(v);
        let bad = || syntax("a status value", text);
        Ok(match id.kind() {
            StatusKind::Position => StatusValue::Position(Position::new(number().ok_or_else(bad)?).map_err(|_| bad())?),
            StatusKind::Number => StatusValue::Number(number().ok_or_else(bad)?),
            StatusKind::BitsS16 => StatusValue::S16(S16Bits(parse_bits(v).ok_or_else(bad)?)),
            StatusKind::BitsS17 => StatusValue::S17(S17Bits(parse_bits(v).ok_or_else(bad)?)),
            StatusKind::History => {
                let mut h = [HistoryEntry::Acknowledged; 8];
                let mut n = 0;
                for word in v.split(|c| *c == b' ').filter(|w| !w.is_empty()) {
                    if n == 8 || word.len() > 2 || !word.iter().all(u8::is_ascii_digit) {
                        return Err(bad());
                    }
                    h[n] = HistoryEntry::from_number(word.iter().fold(0, |a, d| a * 10 + (d - b'0')));
                    n += 1;
                }
                if n != 8 {
                    return Err(bad());
                }
                StatusValue::History(h)
            }
            StatusKind::Text => {
                let s = std::str::from_utf8(v).map_err(|_| bad())?;
                StatusValue::Text(text_prefix(s))
            }
        })
    }

    /// Writes the reply text a drive sends for `S<id>` (the emulator's side): `S001: 360.000`, `S017:
    /// 0000 0010`, `S018: 99 99 ...` (the user guide's S18 example shows this form).
    pub fn write_reply(&self, id: StatusId, out: &mut impl fmt::Write) -> fmt::Result {
        write!(out, "S{:03}: ", id.get())?;
        match self {
            StatusValue::Position(p) => write!(out, "{:.3}", p.units()),
            other => write!(out, "{other}"),
        }
    }
}
