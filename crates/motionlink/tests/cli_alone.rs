//! The command line's tests that load the machine or measure it, in a test binary of their own (cargo runs
//! test binaries one after the other): the bit-flip sweep through the binary, and the CPU a long move costs.

#[allow(dead_code)]
mod common;

mod bitflip_cli;
mod cpu_cli;

/// Held by each test of this binary: they run one at a time, so that one's load does not disturb another's
/// measurement (or a PowerCube move's 50 ms watchdog refresh).
pub static ONE_AT_A_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// Takes [`ONE_AT_A_TIME`] (also after another test failed while holding it).
pub fn alone() -> std::sync::MutexGuard<'static, ()> {
    ONE_AT_A_TIME.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}
