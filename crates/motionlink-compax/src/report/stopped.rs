//! What `stop` reports, as every front end prints or sends it (the command line's `--json`, the gateway's
//! replies): the stop's report, where the axis stands then, and whether the drive is switched on.

use serde::Serialize;

use crate::error::{Error, StopReport};
use crate::model::Position;

/// A drive's stop as the front ends show it, without their own keys: the stop's report (confirmed by S17),
/// where the axis stands then (`position_units`, S1) and whether the drive is switched on (`o0`, from S16),
/// with `position_not_read` / `o0_not_read` saying why a value could not be read (then null). What
/// [`Client::stop_confirmed`](crate::Client::stop_confirmed) returns and Python's `Compax.stop()` gives.
#[derive(Debug, Clone, Serialize)]
pub struct DriveStop {
    /// The stop, confirmed by S17.
    #[serde(flatten)]
    pub report: StopReport,
    /// S1 read after the stop.
    pub position_units: Option<Position>,
    /// Why S1 could not be read.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub position_not_read: Option<String>,
    /// Output O0 (the drive switched on: 1) from S16 read after the stop.
    pub o0: Option<u8>,
    /// Why S16 could not be read.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub o0_not_read: Option<String>,
}

impl DriveStop {
    /// The confirmed stop `report`, with S1 (`position`) and O0 from S16 (`o0`) as they were read (or why
    /// they could not be).
    pub fn new(report: StopReport, position: Result<Position, Error>, o0: Result<u8, Error>) -> Self {
        let not_read = |e: Option<&Error>| e.map(Error::to_string);
        DriveStop {
            position_not_read: not_read(position.as_ref().err()),
            o0_not_read: not_read(o0.as_ref().err()),
            position_units: position.ok(),
            o0: o0.ok(),
            report,
        }
    }
}

/// `stop`'s result: `{action: "stop", holder, ...the drive's stop}` ([`DriveStop`]). `holder` is the front
/// end's own (the command line: the motionlink that held the port and was stopped first, or null).
#[derive(Debug, Clone, Serialize)]
pub struct StopResult<H: Serialize> {
    /// Always `stop`.
    pub action: &'static str,
    /// Who held the port and was stopped first (null when nobody did).
    pub holder: Option<H>,
    /// The stop, and what was read after it.
    #[serde(flatten)]
    pub stop: DriveStop,
}

impl<H: Serialize> StopResult<H> {
    /// The result of the drive's stop `stop`, after `holder`.
    pub fn new(holder: Option<H>, stop: DriveStop) -> Self {
        StopResult { action: "stop", holder, stop }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn what_could_not_be_read_is_said() {
        let r = StopResult::new(
            None::<String>,
            DriveStop::new(StopReport::default(), Ok(Position(1.5)), Err(Error::CancelledBeforeMotion)),
        );
        let json = serde_json::to_value(&r).unwrap();
        assert_eq!((json["action"].clone(), json["position_units"].clone()), ("stop".into(), 1.5.into()));
        assert!(json["o0"].is_null() && json["o0_not_read"].is_string() && json.get("position_not_read").is_none());
    }
}
