//! Growing the trees of a plan, each as a tree alone is grown, and
//! [`ForestCache`]: the daemon's memory of the last forest, so that only
//! the trees whose inputs changed are grown again.

use std::sync::Arc;

use glam::DVec3;

use super::{ForestPlan, TreePlan};
use crate::error::Result;
use crate::model::tips::CapturedTip;
use crate::model::tree::Tree;
use crate::reconstruct::{reconstruct_placed, Placement, ReconstructSettings};

/// One grown tree and whether it was grown just now.
#[derive(Debug, Clone)]
pub struct GrownTree {
    /// The tree.
    pub tree: Arc<Tree>,
    /// False when it was taken unchanged from the last forest.
    pub rebuilt: bool,
}

/// Grows every tree of `plan` afresh.
pub fn grow(plan: &ForestPlan, wind: DVec3, cfg: &ReconstructSettings) -> Result<Vec<Tree>> {
    plan.trees
        .iter()
        .map(|t| grow_one(plan, t, wind, cfg))
        .collect()
}

/// One tree of the plan: a tree alone exactly as always, one among several
/// at its base and inside its cell.
fn grow_one(
    plan: &ForestPlan,
    t: &TreePlan,
    wind: DVec3,
    cfg: &ReconstructSettings,
) -> Result<Tree> {
    let place = if plan.is_single() {
        Placement::default()
    } else {
        Placement {
            base: Some(t.base),
            cell: t.cell.clone(),
        }
    };
    Ok(reconstruct_placed(&t.tips, wind, cfg, t.seed, &place)?.0)
}

/// Everything a tree's reconstruction depends on: equal keys give equal
/// trees, byte for byte.
#[derive(Debug, Clone, PartialEq)]
struct Key {
    single: bool,
    base: DVec3,
    tips: Vec<CapturedTip>,
    cell: super::cell::Cell,
    seed: u64,
    wind: DVec3,
    settings: ReconstructSettings,
}

/// The last forest, tree by tree.
#[derive(Debug, Default)]
pub struct ForestCache {
    last: Vec<(usize, Key, Arc<Tree>)>,
}

impl ForestCache {
    /// Grows the trees of `plan` whose inputs differ from the last forest's
    /// tree of the same id, and takes the others as they were. The result
    /// equals [`grow`]'s.
    pub fn grow(
        &mut self,
        plan: &ForestPlan,
        wind: DVec3,
        cfg: &ReconstructSettings,
    ) -> Result<Vec<GrownTree>> {
        let mut next = Vec::with_capacity(plan.trees.len());
        let mut out = Vec::with_capacity(plan.trees.len());
        for t in &plan.trees {
            let key = Key {
                single: plan.is_single(),
                base: t.base,
                tips: t.tips.clone(),
                cell: t.cell.clone(),
                seed: t.seed,
                wind,
                settings: cfg.clone(),
            };
            let kept = self
                .last
                .iter()
                .find(|(id, k, _)| *id == t.id && *k == key)
                .map(|(_, _, tree)| tree.clone());
            let (tree, rebuilt) = match kept {
                Some(tree) => (tree, false),
                None => (Arc::new(grow_one(plan, t, wind, cfg)?), true),
            };
            next.push((t.id, key, tree.clone()));
            out.push(GrownTree { tree, rebuilt });
        }
        self.last = next;
        Ok(out)
    }
}
