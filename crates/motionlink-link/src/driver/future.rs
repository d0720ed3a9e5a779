//! The async side of a driver: [`OpFuture`], and [`AsyncDriver`] for tokio.

use std::future::Future;
use std::pin::Pin;
use std::sync::Arc;
use std::task::{Context, Poll};

#[cfg(feature = "tokio")]
use super::Driver;
use super::{Shared, Waiter};
#[cfg(feature = "tokio")]
use crate::link::LinkError;
use crate::session::{OpId, Session, SessionError};

/// The result of an operation started by [`Driver::start`](super::Driver::start), for async callers. Runtime-agnostic: the
/// driver's thread does the I/O and wakes the task.
pub struct OpFuture<S: Session> {
    pub(super) shared: Option<Arc<Shared<S>>>,
    pub(super) id: OpId,
    pub(super) early: Option<S::Error>,
}

impl<S: Session> OpFuture<S> {
    /// The operation's id.
    pub fn id(&self) -> OpId {
        self.id
    }

    /// The latest progress report not yet taken, if any (the earlier ones not taken are dropped: an async
    /// caller looks at where the operation is now).
    pub fn take_progress(&self) -> Option<S::Progress> {
        let shared = self.shared.as_ref()?;
        shared.core().ops.get_mut(&self.id).and_then(|s| s.progress.drain(..).last())
    }

    /// Cancels the operation (it stops what it started and ends with a cancelled error, or with its result
    /// if it had already ended); the future still ends with that outcome.
    pub fn cancel(&self) {
        if let Some(shared) = &self.shared {
            let mut core = shared.core();
            let now = shared.clock.now();
            core.session.cancel(self.id, now);
            core.dispatch();
            core.wake_driver(shared);
        }
    }
}

// Nothing in an OpFuture is pinned: its fields are moved freely.
impl<S: Session> Unpin for OpFuture<S> {}

impl<S: Session> Future for OpFuture<S> {
    type Output = Result<S::Output, S::Error>;

    fn poll(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<Self::Output> {
        if let Some(e) = self.early.take() {
            return Poll::Ready(Err(e));
        }
        let id = self.id;
        let Some(shared) = self.shared.clone() else {
            return Poll::Ready(Err(S::Error::session_closed()));
        };
        let mut core = shared.core();
        let Some(slot) = core.ops.get_mut(&id) else {
            drop(core);
            self.shared = None;
            return Poll::Ready(Err(S::Error::session_closed()));
        };
        if let Some(r) = slot.result.take() {
            core.ops.remove(&id);
            drop(core);
            self.shared = None;
            return Poll::Ready(r);
        }
        slot.waiter = Waiter::Waker(Some(cx.waker().clone()));
        Poll::Pending
    }
}

impl<S: Session> Drop for OpFuture<S> {
    fn drop(&mut self) {
        let Some(shared) = self.shared.take() else { return };
        let mut core = shared.core();
        let finished = core.ops.get(&self.id).is_none_or(|s| s.result.is_some());
        if finished {
            core.ops.remove(&self.id);
            return;
        }
        if let Some(slot) = core.ops.get_mut(&self.id) {
            slot.abandoned = true;
        }
        let now = shared.clock.now();
        core.session.cancel(self.id, now);
        core.dispatch();
        core.wake_driver(&shared);
    }
}

/// A [`Driver`] for async code (tokio): operations are futures ([`OpFuture`]); opening and closing, which
/// block on I/O, run on tokio's blocking pool. Dropping it closes the session there as well (stopping
/// everything it started, bounded by [`DriverConfig::close_bound`](super::DriverConfig::close_bound)).
#[cfg(feature = "tokio")]
pub struct AsyncDriver<S: Session> {
    driver: Option<Driver<S>>,
}

#[cfg(feature = "tokio")]
impl<S: Session> std::fmt::Debug for AsyncDriver<S> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("AsyncDriver").field("driver", &self.driver).finish()
    }
}

#[cfg(feature = "tokio")]
impl<S: Session> AsyncDriver<S> {
    /// Runs `open` (which opens the port and makes the driver: blocking work) on tokio's blocking pool.
    pub async fn open<E>(open: impl FnOnce() -> Result<Driver<S>, E> + Send + 'static) -> Result<Self, E>
    where
        E: From<LinkError> + Send + 'static,
    {
        match tokio::task::spawn_blocking(open).await {
            Ok(r) => r.map(|driver| AsyncDriver { driver: Some(driver) }),
            Err(e) => {
                Err(E::from(LinkError::Open { port: "?".into(), reason: format!("the opening task failed: {e}") }))
            }
        }
    }

    /// Wraps a driver made already.
    pub fn from_driver(driver: Driver<S>) -> Self {
        AsyncDriver { driver: Some(driver) }
    }

    /// The blocking driver underneath (for [`Driver::with_session`] and the like).
    pub fn driver(&self) -> &Driver<S> {
        self.driver.as_ref().expect("only close() takes the driver, and it consumes self")
    }

    /// Starts `op`; see [`Driver::start`].
    pub fn start(&self, op: S::Op) -> OpFuture<S> {
        self.driver().start(op)
    }

    /// Runs `op` to its end.
    pub async fn run(&self, op: S::Op) -> Result<S::Output, S::Error> {
        self.start(op).await
    }

    /// Closes the session on tokio's blocking pool; see [`Driver::close`].
    pub async fn close(mut self) -> Result<(), S::Error> {
        let driver = self.driver.take().expect("close consumes self");
        match tokio::task::spawn_blocking(move || driver.close()).await {
            Ok(r) => r,
            Err(e) => Err(S::Error::from(LinkError::Io {
                port: "?".into(),
                source: std::sync::Arc::new(std::io::Error::other(format!("the closing task failed: {e}"))),
            })),
        }
    }
}

#[cfg(feature = "tokio")]
impl<S: Session> Drop for AsyncDriver<S> {
    fn drop(&mut self) {
        let Some(driver) = self.driver.take() else { return };
        match tokio::runtime::Handle::try_current() {
            // Do not block a runtime thread: the close runs on the blocking pool (still bounded in time).
            Ok(handle) => {
                handle.spawn_blocking(move || drop(driver));
            }
            Err(_) => drop(driver),
        }
    }
}
