//! Cancellation of long actions (a move, homing, waiting for a position): set by Ctrl-C in the command-line
//! tool or by the caller's own logic, checked by the clients between steps.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

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
pub struct CancelToken(Arc<AtomicBool>);

impl CancelToken {
    /// A token that is not cancelled.
    pub fn new() -> Self {
        Self::default()
    }

    /// Asks every action watching this token to stop.
    pub fn cancel(&self) {
        self.0.store(true, Ordering::SeqCst);
    }

    /// True once [`CancelToken::cancel`] was called.
    pub fn is_cancelled(&self) -> bool {
        self.0.load(Ordering::SeqCst)
    }

    /// Clears the flag for the next action.
    pub fn reset(&self) {
        self.0.store(false, Ordering::SeqCst);
    }
}
