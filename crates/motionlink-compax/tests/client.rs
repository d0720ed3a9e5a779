//! The client against the bus emulator, in-process, with the auto-advancing manual clock: reads, writes,
//! resends, moves, the position message.

use std::time::Duration;

use motionlink_compax::client::{Client, Config, Error, MoveOptions};
use motionlink_compax::model::{
    Command, ErrorCode, OutputState, ParamId, RampMs, S16Flag, S17Flag, SpeedPercent, StatusId, StatusValue,
};
use motionlink_compax::sim::{Emulator, SimConfig};
use motionlink_compax::wire::Mode;
use motionlink_link::cancel::CancelToken;
use motionlink_link::chunk;
use motionlink_link::clock::{Clock, ManualClock};
use motionlink_link::pipe::{Direction, EmulatorHost, PipeConfig};
use motionlink_link::transcript::{TapLink, Transcript};

use crate::support;

use support::*;

const D9: motionlink_compax::wire::Address = motionlink_compax::wire::Address::drive_const(9);

#[test]
fn every_p196_combination_reads_writes_and_moves() {
    for p196 in 0..=Mode::MAX_P196 {
        let (r, bus) = rig(&[1, 5], p196, 38_400);
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
    let (r, bus) = rig(&[1], 0, 9600);
    let _me = r.clock.reserve_participant().enter();
    bus.set_speed(a(1), SpeedPercent::new(50.0).unwrap(), false).unwrap();
    bus.set_accel(a(1), RampMs::new(500).unwrap(), false).unwrap();
    let t0 = r.clock.now();
    bus.move_absolute(a(1), pos(100.0), MoveOptions::default()).unwrap();
    let s17 = bus.read_s17(a(1)).unwrap();
    assert!(s17.contains(S17Flag::CommandActive) && s17.contains(S17Flag::Run));
    assert_eq!(bus.read_target(a(1)).unwrap(), pos(100.0));
    let mut seen = Vec::new();
    bus.wait_reached(&[a(1)], None, &mut |_, p| seen.push(p.units())).unwrap();
    // 50 units/s cruise, 200 units/s² ramps: 0.25 s up, 0.25 s down, 1.75 s cruise: about 2.25 s.
    let took = (r.clock.now() - t0).as_secs_f64();
    assert!((2.2..2.45).contains(&took), "took {took} s");
    assert!(seen.windows(2).all(|w| w[0] <= w[1]), "positions rise monotonically: {seen:?}");
    assert!(seen.len() > 10, "{seen:?}");
    let s16 = bus.read_s16(a(1)).unwrap();
    assert!(s16.contains(S16Flag::PositionReached) && s16.contains(S16Flag::ReadyForStart));
    assert_eq!(bus.read_status(a(1), StatusId::MOTION_CYCLES).unwrap(), StatusValue::Number(1.0));
}

#[test]
fn e92_for_a_move_while_moving() {
    let (r, bus) = rig(&[1], 0, 9600);
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
    let (r, bus) = rig(&[1], 8, 9600);
    let _me = r.clock.reserve_participant().enter();
    // Flip a bit of the command letter (the second byte): the drive's BCC check fails.
    let at = r.faults().bytes_sent(Direction::HostToDevice);
    r.faults().inject(Direction::HostToDevice, at + 1, motionlink_link::pipe::Fault::Corrupt { xor: 0x01 });
    assert_eq!(bus.read_position(a(1)).unwrap(), pos(0.0));
    let frames = sent(&r.transcript);
    assert_eq!(frames.len(), 2, "sent once, refused with E72, sent again: {frames:?}");
    assert_eq!(frames[0], frames[1]);
    let got = r.transcript.bytes(chunk::Direction::FromDevice);
    assert!(got.starts_with(b"E72\r\n>"), "{got:?}");
}

#[test]
fn a_gap_inside_a_telegram_gives_e73_and_a_resend() {
    let (r, bus) = rig(&[2], 16, 9600);
    let _me = r.clock.reserve_participant().enter();
    let at = r.faults().bytes_sent(Direction::HostToDevice);
    // Five character times at 9600 baud are 5.2 ms: hold the third byte back 10 ms.
    r.faults().inject(Direction::HostToDevice, at + 2, motionlink_link::pipe::Fault::Delay(Duration::from_millis(10)));
    bus.write_param(a(2), ParamId::new(10).unwrap(), 7.0).unwrap();
    assert!(r.transcript.bytes(chunk::Direction::FromDevice).starts_with(b"E73\r\n>"));
    // Sent, E73, sent again; then read back.
    assert_eq!(sent(&r.transcript), [b"2P010=7\r".to_vec(), b"2P010=7\r".to_vec(), b"2P010\r".to_vec()]);
    assert_eq!(bus.read_param(a(2), ParamId::new(10).unwrap()).unwrap(), 7.0);
}

#[test]
fn a_parity_error_gives_e70_and_a_resend() {
    let (r, bus) = rig(&[4], 2 + 4, 9600);
    let _me = r.clock.reserve_participant().enter();
    r.host.with_device(|d| d.inject_parity_error());
    assert_eq!(bus.read_position(a(4)).unwrap(), pos(0.0));
    assert!(r.transcript.bytes(chunk::Direction::FromDevice).starts_with(b"E70\r\n>"));
    assert_eq!(sent(&r.transcript).len(), 2);
}

#[test]
fn overflow_is_refused_before_sending_and_e71_is_a_device_error() {
    let (r, bus) = rig(&[1], 0, 9600);
    let _me = r.clock.reserve_participant().enter();
    let long = format!("P1={}", "1".repeat(40));
    assert!(matches!(bus.raw(a(1), &long), Err(Error::Encode(_))));
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
    let (r, bus) = rig(&[1], 0, 9600);
    let _me = r.clock.reserve_participant().enter();
    // The first reply is lost: the read is sent again.
    r.faults().drop_next(Direction::DeviceToHost, 14);
    assert_eq!(bus.read_position(a(1)).unwrap(), pos(0.0));
    assert_eq!(sent(&r.transcript).len(), 2);
    // Nobody at address 9: four attempts, then a transport error.
    let e = bus.read_position(a(9)).unwrap_err();
    assert!(matches!(e, Error::Timeout { address: D9, attempts: 4, .. }), "{e}");
    assert!(e.is_transport());
}

#[test]
fn a_relative_move_whose_reply_is_lost_is_not_sent_again() {
    let (r, bus) = rig(&[1], 0, 9600);
    let _me = r.clock.reserve_participant().enter();
    r.clock.sleep(Duration::from_millis(1));
    // The reply to S2 (read before the move) passes; the reply to POSR ("\r\n>") is lost.
    let before = r.faults().bytes_sent(Direction::DeviceToHost);
    r.faults().inject(Direction::DeviceToHost, before + 14, motionlink_link::pipe::Fault::Drop);
    r.faults().inject(Direction::DeviceToHost, before + 15, motionlink_link::pipe::Fault::Drop);
    r.faults().inject(Direction::DeviceToHost, before + 16, motionlink_link::pipe::Fault::Drop);
    bus.move_relative(a(1), pos(10.0), MoveOptions::default()).unwrap();
    let posr: Vec<_> = sent(&r.transcript).into_iter().filter(|f| f.starts_with(b"1POSR")).collect();
    assert_eq!(posr.len(), 1, "POSR sent exactly once");
    bus.wait_reached(&[a(1)], None, &mut |_, _| {}).unwrap();
    assert_eq!(bus.read_position(a(1)).unwrap(), pos(10.0), "moved once, not twice");
}

#[test]
fn a_relative_move_too_small_for_s2_to_show_is_not_sent_again_when_its_reply_is_lost() {
    let (r, bus) = rig(&[1], 0, 9600);
    let _me = r.clock.reserve_participant().enter();
    r.clock.sleep(Duration::from_millis(1));
    // As above, the reply to POSR 0.001 is lost: S2 (three decimals) reads alike whether it was taken or not.
    let before = r.faults().bytes_sent(Direction::DeviceToHost);
    for i in 14..17 {
        r.faults().inject(Direction::DeviceToHost, before + i, motionlink_link::pipe::Fault::Drop);
    }
    let e = bus.move_relative(a(1), pos(0.001), MoveOptions::default()).unwrap_err();
    assert!(matches!(e, Error::MoveUncertain { .. }), "{e}");
    let posr = sent(&r.transcript).into_iter().filter(|f| f.starts_with(b"1POSR")).count();
    assert_eq!(posr, 1, "POSR sent exactly once");
    assert_eq!(bus.started(), [a(1)], "still the session's to stop");
    r.clock.sleep(Duration::from_millis(500));
    assert_eq!(bus.read_position(a(1)).unwrap(), pos(0.001), "moved once, not twice");
    bus.close().unwrap();
}

#[test]
fn an_echo_of_a_command_that_is_not_idempotent_is_not_sent_again_when_its_reply_is_lost() {
    let (r, bus) = rig(&[1], 0, 9600);
    let _me = r.clock.reserve_participant().enter();
    r.clock.sleep(Duration::from_millis(1));
    // The manual does not say whether a drive carries out what it echoes: a relative move goes out once.
    r.faults().drop_next(Direction::DeviceToHost, 64);
    assert!(bus.echo(a(1), "POSR 10").is_err());
    let sent_of = |start: &[u8]| sent(&r.transcript).into_iter().filter(|f| f.starts_with(start)).count();
    assert_eq!(sent_of(b"1POSR"), 1, "sent once");
    // A read is sent again.
    r.clock.sleep(Duration::from_millis(500));
    r.faults().heal();
    let before = r.faults().bytes_sent(Direction::DeviceToHost);
    assert_eq!(bus.echo(a(1), "S1").unwrap(), "1S1?");
    let reply = r.faults().bytes_sent(Direction::DeviceToHost) - before;
    r.faults().drop_next(Direction::DeviceToHost, reply);
    assert_eq!(bus.echo(a(1), "S1").unwrap(), "1S1?");
    assert_eq!(sent_of(b"1S1"), 3, "sent again");
    bus.close().unwrap();
}

#[test]
fn a_relative_move_that_never_arrived_is_sent_again_after_checking() {
    let (r, bus) = rig(&[1], 0, 9600);
    let _me = r.clock.reserve_participant().enter();
    r.clock.sleep(Duration::from_millis(1));
    // The S2 read passes ("1S2\r", 4 bytes); the POSR telegram itself is lost on the way to the drive.
    let at = r.faults().bytes_sent(Direction::HostToDevice);
    for i in 0..9 {
        r.faults().inject(Direction::HostToDevice, at + 4 + i, motionlink_link::pipe::Fault::Drop);
    }
    bus.move_relative(a(1), pos(5.0), MoveOptions::default()).unwrap();
    let posr = sent(&r.transcript).into_iter().filter(|f| f.starts_with(b"1POSR")).count();
    assert_eq!(posr, 2, "checked S2, found the move not taken, sent it again");
    bus.wait_reached(&[a(1)], None, &mut |_, _| {}).unwrap();
    assert_eq!(bus.read_position(a(1)).unwrap(), pos(5.0));
}

#[test]
fn synchronous_start_of_two_drives_by_one_broadcast() {
    let (r, bus) = rig(&[1, 5], 0, 19_200);
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
    let (r, bus) = rig(&[3, 12], 64 + 8, 9600);
    let _me = r.clock.reserve_participant().enter();
    bus.sync_start(&[(a(3), Command::PosA(pos(5.0))), (a(12), Command::PosA(pos(8.0)))], true).unwrap();
    bus.wait_reached(&[a(3), a(12)], None, &mut |_, _| panic!("no polling needed")).unwrap();
    let got = r.transcript.bytes(chunk::Direction::FromDevice);
    let s = String::from_utf8_lossy(&got);
    assert!(s.contains("3$\r\n>") && s.contains("12$\r\n>"), "{s:?}");
    assert_eq!(r.host.with_device(|d| d.drive(12).unwrap().position()), 8.0);
}

#[test]
fn binary_moves_end_to_end_in_process() {
    let (r, bus) = rig(&[7], 8, 9600);
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
        Err(Error::Encode(_))
    ));
}

#[test]
fn a_cancelled_scan_ends_between_drives_and_a_cancelled_token_keeps_moves_unsent() {
    let clock = ManualClock::new_auto();
    let _me = clock.reserve_participant().enter();
    let host = EmulatorHost::new(
        Emulator::new(SimConfig::bus(&[1, 31], 0, 9600)).unwrap(),
        clock.shared(),
        PipeConfig::paced(9600),
    );
    let token = CancelToken::new();
    let transcript = Transcript::new();
    let link = TapLink::new(host.connect().0, clock.shared(), transcript.clone());
    let link = CancelAfter { inner: link, token: token.clone(), sends: 0, n: 3 };
    let bus = Client::with_link(Box::new(link), clock.shared(), Config::new(Mode::default(), 9600)).unwrap();
    bus.set_cancel(token.clone());
    // Cancelled while the third address is asked: that answer is awaited, the fourth is not asked.
    assert!(matches!(bus.scan(1..=31), Err(Error::CancelledBeforeMotion)));
    assert_eq!(sent(&transcript), [b"1S1\r".to_vec(), b"2S1\r".to_vec(), b"3S1\r".to_vec()]);
    assert!(bus.is_cancelled());
    // No move goes out while the token is cancelled, in any form.
    assert!(matches!(bus.move_absolute(a(1), pos(10.0), MoveOptions::default()), Err(Error::CancelledBeforeMotion)));
    assert!(matches!(bus.move_relative(a(1), pos(10.0), MoveOptions::default()), Err(Error::CancelledBeforeMotion)));
    assert!(matches!(bus.sync_start(&[(a(1), Command::PosA(pos(1.0)))], false), Err(Error::CancelledBeforeMotion)));
    assert!(matches!(bus.raw(a(1), "POSA 10"), Err(Error::CancelledBeforeMotion)));
    assert!(matches!(bus.broadcast(&Command::PosA(pos(1.0))), Err(Error::CancelledBeforeMotion)));
    assert_eq!(sent(&transcript).len(), 3, "{:?}", sent(&transcript));
    // Reads and stops still work; after a reset, moves too.
    assert_eq!(bus.read_position(a(1)).unwrap(), pos(0.0));
    token.reset();
    bus.move_absolute(a(1), pos(1.0), MoveOptions::default()).unwrap();
    bus.wait_reached(&[a(1)], None, &mut |_, _| {}).unwrap();
    assert!(!host.with_device(|d| d.drive(1).unwrap().is_moving()));
}
