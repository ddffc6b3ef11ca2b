//! Several trees in one session (docs/forest.md, "Simulator"): 2–5 trees,
//! each grown as a tree alone is, turned at random about the vertical and
//! placed in a row or a cluster so that neighbouring crowns overlap by a
//! chosen fraction of the narrower crown's width; optionally the first
//! crown leans towards its neighbour.
//!
//! **ours**: markers go on the visible outside of the canopy. A branch tip
//! inside another tree's crown envelope gets no marker — the cameras could
//! not see it, and the paper places markers on the crown's edge for
//! visibility (§3) — and no marker is placed within `min_spacing_mm` of a
//! marker on another tree, so tracking can tell them apart.

use std::f64::consts::TAU;

use glam::DVec3;
use serde::{Deserialize, Serialize};

use super::tree::{grow, q9, CrownShape, TreeNode, TreeTruth};
use super::SynthOptions;
use crate::error::{Error, Result};
use crate::rng::Rng;

/// How the trees stand.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Layout {
    /// One after the other along x (with a little wander): a row of saplings.
    #[default]
    Row,
    /// Each tree beside a random one of those already placed.
    Cluster,
}

impl Layout {
    /// True for the default, so one-tree truth files leave it out.
    pub fn is_row(&self) -> bool {
        *self == Layout::Row
    }
}

impl std::str::FromStr for Layout {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s.to_ascii_lowercase().as_str() {
            "row" => Ok(Layout::Row),
            "cluster" => Ok(Layout::Cluster),
            _ => Err(format!("unknown layout '{s}' (expected row or cluster)")),
        }
    }
}

/// One tree of a forest session, in capture coordinates.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlacedTree {
    /// Where its trunk stands (m; y = 0).
    pub base: DVec3,
    /// Its turn about the vertical (rad).
    pub turn_rad: f64,
    /// How far its crown leans per metre above the crown's base (m/m,
    /// horizontal); zero for an upright tree.
    pub lean: DVec3,
    /// The tree, its nodes in capture coordinates (its envelope fields are
    /// its own, about its trunk).
    pub tree: TreeTruth,
}

impl PlacedTree {
    /// Where a capture-coordinate point lies in this tree's crown envelope
    /// (below 1 inside).
    pub fn envelope_ratio(&self, p: DVec3) -> f64 {
        let mut q = p - self.base;
        q -= self.lean * (q.y - self.tree.crown_base).max(0.0);
        let (s, c) = (-self.turn_rad).sin_cos();
        let local = DVec3::new(q.x * c - q.z * s, q.y, q.x * s + q.z * c);
        self.tree.envelope_ratio(local)
    }
}

/// The truth of a forest session: every tree, and which tree each tip is on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ForestTruth {
    /// The trees, in the order they were placed.
    pub trees: Vec<PlacedTree>,
    /// The tree of every tip, in tip-index order (what tip-to-tree
    /// assignment is scored against).
    pub tip_tree: Vec<usize>,
}

/// The trees placed, and the `(tree, node)` of every marked tip.
pub(crate) type Placed = (Vec<PlacedTree>, Vec<(usize, usize)>);

/// Grows and places `opts.trees` trees and picks their marked tips.
pub(crate) fn place(
    opts: &SynthOptions,
    root: &Rng,
    tree_stream: u64,
    layout_stream: u64,
) -> Result<Placed> {
    let mut layout = root.stream(layout_stream);
    let trees_rng = root.stream(tree_stream);
    let mut placed: Vec<PlacedTree> = Vec::with_capacity(opts.trees);
    for k in 0..opts.trees {
        let shape = if opts.mixed {
            if layout.chance(0.5) {
                CrownShape::Maple
            } else {
                CrownShape::Pine
            }
        } else {
            opts.shape
        };
        let local = grow(shape, &mut trees_rng.stream(k as u64 + 1));
        let turn = layout.range(0.0, TAU);
        let base = site(&placed, &local, opts, &mut layout)?;
        placed.push(PlacedTree {
            base,
            turn_rad: q9(turn),
            lean: DVec3::ZERO,
            tree: local,
        });
    }
    if opts.lean != 0.0 && placed.len() > 1 {
        let to = (placed[1].base - placed[0].base).normalize_or_zero();
        placed[0].lean = DVec3::new(q9(to.x * opts.lean), 0.0, q9(to.z * opts.lean));
    }
    let tips = markers(&placed, opts)?;
    for p in &mut placed {
        p.tree = to_world(p);
    }
    Ok((placed, tips))
}

/// Where the next tree stands: its crown overlapping a neighbour's by
/// `opts.overlap` of the narrower width, and no other crown by more.
fn site(placed: &[PlacedTree], t: &TreeTruth, opts: &SynthOptions, rng: &mut Rng) -> Result<DVec3> {
    let Some(last) = placed.last() else {
        return Ok(DVec3::ZERO);
    };
    let spacing = |other: &TreeTruth| {
        let (a, b) = (t.crown_radius, other.crown_radius);
        a + b - opts.overlap * 2.0 * a.min(b)
    };
    for _ in 0..500 {
        let (from, angle) = match opts.layout {
            Layout::Row => (last, rng.range(-0.3, 0.3)),
            Layout::Cluster => (
                &placed[rng.int(0, placed.len() as i64 - 1) as usize],
                rng.range(0.0, TAU),
            ),
        };
        let d = spacing(&from.tree);
        let at = from.base + DVec3::new(angle.cos() * d, 0.0, angle.sin() * d);
        let at = DVec3::new(q9(at.x), 0.0, q9(at.z));
        let clear = placed.iter().all(|p| {
            let h = (at - p.base).length();
            h >= spacing(&p.tree) - 1e-9
        });
        if clear {
            return Ok(at);
        }
    }
    Err(Error::config(
        "overlap",
        format!(
            "no place found for tree {} with this overlap; use fewer trees or another seed",
            placed.len()
        ),
    ))
}

/// A point of the tree's own coordinates turned, leaned and moved to its
/// base.
fn world(p: &PlacedTree, q: DVec3) -> DVec3 {
    let (s, c) = p.turn_rad.sin_cos();
    let mut w = DVec3::new(q.x * c - q.z * s, q.y, q.x * s + q.z * c);
    w += p.lean * (q.y - p.tree.crown_base).max(0.0);
    w += p.base;
    DVec3::new(q9(w.x), q9(w.y), q9(w.z))
}

/// The tree (still in its own coordinates) with its nodes in capture
/// coordinates.
fn to_world(p: &PlacedTree) -> TreeTruth {
    let nodes = p
        .tree
        .nodes
        .iter()
        .map(|n| TreeNode {
            position: world(p, n.position),
            ..n.clone()
        })
        .collect();
    TreeTruth {
        nodes,
        ..p.tree.clone()
    }
}

/// The marked tips of every tree (each tree still in its own coordinates,
/// where its crown envelope is): visible (in no other crown's envelope)
/// and away from the markers already placed on other trees.
fn markers(placed: &[PlacedTree], opts: &SynthOptions) -> Result<Vec<(usize, usize)>> {
    let spacing = opts.min_spacing_mm / 1000.0;
    let mut taken: Vec<DVec3> = Vec::new();
    let mut tips = Vec::new();
    for (k, p) in placed.iter().enumerate() {
        let visible = |i: usize| {
            let w = world(p, p.tree.nodes[i].position);
            placed
                .iter()
                .enumerate()
                .all(|(j, o)| j == k || o.envelope_ratio(w) >= 1.0)
                && taken.iter().all(|t| t.distance(w) >= spacing)
        };
        let nodes = p.tree.choose_tips_among(opts.tips, spacing, visible)?;
        taken.extend(nodes.iter().map(|&i| world(p, p.tree.nodes[i].position)));
        tips.extend(nodes.into_iter().map(|i| (k, i)));
    }
    Ok(tips)
}
