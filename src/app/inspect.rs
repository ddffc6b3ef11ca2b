//! `treemocap inspect`: what a recording holds, read in one streaming pass.
//!
//! The questions a user asks before trusting a take: is it the format and
//! rate I think, how long is it, were frames dropped or trimmed, how many
//! markers are seen per frame, and how much is missing.

use std::collections::BTreeMap;
use std::fmt;
use std::path::Path;

use serde::Serialize;

use crate::error::{one_line, Result};
use crate::model::recording::{ChannelKind, Format, Recording};

/// A marker column seen in fewer frames than this is reported as short: the
/// life of a spurious reflection, or a piece of a marker between two gaps.
pub const SHORT_COLUMN_FRAMES: u64 = 50;

/// How many frame-number jumps are listed one by one.
const JUMPS_LISTED: usize = 20;

/// Everything `inspect` reports; serialised as-is by `--json`.
#[derive(Debug, Clone, Serialize)]
pub struct Inspection {
    /// The path as given on the command line.
    pub file: String,
    /// The format detected from the content.
    pub format: Format,
    /// The format's own version ("1.23" for Motive CSV, "1" for our log).
    pub version: String,
    /// Frames per second from the header.
    pub frame_rate: f64,
    /// Length unit as the file writes it (converted to metres on reading).
    pub units: String,
    /// Up axis of the file ("Y" or "Z"; turned to Y up on reading).
    pub up_axis: String,
    /// Take name or source description from the file's header.
    pub source: String,
    /// Frames in the file (read to its end, whatever the header claims).
    pub frames: u64,
    /// Number of the first frame; `None` for a file without frames.
    pub first_frame: Option<i64>,
    /// Number of the last frame.
    pub last_frame: Option<i64>,
    /// Seconds from the first to the last frame.
    pub duration_s: f64,
    /// Places where the frame number did not advance by exactly one.
    pub jumps: u64,
    /// The first few jumps as (frame before, frame after).
    pub jump_list: Vec<(i64, i64)>,
    /// Jumps that went backwards (a restarted source).
    pub backwards: u64,
    /// Markers per frame, to see occlusions and spurious reflections at a glance.
    pub markers_per_frame: MarkerCounts,
    /// Marker samples in all frames.
    pub samples: u64,
    /// Tip-candidate columns (labeled and unlabeled markers) with their counts.
    pub marker_columns: Vec<ColumnSummary>,
    /// Empty cells over all marker columns.
    pub gap_cells: u64,
    /// Marker columns never filled.
    pub empty_columns: u64,
    /// Marker columns filled in 1 to `SHORT_COLUMN_FRAMES` frames.
    pub short_columns: u64,
    /// Columns that are not tip candidates, by kind (rigid bodies, bones…).
    pub other_channels: BTreeMap<String, u64>,
    /// What the reader warned about (a cut-off last row, Time column drift).
    pub warnings: Vec<String>,
}

/// Markers per frame.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct MarkerCounts {
    /// Fewest markers in one frame.
    pub min: usize,
    /// Markers in the median frame: close to the markers placed when
    /// occlusions and reflections are rare.
    pub median: usize,
    /// Most markers in one frame.
    pub max: usize,
}

/// One marker column of the file.
#[derive(Debug, Clone, Serialize)]
pub struct ColumnSummary {
    /// The column's name in the file.
    pub name: String,
    /// An unlabeled point-cloud marker rather than a labeled one.
    pub unlabeled: bool,
    /// Frames in which the marker had a position.
    pub present: u64,
    /// Empty cells in the column's coordinates.
    pub gap_cells: u64,
}

/// Reads the whole file once and summarises it.
pub fn inspect(path: &Path) -> Result<Inspection> {
    inspect_with(path, &crate::app::open::ReplayOptions::default())
}

/// [`inspect`] with the given reading options (`--strict`).
pub fn inspect_with(path: &Path, options: &crate::app::open::ReplayOptions) -> Result<Inspection> {
    let mut rec = crate::app::open::open_with(path, options)?;
    inspect_recording(path, rec.as_mut())
}

/// Summarises an already opened recording, reading it to the end.
pub fn inspect_recording(path: &Path, rec: &mut dyn Recording) -> Result<Inspection> {
    let mut tally = FrameTally::default();
    for frame in &mut *rec {
        tally.add(&frame?);
    }
    let (marker_columns, other_channels) = channel_summary(rec.channels());
    let info = rec.info().clone();
    let t = tally;
    Ok(Inspection {
        file: path.display().to_string(),
        format: info.format,
        version: info.version,
        frame_rate: info.frame_rate,
        units: info.units,
        up_axis: info.up_axis,
        source: info.source,
        frames: t.frames,
        first_frame: t.first,
        last_frame: t.last,
        duration_s: t.last_time - t.first_time.unwrap_or(t.last_time),
        jumps: t.jumps,
        backwards: t.backwards,
        markers_per_frame: t.marker_counts(),
        jump_list: t.jump_list,
        samples: t.samples,
        gap_cells: marker_columns.iter().map(|c| c.gap_cells).sum(),
        empty_columns: marker_columns.iter().filter(|c| c.present == 0).count() as u64,
        short_columns: marker_columns
            .iter()
            .filter(|c| c.present > 0 && c.present <= SHORT_COLUMN_FRAMES)
            .count() as u64,
        marker_columns,
        other_channels,
        warnings: rec.warnings().to_vec(),
    })
}

/// What the frames of a recording add up to, counted in one pass.
#[derive(Default)]
struct FrameTally {
    frames: u64,
    first: Option<i64>,
    last: Option<i64>,
    jumps: u64,
    jump_list: Vec<(i64, i64)>,
    backwards: u64,
    samples: u64,
    /// Histogram of markers per frame rather than a list: memory stays flat
    /// for any length.
    counts: BTreeMap<usize, u64>,
    first_time: Option<f64>,
    last_time: f64,
}

impl FrameTally {
    fn add(&mut self, frame: &crate::model::frame::MarkerFrame) {
        self.frames += 1;
        self.first.get_or_insert(frame.frame);
        self.first_time.get_or_insert(frame.time_s);
        self.last_time = frame.time_s;
        if let Some(prev) = self.last {
            if frame.frame != prev + 1 {
                self.jumps += 1;
                if frame.frame <= prev {
                    self.backwards += 1;
                }
                if self.jump_list.len() < JUMPS_LISTED {
                    self.jump_list.push((prev, frame.frame));
                }
            }
        }
        self.last = Some(frame.frame);
        self.samples += frame.markers.len() as u64;
        *self.counts.entry(frame.markers.len()).or_default() += 1;
    }

    fn marker_counts(&self) -> MarkerCounts {
        if self.frames == 0 {
            return MarkerCounts::default();
        }
        let mut median = 0;
        let mut seen = 0;
        for (&n, &c) in &self.counts {
            seen += c;
            if seen * 2 >= self.frames {
                median = n;
                break;
            }
        }
        MarkerCounts {
            min: self.counts.keys().next().copied().unwrap_or(0),
            median,
            max: self.counts.keys().next_back().copied().unwrap_or(0),
        }
    }
}

/// The marker columns, and how many channels of every other kind.
fn channel_summary(
    channels: &[crate::model::recording::Channel],
) -> (Vec<ColumnSummary>, BTreeMap<String, u64>) {
    let mut marker_columns = Vec::new();
    let mut other_channels = BTreeMap::new();
    for ch in channels {
        if ch.kind.is_marker() {
            marker_columns.push(ColumnSummary {
                name: ch.name.clone(),
                unlabeled: ch.kind == ChannelKind::Unlabeled,
                present: ch.present,
                gap_cells: ch.empty_cells,
            });
        } else {
            let kind = serde_json::to_value(ch.kind)
                .ok()
                .and_then(|v| v.as_str().map(str::to_string))
                .unwrap_or_default();
            *other_channels.entry(kind).or_default() += 1;
        }
    }
    (marker_columns, other_channels)
}

/// How many marker columns the text report lists before pointing to --json.
const COLUMNS_LISTED: usize = 30;

impl fmt::Display for Inspection {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "file        {}", self.file)?;
        writeln!(f, "format      {} {}", self.format, self.version)?;
        if !self.source.is_empty() {
            writeln!(f, "source      {}", one_line(&self.source))?;
        }
        writeln!(
            f,
            "rate        {} Hz   units {} (read as metres)   up {}",
            self.frame_rate, self.units, self.up_axis
        )?;
        match (self.first_frame, self.last_frame) {
            (Some(a), Some(b)) => writeln!(
                f,
                "frames      {}  (numbers {a} to {b}, {:.3} s)",
                self.frames, self.duration_s
            )?,
            _ => writeln!(f, "frames      0")?,
        }
        write!(f, "jumps       {}", self.jumps)?;
        if self.backwards > 0 {
            write!(f, " ({} backwards)", self.backwards)?;
        }
        for (a, b) in &self.jump_list {
            write!(f, "  {a}->{b}")?;
        }
        if self.jumps as usize > self.jump_list.len() {
            write!(f, "  …")?;
        }
        writeln!(f)?;
        let m = self.markers_per_frame;
        writeln!(
            f,
            "markers     per frame min {} / median {} / max {}   samples {}",
            m.min, m.median, m.max, self.samples
        )?;
        writeln!(
            f,
            "columns     {} marker columns ({} unlabeled), {} empty, {} short (<= {} frames)",
            self.marker_columns.len(),
            self.marker_columns.iter().filter(|c| c.unlabeled).count(),
            self.empty_columns,
            self.short_columns,
            SHORT_COLUMN_FRAMES
        )?;
        writeln!(f, "gap cells   {}", self.gap_cells)?;
        for (kind, n) in &self.other_channels {
            writeln!(f, "other       {n} × {kind} (not tips)")?;
        }
        if !self.marker_columns.is_empty() {
            writeln!(
                f,
                "\n  {:<32} {:>8} {:>10}",
                "column", "present", "gap cells"
            )?;
            for c in self.marker_columns.iter().take(COLUMNS_LISTED) {
                // Names come from the file: a newline or an escape code in
                // one must not break the table or the terminal.
                let name = one_line(&c.name);
                writeln!(f, "  {name:<32} {:>8} {:>10}", c.present, c.gap_cells)?;
            }
            if self.marker_columns.len() > COLUMNS_LISTED {
                writeln!(
                    f,
                    "  … {} more columns (treemocap inspect --json lists all)",
                    self.marker_columns.len() - COLUMNS_LISTED
                )?;
            }
        }
        for w in &self.warnings {
            writeln!(f, "warning     {}", one_line(w))?;
        }
        Ok(())
    }
}
