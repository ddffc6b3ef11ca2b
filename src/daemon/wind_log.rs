//! `wind.csv`: every wind estimate with its time and source, one line each,
//! flushed as written (estimates come a few times a second at most).

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::model::wind::WindEstimate;

/// Column names of wind.csv.
pub const HEADER: &str = "time_s,source,azimuth_deg,dir_x,dir_y,dir_z,speed_m_s";

/// Appends wind estimates to a CSV file.
pub struct WindLog {
    path: PathBuf,
    out: BufWriter<File>,
}

impl WindLog {
    /// Creates (truncates) `path` and writes the header line.
    pub fn create(path: &Path) -> Result<Self> {
        let file = File::create(path).map_err(|e| Error::io(path, e))?;
        let mut log = WindLog {
            path: path.to_path_buf(),
            out: BufWriter::new(file),
        };
        writeln!(log.out, "{HEADER}").map_err(|e| Error::io(path, e))?;
        log.out.flush().map_err(|e| Error::io(path, e))?;
        Ok(log)
    }

    /// Appends one estimate and flushes it, so the file is complete at any
    /// moment.
    pub fn write(&mut self, e: &WindEstimate) -> Result<()> {
        let speed = e.speed_m_s.map(|s| format!("{s:.3}")).unwrap_or_default();
        writeln!(
            self.out,
            "{:.4},{},{:.2},{:.6},{:.6},{:.6},{speed}",
            e.time_s,
            e.source.name(),
            e.azimuth_deg(),
            e.direction.x,
            e.direction.y,
            e.direction.z
        )
        .and_then(|_| self.out.flush())
        .map_err(|err| Error::io(&self.path, err))
    }
}
