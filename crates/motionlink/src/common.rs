//! What every family's commands share: errors with exit codes, output as a table or JSON, Ctrl-C, progress
//! bars, emulator servers, and reading captures.

use std::io::Write;
use std::sync::{Arc, Mutex, OnceLock};

use motionlink_link::cancel::CancelToken;
use motionlink_link::emulator::{serve_tcp_with, Emulator, ServeOptions};
use motionlink_link::error::{Classify, ErrorClass, TransportKind};
use motionlink_link::{LinkError, RealClock};

/// An error of the command line, classed by what went wrong (the classes of
/// [`motionlink_link::error::ErrorClass`]).
#[derive(Debug, thiserror::Error)]
pub enum CliError {
    /// The device answered and refused the request (exit code 1).
    #[error("{0}")]
    Refused(String),
    /// The device reported an error, or a move did not end where it was asked to (exit code 1).
    #[error("{0}")]
    Device(String),
    /// The command line itself is wrong (exit code 2).
    #[error("{0}")]
    Usage(String),
    /// The port, the line or the timing failed; the kind says how (exit code 3).
    #[error("{1}")]
    Transport(TransportKind, String),
    /// A signal or a closed stdout ended the action; what it had started was stopped first (exit code
    /// 128 + the signal's number: 130 for SIGINT, 143 SIGTERM, 129 SIGHUP, 131 SIGQUIT; 0 for a closed stdout).
    #[error("{0}")]
    Interrupted(String),
    /// stdout was closed by its reader (`motionlink ... watch | head`): the command ends quietly with exit
    /// code 0 after stopping anything it started.
    #[error("stdout was closed")]
    OutputClosed,
}

impl CliError {
    /// The process exit code for this error: the class's ([`ErrorClass::exit_code`]: 1 refused or device, 2
    /// usage, 3 transport), except that an interruption exits with 128 + the signal's number and a closed
    /// stdout with 0.
    pub fn exit_code(&self) -> u8 {
        match self {
            CliError::Interrupted(_) => stop_cause().unwrap_or(StopCause::Signal(SIGINT)).exit_code(),
            CliError::OutputClosed => 0,
            _ => self.class().exit_code(),
        }
    }

    /// The error's class.
    pub fn class(&self) -> ErrorClass {
        match self {
            CliError::Refused(_) => ErrorClass::Refused,
            CliError::Device(_) => ErrorClass::Device,
            CliError::Usage(_) => ErrorClass::Usage,
            CliError::Transport(kind, _) => ErrorClass::Transport(*kind),
            CliError::Interrupted(_) | CliError::OutputClosed => ErrorClass::Cancelled,
        }
    }

    /// The class's name, as `--json` reports it: `refused`, `device`, `timeout`, `disconnected`, `corrupt`,
    /// `io`, `usage` or `cancelled` ([`ErrorClass::name`]).
    pub fn kind(&self) -> &'static str {
        self.class().name()
    }

    /// The error as `--json` prints it on stderr: `{"exit_code": ..., "kind": ..., "message": ...}`.
    pub fn to_json(&self) -> serde_json::Value {
        #[derive(serde::Serialize)]
        struct Shown {
            exit_code: u8,
            kind: &'static str,
            message: String,
        }
        to_json(&Shown { exit_code: self.exit_code(), kind: self.kind(), message: self.to_string() })
    }

    /// The same error with `f` applied to its message (a closed stdout becomes an interruption whose
    /// message says so).
    pub fn map_message(self, f: impl FnOnce(String) -> String) -> CliError {
        match self {
            CliError::Refused(m) => CliError::Refused(f(m)),
            CliError::Device(m) => CliError::Device(f(m)),
            CliError::Usage(m) => CliError::Usage(f(m)),
            CliError::Transport(k, m) => CliError::Transport(k, f(m)),
            CliError::Interrupted(m) => CliError::Interrupted(f(m)),
            CliError::OutputClosed => CliError::Interrupted(f("stdout closed".into())),
        }
    }

    /// A usage error.
    pub fn usage(msg: impl std::fmt::Display) -> Self {
        CliError::Usage(msg.to_string())
    }

    /// A transport error of the I/O kind (a port that cannot be opened, a file that cannot be written).
    pub fn transport(msg: impl std::fmt::Display) -> Self {
        CliError::Transport(TransportKind::Io, msg.to_string())
    }
}

impl From<LinkError> for CliError {
    fn from(e: LinkError) -> Self {
        classified(&e)
    }
}

impl From<std::io::Error> for CliError {
    fn from(e: std::io::Error) -> Self {
        if e.kind() == std::io::ErrorKind::BrokenPipe {
            record_stop_cause(StopCause::OutputClosed);
            return CliError::OutputClosed;
        }
        CliError::transport(e)
    }
}

/// The command line's error for any classified library error: the one place where error classes become
/// command-line errors (and so exit codes and `--json` kinds).
pub fn classified<E: Classify + std::fmt::Display + ?Sized>(e: &E) -> CliError {
    let msg = e.to_string();
    match e.class() {
        ErrorClass::Refused => CliError::Refused(msg),
        ErrorClass::Device => CliError::Device(msg),
        ErrorClass::Usage => CliError::Usage(msg),
        ErrorClass::Transport(kind) => CliError::Transport(kind, msg),
        ErrorClass::Cancelled => CliError::Interrupted(msg),
    }
}

/// Writes one note on stderr and ignores a failure: after SIGHUP the terminal may be gone, and a message
/// that cannot be shown must not keep the motion from being stopped (`eprintln!` would panic). A progress
/// bar on screen is hidden while the line is written. Notes are left out with `-q` and once stdout was
/// closed (the command then ends quietly); errors go through [`say_error`].
pub fn say(line: impl std::fmt::Display) {
    crate::term::note(&line.to_string());
}

/// Writes one error line on stderr (in red when colours are on; with `--json` as `{"log": ...}`), also with
/// `-q`: for errors besides the one the command ends with, and what must be known though no stop was
/// confirmed.
pub fn say_error(line: impl std::fmt::Display) {
    crate::term::error_note(&line.to_string());
}

/// SIGINT's number, the cause assumed when a cancellation has no recorded cause.
const SIGINT: i32 = 2;

/// Why a command was asked to stop before its action ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StopCause {
    /// A signal: SIGINT (Ctrl-C), SIGTERM (`kill`), SIGHUP (the terminal or SSH session went away) or
    /// SIGQUIT (Ctrl-\\).
    Signal(i32),
    /// stdout was closed by its reader.
    OutputClosed,
}

impl StopCause {
    /// 128 + the signal's number; 0 for a closed stdout (`motionlink ... watch | head` ends quietly, as
    /// `seq 1000000 | head` does, once what the command started was stopped).
    pub fn exit_code(self) -> u8 {
        match self {
            StopCause::Signal(n) => u8::try_from(128 + n).unwrap_or(u8::MAX),
            StopCause::OutputClosed => 0,
        }
    }

    /// The cause as a user reads it: "SIGTERM", "stdout closed".
    pub fn name(self) -> String {
        match self {
            StopCause::Signal(n) => signal_name(n),
            StopCause::OutputClosed => "stdout closed".into(),
        }
    }
}

fn signal_name(n: i32) -> String {
    match n {
        1 => "SIGHUP".into(),
        2 => "SIGINT".into(),
        3 => "SIGQUIT".into(),
        13 => "SIGPIPE".into(),
        15 => "SIGTERM".into(),
        n => format!("signal {n}"),
    }
}

static STOP_CAUSE: OnceLock<Mutex<Option<StopCause>>> = OnceLock::new();

/// The first reason the command was asked to stop, if any.
pub fn stop_cause() -> Option<StopCause> {
    *STOP_CAUSE.get_or_init(|| Mutex::new(None)).lock().unwrap_or_else(|e| e.into_inner())
}

/// Records why the command stops; the first cause wins.
fn record_stop_cause(cause: StopCause) {
    let mut slot = STOP_CAUSE.get_or_init(|| Mutex::new(None)).lock().unwrap_or_else(|e| e.into_inner());
    slot.get_or_insert(cause);
}

/// The token that SIGINT, SIGTERM, SIGHUP, SIGQUIT and a closed stdout cancel; the handlers are installed
/// by the first call, which every command that may start a motion makes before it opens the port.
///
/// The first signal cancels the token (the running action stops its motion and returns; the command then
/// exits with 128 + the signal's number); a second one only says that the stop is under way (stopping the
/// motion matters more than a quick exit); a third exits at once, without waiting for the stop. A closed
/// stdout (its reader went away: `motionlink ... | head`) cancels the token as well.
pub fn interrupt_token() -> CancelToken {
    static TOKEN: OnceLock<CancelToken> = OnceLock::new();
    TOKEN
        .get_or_init(|| {
            let token = CancelToken::new();
            install_signal_handlers(token.clone());
            #[cfg(unix)]
            watch_stdout(token.clone());
            token
        })
        .clone()
}

fn on_signal(token: &CancelToken, presses: &mut u32, n: i32) {
    record_stop_cause(StopCause::Signal(n));
    *presses += 1;
    let name = signal_name(n);
    match *presses {
        1 => match crate::portlock::stop_request() {
            Some(r) => say(format!(
                "motionlink: {name} from `motionlink {}` (pid {}), stopping what this command started",
                r.command, r.pid
            )),
            None => say(format!("motionlink: {name} received, stopping what this command started")),
        },
        2 => say(format!("motionlink: {name}: still stopping the motion; once more exits without waiting")),
        _ => {
            say_error(format!("motionlink: {name} again, exiting before the stop was confirmed"));
            std::process::exit(i32::from(StopCause::Signal(n).exit_code()));
        }
    }
    token.cancel();
}

#[cfg(unix)]
fn install_signal_handlers(token: CancelToken) {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGQUIT, SIGTERM};
    match signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP, SIGQUIT]) {
        Ok(mut signals) => {
            let spawned = std::thread::Builder::new().name("signals".into()).spawn(move || {
                let mut presses = 0;
                for n in signals.forever() {
                    on_signal(&token, &mut presses, n);
                }
            });
            if let Err(e) = spawned {
                tracing::warn!("cannot start the signal thread: {e}");
            }
        }
        Err(e) => tracing::warn!("cannot install the signal handlers: {e}"),
    }
}

#[cfg(not(unix))]
fn install_signal_handlers(token: CancelToken) {
    use std::sync::atomic::{AtomicBool, Ordering};
    let raised = Arc::new(AtomicBool::new(false));
    for n in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        if let Err(e) = signal_hook::flag::register(n, Arc::clone(&raised)) {
            tracing::warn!("cannot install the handler of signal {n}: {e}");
        }
    }
    let _ = std::thread::Builder::new().name("signals".into()).spawn(move || {
        let mut presses = 0;
        loop {
            std::thread::sleep(std::time::Duration::from_millis(20));
            if raised.swap(false, Ordering::SeqCst) {
                on_signal(&token, &mut presses, SIGINT);
            }
        }
    });
}

/// When stdout is a pipe or a socket, a thread waits (in `poll`, without a timeout) for its reader to go
/// away, and then cancels `token`: a move whose output nobody reads any more is stopped like one
/// interrupted by a signal. A terminal that goes away sends SIGHUP instead; a file never closes.
#[cfg(unix)]
fn watch_stdout(token: CancelToken) {
    // SAFETY: fstat on descriptor 1 writes only into the zeroed struct we own.
    let kind = unsafe {
        let mut st: libc::stat = std::mem::zeroed();
        if libc::fstat(1, &mut st) != 0 {
            return;
        }
        st.st_mode & libc::S_IFMT
    };
    if kind != libc::S_IFIFO && kind != libc::S_IFSOCK {
        return;
    }
    let _ = std::thread::Builder::new().name("stdout-watch".into()).spawn(move || loop {
        let mut fd = libc::pollfd { fd: 1, events: 0, revents: 0 };
        // SAFETY: one valid pollfd; POLLERR and POLLHUP are reported whatever `events` asks for.
        let n = unsafe { libc::poll(&mut fd, 1, -1) };
        if n < 0 {
            if std::io::Error::last_os_error().kind() == std::io::ErrorKind::Interrupted {
                continue;
            }
            return;
        }
        if fd.revents & (libc::POLLERR | libc::POLLHUP | libc::POLLNVAL) != 0 {
            record_stop_cause(StopCause::OutputClosed);
            token.cancel();
            return;
        }
    });
}

/// One row of a human-readable table: a name and a value.
pub type Row = (String, String);

/// Prints `rows` as an aligned two-column table.
pub fn print_table(out: &mut dyn Write, rows: &[Row]) -> Result<(), CliError> {
    let width = rows.iter().map(|(k, _)| k.chars().count()).max().unwrap_or(0);
    for (k, v) in rows {
        writeln!(out, "{k:<width$}  {v}")?;
    }
    Ok(())
}

/// Prints `value` as JSON on one line (keys in alphabetical order, as every JSON line of the command line).
pub fn print_json<T: serde::Serialize + ?Sized>(out: &mut dyn Write, value: &T) -> Result<(), CliError> {
    writeln!(out, "{}", to_json(value))?;
    Ok(())
}

/// `value` under a name known only at run time (`"module": 3`, `{"log": "..."}`); flattened into the object
/// that holds it, or an object of its own.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Keyed<T>(pub &'static str, pub T);

impl<T: serde::Serialize> serde::Serialize for Keyed<T> {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        let mut map = s.serialize_map(Some(1))?;
        map.serialize_entry(self.0, &self.1)?;
        map.end()
    }
}

/// The device profile the command's session took (`<path>#<key>`), once it looked for one.
static PROFILE: OnceLock<Option<String>> = OnceLock::new();

/// Records the device profile the command's session took (`None`: none): every JSON object of the command
/// names it from now on (`"profile"`).
pub fn set_profile(reference: Option<String>) {
    let _ = PROFILE.set(reference);
}

/// A result (a library report, which serialises with the names `--json` shows) as a JSON value.
pub fn to_json<T: serde::Serialize + ?Sized>(result: &T) -> serde_json::Value {
    // A report of plain fields always serialises; a failure would be a library defect, shown, not hidden.
    serde_json::to_value(result).unwrap_or_else(|e| serde_json::Value::String(format!("(not serialisable: {e})")))
}

/// Prints a family command's result as one JSON object: `family`, `port` and `profile` first
/// , then `identity` (the unit the command names: `module`, `drive`), then the result's own
/// fields, as it serialises.
pub fn print_result<T: serde::Serialize + ?Sized>(
    out: &mut dyn Write,
    family: &str,
    port: &str,
    identity: &[(&str, serde_json::Value)],
    result: &T,
) -> Result<(), CliError> {
    // Once the session looked for a device profile, `profile` comes first (null: none taken).
    let profile = PROFILE.get().map(|p| ("profile", serde_json::Value::from(p.clone())));
    let keys: Vec<(&str, serde_json::Value)> = profile.into_iter().chain(identity.iter().cloned()).collect();
    // A report of plain fields always serialises; a failure would be a library defect, shown, not hidden.
    let shown = motionlink_link::result::identified(family, port, &keys, result)
        .unwrap_or_else(|e| serde_json::Value::String(format!("(not serialisable: {e})")));
    print_json(out, &shown)
}

/// How a family command prints its results: with `--json` each as the library's report serialises (the
/// identity keys first: [`print_result`]), else as text made from the same report.
#[derive(Debug, Clone, Copy)]
pub struct Out<'a> {
    /// `--json`.
    pub json: bool,
    /// "scu", "powercube" or "compax".
    pub family: &'static str,
    /// The port, as given or resolved.
    pub port: &'a str,
    /// The unit the command names (`("module", 3)`, `("drive", 1)`), where it names one.
    pub unit: Option<(&'static str, u8)>,
}

impl Out<'_> {
    /// Prints `result` as one JSON object: `family`, `port`, `profile`, the unit, then its own fields.
    pub fn print(&self, out: &mut dyn Write, result: impl serde::Serialize) -> Result<(), CliError> {
        let identity: Vec<(&str, serde_json::Value)> = self.unit.iter().map(|&(k, n)| (k, n.into())).collect();
        print_result(out, self.family, self.port, &identity, &result)
    }

    /// `result` as JSON (`--json`), else as `text` writes it.
    pub fn show<R: serde::Serialize>(
        &self,
        out: &mut dyn Write,
        result: &R,
        text: impl FnOnce(&mut dyn Write, &R) -> Result<(), CliError>,
    ) -> Result<(), CliError> {
        match self.json {
            true => self.print(out, result),
            false => text(out, result),
        }
    }

    /// `stop`: in text, first what the motionlink that held the port said when it was stopped, if one was.
    pub fn holder(&self, out: &mut dyn Write, stopped: Option<&motionlink_link::portlock::Stopped>) -> Result<(), CliError> {
        if let (Some(h), false) = (stopped, self.json) {
            writeln!(out, "{}", h.describe())?;
        }
        Ok(())
    }
}

/// What a motion could not verify, one line of text (nothing when it verified everything).
pub fn not_verified(out: &mut dyn Write, why: &[String]) -> Result<(), CliError> {
    if !why.is_empty() {
        writeln!(out, "not verified: {}", why.join("; "))?;
    }
    Ok(())
}

/// `number` followed by `unit` (no unit: the number alone).
pub fn with_unit(number: impl std::fmt::Display, unit: &str) -> String {
    if unit.is_empty() {
        number.to_string()
    } else {
        format!("{number} {unit}")
    }
}

/// How `watch` prints its samples: `--csv`, `--json` or text.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WatchFormat {
    /// One line of text per sample.
    Text,
    /// One JSON object per sample.
    Json,
    /// A CSV header, then lines of values.
    Csv,
}

impl WatchFormat {
    /// The format `--csv` and `--json` ask for (not both).
    pub fn of(csv: bool, json: bool) -> Result<WatchFormat, CliError> {
        match (csv, json) {
            (true, true) => Err(CliError::usage("--csv and --json: give one of them")),
            (true, false) => Ok(WatchFormat::Csv),
            (false, true) => Ok(WatchFormat::Json),
            (false, false) => Ok(WatchFormat::Text),
        }
    }
}

/// One line of CSV: fields separated by commas, quoted when they hold a comma, a quote or a line break.
pub fn csv_line(fields: &[String]) -> String {
    let quoted: Vec<String> = fields
        .iter()
        .map(|f| if f.contains([',', '"', '\n', '\r']) { format!("\"{}\"", f.replace('"', "\"\"")) } else { f.clone() })
        .collect();
    quoted.join(",")
}

pub use crate::term::progress_bar;

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
    /// `--json`: the listening line as a JSON object (set by `main`).
    #[arg(skip)]
    pub json: bool,
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
    let device = Arc::new(Mutex::new(device));
    let clock = RealClock::shared();
    let mut options = ServeOptions::default();
    if args.events {
        let json = args.json;
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
    let line = if args.json {
        #[derive(serde::Serialize)]
        struct Listening<'a> {
            kind: &'static str,
            listening: &'a str,
        }
        let kind = if args.target.tcp.is_some() { "tcp" } else { "pty" };
        to_json(&Listening { kind, listening: server.address() }).to_string()
    } else if args.target.tcp.is_some() {
        format!("listening on {}", server.address())
    } else {
        format!("listening on pty {}", server.address())
    };
    let mut stdout = std::io::stdout().lock();
    writeln!(stdout, "{line}")?;
    stdout.flush()?;
    drop(stdout);
    server.wait();
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csv_quotes_only_what_needs_it() {
        let line = csv_line(&["1.5".into(), "a,b".into(), "say \"hi\"".into(), String::new()]);
        assert_eq!(line, "1.5,\"a,b\",\"say \"\"hi\"\"\",");
    }

    #[test]
    fn errors_carry_their_class_into_json() {
        let e = classified(&LinkError::Disconnected { port: "p".into(), reason: "reset".into() });
        assert_eq!((e.kind(), e.exit_code()), ("disconnected", 3));
        let j = CliError::usage("bad --speed").to_json();
        assert_eq!(j.to_string(), r#"{"exit_code":2,"kind":"usage","message":"bad --speed"}"#);
        assert_eq!(CliError::Refused("PE".into()).kind(), "refused");
    }
}
