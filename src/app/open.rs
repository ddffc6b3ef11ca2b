//! Opening a recorded session by its path: the format is detected from the
//! file's first bytes (not its extension) and the matching reader from
//! `format` streams its frames.

use std::fs::File;
use std::io::Read;
use std::path::{Path, PathBuf};

use crate::config::Config;
use crate::error::{Error, Location, Result};
use crate::format::c3d::{C3dOptions, C3dReader};
use crate::format::log::LogReader;
use crate::format::motive_csv::MotiveCsvReader;
use crate::format::pcap::{PcapOptions, PcapRecording};
use crate::model::recording::{Format, Recording};

/// Opens a recording with the settings of `config` that change how files
/// are read (`replay.time_tolerance_s`, `c3d.up_axis`). On a terminal, a
/// long file shows a progress bar while it is read (`replay`, `tips`,
/// `export`, `view`).
pub fn open_recording(path: &Path, config: &Config) -> Result<Box<dyn Recording>> {
    let format = detect(path)?;
    let file = open_file(path)?;
    let watch = super::progress::Watch::new(&file, path);
    let recording = from_file(format, file, path, &ReplayOptions::from_config(config))?;
    Ok(match watch {
        Some(w) => w.wrap(recording),
        None => recording,
    })
}

/// Looks at the first bytes of a file and says which format it is.
pub fn detect(path: &Path) -> Result<Format> {
    let mut head = [0u8; 512];
    let mut file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let n = read_up_to(&mut file, &mut head).map_err(|e| Error::io(path, e))?;
    let head = &head[..n];
    let text = head.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(head);
    if text.starts_with(crate::format::log::MAGIC.as_bytes())
        || text.starts_with(crate::format::log::COLUMNS.as_bytes())
    {
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
    } else if crate::format::c3d::looks_like_c3d(head) {
        Ok(Format::C3d)
    } else if crate::format::pcap::looks_like_pcap(head) {
        Ok(Format::Pcap)
    } else if n == 0 {
        Err(Error::parse(path, Location::Offset(0), "file is empty"))
    } else {
        Err(Error::Unsupported {
            path: path.into(),
            msg: "not a recording treemocap knows (expected a Motive CSV export starting with \
                  'Format Version', a C3D file, a pcap/pcapng capture or a treemocap log)"
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

/// Settings that change how recordings are interpreted (from the config).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReplayOptions {
    /// `replay.time_tolerance_s`: allowed disagreement of a Motive Time column.
    pub time_tolerance_s: f64,
    /// `c3d.up_axis`.
    pub c3d: crate::format::c3d::C3dOptions,
    /// `replay.natnet_version`, `natnet.markers` and `natnet.up_axis`.
    pub pcap: PcapOptions,
}

impl Default for ReplayOptions {
    fn default() -> Self {
        ReplayOptions::from_config(&crate::config::Config::default())
    }
}

impl ReplayOptions {
    /// The reading settings of `[replay]` and `[c3d]`.
    pub fn from_config(config: &crate::config::Config) -> Self {
        ReplayOptions {
            time_tolerance_s: config.replay.time_tolerance_s,
            c3d: crate::format::c3d::C3dOptions {
                up_axis: config.c3d.up_axis,
                strict: config.replay.strict,
            },
            pcap: PcapOptions {
                version: config.replay.natnet_version,
                markers: config.natnet.markers,
                up_axis: config.natnet.up_axis,
            },
        }
    }
}

/// Opens a recording of any supported format, detected by content, with
/// default options.
pub fn open(path: &Path) -> Result<Box<dyn Recording>> {
    open_with(path, &ReplayOptions::default())
}

/// Finds a recording named by a setting (`daemon.replay_file`): as given
/// (absolute, or relative to the current folder), else relative to the
/// program's folder and its parents, so the replay shipped in the
/// repository's `replays/` is found when the program runs from anywhere
/// (`target/release/treemocap`, a copy in `bin/` beside `replays/`).
/// Otherwise the error says where it looked and what to set.
pub fn locate(path: &Path, setting: &str) -> Result<PathBuf> {
    if path.exists() || path.is_absolute() {
        return Ok(path.to_path_buf());
    }
    let exe = std::env::current_exe().ok();
    let beside: Vec<PathBuf> = exe
        .iter()
        .flat_map(|e| e.ancestors().skip(1).take(4))
        .map(|dir| dir.join(path))
        .collect();
    if let Some(found) = beside.iter().find(|p| p.exists()) {
        tracing::info!("{}: using {}", path.display(), found.display());
        return Ok(found.clone());
    }
    let cwd = std::env::current_dir().map_or_else(|_| "?".into(), |d| d.display().to_string());
    let program = exe
        .as_deref()
        .and_then(Path::parent)
        .map_or_else(|| "?".into(), |d| d.display().to_string());
    Err(Error::Runtime(format!(
        "{}: no such file in the current folder ({cwd}) nor beside the program ({program} \
         and its parent folders); set {setting} to a recording (--set {setting}=PATH), \
         or daemon.source to \"natnet\" or \"osc\" for a live source",
        path.display()
    )))
}

/// Opens a recording of any supported format, detected by content.
pub fn open_with(path: &Path, options: &ReplayOptions) -> Result<Box<dyn Recording>> {
    from_file(detect(path)?, open_file(path)?, path, options)
}

/// The reader of `format` on an opened file (`path` names it in errors).
fn from_file(
    format: Format,
    file: File,
    path: &Path,
    options: &ReplayOptions,
) -> Result<Box<dyn Recording>> {
    Ok(match format {
        Format::MotiveCsv => Box::new(MotiveCsvReader::from_file(
            file,
            path,
            options.time_tolerance_s,
        )?),
        Format::Log => Box::new(LogReader::from_file(file, path)?),
        Format::C3d => Box::new(C3dReader::from_file(file, path, &options.c3d)?),
        Format::Pcap => Box::new(PcapRecording::new(
            Box::new(file),
            path.to_path_buf(),
            options.pcap,
        )?),
    })
}

fn open_file(path: &Path) -> Result<File> {
    File::open(path).map_err(|e| Error::io(path, e))
}

/// A Motive CSV export with the default Time-column tolerance.
pub fn motive_csv(path: &Path) -> Result<MotiveCsvReader> {
    motive_csv_with(path, crate::format::motive_csv::DEFAULT_TIME_TOLERANCE_S)
}

/// A Motive CSV export with `replay.time_tolerance_s`.
pub fn motive_csv_with(path: &Path, time_tolerance_s: f64) -> Result<MotiveCsvReader> {
    MotiveCsvReader::from_file(open_file(path)?, path, time_tolerance_s)
}

/// A treemocap log.
pub fn log(path: &Path) -> Result<LogReader> {
    LogReader::from_file(open_file(path)?, path)
}

/// A Wireshark/tcpdump capture of NatNet traffic.
pub fn pcap(path: &Path, options: PcapOptions) -> Result<PcapRecording> {
    PcapRecording::new(Box::new(open_file(path)?), path.to_path_buf(), options)
}

/// A C3D file.
pub fn c3d(path: &Path, options: &C3dOptions) -> Result<C3dReader> {
    C3dReader::from_file(open_file(path)?, path, options)
}
