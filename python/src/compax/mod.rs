//! Parker COMPAX drives from Python: the native half of `motionlink.Compax`. Every operation is one call
//! of `motionlink_compax::Client`; what stops a drive and how a move is checked are the library's.

mod asyncio;
mod watch;
pub use asyncio::AsyncCompaxClient;
pub use watch::CompaxWatch;

use std::sync::Arc;
use std::time::Duration;

use motionlink_compax::client::{
    BusConfig, MoveOptions, MoveReport, MoveRequest, MoveTarget, TravelLimits, DEFAULT_IN_POSITION_TOLERANCE,
};
use motionlink_compax::model::{
    Command, OutputState, ParamId, Position, RampMs, S16Bits, S17Bits, SpeedPercent, StatusId, StatusValue, BAUD_RATES,
};
use motionlink_compax::session::{Op, Output};
use motionlink_compax::wire::{Address, Mode};
use motionlink_compax::{AsyncClient, Client, Error};
use motionlink_link::cancel::CancelToken;
use motionlink_link::link::{Link, SerialSettings};
use motionlink_link::url::PortUrl;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::common::{json_py, opt_within, target, Int, Record, Slot, Target};
use crate::emulator::{clock, InProcess};
use crate::errors::{to_pyerr, Failure, IntoFailure, OrRaise};
use crate::wait::{block_on_runtime, deliver, interruptible, interruptible_read, spawn_task, NativeTask};

const FAMILY: &str = "compax";

fn usage(msg: impl Into<String>) -> Failure {
    Failure::usage(FAMILY, msg)
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
    tolerance_units: f64,
    /// The device profiles: `"auto"` (default) profiles.toml beside devices.toml, `"off"`, or a path.
    #[pyo3(default)]
    profile: Option<String>,
}

/// The link `port` names and the session's settings, checked.
fn link(port: Target, s: &Settings) -> Result<(Box<dyn Link>, BusConfig), Failure> {
    let p196: u32 = s.mode.within(FAMILY, "mode (P196)", 0..=i64::from(u32::MAX))?;
    let mode = Mode::from_p196(p196).map_err(|e| usage(format!("mode (P196) {p196}: {e}")))?;
    let drive = drive_number(&s.drive)?;
    let baud: u32 = s.baud.within(FAMILY, "baud", 1..=4_000_000)?;
    if !BAUD_RATES.contains(&baud) {
        return Err(usage(format!("baud {baud}: not a rate P195 accepts ({BAUD_RATES:?})")));
    }
    let timeout_ms: u64 = s.timeout_ms.within(FAMILY, "timeout_ms", 1..=60_000)?;
    let poll_ms: u64 = s.poll_ms.within(FAMILY, "poll_ms", 1..=10_000)?;
    if !(s.tolerance_units.is_finite() && s.tolerance_units > 0.0 && s.tolerance_units <= 1e6) {
        return Err(usage(format!("tolerance_units {}: give a distance above 0 (at most 1000000)", s.tolerance_units)));
    }
    let link: Box<dyn Link> = match port {
        Target::InProcess(InProcess::Compax(host)) => Box::new(host.connect().0),
        Target::InProcess(_) => return Err(usage("that emulator is not a COMPAX emulator")),
        Target::Url(PortUrl::Sim) => {
            let cfg = motionlink_compax::sim::SimConfig::bus(&[drive], p196, baud);
            let bus = motionlink_compax::Emulator::new(cfg).map_err(|e| usage(e.to_string()))?;
            let host =
                motionlink_link::pipe::EmulatorHost::new(bus, clock(), motionlink_link::pipe::PipeConfig::instant());
            Box::new(host.connect().0)
        }
        Target::Url(p) if p.is_can() => return Err(usage(format!("{p}: COMPAX drives speak RS485/RS232, not CAN"))),
        Target::Url(p) => {
            let mut settings = SerialSettings::new(baud);
            settings.parity = mode.parity;
            p.open_byte_link(settings).map_err(|e| e.failure())?
        }
    };
    let mut cfg = BusConfig::new(mode, baud);
    cfg.reply_timeout = Duration::from_millis(timeout_ms);
    cfg.poll_interval = Duration::from_millis(poll_ms);
    cfg.in_position_tolerance = Position::new(s.tolerance_units).map_err(|e| usage(format!("tolerance_units: {e}")))?;
    Ok((link, cfg))
}

fn open(port: Target, s: &Settings) -> Result<Client, Failure> {
    let (link, cfg) = link(port, s)?;
    Client::new(link, clock(), cfg).map_err(|e| e.failure())
}

/// A drive address (1..31) as an argument gives it.
fn drive_number(n: &Int) -> Result<u8, Failure> {
    n.within(FAMILY, "drive", 1..=31)
}

fn address(n: u8) -> Result<Address, Failure> {
    Address::drive(n).map_err(|e| usage(format!("drive {n}: {e}")))
}

fn seconds(name: &str, s: f64) -> Result<Duration, Failure> {
    Duration::try_from_secs_f64(s)
        .ok()
        .filter(|t| !t.is_zero())
        .ok_or_else(|| usage(format!("{name} {s}: give a number of seconds above 0")))
}

/// A parameter as the CLI's `compax get --json` prints it (`title` is an extra attribute).
fn param_record<'py>(py: Python<'py>, drive: u8, id: ParamId) -> PyResult<Record<'py>> {
    let r = Record::new(py);
    r.set("family", FAMILY)?.set("drive", drive)?.set("name", id.to_string())?.set("id", id.get())?;
    r.set("unit", id.info().map_or("", |i| i.unit))?.set("access", id.info().map_or("rw", |i| i.access.short()))?;
    r.set("title", id.description().unwrap_or(""))?.extras(&["title"])?;
    Ok(r)
}

/// S16 / S17 as a flag word: `word`, `flags`, `unknown_bits` (when nonzero) and the drive's own bit
/// string `pattern` ("1101 0010").
pub(crate) fn s16_py<'py>(py: Python<'py>, b: S16Bits) -> PyResult<Bound<'py, PyDict>> {
    let r = Record::new(py);
    r.flag_word(b)?.set("pattern", b.pattern().to_string())?;
    Ok(r.done())
}

/// S17 as [`s16_py`] gives S16.
pub(crate) fn s17_py<'py>(py: Python<'py>, b: S17Bits) -> PyResult<Bound<'py, PyDict>> {
    let r = Record::new(py);
    r.flag_word(b)?.set("pattern", b.pattern().to_string())?;
    Ok(r.done())
}

/// A status value as an entry of the CLI's `compax status --json`: `status` ("S1"), `name` (the title),
/// `unit`, `value` (`drive` and `id` are extra attributes).
fn status_record<'py>(py: Python<'py>, drive: u8, id: StatusId, v: &StatusValue) -> PyResult<Record<'py>> {
    let info = id.info();
    let r = Record::new(py);
    r.set("family", FAMILY)?.set("drive", drive)?.set("status", id.to_string())?.set("id", id.get())?;
    r.set("name", info.map_or("(meaning not documented)", |i| i.title))?.set("unit", info.map_or("", |i| i.unit))?;
    match v {
        StatusValue::S16(b) => r.set("value", s16_py(py, *b)?)?,
        StatusValue::S17(b) => r.set("value", s17_py(py, *b)?)?,
        StatusValue::Position(p) => r.set("value", p.units())?,
        StatusValue::Number(n) => r.set("value", *n)?,
        other => r.set("value", other.to_string())?,
    };
    r.extras(&["drive", "id"])?;
    Ok(r)
}

fn move_request(
    target: Option<f64>,
    distance: Option<f64>,
    speed_percent: Option<f64>,
    ramp_ms: Option<&Int>,
    (min_units, max_units): (Option<f64>, Option<f64>),
    timeout_s: f64,
) -> Result<MoveRequest, Failure> {
    let ramp_ms: Option<u32> = opt_within(ramp_ms, FAMILY, "ramp_ms", 0..=i64::from(u32::MAX))?;
    let target = match (target, distance) {
        (Some(t), None) => MoveTarget::Absolute(Position::new(t).map_err(|e| usage(format!("target: {e}")))?),
        (None, Some(d)) => MoveTarget::Relative(Position::new(d).map_err(|e| usage(format!("distance: {e}")))?),
        _ => return Err(usage("give one of target= (absolute) and distance= (relative)")),
    };
    let speed = speed_percent.map(SpeedPercent::new).transpose().map_err(|e| usage(format!("speed_percent: {e}")))?;
    let accel = ramp_ms.map(RampMs::new).transpose().map_err(|e| usage(format!("ramp_ms: {e}")))?;
    let limit =
        |name: &str, v: Option<f64>| v.map(Position::new).transpose().map_err(|e| usage(format!("{name}: {e}")));
    let limits = TravelLimits::new(limit("min_units", min_units)?, limit("max_units", max_units)?)
        .map_err(|e| usage(format!("min_units / max_units: {e}")))?;
    Ok(MoveRequest { target, speed, accel, binary: false, limits, timeout: Some(seconds("timeout_s", timeout_s)?) })
}

/// A move as the CLI's `compax move --json` prints it (`start_units` is an extra attribute).
fn move_record<'py>(py: Python<'py>, report: &MoveReport, tolerance: Position) -> PyResult<Record<'py>> {
    let rec = Record::new(py);
    rec.set("family", FAMILY)?.set("drive", report.address.get())?.set("start_units", report.start.units())?;
    rec.set("target_units", report.target.units())?.set("reached_units", report.reached.units())?;
    rec.set("difference_units", report.difference())?.set("tolerance_units", tolerance.units())?;
    rec.set("waited", true)?.set("verified", report.verified)?.set("not_verifiable", report.not_verifiable.clone())?;
    rec.extras(&["start_units"])?;
    Ok(rec)
}

/// Where a drive stands (S1): the result of `position`, `wait` and `home`.
fn position_record<'py>(py: Python<'py>, drive: Address, p: Position) -> PyResult<Record<'py>> {
    let rec = Record::new(py);
    rec.set("family", FAMILY)?.set("drive", drive.get())?.set("position_units", p.units())?;
    Ok(rec)
}

/// A session with COMPAX drives on one bus (the native half of `motionlink.Compax`).
#[pyclass(frozen, module = "motionlink._native")]
pub struct CompaxClient {
    slot: Slot<Client>,
    token: CancelToken,
    /// The tokens of the watches still running (closing the client ends them).
    watches: std::sync::Mutex<Vec<CancelToken>>,
    drive: u8,
    port: String,
    close_bound: Duration,
    /// The port as given (a URL), for profiles and probes; `None` for an emulator in this process.
    port_url: Option<String>,
    baud: u32,
    profile: crate::common::ProfileUse,
}

impl CompaxClient {
    fn client(&self, py: Python<'_>) -> PyResult<Arc<Client>> {
        self.slot.get().map_err(|f| to_pyerr(py, f))
    }

    fn drive(&self, py: Python<'_>, drive: Option<Int>) -> PyResult<Address> {
        let n = match drive {
            None => self.drive,
            Some(d) => drive_number(&d).map_err(|f| to_pyerr(py, f))?,
        };
        address(n).map_err(|f| to_pyerr(py, f))
    }

    /// Ends the watches still running.
    fn end_watches(&self) {
        for t in motionlink_link::clock::lock(&self.watches).drain(..) {
            t.cancel();
        }
    }
}

fn cancel_cause<T>(py: Python<'_>, r: &Result<T, Error>) -> Option<PyErr> {
    r.as_ref().err().map(|e| to_pyerr(py, e.failure()))
}

#[pymethods]
impl CompaxClient {
    #[new]
    fn py_new(py: Python<'_>, port: &Bound<'_, PyAny>, settings: Settings) -> PyResult<Self> {
        let t = target(port, FAMILY).map_err(|f| to_pyerr(py, f))?;
        let port = match &t {
            Target::InProcess(_) => "in-process emulator".to_string(),
            Target::Url(u) => u.to_string(),
        };
        let port_url = (port != "in-process emulator" && port != "sim").then(|| port.clone());
        let drive = drive_number(&settings.drive).map_err(|f| to_pyerr(py, f))?;
        let baud: u32 = settings.baud.within(FAMILY, "baud", 1..=4_000_000).map_err(|f| to_pyerr(py, f))?;
        let (client, profile) = py
            .detach(|| {
                let client = open(t, &settings)?;
                let address = Address::drive(drive).map_err(|e| usage(e.to_string()))?;
                let used = crate::common::use_profile(settings.profile.as_deref(), port_url.as_deref(), |p, port| {
                    motionlink_compax::probe::use_profile(&client, p, port, address).map_err(|e| e.failure())
                })?;
                Ok::<_, Failure>((client, used))
            })
            .map_err(|f| to_pyerr(py, f))?;
        let token = CancelToken::new();
        client.set_cancel(token.clone());
        let close_bound = client.config().close_bound;
        let watches = Default::default();
        let slot = Slot::new(client, FAMILY);
        Ok(CompaxClient { slot, token, watches, drive, port, close_bound, port_url, baud, profile })
    }

    /// The device profile the session took for its drive (`<path>#<key>`), or None.
    #[getter]
    fn profile(&self) -> Option<String> {
        self.profile.reference.clone()
    }

    /// One line for each profile the session did not take (another identity, a file it could not read).
    #[getter]
    fn profile_notices(&self) -> Vec<String> {
        self.profile.notices.clone()
    }

    /// `motionlink probe compax`'s report of the drives at `drives` (`"1-31"`, `"1,3"`), as a dict (nothing
    /// moves); with `save` (`""`: the default profiles file, else a path) the profile of each drive is
    /// written.
    fn probe<'py>(
        &self,
        py: Python<'py>,
        exchanges: u32,
        low_latency: bool,
        save: Option<String>,
        drives: &str,
    ) -> PyResult<Bound<'py, PyAny>> {
        let client = self.client(py)?;
        let drives = motionlink_compax::probe::parse_drives(drives).map_err(|e| to_pyerr(py, usage(e)))?;
        let setup = crate::common::probe_setup(self.port_url.as_deref(), self.baud, exchanges, low_latency);
        let report = py
            .detach(|| {
                let mut report =
                    motionlink_compax::probe::probe(&client, &setup, &drives).map_err(|e| e.failure())?;
                if let Some(save) = save {
                    let mut profiles = crate::common::profiles_for_save(FAMILY, &save)?;
                    motionlink_compax::probe::save_profile(&mut report, &mut profiles)
                        .map_err(|e| usage(format!("save: {e}")))?;
                }
                serde_json::to_value(&report).map_err(|e| usage(e.to_string()))
            })
            .map_err(|f| to_pyerr(py, f))?;
        json_py(py, &report)
    }

    /// The port.
    #[getter]
    fn port(&self) -> String {
        self.port.clone()
    }

    /// True until closed.
    #[getter]
    fn is_open(&self) -> bool {
        self.slot.is_open()
    }

    /// Drives this session set in motion and has not seen stop.
    fn started(&self, py: Python<'_>) -> PyResult<Vec<u8>> {
        Ok(self.client(py)?.started().into_iter().map(|a| a.get()).collect())
    }

    /// Every drive that answers (addresses 1..31) with its position S1.
    fn scan<'py>(&self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyDict>>> {
        let c = self.client(py)?;
        // The library checks the cancel token before each address; Ctrl-C cancels it and raises at once
        // (the address being asked ends within its reply timeout on the scan's thread).
        let found = interruptible_read(py, Some(self.token.clone()), move || c.scan(1..=31))?.or_raise(py)?;
        found
            .iter()
            .map(|(a, p)| {
                let r = Record::new(py);
                r.set("family", FAMILY)?.set("drive", a.get())?.set("position_units", p.units())?;
                Ok(r.done())
            })
            .collect()
    }

    /// Status values (S1 .. S40) by name ("S1") or number.
    #[pyo3(signature = (names, drive=None))]
    fn status<'py>(
        &self,
        py: Python<'py>,
        names: Vec<String>,
        drive: Option<Int>,
    ) -> PyResult<Vec<Bound<'py, PyDict>>> {
        let c = self.client(py)?;
        let a = self.drive(py, drive)?;
        let ids: Vec<StatusId> = names
            .iter()
            .map(|n| StatusId::parse(n).map_err(|e| usage(format!("status {n:?}: {e}"))))
            .collect::<Result<_, _>>()
            .map_err(|f| to_pyerr(py, f))?;
        let values =
            interruptible_read(py, Some(self.token.clone()), move || c.read_statuses(a, &ids))?.or_raise(py)?;
        values.iter().map(|(id, v)| Ok(status_record(py, a.get(), *id, v)?.done())).collect()
    }

    /// The actual position S1, in the drive's unit.
    #[pyo3(signature = (drive=None))]
    fn position(&self, py: Python<'_>, drive: Option<Int>) -> PyResult<f64> {
        let c = self.client(py)?;
        let a = self.drive(py, drive)?;
        py.detach(|| c.read_position(a)).or_raise(py).map(|p| p.units())
    }

    /// Reads a parameter (P194, device_address).
    #[pyo3(signature = (name, drive=None))]
    fn get<'py>(&self, py: Python<'py>, name: &str, drive: Option<Int>) -> PyResult<Bound<'py, PyDict>> {
        let c = self.client(py)?;
        let a = self.drive(py, drive)?;
        let id = ParamId::parse(name).map_err(|e| to_pyerr(py, usage(format!("{name:?}: {e}"))))?;
        let v = interruptible_read(py, None, move || c.read_param(a, id))?.or_raise(py)?;
        let r = param_record(py, a.get(), id)?;
        r.set("value", v)?;
        Ok(r.done())
    }

    /// Writes a parameter and reads it back (a different value is a DeviceError).
    #[pyo3(signature = (name, value, drive=None))]
    fn set<'py>(&self, py: Python<'py>, name: &str, value: f64, drive: Option<Int>) -> PyResult<Bound<'py, PyDict>> {
        let c = self.client(py)?;
        let a = self.drive(py, drive)?;
        let id = ParamId::parse(name)
            .and_then(|id| id.check(value).map(|()| id))
            .map_err(|e| to_pyerr(py, usage(format!("{name}: {e}"))))?;
        // The library writes and compares what it reads back (a difference is an error); the value is then
        // read once more, so that `read_back` is what the drive holds, not an echo of `value`.
        let back = py.detach(|| c.write_param(a, id, value).and_then(|()| c.read_param(a, id))).or_raise(py)?;
        let r = param_record(py, a.get(), id)?;
        // Always verified (the library compared the value read back): nothing it could not check, as the
        // other families' `set` says it, so that `not_verifiable` is a list in every family's result.
        r.set("value", value)?.set("read_back", back)?.set("verified", true)?;
        r.set("not_verifiable", Vec::<String>::new())?;
        Ok(r.done())
    }

    /// A checked move (absolute `target` or relative `distance`), waited for; Ctrl-C stops the drive.
    #[pyo3(signature = (target=None, distance=None, drive=None, speed_percent=None, ramp_ms=None, min_units=None, max_units=None, timeout_s=600.0))]
    #[allow(clippy::too_many_arguments)]
    fn move_to<'py>(
        &self,
        py: Python<'py>,
        target: Option<f64>,
        distance: Option<f64>,
        drive: Option<Int>,
        speed_percent: Option<f64>,
        ramp_ms: Option<Int>,
        min_units: Option<f64>,
        max_units: Option<f64>,
        timeout_s: f64,
    ) -> PyResult<Bound<'py, PyDict>> {
        let c = self.client(py)?;
        let a = self.drive(py, drive)?;
        let request =
            move_request(target, distance, speed_percent, ramp_ms.as_ref(), (min_units, max_units), timeout_s)
                .map_err(|f| to_pyerr(py, f))?;
        let r = interruptible(py, Some(&self.token), || c.move_to(a, &request, &mut |_| {}), cancel_cause)?;
        let report = r.or_raise(py)?;
        Ok(move_record(py, &report, c.config().in_position_tolerance)?.done())
    }

    /// POSA HOME, waited for; Ctrl-C stops the drive.
    #[pyo3(signature = (drive=None, timeout_s=600.0))]
    fn home<'py>(&self, py: Python<'py>, drive: Option<Int>, timeout_s: f64) -> PyResult<Bound<'py, PyDict>> {
        let c = self.client(py)?;
        let a = self.drive(py, drive)?;
        let timeout = seconds("timeout_s", timeout_s).map_err(|f| to_pyerr(py, f))?;
        let r = interruptible(
            py,
            Some(&self.token),
            || -> Result<Position, Error> {
                c.home(a, Default::default())?;
                c.wait_reached(&[a], Some(timeout), &mut |_, _| {})?;
                c.read_position(a)
            },
            cancel_cause,
        )?;
        let p = r.or_raise(py)?;
        Ok(position_record(py, a, p)?.done())
    }

    /// Waits until the drive reports its positioning ended (S17); Ctrl-C stops the drive.
    #[pyo3(signature = (drive=None, timeout_s=600.0))]
    fn wait<'py>(&self, py: Python<'py>, drive: Option<Int>, timeout_s: f64) -> PyResult<Bound<'py, PyDict>> {
        let c = self.client(py)?;
        let a = self.drive(py, drive)?;
        let timeout = seconds("timeout_s", timeout_s).map_err(|f| to_pyerr(py, f))?;
        let r = interruptible(
            py,
            Some(&self.token),
            || -> Result<Position, Error> {
                c.wait_reached(&[a], Some(timeout), &mut |_, _| {})?;
                c.read_position(a)
            },
            cancel_cause,
        )?;
        let p = r.or_raise(py)?;
        Ok(position_record(py, a, p)?.done())
    }

    /// Stops the drive: OUTPUT O0=0 (switches it off; switch it on with `output(0, 1)`).
    #[pyo3(signature = (drive=None))]
    fn stop(&self, py: Python<'_>, drive: Option<Int>) -> PyResult<()> {
        let c = self.client(py)?;
        let a = self.drive(py, drive)?;
        py.detach(|| c.stop(a)).or_raise(py)
    }

    /// Sets output `number` to `state` (OUTPUT Ox=y).
    #[pyo3(signature = (number, state, drive=None))]
    fn output(&self, py: Python<'_>, number: Int, state: Int, drive: Option<Int>) -> PyResult<()> {
        let c = self.client(py)?;
        let a = self.drive(py, drive)?;
        let number: u16 =
            number.within(FAMILY, "number (the output)", 0..=i64::from(u16::MAX)).map_err(|f| to_pyerr(py, f))?;
        let state: u8 =
            state.within(FAMILY, "state (of the output)", 0..=i64::from(u8::MAX)).map_err(|f| to_pyerr(py, f))?;
        let st = OutputState::new(number, state).map_err(|e| to_pyerr(py, usage(e.to_string())))?;
        py.detach(|| c.set_output(a, number, st, false)).or_raise(py)
    }

    /// Starts the library's watch of the drive (S1 and S17 every `interval_ms`, on a thread of its own):
    /// the samples come from [`CompaxWatch::next`].
    #[pyo3(signature = (drive, interval_ms))]
    fn watch_start(&self, py: Python<'_>, drive: Option<Int>, interval_ms: Int) -> PyResult<CompaxWatch> {
        let c = self.client(py)?;
        let a = self.drive(py, drive)?;
        let ms: u64 = interval_ms.within(FAMILY, "interval_ms", 1..=3_600_000).map_err(|f| to_pyerr(py, f))?;
        let w = CompaxWatch::start(c, a, Duration::from_millis(ms));
        motionlink_link::clock::lock(&self.watches).push(w.token());
        Ok(w)
    }

    /// Ends the session: stops what it set in motion that still moves (confirmed by S17); an exception if
    /// a drive did not confirm.
    fn close(&self, py: Python<'_>) -> PyResult<()> {
        let bound = self.close_bound;
        self.end_watches();
        let taken = py.detach(|| self.slot.take(&self.token, bound));
        match taken {
            None => Ok(()),
            Some(Ok(client)) => py.detach(|| client.close()).or_raise(py).map(|_| ()),
            Some(Err(shared)) => {
                let report = py.detach(|| shared.stop_started());
                if report.all_confirmed() {
                    Ok(())
                } else {
                    Err(to_pyerr(
                        py,
                        Failure::new(motionlink_link::error::ErrorClass::Device, FAMILY, format!("closing: {report}")),
                    ))
                }
            }
        }
    }
}

/// The in-position tolerance the library uses unless told otherwise.
pub fn default_tolerance() -> f64 {
    DEFAULT_IN_POSITION_TOLERANCE
}

impl Drop for CompaxClient {
    fn drop(&mut self) {
        // Not closed by its owner (garbage-collected): the session ends here, stopping what it started as
        // the family's client does when dropped, without holding the GIL while it waits for the device.
        self.end_watches();
        if let Some(taken) = self.slot.take(&self.token, self.close_bound) {
            Python::attach(|py| py.detach(move || drop(taken)));
        }
    }
}
