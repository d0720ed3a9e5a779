//! How the gateway ends with an error, and the errors its replies carry.

use motionlink_link::error::ErrorClass;

/// Why the gateway could not run: a usage error (exit code 2: the file, the command line, the security
/// rules; found before any connection) or a transport error (exit code 3: the broker cannot be reached at
/// start).
#[derive(Debug, thiserror::Error)]
pub enum GatewayError {
    /// The configuration or the command line is wrong.
    #[error("{0}")]
    Usage(String),
    /// The broker cannot be reached, or the TLS setup failed.
    #[error("{0}")]
    Transport(String),
}

impl GatewayError {
    /// The command line's exit code: 2 usage, 3 transport.
    pub fn exit_code(&self) -> u8 {
        match self {
            GatewayError::Usage(_) => ErrorClass::Usage.exit_code(),
            GatewayError::Transport(_) => 3,
        }
    }

    /// The error as the command line's `--json` prints one: `{"exit_code", "kind", "message"}`.
    pub fn report(&self) -> ErrorReport {
        match self {
            GatewayError::Usage(m) => ErrorReport::usage(m),
            GatewayError::Transport(m) => <ErrorReport as GatewayErrors>::transport(m.clone()),
        }
    }
}

pub use motionlink_link::error::ErrorReport;

/// The error of a reply is an [`ErrorReport`]: `{"kind", "message", "exit_code"}`, as the command line's
/// `--json` prints an error (`kind` is the error class's name, `exit_code` the command line's for it); the
/// gateway adds kinds of its own (`lease_expired`, `busy`, `broker_lost`, `unavailable`, `no_lease`), made
/// here.
pub trait GatewayErrors {
    /// A motion request while another motion runs on the device (exit code 3, as the command line's for a
    /// port in use).
    fn busy(message: impl Into<String>) -> Self;
    /// A device whose port failed, while the gateway opens it again (exit code 3, a transport error).
    fn unavailable(message: impl Into<String>) -> Self;
    /// The device could not be opened, or its session failed.
    fn transport(message: impl Into<String>) -> Self;
    /// Why the gateway stops a motion, with the device's stop that followed: its report in one
    /// line, or its error. A stop that failed was not confirmed: the axis may still be moving, so the
    /// error says `stop_unconfirmed` and exit code 3, as the command line's after a Ctrl-C whose stop the
    /// device did not confirm (its kind still says why the gateway stopped it).
    fn stopped(reason: &StopReason, stop: Result<String, ErrorReport>) -> Self;
    /// Whether this error says the device's port is gone (the library's `disconnected`): its session must
    /// be opened again.
    fn port_failed(&self) -> bool;
}

impl GatewayErrors for ErrorReport {
    fn busy(message: impl Into<String>) -> Self {
        ErrorReport::new("busy", message, 3)
    }

    fn unavailable(message: impl Into<String>) -> Self {
        ErrorReport::new("unavailable", message, 3)
    }

    fn transport(message: impl Into<String>) -> Self {
        ErrorReport::new("io", message, 3)
    }

    fn stopped(reason: &StopReason, stop: Result<String, ErrorReport>) -> Self {
        let (kind, exit_code) = match reason {
            StopReason::LeaseExpired { .. } => ("lease_expired", ErrorClass::Cancelled.exit_code()),
            StopReason::StopRequest { .. } | StopReason::PortStop { .. } => {
                ("cancelled", ErrorClass::Cancelled.exit_code())
            }
            StopReason::BrokerLost => ("broker_lost", 3),
            StopReason::PortFailed { .. } => ("disconnected", 3),
            StopReason::Signal { number, .. } => ("cancelled", 128 + *number as u8),
        };
        match stop {
            Ok(summary) => ErrorReport::new(kind, format!("{reason}; the device's stop then: {summary}"), exit_code),
            Err(e) => {
                let message = format!("{reason}; the device's stop then failed: {}", e.message);
                ErrorReport { stop_unconfirmed: true, ..ErrorReport::new(kind, message, 3) }
            }
        }
    }

    fn port_failed(&self) -> bool {
        self.kind == "disconnected"
    }
}

/// Why the gateway stops a motion (the library's cancel: the stop Ctrl-C makes on the command line); said in
/// the present tense, as what the gateway set out to do: what the device's stop found follows it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum StopReason {
    /// No keepalive came within the lease.
    LeaseExpired {
        /// The lease, in ms.
        lease_ms: u64,
    },
    /// A `stop` request.
    StopRequest {
        /// The stop request's id.
        id: String,
    },
    /// `motionlink FAMILY --port PORT stop` from another process, through the port's lock.
    PortStop {
        /// That process: `motionlink pid N (its command)`.
        who: String,
    },
    /// The gateway lost the broker: no lease could be renewed.
    BrokerLost,
    /// The device's port failed (a USB adapter unplugged, a TCP server gone): its session is gone.
    PortFailed {
        /// What failed, as the library said.
        error: String,
    },
    /// A signal ends the gateway.
    Signal {
        /// Its number.
        number: i32,
        /// Its name (SIGTERM).
        name: &'static str,
    },
}

impl std::fmt::Display for StopReason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            StopReason::LeaseExpired { lease_ms } => {
                write!(f, "the lease lapsed: no keepalive within {lease_ms} ms, so the gateway stops the motion")
            }
            StopReason::StopRequest { id } => write!(f, "a stop request {id:?} asks the gateway to stop the motion"),
            StopReason::PortStop { who } => {
                write!(f, "a stop from {who} through the port's lock asks the gateway to stop the motion")
            }
            StopReason::BrokerLost => {
                f.write_str("the gateway lost the broker (no lease could be renewed), so it stops the motion")
            }
            StopReason::Signal { name, .. } => write!(f, "{name} received: the gateway stops the motion"),
            StopReason::PortFailed { error } => {
                write!(f, "the device's port failed ({error}), so the gateway stops the motion")
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stop_of_the_gateway_that_failed_says_the_axis_may_still_move() {
        let lapsed = StopReason::LeaseExpired { lease_ms: 500 };
        let done = ErrorReport::stopped(&lapsed, Ok("{\"stopped\":true}".into()));
        assert_eq!((done.kind.as_ref(), done.exit_code, done.stop_unconfirmed), ("lease_expired", 130, false));
        assert!(done.message.ends_with("the device's stop then: {\"stopped\":true}"), "{}", done.message);
        let silent = ErrorReport::new("timeout", "module 1: Halt not acknowledged (3 sent)", 3);
        let failed = ErrorReport::stopped(&lapsed, Err(silent));
        assert_eq!((failed.kind.as_ref(), failed.exit_code, failed.stop_unconfirmed), ("lease_expired", 3, true));
        assert!(failed.message.ends_with("the device's stop then failed: module 1: Halt not acknowledged (3 sent)"));
        // What the gateway set out to do, not a stop it claims: the device's stop failed.
        assert!(failed
            .message
            .starts_with("the lease lapsed: no keepalive within 500 ms, so the gateway stops the motion;"));
        let json = serde_json::to_value(&failed).unwrap();
        assert_eq!(json["stop_unconfirmed"], true, "{json}");
    }

    #[test]
    fn every_reason_says_what_the_gateway_set_out_to_do_not_a_stop_it_claims() {
        let reasons = [
            (StopReason::StopRequest { id: "s1".into() }, "a stop request \"s1\" asks the gateway to stop the motion"),
            (
                StopReason::PortStop { who: "pid 7".into() },
                "a stop from pid 7 through the port's lock asks the gateway to stop the motion",
            ),
            (
                StopReason::PortFailed { error: "connection reset".into() },
                "the device's port failed (connection reset), so the gateway stops the motion",
            ),
            (
                StopReason::LeaseExpired { lease_ms: 500 },
                "the lease lapsed: no keepalive within 500 ms, so the gateway stops the motion",
            ),
            (StopReason::BrokerLost, "the gateway lost the broker (no lease could be renewed), so it stops the motion"),
            (StopReason::Signal { number: 15, name: "SIGTERM" }, "SIGTERM received: the gateway stops the motion"),
        ];
        for (reason, said) in reasons {
            // The device's stop failed: the reason does not say the motion was stopped, nor the stop reached.
            let silent = ErrorReport::new("timeout", "drive 1: no answer", 3);
            let failed = ErrorReport::stopped(&reason, Err(silent));
            assert!(failed.stop_unconfirmed, "{reason:?}");
            assert_eq!(failed.message, format!("{said}; the device's stop then failed: drive 1: no answer"));
            // The device's stop confirmed: the same words, then what it found.
            let done = ErrorReport::stopped(&reason, Ok("{\"stopped\":true}".into()));
            assert!(!done.stop_unconfirmed, "{reason:?}");
            assert_eq!(done.message, format!("{said}; the device's stop then: {{\"stopped\":true}}"));
        }
    }
}
