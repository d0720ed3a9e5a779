//! The options that describe a session with one module, as every front end that names a module takes them:
//! the command line's `--module`, `--baud`... and a device table's keys `module`, `baud`... (devices.toml,
//! the gateway's file). One rule turns them into the session's settings ([`ModuleOptions::config`]),
//! the guard of its motions ([`ModuleOptions::guard`]) and the bus an in-process emulator stands for
//! ([`ModuleOptions::emulated`]).

use crate::args::{Baud, CanBitRate, PollInterval, ReplyTimeout};
use crate::model::Address;
use crate::session::{Config, Guard, ModulesAt};
use crate::sim::{SimConfig, Variant};

pub use motionlink_link::devices::OptionError;

/// The options of a session with one PowerCube module, checked by their types. [`Default`] is what the
/// command line takes when an option is not given.
#[derive(Debug, Clone, PartialEq)]
pub struct ModuleOptions {
    /// `module`: the module's address.
    pub module: Address,
    /// `baud`: the RS232 rate.
    pub baud: Baud,
    /// `bitrate`: the CAN bit rate of an SLCAN adapter.
    pub bitrate: CanBitRate,
    /// `timeout_ms`: the acknowledge timeout (default: the link's, 200 ms on RS232, 50 ms on CAN).
    pub timeout_ms: Option<ReplyTimeout>,
    /// `poll_ms`: how often homing and a move read the module's state.
    pub poll_ms: PollInterval,
    /// `no_watchdog`: do not arm the module's watchdog for motions.
    pub no_watchdog: bool,
    /// `sim_variants`: firmware variants of an in-process emulator.
    pub sim_variants: Vec<Variant>,
}

impl Default for ModuleOptions {
    fn default() -> Self {
        ModuleOptions {
            module: Address::new(1).expect("address 1"),
            baud: Baud::DEFAULT,
            bitrate: CanBitRate::DEFAULT,
            timeout_ms: None,
            poll_ms: PollInterval::from_ms(10).expect("10 ms"),
            no_watchdog: false,
            sim_variants: Vec::new(),
        }
    }
}

impl ModuleOptions {
    /// The keys of a device table these options take (the command line's options without `--`, with `_`).
    pub const KEYS: [&'static str; 7] =
        ["module", "baud", "bitrate", "timeout_ms", "poll_ms", "no_watchdog", "sim_variants"];

    /// Sets the option `key` from its text as a device table gives it (`sim_variants` takes one name or
    /// comma-separated names per call, added to those before; `no_watchdog` takes `true` or `false`), by the
    /// option's own type and rule. `false` for a key that is not one of [`ModuleOptions::KEYS`].
    pub fn set(&mut self, key: &str, text: &str) -> Result<bool, OptionError> {
        match key {
            "module" => self.module = OptionError::parsed("module", text)?,
            "baud" => self.baud = OptionError::parsed("baud", text)?,
            "bitrate" => self.bitrate = OptionError::parsed("bitrate", text)?,
            "timeout_ms" => self.timeout_ms = Some(OptionError::parsed("timeout_ms", text)?),
            "poll_ms" => self.poll_ms = OptionError::parsed("poll_ms", text)?,
            "no_watchdog" => self.no_watchdog = OptionError::parsed("no_watchdog", text)?,
            "sim_variants" => {
                for name in text.split(',') {
                    self.sim_variants.push(OptionError::parsed("sim_variants", name.trim())?);
                }
            }
            _ => return Ok(false),
        }
        Ok(true)
    }

    /// The session's settings on an RS232 line or (`can`) a CAN bus.
    pub fn config(&self, can: bool) -> Config {
        let mut config = if can { Config::can() } else { Config::rs232() };
        if let Some(t) = self.timeout_ms {
            config.reply_timeout = t.get();
        }
        config.poll_interval = self.poll_ms.get();
        (config.baud, config.can_bitrate) = (self.baud, self.bitrate);
        config
    }

    /// How motions are guarded: the one rule of [`Guard::for_motions`] for modules emulated in this process
    /// (`in_process`) or elsewhere.
    pub fn guard(&self, in_process: bool) -> Guard {
        Guard::for_motions(ModulesAt::emulated_in_process(in_process), self.no_watchdog)
    }

    /// Refuses the emulator's options for a port that is not `sim`.
    pub fn check_port(&self, sim: bool) -> Result<(), OptionError> {
        if !sim && !self.sim_variants.is_empty() {
            return Err(OptionError { key: Some("sim_variants"), message: "only for port sim".into() });
        }
        Ok(())
    }

    /// The bus an emulator in this process stands for: the module these options name, in the firmware
    /// variants asked for.
    pub fn emulated(&self) -> Result<SimConfig, OptionError> {
        let mut bus = SimConfig::with_addresses(&[self.module.get()])
            .map_err(|e| OptionError { key: Some("module"), message: e.to_string() })?;
        bus.variants = self.sim_variants.clone();
        Ok(bus)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_table_s_values_go_through_the_options_own_rules() {
        let mut o = ModuleOptions::default();
        assert!(o.set("module", "3").unwrap() && o.set("timeout_ms", "80").unwrap());
        assert!(o.set("sim_variants", "no-twin-mirror, ack-length-6").unwrap());
        assert!(!o.set("modules", "1").unwrap(), "not a key of these options");
        assert_eq!((o.module.get(), o.sim_variants.len()), (3, 2));
        assert_eq!(o.config(true).reply_timeout, std::time::Duration::from_millis(80));
        assert_eq!(o.emulated().unwrap().modules.len(), 1);
        assert!(o.set("module", "40").unwrap_err().to_string().starts_with("module: \"40\": "));
        assert!(o.set("no_watchdog", "yes").is_err());
        assert!(o.check_port(false).is_err() && o.check_port(true).is_ok());
        assert_eq!(o.guard(true), Guard::HaltOnly);
        assert_eq!(ModuleOptions::default().guard(false), Guard::Watchdog);
    }
}
