//! `motionlink powercube`, `motionlink sim powercube`, `motionlink decode powercube` and the PowerCube part
//! of `motionlink demo`: argument parsing, output and exit codes. What stops a module, when its watchdog is
//! armed and how a move is checked are the library's ([`Guard`], [`Module::move_to_guarded`]).

mod actions;
mod decode;
mod demo;
mod open;
mod send;
mod show;
mod sim;

use std::io::Write;
use std::sync::Arc;

use motionlink_link::can::SlcanAdapter;
use motionlink_link::describe::Describe;
use motionlink_link::pipe::{EmulatorHost, PipeConfig};
use motionlink_link::url::PortUrl;
use motionlink_link::{RealClock, SharedClock};
use motionlink_powercube::args::{
    Baud, CanBitRate, ModuleOptions, MotionTimeout, MoveAcceleration, MoveVelocity, PollInterval, ReplyTimeout, Target,
    Tolerance,
};
use motionlink_powercube::client::{Client, Guard, Module, MotionSpec, MoveSpec, PortLink, Progress};
use motionlink_powercube::describe::Describer;
use motionlink_powercube::model::{Address, CubeState, ModuleKind, MotionId, Param, Position, Value};
use motionlink_powercube::sim::{SimConfig, Variant};
use motionlink_powercube::wire::Payload;
use motionlink_powercube::wire::{Action as PcAction, Request};
use motionlink_powercube::{Emulator, Error};

pub use decode::{decode, DecodeArgs};
pub use demo::demo;
pub(crate) use open::{bus_options, module_options, open};
use send::{parse_send, print_params, send};
use show::{info, progress_text, report_done, scan, watch};
pub use sim::{sim, SimArgs};

use crate::common::{self, CliError, Out, ServeArgs, WatchFormat};
use crate::numbers::{at_least, whole};
use crate::tap::{LinkArgs, Tap};

/// `motionlink powercube` arguments. Every option may come before or after the action.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The port: a serial device or tcp://HOST:PORT (RS232), socketcan://IF or slcan://PATH (CAN), or sim.
    /// Default: --device, else MOTIONLINK_PORT. While a command uses a serial, tcp:// or slcan:// port, another motionlink on it exits 3 naming that
    /// command (pid, action), and `stop` stops its motion (see `stop --help`).
    #[arg(long, global = true)]
    pub port: Option<String>,
    #[command(flatten)]
    pub link: LinkArgs,
    /// The module's address, 1..31.
    #[arg(long, default_value = "1", global = true)]
    pub module: Address,
    #[command(flatten)]
    pub bus: BusArgs,
    /// What to do.
    #[command(subcommand)]
    pub action: Action,
}

/// The bus's options: the session's settings and, with `--port sim`, the emulated modules' firmware. Every
/// `motionlink powercube` action and `motionlink console powercube` take them (a device table gives them as
/// the same keys).
#[derive(clap::Args, Debug, Clone)]
pub struct BusArgs {
    /// RS232 baud rate: one of 1200, 2400, 4800, 9600 (the modules' default), 19200, 38400, 57600, 115200
    /// (the console's emulated line, with `--port sim`, runs at this rate).
    #[arg(long, default_value = "9600", global = true)]
    pub baud: Baud,
    /// CAN bit rate of an SLCAN adapter: one of the rates SLCAN offers, 10000, 20000, 50000, 100000,
    /// 125000, 250000, 500000, 800000, 1000000.
    #[arg(long, default_value = "1000000", global = true)]
    pub bitrate: CanBitRate,
    /// Acknowledge timeout in ms, 1 to 60000 (default: 200 on RS232, 50 on CAN).
    #[arg(long, value_name = "MS", global = true)]
    pub timeout_ms: Option<ReplyTimeout>,
    /// How often `home` and `move` (and the console's moves, jogs and homing) read the module's state while
    /// they wait, in ms (1 to 10000): polls are never sent faster than this, however quickly the line answers.
    #[arg(long, value_name = "MS", default_value = "10", global = true)]
    pub poll_ms: PollInterval,
    /// Do not arm the module watchdog for `home` and `move` (and the console's motions): the Config word is
    /// left alone, and a host that dies then leaves the module moving. Signals, a closed stdout (a closed
    /// page, Stop and the end of the console) and errors still halt it.
    #[arg(long, global = true)]
    pub no_watchdog: bool,
    #[command(flatten)]
    pub sim_variants: crate::common::SimVariants<Variant>,
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
    /// Read parameters (by name, such as ActPos, or id, such as 60 or 0x3c); several at once.
    Get {
        /// The parameters.
        #[arg(required = true, value_name = "PARAM")]
        params: Vec<String>,
    },
    /// Write a parameter.
    Set {
        /// The parameter.
        param: String,
        /// The value, in the parameter's type and unit.
        #[arg(allow_negative_numbers = true)]
        value: String,
    },
    /// Send one command and print it and the module's acknowledge, each explained. Takes a typed command
    /// (get PARAM, set PARAM VALUE, reset, halt, recalc-pid, reset-time, save-parameters), its payload in
    /// hex ("0A 3C": GetExtended ActPos), or a whole RS232 telegram in hex ("02 04 22 0A 3C 6C 03": STX,
    /// TELID, data, BCC, ETX; the BCC is checked and the address must be --module's). Motion commands
    /// (home, the SetMotion family) are refused: use home or move, which watch and stop them.
    Send {
        /// The command's words, its payload in hex, or a whole RS232 telegram in hex.
        #[arg(required = true, value_name = "WORD", allow_negative_numbers = true)]
        words: Vec<String>,
    },
    /// Home the module and wait for the end of homing (watchdog armed; a signal halts it).
    Home {
        /// Give up (and halt) after this many seconds (above 0).
        #[arg(long = "timeout-s", alias = "timeout", value_name = "S", default_value = "60")]
        timeout_s: MotionTimeout,
    },
    /// Reset the module's error state (and switch off a watchdog that a dead host left expired), confirmed by
    /// the state read back: STATE_ERROR still set (a servo amplifier fault: switch the module off) is an error.
    Reset,
    /// Stop what moves: Halt, confirmed by the state read back (halted until a reset); a motionlink holding
    /// the port (a move in another terminal) is stopped first.
    ///
    /// Halt goes to the module (it stops at once and stays halted until `reset`); once acknowledged, its
    /// state is read until STATE_MOTION is clear (at most 500 ms) and its position is printed. Exit 0 only if
    /// the module confirmed that; otherwise the message says what it did not confirm.
    ///
    /// If another motionlink holds the port (its lock file in $XDG_RUNTIME_DIR/motionlink, else
    /// motionlink-UID in the temporary directory, names its pid and command), that process is sent SIGINT:
    /// it halts its module as on Ctrl-C and exits 130, and says what it stopped. This command waits for the
    /// port (at most 15 s), prints who it stopped and what that process said, then halts and reads back as
    /// above.
    #[command(visible_alias = "halt")]
    Stop,
    /// Ramp to a position (rad or m) and wait for the end of the ramp (watchdog armed; a signal halts it).
    /// Succeeds only if the final position read from the module lies within --tolerance of the target.
    Move {
        /// The target position (rad or m, the module's unit).
        position: Target,
        /// Velocity (rad/s or m/s, above 0), written to TargetVel first; if not given, the module's
        /// TargetVel is used as it is.
        #[arg(long)]
        vel: Option<MoveVelocity>,
        /// Acceleration (rad/s² or m/s², above 0), written to TargetAcc first; if not given, the module's
        /// TargetAcc is used as it is.
        #[arg(long)]
        acc: Option<MoveAcceleration>,
        /// Give up (and halt) after this many seconds (above 0).
        #[arg(long = "timeout-s", alias = "timeout", value_name = "S", default_value = "60")]
        timeout_s: MotionTimeout,
        /// In-position tolerance (rad or m, above 0, at most 0.1): the move succeeds only if the final actual
        /// position is at most this far from the target. The manual has no in-position window parameter.
        #[arg(long, default_value = "0.001")]
        tolerance: Tolerance,
    },
    /// Run a motion mode of the manual (FSTEP, FVEL, FCUR, IRAMP, ISTEP, IVEL, ICUR, FCOSLOOP, FRAMPLOOP,
    /// FRAMP; an _ACK form for the extended acknowledge), its numbers checked against the module's limits
    /// before anything moves (watchdog armed; a signal halts it). A position mode waits until the module is
    /// at rest within --tolerance of its target; a velocity, current or loop mode runs for --for-s (without
    /// it, until a signal), then a velocity mode is sent velocity 0 and waited for at rest, and the others
    /// are halted (halted until `reset`).
    Motion {
        /// The mode as the manual names it, any case, _MODE optional: fvel, FSTEP_MODE, ivel_ack ...
        mode: MotionId,
        /// What the mode takes: a position (rad or m), a velocity (rad/s or m/s) or a current (A); in the I
        /// modes whole encoder ticks, ticks/s or current digits (-500..500).
        #[arg(allow_negative_numbers = true)]
        value: f64,
        /// FSTEP and ISTEP: the step's time; FCOSLOOP: its period (ms, 1 to 65535).
        #[arg(long, value_name = "MS")]
        time_ms: Option<u16>,
        /// A velocity, current or loop mode: how long it runs, in seconds (above 0).
        #[arg(long = "for-s", value_name = "S")]
        for_s: Option<MotionTimeout>,
        /// Give up (and halt) after this many seconds (above 0): a position mode's motion, a velocity
        /// mode's stop.
        #[arg(long = "timeout-s", value_name = "S", default_value = "60")]
        timeout_s: MotionTimeout,
        /// A position mode's in-position tolerance (rad or m, above 0, at most 0.1; default 0.001; a device
        /// table's `tolerance` is `move`'s).
        #[arg(long, id = "motion_tolerance")]
        tolerance: Option<Tolerance>,
    },
    /// Print position and state until Ctrl-C (or --count samples).
    Watch {
        /// Milliseconds between samples (1 to 3600000).
        #[arg(long, default_value_t = 200, value_parser = whole::<u64>("the sample interval", 1, 3_600_000, "ms"))]
        interval_ms: u64,
        /// Stop after this many samples (at least 1).
        #[arg(long, value_parser = at_least::<u64>("the number of samples", 1))]
        count: Option<u64>,
        /// Print CSV (a header line, then one line per sample) instead of text.
        #[arg(long)]
        csv: bool,
    },
    /// List the parameter table.
    Params,
}

/// A library error as a command-line error (its class decides the exit code).
fn failed(e: Error) -> CliError {
    common::classified(&e)
}

/// `e` with what the command was doing when it happened.
fn context(e: Error, context: String) -> CliError {
    failed(Error::Context { context, source: Box::new(e), hint: "" })
}

fn parse_param(text: &str) -> Result<Param, CliError> {
    text.parse::<Param>().map_err(CliError::usage)
}

/// `motionlink powercube ...`
pub fn run(args: Args) -> Result<(), CliError> {
    let mut out = std::io::stdout().lock();
    if let Action::Params = args.action {
        return print_params(&mut out, crate::term::json());
    }
    if let Action::Watch { csv, .. } = args.action {
        WatchFormat::of(csv, crate::term::json())?;
    }
    if let Action::Motion { mode, value, time_ms, for_s, timeout_s, tolerance } = args.action {
        MotionSpec::from_args(mode, value, time_ms, for_s, tolerance, timeout_s).map_err(failed)?;
    }
    let request = match &args.action {
        Action::Send { words } => Some(parse_send(words, args.module.get())?),
        _ => None,
    };
    let port = args.link.resolve_port("powercube", args.port.as_deref())?;
    // Signals are handled before the port is claimed: a `stop` from another terminal may send one at once.
    let interrupt = common::interrupt_token();
    let stopped = crate::portlock::claim_as("powercube", &port, matches!(args.action, Action::Stop))?;
    let clock = RealClock::shared();
    let describer = || Box::new(Describer::new()) as Box<dyn Describe + Send>;
    let can_interface = port.parse::<PortUrl>().map(|u| crate::tap::can_interface(&u)).unwrap_or_default();
    let tap = Tap::new("powercube", &port, &clock, &args.link, &can_interface, &describer, request.is_some())?;
    let (client, host) = open(&args, &port, &tap, &clock)?;
    client.set_cancel(interrupt);
    if !matches!(args.action, Action::Scan | Action::Params) {
        let module = args.module;
        crate::probe::use_profile(|p| motionlink_powercube::probe::use_profile(&client, p, &port, module))?;
    }
    let guard = module_options(&args).guard(host.is_some());
    let o =
        &Out { json: crate::term::json(), family: "powercube", port: &port, unit: Some(("module", args.module.get())) };
    let result = match &request {
        Some(r) => send(&args, &client, r, &tap, o, &mut out),
        None => act(&args, &client, guard, o, stopped.as_ref(), &mut out),
    };
    // Closing stops what is still moving and switches off what was armed, and says whether it could;
    // the in-process emulator goes only after that.
    let closed = client.close().map(|_| ());
    drop(host);
    tap.flush();
    // A module that never answered is named as absent (a scan says so itself).
    let result = match args.action {
        Action::Scan => result,
        _ => result.map_err(|e| {
            let absent = || {
                let mut scan = format!("motionlink powercube --port {port}");
                if args.bus.baud != Baud::DEFAULT {
                    scan.push_str(&format!(" --baud {}", args.bus.baud));
                }
                format!("no module answers at address {} on {port}; `{scan} scan` lists the modules there", args.module)
            };
            // A stop's own message says whether anything was stopped: it stays.
            match args.action {
                Action::Stop => tap.name_absent_after(e, absent),
                _ => tap.name_absent(e, absent),
            }
        }),
    };
    match (result, closed) {
        // An unconfirmed halt's error said already that the watchdog was left online.
        (Err(e), Err(motionlink_powercube::Error::WatchdogLeftOnline { .. })) if e.stop_unconfirmed() => Err(e),
        (Err(e), Err(also)) => {
            common::say_error(format!("motionlink: {also}"));
            Err(if motionlink_link::error::Classify::stop_unconfirmed(&also) { e.stop_not_confirmed() } else { e })
        }
        (result, closed) => result.and(closed.map_err(failed)),
    }
}

/// Does what `args` ask of the module, on `client`.
fn act(
    args: &Args,
    client: &Client,
    guard: Guard,
    o: &Out<'_>,
    stopped: Option<&motionlink_link::portlock::Stopped>,
    out: &mut dyn Write,
) -> Result<(), CliError> {
    let m = client.module(args.module);
    match &args.action {
        Action::Scan => scan(client, o, out)?,
        Action::Info => info(o, &m, out)?,
        Action::State => actions::state(o, &m, out)?,
        Action::Get { params } => actions::get(o, &m, params, out)?,
        Action::Set { param, value } => actions::set(o, &m, param, value, out)?,
        Action::Home { timeout_s } => actions::home(o, &m, guard, timeout_s.get(), out)?,
        Action::Reset => actions::reset(o, &m, out)?,
        Action::Stop => actions::stop(o, &m, stopped, out)?,
        Action::Move { position, vel, acc, timeout_s, tolerance } => {
            let spec = MoveSpec::from_args(*position, *vel, *acc, *tolerance, *timeout_s);
            actions::move_to(o, &m, guard, &spec, out)?
        }
        Action::Motion { mode, value, time_ms, for_s, timeout_s, tolerance } => {
            let spec = MotionSpec::from_args(*mode, *value, *time_ms, *for_s, *tolerance, *timeout_s);
            actions::motion(o, &m, guard, &spec.map_err(failed)?, out)?
        }
        Action::Watch { interval_ms, count, csv } => {
            watch(client, o, &m, out, WatchFormat::of(*csv, crate::term::json())?, *interval_ms, *count)?
        }
        Action::Params | Action::Send { .. } => {}
    }
    Ok(())
}
