//! [`Follower`]: streamed setpoints offered at any pace, applied at the rate with the newest winning; the end
//! of the input (the last target reached, then a soft stop, then the check against the tolerance); a cancel
//! while it settles (a fast stop).

use crate::rig;

use motionlink_link::emulator::Emulator as _;
use motionlink_scu::client::{FollowFailure, FollowReport, Follower};
use motionlink_scu::error::TargetMiss;
use rig::*;

fn scp11() -> (Rig, Client) {
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(Config { function_map: FunctionMap::scp11(), ..Default::default() });
    (rig, client)
}

fn stops(rig: &Rig) -> Vec<String> {
    rig.unit(|u| u.take_events()).into_iter().filter(|e| e.contains("stopped (RS")).collect()
}

#[test]
fn a_follower_merges_targets_offered_faster_than_its_rate_and_the_newest_wins() {
    let (rig, client) = scp11();
    let mut follower = Follower::new(client.stream(f(1), &[a(1)], pct(100)).unwrap(), a(1), 2).unwrap();
    assert!(follower.apply_due().unwrap().is_none(), "nothing offered");
    follower.offer(vec![PositionCounts(100)]);
    assert_eq!(follower.apply_due().unwrap(), Some(&[PositionCounts(100)][..]), "the first at once");
    // Faster than 2 a second: merged, the newest wins when the next update is due.
    for t in [200, 300, 400] {
        follower.offer(vec![PositionCounts(t)]);
        assert!(follower.apply_due().unwrap().is_none(), "{t} within 500 ms of the last update");
        rig.sleep(100);
    }
    rig.sleep(200);
    assert_eq!(follower.apply_due().unwrap(), Some(&[PositionCounts(400)][..]));
    assert!(follower.apply_due().unwrap().is_none(), "applied once");
    assert_eq!(follower.updates(), 2);
    let report = follower.finish(&CancelToken::new()).unwrap();
    assert_eq!(report, FollowReport { rest: vec![(a(1), PositionCounts(400))], updates: 2 });
    assert!(client.started().is_empty());
    assert!(Follower::new(client.stream(f(1), &[a(1)], pct(100)).unwrap(), a(1), 0).is_err(), "rate 0");
}

#[test]
fn the_end_of_a_follow_applies_the_newest_target_lets_the_motion_reach_it_and_stops_soft() {
    let (rig, client) = scp11();
    let mut follower = Follower::new(client.stream(f(1), &[a(1)], pct(100)).unwrap(), a(1), 1).unwrap();
    follower.offer(vec![PositionCounts(100)]);
    assert!(follower.apply_due().unwrap().is_some());
    follower.offer(vec![PositionCounts(700)]);
    follower.offer(vec![PositionCounts(600)]);
    assert!(follower.apply_due().unwrap().is_none(), "not due yet");
    stops(&rig);
    let report = follower.finish(&CancelToken::new()).unwrap();
    assert_eq!(report, FollowReport { rest: vec![(a(1), PositionCounts(600))], updates: 2 });
    assert_eq!(rig.unit(|u| (u.position(a(1)), u.is_moving(a(1)))), (Some(600), false));
    assert_eq!(stops(&rig), ["F1 stopped (RS soft)"]);
    // Nothing offered: nothing to wait for, a soft stop all the same.
    let follower = Follower::new(client.stream(f(1), &[a(1)], pct(100)).unwrap(), a(1), 1).unwrap();
    let report = follower.finish(&CancelToken::new()).unwrap();
    assert_eq!(report, FollowReport { rest: vec![(a(1), PositionCounts(600))], updates: 0 });
}

#[test]
fn a_follow_that_ends_away_from_its_last_target_is_a_device_error_naming_actuator_target_and_reached() {
    // The session is told that F1 drives A1 and A2; on this SCP11 unit it drives A1 alone, so A2 stays put.
    let rig = Rig::new(SimConfig::default());
    let map = FunctionMap::scp11().apply("F1=1,2").unwrap();
    let client = rig.client(Config { function_map: map, position_tolerance_counts: 2, ..Default::default() });
    let a2_before = rig.unit(|u| u.position(a(2))).unwrap();
    let mut follower = Follower::new(client.stream(f(1), &[a(1), a(2)], pct(100)).unwrap(), a(1), 20).unwrap();
    follower.offer(vec![PositionCounts(300), PositionCounts(a2_before + 200)]);
    let FollowFailure { error, stopped } = follower.finish(&CancelToken::new()).unwrap_err();
    let miss = TargetMiss {
        actuator: a(2),
        target_counts: PositionCounts(a2_before + 200),
        reached_counts: PositionCounts(a2_before),
    };
    assert!(
        matches!(&error, Error::NotReached { tolerance_counts: 2, misses } if misses[..] == [miss.clone()]),
        "{error:?}"
    );
    assert_eq!(error.class(), ErrorClass::Device);
    assert_eq!(miss.difference_counts(), -200);
    assert_eq!(
        error.to_string(),
        format!(
            "the last target was not reached within 2 counts: A2: target {}, reached {a2_before}, difference -200",
            a2_before + 200
        )
    );
    let stopped = stopped.expect("stopped, and where the actuators rest is known");
    assert_eq!(stopped.rest, [(a(1), PositionCounts(300)), (a(2), PositionCounts(a2_before))]);
    assert_eq!(stops(&rig).last().map(String::as_str), Some("F1 stopped (RS soft)"));
}

#[test]
fn a_cancel_while_a_follow_settles_stops_it_fast() {
    let (rig, client) = scp11();
    let clock = rig.clock.shared();
    let ticket = clock.reserve_participant();
    let cancel = CancelToken::new();
    let canceller = {
        let (clock, cancel) = (Arc::clone(&clock), cancel.clone());
        std::thread::spawn(move || {
            let _in = ticket.enter();
            clock.sleep(Duration::from_millis(300));
            cancel.cancel();
        })
    };
    let mut follower = Follower::new(client.stream(f(1), &[a(1)], pct(100)).unwrap(), a(1), 20).unwrap();
    follower.offer(vec![PositionCounts(800)]);
    stops(&rig);
    let started = clock.now();
    let FollowFailure { error, stopped } = follower.finish(&cancel).unwrap_err();
    canceller.join().unwrap();
    assert!(clock.now() - started < Duration::from_millis(500), "stopped at the cancel, not at 800");
    assert!(matches!(&error, Error::FunctionCancelled { function_id: 0, stopped: true }), "{error:?}");
    assert_eq!(error.to_string(), "cancelled; F1 stopped (the unit acknowledged RS)");
    assert_eq!(error.class(), ErrorClass::Cancelled);
    let [(_, rest)] = stopped.expect("where it came to rest").rest[..] else { panic!() };
    assert!(rest < PositionCounts(800), "stopped on the way: {rest}");
    assert_eq!(rig.unit(|u| (u.position(a(1)), u.is_moving(a(1)))), (Some(rest.get()), false));
    assert_eq!(stops(&rig), ["F1 stopped (RS fast)"]);
    assert!(client.started().is_empty());
}

#[test]
fn without_a_function_map_every_actuator_of_the_follow_that_moved_is_judged_not_only_the_one_asked_for() {
    // F1 drives A1 and A2 on this unit; the session does not know it. A2 meets an obstacle at 150 on its way
    // to 300: it moved, so it is one F1 drives, and its miss fails the follow (was: only A1 judged, success).
    let mut unit = SimConfig::from_toml("[[actuator]]\n[[actuator]]\nobstacle_counts = 150\n").unwrap();
    unit.functions[0] = vec![a(1), a(2)];
    let rig = Rig::new(unit);
    let client = rig.client(Config { function_map: FunctionMap::unknown(), ..Default::default() });
    let stream = client.stream(f(1), &[a(1), a(2)], pct(100)).unwrap();
    let mut follower = Follower::new(stream, a(1), 10).unwrap();
    follower.offer(vec![PositionCounts(300), PositionCounts(300)]);
    assert!(follower.apply_due().unwrap().is_some());
    let FollowFailure { error, stopped } = follower.finish(&CancelToken::new()).unwrap_err();
    match &error {
        Error::NotReached { misses, .. } => {
            assert_eq!(misses.iter().map(|m| m.actuator).collect::<Vec<_>>(), [a(2)], "{error}");
            assert!((140..=150).contains(&misses[0].reached_counts.get()), "{error}");
        }
        other => panic!("{other}"),
    }
    assert!(stopped.is_some());
    // An actuator the follow holds where it stands (the function does not drive it) is not judged: A2 of an
    // SCP11 unit, F1 driving A1 alone.
    let rig = Rig::new(SimConfig::default());
    let client = rig.client(Config { function_map: FunctionMap::unknown(), ..Default::default() });
    let mut follower = Follower::new(client.stream(f(1), &[a(1), a(2)], pct(100)).unwrap(), a(1), 10).unwrap();
    follower.offer(vec![PositionCounts(300), PositionCounts(300)]);
    assert!(follower.apply_due().unwrap().is_some());
    let report = follower.finish(&CancelToken::new()).unwrap();
    assert_eq!(report.rest, [(a(1), PositionCounts(300)), (a(2), PositionCounts(0))]);
}
