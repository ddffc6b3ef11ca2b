//! OptiTrack Motive CSV exports, format versions 1.21–1.25
//! (spec/motive-csv.md).
//!
//! The header is read once at `open`; data rows are then read one at a time,
//! so memory does not grow with the take. Decisions the spec leaves to us:
//! - Row 1 is a key/value map; only `Format Version`, the frame rates and
//!   `Length Units` matter. Frame counts in row 1 are ignored: we read to EOF.
//! - Descriptor rows are found by their label (`Type`, `Name`, `ID`,
//!   `Parent`); rows with an empty label (1.21, and the component row) are
//!   taken in order as Type, Name, ID, …, the last one being the component row.
//! - Columns are grouped into channels by consecutive runs of equal
//!   (Type, Name, ID), never by blocks of three.
//! - Time is the Time column's clock: its value in the first row that has
//!   one, plus (frame − that frame) / export rate (the column is quantized
//!   to 1 ms by some builds). So `tracking.rest_window_s` means what the
//!   user reads in the Time column even when the first frame is not 0. A
//!   row disagreeing beyond `time_tolerance_s` is a warning, never an error.

use std::fs::File;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use super::csv_rows::{Row, RowLimits, RowReader};

use super::{Channel, ChannelKind, Format, Recording, RecordingInfo};
use crate::error::{excerpt, excerpt_bytes, Error, Result};
use crate::model::frame::MarkerFrame;

mod chunks;
mod rows;

pub use chunks::ReadOptions;
use chunks::{Chunks, Pending};
use rows::{row_error, shifted, Layout, Parsed, PoseColumns, RowFrame, NO_CHANNEL};

/// Default allowed disagreement of the Time column (s); see `config.replay`.
/// How far the Time column may disagree with frame / rate by default (s):
/// Motive quantizes Time to 1 ms at high rates.
pub const DEFAULT_TIME_TOLERANCE_S: f64 = 0.002;
/// Keys of row 1 kept at most: Motive writes about 12; thousands mean the
/// file is not a Motive header, and each key costs memory.
const MAX_HEADER_KEYS: usize = 1000;
/// Header rows (Type, Name, ID, Parent, components…) before `Frame,Time`
/// at most: Motive writes up to 5; each one kept costs a row of memory.
const MAX_HEADER_ROWS: usize = 16;

/// Where a channel's numbers are in a data row.
#[derive(Debug, Clone)]
struct ChannelColumns {
    /// All columns of the channel, for empty-cell counts and number checks.
    first: usize,
    end: usize,
    /// For marker channels: the X, Y, Z columns of the `Position` component.
    position: Option<[usize; 3]>,
}

/// Streaming reader of a Motive CSV export.
pub struct MotiveCsvReader {
    path: PathBuf,
    /// The header's rows; once the header is read, an empty stand-in (the
    /// data rows are read in blocks by `data`).
    rows: RowReader<Box<dyn BufRead + Send>>,
    /// The data rows, read and parsed in chunks (on worker threads).
    data: Option<Chunks>,
    /// Threads and block size for `data`.
    options: ReadOptions,
    /// The chunk whose frames are being handed out.
    current: Current,
    info: RecordingInfo,
    /// Row 1 as read, in order, for `inspect` and for users who want the take's
    /// notes or start time.
    pub header: Vec<(String, String)>,
    channels: Vec<Channel>,
    columns: Vec<ChannelColumns>,
    /// Number of fields every data row must have (trailing empty ones may be
    /// missing only if the row is otherwise short of nothing).
    width: usize,
    /// Metres per file unit.
    scale: f64,
    /// Index of the Time column (1) and whether a TimeCode column follows.
    has_timecode: bool,
    time_tolerance_s: f64,
    /// (frame, Time column) of the first data row, for the time check.
    time_origin: Option<(i64, f64)>,
    time_mismatches: u64,
    /// Latest values of non-marker channels (rigid bodies, bones), kept apart
    /// from the tip candidates: (channel index, values in file order; NaN = empty).
    poses: Vec<(usize, Vec<f64>)>,
    /// Per channel: cells that held something, so empty cells are counted
    /// without visiting them (empty = rows × width − non-empty).
    nonempty: Vec<u64>,
    /// Data rows read (blank lines aside).
    rows_read: u64,
    warnings: Vec<String>,
    done: bool,
}

fn channel_kind(type_: &str, name: &str) -> ChannelKind {
    match type_.trim() {
        "Marker" if is_unlabeled(name) => ChannelKind::Unlabeled,
        "Marker" => ChannelKind::Marker,
        "Unlabeled Marker" | "Unlabeled" => ChannelKind::Unlabeled,
        "Rigid Body" => ChannelKind::RigidBody,
        "Rigid Body Marker" => ChannelKind::RigidBodyMarker,
        "Bone" => ChannelKind::Bone,
        "Bone Marker" => ChannelKind::BoneMarker,
        _ => ChannelKind::Other,
    }
}

fn is_unlabeled(name: &str) -> bool {
    name.strip_prefix("Unlabeled")
        .is_some_and(|rest| rest.starts_with([' ', ':']))
}

impl MotiveCsvReader {
    /// Reads the header of an opened export (`path` names it in errors);
    /// data rows are read by iterating. `time_tolerance_s` is how far the
    /// Time column may disagree with frame / rate before a warning.
    pub fn from_file(file: File, path: &Path, time_tolerance_s: f64) -> Result<Self> {
        Self::from_file_with(file, path, time_tolerance_s, ReadOptions::default())
    }

    /// [`Self::from_file`] with the data rows read as `options` say
    /// (`workers: 0` for the single-threaded path).
    pub fn from_file_with(
        file: File,
        path: &Path,
        time_tolerance_s: f64,
        options: ReadOptions,
    ) -> Result<Self> {
        let mut buf = BufReader::with_capacity(1 << 16, file);
        // Skip a UTF-8 BOM ourselves: the CSV parser would keep it in the
        // first key and `Format Version` would not be found.
        let head = buf.fill_buf().map_err(|e| Error::io(path, e))?;
        if head.starts_with(b"\xEF\xBB\xBF") {
            buf.consume(3);
        }
        let mut r = MotiveCsvReader {
            path: path.to_path_buf(),
            rows: RowReader::new(Box::new(buf), RowLimits::default()),
            data: None,
            options,
            current: Current::default(),
            info: RecordingInfo {
                format: Format::MotiveCsv,
                version: String::new(),
                frame_rate: 0.0,
                units: String::new(),
                up_axis: "Y".into(),
                source: String::new(),
            },
            header: Vec::new(),
            channels: Vec::new(),
            columns: Vec::new(),
            width: 2,
            scale: 1.0,
            has_timecode: false,
            time_tolerance_s,
            time_origin: None,
            time_mismatches: 0,
            poses: Vec::new(),
            nonempty: Vec::new(),
            rows_read: 0,
            warnings: Vec::new(),
            done: false,
        };
        r.read_header()?;
        Ok(r)
    }

    fn err(&self, line: u64, column: Option<u64>, msg: impl Into<String>) -> Error {
        Error::at_line(&self.path, line, column, msg)
    }

    fn read_row(&mut self) -> Result<bool> {
        self.rows.read().map_err(|e| row_error(&self.path, e))
    }

    /// Reads the whole header: row 1's key/value map, then the descriptor
    /// rows up to `Frame,Time…`, then groups the columns into channels.
    fn read_header(&mut self) -> Result<()> {
        self.read_key_value_row()?;
        self.apply_key_values()?;
        // Only row 1 (Take Notes) may hold a quoted field over several
        // lines; anywhere else an open quote is an error at its own line.
        self.rows.multiline = false;
        let rows = self.read_descriptor_rows()?;
        let axis_line = self.rows.line();
        if !rows.axis.text(1).starts_with("Time") {
            return Err(self.err(axis_line, Some(2), "the header row must begin 'Frame,Time'"));
        }
        self.has_timecode = rows.axis.text(2) == "TimeCode";
        self.width = rows.axis.len();
        let (labeled, component) = assign_unlabeled_rows(rows.labeled, rows.unlabeled)
            .ok_or_else(|| self.err(axis_line, None, "too many unlabeled header rows"))?;
        let row_of = |label: &str| labeled.iter().find(|(k, _)| k == label).map(|(_, r)| r);
        let Some(types) = row_of("Type") else {
            return Err(self.err(axis_line, None, "header has no 'Type' row"));
        };
        let descriptors = Descriptors {
            types,
            names: row_of("Name"),
            ids: row_of("ID"),
            component: component.as_ref(),
            axis: &rows.axis,
        };
        self.group_channels(&descriptors, axis_line)?;
        let layout = self.map_columns();
        self.start_data(layout);
        Ok(())
    }

    /// Reads row 1 (key, value, key, value…) into `header`, refusing the old
    /// row-typed format whose first cell is `comment`. Excel adds empty pairs
    /// at the end. Read in place: a hostile first row of millions of fields
    /// must not become millions of strings.
    fn read_key_value_row(&mut self) -> Result<()> {
        if !self.read_row()? {
            return Err(self.err(1, None, "file is empty"));
        }
        if self.rows.text(0) == "comment" {
            return Err(Error::Unsupported {
                path: self.path.clone(),
                msg: "unsupported format version: row-typed Motive/Arena CSV (format 1.0/1.1); \
                      re-export the take from Motive 1.5 or later (format 1.2x)"
                    .into(),
            });
        }
        for i in (0..self.rows.len()).step_by(2) {
            let key = self.rows.text(i).trim();
            if key.is_empty() {
                continue;
            }
            if self.header.len() == MAX_HEADER_KEYS {
                return Err(self.err(
                    1,
                    Some(i as u64 + 1),
                    format!(
                        "row 1 has more than {MAX_HEADER_KEYS} keys; a Motive export has about 12"
                    ),
                ));
            }
            let value = self.rows.text(i + 1).trim().to_string();
            self.header.push((key.to_string(), value));
        }
        Ok(())
    }

    /// The value of a row 1 key, as an owned string so that the reader can
    /// be changed (warnings, scale) while it is in use.
    fn header_value(&self, key: &str) -> Option<String> {
        self.header
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| v.clone())
    }

    /// Takes the recording's version, frame rate, units and take name from
    /// row 1; every one but the take name is required.
    fn apply_key_values(&mut self) -> Result<()> {
        let version = self.check_format_version()?;
        let rate = self.header_frame_rate()?;
        let units = self.header_value("Length Units").unwrap_or_default();
        self.scale = self.length_scale(&units)?;
        self.info.version = version;
        self.info.frame_rate = rate;
        self.info.units = units;
        self.info.source = self.header_value("Take Name").unwrap_or_default();
        Ok(())
    }

    /// The `Format Version` of row 1: any 1.2x is read, versions past 1.25
    /// with a warning (read like 1.25); others are unsupported.
    fn check_format_version(&mut self) -> Result<String> {
        let Some(version) = self.header_value("Format Version") else {
            return Err(self.err(
                1,
                None,
                "row 1 has no 'Format Version' key: not a Motive CSV export",
            ));
        };
        let numeric: Option<(u32, u32)> = version
            .split_once('.')
            .and_then(|(a, b)| Some((a.parse().ok()?, b.get(..b.len().min(1))?.parse().ok()?)));
        match numeric {
            Some((1, 2)) => {}
            _ => {
                return Err(Error::Unsupported {
                    path: self.path.clone(),
                    msg: format!(
                        "unsupported format version {version}: treemocap reads Motive CSV formats 1.21–1.25"
                    ),
                })
            }
        }
        if !matches!(
            version.as_str(),
            "1.2" | "1.21" | "1.22" | "1.23" | "1.24" | "1.25"
        ) {
            self.warn(format!(
                "format version {version} is newer than 1.25; reading it like 1.25"
            ));
        }
        Ok(version)
    }

    /// The frame rate of the data rows: the export rate, or the capture rate
    /// when the export rate is missing or empty.
    fn header_frame_rate(&self) -> Result<f64> {
        let rate_text = self
            .header_value("Export Frame Rate")
            .filter(|s| !s.is_empty())
            .or_else(|| self.header_value("Capture Frame Rate"));
        let Some(rate_text) = rate_text else {
            return Err(self.err(
                1,
                None,
                "row 1 has neither 'Export Frame Rate' nor 'Capture Frame Rate'",
            ));
        };
        match rate_text.parse() {
            Ok(r) if f64::is_finite(r) && r > 0.0 => Ok(r),
            _ => Err(self.err(
                1,
                None,
                format!(
                    "frame rate \"{}\" is not a positive number",
                    excerpt(&rate_text)
                ),
            )),
        }
    }

    /// Metres per file unit for row 1's `Length Units`.
    fn length_scale(&self, units: &str) -> Result<f64> {
        match units {
            "Meters" => Ok(1.0),
            "Centimeters" => Ok(0.01),
            "Millimeters" => Ok(0.001),
            "" => Err(self.err(
                1,
                None,
                "row 1 has no 'Length Units' (Meters, Centimeters or Millimeters)",
            )),
            other => Err(self.err(
                1,
                None,
                format!(
                    "Length Units \"{}\" is not Meters, Centimeters or Millimeters",
                    excerpt(other)
                ),
            )),
        }
    }

    /// Reads the descriptor rows up to the axis row `Frame,Time…`, kept as
    /// compact copies (bytes plus field ends), never as a string per cell.
    fn read_descriptor_rows(&mut self) -> Result<DescriptorRows> {
        let mut labeled: LabeledRows = Vec::new();
        let mut unlabeled: Vec<Row> = Vec::new();
        loop {
            if !self.read_row()? {
                return Err(self.err(
                    self.rows.line() + 1,
                    None,
                    "no 'Frame,Time' header row before the end of the file",
                ));
            }
            let line = self.rows.line();
            if self.rows.is_blank() {
                continue; // row 2, plain or Excel's `,,,,`
            }
            if labeled.len() + unlabeled.len() == MAX_HEADER_ROWS {
                return Err(self.err(
                    line,
                    None,
                    format!(
                        "more than {MAX_HEADER_ROWS} header rows before 'Frame,Time': not a Motive CSV header"
                    ),
                ));
            }
            let row = self.rows.to_row();
            if row.text(0) == "Frame" {
                return Ok(DescriptorRows {
                    labeled,
                    unlabeled,
                    axis: row,
                });
            }
            if !self.rows.get(0).is_empty() {
                return Err(self.err(
                    line,
                    Some(1),
                    format!(
                        "expected a header row (',Type,…', ',Name,…', ',ID,…' or 'Frame,Time,…'), found \"{}\"",
                        excerpt_bytes(self.rows.get(0))
                    ),
                ));
            }
            let label = row.text(1).to_string();
            match label.as_str() {
                "Type" | "Name" | "ID" | "Parent" => labeled.push((label, row)),
                "" => unlabeled.push(row),
                other => {
                    return Err(self.err(
                        line,
                        Some(2),
                        format!("unknown header row label \"{}\"", excerpt(other)),
                    ))
                }
            }
        }
    }

    /// Groups the data columns into channels by consecutive runs of equal
    /// (Type, Name, ID), and finds each marker's Position X, Y, Z columns.
    fn group_channels(&mut self, d: &Descriptors<'_>, axis_line: u64) -> Result<()> {
        let mut i = if self.has_timecode { 3 } else { 2 };
        while i < self.width {
            let key = d.key(i);
            if key.0.is_empty() && d.axis.text(i).is_empty() {
                i += 1; // Excel's trailing empty columns
                continue;
            }
            let mut end = i + 1;
            while end < self.width && d.key(end) == key {
                end += 1;
            }
            let kind = channel_kind(key.0, key.1);
            let mut position = None;
            if kind.is_marker() {
                let Some(xyz) = d.position_columns(i..end) else {
                    return Err(self.err(
                        axis_line,
                        Some(i as u64 + 1),
                        format!(
                            "marker \"{}\" has no Position X, Y, Z columns",
                            excerpt(key.1)
                        ),
                    ));
                };
                position = Some(xyz);
            }
            self.channels.push(Channel {
                name: key.1.to_string(),
                kind,
                present: 0,
                empty_cells: 0,
            });
            self.columns.push(ChannelColumns {
                first: i,
                end,
                position,
            });
            i = end;
        }
        Ok(())
    }

    /// Builds the column map and the per-channel counters once the channels
    /// are known: the layout every thread parsing rows reads.
    fn map_columns(&mut self) -> Layout {
        let mut roles = vec![NO_CHANNEL; self.width];
        for (ci, cols) in self.columns.iter().enumerate() {
            for (c, role) in roles.iter_mut().enumerate().take(cols.end).skip(cols.first) {
                let axis = cols
                    .position
                    .and_then(|xyz| xyz.iter().position(|&p| p == c))
                    .unwrap_or(3);
                *role = (ci as u32) << 2 | axis as u32;
            }
        }
        self.nonempty = vec![0; self.channels.len()];
        let mut pose_slot = vec![u32::MAX; self.channels.len()];
        let mut poses = Vec::new();
        let mut offset = 0;
        for (ci, ch) in self.channels.iter().enumerate() {
            if !ch.kind.is_marker() {
                pose_slot[ci] = poses.len() as u32;
                let cols = &self.columns[ci];
                let width = cols.end - cols.first;
                poses.push(PoseColumns {
                    channel: ci,
                    first: cols.first,
                    width,
                    offset,
                });
                offset += width;
                self.poses.push((ci, vec![f64::NAN; width]));
            }
        }
        Layout {
            path: self.path.clone(),
            width: self.width,
            roles,
            pose_slot,
            poses,
            pose_width: offset,
            channels: self
                .channels
                .iter()
                .map(|c| (c.name.clone(), c.kind))
                .collect(),
            scale: self.scale,
            limits: RowLimits::default(),
        }
    }

    /// Hands the rest of the file to the block reader: the header reader
    /// is left with an empty stand-in, the data rows start after its last line.
    fn start_data(&mut self, layout: Layout) {
        let empty: Box<dyn BufRead + Send> = Box::new(std::io::empty());
        let header = std::mem::replace(&mut self.rows, RowReader::new(empty, RowLimits::default()));
        self.current.base = header.line();
        let source = Box::new(header.into_inner());
        self.data = Some(Chunks::new(source, Arc::new(layout), self.options));
    }

    /// Brings the channels' empty-cell counts up to date (they are derived
    /// from the non-empty cells, so only at the end of reading or on request).
    fn count_empty_cells(&mut self) {
        for (ci, ch) in self.channels.iter_mut().enumerate() {
            let width = (self.columns[ci].end - self.columns[ci].first) as u64;
            ch.empty_cells = self.rows_read * width - self.nonempty[ci];
        }
    }

    fn warn(&mut self, msg: String) {
        let msg = format!("{}: {msg}", self.path.display());
        tracing::warn!("{msg}");
        self.warnings.push(msg);
    }

    /// Latest values of the non-marker channels (rigid bodies, bones and their
    /// markers), by channel index. Rotations are X, Y, Z, W as in the file;
    /// positions are in file units; empty cells are NaN.
    pub fn poses(&self) -> &[(usize, Vec<f64>)] {
        &self.poses
    }

    /// Compares the Time column with frame / rate from the first row that
    /// had one; the first disagreement beyond the tolerance is a warning,
    /// later ones are only counted.
    fn check_time_column(&mut self, frame: i64, t: f64, line: u64) {
        let (f0, t0) = *self.time_origin.get_or_insert((frame, t));
        let expected = t0 + (frame - f0) as f64 / self.info.frame_rate;
        if (t - expected).abs() > self.time_tolerance_s {
            self.time_mismatches += 1;
            if self.time_mismatches == 1 {
                let msg = format!(
                    "{}: line {line}: Time column {t} differs from frame/rate ({expected:.6}); \
                     using frame/rate (further mismatches counted, not logged)",
                    self.path.display()
                );
                tracing::warn!("{msg}");
                self.warnings.push(msg);
            }
        }
    }

    /// The Time column's clock, anchored on the first row that has one
    /// (a take whose first frame is not 0 keeps its own Time), advanced
    /// by frame / rate so that a 1 ms quantized column adds no jitter.
    fn frame_time(&self, frame: i64) -> f64 {
        let rate = self.info.frame_rate;
        match self.time_origin {
            Some((f0, t0)) => t0 + (frame - f0) as f64 / rate,
            None => frame as f64 / rate,
        }
    }
}

/// Header rows with the label they stand for (`Type`, `Name`, `ID`, `Parent`).
type LabeledRows = Vec<(String, Row)>;

/// The header rows between row 1 and the data, as read: labeled rows
/// (`Type`, `Name`, `ID`, `Parent`), rows with an empty label in order, and
/// the axis row `Frame,Time,…`.
struct DescriptorRows {
    labeled: LabeledRows,
    unlabeled: Vec<Row>,
    axis: Row,
}

/// The descriptor rows that name a column, once the unlabeled ones have been
/// given their meaning: what [`MotiveCsvReader::group_channels`] reads.
struct Descriptors<'a> {
    types: &'a Row,
    names: Option<&'a Row>,
    ids: Option<&'a Row>,
    /// The component row (`Position`, `Rotation`…), if the file has one.
    component: Option<&'a Row>,
    axis: &'a Row,
}

impl<'a> Descriptors<'a> {
    /// A column's (Type, Name, ID): equal keys in a run make one channel.
    fn key(&self, i: usize) -> (&'a str, &'a str, &'a str) {
        let cell = |row: Option<&'a Row>| row.map_or("", move |r| r.text(i));
        (self.types.text(i), cell(self.names), cell(self.ids))
    }

    /// The X, Y, Z columns of a marker's `Position` component (or of a file
    /// without a component row) among `cols`.
    fn position_columns(&self, cols: std::ops::Range<usize>) -> Option<[usize; 3]> {
        let find = |axis: &str| {
            cols.clone().find(|&c| {
                self.axis.text(c) == axis
                    && self.component.is_none_or(|r| {
                        let s = r.text(c);
                        s == "Position" || s.is_empty()
                    })
            })
        };
        Some([find("X")?, find("Y")?, find("Z")?])
    }
}

/// Gives the unlabeled header rows their meaning: the last one is the
/// component row; earlier ones (format 1.21) stand for Type, Name, ID in that
/// order, skipping labels already present. `None` if there are more of them
/// than labels left.
fn assign_unlabeled_rows(
    mut labeled: LabeledRows,
    mut unlabeled: Vec<Row>,
) -> Option<(LabeledRows, Option<Row>)> {
    let component = unlabeled.pop();
    let mut order = ["Type", "Name", "ID"].into_iter();
    for row in unlabeled {
        let label = order.find(|l| !labeled.iter().any(|(k, _)| k == l))?;
        labeled.push((label.to_string(), row));
    }
    Some((labeled, component))
}

/// The chunk of frames being handed out, and where it lies in the file.
#[derive(Default)]
struct Current {
    frames: std::vec::IntoIter<RowFrame>,
    /// Per frame, its non-marker values, [`Layout::pose_width`] each.
    poses: Vec<f64>,
    /// Frames handed out from this chunk.
    taken: usize,
    /// Lines before the chunk's first line.
    base: u64,
    /// Lines in the chunk: the next chunk's `base` is `base + lines`.
    lines: u64,
    failure: Option<rows::Failure>,
}

impl MotiveCsvReader {
    /// Takes the next chunk in file order and merges its counts; an error
    /// for a chunk that could not be read at all.
    fn next_chunk(&mut self) -> Option<Result<()>> {
        let pending = self.data.as_mut()?.next_chunk()?;
        let base = self.current.base + self.current.lines;
        let parsed = match pending {
            Pending::Ready(p) => p,
            Pending::Working(rx) => match rx.recv() {
                Ok(p) => p,
                Err(_) => {
                    let e = std::io::Error::other("a thread reading the rows stopped");
                    return Some(Err(Error::io(&self.path, e)));
                }
            },
            Pending::TooLong => {
                let e = crate::format::csv_rows::RowError::TooLong {
                    line: base + 1,
                    limit: RowLimits::default().max_bytes,
                };
                return Some(Err(row_error(&self.path, e)));
            }
            Pending::Io(e) => return Some(Err(Error::io(&self.path, e))),
        };
        self.merge(parsed, base);
        Some(Ok(()))
    }

    /// Makes `parsed` the chunk being handed out, its counts the channels'.
    fn merge(&mut self, parsed: Parsed, base: u64) {
        for &(ci, nonempty, present) in &parsed.counts {
            self.nonempty[ci as usize] += nonempty;
            self.channels[ci as usize].present += present;
        }
        self.rows_read += parsed.rows_read;
        self.current = Current {
            frames: parsed.frames.into_iter(),
            poses: parsed.poses,
            taken: 0,
            base,
            lines: parsed.lines,
            failure: parsed.failure,
        };
    }

    /// The next frame of the current chunk in file context: its Time
    /// checked, its time on the file's clock, its poses the latest.
    fn next_frame(&mut self) -> Option<Result<MarkerFrame>> {
        if let Some(row) = self.current.frames.next() {
            let line = self.current.base + row.line;
            if let Some(t) = row.time {
                self.check_time_column(row.frame, t, line);
            }
            self.set_poses();
            self.current.taken += 1;
            let time = self.frame_time(row.frame);
            return Some(Ok(MarkerFrame::new(row.frame, time, row.markers)));
        }
        let failure = self.current.failure.take()?;
        if let Some((frame, t)) = failure.time {
            self.check_time_column(frame, t, self.current.base + failure.line);
        }
        Some(Err(shifted(failure.error, self.current.base)))
    }

    /// Copies the values of the frame being handed out to `poses`.
    fn set_poses(&mut self) {
        let mut at = self.current.taken * self.poses.iter().map(|p| p.1.len()).sum::<usize>();
        for (_, values) in &mut self.poses {
            let n = values.len();
            values.copy_from_slice(&self.current.poses[at..at + n]);
            at += n;
        }
    }

    /// Reading has ended (end of file or an error): counts become final,
    /// the workers stop.
    fn finish(&mut self) {
        self.done = true;
        self.data = None;
        self.count_empty_cells();
    }
}

impl Iterator for MotiveCsvReader {
    type Item = Result<MarkerFrame>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        loop {
            match self.next_frame() {
                Some(Ok(frame)) => return Some(Ok(frame)),
                Some(Err(e)) => {
                    self.finish();
                    return Some(Err(e));
                }
                None => {}
            }
            match self.next_chunk() {
                Some(Ok(())) => {}
                Some(Err(e)) => {
                    self.finish();
                    return Some(Err(e));
                }
                None => {
                    self.finish();
                    if self.time_mismatches > 1 {
                        let n = self.time_mismatches;
                        self.warn(format!(
                            "{n} rows had a Time column off frame/rate by more than {} s",
                            self.time_tolerance_s
                        ));
                    }
                    return None;
                }
            }
        }
    }
}

impl Recording for MotiveCsvReader {
    fn info(&self) -> &RecordingInfo {
        &self.info
    }

    fn channels(&self) -> &[Channel] {
        &self.channels
    }

    fn warnings(&self) -> &[String] {
        &self.warnings
    }
}
