//! [`Client`]: the blocking client, thin typed methods over a [`Driver`] running the [`Session`].

use std::sync::Mutex;
use std::time::Duration;

use motionlink_link::can::CanLink;
use motionlink_link::cancel::CancelToken;
use motionlink_link::clock::lock;
use motionlink_link::driver::{Driver, DriverConfig, Port};
use motionlink_link::url::PortUrl;
use motionlink_link::{LinkError, SharedClock};

use super::calls::{self, Call};
use super::PortLink;
use crate::error::{Error, StopOutcome};
use crate::model::{
    Acceleration, AckKind, Address, Broadcast, ConfigWord, CubeState, Dio, Millis, ModuleKind, Motion, Param, Position,
    Ramp, ShortState, Ticks, Value, Velocity,
};
use crate::report::ModuleDetails;
use crate::session::{
    Config, Guard, HaltReport, HomeReport, ModuleInfo, MotionReport, MotionSpec, MoveReport, MoveSpec, Op, Output,
    Progress, Readback, ScanEntry, Session, SetpointReport, Until,
};
use crate::wire::{Action, ExtAck, Reply, Request};

/// A session with the modules on one line (RS232) or one CAN bus, for blocking callers (any number of
/// threads: share it by reference; their requests interleave on the line as the session schedules them).
///
/// The session runs in a [`Driver`]: a caller whose operation is under way drives the line itself, and
/// one background thread refreshes the watchdog between calls.
///
/// Closing ([`Client::close`], or dropping it) halts every module the session set in motion that is still
/// moving (or cannot be asked), then, if the session switched watchdogs on and has not failed, switches them
/// off again and restores the Config words. It waits for that at most [`Config::close_bound`] (5 s by
/// default; the call returns at most one read slice of the driver, 20 ms, later); then the refresh stops. A session that failed (its line broke, a refresh could not be sent, a
/// module it started could not be confirmed stopped) leaves the watchdogs online: the modules halt within
/// 50 ms, which is the watchdog's purpose.
pub struct Client {
    driver: Driver<Session>,
    cancel: Mutex<Option<CancelToken>>,
    config: Config,
    can: bool,
}

impl std::fmt::Debug for Client {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Client").field("port", &self.driver.port_name()).finish()
    }
}

/// The driver of a session on `link`, and whether it is a CAN bus.
pub(crate) fn driver_on(link: PortLink, clock: SharedClock, config: &Config) -> Result<(Driver<Session>, bool), Error> {
    Ok(match link {
        PortLink::Rs232(link) => {
            let session = Session::rs232(config.clone(), link.describe(), clock.now());
            (driver(session, Port::Bytes(link), clock, config)?, false)
        }
        PortLink::Can(link) => {
            let session = Session::can(config.clone(), link.describe(), clock.now());
            (driver(session, Port::Can(link), clock, config)?, true)
        }
    })
}

/// The driver for `session` over `port`, closing within the session's bound.
fn driver(session: Session, port: Port, clock: SharedClock, config: &Config) -> Result<Driver<Session>, Error> {
    let name = port.describe();
    let driver_config = DriverConfig { close_bound: config.close_bound, ..DriverConfig::default() };
    Driver::new(session, port, None, clock, driver_config).map_err(|e| {
        Error::Link(LinkError::Open { port: name, reason: format!("cannot start the session's thread: {e}") })
    })
}

impl Client {
    /// Opens the port `url` names (a serial device or TCP port at [`Config::baud`], an SLCAN adapter at
    /// [`Config::can_bitrate`], a SocketCAN interface; not `sim`) and starts a session on it. The timing
    /// defaults differ by carrier: give [`Config::can`] for a CAN port and [`Config::rs232`] for the others.
    pub fn open(url: &PortUrl, clock: SharedClock, config: Config) -> Result<Client, Error> {
        let link = PortLink::open_configured(url, &config, &clock)?;
        Client::with_link(link, clock, config)
    }

    /// A session over an open link: an RS232 byte link (a serial port, TCP, a pty, an in-memory link) or a CAN
    /// link (SocketCAN, SLCAN, the in-memory bus, or any embedded-can driver through
    /// [`EmbeddedCanLink`](motionlink_link::can::embedded::EmbeddedCanLink)).
    pub fn with_link(link: impl Into<PortLink>, clock: SharedClock, config: Config) -> Result<Client, Error> {
        let (driver, can) = driver_on(link.into(), clock, &config)?;
        Ok(Client { driver, cancel: Mutex::new(None), config, can })
    }

    /// The driver underneath (to run any [`Op`] with [`Driver::run_with`], or look at the session).
    pub fn driver(&self) -> &Driver<Session> {
        &self.driver
    }

    /// The port, for messages.
    pub fn port(&self) -> &str {
        self.driver.port_name()
    }

    /// True on a CAN bus.
    pub fn is_can(&self) -> bool {
        self.can
    }

    /// The session's settings.
    pub fn config(&self) -> &Config {
        &self.config
    }

    /// The session's clock.
    pub fn clock(&self) -> &SharedClock {
        self.driver.clock()
    }

    /// Every motion and wait of this client watches `token`: when it is cancelled (a signal), the motion is
    /// halted and the call returns [`Error::Cancelled`] saying whether the module confirmed the halt. A
    /// [`Client::scan`] watches it too.
    pub fn set_cancel(&self, token: CancelToken) {
        *lock(&self.cancel) = Some(token);
    }

    /// Runs `f` on the session (its statistics, its watchdog duty).
    pub fn session<R>(&self, f: impl FnOnce(&mut Session) -> R) -> R {
        self.driver.with_session(f)
    }

    /// Runs `op` to its end, with `progress` for its progress reports; a motion or wait is cancelled (and
    /// its motion halted) when the token of [`Client::set_cancel`] is.
    pub fn run_with(&self, op: Op, progress: &mut dyn FnMut(&Progress)) -> Result<Output, Error> {
        // Reads set nothing in motion: a cancellation does not cut them short (a program that was asked to
        // stop still reads what it needs to report). Except the scan: up to 31 reply timeouts on a quiet
        // RS232 line, which a program that was asked to stop has no use for.
        let watches = !op_is_read(&op) || matches!(op, Op::Scan);
        let token = if watches { lock(&self.cancel).clone() } else { None };
        self.driver.run_with(op, progress, token.as_ref())
    }

    /// Runs `op` to its end.
    pub fn run(&self, op: Op) -> Result<Output, Error> {
        self.run_with(op, &mut |_| {})
    }

    pub(crate) fn call<T>(&self, call: Call<T>) -> Result<T, Error> {
        self.call_with(call, &mut |_| {})
    }

    pub(crate) fn call_with<T>(&self, call: Call<T>, progress: &mut dyn FnMut(&Progress)) -> Result<T, Error> {
        let output = self.run_with(call.op.clone(), progress);
        call.result(output)
    }

    /// A handle on the module at `address` (checked once: [`Address::new`]). Nothing is sent.
    pub fn module(&self, address: Address) -> Module<'_> {
        Module { client: self, address }
    }

    /// One request, checked before it is sent ([`Request::validate`]; nothing is sent if it breaks the
    /// manual's rules), its acknowledge checked; reads are retried. Floats go on the wire as numbers in the
    /// module's own unit: no unit check.
    pub fn request(&self, address: Address, request: &Request) -> Result<Reply, Error> {
        request.validate()?;
        self.call(calls::request(address, *request))
    }

    /// Several requests to several modules; on CAN all are sent at once and the acknowledges collected in
    /// any order, on RS232 one after the other. Each is checked (one that breaks the rules gets its error and
    /// is not sent; the others are). Reads that fail are retried.
    pub fn request_many(&self, requests: &[(Address, Request)]) -> Vec<Result<Reply, Error>> {
        let n = requests.len();
        self.call(calls::request_many(requests.to_vec())).unwrap_or_else(|e| fail_all(n, &e))
    }

    /// Reads `param` of every module in `addresses` (on CAN in one round).
    pub fn read_many(&self, addresses: &[Address], param: Param) -> Vec<Result<Value, Error>> {
        let n = addresses.len();
        self.call(calls::read_many(addresses.to_vec(), param)).unwrap_or_else(|e| fail_all(n, &e))
    }

    /// The positions of `addresses` (ActPos), on CAN in one round: in rad or m for a module whose kind the
    /// session has read ([`Module::kind`], a scan, arming its watchdog), in the module's own unit otherwise.
    pub fn positions(&self, addresses: &[Address]) -> Vec<Result<Position, Error>> {
        let n = addresses.len();
        self.call(calls::positions(addresses.to_vec())).unwrap_or_else(|e| fail_all(n, &e))
    }

    /// Sends a broadcast (see [`Op::Broadcast`]).
    pub fn broadcast(&self, broadcast: Broadcast) -> Result<(), Error> {
        self.call(calls::done(Op::Broadcast(broadcast)))
    }

    /// Asks addresses 1..31 for their version; returns every address that answers, with its type, serial
    /// number and state, or the error that kept them from being read. Silence is absence; a corrupt answer
    /// is asked again. Only a failed line fails the whole scan. Ends with [`Error::CancelledBeforeMotion`] as
    /// soon as the token of [`Client::set_cancel`] is cancelled (the only read that watches it).
    pub fn scan(&self) -> Result<Vec<ScanEntry>, Error> {
        self.call(calls::scan())
    }

    /// Switches the watchdog on in `addresses` (see [`Op::EnableWatchdog`]); refreshed from then on.
    pub fn enable_watchdog(&self, addresses: &[Address]) -> Result<(), Error> {
        self.call(calls::done(Op::EnableWatchdog(addresses.to_vec())))
    }

    /// Undoes [`Client::enable_watchdog`] (see [`Op::DisableWatchdog`]; a watchdog that a guarded motion
    /// under way armed stays online until the motion ends).
    pub fn disable_watchdog(&self) -> Result<(), Error> {
        self.call(calls::done(Op::DisableWatchdog))
    }

    super::session_state!();

    /// Halts every module this session set in motion that is still moving or cannot be asked; what closing
    /// does first, callable earlier. An error if one could not be confirmed stopped (a Halt was broadcast).
    pub fn halt_started(&self) -> Result<(), Error> {
        self.call(calls::done(Op::HaltStarted))
    }

    #[cfg(feature = "tokio")]
    pub(crate) fn into_driver(self) -> Driver<Session> {
        self.driver
    }

    /// Ends the session: halts what it set in motion and still moves, switches off the watchdogs it switched
    /// on (unless it failed), and says whether that was confirmed, within [`Config::close_bound`]. Returns the
    /// modules it set in motion and had not seen stop, which the close halted (none when nothing was left
    /// moving).
    pub fn close(self) -> Result<Vec<Address>, Error> {
        let (view, started) = self.driver.with_session(|s| (s.watchdog_view(), s.started()));
        self.driver.close().map(|()| started).map_err(|e| view.explain(e))
    }
}

fn op_is_read(op: &Op) -> bool {
    matches!(
        op,
        Op::ReadMany(..)
            | Op::Positions(_)
            | Op::Get(..)
            | Op::Position(_)
            | Op::PositionTicks(_)
            | Op::State(_)
            | Op::PositionStateDio(_)
            | Op::Look(_)
            | Op::ConfigWord(_)
            | Op::Kind(_)
            | Op::Info(_)
            | Op::Scan
    ) || matches!(op, Op::Request(_, r) if r.is_idempotent())
}

/// One copy of `e` per request (an operation that failed as a whole: the session was closed).
pub(crate) fn fail_all<T>(n: usize, e: &Error) -> Vec<Result<T, Error>> {
    (0..n).map(|_| Err(Error::NotSupported(e.to_string()))).collect()
}

/// One module on a [`Client`], by address.
#[derive(Debug, Clone, Copy)]
pub struct Module<'a> {
    client: &'a Client,
    address: Address,
}

impl Module<'_> {
    /// The address.
    pub fn address(&self) -> Address {
        self.address
    }

    /// Reads `param` (refused before sending if it is write-only).
    pub fn get(&self, param: Param) -> Result<Value, Error> {
        self.client.call(calls::get(self.address, param))
    }

    /// Writes `param` (refused before sending if it is read-only, `value` has another type or is not a
    /// finite number, or, on CAN, it would disable the acknowledges). No read-back: see
    /// [`Module::set_checked`].
    pub fn set(&self, param: Param, value: Value) -> Result<(), Error> {
        Request::set(param, value)?;
        self.client.call(calls::done(Op::Set(self.address, param, value)))
    }

    /// Writes `param` and checks that the module took it: a target beyond the module's limit is refused
    /// ([`Error::OutsideLimits`]) before anything is sent; then the value is read back (the write-only targets
    /// through their tick twins) and a difference is [`Error::ReadBack`].
    pub fn set_checked(&self, param: Param, value: Value) -> Result<Readback, Error> {
        self.client.call(calls::set_checked(self.address, param, value))
    }

    /// The actual position (ActPos): in rad or m once the session knows the module's kind.
    pub fn position(&self) -> Result<Position, Error> {
        self.client.call(calls::position(self.address))
    }

    /// The actual position in encoder ticks (ActIPos).
    pub fn position_ticks(&self) -> Result<Ticks, Error> {
        self.client.call(calls::position_ticks(self.address))
    }

    /// The state word (CubeState).
    pub fn state(&self) -> Result<CubeState, Error> {
        self.client.call(calls::state(self.address))
    }

    /// Position, short state and DIO in one read (ActFPosStateDio).
    pub fn position_state_dio(&self) -> Result<(Position, ShortState, Dio), Error> {
        self.client.call(calls::position_state_dio(self.address))
    }

    /// The position and the short state for a display or a control loop, in the fewest reads the module
    /// allows: one ActFPosStateDio where the module answers it (probed at the first call), else CubeState
    /// and ActPos, whose full state word comes with them. The position is in the module's unit once its
    /// kind is known.
    pub fn look(&self) -> Result<(Position, ShortState, Option<CubeState>), Error> {
        self.client.call(calls::look(self.address))
    }

    /// The Config word.
    pub fn config_word(&self) -> Result<ConfigWord, Error> {
        self.client.call(calls::config_word(self.address))
    }

    /// Rotary or linear (read once from the Config word, then remembered).
    pub fn kind(&self) -> Result<ModuleKind, Error> {
        self.client.call(calls::kind(self.address))
    }

    /// Type, version, serial number and state.
    pub fn info(&self) -> Result<ModuleInfo, Error> {
        self.client.call(calls::info(self.address))
    }

    /// Type, version, serial number and state, with the limits and the position
    /// ([`ModuleDetails::PARAMS`]): what `motionlink powercube info` shows.
    pub fn details(&self) -> Result<ModuleDetails, Error> {
        let info = self.info()?;
        let mut values = [Value::U8(0); 5];
        for (v, p) in values.iter_mut().zip(ModuleDetails::PARAMS) {
            *v = self.get(p)?;
        }
        Ok(ModuleDetails::new(info, values))
    }

    /// Reset: clears the errors that can be cleared and STATE_HALTED. Refused ([`Error::NotSupported`],
    /// nothing sent) while this session serves the module's watchdog (a guarded motion runs).
    pub fn reset(&self) -> Result<(), Error> {
        self.client.call(calls::action(self.address, Action::Reset))
    }

    /// Starts homing (wait for it with [`Module::wait_home`]).
    pub fn home(&self) -> Result<(), Error> {
        self.client.call(calls::action(self.address, Action::Home))
    }

    /// Reset, and the manual's first way to restart after a watchdog expiry (see
    /// [`Op::ResetAndReleaseWatchdog`]); true if it switched an expired watchdog offline.
    pub fn reset_and_release_watchdog(&self) -> Result<bool, Error> {
        self.client.call(calls::reset_and_release_watchdog(self.address))
    }

    /// Halt: stops at once; the module stays halted until a reset.
    pub fn halt(&self) -> Result<(), Error> {
        self.client.call(calls::done(Op::Halt(self.address)))
    }

    /// Halt, confirmed: the Halt acknowledged, then the state read until STATE_MOTION is clear (at most
    /// [`HALT_SETTLE`](crate::session::HALT_SETTLE); still moving then is [`Error::StillMoving`]), then the
    /// position. The module stays halted until a reset. What `motionlink powercube stop` does.
    pub fn halt_confirmed(&self) -> Result<HaltReport, Error> {
        self.client.call(calls::halt_confirmed(self.address))
    }

    /// Stops the module after an action that may have set it in motion cannot go on (see
    /// [`Op::StopMotion`]), and says whether the module confirmed it.
    pub fn stop_motion(&self) -> StopOutcome {
        self.client.call(calls::stop_motion(self.address)).unwrap_or_else(|e| StopOutcome::Unconfirmed {
            reason: e.to_string(),
            watchdog_armed: self.client.watchdog_armed(self.address),
        })
    }

    /// RecalcPIDParam.
    pub fn recalc_pid(&self) -> Result<(), Error> {
        self.client.call(calls::action(self.address, Action::RecalcPid))
    }

    /// ResetTime: restarts the module's millisecond clock.
    pub fn reset_time(&self) -> Result<(), Error> {
        self.client.call(calls::action(self.address, Action::ResetTime))
    }

    /// A motion command in any mode, its units checked against the module's kind (rad for a linear module
    /// is refused); returns the extended acknowledge if `ack` asks for one and the module gives it. `None`
    /// to [`AckKind::Extended`]: the module took the command with the simple acknowledge, as firmware before
    /// PowerCube-OS 2.5.16 / 3.5.13 does (manual 4.5; one warning), so the motion runs.
    pub fn motion(&self, motion: Motion, ack: AckKind) -> Result<Option<ExtAck>, Error> {
        Request::motion(motion, ack)?;
        self.client.call(calls::motion(self.address, motion, ack))
    }

    /// A streamed motion command for a control loop, sent once per cycle (see [`Op::Setpoint`]): typically
    /// FVEL ([`Motion::FVel`]) with [`AckKind::Extended`], whose acknowledge gives where the module stood
    /// in the same exchange. Every call checks the motion's numbers, units and limits (refused, never
    /// clamped: [`Error::OutsideLimits`], nothing sent) against limits read at the first call to the module
    /// and cached; the first call also refuses a module in error or halted and, under [`Guard::Watchdog`],
    /// arms its watchdog, which the session refreshes until [`Client::disable_watchdog`] or the close (the
    /// close halts the module). After it, each call is one exchange. The cache is dropped when this session
    /// writes a limit or the Config word, resets, homes or halts the module, and on any error: a limit
    /// another program changes is not seen until then.
    ///
    /// ```
    /// use std::time::Duration;
    /// use motionlink_link::clock::{Clock, ManualClock};
    /// use motionlink_link::pipe::{EmulatorHost, PipeConfig};
    /// use motionlink_powercube::client::{Client, Config, Guard, PortLink};
    /// use motionlink_powercube::model::{AckKind, Address, Motion, Velocity};
    /// use motionlink_powercube::wire::AckPosition;
    /// use motionlink_powercube::Emulator;
    ///
    /// let clock = ManualClock::new_auto();
    /// let _me = clock.reserve_participant().enter();
    /// let host = EmulatorHost::new(Emulator::new(&Default::default()), clock.shared(), PipeConfig::instant());
    /// let link = PortLink::Rs232(Box::new(host.connect().0));
    /// let client = Client::with_link(link, clock.shared(), Config::rs232()).unwrap();
    /// let joint = client.module(Address::new(1).unwrap());
    /// // A control loop at 100 Hz: FVEL_ACK every 10 ms, where the module stood in each acknowledge.
    /// let vel = Motion::FVel { vel: Velocity::rad_per_s(0.2) };
    /// let mut next = clock.now();
    /// for _ in 0..50 {
    ///     let report = joint.setpoint(vel, AckKind::Extended, Guard::HaltOnly).unwrap();
    ///     let Some(ext) = report.ext_ack else { panic!("an old firmware: no extended acknowledge") };
    ///     assert!(matches!(ext.position, AckPosition::Unit(p) if p.value() >= 0.05));
    ///     next += Duration::from_millis(10);
    ///     clock.sleep_until(next);
    /// }
    /// // A velocity beyond MaxVel is refused, nothing sent.
    /// let fast = Motion::FVel { vel: Velocity::rad_per_s(100.0) };
    /// assert!(joint.setpoint(fast, AckKind::Extended, Guard::HaltOnly).is_err());
    /// let address = joint.address();
    /// assert_eq!(client.close().unwrap(), vec![address]); // the close halts it
    /// ```
    pub fn setpoint(&self, motion: Motion, ack: AckKind, guard: Guard) -> Result<SetpointReport, Error> {
        self.client.call(calls::setpoint(self.address, motion, ack, guard))
    }

    /// A step in encoder ticks (SetIStep).
    pub fn istep(&self, pos: Ticks, time: Millis) -> Result<(), Error> {
        self.client.call(calls::istep(self.address, pos, time))
    }

    /// A ramp move to `pos`, first setting TargetVel and TargetAcc if `ramp` is given (no limit checks,
    /// no read-back, no wait: [`Module::move_to`] has them).
    pub fn move_ramp(&self, pos: Position, ramp: Option<Ramp>) -> Result<(), Error> {
        self.move_ramp_with(pos, ramp.map(|r| r.vel), ramp.map(|r| r.acc))
    }

    /// A ramp move to `pos`, first setting TargetVel if `vel` is given and TargetAcc if `acc` is given.
    pub fn move_ramp_with(&self, pos: Position, vel: Option<Velocity>, acc: Option<Acceleration>) -> Result<(), Error> {
        self.client.call(calls::move_ramp(self.address, pos, vel, acc))
    }

    fn wait(&self, until: Until, timeout: Duration, progress: &mut dyn FnMut(&Progress)) -> Result<CubeState, Error> {
        self.client.call_with(calls::wait(self.address, until, timeout), progress)
    }

    /// Waits until homing has ended (STATE_HOME_OK, not moving); halts on a timeout or a cancellation.
    pub fn wait_home(&self, timeout: Duration, progress: &mut dyn FnMut(&Progress)) -> Result<CubeState, Error> {
        self.wait(Until::Home, timeout, progress)
    }

    /// Waits until the module stands still (no STATE_MOTION); halts on a timeout or a cancellation.
    pub fn wait_motion_end(&self, timeout: Duration, progress: &mut dyn FnMut(&Progress)) -> Result<CubeState, Error> {
        self.wait(Until::Motion, timeout, progress)
    }

    /// Waits until a ramp has ended (STATE_RAMP_END, not moving); halts on a timeout or a cancellation.
    pub fn wait_ramp_end(&self, timeout: Duration, progress: &mut dyn FnMut(&Progress)) -> Result<CubeState, Error> {
        self.wait(Until::Ramp, timeout, progress)
    }

    /// Homes the module and waits for the end of homing (see [`Op::HomeAndWait`]); position and state at
    /// the end.
    pub fn home_and_wait(&self, timeout: Duration, progress: &mut dyn FnMut(&Progress)) -> Result<HomeReport, Error> {
        self.client.call_with(calls::home_and_wait(self.address, timeout, None), progress)
    }

    /// [`Module::home_and_wait`] under `guard` (see [`Guard`]): what `motionlink powercube home` does. What
    /// the guard could not do (a module that ignores the RS232 watchdog refresh homes without its watchdog)
    /// is in the report's `not_verifiable`.
    pub fn home_guarded(
        &self,
        timeout: Duration,
        guard: Guard,
        progress: &mut dyn FnMut(&Progress),
    ) -> Result<HomeReport, Error> {
        self.client.call_with(calls::home_and_wait(self.address, timeout, Some(guard)), progress)
    }

    /// A ramp move with every check this protocol allows (see [`Op::MoveTo`]).
    pub fn move_to(&self, spec: &MoveSpec, progress: &mut dyn FnMut(&Progress)) -> Result<MoveReport, Error> {
        self.client.call_with(calls::move_to(self.address, *spec, None), progress)
    }

    /// [`Module::move_to`] under `guard` (see [`Guard`]): what `motionlink powercube move` does. Its end halts
    /// and disarms this module alone, so other threads' guarded motions of other modules go on; a second one
    /// of this module while one runs is refused (see [`Op::MoveGuarded`]).
    pub fn move_to_guarded(
        &self,
        spec: &MoveSpec,
        guard: Guard,
        progress: &mut dyn FnMut(&Progress),
    ) -> Result<MoveReport, Error> {
        self.client.call_with(calls::move_to(self.address, *spec, Some(guard)), progress)
    }

    /// A motion command of any mode run to its end with every check (see [`Op::RunMotion`]): its limits
    /// refused before anything moves, a position mode waited for and checked within the tolerance of its
    /// target, a continuous mode held for [`MotionSpec::hold`] and then ended (velocity 0, or a confirmed
    /// Halt). `progress` sees every poll.
    pub fn run_motion(&self, spec: &MotionSpec, progress: &mut dyn FnMut(&Progress)) -> Result<MotionReport, Error> {
        self.client.call_with(calls::run_motion(self.address, *spec, None), progress)
    }

    /// [`Module::run_motion`] under `guard` (see [`Guard`]), as [`Module::move_to_guarded`]: its end halts
    /// and disarms this module alone; what the guard could not do is in the report's `not_verifiable`.
    pub fn run_motion_guarded(
        &self,
        spec: &MotionSpec,
        guard: Guard,
        progress: &mut dyn FnMut(&Progress),
    ) -> Result<MotionReport, Error> {
        self.client.call_with(calls::run_motion(self.address, *spec, Some(guard)), progress)
    }
}
