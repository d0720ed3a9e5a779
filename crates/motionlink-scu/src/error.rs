//! What went wrong in a session: [`Error`], with the unit's own status codes and error bits as values, and
//! its class in the one classification of every family ([`Classify`]).
//!
//! ```
//! use motionlink_link::error::{Classify, ErrorClass, TransportKind};
//! use motionlink_link::LinkError;
//! use motionlink_scu::Error;
//! let lost: Error = LinkError::Disconnected { port: "tcp://gw:4001".into(), reason: "reset".into() }.into();
//! assert_eq!(lost.class(), ErrorClass::Transport(TransportKind::Disconnected));
//! ```

use std::time::Duration;

use motionlink_link::error::{Classify, DeviceCode, ErrorBit, ErrorClass, TransportKind};
use motionlink_link::session::SessionError;
use motionlink_link::LinkError;

use crate::model::{Actuator, DataIndex, ErrorCode, Function, PositionCounts};
use crate::wire::{Command, Status, WireError};

/// What went wrong in a session.
#[derive(Debug, Clone, thiserror::Error)]
pub enum Error {
    /// The unit refused a request (an error status instead of ACK).
    #[error("{command} ({}) refused by the unit: {status}", command.description())]
    Refused {
        /// The request's command.
        command: Command,
        /// The unit's status.
        status: Status,
    },
    /// No reply in time.
    #[error("no reply to {command} within {timeout:?} ({attempts} attempt(s))")]
    Timeout {
        /// The request's command.
        command: Command,
        /// How long the reply was awaited.
        timeout: Duration,
        /// Attempts made.
        attempts: u32,
    },
    /// Replies arrived corrupt.
    #[error("corrupt reply to {command}: {error} ({attempts} attempt(s))")]
    Corrupt {
        /// The request's command.
        command: Command,
        /// What was wrong.
        error: WireError,
        /// Attempts made.
        attempts: u32,
    },
    /// The port failed.
    #[error(transparent)]
    Link(LinkError),
    /// The session is lost (port gone) and not reconnected.
    #[error("session lost: {0}")]
    SessionLost(String),
    /// The unit ended remote mode (or its watchdog expired); the session does not open it again by itself.
    #[error("{0}")]
    RemoteEnded(String),
    /// The session was closed.
    #[error("the session is closed")]
    Closed,
    /// A reply that does not fit its request.
    #[error("unexpected reply to {command}: {detail}")]
    UnexpectedReply {
        /// The request's command.
        command: Command,
        /// What was wrong.
        detail: String,
    },
    /// A request was not sent: with the round trips the link has, its reply would come back after the next RC
    /// must go out, and the unit's watchdog would expire (which stops every motion, and with Safety_ID 0 ends
    /// remote mode).
    #[error(
        "{command} was not sent: with round trips of {} ms on this link its reply would come back after the next \
         RC must be sent, and the unit's watchdog (500 ms without RC) would expire; waited {} ms for room between \
         the RC keepalives",
        round_trip.as_millis(),
        waited.as_millis()
    )]
    NoRoom {
        /// The request's command.
        command: Command,
        /// The round trip measured lately.
        round_trip: Duration,
        /// How long it waited.
        waited: Duration,
    },
    /// A value written to the unit reads back different. The data are as on the wire:
    /// [`decode_item`](crate::value::decode_item) of the index's [`item`](crate::model::item) gives their
    /// values (the message shows them so).
    #[error("{name} ({index}): wrote {}, the unit reads back {}", shown(*index, wrote), shown(*index, read))]
    ReadBack {
        /// The entry.
        name: &'static str,
        /// Its index.
        index: DataIndex,
        /// The data written.
        wrote: Vec<u8>,
        /// The data the unit returned.
        read: Vec<u8>,
    },
    /// After an RE or RS of a switching function that the unit acknowledged, the data-list entry that shows
    /// the function ([`Function::switch_status`]) shows the other state.
    #[error("{}", switch_not_shown(*function, *command, *word, *after, *switched_off))]
    SwitchNotShown {
        /// The function.
        function: Function,
        /// What the unit acknowledged: RE (switch on) or RS (switch off).
        command: Command,
        /// The entry's value, as last read.
        word: u16,
        /// How long after the acknowledge it was last read.
        after: Duration,
        /// The function was then switched off (the unit acknowledged the RS): a run whose RE the status did
        /// not show.
        switched_off: bool,
    },
    /// The caller asked for something impossible (bad index, value out of range, read-only entry).
    #[error("{0}")]
    InvalidArgument(String),
    /// A move's target lies outside the actuator's travel range; nothing was moved.
    #[error(
        "{}; nothing was moved",
        stroke_refusal(*actuator, *target_counts, *min_counts, *max_counts, limits_from)
    )]
    OutsideLimits {
        /// The actuator.
        actuator: Actuator,
        /// The target asked for.
        target_counts: PositionCounts,
        /// The lower limit.
        min_counts: PositionCounts,
        /// The upper limit.
        max_counts: PositionCounts,
        /// Where the limits come from.
        limits_from: &'static str,
    },
    /// The actuator is not connected (its status says "drive unavailable").
    #[error("{0} is not connected to the unit (actuator status 1: drive unavailable)")]
    NotConnected(Actuator),
    /// The unit in use does not do what the operation needs beyond the manual's words (it refused it; the
    /// message says what, and what to do instead).
    #[error("{0}")]
    NotSupported(String),
    /// A move ended away from its target; the function was stopped.
    #[error(
        "{actuator} ended at {position_counts}, {} counts from its target {} (more than the tolerance of \
         {tolerance_counts}); last error: {error_code}",
        position_counts.counts_from(*target_counts),
        target_counts.get()
    )]
    MotionEnded {
        /// The actuator.
        actuator: Actuator,
        /// Where it stopped.
        position_counts: PositionCounts,
        /// Where it was going.
        target_counts: PositionCounts,
        /// The tolerance of the move.
        tolerance_counts: u32,
        /// Error_Code 1 when it stopped.
        error_code: ErrorCode,
    },
    /// A follow ([`crate::client::Follower`]) ended with actuators away from the last target each was given
    /// (beyond the tolerance); the function was stopped.
    #[error(
        "the last target was not reached within {tolerance_counts} counts: {}",
        misses.iter().map(TargetMiss::to_string).collect::<Vec<_>>().join("; ")
    )]
    NotReached {
        /// The tolerance of the follow.
        tolerance_counts: u32,
        /// Each actuator that missed, in the stream's order.
        misses: Vec<TargetMiss>,
    },
    /// A move's actuator stopped advancing though the unit reports motion; it was stopped.
    #[error(
        "{actuator} stalled at {position_counts} (no progress for {} ms while the unit reported motion); stopped \
         (RS sent). A stall is an actuator that is driven but does not move: an obstacle or an end stop, a load too \
         heavy, or a speed too low for it (a TLT column stalls below about 30 % speed)",
        after.as_millis()
    )]
    Stalled {
        /// The actuator.
        actuator: Actuator,
        /// Where it stalled.
        position_counts: PositionCounts,
        /// How long without progress.
        after: Duration,
    },
    /// A move took longer than [`crate::Config::move_timeout`]; it was stopped.
    #[error("{actuator} did not reach its target within {} s; stopped at {position_counts}", after.as_secs_f64())]
    MoveTimeout {
        /// The actuator.
        actuator: Actuator,
        /// Where it stopped.
        position_counts: PositionCounts,
        /// The timeout.
        after: Duration,
    },
    /// The caller cancelled a move (Ctrl-C, a dropped future); the unit confirmed the stop.
    #[error("cancelled; {actuator} stopped at {position_counts}")]
    Cancelled {
        /// The actuator.
        actuator: Actuator,
        /// Where it came to rest.
        position_counts: PositionCounts,
    },
    /// The caller cancelled a function's run; the unit confirmed the stop.
    #[error("cancelled; {function} stopped (the unit confirmed it)")]
    RunCancelled {
        /// The function.
        function: Function,
        /// Where each connected actuator came to rest.
        rest: Vec<(Actuator, PositionCounts)>,
        /// As [`crate::session::RunReport::verified`]: a switching function's status showed it on after the RE
        /// and off after the RS.
        verified: bool,
        /// What could not be verified, and why.
        not_verifiable: Vec<String>,
    },
    /// After a stop the unit acknowledged, these actuators still report motion (another function or the hand
    /// switch may drive them).
    #[error(
        "{} still report(s) motion after the unit acknowledged the RS: another function or the hand switch may be \
         driving them",
        crate::model::Actuator::list(.0)
    )]
    StillMoving(Vec<Actuator>),
    /// The caller cancelled an operation while a function it had set going may have been moving (its RE
    /// still awaiting the ACK, a stream, a follow). As the error of the operation, `stopped`: the unit
    /// acknowledged the RS that followed. As the cause of [`Error::StopUnconfirmed`] (`stopped` false),
    /// what was cancelled.
    #[error("{}", cancelled_text(*function_id, *stopped))]
    FunctionCancelled {
        /// The function's id on the wire (`Function::from_id`; an RE may name an id the manual does not).
        function_id: u8,
        /// The unit acknowledged the RS of the function.
        stopped: bool,
    },
    /// The caller cancelled an operation before it sent anything that starts a motion.
    #[error("cancelled before {0} was sent; nothing was started")]
    CancelledBeforeMotion(Command),
    /// An action failed, and the stop that followed was not confirmed by the unit.
    #[error(
        "{}the stop ({}) was NOT confirmed by the unit ({detail}): the actuators may still be moving. \
         {WATCHDOG_NOTE}",
        unconfirmed_cause(cause, detail),
        crate::model::stop_words(functions, *mode)
    )]
    StopUnconfirmed {
        /// What went wrong first.
        cause: Box<Error>,
        /// The functions the stop was sent to.
        functions: Vec<crate::model::Function>,
        /// How (fast or soft).
        mode: crate::model::StopMode,
        /// Why it is not confirmed.
        detail: String,
    },
    /// The end of a session could not confirm the stop of the functions it had started.
    #[error(
        "stopping {} was NOT confirmed by the unit ({cause}): the actuators may still be moving. {WATCHDOG_NOTE}",
        crate::model::function_list(functions)
    )]
    CloseUnconfirmed {
        /// The functions still started.
        functions: Vec<crate::model::Function>,
        /// Why the end of the session failed.
        cause: Box<Error>,
    },
    /// The end of the session (the RS of every started function, then RA) was not confirmed within the bound.
    #[error(
        "the end of the session (RS of every function it started, then RA) was not confirmed within {bound:?}: the \
         actuators may still be moving. The unit stops remote motions by itself 500 ms after the last RC it \
         receives (its watchdog)"
    )]
    CloseTimedOut {
        /// The bound waited.
        bound: Duration,
    },
}

/// What the unit does when a stop is not confirmed, as the errors that say so end.
pub const WATCHDOG_NOTE: &str = "The unit stops remote motions by itself 500 ms after the last RC it receives \
                                 (its watchdog); this program sends none once it has ended";

impl Error {
    /// This error (the end of a session: [`Error::CloseUnconfirmed`]) as a note after an error that said
    /// already that a stop was not confirmed and what the unit's watchdog does then ([`WATCHDOG_NOTE`]):
    /// "the end of the session tried RS to F1 again: not confirmed either (cause)". Any other error as
    /// "then" and its message.
    pub fn note_after_unconfirmed(&self) -> String {
        match self {
            Error::CloseUnconfirmed { functions, cause } => {
                let why = match &**cause {
                    // Its message says what the watchdog does again.
                    Error::CloseTimedOut { bound } => format!("the close's bound of {bound:?} passed"),
                    other => other.to_string(),
                };
                format!(
                    "the end of the session tried RS to {} again: not confirmed either ({why})",
                    crate::model::function_list(functions)
                )
            }
            other => format!("then {other}"),
        }
    }
}

/// An actuator that ended a follow away from the last target it was given.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TargetMiss {
    /// The actuator.
    pub actuator: Actuator,
    /// The last target it was given.
    pub target_counts: PositionCounts,
    /// Where it came to rest.
    pub reached_counts: PositionCounts,
}

impl TargetMiss {
    /// Where it came to rest minus its target.
    pub fn difference_counts(&self) -> i64 {
        self.reached_counts.counts_from(self.target_counts)
    }
}

impl std::fmt::Display for TargetMiss {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}: target {}, reached {}, difference {}",
            self.actuator,
            self.target_counts.get(),
            self.reached_counts.get(),
            self.difference_counts()
        )
    }
}

impl Error {
    /// An error of the caller's input.
    pub(crate) fn invalid(what: impl Into<String>) -> Self {
        Error::InvalidArgument(what.into())
    }
}

/// What [`Error::SwitchNotShown`] says: "the unit acknowledged RS of F20 (emergency stop), but still shows
/// the emergency stop engaged: lock_status (0x0162) shows every motion function F1..F10 locked (0x03FF) (last
/// read 1000 ms after the acknowledge)".
fn switch_not_shown(function: Function, command: Command, word: u16, after: Duration, switched_off: bool) -> String {
    let Some(status) = function.switch_status() else {
        return format!("the unit acknowledged {command} of {function}, but its status shows otherwise (0x{word:04X})");
    };
    let shows = match status.shows_on(word) {
        true => format!("still shows {} {}", status.what, status.state(true)),
        false => format!("does not show {} {}", status.what, status.state(true)),
    };
    let then = if switched_off { "; then switched off (the unit acknowledged the RS)" } else { "" };
    format!(
        "the unit acknowledged {command} of {function}, but {shows}: {} (last read {} ms after the acknowledge){then}",
        status.detail(word),
        after.as_millis()
    )
}

/// Why a target outside the stroke is refused (what [`Error::OutsideLimits`] says before what that means for
/// a move).
fn stroke_refusal(
    actuator: Actuator,
    target: PositionCounts,
    min: PositionCounts,
    max: PositionCounts,
    limits_from: &str,
) -> String {
    format!(
        "target {target} for {actuator} refused: it lies outside {actuator}'s stroke {}..{max} ({limits_from})",
        min.get()
    )
}

impl Error {
    /// For [`Error::OutsideLimits`]: why the target was refused, without "nothing was moved", which holds for
    /// a move only (a follow's target refused after earlier ones had moved the actuators).
    pub fn stroke_refusal(&self) -> Option<String> {
        match self {
            Error::OutsideLimits { actuator, target_counts, min_counts, max_counts, limits_from } => {
                Some(stroke_refusal(*actuator, *target_counts, *min_counts, *max_counts, limits_from))
            }
            _ => None,
        }
    }
}

impl Classify for Error {
    fn class(&self) -> ErrorClass {
        match self {
            Error::Refused { .. } | Error::NotSupported(_) => ErrorClass::Refused,
            Error::MotionEnded { .. }
            | Error::NotReached { .. }
            | Error::Stalled { .. }
            | Error::MoveTimeout { .. }
            | Error::ReadBack { .. }
            | Error::SwitchNotShown { .. }
            | Error::NotConnected(_)
            | Error::StillMoving(_) => ErrorClass::Device,
            Error::Timeout { .. } | Error::NoRoom { .. } | Error::CloseTimedOut { .. } => {
                ErrorClass::Transport(TransportKind::Timeout)
            }
            Error::Corrupt { .. } | Error::UnexpectedReply { .. } => ErrorClass::Transport(TransportKind::Corrupt),
            Error::Link(e) => match e.class() {
                ErrorClass::Transport(kind) => ErrorClass::Transport(kind),
                _ => ErrorClass::Transport(TransportKind::Io),
            },
            Error::SessionLost(_) | Error::RemoteEnded(_) | Error::Closed => {
                ErrorClass::Transport(TransportKind::Disconnected)
            }
            Error::InvalidArgument(_) | Error::OutsideLimits { .. } => ErrorClass::Usage,
            // A cancel is of class Cancelled only once the unit confirmed the stop (the class promises that
            // what was started was stopped); one whose RS was not acknowledged is the line's failure.
            Error::FunctionCancelled { stopped: false, .. } => ErrorClass::Cancelled.stop_unconfirmed(),
            Error::Cancelled { .. }
            | Error::RunCancelled { .. }
            | Error::FunctionCancelled { .. }
            | Error::CancelledBeforeMotion(_) => ErrorClass::Cancelled,
            // The stop after a failure (or the end of the session) was not confirmed: the actuators may still
            // move.
            Error::StopUnconfirmed { cause, .. } | Error::CloseUnconfirmed { cause, .. } => {
                cause.class().stop_unconfirmed()
            }
        }
    }

    /// A stop the session tried was not confirmed: the actuators may be moving.
    fn stop_unconfirmed(&self) -> bool {
        matches!(
            self,
            Error::StopUnconfirmed { .. }
                | Error::CloseUnconfirmed { .. }
                | Error::CloseTimedOut { .. }
                | Error::FunctionCancelled { stopped: false, .. }
        )
    }

    /// The unit's Error_Code with its named bits (numbered 1..32 as the manual counts), of a motion that
    /// ended with one, also when a stop after it was not confirmed.
    fn reported(&self) -> Option<DeviceCode> {
        match self {
            Error::MotionEnded { error_code, .. } => Some(DeviceCode {
                code: u64::from(error_code.0),
                bits: error_code
                    .bits()
                    .map(|b| ErrorBit { bit: u32::from(b.number()), name: b.name().into(), cause: b.cause().into() })
                    .collect(),
            }),
            Error::StopUnconfirmed { cause, .. } | Error::CloseUnconfirmed { cause, .. } => cause.reported(),
            _ => None,
        }
    }
}

/// What went wrong first, as the message of a stop that was then not confirmed says it: a cancelled move
/// names where its actuator was last seen, not that it stopped there.
/// What went wrong before a stop that was not confirmed, with "; then " after it; nothing where the stop's
/// own failure is the cause (`detail` says it already: "X; then the stop ... (X)" would say it twice).
fn unconfirmed_cause(cause: &Error, detail: &str) -> String {
    match cause {
        Error::Cancelled { actuator, position_counts } => {
            format!("cancelled while {actuator} was moving (last seen at {position_counts}); then ")
        }
        other => {
            let text = other.to_string();
            if detail.ends_with(&text) {
                String::new()
            } else {
                format!("{text}; then ")
            }
        }
    }
}

/// "cancelled; F1 stopped (the unit acknowledged RS)" or "cancelled while F1 was under way" (an id no
/// function has: "function id 12").
fn cancelled_text(id: u8, stopped: bool) -> String {
    let name =
        crate::model::Function::from_id(id).map_or(format!("function id {id}"), |f| crate::model::function_list(&[f]));
    match stopped {
        true => format!("cancelled; {name} stopped (the unit acknowledged RS)"),
        false => format!("cancelled while {name} was under way"),
    }
}

/// Data of `index` as their values ("12, 300"), or as bytes where they do not decode.
fn shown(index: DataIndex, data: &[u8]) -> String {
    match crate::model::item(index).map(|it| crate::value::decode_item(it, data)) {
        Some(Ok(values)) => values.iter().map(|(_, v)| v.to_string()).collect::<Vec<_>>().join(", "),
        _ => format!("{data:02X?}"),
    }
}

impl From<LinkError> for Error {
    fn from(e: LinkError) -> Self {
        match e.class() {
            ErrorClass::Usage => Error::InvalidArgument(e.to_string()),
            _ => Error::Link(e),
        }
    }
}

impl SessionError for Error {
    fn close_timed_out(bound: Duration) -> Self {
        Error::CloseTimedOut { bound }
    }

    fn session_closed() -> Self {
        Error::Closed
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The close's note after an error that said a stop was not confirmed: what the close tried, and why it
    /// failed, without the watchdog's sentence a second time (also when the close ran out of its bound).
    #[test]
    fn the_close_s_note_after_an_unconfirmed_stop_says_the_watchdog_once() {
        let f1 = vec![crate::model::Function::from_id(0).unwrap()];
        for cause in
            [Error::SessionLost("port not connected".into()), Error::CloseTimedOut { bound: Duration::from_secs(5) }]
        {
            let close = Error::CloseUnconfirmed { functions: f1.clone(), cause: Box::new(cause) };
            let note = close.note_after_unconfirmed();
            assert!(note.starts_with("the end of the session tried RS to F1 again: not confirmed either ("), "{note}");
            assert!(!note.contains("its watchdog"), "{note}");
        }
        assert!(Error::SessionLost("x".into()).note_after_unconfirmed().starts_with("then "));
    }

    #[test]
    fn every_error_keeps_its_class() {
        let lost = Error::from(LinkError::Disconnected { port: "p".into(), reason: "r".into() });
        assert_eq!(lost.class(), ErrorClass::Transport(TransportKind::Disconnected));
        let invalid = Error::from(LinkError::InvalidPort { port: "p".into(), reason: "r".into() });
        assert_eq!(invalid.class(), ErrorClass::Usage);
        let refused = Error::Refused { command: Command::Execute, status: Status::PermissionError };
        assert_eq!(refused.class().exit_code(), 1);
        let unconfirmed = Error::StopUnconfirmed {
            cause: Box::new(Error::SessionLost("x".into())),
            functions: vec![crate::model::Function::from_id(0).unwrap()],
            mode: crate::model::StopMode::Fast,
            detail: "y".into(),
        };
        assert_eq!(unconfirmed.class(), ErrorClass::Transport(TransportKind::Disconnected));
        assert!(unconfirmed.stop_unconfirmed());
        // After a device error, a stop the unit did not confirm: the actuators may still move, exit 3 (the
        // unit's Error_Code still comes with it).
        let ended = Error::StillMoving(vec![Actuator::new(1).unwrap()]);
        assert_eq!(ended.class(), ErrorClass::Device);
        let unconfirmed = Error::StopUnconfirmed {
            cause: Box::new(ended),
            functions: Vec::new(),
            mode: crate::model::StopMode::Fast,
            detail: "y".into(),
        };
        assert_eq!(unconfirmed.class(), ErrorClass::Transport(TransportKind::Timeout));
        assert_eq!(
            Error::close_timed_out(Duration::from_secs(5)).class(),
            ErrorClass::Transport(TransportKind::Timeout)
        );
    }

    #[test]
    fn a_cancelled_function_is_named_and_says_whether_its_stop_was_acknowledged() {
        let stopped = Error::FunctionCancelled { function_id: 1, stopped: true };
        assert_eq!(stopped.to_string(), "cancelled; F2 stopped (the unit acknowledged RS)");
        assert_eq!(stopped.class(), ErrorClass::Cancelled);
        let unconfirmed = Error::StopUnconfirmed {
            cause: Box::new(Error::FunctionCancelled { function_id: 12, stopped: false }),
            functions: Vec::new(),
            mode: crate::model::StopMode::Fast,
            detail: "no ACK".into(),
        };
        assert!(unconfirmed.to_string().starts_with("cancelled while function id 12 was under way; then the stop"));
        // Not a clean cancel: the class Cancelled promises that what was started was stopped.
        assert_eq!(unconfirmed.class(), ErrorClass::Transport(TransportKind::Timeout));
        // A stop whose own failure is the cause says it once.
        let moving = Error::StillMoving(vec![crate::model::Actuator::new(1).unwrap()]);
        let own = Error::StopUnconfirmed {
            detail: moving.to_string(),
            cause: Box::new(moving),
            functions: Vec::new(),
            mode: crate::model::StopMode::Soft,
        };
        assert!(own.to_string().starts_with("the stop ("), "{own}");
        assert_eq!(own.to_string().matches("still report").count(), 1, "{own}");
    }
}
