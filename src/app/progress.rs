//! A progress bar for long replays and exports, on a terminal only.
//!
//! The readers take an opened `File` and read it through their own buffers,
//! so they cannot say how far they are. A second handle made by
//! `File::try_clone` shares the file offset with the reader's (one open file
//! description), so asking it for its position says how many bytes the reader
//! has taken, within one read-ahead buffer, at the cost of one `lseek` every
//! few hundred frames — and the readers need not know about it.

use std::fs::File;
use std::io::{IsTerminal, Seek};
use std::path::Path;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

use crate::error::Result;
use crate::model::frame::MarkerFrame;
use crate::model::recording::{Channel, Recording, RecordingInfo};

/// Files smaller than this read in about a second: no bar.
const MIN_BYTES: u64 = 16 << 20;
/// Frames between two looks at the file offset.
const EVERY_FRAMES: u64 = 256;

/// A second handle on the reader's file, and the bar it moves.
pub(crate) struct Watch {
    file: File,
    bar: ProgressBar,
}

impl Watch {
    /// A watch on `file` when stderr is a terminal and the file is long
    /// enough to wait for (`TREEMOCAP_PROGRESS=1`: whatever its length);
    /// `None` otherwise, so logs and pipes never get a bar.
    pub(crate) fn new(file: &File, path: &Path) -> Option<Watch> {
        if !std::io::stderr().is_terminal() {
            return None;
        }
        let forced = std::env::var_os("TREEMOCAP_PROGRESS").is_some_and(|v| v == "1");
        let len = file.metadata().ok()?.len();
        if len < MIN_BYTES && !forced {
            return None;
        }
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let bar = ProgressBar::with_draw_target(Some(len), ProgressDrawTarget::stderr());
        let style = ProgressStyle::with_template(
            "{msg} [{bar:30}] {bytes}/{total_bytes} {bytes_per_sec}, {eta} left",
        )
        .ok()?
        .progress_chars("=> ");
        bar.set_style(style);
        bar.set_message(format!("reading {name}"));
        Some(Watch {
            file: file.try_clone().ok()?,
            bar,
        })
    }

    /// The recording, moving the bar as its frames are read.
    pub(crate) fn wrap(self, inner: Box<dyn Recording>) -> Box<dyn Recording> {
        Box::new(Watched {
            inner,
            watch: self,
            frames: 0,
        })
    }
}

/// A recording that moves a progress bar; frames, header and warnings are
/// the inner recording's, untouched.
struct Watched {
    inner: Box<dyn Recording>,
    watch: Watch,
    frames: u64,
}

impl Iterator for Watched {
    type Item = Result<MarkerFrame>;

    fn next(&mut self) -> Option<Self::Item> {
        let item = self.inner.next();
        self.frames += 1;
        if item.is_none() {
            self.watch.bar.finish_and_clear();
        } else if self.frames.is_multiple_of(EVERY_FRAMES) {
            if let Ok(at) = (&self.watch.file).stream_position() {
                self.watch.bar.set_position(at);
            }
        }
        item
    }
}

impl Recording for Watched {
    fn info(&self) -> &RecordingInfo {
        self.inner.info()
    }

    fn channels(&self) -> &[Channel] {
        self.inner.channels()
    }

    fn warnings(&self) -> &[String] {
        self.inner.warnings()
    }
}

impl Drop for Watched {
    fn drop(&mut self) {
        // An error ends the reading early: the bar goes, the error stays.
        if !self.watch.bar.is_finished() {
            self.watch.bar.finish_and_clear();
        }
    }
}
