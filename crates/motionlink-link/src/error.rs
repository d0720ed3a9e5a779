//! One classification of errors for every family: what went wrong, in terms a caller (and the command
//! line's exit codes, and Python's exception classes) can act on.
//!
//! Each family keeps its own `Error` type with the device's own codes and named bits; every such type
//! implements [`Classify`], so that a front end maps classes, not families.
//!
//! ```
//! use motionlink_link::error::{Classify, ErrorClass, TransportKind};
//! use motionlink_link::LinkError;
//! let e = LinkError::Disconnected { port: "tcp://127.0.0.1:9".into(), reason: "reset".into() };
//! assert_eq!(e.class(), ErrorClass::Transport(TransportKind::Disconnected));
//! assert_eq!(e.class().exit_code(), 3);
//! ```

use std::fmt;

use crate::link::LinkError;

/// What kind of failure an error is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ErrorClass {
    /// The device answered and refused the request (it saw a bad checksum, the command is not allowed in
    /// its state, the data is out of its range).
    Refused,
    /// The device reports an error (an error code with named bits, an error state), or a motion did not end
    /// where it was asked to.
    Device,
    /// The link failed; the kind says how.
    Transport(TransportKind),
    /// The caller asked for something invalid; found before anything was sent.
    Usage,
    /// The caller cancelled (a signal, a dropped future); what had been started was stopped, as the device
    /// confirmed. A cancel whose stop the device did not confirm is of the class of what kept it from
    /// confirming (a timeout of the line): the axis may still be moving.
    Cancelled,
}

/// How a link failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum TransportKind {
    /// No (complete) answer within the time the protocol allows.
    Timeout,
    /// The port went away or the peer closed the connection; it cannot be used until reopened.
    Disconnected,
    /// Bytes arrived that are not a valid answer (checksum, framing, length, an answer to something else).
    Corrupt,
    /// The port could not be opened, or another I/O failure.
    Io,
}

impl ErrorClass {
    /// The command line's exit code for this class: 1 device refused or device error, 2 usage, 3 transport,
    /// 130 cancelled (the command line replaces it with 128 + the signal that cancelled).
    pub fn exit_code(self) -> u8 {
        match self {
            ErrorClass::Refused | ErrorClass::Device => 1,
            ErrorClass::Usage => 2,
            ErrorClass::Transport(_) => 3,
            ErrorClass::Cancelled => 130,
        }
    }

    /// A short snake_case name, for JSON output and logs: `refused`, `device`, `timeout`, `disconnected`,
    /// `corrupt`, `io`, `usage`, `cancelled`.
    pub fn name(self) -> &'static str {
        match self {
            ErrorClass::Refused => "refused",
            ErrorClass::Device => "device",
            ErrorClass::Transport(TransportKind::Timeout) => "timeout",
            ErrorClass::Transport(TransportKind::Disconnected) => "disconnected",
            ErrorClass::Transport(TransportKind::Corrupt) => "corrupt",
            ErrorClass::Transport(TransportKind::Io) => "io",
            ErrorClass::Usage => "usage",
            ErrorClass::Cancelled => "cancelled",
        }
    }

    /// The class of an error after which the device did not confirm a stop, whose first failure was of
    /// this class: a transport error of its kind, else a timeout. What was started may still move, so it is
    /// never a class that says the end was settled (`Cancelled`, `Device`...), in every family.
    ///
    /// ```
    /// use motionlink_link::error::{ErrorClass, TransportKind};
    /// assert_eq!(ErrorClass::Cancelled.stop_unconfirmed(), ErrorClass::Transport(TransportKind::Timeout));
    /// let lost = ErrorClass::Transport(TransportKind::Disconnected);
    /// assert_eq!(lost.stop_unconfirmed(), lost);
    /// ```
    pub fn stop_unconfirmed(self) -> ErrorClass {
        match self {
            c @ ErrorClass::Transport(_) => c,
            _ => ErrorClass::Transport(TransportKind::Timeout),
        }
    }

    /// True for every transport kind.
    pub fn is_transport(self) -> bool {
        matches!(self, ErrorClass::Transport(_))
    }
}

impl fmt::Display for ErrorClass {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// An error that knows its [`ErrorClass`].
pub trait Classify {
    /// The class of this error.
    fn class(&self) -> ErrorClass;

    /// What the device reported with it, where it reported something (an SCU's Error_Code, a PowerCube
    /// module's state word, a COMPAX drive's `Exx` number): the code and its named bits, as data for every
    /// front end ([`ErrorReport::device`]). None by default.
    fn reported(&self) -> Option<DeviceCode> {
        None
    }

    /// True when this error says that a stop was not confirmed by the device: what the session had set in
    /// motion may still be moving (its message says so, and what stops it then). False by default.
    fn stop_unconfirmed(&self) -> bool {
        false
    }
}

/// What a device reported with an error: the number it gave and the manual's names of the bits set in it
/// (none for a code that is a number, not a word of bits: a COMPAX `Exx`).
///
/// ```
/// use motionlink_link::error::{DeviceCode, ErrorBit};
/// let code = DeviceCode { code: 0x21, bits: vec![ErrorBit { bit: 0, name: "A".into(), cause: "the first".into() }] };
/// let json = serde_json::to_string(&code).unwrap();
/// assert_eq!(json, r#"{"code":33,"bits":[{"bit":0,"name":"A","cause":"the first"}]}"#);
/// ```
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct DeviceCode {
    /// The error code or state word.
    pub code: u64,
    /// The bits of `code` the manual names, set.
    pub bits: Vec<ErrorBit>,
}

/// One named bit of a device's error code or state word.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct ErrorBit {
    /// The bit's number as the manual counts (SCU: 1..32; PowerCube: 0..31).
    pub bit: u32,
    /// The manual's name.
    pub name: String,
    /// What it means.
    pub cause: String,
}

impl DeviceCode {
    /// A state word with its set flags as bits, numbered from 0 by their mask (as the PowerCube manual
    /// numbers them).
    pub fn of_word<W: crate::flags::FlagWord>(word: W) -> DeviceCode {
        use crate::flags::Flag;
        let bits = word
            .set_flags()
            .into_iter()
            .map(|f| ErrorBit {
                bit: f.mask_u64().trailing_zeros(),
                name: f.name().to_string(),
                cause: f.meaning().into(),
            })
            .collect();
        DeviceCode { code: word.raw(), bits }
    }
}

impl Classify for LinkError {
    fn class(&self) -> ErrorClass {
        match self {
            LinkError::Disconnected { .. } => ErrorClass::Transport(TransportKind::Disconnected),
            LinkError::Open { .. } | LinkError::Busy { .. } | LinkError::Io { .. } => {
                ErrorClass::Transport(TransportKind::Io)
            }
            LinkError::InvalidPort { .. } => ErrorClass::Usage,
        }
    }
}

/// An error as every front end reports it: the command line's `--json` (on stderr), the web console's and the
/// fleet gateway's replies, and Python's `MotionlinkError.to_dict()` have these fields: `kind`, `message`,
/// `exit_code`, `stop_unconfirmed: true` where a stop was not confirmed ([`Classify::stop_unconfirmed`]),
/// and `code` and `bits` where the device reported them ([`Classify::reported`]).
///
/// ```
/// use motionlink_link::error::{ErrorReport, TransportKind};
/// use motionlink_link::LinkError;
/// let e = LinkError::Disconnected { port: "/dev/ttyUSB0".into(), reason: "unplugged".into() };
/// let report = ErrorReport::of(&e);
/// assert_eq!((report.kind.as_ref(), report.exit_code), ("disconnected", 3));
/// let json = serde_json::to_string(&ErrorReport::usage("bad --speed")).unwrap();
/// assert_eq!(json, r#"{"kind":"usage","message":"bad --speed","exit_code":2}"#);
/// ```
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct ErrorReport {
    /// The error class's name ([`ErrorClass::name`]: `refused`, `device`, `timeout`, `disconnected`,
    /// `corrupt`, `io`, `usage`, `cancelled`), or a front end's own kind (the gateway's `busy`,
    /// `lease_expired` ...).
    pub kind: std::borrow::Cow<'static, str>,
    /// What went wrong, in words.
    pub message: String,
    /// The command line's exit code for it.
    pub exit_code: u8,
    /// True when the error says that a stop was not confirmed by the device: what was set in motion may
    /// still be moving ([`Classify::stop_unconfirmed`]). In the object only when true
    /// (`"stop_unconfirmed": true`).
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub stop_unconfirmed: bool,
    /// What the device reported with it (`code` and `bits`, flattened into the object), if anything.
    #[serde(flatten, skip_serializing_if = "Option::is_none")]
    pub device: Option<Box<DeviceCode>>,
}

impl ErrorReport {
    /// A report of `kind` with its exit code.
    pub fn new(kind: impl Into<std::borrow::Cow<'static, str>>, message: impl Into<String>, exit_code: u8) -> Self {
        ErrorReport { kind: kind.into(), message: message.into(), exit_code, stop_unconfirmed: false, device: None }
    }

    /// An error of `class`.
    pub fn classed(class: ErrorClass, message: impl Into<String>) -> Self {
        ErrorReport::new(class.name(), message, class.exit_code())
    }

    /// A library error, by its class, with what the device reported.
    pub fn of<E: Classify + fmt::Display + ?Sized>(e: &E) -> Self {
        ErrorReport {
            stop_unconfirmed: e.stop_unconfirmed(),
            device: e.reported().map(Box::new),
            ..ErrorReport::classed(e.class(), e.to_string())
        }
    }

    /// A request that cannot be carried out as it is (bad input: nothing was sent to the device).
    pub fn usage(message: impl fmt::Display) -> Self {
        ErrorReport::classed(ErrorClass::Usage, message.to_string())
    }
}

/// A classified library error as its report (`?` in a front end that answers with reports).
impl<E: Classify + fmt::Display> From<E> for ErrorReport {
    fn from(e: E) -> Self {
        ErrorReport::of(&e)
    }
}

/// The message, then the kind: `"no reply within 200 ms (timeout)"`.
impl fmt::Display for ErrorReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} ({})", self.message, self.kind)
    }
}

/// The round trips a session measured on its line (a request handed to the line to its answer), for errors
/// that a slow link may have caused: "replies on this link have taken 45-58 ms".
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RoundTripRange {
    /// The fastest answer.
    pub fastest: std::time::Duration,
    /// The slowest answer.
    pub slowest: std::time::Duration,
}

impl RoundTripRange {
    /// `measured` with one more round trip `d`.
    pub fn with(measured: Option<RoundTripRange>, d: std::time::Duration) -> RoundTripRange {
        match measured {
            Some(r) => RoundTripRange { fastest: r.fastest.min(d), slowest: r.slowest.max(d) },
            None => RoundTripRange { fastest: d, slowest: d },
        }
    }
}

impl fmt::Display for RoundTripRange {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (a, b) = (self.fastest.as_millis(), self.slowest.as_millis());
        if a == b {
            write!(f, "replies on this link have taken {a} ms")
        } else {
            write!(f, "replies on this link have taken {a}-{b} ms")
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A device's refusal with code 5 (bits 0 and 2 named).
    #[derive(Debug)]
    struct Refusal;

    impl fmt::Display for Refusal {
        fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
            f.write_str("refused with 5")
        }
    }

    impl Classify for Refusal {
        fn class(&self) -> ErrorClass {
            ErrorClass::Refused
        }

        fn reported(&self) -> Option<DeviceCode> {
            let bit = |bit, name: &str| ErrorBit { bit, name: name.into(), cause: format!("{name} set") };
            Some(DeviceCode { code: 5, bits: vec![bit(0, "A"), bit(2, "C")] })
        }
    }

    #[test]
    fn a_report_carries_what_the_device_reported_flattened_and_nothing_else_without() {
        let json = serde_json::to_value(ErrorReport::of(&Refusal)).unwrap();
        let bits =
            [("A", 0), ("C", 2)].map(|(n, b)| serde_json::json!({"bit": b, "name": n, "cause": format!("{n} set")}));
        let want = serde_json::json!({"kind": "refused", "message": "refused with 5", "exit_code": 1, "code": 5, "bits": bits});
        assert_eq!(json, want);
        let link = LinkError::Busy { port: "p".into() };
        let json = serde_json::to_value(ErrorReport::of(&link)).unwrap();
        assert_eq!(json.as_object().unwrap().keys().collect::<Vec<_>>(), ["exit_code", "kind", "message"]);
    }

    /// A stop the device did not confirm.
    #[derive(Debug)]
    struct Unconfirmed;

    impl fmt::Display for Unconfirmed {
        fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
            f.write_str("the stop was not confirmed: the axis may still be moving")
        }
    }

    impl Classify for Unconfirmed {
        fn class(&self) -> ErrorClass {
            ErrorClass::Cancelled.stop_unconfirmed()
        }

        fn stop_unconfirmed(&self) -> bool {
            true
        }
    }

    #[test]
    fn a_report_says_a_stop_was_not_confirmed_only_when_it_was_not() {
        let json = serde_json::to_value(ErrorReport::of(&Unconfirmed)).unwrap();
        let message = Unconfirmed.to_string();
        let want = serde_json::json!({"kind": "timeout", "message": message, "exit_code": 3, "stop_unconfirmed": true});
        assert_eq!(json, want);
        assert!(!ErrorReport::of(&Refusal).stop_unconfirmed);
    }

    #[test]
    fn every_class_has_its_exit_code_and_name() {
        let all = [
            (ErrorClass::Refused, 1, "refused"),
            (ErrorClass::Device, 1, "device"),
            (ErrorClass::Transport(TransportKind::Timeout), 3, "timeout"),
            (ErrorClass::Transport(TransportKind::Disconnected), 3, "disconnected"),
            (ErrorClass::Transport(TransportKind::Corrupt), 3, "corrupt"),
            (ErrorClass::Transport(TransportKind::Io), 3, "io"),
            (ErrorClass::Usage, 2, "usage"),
            (ErrorClass::Cancelled, 130, "cancelled"),
        ];
        for (class, code, name) in all {
            assert_eq!((class.exit_code(), class.name()), (code, name));
        }
    }

    #[test]
    fn link_errors_keep_their_kind() {
        let invalid = LinkError::InvalidPort { port: "x".into(), reason: "y".into() };
        assert_eq!(invalid.class(), ErrorClass::Usage);
        let io = LinkError::Io { port: "x".into(), source: std::sync::Arc::new(std::io::Error::other("z")) };
        assert_eq!(io.class(), ErrorClass::Transport(TransportKind::Io));
    }
}
