//! SCU control units from Python: the native half of `motionlink.Scu`. Every operation is one call of
//! `motionlink_scu::Client`; what stops an actuator (RS), the keepalive and how a move is verified are the
//! library's.

mod asyncio;
pub use asyncio::AsyncScuClient;

use std::sync::Arc;
use std::time::Duration;

use motionlink_link::cancel::CancelToken;
use motionlink_link::flags::FlagWord;
use motionlink_link::link::{Connector, Link, SerialSettings};
use motionlink_link::url::PortUrl;
use motionlink_scu::model::{
    lookup, Actuator, ActuatorStatus1, DataEntryExt, DataIndex, ErrorCode, Function, Item, MotionDirection,
    MotionFunction, PositionCounts, SafetyId, Speed, SpeedMode, StopMode,
};
use motionlink_scu::session::{MoveReport, RunAction, RunReport};
use motionlink_scu::value::Value;
use motionlink_scu::{AsyncClient, Client, ClientConfig, Error, FunctionMap, MoveOptions, SimConfig, StrokeLimits};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::common::{json_py, opt_within, target, Int, Record, Slot, Target};
use crate::emulator::{clock, InProcess};
use crate::errors::{to_pyerr, Failure, IntoFailure, OrRaise};
use crate::wait::{block_on_runtime, deliver, interruptible, interruptible_read, spawn_task, NativeTask};

const FAMILY: &str = "scu";

fn usage(msg: impl Into<String>) -> Failure {
    Failure::usage(FAMILY, msg)
}

/// How an SCU client is opened, as `motionlink.Scu` passes it.
#[derive(FromPyObject)]
#[pyo3(from_item_all)]
pub struct Settings {
    baud: Int,
    safety: Int,
    reply_timeout_ms: Int,
    functions: Vec<String>,
    strokes: Vec<String>,
    tolerance_counts: Int,
    poll_ms: Int,
    speed_mode: String,
    /// The device profiles: `"auto"` (default) profiles.toml beside devices.toml, `"off"`, or a path.
    #[pyo3(default)]
    profile: Option<String>,
}

fn client_config(s: &Settings) -> Result<ClientConfig, Failure> {
    let safety_id = match s.safety.within::<u8>(FAMILY, "safety (the Safety_ID)", 0..=2)? {
        0 => SafetyId::StopAllAndLock,
        1 => SafetyId::StopAll,
        _ => SafetyId::StopRemoteOnly,
    };
    let baud: u32 = s.baud.within(FAMILY, "baud", 1..=4_000_000)?;
    if ![9_600, 19_200, 38_400].contains(&baud) {
        return Err(usage(format!("baud {baud}: an SCU runs at 9600, 19200 or 38400 baud")));
    }
    let reply_timeout_ms: u64 = s.reply_timeout_ms.within(FAMILY, "reply_timeout_ms", 1..=60_000)?;
    let poll_ms: u64 = s.poll_ms.within(FAMILY, "poll_ms", 5..=10_000)?;
    let tolerance_counts: u32 = s.tolerance_counts.within(FAMILY, "tolerance_counts", 0..=1_000_000)?;
    let speed_mode = match s.speed_mode.as_str() {
        "percent" => SpeedMode::Percent,
        "counts_per_s" => SpeedMode::CountsPerSecond,
        other => return Err(usage(format!("speed_mode {other:?}: give \"percent\" or \"counts_per_s\""))),
    };
    let function_map = function_map(&s.functions)?;
    let mut stroke_limits = [None; 6];
    for spec in &s.strokes {
        let (a, limits) = StrokeLimits::parse_for_actuator(spec).map_err(|e| usage(format!("strokes: {e}")))?;
        stroke_limits[usize::from(a.number() - 1)] = Some(limits);
    }
    let config = ClientConfig {
        safety_id,
        reply_timeout: Duration::from_millis(reply_timeout_ms),
        speed_mode,
        function_map,
        stroke_limits,
        position_tolerance_counts: tolerance_counts,
        poll_interval: Duration::from_millis(poll_ms),
        ..ClientConfig::default()
    };
    config.validate().map_err(|e| usage(e.to_string()))?;
    Ok(config)
}

/// The function map the specifications give, applied in order as the command line's repeated
/// `--functions`: a preset replaces the whole map, `F1=1,2` sets one function.
fn function_map(specs: &[String]) -> Result<FunctionMap, Failure> {
    specs.iter().try_fold(FunctionMap::unknown(), |map, spec| {
        map.apply(spec).map_err(|e| {
            if spec.contains('=') {
                usage(format!("functions: {e}"))
            } else {
                // Not a function's specification: a preset name, then, and the presets are the emulator's.
                usage(format!(
                    "functions: {spec:?}: give a preset ({}) or a function and its actuators (\"F1=1,2\")",
                    SimConfig::PRESETS.join(", ")
                ))
            }
        })
    })
}

/// The unit that `port="sim"` emulates in this process, parameterised as the session was told the unit
/// is: its speed mode, and its function map (the last preset the specifications name, then the functions
/// they set one by one; with none, the emulator's default, SCP11).
fn sim_config(specs: &[String], speed_mode: SpeedMode) -> Result<SimConfig, Failure> {
    let mut sim = SimConfig::default();
    for spec in specs {
        let spec = spec.trim();
        if let Some(preset) = SimConfig::preset(&spec.to_ascii_lowercase()) {
            sim = preset;
            continue;
        }
        // A function's specification: what it sets, read by the library's own rule.
        let set = function_map(&[spec.to_string()])?;
        for n in 1..=10 {
            let Some(f) = MotionFunction::new(n) else { continue };
            if let Some(drives) = set.drives(f) {
                let needed = drives.iter().map(|a| usize::from(a.number())).max().unwrap_or(0);
                if needed > sim.actuators.len() {
                    sim.actuators.resize(needed, Default::default());
                }
                sim.functions[usize::from(f.id())] = drives;
            }
        }
    }
    sim.speed_mode = speed_mode;
    sim.validate().map_err(|e| usage(e.to_string()))?;
    Ok(sim)
}

/// How to reach the unit `port` names, and the session's settings.
fn connector(port: Target, s: &Settings) -> Result<(Connector, ClientConfig), Failure> {
    let config = client_config(s)?;
    let connector: Connector = match port {
        Target::InProcess(InProcess::Scu(host)) => Box::new(move || Ok(Box::new(host.connect().0) as Box<dyn Link>)),
        Target::InProcess(_) => return Err(usage("that emulator is not an SCU emulator")),
        Target::Url(PortUrl::Sim) => {
            let sim = sim_config(&s.functions, config.speed_mode)?;
            let device = motionlink_scu::Emulator::new(sim).map_err(|e| usage(e.to_string()))?;
            let host =
                motionlink_link::pipe::EmulatorHost::new(device, clock(), motionlink_link::pipe::PipeConfig::instant());
            Box::new(move || Ok(Box::new(host.connect().0) as Box<dyn Link>))
        }
        Target::Url(p) if p.is_can() => return Err(usage(format!("{p}: the SCU speaks RS232, not CAN"))),
        Target::Url(p) => {
            let settings = SerialSettings::new(s.baud.within(FAMILY, "baud", 1..=4_000_000)?);
            Box::new(move || p.open_byte_link(settings))
        }
    };
    Ok((connector, config))
}

fn open(port: Target, s: &Settings) -> Result<Client, Failure> {
    let (connector, config) = connector(port, s)?;
    Client::open(connector, clock(), config).map_err(|e| e.failure())
}

fn actuator(n: &Int) -> Result<Actuator, Failure> {
    let n = n.within(FAMILY, "actuator", 1..=6)?;
    Actuator::new(n).ok_or_else(|| usage(format!("actuator {n}: actuators are 1..6")))
}

/// The index of the data-list entry or group the library's table names `name`.
fn named(name: &str) -> Result<DataIndex, Failure> {
    lookup(name).map(|it| it.index()).ok_or_else(|| {
        Failure::new(
            motionlink_link::error::ErrorClass::Usage,
            FAMILY,
            format!("the library's data list has no entry {name:?}"),
        )
    })
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

/// A value in Python: numbers in the entry's unit as `unit` names it (deci-amps become amps, centi-volts
/// volts), bit sets and error codes as dicts.
fn value_py<'py>(py: Python<'py>, v: &Value) -> PyResult<Bound<'py, PyAny>> {
    match v {
        Value::CurrentDeciAmps(_) | Value::BatteryDeciVolts(_) | Value::AnalogueCentiVolts(_) => {
            Ok(v.as_f64().unwrap_or(f64::NAN).into_pyobject(py)?.into_any())
        }
        // A flag word as naming.md spells it: the raw word, the names of the bits set, and the bits no
        // name covers (only when nonzero).
        Value::Flags(f) => {
            let known = f.set.bits().into_iter().fold(0u32, |m, b| m | (1 << b.bit));
            let d = PyDict::new(py);
            d.set_item("word", f.bits)?;
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

fn error_code<'py>(py: Python<'py>, code: ErrorCode) -> PyResult<Bound<'py, PyAny>> {
    json_py(py, &Value::ErrorCode(code).to_json())
}

/// An actuator's status 1 as `info` and `watch` report it: the flags set and whether it moves.
fn status_fields(r: &Record<'_>, s: ActuatorStatus1) -> PyResult<()> {
    r.set("word", s.bits())?.set("flags", s.names())?.set("moving", s.moving())?;
    Ok(())
}

/// A move as the CLI's `scu move --json` reports it (`start_counts` of each actuator is an extra attribute).
pub(crate) fn move_record<'py>(py: Python<'py>, target_counts: i32, report: &MoveReport) -> PyResult<Record<'py>> {
    let rec = Record::new(py);
    rec.set("family", FAMILY)?.set("function", report.function.number())?;
    rec.set("actuator", report.actuator.number())?.set("target_counts", target_counts)?;
    rec.set("reached_counts", report.position_counts.get())?.set("time_s", report.duration.as_secs_f64())?;
    rec.set("difference_counts", i64::from(report.position_counts.get()) - i64::from(target_counts))?;
    let mut acts = Vec::new();
    for o in &report.actuators {
        let d = Record::new(py);
        d.set("actuator", o.actuator.number())?.set("target_counts", o.target_counts.get())?;
        d.set("start_counts", o.start_counts.get())?.set("reached_counts", o.position_counts.get())?;
        d.set("difference_counts", o.difference_counts())?.set("moved", o.moved)?;
        d.extras(&["start_counts"])?;
        acts.push(d.done());
    }
    rec.set("actuators", acts)?;
    rec.set("verified", report.verified)?.set("not_verifiable", report.not_verifiable.clone())?;
    Ok(rec)
}

/// A run as the CLI's `scu run --json` reports it: stopped, and where the actuators came to rest.
pub(crate) fn run_record<'py>(py: Python<'py>, function: Function, report: &RunReport) -> PyResult<Record<'py>> {
    let rec = Record::new(py);
    rec.set("family", FAMILY)?.set("function", function.number())?;
    rec.set("stopped", true)?.set("interrupted", false)?.set("time_s", report.duration.as_secs_f64())?;
    let mut rest = Vec::new();
    for (a, p) in &report.rest {
        let d = Record::new(py);
        d.set("actuator", a.number())?.set("reached_counts", p.get())?;
        rest.push(d.done());
    }
    rec.set("actuators", rest)?.extras(&["time_s"])?;
    Ok(rec)
}

/// A move's checked arguments: the actuator, the function named (if any), the speed.
type MoveArgs = (Actuator, Option<MotionFunction>, Speed);

fn move_args(actuator: &Int, function: Option<&Int>, speed: &Int, mode: SpeedMode) -> Result<MoveArgs, Failure> {
    let a = self::actuator(actuator)?;
    let f = opt_within::<u8>(function, FAMILY, "function (a motion function)", 1..=10)?
        .map(|n| MotionFunction::new(n).ok_or_else(|| usage(format!("function {n}: the motion functions are F1..F10"))))
        .transpose()?;
    let speed: u16 = speed.within(FAMILY, &format!("speed ({})", mode.unit()), 1..=i64::from(mode.max()))?;
    let speed = Speed::parse(&speed.to_string(), mode).map_err(|e| usage(format!("speed {e}")))?;
    Ok((a, f, speed))
}

/// A move's target in counts, checked.
fn target_counts(t: &Int) -> Result<i32, Failure> {
    t.within(FAMILY, "target_counts", i64::from(i32::MIN)..=i64::from(i32::MAX))
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
    /// The port as given (a URL), for profiles and probes; `None` for an emulator in this process.
    port_url: Option<String>,
    baud: u32,
    profile: crate::common::ProfileUse,
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
        let port_url = match &t {
            crate::common::Target::Url(u) => Some(u.to_string()),
            crate::common::Target::InProcess(_) => None,
        };
        let baud: u32 = settings.baud.within(FAMILY, "baud", 1..=4_000_000).map_err(|f| to_pyerr(py, f))?;
        let (client, profile) = py
            .detach(|| {
                let client = open(t, &settings)?;
                let used = crate::common::use_profile(settings.profile.as_deref(), port_url.as_deref(), |p, port| {
                    motionlink_scu::probe::use_profile(&client, p, port).map_err(|e| e.failure())
                })?;
                Ok::<_, Failure>((client, used))
            })
            .map_err(|f| to_pyerr(py, f))?;
        let port = client.port().to_string();
        let speed_mode = client.config().speed_mode;
        let close_bound = client.config().close_bound;
        let slot = Slot::new(client, FAMILY);
        Ok(ScuClient { slot, token: CancelToken::new(), port, speed_mode, close_bound, port_url, baud, profile })
    }

    /// The device profile the session took (`<path>#<key>`), or None.
    #[getter]
    fn profile(&self) -> Option<String> {
        self.profile.reference.clone()
    }

    /// One line for each profile the session did not take (another identity, a file it could not read).
    #[getter]
    fn profile_notices(&self) -> Vec<String> {
        self.profile.notices.clone()
    }

    /// `motionlink probe scu`'s report of this unit, as a dict (nothing moves); with `save` (`""`: the
    /// default profiles file, else a path) its profile is written.
    fn probe<'py>(
        &self,
        py: Python<'py>,
        exchanges: u32,
        low_latency: bool,
        save: Option<String>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let client = self.client(py)?;
        let setup = crate::common::probe_setup(self.port_url.as_deref(), self.baud, exchanges, low_latency);
        let report = py
            .detach(|| {
                let mut report = motionlink_scu::probe::probe(&client, &setup).map_err(|e| e.failure())?;
                if let Some(save) = save {
                    let mut profiles = crate::common::profiles_for_save(FAMILY, &save)?;
                    motionlink_scu::probe::save_profile(&mut report, &mut profiles)
                        .map_err(|e| usage(format!("save: {e}")))?;
                }
                serde_json::to_value(&report).map_err(|e| usage(e.to_string()))
            })
            .map_err(|f| to_pyerr(py, f))?;
        json_py(py, &report)
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

    /// Firmware, configuration, battery/mains, last error and the connected actuators (Ctrl-C raises at
    /// once: nothing is in motion).
    fn info<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let c = self.client(py)?;
        let (info, mains, history, statuses, positions) =
            interruptible_read(py, None, move || -> Result<_, Failure> {
                let fail = |e: Error| e.failure();
                let info = c.get(named("info")?).map_err(fail)?;
                let mains = c.get_value(named("battery_mains")?).map_err(fail)?;
                Ok((
                    info,
                    mains,
                    c.error_history().map_err(fail)?,
                    c.statuses().map_err(fail)?,
                    c.positions().map_err(fail)?,
                ))
            })?
            .or_raise(py)?;
        let r = Record::new(py);
        r.set("family", FAMILY)?.set("port", &self.port)?;
        for (e, v) in &info {
            let key = e.name.strip_suffix("_info").unwrap_or(e.name);
            r.set(key, value_py(py, v)?)?;
        }
        r.set("battery_mains", value_py(py, &mains)?)?.set("last_error", error_code(py, history[0])?)?;
        let mut acts = Vec::new();
        for a in Actuator::all() {
            let i = usize::from(a.number() - 1);
            let s = statuses[i];
            if !s.available() {
                continue;
            }
            let d = Record::new(py);
            d.set("actuator", a.number())?.set("position_counts", positions[i].get())?;
            status_fields(&d, s)?;
            acts.push(d.done());
        }
        r.set("actuators", acts)?;
        Ok(r.done())
    }

    /// The position of an actuator in counts.
    fn position(&self, py: Python<'_>, actuator: Int) -> PyResult<i32> {
        let c = self.client(py)?;
        let a = self::actuator(&actuator).map_err(|f| to_pyerr(py, f))?;
        py.detach(|| c.position(a).map(PositionCounts::get)).or_raise(py)
    }

    /// Reads a data-list entry or group by name or index.
    fn get<'py>(&self, py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyDict>> {
        let c = self.client(py)?;
        let it = parse_item(name).map_err(|f| to_pyerr(py, f))?;
        let index = it.index();
        let values = interruptible_read(py, None, move || c.get(index))?.or_raise(py)?;
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
        // The library writes and compares what it reads back (a difference is an error); the value read back
        // is then read once more, so that `read_back` is what the unit holds, not an echo of `value`.
        // A unit that does not read remote data back: `read_back` is None and `verified` False, with why.
        let (written, back) = py
            .detach(|| {
                let written = c.set(e.index(), &v)?;
                let back = if written.verified { Some(c.get_value(e.index())?) } else { None };
                Ok::<_, Error>((written, back))
            })
            .or_raise(py)?;
        let r = Record::new(py);
        r.set("family", FAMILY)?.set("name", e.name)?.set("id", e.index().0)?;
        r.set("value", value_py(py, &v)?)?.set("unit", value_unit(&v, e.unit))?.set("access", e.access.short())?;
        let back = back.as_ref().map(|b| value_py(py, b)).transpose()?;
        r.set("read_back", back)?.set("verified", written.verified)?.set("not_verifiable", written.not_verifiable)?;
        Ok(r.done())
    }

    /// A verified move of `actuator` to `target_counts` (Ctrl-C stops it).
    #[pyo3(signature = (actuator, target_counts, speed, function=None))]
    fn move_to<'py>(
        &self,
        py: Python<'py>,
        actuator: Int,
        target_counts: Int,
        speed: Int,
        function: Option<Int>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let c = self.client(py)?;
        let (a, f, speed) =
            move_args(&actuator, function.as_ref(), &speed, self.speed_mode).map_err(|f| to_pyerr(py, f))?;
        let target_counts = self::target_counts(&target_counts).map_err(|f| to_pyerr(py, f))?;
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
        // The library's sample: through the keepalive RC where the unit takes the session's cyclic object.
        let s = interruptible_read(py, None, move || c.sample())?.or_raise(py)?;
        let r = Record::new(py);
        r.set("family", FAMILY)?;
        let mut acts = Vec::new();
        for a in Actuator::all() {
            let i = usize::from(a.number() - 1);
            if !s.status(a).available() {
                continue;
            }
            let d = Record::new(py);
            d.set("actuator", a.number())?.set("position_counts", s.position(a).get())?;
            status_fields(&d, s.status(a))?;
            // The library's value in amperes (its data list holds deci-amps; `as_f64` converts them once).
            d.set("current_amps", Value::CurrentDeciAmps(s.currents_deci_amps[i]).as_f64())?;
            acts.push(d.done());
        }
        r.set("actuators", acts)?.set("last_error", error_code(py, s.last_error)?)?;
        Ok(r.done())
    }

    /// The error history: Error_Code 1 (the last) .. 5, each with its named bits.
    fn errors<'py>(&self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyAny>>> {
        let c = self.client(py)?;
        let history = interruptible_read(py, None, move || c.error_history())?.or_raise(py)?;
        history.iter().map(|code| error_code(py, *code)).collect()
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
