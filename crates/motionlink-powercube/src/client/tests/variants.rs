//! The core operations against every firmware variant of the emulator (`sim::Variant`), in-process on the
//! manual clock: each works, or ends with an error that says what the module did not do; a move never ends
//! in success away from its target. Then the discrepancies that are refused whatever was probed: a twin that
//! mirrors but shows another value, a motion target that the module took otherwise.

use super::*;
use crate::client::{Guard, HomeReport, MoveReport, Readback};
use crate::error::Error;
use crate::model::{Acceleration, Param, StateFlag, Value};
use crate::sim::Variant;

/// An RS232 bus of one module at 1 running `variants`, paced at 9600 baud.
fn rs232_variant(variants: &[Variant]) -> (ManualClock, EmulatorHost<Emulator>, Client) {
    let clock = ManualClock::new_auto();
    let config = SimConfig { variants: variants.to_vec(), ..SimConfig::default() };
    let host = EmulatorHost::new(Emulator::new(&config), clock.shared(), PipeConfig::paced(9_600));
    let bus = Client::with_link(PortLink::Rs232(Box::new(host.connect().0)), clock.shared(), Config::rs232()).unwrap();
    (clock, host, bus)
}

/// What the core operations gave against one variant.
#[derive(Debug)]
struct Outcome {
    set: Result<Readback, Error>,
    home: Result<HomeReport, Error>,
    moved_with_speed: Result<MoveReport, Error>,
    moved_without_speed: Result<MoveReport, Error>,
    position: f32,
    closed: Result<(), Error>,
}

/// A CAN bus of one module at 1 running `variants`, at 1 Mbit/s.
fn can_variant(variants: &[Variant]) -> (ManualClock, CanBus<Emulator>, Client) {
    let clock = ManualClock::new_auto();
    let config = SimConfig { variants: variants.to_vec(), ..SimConfig::default() };
    let canbus = CanBus::with_emulator(Emulator::new_can(&config), clock.shared(), CanBusConfig::paced(1_000_000));
    let bus = Client::with_link(PortLink::Can(Box::new(canbus.connect())), clock.shared(), Config::can()).unwrap();
    (clock, canbus, bus)
}

/// Open, scan, get, watch (state and position polled), set, home, move with and without a speed, halt,
/// reset, close, on RS232: the watchdog armed as `motionlink powercube` arms it.
fn core_operations(variants: &[Variant]) -> Outcome {
    let (clock, host, bus) = rs232_variant(variants);
    let _me = clock.reserve_participant().enter();
    let position = || host.with_device(|d| d.module(1).unwrap().position().value());
    run_core_operations(bus, variants, &position)
}

/// The same on CAN.
fn core_operations_can(variants: &[Variant]) -> Outcome {
    let (clock, canbus, bus) = can_variant(variants);
    let _me = clock.reserve_participant().enter();
    let position = || device_view(&canbus, &clock, 1).1;
    run_core_operations(bus, variants, &position)
}

fn run_core_operations(bus: Client, variants: &[Variant], device_position: &dyn Fn() -> f32) -> Outcome {
    let found = bus.scan().unwrap();
    assert_eq!(found.len(), 1, "{variants:?}");
    assert!(found[0].info.is_ok(), "{variants:?}: {:?}", found[0].info);
    let m = bus.module(addr(1));
    assert_eq!(m.get(Param::DefCubeSerial).unwrap(), Value::U32(1001));
    for _ in 0..3 {
        m.state().unwrap();
        m.position().unwrap();
    }
    let set = m.set_checked(Param::TargetVel, Value::F32(0.8));
    let home = m.home_guarded(secs(10), Guard::Watchdog, &mut |_| {});
    let with_speed = MoveSpec {
        vel: Some(Velocity::native(0.7)),
        acc: Some(Acceleration::native(1.5)),
        ..MoveSpec::to(Position::native(0.4))
    };
    let moved_with_speed = m.move_to_guarded(&with_speed, Guard::Watchdog, &mut |_| {});
    let moved_without_speed = m.move_to_guarded(&MoveSpec::to(Position::native(0.2)), Guard::Watchdog, &mut |_| {});
    let position = device_position();
    m.halt().unwrap();
    assert!(m.state().unwrap().contains(StateFlag::Halted));
    m.reset().unwrap();
    let closed = bus.close().map(|_| ());
    Outcome { set, home, moved_with_speed, moved_without_speed, position, closed }
}

/// The move ended where it was sent, by the module's own reading.
fn at(report: &MoveReport, target: f32) -> bool {
    (report.reached.value() - target).abs() <= 0.001
}

#[test]
fn the_default_firmware_is_verified_throughout() {
    let o = core_operations(&[]);
    let set = o.set.unwrap();
    assert!(set.verified && set.not_verifiable.is_empty() && set.read.is_some(), "{set:?}");
    let h = o.home.unwrap();
    assert!(h.verified && h.not_verifiable.is_empty() && h.state.contains(StateFlag::HomeOk), "{h:?}");
    let r = o.moved_with_speed.unwrap();
    assert!(at(&r, 0.4) && r.verified && r.not_verifiable.is_empty(), "{r:?}");
    let r = o.moved_without_speed.unwrap();
    assert!(at(&r, 0.2) && r.verified, "{r:?}");
    assert!((o.position - 0.2).abs() <= 0.001);
    o.closed.unwrap();
}

#[test]
fn a_module_that_keeps_the_twins_apart_moves_unverified_and_says_why() {
    let o = core_operations(&[Variant::NoTwinMirror]);
    let set = o.set.unwrap();
    assert!(!set.verified && set.read.is_none(), "{set:?}");
    assert!(set.not_verifiable[0].contains("keeps TargetVelInc apart from it"), "{set:?}");
    o.home.unwrap();
    let r = o.moved_with_speed.unwrap();
    assert!(at(&r, 0.4) && !r.verified, "{r:?}");
    let why = r.not_verifiable.join("\n");
    for needle in ["TargetVel could not be read back", "TargetAcc could not be read back", "the motion's target"] {
        assert!(why.contains(needle), "{needle}: {why}");
    }
    let r = o.moved_without_speed.unwrap();
    assert!(at(&r, 0.2) && !r.verified && r.not_verifiable.len() == 1, "{r:?}");
    assert!((o.position - 0.2).abs() <= 0.001);
    o.closed.unwrap();
}

#[test]
fn a_module_that_ignores_the_rs232_broadcast_moves_without_a_watchdog_and_says_so() {
    let o = core_operations(&[Variant::NoBroadcastPair]);
    assert!(o.set.unwrap().verified);
    // Homing ran without the watchdog too, and says so as a move does.
    let h = o.home.unwrap();
    assert!(h.state.contains(StateFlag::HomeOk) && !h.verified, "{h:?}");
    assert_eq!(h.not_verifiable.len(), 1, "{h:?}");
    assert!(h.not_verifiable[0].contains("ignores the watchdog refresh broadcast on RS232"), "{h:?}");
    for (r, target) in [(o.moved_with_speed.unwrap(), 0.4), (o.moved_without_speed.unwrap(), 0.2)] {
        assert!(at(&r, target) && !r.verified, "{r:?}");
        assert!(r.not_verifiable[0].contains("ignores the watchdog refresh broadcast on RS232"), "{r:?}");
    }
    o.closed.unwrap();
}

#[test]
fn variants_the_client_takes_as_they_are() {
    // The guarded home and moves use the simple acknowledge, and the Reset here clears no expired watchdog.
    for v in [
        Variant::AckLength6,
        Variant::NoPosStateDio,
        Variant::ExtAckOnPutId,
        Variant::ResetClearsWatchdog,
        Variant::NoExtendedAck,
        Variant::LateMotionStart,
    ] {
        let o = core_operations(&[v]);
        assert!(o.set.as_ref().is_ok_and(|s| s.verified), "{v}: {o:?}");
        assert!(o.home.is_ok(), "{v}: {o:?}");
        assert!(o.moved_with_speed.as_ref().is_ok_and(|r| at(r, 0.4) && r.verified), "{v}: {o:?}");
        assert!(o.moved_without_speed.as_ref().is_ok_and(|r| at(r, 0.2) && r.verified), "{v}: {o:?}");
        assert!(o.closed.is_ok(), "{v}: {o:?}");
    }
}

#[test]
fn a_life_sign_that_is_not_acknowledged_refuses_the_guarded_motion_and_says_so() {
    let o = core_operations(&[Variant::LifeSignUnacknowledged]);
    assert!(o.set.unwrap().verified);
    // The first: the life sign got no acknowledge, so whether the watchdog is online is not known. Switching
    // it off again finds out the only way the manual offers: it expires. So the moves after it find the
    // module with STATE_COMM_ERROR, and say so.
    let text = o.home.as_ref().unwrap_err().to_string();
    assert!(text.contains("cannot arm the watchdog of module 1") && text.contains("not acknowledged"), "{text}");
    for e in [o.home.unwrap_err(), o.moved_with_speed.unwrap_err(), o.moved_without_speed.unwrap_err()] {
        let text = e.to_string();
        assert!(text.contains("cannot arm the watchdog of module 1"), "{text}");
        assert!(e.is_device(), "{e}");
    }
    assert!((o.position - 0.05).abs() <= 0.001, "nothing moved: {}", o.position);
    // Without the watchdog (`--no-watchdog`) the same module moves.
    let (clock, host, bus) = rs232_variant(&[Variant::LifeSignUnacknowledged]);
    let _me = clock.reserve_participant().enter();
    // A target beyond MaxPos is refused as such, before the guard tries (and fails) to arm the watchdog:
    // no life sign, no Config word written.
    let err = bus.module(addr(1)).move_to_guarded(&spec(100.0), Guard::Watchdog, &mut |_| {}).unwrap_err();
    let text = err.to_string();
    assert!(matches!(err, Error::OutsideLimits { limit: Param::MaxPos, .. }) && err.is_usage(), "{text}");
    assert!(text.contains("the target position 100") && !text.contains("watchdog"), "{text}");
    let config = host.with_device(|d| d.module(1).unwrap().config_word());
    assert!(!config.contains(crate::model::ConfigFlag::WatchdogEnable), "the guard never armed: {config}");
    let r = bus.module(addr(1)).move_to_guarded(&spec(0.3), Guard::HaltOnly, &mut |_| {}).unwrap();
    assert!(at(&r, 0.3) && r.verified, "{r:?}");
}

#[test]
fn a_module_without_the_config_word_is_scanned_and_set_but_its_guarded_motions_are_refused() {
    // Its type comes from DefConfig (the scan, the set); the arming's read of the Config word fails, so the
    // guarded home and moves are refused and nothing moves.
    let o = core_operations(&[Variant::NoConfigWord]);
    assert!(o.set.as_ref().is_ok_and(|s| s.verified), "{o:?}");
    for e in [o.home.unwrap_err(), o.moved_with_speed.unwrap_err(), o.moved_without_speed.unwrap_err()] {
        let text = e.to_string();
        assert!(text.contains("cannot arm the watchdog of module 1") && text.contains("GetExtended Config"), "{text}");
    }
    assert!((o.position - 0.05).abs() <= 0.001, "nothing moved: {}", o.position);
    o.closed.unwrap();
}

#[test]
fn a_refused_arming_leaves_the_module_as_it_was_and_the_next_guarded_move_is_refused_the_same_way() {
    let (clock, host, bus) = rs232_variant(&[Variant::LifeSignUnacknowledged]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(addr(1));
    let config_before = host.with_device(|d| d.module(1).unwrap().config_word());
    for attempt in 0..2 {
        let err = m.move_to_guarded(&spec(0.5), Guard::Watchdog, &mut |_| {}).unwrap_err();
        let text = err.to_string();
        assert!(
            text.contains("cannot arm the watchdog of module 1: module 1: watchdog not confirmed online"),
            "{text}"
        );
        // Said what became of it: it had gone online, expired once its refresh stopped, and was released
        // (the manual's restart, chapter 13): the module as before, not in error.
        assert!(text.contains("expired; it was switched offline and the module reset"), "{attempt}: {text}");
        assert!(text.contains("module 1 is left as it was"), "{attempt}: {text}");
        assert!(!text.contains("reports an error"), "{attempt}: the module was not in error: {text}");
        let (state, online, config) = host.with_device(|d| {
            let m = d.module(1).unwrap();
            (m.state(), m.watchdog_online(), m.config_word())
        });
        assert!(!state.has_fault() && !state.contains(StateFlag::Halted), "{attempt}: {state}");
        assert!(!online && config == config_before, "{attempt}: watchdog offline, Config word as it was");
    }
    // Nothing is left for the close to find out.
    bus.close().unwrap();
}

#[test]
fn a_halted_module_is_refused_before_its_watchdog_is_armed() {
    // On CAN as on RS232: the halt is found before anything of the arming goes out (a life sign the module
    // does not acknowledge would leave it an expired watchdog besides), and nothing clears it.
    let (clock, canbus, bus) = can_variant(&[Variant::LifeSignUnacknowledged]);
    let _me = clock.reserve_participant().enter();
    let host = canbus;
    let m = bus.module(addr(1));
    m.halt().unwrap();
    let err = m.move_to_guarded(&spec(0.5), Guard::Watchdog, &mut |_| {}).unwrap_err();
    assert!(matches!(err, Error::Halted { .. }) && err.is_device(), "{err}");
    let state = host.with_device(|d| d.module(1).unwrap().state()).unwrap();
    assert!(state.contains(StateFlag::Halted) && !state.contains(StateFlag::CommError), "only halted: {state}");
    assert!(!host.with_device(|d| d.module(1).unwrap().watchdog_online()).unwrap(), "never armed");
    bus.close().unwrap();
}

#[test]
fn a_move_without_speed_on_a_module_whose_twins_are_apart_uses_the_module_s_own_speed() {
    let (clock, host, bus) = rs232_variant(&[Variant::NoTwinMirror]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(addr(1));
    // TargetVelInc reads 0 (written as a user would), the float TargetVel the ramp uses is the module's own.
    m.set(Param::TargetVelInc, Value::U32(0)).unwrap();
    m.set(Param::TargetAccInc, Value::U32(0)).unwrap();
    assert_eq!(m.get(Param::TargetVelInc).unwrap(), Value::U32(0));
    let r = m.move_to(&MoveSpec::to(Position::native(0.3)), &mut |_| {}).unwrap();
    assert!(at(&r, 0.3), "{r:?}");
    assert!(!r.verified && r.not_verifiable.iter().any(|w| w.contains("TargetPosInc")), "{r:?}");
    assert!(host.with_device(|d| d.module(1).unwrap().position().value() - 0.3).abs() < 1e-3);
    // Found out now (kept apart): a second move does not even read the twin.
    let r = m.move_to(&MoveSpec::to(Position::native(0.1)), &mut |_| {}).unwrap();
    assert!(at(&r, 0.1), "{r:?}");
}

#[test]
fn every_variant_on_can() {
    // On CAN the broadcast refresh is the manual's (not probed) and the RS232 framing variants change nothing.
    for v in [
        None,
        Some(Variant::NoBroadcastPair),
        Some(Variant::AckLength6),
        Some(Variant::ExtAckOnPutId),
        Some(Variant::NoPosStateDio),
        Some(Variant::ResetClearsWatchdog),
        Some(Variant::NoExtendedAck),
        Some(Variant::LateMotionStart),
    ] {
        let o = core_operations_can(v.as_slice());
        assert!(o.set.as_ref().is_ok_and(|s| s.verified), "{v:?}: {o:?}");
        assert!(o.home.is_ok(), "{v:?}: {o:?}");
        assert!(o.moved_with_speed.as_ref().is_ok_and(|r| at(r, 0.4) && r.verified), "{v:?}: {o:?}");
        assert!(o.moved_without_speed.as_ref().is_ok_and(|r| at(r, 0.2) && r.verified), "{v:?}: {o:?}");
        assert!(o.closed.is_ok(), "{v:?}: {o:?}");
    }
    let o = core_operations_can(&[Variant::NoTwinMirror]);
    let r = o.moved_with_speed.unwrap();
    assert!(at(&r, 0.4) && !r.verified && r.not_verifiable.len() == 3, "{r:?}");
    let o = core_operations_can(&[Variant::LifeSignUnacknowledged]);
    assert!(o.home.unwrap_err().to_string().contains("not acknowledged"));
    assert!(o.moved_with_speed.is_err() && (o.position - 0.05).abs() <= 0.001, "nothing moved");
    let o = core_operations_can(&[Variant::NoConfigWord]);
    assert!(o.home.unwrap_err().to_string().contains("a module before version 3.5.00 has no Config word"));
    assert!(o.moved_with_speed.is_err() && (o.position - 0.05).abs() <= 0.001, "nothing moved");
}

#[test]
fn all_variants_at_once() {
    let o = core_operations(&[
        Variant::NoTwinMirror,
        Variant::NoBroadcastPair,
        Variant::AckLength6,
        Variant::NoPosStateDio,
    ]);
    o.home.unwrap();
    let r = o.moved_with_speed.unwrap();
    assert!(at(&r, 0.4) && !r.verified && r.not_verifiable.len() == 4, "{r:?}");
    o.closed.unwrap();
}

#[test]
fn on_can_an_extended_acknowledge_on_the_command_identifier_is_taken() {
    let clock = ManualClock::new_auto();
    let _me = clock.reserve_participant().enter();
    let config = SimConfig { variants: vec![Variant::ExtAckOnPutId], ..SimConfig::default() };
    let canbus = CanBus::with_emulator(Emulator::new_can(&config), clock.shared(), CanBusConfig::paced(1_000_000));
    let bus = Client::with_link(PortLink::Can(Box::new(canbus.connect())), clock.shared(), Config::can()).unwrap();
    let m = bus.module(addr(1));
    let motion = crate::model::Motion::FVel { vel: Velocity::native(0.0) };
    let ack = m.motion(motion, crate::model::AckKind::Extended).unwrap().expect("an extended acknowledge");
    assert!(matches!(ack.position, crate::wire::AckPosition::Unit(p) if (p.value() - 0.05).abs() < 1e-3), "{ack:?}");
    let r = m.move_to_guarded(&spec(0.3), Guard::Watchdog, &mut |_| {}).unwrap();
    assert!(at(&r, 0.3) && r.verified, "{r:?}");
    bus.close().unwrap();
}

#[test]
fn a_twin_that_mirrors_another_value_is_refused() {
    // The module mirrors TargetVel into TargetVelInc (the session finds that out with the first write),
    // then a write arrives corrupted: the twin shows another value. Refused, never taken as "kept apart".
    let (clock, host, bus, faults) = rs232_instant(&[1]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(addr(1));
    assert!(m.set_checked(Param::TargetVel, Value::F32(0.8)).unwrap().verified);
    assert_eq!(bus.session(|s| s.findings(addr(1))).target_vel_twin, Some(true));
    let write = Request::set(Param::TargetVel, Value::F32(0.6)).unwrap();
    // After the reads of MaxVel (the limit) and IncRatio, the float's most significant byte.
    let reads =
        rs232_request_len(1, &Request::Get(Param::MaxVel)) + rs232_request_len(1, &Request::Get(Param::IncRatio));
    let at = faults.bytes_sent(Direction::HostToDevice) + reads + rs232_request_len(1, &write) - 3;
    faults.inject(Direction::HostToDevice, at, motionlink_link::pipe::Fault::Corrupt { xor: 0x01 });
    let err = m.set_checked(Param::TargetVel, Value::F32(0.6)).unwrap_err();
    assert!(matches!(err, Error::ReadBack { param: Param::TargetVel, .. }) && err.is_device(), "{err}");
    // A write that leaves the twin exactly as it was is refused too once the module is known to mirror (a
    // module of the other kind is never concluded from it).
    host.with_device(|d| d.set_variants(&[Variant::NoTwinMirror]));
    let err = m.set_checked(Param::TargetVel, Value::F32(0.5)).unwrap_err();
    assert!(matches!(err, Error::ReadBack { param: Param::TargetVel, .. }), "{err}");
    assert_eq!(bus.session(|s| s.findings(addr(1))).target_vel_twin, Some(true), "still known to mirror");
}

#[test]
fn a_move_whose_target_the_mirroring_module_took_otherwise_is_halted() {
    // Known to mirror from the first move; then the module starts keeping TargetPosInc apart (as if the
    // motion command's target were lost on the way): the check after the motion command halts it.
    let (clock, host, bus, _) = rs232_instant(&[1]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(addr(1));
    assert!(m.move_to(&spec(0.3), &mut |_| {}).unwrap().verified);
    assert_eq!(bus.session(|s| s.findings(addr(1))).target_pos_twin, Some(true));
    host.with_device(|d| d.set_variants(&[Variant::NoTwinMirror]));
    let err = m.move_to(&spec(0.6), &mut |_| {}).unwrap_err();
    assert!(matches!(err, Error::TargetMismatch { stop: crate::client::StopOutcome::Confirmed, .. }), "{err}");
    let (state, p) = sim_module(&host, 1);
    assert!(state.contains(StateFlag::Halted) && p < 0.35, "halted at once: {state} at {p}");
}

#[test]
fn a_timeout_names_the_round_trips_measured_on_the_link() {
    let (clock, _host, bus, _) = rs232(&[1]);
    let _me = clock.reserve_participant().enter();
    let err = bus.module(addr(9)).state().unwrap_err();
    assert!(!err.to_string().contains("replies on this link"), "nothing measured yet: {err}");
    bus.module(addr(1)).state().unwrap();
    let err = bus.module(addr(9)).state().unwrap_err();
    let text = err.to_string();
    // At 9600 baud a GetExtended of CubeState and its acknowledge take about 15 ms on the wire.
    assert!(text.contains("did not answer") && text.contains("replies on this link have taken 1"), "{text}");
}

#[test]
fn a_look_reads_position_and_short_state_in_one_where_the_module_can_and_in_two_where_it_cannot() {
    for (variants, full_state) in [(&[][..], false), (&[Variant::NoPosStateDio][..], true)] {
        let (clock, host, bus) = rs232_variant(variants);
        let _me = clock.reserve_participant().enter();
        let m = bus.module(addr(1));
        m.kind().unwrap();
        let (position, short, state) = m.look().unwrap();
        let expected = host.with_device(|d| d.module(1).unwrap().position().value());
        assert!((position.value() - expected).abs() < 1e-6, "{variants:?}: {position:?} against {expected}");
        assert_eq!(position.unit(), crate::model::AxisUnit::Radian, "{variants:?}");
        assert_eq!(state.is_some(), full_state, "{variants:?}");
        if let Some(state) = state {
            assert_eq!(state.short_state(), short, "{variants:?}");
        }
        // The probe is made once: a second look on a module without ActFPosStateDio costs no timeout.
        let before = clock.now();
        m.look().unwrap();
        assert!(clock.now().saturating_since(before) < std::time::Duration::from_millis(100), "{variants:?}");
    }
}

#[test]
fn the_broadcast_probe_never_resets_a_module_halted_before_it() {
    // A module that ignores the RS232 broadcast is found out by the probe, which resets it afterwards (of the
    // STATE_COMM_ERROR its own life sign caused). A module halted before (a `stop`) must stay halted: the
    // move is refused as on any module, nothing is reset, nothing moves.
    let (clock, host, bus) = rs232_variant(&[Variant::NoBroadcastPair]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(addr(1));
    m.halt_confirmed().unwrap();
    let before = host.with_device(|d| d.module(1).unwrap().position().value());
    let spec = MoveSpec { vel: Some(Velocity::native(0.3)), ..MoveSpec::to(Position::native(0.2)) };
    let err = m.move_to_guarded(&spec, Guard::Watchdog, &mut |_| {}).unwrap_err();
    assert!(matches!(err, Error::Halted { .. }), "{err}");
    let state = host.with_device(|d| d.module(1).unwrap().state());
    assert!(state.contains(StateFlag::Halted) && !state.contains(StateFlag::Motion), "{state}");
    assert_eq!(host.with_device(|d| d.module(1).unwrap().position().value()), before);
    assert!(!host.with_device(|d| d.take_events()).iter().any(|e| e.contains("reset")));
}

#[test]
fn a_module_that_starts_late_is_waited_for_within_the_grace_and_beyond_it_is_halted() {
    // The module starts a motion 0.3 s after acknowledging it, its state until then that of before (the
    // RAMP_END of the last ramp, the HOME_OK of the last homing): within the session's start grace (1 s)
    // the checked moves and homing wait for it, and end where they were sent.
    let (clock, host, bus) = rs232_variant(&[Variant::LateMotionStart]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(addr(1));
    let sim = || host.with_device(|d| (d.module(1).unwrap().state(), d.module(1).unwrap().position().value()));
    m.home_and_wait(secs(10), &mut |_| {}).unwrap();
    for target in [0.4, 0.2] {
        let r = m.move_to(&spec(target), &mut |_| {}).unwrap();
        assert!(at(&r, target) && r.verified, "{r:?}");
    }
    let h = m.home_and_wait(secs(10), &mut |_| {}).unwrap();
    assert!(h.state.contains(StateFlag::HomeOk) && sim().1.abs() < 1e-3, "{h:?}");
    // A motion command the session sent just before its close, not shown yet: the close waits (up to the
    // grace) for it, sees it start, and halts it.
    m.motion(crate::model::Motion::FRamp { pos: Position::native(0.4) }, crate::model::AckKind::Simple).unwrap();
    bus.close().unwrap();
    clock.sleep(secs(1));
    let (state, p) = sim();
    assert!(state.contains(StateFlag::Halted) && !state.contains(StateFlag::Motion) && p < 0.4, "{state} {p}");
    // A start grace shorter than the module's delay: at its end the module still stands at its start,
    // away from its target, and has not been seen to move. It may start yet: it is halted, and the error
    // says where it stood and that the halt was confirmed (never a success, never left to start unseen).
    let mut config = Config::rs232();
    config.start_grace = Duration::from_millis(100);
    let bus = Client::with_link(PortLink::Rs232(Box::new(host.connect().0)), clock.shared(), config).unwrap();
    let m = bus.module(addr(1));
    m.reset().unwrap();
    // (After the halt no end flag is left: this move waits for its motion in any case.)
    let r = m.move_to(&spec(0.2), &mut |_| {}).unwrap();
    assert!(at(&r, 0.2), "{r:?}");
    let from = sim().1;
    let e = m.move_to(&spec(0.4), &mut |_| {}).unwrap_err();
    match &e {
        Error::FailedDuringMotion { cause, stop, .. } => {
            assert!(matches!(**cause, Error::NotReached { .. }) && stop.is_confirmed(), "{e}")
        }
        other => panic!("{other}"),
    }
    clock.sleep(secs(1));
    let (state, p) = sim();
    assert!(state.contains(StateFlag::Halted) && !state.contains(StateFlag::Motion), "{state}");
    assert!((p - from).abs() < 1e-3, "never moved: {from} then {p}");
    bus.close().unwrap();
}

#[test]
fn the_close_halts_every_module_that_shows_its_motion_late_not_only_the_first() {
    // Two modules sent a motion command just before the close: module 1 a velocity of 0 (it never shows a
    // motion), module 2 a ramp it shows 0.3 s later. The close watches module 1 through the whole
    // grace, and then reads module 2 again (its first read is older than the grace, and it moves by now)
    // instead of taking that first read for its rest.
    let clock = ManualClock::new_auto();
    let mut config = SimConfig::with_addresses(&[1, 2]).unwrap();
    config.variants = vec![Variant::LateMotionStart];
    let canbus = CanBus::with_emulator(Emulator::new_can(&config), clock.shared(), CanBusConfig::paced(1_000_000));
    let bus = Client::with_link(PortLink::Can(Box::new(canbus.connect())), clock.shared(), Config::can()).unwrap();
    let _me = clock.reserve_participant().enter();
    let here = bus.module(addr(1)).position().unwrap();
    // (Module 2's first: its grace has passed when module 1's has.)
    let ramp = crate::model::Motion::FRamp { pos: Position::native(0.4) };
    bus.module(addr(2)).motion(ramp, crate::model::AckKind::Simple).unwrap();
    let still = crate::model::Motion::FVel { vel: Velocity::native(0.0) };
    bus.module(addr(1)).motion(still, crate::model::AckKind::Simple).unwrap();
    bus.close().unwrap();
    clock.sleep(secs(1));
    let (state, p, _, _) = device_view(&canbus, &clock, 1);
    assert!(!state.contains(StateFlag::Halted) && (p - here.value()).abs() < 1e-3, "module 1 never moved: {state}");
    let (state, p, _, _) = device_view(&canbus, &clock, 2);
    assert!(state.contains(StateFlag::Halted) && !state.contains(StateFlag::Motion), "module 2: {state}");
    assert!(p < 0.4, "module 2 halted on its way: {p}");
}
