//! `motionlink`: operate, script, emulate and decode industrial motion devices.
//!
//! ```text
//! motionlink <family> <action> ... [--port PORT]  operate a device (scu, powercube, compax); options
//!                                                 go before or after the action
//! motionlink sim <family> --tcp ADDR | --pty     serve an emulated device
//! motionlink probe <family> --port PORT          commissioning: identify, measure, probe (nothing moves)
//! motionlink decode <family>                     annotate a capture
//! motionlink demo                                the manuals' examples against built-in emulators
//! motionlink console <family> --port PORT        a commissioning page in the browser, on 127.0.0.1
//! ```
//!
//! Exit codes: 0 success, 1 device refused or device error (or a move that did not reach its target),
//! 2 usage error, 3 transport error, 128 + n when ended by signal n (after stopping what was started).
//! With `--json`, an error is one JSON object on stderr: `{"kind": ..., "message": ..., "exit_code": ...}`.

mod common;
mod compax;
mod console;
mod decode;
mod demo;
mod devices;
mod gateway;
mod json;
mod manpage;
mod numbers;
mod portlock;
mod ports;
mod powercube;
mod probe;
mod scu;
mod tap;
mod term;
mod tips;

use std::process::ExitCode;

use clap::{CommandFactory, Parser, Subcommand};

use crate::common::CliError;

#[derive(Parser, Debug)]
#[command(name = "motionlink", version, about = "Operate, script, emulate and decode industrial motion devices")]
struct Cli {
    /// More on stderr: -v the live wire trace (each telegram with time, direction, hex and meaning) and
    /// information, -vv
    /// debug logs, -vvv trace logs. RUST_LOG overrides the logs.
    #[arg(short, long, action = clap::ArgAction::Count, global = true)]
    verbose: u8,
    /// Only errors on stderr.
    #[arg(short, long, global = true, conflicts_with = "verbose")]
    quiet: bool,
    /// Colours on stderr: auto (a terminal, unless NO_COLOR is set), always or never.
    #[arg(long, value_enum, default_value_t = term::ColorChoice::Auto, global = true, value_name = "WHEN")]
    color: term::ColorChoice,
    /// JSON on stdout instead of tables and text (one object per line), and an error as one JSON object on
    /// stderr: {"kind", "message", "exit_code"}.
    #[arg(long, global = true)]
    json: bool,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Ewellix / Schaeffler SCU control unit (RS232).
    ///
    /// What the manual leaves open (grouping indices, UserPositionData, cyclic objects, reading remote data
    /// back) is probed on the unit in use; `motionlink sim scu --variant NAME` (`--sim-variant` with --port
    /// sim) emulates a unit that does it the other way. A device profile written by `motionlink probe scu
    /// --save` (profiles.toml beside devices.toml) is loaded when the unit gives the same firmware and
    /// configuration texts: its probes are skipped, and --json results name it ("profile").
    Scu(scu::Args),
    /// Schunk / Amtec PowerCube modules (RS232, CAN).
    ///
    /// What the manual leaves open (the Inc twins, ActFPosStateDio, the RS232 broadcast refresh, the life
    /// sign's acknowledge) is probed on the module in use; `motionlink sim powercube --variant NAME`
    /// (`--sim-variant` with --port sim) emulates a module that does it the other way. A device profile written
    /// by `motionlink probe powercube --save` (profiles.toml beside devices.toml) is loaded for --module when
    /// it gives the same version and serial number: its probes are skipped, and --json results name it.
    Powercube(powercube::Args),
    /// Parker COMPAX servo drives (RS485 / RS232).
    ///
    /// What the manual leaves open (the form of the echo, status values with or without their name) is probed
    /// on the drive in use; `motionlink sim compax --variant NAME` (`--sim-variant` with --port sim) emulates
    /// a drive that does it the other way. A device profile written by `motionlink probe compax --save`
    /// (profiles.toml beside devices.toml) is loaded for --drive when it gives the same S31 and S32: its echo
    /// probe is skipped, and --json results name it ("profile").
    Compax(compax::Args),
    /// Commissioning: find what is on the line, identify it, measure the link and run every harmless probe
    /// of what the manuals leave open (nothing moves); --save keeps the findings as a device profile.
    Probe {
        #[command(subcommand)]
        family: probe::Family,
    },
    /// Serve a commissioning page for a device in the browser, on 127.0.0.1 (prints its address with a
    /// token).
    Console(console::Args),
    /// Serve the devices of this machine on an MQTT broker (the fleet gateway; topics in docs/fleet.md)
    /// until SIGINT, SIGTERM, SIGHUP or SIGQUIT, which stop every motion first.
    Gateway(gateway::Args),
    /// Serve an emulated device over TCP or a pseudo-terminal until killed.
    Sim {
        #[command(subcommand)]
        family: SimFamily,
    },
    /// Read a capture (a --capture file, a candump log, hex, or raw bytes; as arguments or on stdin) and print
    /// each telegram with its meaning.
    Decode {
        #[command(subcommand)]
        family: DecodeFamily,
    },
    /// Run the manuals' examples against the built-in emulators and print each telegram with its meaning.
    Demo(DemoArgs),
    /// List the serial ports and CAN interfaces of this machine.
    ListPorts,
    /// Print a shell completion script (bash, zsh, fish, elvish, powershell) on stdout.
    Completions {
        /// The shell.
        #[arg(value_enum)]
        shell: clap_complete::Shell,
    },
    /// Print the manual page (roff) on stdout: `motionlink man | man -l -`; with --dir, write the page of
    /// every command (motionlink.1, motionlink-scu.1, motionlink-scu-move.1, ...) into a directory.
    Man {
        /// Write one page per command into DIR (created if missing) instead of the top page on stdout.
        #[arg(long, value_name = "DIR")]
        dir: Option<std::path::PathBuf>,
    },
}

#[derive(Subcommand, Debug)]
enum SimFamily {
    /// Emulate an SCU control unit.
    Scu(scu::SimArgs),
    /// Emulate a bus of PowerCube modules.
    Powercube(powercube::SimArgs),
    /// Emulate a bus of COMPAX drives.
    Compax(compax::SimArgs),
}

#[derive(Subcommand, Debug)]
enum DecodeFamily {
    /// SCU telegrams, both directions.
    Scu(scu::DecodeArgs),
    /// PowerCube RS232 frames or candump log lines.
    Powercube(powercube::DecodeArgs),
    /// COMPAX ASCII and binary telegrams, both directions.
    Compax(compax::DecodeArgs),
}

#[derive(clap::Args, Debug)]
struct DemoArgs {
    /// Run only this family's part.
    #[arg(value_enum)]
    only: Option<DemoPart>,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
enum DemoPart {
    Scu,
    Powercube,
    Compax,
}

fn run(cli: Cli) -> Result<(), CliError> {
    let json = cli.json;
    match cli.command {
        Command::Scu(args) => scu::run(args),
        Command::Powercube(args) => powercube::run(args),
        Command::Compax(args) => compax::run(args),
        Command::Probe { family } => probe::run(family, json),
        Command::Gateway(args) => gateway::run(args),
        Command::Console(args) => console::run(args),
        Command::Sim { family } => match family {
            SimFamily::Scu(args) => scu::sim(args),
            SimFamily::Powercube(args) => powercube::sim(args),
            SimFamily::Compax(args) => compax::sim(args),
        },
        Command::Decode { family } => match family {
            DecodeFamily::Scu(args) => scu::decode(args, json),
            DecodeFamily::Powercube(args) => powercube::decode(args, json),
            DecodeFamily::Compax(args) => compax::decode(args, json),
        },
        Command::ListPorts => ports::list(json),
        Command::Completions { shell } => {
            // Into a buffer first: clap_complete panics on a failed write (a closed pipe).
            let mut script = Vec::new();
            clap_complete::generate(shell, &mut Cli::command(), "motionlink", &mut script);
            std::io::Write::write_all(&mut std::io::stdout(), &script)?;
            Ok(())
        }
        Command::Man { dir } => manpage::run(Cli::command(), dir.as_deref()),
        Command::Demo(args) => {
            let mut stdout = std::io::stdout().lock();
            let parts = [
                (DemoPart::Scu, "scu", scu::demo as fn(&mut demo::DemoOut<'_>) -> Result<(), CliError>),
                (DemoPart::Powercube, "powercube", powercube::demo),
                (DemoPart::Compax, "compax", compax::demo),
            ];
            for (part, family, run) in parts {
                if args.only.is_none_or(|only| only == part) {
                    let mut out = demo::DemoOut::new(&mut stdout, json, family);
                    run(&mut out)?;
                    std::io::Write::flush(&mut out)?;
                }
            }
            Ok(())
        }
    }
}

/// clap's colours for its own messages (usage errors, help), from `--color WHEN` / `--color=WHEN` in `args`
/// (the last one wins; nothing after `--` counts) and NO_COLOR, read before clap parses: `always` and `never`
/// win, `auto` colours a terminal unless NO_COLOR is set and not empty.
fn clap_color(args: &[std::ffi::OsString]) -> clap::ColorChoice {
    let mut choice = None;
    let mut words = args.iter().skip(1).map(|a| a.to_string_lossy());
    while let Some(word) = words.next() {
        if word == "--" {
            break;
        }
        if word == "--color" {
            choice = words.next().map(|w| w.into_owned());
        } else if let Some(w) = word.strip_prefix("--color=") {
            choice = Some(w.to_string());
        }
    }
    match choice.as_deref() {
        Some("always") => clap::ColorChoice::Always,
        Some("never") => clap::ColorChoice::Never,
        _ if std::env::var("NO_COLOR").is_ok_and(|v| !v.is_empty()) => clap::ColorChoice::Never,
        _ => clap::ColorChoice::Auto,
    }
}

/// `word` as clap takes a negative number, if it is one that clap would take for an option: clap knows `-3`,
/// `-0.5` and `-1e5`, not `-.5` or `-1e-1`; those are given as the shortest decimal of the same `f64`
/// (`-0.5`, `-0.1`). Anything else (options, `-inf`, words) is left alone.
fn negative_number(word: &std::ffi::OsStr) -> Option<std::ffi::OsString> {
    let text = word.to_str()?;
    let rest = text.strip_prefix('-')?;
    let clap_takes_it = rest.starts_with(|c: char| c.is_ascii_digit())
        && rest.bytes().all(|b| b.is_ascii_digit() || b == b'.' || b == b'e' || b == b'E');
    if clap_takes_it || !rest.bytes().any(|b| b.is_ascii_digit()) {
        return None;
    }
    let value: f64 = text.parse().ok().filter(|v: &f64| v.is_finite())?;
    Some(format!("{value}").into())
}

/// The command line with negative numbers in the form clap takes ([`negative_number`]); nothing after `--`
/// is changed.
fn with_negative_numbers(args: Vec<std::ffi::OsString>) -> Vec<std::ffi::OsString> {
    let mut escaped = false;
    args.into_iter()
        .map(|a| {
            escaped |= a == "--";
            match negative_number(&a) {
                Some(n) if !escaped => n,
                _ => a,
            }
        })
        .collect()
}

/// Parses the command line; with `--json` anywhere in it, a usage error is the JSON error object.
fn parse() -> Cli {
    let args = with_negative_numbers(std::env::args_os().collect());
    let command = numbers::negative_values(Cli::command().color(clap_color(&args)));
    // The options of the device `--device` names: the defaults of the options the command line does not give.
    let command = devices::with_device_options(&args, command).unwrap_or_else(|e| {
        if std::env::args_os().any(|a| a == "--json") {
            term::write_stderr(&format!("{}\n", e.to_json()));
        } else {
            term::write_stderr(&format!("motionlink: {e}\n"));
        }
        std::process::exit(i32::from(e.exit_code()));
    });
    let parsed = command
        .clone()
        .try_get_matches_from(&args)
        .and_then(|m| <Cli as clap::FromArgMatches>::from_arg_matches(&m))
        .map_err(|e| tips::better_tips(e, &command, &args));
    match parsed {
        Ok(cli) => cli,
        Err(e) if e.use_stderr() && std::env::args_os().any(|a| a == "--json") => {
            let message = e.render().to_string();
            let message = message.trim().trim_start_matches("error: ");
            term::write_stderr(&format!("{}\n", CliError::usage(message).to_json()));
            std::process::exit(i32::from(CliError::usage("").exit_code()));
        }
        Err(e) => e.exit(),
    }
}

/// How long the end of the command waits for stderr to take what is still to be written on it.
const STDERR_FLUSH_BOUND: std::time::Duration = std::time::Duration::from_secs(2);

fn main() -> ExitCode {
    let cli = parse();
    term::init(cli.verbose, cli.quiet, cli.color, cli.json);
    // A busy `motionlink sim` that refused the first connection: one plain line, whatever the family.
    let result = run(cli).map_err(tap::refused_as_busy);
    let (code, error) = match (result, common::stop_cause()) {
        (Ok(()), Some(common::StopCause::Signal(n))) => {
            // The action ended (a read, or a stop it completed) but a signal asked the command to end.
            let cause = common::StopCause::Signal(n);
            (cause.exit_code(), Some(CliError::Interrupted(format!("ended by {}", cause.name()))))
        }
        (Ok(()), _) => (0, None),
        (Err(common::CliError::OutputClosed), _) => (0, None),
        // The reader of stdout went away and what the command started was stopped (confirmed): quietly 0.
        (Err(common::CliError::Interrupted(_)), Some(common::StopCause::OutputClosed)) => (0, None),
        (Err(e), _) => (e.exit_code(), Some(e)),
    };
    // The port was closed; a `stop` from another terminal waiting for it learns how this command ended.
    portlock::release(code, &error.as_ref().map(ToString::to_string).unwrap_or_default());
    if let Some(e) = error {
        common::print_final_error(&e);
    }
    term::flush_stderr(STDERR_FLUSH_BOUND);
    ExitCode::from(code)
}
