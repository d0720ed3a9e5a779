//! What the actions `stop`, `errors` and `run` print, as every front end prints or sends it (the command
//! line's `--json`, the gateway's replies): the library's reports with the action's own keys.

use serde::Serialize;

use crate::model::{ErrorCode, Function, MotionFunction};
use crate::session::SwitchReport;

/// What `stop` stops: the motion functions named (every one, F1..F10, when none is), or another function
/// (buzzer, outputs, emergency stop, LEDs) switched off with RS.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum StopScope {
    /// Motion functions: RS, then the status until no actuator moves.
    Motions(Vec<MotionFunction>),
    /// A switching function: RS.
    Switch(Function),
}

impl StopScope {
    /// The scope of `stop [FUNCTION]`.
    pub fn of(function: Option<Function>) -> StopScope {
        match function {
            Some(Function::Motion(m)) => StopScope::Motions(vec![m]),
            None => StopScope::Motions(MotionFunction::all().collect()),
            Some(f) => StopScope::Switch(f),
        }
    }
}

/// A switching function switched off with RS: `{"mode": "off", "verified", "not_verifiable"}`, whether the
/// status entry that shows it showed it off afterwards ([`crate::session::SwitchReport`]).
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct SwitchedOff {
    /// Always `off`.
    pub mode: &'static str,
    /// Its status entry showed it off after the RS.
    pub verified: bool,
    /// Why that could not be verified (empty when `verified`).
    pub not_verifiable: Vec<String>,
}

impl From<SwitchReport> for SwitchedOff {
    fn from(r: SwitchReport) -> Self {
        SwitchedOff { mode: "off", verified: r.verified, not_verifiable: r.not_verifiable }
    }
}

/// A stop without the keys of the front end that made it: `{function (if named), ...report}`, `report` the
/// library's ([`crate::session::StopReport`], [`SwitchedOff`], or [`Stopped`], either of them). What
/// Python's `Scu.stop()` returns; [`StopResult`] puts the command's keys before it.
#[derive(Debug, Clone, Serialize)]
pub struct FunctionStop<R: Serialize> {
    /// The function named, if one was.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub function: Option<Function>,
    /// The stop's report.
    #[serde(flatten)]
    pub report: R,
}

/// What a stop did, as one type: the motion functions stopped, confirmed by the status, or a switching
/// function switched off (serialised as the report it holds).
#[derive(Debug, Clone, Serialize)]
#[serde(untagged)]
pub enum Stopped {
    /// RS to motion functions, then the status until no actuator moves.
    Motions(crate::session::StopReport),
    /// A switching function switched off with RS.
    Switch(SwitchedOff),
}

/// What `stop` reports: `{action: "stop", stopped: true, holder, function (if named), ...report}`, where
/// `holder` is the front end's own (the command line: the motionlink that held the port and was stopped
/// first, or null), and the rest the stop itself ([`FunctionStop`]).
#[derive(Debug, Clone, Serialize)]
pub struct StopResult<H: Serialize, R: Serialize> {
    /// Always `stop`.
    pub action: &'static str,
    /// Always true: an unconfirmed stop is an error, not a result.
    pub stopped: bool,
    /// Who held the port and was stopped first (null when nobody did).
    pub holder: Option<H>,
    /// The stop.
    #[serde(flatten)]
    pub stop: FunctionStop<R>,
}

impl<H: Serialize, R: Serialize> StopResult<H, R> {
    /// The result of a confirmed stop of `function` (None: every motion function).
    pub fn new(holder: Option<H>, function: Option<Function>, report: R) -> Self {
        StopResult { action: "stop", stopped: true, holder, stop: FunctionStop { function, report } }
    }
}

/// What `errors` reports: `{"errors": [Error_Code 1 (most recent), ..., Error_Code 5]}`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct ErrorHistory {
    /// Error_Code 1..5.
    pub errors: [ErrorCode; 5],
}

/// A function's run began (the unit acknowledged its RE): `{"function", "running": true}`, for a switching
/// function with `verified`: whether the status entry that shows it showed it on
/// ([`crate::session::RunProgress::switched_on_shown`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct Running {
    /// The function.
    pub function: Function,
    /// Always true.
    pub running: bool,
    /// A switching function: its status showed it on after the RE (`None` for a motion function).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub verified: Option<bool>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stop_serialises_with_the_action_s_keys() {
        let off = SwitchReport { function: Function::Buzzer, on: false, verified: true, not_verifiable: Vec::new() };
        let r = StopResult::new(None::<String>, "F11".parse().ok(), SwitchedOff::from(off));
        assert_eq!(
            serde_json::to_value(&r).unwrap(),
            serde_json::json!({"action": "stop", "stopped": true, "holder": null, "function": 11, "mode": "off",
                "verified": true, "not_verifiable": []})
        );
        assert_eq!(StopScope::of(None), StopScope::Motions(MotionFunction::all().collect()));
        assert_eq!(StopScope::of("F11".parse().ok()), StopScope::Switch(Function::Buzzer));
    }
}
