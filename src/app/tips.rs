//! What `treemocap tips` prints and writes: the tips table, the summary,
//! `tips.json` and the trace plot.

use std::fmt;
use std::path::Path;

use crate::app::files::write_atomic;
use crate::app::open::open_recording;
use crate::config::Config;
use crate::error::Result;
use crate::model::tips::Tips;
use crate::track::{process, Summary};

impl fmt::Display for Tips {
    /// The tips table: one line per marker, positions in metres.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "{:>6} {:>10} {:>10} {:>10} {:>8} {:>7} {:>10}",
            "marker", "x (m)", "y (m)", "z (m)", "samples", "gaps %", "spread mm"
        )?;
        for t in &self.tips {
            writeln!(
                f,
                "{:>6} {:>10.5} {:>10.5} {:>10.5} {:>8} {:>7.1} {:>10.3}",
                t.marker,
                t.rest.x,
                t.rest.y,
                t.rest.z,
                t.samples,
                t.gap_fraction * 100.0,
                t.spread_m * 1000.0
            )?;
        }
        Ok(())
    }
}

/// `treemocap tips FILE [--json OUT [--traces]] [--plot OUT.png]`: runs
/// the marker stage on a recording, writes the requested files, and returns
/// the text to print (table, then summary). `traces`: the JSON also holds
/// every tip's cleaned trajectory (docs/tracking.md).
pub fn tips_command(
    file: &Path,
    config: &Config,
    json_out: Option<&Path>,
    traces: bool,
    plot_out: Option<&Path>,
) -> Result<(Tips, Summary, String)> {
    let mut recording = open_recording(file, config)?;
    let (tips, summary) = process(recording.as_mut(), &config.tracking)?;
    if let Some(path) = json_out {
        if traces {
            let text = crate::render::trajectories::tips_json_with_traces(&tips);
            write_atomic(path, text.as_bytes())?;
        } else {
            write_atomic(path, tips.to_json().as_bytes())?;
        }
    }
    if let Some(path) = plot_out {
        write_atomic(path, &crate::render::plot::plot_traces(&tips)?)?;
    }
    let text = format!("{tips}\n{summary}\n");
    Ok((tips, summary, text))
}
