//! The live sway (docs/animation.md, "Live"): the current tree deformed
//! with the live tips by the very code that animates tree.glb. When a pose
//! is due (`animate.live_rate_hz`) is `pose_feed`'s decision.

use std::sync::Arc;

use glam::DVec3;

use crate::animate::{Deformer, Rig, TipInput};
use crate::model::motion::TipSource;
use crate::serve::pose::Pose;
use crate::serve::snapshot::TreeSnapshot;

/// The pose worker's state for the live sway.
pub(crate) struct LivePose {
    /// Version of the tree the rig belongs to (0 = none yet).
    tree: u64,
    rig: Option<Arc<Rig>>,
    /// The rig's captured tip of each marker.
    captured_of_marker: Vec<Option<usize>>,
    /// The node of each of the rig's captured tips.
    captured_nodes: Vec<usize>,
    rest: Vec<DVec3>,
    deformer: Deformer,
    inputs: Vec<TipInput>,
    positions: Vec<DVec3>,
    sources: Vec<TipSource>,
    displacements: Vec<DVec3>,
}

impl LivePose {
    pub(crate) fn new() -> Self {
        LivePose {
            tree: 0,
            rig: None,
            captured_of_marker: Vec::new(),
            captured_nodes: Vec::new(),
            rest: Vec::new(),
            deformer: Deformer::default(),
            inputs: Vec::new(),
            positions: Vec::new(),
            sources: Vec::new(),
            displacements: Vec::new(),
        }
    }

    /// The pose of this frame: `tree` is the current tree,
    /// `seen` the live tips `(marker, position)`. Tips not seen borrow.
    pub(crate) fn update(
        &mut self,
        tree: Option<&TreeSnapshot>,
        frame: i64,
        time_s: f64,
        seen: &[(usize, DVec3)],
    ) -> Option<Pose<'_>> {
        let tree = tree?;
        if tree.version != self.tree {
            self.set_rig(tree);
        }
        let rig = self.rig.as_ref()?;
        self.inputs.clear();
        self.inputs
            .resize(self.captured_nodes.len(), TipInput::Missing);
        for &(marker, p) in seen {
            if let Some(Some(c)) = self.captured_of_marker.get(marker) {
                let d = p - self.rest[self.captured_nodes[*c]];
                self.inputs[*c] = TipInput::Tracked(d, TipSource::Measured);
            }
        }
        self.deformer
            .deform(rig, &self.inputs, &mut self.positions, &mut self.sources);
        self.displacements.clear();
        self.displacements
            .extend(self.positions.iter().zip(&self.rest).map(|(p, r)| *p - *r));
        Some(Pose {
            tree: self.tree,
            frame,
            time_s,
            displacements: &self.displacements,
        })
    }

    fn set_rig(&mut self, tree: &TreeSnapshot) {
        self.tree = tree.version;
        self.rig = tree.rig.clone();
        self.captured_of_marker.clear();
        self.rest.clear();
        if let Some(rig) = &self.rig {
            for (c, m) in rig.markers().into_iter().enumerate() {
                if self.captured_of_marker.len() <= m {
                    self.captured_of_marker.resize(m + 1, None);
                }
                self.captured_of_marker[m] = Some(c);
            }
            self.captured_nodes = rig.captured_nodes();
            self.rest = rig.rest_positions();
            self.deformer = Deformer::new(rig);
        }
    }
}
