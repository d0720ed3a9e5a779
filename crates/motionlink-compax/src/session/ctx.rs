//! What an operation of the session uses: the exchanges on this family's line and the waits that listen
//! to it, on top of what every family's operations have ([`motionlink_link::exec::Ctx`]: the session's
//! time, waits on it, progress reports, its cancellation). Each awaits what the session's engine
//! ([`Core`]) hands over when it has it; nothing here does I/O or reads a clock.

use std::ops::Deref;
use std::task::Poll;

use motionlink_link::exec;

use super::core::{Core, Job, JobResult, Retry};
use super::types::Progress;
use crate::error::{Error, Result};
use crate::wire::Request;
use motionlink_link::Timestamp;

/// One operation's handle on the session.
#[derive(Clone)]
pub(crate) struct Ctx {
    inner: exec::Ctx<Core, Progress>,
    /// Its telegrams go before the other operations' (the stop sequence).
    urgent: bool,
}

impl Deref for Ctx {
    type Target = exec::Ctx<Core, Progress>;
    fn deref(&self) -> &Self::Target {
        &self.inner
    }
}

impl Ctx {
    pub(crate) fn new(inner: exec::Ctx<Core, Progress>) -> Self {
        Ctx { inner, urgent: false }
    }

    /// The same operation, its telegrams sent before the others' (for stopping axes).
    pub(crate) fn urgent(&self) -> Ctx {
        Ctx { urgent: true, ..self.clone() }
    }

    /// True once the operation is cancelled.
    pub(crate) fn is_cancelled(&self) -> bool {
        self.cancelled()
    }

    /// [`Error::CancelledBeforeMotion`] once the operation is cancelled.
    pub(crate) fn check_cancel(&self) -> Result<()> {
        if self.is_cancelled() {
            Err(Error::CancelledBeforeMotion)
        } else {
            Ok(())
        }
    }

    /// Sends `req` and waits for its reply (`None` when none is due), with the session's retries.
    pub(crate) async fn exchange(&self, req: &Request<'_>, retry: Retry) -> JobResult {
        let retries = self.core().cfg.retries;
        self.exchange_retries(req, retry, retries).await
    }

    /// Sends `req` and waits for its reply, sent again at most `retries` times.
    pub(crate) async fn exchange_retries(&self, req: &Request<'_>, retry: Retry, retries: u32) -> JobResult {
        // Once the operation is cancelled only a stop's telegrams (urgent) are sent again when unanswered.
        let retries = if self.is_cancelled() && !self.urgent { 0 } else { retries };
        let ticket = {
            let mut core = self.core();
            let mut job = Job::new(self.id(), req, &core.cfg, retry)?;
            job.retries = retries;
            job.urgent = self.urgent;
            core.submit(job)
        };
        self.job(ticket, |core: &mut Core| &mut core.jobs).await
    }

    /// Waits until `until` while listening for the drives' messages; ends early with
    /// [`Error::CancelledBeforeMotion`] once the operation is cancelled, or with the line's failure.
    pub(crate) async fn listen_until(&self, until: Timestamp) -> Result<()> {
        self.poll_core(|op, cx| {
            let id = op.id();
            let failure = op.line_failures.remove(&id);
            if op.now() >= until || op.cancelled() || failure.is_some() {
                op.clear_wake();
                op.listeners.remove(&id);
                return Poll::Ready(failure.map_or(Ok(()), |e| Err(Error::Link(e))));
            }
            op.wake_at(until);
            op.listeners.insert(id, cx.waker().clone());
            Poll::Pending
        })
        .await?;
        self.check_cancel()
    }
}
