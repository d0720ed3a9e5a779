//! The console's messages to a page, as they serialise: `{"type": ..., ...}`, with a unit's number under
//! the family's key (`actuator`, `module`, `drive`) and a sample's values under the unit's key names.

use serde::Serialize;
use serde_json::Value;

use super::device::{Action, ErrorReport, Param, Report, Sample, Unit};
use super::traffic::LogLine;
use crate::common::Keyed;

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

/// One unit's entry of a sample message: its sample, or why it could not be taken.
#[derive(Debug, Serialize)]
#[serde(untagged)]
pub enum SampleEntry {
    /// A look at the unit.
    Taken(Sample),
    /// The look failed: why.
    Failed {
        /// Why.
        error: ErrorReport,
    },
}

impl SampleEntry {
    /// The entry of `unit` for a sample (or its failure), with its number under `unit_key`.
    pub fn of(unit: &Unit, unit_key: &'static str, sample: Result<Sample, ErrorReport>) -> Numbered<SampleEntry> {
        let what = sample.map_or_else(|error| SampleEntry::Failed { error }, SampleEntry::Taken);
        Numbered { unit: Keyed(unit_key, unit.id), what }
    }
}

/// A message to a page; the fields of each as the page's script reads them.
#[derive(Debug, Serialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum Message {
    /// The first message: the family, its port and unit key, the parameter table, the other actions, the
    /// dead-man time and sample period in ms, and the page's role (a `role` message).
    Welcome {
        family: &'static str,
        port: String,
        unit_key: &'static str,
        params: Vec<Param>,
        actions: Vec<Action>,
        dead_man_ms: u64,
        sample_period_ms: u64,
        role: Box<Message>,
    },
    /// The page's role ("control" or "read_only"), whether no page controls, and the role in words.
    Role { role: &'static str, control_free: bool, message: &'static str },
    /// The units found, each with its number under the family's key: none while scanning (or after a failed
    /// scan, with its `error`, while the scan is tried again).
    Units {
        scanning: bool,
        units: Vec<Numbered<Unit>>,
        #[serde(skip_serializing_if = "Option::is_none")]
        error: Option<ErrorReport>,
    },
    /// One look at every unit, `t_s` seconds after the console started.
    Sample { t_s: f64, units: Vec<Numbered<SampleEntry>> },
    /// New lines of the decoded traffic log.
    Traffic { lines: Vec<LogLine> },
    /// A motion `what` ("move", "jog", an action's label) of a unit is "running", has "ended" (`ok`, and
    /// the `error` or the library's `report`) or was "stopped" (`ok` when the stop was confirmed, and the
    /// `reason`); `message` says what happened.
    Motion {
        state: &'static str,
        what: String,
        #[serde(flatten)]
        unit: Keyed<u8>,
        #[serde(skip_serializing_if = "Option::is_none")]
        ok: Option<bool>,
        #[serde(skip_serializing_if = "Option::is_none")]
        reason: Option<&'static str>,
        #[serde(skip_serializing_if = "Option::is_none")]
        error: Option<ErrorReport>,
        #[serde(skip_serializing_if = "Option::is_none")]
        message: Option<String>,
        #[serde(skip_serializing_if = "Option::is_none")]
        report: Option<Value>,
    },
    /// The answer to the Stop button: what was stopped, in words, and the library's report of the stop the
    /// device confirmed (that of `<family> stop --json`) where a unit was stopped (a stop that failed is
    /// `failed`).
    Stopped {
        ok: bool,
        message: String,
        #[serde(skip_serializing_if = "Option::is_none")]
        report: Option<Report>,
    },
    /// An action that does not move ended well: its name, label, and the library's report of it.
    Action { name: String, label: &'static str, ok: bool, report: Report },
    /// A value read, or written (and read back): the family's report of `get` or `set`.
    Param {
        written: bool,
        #[serde(flatten)]
        unit: Keyed<u8>,
        report: Report,
    },
    /// The error history of a unit: the family's report.
    Errors {
        #[serde(flatten)]
        unit: Keyed<u8>,
        report: Report,
    },
    /// A request that was not made (bad input, wrong role).
    Refused(RequestFailure),
    /// A request that was made and failed.
    Failed(RequestFailure),
    /// The console is ending.
    Bye { message: &'static str },
}

/// Why a request of a page failed: its type ("?" when it was not JSON), the failure, and its message.
#[derive(Debug, Serialize)]
pub struct RequestFailure {
    pub request: String,
    pub error: ErrorReport,
    pub message: String,
}

impl Message {
    /// The message as a JSON value (keys in alphabetical order, as `serde_json` keeps them).
    pub fn json(&self) -> Value {
        crate::common::to_json(self)
    }

    /// A `refused` (`made` false) or `failed` message for `request`.
    pub fn failure(request: &str, made: bool, error: ErrorReport) -> Message {
        let failure = RequestFailure { request: request.to_string(), message: error.message.clone(), error };
        if made {
            Message::Failed(failure)
        } else {
            Message::Refused(failure)
        }
    }
}
