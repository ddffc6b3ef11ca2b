//! One reconstruction's outputs in memory: the tree and its encoded
//! tree.glb, tree.json and tree.png. The daemon shares these very bytes with
//! its viewers and `app` writes them to disk. [`Motion`] chooses what
//! tree.glb carries beyond the still tree: a skin for live viewers, or the
//! session's captured motion as an animation (docs/animation.md).

use std::path::PathBuf;

use glam::DVec3;
use serde::Serialize;

use crate::animate::{animate, AnimateSettings, TipPaths};
use crate::error::Result;
use crate::model::motion::{Stretch, TreeMotion};
use crate::model::tips::CapturedTip;
use crate::model::tree::{Kind, Tree};
use crate::reconstruct::{leaves, mesh, reconstruct, ReconstructSettings};
use crate::render::gltf::{to_glb, Movement};

/// What tree.glb carries beyond the still tree.
#[derive(Clone, Copy)]
pub enum Motion<'a> {
    /// The still tree only (`--still`).
    Still,
    /// The skin without animation (the daemon: its viewers sway the tree
    /// with the live tips).
    Rigged,
    /// The skin and the captured motion of these tips' paths.
    Traces(&'a dyn TipPaths, &'a AnimateSettings),
}

/// The animation in tree.glb, for the report.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct AnimationReport {
    /// Keys of the animation.
    pub keys: usize,
    /// Its length (s).
    pub duration_s: f64,
    /// Recording time of its first key (s).
    pub start_s: f64,
    /// Key rate asked for (Hz).
    pub rate_hz: f64,
    /// The window was cut to `animate.max_duration_s`.
    pub cut: bool,
    /// Branch-length change over all segments and keys.
    pub stretch: Stretch,
    /// Size of tree.glb (bytes).
    pub glb_bytes: usize,
}

impl std::fmt::Display for AnimationReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "animation: {} keys over {:.2} s at {} Hz from {:.2} s{}, branch length change max {:.2} % mean {:.3} %, tree.glb {:.2} MB",
            self.keys,
            self.duration_s,
            self.rate_hz,
            self.start_s,
            if self.cut {
                " (cut to animate.max_duration_s)"
            } else {
                ""
            },
            self.stretch.max_pct,
            self.stretch.mean_pct,
            self.glb_bytes as f64 / 1e6
        )
    }
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
    /// The animation in tree.glb, when it has one.
    pub animation: Option<AnimationReport>,
    /// Files written, in order.
    pub files: Vec<PathBuf>,
    /// With several trees: the trees, how they were found, the close calls
    /// (docs/forest.md). `None` for a tree alone.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub forest: Option<super::forest_report::ForestReport>,
}

/// Everything one reconstruction produces, in memory: the daemon shares
/// these very bytes with its viewers (`output::snapshot::TreeSnapshot`), and
/// `run_and_write` writes them to disk.
#[derive(Debug, Clone)]
pub struct Outputs {
    /// The tree itself (the first tree of several).
    pub tree: Tree,
    /// Every tree with its id, name and base; one entry for a tree alone
    /// (empty from [`build_model`] until [`super::forest`] fills it).
    pub trees: Vec<super::forest_report::Member>,
    /// tree.glb bytes.
    pub glb: Vec<u8>,
    /// tree.json text.
    pub tree_json: String,
    /// tree.png bytes.
    pub png: Vec<u8>,
    /// The captured motion on the tree, when tree.glb is animated.
    pub motion: Option<TreeMotion>,
    /// Counts for printing (its `files` is empty until written).
    pub report: Report,
}

/// Reconstructs with `cfg` (and its seed) and encodes the
/// three outputs, without touching the disk.
pub fn build_outputs(
    tips: &[CapturedTip],
    wind: DVec3,
    cfg: &ReconstructSettings,
    motion: Motion<'_>,
) -> Result<Outputs> {
    let mut outputs = build_model(tips, wind, cfg, motion)?;
    outputs.png = super::picture::tree_png(&outputs.tree, outputs.motion.as_ref())?;
    Ok(outputs)
}

/// Like [`build_outputs`] without the picture (`png` left empty): the daemon
/// publishes the tree to its viewers first and draws the picture after.
pub fn build_model(
    tips: &[CapturedTip],
    wind: DVec3,
    cfg: &ReconstructSettings,
    motion: Motion<'_>,
) -> Result<Outputs> {
    let tree = reconstruct(tips, wind, cfg, cfg.seed)?;
    let branch_mesh = mesh::branches(&tree, cfg.sides)?;
    let leaf_mesh = if cfg.leaves {
        Some(leaves::leaves(&tree, cfg, cfg.seed)?)
    } else {
        None
    };
    let tree_motion = match motion {
        Motion::Traces(traced, settings) => Some(animate(&tree, traced, settings)?),
        Motion::Still | Motion::Rigged => None,
    };
    let movement = match (&tree_motion, motion) {
        (Some(m), _) => Movement::Animated(m),
        (None, Motion::Still) => Movement::Still,
        (None, _) => Movement::Rigged,
    };
    let glb = to_glb(&tree, &branch_mesh, leaf_mesh.as_ref(), movement)?;
    let animation = tree_motion.as_ref().map(|m| AnimationReport {
        keys: m.keys(),
        duration_s: m.times.last().copied().unwrap_or(0.0),
        start_s: m.start_s,
        rate_hz: m.rate_hz,
        cut: m.cut,
        stretch: m.stretch,
        glb_bytes: glb.len(),
    });
    let tree_json = super::json::to_json(&tree, cfg)?;
    let png = Vec::new();
    let report = Report {
        captured_tips: tips.len(),
        random_tips: tree.nodes.iter().filter(|n| n.kind == Kind::Tip).count(),
        nodes: tree.nodes.len(),
        steps: tree.steps,
        forced_joins: tree.forced_joins,
        branch_triangles: branch_mesh.triangles(),
        leaves: leaf_mesh.map_or(0, |m| m.triangles() / 2),
        animation,
        files: Vec::new(),
        forest: None,
    };
    Ok(Outputs {
        tree,
        trees: Vec::new(),
        glb,
        tree_json,
        png,
        motion: tree_motion,
        report,
    })
}

impl Report {
    /// The reconstruction's counts on one line, as `replay` and
    /// `reconstruct` print them.
    pub fn counts(&self) -> String {
        format!(
            "tree: {} captured + {} random tips, {} nodes, {} flow steps, {} forced joins, {} triangles, {} leaves",
            self.captured_tips,
            self.random_tips,
            self.nodes,
            self.steps,
            self.forced_joins,
            self.branch_triangles,
            self.leaves
        ) + &self
            .animation
            .map(|a| format!("\n{a}"))
            .unwrap_or_default()
    }
}

impl std::fmt::Display for Report {
    /// The counts, then a line per file written.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if let Some(forest) = &self.forest {
            write!(f, "{forest}")?;
        }
        writeln!(f, "{}", self.counts())?;
        for file in &self.files {
            writeln!(f, "wrote {}", file.display())?;
        }
        Ok(())
    }
}
