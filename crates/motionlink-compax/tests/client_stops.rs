//! The client against the bus emulator, in-process, with the auto-advancing manual clock: what it stops
//! (on drop, on a cancel, on a failed wait) and what it leaves alone, comparators, scans, refusals.

use std::time::Duration;

use motionlink_compax::client::{Client, Config, Error, MoveOptions, StopOutcome};
use motionlink_compax::model::{
    Command, ErrorCode, OutputState, ParamId, S16Flag, S17Flag, SpeedPercent, StatusId, StatusValue,
};
use motionlink_compax::sim::{Emulator, SimConfig, REFUSED};
use motionlink_compax::wire::{Address, Mode};
use motionlink_link::cancel::CancelToken;
use motionlink_link::chunk;
use motionlink_link::clock::{Clock, ManualClock, Timestamp};
use motionlink_link::pipe::{Direction, EmulatorHost, PipeConfig};

use crate::support;

use support::*;

const D1: motionlink_compax::wire::Address = motionlink_compax::wire::Address::drive_const(1);

#[test]
fn dropping_the_client_stops_the_axis_it_moved() {
    let (r, bus) = rig(&[1, 2], 0, 9600);
    let _me = r.clock.reserve_participant().enter();
    bus.move_absolute(a(1), pos(1000.0), MoveOptions::default()).unwrap();
    // Drive 2 is moved by someone else: not ours to stop.
    assert_eq!(someone_else_sends(&r, b"2POSA 1000\r"), b"\r\n>");
    assert!(r.host.with_device(|d| d.drive(2).unwrap().is_moving()));
    drop(bus);
    assert!(!r.host.with_device(|d| d.drive(1).unwrap().is_moving()));
    assert_eq!(r.host.with_device(|d| d.drive(1).unwrap().o0()), 0);
    let sent_cmds = sent(&r.transcript);
    // The stop, then S17 to confirm it.
    assert_eq!(sent_cmds[sent_cmds.len() - 2], b"1OUTPUT O0=0\r");
    assert_eq!(sent_cmds.last().unwrap(), b"1S17\r");
    assert!(!sent_cmds.iter().any(|f| f.starts_with(b"2")), "nothing sent to drive 2: {sent_cmds:?}");
    let (moving, o0) = r.host.with_device(|d| (d.drive(2).unwrap().is_moving(), d.drive(2).unwrap().o0()));
    assert!(moving && o0 == 1, "drive 2 still runs its own move");
}

#[test]
fn a_released_move_keeps_running_when_the_client_is_dropped() {
    let (r, bus) = rig(&[1, 2], 0, 9600);
    let _me = r.clock.reserve_participant().enter();
    bus.move_absolute(a(1), pos(100.0), MoveOptions::default()).unwrap();
    bus.move_absolute(a(2), pos(100.0), MoveOptions::default()).unwrap();
    bus.release(&[a(1)]);
    assert_eq!(bus.started(), [a(2)]);
    drop(bus);
    let (m1, o1, m2) = r
        .host
        .with_device(|d| (d.drive(1).unwrap().is_moving(), d.drive(1).unwrap().o0(), d.drive(2).unwrap().is_moving()));
    assert!(m1 && o1 == 1, "the released axis was left alone");
    assert!(!m2, "the other was stopped");
    assert!(!sent(&r.transcript).iter().any(|f| f.starts_with(b"1OUTPUT")));
    r.clock.sleep(Duration::from_secs(2));
    assert_eq!(r.host.with_device(|d| d.drive(1).unwrap().position()), 100.0);
}

#[test]
fn moves_sent_raw_or_by_broadcast_are_stopped_on_drop() {
    // A raw POSA.
    let (r, bus) = rig(&[1, 5], 0, 9600);
    let _me = r.clock.reserve_participant().enter();
    assert_eq!(bus.raw(a(1), "POSA 1000").unwrap().as_deref(), Some(""));
    assert!(bus.started().contains(&a(1)), "{:?}", bus.started());
    drop(bus);
    assert!(!r.host.with_device(|d| d.drive(1).unwrap().is_moving()));
    // The stop, then S17 to confirm it.
    assert_eq!(sent(&r.transcript).iter().rev().take(2).collect::<Vec<_>>(), [b"1S17\r".as_slice(), b"1OUTPUT O0=0\r"]);
    drop(_me);

    // A buffered move run by "!", with no reply ("/").
    let (r, bus) = rig(&[1, 5], 0, 9600);
    let _me = r.clock.reserve_participant().enter();
    bus.raw(a(5), "PR 500,").unwrap();
    assert!(bus.started().is_empty(), "stored, not run");
    assert_eq!(bus.raw(a(5), "!/").unwrap(), None);
    assert_eq!(bus.started(), [a(5)]);
    r.clock.sleep(Duration::from_millis(100));
    assert!(r.host.with_device(|d| d.drive(5).unwrap().is_moving()));
    drop(bus);
    assert!(!r.host.with_device(|d| d.drive(5).unwrap().is_moving()));
    drop(_me);

    // A broadcast move: every drive that has answered this client counts as started.
    let (r, bus) = rig(&[1, 5, 7], 0, 9600);
    let _me = r.clock.reserve_participant().enter();
    bus.read_position(a(1)).unwrap();
    bus.read_position(a(5)).unwrap();
    assert_eq!(bus.known(), [a(1), a(5)]);
    bus.broadcast(&Command::PosR(pos(800.0))).unwrap();
    assert_eq!(bus.started(), [a(1), a(5)]);
    r.clock.sleep(Duration::from_millis(100));
    drop(bus);
    let moving: Vec<bool> = r.host.with_device(|d| [1, 5, 7].map(|n| d.drive(n).unwrap().is_moving()).to_vec());
    assert_eq!(moving, [false, false, true], "drive 7 never answered this client: it cannot know it");
    drop(_me);

    // The same through raw to address 32.
    let (r, bus) = rig(&[1, 5], 0, 9600);
    let _me = r.clock.reserve_participant().enter();
    bus.read_position(a(5)).unwrap();
    assert_eq!(bus.raw(Address::BROADCAST, "POSA 900").unwrap(), None);
    assert_eq!(bus.started(), [a(5)]);
    drop(bus);
    assert!(!r.host.with_device(|d| d.drive(5).unwrap().is_moving()));
}

#[test]
fn a_refused_move_does_not_forget_the_move_that_runs() {
    let (r, bus) = rig(&[1], 0, 9600);
    let _me = r.clock.reserve_participant().enter();
    bus.move_absolute(a(1), pos(1000.0), MoveOptions::default()).unwrap();
    let e = bus.move_absolute(a(1), pos(5.0), MoveOptions::default()).unwrap_err();
    assert_eq!(e.device_code(), Some(ErrorCode::COMMAND_ACTIVE));
    assert_eq!(bus.raw(a(1), "POSR 1").unwrap_err().device_code(), Some(ErrorCode::COMMAND_ACTIVE));
    assert_eq!(bus.started(), [a(1)], "still moving from the first move");
    drop(bus);
    assert!(!r.host.with_device(|d| d.drive(1).unwrap().is_moving()));
}

#[test]
fn the_broadcast_address_is_refused_where_an_answer_is_needed_and_outputs_reach_every_drive() {
    let (r, bus) = rig(&[1, 5], 0, 9600);
    let _me = r.clock.reserve_participant().enter();
    let all = Address::BROADCAST;
    for e in [
        bus.read_status(all, StatusId::ACTUAL_POSITION).unwrap_err(),
        bus.read_param(all, ParamId::DEVICE_ADDRESS).unwrap_err(),
        bus.echo(all, "S1").unwrap_err(),
        bus.command(all, &Command::ReadStatus(StatusId::STATUS_BITS_1)).unwrap_err(),
        bus.move_absolute(all, pos(10.0), MoveOptions::default()).unwrap_err(),
        bus.wait_reached(&[a(1), all], None, &mut |_, _| {}).unwrap_err(),
    ] {
        assert!(matches!(e, Error::Broadcast(_)), "{e}");
        assert!(e.to_string().contains("none answers"), "{e}");
    }
    assert!(sent(&r.transcript).is_empty(), "nothing was sent: {:?}", sent(&r.transcript));
    // Outputs and settings go to every drive; O0=0 switches every one off and ends every started move.
    bus.move_absolute(a(1), pos(1000.0), MoveOptions::default()).unwrap();
    bus.move_absolute(a(5), pos(1000.0), MoveOptions::default()).unwrap();
    bus.set_output(all, 3, OutputState::ON, false).unwrap();
    bus.set_output(all, 0, OutputState::OFF, false).unwrap();
    assert!(bus.started().is_empty());
    r.clock.sleep(Duration::from_millis(50));
    let (o3, moving) = r.host.with_device(|d| {
        ([1, 5].map(|n| d.drive(n).unwrap().output(3)), [1, 5].map(|n| d.drive(n).unwrap().is_moving()))
    });
    assert_eq!(o3, [Some(1), Some(1)]);
    assert_eq!(moving, [false, false]);
}

#[test]
fn a_drive_handle_is_one_drive() {
    let (r, bus) = rig(&[4], 8, 9600);
    let _me = r.clock.reserve_participant().enter();
    assert!(matches!(bus.drive(Address::BROADCAST), Err(Error::Broadcast(_))));
    let four = bus.drive(a(4)).unwrap();
    assert_eq!(four.address(), a(4));
    four.set_speed(SpeedPercent::new(50.0).unwrap(), true).unwrap();
    four.write_param(ParamId::new(20).unwrap(), 2.5).unwrap();
    assert_eq!(four.read_param(ParamId::new(20).unwrap()).unwrap(), 2.5);
    four.move_relative(pos(5.0), MoveOptions::default()).unwrap();
    let mut seen = Vec::new();
    four.wait_reached(None, &mut |p| seen.push(p.units())).unwrap();
    assert!(!seen.is_empty());
    assert_eq!(four.read_position().unwrap(), pos(5.0));
    assert!(four.read_s16().unwrap().contains(S16Flag::PositionReached));
    assert_eq!(four.raw("S2").unwrap().as_deref(), Some("S002: 5.000"));
    four.move_absolute(pos(500.0), MoveOptions::default()).unwrap();
    four.stop().unwrap();
    assert!(four.client().started().is_empty());
    assert_eq!(r.host.with_device(|d| d.drive(4).unwrap().o0()), 0);
}

#[test]
fn an_e71_is_reported_not_sent_again_unchanged() {
    let (r, bus) = rig(&[1], 0, 9600);
    let _me = r.clock.reserve_participant().enter();
    // The CR of the first telegram is damaged: the drive waits on, the client times out and sends the (20
    // character) telegram again; to the drive both are one command of 42 characters: E71.
    let p12 = ParamId::new(12).unwrap();
    let at = r.faults().bytes_sent(Direction::HostToDevice);
    r.faults().inject(Direction::HostToDevice, at + 21, motionlink_link::pipe::Fault::Corrupt { xor: 0x55 });
    let e = bus.write_param(a(1), p12, -8_388_607.999_999).unwrap_err();
    assert_eq!(e.device_code(), Some(ErrorCode::BUFFER_OVERFLOW), "{e}");
    let frames = sent(&r.transcript);
    assert_eq!(frames.len(), 2, "sent, timed out, sent again, E71, and not a third time: {frames:?}");
    assert_eq!(frames[0], b"1P012=-8388607.999999\r");
    assert_eq!(frames[0], frames[1]);
    assert!(r.transcript.bytes(chunk::Direction::FromDevice).starts_with(b"E71\r\n>"));
    // E70 / E72 / E73 still are (see the tests above); and the next telegram is fine.
    bus.write_param(a(1), p12, 1.0).unwrap();
}

#[test]
fn a_lost_position_message_does_not_hang_the_wait() {
    for (p196, fault) in [(0, "dropped"), (8, "bad BCC"), (0, "garbled")] {
        let (r, bus) = rig(&[1], p196, 9600);
        let _me = r.clock.reserve_participant().enter();
        // 20 units at 100 units/s: 200 ms.
        bus.move_absolute(a(1), pos(20.0), MoveOptions { binary: false, message: true }).unwrap();
        // The next bytes the drive sends are its "$ CR LF > [BCC]".
        let at = r.faults().bytes_sent(Direction::DeviceToHost);
        match fault {
            "dropped" => r.faults().drop_next(Direction::DeviceToHost, 4),
            "bad BCC" => {
                r.faults().inject(Direction::DeviceToHost, at + 4, motionlink_link::pipe::Fault::Corrupt { xor: 1 })
            }
            _ => r.faults().inject(Direction::DeviceToHost, at, motionlink_link::pipe::Fault::Corrupt { xor: 0x40 }),
        }
        let t0 = r.clock.now();
        bus.wait_reached(&[a(1)], Some(Duration::from_secs(60)), &mut |_, _| {}).unwrap();
        let took = (r.clock.now() - t0).as_secs_f64();
        assert!(took < 1.5, "P196={p196} {fault}: found by the state check after about a second, took {took} s");
        let received = String::from_utf8_lossy(&r.transcript.bytes(chunk::Direction::FromDevice)).into_owned();
        assert_eq!(received.contains("$\r"), fault == "bad BCC", "{fault}: {received:?}");
        assert_eq!(bus.read_position(a(1)).unwrap(), pos(20.0));
        assert!(bus.started().is_empty());
    }
}

#[test]
fn a_wait_for_a_message_ends_when_someone_else_stops_the_axis() {
    let (r, bus) = rig(&[1], 0, 9600);
    let _me = r.clock.reserve_participant().enter();
    bus.move_absolute(a(1), pos(1000.0), MoveOptions { binary: false, message: true }).unwrap();
    r.clock.sleep(Duration::from_millis(300));
    // Switched off by another program: the positioning ends where it is, and no "$" will come.
    assert_eq!(someone_else_sends(&r, b"1OUTPUT O0=0\r"), b"\r\n>");
    let t0 = r.clock.now();
    bus.wait_reached(&[a(1)], Some(Duration::from_secs(60)), &mut |_, _| {}).unwrap();
    assert!((r.clock.now() - t0) < Duration::from_millis(1500));
    let p = bus.read_position(a(1)).unwrap().units();
    assert!(p > 20.0 && p < 1000.0, "{p}");
}

#[test]
fn a_wait_without_a_timeout_ends_after_the_default_one() {
    let clock = ManualClock::new_auto();
    let _me = clock.reserve_participant().enter();
    let host = EmulatorHost::new(
        Emulator::new(SimConfig::bus(&[1], 0, 9600)).unwrap(),
        clock.shared(),
        PipeConfig::paced(9600),
    );
    let mut cfg = Config::new(Mode::default(), 9600);
    assert_eq!(cfg.wait_timeout, Duration::from_secs(600));
    cfg.wait_timeout = Duration::from_secs(3);
    let bus = Client::with_link(Box::new(host.connect().0), clock.shared(), cfg).unwrap();
    // 1000 units at 100 units/s: 10 s.
    bus.move_absolute(a(1), pos(1000.0), MoveOptions::default()).unwrap();
    let t0 = clock.now();
    let e = bus.wait_reached(&[a(1)], None, &mut |_, _| {}).unwrap_err();
    assert!(matches!(e.root(), Error::MoveTimeout { address: D1, .. }), "{e}");
    let took = clock.now() - t0;
    assert!(took >= Duration::from_secs(3) && took < Duration::from_secs(4), "{took:?}");
    assert!(!host.with_device(|d| d.drive(1).unwrap().is_moving()), "stopped");
}

#[test]
fn comparator_numbers_are_expected_only_until_the_positioning_ends() {
    let clock = ManualClock::new_auto();
    let _me = clock.reserve_participant().enter();
    let mut polls = 0;
    let answer = move |t: &[u8]| -> Vec<u8> {
        match t {
            b"1POSR 5 OUTPUT O9=1\r" | b"1POSA 10\r" => b"\r\n>".to_vec(),
            b"1S17\r" => {
                polls += 1;
                match polls {
                    // The comparator switches during the first poll: its number comes first.
                    1 => b"1\r\n>S017: 0010 0010\r\n>".to_vec(),
                    2 => b"S017: 0010 0010\r\n>".to_vec(),
                    _ => b"S017: 0000 0010\r\n>".to_vec(),
                }
            }
            b"1S1\r" => b"S001: 10.000\r\n>".to_vec(),
            // A drive that answers a parameter with the bare value.
            b"1P194\r" => b"1\r\n>".to_vec(),
            other => panic!("unexpected telegram {other:?}"),
        }
    };
    let link = Scripted { clock: clock.shared(), answer: Box::new(answer), pending: Default::default() };
    let bus = Client::with_link(Box::new(link), clock.shared(), Config::new(Mode::default(), 9600)).unwrap();
    let comparator = Command::PosROutput { distance: pos(5.0), output: 9, state: OutputState::ON };
    assert_eq!(bus.command(a(1), &comparator).unwrap(), "");
    bus.move_absolute(a(1), pos(10.0), MoveOptions::default()).unwrap();
    let mut positions = Vec::new();
    bus.wait_reached(&[a(1)], None, &mut |_, p| positions.push(p.units())).unwrap();
    assert_eq!(positions, [10.0; 3], "three polls; the comparator's number was taken for what it is, not as a reply");
    // The positioning has ended, and with it the comparator: a bare number is a reply again.
    assert_eq!(bus.read_param(a(1), ParamId::DEVICE_ADDRESS).unwrap(), 1.0);
}

#[test]
fn a_finished_move_is_not_stopped_on_drop() {
    let (r, bus) = rig(&[1], 0, 9600);
    let _me = r.clock.reserve_participant().enter();
    bus.move_absolute(a(1), pos(1.0), MoveOptions::default()).unwrap();
    r.clock.sleep(Duration::from_secs(1));
    drop(bus);
    assert_eq!(r.host.with_device(|d| d.drive(1).unwrap().o0()), 1, "still switched on");
    assert!(!sent(&r.transcript).iter().any(|f| f.starts_with(b"1OUTPUT")));
}

#[test]
fn cancelling_a_wait_stops_the_axes() {
    let (r, bus) = rig(&[1, 5], 0, 9600);
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
    assert!(matches!(e, Error::Cancelled { .. }), "{e}");
    let stop = e.stop_report().expect("the wait stopped the axes");
    assert_eq!(stop.switched_off(), [a(1), a(5)], "{e}");
    assert!(stop.all_confirmed());
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
    let (r, bus) = rig(&[1], 0, 9600);
    let _me = r.clock.reserve_participant().enter();
    bus.move_absolute(a(1), pos(1000.0), MoveOptions::default()).unwrap();
    let e = bus.wait_reached(&[a(1)], Some(Duration::from_secs(2)), &mut |_, _| {}).unwrap_err();
    assert!(matches!(e.root(), Error::MoveTimeout { address: D1, .. }), "{e}");
    assert_eq!(e.stop_report().unwrap().switched_off(), [a(1)], "{e}");
    assert!(!r.host.with_device(|d| d.drive(1).unwrap().is_moving()));
}

#[test]
fn a_broken_link_during_a_wait_is_a_transport_error() {
    let (r, bus) = rig(&[1], 0, 9600);
    let _me = r.clock.reserve_participant().enter();
    bus.move_absolute(a(1), pos(1000.0), MoveOptions::default()).unwrap();
    r.faults().disconnect();
    let e = bus.wait_reached(&[a(1)], None, &mut |_, _| {}).unwrap_err();
    assert!(matches!(e.root(), Error::Link(_)), "{e}");
    assert!(e.is_transport());
    // The stop cannot go out on a broken link: the error says so, in words.
    let stop = e.stop_report().expect("a stop was tried");
    assert_eq!(stop.unconfirmed(), [a(1)]);
    assert!(e.to_string().contains("the axis may still be moving"), "{e}");
    assert!(r.host.with_device(|d| d.drive(1).unwrap().is_moving()), "and indeed it moves on");
    bus.release(&[a(1)]);
}

#[test]
fn scan_finds_the_drives_and_skips_the_deaf_one() {
    let clock = ManualClock::new_auto();
    let _me = clock.reserve_participant().enter();
    let mut cfg = SimConfig::bus(&[2, 9, 31], 0, 19_200);
    cfg.drives[1].baud_rate = Some(9600); // drive 9 listens at another baud rate: it hears only noise
    let host = EmulatorHost::new(Emulator::new(cfg).unwrap(), clock.shared(), PipeConfig::paced(19_200));
    let bus =
        Client::with_link(Box::new(host.connect().0), clock.shared(), Config::new(Mode::default(), 19_200)).unwrap();
    let found: Vec<u8> = bus.scan(1..=31).unwrap().into_iter().map(|(a, _)| a.get()).collect();
    assert_eq!(found, [2, 31]);
}

#[test]
fn parameters_of_the_interface_take_effect_at_power_on() {
    let (r, bus) = rig(&[1], 0, 9600);
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
    let (r, bus) = rig(&[1], 0, 9600);
    let _me = r.clock.reserve_participant().enter();
    let e = bus.raw(a(1), "FOO").unwrap_err();
    assert_eq!(e.device_code(), Some(REFUSED));
    assert_eq!(bus.raw(a(1), "S2").unwrap().as_deref(), Some("S002: 0.000"));
    assert_eq!(bus.raw(a(1), "SPEED 10/").unwrap(), None);
    r.clock.sleep(Duration::from_millis(20)); // the telegram is still on the wire
    assert_eq!(r.host.with_device(|d| d.drive(1).unwrap().move_settings().0), 10.0);
    // A raw command whose reply is lost is reported, not repeated.
    r.faults().drop_next(Direction::DeviceToHost, 3);
    assert!(matches!(bus.raw(a(1), "POSR 1"), Err(Error::Timeout { attempts: 1, .. })));
    assert_eq!(sent(&r.transcript).iter().filter(|f| f.starts_with(b"1POSR")).count(), 1);
    // The drive may have taken it: the client counts it as moving until it has seen otherwise.
    assert_eq!(bus.started(), [a(1)]);
    r.clock.sleep(Duration::from_secs(1));
    drop(bus); // (while this thread still drives the clock)
    assert_eq!(r.host.with_device(|d| d.drive(1).unwrap().position()), 1.0);
    // Checked on drop: S17 shows no command, and (its S17 never seen to show a positioning) S1 holds still
    // over a poll interval: it had stopped, so no OUTPUT O0=0.
    let frames = sent(&r.transcript);
    let n = frames.len();
    assert_eq!(frames[n - 3..], [b"1S17\r".to_vec(), b"1S1\r".to_vec(), b"1S1\r".to_vec()], "{frames:?}");
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

#[test]
fn bare_values_answering_a_read_are_replies_while_a_comparator_is_armed() {
    let clock = ManualClock::new_auto();
    let _me = clock.reserve_participant().enter();
    let answer = move |t: &[u8]| -> Vec<u8> {
        match t {
            b"1POSR 5 OUTPUT O9=1\r" | b"1POSA 10\r" => b"\r\n>".to_vec(),
            // A drive that answers reads with the bare value.
            b"1S6\r" => b"35\r\n>".to_vec(),
            b"1P194\r" => b"5\r\n>".to_vec(),
            // The comparator switches while a setting is sent: its number comes before the acknowledgement,
            // and a setting is never answered with a number.
            b"1SPEED 50\r" => b"1\r\n>\r\n>".to_vec(),
            // S17 cannot be "2": the comparator's number, then the reply.
            b"1S17\r" => b"2\r\n>S017: 0010 0010\r\n>".to_vec(),
            other => panic!("unexpected telegram {other:?}"),
        }
    };
    let link = Scripted { clock: clock.shared(), answer: Box::new(answer), pending: Default::default() };
    let bus = Client::with_link(Box::new(link), clock.shared(), Config::new(Mode::default(), 9600)).unwrap();
    let comparator = Command::PosROutput { distance: pos(5.0), output: 9, state: OutputState::ON };
    assert_eq!(bus.command(a(1), &comparator).unwrap(), "");
    bus.move_absolute(a(1), pos(10.0), MoveOptions::default()).unwrap();
    // The comparator is armed and the positioning runs: the bare values are still the reads' replies.
    assert_eq!(bus.read_status(a(1), StatusId::TEMPERATURE).unwrap(), StatusValue::Number(35.0));
    assert_eq!(bus.read_param(a(1), ParamId::DEVICE_ADDRESS).unwrap(), 5.0);
    bus.set_speed(a(1), SpeedPercent::new(50.0).unwrap(), false).unwrap();
    assert!(bus.read_s17(a(1)).unwrap().contains(S17Flag::CommandActive));
    bus.release(&[a(1)]);
}

#[test]
fn a_failed_synchronous_store_names_the_drives_left_with_a_buffered_move() {
    let clock = ManualClock::new_auto();
    let _me = clock.reserve_participant().enter();
    let sent_frames = std::sync::Arc::new(std::sync::Mutex::new(Vec::<Vec<u8>>::new()));
    let log = sent_frames.clone();
    let answer = move |t: &[u8]| -> Vec<u8> {
        log.lock().unwrap().push(t.to_vec());
        match t {
            b"1POSA 100,\r" | b"1OUTPUT O0=0\r" => b"\r\n>".to_vec(),
            // Drive 5 refuses to store its move.
            b"5POSA 100,\r" => b"E90\r\n>".to_vec(),
            b"32!\r" => Vec::new(),
            // Drive 1 runs the move the later `32!` started.
            b"1S17\r" => b"S017: 0010 0010\r\n>".to_vec(),
            // Drive 5 has nothing buffered: it does not move (S17 shows no command, S1 holds still).
            b"5S17\r" => b"S017: 0000 0010\r\n>".to_vec(),
            b"5S1\r" => b"S001: 0.000\r\n>".to_vec(),
            other => panic!("unexpected telegram {other:?}"),
        }
    };
    let link = Scripted { clock: clock.shared(), answer: Box::new(answer), pending: Default::default() };
    let bus = Client::with_link(Box::new(link), clock.shared(), Config::new(Mode::default(), 9600)).unwrap();
    let e = bus.sync_start(&[(a(1), Command::PosA(pos(100.0))), (a(5), Command::PosA(pos(100.0)))], false).unwrap_err();
    match &e {
        Error::SyncIncomplete { failed, source, buffered } => {
            assert_eq!(*failed, 5);
            assert_eq!(source.device_code(), Some(ErrorCode(90)));
            assert_eq!(buffered, &[1]);
        }
        other => panic!("{other}"),
    }
    assert!(e.to_string().contains("a buffered move is still held by drive 1:"), "{e}");
    assert!(!sent_frames.lock().unwrap().iter().any(|f| f == b"32!\r"), "no '!' after a failed store");
    assert!(bus.started().is_empty(), "nothing runs yet");
    // The `!` this client sends later starts drive 1's buffered move: dropping the client stops it.
    assert_eq!(bus.raw(Address::BROADCAST, "!").unwrap(), None);
    assert!(bus.started().contains(&a(1)), "{:?}", bus.started());
    drop(bus);
    let frames = sent_frames.lock().unwrap();
    assert!(frames.iter().any(|f| f == b"1OUTPUT O0=0\r"), "drive 1 stopped on drop");
    assert!(!frames.iter().any(|f| f == b"5OUTPUT O0=0\r"), "drive 5 does not move");
}

#[test]
fn a_synchronous_start_is_refused_while_a_drive_outside_it_holds_a_buffered_move() {
    let clock = ManualClock::new_auto();
    let _me = clock.reserve_participant().enter();
    let sent_frames = std::sync::Arc::new(std::sync::Mutex::new(Vec::<Vec<u8>>::new()));
    let log = sent_frames.clone();
    let refuse_five = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(true));
    let refusing = refuse_five.clone();
    let answer = move |t: &[u8]| -> Vec<u8> {
        log.lock().unwrap().push(t.to_vec());
        match t {
            b"1POSA 100,\r" | b"1POSA 7,\r" | b"3POSA 9,\r" | b"1OUTPUT O0=0\r" | b"3OUTPUT O0=0\r" => {
                b"\r\n>".to_vec()
            }
            // Drive 5 refuses to store its first move.
            b"5POSA 100,\r" if refusing.load(std::sync::atomic::Ordering::SeqCst) => b"E90\r\n>".to_vec(),
            b"5POSA 100,\r" => b"\r\n>".to_vec(),
            b"32!\r" => Vec::new(),
            b"1S17\r" | b"3S17\r" | b"5S17\r" => b"S017: 0000 0010\r\n>".to_vec(),
            // At rest: S1 holds still (a stop reads it twice where S17 has not shown a positioning yet).
            b"1S1\r" | b"3S1\r" | b"5S1\r" => b"S001: 0.000\r\n>".to_vec(),
            other => panic!("unexpected telegram {other:?}"),
        }
    };
    let link = Scripted { clock: clock.shared(), answer: Box::new(answer), pending: Default::default() };
    let bus = Client::with_link(Box::new(link), clock.shared(), Config::new(Mode::default(), 9600)).unwrap();
    let both = [(a(1), Command::PosA(pos(100.0))), (a(5), Command::PosA(pos(100.0)))];
    assert!(matches!(bus.sync_start(&both, false), Err(Error::SyncIncomplete { .. })));
    // Drive 1 holds POSA 100 in its buffer: a start of drives 3 and 5 alone would run it too.
    let count = sent_frames.lock().unwrap().len();
    let others = [(a(3), Command::PosA(pos(9.0))), (a(5), Command::PosA(pos(100.0)))];
    let e = bus.sync_start(&others, false).unwrap_err();
    assert!(matches!(&e, Error::BufferHeld { held } if held == &[1]), "{e:?}");
    assert_eq!(motionlink_link::error::Classify::class(&e), motionlink_link::error::ErrorClass::Usage);
    let text = e.to_string();
    assert!(text.contains("buffer of drive 1") && text.contains("nothing was sent"), "{text}");
    assert_eq!(sent_frames.lock().unwrap().len(), count, "nothing sent: {:?}", &sent_frames.lock().unwrap()[count..]);
    assert!(bus.started().is_empty());
    // A start that stores a new move for drive 1 replaces what its buffer held: it goes out.
    refuse_five.store(false, std::sync::atomic::Ordering::SeqCst);
    let all = [(a(1), Command::PosA(pos(7.0))), (a(3), Command::PosA(pos(9.0))), (a(5), Command::PosA(pos(100.0)))];
    bus.sync_start(&all, false).unwrap();
    let frames = sent_frames.lock().unwrap()[count..].to_vec();
    assert_eq!(frames, [b"1POSA 7,\r".to_vec(), b"3POSA 9,\r".to_vec(), b"5POSA 100,\r".to_vec(), b"32!\r".to_vec()]);
    assert_eq!(bus.started(), [a(1), a(3), a(5)]);
}

#[test]
fn stop_confirmed_is_the_command_s_stop_with_where_the_axis_stands_and_whether_it_is_on() {
    let (r, bus) = rig(&[1, 5], 0, 9600);
    let _me = r.clock.reserve_participant().enter();
    // At rest: S17 read, nothing switched off; S1 and S16 read after it.
    let rest = bus.stop_confirmed(a(1)).unwrap();
    assert_eq!(rest.report.drives, [(a(1), StopOutcome::AtRest)]);
    assert_eq!((rest.position_units, rest.o0), (Some(pos(0.0)), Some(1)));
    assert!(!sent(&r.transcript).iter().any(|f| f.starts_with(b"1OUTPUT")));
    // Moving: OUTPUT O0=0, confirmed by S17; where it came to rest, and that it is switched off.
    bus.move_absolute(a(5), pos(1000.0), MoveOptions::default()).unwrap();
    r.clock.sleep(Duration::from_millis(300));
    let stop = bus.stop_confirmed(a(5)).unwrap();
    assert_eq!(stop.report.drives, [(a(5), StopOutcome::SwitchedOff)]);
    let at = stop.position_units.unwrap().units();
    assert!(at > 0.0 && at < 1000.0, "{stop:?}");
    assert_eq!(stop.o0, Some(0));
    assert!(stop.position_not_read.is_none() && stop.o0_not_read.is_none());
    let json = serde_json::to_value(motionlink_compax::report::StopResult::new(None::<()>, stop)).unwrap();
    assert_eq!(
        (json["action"].as_str(), json["o0"].as_u64(), json["confirmed"].as_bool()),
        (Some("stop"), Some(0), Some(true))
    );
    assert!(bus.started().is_empty());
}

#[test]
fn stop_started_switches_off_only_the_axes_that_still_move() {
    let (r, bus) = rig(&[1, 5], 0, 9600);
    let _me = r.clock.reserve_participant().enter();
    bus.move_absolute(a(1), pos(1.0), MoveOptions::default()).unwrap();
    bus.move_absolute(a(5), pos(1000.0), MoveOptions::default()).unwrap();
    r.clock.sleep(Duration::from_secs(1));
    let report = bus.stop_started();
    assert_eq!(report.drives, [(a(1), StopOutcome::AtRest), (a(5), StopOutcome::SwitchedOff)]);
    assert!(report.all_confirmed());
    assert_eq!(report.switched_off(), [a(5)]);
    let text = report.to_string();
    assert!(text.contains("drive 1 was already at rest"), "{text}");
    assert!(text.contains("drive 5 was stopped by switching it off") && text.contains("OUTPUT O0=1"), "{text}");
    let frames = sent(&r.transcript);
    assert!(frames.iter().any(|f| f == b"1S17\r") && frames.iter().any(|f| f == b"5S17\r"), "S17 read first");
    assert_eq!(frames.last().unwrap(), b"5S17\r", "the stop confirmed by S17 afterwards: {frames:?}");
    assert!(!frames.iter().any(|f| f.starts_with(b"1OUTPUT")), "drive 1 is at rest: not switched off");
    assert!(frames.iter().any(|f| f == b"5OUTPUT O0=0\r"), "drive 5 still moves: switched off");
    assert_eq!(r.host.with_device(|d| (d.drive(1).unwrap().o0(), d.drive(5).unwrap().o0())), (1, 0));
    assert!(bus.started().is_empty());
}

#[test]
fn stop_started_sends_the_stop_when_s17_cannot_be_read() {
    let clock = ManualClock::new_auto();
    let _me = clock.reserve_participant().enter();
    let sent_frames = std::sync::Arc::new(std::sync::Mutex::new(Vec::<Vec<u8>>::new()));
    let log = sent_frames.clone();
    let answer = move |t: &[u8]| -> Vec<u8> {
        log.lock().unwrap().push(t.to_vec());
        match t {
            b"1POSA 10\r" | b"1OUTPUT O0=0\r" => b"\r\n>".to_vec(),
            // The status read is lost.
            b"1S17\r" => Vec::new(),
            other => panic!("unexpected telegram {other:?}"),
        }
    };
    let link = Scripted { clock: clock.shared(), answer: Box::new(answer), pending: Default::default() };
    let bus = Client::with_link(Box::new(link), clock.shared(), Config::new(Mode::default(), 9600)).unwrap();
    bus.move_absolute(a(1), pos(10.0), MoveOptions::default()).unwrap();
    let report = bus.stop_started();
    let frames = sent_frames.lock().unwrap().clone();
    let stop_at = frames.iter().position(|f| f == b"1OUTPUT O0=0\r").expect("stopped anyway");
    assert_eq!(frames[..stop_at].iter().filter(|f| *f == b"1S17\r").count(), 1, "one attempt first: {frames:?}");
    // The acknowledged stop cannot be confirmed (S17 still unreadable): the report says so in words, and the
    // client keeps the drive on its list (dropping it tries again).
    assert!(!report.all_confirmed());
    assert_eq!(report.unconfirmed(), [a(1)]);
    let text = report.to_string();
    assert!(text.contains("NOT confirmed") && text.contains("may still be moving"), "{text}");
    assert_eq!(bus.started(), [a(1)]);
    bus.release(&[a(1)]);
}
