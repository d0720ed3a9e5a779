//! Test-only helpers of the motionlink workspace, kept out of the libraries' public API. Used as a
//! dev-dependency only.
//!
//! - [`alloc_count`]: a counting global allocator, for tests that prove a codec does not allocate.

#![warn(missing_docs)]

pub mod alloc_count;
