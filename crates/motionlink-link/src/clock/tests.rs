use super::*;
use std::thread;

#[test]
fn timestamp_arithmetic_saturates() {
    let a = Timestamp::from_millis(100);
    let b = Timestamp::from_millis(250);
    assert_eq!(b - a, Duration::from_millis(150));
    assert_eq!(a - b, Duration::ZERO);
    assert_eq!(a + Duration::from_millis(5), Timestamp::from_millis(105));
}

#[test]
fn real_signal_raised_before_wait_returns_at_once() {
    let clock = RealClock::new();
    let s = clock.signal();
    s.raise();
    assert_eq!(s.wait_until(Some(clock.now() + Duration::from_secs(10))), Wake::Raised);
    // Lowered again: now it times out.
    assert_eq!(s.wait_until(Some(clock.now() + Duration::from_millis(5))), Wake::Deadline);
}

#[test]
fn a_sleeping_wait_ends_at_its_deadline_or_when_raised() {
    let clock = RealClock::new();
    let s = clock.signal();
    let deadline = clock.now() + Duration::from_millis(5);
    assert_eq!(s.wait_until_sleeping(Some(deadline)), Wake::Deadline);
    assert!(clock.now() >= deadline, "never before its deadline");
    s.raise();
    assert_eq!(s.wait_until_sleeping(Some(clock.now() + Duration::from_secs(10))), Wake::Raised);
    // A manual clock waits as wait_until does.
    let manual = ManualClock::new_auto();
    let _me = manual.reserve_participant().enter();
    assert_eq!(manual.signal().wait_until_sleeping(Some(Timestamp::from_millis(7))), Wake::Deadline);
    assert_eq!(manual.now(), Timestamp::from_millis(7));
}

#[test]
fn real_signal_wakes_a_blocked_thread() {
    let clock = RealClock::new();
    let s = clock.signal();
    let s2 = s.clone();
    let t = thread::spawn(move || s2.wait_until(None));
    thread::sleep(Duration::from_millis(20));
    s.raise();
    assert_eq!(t.join().unwrap(), Wake::Raised);
}

#[test]
fn real_signal_raises_are_never_lost_between_two_threads() {
    // A raise skips the operating system when nobody sleeps: a ping-pong of 20,000 hand-offs, each a raise
    // racing the other thread's way into its sleep, hangs if one is lost (the join below then times out).
    let clock = RealClock::new();
    let (ping, pong) = (clock.signal(), clock.signal());
    let (p2, q2) = (ping.clone(), pong.clone());
    let (done_tx, done_rx) = std::sync::mpsc::channel();
    thread::spawn(move || {
        for _ in 0..10_000 {
            assert_eq!(p2.wait_until(None), Wake::Raised);
            q2.raise();
        }
        done_tx.send(()).unwrap();
    });
    for _ in 0..10_000 {
        ping.raise();
        assert_eq!(pong.wait_until(Some(clock.now() + Duration::from_secs(10))), Wake::Raised, "a raise was lost");
    }
    done_rx.recv_timeout(Duration::from_secs(10)).expect("the other thread saw every raise");
}

#[test]
fn a_long_real_wait_ends_at_its_deadline_and_not_before() {
    // Long enough for the two-stage sleep (REAL_APPROACH), and raised in its second stage.
    let clock = RealClock::new();
    let s = clock.signal();
    for ms in [1, 3, 20] {
        let deadline = clock.now() + Duration::from_millis(ms);
        assert_eq!(s.wait_until(Some(deadline)), Wake::Deadline);
        assert!(clock.now() >= deadline, "a {ms} ms wait ended before its deadline");
    }
    let s2 = s.clone();
    let t = thread::spawn(move || s2.wait_until(Some(RealClock::new().now() + Duration::from_secs(10))));
    thread::sleep(Duration::from_millis(5));
    s.raise();
    assert_eq!(t.join().unwrap(), Wake::Raised);
}

#[test]
fn manual_advance_wakes_expired_waiters_only() {
    let clock = ManualClock::new();
    let s = clock.signal();
    let c2 = clock.clone();
    let t = thread::spawn(move || {
        let w = s.wait_until(Some(Timestamp::from_millis(100)));
        (w, c2.now())
    });
    thread::sleep(Duration::from_millis(20));
    clock.advance(Duration::from_millis(50));
    thread::sleep(Duration::from_millis(20));
    assert!(!t.is_finished(), "woke before its deadline");
    clock.advance(Duration::from_millis(60));
    let (w, at) = t.join().unwrap();
    assert_eq!(w, Wake::Deadline);
    assert_eq!(at, Timestamp::from_millis(110));
}

#[test]
fn auto_clock_jumps_when_all_participants_wait() {
    let clock = ManualClock::new_auto();
    let _me = clock.reserve_participant().enter();
    let ticket = clock.reserve_participant();
    let c2 = clock.clone();
    // A second participant that ticks every 200 ms, ten times.
    let t = thread::spawn(move || {
        let _g = ticket.enter();
        let s = c2.signal();
        let mut stamps = Vec::new();
        for i in 1..=10u64 {
            s.wait_until(Some(Timestamp::from_millis(200 * i)));
            stamps.push(c2.now());
        }
        stamps
    });
    clock.sleep_until(Timestamp::from_millis(5_000));
    let stamps = t.join().unwrap();
    assert_eq!(stamps, (1..=10).map(|i| Timestamp::from_millis(200 * i)).collect::<Vec<_>>());
    assert_eq!(clock.now(), Timestamp::from_millis(5_000));
}

#[test]
fn auto_clock_does_not_move_while_a_participant_runs() {
    let clock = ManualClock::new_auto();
    // This thread is a participant (counted before the other starts) and busy: the other must not be released.
    let _me = clock.reserve_participant().enter();
    let ticket = clock.reserve_participant();
    let c2 = clock.clone();
    let t = thread::spawn(move || {
        let _g = ticket.enter();
        c2.sleep(Duration::from_millis(100));
    });
    thread::sleep(Duration::from_millis(30));
    assert_eq!(clock.now(), Timestamp::ZERO);
    assert!(!t.is_finished());
    clock.sleep(Duration::from_millis(100));
    t.join().unwrap();
    assert_eq!(clock.now(), Timestamp::from_millis(100));
}

#[test]
fn raising_a_waiter_counts_it_as_running_at_once() {
    // Ping-pong between two participants through signals must never let time move.
    let clock = ManualClock::new_auto();
    let _me = clock.reserve_participant().enter();
    let ticket = clock.reserve_participant();
    let ping = clock.signal();
    let pong = clock.signal();
    let (ping2, pong2, c2) = (ping.clone(), pong.clone(), clock.clone());
    let t = thread::spawn(move || {
        let _g = ticket.enter();
        for _ in 0..1000 {
            assert_eq!(ping2.wait_until(Some(Timestamp::from_millis(1))), Wake::Raised);
            pong2.raise();
        }
        c2.now()
    });
    for _ in 0..1000 {
        ping.raise();
        assert_eq!(pong.wait_until(Some(Timestamp::from_millis(1))), Wake::Raised);
    }
    assert_eq!(t.join().unwrap(), Timestamp::ZERO);
}

/// Joins a thread when dropped.
struct JoinOnDrop(Option<thread::JoinHandle<Timestamp>>);

impl Drop for JoinOnDrop {
    fn drop(&mut self) {
        if let Some(t) = self.0.take() {
            let _ = t.join();
        }
    }
}

#[test]
fn a_participant_that_panics_frees_the_clock_for_what_it_waits_on_while_unwinding() {
    let clock = ManualClock::new_auto();
    let ticket = clock.reserve_participant();
    let other = clock.clone();
    let sleeper = thread::spawn(move || {
        let _me = ticket.enter();
        other.sleep(Duration::from_secs(600));
        other.now()
    });
    let me = clock.clone();
    let unwound = std::panic::catch_unwind(std::panic::AssertUnwindSafe(move || {
        let _me = me.reserve_participant().enter();
        // Dropped first while unwinding, with this thread still a participant that does not wait on the
        // clock: without the panic the clock would never move, and the join would never end.
        let _join = JoinOnDrop(Some(sleeper));
        thread::sleep(Duration::from_millis(20));
        assert_eq!(me.now(), Timestamp::ZERO, "a running participant holds the clock");
        panic!("on purpose: a failing test");
    }));
    assert!(unwound.is_err());
    assert_eq!(clock.now(), Timestamp::ZERO + Duration::from_secs(600), "the sleeper's deadline was reached");
}
