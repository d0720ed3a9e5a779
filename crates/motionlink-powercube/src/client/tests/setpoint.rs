//! Streamed setpoints (`setpoint`): after the first call to a module one exchange per call, the limits
//! cached and refused (never clamped), the cache dropped by what may change them, the watchdog armed and
//! held, a module halted by someone else seen through the short state.

use super::*;
use crate::client::{Guard, SetpointReport, StopOutcome};
use crate::error::Error;
use crate::model::*;
use crate::wire::{AckPosition, Action, Request};

/// The emulator's encoder ticks per rad (4096 per turn through a 1:100 gear).
const RATIO: f64 = 4096.0 * 100.0 / std::f64::consts::TAU;

const EXT: AckKind = AckKind::Extended;

/// The requests the emulator has handled so far (answered or acted upon).
fn handled(host: &EmulatorHost<Emulator>) -> u64 {
    host.with_device(|d| d.stats().handled)
}

fn events(host: &EmulatorHost<Emulator>) -> Vec<String> {
    host.with_device(|d| d.take_events())
}

/// True if a module took a motion command (or ignored one) since the events were last taken.
fn commanded(host: &EmulatorHost<Emulator>) -> bool {
    events(host).iter().any(|e| e.contains("motion started") || e.contains("ignored"))
}

fn vel(v: f32) -> Motion {
    Motion::FVel { vel: Velocity::rad_per_s(v) }
}

/// The float position of a report's extended acknowledge.
fn at(report: &SetpointReport) -> f32 {
    match report.ext_ack.map(|e| e.position) {
        Some(AckPosition::Unit(p)) => p.value(),
        other => panic!("no float position: {other:?}"),
    }
}

/// The position in ticks of a report's extended acknowledge.
fn ticks_at(report: &SetpointReport) -> i32 {
    match report.ext_ack.map(|e| e.position) {
        Some(AckPosition::Ticks(t)) => t.0,
        other => panic!("no position in ticks: {other:?}"),
    }
}

/// `n` setpoints of `motion` to `m`, one every 10 ms: their reports, and the requests the emulator handled
/// meanwhile.
fn stream(
    clock: &ManualClock,
    host: &EmulatorHost<Emulator>,
    m: &crate::client::Module<'_>,
    motion: Motion,
    n: usize,
) -> (Vec<SetpointReport>, u64) {
    let before = handled(host);
    let mut next = clock.now();
    let mut reports = Vec::with_capacity(n);
    for _ in 0..n {
        next += Duration::from_millis(10);
        clock.sleep_until(next);
        reports.push(m.setpoint(motion, EXT, Guard::HaltOnly).unwrap());
    }
    (reports, handled(host) - before)
}

/// Each position strictly beyond the one before.
fn rising<T: PartialOrd + std::fmt::Debug>(positions: &[T]) {
    assert!(positions.windows(2).all(|w| w[1] > w[0]), "{positions:?}");
}

#[test]
fn a_stream_of_fvel_ack_moves_the_module_one_exchange_per_call_each_report_saying_where_it_stood() {
    let (clock, host, bus, _) = rs232_instant(&[1]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(addr(1));
    m.home_and_wait(secs(10), &mut |_| {}).unwrap();
    let first = m.setpoint(vel(0.2), EXT, Guard::HaltOnly).unwrap();
    assert_eq!((first.kind, first.mode, first.watchdog), (ModuleKind::Rotary, MotionId::FVelAck, false));
    assert!(matches!(first.ext_ack.map(|e| e.position), Some(AckPosition::Unit(p)) if p.unit() == AxisUnit::Radian));
    let (reports, exchanges) = stream(&clock, &host, &m, vel(0.2), 30);
    assert_eq!(exchanges, 30, "after the first call, one exchange per call");
    let positions: Vec<f32> = reports.iter().map(at).collect();
    rising(&positions);
    assert!(positions[29] - positions[0] > 0.03, "up to 0.2 rad/s for 0.3 s: {positions:?}");
    for r in &reports {
        let short = r.ext_ack.unwrap().state;
        assert!(short.contains(ShortFlag::Motion) && !short.contains(ShortFlag::NotOk), "{short:?}");
    }
    let (state, position) = sim_module(&host, 1);
    assert!(state.contains(StateFlag::Motion) && position >= positions[29], "{state} {position}");
    // The module counts as set in motion: the close halts it.
    assert_eq!(bus.started(), vec![addr(1)]);
    assert_eq!(bus.close().map_err(|e| e.to_string()), Ok(vec![addr(1)]));
    let state = sim_module(&host, 1).0;
    assert!(state.contains(StateFlag::Halted) && !state.contains(StateFlag::Motion), "{state}");
}

#[test]
fn a_limit_is_refused_with_nothing_sent_and_one_this_session_writes_applies_at_the_next_call() {
    let (clock, host, bus, _) = rs232_instant(&[1]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(addr(1));
    m.setpoint(vel(0.5), EXT, Guard::HaltOnly).unwrap();
    m.setpoint(vel(0.5), EXT, Guard::HaltOnly).unwrap();
    events(&host);
    let before = handled(&host);
    let err = m.setpoint(vel(1.5), EXT, Guard::HaltOnly).unwrap_err();
    assert!(
        matches!(err, Error::OutsideLimits { limit: Param::MaxVel, limit_value, .. } if limit_value == 1.0),
        "{err}"
    );
    assert!(err.is_usage() && err.to_string().contains("the velocity 1.5 rad/s"), "{err}");
    assert_eq!(handled(&host), before, "refused against the cached MaxVel: nothing sent, nothing read");
    assert!(!commanded(&host), "nothing moved");
    // Never clamped either way, and the spec's own rules hold: a NaN is refused before anything.
    let err = m.setpoint(vel(-1.5), EXT, Guard::HaltOnly).unwrap_err();
    assert!(matches!(err, Error::OutsideLimits { limit: Param::MaxVel, .. }), "{err}");
    let err = m.setpoint(Motion::FVel { vel: Velocity::native(f32::NAN) }, EXT, Guard::HaltOnly).unwrap_err();
    assert!(matches!(err, Error::InvalidArgument { what: "the velocity", .. }), "{err}");
    let err = m.setpoint(Motion::FRampLoop { pos: Position::rad(0.5) }, EXT, Guard::HaltOnly).unwrap_err();
    assert!(err.is_usage() && err.to_string().contains("FRAMPLOOP has no mode with extended acknowledge"), "{err}");
    let err = m.setpoint(Motion::FVel { vel: Velocity::m_per_s(0.1) }, EXT, Guard::HaltOnly).unwrap_err();
    assert!(matches!(err, Error::UnitMismatch { .. }), "{err}");
    assert!(!commanded(&host));
    m.setpoint(vel(0.0), EXT, Guard::HaltOnly).unwrap();
    // A write of another parameter keeps the cache: one exchange.
    m.set(Param::TargetAcc, Value::F32(2.0)).unwrap();
    let before = handled(&host);
    m.setpoint(vel(0.0), EXT, Guard::HaltOnly).unwrap();
    assert_eq!(handled(&host) - before, 1);
    // MaxVel lowered by this session: the next call reads it again and refuses what it no longer allows.
    m.set(Param::MaxVel, Value::F32(0.3)).unwrap();
    events(&host);
    let err = m.setpoint(vel(0.5), EXT, Guard::HaltOnly).unwrap_err();
    assert!(
        matches!(err, Error::OutsideLimits { limit: Param::MaxVel, limit_value, .. } if (limit_value - 0.3).abs() < 1e-6),
        "{err}"
    );
    assert!(!commanded(&host), "nothing moved");
    m.setpoint(vel(0.25), EXT, Guard::HaltOnly).unwrap();
    // Raised again through the checked write: taken at once as well.
    m.set_checked(Param::MaxVel, Value::F32(0.8)).unwrap();
    m.setpoint(vel(0.7), EXT, Guard::HaltOnly).unwrap();
    let err = m.setpoint(vel(0.9), EXT, Guard::HaltOnly).unwrap_err();
    assert!(matches!(err, Error::OutsideLimits { limit: Param::MaxVel, .. }), "{err}");
}

#[test]
fn a_step_s_speed_is_checked_from_the_last_extended_acknowledge_without_a_read() {
    let (clock, host, bus, _) = rs232_instant(&[1]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(addr(1));
    m.home_and_wait(secs(10), &mut |_| {}).unwrap();
    let step = |pos: f32, ms: u16| Motion::FStep { pos: Position::rad(pos), time: Millis(ms) };
    let first = m.setpoint(step(0.01, 20), EXT, Guard::HaltOnly).unwrap();
    assert_eq!(first.mode, MotionId::FStepAck);
    clock.sleep(Duration::from_millis(50));
    // 0.5 rad in 100 ms from where the module stood at the last acknowledge (0) needs 5 rad/s.
    let before = handled(&host);
    let err = m.setpoint(step(0.5, 100), EXT, Guard::HaltOnly).unwrap_err();
    assert!(matches!(err, Error::OutsideLimits { limit: Param::MaxVel, .. }), "{err}");
    assert!(err.to_string().contains("the speed the step needs"), "{err}");
    assert_eq!(handled(&host), before, "refused with nothing read or sent");
    // The refusal dropped the cache: the next step is checked with reads again, then one exchange each.
    m.setpoint(step(0.02, 20), EXT, Guard::HaltOnly).unwrap();
    let mut next = clock.now();
    let before = handled(&host);
    let mut positions = Vec::new();
    for i in 1..=10u8 {
        next += Duration::from_millis(20);
        clock.sleep_until(next);
        positions.push(at(&m.setpoint(step(0.02 + f32::from(i) * 0.005, 20), EXT, Guard::HaltOnly).unwrap()));
    }
    assert_eq!(handled(&host) - before, 10, "one exchange per step");
    rising(&positions);
    clock.sleep(Duration::from_millis(50));
    assert!((sim_module(&host, 1).1 - 0.07).abs() < 1e-4, "the last step reached");
    bus.close().unwrap();
}

#[test]
fn the_watchdog_the_first_setpoint_arms_stays_armed_after_it_and_the_close_halts_and_switches_it_off() {
    let (clock, canbus, bus) = can(&[1]);
    let _me = clock.reserve_participant().enter();
    let before = device_view(&canbus, &clock, 1).3;
    let m = bus.module(addr(1));
    let report = m.setpoint(vel(0.2), EXT, Guard::Watchdog).unwrap();
    assert!(report.watchdog, "{report:?}");
    assert!(bus.watchdog_armed(addr(1)) && bus.watchdog_served());
    // The operation has returned: the session refreshes the watchdog on its own.
    clock.sleep(secs(1));
    let (state, _, online, config) = device_view(&canbus, &clock, 1);
    assert!(online && config.contains(ConfigFlag::WatchdogEnable), "{config:?}");
    assert!(state.contains(StateFlag::Motion) && !state.contains(StateFlag::CommError), "{state}");
    for _ in 0..5 {
        assert!(m.setpoint(vel(0.2), EXT, Guard::Watchdog).unwrap().watchdog);
    }
    clock.sleep(secs(1));
    assert!(!device_view(&canbus, &clock, 1).0.has_fault());
    assert_eq!(bus.close().map_err(|e| e.to_string()), Ok(vec![addr(1)]), "the close halted the module");
    clock.sleep(secs(1));
    let (state, _, online, config) = device_view(&canbus, &clock, 1);
    assert!(state.contains(StateFlag::Halted) && !state.contains(StateFlag::Motion), "{state}");
    assert!(!state.contains(StateFlag::CommError) && !online, "switched off, not expired: {state}");
    assert_eq!(config, before, "the Config word as it was");
}

#[test]
fn halt_only_never_arms_the_watchdog_and_disable_watchdog_switches_off_what_a_setpoint_armed() {
    let (clock, canbus, bus) = can(&[1, 2]);
    let _me = clock.reserve_participant().enter();
    for _ in 0..3 {
        assert!(!bus.module(addr(2)).setpoint(vel(0.1), EXT, Guard::HaltOnly).unwrap().watchdog);
    }
    assert!(!bus.watchdog_served() && !device_view(&canbus, &clock, 2).2, "never armed");
    assert!(bus.module(addr(1)).setpoint(vel(0.1), EXT, Guard::Watchdog).unwrap().watchdog);
    bus.disable_watchdog().unwrap();
    assert!(!bus.watchdog_served() && !device_view(&canbus, &clock, 1).2);
    // Switched off by the caller: the stream goes on without it, and says so.
    assert!(!bus.module(addr(1)).setpoint(vel(0.1), EXT, Guard::Watchdog).unwrap().watchdog);
    clock.sleep(secs(1));
    assert!(!device_view(&canbus, &clock, 1).0.has_fault());
    assert_eq!(bus.close().map_err(|e| e.to_string()), Ok(vec![addr(1), addr(2)]));
}

#[test]
fn a_module_halted_by_someone_else_fails_the_next_setpoint_and_the_one_after_checks_it_again() {
    let (clock, host, bus, _) = rs232_instant(&[1]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(addr(1));
    m.home_and_wait(secs(10), &mut |_| {}).unwrap();
    stream(&clock, &host, &m, vel(0.2), 3);
    // Another host halts the module.
    host.with_device(|d| d.request(clock.now(), 1, &Request::Action(Action::Halt)));
    events(&host);
    let err = m.setpoint(vel(0.2), EXT, Guard::HaltOnly).unwrap_err();
    assert!(matches!(err, Error::Halted { address: A1, state } if state.contains(StateFlag::Halted)), "{err}");
    assert!(bus.started().is_empty(), "halted, at rest: nothing left for the close to stop");
    events(&host);
    // The next call checks the module again, and refuses it before any motion command.
    let before = handled(&host);
    let err = m.setpoint(vel(0.2), EXT, Guard::HaltOnly).unwrap_err();
    assert!(matches!(err, Error::Halted { address: A1, .. }), "{err}");
    assert!(handled(&host) > before, "read again");
    assert!(!commanded(&host), "no motion command sent to the halted module");
    // A reset (which drops the cache too) and the stream goes on.
    m.reset().unwrap();
    let report = m.setpoint(vel(0.2), EXT, Guard::HaltOnly).unwrap();
    assert!(!report.ext_ack.unwrap().state.contains(ShortFlag::NotOk), "{report:?}");
    let (_, exchanges) = stream(&clock, &host, &m, vel(0.2), 5);
    assert_eq!(exchanges, 5);
}

#[test]
fn a_module_not_homed_streams_without_a_state_read_per_call() {
    let (clock, host, bus, _) = rs232_instant(&[1]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(addr(1));
    let first = m.setpoint(vel(0.2), EXT, Guard::HaltOnly).unwrap();
    assert!(first.ext_ack.unwrap().state.contains(ShortFlag::NotOk), "not homed is SHORT_NOT_OK");
    let (reports, exchanges) = stream(&clock, &host, &m, vel(0.2), 50);
    assert!(reports.iter().all(|r| r.ext_ack.unwrap().state.contains(ShortFlag::NotOk)));
    rising(&reports.iter().map(at).collect::<Vec<_>>());
    // 500 ms of setpoints: the state read again at most every 100 ms, never once per call.
    let reads = exchanges - 50;
    assert!(reads <= 5, "{reads} state reads in 50 calls");
    // A module not homed halted by someone else is seen all the same, within 100 ms.
    host.with_device(|d| d.request(clock.now(), 1, &Request::Action(Action::Halt)));
    let halted_at = clock.now();
    let mut next = halted_at;
    let err = loop {
        next += Duration::from_millis(10);
        clock.sleep_until(next);
        match m.setpoint(vel(0.2), EXT, Guard::HaltOnly) {
            Ok(_) => assert!(clock.now().saturating_since(halted_at) <= Duration::from_millis(110), "not seen"),
            Err(e) => break e,
        }
    };
    assert!(matches!(err, Error::Halted { address: A1, .. }), "{err}");
}

#[test]
fn fcur_and_ivel_setpoints_stream_with_their_limits() {
    let (clock, host, bus, _) = rs232_instant(&[1]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(addr(1));
    m.home_and_wait(secs(10), &mut |_| {}).unwrap();
    // FCUR_ACK: the current moves the module; beyond MaxCur refused, nothing sent.
    let cur = Motion::FCur { cur: Amperes(1.0) };
    assert_eq!(m.setpoint(cur, EXT, Guard::HaltOnly).unwrap().mode, MotionId::FCurAck);
    let (reports, exchanges) = stream(&clock, &host, &m, cur, 10);
    assert_eq!(exchanges, 10);
    rising(&reports.iter().map(at).collect::<Vec<_>>());
    let before = handled(&host);
    let err = m.setpoint(Motion::FCur { cur: Amperes(-6.0) }, EXT, Guard::HaltOnly).unwrap_err();
    assert!(matches!(err, Error::OutsideLimits { limit: Param::MaxCur, .. }), "{err}");
    assert_eq!(handled(&host), before);
    // IVEL_ACK: ticks/s against ActIMaxVel, the position in ticks.
    let ivel = Motion::IVel { vel: TicksPerSec((0.2 * RATIO) as i32) };
    assert_eq!(m.setpoint(ivel, EXT, Guard::HaltOnly).unwrap().mode, MotionId::IVelAck);
    let (reports, exchanges) = stream(&clock, &host, &m, ivel, 10);
    assert_eq!(exchanges, 10);
    let ticks: Vec<i32> = reports.iter().map(ticks_at).collect();
    rising(&ticks);
    let before = handled(&host);
    let err = m.setpoint(Motion::IVel { vel: TicksPerSec(70_000) }, EXT, Guard::HaltOnly).unwrap_err();
    assert!(matches!(err, Error::OutsideLimits { limit: Param::ActIMaxVel, .. }), "{err}");
    assert_eq!(handled(&host), before);
    // With the simple acknowledge: one exchange too, no position.
    let simple = m.setpoint(ivel, AckKind::Simple, Guard::HaltOnly).unwrap();
    assert_eq!((simple.mode, simple.ext_ack), (MotionId::IVel, None));
    let before = handled(&host);
    assert_eq!(m.setpoint(ivel, AckKind::Simple, Guard::HaltOnly).unwrap().ext_ack, None);
    assert_eq!(handled(&host) - before, 1);
}

#[test]
fn a_lost_acknowledge_halts_the_module() {
    let (clock, host, bus, faults) = rs232_instant(&[1]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(addr(1));
    m.setpoint(vel(0.2), EXT, Guard::HaltOnly).unwrap();
    // The start of the next acknowledge is lost on the way: the command may have been taken.
    faults.drop_next(Direction::DeviceToHost, 3);
    let err = m.setpoint(vel(0.3), EXT, Guard::HaltOnly).unwrap_err();
    assert!(matches!(err, Error::FailedDuringMotion { address: A1, stop: StopOutcome::Confirmed, .. }), "{err}");
    let state = sim_module(&host, 1).0;
    assert!(state.contains(StateFlag::Halted) && !state.contains(StateFlag::Motion), "{state}");
}
