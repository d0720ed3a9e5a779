//! The integration tests of motionlink-compax, built as one test binary (one link instead of one per file:
//! see docs/testing.md). Tests that measure the whole process (allocations, CPU time)
//! stay binaries of their own.

mod support;

mod async_client;
mod async_example;
mod client;
mod client_stops;
mod e2e;
mod echo_check;
mod probe;
mod robustness;
mod safety;
mod shared;
mod variants;
