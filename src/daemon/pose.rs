//! The live sway (docs/animation.md, "Live"): the current tree — or every
//! tree of several, each with its own captured tips — deformed with the
//! live tips by the very code that animates tree.glb. When a pose is due
//! (`animate.live_rate_hz`) is `pose_feed`'s decision.

use std::sync::Arc;

use glam::DVec3;

use crate::animate::{Deformer, Rig, TipInput};
use crate::model::motion::TipSource;
use crate::serve::pose::Pose;
use crate::serve::snapshot::TreeSnapshot;

/// The pose worker's state for the live sway: one [`TreeSway`] per tree
/// that can sway.
pub(crate) struct LivePose {
    /// Version of the snapshot the rigs belong to (0 = none yet).
    tree: u64,
    /// Every tree that sways, in the snapshot's order.
    sways: Vec<TreeSway>,
}

/// One tree's rig and scratch space.
struct TreeSway {
    /// With several trees, the tree's id and name (named in its poses).
    member: Option<(usize, String)>,
    rig: Arc<Rig>,
    /// The rig's captured tip of each marker.
    captured_of_marker: Vec<Option<usize>>,
    /// The node of each of the rig's captured tips.
    captured_nodes: Vec<usize>,
    /// Every node's rest position.
    rest: Vec<DVec3>,
    deformer: Deformer,
    /// Scratch: the captured tips' inputs, the positions, the tips'
    /// sources and the displacements of the last pose.
    inputs: Vec<TipInput>,
    positions: Vec<DVec3>,
    sources: Vec<TipSource>,
    displacements: Vec<DVec3>,
}

impl LivePose {
    pub(crate) fn new() -> Self {
        LivePose {
            tree: 0,
            sways: Vec::new(),
        }
    }

    /// The poses of this frame, one per tree that sways, each handed to
    /// `emit`: `tree` is the current snapshot, `seen` the live tips
    /// `(marker, position)` (markers are unique across trees: each tree
    /// takes its own). Tips not seen borrow.
    pub(crate) fn update(
        &mut self,
        tree: Option<&TreeSnapshot>,
        (frame, time_s): (i64, f64),
        seen: &[(usize, DVec3)],
        emit: &mut dyn FnMut(&Pose<'_>),
    ) {
        let Some(tree) = tree else { return };
        if tree.version != self.tree {
            self.set_rigs(tree);
        }
        for s in &mut self.sways {
            s.deform(seen);
            emit(&Pose {
                tree: self.tree,
                member: s.member.as_ref().map(|(id, name)| (*id, name.as_str())),
                frame,
                time_s,
                displacements: &s.displacements,
            });
        }
    }

    fn set_rigs(&mut self, tree: &TreeSnapshot) {
        self.tree = tree.version;
        self.sways.clear();
        if tree.trees.is_empty() {
            self.sways
                .extend(tree.rig.clone().map(|r| TreeSway::new(r, None)));
        } else {
            for t in &tree.trees {
                if let Some(r) = &t.rig {
                    let member = Some((t.id, t.name.clone()));
                    self.sways.push(TreeSway::new(r.clone(), member));
                }
            }
        }
    }
}

impl TreeSway {
    fn new(rig: Arc<Rig>, member: Option<(usize, String)>) -> Self {
        let mut captured_of_marker = Vec::new();
        for (c, m) in rig.markers().into_iter().enumerate() {
            if captured_of_marker.len() <= m {
                captured_of_marker.resize(m + 1, None);
            }
            captured_of_marker[m] = Some(c);
        }
        TreeSway {
            member,
            captured_of_marker,
            captured_nodes: rig.captured_nodes(),
            rest: rig.rest_positions(),
            deformer: Deformer::new(&rig),
            rig,
            inputs: Vec::new(),
            positions: Vec::new(),
            sources: Vec::new(),
            displacements: Vec::new(),
        }
    }

    /// Deforms the tree with its tips among `seen`; the displacements are
    /// left in `self.displacements`.
    fn deform(&mut self, seen: &[(usize, DVec3)]) {
        self.inputs.clear();
        self.inputs
            .resize(self.captured_nodes.len(), TipInput::Missing);
        for &(marker, p) in seen {
            if let Some(Some(c)) = self.captured_of_marker.get(marker) {
                let d = p - self.rest[self.captured_nodes[*c]];
                self.inputs[*c] = TipInput::Tracked(d, TipSource::Measured);
            }
        }
        self.deformer.deform(
            &self.rig,
            &self.inputs,
            &mut self.positions,
            &mut self.sources,
        );
        self.displacements.clear();
        self.displacements
            .extend(self.positions.iter().zip(&self.rest).map(|(p, r)| *p - *r));
    }
}
