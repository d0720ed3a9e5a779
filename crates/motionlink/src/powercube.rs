//! `motionlink powercube`, `motionlink sim powercube`, `motionlink decode powercube` and the PowerCube part
//! of `motionlink demo`.

use std::io::{IsTerminal, Read, Write};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use motionlink_link::can::{
    CanBus, CanBusConfig, CanFrame, CanLink, CandumpLine, SlcanAdapter, SlcanBitrate, SlcanLink,
};
use motionlink_link::clock::{Clock, ManualClock};
use motionlink_link::pipe::{EmulatorHost, PipeConfig};
use motionlink_link::serial::SerialLink;
use motionlink_link::transcript::{TapLink, Transcript, Way};
use motionlink_link::url::PortUrl;
use motionlink_link::{LinkError, RealClock, SerialSettings, SharedClock};
use motionlink_powercube::client::{Bus, BusConfig, Error as PcError, ModuleInfo, MoveSpec, Progress, Readback};
use motionlink_powercube::model::{
    Acceleration, AckKind, Broadcast, BroadcastForm, CubeState, ModuleKind, Motion, Param, Position, Reply, Request,
    StateFlag, Value, Velocity,
};
use motionlink_powercube::sim::{SimBus, SimConfig};
use motionlink_powercube::wire::can::{self as can_wire, Role};
use motionlink_powercube::wire::rs232::{self, Rs232Decoder, TelKind};
use motionlink_powercube::wire::Payload;
use serde_json::json;

use crate::common::{self, CaptureArgs, CliError, ServeArgs};

/// `motionlink powercube` arguments.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The port: a serial device or tcp://HOST:PORT (RS232), socketcan://IF or slcan://PATH (CAN), or sim.
    #[arg(long)]
    pub port: String,
    /// The module's address, 1..31.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u8).range(1..=31))]
    pub module: u8,
    /// RS232 baud rate.
    #[arg(long, default_value_t = 9600, value_parser = clap::value_parser!(u32).range(1..))]
    pub baud: u32,
    /// CAN bit rate of an SLCAN adapter (10000 .. 1000000).
    #[arg(long, default_value_t = 1_000_000)]
    pub bitrate: u32,
    /// Acknowledge timeout in ms, 1 to 60000 (default: 200 on RS232, 50 on CAN).
    #[arg(long, value_name = "MS", value_parser = clap::value_parser!(u64).range(1..=60_000))]
    pub timeout_ms: Option<u64>,
    /// How often `home` and `move` read the module's state while they wait, in ms (1 to 10000): polls are
    /// never sent faster than this, however quickly the line answers.
    #[arg(long, value_name = "MS", default_value_t = 10, value_parser = clap::value_parser!(u64).range(1..=10_000))]
    pub poll_ms: u64,
    /// Print JSON instead of a table.
    #[arg(long, global = true)]
    pub json: bool,
    /// Do not arm the module watchdog for `home` and `move` (the Config word is left alone; a host that dies
    /// then leaves the module moving). Signals, a closed stdout and errors still halt it.
    #[arg(long, global = true)]
    pub no_watchdog: bool,
    /// What to do.
    #[command(subcommand)]
    pub action: Action,
}

/// What `motionlink powercube` does.
#[derive(clap::Subcommand, Debug)]
pub enum Action {
    /// List the modules on the bus (addresses 1..31) with type, version, serial number and state.
    Scan,
    /// Type, version, serial number, state and limits of the module.
    Info,
    /// The module's state word, flag by flag.
    State,
    /// Read a parameter (by name, such as ActPos, or id, such as 60 or 0x3c).
    Get {
        /// The parameter.
        param: String,
    },
    /// Write a parameter.
    Set {
        /// The parameter.
        param: String,
        /// The value, in the parameter's type and unit.
        value: String,
    },
    /// Home the module and wait for the end of homing (watchdog armed; a signal halts it).
    Home {
        /// Give up (and halt) after this many seconds (above 0).
        #[arg(long, default_value_t = 60.0)]
        timeout: f64,
    },
    /// Reset the module's error state (and switch off a watchdog that a dead host left expired).
    Reset,
    /// Stop the module at once (it stays halted until a reset).
    Halt,
    /// Ramp to a position (rad or m) and wait for the end of the ramp (watchdog armed; a signal halts it).
    /// Succeeds only if the final position read from the module lies within --tolerance of the target.
    Move {
        /// The target position.
        #[arg(allow_negative_numbers = true)]
        position: f32,
        /// Velocity (rad/s or m/s, above 0), written to TargetVel first; if not given, the module's
        /// TargetVel is used as it is.
        #[arg(long)]
        vel: Option<f32>,
        /// Acceleration (rad/s² or m/s², above 0), written to TargetAcc first; if not given, the module's
        /// TargetAcc is used as it is.
        #[arg(long)]
        acc: Option<f32>,
        /// Give up (and halt) after this many seconds (above 0).
        #[arg(long, default_value_t = 60.0)]
        timeout: f64,
        /// In-position tolerance (rad or m, above 0): the move succeeds only if the final actual position is
        /// at most this far from the target. The manual has no in-position window parameter.
        #[arg(long, default_value_t = MoveSpec::DEFAULT_TOLERANCE.value())]
        tolerance: f32,
    },
    /// Print position and state until Ctrl-C (or --count samples).
    Watch {
        /// Milliseconds between samples (1 to 3600000).
        #[arg(long, default_value_t = 200, value_parser = clap::value_parser!(u64).range(1..=3_600_000))]
        interval_ms: u64,
        /// Stop after this many samples (at least 1).
        #[arg(long, value_parser = clap::value_parser!(u64).range(1..))]
        count: Option<u64>,
    },
    /// List the parameter table.
    Params,
}

/// `motionlink sim powercube` arguments.
#[derive(clap::Args, Debug)]
pub struct SimArgs {
    #[command(flatten)]
    pub serve: ServeArgs,
    /// Module addresses, such as 1,17 (default: one module at 1).
    #[arg(long, value_delimiter = ',', conflicts_with = "config")]
    pub modules: Vec<u8>,
    /// A TOML file describing the modules (see crates/motionlink-powercube/README.md).
    #[arg(long, value_name = "FILE")]
    pub config: Option<std::path::PathBuf>,
    /// Serve the modules on CAN through an emulated SLCAN serial adapter instead of RS232 framing.
    #[arg(long)]
    pub slcan: bool,
    /// Drop RS232 frames with a wrong BCC (the modules accept them).
    #[arg(long)]
    pub strict: bool,
}

/// `motionlink decode powercube` arguments.
#[derive(clap::Args, Debug)]
pub struct DecodeArgs {
    #[command(flatten)]
    pub capture: CaptureArgs,
}

fn cli_err(e: PcError) -> CliError {
    if let PcError::Cancelled { .. } = e {
        CliError::Interrupted(e.to_string())
    } else if e.is_transport() {
        CliError::transport(e)
    } else if e.is_usage() {
        CliError::usage(e)
    } else {
        CliError::device(e)
    }
}

/// Runs `action`, which sets the modules in `addresses` moving, with their watchdog armed: switched on
/// before (CONFIGID_MOD_WATCHDOG_ENABLE set if it was not, a life sign, the refresh served by the session's
/// background thread: the CAN broadcast, or on RS232 the broadcast to address 0 as libm5api sends it), so
/// that a host that dies (SIGKILL, power loss, the adapter or cable pulled) stops them within 50 ms; and
/// switched off again after, whether `action` succeeded, failed or was cancelled (a signal), with the
/// Config word restored, so that a normal run leaves the modules as it found them. A session that failed
/// (its line broke, a stop was not confirmed) leaves the watchdog online: it is what stops them then.
///
/// Not with `--no-watchdog`, nor on the in-process emulator (`--port sim`), which dies with the host.
fn with_watchdog<T>(
    bus: &Bus,
    args: &Args,
    in_process: bool,
    addresses: &[u8],
    action: impl FnOnce() -> Result<T, CliError>,
) -> Result<T, CliError> {
    let list = addresses.iter().map(u8::to_string).collect::<Vec<_>>().join(", ");
    let arm = !args.no_watchdog && !in_process && bus.watchdog_reliable();
    if !arm {
        let result = action();
        bus.halt_started();
        return result;
    }
    if let Err(e) = bus.enable_watchdog(addresses) {
        // Undo what was done before the failure (a Config word changed, a life sign sent).
        if let Err(undo) = bus.disable_watchdog() {
            tracing::warn!("switching the watchdog off again failed: {undo}");
        }
        let hint = match &e {
            PcError::Device { state, .. } if state.contains(StateFlag::CommError) => {
                " (its watchdog expired: a host stopped refreshing it; `reset` clears it)"
            }
            _ => "",
        };
        return Err(with_context(e, &format!("cannot arm the watchdog of module {list}"), hint));
    }
    tracing::info!("watchdog armed in module {list}");
    let result = action();
    // Whatever is still moving is stopped before the watchdog goes offline.
    bus.halt_started();
    match (result, bus.disable_watchdog()) {
        (result, Ok(())) => result,
        (Ok(_), Err(e)) => Err(with_context(e, &format!("cannot switch the watchdog of module {list} off again"), "")),
        (Err(e), Err(undo)) => {
            common::say(format!("motionlink: {undo}"));
            Err(e)
        }
    }
}

/// `e` as a command-line error of its class, its message between `context` and `hint`.
fn with_context(e: PcError, context: &str, hint: &str) -> CliError {
    let text = format!("{context}: {e}{hint}");
    if let PcError::Cancelled { .. } = e {
        CliError::Interrupted(text)
    } else if e.is_transport() {
        CliError::transport(text)
    } else if e.is_usage() {
        CliError::usage(text)
    } else {
        CliError::device(text)
    }
}

/// Opens the session `args` ask for.
fn open(args: &Args) -> Result<(Bus, Option<EmulatorHost<SimBus>>), CliError> {
    let url: PortUrl = args.port.parse()?;
    let clock = RealClock::shared();
    let timeout = args.timeout_ms.map(Duration::from_millis);
    let with_timeout = |mut c: BusConfig| {
        if let Some(t) = timeout {
            c.reply_timeout = t;
        }
        c
    };
    let poll = Duration::from_millis(args.poll_ms);
    let with_timeout = |c: BusConfig| BusConfig { poll_interval: poll, ..with_timeout(c) };
    let bus = match &url {
        PortUrl::Serial(_) | PortUrl::Tcp { .. } => {
            let link = url.open_byte_link(SerialSettings { dtr_rts_on: false, ..SerialSettings::new(args.baud) })?;
            Bus::rs232(link, clock, with_timeout(BusConfig::rs232()))
        }
        PortUrl::Sim => {
            let host = EmulatorHost::new(SimBus::new(&SimConfig::default()), Arc::clone(&clock), PipeConfig::instant());
            let bus = Bus::rs232(Box::new(host.connect().0), clock, with_timeout(BusConfig::rs232()));
            return Ok((bus, Some(host)));
        }
        PortUrl::Slcan(path) => {
            let rate = SlcanBitrate::from_bps(args.bitrate)
                .ok_or_else(|| CliError::usage(format!("{} bit/s is not an SLCAN bit rate", args.bitrate)))?;
            // An SLCAN adapter needs no modem lines (opening the port raises them anyway).
            let serial = SerialLink::open(path, SerialSettings { dtr_rts_on: false, ..SerialSettings::new(115_200) })?;
            let link = SlcanLink::open(serial, Arc::clone(&clock), rate)?;
            Bus::can(Box::new(link), clock, with_timeout(BusConfig::can()))
        }
        PortUrl::SocketCan(ifname) => open_socketcan(ifname, clock, with_timeout(BusConfig::can()))?,
    };
    Ok((bus, None))
}

#[cfg(target_os = "linux")]
fn open_socketcan(ifname: &str, clock: SharedClock, config: BusConfig) -> Result<Bus, CliError> {
    let link = motionlink_link::can::socketcan::SocketCanLink::open(ifname)?;
    Ok(Bus::can(Box::new(link), clock, config))
}

#[cfg(not(target_os = "linux"))]
fn open_socketcan(_ifname: &str, _clock: SharedClock, _config: BusConfig) -> Result<Bus, CliError> {
    Err(CliError::usage("socketcan:// ports need Linux"))
}

fn parse_param(text: &str) -> Result<Param, CliError> {
    text.parse::<Param>().map_err(CliError::usage)
}

fn value_json(v: &Value) -> serde_json::Value {
    match *v {
        Value::F32(x) => json!(x),
        Value::U32(x) => json!(x),
        Value::I32(x) => json!(x),
        Value::U16(x) => json!(x),
        Value::I16(x) => json!(x),
        Value::U8(x) => json!(x),
        Value::PosStateDio { pos, state, dio } => json!({"position": pos, "short_state": state.0, "dio": dio.0}),
        Value::PosTime { pos, time_ms } => json!({"position": pos, "time_ms": time_ms}),
    }
}

fn state_json(s: CubeState) -> serde_json::Value {
    json!({
        "word": s.0,
        "flags": s.iter().map(|f| f.label()).collect::<Vec<_>>(),
        "faults": s.faults().map(|f| f.label()).collect::<Vec<_>>(),
    })
}

fn info_json(m: &ModuleInfo) -> serde_json::Value {
    json!({
        "address": m.address,
        "kind": m.kind.name(),
        "version": m.version.to_string(),
        "serial": m.serial,
        "state": state_json(m.state),
    })
}

/// A duration in seconds that must be a number above 0, for `--timeout`.
fn positive_secs(name: &str, s: f64) -> Result<Duration, CliError> {
    if !(s.is_finite() && s > 0.0) {
        return Err(CliError::usage(format!("{name} must be a number of seconds above 0, not {s}")));
    }
    Duration::try_from_secs_f64(s).map_err(|_| CliError::usage(format!("{name} {s} is not a duration in seconds")))
}

/// Checks what can be checked before the port is opened: numbers that must be finite and positive. (The
/// limits of the module itself, such as MaxPos or MaxVel, are checked against the module before anything is
/// written or moved.)
fn check_args(action: &Action) -> Result<(), CliError> {
    match action {
        Action::Move { position, vel, acc, timeout, tolerance } => {
            if !position.is_finite() {
                return Err(CliError::usage(format!("the position must be a number, not {position}")));
            }
            for (name, value) in [("--vel", vel), ("--acc", acc), ("--tolerance", &Some(*tolerance))] {
                if let Some(v) = value {
                    if !(v.is_finite() && *v > 0.0) {
                        return Err(CliError::usage(format!("{name} must be a number above 0, not {v}")));
                    }
                }
            }
            positive_secs("--timeout", *timeout).map(|_| ())
        }
        Action::Home { timeout } => positive_secs("--timeout", *timeout).map(|_| ()),
        _ => Ok(()),
    }
}

/// `motionlink powercube ...`
pub fn run(args: Args) -> Result<(), CliError> {
    let mut out = std::io::stdout().lock();
    if let Action::Params = args.action {
        return print_params(&mut out, args.json);
    }
    check_args(&args.action)?;
    let (bus, host) = open(&args)?;
    let in_process = host.is_some();
    bus.set_cancel_token(common::interrupt_token());
    let m = bus.module(args.module).map_err(cli_err)?;
    match &args.action {
        Action::Scan => {
            let found = bus.scan().map_err(cli_err)?;
            if args.json {
                let entries: Vec<_> = found
                    .iter()
                    .map(|e| match &e.info {
                        Ok(info) => info_json(info),
                        Err(err) => json!({"address": e.address, "error": err.to_string()}),
                    })
                    .collect();
                common::print_json(&mut out, &json!(entries))?;
            } else if found.is_empty() {
                writeln!(out, "no module answered on {}", bus.describe())?;
            } else {
                writeln!(out, "{:<7}  {:<6}  {:<7}  {:<8}  state", "address", "type", "version", "serial")?;
                for e in &found {
                    match &e.info {
                        Ok(i) => writeln!(
                            out,
                            "{:<7}  {:<6}  {:<7}  {:<8}  {}",
                            i.address,
                            i.kind.name(),
                            i.version.to_string(),
                            i.serial,
                            i.state
                        )?,
                        Err(err) => writeln!(out, "{:<7}  answered the scan, then: {err}", e.address)?,
                    }
                }
            }
            if found.is_empty() {
                return Err(CliError::transport(format!("no module answered on {}", bus.describe())));
            }
            // Every module is listed; the exit code still says that one could not be read.
            if let Some(e) = found.into_iter().find_map(|e| e.info.err()) {
                return Err(cli_err(e));
            }
        }
        Action::Info => {
            let info = m.info().map_err(cli_err)?;
            let limits: Vec<(Param, Value)> =
                [Param::MinPos, Param::MaxPos, Param::MaxVel, Param::MaxAcc, Param::ActPos]
                    .into_iter()
                    .map(|p| m.get(p).map(|v| (p, v)))
                    .collect::<Result<_, _>>()
                    .map_err(cli_err)?;
            if args.json {
                let mut j = info_json(&info);
                for (p, v) in &limits {
                    j[p.name()] = value_json(v);
                }
                common::print_json(&mut out, &j)?;
            } else {
                let mut rows = vec![
                    ("address".to_string(), info.address.to_string()),
                    ("type".to_string(), info.kind.name().to_string()),
                    ("version".to_string(), info.version.to_string()),
                    ("serial".to_string(), info.serial.to_string()),
                    ("state".to_string(), info.state.to_string()),
                ];
                rows.extend(limits.iter().map(|(p, v)| (p.name().to_string(), v.show(*p, info.kind))));
                common::print_table(&mut out, &rows)?;
            }
        }
        Action::State => {
            let s = m.state().map_err(cli_err)?;
            if args.json {
                common::print_json(&mut out, &state_json(s))?;
            } else {
                writeln!(out, "CubeState {:#010x}", s.0)?;
                let rows: Vec<_> =
                    s.iter().map(|f| (f.label(), format!("{:<11}  {}", f.class().name(), f.meaning()))).collect();
                common::print_table(&mut out, &rows)?;
                if s.is_empty() {
                    writeln!(out, "(no flag set)")?;
                }
            }
        }
        Action::Get { param } => {
            let p = parse_param(param)?;
            let v = m.get(p).map_err(cli_err)?;
            // The unit depends on the module type (rad or m): no guessing when it cannot be read.
            let kind = m.kind().map_err(|e| {
                with_context(e, &format!("{} read, but the module type (and so its unit) cannot be read", p.name()), "")
            })?;
            if args.json {
                common::print_json(
                    &mut out,
                    &json!({"param": p.name(), "id": p.id(), "value": value_json(&v), "unit": p.unit().symbol(kind)}),
                )?;
            } else {
                common::print_table(&mut out, &[(p.name().to_string(), v.show(p, kind))])?;
            }
        }
        Action::Set { param, value } => {
            let p = parse_param(param)?;
            let v = Value::parse(p, value).map_err(CliError::usage)?;
            // Targets beyond their limits are refused; what was written is read back.
            let readback = m.set_checked(p, v).map_err(cli_err)?;
            let (read_back, not_verifiable) = match readback {
                Readback::Same(r) => (Some(r), None),
                Readback::NotReadable(why) => (None, Some(why)),
            };
            if args.json {
                common::print_json(
                    &mut out,
                    &json!({"param": p.name(), "value": value_json(&v), "ok": true,
                            "read_back": read_back.as_ref().map(value_json), "not_verifiable": not_verifiable}),
                )?;
            } else {
                let kind = m.kind().map_err(|e| {
                    with_context(
                        e,
                        &format!("{} was set, but the module type (and so its unit) cannot be read", p.name()),
                        "",
                    )
                })?;
                let how = match not_verifiable {
                    None => "read back".to_string(),
                    Some(why) => format!("not verified: {why}"),
                };
                writeln!(out, "{} set to {} ({how})", p.name(), v.show(p, kind))?;
            }
        }
        Action::Home { timeout } => {
            let timeout = positive_secs("--timeout", *timeout)?;
            with_watchdog(&bus, &args, in_process, &[args.module], || {
                let bar = common::progress_bar(0, format!("homing module {}", args.module));
                let r = m.home_and_wait(timeout, &mut |p: &Progress| bar.set_message(progress_text(p)));
                bar.finish_and_clear();
                let (position, s) = r.map_err(cli_err)?;
                report_done(&mut out, args.json, "homed", &position, s)
            })?;
        }
        Action::Reset => {
            // After a host died with the watchdog online, a plain Reset would be undone 50 ms later.
            let released = m.reset_and_release_watchdog().map_err(cli_err)?;
            if args.json {
                common::print_json(&mut out, &json!({"ok": true, "action": "reset", "watchdog_released": released}))?;
            } else if released {
                writeln!(out, "reset (the watchdog had expired with no host serving it: switched it offline)")?;
            } else {
                writeln!(out, "reset")?;
            }
        }
        Action::Halt => {
            m.halt().map_err(cli_err)?;
            done(&mut out, args.json, "halted")?;
        }
        Action::Move { position, vel, acc, timeout, tolerance } => {
            let spec = MoveSpec {
                target: Position::native(*position),
                // Only what was given is written; TargetVel / TargetAcc otherwise stay as the module has them.
                vel: vel.map(Velocity::native),
                acc: acc.map(Acceleration::native),
                tolerance: Position::native(*tolerance),
                timeout: positive_secs("--timeout", *timeout)?,
            };
            with_watchdog(&bus, &args, in_process, &[args.module], || {
                let bar = common::progress_bar(0, format!("module {}", args.module));
                let mut start = None;
                let r = m.move_to(&spec, &mut |p: &Progress| {
                    let from = *start.get_or_insert(p.position.value());
                    bar.set_length(((position - from).abs() * 1000.0).round() as u64);
                    bar.set_position(((p.position.value() - from).abs() * 1000.0).round() as u64);
                    bar.set_message(progress_text(p));
                });
                bar.finish_and_clear();
                let report = r.map_err(cli_err)?;
                report_done(&mut out, args.json, "reached", &report.reached, report.state)
            })?;
        }
        Action::Watch { interval_ms, count } => {
            let token = common::interrupt_token();
            let kind = m.kind().map_err(cli_err)?;
            let clock = Arc::clone(bus.clock());
            let interval = Duration::from_millis(*interval_ms);
            let mut due = clock.now();
            let mut n = 0u64;
            while !token.is_cancelled() && count.is_none_or(|c| n < c) {
                let s = m.state().map_err(cli_err)?;
                let p = m.position().map_err(cli_err)?;
                let t = clock.now();
                if args.json {
                    common::print_json(
                        &mut out,
                        &json!({"t_ms": t.as_millis() as u64, "position": p.value(), "state": state_json(s)}),
                    )?;
                } else {
                    writeln!(out, "{:>9.3} s  {}  {}", t.since_origin().as_secs_f64(), p.show(kind), s)?;
                }
                out.flush()?;
                n += 1;
                if count.is_some_and(|c| n >= c) {
                    break;
                }
                // The next sample on a fixed schedule; a signal ends the wait within 20 ms.
                due += interval;
                while !token.is_cancelled() && clock.now() < due {
                    clock.sleep_until(due.min(clock.now() + Duration::from_millis(20)));
                }
            }
        }
        Action::Params => {}
    }
    Ok(())
}

fn progress_text(p: &Progress) -> String {
    format!("module {}: {:.4}  {}", p.address, p.position.value(), p.state)
}

fn done(out: &mut dyn Write, json: bool, what: &str) -> Result<(), CliError> {
    if json {
        common::print_json(out, &json!({"ok": true, "action": what}))
    } else {
        writeln!(out, "{what}")?;
        Ok(())
    }
}

fn report_done(out: &mut dyn Write, json: bool, what: &str, pos: &Position, s: CubeState) -> Result<(), CliError> {
    if json {
        common::print_json(out, &json!({"ok": true, "action": what, "position": pos.value(), "state": state_json(s)}))
    } else {
        writeln!(out, "{what}: position {:.4}, state {s}", pos.value())?;
        Ok(())
    }
}

fn print_params(out: &mut dyn Write, as_json: bool) -> Result<(), CliError> {
    if as_json {
        let list: Vec<_> = Param::ALL
            .iter()
            .map(|p| {
                json!({"id": p.id(), "name": p.name(), "type": p.data_type().name(), "unit": p.unit().symbol(ModuleKind::Rotary),
                       "access": p.access().short(), "class": p.class().name(), "description": p.description()})
            })
            .collect();
        return common::print_json(out, &json!(list));
    }
    writeln!(
        out,
        "{:<4}  {:<22}  {:<17}  {:<9}  {:<6}  {:<7}  description",
        "id", "name", "type", "unit", "access", "class"
    )?;
    for p in Param::ALL {
        writeln!(
            out,
            "0x{:02X}  {:<22}  {:<17}  {:<9}  {:<6}  {:<7}  {}",
            p.id(),
            p.name(),
            p.data_type().name(),
            p.unit().symbol(ModuleKind::Rotary),
            p.access().short(),
            p.class().name(),
            p.description()
        )?;
    }
    Ok(())
}

/// `motionlink sim powercube ...`
pub fn sim(args: SimArgs) -> Result<(), CliError> {
    let config = match (&args.config, args.modules.is_empty()) {
        (Some(path), _) => {
            let text = std::fs::read_to_string(path)
                .map_err(|e| CliError::usage(format!("cannot read {}: {e}", path.display())))?;
            SimConfig::from_toml(&text).map_err(CliError::usage)?
        }
        (None, true) => SimConfig::default(),
        (None, false) => SimConfig::with_addresses(&args.modules).map_err(CliError::usage)?,
    };
    if args.slcan {
        if args.strict {
            return Err(CliError::usage("--strict is about RS232 BCCs; it has no meaning with --slcan"));
        }
        common::serve(&args.serve, SlcanAdapter::new(SimBus::new_can(&config)))
    } else {
        let mut bus = SimBus::new(&config);
        bus.set_strict_bcc(args.strict);
        common::serve(&args.serve, bus)
    }
}

/// Reads the decode input as text (or raw bytes with --raw).
fn read_input(args: &CaptureArgs) -> Result<Result<String, Vec<u8>>, CliError> {
    if !args.hex.is_empty() {
        // Hex bytes or one candump frame; `decode` tells them apart by their shape.
        return Ok(Ok(args.hex.join(" ")));
    }
    let mut input = Vec::new();
    std::io::stdin().read_to_end(&mut input)?;
    if args.raw {
        return Ok(Err(input));
    }
    String::from_utf8(input).map(Ok).map_err(|_| CliError::usage("stdin is not text (use --raw for raw bytes)"))
}

/// Describes a PowerCube payload travelling in `role` (CAN) or as `kind` to/from `address` (RS232).
fn describe_payload(is_ack: bool, broadcast: bool, payload: &Payload) -> String {
    if broadcast {
        return match Broadcast::decode_form(payload) {
            Ok((b, BroadcastForm::Manual)) => format!("broadcast: {b}"),
            Ok((b, BroadcastForm::Padded)) => format!("broadcast: {b} (command + 0x00, as libm5api sends it)"),
            Err(e) => format!("broadcast: not understood ({e})"),
        };
    }
    if is_ack {
        match Reply::decode(payload) {
            Ok(r) => r.to_string(),
            Err(e) => format!("acknowledge not understood: {e}"),
        }
    } else {
        match Request::decode(payload) {
            Ok(r) => r.to_string(),
            Err(e) => format!("command not understood: {e}"),
        }
    }
}

fn describe_can(frame: &CanFrame) -> String {
    match can_wire::from_frame(frame) {
        Ok((Role::Ack(a), p)) => format!("ack from module {a}: {}", describe_payload(true, false, &p)),
        Ok((Role::Get(a), p)) => format!("get to module {a}: {}", describe_payload(false, false, &p)),
        Ok((Role::Put(a), p)) => format!("put to module {a}: {}", describe_payload(false, false, &p)),
        Ok((Role::Broadcast, p)) => describe_payload(false, true, &p),
        Err(e) => format!("not PowerCube: {e}"),
    }
}

fn describe_rs232(frame: &rs232::Rs232Frame) -> String {
    let (dir, is_ack) = match frame.kind {
        TelKind::Send if frame.address == 0 => ("to every module (address 0)", false),
        TelKind::Send => ("to module", false),
        TelKind::Recv => ("from module", true),
    };
    let mut text = if frame.kind == TelKind::Send && frame.address == 0 {
        format!("{dir}: {}", describe_payload(false, true, &frame.payload))
    } else {
        format!("{dir} {}: {}", frame.address, describe_payload(is_ack, false, &frame.payload))
    };
    if !frame.bcc_ok() {
        text.push_str(&format!(" [BCC 0x{:02X} wrong, expected 0x{:02X}]", frame.bcc_received, frame.bcc_computed));
    }
    if !frame.length_ok() {
        text.push_str(&format!(" [TELID length {} for {} bytes]", frame.declared_len, frame.payload.len()));
    }
    text
}

/// A comment line of a capture: `# ...` or `// ...`.
fn is_comment(line: &str) -> bool {
    let line = line.trim_start();
    line.starts_with('#') || line.starts_with("//")
}

/// True if `line` has the shape of a candump line: a log line `(1700000000.000000) can0 0F1#01`, a frame
/// `0F1#01` or `can0 0F1#01`, or a screen line `can0  0F1   [1]  01`. A hex capture (with `#` comment lines)
/// never has it: its words are hex bytes, none with a `#` inside.
fn looks_like_candump(line: &str) -> bool {
    if is_comment(line) {
        return false;
    }
    let words: Vec<&str> = line.split_whitespace().collect();
    let frame_word =
        |w: &str| w.split_once('#').is_some_and(|(id, _)| !id.is_empty() && id.chars().all(|c| c.is_ascii_hexdigit()));
    match words.as_slice() {
        [first, ..] if first.starts_with('(') && first.ends_with(')') => true,
        [frame] => frame_word(frame),
        [_, frame, ..] if frame_word(frame) => true,
        [_, _, len, ..] => len.starts_with('[') && len.ends_with(']'),
        _ => false,
    }
}

/// `motionlink decode powercube`: RS232 bytes (hex or raw) or candump lines.
pub fn decode(args: DecodeArgs) -> Result<(), CliError> {
    let mut out = std::io::stdout().lock();
    let bytes = match read_input(&args.capture)? {
        Ok(text) if text.lines().any(looks_like_candump) => {
            let mut bad = 0;
            for (i, line) in text.lines().enumerate() {
                let line = line.trim();
                if line.is_empty() || is_comment(line) {
                    continue;
                }
                match line.parse::<CandumpLine>() {
                    Ok(l) => writeln!(out, "{:<24}  {}", l.frame.to_string(), describe_can(&l.frame))?,
                    Err(e) => {
                        bad += 1;
                        writeln!(out, "line {}: {e}", i + 1)?;
                    }
                }
            }
            if bad > 0 {
                return Err(CliError::usage(format!("{bad} line(s) are not candump lines")));
            }
            return Ok(());
        }
        Ok(text) => common::parse_hex(&text)?,
        Err(raw) => raw,
    };
    let mut decoder = Rs232Decoder::new();
    let mut frame_bytes = Vec::new();
    let mut frames = 0;
    for &b in &bytes {
        frame_bytes.push(b);
        if b == rs232::STX && frame_bytes.len() > 1 {
            frame_bytes = vec![b];
        }
        match decoder.push(b) {
            Some(Ok(f)) => {
                frames += 1;
                writeln!(out, "{:<36}  {}", common::hex(&frame_bytes), describe_rs232(&f))?;
                frame_bytes.clear();
            }
            Some(Err(e)) => {
                writeln!(out, "{:<36}  error: {e}", "")?;
                if b != rs232::STX {
                    frame_bytes.clear();
                }
            }
            None => {}
        }
    }
    if frames == 0 && !bytes.is_empty() {
        writeln!(out, "no complete RS232 frame in {} byte(s)", bytes.len())?;
    }
    Ok(())
}

/// A CAN link that records every frame, for the demo.
struct TapCan<L> {
    inner: L,
    log: Arc<Mutex<Vec<(bool, CanFrame)>>>,
}

impl<L: CanLink> CanLink for TapCan<L> {
    fn send(&mut self, frame: &CanFrame) -> Result<(), LinkError> {
        motionlink_link::clock::lock(&self.log).push((true, *frame));
        self.inner.send(frame)
    }
    fn recv(&mut self, timeout: Duration) -> Result<Option<CanFrame>, LinkError> {
        let f = self.inner.recv(timeout)?;
        if let Some(f) = f {
            motionlink_link::clock::lock(&self.log).push((false, f));
        }
        Ok(f)
    }
    fn describe(&self) -> String {
        self.inner.describe()
    }
}

/// One example of the demo: a name and what the client does.
type DemoStep<'a> = Box<dyn Fn() -> Result<(), PcError> + 'a>;

/// The manual's chapter 8 (CAN) and 9 (RS232) examples against the emulator (module 17).
pub fn demo(out: &mut dyn Write) -> Result<(), CliError> {
    let color = std::io::stdout().is_terminal();
    let title = |s: &str| if color { format!("\x1b[1m{s}\x1b[0m") } else { s.to_string() };
    writeln!(
        out,
        "{}",
        title("== Schunk / Amtec PowerCube: the manual's chapter 8, CAN examples (module 17, emulated at 1 Mbit/s) ==")
    )?;
    {
        let clock = ManualClock::new_auto();
        let _me = clock.reserve_participant().enter();
        let sim = SimBus::new_can(&SimConfig::with_addresses(&[17]).map_err(CliError::usage)?);
        let can = CanBus::with_emulator(sim, clock.shared(), CanBusConfig::paced(1_000_000));
        let log = Arc::new(Mutex::new(Vec::new()));
        let link = TapCan { inner: can.connect(), log: Arc::clone(&log) };
        let bus = Bus::can(Box::new(link), clock.shared(), BusConfig::can());
        let m = bus.module(17).map_err(cli_err)?;
        let steps: Vec<(&str, DemoStep)> = vec![
            ("Home", Box::new(|| m.home())),
            ("Reset", Box::new(|| m.reset())),
            ("Set ramp motion acceleration", Box::new(|| m.set(Param::TargetAcc, Value::F32(0.5)))),
            ("Set ramp motion velocity", Box::new(|| m.set(Param::TargetVel, Value::F32(0.08)))),
            (
                "Ramp motion command",
                Box::new(|| m.motion(Motion::FRamp { pos: Position::native(0.75) }, AckKind::Simple).map(|_| ())),
            ),
            ("Retrieve module state", Box::new(|| m.state().map(|_| ()))),
            ("Retrieve module position", Box::new(|| m.position().map(|_| ()))),
            (
                "Ramp motion command with extended acknowledge",
                Box::new(|| m.motion(Motion::FRamp { pos: Position::native(0.75) }, AckKind::Extended).map(|_| ())),
            ),
            ("Halt", Box::new(|| m.halt())),
        ];
        for (name, step) in steps {
            step().map_err(cli_err)?;
            writeln!(out, "  {name}")?;
            for (sent, f) in motionlink_link::clock::lock(&log).drain(..) {
                let arrow = if sent { "->" } else { "<-" };
                writeln!(out, "    {arrow} {:<24} {}", f.to_string(), describe_can(&f))?;
            }
        }
        bus.halt_started();
    }
    writeln!(out)?;
    writeln!(
        out,
        "{}",
        title(
            "== Schunk / Amtec PowerCube: the manual's chapter 9, RS232 examples (module 17, emulated at 9600 baud) =="
        )
    )?;
    {
        let clock = ManualClock::new_auto();
        let _me = clock.reserve_participant().enter();
        let sim = SimBus::new(&SimConfig::with_addresses(&[17]).map_err(CliError::usage)?);
        let host = EmulatorHost::new(sim, clock.shared(), PipeConfig::paced(9_600));
        let transcript = Transcript::new();
        let link = TapLink::new(host.connect().0, clock.shared(), transcript.clone());
        let bus = Bus::rs232(Box::new(link), clock.shared(), BusConfig::rs232());
        let m = bus.module(17).map_err(cli_err)?;
        let steps: Vec<(&str, DemoStep)> = vec![
            ("Home", Box::new(|| m.home())),
            ("Reset", Box::new(|| m.reset())),
            ("Set ramp motion acceleration 0.5", Box::new(|| m.set(Param::TargetAcc, Value::F32(0.5)))),
            ("Set ramp motion velocity 0.08", Box::new(|| m.set(Param::TargetVel, Value::F32(0.08)))),
            (
                "Ramp motion command to 0.75",
                Box::new(|| m.motion(Motion::FRamp { pos: Position::native(0.75) }, AckKind::Simple).map(|_| ())),
            ),
            ("Halt (0x02 escaped as 10 82)", Box::new(|| m.halt())),
        ];
        for (name, step) in steps {
            step().map_err(cli_err)?;
            writeln!(out, "  {name}")?;
            for r in transcript.take() {
                let arrow = if r.way == Way::Sent { "->" } else { "<-" };
                let mut d = Rs232Decoder::new();
                let meaning: Vec<String> =
                    d.feed(&r.bytes).map(|f| f.map_or_else(|e| e.to_string(), |f| describe_rs232(&f))).collect();
                writeln!(out, "    {arrow} {:<33} {}", common::hex(&r.bytes), meaning.join("; "))?;
            }
        }
    }
    Ok(())
}
