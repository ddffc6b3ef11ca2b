//! Several trees' outputs (docs/forest.md): every tree grown (or taken from
//! the last forest), then one tree.glb with a node per tree, tree.json
//! version 2 with a list of trees, and one tree.png with all of them. A
//! single tree standing where a tree alone stands gives exactly the
//! one-tree outputs.

use std::sync::Arc;

use glam::DVec3;
use serde_json::json;

use crate::animate::animate;
use crate::error::Result;
use crate::model::motion::TreeMotion;
use crate::model::tree::{Kind, Tree};
use crate::reconstruct::forest::{self, ForestCache, ForestPlan};
use crate::reconstruct::{leaves, mesh, ReconstructSettings};
use crate::render::animation::combined_stretch;
use crate::render::outputs::{build_model, AnimationReport, Motion, Outputs, Report};

use super::forest_report::source_name;
pub use super::forest_report::{AmbiguousLine, ForestReport, Member, TreeLine};

/// Grows the trees of `plan` (through `cache` when given: only trees whose
/// inputs changed are grown) and encodes the outputs, the picture left
/// empty (see [`forest_picture`]).
pub fn forest_model(
    plan: &ForestPlan,
    wind: DVec3,
    cfg: &ReconstructSettings,
    motion: Motion<'_>,
    cache: Option<&mut ForestCache>,
) -> Result<Outputs> {
    if plan.is_single() {
        let mut out = build_model(&plan.trees[0].tips, wind, cfg, motion)?;
        out.trees = vec![member(plan, 0, Arc::new(out.tree.clone()), true)];
        return Ok(out);
    }
    let grown: Vec<(Arc<Tree>, bool)> = match cache {
        Some(c) => c
            .grow(plan, wind, cfg)?
            .into_iter()
            .map(|g| (g.tree, g.rebuilt))
            .collect(),
        None => forest::grow(plan, wind, cfg)?
            .into_iter()
            .map(|t| (Arc::new(t), true))
            .collect(),
    };
    let members: Vec<Member> = grown
        .into_iter()
        .enumerate()
        .map(|(k, (tree, rebuilt))| member(plan, k, tree, rebuilt))
        .collect();
    let meshes = tree_meshes(&members, cfg)?;
    let motions = forest_motions(&members, motion)?;
    let glb = super::gltf::forest_glb(
        &members
            .iter()
            .zip(&meshes)
            .enumerate()
            .map(|(k, (m, (b, l)))| super::gltf::ForestTree {
                name: &m.name,
                tree: &m.tree,
                branches: b,
                leaves: l.as_ref(),
                motion: motions.get(k),
            })
            .collect::<Vec<_>>(),
        matches!(motion, Motion::Rigged),
    )?;
    let mut report = forest_report(plan, &members, &meshes);
    report.animation = animation_report(&motions, glb.len());
    let tree_json = super::json::forest_json(
        &members
            .iter()
            .map(|m| super::json::ForestEntry {
                id: m.id,
                name: &m.name,
                base: m.base.to_array(),
                base_source: source_name(m.source),
                seed: m.seed,
                tree: &m.tree,
            })
            .collect::<Vec<_>>(),
        serde_json::to_value(report.forest.as_ref().map(|f| &f.ambiguous)).unwrap_or(json!([])),
        serde_json::to_value(report.forest.as_ref().and_then(|f| f.count.as_ref()))
            .unwrap_or(serde_json::Value::Null),
        wind.to_array(),
        cfg,
    )?;
    Ok(Outputs {
        tree: (*members[0].tree).clone(),
        trees: members,
        glb,
        tree_json,
        png: Vec::new(),
        // The picture of several trees is still (docs/forest.md); the
        // motion is in tree.glb and the report.
        motion: None,
        report,
    })
}

/// Each tree's branch surface and leaves (when asked for).
fn tree_meshes(
    members: &[Member],
    cfg: &ReconstructSettings,
) -> Result<Vec<(mesh::Mesh, Option<mesh::Mesh>)>> {
    members
        .iter()
        .map(|m| {
            let branches = mesh::branches(&m.tree, cfg.sides)?;
            let leaf = if cfg.leaves {
                Some(leaves::leaves(&m.tree, cfg, m.seed)?)
            } else {
                None
            };
            Ok((branches, leaf))
        })
        .collect()
}

/// Every tree's share of the session's motion when `motion` has traces
/// (each tree animated by its own captured tips, on the same keys), none
/// otherwise (rigged trees are skinned without a motion).
fn forest_motions(members: &[Member], motion: Motion<'_>) -> Result<Vec<TreeMotion>> {
    match motion {
        Motion::Traces(paths, settings) => members
            .iter()
            .map(|m| animate(&m.tree, paths, settings))
            .collect(),
        Motion::Still | Motion::Rigged => Ok(Vec::new()),
    }
}

/// The animation line of the report: the trees' common keys, the largest
/// and mean branch-length change over all of them.
fn animation_report(motions: &[TreeMotion], glb_bytes: usize) -> Option<AnimationReport> {
    let first = motions.first()?;
    let all: Vec<&TreeMotion> = motions.iter().collect();
    Some(AnimationReport {
        keys: first.keys(),
        duration_s: first.times.last().copied().unwrap_or(0.0),
        start_s: first.start_s,
        rate_hz: first.rate_hz,
        cut: first.cut,
        stretch: combined_stretch(&all),
        glb_bytes,
    })
}

/// [`forest_model`] and its picture.
pub fn forest_outputs(
    plan: &ForestPlan,
    wind: DVec3,
    cfg: &ReconstructSettings,
    motion: Motion<'_>,
) -> Result<Outputs> {
    let mut out = forest_model(plan, wind, cfg, motion, None)?;
    out.png = forest_picture(
        &out.tree,
        &out.trees,
        out.report.forest.is_some(),
        out.motion.as_ref(),
    )?;
    Ok(out)
}

/// tree.png of outputs (their `tree`, `trees`, whether they are a forest,
/// and the tree's motion): the one-tree picture for a tree alone, every
/// tree named (and still) otherwise.
pub fn forest_picture(
    tree: &Tree,
    trees: &[Member],
    forest: bool,
    motion: Option<&TreeMotion>,
) -> Result<Vec<u8>> {
    if !forest {
        return super::picture::tree_png(tree, motion);
    }
    let named: Vec<(&str, &Tree)> = trees.iter().map(|m| (m.name.as_str(), &*m.tree)).collect();
    super::picture::forest_png(&named)
}

fn member(plan: &ForestPlan, k: usize, tree: Arc<Tree>, rebuilt: bool) -> Member {
    let t = &plan.trees[k];
    Member {
        id: t.id,
        name: t.name.clone(),
        base: t.base,
        source: t.source,
        seed: t.seed,
        tree,
        rebuilt,
    }
}

/// The summed counts and the forest's lines.
fn forest_report(
    plan: &ForestPlan,
    members: &[Member],
    meshes: &[(mesh::Mesh, Option<mesh::Mesh>)],
) -> Report {
    let name_of = |id: usize| {
        plan.trees
            .iter()
            .find(|t| t.id == id)
            .map_or_else(|| forest::settings::default_name(id), |t| t.name.clone())
    };
    let count = |f: &dyn Fn(&Tree) -> usize| members.iter().map(|m| f(&m.tree)).sum::<usize>();
    Report {
        captured_tips: plan.trees.iter().map(|t| t.tips.len()).sum(),
        random_tips: count(&|t| t.nodes.iter().filter(|n| n.kind == Kind::Tip).count()),
        nodes: count(&|t| t.nodes.len()),
        steps: members.iter().map(|m| m.tree.steps).max().unwrap_or(0),
        forced_joins: count(&|t| t.forced_joins),
        branch_triangles: meshes.iter().map(|(b, _)| b.triangles()).sum(),
        leaves: meshes
            .iter()
            .map(|(_, l)| l.as_ref().map_or(0, |m| m.triangles() / 2))
            .sum(),
        animation: None,
        files: Vec::new(),
        forest: Some(ForestReport {
            trees: members
                .iter()
                .zip(&plan.trees)
                .map(|(m, t)| TreeLine {
                    id: m.id,
                    name: m.name.clone(),
                    base: m.base.to_array(),
                    source: m.source,
                    tips: t.tips.len(),
                    nodes: m.tree.nodes.len(),
                    forced_joins: m.tree.forced_joins,
                    rebuilt: m.rebuilt,
                })
                .collect(),
            empty: plan.empty.clone(),
            rule: plan.rule,
            fits: plan.fits.clone(),
            fits_well: plan.fits_well,
            count: plan.count.clone(),
            ambiguous: plan
                .ambiguous
                .iter()
                .map(|a| AmbiguousLine {
                    marker: a.marker,
                    tree: name_of(a.tree),
                    other: name_of(a.other),
                    costs: a.costs,
                })
                .collect(),
            beyond_planes: plan.beyond_planes,
        }),
    }
}
