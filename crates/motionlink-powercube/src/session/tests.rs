//! The session with no link and no thread: wired straight to the emulator, on a time this test moves.
//! What it sends goes to the emulator at once and the emulator's answers come back at once (an instant
//! line); when nothing is left to send, time jumps to the session's next deadline.

use std::time::Duration;

/// Addresses as patterns match them.
const A1: Address = Address::checked(1);
const A4: Address = Address::checked(4);
const A9: Address = Address::checked(9);

use motionlink_link::can::CanEmulator;
use motionlink_link::session::{Action as LinkAction, Input, OpId, Session as _};
use motionlink_link::Timestamp;
use motionlink_testkit::wired::{Line, SerialOrCan, Telegram, Wired};

use super::*;
use crate::model::{ConfigFlag, StateFlag};
use crate::sim::{ModuleConfig, SimConfig};
use crate::wire::can::{from_frame, Role};
use crate::Emulator;

mod polls;

/// The session wired to the emulated modules on an instant line (the shared harness).
type Bench = Wired<Session, SerialOrCan<Emulator>>;

/// What these tests ask of the harness.
trait PowerCubeBench {
    /// A session on RS232 with modules at `addresses`.
    fn rs232(addresses: &[u8]) -> Self;
    /// A session on CAN with modules at `addresses`.
    fn can(addresses: &[u8]) -> Self;
    /// A session with these modules, on CAN or RS232.
    fn with_modules(modules: Vec<ModuleConfig>, can: bool) -> Self;
    /// Runs `op` to its end (an hour of session time at most).
    fn run(&mut self, op: Op) -> Result<Output, Error>;
    /// Closes the session and runs its close sequence to its end.
    fn close(&mut self) -> Result<(), String>;
    /// Lets `d` of session time pass.
    fn idle(&mut self, d: Duration);
    /// State, position, watchdog online, Config word of module `a`, now.
    fn module(&mut self, a: u8) -> (CubeState, f32, bool, ConfigWord);
    /// When each watchdog refresh went out.
    fn refreshes(&self) -> Vec<Timestamp>;
    /// From now on the line loses every watchdog refresh on the way to the modules.
    fn lose_refreshes(&mut self);
    /// What the modules did since the last call (the lines `motionlink sim --events` prints).
    fn take_device_events(&mut self) -> Vec<String>;
}

impl PowerCubeBench for Bench {
    fn rs232(addresses: &[u8]) -> Bench {
        let device = Emulator::new(&SimConfig::with_addresses(addresses).unwrap());
        let session = Session::rs232(Config::rs232(), "test line", Timestamp::ZERO);
        Wired::new(session, SerialOrCan::Serial(device), Line::instant())
    }

    fn can(addresses: &[u8]) -> Bench {
        let device = Emulator::new_can(&SimConfig::with_addresses(addresses).unwrap());
        let session = Session::can(Config::can(), "test bus", Timestamp::ZERO);
        Wired::new(session, SerialOrCan::Can(device), Line::instant())
    }

    fn with_modules(modules: Vec<ModuleConfig>, can: bool) -> Bench {
        let config = SimConfig { modules, ..SimConfig::default() };
        let mut b = if can { Bench::can(&[1]) } else { Bench::rs232(&[1]) };
        b.device = if can {
            SerialOrCan::Can(Emulator::new_can(&config))
        } else {
            SerialOrCan::Serial(Emulator::new(&config))
        };
        b
    }

    fn run(&mut self, op: Op) -> Result<Output, Error> {
        self.run_op(op)
    }

    fn close(&mut self) -> Result<(), String> {
        self.close_session(Duration::from_secs(5)).map_err(|e| e.to_string())
    }

    fn idle(&mut self, d: Duration) {
        self.run_for(d);
        self.settle();
    }

    fn module(&mut self, a: u8) -> (CubeState, f32, bool, ConfigWord) {
        let now = self.now;
        self.device.update(now);
        let m = self.device.module(a).unwrap();
        (m.state(), m.position().value(), m.watchdog_online(), m.config_word())
    }

    fn refreshes(&self) -> Vec<Timestamp> {
        self.sent.iter().filter(|(_, w)| is_refresh(w)).map(|(t, _)| *t).collect()
    }

    fn lose_refreshes(&mut self) {
        self.lose = Some(Box::new(is_refresh));
    }

    fn take_device_events(&mut self) -> Vec<String> {
        let mut events: Vec<String> = self.device_events.drain(..).map(|(_, e)| e).collect();
        events.extend(self.device.take_events());
        events
    }
}

/// True for the watchdog refresh, on CAN or on RS232.
fn is_refresh(w: &Telegram) -> bool {
    match w.frame_id() {
        Some(id) => id == 0x100 && w[..] == [0x07],
        None => w[..] == *REFRESH_RS232,
    }
}

/// True for a CAN frame with identifier `id` and data `d` (any data if `None`).
fn frame(w: &Telegram, ids: impl Fn(u32) -> bool, d: Option<&[u8]>) -> bool {
    w.frame_id().is_some_and(ids) && d.is_none_or(|d| w[..] == *d)
}

/// The watchdog refresh on RS232: the broadcast to address 0 in libm5api's form.
const REFRESH_RS232: &[u8] = &[0x02, 0x04, 0x10, 0x82, 0x07, 0x00, 0x0D, 0x03];

fn addr(a: u8) -> Address {
    Address::new(a).unwrap()
}

fn addrs(ns: &[u8]) -> Vec<Address> {
    ns.iter().map(|&n| addr(n)).collect()
}

fn ms(n: u64) -> Duration {
    Duration::from_millis(n)
}

#[test]
fn reads_are_retried_and_nothing_else_is() {
    let mut b = Bench::rs232(&[1]);
    let t0 = b.now;
    let err = b.run(Op::Position(addr(9))).unwrap_err();
    assert!(matches!(err, Error::Timeout { address: A9, .. }), "{err}");
    assert_eq!(b.sent.len(), 3, "three tries of the read");
    assert_eq!(b.now - t0, ms(600), "each waited its full 200 ms");
    b.sent.clear();
    b.deaf = true;
    let err = b.run(Op::Set(addr(1), Param::TargetVel, Value::F32(0.2))).unwrap_err();
    assert!(matches!(err, Error::Timeout { address: A1, .. }), "{err}");
    assert_eq!(b.sent.len(), 1, "a write is never repeated");
    // The late answer of the write would be stale: the next exchange drops what is pending first.
    b.deaf = false;
    assert!(matches!(b.run(Op::State(addr(1))), Ok(Output::State(_))));
}

#[test]
fn on_can_acknowledges_are_matched_to_their_module_in_one_round() {
    let mut b = Bench::can(&[1, 2, 3]);
    let t0 = b.now;
    let Ok(Output::Values(v)) = b.run(Op::ReadMany(addrs(&[3, 1, 2, 9]), Param::DefCubeSerial)) else { panic!() };
    assert_eq!(v[0].as_ref().unwrap(), &Value::U32(1003));
    assert_eq!(v[1].as_ref().unwrap(), &Value::U32(1001));
    assert_eq!(v[2].as_ref().unwrap(), &Value::U32(1002));
    assert!(matches!(v[3], Err(Error::Timeout { address: A9, .. })));
    // Three rounds (the first, and two retries of address 9 alone), each one reply timeout.
    assert_eq!(b.now - t0, ms(150));
    let gets = b.sent.iter().filter(|(_, w)| frame(w, |id| (0xC1..=0xDF).contains(&id), None)).count();
    assert_eq!(gets, 4 + 2);
}

#[test]
fn the_watchdog_refresh_is_a_session_duty_on_its_20_ms_grid() {
    let mut b = Bench::can(&[1]);
    b.run(Op::EnableWatchdog(addrs(&[1]))).unwrap();
    assert!(b.module(1).2, "online");
    let armed = b.now;
    b.idle(Duration::from_secs(2));
    let refreshes: Vec<Timestamp> = b.refreshes().into_iter().filter(|t| *t >= armed).collect();
    assert!(refreshes.len() >= 99, "{} refreshes in 2 s", refreshes.len());
    let first = refreshes[0];
    for (i, t) in refreshes.iter().enumerate() {
        assert_eq!(*t - first, ms(20 * i as u64), "refresh {i} on its deadline");
    }
    assert!(!b.module(1).0.has_fault(), "served for 2 s");
    assert_eq!(b.session.watchdog_next_due(), Some(*refreshes.last().unwrap() + ms(20)));
    b.run(Op::DisableWatchdog).unwrap();
    assert!(!b.module(1).2 && !b.session.watchdog_served());
    let n = b.refreshes().len();
    b.idle(Duration::from_secs(1));
    assert_eq!(b.refreshes().len(), n, "no refresh once switched off");
    assert!(!b.module(1).0.has_fault());
}

#[test]
fn on_rs232_the_refresh_is_libm5api_broadcast_to_address_0() {
    let mut b = Bench::rs232(&[1]);
    b.run(Op::EnableWatchdog(addrs(&[1]))).unwrap();
    b.idle(Duration::from_secs(1));
    assert!(b.refreshes().len() >= 49);
    assert!(!b.module(1).0.has_fault());
    assert_eq!(b.device.stats().not_understood, 0);
}

#[test]
fn a_checked_move_polls_at_its_rate_reports_progress_and_ends_within_the_tolerance() {
    let mut b = Bench::rs232(&[1]);
    let spec = MoveSpec {
        vel: Some(Velocity::rad_per_s(0.5)),
        acc: Some(Acceleration::rad_per_s2(2.0)),
        ..MoveSpec::to(Position::rad(1.0))
    };
    let Ok(Output::Moved(report)) = b.run(Op::MoveTo(addr(1), spec)) else { panic!() };
    assert!((report.reached.value() - 1.0).abs() <= 0.001, "{report:?}");
    assert_eq!(report.reached.unit(), crate::model::AxisUnit::Radian, "the kind was read for the units");
    assert_eq!(report.start, Position::rad(0.05));
    let progress: Vec<Progress> = b.progress.iter().map(|(_, p)| *p).collect();
    assert!(progress.len() > 200, "{}", progress.len());
    for w in progress.windows(2) {
        assert_eq!(w[1].elapsed - w[0].elapsed, ms(10), "one poll per 10 ms");
        assert!(w[1].position.value() >= w[0].position.value() - 1e-6);
    }
    assert!(b.session.started().is_empty());
}

#[test]
fn a_position_in_rad_for_a_linear_module_is_refused_before_anything_moves() {
    let mut linear = ModuleConfig::at(4);
    linear.kind = ModuleKind::Linear;
    linear.min_pos = 0.0;
    linear.max_pos = 0.2;
    let mut b = Bench::with_modules(vec![linear], false);
    let err = b.run(Op::MoveTo(addr(4), MoveSpec::to(Position::rad(0.1)))).unwrap_err();
    assert!(matches!(err, Error::UnitMismatch { address: A4, kind: ModuleKind::Linear, .. }), "{err}");
    assert!(err.is_usage() && err.to_string().contains("0.1 rad"), "{err}");
    let err = b.run(Op::Motion(addr(4), Motion::FVel { vel: Velocity::rad_per_s(0.1) }, AckKind::Simple)).unwrap_err();
    assert!(matches!(err, Error::UnitMismatch { .. }), "{err}");
    assert_eq!(b.take_device_events(), Vec::<String>::new(), "nothing moved, nothing was written");
    // In metres it moves; a bare number in the module's own unit too.
    let Ok(Output::Moved(r)) = b.run(Op::MoveTo(addr(4), MoveSpec::to(Position::m(0.1)))) else { panic!() };
    assert_eq!(r.reached.unit(), crate::model::AxisUnit::Metre);
    assert!(matches!(b.run(Op::MoveTo(addr(4), MoveSpec::to(Position::native(0.15)))), Ok(Output::Moved(_))));
    // Mixed units in one move are refused by the move itself.
    let mixed = MoveSpec { vel: Some(Velocity::rad_per_s(0.1)), ..MoveSpec::to(Position::m(0.1)) };
    assert!(matches!(b.run(Op::MoveTo(addr(4), mixed)), Err(Error::InvalidArgument { .. })));
}

#[test]
fn a_cancelled_move_is_halted_and_says_the_module_confirmed_it() {
    let mut b = Bench::can(&[1]);
    let spec = MoveSpec { vel: Some(Velocity::native(0.2)), ..MoveSpec::to(Position::native(2.0)) };
    let id = b.session.start(Op::MoveTo(addr(1), spec), b.now);
    b.idle(ms(500));
    assert!(b.module(1).0.contains(StateFlag::Motion));
    b.session.cancel(id, b.now);
    b.settle();
    let r = b.take_done(id).expect("ends at once: the halt is acknowledged within the same instant here");
    let err = r.unwrap_err();
    assert!(matches!(err, Error::Cancelled { address: A1, stop: StopOutcome::Confirmed }), "{err}");
    let (state, p, _, _) = b.module(1);
    assert!(state.contains(StateFlag::Halted) && !state.contains(StateFlag::Motion), "{state}");
    assert!(p > 0.05 && p < 0.2, "{p}");
    // Confirmed means seen at rest: after the Halt (0x02 to 0x0E1), CubeState (0x0A 0x27) was read.
    let halt = b.sent.iter().rposition(|(_, w)| frame(w, |id| id == 0xE1, Some(&[0x02]))).expect("the Halt");
    assert!(b.sent[halt + 1..].iter().any(|(_, w)| frame(w, |id| id == 0xC1, Some(&[0x0A, 0x27]))), "{:?}", b.sent);
    assert!(err.to_string().ends_with("it is at rest"), "{err}");
}

/// Module 1's CubeState reads (GetExtended 0x27) on CAN.
fn is_state_read(w: &Telegram) -> bool {
    frame(w, |id| id == 0xC1, Some(&[0x0A, 0x27]))
}

/// The Halt to module 1 (CMD_HALT, 0x02) on CAN.
fn is_halt(w: &Telegram) -> bool {
    frame(w, |id| id == 0xE1, Some(&[0x02]))
}

#[test]
fn a_cancelled_move_whose_state_cannot_be_read_after_the_halt_is_not_confirmed() {
    let mut b = Bench::can(&[1]);
    b.run(Op::EnableWatchdog(addrs(&[1]))).unwrap();
    let spec = MoveSpec { vel: Some(Velocity::native(0.2)), ..MoveSpec::to(Position::native(2.0)) };
    let id = b.session.start(Op::MoveTo(addr(1), spec), b.now);
    b.idle(ms(300));
    // From the Halt on, every CubeState read is lost: the Halt is acknowledged, the rest is not seen.
    let halted = std::cell::Cell::new(false);
    b.lose = Some(Box::new(move |w: &Telegram| {
        halted.set(halted.get() || is_halt(w));
        halted.get() && is_state_read(w)
    }));
    b.session.cancel(id, b.now);
    let err = b.wait_done_within(id, Duration::from_secs(5)).unwrap_err();
    match &err {
        Error::Cancelled { stop: StopOutcome::Unconfirmed { reason, watchdog_armed: true }, .. } => {
            assert!(reason.contains("acknowledged the Halt, but its state could not be read"), "{reason}")
        }
        other => panic!("{other:?}"),
    }
    let text = err.to_string();
    assert!(!text.contains("it is at rest") && text.contains("may still be moving"), "{text}");
    assert!(text.contains("halts itself within 50 ms"), "{text}");
    assert!(motionlink_link::error::Classify::stop_unconfirmed(&err), "exit 3, flagged: {err}");
    // The state was asked three times (as any read, also after the cancel), then a Halt broadcast.
    let halt = b.sent.iter().position(|(_, w)| is_halt(w)).unwrap();
    assert_eq!(b.sent[halt..].iter().filter(|(_, w)| is_state_read(w)).count(), 3, "{:?}", &b.sent[halt..]);
    assert!(b.sent[halt..].iter().any(|(_, w)| frame(w, |id| id == 0x100, Some(&[0x02]))));
    assert!(b.session.failed() && !b.session.watchdog_served());
}

#[test]
fn a_cancelled_move_whose_module_acknowledges_the_halt_but_keeps_moving_is_not_confirmed() {
    let mut b = Bench::can(&[1]);
    let spec = MoveSpec { vel: Some(Velocity::native(0.2)), ..MoveSpec::to(Position::native(2.0)) };
    let id = b.session.start(Op::MoveTo(addr(1), spec), b.now);
    b.idle(ms(300));
    // Every Halt by address is kept from the module, and acknowledged here in its name: a module that
    // acknowledges the Halt and goes on moving.
    let halts = std::rc::Rc::new(std::cell::Cell::new(0u32));
    let seen = halts.clone();
    b.lose = Some(Box::new(move |w: &Telegram| {
        let halt = is_halt(w);
        seen.set(seen.get() + u32::from(halt));
        halt
    }));
    b.session.cancel(id, b.now);
    let ack = crate::wire::can::to_frame(
        crate::wire::can::Role::Ack(1),
        &crate::wire::Reply::Action(crate::wire::Action::Halt).encode(),
    );
    let mut acked = 0;
    let limit = b.now + Duration::from_secs(5);
    let err = loop {
        b.settle();
        if acked < halts.get() {
            acked += 1;
            b.session.handle_input(Input::Frame(&ack), b.now);
            continue;
        }
        if let Some(r) = b.take_done(id) {
            break r.unwrap_err();
        }
        assert!(b.step_before(limit), "the stop ends");
    };
    assert_eq!(halts.get(), 1, "acknowledged at once: one Halt by address");
    match &err {
        Error::Cancelled { stop: StopOutcome::Unconfirmed { reason, watchdog_armed: false }, .. } => {
            assert!(reason.contains("acknowledged the Halt, but still reported STATE_MOTION 500 ms later"), "{reason}")
        }
        other => panic!("{other:?}"),
    }
    let text = err.to_string();
    assert!(text.contains("may still be moving") && text.contains("no watchdog is armed on it"), "{text}");
    assert!(motionlink_link::error::Classify::stop_unconfirmed(&err), "{err}");
    // Bounded: about HALT_SETTLE after the cancel. The broadcast Halt (which reaches the module) stops it.
    assert!(b.sent.iter().any(|(_, w)| frame(w, |id| id == 0x100, Some(&[0x02]))));
    assert!(!b.module(1).0.contains(StateFlag::Motion));
}

#[test]
fn a_cancelled_read_ends_at_once_and_sets_nothing_in_motion() {
    let mut b = Bench::rs232(&[1]);
    b.deaf = true;
    let id = b.session.start(Op::Scan, b.now);
    b.settle();
    b.session.cancel(id, b.now);
    b.settle();
    assert!(matches!(b.take_done(id), Some(Err(Error::CancelledBeforeMotion { what: "the scan" }))));
    assert!(b.session.is_idle() || b.session.wants_input(), "only the answer of the request on the line is awaited");
}

#[test]
fn close_halts_what_the_session_started_and_switches_the_watchdog_off() {
    let mut b = Bench::can(&[1, 2]);
    let before = b.module(1).3;
    b.run(Op::EnableWatchdog(addrs(&[1, 2]))).unwrap();
    b.run(Op::Motion(addr(1), Motion::FVel { vel: Velocity::native(0.2) }, AckKind::Simple)).unwrap();
    b.idle(ms(300));
    assert_eq!(b.close(), Ok(()));
    let (state, _, online, config) = b.module(1);
    assert!(state.contains(StateFlag::Halted) && !state.contains(StateFlag::Motion), "halted by address: {state}");
    assert!(!online && config == before, "watchdog off, Config word as it was");
    assert!(!b.module(2).0.contains(StateFlag::Halted), "module 2 did not move: left alone");
    // Nothing new once closed.
    let id = b.session.start(Op::State(addr(1)), b.now);
    b.settle();
    assert!(matches!(b.take_done(id), Some(Err(Error::Closed))));
    b.idle(Duration::from_secs(1));
    assert!(!b.module(2).0.has_fault(), "offline: nothing expires");
}

#[test]
fn a_close_that_cannot_confirm_the_stop_says_so_and_leaves_the_watchdog_to_stop_the_module() {
    let mut b = Bench::can(&[1]);
    b.run(Op::EnableWatchdog(addrs(&[1]))).unwrap();
    b.run(Op::Motion(addr(1), Motion::FVel { vel: Velocity::native(0.2) }, AckKind::Simple)).unwrap();
    b.idle(ms(100));
    b.deaf = true; // the modules' answers are lost from now on
    let sent_before = b.sent.len();
    let err = b.close().unwrap_err();
    assert!(
        err.starts_with("closing the session: module 1 set in motion by this session could not be confirmed stopped"),
        "{err}"
    );
    assert!(err.contains("halts itself within 50 ms"), "{err}");
    // It asked for the state three times; silence from a module that answered before: a Halt broadcast
    // (which reaches the module: the bus carries it, only the answers are lost).
    let broadcast = b.sent[sent_before..].iter().any(|(_, w)| frame(w, |id| id == 0x100, Some(&[0x02])));
    assert!(broadcast, "{:?}", &b.sent[sent_before..]);
    assert!(b.session.failed() && !b.session.watchdog_served());
    b.idle(ms(100));
    let (state, _, online, _) = b.module(1);
    assert!(!state.contains(StateFlag::Motion) && online, "{state}");
}

#[test]
fn a_guarded_move_arms_the_watchdog_for_its_motion_only() {
    let mut b = Bench::rs232(&[1]);
    let before = b.module(1).3;
    let spec = MoveSpec { vel: Some(Velocity::native(1.0)), ..MoveSpec::to(Position::native(0.3)) };
    let Ok(Output::Moved(_)) = b.run(Op::MoveGuarded(addr(1), spec, Guard::Watchdog)) else { panic!() };
    let events = b.take_device_events();
    let on = events.iter().position(|e| e == "module 1 watchdog online").expect("armed");
    let started = events.iter().position(|e| e.starts_with("module 1 motion started")).unwrap();
    let off = events.iter().position(|e| e == "module 1 watchdog offline").expect("disarmed");
    assert!(on < started && started < off, "{events:?}");
    assert_eq!(b.module(1).3, before, "Config word as it was");
    assert!(!b.module(1).3.contains(ConfigFlag::WatchdogEnable));
    // Not arming is the caller's choice.
    let Ok(Output::Moved(_)) = b.run(Op::MoveGuarded(addr(1), MoveSpec::to(Position::native(0.1)), Guard::HaltOnly))
    else {
        panic!()
    };
    assert!(!b.take_device_events().iter().any(|e| e.contains("watchdog")));
}

#[test]
fn arming_a_module_whose_watchdog_expired_is_refused_with_a_hint() {
    let mut b = Bench::can(&[1]);
    b.run(Op::EnableWatchdog(addrs(&[1]))).unwrap();
    b.session.die();
    b.idle(ms(100));
    assert!(b.module(1).0.contains(StateFlag::CommError));
    let mut b2 = Bench::can(&[1]);
    b2.device = b.device.clone();
    let err = b2.run(Op::MoveGuarded(addr(1), MoveSpec::to(Position::native(0.3)), Guard::Watchdog)).unwrap_err();
    assert!(err.is_device() && err.to_string().contains("`reset` clears it"), "{err}");
    assert!(matches!(b2.run(Op::ResetAndReleaseWatchdog(addr(1))), Ok(Output::Released(true))));
    assert!(!b2.module(1).2 && !b2.module(1).0.has_fault());
}

#[test]
fn a_bus_that_answers_in_reverse_order_is_still_matched() {
    // The session takes acknowledges in any order: feed the answers of a batch back to front.
    let mut b = Bench::can(&[1, 2, 3]);
    let id = b.session.start(Op::ReadMany(addrs(&[1, 2, 3]), Param::DefAddress), b.now);
    let mut answers = Vec::new();
    while let Some(LinkAction::SendFrame(f)) = b.session.poll_transmit(b.now) {
        CanEmulator::receive(&mut *b.device, b.now, &f, &mut answers);
    }
    assert_eq!(answers.len(), 3);
    for a in answers.iter().rev() {
        assert!(matches!(from_frame(a), Ok((Role::Ack(_), _))));
        b.session.handle_input(Input::Frame(a), b.now);
    }
    b.settle();
    let Some(Ok(Output::Values(v))) = b.take_done(id) else { panic!() };
    let got: Vec<Value> = v.into_iter().map(Result::unwrap).collect();
    assert_eq!(got, vec![Value::U8(1), Value::U8(2), Value::U8(3)]);
}

#[test]
fn a_scan_asks_each_address_on_rs232_and_all_at_once_on_can() {
    let mut b = Bench::rs232(&[2, 17]);
    let t0 = b.now;
    let Ok(Output::Scan(found)) = b.run(Op::Scan) else { panic!() };
    let infos: Vec<(u8, u32)> = found.iter().map(|e| (e.address.get(), e.info.as_ref().unwrap().serial)).collect();
    assert_eq!(infos, vec![(2, 1002), (17, 1017)]);
    // 29 silent addresses, 60 ms each, one after the other (silence is absence: not asked again).
    assert_eq!(b.now - t0, ms(29 * 60));
    assert_eq!(b.session.known(), vec![2, 17]);
    assert_eq!(b.session.kind_of(addr(17)), Some(ModuleKind::Rotary), "the scan taught the kinds");

    let mut b = Bench::can(&[2, 17]);
    let t0 = b.now;
    let Ok(Output::Scan(found)) = b.run(Op::Scan) else { panic!() };
    assert_eq!(found.len(), 2);
    assert_eq!(b.now - t0, ms(50), "31 questions out at once, one timeout for the silent ones");
}

#[test]
fn homing_is_waited_for_with_progress_at_the_poll_rate() {
    let mut b = Bench::rs232(&[1]);
    let Ok(Output::Homed(r)) = b.run(Op::HomeAndWait(addr(1), Duration::from_secs(10))) else { panic!() };
    let (p, s) = (r.reached, r.state);
    assert!(s.contains(StateFlag::HomeOk) && !s.contains(StateFlag::Motion), "{s}");
    assert!(p.value().abs() < 1e-6, "homed at the switch: {p}");
    assert_eq!(
        (r.kind, p.unit()),
        (ModuleKind::Rotary, crate::model::AxisUnit::Radian),
        "the kind read before homing names the unit"
    );
    assert!(r.verified && r.not_verifiable.is_empty(), "no guard asked for: nothing left undone");
    let polls = b.progress.len();
    assert!(polls >= 5, "{polls}");
    assert!(b.session.started().is_empty(), "seen to end");
}

#[test]
fn an_answer_that_echoes_another_parameter_is_corrupt_and_a_read_is_asked_again() {
    let mut b = Bench::rs232(&[1]);
    let id = b.session.start(Op::Get(addr(1), Param::ActPos), b.now);
    let Some(LinkAction::Send(_)) = b.session.poll_transmit(b.now) else { panic!() };
    // The module answers with PrevActPos (0x3d) instead of ActPos (0x3c): a corrupted echo.
    let wrong = crate::wire::Reply::Get(Param::PrevActPos, Value::F32(0.0)).encode();
    let mut frame = [0u8; crate::wire::rs232::MAX_FRAME];
    let n = crate::wire::rs232::encode(crate::wire::rs232::TelKind::Recv, 1, &wrong, &mut frame).unwrap();
    b.session.handle_input(Input::Bytes(&frame[..n]), b.now);
    b.sent.clear();
    // At the answer's deadline the read is asked again (a read may be), and the emulator answers it.
    let Ok(Output::Value(v)) = ({
        let limit = b.now + Duration::from_secs(1);
        loop {
            b.settle();
            if let Some(r) = b.take_done(id) {
                break r;
            }
            assert!(b.step_before(limit));
        }
    }) else {
        panic!()
    };
    assert_eq!(v, Value::F32(0.05));
    assert_eq!(b.sent.len(), 1, "asked once more");
}

#[test]
fn a_motion_command_cancelled_before_its_acknowledge_is_halted() {
    let mut b = Bench::can(&[1]);
    b.deaf = true; // the command arrives; its acknowledge is lost
    let motion = Motion::FVel { vel: Velocity::native(0.2) };
    let id = b.session.start(Op::Motion(addr(1), motion, AckKind::Simple), b.now);
    b.settle();
    assert!(b.module(1).0.contains(StateFlag::Motion), "the module took it");
    b.session.cancel(id, b.now);
    b.deaf = false;
    let limit = b.now + Duration::from_secs(1);
    let r = loop {
        b.settle();
        if let Some(r) = b.take_done(id) {
            break r;
        }
        assert!(b.step_before(limit));
    };
    let err = r.unwrap_err();
    assert!(matches!(err, Error::Cancelled { address: A1, stop: StopOutcome::Confirmed }), "{err}");
    let (state, ..) = b.module(1);
    assert!(state.contains(StateFlag::Halted) && !state.contains(StateFlag::Motion), "{state}");
}

#[test]
fn a_cancel_while_a_poll_is_unanswered_halts_without_asking_again() {
    let mut b = Bench::can(&[1]);
    let spec = MoveSpec { vel: Some(Velocity::native(0.2)), ..MoveSpec::to(Position::native(2.0)) };
    let id = b.session.start(Op::MoveTo(addr(1), spec), b.now);
    b.idle(ms(500));
    // The next poll's answer is lost; the caller gives up at once.
    b.deaf = true;
    let n = b.sent.len();
    // Requests to module 1: 0x0C1 (reads), 0x0E1 (commands).
    let to_module = |w: &Telegram| frame(w, |id| id == 0xC1 || id == 0xE1, None);
    b.run_until(ms(1000), |b| b.sent[n..].iter().any(|(_, w)| to_module(w)));
    b.deaf = false;
    let lost = n + b.sent[n..].iter().position(|(_, w)| to_module(w)).expect("the poll");
    let cancelled_at = b.now;
    b.session.cancel(id, b.now);
    let err = b.wait_done_within(id, Duration::from_secs(5)).unwrap_err();
    assert!(matches!(err, Error::Cancelled { address: A1, stop: StopOutcome::Confirmed }), "{err}");
    // The first request to the module after the cancel is the Halt (CMD_HALT, 0x02): the poll is not asked
    // again, which would hold the Halt back by a reply timeout per retry.
    let first = b.sent[lost + 1..].iter().find(|(_, w)| to_module(w)).map(|(t, w)| (*t, w[..].to_vec()));
    let (at, data) = first.expect("a request after the cancel");
    assert_eq!(data, [0x02], "the Halt first, not the poll again");
    assert!(at - cancelled_at <= Config::can().reply_timeout, "Halt {:?} after the cancel", at - cancelled_at);
    assert!(!b.module(1).0.contains(StateFlag::Motion));
}

/// A loss of the `n`th (from 1) read of `param_id` from module 1 (GetExtended, 0x0A), and whether it
/// happened.
fn lose_read(param_id: u8, n: u32) -> (motionlink_testkit::wired::Loss, std::rc::Rc<std::cell::Cell<bool>>) {
    let lost = std::rc::Rc::new(std::cell::Cell::new(false));
    let (seen, flag) = (std::cell::Cell::new(0), lost.clone());
    let lose = move |w: &Telegram| {
        if !frame(w, |id| id == 0xC1, Some(&[0x0A, param_id])) {
            return false;
        }
        seen.set(seen.get() + 1);
        let now = seen.get() == n;
        flag.set(flag.get() || now);
        now
    };
    (Box::new(lose), lost)
}

#[test]
fn a_stop_whose_caller_gave_up_still_retries_its_reads() {
    let mut b = Bench::can(&[1]);
    b.run(Op::Motion(addr(1), Motion::FVel { vel: Velocity::native(0.2) }, AckKind::Simple)).unwrap();
    b.idle(ms(100));
    let (lose, lost) = lose_read(0x27, 1); // the first CubeState read
    b.lose = Some(lose);
    let id = b.session.start(Op::HaltConfirmed(addr(1)), b.now);
    // The caller gives up at once: the stop runs to its end all the same, its lost read asked again.
    b.session.cancel(id, b.now);
    let r = b.wait_done_within(id, Duration::from_secs(5));
    assert!(lost.get(), "a state read was lost");
    let Ok(Output::Halted(report)) = r else { panic!("{r:?}") };
    assert!(report.state.contains(StateFlag::Halted) && !report.state.contains(StateFlag::Motion));
}

#[test]
fn a_move_cancelled_while_its_target_read_back_is_unanswered_reports_the_cancel() {
    let mut b = Bench::can(&[1]);
    // Every TargetPosInc read after the motion command (its target read back) is lost.
    let (moving, lost) = (std::cell::Cell::new(false), std::rc::Rc::new(std::cell::Cell::new(false)));
    let flag = lost.clone();
    b.lose = Some(Box::new(move |w: &Telegram| {
        moving.set(moving.get() || frame(w, |id| id == 0xE1, None) && w[0] == 0x0B);
        let now = moving.get() && frame(w, |id| id == 0xC1, Some(&[0x0A, 0x28]));
        flag.set(flag.get() || now);
        now
    }));
    let spec = MoveSpec { vel: Some(Velocity::native(0.2)), ..MoveSpec::to(Position::native(2.0)) };
    let id = b.session.start(Op::MoveTo(addr(1), spec), b.now);
    let seen = lost.clone();
    b.run_until(ms(1000), move |_| seen.get());
    // The caller gives up while the read-back goes unanswered: what ends the move is the cancel (its stop
    // confirmed), not a failing line.
    b.session.cancel(id, b.now);
    let err = b.wait_done_within(id, Duration::from_secs(5)).unwrap_err();
    assert!(matches!(err, Error::Cancelled { address: A1, stop: StopOutcome::Confirmed }), "{err:?}");
    assert!(!b.module(1).0.contains(StateFlag::Motion));
}

#[test]
fn a_module_whose_halt_was_not_confirmed_stays_started_and_the_close_says_so() {
    let mut b = Bench::can(&[1]);
    let spec = MoveSpec { vel: Some(Velocity::native(0.2)), ..MoveSpec::to(Position::native(2.0)) };
    let id = b.session.start(Op::MoveGuarded(addr(1), spec, Guard::HaltOnly), b.now);
    b.idle(ms(300));
    // The line breaks both ways while the module moves: neither the poll nor a Halt gets through.
    (b.cut, b.deaf) = (true, true);
    let err = b.wait_done_within(id, Duration::from_secs(5)).unwrap_err();
    assert!(motionlink_link::error::Classify::stop_unconfirmed(&err), "{err}");
    // It is still among what the session started, and the close tries again and says it could not.
    assert_eq!(b.session.started(), [A1]);
    let closed = b.close().unwrap_err();
    assert!(
        closed
            .starts_with("closing the session: module 1 set in motion by this session could not be confirmed stopped"),
        "{closed}"
    );
}
