//! The PowerCube protocol as a sans-IO [`Session`](motionlink_link::session::Session) for a bus of modules
//! on RS232 or CAN: request/acknowledge matching (module, command and parameter echoed), answer timeouts,
//! retries of reads only, the watchdog refresh broadcast on its own 20 ms grid, and every multi-step
//! operation ([`Op`]: a checked move, homing, a scan, arming and disarming watchdogs, the stop of what was
//! started) as an `async fn` run by the one executor of `motionlink-link`. It is told what arrived and what time it is, and says
//! what to send and when to wake it; it has no thread, no clock and no I/O.
//!
//! Two operations move a module with every check the protocol allows: [`Op::MoveTo`] (and
//! [`Op::MoveGuarded`]), a ramp to a position with its velocity and acceleration written and read back,
//! and [`Op::RunMotion`], any of the manual's motion modes ([`MotionSpec`]: FRAMP, FSTEP, IRAMP, ISTEP run
//! to their target; FVEL, IVEL, FCUR, ICUR, FCOSLOOP, FRAMPLOOP held for a time and then ended), each with
//! its limits refused before anything moves, its end waited for and checked, and a [`MotionReport`].
//! [`Op::Motion`] is the raw command: units checked, nothing else. [`Op::Setpoint`] is between the two, for
//! control loops: a motion command streamed once per cycle, its numbers and limits checked, after the
//! first call to a module one exchange per call.
//!
//! The clients ([`Client`](crate::Client), [`AsyncClient`](crate::client)) run it over a link through
//! [`Driver`](motionlink_link::driver::Driver). Tests run it against the emulator directly:
//!
//! ```
//! use motionlink_link::session::{Action, Event, Input, Session as _};
//! use motionlink_link::emulator::Emulator as _;
//! use motionlink_link::Timestamp;
//! use motionlink_powercube::model::{Address, Param, Value};
//! use motionlink_powercube::session::{Config, Op, Output};
//! use motionlink_powercube::{Emulator, Session};
//!
//! let mut device = Emulator::new(&Default::default());
//! let mut session = Session::rs232(Config::rs232(), "in the test", Timestamp::ZERO);
//! let now = Timestamp::ZERO;
//! let id = session.start(Op::Get(Address::new(1).unwrap(), Param::DefCubeSerial), now);
//! while let Some(Action::Send(bytes)) = session.poll_transmit(now) {
//!     let mut answer = Vec::new();
//!     device.receive(now, &bytes, &mut answer);
//!     session.handle_input(Input::Bytes(&answer), now);
//! }
//! match session.poll_event() {
//!     Some(Event::Done(done, Ok(Output::Value(v)))) => assert_eq!((done, v), (id, Value::U32(1001))),
//!     other => panic!("{other:?}"),
//! }
//! ```

mod core;
mod ctx;
mod ops;
#[cfg(test)]
mod tests;
mod types;

use std::collections::VecDeque;
use std::time::Duration;

use motionlink_link::exec::{CoreGuard, CoreHandle, Executor, Report};
use motionlink_link::session::{Action as LinkAction, Event, Input, OpId};
use motionlink_link::{LinkError, Timestamp};

pub use types::{
    Begun, Config, Guard, HaltReport, HomeReport, ModuleFindings, ModuleInfo, ModulesAt, MotionEnding, MotionReport,
    MotionSpec, MoveReport, MoveSpec, Progress, Readback, ScanEntry, SetpointReport, Until, HALT_SETTLE,
};

use self::core::Core;
use self::ctx::Ctx;
use crate::error::{Error, StopOutcome};
use crate::model::{
    Acceleration, AckKind, Address, Broadcast, ConfigWord, CubeState, Dio, Millis, ModuleKind, Motion, Param, Position,
    ShortState, Ticks, Value, Velocity,
};
use crate::wire::{Action, ExtAck, Reply, Request};

/// An operation a [`Session`] runs. Addresses are checked once ([`Address`]); where a list may hold bad
/// ones (`u8`), each bad one gets its own [`Error::InvalidAddress`] and the others go on.
#[derive(Debug, Clone, PartialEq)]
pub enum Op {
    /// One request as it is, checked ([`Request::validate`]) and retried if it is a read. Its floats go on
    /// the wire as numbers in the module's own unit: no unit check (the typed operations have it). A motion
    /// whose operation is cancelled before its acknowledge came is halted. [`Output::Reply`].
    Request(Address, Request),
    /// Several requests; on CAN all at once, the acknowledges matched in any order. [`Output::Replies`].
    RequestMany(Vec<(Address, Request)>),
    /// One parameter of several modules (on CAN in one round). [`Output::Values`].
    ReadMany(Vec<Address>, Param),
    /// ActPos of several modules (on CAN in one round). [`Output::Positions`].
    Positions(Vec<Address>),
    /// A broadcast (never acknowledged; on RS232 libm5api's form to address 0). Home and StartMotion count as
    /// setting in motion every module the session knows. [`Output::Done`].
    Broadcast(Broadcast),
    /// Asks 1..31 for their version; then type, serial and state of each that answers. [`Output::Scan`].
    Scan,
    /// Reads a parameter. [`Output::Value`].
    Get(Address, Param),
    /// Writes a parameter (no read-back). [`Output::Done`].
    Set(Address, Param, Value),
    /// Writes a parameter with the limit check and the read-back. [`Output::Readback`].
    SetChecked(Address, Param, Value),
    /// ActPos. [`Output::Position`].
    Position(Address),
    /// ActIPos. [`Output::Ticks`].
    PositionTicks(Address),
    /// CubeState. [`Output::State`].
    State(Address),
    /// ActFPosStateDio. [`Output::PositionStateDio`].
    PositionStateDio(Address),
    /// The position and the short state in the fewest reads the module allows: ActFPosStateDio where it
    /// answers it (probed once), else CubeState and ActPos. [`Output::Look`].
    Look(Address),
    /// The Config word. [`Output::ConfigWord`].
    ConfigWord(Address),
    /// Rotary or linear (read once). [`Output::Kind`].
    Kind(Address),
    /// Type, version, serial number and state. [`Output::Info`].
    Info(Address),
    /// A one-byte command (Reset, Home, RecalcPIDParam, ResetTime, ...). [`Output::Done`].
    Action(Address, Action),
    /// Halt. [`Output::Done`].
    Halt(Address),
    /// Halt, then the state until STATE_MOTION is clear (polled every [`Config::poll_interval`], at most
    /// [`HALT_SETTLE`]), then the position: what `motionlink powercube stop` does. Still moving then:
    /// [`Error::StillMoving`]. [`Output::Halted`].
    HaltConfirmed(Address),
    /// A motion command, its units checked against the module's kind. [`Output::ExtAck`]: `None` to an
    /// extended acknowledge asked for is a module that answered with the simple one (the motion taken).
    Motion(Address, Motion, AckKind),
    /// SetIStep. [`Output::Done`].
    IStep(Address, Ticks, Millis),
    /// TargetVel and TargetAcc if given, then FRAMP (no checks beyond the units). [`Output::Done`].
    MoveRamp {
        /// The module.
        address: Address,
        /// The target.
        pos: Position,
        /// TargetVel to write first.
        vel: Option<Velocity>,
        /// TargetAcc to write first.
        acc: Option<Acceleration>,
    },
    /// Waits for homing or a motion to end, polled every [`Config::poll_interval`], with progress;
    /// halts on a timeout, a cancellation or a failing line. [`Output::State`].
    Wait(Address, Until, Duration),
    /// Home and wait, with what a failure needs (a Home that is not acknowledged may have started: halted).
    /// [`Output::Homed`].
    HomeAndWait(Address, Duration),
    /// A ramp move with every check this protocol allows: numbers and units, the module ready, the target
    /// against MinPos/MaxPos, velocity and acceleration against MaxVel/MaxAcc (refused, never clamped),
    /// TargetVel/TargetAcc written and read back, the motion command's target read back from TargetPosInc
    /// (a difference halts), the wait for STATE_RAMP_END, and the final position read twice within the
    /// tolerance. Any failure after the motion command halts the module and says whether that was
    /// confirmed. [`Output::Moved`].
    MoveTo(Address, MoveSpec),
    /// [`Op::HomeAndWait`] under a [`Guard`]; what the guard could not do is in the report's
    /// `not_verifiable`. Its end halts and disarms this module alone (see [`Op::MoveGuarded`]).
    /// [`Output::Homed`].
    HomeGuarded(Address, Duration, Guard),
    /// [`Op::MoveTo`] under a [`Guard`]: what `motionlink powercube move` does. The move's numbers, units and
    /// limits are checked before the guard arms anything. Its end (success, failure, cancel) halts this
    /// module if it still moves and switches off the watchdog the guard switched on, nothing else: guarded
    /// motions of other modules go on, and a watchdog armed by [`Op::EnableWatchdog`] stays armed. A second
    /// guarded motion of a module while one is under way is refused ([`Error::NotSupported`]) before any
    /// command goes to the module. [`Output::Moved`].
    MoveGuarded(Address, MoveSpec, Guard),
    /// A motion command of any mode ([`MotionSpec`]) with the rigour of [`Op::MoveTo`], run to its end.
    /// Before anything that changes the module is sent (reads only): the spec's numbers, their units against
    /// the module's kind, and its limits, refused ([`Error::OutsideLimits`]), never clamped: a position
    /// target (FRAMP, FSTEP, FRAMPLOOP, FCOSLOOP's far end) within MinPos..MaxPos, a tick target (IRAMP,
    /// ISTEP) within ActIMinPos..ActIMaxPos, a step's speed (its distance over its time) and a velocity
    /// within MaxVel (IVEL, ISTEP: ActIMaxVel), an FCUR current within MaxCur. Then the module ready (no
    /// error, not halted, its Config word lets it move), its position read, the command sent (a lost
    /// acknowledge halts it), and:
    ///
    /// - a position mode: the target read back where the module shows it (TargetPosInc for FRAMP / IRAMP,
    ///   StepInc for FSTEP / ISTEP), the wait for its end (STATE_RAMP_END for the ramps; no STATE_MOTION
    ///   for the steps, which set no ramp end), and the final position read twice within the tolerance:
    ///   [`MotionEnding::Reached`];
    /// - a continuous mode: the state polled for [`MotionSpec::hold`] (`None`: until cancelled; a fault or a
    ///   halt of the module's own ends it as an error), then a velocity mode is sent velocity 0 and waited
    ///   for at rest ([`MotionEnding::VelocityZero`]), a current or loop mode is halted, confirmed by its
    ///   state ([`MotionEnding::Halted`]: it takes no motion until a reset).
    ///
    /// A cancel halts the module ([`Error::Cancelled`] says whether that was confirmed). With a [`Guard`],
    /// the checks come before the guard arms anything, and the motion runs as [`Op::MoveGuarded`]'s does:
    /// what the guard could not do is in the report's `not_verifiable`. [`Output::MotionRun`].
    RunMotion(Address, MotionSpec, Option<Guard>),
    /// A streamed motion command ("setpoint") for a control loop, sent once per cycle (100..1000 Hz),
    /// typically FVEL_ACK, whose extended acknowledge gives the module's position, short state and DIO in
    /// the same exchange (what libm5api's `moveVelExtended` does every cycle). After the first call to a
    /// module, one exchange per call: the command and its acknowledge, everything else cached.
    ///
    /// Every call checks the motion's numbers ([`MotionSpec::validate`]: finite, ICUR within -500..500
    /// digits, a time above 0 for FSTEP, ISTEP and FCOSLOOP, no `_ACK` form of a loop), their units against
    /// the module's kind, and its limits by the rules of [`Op::RunMotion`], refused
    /// ([`Error::OutsideLimits`], nothing sent), never clamped, against values read once per module and
    /// cached. A step's speed (FSTEP, ISTEP) starts from the position of the last extended acknowledge of
    /// the same form (a float position, ticks), read only where there is none: with the simple acknowledge
    /// a step reads the position at every call. The first call to a module (and the first after its cache
    /// was dropped) also refuses a module in error, halted, or whose Config word would not let it move, and
    /// with [`Guard::Watchdog`] arms its watchdog where the link allows it (as a guarded motion decides; on
    /// RS232 the first arming also finds out, once per session, whether the module takes the broadcast
    /// refresh, about 90 ms): it stays armed and refreshed after the call, until [`Op::DisableWatchdog`] or
    /// the close (which halts what this session started and switches the watchdogs off); a later call does
    /// not arm it again until the cache is dropped. A link that cannot serve it is no error: the report
    /// says `watchdog: false`. [`Guard::HaltOnly`] never arms it.
    ///
    /// The cache of a module is dropped when this session writes one of those limits (MinPos, MaxPos,
    /// MaxVel, MaxCur, ActIMinPos, ActIMaxPos, ActIMaxVel) or its Config word (beyond the watchdog flag its
    /// own arming and disarming toggle), resets, homes or halts it (also by a broadcast), when a setpoint
    /// fails (any error), and when a state read shows the module in error or halted. A limit changed by
    /// another program (or a module homed or reset by one) is not seen until then.
    ///
    /// An extended acknowledge with SHORT_NOT_OK ("(STATE_ERROR) OR (NOT STATE_HOME_OK) OR (STATE_HALTED)")
    /// has the state word read: an error flag or STATE_HALTED ends the call ([`Error::Device`],
    /// [`Error::Halted`]; a module still moving then is halted, [`Error::FailedDuringMotion`]); a module
    /// merely not homed streams on, its state read again at most every 100 ms (SHORT_NOT_OK cannot show a
    /// halt or an error of a module that is not homed). With the simple acknowledge nothing shows the
    /// module's state: a halted module acknowledges the commands it ignores.
    ///
    /// The command is never repeated (a motion command is not); one whose acknowledge is lost halts the
    /// module ([`Error::FailedDuringMotion`]). A cancel halts it ([`Error::Cancelled`]): while the
    /// acknowledge is awaited, or before the command if an earlier one of this session set it moving. The
    /// module counts as set in motion: the close halts it. [`Output::Setpoint`].
    Setpoint(Address, Motion, AckKind, Guard),
    /// Halts a module after an action that may have set it in motion cannot go on: up to three Halts, then
    /// a broadcast Halt and the watchdog refresh stopped. [`Output::Stop`].
    StopMotion(Address),
    /// Halts every module this session set in motion that still moves or cannot be asked. [`Output::Done`].
    HaltStarted,
    /// Switches the watchdog on in these modules: CONFIGID_MOD_WATCHDOG_ENABLE set where clear (read back,
    /// the word before remembered), the refresh served from now on, a life sign to each (never repeated:
    /// an unconfirmed one is [`Error::WatchdogUnconfirmed`]). A module showing STATE_COMM_ERROR is refused
    /// before anything changes. [`Output::Done`].
    EnableWatchdog(Vec<Address>),
    /// Undoes [`Op::EnableWatchdog`]: a second life sign to each module (one only, whatever else runs), the
    /// refresh stopped once no watchdog needs it, unconfirmed watchdogs observed (an online one expires), the
    /// flag cleared again where this session set it. A watchdog that a guarded motion under way armed stays
    /// online until that motion ends (its end switches it off). A failed session leaves them online
    /// ([`Error::WatchdogLeftOnline`]). [`Output::Done`].
    DisableWatchdog,
    /// Reset; if STATE_COMM_ERROR comes back (a host died with the watchdog online), a life sign switches it
    /// offline and a second Reset clears it. Refused ([`Error::NotSupported`], nothing sent) for a module
    /// whose watchdog this session serves. [`Output::Released`].
    ResetAndReleaseWatchdog(Address),
    /// Whether the module answers ActFPosStateDio (0x62), found out once (a read) and remembered in its
    /// [`ModuleFindings`]. [`Output::Done`].
    ProbePosStateDio(Address),
}

impl Op {
    /// A stop (HaltConfirmed): a cancel leaves it running to its end, so that its reads are retried as any
    /// stop's (the caller that gave up on it still wants the module halted).
    fn firm(&self) -> bool {
        matches!(self, Op::HaltConfirmed(_))
    }

    /// The name of an operation that sets nothing in motion and may be dropped at once when cancelled.
    fn abortable(&self) -> Option<&'static str> {
        Some(match self {
            Op::Request(_, r) if r.is_idempotent() => "a read",
            Op::RequestMany(rs) if rs.iter().all(|(_, r)| r.is_idempotent()) => "reads",
            Op::ReadMany(..) | Op::Get(..) => "a read",
            Op::Positions(_) | Op::Position(_) | Op::PositionTicks(_) | Op::PositionStateDio(_) | Op::Look(_) => {
                "a position read"
            }
            Op::State(_) | Op::ConfigWord(_) | Op::Kind(_) | Op::Info(_) => "a read",
            Op::Scan => "the scan",
            Op::ProbePosStateDio(_) => "a read",
            _ => return None,
        })
    }
}

/// What an operation ends with; each [`Op`] names its variant.
#[derive(Debug)]
pub enum Output {
    /// Done, nothing to give.
    Done,
    /// An acknowledge.
    Reply(Reply),
    /// One acknowledge or error per request.
    Replies(Vec<Result<Reply, Error>>),
    /// One value or error per module.
    Values(Vec<Result<Value, Error>>),
    /// One position or error per module.
    Positions(Vec<Result<Position, Error>>),
    /// The modules found.
    Scan(Vec<ScanEntry>),
    /// A parameter's value.
    Value(Value),
    /// How a write was verified.
    Readback(Readback),
    /// A position (rad or m where the session knows the module's kind).
    Position(Position),
    /// A position in encoder ticks.
    Ticks(Ticks),
    /// A state word.
    State(CubeState),
    /// Position, short state and DIO.
    PositionStateDio(Position, ShortState, Dio),
    /// A position and short state, with the full state word where it was read for them (a module without
    /// ActFPosStateDio).
    Look(Position, ShortState, Option<CubeState>),
    /// A Config word.
    ConfigWord(ConfigWord),
    /// Rotary or linear.
    Kind(ModuleKind),
    /// Type, version, serial, state.
    Info(ModuleInfo),
    /// The extended acknowledge of a motion command, if one was asked for.
    ExtAck(Option<ExtAck>),
    /// What homing did.
    Homed(HomeReport),
    /// What a checked move did.
    Moved(MoveReport),
    /// What a motion of any mode ([`Op::RunMotion`]) did.
    MotionRun(MotionReport),
    /// What a streamed setpoint ([`Op::Setpoint`]) did.
    Setpoint(SetpointReport),
    /// What became of a stop.
    Stop(StopOutcome),
    /// What a confirmed halt found.
    Halted(HaltReport),
    /// Whether a reset had to switch an expired watchdog offline.
    Released(bool),
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Closing {
    Open,
    /// Every operation was asked to end; the close sequence starts when they have.
    Waiting,
    Running,
    Closed,
}

/// The id of the close sequence (operations get ids from 1).
const CLOSE: OpId = OpId(0);

/// The session's operations, run by the one executor of `motionlink-link`.
type Ops = Executor<Core, Progress, Result<Output, Error>>;

/// A session with the modules on one RS232 line or one CAN bus; see the [module documentation](self).
pub struct Session {
    exec: Ops,
    /// The operations that set nothing in motion and may be dropped at once when cancelled: what each is.
    abortable: std::collections::BTreeMap<OpId, &'static str>,
    /// The stops under way ([`Op::firm`]): a cancel does not reach them.
    firm: std::collections::BTreeSet<OpId>,
    events: VecDeque<Event<Session>>,
    closing: Closing,
}

impl std::fmt::Debug for Session {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Session").field("port", &self.core().port).field("ops", &self.exec.len()).finish()
    }
}

impl Session {
    /// A session on an RS232 line (a serial port, TCP, a pty), `port` naming it in messages.
    pub fn rs232(config: Config, port: impl Into<String>, now: Timestamp) -> Session {
        Session::new(config, false, port.into(), now)
    }

    /// A session on a CAN bus.
    pub fn can(config: Config, port: impl Into<String>, now: Timestamp) -> Session {
        Session::new(config, true, port.into(), now)
    }

    fn new(config: Config, can: bool, port: String, now: Timestamp) -> Session {
        Session {
            exec: Executor::new(Core::new(config, can, port, now), now),
            abortable: std::collections::BTreeMap::new(),
            firm: std::collections::BTreeSet::new(),
            events: VecDeque::new(),
            closing: Closing::Open,
        }
    }

    fn core(&self) -> CoreGuard<'_, Core, Progress> {
        self.exec.core()
    }

    /// Every call into the session tells it the time: the engine's and the operations' clock.
    fn now_is(&mut self, now: Timestamp) {
        self.exec.core_at(now).now = now;
    }

    /// The session's settings.
    pub fn config(&self) -> Config {
        self.core().config.clone()
    }

    /// True on a CAN bus.
    pub fn is_can(&self) -> bool {
        self.core().can
    }

    /// Modules this session set in motion and has not seen stop.
    pub fn started(&self) -> Vec<Address> {
        addresses(&self.core().started)
    }

    /// Modules known to exist: every address that answered this session.
    pub fn known(&self) -> Vec<Address> {
        addresses(&self.core().known)
    }

    /// What this session has established about module `address` where the manual is silent (see
    /// [`ModuleFindings`]).
    pub fn findings(&self, address: Address) -> ModuleFindings {
        self.core().findings.get(&address.get()).copied().unwrap_or_default()
    }

    /// Takes what `known` says of module `address` (from a device profile, or a probe) where this session has
    /// not established it yet: those behaviours are not probed again, and no warning is given for them.
    pub fn seed_findings(&mut self, address: Address, known: ModuleFindings) {
        let mut core = self.core();
        let f = core.findings.entry(address.get()).or_default();
        *f = f.or(known);
    }

    /// The kind of module `address`, if the session has read it.
    pub fn kind_of(&self, address: Address) -> Option<ModuleKind> {
        self.core().kinds.get(&address.get()).copied()
    }

    /// True once the session has failed: its line broke, a watchdog refresh could not be sent, or a module
    /// it set in motion could not be confirmed stopped. A failed session leaves the watchdog online.
    pub fn failed(&self) -> bool {
        self.core().failed
    }

    /// True when this session can arm the watchdog: on CAN, and on RS232 unless
    /// [`Config::watchdog_on_rs232`] is false.
    pub fn watchdog_reliable(&self) -> bool {
        let core = self.core();
        core.can || core.config.watchdog_on_rs232
    }

    /// True while the session refreshes the watchdog.
    pub fn watchdog_served(&self) -> bool {
        self.core().duty.serving
    }

    /// True if this session switched the watchdog of `address` on (or may have) and still refreshes it.
    pub fn watchdog_armed(&self, address: Address) -> bool {
        let core = self.core();
        core.duty.serving && core.duty.may_be_online(address.get())
    }

    /// A view of this session's watchdog duty that outlives the session (a driver that closes drops it):
    /// [`WatchdogView::armed`] says afterwards which modules' watchdogs were left armed.
    pub fn watchdog_view(&self) -> WatchdogView {
        WatchdogView(self.exec.handle())
    }

    /// When the next watchdog refresh is due, while the session serves it.
    pub fn watchdog_next_due(&self) -> Option<Timestamp> {
        let core = self.core();
        core.duty.serving.then_some(core.duty.next_due)
    }

    /// The last failure of a watchdog refresh, if any.
    pub fn watchdog_error(&self) -> Option<String> {
        self.core().duty.last_error.clone()
    }

    /// Stops refreshing the watchdog on purpose and marks the session failed: every module whose watchdog
    /// this session switched on halts itself within 50 ms of the last refresh that reached it. Returns true
    /// if any module's watchdog was (or may have been) online.
    pub fn abandon_watchdog(&mut self) -> bool {
        ops::abandon_watchdog(&mut self.core())
    }

    /// What a host that dies leaves behind: no refresh, nothing to stop, nothing to switch off.
    #[cfg(test)]
    pub(crate) fn die(&mut self) {
        let mut core = self.core();
        core.duty.serving = false;
        core.duty.online.clear();
        core.duty.config_before.clear();
        core.started.clear();
    }

    /// Polls every operation whose awaited result is there, until none is; starts the close sequence when
    /// it is due.
    fn run_ops(&mut self) {
        loop {
            if self.closing == Closing::Waiting && self.exec.is_empty() {
                self.closing = Closing::Running;
                self.exec.spawn(CLOSE, |ctx| async move { Ctx(ctx).close_sequence().await.map(|()| Output::Done) });
            }
            let mut ended = Vec::new();
            let (events, closing) = (&mut self.events, &mut self.closing);
            self.exec.run(|report| match report {
                Report::Progress(op, p) => events.push_back(Event::Progress(op, p)),
                Report::Done(CLOSE, r) => {
                    ended.push(CLOSE);
                    *closing = Closing::Closed;
                    events.push_back(Event::Closed(r.map(|_| ())));
                }
                Report::Done(id, r) => {
                    ended.push(id);
                    events.push_back(Event::Done(id, r));
                }
            });
            for id in ended {
                self.abortable.remove(&id);
                self.firm.remove(&id);
                self.core().forget(id);
            }
            if !(self.closing == Closing::Waiting && self.exec.is_empty()) {
                return;
            }
        }
    }
}

impl motionlink_link::session::Session for Session {
    type Op = Op;
    type Output = Output;
    type Progress = Progress;
    type Error = Error;

    fn start(&mut self, op: Op, now: Timestamp) -> OpId {
        let id = self.exec.next_id();
        self.now_is(now);
        if self.closing != Closing::Open {
            self.events.push_back(Event::Done(id, Err(Error::Closed)));
            return id;
        }
        if op.firm() {
            self.firm.insert(id);
        }
        if let Some(what) = op.abortable() {
            self.abortable.insert(id, what);
        }
        self.exec.spawn(id, |ctx| ops::run(Ctx(ctx), op));
        self.run_ops();
        id
    }

    fn cancel(&mut self, id: OpId, now: Timestamp) {
        self.now_is(now);
        if id == CLOSE || self.firm.contains(&id) || !self.exec.contains(id) {
            return;
        }
        match self.abortable.remove(&id) {
            Some(what) => {
                self.exec.abort(id);
                self.core().forget(id);
                self.events.push_back(Event::Done(id, Err(Error::CancelledBeforeMotion { what })));
            }
            None => {
                self.exec.cancel(id);
            }
        }
        self.run_ops();
    }

    fn close(&mut self, now: Timestamp) {
        self.now_is(now);
        if self.closing != Closing::Open {
            return;
        }
        self.closing = Closing::Waiting;
        for id in self.exec.ids() {
            self.cancel(id, now);
        }
        self.run_ops();
    }

    fn handle_input(&mut self, input: Input<'_>, now: Timestamp) {
        self.now_is(now);
        match input {
            Input::Bytes(b) => self.core().handle_bytes(b, now),
            Input::Frame(f) => self.core().handle_frame(f, now),
        }
        self.run_ops();
    }

    fn handle_link_error(&mut self, error: LinkError, now: Timestamp) {
        self.now_is(now);
        self.core().handle_link_error(error, now);
        self.run_ops();
    }

    fn handle_reopened(&mut self, _result: Result<(), LinkError>, now: Timestamp) {
        // This session never asks for its port to be reopened.
        self.now_is(now);
    }

    fn poll_transmit(&mut self, now: Timestamp) -> Option<LinkAction> {
        self.now_is(now);
        loop {
            self.run_ops();
            let action = self.core().poll_transmit(now);
            if action.is_some() {
                return action;
            }
            // Sending may have ended a job (a broadcast that went out): its operation goes on first.
            if !self.exec.has_ready() {
                return None;
            }
        }
    }

    fn poll_timeout(&self) -> Option<Timestamp> {
        let engine = self.core().poll_timeout();
        [engine, self.exec.poll_timeout()].into_iter().flatten().min()
    }

    fn handle_timeout(&mut self, now: Timestamp) {
        self.now_is(now);
        self.core().handle_timeout(now);
        self.exec.handle_timeout(now);
        self.run_ops();
    }

    fn poll_event(&mut self) -> Option<Event<Self>> {
        self.events.pop_front()
    }

    fn wants_input(&self) -> bool {
        self.core().wants_input()
    }

    fn is_idle(&self) -> bool {
        self.exec.is_empty() && matches!(self.closing, Closing::Open | Closing::Closed) && self.core().is_quiet()
    }
}

/// A handle on a session's watchdog duty ([`Session::watchdog_view`]), still readable once the session is
/// gone.
#[derive(Clone)]
pub struct WatchdogView(CoreHandle<Core, Progress>);

impl std::fmt::Debug for WatchdogView {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_tuple("WatchdogView").field(&self.armed()).finish()
    }
}

impl WatchdogView {
    /// The modules whose watchdog the session switched on (or may have: a life sign not confirmed) and has
    /// not switched off again, in address order.
    pub fn armed(&self) -> Vec<Address> {
        let core = self.0.core();
        addresses(&core.duty.left_online().into_iter().collect())
    }

    /// `e` with what this view knows: a [`Error::CloseTimedOut`] that could not say which watchdogs were
    /// armed gets the list.
    pub fn explain(&self, e: Error) -> Error {
        match e {
            Error::CloseTimedOut { bound, armed: None } => Error::CloseTimedOut { bound, armed: Some(self.armed()) },
            other => other,
        }
    }
}

/// The module addresses in `set` (every one the session stores came from a checked address or an answer
/// from a module address; anything else is left out rather than invented).
fn addresses(set: &std::collections::BTreeSet<u8>) -> Vec<Address> {
    set.iter().filter_map(|&a| Address::new(a).ok()).collect()
}
