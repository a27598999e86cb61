//! A global allocator that counts the allocations of the threads that ask
//! for it, for tests that assert a hot path does not allocate: the
//! interpolator's tick (`interp-core`), the trace recorder's producer side
//! (`traces`), the demo loop and the RT thread (`interpd`). One home for it;
//! a dev-dependency only, so that no library carries a test feature.
//!
//! A test binary installs it with
//! `#[global_allocator] static A: alloc_count::Counting = alloc_count::Counting;`
//! (or with another allocator in front of it) and wraps the code under test
//! in [`count`], or brackets it with [`start`] and [`stop`]. Allocations on
//! other threads, and on this thread outside those, are not counted.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

thread_local! {
    static ON: Cell<bool> = const { Cell::new(false) };
    static COUNT: Cell<u64> = const { Cell::new(0) };
}

fn note() {
    // `try_with`: the allocator also runs while thread-locals are torn down.
    let _ = ON.try_with(|on| {
        if on.get() {
            COUNT.with(|c| c.set(c.get() + 1));
        }
    });
}

/// Starts counting this thread's allocations (from zero).
pub fn start() {
    COUNT.with(|c| c.set(0));
    ON.with(|on| on.set(true));
}

/// Stops counting on this thread; returns the allocations since [`start`].
pub fn stop() -> u64 {
    ON.with(|on| on.set(false));
    COUNT.with(Cell::get)
}

/// Runs `f` on this thread and returns its result and the allocations
/// (alloc, alloc_zeroed, realloc) it made on this thread.
pub fn count<R>(f: impl FnOnce() -> R) -> (R, u64) {
    start();
    let r = f();
    (r, stop())
}

/// The system allocator, counting inside [`count`] (or [`start`]..[`stop`]).
#[derive(Debug, Clone, Copy, Default)]
pub struct Counting;

// SAFETY: forwards every call to the system allocator unchanged.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        note();
        // SAFETY: the caller's contract is passed on.
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        note();
        // SAFETY: as above.
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        note();
        // SAFETY: as above.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: as above.
        unsafe { System.dealloc(ptr, layout) }
    }
}
