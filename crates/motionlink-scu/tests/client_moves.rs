//! Moves of functions that drive several actuators, polling, streamed setpoints, watchdog lapses with
//! Safety_ID 1 and 2, read-back of writes, function maps.

use crate::rig;

use motionlink_scu::Variant;
use rig::*;

#[test]
fn a_function_that_drives_two_actuators_moves_each_to_its_own_target_with_one_re() {
    let rig = Rig::new(SimConfig::liftkit());
    let client = rig.client(Config { function_map: FunctionMap::liftkit(), ..Default::default() });
    let f8 = f(8);
    let report = client
        .move_function(
            f8,
            &[(a(1), PositionCounts(300)), (a(2), PositionCounts(320))],
            pct(100),
            &MoveOptions::default(),
        )
        .unwrap();
    let each: Vec<_> =
        report.actuators.iter().map(|o| (o.actuator, o.position_counts, o.difference_counts())).collect();
    assert_eq!(each, [(a(1), PositionCounts(300), 0), (a(2), PositionCounts(320), 0)]);
    assert_eq!(rig.unit(|u| (u.position(a(1)), u.position(a(2)))), (Some(300), Some(320)));
    assert!(rig.unit(|u| u.executed_functions().is_empty()), "RS of F8 at the end");
    // The map is checked before anything is sent: F8 drives both, F1 only A1.
    let before = rig.unit(|u| u.stats().telegrams - u.stats().cyclic);
    for (function, targets) in [
        (f8, vec![(a(1), PositionCounts(10))]),
        (f(1), vec![(a(1), PositionCounts(10)), (a(2), PositionCounts(10))]),
        (f8, vec![(a(1), PositionCounts(1)), (a(1), PositionCounts(2))]),
    ] {
        let err = client.move_function(function, &targets, pct(100), &MoveOptions::default()).unwrap_err();
        assert_eq!(err.class(), ErrorClass::Usage, "{err}");
    }
    assert_eq!(rig.unit(|u| u.stats().telegrams - u.stats().cyclic), before);
    // One of them cannot go there: the move is refused before either moves.
    let err = client
        .move_function(
            f8,
            &[(a(1), PositionCounts(100)), (a(2), PositionCounts(900))],
            pct(100),
            &MoveOptions::default(),
        )
        .unwrap_err();
    assert!(matches!(err, Error::OutsideLimits { target_counts: PositionCounts(900), .. }), "{err}");
    assert_eq!(rig.unit(|u| (u.position(a(1)), u.position(a(2)))), (Some(300), Some(320)));
}

#[test]
fn without_a_function_map_move_to_gives_every_connected_actuator_the_target_and_reports_the_ones_that_moved() {
    // A TLT, of which the client is not told: F1 drives both columns, and both end at 400.
    let rig = Rig::new(SimConfig::tlt());
    let client = rig.client(Config::default());
    let report = client.move_to(a(1), PositionCounts(400), pct(100), &MoveOptions::default()).unwrap();
    assert_eq!(rig.unit(|u| (u.position(a(1)), u.position(a(2)))), (Some(400), Some(400)));
    let each: Vec<_> = report.actuators.iter().map(|o| (o.actuator, o.position_counts, o.moved)).collect();
    assert_eq!(each, [(a(1), PositionCounts(400), true), (a(2), PositionCounts(400), true)]);
    // An SCP11 unit: F1 drives A1 alone; A2 gets the remote position but does not move, and is reported so.
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(Config::default());
    let report = client.move_to(a(1), PositionCounts(400), pct(100), &MoveOptions::default()).unwrap();
    let each: Vec<_> = report.actuators.iter().map(|o| (o.actuator, o.position_counts, o.moved)).collect();
    assert_eq!(each, [(a(1), PositionCounts(400), true), (a(2), PositionCounts(0), false)]);
    assert_eq!(client.get_value(DataIndex(0x3022)).unwrap(), Value::RemotePosition(400));
}

#[test]
fn without_a_function_map_the_actuators_a_move_or_stream_does_not_name_are_held_where_they_stand() {
    // A TLT, of which the client is not told: F1 drives both columns. A2's remote position holds a stale 900.
    let rig = Rig::new(SimConfig::tlt());
    let client = rig.client(Config::default());
    client.move_to(a(1), PositionCounts(400), pct(100), &MoveOptions::default()).unwrap();
    client.set(DataIndex(0x3022), &Value::RemotePosition(900)).unwrap();
    // F1 with a target for A1 alone: A2 is written where it stands, so F1 keeps it there, and is reported.
    let report = client.move_function(f(1), &[(a(1), PositionCounts(200))], pct(100), &MoveOptions::default()).unwrap();
    assert_eq!(rig.unit(|u| (u.position(a(1)), u.position(a(2)))), (Some(200), Some(400)));
    let each: Vec<_> = report.actuators.iter().map(|o| (o.actuator, o.target_counts, o.position_counts)).collect();
    assert_eq!(
        each,
        [(a(1), PositionCounts(200), PositionCounts(200)), (a(2), PositionCounts(400), PositionCounts(400))]
    );
    assert!(report.verified, "{:?}", report.not_verifiable);
    // A stream of F1 naming A1 alone holds A2 the same way.
    client.set(DataIndex(0x3022), &Value::RemotePosition(900)).unwrap();
    let mut stream = client.stream(f(1), &[a(1)], pct(100)).unwrap();
    assert_eq!(client.get_value(DataIndex(0x3022)).unwrap(), Value::RemotePosition(400));
    stream.set_targets(&[PositionCounts(300)]).unwrap();
    for _ in 0..100 {
        if rig.unit(|u| !u.is_moving(a(1)) && u.position(a(1)) == Some(300)) {
            break;
        }
        rig.sleep(100);
    }
    assert_eq!(rig.unit(|u| u.position(a(1))), Some(300));
    assert_eq!(rig.unit(|u| u.position(a(2))), Some(400));
    drop(stream);
    // Where the map knows the function, nothing else is written.
    let client = rig.client(Config { function_map: FunctionMap::scp11(), ..Default::default() });
    client.set(DataIndex(0x3022), &Value::RemotePosition(900)).unwrap();
    let report = client.move_function(f(1), &[(a(1), PositionCounts(250))], pct(100), &MoveOptions::default()).unwrap();
    assert_eq!(report.actuators.len(), 1);
    assert_eq!(client.get_value(DataIndex(0x3022)).unwrap(), Value::RemotePosition(900));
}

#[test]
fn a_move_polls_at_its_interval_and_not_as_fast_as_the_line_answers() {
    // Polling with reads (the choice when the keepalive cannot carry the poll object).
    let rig = Rig::new(SimConfig::default());
    let reads = MovePolling::Reads;
    let client = rig.client(Config { function_map: FunctionMap::scp11(), move_polling: reads, ..Default::default() });
    let before = rig.unit(|u| u.stats().telegrams - u.stats().cyclic);
    let report = client.move_to(a(1), PositionCounts(400), pct(100), &MoveOptions::default()).unwrap();
    let requests = rig.unit(|u| u.stats().telegrams - u.stats().cyclic) - before;
    // Two reads per 50 ms poll, plus a dozen for setting up and ending the move.
    let polls = report.duration.as_millis() as u64 / 50;
    assert!(requests <= 2 * polls + 16, "{requests} requests for {polls} polls");
    assert!(requests >= 2 * polls - 4, "{requests} requests for {polls} polls");
    drop(client);
    let client = rig.client(Config {
        function_map: FunctionMap::scp11(),
        poll_interval: Duration::from_millis(200),
        move_polling: reads,
        ..Default::default()
    });
    let before = rig.unit(|u| u.stats().telegrams - u.stats().cyclic);
    let report = client.move_to(a(1), PositionCounts(0), pct(100), &MoveOptions::default()).unwrap();
    let requests = rig.unit(|u| u.stats().telegrams - u.stats().cyclic) - before;
    assert!(requests <= 2 * (report.duration.as_millis() as u64 / 200) + 16, "{requests}");
}

#[test]
fn a_move_polls_through_the_keepalive_at_its_interval_and_sends_nothing_else_while_the_motion_runs() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(Config { function_map: FunctionMap::scp11(), ..Default::default() });
    // Every request the session sends, with whether the unit's actuator moved when it went out.
    let sent = Arc::new(Mutex::new(Vec::new()));
    let sink = Arc::clone(&sent);
    let host = rig.host.clone();
    rig.on_request(move |bytes, _| {
        sink.lock().unwrap().push((bytes[..2].to_vec(), host.with_device(|u| u.is_moving(a(1)))));
    });
    let cyclic_before = rig.unit(|u| u.stats().cyclic);
    let report = client.move_to(a(1), PositionCounts(400), pct(100), &MoveOptions::default()).unwrap();
    assert_eq!(report.position_counts, PositionCounts(400));
    let sent = sent.lock().unwrap().clone();
    let during: Vec<&Vec<u8>> = sent.iter().filter(|(_, moving)| *moving).map(|(c, _)| c).collect();
    assert!(!during.is_empty());
    assert!(during.iter().all(|c| c.as_slice() == b"RC"), "only RC while the motion runs: {during:?}");
    // One RC per 50 ms poll: each feeds the watchdog and reads the state.
    let polls = report.duration.as_millis() as u64 / 50;
    let rcs = rig.unit(|u| u.stats().cyclic) - cyclic_before;
    assert!(rcs <= polls + 8 && rcs + 8 >= polls, "{rcs} RCs for {polls} polls");
    assert!(client.stats().motion_polls + 4 >= polls, "{:?}", client.stats());
    assert_eq!(rig.unit(|u| u.stats().watchdog_expiries), 0);
}

#[test]
fn a_move_reads_its_result_after_the_unit_reports_the_end_of_the_motion() {
    // Polling with reads: status first, then the position. (Polling through the keepalive, the status and
    // the positions come in one reply, read at one instant: see the test below.)
    let rig = Rig::new(SimConfig::default());
    let reads = MovePolling::Reads;
    let client = rig.client(Config { function_map: FunctionMap::scp11(), move_polling: reads, ..Default::default() });
    // Every position read is recorded with whether the unit reported motion just before.
    let reads = Arc::new(Mutex::new(Vec::new()));
    let sink = Arc::clone(&reads);
    let host = rig.host.clone();
    rig.on_request(move |bytes, _| {
        if bytes.starts_with(&[0x52, 0x47, 0x11, 0x00]) {
            sink.lock().unwrap().push(host.with_device(|u| u.is_moving(a(1))));
        }
    });
    let report = client.move_to(a(1), PositionCounts(300), pct(100), &MoveOptions::default()).unwrap();
    let reads = reads.lock().unwrap();
    assert_eq!(reads.last(), Some(&false), "the last position read came after the motion ended");
    assert_eq!(report.position_counts, PositionCounts(300));
}

#[test]
fn a_move_polled_through_the_keepalive_judges_the_reply_that_reports_the_end_of_the_motion() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(Config { function_map: FunctionMap::scp11(), ..Default::default() });
    // Every RC that carries the poll object (CyclicObj 5: object index 4), with whether the unit moved.
    let polls = Arc::new(Mutex::new(Vec::new()));
    let sink = Arc::clone(&polls);
    let host = rig.host.clone();
    rig.on_request(move |bytes, _| {
        if bytes.starts_with(&[0x52, 0x43, 0x01, 0x00, 0x04]) {
            sink.lock().unwrap().push(host.with_device(|u| u.is_moving(a(1))));
        }
    });
    let report = client.move_to(a(1), PositionCounts(300), pct(100), &MoveOptions::default()).unwrap();
    let polls = polls.lock().unwrap();
    assert!(polls.iter().filter(|m| **m).count() > 20, "{polls:?}");
    assert_eq!(polls.last(), Some(&false), "the last poll came after the motion ended");
    assert_eq!(report.position_counts, PositionCounts(300));
    assert_eq!(rig.unit(|u| u.position(a(1))), Some(300));
}

#[test]
fn streamed_setpoints_retarget_a_running_motion_and_change_its_speed() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(Config { function_map: FunctionMap::scp11(), ..Default::default() });
    let mut stream = client.stream(f(1), &[a(1)], pct(100)).unwrap();
    stream.set_targets(&[PositionCounts(600)]).unwrap();
    rig.sleep(1_000);
    let p = stream.positions().unwrap()[0].1;
    assert!(p > PositionCounts(60) && p < PositionCounts(600), "{p}");
    // 20 Hz updates towards a moving target.
    for k in 0..20 {
        stream.set_targets(&[PositionCounts(200 + 5 * k)]).unwrap();
        rig.sleep(50);
    }
    stream.set_speed(pct(50)).unwrap();
    rig.sleep(5_000);
    let [(_, at, moving)] = stream.positions().unwrap()[..] else { panic!() };
    assert_eq!((at, moving), (PositionCounts(295), false), "at the last setpoint");
    assert!(stream.set_targets(&[PositionCounts(900)]).is_err(), "beyond the stroke");
    assert!(stream.set_targets(&[PositionCounts(1), PositionCounts(2)]).is_err(), "one target per actuator");
    let rest = stream.stop(StopMode::Soft).unwrap();
    assert_eq!(rest, [(a(1), PositionCounts(295))]);
    assert!(client.started().is_empty());
    // Dropping a running stream stops it.
    let mut stream = client.stream(f(1), &[a(1)], pct(100)).unwrap();
    stream.set_targets(&[PositionCounts(800)]).unwrap();
    rig.sleep(500);
    drop(stream);
    assert!(!rig.unit(|u| u.is_moving(a(1))));
    assert!(client.started().is_empty());
    assert!(matches!(client.stream(f(1), &[a(2)], pct(100)), Err(Error::InvalidArgument(_))), "F1 drives A1");
    assert!(matches!(client.stream(f(1), &[a(1)], pct(0)), Err(Error::InvalidArgument(_))), "speed 0");
}

#[test]
fn cyclic_objects_may_name_groups() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(Config::default());
    // Write all six remote positions (group 0x3020), read all positions and all status bytes (groups).
    let obj = CyclicObject::new(&[DataIndex(0x3020)], &[DataIndex(0x0010), DataIndex(0x0170)]).unwrap();
    client.configure_cyclic(2, &obj).unwrap();
    let write: Vec<Value> = (1..=6).map(|k| Value::RemotePosition(100 * k)).collect();
    let read = client.exchange_cyclic(2, &write).unwrap();
    assert_eq!(read.len(), 12);
    assert_eq!(read[0].0.name, "actual_position_a1");
    assert_eq!(read[6].0.name, "actuator_status1_a1");
    assert_eq!(client.get_value(DataIndex(0x3023)).unwrap(), Value::RemotePosition(300));
    assert!(client.exchange_cyclic(2, &write[..5]).is_err(), "a group counts each of its entries");
    client.use_cyclic(2, &write).unwrap();
    rig.sleep(500);
    assert_eq!(client.last_cyclic_read().unwrap().1.len(), 12);
}

/// A move with Safety_ID 1 or 2 whose link goes dead for 700 ms (nothing reaches the unit): the unit's
/// watchdog lapses and stops the motion; the move ends with an error. Returns the client, the link healed.
fn lapse_during_a_move(rig: &Rig, safety: SafetyId) -> Client {
    let config = Config { safety_id: safety, function_map: FunctionMap::scp11(), ..Default::default() };
    let client = rig.client(config);
    assert_eq!(rig.unit(|u| u.mode()), RemoteMode::Active(safety));
    let faults = Arc::clone(&rig.faults);
    let clock = rig.clock.shared();
    let cut = Mutex::new(None);
    let progress = |p: &motionlink_scu::session::MoveProgress| {
        let f = faults.lock().unwrap().clone().unwrap();
        let mut cut = cut.lock().unwrap();
        match *cut {
            None if p.position_counts > PositionCounts(50) => {
                // 700 ms in which nothing reaches the unit (all 8 polls' bytes and keepalives are lost).
                f.drop_next(Direction::HostToDevice, u64::MAX / 2);
                *cut = Some(clock.now());
            }
            Some(t) if clock.now() - t > Duration::from_millis(700) => f.heal(),
            _ => {}
        }
    };
    let err = client
        .move_to(a(1), PositionCounts(800), pct(100), &MoveOptions { progress: Some(&progress), ..Default::default() })
        .unwrap_err();
    assert_eq!(rig.unit(|u| u.stats().watchdog_expiries), 1, "{safety:?}");
    assert!(!rig.unit(|u| u.is_moving(a(1))));
    assert!(matches!(err, Error::RemoteEnded(_) | Error::MotionEnded { .. } | Error::StopUnconfirmed { .. }), "{err}");
    rig.faults().heal();
    client
}

/// By default (chapter 5) the unit deactivates remote mode when its watchdog lapses, whatever the Safety_ID:
/// the session finds the unit refusing even RC, says that remote mode ended, and does not open it again by
/// itself; the caller's reopen does.
#[test]
fn safety_id_1_or_2_through_the_api_a_watchdog_lapse_during_a_move_ends_remote_mode_until_the_caller_reopens() {
    for safety in [SafetyId::StopAll, SafetyId::StopRemoteOnly] {
        let rig = Rig::new(SimConfig::default());
        let client = lapse_during_a_move(&rig, safety);
        assert_eq!(rig.unit(|u| u.mode()), RemoteMode::Off, "{safety:?}");
        let err = client.position(a(1)).unwrap_err();
        assert!(matches!(&err, Error::RemoteEnded(t) if t.contains("left remote mode")), "{safety:?}: {err}");
        assert_eq!(rig.unit(|u| u.mode()), RemoteMode::Off, "the session sends no RO by itself");
        client.reopen().unwrap();
        assert_eq!(rig.unit(|u| u.mode()), RemoteMode::Active(safety));
        let report = client.move_to(a(1), PositionCounts(100), pct(100), &MoveOptions::default()).unwrap();
        assert_eq!(report.position_counts, PositionCounts(100), "{safety:?}");
    }
}

/// A unit of the `rc-rearms-watchdog` variant refuses commands after the lapse until an RC re-arms its
/// watchdog: the session says that the motion it had started was stopped (once), and goes on.
#[test]
fn on_an_rc_rearms_watchdog_unit_a_watchdog_lapse_during_a_move_is_reported_and_the_session_goes_on() {
    for safety in [SafetyId::StopAll, SafetyId::StopRemoteOnly] {
        let rig = Rig::with_variants(SimConfig::default(), &[Variant::RcRearmsWatchdog]);
        let client = lapse_during_a_move(&rig, safety);
        assert_eq!(rig.unit(|u| u.mode()), RemoteMode::TimedOut(safety));
        // The first request after that finds the lapse: the unit refuses it until an RC re-arms the watchdog,
        // and the session says that the motion it had started was stopped (once).
        let err = client.position(a(1)).unwrap_err();
        assert!(matches!(&err, Error::RemoteEnded(t) if t.contains("watchdog")), "{err}");
        assert!(client.is_open(), "Safety_ID 1 and 2 need no RO on such a unit");
        assert!(client.started().is_empty(), "the stopped function got its RS");
        // After the RC the session goes on.
        let report = client.move_to(a(1), PositionCounts(100), pct(100), &MoveOptions::default()).unwrap();
        assert_eq!(report.position_counts, PositionCounts(100), "{safety:?}");
        assert_eq!(client.stats().reopens, 0);
    }
}

#[test]
fn while_idle_a_lapse_with_safety_id_1_ends_remote_mode_and_a_lock_with_safety_id_0_is_reported() {
    // Safety_ID 1: remote mode deactivated (chapter 5); the session says so and sends no RO by itself.
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(Config { safety_id: SafetyId::StopAll, ..Default::default() });
    rig.faults().drop_next(Direction::HostToDevice, u64::MAX / 2);
    rig.sleep(1_500);
    rig.faults().heal();
    assert_eq!(rig.unit(|u| u.mode()), RemoteMode::Off);
    assert!(matches!(client.position(a(1)), Err(Error::RemoteEnded(_))));
    assert_eq!(rig.unit(|u| u.mode()), RemoteMode::Off);
    client.reopen().unwrap();
    assert_eq!(client.position(a(1)).unwrap(), PositionCounts(0));
    drop(client);
    // Safety_ID 1 on a unit whose next RC re-arms the watchdog: idle, the read goes through after the RC;
    // the lapse is counted.
    let rig = Rig::with_variants(SimConfig::default(), &[Variant::RcRearmsWatchdog]);
    let client = rig.client(Config { safety_id: SafetyId::StopAll, ..Default::default() });
    rig.faults().drop_next(Direction::HostToDevice, u64::MAX / 2);
    rig.sleep(1_500);
    rig.faults().heal();
    assert_eq!(rig.unit(|u| u.mode()), RemoteMode::TimedOut(SafetyId::StopAll));
    assert_eq!(client.position(a(1)).unwrap(), PositionCounts(0));
    assert_eq!(client.stats().watchdog_lapses, 1);
    assert!(client.is_open());
    drop(client);
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(Config::default());
    rig.faults().drop_next(Direction::HostToDevice, u64::MAX / 2);
    rig.sleep(1_500);
    rig.faults().heal();
    assert_eq!(rig.unit(|u| u.mode()), RemoteMode::Locked);
    // Safety_ID 0: even idle, the session reports it and does not send RO by itself.
    assert!(matches!(client.position(a(1)), Err(Error::RemoteEnded(_))));
    assert_eq!(rig.unit(|u| u.mode()), RemoteMode::Locked);
    client.reopen().unwrap();
    assert_eq!(client.position(a(1)).unwrap(), PositionCounts(0));
}

/// A unit that keeps its own idea of a written speed: it stores at most 50 % for F1 (its RT telegrams are
/// rewritten on the way in, with a good CRC).
struct ClampingUnit {
    unit: Emulator,
    held: Vec<u8>,
}

impl motionlink_link::emulator::Emulator for ClampingUnit {
    fn receive(&mut self, now: motionlink_link::Timestamp, bytes: &[u8], out: &mut Vec<u8>) {
        use motionlink_scu::wire::{request_to_vec, Request};
        const RT_F1_SPEED: [u8; 6] = [0x52, 0x54, 0x04, 0x00, 0x11, 0x30];
        for &b in bytes {
            self.held.push(b);
            let n = self.held.len();
            if self.held[..n.min(6)] != RT_F1_SPEED[..n.min(6)] {
                // Not that telegram: pass it on, keeping a last 'R' that may start it.
                let keep = usize::from(self.held[n - 1] == 0x52 && n > 1);
                let pass: Vec<u8> = self.held.drain(..n - keep).collect();
                self.unit.receive(now, &pass, out);
            } else if n == 10 {
                if self.held[6] > 50 {
                    self.held = request_to_vec(&Request::Transfer { index: 0x3011, data: &[50, 0] }).unwrap();
                }
                let pass = std::mem::take(&mut self.held);
                self.unit.receive(now, &pass, out);
            }
        }
        if bytes.is_empty() {
            self.unit.receive(now, bytes, out);
        }
    }
    fn advance(&mut self, now: motionlink_link::Timestamp, out: &mut Vec<u8>) {
        self.unit.advance(now, out)
    }
    fn next_wakeup(&self) -> Option<motionlink_link::Timestamp> {
        self.unit.next_wakeup()
    }
    fn connection_closed(&mut self, now: motionlink_link::Timestamp) {
        self.held.clear();
        self.unit.connection_closed(now)
    }
}

#[test]
fn set_reads_the_value_back_and_a_mismatch_is_an_error() {
    // Also on a unit that refuses what the client would rather use beyond the manual: no check is weakened.
    let plain = SimConfig::default();
    let mut refusing = SimConfig::default();
    for v in [Variant::NoGroups, Variant::NoUserPositions, Variant::NoCyclicObjects] {
        refusing.add_variants([v]);
    }
    for config in [plain, refusing] {
        set_read_back_mismatch(config);
    }
}

fn set_read_back_mismatch(config: SimConfig) {
    let clock = ManualClock::new_auto();
    let _me = clock.reserve_participant().enter();
    let host = EmulatorHost::new(
        ClampingUnit { unit: Emulator::new(config).unwrap(), held: Vec::new() },
        clock.shared(),
        PipeConfig::paced(38_400),
    );
    let connector: Connector = host.connector();
    let client = Client::with_connector(connector, clock.shared(), Config::default()).unwrap();
    client.set(DataIndex(0x3011), &Value::RemoteSpeed(40)).unwrap();
    let err = client.set(DataIndex(0x3011), &Value::RemoteSpeed(80)).unwrap_err();
    let Error::ReadBack { name, index, wrote, read } = &err else { panic!("{err}") };
    let values = |data: &[u8]| -> Vec<Value> {
        let it = motionlink_scu::model::item(*index).unwrap();
        motionlink_scu::value::decode_item(it, data).unwrap().into_iter().map(|(_, v)| v).collect()
    };
    assert_eq!(
        (*name, values(wrote), values(read)),
        ("remote_speed_f1", vec![Value::RemoteSpeed(80)], vec![Value::RemoteSpeed(50)])
    );
    assert!(err.to_string().ends_with("wrote 80, the unit reads back 50"), "{err}");
    assert_eq!(err.class(), ErrorClass::Device);
    // A move whose speed does not read back is refused before RE.
    let err = client.move_to(a(1), PositionCounts(100), pct(80), &MoveOptions::default()).unwrap_err();
    assert!(matches!(err, Error::ReadBack { .. }), "{err}");
    assert!(client.started().is_empty(), "no RE was sent");
}

#[test]
fn function_maps_from_presets_and_specifications() {
    let m = FunctionMap::unknown().apply("tlt").unwrap();
    assert_eq!(m, FunctionMap::tlt());
    assert_eq!(m.drives(f(1)), Some(vec![a(1), a(2)]));
    assert_eq!(m.drives(f(4)), Some(vec![]), "a preset says the other functions drive nothing");
    let m = FunctionMap::unknown().apply("F1=1+3").unwrap().apply("f2 = a2, a4").unwrap().apply("F9=").unwrap();
    assert_eq!(m.drives(f(1)), Some(vec![a(1), a(3)]));
    assert_eq!(m.drives(f(2)), Some(vec![a(2), a(4)]));
    assert_eq!(m.drives(f(9)), Some(vec![]));
    assert_eq!(m.drives(f(3)), None, "not given: unknown");
    assert_eq!(FunctionMap::liftkit().drives(f(8)), Some(vec![a(1), a(2)]));
    assert_eq!(FunctionMap::scp11().drives(f(6)), Some(vec![a(6)]));
    for bad in ["F11=1", "F1=7", "F1", "xyz", "F0=1"] {
        assert!(FunctionMap::unknown().apply(bad).is_err(), "{bad}");
    }
}

/// A unit with a standing error after which "motions are not performed" (bit 25, raised 1 ms after
/// power-on): a move fails, never "verified", and nothing moves. By default the unit refuses the RE (PE);
/// on an `ack-without-motion` unit it acknowledges it and nothing moves: the move is judged where the
/// actuator still stands, naming the error.
#[test]
fn a_move_against_a_unit_whose_error_keeps_motions_from_being_performed_fails_and_nothing_moves() {
    for variants in [&[][..], &[Variant::AckWithoutMotion][..]] {
        let config = SimConfig::from_toml("[[error]]\nbit = 25\nat_ms = 1\n").unwrap();
        let rig = Rig::with_variants(config, variants);
        let client = rig.client(Config { function_map: FunctionMap::scp11(), ..Default::default() });
        let err = client.move_to(a(1), PositionCounts(400), pct(80), &MoveOptions::default()).unwrap_err();
        match variants {
            [] => assert!(
                matches!(err, Error::Refused { command: Command::Execute, status: Status::PermissionError }),
                "{err}"
            ),
            _ => assert!(
                matches!(err, Error::MotionEnded { position_counts: PositionCounts(0), error_code, .. }
                    if error_code.has(25)),
                "{variants:?}: {err}"
            ),
        }
        assert_eq!(rig.unit(|u| u.position(a(1))), Some(0), "{variants:?}: nothing moved");
        assert!(client.started().is_empty(), "{variants:?}: the function got its RS");
        assert!(client.is_open(), "{variants:?}: remote mode is fine");
    }
}
