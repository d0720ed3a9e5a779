//! The client against the emulator, in-process: opening, the keepalive, reads and writes, moves, cancel,
//! the end of the session, cyclic objects.

use crate::rig;

use motionlink_scu::session::RunAction;
use rig::*;

#[test]
fn open_sends_ro_and_rc_and_close_leaves_remote_mode() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(Config::default());
    assert_eq!(rig.unit(|u| u.mode()), RemoteMode::Active(SafetyId::StopAllAndLock));
    client.close().unwrap();
    assert_eq!(rig.unit(|u| u.mode()), RemoteMode::Off);
}

#[test]
fn a_unit_that_ignores_the_first_ro_after_a_long_silence_is_opened_by_the_second() {
    // Real units often sleep through the first RO; the client sends it again when no reply comes.
    let rig = Rig::new(SimConfig::default());
    let host = rig.host.clone();
    let connector: Connector = Box::new(move || {
        let (link, faults) = host.connect();
        faults.drop_next(Direction::HostToDevice, 5); // the first RO, all five bytes
        Ok(Box::new(link) as Box<dyn Link>)
    });
    let client = Client::with_connector(connector, rig.clock.shared(), Config::default()).unwrap();
    assert_eq!(client.stats().retries, 1);
    assert!(matches!(rig.unit(|u| u.mode()), RemoteMode::Active(_)));
    client.close().unwrap();
}

/// A battery unit in low-power mode (`low-power`) answers nothing until its RxD is held at space for at
/// least 100 ms (E 3, S 3): without a break the opening times out; `Config::wake_break` (the command line's
/// `--wake`) sends one before RO, at every opening, and the session runs. A break shorter than the manual's
/// 100 ms is refused before anything is sent. Idle outside remote mode, the unit sleeps again.
#[test]
fn a_unit_in_low_power_mode_is_woken_by_a_break_before_ro() {
    let rig = Rig::with_variants(SimConfig::default(), &[motionlink_scu::Variant::LowPower]);
    let short = Config { reply_timeout: Duration::from_millis(300), ..Config::default() };
    let err = Client::with_connector(rig.connector(), rig.clock.shared(), short.clone()).unwrap_err();
    assert!(err.class().is_transport(), "{err}");
    assert!(rig.unit(motionlink_link::emulator::Emulator::take_events).iter().any(|e| e.contains("in low-power mode")));
    let too_short = Config { wake_break: Some(Duration::from_millis(50)), ..short.clone() };
    let err = Client::with_connector(rig.connector(), rig.clock.shared(), too_short).unwrap_err();
    assert!(err.to_string().contains("wake break 50ms: 100 ms"), "{err}");
    let waking = Config { wake_break: Some(motionlink_scu::config::WAKE_BREAK), ..short };
    let client = rig.client(waking.clone());
    assert!(matches!(rig.unit(|u| u.mode()), RemoteMode::Active(_)));
    assert!(rig
        .unit(motionlink_link::emulator::Emulator::take_events)
        .iter()
        .any(|e| e == "woken from low-power mode by a break of 150 ms"));
    client.get(DataIndex(0x0011)).unwrap();
    client.close().unwrap();
    // Asleep again 2 s after its last byte outside remote mode: a new session wakes it again.
    rig.sleep(2_500);
    assert!(rig
        .unit(motionlink_link::emulator::Emulator::take_events)
        .iter()
        .any(|e| e.starts_with("gone to low-power mode")));
    let client = rig.client(waking);
    client.close().unwrap();
}

#[test]
fn the_chosen_safety_id_goes_into_ro() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(Config { safety_id: SafetyId::StopRemoteOnly, ..Default::default() });
    assert_eq!(rig.unit(|u| u.mode()), RemoteMode::Active(SafetyId::StopRemoteOnly));
    drop(client);
}

#[test]
fn a_session_is_kept_alive_for_ten_minutes_of_device_time_without_busy_waiting() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(Config::default());
    let real = Instant::now();
    rig.sleep(600_050); // not on a keepalive's deadline: its reply is in when the counts are compared
    let stats = client.stats();
    assert_eq!(rig.unit(|u| u.stats().watchdog_expiries), 0, "the watchdog never expired");
    // One RC every 200 ms: 3000 in ten minutes (give or take the first).
    assert!((2990..=3001).contains(&stats.keepalives), "{} keepalives", stats.keepalives);
    assert_eq!(rig.unit(|u| u.stats().cyclic), stats.keepalives + 1, "every RC the unit saw was acknowledged");
    assert!(client.is_open());
    assert!(real.elapsed() < Duration::from_secs(20), "ten device minutes took {:?}", real.elapsed());
    client.close().unwrap();
}

#[test]
fn keepalive_period_above_450_ms_is_refused() {
    let rig = Rig::new(SimConfig::default());
    let err = Client::with_connector(
        rig.connector(),
        rig.clock.shared(),
        Config { keepalive_period: Duration::from_millis(451), ..Default::default() },
    )
    .unwrap_err();
    assert!(matches!(err, Error::InvalidArgument(_)), "{err}");
    assert_eq!(*rig.connects.lock().unwrap(), 0, "nothing was opened");
    // 450 ms is allowed and keeps the unit alive.
    let client = rig.client(Config { keepalive_period: Duration::from_millis(450), ..Default::default() });
    rig.sleep(10_000);
    assert_eq!(rig.unit(|u| u.stats().watchdog_expiries), 0);
    drop(client);
}
#[test]
fn watchdog_expiry_with_safety_id_0_locks_the_unit() {
    let (rig, client) = watchdog_expires_after_500_ms(SafetyId::StopAllAndLock);
    assert_eq!(rig.unit(|u| u.mode()), RemoteMode::Locked);
    drop(client);
}

#[test]
fn watchdog_expiry_with_safety_id_1() {
    let (rig, client) = watchdog_expires_after_500_ms(SafetyId::StopAll);
    assert_eq!(rig.unit(|u| u.mode()), RemoteMode::Off, "remote mode deactivated (chapter 5)");
    drop(client);
}

#[test]
fn watchdog_expiry_with_safety_id_2() {
    let (rig, client) = watchdog_expires_after_500_ms(SafetyId::StopRemoteOnly);
    assert_eq!(rig.unit(|u| u.mode()), RemoteMode::Off, "remote mode deactivated (chapter 5)");
    drop(client);
}

#[test]
fn typed_reads_of_entries_and_groups() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(Config::default());
    assert_eq!(client.position(a(1)).unwrap(), PositionCounts(0));
    let status = client.status1(a(1)).unwrap();
    assert!(status.available() && status.contains(Status1Flag::InPosition) && !status.moving());
    let group = client.get(DataIndex(0x0010)).unwrap();
    assert_eq!(group.len(), 6);
    assert_eq!(group[0].0.name, "actual_position_a1");
    match client.get_value(DataIndex(0x0001)).unwrap() {
        Value::Text(t) => assert!(t.starts_with("SCU"), "{t}"),
        other => panic!("{other:?}"),
    }
    assert!(matches!(client.get_value(DataIndex(0x0010)), Err(Error::InvalidArgument(_))), "a group");
    assert!(matches!(client.get(DataIndex(0x0017)), Err(Error::InvalidArgument(_))), "not in the list");
}

#[test]
fn writes_are_checked_before_anything_is_sent() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(Config::default());
    let non_rc = |s: motionlink_scu::sim::SimStats| s.telegrams - s.cyclic;
    let before = rig.unit(|u| non_rc(u.stats()));
    for (index, value) in [
        (0x0011, Value::PositionCounts(1)),   // read-only
        (0x3011, Value::RemoteSpeed(101)),    // out of range
        (0x3011, Value::RemotePosition(100)), // wrong kind
        (0x3010, Value::RemoteSpeed(10)),     // a group
    ] {
        let err = client.set(DataIndex(index), &value).unwrap_err();
        assert_eq!(err.class(), ErrorClass::Usage, "{err}");
    }
    assert_eq!(rig.unit(|u| non_rc(u.stats())), before, "only keepalives reached the unit");
    client.set(DataIndex(0x3011), &Value::RemoteSpeed(100)).unwrap();
    assert_eq!(rig.unit(|u| non_rc(u.stats())), before + 2, "the RT, and the RG that reads the value back");
}

#[test]
fn the_unit_refusing_is_a_device_error() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(Config::default());
    let err = client.start_motion(f(6), MotionDirection::Out).unwrap_err();
    assert!(matches!(err, Error::Refused { command: Command::Execute, status: Status::PermissionError }), "{err}");
    assert_eq!(err.class(), ErrorClass::Refused);
}

#[test]
fn move_to_moves_and_ends_with_rs() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(Config::default());
    let seen = Mutex::new(Vec::new());
    let progress = |p: &motionlink_scu::session::MoveProgress| seen.lock().unwrap().push(p.position_counts);
    let report = client
        .move_to(a(1), PositionCounts(400), pct(80), &MoveOptions { progress: Some(&progress), ..Default::default() })
        .unwrap();
    assert_eq!(report.position_counts, PositionCounts(400));
    assert_eq!(report.function, f(1));
    // 400 counts at 88 counts/s: about 4.5 s.
    assert!((4_400..=5_300).contains(&report.duration.as_millis()), "{:?}", report.duration);
    let seen = seen.into_inner().unwrap();
    assert!(seen.len() > 30 && seen.windows(2).all(|w| w[0] <= w[1]), "progress rises: {seen:?}");
    assert!(client.started().is_empty(), "RS was sent");
    assert!(rig.unit(|u| u.executed_functions().is_empty()));
    assert_eq!(rig.unit(|u| u.position(a(1))), Some(400));
    assert_eq!(rig.unit(|u| u.stats().watchdog_expiries), 0);
}

#[test]
fn move_to_with_the_tlt_function_map() {
    let rig = Rig::new(SimConfig::tlt());
    let client = rig.client(Config { function_map: FunctionMap::tlt(), ..Default::default() });
    // F3 drives column 2 alone.
    let report = client
        .move_to(a(2), PositionCounts(120), pct(100), &MoveOptions { function: Some(f(3)), ..Default::default() })
        .unwrap();
    assert_eq!(report.actuators.len(), 1);
    assert_eq!(
        rig.unit(|u| (u.position(a(1)), u.position(a(2)))),
        (Some(-3), Some(120)),
        "a TLT reads -3 at its In end"
    );
    // F1 drives both columns of a TLT: move_to gives both the target. (Before, only A1's remote position was
    // written, and A2 ran to whatever its remote position held.)
    let report = client.move_to(a(1), PositionCounts(200), pct(100), &MoveOptions::default()).unwrap();
    assert_eq!(rig.unit(|u| (u.position(a(1)), u.position(a(2)))), (Some(200), Some(200)));
    assert_eq!(report.function, f(1));
    let each: Vec<_> = report.actuators.iter().map(|o| (o.actuator, o.position_counts, o.moved)).collect();
    assert_eq!(each, [(a(1), PositionCounts(200), true), (a(2), PositionCounts(200), true)]);
    // A function that does not drive the actuator is refused before anything is sent.
    let err = client
        .move_to(a(1), PositionCounts(300), pct(100), &MoveOptions { function: Some(f(3)), ..Default::default() })
        .unwrap_err();
    assert_eq!(err.class(), ErrorClass::Usage, "{err}");
}

#[test]
fn cancel_stops_the_actuator_at_once() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(Config::default());
    let cancel = CancelToken::new();
    client.set_cancel(cancel.clone());
    let progress = |p: &motionlink_scu::session::MoveProgress| {
        if p.position_counts > PositionCounts(100) {
            cancel.cancel();
        }
    };
    let err = client
        .move_to(a(1), PositionCounts(800), pct(100), &MoveOptions { progress: Some(&progress), ..Default::default() })
        .unwrap_err();
    let Error::Cancelled { position_counts, .. } = err else { panic!("{err}") };
    assert!((PositionCounts(100)..PositionCounts(130)).contains(&position_counts));
    assert!(!rig.unit(|u| u.is_moving(a(1))), "stopped");
    assert!(client.started().is_empty());
    rig.sleep(1000);
    assert!(rig.unit(|u| u.position(a(1))).unwrap() < 140, "and stays stopped");
}

#[test]
fn a_stalled_actuator_is_stopped_and_reported() {
    let rig = Rig::new(SimConfig::tlt());
    let client = rig.client(Config::default());
    let err = client
        .move_to(a(1), PositionCounts(300), pct(20), &MoveOptions { function: Some(f(2)), ..Default::default() })
        .unwrap_err();
    assert!(matches!(err, Error::Stalled { position_counts: PositionCounts(0), .. }), "{err}");
    assert_eq!(err.class(), ErrorClass::Device);
    assert!(!rig.unit(|u| u.any_moving()));
    assert!(rig.unit(|u| u.executed_functions().is_empty()), "RS was sent after the stall");
}

#[test]
fn a_target_outside_the_stroke_is_refused_before_anything_moves() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(Config::default());
    let remote_before = client.get_value(DataIndex(0x3022)).unwrap();
    let err = client.move_to(a(2), PositionCounts(2000), pct(100), &MoveOptions::default()).unwrap_err();
    let Error::OutsideLimits {
        actuator,
        target_counts: PositionCounts(2000),
        min_counts: PositionCounts(0),
        max_counts: PositionCounts(865),
        ..
    } = err
    else {
        panic!("{err}")
    };
    assert_eq!(actuator, a(2));
    assert!(err.to_string().contains("virtual limits"), "names where the limit comes from: {err}");
    assert_eq!(err.class(), ErrorClass::Usage);
    assert_eq!(client.get_value(DataIndex(0x3022)).unwrap(), remote_before, "nothing was written");
    assert!(rig.unit(|u| u.executed_functions().is_empty() && !u.any_moving()));
    // Below the In end as well; and a configured stroke replaces the unit's.
    assert!(matches!(
        client.move_to(a(1), PositionCounts(-1), pct(100), &MoveOptions::default()),
        Err(Error::OutsideLimits { .. })
    ));
    drop(client);
    let mut limits = [None; 6];
    limits[0] = Some(StrokeLimits { min_counts: PositionCounts(0), max_counts: PositionCounts(300) });
    let client = rig.client(Config { stroke_limits: limits, ..Default::default() });
    let err = client.move_to(a(1), PositionCounts(400), pct(100), &MoveOptions::default()).unwrap_err();
    assert!(
        matches!(err, Error::OutsideLimits { max_counts: PositionCounts(300), limits_from: "as configured", .. }),
        "{err}"
    );
}

#[test]
fn a_move_that_ends_short_of_its_target_names_target_position_and_difference() {
    let rig = Rig::new(SimConfig::default());
    // A stroke configured wider than the unit's: the unit stops at its Out end, 865.
    let mut limits = [None; 6];
    limits[1] = Some(StrokeLimits { min_counts: PositionCounts(0), max_counts: PositionCounts(2000) });
    let config = Config { stroke_limits: limits, function_map: FunctionMap::scp11(), ..Default::default() };
    let client = rig.client(config);
    let err = client.move_to(a(2), PositionCounts(900), pct(100), &MoveOptions::default()).unwrap_err();
    assert!(
        matches!(
            err,
            Error::MotionEnded {
                position_counts: PositionCounts(865),
                target_counts: PositionCounts(900),
                tolerance_counts: 5,
                ..
            }
        ),
        "{err}"
    );
    let text = err.to_string();
    assert!(text.contains("865") && text.contains("900") && text.contains("-35 counts"), "{text}");
    assert_eq!(err.class(), ErrorClass::Device);
    assert!(client.started().is_empty(), "RS after the failure");
}

#[test]
fn a_drive_fault_during_a_move_is_reported() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(Config::default());
    let progress = |p: &motionlink_scu::session::MoveProgress| {
        if p.position_counts > PositionCounts(50) {
            rig.unit(|u| u.inject_error(ErrorCode::from_bit(15)));
        }
    };
    let err = client
        .move_to(a(1), PositionCounts(600), pct(100), &MoveOptions { progress: Some(&progress), ..Default::default() })
        .unwrap_err();
    let Error::MotionEnded { error_code, .. } = err else { panic!("{err}") };
    assert!(error_code.has(15), "{error_code}");
}

#[test]
fn dropping_the_client_stops_what_it_started_and_leaves_remote_mode() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(Config::default());
    client.set(DataIndex(0x3021), &Value::RemotePosition(800)).unwrap();
    client.set(DataIndex(0x3022), &Value::RemotePosition(800)).unwrap();
    client.start_motion(f(1), MotionDirection::RemotePosition).unwrap();
    client.start_motion(f(2), MotionDirection::RemotePosition).unwrap();
    client.switch(Function::Buzzer, true).unwrap();
    rig.sleep(500);
    assert!(rig.unit(|u| u.is_moving(a(1)) && u.is_moving(a(2))));
    assert_eq!(client.started().iter().map(|f| f.id()).collect::<Vec<_>>(), [0, 1, 10]);
    drop(client);
    assert!(!rig.unit(|u| u.any_moving()), "both drives stopped");
    assert!(rig.unit(|u| u.executed_functions().is_empty()), "every RE got its RS");
    assert_eq!(rig.unit(|u| u.mode()), RemoteMode::Off, "RA");
}

#[test]
fn the_end_of_a_session_on_a_dead_link_is_bounded_by_the_close_bound() {
    let rig = Rig::new(SimConfig::default());
    let bound = Duration::from_millis(500);
    let client = rig.client(Config { close_bound: bound, ..Default::default() });
    client.start_motion(f(1), MotionDirection::Out).unwrap();
    // The unit answers nothing any more: the RS of F1 alone would be tried for a whole second.
    rig.faults().drop_next(Direction::DeviceToHost, u64::MAX / 2);
    let started = rig.clock.now();
    let err = client.close().unwrap_err();
    let took = rig.clock.now() - started;
    // The close names what it left unconfirmed (F1), and why: its bound ran out.
    assert!(
        matches!(&err, Error::CloseUnconfirmed { functions, cause }
            if functions.iter().map(|g| g.id()).eq([f(1).id()]) && matches!(**cause, Error::CloseTimedOut { bound: b } if b == bound)),
        "{err}"
    );
    assert!(err.to_string().contains("may still be moving") && err.to_string().contains("F1"), "{err}");
    assert!(took >= bound && took < bound + Duration::from_millis(50), "close took {took:?}");
    // Dropping a client is bounded the same way.
    rig.faults().heal();
    let client = rig.client(Config { close_bound: bound, ..Default::default() });
    client.start_motion(f(1), MotionDirection::Out).unwrap();
    rig.faults().drop_next(Direction::DeviceToHost, u64::MAX / 2);
    let started = rig.clock.now();
    drop(client);
    let took = rig.clock.now() - started;
    assert!(took >= bound && took < bound + Duration::from_millis(50), "drop took {took:?}");
    // What stops the drive then is the unit's own watchdog.
    rig.sleep(600);
    assert!(!rig.unit(|u| u.any_moving()));
}

#[test]
fn keepalives_carry_a_cyclic_object() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(Config::default());
    let obj = CyclicObject::new(&[DataIndex(0x3011)], &[DataIndex(0x0011), DataIndex(0x0171)]).unwrap();
    client.configure_cyclic(1, &obj).unwrap();
    client.use_cyclic(1, &[Value::RemoteSpeed(60)]).unwrap();
    rig.sleep(500);
    let (at, read) = client.last_cyclic_read().unwrap();
    assert!(rig.clock.now() - at <= Duration::from_millis(200));
    assert_eq!(read.len(), 2);
    assert_eq!(read[0].1, Value::PositionCounts(0));
    assert_eq!(client.get_value(DataIndex(0x3011)).unwrap(), Value::RemoteSpeed(60), "the write data arrived");
    client.start_motion(f(1), MotionDirection::Out).unwrap();
    rig.sleep(2000);
    let (_, read) = client.last_cyclic_read().unwrap();
    let Value::PositionCounts(p) = read[0].1 else { panic!() };
    assert!(p > 80, "the keepalive reports the moving position: {p}");
    let Value::Flags(s) = &read[1].1 else { panic!() };
    assert!(s.is_set("motion"));
    let now = client.exchange_cyclic(1, &[Value::RemoteSpeed(30)]).unwrap();
    assert_eq!(now.len(), 2);
    assert!(client.exchange_cyclic(1, &[]).is_err(), "one write value is needed");
    assert!(client.exchange_cyclic(6, &[]).is_err());
    client.stop_motion(f(1), StopMode::Fast).unwrap();
}

#[test]
fn error_history_names_the_watchdog() {
    let rig = Rig::new(SimConfig::default());
    rig.unit(|u| u.inject_error(ErrorCode::from_bit(12)));
    let client = rig.client(Config::default());
    let history = client.error_history().unwrap();
    assert_eq!(history[0], ErrorCode::from_bit(12));
    assert!(history[1..].iter().all(|c| *c == ErrorCode::NONE));
    assert!(history[0].to_string().contains("overtemperature"));
}

/// The switching functions, the entry that shows each (read with RG) and its value while the function is on.
const SWITCHES: [(Function, u16, u16); 6] = [
    (Function::Buzzer, 0x0140, 0x01),
    (Function::BinaryOutput1, 0x0110, 0x01),
    (Function::BinaryOutput2, 0x0110, 0x02),
    (Function::EmergencyStop, 0x0162, 0x03FF),
    (Function::Led1, 0x0120, 0x01),
    (Function::Led2, 0x0120, 0x02),
];

/// The value of a flag entry of one or two bytes.
fn word(client: &Client, index: u16) -> u16 {
    let raw = client.get_raw(DataIndex(index)).unwrap();
    raw.iter().rev().fold(0, |w, b| w << 8 | u16::from(*b))
}

/// Counts the RG of `index` the client sends from now on.
fn count_reads(rig: &Rig, index: u16) -> Arc<Mutex<usize>> {
    let n = Arc::new(Mutex::new(0));
    let sink = Arc::clone(&n);
    rig.on_request(move |bytes, _| {
        if bytes.starts_with(b"RG") && bytes[2..4] == index.to_le_bytes() {
            *sink.lock().unwrap() += 1;
        }
    });
    n
}

#[test]
fn switching_functions_are_read_back_after_their_re_and_their_rs() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(Config::default());
    for (function, index, on_word) in SWITCHES {
        let reads = count_reads(&rig, index);
        let on = client.switch(function, true).unwrap();
        assert!(on.on && on.verified && on.not_verifiable.is_empty(), "{function}: {:?}", on.not_verifiable);
        assert_eq!(word(&client, index), on_word, "{function}");
        let off = client.switch(function, false).unwrap();
        assert!(!off.on && off.verified && off.not_verifiable.is_empty(), "{function}: {:?}", off.not_verifiable);
        assert_eq!(word(&client, index), 0, "{function}");
        // Read after each switch; where the manuals do not tie the entry to the function in so many words, also
        // before the first (the probe: the entry seen off, then on); plus the two reads of this test.
        let probe = usize::from(function.switch_status().unwrap().reading.is_some());
        assert_eq!(*reads.lock().unwrap(), 2 + probe + 2, "{function}");
    }
    assert!(client.started().is_empty());
    assert!(client.switch(Function::Motion(f(1)), true).is_err());
    assert!(rig.unit(|u| u.executed_functions().is_empty()));
}

#[test]
fn a_run_of_a_switching_function_is_verified_when_its_status_showed_it_on_then_off() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(Config::default());
    for (function, index, _) in SWITCHES {
        let seen = Mutex::new(Vec::new());
        let progress = |p: &motionlink_scu::session::RunProgress| {
            seen.lock().unwrap().push((p.switched_on_shown, rig.unit(|u| u.executed_functions())));
        };
        let limit = Some(Duration::from_millis(300));
        let run = client.run_function(RunAction::Switch(function), limit, &progress).unwrap();
        assert!(run.verified && run.not_verifiable.is_empty(), "{function}: {:?}", run.not_verifiable);
        let said = seen.lock().unwrap().clone();
        assert_eq!(said, [(Some(true), vec![function.number()])], "{function}: said once, after the RE was read back");
        assert_eq!(word(&client, index), 0, "{function}: off after the run");
    }
    assert!(client.started().is_empty());
}

#[test]
fn a_status_that_shows_the_other_state_after_an_acknowledged_re_or_rs_is_an_error_naming_it() {
    // The buzzer and binary output 1: the manuals name their bits. A unit whose buzzer output failed
    // acknowledges the RE but shows it off.
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(Config::default());
    rig.unit(|u| u.fail_switch(Function::Buzzer));
    let e = client.switch(Function::Buzzer, true).unwrap_err();
    assert!(matches!(e, Error::SwitchNotShown { command: Command::Execute, word: 0, switched_off: false, .. }), "{e}");
    assert_eq!(e.class(), ErrorClass::Device);
    let text = e.to_string();
    assert!(
        text.starts_with(
            "the unit acknowledged RE of F11 (buzzer), but does not show the buzzer on: buzzer (0x0140, bit 0) is \
             clear (0x00) (last read 10"
        ),
        "{text}"
    );
    // A run of binary output 1 whose output fails: the RE is not shown, the run switches it off and says so.
    rig.unit(|u| u.fail_switch(Function::BinaryOutput1));
    let e = client.run_function(RunAction::Switch(Function::BinaryOutput1), None, &|_| {}).unwrap_err();
    assert!(matches!(e, Error::SwitchNotShown { switched_off: true, .. }), "{e}");
    assert!(e.to_string().ends_with("; then switched off (the unit acknowledged the RS)"), "{e}");
    assert!(!client.started().contains(&Function::BinaryOutput1) && rig.unit(|u| u.executed_functions() == [11]));
}

#[test]
fn an_emergency_stop_still_shown_engaged_after_an_acknowledged_rs_is_said_plainly() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(Config::default());
    // The run reads lock_status before the RE (released), after it (engaged): the entry follows F20. Then the
    // unit's emergency stop output fails while it is engaged: the RS is acknowledged, nothing is released.
    let progress = |_: &motionlink_scu::session::RunProgress| rig.unit(|u| u.fail_switch(Function::EmergencyStop));
    let limit = Some(Duration::from_millis(300));
    let e = client.run_function(RunAction::Switch(Function::EmergencyStop), limit, &progress).unwrap_err();
    assert!(matches!(e, Error::SwitchNotShown { command: Command::Stop, word: 0x03FF, .. }), "{e}");
    let text = e.to_string();
    assert!(
        text.starts_with(
            "the unit acknowledged RS of F20 (emergency stop), but still shows the emergency stop engaged: \
             lock_status (0x0162) shows every motion function F1..F10 locked (0x03FF)"
        ),
        "{text}"
    );
    assert_eq!(word(&client, 0x0162), 0x03FF, "still engaged");
    // The reverse: an RE the unit acknowledges but does not show, once the session has seen the entry follow.
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(Config::default());
    client.switch(Function::EmergencyStop, true).unwrap();
    client.switch(Function::EmergencyStop, false).unwrap();
    rig.unit(|u| u.fail_switch(Function::EmergencyStop));
    let e = client.switch(Function::EmergencyStop, true).unwrap_err();
    assert!(
        e.to_string().starts_with(
            "the unit acknowledged RE of F20 (emergency stop), but does not show the emergency stop engaged: \
             lock_status (0x0162) is 0x0000, not every motion function F1..F10 locked"
        ),
        "{e}"
    );
}

#[test]
fn a_unit_that_refuses_the_status_entry_is_switched_and_says_it_was_not_read_back() {
    let rig = Rig::new(SimConfig::default());
    rig.unit(|u| u.refuse_reads(DataIndex(0x0140)));
    let client = rig.client(Config::default());
    let reads = count_reads(&rig, 0x0140);
    let on = client.switch(Function::Buzzer, true).unwrap();
    assert!(!on.verified, "{on:?}");
    assert_eq!(
        on.not_verifiable,
        ["F11 (buzzer) was not verified by its status: the unit refuses buzzer (0x0140) (RG: PDE); the unit's \
          acknowledge is all that says it switched"]
    );
    assert_eq!(rig.unit(|u| u.executed_functions()), [11], "switched on all the same");
    let run = client.run_function(RunAction::Switch(Function::Buzzer), Some(Duration::from_millis(200)), &|_| {});
    let run = run.unwrap();
    assert_eq!((run.verified, &run.not_verifiable), (false, &on.not_verifiable), "said once, for the whole run");
    let off = client.switch(Function::Buzzer, false).unwrap();
    assert_eq!(off.not_verifiable, on.not_verifiable);
    assert_eq!(*reads.lock().unwrap(), 1, "refused once, not asked for again in the session");
    assert!(client.started().is_empty());
}

#[test]
fn stop_functions_stops_every_motion_function_and_reads_where_the_actuators_rest() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(Config::default());
    client.start_motion(f(1), MotionDirection::Out).unwrap();
    client.start_motion(f(2), MotionDirection::Out).unwrap();
    rig.sleep(500);
    assert!(rig.unit(|u| u.any_moving()));
    let all: Vec<MotionFunction> = MotionFunction::all().collect();
    let report = client.stop_functions(&all, StopMode::Fast).unwrap();
    assert!(!rig.unit(|u| u.any_moving()), "nothing moves once the stop is confirmed");
    assert_eq!(report.functions, all);
    assert!(report.refused.is_empty(), "{report:?}");
    let a1 = report.at_rest.iter().find(|r| r.actuator == a(1)).expect("A1 is connected");
    assert_eq!(Some(a1.position_counts.0), rig.unit(|u| u.position(a(1))));
    assert!(a1.position_counts.0 > 0, "A1 had moved: {a1:?}");
    assert!(client.started().is_empty(), "every RS was acknowledged");
    // The report as JSON: functions and actuators by number, the mode by name.
    let json = serde_json::to_value(&report).unwrap();
    assert_eq!(json["functions"][0], 1);
    assert_eq!(json["mode"], "fast");
    assert_eq!(json["at_rest"][0]["actuator"], 1);
    // At rest already: the same stop, confirmed at once.
    let again = client.stop_functions(&[f(1)], StopMode::Soft).unwrap();
    assert_eq!(again.at_rest.iter().find(|r| r.actuator == a(1)).unwrap().position_counts, a1.position_counts);
    client.close().unwrap();
}

#[test]
fn a_session_opened_by_the_port_s_name_runs_over_tcp_and_sim_and_can_are_refused_naming_what_to_do() {
    let clock = motionlink_link::RealClock::shared();
    let unit = Arc::new(Mutex::new(Emulator::new(SimConfig::default()).unwrap()));
    let server = motionlink_link::emulator::serve_tcp("127.0.0.1:0", Arc::clone(&unit), clock.clone()).unwrap();
    let client = Client::open(&server.address().parse().unwrap(), clock.clone(), Config::default()).unwrap();
    assert!(matches!(unit.lock().unwrap().mode(), RemoteMode::Active(_)));
    client.position(Actuator::new(1).unwrap()).unwrap();
    client.close().unwrap();
    assert_eq!(unit.lock().unwrap().mode(), RemoteMode::Off);
    for (port, says) in [("sim", "give its link to `with_link`"), ("socketcan://can0", "not CAN")] {
        let err = Client::open(&port.parse().unwrap(), clock.clone(), Config::default()).unwrap_err();
        let text = err.to_string();
        assert!(text.contains(port) && text.contains(says), "{text}");
        assert_eq!(err.class(), ErrorClass::Usage);
    }
}

#[test]
fn a_session_on_a_link_given_to_it_cannot_reconnect_and_says_why() {
    let rig = Rig::new(SimConfig::default());
    let (link, faults) = rig.host.connect();
    let client = Client::with_link(Box::new(link), rig.clock.shared(), Config::default()).unwrap();
    assert!(matches!(rig.unit(|u| u.mode()), RemoteMode::Active(_)));
    faults.disconnect();
    let err = client.reconnect().unwrap_err();
    assert!(err.to_string().contains("cannot be opened again (with_connector reconnects)"), "{err}");
}

#[test]
fn a_watch_samples_once_per_interval() {
    // Every interval from 100 ms to 1 s: the samples come one interval apart (within 20 ms), never two a
    // poll interval apart and then a long gap (the samples riding on the keepalive RC).
    for interval_ms in [100, 150, 300, 1000] {
        let rig = Rig::new(SimConfig::default());
        let client = rig.client(Config::default());
        let mut at = Vec::new();
        let n = client.watch(Duration::from_millis(interval_ms), Some(6), &mut |s| at.push(s.at)).unwrap();
        assert_eq!(n, 6);
        let gaps: Vec<u128> = at.windows(2).map(|w| (w[1] - w[0]).as_millis()).collect();
        assert!(
            gaps.iter().all(|g| g.abs_diff(u128::from(interval_ms)) <= 20),
            "every {interval_ms} ms: gaps {gaps:?} ms"
        );
    }
}

#[test]
fn a_status_read_that_fails_before_the_emergency_stop_does_not_hold_it_back() {
    // The read before the first RE of F20 (the probe of lock_status) gets corrupt answers, all three sendings:
    // the emergency stop is engaged all the same (was: the read's error, and no RE), and the read after the RE
    // shows it.
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(Config::default());
    rig.corrupt_reads(0x0162, 0..3);
    let report = client.switch(Function::EmergencyStop, true).unwrap();
    assert_eq!(word(&client, 0x0162), 0x03FF, "engaged");
    assert!(!report.verified, "the entry was not seen before the RE: {report:?}");
    assert!(report.not_verifiable[0].contains("not read before it"), "{report:?}");
    client.switch(Function::EmergencyStop, false).unwrap();
}

#[test]
fn a_status_read_that_fails_after_an_acknowledged_switch_says_it_was_not_verified_not_that_it_failed() {
    // The buzzer's entry (0x0140) answers corrupt, all three sendings of the read after the RE: the buzzer is
    // on (the unit acknowledged it), and the report says it was not read back (was: the read's error).
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(Config::default());
    rig.corrupt_reads(0x0140, 0..3);
    let report = client.switch(Function::Buzzer, true).unwrap();
    assert!(!report.verified && report.not_verifiable[0].contains("was not read after the RE"), "{report:?}");
    assert_eq!(word(&client, 0x0140), 0x01, "on");
    assert!(client.switch(Function::Buzzer, false).unwrap().verified);
}
