//! The COMPAX vocabulary as types: commands, status values S1..S40, the status bit words S16 / S17, the
//! error history S18, parameters Pnnn, and error codes Exx.
//!
//! Each table is written once (a `macro_rules!` invocation) and everything else (the client, the emulator,
//! the command line, the capture decoder) reads it.
//!
//! ```
//! use motionlink_compax::model::{Command, CommandStyle, Position};
//! let c = Command::PosA(Position::new(360.0).unwrap());
//! assert_eq!(c.to_ascii(CommandStyle::Long).unwrap().as_str(), "POSA 360");
//! assert_eq!(c.to_ascii(CommandStyle::Short).unwrap().as_str(), "PA 360");
//! assert_eq!(Command::parse(b"PR 200 OT O9=1").unwrap().to_ascii(CommandStyle::Long).unwrap().as_str(),
//!            "POSR 200 OUTPUT O9=1");
//! ```

use std::fmt::{self, Write as _};

use crate::wire::number::{
    fits_fixed24, parse_decimal_bytes, parse_decimal_trimmed, write_decimal, Fixed24, MAX_DECIMALS,
};
use crate::wire::{BinaryCommand, TextBuf, WireError, MAX_COMMAND_LEN};

/// A value or text the model cannot accept.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ModelError {
    /// A value outside its range.
    #[error("{what} {value} is out of range ({range})")]
    Range {
        /// What the value is.
        what: &'static str,
        /// The value as given.
        value: String,
        /// The allowed range.
        range: &'static str,
    },
    /// Text that is not a command or a value of the expected form.
    #[error("cannot read {what} from {text:?}")]
    Syntax {
        /// What was expected.
        what: &'static str,
        /// The text.
        text: String,
    },
    /// The command has no binary form.
    #[error("{0} has no binary form")]
    NoBinary(&'static str),
    /// A wire format limit.
    #[error(transparent)]
    Wire(#[from] WireError),
}

fn syntax(what: &'static str, text: &[u8]) -> ModelError {
    ModelError::Syntax { what, text: String::from_utf8_lossy(text).into_owned() }
}

// ------------------------------------------------------------------------------------------------------
// Units

/// A position or distance in the drive's position unit (mm, inch, degrees: whatever the drive is configured
/// for). Limited to the range of the 24.24 format, -8388608..8388608.
#[derive(Debug, Clone, Copy, PartialEq, PartialOrd, Default)]
pub struct Position(f64);

impl Position {
    /// A position; refused when not finite or outside the 24.24 range.
    #[inline]
    pub fn new(units: f64) -> Result<Self, ModelError> {
        if fits_fixed24(units) {
            Ok(Position(units))
        } else {
            Err(ModelError::Range { what: "position", value: units.to_string(), range: "-8388608 to 8388607.99" })
        }
    }

    /// The value in the drive's position unit.
    #[inline]
    pub fn units(self) -> f64 {
        self.0
    }

    /// The 24.24 form.
    pub fn to_fixed(self) -> Fixed24 {
        Fixed24::from_f64(self.0).unwrap_or_default()
    }
}

impl fmt::Display for Position {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write_decimal(f, self.0, MAX_DECIMALS)
    }
}

/// A speed in percent of the drive's maximum speed: more than 0, at most 100.
#[derive(Debug, Clone, Copy, PartialEq, PartialOrd)]
pub struct SpeedPercent(f64);

impl SpeedPercent {
    /// A speed; refused outside (0, 100].
    pub fn new(percent: f64) -> Result<Self, ModelError> {
        if percent.is_finite() && percent > 0.0 && percent <= 100.0 {
            Ok(SpeedPercent(percent))
        } else {
            Err(ModelError::Range { what: "speed", value: format!("{percent} %"), range: "more than 0, at most 100 %" })
        }
    }

    /// The percentage.
    pub fn percent(self) -> f64 {
        self.0
    }
}

impl fmt::Display for SpeedPercent {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write_decimal(f, self.0, MAX_DECIMALS)
    }
}

/// A ramp time in milliseconds (ACCEL, ACCEL-): 0..=32767, the range of the binary 16-bit format.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct RampMs(u16);

impl RampMs {
    /// The largest ramp time.
    pub const MAX: u16 = 32_767;

    /// A ramp time; refused above 32767 ms.
    pub fn new(ms: u32) -> Result<Self, ModelError> {
        u16::try_from(ms).ok().filter(|&m| m <= Self::MAX).map(RampMs).ok_or_else(|| ModelError::Range {
            what: "ramp time",
            value: format!("{ms} ms"),
            range: "0..=32767 ms",
        })
    }

    /// Milliseconds.
    pub fn ms(self) -> u16 {
        self.0
    }
}

/// The state written to an output by OUTPUT: 0 or 1 (and 2 for O0, the drive's own switch).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct OutputState(u8);

impl OutputState {
    /// Off.
    pub const OFF: OutputState = OutputState(0);
    /// On.
    pub const ON: OutputState = OutputState(1);

    /// A state for `output`: 0 or 1, or 0..=2 for O0.
    pub fn new(output: u16, state: u8) -> Result<Self, ModelError> {
        let max = if output == 0 { 2 } else { 1 };
        if state <= max {
            Ok(OutputState(state))
        } else {
            Err(ModelError::Range { what: "output state", value: state.to_string(), range: "0 or 1 (O0: 0, 1 or 2)" })
        }
    }

    /// The number written.
    pub fn get(self) -> u8 {
        self.0
    }
}

// ------------------------------------------------------------------------------------------------------
// Status values

/// How a status value is read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StatusKind {
    /// A position in the drive's unit.
    Position,
    /// Another number.
    Number,
    /// The 8 status bits of S16.
    BitsS16,
    /// The 8 status bits of S17.
    BitsS17,
    /// The 8-entry error history of S18.
    History,
    /// Text.
    Text,
}

/// A status value number, 1..=40.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct StatusId(u8);

/// What is known about one status value.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StatusInfo {
    /// The number.
    pub id: StatusId,
    /// A short name.
    pub name: &'static str,
    /// What it is.
    pub description: &'static str,
    /// How to read it.
    pub kind: StatusKind,
    /// Its unit, as the drive reports it ("" when none).
    pub unit: &'static str,
}

macro_rules! status_table {
    ($( $num:literal => $konst:ident, $name:literal, $desc:literal, $kind:ident, $unit:literal; )*) => {
        impl StatusId {
            $(
                #[doc = concat!("S", stringify!($num), ": ", $desc, ".")]
                pub const $konst: StatusId = StatusId($num);
            )*
        }

        /// Every status value whose meaning is known (COMPAX-M / -S user guide and its fieldbus interface
        /// description). The others of S1..S40 can be read as text.
        pub const KNOWN_STATUS: &[StatusInfo] = &[
            $( StatusInfo { id: StatusId($num), name: $name, description: $desc, kind: StatusKind::$kind,
                            unit: $unit }, )*
        ];
    };
}

status_table! {
    1 => ACTUAL_POSITION, "actual position", "actual position, relative to the real zero", Position, "unit";
    2 => TARGET_POSITION, "target position", "target position of the current or last positioning", Position, "unit";
    3 => CONTOUR_ERROR, "contour error", "contour (following) error: set minus actual position", Position, "unit";
    6 => TEMPERATURE, "temperature", "temperature of the power output stage", Number, "°C";
    7 => CONTROL_VOLTAGE, "control voltage", "control voltage", Number, "V";
    8 => DC_LINK_VOLTAGE, "DC link voltage", "intermediate circuit voltage", Number, "V";
    9 => MOTION_CYCLES, "motion cycles", "number of axis motion cycles", Number, "";
    10 => OPERATING_HOURS, "operating hours", "COMPAX operating hours", Number, "h";
    11 => LOOP_COUNTER, "loop counter", "loop counter of a running REPEAT loop", Number, "";
    12 => ABSOLUTE_SENSOR, "absolute sensor", "position of the absolute value sensor", Position, "unit";
    16 => STATUS_BITS_1, "status bits S16", "status bits: fault, warning, machine zero, ready, reached, idle", BitsS16, "";
    17 => STATUS_BITS_2, "status bits S17", "status bits: passwords, command active, program, stop, RUN", BitsS17, "";
    18 => ERROR_HISTORY, "error history", "the last eight errors, newest first (99 acknowledged, 98 power on)", History, "";
    30 => ERROR_MESSAGE, "error message", "the pending error message", Text, "";
    31 => DEVICE_ID_1, "device identification 1", "device identification", Text, "";
    32 => DEVICE_ID_2, "device identification 2", "device identification", Text, "";
    33 => DEVICE_ID_3, "device identification 3", "device identification", Text, "";
    34 => DEVICE_ID_4, "device identification 4", "device identification", Text, "";
    35 => DEVICE_ID_5, "device identification 5", "device identification", Text, "";
    36 => DEVICE_ID_6, "device identification 6", "device identification", Text, "";
    37 => DEVICE_ID_7, "device identification 7", "device identification", Text, "";
    38 => DEVICE_ID_8, "device identification 8", "device identification", Text, "";
    39 => DEVICE_ID_9, "device identification 9", "device identification", Text, "";
}

/// Marks a status value without an entry in [`KNOWN_STATUS`].
const NO_INFO: u8 = u8::MAX;

/// For each number 0..=40, its entry's index in [`KNOWN_STATUS`] (or [`NO_INFO`]): a lookup, not a search.
const STATUS_INDEX: [u8; StatusId::MAX as usize + 1] = {
    let mut index = [NO_INFO; StatusId::MAX as usize + 1];
    let mut i = 0;
    while i < KNOWN_STATUS.len() {
        index[KNOWN_STATUS[i].id.0 as usize] = i as u8;
        i += 1;
    }
    index
};

impl StatusId {
    /// The highest status value number.
    pub const MAX: u8 = 40;

    /// S1..=S40.
    pub fn new(n: u8) -> Result<Self, ModelError> {
        if (1..=Self::MAX).contains(&n) {
            Ok(StatusId(n))
        } else {
            Err(ModelError::Range { what: "status value", value: format!("S{n}"), range: "S1..=S40" })
        }
    }

    /// The number.
    pub fn get(self) -> u8 {
        self.0
    }

    /// What is known about it.
    #[inline]
    pub fn info(self) -> Option<&'static StatusInfo> {
        match STATUS_INDEX.get(usize::from(self.0)) {
            Some(&i) if i != NO_INFO => KNOWN_STATUS.get(usize::from(i)),
            _ => None,
        }
    }

    /// How to read it (text when unknown).
    #[inline]
    pub fn kind(self) -> StatusKind {
        self.info().map_or(StatusKind::Text, |i| i.kind)
    }

    /// Parses `S1`, `s16`, `S016`.
    pub fn parse(text: &str) -> Result<Self, ModelError> {
        let t = text.trim();
        let digits = t.strip_prefix('S').or_else(|| t.strip_prefix('s')).unwrap_or(t);
        digits.parse::<u8>().map_err(|_| syntax("a status value (S1..S40)", text.as_bytes())).and_then(StatusId::new)
    }
}

impl fmt::Display for StatusId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "S{}", self.0)
    }
}

// ------------------------------------------------------------------------------------------------------
// Status bit words S16, S17

/// Bit `n` (1..=8) of S16 / S17 is mask `0x80 >> (n - 1)`: "bit 1 is on the left, the transmission starts
/// with bit 1", and "password 302 active: S17 = 0x80".
pub const fn bit_mask(n: u8) -> u8 {
    0x80 >> (n - 1)
}

macro_rules! bit_word {
    ($ty:ident, $doc:literal, $( $bit:literal => $konst:ident, $desc:literal; )*) => {
        #[doc = $doc]
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
        pub struct $ty(pub u8);

        impl $ty {
            $(
                #[doc = concat!("Bit ", stringify!($bit), ": ", $desc, ".")]
                pub const $konst: u8 = $bit;
            )*

            /// Every named bit: (number, name).
            pub const BITS: &'static [(u8, &'static str)] = &[ $( ($bit, $desc), )* ];

            /// True if bit `n` (1..=8) is set.
            pub fn bit(self, n: u8) -> bool {
                (1..=8).contains(&n) && self.0 & bit_mask(n) != 0
            }

            /// Sets or clears bit `n` (1..=8).
            pub fn set(&mut self, n: u8, on: bool) {
                if (1..=8).contains(&n) {
                    if on { self.0 |= bit_mask(n) } else { self.0 &= !bit_mask(n) }
                }
            }

            /// The names of the bits that are set.
            pub fn names_set(self) -> impl Iterator<Item = &'static str> {
                Self::BITS.iter().filter(move |(n, _)| self.bit(*n)).map(|(_, d)| *d)
            }
        }

        impl fmt::Display for $ty {
            /// As transmitted: bit 1 first, `1000 0000`.
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                for n in 1..=8u8 {
                    if n == 5 {
                        f.write_char(' ')?;
                    }
                    f.write_char(if self.bit(n) { '1' } else { '0' })?;
                }
                Ok(())
            }
        }
    };
}

bit_word! {
    S16Bits, "The status bits of S16.",
    1 => NO_FAULT, "no fault";
    2 => NO_WARNING, "no warning";
    3 => MACHINE_ZERO, "machine zero has been approached";
    4 => READY_FOR_START, "ready for start";
    5 => POSITION_REACHED, "programmed nominal position reached";
    6 => IDLE_AFTER_STOP, "idle after stop";
    7 => O0_BIT7, "O0 state bit 7 (set after OUTPUT O0=1)";
    8 => O0_BIT8, "O0 state bit 8 (set after OUTPUT O0=2)";
}

bit_word! {
    S17Bits, "The status bits of S17.",
    1 => PASSWORD_302, "password 302 active";
    2 => SERVICE_PASSWORD, "service password active";
    3 => COMMAND_ACTIVE, "command active (move commands are refused with E92)";
    4 => PROGRAM_RUNNING, "program memory running";
    5 => STOP_VIA_I6, "stop via input I6";
    7 => RUN, "RUN";
}

impl S16Bits {
    /// The O0 state bits 7 and 8 as the OUTPUT O0 value they follow (0, 1 or 2).
    pub fn o0_state(self) -> u8 {
        match (self.bit(7), self.bit(8)) {
            (true, _) => 1,
            (false, true) => 2,
            (false, false) => 0,
        }
    }
}

fn parse_bits(text: &[u8]) -> Option<u8> {
    let mut v = 0u8;
    let mut n = 0;
    for &c in text {
        match c {
            b'0' | b'1' if n < 8 => {
                v = (v << 1) | (c - b'0');
                n += 1;
            }
            b' ' => {}
            _ => return None,
        }
    }
    (n == 8).then_some(v)
}

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
            StatusValue::S16(b) => write!(f, "{b}"),
            StatusValue::S17(b) => write!(f, "{b}"),
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
fn strip_name(text: &[u8], letter: u8, number: u16) -> &[u8] {
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
fn trim(mut s: &[u8]) -> &[u8] {
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
        let v = strip_name(text, b'S', id.0.into());
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
        write!(out, "S{:03}: ", id.0)?;
        match self {
            StatusValue::Position(p) => write!(out, "{:.3}", p.units()),
            other => write!(out, "{other}"),
        }
    }
}

// ------------------------------------------------------------------------------------------------------
// Error codes

/// An error message `Exx` of the drive.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ErrorCode(pub u8);

macro_rules! error_table {
    ($( $code:literal => $konst:ident, $desc:literal; )*) => {
        impl ErrorCode {
            $(
                #[doc = concat!("E", stringify!($code), ": ", $desc, ".")]
                pub const $konst: ErrorCode = ErrorCode($code);
            )*

            /// Every error whose meaning is known: (code, meaning).
            pub const KNOWN: &'static [(ErrorCode, &'static str)] = &[ $( (ErrorCode($code), $desc), )* ];
        }
    };
}

error_table! {
    55 => EMERGENCY_STOP, "emergency stop";
    57 => WARNING, "warning (S16 bit 2 is 0)";
    70 => PARITY, "parity error: the telegram was discarded, retransmit it";
    71 => BUFFER_OVERFLOW, "buffer overflow: more than 40 characters, retransmit with fewer";
    72 => BCC, "block-check character error: the telegram was discarded, retransmit it";
    73 => TIMEOUT, "timeout: five character times of silence inside a telegram, retransmit it";
    74 => BUSY, "busy error (acknowledged by power on)";
    92 => COMMAND_ACTIVE, "command active: a move command is refused while the axis moves";
}

impl ErrorCode {
    /// The meaning, where known.
    pub fn meaning(self) -> Option<&'static str> {
        Self::KNOWN.iter().find(|(c, _)| *c == self).map(|(_, m)| *m)
    }

    /// E70, E72, E73: the drive discarded the telegram (parity, BCC, timeout); sending the same telegram
    /// again is safe and is what the manual asks for. Not E71: its measure is "retransmit with fewer
    /// characters", and the same telegram would overflow the buffer again.
    pub fn is_retransmit(self) -> bool {
        matches!(self.0, 70 | 72 | 73)
    }
}

impl fmt::Display for ErrorCode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "E{:02} ({})", self.0, self.meaning().unwrap_or("meaning not documented in our sources"))
    }
}

// ------------------------------------------------------------------------------------------------------
// Parameters

/// A parameter number, P1..=P250.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ParamId(u16);

/// When a new parameter value takes effect.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ValidFrom {
    /// At the next power-on.
    PowerOn,
    /// At once.
    Immediately,
}

/// What is known about one parameter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParamInfo {
    /// The number.
    pub id: ParamId,
    /// What it sets.
    pub description: &'static str,
    /// Its unit ("" when none).
    pub unit: &'static str,
    /// Smallest value.
    pub min: f64,
    /// Factory value.
    pub default: f64,
    /// Largest value.
    pub max: f64,
    /// When a change takes effect.
    pub valid_from: ValidFrom,
}

macro_rules! param_table {
    ($( $num:literal => $konst:ident, $desc:literal, $unit:literal, $min:literal, $default:literal, $max:literal,
        $valid:ident; )*) => {
        impl ParamId {
            $(
                #[doc = concat!("P", stringify!($num), ": ", $desc, ".")]
                pub const $konst: ParamId = ParamId($num);
            )*
        }

        /// The parameters of the RS485 interface (manual chapter 5).
        pub const KNOWN_PARAMS: &[ParamInfo] = &[
            $( ParamInfo { id: ParamId($num), description: $desc, unit: $unit, min: $min as f64,
                           default: $default as f64, max: $max as f64, valid_from: ValidFrom::$valid }, )*
        ];
    };
}

// P196's maximum is printed as 31, but the table of valences above it adds 32 and 64 (and 164 / 165 for
// the fieldbus): 127 is the largest ASCII mode.
param_table! {
    194 => DEVICE_ADDRESS, "device address", "", 0, 0, 31, PowerOn;
    195 => BAUD_RATE, "baud rate", "bit/s", 150, 9600, 115200, PowerOn;
    196 => OPERATING_MODE, "RS485 operating mode (sum of valences, see Mode)", "", 0, 0, 127, PowerOn;
}

/// The baud rates P195 accepts for the ASCII protocol (150..115200 bit/s, the usual steps).
pub const BAUD_RATES: &[u32] = &[150, 300, 600, 1200, 2400, 4800, 9600, 19_200, 38_400, 57_600, 115_200];

impl ParamId {
    /// The highest parameter number.
    pub const MAX: u16 = 250;

    /// P1..=P250.
    pub fn new(n: u16) -> Result<Self, ModelError> {
        if (1..=Self::MAX).contains(&n) {
            Ok(ParamId(n))
        } else {
            Err(ModelError::Range { what: "parameter", value: format!("P{n}"), range: "P1..=P250" })
        }
    }

    /// The number.
    pub fn get(self) -> u16 {
        self.0
    }

    /// What is known about it.
    pub fn info(self) -> Option<&'static ParamInfo> {
        KNOWN_PARAMS.iter().find(|i| i.id == self)
    }

    /// Parses `P194`, `p3`, `P003`.
    pub fn parse(text: &str) -> Result<Self, ModelError> {
        let t = text.trim();
        let digits = t.strip_prefix('P').or_else(|| t.strip_prefix('p')).unwrap_or(t);
        digits.parse::<u16>().map_err(|_| syntax("a parameter (P1..P250)", text.as_bytes())).and_then(ParamId::new)
    }

    /// Checks a value against the parameter's known range (unknown parameters accept any finite value).
    pub fn check(self, value: f64) -> Result<(), ModelError> {
        if !value.is_finite() {
            return Err(ModelError::Range { what: "parameter value", value: value.to_string(), range: "finite" });
        }
        let range_err = |range| ModelError::Range { what: "parameter value", value: format!("{self}={value}"), range };
        match self {
            ParamId::BAUD_RATE if !BAUD_RATES.iter().any(|&b| f64::from(b) == value) => {
                Err(range_err("150, 300, 600, 1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200"))
            }
            ParamId::OPERATING_MODE if value.fract() != 0.0 || !(0.0..=127.0).contains(&value) => {
                Err(range_err("0..=127 (sum of the valences 1, 2, 4, 8, 16, 32, 64)"))
            }
            ParamId::DEVICE_ADDRESS if value.fract() != 0.0 || !(0.0..=31.0).contains(&value) => {
                Err(range_err("0..=31"))
            }
            _ => Ok(()),
        }
    }
}

impl fmt::Display for ParamId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "P{:03}", self.0)
    }
}

/// Reads the reply text to `P<id>`: `P194=5`, `P194: 5`, or the value alone.
pub fn parse_param_reply(id: ParamId, text: &[u8]) -> Result<f64, ModelError> {
    parse_decimal_trimmed(strip_name(text, b'P', id.0)).ok_or_else(|| syntax("a parameter value", text))
}

/// Writes the reply a drive sends for `P<id>` (the emulator's side): `P194=5`, the form of a write.
pub fn write_param_reply(id: ParamId, value: f64, out: &mut impl fmt::Write) -> fmt::Result {
    write!(out, "{id}=")?;
    write_decimal(out, value, MAX_DECIMALS)
}

// ------------------------------------------------------------------------------------------------------
// Commands

/// Long (`POSA`) or short (`PA`) command names.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum CommandStyle {
    /// `POSA`, `POSR`, `SPEED`, `ACCEL`, `ACCEL-`, `OUTPUT`, `POSA HOME`.
    #[default]
    Long,
    /// `PA`, `PR`, `SD`, `AL`, `AL-`, `OT`, `PH`.
    Short,
}

/// A command of the drive's vocabulary.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Command {
    /// `POSA value`: move to an absolute position.
    PosA(Position),
    /// `POSR value`: move by a distance.
    PosR(Position),
    /// `POSA HOME`: find machine zero.
    PosAHome,
    /// `SPEED value`: speed of the next positionings.
    Speed(SpeedPercent),
    /// `ACCEL value`: acceleration and braking time.
    Accel(RampMs),
    /// `ACCEL- value`: braking time alone.
    AccelBrake(RampMs),
    /// `OUTPUT Ox=y`.
    Output {
        /// Output number (0: the drive itself).
        output: u16,
        /// State.
        state: OutputState,
    },
    /// `POSR value OUTPUT Ox=y`: a comparator for the next positioning.
    PosROutput {
        /// Distance after which the output switches.
        distance: Position,
        /// Output number.
        output: u16,
        /// State.
        state: OutputState,
    },
    /// `POSR value1 SPEED value2`: a speed step for the next positioning.
    PosRSpeed {
        /// Distance after which the speed changes.
        distance: Position,
        /// The new speed.
        speed: SpeedPercent,
    },
    /// `Sn`: read a status value.
    ReadStatus(StatusId),
    /// `Pnnn`: read a parameter.
    ReadParam(ParamId),
    /// `Pnnn=value`: write a parameter.
    WriteParam(ParamId, f64),
}

/// A command string of at most 40 characters.
pub type CommandText = TextBuf<MAX_COMMAND_LEN>;

impl Command {
    /// The command that switches the drive off: `OUTPUT O0=0`, the stop this crate uses (see the crate's
    /// decisions).
    pub const SWITCH_OFF: Command = Command::Output { output: 0, state: OutputState::OFF };

    /// True for commands that start a motion (they take `$`, and E92 refuses them while the axis moves).
    pub fn is_move(&self) -> bool {
        matches!(self, Command::PosA(_) | Command::PosR(_) | Command::PosAHome)
    }

    /// True when sending the command twice has the same effect as once. A relative move is not, nor is a
    /// comparator or speed step (each adds one).
    pub fn is_idempotent(&self) -> bool {
        !matches!(self, Command::PosR(_) | Command::PosROutput { .. } | Command::PosRSpeed { .. })
    }

    /// The ASCII command string.
    #[inline]
    pub fn to_ascii(&self, style: CommandStyle) -> Result<CommandText, ModelError> {
        let mut t = CommandText::new();
        self.write_ascii_into(style, &mut t)?;
        Ok(t)
    }

    /// [`to_ascii`](Self::to_ascii) into `text`, replacing what it held (left empty on an error): no command
    /// string to copy out of a returned value, and one buffer can serve every request.
    ///
    /// ```
    /// use motionlink_compax::model::{Command, CommandStyle, CommandText, StatusId};
    /// let mut text = CommandText::new();
    /// Command::ReadStatus(StatusId::ACTUAL_POSITION).write_ascii_into(CommandStyle::Long, &mut text).unwrap();
    /// assert_eq!(text.as_str(), "S1");
    /// ```
    #[inline]
    pub fn write_ascii_into(&self, style: CommandStyle, text: &mut CommandText) -> Result<(), ModelError> {
        // The polled reads are written without the formatting machinery (the hot path).
        let fast = match self {
            Command::ReadStatus(s) => Some((b'S', u16::from(s.0))),
            Command::ReadParam(p) => Some((b'P', p.0)),
            _ => None,
        };
        if let Some((letter, n)) = fast {
            // `S1`, `S16` (no leading zeros), `P194`, `P003` (three digits): n <= 250.
            let digits = [letter, b'0' + (n / 100) as u8, b'0' + (n / 10 % 10) as u8, b'0' + (n % 10) as u8];
            match (letter, n) {
                (b'P', _) | (_, 100..) => text.set_ascii(digits, 4),
                (_, 10..) => text.set_ascii([letter, digits[2], digits[3]], 3),
                _ => text.set_ascii([letter, digits[3]], 2),
            }
            return Ok(());
        }
        text.clear();
        if self.write_ascii(style, text).is_err() {
            let len = text.as_bytes().len() + 1;
            text.clear();
            return Err(WireError::TooLong(len).into());
        }
        Ok(())
    }

    fn write_ascii(&self, style: CommandStyle, t: &mut impl fmt::Write) -> fmt::Result {
        let long = style == CommandStyle::Long;
        let name = |l: &'static str, s: &'static str| if long { l } else { s };
        match self {
            Command::PosA(p) => write!(t, "{} {p}", name("POSA", "PA")),
            Command::PosR(p) => write!(t, "{} {p}", name("POSR", "PR")),
            Command::PosAHome => t.write_str(name("POSA HOME", "PH")),
            Command::Speed(s) => write!(t, "{} {s}", name("SPEED", "SD")),
            Command::Accel(ms) => write!(t, "{} {}", name("ACCEL", "AL"), ms.0),
            Command::AccelBrake(ms) => write!(t, "{} {}", name("ACCEL-", "AL-"), ms.0),
            Command::Output { output, state } => write!(t, "{} O{output}={}", name("OUTPUT", "OT"), state.0),
            Command::PosROutput { distance, output, state } => {
                write!(t, "{} {distance} {} O{output}={}", name("POSR", "PR"), name("OUTPUT", "OT"), state.0)
            }
            Command::PosRSpeed { distance, speed } => {
                write!(t, "{} {distance} {} {speed}", name("POSR", "PR"), name("SPEED", "SD"))
            }
            Command::ReadStatus(s) => write!(t, "S{}", s.0),
            Command::ReadParam(p) => write!(t, "{p}"),
            Command::WriteParam(p, v) => {
                write!(t, "{p}=")?;
                write_decimal(t, *v, MAX_DECIMALS)
            }
        }
    }

    /// The binary form, for the commands of the binary table.
    pub fn to_binary(&self) -> Result<BinaryCommand, ModelError> {
        let out = |_output: u16, state: OutputState| match state.0 {
            0 | 1 => Ok(state.0 == 1),
            _ => Err(ModelError::NoBinary("OUTPUT O0=2")),
        };
        Ok(match *self {
            Command::PosA(p) => BinaryCommand::PosA(p.to_fixed()),
            Command::PosR(p) => BinaryCommand::PosR(p.to_fixed()),
            Command::Speed(s) => BinaryCommand::Speed(Fixed24::from_f64(s.0).map_err(WireError::from)?),
            Command::Accel(ms) => BinaryCommand::Accel(ms.0 as i16),
            Command::AccelBrake(ms) => BinaryCommand::AccelBrake(ms.0 as i16),
            Command::Output { output, state } => BinaryCommand::Output { output, on: out(output, state)? },
            Command::PosROutput { distance, output, state } => {
                BinaryCommand::PosROutput { distance: distance.to_fixed(), output, on: out(output, state)? }
            }
            Command::PosRSpeed { distance, speed } => BinaryCommand::PosRSpeed {
                distance: distance.to_fixed(),
                speed: Fixed24::from_f64(speed.0).map_err(WireError::from)?,
            },
            Command::PosAHome => return Err(ModelError::NoBinary("POSA HOME")),
            Command::ReadStatus(_) => return Err(ModelError::NoBinary("a status read")),
            Command::ReadParam(_) | Command::WriteParam(..) => return Err(ModelError::NoBinary("a parameter")),
        })
    }

    /// The command a binary telegram carries, checked against the model's ranges.
    pub fn from_binary(b: &BinaryCommand) -> Result<Command, ModelError> {
        let pos = |f: Fixed24| Position::new(f.to_f64());
        let ramp = |ms: i16| {
            RampMs::new(u32::try_from(ms).map_err(|_| ModelError::Range {
                what: "ramp time",
                value: format!("{ms} ms"),
                range: "0..=32767 ms",
            })?)
        };
        Ok(match *b {
            BinaryCommand::PosA(v) => Command::PosA(pos(v)?),
            BinaryCommand::PosR(v) => Command::PosR(pos(v)?),
            BinaryCommand::Speed(v) => Command::Speed(SpeedPercent::new(v.to_f64())?),
            BinaryCommand::Accel(ms) => Command::Accel(ramp(ms)?),
            BinaryCommand::AccelBrake(ms) => Command::AccelBrake(ramp(ms)?),
            BinaryCommand::Output { output, on } => Command::Output { output, state: OutputState(on.into()) },
            BinaryCommand::PosROutput { distance, output, on } => {
                Command::PosROutput { distance: pos(distance)?, output, state: OutputState(on.into()) }
            }
            BinaryCommand::PosRSpeed { distance, speed } => {
                Command::PosRSpeed { distance: pos(distance)?, speed: SpeedPercent::new(speed.to_f64())? }
            }
        })
    }

    /// Parses an ASCII command string (upper case, long or short names, the space before a value optional):
    /// `POSA1000`, `PR 200 OT O9=1`, `SD 50`, `S16`, `P003=-1055.88`.
    pub fn parse(text: &[u8]) -> Result<Command, ModelError> {
        let t = trim(text);
        let bad = || syntax("a command", text);
        let number = |s: &[u8]| parse_decimal_bytes(s).ok_or_else(bad);
        // Longest names first, so that `POSA HOME` is not `POSA`, `ACCEL-` not `ACCEL`, `SD` not `S`.
        if let Some(rest) = strip(t, &[b"POSA HOME", b"POSAHOME", b"PH"]) {
            return if rest.is_empty() { Ok(Command::PosAHome) } else { Err(bad()) };
        }
        if let Some(rest) = strip(t, &[b"POSA", b"PA"]) {
            return Ok(Command::PosA(Position::new(number(rest)?)?));
        }
        if let Some(rest) = strip(t, &[b"POSR", b"PR"]) {
            let rest = trim(rest);
            let split = rest.iter().position(|c| c.is_ascii_alphabetic()).unwrap_or(rest.len());
            let distance = Position::new(number(&rest[..split])?)?;
            let tail = trim(&rest[split..]);
            if tail.is_empty() {
                return Ok(Command::PosR(distance));
            }
            if let Some(out) = strip(tail, &[b"OUTPUT", b"OT"]) {
                let (output, state) = parse_output(trim(out)).ok_or_else(bad)?;
                return Ok(Command::PosROutput { distance, output, state });
            }
            if let Some(sp) = strip(tail, &[b"SPEED", b"SD"]) {
                return Ok(Command::PosRSpeed { distance, speed: SpeedPercent::new(number(sp)?)? });
            }
            return Err(bad());
        }
        if let Some(rest) = strip(t, &[b"SPEED", b"SD"]) {
            return Ok(Command::Speed(SpeedPercent::new(number(rest)?)?));
        }
        let ramp = |rest: &[u8]| {
            let v = number(rest)?;
            if v.fract() != 0.0 || v < 0.0 {
                return Err(ModelError::Range { what: "ramp time", value: format!("{v}"), range: "0..=32767 ms" });
            }
            RampMs::new(v.min(u32::MAX as f64) as u32)
        };
        if let Some(rest) = strip(t, &[b"ACCEL-", b"AL-"]) {
            return Ok(Command::AccelBrake(ramp(rest)?));
        }
        if let Some(rest) = strip(t, &[b"ACCEL", b"AL"]) {
            return Ok(Command::Accel(ramp(rest)?));
        }
        if let Some(rest) = strip(t, &[b"OUTPUT", b"OT"]) {
            let (output, state) = parse_output(trim(rest)).ok_or_else(bad)?;
            return Ok(Command::Output { output, state });
        }
        if let [b'S', digits @ ..] = t {
            let n = small_number(digits).ok_or_else(bad)?;
            return Ok(Command::ReadStatus(StatusId::new(u8::try_from(n).map_err(|_| bad())?)?));
        }
        if let [b'P', rest @ ..] = t {
            let eq = rest.iter().position(|&c| c == b'=');
            let (digits, value) = match eq {
                Some(i) => (&rest[..i], Some(&rest[i + 1..])),
                None => (rest, None),
            };
            let id = ParamId::new(small_number(trim(digits)).ok_or_else(bad)?)?;
            return match value {
                None => Ok(Command::ReadParam(id)),
                Some(v) => Ok(Command::WriteParam(id, number(v)?)),
            };
        }
        Err(bad())
    }
}

impl fmt::Display for Command {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.write_ascii(CommandStyle::Long, f)
    }
}

fn strip<'a>(t: &'a [u8], names: &[&[u8]]) -> Option<&'a [u8]> {
    names.iter().find_map(|n| t.strip_prefix(*n))
}

fn small_number(digits: &[u8]) -> Option<u16> {
    if digits.is_empty() || digits.len() > 4 || !digits.iter().all(u8::is_ascii_digit) {
        return None;
    }
    Some(digits.iter().fold(0u16, |a, d| a * 10 + u16::from(d - b'0')))
}

/// `O9=1` → (9, 1). The RS485 manual's binary table (4.4.1) writes the output as `Ayy` (`OUTPUT Ayy=0`),
/// while its binary code is `4F` (`O`) and the user guide writes `O9=1`: both spellings are read; the
/// command is always written back with `O`.
fn parse_output(t: &[u8]) -> Option<(u16, OutputState)> {
    let rest = t.strip_prefix(b"O").or_else(|| t.strip_prefix(b"A"))?;
    let eq = rest.iter().position(|&c| c == b'=')?;
    let output = small_number(trim(&rest[..eq]))?;
    let state = small_number(trim(&rest[eq + 1..]))?;
    Some((output, OutputState::new(output, u8::try_from(state).ok()?).ok()?))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(v: f64) -> Position {
        Position::new(v).unwrap()
    }

    #[test]
    fn the_manuals_a_spelling_of_outputs_is_read_and_written_as_o() {
        // Manual 4.4.1: `OUTPUT Ayy=0|1` and `POSR value OUTPUT Ayy=0|1`.
        let c = Command::parse(b"OUTPUT A09=1").unwrap();
        assert_eq!(c, Command::Output { output: 9, state: OutputState::ON });
        assert_eq!(c.to_ascii(CommandStyle::Long).unwrap().as_str(), "OUTPUT O9=1");
        let c = Command::parse(b"POSR 200 OUTPUT A9=0").unwrap();
        assert_eq!(c, Command::PosROutput { distance: p(200.0), output: 9, state: OutputState::new(9, 0).unwrap() });
        assert_eq!(c.to_ascii(CommandStyle::Short).unwrap().as_str(), "PR 200 OT O9=0");
        assert!(Command::parse(b"OUTPUT B9=1").is_err());
    }

    #[test]
    fn commands_in_both_styles_round_trip() {
        let cmds = [
            (Command::PosA(p(2500.0)), "POSA 2500", "PA 2500"),
            (Command::PosR(p(-15.8)), "POSR -15.8", "PR -15.8"),
            (Command::PosAHome, "POSA HOME", "PH"),
            (Command::Speed(SpeedPercent::new(50.0).unwrap()), "SPEED 50", "SD 50"),
            (Command::Accel(RampMs::new(500).unwrap()), "ACCEL 500", "AL 500"),
            (Command::AccelBrake(RampMs::new(250).unwrap()), "ACCEL- 250", "AL- 250"),
            (Command::Output { output: 9, state: OutputState::ON }, "OUTPUT O9=1", "OT O9=1"),
            (
                Command::PosROutput { distance: p(200.0), output: 9, state: OutputState::ON },
                "POSR 200 OUTPUT O9=1",
                "PR 200 OT O9=1",
            ),
            (
                Command::PosRSpeed { distance: p(100.0), speed: SpeedPercent::new(50.0).unwrap() },
                "POSR 100 SPEED 50",
                "PR 100 SD 50",
            ),
            (Command::ReadStatus(StatusId::ACTUAL_POSITION), "S1", "S1"),
            (Command::ReadParam(ParamId::DEVICE_ADDRESS), "P194", "P194"),
            (Command::WriteParam(ParamId::new(3).unwrap(), -1055.88), "P003=-1055.88", "P003=-1055.88"),
        ];
        for (c, long, short) in cmds {
            assert_eq!(c.to_ascii(CommandStyle::Long).unwrap().as_str(), long);
            assert_eq!(c.to_ascii(CommandStyle::Short).unwrap().as_str(), short);
            assert_eq!(Command::parse(long.as_bytes()).unwrap(), c, "{long}");
            assert_eq!(Command::parse(short.as_bytes()).unwrap(), c, "{short}");
        }
        // The user guide writes values with and without a space.
        assert_eq!(Command::parse(b"POSA1000").unwrap(), Command::PosA(p(1000.0)));
        assert_eq!(Command::parse(b"POSR15.8").unwrap(), Command::PosR(p(15.8)));
        assert_eq!(
            Command::parse(b"PR 100 SD 50").unwrap().to_ascii(CommandStyle::Short).unwrap().as_str(),
            "PR 100 SD 50"
        );
    }

    #[test]
    fn bad_commands_and_ranges() {
        for bad in [
            &b"POSA"[..],
            b"POSA x",
            b"SPEED 0",
            b"SPEED 101",
            b"ACCEL 40000",
            b"ACCEL -1",
            b"OUTPUT O9=2",
            b"OUTPUT 9=1",
            b"S41",
            b"S0",
            b"P251=1",
            b"P0",
            b"XYZ",
            b"PH 5",
            b"PR 1 OT",
            b"PR 1 XX 5",
            b"",
        ] {
            assert!(Command::parse(bad).is_err(), "{:?}", String::from_utf8_lossy(bad));
        }
        assert!(Command::parse(b"OUTPUT O0=2").is_ok());
        assert!(Position::new(1e7).is_err());
        assert!(SpeedPercent::new(f64::NAN).is_err());
        assert!(RampMs::new(32_768).is_err());
    }

    #[test]
    fn binary_forms() {
        let c = Command::PosA(p(360.0));
        assert_eq!(Command::from_binary(&c.to_binary().unwrap()).unwrap(), c);
        assert!(Command::PosAHome.to_binary().is_err());
        assert!(Command::Output { output: 0, state: OutputState::new(0, 2).unwrap() }.to_binary().is_err());
        assert!(Command::from_binary(&BinaryCommand::Accel(-5)).is_err());
        assert!(Command::from_binary(&BinaryCommand::Speed(Fixed24::from_f64(150.0).unwrap())).is_err());
    }

    #[test]
    fn status_values() {
        let v = StatusValue::parse(StatusId::ACTUAL_POSITION, b"S001: -12.500").unwrap();
        assert_eq!(v, StatusValue::Position(p(-12.5)));
        assert_eq!(
            StatusValue::parse(StatusId::ACTUAL_POSITION, b"+0360.000").unwrap(),
            StatusValue::Position(p(360.0))
        );
        // The user guide's example: password 302 active is S17 = "1000 0000" = 0x80.
        let StatusValue::S17(b) = StatusValue::parse(StatusId::STATUS_BITS_2, b"S017: 1000 0000").unwrap() else {
            panic!()
        };
        assert_eq!(b.0, 0x80);
        assert!(b.bit(S17Bits::PASSWORD_302));
        assert_eq!(b.names_set().collect::<Vec<_>>(), ["password 302 active"]);
        // The user guide's S18 example.
        let h = StatusValue::parse(StatusId::ERROR_HISTORY, b"S018: 99 55 10 99 53 98 10 99").unwrap();
        let StatusValue::History(h) = h else { panic!() };
        assert_eq!(h[1], HistoryEntry::Error(ErrorCode::EMERGENCY_STOP));
        assert_eq!(h[5], HistoryEntry::PowerOn);
        assert!(StatusValue::parse(StatusId::STATUS_BITS_1, b"S016: 1000").is_err());
        assert!(StatusValue::parse(StatusId::ACTUAL_POSITION, b"S002: 1").is_err());
        let mut out = TextBuf::<48>::new();
        StatusValue::Position(p(360.0)).write_reply(StatusId::ACTUAL_POSITION, &mut out).unwrap();
        assert_eq!(out.as_str(), "S001: 360.000");
        out.clear();
        StatusValue::S16(S16Bits(0b1101_0010)).write_reply(StatusId::STATUS_BITS_1, &mut out).unwrap();
        assert_eq!(out.as_str(), "S016: 1101 0010");
        let u = StatusId::new(4).unwrap();
        assert_eq!(u.kind(), StatusKind::Text);
    }

    #[test]
    fn long_text_values_are_cut_between_characters() {
        let id = StatusId::DEVICE_ID_1;
        // 'a' and then two-byte characters: byte 48 falls inside one.
        let text = format!("a{}", "é".repeat(30));
        let StatusValue::Text(t) = StatusValue::parse(id, text.as_bytes()).unwrap() else { panic!() };
        assert_eq!(t.as_str(), format!("a{}", "é".repeat(23)));
        assert_eq!(t.as_str().len(), 47);
        let text = "€".repeat(20); // three bytes each: 48 is a boundary
        let StatusValue::Text(t) = StatusValue::parse(id, text.as_bytes()).unwrap() else { panic!() };
        assert_eq!(t.as_str(), "€".repeat(16));
        let StatusValue::Text(t) = StatusValue::parse(id, b"S031: COMPAX 0260M").unwrap() else { panic!() };
        assert_eq!(t.as_str(), "COMPAX 0260M");
    }

    #[test]
    fn errors_and_params() {
        assert_eq!(
            ErrorCode(72).to_string(),
            "E72 (block-check character error: the telegram was discarded, retransmit it)"
        );
        assert!(ErrorCode(73).is_retransmit() && !ErrorCode(74).is_retransmit());
        assert!(ErrorCode(70).is_retransmit() && ErrorCode(72).is_retransmit());
        assert!(!ErrorCode(71).is_retransmit(), "E71: retransmit with fewer characters, not the same telegram");
        assert_eq!(ErrorCode(10).meaning(), None);
        assert_eq!(parse_param_reply(ParamId::DEVICE_ADDRESS, b"P194=5").unwrap(), 5.0);
        assert_eq!(parse_param_reply(ParamId::DEVICE_ADDRESS, b"5").unwrap(), 5.0);
        assert_eq!(parse_param_reply(ParamId::new(3).unwrap(), b"P003: -1055.88").unwrap(), -1055.88);
        assert!(parse_param_reply(ParamId::DEVICE_ADDRESS, b"P195=9600").is_err());
        assert!(ParamId::BAUD_RATE.check(9600.0).is_ok());
        assert!(ParamId::BAUD_RATE.check(9601.0).is_err());
        assert!(ParamId::OPERATING_MODE.check(127.0).is_ok());
        assert!(ParamId::OPERATING_MODE.check(164.0).is_err());
        assert!(ParamId::DEVICE_ADDRESS.check(32.0).is_err());
        let mut t = TextBuf::<40>::new();
        write_param_reply(ParamId::BAUD_RATE, 9600.0, &mut t).unwrap();
        assert_eq!(t.as_str(), "P195=9600");
        assert_eq!(ParamId::parse("p3").unwrap(), ParamId::new(3).unwrap());
        assert_eq!(StatusId::parse("S016").unwrap(), StatusId::STATUS_BITS_1);
    }

    #[test]
    fn status_lookup_is_the_table() {
        for n in 0..=StatusId::MAX {
            let id = StatusId(n);
            assert_eq!(id.info(), KNOWN_STATUS.iter().find(|i| i.id == id), "S{n}");
            assert_eq!(id.kind(), id.info().map_or(StatusKind::Text, |i| i.kind), "S{n}");
        }
        assert_eq!(StatusId(200).info(), None);
    }

    #[test]
    fn command_text_in_place() {
        let cmds = [
            Command::ReadStatus(StatusId::ACTUAL_POSITION),
            Command::ReadStatus(StatusId::STATUS_BITS_2),
            Command::ReadStatus(StatusId::new(40).unwrap()),
            Command::ReadParam(ParamId::new(3).unwrap()),
            Command::ReadParam(ParamId::OPERATING_MODE),
            Command::WriteParam(ParamId::new(250).unwrap(), -1055.88),
            Command::PosROutput { distance: p(-8_388_608.0), output: 65_535, state: OutputState::ON },
            Command::PosA(p(0.5)),
            Command::PosAHome,
        ];
        // One buffer for all, so that a short text follows a long one.
        let mut text = CommandText::new();
        for style in [CommandStyle::Long, CommandStyle::Short] {
            for c in cmds.iter().chain(cmds.iter().rev()) {
                let owned = c.to_ascii(style).unwrap();
                c.write_ascii_into(style, &mut text).unwrap();
                assert_eq!(text, owned, "{c:?}");
                assert_eq!(text.as_str(), owned.as_str());
                assert!(!text.overflowed());
            }
        }
    }

    /// The name stripping as it was before the three-digit form was compared at once.
    fn strip_name_reference(text: &[u8], letter: u8, number: u16) -> &[u8] {
        let t = trim(text);
        if t.first().is_some_and(|c| c.eq_ignore_ascii_case(&letter)) {
            let digits = t[1..].iter().take_while(|c| c.is_ascii_digit()).count();
            let n = t[1..1 + digits].iter().fold(0u32, |a, d| a.saturating_mul(10).saturating_add(u32::from(d - b'0')));
            if digits > 0 && n == u32::from(number) {
                let mut rest = &t[1 + digits..];
                if let [b':' | b'=', r @ ..] = rest {
                    rest = r;
                }
                return trim(rest);
            }
        }
        t
    }

    #[test]
    fn names_at_the_edges_of_the_three_digit_form() {
        for (text, number, value) in [
            (&b"S001: 5"[..], 1, &b"5"[..]),
            (b" s001= 5 ", 1, b"5"),
            (b"S001", 1, b""),
            (b"S0011: 5", 1, b"S0011: 5"),
            (b"S0011: 5", 11, b"5"),
            (b"S001: 5", 1001, b"S001: 5"),
            (b"S1001: 5", 1001, b"5"),
            (b"S000: 5", 0, b"5"),
            (b"S01: 5", 1, b"5"),
            (b"P194=5", 194, b"5"),
        ] {
            let letter = text.trim_ascii_start()[0].to_ascii_uppercase();
            assert_eq!(strip_name(text, letter, number), value, "{:?} {number}", String::from_utf8_lossy(text));
            assert_eq!(strip_name_reference(text, letter, number), value);
        }
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig { cases: 3000, ..Default::default() })]

        #[test]
        fn names_are_stripped_as_before(
            number in proptest::prop_oneof![0u16..=300, proptest::num::u16::ANY],
            letter in proptest::sample::select(vec![b'S', b'P']),
            // A name made for the number (zero-padded, perhaps more digits, the other case) or any text.
            name in (0usize..7, "[0-9]{0,2}", proptest::bool::ANY, "[ ]{0,2}", "[:=]?", "[ ]{0,3}"),
            value in "[-+0-9. a]{0,8}[ ]{0,2}",
            noise in proptest::option::of("[ ]{0,2}[SsPpx]?[0-9]{0,7}[:=]?[ ]{0,3}[-+0-9. a]{0,8}[ ]{0,2}"),
        ) {
            let (width, extra, lower, lead, sep, gap) = name;
            let l = if lower { letter.to_ascii_lowercase() } else { letter } as char;
            let text = noise.unwrap_or_else(|| format!("{lead}{l}{number:0width$}{extra}{sep}{gap}{value}"));
            proptest::prop_assert_eq!(
                strip_name(text.as_bytes(), letter, number),
                strip_name_reference(text.as_bytes(), letter, number)
            );
        }
    }
}
