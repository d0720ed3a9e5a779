//! How a native session ends, written once for every family: [`faces!`] gives both faces of a family's
//! native client `is_open`, `started` and `close` (async: `close_blocking`) from these, and ends a client
//! its owner dropped unclosed. A family says only what its clients stop ([`Session`], [`AsyncSession`]);
//! what is stopped is named by its ids, as `started()` names it: SCU motion function numbers (1..10),
//! PowerCube module addresses, COMPAX drive addresses.

use std::future::Future;
use std::sync::Arc;
use std::time::Duration;

use motionlink_link::cancel::CancelToken;
use pyo3::prelude::*;

use crate::common::Slot;
use crate::errors::{to_pyerr, Failure};
use crate::wait::{block_on_runtime, runtime};

/// A family's blocking client as a session that ends.
pub trait Session: Send + Sync + Sized + 'static {
    /// The ids of what the session set in motion and has not seen stop.
    fn started_ids(&self) -> Vec<u8>;
    /// Ends the session (the family's `close`): the ids of what it stopped.
    fn end(self) -> Result<Vec<u8>, Failure>;
    /// Stops what the session set in motion while a call of another thread still holds it (that call was
    /// cancelled, and the session ends when it returns): the ids of what is being stopped.
    fn end_shared(shared: Arc<Self>) -> Result<Vec<u8>, Failure>;
}

/// A family's async client as a session that ends ([`Session`]'s methods as futures).
pub trait AsyncSession: Send + Sync + Sized + 'static {
    /// The ids of what the session set in motion and has not seen stop.
    fn started_ids(&self) -> Vec<u8>;
    /// Ends the session: the ids of what it stopped.
    fn end(self) -> impl Future<Output = Result<Vec<u8>, Failure>> + Send;
    /// Stops what the session set in motion while a call still holds it: the ids.
    fn end_shared(shared: Arc<Self>) -> impl Future<Output = Result<Vec<u8>, Failure>> + Send;
}

/// The blocking face's `close()`: calls of other threads are cancelled and waited for (at most `bound`),
/// then the session ends without the GIL; the ids of what it stopped, those a cancelled call stopped
/// included (none when closed already).
pub fn close<C: Session>(py: Python<'_>, slot: &Slot<C>, token: &CancelToken, bound: Duration) -> PyResult<Vec<u8>> {
    let ended = py.detach(|| {
        let before = slot.get().map(|c| c.started_ids()).unwrap_or_default();
        let ended = match slot.take(token, bound) {
            None => Ok(Vec::new()),
            Some(Ok(client)) => client.end(),
            Some(Err(shared)) => C::end_shared(shared),
        };
        ended.map(|ids| and(before, ids))
    });
    ended.map_err(|f| to_pyerr(py, f))
}

/// What was in motion when the close began (a call it cancelled stopped it), then what the end stopped.
fn and(mut before: Vec<u8>, ended: Vec<u8>) -> Vec<u8> {
    for id in ended {
        if !before.contains(&id) {
            before.push(id);
        }
    }
    before
}

/// The async face's `close_blocking()` (`aclose` runs it on a worker thread, the exit handler directly):
/// the session ends on the runtime while this thread waits without the GIL. The Python side has cancelled
/// the client's calls and waited for their ends; a call that still holds the client (none should) is
/// waited for as the blocking close waits (at most the library's default close bound), so that the
/// session's own close runs, which ends every operation of it.
pub fn close_async_blocking<C: AsyncSession>(py: Python<'_>, slot: &Slot<C>) -> PyResult<Vec<u8>> {
    let bound = motionlink_link::driver::DriverConfig::default().close_bound;
    let ended = match py.detach(|| slot.take(&CancelToken::new(), bound)) {
        None => Ok(Vec::new()),
        Some(Ok(client)) => block_on_runtime(py, client.end())?,
        Some(Err(shared)) => block_on_runtime(py, C::end_shared(shared))?,
    };
    ended.map_err(|f| to_pyerr(py, f))
}

/// A blocking client its owner did not close (garbage-collected): the session ends here, stopping what
/// it started as the family's client does when dropped, without holding the GIL while it waits.
pub fn drop_unclosed<C: Send + Sync>(slot: &Slot<C>, token: &CancelToken, bound: Duration) {
    if let Some(taken) = slot.take(token, bound) {
        Python::attach(|py| py.detach(move || drop(taken)));
    }
}

/// An async client dropped unclosed (the Python side holds each until its close has ended, so only one it
/// never held): the session ends on the runtime (stopping what it started), not on the thread that happens
/// to drop the object (which may hold the GIL); nothing waits for that end.
pub fn drop_unclosed_async<C: Send + Sync + 'static>(slot: &Slot<C>) {
    if let Some(taken) = slot.take(&CancelToken::new(), Duration::ZERO) {
        runtime().spawn(async move { drop(taken) });
    }
}
