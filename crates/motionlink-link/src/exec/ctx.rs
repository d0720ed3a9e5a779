//! What an operation holds of its session: the core, the session's time, its cancel flag, its progress
//! reports, and the waits built on them.

use std::future::Future;
use std::ops::{Deref, DerefMut};
use std::sync::Arc;
use std::task::{Context, Poll};

use super::cell::{Locked, SharedCell};
use super::{Jobs, Shared, Ticket};
use crate::clock::Timestamp;
use crate::session::OpId;

/// One operation's handle on its session (see the [module documentation](super)). Cloning it gives another
/// handle of the same operation.
pub struct Ctx<C, P> {
    shared: Arc<SharedCell<Shared<C, P>>>,
    id: OpId,
}

impl<C, P> Clone for Ctx<C, P> {
    fn clone(&self) -> Self {
        Ctx { shared: Arc::clone(&self.shared), id: self.id }
    }
}

impl<C, P> std::fmt::Debug for Ctx<C, P> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_tuple("Ctx").field(&self.id).finish()
    }
}

impl<C, P> Ctx<C, P> {
    pub(super) fn new(shared: Arc<SharedCell<Shared<C, P>>>, id: OpId) -> Self {
        Ctx { shared, id }
    }

    /// The operation's id.
    pub fn id(&self) -> OpId {
        self.id
    }

    /// The core, locked for the span of a call (the guard cannot be held across an `await`).
    pub fn core(&self) -> OpGuard<'_, C, P> {
        OpGuard { shared: self.shared.lock(), id: self.id }
    }

    /// The session's time.
    pub fn now(&self) -> Timestamp {
        self.shared.lock().now
    }

    /// True once the operation was asked to end early.
    pub fn cancelled(&self) -> bool {
        self.shared.lock().cancelled.contains(&self.id)
    }

    /// Reports progress (handed out before the operation's end).
    pub fn progress(&self, p: P) {
        self.shared.lock().progress.push_back((self.id, p));
    }

    /// A future that calls `f` with the core (locked) and the task context each time the operation is
    /// polled, until `f` gives a result. `f` says what wakes the operation again: a waker left with the
    /// core (as [`Jobs`] does), or a time ([`OpGuard::wake_at`]).
    pub fn poll_core<'a, R>(
        &'a self,
        mut f: impl FnMut(&mut OpGuard<'_, C, P>, &mut Context<'_>) -> Poll<R> + 'a,
    ) -> impl Future<Output = R> + 'a {
        std::future::poll_fn(move |cx| f(&mut self.core(), cx))
    }

    /// Waits for the result of job `ticket` of the core's mailbox that `jobs` picks.
    pub fn job<'a, R: 'a>(&'a self, ticket: Ticket, jobs: fn(&mut C) -> &mut Jobs<R>) -> impl Future<Output = R> + 'a {
        self.poll_core(move |core, cx| jobs(core).poll_result(ticket, cx))
    }

    /// Waits until `until` on the session's time (a cancel does not end the wait).
    pub async fn sleep_until(&self, until: Timestamp) {
        self.sleep(until, false).await;
    }

    /// Waits until `until` on the session's time, or until the operation is cancelled (at once if it is).
    /// True if the cancel ended the wait.
    pub async fn sleep_until_cancelled(&self, until: Timestamp) -> bool {
        self.sleep(until, true).await
    }

    async fn sleep(&self, until: Timestamp, interruptible: bool) -> bool {
        self.poll_core(move |op, _| {
            let cancelled = interruptible && op.cancelled();
            if op.now() >= until || cancelled {
                op.clear_wake();
                Poll::Ready(cancelled)
            } else {
                op.wake_at(until);
                Poll::Pending
            }
        })
        .await
    }
}

/// The core as an operation sees it, locked: dereferences to the core, and says what the executor knows of
/// the operation.
pub struct OpGuard<'a, C, P> {
    shared: Locked<'a, Shared<C, P>>,
    id: OpId,
}

impl<C, P> OpGuard<'_, C, P> {
    /// The operation's id.
    pub fn id(&self) -> OpId {
        self.id
    }

    /// The session's time.
    pub fn now(&self) -> Timestamp {
        self.shared.now
    }

    /// True once the operation was asked to end early.
    pub fn cancelled(&self) -> bool {
        self.shared.cancelled.contains(&self.id)
    }

    /// Polls the operation again when the session's time reaches `at` (replacing an earlier time).
    pub fn wake_at(&mut self, at: Timestamp) {
        let id = self.id;
        self.shared.timers.insert(id, at);
    }

    /// Forgets the time [`OpGuard::wake_at`] set.
    pub fn clear_wake(&mut self) {
        let id = self.id;
        self.shared.timers.remove(&id);
    }

    /// Reports progress.
    pub fn progress(&mut self, p: P) {
        let id = self.id;
        self.shared.progress.push_back((id, p));
    }
}

impl<C, P> Deref for OpGuard<'_, C, P> {
    type Target = C;
    fn deref(&self) -> &C {
        &self.shared.core
    }
}

impl<C, P> DerefMut for OpGuard<'_, C, P> {
    fn deref_mut(&mut self) -> &mut C {
        &mut self.shared.core
    }
}

/// The core as the session sees it between operations, locked: dereferences to the core.
pub struct CoreGuard<'a, C, P> {
    shared: Locked<'a, Shared<C, P>>,
}

impl<'a, C, P> CoreGuard<'a, C, P> {
    pub(super) fn new(shared: Locked<'a, Shared<C, P>>) -> Self {
        CoreGuard { shared }
    }

    /// The session's time.
    pub fn now(&self) -> Timestamp {
        self.shared.now
    }
}

impl<C, P> Deref for CoreGuard<'_, C, P> {
    type Target = C;
    fn deref(&self) -> &C {
        &self.shared.core
    }
}

impl<C, P> DerefMut for CoreGuard<'_, C, P> {
    fn deref_mut(&mut self) -> &mut C {
        &mut self.shared.core
    }
}

/// A handle on a session's core that outlives the session ([`super::Executor::handle`]).
pub struct CoreHandle<C, P> {
    shared: Arc<SharedCell<Shared<C, P>>>,
}

impl<C, P> Clone for CoreHandle<C, P> {
    fn clone(&self) -> Self {
        CoreHandle { shared: Arc::clone(&self.shared) }
    }
}

impl<C, P> CoreHandle<C, P> {
    pub(super) fn new(shared: Arc<SharedCell<Shared<C, P>>>) -> Self {
        CoreHandle { shared }
    }

    /// The core, locked.
    pub fn core(&self) -> CoreGuard<'_, C, P> {
        CoreGuard::new(self.shared.lock())
    }
}
