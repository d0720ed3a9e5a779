//! [`Client`]: the session run by the blocking [`Driver`] (a caller's request runs on the caller's own thread;
//! one background thread sends the keepalive when nobody else uses the line).

use motionlink_link::cancel::CancelToken;
use motionlink_link::driver::{Driver, DriverConfig, Port, PortOpener};
use motionlink_link::link::Connector;
use motionlink_link::url::PortUrl;
use motionlink_link::{Link, LinkError, SharedClock, Timestamp};

use super::{expect_output, move_spec, run_spec, MoveOptions};
use crate::config::Config;
use crate::error::Error;
use crate::model::{
    Actuator, ActuatorStatus1, CyclicObject, DataEntry, DataIndex, ErrorCode, Function, MotionDirection,
    MotionFunction, PositionCounts, Speed, StopMode,
};
use crate::session::ops::basic::{cyclic_index, decode_cyclic_read, encode_for};
use crate::session::{
    Capabilities, ClientStats, MoveReport, Op, Output, PreparedRequest, Progress, RunAction, RunProgress, RunReport,
    Session, SetReport, Snapshot, StopReport, SwitchReport, WatchSpec,
};
use crate::value::Value;
use crate::wire::{Command, Request};

/// A session with an SCU control unit, for blocking callers. See the [crate documentation](crate).
///
/// `Client` is `Sync`: share it between threads (`&Client`, `Arc<Client>`); their requests interleave on the
/// line as the session schedules them. Dropping it ends the session as [`Client::close`] does (waiting at
/// most [`Config::close_bound`], 5 s by default).
pub struct Client {
    driver: Driver<Session>,
    config: Config,
    /// Cancels the long operations (watch, run, moves) of this client: [`Client::set_cancel`].
    cancel: std::sync::Mutex<Option<CancelToken>>,
}

impl std::fmt::Debug for Client {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Client").field("port", &self.driver.port_name()).finish()
    }
}

impl Client {
    /// Opens a session on the serial line or TCP port `port` names (`--port` syntax; not `sim`), at
    /// [`Config::baud`]; a lost port is opened again by the same name (see [`Config::auto_reconnect`]).
    pub fn open(port: &PortUrl, clock: SharedClock, config: Config) -> Result<Self, Error> {
        let connector = super::port_connector(port, &config)?;
        Self::with_connector(connector, clock, config)
    }

    /// Opens a session on `link`, already open (a pty, an emulator's link, a port opened by the caller). A
    /// session on it cannot reconnect once it is lost: [`Client::with_connector`] can.
    pub fn with_link(link: Box<dyn Link>, clock: SharedClock, config: Config) -> Result<Self, Error> {
        Self::with_connector(super::link_connector(link), clock, config)
    }

    /// Opens a session: checks the configuration, connects, sends RO with the configured Safety_ID and a
    /// first RC, and starts the keepalive. `connector` is called again to reconnect.
    ///
    /// Requests run on the calling thread; with an auto-advancing
    /// [`ManualClock`](motionlink_link::ManualClock) the calling thread must be one of its participants.
    pub fn with_connector(connector: Connector, clock: SharedClock, config: Config) -> Result<Self, Error> {
        let driver = Self::make_driver(connector, clock, config.clone())?;
        if let Err(e) = driver.run(Op::Open) {
            // Nothing was started: the session is closed here (RA, if remote mode was opened), and a close
            // that cannot be confirmed (the port is gone) says no more than the open's error.
            if let Err(close) = driver.close() {
                tracing::debug!("closing the session whose opening failed: {close}");
            }
            return Err(e);
        }
        Ok(Client { driver, config, cancel: Default::default() })
    }

    /// Validates `config`, connects, and makes the driver (nothing is sent yet).
    pub(crate) fn make_driver(
        connector: Connector,
        clock: SharedClock,
        config: Config,
    ) -> Result<Driver<Session>, Error> {
        config.validate()?;
        let mut connector = super::waking(connector, config.wake_break);
        let link = connector()?;
        let session = Session::new(config.clone(), clock.now())?;
        let opener: PortOpener = Box::new(move || connector().map(Port::Bytes));
        let driver_config = DriverConfig { close_bound: config.close_bound, ..DriverConfig::default() };
        let port = Port::Bytes(link);
        let name = port.describe();
        Driver::new(session, port, Some(opener), clock, driver_config)
            .map_err(|source| Error::Link(LinkError::Io { port: name, source: std::sync::Arc::new(source) }))
    }

    /// The driver underneath (for [`Driver::with_session`], and to run any [`Op`]).
    pub fn driver(&self) -> &Driver<Session> {
        &self.driver
    }

    /// Runs `op` to its end.
    pub fn run(&self, op: Op) -> Result<Output, Error> {
        self.driver.run(op)
    }

    /// The port, as the link describes it.
    pub fn port(&self) -> &str {
        self.driver.port_name()
    }

    /// Makes `token` cancel this client's long operations (a watch, a run, a move), as Ctrl-C does in the
    /// command line and in Python: the operation stops what it set in motion and ends. The same as the
    /// PowerCube's and the COMPAX's `set_cancel`.
    pub fn set_cancel(&self, token: CancelToken) {
        *motionlink_link::clock::lock(&self.cancel) = Some(token);
    }

    fn token(&self) -> Option<CancelToken> {
        motionlink_link::clock::lock(&self.cancel).clone()
    }

    /// The session's settings.
    pub fn config(&self) -> &Config {
        &self.config
    }

    /// The session's clock.
    pub fn clock(&self) -> &SharedClock {
        self.driver.clock()
    }

    /// Counters of the session.
    pub fn stats(&self) -> ClientStats {
        self.driver.with_session(|s| s.stats())
    }

    /// What the session found the unit to do where the manual leaves it open (each probed the first time a
    /// check needed it).
    pub fn capabilities(&self) -> Capabilities {
        self.driver.with_session(|s| s.capabilities())
    }

    /// Takes what `known` says of the unit (a device profile's capabilities) where the session has not found
    /// out yet: what the unit lacks is not asked for, what it has is confirmed by the first check that
    /// depends on it ([`Session::seed_capabilities`]).
    pub fn seed_capabilities(&self, known: Capabilities) {
        self.driver.with_session(|s| s.seed_capabilities(known))
    }

    /// The functions this session started with RE and has not stopped yet.
    pub fn started(&self) -> Vec<Function> {
        self.driver.with_session(|s| s.started())
    }

    /// True while the session is open (not lost, not ended by the unit, not closed).
    pub fn is_open(&self) -> bool {
        self.driver.with_session(|s| s.is_open())
    }

    /// Why the session is not open, if it is not: lost, ended by the unit, or closed.
    pub fn not_open_reason(&self) -> Option<String> {
        self.driver.with_session(|s| s.not_open_reason())
    }

    /// Sends any request and returns the data of its ACK (for what the typed methods do not cover).
    pub fn request(&self, request: &Request<'_>) -> Result<Option<Vec<u8>>, Error> {
        expect_output!(self.driver.run(Op::Request(PreparedRequest::new(request)?)), Output::Data(d) => d)
    }

    // ----- data list

    /// Reads the raw bytes of a data index (entry or group). A group is read by its grouping index, or,
    /// where the unit refuses grouping indices (PDE), entry by entry (the same bytes; said once per session).
    pub fn get_raw(&self, index: DataIndex) -> Result<Vec<u8>, Error> {
        super::data(expect_output!(self.driver.run(Op::Read(index)), Output::Data(d) => d)?)
    }

    /// Reads an entry or a group, each member decoded.
    pub fn get(&self, index: DataIndex) -> Result<Vec<(&'static DataEntry, Value)>, Error> {
        let it = super::item_of(index)?;
        super::decode(it, &self.get_raw(index)?)
    }

    /// Reads one entry.
    pub fn get_value(&self, index: DataIndex) -> Result<Value, Error> {
        super::entry_of(index)?;
        Ok(self.get(index)?.remove(0).1)
    }

    /// Writes a remote data entry (0x3xxx) after checking the value's kind and range, then reads it back: a
    /// value that reads back different is [`Error::ReadBack`]. The report says whether the value was read
    /// back (a unit that refuses to read remote data back: `verified` is false, and why).
    pub fn set(&self, index: DataIndex, value: &Value) -> Result<SetReport, Error> {
        let (_, data) = encode_for(index, value, self.config.speed_mode)?;
        self.set_raw(index, &data)
    }

    /// Writes raw bytes to a data index (no checks but the unit's), then reads the index back where the data
    /// list has it (every remote entry and group is readable): a mismatch is [`Error::ReadBack`]. An index
    /// outside the data list is written, not read back: the report says so (`verified` false).
    pub fn set_raw(&self, index: DataIndex, data: &[u8]) -> Result<SetReport, Error> {
        expect_output!(
            self.driver.run(Op::Set { index, data: data.to_vec(), verify: true }),
            Output::Written(r) => r
        )
    }

    /// Actuator `a`'s position.
    pub fn position(&self, a: Actuator) -> Result<PositionCounts, Error> {
        super::position(self.get_value(a.position_index())?)
    }

    /// Every actuator's position (0x0010), A1 first.
    pub fn positions(&self) -> Result<[PositionCounts; 6], Error> {
        crate::session::ops::positions(&self.get_raw(DataIndex(0x0010))?)
    }

    /// Actuator `a`'s status 1.
    pub fn status1(&self, a: Actuator) -> Result<ActuatorStatus1, Error> {
        super::status1(&self.get_raw(a.status1_index())?)
    }

    /// Every actuator's status 1 (0x0170), A1 first.
    pub fn statuses(&self) -> Result<[ActuatorStatus1; 6], Error> {
        crate::session::ops::statuses(&self.get_raw(DataIndex(0x0170))?)
    }

    /// The actuators whose status 1 says "drive available".
    pub fn connected_actuators(&self) -> Result<Vec<Actuator>, Error> {
        Ok(super::connected(&self.statuses()?))
    }

    /// Actuator `a`'s travel range for targets: [`Config::stroke_limits`] if set, else the virtual limits
    /// of its UserPositionData (0x2001..0x2006) as the unit reports them; `None` if the unit has none (both 0).
    pub fn stroke_limits(&self, a: Actuator) -> Result<Option<(crate::config::StrokeLimits, &'static str)>, Error> {
        expect_output!(self.driver.run(Op::StrokeLimits(a)), Output::Stroke(s) => s)
    }

    /// One sample of every actuator's status 1, position and current and of Error_Code 1: through one RC
    /// carrying the session's cyclic object where the unit takes it (defined on first use), else with reads.
    pub fn sample(&self) -> Result<Snapshot, Error> {
        let op = Op::Watch(WatchSpec { interval: std::time::Duration::ZERO, count: Some(1) });
        let last = expect_output!(self.driver.run(op), Output::Watched { last, .. } => last)?;
        last.ok_or(Error::UnexpectedReply { command: Command::Get, detail: "a watch without a sample".into() })
    }

    /// Samples as [`Client::sample`] every `interval` (the first at once) until `count` samples were taken
    /// or the client's cancel token ([`Client::set_cancel`]) is cancelled (which ends the watch without an error); `on_sample` sees each. Where the
    /// unit takes the session's cyclic object, each sample rides on a keepalive RC, so a link whose round
    /// trips leave no room for other requests beside the keepalive can still be watched once the object is
    /// defined. Returns how many samples were taken.
    pub fn watch(
        &self,
        interval: std::time::Duration,
        count: Option<u64>,
        on_sample: &mut dyn FnMut(&Snapshot),
    ) -> Result<u64, Error> {
        let mut each = |p: &Progress| {
            if let Progress::Watch(s) = p {
                on_sample(s);
            }
        };
        let op = Op::Watch(WatchSpec { interval, count });
        let cancel = self.token();
        expect_output!(self.driver.run_with(op, &mut each, cancel.as_ref()), Output::Watched { samples, .. } => samples)
    }

    /// Error_Code 1 (most recent) to 5 (oldest).
    pub fn error_history(&self) -> Result<[ErrorCode; 5], Error> {
        super::error_history(&self.get_raw(DataIndex(0x00D0))?)
    }

    // ----- functions

    /// RE on a motion function: its drives move as `direction` says, at the function's remote speed. The
    /// function stays started until [`Client::stop_motion`] or the end of the session.
    pub fn start_motion(&self, function: MotionFunction, direction: MotionDirection) -> Result<(), Error> {
        self.request(&Request::Execute { function: function.id(), params: [direction.code(), crate::model::UNUSED] })
            .map(|_| ())
    }

    /// RS on a motion function (sent before anything else that waits).
    pub fn stop_motion(&self, function: MotionFunction, mode: StopMode) -> Result<(), Error> {
        self.request(&Request::Stop { function: function.id(), param: mode.code() }).map(|_| ())
    }

    /// Stops motion functions and confirms it: RS (`mode`) to each of `functions` in turn (an RS the unit
    /// refuses is noted in the report and the others are sent all the same), then the status of every
    /// actuator until none moves (at most 500 ms after a fast stop, 3 s after a soft one), then where each
    /// connected actuator is. An actuator still moving then, or a status that cannot be read, is
    /// [`Error::StopUnconfirmed`]. The RS go out whether or not this session started the functions: what
    /// `motionlink scu stop` sends (with [`MotionFunction::all`] when no function is named).
    pub fn stop_functions(&self, functions: &[MotionFunction], mode: StopMode) -> Result<StopReport, Error> {
        let op = Op::StopMotions { functions: functions.to_vec(), mode };
        expect_output!(self.driver.run(op), Output::Stopped(r) => r)
    }

    /// Switches a switching function (F11 buzzer, F17/F18 binary outputs, F20 emergency stop, F21/F22 LEDs) on
    /// (RE) or off (RS), then reads the status entry that shows it ([`Function::switch_status`]) until it
    /// shows the state asked for (at most [`Config::start_grace`]). The report says whether it did
    /// (`verified`) or why that could not be checked (a unit that refuses the entry, an entry the manuals do
    /// not tie to the function in so many words and that this session has not seen follow it); an entry that
    /// shows the other state is [`Error::SwitchNotShown`].
    pub fn switch(&self, function: Function, on: bool) -> Result<SwitchReport, Error> {
        expect_output!(self.driver.run(super::switch_op(function, on)?), Output::Switched(r) => r)
    }

    /// Runs a function until it ends (a motion function whose actuators all stopped), `limit` passes, or
    /// the client's cancel token ([`Client::set_cancel`]) is cancelled; then stops it (fast) and confirms the stop with the status. `progress` sees every
    /// look at the actuators (the first right after the RE was acknowledged). A cancelled run ends with
    /// [`Error::RunCancelled`] naming where the actuators came to rest.
    pub fn run_function(
        &self,
        action: RunAction,
        limit: Option<std::time::Duration>,
        progress: &dyn Fn(&RunProgress),
    ) -> Result<RunReport, Error> {
        let mut each = |p: &Progress| {
            if let Progress::Run(r) = p {
                progress(r);
            }
        };
        let (spec, cancel) = (run_spec(action, limit)?, self.token());
        expect_output!(self.driver.run_with(Op::Run(spec), &mut each, cancel.as_ref()), Output::Run(r) => r)
    }

    // ----- cyclic objects

    /// Defines CyclicObj `slot` (1..5) on the unit (and reads the definition back, where the unit reads
    /// remote data: the report says).
    pub fn configure_cyclic(&self, slot: u8, object: &CyclicObject) -> Result<SetReport, Error> {
        let report = self.set(cyclic_index(slot)?, &Value::CyclicObject(*object))?;
        self.driver.with_session(|s| s.cyclic_slot_written(slot));
        Ok(report)
    }

    /// From now on every keepalive RC carries CyclicObj `slot` with `write` (one value per entry its definition
    /// writes, a group counting each of its members; the definition is read from the unit). The latest read
    /// data is available from [`Client::last_cyclic_read`]. Keepalive writes are not read back. Meanwhile
    /// moves poll with reads.
    pub fn use_cyclic(&self, slot: u8, write: &[Value]) -> Result<(), Error> {
        self.driver.run(Op::UseCyclic { slot, write: write.to_vec() }).map(|_| ())
    }

    /// Keepalive RCs carry no cyclic object again.
    pub fn stop_cyclic(&self) {
        self.driver.with_session(|s| s.stop_cyclic());
    }

    /// One RC with CyclicObj `slot` now: writes `write`, returns the read data decoded (groups member by
    /// member).
    pub fn exchange_cyclic(&self, slot: u8, write: &[Value]) -> Result<Vec<(&'static DataEntry, Value)>, Error> {
        let (object, data) = expect_output!(
            self.driver.run(Op::ExchangeCyclic { slot, write: write.to_vec() }),
            Output::Cyclic { object, data } => (object, data)
        )?;
        decode_cyclic_read(&object, &data)
    }

    /// The read data of the latest keepalive RC that carried a cyclic object, with its time.
    pub fn last_cyclic_read(&self) -> Option<(Timestamp, Vec<(&'static DataEntry, Value)>)> {
        let (t, object, data) = self.driver.with_session(|s| s.last_cyclic_read())?;
        decode_cyclic_read(&object, &data).ok().map(|v| (t, v))
    }

    // ----- moves

    /// Moves `actuator` to `target` at `speed` with the function of the same number (F1 for A1;
    /// [`MoveOptions::function`] names another). Every actuator that function drives gets the same target: the
    /// ones [`Config::function_map`] names, or, where the map does not know the function, every
    /// connected actuator (its remote position is written; an actuator the function does not drive stays where
    /// it is and is reported as not moved). See [`Client::move_function`] for how the move runs and ends.
    pub fn move_to(
        &self,
        actuator: Actuator,
        target: PositionCounts,
        speed: impl Into<Speed>,
        options: &MoveOptions<'_>,
    ) -> Result<MoveReport, Error> {
        let spec = move_spec(&self.config, actuator, target, speed.into(), options.function)?;
        self.run_move(spec, options)
    }

    /// Moves the actuators `function` drives, each to its own target, with one RE: checks every target against
    /// its actuator's stroke (nothing moves if one is outside), writes and reads back each remote position
    /// and the function's remote speed, starts the function with direction 9, watches the actuators every
    /// [`Config::poll_interval`] (through the keepalive RC, see [`crate::config::MovePolling`]), and when
    /// the unit reports that none of them moves any more judges where they ended. It succeeds if each is within
    /// [`Config::position_tolerance_counts`] of its target, and ends the function with RS. A cancel, a
    /// stall, a timeout or any error stops the function at once (fast RS); if the unit does not confirm that
    /// stop, the error is [`Error::StopUnconfirmed`].
    ///
    /// If [`Config::function_map`] knows `function`, `targets` must name exactly the actuators it
    /// drives. If it does not, the function may drive connected actuators `targets` does not name: each
    /// is held, its remote position written with where it stands (read back), and watched and reported
    /// with that position as its target (an unnamed actuator would otherwise run to whatever its remote
    /// position held).
    pub fn move_function(
        &self,
        function: MotionFunction,
        targets: &[(Actuator, PositionCounts)],
        speed: impl Into<Speed>,
        options: &MoveOptions<'_>,
    ) -> Result<MoveReport, Error> {
        let primary = targets.first().map_or(Actuator::new(1).expect("A1"), |(a, _)| *a);
        let spec = crate::session::MoveSpec {
            function,
            primary,
            targets: crate::session::MoveTargets::Given(targets.to_vec()),
            speed: speed.into(),
        };
        self.run_move(spec, options)
    }

    fn run_move(&self, spec: crate::session::MoveSpec, options: &MoveOptions<'_>) -> Result<MoveReport, Error> {
        let mut each = |p: &Progress| {
            if let (Progress::Move(m), Some(f)) = (p, options.progress) {
                f(m);
            }
        };
        let cancel = self.token();
        expect_output!(self.driver.run_with(Op::Move(spec), &mut each, cancel.as_ref()), Output::Move(r) => r)
    }

    /// Prepares streamed setpoints (as a ros2_control hardware interface sends them, 10..100 times a second)
    /// for `function` driving `actuators` at `speed`: checks the actuators (connected; exactly the ones the
    /// function map says the function drives, if it knows it), reads their strokes, and writes the speed
    /// (read back). A function the map does not know may drive connected actuators not named: each gets
    /// its remote position written with where it stands (read back), so it stays there. Nothing moves until
    /// the first [`SetpointStream::set_targets`].
    pub fn stream(
        &self,
        function: MotionFunction,
        actuators: &[Actuator],
        speed: impl Into<Speed>,
    ) -> Result<SetpointStream<'_>, Error> {
        let op = Op::StreamOpen { function, actuators: actuators.to_vec(), speed: speed.into() };
        let limits = expect_output!(self.driver.run(op), Output::Strokes(s) => s)?;
        Ok(SetpointStream { client: self, function, actuators: actuators.to_vec(), limits, started: false })
    }

    // ----- session

    /// Opens the port again (after a loss): RO, RC, and RS for every function that was started.
    pub fn reconnect(&self) -> Result<(), Error> {
        self.driver.run(Op::Reconnect).map(|_| ())
    }

    /// Opens remote mode again after the unit ended it ([`Error::RemoteEnded`]): RO, RC, and RS for every
    /// function this session started. This is the caller's decision to go on; the session never takes it by
    /// itself.
    pub fn reopen(&self) -> Result<(), Error> {
        self.driver.run(Op::Reopen).map(|_| ())
    }

    /// Ends the session: RS for every started function (motions fast), the status of every actuator until
    /// none moves (an acknowledged RS does not say the drives are at rest), then RA; waits at most
    /// [`Config::close_bound`]. Returns the functions it stopped (the unit acknowledged their RS; none when
    /// nothing was left started). The session is closed even if that fails; the error says what could not be
    /// sent or confirmed ([`Error::CloseUnconfirmed`], naming the functions, when some were left started).
    pub fn close(self) -> Result<Vec<Function>, Error> {
        let started = self.started();
        super::closed(started, self.driver.close())
    }
}

/// Streamed setpoints of one function, made by [`Client::stream`]. Each update writes the remote positions
/// and starts the function towards them again (RE with direction 9: the unit takes the remote positions when
/// RE comes); a new speed applies to the running motion along the ramp. Dropping the stream stops the
/// function (fast RS) if it was started.
pub struct SetpointStream<'c> {
    client: &'c Client,
    function: MotionFunction,
    actuators: Vec<Actuator>,
    limits: Vec<crate::session::ops::basic::Stroke>,
    started: bool,
}

impl std::fmt::Debug for SetpointStream<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SetpointStream").field("function", &self.function).field("actuators", &self.actuators).finish()
    }
}

impl<'c> SetpointStream<'c> {
    /// The function it drives.
    pub fn function(&self) -> MotionFunction {
        self.function
    }

    /// The actuators, in the order targets are given.
    pub fn actuators(&self) -> &[Actuator] {
        &self.actuators
    }

    /// The client it streams through.
    pub(crate) fn client(&self) -> &'c Client {
        self.client
    }

    /// New targets, one per actuator in the order of [`SetpointStream::actuators`]: each is checked against its
    /// stroke (an error moves nothing new), written, and the function is started towards them. The remote
    /// positions are not read back (that would halve the rate); the CRC of every telegram and the unit's ACK
    /// are the check, and [`SetpointStream::positions`] shows where the actuators are.
    pub fn set_targets(&mut self, targets: &[PositionCounts]) -> Result<(), Error> {
        let targets = super::stream_targets(self.function, &self.actuators, &self.limits, targets)?;
        self.started = true;
        self.client.driver.run(Op::StreamTargets { function: self.function, targets }).map(|_| ())
    }

    /// A new speed for the running motion (and the next ones); the unit follows it along its ramp.
    pub fn set_speed(&mut self, speed: impl Into<Speed>) -> Result<(), Error> {
        let raw = speed.into().for_motion(self.client.config.speed_mode).map_err(Error::InvalidArgument)?;
        let index = self.function.remote_speed_index();
        self.client.driver.run(Op::Set { index, data: raw.to_le_bytes().to_vec(), verify: false }).map(|_| ())
    }

    /// Where each actuator is, and whether it moves.
    pub fn positions(&self) -> Result<Vec<(Actuator, PositionCounts, bool)>, Error> {
        let status = self.client.statuses()?;
        let positions = self.client.positions()?;
        Ok(super::stream_positions(&self.actuators, &status, &positions))
    }

    /// Ends the stream: RS (`mode`), then the status until no actuator moves; returns where each came to rest.
    /// A stop the unit did not confirm is [`Error::StopUnconfirmed`].
    pub fn stop(mut self, mode: StopMode) -> Result<Vec<(Actuator, PositionCounts)>, Error> {
        self.started = false;
        let op = Op::Stop { function: self.function, mode, watch: self.actuators.clone(), after: None };
        expect_output!(self.client.driver.run(op), Output::Rest(r) => r)
    }

    /// Stops the function after `cause` ended the stream: fast RS and the status; the error to report.
    pub fn abort(mut self, cause: Error) -> Error {
        self.started = false;
        let op = Op::Stop {
            function: self.function,
            mode: StopMode::Fast,
            watch: self.actuators.clone(),
            after: Some(Box::new(cause)),
        };
        match self.client.driver.run(op) {
            Err(e) => e,
            Ok(other) => Error::UnexpectedReply { command: Command::Stop, detail: format!("{other:?}") },
        }
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
