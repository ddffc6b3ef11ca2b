//! C3D files, the motion-capture format every vendor writes (Motive, Vicon,
//! Qualisys, BTS, Optotrak…): a streaming point reader for all three
//! processor types and both storage kinds (spec/c3d.md).
//!
//! The file is read in three steps: the header block and the parameter
//! section ([`header`], [`params`]) are decoded from bytes, reconciled into a
//! [`layout::Layout`] (where the frames are, how many, in what units and up
//! axis), and then frames are read one at a time from the data section and
//! decoded by [`data::FrameDecoder`]. Analog data are read past, never
//! decoded. Every count and pointer is checked against the file's length
//! before it is used; bad input is an [`Error::Parse`] naming the file, the
//! byte offset and the field, never a panic.
//!
//! The crate c3dio was not used: it misses Motive's −32768 gaps, turns valid
//! BTS residuals into gaps, rejects a byte POINT:USED and panics on an ezc3d
//! file (spec/c3d.md §2).

use std::fs::File;
use std::io::{BufReader, Cursor, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::{Channel, ChannelKind, Format, Recording, RecordingInfo};
use crate::error::{Error, Location, Result};
use crate::model::frame::MarkerFrame;

pub mod data;
pub mod encode;
pub mod header;
pub mod layout;
pub mod params;
pub mod processor;

pub use layout::{Layout, Storage, UpChoice};
pub use processor::Processor;

/// A malformed spot in a C3D file, before the file name is attached.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FormatError {
    /// Byte offset from the start of the file.
    pub at: u64,
    /// What is wrong there, naming the field.
    pub msg: String,
}

impl FormatError {
    fn into_error(self, path: &Path) -> Error {
        Error::parse(path, Location::Offset(self.at), self.msg)
    }
}

pub use crate::model::frame::UpAxis;

/// The `c3d.up_axis` setting: which axis of a C3D file points up.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum UpAxisSetting {
    /// From POINT:Y_SCREEN ("+Z" = Z up, "+Y" = Y up); Z up when absent,
    /// as in most vendors' files.
    #[default]
    Auto,
    /// The file is Y up (Motive's default export).
    Y,
    /// The file is Z up (Vicon, Qualisys, Motive's "Z up" option).
    Z,
}

impl UpAxisSetting {
    fn choice(self) -> UpChoice {
        match self {
            UpAxisSetting::Auto => UpChoice::Auto,
            UpAxisSetting::Y => UpChoice::Fixed(UpAxis::Y),
            UpAxisSetting::Z => UpChoice::Fixed(UpAxis::Z),
        }
    }
}

/// How C3D files are interpreted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct C3dOptions {
    /// `c3d.up_axis` from the config.
    pub up_axis: UpAxisSetting,
    /// `replay.strict` (`--strict`): refuse a file that holds fewer frames
    /// than it declares instead of reading the complete ones.
    pub strict: bool,
}

/// Header byte 1 of a C3D file; what `detect` looks for.
pub fn looks_like_c3d(head: &[u8]) -> bool {
    head.len() >= 2 && head[1] == header::KEY && head[0] >= 1
}

/// Streaming reader of a C3D file's points.
pub struct C3dReader<R = BufReader<File>> {
    path: PathBuf,
    source: R,
    layout: Layout,
    decoder: data::FrameDecoder,
    info: RecordingInfo,
    channels: Vec<Channel>,
    warnings: Vec<String>,
    /// Frames whose bytes are all in the file (≤ `layout.frames`).
    frames_available: u64,
    next: u64,
    buf: Vec<u8>,
    present: Vec<u64>,
    done: bool,
}

impl C3dReader<BufReader<File>> {
    /// Reads the header and parameters of an opened file (`path` names it in
    /// errors) and positions at the first frame.
    pub fn from_file(file: File, path: &Path, options: &C3dOptions) -> Result<Self> {
        let len = file.metadata().map_err(|e| Error::io(path, e))?.len();
        C3dReader::new(path, BufReader::with_capacity(1 << 18, file), len, options)
    }
}

impl C3dReader<Cursor<Vec<u8>>> {
    /// Reads a C3D file held in memory; `name` only labels errors.
    pub fn from_bytes(name: &Path, bytes: Vec<u8>, options: &C3dOptions) -> Result<Self> {
        let len = bytes.len() as u64;
        C3dReader::new(name, Cursor::new(bytes), len, options)
    }
}

fn read_at<R: Read + Seek>(
    r: &mut R,
    path: &Path,
    at: u64,
    buf: &mut [u8],
    what: &str,
    file_len: u64,
) -> Result<()> {
    if at
        .checked_add(buf.len() as u64)
        .is_none_or(|end| end > file_len)
    {
        return Err(Error::parse(
            path,
            Location::Offset(at.min(file_len)),
            format!(
                "file ends ({file_len} bytes) before the {what} (bytes {at}..{})",
                at.saturating_add(buf.len() as u64)
            ),
        ));
    }
    r.seek(SeekFrom::Start(at))
        .map_err(|e| Error::io(path, e))?;
    r.read_exact(buf).map_err(|e| Error::io(path, e))
}

/// Reads the 512-byte header block and checks the two bytes every C3D file
/// starts with: the first parameter block (byte 0) and the key 0x50.
fn read_header_block<R: Read + Seek>(
    source: &mut R,
    path: &Path,
    file_len: u64,
) -> Result<([u8; header::BLOCK], u64)> {
    let mut block = [0u8; header::BLOCK];
    read_at(source, path, 0, &mut block, "512-byte header", file_len)?;
    if block[1] != header::KEY {
        return Err(Error::parse(
            path,
            Location::Offset(1),
            format!(
                "not a C3D file: header byte 1 is 0x{:02X}, expected 0x50",
                block[1]
            ),
        ));
    }
    let param_block = block[0] as u64;
    if param_block < 2 {
        return Err(Error::parse(
            path,
            Location::Offset(0),
            format!("header byte 0 (first parameter block) is {param_block}; it must be 2 or more"),
        ));
    }
    Ok((block, param_block))
}

/// Reads the parameter section's 4-byte prefix: the processor type, which
/// the header's numbers need to be decoded, and the section's block count.
fn read_parameter_prefix<R: Read + Seek>(
    source: &mut R,
    path: &Path,
    param_block: u64,
    file_len: u64,
) -> Result<(Processor, u8)> {
    let param_at = (param_block - 1) * header::BLOCK as u64;
    let mut prefix = [0u8; 4];
    read_at(
        source,
        path,
        param_at,
        &mut prefix,
        "parameter section (header byte 0)",
        file_len,
    )?;
    let processor = Processor::from_code(prefix[3]).ok_or_else(|| {
        Error::parse(
            path,
            Location::Offset(param_at + 3),
            format!(
                "processor type {} is not 84 (Intel), 85 (DEC) or 86 (MIPS)",
                prefix[3]
            ),
        )
    })?;
    Ok((processor, prefix[2]))
}

/// Reads and decodes the parameter section. The section is as long as its
/// block count says (as py-c3d reads it), but never overlaps a data section
/// that follows it; with no count it reaches up to that data section.
fn read_parameters<R: Read + Seek>(
    source: &mut R,
    path: &Path,
    param_block: u64,
    param_blocks: u8,
    data_block: u64,
    processor: Processor,
    file_len: u64,
) -> Result<params::Params> {
    let param_at = (param_block - 1) * header::BLOCK as u64;
    let mut end_block = if param_blocks > 0 {
        param_block + param_blocks as u64
    } else if data_block > param_block {
        data_block
    } else {
        param_block + 1
    };
    if data_block > param_block {
        end_block = end_block.min(data_block);
    }
    let end = (end_block - 1) * header::BLOCK as u64;
    if end > file_len {
        return Err(Error::parse(
            path,
            Location::Offset(file_len),
            format!(
                "file ends inside the parameter section (blocks {param_block} to {}, parameter byte 2 \
                 and header word 9)",
                end_block - 1
            ),
        ));
    }
    let mut section = vec![0u8; (end - param_at) as usize];
    read_at(
        source,
        path,
        param_at,
        &mut section,
        "parameter section",
        file_len,
    )?;
    params::decode(&section, param_at, processor).map_err(|e| e.into_error(path))
}

/// The frames the file really holds. A capture cut short (a full disk, an
/// interrupted copy): ezc3d and py-c3d read the complete frames, and so do
/// we, saying so once; --strict refuses the file.
fn complete_frames(
    layout: &Layout,
    file_len: u64,
    options: &C3dOptions,
    path: &Path,
    warnings: &mut Vec<String>,
) -> Result<u64> {
    let room = file_len.saturating_sub(layout.data_offset);
    let frames_available = if layout.frame_bytes == 0 {
        layout.frames
    } else {
        (room / layout.frame_bytes as u64).min(layout.frames)
    };
    if frames_available < layout.frames {
        let msg = format!(
            "the file declares {} frames but holds {frames_available} complete ones",
            layout.frames
        );
        if options.strict {
            let end = layout.data_offset + frames_available * layout.frame_bytes as u64;
            return Err(Error::parse(
                path,
                Location::Offset(end),
                format!("{msg}; refused (--strict)"),
            ));
        }
        warnings.push(format!(
            "{msg}; reading those (--strict refuses such files)"
        ));
    }
    Ok(frames_available)
}

/// One channel per point label; `*n` and `Unlabeled…` points are the
/// unlabeled markers vendors write.
fn marker_channels(layout: &Layout) -> Vec<Channel> {
    layout
        .labels
        .iter()
        .map(|name| Channel {
            name: name.clone(),
            kind: if name.starts_with('*') || name.starts_with("Unlabeled") {
                ChannelKind::Unlabeled
            } else {
                ChannelKind::Marker
            },
            present: 0,
            empty_cells: 0,
        })
        .collect()
}

/// What `inspect` and the reports say about the file: processor and
/// storage, rate, units, up axis, and the writing software (else the file
/// name).
fn recording_info(path: &Path, processor: Processor, layout: &Layout) -> RecordingInfo {
    RecordingInfo {
        format: Format::C3d,
        version: format!("{} {}", processor.name(), layout.storage.name()),
        frame_rate: layout.rate,
        units: layout.units.clone(),
        up_axis: match layout.up {
            UpAxis::Y => "Y".into(),
            UpAxis::Z => "Z".into(),
        },
        source: layout.software.clone().unwrap_or_else(|| {
            path.file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default()
        }),
    }
}

impl<R: Read + Seek + Send> C3dReader<R> {
    /// Decodes the header and parameters, reconciles them into a layout
    /// and positions `source` at the first frame.
    fn new(path: &Path, mut source: R, file_len: u64, options: &C3dOptions) -> Result<Self> {
        let (block, param_block) = read_header_block(&mut source, path, file_len)?;
        let (processor, param_blocks) =
            read_parameter_prefix(&mut source, path, param_block, file_len)?;
        let head = header::Header::decode(&block, processor);
        let params = read_parameters(
            &mut source,
            path,
            param_block,
            param_blocks,
            head.data_block as u64,
            processor,
            file_len,
        )?;
        let mut warnings = Vec::new();
        let layout = layout::resolve(
            &head,
            &params,
            processor,
            file_len,
            options.up_axis.choice(),
            &mut warnings,
        )
        .map_err(|e| e.into_error(path))?;
        let frames_available = complete_frames(&layout, file_len, options, path, &mut warnings)?;
        source
            .seek(SeekFrom::Start(layout.data_offset))
            .map_err(|e| Error::io(path, e))?;
        let channels = marker_channels(&layout);
        let info = recording_info(path, processor, &layout);
        for w in &warnings {
            tracing::warn!("{}: {w}", path.display());
        }
        Ok(C3dReader {
            path: path.to_path_buf(),
            source,
            decoder: data::FrameDecoder::new(&layout),
            buf: vec![0; layout.frame_bytes],
            present: vec![0; layout.points],
            layout,
            info,
            channels,
            warnings,
            frames_available,
            next: 0,
            done: false,
        })
    }

    /// The reconciled description of the file.
    pub fn layout(&self) -> &Layout {
        &self.layout
    }

    fn read_frame(&mut self) -> Result<MarkerFrame> {
        let index = self.next;
        let at = self.layout.data_offset + index * self.layout.frame_bytes as u64;
        self.source.read_exact(&mut self.buf).map_err(|e| {
            Error::parse(
                &self.path,
                Location::Offset(at),
                format!("frame {index}: {e}"),
            )
        })?;
        let mut markers = Vec::with_capacity(self.layout.points);
        self.decoder
            .decode(&self.buf, &mut markers, &mut self.present);
        self.next += 1;
        Ok(MarkerFrame::new(
            self.layout.first_frame + index as i64,
            index as f64 / self.layout.rate,
            markers,
        ))
    }

    fn update_channels(&mut self) {
        for (c, &n) in self.channels.iter_mut().zip(&self.present) {
            c.present = n;
            c.empty_cells = self.next - n;
        }
    }
}

impl<R: Read + Seek + Send> Iterator for C3dReader<R> {
    type Item = Result<MarkerFrame>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        if self.next >= self.frames_available {
            // Frames declared beyond the end of the file were warned about
            // at open (or refused with `strict`).
            self.done = true;
            return None;
        }
        let frame = self.read_frame();
        if frame.is_err() {
            self.done = true;
        }
        self.update_channels();
        Some(frame)
    }
}

impl<R: Read + Seek + Send> Recording for C3dReader<R> {
    fn info(&self) -> &RecordingInfo {
        &self.info
    }

    /// One channel per point; `present` and `empty_cells` count the frames
    /// read so far in which the point was valid or missing.
    fn channels(&self) -> &[Channel] {
        &self.channels
    }

    fn warnings(&self) -> &[String] {
        &self.warnings
    }
}

#[cfg(test)]
mod tests;
