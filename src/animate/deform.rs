//! One frame's deformation (docs/animation.md, steps 1–4): bends of the
//! tips, borrowing, the blend over subtrees, rotation about the parents and
//! the correction of the tracked tips. Four linear passes over the slots,
//! no allocation after the first frame.

use glam::{DVec3, DVec4};

use super::rig::{Borrow, Rig};
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
    /// Bend of each captured tip this frame, if it has a value.
    bend: Vec<Option<DVec3>>,
    /// Per slot: (sum of bends below, count) for the blend, then the same
    /// for the residuals of the tracked tips.
    acc: Vec<DVec4>,
    /// Per slot: the blended bend (A_i), then the correction (C_i).
    field: Vec<DVec3>,
    /// Per slot: the new position.
    pos: Vec<DVec3>,
}

impl Deformer {
    /// Scratch space for `rig`.
    pub fn new(rig: &Rig) -> Self {
        let n = rig.nodes();
        Deformer {
            bend: vec![None; rig.captured.len()],
            acc: vec![DVec4::ZERO; n],
            field: vec![DVec3::ZERO; n],
            pos: vec![DVec3::ZERO; n],
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
        let n = rig.nodes();
        if self.pos.len() != n || self.bend.len() != rig.captured.len() {
            *self = Deformer::new(rig);
        }
        out.resize(n, DVec3::ZERO);
        sources.clear();
        self.blend(rig, tips, sources);
        self.rotate(rig, tips);
        self.correct(rig, tips);
        for (slot, &node) in rig.order.iter().enumerate() {
            out[node] = self.pos[slot];
        }
    }

    /// Steps 1–3: every slot's blended bend `A_i` into `field`.
    fn blend(&mut self, rig: &Rig, tips: &[TipInput], sources: &mut Vec<TipSource>) {
        for (i, c) in rig.captured.iter().enumerate() {
            self.bend[i] = match tips.get(i) {
                Some(TipInput::Tracked(d, _)) => Some(*d * c.inv_profile),
                _ => None,
            };
        }
        self.acc.fill(DVec4::ZERO);
        for (i, c) in rig.captured.iter().enumerate() {
            let (bend, source) = match (tips.get(i), self.bend[i]) {
                (Some(TipInput::Tracked(_, s)), Some(b)) => (b, *s),
                _ => match borrowed(&rig.captured_borrow[i], &self.bend) {
                    Some(b) => (b, TipSource::Borrowed),
                    None => (DVec3::ZERO, TipSource::Rest),
                },
            };
            sources.push(source);
            self.acc[c.slot] = bend.extend(1.0);
        }
        for (r, &slot) in rig.random.iter().enumerate() {
            let bend = borrowed(&rig.random_borrow[r], &self.bend).unwrap_or(DVec3::ZERO);
            self.acc[slot] = bend.extend(1.0);
        }
        for slot in (1..rig.nodes()).rev() {
            let a = self.acc[slot];
            self.acc[rig.parent[slot]] += a;
        }
        for slot in 0..rig.nodes() {
            let a = self.acc[slot];
            // A node with no tip below it (a bare trunk top) bends as its
            // parent does.
            self.field[slot] = if a.w > 0.0 {
                a.truncate() / a.w
            } else {
                self.field[rig.parent[slot]]
            };
        }
    }

    /// Step 4.1: place every slot at its rest distance from its parent's new
    /// position, pointing at its target.
    fn rotate(&mut self, rig: &Rig, tips: &[TipInput]) {
        for slot in 0..rig.nodes() {
            self.pos[slot] = rig.rest[slot] + self.field[slot] * rig.profile[slot];
        }
        // Tracked tips aim at exactly rest + d (the profile round trip
        // would leave a rounding error).
        for (i, c) in rig.captured.iter().enumerate() {
            if let Some(TipInput::Tracked(d, _)) = tips.get(i) {
                self.pos[c.slot] = rig.rest[c.slot] + *d;
            }
        }
        self.pos[0] = rig.rest[0];
        for slot in 1..rig.nodes() {
            let from = self.pos[rig.parent[slot]];
            let aim = self.pos[slot] - from;
            let dir = aim.try_normalize().unwrap_or(rig.rest_dir[slot]);
            self.pos[slot] = from + dir * rig.length[slot];
        }
    }

    /// Step 4.2: carry each tracked tip's residual back along its path.
    fn correct(&mut self, rig: &Rig, tips: &[TipInput]) {
        self.acc.fill(DVec4::ZERO);
        let mut any = false;
        for (i, c) in rig.captured.iter().enumerate() {
            if let Some(TipInput::Tracked(d, _)) = tips.get(i) {
                let residual = rig.rest[c.slot] + *d - self.pos[c.slot];
                self.acc[c.slot] = (residual * c.inv_profile).extend(1.0);
                any = true;
            }
        }
        if !any {
            return;
        }
        for slot in (1..rig.nodes()).rev() {
            let a = self.acc[slot];
            self.acc[rig.parent[slot]] += a;
        }
        self.field[0] = DVec3::ZERO;
        for slot in 1..rig.nodes() {
            let a = self.acc[slot];
            // No tracked tip below: move rigidly with the parent.
            self.field[slot] = if a.w > 0.0 {
                a.truncate() / a.w * rig.profile[slot]
            } else {
                self.field[rig.parent[slot]]
            };
        }
        for slot in 1..rig.nodes() {
            self.pos[slot] += self.field[slot];
        }
        // The tracked tips themselves: exactly where they were tracked.
        for (i, c) in rig.captured.iter().enumerate() {
            if let Some(TipInput::Tracked(d, _)) = tips.get(i) {
                self.pos[c.slot] = rig.rest[c.slot] + *d;
            }
        }
    }
}

/// A borrower's bend: the weighted mean over the neighbours that have one,
/// renormalised; `None` when none has.
fn borrowed(b: &Borrow, bends: &[Option<DVec3>]) -> Option<DVec3> {
    let mut sum = DVec3::ZERO;
    let mut weight = 0.0;
    for &(i, w) in &b.from {
        if let Some(Some(bend)) = bends.get(i) {
            sum += *bend * w;
            weight += w;
        }
    }
    (weight > 0.0).then(|| sum / weight)
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
        for (i, n) in tree.nodes.iter().enumerate() {
            assert!(p[i].distance(n.position) < 1e-12, "node {i}");
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
        // exact.
        let rest5 = tree.nodes[5].position.distance(tree.nodes[1].position);
        assert!((seg(&p, &tree, 5) - rest5).abs() < 1e-12);
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
            assert!(p[i].distance(n.position) < 1e-12);
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
