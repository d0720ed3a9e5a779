//! Parker COMPAX drives from Python: the native half of `motionlink.Compax`. Every operation is one call
//! of `motionlink_compax::Client`; what stops a drive and how a move is checked are the library's.

mod watch;
pub use watch::CompaxWatch;

use std::sync::Arc;
use std::time::Duration;

use motionlink_compax::client::open_line;
use motionlink_compax::client::{Config, MoveReport, MoveRequest, MoveTarget, TravelLimits};
use motionlink_compax::model::{
    BaudRate, ModelError, OutputNumber, OutputState, ParamId, PollInterval, Position, RampMs, ReplyTimeout,
    SpeedPercent, StatusId, TimeLimit, Tolerance, WatchInterval, WholeArg,
};
use motionlink_compax::report::{DrivePosition, ParamReading, StatusReading};
use motionlink_compax::session::{Op, Output};
use motionlink_compax::wire::{Address, Mode};
use motionlink_compax::{AsyncClient, Client, Error};
use motionlink_link::cancel::CancelToken;
use motionlink_link::link::Link;
use motionlink_link::url::PortUrl;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::common::{opt_float, Bool, Float, Int, Record, Slot, Text};
use crate::emulator::{clock, InProcess};
use crate::emulator::{target, Target};
use crate::errors::{to_pyerr, Failure, IntoFailure, OrRaise};
use crate::wait::{deliver, spawn_task, NativeTask};

const FAMILY: &str = "compax";

fn usage(msg: impl std::fmt::Display) -> Failure {
    Failure::usage(FAMILY, msg.to_string())
}

/// A value by the crate's rule, with the crate's message (the command line's and the console's).
fn checked<T>(r: Result<T, ModelError>) -> Result<T, Failure> {
    r.map_err(usage)
}

/// An int argument `name` by the rule of its type `T` in motionlink-compax: any int gets the crate's
/// message; a value that is no int (or wider than 64 bits) the binding's, with `T`'s span.
fn whole<T: WholeArg>(n: &Int, name: &str) -> Result<T, Failure> {
    let v = n.within::<i64>(FAMILY, name, i64::MIN..=i64::MAX).or_else(|_| n.within::<i64>(FAMILY, name, T::SPAN))?;
    checked(T::from_whole(v))
}

/// A library report as the dict of a record: `family`, then its fields as it serialises (the command line's
/// `--json` names).
fn record<'py, T: serde::Serialize>(py: Python<'py>, report: &T) -> PyResult<Record<'py>> {
    Record::of(py, FAMILY, report)
}

/// How a COMPAX client is opened, as `motionlink.Compax` passes it.
#[derive(FromPyObject)]
#[pyo3(from_item_all)]
pub struct Settings {
    drive: Int,
    mode: Int,
    baud: Int,
    timeout_ms: Int,
    poll_ms: Int,
    tolerance_units: Float,
    /// The device profiles: `"auto"` (default) profiles.toml beside devices.toml, `"off"`, or a path.
    #[pyo3(default)]
    profile: Option<String>,
}

/// The link `port` names and the session's settings, checked.
fn link(port: Target, s: &Settings) -> Result<(Box<dyn Link>, Config), Failure> {
    let mode: Mode = whole(&s.mode, "mode (P196)")?;
    let drive: Address = whole(&s.drive, "drive")?;
    let baud = whole::<BaudRate>(&s.baud, "baud")?.bits_per_s();
    let reply_timeout: ReplyTimeout = whole(&s.timeout_ms, "timeout_ms")?;
    let poll: PollInterval = whole(&s.poll_ms, "poll_ms")?;
    let tolerance = checked(Tolerance::new(s.tolerance_units.get(FAMILY, "tolerance_units")?))?;
    let mut cfg = Config::new(mode, baud);
    cfg.reply_timeout = reply_timeout.duration();
    cfg.poll_interval = poll.duration();
    cfg.in_position_tolerance = tolerance.position();
    let link: Box<dyn Link> = match port {
        Target::InProcess(InProcess::Compax(host)) => Box::new(host.connect().map_err(|e| Failure::of(FAMILY, &e))?),
        Target::InProcess(_) => return Err(usage("that emulator is not a COMPAX emulator")),
        Target::Url(PortUrl::Sim) => {
            let cfg = motionlink_compax::sim::SimConfig::bus(&[drive.get()], mode.to_p196(), baud);
            let bus = motionlink_compax::Emulator::new(cfg).map_err(usage)?;
            let host =
                motionlink_link::pipe::EmulatorHost::new(bus, clock(), motionlink_link::pipe::PipeConfig::instant());
            Box::new(host.connect().0)
        }
        Target::Url(p) => open_line(&p, &cfg).map_err(|e| e.failure())?,
    };
    Ok((link, cfg))
}

fn open(port: Target, s: &Settings) -> Result<Client, Failure> {
    let (link, cfg) = link(port, s)?;
    Client::with_link(link, clock(), cfg).map_err(|e| e.failure())
}

/// The time limit `timeout_s`, checked by the library.
fn seconds(timeout_s: &Float) -> Result<Duration, Failure> {
    checked(TimeLimit::from_secs(timeout_s.get(FAMILY, "timeout_s")?)).map(TimeLimit::duration)
}

/// A parameter read or written, as the CLI's `compax get` / `set --json` prints it (`title` is an extra
/// attribute).
fn param_record<'py, T: serde::Serialize>(
    py: Python<'py>,
    drive: Address,
    id: ParamId,
    report: &T,
) -> PyResult<Bound<'py, PyDict>> {
    let r = record(py, report)?;
    r.set("drive", drive.get())?.set("title", id.description().unwrap_or(""))?.extras(&["title"])?;
    Ok(r.done())
}

fn move_request(
    target: Option<&Float>,
    distance: Option<&Float>,
    speed_percent: Option<&Float>,
    ramp_ms: Option<&Int>,
    (min_units, max_units): (Option<&Float>, Option<&Float>),
    timeout_s: &Float,
) -> Result<MoveRequest, Failure> {
    let number = |v: Option<&Float>, name: &str| opt_float(v, FAMILY, name);
    let (target, distance) = (number(target, "target")?, number(distance, "distance")?);
    let speed_percent = number(speed_percent, "speed_percent")?;
    let (min_units, max_units) = (number(min_units, "min_units")?, number(max_units, "max_units")?);
    let target = match (target, distance) {
        (Some(t), None) => MoveTarget::Absolute(checked(Position::new(t))?),
        (None, Some(d)) => MoveTarget::Relative(checked(Position::new(d))?),
        _ => return Err(usage("give one of target= (absolute) and distance= (relative)")),
    };
    let speed = checked(speed_percent.map(SpeedPercent::new).transpose())?;
    let accel = ramp_ms.map(|r| whole::<RampMs>(r, "ramp_ms")).transpose()?;
    let limit = |v: Option<f64>| checked(v.map(Position::new).transpose());
    let limits = TravelLimits::new(limit(min_units)?, limit(max_units)?).map_err(usage)?;
    Ok(MoveRequest { target, speed, accel, binary: false, limits, timeout: Some(seconds(timeout_s)?) })
}

/// A move as the CLI's `compax move --json` prints it (`start_units` is an extra attribute).
fn move_record<'py>(py: Python<'py>, report: &MoveReport) -> PyResult<Record<'py>> {
    let rec = record(py, report)?;
    rec.set("start_units", report.start.units())?.extras(&["start_units"])?;
    Ok(rec)
}

/// The record of a report about `drive` that does not name it, as the CLI prints it (`family`, `drive`, then
/// the report's keys): a confirmed stop (`compax stop --json` but `action` and `holder`, the command line's
/// own), an output switched.
fn drive_record<'py, T: serde::Serialize>(py: Python<'py>, drive: Address, report: &T) -> PyResult<Record<'py>> {
    let rec = Record::new(py);
    rec.set("family", FAMILY)?.set("drive", drive.get())?;
    rec.0.update(record(py, report)?.0.as_mapping())?;
    Ok(rec)
}

/// Where a drive stands (S1): the result of `position`, `wait` and `home`.
fn position_record<'py>(py: Python<'py>, drive: Address, position: Position) -> PyResult<Record<'py>> {
    record(py, &DrivePosition { drive, position })
}

/// A session with COMPAX drives on one bus (the native half of `motionlink.Compax`).
#[pyclass(frozen, module = "motionlink._native")]
pub struct CompaxClient {
    slot: Slot<Client>,
    token: CancelToken,
    /// The tokens of the watches still running (closing the client ends them).
    watches: std::sync::Mutex<Vec<CancelToken>>,
    drive: Address,
    port: String,
    close_bound: Duration,
    /// The port as given (a URL), for profiles and probes; `None` for an emulator in this process.
    port_url: Option<String>,
    baud: u32,
    profile: crate::common::ProfileUse,
}

impl CompaxClient {
    fn drive(&self, py: Python<'_>, drive: Option<Int>) -> PyResult<Address> {
        drive.map_or(Ok(self.drive), |d| whole(&d, "drive")).map_err(|f| to_pyerr(py, f))
    }

    /// Ends the watches still running.
    fn end_watches(&self) {
        for t in motionlink_link::clock::lock(&self.watches).drain(..) {
            t.cancel();
        }
    }
}

/// An async session with COMPAX drives (the native half of `motionlink.AsyncCompax`): cancelling a move's,
/// a homing's or a wait's task drops its future, which stops the drive (OUTPUT O0=0, confirmed by S17).
#[pyclass(frozen, module = "motionlink._native")]
pub struct AsyncCompaxClient {
    slot: Slot<AsyncClient>,
    drive: Address,
    port: String,
    profile: crate::common::ProfileUse,
}

impl AsyncCompaxClient {
    fn drive(&self, py: Python<'_>, drive: Option<Int>) -> PyResult<Address> {
        drive.map_or(Ok(self.drive), |d| whole(&d, "drive")).map_err(|f| to_pyerr(py, f))
    }
}

impl crate::faces::Closing for CompaxClient {
    /// The watches still running end first.
    fn closing(&self) {
        self.end_watches();
    }
}

/// Drive addresses, as `started()` names them.
fn addresses(drives: Vec<Address>) -> Vec<u8> {
    drives.into_iter().map(Address::get).collect()
}

/// The drives of a stop, or the library's error naming those whose stop was not confirmed.
fn stopped(report: motionlink_compax::error::StopReport) -> Result<Vec<u8>, Failure> {
    let report = report.confirmed().map_err(|e| e.failure())?;
    Ok(addresses(report.drives.into_iter().map(|(a, _)| a).collect()))
}

impl crate::session::Session for Client {
    fn started_ids(&self) -> Vec<u8> {
        addresses(self.started())
    }

    fn end(self) -> Result<Vec<u8>, Failure> {
        self.close().map_err(|e| e.failure()).and_then(stopped)
    }

    /// The call under way was cancelled: the drives it set in motion are stopped here.
    fn end_shared(shared: Arc<Self>) -> Result<Vec<u8>, Failure> {
        stopped(shared.stop_started())
    }
}

impl crate::session::AsyncSession for AsyncClient {
    fn started_ids(&self) -> Vec<u8> {
        addresses(self.started())
    }

    async fn end(self) -> Result<Vec<u8>, Failure> {
        self.close().await.map_err(|e| e.failure()).and_then(stopped)
    }

    async fn end_shared(shared: Arc<Self>) -> Result<Vec<u8>, Failure> {
        stopped(shared.stop_started().await)
    }
}

faces! {
    CompaxClient / AsyncCompaxClient, Error;

    both {}

    blocking {
        #[new]
        fn py_new(py: Python<'_>, port: &Bound<'_, PyAny>, settings: Settings) -> PyResult<Self> {
            let t = target(port, FAMILY).map_err(|f| to_pyerr(py, f))?;
            let port_url = t.profile_port();
            let drive: Address = whole(&settings.drive, "drive").map_err(|f| to_pyerr(py, f))?;
            let baud: u32 = settings.baud.within(FAMILY, "baud", 1..=4_000_000).map_err(|f| to_pyerr(py, f))?;
            let (client, profile) = py
                .detach(|| {
                    let client = open(t, &settings)?;
                    let used = match crate::common::profile_lookup(settings.profile.as_deref(), port_url.as_deref()) {
                        Ok((p, port)) => {
                            motionlink_compax::probe::use_profile(&client, &p, &port, drive).map_err(|e| e.failure())?
                        }
                        Err(used) => used,
                    };
                    Ok::<_, Failure>((client, used))
                })
                .map_err(|f| to_pyerr(py, f))?;
            let port = client.port().to_string();
            let token = CancelToken::new();
            client.set_cancel(token.clone());
            let close_bound = client.config().close_bound;
            let watches = Default::default();
            let slot = Slot::new(client, FAMILY);
            Ok(CompaxClient { slot, token, watches, drive, port, close_bound, port_url, baud, profile })
        }

        /// `motionlink probe compax`'s report of the drives at `drives` (`"1-31"`, `"1,3"`), as a dict (nothing
        /// moves); with `save` (`""`: the default profiles file, else a path) the profile of each drive is
        /// written.
        fn probe<'py>(
            &self,
            py: Python<'py>,
            exchanges: Int,
            low_latency: Bool,
            save: Option<String>,
            drives: Text,
        ) -> PyResult<Bound<'py, PyAny>> {
            let client = self.slot.client(py)?;
            let drives = drives.get(FAMILY, "drives").map_err(|f| to_pyerr(py, f))?;
            let drives = motionlink_compax::probe::parse_drives(drives).map_err(|e| to_pyerr(py, usage(e)))?;
            let setup =
                crate::common::probe_setup(FAMILY, self.port_url.as_deref(), self.baud, &exchanges, &low_latency)
                    .map_err(|f| to_pyerr(py, f))?;
            let probe = || motionlink_compax::probe::probe(&client, &setup, &drives).map_err(|e| e.failure());
            crate::common::probe_py(py, FAMILY, self.port_url.as_deref(), save, probe, motionlink_compax::probe::save_profile)
        }

        /// Starts the library's watch of the drive (S1 and S17 every `interval_ms`, on a thread of its own):
        /// the samples come from [`CompaxWatch::next`].
        #[pyo3(signature = (drive, interval_ms))]
        fn watch_start(&self, py: Python<'_>, drive: Option<Int>, interval_ms: Int) -> PyResult<CompaxWatch> {
            let c = self.slot.client(py)?;
            let a = self.drive(py, drive)?;
            let interval: WatchInterval = whole(&interval_ms, "interval_ms").map_err(|f| to_pyerr(py, f))?;
            let w = CompaxWatch::start(c, a, interval.duration());
            motionlink_link::clock::lock(&self.watches).push(w.token());
            Ok(w)
        }
    }

    asynch {
        /// Opens a session on the runtime (the port on its blocking pool): `done(ok, client)`.
        #[staticmethod]
        fn open(py: Python<'_>, port: &Bound<'_, PyAny>, settings: Settings, done: Py<PyAny>) -> PyResult<NativeTask> {
            let t = target(port, FAMILY).map_err(|f| to_pyerr(py, f))?;
            let lookup =
                crate::common::profile_lookup(settings.profile.as_deref(), t.profile_port().as_deref());
            Ok(spawn_task(done, async move {
                let drive = whole(&settings.drive, "drive")?;
                let (link, cfg) = crate::wait::on_blocking_pool(FAMILY, move || link(t, &settings)).await?;
                let client = AsyncClient::with_link(link, clock(), cfg).await.map_err(|e| e.failure())?;
                let profile = match lookup {
                    Ok((p, port)) => motionlink_compax::probe::use_profile_async(&client, &p, &port, drive)
                        .await
                        .map_err(|e| e.failure())?,
                    Err(used) => used,
                };
                let port = client.port().to_string();
                let native = AsyncCompaxClient { slot: Slot::new(client, FAMILY), drive, port, profile };
                deliver(move |py| Ok(Py::new(py, native)?.into_any()))
            }))
        }
    }

    /// Every drive that answers (addresses 1..31) with its position S1. The library checks the cancel token
    /// before each address; Ctrl-C cancels it and raises at once (the address being asked ends within its
    /// reply timeout on the scan's thread).
    blocking scan scan(me, py) {} |c| { c.scan(1..=31) } => |py, found| {
        found.into_iter().map(|(a, p)| position_record(py, a, p)).collect::<PyResult<Vec<_>>>()
    };

    /// Status values (S1 .. S40) by name ("S1") or number; none: the main ones ([`StatusId::OVERVIEW`]), as
    /// the CLI's `status`.
    blocking scan status(me, py, names: Vec<String>, drive: Option<Int>) {
        let a = me.drive(py, drive)?;
        let ids = names.iter().map(|n| checked(n.parse::<StatusId>())).collect::<Result<Vec<_>, _>>();
        let ids = ids.map_err(|f| to_pyerr(py, f))?;
        let ids = if ids.is_empty() { StatusId::OVERVIEW.to_vec() } else { ids };
    } |c| { c.read_statuses(a, &ids) } => |py, values| {
        let entry = |(id, value): (StatusId, _)| {
            // As an entry of the CLI's `compax status --json` (`drive` and `id` are extra attributes).
            let r = record(py, &StatusReading { id, value })?;
            r.set("drive", a.get())?.set("id", id.get())?.extras(&["drive", "id"])?;
            Ok(r)
        };
        values.into_iter().map(entry).collect::<PyResult<Vec<_>>>()
    };

    /// Reads a parameter (P194, device_address).
    blocking read get(me, py, name: String, drive: Option<Int>) {
        let a = me.drive(py, drive)?;
        let id = checked(name.parse::<ParamId>()).map_err(|f| to_pyerr(py, f))?;
    } |c| { c.read_param(a, id) } => |py, value| param_record(py, a, id, &ParamReading { id, value });

    /// Writes a parameter and reads it back (a different value is a DeviceError). The library writes,
    /// compares what it reads back (a difference is an error) and reads once more: `read_back` is what the
    /// drive holds, not an echo of `value`.
    blocking quick set(me, py, name: String, value: Float, drive: Option<Int>) {
        let a = me.drive(py, drive)?;
        let value = value.get(FAMILY, "value").map_err(|f| to_pyerr(py, f))?;
        let id = checked(name.parse::<ParamId>().and_then(|id| id.check(value).map(|()| id)))
            .map_err(|f| to_pyerr(py, f))?;
    } |c| { c.set_param(a, id, value) } => |py, written| param_record(py, a, id, &written);

    /// Sets output `number` to `state` (OUTPUT Ox=y); O0 is read back from S16 (another state raises).
    blocking quick output(me, py, number: Int, state: Int, drive: Option<Int>) {
        let a = me.drive(py, drive)?;
        let output = |number, state| -> Result<_, Failure> {
            let number = whole::<OutputNumber>(number, "number (the output)")?;
            let state = whole::<OutputState>(state, "state (of the output)")?;
            Ok((number, checked(state.for_output(number))?))
        };
        let (number, state) = output(&number, &state).map_err(|f| to_pyerr(py, f))?;
    } |c| { c.switch_output(a, number.get(), state) } => |py, o| drive_record(py, a, &o);

    /// The actual position S1, in the drive's unit.
    quick position(me, py, drive: Option<Int>) {
        let a = me.drive(py, drive)?;
    } |c| { w!(c.read_position(a)) } => |py, p| Ok(p.units());

    /// A checked move (absolute `target` or relative `distance`), waited for; Ctrl-C, or cancelling the
    /// task, stops the drive.
    motion move_to(
        me, py, target: Option<Float>, distance: Option<Float>, drive: Option<Int>, speed_percent: Option<Float>,
        ramp_ms: Option<Int>, min_units: Option<Float>, max_units: Option<Float>, timeout_s: Float
    ) {
        let a = me.drive(py, drive)?;
        let request = move_request(
            target.as_ref(),
            distance.as_ref(),
            speed_percent.as_ref(),
            ramp_ms.as_ref(),
            (min_units.as_ref(), max_units.as_ref()),
            &timeout_s,
        )
        .map_err(|f| to_pyerr(py, f))?;
    } |c| {
        w!(c.move_to(a, &request, &mut |_| {});
            async c.start(Op::MoveTo(a, request)) => Output::Moved)
    } => |py, r| move_record(py, &r);

    /// POSA HOME, waited for and checked (S16 shows machine zero approached and the drive switched on);
    /// Ctrl-C, or cancelling the task, stops the drive.
    motion home(me, py, drive: Option<Int>, timeout_s: Float) {
        let a = me.drive(py, drive)?;
        let timeout = seconds(&timeout_s).map_err(|f| to_pyerr(py, f))?;
    } |c| {
        w!(c.home_and_wait(a, Some(timeout));
            async c.start(Op::Home(a, Some(timeout))) => Output::Homed)
    } => |py, p| position_record(py, a, p);

    /// Waits until the drive reports its positioning ended (S17); its position then. Ctrl-C stops the
    /// drive; so does cancelling the task (the wait's future stops nothing when dropped: the motion may be
    /// another call's, so the drive is stopped here as `stop` does: OUTPUT O0=0 if S17 shows it moving,
    /// confirmed by S17).
    motion wait(me, py, drive: Option<Int>, timeout_s: Float) {
        let a = me.drive(py, drive)?;
        let timeout = seconds(&timeout_s).map_err(|f| to_pyerr(py, f))?;
    } |c| {
        w!(c => wait_reached(&[a], Some(timeout)); &mut |_, _| {})?;
        w!(c.read_position(a))
    } else |stopping| { stopping.stop_confirmed(a).await } => |py, p| position_record(py, a, p);

    /// Stops the drive as `motionlink compax stop` does: OUTPUT O0=0 if S17 shows it moves (switching it
    /// off), confirmed by S17; then S1 and S16 read (where it stands, whether it is switched on).
    quick stop(me, py, drive: Option<Int>) {
        let a = me.drive(py, drive)?;
    } |c| { w!(c.stop_confirmed(a)) } => |py, s| drive_record(py, a, &s);
}

/// The in-position tolerance the library uses unless told otherwise.
pub fn default_tolerance() -> f64 {
    Tolerance::DEFAULT.position().units()
}
