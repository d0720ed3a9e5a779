//! Every motion mode run to its end with the checks of a ramp move (`run_motion`): limits refused before
//! anything moves, targets read back and reached within the tolerance, continuous modes held and ended
//! (velocity 0 or a confirmed halt), a cancel that halts, the guard's watchdog armed and disarmed.

use super::*;
use crate::client::{Guard, MotionEnding, MotionReport, MotionSpec, StopOutcome};
use crate::error::Error;
use crate::model::*;
use crate::wire::AckPosition;
use motionlink_link::cancel::CancelToken;

/// The emulator's encoder ticks per rad (4096 per turn through a 1:100 gear).
const RATIO: f64 = 4096.0 * 100.0 / std::f64::consts::TAU;

fn held(motion: Motion, ms: u64) -> MotionSpec {
    MotionSpec { hold: Some(Duration::from_millis(ms)), ..MotionSpec::new(motion) }
}

fn events(host: &EmulatorHost<Emulator>) -> Vec<String> {
    host.with_device(|d| d.take_events())
}

#[test]
fn a_velocity_held_then_ended_with_velocity_zero_leaves_the_module_at_rest_moved_its_way_and_not_halted() {
    let (clock, host, bus, _) = rs232_instant(&[1]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(addr(1));
    let mut polls = 0;
    let spec = held(Motion::FVel { vel: Velocity::rad_per_s(0.2) }, 300);
    let report: MotionReport = m.run_motion(&spec, &mut |_| polls += 1).unwrap();
    assert_eq!(
        (report.mode, report.ending, report.kind),
        (MotionId::FVel, MotionEnding::VelocityZero, ModuleKind::Rotary)
    );
    let ran = report.held.unwrap();
    assert!(ran >= Duration::from_millis(300) && ran < Duration::from_millis(400), "{ran:?}");
    assert!(polls >= 10, "the hold was watched: {polls} polls");
    assert_eq!((report.start, report.target), (Position::rad(0.05), None));
    assert!(report.reached.value() - report.start.value() > 0.03, "moved in the velocity's direction: {report:?}");
    assert!(!report.state.contains(StateFlag::Motion) && !report.state.contains(StateFlag::Halted), "{report:?}");
    // The velocity sent cannot be read back, and the report says so.
    assert!(!report.verified && report.not_verifiable[0].contains("velocity the module took"), "{report:?}");
    let (state, position) = sim_module(&host, 1);
    assert!(!state.contains(StateFlag::Motion) && !state.contains(StateFlag::Halted), "{state}");
    assert!((position - report.reached.value()).abs() < 1e-6, "at rest where the report says");
    assert!(bus.started().is_empty());
    // The other way, in ticks/s: IVEL, ended with IVEL 0.
    let back = held(Motion::IVel { vel: TicksPerSec(-(0.2 * RATIO) as i32) }, 300);
    let report = m.run_motion(&back, &mut |_| {}).unwrap();
    assert_eq!((report.mode, report.ending), (MotionId::IVel, MotionEnding::VelocityZero));
    assert!(report.start.value() - report.reached.value() > 0.03, "{report:?}");
    assert!(!sim_module(&host, 1).0.contains(StateFlag::Halted));
    let seen = events(&host);
    assert!(!seen.iter().any(|e| e.contains("halted")), "ended by the velocity 0, never halted: {seen:?}");
    assert!(seen.last().is_some_and(|e| e.contains("at rest")), "{seen:?}");
}

#[test]
fn a_current_held_then_halted_confirms_the_halt_by_the_state() {
    let (clock, host, bus, _) = rs232_instant(&[1]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(addr(1));
    let report = m.run_motion(&held(Motion::FCur { cur: Amperes(1.0) }, 400), &mut |_| {}).unwrap();
    assert_eq!((report.mode, report.ending), (MotionId::FCur, MotionEnding::Halted));
    assert!(report.state.contains(StateFlag::Halted) && !report.state.contains(StateFlag::Motion), "{report:?}");
    assert!(report.reached.value() > report.start.value(), "the current moved it: {report:?}");
    assert!(report.held.unwrap() >= Duration::from_millis(400));
    let state = sim_module(&host, 1).0;
    assert!(state.contains(StateFlag::Halted) && !state.contains(StateFlag::Motion), "{state}");
    assert!(bus.started().is_empty(), "halted: nothing left for the close to stop");
    // Halted, it takes no motion until a reset: the next run is refused before anything is sent.
    events(&host);
    let err = m.run_motion(&held(Motion::ICur { cur: CurrentDigits(100) }, 200), &mut |_| {}).unwrap_err();
    assert!(matches!(err, Error::Halted { address: A1, .. }), "{err}");
    assert!(events(&host).is_empty());
    m.reset().unwrap();
    let report = m.run_motion(&held(Motion::ICur { cur: CurrentDigits(-100) }, 200), &mut |_| {}).unwrap();
    assert_eq!((report.mode, report.ending), (MotionId::ICur, MotionEnding::Halted));
    assert!(report.reached.value() < report.start.value(), "{report:?}");
}

#[test]
fn a_cosine_loop_held_then_halted() {
    let (clock, host, bus, _) = rs232_instant(&[1]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(addr(1));
    let spec = held(Motion::FCosLoop { pos: Position::rad(0.5), time: Millis(2000) }, 700);
    let report = m.run_motion(&spec, &mut |_| {}).unwrap();
    assert_eq!((report.mode, report.ending, report.target), (MotionId::FCosLoop, MotionEnding::Halted, None));
    assert!(report.state.contains(StateFlag::Halted), "{report:?}");
    assert!(report.reached.value() > 0.1 && report.reached.value() < 0.5, "on its way out: {report:?}");
    assert!(report.not_verifiable.iter().any(|n| n.contains("loop's far end")), "{report:?}");
    assert!(sim_module(&host, 1).0.contains(StateFlag::Halted));
    // A loop's far end beyond MaxPos is refused as a ramp target is.
    m.reset().unwrap();
    let err = m.run_motion(&held(Motion::FRampLoop { pos: Position::rad(4.0) }, 500), &mut |_| {}).unwrap_err();
    assert!(matches!(err, Error::OutsideLimits { limit: Param::MaxPos, .. }), "{err}");
    assert!(err.to_string().contains("the loop's far end 4 rad is outside MinPos..MaxPos"), "{err}");
}

#[test]
fn a_step_reaches_its_target_within_the_tolerance_its_target_read_back_from_stepinc() {
    let (clock, host, bus, _) = rs232_instant(&[1]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(addr(1));
    let spec = MotionSpec::new(Motion::FStep { pos: Position::rad(0.3), time: Millis(1000) });
    let report = m.run_motion(&spec, &mut |_| {}).unwrap();
    assert_eq!((report.mode, report.ending, report.held), (MotionId::FStep, MotionEnding::Reached, None));
    assert_eq!(report.target, Some(Position::rad(0.3)));
    assert!((report.reached.value() - 0.3).abs() <= 0.001, "{report:?}");
    assert!(report.verified && report.not_verifiable.is_empty(), "StepInc showed the target: {report:?}");
    assert!(!report.state.contains(StateFlag::Motion) && !report.state.contains(StateFlag::Halted));
    assert!((sim_module(&host, 1).1 - 0.3).abs() <= 0.001);
    // A step faster than MaxVel allows (1.7 rad in 100 ms) is refused, not stretched by the module.
    events(&host);
    let fast = MotionSpec::new(Motion::FStep { pos: Position::rad(2.0), time: Millis(100) });
    let err = m.run_motion(&fast, &mut |_| {}).unwrap_err();
    assert!(matches!(err, Error::OutsideLimits { limit: Param::MaxVel, .. }), "{err}");
    assert!(err.to_string().contains("the speed the step needs"), "{err}");
    assert!(events(&host).is_empty(), "nothing moved");
    // A position mode ends at its target: a hold is refused before anything is read.
    let err = m.run_motion(&MotionSpec { hold: Some(secs(1)), ..spec }, &mut |_| {}).unwrap_err();
    assert!(matches!(err, Error::InvalidArgument { what: "the hold", .. }) && err.is_usage(), "{err}");
    let zero = MotionSpec::new(Motion::FStep { pos: Position::rad(0.3), time: Millis(0) });
    let err = m.run_motion(&zero, &mut |_| {}).unwrap_err();
    assert!(matches!(err, Error::InvalidArgument { what: "the time of FSTEP_MODE", .. }), "{err}");
    assert!(events(&host).is_empty());
}

#[test]
fn a_ramp_in_ticks_is_reached_and_an_ack_mode_gives_its_extended_acknowledge() {
    let (clock, host, bus, _) = rs232_instant(&[1]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(addr(1));
    let ticks = 26_000;
    let spec = MotionSpec { ack: AckKind::Extended, ..MotionSpec::new(Motion::IRamp { pos: Ticks(ticks) }) };
    let report = m.run_motion(&spec, &mut |_| {}).unwrap();
    assert_eq!((report.mode, report.ending), (MotionId::IRampAck, MotionEnding::Reached));
    let target = (f64::from(ticks) / RATIO) as f32;
    assert_eq!(report.target, Some(Position::rad(target)), "converted from ticks with IncRatio");
    assert!((report.reached.value() - target).abs() <= 0.001, "{report:?}");
    assert!(report.verified, "TargetPosInc showed the target: {report:?}");
    assert!(report.state.contains(StateFlag::RampEnd));
    let ack = report.ext_ack.expect("IRAMP_ACK is answered with the extended acknowledge");
    let start_ticks = (0.05 * RATIO).round() as i32;
    assert_eq!(ack.position, AckPosition::Ticks(Ticks(start_ticks)), "where it stood when it took the command");
    let in_ticks = host.with_device(|d| d.module(1).unwrap().position_ticks());
    assert!((in_ticks.0 - ticks).abs() <= 1, "{in_ticks:?}");
    // A float mode's extended acknowledge carries the position in the module's unit; ISTEP in ticks.
    let vel = MotionSpec { ack: AckKind::Extended, ..held(Motion::FVel { vel: Velocity::native(-0.2) }, 200) };
    let report = m.run_motion(&vel, &mut |_| {}).unwrap();
    assert_eq!(report.mode, MotionId::FVelAck);
    assert!(matches!(report.ext_ack.map(|e| e.position), Some(AckPosition::Unit(p)) if p.unit() == AxisUnit::Radian));
    let step = MotionSpec::new(Motion::IStep { pos: Ticks(0), time: Millis(1000) });
    let report = m.run_motion(&step, &mut |_| {}).unwrap();
    assert!(report.reached.value().abs() <= 0.001 && report.verified, "{report:?}");
    // FRAMP through the same checks: TargetPosInc read back, STATE_RAMP_END, the final position.
    let ramp = MotionSpec { ack: AckKind::Extended, ..MotionSpec::new(Motion::FRamp { pos: Position::rad(0.2) }) };
    let report = m.run_motion(&ramp, &mut |_| {}).unwrap();
    assert_eq!((report.mode, report.target), (MotionId::FRampAck, Some(Position::rad(0.2))));
    assert!((report.reached.value() - 0.2).abs() <= 0.001 && report.verified && report.ext_ack.is_some(), "{report:?}");
    // A loop has no extended acknowledge: refused before anything is sent.
    let loop_ack = MotionSpec { ack: AckKind::Extended, ..held(Motion::FRampLoop { pos: Position::rad(0.5) }, 100) };
    let err = m.run_motion(&loop_ack, &mut |_| {}).unwrap_err();
    assert!(err.is_usage() && err.to_string().contains("FRAMPLOOP has no mode with extended acknowledge"), "{err}");
}

#[test]
fn limits_are_refused_before_anything_moves_never_clamped() {
    let (clock, host, bus, _) = rs232_instant(&[1]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(addr(1));
    m.kind().unwrap();
    events(&host);
    let beyond = [
        (Motion::FVel { vel: Velocity::rad_per_s(1.5) }, Param::MaxVel, "the velocity 1.5 rad/s"),
        (Motion::FVel { vel: Velocity::native(-1.5) }, Param::MaxVel, "the velocity -1.5 rad/s"),
        (Motion::IVel { vel: TicksPerSec(70_000) }, Param::ActIMaxVel, "the velocity in ticks/s 70000"),
        (Motion::FCur { cur: Amperes(6.0) }, Param::MaxCur, "the current 6 A is outside the module's limit MaxCur"),
        (Motion::FCur { cur: Amperes(-5.5) }, Param::MaxCur, "the current -5.5 A"),
        (Motion::FCosLoop { pos: Position::rad(-3.5), time: Millis(1000) }, Param::MinPos, "the loop's far end"),
    ];
    for (motion, limit, says) in beyond {
        let err = m.run_motion(&held(motion, 300), &mut |_| {}).unwrap_err();
        assert!(matches!(err, Error::OutsideLimits { limit: l, .. } if l == limit), "{motion:?}: {err}");
        assert!(err.is_usage() && err.to_string().contains(says), "{err}");
    }
    for (motion, limit) in [
        (Motion::FRamp { pos: Position::rad(3.2) }, Param::MaxPos),
        (Motion::IRamp { pos: Ticks(300_000) }, Param::ActIMaxPos),
        (Motion::IStep { pos: Ticks(-300_000), time: Millis(60_000) }, Param::ActIMinPos),
    ] {
        let err = m.run_motion(&MotionSpec::new(motion), &mut |_| {}).unwrap_err();
        assert!(matches!(err, Error::OutsideLimits { limit: l, .. } if l == limit), "{motion:?}: {err}");
    }
    // ICUR beyond its digits, a NaN, a tolerance for a velocity: refused by the spec itself.
    for (spec, what) in [
        (held(Motion::ICur { cur: CurrentDigits(501) }, 300), "the current of ICUR_MODE"),
        (held(Motion::FVel { vel: Velocity::native(f32::NAN) }, 300), "the velocity"),
        (
            MotionSpec { tolerance: Some(Position::rad(0.01)), ..held(Motion::FVel { vel: Velocity::native(0.1) }, 1) },
            "the tolerance",
        ),
        (held(Motion::FCur { cur: Amperes(1.0) }, 0), "the hold"),
    ] {
        let err = m.run_motion(&spec, &mut |_| {}).unwrap_err();
        assert!(matches!(err, Error::InvalidArgument { what: w, .. } if w == what), "{spec:?}: {err}");
    }
    // A velocity in m for a rotary module.
    let err = m.run_motion(&held(Motion::FVel { vel: Velocity::m_per_s(0.1) }, 300), &mut |_| {}).unwrap_err();
    assert!(matches!(err, Error::UnitMismatch { .. }), "{err}");
    // Nothing was sent that moves: the module stands where it stood.
    assert!(events(&host).is_empty());
    let (state, position) = sim_module(&host, 1);
    assert_eq!(position, 0.05);
    assert!(!state.contains(StateFlag::Motion) && !state.contains(StateFlag::Halted), "{state}");
    assert!(bus.started().is_empty());
}

#[test]
fn a_cancel_during_the_hold_halts_the_module_and_says_it_was_confirmed() {
    let (clock, host, bus, _) = rs232_instant(&[1]);
    let _me = clock.reserve_participant().enter();
    let token = CancelToken::new();
    bus.set_cancel(token.clone());
    let m = bus.module(addr(1));
    // No hold: it runs until cancelled.
    let spec = MotionSpec::new(Motion::FVel { vel: Velocity::native(0.2) });
    let err = m
        .run_motion(&spec, &mut |p| {
            if p.elapsed >= Duration::from_millis(300) {
                token.cancel();
            }
        })
        .unwrap_err();
    assert!(matches!(err, Error::Cancelled { address: A1, stop: StopOutcome::Confirmed }), "{err}");
    let (state, position) = sim_module(&host, 1);
    assert!(state.contains(StateFlag::Halted) && !state.contains(StateFlag::Motion), "{state}");
    assert!(position > 0.06, "it ran until the cancel: {position}");
    assert!(bus.started().is_empty());
    // Cancelled before anything was sent: nothing to stop.
    token.reset();
    m.reset().unwrap();
    events(&host);
    token.cancel();
    let err = m.run_motion(&held(Motion::FCur { cur: Amperes(1.0) }, 300), &mut |_| {}).unwrap_err();
    assert!(matches!(err, Error::Cancelled { stop: StopOutcome::NotStarted, .. }), "{err}");
    assert!(!events(&host).iter().any(|e| e.contains("motion started")));
}

#[test]
fn a_fault_during_the_hold_ends_it_as_a_wait_ends() {
    // Homed, the soft limit holds: a velocity that runs into MaxPos stops the module with STATE_BEYOND_SOFT.
    let (clock, host, bus, _) = rs232_instant(&[1]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(addr(1));
    m.home_and_wait(secs(10), &mut |_| {}).unwrap();
    let err = m.run_motion(&held(Motion::FVel { vel: Velocity::native(1.0) }, 10_000), &mut |_| {}).unwrap_err();
    assert!(matches!(err, Error::Device { address: A1, state } if state.contains(StateFlag::BeyondSoft)), "{err}");
    let state = sim_module(&host, 1).0;
    assert!(state.contains(StateFlag::Halted) && !state.contains(StateFlag::Motion), "{state}");
}

#[test]
fn a_guarded_motion_on_can_arms_the_watchdog_for_its_hold_and_disarms_it_after() {
    let (clock, canbus, bus) = can(&[1, 2]);
    let before = device_view(&canbus, &clock, 1).3;
    let (ran, online_meanwhile) = std::thread::scope(|scope| {
        let (mover, looker) = (clock.reserve_participant(), clock.reserve_participant());
        let bus = &bus;
        let moving = scope.spawn(move || {
            let _p = mover.enter();
            let spec = held(Motion::FVel { vel: Velocity::native(0.2) }, 1000);
            bus.module(addr(1)).run_motion_guarded(&spec, Guard::Watchdog, &mut |_| {})
        });
        let (clock, canbus) = (&clock, &canbus);
        let looking = scope.spawn(move || {
            let _p = looker.enter();
            clock.sleep(Duration::from_millis(500));
            device_view(canbus, clock, 1).2
        });
        (moving.join().unwrap(), looking.join().unwrap())
    });
    let _me = clock.reserve_participant().enter();
    assert!(online_meanwhile, "the watchdog was online during the hold");
    let report = ran.unwrap();
    assert_eq!(report.ending, MotionEnding::VelocityZero);
    assert!(!bus.watchdog_served(), "no watchdog left to serve");
    clock.sleep(secs(1));
    let (state, position, online, config) = device_view(&canbus, &clock, 1);
    assert!(!online, "switched off once");
    assert!(
        !state.contains(StateFlag::Halted) && !state.has_fault() && !state.contains(StateFlag::CommError),
        "{state}"
    );
    assert_eq!(config, before, "the Config word as it was");
    assert!((position - report.reached.value()).abs() < 1e-6);
    // A guarded current ends halted, its watchdog off too.
    let report = bus
        .module(addr(2))
        .run_motion_guarded(&held(Motion::FCur { cur: Amperes(1.0) }, 300), Guard::Watchdog, &mut |_| {})
        .unwrap();
    assert_eq!(report.ending, MotionEnding::Halted);
    let (state, _, online, _) = device_view(&canbus, &clock, 2);
    assert!(state.contains(StateFlag::Halted) && !online && !state.contains(StateFlag::CommError), "{state}");
    assert_eq!(bus.close().map_err(|e| e.to_string()), Ok(vec![]));
}

#[test]
fn a_guarded_motion_beyond_a_limit_is_refused_before_the_guard_arms_anything() {
    let (clock, canbus, bus) = can(&[1]);
    let _me = clock.reserve_participant().enter();
    let before = device_view(&canbus, &clock, 1).3;
    let spec = held(Motion::FVel { vel: Velocity::native(2.0) }, 300);
    let err = bus.module(addr(1)).run_motion_guarded(&spec, Guard::Watchdog, &mut |_| {}).unwrap_err();
    assert!(matches!(err, Error::OutsideLimits { limit: Param::MaxVel, .. }), "{err}");
    let (state, position, online, config) = device_view(&canbus, &clock, 1);
    assert!(!online && config == before && !state.contains(StateFlag::Motion), "{state}");
    assert_eq!(position, 0.05);
}

/// Module 1 of the emulator running `variants`, on an RS232 line whose bytes arrive at once.
fn rs232_variant(variants: &[crate::sim::Variant]) -> (ManualClock, EmulatorHost<Emulator>, Client) {
    let config = SimConfig { variants: variants.to_vec(), ..SimConfig::default() };
    let rig = Rig::new(Emulator::new(&config), PipeConfig::instant());
    let bus = Client::with_link(PortLink::Rs232(rig.link().unwrap()), rig.clock.shared(), Config::rs232()).unwrap();
    (rig.clock, rig.host, bus)
}

#[test]
fn what_a_firmware_variant_does_not_show_is_said_never_claimed() {
    use crate::sim::Variant;
    // A module that starts 0.3 s after the acknowledge shows the step's target in StepInc only then: read
    // again once the step is over, and found.
    let (clock, _host, bus) = rs232_variant(&[Variant::LateMotionStart]);
    let _me = clock.reserve_participant().enter();
    let step = MotionSpec::new(Motion::FStep { pos: Position::native(0.3), time: Millis(1000) });
    let report = bus.module(addr(1)).run_motion(&step, &mut |_| {}).unwrap();
    assert!((report.reached.value() - 0.3).abs() <= 0.001 && report.verified, "{report:?}");
    drop(_me);
    // A module that keeps TargetPosInc apart from the target: the ramp in ticks is reached, its target
    // not read back, and the report says so.
    let (clock, _host, bus) = rs232_variant(&[Variant::NoTwinMirror]);
    let _me = clock.reserve_participant().enter();
    let report = bus.module(addr(1)).run_motion(&MotionSpec::new(Motion::IRamp { pos: Ticks(13_000) }), &mut |_| {});
    let report = report.unwrap();
    assert!(
        !report.verified && report.not_verifiable[0].contains("keeps TargetPosInc apart from the targets it is sent"),
        "{report:?}"
    );
    assert!((report.reached.value() - (13_000.0 / RATIO) as f32).abs() <= 0.001, "{report:?}");
    drop(_me);
    // A firmware before extended acknowledges takes an _ACK mode with the simple one: no ext_ack, and the
    // motion ran.
    let (clock, _host, bus) = rs232_variant(&[Variant::NoExtendedAck]);
    let _me = clock.reserve_participant().enter();
    let spec = MotionSpec { ack: AckKind::Extended, ..held(Motion::FVel { vel: Velocity::native(0.2) }, 300) };
    let report = bus.module(addr(1)).run_motion(&spec, &mut |_| {}).unwrap();
    assert_eq!((report.mode, report.ext_ack, report.ending), (MotionId::FVelAck, None, MotionEnding::VelocityZero));
    assert!(report.reached.value() > report.start.value() + 0.03, "{report:?}");
}

#[test]
fn a_ramp_mode_with_the_module_s_own_velocity_found_to_be_0_is_refused_before_it_is_sent() {
    let (clock, host, bus, _) = rs232_instant(&[1]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(addr(1));
    // The checked write finds out that TargetVelInc mirrors TargetVel, and it is 0: a ramp would not move.
    m.set_checked(Param::TargetVel, Value::F32(0.0)).unwrap();
    events(&host);
    let ticks = (0.3 * RATIO).round() as i32;
    for motion in [
        Motion::FRamp { pos: Position::rad(0.3) },
        Motion::IRamp { pos: Ticks(ticks) },
        Motion::FRampLoop { pos: Position::rad(0.3) },
    ] {
        let spec = if motion.continuous() { held(motion, 200) } else { MotionSpec::new(motion) };
        let err = m.run_motion(&spec, &mut |_| {}).unwrap_err();
        assert!(matches!(err, Error::InvalidArgument { what: "the velocity", .. }), "{motion:?}: {err}");
        assert!(err.to_string().contains("found to mirror it"), "{err}");
    }
    assert!(events(&host).is_empty(), "nothing was sent that moves");
    assert!(!sim_module(&host, 1).0.contains(StateFlag::Motion));
    // A step takes its own time, not TargetVel: it runs.
    let step = MotionSpec::new(Motion::FStep { pos: Position::rad(0.1), time: Millis(500) });
    assert_eq!(m.run_motion(&step, &mut |_| {}).unwrap().ending, MotionEnding::Reached);
}
