//! `motionlink scu`, `motionlink sim scu`, `motionlink decode scu` and the SCU part of `motionlink demo`.

use std::io::Write;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use motionlink_link::cancel::CancelToken;
use motionlink_link::clock::Clock;
use motionlink_link::link::{Connector, Link, SerialSettings};
use motionlink_link::pipe::{EmulatorHost, PipeConfig};
use motionlink_link::transcript::{TapLink, Transcript, Way};
use motionlink_link::url::PortUrl;
use motionlink_link::{ManualClock, RealClock, SharedClock, Timestamp};
use motionlink_scu::describe::{describe_incoming, describe_reply, describe_request};
use motionlink_scu::model::Speed;
use motionlink_scu::model::{
    lookup, status1, Actuator, DataEntry, DataEntryExt, DataIndex, ErrorCode, FlagSet, Flags, Function, Item,
    MotionDirection, MotionFunction, SafetyId, StopMode,
};
use motionlink_scu::session::{MoveProgress, MoveReport};
use motionlink_scu::value::{SpeedMode, Value};
use motionlink_scu::wire::{
    capture_step, request_to_vec, CaptureDirection, CaptureItem, Incoming, Request, Telegram, WireError,
};
use motionlink_scu::{Client as ScuClient, ClientConfig, Error as ScuError, FunctionMap, MoveOptions, StrokeLimits};
use motionlink_scu::{Emulator, SimConfig};
use serde_json::json;

use crate::common::{self, CaptureArgs, CliError, Row, ServeArgs};

/// `motionlink scu` arguments.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The port: a serial device (/dev/ttyUSB0, COM3), tcp://HOST:PORT (a serial gateway or `motionlink sim scu`),
    /// or sim (an emulator in this process).
    #[arg(long, value_name = "PORT")]
    pub port: String,
    /// Baud rate of a serial port: 38400 on standard units, 9600 or 19200 on customised ones.
    #[arg(long, default_value_t = 38_400, value_parser = parse_baud)]
    pub baud: u32,
    /// Safety_ID sent with RO: 0 a timeout stops all motion and locks remote motion until RO, 1 stops all
    /// motion, 2 stops remote motion only.
    #[arg(long, default_value_t = 0, value_parser = clap::value_parser!(u8).range(0..=2))]
    pub safety: u8,
    /// How long to wait for the reply to RO, in ms (the manual allows the unit 2000 ms). In remote mode replies
    /// are awaited at most 1000 ms (twice the unit's watchdog), or this if it is shorter.
    #[arg(long, default_value_t = 2000, value_name = "MS", allow_hyphen_values = true,
          value_parser = clap::value_parser!(u64).range(1..=60_000))]
    pub reply_timeout: u64,
    /// Which actuators each motion function drives (the unit's parameterisation, which the data list does not
    /// show): a preset, scp11 (Fn drives An), tlt (F1 both columns, F2 A1, F3 A2) or liftkit (F1 A1, F2 A2, F8
    /// both), or one function, F1=1,2. Repeat to combine (--functions scp11 --functions F7=1,2). Without it,
    /// move gives every connected actuator the target and reports the ones that moved.
    #[arg(long = "functions", value_name = "MAP")]
    pub functions: Vec<String>,
    /// The travel range of an actuator for move targets, ACTUATOR=MIN:MAX in counts (such as 1=0:865), instead of
    /// the virtual limits the unit reports in its UserPositionData. Repeat for several actuators.
    #[arg(long = "stroke", value_name = "A=MIN:MAX")]
    pub stroke: Vec<String>,
    /// How close to its target a move must end to succeed, in counts.
    #[arg(long, default_value_t = 5, value_name = "COUNTS", allow_hyphen_values = true,
          value_parser = clap::value_parser!(u32).range(0..=10_000))]
    pub tolerance: u32,
    /// How often a move polls the actuators, in ms (each poll is two reads, 8 ms of the 38400-baud line).
    #[arg(long, default_value_t = 50, value_name = "MS", allow_hyphen_values = true,
          value_parser = clap::value_parser!(u64).range(5..=10_000))]
    pub poll_interval: u64,
    /// How the unit takes remote speeds: percent (standard units, "speed select relative") or
    /// counts-per-second (units parameterised for "speed select absolute", 0..1000 counts/s).
    #[arg(long, value_enum, default_value_t = SpeedModeArg::Percent, value_name = "MODE")]
    pub speed_mode: SpeedModeArg,
    /// Emulator configuration (TOML) when the port is sim.
    #[arg(long, value_name = "FILE")]
    pub sim_config: Option<PathBuf>,
    /// Print JSON instead of a table.
    #[arg(long, global = true)]
    pub json: bool,
    #[command(subcommand)]
    pub action: Action,
}

/// `--speed-mode`: how the unit's parameterisation gives remote speeds.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum SpeedModeArg {
    /// Percent of the full speed, 0..100.
    Percent,
    /// Encoder counts per second, 0..1000.
    CountsPerSecond,
}

impl From<SpeedModeArg> for SpeedMode {
    fn from(m: SpeedModeArg) -> SpeedMode {
        match m {
            SpeedModeArg::Percent => SpeedMode::Percent,
            SpeedModeArg::CountsPerSecond => SpeedMode::CountsPerSecond,
        }
    }
}

/// What to do.
#[derive(clap::Subcommand, Debug)]
pub enum Action {
    /// Firmware and configuration, actuators, positions, state, last error.
    Info,
    /// Read a data-list entry or group, by name (actual_position_a1, actual_positions) or index (0x0011).
    Get {
        /// Name or index.
        item: String,
    },
    /// Write a remote data entry (0x3xxx), such as remote_speed_f1 80 or remote_position_a1 400.
    Set {
        /// Name or index.
        item: String,
        /// The value, in the entry's unit (percent, counts...).
        value: String,
    },
    /// Move an actuator to a position (counts) and wait until it is there; every actuator the function drives
    /// goes there too. Exits 0 only if each ended within --tolerance of the target. Ctrl-C stops it.
    Move {
        /// Actuator 1..6.
        actuator: u8,
        /// Target position in encoder counts.
        #[arg(allow_negative_numbers = true)]
        position: i32,
        /// Speed in percent, 1..100 (or counts/s, 1..1000, on units set to absolute speed).
        #[arg(long, default_value = "100", value_name = "SPEED", allow_hyphen_values = true)]
        speed: String,
        /// Motion function (1..10) that drives the actuator; default: the one with its number (F1 for A1).
        #[arg(long)]
        function: Option<u8>,
    },
    /// Follow targets read from stdin while the motion runs (streamed setpoints): each line gives the target
    /// in counts, one number for every actuator the function drives or one per actuator ("400" or "400 410"
    /// or "a1=400 a2=410"), or a new speed ("speed 60"); "#" starts a comment. EOF, Ctrl-C or a bad line stops
    /// the motion.
    Follow {
        /// Actuator 1..6 (its function, and every actuator that function drives, follow the targets).
        actuator: u8,
        /// Motion function (1..10); default: the one with the actuator's number.
        #[arg(long)]
        function: Option<u8>,
        /// Speed in percent, 1..100 (or counts/s, 1..1000, on units set to absolute speed).
        #[arg(long, default_value = "100", value_name = "SPEED", allow_hyphen_values = true)]
        speed: String,
        /// At most this many setpoint updates per second (1..100); lines that come faster are merged: the
        /// newest target wins.
        #[arg(long, default_value = "20", value_name = "HZ", allow_hyphen_values = true)]
        rate: String,
    },
    /// Run a function until it ends or Ctrl-C: a motion function (F1..F10) with a direction (in, out, mem1..mem4,
    /// int-in, int-out, remote, or 0..9), or F11 buzzer, F17/F18 outputs, F20 emergency stop, F21/F22 LEDs with "on".
    Run {
        /// F1..F22 (or 1..22).
        function: String,
        /// Direction of a motion function, or "on".
        direction: String,
        /// Stop after this many seconds (default: when the motion ends, or Ctrl-C).
        #[arg(long, value_name = "S", allow_hyphen_values = true)]
        seconds: Option<String>,
    },
    /// Stop a function (RS): motions fast, or along the ramp with --soft.
    Stop {
        /// F1..F22 (or 1..22).
        function: String,
        /// Soft stop (along the stop ramp) instead of a fast stop.
        #[arg(long)]
        soft: bool,
    },
    /// Live positions and state until Ctrl-C.
    Watch {
        /// Time between samples, in ms (10 .. 3600000).
        #[arg(long, default_value_t = 250, value_name = "MS", allow_hyphen_values = true,
              value_parser = clap::value_parser!(u64).range(10..=3_600_000))]
        interval: u64,
        /// Stop after this many samples (at least 1).
        #[arg(long, allow_hyphen_values = true, value_parser = clap::value_parser!(u64).range(1..))]
        count: Option<u64>,
    },
    /// The error history (Error_Code 1..5) with each bit's cause.
    Errors,
}

/// `motionlink sim scu` arguments.
#[derive(clap::Args, Debug)]
pub struct SimArgs {
    #[command(flatten)]
    pub serve: ServeArgs,
    /// Parameterisation (TOML): actuators, function mapping, stroke, speed. See the README.
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Start from a preset: scp11 (default; actuator n on Fn), tlt (F1 drives both columns, F2 and F3 one each)
    /// or liftkit (F1 actuator 1, F2 actuator 2, F8 both, as the public LIFTKIT/TLT drivers assume).
    #[arg(long, value_parser = ["scp11", "tlt", "liftkit"])]
    pub preset: Option<String>,
}

/// `motionlink decode scu` arguments.
#[derive(clap::Args, Debug)]
pub struct DecodeArgs {
    #[command(flatten)]
    pub capture: CaptureArgs,
    /// Print one JSON object per telegram.
    #[arg(long)]
    pub json: bool,
}

fn parse_baud(s: &str) -> Result<u32, String> {
    match s.parse::<u32>() {
        Ok(b @ (9_600 | 19_200 | 38_400)) => Ok(b),
        _ => Err(format!("{s:?}: an SCU runs at 9600, 19200 or 38400 baud")),
    }
}

fn scu_error(e: ScuError) -> CliError {
    common::classified(&e)
}

fn load_sim_config(path: Option<&PathBuf>, preset: Option<&str>) -> Result<SimConfig, CliError> {
    let mut config = preset.and_then(SimConfig::preset).unwrap_or_default();
    if let Some(path) = path {
        let text = std::fs::read_to_string(path)
            .map_err(|e| CliError::usage(format!("cannot read {}: {e}", path.display())))?;
        let text = match preset {
            Some(p) if !text.contains("preset") => format!("preset = \"{p}\"\n{text}"),
            _ => text,
        };
        config = SimConfig::from_toml(&text).map_err(|e| CliError::usage(format!("{}: {e}", path.display())))?;
    }
    Ok(config)
}

/// The session's settings from the command line, checked before anything is sent.
fn client_config(args: &Args) -> Result<ClientConfig, CliError> {
    let safety_id = SafetyId::from_code(args.safety)
        .ok_or_else(|| CliError::usage(format!("--safety {}: the Safety_ID is 0, 1 or 2", args.safety)))?;
    let mut function_map = FunctionMap::unknown();
    for spec in &args.functions {
        function_map = function_map.apply(spec).map_err(|e| CliError::usage(format!("--functions {e}")))?;
    }
    let mut stroke_limits = [None; 6];
    for spec in &args.stroke {
        let (a, limits) = parse_stroke(spec)?;
        stroke_limits[usize::from(a.number() - 1)] = Some(limits);
    }
    let config = ClientConfig {
        safety_id,
        reply_timeout: Duration::from_millis(args.reply_timeout),
        speed_mode: args.speed_mode.into(),
        function_map,
        stroke_limits,
        position_tolerance_counts: args.tolerance,
        poll_interval: Duration::from_millis(args.poll_interval),
        ..ClientConfig::default()
    };
    config.validate().map_err(|e| CliError::usage(e.to_string()))?;
    Ok(config)
}

/// `--stroke 1=0:865`.
fn parse_stroke(spec: &str) -> Result<(Actuator, StrokeLimits), CliError> {
    let bad = || CliError::usage(format!("--stroke {spec:?}: give ACTUATOR=MIN:MAX in counts, such as 1=0:865"));
    let (a, range) = spec.split_once('=').ok_or_else(bad)?;
    let a = a.trim().trim_start_matches(['A', 'a']).parse::<u8>().ok().and_then(Actuator::new).ok_or_else(bad)?;
    let (lo, hi) = range.split_once(':').ok_or_else(bad)?;
    let lo: i32 = lo.trim().parse().map_err(|_| bad())?;
    let hi: i32 = hi.trim().parse().map_err(|_| bad())?;
    if lo > hi {
        return Err(CliError::usage(format!("--stroke {spec:?}: {lo} is above {hi}")));
    }
    Ok((a, StrokeLimits { min_counts: lo, max_counts: hi }))
}

/// `--speed` of a motion: a whole number from 1 to the speed mode's maximum (0 would never move).
fn parse_speed(text: &str, mode: SpeedMode) -> Result<u16, CliError> {
    let range = format!("1..{} {}", mode.max(), mode.unit());
    match text.trim().parse::<i64>() {
        Ok(v) if (1..=i64::from(mode.max())).contains(&v) => Ok(v as u16),
        Ok(v) => Err(CliError::usage(format!(
            "--speed {v}: a motion needs {range}{}",
            if v == 0 { " (0 would never move)" } else { "" }
        ))),
        Err(_) => Err(CliError::usage(format!("--speed {text:?}: give a whole number, {range}"))),
    }
}

/// A speed checked by [`parse_speed`], in the unit the session takes.
fn typed_speed(client: &ScuClient, raw: u16) -> Result<Speed, CliError> {
    let mode = client.config().speed_mode;
    Speed::of_mode(mode, raw)
        .ok_or_else(|| CliError::usage(format!("--speed {raw}: more than {} {}", mode.max(), mode.unit())))
}

/// `--rate` of `follow`: 1..100 updates per second.
fn parse_rate(text: &str) -> Result<u32, CliError> {
    match text.trim().parse::<i64>() {
        Ok(v) if (1..=100).contains(&v) => Ok(v as u32),
        _ => Err(CliError::usage(format!("--rate {text:?}: give 1..100 updates per second"))),
    }
}

/// `--seconds` of `run`: a finite, non-negative number of seconds (at most a day).
fn parse_seconds(text: &str) -> Result<Duration, CliError> {
    match text.trim().parse::<f64>() {
        Ok(s) if s.is_finite() && (0.0..=86_400.0).contains(&s) => Ok(Duration::from_secs_f64(s)),
        _ => Err(CliError::usage(format!("--seconds {text:?}: give a number of seconds, 0 .. 86400"))),
    }
}

/// The motion function of `move` and `follow`: `--function`, or the one with the actuator's number.
fn motion_function(actuator: Actuator, function: Option<u8>) -> Result<MotionFunction, CliError> {
    let n = function.unwrap_or(actuator.number());
    MotionFunction::new(n).ok_or_else(|| CliError::usage(format!("--function {n}: the motion functions are F1..F10")))
}

fn connect(args: &Args, config: ClientConfig) -> Result<ScuClient, CliError> {
    let port: PortUrl = args.port.parse()?;
    let clock = RealClock::shared();
    let connector: Connector = match &port {
        PortUrl::Sim => {
            let mut sim_config = load_sim_config(args.sim_config.as_ref(), None)?;
            if args.sim_config.is_none() {
                // The emulated unit is parameterised the way the command was told the unit is.
                sim_config.speed_mode = args.speed_mode.into();
            }
            let sim = Emulator::new(sim_config).map_err(|e| CliError::usage(e.to_string()))?;
            let host = EmulatorHost::new(sim, Arc::clone(&clock), PipeConfig::paced(args.baud));
            Box::new(move || Ok(Box::new(host.connect().0) as Box<dyn Link>))
        }
        p if p.is_can() => return Err(CliError::usage(format!("{p}: the SCU speaks RS232, not CAN"))),
        p => {
            if args.sim_config.is_some() {
                return Err(CliError::usage("--sim-config is only for --port sim"));
            }
            let p = p.clone();
            let settings = SerialSettings::new(args.baud);
            Box::new(move || p.open_byte_link(settings))
        }
    };
    ScuClient::open(connector, clock, config).map_err(scu_error)
}

fn parse_item(text: &str) -> Result<Item, CliError> {
    lookup(text).ok_or_else(|| {
        CliError::usage(format!(
            "{text:?} is not a data-list entry: give a name such as actual_position_a1 or an index such as 0x0011"
        ))
    })
}

fn parse_actuator(n: u8) -> Result<Actuator, CliError> {
    Actuator::new(n).ok_or_else(|| CliError::usage(format!("actuator {n}: actuators are 1..6")))
}

fn parse_function(text: &str) -> Result<Function, CliError> {
    Function::parse(text).ok_or_else(|| {
        CliError::usage(format!(
            "{text:?} is not a function: F1..F10 motion, F11 buzzer, F17/F18 outputs, F20 emergency stop, F21/F22 LEDs"
        ))
    })
}

fn parse_direction(text: &str) -> Result<MotionDirection, CliError> {
    let d = match text.to_ascii_lowercase().as_str() {
        "none" | "undefined" => MotionDirection::Undefined,
        "in" => MotionDirection::In,
        "out" => MotionDirection::Out,
        "mem1" => MotionDirection::Memory1,
        "mem2" => MotionDirection::Memory2,
        "mem3" => MotionDirection::Memory3,
        "mem4" => MotionDirection::Memory4,
        "int-in" => MotionDirection::IntermediateIn,
        "int-out" => MotionDirection::IntermediateOut,
        "remote" => MotionDirection::RemotePosition,
        other => other.parse::<u8>().ok().and_then(MotionDirection::from_code).ok_or_else(|| {
            CliError::usage(format!(
                "{text:?} is not a direction: in, out, mem1..mem4, int-in, int-out, remote, none, or 0..9"
            ))
        })?,
    };
    Ok(d)
}

fn value_rows(values: &[(&'static DataEntry, Value)]) -> Vec<Row> {
    values.iter().map(|(e, v)| (format!("{} ({})", e.name, e.index()), v.to_string())).collect()
}

fn values_json(values: &[(&'static DataEntry, Value)]) -> serde_json::Value {
    let mut map = serde_json::Map::new();
    for (e, v) in values {
        map.insert(e.name.to_string(), v.to_json());
    }
    serde_json::Value::Object(map)
}

/// `motionlink scu ...`
pub fn run(args: Args) -> Result<(), CliError> {
    // Check everything that can be checked before the port is opened: nothing is sent for bad input.
    let config = client_config(&args)?;
    let mode: SpeedMode = args.speed_mode.into();
    match &args.action {
        Action::Get { item } | Action::Set { item, .. } => {
            parse_item(item)?;
        }
        Action::Move { actuator, function, speed, .. } => {
            motion_function(parse_actuator(*actuator)?, *function)?;
            parse_speed(speed, mode)?;
        }
        Action::Follow { actuator, function, speed, rate } => {
            motion_function(parse_actuator(*actuator)?, *function)?;
            parse_speed(speed, mode)?;
            parse_rate(rate)?;
        }
        Action::Run { function, direction, seconds } => {
            if let Function::Motion(_) = parse_function(function)? {
                parse_direction(direction)?;
            } else if !direction.eq_ignore_ascii_case("on") {
                return Err(CliError::usage(format!("{function} is switched with \"on\", not {direction:?}")));
            }
            if let Some(s) = seconds {
                parse_seconds(s)?;
            }
        }
        Action::Stop { function, .. } => {
            parse_function(function)?;
        }
        _ => {}
    }
    let interrupt = common::interrupt_token();
    let client = connect(&args, config)?;
    let mut out = std::io::stdout().lock();
    let result = act(&client, &args, &mut out, &interrupt);
    // Stop what was started and leave remote mode, whatever happened.
    let started = client.started_functions();
    let closed = client.close();
    finish(result, closed, &started)
}

/// The command's result after the session was closed: a failed close while functions were still started means
/// their stop was not confirmed, and the message says so (keeping the exit code of what went wrong first).
fn finish(result: Result<(), CliError>, closed: Result<(), ScuError>, started: &[u8]) -> Result<(), CliError> {
    let close_error = match closed {
        Ok(()) if started.is_empty() => return result,
        Ok(()) => {
            // The end of the session stopped what the action had left started, and the unit acknowledged it.
            let functions: Vec<String> = started.iter().map(|id| format!("F{}", id + 1)).collect();
            let stopped = format!("{} stopped (the unit acknowledged RS)", functions.join(", "));
            return result.map_err(|e| match e {
                CliError::Device(m) => CliError::Device(format!("{m}; {stopped}")),
                CliError::Usage(m) => CliError::Usage(format!("{m}; {stopped}")),
                CliError::Transport(m) => CliError::Transport(format!("{m}; {stopped}")),
                CliError::Interrupted(m) => CliError::Interrupted(format!("{m}; {stopped}")),
                CliError::OutputClosed => CliError::OutputClosed,
            });
        }
        Err(e) => e,
    };
    if started.is_empty() {
        return result.and(Err(scu_error(close_error)));
    }
    let functions: Vec<String> = started.iter().map(|id| format!("F{}", id + 1)).collect();
    let unconfirmed = format!(
        "stopping {} was NOT confirmed by the unit ({close_error}): the actuators may still be moving. The unit \
         stops remote motions by itself 500 ms after the last RC it receives (its watchdog); this program sends \
         none once it has ended",
        functions.join(", ")
    );
    Err(match result {
        Ok(()) => CliError::Transport(unconfirmed),
        Err(CliError::Device(m)) => CliError::Device(format!("{m}; then {unconfirmed}")),
        Err(CliError::Usage(m)) => CliError::Usage(format!("{m}; then {unconfirmed}")),
        Err(CliError::Transport(m)) => CliError::Transport(format!("{m}; then {unconfirmed}")),
        Err(CliError::Interrupted(m)) => CliError::Interrupted(format!("{m}; then {unconfirmed}")),
        Err(CliError::OutputClosed) => CliError::Interrupted(format!("stdout closed; {unconfirmed}")),
    })
}

fn act(client: &ScuClient, args: &Args, out: &mut dyn Write, interrupt: &CancelToken) -> Result<(), CliError> {
    // A Ctrl-C while the session was being opened: nothing was started; the session is closed (RA).
    if interrupt.is_cancelled() {
        return Err(CliError::Interrupted("interrupted before the action started".into()));
    }
    match &args.action {
        Action::Info => info(client, args.json, out),
        Action::Get { item } => {
            let it = parse_item(item)?;
            let values = client.get(it.index()).map_err(scu_error)?;
            if args.json {
                let (value, unit) = match it {
                    Item::Entry(e) => (values[0].1.to_json(), e.kind.unit()),
                    Item::Group(_) => (values_json(&values), ""),
                };
                common::print_json(
                    out,
                    &json!({"index": it.index().to_string(), "name": it.name(), "value": value, "unit": unit}),
                )
            } else {
                common::print_table(out, &value_rows(&values))
            }
        }
        Action::Set { item, value } => {
            let it = parse_item(item)?;
            let Item::Entry(e) = it else {
                return Err(CliError::usage(format!("{} is a group; set its entries one by one", it.name())));
            };
            let v = Value::parse(e.kind, value).map_err(|err| CliError::usage(format!("{}: {err}", e.name)))?;
            // set() reads the value back and fails if the unit holds another.
            client.set(e.index(), &v).map_err(scu_error)?;
            if args.json {
                common::print_json(
                    out,
                    &json!({"index": e.index().to_string(), "name": e.name, "value": v.to_json(), "read_back": true}),
                )
            } else {
                common::print_table(
                    out,
                    &[(format!("{} ({})", e.name, e.index()), format!("{v} (written, read back)"))],
                )
            }
        }
        Action::Move { actuator, position, speed, function } => {
            let a = parse_actuator(*actuator)?;
            let function = motion_function(a, *function)?;
            let speed = parse_speed(speed, client.config().speed_mode)?;
            let start = client.position(a).map_err(scu_error)?;
            let bar = common::progress_bar(u64::from(start.abs_diff(*position)), format!("{a} -> {position}"));
            let progress = |p: &MoveProgress| bar.set_position(u64::from(p.position_counts.abs_diff(p.start_counts)));
            let options = MoveOptions { cancel: Some(interrupt), progress: Some(&progress), function: Some(function) };
            let result = client.move_to(a, *position, typed_speed(client, speed)?, &options);
            bar.finish_and_clear();
            let report = result.map_err(scu_error)?;
            print_move_report(out, &report, args.json)
        }
        Action::Follow { actuator, function, speed, rate } => {
            let a = parse_actuator(*actuator)?;
            let function = motion_function(a, *function)?;
            let speed = parse_speed(speed, client.config().speed_mode)?;
            follow(client, a, function, speed, parse_rate(rate)?, args.json, interrupt, out)
        }
        Action::Run { function, direction, seconds } => {
            let limit = seconds.as_deref().map(parse_seconds).transpose()?;
            run_function(client, function, direction, limit, interrupt, out)
        }
        Action::Stop { function, soft } => {
            match parse_function(function)? {
                Function::Motion(m) => {
                    client.stop_motion(m, if *soft { StopMode::Soft } else { StopMode::Fast }).map_err(scu_error)?
                }
                f => client.switch(f, false).map_err(scu_error)?,
            }
            writeln!(out, "stopped")?;
            Ok(())
        }
        Action::Watch { interval, count } => watch(client, args.json, *interval, *count, interrupt, out),
        Action::Errors => errors(client, args.json, out),
    }
}

/// Actuators whose status says they are connected, with their status 1.
fn connected_actuators(client: &ScuClient) -> Result<Vec<(Actuator, u8)>, CliError> {
    let raw = client.get_raw(DataIndex(0x0170)).map_err(scu_error)?;
    Ok(Actuator::all().zip(raw).filter(|(_, s)| s & status1::AVAILABLE != 0).collect())
}

fn status_text(s: u8) -> String {
    Value::Flags(Flags { set: FlagSet::ActuatorStatus1, bits: u32::from(s) }).to_string()
}

fn info(client: &ScuClient, json: bool, out: &mut dyn Write) -> Result<(), CliError> {
    let get = |i: u16| client.get_value(DataIndex(i)).map_err(scu_error);
    let firmware = get(0x0001)?;
    let configuration = get(0x0002)?;
    let mains = get(0x0100)?;
    let last_error = get(0x00D1)?;
    let actuators = connected_actuators(client)?;
    let positions = client.get(DataIndex(0x0010)).map_err(scu_error)?;
    let position = |a: Actuator| positions[usize::from(a.number() - 1)].1.clone();
    if json {
        let acts: Vec<_> = actuators
            .iter()
            .map(|(a, s)| {
                json!({"actuator": a.number(), "position": position(*a).to_json(), "status": s,
                       "moving": s & status1::MOTION != 0})
            })
            .collect();
        common::print_json(
            out,
            &json!({"port": client.port(), "firmware": firmware.to_json(), "configuration": configuration.to_json(),
                    "battery_mains": mains.to_json(), "last_error": last_error.to_json(), "actuators": acts}),
        )
    } else {
        let mut rows: Vec<Row> = vec![
            ("port".into(), client.port().to_string()),
            ("firmware".into(), firmware.to_string()),
            ("configuration".into(), configuration.to_string()),
            ("battery/mains".into(), mains.to_string()),
            ("last error".into(), last_error.to_string()),
        ];
        for (a, s) in &actuators {
            rows.push((format!("actuator {}", a.number()), format!("{}, {}", position(*a), status_text(*s))));
        }
        common::print_table(out, &rows)
    }
}

fn errors(client: &ScuClient, json: bool, out: &mut dyn Write) -> Result<(), CliError> {
    let history = client.error_history().map_err(scu_error)?;
    if json {
        let list: Vec<_> = history.iter().map(|c| Value::ErrorCode(*c).to_json()).collect();
        return common::print_json(out, &json!({"errors": list}));
    }
    let mut rows = Vec::new();
    for (i, code) in history.iter().enumerate() {
        let label = if i == 0 {
            "error code 1 (last recent)".to_string()
        } else {
            format!("error code {} (history {i})", i + 1)
        };
        rows.push((label, format!("0x{:08X}", code.0)));
        for b in code.bits() {
            rows.push((format!("  bit {}", b.number()), format!("{}; reaction: {}", b.cause(), b.reaction())));
        }
        if code.unknown_bits() != 0 {
            rows.push(("  undefined bits".into(), format!("0x{:08X}", code.unknown_bits())));
        }
    }
    common::print_table(out, &rows)
}

/// Waits `duration` on the client's clock, returning early on Ctrl-C.
fn pause(client: &ScuClient, duration: Duration, interrupt: &CancelToken) {
    let clock = client.clock();
    let signal = clock.signal();
    let until = clock.now() + duration;
    while clock.now() < until && !interrupt.is_cancelled() {
        signal.wait_until(Some(until.min(clock.now() + Duration::from_millis(10))));
    }
}

fn watch(
    client: &ScuClient,
    json: bool,
    interval_ms: u64,
    count: Option<u64>,
    interrupt: &CancelToken,
    out: &mut dyn Write,
) -> Result<(), CliError> {
    let clock = Arc::clone(client.clock());
    let actuators = connected_actuators(client)?;
    let mut n = 0u64;
    let started = clock.now();
    while !interrupt.is_cancelled() && count.is_none_or(|c| n < c) {
        let positions = client.get(DataIndex(0x0010)).map_err(scu_error)?;
        let status = client.get_raw(DataIndex(0x0170)).map_err(scu_error)?;
        let currents = client.get(DataIndex(0x00A0)).map_err(scu_error)?;
        let last_error = client.get_value(DataIndex(0x00D1)).map_err(scu_error)?;
        let t = (clock.now() - started).as_secs_f64();
        // One row per connected actuator, from the three group reads (a short reply is an error, not a panic).
        let mut rows = Vec::with_capacity(actuators.len());
        for (a, _) in &actuators {
            let i = usize::from(a.number() - 1);
            let short = |what: &str| CliError::transport(format!("the unit's {what} reply has no entry for {a}"));
            let position = &positions.get(i).ok_or_else(|| short("position (0x0010)"))?.1;
            let status = *status.get(i).ok_or_else(|| short("status (0x0170)"))?;
            let current = &currents.get(i).ok_or_else(|| short("current (0x00A0)"))?.1;
            rows.push((a, position, status, current));
        }
        if json {
            let acts: Vec<_> = rows
                .iter()
                .map(|(a, position, status, current)| {
                    json!({"actuator": a.number(), "position": position.to_json(), "status": status,
                           "moving": status & status1::MOTION != 0, "current_deci_amps": current.to_json()})
                })
                .collect();
            common::print_json(out, &json!({"t": t, "actuators": acts, "last_error": last_error.to_json()}))?;
        } else {
            let mut line = format!("{t:7.2} s");
            for (a, position, status, current) in &rows {
                let moving = if status & status1::MOTION != 0 { "moving" } else { "stopped" };
                line.push_str(&format!("  {a}: {position} {moving} {current}"));
            }
            if let Value::ErrorCode(c) = last_error {
                if c != ErrorCode::NONE {
                    line.push_str(&format!("  last error 0x{:08X}", c.0));
                }
            }
            writeln!(out, "{line}")?;
        }
        out.flush()?;
        n += 1;
        if count.is_none_or(|c| n < c) {
            pause(client, Duration::from_millis(interval_ms), interrupt);
        }
    }
    Ok(())
}

fn run_function(
    client: &ScuClient,
    function: &str,
    direction: &str,
    limit: Option<Duration>,
    interrupt: &CancelToken,
    out: &mut dyn Write,
) -> Result<(), CliError> {
    let f = parse_function(function)?;
    let clock = Arc::clone(client.clock());
    let started = clock.now();
    match f {
        Function::Motion(m) => client.start_motion(m, parse_direction(direction)?).map_err(scu_error)?,
        other => client.switch(other, true).map_err(scu_error)?,
    }
    writeln!(out, "{f} running; Ctrl-C stops it")?;
    out.flush()?;
    let mut seen_motion = false;
    loop {
        pause(client, client.config().poll_interval, interrupt);
        let elapsed = clock.now() - started;
        if interrupt.is_cancelled() || limit.is_some_and(|l| elapsed >= l) {
            break;
        }
        if let (Function::Motion(_), None) = (f, limit) {
            // A motion function ends when none of the actuators moves any more.
            let status = client.statuses().map_err(scu_error)?;
            let moving = status.iter().any(|s| s & status1::MOTION != 0);
            seen_motion |= moving;
            if !moving && (seen_motion || elapsed >= client.config().start_grace) {
                break;
            }
        }
    }
    match f {
        Function::Motion(m) => client.stop_motion(m, StopMode::Fast).map_err(scu_error)?,
        other => client.switch(other, false).map_err(scu_error)?,
    }
    // The stop is confirmed by the unit's status: no actuator reports motion.
    let status = client.statuses().map_err(scu_error)?;
    let positions = client.positions().map_err(scu_error)?;
    let moving: Vec<String> = Actuator::all()
        .filter(|a| status[usize::from(a.number() - 1)] & status1::MOTION != 0)
        .map(|a| a.to_string())
        .collect();
    let rows: Vec<Row> = Actuator::all()
        .filter(|a| status[usize::from(a.number() - 1)] & status1::AVAILABLE != 0)
        .map(|a| (a.to_string(), format!("{} counts", positions[usize::from(a.number() - 1)])))
        .collect();
    if !moving.is_empty() && matches!(f, Function::Motion(_)) {
        return Err(CliError::device(format!(
            "{f} was stopped (RS acknowledged), but {} still report(s) motion: another function or the hand \
             switch may be driving them",
            moving.join(", ")
        )));
    }
    writeln!(out, "{f} stopped")?;
    common::print_table(out, &rows)?;
    if interrupt.is_cancelled() {
        return Err(CliError::Interrupted(format!("interrupted; {f} stopped (the unit confirmed it)")));
    }
    Ok(())
}

/// Prints how a move ended: each actuator whose remote position it wrote, with its target and difference.
fn print_move_report(out: &mut dyn Write, report: &MoveReport, json: bool) -> Result<(), CliError> {
    if json {
        let actuators: Vec<_> = report
            .actuators
            .iter()
            .map(|o| {
                json!({"actuator": o.actuator.number(), "target": o.target_counts, "position": o.position_counts,
                       "difference": o.difference_counts(), "moved": o.moved})
            })
            .collect();
        let target = report.actuators.iter().find(|o| o.actuator == report.actuator).map(|o| o.target_counts);
        return common::print_json(
            out,
            &json!({"actuator": report.actuator.number(), "function": report.function.number(),
                    "position": report.position_counts, "target": target,
                    "seconds": report.duration.as_secs_f64(), "actuators": actuators}),
        );
    }
    let mut rows: Vec<Row> = vec![("function".into(), report.function.to_string())];
    for o in &report.actuators {
        let text = if o.moved || o.actuator == report.actuator {
            format!("{} counts (target {}, difference {})", o.position_counts, o.target_counts, o.difference_counts())
        } else {
            format!("{} counts (did not move: not driven by {})", o.position_counts, report.function)
        };
        rows.push((o.actuator.to_string(), text));
    }
    rows.push(("time".into(), format!("{:.1} s", report.duration.as_secs_f64())));
    common::print_table(out, &rows)
}

/// One line of `follow`'s input.
#[derive(Debug, PartialEq)]
enum FollowLine {
    /// Nothing (blank or a comment).
    Skip,
    /// New targets, one per actuator of the stream.
    Targets(Vec<i32>),
    /// A new speed.
    Speed(u16),
}

/// Parses a line of `follow`'s input for a stream of `actuators`: `400` (all), `400 410` (one each, in
/// order), `a1=400 a2=410` (each named), `speed 60`; `#` starts a comment.
fn parse_follow_line(line: &str, actuators: &[Actuator], mode: SpeedMode) -> Result<FollowLine, String> {
    let text = line.split('#').next().unwrap_or("").trim();
    if text.is_empty() {
        return Ok(FollowLine::Skip);
    }
    let words: Vec<&str> = text.split([' ', '\t', ',']).filter(|w| !w.is_empty()).collect();
    if let Some(rest) = text.strip_prefix("speed") {
        let value = rest.trim().trim_start_matches('=').trim();
        return parse_speed(value, mode).map(FollowLine::Speed).map_err(|e| e.to_string());
    }
    let count = |w: &str| w.parse::<i32>().map_err(|_| format!("{w:?} is not a position in counts"));
    if words.iter().all(|w| !w.contains('=')) {
        let values = words.iter().map(|w| count(w)).collect::<Result<Vec<_>, _>>()?;
        return match values.len() {
            1 => Ok(FollowLine::Targets(vec![values[0]; actuators.len()])),
            n if n == actuators.len() => Ok(FollowLine::Targets(values)),
            n => Err(format!("{n} targets for {} actuator(s): give one for all, or one each", actuators.len())),
        };
    }
    let mut targets = vec![None; actuators.len()];
    for w in words {
        let (name, value) = w.split_once('=').ok_or_else(|| format!("{w:?}: give ACTUATOR=COUNTS, such as a1=400"))?;
        let a = name.trim_start_matches(['A', 'a']).parse::<u8>().ok().and_then(Actuator::new);
        let i = a
            .and_then(|a| actuators.iter().position(|x| *x == a))
            .ok_or_else(|| format!("{name:?} is not one of the actuators followed ({})", names(actuators)))?;
        targets[i] = Some(count(value)?);
    }
    if let Some(i) = targets.iter().position(Option::is_none) {
        return Err(format!("no target for {} (every actuator followed needs one)", actuators[i]));
    }
    Ok(FollowLine::Targets(targets.into_iter().flatten().collect()))
}

fn names(actuators: &[Actuator]) -> String {
    actuators.iter().map(Actuator::to_string).collect::<Vec<_>>().join(", ")
}

/// What the stdin reader hands over.
enum Input {
    Line(String),
    End,
    Failed(String),
}

/// `scu follow`: targets from stdin, applied at most `rate_hz` times a second while the motion runs.
#[allow(clippy::too_many_arguments)]
fn follow(
    client: &ScuClient,
    actuator: Actuator,
    function: MotionFunction,
    speed: u16,
    rate_hz: u32,
    json: bool,
    interrupt: &CancelToken,
    out: &mut dyn Write,
) -> Result<(), CliError> {
    let actuators = match client.config().function_map.drives(function) {
        Some(drives) if drives.contains(&actuator) => drives,
        Some(drives) => {
            return Err(CliError::usage(format!(
                "{function} does not drive {actuator} (--functions says it drives {})",
                names(&drives)
            )))
        }
        // Not known: every connected actuator follows, so that none runs to a stale remote position.
        None => client.connected_actuators().map_err(scu_error)?,
    };
    let mode = client.config().speed_mode;
    let mut stream = client.stream(function, &actuators, typed_speed(client, speed)?).map_err(scu_error)?;
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::Builder::new()
        .name("follow-stdin".into())
        .spawn(move || {
            use std::io::BufRead;
            for line in std::io::stdin().lock().lines() {
                let message = match line {
                    Ok(l) => Input::Line(l),
                    Err(e) => Input::Failed(e.to_string()),
                };
                let failed = matches!(message, Input::Failed(_));
                if tx.send(message).is_err() || failed {
                    return;
                }
            }
            let _ = tx.send(Input::End);
        })
        .map_err(|e| CliError::transport(format!("cannot read stdin: {e}")))?;
    writeln!(out, "following {function} ({}): targets from stdin", names(&actuators))?;
    out.flush()?;
    let clock = Arc::clone(client.clock());
    let gap = Duration::from_secs(1) / rate_hz;
    let mut last_update: Option<motionlink_link::Timestamp> = None;
    let mut pending: Option<Vec<i32>> = None;
    let mut updates = 0u64;
    let failure: Option<Result<CliError, ScuError>> = loop {
        if interrupt.is_cancelled() {
            break Some(Ok(CliError::Interrupted(format!("interrupted; {function} stopped"))));
        }
        match rx.recv_timeout(Duration::from_millis(10)) {
            Ok(Input::Line(line)) => match parse_follow_line(&line, &actuators, mode) {
                Ok(FollowLine::Skip) => {}
                Ok(FollowLine::Targets(t)) => pending = Some(t),
                Ok(FollowLine::Speed(s)) => {
                    if let Err(e) = stream.set_speed(typed_speed(client, s)?) {
                        break Some(Err(e));
                    }
                }
                Err(e) => break Some(Ok(CliError::usage(format!("stdin line {line:?}: {e}")))),
            },
            Ok(Input::End) | Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => break None,
            Ok(Input::Failed(e)) => break Some(Ok(CliError::transport(format!("reading stdin: {e}")))),
            Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {}
        }
        let now = clock.now();
        if pending.is_some() && last_update.is_none_or(|t| now - t >= gap) {
            let targets = pending.take().unwrap_or_default();
            if let Err(e) = stream.set_targets(&targets) {
                break Some(Err(e));
            }
            last_update = Some(now);
            updates += 1;
            let text: Vec<String> = actuators.iter().zip(&targets).map(|(a, t)| format!("{a}={t}")).collect();
            if json {
                let map: serde_json::Map<String, serde_json::Value> =
                    actuators.iter().zip(&targets).map(|(a, t)| (a.to_string(), json!(t))).collect();
                common::print_json(out, &json!({"targets": map}))?;
            } else {
                writeln!(out, "target {}", text.join(" "))?;
            }
            out.flush()?;
        }
    };
    // The stream ends: on EOF along the ramp, on anything else at once; where each actuator came to rest.
    let (mode, error) = match failure {
        None => (StopMode::Soft, None),
        Some(Ok(cli)) => (StopMode::Fast, Some(cli)),
        Some(Err(scu)) => return Err(scu_error(stream.abort(scu))),
    };
    let rest = stream.stop(mode).map_err(scu_error)?;
    let text: Vec<String> = rest.iter().map(|(a, p)| format!("{a}={p}")).collect();
    if json {
        let map: serde_json::Map<String, serde_json::Value> =
            rest.iter().map(|(a, p)| (a.to_string(), json!(p))).collect();
        common::print_json(out, &json!({"stopped": map, "updates": updates}))?;
    } else {
        writeln!(out, "stopped after {updates} update(s): {}", text.join(" "))?;
    }
    error.map_or(Ok(()), Err)
}

/// `motionlink sim scu`
pub fn sim(args: SimArgs) -> Result<(), CliError> {
    let config = load_sim_config(args.config.as_ref(), args.preset.as_deref())?;
    let device = Emulator::new(config).map_err(|e| CliError::usage(e.to_string()))?;
    common::serve(&args.serve, device)
}

/// One telegram (or undecodable part) of a capture, described.
struct Annotated {
    offset: usize,
    bytes: Vec<u8>,
    /// "->" host to unit, "<-" unit to host, "!!" not a telegram.
    direction: &'static str,
    text: String,
}

/// Splits `bytes` into telegrams and describes each; replies are decoded with the request before them.
fn annotate(bytes: &[u8], direction: CaptureDirection, last_request: &mut Option<Vec<u8>>) -> Vec<Annotated> {
    let mut out = Vec::new();
    let mut at = 0;
    while at < bytes.len() {
        let (n, found) = capture_step(&bytes[at..], direction);
        let n = n.max(1);
        let raw = &bytes[at..(at + n).min(bytes.len())];
        let (dir, text) = match &found {
            CaptureItem::Telegram(Telegram::Request(i)) => {
                *last_request = Some(raw.to_vec());
                ("->", describe_incoming(i))
            }
            CaptureItem::Telegram(Telegram::Reply(r)) => {
                let context =
                    last_request.as_deref().and_then(|b| match capture_step(b, CaptureDirection::FromHost).1 {
                        CaptureItem::Telegram(Telegram::Request(Incoming::Request(req))) => Some(req),
                        _ => None,
                    });
                ("<-", describe_reply(r, context.as_ref()))
            }
            CaptureItem::Telegram(Telegram::UnknownCommandReply { code, status }) => (
                "<-",
                format!(
                    "{}{} {}: {} (the reply to an unknown command)",
                    char::from(code[0]),
                    char::from(code[1]),
                    status.abbreviation(),
                    status.description()
                ),
            ),
            CaptureItem::Error(WireError::Garbage { count }) => {
                ("!!", format!("{count} byte(s) that start no telegram"))
            }
            CaptureItem::Error(e) => ("!!", e.to_string()),
            CaptureItem::Truncated => ("!!", format!("the capture ends inside a telegram ({} byte(s))", raw.len())),
        };
        out.push(Annotated { offset: at, bytes: raw.to_vec(), direction: dir, text });
        at += n;
    }
    out
}

/// `motionlink decode scu`
pub fn decode(args: DecodeArgs) -> Result<(), CliError> {
    let bytes = common::read_capture(&args.capture)?;
    let mut out = std::io::stdout().lock();
    let mut last_request = None;
    for a in annotate(&bytes, CaptureDirection::Unknown, &mut last_request) {
        if args.json {
            common::print_json(
                &mut out,
                &json!({"offset": a.offset, "direction": a.direction, "bytes": common::hex(&a.bytes), "meaning": a.text}),
            )?;
        } else {
            writeln!(out, "{} {:<38} {}", a.direction, common::hex(&a.bytes), a.text)?;
        }
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------------------
// Demo

/// Prints a session transcript: every exchange once; keepalives after the first folded into a count; an
/// exchange repeated without change (a status poll) collapsed into one line.
fn print_transcript(out: &mut dyn Write, transcript: &Transcript) -> Result<(), CliError> {
    let keepalive = request_to_vec(&Request::Cyclic { object: 0xFF, write: &[] }).unwrap_or_default();
    let mut last_request = None;
    let mut lines: Vec<(Timestamp, Annotated)> = Vec::new();
    for r in transcript.take() {
        let direction = if r.way == Way::Sent { CaptureDirection::FromHost } else { CaptureDirection::FromUnit };
        lines.extend(annotate(&r.bytes, direction, &mut last_request).into_iter().map(|a| (r.at, a)));
    }
    let print = |out: &mut dyn Write, (t, a): &(Timestamp, Annotated)| -> std::io::Result<()> {
        writeln!(
            out,
            "  {:>8.3}  {} {:<38} {}",
            t.since_origin().as_secs_f64(),
            a.direction,
            common::hex(&a.bytes),
            a.text
        )
    };
    let mut keepalives_shown = false;
    let mut keepalives_folded = 0;
    let mut previous: Option<(Vec<u8>, Vec<u8>)> = None;
    let mut repeats = 0;
    let mut last_repeat_at = Timestamp::ZERO;
    let mut i = 0;
    while i < lines.len() {
        let exchange = lines.get(i..i + 2).filter(|p| p[0].1.direction == "->" && p[1].1.direction == "<-");
        let Some(pair) = exchange else {
            print(out, &lines[i])?;
            i += 1;
            continue;
        };
        if pair[0].1.bytes == keepalive {
            if keepalives_shown {
                keepalives_folded += 1;
                i += 2;
                continue;
            }
            keepalives_shown = true;
        }
        let key = (pair[0].1.bytes.clone(), pair[1].1.bytes.clone());
        if previous.as_ref() == Some(&key) {
            repeats += 1;
            last_repeat_at = pair[1].0;
            i += 2;
            continue;
        }
        if repeats > 0 {
            writeln!(
                out,
                "  {:>8}     … the same exchange {repeats} more time(s), until {:.3} s",
                "",
                last_repeat_at.since_origin().as_secs_f64()
            )?;
            repeats = 0;
        }
        if keepalives_folded > 0 {
            writeln!(out, "  {:>8}     … {keepalives_folded} RC keepalive(s), each answered ACK", "")?;
            keepalives_folded = 0;
        }
        print(out, &pair[0])?;
        print(out, &pair[1])?;
        previous = Some(key);
        i += 2;
    }
    Ok(())
}

/// The SCU part of `motionlink demo`: the manual's chapter 5 routine against the emulator.
pub fn demo(out: &mut dyn Write) -> Result<(), CliError> {
    writeln!(out, "== Ewellix / Schaeffler SCU: the manual's chapter 5 routine (SCP11, actuator 1) ==")?;
    writeln!(out, "The manual's example telegrams, as motionlink-scu encodes them (CRC-16/XMODEM, low byte first):")?;
    let examples: [(&str, Request<'_>); 7] = [
        ("RO 00", Request::Open { safety_id: 0 }),
        ("RC 01 00 -1", Request::Cyclic { object: 0xFF, write: &[] }),
        ("RT 04 00 11 30 01 00", Request::Transfer { index: 0x3011, data: &[0x01, 0x00] }),
        ("RE 00 09 -1", Request::Execute { function: 0, params: [9, 0xFF] }),
        ("RG 71 01", Request::Get { index: 0x0171 }),
        ("RG 11 00", Request::Get { index: 0x0011 }),
        ("RA", Request::Abort),
    ];
    for (manual, r) in examples {
        let bytes = request_to_vec(&r).map_err(|e| CliError::usage(e.to_string()))?;
        writeln!(out, "  {manual:<22} {:<38} {}", common::hex(&bytes), describe_request(&r))?;
    }
    writeln!(out, "  (The manual captions its RT example \"100h\"; its bytes 01 00 are little-endian 1. The bytes are the truth.)")?;
    writeln!(out)?;
    writeln!(
        out,
        "The routine against the built-in emulator (2 actuators, stroke 0..865 counts, 110 counts/s at 100 %),"
    )?;
    writeln!(out, "on a virtual clock: times are device seconds. RC keepalives run every 200 ms throughout.")?;
    writeln!(out, "  {:>8}  dir telegram{:<30} meaning", "t [s]", "")?;

    let clock = ManualClock::new_auto();
    let _me = clock.reserve_participant().enter();
    let shared: SharedClock = clock.shared();
    let host = EmulatorHost::new(
        Emulator::new(SimConfig::default()).map_err(|e| CliError::usage(e.to_string()))?,
        Arc::clone(&shared),
        PipeConfig::paced(38_400),
    );
    let transcript = Transcript::new();
    let (tap_transcript, tap_clock, tap_host) = (transcript.clone(), Arc::clone(&shared), host.clone());
    let connector: Connector = Box::new(move || {
        Ok(Box::new(TapLink::new(tap_host.connect().0, Arc::clone(&tap_clock), tap_transcript.clone()))
            as Box<dyn Link>)
    });
    let client = ScuClient::open(connector, Arc::clone(&shared), ClientConfig::default()).map_err(scu_error)?;
    let a1 = Actuator::new(1).ok_or_else(|| CliError::usage("actuator 1"))?;
    let f1 = MotionFunction::new(1).ok_or_else(|| CliError::usage("F1"))?;
    let target = 400;
    let steps = || -> Result<(i32, Duration), ScuError> {
        client.set(DataIndex(0x3011), &Value::RemoteSpeed(80))?;
        client.set(a1.remote_position_index(), &Value::RemotePosition(target))?;
        let started = shared.now();
        client.start_motion(f1, MotionDirection::RemotePosition)?;
        let pause = shared.signal();
        loop {
            let until = shared.now() + Duration::from_millis(250);
            while pause.wait_until(Some(until)) == motionlink_link::clock::Wake::Raised {}
            if client.status1(a1)?.bits as u8 & status1::MOTION == 0 {
                break;
            }
        }
        let took = shared.now() - started;
        let position = client.position(a1)?;
        client.stop_motion(f1, StopMode::Soft)?;
        Ok((position, took))
    };
    let result = steps();
    let keepalives = client.stats().keepalives;
    let closed = client.close();
    print_transcript(out, &transcript)?;
    let (position, took) = result.map_err(scu_error)?;
    closed.map_err(scu_error)?;
    writeln!(out)?;
    writeln!(
        out,
        "Result: actuator 1 reached {position} counts (target {target}) in {:.1} s at 80 %; {keepalives} RC keepalives kept the 500 ms watchdog fed; RS and RA closed the session.",
        took.as_secs_f64()
    )?;
    let idle_error = host.with_device(|u| u.last_error());
    writeln!(out, "The unit's last error code: {idle_error}")?;
    writeln!(out)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn a(n: u8) -> Actuator {
        Actuator::new(n).unwrap()
    }

    #[test]
    fn follow_lines_give_one_target_for_all_one_each_or_named_ones() {
        let two = [a(1), a(2)];
        let p = |l: &str| parse_follow_line(l, &two, SpeedMode::Percent);
        assert_eq!(p("400"), Ok(FollowLine::Targets(vec![400, 400])));
        assert_eq!(p(" 400  410 "), Ok(FollowLine::Targets(vec![400, 410])));
        assert_eq!(p("a2=410 A1=-3"), Ok(FollowLine::Targets(vec![-3, 410])));
        assert_eq!(p("speed 60"), Ok(FollowLine::Speed(60)));
        assert_eq!(p("speed=60 # slower"), Ok(FollowLine::Speed(60)));
        assert_eq!(p("   # only a comment"), Ok(FollowLine::Skip));
        assert_eq!(p(""), Ok(FollowLine::Skip));
        for bad in ["400 410 420", "a1=400", "a3=1 a1=2 a2=3", "four hundred", "speed 0", "speed 101", "a1=x a2=1"] {
            assert!(p(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn speeds_are_whole_numbers_from_1_to_the_mode_maximum() {
        assert_eq!(parse_speed("1", SpeedMode::Percent).unwrap(), 1);
        assert_eq!(parse_speed("100", SpeedMode::Percent).unwrap(), 100);
        assert_eq!(parse_speed("1000", SpeedMode::CountsPerSecond).unwrap(), 1000);
        for bad in ["0", "-1", "101", "NaN", "inf", "50.5", "", "1e2"] {
            let e = parse_speed(bad, SpeedMode::Percent).unwrap_err();
            assert!(matches!(&e, CliError::Usage(m) if m.contains("--speed")), "{bad}: {e}");
        }
        assert!(parse_seconds("NaN").is_err() && parse_seconds("-1").is_err() && parse_seconds("0.5").is_ok());
        assert!(parse_rate("0").is_err() && parse_rate("101").is_err() && parse_rate("100").is_ok());
        assert!(parse_stroke("1=0:865").is_ok() && parse_stroke("1=9:1").is_err() && parse_stroke("7=0:1").is_err());
    }

    #[test]
    fn a_failed_stop_at_the_end_keeps_the_exit_code_and_says_the_actuators_may_move() {
        let lost = ScuError::SessionLost("port gone".into());
        let e = finish(Err(CliError::Interrupted("interrupted".into())), Err(lost.clone()), &[0]).unwrap_err();
        assert!(matches!(&e, CliError::Interrupted(m) if m.contains("may still be moving") && m.contains("F1")), "{e}");
        let e = finish(Ok(()), Err(lost.clone()), &[1]).unwrap_err();
        assert!(matches!(&e, CliError::Transport(m) if m.contains("F2")), "{e}");
        let e = finish(Err(CliError::Device("stalled".into())), Ok(()), &[0]).unwrap_err();
        assert!(matches!(&e, CliError::Device(m) if m.contains("acknowledged RS")), "{e}");
        assert!(finish(Ok(()), Ok(()), &[]).is_ok());
        assert!(matches!(finish(Ok(()), Err(lost), &[]), Err(CliError::Transport(_))));
    }
}
