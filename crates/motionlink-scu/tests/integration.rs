//! The integration tests of motionlink-scu, built as one test binary (one link instead of one per file:
//! see docs/testing.md). Tests that measure the whole process (allocations, CPU time)
//! stay binaries of their own.

mod bench;
mod rig;

mod async_client;
mod async_example;
mod client;
mod client_faults;
mod client_follow;
mod client_moves;
mod probe;
mod session;
mod sim;
mod sim_errors;
mod sim_robustness;
mod slow_link;
mod variants;
mod wire;
