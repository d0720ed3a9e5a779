//! Number formats: the binary 24.24 fixed point and 16-bit integer, and decimal text.
//!
//! The 24.24 format (manual 4.4.1, footnote 2) is `value * 2^24` as a 48-bit two's complement number, three
//! bytes after the binary point and three before, sent least significant byte first. `450.5` is
//! `0x0001_C280_0000`, sent `00 00 80 C2 01 00`. The 16-bit format is a two's complement integer sent most
//! significant byte first.
//!
//! ```
//! use motionlink_compax::wire::number::Fixed24;
//! let x = Fixed24::from_f64(360.0).unwrap();
//! assert_eq!(x.to_le_bytes(), [0x00, 0x00, 0x00, 0x68, 0x01, 0x00]);
//! assert_eq!(Fixed24::from_le_bytes([0, 0, 0, 0xFF, 0xFF, 0xFF]).to_f64(), -1.0);
//! ```

use std::fmt;

/// A number that does not fit its format, or text that is not a number.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum NumberError {
    /// Outside the range of the 24.24 format.
    #[error("{0} does not fit the 24.24 format (-8388608 to 8388607.99999994)")]
    Fixed24Range(String),
    /// Outside the range of the 16-bit format.
    #[error("{0} does not fit the 16-bit format (-32768..=32767)")]
    Int16Range(i64),
    /// Not a finite number.
    #[error("{0} is not a finite number")]
    NotFinite(String),
    /// Text that is not a decimal number.
    #[error("{0:?} is not a decimal number")]
    Syntax(String),
}

/// Scale of the 24.24 format: 2^24.
pub const FIXED24_ONE: i64 = 1 << 24;
const FIXED24_MIN: i64 = -(1 << 47);
const FIXED24_MAX: i64 = (1 << 47) - 1;

/// A value in the 24.24 binary format: the raw 48-bit two's complement number `value * 2^24`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Default)]
pub struct Fixed24(i64);

impl Fixed24 {
    /// The smallest value: -2^23.
    pub const MIN: Fixed24 = Fixed24(FIXED24_MIN);
    /// The largest value: 2^23 - 2^-24.
    pub const MAX: Fixed24 = Fixed24(FIXED24_MAX);

    /// From the raw 48-bit number (`value * 2^24`); refused outside the 48-bit range.
    pub fn from_raw(raw: i64) -> Result<Self, NumberError> {
        if (FIXED24_MIN..=FIXED24_MAX).contains(&raw) {
            Ok(Fixed24(raw))
        } else {
            Err(NumberError::Fixed24Range(format!("{}", raw as f64 / FIXED24_ONE as f64)))
        }
    }

    /// The raw number `value * 2^24`.
    pub const fn raw(self) -> i64 {
        self.0
    }

    /// The nearest 24.24 value to `v` (ties away from zero); refused when out of range or not finite.
    #[inline]
    pub fn from_f64(v: f64) -> Result<Self, NumberError> {
        if !v.is_finite() {
            return Err(NumberError::NotFinite(format!("{v}")));
        }
        let scaled = (v * FIXED24_ONE as f64).round();
        if scaled < FIXED24_MIN as f64 || scaled > FIXED24_MAX as f64 {
            return Err(NumberError::Fixed24Range(format!("{v}")));
        }
        Ok(Fixed24(scaled as i64))
    }

    /// The value (exact: 48 bits fit an f64's mantissa).
    pub fn to_f64(self) -> f64 {
        self.0 as f64 / FIXED24_ONE as f64
    }

    /// The six bytes as sent: least significant first.
    pub fn to_le_bytes(self) -> [u8; 6] {
        let b = self.0.to_le_bytes();
        [b[0], b[1], b[2], b[3], b[4], b[5]]
    }

    /// From the six bytes as sent (least significant first), sign-extending bit 47.
    pub fn from_le_bytes(b: [u8; 6]) -> Self {
        let raw = i64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], 0, 0]);
        Fixed24((raw << 16) >> 16)
    }
}

impl fmt::Display for Fixed24 {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.to_f64())
    }
}

/// Encodes `v` in the 16-bit format: two's complement, most significant byte first.
///
/// ```
/// use motionlink_compax::wire::number::{int16_to_be, int16_from_be};
/// assert_eq!(int16_to_be(500).unwrap(), [0x01, 0xF4]);
/// assert_eq!(int16_to_be(-1).unwrap(), [0xFF, 0xFF]);
/// assert_eq!(int16_from_be([0x80, 0x00]), -32768);
/// assert!(int16_to_be(40_000).is_err());
/// ```
pub fn int16_to_be(v: i64) -> Result<[u8; 2], NumberError> {
    let v = i16::try_from(v).map_err(|_| NumberError::Int16Range(v))?;
    Ok(v.to_be_bytes())
}

/// Decodes the 16-bit format.
pub fn int16_from_be(b: [u8; 2]) -> i16 {
    i16::from_be_bytes(b)
}

/// Decimals sent in ASCII commands at most; finer values are rounded (the drives resolve 0.001 for positions
/// and 0.000001 for the finest parameters).
pub const MAX_DECIMALS: usize = 6;

/// Writes `v` as decimal text without exponent, rounded to `decimals` places, trailing zeros dropped
/// (`360`, `-1055.88`, `0.5`). Never allocates.
pub fn write_decimal(out: &mut impl fmt::Write, v: f64, decimals: usize) -> fmt::Result {
    let mut tmp = super::TextBuf::<48>::new();
    if fmt::Write::write_fmt(&mut tmp, format_args!("{:.*}", decimals.min(MAX_DECIMALS), v)).is_err() {
        // Too large for the buffer: values that big never fit a command anyway; write them plainly.
        return write!(out, "{v}");
    }
    let mut s = tmp.as_str();
    if s.contains('.') {
        s = s.trim_end_matches('0').trim_end_matches('.');
    }
    if s == "-0" {
        s = "0";
    }
    out.write_str(s)
}

/// The number the decimal text of `v` ([`write_decimal`] with [`MAX_DECIMALS`]) carries: `v` rounded to six
/// decimals, as a drive reads the command (0 for a value nearer 0 than 0.0000005).
///
/// ```
/// use motionlink_compax::wire::number::decimal_as_sent;
/// assert_eq!(decimal_as_sent(-1055.88), -1055.88);
/// assert_eq!(decimal_as_sent(0.0000001), 0.0);
/// assert_eq!(decimal_as_sent(1.23456789), 1.234568);
/// ```
pub fn decimal_as_sent(v: f64) -> f64 {
    let mut t = String::new();
    match write_decimal(&mut t, v, MAX_DECIMALS) {
        Ok(()) => t.parse().unwrap_or(v),
        Err(_) => v,
    }
}

/// True when `read` is `wrote` as decimal text carries it back: equal to within a billionth of the value (at
/// least of 1). What a parameter written reads back as, and what a command must carry of a value.
pub fn same_decimal(wrote: f64, read: f64) -> bool {
    (read - wrote).abs() <= 1e-9 * wrote.abs().max(1.0)
}

/// Parses a decimal number: optional sign, digits, optional `.` and digits (`+0360.000`, `-1055.88`, `5`).
/// Leading and trailing spaces are ignored. Fast and allocation-free.
///
/// ```
/// use motionlink_compax::wire::number::parse_decimal;
/// assert_eq!(parse_decimal("-1055.88").unwrap(), -1055.88);
/// assert_eq!(parse_decimal(" +0360.000").unwrap(), 360.0);
/// assert!(parse_decimal("12a").is_err());
/// ```
pub fn parse_decimal(text: &str) -> Result<f64, NumberError> {
    parse_decimal_bytes(text.as_bytes()).ok_or_else(|| NumberError::Syntax(text.to_string()))
}

/// [`parse_decimal`] on bytes; `None` when they are not a decimal number.
///
/// Numbers of up to 18 digits (every value a drive sends) are read as one integer and scaled by a power of
/// ten: one correctly rounded division, the same arithmetic as for longer numbers, whose digits after the
/// 18th significant one are dropped.
#[inline]
pub fn parse_decimal_bytes(text: &[u8]) -> Option<f64> {
    let (neg, s) = split_sign(trim_spaces(text));
    parse_digits(neg, s)
}

/// [`parse_decimal_bytes`] of a text known to have no spaces at either end (it trims none).
#[inline]
pub(crate) fn parse_decimal_trimmed(text: &[u8]) -> Option<f64> {
    debug_assert_eq!(text, trim_spaces(text));
    let (neg, s) = split_sign(text);
    parse_digits(neg, s)
}

#[inline]
fn trim_spaces(mut s: &[u8]) -> &[u8] {
    while let [b' ', rest @ ..] = s {
        s = rest;
    }
    while let [rest @ .., b' '] = s {
        s = rest;
    }
    s
}

#[inline]
fn split_sign(s: &[u8]) -> (bool, &[u8]) {
    match s {
        [b'-', rest @ ..] => (true, rest),
        [b'+', rest @ ..] => (false, rest),
        _ => (false, s),
    }
}

/// `s`, the digits and one point after the sign, one character at a time.
#[inline]
fn parse_digits(neg: bool, s: &[u8]) -> Option<f64> {
    // 18 digits and a point: no digit can be dropped, and 19 digits still fit a u64 without overflow.
    if s.len() > 19 {
        return parse_decimal_general(neg, s);
    }
    let mut mantissa: u64 = 0;
    let mut i = 0;
    // Where the point is; `s.len()` when there is none.
    let mut point = s.len();
    while i < s.len() {
        let d = s[i].wrapping_sub(b'0');
        if d < 10 {
            mantissa = mantissa * 10 + u64::from(d);
        } else if s[i] == b'.' && point == s.len() {
            point = i;
        } else {
            return None;
        }
        i += 1;
    }
    // Every character is a digit but the point, if any.
    let (digits, decimals) = if point < s.len() { (s.len() - 1, s.len() - point - 1) } else { (s.len(), 0) };
    if digits == 0 {
        return None;
    }
    if digits > 18 {
        return parse_decimal_general(neg, s);
    }
    Some(scale(neg, mantissa, decimals))
}

/// `mantissa / 10^decimals` with the sign (`decimals` <= 18: an exact power of ten from the table).
#[inline]
fn scale(neg: bool, mantissa: u64, decimals: usize) -> f64 {
    // At most 18 digits: below 2^63, where the signed conversion (one instruction on x86-64) rounds the
    // same as the unsigned one.
    debug_assert!(mantissa < 1_000_000_000_000_000_000);
    let m = mantissa as i64 as f64;
    let v = if decimals == 0 { m } else { m / POW10[decimals] };
    if neg {
        -v
    } else {
        v
    }
}

/// The general decimal reader behind [`parse_decimal_bytes`], for any length: keeps the first 18
/// significant digits, counts the dropped ones before the point as powers of ten, ignores those after it.
/// `s` is the text after the sign.
#[inline(never)]
fn parse_decimal_general(neg: bool, mut s: &[u8]) -> Option<f64> {
    let mut mantissa: u64 = 0;
    let mut digits = 0usize;
    let mut scale = 0i32;
    let mut seen_point = false;
    let mut significant = 0usize;
    let mut dropped_exp = 0i32;
    while let [c, rest @ ..] = s {
        match *c {
            b'0'..=b'9' => {
                digits += 1;
                if mantissa == 0 && *c == b'0' {
                    if seen_point {
                        scale += 1;
                    }
                } else if significant < 18 {
                    mantissa = mantissa * 10 + u64::from(c - b'0');
                    significant += 1;
                    if seen_point {
                        scale += 1;
                    }
                } else if !seen_point {
                    dropped_exp += 1;
                }
            }
            b'.' if !seen_point => seen_point = true,
            _ => return None,
        }
        s = rest;
    }
    if digits == 0 {
        return None;
    }
    let exp = dropped_exp - scale;
    let m = mantissa as f64;
    let v = if exp >= 0 { m * pow10(exp) } else { m / pow10(-exp) };
    Some(if neg { -v } else { v })
}

/// True when `v` is a value of the 24.24 format: exactly when [`Fixed24::from_f64`] accepts it, without
/// rounding (`round(v * 2^24)` is in range exactly when `v * 2^24` is within half a step of it; the product
/// is exact, the bounds `-2^47 - 0.5` and `2^47 - 0.5` are representable, and NaN compares false).
#[inline]
pub fn fits_fixed24(v: f64) -> bool {
    let x = v * FIXED24_ONE as f64;
    x > FIXED24_MIN as f64 - 0.5 && x < FIXED24_MAX as f64 + 0.5
}

const POW10: [f64; 23] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19, 1e20,
    1e21, 1e22,
];

#[inline]
fn pow10(e: i32) -> f64 {
    match usize::try_from(e) {
        Ok(i) if i < POW10.len() => POW10[i],
        _ => 10f64.powi(e),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The manual's table "Example for the number format of xx xx xx xx xx xx", printed MSB first.
    /// Its third row reads "400,5" but the bytes 00 01 C2 80 00 00 are 450.5 (0x1C2 = 450), the number of
    /// the worked example above the table: the bytes are the truth.
    #[test]
    fn the_manuals_number_format_table() {
        let rows: [(f64, [u8; 6]); 4] = [
            (10.0, [0x00, 0x00, 0x0A, 0x00, 0x00, 0x00]),
            (256.0, [0x00, 0x01, 0x00, 0x00, 0x00, 0x00]),
            (450.5, [0x00, 0x01, 0xC2, 0x80, 0x00, 0x00]),
            (-1.0, [0xFF, 0xFF, 0xFF, 0x00, 0x00, 0x00]),
        ];
        for (value, msb_first) in rows {
            let mut lsb_first = msb_first;
            lsb_first.reverse();
            let x = Fixed24::from_f64(value).unwrap();
            assert_eq!(x.to_le_bytes(), lsb_first, "{value}");
            assert_eq!(Fixed24::from_le_bytes(lsb_first).to_f64(), value);
        }
        // The worked example: 450.5 * 2^24 = 7558135808.
        assert_eq!(Fixed24::from_f64(450.5).unwrap().raw(), 7_558_135_808);
    }

    #[test]
    fn fixed24_range_and_rounding() {
        assert_eq!(Fixed24::from_f64(8_388_607.0).unwrap().to_le_bytes(), [0, 0, 0, 0xFF, 0xFF, 0x7F]);
        assert_eq!(Fixed24::from_f64(-8_388_608.0).unwrap(), Fixed24::MIN);
        assert!(matches!(Fixed24::from_f64(8_388_608.0), Err(NumberError::Fixed24Range(_))));
        assert!(matches!(Fixed24::from_f64(-8_388_609.0), Err(NumberError::Fixed24Range(_))));
        assert!(matches!(Fixed24::from_f64(f64::NAN), Err(NumberError::NotFinite(_))));
        assert!(Fixed24::from_raw(1 << 47).is_err());
        assert_eq!(Fixed24::from_f64(-0.5).unwrap().to_le_bytes(), [0, 0, 0x80, 0xFF, 0xFF, 0xFF]);
        // One step of 2^-24 is kept exactly.
        let tiny = Fixed24::from_raw(1).unwrap();
        assert_eq!(Fixed24::from_f64(tiny.to_f64()).unwrap(), tiny);
    }

    #[test]
    fn int16_range() {
        assert_eq!(int16_to_be(32_767).unwrap(), [0x7F, 0xFF]);
        assert_eq!(int16_to_be(-32_768).unwrap(), [0x80, 0x00]);
        assert_eq!(int16_to_be(32_768), Err(NumberError::Int16Range(32_768)));
        assert_eq!(int16_from_be([0xFF, 0xFE]), -2);
    }

    #[test]
    fn decimal_text() {
        let show = |v: f64| {
            let mut t = crate::wire::TextBuf::<64>::new();
            write_decimal(&mut t, v, MAX_DECIMALS).unwrap();
            t.as_str().to_string()
        };
        assert_eq!(show(360.0), "360");
        assert_eq!(show(-1055.88), "-1055.88");
        assert_eq!(show(0.5), "0.5");
        assert_eq!(show(-0.0000001), "0");
        assert_eq!(show(1.0 / 3.0), "0.333333");
        for (text, v) in [("0", 0.0), ("007", 7.0), ("-0.001", -0.001), ("123456.789", 123456.789), (".5", 0.5)] {
            assert_eq!(parse_decimal(text).unwrap(), v, "{text}");
        }
        for bad in ["", "-", ".", "1.2.3", "1e5", "--1", "1 2"] {
            assert!(parse_decimal(bad).is_err(), "{bad}");
        }
    }

    /// The reader as it was before the fast path: the general one, after the spaces and the sign. The fast
    /// path must give the same f64, bit for bit, or refuse the same texts.
    fn reference(text: &[u8]) -> Option<f64> {
        let (neg, s) = split_sign(trim_spaces(text));
        parse_decimal_general(neg, s)
    }

    fn agrees(text: &[u8]) -> Result<(), String> {
        let (fast, old) = (parse_decimal_bytes(text), reference(text));
        if fast.map(f64::to_bits) == old.map(f64::to_bits) {
            Ok(())
        } else {
            Err(format!("{:?}: fast {fast:?}, reference {old:?}", String::from_utf8_lossy(text)))
        }
    }

    #[test]
    fn fast_decimal_reader_at_its_edges() {
        for text in [
            "0",
            "-0",
            "+0",
            "-0.000",
            "5.",
            ".5",
            "-.5",
            "360.125",
            "-360.125",
            "  1  ",
            "0.1",
            "0.3",
            "-8388608",
            "8388607.99999994",
            "999999999999999999",
            "-999999999999999999",
            "99999999999999999.9",
            "9999999999999999999",
            "999999999999999999.5",
            "1234567890123456789",
            "12345678901234567890",
            "0.000000000000000001",
            "0.0000000000000000001",
            "00000000000000000001",
            "9007199254740993",
            "900719925474099.35",
            ".",
            "-",
            "+",
            "",
            " ",
            "1..2",
            "1.2.",
            "12a",
            "+-1",
            "1e5",
            "1 2",
            "- 1",
            "\t1",
        ] {
            agrees(text.as_bytes()).unwrap();
        }
    }

    #[test]
    fn fits_fixed24_at_the_edges() {
        let one = FIXED24_ONE as f64;
        for raw in [FIXED24_MAX as f64, FIXED24_MIN as f64, 0.0] {
            for x in [raw - 1.0, raw - 0.5, raw, raw + 0.5, raw + 1.0] {
                let v = x / one;
                for v in [v.next_down(), v, v.next_up()] {
                    assert_eq!(fits_fixed24(v), Fixed24::from_f64(v).is_ok(), "{v:e}");
                }
            }
        }
        for v in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY, f64::MAX, f64::MIN, f64::MIN_POSITIVE, -0.0] {
            assert_eq!(fits_fixed24(v), Fixed24::from_f64(v).is_ok(), "{v:e}");
        }
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig { cases: 2000, ..Default::default() })]

        #[test]
        fn fast_decimal_reader_agrees_on_decimal_texts(
            text in "[ ]{0,2}[+-]?[0-9]{0,22}(\\.[0-9]{0,22})?[ ]{0,2}",
        ) {
            proptest::prop_assert!(agrees(text.as_bytes()).is_ok(), "{}", agrees(text.as_bytes()).unwrap_err());
        }

        #[test]
        fn fast_decimal_reader_agrees_on_texts_near_decimals(text in "[0-9.+\\- e]{0,24}") {
            proptest::prop_assert!(agrees(text.as_bytes()).is_ok(), "{}", agrees(text.as_bytes()).unwrap_err());
        }

        #[test]
        fn fast_decimal_reader_agrees_on_printed_numbers(v in proptest::num::f64::ANY, decimals in 0usize..20) {
            for text in [format!("{v:.decimals$}"), format!("{v}"), format!("{:.3}", v / 1e9)] {
                proptest::prop_assert!(agrees(text.as_bytes()).is_ok(), "{}", agrees(text.as_bytes()).unwrap_err());
            }
        }

        #[test]
        fn fast_decimal_reader_agrees_on_arbitrary_bytes(bytes in proptest::collection::vec(proptest::num::u8::ANY, 0..24)) {
            proptest::prop_assert!(agrees(&bytes).is_ok(), "{}", agrees(&bytes).unwrap_err());
        }

        #[test]
        fn fits_fixed24_agrees_with_the_conversion(v in proptest::num::f64::ANY, raw in -(1i64 << 48)..(1i64 << 48)) {
            proptest::prop_assert_eq!(fits_fixed24(v), Fixed24::from_f64(v).is_ok());
            // Values near the range, and halfway between two steps of 2^-24.
            for x in [raw as f64 / FIXED24_ONE as f64, (raw as f64 + 0.5) / FIXED24_ONE as f64] {
                proptest::prop_assert_eq!(fits_fixed24(x), Fixed24::from_f64(x).is_ok(), "{:e}", x);
            }
        }
    }
}
