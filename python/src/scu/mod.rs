//! SCU control units from Python: the native half of `motionlink.Scu`. Every operation is one call of
//! `motionlink_scu::Client`; what stops an actuator (RS), the keepalive and how a move is verified are the
//! library's.

mod asyncio;
pub use asyncio::AsyncScuClient;

use std::sync::Arc;
use std::time::Duration;

use motionlink_link::cancel::CancelToken;
use motionlink_link::link::{Connector, Link, SerialSettings};
use motionlink_link::url::PortUrl;
use motionlink_scu::model::{
    lookup, Actuator, ActuatorStatus1, DataEntryExt, DataIndex, Function, Item, MotionDirection, MotionFunction,
    PositionCounts, SafetyId, Speed, SpeedMode, StopMode,
};
use motionlink_scu::session::{MoveReport, RunAction, RunReport};
use motionlink_scu::value::Value;
use motionlink_scu::{AsyncClient, Client, ClientConfig, Error, FunctionMap, MoveOptions, StrokeLimits};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::common::{json_py, target, Record, Slot, Target};
use crate::emulator::{clock, InProcess};
use crate::errors::{to_pyerr, Failure, IntoFailure, OrRaise};
use crate::wait::{block_on_runtime, deliver, interruptible, spawn_task, NativeTask};

const FAMILY: &str = "scu";

fn usage(msg: impl Into<String>) -> Failure {
    Failure::usage(FAMILY, msg)
}

/// How an SCU client is opened, as `motionlink.Scu` passes it.
#[derive(FromPyObject)]
#[pyo3(from_item_all)]
pub struct Settings {
    baud: u32,
    safety: u8,
    reply_timeout_ms: u64,
    functions: Vec<String>,
    strokes: Vec<String>,
    tolerance_counts: u32,
    poll_ms: u64,
    speed_mode: String,
}

fn client_config(s: &Settings) -> Result<ClientConfig, Failure> {
    let safety_id = match s.safety {
        0 => SafetyId::StopAllAndLock,
        1 => SafetyId::StopAll,
        2 => SafetyId::StopRemoteOnly,
        n => return Err(usage(format!("safety {n}: the Safety_ID is 0, 1 or 2"))),
    };
    if ![9_600, 19_200, 38_400].contains(&s.baud) {
        return Err(usage(format!("baud {}: an SCU runs at 9600, 19200 or 38400 baud", s.baud)));
    }
    if !(1..=60_000).contains(&s.reply_timeout_ms) {
        return Err(usage(format!("reply_timeout_ms {}: give 1 to 60000", s.reply_timeout_ms)));
    }
    if !(5..=10_000).contains(&s.poll_ms) {
        return Err(usage(format!("poll_ms {}: give 5 to 10000", s.poll_ms)));
    }
    let speed_mode = match s.speed_mode.as_str() {
        "percent" => SpeedMode::Percent,
        "counts_per_s" => SpeedMode::CountsPerSecond,
        other => return Err(usage(format!("speed_mode {other:?}: give \"percent\" or \"counts_per_s\""))),
    };
    let mut function_map = FunctionMap::unknown();
    for spec in &s.functions {
        function_map = function_map.apply(spec).map_err(|e| usage(format!("functions: {e}")))?;
    }
    let mut stroke_limits = [None; 6];
    for spec in &s.strokes {
        let (a, limits) = StrokeLimits::parse_for_actuator(spec).map_err(|e| usage(format!("strokes: {e}")))?;
        stroke_limits[usize::from(a.number() - 1)] = Some(limits);
    }
    let config = ClientConfig {
        safety_id,
        reply_timeout: Duration::from_millis(s.reply_timeout_ms),
        speed_mode,
        function_map,
        stroke_limits,
        position_tolerance_counts: s.tolerance_counts,
        poll_interval: Duration::from_millis(s.poll_ms),
        ..ClientConfig::default()
    };
    config.validate().map_err(|e| usage(e.to_string()))?;
    Ok(config)
}

/// How to reach the unit `port` names, and the session's settings.
fn connector(port: Target, s: &Settings) -> Result<(Connector, ClientConfig), Failure> {
    let config = client_config(s)?;
    let connector: Connector = match port {
        Target::InProcess(InProcess::Scu(host)) => Box::new(move || Ok(Box::new(host.connect().0) as Box<dyn Link>)),
        Target::InProcess(_) => return Err(usage("that emulator is not an SCU emulator")),
        Target::Url(PortUrl::Sim) => {
            let sim = motionlink_scu::SimConfig { speed_mode: config.speed_mode, ..Default::default() };
            let device = motionlink_scu::Emulator::new(sim).map_err(|e| usage(e.to_string()))?;
            let host =
                motionlink_link::pipe::EmulatorHost::new(device, clock(), motionlink_link::pipe::PipeConfig::instant());
            Box::new(move || Ok(Box::new(host.connect().0) as Box<dyn Link>))
        }
        Target::Url(p) if p.is_can() => return Err(usage(format!("{p}: the SCU speaks RS232, not CAN"))),
        Target::Url(p) => {
            let settings = SerialSettings::new(s.baud);
            Box::new(move || p.open_byte_link(settings))
        }
    };
    Ok((connector, config))
}

fn open(port: Target, s: &Settings) -> Result<Client, Failure> {
    let (connector, config) = connector(port, s)?;
    Client::open(connector, clock(), config).map_err(|e| e.failure())
}

fn actuator(n: u8) -> Result<Actuator, Failure> {
    Actuator::new(n).ok_or_else(|| usage(format!("actuator {n}: actuators are 1..6")))
}

fn parse_item(text: &str) -> Result<Item, Failure> {
    lookup(text).ok_or_else(|| {
        usage(format!(
            "{text:?} is not a data-list entry: give a name such as actual_position_a1 or an index such as 0x0011"
        ))
    })
}

fn parse_function(text: &str) -> Result<Function, Failure> {
    Function::parse(text).ok_or_else(|| {
        usage(format!(
            "{text:?} is not a function: F1..F10 motion, F11 buzzer, F17/F18 outputs, F20 emergency stop, F21/F22 LEDs"
        ))
    })
}

fn status_flags(s: ActuatorStatus1) -> Vec<&'static str> {
    motionlink_scu::model::Flags::from(s).set_names().collect()
}

/// A value in Python: numbers in the entry's unit as `unit` names it (deci-amps become amps, centi-volts
/// volts), bit sets and error codes as dicts.
fn value_py<'py>(py: Python<'py>, v: &Value) -> PyResult<Bound<'py, PyAny>> {
    match v {
        Value::CurrentDeciAmps(_) | Value::BatteryDeciVolts(_) | Value::AnalogueCentiVolts(_) => {
            Ok(v.as_f64().unwrap_or(f64::NAN).into_pyobject(py)?.into_any())
        }
        // A bit set as naming.md spells flags: the raw word, the names of the bits set, and the bits no
        // name covers (only when nonzero).
        Value::Flags(f) => {
            let known = f.set.bits().into_iter().fold(0u32, |m, b| m | (1 << b.bit));
            let d = PyDict::new(py);
            d.set_item("code", f.bits)?;
            d.set_item("flags", f.set_names().collect::<Vec<_>>())?;
            if f.bits & !known != 0 {
                d.set_item("unknown_bits", f.bits & !known)?;
            }
            Ok(d.into_any())
        }
        _ => json_py(py, &v.to_json()),
    }
}

/// The unit of a value as Python gets it (the converted ones in A and V).
fn value_unit(v: &Value, unit: &'static str) -> &'static str {
    match v {
        Value::CurrentDeciAmps(_) => "A",
        Value::BatteryDeciVolts(_) | Value::AnalogueCentiVolts(_) => "V",
        _ => unit,
    }
}

fn error_code<'py>(py: Python<'py>, v: &Value) -> PyResult<Bound<'py, PyAny>> {
    json_py(py, &v.to_json())
}

fn move_record<'py>(py: Python<'py>, target_counts: i32, report: &MoveReport) -> PyResult<Record<'py>> {
    let rec = Record::new(py);
    rec.set("family", FAMILY)?.set("function", report.function.number())?;
    rec.set("actuator", report.actuator.number())?.set("target_counts", target_counts)?;
    rec.set("position_counts", report.position_counts.get())?.set("time_s", report.duration.as_secs_f64())?;
    let mut acts = Vec::new();
    for o in &report.actuators {
        let d = Record::new(py);
        d.set("actuator", o.actuator.number())?.set("target_counts", o.target_counts.get())?;
        d.set("start_counts", o.start_counts.get())?.set("position_counts", o.position_counts.get())?;
        d.set("difference_counts", o.difference_counts())?.set("moved", o.moved)?;
        acts.push(d.done());
    }
    rec.set("actuators", acts)?;
    Ok(rec)
}

fn run_record<'py>(py: Python<'py>, function: Function, report: &RunReport) -> PyResult<Record<'py>> {
    let rec = Record::new(py);
    rec.set("family", FAMILY)?.set("function", function.number())?;
    rec.set("time_s", report.duration.as_secs_f64())?;
    let mut rest = Vec::new();
    for (a, p) in &report.rest {
        let d = Record::new(py);
        d.set("actuator", a.number())?.set("position_counts", p.get())?;
        rest.push(d.done());
    }
    rec.set("rest", rest)?;
    Ok(rec)
}

/// A move's checked arguments: the actuator, the function named (if any), the speed.
type MoveArgs = (Actuator, Option<MotionFunction>, Speed);

fn move_args(actuator: u8, function: Option<u8>, speed: u32, mode: SpeedMode) -> Result<MoveArgs, Failure> {
    let a = self::actuator(actuator)?;
    let f = function
        .map(|n| MotionFunction::new(n).ok_or_else(|| usage(format!("function {n}: the motion functions are F1..F10"))))
        .transpose()?;
    let speed = Speed::parse(&speed.to_string(), mode).map_err(|e| usage(format!("speed {e}")))?;
    Ok((a, f, speed))
}

/// A run's checked arguments: the function, what to do, the time limit.
type RunArgs = (Function, RunAction, Option<Duration>);

fn run_args(function: &str, direction: &str, seconds: Option<f64>) -> Result<RunArgs, Failure> {
    let f = parse_function(function)?;
    let action = match f {
        Function::Motion(m) => RunAction::Motion(
            m,
            MotionDirection::parse(direction).ok_or_else(|| {
                usage(format!(
                    "{direction:?} is not a direction: in, out, mem1..mem4, int-in, int-out, remote, none, or 0..9"
                ))
            })?,
        ),
        f if direction.eq_ignore_ascii_case("on") => RunAction::Switch(f),
        f => return Err(usage(format!("{f} is switched with \"on\", not {direction:?}"))),
    };
    let limit = match seconds {
        None => None,
        Some(s) if s.is_finite() && (0.0..=86_400.0).contains(&s) => Some(Duration::from_secs_f64(s)),
        Some(s) => return Err(usage(format!("seconds {s}: give 0 .. 86400"))),
    };
    Ok((f, action, limit))
}

/// A session with an SCU control unit (the native half of `motionlink.Scu`).
#[pyclass(frozen, module = "motionlink._native")]
pub struct ScuClient {
    slot: Slot<Client>,
    token: CancelToken,
    port: String,
    speed_mode: SpeedMode,
    close_bound: Duration,
}

impl ScuClient {
    fn client(&self, py: Python<'_>) -> PyResult<Arc<Client>> {
        self.slot.get().map_err(|f| to_pyerr(py, f))
    }
}

fn cancel_cause<T>(py: Python<'_>, r: &Result<T, Error>) -> Option<PyErr> {
    r.as_ref().err().map(|e| to_pyerr(py, e.failure()))
}

#[pymethods]
impl ScuClient {
    #[new]
    fn py_new(py: Python<'_>, port: &Bound<'_, PyAny>, settings: Settings) -> PyResult<Self> {
        let t = target(port, FAMILY).map_err(|f| to_pyerr(py, f))?;
        let client = py.detach(|| open(t, &settings)).map_err(|f| to_pyerr(py, f))?;
        let port = client.port().to_string();
        let speed_mode = client.config().speed_mode;
        let close_bound = client.config().close_bound;
        Ok(ScuClient { slot: Slot::new(client, FAMILY), token: CancelToken::new(), port, speed_mode, close_bound })
    }

    /// The port, as the link describes it.
    #[getter]
    fn port(&self) -> String {
        self.port.clone()
    }

    /// True until closed.
    #[getter]
    fn is_open(&self) -> bool {
        self.slot.is_open()
    }

    /// Motion functions (numbers 1..10) this session started and has not seen stop.
    fn started(&self, py: Python<'_>) -> PyResult<Vec<u8>> {
        Ok(self.client(py)?.started_functions().into_iter().map(|f| f + 1).collect())
    }

    /// Firmware, configuration, battery/mains, last error and the connected actuators.
    fn info<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let c = self.client(py)?;
        let (firmware, configuration, mains, last_error, statuses, positions) = py
            .detach(|| -> Result<_, Error> {
                let get = |i: u16| c.get_value(DataIndex(i));
                Ok((get(0x0001)?, get(0x0002)?, get(0x0100)?, get(0x00D1)?, c.statuses()?, c.positions()?))
            })
            .or_raise(py)?;
        let r = Record::new(py);
        r.set("family", FAMILY)?.set("port", &self.port)?;
        r.set("firmware", value_py(py, &firmware)?)?.set("configuration", value_py(py, &configuration)?)?;
        r.set("battery_mains", value_py(py, &mains)?)?.set("last_error", error_code(py, &last_error)?)?;
        let mut acts = Vec::new();
        for (i, s) in statuses.iter().enumerate() {
            if !s.available() {
                continue;
            }
            let a = Record::new(py);
            a.set("actuator", i + 1)?.set("position_counts", positions[i].get())?;
            a.set("flags", status_flags(*s))?.set("moving", s.moving())?;
            acts.push(a.done());
        }
        r.set("actuators", acts)?;
        Ok(r.done())
    }

    /// The position of an actuator in counts.
    fn position(&self, py: Python<'_>, actuator: u8) -> PyResult<i32> {
        let c = self.client(py)?;
        let a = self::actuator(actuator).map_err(|f| to_pyerr(py, f))?;
        py.detach(|| c.position(a).map(PositionCounts::get)).or_raise(py)
    }

    /// Reads a data-list entry or group by name or index.
    fn get<'py>(&self, py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyDict>> {
        let c = self.client(py)?;
        let it = parse_item(name).map_err(|f| to_pyerr(py, f))?;
        let values = py.detach(|| c.get(it.index())).or_raise(py)?;
        let r = Record::new(py);
        r.set("family", FAMILY)?.set("name", it.name())?.set("id", it.index().0)?;
        match it {
            Item::Entry(e) => {
                let v = &values
                    .first()
                    .ok_or_else(|| {
                        to_pyerr(
                            py,
                            Failure::new(
                                motionlink_link::error::ErrorClass::Transport(
                                    motionlink_link::error::TransportKind::Corrupt,
                                ),
                                FAMILY,
                                format!("the unit's reply to {} is empty", e.name),
                            ),
                        )
                    })?
                    .1;
                r.set("value", value_py(py, v)?)?.set("unit", value_unit(v, e.unit))?;
                r.set("access", e.access.short())?;
            }
            Item::Group(_) => {
                let d = PyDict::new(py);
                for (e, v) in &values {
                    d.set_item(e.name, value_py(py, v)?)?;
                }
                r.set("value", d)?.set("unit", "")?.set("access", if it.is_writable() { "rw" } else { "r" })?;
            }
        }
        Ok(r.done())
    }

    /// Writes a remote data entry (0x3xxx); the library reads it back.
    fn set<'py>(&self, py: Python<'py>, name: &str, value: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyDict>> {
        let c = self.client(py)?;
        let it = parse_item(name).map_err(|f| to_pyerr(py, f))?;
        let Item::Entry(e) = it else {
            return Err(to_pyerr(py, usage(format!("{} is a group; set its entries one by one", it.name()))));
        };
        if value.is_instance_of::<pyo3::types::PyBool>() {
            return Err(to_pyerr(py, usage(format!("{}: give a number, not a bool", e.name))));
        }
        let text: String = value.str()?.extract()?;
        let v = Value::parse(e.kind, &text).map_err(|err| to_pyerr(py, usage(format!("{}: {err}", e.name))))?;
        py.detach(|| c.set(e.index(), &v)).or_raise(py)?;
        let r = Record::new(py);
        r.set("family", FAMILY)?.set("name", e.name)?.set("id", e.index().0)?;
        r.set("value", value_py(py, &v)?)?.set("unit", value_unit(&v, e.unit))?.set("access", e.access.short())?;
        // `set` succeeds only when the value read back equals the one written.
        r.set("read_back", value_py(py, &v)?)?;
        Ok(r.done())
    }

    /// A verified move of `actuator` to `target_counts` (Ctrl-C stops it).
    #[pyo3(signature = (actuator, target_counts, speed, function=None))]
    fn move_to<'py>(
        &self,
        py: Python<'py>,
        actuator: u8,
        target_counts: i32,
        speed: u32,
        function: Option<u8>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let c = self.client(py)?;
        let (a, f, speed) = move_args(actuator, function, speed, self.speed_mode).map_err(|f| to_pyerr(py, f))?;
        let token = &self.token;
        let r = interruptible(
            py,
            Some(token),
            || {
                c.move_to(
                    a,
                    PositionCounts(target_counts),
                    speed,
                    &MoveOptions { cancel: Some(token), progress: None, function: f },
                )
            },
            cancel_cause,
        )?;
        let report = r.or_raise(py)?;
        Ok(move_record(py, target_counts, &report)?.done())
    }

    /// Runs a function until it ends (or `seconds`, or Ctrl-C), then stops it; where the actuators rest.
    #[pyo3(signature = (function, direction, seconds=None))]
    fn run<'py>(
        &self,
        py: Python<'py>,
        function: &str,
        direction: &str,
        seconds: Option<f64>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let c = self.client(py)?;
        let (f, action, limit) = run_args(function, direction, seconds).map_err(|f| to_pyerr(py, f))?;
        let token = &self.token;
        let r = interruptible(py, Some(token), || c.run(action, limit, &|_| {}, Some(token)), cancel_cause)?;
        let report = r.or_raise(py)?;
        Ok(run_record(py, f, &report)?.done())
    }

    /// Stops a function (RS): a motion fast, or along its ramp with `soft`.
    #[pyo3(signature = (function, soft=false))]
    fn stop(&self, py: Python<'_>, function: &str, soft: bool) -> PyResult<()> {
        let c = self.client(py)?;
        let f = parse_function(function).map_err(|f| to_pyerr(py, f))?;
        py.detach(|| match f {
            Function::Motion(m) => c.stop_motion(m, if soft { StopMode::Soft } else { StopMode::Fast }),
            f => c.switch(f, false),
        })
        .or_raise(py)
    }

    /// One sample of `watch`: the connected actuators (position, moving, flags, current) and Error_Code 1.
    fn sample<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let c = self.client(py)?;
        let (positions, statuses, currents, last_error) = py
            .detach(|| -> Result<_, Error> {
                Ok((c.positions()?, c.statuses()?, c.get(DataIndex(0x00A0))?, c.get_value(DataIndex(0x00D1))?))
            })
            .or_raise(py)?;
        let r = Record::new(py);
        r.set("family", FAMILY)?;
        let mut acts = Vec::new();
        for (i, s) in statuses.iter().enumerate() {
            if !s.available() {
                continue;
            }
            let a = Record::new(py);
            a.set("actuator", i + 1)?.set("position_counts", positions[i].get())?;
            a.set("moving", s.moving())?.set("flags", status_flags(*s))?;
            let amps = currents.get(i).and_then(|(_, v)| v.as_f64());
            a.set("current_amps", amps)?;
            acts.push(a.done());
        }
        r.set("actuators", acts)?.set("last_error", error_code(py, &last_error)?)?;
        Ok(r.done())
    }

    /// The error history: Error_Code 1 (the last) .. 5, each with its named bits.
    fn errors<'py>(&self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyAny>>> {
        let c = self.client(py)?;
        let history = py.detach(|| c.error_history()).or_raise(py)?;
        history.iter().map(|code| error_code(py, &Value::ErrorCode(*code))).collect()
    }

    /// Ends the session: RS for every function it started, then RA; an exception if that was not confirmed.
    fn close(&self, py: Python<'_>) -> PyResult<()> {
        let bound = self.close_bound;
        let taken = py.detach(|| self.slot.take(&self.token, bound));
        match taken {
            None => Ok(()),
            Some(Ok(client)) => py.detach(|| client.close()).or_raise(py),
            // A call of another thread still runs: it was cancelled (its motion stops) and the session ends
            // (RS, RA) when it returns and drops the client.
            Some(Err(shared)) => {
                drop(shared);
                Ok(())
            }
        }
    }
}

impl Drop for ScuClient {
    fn drop(&mut self) {
        // Not closed by its owner (garbage-collected): the session ends here, stopping what it started as
        // the family's client does when dropped, without holding the GIL while it waits for the device.
        if let Some(taken) = self.slot.take(&self.token, self.close_bound) {
            Python::attach(|py| py.detach(move || drop(taken)));
        }
    }
}
