//! treemocap's own recording format: a long-form CSV, one row per marker
//! sample, with its header row first and what describes the session in a
//! small JSON file beside it (the sidecar).
//!
//! ```text
//! session.log.csv                  session.log.json
//! frame,time_s,id,x,y,z            {"format": "treemocap log", "version": 2,
//! 0,0,,0.1,1.2,0.3                  "source": "natnet 127.0.0.1:1510",
//! 0,0,,0.4,1.5,-0.2                 "frame_rate": 100.0, "units": "m",
//! 1,0.01,,,,                        "up_axis": "Y"}
//! ```
//!
//! Why this shape: any CSV tool reads it with no options
//! (`pandas.read_csv(path)`, a spreadsheet, `csvkit`), appending a frame is
//! appending lines, and a crash can only cut the last line. The metadata
//! is in the sidecar, not in `#` lines, because pandas and most tools fail
//! on those unless told `comment='#'`; without its sidecar a log is still
//! read, its frame rate taken from the frame numbers and times (with a
//! warning). Logs of format 1 (the metadata in `# key: value` lines before
//! the header row) are still read. Floats are written in Rust's shortest
//! round-trip form, so writer and reader round-trip bit for bit. A frame
//! with no markers is one row with empty x, y, z, so empty frames survive
//! the round trip. Rows of one frame are consecutive and share frame and
//! time; a change of either starts the next frame.
//!
//! The writer only hands whole frames to the OS and does so at least every
//! `flush_interval`, so a killed process leaves a file that ends on a frame
//! boundary and loses at most that interval.

use std::fs::File;
use std::io::{BufRead, BufReader, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use glam::DVec3;

use super::{Format, Recording, RecordingInfo};
use crate::error::{excerpt, Error, Result};
use crate::model::frame::{Marker, MarkerFrame};

/// First bytes of a format-1 log (metadata in `#` lines).
pub const MAGIC: &str = "# treemocap log";
/// The header row, the first line of a format-2 log; `detect` looks for it.
pub const COLUMNS: &str = "frame,time_s,id,x,y,z";
/// The format written.
const VERSION: u32 = 2;
/// The sidecar's `format` value.
const FORMAT_NAME: &str = "treemocap log";
/// Rows read to tell the frame rate of a log without its sidecar.
const RATE_PROBE_ROWS: usize = 100_000;

/// The sidecar of a log: `session.log.csv` → `session.log.json`.
pub fn sidecar_path(log: &Path) -> PathBuf {
    log.with_extension("json")
}

/// What the sidecar holds.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
struct Sidecar {
    format: String,
    version: u32,
    source: String,
    frame_rate: f64,
    units: String,
    up_axis: String,
}
/// Bytes buffered before a write is forced regardless of the interval.
const BUFFER_LIMIT: usize = 1 << 16;

/// What the header of a log names.
#[derive(Debug, Clone, PartialEq)]
pub struct LogHeader {
    /// Where the samples came from (free text on one line).
    pub source: String,
    /// Nominal frames per second of the source.
    pub frame_rate: f64,
}

/// Appends frames to a log file, flushing whole frames at least every
/// `flush_interval`.
///
/// A write that fails (a full disk) may have put part of the buffer in the
/// file; the file is then cut back to its last whole frame, the frames
/// after it are counted as lost, and the writer takes no more frames: a
/// later write could only splice rows into the middle of one. Starting a
/// new file is the owner's business (`app::recording`).
pub struct LogWriter {
    path: PathBuf,
    file: File,
    buf: Vec<u8>,
    /// End of each whole frame in `buf`, to cut a failed write back to.
    frame_ends: Vec<usize>,
    /// Bytes of the file that hold whole frames (the header included).
    written: u64,
    flush_interval: Duration,
    last_flush: Instant,
    samples: u64,
    /// Frames handed to the OS whole.
    frames_written: u64,
    /// Frames cut from the file or refused after a write failed.
    frames_lost: u64,
    /// Set by the first failed write; the file then ends at `written`.
    failed: bool,
}

impl LogWriter {
    /// Creates (truncates) `path` and writes the header.
    pub fn create(path: &Path, header: &LogHeader, flush_interval: Duration) -> Result<Self> {
        let file = File::create(path).map_err(|e| Error::io(path, e))?;
        let source: String = header
            .source
            .chars()
            .map(|c| if c.is_control() { ' ' } else { c })
            .collect();
        let mut w = LogWriter {
            path: path.to_path_buf(),
            file,
            buf: Vec::with_capacity(BUFFER_LIMIT + 4096),
            frame_ends: Vec::new(),
            written: 0,
            flush_interval,
            last_flush: Instant::now(),
            samples: 0,
            frames_written: 0,
            frames_lost: 0,
            failed: false,
        };
        w.write_sidecar(&source, header.frame_rate)?;
        w.buf.extend_from_slice(COLUMNS.as_bytes());
        w.buf.push(b'\n');
        // The header row is cut back like a frame (to nothing) if it fails.
        w.flush()?;
        Ok(w)
    }

    /// (Re)writes the sidecar, e.g. once the source's frame rate is known.
    pub fn write_sidecar(&self, source: &str, frame_rate: f64) -> Result<()> {
        let meta = Sidecar {
            format: FORMAT_NAME.into(),
            version: VERSION,
            source: source.to_string(),
            frame_rate,
            units: "m".into(),
            up_axis: "Y".into(),
        };
        let path = sidecar_path(&self.path);
        let text = serde_json::to_string_pretty(&meta).unwrap_or_default() + "\n";
        // Written whole to a temporary name and renamed, so a reader never
        // sees half a sidecar.
        let tmp = path.with_extension("json.tmp");
        std::fs::write(&tmp, text).map_err(|e| Error::io(&tmp, e))?;
        std::fs::rename(&tmp, &path).map_err(|e| Error::io(&path, e))
    }

    /// Appends one frame. It reaches the disk at the latest one flush interval later.
    pub fn write_frame(&mut self, frame: &MarkerFrame) -> Result<()> {
        if self.failed {
            self.frames_lost += 1;
            return Err(self.failed_error());
        }
        // The "frame,time," prefix is the same for every row of the frame:
        // format it once. ryu and itoa give the shortest round-trip text,
        // several times faster than `Display`.
        let mut f = ryu::Buffer::new();
        let mut i = itoa::Buffer::new();
        let mut prefix = [0u8; 64];
        let mut n = 0;
        for part in [
            i.format(frame.frame).as_bytes(),
            b",",
            f.format(frame.time_s).as_bytes(),
            b",",
        ] {
            prefix[n..n + part.len()].copy_from_slice(part);
            n += part.len();
        }
        let prefix = &prefix[..n];
        let buf = &mut self.buf;
        if frame.markers.is_empty() {
            buf.extend_from_slice(prefix);
            buf.extend_from_slice(b",,,\n");
        }
        for m in &frame.markers {
            buf.extend_from_slice(prefix);
            if let Some(id) = m.id {
                buf.extend_from_slice(i.format(id).as_bytes());
            }
            for v in m.position.to_array() {
                buf.push(b',');
                buf.extend_from_slice(f.format(v).as_bytes());
            }
            buf.push(b'\n');
        }
        self.frame_ends.push(self.buf.len());
        self.samples += frame.markers.len() as u64;
        if self.buf.len() >= BUFFER_LIMIT || self.last_flush.elapsed() >= self.flush_interval {
            self.flush()?;
        }
        Ok(())
    }

    /// Flushes if the interval has passed; a live source calls this on a timer
    /// so a quiet source still gets its last frames onto the disk.
    pub fn tick(&mut self) -> Result<()> {
        if !self.buf.is_empty() && self.last_flush.elapsed() >= self.flush_interval {
            self.flush()?;
        }
        Ok(())
    }

    /// Hands everything buffered (whole frames only) to the OS. On a write
    /// error the file is cut back to its last whole frame (see the type).
    pub fn flush(&mut self) -> Result<()> {
        if self.failed {
            return Err(self.failed_error());
        }
        let mut done = 0;
        while done < self.buf.len() {
            match self.file.write(&self.buf[done..]) {
                Ok(0) => return self.fail(done, std::io::ErrorKind::WriteZero.into()),
                Ok(n) => done += n,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => return self.fail(done, e),
            }
        }
        self.written += self.buf.len() as u64;
        self.frames_written += self.frame_ends.len() as u64;
        self.buf.clear();
        self.frame_ends.clear();
        self.last_flush = Instant::now();
        Ok(())
    }

    /// A write failed after `done` bytes of the buffer reached the file:
    /// keep the whole frames among them, cut the rest off the file, count
    /// the others as lost.
    fn fail(&mut self, done: usize, e: std::io::Error) -> Result<()> {
        let whole = self.frame_ends.partition_point(|&end| end <= done);
        let keep = if whole == 0 {
            0
        } else {
            self.frame_ends[whole - 1]
        };
        self.written += keep as u64;
        self.frames_written += whole as u64;
        self.frames_lost += (self.frame_ends.len() - whole) as u64;
        self.failed = true;
        self.buf.clear();
        self.frame_ends.clear();
        // Cutting a file frees space, so it works on a full disk too; if it
        // does not, the reader still stops at the cut row with a warning.
        let cut = self
            .file
            .set_len(self.written)
            .and_then(|()| self.file.seek(SeekFrom::Start(self.written)).map(drop));
        if let Err(c) = cut {
            tracing::warn!(
                "{}: cannot cut back to the last whole frame: {c}",
                self.path.display()
            );
        }
        Err(Error::io(&self.path, e))
    }

    fn failed_error(&self) -> Error {
        Error::Runtime(format!(
            "{}: an earlier write failed; the file ends at its last whole frame",
            self.path.display()
        ))
    }

    /// Marker samples written so far.
    pub fn samples(&self) -> u64 {
        self.samples
    }

    /// Frames handed to the OS whole so far.
    pub fn frames_written(&self) -> u64 {
        self.frames_written
    }

    /// Frames lost to a failed write (cut back, or refused after it).
    pub fn frames_lost(&self) -> u64 {
        self.frames_lost
    }

    /// True once a write failed.
    pub fn failed(&self) -> bool {
        self.failed
    }

    /// The file written.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Flushes and syncs to the disk.
    pub fn finish(mut self) -> Result<()> {
        self.flush()?;
        self.file.sync_all().map_err(|e| Error::io(&self.path, e))
    }
}

impl Drop for LogWriter {
    fn drop(&mut self) {
        if !self.failed {
            let _ = self.flush();
        }
    }
}

/// Reads a log frame by frame. At the end of the file `next()` returns
/// `None`; called again later it picks up rows appended since, so a log can
/// be followed while it is written. A last line without its newline (a crash
/// mid-write) is held back and, if never completed, reported as a warning.
pub struct LogReader {
    path: PathBuf,
    reader: BufReader<File>,
    info: RecordingInfo,
    line_no: u64,
    /// A line read without its newline, completed on the next read.
    partial: Vec<u8>,
    /// The first row of the next frame (or the error found there), read while
    /// finishing the previous frame; the finished frame is returned first.
    pending: Option<Result<Row>>,
    warnings: Vec<String>,
}

#[derive(Debug, Clone, Copy)]
struct Row {
    frame: i64,
    time_s: f64,
    marker: Option<Marker>,
}

impl LogReader {
    /// Reads the header of an opened log (`path` names it in errors; the
    /// sidecar is looked for beside it); frames are read by iterating. The
    /// frame rate and source come from the sidecar (format 2) or the `#`
    /// lines (format 1).
    pub fn from_file(file: File, path: &Path) -> Result<Self> {
        let mut reader = BufReader::new(file);
        let mut first_bytes = Vec::new();
        read_line_limited(&mut reader, &mut first_bytes).map_err(|e| line_error(path, 1, e))?;
        let first = line_text(&first_bytes)
            .map_err(|(col, msg)| Error::at_line(path, 1, Some(col), msg))?;
        let first_line = first.trim_end_matches(['\r', '\n']);
        let first_line = first_line.strip_prefix('\u{feff}').unwrap_or(first_line);
        let mut warnings = Vec::new();
        let (version, source, frame_rate, line_no) = if first_line == COLUMNS {
            let (source, rate) = read_sidecar(path, &mut warnings)?;
            (VERSION.to_string(), source, rate, 1)
        } else if first_line.starts_with(MAGIC) && first.ends_with('\n') {
            let (source, rate, lines) = read_v1_header(path, first_line, &mut reader)?;
            ("1".to_string(), source, rate, lines)
        } else {
            return Err(Error::at_line(
                path,
                1,
                None,
                format!("not a treemocap log (the first line must be '{COLUMNS}')"),
            ));
        };
        Ok(LogReader {
            path: path.to_path_buf(),
            reader,
            info: RecordingInfo {
                format: Format::Log,
                version,
                frame_rate,
                units: "m".into(),
                up_axis: "Y".into(),
                source,
            },
            line_no,
            partial: Vec::new(),
            pending: None,
            warnings,
        })
    }

    /// The next whole row, or `None` at the current end of the file.
    fn next_row(&mut self) -> Option<Result<Row>> {
        loop {
            let mut line = std::mem::take(&mut self.partial);
            match read_line_limited(&mut self.reader, &mut line) {
                Err(e) => return Some(Err(line_error(&self.path, self.line_no + 1, e))),
                Ok(0) => {
                    if !line.is_empty() {
                        self.partial = line;
                    }
                    return None;
                }
                Ok(_) if !line.ends_with(b"\n") => {
                    self.partial = line;
                    return None;
                }
                Ok(_) => {}
            }
            self.line_no += 1;
            let l = match line_text(&line) {
                Ok(l) => l.trim_end_matches(['\r', '\n']),
                Err((col, msg)) => {
                    return Some(Err(Error::at_line(
                        &self.path,
                        self.line_no,
                        Some(col),
                        msg,
                    )))
                }
            };
            if l.is_empty() || l.starts_with('#') {
                continue;
            }
            return Some(
                parse_row(l)
                    .map_err(|(col, msg)| Error::at_line(&self.path, self.line_no, Some(col), msg)),
            );
        }
    }
}

/// Source and frame rate from a format-2 log's sidecar, or (no sidecar)
/// the rate measured from the rows, with a warning.
fn read_sidecar(path: &Path, warnings: &mut Vec<String>) -> Result<(String, f64)> {
    let side = sidecar_path(path);
    let text = match std::fs::read_to_string(&side) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            let rate = probe_rate(path)?;
            let msg = format!(
                "{}: no sidecar {} beside it; frame rate {rate} Hz measured from the frame numbers and times",
                path.display(),
                side.display()
            );
            tracing::warn!("{msg}");
            warnings.push(msg);
            return Ok((String::new(), rate));
        }
        Err(e) => return Err(Error::io(&side, e)),
    };
    let meta: Sidecar = serde_json::from_str(&text).map_err(|e| Error::json(&side, &e))?;
    let field =
        |name: &str, msg: String| Error::parse(&side, crate::Location::Field(name.into()), msg);
    if meta.format != FORMAT_NAME || meta.version != VERSION {
        return Err(Error::Unsupported {
            path: side.clone(),
            msg: format!(
                "sidecar of format \"{}\" version {} (this build reads \"{FORMAT_NAME}\" version {VERSION})",
                excerpt(&meta.format), meta.version
            ),
        });
    }
    if !(meta.frame_rate.is_finite() && meta.frame_rate > 0.0) {
        return Err(field("frame_rate", "must be a positive number".into()));
    }
    if meta.units != "m" {
        return Err(field(
            "units",
            format!("\"{}\": logs are in metres (\"m\")", excerpt(&meta.units)),
        ));
    }
    if meta.up_axis != "Y" {
        return Err(field(
            "up_axis",
            format!("\"{}\": logs are Y up", excerpt(&meta.up_axis)),
        ));
    }
    Ok((meta.source, meta.frame_rate))
}

/// The frame rate of a log without its sidecar: frames over seconds between
/// the first frame and the last one within the first rows.
fn probe_rate(path: &Path) -> Result<f64> {
    let file = File::open(path).map_err(|e| Error::io(path, e))?;
    let mut first: Option<(i64, f64)> = None;
    let mut last: Option<(i64, f64)> = None;
    for line in BufReader::new(file).lines().skip(1).take(RATE_PROBE_ROWS) {
        let line = line.map_err(|e| Error::io(path, e))?;
        let Ok(row) = parse_row(line.trim_end()) else {
            continue; // the reader reports bad rows where it meets them
        };
        match first {
            None => first = Some((row.frame, row.time_s)),
            Some(f) if row.frame > f.0 && row.time_s > f.1 => last = Some((row.frame, row.time_s)),
            Some(_) => {}
        }
    }
    match (first, last) {
        (Some(a), Some(b)) => {
            let rate = (b.0 - a.0) as f64 / (b.1 - a.1);
            // Rates are set in whole or tenth hertz; time stamps jitter.
            Ok((rate * 10.0).round() / 10.0)
        }
        _ => Err(Error::at_line(
            path,
            1,
            None,
            format!(
                "no sidecar {} and fewer than two frames: the frame rate is unknown",
                sidecar_path(path).display()
            ),
        )),
    }
}

/// The `#` lines of a format-1 log up to its header row: (source, frame
/// rate, lines read).
fn read_v1_header(
    path: &Path,
    first_line: &str,
    reader: &mut BufReader<File>,
) -> Result<(String, f64, u64)> {
    let version = first_line.strip_prefix(MAGIC).unwrap_or_default();
    if version.trim() != "1" {
        return Err(Error::Unsupported {
            path: path.into(),
            msg: format!("unsupported log version \"{}\"", excerpt(version.trim())),
        });
    }
    let mut line_no = 1;
    let mut source = String::new();
    let mut frame_rate = None;
    let mut bytes = Vec::new();
    loop {
        line_no += 1;
        let l = read_header_line(path, reader, &mut bytes, line_no)?;
        if l == COLUMNS {
            break;
        }
        let Some(kv) = l.strip_prefix('#') else {
            return Err(Error::at_line(
                path,
                line_no,
                None,
                format!("expected a '# key: value' header line or '{COLUMNS}'"),
            ));
        };
        let (key, value) = kv.split_once(':').unwrap_or((kv, ""));
        let value = value.trim();
        let bad = |msg: String| Error::at_line(path, line_no, None, msg);
        match key.trim() {
            "source" => source = value.to_string(),
            "frame_rate" => frame_rate = Some(parse_frame_rate(value).map_err(bad)?),
            "units" if value != "m" => {
                return Err(bad(format!(
                    "units \"{}\": logs are in metres (\"m\")",
                    excerpt(value)
                )))
            }
            "up_axis" if value != "Y" => {
                return Err(bad(format!(
                    "up_axis \"{}\": logs are Y up",
                    excerpt(value)
                )))
            }
            _ => {} // unknown header keys are kept for newer writers
        }
    }
    let Some(frame_rate) = frame_rate else {
        return Err(Error::at_line(
            path,
            line_no,
            None,
            "log header has no frame_rate",
        ));
    };
    Ok((source, frame_rate, line_no))
}

/// Reads header line `line_no` into `bytes` and returns it without its line
/// end; a header cut before the column row is an error at that line.
fn read_header_line<'a>(
    path: &Path,
    reader: &mut BufReader<File>,
    bytes: &'a mut Vec<u8>,
    line_no: u64,
) -> Result<&'a str> {
    bytes.clear();
    let n = read_line_limited(&mut *reader, bytes).map_err(|e| line_error(path, line_no, e))?;
    let line =
        line_text(bytes).map_err(|(col, msg)| Error::at_line(path, line_no, Some(col), msg))?;
    if n == 0 || !line.ends_with('\n') {
        return Err(Error::at_line(
            path,
            line_no,
            None,
            "log header is incomplete (missing the 'frame,time_s,id,x,y,z' row)",
        ));
    }
    Ok(line.trim_end_matches(['\r', '\n']))
}

/// The `frame_rate` header value: a positive, finite number of frames per
/// second (it turns frame numbers into times).
fn parse_frame_rate(value: &str) -> std::result::Result<f64, String> {
    let rate: f64 = value
        .parse()
        .map_err(|_| format!("frame_rate \"{}\" is not a number", excerpt(value)))?;
    if !(rate.is_finite() && rate > 0.0) {
        return Err("frame_rate must be positive".into());
    }
    Ok(rate)
}

/// Longest line of a log: a row is under 100 bytes and a header line a
/// source description; a longer line is damage, and must not be read whole.
const MAX_LINE_BYTES: usize = 64 << 10;

/// Appends one line (with its newline, if it has one) to `line`, reading at
/// most up to [`MAX_LINE_BYTES`] in all; the bytes appended.
fn read_line_limited(reader: impl BufRead, line: &mut Vec<u8>) -> std::io::Result<usize> {
    let room = (MAX_LINE_BYTES + 1).saturating_sub(line.len()) as u64;
    let n = reader.take(room).read_until(b'\n', line)?;
    if line.len() > MAX_LINE_BYTES {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!(
                "a line is longer than {} KiB: not a treemocap log row",
                MAX_LINE_BYTES >> 10
            ),
        ));
    }
    Ok(n)
}

/// A read error, at its line when it is the line's fault (too long).
fn line_error(path: &Path, line: u64, e: std::io::Error) -> Error {
    if e.kind() == std::io::ErrorKind::InvalidData {
        Error::at_line(path, line, None, e.to_string())
    } else {
        Error::io(path, e)
    }
}

/// A line as text, or the (field, message) of its first invalid byte.
fn line_text(line: &[u8]) -> std::result::Result<&str, (u64, String)> {
    std::str::from_utf8(line).map_err(|e| {
        let valid = &line[..e.valid_up_to()];
        let field = valid.iter().filter(|&&b| b == b',').count() as u64 + 1;
        let bad = line.get(e.valid_up_to()).copied().unwrap_or(0);
        (
            field,
            format!(
                "not UTF-8 text (byte 0x{bad:02X} after \"{}\")",
                crate::error::excerpt_bytes(&valid[valid.len().saturating_sub(20)..])
            ),
        )
    })
}

fn parse_row(l: &str) -> std::result::Result<Row, (u64, String)> {
    let mut f = l.split(',');
    let mut field = |col: u64, name: &str| {
        f.next()
            .ok_or_else(|| (col, format!("row has too few fields (missing {name})")))
    };
    let frame_s = field(1, "frame")?;
    let time_s = field(2, "time_s")?;
    let id_s = field(3, "id")?;
    let xs = [field(4, "x")?, field(5, "y")?, field(6, "z")?];
    if f.next().is_some() {
        return Err((7, "row has more than 6 fields".into()));
    }
    let frame: i64 = frame_s.parse().map_err(|_| {
        (
            1,
            format!("frame \"{}\" is not an integer", excerpt(frame_s)),
        )
    })?;
    let time: f64 = time_s
        .parse()
        .map_err(|_| (2, format!("time_s \"{}\" is not a number", excerpt(time_s))))?;
    if xs.iter().all(|s| s.is_empty()) {
        return Ok(Row {
            frame,
            time_s: time,
            marker: None,
        });
    }
    let mut p = [0.0; 3];
    for (i, s) in xs.iter().enumerate() {
        p[i] = s.parse().map_err(|_| {
            (
                4 + i as u64,
                format!("coordinate \"{}\" is not a number", excerpt(s)),
            )
        })?;
    }
    let id = if id_s.is_empty() {
        None
    } else {
        Some(
            id_s.parse()
                .map_err(|_| (3, format!("id \"{}\" is not an integer", excerpt(id_s))))?,
        )
    };
    Ok(Row {
        frame,
        time_s: time,
        marker: Some(Marker {
            position: DVec3::from_array(p),
            id,
        }),
    })
}

impl Iterator for LogReader {
    type Item = Result<MarkerFrame>;

    fn next(&mut self) -> Option<Self::Item> {
        let first = match self.pending.take().or_else(|| self.next_row())? {
            Ok(r) => r,
            Err(e) => return Some(Err(e)),
        };
        let mut frame = MarkerFrame::new(first.frame, first.time_s, Vec::new());
        frame.markers.extend(first.marker);
        loop {
            match self.next_row() {
                None => break,
                Some(Err(e)) => {
                    self.pending = Some(Err(e));
                    break;
                }
                Some(Ok(r))
                    if r.frame == frame.frame && r.time_s.to_bits() == frame.time_s.to_bits() =>
                {
                    frame.markers.extend(r.marker)
                }
                Some(Ok(r)) => {
                    self.pending = Some(Ok(r));
                    break;
                }
            }
        }
        Some(Ok(frame))
    }
}

impl Recording for LogReader {
    fn info(&self) -> &RecordingInfo {
        &self.info
    }

    fn warnings(&self) -> &[String] {
        &self.warnings
    }
}

impl LogReader {
    /// Call at the end of a replay: turns a held-back partial line into a
    /// warning (the file was cut off mid-row, as by a crash).
    pub fn finish(&mut self) -> &[String] {
        if !self.partial.is_empty() {
            let msg = format!(
                "{}: line {}: last row is cut off (no newline); read up to the last whole row",
                self.path.display(),
                self.line_no + 1
            );
            tracing::warn!("{msg}");
            self.warnings.push(msg);
            self.partial.clear();
        }
        &self.warnings
    }
}
