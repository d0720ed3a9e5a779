//! The async client on tokio against the emulator in this process (real clock, 115200 baud): the blocking
//! client's operations as futures (home, raw_motion, read_statuses, start_and_release, a drive handle, the
//! watch stream), the same safety when their futures are dropped, and the bound of a dropped client on a
//! dead line.

#![cfg(feature = "tokio")]

use std::future::Future as _;
use std::task::Poll;
use std::time::Duration;

use motionlink_compax::client::{AfterRaw, Config, MoveOptions, MoveRequest, MoveTarget, StopOutcome};
use motionlink_compax::model::{Position, S17Flag, SpeedPercent, StatusId, StatusValue};
use motionlink_compax::sim::SimConfig;
use motionlink_compax::wire::{Address, Mode};
use motionlink_compax::{AsyncClient, Emulator, Error};
use motionlink_link::link::{Link, LinkError};
use motionlink_link::pipe::{Direction, EmulatorHost, PipeConfig};
use motionlink_link::RealClock;

const BAUD: u32 = 115_200;

fn a(n: u8) -> Address {
    Address::drive(n).unwrap()
}

fn pos(v: f64) -> Position {
    Position::new(v).unwrap()
}

fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_multi_thread().worker_threads(2).enable_all().build().unwrap()
}

async fn setup() -> (EmulatorHost<Emulator>, AsyncClient) {
    let clock = RealClock::shared();
    let host = EmulatorHost::new(
        Emulator::new(SimConfig::bus(&[1, 2], 0, BAUD)).unwrap(),
        clock.clone(),
        PipeConfig::paced(BAUD),
    );
    let client =
        AsyncClient::with_link(Box::new(host.connect().0), clock, Config::new(Mode::default(), BAUD)).await.unwrap();
    (host, client)
}

/// Waits (at most 3 s) until `done` says so.
async fn eventually(mut done: impl FnMut() -> bool) -> bool {
    for _ in 0..300 {
        if done() {
            return true;
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    false
}

/// Polls `op` until `until` says so, then drops it (what `tokio::select!` does to the losing branch);
/// fails if `op` ends first.
async fn drop_when<T: std::fmt::Debug>(op: impl std::future::Future<Output = T>, mut until: impl FnMut() -> bool) {
    let mut op = Box::pin(op);
    let mut check = Box::pin(eventually(&mut until));
    let raced = std::future::poll_fn(|cx| {
        if let Poll::Ready(out) = op.as_mut().poll(cx) {
            return Poll::Ready(Err(format!("the operation ended by itself: {out:?}")));
        }
        check.as_mut().poll(cx).map(Ok)
    })
    .await;
    assert_eq!(raced, Ok(true), "the condition came while the operation ran");
    drop(op);
}

#[test]
fn home_raw_motion_with_wait_and_read_statuses() {
    runtime().block_on(async {
        let (host, client) = setup().await;
        client.set_speed(a(1), SpeedPercent::new(100.0).unwrap(), false).await.unwrap();
        client.move_absolute(a(1), pos(30.0), MoveOptions::default()).await.unwrap();
        client.wait_reached(&[a(1)], Some(Duration::from_secs(5))).await.unwrap();
        assert_eq!(client.read_position(a(1)).await.unwrap(), pos(30.0));

        client.home(a(1), MoveOptions::default()).await.unwrap();
        assert_eq!(client.started(), [a(1)], "a homing counts as started");
        client.wait_reached(&[a(1)], Some(Duration::from_secs(5))).await.unwrap();
        assert_eq!(host.with_device(|d| d.drive(1).unwrap().position()), 0.0, "homed to machine zero");

        let out = client.raw_motion(a(1), "POSA 20", AfterRaw::Wait(Duration::from_secs(5))).await.unwrap();
        assert_eq!(out.started, [a(1)]);
        assert!(out.waited, "{out:?}");
        assert_eq!(out.reply.as_deref(), Some(""), "a move is acknowledged");
        assert!(client.started().is_empty(), "seen at rest");

        let ids = [StatusId::ACTUAL_POSITION, StatusId::TARGET_POSITION, StatusId::STATUS_BITS_2];
        let values = client.read_statuses(a(1), &ids).await.unwrap();
        assert_eq!(values.len(), 3);
        assert_eq!(values[0], (StatusId::ACTUAL_POSITION, StatusValue::Position(pos(20.0))));
        assert_eq!(values[1], (StatusId::TARGET_POSITION, StatusValue::Position(pos(20.0))));
        assert!(
            matches!(values[2], (StatusId::STATUS_BITS_2, StatusValue::S17(b)) if !b.contains(S17Flag::CommandActive))
        );
        assert_eq!(client.echo(a(2), "S1").await.unwrap(), "2S1?");
        assert!(matches!(client.read_statuses(Address::BROADCAST, &ids).await, Err(Error::Broadcast(_))));
        assert!(client.close().await.unwrap().is_empty());
    })
}

#[test]
fn a_dropped_raw_motion_future_stops_the_axis_it_started() {
    runtime().block_on(async {
        let (host, client) = setup().await;
        // 1000 units at 100 units/s: ten seconds unless stopped.
        let moving = || host.with_device(|d| d.drive(1).unwrap().position() > 5.0);
        drop_when(client.raw_motion(a(1), "POSA 1000", AfterRaw::Wait(Duration::from_secs(60))), moving).await;
        assert!(eventually(|| client.started().is_empty()).await, "the stop was confirmed");
        let (still, o0, at) = host.with_device(|d| {
            (d.drive(1).unwrap().is_moving(), d.drive(1).unwrap().o0(), d.drive(1).unwrap().position())
        });
        assert!(!still && o0 == 0 && at < 1000.0, "switched off on the way: moving {still}, O0={o0}, at {at}");
        assert!(client.close().await.unwrap().is_empty());
    })
}

#[test]
fn start_and_release_hands_the_move_over_and_close_leaves_it_running() {
    runtime().block_on(async {
        let (host, client) = setup().await;
        let mut request = MoveRequest::new(MoveTarget::Absolute(pos(1000.0)));
        request.speed = Some(SpeedPercent::new(10.0).unwrap());
        let started = client.start_and_release(a(2), &request).await.unwrap();
        assert_eq!(started.target, pos(1000.0));
        assert!(client.started().is_empty(), "handed over");
        assert!(client.close().await.unwrap().is_empty(), "nothing of this client's to stop");
        assert!(host.with_device(|d| d.drive(2).unwrap().is_moving()), "the released move runs on");
    })
}

#[test]
fn a_drive_handle_moves_and_a_watch_stream_follows_it() {
    runtime().block_on(async {
        let (host, client) = setup().await;
        assert!(matches!(client.drive(Address::BROADCAST), Err(Error::Broadcast(_))));
        assert!(matches!(client.watch(Address::BROADCAST, Duration::from_millis(20)), Err(Error::Broadcast(_))));
        let two = client.drive(a(2)).unwrap();
        assert_eq!(two.address(), a(2));
        two.set_speed(SpeedPercent::new(50.0).unwrap(), false).await.unwrap();
        two.move_absolute(pos(25.0), MoveOptions::default()).await.unwrap();
        let interval = Duration::from_millis(20);
        let mut watch = two.watch(interval).unwrap();
        let clock = client.clock().clone();
        let t0 = clock.now();
        let mut samples = Vec::new();
        loop {
            let s = watch.next().await.unwrap();
            assert_eq!(s.drive, a(2));
            samples.push(s);
            if !s.moving() || samples.len() > 500 {
                break;
            }
        }
        let took = clock.now() - t0;
        let last = samples.last().unwrap();
        assert!(!last.moving() && last.position == pos(25.0), "{last:?}");
        assert!(samples.windows(2).all(|w| w[1].position.units() >= w[0].position.units()), "{samples:?}");
        assert!(samples.iter().any(|s| s.moving() && s.position.units() > 0.0), "seen on the way: {samples:?}");
        // One sample per interval, not a busy loop: the first at once, then one per 20 ms.
        let most = (took.as_millis() / interval.as_millis()) as usize + 2;
        assert!(samples.len() <= most, "{} samples in {took:?}", samples.len());
        assert_eq!(two.read_position().await.unwrap(), pos(25.0));
        assert!(host.with_device(|d| d.drive(1).unwrap().position()) == 0.0, "drive 1 untouched");
        // A watch reads S17 but does not end the record of a started axis: the close finds it at rest.
        assert_eq!(client.close().await.unwrap().drives, [(a(2), StopOutcome::AtRest)]);
    })
}

/// A link that records when it is dropped: the driver drops it once the close sequence has ended (or
/// given up at the bound).
struct DropClock<L> {
    inner: L,
    dropped: std::sync::Arc<std::sync::Mutex<Option<std::time::Instant>>>,
}

impl<L: Link> Link for DropClock<L> {
    fn send(&mut self, bytes: &[u8]) -> Result<(), LinkError> {
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

impl<L> Drop for DropClock<L> {
    fn drop(&mut self) {
        *self.dropped.lock().unwrap() = Some(std::time::Instant::now());
    }
}

const BOUND: Duration = Duration::from_millis(500);

/// A client whose line goes silent while drive 1 runs a long move, and the time its link is dropped.
#[allow(clippy::type_complexity)]
fn silent_line_with_a_move(
    runtime: &tokio::runtime::Runtime,
) -> (EmulatorHost<Emulator>, AsyncClient, std::sync::Arc<std::sync::Mutex<Option<std::time::Instant>>>) {
    let clock = RealClock::shared();
    let host = EmulatorHost::new(
        Emulator::new(SimConfig::bus(&[1], 0, BAUD)).unwrap(),
        clock.clone(),
        PipeConfig::paced(BAUD),
    );
    let (link, faults) = host.connect();
    let dropped = std::sync::Arc::new(std::sync::Mutex::new(None));
    let link = DropClock { inner: link, dropped: dropped.clone() };
    let mut cfg = Config::new(Mode::default(), BAUD);
    cfg.close_bound = BOUND;
    let client = runtime.block_on(AsyncClient::with_link(Box::new(link), clock, cfg)).unwrap();
    runtime.block_on(client.move_absolute(a(1), pos(1000.0), MoveOptions::default())).unwrap();
    faults.drop_next(Direction::HostToDevice, u64::MAX / 2);
    faults.drop_next(Direction::DeviceToHost, u64::MAX / 2);
    (host, client, dropped)
}

#[test]
fn dropped_in_the_runtime_on_a_silent_line_the_client_returns_at_once_and_closes_within_the_bound() {
    let runtime = runtime();
    let (host, client, dropped) = silent_line_with_a_move(&runtime);
    runtime.block_on(async {
        let t0 = std::time::Instant::now();
        drop(client);
        let returned = t0.elapsed();
        assert!(returned < BOUND / 2, "the runtime thread is not blocked: {returned:?}");
        assert!(eventually(|| dropped.lock().unwrap().is_some()).await, "the close ended");
        let closed = dropped.lock().unwrap().unwrap() - t0;
        assert!(closed >= BOUND, "it tried to stop the axis until the bound: {closed:?}");
        assert!(closed <= BOUND + Duration::from_millis(400), "bounded: {closed:?}");
    });
    assert!(host.with_device(|d| d.drive(1).unwrap().is_moving()), "COMPAX has no watchdog: it moves on");
}

#[test]
fn dropped_outside_a_runtime_on_a_silent_line_the_client_returns_within_the_bound() {
    let runtime = runtime();
    let (host, client, dropped) = silent_line_with_a_move(&runtime);
    let t0 = std::time::Instant::now();
    drop(client);
    let took = t0.elapsed();
    assert!(dropped.lock().unwrap().is_some(), "closed before the drop returned");
    assert!(took >= BOUND, "it tried to stop the axis until the bound: {took:?}");
    assert!(took <= BOUND + Duration::from_millis(400), "bounded: {took:?}");
    assert!(host.with_device(|d| d.drive(1).unwrap().is_moving()), "COMPAX has no watchdog: it moves on");
}

#[test]
fn a_homing_is_checked_by_machine_zero_and_one_stopped_halfway_is_not_taken_for_done() {
    runtime().block_on(async {
        let (host, client) = setup().await;
        client.set_speed(a(1), SpeedPercent::new(100.0).unwrap(), false).await.unwrap();
        client.move_absolute(a(1), pos(30.0), MoveOptions::default()).await.unwrap();
        client.wait_reached(&[a(1)], Some(Duration::from_secs(5))).await.unwrap();
        let at = client.home_and_wait(a(1), Some(Duration::from_secs(10))).await.unwrap();
        assert_eq!(at, pos(0.0));
        assert!(client.started().is_empty(), "seen at rest");

        // Another homing from far away, slowly; another task's stop switches the drive off halfway. The
        // positioning has ended (S17), but machine zero was not approached.
        client.move_absolute(a(1), pos(500.0), MoveOptions::default()).await.unwrap();
        client.wait_reached(&[a(1)], Some(Duration::from_secs(10))).await.unwrap();
        client.set_speed(a(1), SpeedPercent::new(10.0).unwrap(), false).await.unwrap();
        let stop = async {
            tokio::time::sleep(Duration::from_millis(300)).await;
            client.stop(a(1)).await
        };
        let (homed, stopped) =
            motionlink_testkit::join2(client.home_and_wait(a(1), Some(Duration::from_secs(30))), stop).await;
        stopped.unwrap();
        let e = homed.unwrap_err();
        assert!(matches!(e, Error::NotHomed { switched_off: true, .. }), "{e}");
        assert!(e.to_string().contains("not referenced"), "{e}");
        let rests = host.with_device(|d| d.drive(1).unwrap().position());
        assert!(rests > 100.0, "stopped halfway: {rests}");
    });
}
