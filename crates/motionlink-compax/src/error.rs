//! The one error of the COMPAX crate, classified ([`Classify`]) for every front end, and the report of a
//! stop ([`StopReport`]) that errors carry when they ended an action while axes may have been moving.

use std::fmt;
use std::time::Duration;

use motionlink_link::error::{Classify, DeviceCode, ErrorClass, TransportKind};
use motionlink_link::session::SessionError;
use motionlink_link::LinkError;

use crate::model::{ErrorCode, ModelError, ParamId, Position};
use crate::wire::reply::ReplyError;
use crate::wire::{Address, WireError};

/// An error of a COMPAX session. Positions and distances are in the drive's position unit.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The drive answered with an error message.
    #[error("drive {address}: {command:?} refused with {code}")]
    Refused {
        /// The drive.
        address: Address,
        /// The command sent.
        command: String,
        /// The error.
        code: ErrorCode,
    },
    /// No reply in time, after every retry.
    #[error("drive {address}: no reply to {command:?} within {} ms ({attempts} attempts){}{}", waited.as_millis(), measured(round_trips), too_late(late))]
    Timeout {
        /// The drive.
        address: Address,
        /// The command sent.
        command: String,
        /// Telegrams sent.
        attempts: u32,
        /// How long the last attempt waited (the wire time of request and reply, and the reply timeout).
        waited: Duration,
        /// The round trips the session measured on this line before, if any.
        round_trips: Option<RoundTripRange>,
        /// Replies that came on this line after their telegram's time (and were not taken, so that none is
        /// taken for a later telegram's), if any: how long after their telegrams they came.
        late: Option<RoundTripRange>,
    },
    /// Replies arrived corrupt (BCC, framing), after every retry.
    #[error("drive {address}: corrupt reply to {command:?}: {detail}")]
    Corrupt {
        /// The drive.
        address: Address,
        /// The command sent.
        command: String,
        /// The last corruption seen.
        detail: ReplyError,
    },
    /// A reply the client cannot read.
    #[error("drive {address}: unexpected reply {reply:?} to {command:?}")]
    UnexpectedReply {
        /// The drive.
        address: Address,
        /// The command sent.
        command: String,
        /// The reply text.
        reply: String,
    },
    /// An operation of the session ended with an output of another kind than its call expects (a defect of
    /// this library, never of the drive).
    #[error("{what}: the session answered with {got} (a defect of this library)")]
    WrongOutput {
        /// The call.
        what: String,
        /// The output's kind.
        got: &'static str,
    },
    /// The port failed.
    #[error(transparent)]
    Link(#[from] LinkError),
    /// An argument out of range.
    #[error(transparent)]
    Model(#[from] ModelError),
    /// A telegram that cannot be built.
    #[error(transparent)]
    Encode(#[from] WireError),
    /// A move's reply was lost and the drive's state does not tell whether it took the move.
    #[error("drive {address}: the reply to {command:?} was lost and the drive's target ({target}) does not tell whether it was executed")]
    MoveUncertain {
        /// The drive.
        address: Address,
        /// The command sent.
        command: String,
        /// The target position S2 read afterwards.
        target: Position,
    },
    /// A wait for a position did not end in time; the axes were stopped.
    #[error("drive {address} did not reach its position within {after:?}; stopped")]
    MoveTimeout {
        /// The drive.
        address: Address,
        /// The time waited.
        after: Duration,
    },
    /// The operation was cancelled (a cancelled token, a dropped future, the session closing) while
    /// nothing this session set in motion was in its scope: nothing was stopped, and no move is sent once
    /// it is. Cancelled once axes it moved may run, the operation stops them instead ([`Error::Cancelled`]).
    #[error("cancelled: no further motion is sent")]
    CancelledBeforeMotion,
    /// The operation was cancelled while axes this session set in motion may have been moving: the client
    /// stopped them, and `stop` says for each drive whether the drive confirmed it (and, if not, that the
    /// axis may still be moving).
    #[error("cancelled: no further motion is sent; {stop}")]
    Cancelled {
        /// What the client did to stop the axes, drive by drive.
        stop: StopReport,
    },
    /// An action failed while axes this client set in motion may have been moving: the client tried to
    /// stop them, and `stop` says for each drive whether the drive confirmed it (and, if not, that the
    /// axis may still be moving).
    #[error("{cause}; {stop}")]
    FailedDuringMotion {
        /// What went wrong.
        cause: Box<Error>,
        /// What the client did to stop the axes, drive by drive.
        stop: StopReport,
    },
    /// A move ended with the axis at rest away from its target.
    #[error(
        "drive {address} did not reach its target: target {target}, reached {reached}, difference {:.3} \
         (in-position tolerance {tolerance})",
        .difference.units()
    )]
    NotReached {
        /// The drive.
        address: Address,
        /// The target asked for.
        target: Position,
        /// The actual position S1 read at rest.
        reached: Position,
        /// `reached - target`.
        difference: Position,
        /// [`Config::in_position_tolerance`](crate::session::Config::in_position_tolerance).
        tolerance: Position,
    },
    /// A homing (POSA HOME) that ended, by S17, with S16 showing the drive switched off (a stop, which is
    /// `OUTPUT O0=0`, ended it: another program's, say) or not showing machine zero approached (bit 3,
    /// MACHINE_ZERO: it did not find its zero). The axis is not referenced.
    #[error(
        "drive {address}'s homing (POSA HOME) ended at {position} {}: the axis is not referenced",
        match (*.switched_off, *.machine_zero) {
            (true, _) => "with the drive switched off (S16: O0=0): something stopped it",
            (false, _) => "without S16 showing machine zero approached (MACHINE_ZERO)",
        }
    )]
    NotHomed {
        /// The drive.
        address: Address,
        /// Where it rests (S1).
        position: Position,
        /// S16 shows it switched off (O0 = 0).
        switched_off: bool,
        /// S16 shows machine zero approached.
        machine_zero: bool,
    },
    /// The target a drive reports (S2, read twice after the move was sent) is not the one sent: a telegram
    /// was corrupted on the way (without a BCC a flipped bit in a digit is still a valid command). Returned
    /// inside [`Error::FailedDuringMotion`]: the session stops the axis at once.
    #[error(
        "drive {address} took target {taken} instead of {requested} (its S2 after the move; a corrupted telegram?)"
    )]
    TargetMismatch {
        /// The drive.
        address: Address,
        /// The target sent.
        requested: Position,
        /// The target S2 read back.
        taken: Position,
    },
    /// A target outside the travel limits the caller gave
    /// ([`TravelLimits`](crate::session::TravelLimits)); nothing was sent to move.
    #[error("drive {address}: target {target} is outside the travel limits: it is {side} {limit}")]
    OutsideLimits {
        /// The drive.
        address: Address,
        /// The target.
        target: Position,
        /// "below the minimum" or "above the maximum".
        side: &'static str,
        /// The limit crossed.
        limit: Position,
    },
    /// The drive is switched off (`OUTPUT O0=0`, S16 bits 7 and 8): it takes no move until it is switched on
    /// again with `OUTPUT O0=1`. `refused` is the code it answered a move with, if one was sent.
    #[error("drive {address} is switched off (O0={o0}, S16){}: it moves only once it is switched on again with OUTPUT O0=1", refused.map(|c| format!(" and refused the move with {c}")).unwrap_or_default())]
    SwitchedOff {
        /// The drive.
        address: Address,
        /// The O0 state S16 shows (0, or 2).
        o0: u8,
        /// The drive's answer to the move, when the move was sent.
        refused: Option<ErrorCode>,
    },
    /// An `OUTPUT O0=s` the drive acknowledged, but S16 read afterwards shows O0 in another state: the drive
    /// did not take it (or a corrupted telegram switched something else).
    #[error(
        "drive {address} acknowledged OUTPUT O0={wrote} but S16 read afterwards shows O0={read}: the drive did not \
         take it"
    )]
    OutputNotTaken {
        /// The drive.
        address: Address,
        /// The state sent.
        wrote: u8,
        /// The state S16 shows.
        read: u8,
    },
    /// A checked move was not sent: S17 shows the drive still executing a command (a positioning that runs,
    /// someone else's or one handed over), and the drive takes no move until it has ended (it would refuse
    /// one with E92). Nothing was sent to move; no device error code was reported.
    #[error(
        "drive {address} is still executing a command (S17 shows a command active, such as a positioning that \
         runs): the move was not sent; wait until it has ended, or stop it"
    )]
    StillMoving {
        /// The drive.
        address: Address,
    },
    /// A parameter written reads back another value.
    #[error(
        "drive {address}: {param} reads back {read} after {wrote} was written: the drive did not store the value \
         (without a BCC a corrupted telegram may even have written another parameter; P196 valence 8 adds one)"
    )]
    ReadBack {
        /// The drive.
        address: Address,
        /// The parameter.
        param: ParamId,
        /// The value written.
        wrote: f64,
        /// The value read back.
        read: f64,
    },
    /// A parameter written reads back as the value rounded (or cut) to the decimals the drive answers it
    /// with: the drive keeps the parameter in steps of that size, and holds the nearest step instead of the
    /// value written. Not a corrupted telegram ([`Error::ReadBack`]): the value is not one the drive holds.
    #[error(
        "drive {address}: {param} reads back {read} after {wrote} was written: the drive keeps {param} in steps of \
         {} (the decimals it answers with) and holds {read}, the step it could store; write {}",
        step(*decimals),
        whole(*decimals)
    )]
    Rounded {
        /// The drive.
        address: Address,
        /// The parameter.
        param: ParamId,
        /// The value written.
        wrote: f64,
        /// The value read back.
        read: f64,
        /// The decimals of the drive's reply.
        decimals: usize,
    },
    /// A synchronous start could not store every move, and sent no `!`. The drives in `buffered`
    /// acknowledged storing theirs (and the failed drive may have stored its own if its reply was lost): the
    /// manual has no command that empties a drive's buffer, so the next `!` to such a drive, or any `32!` on
    /// the bus, starts that move. The session counts them as started once it sends such a `!` itself.
    #[error("drive {failed}: storing the synchronous move failed ({source}); no '!' was sent, but a buffered move is still held by {}: the next '!' to such a drive, or any '32!', starts it (the manual has no command to empty a buffer)", drives(buffered))]
    SyncIncomplete {
        /// The drive whose move could not be stored.
        failed: u8,
        /// Why.
        source: Box<Error>,
        /// Drives that hold a buffered move from this call (ascending), the failed one included when its
        /// reply was lost.
        buffered: Vec<u8>,
    },
    /// A synchronous start refused before it sent anything: drives outside its list may still hold a move
    /// this session stored in their buffer and never executed (an earlier [`Error::NotExecuted`] or
    /// [`Error::SyncIncomplete`] named them), and its `32!` would start that move too.
    #[error("a '32!' would also execute the move still held in the buffer of {} (stored by this session and never executed: an earlier error named it); nothing was sent: give those drives a move of this synchronous start (a store replaces what a drive's buffer holds), or execute or replace their buffered move first", drives(held))]
    BufferHeld {
        /// Drives (ascending) outside the start's list that may hold a buffered move of this session.
        held: Vec<u8>,
    },
    /// A checked move sent to the drive's buffer with its echo (`,?`) was not executed: its echo did not
    /// come back as the telegram sent (or not at all), so no `!` was sent, or the `!` was refused or did
    /// not start it (or, where the drive refused the `!` and something may have run, the move was not sent
    /// again as a command of its own). The drives in `buffered` may still hold the command (as they received it) in their
    /// buffer: the manual has no command that empties a buffer, so the next `!` to such a drive, or any
    /// `32!` on the bus, executes it.
    #[error("drive {address}: the move {command:?}, sent with ',?' to be stored and echoed, was not executed by a '!' of this session: {why} ({source}); the command may still be held, as received, in the buffer of {}: the next '!' to such a drive, or any '32!' on the bus, executes it (the manual has no command to empty a buffer)", drives(buffered))]
    NotExecuted {
        /// The drive the move was for.
        address: Address,
        /// The move as sent, without the address and flags (`POSA 12.5`).
        command: String,
        /// What happened (`its echo was not the telegram sent ... so no '!' was sent`).
        why: String,
        /// The error behind it: the echo that came back ([`Error::UnexpectedReply`]), a lost or corrupt reply,
        /// the drive's refusal of `!`.
        source: Box<Error>,
        /// Drives (ascending) that may hold the command in their buffer: the drive addressed, and a drive
        /// whose address the echo shows.
        buffered: Vec<u8>,
    },
    /// Address 32 where one drive's answer or one drive is needed: every drive executes a broadcast and none
    /// answers it.
    #[error("address 32 is the broadcast: every drive executes it and none answers; {0}")]
    Broadcast(&'static str),
    /// The session is closed (or closing): it takes no new operation.
    #[error("the COMPAX session is closed: it takes no new operation")]
    Closed,
    /// A stop (`stop`, `stop_started`, [`StopReport::confirmed`]) that a drive did not confirm: its axis may
    /// still be moving.
    #[error("{stop}")]
    StopUnconfirmed {
        /// Drive by drive, how the stop ended.
        stop: StopReport,
    },
    /// Closing the session: the stop of what it had set in motion was not confirmed for every drive.
    #[error("closing the session: {stop}")]
    CloseUnconfirmed {
        /// Drive by drive, how the stop ended.
        stop: StopReport,
    },
    /// Closing the session did not end within its bound: the stop of what it had set in motion may not
    /// have reached the drives, whose axes may still be moving.
    #[error(
        "closing the session: the stop of the axes it moved did not end within {bound:?}; they may still be moving"
    )]
    CloseTimedOut {
        /// The bound ([`Config::close_bound`](crate::session::Config::close_bound)).
        bound: Duration,
    },
}

impl Error {
    /// True for errors of the line (timeout, corrupt reply, port), as opposed to the drive's answers (for
    /// [`Error::FailedDuringMotion`]: of its cause).
    pub fn is_transport(&self) -> bool {
        self.class().is_transport()
    }

    /// The drive's error code, if the drive refused (for [`Error::FailedDuringMotion`]: in its cause).
    pub fn device_code(&self) -> Option<ErrorCode> {
        match self.root() {
            Error::Refused { code, .. } => Some(*code),
            Error::SwitchedOff { refused, .. } => *refused,
            _ => None,
        }
    }

    /// What went wrong in the first place: the cause of an [`Error::FailedDuringMotion`], or the error itself.
    pub fn root(&self) -> &Error {
        match self {
            Error::FailedDuringMotion { cause, .. } => cause.root(),
            other => other,
        }
    }

    /// What the session did to stop the axes, when the error ended an action that may have left them
    /// moving ([`Error::Cancelled`], [`Error::FailedDuringMotion`], [`Error::StopUnconfirmed`],
    /// [`Error::CloseUnconfirmed`]).
    pub fn stop_report(&self) -> Option<&StopReport> {
        match self {
            Error::Cancelled { stop }
            | Error::FailedDuringMotion { stop, .. }
            | Error::StopUnconfirmed { stop }
            | Error::CloseUnconfirmed { stop } => Some(stop),
            _ => None,
        }
    }

    /// The drives this error left (or found) switched off: they take no move until `OUTPUT O0=1`.
    pub fn switched_off_drives(&self) -> Vec<u8> {
        match self {
            Error::SwitchedOff { address, .. } => vec![address.get()],
            _ => self.stop_report().map(|r| r.switched_off().iter().map(|a| a.get()).collect()).unwrap_or_default(),
        }
    }
}

impl Classify for Error {
    fn class(&self) -> ErrorClass {
        match self {
            Error::Refused { .. } => ErrorClass::Refused,
            Error::MoveTimeout { .. }
            | Error::NotReached { .. }
            | Error::NotHomed { .. }
            | Error::TargetMismatch { .. }
            | Error::SwitchedOff { .. }
            | Error::StillMoving { .. }
            | Error::ReadBack { .. }
            | Error::OutputNotTaken { .. }
            | Error::Rounded { .. } => ErrorClass::Device,
            // What the session started may still move: the line's failure, as in every family.
            Error::Timeout { .. }
            | Error::MoveUncertain { .. }
            | Error::CloseTimedOut { .. }
            | Error::StopUnconfirmed { .. }
            | Error::CloseUnconfirmed { .. } => ErrorClass::Transport(TransportKind::Timeout),
            Error::Corrupt { .. } | Error::UnexpectedReply { .. } | Error::WrongOutput { .. } => {
                ErrorClass::Transport(TransportKind::Corrupt)
            }
            Error::Link(e) => e.class(),
            Error::Model(_)
            | Error::Encode(_)
            | Error::Broadcast(_)
            | Error::OutsideLimits { .. }
            | Error::BufferHeld { .. }
            | Error::Closed => ErrorClass::Usage,
            // A cancel is of class Cancelled only once every drive confirmed the stop (the class promises that
            // what was started was stopped); otherwise the axis may still move, as after a failed line.
            Error::Cancelled { stop } if !stop.all_confirmed() => ErrorClass::Cancelled.stop_unconfirmed(),
            Error::CancelledBeforeMotion | Error::Cancelled { .. } => ErrorClass::Cancelled,
            // A failure whose stop a drive did not confirm: the axis may still move.
            Error::FailedDuringMotion { cause, stop } if !stop.all_confirmed() => cause.class().stop_unconfirmed(),
            Error::FailedDuringMotion { cause, .. } => cause.class(),
            Error::SyncIncomplete { source, .. } | Error::NotExecuted { source, .. } => source.class(),
        }
    }

    /// A drive did not confirm a stop the session sent: the axis may be moving.
    fn stop_unconfirmed(&self) -> bool {
        match self {
            Error::StopUnconfirmed { .. } | Error::CloseUnconfirmed { .. } | Error::CloseTimedOut { .. } => true,
            Error::Cancelled { stop } | Error::FailedDuringMotion { stop, .. } => !stop.all_confirmed(),
            Error::SyncIncomplete { source, .. } | Error::NotExecuted { source, .. } => source.stop_unconfirmed(),
            _ => false,
        }
    }

    /// The drive's `Exx` number ([`Error::device_code`]): a number, not a word of bits.
    fn reported(&self) -> Option<DeviceCode> {
        self.device_code().map(|c| DeviceCode { code: u64::from(c.0), bits: Vec::new() })
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

pub use motionlink_link::error::RoundTripRange;

/// The step of a value shown with `decimals` decimals: `1`, `0.1`, `0.001`.
fn step(decimals: usize) -> String {
    match decimals {
        0 => "1".to_string(),
        d => format!("0.{}1", "0".repeat(d - 1)),
    }
}

/// What value to write to a parameter the drive keeps to `decimals` decimals.
fn whole(decimals: usize) -> String {
    match decimals {
        0 => "a whole number".to_string(),
        1 => "a value of at most 1 decimal".to_string(),
        d => format!("a value of at most {d} decimals"),
    }
}

/// "; " and `r`, or nothing when the session has measured no round trip.
fn measured(r: &Option<RoundTripRange>) -> String {
    r.map(|r| format!("; {r}")).unwrap_or_default()
}

/// The replies that came too late, for [`Error::Timeout`].
fn too_late(r: &Option<RoundTripRange>) -> String {
    let Some(r) = r else { return String::new() };
    let (a, b) = (r.fastest.as_millis(), r.slowest.as_millis());
    let took = if a == b { format!("{a} ms") } else { format!("{a}-{b} ms") };
    format!(
        "; replies came {took} after their telegrams, too late to be taken (a longer reply timeout allows for them)"
    )
}

/// A result of a COMPAX operation.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// How stopping one drive ended. In JSON: `{"outcome": "at_rest" | "switched_off" | "not_confirmed"}`, the
/// last with its `reason`.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
#[serde(tag = "outcome", rename_all = "snake_case")]
pub enum StopOutcome {
    /// The drive reported no command active (S17): its positioning had ended; it was not switched off.
    AtRest,
    /// `OUTPUT O0=0` was acknowledged and the drive then reported no command active (S17): the axis is at
    /// rest and the drive is switched off; it takes no move until `OUTPUT O0=1` switches it on.
    SwitchedOff,
    /// The drive did not confirm the stop (no acknowledgement of `OUTPUT O0=0`, or S17 unreadable or still
    /// "command active" after it): the axis may still be moving.
    NotConfirmed {
        /// What happened.
        reason: String,
    },
}

/// What a stop of the axes a session set in motion did, drive by drive.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct StopReport {
    /// Each drive the session had set in motion, and how stopping it ended.
    pub drives: Vec<(Address, StopOutcome)>,
}

impl StopReport {
    /// True when there was nothing to stop.
    pub fn is_empty(&self) -> bool {
        self.drives.is_empty()
    }

    /// True when every drive confirmed it is at rest (found at rest, or switched off and then at rest).
    pub fn all_confirmed(&self) -> bool {
        self.drives.iter().all(|(_, o)| !matches!(o, StopOutcome::NotConfirmed { .. }))
    }

    /// The drives switched off (they need `OUTPUT O0=1` before the next move).
    pub fn switched_off(&self) -> Vec<Address> {
        self.drives.iter().filter(|(_, o)| *o == StopOutcome::SwitchedOff).map(|(a, _)| *a).collect()
    }

    /// The report, once every drive confirmed its stop; else [`Error::StopUnconfirmed`] (a transport error,
    /// as every error after which an axis may still move).
    pub fn confirmed(self) -> Result<StopReport, Error> {
        match self.all_confirmed() {
            true => Ok(self),
            false => Err(Error::StopUnconfirmed { stop: self }),
        }
    }

    /// The drives whose stop was not confirmed (they may still be moving).
    pub fn unconfirmed(&self) -> Vec<Address> {
        self.drives.iter().filter(|(_, o)| matches!(o, StopOutcome::NotConfirmed { .. })).map(|(a, _)| *a).collect()
    }
}

/// In JSON: `{"drives": [{"drive": 1, "outcome": ..., "reason": ...}, ...], "confirmed": bool}` (confirmed:
/// every drive confirmed it is at rest).
impl serde::Serialize for StopReport {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> std::result::Result<S::Ok, S::Error> {
        #[derive(serde::Serialize)]
        struct Drive<'a> {
            drive: u8,
            #[serde(flatten)]
            outcome: &'a StopOutcome,
        }
        #[derive(serde::Serialize)]
        struct Report<'a> {
            drives: Vec<Drive<'a>>,
            confirmed: bool,
        }
        let drives = self.drives.iter().map(|(a, outcome)| Drive { drive: a.get(), outcome }).collect();
        Report { drives, confirmed: self.all_confirmed() }.serialize(serializer)
    }
}

impl fmt::Display for StopReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.drives.is_empty() {
            return f.write_str("no axis of this client was moving");
        }
        for (i, (a, o)) in self.drives.iter().enumerate() {
            if i > 0 {
                f.write_str("; ")?;
            }
            match o {
                StopOutcome::AtRest => write!(f, "drive {a} was already at rest (not switched off by this stop)")?,
                StopOutcome::SwitchedOff => write!(
                    f,
                    "drive {a} was stopped by switching it off (OUTPUT O0=0, confirmed by the drive): the drive is \
                     now switched off and takes no move until OUTPUT O0=1 switches it on"
                )?,
                StopOutcome::NotConfirmed { reason } => write!(
                    f,
                    "drive {a}: the stop was NOT confirmed by the drive ({reason}): the axis may still be moving"
                )?,
            }
        }
        Ok(())
    }
}

/// Drive addresses in words: "drive 1", "drives 1, 3".
fn drives(list: &[u8]) -> String {
    let numbers: Vec<String> = list.iter().map(u8::to_string).collect();
    match numbers.len() {
        1 => format!("drive {}", numbers[0]),
        _ => format!("drives {}", numbers.join(", ")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_error_has_the_class_a_front_end_maps() {
        let stop = StopReport { drives: vec![(Address::drive(3).unwrap(), StopOutcome::SwitchedOff)] };
        let not_confirmed = StopOutcome::NotConfirmed { reason: "silent".into() };
        let unconfirmed = StopReport { drives: vec![(Address::drive_const(3), not_confirmed)] };
        let mismatch = || Error::TargetMismatch {
            address: Address::drive_const(3),
            requested: Position::new(15.0).unwrap(),
            taken: Position::new(14.0).unwrap(),
        };
        let cases: Vec<(Error, ErrorClass)> = vec![
            (
                Error::Refused { address: Address::drive_const(1), command: "S1".into(), code: ErrorCode(92) },
                ErrorClass::Refused,
            ),
            (
                Error::NotReached {
                    address: Address::drive_const(1),
                    target: Position::new(1.0).unwrap(),
                    reached: Position::new(0.5).unwrap(),
                    difference: Position::new(-0.5).unwrap(),
                    tolerance: Position::new(0.01).unwrap(),
                },
                ErrorClass::Device,
            ),
            (
                Error::Timeout {
                    address: Address::drive_const(1),
                    command: "S1".into(),
                    attempts: 4,
                    waited: Duration::from_millis(210),
                    round_trips: None,
                    late: None,
                },
                ErrorClass::Transport(TransportKind::Timeout),
            ),
            (
                Error::UnexpectedReply { address: Address::drive(1).unwrap(), command: "S1".into(), reply: "x".into() },
                ErrorClass::Transport(TransportKind::Corrupt),
            ),
            (
                Error::Link(LinkError::Disconnected { port: "p".into(), reason: "r".into() }),
                ErrorClass::Transport(TransportKind::Disconnected),
            ),
            (Error::Broadcast("x"), ErrorClass::Usage),
            (Error::CancelledBeforeMotion, ErrorClass::Cancelled),
            (Error::Cancelled { stop: stop.clone() }, ErrorClass::Cancelled),
            // A cancel, a failure or a close whose stop a drive did not confirm: the axis may still move, a
            // transport error (exit 3), never the class of a settled end.
            (Error::Cancelled { stop: unconfirmed.clone() }, ErrorClass::Transport(TransportKind::Timeout)),
            (Error::CloseUnconfirmed { stop: unconfirmed.clone() }, ErrorClass::Transport(TransportKind::Timeout)),
            (unconfirmed.clone().confirmed().unwrap_err(), ErrorClass::Transport(TransportKind::Timeout)),
            (
                Error::FailedDuringMotion { cause: Box::new(mismatch()), stop: unconfirmed },
                ErrorClass::Transport(TransportKind::Timeout),
            ),
            (Error::FailedDuringMotion { cause: Box::new(mismatch()), stop }, ErrorClass::Device),
            (Error::close_timed_out(Duration::from_secs(5)), ErrorClass::Transport(TransportKind::Timeout)),
            (Error::session_closed(), ErrorClass::Usage),
        ];
        for (e, class) in cases {
            assert_eq!(e.class(), class, "{e}");
            // Flagged exactly where a stop was not confirmed (here: the errors carrying `unconfirmed`, the
            // close's bound), each of which says the axis may still move.
            let says = e.to_string().contains("may still be moving") || e.to_string().contains("NOT confirmed");
            assert_eq!(e.stop_unconfirmed(), says, "{e}");
            // And each such error is of the line (exit 3), never the class of a settled end.
            assert!(!e.stop_unconfirmed() || e.class().is_transport(), "{e}");
        }
        let inner = Error::FailedDuringMotion {
            cause: Box::new(Error::CancelledBeforeMotion),
            stop: StopReport {
                drives: vec![(Address::drive_const(2), StopOutcome::NotConfirmed { reason: "x".into() })],
            },
        };
        let sync = Error::NotExecuted {
            address: Address::drive_const(2),
            command: "POSA 1".into(),
            why: "x".into(),
            source: Box::new(inner),
            buffered: vec![2],
        };
        assert!(sync.stop_unconfirmed(), "a wrapped unconfirmed stop: {sync}");
    }
}
