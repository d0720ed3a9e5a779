//! The client against the emulator, in-process, on a manual clock that jumps ahead whenever every participant
//! waits: minutes of device time run in milliseconds, deterministically.

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use motionlink_link::cancel::CancelToken;
use motionlink_link::clock::{Clock, ManualClock, ParticipantGuard};
use motionlink_link::link::{Connector, Link, LinkError};
use motionlink_link::pipe::{Direction, EmulatorHost, Fault, FaultControl, PipeConfig};
use motionlink_scu::client::{ClientConfig, ErrorClass, MoveOptions, ScuClient, ScuError};
use motionlink_scu::model::{
    status1, Actuator, CyclicObject, DataIndex, ErrorCode, Function, MotionDirection, MotionFunction, SafetyId,
    StopMode,
};
use motionlink_scu::sim::{RemoteMode, ScuEmulator, SimConfig};
use motionlink_scu::value::Value;
use motionlink_scu::wire::{Command, Status};

struct Rig {
    clock: ManualClock,
    host: EmulatorHost<ScuEmulator>,
    faults: Arc<Mutex<Option<FaultControl>>>,
    connects: Arc<Mutex<u32>>,
    /// While set, opening the port fails (the adapter is unplugged).
    unplugged: Arc<Mutex<bool>>,
    _me: ParticipantGuard,
}

impl Rig {
    fn new(config: SimConfig) -> Rig {
        let clock = ManualClock::new_auto();
        let me = clock.reserve_participant().enter();
        let host = EmulatorHost::new(ScuEmulator::new(config).unwrap(), clock.shared(), PipeConfig::paced(38_400));
        Rig { clock, host, faults: Arc::default(), connects: Arc::default(), unplugged: Arc::default(), _me: me }
    }

    fn connector(&self) -> Connector {
        let host = self.host.clone();
        let faults = Arc::clone(&self.faults);
        let connects = Arc::clone(&self.connects);
        let unplugged = Arc::clone(&self.unplugged);
        Box::new(move || {
            if *unplugged.lock().unwrap() {
                return Err(LinkError::Disconnected { port: "sim".into(), reason: "unplugged".into() });
            }
            let (link, f) = host.connect();
            *faults.lock().unwrap() = Some(f);
            *connects.lock().unwrap() += 1;
            Ok(Box::new(link) as Box<dyn Link>)
        })
    }

    fn client(&self, config: ClientConfig) -> ScuClient {
        ScuClient::open(self.connector(), self.clock.shared(), config).unwrap()
    }

    fn faults(&self) -> FaultControl {
        self.faults.lock().unwrap().clone().unwrap()
    }

    fn unit<R>(&self, f: impl FnOnce(&mut ScuEmulator) -> R) -> R {
        self.host.with_device(f)
    }

    fn sleep(&self, ms: u64) {
        self.clock.sleep(Duration::from_millis(ms));
    }
}

fn a(n: u8) -> Actuator {
    Actuator::new(n).unwrap()
}

fn f(n: u8) -> MotionFunction {
    MotionFunction::new(n).unwrap()
}

#[test]
fn open_sends_ro_and_rc_and_close_leaves_remote_mode() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(ClientConfig::default());
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
    let client = ScuClient::open(connector, rig.clock.shared(), ClientConfig::default()).unwrap();
    assert_eq!(client.stats().retries, 1);
    assert!(matches!(rig.unit(|u| u.mode()), RemoteMode::Active(_)));
    client.close().unwrap();
}

#[test]
fn the_chosen_safety_id_goes_into_ro() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(ClientConfig { safety_id: SafetyId::StopRemoteOnly, ..Default::default() });
    assert_eq!(rig.unit(|u| u.mode()), RemoteMode::Active(SafetyId::StopRemoteOnly));
    drop(client);
}

#[test]
fn a_session_is_kept_alive_for_ten_minutes_of_device_time_without_busy_waiting() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(ClientConfig::default());
    let real = Instant::now();
    rig.sleep(600_000);
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
    let err = ScuClient::open(
        rig.connector(),
        rig.clock.shared(),
        ClientConfig { keepalive_period: Duration::from_millis(451), ..Default::default() },
    )
    .unwrap_err();
    assert!(matches!(err, ScuError::InvalidArgument(_)), "{err}");
    assert_eq!(*rig.connects.lock().unwrap(), 0, "nothing was opened");
    // 450 ms is allowed and keeps the unit alive.
    let client = rig.client(ClientConfig { keepalive_period: Duration::from_millis(450), ..Default::default() });
    rig.sleep(10_000);
    assert_eq!(rig.unit(|u| u.stats().watchdog_expiries), 0);
    drop(client);
}

/// Starts a long move, then the line goes dead (every byte to the unit lost): the unit's watchdog must stop the
/// drive 500 ms after the last RC it received.
fn watchdog_expires_after_500_ms(safety: SafetyId) -> (Rig, ScuClient) {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(ClientConfig { safety_id: safety, ..Default::default() });
    client.set(DataIndex(0x3021), &Value::RemotePosition(800)).unwrap();
    client.start_motion(f(1), MotionDirection::RemotePosition).unwrap();
    rig.sleep(1000);
    assert!(rig.unit(|u| u.is_moving(a(1))));
    let cyclic_before = rig.unit(|u| u.stats().cyclic);
    rig.faults().drop_next(Direction::HostToDevice, u64::MAX / 2);
    // Find when the unit last saw an RC: the keepalive is at most 200 ms old.
    let cut = rig.clock.now();
    rig.sleep(250);
    assert_eq!(rig.unit(|u| u.stats().cyclic), cyclic_before, "nothing reaches the unit any more");
    // The unit stops at last RC + 500 ms, which lies in (cut - 200 ms, cut] + 500 ms.
    let mut t = cut + Duration::from_millis(250);
    while rig.unit(|u| u.is_moving(a(1))) {
        rig.clock.sleep_until(t + Duration::from_millis(1));
        t = rig.clock.now();
        assert!(t < cut + Duration::from_millis(501), "still moving {:?} after the cut", t - cut);
    }
    assert!(t > cut + Duration::from_millis(300), "stopped too early: {:?} after the cut", t - cut);
    assert_eq!(rig.unit(|u| u.last_error()), ErrorCode::from_bit(22));
    (rig, client)
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
    assert_eq!(rig.unit(|u| u.mode()), RemoteMode::TimedOut(SafetyId::StopAll));
    drop(client);
}

#[test]
fn watchdog_expiry_with_safety_id_2() {
    let (rig, client) = watchdog_expires_after_500_ms(SafetyId::StopRemoteOnly);
    assert_eq!(rig.unit(|u| u.mode()), RemoteMode::TimedOut(SafetyId::StopRemoteOnly));
    drop(client);
}

#[test]
fn typed_reads_of_entries_and_groups() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(ClientConfig::default());
    assert_eq!(client.position(a(1)).unwrap(), 0);
    let status = client.status1(a(1)).unwrap();
    assert!(status.is_set("available") && status.is_set("in_position") && !status.is_set("motion"));
    let group = client.get(DataIndex(0x0010)).unwrap();
    assert_eq!(group.len(), 6);
    assert_eq!(group[0].0.name, "actual_position_a1");
    match client.get_value(DataIndex(0x0001)).unwrap() {
        Value::Text(t) => assert!(t.starts_with("SCU"), "{t}"),
        other => panic!("{other:?}"),
    }
    assert!(matches!(client.get_value(DataIndex(0x0010)), Err(ScuError::InvalidArgument(_))), "a group");
    assert!(matches!(client.get(DataIndex(0x0017)), Err(ScuError::InvalidArgument(_))), "not in the list");
}

#[test]
fn writes_are_checked_before_anything_is_sent() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(ClientConfig::default());
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
    assert_eq!(rig.unit(|u| non_rc(u.stats())), before + 1);
}

#[test]
fn the_unit_refusing_is_a_device_error() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(ClientConfig::default());
    let err = client.start_motion(f(6), MotionDirection::Out).unwrap_err();
    assert!(matches!(err, ScuError::Refused { command: Command::Execute, status: Status::PermissionError }), "{err}");
    assert_eq!(err.class(), ErrorClass::Device);
}

#[test]
fn move_to_moves_and_ends_with_rs() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(ClientConfig::default());
    let seen = Mutex::new(Vec::new());
    let progress = |p: &motionlink_scu::client::MoveProgress| seen.lock().unwrap().push(p.position_counts);
    let report =
        client.move_to(a(1), 400, 80, &MoveOptions { progress: Some(&progress), ..Default::default() }).unwrap();
    assert_eq!(report.position_counts, 400);
    assert_eq!(report.function, f(1));
    // 400 counts at 88 counts/s: about 4.5 s.
    assert!((4_400..=5_300).contains(&report.duration.as_millis()), "{:?}", report.duration);
    let seen = seen.into_inner().unwrap();
    assert!(seen.len() > 30 && seen.windows(2).all(|w| w[0] <= w[1]), "progress rises: {seen:?}");
    assert!(client.started_functions().is_empty(), "RS was sent");
    assert!(rig.unit(|u| u.executed_functions().is_empty()));
    assert_eq!(rig.unit(|u| u.position(a(1))), Some(400));
    assert_eq!(rig.unit(|u| u.stats().watchdog_expiries), 0);
}

#[test]
fn move_to_with_another_function_mapping() {
    let rig = Rig::new(SimConfig::tlt());
    let config = ClientConfig {
        function_map: motionlink_scu::client::FunctionMap::scp11().with(a(1), f(2)).with(a(2), f(3)),
        ..Default::default()
    };
    let client = rig.client(config);
    client.move_to(a(2), 120, 100, &MoveOptions::default()).unwrap();
    assert_eq!(
        rig.unit(|u| (u.position(a(1)), u.position(a(2)))),
        (Some(-3), Some(120)),
        "a TLT reads -3 at its In end"
    );
    // F1 drives both columns of a TLT together, each to its own remote position.
    client.move_to(a(1), 200, 100, &MoveOptions { function: Some(f(1)), ..Default::default() }).unwrap();
    assert_eq!(rig.unit(|u| (u.position(a(1)), u.position(a(2)))), (Some(200), Some(120)));
}

#[test]
fn cancel_stops_the_actuator_at_once() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(ClientConfig::default());
    let cancel = CancelToken::new();
    let progress = |p: &motionlink_scu::client::MoveProgress| {
        if p.position_counts > 100 {
            cancel.cancel();
        }
    };
    let err = client
        .move_to(
            a(1),
            800,
            100,
            &MoveOptions { cancel: Some(&cancel), progress: Some(&progress), ..Default::default() },
        )
        .unwrap_err();
    let ScuError::Cancelled { position_counts, .. } = err else { panic!("{err}") };
    assert!((100..130).contains(&position_counts));
    assert!(!rig.unit(|u| u.is_moving(a(1))), "stopped");
    assert!(client.started_functions().is_empty());
    rig.sleep(1000);
    assert!(rig.unit(|u| u.position(a(1))).unwrap() < 140, "and stays stopped");
}

#[test]
fn a_stalled_actuator_is_stopped_and_reported() {
    let rig = Rig::new(SimConfig::tlt());
    let client = rig.client(ClientConfig::default());
    let err = client.move_to(a(1), 300, 20, &MoveOptions { function: Some(f(2)), ..Default::default() }).unwrap_err();
    assert!(matches!(err, ScuError::Stalled { position_counts: 0, .. }), "{err}");
    assert_eq!(err.class(), ErrorClass::Device);
    assert!(!rig.unit(|u| u.any_moving()));
    assert!(rig.unit(|u| u.executed_functions().is_empty()), "RS was sent after the stall");
}

#[test]
fn a_move_that_ends_short_of_its_target_reports_the_error_code() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(ClientConfig::default());
    // Beyond the stroke: the drive stops at its Out end.
    let err = client.move_to(a(2), 2000, 100, &MoveOptions::default()).unwrap_err();
    assert!(matches!(err, ScuError::MotionEnded { position_counts: 865, target_counts: 2000, .. }), "{err}");
}

#[test]
fn a_drive_fault_during_a_move_is_reported() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(ClientConfig::default());
    let progress = |p: &motionlink_scu::client::MoveProgress| {
        if p.position_counts > 50 {
            rig.unit(|u| u.inject_error(ErrorCode::from_bit(15)));
        }
    };
    let err =
        client.move_to(a(1), 600, 100, &MoveOptions { progress: Some(&progress), ..Default::default() }).unwrap_err();
    let ScuError::MotionEnded { error_code, .. } = err else { panic!("{err}") };
    assert!(error_code.has(15), "{error_code}");
}

#[test]
fn dropping_the_client_stops_what_it_started_and_leaves_remote_mode() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(ClientConfig::default());
    client.set(DataIndex(0x3021), &Value::RemotePosition(800)).unwrap();
    client.set(DataIndex(0x3022), &Value::RemotePosition(800)).unwrap();
    client.start_motion(f(1), MotionDirection::RemotePosition).unwrap();
    client.start_motion(f(2), MotionDirection::RemotePosition).unwrap();
    client.switch(Function::Buzzer, true).unwrap();
    rig.sleep(500);
    assert!(rig.unit(|u| u.is_moving(a(1)) && u.is_moving(a(2))));
    assert_eq!(client.started_functions(), vec![0, 1, 10]);
    drop(client);
    assert!(!rig.unit(|u| u.any_moving()), "both drives stopped");
    assert!(rig.unit(|u| u.executed_functions().is_empty()), "every RE got its RS");
    assert_eq!(rig.unit(|u| u.mode()), RemoteMode::Off, "RA");
}

#[test]
fn a_corrupt_reply_to_a_read_is_retried() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(ClientConfig::default());
    rig.sleep(50); // between keepalives
    rig.faults().corrupt_next(Direction::DeviceToHost, 0x40);
    assert_eq!(client.position(a(1)).unwrap(), 0);
    assert_eq!(client.stats().retries, 1);
    // Corrupting a middle byte makes a CRC error instead of a lost start: also retried at once.
    let faults = rig.faults();
    faults.inject(
        Direction::DeviceToHost,
        faults.bytes_sent(Direction::DeviceToHost) + 6,
        Fault::Corrupt { xor: 0x01 },
    );
    assert_eq!(client.position(a(1)).unwrap(), 0);
    assert_eq!(client.stats().retries, 2);
    assert_eq!(rig.unit(|u| u.stats().watchdog_expiries), 0, "the retries kept inside the watchdog");
}

#[test]
fn a_corrupt_request_gets_cse_and_is_sent_again_even_for_re() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(ClientConfig::default());
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
fn a_lost_reply_to_re_is_not_repeated() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(ClientConfig::default());
    rig.sleep(50);
    // The RE reply (5 bytes) is lost on its way back.
    rig.faults().drop_next(Direction::DeviceToHost, 5);
    let err = client.start_motion(f(1), MotionDirection::Out).unwrap_err();
    assert!(matches!(err, ScuError::Timeout { command: Command::Execute, attempts: 1, .. }), "{err}");
    assert_eq!(client.stats().retries, 0);
    assert_eq!(client.started_functions(), vec![0], "counted as started: the motion may be running");
    // The keepalive did not run for the 2 s the reply was awaited: the unit stopped the drive itself, and
    // with Safety_ID 0 it refuses everything but RO, RA and RC.
    assert!(!rig.unit(|u| u.is_moving(a(1))));
    assert_eq!(rig.unit(|u| u.mode()), RemoteMode::Locked);
    assert_eq!(rig.unit(|u| u.executed_functions()), vec![1]);
    // Dropping the client still gets the RS to the unit: the PE makes it open remote mode again first.
    drop(client);
    assert!(rig.unit(|u| u.executed_functions().is_empty()), "the RE got its RS");
    assert_eq!(rig.unit(|u| u.mode()), RemoteMode::Off, "RA");
}

#[test]
fn after_a_watchdog_lockout_the_session_opens_remote_mode_again() {
    let (rig, client) = watchdog_expires_after_500_ms(SafetyId::StopAllAndLock);
    assert_eq!(rig.unit(|u| u.mode()), RemoteMode::Locked);
    rig.faults().heal();
    // The keepalive's RC, sent again, reaches the unit; the read is refused with PE, and the session sends RO
    // and RC before reading again.
    assert_eq!(client.position(a(1)).unwrap(), rig.unit(|u| u.position(a(1)).unwrap()));
    assert_eq!(client.stats().reopens, 1);
    assert!(matches!(rig.unit(|u| u.mode()), RemoteMode::Active(SafetyId::StopAllAndLock)));
    // An RE after the lockout is not repeated for the caller, but is accepted once remote mode is open again.
    client.start_motion(f(1), MotionDirection::In).unwrap();
    drop(client);
    assert!(rig.unit(|u| u.executed_functions().is_empty()), "every RE got its RS");
}

#[test]
fn a_slow_unit_is_given_the_full_reply_timeout_and_its_late_replies_are_dropped() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(ClientConfig::default());
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
    assert_eq!(client.position(a(1)).unwrap(), 0);
    assert!(rig.clock.now() - started >= Duration::from_millis(300));
    assert_eq!(client.stats().retries, 1);
    assert_eq!(rig.unit(|u| u.stats().telegrams), telegrams + 2, "two sendings of the RG");
    // The reply to the second sending (position 0 as well) must not answer the next read.
    assert_eq!(client.position(a(2)).unwrap(), a2);
    assert_eq!(rig.unit(|u| u.stats().watchdog_expiries), 0);
}

#[test]
fn reads_give_up_after_the_retries_with_a_timeout() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(ClientConfig::default());
    rig.sleep(50);
    rig.faults().drop_next(Direction::DeviceToHost, 10_000);
    let started = rig.clock.now();
    let err = client.position(a(1)).unwrap_err();
    // Sent at 0, 150, 450 and 1050 ms; no reply within the manual's 2000 ms.
    assert!(matches!(err, ScuError::Timeout { command: Command::Get, attempts: 4, .. }), "{err}");
    let waited = rig.clock.now() - started;
    assert!(waited >= Duration::from_millis(2000) && waited < Duration::from_millis(2100), "{waited:?}");
    assert_eq!(err.class(), ErrorClass::Transport);
}

#[test]
fn port_loss_is_reported_and_reconnect_restores_the_session() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(ClientConfig::default());
    client.set(DataIndex(0x3021), &Value::RemotePosition(800)).unwrap();
    client.start_motion(f(1), MotionDirection::RemotePosition).unwrap();
    rig.sleep(300);
    rig.faults().disconnect();
    rig.sleep(300);
    assert!(!client.is_open());
    let err = client.position(a(1)).unwrap_err();
    assert!(matches!(err, ScuError::SessionLost(_)), "{err}");
    rig.sleep(1000);
    assert!(!rig.unit(|u| u.any_moving()), "the unit's watchdog stopped the drive");
    client.reconnect().unwrap();
    assert!(client.is_open());
    assert_eq!(*rig.connects.lock().unwrap(), 2);
    assert!(client.started_functions().is_empty(), "the RE of before got its RS after the reconnect");
    assert!(rig.unit(|u| u.executed_functions().is_empty()));
    assert!(client.position(a(1)).unwrap() > 0);
    assert_eq!(client.stats().reconnects, 1);
}

#[test]
fn a_failed_reconnect_leaves_the_session_lost_and_idle() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(ClientConfig::default());
    *rig.unplugged.lock().unwrap() = true;
    assert!(client.reconnect().is_err());
    assert!(!client.is_open(), "no port: the session is lost");
    assert!(matches!(client.position(a(1)), Err(ScuError::SessionLost(_))));
    // Without auto_reconnect nothing tries again by itself, and the keepalive thread sleeps (on a spinning
    // thread the manual clock could not advance ten seconds).
    rig.sleep(10_000);
    assert_eq!(*rig.connects.lock().unwrap(), 1);
    *rig.unplugged.lock().unwrap() = false;
    client.reconnect().unwrap();
    assert_eq!(client.position(a(1)).unwrap(), 0);
}

#[test]
fn a_move_whose_re_reply_is_corrupt_still_ends_with_rs() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(ClientConfig::default());
    rig.sleep(50);
    // move_to reads the position (11-byte reply), writes position and speed (two 5-byte ACKs), then RE:
    // corrupt the CRC of the RE's ACK.
    let faults = rig.faults();
    faults.inject(
        Direction::DeviceToHost,
        faults.bytes_sent(Direction::DeviceToHost) + 11 + 5 + 5 + 3,
        Fault::Corrupt { xor: 0x01 },
    );
    let err = client.move_to(a(1), 800, 100, &MoveOptions::default()).unwrap_err();
    assert!(matches!(err, ScuError::Corrupt { command: Command::Execute, .. }), "{err}");
    assert!(client.started_functions().is_empty(), "the RE that may have started the motion got its RS");
    assert!(rig.unit(|u| u.executed_functions().is_empty()));
    rig.sleep(500);
    assert!(!rig.unit(|u| u.any_moving()));
}

#[test]
fn a_keepalive_without_answer_does_not_give_up_the_port() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(ClientConfig::default());
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
    let client = rig.client(ClientConfig { auto_reconnect: true, ..Default::default() });
    rig.faults().disconnect();
    rig.sleep(3_000);
    assert!(client.is_open(), "reconnected by itself");
    assert!(*rig.connects.lock().unwrap() >= 2);
    assert_eq!(client.position(a(1)).unwrap(), 0);
    rig.sleep(10_000);
    assert!(client.is_open());
}

#[test]
fn keepalives_carry_a_cyclic_object() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(ClientConfig::default());
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
    assert!(s.bits as u8 & status1::MOTION != 0);
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
    let client = rig.client(ClientConfig::default());
    let history = client.error_history().unwrap();
    assert_eq!(history[0], ErrorCode::from_bit(12));
    assert!(history[1..].iter().all(|c| *c == ErrorCode::NONE));
    assert!(history[0].to_string().contains("overtemperature"));
}

#[test]
fn switching_functions() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(ClientConfig::default());
    client.switch(Function::BinaryOutput2, true).unwrap();
    assert_eq!(client.get_value(DataIndex(0x0110)).unwrap().to_string(), "0x02 [output2]");
    client.switch(Function::BinaryOutput2, false).unwrap();
    assert!(client.started_functions().is_empty());
    assert!(client.switch(Function::Motion(f(1)), true).is_err());
}
