//! The keys of a `[device.NAME]` table besides `family` and `port`: the same keys the command line takes
//! from a device of devices.toml (every option of the family's commands, of their actions and of the
//! family's console, named without `--`), each in one of three kinds:
//!
//! - an option of the device and its session (`module`, `baud`, `functions`...): the family crate's
//!   options type takes it (`UnitOptions`, `ModuleOptions`, `DriveOptions`), as on the command line;
//! - an option of some actions (`speed` of a move, `soft` of a stop...): the device's default for the
//!   requests of those actions, checked at start by the argument's own type; a request's `args` override it;
//! - an option that means nothing to a gateway (a watch's `csv`, the console's `jog_range`, `capture` of
//!   one command's session): accepted, as the command line accepts it, and ignored (docs/fleet.md says why).
//!
//! Any other key is refused, named with the keys the family takes.

use serde_json::{Map, Value};

/// A key that is an option of some actions of the family: the device's default for their requests.
#[derive(Debug, Clone, Copy)]
pub struct OpDefault {
    /// The key, as a request's argument names it.
    pub key: &'static str,
    /// The actions (`op`) that take it.
    pub ops: &'static [&'static str],
}

/// The keys of a family's device table: what each is.
#[derive(Debug, Clone, Copy)]
pub struct FamilyKeys {
    /// Options of the device and its session (the family crate's options type).
    pub options: &'static [&'static str],
    /// Options of actions: the device's defaults for them.
    pub defaults: &'static [OpDefault],
    /// Options the command line takes from a device table that mean nothing to a gateway, with why.
    pub ignored: &'static [(&'static str, &'static str)],
}

/// A wire capture of one command's session: a gateway's sessions run for days.
const CAPTURE: (&str, &str) = ("capture", "a wire capture of one command's session");
/// The options of `watch`: a gateway publishes states at `sample_hz`.
const WATCH: [(&str, &str); 3] = [
    ("count", "an option of watch (the gateway's states come at sample_hz)"),
    ("csv", "an option of watch (the gateway's states come at sample_hz)"),
    ("interval_ms", "an option of watch (the gateway's states come at sample_hz)"),
];

/// An SCU unit's keys.
pub const SCU: FamilyKeys = FamilyKeys {
    options: &motionlink_scu::args::UnitOptions::KEYS,
    defaults: &[
        OpDefault { key: "speed", ops: &["move"] },
        OpDefault { key: "function", ops: &["move"] },
        OpDefault { key: "soft", ops: &["stop"] },
        OpDefault { key: "seconds", ops: &["run"] },
    ],
    ignored: &[
        CAPTURE,
        WATCH[0],
        WATCH[1],
        WATCH[2],
        ("allow_watchdog_lapse", "an option of watch: the gateway's states never let the unit's watchdog lapse"),
        ("rate", "an option of follow, which the gateway does not serve"),
    ],
};

/// A PowerCube module's keys.
pub const POWERCUBE: FamilyKeys = FamilyKeys {
    options: &motionlink_powercube::args::ModuleOptions::KEYS,
    defaults: &[
        OpDefault { key: "vel", ops: &["move"] },
        OpDefault { key: "acc", ops: &["move"] },
        OpDefault { key: "tolerance", ops: &["move"] },
        OpDefault { key: "timeout_s", ops: &["move", "motion", "home"] },
    ],
    ignored: &[
        CAPTURE,
        WATCH[0],
        WATCH[1],
        WATCH[2],
        ("modules", "the console's modules (a gateway's device is the one module of `module`)"),
    ],
};

/// A COMPAX drive's keys.
pub const COMPAX: FamilyKeys = FamilyKeys {
    options: &motionlink_compax::DriveOptions::KEYS,
    defaults: &[
        OpDefault { key: "speed", ops: &["move"] },
        OpDefault { key: "accel", ops: &["move"] },
        OpDefault { key: "binary", ops: &["move"] },
        OpDefault { key: "timeout_s", ops: &["move"] },
        OpDefault { key: "min_pos", ops: &["move"] },
        OpDefault { key: "max_pos", ops: &["move"] },
    ],
    ignored: &[
        CAPTURE,
        WATCH[0],
        WATCH[1],
        WATCH[2],
        ("drives", "the console's drives (a gateway's device is the one drive of `drive`)"),
        ("jog_range", "the console's jog"),
        ("wait", "an option of raw, which the gateway does not serve"),
    ],
};

/// The keys of `family` (`None` for no family of these).
pub fn of(family: &str) -> Option<&'static FamilyKeys> {
    match family {
        "scu" => Some(&SCU),
        "powercube" => Some(&POWERCUBE),
        "compax" => Some(&COMPAX),
        _ => None,
    }
}

/// The SCU's key for an emulator's configuration file (`port = "sim"`), which the gateway reads itself
/// ([`UnitOptions`](motionlink_scu::args::UnitOptions) has no such option).
pub const SCU_SIM_CONFIG: &str = "sim_config";

impl FamilyKeys {
    /// Every key a device table of the family may have besides `family` and `port`, sorted.
    pub fn all(&self, family: &str) -> Vec<&'static str> {
        let mut all: Vec<&'static str> = self.options.to_vec();
        all.extend(self.defaults.iter().map(|d| d.key));
        all.extend(self.ignored.iter().map(|(k, _)| *k));
        if family == "scu" {
            all.push(SCU_SIM_CONFIG);
        }
        all.sort_unstable();
        all.dedup();
        all
    }

    /// The default of `key`, if it is an option of actions.
    pub fn default_of(&self, key: &str) -> Option<&'static OpDefault> {
        self.defaults.iter().find(|d| d.key == key)
    }

    /// Why `key` is ignored, if it is.
    pub fn ignored(&self, key: &str) -> Option<&'static str> {
        self.ignored.iter().find(|(k, _)| *k == key).map(|(_, why)| *why)
    }

    /// A request's `args` with the device's `defaults` for `op` under them (the request's own win).
    pub fn with_defaults(
        &self,
        op: &str,
        defaults: &Map<String, Value>,
        mut args: Map<String, Value>,
    ) -> Map<String, Value> {
        for (key, value) in defaults {
            let takes = self.default_of(key).is_some_and(|d| d.ops.contains(&op));
            if takes && !args.contains_key(key) {
                args.insert(key.clone(), value.clone());
            }
        }
        args
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_key_is_of_one_kind() {
        for (family, keys) in [("scu", SCU), ("powercube", POWERCUBE), ("compax", COMPAX)] {
            let mut seen = Vec::new();
            seen.extend(keys.options.iter().copied());
            seen.extend(keys.defaults.iter().map(|d| d.key));
            seen.extend(keys.ignored.iter().map(|(k, _)| *k));
            let n = seen.len();
            seen.sort_unstable();
            seen.dedup();
            assert_eq!(seen.len(), n, "{family}: a key of two kinds: {seen:?}");
        }
    }

    #[test]
    fn a_request_s_args_override_the_device_s_defaults_for_the_actions_that_take_them() {
        let defaults: Map<String, Value> = serde_json::from_str(r#"{"speed": 40, "soft": true}"#).unwrap();
        let args: Map<String, Value> = serde_json::from_str(r#"{"actuator": 1, "position": 300}"#).unwrap();
        let merged = SCU.with_defaults("move", &defaults, args.clone());
        assert_eq!(Value::Object(merged), serde_json::json!({"actuator": 1, "position": 300, "speed": 40}));
        let mut own = args.clone();
        own.insert("speed".into(), 90.into());
        assert_eq!(SCU.with_defaults("move", &defaults, own)["speed"], 90);
        assert_eq!(Value::Object(SCU.with_defaults("stop", &defaults, Map::new())), serde_json::json!({"soft": true}));
        assert!(SCU.with_defaults("info", &defaults, Map::new()).is_empty());
    }
}
