//! The client against the emulator, in-process, on a manual clock that jumps ahead whenever every participant
//! waits: minutes of device time run in milliseconds, deterministically.

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use motionlink_link::cancel::CancelToken;
use motionlink_link::clock::{Clock, ManualClock, ParticipantGuard};
use motionlink_link::error::{Classify, ErrorClass, TransportKind};
use motionlink_link::link::{Connector, Link, LinkError};
use motionlink_link::pipe::{Direction, EmulatorHost, Fault, FaultControl, PipeConfig};
use motionlink_scu::model::Speed;
use motionlink_scu::model::{
    status1, Actuator, CyclicObject, DataIndex, ErrorCode, Function, MotionDirection, MotionFunction, SafetyId,
    StopMode,
};
use motionlink_scu::sim::{RemoteMode, SimConfig};
use motionlink_scu::value::Value;
use motionlink_scu::wire::{Command, Status};
use motionlink_scu::Emulator;
use motionlink_scu::{Client, ClientConfig, Error, FunctionMap, MoveOptions, MovePolling, StrokeLimits};

/// Called with every request the client sends (its bytes) and the fault control, just before it is sent: a
/// test arranges faults for that request's reply (its first byte is the next one the unit sends).
type Hook = Arc<dyn Fn(&[u8], &FaultControl) + Send + Sync>;

/// A link that runs a [`Hook`] on each request it sends.
struct Hooked {
    inner: Box<dyn Link>,
    faults: FaultControl,
    hook: Hook,
}

impl Link for Hooked {
    fn send(&mut self, bytes: &[u8]) -> Result<(), LinkError> {
        (self.hook)(bytes, &self.faults);
        self.inner.send(bytes)
    }
    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, LinkError> {
        self.inner.recv(buf, timeout)
    }
    fn discard_input(&mut self) -> Result<(), LinkError> {
        self.inner.discard_input()
    }
    fn describe(&self) -> String {
        self.inner.describe()
    }
}

struct Rig {
    clock: ManualClock,
    host: EmulatorHost<Emulator>,
    faults: Arc<Mutex<Option<FaultControl>>>,
    hook: Arc<Mutex<Option<Hook>>>,
    connects: Arc<Mutex<u32>>,
    /// While set, opening the port fails (the adapter is unplugged).
    unplugged: Arc<Mutex<bool>>,
    _me: ParticipantGuard,
}

impl Rig {
    fn new(config: SimConfig) -> Rig {
        let clock = ManualClock::new_auto();
        let me = clock.reserve_participant().enter();
        let host = EmulatorHost::new(Emulator::new(config).unwrap(), clock.shared(), PipeConfig::paced(38_400));
        Rig {
            clock,
            host,
            faults: Arc::default(),
            hook: Arc::default(),
            connects: Arc::default(),
            unplugged: Arc::default(),
            _me: me,
        }
    }

    fn connector(&self) -> Connector {
        let host = self.host.clone();
        let faults = Arc::clone(&self.faults);
        let connects = Arc::clone(&self.connects);
        let unplugged = Arc::clone(&self.unplugged);
        let hook = Arc::clone(&self.hook);
        Box::new(move || {
            if *unplugged.lock().unwrap() {
                return Err(LinkError::Disconnected { port: "sim".into(), reason: "unplugged".into() });
            }
            let (link, f) = host.connect();
            *faults.lock().unwrap() = Some(f.clone());
            *connects.lock().unwrap() += 1;
            let hook = Arc::clone(&hook);
            let hook: Hook = Arc::new(move |bytes: &[u8], faults: &FaultControl| {
                let h = hook.lock().unwrap().clone();
                if let Some(h) = h {
                    h(bytes, faults);
                }
            });
            Ok(Box::new(Hooked { inner: Box::new(link), faults: f, hook }) as Box<dyn Link>)
        })
    }

    fn client(&self, config: ClientConfig) -> Client {
        Client::open(self.connector(), self.clock.shared(), config).unwrap()
    }

    /// From now on, `hook` sees every request before it is sent.
    fn on_request(&self, hook: impl Fn(&[u8], &FaultControl) + Send + Sync + 'static) {
        *self.hook.lock().unwrap() = Some(Arc::new(hook));
    }

    fn faults(&self) -> FaultControl {
        self.faults.lock().unwrap().clone().unwrap()
    }

    fn unit<R>(&self, f: impl FnOnce(&mut Emulator) -> R) -> R {
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

fn pct(n: u16) -> Speed {
    Speed::percent(n).unwrap()
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
    let client = Client::open(connector, rig.clock.shared(), ClientConfig::default()).unwrap();
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
    let err = Client::open(
        rig.connector(),
        rig.clock.shared(),
        ClientConfig { keepalive_period: Duration::from_millis(451), ..Default::default() },
    )
    .unwrap_err();
    assert!(matches!(err, Error::InvalidArgument(_)), "{err}");
    assert_eq!(*rig.connects.lock().unwrap(), 0, "nothing was opened");
    // 450 ms is allowed and keeps the unit alive.
    let client = rig.client(ClientConfig { keepalive_period: Duration::from_millis(450), ..Default::default() });
    rig.sleep(10_000);
    assert_eq!(rig.unit(|u| u.stats().watchdog_expiries), 0);
    drop(client);
}

/// Starts a long move, then the host falls silent (every byte to the unit lost, as when the program is killed):
/// the unit's own watchdog must stop the drive 500 ms after the last RC it received.
fn watchdog_expires_after_500_ms(safety: SafetyId) -> (Rig, Client) {
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
    // What the emulator reports (`motionlink sim scu --events` prints the same lines).
    let events = rig.unit(motionlink_link::emulator::Emulator::take_events);
    let expiry = format!("remote mode ended by watchdog (Safety_ID {})", safety.code());
    let at = events.iter().position(|e| e.starts_with(&expiry)).unwrap_or_else(|| panic!("{events:?}"));
    assert!(events[at + 1].starts_with("A1 at rest"), "{events:?}");
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
    assert!(matches!(client.get_value(DataIndex(0x0010)), Err(Error::InvalidArgument(_))), "a group");
    assert!(matches!(client.get(DataIndex(0x0017)), Err(Error::InvalidArgument(_))), "not in the list");
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
    assert_eq!(rig.unit(|u| non_rc(u.stats())), before + 2, "the RT, and the RG that reads the value back");
}

#[test]
fn the_unit_refusing_is_a_device_error() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(ClientConfig::default());
    let err = client.start_motion(f(6), MotionDirection::Out).unwrap_err();
    assert!(matches!(err, Error::Refused { command: Command::Execute, status: Status::PermissionError }), "{err}");
    assert_eq!(err.class(), ErrorClass::Refused);
}

#[test]
fn move_to_moves_and_ends_with_rs() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(ClientConfig::default());
    let seen = Mutex::new(Vec::new());
    let progress = |p: &motionlink_scu::session::MoveProgress| seen.lock().unwrap().push(p.position_counts);
    let report =
        client.move_to(a(1), 400, pct(80), &MoveOptions { progress: Some(&progress), ..Default::default() }).unwrap();
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
fn move_to_with_the_tlt_function_map() {
    let rig = Rig::new(SimConfig::tlt());
    let client = rig.client(ClientConfig { function_map: FunctionMap::tlt(), ..Default::default() });
    // F3 drives column 2 alone.
    let report =
        client.move_to(a(2), 120, pct(100), &MoveOptions { function: Some(f(3)), ..Default::default() }).unwrap();
    assert_eq!(report.actuators.len(), 1);
    assert_eq!(
        rig.unit(|u| (u.position(a(1)), u.position(a(2)))),
        (Some(-3), Some(120)),
        "a TLT reads -3 at its In end"
    );
    // F1 drives both columns of a TLT: move_to gives both the target. (Before, only A1's remote position was
    // written, and A2 ran to whatever its remote position held.)
    let report = client.move_to(a(1), 200, pct(100), &MoveOptions::default()).unwrap();
    assert_eq!(rig.unit(|u| (u.position(a(1)), u.position(a(2)))), (Some(200), Some(200)));
    assert_eq!(report.function, f(1));
    let each: Vec<_> = report.actuators.iter().map(|o| (o.actuator, o.position_counts, o.moved)).collect();
    assert_eq!(each, [(a(1), 200, true), (a(2), 200, true)]);
    // A function that does not drive the actuator is refused before anything is sent.
    let err =
        client.move_to(a(1), 300, pct(100), &MoveOptions { function: Some(f(3)), ..Default::default() }).unwrap_err();
    assert_eq!(err.class(), ErrorClass::Usage, "{err}");
}

#[test]
fn cancel_stops_the_actuator_at_once() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(ClientConfig::default());
    let cancel = CancelToken::new();
    let progress = |p: &motionlink_scu::session::MoveProgress| {
        if p.position_counts > 100 {
            cancel.cancel();
        }
    };
    let err = client
        .move_to(
            a(1),
            800,
            pct(100),
            &MoveOptions { cancel: Some(&cancel), progress: Some(&progress), ..Default::default() },
        )
        .unwrap_err();
    let Error::Cancelled { position_counts, .. } = err else { panic!("{err}") };
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
    let err =
        client.move_to(a(1), 300, pct(20), &MoveOptions { function: Some(f(2)), ..Default::default() }).unwrap_err();
    assert!(matches!(err, Error::Stalled { position_counts: 0, .. }), "{err}");
    assert_eq!(err.class(), ErrorClass::Device);
    assert!(!rig.unit(|u| u.any_moving()));
    assert!(rig.unit(|u| u.executed_functions().is_empty()), "RS was sent after the stall");
}

#[test]
fn a_target_outside_the_stroke_is_refused_before_anything_moves() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(ClientConfig::default());
    let remote_before = client.get_value(DataIndex(0x3022)).unwrap();
    let err = client.move_to(a(2), 2000, pct(100), &MoveOptions::default()).unwrap_err();
    let Error::OutsideStroke { actuator, target_counts: 2000, min_counts: 0, max_counts: 865, .. } = err else {
        panic!("{err}")
    };
    assert_eq!(actuator, a(2));
    assert!(err.to_string().contains("virtual limits"), "names where the limit comes from: {err}");
    assert_eq!(err.class(), ErrorClass::Usage);
    assert_eq!(client.get_value(DataIndex(0x3022)).unwrap(), remote_before, "nothing was written");
    assert!(rig.unit(|u| u.executed_functions().is_empty() && !u.any_moving()));
    // Below the In end as well; and a configured stroke replaces the unit's.
    assert!(matches!(client.move_to(a(1), -1, pct(100), &MoveOptions::default()), Err(Error::OutsideStroke { .. })));
    drop(client);
    let mut limits = [None; 6];
    limits[0] = Some(StrokeLimits { min_counts: 0, max_counts: 300 });
    let client = rig.client(ClientConfig { stroke_limits: limits, ..Default::default() });
    let err = client.move_to(a(1), 400, pct(100), &MoveOptions::default()).unwrap_err();
    assert!(matches!(err, Error::OutsideStroke { max_counts: 300, limits_from: "as configured", .. }), "{err}");
}

#[test]
fn a_move_that_ends_short_of_its_target_names_target_position_and_difference() {
    let rig = Rig::new(SimConfig::default());
    // A stroke configured wider than the unit's: the unit stops at its Out end, 865.
    let mut limits = [None; 6];
    limits[1] = Some(StrokeLimits { min_counts: 0, max_counts: 2000 });
    let config = ClientConfig { stroke_limits: limits, function_map: FunctionMap::scp11(), ..Default::default() };
    let client = rig.client(config);
    let err = client.move_to(a(2), 900, pct(100), &MoveOptions::default()).unwrap_err();
    assert!(
        matches!(err, Error::MotionEnded { position_counts: 865, target_counts: 900, tolerance_counts: 5, .. }),
        "{err}"
    );
    let text = err.to_string();
    assert!(text.contains("865") && text.contains("900") && text.contains("-35 counts"), "{text}");
    assert_eq!(err.class(), ErrorClass::Device);
    assert!(client.started_functions().is_empty(), "RS after the failure");
}

#[test]
fn a_drive_fault_during_a_move_is_reported() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(ClientConfig::default());
    let progress = |p: &motionlink_scu::session::MoveProgress| {
        if p.position_counts > 50 {
            rig.unit(|u| u.inject_error(ErrorCode::from_bit(15)));
        }
    };
    let err = client
        .move_to(a(1), 600, pct(100), &MoveOptions { progress: Some(&progress), ..Default::default() })
        .unwrap_err();
    let Error::MotionEnded { error_code, .. } = err else { panic!("{err}") };
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
fn a_lost_reply_to_re_is_sent_again_because_every_re_names_an_absolute_destination() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(ClientConfig::default());
    rig.sleep(50);
    // The RE reply (5 bytes) is lost on its way back: after 150 ms of silence the session sends the zeros that
    // would complete a half-received telegram, and the RE again. The unit drives F1 to its Out end either way.
    rig.faults().drop_next(Direction::DeviceToHost, 5);
    client.start_motion(f(1), MotionDirection::Out).unwrap();
    assert_eq!(client.stats().retries, 1);
    assert_eq!(client.stats().flushes, 1);
    assert_eq!(client.started_functions(), vec![0]);
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
    assert_eq!(client.position(a(1)).unwrap(), rig.unit(|u| u.position(a(1)).unwrap()));
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
fn reads_give_up_after_a_second_of_silence_and_later_requests_get_one_short_try() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(ClientConfig::default());
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
    assert!(matches!(client.position(a(1)), Ok(0) | Err(Error::RemoteEnded(_))));
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
    assert!(matches!(err, Error::SessionLost(_)), "{err}");
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
    assert!(matches!(client.position(a(1)), Err(Error::SessionLost(_))));
    // Without auto_reconnect nothing tries again by itself, and the keepalive thread sleeps (on a spinning
    // thread the manual clock could not advance ten seconds).
    rig.sleep(10_000);
    assert_eq!(*rig.connects.lock().unwrap(), 1);
    *rig.unplugged.lock().unwrap() = false;
    client.reconnect().unwrap();
    assert_eq!(client.position(a(1)).unwrap(), 0);
}

#[test]
fn a_corrupt_reply_to_the_re_of_a_move_is_repeated_and_the_move_ends_with_rs() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(ClientConfig { function_map: FunctionMap::scp11(), ..Default::default() });
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
    let report = client.move_to(a(1), 200, pct(100), &MoveOptions::default()).unwrap();
    assert!(*done.lock().unwrap());
    assert_eq!(report.position_counts, 200);
    assert_eq!(client.stats().retries, 1);
    assert!(client.started_functions().is_empty(), "RS at the end");
    assert!(rig.unit(|u| u.executed_functions().is_empty()));
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

// ---------------------------------------------------------------------------------------------------------
// Keepalive timing, corrupted lengths, bit flips, dead links

/// Records the clock time of every keepalive RC (`52 43 01 00 FF ..`) the client sends.
fn record_keepalives(rig: &Rig) -> Arc<Mutex<Vec<Duration>>> {
    let times = Arc::new(Mutex::new(Vec::new()));
    let sink = Arc::clone(&times);
    let clock = rig.clock.shared();
    rig.on_request(move |bytes, _| {
        if bytes.starts_with(&[0x52, 0x43, 0x01, 0x00, 0xFF]) {
            sink.lock().unwrap().push(clock.now().since_origin());
        }
    });
    times
}

#[test]
fn the_keepalive_keeps_its_grid_of_deadlines_while_the_caller_keeps_the_line_busy() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(ClientConfig::default());
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

/// A link whose received bytes reach the client `latency` after they arrived: a slow gateway.
struct Latency {
    inner: Box<dyn Link>,
    clock: motionlink_link::SharedClock,
    latency: Arc<Mutex<Duration>>,
    queue: std::collections::VecDeque<(motionlink_link::Timestamp, u8)>,
}

impl Latency {
    fn pull(&mut self, timeout: Duration) -> Result<(), LinkError> {
        let mut tmp = [0u8; 256];
        let n = self.inner.recv(&mut tmp, timeout)?;
        let now = self.clock.now();
        self.queue.extend(tmp[..n].iter().map(|b| (now, *b)));
        Ok(())
    }
}

impl Link for Latency {
    fn send(&mut self, bytes: &[u8]) -> Result<(), LinkError> {
        self.inner.send(bytes)
    }
    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, LinkError> {
        let deadline = self.clock.now() + timeout;
        loop {
            let now = self.clock.now();
            let mut n = 0;
            let latency = *self.latency.lock().unwrap();
            while n < buf.len() && self.queue.front().is_some_and(|(t, _)| *t + latency <= now) {
                buf[n] = self.queue.pop_front().unwrap().1;
                n += 1;
            }
            if n > 0 || now >= deadline {
                return Ok(n);
            }
            let until = self.queue.front().map_or(deadline, |(t, _)| (*t + latency).min(deadline));
            self.pull(until.saturating_since(now))?;
        }
    }
    fn discard_input(&mut self) -> Result<(), LinkError> {
        self.queue.clear();
        self.inner.discard_input()
    }
    fn describe(&self) -> String {
        self.inner.describe()
    }
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
    let client = Client::open(connector, rig.clock.shared(), ClientConfig::default()).unwrap();
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
    let client = Client::open(
        connector,
        rig.clock.shared(),
        ClientConfig { function_map: FunctionMap::scp11(), ..Default::default() },
    )
    .unwrap();
    // Once the actuator moves, every reply takes 300 ms more; when it stops, the line is quick again.
    let slow_polls = Mutex::new(0);
    let progress = |p: &motionlink_scu::session::MoveProgress| {
        let moving = p.status & status1::MOTION != 0;
        *latency.lock().unwrap() = if moving { Duration::from_millis(300) } else { Duration::ZERO };
        *slow_polls.lock().unwrap() += u32::from(moving);
    };
    let report =
        client.move_to(a(1), 500, pct(100), &MoveOptions { progress: Some(&progress), ..Default::default() }).unwrap();
    assert_eq!(report.position_counts, 500);
    assert!(*slow_polls.lock().unwrap() > 5);
    assert_eq!(rig.unit(|u| u.stats().watchdog_expiries), 0, "the unit never lost its RC");
    assert!(client.started_functions().is_empty());
    client.close().unwrap();
}

#[test]
fn a_corrupted_length_byte_in_a_request_costs_less_than_one_reply_timeout_and_loses_nothing() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(ClientConfig::default());
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
    let client = rig.client(ClientConfig::default());
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
    let client = rig.client(ClientConfig { function_map: FunctionMap::scp11(), ..Default::default() });
    let faults = rig.faults();
    faults.inject(dir, faults.bytes_sent(dir) + offset, Fault::Corrupt { xor: 1 << bit });
    let result = client.move_to(a(1), 60, pct(100), &MoveOptions::default()).map(|r| r.position_counts);
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
    let client = rig.client(ClientConfig { function_map: FunctionMap::scp11(), ..Default::default() });
    let cut_at = Arc::new(Mutex::new(None));
    let cut = Arc::clone(&cut_at);
    let clock = rig.clock.shared();
    let faults = Arc::clone(&rig.faults);
    let progress = move |p: &motionlink_scu::session::MoveProgress| {
        let mut cut = cut.lock().unwrap();
        if p.position_counts > 100 && cut.is_none() {
            // The cable is cut: nothing gets through either way any more.
            let f = faults.lock().unwrap().clone().unwrap();
            f.drop_next(Direction::HostToDevice, u64::MAX / 2);
            f.drop_next(Direction::DeviceToHost, u64::MAX / 2);
            *cut = Some(clock.now());
        }
    };
    let err = client
        .move_to(a(1), 800, pct(100), &MoveOptions { progress: Some(&progress), ..Default::default() })
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
    let client = rig.client(ClientConfig { function_map: FunctionMap::scp11(), ..Default::default() });
    let faults = Arc::clone(&rig.faults);
    let progress = move |p: &motionlink_scu::session::MoveProgress| {
        if p.position_counts > 100 {
            faults.lock().unwrap().clone().unwrap().disconnect();
        }
    };
    let err = client
        .move_to(a(1), 800, pct(100), &MoveOptions { progress: Some(&progress), ..Default::default() })
        .unwrap_err();
    let Error::StopUnconfirmed { cause, .. } = &err else { panic!("{err}") };
    assert!(matches!(**cause, Error::SessionLost(_)), "{cause}");
    assert!(err.to_string().contains("may still be moving"));
    rig.sleep(600);
    assert!(!rig.unit(|u| u.any_moving()), "the unit's watchdog stopped it");
}

#[test]
fn a_function_that_drives_two_actuators_moves_each_to_its_own_target_with_one_re() {
    let rig = Rig::new(SimConfig::liftkit());
    let client = rig.client(ClientConfig { function_map: FunctionMap::liftkit(), ..Default::default() });
    let f8 = f(8);
    let report = client.move_function(f8, &[(a(1), 300), (a(2), 320)], pct(100), &MoveOptions::default()).unwrap();
    let each: Vec<_> =
        report.actuators.iter().map(|o| (o.actuator, o.position_counts, o.difference_counts())).collect();
    assert_eq!(each, [(a(1), 300, 0), (a(2), 320, 0)]);
    assert_eq!(rig.unit(|u| (u.position(a(1)), u.position(a(2)))), (Some(300), Some(320)));
    assert!(rig.unit(|u| u.executed_functions().is_empty()), "RS of F8 at the end");
    // The map is checked before anything is sent: F8 drives both, F1 only A1.
    let before = rig.unit(|u| u.stats().telegrams - u.stats().cyclic);
    for (function, targets) in
        [(f8, vec![(a(1), 10)]), (f(1), vec![(a(1), 10), (a(2), 10)]), (f8, vec![(a(1), 1), (a(1), 2)])]
    {
        let err = client.move_function(function, &targets, pct(100), &MoveOptions::default()).unwrap_err();
        assert_eq!(err.class(), ErrorClass::Usage, "{err}");
    }
    assert_eq!(rig.unit(|u| u.stats().telegrams - u.stats().cyclic), before);
    // One of them cannot go there: the move is refused before either moves.
    let err = client.move_function(f8, &[(a(1), 100), (a(2), 900)], pct(100), &MoveOptions::default()).unwrap_err();
    assert!(matches!(err, Error::OutsideStroke { target_counts: 900, .. }), "{err}");
    assert_eq!(rig.unit(|u| (u.position(a(1)), u.position(a(2)))), (Some(300), Some(320)));
}

#[test]
fn without_a_function_map_move_to_gives_every_connected_actuator_the_target_and_reports_the_ones_that_moved() {
    // A TLT, of which the client is not told: F1 drives both columns, and both end at 400.
    let rig = Rig::new(SimConfig::tlt());
    let client = rig.client(ClientConfig::default());
    let report = client.move_to(a(1), 400, pct(100), &MoveOptions::default()).unwrap();
    assert_eq!(rig.unit(|u| (u.position(a(1)), u.position(a(2)))), (Some(400), Some(400)));
    let each: Vec<_> = report.actuators.iter().map(|o| (o.actuator, o.position_counts, o.moved)).collect();
    assert_eq!(each, [(a(1), 400, true), (a(2), 400, true)]);
    // An SCP11 unit: F1 drives A1 alone; A2 gets the remote position but does not move, and is reported so.
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(ClientConfig::default());
    let report = client.move_to(a(1), 400, pct(100), &MoveOptions::default()).unwrap();
    let each: Vec<_> = report.actuators.iter().map(|o| (o.actuator, o.position_counts, o.moved)).collect();
    assert_eq!(each, [(a(1), 400, true), (a(2), 0, false)]);
    assert_eq!(client.get_value(DataIndex(0x3022)).unwrap(), Value::RemotePosition(400));
}

#[test]
fn a_move_polls_at_its_interval_and_not_as_fast_as_the_line_answers() {
    // Polling with reads (the choice when the keepalive cannot carry the poll object).
    let rig = Rig::new(SimConfig::default());
    let reads = MovePolling::Reads;
    let client =
        rig.client(ClientConfig { function_map: FunctionMap::scp11(), move_polling: reads, ..Default::default() });
    let before = rig.unit(|u| u.stats().telegrams - u.stats().cyclic);
    let report = client.move_to(a(1), 400, pct(100), &MoveOptions::default()).unwrap();
    let requests = rig.unit(|u| u.stats().telegrams - u.stats().cyclic) - before;
    // Two reads per 50 ms poll, plus a dozen for setting up and ending the move.
    let polls = report.duration.as_millis() as u64 / 50;
    assert!(requests <= 2 * polls + 16, "{requests} requests for {polls} polls");
    assert!(requests >= 2 * polls - 4, "{requests} requests for {polls} polls");
    drop(client);
    let client = rig.client(ClientConfig {
        function_map: FunctionMap::scp11(),
        poll_interval: Duration::from_millis(200),
        move_polling: reads,
        ..Default::default()
    });
    let before = rig.unit(|u| u.stats().telegrams - u.stats().cyclic);
    let report = client.move_to(a(1), 0, pct(100), &MoveOptions::default()).unwrap();
    let requests = rig.unit(|u| u.stats().telegrams - u.stats().cyclic) - before;
    assert!(requests <= 2 * (report.duration.as_millis() as u64 / 200) + 16, "{requests}");
}

#[test]
fn a_move_polls_through_the_keepalive_at_its_interval_and_sends_nothing_else_while_the_motion_runs() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(ClientConfig { function_map: FunctionMap::scp11(), ..Default::default() });
    // Every request the session sends, with whether the unit's actuator moved when it went out.
    let sent = Arc::new(Mutex::new(Vec::new()));
    let sink = Arc::clone(&sent);
    let host = rig.host.clone();
    rig.on_request(move |bytes, _| {
        sink.lock().unwrap().push((bytes[..2].to_vec(), host.with_device(|u| u.is_moving(a(1)))));
    });
    let cyclic_before = rig.unit(|u| u.stats().cyclic);
    let report = client.move_to(a(1), 400, pct(100), &MoveOptions::default()).unwrap();
    assert_eq!(report.position_counts, 400);
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
    let client =
        rig.client(ClientConfig { function_map: FunctionMap::scp11(), move_polling: reads, ..Default::default() });
    // Every position read is recorded with whether the unit reported motion just before.
    let reads = Arc::new(Mutex::new(Vec::new()));
    let sink = Arc::clone(&reads);
    let host = rig.host.clone();
    rig.on_request(move |bytes, _| {
        if bytes.starts_with(&[0x52, 0x47, 0x11, 0x00]) {
            sink.lock().unwrap().push(host.with_device(|u| u.is_moving(a(1))));
        }
    });
    let report = client.move_to(a(1), 300, pct(100), &MoveOptions::default()).unwrap();
    let reads = reads.lock().unwrap();
    assert_eq!(reads.last(), Some(&false), "the last position read came after the motion ended");
    assert_eq!(report.position_counts, 300);
}

#[test]
fn a_move_polled_through_the_keepalive_judges_the_reply_that_reports_the_end_of_the_motion() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(ClientConfig { function_map: FunctionMap::scp11(), ..Default::default() });
    // Every RC that carries the poll object (CyclicObj 5: object index 4), with whether the unit moved.
    let polls = Arc::new(Mutex::new(Vec::new()));
    let sink = Arc::clone(&polls);
    let host = rig.host.clone();
    rig.on_request(move |bytes, _| {
        if bytes.starts_with(&[0x52, 0x43, 0x01, 0x00, 0x04]) {
            sink.lock().unwrap().push(host.with_device(|u| u.is_moving(a(1))));
        }
    });
    let report = client.move_to(a(1), 300, pct(100), &MoveOptions::default()).unwrap();
    let polls = polls.lock().unwrap();
    assert!(polls.iter().filter(|m| **m).count() > 20, "{polls:?}");
    assert_eq!(polls.last(), Some(&false), "the last poll came after the motion ended");
    assert_eq!(report.position_counts, 300);
    assert_eq!(rig.unit(|u| u.position(a(1))), Some(300));
}

#[test]
fn streamed_setpoints_retarget_a_running_motion_and_change_its_speed() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(ClientConfig { function_map: FunctionMap::scp11(), ..Default::default() });
    let mut stream = client.stream(f(1), &[a(1)], pct(100)).unwrap();
    stream.set_targets(&[600]).unwrap();
    rig.sleep(1_000);
    let p = stream.positions().unwrap()[0].1;
    assert!(p > 60 && p < 600, "{p}");
    // 20 Hz updates towards a moving target.
    for k in 0..20 {
        stream.set_targets(&[200 + 5 * k]).unwrap();
        rig.sleep(50);
    }
    stream.set_speed(pct(50)).unwrap();
    rig.sleep(5_000);
    let [(_, at, moving)] = stream.positions().unwrap()[..] else { panic!() };
    assert_eq!((at, moving), (295, false), "at the last setpoint");
    assert!(stream.set_targets(&[900]).is_err(), "beyond the stroke");
    assert!(stream.set_targets(&[1, 2]).is_err(), "one target per actuator");
    let rest = stream.stop(StopMode::Soft).unwrap();
    assert_eq!(rest, [(a(1), 295)]);
    assert!(client.started_functions().is_empty());
    // Dropping a running stream stops it.
    let mut stream = client.stream(f(1), &[a(1)], pct(100)).unwrap();
    stream.set_targets(&[800]).unwrap();
    rig.sleep(500);
    drop(stream);
    assert!(!rig.unit(|u| u.is_moving(a(1))));
    assert!(client.started_functions().is_empty());
    assert!(matches!(client.stream(f(1), &[a(2)], pct(100)), Err(Error::InvalidArgument(_))), "F1 drives A1");
    assert!(matches!(client.stream(f(1), &[a(1)], pct(0)), Err(Error::InvalidArgument(_))), "speed 0");
}

#[test]
fn cyclic_objects_may_name_groups() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(ClientConfig::default());
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

#[test]
fn safety_id_1_through_the_api_a_watchdog_lapse_during_a_move_is_reported_and_the_session_goes_on() {
    for safety in [SafetyId::StopAll, SafetyId::StopRemoteOnly] {
        let rig = Rig::new(SimConfig::default());
        let config = ClientConfig { safety_id: safety, function_map: FunctionMap::scp11(), ..Default::default() };
        let client = rig.client(config);
        assert_eq!(rig.unit(|u| u.mode()), RemoteMode::Active(safety));
        let faults = Arc::clone(&rig.faults);
        let clock = rig.clock.shared();
        let cut = Mutex::new(None);
        let progress = |p: &motionlink_scu::session::MoveProgress| {
            let f = faults.lock().unwrap().clone().unwrap();
            let mut cut = cut.lock().unwrap();
            match *cut {
                None if p.position_counts > 50 => {
                    // 700 ms in which nothing reaches the unit (all 8 polls' bytes and keepalives are lost).
                    f.drop_next(Direction::HostToDevice, u64::MAX / 2);
                    *cut = Some(clock.now());
                }
                Some(t) if clock.now() - t > Duration::from_millis(700) => f.heal(),
                _ => {}
            }
        };
        let err = client
            .move_to(a(1), 800, pct(100), &MoveOptions { progress: Some(&progress), ..Default::default() })
            .unwrap_err();
        assert_eq!(rig.unit(|u| u.stats().watchdog_expiries), 1, "{safety:?}");
        assert!(!rig.unit(|u| u.is_moving(a(1))));
        assert!(
            matches!(err, Error::RemoteEnded(_) | Error::MotionEnded { .. } | Error::StopUnconfirmed { .. }),
            "{err}"
        );
        rig.faults().heal();
        // The first request after that finds the lapse: the unit refuses it until an RC re-arms the watchdog,
        // and the session says that the motion it had started was stopped (once).
        let err = client.position(a(1)).unwrap_err();
        assert!(matches!(&err, Error::RemoteEnded(t) if t.contains("watchdog")), "{err}");
        assert!(client.is_open(), "Safety_ID 1 and 2 need no RO");
        assert!(client.started_functions().is_empty(), "the stopped function got its RS");
        // After the RC the session goes on.
        let report = client.move_to(a(1), 100, pct(100), &MoveOptions::default()).unwrap();
        assert_eq!(report.position_counts, 100, "{safety:?}");
        assert_eq!(client.stats().reopens, 0);
    }
}

#[test]
fn while_idle_a_lapse_with_safety_id_1_is_re_armed_and_a_lock_with_safety_id_0_is_reported() {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(ClientConfig { safety_id: SafetyId::StopAll, ..Default::default() });
    rig.faults().drop_next(Direction::HostToDevice, u64::MAX / 2);
    rig.sleep(1_500);
    rig.faults().heal();
    assert_eq!(rig.unit(|u| u.mode()), RemoteMode::TimedOut(SafetyId::StopAll));
    // Idle: the read goes through after the RC re-armed the watchdog; the lapse is counted.
    assert_eq!(client.position(a(1)).unwrap(), 0);
    assert_eq!(client.stats().watchdog_lapses, 1);
    assert!(client.is_open());
    drop(client);
    let client = rig.client(ClientConfig::default());
    rig.faults().drop_next(Direction::HostToDevice, u64::MAX / 2);
    rig.sleep(1_500);
    rig.faults().heal();
    assert_eq!(rig.unit(|u| u.mode()), RemoteMode::Locked);
    // Safety_ID 0: even idle, the session reports it and does not send RO by itself.
    assert!(matches!(client.position(a(1)), Err(Error::RemoteEnded(_))));
    assert_eq!(rig.unit(|u| u.mode()), RemoteMode::Locked);
    client.reopen().unwrap();
    assert_eq!(client.position(a(1)).unwrap(), 0);
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
    let clock = ManualClock::new_auto();
    let _me = clock.reserve_participant().enter();
    let host = EmulatorHost::new(
        ClampingUnit { unit: Emulator::new(SimConfig::default()).unwrap(), held: Vec::new() },
        clock.shared(),
        PipeConfig::paced(38_400),
    );
    let connector: Connector = Box::new(move || Ok(Box::new(host.connect().0) as Box<dyn Link>));
    let client = Client::open(connector, clock.shared(), ClientConfig::default()).unwrap();
    client.set(DataIndex(0x3011), &Value::RemoteSpeed(40)).unwrap();
    let err = client.set(DataIndex(0x3011), &Value::RemoteSpeed(80)).unwrap_err();
    let Error::ReadBack { name, written, read, .. } = &err else { panic!("{err}") };
    assert_eq!((*name, written.as_str(), read.as_str()), ("remote_speed_f1", "80", "50"));
    assert_eq!(err.class(), ErrorClass::Device);
    // A move whose speed does not read back is refused before RE.
    let err = client.move_to(a(1), 100, pct(80), &MoveOptions::default()).unwrap_err();
    assert!(matches!(err, Error::ReadBack { .. }), "{err}");
    assert!(client.started_functions().is_empty(), "no RE was sent");
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
