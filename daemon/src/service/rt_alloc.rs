//! A fixed pool for the RT thread's unavoidable small allocations.
//!
//! Our RT loop allocates nothing, but iceoryx2 0.10's `Publisher::loan_uninit`
//! allocates one small object per sample (the `Arc` of the chunk's shared
//! state in `ChunkMutSharedState::new`), and the loop publishes every tick.
//! [`RtPool`] wraps the process's allocator: on a thread marked with
//! [`enter_rt`], allocations of at most [`SLOT_BYTES`] are served from a static
//! pool of [`SLOTS`] slots through a lock-free free list (no system call, no
//! lock, O(1)); everything else goes to the inner allocator. A pool slot may
//! be freed on any thread. When the pool is empty the inner allocator serves
//! the request and [`fallbacks`] counts it, so exhaustion is visible, never
//! fatal.

use core::alloc::{GlobalAlloc, Layout};
use core::cell::{Cell, UnsafeCell};
use core::sync::atomic::{AtomicU32, AtomicU64, AtomicUsize, Ordering};

/// Bytes per pool slot (and the largest allocation the pool serves).
pub const SLOT_BYTES: usize = 256;
/// Slots in the pool (256 KiB in all).
pub const SLOTS: usize = 1024;
/// Largest alignment the pool serves.
const SLOT_ALIGN: usize = 64;

#[repr(C, align(64))]
struct Pool(UnsafeCell<[[u8; SLOT_BYTES]; SLOTS]>);

// SAFETY: slots are handed to one owner at a time by the free list below.
unsafe impl Sync for Pool {}

static POOL: Pool = Pool(UnsafeCell::new([[0; SLOT_BYTES]; SLOTS]));
/// Slots never handed out yet start at this index.
static BUMP: AtomicUsize = AtomicUsize::new(0);
/// Free list head: (ABA tag << 32) | (slot index + 1); 0 in the low half = empty.
static FREE: AtomicU64 = AtomicU64::new(0);
/// Next free slot (index + 1, 0 = none) of each slot on the free list.
static NEXT: [AtomicU32; SLOTS] = [const { AtomicU32::new(0) }; SLOTS];
/// Requests on an RT thread the pool could not serve (too big, or empty).
static FALLBACKS: AtomicU64 = AtomicU64::new(0);
/// Allocations the pool served.
static SERVED: AtomicU64 = AtomicU64::new(0);
/// Of the fallbacks: requests the pool had no free slot for.
static EXHAUSTED: AtomicU64 = AtomicU64::new(0);
/// Largest request that fell back (bytes), to size the slots by.
static LARGEST_FALLBACK: AtomicUsize = AtomicUsize::new(0);

thread_local! {
    static RT: Cell<bool> = const { Cell::new(false) };
}

/// Marks this thread as an RT thread: its small allocations come from the pool.
pub fn enter_rt() {
    RT.with(|r| r.set(true));
}

/// Ends [`enter_rt`] on this thread: what it allocates from now on (the
/// teardown of its ports after the loop) is not the loop's.
pub fn leave_rt() {
    RT.with(|r| r.set(false));
}

/// Requests on RT threads that the pool could not serve (went to the system allocator).
pub fn fallbacks() -> u64 {
    FALLBACKS.load(Ordering::Relaxed)
}

/// Allocations the pool has served.
pub fn served() -> u64 {
    SERVED.load(Ordering::Relaxed)
}

/// Of [`fallbacks`]: the requests that found the pool empty (the others
/// were larger than a slot or more aligned).
pub fn exhausted() -> u64 {
    EXHAUSTED.load(Ordering::Relaxed)
}

/// The largest request that fell back, bytes (0: none).
pub fn largest_fallback() -> usize {
    LARGEST_FALLBACK.load(Ordering::Relaxed)
}

fn base() -> usize {
    POOL.0.get() as usize
}

fn slot_of(ptr: *mut u8) -> Option<usize> {
    let off = (ptr as usize).wrapping_sub(base());
    (off < SLOTS * SLOT_BYTES).then_some(off / SLOT_BYTES)
}

fn take() -> Option<usize> {
    let mut head = FREE.load(Ordering::Acquire);
    loop {
        let idx = (head & 0xffff_ffff) as usize;
        if idx == 0 {
            break;
        }
        let next = u64::from(NEXT[idx - 1].load(Ordering::Acquire));
        let new = ((head >> 32).wrapping_add(1) << 32) | next;
        match FREE.compare_exchange_weak(head, new, Ordering::AcqRel, Ordering::Acquire) {
            Ok(_) => return Some(idx - 1),
            Err(h) => head = h,
        }
    }
    let i = BUMP.fetch_add(1, Ordering::Relaxed);
    if i < SLOTS {
        Some(i)
    } else {
        BUMP.store(SLOTS, Ordering::Relaxed); // no wrap-around however often it is asked
        None
    }
}

fn give_back(slot: usize) {
    let mut head = FREE.load(Ordering::Acquire);
    loop {
        NEXT[slot].store((head & 0xffff_ffff) as u32, Ordering::Release);
        let new = ((head >> 32).wrapping_add(1) << 32) | (slot as u64 + 1);
        match FREE.compare_exchange_weak(head, new, Ordering::AcqRel, Ordering::Acquire) {
            Ok(_) => return,
            Err(h) => head = h,
        }
    }
}

/// The process's allocator with the RT pool in front of `A`.
#[derive(Debug, Default)]
pub struct RtPool<A>(pub A);

fn on_rt_thread() -> bool {
    // `try_with`: the allocator also runs while thread-locals are torn down.
    RT.try_with(Cell::get).unwrap_or(false)
}

// SAFETY: pool slots are disjoint, 64-byte aligned, handed out once until
// freed; everything else is forwarded to `A` unchanged.
unsafe impl<A: GlobalAlloc> GlobalAlloc for RtPool<A> {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if on_rt_thread() {
            if layout.size() <= SLOT_BYTES && layout.align() <= SLOT_ALIGN {
                if let Some(i) = take() {
                    SERVED.fetch_add(1, Ordering::Relaxed);
                    // SAFETY: `i < SLOTS`, so the slot lies inside the pool.
                    return unsafe { (POOL.0.get() as *mut u8).add(i * SLOT_BYTES) };
                }
                EXHAUSTED.fetch_add(1, Ordering::Relaxed);
            }
            FALLBACKS.fetch_add(1, Ordering::Relaxed);
            LARGEST_FALLBACK.fetch_max(layout.size(), Ordering::Relaxed);
        }
        // SAFETY: the caller's contract is passed on.
        unsafe { self.0.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        match slot_of(ptr) {
            Some(i) => give_back(i),
            // SAFETY: not ours, so `A` allocated it.
            None => unsafe { self.0.dealloc(ptr, layout) },
        }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if slot_of(ptr).is_none() {
            // SAFETY: `A` allocated it.
            return unsafe { self.0.realloc(ptr, layout, new_size) };
        }
        if new_size <= SLOT_BYTES {
            return ptr; // the slot has room
        }
        // SAFETY: a valid layout of the new size (the caller's contract).
        let new_layout = unsafe { Layout::from_size_align_unchecked(new_size, layout.align()) };
        // SAFETY: as for `alloc`; the old block holds `layout.size()` bytes.
        unsafe {
            let new = self.alloc(new_layout);
            if !new.is_null() {
                core::ptr::copy_nonoverlapping(ptr, new, layout.size());
                self.dealloc(ptr, layout);
            }
            new
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_rt_thread_gets_pool_slots_that_any_thread_can_free() {
        let before = served();
        let ptrs: Vec<usize> = std::thread::spawn(|| {
            enter_rt();
            // Boxes made here come from the pool; freed on another thread below.
            (0..100)
                .map(|i| Box::into_raw(Box::new([i as u8; 100])) as usize)
                .collect()
        })
        .join()
        .expect("RT thread");
        assert!(served() >= before + 100);
        for &p in &ptrs {
            assert!(slot_of(p as *mut u8).is_some());
            // SAFETY: made by Box::into_raw above.
            let b = unsafe { Box::from_raw(p as *mut [u8; 100]) };
            assert!(b.iter().all(|&x| x == b[0]));
        }
        // A thread that is not RT never gets a slot.
        let other = Box::new([0u8; 100]);
        assert!(slot_of(&*other as *const _ as *mut u8).is_none());
    }
}
