//! The async example, run as a test: positions read while a move runs, the move cancelled by dropping its
//! future, the module halted.

#[path = "../examples/async_move.rs"]
#[allow(dead_code)] // the example's `main` is not called here
mod example;

use motionlink_powercube::model::{AxisUnit, StateFlag};

#[test]
fn the_async_example_reads_while_a_move_runs_and_a_dropped_move_is_halted() {
    let runtime = tokio::runtime::Builder::new_current_thread().enable_all().build().unwrap();
    runtime.block_on(async {
        let seen = example::run().await.unwrap();
        assert!(seen.during.len() >= 3, "{seen:?}");
        assert!(
            seen.during.windows(2).all(|w| w[1].value() >= w[0].value()),
            "positions change with the move: {seen:?}"
        );
        assert!(seen.during.iter().all(|p| p.unit() == AxisUnit::Radian));
        assert!(seen.after.contains(StateFlag::Halted) && !seen.after.contains(StateFlag::Motion), "{}", seen.after);
        assert_eq!(seen.stopped_at.0, seen.stopped_at.1, "it stays where it stopped");
        assert!(seen.stopped_at.1.value() > 0.4 && seen.stopped_at.1.value() < 1.0, "{seen:?}");
        assert!(seen.events.iter().any(|e| e == "module 1 halted"), "{:?}", seen.events);
    })
}
