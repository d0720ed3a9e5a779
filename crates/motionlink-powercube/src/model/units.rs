//! Quantities with their units in their types, and module addresses checked once.
//!
//! A PowerCube works in its own unit: radians on a rotary module, metres on a linear one ([`ModuleKind`]).
//! The float quantities here ([`Position`], [`Velocity`], [`Acceleration`]) carry their [`AxisUnit`]: rad,
//! m, or, where nothing says which, explicitly [`AxisUnit::ModuleUnit`] ("the module's own unit", as the
//! bytes on the wire and a bare number on the command line are). A session refuses a quantity in rad for a
//! linear module and one in m for a rotary module ([`AxisUnit::fits`]), and gives what it reads in rad or
//! m once it knows the module's kind. Encoder quantities ([`Ticks`], [`TicksPerSec`]) and [`Amperes`],
//! [`CurrentDigits`], [`Millis`] have one unit only.
//!
//! ```
//! use motionlink_powercube::model::{Address, AxisUnit, ModuleKind, Position};
//! let p = Position::rad(0.5);
//! assert_eq!(p.to_string(), "0.5 rad");
//! assert!(p.unit().fits(ModuleKind::Rotary) && !p.unit().fits(ModuleKind::Linear));
//! assert!(Position::native(0.5).unit().fits(ModuleKind::Linear));
//! assert_eq!(Position::native(0.5).in_unit_of(ModuleKind::Linear), Position::m(0.5));
//! assert!(Address::new(0).is_err() && Address::new(32).is_err());
//! assert_eq!(Address::new(17).unwrap().get(), 17);
//! ```

use std::fmt;

use crate::wire::MAX_ADDRESS;

/// Rotary (unit: rad) or linear (unit: m), from the Config word's CONFIGID_MOD_LINEAR flag.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ModuleKind {
    /// A rotary module: positions in rad, velocities in rad/s.
    #[default]
    Rotary,
    /// A linear module: positions in m, velocities in m/s.
    Linear,
}

impl ModuleKind {
    /// The position unit's symbol: "rad" or "m".
    pub fn unit(self) -> &'static str {
        self.axis_unit().symbol()
    }

    /// The position unit.
    pub fn axis_unit(self) -> AxisUnit {
        match self {
            ModuleKind::Rotary => AxisUnit::Radian,
            ModuleKind::Linear => AxisUnit::Metre,
        }
    }

    /// Lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            ModuleKind::Rotary => "rotary",
            ModuleKind::Linear => "linear",
        }
    }
}

/// The unit of a position (and, per second, of a velocity; per second squared, of an acceleration).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum AxisUnit {
    /// Radians: the unit of a rotary module.
    Radian,
    /// Metres: the unit of a linear module.
    Metre,
    /// The module's own unit, not said: rad on a rotary module, m on a linear one. What a number on the
    /// wire is, what a bare number on the command line means, and what a session gives back for a module
    /// whose kind it has not read yet.
    ModuleUnit,
}

impl AxisUnit {
    /// "rad", "m", or "rad|m" for the module's own unit.
    pub fn symbol(self) -> &'static str {
        match self {
            AxisUnit::Radian => "rad",
            AxisUnit::Metre => "m",
            AxisUnit::ModuleUnit => "rad|m",
        }
    }

    /// True if a quantity in this unit may be given to a module of `kind`: rad to a rotary module, m to a
    /// linear one, the module's own unit to either.
    pub fn fits(self, kind: ModuleKind) -> bool {
        matches!(
            (self, kind),
            (AxisUnit::ModuleUnit, _) | (AxisUnit::Radian, ModuleKind::Rotary) | (AxisUnit::Metre, ModuleKind::Linear)
        )
    }
}

impl fmt::Display for AxisUnit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.symbol())
    }
}

macro_rules! axis_quantity {
    ($(#[$meta:meta])* $name:ident, $what:literal, $suffix:literal, $rad:ident, $m:ident) => {
        $(#[$meta])*
        #[derive(Debug, Clone, Copy, PartialEq)]
        pub struct $name {
            value: f32,
            unit: AxisUnit,
        }

        impl $name {
            #[doc = concat!("A ", $what, " in rad", $suffix, ".")]
            pub const fn $rad(value: f32) -> Self {
                $name { value, unit: AxisUnit::Radian }
            }

            #[doc = concat!("A ", $what, " in m", $suffix, ".")]
            pub const fn $m(value: f32) -> Self {
                $name { value, unit: AxisUnit::Metre }
            }

            #[doc = concat!("A ", $what, " in the module's own unit (rad", $suffix, " or m", $suffix, ").")]
            pub const fn native(value: f32) -> Self {
                $name { value, unit: AxisUnit::ModuleUnit }
            }

            #[doc = concat!("A ", $what, " of `value` in `unit`.")]
            pub const fn new(value: f32, unit: AxisUnit) -> Self {
                $name { value, unit }
            }

            /// The number, in [`Self::unit`].
            pub const fn value(self) -> f32 {
                self.value
            }

            /// The unit.
            pub const fn unit(self) -> AxisUnit {
                self.unit
            }

            /// The same number in the unit of a module of `kind` (what the module's own unit is for it).
            /// Only meant for a quantity that [`AxisUnit::fits`] `kind`.
            #[must_use]
            pub fn in_unit_of(self, kind: ModuleKind) -> Self {
                $name { value: self.value, unit: kind.axis_unit() }
            }

            /// The same number in the unit of `kind` if it is known, as it is otherwise.
            #[must_use]
            pub fn resolved(self, kind: Option<ModuleKind>) -> Self {
                match kind {
                    Some(k) => self.in_unit_of(k),
                    None => self,
                }
            }

            /// Formats with four decimals and the unit of `kind`: `1.0000 rad`.
            pub fn show(self, kind: ModuleKind) -> String {
                format!("{:.4} {}{}", self.value, kind.unit(), $suffix)
            }
        }

        impl fmt::Display for $name {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                fmt::Display::fmt(&self.value, f)?;
                write!(f, " {}{}", self.unit.symbol(), $suffix)
            }
        }
    };
}

axis_quantity!(
    /// A position: rad on a rotary module, m on a linear one (or, said so, the module's own unit).
    Position, "position", "", rad, m
);
axis_quantity!(
    /// A velocity: rad/s on a rotary module, m/s on a linear one (or, said so, the module's own unit).
    Velocity, "velocity", "/s", rad_per_s, m_per_s
);
axis_quantity!(
    /// An acceleration: rad/s² on a rotary module, m/s² on a linear one (or, said so, the module's own unit).
    Acceleration, "acceleration", "/s²", rad_per_s2, m_per_s2
);

/// A position, velocity or acceleration, as a check of its unit against a module names it
/// ([`Error::UnitMismatch`](crate::Error::UnitMismatch)).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Quantity {
    /// A position.
    Position(Position),
    /// A velocity.
    Velocity(Velocity),
    /// An acceleration.
    Acceleration(Acceleration),
}

impl Quantity {
    /// Its unit.
    pub fn unit(self) -> AxisUnit {
        match self {
            Quantity::Position(p) => p.unit(),
            Quantity::Velocity(v) => v.unit(),
            Quantity::Acceleration(a) => a.unit(),
        }
    }
}

/// The value with its unit (`0.5 rad`, `0.1 m/s`).
impl fmt::Display for Quantity {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Quantity::Position(p) => p.fmt(f),
            Quantity::Velocity(v) => v.fmt(f),
            Quantity::Acceleration(a) => a.fmt(f),
        }
    }
}

macro_rules! quantity {
    ($(#[$meta:meta])* $name:ident($inner:ty), $suffix:literal) => {
        $(#[$meta])*
        #[derive(Debug, Clone, Copy, PartialEq, PartialOrd, Default)]
        pub struct $name(pub $inner);

        impl fmt::Display for $name {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                fmt::Display::fmt(&self.0, f)?;
                f.write_str($suffix)
            }
        }
    };
}

quantity!(
    /// A motor current in amperes.
    Amperes(f32), " A"
);
quantity!(
    /// A position in encoder ticks.
    Ticks(i32), " ticks"
);
quantity!(
    /// A velocity in encoder ticks per second.
    TicksPerSec(i32), " ticks/s"
);
quantity!(
    /// A motor current in digits of the current controller (-500..500).
    CurrentDigits(i16), " digits"
);
quantity!(
    /// A duration in milliseconds, as the protocol carries it (0..65535).
    Millis(u16), " ms"
);

/// A module's bus address, 1..31, checked once when it is made.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Address(u8);

/// A number that is not a module address.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("module address {0} is outside 1..31")]
pub struct InvalidAddress(pub u8);

impl Address {
    /// The address `n`, if it is one (1..31).
    pub const fn new(n: u8) -> Result<Address, InvalidAddress> {
        if n >= 1 && n <= MAX_ADDRESS {
            Ok(Address(n))
        } else {
            Err(InvalidAddress(n))
        }
    }

    /// A number the session keeps for a module it addressed: it came from a checked [`Address`] or from an
    /// answer that only a module address can send (every request is checked before it goes out), so it is
    /// kept as it is.
    pub(crate) const fn checked(n: u8) -> Address {
        Address(n)
    }

    /// The number.
    pub const fn get(self) -> u8 {
        self.0
    }

    /// Every address, 1..31.
    pub fn all() -> impl Iterator<Item = Address> {
        (1..=MAX_ADDRESS).map(Address)
    }
}

impl TryFrom<u8> for Address {
    type Error = InvalidAddress;
    fn try_from(n: u8) -> Result<Address, InvalidAddress> {
        Address::new(n)
    }
}

impl From<Address> for u8 {
    fn from(a: Address) -> u8 {
        a.0
    }
}

impl PartialEq<u8> for Address {
    fn eq(&self, other: &u8) -> bool {
        self.0 == *other
    }
}

impl fmt::Display for Address {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(&self.0, f)
    }
}

/// Text that is not a module address (what a front end's `--module` or `module=` was given).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("module address {0:?}: give a number 1..31")]
pub struct ParseAddressError(pub String);

impl std::str::FromStr for Address {
    type Err = ParseAddressError;

    /// A decimal number 1..31 (surrounding blanks allowed): what the front ends parse `--module` with.
    fn from_str(s: &str) -> Result<Address, ParseAddressError> {
        s.trim().parse::<u8>().ok().and_then(|n| Address::new(n).ok()).ok_or_else(|| ParseAddressError(s.to_string()))
    }
}

/// A module's firmware version (DefCubeVersion, 0x1D): four hex digits printed as the manual does, major,
/// minor and a two-digit build: 0x351D is "3.5.1D".
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct CubeVersion(pub u16);

impl fmt::Display for CubeVersion {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:X}.{:X}.{:02X}", self.0 >> 12, (self.0 >> 8) & 0xF, self.0 & 0xFF)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn versions_print_as_in_the_manual() {
        assert_eq!(CubeVersion(0x351D).to_string(), "3.5.1D");
        assert_eq!(CubeVersion(0x4634).to_string(), "4.6.34");
        assert_eq!(CubeVersion(0x2516).to_string(), "2.5.16");
    }

    #[test]
    fn quantities_show_their_unit() {
        assert_eq!(Position::rad(1.5).show(ModuleKind::Rotary), "1.5000 rad");
        assert_eq!(Velocity::native(0.1).show(ModuleKind::Linear), "0.1000 m/s");
        assert_eq!(Ticks(-5).to_string(), "-5 ticks");
        assert_eq!(Velocity::m_per_s(0.25).to_string(), "0.25 m/s");
        assert_eq!(Acceleration::native(2.0).to_string(), "2 rad|m/s²");
    }

    #[test]
    fn units_fit_the_module_kind_they_belong_to() {
        assert!(AxisUnit::Radian.fits(ModuleKind::Rotary));
        assert!(!AxisUnit::Radian.fits(ModuleKind::Linear));
        assert!(AxisUnit::Metre.fits(ModuleKind::Linear));
        assert!(!AxisUnit::Metre.fits(ModuleKind::Rotary));
        assert!(AxisUnit::ModuleUnit.fits(ModuleKind::Rotary) && AxisUnit::ModuleUnit.fits(ModuleKind::Linear));
        assert_eq!(Position::native(0.2).resolved(Some(ModuleKind::Rotary)), Position::rad(0.2));
        assert_eq!(Position::native(0.2).resolved(None), Position::native(0.2));
        assert_ne!(Position::rad(0.2), Position::m(0.2));
    }

    #[test]
    fn addresses_are_checked_once() {
        assert_eq!(Address::new(0), Err(InvalidAddress(0)));
        assert_eq!(Address::try_from(32), Err(InvalidAddress(32)));
        assert_eq!(Address::all().count(), 31);
        let a = Address::new(31).unwrap();
        assert!(a == 31 && u8::from(a) == 31 && a.to_string() == "31");
        assert_eq!(InvalidAddress(40).to_string(), "module address 40 is outside 1..31");
    }

    #[test]
    fn addresses_parse_from_text_and_a_bad_one_is_named() {
        assert_eq!(" 17 ".parse::<Address>(), Ok(Address::new(17).unwrap()));
        for bad in ["0", "32", "-1", "300", "x", ""] {
            let err = bad.parse::<Address>().unwrap_err();
            assert_eq!(err, ParseAddressError(bad.to_string()));
            assert_eq!(err.to_string(), format!("module address {bad:?}: give a number 1..31"));
        }
    }
}
