//! `motionlink compax`, `motionlink sim compax`, `motionlink decode compax` and the COMPAX part of the demo.

use std::io::Write;
use std::path::PathBuf;
use std::time::Duration;

use motionlink_compax::client::{Bus, BusConfig, Error as BusError, MoveOptions};
use motionlink_compax::model::{
    Command, CommandStyle, ModelError, OutputState, ParamId, Position, RampMs, S16Bits, S17Bits, SpeedPercent,
    StatusId, StatusKind, StatusValue,
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
    #[arg(long, default_value_t = 1)]
    pub drive: u8,
    /// The drives' operating mode P196 (0..=127): BCC, parity, reply end, address prefix...
    #[arg(long, default_value_t = 0)]
    pub mode: u32,
    /// The drives' baud rate P195.
    #[arg(long, default_value_t = 9600)]
    pub baud: u32,
    /// Time a drive may take to start answering, in ms (on top of the wire time).
    #[arg(long, default_value_t = 200)]
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
    /// Write a parameter, such as P196 8 (P194..P196 take effect at the drive's next power-on).
    Set {
        /// The parameter.
        param: String,
        /// The value.
        #[arg(allow_negative_numbers = true)]
        value: f64,
    },
    /// Move the axis and wait until the position is reached (Ctrl-C stops it). Every argument is checked
    /// before anything is sent.
    Move {
        /// Move to this absolute position (drive's unit).
        #[arg(long, allow_negative_numbers = true, conflicts_with = "rel", required_unless_present = "rel")]
        abs: Option<f64>,
        /// Move by this distance (drive's unit).
        #[arg(long, allow_negative_numbers = true)]
        rel: Option<f64>,
        /// SPEED in percent of the drive's maximum speed.
        #[arg(long)]
        speed: Option<f64>,
        /// ACCEL: ramp time in ms.
        #[arg(long)]
        accel: Option<u32>,
        /// Send the binary commands.
        #[arg(long)]
        binary: bool,
        /// Give up (and stop the axis) after this many seconds (more than 0).
        #[arg(long, default_value_t = 600.0, allow_negative_numbers = true)]
        timeout_s: f64,
        /// Return once the drive has taken the move, without waiting: the move is handed over and keeps
        /// running after the command exits (nothing stops it).
        #[arg(long, conflicts_with = "timeout_s")]
        no_wait: bool,
    },
    /// Switch an output: OUTPUT ON=S (output 0 is the drive itself: 0 switches it off, 1 on).
    Output {
        /// Output number.
        number: u16,
        /// 0 or 1 (O0: 0, 1 or 2).
        state: u8,
    },
    /// Send a command as it is, such as "S1", "POSA 10$", "!" (flag characters $ , / ? at the end are sent as
    /// flags); prints the reply. A move it starts keeps running after the command exits.
    Raw {
        /// The command.
        command: String,
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
    #[arg(long, default_value_t = 0)]
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

fn bus_error(e: BusError) -> CliError {
    match e {
        BusError::Cancelled => CliError::Interrupted(e.to_string()),
        BusError::Device { .. } | BusError::MoveTimeout { .. } => CliError::device(e),
        BusError::SyncIncomplete { ref source, .. } if source.device_code().is_some() => CliError::device(e),
        BusError::Invalid(_) | BusError::Wire(_) | BusError::Broadcast(_) => CliError::usage(e),
        BusError::Link(l) => l.into(),
        _ => CliError::transport(e),
    }
}

fn model_error(e: ModelError) -> CliError {
    CliError::usage(e)
}

/// Ctrl-C came before anything was sent (or between reads): ends the action with exit code 130.
fn check_interrupt(bus: &Bus, what: &str) -> Result<(), CliError> {
    if bus.is_cancelled() {
        return Err(CliError::Interrupted(format!("interrupted; {what}")));
    }
    Ok(())
}

/// The arguments of `move`, checked before anything is sent.
struct MovePlan {
    target: MoveTarget,
    speed: Option<SpeedPercent>,
    accel: Option<RampMs>,
    timeout: Duration,
}

enum MoveTarget {
    Absolute(Position),
    Relative(Position),
}

fn plan_move(
    abs: Option<f64>,
    rel: Option<f64>,
    speed: Option<f64>,
    accel: Option<u32>,
    timeout_s: f64,
) -> Result<MovePlan, CliError> {
    let target = match (abs, rel) {
        (Some(a), None) => MoveTarget::Absolute(Position::new(a).map_err(|e| CliError::usage(format!("--abs: {e}")))?),
        (None, Some(r)) => MoveTarget::Relative(Position::new(r).map_err(|e| CliError::usage(format!("--rel: {e}")))?),
        _ => return Err(CliError::usage("give one of --abs and --rel")),
    };
    let speed = speed.map(SpeedPercent::new).transpose().map_err(|e| CliError::usage(format!("--speed: {e}")))?;
    let accel = accel.map(RampMs::new).transpose().map_err(|e| CliError::usage(format!("--accel: {e}")))?;
    let timeout = Duration::try_from_secs_f64(timeout_s)
        .ok()
        .filter(|t| !t.is_zero())
        .ok_or_else(|| CliError::usage(format!("--timeout-s {timeout_s}: give a number of seconds above 0")))?;
    Ok(MovePlan { target, speed, accel, timeout })
}

fn parse_mode(p196: u32) -> Result<Mode, CliError> {
    Mode::from_p196(p196).map_err(|e| CliError::usage(format!("--mode: {e}")))
}

fn open(args: &Args) -> Result<Bus, CliError> {
    let mode = parse_mode(args.mode)?;
    Address::drive(args.drive).map_err(|e| CliError::usage(format!("--drive: {e}")))?;
    let url: PortUrl = args.port.parse()?;
    let clock: SharedClock = RealClock::shared();
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
    cfg.reply_timeout = Duration::from_millis(args.timeout_ms);
    cfg.style = if args.short { CommandStyle::Short } else { CommandStyle::Long };
    let mut bus = Bus::new(link, clock, cfg);
    bus.set_cancel(common::interrupt_token());
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
    // A move's arguments are checked before the port is opened: nothing is sent for a move that cannot be
    // made.
    let mut move_plan = match &args.action {
        Action::Move { abs, rel, speed, accel, timeout_s, .. } => {
            Some(plan_move(*abs, *rel, *speed, *accel, *timeout_s)?)
        }
        _ => None,
    };
    let mut bus = open(&args)?;
    let drive = Address::drive(args.drive).map_err(CliError::usage)?;
    match &args.action {
        Action::Scan => {
            // Ctrl-C ends the scan between two addresses.
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
            bus.write_param(drive, id, *value).map_err(bus_error)?;
            let note = match id.info() {
                Some(i) if i.valid_from == motionlink_compax::model::ValidFrom::PowerOn => {
                    " (takes effect at the drive's next power-on)"
                }
                _ => "",
            };
            if args.json {
                common::print_json(&mut out, &json!({"drive": drive.get(), "param": id.to_string(), "value": value}))?;
            } else {
                writeln!(out, "{id} = {value}{note}")?;
            }
        }
        Action::Move { binary, no_wait, .. } => {
            let plan = move_plan.take().ok_or_else(|| CliError::usage("move: no plan"))?;
            let opts = MoveOptions { binary: *binary, message: false };
            check_interrupt(&bus, "nothing was sent")?;
            let start = bus.read_position(drive).map_err(bus_error)?;
            let target = match plan.target {
                MoveTarget::Absolute(p) => p,
                MoveTarget::Relative(d) => Position::new(start.units() + d.units())
                    .map_err(|e| CliError::usage(format!("--rel {d} from {start}: {e}")))?,
            };
            let distance = (target.units() - start.units()).abs();
            check_interrupt(&bus, "nothing was moved")?;
            if let Some(s) = plan.speed {
                bus.set_speed(drive, s, *binary).map_err(bus_error)?;
            }
            if let Some(a) = plan.accel {
                bus.set_accel(drive, a, *binary).map_err(bus_error)?;
            }
            // The move itself is not sent once Ctrl-C has come (Error::Cancelled).
            match plan.target {
                MoveTarget::Absolute(p) => bus.move_absolute(drive, p, opts),
                MoveTarget::Relative(d) => bus.move_relative(drive, d, opts),
            }
            .map_err(bus_error)?;
            if *no_wait {
                // Handed over: the move runs on after this command exits.
                bus.release(&[drive]);
            } else {
                let bar =
                    common::progress_bar((distance * 1000.0).round() as u64, format!("drive {drive} to {target}"));
                let r = bus.wait_reached(&[drive], Some(plan.timeout), &mut |_, p| {
                    bar.set_position(((p.units() - start.units()).abs() * 1000.0).round() as u64);
                });
                bar.finish_and_clear();
                r.map_err(bus_error)?;
            }
            let end = bus.read_position(drive).map_err(bus_error)?;
            if args.json {
                common::print_json(
                    &mut out,
                    &json!({"drive": drive.get(), "target": target.units(), "position": end.units(),
                            "waited": !*no_wait}),
                )?;
            } else if *no_wait {
                writeln!(out, "drive {drive}: target {target}, position {end} (moving on)")?;
            } else {
                writeln!(out, "drive {drive}: target {target}, position {end}")?;
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
        Action::Raw { command } => {
            let reply = bus.raw(drive, command).map_err(bus_error)?;
            // A move sent raw runs on after the command exits (as with move --no-wait): handed over.
            let started = bus.started();
            bus.release(&started);
            if args.json {
                common::print_json(&mut out, &json!({"drive": drive.get(), "command": command, "reply": reply}))?;
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
