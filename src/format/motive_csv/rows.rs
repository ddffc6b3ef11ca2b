//! Data rows of a Motive CSV export turned into frames, a chunk of whole
//! rows at a time, on whichever thread holds the chunk.
//!
//! Why a chunk and not a row: the rows of a long take are parsed on worker
//! threads ([`super::chunks`]), and handing rows over one by one would cost
//! more than parsing them. Everything that depends on the rows before a
//! chunk (the Time column's origin and its warnings, line numbers, the
//! channels' counts) is left to the reader, which takes the chunks in file
//! order: a chunk's output carries line numbers relative to its first line,
//! raw Time values, and count deltas.

use std::path::PathBuf;

use glam::DVec3;

use crate::error::{excerpt, excerpt_bytes, Error, Location};
use crate::format::cells::{self, Scan};
use crate::format::csv_rows::{trim_eol, RowError, RowLimits, RowReader};
use crate::format::ChannelKind;
use crate::model::frame::Marker;

/// Column role of Frame, Time, TimeCode and unnamed columns.
pub(super) const NO_CHANNEL: u32 = u32::MAX;

/// What the columns of a data row mean, built once from the header and
/// shared (read-only) by every thread that parses rows.
#[derive(Debug)]
pub(super) struct Layout {
    /// The export, named in errors.
    pub(super) path: PathBuf,
    /// Number of fields of the header's `Frame,Time,…` row.
    pub(super) width: usize,
    /// What each column is: `channel << 2 | role` with role 0–2 the X, Y, Z
    /// of a marker's position and 3 any other column of a channel;
    /// [`NO_CHANNEL`] for Frame, Time, TimeCode and unnamed columns. Rows are
    /// read cell by cell through this map, so a row costs what its
    /// non-empty cells cost, however many columns the take has.
    pub(super) roles: Vec<u32>,
    /// Per channel: its slot in `poses` (non-marker channels), else `u32::MAX`.
    pub(super) pose_slot: Vec<u32>,
    /// Per pose slot: where its values lie in the row and in a frame's values.
    pub(super) poses: Vec<PoseColumns>,
    /// Values of all pose slots of one row together.
    pub(super) pose_width: usize,
    /// Per channel: its name and kind, for errors naming the channel.
    pub(super) channels: Vec<(String, ChannelKind)>,
    /// Metres per file unit.
    pub(super) scale: f64,
    /// The longest and widest row read.
    pub(super) limits: RowLimits,
}

/// The columns of one non-marker channel (rigid body, bone…).
#[derive(Debug, Clone, Copy)]
pub(super) struct PoseColumns {
    /// The channel's index.
    pub(super) channel: usize,
    /// Its first column in a data row.
    pub(super) first: usize,
    /// Its number of columns.
    pub(super) width: usize,
    /// Where its values start among a row's pose values.
    pub(super) offset: usize,
}

/// One data row as a frame, before the reader puts it in file context.
#[derive(Debug)]
pub(super) struct RowFrame {
    /// Line of the row counted from the chunk's first line (1-based).
    pub(super) line: u64,
    /// The Frame column.
    pub(super) frame: i64,
    /// The Time column as written, if the row has one.
    pub(super) time: Option<f64>,
    /// Markers with X, Y and Z, in file units times the scale (metres).
    pub(super) markers: Vec<Marker>,
}

/// The first row of a chunk that could not be read.
#[derive(Debug)]
pub(super) struct Failure {
    /// Its line, counted from the chunk's first line (1-based); the error
    /// holds the same relative line until the reader shifts it.
    pub(super) line: u64,
    /// Its (Frame, Time) when they were read before the error: the reader
    /// checks the Time column of a failing row as it always did.
    pub(super) time: Option<(i64, f64)>,
    /// What is wrong.
    pub(super) error: Error,
}

/// What a chunk of rows gave.
#[derive(Debug, Default)]
pub(super) struct Parsed {
    /// The frames, in file order (blank lines give none).
    pub(super) frames: Vec<RowFrame>,
    /// Per frame, its non-marker values ([`Layout::pose_width`] each; NaN =
    /// empty), for [`super::MotiveCsvReader::poses`].
    pub(super) poses: Vec<f64>,
    /// Lines read, up to and including a failing row.
    pub(super) lines: u64,
    /// Data rows read (blank lines aside), a failing row included once its
    /// frame number was read, as the reader always counted.
    pub(super) rows_read: u64,
    /// Per channel touched: (channel, non-empty cells, frames present).
    pub(super) counts: Vec<(u32, u64, u64)>,
    /// The row that ended the chunk early, if one did.
    pub(super) failure: Option<Failure>,
}

/// A row error with the (Frame, Time) read before it, if any.
type RowFail = (Option<(i64, f64)>, Error);

/// Parses chunks of rows; one per thread, its buffers reused from chunk to
/// chunk.
pub(super) struct RowParser {
    layout: std::sync::Arc<Layout>,
    /// The non-empty cells of the current row: (column, start, end).
    cells: Vec<(usize, usize, usize)>,
    /// A quoted row's fields, back to back (the rare rows that need the
    /// full CSV reader).
    quoted: Vec<u8>,
    /// Per channel, this chunk's non-empty cells and frames present.
    nonempty: Vec<u64>,
    present: Vec<u64>,
    /// Channels with a non-zero count in this chunk, so that handing the
    /// counts over costs what the chunk touched, not the take's width.
    touched: Vec<u32>,
    /// Per pose slot: cells filled in the current row.
    pose_filled: Vec<u32>,
    /// Markers of the last row: the next row's vector is allocated at that
    /// size once instead of growing through 4, 8, 16, 32, 64…
    last_markers: usize,
}

impl RowParser {
    pub(super) fn new(layout: std::sync::Arc<Layout>) -> Self {
        let channels = layout.channels.len();
        let slots = layout.poses.len();
        RowParser {
            layout,
            cells: Vec::new(),
            quoted: Vec::new(),
            nonempty: vec![0; channels],
            present: vec![0; channels],
            touched: Vec::new(),
            pose_filled: vec![0; slots],
            last_markers: 0,
        }
    }

    /// Parses `chunk`: whole rows, each ending with a line end but perhaps
    /// the last one of the file. Stops at the first row in error.
    pub(super) fn parse(&mut self, chunk: &[u8]) -> Parsed {
        let mut out = Parsed::default();
        let mut pos = 0;
        while pos < chunk.len() {
            out.lines += 1;
            let line = out.lines;
            let (end, result) = self.row(&chunk[pos..], line, &mut out);
            if let Err((time, error)) = result {
                out.failure = Some(Failure { line, time, error });
                break;
            }
            pos += end + 1;
        }
        for &ci in &self.touched {
            let ci = ci as usize;
            out.counts
                .push((ci as u32, self.nonempty[ci], self.present[ci]));
            self.nonempty[ci] = 0;
            self.present[ci] = 0;
        }
        self.touched.clear();
        out
    }

    /// Parses the row at the start of `rest` into `out` (a blank row gives
    /// nothing); returns where its line feed is (`rest.len()`: none).
    ///
    /// The row's cells and its end are found in one pass over its bytes
    /// ([`cells::scan_row`]); a row past the length limit is refused at its
    /// line as before, its cells found meanwhile being at most the header's
    /// width plus one.
    fn row(&mut self, rest: &[u8], line: u64, out: &mut Parsed) -> (usize, Result<(), RowFail>) {
        self.cells.clear();
        let cells = &mut self.cells;
        // Cells past the header's width are kept only as far as the first
        // one (the error names it): a hostile row of millions of fields
        // costs no memory beyond the row itself.
        let width = self.layout.width;
        let keep = |c: usize, a: usize, b: usize| {
            if cells.last().is_none_or(|l| l.0 < width) {
                cells.push((c, a, b));
            }
        };
        let (scan, end) = cells::scan_row(rest, keep);
        let len = if end < rest.len() { end + 1 } else { end };
        let limit = self.layout.limits.max_bytes;
        if len > limit {
            let e = RowError::TooLong { line, limit };
            return (end, Err((None, row_error(&self.layout.path, e))));
        }
        let result = match scan {
            Scan::Fields(n) => self.frame(rest, n, line, out),
            Scan::Quoted => self.quoted_row(&rest[..trim_eol(&rest[..len])], line, out),
        };
        (end, result)
    }

    /// A row with a quoted cell (`line_bytes` without its line end): split
    /// by the full CSV reader, then read like any other.
    fn quoted_row(
        &mut self,
        line_bytes: &[u8],
        line: u64,
        out: &mut Parsed,
    ) -> Result<(), RowFail> {
        let n = self.split_quoted(line_bytes, line)?;
        let quoted = std::mem::take(&mut self.quoted);
        let result = self.frame(&quoted, n, line, out);
        self.quoted = quoted;
        result
    }

    /// The frame of a row whose cells were found (`buf` holds them, `n`
    /// fields); nothing for a blank row.
    fn frame(&mut self, buf: &[u8], n: usize, line: u64, out: &mut Parsed) -> Result<(), RowFail> {
        if self.cells.is_empty() {
            return Ok(());
        }
        self.check_field_count(n, line).map_err(|e| (None, e))?;
        let (frame, time) = self.frame_and_time(buf, line).map_err(|e| (None, e))?;
        out.rows_read += 1;
        let start = out.poses.len();
        out.poses.resize(start + self.layout.pose_width, f64::NAN);
        match self.read_channel_cells(buf, line, &mut out.poses[start..]) {
            Ok(markers) => {
                out.frames.push(RowFrame {
                    line,
                    frame,
                    time,
                    markers,
                });
                Ok(())
            }
            Err(e) => {
                out.poses.truncate(start);
                Err((time.map(|t| (frame, t)), e))
            }
        }
    }

    /// A row with a quoted cell, through the full CSV reader (no quoted
    /// field may run over the line end in a data row); its fields go to
    /// `quoted`, its non-empty cells to `cells`. Returns the field count.
    fn split_quoted(&mut self, line_bytes: &[u8], line: u64) -> Result<usize, RowFail> {
        let mut rows = RowReader::new(line_bytes, self.layout.limits);
        rows.multiline = false;
        let shift = |e: RowError| (None, shifted(row_error(&self.layout.path, e), line - 1));
        rows.read().map_err(shift)?;
        self.cells.clear();
        for i in 0..rows.len() {
            let (a, b) = rows.field_range(i);
            if a < b && self.cells.last().is_none_or(|l| l.0 < self.layout.width) {
                self.cells.push((i, a, b));
            }
        }
        self.quoted.clear();
        self.quoted.extend_from_slice(rows.data_buffer());
        Ok(rows.len())
    }

    fn err(&self, line: u64, column: Option<u64>, msg: impl Into<String>) -> Error {
        Error::at_line(&self.layout.path, line, column, msg)
    }

    /// Refuses a row whose field count is not the header's: trailing empty
    /// cells may be cut by hand-edited files, but a row short of real data,
    /// or with data past the header, is malformed.
    fn check_field_count(&self, n: usize, line: u64) -> Result<(), Error> {
        let width = self.layout.width;
        let error = |column: usize| {
            self.err(
                line,
                Some(column as u64 + 1),
                format!("row has {n} fields, the header has {width}"),
            )
        };
        if n < width {
            return Err(error(n));
        }
        if let Some(&(c, _, _)) = self.cells.last().filter(|c| c.0 >= width) {
            return Err(error(c));
        }
        Ok(())
    }

    /// The row's frame number (required) and Time column (optional).
    fn frame_and_time(&self, buf: &[u8], line: u64) -> Result<(i64, Option<f64>), Error> {
        let text = |a: usize, b: usize| excerpt_bytes(&buf[a..b]);
        let (frame_cell, time_cell) = {
            let mut it = self.cells.iter().take(2).filter(|c| c.0 < 2);
            let first = it.next().copied();
            let second = it.next().copied();
            match first {
                Some(c) if c.0 == 0 => (Some(c), second),
                other => (None, other),
            }
        };
        let frame: i64 = frame_cell
            .and_then(|(_, a, b)| std::str::from_utf8(&buf[a..b]).ok()?.trim().parse().ok())
            .ok_or_else(|| {
                let t = frame_cell.map_or(String::new(), |(_, a, b)| text(a, b));
                self.err(
                    line,
                    Some(1),
                    format!("frame number \"{t}\" is not an integer"),
                )
            })?;
        let time = match time_cell {
            Some((_, a, b)) => Some(cells::number(buf, a, b).ok_or_else(|| {
                self.err(
                    line,
                    Some(2),
                    format!("time \"{}\" is not a number", text(a, b)),
                )
            })?),
            None => None,
        };
        Ok((frame, time))
    }

    /// Counts a non-empty cell of channel `ci`.
    #[inline]
    fn count_cell(&mut self, ci: usize) {
        if self.nonempty[ci] == 0 {
            self.touched.push(ci as u32);
        }
        self.nonempty[ci] += 1;
    }

    /// Reads the row's channel cells: markers with X, Y and Z become the
    /// frame's markers, other channels' values go to `poses` (this row's
    /// slice of pose values); counts non-empty cells and present channels.
    fn read_channel_cells(
        &mut self,
        buf: &[u8],
        line: u64,
        poses: &mut [f64],
    ) -> Result<Vec<Marker>, Error> {
        self.pose_filled.fill(0);
        let layout = std::sync::Arc::clone(&self.layout);
        let mut markers = Vec::with_capacity(self.last_markers);
        // The marker channel being filled: (channel, X Y Z, axes seen).
        let mut open: Option<(usize, [f64; 3], u8)> = None;
        for k in 0..self.cells.len() {
            let (c, a, b) = self.cells[k];
            let role = layout.roles[c];
            if role == NO_CHANNEL {
                continue;
            }
            let (ci, axis) = ((role >> 2) as usize, (role & 3) as usize);
            self.count_cell(ci);
            let slot = layout.pose_slot[ci];
            if slot == u32::MAX && axis == 3 {
                continue; // a marker's other columns (quality…) are not read
            }
            if slot == u32::MAX && open.is_some_and(|o| o.0 != ci) {
                self.close_marker(open.take(), &mut markers);
            }
            let v = cells::number(buf, a, b)
                .ok_or_else(|| not_a_number(&layout, line, c, &buf[a..b], ci, slot))?;
            if slot == u32::MAX {
                let o = open.get_or_insert((ci, [0.0; 3], 0));
                o.1[axis] = v;
                o.2 |= 1 << axis;
            } else {
                let p = layout.poses[slot as usize];
                poses[p.offset + c - p.first] = v;
                self.pose_filled[slot as usize] += 1;
            }
        }
        self.close_marker(open, &mut markers);
        self.last_markers = markers.len();
        for (slot, p) in layout.poses.iter().enumerate() {
            if self.pose_filled[slot] as usize == p.width {
                self.present[p.channel] += 1;
            }
        }
        Ok(markers)
    }

    /// Ends a marker channel's cells in a row: a marker if X, Y and Z were all there.
    fn close_marker(&mut self, open: Option<(usize, [f64; 3], u8)>, markers: &mut Vec<Marker>) {
        if let Some((ci, xyz, 0b111)) = open {
            self.present[ci] += 1;
            markers.push(Marker {
                position: DVec3::from_array(xyz) * self.layout.scale,
                id: Some(ci as i64),
            });
        }
    }
}

/// A row the row reader refused, as an error at its line.
pub(super) fn row_error(path: &std::path::Path, e: RowError) -> Error {
    let err = |line, column, msg: String| Error::at_line(path, line, column, msg);
    match e {
        RowError::Io(e) => Error::io(path, e),
        RowError::TooLong { line, limit } => err(
            line,
            None,
            format!(
                "row is longer than {} MiB: not a Motive CSV row (a quote left open?)",
                limit >> 20
            ),
        ),
        RowError::TooManyFields { line, limit } => err(
            line,
            Some(limit as u64 + 1),
            format!("row has more than {limit} fields, more than any Motive export"),
        ),
        RowError::UnterminatedQuote { line, column } => err(
            line,
            Some(column),
            "a quote opened here is not closed on this line (data rows hold no quotes)".into(),
        ),
    }
}

/// `e` with its line moved `by` lines down: errors found in a chunk count
/// lines from the chunk's start until the reader, which knows where the
/// chunk starts, places them.
pub(super) fn shifted(e: Error, by: u64) -> Error {
    match e {
        Error::Parse {
            path,
            at: Location::Line { line, column },
            msg,
        } => Error::Parse {
            path,
            at: Location::Line {
                line: line + by,
                column,
            },
            msg,
        },
        other => other,
    }
}

/// The error for a channel cell that is not a number, naming the channel
/// (`slot` is `u32::MAX` for marker channels, whose kind goes unsaid).
fn not_a_number(
    layout: &Layout,
    line: u64,
    column: usize,
    cell: &[u8],
    ci: usize,
    slot: u32,
) -> Error {
    let (name, kind) = &layout.channels[ci];
    let what = if slot == u32::MAX {
        format!("marker \"{}\"", excerpt(name))
    } else {
        format!("{} \"{}\"", kind_name(*kind), excerpt(name))
    };
    Error::at_line(
        &layout.path,
        line,
        Some(column as u64 + 1),
        format!("\"{}\" is not a number ({what})", excerpt_bytes(cell)),
    )
}

fn kind_name(kind: ChannelKind) -> &'static str {
    match kind {
        ChannelKind::RigidBody => "rigid body",
        ChannelKind::RigidBodyMarker => "rigid body marker",
        ChannelKind::Bone => "bone",
        ChannelKind::BoneMarker => "bone marker",
        _ => "column",
    }
}
