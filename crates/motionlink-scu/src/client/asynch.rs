//! [`AsyncClient`]: the session run by the async driver on tokio. The same operations and the same safety as
//! [`super::Client`]: the driver's thread does the I/O and the keepalive; a future dropped before it is done
//! cancels its operation, which stops any motion it started (RS, confirmed by the status).

use std::time::Duration;

use motionlink_link::driver::{AsyncDriver, OpFuture};
use motionlink_link::link::Connector;
use motionlink_link::url::PortUrl;
use motionlink_link::{Link, SharedClock, Timestamp};

use super::{expect_output, move_spec, run_spec, Client};
use crate::config::{Config, StrokeLimits};
use crate::error::Error;
use crate::model::{
    Actuator, ActuatorStatus1, CyclicObject, DataEntry, DataIndex, ErrorCode, Function, MotionDirection,
    MotionFunction, PositionCounts, Speed, StopMode, UNUSED,
};
use crate::session::ops::basic::{cyclic_index, decode_cyclic_read, encode_for, Stroke};
use crate::session::{
    Capabilities, ClientStats, MoveReport, MoveSpec, MoveTargets, Op, Output, PreparedRequest, RunAction, RunReport,
    Session, SetReport, Snapshot, StopReport, SwitchReport, WatchSpec,
};
use crate::value::Value;
use crate::wire::{Command, Request};

/// A session with an SCU control unit, for async callers (tokio). Share it with `Arc`; every method takes
/// `&self`. Dropping it ends the session on tokio's blocking pool (RS for every started function, then RA,
/// at most [`Config::close_bound`]); [`AsyncClient::close`] does the same and returns the outcome.
pub struct AsyncClient {
    driver: AsyncDriver<Session>,
    config: Config,
}

impl std::fmt::Debug for AsyncClient {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("AsyncClient").field("port", &self.driver.driver().port_name()).finish()
    }
}

impl AsyncClient {
    /// Opens a session as [`Client::open`] does; the port is opened on tokio's blocking pool.
    pub async fn open(port: &PortUrl, clock: SharedClock, config: Config) -> Result<Self, Error> {
        let connector = super::port_connector(port, &config)?;
        Self::with_connector(connector, clock, config).await
    }

    /// Opens a session on `link` as [`Client::with_link`] does.
    pub async fn with_link(link: Box<dyn Link>, clock: SharedClock, config: Config) -> Result<Self, Error> {
        Self::with_connector(super::link_connector(link), clock, config).await
    }

    /// Opens a session as [`Client::with_connector`] does; the port is opened on tokio's blocking pool.
    pub async fn with_connector(connector: Connector, clock: SharedClock, config: Config) -> Result<Self, Error> {
        let for_driver = config.clone();
        let driver = AsyncDriver::open(move || Client::make_driver(connector, clock, for_driver)).await?;
        if let Err(e) = driver.run(Op::Open).await {
            // As Client::open: nothing was started, and an unconfirmed close adds nothing to the open's error.
            if let Err(close) = driver.close().await {
                tracing::debug!("closing the session whose opening failed: {close}");
            }
            return Err(e);
        }
        Ok(AsyncClient { driver, config })
    }

    /// Starts any operation; the future ends with its output, and reports progress
    /// ([`OpFuture::take_progress`]). Dropping it before it is done cancels the operation.
    pub fn start(&self, op: Op) -> OpFuture<Session> {
        self.driver.start(op)
    }

    /// Runs `op` to its end; dropping the future cancels it, as [`AsyncClient::start`] (a function it
    /// started is stopped).
    pub async fn run(&self, op: Op) -> Result<Output, Error> {
        self.driver.run(op).await
    }

    /// The driver underneath.
    pub fn driver(&self) -> &AsyncDriver<Session> {
        &self.driver
    }

    /// The port, as the link describes it.
    pub fn port(&self) -> &str {
        self.driver.driver().port_name()
    }

    /// The session's settings.
    pub fn config(&self) -> &Config {
        &self.config
    }

    /// The session's clock.
    pub fn clock(&self) -> &SharedClock {
        self.driver.driver().clock()
    }

    /// Counters of the session.
    pub fn stats(&self) -> ClientStats {
        self.driver.driver().with_session(|s| s.stats())
    }

    /// The functions this session started with RE and has not stopped yet.
    pub fn started(&self) -> Vec<Function> {
        self.driver.driver().with_session(|s| s.started())
    }

    /// True while the session is open (not lost, not ended by the unit, not closed).
    pub fn is_open(&self) -> bool {
        self.driver.driver().with_session(|s| s.is_open())
    }

    /// Why the session is not open, if it is not: lost, ended by the unit, or closed.
    pub fn not_open_reason(&self) -> Option<String> {
        self.driver.driver().with_session(|s| s.not_open_reason())
    }

    /// Sends any request and returns the data of its ACK.
    pub async fn request(&self, request: &Request<'_>) -> Result<Option<Vec<u8>>, Error> {
        let op = Op::Request(PreparedRequest::new(request)?);
        expect_output!(self.driver.run(op).await, Output::Data(d) => d)
    }

    /// Reads the raw bytes of a data index (entry or group), as [`Client::get_raw`].
    pub async fn get_raw(&self, index: DataIndex) -> Result<Vec<u8>, Error> {
        super::data(expect_output!(self.driver.run(Op::Read(index)).await, Output::Data(d) => d)?)
    }

    /// Reads an entry or a group, each member decoded.
    pub async fn get(&self, index: DataIndex) -> Result<Vec<(&'static DataEntry, Value)>, Error> {
        let it = super::item_of(index)?;
        super::decode(it, &self.get_raw(index).await?)
    }

    /// Reads one entry.
    pub async fn get_value(&self, index: DataIndex) -> Result<Value, Error> {
        super::entry_of(index)?;
        Ok(self.get(index).await?.remove(0).1)
    }

    /// Writes a remote data entry and reads it back, as [`Client::set`].
    pub async fn set(&self, index: DataIndex, value: &Value) -> Result<SetReport, Error> {
        let (_, data) = encode_for(index, value, self.config.speed_mode)?;
        self.set_raw(index, &data).await
    }

    /// Writes raw bytes to a data index and reads them back, as [`Client::set_raw`].
    pub async fn set_raw(&self, index: DataIndex, data: &[u8]) -> Result<SetReport, Error> {
        expect_output!(
            self.driver.run(Op::Set { index, data: data.to_vec(), verify: true }).await,
            Output::Written(r) => r
        )
    }

    /// One sample of the state, as [`Client::sample`].
    pub async fn sample(&self) -> Result<Snapshot, Error> {
        let op = Op::Watch(WatchSpec { interval: Duration::ZERO, count: Some(1) });
        let last = expect_output!(self.driver.run(op).await, Output::Watched { last, .. } => last)?;
        last.ok_or(Error::UnexpectedReply { command: Command::Get, detail: "a watch without a sample".into() })
    }

    /// What the session found the unit to do where the manual leaves it open, as [`Client::capabilities`].
    pub fn capabilities(&self) -> Capabilities {
        self.driver.driver().with_session(|s| s.capabilities())
    }

    /// Takes what `known` says of the unit where the session has not found out yet, as
    /// [`Client::seed_capabilities`].
    pub fn seed_capabilities(&self, known: Capabilities) {
        self.driver.driver().with_session(|s| s.seed_capabilities(known))
    }

    /// Actuator `a`'s position.
    pub async fn position(&self, a: Actuator) -> Result<PositionCounts, Error> {
        super::position(self.get_value(a.position_index()).await?)
    }

    /// Every actuator's position (0x0010), A1 first.
    pub async fn positions(&self) -> Result<[PositionCounts; 6], Error> {
        crate::session::ops::positions(&self.get_raw(DataIndex(0x0010)).await?)
    }

    /// Actuator `a`'s status 1.
    pub async fn status1(&self, a: Actuator) -> Result<ActuatorStatus1, Error> {
        super::status1(&self.get_raw(a.status1_index()).await?)
    }

    /// Every actuator's status 1 (0x0170), A1 first.
    pub async fn statuses(&self) -> Result<[ActuatorStatus1; 6], Error> {
        crate::session::ops::statuses(&self.get_raw(DataIndex(0x0170)).await?)
    }

    /// The actuators whose status 1 says "drive available".
    pub async fn connected_actuators(&self) -> Result<Vec<Actuator>, Error> {
        Ok(super::connected(&self.statuses().await?))
    }

    /// Actuator `a`'s travel range for targets, as [`Client::stroke_limits`].
    pub async fn stroke_limits(&self, a: Actuator) -> Result<Option<(StrokeLimits, &'static str)>, Error> {
        expect_output!(self.driver.run(Op::StrokeLimits(a)).await, Output::Stroke(s) => s)
    }

    /// Error_Code 1 (most recent) to 5 (oldest).
    pub async fn error_history(&self) -> Result<[ErrorCode; 5], Error> {
        super::error_history(&self.get_raw(DataIndex(0x00D0)).await?)
    }

    /// RE on a motion function, as [`Client::start_motion`]. If the future is dropped while the RE is under
    /// way, the function is stopped.
    pub async fn start_motion(&self, function: MotionFunction, direction: MotionDirection) -> Result<(), Error> {
        self.request(&Request::Execute { function: function.id(), params: [direction.code(), UNUSED] })
            .await
            .map(|_| ())
    }

    /// RS on a motion function (it goes out even if the future is dropped).
    pub async fn stop_motion(&self, function: MotionFunction, mode: StopMode) -> Result<(), Error> {
        self.request(&Request::Stop { function: function.id(), param: mode.code() }).await.map(|_| ())
    }

    /// Stops motion functions and confirms it, as [`Client::stop_functions`] (the stop goes on to its end
    /// even if the future is dropped).
    pub async fn stop_functions(&self, functions: &[MotionFunction], mode: StopMode) -> Result<StopReport, Error> {
        let op = Op::StopMotions { functions: functions.to_vec(), mode };
        expect_output!(self.driver.run(op).await, Output::Stopped(r) => r)
    }

    /// Switches a switching function on (RE) or off (RS) and reads back the status entry that shows it, as
    /// [`Client::switch`].
    pub async fn switch(&self, function: Function, on: bool) -> Result<SwitchReport, Error> {
        expect_output!(self.driver.run(super::switch_op(function, on)?).await, Output::Switched(r) => r)
    }

    /// Runs a function as [`Client::run`]; dropping the future stops it. Progress:
    /// [`AsyncClient::start`] with [`AsyncClient::run_function_op`].
    pub async fn run_function(&self, action: RunAction, limit: Option<Duration>) -> Result<RunReport, Error> {
        expect_output!(self.driver.run(self.run_function_op(action, limit)?).await, Output::Run(r) => r)
    }

    /// The operation of [`AsyncClient::run_function`], to start with [`AsyncClient::start`] (for its progress,
    /// or to cancel it with [`OpFuture::cancel`] and still learn how it ended: [`Output::Run`], or
    /// [`Error::RunCancelled`] once the unit confirmed the stop).
    pub fn run_function_op(&self, action: RunAction, limit: Option<Duration>) -> Result<Op, Error> {
        Ok(Op::Run(run_spec(action, limit)?))
    }

    /// Defines CyclicObj `slot` (1..5) on the unit (and reads the definition back).
    pub async fn configure_cyclic(&self, slot: u8, object: &CyclicObject) -> Result<SetReport, Error> {
        let report = self.set(cyclic_index(slot)?, &Value::CyclicObject(*object)).await?;
        self.driver.driver().with_session(|s| s.cyclic_slot_written(slot));
        Ok(report)
    }

    /// From now on every keepalive RC carries CyclicObj `slot` with `write`, as [`Client::use_cyclic`].
    pub async fn use_cyclic(&self, slot: u8, write: &[Value]) -> Result<(), Error> {
        self.driver.run(Op::UseCyclic { slot, write: write.to_vec() }).await.map(|_| ())
    }

    /// Keepalive RCs carry no cyclic object again.
    pub fn stop_cyclic(&self) {
        self.driver.driver().with_session(|s| s.stop_cyclic());
    }

    /// One RC with CyclicObj `slot` now, as [`Client::exchange_cyclic`].
    pub async fn exchange_cyclic(&self, slot: u8, write: &[Value]) -> Result<Vec<(&'static DataEntry, Value)>, Error> {
        let (object, data) = expect_output!(
            self.driver.run(Op::ExchangeCyclic { slot, write: write.to_vec() }).await,
            Output::Cyclic { object, data } => (object, data)
        )?;
        decode_cyclic_read(&object, &data)
    }

    /// The read data of the latest keepalive RC that carried a cyclic object, with its time.
    pub fn last_cyclic_read(&self) -> Option<(Timestamp, Vec<(&'static DataEntry, Value)>)> {
        let (t, object, data) = self.driver.driver().with_session(|s| s.last_cyclic_read())?;
        decode_cyclic_read(&object, &data).ok().map(|v| (t, v))
    }

    /// The operation of [`AsyncClient::move_to`], to start with [`AsyncClient::start`] for its progress.
    pub fn move_to_op(
        &self,
        actuator: Actuator,
        target: PositionCounts,
        speed: impl Into<Speed>,
        function: Option<MotionFunction>,
    ) -> Result<Op, Error> {
        Ok(Op::Move(move_spec(&self.config, actuator, target, speed.into(), function)?))
    }

    /// Moves `actuator` to `target` as [`Client::move_to`] (`function`: instead of the one with the
    /// actuator's number). Dropping the future before it is done stops the motion (fast RS, confirmed).
    pub async fn move_to(
        &self,
        actuator: Actuator,
        target: PositionCounts,
        speed: impl Into<Speed>,
        function: Option<MotionFunction>,
    ) -> Result<MoveReport, Error> {
        let op = self.move_to_op(actuator, target, speed, function)?;
        expect_output!(self.driver.run(op).await, Output::Move(r) => r)
    }

    /// Moves the actuators `function` drives, each to its own target, as [`Client::move_function`].
    /// Dropping the future before it is done stops the motion.
    pub async fn move_function(
        &self,
        function: MotionFunction,
        targets: &[(Actuator, PositionCounts)],
        speed: impl Into<Speed>,
    ) -> Result<MoveReport, Error> {
        let primary = targets.first().map_or(Actuator::new(1).expect("A1"), |(a, _)| *a);
        let spec = MoveSpec { function, primary, targets: MoveTargets::Given(targets.to_vec()), speed: speed.into() };
        expect_output!(self.driver.run(Op::Move(spec)).await, Output::Move(r) => r)
    }

    /// Prepares streamed setpoints, as [`Client::stream`].
    pub async fn stream(
        &self,
        function: MotionFunction,
        actuators: &[Actuator],
        speed: impl Into<Speed>,
    ) -> Result<AsyncSetpointStream<'_>, Error> {
        let op = Op::StreamOpen { function, actuators: actuators.to_vec(), speed: speed.into() };
        let limits = expect_output!(self.driver.run(op).await, Output::Strokes(s) => s)?;
        Ok(AsyncSetpointStream { client: self, function, actuators: actuators.to_vec(), limits, started: false })
    }

    /// Opens the port again (after a loss): RO, RC, and RS for every function that was started.
    pub async fn reconnect(&self) -> Result<(), Error> {
        self.driver.run(Op::Reconnect).await.map(|_| ())
    }

    /// Opens remote mode again after the unit ended it: the caller's decision, as [`Client::reopen`].
    pub async fn reopen(&self) -> Result<(), Error> {
        self.driver.run(Op::Reopen).await.map(|_| ())
    }

    /// Ends the session: RS for every started function (motions fast), the status until no actuator moves,
    /// then RA; waits at most [`Config::close_bound`]; runs on tokio's blocking pool. Returns the functions
    /// it stopped, as [`Client::close`] does.
    pub async fn close(self) -> Result<Vec<Function>, Error> {
        let started = self.started();
        super::closed(started, self.driver.close().await)
    }
}

/// Streamed setpoints of one function for async callers, made by [`AsyncClient::stream`]; see
/// [`super::SetpointStream`]. Dropping it stops the function (fast RS, on the driver's thread) if it was
/// started.
pub struct AsyncSetpointStream<'c> {
    client: &'c AsyncClient,
    function: MotionFunction,
    actuators: Vec<Actuator>,
    limits: Vec<Stroke>,
    started: bool,
}

impl std::fmt::Debug for AsyncSetpointStream<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("AsyncSetpointStream").field("function", &self.function).finish()
    }
}

impl AsyncSetpointStream<'_> {
    /// New targets, one per actuator, as [`super::SetpointStream::set_targets`].
    pub async fn set_targets(&mut self, targets: &[PositionCounts]) -> Result<(), Error> {
        let targets = super::stream_targets(self.function, &self.actuators, &self.limits, targets)?;
        self.started = true;
        self.client.driver.run(Op::StreamTargets { function: self.function, targets }).await.map(|_| ())
    }

    /// A new speed for the running motion (and the next ones).
    pub async fn set_speed(&mut self, speed: impl Into<Speed>) -> Result<(), Error> {
        let raw = speed.into().for_motion(self.client.config.speed_mode).map_err(Error::InvalidArgument)?;
        let index = self.function.remote_speed_index();
        self.client.driver.run(Op::Set { index, data: raw.to_le_bytes().to_vec(), verify: false }).await.map(|_| ())
    }

    /// Where each actuator is, and whether it moves.
    pub async fn positions(&self) -> Result<Vec<(Actuator, PositionCounts, bool)>, Error> {
        let status = self.client.statuses().await?;
        let positions = self.client.positions().await?;
        Ok(super::stream_positions(&self.actuators, &status, &positions))
    }

    /// Ends the stream: RS (`mode`), then the status until no actuator moves; where each came to rest.
    pub async fn stop(mut self, mode: StopMode) -> Result<Vec<(Actuator, PositionCounts)>, Error> {
        self.started = false;
        let op = Op::Stop { function: self.function, mode, watch: self.actuators.clone(), after: None };
        expect_output!(self.client.driver.run(op).await, Output::Rest(r) => r)
    }

    /// Stops the function after `cause` ended the stream: fast RS and the status; the error to report.
    pub async fn abort(mut self, cause: Error) -> Error {
        self.started = false;
        let op = Op::Stop {
            function: self.function,
            mode: StopMode::Fast,
            watch: self.actuators.clone(),
            after: Some(Box::new(cause)),
        };
        match self.client.driver.run(op).await {
            Err(e) => e,
            Ok(other) => Error::UnexpectedReply { command: Command::Stop, detail: format!("{other:?}") },
        }
    }
}

impl Drop for AsyncSetpointStream<'_> {
    fn drop(&mut self) {
        if self.started {
            // A stop is not interrupted when its future is dropped: it runs to its end on the driver's thread.
            let op =
                Op::Stop { function: self.function, mode: StopMode::Fast, watch: self.actuators.clone(), after: None };
            drop(self.client.driver.start(op));
        }
    }
}
