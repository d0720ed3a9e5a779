//! A mutex whose waiters block through clock signals, so that an auto-advancing
//! [`ManualClock`](motionlink_link::ManualClock) sees them as idle (a `std::sync::Mutex` would hide them).

use std::ops::{Deref, DerefMut};
use std::sync::Mutex;

use motionlink_link::clock::lock;
use motionlink_link::{SharedClock, Signal};

struct State<T> {
    value: Option<T>,
    waiters: Vec<Signal>,
}

/// Exclusive access to a `T`, waited for on the clock.
pub(crate) struct ClockLock<T> {
    clock: SharedClock,
    state: Mutex<State<T>>,
}

impl<T> ClockLock<T> {
    pub fn new(clock: SharedClock, value: T) -> Self {
        ClockLock { clock, state: Mutex::new(State { value: Some(value), waiters: Vec::new() }) }
    }

    /// Waits (on the clock) until the value is free.
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

    /// The value if it is free now.
    pub fn try_lock(&self) -> Option<ClockGuard<'_, T>> {
        let mut st = lock(&self.state);
        st.value.take().map(|value| ClockGuard { owner: self, value: Some(value) })
    }
}

/// Access to the value of a [`ClockLock`]; gives it back when dropped.
pub(crate) struct ClockGuard<'a, T> {
    owner: &'a ClockLock<T>,
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
    use motionlink_link::clock::{Clock, ManualClock};
    use std::sync::Arc;
    use std::time::Duration;

    #[test]
    fn a_waiter_on_the_lock_lets_the_manual_clock_run() {
        let clock = ManualClock::new_auto();
        let shared = clock.shared();
        let cell = Arc::new(ClockLock::new(Arc::clone(&shared), 0u32));
        let ticket = clock.reserve_participant();
        let (c2, cell2) = (clock.clone(), Arc::clone(&cell));
        let t = std::thread::spawn(move || {
            let _g = ticket.enter();
            let mut guard = cell2.lock();
            // Holds the lock across 100 ms of clock time.
            c2.sleep(Duration::from_millis(100));
            *guard += 1;
        });
        let _me = clock.reserve_participant().enter();
        clock.sleep(Duration::from_millis(1));
        // Blocks on the lock until the other thread's sleep is over: only possible if the clock moves.
        let v = *cell.lock();
        t.join().unwrap();
        assert_eq!(v + *cell.lock(), 2);
        assert!(cell.try_lock().is_some());
    }
}
