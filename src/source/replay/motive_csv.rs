//! OptiTrack Motive CSV exports, format versions 1.21–1.25 (spec/motive-csv.md).

use std::path::Path;

use super::{Recording, RecordingInfo};
use crate::error::{Error, Result};
use crate::frame::MarkerFrame;

/// Streaming reader of a Motive CSV export.
pub struct MotiveCsvReader {
    info: RecordingInfo,
}

impl MotiveCsvReader {
    pub fn open(path: &Path) -> Result<Self> {
        Err(Error::Unsupported {
            path: path.into(),
            msg: "Motive CSV reader not yet written".into(),
        })
    }
}

impl Iterator for MotiveCsvReader {
    type Item = Result<MarkerFrame>;
    fn next(&mut self) -> Option<Self::Item> {
        None
    }
}

impl Recording for MotiveCsvReader {
    fn info(&self) -> &RecordingInfo {
        &self.info
    }
}
