//! The options that describe a session with one drive, as every front end that names a drive takes them:
//! the command line's `--drive`, `--mode`... and a device table's keys `drive`, `mode`... (devices.toml, the
//! gateway's file). One rule turns them into the session's settings ([`DriveOptions::config`]) and the
//! bus an in-process emulator stands for ([`DriveOptions::emulated`]).

use crate::model::{BaudRate, CommandStyle, PollInterval, ReplyTimeout, Tolerance};
use crate::session::Config;
use crate::sim::{SimConfig, Variant};
use crate::wire::{Address, Mode};

pub use motionlink_link::devices::OptionError;

/// The options of a session with one COMPAX drive, checked by their types. [`Default`] is what the command
/// line takes when an option is not given.
#[derive(Debug, Clone, PartialEq)]
pub struct DriveOptions {
    /// `drive`: the drive's address (P194).
    pub drive: Address,
    /// `mode`: the drives' operating mode P196.
    pub mode: Mode,
    /// `baud`: the drives' baud rate P195.
    pub baud: BaudRate,
    /// `timeout_ms`: the time a drive may take to start answering.
    pub timeout_ms: ReplyTimeout,
    /// `short`: send the short command names.
    pub short: bool,
    /// `poll_ms`: the interval of the status polls while a move is waited for (default: the session's).
    pub poll_ms: Option<PollInterval>,
    /// `tolerance`: how close to its target an axis must come to rest (default: the session's).
    pub tolerance: Option<Tolerance>,
    /// `sim_variants`: firmware variants of an in-process emulator.
    pub sim_variants: Vec<Variant>,
}

impl Default for DriveOptions {
    fn default() -> Self {
        DriveOptions {
            drive: "1".parse().expect("drive 1"),
            mode: "0".parse().expect("P196 0"),
            baud: BaudRate::DEFAULT,
            timeout_ms: "200".parse().expect("200 ms"),
            short: false,
            poll_ms: None,
            tolerance: None,
            sim_variants: Vec::new(),
        }
    }
}

impl DriveOptions {
    /// The keys of a device table these options take (the command line's options without `--`, with `_`).
    pub const KEYS: [&'static str; 8] =
        ["drive", "mode", "baud", "timeout_ms", "short", "poll_ms", "tolerance", "sim_variants"];

    /// Sets the option `key` from its text as a device table gives it (`sim_variants` takes one name or
    /// comma-separated names per call, added to those before; `short` takes `true` or `false`), by the
    /// option's own type and rule. `false` for a key that is not one of [`DriveOptions::KEYS`].
    pub fn set(&mut self, key: &str, text: &str) -> Result<bool, OptionError> {
        match key {
            "drive" => self.drive = OptionError::parsed("drive", text)?,
            "mode" => self.mode = OptionError::parsed("mode", text)?,
            "baud" => self.baud = OptionError::parsed("baud", text)?,
            "timeout_ms" => self.timeout_ms = OptionError::parsed("timeout_ms", text)?,
            "short" => self.short = OptionError::parsed("short", text)?,
            "poll_ms" => self.poll_ms = Some(OptionError::parsed("poll_ms", text)?),
            "tolerance" => self.tolerance = Some(OptionError::parsed("tolerance", text)?),
            "sim_variants" => {
                for name in text.split(',') {
                    self.sim_variants.push(OptionError::parsed("sim_variants", name.trim())?);
                }
            }
            _ => return Ok(false),
        }
        Ok(true)
    }

    /// The session's settings.
    pub fn config(&self) -> Config {
        let mut config = Config::new(self.mode, self.baud.bits_per_s());
        config.reply_timeout = self.timeout_ms.duration();
        config.style = if self.short { CommandStyle::Short } else { CommandStyle::Long };
        if let Some(p) = self.poll_ms {
            config.poll_interval = p.duration();
        }
        if let Some(t) = self.tolerance {
            config.in_position_tolerance = t.position();
        }
        config
    }

    /// Refuses the emulator's options for a port that is not `sim`.
    pub fn check_port(&self, sim: bool) -> Result<(), OptionError> {
        if !sim && !self.sim_variants.is_empty() {
            return Err(OptionError { key: Some("sim_variants"), message: "only for port sim".into() });
        }
        Ok(())
    }

    /// The bus an emulator in this process stands for: the drive these options name, in their mode and
    /// baud rate and the firmware variants asked for.
    pub fn emulated(&self) -> SimConfig {
        let mut config = SimConfig::bus(&[self.drive.get()], self.mode.to_p196(), self.baud.bits_per_s());
        config.variants = self.sim_variants.clone();
        config
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_table_s_values_go_through_the_options_own_rules() {
        let mut o = DriveOptions::default();
        assert!(o.set("drive", "3").unwrap() && o.set("mode", "8").unwrap() && o.set("short", "true").unwrap());
        assert!(o.set("tolerance", "0.5").unwrap() && o.set("poll_ms", "20").unwrap());
        assert!(!o.set("max_pos", "1").unwrap(), "a move's option, not the session's");
        let c = o.config();
        assert_eq!((c.mode.to_p196(), c.style, c.in_position_tolerance.units()), (8, CommandStyle::Short, 0.5));
        assert_eq!(c.poll_interval, std::time::Duration::from_millis(20));
        assert!(o.set("drive", "32").is_ok() || o.set("drive", "40").is_err());
        assert!(o.set("baud", "1234").unwrap_err().to_string().starts_with("baud: \"1234\": "));
        assert_eq!(o.emulated().drives.len(), 1);
        o.set("sim_variants", "no-echo").unwrap();
        assert!(o.check_port(false).is_err() && o.check_port(true).is_ok());
    }
}
