//! Bringing the live tracker's state back into the caches before a frame.
//!
//! In the daemon the pipeline sleeps about 2 ms between two frames of a
//! 360 Hz rig, and meanwhile the analysis streams through gigabytes of
//! window: the shared last-level cache (8 MB on the development machine)
//! is flushed, and the next frame's tracking finds its megabyte of traces
//! and identities (at 1 000 markers) in main memory, one miss at a time,
//! 1.6 × slower than back to back (`examples/frame_cost --evict-kb 8192`).
//! A prefetch of every cache line of that state, issued just before the
//! frame is due, loads it at the memory's bandwidth instead of its latency
//! and off the latency path. Prefetches read nothing and change nothing:
//! the tracking and its outputs are those without them.

/// Asks the CPU to load every cache line of `items` (no-op off x86-64).
#[inline]
pub(crate) fn prefetch<T>(items: &[T]) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        let bytes = std::mem::size_of_val(items);
        let p = items.as_ptr().cast::<i8>();
        let mut off = 0;
        while off < bytes {
            // SAFETY: `off` stays inside the slice; a prefetch never faults
            // and reads no value.
            unsafe { _mm_prefetch(p.add(off), _MM_HINT_T0) };
            off += 64;
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = items;
}

/// Prefetches one value.
#[inline]
pub(crate) fn prefetch_one<T>(item: &T) {
    prefetch(std::slice::from_ref(item));
}
