//! Checked moves, read-back writes, stops that say whether they were confirmed, the poll rate, one
//! flipped bit anywhere.

use super::*;
use crate::client::MoveReport;
use crate::client::{Readback, StopOutcome};
use crate::error::Error;
use crate::model::*;
use crate::wire::Request;
use motionlink_link::Link;

#[test]
fn a_checked_move_refuses_targets_beyond_the_limits_before_anything_moves() {
    let (clock, host, bus, _) = rs232_instant(&[1]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(addr(1));
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
            Error::OutsideLimits { limit: l, .. } => assert_eq!(*l, limit, "{err}"),
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
        MoveSpec { tolerance: Some(Position::native(0.0)), ..MoveSpec::to(Position::native(0.1)) },
        MoveSpec { timeout: Duration::ZERO, ..MoveSpec::to(Position::native(0.1)) },
    ] {
        assert!(matches!(m.move_to(&s, &mut |_| {}), Err(Error::InvalidArgument { .. })), "{s:?}");
    }
    // A module whose own TargetVel is 0 would never arrive: refused when no velocity is given, once its
    // TargetVelInc is found to mirror it (the checked write finds it out).
    m.set_checked(Param::TargetVel, Value::F32(0.0)).unwrap();
    let err = m.move_to(&MoveSpec::to(Position::native(0.5)), &mut |_| {}).unwrap_err();
    assert!(matches!(err, Error::InvalidArgument { what: "the velocity", .. }), "{err}");
    assert!(err.to_string().contains("found to mirror it"), "{err}");
    assert!(!sim_module(&host, 1).0.contains(StateFlag::Motion));
    // A halted module would ignore the motion command: refused, named, before anything is written.
    m.halt().unwrap();
    let err = m.move_to(&spec(0.5), &mut |_| {}).unwrap_err();
    assert!(matches!(err, Error::Halted { address: A1, .. }), "{err}");
    let err = m.home_and_wait(secs(10), &mut |_| {}).unwrap_err();
    assert!(matches!(err, Error::Halted { address: A1, .. }), "{err}");
    let events = host.with_device(|d| d.take_events());
    assert_eq!(events, ["module 1 halted"], "no write, no motion command after the halt");
}

#[test]
fn a_checked_move_ends_within_the_tolerance_or_says_where_it_ended() {
    let (clock, host, bus, _) = rs232_instant(&[1]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(addr(1));
    let report = m.move_to(&spec(0.5), &mut |_| {}).unwrap();
    assert!((report.reached.value() - 0.5).abs() < 1e-6 && report.state.contains(StateFlag::RampEnd), "{report:?}");
    // Every position of the report is in the unit of the module's kind, which the move read first.
    assert_eq!(
        (report.kind, report.start, report.target),
        (ModuleKind::Rotary, Position::rad(0.05), Position::rad(0.5))
    );
    assert!(bus.started().is_empty());
    // A module that settles 5 mrad beyond its target: outside the default 1 mrad tolerance.
    host.with_device(|d| {
        let mut cfg = crate::sim::ModuleConfig::at(2);
        cfg.settle_offset = 0.005;
        let sim = Emulator::new(&SimConfig { modules: vec![cfg], ..SimConfig::default() });
        *d = sim;
    });
    let m = bus.module(addr(2));
    let err = m.move_to(&spec(0.5), &mut |_| {}).unwrap_err();
    match &err {
        Error::NotReached { target, reached, difference, .. } => {
            assert_eq!(target.value(), 0.5);
            assert!((reached.value() - 0.505).abs() < 1e-6 && (difference.value() - 0.005).abs() < 1e-6, "{err}");
        }
        other => panic!("{other}"),
    }
    assert!(err.is_device(), "exit code 1");
    let text = err.to_string();
    assert!(text.contains("target 0.5") && text.contains("0.505") && text.contains("0.005"), "{text}");
    // A wider tolerance accepts it.
    let wide = MoveSpec { tolerance: Some(Position::native(0.01)), ..spec(0.3) };
    assert!((m.move_to(&wide, &mut |_| {}).unwrap().reached.value() - 0.305).abs() < 1e-6);
}

#[test]
fn a_checked_move_reads_back_its_ramp_and_target_and_halts_a_corrupted_command() {
    let (clock, host, bus, faults) = rs232_instant(&[1]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(addr(1));
    // A write of TargetVel whose value is corrupted on the way (the module ignores the BCC): the read-back
    // of TargetVelInc shows it, before anything moves.
    let set_vel = Request::set(Param::TargetVel, Value::F32(1.0)).unwrap();
    let mut frame = [0u8; crate::wire::rs232::MAX_FRAME];
    let n = crate::wire::rs232::encode(crate::wire::rs232::TelKind::Send, 1, &set_vel.encode(), &mut frame).unwrap();
    // The reads before it (the kind, limits, state, the one probe of ActFPosStateDio, IncRatio, ActPos,
    // TargetVelInc before the write: the session does not know yet whether it follows TargetVel) are
    // counted frame by frame; the byte hit is the float's most significant one.
    let before = faults.bytes_sent(Direction::HostToDevice);
    let reads = [
        Param::Config,
        Param::MinPos,
        Param::MaxPos,
        Param::MaxVel,
        Param::MaxAcc,
        Param::CubeState,
        Param::IncRatio,
        Param::ActPos,
    ];
    let first_reads = [Param::ActFPosStateDio, Param::TargetVelInc];
    let read_bytes: u64 = reads.iter().chain(&first_reads).map(|p| rs232_request_len(1, &Request::Get(*p))).sum();
    let value_msb = before + read_bytes + (n as u64 - 3); // STX TELID TELID 08 4F v0 v1 v2 v3 BCC ETX
    assert_eq!(frame[n - 3], 0x3f, "1.0f32 ends in 0x3f");
    faults.inject(Direction::HostToDevice, value_msb, motionlink_link::pipe::Fault::Corrupt { xor: 0x01 });
    let err = m.move_to(&spec(0.5), &mut |_| {}).unwrap_err();
    let Error::ReadBack { param: Param::TargetVel, wrote, read, twin: Some(twin), .. } = &err else { panic!("{err}") };
    assert_eq!((*wrote, twin.param), (Value::F32(1.0), Param::TargetVelInc), "the velocity of the spec: {err}");
    assert_ne!(twin.read_ticks, twin.expected_ticks, "{err}");
    assert_ne!(*read, *wrote, "{err}");
    assert!(err.to_string().contains(&format!("({} ticks in TargetVelInc)", twin.read_ticks)), "{err}");
    assert!(!sim_module(&host, 1).0.contains(StateFlag::Motion), "nothing moved");
    // TargetVelInc changed, to another value: the module mirrors (and took a wrong one).
    assert_eq!(bus.session(|s| s.findings(addr(1))).target_vel_twin, Some(true));
    // The motion command itself corrupted: 0.5 (00 00 00 3f) arrives as 0.5000001 or so many ticks away
    // that the module's TargetPosInc shows it; the module is halted at once.
    faults.heal();
    let start = faults.bytes_sent(Direction::HostToDevice);
    let motion = Request::motion(Motion::FRamp { pos: Position::native(2.0) }, AckKind::Simple).unwrap();
    // TargetAcc and TargetPos are written the first time with their twin read before and after (TargetPos
    // as the target, before the motion command sets it); the kind is known by now.
    let get = |p| rs232_request_len(1, &Request::Get(p));
    let all_before_motion: u64 = reads.iter().filter(|p| **p != Param::Config).map(|p| get(*p)).sum::<u64>()
        + rs232_request_len(1, &Request::set(Param::TargetVel, Value::F32(1.0)).unwrap())
        + get(Param::TargetVelInc)
        + get(Param::TargetAccInc)
        + rs232_request_len(1, &Request::set(Param::TargetAcc, Value::F32(2.0)).unwrap())
        + get(Param::TargetAccInc)
        + get(Param::TargetPosInc)
        + rs232_request_len(1, &Request::set(Param::TargetPos, Value::F32(2.0)).unwrap())
        + get(Param::TargetPosInc);
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

#[test]
fn set_checked_reads_back_and_names_a_mismatch() {
    let (clock, host, bus, _) = rs232_instant(&[1]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(addr(1));
    // Read back as written.
    assert_eq!(m.set_checked(Param::MaxVel, Value::F32(0.5)).unwrap(), Readback::same(Value::F32(0.5)));
    assert!(matches!(m.set_checked(Param::TargetVel, Value::F32(0.25)).unwrap().read, Some(Value::U32(_))));
    assert!(matches!(m.set_checked(Param::TargetPos, Value::F32(-1.0)).unwrap().read, Some(Value::I32(_))));
    assert!(m.set_checked(Param::DioSetup, Value::U32(0x30)).unwrap().verified);
    let cur = m.set_checked(Param::Cur, Value::F32(1.0)).unwrap();
    assert!(!cur.verified && cur.read.is_none() && cur.not_verifiable[0].contains("measured current"), "{cur:?}");
    // The module limits a limit to its ROM default (DefMaxVel = 1 rad/s): not silently.
    let err = m.set_checked(Param::MaxVel, Value::F32(10.0)).unwrap_err();
    let read_back = Error::ReadBack {
        address: addr(1),
        param: Param::MaxVel,
        wrote: Value::F32(10.0),
        read: Value::F32(1.0),
        twin: None,
    };
    assert_eq!(err.to_string(), read_back.to_string());
    assert!(
        matches!(err, Error::ReadBack { wrote: Value::F32(10.0), read: Value::F32(1.0), twin: None, .. })
            && err.is_device()
    );
    assert!(err.to_string().contains("10.000000") && err.to_string().contains("1.000000"), "{err}");
    // A target beyond its limit is refused before it is written.
    let velinc = host.with_device(|d| d.request(clock.now(), 1, &Request::Get(Param::TargetVelInc)));
    let err = m.set_checked(Param::TargetVel, Value::F32(2.0)).unwrap_err();
    assert!(matches!(err, Error::OutsideLimits { limit: Param::MaxVel, .. }) && err.is_usage(), "{err}");
    let err = m.set_checked(Param::TargetPos, Value::F32(4.0)).unwrap_err();
    assert!(matches!(err, Error::OutsideLimits { limit: Param::MaxPos, .. }), "{err}");
    let err = m.set_checked(Param::Cur, Value::F32(6.0)).unwrap_err();
    assert!(matches!(err, Error::OutsideLimits { limit: Param::MaxCur, .. }), "{err}");
    // A ramp's velocity and acceleration are sizes: a negative one is refused as given (not by its size).
    for (param, given) in [(Param::TargetVel, -1.0), (Param::TargetVel, -5.0), (Param::TargetAcc, -1.0)] {
        let err = m.set_checked(param, Value::F32(given)).unwrap_err();
        assert!(matches!(err, Error::InvalidArgument { .. }) && err.is_usage(), "{err}");
        assert!(err.to_string().starts_with(&format!("{param} must be at least 0")), "{err}");
        assert!(err.to_string().ends_with(&format!("not {given}")), "{err}");
    }
    assert_eq!(host.with_device(|d| d.request(clock.now(), 1, &Request::Get(Param::TargetVelInc))), velinc);
}

#[test]
fn the_tick_targets_are_checked_against_the_int32_tick_limits() {
    let (clock, host, bus, _) = rs232_instant(&[1]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(addr(1));
    let limit = |p: Param| match host.with_device(|d| d.request(clock.now(), 1, &Request::Get(p))) {
        Some(crate::wire::Reply::Get(_, Value::I32(v))) => v,
        other => panic!("{p}: {other:?}"),
    };
    let (max_vel, max_acc, max_pos) = (limit(Param::ActIMaxVel), limit(Param::ActIMaxAcc), limit(Param::ActIMaxPos));
    assert!(max_vel > 100 && max_acc > 100 && max_pos > 100, "{max_vel} {max_acc} {max_pos}");
    for (param, value) in [
        (Param::TargetVelInc, Value::U32(100)),
        (Param::TargetAccInc, Value::U32(100)),
        (Param::TargetPosInc, Value::I32(100)),
        (Param::TargetPosInc, Value::I32(-100)),
    ] {
        let r = m.set_checked(param, value).unwrap_or_else(|e| panic!("{param} {value:?}: {e}"));
        assert_eq!(r.read, Some(value), "{param}");
    }
    for (param, value, refused_by) in [
        (Param::TargetVelInc, Value::U32(max_vel as u32 + 1), Param::ActIMaxVel),
        (Param::TargetAccInc, Value::U32(max_acc as u32 + 1), Param::ActIMaxAcc),
        (Param::TargetPosInc, Value::I32(max_pos + 1), Param::ActIMaxPos),
        (Param::TargetPosInc, Value::I32(limit(Param::ActIMinPos) - 1), Param::ActIMinPos),
    ] {
        let err = m.set_checked(param, value).unwrap_err();
        assert!(matches!(err, Error::OutsideLimits { limit, .. } if limit == refused_by), "{param}: {err}");
        assert!(err.is_usage() && err.to_string().contains(refused_by.name()), "{err}");
    }
    let err = m.set_checked(Param::TargetPosInc, Value::I32(max_pos + 1)).unwrap_err().to_string();
    assert!(err.contains(&format!("ActIMinPos..ActIMaxPos = {}..{max_pos}", limit(Param::ActIMinPos))), "{err}");
}

#[test]
fn a_line_that_fails_during_a_move_is_stopped_and_the_error_says_so() {
    // Answers lost for a while: the poll's read times out three times, the halt gets through.
    let (clock, host, bus, faults) = rs232_instant(&[1]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(addr(1));
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
        Error::FailedDuringMotion { stop: StopOutcome::Confirmed, cause, .. } => {
            assert!(matches!(**cause, Error::Timeout { .. } | Error::Corrupt { .. }), "{cause}")
        }
        other => panic!("{other}"),
    }
    assert!(err.is_transport(), "exit code 3");
    assert!(err.to_string().contains("the module acknowledged the halt and then reported no motion"), "{err}");
    let (state, _) = sim_module(&host, 1);
    assert!(state.contains(StateFlag::Halted) && !state.contains(StateFlag::Motion), "{state}");
    drop(bus);

    // The line breaks for good during a move with the watchdog armed: no halt can be confirmed; the error
    // says the axis may still be moving, and that the watchdog (no longer refreshed) halts it; it does.
    let (clock, host, bus, faults) = rs232_instant(&[1]);
    let _me = clock.reserve_participant().enter();
    bus.enable_watchdog(&addrs(&[1])).unwrap();
    let m = bus.module(addr(1));
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
        Error::FailedDuringMotion { stop: StopOutcome::Unconfirmed { watchdog_armed: true, .. }, .. } => {}
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
    let m = bus.module(addr(1));
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
        Error::FailedDuringMotion { stop: StopOutcome::Unconfirmed { watchdog_armed: false, .. }, .. }
    ));
    let text = err.to_string();
    assert!(text.contains("the axis may still be moving") && text.contains("no watchdog is armed"), "{text}");
}

#[test]
fn waiting_polls_at_the_set_rate_not_as_fast_as_the_line_answers() {
    // An instant line answers in no time: the wait still polls once per poll_interval (10 ms).
    let (clock, host, bus, faults) = rs232_instant(&[1]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(addr(1));
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
        let sim = Emulator::new(&SimConfig::default());
        let host = EmulatorHost::new(sim, clock.shared(), PipeConfig::instant());
        let bus = Client::with_link(
            PortLink::Rs232(Box::new(host.connect().0)),
            clock.shared(),
            Config { poll_interval: Duration::from_millis(50), ..Config::rs232() },
        )
        .unwrap();
        (clock, host, bus, ())
    };
    let _me = clock.reserve_participant().enter();
    let mut polls = 0;
    bus.module(addr(1))
        .move_to(&MoveSpec { vel: Some(Velocity::native(0.5)), ..spec(1.0) }, &mut |_| polls += 1)
        .unwrap();
    assert!((43..=45).contains(&polls), "{polls}");
}

#[test]
fn an_answer_that_echoes_another_command_or_has_a_wrong_length_is_corrupt() {
    use crate::wire::rs232::{encode_raw, telid, TelKind};
    let clock = ManualClock::new_auto();
    let _me = clock.reserve_participant().enter();
    let (host_end, mut device_end, _faults) = motionlink_link::pipe::pipe(clock.shared(), PipeConfig::instant());
    let bus = Client::with_link(PortLink::Rs232(Box::new(host_end)), clock.shared(), Config::rs232()).unwrap();
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
    let m = bus.module(addr(1));
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
    let result = bus.enable_watchdog(&addrs(&[1])).and_then(|()| {
        bus.module(addr(1)).move_to(&spec(0.3), &mut |_| {
            first_poll.get_or_insert_with(sent);
        })
    });
    let end = sent();
    let _ = bus.halt_started();
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
    let cases: Vec<(Direction, u64, u8)> = ranges
        .into_iter()
        .flat_map(|(dir, offsets)| offsets.flat_map(move |offset| (0..8).map(move |bit| (dir, offset, 1u8 << bit))))
        .collect();
    // Each run is a session of its own on its own manual clock: the cases are shared out among the cores.
    let threads = std::thread::available_parallelism().map_or(2, std::num::NonZeroUsize::get);
    let failed: usize = std::thread::scope(|scope| {
        let workers: Vec<_> = (0..threads)
            .map(|k| {
                let cases = &cases;
                scope.spawn(move || cases.iter().skip(k).step_by(threads).filter(|c| !flip_case_succeeded(**c)).count())
            })
            .collect();
        workers.into_iter().map(|w| w.join().expect("a flip case failed (its message is above)")).sum()
    });
    let runs = cases.len();
    // Most flips are caught and the move fails (or is retried and succeeds); none succeeds wrongly.
    assert!(runs > 2_000 && failed > 0, "{runs} runs, {failed} failed");
}

/// One run of [`one_flipped_bit_anywhere_never_gives_a_false_success`] with `mask` XORed into the byte at
/// `offset` of the `dir` stream; panics on a false success; whether the move succeeded.
fn flip_case_succeeded((dir, offset, mask): (Direction, u64, u8)) -> bool {
    let run = flip_run(Some((dir, offset, mask)));
    let what = format!("{dir:?} byte {offset} mask {mask:#04x}");
    assert!(!run.after.0.contains(StateFlag::Motion), "{what}: module 1 left moving: {:?}", run.result);
    assert!(!run.other.0.contains(StateFlag::Motion), "{what}: module 3 left moving");
    // A corrupted command is caught before the axis goes anywhere else: module 1 ends between where it stood
    // (0.05) and where it was sent (0.3), give or take 20 mrad.
    assert!((0.03..=0.32).contains(&run.after.1), "{what}: module 1 went to {}: {:?}", run.after.1, run.result);
    match &run.result {
        Ok(report) => {
            assert!((report.reached.value() - 0.3).abs() <= 0.001, "{what}: {report:?}");
            assert!((run.after.1 - 0.3).abs() <= 0.001, "{what}: success, but module 1 is at {}", run.after.1);
            assert_eq!(run.other.1, 0.05, "{what}: success, but module 3 moved");
            true
        }
        // A motion command whose address was corrupted reaches module 3, which moves until the session sees
        // its unexpected acknowledge and halts it: the move fails.
        Err(_) => false,
    }
}

#[test]
fn a_target_read_back_through_its_tick_twin_converts_into_its_own_unit() {
    let (clock, _host, bus, _) = rs232_instant(&[1]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(addr(1));
    let ratio = m.get(Param::IncRatio).unwrap().as_f64().unwrap();
    for (p, twin, v) in [
        (Param::TargetPos, Param::TargetPosInc, -1.0f32),
        (Param::TargetVel, Param::TargetVelInc, 0.25),
        (Param::TargetAcc, Param::TargetAccInc, 0.5),
    ] {
        assert_eq!(p.read_back_as(), Some(twin));
        let Some(read) = m.set_checked(p, Value::F32(v)).unwrap().read else { panic!("{p} read back") };
        // What came back is the twin's value, in ticks, as the module holds it ...
        assert_eq!(read, m.get(twin).unwrap(), "{p}");
        // ... and in the written parameter's unit it is what was written (within a tick).
        let back = p.from_read_back_ticks(&read, ratio).unwrap();
        assert!((back - f64::from(v)).abs() <= 1.0 / ratio, "{p}: {back} for {v}");
    }
    // Parameters read back as themselves have no twin, and nothing to convert.
    assert_eq!(Param::MaxVel.read_back_as(), None);
    assert_eq!(Param::MaxVel.from_read_back_ticks(&Value::F32(0.5), ratio), None);
    // A ratio that is no number above 0 converts nothing.
    assert_eq!(Param::TargetPos.from_read_back_ticks(&Value::I32(100), 0.0), None);
    assert_eq!(Param::TargetPos.from_read_back_ticks(&Value::I32(100), f64::NAN), None);
    assert_eq!(Param::TargetPos.from_read_back_ticks(&Value::I32(-300), 100.0), Some(-3.0));
}

/// A move says whether the module is homed (its coordinates and MinPos/MaxPos hold only after homing, manual
/// 8), and one that the module's Config word would leave undone is refused before anything is sent, naming
/// the flag: CONFIGID_MOD_M3_COMPATIBLE while not homed (was: a move that ended "not reached"), and on CAN
/// CONFIGID_MOD_SYNC_MOTION (was: the ramp's timeout, the module waiting for startMotionAll).
#[test]
fn a_move_says_not_homed_and_is_refused_where_the_config_word_would_leave_it_undone() {
    let (clock, host, bus, _) = rs232_instant(&[1]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(addr(1));
    let r = m.move_to(&spec(0.2), &mut |_| {}).unwrap();
    assert!(!r.homed() && r.not_homed_note().unwrap().contains("not homed"), "{r:?}");
    let json = serde_json::to_value(&r).unwrap();
    assert_eq!(json["homed"], false, "{json}");
    // M3-compatible and not homed: refused, nothing sent to move it.
    let word = m.get(Param::Config).unwrap().as_u32().unwrap();
    m.set(Param::Config, Value::U32(word | ConfigFlag::M3Compatible.mask())).unwrap();
    host.with_device(|d| d.take_events());
    let err = m.move_to(&spec(0.4), &mut |_| {}).unwrap_err();
    assert!(matches!(err, Error::NotReady { address: A1, .. }), "{err}");
    assert!(err.to_string().contains("CONFIGID_MOD_M3_COMPATIBLE") && err.to_string().contains("home it first"));
    assert!(host.with_device(|d| d.take_events()).is_empty(), "something was sent that moves");
    // Homed, it moves, and says so.
    m.home_and_wait(secs(10), &mut |_| {}).unwrap();
    let r = m.move_to(&spec(0.4), &mut |_| {}).unwrap();
    assert!(r.homed() && r.not_homed_note().is_none(), "{r:?}");
    drop(bus);

    // CAN, SYNC_MOTION: refused (on RS232 the manual says the flag has no meaning).
    let (clock, canbus, bus) = can(&[2]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(addr(2));
    let word = m.get(Param::Config).unwrap().as_u32().unwrap();
    m.set(Param::Config, Value::U32(word | ConfigFlag::SyncMotion.mask())).unwrap();
    let t0 = clock.now();
    let err = m.move_to(&spec(0.3), &mut |_| {}).unwrap_err();
    assert!(err.to_string().contains("CONFIGID_MOD_SYNC_MOTION"), "{err}");
    assert!(clock.now() - t0 < Duration::from_millis(200), "refused at once, not at a timeout");
    assert!(!device_view(&canbus, &clock, 2).0.contains(StateFlag::Motion));
    drop(bus);

    // CAN, DISABLE_ACK set by another tool (this client refuses to write it): no motion command would be
    // acknowledged, nor a Halt: refused before anything is sent (was: a motion command, then a timeout).
    let (clock, canbus, bus) = can(&[3]);
    let _me = clock.reserve_participant().enter();
    let word = device_view(&canbus, &clock, 3).3;
    let disabled = Request::Set(Param::Config, Value::U32(word.0 | ConfigFlag::DisableAck.mask()));
    canbus.with_device(|d| d.request(clock.now(), 3, &disabled)).unwrap();
    let t0 = clock.now();
    let err = bus.module(addr(3)).move_to(&spec(0.3), &mut |_| {}).unwrap_err();
    assert!(matches!(err, Error::NotReady { .. }) && err.to_string().contains("CONFIGID_MOD_DISABLE_ACK"), "{err}");
    assert!(clock.now() - t0 < Duration::from_millis(200), "refused at once, not at a timeout");
    assert!(!device_view(&canbus, &clock, 3).0.contains(StateFlag::Motion));
}
