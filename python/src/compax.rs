//! Parker COMPAX drives from Python: the native half of `motionlink.Compax`. Every operation is one call
//! of `motionlink_compax::Client`; what stops a drive and how a move is checked are the library's.

use std::sync::Arc;
use std::time::Duration;

use motionlink_compax::client::{
    BusConfig, MoveOptions, MoveReport, MoveRequest, MoveTarget, TravelLimits, DEFAULT_IN_POSITION_TOLERANCE,
};
use motionlink_compax::model::{
    Command, OutputState, ParamId, Position, RampMs, S17Flag, SpeedPercent, StatusId, StatusValue, BAUD_RATES,
};
use motionlink_compax::session::{Op, Output};
use motionlink_compax::wire::{Address, Mode};
use motionlink_compax::{AsyncClient, Client, Error};
use motionlink_link::cancel::CancelToken;
use motionlink_link::link::{Link, SerialSettings};
use motionlink_link::url::PortUrl;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::common::{target, Record, Slot, Target};
use crate::emulator::{clock, InProcess};
use crate::errors::{to_pyerr, Failure, IntoFailure, OrRaise};
use crate::wait::{block_on_runtime, deliver, interruptible, spawn_task, NativeTask};

const FAMILY: &str = "compax";

fn usage(msg: impl Into<String>) -> Failure {
    Failure::usage(FAMILY, msg)
}

/// How a COMPAX client is opened, as `motionlink.Compax` passes it.
#[derive(FromPyObject)]
#[pyo3(from_item_all)]
pub struct Settings {
    drive: u8,
    mode: u32,
    baud: u32,
    timeout_ms: u64,
    poll_ms: u64,
    tolerance_units: f64,
}

/// The link `port` names and the session's settings, checked.
fn link(port: Target, s: &Settings) -> Result<(Box<dyn Link>, BusConfig), Failure> {
    let mode = Mode::from_p196(s.mode).map_err(|e| usage(format!("mode (P196) {}: {e}", s.mode)))?;
    Address::drive(s.drive).map_err(|e| usage(format!("drive {}: {e}", s.drive)))?;
    if !BAUD_RATES.contains(&s.baud) {
        return Err(usage(format!("baud {}: not a rate P195 accepts ({BAUD_RATES:?})", s.baud)));
    }
    if !(1..=60_000).contains(&s.timeout_ms) {
        return Err(usage(format!("timeout_ms {}: give 1 to 60000", s.timeout_ms)));
    }
    if !(1..=10_000).contains(&s.poll_ms) {
        return Err(usage(format!("poll_ms {}: give 1 to 10000", s.poll_ms)));
    }
    if !(s.tolerance_units.is_finite() && s.tolerance_units > 0.0 && s.tolerance_units <= 1e6) {
        return Err(usage(format!("tolerance_units {}: give a distance above 0 (at most 1000000)", s.tolerance_units)));
    }
    let link: Box<dyn Link> = match port {
        Target::InProcess(InProcess::Compax(host)) => Box::new(host.connect().0),
        Target::InProcess(_) => return Err(usage("that emulator is not a COMPAX emulator")),
        Target::Url(PortUrl::Sim) => {
            let cfg = motionlink_compax::sim::SimConfig::bus(&[s.drive], s.mode, s.baud);
            let bus = motionlink_compax::Emulator::new(cfg).map_err(|e| usage(e.to_string()))?;
            let host =
                motionlink_link::pipe::EmulatorHost::new(bus, clock(), motionlink_link::pipe::PipeConfig::instant());
            Box::new(host.connect().0)
        }
        Target::Url(p) if p.is_can() => return Err(usage(format!("{p}: COMPAX drives speak RS485/RS232, not CAN"))),
        Target::Url(p) => {
            let mut settings = SerialSettings::new(s.baud);
            settings.parity = mode.parity;
            p.open_byte_link(settings).map_err(|e| e.failure())?
        }
    };
    let mut cfg = BusConfig::new(mode, s.baud);
    cfg.reply_timeout = Duration::from_millis(s.timeout_ms);
    cfg.poll_interval = Duration::from_millis(s.poll_ms);
    cfg.in_position_tolerance = Position::new(s.tolerance_units).map_err(|e| usage(format!("tolerance_units: {e}")))?;
    Ok((link, cfg))
}

fn open(port: Target, s: &Settings) -> Result<Client, Failure> {
    let (link, cfg) = link(port, s)?;
    Client::new(link, clock(), cfg).map_err(|e| e.failure())
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

fn param_record<'py>(py: Python<'py>, drive: u8, id: ParamId) -> PyResult<Record<'py>> {
    let r = Record::new(py);
    r.set("family", FAMILY)?.set("drive", drive)?.set("name", id.to_string())?.set("id", id.get())?;
    r.set("unit", id.info().map_or("", |i| i.unit))?.set("access", "rw")?;
    if let Some(d) = id.description() {
        r.set("title", d)?;
    }
    Ok(r)
}

fn status_record<'py>(py: Python<'py>, drive: u8, id: StatusId, v: &StatusValue) -> PyResult<Record<'py>> {
    let info = id.info();
    let r = Record::new(py);
    r.set("family", FAMILY)?.set("drive", drive)?.set("name", id.to_string())?.set("id", id.get())?;
    r.set("title", info.map_or("", |i| i.title))?.set("unit", info.map_or("", |i| i.unit))?;
    match v {
        StatusValue::S16(b) => r.set("value", b.0)?.set("flags", b.meanings())?,
        StatusValue::S17(b) => r.set("value", b.0)?.set("flags", b.meanings())?,
        StatusValue::Position(p) => r.set("value", p.units())?,
        StatusValue::Number(n) => r.set("value", *n)?,
        other => r.set("value", other.to_string())?,
    };
    Ok(r)
}

fn move_request(
    target: Option<f64>,
    distance: Option<f64>,
    speed_percent: Option<f64>,
    ramp_ms: Option<u32>,
    (min_units, max_units): (Option<f64>, Option<f64>),
    timeout_s: f64,
) -> Result<MoveRequest, Failure> {
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

fn move_record<'py>(py: Python<'py>, report: &MoveReport, tolerance: Position) -> PyResult<Record<'py>> {
    let rec = Record::new(py);
    rec.set("family", FAMILY)?.set("drive", report.address.get())?.set("start_units", report.start.units())?;
    rec.set("target_units", report.target.units())?.set("reached_units", report.reached.units())?;
    rec.set("difference_units", report.difference())?.set("tolerance_units", tolerance.units())?;
    Ok(rec)
}

/// A session with COMPAX drives on one bus (the native half of `motionlink.Compax`).
#[pyclass(frozen, module = "motionlink._native")]
pub struct CompaxClient {
    slot: Slot<Client>,
    token: CancelToken,
    drive: u8,
    port: String,
    close_bound: Duration,
}

impl CompaxClient {
    fn client(&self, py: Python<'_>) -> PyResult<Arc<Client>> {
        self.slot.get().map_err(|f| to_pyerr(py, f))
    }

    fn drive(&self, py: Python<'_>, drive: Option<u8>) -> PyResult<Address> {
        address(drive.unwrap_or(self.drive)).map_err(|f| to_pyerr(py, f))
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
        let client = py.detach(|| open(t, &settings)).map_err(|f| to_pyerr(py, f))?;
        let token = CancelToken::new();
        client.set_cancel(token.clone());
        let close_bound = client.config().close_bound;
        Ok(CompaxClient { slot: Slot::new(client, FAMILY), token, drive: settings.drive, port, close_bound })
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
        let found = py.detach(|| c.scan(1..=31)).or_raise(py)?;
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
    fn status<'py>(&self, py: Python<'py>, names: Vec<String>, drive: Option<u8>) -> PyResult<Vec<Bound<'py, PyDict>>> {
        let c = self.client(py)?;
        let a = self.drive(py, drive)?;
        let ids: Vec<StatusId> = names
            .iter()
            .map(|n| StatusId::parse(n).map_err(|e| usage(format!("status {n:?}: {e}"))))
            .collect::<Result<_, _>>()
            .map_err(|f| to_pyerr(py, f))?;
        let values = py.detach(|| c.read_statuses(a, &ids)).or_raise(py)?;
        values.iter().map(|(id, v)| Ok(status_record(py, a.get(), *id, v)?.done())).collect()
    }

    /// The actual position S1, in the drive's unit.
    #[pyo3(signature = (drive=None))]
    fn position(&self, py: Python<'_>, drive: Option<u8>) -> PyResult<f64> {
        let c = self.client(py)?;
        let a = self.drive(py, drive)?;
        py.detach(|| c.read_position(a)).or_raise(py).map(|p| p.units())
    }

    /// Reads a parameter (P194, device_address).
    #[pyo3(signature = (name, drive=None))]
    fn get<'py>(&self, py: Python<'py>, name: &str, drive: Option<u8>) -> PyResult<Bound<'py, PyDict>> {
        let c = self.client(py)?;
        let a = self.drive(py, drive)?;
        let id = ParamId::parse(name).map_err(|e| to_pyerr(py, usage(format!("{name:?}: {e}"))))?;
        let v = py.detach(|| c.read_param(a, id)).or_raise(py)?;
        let r = param_record(py, a.get(), id)?;
        r.set("value", v)?;
        Ok(r.done())
    }

    /// Writes a parameter and reads it back (a different value is a DeviceError).
    #[pyo3(signature = (name, value, drive=None))]
    fn set<'py>(&self, py: Python<'py>, name: &str, value: f64, drive: Option<u8>) -> PyResult<Bound<'py, PyDict>> {
        let c = self.client(py)?;
        let a = self.drive(py, drive)?;
        let id = ParamId::parse(name)
            .and_then(|id| id.check(value).map(|()| id))
            .map_err(|e| to_pyerr(py, usage(format!("{name}: {e}"))))?;
        py.detach(|| c.write_param(a, id, value)).or_raise(py)?;
        let r = param_record(py, a.get(), id)?;
        r.set("value", value)?.set("read_back", value)?;
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
        drive: Option<u8>,
        speed_percent: Option<f64>,
        ramp_ms: Option<u32>,
        min_units: Option<f64>,
        max_units: Option<f64>,
        timeout_s: f64,
    ) -> PyResult<Bound<'py, PyDict>> {
        let c = self.client(py)?;
        let a = self.drive(py, drive)?;
        let request = move_request(target, distance, speed_percent, ramp_ms, (min_units, max_units), timeout_s)
            .map_err(|f| to_pyerr(py, f))?;
        let r = interruptible(py, Some(&self.token), || c.move_to(a, &request, &mut |_| {}), cancel_cause)?;
        let report = r.or_raise(py)?;
        Ok(move_record(py, &report, c.config().in_position_tolerance)?.done())
    }

    /// POSA HOME, waited for; Ctrl-C stops the drive.
    #[pyo3(signature = (drive=None, timeout_s=600.0))]
    fn home<'py>(&self, py: Python<'py>, drive: Option<u8>, timeout_s: f64) -> PyResult<Bound<'py, PyDict>> {
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
        let rec = Record::new(py);
        rec.set("family", FAMILY)?.set("drive", a.get())?.set("position_units", p.units())?;
        Ok(rec.done())
    }

    /// Waits until the drive reports its positioning ended (S17); Ctrl-C stops the drive.
    #[pyo3(signature = (drive=None, timeout_s=600.0))]
    fn wait(&self, py: Python<'_>, drive: Option<u8>, timeout_s: f64) -> PyResult<f64> {
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
        r.or_raise(py).map(|p| p.units())
    }

    /// Stops the drive: OUTPUT O0=0 (switches it off; switch it on with `output(0, 1)`).
    #[pyo3(signature = (drive=None))]
    fn stop(&self, py: Python<'_>, drive: Option<u8>) -> PyResult<()> {
        let c = self.client(py)?;
        let a = self.drive(py, drive)?;
        py.detach(|| c.stop(a)).or_raise(py)
    }

    /// Sets output `number` to `state` (OUTPUT Ox=y).
    #[pyo3(signature = (number, state, drive=None))]
    fn output(&self, py: Python<'_>, number: u16, state: u8, drive: Option<u8>) -> PyResult<()> {
        let c = self.client(py)?;
        let a = self.drive(py, drive)?;
        let st = OutputState::new(number, state).map_err(|e| to_pyerr(py, usage(e.to_string())))?;
        py.detach(|| c.set_output(a, number, st, false)).or_raise(py)
    }

    /// One sample of `watch`: S1 and S17.
    #[pyo3(signature = (drive=None))]
    fn sample<'py>(&self, py: Python<'py>, drive: Option<u8>) -> PyResult<Bound<'py, PyDict>> {
        let c = self.client(py)?;
        let a = self.drive(py, drive)?;
        let (p, s17) = py.detach(|| -> Result<_, Error> { Ok((c.read_position(a)?, c.read_s17(a)?)) }).or_raise(py)?;
        let r = Record::new(py);
        r.set("family", FAMILY)?.set("drive", a.get())?.set("position_units", p.units())?;
        r.set("moving", s17.contains(S17Flag::CommandActive))?.set("flags", s17.meanings())?;
        Ok(r.done())
    }

    /// Ends the session: stops what it set in motion that still moves (confirmed by S17); an exception if
    /// a drive did not confirm.
    fn close(&self, py: Python<'_>) -> PyResult<()> {
        let bound = self.close_bound;
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

/// An async session with COMPAX drives (the native half of `motionlink.AsyncCompax`): cancelling a move's,
/// a homing's or a wait's task drops its future, which stops the drive (OUTPUT O0=0, confirmed by S17).
#[pyclass(frozen, module = "motionlink._native")]
pub struct AsyncCompaxClient {
    slot: Slot<AsyncClient>,
    drive: u8,
    port: String,
}

impl AsyncCompaxClient {
    fn client(&self, py: Python<'_>) -> PyResult<Arc<AsyncClient>> {
        self.slot.get().map_err(|f| to_pyerr(py, f))
    }

    fn drive(&self, py: Python<'_>, drive: Option<u8>) -> PyResult<Address> {
        address(drive.unwrap_or(self.drive)).map_err(|f| to_pyerr(py, f))
    }
}

fn fail<T>(r: Result<T, Error>) -> Result<T, Failure> {
    r.map_err(|e| e.failure())
}

fn units(p: Position) -> crate::wait::Outcome {
    deliver(move |py| Ok(p.units().into_pyobject(py)?.into_any().unbind()))
}

#[pymethods]
impl AsyncCompaxClient {
    /// Opens a session on the runtime (the port on its blocking pool): `done(ok, client)`.
    #[staticmethod]
    fn open(py: Python<'_>, port: &Bound<'_, PyAny>, settings: Settings, done: Py<PyAny>) -> PyResult<NativeTask> {
        let t = target(port, FAMILY).map_err(|f| to_pyerr(py, f))?;
        let port = match &t {
            Target::InProcess(_) => "in-process emulator".to_string(),
            Target::Url(u) => u.to_string(),
        };
        Ok(spawn_task(done, async move {
            let drive = settings.drive;
            let opened = tokio::task::spawn_blocking(move || link(t, &settings)).await;
            let (link, cfg) = opened.map_err(|e| {
                Failure::new(
                    motionlink_link::error::ErrorClass::Transport(motionlink_link::error::TransportKind::Io),
                    FAMILY,
                    format!("the opening task failed: {e}"),
                )
            })??;
            let client = fail(AsyncClient::new(link, clock(), cfg))?;
            let native = AsyncCompaxClient { slot: Slot::new(client, FAMILY), drive, port };
            deliver(move |py| Ok(Py::new(py, native)?.into_any()))
        }))
    }

    /// The port.
    #[getter]
    fn port(&self) -> String {
        self.port.clone()
    }

    /// The actual position S1: `done(ok, float)`.
    #[pyo3(signature = (drive, done))]
    fn position(&self, py: Python<'_>, drive: Option<u8>, done: Py<PyAny>) -> PyResult<NativeTask> {
        let c = self.client(py)?;
        let a = self.drive(py, drive)?;
        Ok(spawn_task(done, async move { units(fail(c.read_position(a).await)?) }))
    }

    /// A checked move, waited for; cancelling the task stops the drive.
    #[pyo3(signature = (target, distance, drive, speed_percent, ramp_ms, min_units, max_units, timeout_s, done))]
    #[allow(clippy::too_many_arguments)]
    fn move_to(
        &self,
        py: Python<'_>,
        target: Option<f64>,
        distance: Option<f64>,
        drive: Option<u8>,
        speed_percent: Option<f64>,
        ramp_ms: Option<u32>,
        min_units: Option<f64>,
        max_units: Option<f64>,
        timeout_s: f64,
        done: Py<PyAny>,
    ) -> PyResult<NativeTask> {
        let c = self.client(py)?;
        let a = self.drive(py, drive)?;
        let request = move_request(target, distance, speed_percent, ramp_ms, (min_units, max_units), timeout_s)
            .map_err(|f| to_pyerr(py, f))?;
        Ok(spawn_task(done, async move {
            let report = fail(c.move_to(a, &request).await)?;
            let tolerance = c.config().in_position_tolerance;
            deliver(move |py| Ok(move_record(py, &report, tolerance)?.done().into_any().unbind()))
        }))
    }

    /// POSA HOME, waited for; cancelling the task stops the drive.
    #[pyo3(signature = (drive, timeout_s, done))]
    fn home(&self, py: Python<'_>, drive: Option<u8>, timeout_s: f64, done: Py<PyAny>) -> PyResult<NativeTask> {
        let c = self.client(py)?;
        let a = self.drive(py, drive)?;
        let timeout = seconds("timeout_s", timeout_s).map_err(|f| to_pyerr(py, f))?;
        Ok(spawn_task(done, async move {
            match fail(c.start(Op::Move(a, Command::PosAHome, MoveOptions::default())).await)? {
                Output::Done => {}
                other => {
                    return Err(Failure::new(
                        motionlink_link::error::ErrorClass::Transport(motionlink_link::error::TransportKind::Corrupt),
                        FAMILY,
                        format!("the session answered {other:?} to POSA HOME"),
                    ))
                }
            }
            fail(c.wait_reached(&[a], Some(timeout)).await)?;
            let p = fail(c.read_position(a).await)?;
            deliver(move |py| {
                let r = Record::new(py);
                r.set("family", FAMILY)?.set("drive", a.get())?.set("position_units", p.units())?;
                Ok(r.done().into_any().unbind())
            })
        }))
    }

    /// Waits until the drive's positioning ended; its position then. Cancelling the task stops the drive.
    #[pyo3(signature = (drive, timeout_s, done))]
    fn wait(&self, py: Python<'_>, drive: Option<u8>, timeout_s: f64, done: Py<PyAny>) -> PyResult<NativeTask> {
        let c = self.client(py)?;
        let a = self.drive(py, drive)?;
        let timeout = seconds("timeout_s", timeout_s).map_err(|f| to_pyerr(py, f))?;
        Ok(spawn_task(done, async move {
            fail(c.wait_reached(&[a], Some(timeout)).await)?;
            units(fail(c.read_position(a).await)?)
        }))
    }

    /// Stops the drive (OUTPUT O0=0).
    #[pyo3(signature = (drive, done))]
    fn stop(&self, py: Python<'_>, drive: Option<u8>, done: Py<PyAny>) -> PyResult<NativeTask> {
        let c = self.client(py)?;
        let a = self.drive(py, drive)?;
        Ok(spawn_task(done, async move {
            fail(c.stop(a).await)?;
            deliver(|py| Ok(py.None()))
        }))
    }

    /// Ends the session (stops what it set in motion that still moves): `done(ok, None)`.
    fn close(&self, done: Py<PyAny>) -> NativeTask {
        let taken = self.slot.take(&CancelToken::new(), Duration::ZERO);
        spawn_task(done, async move {
            match taken {
                None => {}
                Some(Ok(client)) => {
                    fail(client.close().await)?;
                }
                Some(Err(shared)) => {
                    let report = shared.stop_started().await;
                    if !report.all_confirmed() {
                        return Err(Failure::new(
                            motionlink_link::error::ErrorClass::Device,
                            FAMILY,
                            format!("closing: {report}"),
                        ));
                    }
                }
            }
            deliver(|py| Ok(py.None()))
        })
    }

    /// Ends the session from synchronous code (atexit), waiting without the GIL.
    fn close_blocking(&self, py: Python<'_>) -> PyResult<()> {
        let Some(taken) = self.slot.take(&CancelToken::new(), Duration::ZERO) else { return Ok(()) };
        match taken {
            Ok(client) => block_on_runtime(py, client.close())?.or_raise(py).map(|_| ()),
            Err(shared) => {
                block_on_runtime(py, async move { shared.stop_started().await })?;
                Ok(())
            }
        }
    }
}

impl Drop for CompaxClient {
    fn drop(&mut self) {
        // Not closed by its owner (garbage-collected): the session ends here, stopping what it started as
        // the family's client does when dropped, without holding the GIL while it waits for the device.
        if let Some(taken) = self.slot.take(&self.token, self.close_bound) {
            Python::attach(|py| py.detach(move || drop(taken)));
        }
    }
}
