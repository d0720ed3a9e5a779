//! The one executor of every family's session operations.
//!
//! An operation of a session (a read, a checked move, the sequence that closes a session) is written as an
//! `async fn` over a [`Ctx`]: it reads like the manual's routines ("write the target, send the motion
//! command, read the state every 50 ms until the ramp has ended"), and the compiler turns it into the state
//! machine the session resumes. Nothing in an operation does I/O or reads a clock: what it awaits is handed
//! over by the family's engine (its *core*: the line, the requests on it and their answers), or is a time on
//! the session's own clock, which moves only when the driver (or a test) tells the session what time it is.
//!
//! [`Executor`] holds a session's operations and the state they share with the session:
//!
//! - **ids**: each operation is known by its [`OpId`] ([`Executor::next_id`], [`Executor::spawn`]).
//! - **the wake set**: an operation is polled only when it was woken: what it waited for is there (a job of
//!   the core finished: [`Jobs::finish`] wakes the operation that awaits it), its sleep is due, or it was
//!   cancelled. [`Executor::run`] polls the woken ones until none is left.
//! - **sleeping on the session clock**: [`Ctx::sleep_until`], [`Ctx::sleep_until_cancelled`], or any wait
//!   written with [`Ctx::poll_core`] and [`OpGuard::wake_at`]. [`Executor::poll_timeout`] says when the
//!   next sleeper is due; [`Executor::handle_timeout`] wakes the ones whose time has come.
//! - **cancellation**: [`Executor::cancel`] raises the flag an operation reads ([`Ctx::cancelled`]) and
//!   wakes it; what a cancel means beyond that (a request not yet sent dropped, a motion stopped) is the
//!   family's protocol and is written in its operations. [`Executor::abort`] drops an operation at once
//!   (one that sets nothing in motion).
//! - **progress**: [`Ctx::progress`]; [`Executor::run`] hands each report out before the operation's end.
//! - **jobs**: [`Jobs`], a mailbox a family core keeps for what it does on an operation's behalf (an
//!   exchange, a broadcast, the next poll of a motion): the operation opens a ticket and awaits it
//!   ([`Ctx::job`]); the core hands the result over with [`Jobs::finish`] when it has it.
//!
//! The operations and the session share the core behind one lock, taken only for the span of a call (an
//! operation cannot hold it across an `await`: the guard is not `Send`). Each family's session owns its
//! executor and implements [`Session`](crate::session::Session) around it; no family has an executor of its
//! own.
//!
//! ```
//! use motionlink_link::exec::{Ctx, Executor, Jobs, Report, Ticket};
//! use motionlink_link::Timestamp;
//! use std::time::Duration;
//!
//! /// A toy engine: a line on which requests wait for their answers.
//! #[derive(Default)]
//! struct Core {
//!     jobs: Jobs<u32>,
//!     sent: Vec<(Ticket, u32)>,
//! }
//!
//! /// An operation: asks twice, 10 ms apart, and adds the answers.
//! async fn twice(ctx: Ctx<Core, &'static str>, question: u32) -> u32 {
//!     let mut sum = 0;
//!     for _ in 0..2 {
//!         let ticket = {
//!             let mut core = ctx.core();
//!             let t = core.jobs.open(ctx.id());
//!             core.sent.push((t, question));
//!             t
//!         };
//!         sum += ctx.job(ticket, |core: &mut Core| &mut core.jobs).await;
//!         ctx.progress("answered");
//!         ctx.sleep_until(ctx.now() + Duration::from_millis(10)).await;
//!     }
//!     sum
//! }
//!
//! let mut exec: Executor<Core, &'static str, u32> = Executor::new(Core::default(), Timestamp::ZERO);
//! let id = exec.next_id();
//! exec.spawn(id, |ctx| twice(ctx, 20));
//! let mut reports = Vec::new();
//! let mut now = Timestamp::ZERO;
//! loop {
//!     exec.run(|r| reports.push(r));
//!     // The engine answers what was sent (an emulator would, in a test).
//!     let sent: Vec<_> = exec.core().sent.drain(..).collect();
//!     for (ticket, q) in sent {
//!         exec.core().jobs.finish(ticket, q + 1);
//!     }
//!     if exec.is_empty() {
//!         break;
//!     }
//!     if !exec.has_ready() {
//!         now = exec.poll_timeout().expect("the operation sleeps");
//!         exec.handle_timeout(now);
//!     }
//! }
//! assert_eq!(now, Timestamp::from_millis(20));
//! assert!(matches!(reports.last(), Some(Report::Done(done, 42)) if *done == id));
//! assert_eq!(reports.iter().filter(|r| matches!(r, Report::Progress(_, "answered"))).count(), 2);
//! ```

mod cell;
mod ctx;
mod jobs;
#[cfg(test)]
mod tests;

pub use ctx::{CoreGuard, CoreHandle, Ctx, OpGuard};
pub use jobs::{Jobs, Ticket};

use std::collections::{BTreeMap, BTreeSet, VecDeque};
use std::fmt;
use std::future::Future;
use std::pin::Pin;
use std::sync::{Arc, Mutex};
use std::task::{Context, Poll, Wake, Waker};

use self::cell::SharedCell;
use crate::clock::{lock, Timestamp};
use crate::session::{OpId, OpIds};

/// What the operations of a session share with it: the family's core, the session's time, the sleepers,
/// the cancel flags and the progress reports not yet handed out.
pub(crate) struct Shared<C, P> {
    pub(crate) core: C,
    pub(crate) now: Timestamp,
    /// Operations asleep until a time (each waits for one thing at a time).
    pub(crate) timers: BTreeMap<OpId, Timestamp>,
    /// Operations asked to end early.
    pub(crate) cancelled: BTreeSet<OpId>,
    /// Progress reports, oldest first.
    pub(crate) progress: VecDeque<(OpId, P)>,
}

/// The operations to poll: what each waits for is there. Apart from the shared state, because a core
/// wakes an operation while the shared state is locked.
#[derive(Default)]
struct ReadySet(Mutex<BTreeSet<OpId>>);

impl ReadySet {
    fn insert(&self, id: OpId) {
        lock(&self.0).insert(id);
    }

    fn take(&self) -> BTreeSet<OpId> {
        std::mem::take(&mut *lock(&self.0))
    }

    fn is_empty(&self) -> bool {
        lock(&self.0).is_empty()
    }
}

/// The waker of one operation: puts it in the ready set.
struct TaskWaker {
    id: OpId,
    ready: Arc<ReadySet>,
}

impl Wake for TaskWaker {
    fn wake(self: Arc<Self>) {
        self.ready.insert(self.id);
    }

    fn wake_by_ref(self: &Arc<Self>) {
        self.ready.insert(self.id);
    }
}

/// An operation's future.
pub type OpFuture<T> = Pin<Box<dyn Future<Output = T> + Send>>;

struct Task<T> {
    future: OpFuture<T>,
    waker: Waker,
}

/// What [`Executor::run`] hands out.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Report<P, T> {
    /// An operation reported progress.
    Progress(OpId, P),
    /// An operation ended with its output (once per operation; it is gone from the executor then).
    Done(OpId, T),
}

/// The operations of one session and what they share with it; see the [module documentation](self).
///
/// `C` is the family's core (its engine), `P` what operations report on their way, `T` what they end with.
pub struct Executor<C, P, T> {
    shared: Arc<SharedCell<Shared<C, P>>>,
    ready: Arc<ReadySet>,
    tasks: BTreeMap<OpId, Task<T>>,
    ids: OpIds,
}

impl<C, P, T> fmt::Debug for Executor<C, P, T> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Executor").field("operations", &self.tasks.keys().collect::<Vec<_>>()).finish()
    }
}

impl<C, P, T> Executor<C, P, T>
where
    C: Send + 'static,
    P: Send + 'static,
    T: 'static,
{
    /// An executor with no operation, around `core`, its time `now`.
    pub fn new(core: C, now: Timestamp) -> Self {
        let shared =
            Shared { core, now, timers: BTreeMap::new(), cancelled: BTreeSet::new(), progress: VecDeque::new() };
        Executor {
            shared: Arc::new(SharedCell::new(shared)),
            ready: Arc::default(),
            tasks: BTreeMap::new(),
            ids: OpIds::default(),
        }
    }

    /// The next operation id (from 1, increasing).
    pub fn next_id(&mut self) -> OpId {
        self.ids.next_id()
    }

    /// Adds operation `id`, the future `op` makes of its context, and marks it ready: the next
    /// [`Executor::run`] polls it first. An id already running is replaced (its future dropped).
    pub fn spawn<F>(&mut self, id: OpId, op: impl FnOnce(Ctx<C, P>) -> F)
    where
        F: Future<Output = T> + Send + 'static,
    {
        let ctx = Ctx::new(Arc::clone(&self.shared), id);
        let future: OpFuture<T> = Box::pin(op(ctx));
        let waker = Waker::from(Arc::new(TaskWaker { id, ready: Arc::clone(&self.ready) }));
        let old = self.tasks.insert(id, Task { future, waker });
        drop(old);
        self.ready.insert(id);
    }

    /// True while operation `id` runs.
    pub fn contains(&self, id: OpId) -> bool {
        self.tasks.contains_key(&id)
    }

    /// True when no operation runs.
    pub fn is_empty(&self) -> bool {
        self.tasks.is_empty()
    }

    /// How many operations run.
    pub fn len(&self) -> usize {
        self.tasks.len()
    }

    /// The ids of the running operations, in order.
    pub fn ids(&self) -> Vec<OpId> {
        self.tasks.keys().copied().collect()
    }

    /// Asks operation `id` to end early: [`Ctx::cancelled`] is true from now on, and the operation is woken
    /// (an interruptible sleep ends). False if no such operation runs.
    pub fn cancel(&mut self, id: OpId) -> bool {
        if !self.tasks.contains_key(&id) {
            return false;
        }
        self.shared.lock().cancelled.insert(id);
        self.ready.insert(id);
        true
    }

    /// True once operation `id` was cancelled (and while it runs).
    pub fn is_cancelled(&self, id: OpId) -> bool {
        self.shared.lock().cancelled.contains(&id)
    }

    /// Drops operation `id` at once, where it stands (for one that sets nothing in motion). False if no
    /// such operation runs. What the core keeps for it is the family's to forget.
    pub fn abort(&mut self, id: OpId) -> bool {
        let Some(task) = self.tasks.remove(&id) else { return false };
        self.forget(id);
        // Dropped with the shared state unlocked: the future's parts may lock it as they go.
        drop(task);
        true
    }

    fn forget(&self, id: OpId) {
        let mut shared = self.shared.lock();
        shared.timers.remove(&id);
        shared.cancelled.remove(&id);
    }

    /// The core, locked (for the session's own calls between operations; never held while polling).
    pub fn core(&self) -> CoreGuard<'_, C, P> {
        CoreGuard::new(self.shared.lock())
    }

    /// A handle on the core that outlives the executor (a view a caller keeps after the session is gone).
    pub fn handle(&self) -> CoreHandle<C, P> {
        CoreHandle::new(Arc::clone(&self.shared))
    }

    /// The session's time, as last set.
    pub fn now(&self) -> Timestamp {
        self.shared.lock().now
    }

    /// Sets the session's time (every call into a session tells it what time it is).
    pub fn set_now(&self, now: Timestamp) {
        self.shared.lock().now = now;
    }

    /// Sets the session's time and returns the core, locked (one lock for both: what every call into a
    /// session does first).
    pub fn core_at(&self, now: Timestamp) -> CoreGuard<'_, C, P> {
        let mut shared = self.shared.lock();
        shared.now = now;
        CoreGuard::new(shared)
    }

    /// When the next sleeping operation is due, if any sleeps.
    pub fn poll_timeout(&self) -> Option<Timestamp> {
        self.shared.lock().timers.values().min().copied()
    }

    /// Time has reached `now`: every operation whose sleep is due is woken.
    pub fn handle_timeout(&mut self, now: Timestamp) {
        let mut shared = self.shared.lock();
        shared.now = now;
        let due: Vec<OpId> = shared.timers.iter().filter(|(_, t)| **t <= now).map(|(id, _)| *id).collect();
        for id in due {
            shared.timers.remove(&id);
            self.ready.insert(id);
        }
    }

    /// True while an operation was woken and not yet polled.
    pub fn has_ready(&self) -> bool {
        !self.ready.is_empty()
    }

    /// Polls every woken operation, until none is: hands out the progress each reported and, for each that
    /// ended, its output (the operation is gone then).
    pub fn run(&mut self, mut report: impl FnMut(Report<P, T>)) {
        loop {
            let ready = self.ready.take();
            if ready.is_empty() {
                return;
            }
            for id in ready {
                let Some(task) = self.tasks.get_mut(&id) else { continue };
                let mut cx = Context::from_waker(&task.waker);
                let poll = task.future.as_mut().poll(&mut cx);
                let progress = std::mem::take(&mut self.shared.lock().progress);
                for (op, p) in progress {
                    if self.tasks.contains_key(&op) {
                        report(Report::Progress(op, p));
                    }
                }
                if let Poll::Ready(output) = poll {
                    if let Some(task) = self.tasks.remove(&id) {
                        self.forget(id);
                        drop(task);
                    }
                    report(Report::Done(id, output));
                }
            }
        }
    }
}
