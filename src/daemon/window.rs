//! The recent frames the daemon analyses: the last `span_s` seconds, kept
//! as shared immutable chunks so that handing them to the analysis costs a
//! handful of reference counts, not a copy.
//!
//! Why chunks: the analysis runs on its own thread over a minute of frames
//! (up to 60 000 frames × 100 markers, or 21 600 × 1 000) while the window
//! keeps filling. Copying the window for it cost the pipeline more than a
//! frame's budget and dropped frames (issue 15). Frames go into an open
//! chunk; a chunk is sealed (frozen behind an `Arc`) when it is full or when
//! a snapshot is taken, and old chunks are released once all of their
//! frames are older than the span and no snapshot holds them. Markers of a
//! chunk sit in one flat array: one allocation per chunk, not per frame.
//! Memory stays flat however long the daemon runs.

use std::collections::VecDeque;
use std::sync::Arc;

use crate::model::frame::{Marker, MarkerFrame};

/// A chunk is sealed at this many frames (a quarter second at 1 000 Hz)…
const CHUNK_FRAMES: usize = 256;
/// …or when its markers would not fit this many (640 kB): chunks are
/// allocated once at this size and never grow, so the pipeline never copies
/// a large buffer in the middle of a frame.
const CHUNK_SAMPLES: usize = 16_384;

/// The per-frame fields of a frame kept in a chunk.
#[derive(Debug, Clone, Copy)]
struct Head {
    frame: i64,
    time_s: f64,
    latency_s: Option<f64>,
    /// End of this frame's markers in the chunk's `markers`.
    end: usize,
}

/// A run of consecutive frames, immutable once sealed.
#[derive(Debug, Default)]
struct Chunk {
    heads: Vec<Head>,
    markers: Vec<Marker>,
}

impl Chunk {
    fn markers_of(&self, i: usize) -> &[Marker] {
        let start = if i == 0 { 0 } else { self.heads[i - 1].end };
        &self.markers[start..self.heads[i].end]
    }

    /// Frame `i` of the chunk into `out` (its marker buffer reused).
    fn read_into(&self, i: usize, out: &mut MarkerFrame) {
        let h = self.heads[i];
        out.frame = h.frame;
        out.time_s = h.time_s;
        out.latency_s = h.latency_s;
        out.markers.clear();
        out.markers.extend_from_slice(self.markers_of(i));
    }
}

/// The last `span_s` seconds of frames.
#[derive(Debug)]
pub struct FrameWindow {
    span_s: f64,
    /// Sealed chunks, oldest first.
    sealed: VecDeque<Arc<Chunk>>,
    /// The chunk being filled.
    open: Chunk,
    /// Frames of the oldest chunk (sealed, or else the open one) that have
    /// left the span.
    skip: usize,
    /// Frames and marker samples inside the span.
    frames: usize,
    samples: usize,
    /// Counts restarts of the source: a snapshot's epoch tells which run of
    /// frames it belongs to.
    epoch: u64,
    first_time: Option<f64>,
    last: Option<(i64, f64)>,
}

/// The window at one instant, shared with the window itself: cheap to make
/// and to send, immutable, read on another thread.
#[derive(Debug, Clone)]
pub struct WindowSnapshot {
    chunks: Vec<Arc<Chunk>>,
    /// Frames to skip in the first chunk (older than the span).
    skip: usize,
    /// Frames and marker samples in the snapshot.
    pub frames: usize,
    /// Marker samples in the snapshot.
    pub samples: usize,
    /// The window's epoch (restarts of the source) when it was taken.
    pub epoch: u64,
    /// Time of the newest frame.
    pub now_s: f64,
}

impl FrameWindow {
    /// An empty window keeping `span_s` seconds of frames (`daemon.window_s`).
    pub fn new(span_s: f64) -> Self {
        FrameWindow {
            span_s,
            sealed: VecDeque::new(),
            open: Chunk::default(),
            skip: 0,
            frames: 0,
            samples: 0,
            epoch: 0,
            first_time: None,
            last: None,
        }
    }

    /// Adds a frame. A frame whose time or number goes back (a restarted
    /// source) starts the window afresh: traces must not run across a restart.
    pub fn push(&mut self, frame: &MarkerFrame) {
        if self
            .last
            .is_some_and(|(n, t)| frame.time_s < t || frame.frame <= n)
        {
            *self = FrameWindow {
                epoch: self.epoch + 1,
                ..FrameWindow::new(self.span_s)
            };
        }
        self.last = Some((frame.frame, frame.time_s));
        let n = frame.markers.len();
        let open = &self.open;
        if !open.heads.is_empty()
            && (open.heads.len() >= CHUNK_FRAMES
                || open.markers.len() + n > open.markers.capacity())
        {
            self.seal();
        }
        if self.open.heads.is_empty() {
            self.open.heads.reserve(CHUNK_FRAMES);
            self.open.markers.reserve(CHUNK_SAMPLES.max(n));
        }
        self.open.markers.extend_from_slice(&frame.markers);
        self.open.heads.push(Head {
            frame: frame.frame,
            time_s: frame.time_s,
            latency_s: frame.latency_s,
            end: self.open.markers.len(),
        });
        self.frames += 1;
        self.samples += n;
        self.trim(frame.time_s);
    }

    /// Freezes the open chunk (if it has frames) behind an `Arc`.
    fn seal(&mut self) {
        if self.open.heads.is_empty() {
            return;
        }
        let mut full = std::mem::take(&mut self.open);
        // A chunk sealed early by a snapshot gives back its unused space
        // (a copy of at most one chunk, once per analysis).
        if full.markers.capacity() > 2 * full.markers.len() + 1024 {
            full.markers.shrink_to_fit();
            full.heads.shrink_to_fit();
        }
        self.sealed.push_back(Arc::new(full));
    }

    /// Drops frames older than the span: chunk by chunk, the oldest chunk's
    /// leading frames by moving `skip`.
    fn trim(&mut self, now: f64) {
        loop {
            if self
                .sealed
                .front()
                .is_some_and(|c| self.skip >= c.heads.len())
            {
                self.sealed.pop_front();
                self.skip = 0;
                continue;
            }
            let oldest: &Chunk = match self.sealed.front() {
                Some(c) => c,
                None => &self.open,
            };
            let Some(h) = oldest.heads.get(self.skip) else {
                break;
            };
            if now - h.time_s <= self.span_s {
                self.first_time = Some(h.time_s);
                break;
            }
            let n = oldest.markers_of(self.skip).len();
            self.frames -= 1;
            self.samples -= n;
            self.skip += 1;
        }
    }

    /// A snapshot of the window: seals the open chunk and shares every
    /// chunk (reference counts only; no frame is copied).
    pub fn snapshot(&mut self) -> WindowSnapshot {
        self.seal();
        WindowSnapshot {
            chunks: self.sealed.iter().cloned().collect(),
            skip: self.skip,
            frames: self.frames,
            samples: self.samples,
            epoch: self.epoch,
            now_s: self.now_s(),
        }
    }

    /// Frames in the window.
    pub fn len(&self) -> usize {
        self.frames
    }

    /// True before the first frame (and right after a restart's reset).
    pub fn is_empty(&self) -> bool {
        self.frames == 0
    }

    /// Marker samples held, for the memory metric.
    pub fn samples(&self) -> usize {
        self.samples
    }

    /// Seconds covered.
    pub fn duration_s(&self) -> f64 {
        match (self.first_time, self.last) {
            (Some(a), Some((_, b))) if self.frames > 0 => b - a,
            _ => 0.0,
        }
    }

    /// Time of the newest frame.
    pub fn now_s(&self) -> f64 {
        self.last.map_or(0.0, |(_, t)| t)
    }

    /// Sealed chunks held (a snapshot shares exactly these).
    pub fn chunks(&self) -> usize {
        self.sealed.len()
    }
}

impl WindowSnapshot {
    /// Calls `each` with every frame in order; the frame passed is one
    /// buffer refilled each time, so reading allocates nothing per frame.
    pub fn for_each(&self, mut each: impl FnMut(&MarkerFrame)) {
        let mut frame = MarkerFrame::default();
        for (k, chunk) in self.chunks.iter().enumerate() {
            let from = if k == 0 { self.skip } else { 0 };
            for i in from..chunk.heads.len() {
                chunk.read_into(i, &mut frame);
                each(&frame);
            }
        }
    }

    /// Shares chunks with the window that made it (for tests of the hand-off).
    pub fn shares_with(&self, other: &WindowSnapshot) -> bool {
        self.chunks
            .iter()
            .any(|a| other.chunks.iter().any(|b| Arc::ptr_eq(a, b)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    fn frame(i: i64, dt: f64, markers: usize) -> MarkerFrame {
        MarkerFrame::new(
            i,
            i as f64 * dt,
            (0..markers)
                .map(|k| Marker::new(DVec3::new(i as f64, k as f64, 0.0)))
                .collect(),
        )
    }

    fn frames_of(s: &WindowSnapshot) -> Vec<MarkerFrame> {
        let mut out = Vec::new();
        s.for_each(|f| out.push(f.clone()));
        out
    }

    #[test]
    fn keeps_the_span_and_restarts_on_a_restart() {
        let mut w = FrameWindow::new(1.0);
        for i in 0..1000 {
            w.push(&frame(i, 0.01, 3));
        }
        assert_eq!(w.len(), 101);
        assert_eq!(w.samples(), 303);
        assert!((w.duration_s() - 1.0).abs() < 1e-9);
        let s = w.snapshot();
        let got = frames_of(&s);
        assert_eq!(got.len(), 101);
        assert_eq!((got[0].frame, got[100].frame), (899, 999));
        assert_eq!(got[100], frame(999, 0.01, 3));
        w.push(&MarkerFrame::new(0, 0.0, vec![]));
        assert_eq!((w.len(), w.samples()), (1, 0));
        let s2 = w.snapshot();
        assert_eq!(s2.epoch, s.epoch + 1);
        assert_eq!(frames_of(&s2).len(), 1);
        // The old snapshot is unchanged by the restart.
        assert_eq!(frames_of(&s).len(), 101);
    }

    #[test]
    fn snapshots_share_frames_and_memory_stays_bounded() {
        let mut w = FrameWindow::new(2.0);
        let mut last = None;
        for i in 0..20_000 {
            w.push(&frame(i, 0.001, 2));
            if i % 997 == 0 {
                let s = w.snapshot();
                assert_eq!(s.frames, w.len());
                assert_eq!(frames_of(&s).len(), s.frames);
                if let Some(prev) = &last {
                    assert!(s.shares_with(prev), "consecutive snapshots share chunks");
                }
                last = Some(s);
            }
        }
        assert_eq!(w.len(), 2001);
        // 2 s at 1 kHz in chunks of 256 frames, plus the ones sealed early by snapshots.
        assert!(w.chunks() <= 2001 / CHUNK_FRAMES + 4, "{}", w.chunks());
    }
}
