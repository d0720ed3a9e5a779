//! The shape every family's protocol logic takes: a sans-IO [`Session`].
//!
//! A session is a state machine. It is told what arrived on the link and what time it is, and it says
//! what to send, when it next needs to be woken, and what happened. It has no thread, no clock of its own,
//! no I/O: request matching, retries of idempotent requests, keepalive and watchdog duties, the sequence
//! that stops what was started, and the check that a move reached its target all live in it, and are
//! tested with a manual clock and no link at all. A driver ([`crate::driver::Driver`], blocking or async)
//! runs a session over a real link.
//!
//! Operations ([`Session::Op`]: a read, a write, a move) are started with [`Session::start`], which returns
//! an [`OpId`]; they report [`Event::Progress`] and end with exactly one [`Event::Done`]. [`Session::cancel`]
//! asks a running operation to end early, stopping any motion it started; [`Session::close`] ends the
//! session the same way for everything, and is answered by [`Event::Closed`].

use std::fmt;
use std::time::Duration;

use crate::can::CanFrame;
use crate::clock::Timestamp;
use crate::error::Classify;
use crate::link::LinkError;

/// The handle of one operation of a session.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct OpId(pub u64);

impl fmt::Display for OpId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "op {}", self.0)
    }
}

/// Hands out increasing [`OpId`]s.
#[derive(Debug, Default, Clone)]
pub struct OpIds(u64);

impl OpIds {
    /// The next id.
    pub fn next_id(&mut self) -> OpId {
        self.0 += 1;
        OpId(self.0)
    }
}

/// What arrived on the link: the one [`Chunk`](crate::chunk::Chunk) of every user of a link.
pub use crate::chunk::Chunk as Input;

/// What a session asks its driver to do.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Action {
    /// Write these bytes to the serial line.
    Send(Vec<u8>),
    /// Put this frame on the CAN bus.
    SendFrame(CanFrame),
    /// Drop every byte or frame received and not yet handed over (stale answers).
    DiscardInput,
    /// Close the port and open it again; the driver reports the outcome with [`Session::handle_reopened`].
    Reopen,
}

/// What happened in a session.
pub enum Event<S: Session + ?Sized> {
    /// An operation made progress (a position on the way, a phase of homing).
    Progress(OpId, S::Progress),
    /// An operation ended. Exactly one per operation started.
    Done(OpId, Result<S::Output, S::Error>),
    /// The close sequence ended: `Ok` once everything the session started was confirmed stopped.
    Closed(Result<(), S::Error>),
}

impl<S: Session + ?Sized> fmt::Debug for Event<S>
where
    S::Progress: fmt::Debug,
    S::Output: fmt::Debug,
    S::Error: fmt::Debug,
{
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Event::Progress(id, p) => f.debug_tuple("Progress").field(id).field(p).finish(),
            Event::Done(id, r) => f.debug_tuple("Done").field(id).field(r).finish(),
            Event::Closed(r) => f.debug_tuple("Closed").field(r).finish(),
        }
    }
}

/// The error type of a session: classified, and able to say the two things a driver reports by itself.
pub trait SessionError: Classify + From<LinkError> + fmt::Display + fmt::Debug + Send + 'static {
    /// The driver gave up waiting for the close sequence after `bound`: what was started may not have been
    /// confirmed stopped.
    fn close_timed_out(bound: Duration) -> Self;

    /// The operation could not be run because the session is closed (or closing).
    fn session_closed() -> Self;
}

/// A device protocol as a sans-IO state machine. See the [module documentation](self).
pub trait Session: Send + 'static {
    /// An operation a caller can start.
    type Op: Send + 'static;
    /// What an operation ends with.
    type Output: Send + 'static;
    /// What an operation reports on its way.
    type Progress: Clone + Send + 'static;
    /// The session's error.
    type Error: SessionError;

    /// Starts `op` at `now`. An operation that is invalid ends at once, with an [`Event::Done`] carrying a
    /// usage error.
    fn start(&mut self, op: Self::Op, now: Timestamp) -> OpId;

    /// Asks operation `id` to end early: it stops any motion it started and ends with a cancelled error
    /// (or with its result, if it had already ended). Unknown ids are ignored.
    fn cancel(&mut self, id: OpId, now: Timestamp);

    /// Begins the close sequence: no new operation is accepted, running ones are cancelled, everything the
    /// session started is stopped, and [`Event::Closed`] reports the outcome.
    fn close(&mut self, now: Timestamp);

    /// Something arrived on the link at `now`.
    fn handle_input(&mut self, input: Input<'_>, now: Timestamp);

    /// The link failed at `now` (sending or receiving).
    fn handle_link_error(&mut self, error: LinkError, now: Timestamp);

    /// The driver reopened the port after an [`Action::Reopen`] (or failed to).
    fn handle_reopened(&mut self, result: Result<(), LinkError>, now: Timestamp);

    /// The next thing to do on the link at `now`, if any (the driver does it at once: `now` is when a
    /// request's answer time starts).
    fn poll_transmit(&mut self, now: Timestamp) -> Option<Action>;

    /// When the session next wants [`Session::handle_timeout`] to be called, if ever.
    fn poll_timeout(&self) -> Option<Timestamp>;

    /// Time has reached `now`.
    fn handle_timeout(&mut self, now: Timestamp);

    /// The next event, if any.
    fn poll_event(&mut self) -> Option<Event<Self>>;

    /// True while the session expects something from the device (an answer is due, or a message the device
    /// sends by itself): the driver then reads the link; otherwise it sleeps until the next timeout or until
    /// a caller starts something.
    fn wants_input(&self) -> bool;

    /// True when the session has nothing under way: no operation running, nothing to send, no answer due.
    /// A driver may then leave the port alone until [`Session::poll_timeout`].
    fn is_idle(&self) -> bool;
}
