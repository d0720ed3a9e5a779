//! `motionlink compax`, `motionlink sim compax`, `motionlink decode compax` and the COMPAX part of the demo.

use std::io::Write;
use std::path::PathBuf;
use std::time::Duration;

use motionlink_compax::client::{
    Bus, BusConfig, Error as BusError, MoveOptions, MoveRequest, MoveTarget, TravelLimits,
    DEFAULT_IN_POSITION_TOLERANCE,
};
use motionlink_compax::model::{
    Command, CommandStyle, ModelError, OutputState, ParamId, Position, RampMs, S16Bits, S17Bits, SpeedPercent,
    StatusId, StatusKind, StatusValue, BAUD_RATES,
};
use motionlink_compax::sim::{CompaxBus, SimConfig};
use motionlink_compax::wire::binary::announced_len;
use motionlink_compax::wire::reply::{ReplyDecoder, ReplyError};
use motionlink_compax::wire::request::{ParsedRequest, RequestDecoder, RequestError, RequestEvent};
use motionlink_compax::wire::{Address, Body, EscapedBytes, Mode, ReplyEventRef, ReplyKind, CR};
use motionlink_link::clock::{Clock, ManualClock, SharedClock};
use motionlink_link::link::{Link, SerialSettings};
use motionlink_link::pipe::{EmulatorHost, PipeConfig};
use motionlink_link::transcript::{TapLink, Transcript, Way};
use motionlink_link::url::PortUrl;
use motionlink_link::RealClock;
use serde_json::json;

use crate::common::{self, CaptureArgs, CliError, Row, ServeArgs};

/// `motionlink compax` arguments.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The port: a device path (/dev/ttyUSB0, COM3), tcp://HOST:PORT, or sim.
    #[arg(long)]
    pub port: String,
    /// The drive's address (P194), 1..=31.
    #[arg(long, default_value_t = 1, allow_negative_numbers = true)]
    pub drive: u8,
    /// The drives' operating mode P196 (0..=127): BCC, parity, reply end, address prefix...
    #[arg(long, default_value_t = 0, allow_negative_numbers = true)]
    pub mode: u32,
    /// The drives' baud rate P195 (150, 300, 600, 1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200).
    #[arg(long, default_value_t = 9600, allow_negative_numbers = true)]
    pub baud: u32,
    /// Time a drive may take to start answering, in ms (1..=60000, on top of the wire time).
    #[arg(long, default_value_t = 200, allow_negative_numbers = true)]
    pub timeout_ms: u64,
    /// Send the short command names (PA, PR, SD, AL, OT) instead of the long ones.
    #[arg(long)]
    pub short: bool,
    /// Print JSON instead of a table.
    #[arg(long, global = true)]
    pub json: bool,
    /// What to do.
    #[command(subcommand)]
    pub action: Action,
}

/// `motionlink compax` actions.
#[derive(clap::Subcommand, Debug)]
pub enum Action {
    /// Find the drives on the bus (reads S1 of addresses 1..=31).
    Scan,
    /// Read status values (default: S1 S2 S3 S16 S17 S18).
    Status {
        /// Status values such as S1 S16.
        values: Vec<String>,
    },
    /// Read a parameter, such as P194.
    Get {
        /// The parameter.
        param: String,
    },
    /// Write a parameter, such as P196 8, and read it back (P194..P196 take effect at the drive's next
    /// power-on).
    Set {
        /// The parameter.
        param: String,
        /// The value.
        #[arg(allow_negative_numbers = true)]
        value: f64,
    },
    /// Move the axis, wait until it is at rest, and check it is at its target (a signal stops it). Every
    /// argument is checked before anything is sent.
    Move {
        /// Move to this absolute position (drive's unit).
        #[arg(long, allow_negative_numbers = true, conflicts_with = "rel", required_unless_present = "rel")]
        abs: Option<f64>,
        /// Move by this distance from the drive's target S2 (drive's unit).
        #[arg(long, allow_negative_numbers = true)]
        rel: Option<f64>,
        /// SPEED in percent of the drive's maximum speed (more than 0, at most 100).
        #[arg(long, allow_negative_numbers = true)]
        speed: Option<f64>,
        /// ACCEL: ramp time in ms (0..=32767).
        #[arg(long, allow_negative_numbers = true)]
        accel: Option<u32>,
        /// Send the binary commands.
        #[arg(long)]
        binary: bool,
        /// Give up (and stop the axis) after this many seconds (more than 0).
        #[arg(long, default_value_t = 600.0, allow_negative_numbers = true)]
        timeout_s: f64,
        /// Success only if the axis comes to rest this close to its target (drive's unit, more than 0).
        #[arg(long, default_value_t = DEFAULT_IN_POSITION_TOLERANCE, allow_negative_numbers = true)]
        tolerance: f64,
        /// Refuse targets below this position (checked before anything moves).
        #[arg(long, allow_negative_numbers = true)]
        min_pos: Option<f64>,
        /// Refuse targets above this position (checked before anything moves).
        #[arg(long, allow_negative_numbers = true)]
        max_pos: Option<f64>,
        /// Interval of the status polls while waiting, in ms (1..=10000).
        #[arg(long, default_value_t = 50, allow_negative_numbers = true)]
        poll_ms: u64,
        /// Return once the drive has taken the move (its target read back), without waiting: the move is
        /// handed over and keeps running after the command exits (nothing stops it).
        #[arg(long, conflicts_with = "timeout_s")]
        no_wait: bool,
    },
    /// Read S1 and S17 over and over and print them, one line each, until interrupted.
    Watch {
        /// Interval between two lines, in ms (1..=60000).
        #[arg(long, default_value_t = 200, allow_negative_numbers = true)]
        interval_ms: u64,
    },
    /// Switch an output: OUTPUT ON=S (output 0 is the drive itself: 0 switches it off, 1 on).
    Output {
        /// Output number.
        number: u16,
        /// 0 or 1 (O0: 0, 1 or 2).
        state: u8,
    },
    /// Send a command as it is, such as "S1", "POSA 10$", "!" (flag characters $ , / ? at the end are sent as
    /// flags); prints the reply. A move it starts keeps running after the command exits, unless --wait.
    Raw {
        /// The command.
        command: String,
        /// Wait until a move the command started has ended (a signal stops it; its position is not
        /// checked: use move for that).
        #[arg(long)]
        wait: bool,
        /// With --wait: give up (and stop the axis) after this many seconds (more than 0).
        #[arg(long, default_value_t = 600.0, allow_negative_numbers = true, requires = "wait")]
        timeout_s: f64,
        /// With --wait: interval of the status polls, in ms (1..=10000).
        #[arg(long, default_value_t = 50, requires = "wait", allow_negative_numbers = true)]
        poll_ms: u64,
    },
}

/// `motionlink sim compax` arguments.
#[derive(clap::Args, Debug)]
pub struct SimArgs {
    #[command(flatten)]
    pub serve: ServeArgs,
    /// Addresses of the emulated drives, such as 1,5 (default 1).
    #[arg(long, value_delimiter = ',')]
    pub drives: Option<Vec<u8>>,
    /// P196 of every drive (default 0).
    #[arg(long)]
    pub mode: Option<u32>,
    /// The line's and the drives' baud rate (default 9600).
    #[arg(long)]
    pub baud: Option<u32>,
    /// A TOML file describing the bus (see the motionlink-compax README); the options above override it.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// A parameter besides P194..P196 that every drive models, with its value at power-on, such as P12=0
    /// (repeatable). The drives refuse (E90) every other parameter.
    #[arg(long = "param", value_name = "PNNN=VALUE")]
    pub params: Vec<String>,
}

/// `motionlink decode compax` arguments.
#[derive(clap::Args, Debug)]
pub struct DecodeArgs {
    #[command(flatten)]
    pub capture: CaptureArgs,
    /// P196 of the capture (BCC, reply end, address prefix).
    #[arg(long, default_value_t = 0, allow_negative_numbers = true)]
    pub mode: u32,
    /// Which way the bytes went: auto (guess each telegram), host (requests only), drive (replies only).
    #[arg(long, value_enum, default_value_t = Direction::Auto)]
    pub direction: Direction,
}

/// Direction of a capture.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Direction {
    /// Guess each telegram.
    Auto,
    /// Host to drive.
    Host,
    /// Drive to host.
    Drive,
}

/// How to switch drive `a` on again, as a command line on the same port and bus settings.
fn switch_on_hint(args: &Args, a: u8) -> String {
    let mut cmd = format!("motionlink compax --port {}", args.port);
    if args.mode != 0 {
        cmd.push_str(&format!(" --mode {}", args.mode));
    }
    if args.baud != 9600 {
        cmd.push_str(&format!(" --baud {}", args.baud));
    }
    format!("drive {a} is switched off; to switch it on again: {cmd} --drive {a} output 0 1")
}

/// The error as the user reads it, with how to switch on a drive the error left (or found) switched off;
/// classed by what went wrong in the first place.
fn bus_error_for(args: &Args, e: BusError) -> CliError {
    let mut msg = match (e.root(), common::stop_cause()) {
        (BusError::Cancelled, Some(cause)) => match e.stop_report() {
            Some(stop) => format!("{} received: {stop}", cause.name()),
            None => format!("{} received: nothing was moved", cause.name()),
        },
        _ => e.to_string(),
    };
    let off: Vec<u8> = match &e {
        BusError::SwitchedOff { address, .. } => vec![*address],
        _ => e.stop_report().map(|r| r.switched_off().iter().map(|a| a.get()).collect()).unwrap_or_default(),
    };
    for a in off {
        msg.push('\n');
        msg.push_str(&switch_on_hint(args, a));
    }
    match e.root() {
        BusError::Cancelled => CliError::Interrupted(msg),
        BusError::Device { .. }
        | BusError::MoveTimeout { .. }
        | BusError::NotReached { .. }
        | BusError::TargetMismatch { .. }
        | BusError::SwitchedOff { .. }
        | BusError::ReadBack { .. } => CliError::Device(msg),
        BusError::SyncIncomplete { source, .. } if source.device_code().is_some() => CliError::Device(msg),
        BusError::Invalid(_) | BusError::Wire(_) | BusError::Broadcast(_) | BusError::OutsideLimits { .. } => {
            CliError::Usage(msg)
        }
        BusError::Link(motionlink_link::LinkError::InvalidPort { .. }) => CliError::Usage(msg),
        _ => CliError::Transport(msg),
    }
}

fn bus_error(e: BusError) -> CliError {
    match e.root() {
        BusError::Cancelled if e.stop_report().is_none() => {
            let cause = common::stop_cause().map_or("interrupted".to_string(), |c| format!("{} received", c.name()));
            CliError::Interrupted(format!("{cause}: the action ended before it was done"))
        }
        BusError::Cancelled => CliError::Interrupted(e.to_string()),
        BusError::Device { .. } | BusError::MoveTimeout { .. } => CliError::device(e),
        BusError::SyncIncomplete { source, .. } if source.device_code().is_some() => CliError::device(e),
        BusError::Invalid(_) | BusError::Wire(_) | BusError::Broadcast(_) => CliError::usage(e),
        _ => CliError::transport(e),
    }
}

fn model_error(e: ModelError) -> CliError {
    CliError::usage(e)
}

/// A signal came before anything was sent (or between reads): ends the action with exit code 128 + n.
fn check_interrupt(bus: &Bus, what: &str) -> Result<(), CliError> {
    if bus.is_cancelled() {
        let cause = common::stop_cause().map_or("interrupted".to_string(), |c| format!("{} received", c.name()));
        return Err(CliError::Interrupted(format!("{cause}; {what}")));
    }
    Ok(())
}

/// A duration in ms given as `name`, within `min..=max`.
fn checked_ms(name: &str, ms: u64, min: u64, max: u64) -> Result<Duration, CliError> {
    if (min..=max).contains(&ms) {
        Ok(Duration::from_millis(ms))
    } else {
        Err(CliError::usage(format!("{name} {ms}: give {min} to {max} ms")))
    }
}

/// A duration in seconds given as `name`: more than 0, finite.
fn checked_s(name: &str, s: f64) -> Result<Duration, CliError> {
    Duration::try_from_secs_f64(s)
        .ok()
        .filter(|t| !t.is_zero())
        .ok_or_else(|| CliError::usage(format!("{name} {s}: give a number of seconds above 0")))
}

/// The arguments of `move`, checked before anything is sent.
struct MovePlan {
    request: MoveRequest,
    tolerance: f64,
    poll: Duration,
}

#[allow(clippy::too_many_arguments)]
fn plan_move(
    abs: Option<f64>,
    rel: Option<f64>,
    speed: Option<f64>,
    accel: Option<u32>,
    binary: bool,
    timeout_s: f64,
    tolerance: f64,
    (min_pos, max_pos): (Option<f64>, Option<f64>),
    poll_ms: u64,
) -> Result<MovePlan, CliError> {
    let target = match (abs, rel) {
        (Some(a), None) => MoveTarget::Absolute(Position::new(a).map_err(|e| CliError::usage(format!("--abs: {e}")))?),
        (None, Some(r)) => MoveTarget::Relative(Position::new(r).map_err(|e| CliError::usage(format!("--rel: {e}")))?),
        _ => return Err(CliError::usage("give one of --abs and --rel")),
    };
    let speed = speed.map(SpeedPercent::new).transpose().map_err(|e| CliError::usage(format!("--speed: {e}")))?;
    let accel = accel.map(RampMs::new).transpose().map_err(|e| CliError::usage(format!("--accel: {e}")))?;
    let timeout = checked_s("--timeout-s", timeout_s)?;
    if !(tolerance.is_finite() && tolerance > 0.0 && tolerance <= 1e6) {
        return Err(CliError::usage(format!("--tolerance {tolerance}: give a distance above 0 (at most 1000000)")));
    }
    let limit = |name: &str, v: Option<f64>| {
        v.map(Position::new).transpose().map_err(|e| CliError::usage(format!("{name}: {e}")))
    };
    let limits = TravelLimits::new(limit("--min-pos", min_pos)?, limit("--max-pos", max_pos)?)
        .map_err(|e| CliError::usage(format!("--min-pos / --max-pos: {e}")))?;
    let poll = checked_ms("--poll-ms", poll_ms, 1, 10_000)?;
    let request = MoveRequest { target, speed, accel, binary, limits, timeout: Some(timeout) };
    Ok(MovePlan { request, tolerance, poll })
}

fn parse_mode(p196: u32) -> Result<Mode, CliError> {
    Mode::from_p196(p196).map_err(|e| CliError::usage(format!("--mode: {e}")))
}

/// Checks the bus arguments (before anything is opened or sent) and opens the port.
fn open(args: &Args, configure: impl FnOnce(&mut BusConfig)) -> Result<Bus, CliError> {
    let mode = parse_mode(args.mode)?;
    Address::drive(args.drive).map_err(|e| CliError::usage(format!("--drive {}: {e}", args.drive)))?;
    if !BAUD_RATES.contains(&args.baud) {
        return Err(CliError::usage(format!("--baud {}: not a rate P195 accepts ({BAUD_RATES:?})", args.baud)));
    }
    let reply_timeout = checked_ms("--timeout-ms", args.timeout_ms, 1, 60_000)?;
    let url: PortUrl = args.port.parse()?;
    let clock: SharedClock = RealClock::shared();
    // Installed before the port opens: a signal from here on stops what the command starts.
    let token = common::interrupt_token();
    let link: Box<dyn Link> = match url {
        PortUrl::Sim => {
            let cfg = SimConfig::bus(&[args.drive], args.mode, args.baud);
            let bus = CompaxBus::new(cfg).map_err(CliError::usage)?;
            let host = EmulatorHost::new(bus, clock.clone(), PipeConfig::paced(args.baud));
            Box::new(host.connect().0)
        }
        other => {
            let mut settings = SerialSettings::new(args.baud);
            settings.parity = mode.parity;
            other.open_byte_link(settings)?
        }
    };
    let mut cfg = BusConfig::new(mode, args.baud);
    cfg.reply_timeout = reply_timeout;
    cfg.style = if args.short { CommandStyle::Short } else { CommandStyle::Long };
    configure(&mut cfg);
    let mut bus = Bus::new(link, clock, cfg);
    bus.set_cancel(token);
    Ok(bus)
}

fn status_rows(id: StatusId, v: &StatusValue) -> (Row, serde_json::Value) {
    let info = id.info();
    let name = info.map_or("(meaning not documented)", |i| i.name);
    let unit = info.map_or("", |i| i.unit);
    let (shown, js) = match v {
        StatusValue::S16(b) => {
            let names: Vec<&str> = b.names_set().collect();
            (format!("{b}  [{}]", names.join(", ")), json!({"bits": b.to_string(), "value": b.0, "set": names}))
        }
        StatusValue::S17(b) => {
            let names: Vec<&str> = b.names_set().collect();
            (format!("{b}  [{}]", names.join(", ")), json!({"bits": b.to_string(), "value": b.0, "set": names}))
        }
        StatusValue::Position(p) => (format!("{v} {unit}").trim_end().to_string(), json!(p.units())),
        StatusValue::Number(n) => (format!("{v} {unit}").trim_end().to_string(), json!(n)),
        other => (other.to_string(), json!(other.to_string())),
    };
    ((format!("{id} {name}"), shown), json!({"status": id.to_string(), "name": name, "unit": unit, "value": js}))
}

/// Runs `motionlink compax`.
pub fn run(args: Args) -> Result<(), CliError> {
    let mut out = std::io::stdout().lock();
    // Every argument of an action is checked before the port is opened: nothing is sent for an action that
    // cannot be made.
    let move_plan = match &args.action {
        Action::Move { abs, rel, speed, accel, binary, timeout_s, tolerance, min_pos, max_pos, poll_ms, .. } => Some(
            plan_move(*abs, *rel, *speed, *accel, *binary, *timeout_s, *tolerance, (*min_pos, *max_pos), *poll_ms)?,
        ),
        _ => None,
    };
    let mut poll = move_plan.as_ref().map(|p| p.poll);
    let mut raw_wait = None;
    let mut watch_interval = None;
    match &args.action {
        Action::Raw { wait: true, timeout_s, poll_ms, .. } => {
            raw_wait = Some(checked_s("--timeout-s", *timeout_s)?);
            poll = Some(checked_ms("--poll-ms", *poll_ms, 1, 10_000)?);
        }
        Action::Watch { interval_ms } => watch_interval = Some(checked_ms("--interval-ms", *interval_ms, 1, 60_000)?),
        Action::Output { number, state } => {
            OutputState::new(*number, *state).map_err(model_error)?;
        }
        Action::Get { param } => {
            ParamId::parse(param).map_err(model_error)?;
        }
        Action::Set { param, value } => {
            ParamId::parse(param).and_then(|id| id.check(*value)).map_err(model_error)?;
        }
        Action::Status { values } => {
            for v in values {
                StatusId::parse(v).map_err(model_error)?;
            }
        }
        _ => {}
    }
    let tolerance = move_plan.as_ref().map(|p| p.tolerance);
    let mut bus = open(&args, |cfg| {
        if let Some(p) = poll {
            cfg.poll_interval = p;
        }
        if let Some(t) = tolerance {
            cfg.in_position_tolerance = t;
        }
    })?;
    let drive = Address::drive(args.drive).map_err(CliError::usage)?;
    match &args.action {
        Action::Scan => {
            // A signal ends the scan between two addresses.
            let found = bus.scan(1..=31).map_err(bus_error)?;
            if args.json {
                let list: Vec<_> =
                    found.iter().map(|(a, p)| json!({"address": a.get(), "position": p.units()})).collect();
                common::print_json(&mut out, &json!({"drives": list}))?;
            } else if found.is_empty() {
                writeln!(out, "no drive answered on {}", args.port)?;
            } else {
                let rows: Vec<Row> = found.iter().map(|(a, p)| (format!("drive {a}"), format!("S1 = {p}"))).collect();
                common::print_table(&mut out, &rows)?;
            }
            if found.is_empty() {
                return Err(CliError::transport("no drive answered"));
            }
        }
        Action::Status { values } => {
            let ids: Vec<StatusId> = if values.is_empty() {
                [1, 2, 3, 16, 17, 18].iter().filter_map(|&n| StatusId::new(n).ok()).collect()
            } else {
                values.iter().map(|v| StatusId::parse(v)).collect::<Result<_, _>>().map_err(model_error)?
            };
            let mut rows = Vec::new();
            let mut js = Vec::new();
            for id in ids {
                check_interrupt(&bus, "status read stopped")?;
                let v = bus.read_status(drive, id).map_err(bus_error)?;
                let (row, j) = status_rows(id, &v);
                rows.push(row);
                js.push(j);
            }
            if args.json {
                common::print_json(&mut out, &json!({"drive": drive.get(), "status": js}))?;
            } else {
                common::print_table(&mut out, &rows)?;
            }
        }
        Action::Get { param } => {
            let id = ParamId::parse(param).map_err(model_error)?;
            let v = bus.read_param(drive, id).map_err(bus_error)?;
            let desc = id.info().map_or("", |i| i.description);
            if args.json {
                common::print_json(&mut out, &json!({"drive": drive.get(), "param": id.to_string(), "value": v}))?;
            } else {
                common::print_table(&mut out, &[(format!("{id} {desc}").trim_end().to_string(), format!("{v}"))])?;
            }
        }
        Action::Set { param, value } => {
            let id = ParamId::parse(param).map_err(model_error)?;
            // Written and read back: a value that reads back otherwise is an error (exit code 1).
            bus.write_param(drive, id, *value).map_err(|e| bus_error_for(&args, e))?;
            let note = match id.info() {
                Some(i) if i.valid_from == motionlink_compax::model::ValidFrom::PowerOn => {
                    " (takes effect at the drive's next power-on)"
                }
                _ => "",
            };
            if args.json {
                common::print_json(
                    &mut out,
                    &json!({"drive": drive.get(), "param": id.to_string(), "value": value, "read_back": true}),
                )?;
            } else {
                writeln!(out, "{id} = {value}, read back{note}")?;
            }
        }
        Action::Move { no_wait, .. } => {
            let plan = move_plan.ok_or_else(|| CliError::usage("move: no plan"))?;
            check_interrupt(&bus, "nothing was sent")?;
            if *no_wait {
                let started = bus.start_checked_move(drive, &plan.request).map_err(|e| bus_error_for(&args, e))?;
                if bus.is_cancelled() {
                    // A signal came while the move was being sent: it is stopped, not handed over.
                    return Err(bus_error_for(
                        &args,
                        BusError::Aborted { cause: Box::new(BusError::Cancelled), stop: bus.stop_started() },
                    ));
                }
                // Handed over: the move runs on after this command exits.
                bus.release(&[drive]);
                let now = bus.read_position(drive).map_err(bus_error)?;
                if args.json {
                    common::print_json(
                        &mut out,
                        &json!({"drive": drive.get(), "target": started.target.units(), "position": now.units(),
                                "waited": false}),
                    )?;
                } else {
                    writeln!(out, "drive {drive}: target {}, position {now} (moving on)", started.target)?;
                }
            } else {
                let bar = common::progress_bar(0, format!("drive {drive}"));
                let mut started_at: Option<f64> = None;
                let report = bus.move_to(drive, &plan.request, &mut |p| {
                    let s = *started_at.get_or_insert_with(|| {
                        let distance = match plan.request.target {
                            MoveTarget::Absolute(t) => t.units() - p.units(),
                            MoveTarget::Relative(d) => d.units(),
                        };
                        bar.set_length((distance.abs() * 1000.0).round() as u64);
                        p.units()
                    });
                    bar.set_position(((p.units() - s).abs() * 1000.0).round() as u64);
                });
                bar.finish_and_clear();
                let report = report.map_err(|e| bus_error_for(&args, e))?;
                if args.json {
                    common::print_json(
                        &mut out,
                        &json!({"drive": drive.get(), "target": report.target.units(), "position": report.reached.units(),
                                "difference": report.difference(), "tolerance": plan.tolerance, "waited": true}),
                    )?;
                } else {
                    writeln!(out, "drive {drive}: target {}, position {}", report.target, report.reached)?;
                }
            }
        }
        Action::Watch { .. } => {
            let interval = watch_interval.unwrap_or(Duration::from_millis(200));
            loop {
                if bus.is_cancelled() {
                    break;
                }
                let s1 = bus.read_position(drive).map_err(bus_error)?;
                let s17 = bus.read_s17(drive).map_err(bus_error)?;
                let moving = s17.bit(S17Bits::COMMAND_ACTIVE);
                if args.json {
                    common::print_json(
                        &mut out,
                        &json!({"drive": drive.get(), "position": s1.units(), "s17": s17.to_string(), "moving": moving}),
                    )?;
                } else {
                    writeln!(out, "drive {drive}  S1 = {s1}  {}", if moving { "moving" } else { "at rest" })?;
                }
                out.flush()?;
                match bus.pause(interval) {
                    Ok(()) => {}
                    Err(BusError::Cancelled) => break,
                    Err(e) => return Err(bus_error(e)),
                }
            }
            // Interrupted: a signal ends the command with 128 + n (main), a closed stdout quietly.
            if common::stop_cause() == Some(common::StopCause::OutputClosed) {
                return Err(CliError::OutputClosed);
            }
        }
        Action::Output { number, state } => {
            let st = OutputState::new(*number, *state).map_err(model_error)?;
            bus.set_output(drive, *number, st, false).map_err(bus_error)?;
            if args.json {
                common::print_json(&mut out, &json!({"drive": drive.get(), "output": number, "state": state}))?;
            } else {
                writeln!(out, "drive {drive}: OUTPUT O{number}={state}")?;
            }
        }
        Action::Raw { command, .. } => {
            let reply = bus.raw(drive, command).map_err(|e| bus_error_for(&args, e))?;
            let started = bus.started();
            let mut waited = false;
            if bus.is_cancelled() && !started.is_empty() {
                // A signal came while it was being sent: what it started is stopped, not handed over.
                return Err(bus_error_for(
                    &args,
                    BusError::Aborted { cause: Box::new(BusError::Cancelled), stop: bus.stop_started() },
                ));
            }
            if let (Some(timeout), false) = (raw_wait, started.is_empty()) {
                bus.wait_reached(&started, Some(timeout), &mut |_, _| {}).map_err(|e| bus_error_for(&args, e))?;
                waited = true;
            } else {
                // A move sent raw runs on after the command exits (as with move --no-wait): handed over.
                bus.release(&started);
            }
            if args.json {
                common::print_json(
                    &mut out,
                    &json!({"drive": drive.get(), "command": command, "reply": reply, "waited": waited}),
                )?;
            } else {
                match reply {
                    Some(r) if r.is_empty() => writeln!(out, "(acknowledged)")?,
                    Some(r) => writeln!(out, "{r}")?,
                    None => writeln!(out, "(no reply due)")?,
                }
            }
        }
    }
    Ok(())
}

/// Runs `motionlink sim compax`.
pub fn sim(args: SimArgs) -> Result<(), CliError> {
    let mut cfg = match &args.config {
        Some(path) => {
            let text = std::fs::read_to_string(path)
                .map_err(|e| CliError::usage(format!("cannot read {}: {e}", path.display())))?;
            SimConfig::from_toml(&text).map_err(CliError::usage)?
        }
        None => SimConfig::default(),
    };
    if let Some(drives) = &args.drives {
        let base = SimConfig::bus(drives, cfg.p196, cfg.baud_rate);
        cfg.drives = base.drives;
    }
    if let Some(m) = args.mode {
        parse_mode(m)?;
        cfg.p196 = m;
        cfg.drives.iter_mut().for_each(|d| d.p196 = None);
    }
    if let Some(b) = args.baud {
        cfg.baud_rate = b;
        cfg.drives.iter_mut().for_each(|d| d.baud_rate = None);
    }
    for p in &args.params {
        let (name, value) =
            p.split_once('=').ok_or_else(|| CliError::usage(format!("--param {p}: expected PNNN=VALUE")))?;
        let id = ParamId::parse(name).map_err(|e| CliError::usage(format!("--param {p}: {e}")))?;
        let value: f64 =
            value.trim().parse().map_err(|_| CliError::usage(format!("--param {p}: {value:?} is not a number")))?;
        cfg = cfg.with_param(id, value);
    }
    let bus = CompaxBus::new(cfg).map_err(CliError::usage)?;
    common::serve(&args.serve, bus)
}

/// One telegram found in a capture.
struct Found {
    bytes: Vec<u8>,
    text: String,
    /// For a request: its command was recognised (an `Execute`, a known command or binary telegram),
    /// even if its BCC is wrong.
    recognised: bool,
    /// For a request: its BCC is wrong (the drive answers E72).
    bad_bcc: bool,
}

fn annotate_request(bytes: &[u8], mode: &Mode) -> Option<Found> {
    let mut d = RequestDecoder::new(mode);
    for (i, &b) in bytes.iter().enumerate() {
        match d.push(b) {
            None => {}
            Some(RequestEvent::Frame(f)) => {
                let found = |text: String, recognised: bool, bad_bcc: bool| {
                    Some(Found { bytes: bytes[..=i].to_vec(), text, recognised, bad_bcc })
                };
                return match f.parse() {
                    Ok(p) => {
                        let bcc = match f.bcc() {
                            Some((r, _)) => format!(" [BCC {r:02X} ok]"),
                            None => String::new(),
                        };
                        let (what, recognised) = describe_request(&p);
                        found(format!("{what}{bcc}"), recognised, false)
                    }
                    Err(RequestError::Bcc { received, computed }) => match f.parse_ignoring_bcc() {
                        // What it says, and that the drive refuses it for its BCC.
                        Ok(p) => {
                            let (what, recognised) = describe_request(&p);
                            let bcc =
                                format!(" [BCC {received:02X} wrong, computed {computed:02X}: the drive answers E72]");
                            found(format!("{what}{bcc}"), recognised, true)
                        }
                        Err(e) => found(format!("request, bad: {e}"), false, true),
                    },
                    Err(e) => found(format!("request, bad: {e}"), false, false),
                };
            }
            Some(_) => return None,
        }
    }
    None
}

/// `request to drive 1: S1 read ...` and whether the command was recognised.
fn describe_request(p: &ParsedRequest<'_>) -> (String, bool) {
    let who = if p.address == 32 { "all drives".to_string() } else { format!("drive {}", p.address) };
    let (what, recognised) = match p.body {
        Body::Execute => ("! execute the buffered command".to_string(), true),
        Body::Binary(b) => match Command::from_binary(&b) {
            Ok(c) => (format!("binary {c}"), true),
            Err(e) => (format!("binary {b} ({e})"), false),
        },
        Body::Command(t) => match Command::parse(t) {
            Ok(c) => (describe_command(&c), true),
            Err(_) => (format!("{:?} (not a known command)", String::from_utf8_lossy(t)), false),
        },
    };
    let mut flags = Vec::new();
    if p.flags.position_message {
        flags.push("$ position-reached message");
    }
    if p.flags.buffer {
        flags.push(", store in buffer");
    }
    if p.flags.no_reply {
        flags.push("/ no reply");
    }
    if p.flags.echo {
        flags.push("? echo");
    }
    let flags = if flags.is_empty() { String::new() } else { format!(" [{}]", flags.join(", ")) };
    (format!("request to {who}: {what}{flags}"), recognised)
}

fn describe_command(c: &Command) -> String {
    match c {
        Command::ReadStatus(id) => {
            format!("{c} read {}", id.info().map_or("a status value", |i| i.description))
        }
        Command::ReadParam(id) => format!("{c} read {}", id.info().map_or("a parameter", |i| i.description)),
        Command::WriteParam(id, _) => format!("{c} write {}", id.info().map_or("a parameter", |i| i.description)),
        other => other.to_string(),
    }
}

fn annotate_reply(bytes: &[u8], mode: &Mode) -> Option<Found> {
    let mut d = ReplyDecoder::new(mode);
    // The first event, and the bytes up to the one that completed it.
    let (used, event) = d.decode(bytes);
    let text = match event? {
        ReplyEventRef::Reply(r) if !r.line().iter().all(|c| (0x20..0x7F).contains(c)) => return None,
        ReplyEventRef::Reply(r) => {
            let who = r.address().map_or(String::new(), |a| format!(" from drive {a}"));
            let what = match r.kind() {
                ReplyKind::Ack => "acknowledged".to_string(),
                ReplyKind::Error(c) => format!("error {}", motionlink_compax::model::ErrorCode(c)),
                ReplyKind::PositionReached => "$ position reached".to_string(),
                ReplyKind::Comparator(n) => format!("comparator {n} switched"),
                ReplyKind::Text(t) => describe_reply_text(t),
            };
            let bcc = if mode.bcc { " [BCC ok]" } else { "" };
            format!("reply{who}: {what}{bcc}")
        }
        ReplyEventRef::Error(e) => {
            return Some(Found {
                bytes: bytes[..used].to_vec(),
                text: format!("reply, bad: {e}"),
                recognised: false,
                bad_bcc: matches!(e, ReplyError::Bcc { .. }),
            })
        }
        ReplyEventRef::Flow(x) => (if x { "XOFF" } else { "XON" }).to_string(),
    };
    // A reply that decoded cleanly.
    Some(Found { bytes: bytes[..used].to_vec(), text, recognised: true, bad_bcc: false })
}

fn describe_reply_text(t: &str) -> String {
    // "S016: 1000 0000" and the like: name the value.
    if let Some(rest) = t.strip_prefix('S') {
        let n: String = rest.chars().take_while(char::is_ascii_digit).collect();
        if let Ok(id) = n.parse::<u8>().map_err(|_| ()).and_then(|n| StatusId::new(n).map_err(|_| ())) {
            if let Ok(v) = StatusValue::parse(id, t.as_bytes()) {
                let extra = match (id.kind(), v) {
                    (StatusKind::BitsS16, StatusValue::S16(b)) => {
                        format!(" [{}]", b.names_set().collect::<Vec<_>>().join(", "))
                    }
                    (StatusKind::BitsS17, StatusValue::S17(b)) => {
                        format!(" [{}]", b.names_set().collect::<Vec<_>>().join(", "))
                    }
                    _ => String::new(),
                };
                let name = id.info().map_or("status value", |i| i.name);
                return format!("{id} ({name}) = {v}{extra}");
            }
        }
    }
    format!("{t:?}")
}

/// Runs `motionlink decode compax`.
pub fn decode(args: DecodeArgs) -> Result<(), CliError> {
    let bytes = common::read_capture(&args.capture)?;
    let mode = parse_mode(args.mode)?;
    let mut out = std::io::stdout().lock();
    for line in decode_lines(&bytes, &mode, args.direction) {
        writeln!(out, "{line}")?;
    }
    Ok(())
}

fn decode_lines(bytes: &[u8], mode: &Mode, dir: Direction) -> Vec<String> {
    let mut lines = Vec::new();
    let mut pos = 0;
    let mut garbage = Vec::new();
    let flush = |garbage: &mut Vec<u8>, lines: &mut Vec<String>| {
        if !garbage.is_empty() {
            lines.push(format!("{:<40} garbage: {}", common::hex(garbage), EscapedBytes(garbage)));
            garbage.clear();
        }
    };
    while pos < bytes.len() {
        let rest = &bytes[pos..];
        let looks_like_request = rest[0].is_ascii_digit()
            && rest
                .iter()
                .skip(1)
                .find(|b| !b.is_ascii_digit())
                .is_some_and(|&b| b != CR || announced_len(b).is_some());
        let found = match dir {
            Direction::Host => annotate_request(rest, mode),
            Direction::Drive => annotate_reply(rest, mode),
            Direction::Auto => {
                let req = if looks_like_request { annotate_request(rest, mode) } else { None };
                match req {
                    Some(f) if f.recognised && !f.bad_bcc => Some(f),
                    // A recognised request whose BCC alone is wrong is that request, unless the bytes also
                    // read as a good reply.
                    Some(f) if f.recognised => match annotate_reply(rest, mode) {
                        Some(r) if r.recognised => Some(r),
                        _ => Some(f),
                    },
                    other => annotate_reply(rest, mode).or(other),
                }
            }
        };
        match found {
            Some(f) if !f.bytes.is_empty() => {
                flush(&mut garbage, &mut lines);
                lines.push(format!("{:<40} {}", common::hex(&f.bytes), f.text));
                pos += f.bytes.len();
            }
            _ => {
                garbage.push(bytes[pos]);
                pos += 1;
            }
        }
    }
    flush(&mut garbage, &mut lines);
    lines
}

/// The COMPAX part of `motionlink demo`: the manual's chapter 4.5 example and a move.
pub fn demo(out: &mut dyn Write) -> Result<(), CliError> {
    writeln!(out, "== Parker COMPAX: the manual's chapter 4.5, S1 of drives 1 and 5 (P194 = 1 and 5, P195 = 9600) ==")?;
    for (p196, title) in
        [(8, "4.5.1 BASIC program with BCC (P196 = 8)"), (0, "4.5.2 BASIC program without BCC (P196 = 0)")]
    {
        writeln!(out, "-- {title}")?;
        let (mut bus, transcript, clock) = demo_bus(p196)?;
        let _me = clock.reserve_participant().enter();
        for a in [1u8, 5] {
            let addr = Address::drive(a).map_err(CliError::usage)?;
            let p = bus.read_position(addr).map_err(bus_error)?;
            print_transcript(out, &transcript, &parse_mode(p196)?)?;
            writeln!(out, "   drive {a}: S1 = {p}  (at {})", clock.now())?;
        }
    }
    writeln!(out, "-- a move: drive 5, SPEED 50, ACCEL 200, POSA 25 with the position-reached message")?;
    let (mut bus, transcript, clock) = demo_bus(0)?;
    let _me = clock.reserve_participant().enter();
    let five = Address::drive(5).map_err(CliError::usage)?;
    bus.set_speed(five, SpeedPercent::new(50.0).map_err(model_error)?, false).map_err(bus_error)?;
    bus.set_accel(five, RampMs::new(200).map_err(model_error)?, false).map_err(bus_error)?;
    let target = Position::new(25.0).map_err(model_error)?;
    bus.move_absolute(five, target, MoveOptions { binary: false, message: true }).map_err(bus_error)?;
    print_transcript(out, &transcript, &Mode::default())?;
    let t0 = clock.now();
    bus.wait_reached(&[five], Some(Duration::from_secs(10)), &mut |_, _| {}).map_err(bus_error)?;
    print_transcript(out, &transcript, &Mode::default())?;
    let p = bus.read_position(five).map_err(bus_error)?;
    let s16 = bus.read_s16(five).map_err(bus_error)?;
    print_transcript(out, &transcript, &Mode::default())?;
    writeln!(
        out,
        "   drive 5 reached {p} after {:.3} s of device time; S16 = {s16} (position reached: {})",
        (clock.now() - t0).as_secs_f64(),
        s16.bit(S16Bits::POSITION_REACHED)
    )?;
    let s17 = bus.read_s17(five).map_err(bus_error)?;
    writeln!(out, "   S17 = {s17} (command active: {})", s17.bit(S17Bits::COMMAND_ACTIVE))?;
    Ok(())
}

fn demo_bus(p196: u32) -> Result<(Bus, Transcript, ManualClock), CliError> {
    let clock = ManualClock::new_auto();
    let sim = CompaxBus::new(SimConfig::bus(&[1, 5], p196, 9600)).map_err(CliError::usage)?;
    let host = EmulatorHost::new(sim, clock.shared(), PipeConfig::paced(9600));
    let transcript = Transcript::new();
    let link = TapLink::new(host.connect().0, clock.shared(), transcript.clone());
    let bus = Bus::new(Box::new(link), clock.shared(), BusConfig::new(parse_mode(p196)?, 9600));
    Ok((bus, transcript, clock))
}

fn print_transcript(out: &mut dyn Write, transcript: &Transcript, mode: &Mode) -> Result<(), CliError> {
    for r in transcript.take() {
        let (arrow, lines) = match r.way {
            Way::Sent => ("->", decode_lines(&r.bytes, mode, Direction::Host)),
            Way::Received => ("<-", decode_lines(&r.bytes, mode, Direction::Drive)),
        };
        for l in lines {
            writeln!(out, "   {arrow} {l}")?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(clap::Parser, Debug)]
    struct TestCli {
        #[command(flatten)]
        args: Args,
    }

    fn args(line: &[&str]) -> Args {
        TestCli::parse_from(std::iter::once("compax").chain(line.iter().copied())).args
    }

    #[test]
    fn errors_map_to_exit_codes_and_say_how_to_switch_a_drive_on() {
        let a = args(&["--port", "tcp://gw:4001", "--mode", "8", "--drive", "3", "status"]);
        let not_reached =
            BusError::NotReached { address: 3, target: 100.0, reached: 37.5, difference: -62.5, tolerance: 0.01 };
        let e = bus_error_for(&a, not_reached);
        assert_eq!(e.exit_code(), 1);
        assert!(e.to_string().contains("target 100, reached 37.5, difference -62.500"), "{e}");
        let stop = motionlink_compax::client::StopReport {
            drives: vec![(Address::drive(3).unwrap(), motionlink_compax::client::StopOutcome::SwitchedOff)],
        };
        let mismatch = BusError::Aborted {
            cause: Box::new(BusError::TargetMismatch { address: 3, requested: 15.0, taken: 14.0 }),
            stop,
        };
        let e = bus_error_for(&a, mismatch);
        assert_eq!(e.exit_code(), 1);
        let text = e.to_string();
        assert!(text.contains("took target 14 instead of 15"), "{text}");
        assert!(text.contains("motionlink compax --port tcp://gw:4001 --mode 8 --drive 3 output 0 1"), "{text}");
        let lost = BusError::Aborted {
            cause: Box::new(BusError::Timeout { address: 3, command: "S17".into(), attempts: 4 }),
            stop: motionlink_compax::client::StopReport {
                drives: vec![(
                    Address::drive(3).unwrap(),
                    motionlink_compax::client::StopOutcome::NotConfirmed { reason: "no reply".into() },
                )],
            },
        };
        let e = bus_error_for(&a, lost);
        assert_eq!(e.exit_code(), 3);
        assert!(e.to_string().contains("may still be moving") && !e.to_string().contains("output 0 1"), "{e}");
        let limits = BusError::OutsideLimits { address: 3, target: 50.0, side: "above the maximum", limit: 40.0 };
        assert_eq!(bus_error_for(&a, limits).exit_code(), 2);
        let off = BusError::SwitchedOff { address: 3, o0: 0, refused: None };
        let e = bus_error_for(&a, off);
        assert_eq!(e.exit_code(), 1);
        assert!(e.to_string().contains("--drive 3 output 0 1"), "{e}");
        let read_back =
            BusError::ReadBack { address: 3, param: ParamId::new(3).unwrap(), wrote: -1055.88, read: -1055.89 };
        assert_eq!(bus_error_for(&a, read_back).exit_code(), 1);
    }

    #[test]
    fn decode_both_directions_of_the_manuals_example() {
        let mode = Mode::from_p196(8).unwrap();
        let mut bytes = b"1S1\r\x53".to_vec();
        bytes.extend_from_slice(b"S001: 0.000\r\n>");
        bytes.push(motionlink_compax::wire::bcc(b"S001: 0.000"));
        let lines = decode_lines(&bytes, &mode, Direction::Auto);
        assert_eq!(lines.len(), 2, "{lines:?}");
        assert!(lines[0].contains("request to drive 1: S1 read actual position"), "{lines:?}");
        assert!(lines[0].contains("BCC 53 ok"), "{lines:?}");
        assert!(lines[1].contains("S1 (actual position) = 0"), "{lines:?}");
    }

    #[test]
    fn decode_auto_reads_a_request_with_a_bad_bcc_as_that_request() {
        let mode = Mode::from_p196(8).unwrap();
        // The manual's `1S1` with a wrong BCC ('X', not 0x53), then the drive's E72.
        let mut bytes = b"1S1\rX".to_vec();
        bytes.extend_from_slice(b"E72\r\n>");
        bytes.push(motionlink_compax::wire::bcc(b"E72"));
        let lines = decode_lines(&bytes, &mode, Direction::Auto);
        assert_eq!(lines.len(), 2, "{lines:?}");
        assert!(lines[0].contains("request to drive 1: S1 read actual position"), "{lines:?}");
        assert!(lines[0].contains("BCC 58 wrong, computed 53"), "{lines:?}");
        assert!(lines[1].contains("E72"), "{lines:?}");
        // An unknown command with a bad BCC is still not taken for a request.
        let lines = decode_lines(b"1XYZ\rQ", &mode, Direction::Auto);
        assert!(!lines.iter().any(|l| l.contains("request to drive 1")), "{lines:?}");
    }

    #[test]
    fn decode_binary_and_garbage() {
        let mode = Mode::default();
        let bytes = [0xFF, b'1', 0x88, 0x41, 0, 0, 0, 0x68, 0x01, 0, b'E', b'9', b'2', CR, b'\n', b'>'];
        let lines = decode_lines(&bytes, &mode, Direction::Auto);
        assert!(lines[0].contains("garbage"), "{lines:?}");
        assert!(lines[1].contains("binary POSA 360"), "{lines:?}");
        assert!(lines[2].contains("E92"), "{lines:?}");
    }
}
