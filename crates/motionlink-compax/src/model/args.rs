//! The arguments a front end takes (the command line, the console, Python), each a validated type with one
//! rule and one message: text through [`FromStr`], a whole number through [`WholeArg::from_whole`], a
//! number through the type's `new`. The same bad value is refused with the same words everywhere.
//!
//! Out of range, the message is [`ModelError::Range`] ("drive address 32 is out of range (1..=31)"); text
//! that is no number of the right kind, [`ModelError::Syntax`] ("cannot read drive address from \"x\"").
//!
//! ```
//! use motionlink_compax::model::args::{BaudRate, WholeArg};
//! use motionlink_compax::model::RampMs;
//! use motionlink_compax::wire::Address;
//! assert_eq!("5".parse::<Address>().unwrap().get(), 5);
//! assert_eq!("32".parse::<Address>().unwrap_err().to_string(), "drive address 32 is out of range (1..=31)");
//! assert_eq!(BaudRate::from_whole(19_200).unwrap().bits_per_s(), 19_200);
//! assert!("0".parse::<RampMs>().is_err()); // a ramp of no time: an infinite acceleration
//! ```

use std::fmt;
use std::ops::RangeInclusive;
use std::str::FromStr;
use std::time::Duration;

use super::{shown, ModelError, OutputState, ParamId, Position, RampMs, SpeedPercent, StatusId, BAUD_RATES};
use crate::wire::{Address, Mode};

/// An argument given as a whole number: its one rule, for front ends that have the number itself (Python's
/// `int`); text goes through the type's [`FromStr`], which reads the number and applies the same rule.
pub trait WholeArg: Sized {
    /// What the argument is, in messages ("drive address").
    const WHAT: &'static str;
    /// The span of whole numbers the rule allows (some inside may still be refused: a baud rate is one of
    /// [`BAUD_RATES`]), for a front end's message about a value that is no whole number at all.
    const SPAN: RangeInclusive<i64>;
    /// The argument, or the message that says why `n` is refused.
    fn from_whole(n: i64) -> Result<Self, ModelError>;
}

/// `text` as a whole number of `what` (blanks around it ignored); its range is the caller's.
pub fn whole_number(what: &'static str, text: &str) -> Result<i64, ModelError> {
    let t = text.trim();
    t.parse().map_err(|_| ModelError::Syntax { what, text: t.to_string() })
}

/// `text` as a whole number for argument `T`, then `T`'s rule.
fn parse_whole<T: WholeArg>(text: &str) -> Result<T, ModelError> {
    T::from_whole(whole_number(T::WHAT, text)?)
}

/// `text` as a finite number of `what` (its range is the caller's).
pub(crate) fn parse_number(what: &'static str, text: &str) -> Result<f64, ModelError> {
    let t = text.trim();
    match t.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        Ok(_) => Err(ModelError::NotFinite { what, text: t.to_string() }),
        Err(_) => Err(ModelError::Syntax { what, text: t.to_string() }),
    }
}

fn out_of_range(what: &'static str, value: impl fmt::Display, range: &'static str) -> ModelError {
    ModelError::Range { what, value: value.to_string(), range }
}

impl WholeArg for Address {
    const WHAT: &'static str = "drive address";
    const SPAN: RangeInclusive<i64> = 1..=31;
    /// A drive's own address, 1..=31 (the broadcast 32 addresses no one drive).
    fn from_whole(n: i64) -> Result<Self, ModelError> {
        u8::try_from(n).ok().and_then(|a| Address::drive(a).ok()).ok_or_else(|| out_of_range(Self::WHAT, n, "1..=31"))
    }
}

/// A drive's own address, 1..=31 (`--drive`, `drive=`).
impl FromStr for Address {
    type Err = ModelError;
    fn from_str(s: &str) -> Result<Self, ModelError> {
        parse_whole(s)
    }
}

impl WholeArg for Mode {
    const WHAT: &'static str = "P196";
    const SPAN: RangeInclusive<i64> = 0..=Mode::MAX_P196 as i64;
    /// P196: 0..=127, a sum of the valences (164 and 165, the COMTAC fieldbus protocol, are no ASCII mode).
    fn from_whole(n: i64) -> Result<Self, ModelError> {
        u32::try_from(n)
            .ok()
            .filter(|&v| v <= Mode::MAX_P196)
            .and_then(|v| Mode::from_p196(v).ok())
            .ok_or_else(|| out_of_range(Self::WHAT, n, "0..=127, a sum of the valences 1, 2, 4, 8, 16, 32, 64"))
    }
}

/// P196 as a number, 0..=127 (`--mode`, `mode=`).
impl FromStr for Mode {
    type Err = ModelError;
    fn from_str(s: &str) -> Result<Self, ModelError> {
        parse_whole(s)
    }
}

/// A baud rate P195 accepts ([`BAUD_RATES`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct BaudRate(u32);

impl BaudRate {
    /// 9600 bit/s, the drives' default.
    pub const DEFAULT: BaudRate = BaudRate(9600);

    /// The rate in bit/s.
    pub fn bits_per_s(self) -> u32 {
        self.0
    }
}

impl WholeArg for BaudRate {
    const WHAT: &'static str = "baud rate";
    const SPAN: RangeInclusive<i64> = 150..=115_200;
    fn from_whole(n: i64) -> Result<Self, ModelError> {
        u32::try_from(n).ok().filter(|b| BAUD_RATES.contains(b)).map(BaudRate).ok_or_else(|| {
            out_of_range(
                Self::WHAT,
                n,
                "one P195 accepts: 150, 300, 600, 1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200",
            )
        })
    }
}

/// The rate in bit/s, one of [`BAUD_RATES`] (`--baud`, `baud=`).
impl FromStr for BaudRate {
    type Err = ModelError;
    fn from_str(s: &str) -> Result<Self, ModelError> {
        parse_whole(s)
    }
}

impl fmt::Display for BaudRate {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.0)
    }
}

impl WholeArg for RampMs {
    const WHAT: &'static str = "ramp time";
    const SPAN: RangeInclusive<i64> = 1..=RampMs::MAX as i64;
    /// A ramp time a client asks for: 1..=32767 ms. [`RampMs::new`] also takes 0, which the wire can carry
    /// (a capture may show it), but a ramp of no time asks for an infinite acceleration, which the drive
    /// would clamp to whatever it can.
    fn from_whole(n: i64) -> Result<Self, ModelError> {
        u32::try_from(n).ok().filter(|&ms| ms >= 1).and_then(|ms| RampMs::new(ms).ok()).ok_or_else(|| {
            out_of_range(Self::WHAT, format!("{n} ms"), "1..=32767 ms; 0 would ask for an infinite acceleration")
        })
    }
}

/// A ramp time in ms, 1..=32767 (`--accel`, `ramp_ms=`).
impl FromStr for RampMs {
    type Err = ModelError;
    fn from_str(s: &str) -> Result<Self, ModelError> {
        parse_whole(s)
    }
}

/// A speed in percent, 0.000001 to 100 (`--speed`, `speed_percent=`): see [`SpeedPercent::new`].
impl FromStr for SpeedPercent {
    type Err = ModelError;
    fn from_str(s: &str) -> Result<Self, ModelError> {
        SpeedPercent::new(parse_number("speed", s)?)
    }
}

/// A position or distance in the drive's unit (`--abs`, `--rel`, `--min-pos`, `target=`).
impl FromStr for Position {
    type Err = ModelError;
    fn from_str(s: &str) -> Result<Self, ModelError> {
        Position::new(parse_number("position", s)?)
    }
}

/// `P194`, `p3`, `P003` or a name such as `device_address` ([`ParamId::parse`]).
impl FromStr for ParamId {
    type Err = ModelError;
    fn from_str(s: &str) -> Result<Self, ModelError> {
        ParamId::parse(s)
    }
}

/// `S1`, `s16` or a name such as `actual_position` ([`StatusId::parse`]).
impl FromStr for StatusId {
    type Err = ModelError;
    fn from_str(s: &str) -> Result<Self, ModelError> {
        StatusId::parse(s)
    }
}

/// An output's number (OUTPUT On=s): 0..=65535, output 0 being the drive itself (`output NUMBER`,
/// `number=`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct OutputNumber(u16);

impl OutputNumber {
    /// The number.
    pub fn get(self) -> u16 {
        self.0
    }
}

impl WholeArg for OutputNumber {
    const WHAT: &'static str = "output number";
    const SPAN: RangeInclusive<i64> = 0..=u16::MAX as i64;
    fn from_whole(n: i64) -> Result<Self, ModelError> {
        u16::try_from(n).map(OutputNumber).map_err(|_| out_of_range(Self::WHAT, n, "0..=65535"))
    }
}

impl FromStr for OutputNumber {
    type Err = ModelError;
    fn from_str(s: &str) -> Result<Self, ModelError> {
        parse_whole(s)
    }
}

impl WholeArg for OutputState {
    const WHAT: &'static str = "output state";
    const SPAN: RangeInclusive<i64> = 0..=2;
    /// A state some output takes: 0..=2; whether the output takes it is [`OutputState::for_output`].
    fn from_whole(n: i64) -> Result<Self, ModelError> {
        u8::try_from(n).ok().and_then(|s| OutputState::new(0, s).ok()).ok_or_else(|| output_state_range(n))
    }
}

fn output_state_range(n: impl fmt::Display) -> ModelError {
    out_of_range("output state", n, "0 or 1 (O0: 0, 1 or 2)")
}

/// An output's state, 0..=2 (`output NUMBER STATE`, `state=`); [`OutputState::for_output`] checks it
/// against the output.
impl FromStr for OutputState {
    type Err = ModelError;
    fn from_str(s: &str) -> Result<Self, ModelError> {
        parse_whole(s)
    }
}

impl OutputState {
    /// This state for output `output`: 0 or 1, or 0, 1 or 2 for O0 (the drive's own switch).
    pub fn for_output(self, output: OutputNumber) -> Result<OutputState, ModelError> {
        OutputState::new(output.0, self.0).map_err(|_| output_state_range(self.0))
    }
}

/// How far from its target an axis may come to rest for a checked move to count as done, in the drive's
/// unit: more than 0, at most 1000000 (`--tolerance`, `tolerance_units=`).
#[derive(Debug, Clone, Copy, PartialEq, PartialOrd)]
pub struct Tolerance(Position);

impl Tolerance {
    /// The default: [`DEFAULT_IN_POSITION_TOLERANCE`](crate::session::DEFAULT_IN_POSITION_TOLERANCE).
    pub const DEFAULT: Tolerance = Tolerance(Position(crate::session::DEFAULT_IN_POSITION_TOLERANCE));

    /// A tolerance of `units`; refused unless more than 0 and at most 1000000.
    pub fn new(units: f64) -> Result<Self, ModelError> {
        if units.is_finite() && units > 0.0 && units <= 1e6 {
            Ok(Tolerance(Position(units)))
        } else {
            Err(out_of_range(
                "in-position tolerance",
                shown(units),
                "more than 0, at most 1000000, in the drive's unit",
            ))
        }
    }

    /// The tolerance as a distance in the drive's unit.
    pub fn position(self) -> Position {
        self.0
    }
}

impl FromStr for Tolerance {
    type Err = ModelError;
    fn from_str(s: &str) -> Result<Self, ModelError> {
        Tolerance::new(parse_number("in-position tolerance", s)?)
    }
}

impl fmt::Display for Tolerance {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.0.fmt(f)
    }
}

/// How long a move (or a wait for one) may take before the axis is stopped, in seconds: more than 0 and at
/// most 10⁹ (about 32 years; the PowerCube's bound) (`--timeout-s`, `timeout_s=`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub struct TimeLimit(Duration);

impl TimeLimit {
    /// A limit of `s` seconds; refused unless more than 0 and at most 10⁹.
    pub fn from_secs(s: f64) -> Result<Self, ModelError> {
        Duration::try_from_secs_f64(s)
            .ok()
            .filter(|d| !d.is_zero() && s <= 1e9)
            .map(TimeLimit)
            .ok_or_else(|| out_of_range("time limit", format!("{} s", shown(s)), "more than 0 s, at most 1e9 s"))
    }

    /// The limit.
    pub fn duration(self) -> Duration {
        self.0
    }
}

impl FromStr for TimeLimit {
    type Err = ModelError;
    fn from_str(s: &str) -> Result<Self, ModelError> {
        TimeLimit::from_secs(parse_number("time limit", s)?)
    }
}

/// An interval in whole milliseconds with its own range: one type per setting, each with its rule.
macro_rules! millis_arg {
    ($(#[$doc:meta])* $name:ident, $what:literal, $max:literal, $range:literal) => {
        $(#[$doc])*
        #[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
        pub struct $name(Duration);

        impl $name {
            /// The interval.
            pub fn duration(self) -> Duration {
                self.0
            }
        }

        impl WholeArg for $name {
            const WHAT: &'static str = $what;
            const SPAN: RangeInclusive<i64> = 1..=$max;
            fn from_whole(n: i64) -> Result<Self, ModelError> {
                u64::try_from(n)
                    .ok()
                    .filter(|ms| (1..=$max).contains(ms))
                    .map(|ms| $name(Duration::from_millis(ms)))
                    .ok_or_else(|| out_of_range($what, format!("{n} ms"), $range))
            }
        }

        impl FromStr for $name {
            type Err = ModelError;
            fn from_str(s: &str) -> Result<Self, ModelError> {
                parse_whole(s)
            }
        }

        impl fmt::Display for $name {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                write!(f, "{}", self.0.as_millis())
            }
        }
    };
}

millis_arg!(
    /// The time a drive may take to start answering, on top of the wire time: 1..=60000 ms
    /// (`--timeout-ms`, `timeout_ms=`).
    ReplyTimeout,
    "reply timeout",
    60_000,
    "1..=60000 ms"
);

millis_arg!(
    /// The interval of the status polls while a move is waited for: 1..=10000 ms (`--poll-ms`, `poll_ms=`).
    PollInterval,
    "poll interval",
    10_000,
    "1..=10000 ms"
);

millis_arg!(
    /// The interval between two samples of a watch: 1..=3600000 ms, an hour (`--interval-ms`,
    /// `interval_ms=`).
    WatchInterval,
    "watch interval",
    3_600_000,
    "1..=3600000 ms"
);

#[cfg(test)]
mod tests {
    use super::*;

    fn refused<T: FromStr<Err = ModelError> + fmt::Debug>(text: &str) -> String {
        text.parse::<T>().unwrap_err().to_string()
    }

    #[test]
    fn each_argument_has_one_rule_and_says_what_was_wrong() {
        assert_eq!(refused::<Address>("32"), "drive address 32 is out of range (1..=31)");
        assert_eq!(refused::<Address>("0"), "drive address 0 is out of range (1..=31)");
        assert_eq!(refused::<Address>("x"), "cannot read drive address from \"x\"");
        assert_eq!(Address::from_whole(1000).unwrap_err(), "1000".parse::<Address>().unwrap_err());
        assert_eq!(" 31 ".parse::<Address>().unwrap().get(), 31);

        assert_eq!(
            refused::<Mode>("200"),
            "P196 200 is out of range (0..=127, a sum of the valences 1, 2, 4, 8, 16, 32, 64)"
        );
        assert_eq!(
            refused::<Mode>("-1"),
            "P196 -1 is out of range (0..=127, a sum of the valences 1, 2, 4, 8, 16, 32, 64)"
        );
        assert_eq!("72".parse::<Mode>().unwrap().to_p196(), 72);

        assert!(refused::<BaudRate>("1234").starts_with("baud rate 1234 is out of range (one P195 accepts: 150, "));
        assert_eq!("115200".parse::<BaudRate>().unwrap().bits_per_s(), 115_200);

        assert_eq!(
            refused::<RampMs>("0"),
            "ramp time 0 ms is out of range (1..=32767 ms; 0 would ask for an infinite acceleration)"
        );
        assert!(refused::<RampMs>("32768").starts_with("ramp time 32768 ms is out of range"));
        assert_eq!(RampMs::from_whole(200).unwrap().ms(), 200);
        // The wire still carries 0 (a capture may show it): only an argument is refused.
        assert_eq!(RampMs::new(0).unwrap().ms(), 0);

        let speed_range = "0.000001 to 100 %; a SPEED command carries six decimals: less would be sent as 0";
        assert_eq!(refused::<SpeedPercent>("0"), format!("speed 0 % is out of range ({speed_range})"));
        // A speed the command would carry as 0 is refused as 0 is, naming the value as given.
        assert_eq!(refused::<SpeedPercent>("1e-300"), format!("speed 1e-300 % is out of range ({speed_range})"));
        assert_eq!(refused::<SpeedPercent>("0.0000009"), format!("speed 0.0000009 % is out of range ({speed_range})"));
        assert_eq!("0.000001".parse::<SpeedPercent>().unwrap().to_string(), "0.000001");
        assert_eq!(
            refused::<TimeLimit>("1e-300"),
            "time limit 1e-300 s is out of range (more than 0 s, at most 1e9 s)"
        );
        assert!(refused::<Position>("1e300").starts_with("position 1e300 is out of range"));
        assert_eq!(refused::<SpeedPercent>("fast"), "cannot read speed from \"fast\"");
        assert_eq!(refused::<Position>("nan"), "position must be a finite number, not nan");
        assert_eq!(refused::<Position>("1e400"), "position must be a finite number, not 1e400");
        assert_eq!(refused::<Position>("far"), "cannot read position from \"far\"");
        assert_eq!("-1055.88".parse::<Position>().unwrap().units(), -1055.88);
        assert!(refused::<Position>("1e9").starts_with("position 1000000000 is out of range"));

        assert_eq!(
            refused::<Tolerance>("0"),
            "in-position tolerance 0 is out of range (more than 0, at most 1000000, in the drive's unit)"
        );
        assert_eq!("0.5".parse::<Tolerance>().unwrap().position().units(), 0.5);
        assert_eq!(refused::<TimeLimit>("0"), "time limit 0 s is out of range (more than 0 s, at most 1e9 s)");
        assert_eq!(refused::<TimeLimit>("-1"), "time limit -1 s is out of range (more than 0 s, at most 1e9 s)");
        assert_eq!(refused::<TimeLimit>("1e300"), "time limit 1e300 s is out of range (more than 0 s, at most 1e9 s)");
        assert!(TimeLimit::from_secs(1e9).is_ok());
        assert_eq!("1.5".parse::<TimeLimit>().unwrap().duration(), Duration::from_millis(1500));

        assert_eq!(refused::<ReplyTimeout>("0"), "reply timeout 0 ms is out of range (1..=60000 ms)");
        assert_eq!(refused::<PollInterval>("10001"), "poll interval 10001 ms is out of range (1..=10000 ms)");
        assert_eq!(WatchInterval::from_whole(3_600_000).unwrap().duration(), Duration::from_secs(3600));
        assert_eq!("250".parse::<PollInterval>().unwrap().to_string(), "250");

        let (o0, o3) = (OutputNumber::from_whole(0).unwrap(), "3".parse::<OutputNumber>().unwrap());
        let two = OutputState::from_whole(2).unwrap();
        assert_eq!(two.for_output(o0).unwrap(), OutputState(2));
        assert_eq!(
            two.for_output(o3).unwrap_err().to_string(),
            "output state 2 is out of range (0 or 1 (O0: 0, 1 or 2))"
        );
        assert_eq!(refused::<OutputState>("300"), "output state 300 is out of range (0 or 1 (O0: 0, 1 or 2))");
        assert_eq!(refused::<OutputState>("-5"), "output state -5 is out of range (0 or 1 (O0: 0, 1 or 2))");
        assert_eq!(refused::<OutputNumber>("-1"), "output number -1 is out of range (0..=65535)");

        assert_eq!("P194".parse::<ParamId>().unwrap(), ParamId::DEVICE_ADDRESS);
        assert_eq!(refused::<StatusId>("S99"), "status value S99 is out of range (S1..=S40)");
    }
}
