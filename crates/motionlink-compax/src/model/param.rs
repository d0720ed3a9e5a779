//! Parameters P1..P250: their numbers, and the table of those the RS485 manual describes, as rows of the
//! shared [`Table`] ([`PARAMS`]).
//!
//! ```
//! use motionlink_compax::model::{ParamId, PARAMS};
//! assert_eq!(PARAMS.lookup("baud_rate").map(|e| e.id), Some(195));
//! assert_eq!(PARAMS.lookup("196").map(|e| e.name), Some("operating_mode"));
//! assert_eq!(ParamId::parse("device_address").unwrap(), ParamId::DEVICE_ADDRESS);
//! ```

use std::fmt;

use motionlink_link::table::{Access, Entry, Table};

use super::value::strip_name;
use super::{shown, syntax, unknown_name, Command, CommandStyle, ModelError};
use crate::wire::number::{decimal_as_sent, parse_decimal_trimmed, same_decimal, write_decimal, MAX_DECIMALS};

/// A parameter number, P1..=P250.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ParamId(pub(crate) u16);

/// When a new parameter value takes effect.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ValidFrom {
    /// At the next power-on.
    PowerOn,
    /// At once.
    Immediately,
}

/// What the COMPAX table says of a parameter besides the shared columns.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParamDetail {
    /// Smallest value.
    pub min: f64,
    /// Factory value.
    pub default: f64,
    /// Largest value.
    pub max: f64,
    /// When a change takes effect.
    pub valid_from: ValidFrom,
}

/// Writes the constants of [`ParamId`] and the rows of [`PARAMS`] from one list.
macro_rules! param_table {
    ($( $num:literal => $konst:ident, $name:literal, $title:literal, $unit:literal, $min:literal, $default:literal,
        $max:literal, $valid:ident; )*) => {
        impl ParamId {
            $(
                #[doc = concat!("P", stringify!($num), ": ", $title, ".")]
                pub const $konst: ParamId = ParamId($num);
            )*
        }

        /// The rows of [`PARAMS`].
        const PARAM_ENTRIES: &[Entry<ParamDetail>] = &[
            $( Entry { id: $num, name: $name, title: $title, unit: $unit, access: Access::ReadWrite,
                       kind: ParamDetail { min: $min as f64, default: $default as f64, max: $max as f64,
                                           valid_from: ValidFrom::$valid } }, )*
        ];
    };
}

// P196's maximum is printed as 31, but the table of valences above it adds 32 and 64 (and 164 / 165 for
// the fieldbus): 127 is the largest ASCII mode.
param_table! {
    194 => DEVICE_ADDRESS, "device_address", "device address", "", 0, 0, 31, PowerOn;
    195 => BAUD_RATE, "baud_rate", "baud rate", "bit/s", 150, 9600, 115200, PowerOn;
    196 => OPERATING_MODE, "operating_mode", "RS485 operating mode (sum of valences, see Mode)", "", 0, 0, 127, PowerOn;
}

/// The parameters of the RS485 interface (manual chapter 5), found by name or number like every family's
/// table.
pub static PARAMS: Table<ParamDetail> = Table::new("parameter", PARAM_ENTRIES);

/// The baud rates P195 accepts for the ASCII protocol (150..115200 bit/s, the usual steps).
pub const BAUD_RATES: &[u32] = &[150, 300, 600, 1200, 2400, 4800, 9600, 19_200, 38_400, 57_600, 115_200];

/// The baud rates P195 takes for the COMTAC fieldbus protocol, P196 = 164 / 165 (manual 3.3.2 and chapter 5).
/// P195 can be written with them (to prepare a drive for the fieldbus); this crate speaks ASCII only.
pub const FIELDBUS_BAUD_RATES: &[u32] = &[28_800, 57_600, 172_800, 345_600];

/// The P196 values that select the COMTAC fieldbus protocol (option F5; 165 with F5 software >= V1.22 and
/// COMPAX > V2.0): the manual's own instruction for a fieldbus drive. Written, they take effect at the next
/// power-on, and from then on the drive answers no ASCII telegram.
pub const FIELDBUS_MODES: &[u32] = crate::wire::Mode::FIELDBUS_P196;

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

    /// Its row of [`PARAMS`], if its meaning is known.
    pub fn info(self) -> Option<&'static Entry<ParamDetail>> {
        PARAMS.by_id(u32::from(self.0))
    }

    /// What it sets, if known.
    pub fn description(self) -> Option<&'static str> {
        self.info().map(|i| i.title)
    }

    /// Parses `P194`, `p3`, `P003`, or a name of [`PARAMS`] (`device_address`).
    pub fn parse(text: &str) -> Result<Self, ModelError> {
        let t = text.trim();
        if let Some(e) = PARAMS.by_name(t) {
            return ParamId::new(e.id as u16);
        }
        let digits = t.strip_prefix('P').or_else(|| t.strip_prefix('p')).unwrap_or(t);
        digits
            .parse::<u16>()
            .map_err(|_| unknown_name("a parameter", t, &PARAMS, "give P1..P250 or a name such as device_address"))
            .and_then(ParamId::new)
    }

    /// Checks a value against the parameter's known range (unknown parameters accept any finite value), and
    /// that the command `P003=value` carries it: a value with more decimals that matter than the command's
    /// six is refused ([`ModelError::Precision`]: it would be written as another number, `P003=0` for
    /// 0.0000001, and read back as that), and so is a command longer than the drive's input buffer
    /// ([`WireError::TooLong`](crate::wire::WireError::TooLong)).
    pub fn check(self, value: f64) -> Result<(), ModelError> {
        if !value.is_finite() {
            return Err(ModelError::Range { what: ParamWrite::WHAT, value: shown(value), range: "finite" });
        }
        self.check_range(value)?;
        let sent = decimal_as_sent(value);
        if !same_decimal(value, sent) {
            return Err(ModelError::Precision {
                what: ParamWrite::WHAT,
                value: format!("{self}={}", shown(value)),
                sent: format!("{self}={}", shown(sent)),
            });
        }
        Command::WriteParam(self, value).to_ascii(CommandStyle::Long).map(|_| ())
    }

    /// The parameter's known range.
    fn check_range(self, value: f64) -> Result<(), ModelError> {
        let range_err =
            |range| ModelError::Range { what: "parameter value", value: format!("{self}={}", shown(value)), range };
        match self {
            ParamId::BAUD_RATE if !BAUD_RATES.iter().chain(FIELDBUS_BAUD_RATES).any(|&b| f64::from(b) == value) => {
                Err(range_err(
                    "150, 300, 600, 1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200; for the fieldbus protocol \
                     (P196 = 164/165): 28800, 57600, 172800, 345600",
                ))
            }
            ParamId::OPERATING_MODE
                if value.fract() != 0.0
                    || !((0.0..=127.0).contains(&value) || FIELDBUS_MODES.iter().any(|&m| f64::from(m) == value)) =>
            {
                Err(range_err(
                    "a whole number 0..=127 (sum of the valences 1, 2, 4, 8, 16, 32, 64), or 164 / 165 (the COMTAC \
                     fieldbus protocol)",
                ))
            }
            ParamId::DEVICE_ADDRESS if value.fract() != 0.0 || !(0.0..=31.0).contains(&value) => {
                Err(range_err("a whole number 0..=31"))
            }
            _ => Ok(()),
        }
    }
}

/// A parameter write, checked: the parameter and a finite value within the parameter's known range
/// ([`ParamId::check`]). Every front end (the command line's `set`, Python's `set`, the gateway's `set`)
/// builds one with [`ParamWrite::new`] (a number) or [`ParamWrite::parse`] (text), so a value that is no
/// number, not finite or out of range is refused with the same words everywhere, before anything is sent.
///
/// ```
/// use motionlink_compax::model::{ParamId, ParamWrite};
/// let w = ParamWrite::parse(ParamId::DEVICE_ADDRESS, "5").unwrap();
/// assert_eq!((w.id(), w.value()), (ParamId::DEVICE_ADDRESS, 5.0));
/// assert_eq!(ParamWrite::parse(ParamId::DEVICE_ADDRESS, "NaN").unwrap_err().to_string(),
///            "parameter value must be a finite number, not NaN");
/// assert_eq!(ParamWrite::parse(ParamId::DEVICE_ADDRESS, "five").unwrap_err().to_string(),
///            "cannot read parameter value from \"five\"");
/// assert!(ParamWrite::new(ParamId::DEVICE_ADDRESS, f64::INFINITY).is_err());
/// assert!(ParamWrite::new(ParamId::DEVICE_ADDRESS, 32.0).is_err());
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParamWrite {
    id: ParamId,
    value: f64,
}

impl ParamWrite {
    /// What a value of the write is, in messages.
    pub const WHAT: &'static str = "parameter value";

    /// `value` for parameter `id`: refused when not finite or outside the parameter's known range.
    pub fn new(id: ParamId, value: f64) -> Result<ParamWrite, ModelError> {
        id.check(value)?;
        Ok(ParamWrite { id, value })
    }

    /// The value `text` (a decimal number, blanks around it ignored) for parameter `id`, as [`ParamWrite::new`]
    /// checks it; text that is no number is [`ModelError::Syntax`], a number that is not finite
    /// [`ModelError::NotFinite`].
    pub fn parse(id: ParamId, text: &str) -> Result<ParamWrite, ModelError> {
        ParamWrite::new(id, super::args::parse_number(Self::WHAT, text)?)
    }

    /// The parameter.
    pub fn id(self) -> ParamId {
        self.id
    }

    /// The value, in the parameter's unit.
    pub fn value(self) -> f64 {
        self.value
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

/// How many decimals the reply text to `P<id>` shows (`P003=1.000`: 3, `P003=1`: 0): the finest step the
/// drive gives the value in.
pub(crate) fn param_reply_decimals(id: ParamId, text: &[u8]) -> usize {
    let v = strip_name(text, b'P', id.0);
    v.iter().position(|&c| c == b'.').map_or(0, |i| v[i + 1..].iter().take_while(|c| c.is_ascii_digit()).count())
}

/// Writes the reply a drive sends for `P<id>` (the emulator's side): `P194=5`, the form of a write.
pub fn write_param_reply(id: ParamId, value: f64, out: &mut impl fmt::Write) -> fmt::Result {
    write!(out, "{id}=")?;
    write_decimal(out, value, MAX_DECIMALS)
}
