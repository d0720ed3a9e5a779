//! What every family's commands share: errors with exit codes, output as a table or JSON, Ctrl-C, progress
//! bars, emulator servers, and reading captures.

use std::io::{IsTerminal, Read, Write};
use std::sync::{Arc, Mutex, OnceLock};
use std::time::Duration;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use motionlink_link::cancel::CancelToken;
use motionlink_link::emulator::{serve_tcp, Emulator};
use motionlink_link::{LinkError, RealClock};

/// An error of the command line, classed by what went wrong.
#[derive(Debug, thiserror::Error)]
pub enum CliError {
    /// The device refused a command or reported an error (exit code 1).
    #[error("{0}")]
    Device(String),
    /// The command line itself is wrong (exit code 2).
    #[error("{0}")]
    Usage(String),
    /// The port, the line or the timing failed (exit code 3).
    #[error("{0}")]
    Transport(String),
    /// The user pressed Ctrl-C; what was running was stopped (exit code 130, as for SIGINT).
    #[error("{0}")]
    Interrupted(String),
}

impl CliError {
    /// The process exit code for this error.
    pub fn exit_code(&self) -> u8 {
        match self {
            CliError::Device(_) => 1,
            CliError::Usage(_) => 2,
            CliError::Transport(_) => 3,
            CliError::Interrupted(_) => 130,
        }
    }

    /// A usage error.
    pub fn usage(msg: impl std::fmt::Display) -> Self {
        CliError::Usage(msg.to_string())
    }

    /// A transport error.
    pub fn transport(msg: impl std::fmt::Display) -> Self {
        CliError::Transport(msg.to_string())
    }

    /// A device error.
    pub fn device(msg: impl std::fmt::Display) -> Self {
        CliError::Device(msg.to_string())
    }
}

impl From<LinkError> for CliError {
    fn from(e: LinkError) -> Self {
        match e {
            LinkError::InvalidPort { .. } => CliError::Usage(e.to_string()),
            _ => CliError::Transport(e.to_string()),
        }
    }
}

impl From<std::io::Error> for CliError {
    fn from(e: std::io::Error) -> Self {
        CliError::Transport(e.to_string())
    }
}

/// Sets up logging to stderr: warnings by default, more with each `-v`, or as `RUST_LOG` says.
pub fn init_logging(verbose: u8) {
    let default = match verbose {
        0 => "warn",
        1 => "info",
        2 => "debug",
        _ => "trace",
    };
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new(default));
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_ansi(std::io::stderr().is_terminal())
        .try_init();
}

/// The token Ctrl-C cancels. The first Ctrl-C cancels it (the running action stops its motion and returns);
/// a second one only says that the stop is under way (stopping the motion matters more than a quick exit);
/// a third exits at once, without waiting for the stop.
pub fn interrupt_token() -> CancelToken {
    static TOKEN: OnceLock<CancelToken> = OnceLock::new();
    static PRESSES: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);
    TOKEN
        .get_or_init(|| {
            let token = CancelToken::new();
            let handler_token = token.clone();
            if let Err(e) = ctrlc::set_handler(move || {
                match PRESSES.fetch_add(1, std::sync::atomic::Ordering::SeqCst) {
                    0 => eprintln!("motionlink: interrupted, stopping"),
                    1 => eprintln!("motionlink: still stopping the motion; Ctrl-C once more exits without waiting"),
                    _ => {
                        eprintln!("motionlink: interrupted again, exiting before the stop was confirmed");
                        std::process::exit(130);
                    }
                }
                handler_token.cancel();
            }) {
                tracing::warn!("cannot install the Ctrl-C handler: {e}");
            }
            token
        })
        .clone()
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

/// Prints a JSON value on one line.
pub fn print_json(out: &mut dyn Write, value: &serde_json::Value) -> Result<(), CliError> {
    writeln!(out, "{value}")?;
    Ok(())
}

/// A progress bar on stderr, drawn only when stderr is a terminal.
pub fn progress_bar(length: u64, message: impl Into<String>) -> ProgressBar {
    let target =
        if std::io::stderr().is_terminal() { ProgressDrawTarget::stderr() } else { ProgressDrawTarget::hidden() };
    let bar = ProgressBar::with_draw_target(Some(length), target);
    bar.set_style(
        ProgressStyle::with_template("{msg} [{bar:40}] {pos}/{len} {elapsed}")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    bar.set_message(message.into());
    bar.enable_steady_tick(Duration::from_millis(200));
    bar
}

/// Where `motionlink sim` serves.
#[derive(clap::Args, Debug, Clone)]
#[group(required = true, multiple = false)]
pub struct ServeArgs {
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
    let server = if let Some(addr) = &args.tcp {
        serve_tcp(addr, device, clock).map_err(|e| CliError::transport(format!("cannot listen on {addr}: {e}")))?
    } else {
        #[cfg(unix)]
        {
            motionlink_link::emulator::serve_pty(device, clock)
                .map_err(|e| CliError::transport(format!("cannot create a pseudo-terminal: {e}")))?
        }
        #[cfg(not(unix))]
        {
            return Err(CliError::usage("--pty needs a Unix system"));
        }
    };
    let line = if args.tcp.is_some() {
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

/// Input of `motionlink decode`.
#[derive(clap::Args, Debug, Clone)]
pub struct CaptureArgs {
    /// Bytes as hex (such as "52 47 11 00 a3 0e" or "524711"); read from stdin if none are given.
    #[arg(value_name = "HEX")]
    pub hex: Vec<String>,
    /// stdin holds the raw bytes of a capture, not hex text.
    #[arg(long)]
    pub raw: bool,
}

/// Reads the bytes of a capture: hex from the arguments, or hex or raw bytes from stdin.
pub fn read_capture(args: &CaptureArgs) -> Result<Vec<u8>, CliError> {
    if !args.hex.is_empty() {
        return parse_hex(&args.hex.join(" "));
    }
    let mut input = Vec::new();
    std::io::stdin().read_to_end(&mut input)?;
    if args.raw {
        return Ok(input);
    }
    let text =
        String::from_utf8(input).map_err(|_| CliError::usage("stdin is not hex text (use --raw for raw bytes)"))?;
    parse_hex(&text)
}

/// Parses hex text: pairs of digits, optionally separated by whitespace, ',', ':' or '-', each optionally
/// prefixed with 0x. Lines starting with '#' are comments.
pub fn parse_hex(text: &str) -> Result<Vec<u8>, CliError> {
    let mut bytes = Vec::new();
    for (line_no, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.starts_with('#') {
            continue;
        }
        for token in line.split(|c: char| c.is_whitespace() || matches!(c, ',' | ':' | '-')).filter(|t| !t.is_empty()) {
            let digits = token.strip_prefix("0x").or_else(|| token.strip_prefix("0X")).unwrap_or(token);
            if digits.len() % 2 != 0 || !digits.chars().all(|c| c.is_ascii_hexdigit()) {
                return Err(CliError::usage(format!(
                    "line {}: {token:?} is not hex bytes (expected pairs of hex digits such as 52 47 or 5247)",
                    line_no + 1
                )));
            }
            for i in (0..digits.len()).step_by(2) {
                bytes.push(u8::from_str_radix(&digits[i..i + 2], 16).map_err(|e| CliError::usage(e.to_string()))?);
            }
        }
    }
    Ok(bytes)
}

/// Formats bytes as spaced upper-case hex.
pub fn hex(bytes: &[u8]) -> String {
    let mut s = String::with_capacity(bytes.len() * 3);
    for (i, b) in bytes.iter().enumerate() {
        if i > 0 {
            s.push(' ');
        }
        s.push_str(&format!("{b:02X}"));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hex_accepts_common_spellings() {
        assert_eq!(
            parse_hex("52 47 0x11,00:A3-0e\n# comment\n5247").unwrap(),
            vec![0x52, 0x47, 0x11, 0, 0xA3, 0x0E, 0x52, 0x47]
        );
    }

    #[test]
    fn hex_rejects_odd_digits_and_non_hex() {
        assert!(matches!(parse_hex("524"), Err(CliError::Usage(_))));
        assert!(matches!(parse_hex("zz"), Err(CliError::Usage(_))));
    }

    #[test]
    fn hex_formats_spaced_upper_case() {
        assert_eq!(hex(&[0x52, 0x0a]), "52 0A");
    }
}
