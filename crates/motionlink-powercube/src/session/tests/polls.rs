//! Waits on the bench: what a poll reads, and what a watchdog that expired during a guarded move says.

use super::*;

/// Starts a guarded move of module 1 to 1.0 rad and lets it run until the module moves.
fn a_guarded_move_under_way(b: &mut Bench) -> OpId {
    let spec = MoveSpec {
        vel: Some(Velocity::native(0.5)),
        acc: Some(Acceleration::native(1.0)),
        ..MoveSpec::to(Position::native(1.0))
    };
    let id = b.session.start(Op::MoveGuarded(addr(1), spec, Guard::Watchdog), b.now);
    while b.progress.is_empty() {
        assert!(b.step_before(b.now + Duration::from_secs(1)), "the move starts");
    }
    assert!(b.module(1).0.contains(StateFlag::Motion) && b.module(1).2, "moving, watchdog online");
    id
}

fn finish(b: &mut Bench, id: OpId) -> Result<Output, Error> {
    loop {
        b.settle();
        if let Some(r) = b.take_done(id) {
            return r;
        }
        assert!(b.step_before(b.now + Duration::from_secs(3600)), "{id} did not end");
    }
}

#[test]
fn a_watchdog_that_expires_because_the_host_stalled_says_the_refresh_came_late() {
    for can in [false, true] {
        let mut b = if can { Bench::can(&[1]) } else { Bench::rs232(&[1]) };
        let id = a_guarded_move_under_way(&mut b);
        // The host is not scheduled for 120 ms: no refresh, nothing sent; the module's watchdog expires.
        b.now += ms(120);
        b.device.update(b.now);
        assert!(b.module(1).0.contains(StateFlag::CommError), "expired while the host stalled");
        let err = finish(&mut b, id).unwrap_err();
        let Error::WatchdogExpired { address: A1, state, timing } = &err else { panic!("{err:?}") };
        assert!(state.contains(StateFlag::CommError) && timing.was_late(), "{err:?}");
        assert!(timing.longest_gap >= ms(120) && timing.longest_gap < ms(150), "{timing:?}");
        let text = err.to_string();
        assert!(text.contains("STATE_COMM_ERROR"), "{text}");
        assert!(
            text.contains(
                "ms late (at most 50 ms allowed): this host did not run the program in time; the module halted itself"
            ),
            "{text}"
        );
        assert!(err.is_device(), "{err}");
    }
}

#[test]
fn a_watchdog_that_expires_because_the_line_lost_the_refreshes_says_they_went_out_in_time() {
    for can in [false, true] {
        let mut b = if can { Bench::can(&[1]) } else { Bench::rs232(&[1]) };
        let id = a_guarded_move_under_way(&mut b);
        b.lose_refreshes();
        let err = finish(&mut b, id).unwrap_err();
        let Error::WatchdogExpired { address: A1, timing, .. } = &err else { panic!("{err:?}") };
        assert!(!timing.was_late() && timing.longest_gap <= ms(20), "{timing:?}");
        let text = err.to_string();
        assert!(text.contains("went out in time") && text.contains("the line or the module lost them"), "{text}");
        assert!(!text.contains("late"), "{text}");
    }
}

/// The GetExtended requests of parameter `p` that went out on a CAN bench.
fn gets(b: &Bench, p: Param) -> usize {
    b.sent.iter().filter(|(_, w)| frame(w, |id| (0xC1..=0xDF).contains(&id), Some(&[0x0A, p.id()]))).count()
}

#[test]
fn a_wait_polls_with_one_exchange_and_reads_the_full_state_only_when_it_may_say_more() {
    let mut b = Bench::can(&[1]);
    let spec = MoveSpec {
        vel: Some(Velocity::native(0.5)),
        acc: Some(Acceleration::native(2.0)),
        ..MoveSpec::to(Position::native(1.0))
    };
    let Ok(Output::Moved(report)) = b.run(Op::MoveTo(addr(1), spec)) else { panic!() };
    assert!((report.reached.value() - 1.0).abs() <= 0.001, "{report:?}");
    let polls = b.progress.len();
    assert!(polls > 200, "{polls}");
    // One combined read per poll, and the one before the move that finds out whether the module has it.
    assert_eq!(gets(&b, Param::ActFPosStateDio), polls + 1, "one combined read per poll");
    // The full state: before the move, on the first poll, where the short state changed (the end), and
    // every 100 ms in between (every tenth poll); ActPos only for the start and the two final readings.
    let states = gets(&b, Param::CubeState);
    assert!(states <= polls / 10 + 6, "{states} CubeState reads for {polls} polls");
    assert_eq!(gets(&b, Param::ActPos), 3);
}

#[test]
fn a_fault_in_the_middle_of_a_ramp_is_seen_at_the_next_poll() {
    let mut b = Bench::can(&[1]);
    let spec = MoveSpec {
        vel: Some(Velocity::native(0.5)),
        acc: Some(Acceleration::native(2.0)),
        ..MoveSpec::to(Position::native(1.0))
    };
    let id = b.session.start(Op::MoveTo(addr(1), spec), b.now);
    while b.progress.len() < 50 {
        assert!(b.step_before(b.now + Duration::from_secs(1)), "the move runs");
    }
    let at = b.now;
    b.device.module_mut(1).unwrap().inject_fault(CubeState::EMPTY.with(StateFlag::TowError));
    let err = finish(&mut b, id).unwrap_err();
    assert!(matches!(&err, Error::Device { address: A1, state } if state.contains(StateFlag::TowError)), "{err:?}");
    assert!(b.now - at <= ms(10), "seen by the next poll: {:?}", b.now - at);
}

#[test]
fn a_flag_the_short_state_does_not_carry_is_seen_within_100_ms() {
    // STATE_CURLIMIT, a warning that neither stops the module nor shows in the short state: the progress
    // reports it within 100 ms of its rise all the same.
    let mut b = Bench::can(&[1]);
    let spec = MoveSpec {
        vel: Some(Velocity::native(0.5)),
        acc: Some(Acceleration::native(2.0)),
        ..MoveSpec::to(Position::native(1.0))
    };
    let id = b.session.start(Op::MoveTo(addr(1), spec), b.now);
    while b.progress.len() < 50 {
        assert!(b.step_before(b.now + Duration::from_secs(1)), "the move runs");
    }
    let at = b.now;
    b.device.module_mut(1).unwrap().set_flag_for_test(StateFlag::CurLimit);
    b.progress.clear();
    while !b.progress.iter().any(|(_, p)| p.state.contains(StateFlag::CurLimit)) {
        assert!(b.step_before(b.now + Duration::from_secs(1)), "the move runs");
    }
    assert!(b.now - at <= ms(110), "{:?}", b.now - at);
    assert!(finish(&mut b, id).is_ok());
}
