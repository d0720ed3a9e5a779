//! The integration tests of motionlink-powercube, built as one test binary (one link instead of one per file:
//! see docs/testing.md). Tests that measure the whole process (allocations, CPU time)
//! stay binaries of their own.

#[cfg(feature = "tokio")]
mod async_client;
#[cfg(feature = "tokio")]
mod async_example;
mod embedded_can;
mod fuzz;
mod manual_examples;
mod opening;
mod probe;
