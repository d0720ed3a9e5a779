//! The integration tests of motionlink-link, built as one test binary (one link instead of one per file:
//! see docs/testing.md). Tests that measure the whole process (allocations, CPU time)
//! stay binaries of their own.

mod toy;

mod can_slcan;
mod driver;
mod serve;
