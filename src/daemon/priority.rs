//! The daemon's background threads yield the CPU to the live path.
//!
//! On a small machine (the 2-core PCs that often sit beside a rig) the
//! analysis of a full 60 s window and the tree builder are CPU-bound for
//! seconds at a time. At equal priority the scheduler shares a core between
//! them and the pipeline, so a frame arriving while the analysis holds the
//! core waits for its time slice: 20 ms at p99, and backlogs of hundreds of
//! frames, at 1 000 Hz × 100 markers (issue 15). Marked as batch work at
//! the lowest priority, they still get every cycle the live path leaves,
//! but a waking pipeline or source preempts them at once.

/// Lowers the calling thread to background priority (`SCHED_BATCH`, nice
/// 19). Failing to do so only costs latency, so it is logged, not fatal.
pub(crate) fn background() {
    #[cfg(target_os = "linux")]
    {
        // SAFETY: plain system calls on the calling thread with a valid,
        // initialised parameter; no memory is shared with the kernel
        // beyond the call.
        let ok = unsafe {
            let param = libc::sched_param { sched_priority: 0 };
            let tid = libc::gettid();
            libc::sched_setscheduler(0, libc::SCHED_BATCH, &param) == 0
                && libc::setpriority(libc::PRIO_PROCESS, tid as libc::id_t, 19) == 0
        };
        if !ok {
            tracing::debug!(
                "could not lower a background thread's priority: {}",
                std::io::Error::last_os_error()
            );
        }
    }
}
