//! Test-only helpers of the motionlink workspace, kept out of the libraries' public API. Used as a
//! dev-dependency only.
//!
//! - [`alloc_count`]: a counting global allocator, for tests that prove a codec does not allocate.
//! - [`load`]: busy threads beside a benchmark (a loaded host).
//! - [`wired`]: any family's sans-IO session wired straight to its emulator on a time the test moves.
//! - [`rig`]: any family's client over an in-memory link to its emulator, on a manual clock.

#![warn(missing_docs)]

pub mod alloc_count;
pub mod load;
pub mod rig;
pub mod wired;
