//! `treemocap reconstruct TIPS.json`: the particle flow again on saved tips,
//! and the one place the tree files are written for a finished session
//! (`replay` writes through it too).

use std::path::Path;

use crate::app::files::write_atomic;
use crate::config::Config;
use crate::error::{Error, Result};
use crate::model::tips::parse_tips;
use crate::model::tips_traces::parse_traces;
use crate::reconstruct::forest::{self, SwayLink};
use crate::render::forest::forest_outputs;
use crate::render::outputs::{Motion, Outputs, Report};

/// Writes tree.glb, tree.json and tree.png of `outputs` into `out_dir`
/// (created if missing), each atomically, and returns the report with the
/// files listed in the order written.
pub fn write_tree_files(outputs: &Outputs, out_dir: &Path) -> Result<Report> {
    std::fs::create_dir_all(out_dir).map_err(|e| Error::io(out_dir, e))?;
    let mut report = outputs.report.clone();
    for (name, bytes) in [
        ("tree.glb", outputs.glb.as_slice()),
        ("tree.json", outputs.tree_json.as_bytes()),
        ("tree.png", outputs.png.as_slice()),
    ] {
        let path = out_dir.join(name);
        write_atomic(&path, bytes)?;
        report.files.push(path);
    }
    Ok(report)
}

/// Reconstructs from `tips` and the wind vector with `config.reconstruct`
/// (and its seed) and writes the tree files into `out_dir`: one tree, or
/// several (`[[trees]]`, or found from the tips; docs/forest.md). `links`
/// are the tips that sway together (empty without a wind phase); `motion`
/// says whether tree.glb is still, rigged or animated (a tree alone: several
/// trees are written still).
pub fn run_and_write(
    tips: &[crate::model::tips::CapturedTip],
    links: &[SwayLink],
    wind: glam::DVec3,
    config: &Config,
    motion: Motion<'_>,
    out_dir: &Path,
) -> Result<Report> {
    let plan = forest::plan(
        tips,
        links,
        &config.trees,
        &config.forest,
        &config.reconstruct,
    )?;
    write_tree_files(
        &forest_outputs(&plan, wind, &config.reconstruct, motion)?,
        out_dir,
    )
}

/// The command: reads `tips_path`, reconstructs, writes into `out_dir`.
/// When the file carries the tips' trajectories (`tips --json --traces`)
/// tree.glb is animated with them, unless `still`. tips.json holds no sway
/// links, so several trees are split by shape alone.
pub fn command(tips_path: &Path, config: &Config, still: bool, out_dir: &Path) -> Result<Report> {
    let text = std::fs::read_to_string(tips_path).map_err(|e| Error::io(tips_path, e))?;
    let input = parse_tips(&text, tips_path)?;
    let traces = if still {
        None
    } else {
        parse_traces(&text, tips_path)?
    };
    let motion = match &traces {
        Some(t) => Motion::Traces(t, &config.animate),
        None => Motion::Still,
    };
    run_and_write(&input.tips, &[], input.wind, config, motion, out_dir)
}
