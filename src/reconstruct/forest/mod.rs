//! Several trees in one capture volume (docs/forest.md): where the trees
//! stand ([`detect`] or the configured `[[trees]]`), which captured tip
//! belongs to which tree ([`assign`], with [`graph`] — Livny et al. 2010's
//! shortest paths — and [`crown`] surfaces and [`sway`]), and the planes
//! that keep every tree to its own side ([`cell`]). [`grow`] then
//! reconstructs each tree as a tree alone is reconstructed; with one tree
//! the result is exactly what [`super::reconstruct`] gives.
//!
//! Pure: tips and settings in, a plan and trees out.

pub mod assign;
pub mod cell;
pub mod count;
pub mod crown;
pub mod detect;
pub mod graph;
pub mod grow;
pub mod settings;
pub mod sway;

use glam::DVec3;
use serde::Serialize;

use crate::error::Result;
use crate::model::tips::CapturedTip;
use crate::reconstruct::trunk::Bounds;
use crate::reconstruct::{ReconstructError, ReconstructSettings};
use crate::rng::Rng;

pub use count::{CountBasis, CountChoice};
pub use grow::{grow, ForestCache, GrownTree};
pub use settings::{AssignRule, ConfiguredTree, ForestSettings};
pub use sway::SwayLink;

/// Where a tree's base came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum BaseSource {
    /// A `[[trees]]` entry of the config.
    Configured,
    /// Found from the tips' rest positions.
    Detected,
}

/// One tree of the plan: everything its reconstruction depends on.
#[derive(Debug, Clone, PartialEq)]
pub struct TreePlan {
    /// The tree's id: its place among the configured trees, or among the
    /// found ones ordered by x then z.
    pub id: usize,
    /// What the outputs call it.
    pub name: String,
    /// Where the trunk stands (m).
    pub base: DVec3,
    /// Where `base` came from.
    pub source: BaseSource,
    /// Its captured tips.
    pub tips: Vec<CapturedTip>,
    /// Its side of the planes towards its neighbours.
    pub cell: cell::Cell,
    /// The seed of its random draws: `reconstruct.seed` for a tree alone,
    /// else derived from it and the id, so a tree does not change when
    /// another one does.
    pub seed: u64,
}

/// A tip that could nearly as well belong to another tree.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct AmbiguousTip {
    /// Its marker.
    pub marker: usize,
    /// The tree it was given to.
    pub tree: usize,
    /// The runner-up.
    pub other: usize,
    /// Its cost for `tree` and for `other` (m for the crown rule, m² for
    /// Livny's).
    pub costs: [f64; 2],
}

/// The trees, their tips and how sure the split is.
#[derive(Debug, Clone, PartialEq)]
pub struct ForestPlan {
    /// The trees that got tips, by id.
    pub trees: Vec<TreePlan>,
    /// Configured trees that got no tip (named in the report, not grown).
    pub empty: Vec<String>,
    /// Tips that were close calls.
    pub ambiguous: Vec<AmbiguousTip>,
    /// The rule that gave tips to trees.
    pub rule: AssignRule,
    /// The automatic search's RMS fit for each number of trees tried
    /// (empty when the trees are configured).
    pub fits: Vec<(usize, f64)>,
    /// False when the search found no number of trees that fits the tips
    /// within `forest.fit_tolerance_m`, and took the number with the least
    /// penalised RMS (`forest.count_penalty_m`).
    pub fits_well: bool,
    /// How the number of trees was chosen (by the crown fit or the sway,
    /// and with what margin); `None` when the trees are configured.
    pub count: Option<CountChoice>,
    /// Captured tips lying beyond one of their tree's planes (measured data
    /// is never moved; their first branch segment crosses the plane).
    pub beyond_planes: usize,
}

impl ForestPlan {
    /// True for a single tree placed as a tree alone has always been (no
    /// configured base): its reconstruction is exactly the one-tree one.
    pub fn is_single(&self) -> bool {
        self.trees.len() == 1 && self.trees[0].source == BaseSource::Detected
    }
}

/// Share of the tips that must have swayed (a known correlation with some
/// other tip) for the sway to choose the count and pull tips to trunks.
pub const MIN_SWAY_COVERAGE: f64 = 0.8;

/// Splits `tips` into trees: the configured ones, or those found. `links`
/// are the sway correlations of pairs of tips (by marker,
/// [`sway::links`]); empty when the session had no wind phase.
pub fn plan(
    tips: &[CapturedTip],
    links: &[SwayLink],
    configured: &[ConfiguredTree],
    s: &ForestSettings,
    recon: &ReconstructSettings,
) -> Result<ForestPlan> {
    if tips.is_empty() {
        return Err(ReconstructError::NoTips.into());
    }
    if let Some(t) = tips.iter().find(|t| !t.position.is_finite()) {
        return Err(ReconstructError::TipOutOfRange {
            marker: t.marker,
            position: t.position,
            limit_m: 1e4,
        }
        .into());
    }
    let positions: Vec<DVec3> = tips.iter().map(|t| t.position).collect();
    let index_of = |marker: usize| tips.iter().position(|t| t.marker == marker);
    let pairs: Vec<assign::Link> = links
        .iter()
        .filter_map(|l| Some((index_of(l.a)?, index_of(l.b)?, l.correlation)))
        .collect();
    let coherence = sway::Coherence::new(tips.len(), &pairs);
    // The sway decides only where the take swayed (docs/forest.md, "The
    // sway chooses the count"); a still take keeps the geometric rules.
    let swayed =
        (!pairs.is_empty() && coherence.coverage() >= MIN_SWAY_COVERAGE).then_some(&coherence);
    let bases = where_trees_stand(&positions, configured, s, swayed);
    let limbs = sway::limb_links(&pairs, &positions, s.sway_correlation);
    let split = assign::assign(&positions, &bases.centres, &limbs, swayed, s);
    let (mut trees, empty) = tree_plans(tips, &split, &bases, recon);
    let beyond_planes = place_in_cells(&mut trees, recon);
    let ambiguous = split
        .ambiguous(s.ambiguous_ratio)
        .into_iter()
        .map(|(i, tree, other, a, b)| AmbiguousTip {
            marker: tips[i].marker,
            tree,
            other,
            costs: [a, b],
        })
        .collect();
    Ok(ForestPlan {
        trees,
        empty,
        ambiguous,
        rule: split.rule,
        fits: bases.fits,
        fits_well: bases.fits_well,
        count: bases.count,
        beyond_planes,
    })
}

/// Where the trees stand before tips are given to them: configured, or
/// found from the tips (with how well the crowns fit).
struct Bases {
    /// One base per tree, in tree-id order.
    centres: Vec<DVec3>,
    /// The trees' names, in the same order.
    names: Vec<String>,
    /// Configured or detected (a detected base is moved under its tips).
    source: BaseSource,
    /// RMS fit of the crowns for each tree count tried (empty when
    /// configured).
    fits: Vec<(usize, f64)>,
    /// Whether the found crowns explain the tips (true when configured).
    fits_well: bool,
    /// How the number was chosen (`None` when configured).
    count: Option<CountChoice>,
}

fn where_trees_stand(
    positions: &[DVec3],
    configured: &[ConfiguredTree],
    s: &ForestSettings,
    swayed: Option<&sway::Coherence>,
) -> Bases {
    if configured.is_empty() {
        let found = detect::find(positions, s, swayed);
        let names = (0..found.centres.len())
            .map(settings::default_name)
            .collect();
        Bases {
            centres: found.centres,
            names,
            source: BaseSource::Detected,
            fits: found.rms,
            fits_well: found.fits,
            count: Some(found.count),
        }
    } else {
        Bases {
            centres: configured.iter().map(ConfiguredTree::base).collect(),
            names: (0..configured.len())
                .map(|i| settings::tree_name(configured, i))
                .collect(),
            source: BaseSource::Configured,
            fits: Vec::new(),
            fits_well: true,
            count: None,
        }
    }
}

/// One plan per tree that got tips, in tree-id order; the names of the
/// trees that got none (reported, not grown).
fn tree_plans(
    tips: &[CapturedTip],
    split: &assign::Assignment,
    bases: &Bases,
    recon: &ReconstructSettings,
) -> (Vec<TreePlan>, Vec<String>) {
    let mut trees = Vec::new();
    let mut empty = Vec::new();
    for (id, name) in bases.names.iter().enumerate() {
        let own: Vec<CapturedTip> = (0..tips.len())
            .filter(|&i| split.tree[i] == id)
            .map(|i| tips[i])
            .collect();
        if own.is_empty() {
            empty.push(name.clone());
            continue;
        }
        let base = match bases.source {
            BaseSource::Configured => bases.centres[id],
            // The ground under the centre of the tree's tips: where a tree
            // alone has always stood.
            BaseSource::Detected => {
                let b = Bounds::of(own.iter().map(|t| t.position)).unwrap_or(Bounds {
                    min: bases.centres[id],
                    max: bases.centres[id],
                });
                let c = 0.5 * (b.min + b.max);
                DVec3::new(c.x, recon.ground_height, c.z)
            }
        };
        trees.push(TreePlan {
            id,
            name: name.clone(),
            base,
            source: bases.source,
            tips: own,
            cell: cell::Cell::default(),
            seed: recon.seed,
        });
    }
    (trees, empty)
}

/// Gives each tree its cell (a tree alone: all of space) and, with several
/// trees, its own seed; the number of tips outside their own tree's cell.
fn place_in_cells(trees: &mut [TreePlan], recon: &ReconstructSettings) -> usize {
    let single = trees.len() == 1;
    let own_tips: Vec<Vec<DVec3>> = trees
        .iter()
        .map(|t| t.tips.iter().map(|c| c.position).collect())
        .collect();
    let cells = if single {
        vec![cell::Cell::default()]
    } else {
        cell::cells(&own_tips, recon.merge_distance)
    };
    let mut beyond_planes = 0;
    for ((t, c), own) in trees.iter_mut().zip(cells).zip(&own_tips) {
        beyond_planes += own.iter().filter(|p| !c.contains(**p)).count();
        t.cell = c;
        if !single {
            t.seed = tree_seed(recon.seed, t.id);
        }
    }
    beyond_planes
}

/// Label of the stream the per-tree seeds are drawn from.
const TREE_SEED_STREAM: u64 = 0x7EE5;

/// The seed of tree `id` among several: a fixed function of the configured
/// seed and the id alone.
pub fn tree_seed(seed: u64, id: usize) -> u64 {
    Rng::new(seed)
        .fork(TREE_SEED_STREAM.wrapping_add(id as u64))
        .next_u64()
}
