//! What an operation of the session uses to talk to the unit: its requests (through the line's queue, with
//! room beside the keepalive), the next poll of a motion through the keepalive RC, the port reopened, on
//! top of what every family's operations have ([`motionlink_link::exec::Ctx`]: the session's time, waits on
//! it, progress reports, its cancellation). Each awaits what the session's engine ([`Core`]) hands over
//! when it has it; nothing here does I/O or reads a clock.
//!
//! How a cancel reaches an operation depends on the handle it waits through. A plain handle's request still
//! in the queue is dropped (it ends with [`Error::CancelledBeforeMotion`]), and its pause or its wait for
//! the next poll ends at once. A [`Ctx::firm`] handle's waits are not cut short: what stops a motion is
//! never held back by the cancel it answers. A handle from [`Ctx::ending_on_cancel`] ends each request
//! with a given error once the operation is cancelled (the part of an operation that nothing may follow
//! once its caller gave up).

use std::ops::Deref;
use std::task::Poll;

use motionlink_link::exec;
use motionlink_link::Timestamp;

use super::request::{OwnedReply, PreparedRequest, Req};
use super::{Core, Progress, Snapshot};
use crate::error::Error;
use crate::model::DataIndex;

/// One operation's handle on the session.
#[derive(Clone)]
pub(crate) struct Ctx {
    inner: exec::Ctx<Core, Progress>,
    /// A cancel does not cut its waits short.
    firm: bool,
    /// Each of its requests ends with this error once the operation is cancelled.
    on_cancel: Option<Error>,
}

impl Deref for Ctx {
    type Target = exec::Ctx<Core, Progress>;
    fn deref(&self) -> &Self::Target {
        &self.inner
    }
}

impl Ctx {
    pub(crate) fn new(inner: exec::Ctx<Core, Progress>) -> Self {
        Ctx { inner, firm: false, on_cancel: None }
    }

    /// The same operation, its waits not cut short by a cancel (stopping what it started, ending a session).
    pub(crate) fn firm(&self) -> Ctx {
        Ctx { inner: self.inner.clone(), firm: true, on_cancel: None }
    }

    /// The same operation, each of its requests ending with `error` once it is cancelled (after the request's
    /// answer, or at once if the request was still queued).
    pub(crate) fn ending_on_cancel(&self, error: Error) -> Ctx {
        Ctx { inner: self.inner.clone(), firm: false, on_cancel: Some(error) }
    }

    /// Sends `req` when the line has room for it (or at once, as its schedule says) and waits for its reply,
    /// with what a PE answer leads to (see `pe_guard`). A request the session may not send now fails at once.
    pub(crate) async fn send(&self, req: Req) -> Result<OwnedReply, Error> {
        let admitted = {
            let mut core = self.core();
            let id = self.id();
            core.admit(&req).map(|()| core.enqueue(id, req, !self.firm))
        };
        let result = match admitted {
            Ok(ticket) => self.job(ticket, |core: &mut Core| &mut core.replies).await,
            Err(e) => Err(e),
        };
        match &self.on_cancel {
            Some(e) if self.cancelled() => Err(e.clone()),
            _ => result,
        }
    }

    /// RG of `index` as a caller's request.
    pub(crate) async fn get(&self, index: DataIndex) -> Result<OwnedReply, Error> {
        self.send(Req::op(PreparedRequest::get(index))).await
    }

    /// Waits until `until` on the session's time; a plain handle's wait ends at once when the operation is
    /// cancelled. True if the cancel ended it.
    pub(crate) async fn pause_until(&self, until: Timestamp) -> bool {
        if self.firm {
            self.sleep_until(until).await;
            false
        } else {
            self.sleep_until_cancelled(until).await
        }
    }

    /// The next poll of the running motion: the keepalive RC carries the session's cyclic object meanwhile
    /// (polled every poll interval while anyone waits for it). `None`: a plain handle's operation was
    /// cancelled while it waited.
    pub(crate) async fn snapshot(&self) -> Option<Result<Snapshot, Error>> {
        self.snapshot_within(false).await
    }

    /// As [`Ctx::snapshot`], with the RC that carries it sent as soon as the line is free, not on the poll
    /// interval's grid (a watch asks a round trip before its sample is due).
    pub(crate) async fn snapshot_now(&self) -> Option<Result<Snapshot, Error>> {
        self.snapshot_within(true).await
    }

    async fn snapshot_within(&self, at_once: bool) -> Option<Result<Snapshot, Error>> {
        let ticket = {
            let mut core = self.core();
            if !core.link_up {
                return Some(Err(core.lost_error()));
            }
            let id = self.id();
            let ticket = core.subscribe(id);
            if at_once {
                core.keepalive_due = core.keepalive_due.min(core.now);
            }
            ticket
        };
        let interruptible = !self.firm;
        self.poll_core(move |op, cx| {
            if let Poll::Ready(r) = op.snapshots.poll_result(ticket, cx) {
                return Poll::Ready(Some(r));
            }
            if interruptible && op.cancelled() {
                let id = op.id();
                op.unsubscribe(id);
                return Poll::Ready(None);
            }
            Poll::Pending
        })
        .await
    }

    /// Closes the port and opens it again (the driver does it); the outcome.
    pub(crate) async fn reopen_port(&self) -> Result<(), Error> {
        let ticket = {
            let mut core = self.core();
            let id = self.id();
            core.request_reopen(id)
        };
        self.job(ticket, |core: &mut Core| &mut core.reopens).await
    }
}
