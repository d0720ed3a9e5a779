//! What a gateway publishes besides replies: the events of a device (`motionlink/<gw>/<device>/events`,
//! not retained) and the result of a keepalive.

/// One event: a motion started or ended, a lease lapsed, an error with no one to reply to.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Event<'a> {
    /// `motion_started`, `motion_ended`, `lease_expired`, `error`, `repeated` (a motion request whose id was
    /// taken already: not run again), `retained` (a request delivered as a retained message: not run),
    /// `port_released` (a `stop` from another
    /// process took the device's port), `port_taken` (the gateway serves it again), `port_failed` (the
    /// device's port failed: its session is gone), `port_reopened` (served again; where a motion ran when the
    /// port failed, after the device's stop over the new session: `ok` and `error` say what it found),
    /// `device_silent` (the device does not answer over a port that is fine), `state_failed` (a state sample
    /// failed otherwise), `device_answers` (a state sample succeeds again).
    pub event: &'static str,
    /// The request's (or motion's) id, if there is one.
    pub id: Option<&'a crate::request::RequestId>,
    /// The action (`move`...), if there is one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub op: Option<&'a str>,
    /// The lease of a motion that started or lapsed, in ms.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub lease_ms: Option<u64>,
    /// How a motion ended: true when it did what was asked; for `port_reopened`, whether the device's stop
    /// over the new session was confirmed.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ok: Option<bool>,
    /// The error, for an error and a motion that failed.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<&'a crate::error::ErrorReport>,
    /// What happened, in words (`port_released`: what was stopped, for whom).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub message: Option<&'a str>,
}

impl<'a> Event<'a> {
    /// An event of kind `event` about request `id`.
    pub fn new(event: &'static str, id: Option<&'a crate::request::RequestId>) -> Event<'a> {
        Event { event, id, op: None, lease_ms: None, ok: None, error: None, message: None }
    }
}

/// The result of a keepalive: `{"renewed": true, "lease_ms"}`.
#[derive(Debug, Clone, Copy, serde::Serialize)]
pub struct Renewed {
    /// Always true (a keepalive that renews nothing is an error).
    pub renewed: bool,
    /// The lease, in ms: the next keepalive is due within it.
    pub lease_ms: u64,
}

/// The state of a device whose port failed (retained on its `state` topic until the device is served
/// again): after the identity (`family`, `port`, the module or drive), `"available": false`, the error that
/// ended its session and when (`t_s`, as a state's).
#[derive(Debug, Clone, serde::Serialize)]
pub struct Unavailable<'a> {
    /// Always false: no state can be read.
    pub available: bool,
    /// What failed.
    pub error: &'a crate::error::ErrorReport,
    /// Seconds since the gateway started, when it failed.
    pub t_s: f64,
}
