//! Rate-limited warnings: a flood of bad datagrams gives a few log lines,
//! not one per datagram.
//!
//! Each kind of warning ("osc: not OSC", "http: refused") has a window
//! (10 s by default). The first warning of a window is logged; the rest are
//! counted, and when the window is over the count is logged as
//! "… and N more like this in the last 10 s". The summary comes with the
//! next warning of that kind, or from [`LogThrottle::flush`], which the
//! owner calls on a timer and at shutdown so that a flood that stops still
//! gets its count.

use std::collections::HashMap;
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// How long one window of a kind lasts: long enough that a flood costs two
/// lines per kind every 10 s, short enough that a user watching the log
/// sees a new problem within that time.
pub const WINDOW: Duration = Duration::from_secs(10);

/// One kind's window.
#[derive(Debug, Clone, Copy)]
struct Window {
    /// When the first (logged) warning of the window came.
    started: Instant,
    /// Warnings counted but not logged since.
    suppressed: u64,
}

/// Warnings of several kinds, each logged at most once per window. Shared by
/// reference: the lock is held only to update a counter.
#[derive(Debug)]
pub struct LogThrottle {
    window: Duration,
    kinds: Mutex<HashMap<&'static str, Window>>,
}

impl Default for LogThrottle {
    fn default() -> Self {
        LogThrottle::new(WINDOW)
    }
}

impl LogThrottle {
    /// A throttle with windows of `window`.
    pub fn new(window: Duration) -> Self {
        LogThrottle {
            window,
            kinds: Mutex::new(HashMap::new()),
        }
    }

    /// Logs `message()` at warn level unless a warning of `kind` was logged
    /// in the current window, in which case it is only counted. `message` is
    /// only called when the line is written, so a suppressed warning costs
    /// no formatting.
    pub fn warn(&self, kind: &'static str, message: impl FnOnce() -> String) {
        self.warn_at(kind, Instant::now(), message);
    }

    /// [`warn`](Self::warn) at a given time; true when the warning was
    /// written rather than counted.
    pub fn warn_at(
        &self,
        kind: &'static str,
        now: Instant,
        message: impl FnOnce() -> String,
    ) -> bool {
        let (summary, log) = {
            let mut kinds = self.kinds.lock().unwrap_or_else(|p| p.into_inner());
            match kinds.get_mut(kind) {
                Some(w) if now.duration_since(w.started) < self.window => {
                    w.suppressed += 1;
                    (0, false)
                }
                Some(w) => {
                    let n = w.suppressed;
                    *w = Window {
                        started: now,
                        suppressed: 0,
                    };
                    (n, true)
                }
                None => {
                    kinds.insert(
                        kind,
                        Window {
                            started: now,
                            suppressed: 0,
                        },
                    );
                    (0, true)
                }
            }
        };
        if summary > 0 {
            tracing::warn!("{}", self.summary(kind, summary));
        }
        if log {
            tracing::warn!("{}", message());
        }
        log
    }

    /// Logs the counts of every window that is over; call it on a timer.
    pub fn flush(&self) {
        self.flush_at(Instant::now(), false);
    }

    /// Logs every count still pending, over or not (at shutdown).
    pub fn finish(&self) {
        self.flush_at(Instant::now(), true);
    }

    /// The summaries [`flush`](Self::flush) would log at `now`, as lines (for tests).
    pub fn flush_at(&self, now: Instant, all: bool) -> Vec<String> {
        let mut lines = Vec::new();
        {
            let mut kinds = self.kinds.lock().unwrap_or_else(|p| p.into_inner());
            kinds.retain(|kind, w| {
                let over = now.duration_since(w.started) >= self.window;
                if w.suppressed > 0 && (over || all) {
                    lines.push(self.summary(kind, w.suppressed));
                    w.suppressed = 0;
                }
                // A window that is over and counted nothing can go: the
                // next warning of its kind is logged at once anyway.
                !(over && w.suppressed == 0)
            });
        }
        for l in &lines {
            tracing::warn!("{l}");
        }
        lines
    }

    fn summary(&self, kind: &str, n: u64) -> String {
        format!(
            "{kind}: … and {n} more like this in the last {} s",
            self.window.as_secs()
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_flood_is_one_line_and_a_count_per_window() {
        let t = LogThrottle::new(Duration::from_secs(10));
        let t0 = Instant::now();
        let mut logged = 0;
        for i in 0..20_000u64 {
            // 20 000 warnings over 5 s.
            let now = t0 + Duration::from_micros(i * 250);
            logged += t.warn_at("osc: not OSC", now, String::new) as u32;
        }
        assert_eq!(logged, 1);
        assert!(t.flush_at(t0 + Duration::from_secs(6), false).is_empty());
        assert_eq!(
            t.flush_at(t0 + Duration::from_secs(10), false),
            ["osc: not OSC: … and 19999 more like this in the last 10 s"]
        );
        // Counted once only; the next warning starts a new window.
        assert!(t.flush_at(t0 + Duration::from_secs(11), false).is_empty());
        assert!(t.warn_at("osc: not OSC", t0 + Duration::from_secs(12), String::new));
    }

    #[test]
    fn kinds_are_counted_apart_and_finish_reports_the_rest() {
        let t = LogThrottle::new(Duration::from_secs(10));
        let t0 = Instant::now();
        for _ in 0..3 {
            t.warn_at("a", t0, String::new);
            t.warn_at("b", t0, String::new);
        }
        t.warn_at("b", t0, String::new);
        let mut lines = t.flush_at(t0 + Duration::from_secs(1), true);
        lines.sort();
        assert_eq!(
            lines,
            [
                "a: … and 2 more like this in the last 10 s",
                "b: … and 3 more like this in the last 10 s"
            ]
        );
    }
}
