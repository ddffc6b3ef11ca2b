//! `treemocap synth`: a simulated capture session written as a Motive CSV
//! export with its ground truth beside it.

use std::io::BufWriter;
use std::path::Path;

use crate::error::{Error, Result};
use crate::sim::{generate, truth_path, SessionSummary, SynthOptions};

/// Generates a session and writes the Motive CSV to `csv` and the truth to
/// [`truth_path`]`(csv)`. An empty `take_name` becomes the file's stem.
pub fn write_session(opts: &SynthOptions, csv: &Path) -> Result<SessionSummary> {
    let mut opts = opts.clone();
    if opts.take_name.is_empty() {
        opts.take_name = csv
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
    }
    let syn = generate(&opts)?;
    let truth_file = truth_path(csv);
    if let Some(dir) = csv.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    }
    let file = std::fs::File::create(csv).map_err(|e| Error::io(csv, e))?;
    let mut out = BufWriter::with_capacity(1 << 20, file);
    crate::sim::motive_writer::write_motive_csv(&syn, &mut out).map_err(|e| Error::io(csv, e))?;
    drop(out);
    let mut json = serde_json::to_string_pretty(&syn.truth)
        .map_err(|e| Error::Runtime(format!("{}: {e}", truth_file.display())))?;
    json.push('\n');
    std::fs::write(&truth_file, json).map_err(|e| Error::io(&truth_file, e))?;

    let csv_bytes = std::fs::metadata(csv).map_err(|e| Error::io(csv, e))?.len();
    let t = &syn.truth;
    let missing: i64 = t
        .gaps
        .iter()
        .map(|g| g.last_frame - g.first_frame + 1)
        .sum();
    Ok(SessionSummary {
        csv: csv.to_path_buf(),
        truth: truth_file,
        csv_bytes,
        frames: t.frames,
        tips: t.tips.len(),
        columns: t.columns.len(),
        gaps: t.gaps.len(),
        gap_fraction: missing as f64 / (t.frames * t.tips.len()).max(1) as f64,
        spurious: t.spurious.len(),
        tree_height_m: t.tree.height,
        tree_nodes: t.tree.nodes.len(),
        wind_direction: t.wind_direction,
    })
}
