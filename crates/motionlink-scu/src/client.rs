//! A session with an SCU control unit over a [`Link`]: remote mode, the RC keepalive, typed reads and writes
//! (every write read back), functions, cyclic objects, verified moves of one or several actuators, streamed
//! setpoints, the error history, and a clean end.
//!
//! ```no_run
//! use motionlink_scu::client::{ClientConfig, FunctionMap, ScuClient};
//! use motionlink_scu::model::Actuator;
//! use motionlink_link::{url::PortUrl, RealClock, SerialSettings};
//!
//! let port: PortUrl = "/dev/ttyUSB0".parse()?;
//! // The unit's parameterisation decides which actuators each function drives; tell the client.
//! let config = ClientConfig { function_map: FunctionMap::scp11(), ..ClientConfig::default() };
//! let client = ScuClient::open_port(&port, SerialSettings::new(38_400), RealClock::shared(), config)?;
//! let a1 = Actuator::new(1).unwrap();
//! let report = client.move_to(a1, 400, 80, &Default::default())?;
//! println!("actuator 1 at {} counts", report.position_counts);
//! // Dropping the client stops anything it started (RS) and leaves remote mode (RA).
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! # How it works
//!
//! The session sends RO with the configured Safety_ID and a first RC, then an RC every
//! [`ClientConfig::keepalive_period`] (200 ms by default; the unit's watchdog is 500 ms). The keepalive runs
//! on a grid of deadlines (the next one is due one period after the last one was *due*, not after it was
//! sent), so it cannot drift. The line is half-duplex, so it is shared through a lock that waits on the
//! session's [`Clock`](motionlink_link::Clock): a caller's request runs on the caller's own thread, and sends
//! a keepalive that fell due first; a background thread sends the keepalive when the line is free. It sleeps
//! until the next one is due: an idle session wakes five times a second.
//!
//! ## Replies, retries and a dead link
//!
//! RO may take the manual's 2000 ms ([`ClientConfig::reply_timeout`]). In remote mode a reply is awaited at
//! most [`SESSION_REPLY_LIMIT`] (1000 ms, twice the unit's watchdog: no RC can go out while a reply is
//! awaited, so a unit that has not answered by then has stopped its drives and left remote mode if it is
//! alive at all). A request is sent again when not one byte of its reply came within
//! [`ClientConfig::retry_after`] (150 ms, or twice the round trip measured so far if that is longer), then
//! after twice and four times that; the reply to any sending counts, and the replies to the others are read
//! and dropped. Before the first repetition the session sends [`FLUSH_LEN`] zero bytes: a request whose
//! length byte was corrupted on the way leaves the unit waiting for more bytes, and would swallow the
//! repetition; the zeros complete that telegram (the unit answers it CSE) or are skipped as garbage.
//! A reply whose length byte disagrees with what the request asks for is rejected at once, and a reply that
//! stops in the middle for as long as the silence window is given up; both are sent again (at most
//! [`ClientConfig::retries`] times, as after a CSE or a PCE, which mean the unit did not execute the request).
//! So a corrupted length byte costs at most one silence window and one repetition, and no command is lost.
//!
//! RE is repeated like the others: every RE names an absolute destination (an end, a stored position, the
//! remote position) or switches a function on, so sending it twice has the effect of sending it once.
//!
//! When a request got no byte at all until its deadline, the line is *silent*: keepalives pause, and each
//! further request (typically the stops of the session's end) gets one sending and [`SILENT_TRY`] (300 ms)
//! to be answered; the first byte from the unit ends that. So on a dead link a command that was moving an
//! actuator gives up within about two seconds: 1000 ms for the request that found the line dead, then one
//! short try of RS and of RA.
//!
//! ## A session the unit ended
//!
//! A unit answers PE to RG, RT, RE and RS when it is not in remote mode: after its watchdog expired, after a
//! reset, after someone else's RA. The session then sends an RC (with Safety_ID 1 and 2 the unit's next RC
//! re-arms the watchdog) and tries once more. If the unit still refuses, it has ended remote mode (with
//! Safety_ID 0 it accepts remote motion only after a new RO): the caller gets [`ScuError::RemoteEnded`],
//! and so does every later request, until the caller calls [`ScuClient::reopen`]. **The session never sends
//! RO by itself**, whether a motion of it was under way or not: the Safety_ID 0 lock is the unit's way of
//! saying that a host lost contact, and only the caller may decide to go on. The one exception is the end of
//! the session ([`ScuClient::close`], drop): when a function it started still needs its RS (the manual wants
//! one after every RE), it sends RO and RC, the RS, and RA; RO there opens remote mode only to stop and
//! leave it. If the unit accepts the repetition after the RC (Safety_ID 1 or 2: its watchdog had expired and
//! stopped the motions), the session stays open, but a caller with a motion under way gets
//! [`ScuError::RemoteEnded`] once, so that it learns its motion was stopped.
//!
//! ## Moves
//!
//! [`ScuClient::move_function`] moves the actuators a function drives, each to its own target, with one RE;
//! [`ScuClient::move_to`] moves one actuator with the function of its number (F1 for A1: SCP11 numbering,
//! or [`MoveOptions::function`]) and gives every actuator that function drives the same target. Which
//! actuators a function drives is the unit's parameterisation, which the data list does not show; the
//! caller says it in [`ClientConfig::function_map`]. Where the map does not know a function, `move_to`
//! writes the target into the remote position of *every* connected actuator (so whatever the function drives
//! goes there, and nothing runs to a stale remote position), watches all of them, and reports each one that
//! moved; it does not guess which ones the function drives.
//!
//! Before anything moves, each target is checked against the actuator's stroke: the virtual limits of its
//! UserPositionData (0x2001..0x2006), or [`ClientConfig::stroke_limits`]; a target outside is refused
//! ([`ScuError::OutsideStroke`]), never clamped. The remote positions and the speed are written and read back;
//! then RE with direction 9. The move polls each [`ClientConfig::poll_interval`] (50 ms): status 1 first,
//! then the positions, so the result is read after the unit reported the end of the motion. It succeeds only
//! if every actuator that was to move ends within [`ClientConfig::position_tolerance_counts`] of its target;
//! then RS. A cancel, a stall, a timeout or any error stops the function at once (fast RS) and reads the
//! status again: an error whose stop the unit did not confirm says so ([`ScuError::StopUnconfirmed`]).
//!
//! ## The end
//!
//! When the session ends (dropped, [`ScuClient::close`], or the process interrupted and the caller drops
//! it), every started function gets its RS (fast stop for motions), then RA. If the port is lost, the
//! session reports it; the unit's watchdog stops the drives; [`ScuClient::reconnect`] (or
//! [`ClientConfig::auto_reconnect`]) opens the port again, sends RO and RC, and RS for the functions that
//! were started.

use std::collections::BTreeSet;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread;
use std::time::Duration;

use motionlink_link::cancel::CancelToken;
use motionlink_link::clock::{lock, ParticipantTicket};
use motionlink_link::clock_lock::ClockLock;
use motionlink_link::link::{Connector, Link, LinkError, SerialSettings};
use motionlink_link::url::PortUrl;
use motionlink_link::{SharedClock, Signal, Timestamp};

use crate::model::{
    item, status1, timing, Actuator, CyclicObject, DataEntry, DataEntryExt, DataIndex, ErrorCode, FlagSet, Flags,
    Function, Item, MotionDirection, MotionFunction, SafetyId, StopMode, UNUSED,
};
use crate::value::{decode_item, SpeedMode, Value};
use crate::wire::{request_to_vec, Command, ReplyDecoder, ReplyShape, Request, Status, WireError, MAX_REQUEST_LEN};

/// The longest keepalive period accepted: the unit's watchdog is 500 ms, and a period must leave room for a
/// reply and the caller's requests in between.
pub const MAX_KEEPALIVE_PERIOD: Duration = Duration::from_millis(timing::WATCHDOG.as_millis() as u64 - 50);

/// The longest a reply is awaited in remote mode: twice the unit's watchdog.
pub const SESSION_REPLY_LIMIT: Duration = Duration::from_millis(2 * timing::WATCHDOG.as_millis() as u64);

/// On a silent line (a request got no byte of reply at all), the time each further request is given.
pub const SILENT_TRY: Duration = Duration::from_millis(300);

/// How many zero bytes are sent before a request is repeated after silence: enough to complete the longest
/// telegram the unit could be waiting for.
pub const FLUSH_LEN: usize = MAX_REQUEST_LEN;

/// The default poll interval of moves: one status and one position read (about 31 bytes, 8 ms at 38400 baud)
/// every 50 ms uses about a sixth of the half-duplex line and leaves the rest to the keepalive and the caller.
pub const DEFAULT_POLL_INTERVAL: Duration = Duration::from_millis(50);

/// Which actuators each motion function F1..F10 drives: the unit's parameterisation, which the data list
/// does not show. A function may be *unknown* (the default for all): then [`ScuClient::move_to`] treats
/// every connected actuator as possibly driven.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FunctionMap([Option<u8>; 10]);

impl FunctionMap {
    /// Nothing known.
    pub const fn unknown() -> Self {
        FunctionMap([None; 10])
    }

    /// SCP11 (the manual's chapter 5): Fn drives An alone for n = 1..6; F7..F10 drive nothing.
    pub fn scp11() -> Self {
        FunctionMap(std::array::from_fn(|i| Some(if i < 6 { 1 << i } else { 0 })))
    }

    /// The emulator's `tlt` preset: F1 drives A1 and A2 together, F2 A1 alone, F3 A2 alone; the others
    /// nothing.
    pub fn tlt() -> Self {
        let mut m = [Some(0); 10];
        m[0] = Some(0b11);
        m[1] = Some(0b01);
        m[2] = Some(0b10);
        FunctionMap(m)
    }

    /// The mapping the public LIFTKIT/TLT drivers assume (the emulator's `liftkit` preset): F1 drives A1, F2
    /// A2, F8 both; the others nothing.
    pub fn liftkit() -> Self {
        let mut m = [Some(0); 10];
        m[0] = Some(0b01);
        m[1] = Some(0b10);
        m[7] = Some(0b11);
        FunctionMap(m)
    }

    /// The map of a preset by name: `scp11`, `tlt`, `liftkit`, or `unknown`.
    pub fn preset(name: &str) -> Option<Self> {
        match name.to_ascii_lowercase().as_str() {
            "scp11" => Some(Self::scp11()),
            "tlt" => Some(Self::tlt()),
            "liftkit" => Some(Self::liftkit()),
            "unknown" => Some(Self::unknown()),
            _ => None,
        }
    }

    /// `function` drives exactly `actuators` (an empty list: nothing).
    pub fn with(mut self, function: MotionFunction, actuators: &[Actuator]) -> Self {
        self.0[usize::from(function.id())] = Some(actuators.iter().fold(0, |m, a| m | 1 << (a.number() - 1)));
        self
    }

    /// The actuators `function` drives, if known.
    pub fn drives(&self, function: MotionFunction) -> Option<Vec<Actuator>> {
        let mask = self.0[usize::from(function.id())]?;
        Some(Actuator::all().filter(|a| mask & 1 << (a.number() - 1) != 0).collect())
    }

    /// Applies one specification: a preset name (`scp11`, `tlt`, `liftkit`, `unknown`) replaces the whole
    /// map; `F1=1,2` (or `F1=1+2`) says what one function drives, `F7=` that it drives nothing.
    pub fn apply(self, spec: &str) -> Result<Self, String> {
        let spec = spec.trim();
        if let Some(m) = Self::preset(spec) {
            return Ok(m);
        }
        let Some((f, list)) = spec.split_once('=') else {
            return Err(format!(
                "{spec:?}: give a preset (scp11, tlt, liftkit, unknown) or a function and its actuators (F1=1,2)"
            ));
        };
        let function = f
            .trim()
            .trim_start_matches(['F', 'f'])
            .parse::<u8>()
            .ok()
            .and_then(MotionFunction::new)
            .ok_or_else(|| format!("{spec:?}: {f:?} is not a motion function F1..F10"))?;
        let mut actuators = Vec::new();
        for part in list.split([',', '+', ' ']).map(str::trim).filter(|p| !p.is_empty()) {
            let a = part
                .trim_start_matches(['A', 'a'])
                .parse::<u8>()
                .ok()
                .and_then(Actuator::new)
                .ok_or_else(|| format!("{spec:?}: {part:?} is not an actuator 1..6"))?;
            if !actuators.contains(&a) {
                actuators.push(a);
            }
        }
        Ok(self.with(function, &actuators))
    }
}

impl Default for FunctionMap {
    /// Nothing known: see [`FunctionMap::unknown`].
    fn default() -> Self {
        Self::unknown()
    }
}

/// The travel range of an actuator, in counts, both ends included.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StrokeLimits {
    /// The lowest position a target may have.
    pub min_counts: i32,
    /// The highest position a target may have.
    pub max_counts: i32,
}

/// Settings of a session. The defaults follow the manual.
#[derive(Debug, Clone)]
pub struct ClientConfig {
    /// What the unit does when the watchdog expires (RO's Safety_ID). Default 0.
    pub safety_id: SafetyId,
    /// Time between RC keepalives. Default 200 ms; more than [`MAX_KEEPALIVE_PERIOD`] is refused.
    pub keepalive_period: Duration,
    /// How long to wait for the reply to RO. Default 2000 ms (the manual's maximum request delay). In remote
    /// mode replies are awaited at most [`SESSION_REPLY_LIMIT`], or this if it is shorter.
    pub reply_timeout: Duration,
    /// A request is sent again when not one byte of its reply has come this long after it was sent (or twice
    /// the longest round trip measured lately, if that is longer), then after twice this, four times this
    /// ... of silence, within the reply timeout. Default 150 ms.
    pub retry_after: Duration,
    /// How many times a request is sent again after a corrupt reply, a CSE or a PCE. Default 2.
    pub retries: u32,
    /// Which actuators each function drives. Default: unknown for every function.
    pub function_map: FunctionMap,
    /// Whether remote speeds are percent or counts per second. Default percent.
    pub speed_mode: SpeedMode,
    /// How close to its target a move must end, in counts, for success. Default 5: real columns read a few
    /// counts off after homing, and 5 counts are 1.5 mm on a TLT column (about 3225 counts per metre).
    pub position_tolerance_counts: u32,
    /// Each actuator's travel range for targets; `None`: read from the unit (the virtual limits of its
    /// UserPositionData; a unit whose virtual limits are both 0 has none, and then only the unit's own ends
    /// bound the motion, which the final position check reports). Default: all `None`.
    pub stroke_limits: [Option<StrokeLimits>; 6],
    /// How often a move polls the actuators. Default [`DEFAULT_POLL_INTERVAL`] (50 ms); 5 ms .. 10 s.
    pub poll_interval: Duration,
    /// A move whose actuator does not advance for this long while its motion bit is set has stalled. Default 3 s.
    pub stall_timeout: Duration,
    /// The longest a move may take. Default 300 s.
    pub move_timeout: Duration,
    /// After RE, how long the motion bit may take to come up before a still-standing actuator is an error.
    /// Default 1 s.
    pub start_grace: Duration,
    /// Reconnect by itself when the port is lost (every [`ClientConfig::reconnect_interval`]). Default off.
    pub auto_reconnect: bool,
    /// Time between automatic reconnection attempts. Default 1 s.
    pub reconnect_interval: Duration,
}

impl Default for ClientConfig {
    fn default() -> Self {
        ClientConfig {
            safety_id: SafetyId::StopAllAndLock,
            keepalive_period: Duration::from_millis(200),
            reply_timeout: timing::MAX_REPLY_DELAY,
            retry_after: Duration::from_millis(150),
            retries: 2,
            function_map: FunctionMap::default(),
            speed_mode: SpeedMode::Percent,
            position_tolerance_counts: 5,
            stroke_limits: [None; 6],
            poll_interval: DEFAULT_POLL_INTERVAL,
            stall_timeout: Duration::from_secs(3),
            move_timeout: Duration::from_secs(300),
            start_grace: Duration::from_secs(1),
            auto_reconnect: false,
            reconnect_interval: Duration::from_secs(1),
        }
    }
}

impl ClientConfig {
    /// Checks every setting; the error names the one that is out of range.
    pub fn validate(&self) -> Result<(), ScuError> {
        let bad = |what: String| Err(ScuError::InvalidArgument(what));
        if self.keepalive_period.is_zero() || self.keepalive_period > MAX_KEEPALIVE_PERIOD {
            return bad(format!(
                "keepalive period {:?} refused: it must be above 0 and at most {:?} (the unit's watchdog is 500 ms)",
                self.keepalive_period, MAX_KEEPALIVE_PERIOD
            ));
        }
        if self.reply_timeout.is_zero() || self.reply_timeout > Duration::from_secs(60) {
            return bad(format!("reply timeout {:?}: it must be above 0 and at most 60 s", self.reply_timeout));
        }
        if self.retry_after.is_zero() || self.retry_after >= self.reply_timeout {
            return bad(format!(
                "retry_after {:?}: it must be above 0 and below the reply timeout {:?}",
                self.retry_after, self.reply_timeout
            ));
        }
        if self.retries > 10 {
            return bad(format!("retries {}: at most 10", self.retries));
        }
        if self.position_tolerance_counts > 10_000 {
            return bad(format!("position tolerance {} counts: at most 10000", self.position_tolerance_counts));
        }
        if !(Duration::from_millis(5)..=Duration::from_secs(10)).contains(&self.poll_interval) {
            return bad(format!("poll interval {:?}: 5 ms to 10 s", self.poll_interval));
        }
        for (what, d) in [
            ("stall timeout", self.stall_timeout),
            ("move timeout", self.move_timeout),
            ("start grace", self.start_grace),
            ("reconnect interval", self.reconnect_interval),
        ] {
            if d.is_zero() {
                return bad(format!("{what} must be above 0"));
            }
        }
        for (i, s) in self.stroke_limits.iter().enumerate() {
            if let Some(s) = s {
                if s.min_counts > s.max_counts {
                    return bad(format!(
                        "stroke of A{}: {} is above {} (give MIN:MAX)",
                        i + 1,
                        s.min_counts,
                        s.max_counts
                    ));
                }
            }
        }
        Ok(())
    }
}

/// What went wrong in a session.
#[derive(Debug, Clone, thiserror::Error)]
pub enum ScuError {
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
    #[error("{0}")]
    Link(String),
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
    /// A value written to the unit reads back different.
    #[error("{name} ({index}): wrote {written}, the unit reads back {read}")]
    ReadBack {
        /// The entry.
        name: &'static str,
        /// Its index.
        index: DataIndex,
        /// What was written.
        written: String,
        /// What the unit returned.
        read: String,
    },
    /// The caller asked for something impossible (bad index, value out of range, read-only entry).
    #[error("{0}")]
    InvalidArgument(String),
    /// A move's target lies outside the actuator's travel range; nothing was moved.
    #[error(
        "target {target_counts} counts for {actuator} refused: it lies outside {actuator}'s stroke \
         {min_counts}..{max_counts} counts ({limits_from}); nothing was moved"
    )]
    OutsideStroke {
        /// The actuator.
        actuator: Actuator,
        /// The target asked for.
        target_counts: i32,
        /// The lower limit.
        min_counts: i32,
        /// The upper limit.
        max_counts: i32,
        /// Where the limits come from.
        limits_from: &'static str,
    },
    /// The actuator is not connected (its status says "drive unavailable").
    #[error("{0} is not connected to the unit (actuator status 1: drive unavailable)")]
    NotConnected(Actuator),
    /// A move ended away from its target; the function was stopped.
    #[error(
        "{actuator} ended at {position_counts} counts, {} counts from its target {target_counts} (more than the \
         tolerance of {tolerance_counts}); last error: {error_code}",
        i64::from(*position_counts) - i64::from(*target_counts)
    )]
    MotionEnded {
        /// The actuator.
        actuator: Actuator,
        /// Where it stopped.
        position_counts: i32,
        /// Where it was going.
        target_counts: i32,
        /// The tolerance of the move.
        tolerance_counts: u32,
        /// Error_Code 1 when it stopped.
        error_code: ErrorCode,
    },
    /// A move's actuator stopped advancing though the unit reports motion; it was stopped.
    #[error("{actuator} stalled at {position_counts} counts (no progress for {after:?} while moving); stopped")]
    Stalled {
        /// The actuator.
        actuator: Actuator,
        /// Where it stalled.
        position_counts: i32,
        /// How long without progress.
        after: Duration,
    },
    /// A move took longer than [`ClientConfig::move_timeout`]; it was stopped.
    #[error("{actuator} did not reach its target within {after:?}; stopped at {position_counts} counts")]
    MoveTimeout {
        /// The actuator.
        actuator: Actuator,
        /// Where it stopped.
        position_counts: i32,
        /// The timeout.
        after: Duration,
    },
    /// The caller cancelled a move (Ctrl-C); the unit confirmed the stop.
    #[error("cancelled; {actuator} stopped at {position_counts} counts")]
    Cancelled {
        /// The actuator.
        actuator: Actuator,
        /// Where it came to rest.
        position_counts: i32,
    },
    /// An action failed, and the stop that followed was not confirmed by the unit.
    #[error(
        "{cause}; then the stop ({stop}) was NOT confirmed by the unit ({detail}): the actuators may still be \
         moving. The unit stops remote motions by itself 500 ms after the last RC it receives (its watchdog); \
         this program sends none once it has ended"
    )]
    StopUnconfirmed {
        /// What went wrong first.
        cause: Box<ScuError>,
        /// The stop that was tried ("RS of F1").
        stop: String,
        /// Why it is not confirmed.
        detail: String,
    },
}

/// The class of a [`ScuError`], for exit codes and retry decisions.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ErrorClass {
    /// The unit refused or reported an error, or a move did not end where it was asked to.
    Device,
    /// The line failed: timeout, corrupt data, port lost, remote mode ended.
    Transport,
    /// The caller asked for something impossible.
    Usage,
    /// The caller cancelled.
    Cancelled,
}

impl ScuError {
    /// What kind of failure this is.
    pub fn class(&self) -> ErrorClass {
        match self {
            ScuError::Refused { .. }
            | ScuError::MotionEnded { .. }
            | ScuError::Stalled { .. }
            | ScuError::MoveTimeout { .. }
            | ScuError::ReadBack { .. }
            | ScuError::NotConnected(_) => ErrorClass::Device,
            ScuError::Timeout { .. }
            | ScuError::Corrupt { .. }
            | ScuError::Link(_)
            | ScuError::SessionLost(_)
            | ScuError::RemoteEnded(_)
            | ScuError::Closed
            | ScuError::UnexpectedReply { .. } => ErrorClass::Transport,
            ScuError::InvalidArgument(_) | ScuError::OutsideStroke { .. } => ErrorClass::Usage,
            ScuError::Cancelled { .. } => ErrorClass::Cancelled,
            ScuError::StopUnconfirmed { cause, .. } => cause.class(),
        }
    }

    /// True if this error says that a stop the client tried was not confirmed: the actuators may be moving.
    pub fn stop_unconfirmed(&self) -> bool {
        matches!(self, ScuError::StopUnconfirmed { .. })
    }
}

impl From<LinkError> for ScuError {
    fn from(e: LinkError) -> Self {
        ScuError::Link(e.to_string())
    }
}

/// Options of a move.
#[derive(Default)]
pub struct MoveOptions<'a> {
    /// Cancels the move (the actuators are stopped).
    pub cancel: Option<&'a CancelToken>,
    /// Called after every poll.
    pub progress: Option<&'a dyn Fn(&MoveProgress)>,
    /// For [`ScuClient::move_to`]: use this function instead of the one with the actuator's number.
    pub function: Option<MotionFunction>,
}

/// Where a move is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MoveProgress {
    /// The actuator the move is about (the one named to `move_to`, the first target of `move_function`).
    pub actuator: Actuator,
    /// Where it is, in counts.
    pub position_counts: i32,
    /// Where it started, in counts.
    pub start_counts: i32,
    /// Where it is going, in counts.
    pub target_counts: i32,
    /// Actuator status 1.
    pub status: u8,
}

/// How one actuator of a move ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ActuatorOutcome {
    /// The actuator.
    pub actuator: Actuator,
    /// Its target, in counts.
    pub target_counts: i32,
    /// Where it started, in counts.
    pub start_counts: i32,
    /// Where it ended (read after the unit reported the end of the motion), in counts.
    pub position_counts: i32,
    /// Whether it moved (its motion bit was seen, or its position changed by more than the tolerance). An
    /// actuator of a function whose drives are unknown that did not move is not driven by it.
    pub moved: bool,
}

impl ActuatorOutcome {
    /// Position minus target, in counts.
    pub fn difference_counts(&self) -> i64 {
        i64::from(self.position_counts) - i64::from(self.target_counts)
    }
}

/// How a move ended.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MoveReport {
    /// The actuator the move is about (the one named to `move_to`, the first target of `move_function`).
    pub actuator: Actuator,
    /// The function that drove it.
    pub function: MotionFunction,
    /// Where that actuator ended, in counts.
    pub position_counts: i32,
    /// How long it took on the session's clock.
    pub duration: Duration,
    /// Every actuator whose remote position the move wrote, in actuator order.
    pub actuators: Vec<ActuatorOutcome>,
}

/// Counters of a session.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ClientStats {
    /// RC keepalives acknowledged.
    pub keepalives: u64,
    /// Requests sent again after silence, a corrupt reply, a CSE or a PCE.
    pub retries: u64,
    /// Times zero bytes were sent to complete a telegram the unit may have been waiting for.
    pub flushes: u64,
    /// Successful reconnections.
    pub reconnects: u64,
    /// Transactions completed (any outcome from the unit).
    pub transactions: u64,
    /// Times remote mode was opened again: by [`ScuClient::reopen`], or to send the RS of the end of a session.
    pub reopens: u64,
    /// Times the unit's watchdog was found expired and re-armed by an RC (Safety_ID 1 and 2).
    pub watchdog_lapses: u64,
}

/// A request owned by a job.
#[derive(Debug, Clone)]
struct OwnedRequest {
    bytes: Vec<u8>,
    command: Command,
    shape: ReplyShape,
    /// The number of data bytes of the ACK, when the request fixes it.
    reply_len: Option<u16>,
    /// RE of this function id (marked started before it is sent).
    starts: Option<u8>,
    /// RS of this function id (unmarked when acknowledged).
    stops: Option<u8>,
}

impl OwnedRequest {
    fn new(r: &Request<'_>) -> Result<Self, ScuError> {
        let reply_len = match r {
            Request::Get { index } => item(DataIndex(*index)).and_then(|it| u16::try_from(it.size()).ok()),
            _ => None,
        };
        Self::with_reply_len(r, reply_len)
    }

    fn with_reply_len(r: &Request<'_>, reply_len: Option<u16>) -> Result<Self, ScuError> {
        let bytes = request_to_vec(r).map_err(|e| ScuError::InvalidArgument(e.to_string()))?;
        Ok(OwnedRequest {
            bytes,
            command: r.command(),
            shape: r.reply_shape(),
            reply_len,
            starts: match r {
                Request::Execute { function, .. } => Some(*function),
                _ => None,
            },
            stops: match r {
                Request::Stop { function, .. } => Some(*function),
                _ => None,
            },
        })
    }

    fn keepalive() -> Self {
        Self::new(&Request::Cyclic { object: UNUSED, write: &[] }).expect("an RC without object encodes")
    }
}

/// A reply owned by the caller.
#[derive(Debug, Clone, PartialEq, Eq)]
struct OwnedReply {
    status: Status,
    data: Option<Vec<u8>>,
}

#[derive(Debug, Clone)]
enum SessionState {
    Open,
    /// The unit ended remote mode; every request fails with this message until `reopen`.
    Ended(String),
    Lost(String),
    Closed,
}

/// The cyclic object the keepalive RC carries.
#[derive(Debug, Clone)]
struct CyclicUse {
    slot: u8,
    object: CyclicObject,
    write: Vec<u8>,
}

/// What the session knows besides the line itself; locked only for short moments.
struct State {
    session: SessionState,
    /// Functions started with RE and not yet stopped with an acknowledged RS (wire ids).
    started: BTreeSet<u8>,
    cyclic: Option<CyclicUse>,
    last_cyclic_read: Option<(Timestamp, Vec<u8>)>,
    stats: ClientStats,
    /// When the next RC is due: a grid of deadlines one period apart.
    keepalive_due: Timestamp,
    /// When the next automatic reconnection may be tried.
    next_reconnect: Timestamp,
}

/// The half-duplex line: one exchange at a time, by a caller or by the keepalive thread.
struct Line {
    link: Option<Box<dyn Link>>,
    connector: Connector,
    decoder: ReplyDecoder,
    /// Replies that may still arrive for a request that was sent more than once.
    late_replies: Option<LateReplies>,
    /// No byte came from the unit during a whole request: keepalives pause, and each request gets one
    /// sending and [`SILENT_TRY`], until the unit is heard again.
    silent: bool,
    /// The longest round trip measured lately (decaying).
    round_trip: Duration,
    /// RO was acknowledged: the unit is (as far as the session knows) in remote mode.
    remote: bool,
}

/// The replies still owed for the other sendings of a request that was answered.
struct LateReplies {
    /// How many.
    count: u32,
    /// They are awaited no longer than this.
    until: Timestamp,
    command: Command,
    shape: ReplyShape,
}

struct Inner {
    clock: SharedClock,
    config: ClientConfig,
    line: ClockLock<Line>,
    state: Mutex<State>,
    stop: AtomicBool,
    wake_keepalive: Signal,
}

/// A session with an SCU control unit. See the [module documentation](self).
pub struct ScuClient {
    inner: Arc<Inner>,
    thread: Option<thread::JoinHandle<()>>,
    description: String,
}

impl std::fmt::Debug for ScuClient {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ScuClient").field("port", &self.description).finish()
    }
}

/// Why one exchange failed.
enum ExchangeError {
    /// Not one byte of a reply in time. `stray`: bytes came, but none that started a reply.
    Silent {
        stray: bool,
    },
    /// A reply started and then stopped for longer than the silence window.
    Incomplete,
    Corrupt(WireError),
    Link(LinkError),
}

impl ScuClient {
    /// Opens a session on a serial port or TCP gateway (`--port` syntax; not `sim`).
    pub fn open_port(
        port: &PortUrl,
        settings: SerialSettings,
        clock: SharedClock,
        config: ClientConfig,
    ) -> Result<Self, ScuError> {
        let port = port.clone();
        let connector: Connector = Box::new(move || port.open_byte_link(settings));
        Self::open(connector, clock, config)
    }

    /// Opens a session: checks the configuration, connects, sends RO with the configured Safety_ID and a
    /// first RC, and starts the keepalive. `connector` is called again to reconnect.
    ///
    /// Requests run on the calling thread; with an auto-advancing
    /// [`ManualClock`](motionlink_link::ManualClock) the calling thread must be one of its participants.
    pub fn open(mut connector: Connector, clock: SharedClock, config: ClientConfig) -> Result<Self, ScuError> {
        config.validate()?;
        let link = connector()?;
        let description = link.describe();
        let now = clock.now();
        let inner = Arc::new(Inner {
            line: ClockLock::new(
                Arc::clone(&clock),
                Line {
                    link: Some(link),
                    connector,
                    decoder: ReplyDecoder::new(),
                    late_replies: None,
                    silent: false,
                    round_trip: Duration::ZERO,
                    remote: false,
                },
            ),
            state: Mutex::new(State {
                session: SessionState::Open,
                started: BTreeSet::new(),
                cyclic: None,
                last_cyclic_read: None,
                stats: ClientStats::default(),
                keepalive_due: now,
                next_reconnect: now,
            }),
            stop: AtomicBool::new(false),
            wake_keepalive: clock.signal(),
            clock,
            config,
        });
        {
            let mut line = inner.line.lock();
            if let Err(e) = inner.open_remote(&mut line) {
                // Nothing was started; a unit that answered RO gets its RA.
                if line.remote {
                    let ra = OwnedRequest::new(&Request::Abort)?;
                    line.silent = true;
                    let _ = inner.exchange_with_retries(&mut line, &ra);
                }
                return Err(e);
            }
        }
        let ticket = inner.clock.reserve_participant();
        let keepalive = Arc::clone(&inner);
        let thread = thread::Builder::new()
            .name("scu-keepalive".into())
            .spawn(move || keepalive.keepalive_loop(ticket))
            .map_err(|e| ScuError::Link(format!("cannot start the keepalive thread: {e}")))?;
        Ok(ScuClient { inner, thread: Some(thread), description })
    }

    /// The port, as the link describes it.
    pub fn port(&self) -> &str {
        &self.description
    }

    /// The session's settings.
    pub fn config(&self) -> &ClientConfig {
        &self.inner.config
    }

    /// The session's clock.
    pub fn clock(&self) -> &SharedClock {
        &self.inner.clock
    }

    /// Counters of the session.
    pub fn stats(&self) -> ClientStats {
        lock(&self.inner.state).stats
    }

    /// Functions started with RE and not yet stopped (wire ids).
    pub fn started_functions(&self) -> Vec<u8> {
        lock(&self.inner.state).started.iter().copied().collect()
    }

    /// True while the session is open (not lost, not ended by the unit, not closed).
    pub fn is_open(&self) -> bool {
        matches!(lock(&self.inner.state).session, SessionState::Open)
    }

    /// Why the session is not open, if it is not: lost, ended by the unit, or closed.
    pub fn not_open_reason(&self) -> Option<String> {
        match &lock(&self.inner.state).session {
            SessionState::Open => None,
            SessionState::Ended(why) => Some(why.clone()),
            SessionState::Lost(why) => Some(format!("session lost: {why}")),
            SessionState::Closed => Some("the session is closed".into()),
        }
    }

    fn transact_owned(&self, owned: &OwnedRequest) -> Result<OwnedReply, ScuError> {
        let reply = self.inner.transact(owned)?;
        if reply.status != Status::Ack {
            return Err(ScuError::Refused { command: owned.command, status: reply.status });
        }
        Ok(reply)
    }

    fn transact(&self, request: &Request<'_>) -> Result<OwnedReply, ScuError> {
        self.transact_owned(&OwnedRequest::new(request)?)
    }

    /// Sends any request and returns the data of its ACK (for what the typed methods do not cover).
    pub fn request(&self, request: &Request<'_>) -> Result<Option<Vec<u8>>, ScuError> {
        Ok(self.transact(request)?.data)
    }

    // ----- data list

    /// Reads the raw bytes of a data index (entry or group).
    pub fn get_raw(&self, index: DataIndex) -> Result<Vec<u8>, ScuError> {
        let reply = self.transact(&Request::Get { index: index.0 })?;
        reply.data.ok_or(ScuError::UnexpectedReply { command: Command::Get, detail: "ACK without data".into() })
    }

    /// Reads an entry or a group, each member decoded.
    pub fn get(&self, index: DataIndex) -> Result<Vec<(&'static DataEntry, Value)>, ScuError> {
        let it = item(index).ok_or_else(|| ScuError::InvalidArgument(format!("{index} is not in the data list")))?;
        let data = self.get_raw(index)?;
        decode_item(it, &data)
            .map_err(|e| ScuError::UnexpectedReply { command: Command::Get, detail: format!("{}: {e}", it.name()) })
    }

    /// Reads one entry.
    pub fn get_value(&self, index: DataIndex) -> Result<Value, ScuError> {
        match item(index) {
            Some(Item::Entry(_)) => Ok(self.get(index)?.remove(0).1),
            Some(Item::Group(g)) => {
                Err(ScuError::InvalidArgument(format!("{index} is the group {}; use get() for groups", g.name)))
            }
            None => Err(ScuError::InvalidArgument(format!("{index} is not in the data list"))),
        }
    }

    /// Checks that `value` may be written to `index` (a remote entry, the value's kind, its range) and encodes
    /// it.
    fn encode_for(&self, index: DataIndex, value: &Value) -> Result<(&'static DataEntry, Vec<u8>), ScuError> {
        let Some(Item::Entry(e)) = item(index) else {
            return Err(ScuError::InvalidArgument(format!("{index} is not a single data-list entry")));
        };
        if !e.index().is_remote() {
            return Err(ScuError::InvalidArgument(format!(
                "{} ({index}) is read-only: only remote data (0x3xxx) can be written",
                e.name
            )));
        }
        if !value.fits(e.kind) {
            return Err(ScuError::InvalidArgument(format!(
                "{} is a {} entry; a {} value does not fit",
                e.name,
                e.kind.data_type(),
                value.kind_name()
            )));
        }
        value
            .check_range(self.inner.config.speed_mode)
            .map_err(|err| ScuError::InvalidArgument(format!("{}: {err}", e.name)))?;
        let mut data = Vec::with_capacity(e.size());
        value.encode(e.kind, &mut data);
        Ok((e, data))
    }

    /// Writes a remote data entry (0x3xxx) after checking the value's kind and range, then reads it back: a
    /// value that reads back different is [`ScuError::ReadBack`].
    pub fn set(&self, index: DataIndex, value: &Value) -> Result<(), ScuError> {
        let (_, data) = self.encode_for(index, value)?;
        self.set_raw(index, &data)
    }

    /// Writes raw bytes to a data index (no checks but the unit's), then reads the index back where the data
    /// list has it (every remote entry and group is readable): a mismatch is [`ScuError::ReadBack`].
    pub fn set_raw(&self, index: DataIndex, data: &[u8]) -> Result<(), ScuError> {
        self.transact(&Request::Transfer { index: index.0, data })?;
        let Some(it) = item(index) else { return Ok(()) };
        let read = self.get_raw(index)?;
        if read != data {
            let show = |bytes: &[u8]| match decode_item(it, bytes) {
                Ok(v) => v.iter().map(|(_, v)| v.to_string()).collect::<Vec<_>>().join(", "),
                Err(_) => format!("{bytes:02X?}"),
            };
            return Err(ScuError::ReadBack { name: it.name(), index, written: show(data), read: show(&read) });
        }
        Ok(())
    }

    /// Writes a remote entry without reading it back (streamed setpoints).
    fn write_unverified(&self, index: DataIndex, value: &Value) -> Result<(), ScuError> {
        let (_, data) = self.encode_for(index, value)?;
        self.transact(&Request::Transfer { index: index.0, data: &data }).map(|_| ())
    }

    /// Actuator `a`'s position in counts.
    pub fn position(&self, a: Actuator) -> Result<i32, ScuError> {
        match self.get_value(a.position_index())? {
            Value::PositionCounts(p) => Ok(p),
            other => Err(ScuError::UnexpectedReply { command: Command::Get, detail: format!("position {other:?}") }),
        }
    }

    /// Every actuator's position (0x0010), in counts, A1 first.
    pub fn positions(&self) -> Result<[i32; 6], ScuError> {
        let data = self.get_raw(DataIndex(0x0010))?;
        if data.len() != 24 {
            return Err(ScuError::UnexpectedReply {
                command: Command::Get,
                detail: "positions are 6 x 4 bytes".into(),
            });
        }
        Ok(std::array::from_fn(|i| {
            i32::from_le_bytes([data[4 * i], data[4 * i + 1], data[4 * i + 2], data[4 * i + 3]])
        }))
    }

    /// Actuator `a`'s status 1.
    pub fn status1(&self, a: Actuator) -> Result<Flags, ScuError> {
        let data = self.get_raw(a.status1_index())?;
        let [bits] = data[..] else {
            return Err(ScuError::UnexpectedReply { command: Command::Get, detail: "status is one byte".into() });
        };
        Ok(Flags { set: FlagSet::ActuatorStatus1, bits: u32::from(bits) })
    }

    /// Every actuator's status 1 (0x0170), A1 first.
    pub fn statuses(&self) -> Result<[u8; 6], ScuError> {
        let data = self.get_raw(DataIndex(0x0170))?;
        <[u8; 6]>::try_from(&data[..])
            .map_err(|_| ScuError::UnexpectedReply { command: Command::Get, detail: "status 1 is 6 x 1 byte".into() })
    }

    /// The actuators whose status 1 says "drive available".
    pub fn connected_actuators(&self) -> Result<Vec<Actuator>, ScuError> {
        let s = self.statuses()?;
        Ok(Actuator::all().filter(|a| s[usize::from(a.number() - 1)] & status1::AVAILABLE != 0).collect())
    }

    /// Actuator `a`'s travel range for targets: [`ClientConfig::stroke_limits`] if set, else the virtual limits
    /// of its UserPositionData (0x2001..0x2006) as the unit reports them; `None` if the unit has none (both 0).
    pub fn stroke_limits(&self, a: Actuator) -> Result<Option<(StrokeLimits, &'static str)>, ScuError> {
        if let Some(s) = self.inner.config.stroke_limits[usize::from(a.number() - 1)] {
            return Ok(Some((s, "as configured")));
        }
        match self.get_value(DataIndex(0x2000 + u16::from(a.number())))? {
            Value::UserPositions(u) => {
                let (lo, hi) = (u.virtual_limit_in_counts, u.virtual_limit_out_counts);
                if (lo, hi) == (0, 0) {
                    Ok(None)
                } else if lo > hi {
                    Err(ScuError::UnexpectedReply {
                        command: Command::Get,
                        detail: format!("{a}'s virtual limits {lo}..{hi} are reversed"),
                    })
                } else {
                    Ok(Some((
                        StrokeLimits { min_counts: lo, max_counts: hi },
                        "the virtual limits of its UserPositionData",
                    )))
                }
            }
            other => Err(ScuError::UnexpectedReply {
                command: Command::Get,
                detail: format!("UserPositionData of {a}: {other:?}"),
            }),
        }
    }

    /// Refuses `target` for `a` if it lies outside its travel range.
    fn check_stroke(&self, a: Actuator, target: i32) -> Result<(), ScuError> {
        if let Some((s, limits_from)) = self.stroke_limits(a)? {
            if !(s.min_counts..=s.max_counts).contains(&target) {
                return Err(ScuError::OutsideStroke {
                    actuator: a,
                    target_counts: target,
                    min_counts: s.min_counts,
                    max_counts: s.max_counts,
                    limits_from,
                });
            }
        }
        Ok(())
    }

    /// Error_Code 1 (most recent) to 5 (oldest).
    pub fn error_history(&self) -> Result<[ErrorCode; 5], ScuError> {
        let data = self.get_raw(DataIndex(0x00D0))?;
        if data.len() != 20 {
            return Err(ScuError::UnexpectedReply {
                command: Command::Get,
                detail: "error codes are 5 x 4 bytes".into(),
            });
        }
        Ok(std::array::from_fn(|i| {
            ErrorCode(u32::from_le_bytes([data[4 * i], data[4 * i + 1], data[4 * i + 2], data[4 * i + 3]]))
        }))
    }

    // ----- functions

    /// RE on a motion function: its drives move as `direction` says, at the function's remote speed.
    pub fn start_motion(&self, function: MotionFunction, direction: MotionDirection) -> Result<(), ScuError> {
        self.transact(&Request::Execute { function: function.id(), params: [direction.code(), UNUSED] }).map(|_| ())
    }

    /// RS on a motion function.
    pub fn stop_motion(&self, function: MotionFunction, mode: StopMode) -> Result<(), ScuError> {
        self.transact(&Request::Stop { function: function.id(), param: mode.code() }).map(|_| ())
    }

    /// Switches a non-motion function (buzzer, outputs, emergency stop, LEDs) on (RE) or off (RS).
    pub fn switch(&self, function: Function, on: bool) -> Result<(), ScuError> {
        if let Function::Motion(m) = function {
            return Err(ScuError::InvalidArgument(format!("{m} is a motion function: use start_motion/stop_motion")));
        }
        let id = function.id();
        let r = if on {
            Request::Execute { function: id, params: [UNUSED, UNUSED] }
        } else {
            Request::Stop { function: id, param: UNUSED }
        };
        self.transact(&r).map(|_| ())
    }

    // ----- cyclic objects

    /// Defines CyclicObj `slot` (1..5) on the unit (and reads the definition back).
    pub fn configure_cyclic(&self, slot: u8, object: &CyclicObject) -> Result<(), ScuError> {
        let index = Self::cyclic_index(slot)?;
        self.set(index, &Value::CyclicObject(*object))
    }

    fn cyclic_index(slot: u8) -> Result<DataIndex, ScuError> {
        if (1..=5).contains(&slot) {
            Ok(DataIndex(0x3000 + u16::from(slot)))
        } else {
            Err(ScuError::InvalidArgument(format!("cyclic object {slot}: there are CyclicObj 1..5")))
        }
    }

    /// The entries a cyclic object writes, groups expanded into their members, in order.
    fn cyclic_write_entries(object: &CyclicObject) -> Result<Vec<&'static DataEntry>, ScuError> {
        let mut entries = Vec::new();
        for idx in object.write_indices() {
            match item(idx) {
                Some(Item::Entry(e)) => entries.push(e),
                Some(Item::Group(g)) => entries.extend(g.members()),
                None => {
                    return Err(ScuError::InvalidArgument(format!("cyclic write index {idx} is not in the data list")))
                }
            }
        }
        Ok(entries)
    }

    fn encode_cyclic_write(object: &CyclicObject, write: &[Value], mode: SpeedMode) -> Result<Vec<u8>, ScuError> {
        let entries = Self::cyclic_write_entries(object)?;
        if entries.len() != write.len() {
            return Err(ScuError::InvalidArgument(format!(
                "the cyclic object writes {} value(s) (a group counts each of its entries); {} given",
                entries.len(),
                write.len()
            )));
        }
        let mut bytes = Vec::new();
        for (e, v) in entries.iter().zip(write) {
            if !e.index().is_remote() {
                return Err(ScuError::InvalidArgument(format!("{}: cyclic write data must be remote data", e.name)));
            }
            if !v.fits(e.kind) {
                return Err(ScuError::InvalidArgument(format!("{}: a {} value does not fit", e.name, v.kind_name())));
            }
            v.check_range(mode).map_err(|err| ScuError::InvalidArgument(format!("{}: {err}", e.name)))?;
            v.encode(e.kind, &mut bytes);
        }
        Ok(bytes)
    }

    fn read_cyclic_definition(&self, slot: u8) -> Result<CyclicObject, ScuError> {
        let index = Self::cyclic_index(slot)?;
        let Value::CyclicObject(object) = self.get_value(index)? else {
            return Err(ScuError::UnexpectedReply { command: Command::Get, detail: "not a cyclic object".into() });
        };
        Ok(object)
    }

    /// From now on every keepalive RC carries CyclicObj `slot` with `write` (one value per entry its definition
    /// writes, a group counting each of its members; the definition is read from the unit). The latest read
    /// data is available from [`ScuClient::last_cyclic_read`]. Keepalive writes are not read back.
    pub fn use_cyclic(&self, slot: u8, write: &[Value]) -> Result<(), ScuError> {
        let object = self.read_cyclic_definition(slot)?;
        let bytes = Self::encode_cyclic_write(&object, write, self.inner.config.speed_mode)?;
        lock(&self.inner.state).cyclic = Some(CyclicUse { slot, object, write: bytes });
        Ok(())
    }

    /// Keepalive RCs carry no cyclic object again.
    pub fn stop_cyclic(&self) {
        lock(&self.inner.state).cyclic = None;
    }

    /// One RC with CyclicObj `slot` now: writes `write`, returns the read data decoded (groups member by
    /// member).
    pub fn exchange_cyclic(&self, slot: u8, write: &[Value]) -> Result<Vec<(&'static DataEntry, Value)>, ScuError> {
        let object = self.read_cyclic_definition(slot)?;
        let bytes = Self::encode_cyclic_write(&object, write, self.inner.config.speed_mode)?;
        let read_len = object.read_size().and_then(|n| u16::try_from(n).ok());
        let request = OwnedRequest::with_reply_len(&Request::Cyclic { object: slot - 1, write: &bytes }, read_len)?;
        let reply = self.transact_owned(&request)?;
        decode_cyclic_read(&object, reply.data.as_deref().unwrap_or_default())
    }

    /// The read data of the latest keepalive RC that carried a cyclic object, with its time.
    pub fn last_cyclic_read(&self) -> Option<(Timestamp, Vec<(&'static DataEntry, Value)>)> {
        let st = lock(&self.inner.state);
        let (t, data) = st.last_cyclic_read.clone()?;
        let object = st.cyclic.as_ref()?.object;
        drop(st);
        decode_cyclic_read(&object, &data).ok().map(|v| (t, v))
    }

    // ----- moves

    /// Checks a speed for a move or a stream: 1 up to the speed mode's maximum (0 would never move).
    fn check_move_speed(&self, speed: u16) -> Result<(), ScuError> {
        let mode = self.inner.config.speed_mode;
        if speed == 0 || speed > mode.max() {
            return Err(ScuError::InvalidArgument(format!(
                "speed {speed} {}: a motion needs 1..{} {}",
                mode.unit(),
                mode.max(),
                mode.unit()
            )));
        }
        Ok(())
    }

    /// Moves `actuator` to `target_counts` at `speed` (percent, or counts/s per [`ClientConfig::speed_mode`])
    /// with the function of the same number (F1 for A1; [`MoveOptions::function`] names another). Every
    /// actuator that function drives gets the same target: the ones [`ClientConfig::function_map`] names, or,
    /// where the map does not know the function, every connected actuator (its remote position is written; an
    /// actuator the function does not drive stays where it is and is reported as not moved). See
    /// [`ScuClient::move_function`] for how the move runs and ends.
    pub fn move_to(
        &self,
        actuator: Actuator,
        target_counts: i32,
        speed: u16,
        options: &MoveOptions<'_>,
    ) -> Result<MoveReport, ScuError> {
        self.check_move_speed(speed)?;
        let function = match options.function {
            Some(f) => f,
            None => MotionFunction::new(actuator.number())
                .ok_or_else(|| ScuError::InvalidArgument(format!("{actuator} has no function of its number")))?,
        };
        match self.inner.config.function_map.drives(function) {
            Some(drives) => {
                if !drives.contains(&actuator) {
                    return Err(ScuError::InvalidArgument(format!(
                        "{function} does not drive {actuator}: the function map says it drives {}; name the \
                         function that does",
                        list_actuators(&drives)
                    )));
                }
                let targets: Vec<_> = drives.iter().map(|a| (*a, target_counts)).collect();
                self.run_move(function, actuator, &targets, false, speed, options)
            }
            None => {
                let connected = self.connected_actuators()?;
                if !connected.contains(&actuator) {
                    return Err(ScuError::NotConnected(actuator));
                }
                let targets: Vec<_> = connected.iter().map(|a| (*a, target_counts)).collect();
                self.run_move(function, actuator, &targets, true, speed, options)
            }
        }
    }

    /// Moves the actuators `function` drives, each to its own target, with one RE: checks every target against
    /// its actuator's stroke (nothing moves if one is outside), writes and reads back each remote position
    /// and the function's remote speed, starts the function with direction 9, polls every
    /// [`ClientConfig::poll_interval`] (status 1 first, then the positions), and when the unit reports that
    /// none of them moves any more reads where each ended. It succeeds if each is within
    /// [`ClientConfig::position_tolerance_counts`] of its target, and ends the function with RS. A cancel, a
    /// stall, a timeout or any error stops the function at once (fast RS); if the unit does not confirm that
    /// stop, the error is [`ScuError::StopUnconfirmed`].
    ///
    /// If [`ClientConfig::function_map`] knows `function`, `targets` must name exactly the actuators it
    /// drives.
    pub fn move_function(
        &self,
        function: MotionFunction,
        targets: &[(Actuator, i32)],
        speed: u16,
        options: &MoveOptions<'_>,
    ) -> Result<MoveReport, ScuError> {
        self.check_move_speed(speed)?;
        let Some(&(primary, _)) = targets.first() else {
            return Err(ScuError::InvalidArgument("a move needs at least one actuator and its target".into()));
        };
        self.check_targets_match_map(function, &targets.iter().map(|(a, _)| *a).collect::<Vec<_>>())?;
        self.run_move(function, primary, targets, false, speed, options)
    }

    fn check_targets_match_map(&self, function: MotionFunction, actuators: &[Actuator]) -> Result<(), ScuError> {
        for (i, a) in actuators.iter().enumerate() {
            if actuators[..i].contains(a) {
                return Err(ScuError::InvalidArgument(format!("{a} is named twice")));
            }
        }
        if let Some(drives) = self.inner.config.function_map.drives(function) {
            if let Some(a) = actuators.iter().find(|a| !drives.contains(a)) {
                return Err(ScuError::InvalidArgument(format!(
                    "{function} does not drive {a}: the function map says it drives {}",
                    list_actuators(&drives)
                )));
            }
            if let Some(d) = drives.iter().find(|d| !actuators.contains(d)) {
                return Err(ScuError::InvalidArgument(format!(
                    "{function} also drives {d} (the function map says it drives {}): give {d} a target too",
                    list_actuators(&drives)
                )));
            }
        }
        Ok(())
    }

    fn run_move(
        &self,
        function: MotionFunction,
        primary: Actuator,
        targets: &[(Actuator, i32)],
        drives_unknown: bool,
        speed: u16,
        options: &MoveOptions<'_>,
    ) -> Result<MoveReport, ScuError> {
        let started_at = self.inner.clock.now();
        // Everything that can refuse the move is checked before the unit is told anything.
        let status = self.statuses()?;
        // The named actuator first, so that its own problem is the one reported.
        let mut order: Vec<(Actuator, i32)> = targets.to_vec();
        order.sort_by_key(|(a, _)| *a != primary);
        for (a, target) in order {
            if status[usize::from(a.number() - 1)] & status1::AVAILABLE == 0 {
                return Err(ScuError::NotConnected(a));
            }
            match self.check_stroke(a, target) {
                Err(e @ ScuError::OutsideStroke { .. }) if drives_unknown && a != primary => {
                    return Err(ScuError::InvalidArgument(format!(
                        "{e}. The function map does not say which actuators {function} drives, so every connected \
                         actuator gets the target; say which ones it drives (ClientConfig::function_map, \
                         --functions)"
                    )));
                }
                other => other?,
            }
        }
        let start = self.positions()?;
        for &(a, target) in targets {
            self.set(a.remote_position_index(), &Value::RemotePosition(target))?;
        }
        self.set(function.remote_speed_index(), &Value::RemoteSpeed(speed))?;
        // An RE that failed (refused, a lost or corrupt reply) may still have started the motion: it gets its
        // RS like any other failure.
        let watch: Vec<Actuator> = targets.iter().map(|(a, _)| *a).collect();
        let result = self
            .start_motion(function, MotionDirection::RemotePosition)
            .and_then(|()| self.await_motion(primary, targets, &start, drives_unknown, started_at, options));
        match result {
            Ok(actuators) => {
                // Every RE is ended with an RS, even after the drives stopped by themselves.
                self.stop_motion(function, StopMode::Soft)?;
                let position_counts =
                    actuators.iter().find(|o| o.actuator == primary).map_or(start[0], |o| o.position_counts);
                Ok(MoveReport {
                    actuator: primary,
                    function,
                    position_counts,
                    duration: self.inner.clock.now() - started_at,
                    actuators,
                })
            }
            Err(e) => Err(self.stop_after_failure(function, &watch, e)),
        }
    }

    /// Waits until `until` on the session's clock; true if `cancel` was set meanwhile (noticed within 10 ms).
    fn wait_or_cancel(&self, signal: &Signal, until: Timestamp, cancel: Option<&CancelToken>) -> bool {
        loop {
            if cancel.is_some_and(CancelToken::is_cancelled) {
                return true;
            }
            let now = self.inner.clock.now();
            if now >= until {
                return false;
            }
            signal.wait_until(Some(until.min(now + Duration::from_millis(10))));
        }
    }

    /// Polls until the unit reports that none of the actuators of `targets` moves, then judges where they
    /// ended.
    fn await_motion(
        &self,
        primary: Actuator,
        targets: &[(Actuator, i32)],
        start: &[i32; 6],
        drives_unknown: bool,
        started_at: Timestamp,
        options: &MoveOptions<'_>,
    ) -> Result<Vec<ActuatorOutcome>, ScuError> {
        let config = &self.inner.config;
        let tolerance = i64::from(config.position_tolerance_counts);
        let idx = |a: Actuator| usize::from(a.number() - 1);
        let single = match targets {
            [(a, _)] => Some(*a),
            _ => None,
        };
        let primary_target = targets.iter().find(|(a, _)| *a == primary).map_or(0, |(_, t)| *t);
        let signal = self.inner.clock.signal();
        let mut seen_motion = [false; 6];
        let mut last_position = *start;
        let mut last_progress_at = [started_at; 6];
        let mut next_poll = started_at + config.poll_interval;
        loop {
            if self.wait_or_cancel(&signal, next_poll, options.cancel) {
                // Stop first; where it came to rest is read after the stop.
                return Err(ScuError::Cancelled { actuator: primary, position_counts: last_position[idx(primary)] });
            }
            let now = self.inner.clock.now();
            // The next poll is due one interval after this one was due (no drift), and never in the past.
            while next_poll <= now {
                next_poll += config.poll_interval;
            }
            // Status first, positions after: positions read after a status without motion are final.
            let (status, positions) = match single {
                Some(a) => {
                    let mut status = [0u8; 6];
                    let mut positions = *start;
                    status[idx(a)] = self.status1(a)?.bits as u8;
                    positions[idx(a)] = self.position(a)?;
                    (status, positions)
                }
                None => (self.statuses()?, self.positions()?),
            };
            if let Some(report) = options.progress {
                report(&MoveProgress {
                    actuator: primary,
                    position_counts: positions[idx(primary)],
                    start_counts: start[idx(primary)],
                    target_counts: primary_target,
                    status: status[idx(primary)],
                });
            }
            if options.cancel.is_some_and(CancelToken::is_cancelled) {
                return Err(ScuError::Cancelled { actuator: primary, position_counts: positions[idx(primary)] });
            }
            let now = self.inner.clock.now();
            let mut moving = false;
            for &(a, _) in targets {
                if status[idx(a)] & status1::MOTION != 0 {
                    seen_motion[idx(a)] = true;
                    moving = true;
                }
            }
            if !moving {
                let outcomes: Vec<ActuatorOutcome> = targets
                    .iter()
                    .map(|&(a, target)| ActuatorOutcome {
                        actuator: a,
                        target_counts: target,
                        start_counts: start[idx(a)],
                        position_counts: positions[idx(a)],
                        moved: seen_motion[idx(a)]
                            || (i64::from(positions[idx(a)]) - i64::from(start[idx(a)])).abs() > tolerance,
                    })
                    .collect();
                // Where the drives are unknown, an actuator that did not move is not driven by the function.
                let must_arrive = |o: &ActuatorOutcome| !drives_unknown || o.actuator == primary || o.moved;
                let off = outcomes.iter().find(|o| must_arrive(o) && o.difference_counts().abs() > tolerance);
                match off {
                    None => return Ok(outcomes),
                    Some(o) if seen_motion.iter().any(|s| *s) || now - started_at >= config.start_grace => {
                        let error_code = self.error_history().map(|h| h[0]).unwrap_or_default();
                        return Err(ScuError::MotionEnded {
                            actuator: o.actuator,
                            position_counts: o.position_counts,
                            target_counts: o.target_counts,
                            tolerance_counts: config.position_tolerance_counts,
                            error_code,
                        });
                    }
                    // The unit has not raised the motion bit yet.
                    Some(_) => continue,
                }
            }
            for &(a, _) in targets {
                let i = idx(a);
                if positions[i] != last_position[i] {
                    last_position[i] = positions[i];
                    last_progress_at[i] = now;
                } else if status[i] & status1::MOTION != 0 && now - last_progress_at[i] >= config.stall_timeout {
                    tracing::warn!("{a} stalled at {}", positions[i]);
                    return Err(ScuError::Stalled {
                        actuator: a,
                        position_counts: positions[i],
                        after: now - last_progress_at[i],
                    });
                }
            }
            if now - started_at >= config.move_timeout {
                return Err(ScuError::MoveTimeout {
                    actuator: primary,
                    position_counts: positions[idx(primary)],
                    after: config.move_timeout,
                });
            }
        }
    }

    /// After `cause` ended an action of `function`: fast RS, then the status of `watch` until none of them
    /// moves. Returns the error to report: `cause` (a cancel with the position where it came to rest) when
    /// the stop was confirmed, [`ScuError::StopUnconfirmed`] otherwise.
    fn stop_after_failure(&self, function: MotionFunction, watch: &[Actuator], cause: ScuError) -> ScuError {
        let stop = format!("fast RS of {function}");
        if let Err(e) = self.stop_motion(function, StopMode::Fast) {
            tracing::error!("could not stop {function} after a failed action: {e}");
            return ScuError::StopUnconfirmed { cause: Box::new(cause), stop, detail: e.to_string() };
        }
        match self.confirm_at_rest(watch, StopMode::Fast) {
            Ok(positions) => match cause {
                ScuError::Cancelled { actuator, .. } => {
                    ScuError::Cancelled { actuator, position_counts: positions[usize::from(actuator.number() - 1)] }
                }
                other => other,
            },
            Err(detail) => ScuError::StopUnconfirmed { cause: Box::new(cause), stop, detail },
        }
    }

    /// Reads the status of `watch` until none reports motion (500 ms at most after a fast stop, 3 s after a
    /// soft one, which follows the unit's stop ramp), then the positions.
    fn confirm_at_rest(&self, watch: &[Actuator], mode: StopMode) -> Result<[i32; 6], String> {
        let signal = self.inner.clock.signal();
        let patience = match mode {
            StopMode::Fast => Duration::from_millis(500),
            StopMode::Soft => Duration::from_secs(3),
        };
        let give_up = self.inner.clock.now() + patience;
        loop {
            let status = self.statuses().map_err(|e| format!("the status could not be read: {e}"))?;
            let moving: Vec<Actuator> =
                watch.iter().copied().filter(|a| status[usize::from(a.number() - 1)] & status1::MOTION != 0).collect();
            if moving.is_empty() {
                return self.positions().map_err(|e| format!("the positions could not be read: {e}"));
            }
            let now = self.inner.clock.now();
            if now >= give_up {
                return Err(format!("{} still report(s) motion after the RS", list_actuators(&moving)));
            }
            signal.wait_until(Some((now + self.inner.config.poll_interval).min(give_up)));
        }
    }

    /// Prepares streamed setpoints (as a ros2_control hardware interface sends them, 10..100 times a second)
    /// for `function` driving `actuators` at `speed`: checks the actuators (connected; exactly the ones the
    /// function map says the function drives, if it knows it), reads their strokes, and writes the speed
    /// (read back). Nothing moves until the first [`SetpointStream::set_targets`].
    pub fn stream(
        &self,
        function: MotionFunction,
        actuators: &[Actuator],
        speed: u16,
    ) -> Result<SetpointStream<'_>, ScuError> {
        self.check_move_speed(speed)?;
        if actuators.is_empty() {
            return Err(ScuError::InvalidArgument("a stream needs at least one actuator".into()));
        }
        self.check_targets_match_map(function, actuators)?;
        let connected = self.connected_actuators()?;
        if let Some(a) = actuators.iter().find(|a| !connected.contains(a)) {
            return Err(ScuError::NotConnected(*a));
        }
        let limits = actuators.iter().map(|a| self.stroke_limits(*a)).collect::<Result<Vec<_>, _>>()?;
        self.set(function.remote_speed_index(), &Value::RemoteSpeed(speed))?;
        Ok(SetpointStream { client: self, function, actuators: actuators.to_vec(), limits, started: false })
    }

    // ----- session

    /// Opens the port again (after a loss): RO, RC, and RS for every function that was started.
    pub fn reconnect(&self) -> Result<(), ScuError> {
        self.inner.reconnect(&mut self.inner.line.lock())
    }

    /// Opens remote mode again after the unit ended it ([`ScuError::RemoteEnded`]): RO, RC, and RS for every
    /// function this session started. This is the caller's decision to go on; the session never takes it by
    /// itself.
    pub fn reopen(&self) -> Result<(), ScuError> {
        let mut line = self.inner.line.lock();
        if line.link.is_none() {
            return Err(ScuError::SessionLost("port not connected".into()));
        }
        self.inner.reopen(&mut line)
    }

    /// Ends the session: RS for every started function (motions fast), then RA. The session is closed even if
    /// that fails; the error says what could not be sent.
    pub fn close(mut self) -> Result<(), ScuError> {
        let r = self.close_inner();
        self.stop_thread();
        r
    }

    fn close_inner(&self) -> Result<(), ScuError> {
        if matches!(lock(&self.inner.state).session, SessionState::Closed) {
            return Ok(());
        }
        let mut line = self.inner.line.lock();
        let r = self.inner.close(&mut line);
        lock(&self.inner.state).session = SessionState::Closed;
        r
    }

    fn stop_thread(&mut self) {
        self.inner.stop.store(true, Ordering::SeqCst);
        self.inner.wake_keepalive.raise();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for ScuClient {
    fn drop(&mut self) {
        if self.thread.is_some() {
            if let Err(e) = self.close_inner() {
                tracing::warn!("closing the SCU session: {e}");
            }
            self.stop_thread();
        }
    }
}

/// Streamed setpoints of one function, made by [`ScuClient::stream`]. Each update writes the remote positions
/// and starts the function towards them again (RE with direction 9: the unit takes the remote positions when
/// RE comes); a new speed applies to the running motion along the ramp. Dropping the stream stops the
/// function (fast RS) if it was started.
pub struct SetpointStream<'c> {
    client: &'c ScuClient,
    function: MotionFunction,
    actuators: Vec<Actuator>,
    limits: Vec<Option<(StrokeLimits, &'static str)>>,
    started: bool,
}

impl std::fmt::Debug for SetpointStream<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SetpointStream").field("function", &self.function).field("actuators", &self.actuators).finish()
    }
}

impl SetpointStream<'_> {
    /// The function it drives.
    pub fn function(&self) -> MotionFunction {
        self.function
    }

    /// The actuators, in the order targets are given.
    pub fn actuators(&self) -> &[Actuator] {
        &self.actuators
    }

    /// New targets, one per actuator in the order of [`SetpointStream::actuators`]: each is checked against its
    /// stroke (an error moves nothing new), written, and the function is started towards them. The remote
    /// positions are not read back (that would halve the rate); the CRC of every telegram and the unit's ACK
    /// are the check, and [`SetpointStream::positions`] shows where the actuators are.
    pub fn set_targets(&mut self, targets: &[i32]) -> Result<(), ScuError> {
        if targets.len() != self.actuators.len() {
            return Err(ScuError::InvalidArgument(format!(
                "{} target(s) given; {} drives {}: one each",
                targets.len(),
                self.function,
                list_actuators(&self.actuators)
            )));
        }
        for ((a, limits), &t) in self.actuators.iter().zip(&self.limits).zip(targets) {
            if let Some((s, limits_from)) = limits {
                if !(s.min_counts..=s.max_counts).contains(&t) {
                    return Err(ScuError::OutsideStroke {
                        actuator: *a,
                        target_counts: t,
                        min_counts: s.min_counts,
                        max_counts: s.max_counts,
                        limits_from,
                    });
                }
            }
        }
        for (a, &t) in self.actuators.iter().zip(targets) {
            self.client.write_unverified(a.remote_position_index(), &Value::RemotePosition(t))?;
        }
        self.started = true;
        self.client.start_motion(self.function, MotionDirection::RemotePosition)
    }

    /// A new speed for the running motion (and the next ones); the unit follows it along its ramp.
    pub fn set_speed(&mut self, speed: u16) -> Result<(), ScuError> {
        self.client.check_move_speed(speed)?;
        self.client.write_unverified(self.function.remote_speed_index(), &Value::RemoteSpeed(speed))
    }

    /// Where each actuator is, in counts, and whether it moves.
    pub fn positions(&self) -> Result<Vec<(Actuator, i32, bool)>, ScuError> {
        let status = self.client.statuses()?;
        let positions = self.client.positions()?;
        Ok(self
            .actuators
            .iter()
            .map(|a| {
                let i = usize::from(a.number() - 1);
                (*a, positions[i], status[i] & status1::MOTION != 0)
            })
            .collect())
    }

    /// Ends the stream: RS (`mode`), then the status until no actuator moves; returns where each came to rest.
    /// A stop the unit did not confirm is [`ScuError::StopUnconfirmed`].
    pub fn stop(mut self, mode: StopMode) -> Result<Vec<(Actuator, i32)>, ScuError> {
        let stop = format!("RS of {}", self.function);
        self.started = false;
        let result = self
            .client
            .stop_motion(self.function, mode)
            .map_err(|e| e.to_string())
            .and_then(|()| self.client.confirm_at_rest(&self.actuators, mode));
        match result {
            Ok(p) => Ok(self.actuators.iter().map(|a| (*a, p[usize::from(a.number() - 1)])).collect()),
            Err(detail) => Err(ScuError::StopUnconfirmed {
                cause: Box::new(ScuError::InvalidArgument("the stream ended".into())),
                stop,
                detail,
            }),
        }
    }

    /// Stops the function after `cause` ended the stream: fast RS and the status; the error to report.
    pub fn abort(mut self, cause: ScuError) -> ScuError {
        self.started = false;
        self.client.stop_after_failure(self.function, &self.actuators, cause)
    }
}

impl Drop for SetpointStream<'_> {
    fn drop(&mut self) {
        if self.started {
            if let Err(e) = self.client.stop_motion(self.function, StopMode::Fast) {
                tracing::error!("could not stop {} when its stream was dropped: {e}", self.function);
            }
        }
    }
}

/// "A1, A2".
fn list_actuators(actuators: &[Actuator]) -> String {
    if actuators.is_empty() {
        return "no actuator".into();
    }
    actuators.iter().map(Actuator::to_string).collect::<Vec<_>>().join(", ")
}

fn decode_cyclic_read(object: &CyclicObject, data: &[u8]) -> Result<Vec<(&'static DataEntry, Value)>, ScuError> {
    let mut out = Vec::new();
    let mut at = 0;
    for idx in object.read_indices() {
        let it = item(idx).ok_or_else(|| ScuError::InvalidArgument(format!("{idx} is not in the data list")))?;
        let end = at + it.size();
        let chunk = data.get(at..end).ok_or_else(|| ScuError::UnexpectedReply {
            command: Command::Cyclic,
            detail: format!("{} bytes of read data, the object needs more", data.len()),
        })?;
        out.extend(
            decode_item(it, chunk)
                .map_err(|e| ScuError::UnexpectedReply { command: Command::Cyclic, detail: e.to_string() })?,
        );
        at = end;
    }
    Ok(out)
}

// ---------------------------------------------------------------------------------------------------------
// The line and the keepalive

impl Inner {
    /// The keepalive thread: sends the RC when one is due and the line is free (a caller holding the line sends
    /// it itself before its next exchange), and reconnects if told to.
    fn keepalive_loop(&self, ticket: ParticipantTicket) {
        let _participant = ticket.enter();
        while !self.stop.load(Ordering::SeqCst) {
            let now = self.clock.now();
            let wake_at = {
                let st = lock(&self.state);
                match st.session {
                    SessionState::Open => Some(st.keepalive_due),
                    SessionState::Lost(_) if self.config.auto_reconnect => Some(st.next_reconnect),
                    _ => None,
                }
            };
            match wake_at {
                Some(t) if now >= t => match self.line.try_lock() {
                    Some(mut line) => {
                        if line.link.is_some() {
                            self.keepalive_if_due(&mut line);
                        } else {
                            self.try_auto_reconnect(&mut line);
                        }
                    }
                    // A caller is using the line: look again shortly.
                    None => {
                        self.wake_keepalive.wait_until(Some(now + self.config.keepalive_period / 8));
                    }
                },
                other => {
                    self.wake_keepalive.wait_until(other);
                }
            }
        }
    }

    fn lost(&self, line: &mut Line, why: String) -> ScuError {
        tracing::warn!("SCU session lost: {why}");
        line.link = None;
        line.remote = false;
        let mut st = lock(&self.state);
        st.session = SessionState::Lost(why.clone());
        st.next_reconnect = self.clock.now() + self.config.reconnect_interval;
        ScuError::SessionLost(why)
    }

    /// The unit ended remote mode: the session says so to every later request.
    fn ended(&self, line: &mut Line, why: String) -> ScuError {
        tracing::warn!("{why}");
        line.remote = false;
        lock(&self.state).session = SessionState::Ended(why.clone());
        ScuError::RemoteEnded(why)
    }

    /// RO (sent again on no answer: a unit asleep after a long silence often ignores the first) and RC.
    fn open_remote(&self, line: &mut Line) -> Result<(), ScuError> {
        line.remote = false;
        let ro = OwnedRequest::new(&Request::Open { safety_id: self.config.safety_id.code() })?;
        let reply = self.exchange_with_retries(line, &ro)?;
        if reply.status != Status::Ack {
            return Err(ScuError::Refused { command: Command::Open, status: reply.status });
        }
        line.remote = true;
        // The unit's watchdog runs from when it received the RC, which is about when it was sent.
        let rc_sent = self.clock.now();
        let reply = self.exchange_with_retries(line, &OwnedRequest::keepalive())?;
        if reply.status != Status::Ack {
            return Err(ScuError::Refused { command: Command::Cyclic, status: reply.status });
        }
        lock(&self.state).keepalive_due = rc_sent + self.config.keepalive_period;
        Ok(())
    }

    /// Sends the RC (with the cyclic object in use) if one is due. The next one is due one period after this
    /// one was due, so the keepalive keeps its rhythm; one that fell more than a period behind (a long
    /// exchange held the line) is not made up for with a burst.
    fn keepalive_if_due(&self, line: &mut Line) {
        let now = self.clock.now();
        let period = self.config.keepalive_period;
        let cyclic = {
            let mut st = lock(&self.state);
            if !matches!(st.session, SessionState::Open) || now < st.keepalive_due || line.link.is_none() {
                return;
            }
            while st.keepalive_due <= now {
                st.keepalive_due += period;
            }
            if line.silent {
                // The unit has not been heard for a whole request: its watchdog is left to expire (it stops
                // the drives); the caller's next request tries the line.
                return;
            }
            st.cyclic.clone()
        };
        let request = match &cyclic {
            Some(c) => {
                let read_len = c.object.read_size().and_then(|n| u16::try_from(n).ok());
                OwnedRequest::with_reply_len(&Request::Cyclic { object: c.slot - 1, write: &c.write }, read_len)
            }
            None => Ok(OwnedRequest::keepalive()),
        };
        let Ok(rc) = request else { return };
        match self.exchange_with_retries(line, &rc) {
            Ok(reply) if reply.status == Status::Ack => {
                let mut st = lock(&self.state);
                st.stats.keepalives += 1;
                if let (Some(_), Some(data)) = (&cyclic, reply.data) {
                    st.last_cyclic_read = Some((self.clock.now(), data));
                }
            }
            // The caller's next request finds out what it means (PE: remote mode ended).
            Ok(reply) => tracing::warn!("keepalive RC refused: {}", reply.status),
            // A lost port has already been recorded; a unit that did not answer (or answered garbage) is
            // not a lost port: the caller learns of it from its own request; close and drop still send RS
            // and RA.
            Err(e) => tracing::warn!("keepalive failed: {e}"),
        }
    }

    /// One request of a caller, on the caller's thread.
    fn transact(&self, request: &OwnedRequest) -> Result<OwnedReply, ScuError> {
        let check = || match &lock(&self.state).session {
            SessionState::Open => Ok(()),
            SessionState::Ended(why) => Err(ScuError::RemoteEnded(why.clone())),
            SessionState::Lost(why) => Err(ScuError::SessionLost(why.clone())),
            SessionState::Closed => Err(ScuError::Closed),
        };
        check()?;
        let mut line = self.line.lock();
        // The line is ours: a keepalive that fell due goes first.
        self.keepalive_if_due(&mut line);
        check()?;
        if line.link.is_none() {
            return Err(ScuError::SessionLost("port not connected".into()));
        }
        self.transact_on(&mut line, request)
    }

    /// One request on a line already held: marks RE as started, RS as stopped when acknowledged.
    fn transact_on(&self, line: &mut Line, request: &OwnedRequest) -> Result<OwnedReply, ScuError> {
        if let Some(f) = request.starts {
            // Counted as started before it is sent: a lost reply may hide a started motion.
            lock(&self.state).started.insert(f);
        }
        let reply = self.exchange_checked(line, request)?;
        let mut st = lock(&self.state);
        if reply.status == Status::Ack {
            if let Some(f) = request.stops {
                st.started.remove(&f);
            }
        }
        st.stats.transactions += 1;
        Ok(reply)
    }

    /// Sends `request`; a PE (the unit is not in remote mode, or refuses an RE) is looked into: see the module
    /// documentation, "A session the unit ended".
    fn exchange_checked(&self, line: &mut Line, request: &OwnedRequest) -> Result<OwnedReply, ScuError> {
        let reply = self.exchange_with_retries(line, request)?;
        if reply.status != Status::PermissionError || matches!(request.command, Command::Open | Command::Abort) {
            return Ok(reply);
        }
        // An RC is accepted in every state of remote mode (and re-arms the watchdog with Safety_ID 1 and 2);
        // a unit that refuses it has left remote mode altogether.
        let rc = self.exchange_with_retries(line, &OwnedRequest::keepalive())?;
        if rc.status == Status::PermissionError {
            return Err(self.ended(
                line,
                format!(
                    "the unit has left remote mode: it refused {} and even RC with PE (it was reset, or another \
                     host sent RA); the session does not open remote mode again by itself",
                    request.command
                ),
            ));
        }
        // Once more: the request itself, or for an RE or an RC a read that only remote mode allows.
        let probe = match request.command {
            Command::Get | Command::Transfer | Command::Stop => request.clone(),
            _ => OwnedRequest::new(&Request::Get { index: Actuator::new(1).map_or(0x0171, |a| a.status1_index().0) })?,
        };
        let again = self.exchange_with_retries(line, &probe)?;
        if again.status == Status::PermissionError {
            return Err(self.ended(
                line,
                format!(
                    "the unit ended remote mode: it takes RC but refuses {} with PE, as after a communication \
                     time-out with Safety_ID 0 (the unit then stops every motion and accepts remote motion only \
                     after a new RO); the session does not open remote mode again by itself",
                    request.command
                ),
            ));
        }
        // The unit answers again after the RC: its watchdog had expired (Safety_ID 1 or 2) and the RC re-armed
        // it -- or, for an RE, remote mode is fine and the unit refuses that function for its own reasons.
        let reply = match request.command {
            Command::Execute => {
                let retried = self.exchange_with_retries(line, request)?;
                if retried.status == Status::PermissionError {
                    return Ok(retried);
                }
                retried
            }
            Command::Cyclic => self.exchange_with_retries(line, request)?,
            _ => again,
        };
        let started_before: Vec<u8> = {
            let mut st = lock(&self.state);
            st.stats.watchdog_lapses += 1;
            st.started.iter().copied().filter(|f| Some(*f) != request.starts).collect()
        };
        if !started_before.is_empty() {
            // The unit stopped them; each still gets the RS the manual asks for after every RE.
            for f in &started_before {
                if let Err(e) = self.stop_function(line, *f) {
                    tracing::warn!("RS of function id {f} after the watchdog lapse: {e}");
                }
            }
            let stopped = match self.config.safety_id {
                SafetyId::StopRemoteOnly => "the remote motions",
                _ => "every motion",
            };
            return Err(ScuError::RemoteEnded(format!(
                "the unit's communication watchdog had expired (it refused {} with PE until an RC re-armed it, as \
                 with Safety_ID {}): it stopped {stopped}, including what this session had started",
                request.command,
                self.config.safety_id.code()
            )));
        }
        tracing::warn!("the unit's watchdog had expired while the session was idle; an RC re-armed it");
        Ok(reply)
    }

    /// Sends `request` until it is answered, repeating it after silence, a corrupt or incomplete reply, a CSE
    /// or a PCE; see the module documentation, "Replies, retries and a dead link".
    fn exchange_with_retries(&self, line: &mut Line, request: &OwnedRequest) -> Result<OwnedReply, ScuError> {
        self.drain_late_replies(line, request.command);
        let first_sent = self.clock.now();
        let mut limit = self.config.reply_timeout;
        if line.remote && request.command != Command::Open {
            limit = limit.min(SESSION_REPLY_LIMIT);
        }
        let single_try = line.silent;
        if single_try {
            limit = limit.min(SILENT_TRY);
        }
        let deadline = first_sent + limit;
        let mut attempts = 0;
        let mut repairs = 0;
        let mut silent_resends = 0u32;
        let mut heard_anything = false;
        let mut flushed = false;
        let mut silence_window =
            if single_try { limit } else { self.config.retry_after.max(line.round_trip.saturating_mul(2)) };
        loop {
            attempts += 1;
            let may_repair = repairs < self.config.retries;
            let last_sent = if attempts == 1 { first_sent } else { self.clock.now() };
            let outcome = self.exchange(line, request, deadline, silence_window);
            let now = self.clock.now();
            match outcome {
                Ok(reply) => {
                    line.silent = false;
                    // A clean sample when the request went out once; else the time since the first sending
                    // (an upper bound: the reply may answer a later sending).
                    let sample = now - first_sent;
                    line.round_trip =
                        if sample > line.round_trip { sample } else { (line.round_trip * 7 + sample) / 8 };
                    if matches!(reply.status, Status::ChecksumError | Status::ParameterCountError)
                        && may_repair
                        && now < deadline
                    {
                        // The unit did not execute the request (a CSE, or a PCE for a count that a corrupt
                        // byte changed): send it again.
                        tracing::debug!("{} answered {}; sending again", request.command, reply.status);
                        repairs += 1;
                    } else {
                        if silent_resends > 0 || flushed {
                            // The unit may answer the other sendings too, as late as it answered this one.
                            let late_by = now - first_sent;
                            line.late_replies = Some(LateReplies {
                                count: silent_resends,
                                until: last_sent + late_by + self.config.retry_after,
                                command: request.command,
                                shape: request.shape,
                            });
                        }
                        return Ok(reply);
                    }
                }
                Err(ExchangeError::Link(e)) => {
                    if e.is_disconnect() || matches!(e, LinkError::Io { .. }) {
                        return Err(self.lost(line, e.to_string()));
                    }
                    return Err(ScuError::from(e));
                }
                Err(ExchangeError::Silent { stray }) if !single_try && now < deadline => {
                    heard_anything |= stray;
                    tracing::debug!("no reply to {} yet; sending again", request.command);
                    if !flushed {
                        self.flush(line);
                        flushed = true;
                    }
                    if !stray {
                        silent_resends += 1;
                    }
                    silence_window = silence_window.saturating_mul(2);
                    // Nothing is discarded: the reply to the first sending may still come, and counts.
                    lock(&self.state).stats.retries += 1;
                    continue;
                }
                Err(ExchangeError::Incomplete) if !single_try && may_repair && now < deadline => {
                    heard_anything = true;
                    tracing::debug!("the reply to {} stopped in the middle; sending again", request.command);
                    repairs += 1;
                }
                Err(ExchangeError::Corrupt(e)) if !single_try && may_repair && now < deadline => {
                    heard_anything = true;
                    tracing::debug!("corrupt reply to {} ({e}); sending again", request.command);
                    repairs += 1;
                }
                Err(ExchangeError::Silent { stray }) => {
                    if !stray && !heard_anything {
                        line.silent = true;
                    }
                    return Err(ScuError::Timeout { command: request.command, timeout: limit, attempts });
                }
                Err(ExchangeError::Incomplete) => {
                    return Err(ScuError::Timeout { command: request.command, timeout: limit, attempts });
                }
                Err(ExchangeError::Corrupt(error)) => {
                    return Err(ScuError::Corrupt { command: request.command, error, attempts })
                }
            }
            lock(&self.state).stats.retries += 1;
            if let Some(link) = line.link.as_mut() {
                let _ = link.discard_input();
            }
            line.decoder.reset();
        }
    }

    /// Sends [`FLUSH_LEN`] zero bytes: a telegram the unit holds half-received (its length byte was corrupted
    /// on the way, so it waits for more) is completed and answered CSE; a unit that holds nothing skips them as
    /// garbage. Zero is no command letter, so the bytes never start a telegram.
    fn flush(&self, line: &mut Line) {
        if let Some(link) = line.link.as_mut() {
            if link.send(&[0u8; FLUSH_LEN]).is_ok() {
                lock(&self.state).stats.flushes += 1;
            }
        }
    }

    /// Before a request of `command`: reads and drops the late replies to the other sendings of an earlier
    /// request of the same command, or what arrives until they are no longer expected. Late replies of another
    /// command cannot be taken for the reply of this one (the decoder skips them), so they are not waited for.
    fn drain_late_replies(&self, line: &mut Line, command: Command) {
        let Some(late) = line.late_replies.take() else { return };
        if late.command != command {
            if self.clock.now() < late.until {
                line.late_replies = Some(late);
            }
            return;
        }
        let Line { link: Some(link), decoder, .. } = line else { return };
        decoder.reset();
        decoder.expect(late.command, late.shape);
        let mut owed = late.count;
        let mut buf = [0u8; 256];
        while owed > 0 {
            let now = self.clock.now();
            if now >= late.until {
                break;
            }
            let Ok(n) = link.recv(&mut buf, late.until - now) else { break };
            let mut input = &buf[..n];
            while !input.is_empty() {
                let (used, event) = decoder.decode(input);
                input = &input[used..];
                match event {
                    Some(Ok(_)) => {
                        tracing::debug!("late reply to {} dropped", late.command);
                        owed = owed.saturating_sub(1);
                    }
                    None if used == 0 => break,
                    _ => {}
                }
            }
        }
        decoder.reset();
    }

    /// One sending of a request, and its reply. Without a byte of reply for `window` (or until `deadline`),
    /// [`ExchangeError::Silent`]; a reply that has started must go on arriving: a pause of `window` inside it is
    /// [`ExchangeError::Incomplete`].
    fn exchange(
        &self,
        line: &mut Line,
        request: &OwnedRequest,
        deadline: Timestamp,
        window: Duration,
    ) -> Result<OwnedReply, ExchangeError> {
        let Line { link, decoder, .. } = line;
        let Some(link) = link.as_mut() else {
            return Err(ExchangeError::Link(LinkError::Disconnected {
                port: "scu".into(),
                reason: "not connected".into(),
            }));
        };
        decoder.reset();
        match request.reply_len {
            Some(n) => decoder.expect_len(request.command, request.shape, n),
            None => decoder.expect(request.command, request.shape),
        }
        link.send(&request.bytes).map_err(ExchangeError::Link)?;
        let mut progress_at = self.clock.now();
        let mut heard = false;
        let mut stray = false;
        let mut buf = [0u8; 256];
        loop {
            let now = self.clock.now();
            let until = (progress_at + window).min(deadline);
            if now >= until {
                return Err(if heard { ExchangeError::Incomplete } else { ExchangeError::Silent { stray } });
            }
            let n = link.recv(&mut buf, until - now).map_err(ExchangeError::Link)?;
            stray |= n > 0;
            let mut input = &buf[..n];
            loop {
                let (used, event) = decoder.decode(input);
                input = &input[used..];
                match event {
                    Some(Ok(reply)) => {
                        return Ok(OwnedReply { status: reply.status, data: reply.data.map(<[u8]>::to_vec) });
                    }
                    Some(Err(WireError::Garbage { count })) => tracing::trace!("{count} stray byte(s) skipped"),
                    Some(Err(e)) => return Err(ExchangeError::Corrupt(e)),
                    None if input.is_empty() => break,
                    None => {}
                }
            }
            // The unit is answering once the start of a reply is in; each byte of it restarts the window.
            if n > 0 && decoder.is_mid_telegram() {
                heard = true;
                progress_at = self.clock.now();
            }
        }
    }

    fn try_auto_reconnect(&self, line: &mut Line) {
        let now = self.clock.now();
        {
            let mut st = lock(&self.state);
            if now < st.next_reconnect {
                return;
            }
            st.next_reconnect = now + self.config.reconnect_interval;
        }
        if let Err(e) = self.reconnect(line) {
            tracing::info!("reconnect failed: {e}");
        }
    }

    fn reconnect(&self, line: &mut Line) -> Result<(), ScuError> {
        // Close the old port first: a serial device can be opened only once.
        line.link = None;
        line.silent = false;
        let attempt = (line.connector)().map_err(ScuError::from).and_then(|mut link| {
            let _ = link.discard_input();
            line.link = Some(link);
            line.decoder.reset();
            self.open_remote(line)
        });
        if let Err(e) = attempt {
            // Without a port the session is lost (and the keepalive thread sleeps until the next attempt).
            let _ = self.lost(line, format!("reconnect failed: {e}"));
            return Err(e);
        }
        lock(&self.state).stats.reconnects += 1;
        self.after_reopen(line)
    }

    /// RO and RC after the unit ended remote mode, and RS for what was started.
    fn reopen(&self, line: &mut Line) -> Result<(), ScuError> {
        tracing::warn!("opening remote mode again (RO, RC)");
        line.silent = false;
        self.open_remote(line)?;
        lock(&self.state).stats.reopens += 1;
        self.after_reopen(line)
    }

    fn after_reopen(&self, line: &mut Line) -> Result<(), ScuError> {
        let started: Vec<u8> = {
            let mut st = lock(&self.state);
            st.session = SessionState::Open;
            st.started.iter().copied().collect()
        };
        // Every RE needs its RS, even when the unit already stopped the drive (the watchdog did).
        let mut first_error = None;
        for f in started {
            if let Err(e) = self.stop_function(line, f) {
                first_error.get_or_insert(e);
            }
        }
        first_error.map_or(Ok(()), Err)
    }

    fn stop_function(&self, line: &mut Line, f: u8) -> Result<(), ScuError> {
        let param = if f <= 9 { StopMode::Fast.code() } else { UNUSED };
        let rs = OwnedRequest::new(&Request::Stop { function: f, param })?;
        let reply = self.transact_on(line, &rs)?;
        if reply.status == Status::Ack {
            Ok(())
        } else {
            Err(ScuError::Refused { command: Command::Stop, status: reply.status })
        }
    }

    fn close(&self, line: &mut Line) -> Result<(), ScuError> {
        if line.link.is_none() {
            return Err(ScuError::SessionLost("port not connected: the unit's watchdog stops the drives".into()));
        }
        let (started, mut ended): (Vec<u8>, bool) = {
            let st = lock(&self.state);
            (st.started.iter().copied().collect(), matches!(st.session, SessionState::Ended(_)))
        };
        let mut first_error = None;
        if !ended {
            for f in &started {
                match self.stop_function(line, *f) {
                    Ok(()) => {}
                    Err(ScuError::RemoteEnded(_)) => {
                        ended = true;
                        break;
                    }
                    Err(e) => {
                        tracing::error!("RS of function id {f} failed: {e}");
                        first_error.get_or_insert(e);
                    }
                }
            }
        }
        if ended && !lock(&self.state).started.is_empty() {
            // The unit ended remote mode, and a function still needs the RS the manual asks for after every RE:
            // remote mode is opened only to send it, and left at once.
            tracing::warn!("the unit ended remote mode; opening it to send the RS of what this session started");
            if let Err(e) = self.reopen(line) {
                first_error.get_or_insert(e);
            }
        }
        let ra = OwnedRequest::new(&Request::Abort)?;
        match self.exchange_with_retries(line, &ra) {
            Ok(r) if r.status == Status::Ack => {}
            Ok(r) => {
                first_error.get_or_insert(ScuError::Refused { command: Command::Abort, status: r.status });
            }
            Err(e) => {
                first_error.get_or_insert(e);
            }
        }
        line.link = None;
        line.remote = false;
        first_error.map_or(Ok(()), Err)
    }
}
