//! What an operation of the session uses to talk to the modules: exchanges, broadcasts, waits on the
//! session's time, progress reports, its cancellation. Each awaits a result the session's engine hands over
//! when it has it; nothing here does I/O or reads a clock.

use std::future::Future;
use std::pin::Pin;
use std::sync::{Arc, Mutex, MutexGuard};
use std::task::{Context, Poll};
use std::time::Duration;

use motionlink_link::clock::lock;
use motionlink_link::session::OpId;
use motionlink_link::Timestamp;

use super::core::{Core, JobResult, Ticket};
use super::Progress;
use crate::error::Error;
use crate::model::{Broadcast, Reply, Request};

/// One operation's handle on the session.
#[derive(Clone)]
pub(crate) struct Ctx {
    core: Arc<Mutex<Core>>,
    op: OpId,
}

/// Waits for the result of job `ticket`.
struct Job<'a> {
    ctx: &'a Ctx,
    ticket: Ticket,
}

impl Future for Job<'_> {
    type Output = JobResult;
    fn poll(self: Pin<&mut Self>, _: &mut Context<'_>) -> Poll<JobResult> {
        match self.ctx.core().take_result(self.ticket) {
            Some(r) => Poll::Ready(r),
            None => Poll::Pending,
        }
    }
}

/// Waits until the session's time reaches `until` (or, if `interruptible`, the operation is cancelled).
struct Sleep<'a> {
    ctx: &'a Ctx,
    until: Timestamp,
    interruptible: bool,
}

impl Future for Sleep<'_> {
    type Output = ();
    fn poll(self: Pin<&mut Self>, _: &mut Context<'_>) -> Poll<()> {
        let mut core = self.ctx.core();
        let op = self.ctx.op;
        if core.now >= self.until || (self.interruptible && core.cancelled.contains(&op)) {
            core.sleepers.remove(&op);
            return Poll::Ready(());
        }
        core.sleepers.insert(op, self.until);
        Poll::Pending
    }
}

impl Ctx {
    pub fn new(core: Arc<Mutex<Core>>, op: OpId) -> Ctx {
        Ctx { core, op }
    }

    /// The shared state (never held across an await).
    pub fn core(&self) -> MutexGuard<'_, Core> {
        lock(&self.core)
    }

    /// The session's time.
    pub fn now(&self) -> Timestamp {
        self.core().now
    }

    /// True once the operation was asked to end early.
    pub fn cancelled(&self) -> bool {
        self.core().cancelled.contains(&self.op)
    }

    /// Reports progress.
    pub fn progress(&self, p: Progress) {
        let op = self.op;
        self.core().progress.push_back((op, p));
    }

    /// Sends every request of `batch` and collects the acknowledges in any order until all came or
    /// `timeout` passed; one result per request, in order. No retries here.
    pub async fn exchange(&self, batch: Vec<(u8, Request)>, timeout: Duration) -> Vec<Result<Reply, Error>> {
        let ticket = self.core().enqueue_exchange(self.op, batch, timeout);
        match (Job { ctx: self, ticket }).await {
            JobResult::Exchange(r) => r,
            JobResult::Broadcast(_) => unreachable_result(),
        }
    }

    /// Sends a broadcast (never acknowledged); fails only if the line does.
    pub async fn send_broadcast(&self, broadcast: Broadcast) -> Result<(), Error> {
        let ticket = self.core().enqueue_broadcast(self.op, broadcast);
        match (Job { ctx: self, ticket }).await {
            JobResult::Broadcast(r) => r,
            JobResult::Exchange(_) => Err(Error::Unsupported("a broadcast was answered".into())),
        }
    }

    /// Waits until `until` on the session's time.
    pub async fn sleep_until(&self, until: Timestamp) {
        Sleep { ctx: self, until, interruptible: false }.await
    }

    /// Waits until `until` on the session's time, or until the operation is cancelled.
    pub async fn sleep_until_cancelled(&self, until: Timestamp) {
        Sleep { ctx: self, until, interruptible: true }.await
    }
}

/// An exchange's job gives an exchange's result: the engine never mixes them up. Should it ever, the
/// operation sees no answers (each request timed out) rather than a panic.
fn unreachable_result() -> Vec<Result<Reply, Error>> {
    tracing::error!("an exchange got a broadcast's result");
    Vec::new()
}
