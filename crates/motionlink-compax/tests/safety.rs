//! Safety of the client (issue "never leave an axis moving, never report a success that did not happen"):
//! checked moves, travel limits, a switched-off drive, stops that say whether the drive confirmed them,
//! polling at a set rate, and every single bit flip of a move's telegrams. In-process, on the manual clock.

use std::time::Duration;

use motionlink_compax::client::{
    Client, Config, Error, MoveOptions, MoveRequest, MoveTarget, StopOutcome, TravelLimits,
};
use motionlink_compax::model::{OutputState, ParamId, Position, SpeedPercent};
use motionlink_compax::sim::{SimConfig, REFUSED};
use motionlink_compax::wire::Address;
use motionlink_link::cancel::CancelToken;
use motionlink_link::chunk;
use motionlink_link::clock::Clock;
use motionlink_link::pipe::{Direction, Fault};
use motionlink_link::transcript::Transcript;

use crate::support::{rig_on, Rig};

const D1: motionlink_compax::wire::Address = motionlink_compax::wire::Address::drive_const(1);

fn rig_with(addrs: &[u8], p196: u32, baud: u32, cfg: impl FnOnce(&mut Config)) -> (Rig, Client) {
    rig_on(SimConfig::bus(addrs, p196, baud), p196, baud, cfg)
}

fn rig(addrs: &[u8], p196: u32, baud: u32) -> (Rig, Client) {
    rig_with(addrs, p196, baud, |_| {})
}

fn a(n: u8) -> Address {
    Address::drive(n).unwrap()
}

fn pos(v: f64) -> Position {
    Position::new(v).unwrap()
}

fn sent(t: &Transcript) -> Vec<String> {
    t.records()
        .into_iter()
        .filter(|r| r.direction == chunk::Direction::ToDevice)
        .map(|r| String::from_utf8_lossy(&r.bytes).into_owned())
        .collect()
}

fn to(v: f64) -> MoveRequest {
    MoveRequest::new(MoveTarget::Absolute(pos(v)))
}

/// (position, moving, O0) of drive `n`.
fn drive_state(r: &Rig, n: u8) -> (f64, bool, u8) {
    r.host.with_device(|d| {
        let d = d.drive(n).unwrap();
        (d.position(), d.is_moving(), d.o0())
    })
}

/// Sends `telegram` over a second connection to the emulator (another program on the bus) and reads the
/// drive's answer.
fn someone_else_sends(r: &Rig, telegram: &[u8]) -> Vec<u8> {
    use motionlink_link::link::Link;
    let (mut other, _) = r.host.connect();
    other.send(telegram).unwrap();
    let mut got = Vec::new();
    let mut buf = [0u8; 32];
    while !got.ends_with(b">") {
        let n = other.recv(&mut buf, Duration::from_secs(1)).unwrap();
        assert!(n > 0, "no answer to {telegram:?}");
        got.extend_from_slice(&buf[..n]);
    }
    got
}

#[test]
fn a_checked_move_reads_its_target_back_and_checks_where_the_axis_came_to_rest() {
    let (r, bus) = rig(&[1], 0, 9600);
    let _me = r.clock.reserve_participant().enter();
    let mut req = to(12.5);
    req.speed = Some(SpeedPercent::new(50.0).unwrap());
    let mut seen = Vec::new();
    let report = bus.move_to(a(1), &req, &mut |p| seen.push(p.units())).unwrap();
    assert_eq!((report.start, report.target, report.reached), (pos(0.0), pos(12.5), pos(12.5)));
    assert_eq!(report.difference(), 0.0);
    assert!(!seen.is_empty());
    let frames = sent(&r.transcript);
    // Switched on? At rest? Where from? How does it echo (S1 with '?', not executed)? Then the setting, the
    // move stored with its echo (`,?`), executed (`!`) once the echo is the telegram sent, and its target
    // read back at once.
    assert_eq!(
        frames[..8],
        ["1S16\r", "1S17\r", "1S1\r", "1S1?\r", "1SPEED 50\r", "1POSA 12.5,?\r", "1!\r", "1S2\r"],
        "{frames:?}"
    );
    assert!(report.verified && report.not_verifiable.is_empty(), "{report:?}");
    // Polls, and the position at rest at the end.
    assert_eq!(frames.last().unwrap(), "1S1\r");
    assert!(bus.started().is_empty());
    // A relative move goes from the drive's target S2, read before.
    let report = bus.move_to(a(1), &MoveRequest::new(MoveTarget::Relative(pos(-2.5))), &mut |_| {}).unwrap();
    assert_eq!((report.target, report.reached), (pos(10.0), pos(10.0)));
    assert_eq!(drive_state(&r, 1), (10.0, false, 1));
}

#[test]
fn a_move_that_ends_away_from_its_target_fails_naming_target_reached_and_difference() {
    let (r, bus) = rig(&[1], 0, 9600);
    let _me = r.clock.reserve_participant().enter();
    let started = bus.start_checked_move(a(1), &to(100.0)).unwrap();
    r.clock.sleep(Duration::from_millis(250));
    // Another program on the bus switches the drive off: the positioning ends where the axis is.
    someone_else_sends(&r, b"1OUTPUT O0=0\r");
    let e = bus.finish_checked_move(&started, None, &mut |_| {}).unwrap_err();
    let Error::NotReached { address: D1, target, reached, difference, tolerance } = e else { panic!("{e}") };
    let (target, reached, difference, tolerance) =
        (target.units(), reached.units(), difference.units(), tolerance.units());
    assert_eq!(target, 100.0);
    assert!(reached > 10.0 && reached < 100.0, "{reached}");
    assert_eq!(difference, reached - 100.0);
    assert_eq!(tolerance, 0.01);
    let text = e.to_string();
    assert!(text.contains("target 100") && text.contains(&format!("reached {reached}")), "{text}");
    assert!(text.contains("difference -"), "{text}");
    assert!(!e.is_transport());
}

#[test]
fn the_in_position_tolerance_is_a_setting() {
    let (r, bus) = rig_with(&[1], 0, 9600, |c| c.in_position_tolerance = pos(50.0));
    let _me = r.clock.reserve_participant().enter();
    let started = bus.start_checked_move(a(1), &to(100.0)).unwrap();
    r.clock.sleep(Duration::from_millis(600));
    someone_else_sends(&r, b"1OUTPUT O0=0\r");
    // Stopped at about 60, within 50 of 100: done, as the caller asked.
    let report = bus.finish_checked_move(&started, None, &mut |_| {}).unwrap();
    assert!((report.difference() + 40.0).abs() < 5.0, "{report:?}");
}

#[test]
fn a_target_outside_the_travel_limits_is_refused_before_anything_moves() {
    let (r, bus) = rig(&[1], 0, 9600);
    let _me = r.clock.reserve_participant().enter();
    let limits = TravelLimits::new(Some(pos(-5.0)), Some(pos(40.0))).unwrap();
    let mut req = to(50.0);
    req.limits = limits;
    let e = bus.move_to(a(1), &req, &mut |_| {}).unwrap_err();
    assert!(
        matches!(e, Error::OutsideLimits { address: D1, side: "above the maximum", limit, .. } if limit.units() == 40.0),
        "{e}"
    );
    assert!(e.to_string().contains("above the maximum 40"), "{e}");
    assert!(sent(&r.transcript).is_empty(), "an absolute target is checked before anything is sent");
    // A relative one from the drive's target: read first, then refused without a move.
    r.host.with_device(|_| ());
    let mut req = MoveRequest::new(MoveTarget::Relative(pos(-6.0)));
    req.limits = limits;
    let e = bus.move_to(a(1), &req, &mut |_| {}).unwrap_err();
    assert!(e.to_string().contains("target -6 is outside the travel limits: it is below the minimum -5"), "{e}");
    let frames = sent(&r.transcript);
    assert!(!frames.iter().any(|f| f.contains("POS")), "{frames:?}");
    assert_eq!(drive_state(&r, 1), (0.0, false, 1));
    // Inside them, it moves.
    let mut req = to(40.0);
    req.limits = limits;
    bus.move_to(a(1), &req, &mut |_| {}).unwrap();
    assert!(TravelLimits::new(Some(pos(1.0)), Some(pos(0.0))).is_err());
}

#[test]
fn a_switched_off_drive_is_named_as_such_not_with_a_bare_e90() {
    let (r, bus) = rig(&[1], 0, 9600);
    let _me = r.clock.reserve_participant().enter();
    bus.set_output(a(1), 0, OutputState::OFF, false).unwrap();
    let e = bus.move_to(a(1), &to(10.0), &mut |_| {}).unwrap_err();
    assert!(matches!(e, Error::SwitchedOff { address: D1, o0: 0, refused: None }), "{e}");
    assert!(e.to_string().contains("switched off") && e.to_string().contains("OUTPUT O0=1"), "{e}");
    assert!(!sent(&r.transcript).iter().any(|f| f.contains("POSA")), "checked before the move is sent");
    // Sent anyway (raw, or the plain move methods), the drive's E90 is explained.
    let e = bus.raw(a(1), "POSA 10").unwrap_err();
    assert!(matches!(e, Error::SwitchedOff { address: D1, o0: 0, refused: Some(REFUSED) }), "{e}");
    assert!(e.to_string().contains("refused the move with E90"), "{e}");
    let e = bus.move_absolute(a(1), pos(10.0), MoveOptions::default()).unwrap_err();
    assert!(matches!(e, Error::SwitchedOff { .. }), "{e}");
    assert!(bus.started().is_empty());
    // Switched on, it moves.
    bus.set_output(a(1), 0, OutputState::ON, false).unwrap();
    bus.move_to(a(1), &to(10.0), &mut |_| {}).unwrap();
}

#[test]
fn a_corrupted_target_is_caught_by_reading_s2_back_and_the_axis_is_switched_off() {
    let (r, bus) = rig(&[1], 0, 9600);
    let _me = r.clock.reserve_participant().enter();
    // In binary (which takes no `,?`: the ASCII move is checked by its echo before it starts, see
    // echo_check.rs) the target is checked after the start: "1S16\r" "1S17\r" "1S1\r", then the binary
    // POSA 15 ('1' 88 41 00 00 00 0F 00 00): flip 0F (byte 6 of the move) into 0E, 14.
    let at = r.faults().bytes_sent(Direction::HostToDevice);
    r.faults().inject(Direction::HostToDevice, at + 5 + 5 + 4 + 6, Fault::Corrupt { xor: 0x01 });
    let mut req = to(15.0);
    req.binary = true;
    let e = bus.move_to(a(1), &req, &mut |_| {}).unwrap_err();
    assert!(
        matches!(e.root(), Error::TargetMismatch { address: D1, requested, taken } if requested.units() == 15.0 && taken.units() == 14.0),
        "{e}"
    );
    let stop = e.stop_report().unwrap();
    assert_eq!(stop.drives, [(a(1), StopOutcome::SwitchedOff)]);
    let text = e.to_string();
    assert!(text.contains("took target 14 instead of 15"), "{text}");
    assert!(text.contains("now switched off"), "{text}");
    let (p, moving, o0) = drive_state(&r, 1);
    // S2 twice, S17, OUTPUT O0=0 at 9600 baud: about 75 ms at 100 units/s.
    assert!(!moving && o0 == 0 && p < 10.0, "stopped at once, near the start: {p}");
    assert_eq!(sent(&r.transcript).iter().filter(|f| *f == "1S2\r").count(), 2, "S2 read twice before the stop");
}

/// The outcome of one move with one fault injected.
#[derive(Debug)]
enum Outcome {
    Done,
    Failed,
}

/// One checked move of drive 1 from 0 (to `target`, or by it when `relative`) with one byte corrupted by
/// `xor` at `offset` in `dir` (mode `p196`, ASCII or binary); returns what the caller saw, after checking
/// the drives: never at rest elsewhere with success, never left moving, drive 2 never moved.
fn one_fault(p196: u32, kind: MoveKind, target: f64, fault: Option<(Direction, u64, u8)>) -> Outcome {
    let (r, bus) = rig(&[1, 2], p196, 9600);
    let _me = r.clock.reserve_participant().enter();
    if let Some((dir, offset, xor)) = fault {
        r.faults().inject(dir, offset, Fault::Corrupt { xor });
    }
    let mut req = match kind {
        MoveKind::Relative => MoveRequest::new(MoveTarget::Relative(pos(target))),
        _ => to(target),
    };
    req.speed = Some(SpeedPercent::new(50.0).unwrap());
    req.binary = kind == MoveKind::Binary;
    req.timeout = Some(Duration::from_secs(5));
    let result = bus.move_to(a(1), &req, &mut |_| {});
    let what = format!("P196={p196} {kind:?} fault {fault:?}");
    // An ASCII move is checked by its echo before it starts: no positioning ever starts towards another
    // target (a binary move, which takes no echo, may, and is then stopped by the S2 check).
    let started: Vec<String> = {
        use motionlink_link::emulator::Emulator as _;
        r.host.with_device(|d| d.take_events()).into_iter().filter(|e| e.contains("motion started")).collect()
    };
    if kind != MoveKind::Binary {
        let right = format!("drive 1 motion started to {target:.3} from 0.000");
        assert!(started.iter().all(|e| *e == right) && started.len() <= 1, "{what}: {started:?}");
    }
    // Whatever happened, nothing this client started may still move, and no stop stays unconfirmed.
    let report = bus.stop_started();
    assert!(report.all_confirmed(), "{what}: {report}");
    let (p, moving, _) = drive_state(&r, 1);
    assert!(!moving, "{what}: drive 1 left moving at {p} ({result:?})");
    assert!(!drive_state(&r, 2).1, "{what}: drive 2 moving");
    let outcome = match result {
        Ok(rep) => {
            assert!(
                (p - target).abs() <= 0.01,
                "{what}: success reported with the axis at {p}, not {target} ({rep:?}); sent {:?}",
                sent(&r.transcript)
            );
            // What it reports may be a misread within the tolerance (a flipped bit in the last digit).
            assert!((rep.reached.units() - p).abs() <= 0.01 + 1e-9, "{what}: reported {rep:?}, at {p}");
            Outcome::Done
        }
        Err(e) => {
            let text = e.to_string();
            // An error that left the drive switched off says so.
            if drive_state(&r, 1).2 == 0 {
                assert!(text.contains("switched off"), "{what}: {text}");
            }
            assert!(text.len() > 10, "{what}: {text:?}");
            Outcome::Failed
        }
    };
    outcome
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum MoveKind {
    Ascii,
    Binary,
    Relative,
}

/// Bytes of a clean checked move, each way.
fn clean_move_bytes(p196: u32, kind: MoveKind, target: f64) -> (u64, u64) {
    let (r, bus) = rig(&[1, 2], p196, 9600);
    let _me = r.clock.reserve_participant().enter();
    let mut req = match kind {
        MoveKind::Relative => MoveRequest::new(MoveTarget::Relative(pos(target))),
        _ => to(target),
    };
    req.speed = Some(SpeedPercent::new(50.0).unwrap());
    req.binary = kind == MoveKind::Binary;
    bus.move_to(a(1), &req, &mut |_| {}).unwrap();
    (r.faults().bytes_sent(Direction::HostToDevice), r.faults().bytes_sent(Direction::DeviceToHost))
}

#[test]
fn no_single_bit_flip_in_any_telegram_of_a_move_ends_in_success_with_the_axis_elsewhere() {
    // Mode 0: no BCC, so a flipped bit in a digit is still a valid command. Every bit of every byte of a
    // whole move, both ways, for an absolute move in ASCII and in binary and a relative one; drive 2 is on
    // the bus too (a flipped address digit reaches it). 12.5 units at 50 units/s: a quarter of a second, a
    // few polls.
    let target = 12.5;
    assert!(matches!(one_fault(0, MoveKind::Ascii, target, None), Outcome::Done));
    for kind in [MoveKind::Ascii, MoveKind::Binary, MoveKind::Relative] {
        let (up, down) = clean_move_bytes(0, kind, target);
        assert!(up > 30 && down > 40, "{up} {down}");
        let (mut done, mut failed) = (0, 0);
        for (dir, bytes) in [(Direction::HostToDevice, up), (Direction::DeviceToHost, down)] {
            for offset in 0..bytes {
                for bit in 0..8 {
                    match one_fault(0, kind, target, Some((dir, offset, 1 << bit))) {
                        Outcome::Done => done += 1,
                        Outcome::Failed => failed += 1,
                    }
                }
            }
        }
        eprintln!(
            "{kind:?}: {up} + {down} bytes, {} flips: {done} moves done, {failed} failed loudly",
            (up + down) * 8
        );
        // Most flips are retried away or harmless; the others fail. Both happen.
        assert!(done > 0 && failed > 0, "{kind:?}: done {done}, failed {failed}");
    }
}

#[test]
fn a_corrupted_parameter_write_is_caught_by_the_read_back() {
    let (r, bus) = rig(&[1], 0, 9600);
    let _me = r.clock.reserve_participant().enter();
    // "1P003=-1055.88\r": the last '8' (byte 13) becomes '9': a valid write of another value.
    let at = r.faults().bytes_sent(Direction::HostToDevice);
    r.faults().inject(Direction::HostToDevice, at + 13, Fault::Corrupt { xor: 0x01 });
    let p3 = ParamId::new(3).unwrap();
    let e = bus.write_param(a(1), p3, -1055.88).unwrap_err();
    assert!(
        matches!(e, Error::ReadBack { address: D1, wrote, read, .. } if wrote == -1055.88 && read == -1055.89),
        "{e}"
    );
    assert!(e.to_string().contains("P003 reads back -1055.89 after -1055.88 was written"), "{e}");
    // Clean, it reads back what was written.
    bus.write_param(a(1), p3, -1055.88).unwrap();
    assert_eq!(sent(&r.transcript).last().unwrap(), "1P003\r");
}

#[test]
fn a_wait_polls_at_the_set_rate_not_as_fast_as_the_line_answers() {
    for (baud, poll_ms) in [(115_200, 50), (115_200, 200), (9600, 50)] {
        let (r, bus) = rig_with(&[1], 0, baud, |c| c.poll_interval = Duration::from_millis(poll_ms));
        let _me = r.clock.reserve_participant().enter();
        // 1000 units at 100 units/s: 10 s.
        bus.move_to(a(1), &to(1000.0), &mut |_| {}).unwrap();
        let polls = sent(&r.transcript).iter().filter(|f| *f == "1S17\r").count() as f64;
        let expected = 10_000.0 / poll_ms as f64;
        assert!(
            (polls - expected).abs() <= expected * 0.05 + 2.0,
            "{baud} baud, poll every {poll_ms} ms: {polls} polls in 10 s, expected about {expected}"
        );
    }
}

#[test]
fn a_cancel_between_polls_stops_the_axis_within_milliseconds() {
    let (r, bus) = rig_with(&[1], 0, 115_200, |c| c.poll_interval = Duration::from_millis(500));
    let token = CancelToken::new();
    bus.set_cancel(token.clone());
    // This thread takes part in the clock before the canceller starts: otherwise the clock could reach the
    // cancel before the move has begun.
    let _me = r.clock.reserve_participant().enter();
    // Another participant cancels 1.234 s into the move (between two polls 500 ms apart).
    let ticket = r.clock.reserve_participant();
    let clock = r.clock.clone();
    let canceller = std::thread::spawn(move || {
        let _me = ticket.enter();
        clock.sleep(Duration::from_millis(1234));
        token.cancel();
        clock.now()
    });
    let e = bus.move_to(a(1), &to(1000.0), &mut |_| {}).unwrap_err();
    let ended = r.clock.now();
    let cancelled_at = canceller.join().unwrap();
    assert!(matches!(e, Error::Cancelled { .. }), "{e}");
    assert_eq!(e.stop_report().unwrap().switched_off(), [a(1)]);
    let took = ended - cancelled_at;
    // The next look at the token (5 ms), S17, OUTPUT O0=0, S17 to confirm: a few ms at 115200 baud.
    assert!(took < Duration::from_millis(15), "stopped {took:?} after the cancel");
    let (p, moving, o0) = drive_state(&r, 1);
    assert!(!moving && o0 == 0 && (p - 123.4).abs() < 2.0, "{p}");
}

#[test]
fn a_dead_line_during_a_move_is_reported_with_an_unconfirmed_stop() {
    // Nothing gets through any more, either way.
    let (r, bus) = rig(&[1], 0, 9600);
    let _me = r.clock.reserve_participant().enter();
    let started = bus.start_checked_move(a(1), &to(1000.0)).unwrap();
    r.faults().drop_next(Direction::HostToDevice, u64::MAX);
    r.faults().drop_next(Direction::DeviceToHost, u64::MAX);
    let t0 = r.clock.now();
    let e = bus.finish_checked_move(&started, None, &mut |_| {}).unwrap_err();
    assert!(e.is_transport(), "{e}");
    assert!(matches!(e.root(), Error::Timeout { .. }), "{e}");
    assert_eq!(e.stop_report().unwrap().unconfirmed(), [a(1)]);
    let text = e.to_string();
    assert!(text.contains("NOT confirmed") && text.contains("the axis may still be moving"), "{text}");
    assert!(drive_state(&r, 1).1, "it does move on: the link has no watchdog");
    assert!(r.clock.now() - t0 < Duration::from_secs(3), "gave up after {:?}", r.clock.now() - t0);
    bus.release(&[a(1)]);

    // Only the replies are lost: the stop reaches the drive, but it cannot confirm it, and the error says
    // just that.
    let (r, bus) = rig(&[1], 0, 9600);
    let _me = r.clock.reserve_participant().enter();
    let started = bus.start_checked_move(a(1), &to(1000.0)).unwrap();
    r.faults().drop_next(Direction::DeviceToHost, u64::MAX);
    let e = bus.finish_checked_move(&started, None, &mut |_| {}).unwrap_err();
    assert!(e.to_string().contains("the axis may still be moving"), "{e}");
    assert!(!drive_state(&r, 1).1, "(it was stopped: the drive got OUTPUT O0=0)");
    bus.release(&[a(1)]);
}

#[test]
fn a_stop_is_not_held_back_by_the_late_window_of_a_drive_that_turned_slow() {
    // A move runs (100 units/s); 1 s in the drive starts answering 300 ms late, beyond the reply timeout, so
    // the wait's polls go unanswered in time (each followed by a late window); at 1.5 s the move is cancelled.
    let (r, bus) = rig(&[1], 0, 9600);
    let token = CancelToken::new();
    bus.set_cancel(token.clone());
    let _me = r.clock.reserve_participant().enter();
    let ticket = r.clock.reserve_participant();
    let (clock, host) = (r.clock.clone(), r.host.clone());
    let canceller = std::thread::spawn(move || {
        let _me = ticket.enter();
        clock.sleep(Duration::from_millis(1000));
        host.with_device(|d| d.set_variants(&[motionlink_compax::sim::Variant::SlowReplies]));
        clock.sleep(Duration::from_millis(500));
        token.cancel();
        host.with_device(|d| d.drive(1).unwrap().position())
    });
    let result = bus.move_to(a(1), &to(1000.0), &mut |_| {});
    let at_cancel = canceller.join().unwrap();
    // Whatever happened, the close has nothing left to stop (it would wait on a clock nobody advances once
    // this thread stops taking part in it).
    bus.release(&[a(1)]);
    drop(bus);
    let e = result.unwrap_err();
    assert!(matches!(e, Error::Cancelled { .. }), "{e}");
    assert_eq!(e.stop_report().unwrap().switched_off(), [a(1)], "confirmed: {e}");
    let (p, moving, o0) = drive_state(&r, 1);
    assert!(!moving && o0 == 0, "switched off: {e}");
    // The poll on the line fails at its deadline (a cancelled operation's telegram gets no late window), the
    // stop's S17 (one sending, no window) likewise, then OUTPUT O0=0: about 0.5 s at 9600 baud, 50 units.
    // A late window before either would add 0.2 s (20 units).
    let ran_on = p - at_cancel;
    assert!(ran_on > 0.0 && ran_on < 55.0, "the axis ran {ran_on} units after the cancel: {e}");
}
