//! The one error type of the PowerCube family: device answers and named state flags as values, each error
//! classified ([`Classify`]) as device refused, device error, transport (timeout, disconnected, corrupt),
//! usage or cancelled, so that every front end maps classes, not variants.

use std::fmt;
use std::time::Duration;

use motionlink_link::error::{Classify, DeviceCode, ErrorClass, TransportKind};
use motionlink_link::session::SessionError;
use motionlink_link::LinkError;

use crate::model::{Address, CubeState, InvalidAddress, ModuleKind, Param, Position, Quantity, Value};
use crate::wire::rs232::Rs232Error;
use crate::wire::{ModelError, Request};

mod limit;
use limit::beyond_limit_text;

/// What became of the Halt an action sent to a module it had set in motion, when the action could not go
/// on (a failing line, a timeout, a cancellation).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum StopOutcome {
    /// Nothing had been set in motion yet: nothing to stop.
    NotStarted,
    /// The module acknowledged the Halt and then reported no STATE_MOTION (its state read after the Halt,
    /// for at most [`HALT_SETTLE`](crate::session::HALT_SETTLE)): it is at rest, and stays halted until a
    /// reset.
    Confirmed,
    /// The stop was not seen through: no Halt was acknowledged (it was tried three times), or the module
    /// acknowledged it but still reported STATE_MOTION after
    /// [`HALT_SETTLE`](crate::session::HALT_SETTLE), or its state could not be read after it. A Halt was
    /// broadcast; the axis may still be moving.
    Unconfirmed {
        /// Why: the last Halt's error, or what the state read after an acknowledged Halt showed.
        reason: String,
        /// The session had switched the module's watchdog on: its refresh has been stopped, so a module
        /// that the Halt did not reach halts itself within 50 ms of the last refresh that reached it.
        watchdog_armed: bool,
    },
}

impl StopOutcome {
    /// True unless a Halt was needed and not confirmed.
    pub fn is_confirmed(&self) -> bool {
        !matches!(self, StopOutcome::Unconfirmed { .. })
    }
}

impl fmt::Display for StopOutcome {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            StopOutcome::NotStarted => f.write_str("nothing had been set in motion"),
            StopOutcome::Confirmed => f.write_str(
                "the module acknowledged the halt and then reported no motion (STATE_MOTION clear): it is at rest",
            ),
            StopOutcome::Unconfirmed { reason, watchdog_armed } => {
                write!(f, "the halt was not confirmed ({reason}): the axis may still be moving")?;
                if *watchdog_armed {
                    // The watchdog the session had armed was left online, and how the module is cleared.
                    f.write_str(
                        "; its watchdog is online and no longer refreshed, so if the halt did not reach it the \
                         module halts itself within 50 ms of the last refresh that did (STATE_COMM_ERROR; \
                         `reset` clears it)",
                    )
                } else {
                    f.write_str("; no watchdog is armed on it: only a halt or the emergency stop stops it now")
                }
            }
        }
    }
}

/// How a session's watchdog refresh went out (see [`Error::WatchdogExpired`]), measured on the session's
/// own clock when it handed each refresh to the line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RefreshTiming {
    /// The longest time between two consecutive refreshes while the watchdog was armed (the time since
    /// the last one included).
    pub longest_gap: Duration,
    /// The most the modules wait for the next refresh ([`WATCHDOG_TIMEOUT`](crate::model::WATCHDOG_TIMEOUT)).
    pub allowed: Duration,
    /// The round trips the session measured on this link, if any (a slow link is named in the message).
    pub round_trips: Option<RoundTripRange>,
}

impl RefreshTiming {
    /// True when a refresh went out later than the modules wait: the host did not run the session in time.
    pub fn was_late(&self) -> bool {
        self.longest_gap > self.allowed
    }
}

impl fmt::Display for RefreshTiming {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (gap, allowed) = (self.longest_gap.as_millis(), self.allowed.as_millis());
        if self.was_late() {
            write!(
                f,
                "the watchdog refresh came {gap} ms late (at most {allowed} ms allowed): this host did not run the \
                 program in time; the module halted itself{}",
                measured(&self.round_trips)
            )
        } else {
            write!(
                f,
                "the watchdog refreshes went out in time (at most {gap} ms apart, {allowed} ms allowed), so the \
                 line or the module lost them; the module halted itself{}",
                measured(&self.round_trips)
            )
        }
    }
}

pub use motionlink_link::error::RoundTripRange;

/// "; " and `r`, or nothing when the session has measured no round trip.
fn measured(r: &Option<RoundTripRange>) -> String {
    r.map(|r| format!("; {r}")).unwrap_or_default()
}

/// What went wrong in a session. Device errors ([`Error::is_device`]) are the module's answer; transport
/// errors ([`Error::is_transport`]) are the line's; usage errors ([`Error::is_usage`]) are the caller's.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The port or the line failed.
    #[error(transparent)]
    Link(#[from] LinkError),
    /// No acknowledge in time.
    #[error("module {address} did not answer {request} within {} ms{}", waited.as_millis(), measured(round_trips))]
    Timeout {
        /// The module.
        address: Address,
        /// The request.
        request: Request,
        /// How long the session waited (the last attempt).
        waited: Duration,
        /// The round trips the session measured on this link before, if any.
        round_trips: Option<RoundTripRange>,
    },
    /// Only a corrupt answer came (bad BCC, broken frame, unknown content).
    #[error("module {address}: corrupt answer to {request}: {detail}")]
    Corrupt {
        /// The module.
        address: Address,
        /// The request.
        request: Request,
        /// What was wrong.
        detail: String,
    },
    /// The module reports error flags; they are named.
    #[error("module {address} reports an error: {}", fault_names(*state))]
    Device {
        /// The module.
        address: Address,
        /// Its state word (match on the flags with [`CubeState::contains`]).
        state: CubeState,
    },
    /// The module's watchdog expired while this session refreshed it (STATE_COMM_ERROR): it halted itself.
    /// [`Error::WatchdogExpired::timing`] says whether the refresh went out late (a host too loaded to run
    /// the program in time) or in time (lost on the line or in the module). `reset` clears it.
    #[error("module {address} reports an error: {}; {timing}", fault_names(*state))]
    WatchdogExpired {
        /// The module.
        address: Address,
        /// Its state word.
        state: CubeState,
        /// How the refresh went out.
        timing: RefreshTiming,
    },
    /// The module is halted (STATE_HALTED) without an error flag: a Halt, or a watchdog that expired.
    #[error("module {address} is halted (STATE_HALTED); send a reset")]
    Halted {
        /// The module.
        address: Address,
        /// Its state word.
        state: CubeState,
    },
    /// The module acknowledged a Halt, but its state still showed STATE_MOTION when the session stopped
    /// looking ([`HALT_SETTLE`](crate::session::HALT_SETTLE) later): the axis may still be moving.
    #[error(
        "module {address} acknowledged the Halt, but still reports STATE_MOTION {} ms later (state: {state}): \
         the axis may still be moving",
        waited.as_millis()
    )]
    StillMoving {
        /// The module.
        address: Address,
        /// The last state read.
        state: CubeState,
        /// How long the session looked.
        waited: Duration,
    },
    /// The module acknowledged with a status other than 0x64.
    #[error("module {address} refused {request} (status 0x{status:02X})")]
    Refused {
        /// The module.
        address: Address,
        /// The request.
        request: Request,
        /// The status byte.
        status: u8,
    },
    /// Homing or a motion did not end in time; the motion was halted ([`Error::MoveTimeout::stop`] says
    /// whether that was confirmed).
    #[error("module {address}: {what} did not happen within {} ms (state: {state}); {stop}", waited.as_millis())]
    MoveTimeout {
        /// The module.
        address: Address,
        /// What was waited for.
        what: &'static str,
        /// How long.
        waited: Duration,
        /// The last state read.
        state: CubeState,
        /// What became of the Halt.
        stop: StopOutcome,
    },
    /// The action was cancelled (Ctrl-C, a signal, [`Client::set_cancel`](crate::Client::set_cancel),
    /// a dropped future); what it had set in motion was halted ([`Error::Cancelled::stop`] says whether that
    /// was confirmed).
    #[error("module {address}: cancelled; {stop}")]
    Cancelled {
        /// The module.
        address: Address,
        /// What became of the Halt.
        stop: StopOutcome,
    },
    /// The line failed, or the module stopped answering, while a motion this session started may have been
    /// running: the session tried to halt it, and [`Error::FailedDuringMotion::stop`] says whether the module
    /// confirmed that.
    #[error("while module {address} may have been moving: {cause}; {stop}")]
    FailedDuringMotion {
        /// The module.
        address: Address,
        /// What failed.
        cause: Box<Error>,
        /// What became of the Halt.
        stop: StopOutcome,
    },
    /// A value outside one of the module's limits: refused before anything was sent that moves (the module
    /// would have limited it silently).
    #[error("{}", beyond_limit_text(*address, what, *value, *limit, *limit_value, unit, *other_limit))]
    OutsideLimits {
        /// The module.
        address: Address,
        /// What the value is ("target position", "--vel", "TargetVel").
        what: String,
        /// The value asked for.
        value: f64,
        /// The limit parameter (MinPos, MaxPos, MaxVel, MaxAcc, MaxCur ...).
        limit: Param,
        /// Its value in the module.
        limit_value: f64,
        /// The unit of the value and the limit ("rad", "m/s", "A"; "" where the module's kind was not known).
        unit: &'static str,
        /// The other end of a range (MaxPos when MinPos was passed, and the other way round), as read from
        /// the module, so that the message gives the whole range.
        other_limit: Option<(Param, f64)>,
    },
    /// A parameter read back after it was written differs from what was written: the module limited it, or
    /// the write was corrupted on the way (the modules ignore the checksum).
    #[error(
        "module {address}: {param} was written as {} but reads back as {} (the module limited it, or the write \
         was corrupted on the way)",
        read_back_side(wrote, twin.as_ref().map(|t| (t.expected_ticks, None))),
        read_back_side(read, twin.as_ref().map(|t| (t.read_ticks, Some(t.param))))
    )]
    ReadBack {
        /// The module.
        address: Address,
        /// The parameter written.
        param: Param,
        /// What was written.
        wrote: Value,
        /// What the module holds: `param` read back, or, read back through its tick twin (`twin`), what the
        /// twin's ticks amount to in `param`'s unit.
        read: Value,
        /// For a parameter read back through its tick twin (TargetVel through TargetVelInc): the ticks.
        twin: Option<TwinTicks>,
    },
    /// After the motion command, the module's target (TargetPosInc) is not the target sent: the command
    /// was corrupted on the way; the motion was halted.
    #[error("module {address}: the motion command was sent with target {sent} ticks but the module took {taken} ticks (a corrupted command); {stop}")]
    TargetMismatch {
        /// The module.
        address: Address,
        /// The target sent, in encoder ticks.
        sent: i32,
        /// The target the module holds.
        taken: i32,
        /// What became of the Halt.
        stop: StopOutcome,
    },
    /// The motion ended, but not where it was asked to: the final position read from the module is further
    /// from the target than the in-position tolerance.
    #[error("module {address}: target {} not reached: the module stands at {reached}, {:.6} away (tolerance {tolerance}; state: {state})", .target.value(), .difference.value())]
    NotReached {
        /// The module.
        address: Address,
        /// The target, in the unit of `reached`.
        target: Position,
        /// The final actual position read from the module (in rad or m: a move reads the module's kind).
        reached: Position,
        /// `reached - target`, in the unit of `reached`.
        difference: Position,
        /// The tolerance allowed, in the unit of `reached`.
        tolerance: Position,
        /// The state word at the end.
        state: CubeState,
    },
    /// The module would not carry out the motion command as sent, by its Config word and state (see
    /// `why`): nothing was sent.
    #[error("module {address} takes no motion command of this move: {why}")]
    NotReady {
        /// The module.
        address: Address,
        /// Why, naming the flag.
        why: &'static str,
    },
    /// A value given to an action that makes no sense (not a finite number, not above 0): nothing was sent.
    #[error("{what} must be {must}, not {value}")]
    InvalidArgument {
        /// The argument.
        what: &'static str,
        /// What it must be.
        must: &'static str,
        /// What it was.
        value: String,
    },
    /// A request the manual does not allow (access, type): nothing was sent.
    #[error(transparent)]
    Model(#[from] ModelError),
    /// An address outside 1..31.
    #[error("module address {0} is outside 1..31")]
    InvalidAddress(u8),
    /// Something this client does not do.
    #[error("{0}")]
    NotSupported(String),
    /// The session failed with the watchdog of these modules online: it was left online (its refresh
    /// stopped), so they halt within 50 ms with STATE_COMM_ERROR; `reset_and_release_watchdog` (the `reset`
    /// command) clears them afterwards.
    #[error("the watchdog of module {} is left online: {detail}; the module halts within 50 ms of the last refresh (STATE_COMM_ERROR; `reset` clears it)", addresses.iter().map(Address::to_string).collect::<Vec<_>>().join(", "))]
    WatchdogLeftOnline {
        /// The modules.
        addresses: Vec<Address>,
        /// Why.
        detail: String,
    },
    /// A watchdog toggle (the life sign, chapter 13) was not confirmed: whether the module's watchdog is
    /// online is not known. No second life sign is sent blindly (it could switch the watchdog the wrong way).
    #[error("module {address}: watchdog not confirmed {}: {detail}", if *on { "online" } else { "offline" })]
    WatchdogUnconfirmed {
        /// The module.
        address: Address,
        /// True when switching on, false when switching off.
        on: bool,
        /// What was seen.
        detail: String,
    },
    /// A quantity in a unit that does not fit the module: a position in rad for a linear module, in m for a
    /// rotary one. Nothing was sent.
    #[error("module {address} is {} (its unit is {}): {what} {value} does not fit it", kind.name(), kind.unit())]
    UnitMismatch {
        /// The module.
        address: Address,
        /// What the module is.
        kind: ModuleKind,
        /// What the quantity is ("the target position", "the velocity").
        what: &'static str,
        /// The quantity, with its unit.
        value: Quantity,
    },
    /// An error with what was being done when it happened (and, after it, a hint).
    #[error("{context}: {source}{hint}")]
    Context {
        /// What was being done.
        context: String,
        /// What went wrong.
        source: Box<Error>,
        /// What to do about it ("" for nothing).
        hint: &'static str,
    },
    /// An error, and one that followed while cleaning up after it (both are told; the first decides the
    /// class).
    #[error("{error}; afterwards: {also}")]
    Also {
        /// The error.
        error: Box<Error>,
        /// What went wrong while cleaning up after it.
        also: Box<Error>,
    },
    /// Modules this session set in motion could not be confirmed stopped (`stop_started`, and after a
    /// motion the guard ended): no Halt by address was acknowledged, a Halt was broadcast. The end of a
    /// session says the same as [`Error::CloseUnconfirmed`].
    #[error("{}", unconfirmed_text(addresses, detail, *watchdog_armed))]
    StopUnconfirmed {
        /// The modules.
        addresses: Vec<Address>,
        /// Why.
        detail: String,
        /// A watchdog this session switched on is left online (no longer refreshed).
        watchdog_armed: bool,
    },
    /// The end of the session could not confirm the stop of modules it had set in motion: no Halt by
    /// address was acknowledged, a Halt was broadcast and the watchdog refresh stopped (as SCU's and
    /// COMPAX's `CloseUnconfirmed`).
    #[error("closing the session: {}", unconfirmed_text(addresses, detail, *watchdog_armed))]
    CloseUnconfirmed {
        /// The modules.
        addresses: Vec<Address>,
        /// Why.
        detail: String,
        /// A watchdog this session switched on is left online (no longer refreshed).
        watchdog_armed: bool,
    },
    /// The session's close sequence (stop what was started, switch the watchdogs off) did not end within
    /// its bound: what was started may not have been confirmed stopped; the watchdog refresh has stopped.
    #[error("the session did not confirm within {} ms that what it started is stopped: the axis may still be moving{}", bound.as_millis(), watchdogs_left(.armed.as_deref()))]
    CloseTimedOut {
        /// The bound waited.
        bound: Duration,
        /// The modules whose watchdog the session had switched on (or may have) when it gave up: their
        /// refresh has stopped, so they halt themselves within 50 ms. Empty: no watchdog was armed, nothing
        /// but a halt or the emergency stop stops a module still moving. `None`: not known where the error
        /// was made (the driver's drop); [`Client::close`](crate::Client::close) always says.
        armed: Option<Vec<Address>>,
    },
    /// A Halt (the `stop` of a module: [`Module::halt_confirmed`](crate::client::Module::halt_confirmed))
    /// was sent `sent` times and none was acknowledged: the axis may still be moving.
    #[error("module {address}: Halt not acknowledged ({sent} sent): {cause}; the axis may still be moving")]
    HaltUnacknowledged {
        /// The module.
        address: Address,
        /// How many Halts were sent.
        sent: u32,
        /// The last one's error.
        cause: Box<Error>,
    },
    /// The session is closed (or closing): nothing more is sent.
    #[error("the session is closed")]
    Closed,
    /// A request that cannot be framed (nothing was sent).
    #[error("cannot frame the request: {0}")]
    Encode(#[from] Rs232Error),
    /// An operation that sets nothing in motion was cancelled before its end.
    #[error("{what} cancelled (nothing had been set in motion)")]
    CancelledBeforeMotion {
        /// What was cancelled.
        what: &'static str,
    },
}

/// A parameter read back through its tick twin ([`Error::ReadBack::twin`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TwinTicks {
    /// The twin read (TargetVelInc for TargetVel).
    pub param: Param,
    /// The ticks the value written amounts to.
    pub expected_ticks: f64,
    /// The ticks the twin shows.
    pub read_ticks: f64,
}

/// One side of a read-back message: a float with six decimals, a large word in hex, with its ticks (and the
/// twin that shows them) where it was read back through a twin.
fn read_back_side(v: &Value, ticks: Option<(f64, Option<Param>)>) -> String {
    let shown = match *v {
        Value::F32(x) => format!("{x:.6}"),
        Value::U32(x) if x > 0xFFFF => format!("{x:#010x}"),
        other => other.as_f64().map_or_else(|| format!("{other:?}"), |n| format!("{n}")),
    };
    match ticks {
        None => shown,
        Some((ticks, None)) => format!("{shown} ({ticks} ticks)"),
        Some((ticks, Some(twin))) => format!("{shown} ({ticks} ticks in {twin})"),
    }
}

/// A number for messages: a value that came from a float parameter is shown as that float (0.05, not
/// 0.05000000074505806).
fn number(x: f64) -> String {
    let single = x as f32;
    if f64::from(single) == x {
        single.to_string()
    } else {
        x.to_string()
    }
}

fn fault_names(state: CubeState) -> String {
    let names: Vec<String> = state.faults().map(|f| f.label()).collect();
    if names.is_empty() {
        state.to_string()
    } else {
        names.join(" | ")
    }
}

impl Classify for Error {
    fn class(&self) -> ErrorClass {
        match self {
            Error::Link(e) => e.class(),
            Error::Timeout { .. } | Error::CloseTimedOut { .. } => ErrorClass::Transport(TransportKind::Timeout),
            Error::Corrupt { .. } => ErrorClass::Transport(TransportKind::Corrupt),
            // A motion that may still run after the line failed: a transport error of the cause's kind; a
            // halt not confirmed after another failure: a timeout, as in every family. A confirmed halt
            // leaves the class of what went wrong.
            Error::FailedDuringMotion { cause, stop, .. } => match stop {
                StopOutcome::Unconfirmed { .. } => cause.class().stop_unconfirmed(),
                _ => cause.class(),
            },
            // A halt not confirmed at rest (still moving after it was acknowledged, as the SCU's status after
            // an RS): a timeout, as every stop not confirmed.
            Error::StopUnconfirmed { .. } | Error::CloseUnconfirmed { .. } | Error::StillMoving { .. } => {
                ErrorClass::Transport(TransportKind::Timeout)
            }
            Error::HaltUnacknowledged { cause, .. } => cause.class().stop_unconfirmed(),
            Error::Refused { .. } => ErrorClass::Refused,
            Error::Device { .. }
            | Error::WatchdogExpired { .. }
            | Error::Halted { .. }
            | Error::MoveTimeout { .. }
            | Error::WatchdogUnconfirmed { .. }
            | Error::WatchdogLeftOnline { .. }
            | Error::ReadBack { .. }
            | Error::TargetMismatch { .. }
            | Error::NotReady { .. }
            | Error::NotReached { .. } => ErrorClass::Device,
            // A cancel is of class Cancelled only once the module confirmed the halt (the class promises that
            // what was started was stopped); one whose halt was not acknowledged is the line's failure.
            Error::Cancelled { stop: StopOutcome::Unconfirmed { .. }, .. } => ErrorClass::Cancelled.stop_unconfirmed(),
            Error::Cancelled { .. } | Error::CancelledBeforeMotion { .. } => ErrorClass::Cancelled,
            Error::Model(_)
            | Error::InvalidAddress(_)
            | Error::NotSupported(_)
            | Error::OutsideLimits { .. }
            | Error::InvalidArgument { .. }
            | Error::UnitMismatch { .. }
            | Error::Encode(_)
            | Error::Closed => ErrorClass::Usage,
            Error::Context { source, .. } => source.class(),
            // A stop not confirmed while cleaning up makes it one of the line, as every such error.
            Error::Also { error, also } if also.stop_unconfirmed() => error.class().stop_unconfirmed(),
            Error::Also { error, .. } => error.class(),
        }
    }

    /// A Halt the session needed was not acknowledged, or the end of the session could not confirm its
    /// stop: the axis may be moving.
    fn stop_unconfirmed(&self) -> bool {
        match self {
            Error::FailedDuringMotion { stop, .. } | Error::Cancelled { stop, .. } => !stop.is_confirmed(),
            Error::StopUnconfirmed { .. }
            | Error::CloseUnconfirmed { .. }
            | Error::CloseTimedOut { .. }
            | Error::HaltUnacknowledged { .. }
            | Error::StillMoving { .. } => true,
            Error::Context { source, .. } => source.stop_unconfirmed(),
            Error::Also { error, also } => error.stop_unconfirmed() || also.stop_unconfirmed(),
            _ => false,
        }
    }

    /// The module's state word (CubeState) with its flags set, numbered from bit 0, where the error carries
    /// it (also as the cause of another).
    fn reported(&self) -> Option<DeviceCode> {
        match self {
            Error::Device { state, .. }
            | Error::Halted { state, .. }
            | Error::MoveTimeout { state, .. }
            | Error::NotReached { state, .. }
            | Error::WatchdogExpired { state, .. } => Some(DeviceCode::of_word(*state)),
            Error::Context { source, .. } | Error::FailedDuringMotion { cause: source, .. } => source.reported(),
            Error::Also { error, .. } => error.reported(),
            _ => None,
        }
    }
}

impl SessionError for Error {
    fn close_timed_out(bound: Duration) -> Self {
        Error::CloseTimedOut { bound, armed: None }
    }

    fn session_closed() -> Self {
        Error::Closed
    }
}

impl From<InvalidAddress> for Error {
    fn from(e: InvalidAddress) -> Self {
        Error::InvalidAddress(e.0)
    }
}

impl Error {
    /// The line failed: port, timeout, corrupt answer, a motion lost with its line ([`ErrorClass::Transport`]).
    pub fn is_transport(&self) -> bool {
        self.class().is_transport()
    }

    /// The module refused or reported an error, or an action did not complete as asked
    /// ([`ErrorClass::Device`], [`ErrorClass::Refused`]).
    pub fn is_device(&self) -> bool {
        matches!(self.class(), ErrorClass::Device | ErrorClass::Refused)
    }

    /// The request was wrong before anything was sent ([`ErrorClass::Usage`]).
    pub fn is_usage(&self) -> bool {
        self.class() == ErrorClass::Usage
    }

    /// What became of the stop of a motion this error interrupted, if it interrupted one.
    pub fn stop(&self) -> Option<&StopOutcome> {
        match self {
            Error::MoveTimeout { stop, .. }
            | Error::Cancelled { stop, .. }
            | Error::FailedDuringMotion { stop, .. }
            | Error::TargetMismatch { stop, .. } => Some(stop),
            Error::Context { source, .. } => source.stop(),
            Error::Also { error, .. } => error.stop(),
            _ => None,
        }
    }

    /// A read that failed this way may be asked again.
    pub(crate) fn retryable(&self) -> bool {
        matches!(self, Error::Timeout { .. } | Error::Corrupt { .. })
    }
}

/// What [`Error::CloseTimedOut`] says about the watchdogs: only what the session knew.
fn watchdogs_left(armed: Option<&[Address]>) -> String {
    match armed {
        None => "; if this session armed a module's watchdog, its refresh has stopped and that module halts \
                 itself within 50 ms"
            .into(),
        Some([]) => "; no watchdog was armed by this session: only a halt or the emergency stop stops it now".into(),
        Some([a]) => format!(
            "; the watchdog of module {a} is armed and no longer refreshed: the module halts itself within 50 ms"
        ),
        Some(many) => format!(
            "; the watchdogs of modules {} are armed and no longer refreshed: those modules halt themselves \
             within 50 ms",
            list(many)
        ),
    }
}

/// "module 1 set in motion by this session could not be confirmed stopped (why): the axis may still be
/// moving", and what its watchdog does where the session had armed it.
fn unconfirmed_text(addresses: &[Address], detail: &str, watchdog_armed: bool) -> String {
    let watchdog = match watchdog_armed {
        true => {
            "; its watchdog is online and no longer refreshed, so the module halts itself within 50 ms of the \
                 last refresh that reached it"
        }
        false => "",
    };
    format!(
        "module {} set in motion by this session could not be confirmed stopped ({detail}): the axis may still be \
         moving{watchdog}",
        list(addresses)
    )
}

fn list(addresses: &[Address]) -> String {
    addresses.iter().map(Address::to_string).collect::<Vec<_>>().join(", ")
}

/// An answer that decoded but is not what `request` asks for (a value of another type, another reply).
pub(crate) fn unexpected(address: u8, request: &Request, what: impl fmt::Display) -> Error {
    Error::Corrupt {
        address: Address::checked(address),
        request: *request,
        detail: format!("unexpected answer {what}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_error_has_the_class_its_exit_code_needs() {
        let timeout = || Error::Timeout {
            address: Address::checked(1),
            request: Request::Get(crate::model::Param::ActPos),
            waited: Duration::from_millis(1),
            round_trips: None,
        };
        assert_eq!(timeout().class(), ErrorClass::Transport(TransportKind::Timeout));
        assert_eq!(Error::Encode(Rs232Error::BadAddress(40)).class().exit_code(), 2, "a framing error is usage");
        assert_eq!(Error::InvalidAddress(0).class(), ErrorClass::Usage);
        assert_eq!(
            Error::Cancelled { address: Address::checked(1), stop: StopOutcome::Confirmed }.class(),
            ErrorClass::Cancelled
        );
        // A cancel whose halt was not acknowledged is no clean cancel (exit 130 promises the stop).
        let unconfirmed = StopOutcome::Unconfirmed { reason: "no answer".into(), watchdog_armed: true };
        assert_eq!(
            Error::Cancelled { address: Address::checked(1), stop: unconfirmed }.class(),
            ErrorClass::Transport(TransportKind::Timeout)
        );
        let lost = Error::FailedDuringMotion {
            address: Address::checked(1),
            cause: Box::new(timeout()),
            stop: StopOutcome::Confirmed,
        };
        assert_eq!(lost.class(), ErrorClass::Transport(TransportKind::Timeout));
        // Another failure during a motion: its class once the halt was confirmed, a timeout (exit 3) if not.
        let halted = || Box::new(Error::Halted { address: Address::checked(1), state: CubeState(4) });
        let settled =
            Error::FailedDuringMotion { address: Address::checked(1), cause: halted(), stop: StopOutcome::Confirmed };
        assert_eq!(settled.class(), ErrorClass::Device);
        let open = StopOutcome::Unconfirmed { reason: "no answer".into(), watchdog_armed: false };
        let unsettled = Error::FailedDuringMotion { address: Address::checked(1), cause: halted(), stop: open };
        assert_eq!(unsettled.class(), ErrorClass::Transport(TransportKind::Timeout));
        // Flagged as a stop not confirmed where the halt was not, also inside a context; not otherwise.
        assert!(unsettled.stop_unconfirmed() && !settled.stop_unconfirmed() && !lost.stop_unconfirmed());
        let wrapped = Error::Context { context: "moving".into(), source: Box::new(unsettled), hint: "" };
        assert!(wrapped.stop_unconfirmed(), "{wrapped}");
        assert!(Error::close_timed_out(Duration::from_secs(5)).stop_unconfirmed());
        // A motion's device error, then a stop after it not confirmed: flagged, and of the line (exit 3).
        let halted = Error::Halted { address: Address::checked(1), state: CubeState(4) };
        let stop =
            Error::StopUnconfirmed { addresses: vec![Address::checked(1)], detail: "x".into(), watchdog_armed: false };
        let also = Error::Also { error: Box::new(halted), also: Box::new(stop) };
        assert!(also.stop_unconfirmed() && also.class() == ErrorClass::Transport(TransportKind::Timeout), "{also}");
        // Acknowledged, but still moving: not confirmed either, a timeout as the SCU's stop says it.
        let moving = Error::StillMoving { address: Address::checked(1), state: CubeState(0), waited: Duration::ZERO };
        assert!(moving.stop_unconfirmed() && moving.class() == ErrorClass::Transport(TransportKind::Timeout));
        let link = LinkError::Disconnected { port: "p".into(), reason: "r".into() };
        assert_eq!(Error::Link(link).class(), ErrorClass::Transport(TransportKind::Disconnected));
        let ctx = Error::Context {
            context: "arming".into(),
            source: Box::new(Error::Halted { address: Address::checked(1), state: CubeState(4) }),
            hint: "",
        };
        assert_eq!(ctx.class(), ErrorClass::Device);
        // What the module reported comes through the context: its state word, STATE_HALTED as bit 2.
        let reported = ctx.reported().expect("the state word");
        assert_eq!((reported.code, reported.bits.len(), reported.bits[0].bit), (4, 1, 2), "{reported:?}");
        assert_eq!(reported.bits[0].name, "STATE_HALTED");
        assert_eq!(timeout().reported(), None);
        assert_eq!(Error::Closed.class(), ErrorClass::Usage);
        assert_eq!(Error::close_timed_out(Duration::from_secs(5)).class().exit_code(), 3);
        let unit = Error::UnitMismatch {
            address: Address::checked(3),
            kind: ModuleKind::Linear,
            what: "the target position",
            value: Quantity::Position(Position::rad(0.5)),
        };
        assert_eq!(unit.class(), ErrorClass::Usage);
        assert_eq!(unit.to_string(), "module 3 is linear (its unit is m): the target position 0.5 rad does not fit it");
        // A slow link is named where the session measured it.
        let ms = Duration::from_millis;
        let slow = Error::Timeout {
            address: Address::checked(2),
            request: Request::Get(crate::model::Param::ActPos),
            waited: ms(60),
            round_trips: Some(RoundTripRange { fastest: ms(45), slowest: ms(58) }),
        };
        assert_eq!(
            slow.to_string(),
            "module 2 did not answer GetExtended ActPos within 60 ms; replies on this link have taken 45-58 ms"
        );
        assert!(!timeout().to_string().contains("replies"), "nothing measured, nothing said");
    }
}
