//! Samples of many traces at a few chosen frames, read in one pass.
//!
//! The steps after the session that weigh a few samples against their
//! neighbours (`lone.rs`, `stray.rs`) need each trace's positions at a
//! handful of frames. Traces are stored compressed and decode in frame
//! order only, so the frames wanted are gathered first, each trace is
//! decoded once up to the last of them, and the samples are looked up
//! here by binary search.

use glam::DVec3;

use crate::model::trace::Trace;

/// Every trace's samples at the frames a few samples are weighed at,
/// in frame order: the traces are stored compressed and decoded in
/// order, so the samples wanted are read in one pass and looked up here.
pub(super) struct Places(Vec<Vec<(i64, DVec3)>>);

impl Places {
    /// Each trace's samples at its own `frames` (sorted, one list per
    /// trace), each trace decoded up to the last of its own only and
    /// those with none not at all.
    pub(super) fn at_frames(traces: &[Trace], frames: &[Vec<i64>]) -> Places {
        Places(
            traces
                .iter()
                .zip(frames)
                .map(|(t, mine)| read(t, mine))
                .collect(),
        )
    }

    /// Every trace's samples at the same `frames` (sorted).
    pub(super) fn shared(traces: &[Trace], frames: &[i64]) -> Places {
        Places(traces.iter().map(|t| read(t, frames)).collect())
    }

    /// How many traces it holds.
    pub(super) fn len(&self) -> usize {
        self.0.len()
    }

    /// Where trace `k` was measured at frame `f`, if it was.
    pub(super) fn at(&self, k: usize, f: i64) -> Option<DVec3> {
        let v = &self.0[k];
        v.binary_search_by_key(&f, |s| s.0).ok().map(|i| v[i].1)
    }
}

/// `t`'s samples at `frames` (sorted), decoded up to the last of them.
fn read(t: &Trace, frames: &[i64]) -> Vec<(i64, DVec3)> {
    let Some(&last) = frames.last() else {
        return Vec::new();
    };
    t.measurements()
        .take_while(|s| s.0 <= last)
        .filter(|s| frames.binary_search(&s.0).is_ok())
        .collect()
}
