//! `motionlink sim <family> --tcp ADDR | --pty`: an emulator served until killed.

use std::io::Write;
use std::sync::{Arc, Mutex};

use motionlink_link::emulator::{serve_tcp_with, Emulator, ServeOptions};
use motionlink_link::RealClock;

use super::{say, to_json, CliError};

/// Where `motionlink sim` serves, and what it reports.
#[derive(clap::Args, Debug, Clone)]
pub struct ServeArgs {
    #[command(flatten)]
    pub target: ServeTarget,
    /// Print what the emulated device does (a motion started, an axis at rest, a watchdog expired) on
    /// stderr, one line each: `event <unix time in s> <what>` (with --json `{"event": WHAT, "time_s": UNIX
    /// TIME}`).
    #[arg(long)]
    pub events: bool,
}

/// `--tcp ADDR` or `--pty`.
#[derive(clap::Args, Debug, Clone)]
#[group(required = true, multiple = false)]
pub struct ServeTarget {
    /// Serve over TCP at this address, such as 127.0.0.1:0 (port 0: any free port).
    #[arg(long, value_name = "ADDR")]
    pub tcp: Option<String>,
    /// Serve on a new pseudo-terminal.
    #[arg(long)]
    pub pty: bool,
}

/// Serves `device` as `args` say, prints the single `listening on ...` line, and serves until killed.
pub fn serve<E: Emulator + 'static>(args: &ServeArgs, device: E) -> Result<(), CliError> {
    serve_behind(args, device, "")
}

/// [`serve`] for a device behind an adapter whose port URL starts with `scheme` (`slcan://`): the line
/// names the port a client gives (`listening on slcan://tcp://127.0.0.1:PORT`).
pub fn serve_behind<E: Emulator + 'static>(args: &ServeArgs, device: E, scheme: &str) -> Result<(), CliError> {
    let device = Arc::new(Mutex::new(device));
    let clock = RealClock::shared();
    let mut options = ServeOptions::default();
    if args.events {
        let json = crate::term::json();
        options.on_event = Some(Arc::new(move |event: &str| {
            let t = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap_or_default();
            let mut err = std::io::stderr().lock();
            #[derive(serde::Serialize)]
            struct Event<'a> {
                event: &'a str,
                time_s: f64,
            }
            let _ = if json {
                writeln!(err, "{}", to_json(&Event { event, time_s: t.as_secs_f64() }))
            } else {
                writeln!(err, "event {:.6} {event}", t.as_secs_f64())
            };
            let _ = err.flush();
        }));
    }
    let server = if let Some(addr) = &args.target.tcp {
        let unspecified = std::net::ToSocketAddrs::to_socket_addrs(addr.as_str())
            .map_err(|e| {
                CliError::usage(format!("--tcp {addr:?}: give an address and port such as 127.0.0.1:0 ({e})"))
            })?
            .any(|a| a.ip().is_unspecified());
        if unspecified {
            say(format!(
                "motionlink sim: warning: {addr} listens on every network interface; the emulator can be reached and \
                 driven from the network. Use 127.0.0.1 to keep it on this machine."
            ));
        }
        serve_tcp_with(addr, device, clock, options)
            .map_err(|e| CliError::transport(format!("cannot listen on {addr}: {e}")))?
    } else {
        #[cfg(unix)]
        {
            motionlink_link::emulator::serve_pty_with(device, clock, options)
                .map_err(|e| CliError::transport(format!("cannot create a pseudo-terminal: {e}")))?
        }
        #[cfg(not(unix))]
        {
            return Err(CliError::usage("--pty needs a Unix system"));
        }
    };
    let line = if crate::term::json() {
        #[derive(serde::Serialize)]
        struct Listening<'a> {
            kind: &'static str,
            listening: &'a str,
        }
        let kind = if args.target.tcp.is_some() { "tcp" } else { "pty" };
        to_json(&Listening { kind, listening: &format!("{scheme}{}", server.address()) }).to_string()
    } else if args.target.tcp.is_some() {
        format!("listening on {scheme}{}", server.address())
    } else {
        format!("listening on pty {scheme}{}", server.address())
    };
    let mut stdout = std::io::stdout().lock();
    writeln!(stdout, "{line}")?;
    stdout.flush()?;
    drop(stdout);
    server.wait();
    Ok(())
}

/// The text of an emulator's configuration file (`--config`, `--sim-config`); one that cannot be read is a
/// usage error naming it.
pub fn config_text(path: &std::path::Path) -> Result<String, CliError> {
    std::fs::read_to_string(path).map_err(|e| CliError::usage(format!("cannot read {}: {e}", path.display())))
}
