//! Closing a client: what it stops, what it reports, and how long it may take.

use super::*;
use crate::client::Guard;
use crate::error::Error;
use crate::model::*;
use motionlink_link::error::Classify;

#[test]
fn close_stops_what_was_started_and_says_it_was_confirmed() {
    let (clock, canbus, bus) = can(&[1, 2]);
    let _me = clock.reserve_participant().enter();
    let before = device_view(&canbus, &clock, 1).3;
    bus.enable_watchdog(&addrs(&[1, 2])).unwrap();
    bus.module(addr(1)).motion(Motion::FVel { vel: Velocity::native(0.2) }, AckKind::Simple).unwrap();
    clock.sleep(Duration::from_millis(300));
    assert_eq!(bus.close().map_err(|e| e.to_string()), Ok(vec![addr(1)]), "the close halted the module set in motion");
    let (state, _, online, config) = device_view(&canbus, &clock, 1);
    assert!(state.contains(StateFlag::Halted) && !state.contains(StateFlag::Motion), "{state}");
    assert!(!online && config == before, "watchdog off, Config word as it was");
    clock.sleep(Duration::from_secs(1));
    assert!(!device_view(&canbus, &clock, 2).0.has_fault(), "nothing left to expire");
}

#[test]
fn close_on_a_dead_line_says_the_stop_was_not_confirmed_and_the_watchdog_stops_the_module() {
    let (clock, canbus, bus) = can(&[1]);
    let _me = clock.reserve_participant().enter();
    bus.enable_watchdog(&addrs(&[1])).unwrap();
    bus.module(addr(1)).motion(Motion::FVel { vel: Velocity::native(0.2) }, AckKind::Simple).unwrap();
    canbus.drop_next_from_device(u64::MAX);
    let t0 = clock.now();
    let err = bus.close().unwrap_err();
    assert!(matches!(err, Error::CloseUnconfirmed { watchdog_armed: true, .. }), "{err}");
    assert!(err.is_transport() && err.to_string().contains("the axis may still be moving"), "{err}");
    assert!(clock.now() - t0 < Duration::from_millis(300), "three state polls of 50 ms, then the broadcast");
    clock.sleep(Duration::from_millis(100));
    let (state, _, online, _) = device_view(&canbus, &clock, 1);
    assert!(!state.contains(StateFlag::Motion) && online, "halted (the broadcast reached it), watchdog left: {state}");
}

#[test]
fn close_and_drop_are_bounded_in_time_and_a_missed_bound_is_reported() {
    // RS232 with a 300 ms bound: the close sequence would take 600 ms asking a silent module for its state.
    let config = Config { close_bound: Duration::from_millis(300), ..Config::rs232() };
    let (clock, host, bus, faults) = rs232_with(&[1], config.clone());
    let _me = clock.reserve_participant().enter();
    bus.enable_watchdog(&addrs(&[1])).unwrap();
    bus.module(addr(1)).motion(Motion::FVel { vel: Velocity::native(0.2) }, AckKind::Simple).unwrap();
    faults.drop_next(Direction::DeviceToHost, u64::MAX);
    let t0 = clock.now();
    let err = bus.close().unwrap_err();
    assert!(matches!(err, Error::CloseTimedOut { .. }) && err.is_transport(), "{err}");
    assert!(err.to_string().contains("the axis may still be moving"), "{err}");
    assert!(matches!(&err, Error::CloseTimedOut { armed: Some(a), .. } if a == &[1]), "{err:?}");
    assert!(err.to_string().contains("the watchdog of module 1 is armed and no longer refreshed"), "{err}");
    // The bound, and at most one read slice of the driver (20 ms) that was under way when it passed.
    let most = Duration::from_millis(300 + 20 + 1);
    assert!(clock.now() - t0 <= most, "{:?}", clock.now() - t0);
    // The refresh stopped with the session: the module's watchdog halts it.
    clock.sleep(Duration::from_millis(100));
    let s = host.with_device(|d| d.module(1).unwrap().state());
    assert!(s.contains(StateFlag::CommError) && !s.contains(StateFlag::Motion), "{s}");

    // Dropping is bounded the same way.
    let (clock, _host, bus, faults) = rs232_with(&[1], config);
    let _me = clock.reserve_participant().enter();
    bus.module(addr(1)).motion(Motion::FVel { vel: Velocity::native(0.2) }, AckKind::Simple).unwrap();
    faults.drop_next(Direction::DeviceToHost, u64::MAX);
    let t0 = clock.now();
    drop(bus);
    assert!(clock.now() - t0 <= most, "{:?}", clock.now() - t0);
}

#[test]
fn a_guarded_move_through_the_client_is_what_the_command_line_runs() {
    let (clock, host, bus, _) = rs232_instant(&[1]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(addr(1));
    let report = m.move_to_guarded(&spec(0.4), Guard::Watchdog, &mut |_| {}).unwrap();
    assert!((report.reached.value() - 0.4).abs() <= 0.001);
    let events = host.with_device(|d| d.take_events());
    assert!(events.iter().any(|e| e == "module 1 watchdog online"), "{events:?}");
    assert!(events.last().is_some_and(|e| e == "module 1 watchdog offline"), "{events:?}");
    // After a module died with its watchdog online: refused with the hint, nothing moved.
    host.with_device(|d| d.module_mut(1).unwrap().inject_fault(CubeState::EMPTY.with(StateFlag::CommError)));
    let err = m.move_to_guarded(&spec(0.1), Guard::Watchdog, &mut |_| {}).unwrap_err();
    assert!(err.to_string().contains("cannot arm the watchdog of module 1") && err.is_device(), "{err}");
    assert!(err.to_string().contains("`reset` clears it"), "{err}");
}

#[test]
fn the_front_ends_guard_rule_arms_only_modules_outside_this_process_that_the_user_did_not_exempt() {
    use crate::client::ModulesAt;
    use motionlink_link::url::PortUrl;
    let at = |url: &str| ModulesAt::of_url(&url.parse::<PortUrl>().unwrap());
    assert_eq!(at("sim"), ModulesAt::ThisProcess);
    for url in ["/dev/ttyS0", "tcp://127.0.0.1:5000", "socketcan://can0", "slcan:///dev/ttyACM0", "slcan://tcp://h:1"] {
        assert_eq!(at(url), ModulesAt::Elsewhere, "{url}");
    }
    assert_eq!(ModulesAt::emulated_in_process(true), ModulesAt::ThisProcess);
    assert_eq!(ModulesAt::emulated_in_process(false), ModulesAt::Elsewhere);
    // What each choice does to a module during a guarded move: armed for it, or left alone.
    for (modules, no_watchdog, armed) in [
        (ModulesAt::Elsewhere, false, true),
        (ModulesAt::Elsewhere, true, false),
        (ModulesAt::ThisProcess, false, false),
        (ModulesAt::ThisProcess, true, false),
    ] {
        let guard = Guard::for_motions(modules, no_watchdog);
        let (clock, host, bus, _) = rs232_instant(&[1]);
        let _me = clock.reserve_participant().enter();
        let before = host.with_device(|d| d.module(1).unwrap().config_word());
        let report = bus.module(addr(1)).move_to_guarded(&spec(0.3), guard, &mut |_| {}).unwrap();
        assert!((report.reached.value() - 0.3).abs() <= 0.001);
        let events = host.with_device(|d| d.take_events());
        let online = events.iter().any(|e| e == "module 1 watchdog online");
        assert_eq!(online, armed, "{modules:?}, no_watchdog {no_watchdog}: {guard:?}, {events:?}");
        let after = host.with_device(|d| d.module(1).unwrap().config_word());
        assert_eq!(after, before, "the Config word as it was found");
        assert!(!host.with_device(|d| d.module(1).unwrap().watchdog_online()));
    }
}

#[test]
fn a_close_that_times_out_without_a_watchdog_does_not_claim_one() {
    // The same missed bound, with no watchdog armed (`--no-watchdog`): the error must not promise a halt.
    let config = Config { close_bound: Duration::from_millis(300), ..Config::rs232() };
    let (clock, host, bus, faults) = rs232_with(&[1], config);
    let _me = clock.reserve_participant().enter();
    bus.module(addr(1)).motion(Motion::FVel { vel: Velocity::native(0.2) }, AckKind::Simple).unwrap();
    faults.drop_next(Direction::DeviceToHost, u64::MAX);
    let err = bus.close().unwrap_err();
    assert!(matches!(&err, Error::CloseTimedOut { armed: Some(a), .. } if a.is_empty()), "{err:?}");
    let text = err.to_string();
    assert!(text.contains("the axis may still be moving") && text.contains("no watchdog was armed"), "{text}");
    assert!(!text.contains("halts itself") && !text.contains("within 50 ms"), "{text}");
    // And it is true: nothing halts the module.
    clock.sleep(Duration::from_millis(200));
    let s = host.with_device(|d| d.module(1).unwrap().state());
    assert!(s.contains(StateFlag::Motion) && !s.contains(StateFlag::CommError), "{s}");
}

#[test]
fn a_confirmed_halt_reads_the_state_and_the_position_after_the_halt() {
    let (clock, host, bus, _) = rs232(&[1]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(addr(1));
    m.motion(Motion::FVel { vel: Velocity::native(0.2) }, AckKind::Simple).unwrap();
    clock.sleep(Duration::from_millis(500));
    assert!(m.state().unwrap().contains(StateFlag::Motion));
    let report = m.halt_confirmed().unwrap();
    assert!(report.state.contains(StateFlag::Halted) && !report.state.contains(StateFlag::Motion), "{report:?}");
    let there = host.with_device(|d| d.module(1).unwrap().state());
    assert!(!there.contains(StateFlag::Motion), "{there}");
    assert!(report.position.value() > 0.05, "it had moved: {report:?}");
    assert!((m.position().unwrap().value() - report.position.value()).abs() < 1e-6, "it stays where it stopped");
    // At rest already: the same, confirmed at once.
    let again = m.halt_confirmed().unwrap();
    assert!((again.position.value() - report.position.value()).abs() < 1e-6);
}

#[test]
fn a_halt_that_is_not_acknowledged_is_sent_again_and_then_said_unacknowledged() {
    let (clock, canbus, bus) = can(&[1]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(addr(1));
    m.motion(Motion::FVel { vel: Velocity::native(0.2) }, AckKind::Simple).unwrap();
    // Two acknowledgements lost: the third Halt is acknowledged, and the stop confirmed.
    canbus.drop_next_from_device(2);
    let report = m.halt_confirmed().unwrap();
    assert!(report.state.contains(StateFlag::Halted) && !report.state.contains(StateFlag::Motion), "{report:?}");
    // None acknowledged: three sent (the read retries' count), then an error that says the axis may move.
    bus.module(addr(1)).reset().unwrap();
    m.motion(Motion::FVel { vel: Velocity::native(0.2) }, AckKind::Simple).unwrap();
    canbus.drop_next_from_device(3);
    let err = m.halt_confirmed().unwrap_err();
    let text = err.to_string();
    assert!(text.starts_with("module 1: Halt not acknowledged (3 sent): "), "{text}");
    assert!(text.ends_with("; the axis may still be moving") && err.is_transport(), "{text}");
    assert!(matches!(err, Error::HaltUnacknowledged { sent: 3, .. }) && err.stop_unconfirmed(), "{err:?}");
    // The Halts reached it (their acknowledgements were lost), which the session cannot know: it still
    // counts the module as set in motion, and the close halts it again.
    assert!(device_view(&canbus, &clock, 1).0.contains(StateFlag::Halted));
    assert_eq!(bus.close().map_err(|e| e.to_string()), Ok(vec![addr(1)]));
}

#[test]
fn the_close_confirms_its_halt_by_the_state_and_says_so_when_it_cannot() {
    // The close halts a module still moving, and a Halt acknowledged is not yet a module at rest: its state
    // is read after it, as after every stop. Here the state after the Halt never comes back.
    let (rig, bus) = super::firmware::module_of(ModuleKind::Rotary, &[]);
    bus.module(addr(1)).motion(Motion::FVel { vel: Velocity::native(0.2) }, AckKind::Simple).unwrap();
    rig.sleep(100);
    // The close's telegrams: CubeState (moving), the Halt, then its state reads, whose answers are lost.
    let count = std::sync::Arc::new(std::sync::atomic::AtomicUsize::new(0));
    let seen = std::sync::Arc::clone(&count);
    rig.on_request(move |_, faults| {
        if seen.fetch_add(1, std::sync::atomic::Ordering::SeqCst) == 2 {
            faults.drop_next(Direction::DeviceToHost, u64::MAX / 2);
        }
    });
    let err = bus.close().unwrap_err();
    assert!(matches!(err, Error::CloseUnconfirmed { .. }) && err.is_transport(), "{err}");
    assert!(err.to_string().contains("the axis may still be moving"), "{err}");
    let state = rig.device(|d| d.module(1).unwrap().state());
    assert!(state.contains(StateFlag::Halted), "the Halt (and the broadcast) reached it: {state}");
}
