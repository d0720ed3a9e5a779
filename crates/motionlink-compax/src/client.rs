//! A blocking client for a bus of COMPAX drives over any byte [`Link`]: an RS485 adapter, RS232, a TCP
//! serial gateway, a pseudo-terminal, or an in-process emulator.
//!
//! The protocol needs no background traffic (no watchdog, no keepalive), so the client owns no thread: every
//! call sends, waits through the [`Clock`](motionlink_link::Clock) of the session, and returns. Unsolicited
//! messages (the `$` position-reached message, comparator numbers) are collected whenever the client reads.
//!
//! Safety: a drive the client set in motion is remembered until the client has seen it stop. Dropping the
//! [`Bus`], cancelling a wait through its [`CancelToken`], or a failure during a wait or a checked move
//! stops every such axis that still moves with `OUTPUT O0=0` ("switch off drive", the one documented
//! command that ends a running positioning; every move command is refused with E92 while the axis moves):
//! the client reads the drive's S17 first and switches it off only if "command active" is set, or if S17
//! cannot be read (on a failing line the stop is sent anyway), then reads S17 again to confirm the axis is
//! at rest. The error says per drive whether the drive confirmed the stop ([`Error::Aborted`],
//! [`StopReport`]); if not, that the axis may still be moving. A drive switched off this way takes no move
//! until `OUTPUT O0=1` switches it on again; a checked move to it says so ([`Error::SwitchedOff`]). The stop
//! is addressed to each drive, not broadcast: other drives on the bus may be someone else's. Moves sent
//! with [`Bus::raw`] or [`Bus::broadcast`] count too (a broadcast move counts for every drive that has
//! answered this client). [`Bus::release`] hands a running move over to the caller: the client forgets it
//! and does not stop it.
//!
//! What the drives do not do: COMPAX has no host watchdog. A host that dies (killed, crashed, unplugged)
//! leaves a running positioning running to its target; nothing on the link stops it. P196's "timeout
//! supervision" (valence 16) only discards a telegram that stalls for five character times (E73); it never
//! stops an axis.
//!
//! Success means the drive did it: [`Bus::move_to`] reads the target back (S2) right after the move and
//! the actual position (S1) at rest, and fails unless the axis came to rest within
//! [`BusConfig::in_position_tolerance`] of its target; [`Bus::write_param`] reads the value back.
//!
//! Retries: E70, E72 and E73 mean the drive discarded the telegram; the client sends it again (up to
//! [`BusConfig::retries`] times). E71 (more than 40 characters) is reported: the same telegram would overflow
//! again, and the manual's measure is to send fewer characters. A timeout or a corrupt reply is retried only
//! for idempotent commands. A move whose reply was lost is never sent again blind: the client reads the
//! target position S2 to find out whether the drive took it (see [`Bus::move_relative`]).
//!
//! Address 32 reaches every drive and none answers it: reads, echoes, moves to one drive and waits refuse it
//! with [`Error::Broadcast`]; settings, outputs, [`Bus::stop`], [`Bus::raw`] and [`Bus::broadcast`] send it.
//! A [`Drive`] is a handle on one drive (1..=31) of a bus.
//!
//! ```
//! use motionlink_compax::client::{Bus, BusConfig, MoveOptions};
//! use motionlink_compax::model::Position;
//! use motionlink_compax::sim::{CompaxBus, SimConfig};
//! use motionlink_compax::wire::{Address, Mode};
//! use motionlink_link::{clock::{Clock, ManualClock}, pipe::{EmulatorHost, PipeConfig}};
//!
//! let clock = ManualClock::new_auto();
//! let _me = clock.reserve_participant().enter();
//! let host = EmulatorHost::new(CompaxBus::new(SimConfig::bus(&[1, 5], 0, 9600)).unwrap(),
//!                              clock.shared(), PipeConfig::paced(9600));
//! let (link, _faults) = host.connect();
//! let mut bus = Bus::new(Box::new(link), clock.shared(), BusConfig::new(Mode::default(), 9600));
//! let five = Address::drive(5).unwrap();
//! bus.move_absolute(five, Position::new(25.0).unwrap(), MoveOptions::default()).unwrap();
//! bus.wait_reached(&[five], None, &mut |_, _| {}).unwrap();
//! assert_eq!(bus.read_position(five).unwrap().units(), 25.0);
//! ```

use std::fmt;
use std::time::Duration;

use motionlink_link::cancel::CancelToken;
use motionlink_link::clock::{SharedClock, Timestamp};
use motionlink_link::link::{char_time, Link, LinkError};

use crate::model::{
    parse_param_reply, Command, CommandStyle, ErrorCode, ModelError, OutputState, ParamId, Position, RampMs, S16Bits,
    S17Bits, SpeedPercent, StatusId, StatusValue,
};
use crate::wire::reply::ReplyError;
use crate::wire::{
    Address, Body, EscapedBytes, Flags, Mode, Reply, ReplyDecoder, ReplyEvent, ReplyKind, Request, WireError, BROADCAST,
};

/// The default of [`BusConfig::in_position_tolerance`], in the drive's position unit.
pub const DEFAULT_IN_POSITION_TOLERANCE: f64 = 0.01;

/// While a wait listens (between polls, or for `$` messages), how often it looks at the cancel token: a
/// cancelled wait stops the axes within this time plus two exchanges.
const CANCEL_CHECK: Duration = Duration::from_millis(5);

/// How the client talks to the bus.
#[derive(Debug, Clone, PartialEq)]
pub struct BusConfig {
    /// P196 of the drives (they must all have the same).
    pub mode: Mode,
    /// P195 of the drives, bit/s (it sets the wire time the timeouts allow for).
    pub baud_rate: u32,
    /// Time a drive may take to start answering, on top of the wire time of request and reply. The manual
    /// gives none; 200 ms by default.
    pub reply_timeout: Duration,
    /// How often a telegram is sent again after E70, E72, E73, a timeout or a corrupt reply (idempotent
    /// commands).
    pub retries: u32,
    /// Silence after a broadcast before the next telegram (nobody answers a broadcast); 20 ms by default.
    pub broadcast_gap: Duration,
    /// Interval of status polls while waiting for a position (S17, and S1 for progress): a poll starts
    /// every `poll_interval`, counted from the start of the previous one (when a poll takes longer than
    /// that, as at 9600 baud with a short interval, the next one starts at once, never several to catch
    /// up). 50 ms by default: at 9600 baud the two reads of one poll take about 40 ms of line time.
    pub poll_interval: Duration,
    /// While a wait listens for `$` messages, how often it still reads each drive's state (a `$` may be lost
    /// to a line error, or the axis stopped by someone else, and then none comes); 1 s by default.
    pub message_check_interval: Duration,
    /// How long [`Bus::wait_reached`] waits when it is given no timeout; 600 s by default.
    pub wait_timeout: Duration,
    /// Long or short command names.
    pub style: CommandStyle,
    /// How far from its target (in the drive's position unit) an axis may come to rest for a move to count
    /// as done ([`Bus::move_to`]), and how far the target a drive reports (S2) may be from the one sent.
    /// The manuals give no position window for the ASCII protocol; 0.01 by default (the user guide gives
    /// positions two decimals in mm).
    pub in_position_tolerance: f64,
}

impl BusConfig {
    /// Defaults for drives with mode `mode` at `baud_rate`.
    pub fn new(mode: Mode, baud_rate: u32) -> Self {
        BusConfig {
            mode,
            baud_rate,
            reply_timeout: Duration::from_millis(200),
            retries: 3,
            broadcast_gap: Duration::from_millis(20),
            poll_interval: Duration::from_millis(50),
            message_check_interval: Duration::from_secs(1),
            wait_timeout: Duration::from_secs(600),
            style: CommandStyle::Long,
            in_position_tolerance: DEFAULT_IN_POSITION_TOLERANCE,
        }
    }

    fn char_time(&self) -> Duration {
        char_time(self.baud_rate, self.mode.parity)
    }
}

/// An error of a client call.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The drive answered with an error message.
    #[error("drive {address}: {command:?} refused with {code}")]
    Device {
        /// The drive.
        address: u8,
        /// The command sent.
        command: String,
        /// The error.
        code: ErrorCode,
    },
    /// No reply in time, after every retry.
    #[error("drive {address}: no reply to {command:?} ({attempts} attempts)")]
    Timeout {
        /// The drive.
        address: u8,
        /// The command sent.
        command: String,
        /// Telegrams sent.
        attempts: u32,
    },
    /// Replies arrived corrupt (BCC, framing), after every retry.
    #[error("drive {address}: corrupt reply to {command:?}: {detail}")]
    Corrupt {
        /// The drive.
        address: u8,
        /// The command sent.
        command: String,
        /// The last corruption seen.
        detail: ReplyError,
    },
    /// A reply the client cannot read.
    #[error("drive {address}: unexpected reply {reply:?} to {command:?}")]
    Unexpected {
        /// The drive.
        address: u8,
        /// The command sent.
        command: String,
        /// The reply text.
        reply: String,
    },
    /// The port failed.
    #[error(transparent)]
    Link(#[from] LinkError),
    /// An argument out of range.
    #[error(transparent)]
    Invalid(#[from] ModelError),
    /// A telegram that cannot be built.
    #[error(transparent)]
    Wire(#[from] WireError),
    /// A move's reply was lost and the drive's state does not tell whether it took the move.
    #[error("drive {address}: the reply to {command:?} was lost and the drive's target ({target}) does not tell whether it was executed")]
    MoveUncertain {
        /// The drive.
        address: u8,
        /// The command sent.
        command: String,
        /// The target position S2 read afterwards.
        target: f64,
    },
    /// A wait for a position did not end in time; the axes were stopped.
    #[error("drive {address} did not reach its position within {after:?}; stopped")]
    MoveTimeout {
        /// The drive.
        address: u8,
        /// The time waited.
        after: Duration,
    },
    /// The action was cancelled through the [`CancelToken`] (Ctrl-C): no move is sent once it is. A
    /// cancelled wait or move returns it inside [`Error::Aborted`], which says how the axes were stopped.
    #[error("cancelled: no further motion is sent")]
    Cancelled,
    /// An action failed, or was cancelled, while axes this client set in motion may have been moving: the
    /// client tried to stop them, and `stop` says for each drive whether the drive confirmed it (and, if
    /// not, that the axis may still be moving).
    #[error("{cause}; {stop}")]
    Aborted {
        /// What went wrong.
        cause: Box<Error>,
        /// What the client did to stop the axes, drive by drive.
        stop: StopReport,
    },
    /// A move ended with the axis at rest away from its target.
    #[error(
        "drive {address} did not reach its target: target {target}, reached {reached}, difference {difference:.3} \
         (in-position tolerance {tolerance})"
    )]
    NotReached {
        /// The drive.
        address: u8,
        /// The target asked for.
        target: f64,
        /// The actual position S1 read at rest.
        reached: f64,
        /// `reached - target`.
        difference: f64,
        /// [`BusConfig::in_position_tolerance`].
        tolerance: f64,
    },
    /// The target a drive reports (S2, read twice after the move was sent) is not the one sent: a telegram
    /// was corrupted on the way (without a BCC a flipped bit in a digit is still a valid command). Returned
    /// inside [`Error::Aborted`]: the client stops the axis at once.
    #[error(
        "drive {address} took target {taken} instead of {requested} (its S2 after the move; a corrupted telegram?)"
    )]
    TargetMismatch {
        /// The drive.
        address: u8,
        /// The target sent.
        requested: f64,
        /// The target S2 read back.
        taken: f64,
    },
    /// A target outside the travel limits the caller gave ([`TravelLimits`]); nothing was sent to move.
    #[error("drive {address}: target {target} is outside the travel limits: it is {side} {limit}")]
    OutsideLimits {
        /// The drive.
        address: u8,
        /// The target.
        target: f64,
        /// "below the minimum" or "above the maximum".
        side: &'static str,
        /// The limit crossed.
        limit: f64,
    },
    /// The drive is switched off (`OUTPUT O0=0`, S16 bits 7 and 8): it takes no move until it is switched on
    /// again with `OUTPUT O0=1`. `refused` is the code it answered a move with, if one was sent.
    #[error("drive {address} is switched off (O0={o0}, S16){}: it moves only once it is switched on again with OUTPUT O0=1", refused.map(|c| format!(" and refused the move with {c}")).unwrap_or_default())]
    SwitchedOff {
        /// The drive.
        address: u8,
        /// The O0 state S16 shows (0, or 2).
        o0: u8,
        /// The drive's answer to the move, when the move was sent.
        refused: Option<ErrorCode>,
    },
    /// A parameter written reads back another value.
    #[error(
        "drive {address}: {param} reads back {read} after {wrote} was written: the drive did not store the value \
         (without a BCC a corrupted telegram may even have written another parameter; P196 valence 8 adds one)"
    )]
    ReadBack {
        /// The drive.
        address: u8,
        /// The parameter.
        param: ParamId,
        /// The value written.
        wrote: f64,
        /// The value read back.
        read: f64,
    },
    /// [`Bus::sync_start`] could not store every move, and sent no `!`. The drives in `buffered` acknowledged
    /// storing theirs (and the failed drive may have stored its own if its reply was lost): the manual has
    /// no command that empties a drive's buffer, so the next `!` to such a drive, or any `32!` on the bus,
    /// starts that move. The client counts them as started once it sends such a `!` itself.
    #[error("drive {failed}: storing the synchronous move failed ({source}); no '!' was sent, but drives {buffered:?} still hold a buffered move that the next '!' to them or '32!' starts (the manual has no command to empty a buffer)")]
    SyncIncomplete {
        /// The drive whose move could not be stored.
        failed: u8,
        /// Why.
        source: Box<Error>,
        /// Drives that hold a buffered move from this call (ascending), the failed one included when its
        /// reply was lost.
        buffered: Vec<u8>,
    },
    /// Address 32 where one drive's answer or one drive is needed: every drive executes a broadcast and none
    /// answers it.
    #[error("address 32 is the broadcast: every drive executes it and none answers; {0}")]
    Broadcast(&'static str),
}

impl Error {
    /// True for errors of the line (timeout, corrupt reply, port), as opposed to the drive's answers (for
    /// [`Error::Aborted`]: of its cause).
    pub fn is_transport(&self) -> bool {
        matches!(self.root(), Error::Timeout { .. } | Error::Corrupt { .. } | Error::Link(_) | Error::Unexpected { .. })
    }

    /// The drive's error code, if the drive refused (for [`Error::Aborted`]: in its cause).
    pub fn device_code(&self) -> Option<ErrorCode> {
        match self.root() {
            Error::Device { code, .. } => Some(*code),
            Error::SwitchedOff { refused, .. } => *refused,
            _ => None,
        }
    }

    /// What went wrong in the first place: the cause of an [`Error::Aborted`], or the error itself.
    pub fn root(&self) -> &Error {
        match self {
            Error::Aborted { cause, .. } => cause.root(),
            other => other,
        }
    }

    /// What the client did to stop the axes, when the error ended an action that may have left them
    /// moving ([`Error::Aborted`]).
    pub fn stop_report(&self) -> Option<&StopReport> {
        match self {
            Error::Aborted { stop, .. } => Some(stop),
            _ => None,
        }
    }
}

/// How stopping one drive ended.
#[derive(Debug, Clone, PartialEq, Eq)]
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

/// What [`Bus::stop_started`] did, drive by drive.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct StopReport {
    /// Each drive the client had set in motion, and how stopping it ended.
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

    /// The drives whose stop was not confirmed (they may still be moving).
    pub fn unconfirmed(&self) -> Vec<Address> {
        self.drives.iter().filter(|(_, o)| matches!(o, StopOutcome::NotConfirmed { .. })).map(|(a, _)| *a).collect()
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
                StopOutcome::AtRest => write!(f, "drive {a} was already at rest (left switched on)")?,
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

/// Where a move goes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MoveTarget {
    /// To this position (POSA).
    Absolute(Position),
    /// By this distance from the drive's current target S2 (POSR).
    Relative(Position),
}

/// Travel limits the caller knows for an axis (the drive's own limits are not in the RS485 manual, and
/// the client does not read them): a target outside them is refused before anything moves.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TravelLimits {
    /// The lowest target allowed.
    pub min: Option<Position>,
    /// The highest target allowed.
    pub max: Option<Position>,
}

impl TravelLimits {
    /// Limits; refused when `min` is above `max`.
    pub fn new(min: Option<Position>, max: Option<Position>) -> Result<Self, ModelError> {
        if let (Some(lo), Some(hi)) = (min, max) {
            if lo.units() > hi.units() {
                return Err(ModelError::Range {
                    what: "travel limits",
                    value: format!("minimum {lo} above maximum {hi}"),
                    range: "minimum at most the maximum",
                });
            }
        }
        Ok(TravelLimits { min, max })
    }

    fn check(&self, address: Address, target: Position) -> Result<()> {
        let t = target.units();
        let outside = |side, limit: Position| Error::OutsideLimits {
            address: address.get(),
            target: t,
            side,
            limit: limit.units(),
        };
        match (self.min, self.max) {
            (Some(lo), _) if t < lo.units() => Err(outside("below the minimum", lo)),
            (_, Some(hi)) if t > hi.units() => Err(outside("above the maximum", hi)),
            _ => Ok(()),
        }
    }
}

/// A move as [`Bus::move_to`] makes it: checked, sent, read back, waited for, verified.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MoveRequest {
    /// Where to.
    pub target: MoveTarget,
    /// SPEED for this move (the drive's current setting if `None`).
    pub speed: Option<SpeedPercent>,
    /// ACCEL for this move (the drive's current setting if `None`).
    pub accel: Option<RampMs>,
    /// Send the binary forms.
    pub binary: bool,
    /// Targets outside these are refused before anything is sent.
    pub limits: TravelLimits,
    /// How long the wait may take ([`BusConfig::wait_timeout`] if `None`); then the axis is stopped.
    pub timeout: Option<Duration>,
}

impl MoveRequest {
    /// A move to `target` with the drive's current settings, no limits and the default timeout.
    pub fn new(target: MoveTarget) -> Self {
        MoveRequest { target, speed: None, accel: None, binary: false, limits: TravelLimits::default(), timeout: None }
    }
}

/// A move the drive has taken, with its target confirmed by S2 ([`Bus::start_checked_move`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StartedMove {
    /// The drive.
    pub address: Address,
    /// S1 before the move.
    pub start: Position,
    /// The absolute target (for a relative move: S2 before it plus the distance, as the drive computes it).
    pub target: Position,
}

/// A move that ended at its target ([`Bus::move_to`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MoveReport {
    /// The drive.
    pub address: Address,
    /// S1 before the move.
    pub start: Position,
    /// The target.
    pub target: Position,
    /// S1 at rest afterwards (within [`BusConfig::in_position_tolerance`] of the target).
    pub reached: Position,
}

impl MoveReport {
    /// `reached - target`.
    pub fn difference(&self) -> f64 {
        self.reached.units() - self.target.units()
    }
}

/// A result of a client call.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// How a move is sent.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct MoveOptions {
    /// Send the binary form (no ASCII conversion in the drive).
    pub binary: bool,
    /// Append `$`: the drive sends the position-reached message (ASCII only).
    pub message: bool,
}

/// When a telegram may be sent again.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Retry {
    /// After E70 / E72 / E73, a timeout or a corrupt reply.
    Idempotent,
    /// After E70 / E72 / E73 only; a lost reply is returned to the caller (who checks the drive's state).
    DiscardedOnly,
}

/// A client for one bus of COMPAX drives.
pub struct Bus {
    link: Box<dyn Link>,
    clock: SharedClock,
    cfg: BusConfig,
    decoder: ReplyDecoder,
    cancel: CancelToken,
    /// Drives this client set in motion and has not yet seen stop (bit n: address n).
    started: u32,
    /// Drives that have answered this client (a broadcast move counts as started for each of them).
    known: u32,
    /// Drives whose move asked for `$` and whose message has not come.
    awaiting_message: u32,
    /// Drives whose `$` has come.
    message_seen: u32,
    /// `$` messages without address that could not be attributed.
    unattributed_messages: u32,
    /// Drives with comparators armed (their bare-number messages are expected).
    comparators: u32,
    /// Drives that may hold a move in their buffer, stored by this client and not yet executed: a `!` to
    /// them (or `32!`) starts it.
    buffered: u32,
    /// The request awaiting its reply, while [`Bus::transact`] reads it: a bare number that can be its reply
    /// is taken as the reply, not as a comparator message.
    awaiting_reply: Option<(Address, ReplyShape)>,
    paused: bool,
    /// Earliest time of the next send (after a broadcast).
    quiet_until: Timestamp,
    rx: [u8; 256],
    rx_pos: usize,
    rx_len: usize,
}

impl fmt::Debug for Bus {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Bus").field("port", &self.link.describe()).field("config", &self.cfg).finish()
    }
}

/// Bits 1..=31: every drive address.
const ALL_DRIVES: u32 = !1;

/// The bit of drive `a` in the client's sets of drives; for the broadcast address 32, every drive's.
fn bit(a: Address) -> u32 {
    if a.is_broadcast() {
        ALL_DRIVES
    } else {
        1 << a.get()
    }
}

/// What the reply to a request can be, as far as a bare number (`35`, which is also what a comparator sends)
/// is concerned.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum ReplyShape {
    /// The value of a status read: a bare number is its reply if it reads as that status value.
    Status(StatusId),
    /// The value of a parameter read: a bare number is its reply if it reads as a value.
    Param(ParamId),
    /// An acknowledgement or `Exx` only (moves, settings, outputs, binary telegrams): never a bare number.
    AckOnly,
    /// Anything (an echo, `!`, text the model cannot read): a bare number may be its reply.
    Any,
}

impl ReplyShape {
    fn of(req: &Request<'_>) -> ReplyShape {
        if req.flags.echo {
            return ReplyShape::Any;
        }
        match req.body {
            Body::Execute => ReplyShape::Any,
            Body::Binary(_) => ReplyShape::AckOnly,
            Body::Command(t) => match Command::parse(t) {
                Ok(Command::ReadStatus(id)) => ReplyShape::Status(id),
                Ok(Command::ReadParam(id)) => ReplyShape::Param(id),
                Ok(_) => ReplyShape::AckOnly,
                Err(_) => ReplyShape::Any,
            },
        }
    }

    /// True if `text` (not an error message) can answer the request at all: an acknowledgement is empty,
    /// a read's reply reads as its value.
    fn accepts(self, text: &[u8]) -> bool {
        match self {
            ReplyShape::Status(id) => StatusValue::parse(id, text).is_ok(),
            ReplyShape::Param(id) => parse_param_reply(id, text).is_ok(),
            ReplyShape::AckOnly => text.is_empty(),
            ReplyShape::Any => true,
        }
    }

    /// True if `text` can be the reply.
    fn fits(self, text: &[u8]) -> bool {
        match self {
            ReplyShape::Status(id) => StatusValue::parse(id, text).is_ok(),
            ReplyShape::Param(id) => parse_param_reply(id, text).is_ok(),
            ReplyShape::AckOnly => false,
            ReplyShape::Any => true,
        }
    }
}

/// What a command does to the client's record of the axes it moves.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Effect {
    /// Nothing the client tracks.
    None,
    /// It may start a positioning (a move, or `!`, which runs whatever the buffer holds).
    Starts,
    /// `OUTPUT O0=0` / `=2`: the drive is switched off, its positioning ends.
    SwitchesOff,
    /// `POSR x OUTPUT Oy=z`: a comparator, whose number the drive will send unasked.
    Comparator,
}

impl Effect {
    fn of_command(c: &Command) -> Effect {
        match c {
            c if c.is_move() => Effect::Starts,
            Command::Output { output: 0, state } if *state != OutputState::ON => Effect::SwitchesOff,
            Command::PosROutput { .. } => Effect::Comparator,
            _ => Effect::None,
        }
    }

    /// Of a telegram as [`Bus::raw`] sends it. A stored (`,`) or echoed (`?`) command is not executed;
    /// `!` may start anything. Text the model cannot read is not tracked.
    fn of_request(body: &Body<'_>, flags: Flags) -> Effect {
        if flags.echo || flags.buffer {
            return Effect::None;
        }
        match body {
            Body::Execute => Effect::Starts,
            Body::Command(t) => Command::parse(t).map_or(Effect::None, |c| Effect::of_command(&c)),
            Body::Binary(b) => Command::from_binary(b).map_or(Effect::None, |c| Effect::of_command(&c)),
        }
    }
}

impl Bus {
    /// A client on `link`, timed by `clock`.
    pub fn new(link: Box<dyn Link>, clock: SharedClock, cfg: BusConfig) -> Self {
        Bus {
            decoder: ReplyDecoder::new(&cfg.mode),
            link,
            clock,
            cfg,
            cancel: CancelToken::new(),
            started: 0,
            known: 0,
            awaiting_message: 0,
            message_seen: 0,
            unattributed_messages: 0,
            comparators: 0,
            buffered: 0,
            awaiting_reply: None,
            paused: false,
            quiet_until: Timestamp::ZERO,
            rx: [0; 256],
            rx_pos: 0,
            rx_len: 0,
        }
    }

    /// Long actions watch `token`: a wait stops the axes when it is cancelled, a scan ends, and no move is
    /// sent once it is cancelled (until the token is reset). All of them return [`Error::Cancelled`].
    pub fn set_cancel(&mut self, token: CancelToken) {
        self.cancel = token;
    }

    /// True once the cancel token is cancelled (see [`Bus::set_cancel`]).
    pub fn is_cancelled(&self) -> bool {
        self.cancel.is_cancelled()
    }

    fn check_cancel(&self) -> Result<()> {
        if self.cancel.is_cancelled() {
            Err(Error::Cancelled)
        } else {
            Ok(())
        }
    }

    /// A handle on drive `address` (1..=31) of this bus; the broadcast address 32 is refused
    /// ([`Error::Broadcast`]).
    pub fn drive(&mut self, address: Address) -> Result<Drive<'_>> {
        if address.is_broadcast() {
            return Err(Error::Broadcast("a drive handle is one drive (1..=31)"));
        }
        Ok(Drive { bus: self, address })
    }

    /// The configuration.
    pub fn config(&self) -> &BusConfig {
        &self.cfg
    }

    /// The drives this client set in motion and has not yet seen stop.
    pub fn started(&self) -> Vec<Address> {
        drives_in(self.started)
    }

    /// The drives that have answered this client.
    pub fn known(&self) -> Vec<Address> {
        drives_in(self.known)
    }

    /// Hands the motion of `drives` over to the caller: the client forgets that it set them in motion, so
    /// neither dropping it nor a cancelled wait stops them, and it no longer waits for their `$` messages.
    /// What `motionlink compax move --no-wait` does to leave a move running after it exits. The broadcast
    /// address releases every drive.
    pub fn release(&mut self, drives: &[Address]) {
        for &a in drives {
            self.started &= !bit(a);
            self.awaiting_message &= !bit(a);
            self.message_seen &= !bit(a);
        }
        if self.awaiting_message == 0 {
            self.unattributed_messages = 0;
        }
    }

    /// Records what sending a command with `effect` to `address` does, before it is sent (a move counts as
    /// started before it is sent: if the session fails then, the stop still reaches it). Returns the state
    /// to restore if the drive refuses the command.
    fn before_send(&mut self, address: Address, effect: Effect) -> u32 {
        let saved = self.started;
        if effect == Effect::Starts {
            let drives = if address.is_broadcast() { self.known } else { bit(address) };
            if address.is_broadcast() && drives == 0 {
                tracing::warn!("a broadcast that may start motion before any drive answered: none can be stopped");
            }
            self.started |= drives;
        }
        saved
    }

    /// Records what a command with `effect` did once the drive took it.
    fn after_send(&mut self, address: Address, effect: Effect) {
        match effect {
            Effect::SwitchesOff => self.finish(address),
            Effect::Comparator => self.comparators |= bit(address),
            Effect::Starts | Effect::None => {}
        }
    }

    // --------------------------------------------------------------------------------------------------
    // Transport

    fn command_text(&self, body: &Body<'_>, flags: Flags) -> String {
        match body {
            Body::Command(t) => format!("{}{flags}", EscapedBytes(t)),
            Body::Execute => format!("!{flags}"),
            Body::Binary(b) => format!("{b} (binary)"),
        }
    }

    fn handle_unsolicited(&mut self, r: &Reply) -> bool {
        match r.kind() {
            ReplyKind::PositionReached => {
                match r.address() {
                    Some(a) => self.message_seen |= 1 << a.min(31),
                    None if self.awaiting_message.count_ones() == 1 => self.message_seen |= self.awaiting_message,
                    None => self.unattributed_messages += 1,
                }
                tracing::debug!("position reached message from {:?}", r.address());
                true
            }
            ReplyKind::Comparator(n) if self.expects_comparator(r.address()) && !self.may_be_the_reply(r) => {
                tracing::info!("comparator {n} switched (drive {:?})", r.address());
                true
            }
            _ => false,
        }
    }

    /// True when a bare number from `from` (the reply's address prefix, if any) is a comparator message: a
    /// comparator is armed on that drive (on any, when replies carry no address).
    fn expects_comparator(&self, from: Option<u8>) -> bool {
        match from {
            Some(a) => a < BROADCAST && self.comparators & (1 << a) != 0,
            None => self.comparators != 0,
        }
    }

    /// True when `r` can be the reply to the request awaiting one (from its drive, when replies carry an
    /// address, and of the form that request is answered with). A reply to an outstanding request is that
    /// request's reply first: a bare number is a comparator message only when it cannot be.
    fn may_be_the_reply(&self, r: &Reply) -> bool {
        match self.awaiting_reply {
            None => false,
            Some((a, shape)) => r.address().is_none_or(|from| from == a.get()) && shape.fits(r.text()),
        }
    }

    /// Reads whatever arrives until `until`, handling unsolicited messages; returns the first reply that is
    /// not one, or a line error.
    fn read_event(&mut self, until: Timestamp, want: Option<Address>) -> Result<Option<ReplyEvent>> {
        loop {
            if self.rx_pos >= self.rx_len {
                let now = self.clock.now();
                if now >= until {
                    return Ok(None);
                }
                self.rx_pos = 0;
                self.rx_len = self.link.recv(&mut self.rx, until - now)?;
                continue;
            }
            let (used, event) = self.decoder.decode(&self.rx[self.rx_pos..self.rx_len]);
            let event = event.map(ReplyEvent::from);
            self.rx_pos += used;
            let Some(ev) = event else { continue };
            match ev {
                ReplyEvent::Flow(xoff) => self.paused = xoff,
                ReplyEvent::Reply(r) if self.handle_unsolicited(&r) => {}
                ReplyEvent::Reply(r) if want.is_some_and(|w| r.address().is_some_and(|a| a != w.get())) => {
                    tracing::warn!("ignoring a reply from drive {:?} while waiting for {want:?}: {r:?}", r.address());
                }
                other => return Ok(Some(other)),
            }
        }
    }

    /// Handles everything that arrives for `d` (a sleep that listens).
    fn listen(&mut self, d: Duration) -> Result<()> {
        let until = self.clock.now() + d;
        while let Some(ev) = self.read_event(until, None)? {
            tracing::debug!("unexpected while listening: {ev:?}");
        }
        Ok(())
    }

    /// Handles every byte already received (late replies are dropped, messages noted).
    fn drain(&mut self) -> Result<()> {
        loop {
            self.listen(Duration::ZERO)?;
            self.rx_pos = 0;
            self.rx_len = self.link.recv(&mut self.rx, Duration::ZERO)?;
            if self.rx_len == 0 {
                return Ok(());
            }
        }
    }

    /// Sends one telegram and reads its reply (`None` when none is due).
    fn transact(&mut self, req: &Request<'_>, retry: Retry) -> Result<Option<Reply>> {
        let frame = req.encode(&self.cfg.mode)?;
        let wire_time = self.cfg.char_time() * (frame.len() as u32 + 48);
        let mut attempts = 0;
        let mut last_corrupt = None;
        let mut unfit: Option<String> = None;
        loop {
            attempts += 1;
            // Whatever arrived before (late replies, messages) is handled, not mistaken for the answer.
            let now = self.clock.now();
            if self.quiet_until > now {
                self.listen(self.quiet_until - now)?;
            }
            self.drain()?;
            if self.paused {
                tracing::debug!("XOFF: waiting for XON");
                let until = self.clock.now() + self.cfg.reply_timeout;
                while self.paused && self.clock.now() < until {
                    self.listen(self.cfg.poll_interval.min(until - self.clock.now()))?;
                }
            }
            self.decoder.reset();
            self.decoder.expect_from(Some(req.address.get()));
            tracing::trace!("send {:?}", EscapedBytes(frame.as_bytes()));
            self.link.send(frame.as_bytes())?;
            if !req.expects_reply() {
                let on_wire = self.cfg.char_time() * frame.len() as u32;
                self.quiet_until = self.clock.now()
                    + on_wire
                    + if req.address.is_broadcast() { self.cfg.broadcast_gap } else { Duration::ZERO };
                return Ok(None);
            }
            let deadline = self.clock.now() + wire_time + self.cfg.reply_timeout;
            // Only with comparators armed can a bare number be anything but the reply: work out then what
            // the reply can be.
            let shape = if self.comparators != 0 { ReplyShape::of(req) } else { ReplyShape::Any };
            self.awaiting_reply = Some((req.address, shape));
            // A reply that cannot answer this request (text to a move or setting, an acknowledgement or
            // another value to a read) is a late reply to an earlier one, or garbled: it is not taken.
            let accept = ReplyShape::of(req);
            let outcome = loop {
                match self.read_event(deadline, Some(req.address)) {
                    Ok(Some(ReplyEvent::Reply(r)))
                        if !matches!(r.kind(), ReplyKind::Error(_)) && !accept.accepts(r.text()) =>
                    {
                        tracing::info!("drive {}: {:?} cannot answer this request: ignored", req.address, r.text_str());
                        unfit = Some(r.text_str().to_string());
                    }
                    other => break other,
                }
            };
            self.awaiting_reply = None;
            let outcome = outcome?;
            let retry_left = attempts <= self.cfg.retries;
            if matches!(outcome, Some(ReplyEvent::Reply(_))) && !req.address.is_broadcast() {
                self.known |= bit(req.address);
            }
            match outcome {
                Some(ReplyEvent::Reply(r)) => match r.kind() {
                    ReplyKind::Error(code) if ErrorCode(code).is_retransmit() && retry_left => {
                        tracing::info!("drive {} answered E{code}: sending again", req.address);
                    }
                    ReplyKind::Error(code) => {
                        return Err(Error::Device {
                            address: req.address.get(),
                            command: self.command_text(&req.body, req.flags),
                            code: ErrorCode(code),
                        })
                    }
                    _ => return Ok(Some(r)),
                },
                Some(ReplyEvent::Error(e)) => {
                    tracing::info!("drive {}: corrupt reply ({e})", req.address);
                    last_corrupt = Some(e);
                    // Let the rest of a broken reply pass before trying again.
                    self.listen(self.cfg.char_time() * 4)?;
                    if retry != Retry::Idempotent || !retry_left {
                        return Err(Error::Corrupt {
                            address: req.address.get(),
                            command: self.command_text(&req.body, req.flags),
                            detail: e,
                        });
                    }
                }
                Some(ReplyEvent::Flow(_)) => unreachable!("handled by read_event"),
                None => {
                    tracing::info!("drive {}: no reply (attempt {attempts})", req.address);
                    if retry != Retry::Idempotent || !retry_left {
                        if let Some(reply) = unfit {
                            return Err(Error::Unexpected {
                                address: req.address.get(),
                                command: self.command_text(&req.body, req.flags),
                                reply,
                            });
                        }
                        return Err(match last_corrupt {
                            Some(detail) if retry == Retry::Idempotent => Error::Corrupt {
                                address: req.address.get(),
                                command: self.command_text(&req.body, req.flags),
                                detail,
                            },
                            _ => Error::Timeout {
                                address: req.address.get(),
                                command: self.command_text(&req.body, req.flags),
                                attempts,
                            },
                        });
                    }
                }
            }
        }
    }

    fn send_command(&mut self, address: Address, cmd: &Command, flags: Flags) -> Result<Option<Reply>> {
        let text = cmd.to_ascii(self.cfg.style)?;
        let retry = if cmd.is_idempotent() || flags.buffer { Retry::Idempotent } else { Retry::DiscardedOnly };
        self.transact(&Request { address, body: Body::Command(text.as_bytes()), flags }, retry)
    }

    /// Sends `cmd` to one drive (or, with address 32, to all: then only commands without an answer) and
    /// returns the reply text (empty for an acknowledgement). Moves have their own methods.
    pub fn command(&mut self, address: Address, cmd: &Command) -> Result<String> {
        if cmd.is_move() {
            return Err(ModelError::Syntax {
                what: "a command (use the move methods for moves)",
                text: cmd.to_string(),
            }
            .into());
        }
        if address.is_broadcast() && matches!(cmd, Command::ReadStatus(_) | Command::ReadParam(_)) {
            return Err(Error::Broadcast("nothing can be read from it"));
        }
        let effect = Effect::of_command(cmd);
        let r = self.send_command(address, cmd, Flags::NONE)?;
        self.after_send(address, effect);
        Ok(r.map(|r| r.text_str().to_string()).unwrap_or_default())
    }

    /// Sends `text` as it is (`S1`, `POSA 10$`, `!`, `OUTPUT O9=1/`); flag characters at its end are sent
    /// as flags. Sent again only after E70, E72 or E73 (the drive discarded it); never after a lost reply.
    /// Returns the reply text, or `None` when no reply is due (a broadcast, `/`).
    ///
    /// A move or `!` counts as started (for address 32: every drive that has answered this client), so
    /// dropping the client or a cancelled wait stops it; `OUTPUT O0=0` counts as a stop. Text the model
    /// cannot read is sent but not tracked.
    pub fn raw(&mut self, address: Address, text: &str) -> Result<Option<String>> {
        let (body, flags) = Flags::split(text.trim().as_bytes());
        let body = if body == b"!" { Body::Execute } else { Body::Command(body) };
        let effect = Effect::of_request(&body, flags);
        if effect == Effect::Starts {
            self.check_cancel()?;
        }
        let saved = self.before_send(address, effect);
        let executes = matches!(body, Body::Execute) && !flags.echo && !flags.buffer;
        if executes {
            self.execute_buffers(address);
        }
        let stores_move = flags.buffer
            && !flags.echo
            && matches!(body, Body::Command(t) if Command::parse(t).is_ok_and(|c| c.is_move()));
        match self.transact(&Request { address, body, flags }, Retry::DiscardedOnly) {
            Ok(r) => {
                if stores_move {
                    // A broadcast store reaches every drive; the client can stop only those it knows.
                    self.buffered |= if address.is_broadcast() { self.known } else { bit(address) };
                }
                self.after_send(address, effect);
                Ok(r.map(|r| r.text_str().to_string()))
            }
            Err(e) => {
                if matches!(e, Error::Device { .. }) {
                    // Refused: it started nothing (an axis that was moving before still is).
                    self.started = saved;
                    if effect == Effect::Starts {
                        return Err(self.explain_refused_move(address, e));
                    }
                }
                Err(e)
            }
        }
    }

    /// A move `address` refused: if the drive is switched off (S16), that is the reason to give
    /// ([`Error::SwitchedOff`]) rather than the bare code. E92 (the axis still moves) needs no reading.
    fn explain_refused_move(&mut self, address: Address, e: Error) -> Error {
        let Error::Device { code, .. } = e else { return e };
        if code == ErrorCode::COMMAND_ACTIVE || address.is_broadcast() {
            return e;
        }
        match self.read_s16(address) {
            Ok(s16) if s16.o0_state() != 1 => {
                Error::SwitchedOff { address: address.get(), o0: s16.o0_state(), refused: Some(code) }
            }
            _ => e,
        }
    }

    /// Sends `text` with `?`: the drive sends it back. Returns the echo.
    pub fn echo(&mut self, address: Address, text: &str) -> Result<String> {
        if address.is_broadcast() {
            return Err(Error::Broadcast("no echo comes back"));
        }
        let r = self.transact(
            &Request { address, body: Body::Command(text.as_bytes()), flags: Flags { echo: true, ..Flags::NONE } },
            Retry::Idempotent,
        )?;
        Ok(r.map(|r| r.text_str().to_string()).unwrap_or_default())
    }

    fn unexpected(&self, address: Address, cmd: &Command, r: &[u8]) -> Error {
        Error::Unexpected {
            address: address.get(),
            command: cmd.to_string(),
            reply: String::from_utf8_lossy(r).into_owned(),
        }
    }

    // --------------------------------------------------------------------------------------------------
    // Reading

    /// Sends a command whose answer is wanted; refuses the broadcast address (nobody answers it).
    fn ask(&mut self, address: Address, cmd: &Command, what: &'static str) -> Result<Reply> {
        if address.is_broadcast() {
            return Err(Error::Broadcast(what));
        }
        self.send_command(address, cmd, Flags::NONE)?.ok_or(Error::Broadcast(what))
    }

    /// Reads status value `id`. Address 32 is refused with [`Error::Broadcast`].
    ///
    /// A reply that does not read as that value (without a BCC, a flipped bit can garble a reply beyond
    /// recognition) is asked for again, up to [`BusConfig::retries`] times: a read changes nothing.
    pub fn read_status(&mut self, address: Address, id: StatusId) -> Result<StatusValue> {
        let cmd = Command::ReadStatus(id);
        let mut attempts = 0;
        loop {
            attempts += 1;
            let r = self.ask(address, &cmd, "a status value cannot be read from it")?;
            match StatusValue::parse(id, r.text()) {
                Ok(v) => return Ok(v),
                Err(_) if attempts <= self.cfg.retries => {
                    tracing::info!("drive {address}: {id} answered {:?}, not a value: reading again", r.text_str());
                }
                Err(_) => return Err(self.unexpected(address, &cmd, r.text())),
            }
        }
    }

    /// Reads the actual position S1.
    pub fn read_position(&mut self, address: Address) -> Result<Position> {
        self.read_position_value(address, StatusId::ACTUAL_POSITION)
    }

    /// Reads the target position S2.
    pub fn read_target(&mut self, address: Address) -> Result<Position> {
        self.read_position_value(address, StatusId::TARGET_POSITION)
    }

    fn read_position_value(&mut self, address: Address, id: StatusId) -> Result<Position> {
        match self.read_status(address, id)? {
            StatusValue::Position(p) => Ok(p),
            other => {
                Err(Error::Unexpected { address: address.get(), command: id.to_string(), reply: other.to_string() })
            }
        }
    }

    /// Reads the status bits S16.
    pub fn read_s16(&mut self, address: Address) -> Result<S16Bits> {
        match self.read_status(address, StatusId::STATUS_BITS_1)? {
            StatusValue::S16(b) => Ok(b),
            other => Err(Error::Unexpected { address: address.get(), command: "S16".into(), reply: other.to_string() }),
        }
    }

    /// Reads the status bits S17.
    pub fn read_s17(&mut self, address: Address) -> Result<S17Bits> {
        match self.read_status(address, StatusId::STATUS_BITS_2)? {
            StatusValue::S17(b) => Ok(b),
            other => Err(Error::Unexpected { address: address.get(), command: "S17".into(), reply: other.to_string() }),
        }
    }

    /// Reads parameter `id`. Address 32 is refused with [`Error::Broadcast`].
    ///
    /// A reply that does not read as a value is asked for again, as for [`Bus::read_status`].
    pub fn read_param(&mut self, address: Address, id: ParamId) -> Result<f64> {
        let cmd = Command::ReadParam(id);
        let mut attempts = 0;
        loop {
            attempts += 1;
            let r = self.ask(address, &cmd, "a parameter cannot be read from it")?;
            match parse_param_reply(id, r.text()) {
                Ok(v) => return Ok(v),
                Err(_) if attempts <= self.cfg.retries => {
                    tracing::info!("drive {address}: {id} answered {:?}, not a value: reading again", r.text_str());
                }
                Err(_) => return Err(self.unexpected(address, &cmd, r.text())),
            }
        }
    }

    /// Writes parameter `id` (checked against its known range first) and reads it back: a value that reads
    /// back otherwise is [`Error::ReadBack`]. P194..P196 take effect at power-on (they read back at once).
    /// To address 32 (every drive) the value is written and cannot be read back (nobody answers).
    pub fn write_param(&mut self, address: Address, id: ParamId, value: f64) -> Result<()> {
        id.check(value)?;
        self.expect_ack(address, &Command::WriteParam(id, value))?;
        if address.is_broadcast() {
            return Ok(());
        }
        let read = self.read_param(address, id)?;
        // The reply is decimal text: what was written reads back as the same number, at any magnitude.
        if (read - value).abs() > 1e-9 * value.abs().max(1.0) {
            return Err(Error::ReadBack { address: address.get(), param: id, wrote: value, read });
        }
        Ok(())
    }

    fn expect_ack(&mut self, address: Address, cmd: &Command) -> Result<()> {
        match self.send_command(address, cmd, Flags::NONE)? {
            Some(r) if !r.text().is_empty() => Err(self.unexpected(address, cmd, r.text())),
            _ => Ok(()),
        }
    }

    /// Tries every address in `range` once with a short timeout; returns the drives that answered S1 with
    /// their positions. Ends with [`Error::Cancelled`] when the cancel token is cancelled (checked before
    /// each address).
    pub fn scan(&mut self, range: std::ops::RangeInclusive<u8>) -> Result<Vec<(Address, Position)>> {
        let saved = self.cfg.retries;
        self.cfg.retries = 0;
        let mut found = Vec::new();
        let mut result = Ok(());
        for a in range.filter_map(|a| Address::drive(a).ok()) {
            if let Err(e) = self.check_cancel() {
                result = Err(e);
                break;
            }
            match self.read_position(a) {
                Ok(p) => found.push((a, p)),
                Err(Error::Timeout { .. } | Error::Corrupt { .. }) => {}
                Err(e @ Error::Link(_)) => {
                    result = Err(e);
                    break;
                }
                Err(e) => tracing::warn!("drive {a}: {e}"),
            }
        }
        self.cfg.retries = saved;
        result.map(|()| found)
    }

    // --------------------------------------------------------------------------------------------------
    // Settings and outputs

    /// SPEED for the next positionings.
    pub fn set_speed(&mut self, address: Address, speed: SpeedPercent, binary: bool) -> Result<()> {
        self.setting(address, Command::Speed(speed), binary)
    }

    /// ACCEL (acceleration and braking time) for the next positionings.
    pub fn set_accel(&mut self, address: Address, ramp: RampMs, binary: bool) -> Result<()> {
        self.setting(address, Command::Accel(ramp), binary)
    }

    /// ACCEL- (braking time alone) for the next positionings.
    pub fn set_brake(&mut self, address: Address, ramp: RampMs, binary: bool) -> Result<()> {
        self.setting(address, Command::AccelBrake(ramp), binary)
    }

    /// OUTPUT O`output`=`state`. Output 0 is the drive itself: 0 switches it off, 1 on. To address 32, every
    /// drive's output (and `O0=0` switches every drive off: the client forgets every axis it moved).
    pub fn set_output(&mut self, address: Address, output: u16, state: OutputState, binary: bool) -> Result<()> {
        let cmd = Command::Output { output, state };
        self.setting(address, cmd, binary)?;
        self.after_send(address, Effect::of_command(&cmd));
        Ok(())
    }

    fn setting(&mut self, address: Address, cmd: Command, binary: bool) -> Result<()> {
        if binary {
            let b = cmd.to_binary()?;
            self.transact(&Request { address, body: Body::Binary(b), flags: Flags::NONE }, Retry::Idempotent)?;
            Ok(())
        } else {
            self.expect_ack(address, &cmd)
        }
    }

    // --------------------------------------------------------------------------------------------------
    // Moves

    /// POSA: moves to `target`. Returns once the drive has taken the command; see [`Bus::wait_reached`].
    /// Moves go to one drive (address 32 is refused with [`Error::Broadcast`]: see [`Bus::broadcast`] and
    /// [`Bus::sync_start`]) and are not sent once the cancel token is cancelled ([`Error::Cancelled`]).
    pub fn move_absolute(&mut self, address: Address, target: Position, opts: MoveOptions) -> Result<()> {
        self.start_move(address, Command::PosA(target), opts)
    }

    /// POSR: moves by `distance`. If the reply is lost the client reads the target position S2: unchanged,
    /// the drive did not take the move and it is sent again; moved by `distance`, it did; anything else is
    /// [`Error::MoveUncertain`]. Never sent again blind.
    pub fn move_relative(&mut self, address: Address, distance: Position, opts: MoveOptions) -> Result<()> {
        self.start_move(address, Command::PosR(distance), opts)
    }

    /// POSA HOME: finds machine zero.
    pub fn home(&mut self, address: Address, opts: MoveOptions) -> Result<()> {
        self.start_move(address, Command::PosAHome, opts)
    }

    fn move_request<'a>(
        &self,
        address: Address,
        cmd: &Command,
        text: &'a [u8],
        opts: MoveOptions,
    ) -> Result<Request<'a>> {
        if opts.binary {
            if opts.message {
                return Err(WireError::Flags("the binary form takes no '$'").into());
            }
            return Ok(Request { address, body: Body::Binary(cmd.to_binary()?), flags: Flags::NONE });
        }
        Ok(Request {
            address,
            body: Body::Command(text),
            flags: Flags { position_message: opts.message, ..Flags::NONE },
        })
    }

    fn start_move(&mut self, address: Address, cmd: Command, opts: MoveOptions) -> Result<()> {
        self.start_move_from(address, cmd, opts, None)
    }

    /// Sends move `cmd`; for a POSR, `target_before` is the drive's S2 if the caller has just read it.
    fn start_move_from(
        &mut self,
        address: Address,
        cmd: Command,
        opts: MoveOptions,
        target_before: Option<f64>,
    ) -> Result<()> {
        if address.is_broadcast() {
            return Err(Error::Broadcast(
                "a move needs one drive's answer (broadcast() moves every drive, sync_start() several at once)",
            ));
        }
        self.check_cancel()?;
        let text = cmd.to_ascii(self.cfg.style)?;
        let req = self.move_request(address, &cmd, text.as_bytes(), opts)?;
        let before = match (cmd, target_before) {
            (Command::PosR(_), Some(b)) => Some(b),
            (Command::PosR(_), None) => Some(self.read_target(address)?.units()),
            _ => None,
        };
        let expected = match cmd {
            Command::PosA(p) => p.units(),
            Command::PosR(d) => before.unwrap_or(0.0) + d.units(),
            _ => 0.0,
        };
        // The read above may have taken a while: a cancel that came meanwhile still keeps the move unsent.
        self.check_cancel()?;
        // Counted as started before it is sent: if the session fails now, the stop still reaches it.
        let saved = self.before_send(address, Effect::Starts);
        let saved_awaiting = self.awaiting_message;
        if opts.message {
            self.awaiting_message |= bit(address);
            self.message_seen &= !bit(address);
        }
        let mut attempts = 0;
        loop {
            attempts += 1;
            match self.transact(&req, Retry::DiscardedOnly) {
                Ok(_) => return Ok(()),
                Err(e @ (Error::Timeout { .. } | Error::Corrupt { .. } | Error::Unexpected { .. })) => {
                    // The reply is lost (or only a reply that cannot be the acknowledgement came): did the
                    // drive take the move? Its target position tells.
                    let target = self.read_target(address)?.units();
                    let close = |a: f64, b: f64| (a - b).abs() < 0.0015;
                    if close(target, expected) && (before.is_none() || !close(expected, before.unwrap_or(0.0))) {
                        tracing::info!("drive {address}: reply lost, but the drive took the move (S2 = {target})");
                        return Ok(());
                    }
                    let not_taken = match before {
                        Some(b) => close(target, b),
                        None => !self.read_s17(address)?.bit(S17Bits::COMMAND_ACTIVE),
                    };
                    if not_taken && attempts <= self.cfg.retries {
                        tracing::info!("drive {address}: reply lost and the move was not taken: sending it again");
                        continue;
                    }
                    if not_taken {
                        self.started = saved;
                        self.awaiting_message = saved_awaiting;
                        return Err(e);
                    }
                    return Err(Error::MoveUncertain { address: address.get(), command: cmd.to_string(), target });
                }
                Err(e) => {
                    if matches!(e, Error::Device { .. }) {
                        // Refused (E92 while it still moves, for one): it started nothing new, and an axis
                        // this client set moving before is still its to stop.
                        self.started = saved;
                        self.awaiting_message = saved_awaiting;
                        return Err(self.explain_refused_move(address, e));
                    }
                    return Err(e);
                }
            }
        }
    }

    /// Starts several drives at the same instant: each move is stored in its drive's buffer (`,`), then one
    /// broadcast `32!` executes them all. Note that every drive on the bus runs what its buffer holds.
    ///
    /// Hazard: if storing the move fails for one drive, no `!` is sent, but the drives before it keep their
    /// buffered move, and the manual has no command that empties a buffer (only `!` does, by executing
    /// it). The call then returns [`Error::SyncIncomplete`], which names those drives: the next `!` to one
    /// of them, or any `32!` on the bus, starts its move. If this client sends that `!` (through
    /// [`Bus::raw`] or another `sync_start`), it counts those drives as started, so dropping it stops them.
    pub fn sync_start(&mut self, moves: &[(Address, Command)], message: bool) -> Result<()> {
        for (a, c) in moves {
            if !c.is_move() || a.is_broadcast() {
                return Err(ModelError::Syntax { what: "a move to one drive", text: format!("{a}: {c}") }.into());
            }
        }
        self.check_cancel()?;
        let mut stored = 0u32;
        for (a, c) in moves {
            match self.send_command(*a, c, Flags { buffer: true, position_message: message, ..Flags::NONE }) {
                Ok(_) => {
                    stored |= bit(*a);
                    self.buffered |= bit(*a);
                }
                Err(e) => {
                    if e.is_transport() {
                        // The reply was lost: the drive may have stored the move.
                        self.buffered |= bit(*a);
                        stored |= bit(*a);
                    }
                    tracing::error!("drive {a}: storing the synchronous move failed ({e}); buffered moves remain");
                    return Err(Error::SyncIncomplete {
                        failed: a.get(),
                        source: Box::new(e),
                        buffered: drives_in(stored).iter().map(|d| d.get()).collect(),
                    });
                }
            }
        }
        self.check_cancel()?;
        for (a, _) in moves {
            if message {
                self.awaiting_message |= bit(*a);
                self.message_seen &= !bit(*a);
            }
        }
        self.execute_buffers(Address::BROADCAST);
        self.transact(
            &Request { address: Address::BROADCAST, body: Body::Execute, flags: Flags::NONE },
            Retry::DiscardedOnly,
        )?;
        Ok(())
    }

    /// Before a `!` to `address` (32: every drive) is sent: the buffered moves it executes count as started.
    fn execute_buffers(&mut self, address: Address) {
        let executed = self.buffered & bit(address);
        self.started |= executed;
        self.buffered &= !executed;
    }

    /// Sends `cmd` to every drive at once (no reply). A move counts as started for every drive that has
    /// answered this client (drives it has never heard cannot be stopped by it); `OUTPUT O0=0` ends every
    /// record of a started axis.
    pub fn broadcast(&mut self, cmd: &Command) -> Result<()> {
        let effect = Effect::of_command(cmd);
        if effect == Effect::Starts {
            self.check_cancel()?;
        }
        let text = cmd.to_ascii(self.cfg.style)?;
        self.before_send(Address::BROADCAST, effect);
        self.transact(
            &Request { address: Address::BROADCAST, body: Body::Command(text.as_bytes()), flags: Flags::NONE },
            Retry::DiscardedOnly,
        )?;
        self.after_send(Address::BROADCAST, effect);
        Ok(())
    }

    /// Waits until every drive in `drives` has ended its positioning: by its `$` message when the move asked
    /// for one, otherwise by polling S17 ("command active") every [`BusConfig::poll_interval`]. `progress`
    /// gets each polled position.
    ///
    /// While it listens for `$` messages it still reads each drive's S17 every
    /// [`BusConfig::message_check_interval`]: a `$` lost to a line error, or a positioning that someone else
    /// ended (no `$` comes then), ends the wait too. Without a `timeout` it waits at most
    /// [`BusConfig::wait_timeout`]. Between polls it looks at the cancel token every few milliseconds. On
    /// timeout, cancellation or a line failure, every axis this client started is stopped
    /// ([`Bus::stop_started`]) and the error is [`Error::Aborted`], which says whether each drive confirmed
    /// its stop. Address 32 is refused ([`Error::Broadcast`]): a broadcast has no state to read.
    ///
    /// The end of a positioning is not the end of a move: [`Bus::move_to`] also checks where the axis came
    /// to rest.
    pub fn wait_reached(
        &mut self,
        drives: &[Address],
        timeout: Option<Duration>,
        progress: &mut dyn FnMut(Address, Position),
    ) -> Result<()> {
        if drives.iter().any(|a| a.is_broadcast()) {
            return Err(Error::Broadcast("a wait reads each drive's state: name the drives"));
        }
        let timeout = timeout.unwrap_or(self.cfg.wait_timeout);
        let started_at = self.clock.now();
        let give_up_at = started_at + timeout;
        let mut next_check = started_at + self.cfg.message_check_interval;
        let mut poll_at = started_at;
        let mut pending: Vec<Address> = drives.to_vec();
        pending.sort();
        pending.dedup();
        let result = (|| -> Result<()> {
            loop {
                self.check_cancel()?;
                let check_due = self.clock.now() >= next_check;
                let mut still = Vec::new();
                for &a in &pending {
                    let by_message = self.awaiting_message & bit(a) != 0;
                    if by_message && self.message_seen & bit(a) != 0 {
                        self.finish(a);
                        continue;
                    }
                    let attributable = self.cfg.mode.reply_address || self.awaiting_message.count_ones() == 1;
                    if by_message && self.unattributed_messages == 0 && attributable && !check_due {
                        still.push(a);
                        continue;
                    }
                    let s17 = self.read_s17(a)?;
                    if let Ok(p) = self.read_position(a) {
                        progress(a, p);
                    }
                    if s17.bit(S17Bits::COMMAND_ACTIVE) {
                        still.push(a);
                    } else {
                        if by_message && self.message_seen & bit(a) == 0 {
                            tracing::info!("drive {a}: positioning ended without its '$' message (lost, or stopped)");
                        }
                        self.finish(a);
                    }
                }
                if check_due {
                    next_check = self.clock.now() + self.cfg.message_check_interval;
                }
                pending = still;
                if pending.is_empty() {
                    return Ok(());
                }
                let now = self.clock.now();
                if now >= give_up_at {
                    return Err(Error::MoveTimeout { address: pending[0].get(), after: now - started_at });
                }
                // The next poll is due one interval after the start of this one (at once if this one took
                // longer), never later than the end of the wait.
                poll_at = (poll_at + self.cfg.poll_interval).max(now).min(give_up_at);
                self.listen_until(poll_at)?;
            }
        })();
        result.map_err(|e| self.abort(e))
    }

    /// Waits `d` on the session's clock, handling what arrives meanwhile (`$` and comparator messages),
    /// and ends early with [`Error::Cancelled`] once the cancel token is cancelled (it looks every 5 ms). For
    /// callers that poll at their own rate (`motionlink compax watch`).
    pub fn pause(&mut self, d: Duration) -> Result<()> {
        let until = self.clock.now() + d;
        self.listen_until(until)
    }

    /// Handles what arrives until `until`, looking at the cancel token every [`CANCEL_CHECK`].
    fn listen_until(&mut self, until: Timestamp) -> Result<()> {
        loop {
            self.check_cancel()?;
            let now = self.clock.now();
            if now >= until {
                return Ok(());
            }
            self.listen((until - now).min(CANCEL_CHECK))?;
        }
    }

    /// `cause` ended an action while axes of this client may be moving: stops them and says how that went
    /// ([`Error::Aborted`]); with nothing to stop, `cause` alone.
    fn abort(&mut self, cause: Error) -> Error {
        if self.started == 0 {
            return cause;
        }
        tracing::warn!("{cause}: stopping the axes this client moved");
        let stop = self.stop_started();
        Error::Aborted { cause: Box::new(cause), stop }
    }

    /// Forgets `a` as moving: its positioning ended (or the broadcast address: every drive's). Its
    /// comparators belonged to that positioning, so bare numbers are replies again.
    fn finish(&mut self, a: Address) {
        self.started &= !bit(a);
        self.awaiting_message &= !bit(a);
        self.message_seen &= !bit(a);
        self.comparators &= !bit(a);
        if self.awaiting_message == 0 {
            self.unattributed_messages = 0;
        }
    }

    /// Stops one drive: `OUTPUT O0=0` (switch off drive), acknowledged. Switch it on again with
    /// `set_output(address, 0, OutputState::ON, false)`. Address 32 switches every drive on the bus off.
    /// [`Bus::stop_started`] also confirms the stop by reading S17.
    pub fn stop(&mut self, address: Address) -> Result<()> {
        let r = self.expect_ack(address, &Command::SWITCH_OFF);
        if r.is_ok() {
            self.finish(address);
        }
        r
    }

    /// Stops every drive this client set in motion and has not seen stop, if it still moves, and reports
    /// per drive how that ended. It reads the drive's S17 first (one attempt, no retries): a drive at rest
    /// is forgotten without being switched off ([`StopOutcome::AtRest`]). A drive whose S17 says "command
    /// active", or cannot be read (a line failure, a corrupt or unexpected reply, a refusal: on a failing
    /// line a moving axis must not be left running), is sent `OUTPUT O0=0`; once acknowledged, S17 is read
    /// again to confirm that no command is active ([`StopOutcome::SwitchedOff`]). Without a BCC the
    /// acknowledgement alone proves little (a flipped bit can turn `O0=0` into `O0=1`, which is
    /// acknowledged alike): if S17 still shows the positioning, the stop is sent once more. A drive that
    /// does not confirm is [`StopOutcome::NotConfirmed`]: the axis may still be moving, and the client
    /// keeps it on its list, so dropping the client tries once more.
    pub fn stop_started(&mut self) -> StopReport {
        let mut report = StopReport::default();
        for a in self.started() {
            let saved = std::mem::replace(&mut self.cfg.retries, 0);
            let s17 = self.read_s17(a);
            self.cfg.retries = saved;
            match s17 {
                Ok(s) if !s.bit(S17Bits::COMMAND_ACTIVE) => {
                    tracing::debug!("drive {a}: at rest, not switched off");
                    self.finish(a);
                    report.drives.push((a, StopOutcome::AtRest));
                    continue;
                }
                Ok(_) => tracing::warn!("drive {a} still moves: stopping it"),
                Err(e) => tracing::warn!("drive {a}: S17 unreadable ({e}): stopping it anyway"),
            }
            let outcome = self.switch_off_confirmed(a);
            match &outcome {
                StopOutcome::NotConfirmed { reason } => tracing::error!("drive {a}: stop not confirmed: {reason}"),
                _ => tracing::info!("drive {a}: switched off, at rest"),
            }
            report.drives.push((a, outcome));
        }
        report
    }

    /// `OUTPUT O0=0` to `a`, confirmed by S17 ("command active" clear) afterwards.
    fn switch_off_confirmed(&mut self, a: Address) -> StopOutcome {
        for _ in 0..2 {
            if let Err(e) = self.expect_ack(a, &Command::SWITCH_OFF) {
                return StopOutcome::NotConfirmed { reason: format!("OUTPUT O0=0 was not acknowledged: {e}") };
            }
            match self.read_s17(a) {
                Ok(s) if !s.bit(S17Bits::COMMAND_ACTIVE) => {
                    self.finish(a);
                    return StopOutcome::SwitchedOff;
                }
                Ok(_) => {
                    tracing::warn!("drive {a}: S17 still shows a command active after OUTPUT O0=0: sending it again")
                }
                Err(e) => {
                    return StopOutcome::NotConfirmed {
                        reason: format!("OUTPUT O0=0 was acknowledged, but S17 could not be read afterwards: {e}"),
                    }
                }
            }
        }
        StopOutcome::NotConfirmed {
            reason: "S17 still shows a command active after OUTPUT O0=0 was acknowledged twice".into(),
        }
    }

    // --------------------------------------------------------------------------------------------------
    // Checked moves

    /// Moves one drive and makes sure it got there: [`Bus::start_checked_move`], then
    /// [`Bus::finish_checked_move`]. `progress` gets each polled position. Returns where the axis came to
    /// rest, within [`BusConfig::in_position_tolerance`] of the target; any other outcome is an error,
    /// and an error while the axis may move has stopped it ([`Error::Aborted`] says whether the drive
    /// confirmed that).
    pub fn move_to(
        &mut self,
        address: Address,
        request: &MoveRequest,
        progress: &mut dyn FnMut(Position),
    ) -> Result<MoveReport> {
        let started = self.start_checked_move(address, request)?;
        self.finish_checked_move(&started, request.timeout, progress)
    }

    /// Starts a move and confirms the drive took the right target, in this order:
    ///
    /// 1. an absolute target outside `request.limits` is refused ([`Error::OutsideLimits`]) before anything
    ///    is sent;
    /// 2. S16: a drive that is switched off is refused ([`Error::SwitchedOff`]) before anything moves;
    /// 3. S1 (the start), and for a relative move S2 (the drive adds the distance to its target S2), then the
    ///    limits for the target that makes;
    /// 4. SPEED and ACCEL if given, then the move (POSA / POSR, ASCII or binary; see
    ///    [`Bus::move_absolute`] for what happens when its reply is lost);
    /// 5. S2 read back: the protocol starts a positioning with the move telegram itself (a move stored with
    ///    `,` cannot be read back before `!` executes it), so the target is checked as early as it can be,
    ///    just after. A target off by more than the tolerance is read once more (a reply can be garbled
    ///    too); still off, the axis is switched off at once and the error is [`Error::TargetMismatch`]
    ///    inside [`Error::Aborted`].
    ///
    /// Once the move may have been sent, any error stops the axis ([`Error::Aborted`]). Nothing is sent once
    /// the cancel token is cancelled.
    pub fn start_checked_move(&mut self, address: Address, request: &MoveRequest) -> Result<StartedMove> {
        if address.is_broadcast() {
            return Err(Error::Broadcast("a checked move reads one drive's state"));
        }
        self.check_cancel()?;
        if let MoveTarget::Absolute(p) = request.target {
            request.limits.check(address, p)?;
        }
        let s16 = self.read_s16(address)?;
        if s16.o0_state() != 1 {
            return Err(Error::SwitchedOff { address: address.get(), o0: s16.o0_state(), refused: None });
        }
        if self.read_s17(address)?.bit(S17Bits::COMMAND_ACTIVE) {
            // Someone else's positioning (or one this client handed over): not this call's to stop.
            return Err(Error::Device {
                address: address.get(),
                command: "S17".into(),
                code: ErrorCode::COMMAND_ACTIVE,
            });
        }
        let start = self.read_position(address)?;
        let (cmd, target, before) = match request.target {
            MoveTarget::Absolute(p) => (Command::PosA(p), p, None),
            MoveTarget::Relative(d) => {
                let s2 = self.read_target(address)?;
                (Command::PosR(d), Position::new(s2.units() + d.units())?, Some(s2.units()))
            }
        };
        request.limits.check(address, target)?;
        self.check_cancel()?;
        // The axis is at rest and switched on. From the first telegram that can change that on, it counts as
        // this client's to stop: without a BCC one flipped bit turns a binary SPEED into a POSR (53 -> 52),
        // and a move the drive then refuses with E92 means exactly that.
        self.started |= bit(address);
        let opts = MoveOptions { binary: request.binary, message: false };
        let sent = (|| {
            if let Some(speed) = request.speed {
                self.set_speed(address, speed, request.binary)?;
            }
            if let Some(ramp) = request.accel {
                self.set_accel(address, ramp, request.binary)?;
            }
            self.start_move_from(address, cmd, opts, before)
        })();
        if let Err(e) = sent {
            self.started |= bit(address);
            return Err(self.abort(e));
        }
        if let Err(e) = self.confirm_target(address, target) {
            return Err(self.abort(e));
        }
        Ok(StartedMove { address, start, target })
    }

    /// Reads S2 after a move was sent; [`Error::TargetMismatch`] when it is off the target twice.
    fn confirm_target(&mut self, address: Address, target: Position) -> Result<()> {
        let tolerance = self.cfg.in_position_tolerance;
        let mut taken = target.units();
        for attempt in 0..2 {
            taken = self.read_target(address)?.units();
            if (taken - target.units()).abs() <= tolerance {
                return Ok(());
            }
            tracing::warn!("drive {address}: S2 reads {taken}, not the target {target} (read {})", attempt + 1);
        }
        Err(Error::TargetMismatch { address: address.get(), requested: target.units(), taken })
    }

    /// Waits for a move [`Bus::start_checked_move`] started and checks where the axis came to rest: the
    /// actual position S1 must lie within [`BusConfig::in_position_tolerance`] of the target, or the
    /// error is [`Error::NotReached`] naming target, reached position and difference. A position off the
    /// target is checked against S17 and read once more before it counts: if S17 still shows the
    /// positioning (a garbled status reply ended the wait early), the wait goes on; a second S1 read
    /// decides (a garbled position reply is not the axis's position). Errors during the wait stop the axis
    /// ([`Bus::wait_reached`]).
    pub fn finish_checked_move(
        &mut self,
        started: &StartedMove,
        timeout: Option<Duration>,
        progress: &mut dyn FnMut(Position),
    ) -> Result<MoveReport> {
        let a = started.address;
        let tolerance = self.cfg.in_position_tolerance;
        let target = started.target;
        let give_up_at = self.clock.now() + timeout.unwrap_or(self.cfg.wait_timeout);
        let report = |reached: Position| MoveReport { address: a, start: started.start, target, reached };
        let close = |p: Position| (p.units() - target.units()).abs() <= tolerance;
        loop {
            let left = give_up_at.saturating_since(self.clock.now()).max(Duration::from_millis(1));
            self.wait_reached(&[a], Some(left), &mut |_, p| progress(p))?;
            let reached = self.read_position(a)?;
            if close(reached) {
                return Ok(report(reached));
            }
            if self.read_s17(a)?.bit(S17Bits::COMMAND_ACTIVE) {
                tracing::info!("drive {a}: the positioning still runs (a garbled status reply?): waiting on");
                self.started |= bit(a);
                continue;
            }
            let again = self.read_position(a)?;
            if close(again) {
                return Ok(report(again));
            }
            return Err(Error::NotReached {
                address: a.get(),
                target: target.units(),
                reached: again.units(),
                difference: again.units() - target.units(),
                tolerance,
            });
        }
    }
}

/// A handle on one drive (address 1..=31) of a [`Bus`]: the bus's single-drive operations without the
/// address. Made by [`Bus::drive`], which refuses the broadcast address 32, so nothing called on a `Drive`
/// waits for the answer of a broadcast.
///
/// It borrows the bus mutably, as every exchange on the one line does: make one when needed, or keep the
/// [`Address`] and call the [`Bus`] (whose methods also take several drives: [`Bus::sync_start`],
/// [`Bus::wait_reached`]).
///
/// ```
/// use motionlink_compax::client::{Bus, BusConfig, MoveOptions};
/// use motionlink_compax::model::Position;
/// use motionlink_compax::sim::{CompaxBus, SimConfig};
/// use motionlink_compax::wire::{Address, Mode};
/// use motionlink_link::{clock::{Clock, ManualClock}, pipe::{EmulatorHost, PipeConfig}};
///
/// let clock = ManualClock::new_auto();
/// let _me = clock.reserve_participant().enter();
/// let host = EmulatorHost::new(CompaxBus::new(SimConfig::bus(&[3], 0, 9600)).unwrap(),
///                              clock.shared(), PipeConfig::paced(9600));
/// let mut bus = Bus::new(Box::new(host.connect().0), clock.shared(), BusConfig::new(Mode::default(), 9600));
/// assert!(bus.drive(Address::BROADCAST).is_err());
/// let mut three = bus.drive(Address::drive(3).unwrap()).unwrap();
/// three.move_absolute(Position::new(2.5).unwrap(), MoveOptions::default()).unwrap();
/// three.wait_reached(None, &mut |_| {}).unwrap();
/// assert_eq!(three.read_position().unwrap().units(), 2.5);
/// ```
pub struct Drive<'a> {
    bus: &'a mut Bus,
    address: Address,
}

impl fmt::Debug for Drive<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Drive").field("address", &self.address).field("bus", &self.bus).finish()
    }
}

impl Drive<'_> {
    /// The drive's address (1..=31).
    pub fn address(&self) -> Address {
        self.address
    }

    /// The bus, for what involves several drives.
    pub fn bus(&mut self) -> &mut Bus {
        self.bus
    }

    /// [`Bus::read_status`].
    pub fn read_status(&mut self, id: StatusId) -> Result<StatusValue> {
        self.bus.read_status(self.address, id)
    }

    /// [`Bus::read_position`]: S1.
    pub fn read_position(&mut self) -> Result<Position> {
        self.bus.read_position(self.address)
    }

    /// [`Bus::read_target`]: S2.
    pub fn read_target(&mut self) -> Result<Position> {
        self.bus.read_target(self.address)
    }

    /// [`Bus::read_s16`].
    pub fn read_s16(&mut self) -> Result<S16Bits> {
        self.bus.read_s16(self.address)
    }

    /// [`Bus::read_s17`].
    pub fn read_s17(&mut self) -> Result<S17Bits> {
        self.bus.read_s17(self.address)
    }

    /// [`Bus::read_param`].
    pub fn read_param(&mut self, id: ParamId) -> Result<f64> {
        self.bus.read_param(self.address, id)
    }

    /// [`Bus::write_param`].
    pub fn write_param(&mut self, id: ParamId, value: f64) -> Result<()> {
        self.bus.write_param(self.address, id, value)
    }

    /// [`Bus::set_speed`].
    pub fn set_speed(&mut self, speed: SpeedPercent, binary: bool) -> Result<()> {
        self.bus.set_speed(self.address, speed, binary)
    }

    /// [`Bus::set_accel`].
    pub fn set_accel(&mut self, ramp: RampMs, binary: bool) -> Result<()> {
        self.bus.set_accel(self.address, ramp, binary)
    }

    /// [`Bus::set_brake`].
    pub fn set_brake(&mut self, ramp: RampMs, binary: bool) -> Result<()> {
        self.bus.set_brake(self.address, ramp, binary)
    }

    /// [`Bus::set_output`].
    pub fn set_output(&mut self, output: u16, state: OutputState, binary: bool) -> Result<()> {
        self.bus.set_output(self.address, output, state, binary)
    }

    /// [`Bus::move_absolute`].
    pub fn move_absolute(&mut self, target: Position, opts: MoveOptions) -> Result<()> {
        self.bus.move_absolute(self.address, target, opts)
    }

    /// [`Bus::move_relative`].
    pub fn move_relative(&mut self, distance: Position, opts: MoveOptions) -> Result<()> {
        self.bus.move_relative(self.address, distance, opts)
    }

    /// [`Bus::home`].
    pub fn home(&mut self, opts: MoveOptions) -> Result<()> {
        self.bus.home(self.address, opts)
    }

    /// [`Bus::move_to`]: a move that is checked, read back, waited for and verified.
    pub fn move_to(&mut self, request: &MoveRequest, progress: &mut dyn FnMut(Position)) -> Result<MoveReport> {
        self.bus.move_to(self.address, request, progress)
    }

    /// [`Bus::wait_reached`] for this drive.
    pub fn wait_reached(&mut self, timeout: Option<Duration>, progress: &mut dyn FnMut(Position)) -> Result<()> {
        self.bus.wait_reached(&[self.address], timeout, &mut |_, p| progress(p))
    }

    /// [`Bus::stop`]: `OUTPUT O0=0`.
    pub fn stop(&mut self) -> Result<()> {
        self.bus.stop(self.address)
    }

    /// [`Bus::release`]: leaves this drive's move running when the bus is dropped.
    pub fn release(&mut self) {
        self.bus.release(&[self.address])
    }

    /// [`Bus::command`].
    pub fn command(&mut self, cmd: &Command) -> Result<String> {
        self.bus.command(self.address, cmd)
    }

    /// [`Bus::raw`].
    pub fn raw(&mut self, text: &str) -> Result<Option<String>> {
        self.bus.raw(self.address, text)
    }

    /// [`Bus::echo`].
    pub fn echo(&mut self, text: &str) -> Result<String> {
        self.bus.echo(self.address, text)
    }
}

fn drives_in(set: u32) -> Vec<Address> {
    (1..BROADCAST).filter(|a| set & (1 << a) != 0).filter_map(|a| Address::drive(a).ok()).collect()
}

impl Drop for Bus {
    /// Stops every axis this client set in motion that is still moving (or whose state cannot be read):
    /// [`Bus::stop_started`].
    fn drop(&mut self) {
        if self.started == 0 {
            return;
        }
        tracing::debug!("the client closes: stopping the axes it moved that still move");
        let report = self.stop_started();
        if report.all_confirmed() {
            tracing::info!("as the client closes: {report}");
        } else {
            tracing::error!("as the client closes: {report}");
        }
    }
}
