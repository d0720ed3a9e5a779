//! The client against the emulator, in-process, with an auto-advancing manual clock.

use super::*;
use crate::model::{Amperes, Velocity};
use crate::sim::{SimBus, SimConfig};
use motionlink_link::can::{CanBus, CanBusConfig};
use motionlink_link::clock::{Clock, ManualClock};
use motionlink_link::pipe::{Direction, EmulatorHost, FaultControl, PipeConfig};

fn rs232(addresses: &[u8]) -> (ManualClock, EmulatorHost<SimBus>, Bus, FaultControl) {
    let clock = ManualClock::new_auto();
    let sim = SimBus::new(&SimConfig::with_addresses(addresses).unwrap());
    let host = EmulatorHost::new(sim, clock.shared(), PipeConfig::paced(9_600));
    let (link, faults) = host.connect();
    let bus = Bus::rs232(Box::new(link), clock.shared(), BusConfig::rs232());
    (clock, host, bus, faults)
}

fn can(addresses: &[u8]) -> (ManualClock, CanBus<SimBus>, Bus) {
    let clock = ManualClock::new_auto();
    let sim = SimBus::new_can(&SimConfig::with_addresses(addresses).unwrap());
    let canbus = CanBus::with_emulator(sim, clock.shared(), CanBusConfig::paced(1_000_000));
    let bus = Bus::can(Box::new(canbus.connect()), clock.shared(), BusConfig::can());
    (clock, canbus, bus)
}

fn secs(s: u64) -> Duration {
    Duration::from_secs(s)
}

#[test]
fn scan_finds_every_module_on_rs232_and_can() {
    let (clock, _host, bus, _) = rs232(&[1, 17, 31]);
    let _me = clock.reserve_participant().enter();
    let found = bus.scan().unwrap();
    assert_eq!(found.iter().map(|m| m.address).collect::<Vec<_>>(), vec![1, 17, 31]);
    assert_eq!(found[1].serial, 1017);
    assert_eq!(found[1].version, CubeVersion(0x4634));
    assert_eq!(found[1].kind, ModuleKind::Rotary);
    assert!(!found[1].state.contains(StateFlag::HomeOk));
    drop(bus);

    let (clock, _canbus, bus) = can(&[2, 5]);
    let _me = clock.reserve_participant().enter();
    let t0 = clock.now();
    let found = bus.scan().unwrap();
    assert_eq!(found.iter().map(|m| m.address).collect::<Vec<_>>(), vec![2, 5]);
    // On CAN the 31 questions go out at once: the scan takes one timeout, not 31.
    assert!(clock.now() - t0 < Duration::from_millis(200), "{:?}", clock.now() - t0);
}

#[test]
fn every_parameter_reads_and_every_writable_one_writes() {
    let (clock, host, bus, faults) = rs232(&[1]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(1).unwrap();
    for p in Param::ALL {
        if p.access().readable() {
            let v = m.get(*p).unwrap_or_else(|e| panic!("{p}: {e}"));
            assert_eq!(v.data_type(), p.data_type(), "{p}");
        } else {
            assert!(matches!(m.get(*p), Err(Error::Model(ModelError::NotReadable(_)))));
        }
    }
    for p in Param::ALL.iter().filter(|p| p.access().writable()) {
        let value = match p.data_type() {
            crate::model::DataType::F32 => Value::F32(0.5),
            crate::model::DataType::U32 => Value::U32(0),
            crate::model::DataType::I32 => Value::I32(100),
            crate::model::DataType::U16 => Value::U16(1),
            crate::model::DataType::I16 => Value::I16(1),
            _ => continue,
        };
        m.set(*p, value).unwrap_or_else(|e| panic!("{p}: {e}"));
    }
    assert_eq!(m.get(Param::HomeOffset).unwrap(), Value::F32(0.5));
    assert_eq!(m.get(Param::ActIMinPos).unwrap(), Value::I32(100));
    // Access and types are checked before anything is sent.
    let before = faults.bytes_sent(Direction::HostToDevice);
    assert!(matches!(m.set(Param::ActPos, Value::F32(0.0)), Err(Error::Model(ModelError::NotWritable(_)))));
    assert!(matches!(m.set(Param::MaxVel, Value::U32(1)), Err(Error::Model(ModelError::Value(_)))));
    assert_eq!(faults.bytes_sent(Direction::HostToDevice), before);
    assert!(host.with_device(|d| d.stats().not_understood) == 0);
}

#[test]
fn home_and_move_with_progress() {
    let (clock, host, bus, _) = rs232(&[1]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(1).unwrap();
    m.home().unwrap();
    let mut polls = 0;
    let s = m.wait_home(secs(10), &mut |_| polls += 1).unwrap();
    assert!(s.contains(StateFlag::HomeOk));
    assert!(polls >= 2, "{polls}");
    let ramp = Ramp { vel: Velocity(0.5), acc: Acceleration(1.0) };
    m.move_ramp(Position(-1.0), Some(ramp)).unwrap();
    let mut seen = Vec::new();
    let t0 = clock.now();
    m.wait_ramp_end(secs(10), &mut |p| seen.push(p.position.0)).unwrap();
    // 1 rad at 0.5 rad/s, 1 rad/s²: 2.5 s.
    let took = (clock.now() - t0).as_secs_f64();
    assert!((2.4..2.7).contains(&took), "{took}");
    assert!(seen.windows(2).all(|w| w[1] <= w[0] + 1e-6), "monotonic progress");
    assert!((m.position().unwrap().0 + 1.0).abs() < 1e-4);
    assert!(bus.started().is_empty(), "the motion was seen to end");
    assert!(host.with_device(|d| d.module(1).unwrap().state().contains(StateFlag::RampEnd)));
    use crate::model::Acceleration;
}

#[test]
fn device_errors_name_their_flags() {
    let (clock, _host, bus, _) = rs232(&[1]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(1).unwrap();
    m.home().unwrap();
    m.wait_home(secs(10), &mut |_| {}).unwrap();
    m.set(Param::MaxPos, Value::F32(0.2)).unwrap();
    m.motion(Motion::FVel { vel: Velocity(0.5) }, AckKind::Simple).unwrap();
    let err = m.wait_motion_end(secs(10), &mut |_| {}).unwrap_err();
    match &err {
        Error::Device { address: 1, state } => assert!(state.contains(StateFlag::BeyondSoft)),
        other => panic!("{other}"),
    }
    assert!(err.is_device() && !err.is_transport());
    assert!(err.to_string().contains("STATE_BEYOND_SOFT"), "{err}");
    // Halted: motions are ignored, the wait says so; a reset clears it.
    m.reset().unwrap();
    m.halt().unwrap();
    m.move_ramp(Position(0.0), None).unwrap();
    assert!(matches!(m.wait_motion_end(secs(1), &mut |_| {}), Err(Error::Halted { .. })));
    m.reset().unwrap();
    assert!(!m.state().unwrap().contains(StateFlag::Halted));
}

#[test]
fn timeouts_retry_reads_only() {
    let (clock, _host, bus, faults) = rs232(&[1]);
    let _me = clock.reserve_participant().enter();
    // Nobody at 9: the read is tried 3 times, each waiting the reply timeout.
    let t0 = clock.now();
    let sent0 = faults.bytes_sent(Direction::HostToDevice);
    let err = bus.module(9).unwrap().position().unwrap_err();
    assert!(matches!(err, Error::Timeout { address: 9, .. }) && err.is_transport(), "{err}");
    assert!(err.to_string().contains("did not answer GetExtended ActPos"), "{err}");
    let frame = 8; // STX TELID(2) 0a 3c BCC ETX + escaping: 7 or 8
    let sent = faults.bytes_sent(Direction::HostToDevice) - sent0;
    assert!((3 * 7..=3 * frame).contains(&sent), "{sent}");
    assert!(clock.now() - t0 >= Duration::from_millis(600));
    // A lost acknowledge of a read: the second try answers.
    faults.drop_next(Direction::DeviceToHost, 3);
    assert!(bus.module(1).unwrap().position().is_ok());
    // A lost acknowledge of a write is not repeated: the caller learns it.
    let sent0 = faults.bytes_sent(Direction::HostToDevice);
    faults.drop_next(Direction::DeviceToHost, 3);
    let err = bus.module(1).unwrap().set(Param::TargetVel, Value::F32(0.2)).unwrap_err();
    assert!(matches!(err, Error::Timeout { .. }), "{err}");
    let sent = faults.bytes_sent(Direction::HostToDevice) - sent0;
    assert!(sent <= 11, "one frame only: {sent}");
    // Late replies of the timed-out request do not confuse the next one.
    assert!(bus.module(1).unwrap().state().is_ok());
}

#[test]
fn a_corrupt_answer_is_an_error_and_reads_recover() {
    let (clock, _host, bus, faults) = rs232(&[1]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(1).unwrap();
    // Flip a data bit of the acknowledge of a write: BCC mismatch, reported as corrupt.
    faults.inject(
        Direction::DeviceToHost,
        faults.bytes_sent(Direction::DeviceToHost) + 4,
        motionlink_link::pipe::Fault::Corrupt { xor: 0x01 },
    );
    let err = m.set(Param::TargetAcc, Value::F32(0.5)).unwrap_err();
    assert!(matches!(err, Error::Corrupt { .. }) && err.is_transport(), "{err}");
    // A read with a corrupt answer is simply read again.
    faults.inject(
        Direction::DeviceToHost,
        faults.bytes_sent(Direction::DeviceToHost) + 4,
        motionlink_link::pipe::Fault::Corrupt { xor: 0x01 },
    );
    assert!(m.state().is_ok());
}

#[test]
fn the_watchdog_is_served_in_the_background_and_trips_when_the_session_dies() {
    let (clock, host, bus) = can_host();
    let _me = clock.reserve_participant().enter();
    bus.enable_watchdog(&[1, 2]).unwrap();
    assert!(host.with_device(|d| d.module(1).unwrap().watchdog_online()).unwrap());
    let m = bus.module(1).unwrap();
    m.home().unwrap();
    m.wait_home(secs(10), &mut |_| {}).unwrap();
    // Ten seconds of device time with the test thread mostly asleep: the background thread refreshes.
    clock.sleep(secs(10));
    for a in [1, 2] {
        let s = bus.module(a).unwrap().state().unwrap();
        assert!(!s.contains(StateFlag::CommError), "{s}");
    }
    assert!(bus.watchdog_served());
    drop(bus);
    clock.sleep(Duration::from_millis(100));
    let s = host.with_device(|d| d.module(2).unwrap().state()).unwrap();
    assert!(s.contains(StateFlag::CommError) && s.contains(StateFlag::Halted), "{s}");
}

fn can_host() -> (ManualClock, CanBus<SimBus>, Bus) {
    can(&[1, 2])
}

#[test]
fn disabling_the_watchdog_switches_it_off_in_the_modules() {
    let (clock, host, bus, _) = rs232(&[1]);
    let _me = clock.reserve_participant().enter();
    bus.enable_watchdog(&[1]).unwrap();
    clock.sleep(secs(2));
    bus.disable_watchdog().unwrap();
    assert!(!host.with_device(|d| d.module(1).unwrap().watchdog_online()));
    clock.sleep(secs(2));
    assert!(!bus.module(1).unwrap().state().unwrap().contains(StateFlag::CommError));
}

#[test]
fn dropping_the_session_halts_what_it_started() {
    let (clock, host, bus, _) = rs232(&[1, 2]);
    let _me = clock.reserve_participant().enter();
    bus.module(1).unwrap().motion(Motion::FVel { vel: Velocity(0.3) }, AckKind::Simple).unwrap();
    bus.module(2).unwrap().motion(Motion::FRamp { pos: Position(0.06) }, AckKind::Simple).unwrap();
    clock.sleep(secs(1));
    drop(bus);
    host.with_device(|d| {
        let s = d.module(1).unwrap().state();
        assert!(s.contains(StateFlag::Halted) && !s.contains(StateFlag::Motion), "{s}");
        // Module 2 had already stopped: it is left alone.
        assert!(!d.module(2).unwrap().state().contains(StateFlag::Halted));
    });
}

#[test]
fn cancelling_a_wait_halts_the_motion() {
    let (clock, host, bus, _) = rs232(&[1]);
    let _me = clock.reserve_participant().enter();
    let token = CancelToken::new();
    bus.set_cancel_token(token.clone());
    let m = bus.module(1).unwrap();
    m.motion(Motion::FCur { cur: Amperes(1.0) }, AckKind::Simple).unwrap();
    let err = m
        .wait_motion_end(secs(60), &mut |p| {
            if p.elapsed > Duration::from_millis(500) {
                token.cancel();
            }
        })
        .unwrap_err();
    assert!(matches!(err, Error::Cancelled { address: 1 }), "{err}");
    assert!(host.with_device(|d| d.module(1).unwrap().state().contains(StateFlag::Halted)));
    // A wait that times out halts too.
    token.reset();
    m.reset().unwrap();
    m.motion(Motion::FVel { vel: Velocity(0.1) }, AckKind::Simple).unwrap();
    let err = m.wait_motion_end(Duration::from_millis(300), &mut |_| {}).unwrap_err();
    assert!(matches!(err, Error::WaitTimeout { .. }), "{err}");
    assert!(host.with_device(|d| d.module(1).unwrap().state().contains(StateFlag::Halted)));
}

#[test]
fn on_can_many_modules_are_polled_in_one_round() {
    let addresses: Vec<u8> = (1..=6).collect();
    let (clock, _canbus, bus) = can(&addresses);
    let _me = clock.reserve_participant().enter();
    let t0 = clock.now();
    bus.module(3).unwrap().position().unwrap();
    let one = clock.now() - t0;
    let t0 = clock.now();
    let all = bus.positions(&addresses);
    let six = clock.now() - t0;
    assert!(all.iter().all(Result::is_ok));
    // Request (63 bits) + acknowledge (95 bits) at 1 Mbit/s: 158 µs for one, 948 µs for six back to back.
    assert_eq!(one, Duration::from_micros(158));
    assert_eq!(six, Duration::from_micros(948));
    // One missing module does not hold the others up beyond one timeout (and reads are retried).
    let t0 = clock.now();
    let r = bus.positions(&[1, 9, 2]);
    assert!(r[0].is_ok() && r[2].is_ok() && matches!(r[1], Err(Error::Timeout { address: 9, .. })));
    assert!(clock.now() - t0 < Duration::from_millis(200));
}

#[test]
fn six_joints_in_a_control_loop_with_the_watchdog() {
    let addresses: Vec<u8> = (1..=6).collect();
    let (clock, canbus, bus) = can(&addresses);
    let _me = clock.reserve_participant().enter();
    bus.broadcast(Broadcast::Home).unwrap();
    for a in &addresses {
        bus.module(*a).unwrap().wait_home(secs(10), &mut |_| {}).unwrap();
    }
    bus.enable_watchdog(&addresses).unwrap();
    // 100 cycles of 10 ms: read all positions, command a step towards 0.2 rad.
    let period = Duration::from_millis(10);
    let mut next = clock.now();
    for cycle in 1..=100u32 {
        let positions = bus.positions(&addresses);
        assert!(positions.iter().all(Result::is_ok));
        let target = 0.2 * cycle as f32 / 100.0;
        let reqs: Vec<(u8, Request)> = addresses
            .iter()
            .map(|a| (*a, Request::Motion(Motion::FStep { pos: Position(target), time: Millis(10) }, AckKind::Simple)))
            .collect();
        assert!(bus.request_many(&reqs).iter().all(Result::is_ok));
        next += period;
        clock.sleep_until(next);
    }
    clock.sleep(Duration::from_millis(50));
    for p in bus.positions(&addresses) {
        assert!((p.unwrap().0 - 0.2).abs() < 1e-4);
    }
    for a in &addresses {
        assert!(!bus.module(*a).unwrap().state().unwrap().has_fault());
    }
    assert!(canbus.frames_carried() > 2_400);
}

#[test]
fn extended_acknowledges_and_steps() {
    let (clock, _canbus, bus) = can(&[4]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(4).unwrap();
    let ext = m.motion(Motion::IRamp { pos: Ticks(1000) }, AckKind::Extended).unwrap().unwrap();
    assert!(matches!(ext.position, crate::model::AckPosition::Ticks(_)));
    assert!(ext.state.contains(crate::model::ShortFlag::NotOk), "not homed");
    m.wait_motion_end(secs(10), &mut |_| {}).unwrap();
    assert_eq!(m.position_ticks().unwrap(), Ticks(1000));
    m.istep(Ticks(0), Millis(100)).unwrap();
    m.wait_motion_end(secs(10), &mut |_| {}).unwrap();
    assert_eq!(m.position_ticks().unwrap(), Ticks(0));
    let (_, short, _) = m.position_state_dio().unwrap();
    assert!(!short.contains(crate::model::ShortFlag::Motion));
    assert!(matches!(m.set(Param::Config, Value::U32(0x0400_0000)), Err(Error::Unsupported(_))));
}

#[test]
fn a_broken_line_is_a_transport_error() {
    let (clock, _host, bus, faults) = rs232(&[1]);
    let _me = clock.reserve_participant().enter();
    faults.disconnect();
    let err = bus.module(1).unwrap().state().unwrap_err();
    assert!(matches!(err, Error::Link(ref l) if l.is_disconnect()) && err.is_transport(), "{err}");
    assert!(matches!(bus.module(0), Err(Error::InvalidAddress(0))));
}

/// The host dies: no more refresh, no halt, no goodbye (what SIGKILL, a power loss or a pulled adapter does
/// to a session).
fn kill(bus: Bus) {
    lock_mutex(&bus.inner.duty).serving = false;
    bus.stop_watchdog_thread();
    lock_mutex(&bus.inner.started).clear();
    drop(bus);
}

/// State and position of module `a` at the clock's time, straight from the emulator.
fn device_view(canbus: &CanBus<SimBus>, clock: &ManualClock, a: u8) -> (CubeState, f32, bool, ConfigWord) {
    canbus
        .with_device(|d| {
            d.update(clock.now());
            let m = d.module(a).unwrap();
            (m.state(), m.position().0, m.watchdog_online(), m.config_word())
        })
        .unwrap()
}

#[test]
fn arming_the_watchdog_for_a_motion_leaves_the_modules_as_it_found_them() {
    let (clock, canbus, bus) = can(&[1, 2]);
    let _me = clock.reserve_participant().enter();
    assert!(bus.watchdog_reliable());
    let (m1, m2) = (bus.module(1).unwrap(), bus.module(2).unwrap());
    let before1 = m1.config_word().unwrap();
    assert!(!before1.contains(ConfigFlag::WatchdogEnable));
    // Module 2's user keeps the flag set: it must stay set.
    let before2 = m2.config_word().unwrap().with(ConfigFlag::WatchdogEnable);
    m2.set(Param::Config, Value::U32(before2.0)).unwrap();

    bus.enable_watchdog(&[1, 2]).unwrap();
    assert!(m1.config_word().unwrap().contains(ConfigFlag::WatchdogEnable));
    assert!(device_view(&canbus, &clock, 1).2 && device_view(&canbus, &clock, 2).2, "online");
    m1.home().unwrap();
    m1.wait_home(secs(10), &mut |_| {}).unwrap();
    m1.move_ramp(Position(0.5), Some(Ramp { vel: Velocity(0.5), acc: Acceleration(1.0) })).unwrap();
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
    assert!((m1.position().unwrap().0 - 0.5).abs() < 1e-4);
    // Disabling twice is harmless.
    bus.disable_watchdog().unwrap();
    assert_eq!(m1.config_word().unwrap(), before1);
    use crate::model::Acceleration;
}

#[test]
fn a_host_that_dies_while_moving_is_stopped_by_the_watchdog_within_50_ms() {
    let (clock, canbus, bus) = can(&[1]);
    let _me = clock.reserve_participant().enter();
    bus.enable_watchdog(&[1]).unwrap();
    let m = bus.module(1).unwrap();
    m.move_ramp(Position(2.0), Some(Ramp { vel: Velocity(0.2), acc: Acceleration(1.0) })).unwrap();
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
    let bus = Bus::can(Box::new(canbus.connect()), clock.shared(), BusConfig::can());
    let m = bus.module(1).unwrap();
    let err = bus.enable_watchdog(&[1]).unwrap_err();
    assert!(matches!(err, Error::Device { address: 1, state } if state.contains(StateFlag::CommError)), "{err}");
    assert!(device_view(&canbus, &clock, 1).2, "still online");
    assert!(m.reset_and_release_watchdog().unwrap());
    clock.sleep(secs(1));
    let (state, _, online, _) = device_view(&canbus, &clock, 1);
    assert!(!online && !state.contains(StateFlag::Halted) && !state.contains(StateFlag::CommError), "{state}");
    // A reset of a module whose watchdog did not expire is a plain reset.
    assert!(!m.reset_and_release_watchdog().unwrap());
    // And the watchdog arms again (the Config flag the dead session left is kept).
    bus.enable_watchdog(&[1]).unwrap();
    bus.disable_watchdog().unwrap();
    assert!(m.config_word().unwrap().contains(ConfigFlag::WatchdogEnable));
    use crate::model::Acceleration;
}

#[test]
fn a_watchdog_another_host_serves_is_not_released() {
    let (clock, canbus, host_a) = can(&[1]);
    let _me = clock.reserve_participant().enter();
    host_a.enable_watchdog(&[1]).unwrap();
    // Three refreshes in a row are lost: the module halts, though host A is alive and keeps refreshing.
    canbus.drop_next_to_device(3);
    clock.sleep(Duration::from_millis(200));
    assert!(device_view(&canbus, &clock, 1).0.contains(StateFlag::CommError));
    let host_b = Bus::can(Box::new(canbus.connect()), clock.shared(), BusConfig::can());
    assert!(!host_b.module(1).unwrap().reset_and_release_watchdog().unwrap(), "host A serves it");
    clock.sleep(secs(1));
    let (state, _, online, _) = device_view(&canbus, &clock, 1);
    assert!(online, "host B did not toggle host A's watchdog");
    assert!(!state.contains(StateFlag::CommError) && !state.contains(StateFlag::Halted), "{state}");
    drop(host_b);
    host_a.disable_watchdog().unwrap();
}

#[test]
fn rs232_cannot_rely_on_the_watchdog() {
    let (clock, _host, bus, _) = rs232(&[1]);
    let _me = clock.reserve_participant().enter();
    assert!(!bus.watchdog_reliable());
}
