//! Runs `examples/async_move.rs` (feature `tokio`, which the crate's own dev-dependency turns on in
//! `cargo test`): positions read while a move runs, and a dropped move future that stops the axis.

#![cfg(feature = "tokio")]

#[path = "../examples/async_move.rs"]
#[allow(dead_code)]
mod example;

#[test]
fn the_async_example_reads_while_a_move_runs_and_its_dropped_future_stops_the_axis() {
    let runtime = tokio::runtime::Builder::new_multi_thread().worker_threads(2).enable_all().build().unwrap();
    runtime.block_on(async {
        let s = example::run().await.unwrap();
        assert_eq!(s.during.len(), 8);
        assert!(s.during.windows(2).all(|w| w[1] > w[0]), "rising while the move runs: {:?}", s.during);
        assert!(s.stopped_at < 1000.0 && s.stopped_at >= s.during[7], "{s:?}");
        assert_eq!(s.later, s.stopped_at, "at rest: {s:?}");
        assert_eq!(s.o0, 0, "switched off by the stop: {s:?}");
        assert!(!s.moving, "{s:?}");
    })
}
