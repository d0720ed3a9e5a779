//! A global allocator that counts allocations, for tests that prove a codec allocates nothing per telegram.
//!
//! ```no_run
//! use motionlink_testkit::alloc_count::CountingAllocator;
//!
//! #[global_allocator]
//! static ALLOCATOR: CountingAllocator = CountingAllocator::new();
//!
//! let before = CountingAllocator::allocations_on_this_thread();
//! // ... encode and decode ...
//! assert_eq!(CountingAllocator::allocations_on_this_thread() - before, 0);
//! ```

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicUsize, Ordering};

thread_local! {
    /// Allocations made by this thread (const-initialised: reading it never allocates).
    static ON_THIS_THREAD: Cell<usize> = const { Cell::new(0) };
}

/// The system allocator, counting every allocation and reallocation made through it.
#[derive(Debug, Default)]
pub struct CountingAllocator {
    allocations: AtomicUsize,
}

impl CountingAllocator {
    /// A counter at zero.
    pub const fn new() -> Self {
        CountingAllocator { allocations: AtomicUsize::new(0) }
    }

    /// Allocations and reallocations so far, by every thread of the process.
    pub fn allocations(&self) -> usize {
        self.allocations.load(Ordering::SeqCst)
    }

    /// Allocations and reallocations so far by the calling thread: what a test should compare, since the test
    /// harness allocates on its own threads while a test runs.
    pub fn allocations_on_this_thread() -> usize {
        ON_THIS_THREAD.try_with(Cell::get).unwrap_or(0)
    }

    fn count(&self) {
        self.allocations.fetch_add(1, Ordering::SeqCst);
        // A thread being torn down has no thread-locals any more; its allocations count only globally.
        let _ = ON_THIS_THREAD.try_with(|c| c.set(c.get() + 1));
    }
}

// SAFETY: every call is passed on unchanged to the system allocator; counting has no effect on memory.
unsafe impl GlobalAlloc for CountingAllocator {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        self.count();
        // SAFETY: the caller upholds `alloc`'s contract, which is passed on unchanged.
        unsafe { System.alloc(layout) }
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        self.count();
        // SAFETY: as for `alloc`.
        unsafe { System.alloc_zeroed(layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        self.count();
        // SAFETY: the caller upholds `realloc`'s contract, which is passed on unchanged.
        unsafe { System.realloc(ptr, layout, new_size) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: the caller upholds `dealloc`'s contract, which is passed on unchanged.
        unsafe { System.dealloc(ptr, layout) }
    }
}
