//! What a tree needs to be deformed, computed once per tree: the inner
//! nodes in root-first order (slots), each slot's parent slot, rest
//! position, segment length and bending profile, the random tips at branch
//! ends apart (the leaves: most of a big tree's nodes, deformed in one
//! compact f32 pass), and who borrows motion from whom.

use glam::{DVec3, Vec3A};

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
    /// Its slot (root-first index among the inner slots).
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

/// What the first leaf pass reads of a leaf: where its bend goes and how
/// much it bends (8 bytes, so that the pass streams little memory).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct LeafBend {
    /// Inner slot of its parent.
    pub(crate) parent: u32,
    /// Its bending profile `s^p`.
    pub(crate) profile: f32,
}

/// What the second leaf pass reads of a leaf: its segment at rest, relative
/// to its parent (small numbers: f32 keeps them to well under a micrometre).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct LeafSegment {
    /// Rest offset from its parent (m; a SIMD vector, as the pass reads
    /// it).
    pub(crate) rel: Vec3A,
    /// Inner slot of its parent.
    pub(crate) parent: u32,
    /// Its node (where its position goes in the output).
    pub(crate) node: u32,
    /// Rest length of its segment (m).
    pub(crate) length: f32,
}

/// The deformation rig of one tree (docs/animation.md, "Speed").
///
/// A node is either a *leaf* (a random tip at a branch end: nothing hangs
/// on it, no tracked tip is below it, so its position follows from its
/// parent's and its own bend alone) or an *inner* node (everything else:
/// the trunk, junctions, the captured tips, a random tip something hangs
/// on). Inner nodes are the slots, in root-first order.
#[derive(Debug, Clone, PartialEq)]
pub struct Rig {
    /// Number of nodes of the tree.
    pub(crate) nodes: usize,
    /// Node index of each slot; slots are a breadth-first walk from the
    /// root over the inner nodes, so a parent's slot comes before its
    /// children's.
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
    /// The captured tips, in node index order.
    pub(crate) captured: Vec<CapturedSlot>,
    /// What each captured tip borrows when its marker is missing (its
    /// nearest other captured tips).
    pub(crate) captured_borrow: Vec<Borrow>,
    /// Slots of the random tips that something hangs on (none in a tree
    /// `reconstruct` grows; a hand-made tree.json may have them).
    pub(crate) inner_random: Vec<usize>,
    /// Their borrowing in one flat list, one after another.
    pub(crate) inner_from: Vec<(usize, f64)>,
    /// Each inner random tip's range in `inner_from`.
    pub(crate) inner_span: Vec<Span>,
    /// Per slot: the index of its captured tip in `captured`, or
    /// [`NOT_CAPTURED`].
    pub(crate) captured_at: Vec<u32>,
    /// The captured tips' slots and all their ancestors', increasing: the
    /// only slots the correction's sums can reach (docs/animation.md,
    /// step 4.2), so that a frame sums over them and not the whole tree.
    pub(crate) spine: Vec<usize>,
    /// The leaves for the first pass (their bends), in node order.
    pub(crate) leaf_bend: Vec<LeafBend>,
    /// The same leaves for the second pass (their positions).
    pub(crate) leaf_segment: Vec<LeafSegment>,
    /// The leaves' borrowing: `leaf_k` (captured tip, weight) pairs per
    /// leaf, leaf after leaf (every leaf borrows from as many tips).
    pub(crate) leaf_from: Vec<(u32, f32)>,
    /// Neighbours per leaf in `leaf_from`.
    pub(crate) leaf_k: usize,
    /// Per slot: how many leaves hang on it (their count in the blend's
    /// sums, the same every frame).
    pub(crate) leaf_count: Vec<f64>,
    /// The leaves' rest positions in f64 (never read by a frame: for
    /// [`Rig::rest_positions`], exact).
    pub(crate) leaf_rest: Vec<DVec3>,
}

/// `Rig::captured_at` of a slot that is not a captured tip.
pub(crate) const NOT_CAPTURED: u32 = u32::MAX;

impl Rig {
    /// The rig of `tree` (which must pass `Tree::check`).
    pub fn new(tree: &Tree, settings: &AnimateSettings) -> Result<Rig> {
        tree.check()
            .map_err(|e| Error::Runtime(format!("cannot animate a broken tree: {e}")))?;
        if u32::try_from(tree.nodes.len()).is_err() {
            return Err(Error::Runtime("too many nodes to animate".into()));
        }
        let full = tree.root_first_order();
        let leaf = leaves_of(tree);
        let order: Vec<usize> = full.iter().copied().filter(|&n| !leaf[n]).collect();
        let slot_of = slots_of(tree, &order);
        let Skeleton {
            parent,
            rest,
            length,
            rest_dir,
            path,
        } = skeleton(tree, &order, &slot_of);
        let profile = bend_profile(&path, settings.bend_power);
        let (captured, inner_random) = tip_slots(tree, &order, &slot_of, &profile);
        let k = settings.neighbours.max(1);
        let captured_pos: Vec<DVec3> = captured.iter().map(|c| rest[c.slot]).collect();
        let inner_borrow: Vec<Borrow> = inner_random
            .iter()
            .map(|&s| borrow(rest[s], &captured_pos, None, k))
            .collect();
        let captured_borrow = captured
            .iter()
            .enumerate()
            .map(|(i, c)| borrow(rest[c.slot], &captured_pos, Some(i), k))
            .collect();
        let (inner_from, inner_span) = flatten(&inner_borrow);
        let mut captured_at = vec![NOT_CAPTURED; order.len()];
        for (i, c) in captured.iter().enumerate() {
            captured_at[c.slot] = u32::try_from(i)
                .map_err(|_| Error::Runtime("too many captured tips to animate".into()))?;
        }
        let spine = spine(&parent, &captured);
        let leaves = Leaves::new(
            tree,
            &leaf,
            (&slot_of, &path),
            (&captured_pos, k),
            settings.bend_power,
        );
        Ok(Rig {
            nodes: tree.nodes.len(),
            order,
            parent,
            rest,
            length,
            rest_dir,
            profile,
            captured,
            captured_borrow,
            inner_random,
            inner_from,
            inner_span,
            captured_at,
            spine,
            leaf_bend: leaves.bend,
            leaf_segment: leaves.segment,
            leaf_from: leaves.from,
            leaf_k: leaves.k,
            leaf_count: leaves.count,
            leaf_rest: leaves.rest,
        })
    }

    /// Number of nodes.
    pub fn nodes(&self) -> usize {
        self.nodes
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
        let mut out = vec![DVec3::ZERO; self.nodes];
        for (slot, &node) in self.order.iter().enumerate() {
            out[node] = self.rest[slot];
        }
        for (l, &rest) in self.leaf_segment.iter().zip(&self.leaf_rest) {
            out[l.node as usize] = rest;
        }
        out
    }

    /// The tree nodes of the captured tips, in the same order as `markers`.
    pub fn captured_nodes(&self) -> Vec<usize> {
        self.captured.iter().map(|c| c.node).collect()
    }
}

/// The leaves of a tree while the rig is built.
struct Leaves {
    /// What the first pass reads.
    bend: Vec<LeafBend>,
    /// What the second pass reads.
    segment: Vec<LeafSegment>,
    /// The borrowing, `k` per leaf.
    from: Vec<(u32, f32)>,
    /// Neighbours per leaf.
    k: usize,
    /// Rest positions.
    rest: Vec<DVec3>,
    /// Per slot: leaves on it.
    count: Vec<f64>,
}

impl Leaves {
    /// The leaves (flagged in `leaf`) in node order: segments, profiles
    /// (`path` and `slot_of` are the inner slots') and the borrowing from
    /// the `k` captured tips nearest to each (all of them when there are
    /// fewer).
    fn new(
        tree: &Tree,
        leaf: &[bool],
        (slot_of, path): (&[usize], &[f64]),
        (captured, k): (&[DVec3], usize),
        power: f64,
    ) -> Leaves {
        let k = k.min(captured.len());
        let mut l = Leaves {
            bend: Vec::new(),
            segment: Vec::new(),
            from: Vec::new(),
            k,
            rest: Vec::new(),
            count: vec![0.0; path.len()],
        };
        for (node, nd) in tree.nodes.iter().enumerate() {
            let Some(p) = nd.parent.filter(|_| leaf[node]) else {
                continue;
            };
            let parent = slot_of[p];
            l.count[parent] += 1.0;
            let rel = nd.position - tree.nodes[p].position;
            let profile = profile_at(path[parent] + rel.length(), power);
            // Both fit: the tree has fewer than 2^32 nodes (Rig::new).
            let parent = parent as u32;
            l.bend.push(LeafBend {
                parent,
                profile: profile as f32,
            });
            l.segment.push(LeafSegment {
                parent,
                node: node as u32,
                rel: rel.as_vec3().into(),
                length: rel.length() as f32,
            });
            l.rest.push(nd.position);
            let b = borrow(nd.position, captured, None, k);
            l.from
                .extend(b.from.iter().map(|&(i, w)| (i as u32, w as f32)));
        }
        l
    }
}

/// Which nodes are leaves: random tips nothing hangs on.
fn leaves_of(tree: &Tree) -> Vec<bool> {
    let mut leaf: Vec<bool> = tree.nodes.iter().map(|n| n.kind == Kind::Tip).collect();
    for n in &tree.nodes {
        if let Some(p) = n.parent {
            leaf[p] = false;
        }
    }
    leaf
}

/// A range `[start, end)` in a flat list.
pub(crate) type Span = (usize, usize);

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
    path.iter().map(|&s| profile_at(s, bend_power)).collect()
}

/// The bending profile at path length `s`.
fn profile_at(s: f64, bend_power: f64) -> f64 {
    if s < MIN_PATH {
        0.0
    } else {
        s.powf(bend_power)
    }
}

/// The captured tips (driven by their markers) and the slots of the inner
/// random tips (which borrow their neighbours' motion), in node order.
fn tip_slots(
    tree: &Tree,
    order: &[usize],
    slot_of: &[usize],
    profile: &[f64],
) -> (Vec<CapturedSlot>, Vec<usize>) {
    let mut inner = vec![false; tree.nodes.len()];
    for &node in order {
        inner[node] = true;
    }
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
            Kind::Tip if inner[node] => random.push(slot),
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
        // The random tip 5 is a leaf: not a slot.
        assert_eq!(rig.nodes(), 6);
        assert_eq!(rig.order, vec![0, 1, 2, 3, 4]);
        assert_eq!(rig.parent, vec![0, 0, 1, 2, 2]);
        assert_eq!(rig.profile[0], 0.0);
        // Path to the junction: 1 + |(0.2, 0.5)|; profile = path².
        let s = 1.0 + DVec3::new(0.2, 0.5, 0.0).length();
        assert!((rig.profile[2] - s * s).abs() < 1e-12);
        assert_eq!(rig.markers(), vec![5, 2]);
        // The leaf: on the trunk top (slot 1), profile (1 + |(0.3, 0.2)|)².
        let s = 1.0 + DVec3::new(0.3, 0.2, 0.0).length();
        assert_eq!(rig.leaf_bend.len(), 1);
        assert_eq!(rig.leaf_bend[0].parent, 1);
        assert!((f64::from(rig.leaf_bend[0].profile) - s * s).abs() < 1e-6);
        assert_eq!(rig.leaf_segment[0].node, 5);
        assert_eq!(rig.rest_positions()[5], DVec3::new(0.3, 1.2, 0.0));
        // It borrows from both captured tips, the nearer more.
        assert_eq!(rig.leaf_k, 2);
        let b = &rig.leaf_from;
        assert_eq!((b[0].0, b[1].0), (0, 1));
        assert!(b[0].1 > b[1].1 && (b[0].1 + b[1].1 - 1.0).abs() < 1e-6);
        // A captured tip never borrows from itself.
        assert_eq!(rig.captured_borrow[0].from, vec![(1, 1.0)]);
        assert!(rig.inner_random.is_empty());
        assert_eq!(rig.captured_at[3], 0);
        assert_eq!(rig.captured_at[2], NOT_CAPTURED);
        assert_eq!(rig.spine, vec![0, 1, 2, 3, 4]);
    }

    #[test]
    fn a_random_tip_something_hangs_on_is_a_slot() {
        let mut tree = small_tree();
        let mut extra = tree.nodes[5].clone();
        extra.position.x += 0.1;
        extra.parent = Some(5);
        tree.nodes.push(extra);
        let rig = Rig::new(&tree, &AnimateSettings::default()).unwrap();
        assert_eq!(rig.order, vec![0, 1, 2, 5, 3, 4]);
        assert_eq!(rig.inner_random, vec![3]);
        assert_eq!(rig.inner_span, vec![(0, 2)]);
        assert_eq!(rig.leaf_segment.len(), 1);
        assert_eq!(rig.leaf_segment[0].parent, 3);
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
