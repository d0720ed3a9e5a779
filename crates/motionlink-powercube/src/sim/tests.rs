//! The emulator's physical model and protocol behaviour, driven by explicit timestamps.

#![allow(clippy::approx_constant)] // ±3.14 rad is the configured soft limit

use super::*;
use crate::model::{
    AckKind, Amperes, ConfigFlag, CubeState, Millis, Motion, Param, Position, ShortFlag, StateFlag, Ticks, Value,
    Velocity,
};
use crate::wire::profibus::OutputWriter;
use crate::wire::{AckPosition, Action};

fn at(ms: u64) -> Timestamp {
    Timestamp::from_millis(ms)
}

fn state(bus: &mut Emulator, ms: u64) -> CubeState {
    match bus.request(at(ms), 1, &Request::Get(Param::CubeState)) {
        Some(Reply::Get(_, Value::U32(s))) => CubeState(s),
        other => panic!("{other:?}"),
    }
}

fn pos(bus: &mut Emulator, ms: u64) -> f32 {
    match bus.request(at(ms), 1, &Request::Get(Param::ActPos)) {
        Some(Reply::Get(_, Value::F32(p))) => p,
        other => panic!("{other:?}"),
    }
}

fn set(bus: &mut Emulator, ms: u64, p: Param, v: Value) {
    assert!(matches!(bus.request(at(ms), 1, &Request::Set(p, v)), Some(Reply::Set(_, 0x64))));
}

fn homed_bus() -> Emulator {
    let mut bus = Emulator::new(&SimConfig::default());
    bus.request(at(0), 1, &Request::Action(Action::Home));
    assert!(state(&mut bus, 10).contains(StateFlag::Motion), "homing moves");
    assert!(state(&mut bus, 2_000).contains(StateFlag::HomeOk));
    bus
}

fn homed_can_bus() -> Emulator {
    let mut bus = Emulator::new_can(&SimConfig::default());
    bus.request(at(0), 1, &Request::Action(Action::Home));
    assert!(state(&mut bus, 2_000).contains(StateFlag::HomeOk));
    bus
}

#[test]
fn homing_moves_then_sets_home_ok() {
    let mut bus = Emulator::new(&SimConfig::default());
    let s = state(&mut bus, 0);
    assert!(!s.contains(StateFlag::HomeOk));
    assert!((pos(&mut bus, 0) - 0.05).abs() < 1e-6);
    bus.request(at(100), 1, &Request::Action(Action::Home));
    let s = state(&mut bus, 150);
    assert!(s.contains(StateFlag::Motion) && !s.contains(StateFlag::HomeOk), "{s}");
    let p = pos(&mut bus, 150);
    assert!(p < 0.05 && p > 0.0, "{p}");
    let s = state(&mut bus, 1_000);
    assert!(s.contains(StateFlag::HomeOk) && !s.contains(StateFlag::Motion), "{s}");
    assert_eq!(pos(&mut bus, 1_000), 0.0);
}

#[test]
fn ramp_is_a_trapezoid_with_its_phase_flags() {
    let mut bus = homed_bus();
    set(&mut bus, 2_000, Param::TargetVel, Value::F32(1.0));
    set(&mut bus, 2_000, Param::TargetAcc, Value::F32(2.0));
    // 1 rad at 1 rad/s and 2 rad/s²: 0.5 s up, 0.5 s steady, 0.5 s down.
    let r = bus.request(at(2_000), 1, &Request::Motion(Motion::FRamp { pos: Position::native(1.0) }, AckKind::Simple));
    assert!(matches!(r, Some(Reply::Motion { status: Some(0x64), .. })));
    let phases = [(2_250, StateFlag::RampAcc), (2_750, StateFlag::RampSteady), (3_250, StateFlag::RampDec)];
    for (ms, flag) in phases {
        let s = state(&mut bus, ms);
        assert!(s.contains(flag) && s.contains(StateFlag::Motion) && !s.contains(StateFlag::RampEnd), "{ms}: {s}");
    }
    // At 0.25 s: 0.5 * 2 * 0.25² = 0.0625 rad.
    assert!((pos(&mut bus, 2_250) - 0.0625).abs() < 1e-4);
    let s = state(&mut bus, 3_600);
    assert!(s.contains(StateFlag::RampEnd) && !s.contains(StateFlag::Motion), "{s}");
    assert!((pos(&mut bus, 3_600) - 1.0).abs() < 1e-6);
    // TargetVel above MaxVel is limited to MaxVel.
    set(&mut bus, 4_000, Param::TargetVel, Value::F32(10.0));
    bus.request(at(4_000), 1, &Request::Motion(Motion::FRamp { pos: Position::native(0.0) }, AckKind::Simple));
    assert!(state(&mut bus, 5_400).contains(StateFlag::Motion), "1 rad/s at most: still moving at 1.4 s");
}

#[test]
fn targets_beyond_the_soft_limits_are_limited_and_velocity_runs_into_them() {
    let mut bus = homed_bus();
    set(&mut bus, 2_000, Param::MaxPos, Value::F32(0.5));
    bus.request(at(2_000), 1, &Request::Motion(Motion::FRamp { pos: Position::native(3.0) }, AckKind::Simple));
    assert!((pos(&mut bus, 10_000) - 0.5).abs() < 1e-6);
    assert!(!state(&mut bus, 10_000).has_fault());
    // Velocity mode runs into the lower limit -3.14: from 0.5 at 1 rad/s that takes about 3.9 s.
    bus.request(at(10_000), 1, &Request::Motion(Motion::FVel { vel: Velocity::native(-1.0) }, AckKind::Simple));
    assert!(!state(&mut bus, 12_000).has_fault());
    let s = state(&mut bus, 20_000);
    assert!(s.contains(StateFlag::BeyondSoft) && s.contains(StateFlag::Halted) && s.contains(StateFlag::Error), "{s}");
    assert!((pos(&mut bus, 20_000) + 3.14).abs() < 1e-3);
    // Halted: motion commands are acknowledged and ignored.
    let r = bus.request(at(20_000), 1, &Request::Motion(Motion::FRamp { pos: Position::native(0.0) }, AckKind::Simple));
    assert!(r.is_some());
    assert!(!state(&mut bus, 20_100).contains(StateFlag::Motion));
    bus.request(at(20_200), 1, &Request::Action(Action::Reset));
    let s = state(&mut bus, 20_200);
    assert!(!s.has_fault() && !s.contains(StateFlag::Halted) && s.contains(StateFlag::HomeOk), "{s}");
    bus.request(at(20_300), 1, &Request::Motion(Motion::FRamp { pos: Position::native(0.0) }, AckKind::Simple));
    assert!(state(&mut bus, 20_400).contains(StateFlag::Motion));
}

#[test]
fn halt_stops_at_once_until_reset() {
    let mut bus = homed_bus();
    bus.request(at(2_000), 1, &Request::Motion(Motion::FVel { vel: Velocity::native(0.5) }, AckKind::Simple));
    bus.request(at(3_000), 1, &Request::Action(Action::Halt));
    let p = pos(&mut bus, 3_000);
    assert!(p > 0.3, "{p}");
    assert_eq!(pos(&mut bus, 4_000), p);
    let s = state(&mut bus, 4_000);
    assert!(s.contains(StateFlag::Halted) && !s.contains(StateFlag::Motion));
    bus.request(at(4_000), 1, &Request::Action(Action::Home));
    assert!(!state(&mut bus, 4_010).contains(StateFlag::Motion), "halted: homing ignored too");
}

#[test]
fn the_watchdog_trips_without_refresh() {
    let mut bus = homed_bus();
    // Without the Config flag the life sign does nothing.
    bus.request(at(2_000), 1, &Request::Action(Action::LifeSign));
    assert!(!bus.module(1).unwrap().watchdog_online());
    set(&mut bus, 2_000, Param::Config, Value::U32(ConfigFlag::WatchdogEnable.mask()));
    assert!(matches!(
        bus.request(at(2_000), 1, &Request::Action(Action::LifeSign)),
        Some(Reply::Action(Action::LifeSign))
    ));
    assert!(bus.module(1).unwrap().watchdog_online());
    bus.request(at(2_000), 1, &Request::Motion(Motion::FVel { vel: Velocity::native(0.2) }, AckKind::Simple));
    for ms in (2_040..3_000).step_by(40) {
        bus.broadcast(at(ms), &Broadcast::WatchdogRefresh);
    }
    assert!(!state(&mut bus, 3_000).has_fault());
    // Last refresh at 2960 ms: trips at 3010 ms, motion stops there.
    let s = state(&mut bus, 3_500);
    assert!(s.contains(StateFlag::CommError) && s.contains(StateFlag::Halted), "{s}");
    // "... and enter an error state": STATE_ERROR too, which Profibus shows as STATE_ERRORM4.
    assert!(s.contains(StateFlag::Error), "{s}");
    assert!(s.profibus_state().contains(crate::model::ProfibusFlag::ErrorM4), "{}", s.profibus_state());
    let p = pos(&mut bus, 3_500);
    // TargetAcc defaults to half of MaxAcc: 0.2 s to reach 0.2 rad/s.
    let expected = 0.2 * 0.2 / 2.0 + 0.2 * (1.010 - 0.2);
    assert!((f64::from(p) - expected).abs() < 1e-3, "{p} vs {expected}");
    // Refresh again and reset: running again.
    bus.broadcast(at(3_500), &Broadcast::WatchdogRefresh);
    bus.broadcast(at(3_500), &Broadcast::Reset);
    assert!(!state(&mut bus, 3_520).has_fault());
    // A second life sign switches the watchdog off: no trip any more.
    bus.request(at(3_520), 1, &Request::Action(Action::LifeSign));
    assert!(!state(&mut bus, 60_000).has_fault());
}

#[test]
fn a_small_max_delta_pos_gives_a_tow_error() {
    let mut bus = homed_bus();
    // The servo lags 5 ms: at 0.5 rad/s that is 2.5 mrad.
    set(&mut bus, 2_000, Param::MaxDeltaPos, Value::F32(0.001));
    bus.request(at(2_000), 1, &Request::Motion(Motion::FVel { vel: Velocity::native(0.5) }, AckKind::Simple));
    let s = state(&mut bus, 3_000);
    assert!(s.contains(StateFlag::TowError) && s.contains(StateFlag::Error), "{s}");
    assert!(s.faults().any(|f| f == StateFlag::TowError));
}

#[test]
fn step_mode_buffers_one_step() {
    let mut bus = homed_bus();
    bus.request(
        at(2_000),
        1,
        &Request::Motion(Motion::FStep { pos: Position::native(0.1), time: Millis(200) }, AckKind::Simple),
    );
    let s = state(&mut bus, 2_050);
    assert!(s.contains(StateFlag::InProgress) && !s.contains(StateFlag::FullBuffer));
    assert!((pos(&mut bus, 2_100) - 0.05).abs() < 1e-4, "linear in time");
    bus.request(at(2_100), 1, &Request::IStep { pos: Ticks(0), time: Millis(100) });
    assert!(state(&mut bus, 2_150).contains(StateFlag::FullBuffer));
    let s = state(&mut bus, 2_250);
    assert!(s.contains(StateFlag::InProgress) && !s.contains(StateFlag::FullBuffer), "{s}");
    assert!(!state(&mut bus, 2_400).contains(StateFlag::InProgress));
    assert!(pos(&mut bus, 2_400).abs() < 1e-6);
}

#[test]
fn extended_acknowledges_carry_position_state_and_dio() {
    let mut bus = homed_bus();
    set(&mut bus, 2_000, Param::DioSetup, Value::U32(0x30));
    bus.module_mut(1).unwrap().set_inputs(0x05);
    let r =
        bus.request(at(2_000), 1, &Request::Motion(Motion::FRamp { pos: Position::native(0.5) }, AckKind::Extended));
    let Some(Reply::Motion { ext: Some(e), .. }) = r else { panic!("{r:?}") };
    assert_eq!(e.position, AckPosition::Unit(Position::native(0.0)));
    assert_eq!(e.dio.0, 0x35);
    assert!(!e.state.contains(ShortFlag::NotOk));
    let r = bus.request(at(2_200), 1, &Request::Motion(Motion::IRamp { pos: Ticks(0) }, AckKind::Extended));
    let Some(Reply::Motion { ext: Some(e), .. }) = r else { panic!("{r:?}") };
    assert!(matches!(e.position, AckPosition::Ticks(t) if t.0 > 0));
    assert!(e.state.contains(ShortFlag::Motion));
}

#[test]
fn velocity_and_current_modes_move() {
    let mut bus = homed_bus();
    bus.request(at(2_000), 1, &Request::Motion(Motion::FCur { cur: Amperes(2.5) }, AckKind::Simple));
    assert!(pos(&mut bus, 3_000) > 0.1);
    bus.request(at(3_000), 1, &Request::Motion(Motion::FVel { vel: Velocity::native(0.0) }, AckKind::Simple));
    let s = state(&mut bus, 4_000);
    assert!(!s.contains(StateFlag::Motion), "velocity 0 stops: {s}");
}

#[test]
fn rs232_framing_and_bcc_policy() {
    let mut bus = Emulator::new(&SimConfig::with_addresses(&[1, 17]).unwrap());
    let mut out = Vec::new();
    // The manual's Home to module 17.
    ByteEmulator::receive(&mut bus, at(0), &[0x02, 0x06, 0x21, 0x01, 0x28, 0x03], &mut out);
    assert_eq!(out, vec![0x02, 0x0a, 0x21, 0x01, 0x2c, 0x03]);
    // A wrong BCC is accepted by default...
    out.clear();
    ByteEmulator::receive(&mut bus, at(1), &[0x02, 0x06, 0x21, 0x00, 0x00, 0x03], &mut out);
    assert_eq!(out, vec![0x02, 0x0a, 0x21, 0x00, 0x2b, 0x03]);
    // ...and dropped when strict.
    bus.set_strict_bcc(true);
    out.clear();
    ByteEmulator::receive(&mut bus, at(2), &[0x02, 0x06, 0x21, 0x00, 0x00, 0x03], &mut out);
    assert!(out.is_empty());
    assert_eq!(bus.stats().bad_bcc, 1);
    // A length that does not match is never interpreted; address 5 has no module.
    ByteEmulator::receive(&mut bus, at(3), &[0x02, 0x06, 0x22, 0x00, 0x28, 0x03], &mut out);
    ByteEmulator::receive(&mut bus, at(3), &[0x02, 0x04, 0xA1, 0x00, 0xa5, 0x03], &mut out);
    assert!(out.is_empty());
    assert_eq!((bus.stats().bad_length, bus.stats().nobody), (1, 1));
    // A broadcast (address 0) reaches every module and is not acknowledged.
    ByteEmulator::receive(&mut bus, at(4), &[0x02, 0x04, 0x01, 0x10, 0x82, 0x07, 0x03], &mut out);
    assert!(out.is_empty());
    assert!(bus.module(1).unwrap().state().contains(StateFlag::Halted));
    assert!(bus.module(17).unwrap().state().contains(StateFlag::Halted));
}

#[test]
fn can_frames_and_disabled_acknowledges() {
    let mut bus = Emulator::new_can(&SimConfig::with_addresses(&[17]).unwrap());
    let mut out = Vec::new();
    let f = |text: &str| text.parse::<CanFrame>().unwrap();
    CanEmulator::receive(&mut bus, at(0), &f("0D1#0A27"), &mut out);
    assert_eq!(out.len(), 1);
    assert_eq!(out[0].id(), 0x0B1);
    assert_eq!(&out[0].data()[..2], &[0x0a, 0x27]);
    out.clear();
    CanEmulator::receive(&mut bus, at(0), &f("0F1#083900000004"), &mut out); // Config: DISABLE_ACK
    assert_eq!(out.len(), 1, "the change itself is acknowledged");
    out.clear();
    CanEmulator::receive(&mut bus, at(0), &f("0F1#01"), &mut out);
    assert!(out.is_empty(), "no acknowledge of Home any more");
    CanEmulator::receive(&mut bus, at(0), &f("0D1#0A3C"), &mut out);
    assert_eq!(out.len(), 1, "Get is still answered");
    out.clear();
    CanEmulator::receive(&mut bus, at(0), &f("100#02"), &mut out);
    CanEmulator::receive(&mut bus, at(0), &f("0B1#0A3C00000000"), &mut out);
    CanEmulator::receive(&mut bus, at(0), &f("3E9#01"), &mut out);
    assert!(out.is_empty());
    assert!(bus.module(17).unwrap().state().contains(StateFlag::Halted));
    assert_eq!(bus.stats().malformed, 1);
}

#[test]
fn synchronised_motion_waits_for_the_broadcast() {
    let mut bus = homed_can_bus();
    set(&mut bus, 2_000, Param::Config, Value::U32(ConfigFlag::SyncMotion.mask()));
    bus.request(at(2_000), 1, &Request::Motion(Motion::FRamp { pos: Position::native(0.5) }, AckKind::Simple));
    assert!(!state(&mut bus, 2_100).contains(StateFlag::Motion));
    bus.broadcast(at(2_100), &Broadcast::StartMotion);
    assert!(state(&mut bus, 2_200).contains(StateFlag::Motion));
    bus.broadcast(at(5_000), &Broadcast::SavePosition);
    let Some(Reply::Get(_, Value::F32(saved))) = bus.request(at(5_000), 1, &Request::Get(Param::ActFSavedPos)) else {
        panic!()
    };
    assert!((saved - 0.5).abs() < 1e-6);
}

#[test]
fn synchronised_motion_is_valid_only_on_can() {
    // RS232 (`homed_bus`): the flag is stored but ignored, the motion starts at once (on CAN it waits for the
    // broadcast: `synchronised_motion_waits_for_the_broadcast`).
    let mut bus = homed_bus();
    set(&mut bus, 2_000, Param::Config, Value::U32(ConfigFlag::SyncMotion.mask()));
    bus.request(at(2_000), 1, &Request::Motion(Motion::FRamp { pos: Position::native(0.5) }, AckKind::Simple));
    assert!(state(&mut bus, 2_100).contains(StateFlag::Motion), "no StartMotion needed on RS232");
}

#[test]
fn the_change_baud_rate_broadcast_is_decoded_and_recorded() {
    let mut bus = Emulator::new_can(&SimConfig::with_addresses(&[17]).unwrap());
    assert_eq!(bus.can_baud(), None);
    let mut out = Vec::new();
    // CANID_CMDALL: Change Baudrate (0x09) to 2 = 500 kbit/s.
    CanEmulator::receive(&mut bus, at(0), &"100#0902".parse::<CanFrame>().unwrap(), &mut out);
    assert!(out.is_empty(), "broadcasts are not acknowledged");
    assert_eq!(bus.can_baud(), Some(crate::model::CanBaud::K500));
    assert_eq!(bus.module(17).unwrap().can_baud(), Some(crate::model::CanBaud::K500));
    // Recorded only: the module still answers on the same link.
    CanEmulator::receive(&mut bus, at(10), &"0D1#0A27".parse::<CanFrame>().unwrap(), &mut out);
    assert_eq!(out.len(), 1);
}

#[test]
fn profibus_images_ignore_repeats() {
    let mut bus = homed_bus();
    let mut w = OutputWriter::new();
    let halt = w.image(&Request::Action(Action::Halt).encode()).unwrap();
    let img = bus.profibus_exchange(at(2_000), 1, &halt).unwrap();
    assert_eq!(img.reply_bytes()[0], 0x02);
    assert!(CubeState(bus.module(1).unwrap().state().0).contains(StateFlag::Halted));
    assert!(img.short_state().contains(crate::model::ProfibusFlag::HaltM4), "{}", img.short_state());
    let reset = w.image(&Request::Action(Action::Reset).encode()).unwrap();
    bus.profibus_exchange(at(2_010), 1, &reset).unwrap();
    assert!(!bus.module(1).unwrap().state().contains(StateFlag::Halted));
    // The same output image again is not a new Halt.
    bus.profibus_exchange(at(2_020), 1, &reset).unwrap();
    let again = bus.profibus_exchange(at(2_030), 1, &halt).unwrap();
    assert_eq!(again.reply_bytes()[0], 0x02, "a changed image is interpreted");
    let same = bus.profibus_exchange(at(2_040), 1, &halt).unwrap();
    assert_eq!(same.millis(), (2_040 % 256) as u8, "the millisecond byte runs on");
    assert!(bus.profibus_exchange(at(0), 9, &halt).is_none());
}

fn get(bus: &mut Emulator, ms: u64, p: Param) -> Value {
    match bus.request(at(ms), 1, &Request::Get(p)) {
        Some(Reply::Get(_, v)) => v,
        other => panic!("{p}: {other:?}"),
    }
}

#[test]
fn soft_limits_never_cross_and_values_that_cannot_apply_are_ignored() {
    let mut bus = homed_bus();
    set(&mut bus, 2_000, Param::MaxPos, Value::F32(0.5));
    // A lower limit above the upper one is not applied (acknowledged, as every write): the old one stays.
    set(&mut bus, 2_000, Param::MinPos, Value::F32(1.0));
    set(&mut bus, 2_000, Param::ActIMinPos, Value::I32(i32::MAX));
    // Nor an upper limit below the lower one, nor a limit that is not a number.
    set(&mut bus, 2_000, Param::MaxPos, Value::F32(-5.0));
    for v in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
        set(&mut bus, 2_000, Param::MinPos, Value::F32(v));
        set(&mut bus, 2_000, Param::MaxPos, Value::F32(v));
        set(&mut bus, 2_000, Param::MaxDeltaPos, Value::F32(v));
        set(&mut bus, 2_000, Param::TargetVel, Value::F32(v));
    }
    assert_eq!(get(&mut bus, 2_000, Param::MinPos), Value::F32(-3.14));
    assert_eq!(get(&mut bus, 2_000, Param::MaxPos), Value::F32(0.5));
    assert_eq!(get(&mut bus, 2_000, Param::MaxDeltaPos), Value::F32(0.1));
    // Limits that meet are allowed: the axis may only stand there.
    set(&mut bus, 2_000, Param::MinPos, Value::F32(0.5));
    assert_eq!(get(&mut bus, 2_000, Param::MinPos), Value::F32(0.5));
    set(&mut bus, 2_000, Param::MinPos, Value::F32(-1.0));
    // A ramp beyond the limit is limited to it; a velocity motion stops at it: no panic on the way.
    bus.request(at(2_000), 1, &Request::Motion(Motion::FRamp { pos: Position::native(2.0) }, AckKind::Simple));
    assert!((pos(&mut bus, 5_000) - 0.5).abs() < 1e-6);
    bus.request(at(5_000), 1, &Request::Motion(Motion::FVel { vel: Velocity::native(-1.0) }, AckKind::Simple));
    let s = state(&mut bus, 8_000);
    assert!(s.contains(StateFlag::BeyondSoft), "{s}");
    assert!((pos(&mut bus, 8_000) + 1.0).abs() < 1e-3);
    // A motion to a position that is not a number is acknowledged and ignored.
    bus.request(at(8_000), 1, &Request::Action(Action::Reset));
    for m in [
        Motion::FRamp { pos: Position::native(f32::NAN) },
        Motion::FStep { pos: Position::native(f32::INFINITY), time: Millis(10) },
        Motion::FVel { vel: Velocity::native(f32::NAN) },
        Motion::FCur { cur: Amperes(f32::NEG_INFINITY) },
        Motion::FCosLoop { pos: Position::native(f32::NAN), time: Millis(100) },
        Motion::FRampLoop { pos: Position::native(f32::NAN) },
    ] {
        assert!(bus.request(at(8_000), 1, &Request::Motion(m, AckKind::Simple)).is_some(), "{m:?}");
    }
    let p = pos(&mut bus, 9_000);
    assert!(!state(&mut bus, 9_000).contains(StateFlag::Motion));
    assert!((p + 1.0).abs() < 1e-3, "{p}");
}

#[test]
fn a_ramp_loop_too_short_to_turn_round_ends() {
    let mut bus = homed_bus();
    // A loop of a tenth of a microradian at 1 rad/s² would turn round every 0.6 ms, millions of times in an
    // hour of device time.
    bus.request(at(2_000), 1, &Request::Motion(Motion::FRampLoop { pos: Position::native(1e-7) }, AckKind::Simple));
    let s = state(&mut bus, 3_600_000);
    assert!(!s.contains(StateFlag::Motion) && s.contains(StateFlag::RampEnd), "{s}");
    // A real one goes on.
    bus.request(at(3_600_000), 1, &Request::Motion(Motion::FRampLoop { pos: Position::native(0.5) }, AckKind::Simple));
    assert!(state(&mut bus, 3_700_000).contains(StateFlag::Motion));
}

/// Feeds `bytes` to the bus as RS232 at `ms`; returns what it answered.
fn rs232_in(bus: &mut Emulator, ms: u64, bytes: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    ByteEmulator::receive(bus, at(ms), bytes, &mut out);
    out
}

fn homed_pair() -> Emulator {
    let mut bus = Emulator::new(&SimConfig::with_addresses(&[1, 2]).unwrap());
    for a in [1, 2] {
        bus.request(at(0), a, &Request::Action(Action::Home));
    }
    bus.update(at(2_000));
    bus
}

fn module_state(bus: &Emulator, a: u8) -> CubeState {
    bus.module(a).unwrap().state()
}

#[test]
fn libm5api_broadcasts_reach_every_module_byte_for_byte() {
    // The exact bytes Schunk's libm5api sends over RS232 (field notes): address 0, command + 0x00.
    const HALT_ALL: &[u8] = &[0x02, 0x04, 0x10, 0x82, 0x10, 0x82, 0x00, 0x08, 0x03];
    const RESET_ALL: &[u8] = &[0x02, 0x04, 0x10, 0x82, 0x00, 0x00, 0x06, 0x03];
    const HOME_ALL: &[u8] = &[0x02, 0x04, 0x10, 0x82, 0x01, 0x00, 0x07, 0x03];
    const SERVE_WATCHDOG_ALL: &[u8] = &[0x02, 0x04, 0x10, 0x82, 0x07, 0x00, 0x0D, 0x03];
    // savePosAll: 0x0E 0x00; BCC = 04 + 02 + 0E + 00 = 0x14.
    const SAVE_POS_ALL: &[u8] = &[0x02, 0x04, 0x10, 0x82, 0x0E, 0x00, 0x14, 0x03];

    // homeAll starts homing in both modules; no acknowledge.
    let mut bus = Emulator::new(&SimConfig::with_addresses(&[1, 2]).unwrap());
    assert!(rs232_in(&mut bus, 0, HOME_ALL).is_empty());
    bus.update(at(10));
    for a in [1, 2] {
        assert!(module_state(&bus, a).contains(StateFlag::Motion), "module {a} homes");
    }
    bus.update(at(2_000));
    for a in [1, 2] {
        assert!(module_state(&bus, a).contains(StateFlag::HomeOk), "module {a} homed");
    }
    let events = bus.take_events();
    for a in [1, 2] {
        assert!(events.contains(&format!("module {a} motion started: homing")), "{events:?}");
        assert!(events.contains(&format!("module {a} homed")), "{events:?}");
    }

    // haltAll stops both, moving or not.
    for (a, target) in [(1u8, 1.0f32), (2, -1.0)] {
        bus.request(at(2_000), a, &Request::Motion(Motion::FRamp { pos: Position::native(target) }, AckKind::Simple));
    }
    assert!(rs232_in(&mut bus, 2_300, HALT_ALL).is_empty());
    for a in [1, 2] {
        let s = module_state(&bus, a);
        assert!(s.contains(StateFlag::Halted) && !s.contains(StateFlag::Motion), "module {a}: {s}");
    }
    let (p1, p2) = (pos(&mut bus, 2_300), bus.module(2).unwrap().position().value());
    assert!(p1 > 0.0 && p2 < 0.0, "{p1} {p2}");

    // resetAll clears both.
    assert!(rs232_in(&mut bus, 2_400, RESET_ALL).is_empty());
    for a in [1, 2] {
        assert!(!module_state(&bus, a).contains(StateFlag::Halted), "module {a} reset");
    }

    // savePosAll stores each one's own position.
    assert!(rs232_in(&mut bus, 2_500, SAVE_POS_ALL).is_empty());
    for (a, p) in [(1, p1), (2, p2)] {
        assert_eq!(
            bus.request(at(2_500), a, &Request::Get(Param::ActFSavedPos)),
            Some(Reply::Get(Param::ActFSavedPos, Value::F32(p)))
        );
    }

    // serveWatchdogAll keeps both watchdogs alive; without it both expire.
    for a in [1, 2] {
        set_on(&mut bus, a, 2_600, Param::Config, Value::U32(ConfigFlag::WatchdogEnable.mask()));
        bus.request(at(2_600), a, &Request::Action(Action::LifeSign));
        assert!(bus.module(a).unwrap().watchdog_online());
    }
    for ms in (2_620..3_600).step_by(20) {
        assert!(rs232_in(&mut bus, ms, SERVE_WATCHDOG_ALL).is_empty());
    }
    bus.update(at(3_600));
    for a in [1, 2] {
        assert!(!module_state(&bus, a).has_fault(), "module {a} served: {}", module_state(&bus, a));
    }
    bus.update(at(3_700));
    for a in [1, 2] {
        assert!(module_state(&bus, a).contains(StateFlag::CommError), "module {a} not served any more");
    }
    assert_eq!(bus.stats().not_understood, 0);
    assert_eq!(bus.stats().malformed, 0);

    // The one-byte form (the manual's, and what this crate sent on RS232 before) still works.
    let mut bus = homed_pair();
    let mut one_byte = [0u8; crate::wire::rs232::MAX_FRAME];
    let n = crate::wire::rs232::encode(TelKind::Send, 0, &Broadcast::Halt.encode(), &mut one_byte).unwrap();
    assert!(rs232_in(&mut bus, 2_000, &one_byte[..n]).is_empty());
    assert!(module_state(&bus, 1).contains(StateFlag::Halted) && module_state(&bus, 2).contains(StateFlag::Halted));
}

fn set_on(bus: &mut Emulator, a: u8, ms: u64, p: Param, v: Value) {
    assert!(matches!(bus.request(at(ms), a, &Request::Set(p, v)), Some(Reply::Set(_, 0x64))));
}

#[test]
fn events_say_what_the_modules_did() {
    let mut bus = Emulator::new(&SimConfig::with_addresses(&[1]).unwrap());
    bus.request(at(0), 1, &Request::Action(Action::Home));
    bus.update(at(2_000));
    assert_eq!(bus.take_events(), ["module 1 motion started: homing", "module 1 homed", "module 1 at rest 0.0000 rad"]);
    assert!(bus.take_events().is_empty(), "taken once");
    set(&mut bus, 2_000, Param::TargetVel, Value::F32(1.0));
    set(&mut bus, 2_000, Param::TargetAcc, Value::F32(2.0));
    bus.request(at(2_000), 1, &Request::Motion(Motion::FRamp { pos: Position::native(1.2) }, AckKind::Simple));
    // Reads are no events; the end of the ramp is, when it happens, however late someone looks.
    state(&mut bus, 2_100);
    bus.update(at(9_000));
    assert_eq!(bus.take_events(), ["module 1 motion started: ramp to 1.2000 rad", "module 1 at rest 1.2000 rad"]);
    bus.request(at(9_000), 1, &Request::Motion(Motion::FRamp { pos: Position::native(0.0) }, AckKind::Simple));
    bus.request(at(9_500), 1, &Request::Action(Action::Halt));
    let events = bus.take_events();
    assert_eq!(events[..2], ["module 1 motion started: ramp to 0.0000 rad".to_string(), "module 1 halted".into()]);
    assert!(events[2].starts_with("module 1 at rest 0.9"), "{events:?}");
    bus.request(at(9_600), 1, &Request::Motion(Motion::FRamp { pos: Position::native(0.0) }, AckKind::Simple));
    bus.request(at(9_700), 1, &Request::Action(Action::Reset));
    assert_eq!(
        bus.take_events(),
        ["module 1 ignored SetMotion FRAMP_MODE ramp to 0: halted or not homed", "module 1 reset"]
    );
    // The watchdog: online, expiry with the stop, offline.
    set(&mut bus, 10_000, Param::Config, Value::U32(ConfigFlag::WatchdogEnable.mask()));
    bus.request(at(10_000), 1, &Request::Action(Action::LifeSign));
    bus.request(at(10_000), 1, &Request::Motion(Motion::FVel { vel: Velocity::native(0.1) }, AckKind::Simple));
    bus.update(at(11_000));
    let events = bus.take_events();
    assert_eq!(
        events[..3],
        [
            "module 1 watchdog online".to_string(),
            "module 1 motion started: velocity or current mode".into(),
            "module 1 watchdog expired: STATE_COMM_ERROR".into()
        ]
    );
    assert!(events[3].starts_with("module 1 at rest 0.9"), "{events:?}");
    bus.request(at(11_000), 1, &Request::Action(Action::LifeSign));
    assert_eq!(bus.take_events(), ["module 1 watchdog offline"]);
    // A tow error.
    bus.request(at(11_000), 1, &Request::Action(Action::Reset));
    set(&mut bus, 11_000, Param::MaxDeltaPos, Value::F32(0.0001));
    bus.request(at(11_000), 1, &Request::Motion(Motion::FRamp { pos: Position::native(0.0) }, AckKind::Simple));
    bus.update(at(12_000));
    let events = bus.take_events();
    assert!(events.contains(&"module 1 error: STATE_TOW_ERROR".to_string()), "{events:?}");
    assert!(events.last().unwrap().starts_with("module 1 at rest"), "{events:?}");
}

#[test]
fn the_next_wakeup_is_the_next_change_a_module_makes() {
    let mut bus = homed_bus();
    assert_eq!(ByteEmulator::next_wakeup(&bus), None, "at rest, no watchdog: nothing will happen by itself");
    set(&mut bus, 2_000, Param::TargetVel, Value::F32(1.0));
    set(&mut bus, 2_000, Param::TargetAcc, Value::F32(2.0));
    bus.request(at(2_000), 1, &Request::Motion(Motion::FRamp { pos: Position::native(1.0) }, AckKind::Simple));
    // 1 rad at 1 rad/s, 2 rad/s²: ends 1.5 s later.
    let end = ByteEmulator::next_wakeup(&bus).unwrap();
    assert!(end >= at(3_500) && end <= at(3_500) + std::time::Duration::from_micros(1), "{end}");
    assert_eq!(CanEmulator::next_wakeup(&bus), Some(end));
    // A watchdog that expires earlier comes first.
    set(&mut bus, 2_000, Param::Config, Value::U32(ConfigFlag::WatchdogEnable.mask()));
    bus.request(at(2_000), 1, &Request::Action(Action::LifeSign));
    let expiry = ByteEmulator::next_wakeup(&bus).unwrap();
    assert!(expiry >= at(2_050) && expiry <= at(2_050) + std::time::Duration::from_micros(1), "{expiry}");
    // Advancing to that instant makes it happen: the wake-up moves on.
    let mut out = Vec::new();
    ByteEmulator::advance(&mut bus, expiry, &mut out);
    assert!(bus.module(1).unwrap().state().contains(StateFlag::CommError));
    assert_eq!(ByteEmulator::next_wakeup(&bus), None, "expired and halted: nothing more");
}

#[test]
fn the_can_emulator_reports_the_same_events() {
    let mut bus = Emulator::new_can(&SimConfig::with_addresses(&[3]).unwrap());
    let mut out = Vec::new();
    let home = crate::wire::can::to_frame(crate::wire::can::Role::Put(3), &Request::Action(Action::Home).encode());
    CanEmulator::receive(&mut bus, at(0), &home, &mut out);
    let halt = crate::wire::can::to_frame(crate::wire::can::Role::Broadcast, &Broadcast::Halt.encode());
    CanEmulator::receive(&mut bus, at(10), &halt, &mut out);
    let events = CanEmulator::take_events(&mut bus);
    assert_eq!(events[..2], ["module 3 motion started: homing".to_string(), "module 3 halted".into()]);
    assert!(events[2].starts_with("module 3 at rest 0.04"), "{events:?}");
}

/// A bus of the default module running `variant`.
fn with_variant(v: Variant) -> Emulator {
    Emulator::new(&SimConfig { variants: vec![v], ..SimConfig::default() })
}

#[test]
fn no_config_word_leaves_the_config_word_unanswered_and_unwritten() {
    // GetExtended Config (02 04 22 0A 39 69 03) and SetExtended Config get no acknowledge; DefConfig is
    // answered.
    let get_config = [0x02, 0x04, 0x22, 0x0A, 0x39, 0x69, 0x03];
    let mut out = Vec::new();
    ByteEmulator::receive(&mut Emulator::new(&SimConfig::default()), at(0), &get_config, &mut out);
    assert_eq!(out[..5], [0x02, 0x08, 0x26, 0x0A, 0x39], "the default answers: {out:02X?}");
    let mut bus = with_variant(Variant::NoConfigWord);
    let mut out = Vec::new();
    ByteEmulator::receive(&mut bus, at(0), &get_config, &mut out);
    assert!(out.is_empty(), "{out:02X?}");
    let word = Value::U32(ConfigFlag::WatchdogEnable.mask());
    assert_eq!(bus.request(at(1), 1, &Request::Set(Param::Config, word)), None);
    assert!(!bus.module(1).unwrap().config_word().contains(ConfigFlag::WatchdogEnable), "nothing written");
    assert!(matches!(bus.request(at(2), 1, &Request::Get(Param::DefConfig)), Some(Reply::Get(_, Value::U32(_)))));
}

#[test]
fn reset_clears_watchdog_switches_an_online_watchdog_offline() {
    // Without the variant, the watchdog expires again 50 ms after the Reset.
    let word = Value::U32(ConfigFlag::WatchdogEnable.mask());
    for (variants, expires_again) in [(vec![], true), (vec![Variant::ResetClearsWatchdog], false)] {
        let mut bus = Emulator::new(&SimConfig { variants, ..SimConfig::default() });
        set(&mut bus, 0, Param::Config, word);
        bus.request(at(1), 1, &Request::Action(Action::LifeSign));
        assert!(state(&mut bus, 100).contains(StateFlag::CommError), "expired");
        bus.broadcast(at(110), &Broadcast::Reset);
        assert!(!state(&mut bus, 111).contains(StateFlag::CommError), "cleared");
        assert_eq!(state(&mut bus, 200).contains(StateFlag::CommError), expires_again);
        assert_eq!(bus.module(1).unwrap().watchdog_online(), expires_again);
    }
}

#[test]
fn no_extended_ack_runs_the_motion_with_the_simple_acknowledge() {
    // FRAMP_ACK (14) runs and gets [0x0b][14][0x64].
    let mut bus = with_variant(Variant::NoExtendedAck);
    let ramp = Request::Motion(Motion::FRamp { pos: Position::native(0.5) }, AckKind::Extended);
    let ack = bus.request(at(0), 1, &ramp).unwrap();
    assert_eq!(ack.encode().as_bytes(), [0x0b, 14, 0x64]);
    assert!(state(&mut bus, 100).contains(StateFlag::Motion));
}

/// A commanded current beyond the manual's range (RawCur, -500..500 digits) is limited to it, as commanded
/// values are (chapter 12): what reads back is the limit, not the value sent.
#[test]
fn raw_current_is_limited_to_its_range() {
    let mut bus = Emulator::new(&SimConfig::default());
    assert_eq!(get(&mut bus, 0, Param::RawCur), Value::I16(0));
    // Sent as the wire carries it, past the client's own check.
    set(&mut bus, 1, Param::RawCur, Value::I16(1000));
    assert_eq!(get(&mut bus, 2, Param::RawCur), Value::I16(500));
    set(&mut bus, 3, Param::RawCur, Value::I16(-2000));
    assert_eq!(get(&mut bus, 4, Param::RawCur), Value::I16(-500));
    set(&mut bus, 5, Param::RawCur, Value::I16(-123));
    assert_eq!(get(&mut bus, 6, Param::RawCur), Value::I16(-123));
}
