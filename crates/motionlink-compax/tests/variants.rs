//! The core operations against every firmware variant of the emulator (`sim::Variant`), in-process on the
//! manual clock, in the reply formats that matter to them: each works (saying what it could not verify) or
//! ends with an error that says what the drive did not do; a move never ends in success away from its
//! target. Then the discrepancies that are refused whatever form was found: an echo whose command text
//! differs, an echo in another form than the one the drive was found to use, and one flipped bit anywhere
//! in the probe, which never makes a drive that echoes pass for one that does not.

use std::time::Duration;

use motionlink_compax::client::{Client, Config, EchoForm, Error, MoveOptions, MoveRequest, MoveTarget};
use motionlink_compax::model::{Command, ParamId, S17Flag, SpeedPercent, StatusId};
use motionlink_compax::sim::{Emulator, SimConfig, Variant};
use motionlink_compax::wire::Mode;
use motionlink_link::clock::{Clock, ManualClock};
use motionlink_link::emulator::Emulator as _;
use motionlink_link::pipe::{Direction, EmulatorHost, Fault, FaultControl, PipeConfig};

use crate::support::{a, pos};

fn emulated(variants: &[Variant], p196: u32) -> (ManualClock, EmulatorHost<Emulator>, FaultControl, Client) {
    emulated_with(variants, p196, Config::new(Mode::from_p196(p196).unwrap(), 9600))
}

fn emulated_with(
    variants: &[Variant],
    p196: u32,
    config: Config,
) -> (ManualClock, EmulatorHost<Emulator>, FaultControl, Client) {
    let clock = ManualClock::new_auto();
    let mut cfg = SimConfig::bus(&[1, 3], p196, 9600).with_param(ParamId::new(3).unwrap(), 0.0);
    cfg.variants = variants.to_vec();
    let host = EmulatorHost::new(Emulator::new(cfg).unwrap(), clock.shared(), PipeConfig::paced(9600));
    let (link, faults) = host.connect();
    let client = Client::with_link(Box::new(link), clock.shared(), config).unwrap();
    (clock, host, faults, client)
}

/// The reply timeout drives of the `slow-replies` variant (300 ms late) need: `--timeout-ms 600`.
fn slow_enough(p196: u32) -> Config {
    let mut config = Config::new(Mode::from_p196(p196).unwrap(), 9600);
    config.reply_timeout = Duration::from_millis(600);
    config
}

fn to(v: f64) -> MoveRequest {
    MoveRequest::new(MoveTarget::Absolute(pos(v)))
}

/// What the core operations gave against one variant: the two moves' reports (or errors).
type Moves =
    (Result<motionlink_compax::client::MoveReport, Error>, Result<motionlink_compax::client::MoveReport, Error>);

/// Scan, status, parameter write, home, a move with a speed and a relative move without one, watch, stop,
/// close.
fn core_operations(variants: &[Variant], p196: u32) -> Moves {
    // Slow drives with the reply timeout they need (with the default one nothing is answered in time).
    let (clock, host, _faults, bus) = if variants.contains(&Variant::SlowReplies) {
        emulated_with(variants, p196, slow_enough(p196))
    } else {
        emulated(variants, p196)
    };
    let _me = clock.reserve_participant().enter();
    let what = format!("{variants:?} P196={p196}");
    let found = bus.scan(1..=4).unwrap();
    assert_eq!(found.iter().map(|(d, _)| d.get()).collect::<Vec<_>>(), [1, 3], "{what}");
    bus.read_statuses(a(1), &[StatusId::ACTUAL_POSITION, StatusId::STATUS_BITS_1, StatusId::STATUS_BITS_2]).unwrap();
    bus.write_param(a(1), ParamId::new(3).unwrap(), 12.5).unwrap();
    bus.home(a(1), Default::default()).unwrap();
    bus.wait_reached(&[a(1)], Some(Duration::from_secs(5)), &mut |_, _| {}).unwrap();
    let mut with_speed = to(20.0);
    with_speed.speed = Some(SpeedPercent::new(50.0).unwrap());
    let first = bus.move_to(a(1), &with_speed, &mut |_| {});
    let second = bus.move_to(a(1), &MoveRequest::new(MoveTarget::Relative(pos(-5.0))), &mut |_| {});
    // What `watch` reads, a few times.
    for _ in 0..3 {
        bus.read_position(a(1)).unwrap();
        bus.read_s17(a(1)).unwrap();
    }
    bus.stop(a(1)).unwrap();
    let at = host.with_device(|d| d.drive(1).unwrap().position());
    for (r, target) in [(&first, 20.0), (&second, 15.0)] {
        if let Ok(report) = r {
            assert_eq!(report.reached, pos(target), "{what}: {report:?}");
        }
    }
    if second.is_ok() {
        assert_eq!(at, 15.0, "{what}");
    }
    bus.close().unwrap();
    (first, second)
}

#[test]
fn every_variant_in_every_address_mode() {
    for p196 in [0, 8, 64] {
        let prefixed = p196 & 64 != 0;
        for variants in [
            &[][..],
            &[Variant::EchoWithoutAddress],
            &[Variant::EchoBare],
            &[Variant::NoEcho],
            &[Variant::StatusValueOnly],
            &[Variant::EchoBare, Variant::StatusValueOnly],
            &[Variant::NoPositionMessage],
            &[Variant::SlowReplies],
            &[Variant::BufferQueues],
            &[Variant::NoCommandBit],
        ] {
            let what = format!("{variants:?} P196={p196}");
            let (first, second) = core_operations(variants, p196);
            let (first, second) = (first.unwrap(), second.unwrap());
            assert_eq!(first.verified, second.verified, "{what}");
            assert_eq!(first.not_verifiable, second.not_verifiable, "{what}");
            let why = first.not_verifiable.join("\n");
            let echo = variants.iter().find(|v| {
                matches!(
                    v,
                    Variant::EchoWithoutAddress | Variant::EchoBare | Variant::NoEcho | Variant::EchoWithoutStore
                )
            });
            match echo {
                // Both moves still run at their first poll: S1 moves while S17 shows no command.
                None if variants.contains(&Variant::NoCommandBit) => {
                    assert!(!first.verified && why.contains("S17 did not show the positioning"), "{what}: {why}")
                }
                None => assert!(first.verified && why.is_empty(), "{what}: {why}"),
                // The address prefix names the drive that echoed: only the missing address is then no loss.
                Some(Variant::EchoWithoutAddress) if prefixed => assert!(first.verified, "{what}: {why}"),
                Some(Variant::EchoWithoutAddress) => {
                    assert!(!first.verified && why.contains("echoes without its address"), "{what}: {why}")
                }
                Some(Variant::EchoBare) => {
                    assert!(!first.verified && why.contains("without the flag characters"), "{what}: {why}");
                    assert_eq!(why.contains("without its address"), !prefixed, "{what}: {why}");
                }
                Some(_) => assert!(!first.verified && why.contains("does not echo"), "{what}: {why}"),
            }
        }
    }
}

#[test]
fn the_form_found_is_remembered_and_a_move_is_sent_in_the_plain_form_to_a_drive_without_echo() {
    let (clock, host, _faults, bus) = emulated(&[Variant::NoEcho], 0);
    let _me = clock.reserve_participant().enter();
    let r = bus.move_to(a(1), &to(10.0), &mut |_| {}).unwrap();
    assert!(!r.verified && r.reached == pos(10.0), "{r:?}");
    assert_eq!(bus.driver().with_session(|s| s.echo_form(a(1))), Some(EchoForm::None));
    // Nothing was stored: the move went out as a command of its own.
    assert_eq!(host.with_device(|d| d.drive(1).unwrap().buffered().map(str::to_string)), None);
    let events = host.with_device(|d| d.take_events());
    assert_eq!(events.iter().filter(|e| e.contains("motion started")).count(), 1, "{events:?}");
    // Found once per session: the next move asks nothing more about the echo.
    bus.move_to(a(1), &to(11.0), &mut |_| {}).unwrap();
}

#[test]
fn an_echo_in_another_form_than_found_is_refused() {
    // Found to echo in full; then the drive drops its address from the echo: a check that never weakens
    // for a drive that gives it refuses the move, and nothing is executed.
    let (clock, host, _faults, bus) = emulated(&[], 0);
    let _me = clock.reserve_participant().enter();
    assert!(bus.move_to(a(1), &to(10.0), &mut |_| {}).unwrap().verified);
    host.with_device(|d| d.set_variants(&[Variant::EchoWithoutAddress]));
    let e = bus.move_to(a(1), &to(12.0), &mut |_| {}).unwrap_err();
    let Error::NotExecuted { why, buffered, .. } = e.root() else { panic!("{e}") };
    assert!(why.contains("expected \"1POSA 12") && why.contains("echo \"POSA 12"), "{why}");
    assert!(!why.contains("is what the drive that answered received"), "{why}");
    assert_eq!(buffered, &[1]);
    assert_eq!(host.with_device(|d| d.drive(1).unwrap().position()), 10.0, "not executed");
    // Drive 1 holds "POSA 12" in its buffer: a synchronous start of drive 3 alone (whose `32!` would run
    // it) is refused, and nothing moves.
    let e = bus.sync_start(&[(a(3), Command::PosA(pos(5.0)))], false).unwrap_err();
    assert!(matches!(&e, Error::BufferHeld { held } if held == &[1]), "{e}");
    assert_eq!(host.with_device(|d| d.drive(1).unwrap().buffered().map(str::to_string)).as_deref(), Some("POSA 12"));
    assert_eq!(host.with_device(|d| d.drive(3).unwrap().buffered().map(str::to_string)), None, "nothing stored");

    // Found to echo without its address; an echo of other command text is refused all the same.
    let (clock, host, faults, bus) = emulated(&[Variant::EchoWithoutAddress], 0);
    let _me = clock.reserve_participant().enter();
    assert!(!bus.move_to(a(1), &to(10.0), &mut |_| {}).unwrap().verified);
    // "1POSA 12.5,?\r" to drive 1 arrives as "1POSA 13.5,?": '2' (0x32) with bit 0 flipped is '3'.
    let at = faults.bytes_sent(Direction::HostToDevice) + ["1S16\r", "1S17\r", "1S1\r"].concat().len() as u64 + 7;
    faults.inject(Direction::HostToDevice, at, Fault::Corrupt { xor: 0x01 });
    let e = bus.move_to(a(1), &to(12.5), &mut |_| {}).unwrap_err();
    let Error::NotExecuted { why, .. } = e.root() else { panic!("{e}") };
    assert!(why.contains("\"POSA 13.5,?\"") && why.contains("its buffer holds"), "{why}");
    assert_eq!(host.with_device(|d| d.drive(1).unwrap().position()), 10.0, "not executed");
}

#[test]
fn no_flipped_bit_of_the_probe_makes_a_drive_that_echoes_pass_for_one_that_does_not() {
    // The probe "1S1?\r" (after "1S16\r" "1S17\r" "1S1\r") and its echo "1S1?\r\n>" (after the three
    // replies), every bit, both ways: the move is refused, or it succeeds verified.
    let probe_at = ["1S16\r", "1S17\r", "1S1\r"].concat().len() as u64;
    let replies_at = {
        let (clock, _host, faults, bus) = emulated(&[], 0);
        let _me = clock.reserve_participant().enter();
        bus.read_s16(a(1)).unwrap();
        bus.read_s17(a(1)).unwrap();
        bus.read_position(a(1)).unwrap();
        faults.bytes_sent(Direction::DeviceToHost)
    };
    let mut done = 0;
    for (dir, start, len) in [(Direction::HostToDevice, probe_at, 5), (Direction::DeviceToHost, replies_at, 7)] {
        for offset in start..start + len {
            for bit in 0..8 {
                let (clock, host, faults, bus) = emulated(&[], 0);
                let _me = clock.reserve_participant().enter();
                faults.inject(dir, offset, Fault::Corrupt { xor: 1 << bit });
                let mut req = to(10.0);
                req.timeout = Some(Duration::from_secs(5));
                let what = format!("{dir:?} byte {} bit {bit}", offset - start);
                match bus.move_to(a(1), &req, &mut |_| {}) {
                    Ok(r) => {
                        assert!(r.verified, "{what}: {r:?}");
                        assert_eq!(bus.driver().with_session(|s| s.echo_form(a(1))), Some(EchoForm::Full), "{what}");
                        done += 1;
                    }
                    Err(e) => assert_eq!(host.with_device(|d| d.drive(1).unwrap().position()), 0.0, "{what}: {e}"),
                }
                assert!(!host.with_device(|d| d.drive(3).unwrap().is_moving()), "{what}");
            }
        }
    }
    assert!(done > 0);
}

/// "motion started" events of the emulator since the last call.
fn starts(host: &EmulatorHost<Emulator>) -> usize {
    host.with_device(|d| d.take_events()).iter().filter(|e| e.contains("motion started")).count()
}

#[test]
fn a_drive_that_echoes_without_storing_gets_its_moves_as_commands_of_their_own_and_says_so() {
    let (clock, host, _faults, bus) = emulated(&[Variant::EchoWithoutStore], 0);
    let _me = clock.reserve_participant().enter();
    // The '!' after the echo is refused: nothing ran (S17), so the move goes out in the plain form, once.
    let r = bus.move_to(a(1), &to(10.0), &mut |_| {}).unwrap();
    assert!(!r.verified && r.reached == pos(10.0), "{r:?}");
    let why = r.not_verifiable.join("\n");
    assert!(why.contains("refused the '!' after echoing a move sent with ',?'"), "{why}");
    assert!(why.contains("without being checked before it started") && !why.contains("was stored"), "{why}");
    assert!(bus.driver().with_session(|s| s.echo_without_store(a(1))), "remembered");
    assert_eq!(starts(&host), 1);
    // Remembered: a relative move goes out as a command of its own at once, and runs once (S2 checked).
    let r = bus.move_to(a(1), &MoveRequest::new(MoveTarget::Relative(pos(-4.0))), &mut |_| {}).unwrap();
    assert!(!r.verified && r.reached == pos(6.0) && r.not_verifiable.join("\n") == why, "{r:?}");
    assert_eq!(host.with_device(|d| d.drive(1).unwrap().position()), 6.0, "the distance once");
    assert_eq!(starts(&host), 1);
    // A relative move as the first of a session: after the refused '!' it is not sent again (the drive may
    // hold it after all, and a later '!' would run it a second time): nothing ran, and the error says so.
    let (clock, host, _faults, bus) = emulated(&[Variant::EchoWithoutStore], 0);
    let _me = clock.reserve_participant().enter();
    let e = bus.move_to(a(1), &MoveRequest::new(MoveTarget::Relative(pos(3.0))), &mut |_| {}).unwrap_err();
    assert!(e.to_string().contains("a relative move is not sent again"), "{e}");
    assert!(e.to_string().contains("already at rest"), "the stop that followed found it at rest: {e}");
    assert_eq!(host.with_device(|d| d.drive(1).unwrap().position()), 0.0, "nothing ran");
    assert_eq!(starts(&host), 0);
    assert!(!bus.driver().with_session(|s| s.echo_without_store(a(1))));
}

#[test]
fn a_profile_form_the_drive_contradicts_is_found_again_and_the_move_runs_once() {
    for v in [Variant::NoEcho, Variant::EchoBare, Variant::EchoWithoutAddress] {
        for relative in [false, true] {
            let what = format!("{v:?} relative {relative}");
            let (clock, host, _faults, bus) = emulated(&[v], 0);
            let _me = clock.reserve_participant().enter();
            // A profile saved from a drive that echoed in full.
            bus.driver().with_session(|s| s.seed_echo_form(a(1), EchoForm::Full, "profiles.toml#compax:x"));
            let req = if relative { MoveRequest::new(MoveTarget::Relative(pos(3.0))) } else { to(20.0) };
            let r = bus.move_to(a(1), &req, &mut |_| {}).unwrap_or_else(|e| panic!("{what}: {e}"));
            let target = if relative { 3.0 } else { 20.0 };
            assert!(!r.verified && r.reached == pos(target), "{what}: {r:?}");
            assert_eq!(host.with_device(|d| d.drive(1).unwrap().position()), target, "{what}: once");
            assert_eq!(starts(&host), 1, "{what}");
            let (found, why) = match v {
                Variant::NoEcho => (EchoForm::None, "does not echo"),
                Variant::EchoBare => (EchoForm::Bare, "without the flag characters"),
                _ => (EchoForm::WithoutAddress, "echoes without its address"),
            };
            assert!(r.not_verifiable.join("\n").contains(why), "{what}: {r:?}");
            assert_eq!(bus.driver().with_session(|s| s.echo_form(a(1))), Some(found), "{what}");
            // Found now: the next move is checked in that form.
            let r = bus.move_to(a(1), &MoveRequest::new(MoveTarget::Relative(pos(-1.0))), &mut |_| {}).unwrap();
            assert_eq!(r.reached, pos(target - 1.0), "{what}");
            assert_eq!(starts(&host), 1, "{what}");
            bus.close().unwrap();
        }
    }
}

#[test]
fn a_profile_form_an_echo_has_shown_is_checked_as_one_found() {
    // The profile's form confirmed by the first echo; then the drive drops its address: refused, as for a
    // form found by this session, and nothing runs.
    let (clock, host, _faults, bus) = emulated(&[], 0);
    let _me = clock.reserve_participant().enter();
    bus.driver().with_session(|s| s.seed_echo_form(a(1), EchoForm::Full, "profiles.toml#compax:x"));
    assert!(bus.move_to(a(1), &to(10.0), &mut |_| {}).unwrap().verified);
    host.with_device(|d| d.set_variants(&[Variant::EchoWithoutAddress]));
    let e = bus.move_to(a(1), &to(12.0), &mut |_| {}).unwrap_err();
    let Error::NotExecuted { why, .. } = e.root() else { panic!("{e}") };
    assert!(why.contains("without its address digits, not in full as drive 1 was found to echo"), "{why}");
    assert!(!why.contains("is what the drive that answered received"), "{why}");
    assert_eq!(host.with_device(|d| d.drive(1).unwrap().position()), 10.0, "not executed");
}

#[test]
fn a_binary_move_says_it_was_not_checked_before_it_started() {
    for v in [&[][..], &[Variant::NoEcho], &[Variant::EchoWithoutStore]] {
        let (clock, _host, _faults, bus) = emulated(v, 0);
        let _me = clock.reserve_participant().enter();
        let mut req = MoveRequest::new(MoveTarget::Relative(pos(3.0)));
        req.binary = true;
        let r = bus.move_to(a(1), &req, &mut |_| {}).unwrap();
        assert_eq!(r.reached, pos(3.0));
        let why = r.not_verifiable.join("\n");
        assert!(
            !r.verified && why.contains("binary") && why.contains("without being checked before it started"),
            "{why}"
        );
    }
}

#[test]
fn the_variants_are_named_in_the_configuration() {
    let c = SimConfig::from_toml("variants = [\"echo-bare\", \"no-echo\"]\n[[drive]]\naddress = 2\n").unwrap();
    assert_eq!(c.variants, [Variant::EchoBare, Variant::NoEcho]);
    let e = SimConfig::from_toml("variants = [\"echo\"]\n").unwrap_err().to_string();
    assert!(e.contains("\"echo\" is not a variant of the COMPAX emulator (known: echo-without-address"), "{e}");
    // The emulator answers as the variant says.
    let mut cfg = SimConfig::bus(&[1], 0, 9600);
    cfg.variants = vec![Variant::StatusValueOnly, Variant::EchoBare];
    let mut sim = Emulator::new(cfg).unwrap();
    let mut out = Vec::new();
    sim.receive(motionlink_link::Timestamp::ZERO, b"1S1\r1POSA 3,?\r", &mut out);
    assert_eq!(out, b"0.000\r\n>POSA 3\r\n>");
}

#[test]
fn a_timeout_names_the_round_trips_measured_on_the_line() {
    let (clock, _host, _faults, bus) = emulated(&[], 0);
    let _me = clock.reserve_participant().enter();
    bus.read_position(a(1)).unwrap();
    let e = bus.read_position(a(9)).unwrap_err();
    let text = e.to_string();
    // "9S1\r" and "S001: 0.000\r\n>" at 9600 baud: about 20 ms on the wire.
    assert!(text.contains("no reply to \"S1\" within") && text.contains("replies on this link have taken 1"), "{text}");
    let Error::Timeout { round_trips: Some(r), .. } = e else { panic!("{e:?}") };
    assert!(r.fastest <= r.slowest && r.slowest < Duration::from_millis(40), "{r:?}");
}

#[test]
fn a_slow_drive_times_out_naming_its_late_replies_and_nothing_is_taken_for_a_later_telegram_s_reply() {
    let (clock, host, _faults, bus) = emulated(&[Variant::SlowReplies], 0);
    let _me = clock.reserve_participant().enter();
    let e = bus.read_position(a(1)).unwrap_err();
    let text = e.to_string();
    assert!(text.contains("drive 1: no reply to \"S1\" within 25") && text.contains("ms (4 attempts)"), "{text}");
    assert!(text.contains("; replies came 31") && text.contains("too late to be taken"), "{text}");
    let Error::Timeout { round_trips: None, late: Some(late), .. } = &e else { panic!("{e:?}") };
    // "1S1\r" takes 4 ms at 9600 baud, the reply "S001: 0.000\r\n>" 15 ms: 300 ms late, 319 ms in all.
    assert!(late.fastest >= Duration::from_millis(300) && late.slowest < Duration::from_millis(330), "{late:?}");
    // A late reply is never another telegram's: a scan finds no drive (none at 2 or 4 answering with the late
    // replies of 1 and 3), and says that 1 and 3 answered too late.
    assert_eq!(bus.scan(1..=4).unwrap(), []);
    // A checked move ends at its first read: nothing moved, nothing was switched off.
    let e = bus.move_to(a(1), &to(10.0), &mut |_| {}).unwrap_err();
    assert!(e.is_transport() && matches!(e.root(), Error::Timeout { command, .. } if command == "S16"), "{e}");
    assert!(e.stop_report().is_none(), "{e}");
    host.with_device(|d| {
        let d = d.drive(1).unwrap();
        assert_eq!((d.position(), d.o0(), d.is_moving()), (0.0, 1, false));
    });
    bus.close().unwrap();

    // With the reply timeout such a drive needs, it is found and moves; its round trips are measured.
    let (clock, _host, _faults, bus) = emulated_with(&[Variant::SlowReplies], 0, slow_enough(0));
    let _me = clock.reserve_participant().enter();
    let found: Vec<u8> = bus.scan(1..=4).unwrap().into_iter().map(|(d, _)| d.get()).collect();
    assert_eq!(found, [1, 3]);
    let r = bus.move_to(a(1), &MoveRequest::new(MoveTarget::Relative(pos(5.0))), &mut |_| {}).unwrap();
    assert!(r.verified && r.reached == pos(5.0), "{r:?}");
    let e = bus.read_position(a(9)).unwrap_err().to_string();
    assert!(e.contains("replies on this link have taken 3") && !e.contains("too late"), "{e}");
}

#[test]
fn a_move_whose_position_message_never_comes_ends_its_wait_by_s17() {
    for variants in [&[][..], &[Variant::NoPositionMessage]] {
        let (clock, host, _faults, bus) = emulated(variants, 0);
        let _me = clock.reserve_participant().enter();
        let reads = || host.with_device(|d| d.drive(1).unwrap().telegrams());
        bus.move_absolute(a(1), pos(10.0), MoveOptions { binary: false, message: true }).unwrap();
        let (t0, before) = (clock.now(), reads());
        bus.wait_reached(&[a(1)], Some(Duration::from_secs(5)), &mut |_, _| {}).unwrap();
        let (waited, read) = (clock.now() - t0, reads() - before);
        assert_eq!(bus.read_position(a(1)).unwrap(), pos(10.0), "{variants:?}");
        assert!(bus.started().is_empty(), "{variants:?}");
        if variants.is_empty() {
            // The '$' at 100 ms ended it (seen at the next poll interval); nothing was read meanwhile.
            assert!(waited <= Duration::from_millis(200) && read == 0, "{waited:?}, {read} telegrams");
        } else {
            // No '$': S17 (and S1), read once a second while a wait listens for one, ended it, once S1
            // held still over a poll interval (the session had not seen this drive's S17 show a positioning).
            assert!(waited >= Duration::from_secs(1) && waited < Duration::from_millis(1150), "{waited:?}");
            assert_eq!(read, 4, "S17 and S1, then S1 twice a poll interval apart");
        }
        // A synchronous start of two drives with '$' likewise.
        let moves = [(a(1), Command::PosA(pos(20.0))), (a(3), Command::PosA(pos(5.0)))];
        bus.sync_start(&moves, true).unwrap();
        let t0 = clock.now();
        bus.wait_reached(&[a(1), a(3)], Some(Duration::from_secs(5)), &mut |_, _| {}).unwrap();
        assert!(clock.now() - t0 < Duration::from_millis(1200), "{variants:?}");
        assert_eq!((bus.read_position(a(1)).unwrap(), bus.read_position(a(3)).unwrap()), (pos(20.0), pos(5.0)));
        bus.close().unwrap();
    }
}

#[test]
fn a_drive_whose_s17_never_shows_its_positioning_is_judged_by_s1_and_stopped_while_it_moves() {
    let (clock, host, _faults, bus) = emulated(&[Variant::NoCommandBit], 0);
    let _me = clock.reserve_participant().enter();
    let moving = || host.with_device(|d| d.drive(1).unwrap().is_moving());
    // A checked move: S17 shows no command from the first poll on, but S1 moves: the wait goes on until S1
    // holds still, the move ends at its target, and it says how its end was judged.
    let report = bus.move_to(a(1), &to(50.0), &mut |_| {}).unwrap();
    assert_eq!(report.reached, pos(50.0));
    assert!(!moving());
    assert!(!report.verified, "{report:?}");
    assert!(report.not_verifiable.iter().any(|w| w.contains("S17 did not show the positioning")), "{report:?}");
    // A cancelled wait stops the drive: it is seen to move by S1, and switched off.
    let token = motionlink_link::cancel::CancelToken::new();
    bus.set_cancel(token.clone());
    bus.move_absolute(a(1), pos(500.0), MoveOptions::default()).unwrap();
    let mut polls = 0;
    let e = bus
        .wait_reached(&[a(1)], None, &mut |_, _| {
            polls += 1;
            if polls == 3 {
                token.cancel();
            }
        })
        .unwrap_err();
    assert!(matches!(e, Error::Cancelled { .. }), "{e}");
    assert_eq!(e.stop_report().expect("a stop").switched_off(), [a(1)], "{e}");
    assert!(!moving() && host.with_device(|d| d.drive(1).unwrap().o0()) == 0);
    token.reset();
    // On a new session (nothing seen yet): a stop of a drive S17 calls idle but S1 shows moving switches it
    // off; one that rests is left switched on.
    drop(bus);
    let (clock, host, _faults, bus) = emulated(&[Variant::NoCommandBit], 0);
    let _me = clock.reserve_participant().enter();
    let stopped = bus.stop_confirmed(a(1)).unwrap();
    assert!(stopped.report.switched_off().is_empty(), "{stopped:?}");
    assert_eq!(host.with_device(|d| d.drive(1).unwrap().o0()), 1, "at rest: left switched on");
    bus.move_absolute(a(1), pos(500.0), MoveOptions::default()).unwrap();
    // A watch of it shows it moving by S1 (its S17 shows no command).
    let token = motionlink_link::cancel::CancelToken::new();
    bus.set_cancel(token.clone());
    let mut samples = Vec::new();
    bus.watch(a(1), Duration::from_millis(50), &mut |s| {
        samples.push((s.s17.contains(S17Flag::CommandActive), s.moving()));
        if samples.len() == 3 {
            token.cancel();
        }
    })
    .unwrap();
    assert_eq!(samples, [(false, false), (false, true), (false, true)], "the first has nothing to compare with");
    token.reset();
    let stopped = bus.stop_confirmed(a(1)).unwrap();
    assert_eq!(stopped.report.switched_off(), [a(1)], "{stopped:?}");
    assert!(!host.with_device(|d| d.drive(1).unwrap().is_moving()));
    bus.close().unwrap();
}

#[test]
fn a_progress_callback_that_panics_has_its_move_stopped_before_the_panic_goes_on() {
    let (clock, host, _faults, bus) = emulated(&[], 0);
    let _me = clock.reserve_participant().enter();
    let moving = || host.with_device(|d| d.drive(1).unwrap().is_moving());
    // The caller's code panics on the first position the wait reports: the move is cancelled (the drive
    // switched off, confirmed), and only then does the panic reach the caller.
    let panicked = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        bus.move_to(a(1), &to(500.0), &mut |_| panic!("the caller's bug"))
    }));
    let payload = panicked.expect_err("the panic goes on");
    assert_eq!(payload.downcast_ref::<&str>(), Some(&"the caller's bug"));
    assert!(!moving(), "stopped");
    assert_eq!(host.with_device(|d| d.drive(1).unwrap().o0()), 0, "switched off");
    assert!(bus.started().is_empty());
    bus.close().unwrap();
}

/// A move sent with `?` may be carried out as well as echoed (the manual says only that the drive sends it
/// back; `echo-executes` does both): `raw` and `echo` count it as started, so that the close (a signal, a
/// drop) stops the axis it moved (was: not counted, and the axis ran on unstopped). Sent with `,?`, it is
/// stored, not started; a switch-off sent with `?` is not taken for done.
#[test]
fn a_move_sent_with_an_echo_counts_as_started_and_the_close_stops_it() {
    use motionlink_compax::client::AfterRaw;
    let (clock, host, _faults, bus) = emulated(&[Variant::EchoExecutes], 0);
    let _me = clock.reserve_participant().enter();
    assert_eq!(bus.raw(a(1), "POSA 500?").unwrap().as_deref(), Some("1POSA 500?"));
    assert_eq!(bus.started(), [a(1)]);
    assert_eq!(starts(&host), 1, "the drive moves");
    bus.echo(a(3), "POSA 400").unwrap();
    assert_eq!(bus.started(), [a(1), a(3)]);
    assert_eq!(starts(&host), 1, "drive 3's move started too");
    // `OUTPUT O0=0?` echoed: drive 1 is still taken as moving.
    bus.raw(a(1), "OUTPUT O0=0?").unwrap();
    assert!(bus.started().contains(&a(1)));
    let stopped = bus.close().unwrap();
    assert_eq!(stopped.drives.len(), 2, "{stopped:?}");
    assert!(stopped.all_confirmed(), "{stopped:?}");
    for d in [1, 3] {
        let (position, moving) = host.with_device(|e| {
            let drive = e.drive(d).unwrap();
            (drive.position(), drive.is_moving())
        });
        assert!(!moving && position < 400.0, "drive {d} stopped by the close, at {position}");
    }
    // The default drive does not carry it out: counted all the same (nothing tells the two apart; `raw`'s
    // hand-over names it), and the close finds it at rest.
    let (clock, host, _faults, bus) = emulated(&[], 0);
    let _me = clock.reserve_participant().enter();
    let r = bus.raw_motion(a(1), "POSA 500?", AfterRaw::HandOver).unwrap();
    assert_eq!(r.started, [a(1)]);
    assert_eq!(starts(&host), 0);
    assert!(bus.raw_motion(a(1), "POSA 500,?", AfterRaw::HandOver).unwrap().started.is_empty());
    assert!(bus.close().unwrap().all_confirmed());
}
