//! Handing memory the process freed back to the operating system.
//!
//! An hour-long replay frees its traces (most of the marker stage's memory,
//! hundreds of megabytes in thousands of small chunks) before it builds the
//! animation, whose large buffers the allocator maps afresh rather than
//! carve from the freed chunks. Without this the freed pages stay counted
//! in the process's resident memory, and the animation's peak adds to the
//! marker stage's instead of reusing it.

/// Returns the freed pages of every allocator arena to the OS (glibc's
/// `malloc_trim`, which also releases whole free pages inside the heap, not
/// only at its top). Elsewhere it does nothing.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
pub fn release_freed() {
    // SAFETY: malloc_trim takes no pointer and only walks glibc's own
    // free lists, under their locks.
    unsafe {
        libc::malloc_trim(0);
    }
}

/// Returns the freed pages to the OS where the allocator can (see above).
#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
pub fn release_freed() {}
