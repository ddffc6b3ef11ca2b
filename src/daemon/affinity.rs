//! `daemon.pipeline_cpu`: the pipeline thread on a CPU of its own.
//!
//! Between two frames of a 360 Hz rig the pipeline sleeps about 2 ms. On a
//! machine with few cores the analysis (seconds of CPU on a full window of
//! 1 000 markers) and the tree builder then run on the pipeline's core, and
//! their gigabytes of window and tree push the live tracker's state (about
//! a megabyte of traces and identities at 1 000 markers) out of that core's
//! caches: the next frame's tracking starts cold. Pinning the pipeline to
//! one CPU and keeping the background threads off it leaves the tracker's
//! state where the last frame left it. The cost is a core the background
//! work no longer gets; nothing else changes, so it is off by default (-1).

use crate::error::{Error, Result};

/// Where the pipeline and the background threads may run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub(crate) struct Placement {
    /// The pipeline's CPU, `None` when not pinned.
    pub(crate) pipeline: Option<usize>,
}

impl Placement {
    /// From `daemon.pipeline_cpu` (-1: no pinning). A CPU this process may
    /// not run on is an error naming the key, not a silent no-op.
    pub(crate) fn from_setting(cpu: i32) -> Result<Placement> {
        let Ok(cpu) = usize::try_from(cpu) else {
            return Ok(Placement::default());
        };
        let allowed = allowed_cpus();
        if !allowed.contains(&cpu) {
            return Err(Error::config(
                "daemon.pipeline_cpu",
                format!("CPU {cpu} is not one this process may run on (allowed: {allowed:?})"),
            ));
        }
        Ok(Placement {
            pipeline: Some(cpu),
        })
    }

    /// Pins the calling thread (the pipeline) to its CPU.
    pub(crate) fn pin_pipeline(&self) {
        if let Some(cpu) = self.pipeline {
            set_affinity(&[cpu]);
        }
    }

    /// Keeps the calling thread (a background one) off the pipeline's CPU;
    /// the threads it starts inherit that. With a single CPU allowed there
    /// is nowhere else to go, and the thread stays where it may run.
    pub(crate) fn keep_off_pipeline(&self) {
        let Some(cpu) = self.pipeline else { return };
        let others: Vec<usize> = allowed_cpus().into_iter().filter(|&c| c != cpu).collect();
        if !others.is_empty() {
            set_affinity(&others);
        }
    }
}

/// The CPUs the calling thread may run on.
#[cfg(target_os = "linux")]
pub(crate) fn allowed_cpus() -> Vec<usize> {
    // SAFETY: a zeroed cpu_set_t is a valid empty set; the calls only read
    // and write through a pointer to it.
    unsafe {
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        if libc::sched_getaffinity(0, std::mem::size_of_val(&set), &mut set) != 0 {
            return Vec::new();
        }
        (0..libc::CPU_SETSIZE as usize)
            .filter(|&c| libc::CPU_ISSET(c, &set))
            .collect()
    }
}

#[cfg(target_os = "linux")]
fn set_affinity(cpus: &[usize]) {
    // SAFETY: as above; `sched_setaffinity(0, …)` acts on this thread only.
    let r = unsafe {
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        for &c in cpus {
            libc::CPU_SET(c, &mut set);
        }
        libc::sched_setaffinity(0, std::mem::size_of_val(&set), &set)
    };
    if r != 0 {
        tracing::warn!("daemon.pipeline_cpu: could not set a thread's CPUs to {cpus:?}");
    }
}

#[cfg(not(target_os = "linux"))]
pub(crate) fn allowed_cpus() -> Vec<usize> {
    Vec::new()
}

#[cfg(not(target_os = "linux"))]
fn set_affinity(_cpus: &[usize]) {}
