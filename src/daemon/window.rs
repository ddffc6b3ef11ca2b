//! The recent frames the daemon analyses: a ring buffer trimmed to a time
//! span, so memory stays flat however long the daemon runs, readable as a
//! `Recording` so the very same marker stage as for replays runs on it.

use std::collections::VecDeque;

use crate::error::Result;
use crate::model::frame::MarkerFrame;
use crate::model::recording::{Format, Recording, RecordingInfo};

/// The last `span_s` seconds of frames.
#[derive(Debug, Clone)]
pub struct FrameWindow {
    span_s: f64,
    frames: VecDeque<MarkerFrame>,
    /// Marker samples held, for the memory metric.
    samples: usize,
}

impl FrameWindow {
    /// An empty window keeping `span_s` seconds of frames (`daemon.window_s`).
    pub fn new(span_s: f64) -> Self {
        FrameWindow {
            span_s,
            frames: VecDeque::new(),
            samples: 0,
        }
    }

    /// Adds a frame. A frame whose time goes back (a restarted source)
    /// starts the window afresh: traces must not run across a restart.
    pub fn push(&mut self, frame: MarkerFrame) {
        if self
            .frames
            .back()
            .is_some_and(|last| frame.time_s < last.time_s || frame.frame <= last.frame)
        {
            self.frames.clear();
            self.samples = 0;
        }
        self.samples += frame.markers.len();
        let now = frame.time_s;
        self.frames.push_back(frame);
        while self
            .frames
            .front()
            .is_some_and(|f| now - f.time_s > self.span_s)
        {
            if let Some(f) = self.frames.pop_front() {
                self.samples -= f.markers.len();
            }
        }
    }

    /// Frames held.
    pub fn len(&self) -> usize {
        self.frames.len()
    }

    /// True before the first frame and after a restart of the source.
    pub fn is_empty(&self) -> bool {
        self.frames.is_empty()
    }

    /// Marker samples held: what the window costs in memory.
    pub fn samples(&self) -> usize {
        self.samples
    }

    /// Seconds covered.
    pub fn duration_s(&self) -> f64 {
        match (self.frames.front(), self.frames.back()) {
            (Some(a), Some(b)) => b.time_s - a.time_s,
            _ => 0.0,
        }
    }

    /// Time of the newest frame.
    pub fn now_s(&self) -> f64 {
        self.frames.back().map_or(0.0, |f| f.time_s)
    }

    /// A copy of the frames as a recording (the analysis runs on another
    /// thread while the window keeps filling).
    pub fn to_recording(&self, frame_rate: f64, source: &str) -> WindowRecording {
        WindowRecording {
            frames: self.frames.iter().cloned().collect::<Vec<_>>().into_iter(),
            info: RecordingInfo {
                format: Format::Log,
                version: "live".into(),
                frame_rate,
                units: "m".into(),
                up_axis: "Y".into(),
                source: source.to_string(),
            },
        }
    }
}

/// Frames of a window, replayed as a `Recording`.
pub struct WindowRecording {
    frames: std::vec::IntoIter<MarkerFrame>,
    info: RecordingInfo,
}

impl Iterator for WindowRecording {
    type Item = Result<MarkerFrame>;
    fn next(&mut self) -> Option<Self::Item> {
        self.frames.next().map(Ok)
    }
}

impl Recording for WindowRecording {
    fn info(&self) -> &RecordingInfo {
        &self.info
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::frame::Marker;
    use glam::DVec3;

    #[test]
    fn keeps_the_span_and_restarts_on_a_restart() {
        let mut w = FrameWindow::new(1.0);
        for i in 0..1000 {
            w.push(MarkerFrame::new(
                i,
                i as f64 * 0.01,
                vec![Marker::new(DVec3::ZERO); 3],
            ));
        }
        assert_eq!(w.len(), 101);
        assert_eq!(w.samples(), 303);
        assert!((w.duration_s() - 1.0).abs() < 1e-9);
        w.push(MarkerFrame::new(0, 0.0, vec![]));
        assert_eq!((w.len(), w.samples()), (1, 0));
        let rec = w.to_recording(100.0, "test");
        assert_eq!(rec.count(), 1);
    }
}
