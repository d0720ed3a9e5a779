//! The client against the bus emulator, in-process, with the auto-advancing manual clock.

use std::time::Duration;

use motionlink_compax::client::{Bus, BusConfig, Error, MoveOptions};
use motionlink_compax::model::{
    Command, ErrorCode, OutputState, ParamId, Position, RampMs, S16Bits, S17Bits, SpeedPercent, StatusId, StatusValue,
};
use motionlink_compax::sim::{CompaxBus, SimConfig, REFUSED};
use motionlink_compax::wire::{Address, Mode};
use motionlink_link::cancel::CancelToken;
use motionlink_link::clock::{Clock, ManualClock, Timestamp};
use motionlink_link::pipe::{Direction, EmulatorHost, FaultControl, PipeConfig};
use motionlink_link::transcript::{TapLink, Transcript, Way};

struct Rig {
    clock: ManualClock,
    host: EmulatorHost<CompaxBus>,
    faults: FaultControl,
    transcript: Transcript,
}

fn rig(addrs: &[u8], p196: u32, baud: u32) -> (Rig, Bus) {
    let clock = ManualClock::new_auto();
    let sim = CompaxBus::new(SimConfig::bus(addrs, p196, baud)).unwrap();
    let host = EmulatorHost::new(sim, clock.shared(), PipeConfig::paced(baud));
    let (link, faults) = host.connect();
    let transcript = Transcript::new();
    let link = TapLink::new(link, clock.shared(), transcript.clone());
    let bus = Bus::new(Box::new(link), clock.shared(), BusConfig::new(Mode::from_p196(p196).unwrap(), baud));
    (Rig { clock, host, faults, transcript }, bus)
}

fn a(n: u8) -> Address {
    Address::drive(n).unwrap()
}

fn pos(v: f64) -> Position {
    Position::new(v).unwrap()
}

fn sent(t: &Transcript) -> Vec<Vec<u8>> {
    t.records().into_iter().filter(|r| r.way == Way::Sent).map(|r| r.bytes).collect()
}

#[test]
fn every_p196_combination_reads_writes_and_moves() {
    for p196 in 0..=Mode::MAX_P196 {
        let (r, mut bus) = rig(&[1, 5], p196, 38_400);
        let _me = r.clock.reserve_participant().enter();
        assert_eq!(bus.read_position(a(5)).unwrap(), pos(0.0), "P196={p196}");
        bus.write_param(a(5), ParamId::new(3).unwrap(), -1055.88).unwrap();
        assert_eq!(bus.read_param(a(5), ParamId::new(3).unwrap()).unwrap(), -1055.88, "P196={p196}");
        assert_eq!(bus.read_param(a(1), ParamId::OPERATING_MODE).unwrap(), f64::from(p196));
        let message = p196 % 3 == 0;
        bus.move_relative(a(1), pos(2.5), MoveOptions { binary: p196 % 2 == 1, message: message && p196 % 2 == 0 })
            .unwrap();
        bus.wait_reached(&[a(1)], Some(Duration::from_secs(5)), &mut |_, _| {}).unwrap();
        assert_eq!(bus.read_position(a(1)).unwrap(), pos(2.5), "P196={p196}");
        assert_eq!(bus.echo(a(5), "S1").unwrap(), "5S1?", "P196={p196}");
        assert!(bus.started().is_empty());
    }
}

#[test]
fn status_values_follow_the_motion_model() {
    let (r, mut bus) = rig(&[1], 0, 9600);
    let _me = r.clock.reserve_participant().enter();
    bus.set_speed(a(1), SpeedPercent::new(50.0).unwrap(), false).unwrap();
    bus.set_accel(a(1), RampMs::new(500).unwrap(), false).unwrap();
    let t0 = r.clock.now();
    bus.move_absolute(a(1), pos(100.0), MoveOptions::default()).unwrap();
    let s17 = bus.read_s17(a(1)).unwrap();
    assert!(s17.bit(S17Bits::COMMAND_ACTIVE) && s17.bit(S17Bits::RUN));
    assert_eq!(bus.read_target(a(1)).unwrap(), pos(100.0));
    let mut seen = Vec::new();
    bus.wait_reached(&[a(1)], None, &mut |_, p| seen.push(p.units())).unwrap();
    // 50 units/s cruise, 200 units/s² ramps: 0.25 s up, 0.25 s down, 1.75 s cruise: about 2.25 s.
    let took = (r.clock.now() - t0).as_secs_f64();
    assert!((2.2..2.45).contains(&took), "took {took} s");
    assert!(seen.windows(2).all(|w| w[0] <= w[1]), "positions rise monotonically: {seen:?}");
    assert!(seen.len() > 10, "{seen:?}");
    let s16 = bus.read_s16(a(1)).unwrap();
    assert!(s16.bit(S16Bits::POSITION_REACHED) && s16.bit(S16Bits::READY_FOR_START));
    assert_eq!(bus.read_status(a(1), StatusId::MOTION_CYCLES).unwrap(), StatusValue::Number(1.0));
}

#[test]
fn e92_for_a_move_while_moving() {
    let (r, mut bus) = rig(&[1], 0, 9600);
    let _me = r.clock.reserve_participant().enter();
    bus.move_absolute(a(1), pos(50.0), MoveOptions::default()).unwrap();
    let e = bus.move_absolute(a(1), pos(10.0), MoveOptions::default()).unwrap_err();
    assert_eq!(e.device_code(), Some(ErrorCode::COMMAND_ACTIVE), "{e}");
    assert!(!e.is_transport());
    bus.wait_reached(&[a(1)], None, &mut |_, _| {}).unwrap();
    assert_eq!(bus.read_position(a(1)).unwrap(), pos(50.0));
}

#[test]
fn a_corrupted_request_is_sent_again_after_e72() {
    let (r, mut bus) = rig(&[1], 8, 9600);
    let _me = r.clock.reserve_participant().enter();
    // Flip a bit of the command letter (the second byte): the drive's BCC check fails.
    let at = r.faults.bytes_sent(Direction::HostToDevice);
    r.faults.inject(Direction::HostToDevice, at + 1, motionlink_link::pipe::Fault::Corrupt { xor: 0x01 });
    assert_eq!(bus.read_position(a(1)).unwrap(), pos(0.0));
    let frames = sent(&r.transcript);
    assert_eq!(frames.len(), 2, "sent once, refused with E72, sent again: {frames:?}");
    assert_eq!(frames[0], frames[1]);
    let got = r.transcript.bytes(Way::Received);
    assert!(got.starts_with(b"E72\r\n>"), "{got:?}");
}

#[test]
fn a_gap_inside_a_telegram_gives_e73_and_a_resend() {
    let (r, mut bus) = rig(&[2], 16, 9600);
    let _me = r.clock.reserve_participant().enter();
    let at = r.faults.bytes_sent(Direction::HostToDevice);
    // Five character times at 9600 baud are 5.2 ms: hold the third byte back 10 ms.
    r.faults.inject(Direction::HostToDevice, at + 2, motionlink_link::pipe::Fault::Delay(Duration::from_millis(10)));
    bus.write_param(a(2), ParamId::new(10).unwrap(), 7.0).unwrap();
    assert!(r.transcript.bytes(Way::Received).starts_with(b"E73\r\n>"));
    assert_eq!(sent(&r.transcript).len(), 2);
    assert_eq!(bus.read_param(a(2), ParamId::new(10).unwrap()).unwrap(), 7.0);
}

#[test]
fn a_parity_error_gives_e70_and_a_resend() {
    let (r, mut bus) = rig(&[4], 2 + 4, 9600);
    let _me = r.clock.reserve_participant().enter();
    r.host.with_device(|d| d.inject_parity_error());
    assert_eq!(bus.read_position(a(4)).unwrap(), pos(0.0));
    assert!(r.transcript.bytes(Way::Received).starts_with(b"E70\r\n>"));
    assert_eq!(sent(&r.transcript).len(), 2);
}

#[test]
fn overflow_is_refused_before_sending_and_e71_is_a_device_error() {
    let (r, mut bus) = rig(&[1], 0, 9600);
    let _me = r.clock.reserve_participant().enter();
    let long = format!("P1={}", "1".repeat(40));
    assert!(matches!(bus.raw(a(1), &long), Err(Error::Wire(_))));
    assert!(sent(&r.transcript).is_empty());
    // Sent by hand (as a foreign program would), the drive answers E71.
    use motionlink_link::link::Link;
    let (mut raw_link, _) = r.host.connect();
    let mut t = b"1".to_vec();
    t.extend_from_slice(long.as_bytes());
    t.push(b'\r');
    raw_link.send(&t).unwrap();
    let mut buf = [0u8; 16];
    let mut got = Vec::new();
    while !got.ends_with(b">") {
        let n = raw_link.recv(&mut buf, Duration::from_secs(1)).unwrap();
        assert!(n > 0);
        got.extend_from_slice(&buf[..n]);
    }
    assert_eq!(got, b"E71\r\n>");
}

#[test]
fn timeouts_of_idempotent_reads_are_retried_then_reported() {
    let (r, mut bus) = rig(&[1], 0, 9600);
    let _me = r.clock.reserve_participant().enter();
    // The first reply is lost: the read is sent again.
    r.faults.drop_next(Direction::DeviceToHost, 14);
    assert_eq!(bus.read_position(a(1)).unwrap(), pos(0.0));
    assert_eq!(sent(&r.transcript).len(), 2);
    // Nobody at address 9: four attempts, then a transport error.
    let e = bus.read_position(a(9)).unwrap_err();
    assert!(matches!(e, Error::Timeout { address: 9, attempts: 4, .. }), "{e}");
    assert!(e.is_transport());
}

#[test]
fn a_relative_move_whose_reply_is_lost_is_not_sent_again() {
    let (r, mut bus) = rig(&[1], 0, 9600);
    let _me = r.clock.reserve_participant().enter();
    r.clock.sleep(Duration::from_millis(1));
    // The reply to S2 (read before the move) passes; the reply to POSR ("\r\n>") is lost.
    let before = r.faults.bytes_sent(Direction::DeviceToHost);
    r.faults.inject(Direction::DeviceToHost, before + 14, motionlink_link::pipe::Fault::Drop);
    r.faults.inject(Direction::DeviceToHost, before + 15, motionlink_link::pipe::Fault::Drop);
    r.faults.inject(Direction::DeviceToHost, before + 16, motionlink_link::pipe::Fault::Drop);
    bus.move_relative(a(1), pos(10.0), MoveOptions::default()).unwrap();
    let posr: Vec<_> = sent(&r.transcript).into_iter().filter(|f| f.starts_with(b"1POSR")).collect();
    assert_eq!(posr.len(), 1, "POSR sent exactly once");
    bus.wait_reached(&[a(1)], None, &mut |_, _| {}).unwrap();
    assert_eq!(bus.read_position(a(1)).unwrap(), pos(10.0), "moved once, not twice");
}

#[test]
fn a_relative_move_that_never_arrived_is_sent_again_after_checking() {
    let (r, mut bus) = rig(&[1], 0, 9600);
    let _me = r.clock.reserve_participant().enter();
    r.clock.sleep(Duration::from_millis(1));
    // The S2 read passes ("1S2\r", 4 bytes); the POSR telegram itself is lost on the way to the drive.
    let at = r.faults.bytes_sent(Direction::HostToDevice);
    for i in 0..9 {
        r.faults.inject(Direction::HostToDevice, at + 4 + i, motionlink_link::pipe::Fault::Drop);
    }
    bus.move_relative(a(1), pos(5.0), MoveOptions::default()).unwrap();
    let posr = sent(&r.transcript).into_iter().filter(|f| f.starts_with(b"1POSR")).count();
    assert_eq!(posr, 2, "checked S2, found the move not taken, sent it again");
    bus.wait_reached(&[a(1)], None, &mut |_, _| {}).unwrap();
    assert_eq!(bus.read_position(a(1)).unwrap(), pos(5.0));
}

#[test]
fn synchronous_start_of_two_drives_by_one_broadcast() {
    let (r, mut bus) = rig(&[1, 5], 0, 19_200);
    let _me = r.clock.reserve_participant().enter();
    bus.sync_start(&[(a(1), Command::PosA(pos(20.0))), (a(5), Command::PosR(pos(-20.0)))], false).unwrap();
    let frames = sent(&r.transcript);
    assert_eq!(frames.last().unwrap(), b"32!\r");
    assert_eq!(frames[0], b"1POSA 20,\r");
    assert_eq!(frames[1], b"5POSR -20,\r");
    // Both started at the same instant: their positions are equal in magnitude at any time.
    r.clock.sleep(Duration::from_millis(50));
    let (p1, p5) = r.host.with_device(|d| (d.drive(1).unwrap().position(), d.drive(5).unwrap().position()));
    assert!(p1 > 0.0 && (p1 + p5).abs() < 1e-9, "{p1} {p5}");
    bus.wait_reached(&[a(1), a(5)], None, &mut |_, _| {}).unwrap();
    assert_eq!(bus.read_position(a(5)).unwrap(), pos(-20.0));
}

#[test]
fn position_message_with_address_prefix_ends_the_wait_without_polling() {
    let (r, mut bus) = rig(&[3, 12], 64 + 8, 9600);
    let _me = r.clock.reserve_participant().enter();
    bus.sync_start(&[(a(3), Command::PosA(pos(5.0))), (a(12), Command::PosA(pos(8.0)))], true).unwrap();
    bus.wait_reached(&[a(3), a(12)], None, &mut |_, _| panic!("no polling needed")).unwrap();
    let got = r.transcript.bytes(Way::Received);
    let s = String::from_utf8_lossy(&got);
    assert!(s.contains("3$\r\n>") && s.contains("12$\r\n>"), "{s:?}");
    assert_eq!(r.host.with_device(|d| d.drive(12).unwrap().position()), 8.0);
}

#[test]
fn binary_moves_end_to_end_in_process() {
    let (r, mut bus) = rig(&[7], 8, 9600);
    let _me = r.clock.reserve_participant().enter();
    let bin = MoveOptions { binary: true, message: false };
    bus.set_speed(a(7), SpeedPercent::new(25.0).unwrap(), true).unwrap();
    bus.set_accel(a(7), RampMs::new(100).unwrap(), true).unwrap();
    bus.move_absolute(a(7), pos(-12.5), bin).unwrap();
    bus.wait_reached(&[a(7)], None, &mut |_, _| {}).unwrap();
    bus.move_relative(a(7), pos(2.25), bin).unwrap();
    bus.wait_reached(&[a(7)], None, &mut |_, _| {}).unwrap();
    assert_eq!(bus.read_position(a(7)).unwrap(), pos(-10.25));
    bus.set_output(a(7), 9, OutputState::ON, true).unwrap();
    assert_eq!(r.host.with_device(|d| d.drive(7).unwrap().output(9)), Some(1));
    assert_eq!(r.host.with_device(|d| d.drive(7).unwrap().move_settings()), (25.0, 100, 100));
    let frames = sent(&r.transcript);
    assert!(frames.iter().any(|f| f[..3] == [b'7', 0x88, 0x41]), "binary POSA sent");
    assert!(matches!(
        bus.move_absolute(a(7), pos(1.0), MoveOptions { binary: true, message: true }),
        Err(Error::Wire(_))
    ));
}

#[test]
fn dropping_the_client_stops_the_axis_it_moved() {
    let (r, mut bus) = rig(&[1, 2], 0, 9600);
    let _me = r.clock.reserve_participant().enter();
    bus.move_absolute(a(1), pos(1000.0), MoveOptions::default()).unwrap();
    // Drive 2 was moved by someone else: not ours to stop.
    use motionlink_link::link::Link;
    let (mut other, _) = r.host.connect();
    drop(bus);
    assert!(!r.host.with_device(|d| d.drive(1).unwrap().is_moving()));
    assert_eq!(r.host.with_device(|d| d.drive(1).unwrap().o0()), 0);
    let sent_cmds = sent(&r.transcript);
    assert_eq!(sent_cmds.last().unwrap(), b"1OUTPUT O0=0\r");
    other.send(b"2S1\r").unwrap();
}

#[test]
fn a_finished_move_is_not_stopped_on_drop() {
    let (r, mut bus) = rig(&[1], 0, 9600);
    let _me = r.clock.reserve_participant().enter();
    bus.move_absolute(a(1), pos(1.0), MoveOptions::default()).unwrap();
    r.clock.sleep(Duration::from_secs(1));
    drop(bus);
    assert_eq!(r.host.with_device(|d| d.drive(1).unwrap().o0()), 1, "still switched on");
    assert!(!sent(&r.transcript).iter().any(|f| f.starts_with(b"1OUTPUT")));
}

#[test]
fn cancelling_a_wait_stops_the_axes() {
    let (r, mut bus) = rig(&[1, 5], 0, 9600);
    let _me = r.clock.reserve_participant().enter();
    let token = CancelToken::new();
    bus.set_cancel(token.clone());
    bus.sync_start(&[(a(1), Command::PosA(pos(500.0))), (a(5), Command::PosA(pos(500.0)))], false).unwrap();
    let mut polls = 0;
    let e = bus
        .wait_reached(&[a(1), a(5)], None, &mut |_, _| {
            polls += 1;
            if polls == 4 {
                token.cancel();
            }
        })
        .unwrap_err();
    assert!(matches!(e, Error::Cancelled), "{e}");
    let (m1, m5) = r.host.with_device(|d| (d.drive(1).unwrap().is_moving(), d.drive(5).unwrap().is_moving()));
    assert!(!m1 && !m5);
    assert!(bus.started().is_empty());
    let p = bus.read_position(a(1)).unwrap().units();
    assert!(p > 0.0 && p < 500.0, "{p}");
    // Switched on again, the drive moves again.
    token.reset();
    bus.set_output(a(1), 0, OutputState::ON, false).unwrap();
    bus.move_absolute(a(1), pos(0.0), MoveOptions::default()).unwrap();
    bus.wait_reached(&[a(1)], None, &mut |_, _| {}).unwrap();
}

#[test]
fn a_wait_that_takes_too_long_stops_the_axis() {
    let (r, mut bus) = rig(&[1], 0, 9600);
    let _me = r.clock.reserve_participant().enter();
    bus.move_absolute(a(1), pos(1000.0), MoveOptions::default()).unwrap();
    let e = bus.wait_reached(&[a(1)], Some(Duration::from_secs(2)), &mut |_, _| {}).unwrap_err();
    assert!(matches!(e, Error::MoveTimeout { address: 1, .. }), "{e}");
    assert!(!r.host.with_device(|d| d.drive(1).unwrap().is_moving()));
}

#[test]
fn a_broken_link_during_a_wait_is_a_transport_error() {
    let (r, mut bus) = rig(&[1], 0, 9600);
    let _me = r.clock.reserve_participant().enter();
    bus.move_absolute(a(1), pos(1000.0), MoveOptions::default()).unwrap();
    r.faults.disconnect();
    let e = bus.wait_reached(&[a(1)], None, &mut |_, _| {}).unwrap_err();
    assert!(matches!(e, Error::Link(_)), "{e}");
}

#[test]
fn scan_finds_the_drives_and_skips_the_deaf_one() {
    let clock = ManualClock::new_auto();
    let _me = clock.reserve_participant().enter();
    let mut cfg = SimConfig::bus(&[2, 9, 31], 0, 19_200);
    cfg.drives[1].baud_rate = Some(9600); // drive 9 listens at another baud rate: it hears only noise
    let host = EmulatorHost::new(CompaxBus::new(cfg).unwrap(), clock.shared(), PipeConfig::paced(19_200));
    let mut bus = Bus::new(Box::new(host.connect().0), clock.shared(), BusConfig::new(Mode::default(), 19_200));
    let found: Vec<u8> = bus.scan(1..=31).unwrap().into_iter().map(|(a, _)| a.get()).collect();
    assert_eq!(found, [2, 31]);
}

#[test]
fn parameters_of_the_interface_take_effect_at_power_on() {
    let (r, mut bus) = rig(&[1], 0, 9600);
    let _me = r.clock.reserve_participant().enter();
    bus.write_param(a(1), ParamId::DEVICE_ADDRESS, 6.0).unwrap();
    assert!(bus.write_param(a(1), ParamId::BAUD_RATE, 1234.0).is_err(), "refused by the client's range check");
    assert_eq!(bus.read_param(a(1), ParamId::DEVICE_ADDRESS).unwrap(), 6.0);
    assert_eq!(bus.read_position(a(1)).unwrap(), pos(0.0), "still at address 1");
    r.host.with_device(|d| d.power_cycle(Timestamp::from_millis(1)));
    assert!(matches!(bus.read_position(a(1)), Err(Error::Timeout { .. })));
    assert_eq!(bus.read_position(a(6)).unwrap(), pos(0.0));
}

#[test]
fn refused_commands_are_device_errors_and_raw_is_sent_once() {
    let (r, mut bus) = rig(&[1], 0, 9600);
    let _me = r.clock.reserve_participant().enter();
    let e = bus.raw(a(1), "FOO").unwrap_err();
    assert_eq!(e.device_code(), Some(REFUSED));
    assert_eq!(bus.raw(a(1), "S2").unwrap().as_deref(), Some("S002: 0.000"));
    assert_eq!(bus.raw(a(1), "SPEED 10/").unwrap(), None);
    r.clock.sleep(Duration::from_millis(20)); // the telegram is still on the wire
    assert_eq!(r.host.with_device(|d| d.drive(1).unwrap().move_settings().0), 10.0);
    // A raw command whose reply is lost is reported, not repeated.
    r.faults.drop_next(Direction::DeviceToHost, 3);
    assert!(matches!(bus.raw(a(1), "POSR 1"), Err(Error::Timeout { attempts: 1, .. })));
    assert_eq!(sent(&r.transcript).iter().filter(|f| f.starts_with(b"1POSR")).count(), 1);
}

#[test]
fn xoff_from_the_host_holds_the_drives_reply() {
    let (r, _bus) = rig(&[1], 1, 9600);
    let _me = r.clock.reserve_participant().enter();
    use motionlink_link::link::Link;
    let (mut l, _) = r.host.connect();
    l.send(b"\x131S1\r").unwrap();
    let mut buf = [0u8; 32];
    assert_eq!(l.recv(&mut buf, Duration::from_millis(100)).unwrap(), 0, "held while XOFF");
    l.send(b"\x11").unwrap();
    let mut got = Vec::new();
    while !got.ends_with(b">") {
        let n = l.recv(&mut buf, Duration::from_millis(100)).unwrap();
        assert!(n > 0);
        got.extend_from_slice(&buf[..n]);
    }
    assert_eq!(got, b"S001: 0.000\r\n>");
}
