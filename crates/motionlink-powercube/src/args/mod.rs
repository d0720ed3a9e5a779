//! The family's arguments as validated types: one rule and one message each, for the command line (which
//! parses them from text: [`FromStr`]), the web console and Python (which make them from numbers: the
//! checked constructors). The same bad value gets the same message everywhere: [`Error::InvalidArgument`],
//! "the velocity must be a number above 0 (rad/s or m/s, the module's unit), not -5".
//!
//! ```
//! use motionlink_powercube::args::{Baud, MoveVelocity, Target};
//! assert_eq!("19200".parse::<Baud>().unwrap().get(), 19200);
//! assert_eq!(Baud::new(7).unwrap_err().to_string(),
//!            "the RS232 baud rate must be one of 1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200, not 7");
//! assert!("-5".parse::<MoveVelocity>().unwrap_err().to_string().starts_with("the velocity must be a number above 0"));
//! assert_eq!(Target::new(0.5).unwrap().position().value(), 0.5);
//! ```
//!
//! Module addresses are [`Address`](crate::model::Address) (its `FromStr` and [`Address::new`](crate::model::Address::new)).

use std::fmt;
use std::str::FromStr;
use std::time::Duration;

use motionlink_link::can::SlcanBitrate;

use crate::error::Error;
use crate::model::{Acceleration, AxisUnit, Motion, MotionId, Position, Velocity};
use crate::session::{MotionSpec, MoveSpec};

mod options;
pub use options::{ModuleOptions, OptionError};

/// The refusal of `value` for the argument `what`, which must be `must`.
fn refused(what: &'static str, must: &'static str, value: impl fmt::Display) -> Error {
    Error::InvalidArgument { what, must, value: value.to_string() }
}

/// [`refused`] of a number, shown as the user could have typed it (`1e39`, not its 40 digits).
fn refused_number(what: &'static str, must: &'static str, value: f64) -> Error {
    let plain = value.to_string();
    refused(what, must, if plain.len() > 24 { format!("{value:e}") } else { plain })
}

/// `text` as a number of type `T`, or the refusal naming the argument.
fn number<T: FromStr>(what: &'static str, must: &'static str, text: &str) -> Result<T, Error> {
    text.trim().parse().map_err(|_| refused(what, must, text.trim()))
}

const BAUD_WHAT: &str = "the RS232 baud rate";
const BAUD_MUST: &str = "one of 1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200";

/// An RS232 baud rate the modules run at: one of [`Baud::RATES`] (9600 unless DefPrimBaud says otherwise).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Baud(u32);

impl Baud {
    /// The rates a module's RS232 port takes: the standard rates of a serial port from 1200 up.
    pub const RATES: [u32; 8] = [1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200];
    /// The modules' default, 9600 baud.
    pub const DEFAULT: Baud = Baud(9600);

    /// `bits_per_second`, if it is one of [`Baud::RATES`].
    pub fn new(bits_per_second: u32) -> Result<Baud, Error> {
        if Baud::RATES.contains(&bits_per_second) {
            Ok(Baud(bits_per_second))
        } else {
            Err(refused(BAUD_WHAT, BAUD_MUST, bits_per_second))
        }
    }

    /// The rate in bit/s.
    pub fn get(self) -> u32 {
        self.0
    }
}

impl Default for Baud {
    fn default() -> Baud {
        Baud::DEFAULT
    }
}

impl FromStr for Baud {
    type Err = Error;
    fn from_str(s: &str) -> Result<Baud, Error> {
        Baud::new(number(BAUD_WHAT, BAUD_MUST, s)?)
    }
}

impl fmt::Display for Baud {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(&self.0, f)
    }
}

const BITRATE_WHAT: &str = "the SLCAN bit rate";
const BITRATE_MUST: &str = "one of 10000, 20000, 50000, 100000, 125000, 250000, 500000, 800000, 1000000";

/// The CAN bit rate an SLCAN adapter is opened at: one of the rates SLCAN offers (`S0` .. `S8`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CanBitRate(SlcanBitrate);

impl CanBitRate {
    /// 1 Mbit/s, the modules' default on CAN.
    pub const DEFAULT: CanBitRate = CanBitRate(SlcanBitrate::M1);

    /// `bits_per_second`, if SLCAN offers it.
    pub fn new(bits_per_second: u32) -> Result<CanBitRate, Error> {
        SlcanBitrate::from_bps(bits_per_second)
            .map(CanBitRate)
            .ok_or_else(|| refused(BITRATE_WHAT, BITRATE_MUST, bits_per_second))
    }

    /// The rate in bit/s.
    pub fn get(self) -> u32 {
        self.0.bps()
    }

    /// The adapter's rate.
    pub fn slcan(self) -> SlcanBitrate {
        self.0
    }
}

impl Default for CanBitRate {
    fn default() -> CanBitRate {
        CanBitRate::DEFAULT
    }
}

impl FromStr for CanBitRate {
    type Err = Error;
    fn from_str(s: &str) -> Result<CanBitRate, Error> {
        CanBitRate::new(number(BITRATE_WHAT, BITRATE_MUST, s)?)
    }
}

impl fmt::Display for CanBitRate {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(&self.get(), f)
    }
}

/// A whole number of milliseconds in `min..=max` (each type below names its own bounds and message).
macro_rules! millis {
    ($(#[$meta:meta])* $name:ident, $what:literal, $min:literal, $max:literal, $must:literal) => {
        $(#[$meta])*
        #[derive(Debug, Clone, Copy, PartialEq, Eq)]
        pub struct $name(Duration);

        impl $name {
            #[doc = concat!("`ms` milliseconds, if it is ", $must, ".")]
            pub fn from_ms(ms: u64) -> Result<$name, Error> {
                if ($min..=$max).contains(&ms) {
                    Ok($name(Duration::from_millis(ms)))
                } else {
                    Err(refused($what, $must, ms))
                }
            }

            /// The duration.
            pub fn get(self) -> Duration {
                self.0
            }
        }

        impl FromStr for $name {
            type Err = Error;
            fn from_str(s: &str) -> Result<$name, Error> {
                $name::from_ms(number($what, $must, s)?)
            }
        }
    };
}

millis!(
    /// How long to wait for an acknowledge ([`Config::reply_timeout`](crate::session::Config::reply_timeout)):
    /// 1 to 60000 ms.
    ReplyTimeout, "the acknowledge timeout", 1, 60_000, "a whole number from 1 to 60000 ms"
);
millis!(
    /// How often a wait polls the module ([`Config::poll_interval`](crate::session::Config::poll_interval)):
    /// 1 to 10000 ms.
    PollInterval, "the poll interval", 1, 10_000, "a whole number from 1 to 10000 ms"
);

const TIMEOUT_WHAT: &str = "the timeout";
const TIMEOUT_MUST: &str = "a number of seconds above 0 and at most 1000000000";

/// How long homing or a move may take before it is halted: above 0 s (at most 10⁹ s, about 31 years).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MotionTimeout(Duration);

impl MotionTimeout {
    /// 60 s, what homing and a move get unless told otherwise.
    pub const DEFAULT: MotionTimeout = MotionTimeout(Duration::from_secs(60));

    /// `seconds`, if it is a number above 0 and at most 10⁹.
    pub fn from_secs(seconds: f64) -> Result<MotionTimeout, Error> {
        if seconds > 0.0 && seconds <= 1e9 {
            Ok(MotionTimeout(Duration::from_secs_f64(seconds)))
        } else {
            Err(refused_number(TIMEOUT_WHAT, TIMEOUT_MUST, seconds))
        }
    }

    /// The duration.
    pub fn get(self) -> Duration {
        self.0
    }
}

impl Default for MotionTimeout {
    fn default() -> MotionTimeout {
        MotionTimeout::DEFAULT
    }
}

impl FromStr for MotionTimeout {
    type Err = Error;
    fn from_str(s: &str) -> Result<MotionTimeout, Error> {
        MotionTimeout::from_secs(number(TIMEOUT_WHAT, TIMEOUT_MUST, s)?)
    }
}

/// A number of a move in the module's own unit, checked by `ok` (which the message `must` describes).
macro_rules! move_number {
    ($(#[$meta:meta])* $name:ident($quantity:ident, $method:ident), $what:literal, $must:literal, $ok:expr) => {
        $(#[$meta])*
        #[derive(Debug, Clone, Copy, PartialEq)]
        pub struct $name(f32);

        impl $name {
            /// What the number is (in messages).
            pub const WHAT: &'static str = $what;
            /// What it must be.
            pub const MUST: &'static str = $must;

            #[doc = concat!("`value` in the module's own unit, if it is ", $must, ".")]
            pub fn new(value: f64) -> Result<$name, Error> {
                let ok: fn(f64) -> bool = $ok;
                let narrow = value as f32;
                if narrow.is_finite() && ok(value) {
                    Ok($name(narrow))
                } else if value.is_finite() && ok(value) {
                    // A number, beyond what the module's 32-bit floats hold.
                    Err(refused($what, "within the module's 32-bit float range (about 3.4e38)", format!("{value:e}")))
                } else {
                    Err(refused_number($what, $must, value))
                }
            }

            /// The number in the module's own unit.
            pub fn value(self) -> f32 {
                self.0
            }

            #[doc = concat!("As a ", stringify!($quantity), " in the module's own unit.")]
            pub fn $method(self) -> $quantity {
                $quantity::native(self.0)
            }
        }

        impl FromStr for $name {
            type Err = Error;
            fn from_str(s: &str) -> Result<$name, Error> {
                $name::new(number($what, $must, s)?)
            }
        }
    };
}

move_number!(
    /// The target of a move: a finite number in the module's own unit (rad or m).
    Target(Position, position), "the target position", "a number (rad or m, the module's unit)", |_| true
);
move_number!(
    /// The velocity of a move (written to TargetVel first): above 0, in rad/s or m/s.
    MoveVelocity(Velocity, velocity), "the velocity", "a number above 0 (rad/s or m/s, the module's unit)", |v| v > 0.0
);
move_number!(
    /// The acceleration of a move (written to TargetAcc first): above 0, in rad/s² or m/s².
    MoveAcceleration(Acceleration, acceleration),
    "the acceleration",
    "a number above 0 (rad/s² or m/s², the module's unit)",
    |v| v > 0.0
);
move_number!(
    /// The in-position tolerance of a move: above 0 and at most [`MoveSpec::MAX_TOLERANCE`], in rad or m.
    Tolerance(Position, position),
    "the tolerance",
    "a number above 0 and at most 0.1 (rad or m, the module's unit)",
    |v| v > 0.0 && v <= f64::from(MoveSpec::MAX_TOLERANCE.value())
);

impl Tolerance {
    /// [`MoveSpec::DEFAULT_TOLERANCE`].
    pub const DEFAULT: Tolerance = Tolerance(MoveSpec::DEFAULT_TOLERANCE.value());
}

impl Default for Tolerance {
    fn default() -> Tolerance {
        Tolerance::DEFAULT
    }
}

impl MoveSpec {
    /// The move its checked arguments describe, every number in the module's own unit: only the velocity
    /// and acceleration given are written, TargetVel / TargetAcc otherwise stay as the module has them.
    pub fn from_args(
        target: Target,
        vel: Option<MoveVelocity>,
        acc: Option<MoveAcceleration>,
        tolerance: Tolerance,
        timeout: MotionTimeout,
    ) -> MoveSpec {
        MoveSpec {
            target: target.position(),
            vel: vel.map(MoveVelocity::velocity),
            acc: acc.map(MoveAcceleration::acceleration),
            tolerance: Some(tolerance.position()),
            timeout: timeout.get(),
        }
    }
}

impl MotionSpec {
    /// The motion of mode `mode` its arguments describe (what `motionlink powercube motion` and Python's
    /// `motion()` take): `value` in the mode's unit (the module's own for a float position or velocity),
    /// `time_ms` for FSTEP, ISTEP and FCOSLOOP, `hold` for a continuous mode (`None`: until cancelled),
    /// `tolerance` for a position mode; checked as [`Motion::from_id`] and [`MotionSpec::validate`] check
    /// it, so that a bad argument is refused before anything is opened.
    ///
    /// ```
    /// use motionlink_powercube::args::MotionTimeout;
    /// use motionlink_powercube::client::MotionSpec;
    /// use motionlink_powercube::model::MotionId;
    /// let spec = MotionSpec::from_args(MotionId::FVel, 0.2, None, MotionTimeout::from_secs(2.0).ok(), None,
    ///     MotionTimeout::DEFAULT).unwrap();
    /// assert!(spec.continuous());
    /// let e = MotionSpec::from_args(MotionId::FStep, 0.2, None, None, None, MotionTimeout::DEFAULT).unwrap_err();
    /// assert!(e.to_string().starts_with("FSTEP_MODE takes a target position"), "{e}");
    /// ```
    pub fn from_args(
        mode: MotionId,
        value: f64,
        time_ms: Option<u16>,
        hold: Option<MotionTimeout>,
        tolerance: Option<Tolerance>,
        timeout: MotionTimeout,
    ) -> Result<MotionSpec, Error> {
        let (motion, ack) = Motion::from_id(mode, value, time_ms, AxisUnit::ModuleUnit)?;
        let spec = MotionSpec {
            motion,
            ack,
            hold: hold.map(MotionTimeout::get),
            tolerance: tolerance.map(Tolerance::position),
            timeout: timeout.get(),
        };
        spec.validate()?;
        Ok(spec)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_argument_is_refused_with_one_message_naming_it_and_its_range() {
        let says = |e: Error| e.to_string();
        assert_eq!(Baud::new(9600).ok(), Some(Baud::DEFAULT));
        assert_eq!(" 115200 ".parse::<Baud>().ok().map(Baud::get), Some(115_200));
        assert_eq!(
            says("7".parse::<Baud>().unwrap_err()),
            "the RS232 baud rate must be one of 1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200, not 7"
        );
        assert_eq!(says("fast".parse::<Baud>().unwrap_err()), says(Baud::new(0).unwrap_err()).replace(" 0", " fast"));
        assert_eq!("125000".parse::<CanBitRate>().ok().map(CanBitRate::get), Some(125_000));
        assert!(says(CanBitRate::new(12345).unwrap_err()).starts_with("the SLCAN bit rate must be one of 10000, "));
        assert_eq!(ReplyTimeout::from_ms(200).ok().map(ReplyTimeout::get), Some(Duration::from_millis(200)));
        assert_eq!(
            says("0".parse::<ReplyTimeout>().unwrap_err()),
            "the acknowledge timeout must be a whole number from 1 to 60000 ms, not 0"
        );
        assert!(says(PollInterval::from_ms(10_001).unwrap_err()).contains("from 1 to 10000 ms, not 10001"));
        assert_eq!("1.5".parse::<MotionTimeout>().ok().map(MotionTimeout::get), Some(Duration::from_millis(1500)));
        for bad in ["0", "-1", "NaN", "inf", "1e300", "soon"] {
            let e = says(bad.parse::<MotionTimeout>().unwrap_err());
            assert!(e.starts_with("the timeout must be a number of seconds above 0"), "{bad}: {e}");
        }
        assert_eq!(
            says("-5".parse::<MoveVelocity>().unwrap_err()),
            "the velocity must be a number above 0 (rad/s or m/s, the module's unit), not -5"
        );
        assert_eq!(says(MoveVelocity::new(-5.0).unwrap_err()), says("-5".parse::<MoveVelocity>().unwrap_err()));
        assert!(says(MoveAcceleration::new(0.0).unwrap_err()).starts_with("the acceleration must be a number above 0"));
        assert!(says(Tolerance::new(0.5).unwrap_err()).ends_with("at most 0.1 (rad or m, the module's unit), not 0.5"));
        assert_eq!(Tolerance::new(0.1).ok().map(Tolerance::value), Some(0.1));
        assert_eq!(
            says(Target::new(1e39).unwrap_err()),
            "the target position must be within the module's 32-bit float range (about 3.4e38), not 1e39"
        );
        assert!(says("1e300".parse::<MotionTimeout>().unwrap_err()).ends_with(", not 1e300"));
        assert_eq!("-0.25".parse::<Target>().ok().map(Target::position), Some(Position::native(-0.25)));
    }

    #[test]
    fn a_move_of_checked_arguments_is_the_spec_that_validates() {
        let spec = MoveSpec::from_args(
            Target::new(0.3).unwrap(),
            Some(MoveVelocity::new(0.5).unwrap()),
            None,
            Tolerance::default(),
            MotionTimeout::default(),
        );
        assert_eq!(spec.vel, Some(Velocity::native(0.5)));
        assert_eq!(
            (spec.acc, spec.tolerance(), spec.timeout),
            (None, MoveSpec::DEFAULT_TOLERANCE, Duration::from_secs(60))
        );
        assert_eq!(spec.validate().map_err(says), Ok(()));
        // The spec's own check gives the arguments' messages.
        let bad = MoveSpec { vel: Some(Velocity::native(-5.0)), ..spec };
        assert_eq!(bad.validate().map_err(says), Err(says(MoveVelocity::new(-5.0).unwrap_err())));
        fn says(e: Error) -> String {
            e.to_string()
        }
    }
}
