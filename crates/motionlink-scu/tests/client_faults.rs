//! The client against the emulator with faults on the line: corrupt and lost bytes, a slow unit, a silent
//! line, a lost port and reconnection, keepalive timing, round trips of 300 ms, one flipped bit, dead links.

use crate::rig;

use rig::*;

#[test]
fn a_corrupt_reply_to_a_read_is_retried() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(Config::default());
    rig.sleep(50); // between keepalives
    rig.faults().corrupt_next(Direction::DeviceToHost, 0x40);
    assert_eq!(client.position(a(1)).unwrap(), PositionCounts(0));
    assert_eq!(client.stats().retries, 1);
    // Corrupting a middle byte makes a CRC error instead of a lost start: also retried at once.
    let faults = rig.faults();
    faults.inject(
        Direction::DeviceToHost,
        faults.bytes_sent(Direction::DeviceToHost) + 6,
        Fault::Corrupt { xor: 0x01 },
    );
    assert_eq!(client.position(a(1)).unwrap(), PositionCounts(0));
    assert_eq!(client.stats().retries, 2);
    assert_eq!(rig.unit(|u| u.stats().watchdog_expiries), 0, "the retries kept inside the watchdog");
}

#[test]
fn a_corrupt_request_gets_cse_and_is_sent_again_even_for_re() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(Config::default());
    rig.sleep(50);
    // Corrupt the RE's direction byte (its fourth): the unit sees an RE with a wrong CRC.
    let faults = rig.faults();
    faults.inject(
        Direction::HostToDevice,
        faults.bytes_sent(Direction::HostToDevice) + 3,
        Fault::Corrupt { xor: 0x01 },
    );
    client.start_motion(f(1), MotionDirection::Out).unwrap();
    assert_eq!(rig.unit(|u| u.stats().crc_errors), 1);
    assert_eq!(client.stats().retries, 1);
    rig.sleep(300);
    assert!(rig.unit(|u| u.is_moving(a(1))));
}

#[test]
fn a_lost_reply_to_re_is_sent_again_because_every_re_names_an_absolute_destination() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(Config::default());
    rig.sleep(50);
    // The RE reply (5 bytes) is lost on its way back: after 150 ms of silence the session sends the zeros that
    // would complete a half-received telegram, and the RE again. The unit drives F1 to its Out end either way.
    rig.faults().drop_next(Direction::DeviceToHost, 5);
    client.start_motion(f(1), MotionDirection::Out).unwrap();
    assert_eq!(client.stats().retries, 1);
    assert_eq!(client.stats().flushes, 1);
    assert_eq!(client.started().iter().map(|f| f.id()).collect::<Vec<_>>(), [0]);
    rig.sleep(500);
    assert!(rig.unit(|u| u.is_moving(a(1))));
    assert_eq!(rig.unit(|u| u.stats().watchdog_expiries), 0, "the repetition came well inside the watchdog");
    drop(client);
    assert!(rig.unit(|u| u.executed_functions().is_empty()), "the RE got its RS");
    assert!(!rig.unit(|u| u.any_moving()));
}

#[test]
fn after_a_watchdog_lockout_the_session_reports_it_and_opens_remote_mode_only_when_asked() {
    let (rig, client) = watchdog_expires_after_500_ms(SafetyId::StopAllAndLock);
    assert_eq!(rig.unit(|u| u.mode()), RemoteMode::Locked);
    rig.faults().heal();
    // The read is refused with PE; an RC is accepted (the unit takes RC while locked), the read again is not:
    // the unit ended remote mode, and the session says so instead of sending RO.
    let err = client.position(a(1)).unwrap_err();
    assert!(matches!(err, Error::RemoteEnded(_)), "{err}");
    assert!(err.to_string().contains("Safety_ID 0"), "{err}");
    assert_eq!(err.class(), ErrorClass::Transport(TransportKind::Disconnected));
    assert_eq!(client.stats().reopens, 0, "no RO by itself");
    assert_eq!(rig.unit(|u| u.mode()), RemoteMode::Locked);
    assert!(!client.is_open());
    assert!(matches!(client.start_motion(f(1), MotionDirection::In), Err(Error::RemoteEnded(_))));
    rig.sleep(2_000);
    assert_eq!(rig.unit(|u| u.mode()), RemoteMode::Locked, "the keepalive does not open it either");
    // The caller decides to go on: RO, RC, and the RS of the motion that was under way.
    client.reopen().unwrap();
    assert_eq!(client.stats().reopens, 1);
    assert!(matches!(rig.unit(|u| u.mode()), RemoteMode::Active(SafetyId::StopAllAndLock)));
    assert!(rig.unit(|u| u.executed_functions().is_empty()), "F1 got its RS");
    assert_eq!(client.position(a(1)).unwrap(), PositionCounts(rig.unit(|u| u.position(a(1)).unwrap())));
    client.start_motion(f(1), MotionDirection::In).unwrap();
    drop(client);
    assert!(rig.unit(|u| u.executed_functions().is_empty()), "every RE got its RS");
}

#[test]
fn a_session_the_unit_ended_still_gets_the_rs_of_its_motion_when_it_ends() {
    let (rig, client) = watchdog_expires_after_500_ms(SafetyId::StopAllAndLock);
    rig.faults().heal();
    assert!(matches!(client.position(a(1)), Err(Error::RemoteEnded(_))));
    assert_eq!(rig.unit(|u| u.executed_functions()), vec![1]);
    // close() opens remote mode only to send the RS every RE needs, then leaves it.
    client.close().unwrap();
    assert!(rig.unit(|u| u.executed_functions().is_empty()));
    assert_eq!(rig.unit(|u| u.mode()), RemoteMode::Off);
}

#[test]
fn a_slow_unit_is_given_the_full_reply_timeout_and_its_late_replies_are_dropped() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(Config::default());
    client.set(DataIndex(0x3022), &Value::RemotePosition(800)).unwrap();
    client.start_motion(f(2), MotionDirection::RemotePosition).unwrap();
    rig.sleep(1000);
    client.stop_motion(f(2), StopMode::Fast).unwrap();
    rig.sleep(300);
    let a2 = rig.unit(|u| u.position(a(2)).unwrap());
    assert!(a2 > 50, "actuator 2 moved: {a2}");
    let telegrams = rig.unit(|u| u.stats().telegrams);
    // The unit's replies take 300 ms more: the RG is sent again after 150 ms of silence, and the reply to the
    // first sending is the answer.
    rig.faults().delay_next(Direction::DeviceToHost, Duration::from_millis(300));
    let started = rig.clock.now();
    assert_eq!(client.position(a(1)).unwrap(), PositionCounts(0));
    assert!(rig.clock.now() - started >= Duration::from_millis(300));
    assert_eq!(client.stats().retries, 1);
    assert_eq!(rig.unit(|u| u.stats().telegrams), telegrams + 2, "two sendings of the RG");
    // The reply to the second sending (position 0 as well) must not answer the next read.
    assert_eq!(client.position(a(2)).unwrap(), PositionCounts(a2));
    assert_eq!(rig.unit(|u| u.stats().watchdog_expiries), 0);
}

#[test]
fn reads_give_up_after_a_second_of_silence_and_later_requests_get_one_short_try() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(Config::default());
    rig.sleep(50);
    rig.faults().drop_next(Direction::DeviceToHost, 10_000);
    let started = rig.clock.now();
    let err = client.position(a(1)).unwrap_err();
    // Sent at 0, 150 and 450 ms; in remote mode no reply is awaited longer than 1000 ms (twice the unit's
    // watchdog: a unit that has not answered by then has left remote mode anyway). Before, reads waited the
    // manual's 2000 ms, and every later request again: a dead link took many seconds to be given up.
    assert!(matches!(err, Error::Timeout { command: Command::Get, attempts: 3, .. }), "{err}");
    let waited = rig.clock.now() - started;
    assert!(waited >= Duration::from_millis(1000) && waited < Duration::from_millis(1100), "{waited:?}");
    assert_eq!(err.class(), ErrorClass::Transport(TransportKind::Timeout));
    // The line is silent: the next request is sent once and given 300 ms.
    let started = rig.clock.now();
    let err = client.stop_motion(f(1), StopMode::Fast).unwrap_err();
    assert!(matches!(err, Error::Timeout { command: Command::Stop, attempts: 1, .. }), "{err}");
    let waited = rig.clock.now() - started;
    assert!(waited < Duration::from_millis(350), "{waited:?}");
    // The unit answers again: the line is trusted again.
    rig.faults().heal();
    assert!(matches!(client.position(a(1)), Ok(PositionCounts(0)) | Err(Error::RemoteEnded(_))));
}

#[test]
fn port_loss_is_reported_and_reconnect_restores_the_session() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(Config::default());
    client.set(DataIndex(0x3021), &Value::RemotePosition(800)).unwrap();
    client.start_motion(f(1), MotionDirection::RemotePosition).unwrap();
    rig.sleep(300);
    rig.faults().disconnect();
    rig.sleep(300);
    assert!(!client.is_open());
    let err = client.position(a(1)).unwrap_err();
    assert!(matches!(err, Error::SessionLost(_)), "{err}");
    rig.sleep(1000);
    assert!(!rig.unit(|u| u.any_moving()), "the unit's watchdog stopped the drive");
    client.reconnect().unwrap();
    assert!(client.is_open());
    assert_eq!(*rig.connects.lock().unwrap(), 2);
    assert!(client.started().is_empty(), "the RE of before got its RS after the reconnect");
    assert!(rig.unit(|u| u.executed_functions().is_empty()));
    assert!(client.position(a(1)).unwrap() > PositionCounts(0));
    assert_eq!(client.stats().reconnects, 1);
}

#[test]
fn a_failed_reconnect_leaves_the_session_lost_and_idle() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(Config::default());
    *rig.unplugged.lock().unwrap() = true;
    assert!(client.reconnect().is_err());
    assert!(!client.is_open(), "no port: the session is lost");
    assert!(matches!(client.position(a(1)), Err(Error::SessionLost(_))));
    // Without auto_reconnect nothing tries again by itself, and the keepalive thread sleeps (on a spinning
    // thread the manual clock could not advance ten seconds).
    rig.sleep(10_000);
    assert_eq!(*rig.connects.lock().unwrap(), 1);
    *rig.unplugged.lock().unwrap() = false;
    client.reconnect().unwrap();
    assert_eq!(client.position(a(1)).unwrap(), PositionCounts(0));
}

#[test]
fn a_corrupt_reply_to_the_re_of_a_move_is_repeated_and_the_move_ends_with_rs() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(Config { function_map: FunctionMap::scp11(), ..Default::default() });
    // Corrupt the CRC of the ACK of the first RE.
    let done = Arc::new(Mutex::new(false));
    let once = Arc::clone(&done);
    rig.on_request(move |bytes, faults| {
        let mut done = once.lock().unwrap();
        if bytes.starts_with(b"RE") && !*done {
            *done = true;
            faults.inject(
                Direction::DeviceToHost,
                faults.bytes_sent(Direction::DeviceToHost) + 3,
                Fault::Corrupt { xor: 1 },
            );
        }
    });
    let report = client.move_to(a(1), PositionCounts(200), pct(100), &MoveOptions::default()).unwrap();
    assert!(*done.lock().unwrap());
    assert_eq!(report.position_counts, PositionCounts(200));
    assert_eq!(client.stats().retries, 1);
    assert!(client.started().is_empty(), "RS at the end");
    assert!(rig.unit(|u| u.executed_functions().is_empty()));
}

#[test]
fn a_keepalive_without_answer_does_not_give_up_the_port() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(Config::default());
    client.set(DataIndex(0x3021), &Value::RemotePosition(800)).unwrap();
    client.start_motion(f(1), MotionDirection::RemotePosition).unwrap();
    // The unit's answers are lost for three seconds: keepalives fail, the port is still there.
    rig.faults().drop_next(Direction::DeviceToHost, 3 * 3840 / 10);
    rig.sleep(3_000);
    rig.faults().heal();
    rig.sleep(1_000);
    assert!(client.is_open());
    // Dropping the client still sends the RS of the started function and the RA.
    drop(client);
    assert!(rig.unit(|u| u.executed_functions().is_empty()), "the RE got its RS");
    assert_eq!(rig.unit(|u| u.mode()), RemoteMode::Off, "RA");
}

#[test]
fn auto_reconnect() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(Config { auto_reconnect: true, ..Default::default() });
    rig.faults().disconnect();
    rig.sleep(3_000);
    assert!(client.is_open(), "reconnected by itself");
    assert!(*rig.connects.lock().unwrap() >= 2);
    assert_eq!(client.position(a(1)).unwrap(), PositionCounts(0));
    rig.sleep(10_000);
    assert!(client.is_open());
}

#[test]
fn the_keepalive_keeps_its_grid_of_deadlines_while_the_caller_keeps_the_line_busy() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(Config::default());
    let times = record_keepalives(&rig);
    // A caller reading a 104-byte structure back to back (30 ms each on the line) for ten seconds.
    let end = rig.clock.now() + Duration::from_secs(10);
    while rig.clock.now() < end {
        client.get_raw(DataIndex(0x2001)).unwrap();
    }
    let times = times.lock().unwrap().clone();
    assert!(times.len() >= 49, "{} keepalives in 10 s", times.len());
    let period = Duration::from_millis(200);
    // The grid: the earliest any keepalive could have been due.
    let t0 = times.iter().enumerate().map(|(k, t)| *t - period * k as u32).min().unwrap();
    for (k, t) in times.iter().enumerate() {
        let due = t0 + period * k as u32;
        // Sent at its deadline, or right after the exchange that held the line then: never drifting.
        assert!(*t >= due && *t - due < Duration::from_millis(40), "keepalive {k} at {t:?}, due {due:?}");
    }
    assert_eq!(rig.unit(|u| u.stats().watchdog_expiries), 0);
}
#[test]
fn round_trips_of_300_ms_still_keep_the_unit_alive() {
    let rig = Rig::new(SimConfig::default());
    let host = rig.host.clone();
    let clock = rig.clock.shared();
    let connector: Connector = Box::new(move || {
        let (link, _) = host.connect();
        Ok(Box::new(Latency {
            inner: Box::new(link),
            clock: Arc::clone(&clock),
            latency: Arc::new(Mutex::new(Duration::from_millis(300))),
            queue: Default::default(),
        }) as Box<dyn Link>)
    });
    let client = Client::with_connector(connector, rig.clock.shared(), Config::default()).unwrap();
    let keepalives_before = client.stats().keepalives;
    rig.sleep(10_000);
    assert_eq!(rig.unit(|u| u.stats().watchdog_expiries), 0, "the unit never lost its RC");
    // One RC per round trip (the next one is already due when the last one's reply comes).
    let keepalives = client.stats().keepalives - keepalives_before;
    assert!((28..=34).contains(&keepalives), "{keepalives} keepalives in 10 s");
    assert!(client.is_open());
    assert_eq!(client.stats().retries, 1, "only the RO was sent again, before the round trip was known");
    // (Any other request holds the half-duplex line for a round trip in which no RC can go out: with 300 ms
    // round trips the RC before it and the one after it reach the unit 600 ms apart, beyond its watchdog.
    // The README says so; the keepalive alone is what this test is about.)
    client.close().unwrap();
}

#[test]
fn round_trips_of_300_ms_during_a_move_still_keep_the_unit_alive() {
    let rig = Rig::new(SimConfig::default());
    let host = rig.host.clone();
    let clock = rig.clock.shared();
    let latency = Arc::new(Mutex::new(Duration::ZERO));
    let link_latency = Arc::clone(&latency);
    let connector: Connector = Box::new(move || {
        let (link, _) = host.connect();
        Ok(Box::new(Latency {
            inner: Box::new(link),
            clock: Arc::clone(&clock),
            latency: Arc::clone(&link_latency),
            queue: Default::default(),
        }) as Box<dyn Link>)
    });
    let client = Client::with_connector(
        connector,
        rig.clock.shared(),
        Config { function_map: FunctionMap::scp11(), ..Default::default() },
    )
    .unwrap();
    // Once the actuator moves, every reply takes 300 ms more; when it stops, the line is quick again.
    let slow_polls = Mutex::new(0);
    let progress = |p: &motionlink_scu::session::MoveProgress| {
        let moving = p.status.moving();
        *latency.lock().unwrap() = if moving { Duration::from_millis(300) } else { Duration::ZERO };
        *slow_polls.lock().unwrap() += u32::from(moving);
    };
    let report = client
        .move_to(a(1), PositionCounts(500), pct(100), &MoveOptions { progress: Some(&progress), ..Default::default() })
        .unwrap();
    assert_eq!(report.position_counts, PositionCounts(500));
    assert!(*slow_polls.lock().unwrap() > 5);
    assert_eq!(rig.unit(|u| u.stats().watchdog_expiries), 0, "the unit never lost its RC");
    assert!(client.started().is_empty());
    client.close().unwrap();
}

#[test]
fn a_corrupted_length_byte_in_a_request_costs_less_than_one_reply_timeout_and_loses_nothing() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(Config::default());
    rig.sleep(20);
    // Bit 7 of the ctp of the next RT: the unit reads ctp 134 and waits for 128 more bytes than come.
    let done = Arc::new(Mutex::new(false));
    let once = Arc::clone(&done);
    rig.on_request(move |bytes, faults| {
        let mut done = once.lock().unwrap();
        if bytes.starts_with(b"RT") && !*done {
            *done = true;
            let at = faults.bytes_sent(Direction::HostToDevice) + 2;
            faults.inject(Direction::HostToDevice, at, Fault::Corrupt { xor: 0x80 });
        }
    });
    let started = rig.clock.now();
    client.set(DataIndex(0x3021), &Value::RemotePosition(432)).unwrap();
    let took = rig.clock.now() - started;
    assert!(*done.lock().unwrap());
    assert!(took < Duration::from_millis(500), "{took:?}");
    assert_eq!(client.get_value(DataIndex(0x3021)).unwrap(), Value::RemotePosition(432), "nothing lost");
    assert_eq!(client.stats().flushes, 1);
    assert_eq!(rig.unit(|u| u.stats().watchdog_expiries), 0);
}

#[test]
fn a_corrupted_length_byte_in_a_reply_is_rejected_at_once_and_the_read_repeated() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(Config::default());
    rig.sleep(20);
    for xor in [0x01u8, 0x80] {
        let done = Arc::new(Mutex::new(false));
        let once = Arc::clone(&done);
        rig.on_request(move |bytes, faults| {
            let mut done = once.lock().unwrap();
            if bytes.starts_with(b"RG") && !*done {
                *done = true;
                // The reply's ctp (its fourth byte).
                let at = faults.bytes_sent(Direction::DeviceToHost) + 3;
                faults.inject(Direction::DeviceToHost, at, Fault::Corrupt { xor });
            }
        });
        let started = rig.clock.now();
        let history = client.error_history().unwrap();
        assert!(rig.clock.now() - started < Duration::from_millis(50), "no waiting for bytes that never come");
        assert_eq!(history, [ErrorCode::NONE; 5]);
        assert!(*done.lock().unwrap());
    }
    assert_eq!(client.stats().retries, 2);
}

/// One move of A1 from 0 to 60 counts with one bit flipped at byte `offset` of direction `dir`.
fn move_with_one_flipped_bit(dir: Direction, offset: u64, bit: u8) -> (Result<i32, Error>, i32) {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(Config { function_map: FunctionMap::scp11(), ..Default::default() });
    let faults = rig.faults();
    faults.inject(dir, faults.bytes_sent(dir) + offset, Fault::Corrupt { xor: 1 << bit });
    let result =
        client.move_to(a(1), PositionCounts(60), pct(100), &MoveOptions::default()).map(|r| r.position_counts.get());
    drop(client);
    (result, rig.unit(|u| u.position(a(1)).unwrap()))
}

#[test]
fn one_flipped_bit_anywhere_in_a_move_never_yields_success_elsewhere() {
    // Every byte of the move in both directions (a different bit each time): the move either succeeds with
    // the actuator where it was asked to go, or fails; it never reports success with the actuator elsewhere.
    let mut failures = 0;
    for dir in [Direction::HostToDevice, Direction::DeviceToHost] {
        for offset in 0..900u64 {
            let (result, at) = move_with_one_flipped_bit(dir, offset, (offset % 8) as u8);
            match result {
                Ok(reported) => {
                    assert!((55..=65).contains(&at), "{dir:?} byte {offset}: success, but the unit is at {at}");
                    assert_eq!(reported, at, "{dir:?} byte {offset}: the report is the unit's position");
                }
                Err(_) => failures += 1,
            }
        }
    }
    // A CRC-16 catches every single-bit error and the session repeats the request: almost every move succeeds.
    assert!(failures < 20, "{failures} of 1800 moves failed");
}

#[test]
fn a_dead_link_during_a_move_is_given_up_quickly_and_the_error_says_the_axis_may_still_move() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(Config { function_map: FunctionMap::scp11(), ..Default::default() });
    let cut_at = Arc::new(Mutex::new(None));
    let cut = Arc::clone(&cut_at);
    let clock = rig.clock.shared();
    let faults = Arc::clone(&rig.faults);
    let progress = move |p: &motionlink_scu::session::MoveProgress| {
        let mut cut = cut.lock().unwrap();
        if p.position_counts > PositionCounts(100) && cut.is_none() {
            // The cable is cut: nothing gets through either way any more.
            let f = faults.lock().unwrap().clone().unwrap();
            f.drop_next(Direction::HostToDevice, u64::MAX / 2);
            f.drop_next(Direction::DeviceToHost, u64::MAX / 2);
            *cut = Some(clock.now());
        }
    };
    let err = client
        .move_to(a(1), PositionCounts(800), pct(100), &MoveOptions { progress: Some(&progress), ..Default::default() })
        .unwrap_err();
    let cut_at = cut_at.lock().unwrap().unwrap();
    let given_up = rig.clock.now() - cut_at;
    // At most 1000 ms for the request that finds the line dead (the keepalive's RC, or the poll), 300 ms for one
    // more, 300 ms for the fast RS.
    assert!(given_up < Duration::from_millis(1700), "the move gave up {given_up:?} after the cut");
    assert!(err.stop_unconfirmed(), "{err}");
    let text = err.to_string();
    assert!(text.contains("may still be moving") && text.contains("watchdog"), "{text}");
    assert_eq!(err.class(), ErrorClass::Transport(TransportKind::Timeout));
    client.close().unwrap_err();
    let closed = rig.clock.now() - cut_at;
    // Then 300 ms each for the RS and the RA of the end of the session.
    assert!(closed < Duration::from_millis(2400), "closed {closed:?} after the cut");
    // What actually happened on the unit: its watchdog stopped the drive 500 ms after the last RC.
    assert!(!rig.unit(|u| u.any_moving()));
    assert_eq!(rig.unit(|u| u.last_error()), ErrorCode::from_bit(22));
}

#[test]
fn a_broken_port_during_a_move_is_reported_with_an_unconfirmed_stop() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(Config { function_map: FunctionMap::scp11(), ..Default::default() });
    let faults = Arc::clone(&rig.faults);
    let progress = move |p: &motionlink_scu::session::MoveProgress| {
        if p.position_counts > PositionCounts(100) {
            faults.lock().unwrap().clone().unwrap().disconnect();
        }
    };
    let err = client
        .move_to(a(1), PositionCounts(800), pct(100), &MoveOptions { progress: Some(&progress), ..Default::default() })
        .unwrap_err();
    let Error::StopUnconfirmed { cause, .. } = &err else { panic!("{err}") };
    assert!(matches!(**cause, Error::SessionLost(_)), "{cause}");
    assert!(err.to_string().contains("may still be moving"));
    rig.sleep(600);
    assert!(!rig.unit(|u| u.any_moving()), "the unit's watchdog stopped it");
}

#[test]
fn a_close_that_cannot_confirm_the_stop_leaves_remote_mode_on_so_the_units_watchdog_stops_the_drive() {
    // The manual says of remote mode that the unit stops the motions 500 ms after the last RC; of RA only
    // that it sets normal mode. A close whose RS is not answered does not send RA.
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(Config::default());
    client.start_motion(f(1), MotionDirection::Out).unwrap();
    let sent: Arc<Mutex<Vec<Vec<u8>>>> = Arc::default();
    let log = Arc::clone(&sent);
    rig.on_request(move |bytes, _| log.lock().unwrap().push(bytes[..2].to_vec()));
    // The unit hears the host, the host does not hear the unit.
    rig.faults().drop_next(Direction::DeviceToHost, u64::MAX / 2);
    let err = client.close().unwrap_err();
    assert!(matches!(&err, Error::CloseUnconfirmed { .. }), "{err}");
    assert!(!sent.lock().unwrap().iter().any(|b| b == b"RA"), "{:?}", sent.lock().unwrap());
    assert_ne!(rig.unit(|u| u.mode()), RemoteMode::Off, "no RA: the unit was not set to normal mode");
    rig.sleep(600);
    assert!(!rig.unit(|u| u.any_moving()), "the unit's watchdog stopped the drive");
    assert_eq!(rig.unit(|u| u.last_error()), ErrorCode::from_bit(22));
}

#[test]
fn a_stop_left_unconfirmed_is_confirmed_by_the_close_before_it_leaves_remote_mode() {
    // A soft stop of an actuator with a 20 s ramp that ran 4 s takes 4 s: longer than the stop's 3 s of
    // patience, so the stop is not confirmed while the line and remote mode are fine.
    let config = SimConfig::from_toml("[[actuator]]\nramp_ms = 20000\n").unwrap();
    let rig = Rig::new(config);
    let client = rig.client(Config { function_map: FunctionMap::scp11(), ..Default::default() });
    client.start_motion(f(1), MotionDirection::Out).unwrap();
    rig.sleep(4000);
    let err = client.stop_functions(&[f(1)], StopMode::Soft).unwrap_err();
    assert!(err.stop_unconfirmed() && err.to_string().contains("still report(s) motion"), "{err}");
    assert!(matches!(rig.unit(|u| u.mode()), RemoteMode::Active(_)));
    // The close stops F1 again (fast) and reads the status until it is at rest, then sends RA.
    let sent: Arc<Mutex<Vec<Vec<u8>>>> = Arc::default();
    let log = Arc::clone(&sent);
    rig.on_request(move |bytes, _| log.lock().unwrap().push(bytes[..2].to_vec()));
    assert_eq!(client.close().unwrap(), Vec::new(), "F1's RS was acknowledged before: nothing left started");
    let sent = sent.lock().unwrap().clone();
    let ra = sent.iter().position(|b| b == b"RA").expect("RA sent");
    let rs = sent[..ra].iter().position(|b| b == b"RS").unwrap_or_else(|| panic!("RS again before RA: {sent:?}"));
    assert!(sent[rs..ra].iter().any(|b| b == b"RG" || b == b"RC"), "the status between RS and RA: {sent:?}");
    assert_eq!(rig.unit(|u| u.mode()), RemoteMode::Off);
    assert!(!rig.unit(|u| u.any_moving()));
}

#[test]
fn a_close_confirms_the_stop_of_what_it_started_by_the_status_before_it_leaves_remote_mode() {
    // An acknowledged RS does not say that the drives are at rest, and the manual does not say what RA does
    // to a motion under way: the close reads the status after its RS and sends RA once no actuator moves.
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(Config { function_map: FunctionMap::scp11(), ..Default::default() });
    client.start_motion(f(1), MotionDirection::Out).unwrap();
    rig.sleep(500);
    assert!(rig.unit(|u| u.is_moving(a(1))));
    let sent: Arc<Mutex<Vec<Vec<u8>>>> = Arc::default();
    let log = Arc::clone(&sent);
    rig.on_request(move |bytes, _| log.lock().unwrap().push(bytes[..2].to_vec()));
    assert_eq!(client.close().unwrap(), vec![Function::Motion(f(1))], "the close says what it stopped");
    let sent = sent.lock().unwrap().clone();
    let ra = sent.iter().position(|b| b == b"RA").expect("RA sent");
    let rs = sent[..ra].iter().position(|b| b == b"RS").unwrap_or_else(|| panic!("RS before RA: {sent:?}"));
    assert!(sent[rs..ra].iter().any(|b| b == b"RG"), "the status read between RS and RA: {sent:?}");
    assert_eq!(rig.unit(|u| u.mode()), RemoteMode::Off);
    assert!(!rig.unit(|u| u.any_moving()));
}

#[test]
fn a_run_whose_re_never_got_a_clean_answer_fails_after_its_stop_and_is_no_report() {
    use motionlink_scu::session::RunAction;
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(Config::default());
    // Every reply to an RE comes back corrupt: the RE may have switched the buzzer on, none says so.
    rig.on_request(|bytes, faults| {
        if bytes.starts_with(b"RE") {
            let at = faults.bytes_sent(Direction::DeviceToHost) + 3;
            faults.inject(Direction::DeviceToHost, at, Fault::Corrupt { xor: 1 });
        }
    });
    let limit = Some(Duration::from_millis(200));
    let e = client.run_function(RunAction::Switch(Function::Buzzer), limit, &|_| {}).unwrap_err();
    assert!(matches!(e, Error::Corrupt { .. }), "a failure, not a run: {e}");
    // It was switched off all the same.
    assert!(rig.unit(|u| u.executed_functions().is_empty()), "RS sent");
    assert!(client.started().is_empty());
}
