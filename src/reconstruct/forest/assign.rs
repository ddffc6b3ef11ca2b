//! Giving every tip to one tree once the trunk bases are known
//! (docs/forest.md, "Which tip belongs to which tree").
//!
//! - [`AssignRule::Livny`]: the shortest-path rule of Livny et al. 2010
//!   ([`super::graph`]), alone.
//! - [`AssignRule::Crown`] (ours): start from the tips clearly nearer one
//!   trunk than any other (horizontally), fit each tree's crown surface to
//!   its clear tips, give every tip to the surface it lies nearest, with a
//!   pull towards the trees of the tips it sways with, and repeat with the
//!   tips whose costs are clearly apart until nothing changes. Measured
//!   better than the shortest paths on every overlap (README, Tests).

use glam::DVec3;

use super::crown::{Crown, FitOptions};
use super::graph::path_costs;
use super::settings::{AssignRule, ForestSettings};
use super::sway::Coherence;

/// A tip is *clear* for the first fit when its horizontal distance to the
/// nearest trunk is below this fraction of the second nearest.
const CLEAR_START: f64 = 0.6;
/// …and for the refits when its best surface distance is below this
/// fraction of its second best.
const CLEAR_FIT: f64 = 0.5;
/// Ridge on the axis's offset and lean when the base is known: the axis
/// stays near its trunk unless many tips say otherwise.
const ANCHORED: FitOptions = FitOptions {
    offset_ridge: 1.0,
    lean: true,
    weighted: true,
};
/// Fewest clear tips a crown is fitted to; with fewer, all its tips.
const MIN_FIT: usize = 6;
/// Most refit rounds.
const ROUNDS: usize = 15;

/// Which tree each tip went to, and how sure that is.
#[derive(Debug, Clone, PartialEq)]
pub struct Assignment {
    /// Tree index of every tip, in the order of the tips given.
    pub tree: Vec<usize>,
    /// Each tip's cost for each tree (surface distance in m for the crown
    /// rule, summed squared path lengths in m² for Livny's).
    pub costs: Vec<Vec<f64>>,
    /// The rule that was applied (the crown rule falls back to Livny's when
    /// a tree has too few tips for a surface).
    pub rule: AssignRule,
}

impl Assignment {
    /// Tips whose best cost is more than `ratio` of their second best:
    /// `(tip index, best tree, second tree, best cost, second cost)`.
    pub fn ambiguous(&self, ratio: f64) -> Vec<(usize, usize, usize, f64, f64)> {
        let mut out = Vec::new();
        for (i, c) in self.costs.iter().enumerate() {
            let best = self.tree[i];
            let second = (0..c.len())
                .filter(|&t| t != best)
                .min_by(|&a, &b| c[a].total_cmp(&c[b]).then(a.cmp(&b)));
            if let Some(s) = second {
                if c[s].is_finite() && c[best] > ratio * c[s] {
                    out.push((i, best, s, c[best], c[s]));
                }
            }
        }
        out
    }
}

/// A link between two tips (indices into the tips) and its weight.
pub type Link = (usize, usize, f64);

/// Gives each of `tips` to one of the trees standing on `bases`.
pub fn assign(
    tips: &[DVec3],
    bases: &[DVec3],
    links: &[Link],
    sway: Option<&Coherence>,
    s: &ForestSettings,
) -> Assignment {
    if bases.len() <= 1 {
        return Assignment {
            tree: vec![0; tips.len()],
            costs: vec![vec![0.0; bases.len()]; tips.len()],
            rule: s.rule,
        };
    }
    let livny = || {
        let costs = path_costs(tips, bases, s.neighbours);
        Assignment {
            tree: costs.iter().map(|c| argmin(c)).collect(),
            costs,
            rule: AssignRule::Livny,
        }
    };
    match s.rule {
        AssignRule::Livny => livny(),
        AssignRule::Crown => crowns(tips, bases, links, sway, s).unwrap_or_else(livny),
    }
}

/// The crown rule; `None` when some tree has too few tips for a surface.
fn crowns(
    tips: &[DVec3],
    bases: &[DVec3],
    links: &[Link],
    sway: Option<&Coherence>,
    s: &ForestSettings,
) -> Option<Assignment> {
    let pull = Pull {
        links,
        weight: s.sway_weight_m,
        trunk: sway.filter(|_| s.trunk_weight_m > 0.0),
        trunk_weight: s.trunk_weight_m,
    };
    let horizontal: Vec<Vec<f64>> = tips
        .iter()
        .map(|p| bases.iter().map(|b| (p.x - b.x).hypot(p.z - b.z)).collect())
        .collect();
    let start: Vec<usize> = horizontal.iter().map(|c| argmin(c)).collect();
    let sure = clear(&horizontal, CLEAR_START);
    let mut costs = surface_costs(tips, bases, &start, &sure)?;
    let mut tree = pull.apply(&costs);
    for _ in 0..ROUNDS {
        let sure = clear(&costs, CLEAR_FIT);
        costs = surface_costs(tips, bases, &tree, &sure)?;
        let next = pull.apply(&costs);
        if next == tree {
            break;
        }
        tree = next;
    }
    Some(Assignment {
        tree,
        costs,
        rule: AssignRule::Crown,
    })
}

/// Each tip's distance from every tree's crown surface, the crowns fitted
/// to the tips of `tree` that are `clear` (all of a tree's tips when fewer
/// than [`MIN_FIT`] of them are).
fn surface_costs(
    tips: &[DVec3],
    bases: &[DVec3],
    tree: &[usize],
    clear: &[bool],
) -> Option<Vec<Vec<f64>>> {
    let mut crowns = Vec::with_capacity(bases.len());
    for (t, base) in bases.iter().enumerate() {
        let pick = |only_clear: bool| -> Vec<DVec3> {
            (0..tips.len())
                .filter(|&i| tree[i] == t && (clear[i] || !only_clear))
                .map(|i| tips[i])
                .collect()
        };
        let mut own = pick(true);
        if own.len() < MIN_FIT {
            own = pick(false);
        }
        crowns.push(Crown::fit(&own, *base, ANCHORED)?);
    }
    Some(
        tips.iter()
            .map(|p| crowns.iter().map(|c| c.distance(*p)).collect())
            .collect(),
    )
}

/// What pulls a tip towards a tree besides its crown: the limb links
/// (tips it sways with closely) and its trunk's sway (its mean correlation
/// with the tree's tips).
struct Pull<'a> {
    /// Limb links between tip indices.
    links: &'a [Link],
    /// Pull per unit of limb correlation (m).
    weight: f64,
    /// Every two tips' correlation, when the trunk pull is on.
    trunk: Option<&'a Coherence>,
    /// Pull per unit of mean correlation with a tree (m).
    trunk_weight: f64,
}

impl Pull<'_> {
    /// The tree of least cost for every tip, less `weight` × the
    /// correlation of each linked tip already in that tree and
    /// `trunk_weight` × its mean correlation with that tree's tips; a few
    /// rounds, all tips at once (the result does not depend on the order of
    /// the tips).
    fn apply(&self, costs: &[Vec<f64>]) -> Vec<usize> {
        let mut tree: Vec<usize> = costs.iter().map(|c| argmin(c)).collect();
        let limbs = self.weight > 0.0 && !self.links.is_empty();
        if !limbs && self.trunk.is_none() {
            return tree;
        }
        for _ in 0..5 {
            let mut pulled: Vec<Vec<f64>> = costs.to_vec();
            if limbs {
                for &(a, b, w) in self.links {
                    pulled[a][tree[b]] -= self.weight * w;
                    pulled[b][tree[a]] -= self.weight * w;
                }
            }
            if let Some(c) = self.trunk {
                // Every tip's mean with every tree in one pass over the
                // pairs (the same sums, in the same order, as one
                // `mean_with` per tip and tree).
                let k = pulled.first().map_or(0, Vec::len);
                let shared = c.means_with(&tree, k);
                for (a, row) in pulled.iter_mut().enumerate() {
                    for (t, cost) in row.iter_mut().enumerate() {
                        let with = shared.get(a).and_then(|m| m[t]);
                        *cost -= self.trunk_weight * with.unwrap_or(0.0);
                    }
                }
            }
            let next: Vec<usize> = pulled.iter().map(|c| argmin(c)).collect();
            if next == tree {
                break;
            }
            tree = next;
        }
        tree
    }
}

/// Tips whose best cost is below `ratio` × their second best.
fn clear(costs: &[Vec<f64>], ratio: f64) -> Vec<bool> {
    costs
        .iter()
        .map(|c| {
            let mut sorted = c.clone();
            sorted.sort_by(f64::total_cmp);
            sorted.len() < 2 || sorted[0] < ratio * sorted[1]
        })
        .collect()
}

/// Index of the least value (ties to the lower index; NaN last).
fn argmin(c: &[f64]) -> usize {
    let mut best = 0;
    for (i, v) in c.iter().enumerate() {
        if v.total_cmp(&c[best]).is_lt() {
            best = i;
        }
    }
    best
}
