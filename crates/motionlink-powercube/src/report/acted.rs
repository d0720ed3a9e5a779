//! What the actions `home`, `move`, `motion`, `stop` and `reset` report and what `watch` samples, as every front end
//! prints or sends it (the command line's `--json`, the gateway's replies and states): the library's reports
//! with the action's own keys.

use serde::Serialize;

use super::Sample;

/// A report with the action's keys: its tag (`homed`, `reached`, `ran`, `halted`, `reset`), `ok` where the action
/// has no report of its own to say so (`halted`, `reset`), and for `stop` who held the port (`holder`: the
/// front end's own; the command line names the motionlink it stopped first, or null).
#[derive(Debug, Clone, Serialize)]
pub struct Acted<T: Serialize, H: Serialize = ()> {
    /// True for an action whose report does not say itself that it succeeded (left out when false).
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub ok: bool,
    /// `homed`, `reached`, `ran`, `halted` or `reset`.
    pub action: &'static str,
    /// The library's report.
    #[serde(flatten)]
    pub report: T,
    /// `stop` only (`Some`): who held the port and was stopped first, or null.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub holder: Option<Option<H>>,
}

impl<T: Serialize> Acted<T> {
    /// `home`'s result.
    pub fn homed(report: T) -> Self {
        Acted { ok: false, action: "homed", report, holder: None }
    }

    /// `move`'s result.
    pub fn reached(report: T) -> Self {
        Acted { ok: false, action: "reached", report, holder: None }
    }

    /// `motion`'s result (the report says how the motion ended: `ended`).
    pub fn ran(report: T) -> Self {
        Acted { ok: false, action: "ran", report, holder: None }
    }

    /// `reset`'s result.
    pub fn reset(report: T) -> Self {
        Acted { ok: true, action: "reset", report, holder: None }
    }
}

impl<T: Serialize, H: Serialize> Acted<T, H> {
    /// `stop`'s result: the halt, and who held the port first (`None`: nobody).
    pub fn halted(report: T, holder: Option<H>) -> Self {
        Acted { ok: true, action: "halted", report, holder: Some(holder) }
    }
}

/// What `reset` did besides the Reset: `{"watchdog_released"}`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct Released {
    /// True when a watchdog that had expired with no host serving it was switched off.
    pub watchdog_released: bool,
}

/// A sample of `watch`: the time since the first, then the sample (`{t_s, position_rad, state}`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Timed {
    /// Seconds since the first sample.
    pub t_s: f64,
    /// The sample.
    #[serde(flatten)]
    pub sample: Sample,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_action_s_keys_come_with_the_report() {
        let r = Acted::reset(Released { watchdog_released: false });
        assert_eq!(
            serde_json::to_value(&r).unwrap(),
            serde_json::json!({"ok": true, "action": "reset", "watchdog_released": false})
        );
        let h: Acted<Released, String> = Acted::halted(Released { watchdog_released: true }, None);
        assert_eq!(serde_json::to_value(&h).unwrap()["holder"], serde_json::Value::Null);
    }
}
