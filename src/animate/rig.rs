//! What a tree needs to be deformed, computed once per tree: the nodes in
//! root-first order (slots), each slot's parent slot, rest position,
//! segment length, bending profile and tip counts, and who borrows motion
//! from whom.

use glam::DVec3;

use super::AnimateSettings;
use crate::error::{Error, Result};
use crate::model::tree::{Kind, Tree};

/// Shortest distance used in the borrowing weights (m): a random tip on top
/// of a captured tip would otherwise take an infinite weight.
const MIN_BORROW_DISTANCE: f64 = 1e-3;
/// Path lengths below this (m) count as the trunk base: profile 0.
const MIN_PATH: f64 = 1e-9;

/// A captured tip of the rig.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct CapturedSlot {
    /// Its slot (root-first index).
    pub(crate) slot: usize,
    /// Its node in the tree.
    pub(crate) node: usize,
    /// Its marker.
    pub(crate) marker: usize,
    /// 1 / profile: turns a displacement into a bend.
    pub(crate) inv_profile: f64,
}

/// One tip that borrows: from which captured tips (indices into
/// `Rig::captured`) with which weights (summing to 1).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Borrow {
    pub(crate) from: Vec<(usize, f64)>,
}

/// The deformation rig of one tree (docs/animation.md).
#[derive(Debug, Clone, PartialEq)]
pub struct Rig {
    /// Node index of each slot; slots are a breadth-first walk from the
    /// root, so a parent's slot comes before its children's.
    pub(crate) order: Vec<usize>,
    /// Parent slot of each slot (slot 0, the root, points at itself).
    pub(crate) parent: Vec<usize>,
    /// Rest position of each slot.
    pub(crate) rest: Vec<DVec3>,
    /// Rest length of the segment from the parent to each slot.
    pub(crate) length: Vec<f64>,
    /// Unit rest direction of that segment (Y for a zero-length one), used
    /// when a target coincides with the parent's new position.
    pub(crate) rest_dir: Vec<DVec3>,
    /// Bending profile `s^p` of each slot (0 at the root).
    pub(crate) profile: Vec<f64>,
    /// Number of tips in each slot's subtree (itself included).
    pub(crate) tips_below: Vec<f64>,
    /// Slots of the random tips.
    pub(crate) random: Vec<usize>,
    /// Profile of each random tip.
    pub(crate) random_profile: Vec<f64>,
    /// What each random tip borrows.
    pub(crate) random_borrow: Vec<Borrow>,
    /// The captured tips, in node index order.
    pub(crate) captured: Vec<CapturedSlot>,
    /// What each captured tip borrows when its marker is missing (its
    /// nearest other captured tips).
    pub(crate) captured_borrow: Vec<Borrow>,
    /// The random tips' borrowing in one flat list, `random_borrow` after
    /// another (what a frame reads: no pointer per tip to follow).
    pub(crate) random_from: Vec<(usize, f64)>,
    /// Each random tip's range in `random_from`.
    pub(crate) random_span: Vec<(usize, usize)>,
    /// Per slot: the index of its captured tip in `captured`, or
    /// [`NOT_CAPTURED`].
    pub(crate) captured_at: Vec<u32>,
    /// The captured tips' slots and all their ancestors', increasing: the
    /// only slots the correction's sums can reach (docs/animation.md,
    /// step 4.2), so that a frame sums over them and not the whole tree.
    pub(crate) spine: Vec<usize>,
}

/// `Rig::captured_at` of a slot that is not a captured tip.
pub(crate) const NOT_CAPTURED: u32 = u32::MAX;

impl Rig {
    /// The rig of `tree` (which must pass `Tree::check`).
    pub fn new(tree: &Tree, settings: &AnimateSettings) -> Result<Rig> {
        tree.check()
            .map_err(|e| Error::Runtime(format!("cannot animate a broken tree: {e}")))?;
        let order = tree.root_first_order();
        let slot_of = slots_of(tree, &order);
        let Skeleton {
            parent,
            rest,
            length,
            rest_dir,
            path,
        } = skeleton(tree, &order, &slot_of);
        let profile = bend_profile(&path, settings.bend_power);
        let tips_below = tips_below(tree, &order, &parent);
        let (captured, random) = tip_slots(tree, &slot_of, &profile);
        let k = settings.neighbours.max(1);
        let captured_pos: Vec<DVec3> = captured.iter().map(|c| rest[c.slot]).collect();
        let random_borrow: Vec<Borrow> = random
            .iter()
            .map(|&s| borrow(rest[s], &captured_pos, None, k))
            .collect();
        let captured_borrow = captured
            .iter()
            .enumerate()
            .map(|(i, c)| borrow(rest[c.slot], &captured_pos, Some(i), k))
            .collect();
        let random_profile = random.iter().map(|&s| profile[s]).collect();
        let (random_from, random_span) = flatten(&random_borrow);
        let mut captured_at = vec![NOT_CAPTURED; order.len()];
        for (i, c) in captured.iter().enumerate() {
            captured_at[c.slot] = u32::try_from(i)
                .map_err(|_| Error::Runtime("too many captured tips to animate".into()))?;
        }
        let spine = spine(&parent, &captured);
        Ok(Rig {
            order,
            parent,
            rest,
            length,
            rest_dir,
            profile,
            tips_below,
            random,
            random_profile,
            random_borrow,
            captured,
            captured_borrow,
            random_from,
            random_span,
            captured_at,
            spine,
        })
    }

    /// Number of nodes.
    pub fn nodes(&self) -> usize {
        self.order.len()
    }

    /// The markers of the captured tips, in the order [`Deformer::deform`]
    /// takes their displacements (node index order).
    ///
    /// [`Deformer::deform`]: super::Deformer::deform
    pub fn markers(&self) -> Vec<usize> {
        self.captured.iter().map(|c| c.marker).collect()
    }

    /// Every node's rest position, in node index order.
    pub fn rest_positions(&self) -> Vec<DVec3> {
        let mut out = vec![DVec3::ZERO; self.order.len()];
        for (slot, &node) in self.order.iter().enumerate() {
            out[node] = self.rest[slot];
        }
        out
    }

    /// The tree nodes of the captured tips, in the same order as `markers`.
    pub fn captured_nodes(&self) -> Vec<usize> {
        self.captured.iter().map(|c| c.node).collect()
    }
}

/// A range `[start, end)` in a flat list.
type Span = (usize, usize);

/// The borrow lists one after another, and each one's range.
fn flatten(borrows: &[Borrow]) -> (Vec<(usize, f64)>, Vec<Span>) {
    let mut from = Vec::with_capacity(borrows.iter().map(|b| b.from.len()).sum());
    let mut span = Vec::with_capacity(borrows.len());
    for b in borrows {
        let start = from.len();
        from.extend_from_slice(&b.from);
        span.push((start, from.len()));
    }
    (from, span)
}

/// The captured tips' slots and their ancestors', in increasing slot order
/// (the root included).
fn spine(parent: &[usize], captured: &[CapturedSlot]) -> Vec<usize> {
    let mut on = vec![false; parent.len()];
    for c in captured {
        let mut s = c.slot;
        while !on[s] {
            on[s] = true;
            if s == 0 {
                break;
            }
            s = parent[s];
        }
    }
    (0..parent.len()).filter(|&s| on[s]).collect()
}

/// Each node's slot in root-first order (the order the rig walks in).
fn slots_of(tree: &Tree, order: &[usize]) -> Vec<usize> {
    let mut slot_of = vec![0usize; tree.nodes.len()];
    for (slot, &node) in order.iter().enumerate() {
        slot_of[node] = slot;
    }
    slot_of
}

/// The rest pose by slot: what [`skeleton`] derives from the tree once so
/// that each frame only rotates and scales it.
struct Skeleton {
    /// Parent slot (the root's is 0).
    parent: Vec<usize>,
    /// Rest position.
    rest: Vec<DVec3>,
    /// Rest length of the segment from the parent.
    length: Vec<f64>,
    /// Rest direction of that segment (+Y for the root and zero segments).
    rest_dir: Vec<DVec3>,
    /// Path length from the root.
    path: Vec<f64>,
}

/// Walks the tree root first and measures each segment at rest.
fn skeleton(tree: &Tree, order: &[usize], slot_of: &[usize]) -> Skeleton {
    let n = order.len();
    let mut k = Skeleton {
        parent: vec![0usize; n],
        rest: vec![DVec3::ZERO; n],
        length: vec![0.0; n],
        rest_dir: vec![DVec3::Y; n],
        path: vec![0.0; n],
    };
    for (slot, &node) in order.iter().enumerate() {
        let here = tree.nodes[node].position;
        k.rest[slot] = here;
        if let Some(p) = tree.nodes[node].parent {
            let ps = slot_of[p];
            k.parent[slot] = ps;
            let seg = here - k.rest[ps];
            k.length[slot] = seg.length();
            k.rest_dir[slot] = seg.try_normalize().unwrap_or(DVec3::Y);
            k.path[slot] = k.path[ps] + k.length[slot];
        }
    }
    k
}

/// How much each slot bends: its path length from the root to the power
/// `bend_power`, 0 near the root (below [`MIN_PATH`]).
fn bend_profile(path: &[f64], bend_power: f64) -> Vec<f64> {
    path.iter()
        .map(|&s| {
            if s < MIN_PATH {
                0.0
            } else {
                s.powf(bend_power)
            }
        })
        .collect()
}

/// The number of tips at or below each slot.
fn tips_below(tree: &Tree, order: &[usize], parent: &[usize]) -> Vec<f64> {
    let n = order.len();
    let is_tip = |slot: usize| tree.nodes[order[slot]].kind.is_tip();
    let mut tips_below: Vec<f64> = (0..n).map(|s| f64::from(u8::from(is_tip(s)))).collect();
    for slot in (1..n).rev() {
        tips_below[parent[slot]] += tips_below[slot];
    }
    tips_below
}

/// The captured tips (driven by their markers) and the slots of the random
/// tips (which borrow their neighbours' motion), in node order.
fn tip_slots(tree: &Tree, slot_of: &[usize], profile: &[f64]) -> (Vec<CapturedSlot>, Vec<usize>) {
    let mut captured: Vec<CapturedSlot> = Vec::new();
    let mut random = Vec::new();
    for (node, nd) in tree.nodes.iter().enumerate() {
        let slot = slot_of[node];
        match nd.kind {
            Kind::Captured { marker } => captured.push(CapturedSlot {
                slot,
                node,
                marker,
                inv_profile: if profile[slot] > 0.0 {
                    1.0 / profile[slot]
                } else {
                    0.0
                },
            }),
            Kind::Tip => random.push(slot),
            _ => {}
        }
    }
    (captured, random)
}

/// Inverse-square-distance weights over the `k` captured tips nearest to
/// `at` (`skip` excluded), nearest first, ties to the lower index.
fn borrow(at: DVec3, captured: &[DVec3], skip: Option<usize>, k: usize) -> Borrow {
    let mut near: Vec<(f64, usize)> = captured
        .iter()
        .enumerate()
        .filter(|(i, _)| Some(*i) != skip)
        .map(|(i, c)| (c.distance(at), i))
        .collect();
    near.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    near.truncate(k);
    let weights: Vec<f64> = near
        .iter()
        .map(|(d, _)| 1.0 / d.max(MIN_BORROW_DISTANCE).powi(2))
        .collect();
    let total: f64 = weights.iter().sum();
    Borrow {
        from: near
            .iter()
            .zip(&weights)
            .map(|(&(_, i), &w)| (i, w / total))
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::animate::fixture::small_tree;
    use crate::animate::AnimateSettings;

    #[test]
    fn slots_profiles_and_borrowing() {
        let rig = Rig::new(&small_tree(), &AnimateSettings::default()).unwrap();
        assert_eq!(rig.order, vec![0, 1, 2, 5, 3, 4]);
        assert_eq!(rig.parent, vec![0, 0, 1, 1, 2, 2]);
        assert_eq!(rig.profile[0], 0.0);
        // Path to the junction: 1 + |(0.2, 0.5)|; profile = path².
        let s = 1.0 + DVec3::new(0.2, 0.5, 0.0).length();
        assert!((rig.profile[2] - s * s).abs() < 1e-12);
        assert_eq!(rig.tips_below, vec![3.0, 3.0, 2.0, 1.0, 1.0, 1.0]);
        assert_eq!(rig.markers(), vec![5, 2]);
        // The random tip borrows from both captured tips, the nearer more.
        let b = &rig.random_borrow[0].from;
        assert_eq!(b.len(), 2);
        assert_eq!(b[0].0, 0);
        assert!(b[0].1 > b[1].1 && (b[0].1 + b[1].1 - 1.0).abs() < 1e-12);
        // A captured tip never borrows from itself.
        assert_eq!(rig.captured_borrow[0].from, vec![(1, 1.0)]);
        // The flat copies of what a frame reads.
        assert_eq!(rig.random_span, vec![(0, 2)]);
        assert_eq!(rig.random_from, rig.random_borrow[0].from);
        assert_eq!(rig.captured_at[4], 0);
        assert_eq!(rig.captured_at[3], NOT_CAPTURED);
        // Tips 3 (slot 4) and 4 (slot 5) and their ancestors: not the
        // random tip (slot 3).
        assert_eq!(rig.spine, vec![0, 1, 2, 4, 5]);
    }

    #[test]
    fn a_broken_tree_is_an_error() {
        let mut tree = small_tree();
        tree.nodes[1].parent = Some(3);
        tree.nodes[3].parent = Some(1);
        assert!(Rig::new(&tree, &AnimateSettings::default()).is_err());
    }
}
