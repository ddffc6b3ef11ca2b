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
    /// Per-frame latency in microseconds, from the frame's arrival (the
    /// NatNet client stamps it when `recv` returns the datagram, so decoding
    /// and time queued in the channel count) to its tips published.
    pub latency_us_last: AtomicU64,
    /// The largest of those latencies since the start (µs).
    pub latency_us_max: AtomicU64,
    /// Their sum (µs), for the Prometheus histogram's `_sum`.
    pub latency_us_sum: AtomicU64,
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
    /// How long the frame just taken waited since it arrived (decoding and
    /// the channel), and the longest wait seen (µs).
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

    /// Frames at or below each of `edges_us` (cumulative, as Prometheus
    /// buckets count), and all frames. An edge falls on a 10 µs bucket
    /// edge, so the counts are exact.
    fn cumulative(&self, edges_us: &[u64]) -> (Vec<u64>, u64) {
        let mut out = Vec::with_capacity(edges_us.len());
        let mut seen = 0;
        let mut k = 0;
        for &edge in edges_us {
            let last = ((edge / BUCKET_US) as usize).min(BUCKETS - 1);
            while k < last {
                seen += get(&self.0[k]);
                k += 1;
            }
            out.push(seen);
        }
        let total = seen + self.0[k..].iter().map(get).sum::<u64>();
        (out, total)
    }

    /// The histogram as Prometheus exposition text: buckets every 100 µs up
    /// to 2 ms (where a 1 ms target is decided), then 5, 10 and 20 ms. A
    /// scraper takes the latency of any period from two scrapes' difference,
    /// `histogram_quantile(0.99, rate(..._bucket[5m]))` in PromQL.
    fn to_prometheus(&self, sum_us: u64, out: &mut String) {
        let edges: Vec<u64> = (1..=20)
            .map(|k| k * 100)
            .chain([5000, 10_000, 20_000])
            .collect();
        let (counts, total) = self.cumulative(&edges);
        let name = "treemocap_frame_latency_seconds";
        out.push_str(&format!(
            "# HELP {name} Time from a frame's arrival to its tips published.\n# TYPE {name} histogram\n"
        ));
        for (edge, count) in edges.iter().zip(&counts) {
            let le = *edge as f64 / 1e6;
            out.push_str(&format!("{name}_bucket{{le=\"{le}\"}} {count}\n"));
        }
        out.push_str(&format!("{name}_bucket{{le=\"+Inf\"}} {total}\n"));
        out.push_str(&format!("{name}_sum {}\n", sum_us as f64 * 1e-6));
        out.push_str(&format!("{name}_count {total}\n"));
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
        self.latency_hist
            .to_prometheus(get(&self.latency_us_sum), &mut out);
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

    /// `/metrics` buckets count the frames at or below their edge, and the
    /// last counts them all.
    #[test]
    fn prometheus_buckets_are_cumulative() {
        let h = LatencyHistogram::default();
        for us in [50, 99, 100, 150, 990, 1000, 1999, 30_000] {
            h.record(us);
        }
        let mut out = String::new();
        h.to_prometheus(12_345, &mut out);
        let bucket = |le: &str| -> u64 {
            let key = format!("treemocap_frame_latency_seconds_bucket{{le=\"{le}\"}} ");
            let line = out.lines().find(|l| l.starts_with(&key)).expect(le);
            line[key.len()..].parse().unwrap()
        };
        // Buckets hold [k×10, (k+1)×10) µs: 100 µs lies above le=0.0001.
        assert_eq!(bucket("0.0001"), 2);
        assert_eq!(bucket("0.001"), 5);
        assert_eq!(bucket("0.002"), 7);
        assert_eq!(bucket("0.02"), 7);
        assert_eq!(bucket("+Inf"), 8);
        assert!(out.contains("treemocap_frame_latency_seconds_sum 0.012345\n"));
        assert!(out.contains("treemocap_frame_latency_seconds_count 8\n"));
    }
}
