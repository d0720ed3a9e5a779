//! A mutex whose waiters block through clock signals, for the half-duplex line a session shares between its
//! caller's requests and its background keepalive or watchdog duty.
//!
//! A thread blocked on a `std::sync::Mutex` is invisible to an auto-advancing
//! [`ManualClock`](crate::clock::ManualClock): it is neither running nor waiting on the clock, so the clock
//! would stall (or run ahead). A thread blocked on a [`ClockLock`] waits on a [`Signal`] of the clock and counts
//! as idle.
//!
//! ```
//! use motionlink_link::clock_lock::ClockLock;
//! use motionlink_link::RealClock;
//! let line = ClockLock::new(RealClock::shared(), Vec::<u8>::new());
//! line.lock().push(1);
//! assert_eq!(line.try_lock().map(|g| g.len()), Some(1));
//! ```

use std::ops::{Deref, DerefMut};
use std::sync::Mutex;

use crate::clock::{lock, SharedClock, Signal};

struct State<T> {
    value: Option<T>,
    waiters: Vec<Signal>,
}

/// Exclusive access to a `T`, waited for on a clock.
pub struct ClockLock<T> {
    clock: SharedClock,
    state: Mutex<State<T>>,
}

impl<T> std::fmt::Debug for ClockLock<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ClockLock").field("free", &lock(&self.state).value.is_some()).finish()
    }
}

impl<T> ClockLock<T> {
    /// `value` behind a lock whose waiters wait on `clock`.
    pub fn new(clock: SharedClock, value: T) -> Self {
        ClockLock { clock, state: Mutex::new(State { value: Some(value), waiters: Vec::new() }) }
    }

    /// Waits (on the clock) until the value is free, and takes it.
    pub fn lock(&self) -> ClockGuard<'_, T> {
        loop {
            let signal = {
                let mut st = lock(&self.state);
                if let Some(value) = st.value.take() {
                    return ClockGuard { owner: self, value: Some(value) };
                }
                let s = self.clock.signal();
                st.waiters.push(s.clone());
                s
            };
            signal.wait_until(None);
        }
    }

    /// The value, if it is free now.
    pub fn try_lock(&self) -> Option<ClockGuard<'_, T>> {
        let mut st = lock(&self.state);
        st.value.take().map(|value| ClockGuard { owner: self, value: Some(value) })
    }
}

/// Access to the value of a [`ClockLock`]; gives it back, and wakes the waiters, when dropped.
pub struct ClockGuard<'a, T> {
    owner: &'a ClockLock<T>,
    /// Always `Some` until the guard is dropped.
    value: Option<T>,
}

impl<T> Deref for ClockGuard<'_, T> {
    type Target = T;
    fn deref(&self) -> &T {
        self.value.as_ref().expect("a guard holds its value until dropped")
    }
}

impl<T> DerefMut for ClockGuard<'_, T> {
    fn deref_mut(&mut self) -> &mut T {
        self.value.as_mut().expect("a guard holds its value until dropped")
    }
}

impl<T> Drop for ClockGuard<'_, T> {
    fn drop(&mut self) {
        let mut st = lock(&self.owner.state);
        st.value = self.value.take();
        for w in st.waiters.drain(..) {
            w.raise();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::clock::{Clock, ManualClock};
    use std::sync::Arc;
    use std::time::Duration;

    #[test]
    fn a_waiter_on_the_lock_lets_the_manual_clock_run() {
        let clock = ManualClock::new_auto();
        let _me = clock.reserve_participant().enter();
        let cell = Arc::new(ClockLock::new(clock.shared(), 0u32));
        let ticket = clock.reserve_participant();
        let (c2, cell2) = (clock.clone(), Arc::clone(&cell));
        let t = std::thread::spawn(move || {
            let _g = ticket.enter();
            let mut guard = cell2.lock();
            // Holds the lock across 100 ms of clock time.
            c2.sleep(Duration::from_millis(100));
            *guard += 1;
        });
        clock.sleep(Duration::from_millis(1));
        // Blocks on the lock until the other thread's sleep is over: only possible if the clock moves.
        let v = *cell.lock();
        assert_eq!(v, 1);
        assert!(clock.now() >= crate::Timestamp::from_millis(100));
        t.join().unwrap();
        assert!(cell.try_lock().is_some());
    }
}
