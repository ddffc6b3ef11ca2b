//! What the daemon lost and refused, for `/status` and `/metrics`:
//! - bad input per source and kind: every socket the daemon listens on
//!   registers how to read its counts, and both documents list them with
//!   the same kinds ([`BadInputKind`]), zeros included, so that a user can
//!   tell a quiet network from a hostile one;
//! - the recording's files and lost frames (a full disk), and the summary
//!   logged at shutdown.

use std::path::Path;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use serde_json::{json, Map, Value};

use crate::app::recording::{Recorder, RecordingStats};
use crate::error::Result;
use crate::format::log::LogHeader;
use crate::serve::limits::HttpLimits;
use crate::source::allow::AllowList;
use crate::source::bad_input::{BadInput, BadInputKind};

/// The HTTP server's limits from the `[daemon]` settings, and its bad-input
/// counters, registered on `status` as "http".
pub(crate) fn http_limits(
    d: &crate::config::DaemonConfig,
    bad_input: &InputCounters,
) -> Result<(HttpLimits, Arc<BadInput>)> {
    let limits = HttpLimits {
        allow: AllowList::parse("daemon.http_allow", &d.http_allow)?,
        max_connections: d.http_max_connections as usize,
        max_websockets: d.http_max_websockets as usize,
        header_timeout: Duration::from_secs_f64(d.http_header_timeout_s),
        idle_timeout: Duration::from_secs_f64(d.http_idle_timeout_s),
    };
    let bad = Arc::new(BadInput::default());
    let b = bad.clone();
    bad_input.register("http", Arc::new(move || b.counts()));
    Ok((limits, bad))
}

/// Starts the daemon's recording, `OUT/session.log.csv` (then
/// `session-2.log.csv`, … after a failed write), its counters on `status`.
pub(crate) fn start_recording(
    out: &Path,
    flush_interval_s: f64,
    recording: &std::sync::OnceLock<Arc<RecordingStats>>,
    header: LogHeader,
) -> Result<Recorder> {
    let stats = Arc::new(RecordingStats::default());
    let _ = recording.set(stats.clone());
    Recorder::create(
        &out.join("session.log.csv"),
        header,
        Duration::from_secs_f64(flush_interval_s),
        stats,
    )
}

/// Ends the recording and logs its summary: a warning when frames were
/// lost, so that it shows at the default log level.
pub(crate) fn finish_recording(recorder: Recorder) {
    let counts = recorder.finish();
    if counts.frames_lost > 0 {
        tracing::warn!("{counts}");
    } else {
        tracing::info!("{counts}");
    }
}

/// The `recording` object of `/status` (`null` when not recording).
pub(crate) fn recording_json(stats: Option<&Arc<RecordingStats>>) -> Value {
    match stats.map(|s| s.snapshot()) {
        Some(c) => json!(c),
        None => Value::Null,
    }
}

/// The recording's lines of `/metrics`.
pub(crate) fn recording_prometheus(stats: Option<&Arc<RecordingStats>>, out: &mut String) {
    let Some(c) = stats.map(|s| s.snapshot()) else {
        return;
    };
    for (name, kind, help, value) in [
        (
            "recording_frames_written_total",
            "counter",
            "Frames written to the recording.",
            c.frames_written,
        ),
        (
            "recording_frames_lost_total",
            "counter",
            "Frames lost because writes failed (a full disk).",
            c.frames_lost,
        ),
        (
            "recording_files",
            "gauge",
            "Files of the recording (a new one after each failed write).",
            c.files,
        ),
        (
            "recording_failing",
            "gauge",
            "1 while recording writes fail.",
            c.failing as u64,
        ),
    ] {
        out.push_str(&format!(
            "# HELP treemocap_{name} {help}\n# TYPE treemocap_{name} {kind}\ntreemocap_{name} {value}\n"
        ));
    }
}

/// How to read one source's counts: (kind, count) pairs.
pub type ReadCounts = Arc<dyn Fn() -> Vec<(String, u64)> + Send + Sync>;

/// The daemon's sources of bad-input counts, by name ("osc", "natnet",
/// "osc_control", "http").
#[derive(Default)]
pub struct InputCounters {
    sources: Mutex<Vec<(String, ReadCounts)>>,
}

impl std::fmt::Debug for InputCounters {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_map().entries(self.read()).finish()
    }
}

impl InputCounters {
    /// Adds a source; `read` is called for every `/status` and `/metrics`.
    pub fn register(&self, name: &str, read: ReadCounts) {
        if let Ok(mut s) = self.sources.lock() {
            s.push((name.to_string(), read));
        }
    }

    /// Every source's counts: the common kinds first (zero when a source
    /// has no such counter), then whatever else the source counts.
    pub fn read(&self) -> Vec<(String, Vec<(String, u64)>)> {
        let sources: Vec<(String, ReadCounts)> =
            self.sources.lock().map(|s| s.clone()).unwrap_or_default();
        sources
            .into_iter()
            .map(|(name, read)| {
                let own = read();
                let mut counts: Vec<(String, u64)> = BadInputKind::ALL
                    .iter()
                    .map(|k| {
                        let n = own.iter().find(|(n, _)| n == k.name()).map_or(0, |c| c.1);
                        (k.name().to_string(), n)
                    })
                    .collect();
                for (kind, n) in own {
                    if !counts.iter().any(|(k, _)| *k == kind) {
                        counts.push((kind, n));
                    }
                }
                (name, counts)
            })
            .collect()
    }

    /// `{"osc": {"invalid": 0, …}, …}`: `bad_input` of `/status`.
    pub fn to_json(&self) -> Value {
        let mut all = Map::new();
        for (name, counts) in self.read() {
            let mut one = Map::new();
            for (kind, n) in counts {
                one.insert(kind, json!(n));
            }
            all.insert(name, Value::Object(one));
        }
        Value::Object(all)
    }

    /// `treemocap_bad_input_total{source="osc",kind="invalid"} 0` lines.
    pub fn to_prometheus(&self, out: &mut String) {
        out.push_str(
            "# HELP treemocap_bad_input_total Input rejected, by listening source and kind.\n\
             # TYPE treemocap_bad_input_total counter\n",
        );
        for (name, counts) in self.read() {
            for (kind, n) in counts {
                out.push_str(&format!(
                    "treemocap_bad_input_total{{source=\"{name}\",kind=\"{kind}\"}} {n}\n"
                ));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn common_kinds_always_then_the_source_own() {
        let c = InputCounters::default();
        c.register(
            "natnet",
            Arc::new(|| vec![("invalid".into(), 3), ("reconnects".into(), 1)]),
        );
        let v = c.to_json();
        assert_eq!(v["natnet"]["invalid"], 3);
        assert_eq!(v["natnet"]["wrong_sender"], 0);
        assert_eq!(v["natnet"]["reconnects"], 1);
        let mut text = String::new();
        c.to_prometheus(&mut text);
        assert!(text.contains("treemocap_bad_input_total{source=\"natnet\",kind=\"invalid\"} 3\n"));
        assert!(text.contains("{source=\"natnet\",kind=\"failed_decode\"} 0\n"));
    }
}
