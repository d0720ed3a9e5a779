//! Drivers that run a [`Session`] over a link: [`Driver`] for blocking callers (any number of threads)
//! and [`OpFuture`] for async ones, on the same session and the same background duty.
//!
//! A driver owns the session, the port, and at most one background thread. Whoever needs the link drives
//! it: a blocking caller whose operation is under way drives the port itself while it is free (no thread
//! hand-off on the fast path), and the background thread drives it when nobody else does: for a
//! keepalive or watchdog deadline of the session, or for operations of async callers. The thread is
//! started when the first such duty comes: a session without deadlines (a protocol with no keepalive)
//! used only by blocking callers never has one. Every wait is a wait
//! on the [`Clock`](crate::clock::Clock), so a session runs on a manual clock in tests exactly as on the
//! real one.
//!
//! Safety: dropping a [`Driver`] (or calling [`Driver::close`]) runs the session's close sequence, which
//! stops everything the session started, and waits for it at most [`DriverConfig::close_bound`]. Dropping
//! an [`OpFuture`] before it is done cancels its operation, which stops any motion it started.

use std::collections::{HashMap, VecDeque};
use std::sync::{Arc, Mutex, MutexGuard};
use std::task::Waker;
use std::time::Duration;

use crate::cancel::CancelToken;
use crate::clock::{lock, SharedClock, Signal, Timestamp};
use crate::link::LinkError;
use crate::session::{Action, Event, Input, OpId, Session, SessionError};

mod background;
mod future;
mod port;

#[cfg(feature = "tokio")]
pub use future::AsyncDriver;
pub use future::OpFuture;
use port::Received;
pub use port::{Port, PortOpener};

/// How long a close waits, after its bound, for the background thread to end before it leaves the thread
/// to end by itself (see [`DriverConfig::close_bound`]).
pub const BACKGROUND_EXIT_GRACE: Duration = Duration::from_secs(1);

/// How a driver waits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DriverConfig {
    /// The longest [`Driver::close`] (and `Drop`) waits for the session's close sequence before it gives
    /// up and reports that the stop was not confirmed. Default 5 s. The background thread then gets at most
    /// [`BACKGROUND_EXIT_GRACE`] more to end; one stuck in a link call longer than that (a reopen's connect) is
    /// left to end by itself, so that a close never blocks longer than `close_bound` plus that grace.
    pub close_bound: Duration,
    /// The longest single read of the link while the session waits for input, so that an operation
    /// started meanwhile by another caller is sent without waiting for the whole answer timeout. Default
    /// 20 ms.
    pub read_slice: Duration,
}

impl Default for DriverConfig {
    fn default() -> Self {
        DriverConfig { close_bound: Duration::from_secs(5), read_slice: Duration::from_millis(20) }
    }
}

/// The most progress reports an operation keeps for its caller: a caller that falls this far behind loses
/// the oldest (a watch's samples come at most every few ms; a caller reads them at each wake-up).
const PROGRESS_KEPT: usize = 256;

enum Waiter {
    Signal(Signal),
    Waker(Option<Waker>),
}

impl Waiter {
    /// Tells the caller that its operation's result is there.
    fn wake(&mut self) {
        match self {
            Waiter::Signal(s) => s.raise(),
            Waiter::Waker(w) => {
                if let Some(w) = w.take() {
                    w.wake();
                }
            }
        }
    }
}

/// One caller's operation as the driver sees it: its result and progress once they come, and who waits for them.
struct CallerSlot<S: Session> {
    result: Option<Result<S::Output, S::Error>>,
    /// Progress reports not yet taken, oldest first (at most [`PROGRESS_KEPT`]: beyond, the oldest goes).
    progress: VecDeque<S::Progress>,
    waiter: Waiter,
    /// The caller went away (a dropped future): the result is dropped when it comes.
    abandoned: bool,
}

/// What the driver owns behind its lock: the session, the port while nobody drives it, and each caller's slot.
struct DriverState<S: Session> {
    session: S,
    /// The port while nobody drives it.
    port: Option<Port>,
    opener: Option<PortOpener>,
    ops: HashMap<OpId, CallerSlot<S>>,
    /// The wake-up of whoever drives the port now.
    driver_wake: Option<Signal>,
    /// Callers waiting for the port to be free.
    port_waiters: Vec<Signal>,
    /// The close sequence's outcome, once known.
    closed: Option<Result<(), S::Error>>,
    close_started: bool,
    close_waiter: Option<Signal>,
    stop_thread: bool,
    /// The background thread sleeps until this (`Some(None)`: until woken); `None` while it is awake.
    background_sleeps: Option<Option<Timestamp>>,
}

impl<S: Session> DriverState<S> {
    /// Hands every event of the session to whoever waits for it.
    fn dispatch(&mut self) {
        while let Some(event) = self.session.poll_event() {
            match event {
                Event::Progress(id, p) => {
                    if let Some(slot) = self.ops.get_mut(&id) {
                        if slot.progress.len() == PROGRESS_KEPT {
                            slot.progress.pop_front();
                        }
                        slot.progress.push_back(p);
                        if let Waiter::Signal(s) = &slot.waiter {
                            s.raise();
                        }
                    }
                }
                Event::Done(id, result) => {
                    let abandoned = self.ops.get(&id).is_none_or(|s| s.abandoned);
                    if abandoned {
                        self.ops.remove(&id);
                        if let Err(e) = result {
                            tracing::debug!("{id} of a caller that went away ended: {e}");
                        }
                        continue;
                    }
                    if let Some(slot) = self.ops.get_mut(&id) {
                        slot.result = Some(result);
                        slot.waiter.wake();
                    }
                }
                Event::Closed(result) => {
                    self.closed = Some(result);
                    if let Some(s) = &self.close_waiter {
                        s.raise();
                    }
                }
            }
        }
    }

    /// Wakes whoever drives the port, or else the background thread (started if it was not yet).
    fn wake_driver(&self, shared: &Shared<S>) {
        match &self.driver_wake {
            Some(s) => s.raise(),
            None => shared.wake_background(),
        }
    }
}

use background::Background;

struct Shared<S: Session> {
    clock: SharedClock,
    config: DriverConfig,
    core: Mutex<DriverState<S>>,
    /// The background thread's wake-up.
    background: Signal,
    /// Raised by the background thread when it ends: joining waits on the clock first, so that a manual
    /// clock sees the joining thread as waiting.
    exited: Signal,
    exited_flag: std::sync::atomic::AtomicBool,
    thread: Mutex<Background>,
    /// This driver, for the background thread started from `&self`.
    this: std::sync::Weak<Shared<S>>,
}

/// What a blocking caller that drives the port does on the way: its progress and its cancellation.
struct Caller<'a, P> {
    id: OpId,
    progress: &'a mut dyn FnMut(&P),
    cancel: Option<&'a CancelToken>,
    cancel_sent: bool,
    /// The panic of the caller's progress callback, if it panicked: the operation is cancelled (which stops
    /// what it started, as the port is still here to say it), and the panic goes on once it has ended.
    panicked: &'a PanicSlot,
}

/// Where a progress callback's panic waits until its operation has ended.
type PanicSlot = std::cell::RefCell<Option<Box<dyn std::any::Any + Send>>>;

impl<P> Caller<'_, P> {
    /// True when the operation is to be cancelled now: the caller's token was cancelled, or its progress
    /// callback panicked.
    fn to_cancel(&self) -> bool {
        !self.cancel_sent && (self.cancel.is_some_and(CancelToken::is_cancelled) || self.panicked.borrow().is_some())
    }
}

impl<S: Session> Shared<S> {
    fn core(&self) -> MutexGuard<'_, DriverState<S>> {
        lock(&self.core)
    }

    /// Drives the port until `until` holds (checked whenever nothing is left to send) or `hard_deadline`
    /// passes, then puts the port back and wakes those who wait for it.
    fn drive(
        &self,
        mut port: Port,
        me: &Signal,
        hard_deadline: Option<Timestamp>,
        mut caller: Option<&mut Caller<'_, S::Progress>>,
        until: &dyn Fn(&mut DriverState<S>, Timestamp) -> bool,
    ) {
        let mut buf = [0u8; 1024];
        loop {
            // Cancellation and progress of the caller that drives.
            if let Some(c) = caller.as_deref_mut() {
                let mut core = self.core();
                if c.to_cancel() {
                    c.cancel_sent = true;
                    let now = self.clock.now();
                    core.session.cancel(c.id, now);
                }
                drop(core);
                // Every report in order, each taken alone (the lock is not held while the caller looks).
                loop {
                    let next = self.core().ops.get_mut(&c.id).and_then(|s| s.progress.pop_front());
                    let Some(p) = next else { break };
                    (c.progress)(&p);
                }
            }
            // Everything there is to send, one action at a time (the lock is not held during I/O).
            let mut acted = false;
            loop {
                let action = {
                    let mut core = self.core();
                    core.driver_wake = Some(me.clone());
                    let now = self.clock.now();
                    if core.session.poll_timeout().is_some_and(|t| t <= now) {
                        core.session.handle_timeout(now);
                    }
                    let a = core.session.poll_transmit(now);
                    core.dispatch();
                    a
                };
                let Some(action) = action else { break };
                acted = true;
                let result = match action {
                    Action::Reopen => self.reopen(&mut port),
                    a => port.perform(&a).map_err(|e| (e, false)),
                };
                if let Err((e, reopen)) = result {
                    let mut core = self.core();
                    let now = self.clock.now();
                    if reopen {
                        core.session.handle_reopened(Err(e), now);
                    } else {
                        core.session.handle_link_error(e, now);
                    }
                    core.dispatch();
                }
            }
            let (deadline, wants_input) = {
                let mut core = self.core();
                let now = self.clock.now();
                core.dispatch();
                let done = until(&mut core, now) || hard_deadline.is_some_and(|d| now >= d);
                if !acted && done {
                    core.driver_wake = None;
                    core.port = Some(port);
                    for w in core.port_waiters.drain(..) {
                        w.raise();
                    }
                    // The background thread is woken only if the session now has something for it (work
                    // under way, or a deadline earlier than the one it sleeps until): waking it for nothing
                    // costs a thread switch per operation.
                    let next = core.session.poll_timeout();
                    let earlier = match core.background_sleeps {
                        Some(until) => next.is_some_and(|t| until.is_none_or(|u| t < u)),
                        None => false,
                    };
                    let background_needed = !core.session.is_idle() || earlier;
                    drop(core);
                    if background_needed {
                        self.wake_background();
                    }
                    return;
                }
                if acted {
                    continue;
                }
                let deadline = match (core.session.poll_timeout(), hard_deadline) {
                    (Some(a), Some(b)) => Some(a.min(b)),
                    (a, b) => a.or(b),
                };
                (deadline, core.session.wants_input())
            };
            let now = self.clock.now();
            if deadline.is_some_and(|d| d <= now) {
                continue;
            }
            if wants_input {
                let slice = deadline.map_or(self.config.read_slice, |d| (d - now).min(self.config.read_slice));
                let received = port.recv(&mut buf, slice);
                let mut core = self.core();
                let now = self.clock.now();
                match received {
                    Ok(Some(Received::Bytes(n))) => core.session.handle_input(Input::Bytes(&buf[..n]), now),
                    Ok(Some(Received::Frame(f))) => core.session.handle_input(Input::Frame(&f), now),
                    Ok(None) => {}
                    Err(e) => core.session.handle_link_error(e, now),
                }
                core.dispatch();
            } else {
                me.wait_until(deadline);
            }
        }
    }

    /// Replaces the port by a new one from the opener. The error says whether it was the reopening that
    /// failed (true) or something else.
    fn reopen(&self, port: &mut Port) -> Result<(), (LinkError, bool)> {
        let name = port.describe();
        *port = Port::Closed(name.clone());
        let opener = self.core().opener.take();
        let Some(mut opener) = opener else {
            let e = LinkError::Open { port: name, reason: "this session has no way to reopen its port".into() };
            return Err((e, true));
        };
        let result = opener();
        self.core().opener = Some(opener);
        match result {
            Ok(p) => {
                *port = p;
                let mut core = self.core();
                let now = self.clock.now();
                core.session.handle_reopened(Ok(()), now);
                core.dispatch();
                Ok(())
            }
            Err(e) => Err((e, true)),
        }
    }
}

/// Runs a session over a port; see the [module documentation](self).
///
/// `Driver` is `Sync`: share it (`&Driver`, `Arc<Driver>`) between threads; their operations interleave on
/// the line as the session schedules them.
pub struct Driver<S: Session> {
    shared: Arc<Shared<S>>,
    /// False once closed.
    open: bool,
    describe: String,
}

impl<S: Session> std::fmt::Debug for Driver<S> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Driver").field("port", &self.describe).finish()
    }
}

impl<S: Session> Driver<S> {
    /// Starts driving `session` over `port`; `opener` reopens the port when the session asks for it
    /// ([`Action::Reopen`]). The background thread (a participant of `clock`) is spawned now if the session
    /// has a deadline or work under way, else when it first gets one or an async caller starts an operation.
    pub fn new(
        session: S,
        port: Port,
        opener: Option<PortOpener>,
        clock: SharedClock,
        config: DriverConfig,
    ) -> std::io::Result<Self> {
        let describe = port.describe();
        let needs_background = session.poll_timeout().is_some() || !session.is_idle();
        let shared = Arc::new_cyclic(|this| Shared {
            background: clock.signal(),
            exited: clock.signal(),
            exited_flag: std::sync::atomic::AtomicBool::new(false),
            thread: Mutex::new(Background::NotStarted),
            this: this.clone(),
            clock: Arc::clone(&clock),
            config,
            core: Mutex::new(DriverState {
                session,
                port: Some(port),
                opener,
                ops: HashMap::new(),
                driver_wake: None,
                port_waiters: Vec::new(),
                closed: None,
                close_started: false,
                close_waiter: None,
                stop_thread: false,
                // Until the thread runs, it counts as asleep with no deadline: a deadline the session gets
                // starts it.
                background_sleeps: Some(None),
            }),
        });
        if needs_background {
            shared.start_background()?;
        }
        Ok(Driver { shared, open: true, describe })
    }

    /// True while the driver's background thread runs (it is started only when a duty needs it).
    pub fn has_background_thread(&self) -> bool {
        matches!(*lock(&self.shared.thread), Background::Running(_))
    }

    /// The port as the user named it.
    pub fn port_name(&self) -> &str {
        &self.describe
    }

    /// The clock the session runs on.
    pub fn clock(&self) -> &SharedClock {
        &self.shared.clock
    }

    /// Runs `f` on the session (to read its statistics or change a setting), then lets the driver look at
    /// it again.
    pub fn with_session<R>(&self, f: impl FnOnce(&mut S) -> R) -> R {
        let mut core = self.shared.core();
        let r = f(&mut core.session);
        core.dispatch();
        // Only a deadline the session got (or work under way) needs a thread that is not running yet.
        let needed = core.session.poll_timeout().is_some() || !core.session.is_idle();
        if core.driver_wake.is_some() || needed || self.has_background_thread() {
            core.wake_driver(&self.shared);
        }
        r
    }

    /// Starts `op`, returns its id and the waiter's registration. The driver of the port (if one drives it
    /// now) is woken to send it; if nobody does, the background thread is, unless the caller is about to
    /// drive the port itself (`caller_drives`): waking a thread it would only race for the port costs a
    /// hand-off on the fast path.
    fn submit(&self, op: S::Op, waiter: Waiter, caller_drives: bool) -> Result<OpId, S::Error> {
        let mut core = self.shared.core();
        if core.close_started {
            return Err(S::Error::session_closed());
        }
        let now = self.shared.clock.now();
        let id = core.session.start(op, now);
        core.ops.insert(id, CallerSlot { result: None, progress: VecDeque::new(), waiter, abandoned: false });
        core.dispatch();
        match &core.driver_wake {
            Some(s) => s.raise(),
            None if caller_drives => {}
            None => self.shared.wake_background(),
        }
        Ok(id)
    }

    /// Runs `op` to its end on the calling thread.
    pub fn run(&self, op: S::Op) -> Result<S::Output, S::Error> {
        self.run_with(op, &mut |_| {}, None)
    }

    /// Runs `op` to its end on the calling thread, calling `progress` with each progress report in order (none
    /// is left out because two came before the caller looked), and
    /// cancelling the operation (which stops what it started) when `cancel` is cancelled. If `progress`
    /// panics, the operation is cancelled the same way (no more reports go to it), and the panic resumes once
    /// the operation has ended: unwinding at once would drop the port with the stop still to be sent.
    pub fn run_with(
        &self,
        op: S::Op,
        progress: &mut dyn FnMut(&S::Progress),
        cancel: Option<&CancelToken>,
    ) -> Result<S::Output, S::Error> {
        let shared = &*self.shared;
        let me = shared.clock.signal();
        if let Some(t) = cancel {
            t.watch(&me);
        }
        let panicked = PanicSlot::new(None);
        // A panic of `progress` is held until the operation has ended (it is cancelled meanwhile): unwinding
        // here would drop the port, and with it the stop of what the operation started.
        let mut guarded = |p: &S::Progress| {
            if panicked.borrow().is_some() {
                return;
            }
            if let Err(payload) = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| progress(p))) {
                *panicked.borrow_mut() = Some(payload);
            }
        };
        let result = self.submit(op, Waiter::Signal(me.clone()), true).and_then(|id| {
            let mut caller = Caller { id, progress: &mut guarded, cancel, cancel_sent: false, panicked: &panicked };
            loop {
                let (port, progress) = {
                    let mut core = shared.core();
                    let slot = core.ops.get_mut(&id).expect("a waited-for operation keeps its slot");
                    if let Some(r) = slot.result.take() {
                        // The progress that came with the end (a watch's last sample) is still the caller's.
                        let last = core.ops.remove(&id).map(|s| s.progress).unwrap_or_default();
                        drop(core);
                        last.iter().for_each(|p| (caller.progress)(p));
                        return r;
                    }
                    let progress = slot.progress.pop_front();
                    if caller.to_cancel() {
                        caller.cancel_sent = true;
                        let now = shared.clock.now();
                        core.session.cancel(id, now);
                        core.dispatch();
                        core.wake_driver(shared);
                    }
                    let port = core.port.take();
                    if port.is_none() {
                        core.port_waiters.push(me.clone());
                    }
                    (port, progress)
                };
                if let Some(p) = progress {
                    (caller.progress)(&p);
                }
                match port {
                    Some(port) => shared.drive(port, &me, None, Some(&mut caller), &|core, _| {
                        core.ops.get(&id).is_none_or(|s| s.result.is_some() || !s.progress.is_empty())
                    }),
                    None => {
                        me.wait_until(None);
                    }
                }
            }
        });
        if let Some(t) = cancel {
            t.unwatch(&me);
        }
        if let Some(payload) = panicked.into_inner() {
            std::panic::resume_unwind(payload);
        }
        result
    }

    /// Starts `op` for an async caller: the background thread drives it, and the returned future ends
    /// with its result. Dropping the future before it is done cancels the operation (which stops any
    /// motion it started).
    pub fn start(&self, op: S::Op) -> OpFuture<S> {
        // Only the background thread drives an async caller's operation.
        if let Err(e) = self.shared.start_background() {
            let port = self.describe.clone();
            let source = std::io::Error::other(format!("cannot start the driver's background thread: {e}"));
            return OpFuture {
                shared: None,
                id: OpId(0),
                early: Some(S::Error::from(LinkError::Io { port, source: std::sync::Arc::new(source) })),
            };
        }
        match self.submit(op, Waiter::Waker(None), false) {
            Ok(id) => OpFuture { shared: Some(Arc::clone(&self.shared)), id, early: None },
            Err(e) => OpFuture { shared: None, id: OpId(0), early: Some(e) },
        }
    }

    /// Runs the session's close sequence (stop everything it started) and waits for its outcome at most
    /// [`DriverConfig::close_bound`]; then stops the background thread (waiting for it at most
    /// [`BACKGROUND_EXIT_GRACE`]). Operations started afterwards fail.
    pub fn close(mut self) -> Result<(), S::Error> {
        self.close_inner()
    }

    fn close_inner(&mut self) -> Result<(), S::Error> {
        let shared = &*self.shared;
        let me = shared.clock.signal();
        let bound = shared.config.close_bound;
        let give_up = shared.clock.now() + bound;
        {
            let mut core = shared.core();
            core.close_waiter = Some(me.clone());
            if !core.close_started {
                core.close_started = true;
                let now = shared.clock.now();
                core.session.close(now);
                core.dispatch();
            }
            if core.driver_wake.is_some() {
                core.wake_driver(shared);
            }
        }
        let mut gave_up = false;
        let result = loop {
            let port = {
                let mut core = shared.core();
                if let Some(r) = core.closed.take() {
                    break r;
                }
                if shared.clock.now() >= give_up {
                    gave_up = true;
                    break Err(S::Error::close_timed_out(bound));
                }
                let port = core.port.take();
                if port.is_none() {
                    core.port_waiters.push(me.clone());
                }
                port
            };
            match port {
                Some(port) => shared.drive(port, &me, Some(give_up), None, &|core, _| core.closed.is_some()),
                None => {
                    me.wait_until(Some(give_up));
                }
            }
        };
        {
            let mut core = shared.core();
            core.stop_thread = true;
            // A result kept for later is no use once the session is closed.
            core.closed = Some(Ok(()));
            // An operation without an outcome gets none from the session now: its caller (a future, which
            // may outlive the driver) is told so rather than left waiting for ever; after a close that gave
            // up, with the close's error (what was started may not be stopped).
            for slot in core.ops.values_mut().filter(|slot| slot.result.is_none()) {
                let e = if gave_up { S::Error::close_timed_out(bound) } else { S::Error::session_closed() };
                slot.result = Some(Err(e));
                slot.waiter.wake();
            }
        }
        self.open = false;
        shared.background.raise();
        let thread = std::mem::replace(&mut *lock(&shared.thread), Background::Done);
        if let Background::Running(t) = thread {
            let join_by = shared.clock.now() + BACKGROUND_EXIT_GRACE;
            let exited = || shared.exited_flag.load(std::sync::atomic::Ordering::SeqCst);
            while !exited() && shared.clock.now() < join_by {
                shared.exited.wait_until(Some(join_by));
            }
            if exited() {
                let _ = t.join();
            } else {
                // Stuck in a call of its link (it ends when the call returns: stop_thread is set).
                tracing::info!(
                    "{}: the driver's background thread did not end within {BACKGROUND_EXIT_GRACE:?} of the close; \
                     left to end by itself",
                    self.describe
                );
            }
        }
        result
    }
}

impl<S: Session> Drop for Driver<S> {
    fn drop(&mut self) {
        if self.open {
            if let Err(e) = self.close_inner() {
                tracing::warn!("{}: dropped without close(): {e}", self.describe);
            }
        }
    }
}
