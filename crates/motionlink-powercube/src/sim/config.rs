//! Emulator configuration, from TOML.
//!
//! ```toml
//! watchdog_timeout_ms = 50
//!
//! [[module]]
//! address = 1
//! kind = "rotary"        # or "linear"
//! min_pos = -3.14        # soft limits, rad (m for linear)
//! max_pos = 3.14
//! max_vel = 1.0          # rad/s
//! max_acc = 2.0          # rad/s²
//!
//! [[module]]
//! address = 17
//! kind = "linear"
//! min_pos = 0.0
//! max_pos = 0.3
//! max_vel = 0.1
//! max_acc = 0.5
//! ```
//!
//! `address` is required in every `[[module]]`; every other key may be left out, see [`ModuleConfig`] for
//! the defaults. `variants = ["no-twin-mirror"]` (top level) runs every module as that firmware variant
//! ([`Variant`]).

use serde::Deserialize;

use super::variant::Variant;
use crate::model::ModuleKind;
use crate::wire::is_module_address;
use motionlink_link::emulator::FirmwareVariant;

/// One module's defaults. In TOML (and any serde format) `address` is required; every other key may be
/// left out and takes the value of [`ModuleConfig::at`] that address.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(from = "ModuleToml")]
pub struct ModuleConfig {
    /// Bus address, 1..31.
    pub address: u8,
    /// Rotary or linear.
    pub kind: ModuleKind,
    /// Lower soft limit (default -3.14 rad).
    pub min_pos: f64,
    /// Upper soft limit (default 3.14 rad).
    pub max_pos: f64,
    /// Maximum velocity (default 1 rad/s).
    pub max_vel: f64,
    /// Maximum acceleration (default 2 rad/s²).
    pub max_acc: f64,
    /// Maximum current (default 5 A).
    pub max_cur: f64,
    /// Maximum following error (default 0.1 rad); the emulated servo lags 5 ms behind the target.
    pub max_delta_pos: f64,
    /// Homing velocity, signed (default 0.5 rad/s).
    pub home_vel: f64,
    /// Homing acceleration (default 2 rad/s²).
    pub home_acc: f64,
    /// Where the module stands at power on, relative to its home switch (default 0.05 rad).
    pub start_position: f64,
    /// Encoder ticks per rad or m (default 4096 ticks per turn through a 1:100 gear).
    pub inc_ratio: f64,
    /// Encoder ticks per motor revolution (default 4096).
    pub pulses_per_turn: u32,
    /// Gear ratio (default 100).
    pub gear_ratio: f64,
    /// Serial number (default 1000 + address).
    pub serial: u32,
    /// Firmware version, as four hex digits (default 0x4634: 4.6.34).
    pub version: u16,
    /// A brake is fitted (default false).
    pub brake: bool,
    /// Digital inputs 0..3 (default 0).
    pub inputs: u8,
    /// How far beyond its target a ramp comes to rest (default 0): a module that does not settle where it
    /// is told (a load that pushes, a worn gear), for trying out in-position checks.
    pub settle_offset: f64,
}

impl Default for ModuleConfig {
    // ±3.14 rad is the soft limit asked for, not an approximation of π.
    #[allow(clippy::approx_constant)]
    fn default() -> Self {
        ModuleConfig {
            address: 1,
            kind: ModuleKind::Rotary,
            min_pos: -3.14,
            max_pos: 3.14,
            max_vel: 1.0,
            max_acc: 2.0,
            max_cur: 5.0,
            max_delta_pos: 0.1,
            home_vel: 0.5,
            home_acc: 2.0,
            start_position: 0.05,
            inc_ratio: 4096.0 * 100.0 / std::f64::consts::TAU,
            pulses_per_turn: 4096,
            gear_ratio: 100.0,
            serial: 0,
            version: 0x4634,
            brake: false,
            inputs: 0,
            settle_offset: 0.0,
        }
    }
}

impl ModuleConfig {
    /// The default module at `address`.
    pub fn at(address: u8) -> Self {
        ModuleConfig { address, serial: 1000 + u32::from(address), ..ModuleConfig::default() }
    }
}

/// A `[[module]]` table as written: `address` required (a module without one is a mistake, not module 1),
/// everything else optional.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ModuleToml {
    address: u8,
    kind: Option<ModuleKind>,
    min_pos: Option<f64>,
    max_pos: Option<f64>,
    max_vel: Option<f64>,
    max_acc: Option<f64>,
    max_cur: Option<f64>,
    max_delta_pos: Option<f64>,
    home_vel: Option<f64>,
    home_acc: Option<f64>,
    start_position: Option<f64>,
    inc_ratio: Option<f64>,
    pulses_per_turn: Option<u32>,
    gear_ratio: Option<f64>,
    serial: Option<u32>,
    version: Option<u16>,
    brake: Option<bool>,
    inputs: Option<u8>,
    settle_offset: Option<f64>,
}

impl From<ModuleToml> for ModuleConfig {
    fn from(t: ModuleToml) -> Self {
        let d = ModuleConfig::at(t.address);
        ModuleConfig {
            address: t.address,
            kind: t.kind.unwrap_or(d.kind),
            min_pos: t.min_pos.unwrap_or(d.min_pos),
            max_pos: t.max_pos.unwrap_or(d.max_pos),
            max_vel: t.max_vel.unwrap_or(d.max_vel),
            max_acc: t.max_acc.unwrap_or(d.max_acc),
            max_cur: t.max_cur.unwrap_or(d.max_cur),
            max_delta_pos: t.max_delta_pos.unwrap_or(d.max_delta_pos),
            home_vel: t.home_vel.unwrap_or(d.home_vel),
            home_acc: t.home_acc.unwrap_or(d.home_acc),
            start_position: t.start_position.unwrap_or(d.start_position),
            inc_ratio: t.inc_ratio.unwrap_or(d.inc_ratio),
            pulses_per_turn: t.pulses_per_turn.unwrap_or(d.pulses_per_turn),
            gear_ratio: t.gear_ratio.unwrap_or(d.gear_ratio),
            serial: t.serial.unwrap_or(d.serial),
            version: t.version.unwrap_or(d.version),
            brake: t.brake.unwrap_or(d.brake),
            inputs: t.inputs.unwrap_or(d.inputs),
            settle_offset: t.settle_offset.unwrap_or(d.settle_offset),
        }
    }
}

/// The emulated bus.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SimConfig {
    /// How long a module's watchdog waits for a refresh (default 50 ms, as the manual says).
    pub watchdog_timeout_ms: u64,
    /// The modules.
    #[serde(rename = "module")]
    pub modules: Vec<ModuleConfig>,
    /// Firmware variants every module runs (none by default: the behaviour this crate's client was first
    /// written against).
    pub variants: Vec<Variant>,
}

impl Default for SimConfig {
    /// One rotary module at address 1.
    fn default() -> Self {
        SimConfig {
            watchdog_timeout_ms: crate::model::WATCHDOG_TIMEOUT.as_millis() as u64,
            modules: vec![ModuleConfig::at(1)],
            variants: Vec::new(),
        }
    }
}

/// A configuration that cannot be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SimConfigError {
    /// Not valid TOML, or unknown keys.
    #[error("emulator configuration: {0}")]
    Toml(String),
    /// A value out of range.
    #[error("emulator configuration: {0}")]
    Invalid(String),
}

impl SimConfig {
    /// Adds the firmware `variants` to the configuration's, each kept once (sorted).
    pub fn add_variants(&mut self, variants: impl IntoIterator<Item = Variant>) {
        Variant::merge(&mut self.variants, variants);
    }

    /// Default modules at `addresses`.
    pub fn with_addresses(addresses: &[u8]) -> Result<Self, SimConfigError> {
        let config = SimConfig { modules: addresses.iter().map(|a| ModuleConfig::at(*a)).collect(), ..Self::default() };
        config.validate()?;
        Ok(config)
    }

    /// Parses TOML text (see the module documentation) and checks it.
    pub fn from_toml(text: &str) -> Result<Self, SimConfigError> {
        let config: SimConfig = toml::from_str(text).map_err(|e| SimConfigError::Toml(e.to_string()))?;
        config.validate()?;
        Ok(config)
    }

    /// Checks addresses (1..31, each once) and limits.
    pub fn validate(&self) -> Result<(), SimConfigError> {
        let invalid = |s: String| Err(SimConfigError::Invalid(s));
        if self.modules.is_empty() {
            return invalid("no modules".into());
        }
        if self.watchdog_timeout_ms == 0 {
            return invalid("watchdog_timeout_ms must be at least 1".into());
        }
        for (i, m) in self.modules.iter().enumerate() {
            if !is_module_address(m.address) {
                return invalid(format!("module address {} is outside 1..31", m.address));
            }
            if self.modules[..i].iter().any(|o| o.address == m.address) {
                return invalid(format!("module address {} is given twice", m.address));
            }
            let positive = [
                ("max_vel", m.max_vel),
                ("max_acc", m.max_acc),
                ("max_cur", m.max_cur),
                ("max_delta_pos", m.max_delta_pos),
                ("home_acc", m.home_acc),
                ("inc_ratio", m.inc_ratio),
            ];
            for (name, v) in positive {
                if !(v.is_finite() && v > 0.0) {
                    return invalid(format!("module {}: {name} must be a positive number", m.address));
                }
            }
            if !(m.min_pos.is_finite() && m.max_pos.is_finite() && m.min_pos < m.max_pos) {
                return invalid(format!("module {}: min_pos must be below max_pos", m.address));
            }
            if !(m.home_vel.is_finite() && m.home_vel != 0.0) {
                return invalid(format!("module {}: home_vel must not be zero", m.address));
            }
            if !m.start_position.is_finite() {
                return invalid(format!("module {}: start_position must be a number", m.address));
            }
            if !m.settle_offset.is_finite() {
                return invalid(format!("module {}: settle_offset must be a number", m.address));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
#[allow(clippy::approx_constant)] // ±3.14 rad is the configured soft limit
mod tests {
    use super::*;

    #[test]
    fn variants_added_are_kept_once_each_in_order() {
        let mut c = SimConfig::default();
        c.add_variants([Variant::AckLength6, Variant::NoTwinMirror]);
        c.add_variants([Variant::NoTwinMirror, Variant::NoPosStateDio]);
        assert_eq!(c.variants, vec![Variant::NoTwinMirror, Variant::AckLength6, Variant::NoPosStateDio]);
    }

    #[test]
    fn defaults_and_toml() {
        let d = SimConfig::default();
        assert_eq!(d.modules.len(), 1);
        assert_eq!((d.modules[0].min_pos, d.modules[0].max_vel, d.modules[0].max_acc), (-3.14, 1.0, 2.0));
        let c = SimConfig::from_toml(
            "watchdog_timeout_ms = 40\n[[module]]\naddress = 3\n[[module]]\naddress = 17\nkind = \"linear\"\nmax_pos = 0.3\nmin_pos = 0.0\nversion = 0x351D\n",
        )
        .unwrap();
        assert_eq!(c.watchdog_timeout_ms, 40);
        assert_eq!(c.modules[1].kind, ModuleKind::Linear);
        assert_eq!(c.modules[1].version, 0x351D);
        assert_eq!(c.modules[0].serial, 1003);
        assert_eq!(c.modules[0], ModuleConfig::at(3), "every key left out takes the default");
        let c = SimConfig::from_toml("[[module]]\naddress = 5\nserial = 77\n").unwrap();
        assert_eq!(c.modules[0].serial, 77);
        let c = SimConfig::from_toml("variants = [\"no-twin-mirror\", \"ack-length-6\"]\n[[module]]\naddress = 5\n")
            .unwrap();
        assert_eq!(c.variants, [Variant::NoTwinMirror, Variant::AckLength6]);
        let e = SimConfig::from_toml("variants = [\"nope\"]\n[[module]]\naddress = 5\n").unwrap_err().to_string();
        assert!(
            e.contains("\"nope\" is not a variant of the PowerCube emulator") && e.contains("no-twin-mirror"),
            "{e}"
        );
    }

    #[test]
    fn a_module_without_an_address_is_refused() {
        // Not quietly module 1: a second module at the default address would shadow the first.
        for text in ["[[module]]\nkind = \"linear\"\n", "[[module]]\naddress = 1\n[[module]]\nmax_vel = 2.0\n"] {
            let e = SimConfig::from_toml(text).unwrap_err();
            assert!(matches!(e, SimConfigError::Toml(_)), "{text}: {e:?}");
            assert!(e.to_string().contains("missing field `address`"), "{text}: {e}");
        }
    }

    #[test]
    fn bad_configurations_are_named() {
        for (text, needle) in [
            ("[[module]]\naddress = 0\n", "outside 1..31"),
            ("[[module]]\naddress = 2\n[[module]]\naddress = 2\n", "twice"),
            ("[[module]]\naddress = 2\nmax_vel = -1.0\n", "max_vel"),
            ("[[module]]\naddress = 2\nmin_pos = 1.0\nmax_pos = 0.0\n", "min_pos"),
            ("[[module]]\naddress = 2\nspeed = 1\n", "unknown field"),
            ("module = 3", "invalid type"),
        ] {
            let e = SimConfig::from_toml(text).unwrap_err().to_string();
            assert!(e.contains(needle), "{text}: {e}");
        }
        assert!(SimConfig::with_addresses(&[1, 32]).is_err());
    }
}
