//! The options that describe a session with one unit, as every front end that names a unit takes them: the
//! command line's `--baud`, `--functions`... and a device table's keys `baud`, `functions`... (devices.toml,
//! the gateway's file). One rule turns them into the session's settings ([`UnitOptions::config`]) and
//! into the unit an in-process emulator stands for ([`UnitOptions::emulated`]).

use super::{Baud, PollInterval, ReplyTimeout, ToleranceCounts};
use crate::config::{Config, FunctionMap, StrokeLimits};
use crate::model::{SafetyId, SpeedMode};
use crate::sim::{SimConfig, Variant};
use motionlink_link::emulator::FirmwareVariant;

pub use motionlink_link::devices::OptionError;

fn on(key: &'static str) -> impl Fn(String) -> OptionError {
    move |message| OptionError { key: Some(key), message }
}

/// The options of a session with one SCU unit, checked by their types. [`Default`] is what the command line
/// takes when an option is not given.
#[derive(Debug, Clone, PartialEq)]
pub struct UnitOptions {
    /// `baud`: the serial line's rate.
    pub baud: Baud,
    /// `safety`: RO's Safety_ID.
    pub safety: SafetyId,
    /// `timeout_ms`: how long to wait for the reply to RO.
    pub timeout_ms: ReplyTimeout,
    /// `functions`: which actuators each motion function drives (presets and `F1=1,2` forms, in order).
    pub functions: Vec<String>,
    /// `stroke`: travel ranges for targets, `A=MIN:MAX`.
    pub stroke: Vec<String>,
    /// `tolerance`: how close to its target a move must end, in counts.
    pub tolerance: ToleranceCounts,
    /// `poll_ms`: how often a move or a run looks at the actuators.
    pub poll_ms: PollInterval,
    /// `speed_mode`: how the unit takes remote speeds.
    pub speed_mode: SpeedMode,
    /// `sim_preset`: the preset an in-process emulator starts from.
    pub sim_preset: Option<String>,
    /// `sim_variants`: firmware variants of an in-process emulator.
    pub sim_variants: Vec<Variant>,
    /// `wake`: send a break before opening ([`Config::wake_break`], [`crate::config::WAKE_BREAK`] long).
    pub wake: bool,
}

impl Default for UnitOptions {
    fn default() -> Self {
        UnitOptions {
            baud: Baud::STANDARD,
            safety: SafetyId::from_code(0).expect("Safety_ID 0"),
            timeout_ms: "2000".parse().expect("2000 ms"),
            functions: Vec::new(),
            stroke: Vec::new(),
            tolerance: "5".parse().expect("5 counts"),
            poll_ms: "50".parse().expect("50 ms"),
            speed_mode: SpeedMode::Percent,
            sim_preset: None,
            sim_variants: Vec::new(),
            wake: false,
        }
    }
}

impl UnitOptions {
    /// The keys of a device table these options take (the command line's options without `--`, with `_`).
    pub const KEYS: [&'static str; 11] = [
        "baud",
        "safety",
        "timeout_ms",
        "functions",
        "stroke",
        "tolerance",
        "poll_ms",
        "speed_mode",
        "sim_preset",
        "sim_variants",
        "wake",
    ];

    /// Sets the option `key` from its text as a device table gives it (a list option takes one element per
    /// call, added to those before), by the option's own type and rule. `false` for a key that is not one of
    /// [`UnitOptions::KEYS`].
    pub fn set(&mut self, key: &str, text: &str) -> Result<bool, OptionError> {
        match key {
            "baud" => self.baud = OptionError::parsed("baud", text)?,
            "safety" => self.safety = OptionError::parsed("safety", text)?,
            "timeout_ms" => self.timeout_ms = OptionError::parsed("timeout_ms", text)?,
            "functions" => self.functions.push(text.to_string()),
            "stroke" => self.stroke.push(text.to_string()),
            "tolerance" => self.tolerance = OptionError::parsed("tolerance", text)?,
            "poll_ms" => self.poll_ms = OptionError::parsed("poll_ms", text)?,
            "speed_mode" => self.speed_mode = OptionError::parsed("speed_mode", text)?,
            "sim_preset" => {
                if SimConfig::preset(text).is_none() {
                    return Err(on("sim_preset")(format!(
                        "{text:?} is not a preset: {}",
                        SimConfig::PRESETS.join(", ")
                    )));
                }
                self.sim_preset = Some(text.to_string())
            }
            "wake" => {
                self.wake = match text.trim() {
                    "true" => true,
                    "false" => false,
                    other => return Err(on("wake")(format!("{other:?} is neither true nor false"))),
                }
            }
            "sim_variants" => {
                self.sim_variants.extend(Variant::list(text).map_err(|e| on("sim_variants")(e.to_string()))?)
            }
            _ => return Ok(false),
        }
        Ok(true)
    }

    /// The session's settings: the function map and stroke limits parsed, every value checked together
    /// ([`Config::validate`]).
    pub fn config(&self) -> Result<Config, OptionError> {
        let config = Config {
            baud: self.baud,
            safety_id: self.safety,
            reply_timeout: self.timeout_ms.get(),
            speed_mode: self.speed_mode,
            function_map: FunctionMap::from_specs(&self.functions).map_err(on("functions"))?,
            stroke_limits: StrokeLimits::per_actuator(&self.stroke).map_err(on("stroke"))?,
            position_tolerance_counts: self.tolerance.get(),
            poll_interval: self.poll_ms.get(),
            wake_break: self.wake.then_some(crate::config::WAKE_BREAK),
            ..Config::default()
        };
        config.validate().map_err(|e| OptionError { key: None, message: e.to_string() })?;
        Ok(config)
    }

    /// Refuses the emulator's options for a port that is not `sim`.
    pub fn check_port(&self, sim: bool) -> Result<(), OptionError> {
        if !sim && (self.sim_preset.is_some() || !self.sim_variants.is_empty()) {
            return Err(OptionError { key: None, message: "sim_preset and sim_variants are only for port sim".into() });
        }
        Ok(())
    }

    /// The unit an emulator in this process stands for ([`super::emulated_unit`]): the one these options
    /// name, with the firmware variants asked for.
    pub fn emulated(&self) -> Result<SimConfig, OptionError> {
        let mut config = super::emulated_unit(self.sim_preset.as_deref(), &self.functions, self.speed_mode)
            .map_err(|message| OptionError { key: None, message })?;
        config.add_variants(self.sim_variants.iter().copied());
        Ok(config)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::args::Checked;

    #[test]
    fn a_table_s_values_go_through_the_options_own_rules() {
        let mut o = UnitOptions::default();
        assert!(o.set("baud", "19200").unwrap());
        assert!(o.set("functions", "tlt").unwrap());
        assert!(o.set("stroke", "1=0:865").unwrap());
        assert!(!o.set("modules", "1").unwrap(), "not a key of these options");
        assert_eq!(o.baud.get(), 19_200);
        let e = o.set("baud", "5").unwrap_err();
        assert_eq!(e.to_string(), format!("baud: \"5\": {}", Baud::RULE));
        assert!(o.set("sim_preset", "lift").unwrap_err().message.contains("tlt"));
        let config = o.config().unwrap();
        assert_eq!(config.stroke_limits[0].map(|l| l.max_counts.0), Some(865));
        assert_eq!(o.emulated().unwrap(), SimConfig::tlt());
        o.functions.push("F30=1".into());
        assert_eq!(o.config().unwrap_err().key, Some("functions"));
    }

    #[test]
    fn the_emulator_s_options_are_for_port_sim_only() {
        let mut o = UnitOptions::default();
        assert!(o.check_port(false).is_ok());
        o.set("sim_preset", "tlt").unwrap();
        assert!(o.check_port(true).is_ok());
        assert!(o.check_port(false).unwrap_err().message.contains("port sim"));
    }
}
