//! `TreeSnapshot`: one reconstructed tree, serialised once, shared read-only
//! (`Arc`) by every output. Serialising once means a viewer that downloads
//! `tree.glb` gets the very bytes written to disk, and ten viewers cost no
//! more reconstruction work than one.

use glam::DVec3;
use serde::Serialize;

/// A finished tree as the outputs need it.
#[derive(Debug, Clone, Default)]
pub struct TreeSnapshot {
    /// 1 for the first tree of a run, +1 for every new tree; viewers use it
    /// to tell a new tree from a repeated notice.
    pub version: u64,
    /// Session time (s) of the data the tree was built from.
    pub time_s: f64,
    /// Why it was rebuilt (trigger name), for `/status` and the log.
    pub reason: String,
    /// Binary glTF, exactly as written to `tree.glb`.
    pub glb: Vec<u8>,
    /// `tree.json`, exactly as written.
    pub tree_json: String,
    /// `tips.json`, exactly as written.
    pub tips_json: String,
    /// The skeleton for OSC: node id is the index (the first tree's, when
    /// there are several).
    pub nodes: Vec<SnapshotNode>,
    /// Every tree of a capture of several (docs/forest.md); empty for a
    /// tree alone, whose outputs are as they have always been.
    pub trees: Vec<SnapshotTree>,
    /// How the tree sways with the live tips (`None` when it cannot, and
    /// for several trees: each [`SnapshotTree`] has its own).
    pub rig: Option<std::sync::Arc<crate::animate::Rig>>,
}

/// One tree of several, as the outputs carry it.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct SnapshotTree {
    /// The tree's id (tree.json `id`, the OSC `tree` argument).
    pub id: usize,
    /// Its name.
    pub name: String,
    /// Its trunk base (m).
    pub base: [f64; 3],
    /// Captured tips given to it.
    pub tips: usize,
    /// Built for this snapshot (false: the same as in the last one).
    pub rebuilt: bool,
    /// Its skeleton; node id is the index.
    #[serde(skip)]
    pub nodes: Vec<SnapshotNode>,
    /// The tree alone as a version-1 tree.json (`GET /trees/{id}.json`).
    #[serde(skip)]
    pub tree_json: String,
    /// How the tree sways with its own live tips (`None` when it cannot).
    #[serde(skip)]
    pub rig: Option<std::sync::Arc<crate::animate::Rig>>,
}

/// One node of the skeleton.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SnapshotNode {
    /// Parent index; `None` for the root (trunk base).
    pub parent: Option<u32>,
    /// Metres, Y up.
    pub position: DVec3,
    /// Branch radius at the node (m).
    pub radius: f64,
}

impl SnapshotNode {
    /// The skeleton of `tree` as the OSC and HTTP outputs carry it (node id =
    /// index).
    pub fn of_tree(tree: &crate::model::tree::Tree) -> Vec<SnapshotNode> {
        tree.nodes
            .iter()
            .map(|n| SnapshotNode {
                parent: n.parent.and_then(|p| u32::try_from(p).ok()),
                position: n.position,
                radius: n.radius,
            })
            .collect()
    }
}
