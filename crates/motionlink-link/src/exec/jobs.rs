//! The mailbox through which a family core hands the result of what it did for an operation (an exchange,
//! a broadcast, the next poll of a motion) to the operation that awaits it.

use std::collections::BTreeMap;
use std::task::{Context, Poll, Waker};

use crate::session::OpId;

/// A job's handle: its result is kept under it until its operation takes it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Ticket(u64);

enum State<R> {
    /// Not done yet; the waker of the operation once it has polled.
    Waiting(Option<Waker>),
    Done(R),
}

/// One open ticket: the operation it is for, and its result once the core hands it over.
struct Ticketed<R> {
    op: OpId,
    state: State<R>,
}

/// Jobs a core does for operations, each with a result of type `R`: an operation opens a ticket
/// ([`Jobs::open`]) and awaits it ([`super::Ctx::job`]); the core hands the result over with
/// [`Jobs::finish`], which wakes the operation.
///
/// ```
/// use motionlink_link::exec::Jobs;
/// use motionlink_link::session::OpId;
/// let mut jobs: Jobs<&str> = Jobs::default();
/// let t = jobs.open(OpId(1));
/// assert_eq!(jobs.owner(t), Some(OpId(1)));
/// assert!(jobs.finish(t, "answer"));
/// jobs.forget(OpId(1));
/// assert!(!jobs.finish(t, "nobody waits for this"));
/// ```
pub struct Jobs<R> {
    next: u64,
    slots: BTreeMap<Ticket, Ticketed<R>>,
}

impl<R> Default for Jobs<R> {
    fn default() -> Self {
        Jobs { next: 0, slots: BTreeMap::new() }
    }
}

impl<R> std::fmt::Debug for Jobs<R> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Jobs").field("open", &self.slots.len()).finish()
    }
}

impl<R> Jobs<R> {
    /// A new job of operation `op`.
    pub fn open(&mut self, op: OpId) -> Ticket {
        self.next += 1;
        let ticket = Ticket(self.next);
        self.slots.insert(ticket, Ticketed { op, state: State::Waiting(None) });
        ticket
    }

    /// The operation that awaits job `ticket`, while one does.
    pub fn owner(&self, ticket: Ticket) -> Option<OpId> {
        self.slots.get(&ticket).map(|s| s.op)
    }

    /// Hands over the result of job `ticket` and wakes its operation. False (and the result dropped) if no
    /// operation awaits it any more (it ended, or its job was forgotten), or it already has its result.
    pub fn finish(&mut self, ticket: Ticket, result: R) -> bool {
        let Some(slot) = self.slots.get_mut(&ticket) else { return false };
        let State::Waiting(waker) = std::mem::replace(&mut slot.state, State::Done(result)) else {
            tracing::debug!("job {ticket:?} finished twice: the second result dropped");
            return false;
        };
        if let Some(w) = waker {
            w.wake();
        }
        true
    }

    /// The result of job `ticket` once it is there (the job is then closed); until then the operation's
    /// waker is kept for [`Jobs::finish`]. A ticket that is not open never gets a result.
    pub fn poll_result(&mut self, ticket: Ticket, cx: &mut Context<'_>) -> Poll<R> {
        let Some(slot) = self.slots.get_mut(&ticket) else {
            tracing::error!("job {ticket:?} awaited but not open");
            return Poll::Pending;
        };
        match &mut slot.state {
            State::Waiting(waker) => {
                if !waker.as_ref().is_some_and(|w| w.will_wake(cx.waker())) {
                    *waker = Some(cx.waker().clone());
                }
                Poll::Pending
            }
            State::Done(_) => match self.slots.remove(&ticket).map(|s| s.state) {
                Some(State::Done(r)) => Poll::Ready(r),
                _ => Poll::Pending,
            },
        }
    }

    /// Closes job `ticket` (its result, if one comes, is dropped).
    pub fn close(&mut self, ticket: Ticket) {
        self.slots.remove(&ticket);
    }

    /// Closes every job of operation `op` (it ended, or gave up waiting).
    pub fn forget(&mut self, op: OpId) {
        self.slots.retain(|_, s| s.op != op);
    }

    /// True when no job is open.
    pub fn is_empty(&self) -> bool {
        self.slots.is_empty()
    }
}
