//! `treemocap export SESSION --out FILE`: the cleaned, labelled tip
//! trajectories as C3D, CSV or TRC, chosen by FILE's extension (see
//! `render::trajectories` and docs/tracking.md).

use std::path::Path;

use crate::app::files::write_atomic;
use crate::app::open::open_recording;
use crate::config::Config;
use crate::error::{Error, Result};
use crate::render::trajectories;
use crate::track::{process, Summary};

/// The formats `export` writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ExportFormat {
    /// `.c3d`: float32 millimetres, Z up, residuals flag fills.
    C3d,
    /// `.csv`: one header row, metres, Y up.
    Csv,
    /// `.trc`: OpenSim's marker format, millimetres, Y up.
    Trc,
}

impl ExportFormat {
    /// From the output file's extension (case-insensitive).
    pub fn from_path(path: &Path) -> Result<Self> {
        let ext = path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase())
            .unwrap_or_default();
        match ext.as_str() {
            "c3d" => Ok(ExportFormat::C3d),
            "csv" => Ok(ExportFormat::Csv),
            "trc" => Ok(ExportFormat::Trc),
            _ => Err(Error::Unsupported {
                path: path.to_path_buf(),
                msg: format!("unknown export format '.{ext}' (use .c3d, .csv or .trc)"),
            }),
        }
    }
}

/// Runs the marker stage on `session` and writes the trajectories to
/// `out`; returns the stage's summary.
pub fn export_command(session: &Path, out: &Path, config: &Config) -> Result<Summary> {
    let format = ExportFormat::from_path(out)?;
    let mut recording = open_recording(session, config)?;
    let (tips, summary) = process(recording.as_mut(), &config.tracking)?;
    let name = out
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let bytes = match format {
        ExportFormat::C3d => trajectories::to_c3d(&tips),
        ExportFormat::Csv => trajectories::to_csv(&tips),
        ExportFormat::Trc => trajectories::to_trc(&tips, &name),
    };
    write_atomic(out, &bytes)?;
    Ok(summary)
}
