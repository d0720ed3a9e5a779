//! A checked ASCII move is checked before it starts: stored in the drive's buffer with its echo (`,?`,
//! RS485 manual 4.1 / 4.2), the echo compared byte for byte with the telegram sent, and executed (`!`)
//! only when they match. Every flipped bit of the stored move and of its echo, a flipped address digit,
//! a lost echo, a lost reply to `!`. In-process, on the manual clock, with the emulator's events telling
//! which motions started.

use std::time::Duration;

use motionlink_compax::client::{Client, Error, MoveRequest, MoveTarget, StopOutcome};
use motionlink_compax::model::{Command, Position};
use motionlink_compax::sim::SimConfig;
use motionlink_compax::wire::{bcc, Address};
use motionlink_link::chunk;
use motionlink_link::clock::Clock;
use motionlink_link::emulator::Emulator as _;
use motionlink_link::pipe::{Direction, Fault};

use crate::support::{rig_on, Rig};

const D1: motionlink_compax::wire::Address = motionlink_compax::wire::Address::drive_const(1);

fn rig(addrs: &[u8], p196: u32) -> (Rig, Client) {
    rig_on(SimConfig::bus(addrs, p196, 9600), p196, 9600, |_| {})
}

fn a(n: u8) -> Address {
    Address::drive(n).unwrap()
}

fn pos(v: f64) -> Position {
    Position::new(v).unwrap()
}

fn sent(r: &Rig) -> Vec<String> {
    let records = r.transcript.records();
    records
        .into_iter()
        .filter(|r| r.direction == chunk::Direction::ToDevice)
        .map(|r| String::from_utf8_lossy(&r.bytes).into_owned())
        .collect()
}

fn executes(r: &Rig) -> usize {
    sent(r).iter().filter(|f| f.starts_with("1!\r")).count()
}

/// The emulator's "motion started" events since the last call.
fn motions(r: &Rig) -> Vec<String> {
    r.host.with_device(|d| d.take_events()).into_iter().filter(|e| e.contains("motion started")).collect()
}

/// (position, moving, O0, buffer) of drive `n`.
fn state(r: &Rig, n: u8) -> (f64, bool, u8, Option<String>) {
    r.host.with_device(|d| {
        let d = d.drive(n).unwrap();
        (d.position(), d.is_moving(), d.o0(), d.buffered().map(str::to_string))
    })
}

/// Bytes of the telegrams before the stored move of a checked move without settings: "1S16\r" "1S17\r"
/// "1S1\r" (each with a BCC in mode 8), for a relative move "1S2\r", then the probe of the echo form
/// "1S1?\r".
fn before_store(p196: u32, relative: bool) -> u64 {
    let with_bcc = u64::from(p196 & 8 != 0);
    5 + 5 + 4 + with_bcc * 3 + if relative { 4 + with_bcc } else { 0 } + 5 + with_bcc
}

/// Bytes the drive sends back before the echo of the stored move of a checked move without settings (S16,
/// S17, S1 and for a relative move S2, with P196's line ends and prefixes), and with `then` (raw commands
/// sent after them) those replies too: measured on a bus of its own.
fn replies_before(p196: u32, relative: bool, then: &[&str]) -> u64 {
    let (r, bus) = rig(&[1, 3], p196);
    let _me = r.clock.reserve_participant().enter();
    bus.read_s16(a(1)).unwrap();
    bus.read_s17(a(1)).unwrap();
    bus.read_position(a(1)).unwrap();
    if relative {
        bus.read_target(a(1)).unwrap();
    }
    // The probe of how the drive echoes.
    bus.echo(a(1), "S1").unwrap();
    for t in then {
        bus.raw(a(1), t).unwrap();
    }
    r.faults().bytes_sent(Direction::DeviceToHost)
}

#[test]
fn the_move_is_stored_with_its_echo_then_executed_in_every_reply_format() {
    for p196 in [0, 8, 32, 64, 72, 104] {
        let (r, bus) = rig(&[1, 3], p196);
        let _me = r.clock.reserve_participant().enter();
        bus.move_to(a(1), &MoveRequest::new(MoveTarget::Absolute(pos(12.5))), &mut |_| {}).unwrap();
        let frames = sent(&r);
        let mut store = b"1POSA 12.5,?\r".to_vec();
        let mut exec = b"1!\r".to_vec();
        if p196 & 8 != 0 {
            store.push(bcc(b"1POSA 12.5,?"));
            exec.push(bcc(b"1!"));
        }
        let (store, exec) = (String::from_utf8(store).unwrap(), String::from_utf8(exec).unwrap());
        let at = frames.iter().position(|f| *f == store).unwrap_or_else(|| panic!("P196={p196}: {frames:?}"));
        assert_eq!(frames[at + 1], exec, "P196={p196}: '!' right after the echo");
        assert!(frames[at + 2].starts_with("1S2\r"), "P196={p196}: then the target read back: {frames:?}");
        assert_eq!(frames.iter().filter(|f| f.contains("POSA")).count(), 1, "P196={p196}: {frames:?}");
        // The drive sent the telegram back in full (after its address prefix, when P196 has 64).
        let back = String::from_utf8_lossy(&r.transcript.bytes(chunk::Direction::FromDevice)).into_owned();
        let echo = if p196 & 64 != 0 { "11POSA 12.5,?\r" } else { "1POSA 12.5,?\r" };
        assert!(back.contains(echo), "P196={p196}: {back:?}");
        assert_eq!(motions(&r), ["drive 1 motion started to 12.500 from 0.000"], "P196={p196}");
        assert_eq!(state(&r, 1), (12.5, false, 1, None), "P196={p196}: '!' emptied the buffer");
    }
    // A relative move likewise.
    let (r, bus) = rig(&[1], 0);
    let _me = r.clock.reserve_participant().enter();
    bus.move_to(a(1), &MoveRequest::new(MoveTarget::Relative(pos(-2.5))), &mut |_| {}).unwrap();
    assert_eq!(sent(&r)[3..7], ["1S2\r", "1S1?\r", "1POSR -2.5,?\r", "1!\r"]);
    assert_eq!(state(&r, 1).0, -2.5);
}

/// One checked move of drive 1 (drives 1 and 3 on the bus, mode `p196`) with one bit flipped at `offset`
/// bytes `dir`; checks that no motion started other than the one asked for, that an error left every axis
/// where it was with no '!' sent after a bad echo, and returns the error if there was one.
fn flipped(p196: u32, relative: bool, dir: Direction, offset: u64, bit: u8) -> Option<Error> {
    let (r, bus) = rig(&[1, 3], p196);
    let _me = r.clock.reserve_participant().enter();
    r.faults().inject(dir, offset, Fault::Corrupt { xor: 1 << bit });
    let (target, request) = if relative {
        (-2.5, MoveRequest::new(MoveTarget::Relative(pos(-2.5))))
    } else {
        (12.5, MoveRequest::new(MoveTarget::Absolute(pos(12.5))))
    };
    let mut request = request;
    request.timeout = Some(Duration::from_secs(5));
    let result = bus.move_to(a(1), &request, &mut |_| {});
    let what =
        format!("P196={p196} relative={relative} {dir:?} byte {offset} bit {bit}: {result:?}; sent {:?}", sent(&r));
    let started = motions(&r);
    assert!(
        started.iter().all(|m| m.starts_with(&format!("drive 1 motion started to {target:.3} from 0.000"))),
        "{what}: {started:?}"
    );
    assert!(started.len() <= 1, "{what}: {started:?}");
    assert!(!state(&r, 1).1 && !state(&r, 3).1, "{what}");
    match result {
        Ok(report) => {
            assert_eq!(report.reached, pos(target), "{what}");
            assert_eq!(executes(&r), 1, "{what}");
            None
        }
        Err(e) => {
            if let Error::NotExecuted { buffered, .. } = e.root() {
                // The drive never moved, and nothing told it to.
                assert!(started.is_empty(), "{what}");
                assert_eq!(executes(&r), 0, "{what}: no '!' after a bad echo");
                assert!(buffered.contains(&1), "{what}");
                let text = e.to_string();
                assert!(
                    text.contains("may still be held, as received, in the buffer of drive") && text.contains("'32!'"),
                    "{what}: {text}"
                );
                // The stop found the axis at rest: nothing to switch off. Unless no echo came (a relative
                // move is not stored again): the drive may still be reading what the flip made of the
                // telegram (a binary length byte swallows what follows), its S17 unreadable, and it is
                // switched off to be sure.
                let stop = e.stop_report().unwrap().drives.clone();
                let unanswered =
                    matches!(e.root(), Error::NotExecuted { source, .. } if matches!(**source, Error::Timeout { .. }));
                if relative && unanswered {
                    assert!(
                        matches!(stop[..], [(D1, StopOutcome::AtRest | StopOutcome::SwitchedOff)]),
                        "{what}: {stop:?}"
                    );
                } else {
                    assert_eq!(stop, [(a(1), StopOutcome::AtRest)], "{what}");
                }
                assert_eq!(state(&r, 1).0, 0.0, "{what}");
            }
            Some(e)
        }
    }
}

#[test]
fn no_flipped_bit_of_the_stored_move_is_ever_executed() {
    // Every bit of the stored move's telegram, without and with BCC, absolute and relative.
    for (p196, relative) in [(0, false), (0, true), (8, false), (72, true)] {
        let start = before_store(p196, relative);
        let len = (if relative { "1POSR -2.5,?\r" } else { "1POSA 12.5,?\r" }).len() as u64 + u64::from(p196 & 8 != 0);
        let (mut done, mut refused) = (0, 0);
        for offset in start..start + len {
            for bit in 0..8 {
                match flipped(p196, relative, Direction::HostToDevice, offset, bit) {
                    None => done += 1,
                    Some(_) => refused += 1,
                }
            }
        }
        eprintln!("P196={p196} relative={relative}: {done} done after a store again, {refused} refused");
        // In mode 0 a flipped digit is a valid telegram that only the echo catches.
        assert!(refused > 0 || p196 & 8 != 0, "P196={p196}: no flip was refused");
        // A flip nobody answers (the CR, the address) is stored again: an absolute move; or answered E72 with
        // a BCC (the drive did not store it). A relative move whose echo is lost is not stored again.
        assert!(done > 0 || (relative && p196 & 8 == 0), "P196={p196}: no flip was stored again");
    }
}

#[test]
fn no_flipped_bit_of_the_echo_ever_executes_the_move() {
    for (p196, relative) in [(0, false), (0, true), (8, false), (64, false)] {
        let start = replies_before(p196, relative, &[]);
        let store = if relative { "POSR -2.5,?" } else { "POSA 12.5,?" };
        let len = replies_before(p196, relative, &[store]) - start;
        // The echo's text (address prefix, telegram), then its line end (and BCC).
        let end = if p196 & 32 != 0 { 1 } else { 3 } + u64::from(p196 & 8 != 0);
        let mut refused = 0;
        for offset in start..start + len {
            for bit in 0..8 {
                let e = flipped(p196, relative, Direction::DeviceToHost, offset, bit);
                if offset < start + len - end {
                    // The echo is not the telegram sent (or not readable): never executed.
                    assert!(
                        matches!(e.as_ref().map(Error::root), Some(Error::NotExecuted { .. })),
                        "P196={p196} relative={relative} echo byte {} bit {bit}: {e:?}",
                        offset - start
                    );
                }
                refused += usize::from(e.is_some());
            }
        }
        eprintln!("P196={p196} relative={relative}: {refused} of {} flips of the echo refused", len * 8);
    }
}

#[test]
fn a_flipped_address_digit_makes_another_drive_echo_and_nothing_moves() {
    for p196 in [0, 64] {
        // "1POSA 12.5,?\r": '1' (0x31) with bit 1 flipped is '3': drive 3 stores the move and echoes it.
        let (r, bus) = rig(&[1, 3], p196);
        let _me = r.clock.reserve_participant().enter();
        r.faults().inject(Direction::HostToDevice, before_store(p196, false), Fault::Corrupt { xor: 0x02 });
        let e = bus.move_to(a(1), &MoveRequest::new(MoveTarget::Absolute(pos(12.5))), &mut |_| {}).unwrap_err();
        let Error::NotExecuted { address: D1, command, buffered, source, .. } = e.root() else { panic!("{e}") };
        assert_eq!((command.as_str(), buffered.as_slice()), ("POSA 12.5", &[1u8, 3][..]), "P196={p196}");
        let Error::UnexpectedReply { reply, .. } = source.as_ref() else { panic!("{source}") };
        let want = if p196 & 64 != 0 { "3:3POSA 12.5,?" } else { "3POSA 12.5,?" };
        assert_eq!(reply, want, "P196={p196}: the error names what came back");
        let text = e.to_string();
        assert!(text.contains("no '!' was sent") && text.contains("in the buffer of drives 1, 3:"), "{text}");
        assert_eq!(executes(&r), 0);
        assert!(!sent(&r).iter().any(|f| f.contains('!')), "P196={p196}: {:?}", sent(&r));
        assert!(motions(&r).is_empty(), "P196={p196}: nothing moved");
        // Drive 3 holds the move, as the error says: the next '3!' or '32!' would start it.
        assert_eq!(state(&r, 3), (0.0, false, 1, Some("POSA 12.5".into())), "P196={p196}");
        assert_eq!(state(&r, 1), (0.0, false, 1, None), "P196={p196}");
    }
    // No drive at the flipped address: no echo, the move is stored again at drive 1 and runs once.
    let (r, bus) = rig(&[1], 0);
    let _me = r.clock.reserve_participant().enter();
    r.faults().inject(Direction::HostToDevice, before_store(0, false), Fault::Corrupt { xor: 0x02 });
    bus.move_to(a(1), &MoveRequest::new(MoveTarget::Absolute(pos(12.5))), &mut |_| {}).unwrap();
    // (The transcript shows the telegram as the client sent it, before the flip.)
    assert_eq!(sent(&r)[4..7], ["1POSA 12.5,?\r", "1POSA 12.5,?\r", "1!\r"]);
    assert_eq!(motions(&r), ["drive 1 motion started to 12.500 from 0.000"]);
}

#[test]
fn a_lost_echo_of_a_relative_move_is_not_stored_again_and_nothing_runs() {
    // The replies to S16, S17, S1 and S2 pass; the echo of the store is lost.
    let at = replies_before(0, true, &[]);
    let (r, bus) = rig(&[1], 0);
    let _me = r.clock.reserve_participant().enter();
    for i in 0.."1POSR 5,?\r\n>".len() as u64 {
        r.faults().inject(Direction::DeviceToHost, at + i, Fault::Drop);
    }
    let e = bus.move_to(a(1), &MoveRequest::new(MoveTarget::Relative(pos(5.0))), &mut |_| {}).unwrap_err();
    assert!(e.is_transport(), "{e}");
    let Error::NotExecuted { command, why, buffered, source, .. } = e.root() else { panic!("{e}") };
    assert_eq!((command.as_str(), buffered.as_slice()), ("POSR 5", &[1u8][..]));
    assert!(why.contains("no echo came back") && why.contains("a relative move is not stored again"), "{why}");
    assert!(matches!(**source, Error::Timeout { attempts: 1, .. }), "{source}");
    let frames = sent(&r);
    assert_eq!(frames.iter().filter(|f| f.contains("POSR")).count(), 1, "stored once: {frames:?}");
    assert_eq!(executes(&r), 0, "{frames:?}");
    assert!(motions(&r).is_empty());
    // The drive holds it (the store arrived), as the error says; the next checked move's store replaces it
    // (the buffer holds one command), and that move alone runs.
    assert_eq!(state(&r, 1), (0.0, false, 1, Some("POSR 5".into())));
    let report = bus.move_to(a(1), &MoveRequest::new(MoveTarget::Absolute(pos(20.0))), &mut |_| {}).unwrap();
    assert!(report.verified && report.reached == pos(20.0), "{report:?}");
    assert_eq!(motions(&r), ["drive 1 motion started to 20.000 from 0.000"]);
}

#[test]
fn a_lost_reply_to_execute_is_checked_through_s2_and_s17_not_sent_again_blindly() {
    // The reply to '!' ("\r\n>") is lost, the move ran: S2 shows its target; '!' is not sent again.
    let at = replies_before(0, true, &["POSR 5,?"]);
    let (r, bus) = rig(&[1], 0);
    let _me = r.clock.reserve_participant().enter();
    for i in 0..3 {
        r.faults().inject(Direction::DeviceToHost, at + i, Fault::Drop);
    }
    bus.move_to(a(1), &MoveRequest::new(MoveTarget::Relative(pos(5.0))), &mut |_| {}).unwrap();
    let frames = sent(&r);
    assert_eq!(frames[6..9], ["1!\r", "1S2\r", "1S2\r"], "S2 read after the lost reply, then the read-back");
    assert_eq!(executes(&r), 1, "{frames:?}");
    assert_eq!(state(&r, 1).0, 5.0, "moved once");

    // The '!' itself is lost on its way ("1!\r" dropped): S2 unchanged and S17 at rest say it did not
    // start, and only then is '!' sent again.
    let (r, bus) = rig(&[1], 0);
    let _me = r.clock.reserve_participant().enter();
    let at = r.faults().bytes_sent(Direction::HostToDevice) + 5 + 5 + 4 + 4 + 5 + "1POSR 5,?\r".len() as u64;
    for i in 0..3 {
        r.faults().inject(Direction::HostToDevice, at + i, Fault::Drop);
    }
    bus.move_to(a(1), &MoveRequest::new(MoveTarget::Relative(pos(5.0))), &mut |_| {}).unwrap();
    let frames = sent(&r);
    assert_eq!(frames[6..10], ["1!\r", "1S2\r", "1S17\r", "1!\r"], "{frames:?}");
    assert_eq!(motions(&r), ["drive 1 motion started to 5.000 from 0.000"]);
    assert_eq!(state(&r, 1).0, 5.0, "moved once");
}

/// Drive 1 (and 3) whose buffer is a queue (`buffer-queues`): each store appends, `!` runs the oldest.
fn queueing(addrs: &[u8]) -> (Rig, Client) {
    let mut cfg = SimConfig::bus(addrs, 0, 9600);
    cfg.variants = vec![motionlink_compax::sim::Variant::BufferQueues];
    rig_on(cfg, 0, 9600, |_| {})
}

fn queue(r: &Rig, n: u8) -> Vec<String> {
    r.host.with_device(|d| d.drive(n).unwrap().buffered_all().into_iter().map(str::to_string).collect())
}

#[test]
fn a_drive_whose_buffer_queues_commands_never_runs_a_relative_move_twice() {
    let relative = |d: f64| MoveRequest::new(MoveTarget::Relative(pos(d)));
    let absolute = |p: f64| MoveRequest::new(MoveTarget::Absolute(pos(p)));

    // The reply to '!' is lost: S2 shows the move started; '!' is not sent again, and nothing is left held.
    let at = replies_before(0, true, &["POSR 5,?"]);
    let (r, bus) = queueing(&[1]);
    let _me = r.clock.reserve_participant().enter();
    for i in 0..3 {
        r.faults().inject(Direction::DeviceToHost, at + i, Fault::Drop);
    }
    assert_eq!(bus.move_to(a(1), &relative(5.0), &mut |_| {}).unwrap().reached, pos(5.0));
    assert_eq!((executes(&r), motions(&r).len(), queue(&r, 1).len()), (1, 1, 0));

    // The echo of a relative move is lost: it is not stored again, so the drive holds one copy, not two.
    let at = replies_before(0, true, &[]);
    let (r, bus) = queueing(&[1]);
    let _me = r.clock.reserve_participant().enter();
    for i in 0.."1POSR 5,?\r\n>".len() as u64 {
        r.faults().inject(Direction::DeviceToHost, at + i, Fault::Drop);
    }
    let e = bus.move_to(a(1), &relative(5.0), &mut |_| {}).unwrap_err();
    assert!(matches!(e.root(), Error::NotExecuted { buffered, .. } if buffered == &[1]), "{e}");
    assert_eq!(queue(&r, 1), ["POSR 5"]);
    assert!(motions(&r).is_empty());
    // As the error says, the next '!' to the drive runs what it holds: here the '!' of the next checked
    // move, which runs the held POSR (once) instead of the new move; S2 shows it and the axis is stopped.
    let e = bus.move_to(a(1), &absolute(20.0), &mut |_| {}).unwrap_err();
    let Error::TargetMismatch { requested, taken, .. } = e.root() else { panic!("{e}") };
    assert_eq!((*requested, *taken), (pos(20.0), pos(5.0)), "{e}");
    assert_eq!(motions(&r), ["drive 1 motion started to 5.000 from 0.000"], "the relative move ran once");
    assert!(state(&r, 1).0 <= 5.0 && !state(&r, 1).1);
    assert_eq!(queue(&r, 1), ["POSA 20"]);

    // The echo of an absolute move is lost: stored again, it runs once; the drive holds the other copy,
    // which the next '!' runs to the same target (S2 then shows it, and the axis does not move).
    let at = replies_before(0, false, &[]);
    let (r, bus) = queueing(&[1]);
    let _me = r.clock.reserve_participant().enter();
    for i in 0.."1POSA 12.5,?\r\n>".len() as u64 {
        r.faults().inject(Direction::DeviceToHost, at + i, Fault::Drop);
    }
    let report = bus.move_to(a(1), &absolute(12.5), &mut |_| {}).unwrap();
    assert_eq!(report.reached, pos(12.5));
    assert_eq!(sent(&r).iter().filter(|f| f.contains("POSA 12.5")).count(), 2);
    assert_eq!((executes(&r), queue(&r, 1)), (1, vec!["POSA 12.5".to_string()]));
    let e = bus.move_to(a(1), &absolute(20.0), &mut |_| {}).unwrap_err();
    assert!(matches!(e.root(), Error::TargetMismatch { taken, .. } if *taken == pos(12.5)), "{e}");
    assert_eq!(state(&r, 1).0, 12.5);

    // A synchronous start whose store of a relative move goes unanswered: not stored again, no '32!'.
    let (r, bus) = queueing(&[1, 3]);
    let _me = r.clock.reserve_participant().enter();
    for i in 0..3 {
        r.faults().inject(Direction::DeviceToHost, i, Fault::Drop);
    }
    let moves = [(a(1), Command::PosR(pos(5.0))), (a(3), Command::PosA(pos(7.0)))];
    let e = bus.sync_start(&moves, false).unwrap_err();
    assert!(matches!(&e, Error::SyncIncomplete { failed: 1, buffered, .. } if buffered == &[1]), "{e}");
    assert_eq!(sent(&r), ["1POSR 5,\r"], "stored once, nothing executed");
    assert_eq!(queue(&r, 1), ["POSR 5"]);
    assert!(motions(&r).is_empty());
}
