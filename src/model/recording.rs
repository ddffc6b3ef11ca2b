//! A recorded session as the stages see it: a stream of frames and what the
//! file says about itself. The readers live in `format`; nothing here knows
//! about files.

use serde::Serialize;

use crate::error::Result;
use crate::model::frame::MarkerFrame;

/// The file formats treemocap reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Format {
    /// OptiTrack Motive CSV export, format versions 1.21–1.25.
    MotiveCsv,
    /// treemocap's own long-form CSV recording (`log.rs`).
    Log,
    /// C3D, any processor type and storage (`c3d/`).
    C3d,
    /// A Wireshark/tcpdump capture (pcap, pcapng) of NatNet traffic.
    Pcap,
}

impl std::fmt::Display for Format {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Format::MotiveCsv => "Motive CSV",
            Format::Log => "treemocap log",
            Format::C3d => "C3D",
            Format::Pcap => "NatNet capture (pcap)",
        })
    }
}

/// What a recording says about itself in its header.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RecordingInfo {
    /// Which reader read it (detected from the content, not the name).
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
    /// The name the file gives it (`Unlabeled 1036`, `Tree:Tip3`, a C3D
    /// point label), shown by `inspect`.
    pub name: String,
    /// What the channel holds; only marker kinds feed tracking.
    pub kind: ChannelKind,
    /// Frames in which the channel had a complete value.
    pub present: u64,
    /// Empty cells counted in this channel's columns.
    pub empty_cells: u64,
}

/// A streaming reader of one recorded session.
pub trait Recording: Iterator<Item = Result<MarkerFrame>> + Send {
    /// What the header says: format, rate, units, source.
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
