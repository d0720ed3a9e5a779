//! Requests, reads, writes, scans, errors, matching on RS232 and CAN.

use super::*;
use crate::client::StopOutcome;
use crate::error::Error;
use crate::model::*;
use crate::wire::ACK_OK;
use crate::wire::{Action, ModelError, Reply, Request};
use motionlink_link::cancel::CancelToken;
use motionlink_link::Timestamp;

#[test]
fn scan_finds_every_module_on_rs232_and_can() {
    let (clock, _host, bus, _) = rs232(&[1, 17, 31]);
    let _me = clock.reserve_participant().enter();
    let found = scan_infos(&bus);
    assert_eq!(found.iter().map(|m| m.address.get()).collect::<Vec<_>>(), vec![1, 17, 31]);
    assert_eq!(found[1].serial, 1017);
    assert_eq!(found[1].version, CubeVersion(0x4634));
    assert_eq!(found[1].kind, ModuleKind::Rotary);
    assert!(!found[1].state.contains(StateFlag::HomeOk));
    drop(bus);

    let (clock, _canbus, bus) = can(&[2, 5]);
    let _me = clock.reserve_participant().enter();
    let t0 = clock.now();
    let found = scan_infos(&bus);
    assert_eq!(found.iter().map(|m| m.address.get()).collect::<Vec<_>>(), vec![2, 5]);
    // On CAN the 31 questions go out at once: the scan takes one timeout, not 31.
    assert!(clock.now() - t0 < Duration::from_millis(200), "{:?}", clock.now() - t0);
}

#[test]
fn every_parameter_reads_and_every_writable_one_writes() {
    let (clock, host, bus, faults) = rs232(&[1]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(addr(1));
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
    let m = bus.module(addr(1));
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
    let m = bus.module(addr(1));
    m.home().unwrap();
    m.wait_home(secs(10), &mut |_| {}).unwrap();
    m.set(Param::MaxPos, Value::F32(0.2)).unwrap();
    m.motion(Motion::FVel { vel: Velocity::native(0.5) }, AckKind::Simple).unwrap();
    let err = m.wait_motion_end(secs(10), &mut |_| {}).unwrap_err();
    match &err {
        Error::Device { address: A1, state } => assert!(state.contains(StateFlag::BeyondSoft)),
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
    let err = bus.module(addr(9)).position().unwrap_err();
    assert!(matches!(err, Error::Timeout { address: A9, .. }) && err.is_transport(), "{err}");
    assert!(err.to_string().contains("did not answer GetExtended ActPos"), "{err}");
    let frame = 8; // STX TELID(2) 0a 3c BCC ETX + escaping: 7 or 8
    let sent = faults.bytes_sent(Direction::HostToDevice) - sent0;
    assert!((3 * 7..=3 * frame).contains(&sent), "{sent}");
    assert!(clock.now() - t0 >= Duration::from_millis(600));
    // A lost acknowledge of a read: the second try answers.
    faults.drop_next(Direction::DeviceToHost, 3);
    assert!(bus.module(addr(1)).position().is_ok());
    // A lost acknowledge of a write is not repeated: the caller learns it.
    let sent0 = faults.bytes_sent(Direction::HostToDevice);
    faults.drop_next(Direction::DeviceToHost, 3);
    let err = bus.module(addr(1)).set(Param::TargetVel, Value::F32(0.2)).unwrap_err();
    assert!(matches!(err, Error::Timeout { .. }), "{err}");
    let sent = faults.bytes_sent(Direction::HostToDevice) - sent0;
    assert!(sent <= 11, "one frame only: {sent}");
    // Late replies of the timed-out request do not confuse the next one.
    assert!(bus.module(addr(1)).state().is_ok());
}

#[test]
fn a_corrupt_answer_is_an_error_and_reads_recover() {
    let (clock, _host, bus, faults) = rs232(&[1]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(addr(1));
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
fn dropping_the_session_halts_what_it_started() {
    let (clock, host, bus, _) = rs232(&[1, 2]);
    let _me = clock.reserve_participant().enter();
    bus.module(addr(1)).motion(Motion::FVel { vel: Velocity::native(0.3) }, AckKind::Simple).unwrap();
    bus.module(addr(2)).motion(Motion::FRamp { pos: Position::native(0.06) }, AckKind::Simple).unwrap();
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
    bus.set_cancel(token.clone());
    let m = bus.module(addr(1));
    m.motion(Motion::FCur { cur: Amperes(1.0) }, AckKind::Simple).unwrap();
    let err = m
        .wait_motion_end(secs(60), &mut |p| {
            if p.elapsed > Duration::from_millis(500) {
                token.cancel();
            }
        })
        .unwrap_err();
    assert!(matches!(err, Error::Cancelled { address: A1, stop: StopOutcome::Confirmed }), "{err}");
    assert!(err.to_string().contains("the module acknowledged the halt"), "{err}");
    assert!(host.with_device(|d| d.module(1).unwrap().state().contains(StateFlag::Halted)));
    // A wait that times out halts too.
    token.reset();
    m.reset().unwrap();
    m.motion(Motion::FVel { vel: Velocity::native(0.1) }, AckKind::Simple).unwrap();
    let err = m.wait_motion_end(Duration::from_millis(300), &mut |_| {}).unwrap_err();
    assert!(matches!(err, Error::MoveTimeout { stop: StopOutcome::Confirmed, .. }), "{err}");
    assert!(host.with_device(|d| d.module(1).unwrap().state().contains(StateFlag::Halted)));
}

#[test]
fn on_can_many_modules_are_polled_in_one_round() {
    let numbers: Vec<u8> = (1..=6).collect();
    let addresses = addrs(&numbers);
    let (clock, _canbus, bus) = can(&numbers);
    let _me = clock.reserve_participant().enter();
    let t0 = clock.now();
    bus.module(addr(3)).position().unwrap();
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
    assert_eq!(six, numbers.iter().map(|a| wire_time(*a)).sum::<Duration>());
    // One missing module does not hold the others up beyond one timeout (and reads are retried).
    let t0 = clock.now();
    let r = bus.positions(&addrs(&[1, 9, 2]));
    assert!(r[0].is_ok() && r[2].is_ok() && matches!(r[1], Err(Error::Timeout { address: A9, .. })));
    assert!(clock.now() - t0 < Duration::from_millis(200));
}

#[test]
fn extended_acknowledges_and_steps() {
    let (clock, _canbus, bus) = can(&[4]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(addr(4));
    let ext = m.motion(Motion::IRamp { pos: Ticks(1000) }, AckKind::Extended).unwrap().unwrap();
    assert!(matches!(ext.position, crate::wire::AckPosition::Ticks(_)));
    assert!(ext.state.contains(crate::model::ShortFlag::NotOk), "not homed");
    m.wait_motion_end(secs(10), &mut |_| {}).unwrap();
    assert_eq!(m.position_ticks().unwrap(), Ticks(1000));
    m.istep(Ticks(0), Millis(100)).unwrap();
    m.wait_motion_end(secs(10), &mut |_| {}).unwrap();
    assert_eq!(m.position_ticks().unwrap(), Ticks(0));
    let (_, short, _) = m.position_state_dio().unwrap();
    assert!(!short.contains(crate::model::ShortFlag::Motion));
    // The driver underneath, as every family's client gives it: the session it runs is this one.
    assert_eq!(bus.driver().port_name(), bus.port());
    assert_eq!(bus.driver().with_session(|s| s.started()), bus.started());
    assert!(matches!(m.set(Param::Config, Value::U32(0x0400_0000)), Err(Error::NotSupported(_))));
}

#[test]
fn a_broken_line_is_a_transport_error() {
    let (clock, _host, bus, faults) = rs232(&[1]);
    let _me = clock.reserve_participant().enter();
    faults.disconnect();
    let err = bus.module(addr(1)).state().unwrap_err();
    assert!(matches!(err, Error::Link(ref l) if l.is_disconnect()) && err.is_transport(), "{err}");
    // An address outside 1..31 cannot be made, so no handle on it: the number is refused where it is typed.
    assert!(matches!(Address::new(0).map_err(Error::from), Err(Error::InvalidAddress(0))));
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
        let err = bus.request(addr(1), r).unwrap_err();
        assert!(matches!(err, Error::Model(_)) && err.is_usage(), "{r}: {err}");
    }
    assert_eq!(faults.bytes_sent(Direction::HostToDevice), sent, "nothing was sent");
    assert!(bus.started().is_empty(), "a refused motion starts nothing");
    // Several at once: the bad ones get their error, the good ones go out and are answered.
    // (An address outside 1..31 cannot be among them: `Address` refuses it where it is made.)
    assert!(matches!(Address::new(0).map_err(Error::from), Err(Error::InvalidAddress(0))));
    let mixed = [
        (addr(1), Request::Get(Param::ActPos)),
        (addr(1), bad[0]),
        (addr(1), bad[4]),
        (addr(1), Request::Get(Param::CubeState)),
    ];
    let r = bus.request_many(&mixed);
    assert!(matches!(r[0], Ok(Reply::Get(Param::ActPos, _))), "{:?}", r[0]);
    assert!(matches!(r[1], Err(Error::Model(ModelError::NotWritable(Param::ActPos)))), "{:?}", r[1]);
    assert!(matches!(r[2], Err(Error::Model(ModelError::NoExtendedAck(_)))), "{:?}", r[2]);
    assert!(matches!(r[3], Ok(Reply::Get(Param::CubeState, _))), "{:?}", r[3]);
    clock.sleep(secs(1));
    let s = host.with_device(|d| d.module(1).unwrap().state());
    assert!(!s.contains(StateFlag::Motion), "no loop was started under another MotionID: {s}");
    // On CAN, a Config word that would switch the acknowledges off is refused the same way.
    let (clock, _canbus, bus) = can(&[1]);
    let _me = clock.reserve_participant().enter();
    let err = bus.request(addr(1), &Request::Set(Param::Config, Value::U32(0x0400_0000))).unwrap_err();
    assert!(matches!(err, Error::NotSupported(_)), "{err}");
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
    let sim = Emulator::new_can(&SimConfig::with_addresses(&addresses).unwrap());
    let canbus = CanBus::with_emulator(sim, clock.shared(), CanBusConfig::paced(1_000_000));
    let reordered = Arc::new(std::sync::atomic::AtomicU64::new(0));
    let link = Reversing {
        inner: canbus.connect(),
        held: Vec::new(),
        window: Duration::from_millis(1),
        reordered: Arc::clone(&reordered),
    };
    let _me = clock.reserve_participant().enter();
    let bus = Client::with_link(PortLink::Can(Box::new(link)), clock.shared(), Config::can()).unwrap();

    // Each module's own serial number comes back to it, however the answers are ordered.
    let t0 = clock.now();
    let serials = bus.read_many(&addrs(&addresses), Param::DefCubeSerial);
    assert!(clock.now() - t0 < bus.config().reply_timeout, "one round, nothing timed out or retried");
    for (a, s) in addresses.iter().zip(serials) {
        assert_eq!(s.unwrap(), Value::U32(1000 + u32::from(*a)), "module {a}");
    }
    assert!(reordered.load(Ordering::SeqCst) > 0, "the answers did arrive out of order");

    // Several requests to one module, and writes and motions among reads: each matched to its own.
    let requests = [
        (addr(1), Request::Get(Param::ActPos)),
        (addr(1), Request::Get(Param::CubeState)),
        (addr(1), Request::Get(Param::DefCubeSerial)),
        (addr(2), Request::Get(Param::DefAddress)),
        (addr(3), Request::Set(Param::TargetVel, Value::F32(0.5))),
        (addr(4), Request::Motion(Motion::FRamp { pos: Position::native(0.1) }, AckKind::Extended)),
        (addr(5), Request::Action(Action::Reset)),
        (addr(6), Request::Get(Param::DefAddress)),
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
        assert!(bus.positions(&addrs(&addresses)).iter().all(Result::is_ok));
        assert!(bus
            .read_many(&addrs(&addresses), Param::DefAddress)
            .iter()
            .zip(&addresses)
            .all(|(v, a)| *v.as_ref().unwrap() == Value::U8(*a)));
    }
}

#[test]
fn a_cancelled_token_ends_a_scan_at_once() {
    // Only module 1 answers: every other address of 2..31 costs a reply timeout. A signal 150 ms into the
    // scan ends it then, not after all of them.
    let (clock, _host, bus, _faults) = rs232(&[1]);
    let _me = clock.reserve_participant().enter();
    let token = CancelToken::new();
    bus.set_cancel(token.clone());
    let whole = {
        let started = clock.now();
        assert_eq!(bus.scan().unwrap().len(), 1);
        clock.now() - started
    };
    assert!(whole > Duration::from_millis(600), "a whole scan takes {whole:?}");
    let ticket = clock.reserve_participant();
    let (c2, t2) = (clock.clone(), token.clone());
    let canceller = std::thread::spawn(move || {
        let _p = ticket.enter();
        c2.sleep(Duration::from_millis(150));
        t2.cancel();
    });
    let started = clock.now();
    let err = bus.scan().unwrap_err();
    let took = clock.now() - started;
    canceller.join().unwrap();
    assert!(matches!(err, Error::CancelledBeforeMotion { what: "the scan" }), "{err}");
    assert!(took < Duration::from_millis(200), "ended {took:?} after its start");
    // The session goes on: with the token reset, reads and scans work again.
    token.reset();
    assert_eq!(bus.scan().unwrap().len(), 1);
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
    assert_eq!(
        found.iter().map(|m| m.address.get()).collect::<Vec<_>>(),
        vec![1, 17],
        "read again, not taken as absent"
    );
    assert_eq!(found[1].serial, 1017);
}

#[test]
fn a_module_that_cannot_be_read_is_reported_and_the_scan_goes_on() {
    let (clock, _host, bus, faults) = rs232(&[1, 17]);
    let _me = clock.reserve_participant().enter();
    // What the modules send before module 17's info: both scan answers, then module 1's info (version,
    // Config, serial, state), as a twin emulator answers them.
    let mut twin = Emulator::new(&SimConfig::with_addresses(&[1, 17]).unwrap());
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
    assert_eq!(entries.iter().map(|e| e.address.get()).collect::<Vec<_>>(), vec![1, 17]);
    assert_eq!(entries[0].info.as_ref().unwrap().serial, 1001);
    let err = entries[1].info.as_ref().unwrap_err();
    assert!(matches!(err, Error::Timeout { address: A17, .. }), "{err}");
}

#[test]
fn an_slcan_adapter_that_refuses_a_frame_is_a_link_error_not_a_timeout() {
    use motionlink_link::can::{SlcanAdapter, SlcanBitrate, SlcanLink};
    let clock = ManualClock::new_auto();
    let adapter = SlcanAdapter::new(Emulator::new_can(&SimConfig::with_addresses(&[3]).unwrap()));
    let host = EmulatorHost::new(adapter, clock.shared(), PipeConfig::paced(115_200));
    let _me = clock.reserve_participant().enter();
    let link = SlcanLink::open(host.connect().0, clock.shared(), SlcanBitrate::M1).unwrap();
    let bus = Client::with_link(PortLink::Can(Box::new(link)), clock.shared(), Config::can()).unwrap();
    let m = bus.module(addr(3));
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
    assert_eq!(entries.iter().map(|e| e.address.get()).collect::<Vec<_>>(), vec![1], "{entries:?}");
    assert!(entries[0].info.is_ok());
}

#[test]
fn a_reset_is_confirmed_by_the_state_and_a_fault_it_leaves_is_an_error() {
    let (clock, host, bus, _) = rs232(&[1]);
    let _me = clock.reserve_participant().enter();
    let m = bus.module(addr(1));
    // A following error: the Reset clears it, read back.
    host.with_device(|d| d.module_mut(1).unwrap().inject_fault(CubeState::EMPTY.with(StateFlag::TowError)));
    assert!(!m.reset_and_release_watchdog().unwrap());
    assert!(!m.state().unwrap().contains(StateFlag::Error));
    // A fault of the servo amplifier outlives the Reset (manual 5: the module is switched off to reset it).
    let fet = CubeState::EMPTY.with(StateFlag::PowerFault).with(StateFlag::PowFetTemp);
    host.with_device(|d| d.module_mut(1).unwrap().inject_fault(fet));
    let t0 = clock.now();
    let e = m.reset_and_release_watchdog().unwrap_err();
    // The state was read again for the settling time (a Reset may take effect a little later).
    assert!(clock.now().saturating_since(t0) >= Duration::from_millis(100), "{:?}", clock.now().saturating_since(t0));
    assert!(e.is_device(), "{e:?}");
    let text = e.to_string();
    assert!(text.starts_with("the Reset of module 1 left STATE_ERROR set: module 1 reports an error:"), "{text}");
    assert!(text.contains("STATE_POW_FET_TEMP") && text.contains("switching the module off"), "{text}");
    // So does a CPU that lost its current controller (STATE_CPU_OVERLOAD: "Power must be switched off").
    let (clock, host, bus, _) = rs232(&[1]);
    let _me = clock.reserve_participant().enter();
    host.with_device(|d| d.module_mut(1).unwrap().inject_fault(CubeState::EMPTY.with(StateFlag::CpuOverload)));
    let e = bus.module(addr(1)).reset_and_release_watchdog().unwrap_err();
    assert!(e.is_device() && e.to_string().contains("STATE_CPU_OVERLOAD"), "{e}");
    // A fault of the supply voltage, the voltage back: the Reset clears it.
    let (clock, host, bus, _) = rs232(&[1]);
    let _me = clock.reserve_participant().enter();
    let volt = CubeState::EMPTY.with(StateFlag::PowerFault).with(StateFlag::PowVoltErr);
    host.with_device(|d| d.module_mut(1).unwrap().inject_fault(volt));
    assert!(!bus.module(addr(1)).reset_and_release_watchdog().unwrap());
    assert!(!bus.module(addr(1)).state().unwrap().has_fault());
}
