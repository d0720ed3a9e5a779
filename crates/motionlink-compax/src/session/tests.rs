//! The session wired straight to the emulator: no link, no thread, no clock but a number this test
//! advances. Each byte takes its character time on the line; the emulator answers when the whole telegram
//! has arrived, and its answer reaches the session byte time by byte time.

use std::time::Duration;

use motionlink_link::error::{Classify, ErrorClass};
use motionlink_link::session::{OpId, Session as _};
use motionlink_link::Timestamp;
use motionlink_testkit::wired::{Line, Serial, Telegram, Wired};

use super::*;
use crate::error::StopOutcome;
use crate::model::{Command, ParamId, Position, S17Flag, SpeedPercent, StatusId, StatusValue};
use crate::sim::{Emulator, SimConfig};
use crate::wire::Mode;

/// A session, an emulated bus, and the line between them (the shared harness): each byte takes its character
/// time, the drives answer when the whole telegram has arrived, and their answer reaches the session byte
/// by byte.
type Bench = Wired<Session, Serial<Emulator>>;

fn a(n: u8) -> Address {
    Address::drive(n).unwrap()
}

fn pos(v: f64) -> Position {
    Position::new(v).unwrap()
}

/// What these tests ask of the harness.
trait CompaxBench {
    /// A session with drives at `addrs`, P196 = `p196`, at `baud`.
    fn bus(addrs: &[u8], p196: u32, baud: u32) -> Self;
    /// The same, the session's settings changed by `configure`.
    fn with(addrs: &[u8], p196: u32, baud: u32, configure: impl FnOnce(&mut Config)) -> Self;
    /// Runs until `id` ends (at most ten minutes of bus time).
    fn finish(&mut self, id: OpId) -> Result<Output>;
    /// Starts `op` and runs it to its end.
    fn run(&mut self, op: Op) -> Result<Output>;
    /// Every telegram the session sent, as text.
    fn sent_text(&self) -> Vec<String>;
    /// Drive `n` of the emulated bus.
    fn drive(&self, n: u8) -> &crate::sim::Drive;
}

impl CompaxBench for Bench {
    fn bus(addrs: &[u8], p196: u32, baud: u32) -> Bench {
        Bench::with(addrs, p196, baud, |_| {})
    }

    fn with(addrs: &[u8], p196: u32, baud: u32, configure: impl FnOnce(&mut Config)) -> Bench {
        let mut cfg = Config::new(Mode::from_p196(p196).unwrap(), baud);
        configure(&mut cfg);
        let sim = SimConfig::bus(addrs, p196, baud).with_param(ParamId::new(3).unwrap(), 0.0);
        let line = Line { byte_time: cfg.char_time(), ..Line::instant() }.bytewise();
        Wired::new(Session::new(cfg, Timestamp::ZERO), Serial(Emulator::new(sim).unwrap()), line)
    }

    fn finish(&mut self, id: OpId) -> Result<Output> {
        self.wait_done_within(id, Duration::from_secs(600))
    }

    fn run(&mut self, op: Op) -> Result<Output> {
        self.run_op(op)
    }

    fn sent_text(&self) -> Vec<String> {
        self.sent.iter().map(|(_, t)| t.text()).collect()
    }

    fn drive(&self, n: u8) -> &crate::sim::Drive {
        self.device.drive(n).unwrap()
    }
}

fn to(v: f64) -> MoveRequest {
    MoveRequest::new(MoveTarget::Absolute(pos(v)))
}

#[test]
fn a_checked_move_is_checked_sent_read_back_polled_and_verified() {
    let mut b = Bench::bus(&[1], 0, 9600);
    let mut req = to(12.5);
    req.speed = Some(SpeedPercent::new(50.0).unwrap());
    let id = b.session.start(Op::MoveTo(a(1), req), b.now);
    let Ok(Output::Moved(report)) = b.finish(id) else { panic!("{:?}", b.sent_text()) };
    assert_eq!((report.start, report.target, report.reached), (pos(0.0), pos(12.5), pos(12.5)));
    assert!(report.verified && report.not_verifiable.is_empty(), "{report:?}");
    // How the drive echoes is found out first (S1 with '?', which it does not execute); the move is stored
    // with its echo (`,?`), executed (`!`) once the echo is the telegram sent, and its target read back.
    assert_eq!(
        b.sent_text()[..8],
        ["1S16\r", "1S17\r", "1S1\r", "1S1?\r", "1SPEED 50\r", "1POSA 12.5,?\r", "1!\r", "1S2\r"]
    );
    assert_eq!(b.session.echo_form(a(1)), Some(crate::session::EchoForm::Full));
    assert_eq!(b.sent_text().last().unwrap(), "1S1\r");
    // 12.5 units at 50 units/s: about a quarter of a second, polled every 50 ms (S17 then S1).
    let polls = b.sent_text().iter().filter(|f| *f == "1S17\r").count();
    assert!((4..=8).contains(&polls), "{polls} polls: {:?}", b.sent_text());
    let positions: Vec<f64> = b
        .progress
        .iter()
        .filter_map(|(i, p)| match p {
            Progress::Position { drive, position } if *i == id && *drive == a(1) => Some(position.units()),
            _ => None,
        })
        .collect();
    assert!(positions.len() >= 3 && positions.windows(2).all(|w| w[0] <= w[1]), "{positions:?}");
    assert!(b.session.started().is_empty());
}

#[test]
fn e72_is_answered_by_sending_the_telegram_again() {
    let mut b = Bench::bus(&[1], 8, 9600);
    // The second byte of "1S1\r" + BCC: the drive's BCC check fails.
    b.corrupt_to_device = Some((1, 0x01));
    let r = b.run(Op::ReadStatus(a(1), StatusId::ACTUAL_POSITION)).unwrap();
    assert_eq!(r, Output::Status(StatusValue::Position(pos(0.0))));
    assert_eq!(b.sent_text().len(), 2);
    assert_eq!(b.sent_text()[0], b.sent_text()[1], "the same telegram again");
}

#[test]
fn a_relative_move_whose_reply_is_lost_is_checked_through_s2_not_sent_again() {
    let mut b = Bench::bus(&[1], 0, 9600);
    // The S2 read before the move is answered ("S002: 0.000\r\n>", 14 bytes); the move's
    // acknowledgement ("\r\n>") is lost.
    let at = b.to_host_count;
    b.drop_to_host = (at + 14..at + 17).collect();
    let id = b.session.start(Op::Move(a(1), Command::PosR(pos(10.0)), MoveOptions::default()), b.now);
    b.finish(id).unwrap();
    assert_eq!(b.sent_text().iter().filter(|f| f.starts_with("1POSR")).count(), 1, "{:?}", b.sent_text());
    assert_eq!(b.sent_text(), ["1S2\r", "1POSR 10\r", "1S2\r"], "S2 read after the lost reply");
    b.run(Op::Wait(vec![a(1)], None)).unwrap();
    assert_eq!(b.drive(1).position(), 10.0, "moved once");
}

#[test]
fn a_position_message_ends_the_wait_without_polling() {
    let mut b = Bench::bus(&[3], 64 + 8, 9600);
    b.run(Op::Move(a(3), Command::PosA(pos(5.0)), MoveOptions { binary: false, message: true })).unwrap();
    let before = b.sent_text().len();
    let id = b.session.start(Op::Wait(vec![a(3)], None), b.now);
    b.finish(id).unwrap();
    assert_eq!(b.sent_text().len(), before, "no status read: the '$' ended the wait");
    assert!(b.progress.iter().all(|(i, _)| *i != id));
    assert_eq!(b.drive(3).position(), 5.0);
}

#[test]
fn a_cancelled_wait_switches_the_axis_off_and_confirms_it() {
    let mut b = Bench::bus(&[1, 2], 0, 9600);
    b.run(Op::Move(a(1), Command::PosA(pos(1000.0)), MoveOptions::default())).unwrap();
    let id = b.session.start(Op::Wait(vec![a(1)], None), b.now);
    b.run_for(Duration::from_millis(500));
    let cancelled_at = b.now;
    b.session.cancel(id, b.now);
    let e = b.finish(id).unwrap_err();
    assert!(matches!(e, Error::Cancelled { .. }), "{e}");
    assert_eq!(e.stop_report().unwrap().drives, [(a(1), StopOutcome::SwitchedOff)]);
    let sent = b.sent_text();
    let tail: Vec<&str> = sent.iter().rev().take(3).rev().map(String::as_str).collect();
    assert_eq!(tail, ["1S17\r", "1OUTPUT O0=0\r", "1S17\r"]);
    assert!(!b.drive(1).is_moving() && b.drive(1).o0() == 0);
    // At 9600 baud the three exchanges take about 60 ms (a poll may be on the line when the cancel comes).
    assert!(b.now - cancelled_at < Duration::from_millis(100), "{:?}", b.now - cancelled_at);
    assert!(!b.sent_text().iter().any(|f| f.starts_with('2')), "drive 2 is not this wait's");
}

#[test]
fn a_move_cancelled_before_it_is_sent_is_never_sent() {
    let mut b = Bench::bus(&[1], 0, 9600);
    // A read is on the line; the move waits its turn, and is cancelled meanwhile.
    let read = b.session.start(Op::ReadStatus(a(1), StatusId::ACTUAL_POSITION), b.now);
    assert!(b.step(None), "the read goes out");
    let mv = b.session.start(Op::Move(a(1), Command::PosA(pos(50.0)), MoveOptions::default()), b.now);
    b.session.cancel(mv, b.now);
    assert!(matches!(b.finish(mv), Err(Error::CancelledBeforeMotion)));
    b.finish(read).unwrap();
    assert!(!b.sent_text().iter().any(|f| f.contains("POSA")), "{:?}", b.sent_text());
    assert!(b.session.started().is_empty());
    b.run_for(Duration::from_millis(200));
    assert!(!b.drive(1).is_moving());
}

#[test]
fn a_read_runs_between_the_polls_of_a_wait() {
    let mut b = Bench::bus(&[1, 5], 0, 115_200);
    b.run(Op::Move(a(1), Command::PosA(pos(100.0)), MoveOptions::default())).unwrap();
    let wait = b.session.start(Op::Wait(vec![a(1)], None), b.now);
    b.run_for(Duration::from_millis(120));
    let read = b.session.start(Op::ReadStatus(a(5), StatusId::ACTUAL_POSITION), b.now);
    let t0 = b.now;
    assert_eq!(b.finish(read).unwrap(), Output::Status(StatusValue::Position(pos(0.0))));
    assert!(b.now - t0 < Duration::from_millis(5), "not held up by the wait: {:?}", b.now - t0);
    assert!(b.take_done(wait).is_none(), "the wait goes on");
    b.finish(wait).unwrap();
    assert_eq!(b.drive(1).position(), 100.0);
}

#[test]
fn closing_stops_every_drive_the_session_started_and_reports_it() {
    let mut b = Bench::bus(&[1, 5, 7], 0, 9600);
    b.run(Op::Move(a(1), Command::PosA(pos(1000.0)), MoveOptions::default())).unwrap();
    b.run(Op::Move(a(5), Command::PosA(pos(1.0)), MoveOptions::default())).unwrap();
    b.run_for(Duration::from_millis(200));
    let w = b.session.start(Op::Wait(vec![a(1)], None), b.now);
    b.session.close(b.now);
    let late = b.session.start(Op::ReadStatus(a(1), StatusId::ACTUAL_POSITION), b.now);
    while b.closed.is_none() {
        assert!(b.step(None), "the close sequence ends");
        b.collect();
    }
    assert!(matches!(b.take_done(late), Some(Err(Error::Closed))));
    assert!(matches!(b.take_done(w), Some(Err(_))));
    assert!(b.closed.take().unwrap().is_ok());
    let report = lock(&b.session.close_report()).clone().unwrap();
    assert_eq!(report.drives, [(a(1), StopOutcome::SwitchedOff), (a(5), StopOutcome::AtRest)]);
    assert!(!b.drive(1).is_moving() && b.drive(5).o0() == 1, "drive 5 had stopped: left switched on");
    assert!(!b.sent_text().iter().any(|f| f.starts_with('7')));
    assert!(b.session.is_idle());
}

#[test]
fn closing_on_a_dead_line_says_the_stop_was_not_confirmed() {
    let mut b = Bench::bus(&[1], 0, 9600);
    b.run(Op::Move(a(1), Command::PosA(pos(1000.0)), MoveOptions::default())).unwrap();
    b.deaf = true;
    b.session.close(b.now);
    while b.closed.is_none() {
        assert!(b.step(None));
        b.collect();
    }
    let Some(Err(e)) = b.closed.take() else { panic!("confirmed on a dead line?") };
    assert!(e.to_string().contains("NOT confirmed") && e.to_string().contains("may still be moving"), "{e}");
    assert_eq!(e.stop_report().unwrap().unconfirmed(), [a(1)]);
}

#[test]
fn a_corrupted_parameter_write_is_caught_by_the_read_back() {
    let mut b = Bench::bus(&[1], 0, 9600);
    // "1P003=-1055.88\r": the last '8' (byte 13) becomes '9'.
    b.corrupt_to_device = Some((13, 0x01));
    let e = b.run(Op::WriteParam(a(1), ParamId::new(3).unwrap(), -1055.88)).unwrap_err();
    assert!(matches!(e, Error::ReadBack { read, .. } if read == -1055.89), "{e}");
}

/// A drive that keeps P003 to three decimals: it answers a read of P003 with the value it was given,
/// rounded to 0.001 (the emulator keeps any value).
struct ThreeDecimals(Serial<Emulator>);

impl motionlink_testkit::wired::Device for ThreeDecimals {
    fn receive(&mut self, now: Timestamp, telegram: &Telegram, out: &mut Vec<Telegram>) {
        let mut answers = Vec::new();
        self.0.receive(now, telegram, &mut answers);
        for t in answers {
            let text = t.text();
            let rounded = text.strip_prefix("P003=").and_then(|r| r.strip_suffix("\r\n>")).map(|v| {
                let v: f64 = v.parse().unwrap();
                Telegram::Bytes(format!("P003={v:.3}\r\n>").into_bytes())
            });
            out.push(rounded.unwrap_or(t));
        }
    }
    fn advance(&mut self, now: Timestamp, out: &mut Vec<Telegram>) {
        self.0.advance(now, out);
    }
    fn next_wakeup(&self) -> Option<Timestamp> {
        self.0.next_wakeup()
    }
    fn take_events(&mut self) -> Vec<String> {
        self.0.take_events()
    }
}

/// A value the drive holds only to its own step reads back rounded: said as that (the step the drive
/// answers with), not as a corrupted telegram; a value off by more than the rounding still is one.
#[test]
fn a_parameter_the_drive_keeps_to_fewer_decimals_reads_back_rounded_not_corrupted() {
    let cfg = Config::new(Mode::default(), 9600);
    let sim = SimConfig::bus(&[1], 0, 9600).with_param(ParamId::new(3).unwrap(), 0.0);
    let line = Line { byte_time: cfg.char_time(), ..Line::instant() }.bytewise();
    let device = ThreeDecimals(Serial(Emulator::new(sim).unwrap()));
    let mut b = Wired::new(Session::new(cfg, Timestamp::ZERO), device, line);
    let p3 = ParamId::new(3).unwrap();
    b.run_op(Op::WriteParam(a(1), p3, 2.5)).unwrap();
    let e = b.run_op(Op::WriteParam(a(1), p3, 1.0004)).unwrap_err();
    assert!(matches!(e, Error::Rounded { read, decimals: 3, .. } if read == 1.0), "{e}");
    assert_eq!(
        e.to_string(),
        "drive 1: P003 reads back 1 after 1.0004 was written: the drive keeps P003 in steps of 0.001 (the \
         decimals it answers with) and holds 1, the step it could store; write a value of at most 3 decimals"
    );
    assert!(!e.to_string().contains("corrupt"), "{e}");
    assert_eq!(e.class(), ErrorClass::Device);
    // A negative value too.
    let e = b.run_op(Op::WriteParam(a(1), p3, -7.0009)).unwrap_err();
    assert!(matches!(e, Error::Rounded { .. }), "{e}");
    // "1P003=-1055.88\r": the last '8' (byte 13) becomes '9': the drive holds -1055.89, which no rounding of
    // -1055.88 to its three decimals gives: a corrupted telegram.
    b.corrupt_to_device = Some((b.to_device_count + 13, 0x01));
    let e = b.run_op(Op::WriteParam(a(1), p3, -1055.88)).unwrap_err();
    assert!(matches!(e, Error::ReadBack { read, .. } if read == -1055.89), "{e}");
}

/// A checked move to a drive still executing a command (S17) is not sent, and the error says so: the
/// drive reported no error code (it answered S17 normally), so none is made up.
#[test]
fn a_checked_move_to_a_drive_still_moving_is_not_sent_and_no_code_is_made_up() {
    let mut b = Bench::bus(&[1], 0, 9600);
    b.run(Op::Move(a(1), Command::PosA(pos(1000.0)), MoveOptions::default())).unwrap();
    let before = b.sent_text().len();
    let e = b.run(Op::MoveTo(a(1), to(10.0))).unwrap_err();
    assert!(matches!(e, Error::StillMoving { address } if address == a(1)), "{e}");
    assert_eq!(
        e.to_string(),
        "drive 1 is still executing a command (S17 shows a command active, such as a positioning that runs): \
         the move was not sent; wait until it has ended, or stop it"
    );
    assert_eq!((e.device_code(), e.reported()), (None, None), "the drive reported no code");
    assert_eq!(e.class(), ErrorClass::Device);
    assert_eq!(b.sent_text()[before..], ["1S16\r", "1S17\r"], "S16 and S17 read, nothing sent to move");
    assert!(!b.device_events.iter().any(|(_, t)| t.contains("E92")), "{:?}", b.device_events);
}

/// A scan's warning names the drive once (it said "drive 3: drive 3: ...").
#[test]
fn a_scan_names_the_drive_of_an_error_once() {
    let e = Error::Refused { address: a(3), command: "S1".into(), code: crate::model::ErrorCode(90) };
    assert_eq!(super::ops::scan_warning(a(3), &e), e.to_string());
    assert!(e.to_string().starts_with("drive 3: \"S1\" refused with E90"), "{e}");
    let other = Error::Broadcast("x");
    assert!(super::ops::scan_warning(a(3), &other).starts_with("drive 3: address 32"));
}

/// A scan by a host without a BCC of a bus whose drives check one: the one drive answers E72 (late, while
/// the next address is asked, the only time it is addressed), and no drive it does not have answers.
#[test]
fn a_scan_without_the_drives_bcc_hears_e72_only_where_the_one_drive_is_addressed() {
    let cfg = Config { reply_timeout: Duration::from_millis(20), ..Config::new(Mode::default(), 115_200) };
    let sim = SimConfig::bus(&[1], 8, 115_200);
    let line = Line { byte_time: cfg.char_time(), ..Line::instant() }.bytewise();
    let mut b = Wired::new(Session::new(cfg, Timestamp::ZERO), Serial(Emulator::new(sim).unwrap()), line);
    let Ok(Output::Found(found)) = b.run_op(Op::Scan(1..=31)) else { panic!() };
    assert!(found.is_empty());
    let e72: Vec<&String> = b.device_events.iter().map(|(_, t)| t).filter(|t| t.contains("E72")).collect();
    // "1S1\r" with '2' taken for its BCC; then the "1S1\r" inside "11S1\r12S1\r" and "21S1\r22S1\r".
    assert_eq!(e72.len(), 3, "{e72:?}");
    assert!(e72.iter().all(|t| t.starts_with("drive 1 error E72")), "{e72:?}");
    let warning = super::ops::bcc_mismatch_warning(&Mode::default(), &[a(2), a(12), a(22)]);
    assert!(
        warning.starts_with(
            "E72 (BCC error) answered S1 at addresses 2, 12, 22, although this client sends \
                                 no BCC (P196 0 has no valence 8)"
        ),
        "{warning}"
    );
}

#[test]
fn a_scan_asks_each_address_once_and_a_watch_reports_until_cancelled() {
    let mut b = Bench::with(&[2, 9], 0, 115_200, |c| c.reply_timeout = Duration::from_millis(20));
    let Ok(Output::Found(found)) = b.run(Op::Scan(1..=10)) else { panic!() };
    assert_eq!(found.iter().map(|(a, _)| a.get()).collect::<Vec<_>>(), [2, 9]);
    assert_eq!(b.sent_text().len(), 10, "once each: {:?}", b.sent_text());
    // Each address announced before it is asked, with how far the scan has come.
    let announced: Vec<(u8, usize, usize)> = b
        .progress
        .iter()
        .filter_map(|(_, p)| match p {
            Progress::Scan { drive, index, of } => Some((drive.get(), *index, *of)),
            _ => None,
        })
        .collect();
    assert_eq!(announced, (1..=10).map(|d| (d, usize::from(d) - 1, 10)).collect::<Vec<_>>());
    let id = b.session.start(Op::Watch(a(2), Duration::from_millis(100)), b.now);
    b.run_for(Duration::from_millis(1000));
    b.session.cancel(id, b.now);
    assert_eq!(b.finish(id).unwrap(), Output::Done);
    let samples: Vec<&WatchSample> = b
        .progress
        .iter()
        .filter_map(|(i, p)| match p {
            Progress::Watch(s) if *i == id => Some(s),
            _ => None,
        })
        .collect();
    assert!((9..=11).contains(&samples.len()), "one every 100 ms: {}", samples.len());
    assert!(samples.iter().all(|s| !s.moving() && s.s17.contains(S17Flag::Run)));
}

#[test]
fn a_synchronous_start_stores_then_executes_with_one_broadcast() {
    let mut b = Bench::bus(&[1, 5], 0, 19_200);
    let moves = vec![(a(1), Command::PosA(pos(20.0))), (a(5), Command::PosR(pos(-20.0)))];
    b.run(Op::SyncStart(moves, false)).unwrap();
    assert_eq!(b.sent_text(), ["1POSA 20,\r", "5POSR -20,\r", "32!\r"]);
    assert_eq!(b.session.started(), [a(1), a(5)]);
    b.run(Op::Wait(vec![a(1), a(5)], None)).unwrap();
    assert_eq!((b.drive(1).position(), b.drive(5).position()), (20.0, -20.0));
}

#[test]
fn a_stop_of_drives_the_session_did_not_start_switches_off_only_the_moving_one_and_confirms_it() {
    let mut b = Bench::bus(&[1, 5], 0, 9600);
    b.run(Op::Move(a(1), Command::PosA(pos(1000.0)), MoveOptions::default())).unwrap();
    // Handed over, as `move --no-wait` leaves it: no longer this session's to stop.
    b.session.release(&[a(1)]);
    b.run_for(Duration::from_millis(200));
    assert!(b.drive(1).is_moving());
    let Output::Stopped(report) = b.run(Op::StopIfMoving(vec![a(1), a(5)])).unwrap() else { panic!() };
    assert_eq!(report.drives, [(a(1), StopOutcome::SwitchedOff), (a(5), StopOutcome::AtRest)]);
    assert!(!b.drive(1).is_moving() && b.drive(1).o0() == 0, "drive 1 stopped by switching it off");
    assert_eq!(b.drive(5).o0(), 1, "drive 5 was at rest: left switched on");
    assert!(
        b.sent_text().iter().any(|f| f.starts_with("1OUTPUT O0=0"))
            && !b.sent_text().iter().any(|f| f.starts_with("5OUTPUT"))
    );
    let json = serde_json::to_value(&report).unwrap();
    assert_eq!(
        json,
        serde_json::json!({"drives": [{"drive": 1, "outcome": "switched_off"}, {"drive": 5, "outcome": "at_rest"}],
                           "confirmed": true})
    );
    assert!(matches!(b.run(Op::StopIfMoving(vec![Address::BROADCAST])), Err(Error::Broadcast(_))));
}

/// Cancels `id` while the reply to the telegram just sent is lost (also if on its way already); the line
/// carries again 50 ms later, for the stop. When the cancel came.
fn cancel_with_the_reply_lost(b: &mut Bench, id: OpId) -> Timestamp {
    b.deaf = true;
    b.to_host.clear();
    let cancelled_at = b.now;
    b.session.cancel(id, b.now);
    b.run_for(Duration::from_millis(50));
    b.deaf = false;
    cancelled_at
}

/// A cancel while a poll of the wait awaits a reply that was lost: the poll is not sent again (its retries
/// would hold the stop back by up to three more reply timeouts, and a COMPAX drive has no watchdog), so the
/// stop goes out once that one sending went unanswered, and the error is the cancel's.
#[test]
fn a_cancel_while_a_poll_is_unanswered_sends_the_stop_after_one_reply_timeout() {
    let mut b = Bench::bus(&[1], 0, 9600);
    b.run(Op::Move(a(1), Command::PosA(pos(1000.0)), MoveOptions::default())).unwrap();
    let id = b.session.start(Op::Wait(vec![a(1)], None), b.now);
    b.run_for(Duration::from_millis(300));
    let from = b.now;
    b.run_until(Duration::from_secs(5), |b| b.sent.last().is_some_and(|(t, x)| *t > from && x.text() == "1S17\r"));
    let cancelled_at = cancel_with_the_reply_lost(&mut b, id);
    let e = b.finish(id).unwrap_err();
    assert!(matches!(e, Error::Cancelled { .. }), "{e}");
    assert_eq!(e.stop_report().unwrap().drives, [(a(1), StopOutcome::SwitchedOff)]);
    let after: Vec<(Timestamp, String)> =
        b.sent.iter().filter(|(t, _)| *t > cancelled_at).map(|(t, x)| (*t, x.text())).collect();
    let stop = after.iter().find(|(_, x)| x == "1OUTPUT O0=0\r").expect("the stop");
    // One reply timeout (200 ms) for the poll on the line, then the stop's own S17 (one attempt): not the
    // poll's three retries.
    assert!(
        stop.0 - cancelled_at < Duration::from_millis(300),
        "stop {:?} after the cancel: {after:?}",
        stop.0 - cancelled_at
    );
    let polls_before_stop = after.iter().take_while(|(_, x)| x != "1OUTPUT O0=0\r").count();
    assert_eq!(polls_before_stop, 1, "only the stop's S17 before it: {after:?}");
    assert!(!b.drive(1).is_moving() && b.drive(1).o0() == 0);
}

/// A cancel while the move's execute (`!`) awaits a reply that was lost: nothing is sent again, the drive
/// (which got the `!` and moves) is stopped, and the error is the cancel's, with the stop's report.
#[test]
fn a_cancel_while_the_move_s_execute_is_unanswered_stops_the_drive_and_says_cancelled() {
    let mut b = Bench::bus(&[1], 0, 9600);
    let id = b.session.start(Op::MoveTo(a(1), to(1000.0)), b.now);
    b.run_until(Duration::from_secs(5), |b| b.sent.last().is_some_and(|(_, x)| x.text() == "1!\r"));
    let cancelled_at = cancel_with_the_reply_lost(&mut b, id);
    let e = b.finish(id).unwrap_err();
    assert!(matches!(e, Error::Cancelled { .. }), "{e}");
    assert_eq!(e.stop_report().unwrap().drives, [(a(1), StopOutcome::SwitchedOff)]);
    let after: Vec<String> = b.sent.iter().filter(|(t, _)| *t > cancelled_at).map(|(_, x)| x.text()).collect();
    assert_eq!(after, ["1S17\r", "1OUTPUT O0=0\r", "1S17\r"], "the stop only");
    assert!(!b.drive(1).is_moving() && b.drive(1).o0() == 0);
}

#[test]
fn a_refused_move_forgets_only_its_own_drive_not_one_another_operation_set_moving_meanwhile() {
    let mut b = Bench::bus(&[1, 2], 0, 9600);
    b.run(Op::Stop(a(1))).unwrap();
    // Drive 1 is switched off and refuses its move; drive 2's move waits its turn behind it, counted as started.
    let refused = b.session.start(Op::Move(a(1), Command::PosA(pos(50.0)), MoveOptions::default()), b.now);
    let taken = b.session.start(Op::Move(a(2), Command::PosA(pos(500.0)), MoveOptions::default()), b.now);
    assert!(b.finish(refused).is_err());
    b.finish(taken).unwrap();
    assert!(b.drive(2).is_moving());
    assert_eq!(b.session.started(), [a(2)], "drive 2 moves: the session still knows it, and its close stops it");
}

/// A drive that sends XOFF before its first reply, and XON `pause` later.
struct XoffOnce {
    bus: Serial<Emulator>,
    pause: Duration,
    xoff_at: Option<Timestamp>,
    xon_due: Option<Timestamp>,
}

impl motionlink_testkit::wired::Device for XoffOnce {
    fn receive(&mut self, now: Timestamp, telegram: &Telegram, out: &mut Vec<Telegram>) {
        if self.xoff_at.is_none() {
            out.push(Telegram::Bytes(vec![crate::wire::XOFF]));
            self.xoff_at = Some(now);
            self.xon_due = Some(now + self.pause);
        }
        self.bus.receive(now, telegram, out);
    }
    fn advance(&mut self, now: Timestamp, out: &mut Vec<Telegram>) {
        self.bus.advance(now, out);
        if self.xon_due.is_some_and(|t| t <= now) {
            self.xon_due = None;
            out.push(Telegram::Bytes(vec![crate::wire::XON]));
        }
    }
    fn next_wakeup(&self) -> Option<Timestamp> {
        [self.bus.next_wakeup(), self.xon_due].into_iter().flatten().min()
    }
    fn take_events(&mut self) -> Vec<String> {
        self.bus.take_events()
    }
}

/// With XON/XOFF (P196 valence 1), a drive's XOFF holds the session's next telegram until its XON; a drive
/// that gives no XON within the reply timeout gets the telegram all the same (the manual gives no longest
/// pause, and a stop must not wait for ever).
#[test]
fn an_xoff_holds_the_next_telegram_until_the_xon_or_for_the_reply_timeout_at_most() {
    for (pause_ms, held_ms) in [(120, 120), (5_000, 200)] {
        let cfg = Config::new(Mode::from_p196(1).unwrap(), 9600);
        let sim = SimConfig::bus(&[1], 1, 9600);
        let line = Line { byte_time: cfg.char_time(), ..Line::instant() }.bytewise();
        let device = XoffOnce {
            bus: Serial(Emulator::new(sim).unwrap()),
            pause: Duration::from_millis(pause_ms),
            xoff_at: None,
            xon_due: None,
        };
        let mut b = Wired::new(Session::new(cfg, Timestamp::ZERO), device, line);
        b.run_op(Op::ReadStatus(a(1), StatusId::ACTUAL_POSITION)).unwrap();
        b.run_op(Op::ReadStatus(a(1), StatusId::ACTUAL_POSITION)).unwrap();
        let xoff_at = b.device.xoff_at.unwrap();
        let second = b.sent[1].0;
        let held = second.saturating_since(xoff_at);
        // The XOFF reaches the session one character time after the drive sent it.
        assert!(
            held >= Duration::from_millis(held_ms) && held < Duration::from_millis(held_ms + 5),
            "pause {pause_ms} ms: the next telegram went {held:?} after the XOFF"
        );
    }
}
