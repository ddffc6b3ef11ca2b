//! Reconstruction of the branching structure from the captured tips by
//! particle flow (Long & Jones 2013 §5–6; spec §6–8).
//!
//! `reconstruct` turns captured tips and the wind into a `Tree`;
//! `run_and_write` also writes tree.glb, tree.json and tree.png, and is what
//! `treemocap reconstruct` and `treemocap replay` call.

pub mod flow;
pub mod hull;
pub mod leaves;
pub mod mesh;
pub mod radii;
pub mod tips_file;
pub mod tree;
pub mod trunk;
pub mod volume;

use std::path::{Path, PathBuf};

use glam::DVec3;
use serde::{Deserialize, Serialize};

use crate::config::{Config, ReconstructConfig};
use crate::error::{Error, Result};
use crate::rng::Rng;

pub use tips_file::{parse_tips, read_tips, TipsInput};
pub use tree::{Kind, Node, Tree};

/// A captured branch tip: a marker's rest position (contract 3).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CapturedTip {
    /// The marker's index in tips.json, kept through to the outputs so a
    /// captured tip can be matched to its live motion.
    pub marker: usize,
    /// Rest position (m, Y up).
    pub position: DVec3,
}

/// Labels of the independent random streams, so that e.g. a change in the
/// number of trunk nodes does not move every random tip.
const TRUNK_STREAM: u64 = 1;
const VOLUME_STREAM: u64 = 2;

/// Reconstructs a tree from captured tips (contract 3): trunk, random tips
/// in the crown volume, particle flow, pipe-model radii. `wind` is direction
/// × speed (zero when unknown). The same inputs and seed give the same tree.
pub fn reconstruct(
    tips: &[CapturedTip],
    wind: DVec3,
    cfg: &ReconstructConfig,
    seed: u64,
) -> Result<Tree> {
    Ok(reconstruct_with_volume(tips, wind, cfg, seed)?.0)
}

/// `reconstruct`, also returning the crown volume used (for checks and
/// reports).
pub fn reconstruct_with_volume(
    tips: &[CapturedTip],
    wind: DVec3,
    cfg: &ReconstructConfig,
    seed: u64,
) -> Result<(Tree, volume::Volume)> {
    cfg.validate()?;
    if tips.is_empty() {
        return Err(Error::Runtime(
            "no captured tips to reconstruct from".into(),
        ));
    }
    // A capture volume is metres across; anything beyond 10 km is a unit or
    // file error, and would only overflow the geometry further down.
    const FAR: f64 = 1e4;
    if let Some(t) = tips
        .iter()
        .find(|t| !t.position.is_finite() || t.position.abs().max_element() > FAR)
    {
        return Err(Error::Runtime(format!(
            "captured tip of marker {} is not a finite position within {FAR} m: {}",
            t.marker, t.position
        )));
    }
    if !wind.is_finite() || wind.length() > FAR {
        return Err(Error::Runtime(format!(
            "the wind vector {wind} is not finite or absurdly large"
        )));
    }
    let positions: Vec<DVec3> = tips.iter().map(|t| t.position).collect();
    let crown = trunk::Bounds::of(positions.iter().copied())
        .ok_or_else(|| Error::Runtime("no captured tips".into()))?;
    let trunk = trunk::Trunk::build(crown, cfg, &mut Rng::new(seed).fork(TRUNK_STREAM))?;
    let (volume, random) =
        volume::random_tips(&positions, cfg, &mut Rng::new(seed).fork(VOLUME_STREAM))?;

    let mut starts: Vec<(DVec3, Kind)> = tips
        .iter()
        .map(|t| (t.position, Kind::Captured { marker: t.marker }))
        .collect();
    starts.extend(random.into_iter().map(|p| (p, Kind::Tip)));
    let mut tree = flow::run(&starts, &trunk, wind, cfg)?;
    // Cheap (linear) and every output relies on it: fail loudly rather than
    // write a broken tree.
    tree.check()
        .map_err(|e| Error::Runtime(format!("reconstruction produced a broken tree: {e}")))?;
    radii::assign(&mut tree, cfg.tip_radius, cfg.gamma);
    Ok((tree, volume))
}

/// What a reconstruction produced, for the CLI and the daemon to print.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Report {
    /// Captured tips used.
    pub captured_tips: usize,
    /// Random tips added in the crown volume.
    pub random_tips: usize,
    /// Nodes in the skeleton.
    pub nodes: usize,
    /// Flow steps taken.
    pub steps: usize,
    /// Particles joined to the trunk after `max_steps` (should be 0).
    pub forced_joins: usize,
    /// Triangles of the branch mesh.
    pub branch_triangles: usize,
    /// Leaves (0 when leaves are off).
    pub leaves: usize,
    /// Files written, in order.
    pub files: Vec<PathBuf>,
}

/// Everything one reconstruction produces, in memory: the daemon shares
/// these very bytes with its viewers (`output::snapshot::TreeSnapshot`), and
/// `run_and_write` writes them to disk.
#[derive(Debug, Clone)]
pub struct Outputs {
    /// The tree itself.
    pub tree: Tree,
    /// tree.glb bytes.
    pub glb: Vec<u8>,
    /// tree.json text.
    pub tree_json: String,
    /// tree.png bytes.
    pub png: Vec<u8>,
    /// Counts for printing (its `files` is empty until written).
    pub report: Report,
}

/// Reconstructs with `config.reconstruct` (and its seed) and encodes the
/// three outputs, without touching the disk.
pub fn build_outputs(tips: &[CapturedTip], wind: DVec3, config: &Config) -> Result<Outputs> {
    let mut outputs = build_model(tips, wind, config)?;
    outputs.png = crate::output::picture::tree_png(&outputs.tree)?;
    Ok(outputs)
}

/// Like [`build_outputs`] without the picture (`png` left empty): the daemon
/// publishes the tree to its viewers first and draws the picture after.
pub fn build_model(tips: &[CapturedTip], wind: DVec3, config: &Config) -> Result<Outputs> {
    let cfg = &config.reconstruct;
    let tree = reconstruct(tips, wind, cfg, cfg.seed)?;
    let branch_mesh = mesh::branches(&tree, cfg.sides)?;
    let leaf_mesh = if cfg.leaves {
        Some(leaves::leaves(&tree, cfg, cfg.seed)?)
    } else {
        None
    };
    let glb = crate::output::gltf::to_glb(&tree, &branch_mesh, leaf_mesh.as_ref())?;
    let tree_json = crate::output::json::to_json(&tree, cfg)?;
    let png = Vec::new();
    let report = Report {
        captured_tips: tips.len(),
        random_tips: tree.nodes.iter().filter(|n| n.kind == Kind::Tip).count(),
        nodes: tree.nodes.len(),
        steps: tree.steps,
        forced_joins: tree.forced_joins,
        branch_triangles: branch_mesh.triangles(),
        leaves: leaf_mesh.map_or(0, |m| m.triangles() / 2),
        files: Vec::new(),
    };
    Ok(Outputs {
        tree,
        glb,
        tree_json,
        png,
        report,
    })
}

/// Reconstructs and writes `tree.glb`, `tree.json` and `tree.png` into
/// `out_dir` (created if missing), each atomically. Uses
/// `config.reconstruct` and its seed.
pub fn run_and_write(
    tips: &[CapturedTip],
    wind: DVec3,
    config: &Config,
    out_dir: &Path,
) -> Result<Report> {
    let outputs = build_outputs(tips, wind, config)?;
    std::fs::create_dir_all(out_dir).map_err(|e| Error::io(out_dir, e))?;
    let mut report = outputs.report;
    for (name, bytes) in [
        ("tree.glb", outputs.glb.as_slice()),
        ("tree.json", outputs.tree_json.as_bytes()),
        ("tree.png", outputs.png.as_slice()),
    ] {
        let path = out_dir.join(name);
        crate::output::write_atomic(&path, bytes)?;
        report.files.push(path);
    }
    Ok(report)
}
