//! Units as types: a remote speed in percent and one in counts per second are different types, and a
//! position is a number of encoder counts.
//!
//! A unit takes remote speeds (0x3011..0x301A) either in percent ("speed select relative", the standard
//! units) or in encoder counts per second ("speed select absolute"); the same number on the wire means one
//! or the other by the unit's parameterisation. A session knows which its unit uses
//! ([`crate::Config::speed_mode`]) and refuses a [`Speed`] of the other kind.
//!
//! ```
//! use motionlink_scu::model::{Speed, SpeedMode, SpeedPercent};
//! let s = Speed::percent(80).unwrap();
//! assert_eq!((s.mode(), s.raw()), (SpeedMode::Percent, 80));
//! assert!(SpeedPercent::new(101).is_none());
//! assert!(s.for_mode(SpeedMode::CountsPerSecond).is_err());
//! assert_eq!(Speed::parse("400", SpeedMode::CountsPerSecond).unwrap(), Speed::counts_per_second(400).unwrap());
//! assert!(Speed::parse("0", SpeedMode::Percent).is_err(), "0 would never move");
//! ```

use std::fmt;

/// How the unit's parameterisation gives remote speeds (0x3011..0x301A).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SpeedMode {
    /// "Speed select relative": percent, 0..100 (standard units).
    #[default]
    Percent,
    /// "Speed select absolute": encoder counts per second, 0..1000.
    CountsPerSecond,
}

impl SpeedMode {
    /// The largest remote speed.
    pub const fn max(self) -> u16 {
        match self {
            SpeedMode::Percent => 100,
            SpeedMode::CountsPerSecond => 1000,
        }
    }

    /// The unit as text.
    pub const fn unit(self) -> &'static str {
        match self {
            SpeedMode::Percent => "%",
            SpeedMode::CountsPerSecond => "counts/s",
        }
    }
}

/// A remote speed in percent of full speed, 0..=100.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct SpeedPercent(u16);

impl SpeedPercent {
    /// `percent` (0..=100), or `None`.
    pub const fn new(percent: u16) -> Option<Self> {
        if percent <= 100 {
            Some(SpeedPercent(percent))
        } else {
            None
        }
    }

    /// The value in percent.
    pub const fn get(self) -> u16 {
        self.0
    }
}

/// A remote speed in encoder counts per second, 0..=1000.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct SpeedCountsPerSecond(u16);

impl SpeedCountsPerSecond {
    /// `counts_per_second` (0..=1000), or `None`.
    pub const fn new(counts_per_second: u16) -> Option<Self> {
        if counts_per_second <= 1000 {
            Some(SpeedCountsPerSecond(counts_per_second))
        } else {
            None
        }
    }

    /// The value in counts per second.
    pub const fn get(self) -> u16 {
        self.0
    }
}

/// A remote speed, of either kind.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Speed {
    /// Percent of full speed.
    Percent(SpeedPercent),
    /// Encoder counts per second.
    CountsPerSecond(SpeedCountsPerSecond),
}

impl Speed {
    /// `percent` (0..=100) of full speed, or `None`.
    pub const fn percent(percent: u16) -> Option<Speed> {
        match SpeedPercent::new(percent) {
            Some(p) => Some(Speed::Percent(p)),
            None => None,
        }
    }

    /// `counts_per_second` (0..=1000), or `None`.
    pub const fn counts_per_second(counts_per_second: u16) -> Option<Speed> {
        match SpeedCountsPerSecond::new(counts_per_second) {
            Some(c) => Some(Speed::CountsPerSecond(c)),
            None => None,
        }
    }

    /// Which kind of speed this is.
    pub const fn mode(self) -> SpeedMode {
        match self {
            Speed::Percent(_) => SpeedMode::Percent,
            Speed::CountsPerSecond(_) => SpeedMode::CountsPerSecond,
        }
    }

    /// The number on the wire.
    pub const fn raw(self) -> u16 {
        match self {
            Speed::Percent(p) => p.get(),
            Speed::CountsPerSecond(c) => c.get(),
        }
    }

    /// The number on the wire for a unit that takes speeds as `mode` says; a speed of the other kind is
    /// refused, naming both.
    pub fn for_mode(self, mode: SpeedMode) -> Result<u16, String> {
        if self.mode() == mode {
            Ok(self.raw())
        } else {
            Err(format!(
                "a speed of {self} does not apply: the unit takes remote speeds in {} (its speed mode); give the \
                 speed in {}",
                mode.unit(),
                mode.unit()
            ))
        }
    }

    /// Checks that the speed moves anything and fits a unit of `mode`: 1 up to the mode's maximum.
    pub fn for_motion(self, mode: SpeedMode) -> Result<u16, String> {
        let raw = self.for_mode(mode)?;
        if raw == 0 {
            return Err(format!(
                "speed 0 {}: a motion needs 1..{} {} (0 would never move)",
                mode.unit(),
                mode.max(),
                mode.unit()
            ));
        }
        Ok(raw)
    }

    /// The speed of a move that names none, in every front end (the command line's `--speed` default, the
    /// console, the gateway, Python): 100 in the unit's mode, that is 100 %, or 100 counts/s on a unit set
    /// to absolute speed (whose maximum is 1000).
    ///
    /// ```
    /// use motionlink_scu::model::{Speed, SpeedMode};
    /// assert_eq!(Speed::default_for(SpeedMode::CountsPerSecond).for_motion(SpeedMode::CountsPerSecond), Ok(100));
    /// ```
    pub const fn default_for(mode: SpeedMode) -> Speed {
        match mode {
            SpeedMode::Percent => Speed::Percent(SpeedPercent(100)),
            SpeedMode::CountsPerSecond => Speed::CountsPerSecond(SpeedCountsPerSecond(100)),
        }
    }

    /// The speed `raw` of a unit that takes speeds as `mode` says, if in range.
    pub const fn of_mode(mode: SpeedMode, raw: u16) -> Option<Speed> {
        match mode {
            SpeedMode::Percent => Speed::percent(raw),
            SpeedMode::CountsPerSecond => Speed::counts_per_second(raw),
        }
    }
}

impl From<SpeedPercent> for Speed {
    fn from(p: SpeedPercent) -> Speed {
        Speed::Percent(p)
    }
}

impl From<SpeedCountsPerSecond> for Speed {
    fn from(c: SpeedCountsPerSecond) -> Speed {
        Speed::CountsPerSecond(c)
    }
}

impl fmt::Display for Speed {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} {}", self.raw(), self.mode().unit())
    }
}

/// A position in encoder counts (the only unit of position the SCU has; positions are INT32).
///
/// Built explicitly, `PositionCounts(400)` or [`PositionCounts::new`]: a bare number is not a position, so
/// it does not compile where one is meant. It serialises as the bare number of counts.
///
/// ```compile_fail
/// use motionlink_scu::model::PositionCounts;
/// let p: PositionCounts = 400.into(); // no `From<i32>`: say what the number is
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Default, serde::Serialize)]
#[serde(transparent)]
pub struct PositionCounts(pub i32);

impl PositionCounts {
    /// `counts` encoder counts.
    pub const fn new(counts: i32) -> Self {
        PositionCounts(counts)
    }

    /// The number of counts.
    pub const fn get(self) -> i32 {
        self.0
    }

    /// `self` minus `other`, in counts (as `i64`: the difference of two INT32 positions always fits).
    pub const fn counts_from(self, other: PositionCounts) -> i64 {
        self.0 as i64 - other.0 as i64
    }
}

impl fmt::Display for PositionCounts {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} counts", self.0)
    }
}

/// The baud rate of an SCU's serial line: 38400 on standard units, 9600 or 19200 on customised ones
/// (checked from a number by [`Checked`](crate::args::Checked): `"19200".parse::<Baud>()`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Baud(pub(crate) u32);

impl Baud {
    /// The rate of standard units.
    pub const STANDARD: Baud = Baud(38_400);

    /// Bits per second.
    pub const fn get(self) -> u32 {
        self.0
    }
}

impl Default for Baud {
    fn default() -> Self {
        Baud::STANDARD
    }
}

impl fmt::Display for Baud {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.0)
    }
}
