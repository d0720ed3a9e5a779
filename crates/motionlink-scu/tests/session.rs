//! The sans-IO session wired directly to the emulator: no link, no thread, no real time. A bench moves bytes
//! between them with the wire time of 38400 baud and a latency each way that a test can change, on a clock
//! that jumps from one deadline to the next.

use std::time::Duration;

use motionlink_link::session::Session as _;
use motionlink_link::Timestamp;
use motionlink_scu::config::FLUSH_LEN;
use motionlink_scu::model::{Actuator, DataIndex, MotionDirection, MotionFunction, PositionCounts, SafetyId, Speed};
use motionlink_scu::session::{MoveSpec, MoveTargets, Op, Output, PreparedRequest, Progress, RunAction, RunSpec};
use motionlink_scu::sim::RemoteMode;
use motionlink_scu::wire::{reply_to_vec, request_to_vec, Command, Reply, Request, Status};
use motionlink_scu::{Config, Emulator, Error, FunctionMap, Session, SimConfig};
use motionlink_testkit::wired::{Device, Line, Serial, Telegram, Wired};

/// The session wired to the unit at 38400 baud, 8N1 (the shared harness).
type Bench = Wired<Session, Serial<Emulator>>;

/// What these tests ask of the harness.
trait ScuBench {
    /// A session on a unit, not yet opened.
    fn unopened(config: Config, unit: SimConfig) -> Self;
    /// A session opened on a unit.
    fn opened(config: Config, unit: SimConfig) -> Self;
    /// The command letters of what the session sent between `from` and `to`.
    fn sent_between(&self, from: Timestamp, to: Timestamp) -> Vec<String>;
}

impl ScuBench for Bench {
    fn unopened(config: Config, unit: SimConfig) -> Bench {
        let session = Session::new(config, Timestamp::ZERO).unwrap();
        Wired::new(session, Serial(Emulator::new(unit).unwrap()), Line::baud(38_400, 10))
    }

    fn opened(config: Config, unit: SimConfig) -> Bench {
        let mut b = Bench::unopened(config, unit);
        let open = b.start(Op::Open);
        b.wait_done(open).unwrap();
        b
    }

    fn sent_between(&self, from: Timestamp, to: Timestamp) -> Vec<String> {
        self.sent
            .iter()
            .filter(|(t, b)| *t >= from && *t <= to && b[0] == b'R')
            .map(|(_, b)| String::from_utf8_lossy(&b[..2]).into_owned())
            .collect()
    }
}

fn a(n: u8) -> Actuator {
    Actuator::new(n).unwrap()
}

fn f(n: u8) -> MotionFunction {
    MotionFunction::new(n).unwrap()
}

fn move_a1(target: i32) -> Op {
    Op::Move(MoveSpec {
        function: f(1),
        primary: a(1),
        targets: MoveTargets::Given(vec![(a(1), PositionCounts(target))]),
        speed: Speed::percent(100).unwrap(),
    })
}

fn scp11() -> Config {
    Config { function_map: FunctionMap::scp11(), ..Config::default() }
}

fn is_keepalive(bytes: &[u8]) -> bool {
    bytes.starts_with(&[0x52, 0x43, 0x01, 0x00, 0xFF])
}

#[test]
fn open_sends_ro_then_rc_and_the_keepalive_keeps_its_grid_of_deadlines() {
    let mut b = Bench::opened(Config::default(), SimConfig::default());
    assert_eq!(b.sent_between(Timestamp::ZERO, b.now), ["RO", "RC"]);
    assert_eq!(b.device.mode(), RemoteMode::Active(SafetyId::StopAllAndLock));
    let rc_at = b.sent[1].0;
    b.run_for(Duration::from_secs(10));
    let keepalives: Vec<Timestamp> = b.sent.iter().skip(2).filter(|(_, x)| is_keepalive(x)).map(|(t, _)| *t).collect();
    assert_eq!(keepalives.len(), 50, "one RC every 200 ms");
    for (k, t) in keepalives.iter().enumerate() {
        let due = rc_at + Duration::from_millis(200) * (k as u32 + 1);
        assert_eq!(*t, due, "keepalive {k}: sent on its deadline, never drifting");
    }
    assert_eq!(b.device.stats().watchdog_expiries, 0);
    assert_eq!(b.session.stats().keepalives, 50);
}

#[test]
fn a_move_is_watched_through_the_keepalive_and_every_exchange_while_it_runs_is_an_rc() {
    let mut b = Bench::opened(scp11(), SimConfig::default());
    let id = b.start(move_a1(300));
    let Output::Move(report) = b.wait_done(id).unwrap() else { panic!() };
    assert_eq!(report.position_counts, PositionCounts(300));
    assert_eq!(b.device.position(a(1)), Some(300));
    let started = b.device_saw("F1 started").unwrap();
    let rest = b.device_saw("A1 at rest").unwrap();
    let during = b.sent_between(started, rest);
    assert!(during.len() > 40 && during.iter().all(|c| c == "RC"), "{during:?}");
    // The poll object (CyclicObj 5) was defined and read back once, before the RE.
    let before = b.sent_between(Timestamp::ZERO, started);
    assert_eq!(before.iter().filter(|c| *c == "RE").count(), 1);
    assert!(b.sent.iter().any(|(_, x)| x.starts_with(&[0x52, 0x54, 0x1A, 0x00, 0x05, 0x30])), "RT of 0x3005");
    // Progress came with every poll, rising.
    let seen: Vec<PositionCounts> = b
        .progress
        .iter()
        .filter_map(|(i, p)| match p {
            Progress::Move(m) if *i == id => Some(m.position_counts),
            _ => None,
        })
        .collect();
    assert!(seen.len() > 40 && seen.windows(2).all(|w| w[0] <= w[1]), "{seen:?}");
    // RS at the end: nothing stays started.
    assert!(b.session.started().is_empty());
    assert!(b.device.executed_functions().is_empty());
    assert_eq!(b.device.stats().watchdog_expiries, 0);
}

#[test]
fn a_move_keeps_the_unit_alive_with_round_trips_of_300_ms() {
    let mut b = Bench::opened(scp11(), SimConfig::default());
    let id = b.start(move_a1(400));
    // Once the motion runs, the line gets 150 ms of latency each way: round trips of 300 ms and more.
    b.run_until(Duration::from_secs(5), |b| b.device_saw("F1 started").is_some());
    b.line.one_way = Duration::from_millis(150);
    let slow_from = b.now;
    b.run_until(Duration::from_secs(30), |b| b.device_saw("A1 at rest").is_some());
    let slow_to = b.now;
    assert!(b.session.round_trip() >= Duration::from_millis(300), "{:?}", b.session.round_trip());
    b.line.one_way = Duration::ZERO;
    let Output::Move(report) = b.wait_done(id).unwrap() else { panic!() };
    assert_eq!(report.position_counts, PositionCounts(400));
    // The unit's watchdog never expired: while the round trips were slow, only RCs went out, one after the
    // other, each both feeding the watchdog and reading the state.
    assert_eq!(b.device.stats().watchdog_expiries, 0);
    let slow = b.sent_between(slow_from, slow_to);
    assert!(slow.len() > 5 && slow.iter().all(|c| c == "RC"), "{slow:?}");
    assert!(b.device.executed_functions().is_empty(), "RS after the end of the motion");
}

#[test]
fn a_request_that_would_let_the_watchdog_expire_waits_for_room_and_is_refused_without_a_lapse() {
    let mut b = Bench::opened(scp11(), SimConfig::default());
    let moving = b.start(move_a1(800));
    b.run_until(Duration::from_secs(5), |b| b.device_saw("F1 started").is_some());
    b.line.one_way = Duration::from_millis(150);
    b.run_for(Duration::from_secs(1));
    // Another caller reads a position: with 300 ms round trips its reply would come back after the next RC
    // must have gone out (the RC before it and the one after it would reach the unit 600 ms apart).
    let asked = b.now;
    let read = b.start(Op::Request(PreparedRequest::new(&Request::Get { index: 0x0011 }).unwrap()));
    let result = b.wait_done(read);
    assert!(matches!(result, Err(Error::NoRoom { .. })), "{result:?}");
    assert!(b.now - asked >= Duration::from_secs(1) && b.now - asked < Duration::from_millis(1400));
    assert!(!b.sent_between(asked, b.now).iter().any(|c| c == "RG"), "the read was never sent");
    b.line.one_way = Duration::ZERO;
    let Output::Move(report) = b.wait_done(moving).unwrap() else { panic!() };
    assert_eq!(report.position_counts, PositionCounts(800));
    assert_eq!(b.device.stats().watchdog_expiries, 0);
    // On a healthy line the same read goes through.
    let read = b.start(Op::Request(PreparedRequest::new(&Request::Get { index: 0x0011 }).unwrap()));
    assert!(b.wait_done(read).is_ok());
}

#[test]
fn a_cancelled_move_sends_rs_at_once_and_reports_where_the_actuator_came_to_rest() {
    let mut b = Bench::opened(scp11(), SimConfig::default());
    let id = b.start(move_a1(800));
    b.run_until(Duration::from_secs(10), |b| b.device.position(a(1)).unwrap_or(0) > 100);
    let cancelled_at = b.now;
    b.session.cancel(id, b.now);
    let result = b.wait_done(id);
    let Err(Error::Cancelled { position_counts, .. }) = result else { panic!("{result:?}") };
    let rs = b.sent.iter().find(|(t, x)| *t >= cancelled_at && x.starts_with(b"RS")).unwrap();
    assert!(rs.0 - cancelled_at < Duration::from_millis(15), "RS {:?} after the cancel", rs.0 - cancelled_at);
    assert_eq!(&rs.1[..4], &[0x52, 0x53, 0x00, 0x00], "a fast stop of F1");
    assert!(!b.device.is_moving(a(1)));
    assert_eq!(Some(position_counts), b.device.position(a(1)).map(PositionCounts), "the position after the stop");
    assert!(b.session.started().is_empty());
}

#[test]
fn an_operation_cancelled_before_its_request_went_out_sends_nothing() {
    let mut b = Bench::opened(scp11(), SimConfig::default());
    let sent = b.sent.len();
    let id = b.start(move_a1(800));
    b.session.cancel(id, b.now);
    assert!(matches!(b.wait_done(id), Err(Error::CancelledBeforeMotion(_))));
    assert!(b.sent[sent..].iter().all(|(_, x)| !x.starts_with(b"RE") && !x.starts_with(b"RT")));
    assert!(b.device.executed_functions().is_empty());
}

#[test]
fn closing_stops_what_runs_then_sends_rs_for_every_re_and_ra() {
    let mut b = Bench::opened(scp11(), SimConfig::default());
    let re = Request::Execute { function: f(2).id(), params: [MotionDirection::Out.code(), 0xFF] };
    let started = b.start(Op::Request(PreparedRequest::new(&re).unwrap()));
    b.wait_done(started).unwrap();
    let moving = b.start(move_a1(800));
    b.run_until(Duration::from_secs(5), |b| b.device.is_moving(a(1)) && b.device.is_moving(a(2)));
    assert_eq!(b.session.started().iter().map(|f| f.id()).collect::<Vec<_>>(), [0, 1]);
    b.session.close(b.now);
    b.run_until(Duration::from_secs(5), |b| b.closed.is_some());
    assert!(b.closed.take().unwrap().is_ok());
    assert!(matches!(b.done.iter().find(|(i, _)| *i == moving), Some((_, Err(Error::Cancelled { .. })))));
    assert!(!b.device.any_moving());
    assert!(b.device.executed_functions().is_empty(), "every RE got its RS");
    assert_eq!(b.device.mode(), RemoteMode::Off, "RA");
    assert_eq!(b.sent.last().map(|(_, x)| x[..2].to_vec()), Some(b"RA".to_vec()));
    // Nothing starts after the close.
    let late = b.start(Op::Open);
    assert!(matches!(b.wait_done(late), Err(Error::Closed)));
}

#[test]
fn a_session_the_unit_ended_is_reported_and_never_opened_again_by_itself() {
    let mut b = Bench::opened(Config::default(), SimConfig::default());
    b.cut = true;
    b.run_for(Duration::from_secs(1));
    b.cut = false;
    assert_eq!(b.device.mode(), RemoteMode::Locked);
    let read = b.start(Op::Request(PreparedRequest::new(&Request::Get { index: 0x0011 }).unwrap()));
    let result = b.wait_done(read);
    assert!(matches!(&result, Err(Error::RemoteEnded(t)) if t.contains("Safety_ID 0")), "{result:?}");
    b.run_for(Duration::from_secs(3));
    assert_eq!(b.sent.iter().filter(|(_, x)| x.starts_with(b"RO")).count(), 1, "only the RO of the start");
    assert_eq!(b.device.mode(), RemoteMode::Locked);
    // The caller decides to go on.
    let reopen = b.start(Op::Reopen);
    b.wait_done(reopen).unwrap();
    assert!(matches!(b.device.mode(), RemoteMode::Active(_)));
}

#[test]
fn a_lost_reply_is_asked_again_after_silence_with_zeros_first_and_the_late_reply_is_dropped() {
    let mut b = Bench::opened(Config::default(), SimConfig::default());
    b.run_for(Duration::from_millis(50));
    // The unit's reply is held back 300 ms: the RG goes out again after 150 ms of silence, behind the zeros
    // that complete a telegram the unit may hold half-received.
    b.hold_next_reply = Some(Duration::from_millis(300));
    let read = b.start(Op::Request(PreparedRequest::new(&Request::Get { index: 0x0011 }).unwrap()));
    let Output::Data(Some(data)) = b.wait_done(read).unwrap() else { panic!() };
    assert_eq!(data, 0i32.to_le_bytes());
    let stats = b.session.stats();
    assert_eq!((stats.retries, stats.flushes), (1, 1));
    assert!(b.sent.iter().any(|(_, x)| x.len() == FLUSH_LEN && x.iter().all(|z| *z == 0)));
    // The reply to the second sending does not answer the next read.
    let read = b.start(Op::Request(PreparedRequest::new(&Request::Get { index: 0x0171 }).unwrap()));
    let Output::Data(Some(status)) = b.wait_done(read).unwrap() else { panic!() };
    assert_eq!(status.len(), 1);
    assert_eq!(b.device.stats().watchdog_expiries, 0);
}

#[test]
fn a_broken_port_fails_what_runs_and_a_reconnect_reopens_it_and_stops_what_was_started() {
    let mut b = Bench::opened(scp11(), SimConfig::default());
    let moving = b.start(move_a1(800));
    b.run_until(Duration::from_secs(5), |b| b.device.is_moving(a(1)));
    b.session.handle_link_error(
        motionlink_link::LinkError::Disconnected { port: "bench".into(), reason: "cable".into() },
        b.now,
    );
    b.to_device.clear();
    b.to_host.clear();
    let result = b.wait_done(moving);
    let Err(Error::StopUnconfirmed { cause, .. }) = &result else { panic!("{result:?}") };
    assert!(matches!(**cause, Error::SessionLost(_)));
    assert!(!b.session.is_open());
    // The unit's own watchdog stops the drive.
    b.run_for(Duration::from_secs(1));
    assert!(!b.device.any_moving());
    let reconnect = b.start(Op::Reconnect);
    b.wait_done(reconnect).unwrap();
    assert_eq!(b.reopens, 1);
    assert!(b.session.is_open());
    assert!(b.device.executed_functions().is_empty(), "the RE of before got its RS");
    assert_eq!(b.session.stats().reconnects, 1);
}

#[test]
fn a_write_is_read_back_and_a_value_the_unit_refuses_is_a_refusal() {
    let mut b = Bench::opened(Config::default(), SimConfig::default());
    // Written and read back: RT, RG.
    let set = b.start(Op::Set { index: DataIndex(0x3011), data: vec![40, 0], verify: true });
    b.wait_done(set).unwrap();
    let last: Vec<String> =
        b.sent_between(Timestamp::ZERO, b.now).into_iter().filter(|c| c != "RC").rev().take(2).collect();
    assert_eq!(last, ["RG", "RT"]);
    let set = b.start(Op::Set { index: DataIndex(0x3011), data: vec![101, 0], verify: true });
    assert!(matches!(b.wait_done(set), Err(Error::Refused { .. })), "101 % is refused by the unit (PDE)");
}

#[test]
fn a_run_is_watched_through_the_keepalive_until_its_motion_ends_and_then_stopped() {
    let mut b = Bench::opened(Config::default(), SimConfig::default());
    let id = b.start(Op::Run(RunSpec { action: RunAction::Motion(f(1), MotionDirection::Out), limit: None }));
    let Output::Run(report) = b.wait_done(id).unwrap() else { panic!() };
    assert_eq!(report.rest, [(a(1), PositionCounts(865)), (a(2), PositionCounts(0))], "F1 ran to the Out end");
    let started = b.device_saw("F1 started").unwrap();
    let rest = b.device_saw("A1 at rest").unwrap();
    let during = b.sent_between(started, rest);
    assert!(during.len() > 100 && during.iter().all(|c| c == "RC"), "{during:?}");
    assert!(b.device.executed_functions().is_empty(), "RS after the run");
    assert_eq!(b.device.stats().watchdog_expiries, 0);
}

#[test]
fn a_cancelled_run_stops_its_function_and_says_where_the_actuators_came_to_rest() {
    let mut b = Bench::opened(Config::default(), SimConfig::default());
    let id = b.start(Op::Run(RunSpec { action: RunAction::Motion(f(2), MotionDirection::Out), limit: None }));
    b.run_until(Duration::from_secs(5), |b| b.device.position(a(2)).unwrap_or(0) > 50);
    b.session.cancel(id, b.now);
    let result = b.wait_done(id);
    let Err(Error::RunCancelled { rest, .. }) = result else { panic!("{result:?}") };
    assert!(!b.device.is_moving(a(2)));
    assert_eq!(rest[1], (a(2), PositionCounts(b.device.position(a(2)).unwrap())));
    assert!(b.session.started().is_empty());
}

/// A run no actuator was seen to carry out says so once its start grace has passed; a run cancelled before
/// then (the motion bit of a `late-motion-bit` unit not up yet) says nothing of it: the grace had not passed.
#[test]
fn a_run_cancelled_within_its_start_grace_does_not_say_that_nothing_moved() {
    let mut config = SimConfig::default();
    config.add_variants([motionlink_scu::Variant::LateMotionBit]);
    let mut b = Bench::opened(Config::default(), config);
    let id = b.start(Op::Run(RunSpec { action: RunAction::Motion(f(1), MotionDirection::Out), limit: None }));
    let at = b.now;
    b.run_until(Duration::from_secs(5), |b| b.now.saturating_since(at) >= Duration::from_millis(200));
    b.session.cancel(id, b.now);
    let result = b.wait_done(id);
    let Err(Error::RunCancelled { verified, not_verifiable, .. }) = result else { panic!("{result:?}") };
    assert!(verified && not_verifiable.is_empty(), "{not_verifiable:?}");
}

#[test]
fn a_unit_slow_to_answer_ro_does_not_hold_back_the_requests_after_it() {
    let mut b = Bench::unopened(Config::default(), SimConfig::default());
    // A unit asleep after a long silence answers the first RO after 1.5 s.
    b.hold_next_reply = Some(Duration::from_millis(1500));
    let open = b.start(Op::Open);
    b.wait_done(open).unwrap();
    assert!(b.session.round_trip() >= Duration::from_millis(1000), "{:?}", b.session.round_trip());
    // The next read goes out at once: what the watchdog's schedule counts is the round trip of ordinary
    // exchanges, not that of the RO.
    let asked = b.now;
    let read = b.start(Op::Request(PreparedRequest::new(&Request::Get { index: 0x0011 }).unwrap()));
    b.wait_done(read).unwrap();
    assert!(b.now - asked < Duration::from_millis(20), "{:?}", b.now - asked);
}

/// A cancel while the move's RE awaits its acknowledgement, whose reply was lost: the RE is not sent again
/// (a repeat could start the motion being stopped) and the RS goes out when that one sending goes
/// unanswered, not after the RE's whole timeout of repetitions.
#[test]
fn a_cancel_while_an_unanswered_re_is_repeated_sends_no_more_re_and_stops_sooner() {
    for line_comes_back in [true, false] {
        let mut b = Bench::opened(scp11(), SimConfig::default());
        let id = b.start(move_a1(800));
        b.run_until(Duration::from_secs(5), |b| b.sent.iter().any(|(_, x)| x.starts_with(b"RE")));
        // The unit's answer to the RE is lost (also if it is on its way already); the caller gives up at once.
        b.deaf = true;
        b.to_host.clear();
        let cancelled_at = b.now;
        b.session.cancel(id, b.now);
        b.run_until(Duration::from_secs(5), |b| b.device_saw("F1 started").is_some());
        b.deaf = !line_comes_back;
        let result = b.wait_done_within(id, Duration::from_secs(10));
        let after: Vec<_> = b.sent.iter().filter(|(t, _)| *t > cancelled_at).collect();
        assert!(
            after.iter().all(|(_, x)| !x.starts_with(b"RE")),
            "an RE after the cancel: {:?}",
            b.sent_between(cancelled_at, b.now)
        );
        let rs = after.iter().find(|(_, x)| x.starts_with(b"RS")).expect("an RS");
        let waited = rs.0 - cancelled_at;
        // One reply window (150 ms, or twice the round trip), not the RE's second of repetitions.
        assert!(waited < Duration::from_millis(400), "RS {waited:?} after the cancel");
        if line_comes_back {
            // The cancel's error (where the actuator came to rest), not the lost reply's.
            let Err(Error::Cancelled { position_counts, .. }) = result else { panic!("{result:?}") };
            assert!(!b.device.is_moving(a(1)));
            assert_eq!(Some(position_counts), b.device.position(a(1)).map(PositionCounts));
        } else {
            let e = result.unwrap_err();
            assert!(motionlink_link::error::Classify::stop_unconfirmed(&e), "{e}");
        }
    }
}

/// A unit that also acknowledges one write to an index the data list does not have (as a firmware with
/// entries of its own might); everything else goes to the emulated unit.
struct AcksAnUnlistedWrite {
    unit: Serial<Emulator>,
    write: Vec<u8>,
}

impl Device for AcksAnUnlistedWrite {
    fn receive(&mut self, now: Timestamp, telegram: &Telegram, out: &mut Vec<Telegram>) {
        if **telegram == self.write[..] {
            let ack = Reply::status_only(Command::Transfer, Status::Ack);
            out.push(Telegram::Bytes(reply_to_vec(&ack).unwrap()));
        } else {
            self.unit.receive(now, telegram, out);
        }
    }
    fn advance(&mut self, now: Timestamp, out: &mut Vec<Telegram>) {
        self.unit.advance(now, out);
    }
    fn next_wakeup(&self) -> Option<Timestamp> {
        self.unit.next_wakeup()
    }
    fn take_events(&mut self) -> Vec<String> {
        self.unit.take_events()
    }
}

#[test]
fn a_write_to_an_index_outside_the_data_list_says_it_was_not_read_back() {
    // The unit acknowledges RT 0x7F00; the session cannot read it back (nothing says what it holds): the
    // report says so, not `verified` (was: verified with nothing read).
    let write = request_to_vec(&Request::Transfer { index: 0x7F00, data: &[1, 2] }).unwrap();
    let unit = AcksAnUnlistedWrite { unit: Serial(Emulator::new(SimConfig::default()).unwrap()), write };
    let mut b = Wired::new(Session::new(Config::default(), Timestamp::ZERO).unwrap(), unit, Line::baud(38_400, 10));
    let open = b.start(Op::Open);
    b.wait_done(open).unwrap();
    let set = b.start(Op::Set { index: DataIndex(0x7F00), data: vec![1, 2], verify: true });
    match b.wait_done(set).unwrap() {
        Output::Written(report) => {
            assert!(!report.verified, "{report:?}");
            assert!(report.not_verifiable[0].contains("not in the data list"), "{report:?}");
        }
        other => panic!("{other:?}"),
    }
}
