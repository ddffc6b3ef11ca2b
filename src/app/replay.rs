//! `treemocap replay`: the whole job on a recorded session, the same stages
//! the daemon runs live: read → track, fill, clean, average (`track`) → wind
//! → particle flow (`reconstruct`) → tips.json, tree.glb, tree.json, tree.png.

use std::fmt;
use std::path::{Path, PathBuf};

use glam::DVec3;

use crate::animate::KeyPaths;
use crate::app::files::write_atomic;
use crate::app::open::open_recording;
use crate::app::reconstruct::run_and_write;
use crate::config::Config;
use crate::error::Result;
use crate::model::tips::Tips;
use crate::model::trace::Trace;
use crate::model::wind::{WindEstimate, WindSource};
use crate::reconstruct::forest::sway;
use crate::render::outputs::{Motion, Report};
use crate::track::{self, Summary};
use crate::wind::{fan::configured_fan_wind, pca::SwayPca, WindSelector};

/// What a replay found and wrote.
pub struct ReplayReport {
    /// The tips found, as written to tips.json; their traces are dropped
    /// once the wind, the sway links and the animation's keys are taken
    /// from them (memory: `tips --json --traces` and `export` have them).
    pub tips: Tips,
    /// What the marker stage did, printed before the tree's line.
    pub summary: Summary,
    /// The wind used by the flow, with its source; `None` when no source
    /// gave one (the flow then runs without a wind force).
    pub wind: Option<WindEstimate>,
    /// Counts of the reconstruction (tips, nodes, steps, forced joins).
    pub tree: Report,
    /// Every file written, tips.json first.
    pub files: Vec<PathBuf>,
}

/// Runs the whole job on `file` and writes the results into `out_dir`;
/// tree.glb carries the session's motion as an animation.
pub fn run(file: &Path, config: &Config, out_dir: &Path) -> Result<ReplayReport> {
    run_with(file, config, false, out_dir)
}

/// [`run`], with `still` choosing the still tree.glb (no skin, no
/// animation).
pub fn run_with(file: &Path, config: &Config, still: bool, out_dir: &Path) -> Result<ReplayReport> {
    let mut rec = open_recording(file, config)?;
    let (mut tips, summary) = track::process(rec.as_mut(), &config.tracking)?;

    let wind = estimate_wind(&tips, config);
    tips.wind = wind;
    let wind_vector = wind.map_or(DVec3::ZERO, |w| w.flow_vector());

    std::fs::create_dir_all(out_dir).map_err(|e| crate::Error::io(out_dir, e))?;
    let tips_path = out_dir.join("tips.json");
    write_atomic(&tips_path, tips.to_json().as_bytes())?;
    let links = if config.forest.sway_weight_m > 0.0 {
        sway::links(&tips)
    } else {
        Vec::new()
    };
    // The animation needs the traces at its keys only: sampled there, the
    // traces go before the animation and tree.glb are built, so the two
    // never sit in memory together (on an hour-long take the traces are
    // most of the marker stage's memory, the animation a constant part).
    let keys = if still {
        None
    } else {
        Some(KeyPaths::of(&tips, &config.animate)?)
    };
    for tip in &mut tips.tips {
        tip.trace = Trace::default();
    }
    crate::memory::release_freed();
    let motion = match &keys {
        None => Motion::Still,
        Some(keys) => Motion::Traces(keys, &config.animate),
    };
    let tree = run_and_write(
        &tips.captured(),
        &links,
        wind_vector,
        config,
        motion,
        out_dir,
    )?;
    let mut files = vec![tips_path];
    files.extend(tree.files.iter().cloned());
    Ok(ReplayReport {
        tips,
        summary,
        wind,
        tree,
        files,
    })
}

/// The wind of a recorded session by the configured priority: the fan if
/// one is configured, else the principal axis of the tips' sway over the
/// whole session (a recording has no serial sensor).
pub fn estimate_wind(tips: &Tips, config: &Config) -> Option<WindEstimate> {
    let w = &config.wind;
    let end_s = tips.timeline.time(tips.timeline.len() as i64 - 1);
    let mut selector = WindSelector::new(w.priority.clone(), f64::INFINITY);
    let rest: Vec<DVec3> = tips.tips.iter().map(|t| t.rest).collect();
    if let Some(e) = configured_fan_wind(w, &rest, end_s) {
        selector.update(e);
    }
    if w.priority.contains(&WindSource::Pca) {
        let mut pca = SwayPca::new(f64::INFINITY, w.pca_min_sway_mm / 1000.0);
        for tip in &tips.tips {
            for (frame, p) in tip.trace.measurements() {
                pca.push(tips.timeline.time(frame), [p - tip.rest]);
            }
        }
        if let Some(e) = pca.estimate() {
            selector.update(WindEstimate { time_s: end_s, ..e });
        }
    }
    selector.current(end_s)
}

impl fmt::Display for ReplayReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "{}", self.summary)?;
        match &self.wind {
            Some(w) => writeln!(
                f,
                "wind: from {}, blowing towards azimuth {:.1}° ({:.3}, {:.3}, {:.3}){}",
                w.source.name(),
                w.azimuth_deg(),
                w.direction.x,
                w.direction.y,
                w.direction.z,
                w.speed_m_s
                    .map(|s| format!(", {s:.2} m/s"))
                    .unwrap_or_default()
            )?,
            None => writeln!(f, "wind: none (the tree did not sway; no fan configured)")?,
        }
        if let Some(forest) = &self.tree.forest {
            write!(f, "{forest}")?;
        }
        writeln!(f, "{}", self.tree.counts())?;
        for file in &self.files {
            writeln!(f, "wrote {}", file.display())?;
        }
        Ok(())
    }
}
