//! The core operations against every firmware variant of the emulator (what a real unit may do where the
//! manual leaves it open): each works, in the manual's plain form where the unit refuses what the client
//! would rather use, and says what it could not verify; or it ends with an error that names what the unit did
//! not do. Never a hang, never a success away from the target.

use crate::rig;

use motionlink_scu::session::{Capabilities, RunAction, Snapshot};
use motionlink_scu::{FirmwareVariant, Variant};
use rig::*;

/// What the core operations gave on one unit.
struct Outcome {
    caps: Capabilities,
    set_verified: bool,
    set_why: Vec<String>,
    move_verified: bool,
    move_why: Vec<String>,
    home_rest: PositionCounts,
    samples: Vec<Snapshot>,
    retries: u64,
    /// A run of F11 (whose entry the manuals name) and of F18 (whose bit is this crate's reading): verified,
    /// and what could not be.
    switched: [(bool, Vec<String>); 2],
}

/// Open (with what a device profile says of the unit: `seed`), get, set, move (two functions, two speeds),
/// home (F1 In), stop, watch, close: each must succeed.
fn core_operations(rig: &Rig, config: Config, seed: Capabilities) -> Outcome {
    let client = rig.client(config);
    client.seed_capabilities(seed);
    // get: a group (every position) and an entry, the same values either way.
    let all = client.get(DataIndex(0x0010)).unwrap();
    assert_eq!(all.len(), 6);
    assert_eq!(all[0].1, client.get_value(DataIndex(0x0011)).unwrap());
    assert_eq!(client.statuses().unwrap().iter().filter(|s| s.available()).count(), 2);
    assert_eq!(client.error_history().unwrap()[0], ErrorCode::NONE);
    // set
    let set = client.set(DataIndex(0x3012), &Value::RemoteSpeed(50)).unwrap();
    assert_eq!(rig.unit(|u| u.config().default_speed), 100);
    // move with a speed, then another function at another speed
    let report = client.move_to(a(1), PositionCounts(400), pct(80), &MoveOptions::default()).unwrap();
    assert_eq!(report.position_counts, PositionCounts(400));
    assert_eq!(rig.unit(|u| u.position(a(1))), Some(400), "where the unit says A1 is");
    let second = client.move_function(f(2), &[(a(2), PositionCounts(250))], pct(100), &MoveOptions::default()).unwrap();
    assert_eq!(second.position_counts, PositionCounts(250));
    assert_eq!((report.verified, report.not_verifiable.len()), (second.verified, second.not_verifiable.len()));
    assert_eq!(report.verified, report.not_verifiable.is_empty());
    // home: F1 to its In end
    let run = client.run_function(RunAction::Motion(f(1), MotionDirection::In), None, &|_| {}).unwrap();
    let home_rest = run.rest.iter().find(|(x, _)| *x == a(1)).map(|(_, p)| *p).unwrap();
    assert_eq!(rig.unit(|u| u.position(a(1))), Some(home_rest.get()));
    // stop
    client.stop_motion(f(1), StopMode::Fast).unwrap();
    // watch: three samples, a quarter of a second apart
    let mut samples = Vec::new();
    let n = client.watch(Duration::from_millis(250), Some(3), &mut |s| samples.push(*s)).unwrap();
    assert_eq!(n, 3);
    for s in &samples {
        assert_eq!((s.position(a(1)), s.position(a(2))), (home_rest, PositionCounts(250)));
        assert!(s.status(a(1)).available() && !s.moving(a(1)));
    }
    let gaps: Vec<Duration> = samples.windows(2).map(|w| w[1].at - w[0].at).collect();
    assert!(gaps.iter().all(|g| *g >= Duration::from_millis(200) && *g <= Duration::from_millis(300)), "{gaps:?}");
    // switching functions: on for a moment, read back after the RE and after the RS
    let switched = [Function::Buzzer, Function::BinaryOutput2].map(|function| {
        let limit = Some(Duration::from_millis(200));
        let run = client.run_function(RunAction::Switch(function), limit, &|_| {}).unwrap();
        assert_eq!(run.verified, run.not_verifiable.is_empty(), "{function}");
        (run.verified, run.not_verifiable)
    });
    assert_eq!(rig.unit(|u| u.stats().watchdog_expiries), 0);
    let caps = client.capabilities();
    let retries = client.stats().retries;
    assert!(client.started().is_empty());
    client.close().unwrap();
    assert!(rig.unit(|u| u.executed_functions().is_empty()));
    Outcome {
        caps,
        set_verified: set.verified,
        set_why: set.not_verifiable,
        move_verified: report.verified,
        move_why: report.not_verifiable,
        home_rest,
        samples,
        retries,
        switched,
    }
}

fn scp11() -> Config {
    Config { function_map: FunctionMap::scp11(), ..Default::default() }
}

fn run_on(variants: &[Variant]) -> (Rig, Outcome) {
    let rig = Rig::with_variants(SimConfig::default(), variants);
    // A unit in low-power mode answers once a break has woken it (`Config::wake_break`, the CLI's `--wake`).
    let wake_break = variants.contains(&Variant::LowPower).then_some(motionlink_scu::config::WAKE_BREAK);
    let outcome = core_operations(&rig, Config { wake_break, ..scp11() }, Capabilities::default());
    (rig, outcome)
}

#[test]
fn a_profile_that_says_the_unit_does_everything_is_corrected_by_a_unit_that_does_not() {
    // A profile saved on a unit that answered every probe, used on a unit of the same identity that does
    // not: each behaviour is found out as without the profile (the plain form, what was not verified said),
    // never an error on the profile's word.
    let all = Some(true);
    let said =
        Capabilities { grouping_indices: all, user_position_data: all, cyclic_objects: all, remote_read_back: all };
    for variant in [Variant::NoGroups, Variant::NoUserPositions, Variant::NoCyclicObjects, Variant::NoRemoteReadBack] {
        let (_, plain) = run_on(&[variant]);
        let rig = Rig::with_variants(SimConfig::default(), &[variant]);
        let seeded = core_operations(&rig, scp11(), said);
        assert_eq!(seeded.move_verified, plain.move_verified, "{variant:?}: {:?}", seeded.move_why);
        assert_eq!(seeded.move_why, plain.move_why, "{variant:?}");
        assert_eq!((seeded.set_verified, &seeded.set_why), (plain.set_verified, &plain.set_why), "{variant:?}");
        let refused = |c: Capabilities| {
            [c.grouping_indices, c.user_position_data, c.cyclic_objects, c.remote_read_back].map(|x| x == Some(false))
        };
        assert_eq!(refused(seeded.caps), refused(plain.caps), "{variant:?}: what the unit refused is known");
    }
}

#[test]
fn a_unit_as_the_emulator_reads_the_manual_answers_every_probe_and_everything_is_verified() {
    let (_, o) = run_on(&[]);
    let all = Some(true);
    assert_eq!(
        o.caps,
        Capabilities { grouping_indices: all, user_position_data: all, cyclic_objects: all, remote_read_back: all }
    );
    assert!(o.set_verified && o.set_why.is_empty() && o.move_verified && o.move_why.is_empty());
    assert_eq!(o.home_rest, PositionCounts(0));
    assert_eq!(o.retries, 0);
}

#[test]
fn without_grouping_indices_every_group_is_read_entry_by_entry_and_nothing_is_lost() {
    let (rig, o) = run_on(&[Variant::NoGroups]);
    assert_eq!(o.caps.grouping_indices, Some(false));
    // The session's cyclic object reads groups: the unit would refuse it, so motions are watched with reads.
    assert_eq!(o.caps.cyclic_objects, None);
    assert!(o.move_verified && o.set_verified, "{:?}", o.move_why);
    // The grouping index was asked once per session, then never again.
    let client = rig.client(scp11());
    let groups = Arc::new(Mutex::new(0));
    let sink = Arc::clone(&groups);
    rig.on_request(move |bytes, _| {
        if bytes.starts_with(&[0x52, 0x47, 0x70, 0x01]) || bytes.starts_with(&[0x52, 0x47, 0x10, 0x00]) {
            *sink.lock().unwrap() += 1;
        }
    });
    client.move_to(a(1), PositionCounts(100), pct(100), &MoveOptions::default()).unwrap();
    client.statuses().unwrap();
    client.positions().unwrap();
    assert_eq!(*groups.lock().unwrap(), 1, "one probe of a grouping index, refused; entries from then on");
    // Its warning is said once; the unit never saw a group it would refuse after that.
    assert_eq!(client.capabilities().grouping_indices, Some(false));
}

#[test]
fn without_user_position_data_a_move_says_its_target_was_not_checked_unless_strokes_are_configured() {
    let (rig, o) = run_on(&[Variant::NoUserPositions]);
    assert_eq!(o.caps.user_position_data, Some(false));
    assert!(!o.move_verified);
    assert_eq!(o.move_why.len(), 1, "{:?}", o.move_why);
    assert!(o.move_why[0].contains("UserPositionData (0x2001, PDE)") && o.move_why[0].contains("--stroke 1="));
    assert!(o.set_verified, "a write is read back as usual");
    // The stroke query says what the unit did not do; a target outside the unit's own stroke still ends away
    // from its target (the unit stops at its end), and that is an error, not a success.
    let client = rig.client(scp11());
    let e = client.stroke_limits(a(1)).unwrap_err();
    assert!(matches!(&e, Error::NotSupported(m) if m.contains("UserPositionData")), "{e}");
    let e = client.move_to(a(1), PositionCounts(900), pct(100), &MoveOptions::default()).unwrap_err();
    assert!(matches!(e, Error::MotionEnded { position_counts: PositionCounts(865), .. }), "{e}");
    // With the stroke configured, the client's limits are the check: verified, and refused before moving.
    let stroke = StrokeLimits { min_counts: PositionCounts(0), max_counts: PositionCounts(865) };
    let client = rig.client(Config { stroke_limits: [Some(stroke); 6], ..scp11() });
    let report = client.move_to(a(1), PositionCounts(500), pct(100), &MoveOptions::default()).unwrap();
    assert!(report.verified, "{:?}", report.not_verifiable);
    let e = client.move_to(a(1), PositionCounts(900), pct(100), &MoveOptions::default()).unwrap_err();
    assert!(matches!(e, Error::OutsideLimits { limits_from: "as configured", .. }), "{e}");
    // A stream checks every target against the stroke: without one it says so before anything moves.
    let client = rig.client(scp11());
    let e = client.stream(f(1), &[a(1)], pct(50)).unwrap_err();
    assert!(matches!(&e, Error::NotSupported(m) if m.contains("UserPositionData")), "{e}");
}

#[test]
fn without_cyclic_objects_the_probe_rc_is_refused_once_and_motions_are_watched_with_reads() {
    let (rig, o) = run_on(&[Variant::NoCyclicObjects]);
    assert_eq!(o.caps.cyclic_objects, Some(false));
    assert!(o.move_verified && o.set_verified);
    // The refused RC was the only one that carried an object; the probe is not repeated in the session.
    let client = rig.client(scp11());
    let carried = Arc::new(Mutex::new(0));
    let sink = Arc::clone(&carried);
    rig.on_request(move |bytes, _| {
        if bytes.starts_with(b"RC") && bytes.get(4).is_some_and(|o| *o != 0xFF) {
            *sink.lock().unwrap() += 1;
        }
    });
    for target in [300, 100] {
        client.move_to(a(1), PositionCounts(target), pct(100), &MoveOptions::default()).unwrap();
    }
    client.sample().unwrap();
    assert_eq!(*carried.lock().unwrap(), 1);
}

#[test]
fn without_remote_read_back_writes_and_moves_say_they_were_not_read_back() {
    let (_, o) = run_on(&[Variant::NoRemoteReadBack]);
    assert_eq!(o.caps.remote_read_back, Some(false));
    assert!(!o.set_verified && o.set_why[0].contains("remote_speed_f2 (0x3012)"), "{:?}", o.set_why);
    assert!(!o.move_verified);
    let why = o.move_why.join("; ");
    assert!(why.contains("remote_position_a1 (0x3021)") && why.contains("remote_speed_f1 (0x3011)"), "{why}");
    assert!(why.contains("not read back"), "{why}");
}

#[test]
fn the_rc_reply_with_ctp_0_is_taken_as_the_status_alone_is() {
    let (_, o) = run_on(&[Variant::RcEmptyData]);
    assert!(o.move_verified && o.set_verified && o.retries == 0, "{:?}", o.move_why);
}

#[test]
fn a_sleepy_unit_is_woken_by_the_first_ro_and_answers_the_second() {
    let (_, o) = run_on(&[Variant::Sleepy]);
    assert!(o.retries >= 1);
    assert!(o.move_verified);
}

#[test]
fn error_bits_that_stay_after_the_next_motion_do_not_stop_a_move() {
    let rig = Rig::with_variants(SimConfig::default(), &[Variant::StickyErrors]);
    rig.unit(|u| u.inject_error(ErrorCode::from_bit(15)));
    let client = rig.client(scp11());
    let report = client.move_to(a(1), PositionCounts(300), pct(100), &MoveOptions::default()).unwrap();
    assert!(report.verified);
    assert_eq!(client.error_history().unwrap()[0], ErrorCode::from_bit(15), "the unit kept bit 15");
    assert_eq!(client.sample().unwrap().last_error, ErrorCode::from_bit(15));
}

#[test]
fn after_homing_a_column_reads_a_few_counts_below_its_in_end_which_the_tolerance_takes() {
    let (rig, o) = run_on(&[Variant::InEndUndershoot]);
    assert_eq!(o.home_rest, PositionCounts(-3));
    assert!(o.samples.iter().all(|s| s.position(a(1)) == PositionCounts(-3)));
    let client = rig.client(scp11());
    client.move_to(a(1), PositionCounts(200), pct(100), &MoveOptions::default()).unwrap();
    let report = client.move_to(a(1), PositionCounts(0), pct(100), &MoveOptions::default()).unwrap();
    assert_eq!(report.position_counts, PositionCounts(-3));
    let strict = rig.client(Config { position_tolerance_counts: 2, ..scp11() });
    strict.move_to(a(1), PositionCounts(200), pct(100), &MoveOptions::default()).unwrap();
    let e = strict.move_to(a(1), PositionCounts(0), pct(100), &MoveOptions::default()).unwrap_err();
    assert!(matches!(e, Error::MotionEnded { position_counts: PositionCounts(-3), .. }), "{e}");
}

#[test]
fn a_unit_that_needs_rs_before_a_new_re_gets_it_and_the_stream_goes_on_in_the_manuals_form() {
    let (rig, o) = run_on(&[Variant::ReNeedsRs]);
    assert!(o.move_verified);
    let client = rig.client(scp11());
    let sent: Arc<Mutex<Vec<Vec<u8>>>> = Arc::default();
    let log = Arc::clone(&sent);
    rig.on_request(move |bytes, _| log.lock().unwrap().push(bytes[..2].to_vec()));
    let mut stream = client.stream(f(1), &[a(1)], pct(100)).unwrap();
    stream.set_targets(&[PositionCounts(600)]).unwrap();
    rig.sleep(300);
    // The unit refuses the second RE while F1 runs (PE): RS, then the RE again, which it takes.
    stream.set_targets(&[PositionCounts(500)]).unwrap();
    rig.sleep(300);
    stream.set_targets(&[PositionCounts(450)]).unwrap();
    let sent = sent.lock().unwrap().clone();
    let commands: Vec<&[u8]> = sent.iter().map(|b| &b[..]).filter(|b| *b == b"RE" || *b == b"RS").collect();
    // (The refused RE is looked into by the session once before it is taken as a refusal.)
    let first_rs = commands.iter().position(|c| *c == b"RS").expect("an RS");
    assert!(first_rs >= 2 && commands[..first_rs].iter().all(|c| *c == b"RE"), "{commands:?}");
    assert_eq!(commands[first_rs..], [&b"RS"[..], b"RE", b"RS", b"RE"], "RS before each RE from then on");
    rig.sleep(10_000);
    assert_eq!(rig.unit(|u| u.position(a(1))), Some(450), "the last setpoint reached");
    let rest = stream.stop(StopMode::Fast).unwrap();
    assert_eq!(rest, [(a(1), PositionCounts(450))]);
    assert!(!rig.unit(|u| u.is_moving(a(1))) && client.started().is_empty());
}

#[test]
fn every_variant_together_still_runs_the_core_operations() {
    let (_, o) = run_on(Variant::ALL);
    assert!(!o.move_verified && o.move_why.len() == 2, "{:?}", o.move_why);
    assert_eq!(o.home_rest, PositionCounts(-3));
    assert!(o.switched[0].0 && !o.switched[1].0, "{:?}", o.switched);
}

#[test]
fn every_variant_but_one_shows_both_switching_functions_and_that_one_says_what_it_could_not_verify() {
    for &v in Variant::ALL {
        let (_, o) = run_on(&[v]);
        assert!(o.switched[0].0, "{v:?}: the buzzer, whose bit the manuals name: {:?}", o.switched[0].1);
        assert_eq!(o.switched[1].0, v != Variant::SwitchStatusUnshown, "{v:?}: {:?}", o.switched[1].1);
    }
}

#[test]
fn a_unit_whose_entries_do_not_follow_f18_f20_f21_f22_switches_them_and_says_they_were_not_verified() {
    let (rig, o) = run_on(&[Variant::SwitchStatusUnshown]);
    assert!(o.move_verified && o.set_verified, "{:?}", o.move_why);
    assert_eq!(o.switched[1].1.len(), 1, "one reason for the RE and the RS: {:?}", o.switched[1].1);
    assert!(
        o.switched[1].1[0].starts_with(
            "F18 (binary output 2) was not verified by its status: binary_outputs (0x0110, bit 1) did not show binary \
             output 2 on after the acknowledged RE"
        ),
        "{:?}",
        o.switched[1].1
    );
    for function in [Function::EmergencyStop, Function::Led1, Function::Led2] {
        // A run: switched on and off, not verified, never an error; the emergency stop still stops motions.
        let client = rig.client(scp11());
        let seen = Mutex::new(Vec::new());
        let progress = |p: &motionlink_scu::session::RunProgress| seen.lock().unwrap().push(p.switched_on_shown);
        let run = client.run_function(RunAction::Switch(function), Some(Duration::from_millis(300)), &progress);
        let run = run.unwrap();
        assert!(!run.verified && run.not_verifiable.len() == 1, "{function}: {:?}", run.not_verifiable);
        let why = &run.not_verifiable[0];
        assert!(why.starts_with(&format!("{function} was not verified by its status: ")), "{why}");
        assert!(why.contains("did not show") && why.contains("so this session does not take the entry"), "{why}");
        assert_eq!(*seen.lock().unwrap(), [Some(false)], "{function}");
        assert!(rig.unit(|u| u.executed_functions().is_empty()), "{function}: switched off");
        // Later switches of the session say the same, without reading the entry again.
        let on = client.switch(function, true).unwrap();
        let off = client.switch(function, false).unwrap();
        assert_eq!((on.verified, &on.not_verifiable), (false, &run.not_verifiable), "{function}");
        assert_eq!((off.verified, &off.not_verifiable), (false, &run.not_verifiable), "{function}");
        client.close().unwrap();
    }
    // A switch off alone finds the entry off before the RS as after it: not verified (the session has not seen
    // it follow), not claimed.
    let client = rig.client(scp11());
    let off = client.switch(Function::Led1, false).unwrap();
    assert!(!off.verified, "{off:?}");
    assert!(
        off.not_verifiable[0].contains("shows LED 1 of the operating unit off after the RS as before it"),
        "{off:?}"
    );
    // While the emergency stop is on, the unit refuses motions all the same.
    client.switch(Function::EmergencyStop, true).unwrap();
    let e = client.run_function(RunAction::Motion(f(1), MotionDirection::Out), None, &|_| {}).unwrap_err();
    assert!(matches!(e, Error::Refused { command: Command::Execute, .. }), "{e}");
}

#[test]
fn a_unit_with_no_virtual_limits_set_moves_and_says_the_target_was_not_checked_against_a_stroke() {
    // UserPositionData answered, its virtual limits 0 / 0: the manual's "none set", so nothing bounds the
    // target but the unit's own limits; the move says so rather than claim every check was made.
    let config = SimConfig::from_toml(
        "[[actuator]]\n[actuator.user_positions]\nvirtual_limit_in_counts = 0\nvirtual_limit_out_counts = 0\n\
         users = [{memory_counts = [0, 0, 0, 0], intermediate_in_counts = 0, intermediate_out_counts = 0}, \
         {memory_counts = [0, 0, 0, 0], intermediate_in_counts = 0, intermediate_out_counts = 0}, \
         {memory_counts = [0, 0, 0, 0], intermediate_in_counts = 0, intermediate_out_counts = 0}, \
         {memory_counts = [0, 0, 0, 0], intermediate_in_counts = 0, intermediate_out_counts = 0}]\n",
    )
    .unwrap();
    let rig = Rig::new(config);
    let client = rig.client(scp11());
    let report = client.move_to(a(1), PositionCounts(300), pct(100), &MoveOptions::default()).unwrap();
    assert_eq!(report.position_counts, PositionCounts(300));
    assert!(!report.verified);
    assert_eq!(report.not_verifiable.len(), 1, "{:?}", report.not_verifiable);
    assert!(report.not_verifiable[0].contains("0 / 0") && report.not_verifiable[0].contains("--stroke 1="));
    // Configured limits are the check then.
    let bounded = rig.client(Config { stroke_limits: StrokeLimits::per_actuator(&["1=0:500"]).unwrap(), ..scp11() });
    assert!(bounded.move_to(a(1), PositionCounts(200), pct(100), &MoveOptions::default()).unwrap().verified);
    client.close().unwrap();
    bounded.close().unwrap();
}

#[test]
fn a_unit_whose_motion_bit_rises_late_is_waited_for_within_the_start_grace_and_beyond_it_the_move_fails_plainly() {
    // The drives start, and the motion bit rises, 0.4 s after the RE's ACK: within the session's start
    // grace (1 s), so every core operation runs as on any unit.
    let (rig, o) = run_on(&[Variant::LateMotionBit]);
    assert!(o.move_verified && o.set_verified, "{:?}", o.move_why);
    // A start grace shorter than the unit's delay: a unit without the delay moves as usual ...
    let short = || Config { start_grace: Duration::from_millis(200), ..scp11() };
    let prompt = Rig::new(SimConfig::default());
    prompt.client(short()).move_to(a(1), PositionCounts(300), pct(100), &MoveOptions::default()).unwrap();
    // ... this one still stands when the grace ends: the move is judged where it stands, away from its
    // target (an error naming it, never a success), and its function is stopped before the drive starts.
    let before = rig.unit(|u| u.position(a(1))).unwrap();
    let client = rig.client(short());
    let e = client.move_to(a(1), PositionCounts(before + 300), pct(100), &MoveOptions::default()).unwrap_err();
    assert!(matches!(e, Error::MotionEnded { position_counts, .. } if position_counts.get() == before), "{e}");
    rig.sleep(1_000);
    assert_eq!(rig.unit(|u| u.position(a(1))), Some(before), "stopped (RS) before it started");
    assert!(!rig.unit(|u| u.is_moving(a(1))) && client.started().is_empty());
}

/// A rig with a `re-needs-rs` unit that loses the unit's answer to the first RE (the unit takes it), and the
/// log of the commands the unit hears from then on.
fn re_reply_lost() -> (Rig, Client, Arc<Mutex<Vec<Vec<u8>>>>) {
    let rig = Rig::with_variants(SimConfig::default(), &[Variant::ReNeedsRs]);
    let client = rig.client(scp11());
    rig.sleep(50);
    let sent: Arc<Mutex<Vec<Vec<u8>>>> = Arc::default();
    let log = Arc::clone(&sent);
    let lost = std::sync::atomic::AtomicBool::new(false);
    rig.on_request(move |bytes, faults| {
        log.lock().unwrap().push(bytes[..2].to_vec());
        if bytes.starts_with(b"RE") && !lost.swap(true, std::sync::atomic::Ordering::Relaxed) {
            faults.drop_next(Direction::DeviceToHost, 5);
        }
    });
    (rig, client, sent)
}

/// The REs and RSs in `sent`.
fn starts_and_stops(sent: &Mutex<Vec<Vec<u8>>>) -> Vec<String> {
    let sent = sent.lock().unwrap();
    sent.iter().filter(|b| *b == b"RE" || *b == b"RS").map(|b| String::from_utf8_lossy(b).into_owned()).collect()
}

#[test]
fn a_move_whose_re_answer_was_lost_on_a_unit_that_refuses_a_second_re_gets_the_rs_and_reaches_its_target() {
    // The unit took the first RE; the session, which did not hear it, sends it again and the unit refuses the
    // repeat with PE. That PE is the unit asking for the RS the manual wants after every RE: a soft RS, then
    // the RE again (to remote positions: absolute, nothing is repeated), and the move goes on.
    let (rig, client, sent) = re_reply_lost();
    let report = client.move_to(a(1), PositionCounts(600), pct(100), &MoveOptions::default()).unwrap();
    assert_eq!(report.position_counts, PositionCounts(600));
    assert_eq!(rig.unit(|u| u.position(a(1))), Some(600));
    let commands = starts_and_stops(&sent);
    let first_rs = commands.iter().position(|c| c == "RS").expect("an RS");
    assert!(first_rs >= 2 && commands[..first_rs].iter().all(|c| c == "RE"), "{commands:?}");
    assert_eq!(commands[first_rs..first_rs + 2], ["RS", "RE"], "{commands:?}");
    assert!(client.started().is_empty());
    client.close().unwrap();
    assert!(!rig.unit(|u| u.any_moving()));
}

#[test]
fn a_run_whose_re_answer_was_lost_on_a_unit_that_refuses_a_second_re_runs_and_is_stopped() {
    let (rig, client, sent) = re_reply_lost();
    let run = client
        .run_function(RunAction::Motion(f(1), MotionDirection::Out), Some(Duration::from_millis(400)), &|_| {})
        .unwrap();
    assert!(run.duration >= Duration::from_millis(400), "{run:?}");
    let commands = starts_and_stops(&sent);
    let first_rs = commands.iter().position(|c| c == "RS").expect("an RS");
    assert!(first_rs >= 2 && commands[..first_rs].iter().all(|c| c == "RE"), "{commands:?}");
    assert_eq!(commands[first_rs..], ["RS", "RE", "RS"], "the soft RS, the RE again, the run's own stop");
    assert!(!rig.unit(|u| u.any_moving()) && client.started().is_empty());
    client.close().unwrap();
}

#[test]
fn a_run_the_unit_refuses_still_gets_its_rs_for_the_motion_an_earlier_sending_may_have_started() {
    // F5 drives nothing on this unit: the unit refuses its RE (PE). The run sends the RS all the same (a
    // refusal can answer the repeat of an RE the unit took) and reports the refusal.
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(scp11());
    let sent: Arc<Mutex<Vec<Vec<u8>>>> = Arc::default();
    let log = Arc::clone(&sent);
    rig.on_request(move |bytes, _| log.lock().unwrap().push(bytes[..2].to_vec()));
    let e = client.run_function(RunAction::Motion(f(5), MotionDirection::Out), None, &|_| {}).unwrap_err();
    assert!(matches!(e, Error::Refused { command: Command::Execute, status: Status::PermissionError }), "{e}");
    assert_eq!(starts_and_stops(&sent).last().map(String::as_str), Some("RS"), "{:?}", starts_and_stops(&sent));
    assert!(client.started().is_empty());
    client.close().unwrap();
}

#[test]
fn a_run_whose_status_cannot_be_read_is_stopped_and_fails_rather_than_end_as_done() {
    // Without cyclic objects a run is watched by reading the status (RG 0x0170). The answers to the second
    // read are corrupt, all three sendings: the run cannot tell whether the function ended, so it stops it
    // (the stop's own reads answered) and says why (was: a run that ended, the read's failure a warning).
    let rig = Rig::with_variants(SimConfig::default(), &[Variant::NoCyclicObjects]);
    let client = rig.client(scp11());
    rig.corrupt_reads(0x0170, 1..4);
    let e = client.run_function(RunAction::Motion(f(1), MotionDirection::Out), None, &|_| {}).unwrap_err();
    assert!(matches!(e, Error::Corrupt { command: Command::Get, .. }), "{e}");
    assert!(rig.unit(|u| u.position(a(1))) < Some(800), "cut short, not at its end of travel");
    assert!(!rig.unit(|u| u.any_moving()), "stopped");
    assert!(rig.unit(|u| u.executed_functions().is_empty()), "its RS was sent");
}
