//! PowerCube modules from Python: the native half of `motionlink.PowerCube` (blocking) and
//! `motionlink.AsyncPowerCube` (asyncio). Every operation is one call of the family's `Client` /
//! `AsyncClient`; what stops a module and when its watchdog is armed are the library's.

mod records;
use records::*;

use std::sync::Arc;
use std::time::Duration;

use motionlink_link::cancel::CancelToken;
use motionlink_powercube::args::{
    Baud, CanBitRate, MotionTimeout, MoveAcceleration, MoveVelocity, PollInterval, ReplyTimeout, Target as MoveTarget,
    Tolerance,
};
use motionlink_powercube::client::{
    Client, Config, Guard, HaltReport, HomeReport, ModulesAt, MotionReport, MotionSpec, MoveReport, MoveSpec, PortLink,
    SetpointReport,
};
use motionlink_powercube::model::{
    AckKind, Address, AxisUnit, CubeState, ModuleKind, Motion, MotionId, Param, Position, Value,
};
use motionlink_powercube::report::{ParamReading, SetReport};
use motionlink_powercube::session::{Op, Output};
use motionlink_powercube::{AsyncClient, Error};
use pyo3::prelude::*;

use crate::common::{f32_py, opt_float, opt_within, Bool, Float, Int, Record, Slot, Text};
use crate::emulator::{clock, InProcess};
use crate::emulator::{target, Target};
use crate::errors::{to_pyerr, Failure, IntoFailure, OrRaise};
use crate::wait::{deliver, spawn_task, NativeTask};

const FAMILY: &str = "powercube";

/// How a PowerCube client is opened, as `motionlink.PowerCube` passes it.
#[derive(FromPyObject)]
#[pyo3(from_item_all)]
pub struct Settings {
    module: Int,
    baud: Int,
    bitrate: Int,
    timeout_ms: Option<Int>,
    poll_ms: Int,
    watchdog: Bool,
    /// The device profiles: `"auto"` (default) profiles.toml beside devices.toml, `"off"`, or a path.
    #[pyo3(default)]
    profile: Option<String>,
}

/// The decimal text of the integer argument `i`, for the library's parser of the argument (one rule, one
/// message, the command line's). Something that is no `int` (or an `int` wider than 64 bits) is refused
/// here, naming `name` and its `range`.
fn int_text(i: &Int, name: &str, range: std::ops::RangeInclusive<i64>) -> Result<String, Failure> {
    match i.within::<i64>(FAMILY, name, i64::MIN..=i64::MAX) {
        Ok(n) => Ok(n.to_string()),
        Err(_) => Err(i.within::<i64>(FAMILY, name, range).err().unwrap_or_else(|| usage(format!("{name}: no int")))),
    }
}

/// The checked value of the integer argument `i` (named `name`, in `range`), parsed by the library as the
/// command line parses it.
fn int_arg<T>(i: &Int, name: &str, range: std::ops::RangeInclusive<i64>) -> Result<T, Failure>
where
    T: std::str::FromStr,
    T::Err: std::fmt::Display,
{
    int_text(i, name, range)?.parse::<T>().map_err(|e| usage(e.to_string()))
}

/// A module address as an argument gives it (a usage error naming it).
fn module_address(module: &Int) -> Result<u8, Failure> {
    let max = i64::from(motionlink_powercube::wire::MAX_ADDRESS);
    Ok(int_arg::<Address>(module, "module", 1..=max)?.get())
}

/// A library error (an argument refused) as a failure.
fn refused(e: Error) -> Failure {
    e.failure()
}

fn usage(msg: impl Into<String>) -> Failure {
    Failure::usage(FAMILY, msg)
}

/// The session's settings from `s`, checked.
fn bus_config(s: &Settings, can: bool) -> Result<Config, Failure> {
    let mut c = if can { Config::can() } else { Config::rs232() };
    if let Some(t) = &s.timeout_ms {
        c.reply_timeout = int_arg::<ReplyTimeout>(t, "timeout_ms", 1..=60_000)?.get();
    }
    c.poll_interval = int_arg::<PollInterval>(&s.poll_ms, "poll_ms", 1..=10_000)?.get();
    Ok(c)
}

/// Opens the blocking client `s` and `port` ask for; true if the modules are emulated in this process
/// (they die with it: no watchdog is armed for them, as `motionlink powercube --port sim` does).
fn open(port: Target, s: &Settings) -> Result<(Client, bool), Failure> {
    module_address(&s.module)?;
    let baud = int_arg::<Baud>(&s.baud, "baud", 1200..=115_200)?;
    let bitrate = int_arg::<CanBitRate>(&s.bitrate, "bitrate", 10_000..=1_000_000)?;
    let fail = |e: Error| e.failure();
    let rs232 = |link| Client::with_link(PortLink::Rs232(link), clock(), bus_config(s, false)?).map_err(fail);
    let can = |link| Client::with_link(PortLink::Can(link), clock(), bus_config(s, true)?).map_err(fail);
    match port {
        Target::InProcess(InProcess::PowerCube(host)) => {
            Ok((rs232(Box::new(host.connect().map_err(|e| Failure::of(FAMILY, &e))?))?, true))
        }
        Target::InProcess(InProcess::PowerCubeCan(bus)) => Ok((can(Box::new(bus.connect()))?, true)),
        Target::InProcess(_) => Err(usage("that emulator is not a PowerCube emulator")),
        Target::Url(url) => match PortLink::open(&url, baud, bitrate, &clock()).map_err(fail)? {
            Some(PortLink::Rs232(link)) => Ok((rs232(link)?, false)),
            // An SLCAN adapter on a serial device or behind a TCP port (such as a served emulator's
            // `slcan://tcp://HOST:PORT`), or SocketCAN.
            Some(PortLink::Can(link)) => Ok((can(link)?, false)),
            None => {
                let device = motionlink_powercube::Emulator::new(&Default::default());
                let host = motionlink_link::pipe::EmulatorHost::new(
                    device,
                    clock(),
                    motionlink_link::pipe::PipeConfig::instant(),
                );
                Ok((rs232(Box::new(host.connect().0))?, true))
            }
        },
    }
}

/// [`open`], then the device profile of the client's module (the setting `profile`), as both faces take it.
fn open_profiled(port: Target, s: &Settings) -> Result<(Client, bool, crate::common::ProfileUse), Failure> {
    let port_url = port.profile_port();
    let address = Address::new(module_address(&s.module)?).map_err(|e| Error::from(e).failure())?;
    let (client, in_process) = open(port, s)?;
    let used = match crate::common::profile_lookup(s.profile.as_deref(), port_url.as_deref()) {
        Ok((p, port)) => {
            motionlink_powercube::probe::use_profile(&client, &p, &port, address).map_err(|e| e.failure())?
        }
        Err(used) => used,
    };
    Ok((client, in_process, used))
}

fn parse_param(name: &str) -> Result<Param, Failure> {
    name.parse::<Param>().map_err(|e| usage(e.to_string()))
}

/// The timeout `timeout_s`, checked by the library.
fn seconds(timeout_s: &Float) -> Result<Duration, Failure> {
    MotionTimeout::from_secs(timeout_s.get(FAMILY, "timeout_s")?).map(MotionTimeout::get).map_err(refused)
}

/// The checked move `move` asks for; numbers in the module's own unit (rad or m), each checked by the
/// library as the command line checks it.
fn move_spec(
    target: &Float,
    velocity: Option<&Float>,
    acceleration: Option<&Float>,
    tolerance: Option<&Float>,
    timeout_s: &Float,
) -> Result<MoveSpec, Failure> {
    let target = target.get(FAMILY, "target")?;
    let velocity = opt_float(velocity, FAMILY, "velocity")?;
    let acceleration = opt_float(acceleration, FAMILY, "acceleration")?;
    let tolerance = opt_float(tolerance, FAMILY, "tolerance")?;
    let timeout_s = timeout_s.get(FAMILY, "timeout_s")?;
    Ok(MoveSpec::from_args(
        MoveTarget::new(target).map_err(refused)?,
        velocity.map(MoveVelocity::new).transpose().map_err(refused)?,
        acceleration.map(MoveAcceleration::new).transpose().map_err(refused)?,
        tolerance.map(Tolerance::new).transpose().map_err(refused)?.unwrap_or_default(),
        MotionTimeout::from_secs(timeout_s).map_err(refused)?,
    ))
}

/// The motion `motion` asks for, every argument checked by the library as the command line checks it.
fn motion_spec(
    mode: &Text,
    value: &Float,
    time_ms: Option<&Int>,
    for_s: Option<&Float>,
    tolerance: Option<&Float>,
    timeout_s: &Float,
) -> Result<MotionSpec, Failure> {
    let mode = mode.get(FAMILY, "mode")?.parse::<MotionId>().map_err(|e| usage(e.to_string()))?;
    let time_ms = opt_within(time_ms, FAMILY, "time_ms", 0..=65535)?;
    let hold = opt_float(for_s, FAMILY, "for_s")?.map(MotionTimeout::from_secs).transpose().map_err(refused)?;
    let tolerance = opt_float(tolerance, FAMILY, "tolerance")?.map(Tolerance::new).transpose().map_err(refused)?;
    let timeout = MotionTimeout::from_secs(timeout_s.get(FAMILY, "timeout_s")?).map_err(refused)?;
    MotionSpec::from_args(mode, value.get(FAMILY, "value")?, time_ms, hold, tolerance, timeout).map_err(refused)
}

/// The motion command `setpoint` sends, checked as [`Motion::from_id`] checks it.
fn setpoint_motion(mode: &Text, value: &Float, time_ms: Option<&Int>) -> Result<(Motion, AckKind), Failure> {
    let mode = mode.get(FAMILY, "mode")?.parse::<MotionId>().map_err(|e| usage(e.to_string()))?;
    let time_ms = opt_within(time_ms, FAMILY, "time_ms", 0..=65535)?;
    Motion::from_id(mode, value.get(FAMILY, "value")?, time_ms, AxisUnit::ModuleUnit).map_err(|e| usage(e.to_string()))
}

/// The value `value` (a Python number) for parameter `p`, parsed as the command line parses it (a whole
/// number is written without a fraction: `5.0` reads as `5`).
fn parse_value(p: Param, value: &Float) -> Result<Value, Failure> {
    let text = value.get(FAMILY, "value")?.to_string();
    Value::parse(p, &text).map_err(|e| usage(e.to_string()))
}

/// A session with PowerCube modules (the native half of `motionlink.PowerCube`).
#[pyclass(frozen, module = "motionlink._native")]
pub struct PowerCubeClient {
    slot: Slot<Client>,
    token: CancelToken,
    guard: Guard,
    module: u8,
    port: String,
    close_bound: Duration,
    /// The port as given (a URL), for profiles and probes; `None` for an emulator in this process.
    port_url: Option<String>,
    baud: u32,
    profile: crate::common::ProfileUse,
}

impl PowerCubeClient {
    fn address(&self, py: Python<'_>, module: Option<Int>) -> PyResult<u8> {
        address_or(self.module, py, module)
    }
}

/// The module `module` names, or `default` (the client's) when it names none.
fn address_or(default: u8, py: Python<'_>, module: Option<Int>) -> PyResult<u8> {
    match module {
        None => Ok(default),
        Some(m) => module_address(&m).map_err(|f| to_pyerr(py, f)),
    }
}

/// An async session with PowerCube modules (the native half of `motionlink.AsyncPowerCube`): the long
/// operations are coroutines; cancelling one (its task) halts the module.
#[pyclass(frozen, module = "motionlink._native")]
pub struct AsyncPowerCubeClient {
    slot: Slot<AsyncClient>,
    guard: Guard,
    module: u8,
    port: String,
    profile: crate::common::ProfileUse,
}

impl AsyncPowerCubeClient {
    fn address(&self, py: Python<'_>, module: Option<Int>) -> PyResult<u8> {
        address_or(self.module, py, module)
    }
}

impl crate::faces::Closing for PowerCubeClient {}

/// Module addresses, as `started()` names them.
fn addresses(modules: Vec<Address>) -> Vec<u8> {
    modules.into_iter().map(Address::get).collect()
}

impl crate::session::Session for Client {
    fn started_ids(&self) -> Vec<u8> {
        addresses(self.started())
    }

    fn end(self) -> Result<Vec<u8>, Failure> {
        self.close().map(addresses).map_err(|e| e.failure())
    }

    /// The call under way was cancelled: the modules it set in motion are halted here.
    fn end_shared(shared: Arc<Self>) -> Result<Vec<u8>, Failure> {
        let modules = addresses(shared.started());
        shared.halt_started().map_err(|e| e.failure())?;
        Ok(modules)
    }
}

impl crate::session::AsyncSession for AsyncClient {
    fn started_ids(&self) -> Vec<u8> {
        addresses(self.started())
    }

    async fn end(self) -> Result<Vec<u8>, Failure> {
        self.close().await.map(addresses).map_err(|e| e.failure())
    }

    async fn end_shared(shared: Arc<Self>) -> Result<Vec<u8>, Failure> {
        let modules = addresses(shared.started());
        shared.halt_started().await.map_err(|e| e.failure())?;
        Ok(modules)
    }
}

faces! {
    PowerCubeClient / AsyncPowerCubeClient, Error;

    both {}

    blocking {
        #[new]
        fn py_new(py: Python<'_>, port: &Bound<'_, PyAny>, settings: Settings) -> PyResult<Self> {
            let t = target(port, FAMILY).map_err(|f| to_pyerr(py, f))?;
            let port_url = t.profile_port();
            let module = module_address(&settings.module).map_err(|f| to_pyerr(py, f))?;
            let baud: u32 = settings.baud.within(FAMILY, "baud", 1..=4_000_000).map_err(|f| to_pyerr(py, f))?;
            let watchdog = settings.watchdog.get(FAMILY, "watchdog").map_err(|f| to_pyerr(py, f))?;
            let (client, in_process, profile) = py.detach(|| open_profiled(t, &settings)).map_err(|f| to_pyerr(py, f))?;
            let token = CancelToken::new();
            client.set_cancel(token.clone());
            let guard = Guard::for_motions(ModulesAt::emulated_in_process(in_process), !watchdog);
            let port = client.port().to_string();
            let close_bound = client.config().close_bound;
            Ok(PowerCubeClient {
                slot: Slot::new(client, FAMILY),
                token,
                guard,
                module,
                port,
                close_bound,
                port_url,
                baud,
                profile,
            })
        }

        /// `motionlink probe powercube`'s report of the bus, as a dict (nothing moves); with `save` (`""`: the
        /// default profiles file, else a path) the profile of each module is written.
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
            let probe = || motionlink_powercube::probe::probe(&client, &setup).map_err(|e| e.failure());
            crate::common::probe_py(py, FAMILY, self.port_url.as_deref(), save, probe, motionlink_powercube::probe::save_profile)
        }
    }

    asynch {
        /// Opens a session on the runtime (the port is opened on its blocking pool): `done(ok, client)`.
        #[staticmethod]
        fn open(
            py: Python<'_>,
            port: &Bound<'_, PyAny>,
            settings: &Bound<'_, PyAny>,
            done: Py<PyAny>,
        ) -> PyResult<NativeTask> {
            let t = target(port, FAMILY).map_err(|f| to_pyerr(py, f))?;
            let s: Settings = settings.extract()?;
            Ok(spawn_task(done, async move {
                let module = module_address(&s.module)?;
                let watchdog = s.watchdog.get(FAMILY, "watchdog")?;
                let (client, in_process, profile) =
                    crate::wait::on_blocking_pool(FAMILY, move || open_profiled(t, &s)).await?;
                let client = AsyncClient::from_client(client);
                let port = client.port().to_string();
                let guard = Guard::for_motions(ModulesAt::emulated_in_process(in_process), !watchdog);
                let native = AsyncPowerCubeClient { slot: Slot::new(client, FAMILY), guard, module, port, profile };
                deliver(move |py| Ok(Py::new(py, native)?.into_any()))
            }))
        }

    }


    /// Every module on the bus (`error` set for a module that answered but could not be read). Ctrl-C
    /// raises at once and cancels the session's token: the scan, which watches it, ends on its thread at
    /// once (the address being asked is not waited for).
    blocking scan scan(me, py) {} |c| { c.scan() } => |py, found| {
        let kind = |e: &motionlink_powercube::client::ScanEntry| e.info.as_ref().ok().map(|i| i.kind);
        found.iter().map(|e| record(py, e.address.get(), e, kind(e), &[])).collect::<PyResult<Vec<_>>>()
    };

    /// Type, version, serial number, state and limits of a module.
    blocking read info(me, py, module: Option<Int>) {
        let a = me.address(py, module)?;
    } |c| { c.module(Address::new(a)?).details() } => |py, d| record(py, a, &d, Some(d.info.kind), &[]);

    /// One sample of `watch`: the position and the state word.
    blocking read sample(me, py, module: Option<Int>) {
        let a = me.address(py, module)?;
    } |c| {
        let m = c.module(Address::new(a)?);
        let kind = m.kind()?;
        let s = m.state()?;
        Ok((kind, in_unit(m.position()?, kind), s))
    } => |py, p| sample_record(py, a, p.0, p.1, p.2);

    /// Reads a parameter by name (ActPos) or id (60, 0x3c).
    blocking read get(me, py, name: String, module: Option<Int>) {
        let a = me.address(py, module)?;
        let p = parse_param(&name).map_err(|f| to_pyerr(py, f))?;
    } |c| {
        let m = c.module(Address::new(a)?);
        Ok(ParamReading { param: p, value: m.get(p)?, kind: m.kind()? })
    } => |py, reading| get_record(py, a, &reading);

    /// Writes a parameter, refusing a target beyond its limit, and reads it back.
    blocking quick set(me, py, name: String, value: Float, module: Option<Int>) {
        let a = me.address(py, module)?;
        let p = parse_param(&name).map_err(|f| to_pyerr(py, f))?;
        let v = parse_value(p, &value).map_err(|f| to_pyerr(py, f))?;
    } |c| {
        let m = c.module(Address::new(a)?);
        Ok((m.set_checked(p, v)?, m.kind()?))
    } => |py, (readback, kind)| set_record(py, a, kind, &SetReport { param: p, value: v, readback });

    /// Resets the module's error state, confirmed by the state read back; true if it switched off a watchdog a
    /// dead host left expired.
    blocking quick reset(me, py, module: Option<Int>) {
        let a = me.address(py, module)?;
    } |c| { c.module(Address::new(a)?).reset_and_release_watchdog() } => |py, released| Ok(released);

    /// Loops `n` position reads in Rust (no Python in between): the benchmark's reference.
    blocking quick _bench_native_reads(me, py, n: u32, module: Option<Int>) {
        let a = me.address(py, module)?;
    } |c| {
        let m = c.module(Address::new(a)?);
        let start = std::time::Instant::now();
        for _ in 0..n {
            std::hint::black_box(m.position()?);
        }
        Ok(start.elapsed().as_secs_f64())
    } => |py, seconds| Ok(seconds);

    /// The actual position: (module, value, unit) with unit "rad", "m", or "module" while the kind is not
    /// known.
    quick position(me, py, module: Option<Int>) {
        let a = me.address(py, module)?;
    } |c| {
        let m = c.module(Address::new(a)?);
        // The kind names the unit (rad or m); the session keeps it after the first read.
        let kind = w!(m.kind())?;
        Ok(in_unit(w!(m.position())?, kind))
    } => |py, p| Ok((a, f32_py(p.value()), suffix(p.unit()).1));

    /// The state word, flag by flag.
    read state(me, py, module: Option<Int>) {
        let a = me.address(py, module)?;
    } |c| { w!(c.module(Address::new(a)?).state()) } => |py, s| state_record(py, a, s);

    /// Homes the module and waits for the end of homing (Ctrl-C, or cancelling the task, halts it).
    motion home(me, py, module: Option<Int>, timeout_s: Float) {
        let a = me.address(py, module)?;
        let timeout = seconds(&timeout_s).map_err(|f| to_pyerr(py, f))?;
        let guard = me.guard;
    } |c| {
        w!(c.module(Address::new(a)?).home_guarded(timeout, guard, &mut |_| {});
            async c.start(Op::HomeGuarded(Address::new(a)?, timeout, guard)) => Output::Homed)
    } => |py, r| home_record(py, a, &r);

    /// A checked ramp move to `target` (the module's unit: rad or m), waited for (Ctrl-C, or cancelling the
    /// task, halts it).
    motion move_to(
        me, py, target: Float, module: Option<Int>, velocity: Option<Float>, acceleration: Option<Float>,
        tolerance: Option<Float>, timeout_s: Float
    ) {
        let a = me.address(py, module)?;
        let spec = move_spec(&target, velocity.as_ref(), acceleration.as_ref(), tolerance.as_ref(), &timeout_s)
            .map_err(|f| to_pyerr(py, f))?;
        let guard = me.guard;
    } |c| {
        w!(c.module(Address::new(a)?).move_to_guarded(&spec, guard, &mut |_| {});
            async c.start(Op::MoveGuarded(Address::new(a)?, spec, guard)) => Output::Moved)
    } => |py, r| move_record(py, a, &r);

    /// A motion of any of the manual's modes (`mode`: "fvel", "FSTEP_MODE", "ivel_ack" ...), checked against
    /// the module's limits and run to its end (Ctrl-C, or cancelling the task, halts it).
    motion motion(
        me, py, mode: Text, value: Float, module: Option<Int>, time_ms: Option<Int>, for_s: Option<Float>,
        tolerance: Option<Float>, timeout_s: Float
    ) {
        let a = me.address(py, module)?;
        let spec = motion_spec(&mode, &value, time_ms.as_ref(), for_s.as_ref(), tolerance.as_ref(), &timeout_s)
            .map_err(|f| to_pyerr(py, f))?;
        let guard = me.guard;
    } |c| {
        w!(c.module(Address::new(a)?).run_motion_guarded(&spec, guard, &mut |_| {});
            async c.start(Op::RunMotion(Address::new(a)?, spec, Some(guard))) => Output::MotionRun)
    } => |py, r| motion_record(py, a, &r);

    /// Waits until the module stands still (no STATE_MOTION); the state at the end. Ctrl-C halts it; so does
    /// cancelling the task (the wait's future stops nothing when dropped: the motion may be another call's,
    /// so the module is halted here, confirmed by its state as `stop` does).
    motion wait(me, py, module: Option<Int>, timeout_s: Float) {
        let a = me.address(py, module)?;
        let timeout = seconds(&timeout_s).map_err(|f| to_pyerr(py, f))?;
    } |c| { w!(c.module(Address::new(a)?) => wait_motion_end(timeout); &mut |_| {}) }
    else |halting| { halting.module(Address::new(a)?).halt_confirmed().await } => |py, s| state_record(py, a, s);

    /// One streamed motion command (a control loop's setpoint): checked against the module's limits (read
    /// once, cached), sent, its acknowledge returned; the motion goes on after the call.
    quick setpoint(me, py, mode: Text, value: Float, module: Option<Int>, time_ms: Option<Int>) {
        let a = me.address(py, module)?;
        let (motion, ack) = setpoint_motion(&mode, &value, time_ms.as_ref()).map_err(|f| to_pyerr(py, f))?;
        let guard = me.guard;
    } |c| { w!(c.module(Address::new(a)?).setpoint(motion, ack, guard)) } => |py, r| setpoint_record(py, a, &r);

    /// Halts the module at once (it stays halted until a reset), confirmed by its state read back until it
    /// is at rest; the state and where it stands then, as `motionlink powercube stop --json` prints them.
    quick stop(me, py, module: Option<Int>) {
        let a = me.address(py, module)?;
    } |c| { w!(c.module(Address::new(a)?).halt_confirmed()) } => |py, h| halt_record(py, a, &h);
}
