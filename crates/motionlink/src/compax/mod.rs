//! `motionlink compax`, `motionlink sim compax`, `motionlink decode compax` and the COMPAX part of the demo.

use std::io::Write;
use std::path::PathBuf;
use std::time::Duration;

use motionlink_compax::client::{AfterRaw, Config, MoveRequest, MoveTarget, TravelLimits};
use motionlink_compax::model::{
    BaudRate, OutputNumber, OutputState, ParamId, PollInterval, Position, RampMs, ReplyTimeout, SpeedPercent, StatusId,
    StatusValue, TimeLimit, Tolerance, WatchInterval,
};
use motionlink_compax::sim::Variant;
use motionlink_compax::wire::{Address, Mode};
use motionlink_compax::{Client, DriveOptions, Emulator, Error};
use motionlink_link::clock::SharedClock;
use motionlink_link::error::{Classify, ErrorClass};
use motionlink_link::link::Link;
use motionlink_link::pipe::{EmulatorHost, PipeConfig};
use motionlink_link::url::PortUrl;
use motionlink_link::RealClock;

use crate::common::{self, CliError, Out, Row, ServeArgs, WatchFormat};
use crate::decode::CaptureArgs;
use crate::numbers::{at_least, finite};
use crate::tap::{LinkArgs, Tap};
use motionlink_compax::describe::Describer;
use motionlink_link::describe::Describe;

mod actions;
mod decode;
mod demo;
mod open;
mod show;
mod sim;

pub use decode::{decode, DecodeArgs};
pub use demo::demo;
pub(crate) use open::{line_options, link, open};
use show::{send_text, status_row};
pub use sim::{sim, SimArgs};

/// `motionlink compax` arguments. Every option may come before or after the action; every value is checked
/// by its type's rule in motionlink-compax (the same rule and message as in Python and the console).
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The port: a device path (/dev/ttyUSB0, COM3), tcp://HOST:PORT, or sim. Default: --device, else
    /// MOTIONLINK_PORT. While a command uses a serial, tcp:// or slcan:// port, another motionlink on it exits 3 naming that
    /// command (pid, action), and `stop` stops its motion (see `stop --help`).
    #[arg(long, global = true)]
    pub port: Option<String>,
    #[command(flatten)]
    pub link: LinkArgs,
    /// The drive's address (P194), 1..=31.
    #[arg(long, default_value = "1", global = true)]
    pub drive: Address,
    #[command(flatten)]
    pub line: LineArgs,
    /// The port resolved from --port, --device or MOTIONLINK_PORT (set by `run`).
    #[arg(skip)]
    pub resolved_port: String,
    /// What to do.
    #[command(subcommand)]
    pub action: Action,
}

/// The line's options: the session's settings and, with `--port sim`, the emulated drives' firmware. Every
/// `motionlink compax` action and `motionlink console compax` take them (a device table gives them as the
/// same keys).
#[derive(clap::Args, Debug, Clone)]
pub struct LineArgs {
    /// The drives' operating mode P196 (0..=127): BCC, parity, reply end, address prefix...
    #[arg(long, default_value = "0", global = true)]
    pub mode: Mode,
    /// The drives' baud rate P195 (150, 300, 600, 1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200; the
    /// console's emulated line, with `--port sim`, runs at this rate).
    #[arg(long, default_value = "9600", global = true)]
    pub baud: BaudRate,
    /// Time a drive may take to start answering, in ms (1..=60000, on top of the wire time).
    #[arg(long, default_value = "200", value_name = "MS", global = true)]
    pub timeout_ms: ReplyTimeout,
    /// Send the short command names (PA, PR, SD, AL, OT) instead of the long ones.
    #[arg(long, global = true)]
    pub short: bool,
    #[command(flatten)]
    pub sim_variants: crate::common::SimVariants<Variant>,
}

/// `motionlink compax` actions.
#[derive(clap::Subcommand, Debug)]
pub enum Action {
    /// Find the drives on the bus (reads S1 of addresses 1..=31).
    Scan,
    /// Read status values (default: S1 S2 S3 S16 S17 S18).
    Status {
        /// Status values such as S1 S16.
        values: Vec<StatusId>,
    },
    /// Read parameters, such as P194; several at once.
    Get {
        /// The parameters.
        #[arg(required = true, value_name = "PARAM")]
        params: Vec<ParamId>,
    },
    /// Write a parameter, such as P196 8, and read it back (P194..P196 take effect at the drive's next
    /// power-on).
    Set {
        /// The parameter.
        param: ParamId,
        /// The value.
        #[arg(value_parser = finite::<f64>("the value", ""))]
        value: f64,
    },
    /// Move the axis, wait until it is at rest, and check it is at its target (a signal stops it). Every
    /// argument is checked before anything is sent.
    #[command(group(clap::ArgGroup::new("target_of_move").args(["target", "abs", "rel"]).required(true)))]
    Move {
        /// Move to this absolute position (drive's unit), as --abs does: `move 100` is `move --abs 100`.
        #[arg(value_name = "POSITION", conflicts_with_all = ["abs", "rel"])]
        target: Option<Position>,
        /// Move to this absolute position (drive's unit).
        #[arg(long, conflicts_with = "rel")]
        abs: Option<Position>,
        /// Move by this distance from the drive's target S2 (drive's unit).
        #[arg(long)]
        rel: Option<Position>,
        /// SPEED in percent of the drive's maximum speed (0.000001 to 100: a command carries six decimals).
        #[arg(long)]
        speed: Option<SpeedPercent>,
        /// ACCEL: ramp time in ms (1..=32767).
        #[arg(long)]
        accel: Option<RampMs>,
        /// Send the binary commands.
        #[arg(long)]
        binary: bool,
        /// Give up (and stop the axis) after this many seconds (more than 0).
        #[arg(long, default_value = "600")]
        timeout_s: TimeLimit,
        /// Success only if the axis comes to rest this close to its target (drive's unit, more than 0, at
        /// most 1000000).
        #[arg(long, default_value_t = Tolerance::DEFAULT)]
        tolerance: Tolerance,
        /// Refuse targets below this position (checked before anything moves).
        #[arg(long)]
        min_pos: Option<Position>,
        /// Refuse targets above this position (checked before anything moves).
        #[arg(long)]
        max_pos: Option<Position>,
        /// Interval of the status polls while waiting, in ms (1..=10000).
        #[arg(long, default_value = "50")]
        poll_ms: PollInterval,
        /// Return once the drive has taken the move (its target read back), without waiting: the move is
        /// handed over and keeps running after the command exits (nothing stops it).
        #[arg(long, conflicts_with_all = ["timeout_s", "tolerance", "poll_ms"])]
        no_wait: bool,
    },
    /// Read S1 and S17 over and over and print them, one line each, until interrupted (or --count lines).
    Watch {
        /// Interval between two lines, in ms (1..=3600000).
        #[arg(long, default_value = "200")]
        interval_ms: WatchInterval,
        /// Stop after this many samples (at least 1).
        #[arg(long, value_parser = at_least::<u64>("the number of samples", 1))]
        count: Option<u64>,
        /// Print CSV (a header line, then one line per sample) instead of text.
        #[arg(long)]
        csv: bool,
    },
    /// Send one command and print it and the drive's reply as they went on the line, each explained. Takes
    /// the command as text ("S1", "P12", "P12=0") or its characters in hex ("53 31"), without the address
    /// prefix, CR and BCC: those are added as --drive and --mode ask. A move it starts is waited for until
    /// it ends (a signal stops it); the status polls of that wait are counted apart from the reply.
    Send {
        /// The command's words (joined by spaces), or its characters in hex.
        #[arg(required = true, value_name = "WORD", allow_negative_numbers = true)]
        words: Vec<String>,
    },
    /// Stop what moves: a drive still moving is switched off (OUTPUT O0=0, the only stop COMPAX has),
    /// confirmed by S17 read back; a motionlink holding the port (a move in another terminal) is stopped
    /// first.
    ///
    /// S17 is read; if a command is active (the axis moves), OUTPUT O0=0 goes out and S17 is read again until
    /// no command is active; then S1 (the position) and S16 (switched on or off) are read. OUTPUT O0=0
    /// switches the drive off: the command set has no stop that leaves the drive on (every move command is
    /// refused with E92 while one runs), so the drive then takes no move until `output 0 1` switches it on
    /// again (the command is printed). A drive at rest is not switched off. Exit 0 only if the drive
    /// confirmed it is at rest; otherwise the message says the axis may still be moving.
    ///
    /// If another motionlink holds the port (its lock file in $XDG_RUNTIME_DIR/motionlink, else
    /// motionlink-UID in the temporary directory, names its pid and command), that process is sent SIGINT:
    /// it stops the move it started as on Ctrl-C and exits 130, and says what it stopped. This command waits
    /// for the port (at most 15 s), prints who it stopped and what that process said, then reads back (and
    /// stops what still moves) as above.
    Stop,
    /// Switch an output: OUTPUT ON=S (output 0 is the drive itself: 0 switches it off, 1 on).
    Output {
        /// Output number (0..=65535).
        number: OutputNumber,
        /// 0 or 1 (O0: 0, 1 or 2).
        state: OutputState,
    },
    /// Send a command as it is, such as "S1", "POSA 10$", "!" (flag characters $ , / ? at the end are sent as
    /// flags); prints the reply. A move it starts keeps running after the command exits, unless --wait.
    Raw {
        /// The command.
        command: String,
        /// Send it to address 32, every drive on the bus (the manual's broadcast: no drive answers), instead
        /// of --drive: `OUTPUT O0=0` switches every drive off, `!` starts what each holds in its buffer.
        #[arg(long, conflicts_with = "wait")]
        broadcast: bool,
        /// Wait until a move the command started has ended (a signal stops it; its position is not
        /// checked: use move for that).
        #[arg(long)]
        wait: bool,
        /// With --wait: give up (and stop the axis) after this many seconds (more than 0).
        #[arg(long, default_value = "600", requires = "wait")]
        timeout_s: TimeLimit,
        /// With --wait: interval of the status polls, in ms (1..=10000).
        #[arg(long, default_value = "50", requires = "wait")]
        poll_ms: PollInterval,
    },
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

/// `motionlink compax` on the same port and bus settings, for a hint that gives a command to run.
fn same_line(args: &Args) -> String {
    // The port as resolved (from --port, --device or MOTIONLINK_PORT), else as given.
    let port = match (args.resolved_port.as_str(), args.port.as_deref()) {
        ("", Some(p)) => p,
        ("", None) => "PORT",
        (resolved, _) => resolved,
    };
    format!("motionlink compax --port {port}{}", bus_options(args))
}

/// How to switch drive `a` on again, as a command line on the same port and bus settings.
fn switch_on_hint(args: &Args, a: u8) -> String {
    format!("drive {a} is switched off; to switch it on again: {} --drive {a} output 0 1", same_line(args))
}

/// An error of the library with the message the command line shows: classed as the library classes it.
struct Explained<'a> {
    error: &'a Error,
    message: String,
}

impl Classify for Explained<'_> {
    fn class(&self) -> ErrorClass {
        self.error.class()
    }

    fn reported(&self) -> Option<motionlink_link::error::DeviceCode> {
        self.error.reported()
    }

    fn stop_unconfirmed(&self) -> bool {
        self.error.stop_unconfirmed()
    }
}

impl std::fmt::Display for Explained<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.message)
    }
}

/// The error as the user reads it: for a signal, which one and what was stopped; for a drive the error
/// left (or found) switched off, the command that switches it on. The exit code is the error's class
/// ([`common::classified`]).
fn error_for(args: &Args, e: Error) -> CliError {
    let cause = common::stop_cause();
    let mut message = match (e.root(), e.stop_report(), cause) {
        (Error::Cancelled { stop }, _, Some(cause)) => format!("{} received: {stop}", cause.name()),
        (Error::CancelledBeforeMotion, _, cause) => {
            let cause = cause.map_or("interrupted".to_string(), |c| format!("{} received", c.name()));
            format!("{cause}: the action ended before it was done; nothing was moved")
        }
        _ => e.to_string(),
    };
    // How to switch a drive on again is a note: left out with -q.
    if !crate::term::output().quiet {
        for a in e.switched_off_drives() {
            message.push('\n');
            message.push_str(&switch_on_hint(args, a));
        }
    }
    common::classified(&Explained { error: &e, message })
}

/// Runs `motionlink compax`.
pub fn run(mut args: Args) -> Result<(), CliError> {
    args.resolved_port = args.link.resolve_port("compax", args.port.as_deref())?;
    let clock: SharedClock = RealClock::shared();
    let mode = args.line.mode;
    let describer = move || Box::new(Describer::new(mode)) as Box<dyn Describe + Send>;
    let sending = matches!(args.action, Action::Send { .. });
    if let Action::Watch { csv, .. } = args.action {
        WatchFormat::of(csv, crate::term::json())?;
    }
    let tap = Tap::new("compax", &args.resolved_port, &clock, &args.link, "can0", &describer, sending)?;
    let result = act(&args, &tap, &clock);
    tap.flush();
    // A drive that never answered is named as absent (a scan says so itself).
    match args.action {
        Action::Scan => result,
        _ => result.map_err(|e| {
            let absent = || {
                let port = &args.resolved_port;
                let (drive, options) = (args.drive, bus_options(&args));
                format!("drive {drive} does not answer on {port}; `motionlink compax --port {port}{options} scan` lists the drives there")
            };
            // A stop's own message says whether anything was stopped: it stays.
            match args.action {
                Action::Stop => tap.name_absent_after(e, absent),
                _ => tap.name_absent(e, absent),
            }
        }),
    }
}

/// `--mode` and `--baud` as a command line on this bus gives them (only where not the default).
fn bus_options(args: &Args) -> String {
    let mut options = String::new();
    if args.line.mode.to_p196() != 0 {
        options.push_str(&format!(" --mode {}", args.line.mode.to_p196()));
    }
    if args.line.baud != BaudRate::DEFAULT {
        options.push_str(&format!(" --baud {}", args.line.baud));
    }
    options
}

impl Args {
    /// How results are printed: family, port and drive first.
    fn out(&self) -> Out<'_> {
        Out {
            json: crate::term::json(),
            family: "compax",
            port: &self.resolved_port,
            unit: Some(("drive", self.drive.get())),
        }
    }
}

/// Does what `args` ask: checks the action's arguments, opens the port, calls the action's function and
/// closes the bus.
fn act(args: &Args, tap: &Tap, clock: &SharedClock) -> Result<(), CliError> {
    let mut out = std::io::stdout().lock();
    // Every argument of an action is checked before the port is opened: nothing is sent for an action that
    // cannot be made.
    let checked = actions::check(args)?;
    // Signals are handled before the port is claimed: a `stop` from another terminal may send one at once.
    common::interrupt_token();
    let stopped = crate::portlock::claim_as("compax", &args.resolved_port, matches!(args.action, Action::Stop))?;
    let (poll, tolerance) = (checked.poll, checked.move_plan.as_ref().map(|p| p.tolerance));
    let bus = open(args, tap, |cfg| {
        if let Some(p) = poll {
            cfg.poll_interval = p;
        }
        if let Some(t) = tolerance {
            cfg.in_position_tolerance = t.position();
        }
    })?;
    let drive = args.drive;
    if !matches!(args.action, Action::Scan) {
        let port = &args.resolved_port;
        crate::probe::use_profile(|p| motionlink_compax::probe::use_profile(&bus, p, port, drive))?;
    }
    let result = act_on(args, tap, clock, &bus, &checked, stopped.as_ref(), &mut out);
    // What this command set in motion and did not hand over is stopped here, and the result said (also
    // after an error: the stop is tried again).
    match (result, bus.close()) {
        (result, Ok(report)) => {
            if !report.is_empty() {
                common::say(format!("motionlink: {report}"));
            }
            result
        }
        (Ok(()) | Err(CliError::OutputClosed), Err(e)) => Err(error_for(args, e)),
        (Err(first), Err(e)) => {
            // An error that said already that a stop was not confirmed is not said again in full.
            let said = first.stop_unconfirmed();
            let again = e.stop_unconfirmed();
            let note = match &e {
                Error::CloseUnconfirmed { stop } if said => {
                    let drives: Vec<String> = stop.unconfirmed().iter().map(|a| a.to_string()).collect();
                    let s = if drives.len() == 1 { "" } else { "s" };
                    format!(
                        "the end of the session tried the stop again: drive{s} {} not confirmed either",
                        drives.join(", ")
                    )
                }
                _ => format!("then {}", error_for(args, e)),
            };
            let first = first.map_message(|m| format!("{m}; {note}"));
            Err(if again { first.stop_not_confirmed() } else { first })
        }
    }
}

/// The action `args` ask for, on the open bus.
fn act_on(
    args: &Args,
    tap: &Tap,
    clock: &SharedClock,
    bus: &Client,
    checked: &actions::Checked,
    stopped: Option<&motionlink_link::portlock::Stopped>,
    out: &mut dyn Write,
) -> Result<(), CliError> {
    let drive = args.drive;
    match &args.action {
        Action::Scan => actions::scan(args, bus, out)?,
        Action::Status { .. } => actions::status(args, bus, &checked.status_ids, out)?,
        Action::Get { params } => actions::get(args, bus, params, out)?,
        Action::Set { param, value } => actions::set(args, bus, *param, *value, out)?,
        Action::Move { no_wait, .. } => actions::move_drive(args, bus, checked.move_plan.as_ref(), *no_wait, out)?,
        Action::Watch { interval_ms, count, csv } => {
            show::watch(args, bus, clock, interval_ms.duration(), count, *csv, out)?;
        }
        Action::Stop => actions::stop(args, bus, stopped, out)?,
        Action::Output { .. } => actions::output(args, bus, checked.output, out)?,
        Action::Raw { command, broadcast, .. } => actions::raw(args, bus, command, *broadcast, checked.raw_wait, out)?,
        Action::Send { words } => actions::send(args, tap, bus, drive, words, out)?,
    }
    Ok(())
}

#[cfg(test)]
mod tests;
