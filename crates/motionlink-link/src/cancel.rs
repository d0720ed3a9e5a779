//! Cancellation of long actions (a move, homing, waiting for a position): set by a signal in the
//! command-line tool or by the caller's own logic, seen at once by a session driver waiting on it.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

use crate::clock::{lock, Signal};

/// A flag shared between whoever may cancel and the action that checks it.
///
/// ```
/// use motionlink_link::cancel::CancelToken;
/// let token = CancelToken::new();
/// let for_handler = token.clone();
/// assert!(!token.is_cancelled());
/// for_handler.cancel();
/// assert!(token.is_cancelled());
/// ```
#[derive(Debug, Clone, Default)]
pub struct CancelToken(Arc<Inner>);

#[derive(Debug, Default)]
struct Inner {
    cancelled: AtomicBool,
    /// Raised on cancel: the waits of those who watch the token.
    watchers: Mutex<Vec<Signal>>,
}

impl CancelToken {
    /// A token that is not cancelled.
    pub fn new() -> Self {
        Self::default()
    }

    /// Asks every action watching this token to stop, and wakes those that wait.
    pub fn cancel(&self) {
        self.0.cancelled.store(true, Ordering::SeqCst);
        for s in lock(&self.0.watchers).iter() {
            s.raise();
        }
    }

    /// True once [`CancelToken::cancel`] was called.
    pub fn is_cancelled(&self) -> bool {
        self.0.cancelled.load(Ordering::SeqCst)
    }

    /// Clears the flag for the next action.
    pub fn reset(&self) {
        self.0.cancelled.store(false, Ordering::SeqCst);
    }

    /// Raises `signal` when the token is cancelled (at once, if it already is), until
    /// [`CancelToken::unwatch`] removes it.
    pub fn watch(&self, signal: &Signal) {
        lock(&self.0.watchers).push(signal.clone());
        if self.is_cancelled() {
            signal.raise();
        }
    }

    /// Stops raising `signal` (compared by identity).
    pub fn unwatch(&self, signal: &Signal) {
        lock(&self.0.watchers).retain(|s| !s.same_as(signal));
    }
}
