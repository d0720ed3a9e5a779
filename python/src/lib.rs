//! `motionlink._native`: the Rust half of the `motionlink` Python package. Thin: each method is one call
//! of a family's `Client`, `AsyncClient` or `Emulator`; what stops an axis, when a watchdog is armed and how
//! a move is verified stay in the family crates. The Python half (`motionlink/`) gives the results their
//! types and the clients their context managers.

mod common;
#[macro_use]
mod faces;
mod compax;
mod emulator;
mod errors;
mod powercube;
mod scu;
mod session;
mod wait;

use pyo3::prelude::*;

/// The native module.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<emulator::NativeEmulator>()?;
    m.add_class::<powercube::PowerCubeClient>()?;
    m.add_class::<powercube::AsyncPowerCubeClient>()?;
    m.add_class::<scu::ScuClient>()?;
    m.add_class::<scu::AsyncScuClient>()?;
    m.add_class::<wait::NativeTask>()?;
    m.add_function(wrap_pyfunction!(wait::stop_deliveries, m)?)?;
    m.add_class::<compax::CompaxClient>()?;
    m.add_class::<compax::AsyncCompaxClient>()?;
    m.add_class::<compax::CompaxWatch>()?;
    m.add("COMPAX_DEFAULT_TOLERANCE_UNITS", compax::default_tolerance())?;
    Ok(())
}
