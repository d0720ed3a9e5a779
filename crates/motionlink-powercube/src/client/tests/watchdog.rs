//! The watchdog, and what closing a session (dropping its client) stops.

use super::*;
use crate::client::{MoveReport, StopOutcome, WATCHDOG_TIMEOUT};
use crate::error::Error;
use crate::model::*;
use crate::wire::Request;

#[test]
fn the_watchdog_is_served_in_the_background_and_trips_when_the_session_dies() {
    let (clock, host, bus) = can_host();
    let _me = clock.reserve_participant().enter();
    bus.enable_watchdog(&addrs(&[1, 2])).unwrap();
    assert!(host.with_device(|d| d.module(1).unwrap().watchdog_online()).unwrap());
    let m = bus.module(addr(1));
    m.home().unwrap();
    m.wait_home(secs(10), &mut |_| {}).unwrap();
    // Ten seconds of device time with the test thread mostly asleep: the background thread refreshes.
    clock.sleep(secs(10));
    for a in [1, 2] {
        let s = bus.module(addr(a)).state().unwrap();
        assert!(!s.contains(StateFlag::CommError), "{s}");
    }
    assert!(bus.watchdog_served());
    kill(bus);
    clock.sleep(Duration::from_millis(100));
    let s = host.with_device(|d| d.module(2).unwrap().state()).unwrap();
    assert!(s.contains(StateFlag::CommError) && s.contains(StateFlag::Halted), "{s}");
}

#[test]
fn disabling_the_watchdog_switches_it_off_in_the_modules() {
    // RS232 with the opt-in: the emulator takes address 0 as every module.
    let (clock, host, bus, _) = rs232_with(&[1], Config { watchdog_on_rs232: true, ..Config::rs232() });
    let _me = clock.reserve_participant().enter();
    bus.enable_watchdog(&addrs(&[1])).unwrap();
    clock.sleep(secs(2));
    bus.disable_watchdog().unwrap();
    assert!(!host.with_device(|d| d.module(1).unwrap().watchdog_online()));
    clock.sleep(secs(2));
    assert!(!bus.module(addr(1)).state().unwrap().contains(StateFlag::CommError));
}

#[test]
fn six_joints_in_a_control_loop_with_the_watchdog() {
    let addresses: Vec<u8> = (1..=6).collect();
    let (clock, canbus, bus) = can(&addresses);
    let _me = clock.reserve_participant().enter();
    bus.broadcast(Broadcast::Home).unwrap();
    for a in &addresses {
        bus.module(addr(*a)).wait_home(secs(10), &mut |_| {}).unwrap();
    }
    bus.enable_watchdog(&addrs(&addresses)).unwrap();
    // 100 cycles of 10 ms: read all positions, command a step towards 0.2 rad.
    let period = Duration::from_millis(10);
    let mut next = clock.now();
    for cycle in 1..=100u32 {
        let positions = bus.positions(&addrs(&addresses));
        assert!(positions.iter().all(Result::is_ok));
        let target = 0.2 * cycle as f32 / 100.0;
        let reqs: Vec<(Address, Request)> = addresses
            .iter()
            .map(|a| {
                (
                    addr(*a),
                    Request::Motion(Motion::FStep { pos: Position::native(target), time: Millis(10) }, AckKind::Simple),
                )
            })
            .collect();
        assert!(bus.request_many(&reqs).iter().all(Result::is_ok));
        next += period;
        clock.sleep_until(next);
    }
    clock.sleep(Duration::from_millis(50));
    for p in bus.positions(&addrs(&addresses)) {
        assert!((p.unwrap().value() - 0.2).abs() < 1e-4);
    }
    for a in &addresses {
        assert!(!bus.module(addr(*a)).state().unwrap().has_fault());
    }
    assert!(canbus.frames_carried() > 2_400);
    // The session ends normally: the watchdogs go offline, nothing halts.
    drop(bus);
    clock.sleep(Duration::from_millis(200));
    for a in &addresses {
        let (state, _, online, _) = device_view(&canbus, &clock, *a);
        assert!(!online && !state.contains(StateFlag::Halted), "module {a}: {state}");
    }
}

#[test]
fn arming_the_watchdog_for_a_motion_leaves_the_modules_as_it_found_them() {
    let (clock, canbus, bus) = can(&[1, 2]);
    let _me = clock.reserve_participant().enter();
    assert!(bus.watchdog_reliable());
    let (m1, m2) = (bus.module(addr(1)), bus.module(addr(2)));
    let before1 = m1.config_word().unwrap();
    assert!(!before1.contains(ConfigFlag::WatchdogEnable));
    // Module 2's user keeps the flag set: it must stay set.
    let before2 = m2.config_word().unwrap().with(ConfigFlag::WatchdogEnable);
    m2.set(Param::Config, Value::U32(before2.0)).unwrap();

    bus.enable_watchdog(&addrs(&[1, 2])).unwrap();
    assert!(m1.config_word().unwrap().contains(ConfigFlag::WatchdogEnable));
    assert!(device_view(&canbus, &clock, 1).2 && device_view(&canbus, &clock, 2).2, "online");
    m1.home().unwrap();
    m1.wait_home(secs(10), &mut |_| {}).unwrap();
    m1.move_ramp(Position::native(0.5), Some(Ramp { vel: Velocity::native(0.5), acc: Acceleration::native(1.0) }))
        .unwrap();
    m1.wait_ramp_end(secs(10), &mut |_| {}).unwrap();
    bus.disable_watchdog().unwrap();

    assert!(!bus.watchdog_served());
    assert_eq!(m1.config_word().unwrap(), before1, "the flag this session set is cleared again");
    assert_eq!(m2.config_word().unwrap(), before2, "the flag the user had set stays");
    // Offline: a second of device time without refreshes changes nothing.
    clock.sleep(secs(1));
    for a in [1, 2] {
        let (state, _, online, _) = device_view(&canbus, &clock, a);
        assert!(!online, "module {a}");
        assert!(!state.contains(StateFlag::Halted) && !state.contains(StateFlag::CommError), "module {a}: {state}");
    }
    assert!((m1.position().unwrap().value() - 0.5).abs() < 1e-4);
    // Disabling twice is harmless.
    bus.disable_watchdog().unwrap();
    assert_eq!(m1.config_word().unwrap(), before1);
    use crate::model::Acceleration;
}

#[test]
fn a_host_that_dies_while_moving_is_stopped_by_the_watchdog_within_50_ms() {
    let (clock, canbus, bus) = can(&[1]);
    let _me = clock.reserve_participant().enter();
    bus.enable_watchdog(&addrs(&[1])).unwrap();
    let m = bus.module(addr(1));
    m.move_ramp(Position::native(2.0), Some(Ramp { vel: Velocity::native(0.2), acc: Acceleration::native(1.0) }))
        .unwrap();
    clock.sleep(secs(1));
    assert!(m.state().unwrap().contains(StateFlag::Motion));
    let died = clock.now();
    kill(bus);

    clock.sleep_until(died + Duration::from_millis(45));
    assert!(device_view(&canbus, &clock, 1).0.contains(StateFlag::Motion), "still moving 45 ms later");
    clock.sleep_until(died + WATCHDOG_TIMEOUT);
    let (state, stopped_at, online, config) = device_view(&canbus, &clock, 1);
    assert!(state.contains(StateFlag::CommError) && state.contains(StateFlag::Halted), "{state}");
    assert!(!state.contains(StateFlag::Motion), "{state}");
    assert!(online && config.contains(ConfigFlag::WatchdogEnable), "a dead host cannot clean up");
    assert!(stopped_at > 0.1 && stopped_at < 1.0, "{stopped_at}");
    clock.sleep(Duration::from_millis(500));
    assert_eq!(device_view(&canbus, &clock, 1).1, stopped_at, "it does not move any more");

    // The next session: arming is refused (a life sign would switch the expired watchdog off) and changes
    // nothing; a reset that releases the watchdog brings the module back for good.
    let bus = Client::with_link(PortLink::Can(Box::new(canbus.connect())), clock.shared(), Config::can()).unwrap();
    let m = bus.module(addr(1));
    let err = bus.enable_watchdog(&addrs(&[1])).unwrap_err();
    assert!(matches!(err, Error::Device { address: A1, state } if state.contains(StateFlag::CommError)), "{err}");
    assert!(device_view(&canbus, &clock, 1).2, "still online");
    assert!(m.reset_and_release_watchdog().unwrap());
    clock.sleep(secs(1));
    let (state, _, online, _) = device_view(&canbus, &clock, 1);
    assert!(!online && !state.contains(StateFlag::Halted) && !state.contains(StateFlag::CommError), "{state}");
    // A reset of a module whose watchdog did not expire is a plain reset.
    assert!(!m.reset_and_release_watchdog().unwrap());
    // And the watchdog arms again (the Config flag the dead session left is kept).
    bus.enable_watchdog(&addrs(&[1])).unwrap();
    bus.disable_watchdog().unwrap();
    assert!(m.config_word().unwrap().contains(ConfigFlag::WatchdogEnable));
    use crate::model::Acceleration;
}

#[test]
fn a_watchdog_another_host_serves_is_not_released() {
    let (clock, canbus, host_a) = can(&[1]);
    let _me = clock.reserve_participant().enter();
    host_a.enable_watchdog(&addrs(&[1])).unwrap();
    // Three refreshes in a row are lost: the module halts, though host A is alive and keeps refreshing.
    canbus.drop_next_to_device(3);
    clock.sleep(Duration::from_millis(200));
    assert!(device_view(&canbus, &clock, 1).0.contains(StateFlag::CommError));
    let host_b = Client::with_link(PortLink::Can(Box::new(canbus.connect())), clock.shared(), Config::can()).unwrap();
    assert!(!host_b.module(addr(1)).reset_and_release_watchdog().unwrap(), "host A serves it");
    clock.sleep(secs(1));
    let (state, _, online, _) = device_view(&canbus, &clock, 1);
    assert!(online, "host B did not toggle host A's watchdog");
    assert!(!state.contains(StateFlag::CommError) && !state.contains(StateFlag::Halted), "{state}");
    drop(host_b);
    host_a.disable_watchdog().unwrap();
}

#[test]
fn rs232_arms_the_watchdog_with_libm5api_broadcasts_unless_told_not_to() {
    // The refresh goes to address 0 as 0x07 0x00, the form Schunk's libm5api sends over RS232: the module
    // stays alive while the session serves it, and halts 50 ms after the session dies.
    let (clock, host, bus, _) = rs232(&[1]);
    let _me = clock.reserve_participant().enter();
    assert!(bus.watchdog_reliable());
    bus.enable_watchdog(&addrs(&[1])).unwrap();
    assert!(host.with_device(|d| d.module(1).unwrap().watchdog_online()));
    clock.sleep(secs(2));
    assert!(!host.with_device(|d| d.module(1).unwrap().state().has_fault()), "served for 2 s");
    assert_eq!(host.with_device(|d| d.stats().not_understood), 0, "every refresh understood");
    bus.disable_watchdog().unwrap();
    assert!(!host.with_device(|d| d.module(1).unwrap().watchdog_online()));
    drop(bus);

    let (clock, host, bus, faults) = rs232_with(&[1], Config { watchdog_on_rs232: false, ..Config::rs232() });
    let _me = clock.reserve_participant().enter();
    assert!(!bus.watchdog_reliable());
    let sent = faults.bytes_sent(Direction::HostToDevice);
    let err = bus.enable_watchdog(&addrs(&[1])).unwrap_err();
    assert!(matches!(err, Error::NotSupported(_)) && err.is_usage(), "{err}");
    assert!(err.to_string().contains("watchdog_on_rs232"), "the setting is named: {err}");
    assert_eq!(faults.bytes_sent(Direction::HostToDevice), sent, "nothing was sent");
    assert!(!bus.watchdog_served());
    assert!(!host.with_device(|d| d.module(1).unwrap().config_word().contains(ConfigFlag::WatchdogEnable)));
}

#[test]
fn a_broadcast_home_sets_only_known_modules_moving_and_the_drop_is_quick() {
    let (clock, host, bus, _) = rs232(&[1, 2]);
    let _me = clock.reserve_participant().enter();
    // Before anything answered, a broadcast Home marks nobody (the session knows of no module).
    bus.broadcast(Broadcast::Home).unwrap();
    assert!(bus.started().is_empty(), "{:?}", bus.started());
    clock.sleep(secs(2));
    assert_eq!(scan_infos(&bus).len(), 2);
    assert_eq!(bus.known(), vec![1, 2]);
    bus.broadcast(Broadcast::Home).unwrap();
    assert_eq!(bus.started(), vec![1, 2], "the modules that exist, not 1..31");
    // Module 1 is seen to end homing; module 2 ends it unwatched and sits idle.
    bus.module(addr(1)).wait_home(secs(10), &mut |_| {}).unwrap();
    clock.sleep(secs(2));
    assert_eq!(bus.started(), vec![2]);
    let t0 = clock.now();
    drop(bus);
    // One state poll of module 2 (about 25 ms at 9600 baud): no 29 absent addresses timing out three times
    // each (17 s), and no broadcast Halt.
    let took = clock.now() - t0;
    assert!(took < Duration::from_millis(100), "{took:?}");
    for a in [1, 2] {
        let s = host.with_device(|d| d.module(a).unwrap().state());
        assert!(s.contains(StateFlag::HomeOk) && !s.contains(StateFlag::Halted), "module {a}: {s}");
    }
}

#[test]
fn a_drop_halts_a_known_module_still_homing_but_not_for_an_address_that_never_answered() {
    let (clock, host, bus, _) = rs232(&[1, 2]);
    let _me = clock.reserve_participant().enter();
    bus.module(addr(1)).state().unwrap();
    bus.broadcast(Broadcast::Home).unwrap();
    // Module 2 exists but the session does not know it; it homes too (no harm) and is idle at the drop.
    // A motion command to an address where nobody is: no acknowledge.
    let err = bus.module(addr(9)).motion(Motion::FVel { vel: Velocity::native(0.1) }, AckKind::Simple).unwrap_err();
    assert!(matches!(err, Error::Timeout { address: A9, .. }), "{err}");
    assert_eq!(bus.started(), vec![1, 9]);
    drop(bus);
    let s = host.with_device(|d| d.module(1).unwrap().state());
    assert!(s.contains(StateFlag::Halted) && !s.contains(StateFlag::Motion), "halted by address: {s}");
    let s = host.with_device(|d| d.module(2).unwrap().state());
    assert!(!s.contains(StateFlag::Halted), "no broadcast Halt for the silence at 9: {s}");
    assert_eq!(host.with_device(|d| d.stats().nobody), 4, "one motion and three state polls to 9");
}

#[test]
fn on_rs232_a_broadcast_halt_does_not_forget_what_was_started() {
    let (clock, host, bus, _) = rs232(&[1]);
    let _me = clock.reserve_participant().enter();
    // Real RS232 modules may ignore address 0, where the client sends broadcasts.
    host.with_device(|d| d.set_rs232_broadcasts(false));
    bus.module(addr(1)).motion(Motion::FVel { vel: Velocity::native(0.3) }, AckKind::Simple).unwrap();
    bus.broadcast(Broadcast::Halt).unwrap();
    clock.sleep(Duration::from_millis(500));
    assert!(bus.module(addr(1)).state().unwrap().contains(StateFlag::Motion), "the broadcast was ignored");
    assert_eq!(bus.started(), vec![1], "so the session still counts module 1 as moving");
    drop(bus);
    let s = host.with_device(|d| d.module(1).unwrap().state());
    assert!(s.contains(StateFlag::Halted) && !s.contains(StateFlag::Motion), "halted by address on drop: {s}");

    // On CAN a broadcast is the manual's and reaches every module: it ends the list.
    let (clock, canbus, bus) = can(&[1]);
    let _me = clock.reserve_participant().enter();
    bus.module(addr(1)).motion(Motion::FVel { vel: Velocity::native(0.3) }, AckKind::Simple).unwrap();
    bus.broadcast(Broadcast::Halt).unwrap();
    assert!(bus.started().is_empty());
    clock.sleep(Duration::from_millis(1)); // the frame's time on the bus
    assert!(device_view(&canbus, &clock, 1).0.contains(StateFlag::Halted));
}

#[test]
fn a_normal_drop_switches_the_watchdog_off_and_a_new_session_can_arm_it_again() {
    let (clock, canbus, bus) = can(&[1, 2]);
    let _me = clock.reserve_participant().enter();
    let before = device_view(&canbus, &clock, 1).3;
    bus.enable_watchdog(&addrs(&[1, 2])).unwrap();
    let m = bus.module(addr(1));
    m.home().unwrap();
    m.wait_home(secs(10), &mut |_| {}).unwrap();
    m.motion(Motion::FVel { vel: Velocity::native(0.2) }, AckKind::Simple).unwrap();
    assert!(device_view(&canbus, &clock, 1).2 && device_view(&canbus, &clock, 2).2, "online");
    drop(bus);
    // Well past the watchdog's 50 ms: a watchdog left online would have halted both modules.
    clock.sleep(secs(1));
    for a in [1, 2] {
        let (state, _, online, config) = device_view(&canbus, &clock, a);
        assert!(!online, "module {a}: switched off");
        assert!(!state.contains(StateFlag::CommError), "module {a}: {state}");
        assert_eq!(config, before, "module {a}: the Config word as it was");
    }
    // Module 1 was moving: halted by the drop (by address), not by its watchdog.
    assert!(device_view(&canbus, &clock, 1).0.contains(StateFlag::Halted));
    assert!(!device_view(&canbus, &clock, 2).0.contains(StateFlag::Halted));
    // A new session arms them again (a watchdog left online and expired would be refused).
    let bus = Client::with_link(PortLink::Can(Box::new(canbus.connect())), clock.shared(), Config::can()).unwrap();
    bus.module(addr(1)).reset().unwrap();
    bus.enable_watchdog(&addrs(&[1, 2])).unwrap();
    assert!(device_view(&canbus, &clock, 1).2 && device_view(&canbus, &clock, 2).2);
    drop(bus);
    clock.sleep(secs(1));
    assert!(!device_view(&canbus, &clock, 2).2);
}

#[test]
fn a_session_that_failed_leaves_the_watchdog_armed_on_drop() {
    let (clock, canbus, bus) = can(&[1, 2]);
    let _me = clock.reserve_participant().enter();
    bus.enable_watchdog(&addrs(&[1, 2])).unwrap();
    bus.module(addr(1)).motion(Motion::FVel { vel: Velocity::native(0.2) }, AckKind::Simple).unwrap();
    // The modules' answers are lost from now on: the drop cannot see module 1 stop.
    canbus.drop_next_from_device(u64::MAX);
    drop(bus);
    clock.sleep(Duration::from_millis(100));
    for a in [1, 2] {
        let (state, _, online, config) = device_view(&canbus, &clock, a);
        assert!(online && config.contains(ConfigFlag::WatchdogEnable), "module {a}: left armed");
        assert!(state.contains(StateFlag::Halted) && !state.contains(StateFlag::Motion), "module {a}: {state}");
        assert!(state.contains(StateFlag::CommError), "module {a}: its watchdog expired: {state}");
    }
}

/// A CAN link that loses the first `left` life signs it sends to a module (`outgoing`), or the first
/// `left` acknowledges of one it receives.
struct LoseLifeSign<L> {
    inner: L,
    outgoing: bool,
    left: usize,
}

fn is_life_sign(frame: &motionlink_link::can::CanFrame) -> bool {
    frame.data() == [0x07] && frame.id() < 0x100
}

impl<L: CanLink> CanLink for LoseLifeSign<L> {
    fn send(&mut self, frame: &motionlink_link::can::CanFrame) -> Result<(), LinkError> {
        if self.outgoing && self.left > 0 && is_life_sign(frame) {
            self.left -= 1;
            return Ok(());
        }
        self.inner.send(frame)
    }

    fn recv(&mut self, timeout: Duration) -> Result<Option<motionlink_link::can::CanFrame>, LinkError> {
        let frame = self.inner.recv(timeout)?;
        match frame {
            Some(f) if !self.outgoing && self.left > 0 && is_life_sign(&f) => {
                self.left -= 1;
                Ok(None)
            }
            other => Ok(other),
        }
    }

    fn discard_input(&mut self) -> Result<(), LinkError> {
        self.inner.discard_input()
    }

    fn describe(&self) -> String {
        format!("lossy {}", self.inner.describe())
    }
}

fn can_losing(addresses: &[u8], outgoing: bool) -> (ManualClock, CanBus<Emulator>, Client) {
    let clock = ManualClock::new_auto();
    let sim = Emulator::new_can(&SimConfig::with_addresses(addresses).unwrap());
    let canbus = CanBus::with_emulator(sim, clock.shared(), CanBusConfig::paced(1_000_000));
    let link = LoseLifeSign { inner: canbus.connect(), outgoing, left: 1 };
    let bus = Client::with_link(PortLink::Can(Box::new(link)), clock.shared(), Config::can()).unwrap();
    (clock, canbus, bus)
}

#[test]
fn a_lost_life_sign_is_reported_and_never_toggled_again_blindly() {
    let (clock, canbus, bus) = can_losing(&[1, 2], true);
    let _me = clock.reserve_participant().enter();
    let before = bus.module(addr(1)).config_word().unwrap();
    let err = bus.enable_watchdog(&addrs(&[1, 2])).unwrap_err();
    assert!(matches!(err, Error::WatchdogUnconfirmed { address: A1, on: true, .. }), "{err}");
    assert!(err.to_string().contains("module 1"), "{err}");
    // Module 1 never got the toggle; module 2 did.
    assert!(!device_view(&canbus, &clock, 1).2);
    assert!(device_view(&canbus, &clock, 2).2);
    // Served anyway: nothing trips meanwhile.
    clock.sleep(secs(1));
    assert!(!device_view(&canbus, &clock, 2).0.has_fault());
    // Switching off: module 1 gets no life sign (it would switch its watchdog ON); its state is observed.
    bus.disable_watchdog().unwrap();
    for a in [1, 2] {
        let (state, _, online, _) = device_view(&canbus, &clock, a);
        assert!(!online, "module {a}");
        assert!(!state.has_fault(), "module {a}: {state}");
    }
    assert_eq!(bus.module(addr(1)).config_word().unwrap(), before, "Config word restored");
    clock.sleep(secs(1));
    assert!(!device_view(&canbus, &clock, 1).2, "still offline");
}

#[test]
fn a_lost_acknowledge_of_the_life_sign_is_found_out_when_switching_off() {
    let (clock, canbus, bus) = can_losing(&[1], false);
    let _me = clock.reserve_participant().enter();
    let err = bus.enable_watchdog(&addrs(&[1])).unwrap_err();
    assert!(matches!(err, Error::WatchdogUnconfirmed { address: A1, on: true, .. }), "{err}");
    // The toggle did arrive: the watchdog is online and the session refreshes it.
    assert!(device_view(&canbus, &clock, 1).2);
    clock.sleep(secs(1));
    assert!(!device_view(&canbus, &clock, 1).0.has_fault());
    // No blind second life sign: with the refresh stopped it expires, which names the module.
    let err = bus.disable_watchdog().unwrap_err();
    assert!(matches!(err, Error::WatchdogUnconfirmed { address: A1, on: false, .. }), "{err}");
    // The way back it names is the one every front end has (`motionlink powercube reset`, Python's reset()).
    assert!(err.to_string().contains("the module is halted, `reset` clears it"), "{err}");
    let (state, _, online, config) = device_view(&canbus, &clock, 1);
    assert!(online && state.contains(StateFlag::CommError) && state.contains(StateFlag::Halted), "{state}");
    assert!(config.contains(ConfigFlag::WatchdogEnable), "Config word left as is");
    // The manual's way back.
    assert!(bus.module(addr(1)).reset_and_release_watchdog().unwrap());
    assert!(!device_view(&canbus, &clock, 1).2);
    drop(bus);
    assert!(!device_view(&canbus, &clock, 1).3.contains(ConfigFlag::WatchdogEnable), "restored on drop");
}

#[test]
fn the_watchdog_refresh_keeps_absolute_deadlines() {
    let (clock, canbus, bus) = can(&[1]);
    let _me = clock.reserve_participant().enter();
    bus.enable_watchdog(&addrs(&[1])).unwrap();
    let due0 = bus.session(|s| s.watchdog_next_due()).unwrap();
    clock.sleep(Duration::from_millis(1_000));
    let due = bus.session(|s| s.watchdog_next_due()).unwrap();
    let periods = (due - due0).as_nanos() % Duration::from_millis(20).as_nanos();
    assert_eq!(periods, 0, "every refresh due a whole number of periods after the first: {due0} -> {due}");
    assert!(!device_view(&canbus, &clock, 1).0.has_fault());
    bus.disable_watchdog().unwrap();
}

#[test]
fn a_watchdog_release_whose_life_sign_is_lost_is_not_reported_released() {
    // A host died with the watchdog online: the module halted with STATE_COMM_ERROR.
    let (clock, canbus, bus) = can(&[1]);
    let _me = clock.reserve_participant().enter();
    bus.enable_watchdog(&addrs(&[1])).unwrap();
    kill(bus);
    clock.sleep(Duration::from_millis(200));
    assert!(device_view(&canbus, &clock, 1).0.contains(StateFlag::CommError));
    // The next session's life sign (which switches the watchdog offline) never reaches the module: the Reset
    // clears the error, and the watchdog, still online and unrefreshed, expires again 50 ms later.
    let link = LoseLifeSign { inner: canbus.connect(), outgoing: true, left: 1 };
    let bus = Client::with_link(PortLink::Can(Box::new(link)), clock.shared(), Config::can()).unwrap();
    let err = bus.module(addr(1)).reset_and_release_watchdog().unwrap_err();
    assert!(err.to_string().contains("expired again"), "{err}");
    let (state, _, online, _) = device_view(&canbus, &clock, 1);
    assert!(online && state.contains(StateFlag::CommError), "the module as the error says: {state}");
}

/// Guarded moves of several modules at once on one client, each run by a thread of its own: `(module,
/// target, cancel)`, where `cancel` cancels that move alone (its own token) once its wait has run that long.
/// The results, in the same order.
fn guarded_moves_at_once(
    clock: &ManualClock,
    bus: &Client,
    moves: &[(u8, f32, Option<Duration>)],
) -> Vec<Result<MoveReport, Error>> {
    use crate::session::{Guard, Op, Output};
    std::thread::scope(|scope| {
        let threads: Vec<_> = moves
            .iter()
            .map(|&(a, target, cancel)| {
                let ticket = clock.reserve_participant();
                scope.spawn(move || {
                    let _p = ticket.enter();
                    let token = motionlink_link::cancel::CancelToken::new();
                    let op = Op::MoveGuarded(addr(a), spec(target), Guard::Watchdog);
                    let mut progress = |p: &crate::session::Progress| {
                        if cancel.is_some_and(|after| p.elapsed >= after) {
                            token.cancel();
                        }
                    };
                    match bus.driver().run_with(op, &mut progress, Some(&token)) {
                        Ok(Output::Moved(report)) => Ok(report),
                        Ok(other) => panic!("module {a}: {other:?}"),
                        Err(e) => Err(e),
                    }
                })
            })
            .collect();
        threads.into_iter().map(|t| t.join().expect("a move's thread panicked")).collect()
    })
}

#[test]
fn two_guarded_moves_at_once_each_end_only_their_own_module() {
    // Module 1 arrives first: the end of its move halts and disarms module 1 alone, while module 2 goes on.
    let (clock, canbus, bus) = can(&[1, 2]);
    let before = [device_view(&canbus, &clock, 1).3, device_view(&canbus, &clock, 2).3];
    let results = guarded_moves_at_once(&clock, &bus, &[(1, 0.3, None), (2, 1.2, None)]);
    let _me = clock.reserve_participant().enter();
    for ((a, target), result) in [(1u8, 0.3f32), (2, 1.2)].into_iter().zip(&results) {
        let report = result.as_ref().unwrap_or_else(|e| panic!("module {a}: {e}"));
        assert!((report.reached.value() - target).abs() <= 0.001, "module {a}: {report:?}");
        assert!(report.verified, "module {a}: {report:?}");
    }
    assert!(!bus.watchdog_served(), "no watchdog left to serve");
    clock.sleep(secs(1));
    for a in [1, 2] {
        let (state, position, online, config) = device_view(&canbus, &clock, a);
        assert!(!state.contains(StateFlag::Halted) && !state.has_fault(), "module {a}: {state}");
        assert!(!online, "module {a}: its watchdog switched off once");
        assert_eq!(config, before[usize::from(a - 1)], "module {a}: the Config word as it was");
        assert!((position - if a == 1 { 0.3 } else { 1.2 }).abs() <= 0.001, "module {a}: {position}");
    }
    assert_eq!(bus.close().map_err(|e| e.to_string()), Ok(vec![]));
}

#[test]
fn two_guarded_moves_cancelled_at_once_halt_both_and_leave_no_watchdog_online() {
    // What Ctrl-C does to two threads moving: each move halts its module and switches its own watchdog off,
    // once (a second life sign would switch it on again, and it would expire 50 ms later).
    let (clock, canbus, bus) = can(&[1, 2]);
    let before = [device_view(&canbus, &clock, 1).3, device_view(&canbus, &clock, 2).3];
    let cancel = Some(Duration::from_millis(300));
    let results = guarded_moves_at_once(&clock, &bus, &[(1, 1.2, cancel), (2, 1.5, cancel)]);
    let _me = clock.reserve_participant().enter();
    for (a, result) in [1u8, 2].into_iter().zip(&results) {
        let address = addr(a);
        assert!(
            matches!(result, Err(Error::Cancelled { address: at, stop: StopOutcome::Confirmed }) if *at == address),
            "module {a}: {result:?}"
        );
    }
    assert!(!bus.watchdog_served());
    for a in [1, 2] {
        let (state, _, online, config) = device_view(&canbus, &clock, a);
        assert!(state.contains(StateFlag::Halted) && !state.contains(StateFlag::Motion), "module {a}: {state}");
        assert!(!online, "module {a}: watchdog offline");
        assert_eq!(config, before[usize::from(a - 1)], "module {a}: the Config word as it was");
    }
    // Nothing left to expire: a second later, no STATE_COMM_ERROR.
    clock.sleep(secs(1));
    for a in [1, 2] {
        let (state, _, online, _) = device_view(&canbus, &clock, a);
        assert!(!online && !state.contains(StateFlag::CommError), "module {a}: {state}");
    }
    // The moves halted their modules themselves: the close has nothing left to halt, and says so truly.
    assert_eq!(bus.close().map_err(|e| e.to_string()), Ok(vec![]));
    clock.sleep(secs(1));
    for a in [1, 2] {
        let (state, _, online, _) = device_view(&canbus, &clock, a);
        assert!(!online && !state.contains(StateFlag::CommError), "module {a} after the close: {state}");
    }
}

#[test]
fn a_guarded_move_cancelled_while_another_runs_leaves_the_other_going_to_its_target() {
    let (clock, canbus, bus) = can(&[1, 2]);
    let results = guarded_moves_at_once(&clock, &bus, &[(1, 1.2, Some(Duration::from_millis(300))), (2, 0.9, None)]);
    let _me = clock.reserve_participant().enter();
    assert!(matches!(results[0], Err(Error::Cancelled { address: A1, stop: StopOutcome::Confirmed })), "{results:?}");
    let report = results[1].as_ref().unwrap_or_else(|e| panic!("module 2: {e}"));
    assert!((report.reached.value() - 0.9).abs() <= 0.001 && report.verified, "{report:?}");
    clock.sleep(secs(1));
    let (state, _, online, _) = device_view(&canbus, &clock, 1);
    assert!(state.contains(StateFlag::Halted) && !online && !state.contains(StateFlag::CommError), "{state}");
    let (state, position, online, _) = device_view(&canbus, &clock, 2);
    assert!(!state.contains(StateFlag::Halted) && !state.has_fault() && !online, "{state}");
    assert!((position - 0.9).abs() <= 0.001, "{position}");
    assert_eq!(bus.close().map_err(|e| e.to_string()), Ok(vec![]));
}

#[test]
fn a_second_guarded_motion_of_a_module_is_refused_while_the_first_runs() {
    // Two guarded motions of one module would share its watchdog (the first to end would switch it off under
    // the other) and fight over the module: the second is refused before any command goes to the module.
    let (clock, canbus, bus) = can(&[1]);
    let results = guarded_moves_at_once(&clock, &bus, &[(1, 1.2, None), (1, 0.2, None)]);
    let _me = clock.reserve_participant().enter();
    let (done, refused): (Vec<_>, Vec<_>) = results.iter().partition(|r| r.is_ok());
    assert_eq!((done.len(), refused.len()), (1, 1), "{results:?}");
    let err = refused[0].as_ref().unwrap_err();
    assert!(matches!(err, Error::NotSupported(_)) && err.is_usage(), "{err}");
    assert!(err.to_string().contains("a guarded motion of module 1 is under way"), "{err}");
    let reached = done[0].as_ref().unwrap().reached.value();
    clock.sleep(secs(1));
    let (state, position, online, _) = device_view(&canbus, &clock, 1);
    assert!(!state.contains(StateFlag::Halted) && !state.has_fault() && !online, "{state}");
    assert!((position - reached).abs() <= 0.001, "{position} {reached}");
}

#[test]
fn a_guarded_motion_leaves_a_watchdog_the_user_armed_as_it_was() {
    // The guard switches off only what it switched on: module 1's watchdog was online before it (the user's
    // enable_watchdog), and stays so, as does module 2's.
    let (clock, canbus, bus) = can(&[1, 2]);
    let _me = clock.reserve_participant().enter();
    bus.enable_watchdog(&addrs(&[1, 2])).unwrap();
    let report = bus.module(addr(1)).move_to_guarded(&spec(0.3), crate::client::Guard::Watchdog, &mut |_| {}).unwrap();
    assert!((report.reached.value() - 0.3).abs() <= 0.001);
    assert!(bus.watchdog_served());
    clock.sleep(secs(1));
    for a in [1, 2] {
        let (state, _, online, _) = device_view(&canbus, &clock, a);
        assert!(online && !state.has_fault() && !state.contains(StateFlag::Halted), "module {a}: {state}");
    }
    bus.disable_watchdog().unwrap();
    clock.sleep(secs(1));
    for a in [1, 2] {
        let (state, _, online, _) = device_view(&canbus, &clock, a);
        assert!(!online && !state.has_fault(), "module {a}: {state}");
    }
}

#[test]
fn disable_watchdog_leaves_the_watchdog_of_a_guarded_motion_under_way_to_its_end() {
    let (clock, canbus, bus) = can(&[1, 2]);
    let (moved, online_meanwhile) = std::thread::scope(|scope| {
        let (mover, other) = (clock.reserve_participant(), clock.reserve_participant());
        let bus = &bus;
        let moving = scope.spawn(move || {
            let _p = mover.enter();
            bus.module(addr(1)).move_to_guarded(&spec(1.2), crate::client::Guard::Watchdog, &mut |_| {})
        });
        let (clock, canbus) = (&clock, &canbus);
        let disabling = scope.spawn(move || {
            let _p = other.enter();
            bus.enable_watchdog(&addrs(&[2])).unwrap();
            clock.sleep(Duration::from_millis(500));
            bus.disable_watchdog().unwrap();
            // Module 2's (the caller's) is off; module 1's stays with its motion.
            (device_view(canbus, clock, 1).2, device_view(canbus, clock, 2).2)
        });
        (moving.join().unwrap(), disabling.join().unwrap())
    });
    let _me = clock.reserve_participant().enter();
    assert_eq!(online_meanwhile, (true, false));
    let report = moved.unwrap();
    assert!((report.reached.value() - 1.2).abs() <= 0.001, "{report:?}");
    clock.sleep(secs(1));
    for a in [1, 2] {
        let (state, _, online, _) = device_view(&canbus, &clock, a);
        assert!(!online && !state.has_fault() && !state.contains(StateFlag::Halted), "module {a}: {state}");
    }
}

#[test]
fn halting_what_was_started_keeps_a_module_another_operation_sets_moving_meanwhile() {
    // `halt_started` halts module 1 (its telegrams take some 50 ms at 9600 baud); 10 ms into it, another
    // thread sets module 2 in motion: module 2 stays among those the session started, and the close halts it.
    let (clock, host, bus, _) = rs232(&[1, 2]);
    {
        let _me = clock.reserve_participant().enter();
        bus.module(addr(2)).kind().unwrap();
        bus.module(addr(1)).motion(Motion::FVel { vel: Velocity::native(0.2) }, AckKind::Simple).unwrap();
        clock.sleep(Duration::from_millis(200));
    }
    std::thread::scope(|scope| {
        let (halter, mover) = (clock.reserve_participant(), clock.reserve_participant());
        let (bus, clock) = (&bus, &clock);
        let halting = scope.spawn(move || {
            let _p = halter.enter();
            bus.halt_started()
        });
        let moving = scope.spawn(move || {
            let _p = mover.enter();
            clock.sleep(Duration::from_millis(10));
            bus.module(addr(2)).motion(Motion::FVel { vel: Velocity::native(0.2) }, AckKind::Simple)
        });
        halting.join().unwrap().unwrap();
        moving.join().unwrap().unwrap();
    });
    let _me = clock.reserve_participant().enter();
    assert!(sim_module(&host, 1).0.contains(StateFlag::Halted));
    assert!(sim_module(&host, 2).0.contains(StateFlag::Motion));
    assert_eq!(bus.started(), vec![2], "module 2 is moving");
    assert_eq!(bus.close().map_err(|e| e.to_string()), Ok(vec![addr(2)]));
    let state = sim_module(&host, 2).0;
    assert!(state.contains(StateFlag::Halted) && !state.contains(StateFlag::Motion), "{state}");
}
