//! The one place where a family's error becomes a Python exception: its class
//! ([`ErrorClass`](motionlink_link::error::ErrorClass)) picks the exception class of `motionlink.errors`,
//! and the family adds what the device said (a code and its named bits).

use motionlink_link::error::{Classify, ErrorClass, TransportKind};
use motionlink_link::flags::{Flag, FlagWord};
use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{PyDict, PyList, PyModule};

/// One named bit of a device's error code or state word.
pub struct Bit {
    /// The bit's number as the manual counts (SCU: 1..32; PowerCube: 0..31).
    pub bit: u32,
    /// The manual's name.
    pub name: String,
    /// What it means.
    pub cause: String,
}

/// A failure on its way to Python: its class, its message, and what the device reported.
pub struct Failure {
    /// The class (decides the exception class and the exit code).
    pub class: ErrorClass,
    /// The library's message.
    pub message: String,
    /// "scu", "powercube", "compax", or "" for the bindings themselves.
    pub family: &'static str,
    /// The device's error code or state word, where it reported one.
    pub code: Option<u64>,
    /// The named bits of `code`.
    pub bits: Vec<Bit>,
}

impl Failure {
    /// A failure of `class` with `message` and nothing from a device.
    pub fn new(class: ErrorClass, family: &'static str, message: impl Into<String>) -> Self {
        Failure { class, message: message.into(), family, code: None, bits: Vec::new() }
    }

    /// A usage error (a bad argument), found before anything was sent.
    pub fn usage(family: &'static str, message: impl Into<String>) -> Self {
        Failure::new(ErrorClass::Usage, family, message)
    }

    /// `e` classified, with no device details.
    pub fn of<E: Classify + std::fmt::Display>(family: &'static str, e: &E) -> Self {
        Failure::new(e.class(), family, e.to_string())
    }

    /// The set flags of `word` as bits (numbered from 0, as the PowerCube manual does).
    pub fn with_word<W: FlagWord>(mut self, word: W) -> Self {
        self.code = Some(word.raw());
        self.bits = word
            .set_flags()
            .into_iter()
            .map(|f| Bit { bit: f.mask_u64().trailing_zeros(), name: f.name().to_string(), cause: f.meaning().into() })
            .collect();
        self
    }
}

/// The Python exception class name of each error class.
fn class_name(class: ErrorClass) -> &'static str {
    match class {
        ErrorClass::Refused => "DeviceRefused",
        ErrorClass::Device => "DeviceError",
        ErrorClass::Transport(TransportKind::Timeout) => "TimeoutError",
        ErrorClass::Transport(TransportKind::Disconnected) => "Disconnected",
        ErrorClass::Transport(TransportKind::Corrupt) => "CorruptFrame",
        ErrorClass::Transport(TransportKind::Io) => "TransportError",
        ErrorClass::Usage => "UsageError",
        ErrorClass::Cancelled => "Cancelled",
    }
}

static ERRORS: PyOnceLock<Py<PyModule>> = PyOnceLock::new();

fn errors_module(py: Python<'_>) -> PyResult<&Bound<'_, PyModule>> {
    ERRORS.get_or_try_init(py, || PyModule::import(py, "motionlink.errors").map(Bound::unbind)).map(|m| m.bind(py))
}

/// The Python exception for `failure`: an instance of the class its [`ErrorClass`] names, with the
/// attributes `kind`, `message`, `exit_code`, `family`, `code` and `bits`.
pub fn to_pyerr(py: Python<'_>, failure: Failure) -> PyErr {
    match build(py, &failure) {
        Ok(e) => e,
        Err(e) => PyRuntimeError::new_err(format!("{} (and the exception could not be made: {e})", failure.message)),
    }
}

fn build(py: Python<'_>, f: &Failure) -> PyResult<PyErr> {
    let class = errors_module(py)?.getattr(class_name(f.class))?;
    let bits = PyList::empty(py);
    for b in &f.bits {
        let d = PyDict::new(py);
        d.set_item("bit", b.bit)?;
        d.set_item("name", &b.name)?;
        d.set_item("cause", &b.cause)?;
        bits.append(d)?;
    }
    let kwargs = PyDict::new(py);
    kwargs.set_item("kind", f.class.name())?;
    kwargs.set_item("exit_code", f.class.exit_code())?;
    kwargs.set_item("family", f.family)?;
    kwargs.set_item("code", f.code)?;
    kwargs.set_item("bits", bits)?;
    let value = class.call((f.message.as_str(),), Some(&kwargs))?;
    Ok(PyErr::from_value(value))
}

/// Converts a family's error into a Python exception (each family implements it in its module).
pub trait IntoFailure {
    /// The failure, with the device's code and bits where it reported them.
    fn failure(&self) -> Failure;
}

/// `Result<T, E>` of a family into `PyResult<T>`.
pub trait OrRaise<T> {
    /// The value, or the family error as its Python exception.
    fn or_raise(self, py: Python<'_>) -> PyResult<T>;
}

impl<T, E: IntoFailure> OrRaise<T> for Result<T, E> {
    fn or_raise(self, py: Python<'_>) -> PyResult<T> {
        self.map_err(|e| to_pyerr(py, e.failure()))
    }
}

impl IntoFailure for Failure {
    fn failure(&self) -> Failure {
        Failure {
            class: self.class,
            message: self.message.clone(),
            family: self.family,
            code: self.code,
            bits: self.bits.iter().map(|b| Bit { bit: b.bit, name: b.name.clone(), cause: b.cause.clone() }).collect(),
        }
    }
}

impl IntoFailure for motionlink_scu::Error {
    fn failure(&self) -> Failure {
        use motionlink_scu::Error as E;
        let mut f = Failure::of("scu", self);
        let code = match self {
            E::MotionEnded { error_code, .. } => Some(*error_code),
            E::StopUnconfirmed { cause, .. } | E::CloseUnconfirmed { cause, .. } => {
                let inner = cause.failure();
                f.code = inner.code;
                f.bits = inner.bits;
                None
            }
            _ => None,
        };
        if let Some(code) = code {
            f.code = Some(u64::from(code.0));
            f.bits = code
                .bits()
                .map(|b| Bit { bit: u32::from(b.number()), name: b.name().to_string(), cause: b.cause().to_string() })
                .collect();
        }
        f
    }
}

impl IntoFailure for motionlink_powercube::Error {
    fn failure(&self) -> Failure {
        use motionlink_powercube::Error as E;
        let f = Failure::of("powercube", self);
        match self {
            E::Device { state, .. }
            | E::Halted { state, .. }
            | E::MoveTimeout { state, .. }
            | E::NotReached { state, .. }
            | E::WatchdogExpired { state, .. } => f.with_word(*state),
            E::Context { source, .. } | E::FailedDuringMotion { cause: source, .. } => {
                let inner = source.failure();
                Failure { code: inner.code, bits: inner.bits, ..f }
            }
            E::Also { error, .. } => {
                let inner = error.failure();
                Failure { code: inner.code, bits: inner.bits, ..f }
            }
            _ => f,
        }
    }
}

impl IntoFailure for motionlink_compax::Error {
    fn failure(&self) -> Failure {
        let mut f = Failure::of("compax", self);
        // An `Exx` answer is a number, not a word of bits: `code` carries it, the message its meaning.
        f.code = self.device_code().map(|c| u64::from(c.0));
        f
    }
}

impl IntoFailure for motionlink_link::LinkError {
    fn failure(&self) -> Failure {
        Failure::of("", self)
    }
}
