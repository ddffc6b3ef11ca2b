//! Recorded sessions: Motive CSV exports and our own recording format.
//!
//! [`open`] detects the format from the file's content (not its extension)
//! and returns a streaming [`Recording`]: frames are read one at a time, so
//! memory does not grow with the length of the file.

use std::io::Read;
use std::path::Path;

use serde::Serialize;

use crate::error::{Error, Result};
use crate::frame::MarkerFrame;

mod csv_rows;
pub mod log;
pub mod motive_csv;

/// The file formats treemocap reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Format {
    /// OptiTrack Motive CSV export, format versions 1.21–1.25.
    MotiveCsv,
    /// treemocap's own long-form CSV recording (`log.rs`).
    Log,
}

impl std::fmt::Display for Format {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Format::MotiveCsv => "Motive CSV",
            Format::Log => "treemocap log",
        })
    }
}

/// What a recording says about itself in its header.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RecordingInfo {
    pub format: Format,
    /// The format's own version string ("1.23" for Motive, "1" for our log).
    pub version: String,
    /// Frames per second (Motive: the export rate).
    pub frame_rate: f64,
    /// Length unit of the file as written ("Millimeters", "m", …); frames are
    /// always converted to metres.
    pub units: String,
    /// The up axis of the file ("Y" or "Z"); frames are always Y up.
    pub up_axis: String,
    /// Where the data came from: take name, NatNet server, simulator seed.
    pub source: String,
}

/// What kind of data a channel (a column group of the file) holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ChannelKind {
    /// A labeled marker (`Asset:Label`): a tip candidate.
    Marker,
    /// An unlabeled point-cloud marker (`Unlabeled 1036`): a tip candidate.
    Unlabeled,
    /// A rigid body pose; never a tip.
    RigidBody,
    /// A rigid body's solved marker; never a tip.
    RigidBodyMarker,
    /// A skeleton bone pose; never a tip.
    Bone,
    /// A skeleton bone's marker; never a tip.
    BoneMarker,
    /// Anything else the file declares.
    Other,
}

impl ChannelKind {
    /// Marker positions that feed tracking (labeled or not).
    pub fn is_marker(self) -> bool {
        matches!(self, ChannelKind::Marker | ChannelKind::Unlabeled)
    }
}

/// One declared track of a file and what was seen of it while reading.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Channel {
    pub name: String,
    pub kind: ChannelKind,
    /// Frames in which the channel had a complete value.
    pub present: u64,
    /// Empty cells counted in this channel's columns.
    pub empty_cells: u64,
}

/// A streaming reader of one recorded session.
pub trait Recording: Iterator<Item = Result<MarkerFrame>> + Send {
    fn info(&self) -> &RecordingInfo;
    /// The file's channels with counts of what has been read so far. A
    /// `Marker` whose `id` is `Some(i)` came from `channels()[i]`. Formats
    /// without channels (our log) return an empty slice.
    fn channels(&self) -> &[Channel] {
        &[]
    }
    /// Warnings collected while reading (a cut-off last line, time column
    /// disagreements), for `inspect` and the replay summary.
    fn warnings(&self) -> &[String] {
        &[]
    }
}

/// Looks at the first bytes of a file and says which format it is.
pub fn detect(path: &Path) -> Result<Format> {
    let mut head = [0u8; 512];
    let mut file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let n = read_up_to(&mut file, &mut head).map_err(|e| Error::io(path, e))?;
    let head = &head[..n];
    let text = head.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(head);
    if text.starts_with(log::MAGIC.as_bytes()) {
        Ok(Format::Log)
    } else if text.starts_with(b"Format Version") {
        Ok(Format::MotiveCsv)
    } else if text.starts_with(b"comment,") {
        Err(Error::Unsupported {
            path: path.into(),
            msg: "unsupported format version: this is a row-typed Motive/Arena CSV (format 1.0/1.1); \
                  re-export the take from Motive 1.5 or later (format 1.2x)"
                .into(),
        })
    } else if n == 0 {
        Err(Error::parse(
            path,
            crate::Location::Offset(0),
            "file is empty",
        ))
    } else {
        Err(Error::Unsupported {
            path: path.into(),
            msg: "not a recording treemocap knows (expected a Motive CSV export starting with \
                  'Format Version' or a treemocap log)"
                .into(),
        })
    }
}

fn read_up_to(r: &mut impl Read, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut n = 0;
    while n < buf.len() {
        match r.read(&mut buf[n..])? {
            0 => break,
            k => n += k,
        }
    }
    Ok(n)
}

/// Opens a recording of any supported format, detected by content, with
/// default settings.
pub fn open(path: &Path) -> Result<Box<dyn Recording>> {
    open_with(path, &crate::config::Config::default().replay)
}

/// Opens a recording with the `[replay]` settings of a config.
pub fn open_with(path: &Path, config: &crate::config::ReplayConfig) -> Result<Box<dyn Recording>> {
    match detect(path)? {
        Format::MotiveCsv => Ok(Box::new(motive_csv::MotiveCsvReader::open_with(
            path,
            config.time_tolerance_s,
        )?)),
        Format::Log => Ok(Box::new(log::LogReader::open(path)?)),
    }
}
