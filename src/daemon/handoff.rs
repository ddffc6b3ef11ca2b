//! The hand-off of the recent frames from the pipeline thread to the
//! analysis thread.
//!
//! The pipeline must never wait and never copy the window for an analysis
//! that cannot start yet: it asks [`AnalysisHandoff::wants`] (two atomic
//! loads) and only then takes a [`WindowSnapshot`] (reference counts) and
//! offers it. The analysis thus always starts on the newest frames, and a
//! slow analysis only makes analyses rarer, never the pipeline slower.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Condvar, Mutex};
use std::time::Duration;

use super::window::WindowSnapshot;
use crate::model::tips::Tips;
use crate::track::TrackingSettings;
use crate::track::{self, Summary, Tracker};

/// One analysis to run: the frames and the rate they came at.
pub struct Job {
    /// The window when the job was offered.
    pub snapshot: WindowSnapshot,
    /// Frames per second of the source as measured (tracking needs it).
    pub frame_rate: f64,
}

/// A one-slot, latest-wins hand-off with a busy flag.
#[derive(Default)]
pub struct AnalysisHandoff {
    /// The job waiting, and whether the pipeline has closed the hand-off.
    slot: Mutex<(Option<Job>, bool)>,
    ready: Condvar,
    /// A job waits in the slot.
    pending: AtomicBool,
    /// The analysis is working on a job.
    busy: AtomicBool,
}

impl AnalysisHandoff {
    /// True when a job offered now would start at once.
    pub fn wants(&self) -> bool {
        !self.pending.load(Ordering::Acquire) && !self.busy.load(Ordering::Acquire)
    }

    /// Offers a job, replacing one still waiting.
    pub fn offer(&self, job: Job) {
        if let Ok(mut slot) = self.slot.lock() {
            slot.0 = Some(job);
            self.pending.store(true, Ordering::Release);
        }
        self.ready.notify_one();
    }

    /// The pipeline has stopped: [`Self::recv`] returns `None` once the
    /// waiting job (if any) is taken.
    pub fn close(&self) {
        if let Ok(mut slot) = self.slot.lock() {
            slot.1 = true;
        }
        self.ready.notify_all();
    }

    /// Waits for the next job; `None` once the hand-off is closed. The
    /// analysis counts as busy until [`Self::done`].
    pub fn recv(&self) -> Option<Job> {
        let slot = self.slot.lock().ok()?;
        let mut slot = self
            .ready
            .wait_while(slot, |s| s.0.is_none() && !s.1)
            .ok()?;
        let job = slot.0.take()?;
        self.busy.store(true, Ordering::Release);
        self.pending.store(false, Ordering::Release);
        Some(job)
    }

    /// The next job, waiting at most `timeout`; the analysis counts as busy
    /// until [`Self::done`].
    pub fn take(&self, timeout: Duration) -> Option<Job> {
        let slot = self.slot.lock().ok()?;
        let (mut slot, _) = self
            .ready
            .wait_timeout_while(slot, timeout, |s| s.0.is_none() && !s.1)
            .ok()?;
        let job = slot.0.take()?;
        self.busy.store(true, Ordering::Release);
        self.pending.store(false, Ordering::Release);
        Some(job)
    }

    /// The analysis finished its job.
    pub fn done(&self) {
        self.busy.store(false, Ordering::Release);
    }

    /// Wakes a waiting [`Self::take`] (at shutdown).
    pub fn wake(&self) {
        self.ready.notify_all();
    }
}

/// The marker stage on a snapshot: the same tracker and cleaning as
/// `treemocap tips`, reading the shared chunks in place.
pub fn track_snapshot(job: &Job, cfg: &TrackingSettings) -> (Tips, Summary) {
    let mut tracker = Tracker::new(cfg, Some(job.frame_rate));
    job.snapshot.for_each(|f| tracker.push(f));
    track::clean(tracker.finish(), cfg, "live", job.frame_rate)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::daemon::window::FrameWindow;
    use crate::model::frame::MarkerFrame;
    use std::sync::Arc;

    #[test]
    fn offers_only_when_free_and_the_latest_wins() {
        let h = Arc::new(AnalysisHandoff::default());
        let mut w = FrameWindow::new(10.0);
        assert!(h.wants());
        for i in 0..3 {
            w.push(&MarkerFrame::new(i, i as f64, vec![]));
            h.offer(Job {
                snapshot: w.snapshot(),
                frame_rate: 1.0,
            });
            assert!(!h.wants(), "a job is waiting");
        }
        let job = h.take(Duration::from_millis(10)).unwrap();
        assert_eq!(job.snapshot.frames, 3, "the latest offer");
        assert!(!h.wants(), "busy");
        h.done();
        assert!(h.wants());
        assert!(h.take(Duration::from_millis(10)).is_none());
        // Closing ends the analysis's loop once the last job is taken.
        h.offer(Job {
            snapshot: w.snapshot(),
            frame_rate: 1.0,
        });
        h.close();
        assert!(h.recv().is_some());
        assert!(h.recv().is_none());
    }
}
