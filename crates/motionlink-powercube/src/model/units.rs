//! Quantities with their units in their types.
//!
//! A PowerCube works in its own unit: radians on a rotary module, metres on a linear one. The float
//! quantities here ([`Position`], [`Velocity`], [`Acceleration`]) are in that unit; [`ModuleKind`] says which.
//! Encoder quantities ([`Ticks`], [`TicksPerSec`]) and [`Amperes`], [`CurrentDigits`], [`Millis`] have one
//! unit only.

use std::fmt;

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
    /// The position unit: "rad" or "m".
    pub fn unit(self) -> &'static str {
        match self {
            ModuleKind::Rotary => "rad",
            ModuleKind::Linear => "m",
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
    /// A position in the module's unit: rad (rotary) or m (linear).
    Position(f32), " (rad|m)"
);
quantity!(
    /// A velocity in the module's unit per second: rad/s or m/s.
    Velocity(f32), " (rad|m)/s"
);
quantity!(
    /// An acceleration in the module's unit per second squared: rad/s² or m/s².
    Acceleration(f32), " (rad|m)/s²"
);
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

impl Position {
    /// Formats with the unit of `kind`: `1.0000 rad`.
    pub fn show(self, kind: ModuleKind) -> String {
        format!("{:.4} {}", self.0, kind.unit())
    }
}

impl Velocity {
    /// Formats with the unit of `kind`: `0.5000 rad/s`.
    pub fn show(self, kind: ModuleKind) -> String {
        format!("{:.4} {}/s", self.0, kind.unit())
    }
}

impl Acceleration {
    /// Formats with the unit of `kind`: `2.0000 rad/s²`.
    pub fn show(self, kind: ModuleKind) -> String {
        format!("{:.4} {}/s²", self.0, kind.unit())
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
        assert_eq!(Position(1.5).show(ModuleKind::Rotary), "1.5000 rad");
        assert_eq!(Velocity(0.1).show(ModuleKind::Linear), "0.1000 m/s");
        assert_eq!(Ticks(-5).to_string(), "-5 ticks");
    }
}
