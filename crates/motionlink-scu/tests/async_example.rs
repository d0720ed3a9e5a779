//! The async example runs to its end in CI: the same code, as a test.

#![cfg(feature = "tokio")]

#[path = "../examples/async_move.rs"]
#[allow(dead_code)]
mod example;

use motionlink_scu::model::PositionCounts;

#[test]
fn positions_are_read_while_a_move_runs_and_a_dropped_move_stops_the_actuator() {
    let runtime = tokio::runtime::Builder::new_multi_thread().worker_threads(2).enable_all().build().unwrap();
    runtime.block_on(async {
        let seen = example::run().await.unwrap();
        assert!(seen.reads.windows(2).any(|w| w[1] > w[0]), "A1 moved while it was read: {:?}", seen.reads);
        assert!(seen.reads.iter().all(|p| *p < PositionCounts(800)), "{:?}", seen.reads);
        assert_eq!(seen.rest.0, seen.rest.1, "at rest: {:?}", seen.rest);
        assert!(seen.rest.0 < PositionCounts(800), "stopped on the way");
        assert!(!seen.unit_moving);
        assert!(seen.started.is_empty(), "the cancelled move got its RS: {:?}", seen.started);
    })
}
