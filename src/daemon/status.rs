//! The daemon's counters, read by `/status` (JSON) and `/metrics`
//! (Prometheus text). Atomics and short locks only: the pipeline never waits
//! for a reader.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;

use serde_json::json;

use super::progress::Progress;
use crate::model::wind::WindEstimate;

/// How the daemon asks the live source for its state (see
/// [`Status::source_state`]).
#[derive(Clone)]
pub struct SourceState(pub std::sync::Arc<dyn Fn() -> Option<String> + Send + Sync>);

impl std::fmt::Debug for SourceState {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_tuple("SourceState").field(&(self.0)()).finish()
    }
}

/// Shared counters of a running daemon.
#[derive(Debug, Default)]
pub struct Status {
    /// What the frames come from, as a user would name it
    /// (`natnet 192.168.1.10:1510`, `replay FILE at 1×`).
    pub source: Mutex<String>,
    /// Frames the pipeline has taken in.
    pub frames: AtomicU64,
    /// Marker samples in those frames.
    pub samples: AtomicU64,
    /// Markers in the latest frame.
    pub markers: AtomicU64,
    /// Tips seen in the latest frame.
    pub tips_live: AtomicU64,
    /// Tips of the current tree.
    pub tips: AtomicU64,
    /// Frames the bounded channel dropped (pipeline too slow).
    pub dropped: AtomicU64,
    /// Runs of the marker stage on the window.
    pub analyses: AtomicU64,
    /// Trees built and published.
    pub trees: AtomicU64,
    /// Frame time in f64 bits, so it fits an atomic.
    pub last_frame_time_bits: AtomicU64,
    /// The source's number of the latest frame.
    pub last_frame: AtomicU64,
    /// Frames per second of the source as measured (f64 bits).
    pub frame_rate_bits: AtomicU64,
    /// Version of the current tree (1, 2, …), as in the outputs.
    pub tree_version: AtomicU64,
    /// The last tree's report (version, trigger, nodes, forced joins, times).
    pub last_tree: Mutex<Option<serde_json::Value>>,
    /// The wind estimate currently used.
    pub wind: Mutex<Option<WindEstimate>>,
    /// The last error of an output (a disk refusing writes), cleared by the
    /// next success.
    pub output_error: Mutex<Option<String>>,
    /// Why the source stopped or cannot start (nothing listening, a bad file).
    pub source_error: Mutex<Option<String>>,
    /// The live source's own state in words, asked on each `/status`
    /// ("connected to Motive (NatNet 4.1) at …; frames fail to decode;
    /// renegotiating"): a server whose frames stopped decoding shows here
    /// while frames stop arriving. Unset for a replay.
    pub source_state: std::sync::OnceLock<SourceState>,
    /// The last failed config reload (SIGHUP), cleared by a good one.
    pub config_error: Mutex<Option<String>>,
    /// Per-frame latency in microseconds, from the frame's arrival (stamped
    /// by the source as it hands the decoded datagram over, so time queued
    /// in the channel counts) to its tips published.
    pub latency_us_last: AtomicU64,
    /// The largest of those latencies since the start (µs).
    pub latency_us_max: AtomicU64,
    /// Latency histogram: bucket k counts frames of k×10 to (k+1)×10 µs; the
    /// last bucket everything slower. Fixed size, so percentiles cost no
    /// memory however long the daemon runs.
    pub latency_hist: LatencyHistogram,
    /// Bad input of every listening socket, by source and kind.
    pub bad_input: super::counters::InputCounters,
    /// The recording's counters, once recording.
    pub recording: std::sync::OnceLock<std::sync::Arc<crate::app::recording::RecordingStats>>,
    /// Frames waiting in the channel behind the one just taken (the backlog).
    pub backlog_frames: AtomicU64,
    /// The largest backlog seen.
    pub backlog_max: AtomicU64,
    /// How long the frame just taken waited in the channel, and the longest
    /// wait seen (µs).
    pub queue_us_last: AtomicU64,
    /// The longest wait seen (µs).
    pub queue_us_max: AtomicU64,
    /// Source connection, still-phase progress and rejected input, for the
    /// live page and the console.
    pub progress: Progress,
}

/// Buckets of 10 µs up to 20 ms.
const BUCKETS: usize = 2000;
const BUCKET_US: u64 = 10;

/// A fixed histogram of per-frame latencies.
#[derive(Debug)]
pub struct LatencyHistogram(Vec<AtomicU64>);

impl Default for LatencyHistogram {
    fn default() -> Self {
        LatencyHistogram((0..BUCKETS).map(|_| AtomicU64::new(0)).collect())
    }
}

impl LatencyHistogram {
    /// Counts one frame's latency (µs); anything beyond 20 ms goes to the
    /// last bucket.
    pub fn record(&self, us: u64) {
        let k = ((us / BUCKET_US) as usize).min(BUCKETS - 1);
        self.0[k].fetch_add(1, Ordering::Relaxed);
    }

    /// The latency (µs, upper bucket edge) below which a fraction `q` of frames fell.
    pub fn quantile_us(&self, q: f64) -> Option<u64> {
        let counts: Vec<u64> = self.0.iter().map(get).collect();
        let total: u64 = counts.iter().sum();
        if total == 0 {
            return None;
        }
        let want = (q * total as f64).ceil() as u64;
        let mut seen = 0;
        for (k, c) in counts.iter().enumerate() {
            seen += c;
            if seen >= want {
                return Some((k as u64 + 1) * BUCKET_US);
            }
        }
        Some(BUCKETS as u64 * BUCKET_US)
    }
}

fn get(a: &AtomicU64) -> u64 {
    a.load(Ordering::Relaxed)
}

/// One metric of `/metrics`, read from the status when scraped.
struct Metric {
    /// Its name after `treemocap_`.
    name: &'static str,
    /// `counter` or `gauge`.
    kind: &'static str,
    /// The `# HELP` text.
    help: &'static str,
    /// Its current value.
    value: fn(&Status) -> f64,
}

/// The daemon's own metrics, in the order `/metrics` lists them (the bad
/// input and recording counters follow).
const METRICS: [Metric; 11] = [
    Metric {
        name: "frames_total",
        kind: "counter",
        help: "Frames received from the source.",
        value: |s| get(&s.frames) as f64,
    },
    Metric {
        name: "marker_samples_total",
        kind: "counter",
        help: "Marker samples received.",
        value: |s| get(&s.samples) as f64,
    },
    Metric {
        name: "frames_dropped_total",
        kind: "counter",
        help: "Frames dropped because the pipeline fell behind.",
        value: |s| get(&s.dropped) as f64,
    },
    Metric {
        name: "markers",
        kind: "gauge",
        help: "Markers in the latest frame.",
        value: |s| get(&s.markers) as f64,
    },
    Metric {
        name: "tips",
        kind: "gauge",
        help: "Tips of the current tree.",
        value: |s| get(&s.tips) as f64,
    },
    Metric {
        name: "tips_live",
        kind: "gauge",
        help: "Tips seen in the latest frame.",
        value: |s| get(&s.tips_live) as f64,
    },
    Metric {
        name: "analyses_total",
        kind: "counter",
        help: "Analyses of the recent frames.",
        value: |s| get(&s.analyses) as f64,
    },
    Metric {
        name: "trees_total",
        kind: "counter",
        help: "Trees built.",
        value: |s| get(&s.trees) as f64,
    },
    Metric {
        name: "backlog_frames",
        kind: "gauge",
        help: "Frames waiting between the source and the pipeline.",
        value: |s| get(&s.backlog_frames) as f64,
    },
    Metric {
        name: "frame_latency_seconds_max",
        kind: "gauge",
        help: "Longest time from frame arrival to tips published.",
        value: |s| get(&s.latency_us_max) as f64 * 1e-6,
    },
    Metric {
        name: "output_errors",
        kind: "gauge",
        help: "1 while an output cannot be written.",
        value: |s| {
            s.output_error
                .lock()
                .map(|e| e.is_some() as u8 as f64)
                .unwrap_or(0.0)
        },
    },
];

impl Status {
    /// Records the channel's state as the pipeline takes a frame: `waiting`
    /// frames behind it, after it waited `wait`.
    pub fn record_backlog(&self, waiting: usize, wait: std::time::Duration) {
        let us = wait.as_micros() as u64;
        self.backlog_frames.store(waiting as u64, Ordering::Relaxed);
        self.backlog_max
            .fetch_max(waiting as u64, Ordering::Relaxed);
        self.queue_us_last.store(us, Ordering::Relaxed);
        self.queue_us_max.fetch_max(us, Ordering::Relaxed);
    }

    /// Time of the latest frame (s): the daemon's session clock.
    pub fn frame_time(&self) -> f64 {
        f64::from_bits(get(&self.last_frame_time_bits))
    }

    /// The `/status` document.
    pub fn to_json(&self) -> serde_json::Value {
        let wind = self.wind.lock().ok().and_then(|w| *w).map(|w| {
            json!({
                "source": w.source.name(),
                "azimuth_deg": w.azimuth_deg(),
                "direction": [w.direction.x, w.direction.y, w.direction.z],
                "speed_m_s": w.speed_m_s,
                "time_s": w.time_s,
            })
        });
        let mut doc = json!({
            "source": self.source.lock().map(|s| s.clone()).unwrap_or_default(),
            "source_error": self.source_error.lock().ok().and_then(|e| e.clone()),
            "source_state": self.source_state.get().and_then(|s| (s.0)()),
            "config_error": self.config_error.lock().ok().and_then(|e| e.clone()),
            "frames": get(&self.frames),
            "samples": get(&self.samples),
            "last_frame": get(&self.last_frame),
            "time_s": self.frame_time(),
            "frame_rate_hz": f64::from_bits(get(&self.frame_rate_bits)),
            "markers": get(&self.markers),
            "tips": get(&self.tips),
            "tips_live": get(&self.tips_live),
            "dropped": get(&self.dropped),
            "analyses": get(&self.analyses),
            "trees": get(&self.trees),
            "tree_version": get(&self.tree_version),
            "last_tree": self.last_tree.lock().ok().and_then(|t| t.clone()),
            "wind": wind,
            "output_error": self.output_error.lock().ok().and_then(|e| e.clone()),
            "backlog": {
                "frames": get(&self.backlog_frames),
                "max_frames": get(&self.backlog_max),
                "wait_us": get(&self.queue_us_last),
                "max_wait_us": get(&self.queue_us_max),
            },
            "latency_us": {
                "last": get(&self.latency_us_last),
                "p50": self.latency_hist.quantile_us(0.5),
                "p99": self.latency_hist.quantile_us(0.99),
                "max": get(&self.latency_us_max),
            },
            "bad_input": self.bad_input.to_json(),
            "recording": super::counters::recording_json(self.recording.get()),
        });
        if let (Some(doc), serde_json::Value::Object(more)) =
            (doc.as_object_mut(), self.progress.to_json())
        {
            doc.extend(more);
        }
        doc
    }

    /// The `/metrics` text (Prometheus exposition format 0.0.4).
    pub fn to_prometheus(&self) -> String {
        let mut out = String::new();
        for m in &METRICS {
            let (name, kind, help) = (m.name, m.kind, m.help);
            let value = (m.value)(self);
            out.push_str(&format!(
                "# HELP treemocap_{name} {help}\n# TYPE treemocap_{name} {kind}\ntreemocap_{name} {value}\n"
            ));
        }
        self.bad_input.to_prometheus(&mut out);
        super::counters::recording_prometheus(self.recording.get(), &mut out);
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles_from_the_histogram() {
        let h = LatencyHistogram::default();
        assert_eq!(h.quantile_us(0.99), None);
        for us in 0..1000 {
            h.record(us);
        }
        h.record(1_000_000);
        assert_eq!(h.quantile_us(0.5), Some(510));
        assert_eq!(h.quantile_us(0.99), Some(1000));
        assert_eq!(h.quantile_us(1.0), Some(20_000));
    }
}
