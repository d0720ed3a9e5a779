//! Quantities with their unit: a position in the drive's unit, a speed in percent of the drive's maximum,
//! a ramp time in milliseconds, the state an output is switched to.

use std::fmt;

use super::{shown, ModelError};
use crate::wire::number::{fits_fixed24, write_decimal, Fixed24, MAX_DECIMALS};

/// A position or distance in the drive's position unit (mm, inch, degrees: whatever the drive is configured
/// for). Limited to the range of the 24.24 format, -8388608..8388608.
#[derive(Debug, Clone, Copy, PartialEq, PartialOrd, Default)]
pub struct Position(pub(crate) f64);

impl Position {
    /// A position; refused when not finite or outside the 24.24 range.
    #[inline]
    pub fn new(units: f64) -> Result<Self, ModelError> {
        if fits_fixed24(units) {
            Ok(Position(units))
        } else {
            Err(ModelError::Range { what: "position", value: shown(units), range: "-8388608 to 8388607.99" })
        }
    }

    /// The value in the drive's position unit.
    #[inline]
    pub fn units(self) -> f64 {
        self.0
    }

    /// A position known to be in range (a constant of this crate).
    pub(crate) const fn from_units_unchecked(units: f64) -> Self {
        Position(units)
    }

    /// The 24.24 form.
    pub fn to_fixed(self) -> Fixed24 {
        Fixed24::from_f64(self.0).unwrap_or_default()
    }
}

/// A number in the drive's unit (the results name it `..._units`).
impl serde::Serialize for Position {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_f64(self.0)
    }
}

impl fmt::Display for Position {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write_decimal(f, self.0, MAX_DECIMALS)
    }
}

/// A speed in percent of the drive's maximum speed: 0.000001 to 100.
///
/// The smallest is the finest step the SPEED command carries (six decimals, [`MAX_DECIMALS`]): a smaller speed
/// would go out as `SPEED 0`, which the drive refuses, so it is refused here, before anything is sent.
///
/// ```
/// use motionlink_compax::model::SpeedPercent;
/// assert_eq!(SpeedPercent::new(0.000001).unwrap().to_string(), "0.000001");
/// assert_eq!(SpeedPercent::new(1e-300).unwrap_err().to_string(),
///            "speed 1e-300 % is out of range (0.000001 to 100 %; a SPEED command carries six decimals: \
///             less would be sent as 0)");
/// ```
#[derive(Debug, Clone, Copy, PartialEq, PartialOrd)]
pub struct SpeedPercent(pub(crate) f64);

impl SpeedPercent {
    /// The smallest speed: 0.000001 %, the finest step of the command's number.
    pub const MIN: f64 = 0.000_001;

    /// A speed; refused outside [`SpeedPercent::MIN`]..=100 (and when not finite).
    pub fn new(percent: f64) -> Result<Self, ModelError> {
        if percent.is_finite() && (Self::MIN..=100.0).contains(&percent) {
            Ok(SpeedPercent(percent))
        } else {
            Err(ModelError::Range {
                what: "speed",
                value: format!("{} %", shown(percent)),
                range: "0.000001 to 100 %; a SPEED command carries six decimals: less would be sent as 0",
            })
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
pub struct RampMs(pub(crate) u16);

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
pub struct OutputState(pub(crate) u8);

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

/// The number written.
impl serde::Serialize for OutputState {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_u8(self.0)
    }
}
