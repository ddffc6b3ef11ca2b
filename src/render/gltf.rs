//! The tree as binary glTF 2.0 (.glb): the branch mesh, the leaves as a
//! second mesh (when there are any), and the skeleton as a LINES primitive
//! (one line per node–parent pair) so a viewer can show the structure the
//! flow produced. With a [`Movement`] other than `Still` the meshes are
//! skinned to one joint per tree node and may carry the captured motion as
//! an animation (`super::animation`, docs/animation.md). The JSON part is
//! built with `gltf-json` through the document builder of `super::glb`,
//! which also writes the GLB container (a 12-byte header and two chunks).

use gltf_json as json;

use super::animation::{animate_skins, Skin};
use super::glb::{Builder, Skinning};
use crate::error::Result;
use crate::model::motion::TreeMotion;
use crate::model::tree::Tree;
use crate::reconstruct::mesh::Mesh;

/// What the file carries beyond the still tree. In every case the still
/// tree is what a viewer shows when it ignores skins and animations.
#[derive(Debug, Clone, Copy)]
pub enum Movement<'a> {
    /// The still tree only.
    Still,
    /// A skin (a joint per tree node, weights on every vertex) in the bind
    /// pose, without animation: for viewers that sway the tree live.
    Rigged,
    /// The skin and the captured motion as an animation.
    Animated(&'a TreeMotion),
}

/// Encodes the tree and its meshes as a .glb file's bytes.
pub fn to_glb(
    tree: &Tree,
    branches: &Mesh,
    leaves: Option<&Mesh>,
    movement: Movement<'_>,
) -> Result<Vec<u8>> {
    let mut b = Builder::default();
    let skin = match movement {
        Movement::Still => None,
        Movement::Rigged => Some(Skin::new(&mut b, tree, None)?),
        Movement::Animated(m) => Some(Skin::new(&mut b, tree, Some(m))?),
    };
    let skinning: Option<&dyn Skinning> = skin.as_ref().map(|s| s as _);
    let bark = b.material("bark", [0.40, 0.29, 0.20, 1.0], false);
    let mut scene_nodes = Vec::new();
    if let Some(mesh) = b.triangle_mesh("branches", branches, bark, skinning)? {
        scene_nodes.push(b.node("branches", mesh, skinning));
    }
    if let Some(leaves) = leaves.filter(|m| !m.indices.is_empty()) {
        let leaf = b.material("leaf", [0.27, 0.52, 0.16, 1.0], true);
        if let Some(mesh) = b.triangle_mesh("leaves", leaves, leaf, skinning)? {
            scene_nodes.push(b.node("leaves", mesh, skinning));
        }
    }
    if let Some(mesh) = b.skeleton(tree, skinning)? {
        scene_nodes.push(b.node("skeleton", mesh, skinning));
    }
    if let Some(skin) = &skin {
        scene_nodes.push(skin.root());
        if let Movement::Animated(motion) = movement {
            skin.animate(&mut b, tree, motion)?;
        }
    }
    let scene = b.root.push(json::Scene {
        extensions: None,
        extras: Default::default(),
        name: Some("tree".into()),
        nodes: scene_nodes,
    });
    b.root.scene = Some(scene);
    b.finish()
}

/// One tree of a forest: its name, skeleton and meshes.
pub struct ForestTree<'a> {
    /// The node's name: the tree's name.
    pub name: &'a str,
    /// The skeleton.
    pub tree: &'a Tree,
    /// The branch surface.
    pub branches: &'a Mesh,
    /// The leaves, when there are any.
    pub leaves: Option<&'a Mesh>,
    /// Its share of the session's motion, for an animated forest (every
    /// tree has one, or none does).
    pub motion: Option<&'a TreeMotion>,
}

/// Several trees in one .glb (docs/forest.md): one scene node per tree,
/// named as the tree, holding its branches, leaves and skeleton; the
/// materials are shared. When every tree has a motion, the trees are
/// skinned and animated instead ([`animated_forest_glb`]); `rigged`
/// skins them without an animation (the daemon: its viewers sway every
/// tree live).
pub fn forest_glb(trees: &[ForestTree<'_>], rigged: bool) -> Result<Vec<u8>> {
    if !trees.is_empty() && (rigged || trees.iter().all(|t| t.motion.is_some())) {
        return animated_forest_glb(trees);
    }
    let mut b = Builder::default();
    let mut scene_nodes = Vec::with_capacity(trees.len());
    for t in trees {
        let children = b.tree_nodes(t.tree, t.branches, t.leaves, None)?;
        scene_nodes.push(b.root.push(json::Node {
            children: (!children.is_empty()).then_some(children),
            name: Some(t.name.into()),
            ..Default::default()
        }));
    }
    b.finish_scene("forest", scene_nodes)
}

/// Several trees skinned and animated (docs/animation.md, "Several trees"):
/// per tree, a scene node named as the tree holding its joints (the trunk
/// base is the root joint), then its skinned branches, leaves and skeleton
/// as scene roots (`tree-1 branches`, …); one animation, `capture`, moves
/// every tree's joints on one clock (none when no tree has a motion: the
/// trees are only rigged).
fn animated_forest_glb(trees: &[ForestTree<'_>]) -> Result<Vec<u8>> {
    let mut b = Builder::default();
    let mut scene_nodes = Vec::with_capacity(4 * trees.len());
    let mut skins = Vec::with_capacity(trees.len());
    for t in trees {
        let skin = Skin::named(&mut b, t.tree, t.motion, Some(t.name))?;
        let meshes = b.tree_nodes(
            t.tree,
            t.branches,
            t.leaves,
            Some((&skin as &dyn Skinning, t.name)),
        )?;
        scene_nodes.push(b.root.push(json::Node {
            children: Some(vec![skin.root()]),
            name: Some(t.name.into()),
            ..Default::default()
        }));
        scene_nodes.extend(meshes);
        skins.push(skin);
    }
    let animated: Vec<_> = skins
        .iter()
        .zip(trees)
        .filter_map(|(s, t)| Some((s, t.tree, t.motion?)))
        .collect();
    animate_skins(&mut b, &animated)?;
    b.finish_scene("forest", scene_nodes)
}
