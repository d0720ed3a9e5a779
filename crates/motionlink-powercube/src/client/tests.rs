//! The client against the emulator, in-process, with an auto-advancing manual clock.

use super::*;
use crate::model::{Amperes, Velocity};
use crate::sim::{SimBus, SimConfig};
use crate::wire::ACK_OK;
use motionlink_link::can::{CanBus, CanBusConfig};
use motionlink_link::clock::{Clock, ManualClock};
use motionlink_link::pipe::{Direction, EmulatorHost, FaultControl, PipeConfig};

fn rs232(addresses: &[u8]) -> (ManualClock, EmulatorHost<SimBus>, Bus, FaultControl) {
    rs232_with(addresses, BusConfig::rs232())
}

fn rs232_with(addresses: &[u8], config: BusConfig) -> (ManualClock, EmulatorHost<SimBus>, Bus, FaultControl) {
    let clock = ManualClock::new_auto();
    let sim = SimBus::new(&SimConfig::with_addresses(addresses).unwrap());
    let host = EmulatorHost::new(sim, clock.shared(), PipeConfig::paced(9_600));
    let (link, faults) = host.connect();
    let bus = Bus::rs232(Box::new(link), clock.shared(), config);
    (clock, host, bus, faults)
}

/// The infos of a scan in which every module could be read.
fn scan_infos(bus: &Bus) -> Vec<ModuleInfo> {
    bus.scan()
        .unwrap()
        .into_iter()
        .map(|e| e.info.unwrap_or_else(|err| panic!("module {}: {err}", e.address)))
        .collect()
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
    let found = scan_infos(&bus);
    assert_eq!(found.iter().map(|m| m.address).collect::<Vec<_>>(), vec![1, 17, 31]);
    assert_eq!(found[1].serial, 1017);
    assert_eq!(found[1].version, CubeVersion(0x4634));
    assert_eq!(found[1].kind, ModuleKind::Rotary);
    assert!(!found[1].state.contains(StateFlag::HomeOk));
    drop(bus);

    let (clock, _canbus, bus) = can(&[2, 5]);
    let _me = clock.reserve_participant().enter();
    let t0 = clock.now();
    let found = scan_infos(&bus);
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
    let ramp = Ramp { vel: Velocity::native(0.5), acc: Acceleration::native(1.0) };
    m.move_ramp(Position::native(-1.0), Some(ramp)).unwrap();
    let mut seen = Vec::new();
    let t0 = clock.now();
    m.wait_ramp_end(secs(10), &mut |p| seen.push(p.position.value())).unwrap();
    // 1 rad at 0.5 rad/s, 1 rad/s²: 2.5 s.
    let took = (clock.now() - t0).as_secs_f64();
    assert!((2.4..2.7).contains(&took), "{took}");
    assert!(seen.windows(2).all(|w| w[1] <= w[0] + 1e-6), "monotonic progress");
    assert!((m.position().unwrap().value() + 1.0).abs() < 1e-4);
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
    m.motion(Motion::FVel { vel: Velocity::native(0.5) }, AckKind::Simple).unwrap();
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
    m.move_ramp(Position::native(0.0), None).unwrap();
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
    kill(bus);
    clock.sleep(Duration::from_millis(100));
    let s = host.with_device(|d| d.module(2).unwrap().state()).unwrap();
    assert!(s.contains(StateFlag::CommError) && s.contains(StateFlag::Halted), "{s}");
}

fn can_host() -> (ManualClock, CanBus<SimBus>, Bus) {
    can(&[1, 2])
}

#[test]
fn disabling_the_watchdog_switches_it_off_in_the_modules() {
    // RS232 with the opt-in: the emulator takes address 0 as every module.
    let (clock, host, bus, _) = rs232_with(&[1], BusConfig { watchdog_on_rs232: true, ..BusConfig::rs232() });
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
    bus.module(1).unwrap().motion(Motion::FVel { vel: Velocity::native(0.3) }, AckKind::Simple).unwrap();
    bus.module(2).unwrap().motion(Motion::FRamp { pos: Position::native(0.06) }, AckKind::Simple).unwrap();
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
    assert!(matches!(err, Error::Cancelled { address: 1, stop: StopOutcome::Confirmed }), "{err}");
    assert!(err.to_string().contains("the module acknowledged the halt"), "{err}");
    assert!(host.with_device(|d| d.module(1).unwrap().state().contains(StateFlag::Halted)));
    // A wait that times out halts too.
    token.reset();
    m.reset().unwrap();
    m.motion(Motion::FVel { vel: Velocity::native(0.1) }, AckKind::Simple).unwrap();
    let err = m.wait_motion_end(Duration::from_millis(300), &mut |_| {}).unwrap_err();
    assert!(matches!(err, Error::WaitTimeout { stop: StopOutcome::Confirmed, .. }), "{err}");
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
    // Request (63 bits) + acknowledge (95 bits) at 1 Mbit/s, each with its own stuff bits: about 160 µs for
    // one, six of those back to back for six.
    use crate::wire::can::{to_frame, Role};
    let wire_time = |a: u8| {
        let get = to_frame(Role::Get(a), &Request::Get(Param::ActPos).encode());
        let ack = to_frame(Role::Ack(a), &Reply::Get(Param::ActPos, Value::F32(0.05)).encode());
        Duration::from_micros(u64::from(get.bit_length_stuffed() + ack.bit_length_stuffed()))
    };
    assert_eq!(one, wire_time(3));
    assert!((Duration::from_micros(158)..Duration::from_micros(190)).contains(&one), "{one:?}");
    assert_eq!(six, addresses.iter().map(|a| wire_time(*a)).sum::<Duration>());
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
            .map(|a| {
                (
                    *a,
                    Request::Motion(Motion::FStep { pos: Position::native(target), time: Millis(10) }, AckKind::Simple),
                )
            })
            .collect();
        assert!(bus.request_many(&reqs).iter().all(Result::is_ok));
        next += period;
        clock.sleep_until(next);
    }
    clock.sleep(Duration::from_millis(50));
    for p in bus.positions(&addresses) {
        assert!((p.unwrap().value() - 0.2).abs() < 1e-4);
    }
    for a in &addresses {
        assert!(!bus.module(*a).unwrap().state().unwrap().has_fault());
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
    {
        let mut duty = lock_mutex(&bus.inner.duty);
        duty.serving = false;
        duty.online.clear();
        duty.config_before.clear();
    }
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
            (m.state(), m.position().value(), m.watchdog_online(), m.config_word())
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
    bus.enable_watchdog(&[1]).unwrap();
    let m = bus.module(1).unwrap();
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
fn rs232_arms_the_watchdog_with_libm5api_broadcasts_unless_told_not_to() {
    // The refresh goes to address 0 as 0x07 0x00, the form Schunk's libm5api sends over RS232: the module
    // stays alive while the session serves it, and halts 50 ms after the session dies.
    let (clock, host, bus, _) = rs232(&[1]);
    let _me = clock.reserve_participant().enter();
    assert!(bus.watchdog_reliable());
    bus.enable_watchdog(&[1]).unwrap();
    assert!(host.with_device(|d| d.module(1).unwrap().watchdog_online()));
    clock.sleep(secs(2));
    assert!(!host.with_device(|d| d.module(1).unwrap().state().has_fault()), "served for 2 s");
    assert_eq!(host.with_device(|d| d.stats().not_understood), 0, "every refresh understood");
    bus.disable_watchdog().unwrap();
    assert!(!host.with_device(|d| d.module(1).unwrap().watchdog_online()));
    drop(bus);

    let (clock, host, bus, faults) = rs232_with(&[1], BusConfig { watchdog_on_rs232: false, ..BusConfig::rs232() });
    let _me = clock.reserve_participant().enter();
    assert!(!bus.watchdog_reliable());
    let sent = faults.bytes_sent(Direction::HostToDevice);
    let err = bus.enable_watchdog(&[1]).unwrap_err();
    assert!(matches!(err, Error::Unsupported(_)) && err.is_usage(), "{err}");
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
    bus.module(1).unwrap().wait_home(secs(10), &mut |_| {}).unwrap();
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
    bus.module(1).unwrap().state().unwrap();
    bus.broadcast(Broadcast::Home).unwrap();
    // Module 2 exists but the session does not know it; it homes too (no harm) and is idle at the drop.
    // A motion command to an address where nobody is: no acknowledge.
    let err = bus.module(9).unwrap().motion(Motion::FVel { vel: Velocity::native(0.1) }, AckKind::Simple).unwrap_err();
    assert!(matches!(err, Error::Timeout { address: 9, .. }), "{err}");
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
    bus.module(1).unwrap().motion(Motion::FVel { vel: Velocity::native(0.3) }, AckKind::Simple).unwrap();
    bus.broadcast(Broadcast::Halt).unwrap();
    clock.sleep(Duration::from_millis(500));
    assert!(bus.module(1).unwrap().state().unwrap().contains(StateFlag::Motion), "the broadcast was ignored");
    assert_eq!(bus.started(), vec![1], "so the session still counts module 1 as moving");
    drop(bus);
    let s = host.with_device(|d| d.module(1).unwrap().state());
    assert!(s.contains(StateFlag::Halted) && !s.contains(StateFlag::Motion), "halted by address on drop: {s}");

    // On CAN a broadcast is the manual's and reaches every module: it ends the list.
    let (clock, canbus, bus) = can(&[1]);
    let _me = clock.reserve_participant().enter();
    bus.module(1).unwrap().motion(Motion::FVel { vel: Velocity::native(0.3) }, AckKind::Simple).unwrap();
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
    bus.enable_watchdog(&[1, 2]).unwrap();
    let m = bus.module(1).unwrap();
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
    let bus = Bus::can(Box::new(canbus.connect()), clock.shared(), BusConfig::can());
    bus.module(1).unwrap().reset().unwrap();
    bus.enable_watchdog(&[1, 2]).unwrap();
    assert!(device_view(&canbus, &clock, 1).2 && device_view(&canbus, &clock, 2).2);
    drop(bus);
    clock.sleep(secs(1));
    assert!(!device_view(&canbus, &clock, 2).2);
}

#[test]
fn a_session_that_failed_leaves_the_watchdog_armed_on_drop() {
    let (clock, canbus, bus) = can(&[1, 2]);
    let _me = clock.reserve_participant().enter();
    bus.enable_watchdog(&[1, 2]).unwrap();
    bus.module(1).unwrap().motion(Motion::FVel { vel: Velocity::native(0.2) }, AckKind::Simple).unwrap();
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

#[test]
fn every_request_is_checked_before_it_is_sent() {
    let (clock, host, bus, faults) = rs232(&[1]);
    let _me = clock.reserve_participant().enter();
    let bad = [
        Request::Set(Param::ActPos, Value::F32(0.0)),
        Request::Set(Param::MaxVel, Value::U32(1)),
        Request::Get(Param::TargetAcc),
        Request::Set(Param::TargetVel, Value::F32(f32::NAN)),
        Request::Motion(Motion::FRampLoop { pos: Position::native(1.0) }, AckKind::Extended),
        Request::Motion(Motion::FRamp { pos: Position::native(f32::INFINITY) }, AckKind::Simple),
    ];
    let sent = faults.bytes_sent(Direction::HostToDevice);
    for r in &bad {
        let err = bus.request(1, r).unwrap_err();
        assert!(matches!(err, Error::Model(_)) && err.is_usage(), "{r}: {err}");
    }
    assert_eq!(faults.bytes_sent(Direction::HostToDevice), sent, "nothing was sent");
    assert!(bus.started().is_empty(), "a refused motion starts nothing");
    // Several at once: the bad ones get their error, the good ones go out and are answered.
    let mixed = [
        (1, Request::Get(Param::ActPos)),
        (1, bad[0]),
        (1, bad[4]),
        (0, Request::Get(Param::ActPos)),
        (1, Request::Get(Param::CubeState)),
    ];
    let r = bus.request_many(&mixed);
    assert!(matches!(r[0], Ok(Reply::Get(Param::ActPos, _))), "{:?}", r[0]);
    assert!(matches!(r[1], Err(Error::Model(ModelError::NotWritable(Param::ActPos)))), "{:?}", r[1]);
    assert!(matches!(r[2], Err(Error::Model(ModelError::NoExtendedAck(_)))), "{:?}", r[2]);
    assert!(matches!(r[3], Err(Error::InvalidAddress(0))), "{:?}", r[3]);
    assert!(matches!(r[4], Ok(Reply::Get(Param::CubeState, _))), "{:?}", r[4]);
    clock.sleep(secs(1));
    let s = host.with_device(|d| d.module(1).unwrap().state());
    assert!(!s.contains(StateFlag::Motion), "no loop was started under another MotionID: {s}");
    // On CAN, a Config word that would switch the acknowledges off is refused the same way.
    let (clock, _canbus, bus) = can(&[1]);
    let _me = clock.reserve_participant().enter();
    let err = bus.request(1, &Request::Set(Param::Config, Value::U32(0x0400_0000))).unwrap_err();
    assert!(matches!(err, Error::Unsupported(_)), "{err}");
}

/// A CAN link that hands over what it receives in reverse order: whatever arrives within `window` of a
/// frame is held back and delivered last first.
struct Reversing<L> {
    inner: L,
    held: Vec<motionlink_link::can::CanFrame>,
    window: Duration,
    reordered: Arc<std::sync::atomic::AtomicU64>,
}

impl<L: CanLink> CanLink for Reversing<L> {
    fn send(&mut self, frame: &motionlink_link::can::CanFrame) -> Result<(), LinkError> {
        self.inner.send(frame)
    }

    fn recv(&mut self, timeout: Duration) -> Result<Option<motionlink_link::can::CanFrame>, LinkError> {
        if self.held.is_empty() {
            let Some(first) = self.inner.recv(timeout)? else { return Ok(None) };
            self.held.push(first);
            while let Some(f) = self.inner.recv(self.window)? {
                self.held.push(f);
            }
            if self.held.len() > 1 {
                self.reordered.fetch_add(1, Ordering::SeqCst);
            }
        }
        Ok(self.held.pop())
    }

    fn discard_input(&mut self) -> Result<(), LinkError> {
        self.held.clear();
        self.inner.discard_input()
    }

    fn describe(&self) -> String {
        format!("reversing {}", self.inner.describe())
    }
}

#[test]
fn on_can_acknowledges_are_matched_in_whatever_order_they_arrive() {
    let addresses: Vec<u8> = (1..=6).collect();
    let clock = ManualClock::new_auto();
    let sim = SimBus::new_can(&SimConfig::with_addresses(&addresses).unwrap());
    let canbus = CanBus::with_emulator(sim, clock.shared(), CanBusConfig::paced(1_000_000));
    let reordered = Arc::new(std::sync::atomic::AtomicU64::new(0));
    let link = Reversing {
        inner: canbus.connect(),
        held: Vec::new(),
        window: Duration::from_millis(1),
        reordered: Arc::clone(&reordered),
    };
    let _me = clock.reserve_participant().enter();
    let bus = Bus::can(Box::new(link), clock.shared(), BusConfig::can());

    // Each module's own serial number comes back to it, however the answers are ordered.
    let t0 = clock.now();
    let serials = bus.read_many(&addresses, Param::DefCubeSerial);
    assert!(clock.now() - t0 < bus.config().reply_timeout, "one round, nothing timed out or retried");
    for (a, s) in addresses.iter().zip(serials) {
        assert_eq!(s.unwrap(), Value::U32(1000 + u32::from(*a)), "module {a}");
    }
    assert!(reordered.load(Ordering::SeqCst) > 0, "the answers did arrive out of order");

    // Several requests to one module, and writes and motions among reads: each matched to its own.
    let requests = [
        (1, Request::Get(Param::ActPos)),
        (1, Request::Get(Param::CubeState)),
        (1, Request::Get(Param::DefCubeSerial)),
        (2, Request::Get(Param::DefAddress)),
        (3, Request::Set(Param::TargetVel, Value::F32(0.5))),
        (4, Request::Motion(Motion::FRamp { pos: Position::native(0.1) }, AckKind::Extended)),
        (5, Request::Action(Action::Reset)),
        (6, Request::Get(Param::DefAddress)),
    ];
    let before = reordered.load(Ordering::SeqCst);
    let t0 = clock.now();
    let r = bus.request_many(&requests);
    assert!(clock.now() - t0 < bus.config().reply_timeout);
    assert!(reordered.load(Ordering::SeqCst) > before);
    assert!(matches!(r[0], Ok(Reply::Get(Param::ActPos, Value::F32(_)))), "{:?}", r[0]);
    assert!(matches!(r[1], Ok(Reply::Get(Param::CubeState, Value::U32(_)))), "{:?}", r[1]);
    assert!(matches!(r[2], Ok(Reply::Get(Param::DefCubeSerial, Value::U32(1001)))), "{:?}", r[2]);
    assert!(matches!(r[3], Ok(Reply::Get(Param::DefAddress, Value::U8(2)))), "{:?}", r[3]);
    assert!(matches!(r[4], Ok(Reply::Set(Param::TargetVel, ACK_OK))), "{:?}", r[4]);
    assert!(matches!(r[5], Ok(Reply::Motion { id: crate::model::MotionId::FRampAck, ext: Some(_), .. })), "{:?}", r[5]);
    assert!(matches!(r[6], Ok(Reply::Action(Action::Reset))), "{:?}", r[6]);
    assert!(matches!(r[7], Ok(Reply::Get(Param::DefAddress, Value::U8(6)))), "{:?}", r[7]);

    // Polling in a loop: every round complete.
    for _ in 0..20 {
        assert!(bus.positions(&addresses).iter().all(Result::is_ok));
        assert!(bus
            .read_many(&addresses, Param::DefAddress)
            .iter()
            .zip(&addresses)
            .all(|(v, a)| *v.as_ref().unwrap() == Value::U8(*a)));
    }
}

/// The length on the wire of `reply` from module `address` in an RS232 frame.
fn rs232_len(address: u8, reply: &Reply) -> u64 {
    let mut buf = [0u8; crate::wire::rs232::MAX_FRAME];
    crate::wire::rs232::encode(crate::wire::rs232::TelKind::Recv, address, &reply.encode(), &mut buf).unwrap() as u64
}

#[test]
fn a_scan_asks_again_after_a_corrupt_answer() {
    let (clock, _host, bus, faults) = rs232(&[1, 17]);
    let _me = clock.reserve_participant().enter();
    // Module 17's answer to the scan comes after module 1's: flip a bit of its parameter id (BCC mismatch).
    let version = Reply::Get(Param::DefCubeVersion, Value::U16(0x4634));
    faults.inject(
        Direction::DeviceToHost,
        rs232_len(1, &version) + 4,
        motionlink_link::pipe::Fault::Corrupt { xor: 1 },
    );
    let found = scan_infos(&bus);
    assert_eq!(found.iter().map(|m| m.address).collect::<Vec<_>>(), vec![1, 17], "read again, not taken as absent");
    assert_eq!(found[1].serial, 1017);
}

#[test]
fn a_module_that_cannot_be_read_is_reported_and_the_scan_goes_on() {
    let (clock, _host, bus, faults) = rs232(&[1, 17]);
    let _me = clock.reserve_participant().enter();
    // What the modules send before module 17's info: both scan answers, then module 1's info (version,
    // Config, serial, state), as a twin emulator answers them.
    let mut twin = SimBus::new(&SimConfig::with_addresses(&[1, 17]).unwrap());
    let mut ask = |a: u8, p: Param| twin.request(Timestamp::ZERO, a, &Request::Get(p)).unwrap();
    let mut offset = rs232_len(1, &ask(1, Param::DefCubeVersion)) + rs232_len(17, &ask(17, Param::DefCubeVersion));
    for p in [Param::DefCubeVersion, Param::Config, Param::DefCubeSerial, Param::CubeState] {
        offset += rs232_len(1, &ask(1, p));
    }
    // From there on, everything module 17 says is lost.
    for o in offset..offset + 200 {
        faults.inject(Direction::DeviceToHost, o, motionlink_link::pipe::Fault::Drop);
    }
    let entries = bus.scan().unwrap();
    assert_eq!(entries.iter().map(|e| e.address).collect::<Vec<_>>(), vec![1, 17]);
    assert_eq!(entries[0].info.as_ref().unwrap().serial, 1001);
    let err = entries[1].info.as_ref().unwrap_err();
    assert!(matches!(err, Error::Timeout { address: 17, .. }), "{err}");
}

#[test]
fn an_slcan_adapter_that_refuses_a_frame_is_a_link_error_not_a_timeout() {
    use motionlink_link::can::{SlcanAdapter, SlcanBitrate, SlcanLink};
    let clock = ManualClock::new_auto();
    let adapter = SlcanAdapter::new(SimBus::new_can(&SimConfig::with_addresses(&[3]).unwrap()));
    let host = EmulatorHost::new(adapter, clock.shared(), PipeConfig::paced(115_200));
    let _me = clock.reserve_participant().enter();
    let link = SlcanLink::open(host.connect().0, clock.shared(), SlcanBitrate::M1).unwrap();
    let bus = Bus::can(Box::new(link), clock.shared(), BusConfig::can());
    let m = bus.module(3).unwrap();
    assert!(m.state().is_ok());
    // The adapter's transmit queue is full: it rings the bell instead of sending the write.
    host.with_device(|a| a.refuse_next(1));
    let t0 = clock.now();
    let err = m.set(Param::TargetVel, Value::F32(0.5)).unwrap_err();
    assert!(matches!(err, Error::Link(_)) && err.is_transport(), "{err}");
    assert!(err.to_string().contains("refused to send 0E3#084F"), "{err}");
    assert!(clock.now() - t0 < bus.config().reply_timeout, "at once, not after the reply timeout");
    // The line goes on.
    assert!(m.state().is_ok());
}

#[test]
fn a_corrupt_answer_then_silence_is_absence_not_a_module() {
    let (clock, _host, bus, faults) = rs232(&[1, 17]);
    let _me = clock.reserve_participant().enter();
    // Module 17's first answer to the scan is corrupt, and its answer when asked again is lost: what came
    // could as well have been noise or a late frame. It is not listed as a module that answered.
    let version = Reply::Get(Param::DefCubeVersion, Value::U16(0x4634));
    let first = rs232_len(1, &version);
    let len17 = rs232_len(17, &version);
    faults.inject(Direction::DeviceToHost, first + 4, motionlink_link::pipe::Fault::Corrupt { xor: 1 });
    for o in first + len17..first + 2 * len17 {
        faults.inject(Direction::DeviceToHost, o, motionlink_link::pipe::Fault::Drop);
    }
    let entries = bus.scan().unwrap();
    assert_eq!(entries.iter().map(|e| e.address).collect::<Vec<_>>(), vec![1], "{entries:?}");
    assert!(entries[0].info.is_ok());
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

fn can_losing(addresses: &[u8], outgoing: bool) -> (ManualClock, CanBus<SimBus>, Bus) {
    let clock = ManualClock::new_auto();
    let sim = SimBus::new_can(&SimConfig::with_addresses(addresses).unwrap());
    let canbus = CanBus::with_emulator(sim, clock.shared(), CanBusConfig::paced(1_000_000));
    let link = LoseLifeSign { inner: canbus.connect(), outgoing, left: 1 };
    let bus = Bus::can(Box::new(link), clock.shared(), BusConfig::can());
    (clock, canbus, bus)
}

#[test]
fn a_lost_life_sign_is_reported_and_never_toggled_again_blindly() {
    let (clock, canbus, bus) = can_losing(&[1, 2], true);
    let _me = clock.reserve_participant().enter();
    let before = bus.module(1).unwrap().config_word().unwrap();
    let err = bus.enable_watchdog(&[1, 2]).unwrap_err();
    assert!(matches!(err, Error::WatchdogUnconfirmed { address: 1, on: true, .. }), "{err}");
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
    assert_eq!(bus.module(1).unwrap().config_word().unwrap(), before, "Config word restored");
    clock.sleep(secs(1));
    assert!(!device_view(&canbus, &clock, 1).2, "still offline");
}

#[test]
fn a_lost_acknowledge_of_the_life_sign_is_found_out_when_switching_off() {
    let (clock, canbus, bus) = can_losing(&[1], false);
    let _me = clock.reserve_participant().enter();
    let err = bus.enable_watchdog(&[1]).unwrap_err();
    assert!(matches!(err, Error::WatchdogUnconfirmed { address: 1, on: true, .. }), "{err}");
    // The toggle did arrive: the watchdog is online and the session refreshes it.
    assert!(device_view(&canbus, &clock, 1).2);
    clock.sleep(secs(1));
    assert!(!device_view(&canbus, &clock, 1).0.has_fault());
    // No blind second life sign: with the refresh stopped it expires, which names the module.
    let err = bus.disable_watchdog().unwrap_err();
    assert!(matches!(err, Error::WatchdogUnconfirmed { address: 1, on: false, .. }), "{err}");
    let (state, _, online, config) = device_view(&canbus, &clock, 1);
    assert!(online && state.contains(StateFlag::CommError) && state.contains(StateFlag::Halted), "{state}");
    assert!(config.contains(ConfigFlag::WatchdogEnable), "Config word left as is");
    // The manual's way back.
    assert!(bus.module(1).unwrap().reset_and_release_watchdog().unwrap());
    assert!(!device_view(&canbus, &clock, 1).2);
    drop(bus);
    assert!(!device_view(&canbus, &clock, 1).3.contains(ConfigFlag::WatchdogEnable), "restored on drop");
}

// ---------------------------------------------------------------------------------------------------------
// Checked moves, read-back writes, stops that say whether they were confirmed, the poll rate.

/// An RS232 session whose bytes arrive at once (no 9600 baud pacing): only the session's own timing counts.
fn rs232_instant(addresses: &[u8]) -> (ManualClock, EmulatorHost<SimBus>, Bus, FaultControl) {
    let clock = ManualClock::new_auto();
    let sim = SimBus::new(&SimConfig::with_addresses(addresses).unwrap());
    let host = EmulatorHost::new(sim, clock.shared(), PipeConfig::instant());
    let (link, faults) = host.connect();
    let bus = Bus::rs232(Box::new(link), clock.shared(), BusConfig::rs232());
    (clock, host, bus, faults)
}

fn spec(target: f32) -> MoveSpec {
    MoveSpec {
        vel: Some(Velocity::native(1.0)),
        acc: Some(crate::model::Acceleration::native(2.0)),
        ..MoveSpec::to(Position::native(target))
    }
}

fn sim_module(host: &EmulatorHost<SimBus>, a: u8) -> (CubeState, f32) {
    host.with_device(|d| {
        let m = d.module(a).unwrap();
        (m.state(), m.position().value())
    })
}

#[test]
fn a_checked_move_refuses_targets_beyond_the_limits_before_anything_moves() {
    let (clock, host, bus, _) = rs232_instant(&[1]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(1).unwrap();
    m.set(Param::TargetVel, Value::F32(0.5)).unwrap();
    host.with_device(|d| d.take_events());
    for (s, limit) in [
        (MoveSpec::to(Position::native(10.0)), Param::MaxPos),
        (MoveSpec::to(Position::native(-3.2)), Param::MinPos),
        (MoveSpec { vel: Some(Velocity::native(1.5)), ..MoveSpec::to(Position::native(0.5)) }, Param::MaxVel),
        (
            MoveSpec { acc: Some(crate::model::Acceleration::native(9.0)), ..MoveSpec::to(Position::native(0.5)) },
            Param::MaxAcc,
        ),
    ] {
        let err = m.move_to(&s, &mut |_| {}).unwrap_err();
        match &err {
            Error::BeyondLimit { limit: l, .. } => assert_eq!(*l, limit, "{err}"),
            other => panic!("{other}"),
        }
        assert!(err.is_usage() && err.to_string().contains(limit.name()), "{err}");
    }
    // "10 -> 3.14" is refused, not clamped: nothing was written, nothing moved.
    assert!(host.with_device(|d| d.take_events()).is_empty());
    assert_eq!(sim_module(&host, 1).1, 0.05);
    // Numbers that make no sense are refused before anything is read.
    for s in [
        MoveSpec::to(Position::native(f32::NAN)),
        MoveSpec { vel: Some(Velocity::native(0.0)), ..MoveSpec::to(Position::native(0.1)) },
        MoveSpec { acc: Some(crate::model::Acceleration::native(-1.0)), ..MoveSpec::to(Position::native(0.1)) },
        MoveSpec { tolerance: Position::native(0.0), ..MoveSpec::to(Position::native(0.1)) },
        MoveSpec { timeout: Duration::ZERO, ..MoveSpec::to(Position::native(0.1)) },
    ] {
        assert!(matches!(m.move_to(&s, &mut |_| {}), Err(Error::InvalidArgument { .. })), "{s:?}");
    }
    // A module whose own TargetVel is 0 would never arrive: refused when no velocity is given.
    m.set(Param::TargetVel, Value::F32(0.0)).unwrap();
    let err = m.move_to(&MoveSpec::to(Position::native(0.5)), &mut |_| {}).unwrap_err();
    assert!(matches!(err, Error::InvalidArgument { what: "the velocity", .. }), "{err}");
    assert!(!sim_module(&host, 1).0.contains(StateFlag::Motion));
    // A halted module would ignore the motion command: refused, named, before anything is written.
    m.halt().unwrap();
    let err = m.move_to(&spec(0.5), &mut |_| {}).unwrap_err();
    assert!(matches!(err, Error::Halted { address: 1, .. }), "{err}");
    let err = m.home_and_wait(secs(10), &mut |_| {}).unwrap_err();
    assert!(matches!(err, Error::Halted { address: 1, .. }), "{err}");
    let events = host.with_device(|d| d.take_events());
    assert_eq!(events, ["module 1 halted"], "no write, no motion command after the halt");
}

#[test]
fn a_checked_move_ends_within_the_tolerance_or_says_where_it_ended() {
    let (clock, host, bus, _) = rs232_instant(&[1]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(1).unwrap();
    let report = m.move_to(&spec(0.5), &mut |_| {}).unwrap();
    assert!((report.reached.value() - 0.5).abs() < 1e-6 && report.state.contains(StateFlag::RampEnd), "{report:?}");
    assert_eq!(report.start, Position::native(0.05));
    assert!(bus.started().is_empty());
    // A module that settles 5 mrad beyond its target: outside the default 1 mrad tolerance.
    host.with_device(|d| {
        let mut cfg = crate::sim::ModuleConfig::at(2);
        cfg.settle_offset = 0.005;
        let sim = SimBus::new(&SimConfig { modules: vec![cfg], ..SimConfig::default() });
        *d = sim;
    });
    let m = bus.module(2).unwrap();
    let err = m.move_to(&spec(0.5), &mut |_| {}).unwrap_err();
    match &err {
        Error::NotReached { target, reached, difference, .. } => {
            assert_eq!(*target, 0.5);
            assert!((reached - 0.505).abs() < 1e-6 && (difference - 0.005).abs() < 1e-6, "{err}");
        }
        other => panic!("{other}"),
    }
    assert!(err.is_device(), "exit code 1");
    let text = err.to_string();
    assert!(text.contains("target 0.5") && text.contains("0.505") && text.contains("0.005"), "{text}");
    // A wider tolerance accepts it.
    let wide = MoveSpec { tolerance: Position::native(0.01), ..spec(0.3) };
    assert!((m.move_to(&wide, &mut |_| {}).unwrap().reached.value() - 0.305).abs() < 1e-6);
}

#[test]
fn a_checked_move_reads_back_its_ramp_and_target_and_halts_a_corrupted_command() {
    let (clock, host, bus, faults) = rs232_instant(&[1]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(1).unwrap();
    // A write of TargetVel whose value is corrupted on the way (the module ignores the BCC): the read-back
    // of TargetVelInc shows it, before anything moves.
    let set_vel = Request::set(Param::TargetVel, Value::F32(1.0)).unwrap();
    let mut frame = [0u8; crate::wire::rs232::MAX_FRAME];
    let n = crate::wire::rs232::encode(crate::wire::rs232::TelKind::Send, 1, &set_vel.encode(), &mut frame).unwrap();
    // The reads before it (state, limits, IncRatio, ActPos) are counted frame by frame; the byte hit is
    // the float's most significant one.
    let before = faults.bytes_sent(Direction::HostToDevice);
    let reads =
        [Param::CubeState, Param::MinPos, Param::MaxPos, Param::MaxVel, Param::MaxAcc, Param::IncRatio, Param::ActPos];
    let read_bytes: u64 = reads.iter().map(|p| rs232_request_len(1, &Request::Get(*p))).sum();
    let value_msb = before + read_bytes + (n as u64 - 3); // STX TELID TELID 08 4F v0 v1 v2 v3 BCC ETX
    assert_eq!(frame[n - 3], 0x3f, "1.0f32 ends in 0x3f");
    faults.inject(Direction::HostToDevice, value_msb, motionlink_link::pipe::Fault::Corrupt { xor: 0x01 });
    let err = m.move_to(&spec(0.5), &mut |_| {}).unwrap_err();
    assert!(matches!(err, Error::Mismatch { param: Param::TargetVel, .. }), "{err}");
    assert!(!sim_module(&host, 1).0.contains(StateFlag::Motion), "nothing moved");
    // The motion command itself corrupted: 0.5 (00 00 00 3f) arrives as 0.5000001 or so many ticks away
    // that the module's TargetPosInc shows it; the module is halted at once.
    faults.heal();
    let start = faults.bytes_sent(Direction::HostToDevice);
    let motion = Request::motion(Motion::FRamp { pos: Position::native(2.0) }, AckKind::Simple).unwrap();
    let all_before_motion: u64 = reads.iter().map(|p| rs232_request_len(1, &Request::Get(*p))).sum::<u64>()
        + rs232_request_len(1, &Request::set(Param::TargetVel, Value::F32(1.0)).unwrap())
        + rs232_request_len(1, &Request::Get(Param::TargetVelInc))
        + rs232_request_len(1, &Request::set(Param::TargetAcc, Value::F32(2.0)).unwrap())
        + rs232_request_len(1, &Request::Get(Param::TargetAccInc));
    // 2.0f32 = 00 00 00 40: flip a bit of its second byte (a mantissa bit: 2.0 -> 2.000122).
    let n = rs232_request_len(1, &motion);
    faults.inject(
        Direction::HostToDevice,
        start + all_before_motion + n - 5,
        motionlink_link::pipe::Fault::Corrupt { xor: 0x04 },
    );
    let err = m.move_to(&spec(2.0), &mut |_| {}).unwrap_err();
    match &err {
        Error::TargetMismatch { stop: StopOutcome::Confirmed, sent, taken, .. } => assert_ne!(sent, taken),
        other => panic!("{other}"),
    }
    assert!(err.is_device(), "{err}");
    let (state, p) = sim_module(&host, 1);
    assert!(state.contains(StateFlag::Halted) && !state.contains(StateFlag::Motion), "{state}");
    assert!(p < 0.2, "halted right after it started: {p}");
}

/// The length of the RS232 frame of `request` to `address`, DLE escapes included.
fn rs232_request_len(address: u8, request: &Request) -> u64 {
    let mut buf = [0u8; crate::wire::rs232::MAX_FRAME];
    crate::wire::rs232::encode(crate::wire::rs232::TelKind::Send, address, &request.encode(), &mut buf).unwrap() as u64
}

#[test]
fn set_checked_reads_back_and_names_a_mismatch() {
    let (clock, host, bus, _) = rs232_instant(&[1]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(1).unwrap();
    // Read back as written.
    assert_eq!(m.set_checked(Param::MaxVel, Value::F32(0.5)).unwrap(), Readback::Same(Value::F32(0.5)));
    assert!(matches!(m.set_checked(Param::TargetVel, Value::F32(0.25)).unwrap(), Readback::Same(Value::U32(_))));
    assert!(matches!(m.set_checked(Param::TargetPos, Value::F32(-1.0)).unwrap(), Readback::Same(Value::I32(_))));
    assert!(matches!(m.set_checked(Param::DioSetup, Value::U32(0x30)).unwrap(), Readback::Same(_)));
    assert!(matches!(m.set_checked(Param::Cur, Value::F32(1.0)).unwrap(), Readback::NotReadable(_)));
    // The module limits a limit to its ROM default (DefMaxVel = 1 rad/s): not silently.
    let err = m.set_checked(Param::MaxVel, Value::F32(10.0)).unwrap_err();
    assert!(matches!(err, Error::Mismatch { param: Param::MaxVel, .. }) && err.is_device(), "{err}");
    assert!(err.to_string().contains("10.000000") && err.to_string().contains("1.000000"), "{err}");
    // A target beyond its limit is refused before it is written.
    let velinc = host.with_device(|d| d.request(clock.now(), 1, &Request::Get(Param::TargetVelInc)));
    let err = m.set_checked(Param::TargetVel, Value::F32(2.0)).unwrap_err();
    assert!(matches!(err, Error::BeyondLimit { limit: Param::MaxVel, .. }) && err.is_usage(), "{err}");
    let err = m.set_checked(Param::TargetPos, Value::F32(4.0)).unwrap_err();
    assert!(matches!(err, Error::BeyondLimit { limit: Param::MaxPos, .. }), "{err}");
    let err = m.set_checked(Param::Cur, Value::F32(6.0)).unwrap_err();
    assert!(matches!(err, Error::BeyondLimit { limit: Param::MaxCur, .. }), "{err}");
    assert_eq!(host.with_device(|d| d.request(clock.now(), 1, &Request::Get(Param::TargetVelInc))), velinc);
}

#[test]
fn a_line_that_fails_during_a_move_is_stopped_and_the_error_says_so() {
    // Answers lost for a while: the poll's read times out three times, the halt gets through.
    let (clock, host, bus, faults) = rs232_instant(&[1]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(1).unwrap();
    let mut dropped = false;
    let err = m
        .move_to(&MoveSpec { vel: Some(Velocity::native(0.2)), ..spec(1.0) }, &mut |p| {
            if !dropped && p.elapsed > Duration::from_millis(200) {
                dropped = true;
                // Enough to lose the three tries of the next state read, not the halt after them.
                faults.drop_next(Direction::DeviceToHost, 3 * 10);
            }
        })
        .unwrap_err();
    match &err {
        Error::LostDuringMotion { stop: StopOutcome::Confirmed, cause, .. } => {
            assert!(matches!(**cause, Error::Timeout { .. } | Error::Corrupt { .. }), "{cause}")
        }
        other => panic!("{other}"),
    }
    assert!(err.is_transport(), "exit code 3");
    assert!(err.to_string().contains("the module acknowledged the halt: it has stopped"), "{err}");
    let (state, _) = sim_module(&host, 1);
    assert!(state.contains(StateFlag::Halted) && !state.contains(StateFlag::Motion), "{state}");
    drop(bus);

    // The line breaks for good during a move with the watchdog armed: no halt can be confirmed; the error
    // says the axis may still be moving, and that the watchdog (no longer refreshed) halts it; it does.
    let (clock, host, bus, faults) = rs232_instant(&[1]);
    let _me = clock.reserve_participant().enter();
    bus.enable_watchdog(&[1]).unwrap();
    let m = bus.module(1).unwrap();
    let mut broke_at = None;
    let err = m
        .move_to(&MoveSpec { vel: Some(Velocity::native(0.2)), ..spec(1.0) }, &mut |p| {
            if broke_at.is_none() && p.elapsed > Duration::from_millis(200) {
                broke_at = Some(clock.now());
                faults.drop_next(Direction::HostToDevice, u64::MAX);
                faults.drop_next(Direction::DeviceToHost, u64::MAX);
            }
        })
        .unwrap_err();
    match &err {
        Error::LostDuringMotion { stop: StopOutcome::Unconfirmed { watchdog_armed: true, .. }, .. } => {}
        other => panic!("{other}"),
    }
    let text = err.to_string();
    assert!(text.contains("the axis may still be moving") && text.contains("halts itself within 50 ms"), "{text}");
    assert!(bus.failed() && !bus.watchdog_served());
    let err = bus.disable_watchdog().unwrap_err();
    assert!(matches!(err, Error::WatchdogLeftOnline { .. }), "a failed session leaves the watchdog on: {err}");
    drop(bus);
    clock.sleep(Duration::from_millis(100));
    let (state, _) = sim_module(&host, 1);
    assert!(state.contains(StateFlag::CommError) && !state.contains(StateFlag::Motion), "{state}");
    let expired = host.with_device(|d| d.take_events()).into_iter().find(|e| e.contains("watchdog expired"));
    assert!(expired.is_some(), "the watchdog stopped it");

    // The same without a watchdog: the error says nothing else stops it.
    let (clock, _host, bus, faults) = rs232_instant(&[1]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(1).unwrap();
    let mut broke = false;
    let err = m
        .move_to(&MoveSpec { vel: Some(Velocity::native(0.2)), ..spec(1.0) }, &mut |p| {
            if !broke && p.elapsed > Duration::from_millis(200) {
                broke = true;
                faults.disconnect();
            }
        })
        .unwrap_err();
    assert!(matches!(
        err,
        Error::LostDuringMotion { stop: StopOutcome::Unconfirmed { watchdog_armed: false, .. }, .. }
    ));
    let text = err.to_string();
    assert!(text.contains("the axis may still be moving") && text.contains("no watchdog is armed"), "{text}");
}

#[test]
fn waiting_polls_at_the_set_rate_not_as_fast_as_the_line_answers() {
    // An instant line answers in no time: the wait still polls once per poll_interval (10 ms).
    let (clock, host, bus, faults) = rs232_instant(&[1]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(1).unwrap();
    let mut polls = Vec::new();
    let t0 = clock.now();
    let sent0 = host.with_device(|d| d.stats().handled);
    // 0.95 rad at 0.5 rad/s, 2 rad/s²: 0.25 s up, 1.65 s steady, 0.25 s down: 2.15 s.
    m.move_to(&MoveSpec { vel: Some(Velocity::native(0.5)), ..spec(1.0) }, &mut |p| polls.push(p.elapsed)).unwrap();
    let took = clock.now() - t0;
    let requests = host.with_device(|d| d.stats().handled) - sent0;
    assert!((2.15..2.2).contains(&took.as_secs_f64()), "{took:?}");
    // One poll per 10 ms (two reads each), and the reads around the motion: no more.
    assert!((214..=217).contains(&polls.len()), "{} polls", polls.len());
    assert!(requests <= 2 * 217 + 20, "{requests} requests in {took:?}");
    for w in polls.windows(2) {
        assert_eq!(w[1] - w[0], Duration::from_millis(10), "polls on a fixed schedule");
    }
    let _ = faults;
    // A different rate is a setting.
    let (clock, _host, bus, _) = {
        let clock = ManualClock::new_auto();
        let sim = SimBus::new(&SimConfig::default());
        let host = EmulatorHost::new(sim, clock.shared(), PipeConfig::instant());
        let bus = Bus::rs232(
            Box::new(host.connect().0),
            clock.shared(),
            BusConfig { poll_interval: Duration::from_millis(50), ..BusConfig::rs232() },
        );
        (clock, host, bus, ())
    };
    let _me = clock.reserve_participant().enter();
    let mut polls = 0;
    bus.module(1)
        .unwrap()
        .move_to(&MoveSpec { vel: Some(Velocity::native(0.5)), ..spec(1.0) }, &mut |_| polls += 1)
        .unwrap();
    assert!((43..=45).contains(&polls), "{polls}");
}

#[test]
fn the_watchdog_refresh_keeps_absolute_deadlines() {
    let (clock, canbus, bus) = can(&[1]);
    let _me = clock.reserve_participant().enter();
    bus.enable_watchdog(&[1]).unwrap();
    let due0 = lock_mutex(&bus.inner.duty).next_due;
    clock.sleep(Duration::from_millis(1_000));
    let due = lock_mutex(&bus.inner.duty).next_due;
    let periods = (due - due0).as_nanos() % Duration::from_millis(20).as_nanos();
    assert_eq!(periods, 0, "every refresh due a whole number of periods after the first: {due0} -> {due}");
    assert!(!device_view(&canbus, &clock, 1).0.has_fault());
    bus.disable_watchdog().unwrap();
}

#[test]
fn an_answer_that_echoes_another_command_or_has_a_wrong_length_is_corrupt() {
    use crate::wire::rs232::{encode_raw, telid, TelKind};
    let clock = ManualClock::new_auto();
    let _me = clock.reserve_participant().enter();
    let (host_end, mut device_end, _faults) = motionlink_link::pipe::pipe(clock.shared(), PipeConfig::instant());
    let bus = Bus::rs232(Box::new(host_end), clock.shared(), BusConfig::rs232());
    let answer = |payload: &[u8], len: u8| {
        let p = crate::wire::Payload::new(payload).unwrap();
        let id = telid(TelKind::Recv, 1, len);
        let mut buf = [0u8; crate::wire::rs232::MAX_FRAME];
        let bcc = crate::wire::rs232::bcc(&[&id[..], payload].concat());
        let n = encode_raw(id, &p, bcc, &mut buf);
        buf[..n].to_vec()
    };
    let device = std::thread::spawn({
        let ticket = clock.reserve_participant();
        let (a, b, c) = (
            answer(&[0x0a, 0x3d, 0, 0, 0, 0], 6), // PrevActPos for ActPos: a wrong echo
            answer(&[0x0a, 0x3c, 0, 0, 0, 0], 5), // the right answer with a wrong TELID length
            answer(&[0x08, 0x4f, 0x64], 6),       // the manual's own slip: 6 for 3 bytes
        );
        move || {
            let _p = ticket.enter();
            let mut buf = [0u8; 64];
            for reply in [&a, &a, &a, &b, &b, &b, &c] {
                let _ = device_end.recv(&mut buf, Duration::from_secs(5)).unwrap();
                device_end.send(reply).unwrap();
            }
        }
    });
    let m = bus.module(1).unwrap();
    let err = m.position().unwrap_err();
    assert!(matches!(err, Error::Corrupt { .. }) && err.to_string().contains("does not echo"), "{err}");
    let err = m.position().unwrap_err();
    assert!(matches!(err, Error::Corrupt { .. }) && err.to_string().contains("TELID length 5"), "{err}");
    m.set(Param::TargetVel, Value::F32(1.0)).unwrap();
    device.join().unwrap();
}

/// What one run of the bit-flip scenario ended with.
struct FlipRun {
    /// The move's result (or the watchdog's, if arming failed).
    result: Result<MoveReport, Error>,
    /// Module 1's state and position well after the session ended.
    after: (CubeState, f32),
    /// Module 3's.
    other: (CubeState, f32),
    /// Bytes sent each way when the first poll came, and at the end of the move.
    marks: [(u64, u64); 2],
}

/// The `motionlink powercube move` scenario over RS232 (modules at 1 and 3, the watchdog armed on module 1,
/// a checked move of module 1 to 0.3), with `fault` applied to the line first.
fn flip_run(fault: Option<(Direction, u64, u8)>) -> FlipRun {
    let (clock, host, bus, faults) = rs232_instant(&[1, 3]);
    let _me = clock.reserve_participant().enter();
    if let Some((dir, offset, xor)) = fault {
        faults.inject(dir, offset, motionlink_link::pipe::Fault::Corrupt { xor });
    }
    let sent = || (faults.bytes_sent(Direction::HostToDevice), faults.bytes_sent(Direction::DeviceToHost));
    let mut first_poll = None;
    let result = bus.enable_watchdog(&[1]).and_then(|()| {
        bus.module(1).unwrap().move_to(&spec(0.3), &mut |_| {
            first_poll.get_or_insert_with(sent);
        })
    });
    let end = sent();
    bus.halt_started();
    drop(bus);
    clock.sleep(Duration::from_millis(200));
    FlipRun {
        result,
        after: sim_module(&host, 1),
        other: sim_module(&host, 3),
        marks: [first_poll.unwrap_or(end), end],
    }
}

#[test]
fn one_flipped_bit_anywhere_never_gives_a_false_success() {
    let clean = flip_run(None);
    assert!(clean.result.is_ok(), "{:?}", clean.result.err());
    let [(poll_h, poll_d), (end_h, end_d)] = clean.marks;
    // Every bit of every byte up to a few polls into the motion (arming the watchdog, the limit reads, the
    // ramp writes and read-backs, the motion command, the target read-back, the first polls), and of the
    // last bytes (the final polls and the two final position reads), both ways.
    let ranges = [
        (Direction::HostToDevice, (0..poll_h + 40).chain(end_h.saturating_sub(40)..end_h)),
        (Direction::DeviceToHost, (0..poll_d + 40).chain(end_d.saturating_sub(50)..end_d)),
    ];
    let (mut runs, mut failed) = (0, 0);
    for (dir, offsets) in ranges {
        for offset in offsets {
            for bit in 0..8 {
                let run = flip_run(Some((dir, offset, 1 << bit)));
                runs += 1;
                let what = format!("{dir:?} byte {offset} bit {bit}");
                assert!(!run.after.0.contains(StateFlag::Motion), "{what}: module 1 left moving: {:?}", run.result);
                assert!(!run.other.0.contains(StateFlag::Motion), "{what}: module 3 left moving");
                // A corrupted command is caught before the axis goes anywhere else: module 1 ends between
                // where it stood (0.05) and where it was sent (0.3), give or take 20 mrad.
                assert!(
                    (0.03..=0.32).contains(&run.after.1),
                    "{what}: module 1 went to {}: {:?}",
                    run.after.1,
                    run.result
                );
                match &run.result {
                    Ok(report) => {
                        assert!((report.reached.value() - 0.3).abs() <= 0.001, "{what}: {report:?}");
                        assert!(
                            (run.after.1 - 0.3).abs() <= 0.001,
                            "{what}: success, but module 1 is at {}",
                            run.after.1
                        );
                        assert_eq!(run.other.1, 0.05, "{what}: success, but module 3 moved");
                    }
                    // A motion command whose address was corrupted reaches module 3, which moves until the
                    // session sees its unexpected acknowledge and halts it: the move fails.
                    Err(_) => failed += 1,
                }
            }
        }
    }
    // Most flips are caught and the move fails (or is retried and succeeds); none succeeds wrongly.
    assert!(runs > 2_000 && failed > 0, "{runs} runs, {failed} failed");
}
