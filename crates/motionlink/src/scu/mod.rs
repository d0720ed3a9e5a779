//! `motionlink scu`, `motionlink sim scu`, `motionlink decode scu` and the SCU part of `motionlink demo`.

use std::io::Write;
use std::path::PathBuf;
use std::sync::Arc;

use motionlink_link::cancel::CancelToken;
use motionlink_link::describe::Describe;
use motionlink_link::link::Connector;
use motionlink_link::pipe::{EmulatorHost, PipeConfig};
use motionlink_link::url::PortUrl;
use motionlink_link::{RealClock, SharedClock};
use motionlink_scu::args::{
    Baud, Checked, PollInterval, ReplyTimeout, RunLimit, ToleranceCounts, UnitOptions, UpdateRate,
};
use motionlink_scu::describe::Describer;
use motionlink_scu::model::{Actuator, Function, MotionFunction, PositionCounts, SafetyId, SpeedMode};
use motionlink_scu::session::RunAction;
use motionlink_scu::{Client, Config, Emulator, Ending, SimConfig, Variant};

use crate::common::{self, CliError};
use crate::numbers::{at_least, whole};
use crate::tap::{LinkArgs, Tap};

mod actions;
mod decode;
mod demo;
mod follow;
mod open;
mod parse;
mod send;
mod sim;
mod stop;
pub(crate) use stop::print_stop_text;

pub use decode::{decode, DecodeArgs};
pub use demo::demo;
use open::connect;
#[cfg(test)]
use open::unit_options;
pub(crate) use open::{client_config, connector, in_process};
pub(crate) use parse::speed_mode_parser;
use parse::{parse_item, parse_speed};
pub(crate) use sim::{in_process_config, InProcess};
pub use sim::{sim, SimArgs};

/// `motionlink scu` arguments. Every option may come before or after the action.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The port: a serial device (/dev/ttyUSB0, COM3), tcp://HOST:PORT (a serial gateway or `motionlink sim scu`),
    /// or sim (an emulator in this process). Default: --device, else MOTIONLINK_PORT. While a command uses a serial, tcp:// or slcan:// port, another motionlink on it exits 3 naming that
    /// command (pid, action), and `stop` stops its motion (see `stop --help`).
    #[arg(long, value_name = "PORT", global = true)]
    pub port: Option<String>,
    #[command(flatten)]
    pub link: LinkArgs,
    #[command(flatten)]
    pub unit: UnitArgs,
    #[command(subcommand)]
    pub action: Action,
}

/// The unit's options: the session's settings and, with `--port sim`, the emulated unit. Every `motionlink
/// scu` action and `motionlink console scu` take them (a device table gives them as the same keys).
#[derive(clap::Args, Debug, Clone)]
pub struct UnitArgs {
    /// Baud rate of a serial port: 38400 on standard units, 9600 or 19200 on customised ones (with `--port
    /// sim`: the emulated line runs at this rate).
    #[arg(long, default_value_t = Baud::STANDARD, value_parser = Baud::parse_whole, global = true)]
    pub baud: Baud,
    /// Safety_ID sent with RO: 0 a timeout stops all motion and locks remote motion until RO, 1 stops all
    /// motion, 2 stops remote motion only.
    #[arg(long, default_value = "0", value_parser = SafetyId::parse_whole, global = true)]
    pub safety: SafetyId,
    /// How long to wait for the reply to RO, in ms (the manual allows the unit 2000 ms). In remote mode replies
    /// are awaited at most 1000 ms (twice the unit's watchdog), or this if it is shorter.
    #[arg(long, default_value = "2000", value_name = "MS", global = true, alias = "reply-timeout",
          value_parser = ReplyTimeout::parse_whole)]
    pub timeout_ms: ReplyTimeout,
    /// Which actuators each motion function drives (the unit's parameterisation, which the data list does not
    /// show): a preset, scp11 (Fn drives An), tlt (F1 both columns, F2 A1, F3 A2) or liftkit (F1 A1, F2 A2, F8
    /// both), or one function, F1=1,2. Repeat to combine (--functions scp11 --functions F7=1,2). Without it,
    /// move gives every connected actuator the target and reports the ones that moved; the console moves and
    /// jogs actuator n with the function that drives it alone (default: Fn).
    #[arg(long = "functions", value_name = "MAP", global = true)]
    pub functions: Vec<String>,
    /// The travel range of an actuator for move targets, ACTUATOR=MIN:MAX in counts (such as 1=0:865), instead of
    /// the virtual limits the unit reports in its UserPositionData. Repeat for several actuators.
    #[arg(long = "stroke", value_name = "A=MIN:MAX", global = true)]
    pub stroke: Vec<String>,
    /// How close to its target a move must end to succeed, in counts.
    #[arg(long, default_value = "5", value_name = "COUNTS", global = true, value_parser = ToleranceCounts::parse_whole)]
    pub tolerance: ToleranceCounts,
    /// How often a move (or a run, or the console's move or jog) looks at the actuators, in ms: each look is one RC keepalive that also reads
    /// the status, position and current of every actuator (about 16 ms of the 38400-baud line). A watch's
    /// samples ride on such RCs too: at most one per this interval.
    #[arg(long, default_value = "50", value_name = "MS", global = true, alias = "poll-interval",
          value_parser = PollInterval::parse_whole)]
    pub poll_ms: PollInterval,
    /// How the unit takes remote speeds: percent (standard units, "speed select relative") or
    /// counts-per-second (units parameterised for "speed select absolute", 0..1000 counts/s).
    #[arg(long, default_value = "percent", value_name = "MODE", global = true, value_parser = speed_mode_parser())]
    pub speed_mode: SpeedMode,
    /// Emulator configuration (TOML) when the port is sim: the unit as it stands (--functions is then only
    /// what the command believes of it).
    #[arg(long, value_name = "FILE", global = true)]
    pub sim_config: Option<PathBuf>,
    #[command(flatten)]
    pub sim_variants: crate::common::SimVariants<Variant>,
    /// The preset the emulator starts from when the port is sim: scp11, tlt or liftkit (as `motionlink sim
    /// scu --preset`). Default: the preset --functions names, else scp11; the Fn=... of --functions apply
    /// on top.
    #[arg(long, value_name = "NAME", global = true, value_parser = SimConfig::PRESETS)]
    pub sim_preset: Option<String>,
    /// Before opening the port, hold the unit's RxD at "space" for 150 ms (a break): a battery unit with
    /// "Low Power" enabled in low-power mode answers nothing until woken so (the manual: at least 100 ms,
    /// from FW V2B1). Only on a serial port (or --port sim).
    #[arg(long, global = true)]
    pub wake: bool,
}

/// What to do.
#[derive(clap::Subcommand, Debug)]
pub enum Action {
    /// Firmware and configuration, actuators, positions, state, last error.
    Info,
    /// Read data-list entries or groups, by name (actual_position_a1, actual_positions) or index (0x0011);
    /// several at once, one after the other.
    Get {
        /// Names or indices.
        #[arg(required = true, value_name = "ITEM")]
        items: Vec<String>,
    },
    /// Write a remote data entry (0x3xxx), such as remote_speed_f1 80 or remote_position_a1 400.
    Set {
        /// Name or index.
        item: String,
        /// The value, in the entry's unit (percent, counts...).
        #[arg(allow_negative_numbers = true)]
        value: String,
    },
    /// Send one telegram and print it and the reply, each explained. Takes a typed request (RG ITEM, RT ITEM
    /// VALUE, RE FUNCTION [DIRECTION|P0 [P1]], RS FUNCTION [fast|soft]) or the whole telegram in hex (command,
    /// data and CRC: "52 47 11 00 2C 30"; the CRC is checked). RO, RA and RC belong to the session and are
    /// refused; a function an RE starts is stopped (RS) when the command ends.
    #[allow(rustdoc::broken_intra_doc_links)] // the text is the help of `scu send`: [P1] is an optional word
    Send {
        /// The request's words, or the whole telegram in hex.
        #[arg(required = true, value_name = "WORD", allow_negative_numbers = true)]
        words: Vec<String>,
    },
    /// List the names of the data list (entries and groups) with index, unit and access (no port needed).
    Names,
    /// Move an actuator to a position (counts) and wait until it is there; every actuator the function drives
    /// goes there too. Exits 0 only if each ended within --tolerance of the target. Ctrl-C stops it.
    Move {
        /// Actuator 1..6.
        #[arg(value_parser = Actuator::parse_whole)]
        actuator: Actuator,
        /// Target position in encoder counts.
        #[arg(value_parser = PositionCounts::parse_whole)]
        position: PositionCounts,
        /// Speed in percent, 1..100 (or counts/s, 1..1000, on units set to absolute speed).
        #[arg(long, default_value = "100", value_name = "SPEED", allow_hyphen_values = true)]
        speed: String,
        /// Motion function (1..10) that drives the actuator; default: the one with its number (F1 for A1).
        #[arg(long, value_parser = MotionFunction::parse_whole)]
        function: Option<MotionFunction>,
    },
    /// Follow targets read from stdin while the motion runs (streamed setpoints): each line gives the target
    /// in counts, one number for every actuator the function drives or one per actuator ("400" or "400 410"
    /// or "a1=400 a2=410"), or a new speed ("speed 60"); "#" starts a comment. At EOF the motion runs on to the
    /// newest target and then ends (RS); Ctrl-C or a bad line stops it at once.
    Follow {
        /// Actuator 1..6 (its function, and every actuator that function drives, follow the targets).
        #[arg(value_parser = Actuator::parse_whole)]
        actuator: Actuator,
        /// Motion function (1..10); default: the one with the actuator's number.
        #[arg(long, value_parser = MotionFunction::parse_whole)]
        function: Option<MotionFunction>,
        /// Speed in percent, 1..100 (or counts/s, 1..1000, on units set to absolute speed).
        #[arg(long, default_value = "100", value_name = "SPEED", allow_hyphen_values = true)]
        speed: String,
        /// At most this many setpoint updates per second (1..100); lines that come faster are merged: the
        /// newest target wins.
        #[arg(long, default_value = "20", value_name = "HZ", allow_hyphen_values = true,
              value_parser = UpdateRate::parse_whole)]
        rate: UpdateRate,
    },
    /// Run a function until it ends or Ctrl-C: a motion function (F1..F10) with a direction (in, out, mem1..mem4,
    /// int-in, int-out, remote, or 0..9), or F11 buzzer, F17/F18 outputs, F20 emergency stop, F21/F22 LEDs with "on".
    Run {
        /// F1..F22 (or 1..22).
        function: String,
        /// Direction of a motion function, or "on".
        direction: String,
        /// Stop after this many seconds (default: when the motion ends, or Ctrl-C).
        #[arg(long, value_name = "S", allow_hyphen_values = true, value_parser = |s: &str| s.parse::<RunLimit>())]
        seconds: Option<RunLimit>,
    },
    /// Stop what moves: RS to every motion function (or to FUNCTION), confirmed by the status read back; a
    /// motionlink holding the port (a move in another terminal) is stopped first.
    ///
    /// RS goes to every motion function F1..F10 (or to FUNCTION alone), fast, or along the stop ramp with
    /// --soft; then the status of every actuator is read until none moves (at most 500 ms after a fast stop,
    /// 3 s after a soft one) and where each connected actuator rests is printed. Exit 0 only if the unit
    /// confirmed that; otherwise the message says what it did not confirm. Outputs, LEDs, buzzer and the
    /// emergency-stop function (F11..F22) are left as they are unless named (RS then switches that one off).
    ///
    /// If another motionlink holds the port (its lock file in $XDG_RUNTIME_DIR/motionlink, else
    /// motionlink-UID in the temporary directory, names its pid and command), that process is sent SIGINT:
    /// it stops its motion as on Ctrl-C and exits 130, and says what it stopped. This command waits for the
    /// port (at most 15 s), prints who it stopped and what that process said, then opens the port and stops
    /// and reads back as above. The unit itself stops remote motions 500 ms after the last RC it receives.
    Stop {
        /// F1..F22 (or 1..22); default: every motion function, F1..F10.
        #[arg(value_parser = |s: &str| s.parse::<Function>())]
        function: Option<Function>,
        /// Soft stop (along the stop ramp) instead of a fast stop.
        #[arg(long)]
        soft: bool,
    },
    /// Live positions and state until Ctrl-C. Each sample rides on an RC keepalive where the unit takes the
    /// session's cyclic object (so a link too slow for any other request beside the keepalive can be watched
    /// once it is defined), else it is read.
    Watch {
        /// Time between samples, in ms (10 .. 3600000).
        #[arg(long, default_value_t = 250, value_name = "MS", alias = "interval",
              value_parser = whole::<u64>("the sample interval", 10, 3_600_000, "ms"))]
        interval_ms: u64,
        /// Stop after this many samples (at least 1).
        #[arg(long, value_parser = at_least::<u64>("the number of samples", 1))]
        count: Option<u64>,
        /// Print CSV (a header line, then one line per actuator and sample) instead of a table.
        #[arg(long)]
        csv: bool,
        /// On a link too slow to define the cyclic object beside the keepalive (round trips near 290 ms), define
        /// it across one lapse of the unit's 500 ms watchdog. The unit then records error bit 22 and stops every
        /// motion under way, a hand switch's included (with --safety 2 the remote ones only); this session must
        /// have started nothing. Without it, such a watch ends with exit 3 and nothing lapses.
        #[arg(long)]
        allow_watchdog_lapse: bool,
    },
    /// The error history (Error_Code 1..5) with each bit's cause.
    Errors,
}

/// `motionlink scu ...`
pub fn run(args: Args) -> Result<(), CliError> {
    if let Action::Names = args.action {
        return send::names(crate::term::json(), args.unit.speed_mode, &mut std::io::stdout().lock());
    }
    // Check everything that can be checked before the port is opened: nothing is sent for bad input.
    let mut config = client_config(&args.unit)?;
    config.watch_may_lapse = matches!(args.action, Action::Watch { allow_watchdog_lapse: true, .. });
    let mut request = None;
    match &args.action {
        Action::Get { items } => {
            for item in items {
                parse_item(item)?;
            }
        }
        Action::Set { item, value } => {
            motionlink_scu::args::parse_write(parse_item(item)?, value).map_err(CliError::usage)?;
        }
        Action::Send { words } => request = Some(send::parse(words)?),
        Action::Move { speed, .. } | Action::Follow { speed, .. } => {
            parse_speed(speed, args.unit.speed_mode)?;
        }
        Action::Run { function, direction, .. } => {
            RunAction::parse(function, direction).map_err(CliError::usage)?;
        }
        Action::Watch { csv, .. } => {
            common::WatchFormat::of(*csv, crate::term::json())?;
        }
        _ => {}
    }
    let port = args.link.resolve_port("scu", args.port.as_deref())?;
    let interrupt = common::interrupt_token();
    // Found by another motionlink as the holder of the port; `stop` takes it from a holder first.
    let stopped = crate::portlock::claim_as("scu", &port, matches!(args.action, Action::Stop { .. }))?;
    let clock = RealClock::shared();
    let describer = || Box::new(Describer::new()) as Box<dyn Describe + Send>;
    let tap = Tap::new("scu", &port, &clock, &args.link, "can0", &describer, request.is_some())?;
    let is_stop = matches!(args.action, Action::Stop { .. });
    let absent = || {
        // A stop says first that it sent no stop: RS goes out only in the remote mode that RO opens.
        let stop = if is_stop { "this command sent no RS (RS needs the remote mode RO opens): " } else { "" };
        format!(
            "{stop}the SCU on {port} does not answer (nothing came back to RO within {} ms): check the cable, the \
             baud rate (--baud {}; standard units run at 38400, customised ones at 9600 or 19200) and that the \
             control unit is powered{}",
            args.unit.timeout_ms.get().as_millis(),
            args.unit.baud,
            if args.unit.wake { "" } else { " (a battery unit in low-power mode answers only once woken: --wake)" }
        )
    };
    let client = connect(&args.unit, &port, &tap, &clock, config).map_err(|e| {
        let e = tap.name_absent(e, absent);
        // A stop whose line failed before it could send RS is a stop not confirmed, as the other families'
        // stops on a silent device are.
        if is_stop && matches!(e.class(), motionlink_link::error::ErrorClass::Transport(_)) {
            e.stop_not_confirmed()
        } else {
            e
        }
    })?;
    client.set_cancel(interrupt.clone());
    crate::probe::use_profile(|p| motionlink_scu::probe::use_profile(&client, p, &port))?;
    let mut out = std::io::stdout().lock();
    let report = common::Out { json: crate::term::json(), family: "scu", port: &port, unit: None };
    let result = match &request {
        // A Ctrl-C while the session was being opened: nothing was sent; the session is closed (RA).
        Some(_) if interrupt.is_cancelled() => {
            Err(CliError::Interrupted("interrupted before the request was sent".into()))
        }
        Some(r) => send::send(&client, r, &tap, &report, &mut out),
        None => act(&client, &args, &report, stopped.as_ref(), &mut out, &interrupt),
    };
    // Stop what was started and leave remote mode, whatever happened.
    let closed = client.close();
    tap.flush();
    finish(result, closed).map_err(|e| tap.name_absent(e, absent))
}

/// Appends `note` to the message of `e`, keeping its exit code.
fn with_note(e: CliError, note: &str) -> CliError {
    e.map_message(|m| format!("{m}; {note}"))
}

/// The command's result after the session was closed ([`motionlink_scu::ending`] says what the close means):
/// a stop the unit did not confirm is said in words (keeping the exit code of what went wrong first).
fn finish(
    result: Result<(), CliError>,
    closed: Result<Vec<motionlink_scu::model::Function>, motionlink_scu::Error>,
) -> Result<(), CliError> {
    match motionlink_scu::ending(closed) {
        Ending::Clean => result,
        Ending::Stopped(note) => result.map_err(|e| match e {
            CliError::OutputClosed => CliError::OutputClosed,
            e => with_note(e, &note),
        }),
        Ending::Failed(e) => result.and(Err(common::classified(&e))),
        Ending::Unconfirmed(e) => Err(match result {
            Ok(()) => common::classified(&e),
            // An error that said already that a stop was not confirmed is not said again in full.
            Err(cli) if cli.stop_unconfirmed() => with_note(cli, &e.note_after_unconfirmed()),
            Err(cli) => with_note(cli, &format!("then {e}")).stop_not_confirmed(),
        }),
    }
}

fn act(
    client: &Client,
    args: &Args,
    report: &common::Out<'_>,
    stopped: Option<&motionlink_link::portlock::Stopped>,
    out: &mut dyn Write,
    interrupt: &CancelToken,
) -> Result<(), CliError> {
    // A Ctrl-C while the session was being opened: nothing was started; the session is closed (RA).
    if interrupt.is_cancelled() {
        return Err(CliError::Interrupted("interrupted before the action started".into()));
    }
    let mode = client.config().speed_mode;
    // The motion function of `move` and `follow`: `--function`, or the one with the actuator's number.
    let function_of = |a: Actuator, f: Option<MotionFunction>| {
        f.map_or_else(|| MotionFunction::checked(i64::from(a.number())), Ok).map_err(CliError::usage)
    };
    match &args.action {
        Action::Info => actions::info(client, report, out),
        Action::Get { items } => {
            let items = items.iter().map(|i| parse_item(i)).collect::<Result<Vec<_>, _>>()?;
            actions::get(client, &items, report, out)
        }
        Action::Set { item, value } => actions::set(client, parse_item(item)?, value, report, out),
        Action::Move { actuator, position, speed, function } => {
            let function = function_of(*actuator, *function)?;
            let speed = parse_speed(speed, mode)?;
            actions::move_to(client, *actuator, *position, speed, function, report, out)
        }
        Action::Follow { actuator, function, speed, rate } => {
            let function = function_of(*actuator, *function)?;
            let speed = parse_speed(speed, mode)?;
            follow::follow(client, *actuator, function, speed, rate.per_second(), report, interrupt, out)
        }
        Action::Run { function, direction, seconds } => {
            let action = RunAction::parse(function, direction).map_err(CliError::usage)?;
            actions::run(client, action, seconds.map(RunLimit::get), report, out)
        }
        Action::Stop { function, soft } => stop::stop(client, *function, *soft, report, stopped, out),
        Action::Watch { interval_ms, count, csv, .. } => {
            let format = common::WatchFormat::of(*csv, report.json)?;
            actions::watch(client, report, format, *interval_ms, *count, interrupt, out)
        }
        Action::Errors => actions::errors(client, report, out),
        Action::Send { .. } | Action::Names => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use motionlink_scu::model::Speed;
    use serde_json::json;

    #[test]
    fn the_command_line_s_defaults_are_the_library_s() {
        let cli = <crate::Cli as clap::Parser>::try_parse_from(["motionlink", "scu", "--port", "sim", "info"]).unwrap();
        let crate::Command::Scu(args) = cli.command else { panic!("scu") };
        assert_eq!(unit_options(&args.unit), UnitOptions::default());
    }

    #[test]
    fn a_bad_speed_names_the_option_and_gives_the_library_s_rule() {
        assert_eq!(parse_speed("1000", SpeedMode::CountsPerSecond).unwrap().raw(), 1000);
        for bad in ["0", "-1", "101", "NaN", "50.5", ""] {
            let e = parse_speed(bad, SpeedMode::Percent).unwrap_err();
            let rule = Speed::parse(bad, SpeedMode::Percent).unwrap_err().to_string();
            assert!(matches!(&e, CliError::Usage(m) if *m == format!("--speed {bad}: {rule}")), "{bad}: {e}");
        }
    }

    #[test]
    fn a_failed_stop_at_the_end_keeps_the_exit_code_and_says_the_actuators_may_move() {
        let lost = motionlink_scu::Error::SessionLost("port gone".into());
        let f = |id| motionlink_scu::model::Function::from_id(id).unwrap();
        // What Client::close says when the functions `functions` were left started and the port was gone.
        let unconfirmed =
            |functions| motionlink_scu::Error::CloseUnconfirmed { functions, cause: Box::new(lost.clone()) };
        // A stop not confirmed at the end makes any first error one of the line (exit code 3), flagged.
        let e = finish(Err(CliError::Interrupted("interrupted".into())), Err(unconfirmed(vec![f(0)]))).unwrap_err();
        assert!(e.to_string().starts_with("interrupted; then ") && e.to_string().contains("F1"), "{e}");
        assert!(e.to_string().contains("may still be moving") && e.stop_unconfirmed(), "{e}");
        assert_eq!((e.kind(), e.exit_code(), &e.to_json()["stop_unconfirmed"]), ("timeout", 3, &json!(true)));
        let e = finish(Ok(()), Err(unconfirmed(vec![f(1)]))).unwrap_err();
        assert!(e.to_string().contains("F2") && e.stop_unconfirmed(), "{e}");
        assert_eq!((e.kind(), e.exit_code()), ("disconnected", 3));
        // An error that said so already is followed by the short note, and stays flagged.
        let said = common::classified(&unconfirmed(vec![f(0)]));
        let e = finish(Err(said), Err(unconfirmed(vec![f(0)]))).unwrap_err();
        assert!(
            e.to_string().ends_with(
                "the end of the session tried RS to F1 again: not confirmed either (session lost: port gone)"
            ),
            "{e}"
        );
        assert!(e.stop_unconfirmed(), "{e}");
        let e = finish(Err(CliError::Device("stalled".into())), Ok(vec![f(0)])).unwrap_err();
        assert!(matches!(&e, CliError::Device(m) if m.contains("acknowledged RS")), "{e}");
        assert!(finish(Ok(()), Ok(vec![])).is_ok());
        assert!(matches!(finish(Ok(()), Err(lost.clone())), Err(CliError::Transport(..))));
    }
}
