//! A recording that survives a full disk. Frames go to a treemocap log
//! ([`LogWriter`]); when a write fails, that file is cut back to its last
//! whole frame and closed, frames that come while writes fail are counted
//! as lost, and once a second a new numbered file (`session-2.log.csv`, …)
//! is tried; when space returns it starts with its own header. Nothing is
//! ever spliced into a file that failed, so every file reads back whole.
//!
//! Used by `treemocap record` and the daemon; the counters are shared so
//! that `/status` and `/metrics` show them while it runs.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use serde::Serialize;

use crate::error::{Error, Result};
use crate::format::log::{LogHeader, LogWriter};
use crate::model::frame::MarkerFrame;

/// How often a new file is tried while writes fail: often enough that little
/// more is lost once space returns, rarely enough to cost nothing meanwhile.
const RETRY: Duration = Duration::from_secs(1);

/// Live counters of a recording, read by `/status` and `/metrics`.
#[derive(Debug, Default)]
pub struct RecordingStats {
    /// Frames handed to the OS whole, over all files.
    pub frames_written: AtomicU64,
    /// Frames lost because writes failed: cut from a failed file, or come
    /// while no file could be written.
    pub frames_lost: AtomicU64,
    /// Files started (1 until a write fails and a new one starts).
    pub files: AtomicU64,
    /// True while writes fail.
    pub failing: AtomicBool,
    /// The file being written (or last written) and the last write error.
    detail: Mutex<(PathBuf, Option<String>)>,
}

/// A copy of [`RecordingStats`] at one instant; also the shutdown summary.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize)]
pub struct RecordingCounts {
    /// The file being written, or the last one.
    pub file: PathBuf,
    /// Files started.
    pub files: u64,
    /// Frames handed to the OS whole, over all files.
    pub frames_written: u64,
    /// Frames lost because writes failed.
    pub frames_lost: u64,
    /// True while writes fail.
    pub failing: bool,
    /// The last write error, if any write failed.
    pub error: Option<String>,
}

impl RecordingStats {
    /// The counters now.
    pub fn snapshot(&self) -> RecordingCounts {
        let (file, error) = self.detail.lock().map(|d| d.clone()).unwrap_or_default();
        RecordingCounts {
            file,
            files: self.files.load(Ordering::Relaxed),
            frames_written: self.frames_written.load(Ordering::Relaxed),
            frames_lost: self.frames_lost.load(Ordering::Relaxed),
            failing: self.failing.load(Ordering::Relaxed),
            error,
        }
    }

    fn set_file(&self, file: &Path) {
        if let Ok(mut d) = self.detail.lock() {
            d.0 = file.to_path_buf();
        }
    }

    fn set_error(&self, e: &Error) {
        if let Ok(mut d) = self.detail.lock() {
            d.1 = Some(e.to_string());
        }
    }
}

impl std::fmt::Display for RecordingCounts {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "recording: {} frames written in {} file{} (last {})",
            self.frames_written,
            self.files,
            if self.files == 1 { "" } else { "s" },
            self.file.display()
        )?;
        if self.frames_lost > 0 {
            write!(
                f,
                "; {} frames lost while writes failed (last error: {})",
                self.frames_lost,
                self.error.as_deref().unwrap_or("unknown")
            )?;
        }
        Ok(())
    }
}

/// The `n`-th file of a recording: `session.log.csv` → `session-2.log.csv`,
/// `take.csv` → `take-2.csv`, `take` → `take-2`. The number goes before the
/// extensions, so the files sort together and open like the first.
pub fn numbered(path: &Path, n: u64) -> PathBuf {
    let name = path
        .file_name()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let (stem, ext) = match name.find('.') {
        Some(0) | None => (name.as_str(), ""),
        Some(i) => name.split_at(i),
    };
    path.with_file_name(format!("{stem}-{n}{ext}"))
}

/// Writes frames to a log and, after a failed write, to numbered successors.
/// Fails only when the first file cannot be created.
pub struct Recorder {
    first: PathBuf,
    header: LogHeader,
    flush_interval: Duration,
    current: Option<LogWriter>,
    /// Number of the last file tried.
    index: u64,
    /// Counts of the files closed so far.
    closed_written: u64,
    closed_lost: u64,
    /// Frames that came while no file was open.
    between: u64,
    next_try: Instant,
    stats: Arc<RecordingStats>,
}

impl Recorder {
    /// Creates (truncates) the first file and writes its header; an
    /// unwritable path is an error here, before anything is recorded.
    pub fn create(
        path: &Path,
        header: LogHeader,
        flush_interval: Duration,
        stats: Arc<RecordingStats>,
    ) -> Result<Self> {
        let w = LogWriter::create(path, &header, flush_interval)?;
        stats.files.store(1, Ordering::Relaxed);
        stats.set_file(path);
        Ok(Recorder {
            first: path.to_path_buf(),
            header,
            flush_interval,
            current: Some(w),
            index: 1,
            closed_written: 0,
            closed_lost: 0,
            between: 0,
            next_try: Instant::now(),
            stats,
        })
    }

    /// The shared counters.
    pub fn stats(&self) -> Arc<RecordingStats> {
        self.stats.clone()
    }

    /// Appends a frame, or counts it lost while no file can be written.
    pub fn write_frame(&mut self, frame: &MarkerFrame) {
        self.reopen_if_due();
        let r = match self.current.as_mut() {
            Some(w) => w.write_frame(frame),
            None => {
                self.between += 1;
                Ok(())
            }
        };
        self.account(r);
    }

    /// Flushes on the interval (call it on a timer, so that a quiet source
    /// still reaches the disk) and tries a new file when one is due.
    pub fn tick(&mut self) {
        self.reopen_if_due();
        let r = self.current.as_mut().map_or(Ok(()), LogWriter::tick);
        self.account(r);
    }

    /// Flushes and syncs the open file; the final counts.
    pub fn finish(mut self) -> RecordingCounts {
        let r = self.current.as_mut().map_or(Ok(()), LogWriter::flush);
        self.account(r);
        if let Some(w) = self.current.take() {
            if let Err(e) = w.finish() {
                tracing::error!("recording: {e}");
            }
        }
        self.stats.snapshot()
    }

    /// Updates the shared counters; on a failed write closes the file.
    fn account(&mut self, r: Result<()>) {
        let (written, lost) = self
            .current
            .as_ref()
            .map_or((0, 0), |w| (w.frames_written(), w.frames_lost()));
        self.stats
            .frames_written
            .store(self.closed_written + written, Ordering::Relaxed);
        self.stats
            .frames_lost
            .store(self.closed_lost + lost + self.between, Ordering::Relaxed);
        let Err(e) = r else { return };
        let Some(w) = self.current.take() else { return };
        self.closed_written += w.frames_written();
        self.closed_lost += w.frames_lost();
        tracing::error!(
            "recording: {e}; {} ends at its last whole frame, frames are counted as lost \
             until writes work again, then a new file starts ({})",
            w.path().display(),
            numbered(&self.first, self.index + 1).display()
        );
        self.stats.set_error(&e);
        self.stats.failing.store(true, Ordering::Relaxed);
        self.next_try = Instant::now() + RETRY;
    }

    /// While no file is open: once a second, tries the next numbered file.
    fn reopen_if_due(&mut self) {
        if self.current.is_some() || Instant::now() < self.next_try {
            return;
        }
        self.next_try = Instant::now() + RETRY;
        let path = numbered(&self.first, self.index + 1);
        match LogWriter::create(&path, &self.header, self.flush_interval) {
            Ok(w) => {
                self.index += 1;
                tracing::warn!(
                    "recording: writes work again; continuing in {} after losing {} frames",
                    path.display(),
                    self.stats.frames_lost.load(Ordering::Relaxed)
                );
                self.current = Some(w);
                self.stats.files.store(self.index, Ordering::Relaxed);
                self.stats.set_file(&path);
                self.stats.failing.store(false, Ordering::Relaxed);
            }
            Err(_) => {
                // Still full: leave no empty file behind.
                let _ = std::fs::remove_file(&path);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbered_files_keep_their_extensions() {
        let p = |s: &str, n| numbered(Path::new(s), n).display().to_string();
        assert_eq!(p("out/session.log.csv", 2), "out/session-2.log.csv");
        assert_eq!(p("take.csv", 3), "take-3.csv");
        assert_eq!(p("/x/take", 2), "/x/take-2");
        assert_eq!(p(".hidden", 2), ".hidden-2");
    }
}
