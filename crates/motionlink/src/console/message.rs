//! The console's messages to a page, as they serialise: `{"type": ..., ...}`, with a unit's number under
//! the family's key (`actuator`, `module`, `drive`) and a sample's values under the unit's key names.

use serde::ser::{SerializeMap, Serializer};
use serde::Serialize;
use serde_json::Value;

use super::device::{Action, ErrorHistory, Failure, Param, ParamValue, Sample, Unit};
use super::traffic::LogLine;

/// `value` under a name known only at run time (`"module": 3`, `"position_rad": 0.5`); flattened into the
/// message that holds it.
#[derive(Debug, Clone, Copy)]
pub struct Keyed<T>(pub &'static str, pub T);

impl<T: Serialize> Serialize for Keyed<T> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut map = s.serialize_map(Some(1))?;
        map.serialize_entry(self.0, &self.1)?;
        map.end()
    }
}

/// `what` with the number of its unit under the family's key.
#[derive(Debug, Serialize)]
pub struct Numbered<T> {
    /// The unit's number (`"drive": 1`).
    #[serde(flatten)]
    pub unit: Keyed<u8>,
    /// What is said of it.
    #[serde(flatten)]
    pub what: T,
}

/// One unit's entry of a sample message: its sample under its key names, or why it could not be taken.
#[derive(Debug, Serialize)]
#[serde(untagged)]
pub enum SampleEntry {
    /// A look at the unit.
    Taken {
        /// Its position under the unit's position key.
        #[serde(flatten)]
        position: Keyed<f64>,
        /// Its speed under the unit's speed key, where known.
        #[serde(flatten)]
        speed: Option<Keyed<f64>>,
        /// Its motor current in A, where the device reports it.
        #[serde(skip_serializing_if = "Option::is_none")]
        current_amps: Option<f64>,
        /// Set flags, by name.
        flags: Vec<&'static str>,
        /// The flags among them that report a fault.
        faults: Vec<&'static str>,
        /// True while it moves.
        moving: bool,
        /// Set bits that have no name (left out when none).
        #[serde(skip_serializing_if = "is_zero")]
        unknown_bits: u64,
    },
    /// The look failed.
    Failed {
        /// Why.
        error: Failure,
    },
}

fn is_zero(n: &u64) -> bool {
    *n == 0
}

impl SampleEntry {
    /// The entry of `unit` for a sample (or its failure), with its number under `unit_key`.
    pub fn of(unit: &Unit, unit_key: &'static str, sample: Result<Sample, Failure>) -> Numbered<SampleEntry> {
        let what = match sample {
            Ok(s) => SampleEntry::Taken {
                position: Keyed(unit.position_key, s.position),
                speed: s.speed.map(|v| Keyed(unit.speed_key, v)),
                current_amps: s.current_amps,
                flags: s.flags,
                faults: s.faults,
                moving: s.moving,
                unknown_bits: s.unknown_bits,
            },
            Err(error) => SampleEntry::Failed { error },
        };
        Numbered { unit: Keyed(unit_key, unit.id), what }
    }
}

/// A message to a page.
#[derive(Debug, Serialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum Message {
    /// The first message: what the page shows and may ask.
    Welcome {
        /// "scu", "powercube" or "compax".
        family: &'static str,
        /// The port, as the user gave it.
        port: String,
        /// The JSON name of a unit's number.
        unit_key: &'static str,
        /// The parameter table or data list.
        params: Vec<Param>,
        /// The family's other actions.
        actions: Vec<Action>,
        /// How long a jog runs without a renewal, in ms.
        dead_man_ms: u64,
        /// How often the device is sampled, in ms.
        sample_period_ms: u64,
        /// The page's role (a `role` message).
        role: Box<Message>,
    },
    /// The page's role.
    Role {
        /// "control" or "read-only".
        role: &'static str,
        /// True when no page controls the console.
        control_free: bool,
        /// The role in words.
        message: &'static str,
    },
    /// The units found (none while scanning).
    Units {
        /// True while the scan is under way (or tried again after a failure).
        scanning: bool,
        /// The units, each with its number under the family's key.
        units: Vec<Numbered<Unit>>,
        /// Why the scan failed.
        #[serde(skip_serializing_if = "Option::is_none")]
        error: Option<Failure>,
    },
    /// One look at every unit.
    Sample {
        /// Seconds since the console started.
        t_s: f64,
        /// One entry per unit.
        units: Vec<Numbered<SampleEntry>>,
    },
    /// Decoded telegrams of the traffic log.
    Traffic {
        /// The new lines.
        lines: Vec<LogLine>,
    },
    /// A motion started, ended or was stopped.
    Motion {
        /// "running", "ended" or "stopped".
        state: &'static str,
        /// "move", "jog" or an action's label.
        what: String,
        /// The unit.
        #[serde(flatten)]
        unit: Keyed<u8>,
        /// True when it ended well or its stop was confirmed (none while running).
        #[serde(skip_serializing_if = "Option::is_none")]
        ok: Option<bool>,
        /// Why it was stopped.
        #[serde(skip_serializing_if = "Option::is_none")]
        reason: Option<&'static str>,
        /// Why it failed.
        #[serde(skip_serializing_if = "Option::is_none")]
        error: Option<Failure>,
        /// What happened, in words (none while running).
        #[serde(skip_serializing_if = "Option::is_none")]
        message: Option<String>,
        /// The library's report of a motion that ended well, where the family keeps one.
        #[serde(skip_serializing_if = "Option::is_none")]
        report: Option<Value>,
    },
    /// The answer to the Stop button.
    Stopped {
        /// Always true (a stop that failed is a `failed` message).
        ok: bool,
        /// What the device confirmed.
        message: String,
    },
    /// An action that does not move ended well.
    Action {
        /// Its name.
        name: String,
        /// Its label.
        label: &'static str,
        /// Always true.
        ok: bool,
        /// What the device did.
        message: String,
    },
    /// A value read or written.
    Param {
        /// True for a write (read back).
        written: bool,
        /// The value.
        param: ParamValue,
    },
    /// The error history of a unit.
    Errors(Numbered<ErrorHistory>),
    /// A request that was not made (bad input, wrong role).
    Refused {
        /// The request's type ("?" when it was not JSON).
        request: String,
        /// Why.
        error: Failure,
        /// Why, in words.
        message: String,
    },
    /// A request that was made and failed.
    Failed {
        /// The request's type.
        request: String,
        /// Why.
        error: Failure,
        /// Why, in words.
        message: String,
    },
    /// The console is ending.
    Bye {
        /// In words.
        message: &'static str,
    },
}

impl Message {
    /// The message as a JSON value (keys in the order `serde_json` keeps them).
    pub fn json(&self) -> Value {
        crate::common::to_json(self)
    }

    /// A `refused` (`made` false) or `failed` message for `request`.
    pub fn failure(request: &str, made: bool, error: Failure) -> Message {
        let (request, message) = (request.to_string(), error.message.clone());
        if made {
            Message::Failed { request, error, message }
        } else {
            Message::Refused { request, error, message }
        }
    }
}
