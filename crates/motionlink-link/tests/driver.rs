//! The drivers, on a toy protocol whose session has every duty a device session has: requests with answer
//! timeouts and retries, a keepalive on its own deadlines, a move that polls until it arrives and reports
//! progress, cancellation that stops the motion, and a close sequence that stops what was started.
//!
//! The toy device answers `GET` with `VAL <position>`, `MOVE <target>` with `OK` (then moves one unit per
//! 10 ms), `STOP` with `OK`, `PING` with `PONG`; it stops by itself when no `PING` came for 100 ms.

use std::future::Future;
use std::sync::{Arc, Mutex};
use std::task::{Context, Poll, Wake, Waker};
use std::time::Duration;

use motionlink_link::cancel::CancelToken;
use motionlink_link::clock::{Clock, ManualClock, RealClock, SharedClock};
use motionlink_link::driver::{Driver, DriverConfig, Port};
use motionlink_link::pipe::{EmulatorHost, PipeConfig};
use motionlink_link::LinkError;

use crate::toy;
use toy::{Op, Toy, ToyError, ToySession};

// ----------------------------------------------------------------------------------------------------------

fn setup(clock: SharedClock) -> (Driver<ToySession>, EmulatorHost<Toy>) {
    let host = EmulatorHost::new(Toy::default(), Arc::clone(&clock), PipeConfig::paced(115_200));
    let port = Port::Bytes(Box::new(host.connect().0));
    let session = ToySession::new(clock.now());
    let driver = Driver::new(session, port, None, clock, DriverConfig::default()).unwrap();
    (driver, host)
}

#[test]
fn the_background_thread_keeps_the_device_alive_on_its_own_deadlines() {
    let clock = ManualClock::new_auto();
    let _me = clock.reserve_participant().enter();
    let (driver, host) = setup(clock.shared());
    clock.sleep(Duration::from_secs(3));
    let pings = host.with_device(|d| d.pings.clone());
    assert!(pings.len() >= 100, "{} pings in 3 s", pings.len());
    // Sent on the 30 ms grid (plus wire time), never drifting.
    for (i, at) in pings.iter().enumerate() {
        let due = Duration::from_millis(30 * i as u64);
        let late = at.since_origin().saturating_sub(due);
        assert!(late < Duration::from_millis(2), "ping {i} at {at} is {late:?} late");
    }
    driver.close().unwrap();
}

/// A link that calls `before_send` before each send (to record the sending thread, or to block).
struct BeforeSend<F: FnMut() + Send> {
    inner: Box<dyn motionlink_link::Link>,
    before_send: F,
}

impl<F: FnMut() + Send> motionlink_link::Link for BeforeSend<F> {
    fn send(&mut self, bytes: &[u8]) -> Result<(), LinkError> {
        (self.before_send)();
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

#[test]
fn a_blocking_caller_sends_its_request_itself_without_a_hand_off_to_the_background_thread() {
    let clock = RealClock::shared();
    let host = EmulatorHost::new(Toy::default(), Arc::clone(&clock), PipeConfig::paced(115_200));
    let threads = Arc::new(Mutex::new(Vec::new()));
    let record = Arc::clone(&threads);
    let link = BeforeSend {
        inner: Box::new(host.connect().0),
        before_send: move || record.lock().unwrap().push(std::thread::current().id()),
    };
    let mut session = ToySession::new(clock.now());
    session.pings = false;
    let driver = Driver::new(session, Port::Bytes(Box::new(link)), None, clock, DriverConfig::default()).unwrap();
    for _ in 0..500 {
        driver.run(Op::Get).unwrap();
    }
    let me = std::thread::current().id();
    let threads = threads.lock().unwrap().clone();
    assert_eq!(threads.len(), 500);
    assert!(threads.iter().all(|t| *t == me), "every GET went out from the caller's own thread");
    driver.close().unwrap();
}

#[test]
fn a_session_without_deadlines_gets_a_background_thread_only_when_a_duty_needs_one() {
    // Without pings the toy session has no deadline of its own: blocking GETs are driven by the caller and
    // no thread is started; the first async operation (driven by the background thread) starts it. On the
    // real clock: the future below is awaited outside the clock.
    let clock = RealClock::shared();
    let host = EmulatorHost::new(Toy::default(), Arc::clone(&clock), PipeConfig::paced(115_200));
    let mut session = ToySession::new(clock.now());
    session.pings = false;
    let port = Port::Bytes(Box::new(host.connect().0));
    let driver = Driver::new(session, port, None, Arc::clone(&clock), DriverConfig::default()).unwrap();
    assert!(!driver.has_background_thread());
    for _ in 0..20 {
        driver.run(Op::Get).unwrap();
    }
    driver.with_session(|_| ());
    assert!(!driver.has_background_thread(), "nothing needed a thread for blocking GETs");
    assert_eq!(driver.with_session(|s| s.background_looks.load(std::sync::atomic::Ordering::Relaxed)), 0);
    assert_eq!(block_on(driver.start(Op::Get)).unwrap(), 0);
    assert!(driver.has_background_thread(), "an async operation needs the thread");
    let (sent, by) = driver.with_session(|s| (s.sent.clone(), s.sent_by.clone()));
    assert_eq!(sent.last().map(String::as_str), Some("GET"));
    assert_eq!(by.last().cloned().flatten().as_deref(), Some("motionlink-driver"));
    driver.close().unwrap();
    // With pings (a deadline from the start) the thread runs from the start.
    let (driver, _host) = setup(clock);
    assert!(driver.has_background_thread());
    driver.close().unwrap();
}

#[test]
fn a_blocking_move_reports_progress_and_ends_at_the_target() {
    let clock = ManualClock::new_auto();
    let _me = clock.reserve_participant().enter();
    let (driver, host) = setup(clock.shared());
    let mut seen = Vec::new();
    let end = driver.run_with(Op::Move(20), &mut |p| seen.push(*p), None).unwrap();
    assert_eq!(end, 20);
    assert!(seen.len() >= 5 && seen.windows(2).all(|w| w[0] <= w[1]), "{seen:?}");
    assert_eq!(seen.last(), Some(&20), "the progress that came with the end reaches the caller: {seen:?}");
    assert_eq!(host.with_device(|d| (d.position, d.watchdog_stops)), (20, 0));
    driver.close().unwrap();
}

#[test]
fn every_progress_report_reaches_a_blocking_caller_in_order_even_two_at_once() {
    // Each look is reported twice in one go (v, then -v): both reach the caller, in order, none replaced by
    // the next before the caller saw it.
    let clock = ManualClock::new_auto();
    let _me = clock.reserve_participant().enter();
    let host = EmulatorHost::new(Toy::default(), clock.shared(), PipeConfig::paced(115_200));
    let mut session = ToySession::new(clock.now());
    session.double_progress = true;
    let port = Port::Bytes(Box::new(host.connect().0));
    let driver = Driver::new(session, port, None, clock.shared(), DriverConfig::default()).unwrap();
    let mut seen = Vec::new();
    assert_eq!(driver.run_with(Op::Move(20), &mut |p| seen.push(*p), None).unwrap(), 20);
    let (last, pairs) = seen.split_last().unwrap();
    assert_eq!(*last, 20, "{seen:?}");
    assert!(pairs.len() >= 4 && pairs.len() % 2 == 0, "{seen:?}");
    assert!(pairs.chunks(2).all(|p| p[1] == -p[0]), "each look and its twin, in order: {seen:?}");
    driver.close().unwrap();
}

#[test]
fn the_background_thread_does_not_spin_while_a_caller_holds_the_port_past_a_deadline() {
    // On the real clock: a deadline due while a blocking caller drives the port (here the keepalive pings,
    // due every 30 ms during a move of about 200 ms) is the caller's to meet; the background thread waits
    // for the port to come back instead of waking again and again at the deadline already past.
    let clock = motionlink_link::RealClock::shared();
    let (driver, _host) = setup(clock);
    let looks_before = driver.with_session(|s| s.background_looks.load(std::sync::atomic::Ordering::Relaxed));
    assert_eq!(driver.run_with(Op::Move(20), &mut |_| {}, None).unwrap(), 20);
    let looks = driver.with_session(|s| s.background_looks.load(std::sync::atomic::Ordering::Relaxed));
    // A few looks per ping at most; a spinning thread looks hundreds of thousands of times.
    assert!(looks - looks_before < 200, "the background thread looked {} times", looks - looks_before);
    driver.close().unwrap();
}

#[test]
fn a_blocking_caller_drives_the_port_itself_and_leaves_the_background_thread_asleep() {
    let clock = ManualClock::new_auto();
    let _me = clock.reserve_participant().enter();
    let (driver, _host) = setup(clock.shared());
    // The background thread sends the first keepalive (at 0) and sleeps until the next (at 30 ms); the 20
    // GETs below take about 18 ms of line time in between.
    clock.sleep(Duration::from_millis(2));
    let me = std::thread::current().name().map(str::to_string);
    let looks_before = driver.with_session(|s| s.background_looks.load(std::sync::atomic::Ordering::Relaxed));
    for _ in 0..20 {
        driver.run(Op::Get).unwrap();
    }
    let looks = driver.with_session(|s| s.background_looks.load(std::sync::atomic::Ordering::Relaxed));
    // Nothing was due for the background thread meanwhile: it was not woken at each call.
    assert!(looks - looks_before < 5, "the background thread looked {} times", looks - looks_before);
    let (sent, by) = driver.with_session(|s| (s.sent.clone(), s.sent_by.clone()));
    let gets: Vec<_> = sent.iter().zip(&by).filter(|(t, _)| *t == "GET").map(|(_, b)| b.clone()).collect();
    assert_eq!(gets.len(), 20);
    // Every GET was sent by the caller's thread: no hand-off to the background thread (a thread switch per
    // operation, which a loaded machine makes slow).
    assert!(gets.iter().all(|b| *b == me), "{gets:?}");
    driver.close().unwrap();
}

#[test]
fn another_thread_reads_while_a_move_runs() {
    let clock = ManualClock::new_auto();
    let _me = clock.reserve_participant().enter();
    let (driver, host) = setup(clock.shared());
    let reader_ticket = clock.reserve_participant();
    std::thread::scope(|s| {
        let reader = s.spawn(|| {
            let _p = reader_ticket.enter();
            let mut reads = Vec::new();
            for _ in 0..10 {
                reads.push(driver.run(Op::Get).unwrap());
                clock.sleep(Duration::from_millis(25));
            }
            reads
        });
        assert_eq!(driver.run(Op::Move(30)).unwrap(), 30);
        let reads = reader.join().unwrap();
        assert!(reads.iter().any(|&p| p > 0 && p < 30), "reads during the move: {reads:?}");
    });
    assert_eq!(host.with_device(|d| d.watchdog_stops), 0);
    driver.close().unwrap();
}

#[test]
fn a_cancelled_blocking_move_is_stopped_on_the_device() {
    let clock = ManualClock::new_auto();
    let _me = clock.reserve_participant().enter();
    let (driver, host) = setup(clock.shared());
    let token = CancelToken::new();
    let mut n = 0;
    let t = token.clone();
    let r = driver.run_with(
        Op::Move(100),
        &mut |_| {
            n += 1;
            if n == 3 {
                t.cancel();
            }
        },
        Some(&token),
    );
    assert!(matches!(r, Err(ToyError::Cancelled)), "{r:?}");
    let (position, moving) = host.with_device(|d| (d.position, d.moving_since.is_some()));
    assert!(!moving && position < 100, "stopped at {position}");
    clock.sleep(Duration::from_millis(200));
    assert_eq!(host.with_device(|d| d.position), position, "it stays stopped");
    driver.close().unwrap();
}

#[test]
fn dropping_the_driver_stops_what_it_started() {
    let clock = ManualClock::new_auto();
    let _me = clock.reserve_participant().enter();
    let (driver, host) = setup(clock.shared());
    let future = driver.start(Op::Move(100));
    std::mem::forget(future); // nobody waits for it; the driver still drives it
    clock.sleep(Duration::from_millis(100));
    assert!(host.with_device(|d| d.moving_since.is_some()));
    drop(driver);
    let (moving, last) = host.with_device(|d| (d.moving_since.is_some(), d.commands.last().cloned()));
    assert!(!moving, "the drop stopped the motion");
    assert_eq!(last.as_deref(), Some("STOP"));
}

/// A minimal executor: polls the future on this thread, parking between wake-ups.
fn block_on<F: Future>(future: F) -> F::Output {
    struct Unpark(std::thread::Thread);
    impl Wake for Unpark {
        fn wake(self: Arc<Self>) {
            self.0.unpark();
        }
    }
    let waker = Waker::from(Arc::new(Unpark(std::thread::current())));
    let mut cx = Context::from_waker(&waker);
    let mut future = std::pin::pin!(future);
    loop {
        if let Poll::Ready(v) = future.as_mut().poll(&mut cx) {
            return v;
        }
        std::thread::park_timeout(Duration::from_millis(100));
    }
}

#[test]
fn an_async_move_runs_on_the_background_thread_and_a_dropped_future_stops_it() {
    let clock = RealClock::shared();
    let (driver, host) = setup(Arc::clone(&clock));
    assert_eq!(block_on(driver.start(Op::Move(3))).unwrap(), 3);

    let future = driver.start(Op::Move(1000));
    clock.sleep(Duration::from_millis(60));
    assert!(host.with_device(|d| d.moving_since.is_some()));
    drop(future);
    let stopped = Arc::new(Mutex::new(false));
    for _ in 0..100 {
        if host.with_device(|d| d.moving_since.is_none()) {
            *stopped.lock().unwrap() = true;
            break;
        }
        clock.sleep(Duration::from_millis(5));
    }
    assert!(*stopped.lock().unwrap(), "the dropped future's move was stopped");
    assert_eq!(host.with_device(|d| d.commands.last().cloned()).as_deref(), Some("STOP"));
    driver.close().unwrap();
}

#[test]
fn operations_after_close_fail_and_a_dead_device_bounds_the_close() {
    let clock = ManualClock::new_auto();
    let _me = clock.reserve_participant().enter();
    let host = EmulatorHost::new(Toy::default(), clock.shared(), PipeConfig::instant());
    let (link, faults) = host.connect();
    let config = DriverConfig { close_bound: Duration::from_millis(500), ..DriverConfig::default() };
    let driver =
        Driver::new(ToySession::new(clock.now()), Port::Bytes(Box::new(link)), None, clock.shared(), config).unwrap();
    driver.run(Op::Get).unwrap();
    faults.drop_next(motionlink_link::pipe::Direction::DeviceToHost, u64::MAX / 2);
    let started = clock.now();
    let r = driver.close();
    assert!(matches!(r, Err(ToyError::Unconfirmed)), "{r:?}");
    assert!(clock.now() - started <= Duration::from_millis(500));
}

#[test]
fn a_move_whose_stop_a_dead_device_never_confirms_ends_with_the_close_s_error_not_never() {
    let clock = RealClock::shared();
    let host = EmulatorHost::new(Toy::default(), Arc::clone(&clock), PipeConfig::paced(115_200));
    let (link, faults) = host.connect();
    let config = DriverConfig { close_bound: Duration::from_millis(10), ..DriverConfig::default() };
    let driver = Driver::new(ToySession::new(clock.now()), Port::Bytes(Box::new(link)), None, clock, config).unwrap();
    let future = driver.start(Op::Move(1000));
    let moving = (0..200).any(|_| {
        std::thread::sleep(Duration::from_millis(5));
        host.with_device(|d| d.moving_since.is_some())
    });
    assert!(moving, "the move started");
    // The device goes silent: the close's STOP is not answered, and the close gives up after its bound
    // (10 ms, shorter than the toy's answer timeout: the session has not ended the move by then).
    faults.drop_next(motionlink_link::pipe::Direction::DeviceToHost, u64::MAX / 2);
    assert!(matches!(driver.close(), Err(ToyError::Unconfirmed)));
    // The future of the move, which the session had not ended, ends with the close's error (or, on a
    // machine so loaded that the stop's answer timed out first, with that).
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || tx.send(block_on(future)).unwrap());
    let ended = rx.recv_timeout(Duration::from_secs(2)).expect("the move's future ended");
    assert!(matches!(ended, Err(ToyError::Unconfirmed | ToyError::Timeout)), "{ended:?}");
}

#[test]
fn a_close_returns_within_its_bound_and_grace_while_the_background_thread_is_stuck_in_a_send() {
    let clock = RealClock::shared();
    let host = EmulatorHost::new(Toy::default(), Arc::clone(&clock), PipeConfig::paced(115_200));
    let stuck = Arc::new(std::sync::atomic::AtomicBool::new(false));
    let release = Arc::new((Mutex::new(false), std::sync::Condvar::new()));
    // Once `stuck` is set, a send blocks (as a TCP send into a peer that stopped reading) until `release` is.
    let (stuck_now, released) = (Arc::clone(&stuck), Arc::clone(&release));
    let block = move || {
        if stuck_now.load(std::sync::atomic::Ordering::SeqCst) {
            let (done, cv) = &*released;
            let mut r = done.lock().unwrap();
            while !*r {
                r = cv.wait(r).unwrap();
            }
        }
    };
    let link = BeforeSend { inner: Box::new(host.connect().0), before_send: block };
    let config = DriverConfig { close_bound: Duration::from_millis(200), ..DriverConfig::default() };
    let driver = Driver::new(ToySession::new(clock.now()), Port::Bytes(Box::new(link)), None, clock, config).unwrap();
    stuck.store(true, std::sync::atomic::Ordering::SeqCst);
    // An async operation: the background thread sends it, and stays in that send.
    let future = driver.start(Op::Get);
    std::thread::sleep(Duration::from_millis(50));
    let (tx, rx) = std::sync::mpsc::channel();
    let closer = std::thread::spawn(move || {
        let started = std::time::Instant::now();
        let r = driver.close();
        tx.send((r.is_err(), started.elapsed())).unwrap();
    });
    let outcome = rx.recv_timeout(Duration::from_secs(5));
    // Let the stuck send return, so that the thread ends before the test does.
    *release.0.lock().unwrap() = true;
    release.1.notify_all();
    let (failed, took) = outcome.expect("the close returned within 5 s");
    closer.join().unwrap();
    drop(future);
    assert!(failed, "a close whose stop could not be sent is not confirmed");
    let bound = Duration::from_millis(200) + motionlink_link::driver::BACKGROUND_EXIT_GRACE;
    assert!(took <= bound + Duration::from_millis(200), "the close took {took:?} (bound {bound:?})");
}

#[cfg(feature = "tokio")]
#[test]
fn on_tokio_positions_are_read_while_a_move_runs_and_a_dropped_task_stops_it() {
    let runtime = tokio::runtime::Builder::new_current_thread().enable_all().build().unwrap();
    runtime.block_on(async {
        use motionlink_link::driver::AsyncDriver;
        let clock = RealClock::shared();
        let (driver, host) = setup(Arc::clone(&clock));
        let driver = Arc::new(AsyncDriver::from_driver(driver));
        let mover = {
            let d = Arc::clone(&driver);
            tokio::spawn(async move { d.run(Op::Move(1000)).await })
        };
        let mut reads = Vec::new();
        for _ in 0..5 {
            reads.push(driver.run(Op::Get).await.unwrap());
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        assert!(reads.windows(2).any(|w| w[1] > w[0]), "positions change during the move: {reads:?}");
        mover.abort(); // the task's future is dropped: its move is cancelled and stopped
        let _ = mover.await;
        let mut stopped = false;
        for _ in 0..100 {
            if host.with_device(|d| d.moving_since.is_none()) {
                stopped = true;
                break;
            }
            tokio::time::sleep(Duration::from_millis(5)).await;
        }
        assert!(stopped, "aborting the task stopped the motion");
        Arc::try_unwrap(driver).unwrap().close().await.unwrap();
    })
}
