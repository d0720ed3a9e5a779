//! Links whose round trips take 290 ms (a serial gateway far away): between two RCs no other request fits
//! (RC, request, RC reach the unit 2 x 290 ms apart, beyond its 500 ms watchdog). A watch rides on the
//! keepalive RC through the session's cyclic object (on a link slow from the start, the object is defined
//! across one deliberate lapse of the watchdog, while the session has started nothing); a move that cannot
//! keep the watchdog fed is refused before anything moves; a unit that takes no cyclic object cannot be
//! watched there, and says so without ever starving the keepalive.

use crate::rig;

use motionlink_scu::Variant;
use rig::*;

const SLOW: Duration = Duration::from_millis(290);

fn scp11() -> Config {
    Config { function_map: FunctionMap::scp11(), ..Default::default() }
}

/// [`scp11`], and a watch may define its object across one lapse of the watchdog (the user's opt-in).
fn scp11_may_lapse() -> Config {
    Config { watch_may_lapse: true, ..scp11() }
}

#[test]
fn a_watch_rides_on_the_keepalive_when_round_trips_take_290_ms() {
    let rig = Rig::new(SimConfig::default());
    let latency = Arc::new(Mutex::new(Duration::ZERO));
    let client = rig.client_behind(&latency, scp11()).unwrap();
    // The first sample defines the session's cyclic object (an RT and its read-back need room on the line).
    assert_eq!(client.sample().unwrap().position(a(1)), PositionCounts(0));
    assert_eq!(client.capabilities().cyclic_objects, Some(true));
    // Actuator 1 moves out by the hand switch; the link becomes slow.
    rig.unit(|u| u.press_hand_switch(1, true));
    *latency.lock().unwrap() = SLOW;
    let others_before = rig.unit(|u| u.stats().telegrams - u.stats().cyclic);
    let mut samples = Vec::new();
    let n = client.watch(Duration::from_millis(500), Some(12), &mut |s| samples.push(*s)).unwrap();
    assert_eq!(n, 12);
    // A1 runs out at 110 counts/s towards its end at 865 counts.
    let positions: Vec<i32> = samples.iter().map(|s| s.position(a(1)).get()).collect();
    assert!(positions.windows(2).all(|w| w[1] > w[0]), "each sample sees A1 further out: {positions:?}");
    assert!(samples[1..].iter().all(|s| s.moving(a(1)) && s.currents_deci_amps[0] > 0), "{samples:?}");
    // A sample every 500 ms, each within a round trip of its time (the RC under way is waited for first).
    let gaps: Vec<u128> = samples.windows(2).map(|w| (w[1].at - w[0].at).as_millis()).collect();
    assert!(gaps.iter().all(|g| (200..=800).contains(g)), "{gaps:?}");
    let span = samples[11].at - samples[0].at;
    assert!(span >= Duration::from_millis(5200) && span <= Duration::from_millis(5800), "{span:?}");
    assert_eq!(rig.unit(|u| u.stats().telegrams - u.stats().cyclic), others_before, "nothing but RC was sent");
    assert_eq!(rig.unit(|u| u.stats().watchdog_expiries), 0, "the unit never lost its RC");
    rig.unit(|u| u.release_hand_switch());
    assert!(client.is_open());
    client.close().unwrap();
}

#[test]
fn a_watch_over_a_link_slow_from_the_start_defines_its_object_across_one_lapse_and_samples_through_the_rc() {
    let rig = Rig::new(SimConfig::default());
    let latency = Arc::new(Mutex::new(SLOW));
    let client = rig.client_behind(&latency, scp11_may_lapse()).unwrap();
    assert_eq!(rig.unit(|u| u.stats().watchdog_expiries), 0, "opened without a lapse");
    let mut samples = Vec::new();
    let n = client.watch(Duration::from_millis(500), Some(8), &mut |s| samples.push(*s)).unwrap();
    assert_eq!(n, 8);
    assert_eq!(samples.len(), 8);
    assert!(samples.iter().all(|s| s.position(a(1)) == PositionCounts(0) && !s.moving(a(1))), "{samples:?}");
    // The unit lapsed once, on purpose, and says so in its error code (bit 22: remote communication time out).
    assert_eq!(rig.unit(|u| u.stats().watchdog_expiries), 1);
    assert_eq!(client.stats().deliberate_lapses, 1);
    assert_ne!(samples[0].last_error.0 & (1 << 21), 0, "{:?}", samples[0].last_error);
    assert_eq!(client.capabilities().cyclic_objects, Some(true));
    // Every sample after the definition rode on an RC: the unit saw nothing else but the RT and the RO.
    let stats = rig.unit(|u| u.stats());
    assert!(stats.telegrams - stats.cyclic <= 4, "RO, RT, RO (and RA at the end) besides the RCs: {stats:?}");
    let span = samples[7].at - samples[0].at;
    assert!(span >= Duration::from_millis(3200) && span <= Duration::from_millis(3800), "{span:?}");
    // Remote mode is open again, and fed: no further lapse while the watch ran.
    assert!(client.is_open());
    assert!(matches!(rig.unit(|u| u.mode()), RemoteMode::Active(_)), "{:?}", rig.unit(|u| u.mode()));
    // A move on this link is still refused before anything moves.
    let e = client.move_to(a(1), PositionCounts(400), pct(100), &MoveOptions::default()).unwrap_err();
    assert!(matches!(e, Error::NoRoom { .. }), "{e}");
    rig.sleep(1000);
    assert_eq!(rig.unit(|u| u.position(a(1))), Some(0), "nothing moved");
    assert!(rig.unit(|u| u.executed_functions().is_empty()), "no RE reached the unit");
    assert_eq!(rig.unit(|u| u.stats().watchdog_expiries), 1);
    client.close().unwrap();
}

#[test]
fn a_session_that_started_a_function_never_lets_the_watchdog_lapse_for_a_watch() {
    let rig = Rig::new(SimConfig::default());
    let latency = Arc::new(Mutex::new(Duration::ZERO));
    let client = rig.client_behind(&latency, scp11_may_lapse()).unwrap();
    // A function of this session is on (binary output 1): a lapse would switch it off.
    client.switch(motionlink_scu::model::Function::BinaryOutput1, true).unwrap();
    *latency.lock().unwrap() = SLOW;
    let e = client.watch(Duration::from_millis(250), Some(3), &mut |_| {}).unwrap_err();
    // The RT of the definition or its read-back found no room (which one depends on the round trip the
    // session had measured when the link became slow); either way, no lapse.
    assert!(matches!(e, Error::NoRoom { .. }), "{e}");
    assert_eq!(rig.unit(|u| u.stats().watchdog_expiries), 0);
    assert_eq!(client.stats().deliberate_lapses, 0);
    assert_eq!(rig.unit(|u| u.executed_functions()), vec![17], "binary output 1 is still on");
    assert!(client.is_open());
    *latency.lock().unwrap() = Duration::ZERO;
    client.close().unwrap();
}

#[test]
fn a_move_over_a_link_slow_from_the_start_is_refused_before_anything_moves() {
    let rig = Rig::new(SimConfig::default());
    let latency = Arc::new(Mutex::new(SLOW));
    let client = rig.client_behind(&latency, scp11()).unwrap();
    let e = client.move_to(a(1), PositionCounts(400), pct(100), &MoveOptions::default()).unwrap_err();
    assert!(matches!(e, Error::NoRoom { .. }), "{e}");
    assert_eq!(e.class(), ErrorClass::Transport(TransportKind::Timeout));
    rig.sleep(1000);
    assert_eq!(rig.unit(|u| u.position(a(1))), Some(0), "nothing moved");
    assert!(rig.unit(|u| u.executed_functions().is_empty()), "no RE reached the unit");
    assert!(client.started().is_empty());
    assert_eq!(rig.unit(|u| u.stats().watchdog_expiries), 0);
    client.close().unwrap();
}

#[test]
fn a_unit_without_cyclic_objects_cannot_be_watched_over_a_slow_link_and_its_keepalive_is_never_starved() {
    let rig = Rig::with_variants(SimConfig::default(), &[Variant::NoCyclicObjects]);
    let latency = Arc::new(Mutex::new(Duration::ZERO));
    let client = rig.client_behind(&latency, scp11()).unwrap();
    client.sample().unwrap();
    assert_eq!(client.capabilities().cyclic_objects, Some(false));
    *latency.lock().unwrap() = SLOW;
    let mut samples = 0;
    let e = client.watch(Duration::from_millis(250), None, &mut |_| samples += 1).unwrap_err();
    assert!(matches!(e, Error::NoRoom { command: Command::Get, .. }), "{e}");
    assert_eq!(samples, 0);
    assert_eq!(rig.unit(|u| u.stats().watchdog_expiries), 0, "the reads waited for room that never came");
    assert!(client.is_open());
    // On a quick link again, it samples with reads.
    *latency.lock().unwrap() = Duration::ZERO;
    rig.sleep(1000);
    assert_eq!(client.sample().unwrap().position(a(2)), PositionCounts(0));
    client.close().unwrap();
}

#[test]
fn a_unit_without_cyclic_objects_is_back_in_remote_mode_after_the_lapse_and_the_watch_ends_for_lack_of_room() {
    let rig = Rig::with_variants(SimConfig::default(), &[Variant::NoCyclicObjects]);
    let latency = Arc::new(Mutex::new(SLOW));
    let client = rig.client_behind(&latency, scp11_may_lapse()).unwrap();
    let mut samples = 0;
    let e = client.watch(Duration::from_millis(250), Some(3), &mut |_| samples += 1).unwrap_err();
    assert!(matches!(e, Error::NoRoom { command: Command::Get, .. }), "{e}");
    assert_eq!(samples, 0);
    assert_eq!(client.capabilities().cyclic_objects, Some(false));
    assert_eq!(rig.unit(|u| u.stats().watchdog_expiries), 1, "the one deliberate lapse, and no other");
    assert!(client.is_open());
    assert!(matches!(rig.unit(|u| u.mode()), RemoteMode::Active(_)));
    client.close().unwrap();
}

#[test]
fn without_the_users_leave_a_watch_over_a_link_slow_from_the_start_lets_nothing_lapse_and_ends_for_lack_of_room() {
    let rig = Rig::new(SimConfig::default());
    let latency = Arc::new(Mutex::new(SLOW));
    let client = rig.client_behind(&latency, scp11()).unwrap();
    let mut samples = 0;
    let e = client.watch(Duration::from_millis(250), Some(3), &mut |_| samples += 1).unwrap_err();
    assert!(matches!(e, Error::NoRoom { .. }), "{e}");
    assert_eq!(samples, 0);
    assert_eq!(rig.unit(|u| u.stats().watchdog_expiries), 0, "the unit's watchdog never lapsed");
    assert_eq!(client.stats().deliberate_lapses, 0);
    assert!(client.is_open());
    assert!(matches!(rig.unit(|u| u.mode()), RemoteMode::Active(_)));
    client.close().unwrap();
}
