//! SCU control units from Python: the native half of `motionlink.Scu`. Every operation is one call of
//! `motionlink_scu::Client`; what stops an actuator (RS), the keepalive and how a move is verified are the
//! library's. Every argument is checked by the library's rule ([`motionlink_scu::args`], the same message as
//! the command line's), and every result is the library's report as it serialises (the command line's
//! `--json` names), converted to Python objects.

use std::sync::Arc;
use std::time::Duration;

use motionlink_link::cancel::CancelToken;
use motionlink_link::link::Connector;
use motionlink_link::url::PortUrl;
use motionlink_scu::args::{
    emulated_unit, parse_write, ArgumentError, Baud, Checked, PollInterval, ReplyTimeout, RunLimit, ToleranceCounts,
};
use motionlink_scu::model::{
    find, Actuator, Function, Item, MotionFunction, PositionCounts, SafetyId, Speed, SpeedMode, StopMode,
};
use motionlink_scu::results::{FunctionStop, RunOutcome, SampleReport, StopScope, Stopped, SwitchedOff};
use motionlink_scu::session::{MoveReport, RunAction, RunReport};
use motionlink_scu::{
    port_connector, AsyncClient, Client, Config, Error, FunctionMap, MoveOptions, Output, StrokeLimits,
};
use pyo3::prelude::*;

use crate::common::{json_py, opt_float, Bool, Float, Int, Slot, Text};
use crate::emulator::{clock, InProcess};
use crate::emulator::{target, Target};
use crate::errors::{to_pyerr, Failure, IntoFailure, OrRaise};
use crate::wait::{deliver, spawn_task, NativeTask};

const FAMILY: &str = "scu";

fn usage(msg: impl Into<String>) -> Failure {
    Failure::usage(FAMILY, msg)
}

/// A whole-number argument `v` (Python's `name`) checked by the library's `check`: the message is the
/// library's rule after the argument's name and value. A value that is no int (a bool, a str, a float) is
/// refused with the same rule, naming what was given.
fn whole<T>(
    v: &Int,
    name: &str,
    rule: &str,
    check: impl FnOnce(i64) -> Result<T, ArgumentError>,
) -> Result<T, Failure> {
    match v.within::<i64>(FAMILY, name, i64::MIN..=i64::MAX) {
        Ok(n) => check(n).map_err(|e| usage(format!("{name} {n}: {e}"))),
        // Not an int: the bindings' message names the value and its type ("True (a bool)"); the rule
        // replaces its range.
        Err(f) => {
            let shown = f.report.message.split(": give a whole number").next().unwrap_or(&f.report.message);
            Err(usage(format!("{shown}: {rule}")))
        }
    }
}

/// A whole-number argument of a type with its own rule ([`Checked`]).
fn checked<T: Checked>(v: &Int, name: &str) -> Result<T, Failure> {
    whole(v, name, T::RULE, T::checked)
}

/// A library argument error as a usage error, after what it is about.
fn bad(what: &str) -> impl Fn(ArgumentError) -> Failure + '_ {
    move |e| usage(if what.is_empty() { e.0 } else { format!("{what}: {e}") })
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
    speed_mode: Text,
    /// Send a break before opening (`motionlink scu --wake`): wakes a battery unit in low-power mode.
    #[pyo3(default)]
    wake: Option<Bool>,
    /// The device profiles: `"auto"` (default) profiles.toml beside devices.toml, `"off"`, or a path.
    #[pyo3(default)]
    profile: Option<String>,
}

/// The session's settings, each checked by the library's rule.
fn client_config(s: &Settings) -> Result<Config, Failure> {
    let config = Config {
        baud: checked::<Baud>(&s.baud, "baud")?,
        safety_id: checked::<SafetyId>(&s.safety, "safety")?,
        reply_timeout: checked::<ReplyTimeout>(&s.reply_timeout_ms, "reply_timeout_ms")?.get(),
        speed_mode: s.speed_mode.get(FAMILY, "speed_mode")?.parse::<SpeedMode>().map_err(bad("speed_mode"))?,
        function_map: FunctionMap::from_specs(&s.functions).map_err(|e| usage(format!("functions: {e}")))?,
        stroke_limits: StrokeLimits::per_actuator(&s.strokes).map_err(|e| usage(format!("strokes: {e}")))?,
        position_tolerance_counts: checked::<ToleranceCounts>(&s.tolerance_counts, "tolerance_counts")?.get(),
        poll_interval: checked::<PollInterval>(&s.poll_ms, "poll_ms")?.get(),
        wake_break: match &s.wake {
            Some(w) => w.get(FAMILY, "wake")?.then_some(motionlink_scu::config::WAKE_BREAK),
            None => None,
        },
        ..Config::default()
    };
    config.validate().map_err(|e| usage(e.to_string()))?;
    Ok(config)
}

/// How to reach the unit `port` names, and the session's settings. `port="sim"` emulates, in this process,
/// the unit the session is told it is (its function map and speed mode).
fn connector(port: Target, s: &Settings) -> Result<(Connector, Config), Failure> {
    let config = client_config(s)?;
    let connector: Connector = match port {
        Target::InProcess(InProcess::Scu(host)) => host.connector(),
        Target::InProcess(_) => return Err(usage("that emulator is not an SCU emulator")),
        Target::Url(PortUrl::Sim) => {
            let sim = emulated_unit(None, &s.functions, config.speed_mode).map_err(usage)?;
            let device = motionlink_scu::Emulator::new(sim).map_err(|e| usage(e.to_string()))?;
            let host =
                motionlink_link::pipe::EmulatorHost::new(device, clock(), motionlink_link::pipe::PipeConfig::instant());
            host.connector()
        }
        Target::Url(p) => port_connector(&p, &config).map_err(|e| e.failure())?,
    };
    Ok((connector, config))
}

fn open(port: Target, s: &Settings) -> Result<Client, Failure> {
    let (connector, config) = connector(port, s)?;
    Client::with_connector(connector, clock(), config).map_err(|e| e.failure())
}

fn actuator(n: &Int) -> Result<Actuator, Failure> {
    checked(n, "actuator")
}

fn parse_item(text: &str) -> Result<Item, Failure> {
    find(text).map_err(|e| usage(e.to_string()))
}

fn parse_function(text: &str) -> Result<Function, Failure> {
    text.parse::<Function>().map_err(bad(""))
}

/// A report as Python gets it: the library's serialisation (the command line's `--json` object, without
/// `port`), with `family`; `extra` adds what Python shows besides (attributes left out of `to_dict()`, named
/// in `_extras`), converted as `json.loads` would.
fn report_py<'py, T: serde::Serialize>(
    py: Python<'py>,
    report: &T,
    extra: impl FnOnce(&mut serde_json::Map<String, serde_json::Value>),
) -> PyResult<Bound<'py, PyAny>> {
    let mut fields = match crate::common::report_value(report)? {
        serde_json::Value::Object(fields) => fields,
        other => return json_py(py, &other),
    };
    fields.insert("family".into(), FAMILY.into());
    extra(&mut fields);
    json_py(py, &serde_json::Value::Object(fields))
}

/// A move as the CLI's `scu move --json` reports it; where each actuator started is an attribute besides
/// (`start_counts`, not in `to_dict()`).
pub(crate) fn move_py<'py>(py: Python<'py>, report: &MoveReport) -> PyResult<Bound<'py, PyAny>> {
    report_py(py, report, |fields| {
        if let Some(serde_json::Value::Array(list)) = fields.get_mut("actuators") {
            for (one, o) in list.iter_mut().zip(&report.actuators) {
                one["start_counts"] = o.start_counts.get().into();
                one["_extras"] = serde_json::json!(["start_counts"]);
            }
        }
    })
}

/// A run as the CLI's `scu run --json` reports it; how long it ran is an attribute besides (`time_s`).
pub(crate) fn run_py<'py>(py: Python<'py>, report: &RunReport) -> PyResult<Bound<'py, PyAny>> {
    report_py(py, &RunOutcome::from(report), |fields| {
        fields.insert("time_s".into(), report.duration.as_secs_f64().into());
        fields.insert("_extras".into(), serde_json::json!(["time_s"]));
    })
}

/// A move's checked arguments: the actuator, the target, the function named (if any), the speed.
type MoveArgs = (Actuator, PositionCounts, Option<MotionFunction>, Speed);

fn move_args(
    actuator: &Int,
    target_counts: &Int,
    function: Option<&Int>,
    speed: &Int,
    mode: SpeedMode,
) -> Result<MoveArgs, Failure> {
    let a = self::actuator(actuator)?;
    let target = checked::<PositionCounts>(target_counts, "target_counts")?;
    let f = function.map(|f| checked::<MotionFunction>(f, "function")).transpose()?;
    let speed = whole(speed, "speed", &Speed::rule(mode), |n| Speed::checked(n, mode))?;
    Ok((a, target, f, speed))
}

/// A run's checked arguments: the function and what to do, and the time limit.
fn run_args(
    function: &str,
    direction: &Text,
    seconds: Option<&Float>,
) -> Result<(RunAction, Option<Duration>), Failure> {
    let action = RunAction::parse(function, direction.get(FAMILY, "direction")?).map_err(bad(""))?;
    let seconds = opt_float(seconds, FAMILY, "seconds")?;
    let limit = seconds.map(|s| RunLimit::seconds(s).map_err(|e| usage(format!("seconds {s}: {e}")))).transpose()?;
    Ok((action, limit.map(RunLimit::get)))
}

/// What `stop` stops, as `motionlink scu stop [FUNCTION] [--soft]` does: the function named (`None`: every
/// motion function), its scope (motion functions: RS, then the status until no actuator moves; another
/// function: RS), and how a motion stops.
fn stop_what(function: Option<&str>, soft: &Bool) -> Result<(Option<Function>, StopScope, StopMode), Failure> {
    let mode = if soft.get(FAMILY, "soft")? { StopMode::Soft } else { StopMode::Fast };
    let function = function.map(parse_function).transpose()?;
    Ok((function, StopScope::of(function), mode))
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

/// An async session with an SCU (the native half of `motionlink.AsyncScu`): the operations run on the
/// library's runtime; cancelling a move's or a run's task drops its future, which stops the function
/// (fast RS, confirmed).
#[pyclass(frozen, module = "motionlink._native")]
pub struct AsyncScuClient {
    slot: Slot<AsyncClient>,
    port: String,
    speed_mode: SpeedMode,
    profile: crate::common::ProfileUse,
}

impl crate::faces::Closing for ScuClient {}

/// Function numbers (1..10), as `started()` names them.
fn numbers(functions: Vec<Function>) -> Vec<u8> {
    functions.into_iter().map(|f| f.number()).collect()
}

impl crate::session::Session for Client {
    fn started_ids(&self) -> Vec<u8> {
        numbers(self.started())
    }

    fn end(self) -> Result<Vec<u8>, Failure> {
        self.close().map(numbers).map_err(|e| e.failure())
    }

    /// The call under way was cancelled (its motion stops) and the session ends (RS, RA) when it returns
    /// and drops the client: the functions it stops.
    fn end_shared(shared: Arc<Self>) -> Result<Vec<u8>, Failure> {
        Ok(numbers(shared.started()))
    }
}

impl crate::session::AsyncSession for AsyncClient {
    fn started_ids(&self) -> Vec<u8> {
        numbers(self.started())
    }

    async fn end(self) -> Result<Vec<u8>, Failure> {
        self.close().await.map(numbers).map_err(|e| e.failure())
    }

    async fn end_shared(shared: Arc<Self>) -> Result<Vec<u8>, Failure> {
        Ok(numbers(shared.started()))
    }
}

faces! {
    ScuClient / AsyncScuClient, Error;

    both {}

    blocking {
        #[new]
        fn py_new(py: Python<'_>, port: &Bound<'_, PyAny>, settings: Settings) -> PyResult<Self> {
            let t = target(port, FAMILY).map_err(|f| to_pyerr(py, f))?;
            let port_url = t.profile_port();
            let baud: u32 = checked::<Baud>(&settings.baud, "baud").map_err(|f| to_pyerr(py, f))?.get();
            let (client, profile) = py
                .detach(|| {
                    let client = open(t, &settings)?;
                    let used = match crate::common::profile_lookup(settings.profile.as_deref(), port_url.as_deref()) {
                        Ok((p, port)) => {
                            motionlink_scu::probe::use_profile(&client, &p, &port).map_err(|e| e.failure())?
                        }
                        Err(used) => used,
                    };
                    Ok::<_, Failure>((client, used))
                })
                .map_err(|f| to_pyerr(py, f))?;
            let port = client.port().to_string();
            let speed_mode = client.config().speed_mode;
            let close_bound = client.config().close_bound;
            let token = CancelToken::new();
            client.set_cancel(token.clone());
            let slot = Slot::new(client, FAMILY);
            Ok(ScuClient { slot, token, port, speed_mode, close_bound, port_url, baud, profile })
        }

        /// `motionlink probe scu`'s report of this unit, as a dict (nothing moves); with `save` (`""`: the
        /// default profiles file, else a path) its profile is written.
        fn probe<'py>(
            &self,
            py: Python<'py>,
            exchanges: Int,
            low_latency: Bool,
            save: Option<String>,
        ) -> PyResult<Bound<'py, PyAny>> {
            let client = self.slot.client(py)?;
            let setup =
                crate::common::probe_setup(FAMILY, self.port_url.as_deref(), self.baud, &exchanges, &low_latency)
                    .map_err(|f| to_pyerr(py, f))?;
            let probe = || motionlink_scu::probe::probe(&client, &setup).map_err(|e| e.failure());
            crate::common::probe_py(py, FAMILY, self.port_url.as_deref(), save, probe, motionlink_scu::probe::save_profile)
        }
    }

    asynch {
        /// Opens a session on the runtime: `done(ok, client)`.
        #[staticmethod]
        fn open(py: Python<'_>, port: &Bound<'_, PyAny>, settings: Settings, done: Py<PyAny>) -> PyResult<NativeTask> {
            let t = target(port, FAMILY).map_err(|f| to_pyerr(py, f))?;
            let lookup = crate::common::profile_lookup(settings.profile.as_deref(), t.profile_port().as_deref());
            let (connector, config) = connector(t, &settings).map_err(|f| to_pyerr(py, f))?;
            Ok(spawn_task(done, async move {
                let client = AsyncClient::with_connector(connector, clock(), config).await.map_err(|e| e.failure())?;
                let profile = match lookup {
                    Ok((p, port)) => {
                        motionlink_scu::probe::use_profile_async(&client, &p, &port).await.map_err(|e| e.failure())?
                    }
                    Err(used) => used,
                };
                let port = client.port().to_string();
                let speed_mode = client.config().speed_mode;
                let native = AsyncScuClient { slot: Slot::new(client, FAMILY), port, speed_mode, profile };
                deliver(move |py| Ok(Py::new(py, native)?.into_any()))
            }))
        }
    }

    /// Firmware, configuration, battery/mains, last error and the connected actuators (Ctrl-C raises at
    /// once: nothing is in motion).
    blocking read info(me, py) {} |c| { c.info() } => |py, info| {
        report_py(py, &info, |fields| {
            fields.insert("port".into(), me.port.clone().into());
        })
    };

    /// Reads a data-list entry or group by name or index.
    blocking read get(me, py, name: String) {
        let it = parse_item(&name).map_err(|f| to_pyerr(py, f))?;
    } |c| { c.read(it) } => |py, read| report_py(py, &read, |_| {});

    /// Writes a remote data entry (0x3xxx); the library reads it back and compares, then reads what the unit
    /// holds (`read_back`; None, with `verified` False and why, on a unit that does not read remote data back).
    blocking quick set(me, py, name: String, value: Bound<'_, PyAny>) {
        let it = parse_item(&name).map_err(|f| to_pyerr(py, f))?;
        if value.is_instance_of::<pyo3::types::PyBool>() {
            return Err(to_pyerr(py, usage(format!("{}: give a number, not a bool", it.name()))));
        };
        let text = value.str()?.extract::<String>()?;
        let (entry, v) = parse_write(it, &text).map_err(|e| to_pyerr(py, bad("")(e)))?;
    } |c| { c.write(entry, v) } => |py, written| report_py(py, &written, |_| {});

    /// One sample of `watch`, `t_s` into it: the connected actuators (position, moving, flags, current) and
    /// Error_Code 1. The library's sample: through the keepalive RC where the unit takes the session's cyclic
    /// object.
    blocking read sample(me, py, t_s: f64) {} |c| { c.sample() }
    => |py, s| report_py(py, &SampleReport::new(&s, t_s), |_| {});

    /// The error history: Error_Code 1 (the last) .. 5, each with its named bits.
    blocking read errors(me, py) {} |c| { c.error_history() } => |py, history| report_py(py, &history, |_| {});

    /// The position of an actuator in counts.
    quick position(me, py, actuator: Int) {
        let a = self::actuator(&actuator).map_err(|f| to_pyerr(py, f))?;
    } |c| { w!(c.position(a)) } => |py, p| Ok(p.get());

    /// A verified move of `actuator` to `target_counts`; Ctrl-C, or cancelling the task, stops the function.
    motion move_to(me, py, actuator: Int, target_counts: Int, speed: Int, function: Option<Int>) {
        let (a, target, f, speed) = move_args(&actuator, &target_counts, function.as_ref(), &speed, me.speed_mode)
            .map_err(|f| to_pyerr(py, f))?;
    } |c| {
        w!(c.move_to(a, target, speed, &MoveOptions { progress: None, function: f });
            async c.start(c.move_to_op(a, target, speed, f)?) => Output::Move)
    } => |py, r| move_py(py, &r);

    /// Runs a function until it ends (or `seconds`), then stops it; where the actuators rest. Ctrl-C, or
    /// cancelling the task, stops it.
    motion run(me, py, function: String, direction: Text, seconds: Option<Float>) {
        let (action, limit) = run_args(&function, &direction, seconds.as_ref()).map_err(|f| to_pyerr(py, f))?;
    } |c| {
        w!(c.run_function(action, limit, &|_| {});
            async c.start(c.run_function_op(action, limit)?) => Output::Run)
    } => |py, r| run_py(py, &r);

    /// Stops what moves, as `motionlink scu stop` does: RS to the motion function named, or with no function
    /// to every one (F1..F10), fast or along the stop ramp (`soft`), confirmed by the status read until no
    /// actuator moves: the stop report, with where each connected actuator rests. Another function named
    /// (F11..F22) is switched off with RS and its status read back: `{function, mode: "off", verified,
    /// not_verifiable}`.
    quick stop(me, py, function: Option<String>, soft: Bool) {
        let (function, scope, mode) = stop_what(function.as_deref(), &soft).map_err(|f| to_pyerr(py, f))?;
    } |c| {
        match scope {
            StopScope::Motions(all) => w!(c.stop_functions(&all, mode)).map(Stopped::Motions),
            StopScope::Switch(f) => w!(c.switch(f, false)).map(|r| Stopped::Switch(SwitchedOff::from(r))),
        }
    } => |py, report| report_py(py, &FunctionStop { function, report }, |_| {});
}
