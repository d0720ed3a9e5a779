//! The blocking client shared between threads, and its close: what stopping returned, and how long a dead
//! line may hold it. In-process, on the manual clock.

use std::time::Duration;

use motionlink_compax::client::{Config, MoveOptions, MoveRequest, MoveTarget, StopOutcome};
use motionlink_compax::model::Position;
use motionlink_compax::sim::SimConfig;
use motionlink_compax::wire::{Address, Mode};
use motionlink_compax::{Client, Emulator, Error};
use motionlink_link::clock::{Clock, ManualClock};
use motionlink_link::pipe::{Direction, EmulatorHost, FaultControl, PipeConfig};

fn a(n: u8) -> Address {
    Address::drive(n).unwrap()
}

fn pos(v: f64) -> Position {
    Position::new(v).unwrap()
}

fn rig(clock: &ManualClock, cfg: impl FnOnce(&mut Config)) -> (EmulatorHost<Emulator>, FaultControl, Client) {
    let host = EmulatorHost::new(
        Emulator::new(SimConfig::bus(&[1, 2], 0, 9600)).unwrap(),
        clock.shared(),
        PipeConfig::paced(9600),
    );
    let (link, faults) = host.connect();
    let mut c = Config::new(Mode::default(), 9600);
    cfg(&mut c);
    let client = Client::with_link(Box::new(link), clock.shared(), c).unwrap();
    (host, faults, client)
}

#[test]
fn another_thread_reads_while_a_checked_move_runs() {
    let clock = ManualClock::new_auto();
    let _me = clock.reserve_participant().enter();
    let (host, _faults, client) = rig(&clock, |_| {});
    host.with_device(|_| ());
    let reader_ticket = clock.reserve_participant();
    std::thread::scope(|s| {
        let reader = s.spawn(|| {
            let _p = reader_ticket.enter();
            let mut seen = Vec::new();
            for _ in 0..8 {
                clock.sleep(Duration::from_millis(100));
                // Drive 1 moves; reading it goes between the move's polls.
                seen.push(client.read_position(a(1)).unwrap().units());
            }
            seen
        });
        // 100 units at 100 units/s: about a second.
        let report = client.move_to(a(1), &MoveRequest::new(MoveTarget::Absolute(pos(100.0))), &mut |_| {}).unwrap();
        assert_eq!(report.reached, pos(100.0));
        let seen = reader.join().unwrap();
        assert!(seen.windows(2).all(|w| w[1] >= w[0]), "{seen:?}");
        assert!(seen.iter().any(|p| *p > 0.0 && *p < 100.0), "read during the move: {seen:?}");
    });
    assert!(client.close().unwrap().is_empty(), "nothing left to stop");
}

#[test]
fn close_stops_what_was_started_and_returns_the_report() {
    let clock = ManualClock::new_auto();
    let _me = clock.reserve_participant().enter();
    let (host, _faults, client) = rig(&clock, |_| {});
    client.move_absolute(a(1), pos(1000.0), MoveOptions::default()).unwrap();
    client.move_absolute(a(2), pos(1.0), MoveOptions::default()).unwrap();
    clock.sleep(Duration::from_millis(500));
    let report = client.close().unwrap();
    assert_eq!(report.drives, [(a(1), StopOutcome::SwitchedOff), (a(2), StopOutcome::AtRest)]);
    let (moving, o0) = host.with_device(|d| (d.drive(1).unwrap().is_moving(), d.drive(1).unwrap().o0()));
    assert!(!moving && o0 == 0);
}

#[test]
fn a_dead_line_bounds_the_close_and_says_the_axis_may_still_move() {
    let clock = ManualClock::new_auto();
    let _me = clock.reserve_participant().enter();
    let (host, faults, client) = rig(&clock, |c| c.close_bound = Duration::from_millis(800));
    client.move_absolute(a(1), pos(1000.0), MoveOptions::default()).unwrap();
    faults.drop_next(Direction::HostToDevice, u64::MAX / 2);
    faults.drop_next(Direction::DeviceToHost, u64::MAX / 2);
    let t0 = clock.now();
    let e = client.close().unwrap_err();
    let took = clock.now() - t0;
    assert!(took <= Duration::from_millis(850), "bounded: {took:?}");
    assert!(matches!(e, Error::CloseTimedOut { .. } | Error::CloseUnconfirmed { .. }), "{e}");
    assert!(e.to_string().contains("may still be moving"), "{e}");
    assert!(host.with_device(|d| d.drive(1).unwrap().is_moving()), "COMPAX has no watchdog: it moves on");
}

/// Dropping the client instead of closing it: the same bound ([`Config::close_bound`]).
#[test]
fn dropping_the_client_on_a_silent_line_returns_within_the_close_bound() {
    let clock = ManualClock::new_auto();
    let _me = clock.reserve_participant().enter();
    let (host, faults, client) = rig(&clock, |c| c.close_bound = Duration::from_millis(800));
    client.move_absolute(a(1), pos(1000.0), MoveOptions::default()).unwrap();
    faults.drop_next(Direction::HostToDevice, u64::MAX / 2);
    faults.drop_next(Direction::DeviceToHost, u64::MAX / 2);
    let t0 = clock.now();
    drop(client);
    let took = clock.now() - t0;
    assert!(took >= Duration::from_millis(800), "it tried to stop the axis until the bound: {took:?}");
    assert!(took <= Duration::from_millis(850), "bounded: {took:?}");
    assert!(host.with_device(|d| d.drive(1).unwrap().is_moving()), "COMPAX has no watchdog: it moves on");
}

/// The peer gone (the link disconnected) while an axis moves: dropping the client returns within the bound.
#[test]
fn dropping_the_client_after_the_peer_is_gone_returns_within_the_close_bound() {
    let clock = ManualClock::new_auto();
    let _me = clock.reserve_participant().enter();
    let (host, faults, client) = rig(&clock, |c| c.close_bound = Duration::from_millis(800));
    client.move_absolute(a(1), pos(1000.0), MoveOptions::default()).unwrap();
    faults.disconnect();
    let t0 = clock.now();
    drop(client);
    let took = clock.now() - t0;
    assert!(took <= Duration::from_millis(850), "bounded: {took:?}");
    assert!(host.with_device(|d| d.drive(1).unwrap().is_moving()), "nothing reached the drive: it moves on");
}
