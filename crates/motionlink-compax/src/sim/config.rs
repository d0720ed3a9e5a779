//! The emulated bus's configuration: its drives, their addresses, modes, baud rates and positions, the
//! parameters they model; from code or a TOML file.

use std::collections::BTreeMap;

use serde::Deserialize;

use super::variant::Variant;
use crate::model::{ParamId, Position, BAUD_RATES};
use crate::wire::Mode;
use motionlink_link::emulator::FirmwareVariant;

/// A configuration error of the emulator.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("emulator configuration: {0}")]
pub struct SimConfigError(pub String);

/// One emulated drive's settings at power-on.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DriveConfig {
    /// P194, 1..=31 (0: answers nothing).
    pub address: u8,
    /// P195, bit/s (default: the line's baud rate).
    #[serde(default)]
    pub baud_rate: Option<u32>,
    /// P196 (default: the bus's mode).
    #[serde(default)]
    pub p196: Option<u32>,
    /// The position at power-on, in the drive's unit.
    #[serde(default)]
    pub position: f64,
}

/// The emulated bus.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SimConfig {
    /// The line's baud rate (the rate the host sends at).
    #[serde(default = "default_baud")]
    pub baud_rate: u32,
    /// P196 of every drive that does not set its own.
    #[serde(default)]
    pub p196: u32,
    /// The speed of SPEED 100, in position units per second.
    #[serde(default = "default_max_speed")]
    pub max_speed_units_per_s: f64,
    /// The drives.
    #[serde(default = "default_drives", rename = "drive")]
    pub drives: Vec<DriveConfig>,
    /// Parameters besides P194..P196 that every drive models, with their values at power-on (`P12 = 0.0`).
    /// The manual defines only P194..P196: a drive answers a read or write of any other parameter with
    /// [`REFUSED`](super::REFUSED) (E90) unless it is listed here.
    #[serde(default)]
    pub params: BTreeMap<String, f64>,
    /// Firmware variants every drive runs (none by default: the behaviour this crate's client was first
    /// written against); see [`Variant`].
    #[serde(default)]
    pub variants: Vec<Variant>,
}

fn default_baud() -> u32 {
    9600
}
fn default_max_speed() -> f64 {
    100.0
}
fn default_drives() -> Vec<DriveConfig> {
    vec![DriveConfig { address: 1, baud_rate: None, p196: None, position: 0.0 }]
}

impl Default for SimConfig {
    /// One drive at address 1, 9600 baud, P196 = 0, 100 units/s.
    fn default() -> Self {
        SimConfig {
            baud_rate: 9600,
            p196: 0,
            max_speed_units_per_s: 100.0,
            drives: default_drives(),
            params: BTreeMap::new(),
            variants: Vec::new(),
        }
    }
}

impl SimConfig {
    /// Adds the firmware `variants` to the configuration's, each kept once (sorted).
    pub fn add_variants(&mut self, variants: impl IntoIterator<Item = Variant>) {
        Variant::merge(&mut self.variants, variants);
    }

    /// Drives at `addresses`, every one with `p196` at `baud_rate`.
    pub fn bus(addresses: &[u8], p196: u32, baud_rate: u32) -> Self {
        SimConfig {
            baud_rate,
            p196,
            max_speed_units_per_s: 100.0,
            drives: addresses
                .iter()
                .map(|&address| DriveConfig { address, baud_rate: None, p196: None, position: 0.0 })
                .collect(),
            params: BTreeMap::new(),
            variants: Vec::new(),
        }
    }

    /// The bus with what a command line or a program sets over its configuration (`motionlink sim compax
    /// --drives --mode --baud`, Python's `Emulator("compax", drives=, mode=, baud=)`): drives at `addresses`
    /// in place of the configuration's (each with the bus's settings), and P196 and the baud rate of every
    /// drive (a drive's own setting dropped).
    ///
    /// ```
    /// use motionlink_compax::sim::SimConfig;
    /// let c = SimConfig::default().overridden(Some(&[1, 5]), Some(8), Some(19_200));
    /// assert_eq!((c.drives.len(), c.p196, c.baud_rate), (2, 8, 19_200));
    /// ```
    pub fn overridden(mut self, addresses: Option<&[u8]>, p196: Option<u32>, baud_rate: Option<u32>) -> Self {
        if let Some(addresses) = addresses {
            self.drives = SimConfig::bus(addresses, self.p196, self.baud_rate).drives;
        }
        if let Some(p196) = p196 {
            self.p196 = p196;
            self.drives.iter_mut().for_each(|d| d.p196 = None);
        }
        if let Some(baud_rate) = baud_rate {
            self.baud_rate = baud_rate;
            self.drives.iter_mut().for_each(|d| d.baud_rate = None);
        }
        self
    }

    /// Lets every drive model parameter `id` (besides P194..P196), starting at `value`.
    pub fn with_param(mut self, id: ParamId, value: f64) -> Self {
        self.params.insert(id.to_string(), value);
        self
    }

    /// The extra parameters as numbers (see [`SimConfig::params`]).
    pub(crate) fn param_ids(&self) -> Result<Vec<(ParamId, f64)>, SimConfigError> {
        self.params
            .iter()
            .map(|(name, &v)| {
                let id = ParamId::parse(name).map_err(|e| SimConfigError(format!("params: {e}")))?;
                if id.info().is_some() {
                    return Err(SimConfigError(format!("params: {id} is set by the drive's own settings")));
                }
                id.check(v).map_err(|e| SimConfigError(format!("params: {e}")))?;
                Ok((id, v))
            })
            .collect()
    }

    /// Reads a TOML configuration:
    ///
    /// ```toml
    /// baud_rate = 9600
    /// p196 = 8
    /// max_speed_units_per_s = 100.0
    /// params = { P12 = 0.0 }
    /// variants = ["echo-bare"]
    /// [[drive]]
    /// address = 1
    /// [[drive]]
    /// address = 5
    /// position = 12.5
    /// ```
    pub fn from_toml(text: &str) -> Result<Self, SimConfigError> {
        let c: SimConfig = toml::from_str(text).map_err(|e| SimConfigError(e.to_string()))?;
        c.validate()?;
        Ok(c)
    }

    /// Checks addresses (unique, 0..=31), baud rates and modes.
    pub fn validate(&self) -> Result<(), SimConfigError> {
        let err = |m: String| Err(SimConfigError(m));
        if self.drives.is_empty() || self.drives.len() > 31 {
            return err(format!("{} drives: a bus has 1 to 31", self.drives.len()));
        }
        if !(self.max_speed_units_per_s.is_finite() && self.max_speed_units_per_s > 0.0) {
            return err(format!("max_speed_units_per_s = {} must be positive", self.max_speed_units_per_s));
        }
        let mut seen = [false; 32];
        for d in &self.drives {
            if d.address > 31 {
                return err(format!("address {} is not 0..=31 (P194)", d.address));
            }
            if d.address != 0 && std::mem::replace(&mut seen[usize::from(d.address)], true) {
                return err(format!("two drives have address {}", d.address));
            }
            let baud = d.baud_rate.unwrap_or(self.baud_rate);
            if !BAUD_RATES.contains(&baud) {
                return err(format!("baud rate {baud} is not one P195 accepts ({BAUD_RATES:?})"));
            }
            Mode::from_p196(d.p196.unwrap_or(self.p196)).map_err(|e| SimConfigError(e.to_string()))?;
            Position::new(d.position).map_err(|e| SimConfigError(e.to_string()))?;
        }
        if !BAUD_RATES.contains(&self.baud_rate) {
            return err(format!("line baud rate {} is not one P195 accepts", self.baud_rate));
        }
        self.param_ids()?;
        Ok(())
    }
}
