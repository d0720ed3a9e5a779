//! A session with an SCU control unit over a [`Link`]: remote mode, the RC keepalive, typed reads and writes,
//! functions, cyclic objects, moves, the error history, and a clean end.
//!
//! ```no_run
//! use motionlink_scu::client::{ClientConfig, ScuClient};
//! use motionlink_scu::model::Actuator;
//! use motionlink_link::{url::PortUrl, RealClock, SerialSettings};
//!
//! let port: PortUrl = "/dev/ttyUSB0".parse()?;
//! let client = ScuClient::open_port(&port, SerialSettings::new(38_400), RealClock::shared(), ClientConfig::default())?;
//! let a1 = Actuator::new(1).unwrap();
//! let report = client.move_to(a1, 400, 80, &Default::default())?;
//! println!("actuator 1 at {} counts", report.position_counts);
//! // Dropping the client stops anything it started (RS) and leaves remote mode (RA).
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! # How it works
//!
//! The session sends RO and a first RC, then an RC every [`ClientConfig::keepalive_period`] (200 ms by
//! default; the unit's watchdog is 500 ms). The line is half-duplex, so it is shared through a lock that waits
//! on the session's [`Clock`](motionlink_link::Clock): a caller's request runs on the caller's own thread (no
//! hand-over to another thread, which would cost two wake-ups per request), and sends a keepalive that fell due
//! first; a background thread sends the keepalive when the line is free. It sleeps until the next one is due:
//! an idle session wakes five times a second and costs no measurable CPU.
//!
//! A reply must come within [`ClientConfig::reply_timeout`] (2000 ms, the manual's maximum request delay)
//! of the request's first sending. Requests that can be repeated safely (RO, RA, RC, RG, RT, RS) are sent
//! again when not one byte of the reply came within [`ClientConfig::retry_after`] (150 ms), then after
//! 300 ms, 600 ms ... of silence until the reply timeout (a lost byte costs 150 ms, not the unit's 500 ms
//! watchdog; a slow unit still has its 2000 ms, and the reply to any sending counts; the replies to the
//! other sendings are read and dropped before the next request), and up to [`ClientConfig::retries`] times
//! after a corrupt reply or a CSE. RE is never repeated unless the unit answered CSE (it then did not execute
//! it): a lost reply to RE may mean the motion started. Every function the session sent RE for, answered or
//! not, counts as started until an RS for it is acknowledged.
//!
//! While the session waits for the reply to an RE no RC can go out, so a unit that never answers it lets its
//! watchdog expire; with Safety_ID 0 it then refuses everything but RO, RA and RC with PE. Whenever the unit
//! answers PE, the session opens remote mode again (RO, RC) and sends the request once more, unless it is an
//! RE: so the RS of a started function always reaches the unit.
//!
//! When the session ends (dropped, [`ScuClient::close`], or the process interrupted and the caller drops it),
//! every started function gets its RS (fast stop for motions), then RA. If the port is lost, the session
//! reports it; the unit's watchdog stops the drives; [`ScuClient::reconnect`] (or
//! [`ClientConfig::auto_reconnect`]) opens the port again, sends RO and RC, and sends RS for the functions
//! that were started.

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
    item, status1, timing, Actuator, CyclicObject, DataEntry, DataIndex, ErrorCode, FlagSet, Flags, Function, Item,
    MotionDirection, MotionFunction, SafetyId, StopMode, UNUSED,
};
use crate::value::{decode_item, SpeedMode, Value};
use crate::wire::{request_to_vec, Command, ReplyDecoder, ReplyShape, Request, Status, WireError};

/// The longest keepalive period accepted: the unit's watchdog is 500 ms, and a period must leave room for a
/// reply and the caller's requests in between.
pub const MAX_KEEPALIVE_PERIOD: Duration = Duration::from_millis(timing::WATCHDOG.as_millis() as u64 - 50);

/// Which motion function drives each actuator, for [`ScuClient::move_to`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FunctionMap([MotionFunction; 6]);

impl FunctionMap {
    /// SCP11: actuator n on function Fn.
    pub fn scp11() -> Self {
        FunctionMap(std::array::from_fn(|i| MotionFunction::new(i as u8 + 1).expect("1..6 are motion functions")))
    }

    /// Drives `actuator` with `function`.
    pub fn with(mut self, actuator: Actuator, function: MotionFunction) -> Self {
        self.0[usize::from(actuator.number()) - 1] = function;
        self
    }

    /// The function that drives `actuator`.
    pub fn function_for(&self, actuator: Actuator) -> MotionFunction {
        self.0[usize::from(actuator.number()) - 1]
    }
}

impl Default for FunctionMap {
    fn default() -> Self {
        Self::scp11()
    }
}

/// Settings of a session. The defaults follow the manual.
#[derive(Debug, Clone)]
pub struct ClientConfig {
    /// What the unit does when the watchdog expires (RO's Safety_ID). Default 0.
    pub safety_id: SafetyId,
    /// Time between RC keepalives. Default 200 ms; more than [`MAX_KEEPALIVE_PERIOD`] is refused.
    pub keepalive_period: Duration,
    /// How long to wait for a reply. Default 2000 ms (the manual's maximum request delay).
    pub reply_timeout: Duration,
    /// A request that may be repeated is sent again when not one byte of its reply has come this long after
    /// it was sent, then after twice this, four times this ... of silence, within the reply timeout. Default
    /// 150 ms: the unit's watchdog expires 500 ms after the last RC, so waiting the full reply timeout for a
    /// reply that was lost would always cost the session; a unit that is answering (bytes are arriving) is
    /// given the full reply timeout.
    pub retry_after: Duration,
    /// How many times an idempotent request is sent again after a corrupt reply, and any request after a
    /// CSE. Default 2.
    pub retries: u32,
    /// Which function drives each actuator. Default SCP11.
    pub function_map: FunctionMap,
    /// Whether remote speeds are percent or counts per second. Default percent.
    pub speed_mode: SpeedMode,
    /// How close to its target a move must end, in counts. Default 5 (units read a few counts off at the In end).
    pub position_tolerance_counts: u32,
    /// How often a move polls the actuator. Default 100 ms.
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
            function_map: FunctionMap::scp11(),
            speed_mode: SpeedMode::Percent,
            position_tolerance_counts: 5,
            poll_interval: Duration::from_millis(100),
            stall_timeout: Duration::from_secs(3),
            move_timeout: Duration::from_secs(300),
            start_grace: Duration::from_secs(1),
            auto_reconnect: false,
            reconnect_interval: Duration::from_secs(1),
        }
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
        /// The reply timeout.
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
    /// The session is lost (port gone or unit silent) and not reconnected.
    #[error("session lost: {0}")]
    SessionLost(String),
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
    /// The caller asked for something impossible (bad index, value out of range, read-only entry).
    #[error("{0}")]
    InvalidArgument(String),
    /// A move ended away from its target.
    #[error(
        "{actuator} stopped at {position_counts} counts, not at its target {target_counts}; last error: {error_code}"
    )]
    MotionEnded {
        /// The actuator.
        actuator: Actuator,
        /// Where it stopped.
        position_counts: i32,
        /// Where it was going.
        target_counts: i32,
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
    /// The caller cancelled a move (Ctrl-C); the actuator was stopped.
    #[error("cancelled; {actuator} stopped at {position_counts} counts")]
    Cancelled {
        /// The actuator.
        actuator: Actuator,
        /// Where it was when stopped.
        position_counts: i32,
    },
}

/// The class of a [`ScuError`], for exit codes and retry decisions.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ErrorClass {
    /// The unit refused or reported an error.
    Device,
    /// The line failed: timeout, corrupt data, port lost.
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
            | ScuError::MoveTimeout { .. } => ErrorClass::Device,
            ScuError::Timeout { .. }
            | ScuError::Corrupt { .. }
            | ScuError::Link(_)
            | ScuError::SessionLost(_)
            | ScuError::Closed
            | ScuError::UnexpectedReply { .. } => ErrorClass::Transport,
            ScuError::InvalidArgument(_) => ErrorClass::Usage,
            ScuError::Cancelled { .. } => ErrorClass::Cancelled,
        }
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
    /// Cancels the move (the actuator is stopped).
    pub cancel: Option<&'a CancelToken>,
    /// Called after every poll.
    pub progress: Option<&'a dyn Fn(&MoveProgress)>,
    /// Use this function instead of the one [`ClientConfig::function_map`] names.
    pub function: Option<MotionFunction>,
}

/// Where a move is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MoveProgress {
    /// The actuator.
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

/// How a move ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MoveReport {
    /// The actuator.
    pub actuator: Actuator,
    /// The function that drove it.
    pub function: MotionFunction,
    /// Where it ended, in counts.
    pub position_counts: i32,
    /// How long it took on the session's clock.
    pub duration: Duration,
}

/// Counters of a session.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ClientStats {
    /// RC keepalives acknowledged.
    pub keepalives: u64,
    /// Requests sent again after silence, a corrupt reply or a CSE.
    pub retries: u64,
    /// Successful reconnections.
    pub reconnects: u64,
    /// Transactions completed (any outcome from the unit).
    pub transactions: u64,
    /// Times remote mode was opened again after the unit answered PE (it had left remote mode).
    pub reopens: u64,
}

/// A request owned by a job.
#[derive(Debug, Clone)]
struct OwnedRequest {
    bytes: Vec<u8>,
    command: Command,
    shape: ReplyShape,
    repeatable: bool,
    /// RE of this function id (marked started before it is sent).
    starts: Option<u8>,
    /// RS of this function id (unmarked when acknowledged).
    stops: Option<u8>,
}

impl OwnedRequest {
    fn new(r: &Request<'_>) -> Result<Self, ScuError> {
        let bytes = request_to_vec(r).map_err(|e| ScuError::InvalidArgument(e.to_string()))?;
        let command = r.command();
        Ok(OwnedRequest {
            bytes,
            command,
            shape: r.reply_shape(),
            repeatable: command != Command::Execute,
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
    /// When the next RC is due.
    next_keepalive: Timestamp,
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

    /// Opens a session: connects, sends RO with the configured Safety_ID and a first RC, and starts the
    /// keepalive. `connector` is called again to reconnect.
    ///
    /// Requests run on the calling thread; with an auto-advancing
    /// [`ManualClock`](motionlink_link::ManualClock) the calling thread must be one of its participants.
    pub fn open(mut connector: Connector, clock: SharedClock, config: ClientConfig) -> Result<Self, ScuError> {
        if config.keepalive_period.is_zero() || config.keepalive_period > MAX_KEEPALIVE_PERIOD {
            return Err(ScuError::InvalidArgument(format!(
                "keepalive period {:?} refused: it must be above 0 and at most {:?} (the unit's watchdog is 500 ms)",
                config.keepalive_period, MAX_KEEPALIVE_PERIOD
            )));
        }
        if config.reply_timeout.is_zero() {
            return Err(ScuError::InvalidArgument("reply timeout must be above 0".into()));
        }
        let link = connector()?;
        let description = link.describe();
        let now = clock.now();
        let inner = Arc::new(Inner {
            line: ClockLock::new(
                Arc::clone(&clock),
                Line { link: Some(link), connector, decoder: ReplyDecoder::new(), late_replies: None },
            ),
            state: Mutex::new(State {
                session: SessionState::Open,
                started: BTreeSet::new(),
                cyclic: None,
                last_cyclic_read: None,
                stats: ClientStats::default(),
                next_keepalive: now,
                next_reconnect: now,
            }),
            stop: AtomicBool::new(false),
            wake_keepalive: clock.signal(),
            clock,
            config,
        });
        inner.open_remote(&mut inner.line.lock())?;
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

    /// True while the session is open (not lost, not closed).
    pub fn is_open(&self) -> bool {
        matches!(lock(&self.inner.state).session, SessionState::Open)
    }

    fn transact(&self, request: &Request<'_>) -> Result<OwnedReply, ScuError> {
        let owned = OwnedRequest::new(request)?;
        let reply = self.inner.transact(&owned)?;
        if reply.status != Status::Ack {
            return Err(ScuError::Refused { command: owned.command, status: reply.status });
        }
        Ok(reply)
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

    /// Writes a remote data entry (0x3xxx) after checking the value's kind and range.
    pub fn set(&self, index: DataIndex, value: &Value) -> Result<(), ScuError> {
        let Some(Item::Entry(e)) = item(index) else {
            return Err(ScuError::InvalidArgument(format!("{index} is not a single data-list entry")));
        };
        if !e.index.is_remote() {
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
        self.set_raw(index, &data)
    }

    /// Writes raw bytes to a data index (no checks but the unit's).
    pub fn set_raw(&self, index: DataIndex, data: &[u8]) -> Result<(), ScuError> {
        self.transact(&Request::Transfer { index: index.0, data }).map(|_| ())
    }

    /// Actuator `a`'s position in counts.
    pub fn position(&self, a: Actuator) -> Result<i32, ScuError> {
        match self.get_value(a.position_index())? {
            Value::PositionCounts(p) => Ok(p),
            other => Err(ScuError::UnexpectedReply { command: Command::Get, detail: format!("position {other:?}") }),
        }
    }

    /// Actuator `a`'s status 1.
    pub fn status1(&self, a: Actuator) -> Result<Flags, ScuError> {
        let data = self.get_raw(a.status1_index())?;
        let [bits] = data[..] else {
            return Err(ScuError::UnexpectedReply { command: Command::Get, detail: "status is one byte".into() });
        };
        Ok(Flags { set: FlagSet::ActuatorStatus1, bits: u32::from(bits) })
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

    /// Defines CyclicObj `slot` (1..5) on the unit.
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

    fn encode_cyclic_write(object: &CyclicObject, write: &[Value], mode: SpeedMode) -> Result<Vec<u8>, ScuError> {
        let indices: Vec<DataIndex> = object.write_indices().collect();
        if indices.len() != write.len() {
            return Err(ScuError::InvalidArgument(format!(
                "the cyclic object writes {} value(s); {} given",
                indices.len(),
                write.len()
            )));
        }
        let mut bytes = Vec::new();
        for (idx, v) in indices.iter().zip(write) {
            let Some(Item::Entry(e)) = item(*idx) else {
                return Err(ScuError::InvalidArgument(format!("cyclic write index {idx} is not a single entry")));
            };
            if !v.fits(e.kind) {
                return Err(ScuError::InvalidArgument(format!("{}: a {} value does not fit", e.name, v.kind_name())));
            }
            v.check_range(mode).map_err(|err| ScuError::InvalidArgument(format!("{}: {err}", e.name)))?;
            v.encode(e.kind, &mut bytes);
        }
        Ok(bytes)
    }

    /// From now on every keepalive RC carries CyclicObj `slot` with `write` (one value per write index of its
    /// definition, which is read from the unit). The latest read data is available from
    /// [`ScuClient::last_cyclic_read`].
    pub fn use_cyclic(&self, slot: u8, write: &[Value]) -> Result<(), ScuError> {
        let index = Self::cyclic_index(slot)?;
        let Value::CyclicObject(object) = self.get_value(index)? else {
            return Err(ScuError::UnexpectedReply { command: Command::Get, detail: "not a cyclic object".into() });
        };
        let bytes = Self::encode_cyclic_write(&object, write, self.inner.config.speed_mode)?;
        lock(&self.inner.state).cyclic = Some(CyclicUse { slot, object, write: bytes });
        Ok(())
    }

    /// Keepalive RCs carry no cyclic object again.
    pub fn stop_cyclic(&self) {
        lock(&self.inner.state).cyclic = None;
    }

    /// One RC with CyclicObj `slot` now: writes `write`, returns the read data decoded.
    pub fn exchange_cyclic(&self, slot: u8, write: &[Value]) -> Result<Vec<(&'static DataEntry, Value)>, ScuError> {
        let index = Self::cyclic_index(slot)?;
        let Value::CyclicObject(object) = self.get_value(index)? else {
            return Err(ScuError::UnexpectedReply { command: Command::Get, detail: "not a cyclic object".into() });
        };
        let bytes = Self::encode_cyclic_write(&object, write, self.inner.config.speed_mode)?;
        let reply = self.transact(&Request::Cyclic { object: slot - 1, write: &bytes })?;
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

    /// Moves `actuator` to `target_counts` at `speed` (percent, or counts/s per [`ClientConfig::speed_mode`]):
    /// writes the remote position and the function's remote speed, starts the function with direction 9,
    /// waits for status bit 4 to clear and the position to be within
    /// [`ClientConfig::position_tolerance_counts`] of the target, and ends with RS. On cancel, stall, timeout
    /// or any error the function gets a fast RS before the error is returned.
    pub fn move_to(
        &self,
        actuator: Actuator,
        target_counts: i32,
        speed: u16,
        options: &MoveOptions<'_>,
    ) -> Result<MoveReport, ScuError> {
        let function = options.function.unwrap_or_else(|| self.inner.config.function_map.function_for(actuator));
        Value::RemoteSpeed(speed)
            .check_range(self.inner.config.speed_mode)
            .map_err(|e| ScuError::InvalidArgument(format!("speed: {e}")))?;
        let started_at = self.inner.clock.now();
        let start_counts = self.position(actuator)?;
        self.set(actuator.remote_position_index(), &Value::RemotePosition(target_counts))?;
        self.set(function.remote_speed_index(), &Value::RemoteSpeed(speed))?;
        // An RE that failed (refused, a lost or corrupt reply) may still have started the motion: it gets its
        // RS like any other failure.
        let result = self
            .start_motion(function, MotionDirection::RemotePosition)
            .and_then(|()| self.follow_move(actuator, function, start_counts, target_counts, started_at, options));
        match result {
            Ok(position_counts) => {
                self.stop_motion(function, StopMode::Soft)?;
                Ok(MoveReport { actuator, function, position_counts, duration: self.inner.clock.now() - started_at })
            }
            Err(e) => {
                if let Err(stop_err) = self.stop_motion(function, StopMode::Fast) {
                    tracing::error!("could not stop {function} after a failed move: {stop_err}");
                }
                Err(e)
            }
        }
    }

    fn follow_move(
        &self,
        actuator: Actuator,
        function: MotionFunction,
        start_counts: i32,
        target_counts: i32,
        started_at: Timestamp,
        options: &MoveOptions<'_>,
    ) -> Result<i32, ScuError> {
        let tolerance = i64::from(self.inner.config.position_tolerance_counts);
        let pause = self.inner.clock.signal();
        let mut last_position = start_counts;
        let mut last_progress_at = started_at;
        loop {
            // Wait a poll interval, but notice a cancel within it.
            let until = self.inner.clock.now() + self.inner.config.poll_interval;
            while self.inner.clock.now() < until {
                if options.cancel.is_some_and(CancelToken::is_cancelled) {
                    break;
                }
                pause.wait_until(Some(until.min(self.inner.clock.now() + Duration::from_millis(50))));
            }
            let position_counts = self.position(actuator)?;
            let status = self.status1(actuator)?.bits as u8;
            if let Some(report) = options.progress {
                report(&MoveProgress { actuator, position_counts, start_counts, target_counts, status });
            }
            let now = self.inner.clock.now();
            if options.cancel.is_some_and(CancelToken::is_cancelled) {
                return Err(ScuError::Cancelled { actuator, position_counts });
            }
            let on_target = (i64::from(position_counts) - i64::from(target_counts)).abs() <= tolerance;
            let moving = status & status1::MOTION != 0;
            if !moving && on_target {
                return Ok(position_counts);
            }
            if !moving && now - started_at >= self.inner.config.start_grace {
                let error_code = self.error_history().map(|h| h[0]).unwrap_or_default();
                return Err(ScuError::MotionEnded { actuator, position_counts, target_counts, error_code });
            }
            if position_counts != last_position {
                last_position = position_counts;
                last_progress_at = now;
            } else if moving && now - last_progress_at >= self.inner.config.stall_timeout {
                tracing::warn!("{actuator} on {function} stalled at {position_counts}");
                return Err(ScuError::Stalled { actuator, position_counts, after: now - last_progress_at });
            }
            if now - started_at >= self.inner.config.move_timeout {
                return Err(ScuError::MoveTimeout { actuator, position_counts, after: self.inner.config.move_timeout });
            }
        }
    }

    // ----- session

    /// Opens the port again (after a loss): RO, RC, and RS for every function that was started.
    pub fn reconnect(&self) -> Result<(), ScuError> {
        self.inner.reconnect(&mut self.inner.line.lock())
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

/// Why one exchange failed.
enum ExchangeError {
    /// Not one byte of a reply in time. `stray`: bytes came, but none that started a reply (a reply whose
    /// first byte was lost or corrupt: it will not come any more).
    Silent {
        stray: bool,
    },
    Corrupt(WireError),
    Link(LinkError),
}

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
                    SessionState::Open => Some(st.next_keepalive),
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
        let mut st = lock(&self.state);
        st.session = SessionState::Lost(why.clone());
        st.next_reconnect = self.clock.now() + self.config.reconnect_interval;
        ScuError::SessionLost(why)
    }

    /// RO (sent again on no answer: a unit asleep after a long silence often ignores the first) and RC.
    fn open_remote(&self, line: &mut Line) -> Result<(), ScuError> {
        let ro = OwnedRequest::new(&Request::Open { safety_id: self.config.safety_id.code() })?;
        let reply = self.exchange_with_retries(line, &ro)?;
        if reply.status != Status::Ack {
            return Err(ScuError::Refused { command: Command::Open, status: reply.status });
        }
        let rc = OwnedRequest::new(&Request::Cyclic { object: UNUSED, write: &[] })?;
        let reply = self.exchange_with_retries(line, &rc)?;
        if reply.status != Status::Ack {
            return Err(ScuError::Refused { command: Command::Cyclic, status: reply.status });
        }
        lock(&self.state).next_keepalive = self.clock.now() + self.config.keepalive_period;
        Ok(())
    }

    /// Sends the RC (with the cyclic object in use) if one is due.
    fn keepalive_if_due(&self, line: &mut Line) {
        let now = self.clock.now();
        let cyclic = {
            let mut st = lock(&self.state);
            if !matches!(st.session, SessionState::Open) || now < st.next_keepalive || line.link.is_none() {
                return;
            }
            // The next keepalive is due one period after this one was sent, whatever happens to it.
            st.next_keepalive = now + self.config.keepalive_period;
            st.cyclic.clone()
        };
        let request = match &cyclic {
            Some(c) => Request::Cyclic { object: c.slot - 1, write: &c.write },
            None => Request::Cyclic { object: UNUSED, write: &[] },
        };
        let Ok(rc) = OwnedRequest::new(&request) else { return };
        match self.exchange_reopening(line, &rc) {
            Ok(reply) if reply.status == Status::Ack => {
                let mut st = lock(&self.state);
                st.stats.keepalives += 1;
                if let (Some(_), Some(data)) = (&cyclic, reply.data) {
                    st.last_cyclic_read = Some((self.clock.now(), data));
                }
            }
            Ok(reply) => tracing::warn!("keepalive RC refused: {}", reply.status),
            // A lost port has already been recorded; a unit that did not answer (or answered garbage) is
            // not a lost port: the next keepalive and the caller's next request try again, and the caller
            // learns of it from its own request; close and drop still send RS and RA.
            Err(e) => tracing::warn!("keepalive failed: {e}"),
        }
    }

    /// One request of a caller, on the caller's thread.
    fn transact(&self, request: &OwnedRequest) -> Result<OwnedReply, ScuError> {
        let check = || match &lock(&self.state).session {
            SessionState::Open => Ok(()),
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
        if let Some(f) = request.starts {
            // Counted as started before it is sent: a lost reply may hide a started motion.
            lock(&self.state).started.insert(f);
        }
        let reply = self.exchange_reopening(&mut line, request)?;
        let mut st = lock(&self.state);
        if reply.status == Status::Ack {
            if let Some(f) = request.stops {
                st.started.remove(&f);
            }
            if request.command == Command::Cyclic {
                st.next_keepalive = self.clock.now() + self.config.keepalive_period;
            }
        }
        st.stats.transactions += 1;
        Ok(reply)
    }

    /// Sends `request`; if the unit answers PE because it left remote mode (its watchdog expired while the
    /// line was busy, or it was reset), opens remote mode again with RO and RC and, for a request that may be
    /// repeated, sends it once more. RE is not repeated: the caller learns that it was refused.
    fn exchange_reopening(&self, line: &mut Line, request: &OwnedRequest) -> Result<OwnedReply, ScuError> {
        let reply = self.exchange_with_retries(line, request)?;
        if reply.status != Status::PermissionError || request.command == Command::Open {
            return Ok(reply);
        }
        tracing::warn!("{} answered PE: opening remote mode again (RO, RC)", request.command);
        self.open_remote(line)?;
        lock(&self.state).stats.reopens += 1;
        if request.repeatable {
            self.exchange_with_retries(line, request)
        } else {
            Ok(reply)
        }
    }

    /// Sends `request`, retrying repeatable requests after silence and corrupt replies, and any request the
    /// unit answered with CSE (it did not execute it).
    ///
    /// The unit has [`ClientConfig::reply_timeout`] from the first sending to answer. A repeatable request is
    /// sent again when not one byte came for [`ClientConfig::retry_after`], then for twice that, four times
    /// that ... until the reply timeout; a reply to any of the sendings is its answer. Replies to the other
    /// sendings may still come: they are read and discarded before the next request goes out. After a
    /// corrupt reply or a CSE the request is sent again at most [`ClientConfig::retries`] times.
    fn exchange_with_retries(&self, line: &mut Line, request: &OwnedRequest) -> Result<OwnedReply, ScuError> {
        self.drain_late_replies(line);
        let first_sent = self.clock.now();
        let deadline = first_sent + self.config.reply_timeout;
        let mut attempts = 0;
        let mut repairs = 0;
        let mut silent_resends = 0u32;
        let mut silence_window = self.config.retry_after;
        loop {
            attempts += 1;
            let may_retry = repairs < self.config.retries;
            let last_sent = if attempts == 1 { first_sent } else { self.clock.now() };
            let window = if request.repeatable { Some(silence_window) } else { None };
            let outcome = self.exchange(line, request, deadline, window);
            match outcome {
                Ok(reply) if reply.status == Status::ChecksumError && may_retry => {
                    tracing::debug!("{} answered CSE; sending again", request.command);
                    repairs += 1;
                }
                Ok(reply) => {
                    if silent_resends > 0 {
                        // The unit may answer the other sendings too, as late as it answered this one.
                        let late_by = self.clock.now() - first_sent;
                        line.late_replies = Some(LateReplies {
                            count: silent_resends,
                            until: last_sent + late_by + self.config.retry_after,
                            command: request.command,
                            shape: request.shape,
                        });
                    }
                    return Ok(reply);
                }
                Err(ExchangeError::Link(e)) => {
                    if e.is_disconnect() || matches!(e, LinkError::Io { .. }) {
                        return Err(self.lost(line, e.to_string()));
                    }
                    return Err(ScuError::from(e));
                }
                Err(ExchangeError::Silent { stray }) if request.repeatable && self.clock.now() < deadline => {
                    tracing::debug!("no reply to {} yet; sending again", request.command);
                    if !stray {
                        silent_resends += 1;
                    }
                    silence_window = silence_window.saturating_mul(2);
                }
                Err(ExchangeError::Corrupt(e)) if request.repeatable && may_retry && self.clock.now() < deadline => {
                    tracing::debug!("corrupt reply to {} ({e}); sending again", request.command);
                    repairs += 1;
                }
                Err(ExchangeError::Silent { .. }) => {
                    return Err(ScuError::Timeout {
                        command: request.command,
                        timeout: self.config.reply_timeout,
                        attempts,
                    })
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

    /// Reads and drops the late replies to the other sendings of the last request, or what arrives until
    /// they are no longer expected.
    fn drain_late_replies(&self, line: &mut Line) {
        let Some(late) = line.late_replies.take() else { return };
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

    /// One sending of a request, and its reply. Without a byte of reply for `silence_window` (when given) or
    /// until `deadline`, [`ExchangeError::Silent`]; a reply that has started to arrive is awaited until
    /// `deadline`.
    fn exchange(
        &self,
        line: &mut Line,
        request: &OwnedRequest,
        deadline: Timestamp,
        silence_window: Option<Duration>,
    ) -> Result<OwnedReply, ExchangeError> {
        let Line { link, decoder, .. } = line;
        let Some(link) = link.as_mut() else {
            return Err(ExchangeError::Link(LinkError::Disconnected {
                port: "scu".into(),
                reason: "not connected".into(),
            }));
        };
        decoder.reset();
        decoder.expect(request.command, request.shape);
        link.send(&request.bytes).map_err(ExchangeError::Link)?;
        let sent = self.clock.now();
        let silent_deadline = silence_window.map_or(deadline, |w| (sent + w).min(deadline));
        let mut heard = false;
        let mut stray = false;
        let mut buf = [0u8; 256];
        loop {
            let now = self.clock.now();
            let until = if heard { deadline } else { silent_deadline };
            if now >= until {
                return Err(ExchangeError::Silent { stray });
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
            // The unit is answering once the start of a reply is in: give it the full reply timeout.
            heard |= decoder.is_mid_telegram();
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
        let started: Vec<u8> = {
            let mut st = lock(&self.state);
            st.session = SessionState::Open;
            st.stats.reconnects += 1;
            st.started.iter().copied().collect()
        };
        // Every RE needs its RS, even when the unit already stopped the drive (the watchdog did).
        for f in started {
            let _ = self.stop_function(line, f);
        }
        Ok(())
    }

    fn stop_function(&self, line: &mut Line, f: u8) -> Result<(), ScuError> {
        let param = if f <= 9 { StopMode::Fast.code() } else { UNUSED };
        let rs = OwnedRequest::new(&Request::Stop { function: f, param })?;
        let reply = self.exchange_reopening(line, &rs)?;
        if reply.status == Status::Ack {
            lock(&self.state).started.remove(&f);
            Ok(())
        } else {
            Err(ScuError::Refused { command: Command::Stop, status: reply.status })
        }
    }

    fn close(&self, line: &mut Line) -> Result<(), ScuError> {
        if line.link.is_none() {
            return Err(ScuError::SessionLost("port not connected: the unit's watchdog stops the drives".into()));
        }
        let started: Vec<u8> = lock(&self.state).started.iter().copied().collect();
        let mut first_error = None;
        for f in started {
            if let Err(e) = self.stop_function(line, f) {
                tracing::error!("RS of function id {f} failed: {e}");
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
        first_error.map_or(Ok(()), Err)
    }
}
