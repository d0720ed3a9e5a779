//! The counting allocator counts: a test that relies on it to prove "no allocation" cannot pass vacuously.

use motionlink_testkit::alloc_count::CountingAllocator;

#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator::new();

#[test]
fn it_counts_this_threads_allocations_and_reallocations() {
    let before = CountingAllocator::allocations_on_this_thread();
    let global_before = ALLOCATOR.allocations();
    let mut v: Vec<u8> = Vec::with_capacity(1);
    v.extend_from_slice(&[1, 2, 3, 4, 5, 6, 7, 8, 9]);
    std::hint::black_box(&v);
    let here = CountingAllocator::allocations_on_this_thread() - before;
    assert!(here >= 2, "one allocation and at least one reallocation, counted {here}");
    assert!(ALLOCATOR.allocations() - global_before >= here);
    // Another thread's allocations are its own: here only the few of spawning it count.
    let mark = CountingAllocator::allocations_on_this_thread();
    let theirs = std::thread::spawn(|| {
        let start = CountingAllocator::allocations_on_this_thread();
        for i in 0..1000 {
            std::hint::black_box(vec![0u8; 64 + i]);
        }
        CountingAllocator::allocations_on_this_thread() - start
    })
    .join()
    .unwrap();
    assert_eq!(theirs, 1000);
    let ours = CountingAllocator::allocations_on_this_thread() - mark;
    assert!(ours < 50, "{ours} allocations counted here for a thread that made 1000");
}
