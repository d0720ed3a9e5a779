//! What an operation of the session uses to talk to the modules: the exchanges and broadcasts of this
//! family, on top of what every family's operations have ([`motionlink_link::exec::Ctx`]: the session's
//! time, waits on it, progress reports, its cancellation). Each awaits a result the session's engine hands
//! over when it has it; nothing here does I/O or reads a clock.

use std::ops::Deref;
use std::time::Duration;

use motionlink_link::exec;

use super::core::{Core, JobResult};
use super::Progress;
use crate::error::Error;
use crate::model::Broadcast;
use crate::wire::{Reply, Request};

/// One operation's handle on the session.
#[derive(Clone)]
pub(crate) struct Ctx(pub exec::Ctx<Core, Progress>);

impl Deref for Ctx {
    type Target = exec::Ctx<Core, Progress>;
    fn deref(&self) -> &Self::Target {
        &self.0
    }
}

impl Ctx {
    /// Sends every request of `batch` and collects the acknowledges in any order until all came or
    /// `timeout` passed; one result per request, in order. No retries here.
    pub async fn exchange(&self, batch: Vec<(u8, Request)>, timeout: Duration) -> Vec<Result<Reply, Error>> {
        let ticket = self.core().enqueue_exchange(self.id(), batch, timeout);
        match self.job(ticket, |core: &mut Core| &mut core.jobs).await {
            JobResult::Exchange(r) => r,
            JobResult::Broadcast(_) => unreachable_result(),
        }
    }

    /// Sends a broadcast (never acknowledged); fails only if the line does.
    pub async fn send_broadcast(&self, broadcast: Broadcast) -> Result<(), Error> {
        let ticket = self.core().enqueue_broadcast(self.id(), broadcast);
        match self.job(ticket, |core: &mut Core| &mut core.jobs).await {
            JobResult::Broadcast(r) => r,
            JobResult::Exchange(_) => Err(Error::NotSupported("a broadcast was answered".into())),
        }
    }
}

/// An exchange's job gives an exchange's result: the engine never mixes them up. Should it ever, the
/// operation sees no answers (each request timed out) rather than a panic.
fn unreachable_result() -> Vec<Result<Reply, Error>> {
    tracing::error!("an exchange got a broadcast's result");
    Vec::new()
}
