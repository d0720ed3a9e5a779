//! What every family's commands share: errors with exit codes (here), Ctrl-C and the other signals
//! ([`signals`]), output as a table or JSON ([`output`]), emulator servers ([`serve`](mod@serve)).

use motionlink_link::emulator::FirmwareVariant;
use motionlink_link::error::{Classify, ErrorClass, ErrorReport, TransportKind};
use motionlink_link::LinkError;

mod output;
mod serve;
mod signals;

pub use output::*;
pub use serve::{config_text, serve, serve_behind, ServeArgs};
pub use signals::{interrupt_token, stop_cause, StopCause};
use signals::{record_stop_cause, SIGINT};

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
    /// 128 + the signal's number: 130 for SIGINT, 143 SIGTERM, 129 SIGHUP, 131 SIGQUIT, 148 SIGTSTP; 0 for a closed stdout).
    #[error("{0}")]
    Interrupted(String),
    /// stdout was closed by its reader (`motionlink ... watch | head`): the command ends quietly with exit
    /// code 0 after stopping anything it started.
    #[error("stdout was closed")]
    OutputClosed,
    /// A library error with what the device reported (an SCU's Error_Code, a PowerCube module's state word,
    /// a COMPAX drive's `Exx`), or one that says a stop was not confirmed: of its class, and `--json` gives
    /// the code and its bits ([`ErrorReport::device`]) and `"stop_unconfirmed": true`.
    #[error("{}", .1.message)]
    Reported(ErrorClass, ErrorReport),
}

impl CliError {
    /// The process exit code for this error: the class's ([`ErrorClass::exit_code`]: 1 refused or device, 2
    /// usage, 3 transport), except that an interruption exits with 128 + the signal's number and a closed
    /// stdout with 0.
    pub fn exit_code(&self) -> u8 {
        match self {
            CliError::Interrupted(_) | CliError::Reported(ErrorClass::Cancelled, _) => {
                stop_cause().unwrap_or(StopCause::Signal(SIGINT)).exit_code()
            }
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
            CliError::Reported(class, _) => *class,
        }
    }

    /// The class's name, as `--json` reports it: `refused`, `device`, `timeout`, `disconnected`, `corrupt`,
    /// `io`, `usage` or `cancelled` ([`ErrorClass::name`]).
    pub fn kind(&self) -> &'static str {
        self.class().name()
    }

    /// The error as `--json` prints it on stderr: its [`ErrorReport`] (`{"exit_code", "kind", "message"}`, and
    /// `code` and `bits` where the device reported them).
    pub fn to_json(&self) -> serde_json::Value {
        let device = match self {
            CliError::Reported(_, r) => r.device.clone(),
            _ => None,
        };
        let report = ErrorReport::new(self.kind(), self.to_string(), self.exit_code());
        to_json(&ErrorReport { device, stop_unconfirmed: self.stop_unconfirmed(), ..report })
    }

    /// True when the error says that a stop was not confirmed by the device (the library's
    /// [`Classify::stop_unconfirmed`]): what was set in motion may still be moving.
    pub fn stop_unconfirmed(&self) -> bool {
        matches!(self, CliError::Reported(_, r) if r.stop_unconfirmed)
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
            CliError::Reported(c, r) => {
                let message = f(r.message);
                CliError::Reported(c, ErrorReport { message, ..r })
            }
        }
    }

    /// This error, followed by a stop the device did not confirm (the end of the session tried it again,
    /// in vain): what was set in motion may still be moving, so it is of a transport class (its kind kept,
    /// else a timeout: exit code 3, whatever the first error was) and `--json` says `"stop_unconfirmed":
    /// true`. The message is kept (it says what the stop did).
    pub fn stop_not_confirmed(self) -> CliError {
        let class = self.class().stop_unconfirmed();
        let (message, device) = match self {
            CliError::Reported(_, r) => (r.message, r.device),
            e => (e.to_string(), None),
        };
        CliError::Reported(
            class,
            ErrorReport { stop_unconfirmed: true, device, ..ErrorReport::classed(class, message) },
        )
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
    if e.reported().is_some() || e.stop_unconfirmed() {
        return CliError::Reported(e.class(), ErrorReport::of(e));
    }
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

/// Writes the error a command ends with on stderr: with `--json` one JSON object, the error's class name as
/// its kind (the one place that maps errors to JSON), else one line.
pub fn print_final_error(e: &CliError) {
    if crate::term::json() {
        crate::term::write_stderr(&format!("{}\n", e.to_json()));
    } else {
        crate::term::write_stderr(&crate::term::error_line(&format!("motionlink: {e}")));
    }
}

/// Writes one error line on stderr (in red when colours are on; with `--json` as `{"log": ...}`), also with
/// `-q`: for errors besides the one the command ends with, and what must be known though no stop was
/// confirmed.
pub fn say_error(line: impl std::fmt::Display) {
    crate::term::error_note(&line.to_string());
}

/// The parser of `--variant` and `--sim-variant`: a family's firmware variant by the family's rule
/// ([`FirmwareVariant::named`]), every name with its description in `--help` (and in shell completions).
pub fn variant_parser<V: FirmwareVariant + Send + Sync>() -> VariantParser<V> {
    VariantParser(std::marker::PhantomData)
}

/// `--sim-variant` of a family's commands and probe: with `--port sim`, firmware variants of the emulated
/// device, by [`variant_parser`] (the argument's id is `sim_variants`, the key of devices.toml).
#[derive(clap::Args, Debug, Clone)]
pub struct SimVariants<V: FirmwareVariant + Clone + Send + Sync + 'static> {
    /// With --port sim: the emulated device runs this firmware variant (as `motionlink sim FAMILY --variant`);
    /// repeat or comma-separate for several.
    #[arg(
        id = "sim_variants",
        long = "sim-variant",
        value_name = "NAME",
        value_delimiter = ',',
        value_parser = variant_parser::<V>(),
        global = true
    )]
    pub list: Vec<V>,
}

/// `--variant` of `motionlink sim FAMILY`: firmware variants of the emulated device, by [`variant_parser`].
#[derive(clap::Args, Debug, Clone)]
pub struct Variants<V: FirmwareVariant + Clone + Send + Sync + 'static> {
    /// A firmware variant: the emulated device does what the manual leaves open the other plausible way (see
    /// docs/assumptions.md). Repeat or comma-separate for several; added to the configuration's `variants`.
    #[arg(
        id = "variants",
        long = "variant",
        value_name = "NAME",
        value_delimiter = ',',
        value_parser = variant_parser::<V>()
    )]
    pub list: Vec<V>,
}

/// See [`variant_parser`].
#[derive(Clone)]
pub struct VariantParser<V>(std::marker::PhantomData<fn() -> V>);

impl<V: FirmwareVariant + Send + Sync> clap::builder::TypedValueParser for VariantParser<V> {
    type Value = V;

    fn parse_ref(
        &self,
        cmd: &clap::Command,
        arg: Option<&clap::Arg>,
        value: &std::ffi::OsStr,
    ) -> Result<V, clap::Error> {
        clap::builder::StringValueParser::new().try_map(|s| V::named(&s)).parse_ref(cmd, arg, value)
    }

    fn possible_values(&self) -> Option<Box<dyn Iterator<Item = clap::builder::PossibleValue> + '_>> {
        Some(Box::new(V::ALL.iter().map(|v| clap::builder::PossibleValue::new(v.name()).help(v.description()))))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn errors_carry_their_class_into_json() {
        let e = classified(&LinkError::Disconnected { port: "p".into(), reason: "reset".into() });
        assert_eq!((e.kind(), e.exit_code()), ("disconnected", 3));
        let j = CliError::usage("bad --speed").to_json();
        assert_eq!(j.to_string(), r#"{"exit_code":2,"kind":"usage","message":"bad --speed"}"#);
        assert_eq!(CliError::Refused("PE".into()).kind(), "refused");
    }
}
