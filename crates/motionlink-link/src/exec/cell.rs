//! The lock around what a session shares with its operations. A guard held across another call into the
//! same state (`match ctx.core().x { _ => ctx.core() }`, both halves of `[a.core().x(), exec.y()]`) would
//! wait for itself forever; in debug builds such a second lock panics at once, naming the mistake.

use std::ops::{Deref, DerefMut};
use std::sync::{Mutex, MutexGuard};

use crate::clock::lock;

/// A mutex that, in debug builds, refuses to be locked twice by the same thread.
pub(crate) struct SharedCell<T> {
    mutex: Mutex<T>,
    #[cfg(debug_assertions)]
    holder: std::sync::atomic::AtomicUsize,
}

/// A number that tells the threads alive apart (the address of a thread-local).
#[cfg(debug_assertions)]
fn this_thread() -> usize {
    thread_local!(static MARK: u8 = const { 0 });
    MARK.with(|m| m as *const u8 as usize)
}

impl<T> SharedCell<T> {
    pub(crate) fn new(value: T) -> Self {
        SharedCell {
            mutex: Mutex::new(value),
            #[cfg(debug_assertions)]
            holder: std::sync::atomic::AtomicUsize::new(0),
        }
    }

    pub(crate) fn lock(&self) -> Locked<'_, T> {
        #[cfg(debug_assertions)]
        {
            use std::sync::atomic::Ordering;
            let me = this_thread();
            assert!(
                self.holder.load(Ordering::Acquire) != me,
                "a session's core locked twice by one thread: a guard (ctx.core(), exec.core()) is still held \
                 (bind the value first: `let x = ctx.core().x;`)"
            );
            let guard = lock(&self.mutex);
            self.holder.store(me, Ordering::Release);
            Locked { guard, holder: &self.holder }
        }
        #[cfg(not(debug_assertions))]
        Locked { guard: lock(&self.mutex) }
    }
}

/// The locked state.
pub(crate) struct Locked<'a, T> {
    guard: MutexGuard<'a, T>,
    #[cfg(debug_assertions)]
    holder: &'a std::sync::atomic::AtomicUsize,
}

impl<T> Drop for Locked<'_, T> {
    fn drop(&mut self) {
        #[cfg(debug_assertions)]
        self.holder.store(0, std::sync::atomic::Ordering::Release);
    }
}

impl<T> Deref for Locked<'_, T> {
    type Target = T;
    fn deref(&self) -> &T {
        &self.guard
    }
}

impl<T> DerefMut for Locked<'_, T> {
    fn deref_mut(&mut self) -> &mut T {
        &mut self.guard
    }
}
