//! [`AsyncClient`]: the same operations as [`Client`](super::Client), as futures on tokio, over an
//! [`AsyncDriver`] running the same [`Session`]. Dropping a future before it is done cancels its
//! operation: a motion it started is halted (and the halt's outcome logged), a read is dropped.

use std::time::Duration;

use motionlink_link::driver::{AsyncDriver, OpFuture};
use motionlink_link::url::PortUrl;
use motionlink_link::SharedClock;

use super::blocking::{driver_on, fail_all};
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
    Readback, ScanEntry, Session, SetpointReport, Until,
};
use crate::wire::{Action, ExtAck, Reply, Request};

/// A session with the modules on one line or one CAN bus, for async callers (tokio). Share it by
/// reference or in an `Arc`: concurrent operations interleave on the line as the session schedules them.
///
/// Closing ([`AsyncClient::close`]) halts what the session set in motion and switches off the watchdogs it
/// switched on, bounded by [`Config::close_bound`]; dropping it does the same on tokio's blocking pool.
pub struct AsyncClient {
    driver: AsyncDriver<Session>,
    config: Config,
    can: bool,
}

impl std::fmt::Debug for AsyncClient {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("AsyncClient").field("port", &self.driver.driver().port_name()).finish()
    }
}

impl AsyncClient {
    /// Opens the port `url` names as [`Client::open`](super::Client::open) does; the port is opened on
    /// tokio's blocking pool.
    pub async fn open(url: &PortUrl, clock: SharedClock, config: Config) -> Result<AsyncClient, Error> {
        let url = url.clone();
        let for_open = config.clone();
        let opened = tokio::task::spawn_blocking(move || {
            let link = PortLink::open_configured(&url, &for_open, &clock)?;
            driver_on(link, clock, &for_open)
        })
        .await;
        let (driver, can) = match opened {
            Ok(r) => r?,
            Err(e) => return Err(Error::NotSupported(format!("the opening task failed: {e}"))),
        };
        Ok(AsyncClient { driver: AsyncDriver::from_driver(driver), config, can })
    }

    /// A session over an open link (RS232 bytes or CAN frames), as [`Client::with_link`](super::Client::with_link).
    pub async fn with_link(
        link: impl Into<PortLink>,
        clock: SharedClock,
        config: Config,
    ) -> Result<AsyncClient, Error> {
        let (driver, can) = driver_on(link.into(), clock, &config)?;
        Ok(AsyncClient { driver: AsyncDriver::from_driver(driver), config, can })
    }

    /// The asynchronous face of an open blocking client (its session goes on, nothing is sent).
    pub fn from_client(client: super::Client) -> AsyncClient {
        let (config, can) = (client.config().clone(), client.is_can());
        AsyncClient { driver: AsyncDriver::from_driver(client.into_driver()), config, can }
    }

    /// Runs `f` on the session (its statistics, its watchdog duty).
    pub fn session<R>(&self, f: impl FnOnce(&mut Session) -> R) -> R {
        self.driver.driver().with_session(f)
    }

    /// The driver underneath (to look at the session).
    pub fn driver(&self) -> &AsyncDriver<Session> {
        &self.driver
    }

    /// The port, for messages.
    pub fn port(&self) -> &str {
        self.driver.driver().port_name()
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
        self.driver.driver().clock()
    }

    super::session_state!();

    /// Runs `op` to its end; dropping the future cancels it (halting a motion it started).
    pub async fn run(&self, op: Op) -> Result<Output, Error> {
        self.driver.run(op).await
    }

    /// Starts `op`: the future ends with its output. [`OpFuture::cancel`] stops it as a dropped future does
    /// (a motion it started is halted) and the future still ends with how it ended; its progress can be
    /// taken meanwhile ([`OpFuture::take_progress`]).
    pub fn start(&self, op: Op) -> OpFuture<Session> {
        self.driver.start(op)
    }

    async fn call<T>(&self, call: Call<T>) -> Result<T, Error> {
        let output = self.driver.run(call.op.clone()).await;
        call.result(output)
    }

    /// A handle on the module at `address` (checked once: [`Address::new`]). Nothing is sent.
    pub fn module(&self, address: Address) -> AsyncModule<'_> {
        AsyncModule { client: self, address }
    }

    /// One request, checked, reads retried (see [`Client::request`](super::Client::request)).
    pub async fn request(&self, address: Address, request: Request) -> Result<Reply, Error> {
        request.validate()?;
        self.call(calls::request(address, request)).await
    }

    /// Several requests to several modules (see [`Client::request_many`](super::Client::request_many)): on
    /// CAN all at once, each checked, reads retried; dropping the future halts the modules a motion request
    /// among them may have started.
    pub async fn request_many(&self, requests: &[(Address, Request)]) -> Vec<Result<Reply, Error>> {
        let n = requests.len();
        self.call(calls::request_many(requests.to_vec())).await.unwrap_or_else(|e| fail_all(n, &e))
    }

    /// Reads `param` of every module in `addresses` (on CAN in one round).
    pub async fn read_many(&self, addresses: &[Address], param: Param) -> Vec<Result<Value, Error>> {
        let n = addresses.len();
        self.call(calls::read_many(addresses.to_vec(), param)).await.unwrap_or_else(|e| fail_all(n, &e))
    }

    /// The positions of `addresses` (ActPos), on CAN in one round.
    pub async fn positions(&self, addresses: &[Address]) -> Vec<Result<Position, Error>> {
        let n = addresses.len();
        self.call(calls::positions(addresses.to_vec())).await.unwrap_or_else(|e| fail_all(n, &e))
    }

    /// Sends a broadcast.
    pub async fn broadcast(&self, broadcast: Broadcast) -> Result<(), Error> {
        self.call(calls::done(Op::Broadcast(broadcast))).await
    }

    /// Every module on the bus (see [`Client::scan`](super::Client::scan)).
    pub async fn scan(&self) -> Result<Vec<ScanEntry>, Error> {
        self.call(calls::scan()).await
    }

    /// Switches the watchdog on in `addresses`; refreshed from then on.
    pub async fn enable_watchdog(&self, addresses: &[Address]) -> Result<(), Error> {
        self.call(calls::done(Op::EnableWatchdog(addresses.to_vec()))).await
    }

    /// Switches the watchdogs this session switched on off again (see [`Op::DisableWatchdog`]; a watchdog that
    /// a guarded motion under way armed stays online until the motion ends).
    pub async fn disable_watchdog(&self) -> Result<(), Error> {
        self.call(calls::done(Op::DisableWatchdog)).await
    }

    /// Halts every module this session set in motion that still moves.
    pub async fn halt_started(&self) -> Result<(), Error> {
        self.call(calls::done(Op::HaltStarted)).await
    }

    /// Ends the session; returns the modules it halted (see [`Client::close`](super::Client::close)).
    pub async fn close(self) -> Result<Vec<Address>, Error> {
        let (view, started) = self.driver.driver().with_session(|s| (s.watchdog_view(), s.started()));
        self.driver.close().await.map(|()| started).map_err(|e| view.explain(e))
    }
}

/// One module on an [`AsyncClient`], by address.
#[derive(Debug, Clone, Copy)]
pub struct AsyncModule<'a> {
    client: &'a AsyncClient,
    address: Address,
}

impl AsyncModule<'_> {
    /// The address.
    pub fn address(&self) -> Address {
        self.address
    }

    /// Reads `param`.
    pub async fn get(&self, param: Param) -> Result<Value, Error> {
        self.client.call(calls::get(self.address, param)).await
    }

    /// Writes `param` (no read-back).
    pub async fn set(&self, param: Param, value: Value) -> Result<(), Error> {
        Request::set(param, value)?;
        self.client.call(calls::done(Op::Set(self.address, param, value))).await
    }

    /// Writes `param` with the limit check and the read-back.
    pub async fn set_checked(&self, param: Param, value: Value) -> Result<Readback, Error> {
        self.client.call(calls::set_checked(self.address, param, value)).await
    }

    /// The actual position.
    pub async fn position(&self) -> Result<Position, Error> {
        self.client.call(calls::position(self.address)).await
    }

    /// The actual position in encoder ticks (ActIPos).
    pub async fn position_ticks(&self) -> Result<Ticks, Error> {
        self.client.call(calls::position_ticks(self.address)).await
    }

    /// Position, short state and DIO in one read (ActFPosStateDio).
    pub async fn position_state_dio(&self) -> Result<(Position, ShortState, Dio), Error> {
        self.client.call(calls::position_state_dio(self.address)).await
    }

    /// As [`Module::look`](crate::client::Module::look).
    pub async fn look(&self) -> Result<(Position, ShortState, Option<CubeState>), Error> {
        self.client.call(calls::look(self.address)).await
    }

    /// The Config word.
    pub async fn config_word(&self) -> Result<ConfigWord, Error> {
        self.client.call(calls::config_word(self.address)).await
    }

    /// The state word.
    pub async fn state(&self) -> Result<CubeState, Error> {
        self.client.call(calls::state(self.address)).await
    }

    /// Rotary or linear.
    pub async fn kind(&self) -> Result<ModuleKind, Error> {
        self.client.call(calls::kind(self.address)).await
    }

    /// Type, version, serial number and state.
    pub async fn info(&self) -> Result<ModuleInfo, Error> {
        self.client.call(calls::info(self.address)).await
    }

    /// Type, version, serial number and state, with the limits and the position
    /// ([`ModuleDetails::PARAMS`]).
    pub async fn details(&self) -> Result<ModuleDetails, Error> {
        let info = self.info().await?;
        let mut values = [Value::U8(0); 5];
        for (v, p) in values.iter_mut().zip(ModuleDetails::PARAMS) {
            *v = self.get(p).await?;
        }
        Ok(ModuleDetails::new(info, values))
    }

    /// Reset; refused while this session serves the module's watchdog, as
    /// [`Module::reset`](crate::client::Module::reset).
    pub async fn reset(&self) -> Result<(), Error> {
        self.client.call(calls::action(self.address, Action::Reset)).await
    }

    /// Starts homing (wait for it with [`AsyncModule::wait_home`]).
    pub async fn home(&self) -> Result<(), Error> {
        self.client.call(calls::action(self.address, Action::Home)).await
    }

    /// RecalcPIDParam.
    pub async fn recalc_pid(&self) -> Result<(), Error> {
        self.client.call(calls::action(self.address, Action::RecalcPid)).await
    }

    /// ResetTime: restarts the module's millisecond clock.
    pub async fn reset_time(&self) -> Result<(), Error> {
        self.client.call(calls::action(self.address, Action::ResetTime)).await
    }

    /// Reset, releasing a watchdog a dead host left expired.
    pub async fn reset_and_release_watchdog(&self) -> Result<bool, Error> {
        self.client.call(calls::reset_and_release_watchdog(self.address)).await
    }

    /// Halt.
    pub async fn halt(&self) -> Result<(), Error> {
        self.client.call(calls::done(Op::Halt(self.address))).await
    }

    /// Halt, confirmed by the state and followed by the position, as
    /// [`Module::halt_confirmed`](crate::client::Module::halt_confirmed).
    pub async fn halt_confirmed(&self) -> Result<HaltReport, Error> {
        self.client.call(calls::halt_confirmed(self.address)).await
    }

    /// Stops the module after an action that may have set it in motion cannot go on (see
    /// [`Op::StopMotion`]), and says whether the module confirmed it.
    pub async fn stop_motion(&self) -> StopOutcome {
        match self.client.call(calls::stop_motion(self.address)).await {
            Ok(outcome) => outcome,
            Err(e) => StopOutcome::Unconfirmed {
                reason: e.to_string(),
                watchdog_armed: self.client.watchdog_armed(self.address),
            },
        }
    }

    /// A step in encoder ticks (SetIStep).
    pub async fn istep(&self, pos: Ticks, time: Millis) -> Result<(), Error> {
        self.client.call(calls::istep(self.address, pos, time)).await
    }

    /// A ramp move to `pos`, first setting TargetVel and TargetAcc if `ramp` is given (no limit checks, no
    /// read-back, no wait: [`AsyncModule::move_to`] has them). The motion goes on when the future is dropped
    /// after its acknowledge: wait for it with [`AsyncModule::wait_ramp_end`].
    pub async fn move_ramp(&self, pos: Position, ramp: Option<Ramp>) -> Result<(), Error> {
        self.move_ramp_with(pos, ramp.map(|r| r.vel), ramp.map(|r| r.acc)).await
    }

    /// A ramp move to `pos`, first setting TargetVel if `vel` is given and TargetAcc if `acc` is given.
    pub async fn move_ramp_with(
        &self,
        pos: Position,
        vel: Option<Velocity>,
        acc: Option<Acceleration>,
    ) -> Result<(), Error> {
        self.client.call(calls::move_ramp(self.address, pos, vel, acc)).await
    }

    async fn wait(&self, until: Until, timeout: Duration) -> Result<CubeState, Error> {
        self.client.call(calls::wait(self.address, until, timeout)).await
    }

    /// Waits until homing has ended (STATE_HOME_OK, not moving); halts on a timeout or when the future is
    /// dropped.
    pub async fn wait_home(&self, timeout: Duration) -> Result<CubeState, Error> {
        self.wait(Until::Home, timeout).await
    }

    /// Waits until the module stands still (no STATE_MOTION); halts on a timeout or when the future is
    /// dropped.
    pub async fn wait_motion_end(&self, timeout: Duration) -> Result<CubeState, Error> {
        self.wait(Until::Motion, timeout).await
    }

    /// Waits until a ramp has ended (STATE_RAMP_END, not moving); halts on a timeout or when the future is
    /// dropped.
    pub async fn wait_ramp_end(&self, timeout: Duration) -> Result<CubeState, Error> {
        self.wait(Until::Ramp, timeout).await
    }

    /// A motion command, its units checked; dropping the future before its acknowledge halts the module.
    /// As [`Module::motion`](crate::client::Module::motion): `None` to [`AckKind::Extended`] is the simple
    /// acknowledge of a firmware before extended ones, and the motion runs.
    pub async fn motion(&self, motion: Motion, ack: AckKind) -> Result<Option<ExtAck>, Error> {
        Request::motion(motion, ack)?;
        self.client.call(calls::motion(self.address, motion, ack)).await
    }

    /// A streamed motion command for a control loop, as [`Module::setpoint`](crate::client::Module::setpoint)
    /// (see [`Op::Setpoint`]): after the first call to the module one exchange per call; dropping the
    /// future halts the module.
    pub async fn setpoint(&self, motion: Motion, ack: AckKind, guard: Guard) -> Result<SetpointReport, Error> {
        self.client.call(calls::setpoint(self.address, motion, ack, guard)).await
    }

    /// Homes and waits for the end of homing; dropping the future halts the module.
    pub async fn home_and_wait(&self, timeout: Duration) -> Result<HomeReport, Error> {
        self.client.call(calls::home_and_wait(self.address, timeout, None)).await
    }

    /// [`AsyncModule::home_and_wait`] under `guard`.
    pub async fn home_guarded(&self, timeout: Duration, guard: Guard) -> Result<HomeReport, Error> {
        self.client.call(calls::home_and_wait(self.address, timeout, Some(guard))).await
    }

    /// A checked ramp move (see [`Op::MoveTo`]); dropping the future halts the module.
    pub async fn move_to(&self, spec: &MoveSpec) -> Result<MoveReport, Error> {
        self.client.call(calls::move_to(self.address, *spec, None)).await
    }

    /// [`AsyncModule::move_to`] under `guard`: its end halts and disarms this module alone (see
    /// [`Op::MoveGuarded`]).
    pub async fn move_to_guarded(&self, spec: &MoveSpec, guard: Guard) -> Result<MoveReport, Error> {
        self.client.call(calls::move_to(self.address, *spec, Some(guard))).await
    }

    /// A motion command of any mode run to its end with every check (see [`Op::RunMotion`]); dropping the
    /// future halts the module (a continuous mode without [`MotionSpec::hold`] runs until then).
    pub async fn run_motion(&self, spec: &MotionSpec) -> Result<MotionReport, Error> {
        self.client.call(calls::run_motion(self.address, *spec, None)).await
    }

    /// [`AsyncModule::run_motion`] under `guard`: its end halts and disarms this module alone (see
    /// [`Op::MoveGuarded`]).
    pub async fn run_motion_guarded(&self, spec: &MotionSpec, guard: Guard) -> Result<MotionReport, Error> {
        self.client.call(calls::run_motion(self.address, *spec, Some(guard))).await
    }
}
