//! What an operation of the session uses: exchanges on the line, waits on the session's time, progress
//! reports, its cancellation. Each awaits what the session's engine ([`Core`]) hands over when it has it;
//! nothing here does I/O or reads a clock.

use std::future::Future;
use std::pin::Pin;
use std::sync::{Arc, Mutex, MutexGuard};
use std::task::{Context, Poll};

use motionlink_link::clock::lock;
use motionlink_link::session::OpId;
use motionlink_link::Timestamp;

use super::core::{Core, Job, JobResult, Retry};
use super::types::Progress;
use crate::error::{Error, Result};
use crate::wire::Request;

/// One operation's handle on the session.
#[derive(Clone)]
pub(crate) struct Ctx {
    core: Arc<Mutex<Core>>,
    op: OpId,
    /// Its telegrams go before the other operations' (the stop sequence).
    urgent: bool,
}

/// Waits for the outcome of job `ticket`.
struct JobWait<'a> {
    ctx: &'a Ctx,
    ticket: u64,
}

impl Future for JobWait<'_> {
    type Output = JobResult;
    fn poll(self: Pin<&mut Self>, _: &mut Context<'_>) -> Poll<JobResult> {
        match self.ctx.core().take_result(self.ticket) {
            Some(r) => Poll::Ready(r),
            None => Poll::Pending,
        }
    }
}

/// Waits until the session's time reaches `until`, the operation is cancelled, or (when it listens) the
/// line fails.
struct Sleep<'a> {
    ctx: &'a Ctx,
    until: Timestamp,
    listen: bool,
}

impl Future for Sleep<'_> {
    type Output = Result<()>;
    fn poll(self: Pin<&mut Self>, _: &mut Context<'_>) -> Poll<Result<()>> {
        let mut core = self.ctx.core();
        let op = self.ctx.op;
        let failure = core.line_failures.remove(&op);
        if core.now >= self.until || core.cancelled.contains(&op) || failure.is_some() {
            core.sleepers.remove(&op);
            core.listeners.remove(&op);
            return Poll::Ready(failure.map_or(Ok(()), |e| Err(Error::Link(e))));
        }
        core.sleepers.insert(op, self.until);
        if self.listen {
            core.listeners.insert(op);
        }
        Poll::Pending
    }
}

impl Ctx {
    pub(crate) fn new(core: Arc<Mutex<Core>>, op: OpId) -> Self {
        Ctx { core, op, urgent: false }
    }

    /// The same operation, its telegrams sent before the others' (for stopping axes).
    pub(crate) fn urgent(&self) -> Ctx {
        Ctx { urgent: true, ..self.clone() }
    }

    /// The session's state.
    pub(crate) fn core(&self) -> MutexGuard<'_, Core> {
        lock(&self.core)
    }

    /// The session's time.
    pub(crate) fn now(&self) -> Timestamp {
        self.core().now
    }

    /// True once the operation is cancelled.
    pub(crate) fn is_cancelled(&self) -> bool {
        self.core().cancelled.contains(&self.op)
    }

    /// [`Error::Cancelled`] once the operation is cancelled.
    pub(crate) fn check_cancel(&self) -> Result<()> {
        if self.is_cancelled() {
            Err(Error::Cancelled)
        } else {
            Ok(())
        }
    }

    /// Reports progress.
    pub(crate) fn progress(&self, p: Progress) {
        let op = self.op;
        self.core().progress.push_back((op, p));
    }

    /// Sends `req` and waits for its reply (`None` when none is due), with the session's retries.
    pub(crate) async fn exchange(&self, req: &Request<'_>, retry: Retry) -> JobResult {
        let retries = self.core().cfg.retries;
        self.exchange_retries(req, retry, retries).await
    }

    /// Sends `req` and waits for its reply, sent again at most `retries` times.
    pub(crate) async fn exchange_retries(&self, req: &Request<'_>, retry: Retry, retries: u32) -> JobResult {
        let ticket = {
            let mut core = self.core();
            let mut job = Job::new(self.op, req, &core.cfg, retry)?;
            job.retries = retries;
            job.urgent = self.urgent;
            core.submit(job)
        };
        JobWait { ctx: self, ticket }.await
    }

    /// Waits until `until` while listening for the drives' messages; ends early with
    /// [`Error::Cancelled`] once the operation is cancelled, or with the line's failure.
    pub(crate) async fn listen_until(&self, until: Timestamp) -> Result<()> {
        Sleep { ctx: self, until, listen: true }.await?;
        self.check_cancel()
    }
}
