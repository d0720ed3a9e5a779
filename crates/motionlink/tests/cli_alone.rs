//! The command line's tests that load the machine or measure it, in a test binary of their own (cargo runs
//! test binaries one after the other): the bit-flip sweep through the binary, and the CPU a long move costs.

mod common;

mod bitflip_cli;
mod cpu_cli;

/// The bit-flip sweeps hold it for writing (one at a time, alone), the CPU measurements for reading (they may
/// run side by side: each measures the CPU time of its own command, which the other commands waiting on their
/// moves hardly disturb, but never beside a sweep's load, which would also starve a PowerCube move's 50 ms
/// watchdog refresh).
pub static LOAD: std::sync::RwLock<()> = std::sync::RwLock::new(());

/// Alone: no other test of this binary runs meanwhile.
pub fn alone() -> std::sync::RwLockWriteGuard<'static, ()> {
    LOAD.write().unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// Beside other light tests, never beside a sweep.
pub fn light() -> std::sync::RwLockReadGuard<'static, ()> {
    LOAD.read().unwrap_or_else(std::sync::PoisonError::into_inner)
}
