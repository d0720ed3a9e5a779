//! A session with a bus of modules over RS232 or CAN: request/acknowledge matching, timeouts, retries of
//! reads, the watchdog refresh in a background thread, and halting what the session set in motion.
//!
//! ```
//! use motionlink_link::pipe::{EmulatorHost, PipeConfig};
//! use motionlink_link::clock::{Clock, ManualClock};
//! use motionlink_powercube::client::{Bus, BusConfig};
//! use motionlink_powercube::model::{Position, StateFlag};
//! use motionlink_powercube::sim::{SimBus, SimConfig};
//! use std::time::Duration;
//!
//! let clock = ManualClock::new_auto();
//! let _me = clock.reserve_participant().enter();
//! let host = EmulatorHost::new(SimBus::new(&SimConfig::default()), clock.shared(), PipeConfig::paced(9_600));
//! let bus = Bus::rs232(Box::new(host.connect().0), clock.shared(), BusConfig::rs232());
//! let joint = bus.module(1).unwrap();
//! joint.home().unwrap();
//! joint.wait_home(Duration::from_secs(10), &mut |_| {}).unwrap();
//! joint.move_ramp(Position::native(0.5), None).unwrap();
//! let state = joint.wait_ramp_end(Duration::from_secs(10), &mut |_| {}).unwrap();
//! assert!(state.contains(StateFlag::RampEnd));
//! assert!((joint.position().unwrap().value() - 0.5).abs() < 1e-4);
//! ```

mod transport;

use std::collections::{BTreeMap, BTreeSet};
use std::fmt;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread;
use std::time::Duration;

use motionlink_link::can::CanLink;
use motionlink_link::cancel::CancelToken;
use motionlink_link::clock::lock as lock_mutex;
use motionlink_link::{Link, LinkError, SharedClock, Signal, Timestamp};

use crate::model::{
    Acceleration, AckKind, Action, Broadcast, ConfigFlag, ConfigWord, CubeState, CubeVersion, Dio, ExtAck, Millis,
    ModelError, ModuleKind, Motion, Param, Position, Ramp, Reply, Request, ShortState, StateFlag, Ticks, Value,
    Velocity,
};
use crate::wire::{is_module_address, ACK_OK, MAX_ADDRESS};
use motionlink_link::clock_lock::ClockLock;
use transport::{Incoming, Transport};

pub use crate::model::WATCHDOG_TIMEOUT;

/// Timing and retry settings of a session; the defaults depend on the carrier.
#[derive(Debug, Clone, PartialEq)]
pub struct BusConfig {
    /// How long to wait for an acknowledge.
    pub reply_timeout: Duration,
    /// How often a read is repeated after a timeout or a corrupt answer (writes and motions never are).
    pub read_retries: u32,
    /// How long a scan waits for each address (RS232) or for all answers (CAN).
    pub scan_timeout: Duration,
    /// How often the watchdog refresh is broadcast while the watchdog is served (the modules wait 50 ms).
    pub watchdog_period: Duration,
    /// How often the state is polled while waiting for homing or a motion to end (10 ms by default): the
    /// polls are scheduled at this period from the first one (absolute deadlines), never faster, however
    /// quickly the line answers, so that a wait leaves the bus to the other modules and hosts on it.
    pub poll_interval: Duration,
    /// Let [`Bus::enable_watchdog`] arm modules on RS232 (default true). The manual lists the broadcasts
    /// for CAN only; on RS232 the refresh goes to module address 0 as the command followed by 0x00, the form
    /// Schunk's own library (libm5api, serveWatchdogAll) sends over RS232. Set false to refuse arming on
    /// RS232 for a chain known not to take it.
    pub watchdog_on_rs232: bool,
}

impl BusConfig {
    /// RS232: a full frame takes up to 25 ms each way at 9600 baud; acknowledges within 200 ms.
    pub fn rs232() -> Self {
        BusConfig {
            reply_timeout: Duration::from_millis(200),
            read_retries: 2,
            scan_timeout: Duration::from_millis(60),
            watchdog_period: Duration::from_millis(20),
            poll_interval: Duration::from_millis(10),
            watchdog_on_rs232: true,
        }
    }

    /// CAN: acknowledges within 50 ms.
    pub fn can() -> Self {
        BusConfig {
            reply_timeout: Duration::from_millis(50),
            read_retries: 2,
            scan_timeout: Duration::from_millis(50),
            watchdog_period: Duration::from_millis(20),
            poll_interval: Duration::from_millis(10),
            watchdog_on_rs232: true,
        }
    }
}

/// What became of the Halt an action sent to a module it had set in motion, when the action could not go
/// on (a failing line, a timeout, a cancellation).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum StopOutcome {
    /// Nothing had been set in motion yet: nothing to stop.
    NotStarted,
    /// The module acknowledged the Halt: it stopped at once (and stays halted until a reset).
    Confirmed,
    /// No Halt was acknowledged (it was tried three times, then broadcast): the axis may still be moving.
    Unconfirmed {
        /// Why: the last Halt's error.
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
            StopOutcome::Confirmed => f.write_str("the module acknowledged the halt: it has stopped"),
            StopOutcome::Unconfirmed { reason, watchdog_armed } => {
                write!(f, "the halt was not confirmed ({reason}): the axis may still be moving")?;
                if *watchdog_armed {
                    f.write_str(
                        "; its watchdog is online and no longer refreshed, so if the halt did not reach it the \
                         module halts itself within 50 ms of the last refresh that did",
                    )
                } else {
                    f.write_str("; no watchdog is armed on it: only a halt or the emergency stop stops it now")
                }
            }
        }
    }
}

/// What went wrong in a session. Device errors ([`Error::is_device`]) are the module's answer; transport
/// errors ([`Error::is_transport`]) are the line's; usage errors ([`Error::is_usage`]) are the caller's.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The port or the line failed.
    #[error(transparent)]
    Link(#[from] LinkError),
    /// No acknowledge in time.
    #[error("module {address} did not answer {request} within {} ms", waited.as_millis())]
    Timeout {
        /// The module.
        address: u8,
        /// The request, described.
        request: String,
        /// How long the session waited (the last attempt).
        waited: Duration,
    },
    /// Only a corrupt answer came (bad BCC, broken frame, unknown content).
    #[error("module {address}: corrupt answer to {request}: {detail}")]
    Corrupt {
        /// The module.
        address: u8,
        /// The request, described.
        request: String,
        /// What was wrong.
        detail: String,
    },
    /// The module reports error flags; they are named.
    #[error("module {address} reports an error: {}", fault_names(*state))]
    Device {
        /// The module.
        address: u8,
        /// Its state word (match on the flags with [`CubeState::contains`]).
        state: CubeState,
    },
    /// The module is halted (STATE_HALTED) without an error flag: a Halt, or a watchdog that expired.
    #[error("module {address} is halted (STATE_HALTED); send a reset")]
    Halted {
        /// The module.
        address: u8,
        /// Its state word.
        state: CubeState,
    },
    /// The module acknowledged with a status other than 0x64.
    #[error("module {address} refused {request} (status 0x{status:02X})")]
    Refused {
        /// The module.
        address: u8,
        /// The request, described.
        request: String,
        /// The status byte.
        status: u8,
    },
    /// Homing or a motion did not end in time; the motion was halted ([`Error::WaitTimeout::stop`] says
    /// whether that was confirmed).
    #[error("module {address}: {what} did not happen within {} ms (state: {state}); {stop}", waited.as_millis())]
    WaitTimeout {
        /// The module.
        address: u8,
        /// What was waited for.
        what: &'static str,
        /// How long.
        waited: Duration,
        /// The last state read.
        state: CubeState,
        /// What became of the Halt.
        stop: StopOutcome,
    },
    /// The action was cancelled (Ctrl-C, a signal, [`Bus::set_cancel_token`]); what it had set in motion was
    /// halted ([`Error::Cancelled::stop`] says whether that was confirmed).
    #[error("module {address}: cancelled; {stop}")]
    Cancelled {
        /// The module.
        address: u8,
        /// What became of the Halt.
        stop: StopOutcome,
    },
    /// The line failed, or the module stopped answering, while a motion this session started may have been
    /// running: the session tried to halt it, and [`Error::LostDuringMotion::stop`] says whether the module
    /// confirmed that.
    #[error("while module {address} may have been moving: {cause}; {stop}")]
    LostDuringMotion {
        /// The module.
        address: u8,
        /// What failed.
        cause: Box<Error>,
        /// What became of the Halt.
        stop: StopOutcome,
    },
    /// A value outside one of the module's limits: refused before anything was sent that moves (the module
    /// would have limited it silently).
    #[error("module {address}: {what} {} is outside the module's limit {limit} = {}", number(*value), number(*limit_value))]
    BeyondLimit {
        /// The module.
        address: u8,
        /// What the value is ("target position", "--vel", "TargetVel").
        what: String,
        /// The value asked for.
        value: f64,
        /// The limit parameter (MinPos, MaxPos, MaxVel, MaxAcc, MaxCur ...).
        limit: Param,
        /// Its value in the module.
        limit_value: f64,
    },
    /// A parameter read back after it was written differs from what was written: the module limited it, or
    /// the write was corrupted on the way (the modules ignore the checksum).
    #[error("module {address}: {param} was written as {wrote} but reads back as {read} (the module limited it, or the write was corrupted on the way)")]
    Mismatch {
        /// The module.
        address: u8,
        /// The parameter written.
        param: Param,
        /// What was written.
        wrote: String,
        /// What the module holds.
        read: String,
    },
    /// After the motion command, the module's target (TargetPosInc) is not the target sent: the command
    /// was corrupted on the way; the motion was halted.
    #[error("module {address}: the motion command was sent with target {sent} ticks but the module took {taken} ticks (a corrupted command); {stop}")]
    TargetMismatch {
        /// The module.
        address: u8,
        /// The target sent, in encoder ticks.
        sent: i32,
        /// The target the module holds.
        taken: i32,
        /// What became of the Halt.
        stop: StopOutcome,
    },
    /// The motion ended, but not where it was asked to: the final position read from the module is further
    /// from the target than the in-position tolerance.
    #[error("module {address}: target {target} not reached: the module stands at {reached}, {difference:.6} away (tolerance {tolerance}; state: {state})")]
    NotReached {
        /// The module.
        address: u8,
        /// The target.
        target: f32,
        /// The final actual position read from the module.
        reached: f32,
        /// `reached - target`.
        difference: f32,
        /// The tolerance allowed.
        tolerance: f32,
        /// The state word at the end.
        state: CubeState,
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
    Unsupported(String),
    /// The session failed with the watchdog of these modules online: it was left online (its refresh
    /// stopped), so they halt within 50 ms with STATE_COMM_ERROR; `reset_and_release_watchdog` (the `reset`
    /// command) clears them afterwards.
    #[error("the watchdog of module {} is left online: {detail}; the module halts within 50 ms of the last refresh (STATE_COMM_ERROR; `reset` clears it)", addresses.iter().map(u8::to_string).collect::<Vec<_>>().join(", "))]
    WatchdogLeftOnline {
        /// The modules.
        addresses: Vec<u8>,
        /// Why.
        detail: String,
    },
    /// A watchdog toggle (the life sign, chapter 13) was not confirmed: whether the module's watchdog is
    /// online is not known. No second life sign is sent blindly (it could switch the watchdog the wrong way).
    #[error("module {address}: watchdog not confirmed {}: {detail}", if *on { "online" } else { "offline" })]
    WatchdogUnconfirmed {
        /// The module.
        address: u8,
        /// True when switching on, false when switching off.
        on: bool,
        /// What was seen.
        detail: String,
    },
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

impl Error {
    /// The line failed: port, timeout, corrupt answer.
    pub fn is_transport(&self) -> bool {
        matches!(self, Error::Link(_) | Error::Timeout { .. } | Error::Corrupt { .. } | Error::LostDuringMotion { .. })
    }

    /// The module refused or reported an error, or an action did not complete.
    pub fn is_device(&self) -> bool {
        matches!(
            self,
            Error::Device { .. }
                | Error::Halted { .. }
                | Error::Refused { .. }
                | Error::WaitTimeout { .. }
                | Error::WatchdogUnconfirmed { .. }
                | Error::WatchdogLeftOnline { .. }
                | Error::Cancelled { .. }
                | Error::Mismatch { .. }
                | Error::TargetMismatch { .. }
                | Error::NotReached { .. }
        )
    }

    /// The request was wrong before anything was sent.
    pub fn is_usage(&self) -> bool {
        matches!(
            self,
            Error::Model(_)
                | Error::InvalidAddress(_)
                | Error::Unsupported(_)
                | Error::BeyondLimit { .. }
                | Error::InvalidArgument { .. }
        )
    }

    /// What became of the stop of a motion this error interrupted, if it interrupted one.
    pub fn stop(&self) -> Option<&StopOutcome> {
        match self {
            Error::WaitTimeout { stop, .. }
            | Error::Cancelled { stop, .. }
            | Error::LostDuringMotion { stop, .. }
            | Error::TargetMismatch { stop, .. } => Some(stop),
            _ => None,
        }
    }

    fn retryable(&self) -> bool {
        matches!(self, Error::Timeout { .. } | Error::Corrupt { .. })
    }
}

/// One module a scan found: its address, and its type, version, serial number and state, or the error that
/// kept the session from reading them (the module answered the scan, so it is there; the rest of the scan
/// goes on without it).
#[derive(Debug)]
pub struct ScanEntry {
    /// The address that answered.
    pub address: u8,
    /// What [`Module::info`] read, or why it could not (also a scan answer that stayed corrupt on every
    /// retry).
    pub info: Result<ModuleInfo, Error>,
}

/// An answer that decoded but is not what `request` asks for (a value of another type, another reply).
fn unexpected(address: u8, request: &Request, what: impl fmt::Display) -> Error {
    Error::Corrupt { address, request: request.to_string(), detail: format!("unexpected answer {what}") }
}

/// What a scan finds at one address.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ModuleInfo {
    /// The address.
    pub address: u8,
    /// Rotary or linear (from the Config word).
    pub kind: ModuleKind,
    /// Firmware version.
    pub version: CubeVersion,
    /// Serial number.
    pub serial: u32,
    /// The state word.
    pub state: CubeState,
}

/// One poll while waiting for homing or a motion: position and state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Progress {
    /// The module.
    pub address: u8,
    /// Its position.
    pub position: Position,
    /// Its state.
    pub state: CubeState,
    /// Time waited so far.
    pub elapsed: Duration,
}

#[derive(Debug)]
struct WatchdogDuty {
    serving: bool,
    next_due: Timestamp,
    period: Duration,
    /// Modules whose watchdog this session switched on.
    online: BTreeSet<u8>,
    /// Modules in which this session set CONFIGID_MOD_WATCHDOG_ENABLE, with their Config word before.
    config_before: BTreeMap<u8, ConfigWord>,
    /// Modules that got a life sign this session could not confirm: their watchdog may be online or not.
    uncertain: BTreeSet<u8>,
    last_error: Option<String>,
}

struct Inner {
    clock: SharedClock,
    config: BusConfig,
    io: ClockLock<Transport>,
    description: String,
    can: bool,
    /// Modules this session may have set in motion and has not seen stop (halted on drop).
    started: Mutex<BTreeSet<u8>>,
    /// Modules known to exist: every address that has answered this session (a scan, any request).
    known: Mutex<BTreeSet<u8>>,
    /// The session lost its line or could not stop what it started: a link error, a failed watchdog
    /// refresh, a known module that stopped answering. A failed session leaves the watchdog online on drop.
    failed: AtomicBool,
    duty: Mutex<WatchdogDuty>,
    kinds: Mutex<BTreeMap<u8, ModuleKind>>,
    cancel: Mutex<Option<CancelToken>>,
}

struct WatchdogThread {
    stop: Arc<AtomicBool>,
    wake: Signal,
    handle: Option<thread::JoinHandle<()>>,
}

/// A session with the modules on one line (RS232) or one CAN bus.
///
/// Dropping it halts every module the session set in motion that is still moving (or cannot be asked),
/// then, if the session switched watchdogs on and has not failed, switches them off again and restores the
/// Config words as [`Bus::disable_watchdog`] does, and stops the refresh thread. A session that failed (its
/// line broke, a refresh could not be sent, a module it started stopped answering) leaves the watchdogs
/// online: the modules halt within 50 ms, which is the watchdog's purpose.
pub struct Bus {
    inner: Arc<Inner>,
    watchdog: Mutex<Option<WatchdogThread>>,
}

impl fmt::Debug for Bus {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Bus").field("port", &self.inner.description).finish()
    }
}

impl Bus {
    /// A session over an RS232 byte link (a serial port, TCP, a pty, an in-memory link).
    pub fn rs232(link: Box<dyn Link>, clock: SharedClock, config: BusConfig) -> Bus {
        Self::build(Transport::rs232(link), clock, config)
    }

    /// A session over a CAN link (SocketCAN, SLCAN, the in-memory bus).
    pub fn can(link: Box<dyn CanLink>, clock: SharedClock, config: BusConfig) -> Bus {
        Self::build(Transport::can(link), clock, config)
    }

    fn build(transport: Transport, clock: SharedClock, config: BusConfig) -> Bus {
        let description = transport.describe();
        let can = transport.is_can();
        let duty = WatchdogDuty {
            serving: false,
            next_due: Timestamp::ZERO,
            period: config.watchdog_period,
            online: BTreeSet::new(),
            config_before: BTreeMap::new(),
            uncertain: BTreeSet::new(),
            last_error: None,
        };
        Bus {
            inner: Arc::new(Inner {
                io: ClockLock::new(Arc::clone(&clock), transport),
                clock,
                config,
                description,
                can,
                started: Mutex::new(BTreeSet::new()),
                known: Mutex::new(BTreeSet::new()),
                failed: AtomicBool::new(false),
                duty: Mutex::new(duty),
                kinds: Mutex::new(BTreeMap::new()),
                cancel: Mutex::new(None),
            }),
            watchdog: Mutex::new(None),
        }
    }

    /// The port, for messages.
    pub fn describe(&self) -> &str {
        &self.inner.description
    }

    /// True on a CAN bus.
    pub fn is_can(&self) -> bool {
        self.inner.can
    }

    /// The session's settings.
    pub fn config(&self) -> &BusConfig {
        &self.inner.config
    }

    /// The session's clock.
    pub fn clock(&self) -> &SharedClock {
        &self.inner.clock
    }

    /// Every wait of this session watches `token`: when it is cancelled (Ctrl-C), the motion is halted and
    /// the wait returns [`Error::Cancelled`].
    pub fn set_cancel_token(&self, token: CancelToken) {
        *lock_mutex(&self.inner.cancel) = Some(token);
    }

    /// A handle on the module at `address` (1..31). Nothing is sent.
    pub fn module(&self, address: u8) -> Result<Module<'_>, Error> {
        if !is_module_address(address) {
            return Err(Error::InvalidAddress(address));
        }
        Ok(Module { bus: self, address })
    }

    /// Checks a request before it is sent: the address (1..31), the manual's rules
    /// ([`Request::validate`]: access, value type, finite floats, the MotionID for the acknowledge asked),
    /// and, on CAN, no CONFIGID_MOD_DISABLE_ACK (this client needs acknowledges). Every request goes through
    /// here.
    fn check(&self, address: u8, request: &Request) -> Result<(), Error> {
        if !is_module_address(address) {
            return Err(Error::InvalidAddress(address));
        }
        request.validate()?;
        if let Request::Set(Param::Config, value) = request {
            let word = value.as_u32().map(ConfigWord);
            if self.inner.can && word.is_some_and(|w| w.contains(ConfigFlag::DisableAck)) {
                return Err(Error::Unsupported(
                    "CONFIGID_MOD_DISABLE_ACK: this client needs the acknowledges of its commands".into(),
                ));
            }
        }
        Ok(())
    }

    /// True once the session has failed: its line broke, a watchdog refresh could not be sent, or a module it
    /// set in motion stopped answering. A failed session leaves the watchdog online when dropped.
    pub fn failed(&self) -> bool {
        self.inner.failed.load(Ordering::SeqCst)
    }

    /// Modules known to exist: every address that answered this session.
    pub fn known(&self) -> Vec<u8> {
        lock_mutex(&self.inner.known).iter().copied().collect()
    }

    /// One request, checked before it is sent ([`Request::validate`]; nothing is sent if it breaks the
    /// manual's rules), its acknowledge checked; reads are retried.
    pub fn request(&self, address: u8, request: &Request) -> Result<Reply, Error> {
        self.check(address, request)?;
        let attempts = if request.is_idempotent() { 1 + self.inner.config.read_retries } else { 1 };
        if request.starts_motion() {
            lock_mutex(&self.inner.started).insert(address);
        }
        let mut last = None;
        for attempt in 0..attempts {
            match self.inner.transact_many(&[(address, *request)], self.inner.config.reply_timeout).pop() {
                Some(Ok(reply)) => return check_reply(address, request, reply),
                Some(Err(e)) if e.retryable() && attempt + 1 < attempts => {
                    tracing::debug!("{e}; trying again");
                    last = Some(e);
                }
                Some(Err(e)) => return Err(e),
                None => break,
            }
        }
        Err(last.unwrap_or_else(|| Error::Unsupported("no request".into())))
    }

    /// Several requests to several modules; on CAN all are sent at once and the acknowledges collected in
    /// any order, on RS232 one after the other. Each is checked as [`Bus::request`] checks it (one that
    /// breaks the rules gets its error and is not sent; the others are). Reads that fail are retried.
    pub fn request_many(&self, requests: &[(u8, Request)]) -> Vec<Result<Reply, Error>> {
        let mut results: Vec<Option<Result<Reply, Error>>> = requests.iter().map(|_| None).collect();
        for (i, (address, request)) in requests.iter().enumerate() {
            if let Err(e) = self.check(*address, request) {
                results[i] = Some(Err(e));
            } else if request.starts_motion() {
                lock_mutex(&self.inner.started).insert(*address);
            }
        }
        for attempt in 0..=self.inner.config.read_retries {
            let todo: Vec<usize> = (0..requests.len())
                .filter(|&i| match &results[i] {
                    None => true,
                    Some(Err(e)) => attempt > 0 && e.retryable() && requests[i].1.is_idempotent(),
                    Some(Ok(_)) => false,
                })
                .collect();
            if todo.is_empty() {
                break;
            }
            let batch: Vec<(u8, Request)> = todo.iter().map(|&i| requests[i]).collect();
            let answers = if self.inner.can {
                self.inner.transact_many(&batch, self.inner.config.reply_timeout)
            } else {
                batch.iter().flat_map(|r| self.inner.transact_many(&[*r], self.inner.config.reply_timeout)).collect()
            };
            for (&i, answer) in todo.iter().zip(answers) {
                let (address, request) = &requests[i];
                results[i] = Some(answer.and_then(|r| check_reply(*address, request, r)));
            }
        }
        results.into_iter().map(|r| r.unwrap_or_else(|| Err(Error::Unsupported("not sent".into())))).collect()
    }

    /// Reads `param` of every module in `addresses` (on CAN in one round).
    pub fn read_many(&self, addresses: &[u8], param: Param) -> Vec<Result<Value, Error>> {
        let req = match Request::get(param) {
            Ok(r) => r,
            Err(e) => return addresses.iter().map(|_| Err(Error::Model(e.clone()))).collect(),
        };
        let requests: Vec<(u8, Request)> = addresses.iter().map(|a| (*a, req)).collect();
        self.request_many(&requests)
            .into_iter()
            .zip(addresses)
            .map(|(r, a)| match r? {
                Reply::Get(_, v) => Ok(v),
                other => Err(unexpected(*a, &req, other)),
            })
            .collect()
    }

    /// The positions of `addresses` (ActPos), on CAN in one round.
    pub fn positions(&self, addresses: &[u8]) -> Vec<Result<Position, Error>> {
        let req = Request::Get(Param::ActPos);
        self.read_many(addresses, Param::ActPos)
            .into_iter()
            .zip(addresses)
            .map(|(r, a)| {
                r.and_then(|v| v.as_f32().map(Position::native).ok_or_else(|| unexpected(*a, &req, format!("{v:?}"))))
            })
            .collect()
    }

    /// Sends a broadcast (never acknowledged). On RS232, where the manual defines no broadcast, it goes to
    /// address 0, which the emulator treats as every module and real modules may ignore.
    ///
    /// Home and StartMotion count as setting in motion every module the session knows ([`Bus::known`]: the
    /// addresses that have answered it, so scan first or talk to the modules first), so that a drop looks at
    /// them; absent addresses are not. A Halt clears that list on CAN only: on RS232 the modules may have
    /// ignored it, so a drop still asks each one and halts it by address if it moves.
    pub fn broadcast(&self, broadcast: Broadcast) -> Result<(), Error> {
        match broadcast {
            Broadcast::Halt if self.inner.can => lock_mutex(&self.inner.started).clear(),
            Broadcast::Home | Broadcast::StartMotion => {
                let known = lock_mutex(&self.inner.known).clone();
                lock_mutex(&self.inner.started).extend(known);
            }
            _ => {}
        }
        let mut io = self.inner.io.lock();
        if let Err(e) = io.broadcast(&broadcast) {
            self.inner.failed.store(true, Ordering::SeqCst);
            return Err(e.into());
        }
        Ok(())
    }

    /// Asks addresses 1..31 for their version; returns every address that answers, with its type, serial
    /// number and state, or the error that kept them from being read (per module: one module that fails
    /// does not fail the scan). Silence is absence; a corrupt answer is asked again (up to
    /// [`BusConfig::read_retries`] times): an address that answers corruptly every time is reported with
    /// that error, one that is silent when asked again is absent (a warning is logged: the garbage was line
    /// noise or another module's late answer). Only a failed line fails the whole scan.
    pub fn scan(&self) -> Result<Vec<ScanEntry>, Error> {
        let probe = Request::Get(Param::DefCubeVersion);
        let timeout = self.inner.config.scan_timeout;
        let mut todo: Vec<u8> = (1..=MAX_ADDRESS).collect();
        let mut answered = BTreeSet::new();
        let mut broken: BTreeMap<u8, Error> = BTreeMap::new();
        for _ in 0..=self.inner.config.read_retries {
            if todo.is_empty() {
                break;
            }
            let batch: Vec<(u8, Request)> = todo.iter().map(|a| (*a, probe)).collect();
            let answers = if self.inner.can {
                self.inner.transact_many(&batch, timeout)
            } else {
                batch.iter().flat_map(|r| self.inner.transact_many(&[*r], timeout)).collect()
            };
            todo.clear();
            for ((a, _), r) in batch.iter().zip(answers) {
                match r {
                    Ok(_) => {
                        broken.remove(a);
                        answered.insert(*a);
                    }
                    Err(e @ Error::Corrupt { .. }) => {
                        tracing::debug!("scan: {e}; asking again");
                        todo.push(*a);
                        broken.insert(*a, e);
                    }
                    // Nobody there. After a corrupt answer, silence means the garbage was not this module's
                    // (on RS232 a frame with a wrong BCC names no trustworthy address): absent, with a warning.
                    Err(Error::Timeout { .. }) => {
                        if let Some(e) = broken.remove(a) {
                            tracing::warn!("scan: address {a}: {e}, then silence when asked again: taken as absent");
                        }
                    }
                    Err(e) => return Err(e),
                }
            }
        }
        let mut entries: Vec<ScanEntry> = answered
            .into_iter()
            .map(|address| ScanEntry { address, info: self.module(address).and_then(|m| m.info()) })
            .collect();
        entries.extend(broken.into_iter().map(|(address, e)| ScanEntry { address, info: Err(e) }));
        entries.sort_by_key(|e| e.address);
        Ok(entries)
    }

    /// Switches the watchdog on in `addresses`: sets CONFIGID_MOD_WATCHDOG_ENABLE in their Config word where
    /// it is not set (remembering the word, for [`Bus::disable_watchdog`]), starts broadcasting the refresh
    /// every [`BusConfig::watchdog_period`] from a background thread, and sends each module its first life
    /// sign. From then on, if this session stops refreshing (the program dies, the line breaks), the modules
    /// halt within 50 ms.
    ///
    /// The life sign toggles the watchdog, and its acknowledge is the only confirmation the manual offers.
    /// A module that does not acknowledge it gets [`Error::WatchdogUnconfirmed`] naming it (the first such
    /// error is returned after the other modules are handled): its watchdog may be online, so it is refreshed
    /// like the others, but it never gets a second life sign; [`Bus::disable_watchdog`] finds out its state.
    ///
    /// A module that shows STATE_COMM_ERROR (its watchdog expired: a host stopped serving it) is refused
    /// with [`Error::Device`] before anything is changed in any module: its watchdog is probably still
    /// online, and a life sign would switch it off. [`Module::reset_and_release_watchdog`] clears it.
    ///
    /// On RS232 the refresh goes to module address 0 as the command followed by 0x00, as Schunk's libm5api
    /// sends it (the manual lists broadcasts for CAN only); [`BusConfig::watchdog_on_rs232`] set to false
    /// refuses arming there with [`Error::Unsupported`].
    pub fn enable_watchdog(&self, addresses: &[u8]) -> Result<(), Error> {
        if !self.inner.can && !self.inner.config.watchdog_on_rs232 {
            return Err(Error::Unsupported(
                "the watchdog on RS232 is switched off in this session's settings (BusConfig::watchdog_on_rs232)"
                    .into(),
            ));
        }
        if self.failed() {
            return Err(Error::Unsupported(
                "this session has failed (its line broke or a stop was not confirmed): it cannot serve a watchdog"
                    .into(),
            ));
        }
        let mut words = Vec::with_capacity(addresses.len());
        for &a in addresses {
            let module = self.module(a)?;
            let state = module.state()?;
            if state.contains(StateFlag::CommError) && !lock_mutex(&self.inner.duty).online.contains(&a) {
                return Err(Error::Device { address: a, state });
            }
            words.push((module, module.config_word()?));
        }
        for (module, config) in words {
            if !config.contains(ConfigFlag::WatchdogEnable) {
                // Remembered before the write: a write that fails may still have arrived.
                lock_mutex(&self.inner.duty).config_before.entry(module.address).or_insert(config);
                // Read back: a Config word corrupted on the way (the modules ignore the BCC) is not used.
                module.set_checked(Param::Config, Value::U32(config.with(ConfigFlag::WatchdogEnable).0))?;
            }
        }
        {
            let mut duty = lock_mutex(&self.inner.duty);
            duty.serving = true;
            duty.next_due = self.inner.clock.now();
        }
        self.start_watchdog_thread();
        let mut first_error = None;
        for &a in addresses {
            {
                let duty = lock_mutex(&self.inner.duty);
                if duty.online.contains(&a) {
                    continue;
                }
                if duty.uncertain.contains(&a) {
                    first_error.get_or_insert(Error::WatchdogUnconfirmed {
                        address: a,
                        on: true,
                        detail: "an earlier life sign was not acknowledged; not toggled again (disable_watchdog \
                                 finds out its state)"
                            .into(),
                    });
                    continue;
                }
            }
            // The acknowledge of the life sign is the only confirmation the manual offers that the toggle
            // arrived (no state flag shows an online watchdog). Silence leaves the watchdog in an unknown
            // state: it is served (refreshed) as if online, reported, and never toggled again blindly.
            match self.request(a, &Request::Action(Action::LifeSign)) {
                Ok(_) => {
                    tracing::debug!("module {a}: watchdog online");
                    lock_mutex(&self.inner.duty).online.insert(a);
                }
                Err(e @ (Error::Timeout { .. } | Error::Corrupt { .. })) => {
                    tracing::warn!("module {a}: life sign not acknowledged ({e}); its watchdog state is unknown");
                    lock_mutex(&self.inner.duty).uncertain.insert(a);
                    first_error.get_or_insert(Error::WatchdogUnconfirmed {
                        address: a,
                        on: true,
                        detail: format!("the life sign was not acknowledged ({e}); not sent again"),
                    });
                }
                Err(e) => return Err(e),
            }
        }
        first_error.map_or(Ok(()), Err)
    }

    /// Undoes [`Bus::enable_watchdog`]: switches the watchdog off again in the modules this session switched
    /// it on in (a second life sign), stops refreshing, and clears CONFIGID_MOD_WATCHDOG_ENABLE again in the
    /// modules where this session set it, leaving every other bit of their Config word as it is now
    /// (normally the word is then exactly what it was before). A module whose watchdog could not be switched
    /// off keeps its Config word and halts within 50 ms, as a session that dies would leave it; the other
    /// modules are still handled, and the first error is returned.
    ///
    /// A life sign that is not acknowledged is not sent again (it could switch the watchdog back on). For
    /// those modules, and those whose first life sign was not confirmed, the refresh is stopped and, after
    /// twice [`WATCHDOG_TIMEOUT`], their state is read: STATE_COMM_ERROR means the watchdog was online (the
    /// module is now halted; [`Error::WatchdogUnconfirmed`] names it and its Config word is left as is),
    /// without it the watchdog is offline and the Config word is restored.
    pub fn disable_watchdog(&self) -> Result<(), Error> {
        if self.failed() {
            // A failed session may have left something moving that it could not stop: the watchdog is what
            // stops it now. It is not switched off.
            let left: Vec<u8> = {
                let duty = lock_mutex(&self.inner.duty);
                duty.online.iter().chain(duty.uncertain.iter()).copied().collect()
            };
            self.abandon_watchdog();
            self.stop_watchdog_thread();
            if left.is_empty() {
                return Ok(());
            }
            return Err(Error::WatchdogLeftOnline {
                addresses: left,
                detail: "the session failed (its line broke, or a stop it sent was not confirmed)".into(),
            });
        }
        let mut first_error = None;
        let online: Vec<u8> = lock_mutex(&self.inner.duty).online.iter().copied().collect();
        for a in online {
            match self.request(a, &Request::Action(Action::LifeSign)) {
                Ok(_) => {
                    tracing::debug!("module {a}: watchdog offline");
                    lock_mutex(&self.inner.duty).online.remove(&a);
                }
                Err(e @ (Error::Timeout { .. } | Error::Corrupt { .. })) => {
                    // It may or may not have arrived: a second life sign could switch the watchdog on again.
                    tracing::warn!("module {a}: life sign not acknowledged ({e}); its watchdog state is unknown");
                    let mut duty = lock_mutex(&self.inner.duty);
                    duty.online.remove(&a);
                    duty.uncertain.insert(a);
                }
                Err(e) => {
                    tracing::warn!("module {a}: cannot switch the watchdog off: {e}");
                    first_error.get_or_insert(e);
                }
            }
        }
        lock_mutex(&self.inner.duty).serving = false;
        self.stop_watchdog_thread();
        if let Err(e) = self.observe_uncertain_watchdogs() {
            first_error.get_or_insert(e);
        }
        let restore: Vec<(u8, ConfigWord)> = {
            let duty = lock_mutex(&self.inner.duty);
            duty.config_before
                .iter()
                .filter(|(a, _)| !duty.online.contains(a) && !duty.uncertain.contains(a))
                .map(|(a, w)| (*a, *w))
                .collect()
        };
        for (a, before) in restore {
            match self.restore_watchdog_flag(a, before) {
                Ok(()) => {
                    lock_mutex(&self.inner.duty).config_before.remove(&a);
                }
                Err(e) => {
                    tracing::warn!("module {a}: cannot restore the Config word {:#010x}: {e}", before.0);
                    first_error.get_or_insert(e);
                }
            }
        }
        first_error.map_or(Ok(()), Err)
    }

    /// With the refresh stopped, finds out whether the modules whose life sign was not confirmed have their
    /// watchdog online, the only way the manual offers to observe it: an online watchdog that is not
    /// refreshed expires (STATE_COMM_ERROR, STATE_HALTED) within [`WATCHDOG_TIMEOUT`]. Waits twice that on
    /// the session's clock, then reads each one's state. A module without STATE_COMM_ERROR is offline (and
    /// forgotten); one with it had its watchdog online and is now halted: that is an error naming it
    /// ([`Module::reset_and_release_watchdog`] clears it), as is one that cannot be read.
    fn observe_uncertain_watchdogs(&self) -> Result<(), Error> {
        let uncertain: Vec<u8> = lock_mutex(&self.inner.duty).uncertain.iter().copied().collect();
        if uncertain.is_empty() {
            return Ok(());
        }
        self.inner.clock.sleep(WATCHDOG_TIMEOUT * 2);
        let mut first_error = None;
        for a in uncertain {
            let seen = self.module(a).and_then(|m| m.state());
            match seen {
                Ok(state) if !state.contains(StateFlag::CommError) => {
                    tracing::debug!("module {a}: watchdog seen offline");
                    lock_mutex(&self.inner.duty).uncertain.remove(&a);
                }
                Ok(state) => {
                    first_error.get_or_insert(Error::WatchdogUnconfirmed {
                        address: a,
                        on: false,
                        detail: format!(
                            "its watchdog was still online and has expired ({state}); the module is halted, \
                             reset_and_release_watchdog clears it"
                        ),
                    });
                }
                Err(e) => {
                    first_error.get_or_insert(Error::WatchdogUnconfirmed {
                        address: a,
                        on: false,
                        detail: format!("its state cannot be read to check: {e}"),
                    });
                }
            }
        }
        first_error.map_or(Ok(()), Err)
    }

    /// Gives CONFIGID_MOD_WATCHDOG_ENABLE of module `a` back the value it had in `before`.
    fn restore_watchdog_flag(&self, a: u8, before: ConfigWord) -> Result<(), Error> {
        let module = self.module(a)?;
        let now = module.config_word()?;
        let mut word = now;
        word.set(ConfigFlag::WatchdogEnable, before.contains(ConfigFlag::WatchdogEnable));
        if word != before {
            tracing::debug!(
                "module {a}: Config word {:#010x} was {:#010x} before; only the watchdog flag is restored",
                word.0,
                before.0
            );
        }
        if word != now {
            module.set_checked(Param::Config, Value::U32(word.0))?;
        }
        Ok(())
    }

    /// True when this session can arm the watchdog: on CAN, where the refresh is the broadcast of the
    /// manual's chapter 13, and on RS232 (unless [`BusConfig::watchdog_on_rs232`] is false), where it is the
    /// broadcast to address 0 in the form Schunk's libm5api sends. A host that dies (killed, powered off, its
    /// adapter or cable pulled) then stops the modules whose watchdog it switched on within 50 ms.
    pub fn watchdog_reliable(&self) -> bool {
        self.inner.can || self.inner.config.watchdog_on_rs232
    }

    /// Stops refreshing the watchdog and marks the session failed: every module whose watchdog this session
    /// switched on halts itself within 50 ms of the last refresh that reached it. What a session does when it
    /// can no longer confirm that it stopped what it started. Returns true if any module's watchdog was
    /// (or may have been) online.
    pub fn abandon_watchdog(&self) -> bool {
        self.inner.failed.store(true, Ordering::SeqCst);
        let mut duty = lock_mutex(&self.inner.duty);
        let was_serving = duty.serving;
        duty.serving = false;
        if was_serving {
            tracing::warn!("watchdog refresh stopped: the modules it protects halt within 50 ms");
        }
        was_serving && !(duty.online.is_empty() && duty.uncertain.is_empty())
    }

    /// True if this session switched the watchdog of module `address` on (or may have) and still
    /// refreshes it.
    pub fn watchdog_armed(&self, address: u8) -> bool {
        let duty = lock_mutex(&self.inner.duty);
        duty.serving && (duty.online.contains(&address) || duty.uncertain.contains(&address))
    }

    /// True while the session refreshes the watchdog.
    pub fn watchdog_served(&self) -> bool {
        lock_mutex(&self.inner.duty).serving
    }

    /// The last failure of the background refresh, if any.
    pub fn watchdog_error(&self) -> Option<String> {
        lock_mutex(&self.inner.duty).last_error.clone()
    }

    fn start_watchdog_thread(&self) {
        let mut slot = lock_mutex(&self.watchdog);
        if slot.is_some() {
            return;
        }
        let inner = Arc::clone(&self.inner);
        let stop = Arc::new(AtomicBool::new(false));
        let wake = self.inner.clock.signal();
        let ticket = self.inner.clock.reserve_participant();
        let (stop2, wake2) = (Arc::clone(&stop), wake.clone());
        let handle = thread::Builder::new()
            .name("powercube-watchdog".into())
            .spawn(move || {
                let _participant = ticket.enter();
                while !stop2.load(Ordering::SeqCst) {
                    let now = inner.clock.now();
                    let (serving, due, period) = {
                        let d = lock_mutex(&inner.duty);
                        (d.serving, d.next_due, d.period)
                    };
                    let mut until = if serving { due } else { now + Duration::from_secs(3600) };
                    if serving && now >= due {
                        match inner.io.try_lock() {
                            Some(mut io) => {
                                inner.serve_watchdog(&mut io);
                                until = lock_mutex(&inner.duty).next_due;
                            }
                            // The session is in a transaction, which serves the watchdog itself; look again soon.
                            None => until = now + period / 4,
                        }
                    }
                    wake2.wait_until(Some(until));
                }
            })
            .ok();
        match handle {
            Some(h) => *slot = Some(WatchdogThread { stop, wake, handle: Some(h) }),
            None => tracing::error!("cannot start the watchdog thread; transactions still refresh it"),
        }
    }

    fn stop_watchdog_thread(&self) {
        if let Some(mut t) = lock_mutex(&self.watchdog).take() {
            t.stop.store(true, Ordering::SeqCst);
            t.wake.raise();
            if let Some(h) = t.handle.take() {
                let _ = h.join();
            }
        }
    }

    /// Modules this session set in motion and has not seen stop.
    pub fn started(&self) -> Vec<u8> {
        lock_mutex(&self.inner.started).iter().copied().collect()
    }

    /// Halts every module this session set in motion that is still moving or cannot be asked; what
    /// [`Drop`] does, callable earlier.
    ///
    /// Each one is asked for its state and halted by address if it moves. A module that never answered this
    /// session and does not answer now is taken as absent. A known module that does not answer, or a halt
    /// that fails, calls for a broadcast Halt of the whole bus and marks the session failed.
    pub fn halt_started(&self) {
        self.halt_started_clean();
    }

    /// [`Bus::halt_started`]; false if a broadcast Halt was needed (the session failed).
    fn halt_started_clean(&self) -> bool {
        let started: Vec<u8> = lock_mutex(&self.inner.started).iter().copied().collect();
        if started.is_empty() {
            return true;
        }
        let known = lock_mutex(&self.inner.known).clone();
        let states =
            self.request_many(&started.iter().map(|a| (*a, Request::Get(Param::CubeState))).collect::<Vec<_>>());
        let mut halt_all = false;
        for (a, s) in started.iter().zip(states) {
            let moving = match s {
                Ok(Reply::Get(_, Value::U32(s))) => CubeState(s).contains(StateFlag::Motion),
                Ok(_) => true,
                // Never answered this session and silent now: nobody is there.
                Err(Error::Timeout { .. }) if !known.contains(a) => {
                    tracing::debug!("module {a} never answered this session: taken as absent");
                    false
                }
                // A module that answered before and not now cannot be halted by address: broadcast below.
                Err(Error::Timeout { .. }) => {
                    halt_all = true;
                    false
                }
                Err(_) => true,
            };
            if moving {
                tracing::warn!("halting module {a}, set in motion by this session");
                if self.request(*a, &Request::Action(Action::Halt)).is_err() {
                    halt_all = true;
                }
            }
        }
        if halt_all {
            tracing::warn!("{}: a module this session started cannot be asked; halting every module", self.describe());
            self.inner.failed.store(true, Ordering::SeqCst);
            let _ = self.broadcast(Broadcast::Halt);
        }
        lock_mutex(&self.inner.started).clear();
        !halt_all
    }
}

impl Drop for Bus {
    /// Halts what the session started and still moves; then, unless the session failed, switches off the
    /// watchdogs it switched on and restores their Config words ([`Bus::disable_watchdog`]); then stops the
    /// refresh thread. After a failure the watchdogs stay online and the modules halt within 50 ms.
    fn drop(&mut self) {
        let clean = self.halt_started_clean();
        let armed = {
            let duty = lock_mutex(&self.inner.duty);
            duty.serving || !duty.online.is_empty() || !duty.config_before.is_empty() || !duty.uncertain.is_empty()
        };
        if armed {
            if clean && !self.failed() {
                if let Err(e) = self.disable_watchdog() {
                    tracing::warn!("switching the watchdog off on drop failed (those modules halt within 50 ms): {e}");
                }
            } else {
                tracing::warn!("the session failed: the watchdog stays online and the modules halt within 50 ms");
            }
        }
        self.stop_watchdog_thread();
    }
}

fn check_reply(address: u8, request: &Request, reply: Reply) -> Result<Reply, Error> {
    match reply {
        Reply::Set(_, status) | Reply::Motion { status: Some(status), .. } if status != ACK_OK => {
            Err(Error::Refused { address, request: request.to_string(), status })
        }
        r => Ok(r),
    }
}

impl Inner {
    /// Sends the watchdog refresh if it is due.
    fn serve_watchdog(&self, io: &mut Transport) {
        let mut duty = lock_mutex(&self.duty);
        if !duty.serving {
            return;
        }
        let now = self.clock.now();
        if now < duty.next_due {
            return;
        }
        // Absolute deadlines: the next refresh is due one period after this one was due, so late sends do
        // not make the schedule drift; a refresh more than a period late is followed by the next one a
        // period after it went out.
        let next = duty.next_due + duty.period;
        duty.next_due = if next > now { next } else { now + duty.period };
        drop(duty);
        if let Err(e) = io.broadcast(&Broadcast::WatchdogRefresh) {
            tracing::warn!("watchdog refresh failed: {e}");
            lock_mutex(&self.duty).last_error = Some(e.to_string());
            self.failed.store(true, Ordering::SeqCst);
        }
    }

    fn next_watchdog_due(&self) -> Option<Timestamp> {
        let duty = lock_mutex(&self.duty);
        duty.serving.then_some(duty.next_due)
    }

    /// Sends every request, then collects acknowledges in any order until all came or `timeout` passed.
    fn transact_many(&self, batch: &[(u8, Request)], timeout: Duration) -> Vec<Result<Reply, Error>> {
        let mut io = self.io.lock();
        let mut results: Vec<Option<Result<Reply, Error>>> = batch.iter().map(|_| None).collect();
        let mut corrupt: Vec<Option<String>> = batch.iter().map(|_| None).collect();
        if let Err(e) = io.discard_stale() {
            return self.fail_all(batch, e);
        }
        let start = self.clock.now();
        for (address, request) in batch {
            if let Err(e) = io.send(*address, &request.encode()) {
                return self.fail_all(batch, e);
            }
        }
        let deadline = start + timeout;
        let mut open = batch.len();
        while open > 0 {
            self.serve_watchdog(&mut io);
            let now = self.clock.now();
            if now >= deadline {
                break;
            }
            let until = self.next_watchdog_due().map_or(deadline, |d| d.max(now).min(deadline));
            let wait = until.saturating_since(now);
            match io.recv(wait) {
                Ok(None) => {}
                Ok(Some(Incoming::Frame { address, payload })) => {
                    let reply = Reply::decode(&payload);
                    let slot = batch.iter().enumerate().position(|(i, (a, req))| {
                        *a == address && results[i].is_none() && reply.as_ref().is_ok_and(|r| req.is_answered_by(r))
                    });
                    match (slot, reply) {
                        (Some(i), Ok(r)) => {
                            results[i] = Some(Ok(r));
                            lock_mutex(&self.known).insert(address);
                            open -= 1;
                        }
                        (_, Err(e)) => {
                            tracing::debug!("module {address}: undecodable answer {payload:?}: {e}");
                            for (i, (a, _)) in batch.iter().enumerate() {
                                if *a == address && results[i].is_none() {
                                    corrupt[i] = Some(format!("{e} in {payload:?}"));
                                }
                            }
                        }
                        (None, Ok(r)) => {
                            // A module acknowledged a motion command it was not sent in this exchange: a command
                            // whose address or content was corrupted on the way (the modules ignore the BCC).
                            // It may be moving: the session halts it when it stops what it started.
                            let expected_motion = batch.iter().any(|(a, req)| *a == address && req.is_answered_by(&r));
                            let moves = matches!(r, Reply::Motion { .. } | Reply::IStep | Reply::Action(Action::Home));
                            if moves && !expected_motion {
                                tracing::warn!(
                                    "module {address} acknowledged {r}, which it was not sent: it may be moving"
                                );
                                lock_mutex(&self.started).insert(address);
                            }
                            // On a line that carries one request at a time, a frame from the module asked that
                            // answers something else is a corrupted answer (its echoed command or parameter is
                            // wrong), not silence.
                            if let [(a, req)] = batch {
                                if *a == address && results[0].is_none() {
                                    corrupt[0] = Some(format!("answer {r} does not echo {req}"));
                                }
                            }
                            tracing::debug!("module {address}: unexpected answer {r} (ignored)");
                        }
                    }
                }
                Ok(Some(Incoming::Corrupt(detail))) => {
                    tracing::debug!("{}: {detail}", self.description);
                    for (i, c) in corrupt.iter_mut().enumerate() {
                        if results[i].is_none() {
                            *c = Some(detail.clone());
                        }
                    }
                }
                Err(e) => return self.fail_all(batch, e),
            }
        }
        let waited = self.clock.now().saturating_since(start);
        if open > 0 {
            io.stale = true;
        }
        results
            .into_iter()
            .zip(corrupt)
            .zip(batch)
            .map(|((r, c), (address, request))| match (r, c) {
                (Some(r), _) => r,
                (None, Some(detail)) => Err(Error::Corrupt { address: *address, request: request.to_string(), detail }),
                (None, None) => Err(Error::Timeout { address: *address, request: request.to_string(), waited }),
            })
            .collect()
    }

    fn fail_all(&self, batch: &[(u8, Request)], e: LinkError) -> Vec<Result<Reply, Error>> {
        self.failed.store(true, Ordering::SeqCst);
        let text = e.to_string();
        let disconnect = e.is_disconnect();
        let mut first = Some(e);
        batch
            .iter()
            .map(|_| {
                Err(Error::Link(first.take().unwrap_or_else(|| {
                    if disconnect {
                        LinkError::Disconnected { port: self.description.clone(), reason: text.clone() }
                    } else {
                        LinkError::Io { port: self.description.clone(), source: std::io::Error::other(text.clone()) }
                    }
                })))
            })
            .collect()
    }
}

/// A checked ramp move ([`Module::move_to`]): where to, how fast, how close counts as arrived, how long to
/// wait.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MoveSpec {
    /// The target position (rad or m).
    pub target: Position,
    /// Velocity to write to TargetVel first (above 0); `None` leaves the module's TargetVel as it is.
    pub vel: Option<Velocity>,
    /// Acceleration to write to TargetAcc first (above 0); `None` leaves the module's TargetAcc as it is.
    pub acc: Option<Acceleration>,
    /// The in-position tolerance: the move succeeds only if the final actual position is at most this far
    /// from the target (rad or m, above 0). The manual offers no in-position window parameter, so this is
    /// the caller's; [`MoveSpec::DEFAULT_TOLERANCE`] by default.
    pub tolerance: Position,
    /// How long to wait for the end of the ramp before halting it.
    pub timeout: Duration,
}

impl MoveSpec {
    /// The default in-position tolerance: 0.001 rad (0.057°) on a rotary module, 1 mm on a linear one.
    pub const DEFAULT_TOLERANCE: Position = Position::native(0.001);

    /// A move to `target` with the module's own TargetVel and TargetAcc, the default tolerance, and 60 s to
    /// get there.
    pub fn to(target: Position) -> MoveSpec {
        MoveSpec { target, vel: None, acc: None, tolerance: Self::DEFAULT_TOLERANCE, timeout: Duration::from_secs(60) }
    }

    /// Checks that every number makes sense (finite; velocity, acceleration, tolerance and timeout above 0).
    pub fn validate(&self) -> Result<(), Error> {
        let bad = |what, must, value: String| Err(Error::InvalidArgument { what, must, value });
        if !self.target.value().is_finite() {
            return bad("the target position", "a finite number", self.target.value().to_string());
        }
        for (what, v) in
            [("the velocity", self.vel.map(|v| v.value())), ("the acceleration", self.acc.map(|a| a.value()))]
        {
            if let Some(v) = v {
                if !(v.is_finite() && v > 0.0) {
                    return bad(what, "a number above 0", v.to_string());
                }
            }
        }
        if !(self.tolerance.value().is_finite() && self.tolerance.value() > 0.0) {
            return bad("the tolerance", "a number above 0", self.tolerance.value().to_string());
        }
        if self.timeout.is_zero() {
            return bad("the timeout", "above 0", format!("{:?}", self.timeout));
        }
        Ok(())
    }
}

/// What a checked move ([`Module::move_to`]) did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MoveReport {
    /// Where the module stood before.
    pub start: Position,
    /// The final actual position, read from the module after the ramp ended (twice, both within the
    /// tolerance of the target).
    pub reached: Position,
    /// The state word at the end.
    pub state: CubeState,
}

/// How a parameter written with [`Module::set_checked`] was verified.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Readback {
    /// Read back (the parameter itself, or for the write-only TargetPos / TargetVel / TargetAcc their
    /// encoder-tick twin) and found as written; the value read.
    Same(Value),
    /// The parameter cannot be read back meaningfully; why.
    NotReadable(&'static str),
}

/// A value for messages: the number alone, floats with six decimals.
fn raw(v: &Value) -> String {
    match *v {
        Value::F32(x) => format!("{x:.6}"),
        Value::U32(x) if x > 0xFFFF => format!("{x:#010x}"),
        other => other.as_f64().map_or_else(|| format!("{other:?}"), |n| format!("{n}")),
    }
}

/// What a wait waits for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Until {
    Home,
    Motion,
    Ramp,
}

impl Until {
    fn what(self) -> &'static str {
        match self {
            Until::Home => "the end of homing",
            Until::Motion => "the end of the motion",
            Until::Ramp => "the end of the ramp",
        }
    }

    fn reached(self, s: CubeState) -> bool {
        !s.contains(StateFlag::Motion)
            && match self {
                Until::Home => s.contains(StateFlag::HomeOk),
                Until::Motion => true,
                Until::Ramp => s.contains(StateFlag::RampEnd),
            }
    }
}

/// One module on a [`Bus`], by address.
#[derive(Debug, Clone, Copy)]
pub struct Module<'a> {
    bus: &'a Bus,
    address: u8,
}

impl Module<'_> {
    /// The address.
    pub fn address(&self) -> u8 {
        self.address
    }

    fn request(&self, request: &Request) -> Result<Reply, Error> {
        self.bus.request(self.address, request)
    }

    /// Reads `param` (refused before sending if it is write-only).
    pub fn get(&self, param: Param) -> Result<Value, Error> {
        let request = Request::get(param)?;
        match self.request(&request)? {
            Reply::Get(_, v) => Ok(v),
            other => Err(unexpected(self.address, &request, other)),
        }
    }

    /// Writes `param` (refused before sending if it is read-only, `value` has another type or is not a
    /// finite number, or, on CAN, it would disable the acknowledges).
    pub fn set(&self, param: Param, value: Value) -> Result<(), Error> {
        let request = Request::set(param, value)?;
        self.request(&request)?;
        if param == Param::Config {
            lock_mutex(&self.bus.inner.kinds).remove(&self.address);
        }
        Ok(())
    }

    /// Reads `param` and converts it with `convert`; a value of another type is a corrupt answer.
    fn get_as<T>(&self, param: Param, convert: impl FnOnce(&Value) -> Option<T>) -> Result<T, Error> {
        let value = self.get(param)?;
        convert(&value).ok_or_else(|| unexpected(self.address, &Request::Get(param), format!("{value:?}")))
    }

    fn get_f32(&self, param: Param) -> Result<f32, Error> {
        self.get_as(param, Value::as_f32)
    }

    fn get_u32(&self, param: Param) -> Result<u32, Error> {
        self.get_as(param, Value::as_u32)
    }

    /// The actual position (ActPos).
    pub fn position(&self) -> Result<Position, Error> {
        Ok(Position::native(self.get_f32(Param::ActPos)?))
    }

    /// The actual position in encoder ticks (ActIPos).
    pub fn position_ticks(&self) -> Result<Ticks, Error> {
        Ok(Ticks(self.get_as(Param::ActIPos, Value::as_i32)?))
    }

    /// The state word (CubeState).
    pub fn state(&self) -> Result<CubeState, Error> {
        Ok(CubeState(self.get_u32(Param::CubeState)?))
    }

    /// Position, short state and DIO in one read (ActFPosStateDio).
    pub fn position_state_dio(&self) -> Result<(Position, ShortState, Dio), Error> {
        self.get_as(Param::ActFPosStateDio, |v| match *v {
            Value::PosStateDio { pos, state, dio } => Some((Position::native(pos), state, dio)),
            _ => None,
        })
    }

    /// The Config word.
    pub fn config_word(&self) -> Result<ConfigWord, Error> {
        Ok(ConfigWord(self.get_u32(Param::Config)?))
    }

    /// Rotary or linear (read once from the Config word, then remembered).
    pub fn kind(&self) -> Result<ModuleKind, Error> {
        if let Some(k) = lock_mutex(&self.bus.inner.kinds).get(&self.address) {
            return Ok(*k);
        }
        let kind =
            if self.config_word()?.contains(ConfigFlag::Linear) { ModuleKind::Linear } else { ModuleKind::Rotary };
        lock_mutex(&self.bus.inner.kinds).insert(self.address, kind);
        Ok(kind)
    }

    /// Type, version, serial number and state.
    pub fn info(&self) -> Result<ModuleInfo, Error> {
        let version = self.get_as(Param::DefCubeVersion, |v| match *v {
            Value::U16(v) => Some(CubeVersion(v)),
            _ => None,
        })?;
        Ok(ModuleInfo {
            address: self.address,
            kind: self.kind()?,
            version,
            serial: self.get_u32(Param::DefCubeSerial)?,
            state: self.state()?,
        })
    }

    /// Reset: clears the errors that can be cleared and STATE_HALTED.
    pub fn reset(&self) -> Result<(), Error> {
        self.request(&Request::Action(Action::Reset)).map(|_| ())
    }

    /// Starts homing (wait for it with [`Module::wait_home`]).
    pub fn home(&self) -> Result<(), Error> {
        self.request(&Request::Action(Action::Home)).map(|_| ())
    }

    /// Reset, and the manual's first way to restart after a watchdog expiry (chapter 13): if the module
    /// showed STATE_COMM_ERROR and the flag comes back after the Reset (its watchdog is online and nobody
    /// refreshes it: a host died), a life sign switches the watchdog offline and a second Reset clears the
    /// flags for good. Returns true if it did that.
    ///
    /// The life sign is only sent once the expiry has been seen to come back: a watchdog that is offline
    /// already, or that another live host serves, is left alone (a life sign would toggle it). That costs
    /// one wait of [`WATCHDOG_TIMEOUT`] × 2 on the session's clock, only when STATE_COMM_ERROR was set. A
    /// module whose watchdog this session serves only gets the Reset.
    pub fn reset_and_release_watchdog(&self) -> Result<bool, Error> {
        let served = lock_mutex(&self.bus.inner.duty).online.contains(&self.address);
        let before = if served { CubeState::EMPTY } else { self.state()? };
        self.reset()?;
        if !before.contains(StateFlag::CommError) {
            return Ok(false);
        }
        self.bus.inner.clock.sleep(WATCHDOG_TIMEOUT * 2);
        if !self.state()?.contains(StateFlag::CommError) {
            return Ok(false);
        }
        tracing::info!("module {}: its watchdog expires again after a reset; switching it offline", self.address);
        match self.request(&Request::Action(Action::LifeSign)) {
            Ok(_) | Err(Error::Timeout { .. }) => {}
            Err(e) => return Err(e),
        }
        lock_mutex(&self.bus.inner.duty).uncertain.remove(&self.address);
        self.reset()?;
        Ok(true)
    }

    /// Halt: stops at once; the module stays halted until a reset.
    pub fn halt(&self) -> Result<(), Error> {
        self.request(&Request::Action(Action::Halt))?;
        lock_mutex(&self.bus.inner.started).remove(&self.address);
        Ok(())
    }

    /// Stops the module after an action that may have set it in motion cannot go on, and says whether the
    /// module confirmed it: up to three Halts by address (a Halt may be repeated safely; not after the line
    /// itself failed), then, if none was acknowledged, a Halt broadcast to every module and the watchdog
    /// refresh stopped ([`Bus::abandon_watchdog`]), so that an armed module halts itself within 50 ms.
    pub fn stop_motion(&self) -> StopOutcome {
        let attempts = 1 + self.bus.inner.config.read_retries;
        let mut last = None;
        for _ in 0..attempts {
            match self.halt() {
                Ok(()) => return StopOutcome::Confirmed,
                Err(e) => {
                    let line_failed = matches!(e, Error::Link(_));
                    last = Some(e);
                    if line_failed {
                        break;
                    }
                }
            }
        }
        let reason = last.map_or_else(|| "no halt could be sent".to_string(), |e| e.to_string());
        tracing::warn!(
            "module {}: halt not confirmed ({reason}); broadcasting a halt and stopping the watchdog refresh",
            self.address
        );
        let watchdog_armed = self.bus.watchdog_armed(self.address);
        if let Err(e) = self.bus.broadcast(Broadcast::Halt) {
            tracing::warn!("the halt broadcast could not be sent either: {e}");
        }
        self.bus.abandon_watchdog();
        StopOutcome::Unconfirmed { reason, watchdog_armed }
    }

    /// An error of a request sent while this module may be moving: the motion is stopped, and the error
    /// says whether that was confirmed.
    fn lost(&self, cause: Error) -> Error {
        let stop = self.stop_motion();
        Error::LostDuringMotion { address: self.address, cause: Box::new(cause), stop }
    }

    fn cancelled(&self) -> bool {
        lock_mutex(&self.bus.inner.cancel).as_ref().is_some_and(CancelToken::is_cancelled)
    }

    /// Refuses a module that would ignore a motion command: one with an error flag ([`Error::Device`]) or
    /// halted ([`Error::Halted`]; a reset clears it).
    fn ready_for_motion(&self) -> Result<(), Error> {
        let state = self.state()?;
        if state.has_fault() {
            return Err(Error::Device { address: self.address, state });
        }
        if state.contains(StateFlag::Halted) {
            return Err(Error::Halted { address: self.address, state });
        }
        Ok(())
    }

    /// Reads a float parameter that must be a finite number.
    fn get_finite(&self, param: Param) -> Result<f32, Error> {
        let v = self.get_f32(param)?;
        if v.is_finite() {
            Ok(v)
        } else {
            Err(unexpected(self.address, &Request::Get(param), format!("{v} (not a finite number)")))
        }
    }

    /// The encoder ticks per unit (IncRatio), which must be a number above 0.
    fn inc_ratio(&self) -> Result<f64, Error> {
        let r = self.get_finite(Param::IncRatio)?;
        if r > 0.0 {
            Ok(f64::from(r))
        } else {
            Err(unexpected(self.address, &Request::Get(Param::IncRatio), format!("{r} (not above 0)")))
        }
    }

    /// Refuses `value` (named `what`) if it lies beyond the limit `param` of the module (`upper`: a maximum).
    fn within_limit(&self, what: &str, value: f64, param: Param, upper: bool) -> Result<(), Error> {
        let limit = f64::from(self.get_finite(param)?);
        let beyond = if upper { value > limit } else { value < limit };
        if beyond {
            return Err(Error::BeyondLimit {
                address: self.address,
                what: what.into(),
                value,
                limit: param,
                limit_value: limit,
            });
        }
        Ok(())
    }

    /// Reads the integer parameter `param` (in encoder ticks) and compares it with `value` units times
    /// `ratio`, allowing one tick for rounding; a difference is [`Error::Mismatch`] naming `written`.
    fn check_ticks(&self, written: Param, param: Param, value: f64, ratio: f64) -> Result<Value, Error> {
        let read = self.get(param)?;
        let ticks = read.as_f64().ok_or_else(|| unexpected(self.address, &Request::Get(param), format!("{read:?}")))?;
        let expected = (value * ratio).round();
        if (ticks - expected).abs() > 1.0 {
            return Err(Error::Mismatch {
                address: self.address,
                param: written,
                wrote: format!("{value:.6} ({expected} ticks)"),
                read: format!("{:.6} ({ticks} ticks in {param})", ticks / ratio),
            });
        }
        Ok(read)
    }

    /// Writes `param` and checks that the module took it: a target (TargetPos, TargetVel, TargetAcc, Cur and
    /// their tick twins) beyond the module's limit (MinPos / MaxPos, MaxVel, MaxAcc, MaxCur) is refused with
    /// [`Error::BeyondLimit`] before anything is sent; then the value is read back (the write-only targets
    /// through TargetPosInc / TargetVelInc / TargetAccInc) and a difference is [`Error::Mismatch`]: the
    /// module limited it, or the write was corrupted on the way (the modules ignore the BCC). DioSetup is
    /// compared on its output bits; Cur cannot be read back (a read gives the measured current).
    pub fn set_checked(&self, param: Param, value: Value) -> Result<Readback, Error> {
        Request::set(param, value)?;
        let number = value.as_f64();
        let name = param.name();
        match (param, number) {
            (Param::TargetPos, Some(v)) => {
                self.within_limit(name, v, Param::MinPos, false)?;
                self.within_limit(name, v, Param::MaxPos, true)?;
            }
            (Param::TargetPosInc, Some(v)) => {
                self.within_limit(name, v, Param::ActIMinPos, false)?;
                self.within_limit(name, v, Param::ActIMaxPos, true)?;
            }
            (Param::TargetVel, Some(v)) => self.within_limit(name, v.abs(), Param::MaxVel, true)?,
            (Param::TargetVelInc, Some(v)) => self.within_limit(name, v, Param::ActIMaxVel, true)?,
            (Param::TargetAcc, Some(v)) => self.within_limit(name, v.abs(), Param::MaxAcc, true)?,
            (Param::TargetAccInc, Some(v)) => self.within_limit(name, v, Param::ActIMaxAcc, true)?,
            (Param::Cur, Some(v)) => self.within_limit(name, v.abs(), Param::MaxCur, true)?,
            _ => {}
        }
        self.set(param, value)?;
        let twin = match param {
            Param::TargetPos => Some(Param::TargetPosInc),
            Param::TargetVel => Some(Param::TargetVelInc),
            Param::TargetAcc => Some(Param::TargetAccInc),
            _ => None,
        };
        if let (Some(twin), Some(v)) = (twin, number) {
            let ratio = self.inc_ratio()?;
            return self.check_ticks(param, twin, v, ratio).map(Readback::Same);
        }
        if param == Param::Cur {
            return Ok(Readback::NotReadable("reading Cur gives the measured current, not the value written"));
        }
        if !param.access().readable() {
            return Ok(Readback::NotReadable("the manual has no way to read it"));
        }
        let read = self.get(param)?;
        let same = match (param, value.as_u32(), read.as_u32()) {
            // Only the outputs of the DIO word are written; the inputs and switches are the outside world's.
            (Param::DioSetup, Some(w), Some(r)) => w & 0xF0 == r & 0xF0,
            _ => read == value,
        };
        if same {
            Ok(Readback::Same(read))
        } else {
            Err(Error::Mismatch { address: self.address, param, wrote: raw(&value), read: raw(&read) })
        }
    }

    /// RecalcPIDParam.
    pub fn recalc_pid(&self) -> Result<(), Error> {
        self.request(&Request::Action(Action::RecalcPid)).map(|_| ())
    }

    /// ResetTime: restarts the module's millisecond clock.
    pub fn reset_time(&self) -> Result<(), Error> {
        self.request(&Request::Action(Action::ResetTime)).map(|_| ())
    }

    /// A motion command in any mode; returns the extended acknowledge if `ack` asks for one.
    pub fn motion(&self, motion: Motion, ack: AckKind) -> Result<Option<ExtAck>, Error> {
        let request = Request::motion(motion, ack)?;
        match self.request(&request)? {
            Reply::Motion { ext, .. } => Ok(ext),
            other => Err(unexpected(self.address, &request, other)),
        }
    }

    /// A step in encoder ticks (SetIStep).
    pub fn istep(&self, pos: Ticks, time: Millis) -> Result<(), Error> {
        self.request(&Request::IStep { pos, time }).map(|_| ())
    }

    /// A ramp move to `pos`, first setting TargetVel and TargetAcc if `ramp` is given. Every value is checked
    /// before anything is sent (a NaN or infinite one is [`ModelError::NotFinite`]).
    pub fn move_ramp(&self, pos: Position, ramp: Option<Ramp>) -> Result<(), Error> {
        self.move_ramp_with(pos, ramp.map(|r| r.vel), ramp.map(|r| r.acc))
    }

    /// A ramp move to `pos`, first setting TargetVel if `vel` is given and TargetAcc if `acc` is given; what
    /// is not given stays as the module has it. Every value is checked before anything is sent.
    pub fn move_ramp_with(&self, pos: Position, vel: Option<Velocity>, acc: Option<Acceleration>) -> Result<(), Error> {
        let motion = Request::motion(Motion::FRamp { pos }, AckKind::Simple)?;
        let vel = vel.map(|v| Request::set(Param::TargetVel, Value::F32(v.value()))).transpose()?;
        let acc = acc.map(|a| Request::set(Param::TargetAcc, Value::F32(a.value()))).transpose()?;
        for r in [vel, acc].iter().flatten() {
            self.request(r)?;
        }
        self.request(&motion).map(|_| ())
    }

    /// Waits until homing has ended (STATE_HOME_OK, not moving).
    pub fn wait_home(&self, timeout: Duration, progress: &mut dyn FnMut(&Progress)) -> Result<CubeState, Error> {
        self.wait(Until::Home, timeout, progress)
    }

    /// Waits until the module stands still (no STATE_MOTION).
    pub fn wait_motion_end(&self, timeout: Duration, progress: &mut dyn FnMut(&Progress)) -> Result<CubeState, Error> {
        self.wait(Until::Motion, timeout, progress)
    }

    /// Waits until a ramp has ended (STATE_RAMP_END, not moving).
    pub fn wait_ramp_end(&self, timeout: Duration, progress: &mut dyn FnMut(&Progress)) -> Result<CubeState, Error> {
        self.wait(Until::Ramp, timeout, progress)
    }

    /// Homes the module and waits for the end of homing ([`Module::home`], [`Module::wait_home`]), with
    /// what a failure needs: nothing is sent if the session's cancel token is already cancelled
    /// ([`Error::Cancelled`] with [`StopOutcome::NotStarted`]); a Home that is not acknowledged may still
    /// have started homing, so the module is halted ([`Error::LostDuringMotion`] says whether that was
    /// confirmed); the wait halts on a timeout, a cancellation or a failing line. Returns the position and
    /// state at the end.
    pub fn home_and_wait(
        &self,
        timeout: Duration,
        progress: &mut dyn FnMut(&Progress),
    ) -> Result<(Position, CubeState), Error> {
        if timeout.is_zero() {
            return Err(Error::InvalidArgument { what: "the timeout", must: "above 0", value: "0".into() });
        }
        self.ready_for_motion()?;
        if self.cancelled() {
            return Err(Error::Cancelled { address: self.address, stop: StopOutcome::NotStarted });
        }
        if let Err(e) = self.home() {
            return Err(self.lost(e));
        }
        tracing::info!("module {}: homing", self.address);
        let state = self.wait_home(timeout, progress)?;
        Ok((self.position()?, state))
    }

    /// A ramp move with every check this protocol allows; what `motionlink powercube move` does.
    ///
    /// Before anything moves: the numbers are checked ([`MoveSpec::validate`]); the target is compared with
    /// MinPos and MaxPos, a velocity with MaxVel and an acceleration with MaxAcc, and one beyond its limit
    /// is refused ([`Error::BeyondLimit`]) instead of being limited silently by the module; TargetVel and
    /// TargetAcc are written if given and read back through TargetVelInc and TargetAccInc (a module whose
    /// TargetVel or TargetAcc is 0 is refused: the ramp would never get anywhere); a cancelled token stops
    /// here.
    ///
    /// Then the FRAMP motion command; right after its acknowledge the module's target (TargetPosInc) is read
    /// back and compared with the target sent (the modules ignore the BCC, so a corrupted command would
    /// otherwise run to a wrong place): a difference halts the module ([`Error::TargetMismatch`]). Then the
    /// wait for STATE_RAMP_END (polled every [`BusConfig::poll_interval`]), which halts on a timeout, a
    /// cancellation, a failing line or a module that stops answering (the error says whether the halt was
    /// confirmed). Finally the actual position is read twice, and both readings must lie within
    /// [`MoveSpec::tolerance`] of the target ([`Error::NotReached`] otherwise): one corrupted telegram
    /// cannot make a move that ended elsewhere look like a success.
    pub fn move_to(&self, spec: &MoveSpec, progress: &mut dyn FnMut(&Progress)) -> Result<MoveReport, Error> {
        spec.validate()?;
        self.ready_for_motion()?;
        let target = f64::from(spec.target.value());
        self.within_limit("the target position", target, Param::MinPos, false)?;
        self.within_limit("the target position", target, Param::MaxPos, true)?;
        if let Some(v) = spec.vel {
            self.within_limit("the velocity", f64::from(v.value()), Param::MaxVel, true)?;
        }
        if let Some(a) = spec.acc {
            self.within_limit("the acceleration", f64::from(a.value()), Param::MaxAcc, true)?;
        }
        let ratio = self.inc_ratio()?;
        let start = self.position()?;
        let motion = Request::motion(Motion::FRamp { pos: spec.target }, AckKind::Simple)?;
        for (param, twin, given) in [
            (Param::TargetVel, Param::TargetVelInc, spec.vel.map(|v| v.value())),
            (Param::TargetAcc, Param::TargetAccInc, spec.acc.map(|a| a.value())),
        ] {
            match given {
                Some(v) => {
                    self.set(param, Value::F32(v))?;
                    self.check_ticks(param, twin, f64::from(v), ratio)?;
                }
                None => {
                    let ticks = self.get(twin)?;
                    if ticks.as_f64() == Some(0.0) {
                        return Err(Error::InvalidArgument {
                            what: if param == Param::TargetVel { "the velocity" } else { "the acceleration" },
                            must: "given: the module's own value is 0, and a ramp with it would not move",
                            value: "none".into(),
                        });
                    }
                }
            }
        }
        if self.cancelled() {
            return Err(Error::Cancelled { address: self.address, stop: StopOutcome::NotStarted });
        }
        if let Err(e) = self.request(&motion) {
            // It may have arrived and started the ramp.
            return Err(self.lost(e));
        }
        tracing::info!("module {}: moving from {:.4} to {}", self.address, start.value(), spec.target.value());
        let sent = (target * ratio).round() as i32;
        match self.get_as(Param::TargetPosInc, Value::as_i32) {
            Ok(taken) if (i64::from(taken) - i64::from(sent)).abs() <= 1 => {}
            Ok(taken) => {
                let stop = self.stop_motion();
                return Err(Error::TargetMismatch { address: self.address, sent, taken, stop });
            }
            Err(e) => return Err(self.lost(e)),
        }
        let state = self.wait_ramp_end(spec.timeout, progress)?;
        let mut reached = start;
        for _ in 0..2 {
            reached = self.position()?;
            let difference = reached.value() - spec.target.value();
            // A NaN reading is not within any tolerance.
            let within = difference.abs() <= spec.tolerance.value();
            if !within {
                return Err(Error::NotReached {
                    address: self.address,
                    target: spec.target.value(),
                    reached: reached.value(),
                    difference,
                    tolerance: spec.tolerance.value(),
                    state,
                });
            }
        }
        Ok(MoveReport { start, reached, state })
    }

    fn wait(&self, until: Until, timeout: Duration, progress: &mut dyn FnMut(&Progress)) -> Result<CubeState, Error> {
        let clock = &self.bus.inner.clock;
        let start = clock.now();
        let deadline = start + timeout;
        let period = self.bus.inner.config.poll_interval.max(Duration::from_micros(100));
        let mut due = start;
        loop {
            let polled = self.state().and_then(|s| Ok((s, self.position()?)));
            let (state, position) = match polled {
                Ok(x) => x,
                // The line is failing, or the module stopped answering, while a motion may be running.
                Err(e) => return Err(self.lost(e)),
            };
            let now = clock.now();
            progress(&Progress { address: self.address, position, state, elapsed: now.saturating_since(start) });
            if state.has_fault() {
                lock_mutex(&self.bus.inner.started).remove(&self.address);
                return Err(Error::Device { address: self.address, state });
            }
            if state.contains(StateFlag::Halted) {
                lock_mutex(&self.bus.inner.started).remove(&self.address);
                return Err(Error::Halted { address: self.address, state });
            }
            if until.reached(state) {
                lock_mutex(&self.bus.inner.started).remove(&self.address);
                return Ok(state);
            }
            if self.cancelled() {
                return Err(Error::Cancelled { address: self.address, stop: self.stop_motion() });
            }
            if now >= deadline {
                let stop = self.stop_motion();
                return Err(Error::WaitTimeout {
                    address: self.address,
                    what: until.what(),
                    waited: timeout,
                    state,
                    stop,
                });
            }
            // Polls on a fixed schedule from the first one: never faster than the period, whatever the line;
            // a poll that took longer than a period skips the slots it missed.
            due += period;
            if due <= now {
                let missed = (now - due).as_nanos() / period.as_nanos() + 1;
                due += period * u32::try_from(missed).unwrap_or(u32::MAX);
            }
            clock.sleep_until(due.min(deadline));
        }
    }
}

#[cfg(test)]
mod tests;
