//! [`Client`]: the blocking driver of a COMPAX session, and [`Drive`], a handle on one drive of it.

use std::ops::RangeInclusive;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use motionlink_link::cancel::CancelToken;
use motionlink_link::clock::{lock, SharedClock};
use motionlink_link::driver::{Driver, Port};
use motionlink_link::link::Link;
use motionlink_link::url::PortUrl;
use motionlink_link::LinkError;

use super::{driver_config, open_line, output, Drive};
use crate::error::{Error, Result, StopReport};
use crate::model::{
    Command, OutputState, ParamId, Position, RampMs, S16Bits, S17Bits, SpeedPercent, StatusId, StatusValue,
};
use crate::report::{DriveStop, OutputSwitched, ParamReading, ParamWritten};
use crate::session::core::Effect;
use crate::session::{
    AfterRaw, Config, MoveOptions, MoveReport, MoveRequest, Op, Output, Progress, RawOutcome, Session, StartedMove,
    WatchSample,
};
use crate::wire::{Address, Request};

/// A blocking client of one bus of COMPAX drives; see the [module documentation](super).
///
/// Its methods take `&self`: share it between threads (`&Client`, `Arc<Client>`); their telegrams take
/// turns on the line as the session schedules them.
///
/// ```
/// use motionlink_compax::client::{Config, MoveOptions};
/// use motionlink_compax::model::Position;
/// use motionlink_compax::sim::SimConfig;
/// use motionlink_compax::wire::{Address, Mode};
/// use motionlink_compax::{Client, Emulator};
/// use motionlink_link::{clock::{Clock, ManualClock}, pipe::{EmulatorHost, PipeConfig}};
///
/// let clock = ManualClock::new_auto();
/// let _me = clock.reserve_participant().enter();
/// let host = EmulatorHost::new(Emulator::new(SimConfig::bus(&[1, 5], 0, 9600)).unwrap(),
///                              clock.shared(), PipeConfig::paced(9600));
/// let (link, _faults) = host.connect();
/// let bus = Client::with_link(Box::new(link), clock.shared(), Config::new(Mode::default(), 9600)).unwrap();
/// let five = Address::drive(5).unwrap();
/// bus.move_absolute(five, Position::new(25.0).unwrap(), MoveOptions::default()).unwrap();
/// bus.wait_reached(&[five], None, &mut |_, _| {}).unwrap();
/// assert_eq!(bus.read_position(five).unwrap().units(), 25.0);
/// let report = bus.close().unwrap(); // nothing moves any more: nothing to stop
/// assert!(report.is_empty());
/// ```
pub struct Client {
    driver: Driver<Session>,
    config: Config,
    cancel: Mutex<CancelToken>,
    close_report: Arc<Mutex<Option<StopReport>>>,
}

impl std::fmt::Debug for Client {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Client").field("port", &self.driver.port_name()).field("config", &self.config).finish()
    }
}

impl Client {
    /// Opens the serial line or TCP port `url` names (not `sim`) at the configuration's baud rate, with the
    /// parity of its mode, and starts a session on it.
    pub fn open(url: &PortUrl, clock: SharedClock, cfg: Config) -> Result<Self> {
        let link = open_line(url, &cfg)?;
        Client::with_link(link, clock, cfg)
    }

    /// A client on `link`, already open, timed by `clock`. Starts the driver's thread (which runs the
    /// session's operations for async callers and otherwise sleeps: COMPAX has no keepalive).
    pub fn with_link(link: Box<dyn Link>, clock: SharedClock, cfg: Config) -> Result<Self> {
        let session = Session::new(cfg.clone(), clock.now());
        let close_report = session.close_report();
        let port = Port::Bytes(link);
        let name = port.describe();
        let driver = Driver::new(session, port, None, clock, driver_config(&cfg))
            .map_err(|source| Error::Link(LinkError::Io { port: name, source: std::sync::Arc::new(source) }))?;
        Ok(Client { driver, config: cfg, cancel: Mutex::new(CancelToken::new()), close_report })
    }

    /// Long actions watch `token`: a wait or checked move stops its axes when it is cancelled, a scan ends,
    /// and no move is sent once it is cancelled (until the token is reset). All of them return
    /// [`Error::CancelledBeforeMotion`], or [`Error::Cancelled`] with its stop report when axes were
    /// stopped. Reads, settings and stops still work.
    pub fn set_cancel(&self, token: CancelToken) {
        *lock(&self.cancel) = token;
    }

    /// True once the cancel token is cancelled.
    pub fn is_cancelled(&self) -> bool {
        lock(&self.cancel).is_cancelled()
    }

    fn token(&self) -> CancelToken {
        lock(&self.cancel).clone()
    }

    fn check_cancel(&self) -> Result<()> {
        if self.is_cancelled() {
            Err(Error::CancelledBeforeMotion)
        } else {
            Ok(())
        }
    }

    /// A handle on drive `address` (1..=31); the broadcast address 32 is refused ([`Error::Broadcast`]).
    pub fn drive(&self, address: Address) -> Result<Drive<'_>> {
        if address.is_broadcast() {
            return Err(Error::Broadcast("a drive handle is one drive (1..=31)"));
        }
        Ok(Drive { client: self, address })
    }

    /// The configuration.
    pub fn config(&self) -> &Config {
        &self.config
    }

    /// The driver underneath (to run any [`Op`] with [`Driver::run_with`], or look at the session).
    pub fn driver(&self) -> &Driver<Session> {
        &self.driver
    }

    /// The port, for messages.
    pub fn port(&self) -> &str {
        self.driver.port_name()
    }

    /// The drives this client set in motion and has not yet seen stop.
    pub fn started(&self) -> Vec<Address> {
        self.driver.with_session(|s| s.started())
    }

    /// The drives that have answered this client.
    pub fn known(&self) -> Vec<Address> {
        self.driver.with_session(|s| s.known())
    }

    /// Hands the motion of `drives` over to the caller: the client forgets that it set them in motion, so
    /// neither closing it nor a cancelled wait stops them. The broadcast address releases every drive.
    pub fn release(&self, drives: &[Address]) {
        self.driver.with_session(|s| s.release(drives));
    }

    /// Runs `op` to its end.
    pub fn run(&self, op: Op) -> Result<Output> {
        self.driver.run(op)
    }

    /// Runs `op`, watching the cancel token and handing its progress to `progress`.
    fn run_cancellable(&self, op: Op, progress: &mut dyn FnMut(&Progress)) -> Result<Output> {
        let token = self.token();
        self.driver.run_with(op, progress, Some(&token))
    }

    fn done(&self, op: Op, what: &str) -> Result<()> {
        output(self.run(op)?, what, |o| if o == Output::Done { Ok(()) } else { Err(o) })
    }

    // --------------------------------------------------------------------------------------------------
    // Reading

    /// Reads status value `id`. Address 32 is refused with [`Error::Broadcast`]. A reply that does not read
    /// as that value is asked for again, up to [`Config::retries`] times: a read changes nothing.
    pub fn read_status(&self, address: Address, id: StatusId) -> Result<StatusValue> {
        output(self.run(Op::ReadStatus(address, id))?, "a status read", |o| match o {
            Output::Status(v) => Ok(v),
            o => Err(o),
        })
    }

    /// Reads several status values of one drive, in order; a cancel of the token ends it between two.
    pub fn read_statuses(&self, address: Address, ids: &[StatusId]) -> Result<Vec<(StatusId, StatusValue)>> {
        let op = Op::ReadStatuses(address, ids.to_vec());
        output(self.run_cancellable(op, &mut |_| {})?, "status reads", |o| match o {
            Output::Statuses(v) => Ok(v),
            o => Err(o),
        })
    }

    fn position_value(&self, address: Address, id: StatusId) -> Result<Position> {
        match self.read_status(address, id)? {
            StatusValue::Position(p) => Ok(p),
            other => Err(Error::UnexpectedReply { address, command: id.to_string(), reply: other.to_string() }),
        }
    }

    /// Reads the actual position S1.
    pub fn read_position(&self, address: Address) -> Result<Position> {
        self.position_value(address, StatusId::ACTUAL_POSITION)
    }

    /// Reads the target position S2.
    pub fn read_target(&self, address: Address) -> Result<Position> {
        self.position_value(address, StatusId::TARGET_POSITION)
    }

    /// Reads the status bits S16.
    pub fn read_s16(&self, address: Address) -> Result<S16Bits> {
        match self.read_status(address, StatusId::STATUS_BITS_1)? {
            StatusValue::S16(b) => Ok(b),
            other => Err(Error::UnexpectedReply { address, command: "S16".into(), reply: other.to_string() }),
        }
    }

    /// Reads the status bits S17.
    pub fn read_s17(&self, address: Address) -> Result<S17Bits> {
        match self.read_status(address, StatusId::STATUS_BITS_2)? {
            StatusValue::S17(b) => Ok(b),
            other => Err(Error::UnexpectedReply { address, command: "S17".into(), reply: other.to_string() }),
        }
    }

    /// Reads parameter `id`. Address 32 is refused with [`Error::Broadcast`].
    pub fn read_param(&self, address: Address, id: ParamId) -> Result<f64> {
        output(self.run(Op::ReadParam(address, id))?, "a parameter read", |o| match o {
            Output::Number(v) => Ok(v),
            o => Err(o),
        })
    }

    /// Writes parameter `id` (checked against its known range first) and reads it back: a value that reads
    /// back otherwise is [`Error::ReadBack`]. P194..P196 take effect at power-on (they read back at once).
    /// To address 32 (every drive) the value is written and cannot be read back (nobody answers).
    pub fn write_param(&self, address: Address, id: ParamId, value: f64) -> Result<()> {
        self.done(Op::WriteParam(address, id, value), "a parameter write")
    }

    /// Writes parameter `id` as [`Client::write_param`] does (a value that reads back otherwise is
    /// [`Error::ReadBack`]), then reads it once more: the report's `read_back` is what the drive holds now.
    pub fn set_param(&self, address: Address, id: ParamId, value: f64) -> Result<ParamWritten> {
        self.write_param(address, id, value)?;
        let read_back = self.read_param(address, id)?;
        Ok(ParamWritten { written: ParamReading { id, value }, read_back })
    }

    /// Tries every address in `range` once with a short timeout; returns the drives that answered S1 with
    /// their positions. Ends with [`Error::CancelledBeforeMotion`] when the cancel token is cancelled (checked before
    /// each address).
    pub fn scan(&self, range: RangeInclusive<u8>) -> Result<Vec<(Address, Position)>> {
        self.scan_with(range, &mut |_| {})
    }

    /// [`Client::scan`], each address announced to `progress` before it is asked ([`Progress::Scan`]): a
    /// scan waits a reply timeout and as long again at each address without a drive.
    pub fn scan_with(
        &self,
        range: RangeInclusive<u8>,
        progress: &mut dyn FnMut(&Progress),
    ) -> Result<Vec<(Address, Position)>> {
        self.check_cancel()?;
        output(self.run_cancellable(Op::Scan(range), progress)?, "a scan", |o| match o {
            Output::Found(v) => Ok(v),
            o => Err(o),
        })
    }

    // --------------------------------------------------------------------------------------------------
    // Commands, settings, outputs

    /// Sends `cmd` to one drive (or, with address 32, to all: then only commands without an answer) and
    /// returns the reply text (empty for an acknowledgement). Moves have their own methods.
    pub fn command(&self, address: Address, cmd: &Command) -> Result<String> {
        output(self.run(Op::Command(address, *cmd))?, "a command", |o| match o {
            Output::Text(t) => Ok(t),
            o => Err(o),
        })
    }

    /// Sends `text` as it is (`S1`, `POSA 10$`, `!`, `OUTPUT O9=1/`); flag characters at its end are sent
    /// as flags. Sent again only after E70, E72 or E73 (the drive discarded it); never after a lost reply.
    /// Returns the reply text, or `None` when no reply is due (a broadcast, `/`).
    ///
    /// A move or `!` counts as started (for address 32: every drive that has answered this client), so
    /// closing the client or a cancelled wait stops it; `OUTPUT O0=0` counts as a stop. No move is sent
    /// once the cancel token is cancelled.
    pub fn raw(&self, address: Address, text: &str) -> Result<Option<String>> {
        if self.raw_starts(text) {
            self.check_cancel()?;
        }
        output(self.run_cancellable(Op::Raw(address, text.to_string()), &mut |_| {})?, "a raw command", |o| match o {
            Output::Reply(r) => Ok(r),
            o => Err(o),
        })
    }

    /// Sends `text` as [`Client::raw`] does, then hands what it set in motion over (it runs on after the
    /// call) or waits for it to end: what `motionlink compax raw` runs. Cancelled while it is sent, what
    /// it started is stopped instead ([`Error::Cancelled`]).
    pub fn raw_motion(&self, address: Address, text: &str, after: AfterRaw) -> Result<RawOutcome> {
        if self.raw_starts(text) {
            self.check_cancel()?;
        }
        let op = Op::RawMotion(address, text.to_string(), after);
        output(self.run_cancellable(op, &mut |_| {})?, "a raw command", |o| match o {
            Output::Raw(r) => Ok(r),
            o => Err(o),
        })
    }

    fn raw_starts(&self, text: &str) -> bool {
        raw_may_start_motion(text)
    }

    /// Sends `text` with `?`: the drive sends it back. Returns the echo.
    pub fn echo(&self, address: Address, text: &str) -> Result<String> {
        output(self.run(Op::Echo(address, text.to_string()))?, "an echo", |o| match o {
            Output::Text(t) => Ok(t),
            o => Err(o),
        })
    }

    /// SPEED for the next positionings.
    pub fn set_speed(&self, address: Address, speed: SpeedPercent, binary: bool) -> Result<()> {
        self.done(Op::Setting(address, Command::Speed(speed), binary), "a setting")
    }

    /// ACCEL (acceleration and braking time) for the next positionings.
    pub fn set_accel(&self, address: Address, ramp: RampMs, binary: bool) -> Result<()> {
        self.done(Op::Setting(address, Command::Accel(ramp), binary), "a setting")
    }

    /// ACCEL- (braking time alone) for the next positionings.
    pub fn set_brake(&self, address: Address, ramp: RampMs, binary: bool) -> Result<()> {
        self.done(Op::Setting(address, Command::AccelBrake(ramp), binary), "a setting")
    }

    /// OUTPUT O`output`=`state`. Output 0 is the drive itself: 0 switches it off, 1 on. To address 32, every
    /// drive's output (and `O0=0` switches every drive off: the client forgets every axis it moved).
    pub fn set_output(&self, address: Address, output: u16, state: OutputState, binary: bool) -> Result<()> {
        self.done(Op::Setting(address, Command::Output { output, state }, binary), "a setting")
    }

    /// OUTPUT O`output`=`state` to one drive (as [`Client::set_output`](crate::Client::set_output)), then
    /// read back where the drive shows it: O0 (the drive switched on or off) in S16, an error
    /// ([`Error::OutputNotTaken`]) if it shows another state. No other output can be read: the report
    /// says so (`verified` false), as it does when S16 could not be read or the switch went to every drive.
    pub fn switch_output(&self, address: Address, output: u16, state: OutputState) -> Result<OutputSwitched> {
        self.set_output(address, output, state, false)?;
        let read = match OutputSwitched::shown_in_s16(address, output) {
            true => Some(self.read_s16(address).map(|s| s.o0_state())),
            false => None,
        };
        OutputSwitched::checked(address, output, state, read)
    }

    // --------------------------------------------------------------------------------------------------
    // Moves

    fn start_move(&self, address: Address, cmd: Command, opts: MoveOptions) -> Result<()> {
        if !address.is_broadcast() {
            self.check_cancel()?;
        }
        let op = Op::Move(address, cmd, opts);
        output(self.run_cancellable(op, &mut |_| {})?, "a move", |o| if o == Output::Done { Ok(()) } else { Err(o) })
    }

    /// POSA: moves to `target`. Returns once the drive has taken the command; see [`Client::wait_reached`].
    /// Moves go to one drive (address 32 is refused with [`Error::Broadcast`]: see [`Client::broadcast`]
    /// and [`Client::sync_start`]) and are not sent once the cancel token is cancelled.
    pub fn move_absolute(&self, address: Address, target: Position, opts: MoveOptions) -> Result<()> {
        self.start_move(address, Command::PosA(target), opts)
    }

    /// POSR: moves by `distance`. If the reply is lost the session reads the target position S2: unchanged,
    /// the drive did not take the move and it is sent again; moved by `distance`, it did; anything else is
    /// [`Error::MoveUncertain`]. Never sent again blind.
    pub fn move_relative(&self, address: Address, distance: Position, opts: MoveOptions) -> Result<()> {
        self.start_move(address, Command::PosR(distance), opts)
    }

    /// POSA HOME: finds machine zero; returns once the drive has taken it (see [`Client::home_and_wait`]).
    pub fn home(&self, address: Address, opts: MoveOptions) -> Result<()> {
        self.start_move(address, Command::PosAHome, opts)
    }

    /// POSA HOME, waited for (as [`Client::wait_reached`]: without `timeout`, at most
    /// [`Config::wait_timeout`]), then checked: S16 must show machine zero approached (bit 3), else
    /// [`Error::NotHomed`] (a homing stopped halfway, by another program's stop say, ends at rest too).
    /// Returns where the drive rests (S1). A cancel stops the drive.
    pub fn home_and_wait(&self, address: Address, timeout: Option<Duration>) -> Result<Position> {
        output(self.run_cancellable(Op::Home(address, timeout), &mut |_| {})?, "a homing", |o| match o {
            Output::Homed(p) => Ok(p),
            o => Err(o),
        })
    }

    /// Starts several drives at the same instant: each move is stored in its drive's buffer (`,`), then one
    /// broadcast `32!` executes them all. Every drive on the bus runs what its buffer holds.
    ///
    /// Hazard: if storing the move fails for one drive, no `!` is sent, but the drives before it keep their
    /// buffered move, and the manual has no command that empties a buffer. The call then returns
    /// [`Error::SyncIncomplete`], which names those drives: the next `!` to one of them, or any `32!` on the
    /// bus, starts its move. If this client sends that `!`, it counts those drives as started. While a drive
    /// outside `moves` may still hold a move this session stored and never executed (after
    /// [`Error::SyncIncomplete`] or [`Error::NotExecuted`]), the `32!` would run it too: the call is refused
    /// before anything is sent, with [`Error::BufferHeld`] naming those drives.
    pub fn sync_start(&self, moves: &[(Address, Command)], message: bool) -> Result<()> {
        self.check_cancel()?;
        let op = Op::SyncStart(moves.to_vec(), message);
        output(self.run_cancellable(op, &mut |_| {})?, "a synchronous start", |o| {
            if o == Output::Done {
                Ok(())
            } else {
                Err(o)
            }
        })
    }

    /// Sends `cmd` to every drive at once (no reply). A move counts as started for every drive that has
    /// answered this client; `OUTPUT O0=0` ends every record of a started axis.
    pub fn broadcast(&self, cmd: &Command) -> Result<()> {
        if cmd.is_move() {
            self.check_cancel()?;
        }
        let op = Op::Broadcast(*cmd);
        output(
            self.run_cancellable(op, &mut |_| {})?,
            "a broadcast",
            |o| if o == Output::Done { Ok(()) } else { Err(o) },
        )
    }

    /// Waits until every drive in `drives` has ended its positioning: by its `$` message when the move asked
    /// for one, otherwise by polling S17 every [`Config::poll_interval`]; `progress` gets each polled
    /// position. While it listens for `$` messages it still reads each drive's S17 every
    /// [`Config::message_check_interval`]. Without a `timeout` it waits at most
    /// [`Config::wait_timeout`]. On timeout, cancellation or a line failure, the drives it waits for
    /// that this client started are stopped and the error is [`Error::FailedDuringMotion`] (a cancel:
    /// [`Error::Cancelled`]). Address 32 is refused.
    pub fn wait_reached(
        &self,
        drives: &[Address],
        timeout: Option<Duration>,
        progress: &mut dyn FnMut(Address, Position),
    ) -> Result<()> {
        let op = Op::Wait(drives.to_vec(), timeout);
        let mut report = |p: &Progress| {
            if let Progress::Position { drive, position } = p {
                progress(*drive, *position);
            }
        };
        output(self.run_cancellable(op, &mut report)?, "a wait", |o| if o == Output::Done { Ok(()) } else { Err(o) })
    }

    /// Waits `d`, handling what arrives meanwhile (`$` and comparator messages), and ends early with
    /// [`Error::CancelledBeforeMotion`] once the cancel token is cancelled.
    pub fn pause(&self, d: Duration) -> Result<()> {
        self.check_cancel()?;
        output(self.run_cancellable(Op::Pause(d), &mut |_| {})?, "a pause", |o| {
            if o == Output::Done {
                Ok(())
            } else {
                Err(o)
            }
        })
    }

    /// Reads S1 and S17 of `drive` every `interval` and hands each reading to `sample`, until the cancel
    /// token is cancelled (then it returns `Ok`).
    pub fn watch(&self, drive: Address, interval: Duration, sample: &mut dyn FnMut(&WatchSample)) -> Result<()> {
        let mut report = |p: &Progress| {
            if let Progress::Watch(s) = p {
                sample(s);
            }
        };
        output(self.run_cancellable(Op::Watch(drive, interval), &mut report)?, "a watch", |o| {
            if o == Output::Done {
                Ok(())
            } else {
                Err(o)
            }
        })
    }

    // --------------------------------------------------------------------------------------------------
    // Stops

    /// Stops one drive: `OUTPUT O0=0` (switch off drive), acknowledged. Switch it on again with
    /// `set_output(address, 0, OutputState::ON, false)`. Address 32 switches every drive on the bus off.
    /// [`Client::stop_started`] also confirms the stop by reading S17.
    pub fn stop(&self, address: Address) -> Result<()> {
        self.done(Op::Stop(address), "a stop")
    }

    /// Stops every drive this client set in motion and has not seen stop, if it still moves, and reports
    /// per drive how that ended: S17 first (one attempt); a drive at rest is left switched on; one that
    /// still moves, or whose S17 cannot be read, gets `OUTPUT O0=0`, confirmed by S17 afterwards (sent once
    /// more if S17 still shows the positioning). A drive that does not confirm stays on the list.
    pub fn stop_started(&self) -> StopReport {
        match self.run(Op::StopStarted) {
            Ok(Output::Stopped(r)) => r,
            Ok(_) | Err(_) => StopReport::default(),
        }
    }

    /// Stops each of `drives` that still moves, whoever set it in motion (another program, a move handed
    /// over), and reports per drive how that ended: S17 first (one attempt); a drive at rest is left
    /// switched on ([`StopOutcome::AtRest`](crate::error::StopOutcome)); one that moves, or whose S17
    /// cannot be read, gets `OUTPUT O0=0` (the only stop of the command set: it switches the drive off),
    /// confirmed by S17 afterwards. What `motionlink compax stop` does.
    pub fn stop_if_moving(&self, drives: &[Address]) -> Result<StopReport> {
        output(self.run(Op::StopIfMoving(drives.to_vec()))?, "a stop", |o| match o {
            Output::Stopped(r) => Ok(r),
            o => Err(o),
        })
    }

    /// `motionlink compax stop` of one drive: [`Client::stop_if_moving`] (`OUTPUT O0=0` if S17 shows it
    /// moves or cannot be read), an error unless the stop is confirmed by S17; then S1 and S16 are read, so
    /// that the report says where the axis stands and whether the drive is still switched on (what could
    /// not be read is said in the report).
    pub fn stop_confirmed(&self, address: Address) -> Result<DriveStop> {
        let report = self.stop_if_moving(&[address])?.confirmed()?;
        let position = self.read_position(address);
        Ok(DriveStop::new(report, position, self.read_s16(address).map(|s| s.o0_state())))
    }

    /// Stops what this client set in motion that still moves (as [`Client::stop_started`]), ends the
    /// session and returns the report: `Err` if a drive did not confirm its stop
    /// ([`Error::CloseUnconfirmed`]), or if the stop did not end within [`Config::close_bound`].
    pub fn close(self) -> Result<StopReport> {
        let Client { driver, close_report, .. } = self;
        driver.close()?;
        let report = lock(&close_report).take().unwrap_or_default();
        Ok(report)
    }

    // --------------------------------------------------------------------------------------------------
    // Checked moves

    /// Moves one drive and makes sure it got there: [`Client::start_checked_move`], then
    /// [`Client::finish_checked_move`]. `progress` gets each polled position. Returns where the axis came
    /// to rest, within [`Config::in_position_tolerance`] of the target; any other outcome is an error,
    /// and an error (or a cancel) while the axis may move has stopped it ([`Error::FailedDuringMotion`],
    /// [`Error::Cancelled`]).
    pub fn move_to(
        &self,
        address: Address,
        request: &MoveRequest,
        progress: &mut dyn FnMut(Position),
    ) -> Result<MoveReport> {
        self.check_cancel()?;
        let mut report = |p: &Progress| {
            if let Progress::Position { position, .. } = p {
                progress(*position);
            }
        };
        output(self.run_cancellable(Op::MoveTo(address, *request), &mut report)?, "a checked move", |o| match o {
            Output::Moved(r) => Ok(r),
            o => Err(o),
        })
    }

    /// Starts a move and confirms the drive took the right target: an absolute target outside
    /// `request.limits` is refused ([`Error::OutsideLimits`]) before anything is sent; a drive switched off
    /// (S16) is refused ([`Error::SwitchedOff`]) before anything moves; S1 (the start), and for a relative
    /// move S2, then the limits for the target that makes; SPEED and ACCEL if given, then the move, checked
    /// before it starts: stored in the drive's buffer with its echo (`POSA 12.5,?`) and executed (`!`) only
    /// when the echo is the telegram sent byte for byte (otherwise [`Error::NotExecuted`], naming the echo
    /// and the drives that may hold the command in their buffer; a binary move, which takes no flags, is
    /// sent as it is); S2 read back right after the start: a target off by more than the tolerance twice
    /// switches the axis off ([`Error::TargetMismatch`] inside [`Error::FailedDuringMotion`]). Once the move may have
    /// been sent, any error or a cancel stops the axis if it moves.
    pub fn start_checked_move(&self, address: Address, request: &MoveRequest) -> Result<StartedMove> {
        self.start_checked(address, request, false)
    }

    /// [`Client::start_checked_move`], then the move is handed over (the client forgets it and does not
    /// stop it): what `motionlink compax move --no-wait` runs. Cancelled before the target was read back,
    /// the move is stopped instead.
    pub fn start_and_release(&self, address: Address, request: &MoveRequest) -> Result<StartedMove> {
        self.start_checked(address, request, true)
    }

    fn start_checked(&self, address: Address, request: &MoveRequest, hand_over: bool) -> Result<StartedMove> {
        self.check_cancel()?;
        let op = Op::StartMove(address, *request, hand_over);
        output(self.run_cancellable(op, &mut |_| {})?, "a checked move", |o| match o {
            Output::Started(s) => Ok(s),
            o => Err(o),
        })
    }

    /// Waits for a move [`Client::start_checked_move`] started and checks where the axis came to rest: S1
    /// must lie within [`Config::in_position_tolerance`] of the target, or the error is
    /// [`Error::NotReached`] naming target, reached position and difference. Errors during the wait stop the
    /// axis.
    pub fn finish_checked_move(
        &self,
        started: &StartedMove,
        timeout: Option<Duration>,
        progress: &mut dyn FnMut(Position),
    ) -> Result<MoveReport> {
        let mut report = |p: &Progress| {
            if let Progress::Position { position, .. } = p {
                progress(*position);
            }
        };
        output(self.run_cancellable(Op::FinishMove(started.clone(), timeout), &mut report)?, "a checked move", |o| {
            match o {
                Output::Moved(r) => Ok(r),
                o => Err(o),
            }
        })
    }
}

/// True when `text`, sent as [`Client::raw`] sends it, may set an axis in motion: a move (sent alone or with
/// `?`, which a drive may carry out as well as echo) or `!`, which runs whatever the buffer holds; a command
/// stored with `,` does not (its `!` will).
///
/// ```
/// use motionlink_compax::client::raw_may_start_motion;
/// assert!(raw_may_start_motion("POSA 10") && raw_may_start_motion("!") && raw_may_start_motion("POSR 5?"));
/// assert!(!raw_may_start_motion("POSA 10,") && !raw_may_start_motion("S1"));
/// ```
pub fn raw_may_start_motion(text: &str) -> bool {
    let Request { body, flags, .. } = Request::raw(Address::BROADCAST, text);
    Effect::of_request(&body, flags) == Effect::Starts
}
