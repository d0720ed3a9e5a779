//! The one place where a family's error becomes a Python exception: its class
//! ([`ErrorClass`](motionlink_link::error::ErrorClass)) picks the exception class of `motionlink.errors`,
//! and its [`ErrorReport`] (what every front end reports: the kind, the message, the exit code, and the
//! code and bits the device reported) gives the exception's attributes.

use motionlink_link::error::{Classify, ErrorClass, ErrorReport, TransportKind};
use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{PyDict, PyList, PyModule};

/// A failure on its way to Python: its class, and its report.
pub struct Failure {
    /// The class (decides the exception class).
    pub class: ErrorClass,
    /// The report: kind, message, exit code, and what the device reported.
    pub report: ErrorReport,
    /// "scu", "powercube", "compax", or "" for the bindings themselves.
    pub family: &'static str,
}

impl Failure {
    /// A failure of `class` with `message` and nothing from a device.
    pub fn new(class: ErrorClass, family: &'static str, message: impl Into<String>) -> Self {
        Failure { class, report: ErrorReport::classed(class, message), family }
    }

    /// A usage error (a bad argument), found before anything was sent.
    pub fn usage(family: &'static str, message: impl Into<String>) -> Self {
        Failure::new(ErrorClass::Usage, family, message)
    }

    /// `e` classified, with what the device reported ([`ErrorReport::of`]).
    pub fn of<E: Classify + std::fmt::Display>(family: &'static str, e: &E) -> Self {
        Failure { class: e.class(), report: ErrorReport::of(e), family }
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
/// attributes `kind`, `message`, `exit_code`, `family`, `code`, `bits` and `stop_unconfirmed`.
pub fn to_pyerr(py: Python<'_>, failure: Failure) -> PyErr {
    match build(py, &failure) {
        Ok(e) => e,
        Err(e) => {
            PyRuntimeError::new_err(format!("{} (and the exception could not be made: {e})", failure.report.message))
        }
    }
}

fn build(py: Python<'_>, f: &Failure) -> PyResult<PyErr> {
    let class = errors_module(py)?.getattr(class_name(f.class))?;
    // The report as it serialises (kind, exit_code, stop_unconfirmed when true, and code and bits where the
    // device reported them),
    // the message aside: it is the exception's argument.
    let kwargs = PyDict::new(py);
    if let serde_json::Value::Object(fields) = crate::common::report_value(&f.report)? {
        for (key, value) in fields.iter().filter(|(k, _)| k.as_str() != "message") {
            kwargs.set_item(key, crate::common::json_py(py, value)?)?;
        }
    }
    if f.report.device.is_none() {
        kwargs.set_item("code", py.None())?;
        kwargs.set_item("bits", PyList::empty(py))?;
    }
    kwargs.set_item("family", f.family)?;
    let value = class.call((f.report.message.as_str(),), Some(&kwargs))?;
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
        Failure { class: self.class, report: self.report.clone(), family: self.family }
    }
}

impl IntoFailure for motionlink_scu::Error {
    fn failure(&self) -> Failure {
        Failure::of("scu", self)
    }
}

impl IntoFailure for motionlink_powercube::Error {
    fn failure(&self) -> Failure {
        Failure::of("powercube", self)
    }
}

impl IntoFailure for motionlink_compax::Error {
    fn failure(&self) -> Failure {
        Failure::of("compax", self)
    }
}

impl IntoFailure for motionlink_link::LinkError {
    fn failure(&self) -> Failure {
        Failure::of("", self)
    }
}
