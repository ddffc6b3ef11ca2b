//! One frame's deformation (docs/animation.md, steps 1–4): bends of the
//! tips, borrowing, the blend over subtrees, rotation about the parents and
//! the correction of the tracked tips. Everything that depends on the tree
//! alone (inner slots in root-first order, profiles, borrowing weights in
//! flat lists, the slots the correction can reach, the leaves apart) is in
//! the [`Rig`]. A frame is a pass over the leaves (their bends, summed into
//! their parents), two sweeps over the inner slots (a backward sum, a
//! forward blend-and-rotate), a backward sum over the captured tips' paths
//! only, a forward correction, and a last pass that hangs every leaf on its
//! parent. No allocation after the first frame.
//!
//! The inner slots are computed in f64; the leaves (most of a big tree's
//! nodes) in f32, relative to their parents (numbers of a segment's size,
//! so that f32 keeps them to a fraction of a micrometre), which halves the
//! memory a frame streams.

use glam::{DVec3, DVec4, Vec3A, Vec4};

use super::rig::{Rig, NOT_CAPTURED};
use crate::model::motion::TipSource;

/// A captured tip's displacement in one frame, as the deformation takes it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TipInput {
    /// Measured or filled: the tip must end exactly here (rest + d).
    Tracked(DVec3, TipSource),
    /// No value: borrow from the neighbours.
    Missing,
}

/// Scratch space for deforming one rig, reused frame after frame.
#[derive(Debug, Clone, Default)]
pub struct Deformer {
    /// Bend of each captured tip this frame (zero when it has none).
    bend: Vec<DVec3>,
    /// Whether each captured tip has a bend this frame.
    has_bend: Vec<bool>,
    /// Per captured tip: its bend and 1 when it has one, zero when not:
    /// what the leaves borrow (a weighted sum of these is the sum of the
    /// weighted bends and of the weights, in one vector operation).
    table: Vec<Vec4>,
    /// Per slot: (sum of bends below, count) for the blend.
    acc: Vec<DVec4>,
    /// Per slot: the sum of its leaves' bends (f32, added to `acc` before
    /// the sums over the subtrees; the leaves' count is the rig's).
    leaf_acc: Vec<Vec3A>,
    /// Per slot: the same for the residuals of the tracked tips; zero off
    /// the rig's spine (no tracked tip below), always.
    residual: Vec<DVec4>,
    /// Per slot: the blended bend (A_i), then the correction (C_i).
    field: Vec<DVec3>,
    /// Per slot: the new position.
    pos: Vec<DVec3>,
    /// Per slot: its displacement after the rotation, before the
    /// correction (what its leaves aim from).
    moved: Vec<Vec3A>,
    /// Per leaf: its target displacement (bend × profile).
    leaf_u: Vec<Vec3A>,
}

impl Deformer {
    /// Scratch space for `rig`.
    pub fn new(rig: &Rig) -> Self {
        let n = rig.order.len();
        let c = rig.captured.len();
        Deformer {
            bend: vec![DVec3::ZERO; c],
            has_bend: vec![false; c],
            table: vec![Vec4::ZERO; c],
            acc: vec![DVec4::ZERO; n],
            leaf_acc: vec![Vec3A::ZERO; n],
            residual: vec![DVec4::ZERO; n],
            field: vec![DVec3::ZERO; n],
            pos: vec![DVec3::ZERO; n],
            moved: vec![Vec3A::ZERO; n],
            leaf_u: vec![Vec3A::ZERO; rig.leaf_bend.len()],
        }
    }

    /// Deforms `rig` for one frame. `tips` holds one entry per captured tip
    /// in the rig's order ([`Rig::markers`]); `out` receives every node's
    /// position in node index order and `sources` where each captured tip's
    /// displacement came from. Slices of the wrong length are resized.
    pub fn deform(
        &mut self,
        rig: &Rig,
        tips: &[TipInput],
        out: &mut Vec<DVec3>,
        sources: &mut Vec<TipSource>,
    ) {
        if self.pos.len() != rig.order.len()
            || self.bend.len() != rig.captured.len()
            || self.leaf_u.len() != rig.leaf_bend.len()
        {
            *self = Deformer::new(rig);
        }
        out.resize(rig.nodes(), DVec3::ZERO);
        sources.clear();
        self.tip_bends(rig, tips, sources);
        self.leaf_bends(rig);
        for slot in (1..rig.order.len()).rev() {
            let a = self.acc[slot];
            self.acc[rig.parent[slot]] += a;
        }
        self.blend_and_rotate(rig, tips);
        self.correct(rig, tips, out);
        self.place_leaves(rig, out);
    }

    /// Steps 1–2 for the slots: every tip slot's bend (tracked, borrowed or
    /// none) into `acc` with a count of 1, every other slot zero.
    fn tip_bends(&mut self, rig: &Rig, tips: &[TipInput], sources: &mut Vec<TipSource>) {
        for (i, c) in rig.captured.iter().enumerate() {
            (self.bend[i], self.has_bend[i]) = match tips.get(i) {
                Some(TipInput::Tracked(d, _)) => (*d * c.inv_profile, true),
                _ => (DVec3::ZERO, false),
            };
            self.table[i] = if self.has_bend[i] {
                self.bend[i].as_vec3().extend(1.0)
            } else {
                Vec4::ZERO
            };
        }
        self.acc.fill(DVec4::ZERO);
        for (i, c) in rig.captured.iter().enumerate() {
            let (bend, source) = match tips.get(i) {
                Some(TipInput::Tracked(_, s)) => (self.bend[i], *s),
                _ => match self.borrowed(&rig.captured_borrow[i].from) {
                    Some(b) => (b, TipSource::Borrowed),
                    None => (DVec3::ZERO, TipSource::Rest),
                },
            };
            sources.push(source);
            self.acc[c.slot] = bend.extend(1.0);
        }
        for (&slot, &(a, b)) in rig.inner_random.iter().zip(&rig.inner_span) {
            let bend = self.borrowed(&rig.inner_from[a..b]).unwrap_or(DVec3::ZERO);
            self.acc[slot] = bend.extend(1.0);
        }
    }

    /// Step 2 for the leaves: each one's borrowed bend (the weighted mean
    /// over its neighbours that have one), its target displacement, and
    /// its bend added to its parent's sum (with its count, the rig's).
    fn leaf_bends(&mut self, rig: &Rig) {
        self.leaf_acc.fill(Vec3A::ZERO);
        let k = rig.leaf_k;
        if k == 0 {
            // No captured tip: no leaf bends.
            self.leaf_u.fill(Vec3A::ZERO);
        } else {
            let from = rig.leaf_from.chunks_exact(k);
            for ((l, u), from) in rig.leaf_bend.iter().zip(&mut self.leaf_u).zip(from) {
                let mut sum = Vec4::ZERO;
                for &(c, w) in from {
                    sum += self.table[c as usize] * w;
                }
                // (Σ w bend, Σ w) over the neighbours with a bend.
                let bend = if sum.w > 0.0 {
                    Vec3A::from_vec4(sum) * sum.w.recip()
                } else {
                    Vec3A::ZERO
                };
                *u = bend * l.profile;
                self.leaf_acc[l.parent as usize] += bend;
            }
        }
        for ((acc, leaves), &count) in self.acc.iter_mut().zip(&self.leaf_acc).zip(&rig.leaf_count)
        {
            *acc += leaves.as_dvec3().extend(count);
        }
    }

    /// Steps 3 and 4.1 in one root-first sweep over the slots: each slot's
    /// blended bend `A_i`, its target (rest + A_i × profile, or exactly
    /// rest + d for a tracked tip), and its new position at its rest
    /// distance from its parent's new one, pointing at the target.
    fn blend_and_rotate(&mut self, rig: &Rig, tips: &[TipInput]) {
        self.pos[0] = rig.rest[0];
        self.moved[0] = Vec3A::ZERO;
        let a = self.acc[0];
        self.field[0] = if a.w > 0.0 {
            a.truncate() / a.w
        } else {
            DVec3::ZERO
        };
        for slot in 1..rig.order.len() {
            let a = self.acc[slot];
            // A node with no tip below it (a bare trunk top) bends as its
            // parent does.
            let field = if a.w > 0.0 {
                a.truncate() / a.w
            } else {
                self.field[rig.parent[slot]]
            };
            self.field[slot] = field;
            // Tracked tips aim at exactly rest + d (the profile round trip
            // would leave a rounding error).
            let target = match tracked(rig, tips, slot) {
                Some(d) => rig.rest[slot] + d,
                None => rig.rest[slot] + field * rig.profile[slot],
            };
            let from = self.pos[rig.parent[slot]];
            let aim = target - from;
            let dir = aim.try_normalize().unwrap_or(rig.rest_dir[slot]);
            self.pos[slot] = from + dir * rig.length[slot];
            self.moved[slot] = (self.pos[slot] - rig.rest[slot]).as_vec3().into();
        }
    }

    /// Step 4.2: carry each tracked tip's residual back along its path, and
    /// write every slot's position into `out` (node order).
    fn correct(&mut self, rig: &Rig, tips: &[TipInput], out: &mut [DVec3]) {
        for &slot in &rig.spine {
            self.residual[slot] = DVec4::ZERO;
        }
        let mut any = false;
        for (i, c) in rig.captured.iter().enumerate() {
            if let Some(TipInput::Tracked(d, _)) = tips.get(i) {
                let residual = rig.rest[c.slot] + *d - self.pos[c.slot];
                self.residual[c.slot] = (residual * c.inv_profile).extend(1.0);
                any = true;
            }
        }
        if !any {
            for (slot, &node) in rig.order.iter().enumerate() {
                out[node] = self.pos[slot];
            }
            return;
        }
        // Off the spine every sum is zero: only the spine is summed.
        for &slot in rig.spine.iter().skip(1).rev() {
            let a = self.residual[slot];
            self.residual[rig.parent[slot]] += a;
        }
        self.field[0] = DVec3::ZERO;
        out[rig.order[0]] = self.pos[0];
        for slot in 1..rig.order.len() {
            let a = self.residual[slot];
            // No tracked tip below: move rigidly with the parent.
            let field = if a.w > 0.0 {
                a.truncate() / a.w * rig.profile[slot]
            } else {
                self.field[rig.parent[slot]]
            };
            self.field[slot] = field;
            self.pos[slot] += field;
            // The tracked tips themselves: exactly where they were tracked.
            if let Some(d) = tracked(rig, tips, slot) {
                self.pos[slot] = rig.rest[slot] + d;
            }
            out[rig.order[slot]] = self.pos[slot];
        }
    }

    /// Steps 4.1 and 4.2 for the leaves: each one at its rest length from
    /// its parent's rotated position, pointing at its target, then moved
    /// with its parent's correction (no tracked tip is below a leaf), i.e.
    /// hung on its parent's final position.
    fn place_leaves(&self, rig: &Rig, out: &mut [DVec3]) {
        for (l, u) in rig.leaf_segment.iter().zip(&self.leaf_u) {
            let p = l.parent as usize;
            // Target − parent's rotated position, both relative to the
            // parent's rest position.
            let aim = l.rel + *u - self.moved[p];
            let len2 = aim.length_squared();
            let offset = if len2 > f32::MIN_POSITIVE {
                aim * (l.length / len2.sqrt())
            } else {
                l.rel
            };
            out[l.node as usize] = self.pos[p] + offset.as_dvec3();
        }
    }

    /// A borrower's bend: the weighted mean over the neighbours that have
    /// one, renormalised; `None` when none has.
    fn borrowed(&self, from: &[(usize, f64)]) -> Option<DVec3> {
        let mut sum = DVec3::ZERO;
        let mut weight = 0.0;
        for &(i, w) in from {
            if self.has_bend[i] {
                sum += self.bend[i] * w;
                weight += w;
            }
        }
        (weight > 0.0).then(|| sum / weight)
    }
}

/// The displacement of the tracked tip at `slot`, if it is one this frame.
#[inline]
fn tracked(rig: &Rig, tips: &[TipInput], slot: usize) -> Option<DVec3> {
    let c = rig.captured_at[slot];
    if c == NOT_CAPTURED {
        return None;
    }
    match tips.get(c as usize) {
        Some(TipInput::Tracked(d, _)) => Some(*d),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::animate::fixture::small_tree;
    use crate::animate::AnimateSettings;
    use crate::model::tree::Tree;

    fn run(tree: &Tree, tips: &[TipInput]) -> (Vec<DVec3>, Vec<TipSource>) {
        let rig = Rig::new(tree, &AnimateSettings::default()).unwrap();
        let mut d = Deformer::new(&rig);
        let (mut out, mut src) = (Vec::new(), Vec::new());
        d.deform(&rig, tips, &mut out, &mut src);
        (out, src)
    }

    fn seg(p: &[DVec3], tree: &Tree, i: usize) -> f64 {
        p[i].distance(p[tree.nodes[i].parent.unwrap()])
    }

    #[test]
    fn no_motion_is_the_rest_pose() {
        let tree = small_tree();
        let tracked = TipInput::Tracked(DVec3::ZERO, TipSource::Measured);
        let (p, src) = run(&tree, &[tracked, tracked]);
        // Within a micrometre: the leaf (node 5) is computed in f32.
        for (i, n) in tree.nodes.iter().enumerate() {
            assert!(p[i].distance(n.position) < 1e-6, "node {i}");
        }
        assert_eq!(src, vec![TipSource::Measured; 2]);
    }

    #[test]
    fn tracked_tips_exact_base_fixed_lengths_nearly_kept() {
        let tree = small_tree();
        let d3 = DVec3::new(0.03, -0.004, 0.05);
        let d4 = DVec3::new(-0.02, 0.0, 0.04);
        let tips = [
            TipInput::Tracked(d3, TipSource::Measured),
            TipInput::Tracked(d4, TipSource::Filled),
        ];
        let (p, src) = run(&tree, &tips);
        assert_eq!(src, vec![TipSource::Measured, TipSource::Filled]);
        assert_eq!(p[0], tree.nodes[0].position);
        assert!(p[3].distance(tree.nodes[3].position + d3) < 1e-12);
        assert!(p[4].distance(tree.nodes[4].position + d4) < 1e-12);
        // The junction and the trunk top moved, less than the tips, with
        // the tips' mean direction (+z).
        assert!(p[2].z > 0.0 && p[2].z < 0.045);
        assert!(p[1].z > 0.0 && p[1].z < p[2].z);
        // The random tip moves with the trunk top it hangs on and borrows.
        assert!(p[5].z > 0.0);
        for i in 1..6 {
            let rest = seg(
                &tree.nodes.iter().map(|n| n.position).collect::<Vec<_>>(),
                &tree,
                i,
            );
            let change = (seg(&p, &tree, i) / rest - 1.0).abs();
            assert!(
                change < 0.02,
                "segment {i} changed by {:.3} %",
                change * 100.0
            );
        }
        // The random tip's segment has no tracked tip below: its length is
        // kept (to f32's precision: well under a micrometre).
        let rest5 = tree.nodes[5].position.distance(tree.nodes[1].position);
        assert!((seg(&p, &tree, 5) - rest5).abs() < 1e-6);
    }

    #[test]
    fn a_missing_tip_borrows_and_none_at_all_is_rest() {
        let tree = small_tree();
        let d3 = DVec3::new(0.03, 0.0, 0.0);
        let (p, src) = run(
            &tree,
            &[
                TipInput::Tracked(d3, TipSource::Measured),
                TipInput::Missing,
            ],
        );
        assert_eq!(src, vec![TipSource::Measured, TipSource::Borrowed]);
        assert!(p[4].x > tree.nodes[4].position.x);
        let (p, src) = run(&tree, &[TipInput::Missing, TipInput::Missing]);
        assert_eq!(src, vec![TipSource::Rest; 2]);
        for (i, n) in tree.nodes.iter().enumerate() {
            assert!(p[i].distance(n.position) < 1e-6);
        }
    }

    #[test]
    fn same_input_same_output_bits() {
        let tree = small_tree();
        let tips = [
            TipInput::Tracked(DVec3::new(0.01, 0.02, -0.03), TipSource::Measured),
            TipInput::Missing,
        ];
        let (a, _) = run(&tree, &tips);
        let (b, _) = run(&tree, &tips);
        assert_eq!(a, b);
    }
}
