//! What an operator watches besides the counters: is the source sending,
//! and how far the still phase has got (bad input is `status.bad_input`).
//! Read by `/status` (and so the live page) and by the console.

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use serde::Serialize;

/// A source with no frame for this long is reported silent.
pub const SILENT_AFTER: Duration = Duration::from_secs(1);

/// Whether frames are coming in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Connection {
    /// No frame yet.
    Waiting,
    /// A frame within [`SILENT_AFTER`].
    Receiving,
    /// Frames came, then stopped.
    Silent,
}

/// Progress of a running daemon. Atomics and a short lock: the pipeline
/// never waits for a reader.
pub struct Progress {
    /// When the daemon started; frame arrivals are kept relative to it.
    started: Instant,
    /// Milliseconds after `started` of the last frame's arrival, +1 (0: none).
    last_frame_ms: AtomicU64,
    /// Length (s) of the still phase the last analysis found, f64 bits;
    /// NaN before the first analysis.
    still_bits: AtomicU64,
    /// The still phase the first tree needs (`daemon.rest_min_s`).
    needed_s: f64,
}

impl std::fmt::Debug for Progress {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Progress")
            .field("connection", &self.connection())
            .field("still_s", &self.still_s())
            .finish()
    }
}

impl Default for Progress {
    fn default() -> Self {
        Progress::new(0.0)
    }
}

impl Progress {
    /// A daemon whose first tree needs a still phase of `needed_s`.
    pub fn new(needed_s: f64) -> Self {
        Progress {
            started: Instant::now(),
            last_frame_ms: AtomicU64::new(0),
            still_bits: AtomicU64::new(f64::NAN.to_bits()),
            needed_s,
        }
    }

    /// A frame arrived now.
    pub fn frame_arrived(&self) {
        let ms = self.started.elapsed().as_millis() as u64 + 1;
        self.last_frame_ms.store(ms, Ordering::Relaxed);
    }

    /// The last analysis found a still phase of `still_s` (0 when none).
    pub fn set_still(&self, still_s: f64) {
        self.still_bits.store(still_s.to_bits(), Ordering::Relaxed);
    }

    /// Seconds since the last frame, `None` before the first.
    pub fn silent_s(&self) -> Option<f64> {
        let ms = self.last_frame_ms.load(Ordering::Relaxed);
        if ms == 0 {
            return None;
        }
        let now = self.started.elapsed().as_millis() as u64 + 1;
        Some(now.saturating_sub(ms) as f64 / 1000.0)
    }

    /// Whether frames are coming in.
    pub fn connection(&self) -> Connection {
        match self.silent_s() {
            None => Connection::Waiting,
            Some(s) if s <= SILENT_AFTER.as_secs_f64() => Connection::Receiving,
            Some(_) => Connection::Silent,
        }
    }

    /// The still phase found so far, `None` before the first analysis.
    pub fn still_s(&self) -> Option<f64> {
        let s = f64::from_bits(self.still_bits.load(Ordering::Relaxed));
        (!s.is_nan()).then_some(s)
    }

    /// The still phase the first tree needs.
    pub fn needed_s(&self) -> f64 {
        self.needed_s
    }

    /// The `/status` fields: `connection`, `still`.
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::json!({
            "connection": {"state": self.connection(), "silent_s": self.silent_s()},
            "still": {"still_s": self.still_s(), "needed_s": self.needed_s},
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn waiting_receiving_silent() {
        let p = Progress::new(5.0);
        assert_eq!(p.connection(), Connection::Waiting);
        assert_eq!(p.still_s(), None);
        p.frame_arrived();
        assert_eq!(p.connection(), Connection::Receiving);
        // A frame 2 s ago: silent.
        p.last_frame_ms.store(1, Ordering::Relaxed);
        let p = Progress {
            started: Instant::now() - Duration::from_secs(2),
            ..p
        };
        assert_eq!(p.connection(), Connection::Silent);
        p.set_still(3.25);
        let v = p.to_json();
        assert_eq!(v["still"]["still_s"], 3.25);
        assert_eq!(v["connection"]["state"], "silent");
    }
}
