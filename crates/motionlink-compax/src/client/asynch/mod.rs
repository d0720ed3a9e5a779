//! [`AsyncClient`]: the async driver of a COMPAX session, on tokio (feature `tokio`).

mod drive;

use std::ops::RangeInclusive;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use motionlink_link::clock::{lock, SharedClock};
use motionlink_link::driver::{AsyncDriver, Driver, OpFuture, Port};
use motionlink_link::link::Link;
use motionlink_link::url::PortUrl;
use motionlink_link::LinkError;

use super::{driver_config, output};
use crate::error::{Error, Result, StopReport};
use crate::model::{
    Command, OutputState, ParamId, Position, RampMs, S16Bits, S17Bits, SpeedPercent, StatusId, StatusValue,
};
use crate::report::{DriveStop, OutputSwitched, ParamReading, ParamWritten};
use crate::session::{
    AfterRaw, Config, MoveOptions, MoveReport, MoveRequest, Op, Output, RawOutcome, Session, StartedMove,
};
use crate::wire::Address;
pub use drive::{AsyncDrive, AsyncWatch};

/// An async client of one bus of COMPAX drives: the operations of [`Client`](super::Client) as futures,
/// with the same safety. Each method runs the same [`Op`] of the session as its blocking namesake.
/// Dropping a future before it is done cancels its operation: a move not yet sent is not sent, and a
/// wait, checked move or [`AsyncClient::raw_motion`] that set an axis in motion stops it (`OUTPUT O0=0`,
/// confirmed by S17). Operations of several tasks take turns on the line.
///
/// What the blocking client does with a cancel token ([`Client::set_cancel`](super::Client::set_cancel))
/// the async one does by dropping the future; [`AsyncClient::watch`] is a stream of samples
/// ([`AsyncWatch::next`]) instead of a callback; progress reports of a wait or checked move are taken from
/// the future [`AsyncClient::start`] returns ([`OpFuture::take_progress`]).
///
/// The session runs on the driver's thread; opening and closing (which block on I/O) run on tokio's
/// blocking pool. Dropping the client closes the session there (stopping what it set in motion, bounded
/// by [`Config::close_bound`]).
pub struct AsyncClient {
    driver: AsyncDriver<Session>,
    config: Config,
    close_report: ReportSlot,
}

impl std::fmt::Debug for AsyncClient {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("AsyncClient").field("port", &self.driver.driver().port_name()).finish()
    }
}

/// Where the close sequence's report is put.
type ReportSlot = Arc<Mutex<Option<StopReport>>>;

fn driver_for(link: Box<dyn Link>, clock: SharedClock, cfg: &Config) -> Result<(Driver<Session>, ReportSlot)> {
    let session = Session::new(cfg.clone(), clock.now());
    let report = session.close_report();
    let port = Port::Bytes(link);
    let name = port.describe();
    let driver = Driver::new(session, port, None, clock, driver_config(cfg))
        .map_err(|source| Error::Link(LinkError::Io { port: name, source: std::sync::Arc::new(source) }))?;
    Ok((driver, report))
}

impl AsyncClient {
    /// A client on `link` (already open), timed by `clock`, as [`Client::with_link`](super::Client::with_link).
    pub async fn with_link(link: Box<dyn Link>, clock: SharedClock, cfg: Config) -> Result<Self> {
        let (driver, close_report) = driver_for(link, clock, &cfg)?;
        Ok(AsyncClient { driver: AsyncDriver::from_driver(driver), config: cfg, close_report })
    }

    /// Opens the line `url` names as [`Client::open`](super::Client::open) does, on tokio's blocking pool
    /// (opening a serial port or a TCP connection blocks), then starts the session on it.
    pub async fn open(url: &PortUrl, clock: SharedClock, cfg: Config) -> Result<Self> {
        let report = Arc::new(Mutex::new(None));
        let slot = Arc::clone(&report);
        let for_open = cfg.clone();
        let url = url.clone();
        let driver = AsyncDriver::open(move || -> Result<Driver<Session>> {
            let (driver, r) = driver_for(super::open_line(&url, &for_open)?, clock, &for_open)?;
            *lock(&slot) = Some(r);
            Ok(driver)
        })
        .await?;
        let close_report = lock(&report).take().unwrap_or_default();
        Ok(AsyncClient { driver, config: cfg, close_report })
    }

    /// The configuration.
    pub fn config(&self) -> &Config {
        &self.config
    }

    /// Starts `op`: the returned future ends with its output; dropping it cancels the operation (which
    /// stops what it started). Its progress can be taken from it meanwhile
    /// ([`OpFuture::take_progress`]).
    pub fn start(&self, op: Op) -> OpFuture<Session> {
        self.driver.start(op)
    }

    /// Runs `op` to its end; dropping the future cancels it, as [`AsyncClient::start`].
    pub async fn run(&self, op: Op) -> Result<Output> {
        self.driver.run(op).await
    }

    /// The driver underneath (to look at the session).
    pub fn driver(&self) -> &AsyncDriver<Session> {
        &self.driver
    }

    /// The port, for messages.
    pub fn port(&self) -> &str {
        self.driver.driver().port_name()
    }

    /// The clock the session runs on.
    pub fn clock(&self) -> &SharedClock {
        self.driver.driver().clock()
    }

    /// A handle on drive `address` (1..=31); the broadcast address 32 is refused ([`Error::Broadcast`]).
    pub fn drive(&self, address: Address) -> Result<AsyncDrive<'_>> {
        AsyncDrive::new(self, address)
    }

    /// The drives this client set in motion and has not yet seen stop.
    pub fn started(&self) -> Vec<Address> {
        self.driver.driver().with_session(|s| s.started())
    }

    /// The drives that have answered this client.
    pub fn known(&self) -> Vec<Address> {
        self.driver.driver().with_session(|s| s.known())
    }

    /// Hands the motion of `drives` over: the client forgets it set them in motion and does not stop them.
    pub fn release(&self, drives: &[Address]) {
        self.driver.driver().with_session(|s| s.release(drives));
    }

    async fn done(&self, op: Op, what: &str) -> Result<()> {
        output(self.driver.run(op).await?, what, |o| if o == Output::Done { Ok(()) } else { Err(o) })
    }

    /// A status value; see [`Client::read_status`](super::Client::read_status).
    pub async fn read_status(&self, address: Address, id: StatusId) -> Result<StatusValue> {
        output(self.driver.run(Op::ReadStatus(address, id)).await?, "a status read", |o| match o {
            Output::Status(v) => Ok(v),
            o => Err(o),
        })
    }

    /// Several status values of one drive, in order; see
    /// [`Client::read_statuses`](super::Client::read_statuses).
    pub async fn read_statuses(&self, address: Address, ids: &[StatusId]) -> Result<Vec<(StatusId, StatusValue)>> {
        output(self.driver.run(Op::ReadStatuses(address, ids.to_vec())).await?, "status reads", |o| match o {
            Output::Statuses(v) => Ok(v),
            o => Err(o),
        })
    }

    /// The actual position S1.
    pub async fn read_position(&self, address: Address) -> Result<Position> {
        match self.read_status(address, StatusId::ACTUAL_POSITION).await? {
            StatusValue::Position(p) => Ok(p),
            v => Err(Error::UnexpectedReply { address, command: "S1".into(), reply: v.to_string() }),
        }
    }

    /// The target position S2.
    pub async fn read_target(&self, address: Address) -> Result<Position> {
        match self.read_status(address, StatusId::TARGET_POSITION).await? {
            StatusValue::Position(p) => Ok(p),
            v => Err(Error::UnexpectedReply { address, command: "S2".into(), reply: v.to_string() }),
        }
    }

    /// The status bits S16.
    pub async fn read_s16(&self, address: Address) -> Result<S16Bits> {
        match self.read_status(address, StatusId::STATUS_BITS_1).await? {
            StatusValue::S16(b) => Ok(b),
            v => Err(Error::UnexpectedReply { address, command: "S16".into(), reply: v.to_string() }),
        }
    }

    /// The status bits S17.
    pub async fn read_s17(&self, address: Address) -> Result<S17Bits> {
        match self.read_status(address, StatusId::STATUS_BITS_2).await? {
            StatusValue::S17(b) => Ok(b),
            v => Err(Error::UnexpectedReply { address, command: "S17".into(), reply: v.to_string() }),
        }
    }

    /// A parameter.
    pub async fn read_param(&self, address: Address, id: ParamId) -> Result<f64> {
        output(self.driver.run(Op::ReadParam(address, id)).await?, "a parameter read", |o| match o {
            Output::Number(v) => Ok(v),
            o => Err(o),
        })
    }

    /// A parameter written and read back; see [`Client::write_param`](super::Client::write_param).
    pub async fn write_param(&self, address: Address, id: ParamId, value: f64) -> Result<()> {
        self.done(Op::WriteParam(address, id, value), "a parameter write").await
    }

    /// A parameter written, read back, and read once more; see [`Client::set_param`](super::Client::set_param).
    pub async fn set_param(&self, address: Address, id: ParamId, value: f64) -> Result<ParamWritten> {
        self.write_param(address, id, value).await?;
        let read_back = self.read_param(address, id).await?;
        Ok(ParamWritten { written: ParamReading { id, value }, read_back })
    }

    /// S1 of every address in `range`.
    pub async fn scan(&self, range: RangeInclusive<u8>) -> Result<Vec<(Address, Position)>> {
        output(self.driver.run(Op::Scan(range)).await?, "a scan", |o| match o {
            Output::Found(v) => Ok(v),
            o => Err(o),
        })
    }

    /// A command other than a move; the reply text.
    pub async fn command(&self, address: Address, cmd: &Command) -> Result<String> {
        output(self.driver.run(Op::Command(address, *cmd)).await?, "a command", |o| match o {
            Output::Text(t) => Ok(t),
            o => Err(o),
        })
    }

    /// Text sent as it is; see [`Client::raw`](super::Client::raw).
    pub async fn raw(&self, address: Address, text: &str) -> Result<Option<String>> {
        output(self.driver.run(Op::Raw(address, text.to_string())).await?, "a raw command", |o| match o {
            Output::Reply(r) => Ok(r),
            o => Err(o),
        })
    }

    /// Text sent as [`AsyncClient::raw`] sends it, then what it set in motion handed over or waited for;
    /// see [`Client::raw_motion`](super::Client::raw_motion). Dropping the future stops what it started
    /// (unless it was handed over already).
    pub async fn raw_motion(&self, address: Address, text: &str, after: AfterRaw) -> Result<RawOutcome> {
        let op = Op::RawMotion(address, text.to_string(), after);
        output(self.driver.run(op).await?, "a raw command", |o| match o {
            Output::Raw(r) => Ok(r),
            o => Err(o),
        })
    }

    /// `text?`: the drive sends it back; see [`Client::echo`](super::Client::echo).
    pub async fn echo(&self, address: Address, text: &str) -> Result<String> {
        output(self.driver.run(Op::Echo(address, text.to_string())).await?, "an echo", |o| match o {
            Output::Text(t) => Ok(t),
            o => Err(o),
        })
    }

    /// SPEED for the next positionings.
    pub async fn set_speed(&self, address: Address, speed: SpeedPercent, binary: bool) -> Result<()> {
        self.done(Op::Setting(address, Command::Speed(speed), binary), "a setting").await
    }

    /// ACCEL (acceleration and braking time) for the next positionings.
    pub async fn set_accel(&self, address: Address, ramp: RampMs, binary: bool) -> Result<()> {
        self.done(Op::Setting(address, Command::Accel(ramp), binary), "a setting").await
    }

    /// ACCEL- (braking time alone) for the next positionings.
    pub async fn set_brake(&self, address: Address, ramp: RampMs, binary: bool) -> Result<()> {
        self.done(Op::Setting(address, Command::AccelBrake(ramp), binary), "a setting").await
    }

    /// OUTPUT O`output`=`state` (output 0 is the drive itself: 0 switches it off, 1 on).
    pub async fn set_output(&self, address: Address, output: u16, state: OutputState, binary: bool) -> Result<()> {
        self.done(Op::Setting(address, Command::Output { output, state }, binary), "a setting").await
    }

    /// OUTPUT O`output`=`state` to one drive (as [`Client::set_output`](crate::Client::set_output)), then
    /// read back where the drive shows it: O0 (the drive switched on or off) in S16, an error
    /// ([`Error::OutputNotTaken`]) if it shows another state. No other output can be read: the report
    /// says so (`verified` false), as it does when S16 could not be read or the switch went to every drive.
    pub async fn switch_output(&self, address: Address, output: u16, state: OutputState) -> Result<OutputSwitched> {
        self.set_output(address, output, state, false).await?;
        let read = match OutputSwitched::shown_in_s16(address, output) {
            true => Some(self.read_s16(address).await.map(|s| s.o0_state())),
            false => None,
        };
        OutputSwitched::checked(address, output, state, read)
    }

    /// POSA; returns once the drive has taken it.
    pub async fn move_absolute(&self, address: Address, target: Position, opts: MoveOptions) -> Result<()> {
        self.done(Op::Move(address, Command::PosA(target), opts), "a move").await
    }

    /// POSR; returns once the drive has taken it (never sent again blind).
    pub async fn move_relative(&self, address: Address, distance: Position, opts: MoveOptions) -> Result<()> {
        self.done(Op::Move(address, Command::PosR(distance), opts), "a move").await
    }

    /// POSA HOME: finds machine zero; returns once the drive has taken it.
    pub async fn home(&self, address: Address, opts: MoveOptions) -> Result<()> {
        self.done(Op::Move(address, Command::PosAHome, opts), "a move").await
    }

    /// POSA HOME, waited for and checked by S16; see
    /// [`Client::home_and_wait`](super::Client::home_and_wait). Dropping the future stops the drive.
    pub async fn home_and_wait(&self, address: Address, timeout: Option<Duration>) -> Result<Position> {
        output(self.driver.run(Op::Home(address, timeout)).await?, "a homing", |o| match o {
            Output::Homed(p) => Ok(p),
            o => Err(o),
        })
    }

    /// `cmd` to every drive at once, no reply; see [`Client::broadcast`](super::Client::broadcast).
    pub async fn broadcast(&self, cmd: &Command) -> Result<()> {
        self.done(Op::Broadcast(*cmd), "a broadcast").await
    }

    /// Several drives started at one instant; see [`Client::sync_start`](super::Client::sync_start).
    pub async fn sync_start(&self, moves: &[(Address, Command)], message: bool) -> Result<()> {
        self.done(Op::SyncStart(moves.to_vec(), message), "a synchronous start").await
    }

    /// Waits until the drives' positionings have ended; dropped, or failing, it stops those this client
    /// started.
    pub async fn wait_reached(&self, drives: &[Address], timeout: Option<Duration>) -> Result<()> {
        self.done(Op::Wait(drives.to_vec(), timeout), "a wait").await
    }

    /// A checked move; see [`Client::move_to`](super::Client::move_to). Dropping the future stops the axis.
    pub async fn move_to(&self, address: Address, request: &MoveRequest) -> Result<MoveReport> {
        output(self.driver.run(Op::MoveTo(address, *request)).await?, "a checked move", |o| match o {
            Output::Moved(r) => Ok(r),
            o => Err(o),
        })
    }

    /// The first half of a checked move, up to the target read back.
    pub async fn start_checked_move(&self, address: Address, request: &MoveRequest) -> Result<StartedMove> {
        output(self.driver.run(Op::StartMove(address, *request, false)).await?, "a checked move", |o| match o {
            Output::Started(s) => Ok(s),
            o => Err(o),
        })
    }

    /// [`AsyncClient::start_checked_move`], then the move is handed over (the client forgets it and does
    /// not stop it); see [`Client::start_and_release`](super::Client::start_and_release). Dropped before
    /// the target was read back, the future stops the move instead.
    pub async fn start_and_release(&self, address: Address, request: &MoveRequest) -> Result<StartedMove> {
        output(self.driver.run(Op::StartMove(address, *request, true)).await?, "a checked move", |o| match o {
            Output::Started(s) => Ok(s),
            o => Err(o),
        })
    }

    /// The second half of a checked move: the wait and the position at rest.
    pub async fn finish_checked_move(&self, started: &StartedMove, timeout: Option<Duration>) -> Result<MoveReport> {
        output(self.driver.run(Op::FinishMove(started.clone(), timeout)).await?, "a checked move", |o| match o {
            Output::Moved(r) => Ok(r),
            o => Err(o),
        })
    }

    /// Waits `d`, handling what arrives meanwhile (`$` and comparator messages).
    pub async fn pause(&self, d: Duration) -> Result<()> {
        self.done(Op::Pause(d), "a pause").await
    }

    /// S1 and S17 of `drive` every `interval`, as a stream: [`AsyncWatch::next`] waits for the next
    /// sample. The broadcast address 32 is refused ([`Error::Broadcast`]).
    pub fn watch(&self, drive: Address, interval: Duration) -> Result<AsyncWatch<'_>> {
        AsyncWatch::new(self, drive, interval)
    }

    /// `OUTPUT O0=0` to one drive, acknowledged.
    pub async fn stop(&self, address: Address) -> Result<()> {
        self.done(Op::Stop(address), "a stop").await
    }

    /// Stops each of `drives` that still moves, whoever set it in motion, as
    /// [`Client::stop_if_moving`](super::Client::stop_if_moving).
    pub async fn stop_if_moving(&self, drives: &[Address]) -> Result<StopReport> {
        output(self.driver.run(Op::StopIfMoving(drives.to_vec())).await?, "a stop", |o| match o {
            Output::Stopped(r) => Ok(r),
            o => Err(o),
        })
    }

    /// One drive's stop, confirmed, and S1 and S16 read after it, as
    /// [`Client::stop_confirmed`](super::Client::stop_confirmed).
    pub async fn stop_confirmed(&self, address: Address) -> Result<DriveStop> {
        let report = self.stop_if_moving(&[address]).await?.confirmed()?;
        let position = self.read_position(address).await;
        Ok(DriveStop::new(report, position, self.read_s16(address).await.map(|s| s.o0_state())))
    }

    /// Stops every drive this client set in motion that still moves, confirmed by S17.
    pub async fn stop_started(&self) -> StopReport {
        match self.driver.run(Op::StopStarted).await {
            Ok(Output::Stopped(r)) => r,
            Ok(_) | Err(_) => StopReport::default(),
        }
    }

    /// Stops what this client set in motion that still moves, ends the session and returns the report;
    /// see [`Client::close`](super::Client::close). Runs on tokio's blocking pool.
    pub async fn close(self) -> Result<StopReport> {
        let AsyncClient { driver, close_report, .. } = self;
        driver.close().await?;
        let report = lock(&close_report).take().unwrap_or_default();
        Ok(report)
    }
}
