//! The skin and the animation of the animated tree.glb (docs/animation.md):
//!
//! - one joint node per tree node, nested as the skeleton is (the trunk
//!   base is the root joint), each with its rest offset from its parent as
//!   `translation`; captured tips are named `tip_07` (marker 7, also in
//!   `extras`), the others `node_123` (the node's index in tree.json; in a
//!   forest `tree-1_node_123`, so that every joint's name is unique);
//! - inverse bind matrices that are translations by −rest position (joints
//!   carry no rotation or scale);
//! - `JOINTS_0`/`WEIGHTS_0` on every vertex: one or two weights (a ring
//!   vertex follows its node, a leaf the point of its segment);
//! - one animation, `capture`: a LINEAR translation sampler per joint that
//!   moves, all sharing one input (the key times), each tree's outputs in
//!   one buffer view; in a forest the one animation drives every tree's
//!   joints ([`animate_skins`]).
//!
//! Translations only: a joint's local translation is its node's offset from
//! its parent's node, so positions and lengths read directly off the
//! armature in Blender, and the still tree is the bind pose.

use gltf_json as json;
use json::accessor::{ComponentType, Type};
use json::validation::Checked::Valid;
use serde_json::value::RawValue;

use super::error::RenderError;
use super::glb::{Attributes, Builder, Skinning};
use crate::error::Result;
use crate::model::motion::{Stretch, TipSource, TreeMotion};
use crate::model::tree::{Kind, Tree};
use crate::reconstruct::mesh::Bind;

/// The joints of one tree in a document being built.
pub(super) struct Skin {
    index: json::Index<json::Skin>,
    /// The joint (glTF node) of each tree node.
    joints: Vec<json::Index<json::Node>>,
    /// Each joint's rest translation (offset from its parent's node).
    rest_local: Vec<[f32; 3]>,
}

impl Skin {
    /// Adds a joint per node of `tree` and the skin over them. With
    /// `motion`, captured tips' extras also list the keys in which their
    /// displacement was not measured.
    pub(super) fn new(b: &mut Builder, tree: &Tree, motion: Option<&TreeMotion>) -> Result<Skin> {
        Skin::named(b, tree, motion, None)
    }

    /// [`Skin::new`] for one tree of a forest: its joints other than the
    /// captured tips are named `{tree}_node_{i}` and the skin `tree`.
    pub(super) fn named(
        b: &mut Builder,
        tree: &Tree,
        motion: Option<&TreeMotion>,
        tree_name: Option<&str>,
    ) -> Result<Skin> {
        let n = tree.nodes.len();
        let first = b.root.nodes.len();
        let joint = |i: usize| json::Index::<json::Node>::new((first + i) as u32);
        if u32::try_from(first + n).is_err() {
            return Err(RenderError::TooLarge("the tree has too many nodes for glTF").into());
        }
        let children = tree.children();
        let rest_local: Vec<[f32; 3]> = tree
            .nodes
            .iter()
            .map(|node| {
                let parent = node
                    .parent
                    .map_or(glam::DVec3::ZERO, |p| tree.nodes[p].position);
                (node.position - parent).as_vec3().to_array()
            })
            .collect();
        for (i, node) in tree.nodes.iter().enumerate() {
            let (name, extras) = match node.kind {
                Kind::Captured { marker } => (
                    format!("tip_{marker:02}"),
                    Some(tip_extras(marker, i, motion)?),
                ),
                _ => match tree_name {
                    Some(t) => (format!("{t}_node_{i}"), None),
                    None => (format!("node_{i}"), None),
                },
            };
            let kids: Vec<_> = children[i].iter().map(|&c| joint(c)).collect();
            b.root.push(json::Node {
                name: Some(name),
                translation: Some(rest_local[i]),
                children: (!kids.is_empty()).then_some(kids),
                extras,
                ..Default::default()
            });
        }
        let mut ibm = Vec::with_capacity(n * 64);
        for node in &tree.nodes {
            let t = (-node.position).as_vec3();
            let m = glam::Mat4::from_translation(t).to_cols_array();
            ibm.extend(m.iter().flat_map(|v| v.to_le_bytes()));
        }
        let view = b.view(ibm, None);
        let ibm = b.accessor(view, 0, n, ComponentType::F32, Type::Mat4, None);
        let joints: Vec<_> = (0..n).map(joint).collect();
        let index = b.root.push(json::Skin {
            extensions: None,
            extras: Default::default(),
            inverse_bind_matrices: Some(ibm),
            joints: joints.clone(),
            name: Some(tree_name.unwrap_or("tree").into()),
            skeleton: joints.first().copied(),
        });
        Ok(Skin {
            index,
            joints,
            rest_local,
        })
    }

    /// The root joint (the trunk base), a scene root.
    pub(super) fn root(&self) -> json::Index<json::Node> {
        self.joints[0]
    }

    /// Adds the animation `capture`: every joint whose translation changes
    /// gets a LINEAR sampler over the shared key times.
    pub(super) fn animate(&self, b: &mut Builder, tree: &Tree, motion: &TreeMotion) -> Result<()> {
        animate_skins(b, &[(self, tree, motion)])
    }

    /// Appends the moving joints' local translations (to their parent),
    /// joint after joint, as little-endian floats, to `out`; returns each
    /// joint's index and byte offset from where `out` started. Joints that
    /// never leave their rest translation are left out.
    fn moving_translations(
        &self,
        tree: &Tree,
        motion: &TreeMotion,
        out: &mut Vec<u8>,
    ) -> Vec<(usize, usize)> {
        let keys = motion.keys();
        let start = out.len();
        let mut moving = Vec::new();
        let mut local = Vec::with_capacity(keys);
        // At most every joint: reserved once, so the chunk is not copied
        // while it grows (pages never written are never resident).
        out.reserve(tree.nodes.len() * keys * 12);
        for (i, node) in tree.nodes.iter().enumerate() {
            local.clear();
            for k in 0..keys {
                let pose = motion.pose(k);
                let p = pose[i];
                let q = node.parent.map_or([0.0; 3], |par| pose[par]);
                local.push([p[0] - q[0], p[1] - q[1], p[2] - q[2]]);
            }
            if local.iter().all(|l| *l == self.rest_local[i]) {
                continue;
            }
            moving.push((i, out.len() - start));
            out.extend(local.iter().flatten().flat_map(|v| v.to_le_bytes()));
        }
        moving
    }

    /// The channel that drives joint `i`'s translation from sampler `s`.
    fn translation_channel(&self, s: usize, i: usize) -> json::animation::Channel {
        json::animation::Channel {
            sampler: json::Index::new(s as u32),
            target: json::animation::Target {
                extensions: None,
                extras: Default::default(),
                node: self.joints[i],
                path: Valid(json::animation::Property::Translation),
            },
            extensions: None,
            extras: Default::default(),
        }
    }
}

impl Skinning for Skin {
    /// Adds `JOINTS_0` and `WEIGHTS_0` for vertices that follow `binds`.
    fn bind(&self, b: &mut Builder, binds: &[Bind], attributes: &mut Attributes) -> Result<()> {
        let n = self.joints.len();
        let mut joints = Vec::with_capacity(binds.len() * 8);
        let mut weights = Vec::with_capacity(binds.len() * 16);
        for bind in binds {
            let [a, c] = bind.nodes.map(|j| j as usize);
            if a >= n || c >= n || a > usize::from(u16::MAX) || c > usize::from(u16::MAX) {
                return Err(RenderError::Inconsistent(format!(
                    "a vertex follows node {} of a {n}-node tree (glTF skins take at most 65 536 joints)",
                    a.max(c)
                ))
                .into());
            }
            // Unused slots: joint 0 with weight 0 (the validator wants
            // zero-weight slots to name joint 0).
            let (j, w) = if a == c || bind.weight >= 1.0 {
                ([a, 0], [1.0f32, 0.0])
            } else if bind.weight <= 0.0 {
                ([c, 0], [1.0, 0.0])
            } else {
                ([a, c], [bind.weight, 1.0 - bind.weight])
            };
            for v in [j[0] as u16, j[1] as u16, 0, 0] {
                joints.extend(v.to_le_bytes());
            }
            for v in [w[0], w[1], 0.0, 0.0] {
                weights.extend(v.to_le_bytes());
            }
        }
        let view = b.view(joints, Some(json::buffer::Target::ArrayBuffer));
        let j = b.accessor(view, 0, binds.len(), ComponentType::U16, Type::Vec4, None);
        let view = b.view(weights, Some(json::buffer::Target::ArrayBuffer));
        let w = b.accessor(view, 0, binds.len(), ComponentType::F32, Type::Vec4, None);
        attributes.insert(Valid(json::mesh::Semantic::Joints(0)), j);
        attributes.insert(Valid(json::mesh::Semantic::Weights(0)), w);
        Ok(())
    }

    /// The skin's index, for the skinned mesh nodes.
    fn index(&self) -> json::Index<json::Skin> {
        self.index
    }
}

/// Adds one animation, `capture`, over several trees' skins (a forest: one
/// clock for every tree, so they sway together): every joint whose
/// translation changes gets a LINEAR sampler over the shared key times.
/// The motions must share their key times.
pub(super) fn animate_skins(b: &mut Builder, skins: &[(&Skin, &Tree, &TreeMotion)]) -> Result<()> {
    let Some(&(_, _, first)) = skins.first() else {
        return Ok(());
    };
    let keys = first.keys();
    for &(skin, _, motion) in skins {
        let n = skin.joints.len();
        if motion.nodes != n
            || motion.positions.len() != motion.keys() * n
            || keys == 0
            || motion.times != first.times
        {
            return Err(RenderError::Inconsistent(
                "the motion does not belong to this tree".into(),
            )
            .into());
        }
    }
    let input = key_times(b, first);
    let mut samplers = Vec::new();
    let mut channels = Vec::new();
    for &(skin, tree, motion) in skins {
        let mut moving = Vec::new();
        let view = b.view_written(None, |bin| {
            moving = skin.moving_translations(tree, motion, bin);
        });
        let Some(view) = view else {
            // Nothing of this tree moves (a buffer view may not be empty).
            continue;
        };
        for &(i, offset) in &moving {
            let output = b.accessor(view, offset, keys, ComponentType::F32, Type::Vec3, None);
            channels.push(skin.translation_channel(samplers.len(), i));
            samplers.push(linear_sampler(input, output));
        }
    }
    if channels.is_empty() {
        // Nothing moved: a glTF animation needs at least one channel.
        return Ok(());
    }
    let motions: Vec<&TreeMotion> = skins.iter().map(|s| s.2).collect();
    b.root.push(json::Animation {
        extensions: None,
        extras: Some(motion_extras(&motions)?),
        channels,
        name: Some("capture".into()),
        samplers,
    });
    Ok(())
}

/// The key times (s) as the samplers' shared input accessor, with the
/// min/max glTF requires of an animation input.
fn key_times(b: &mut Builder, motion: &TreeMotion) -> json::Index<json::Accessor> {
    let keys = motion.keys();
    let times: Vec<f32> = motion.times.iter().map(|&t| t as f32).collect();
    let bytes: Vec<u8> = times.iter().flat_map(|t| t.to_le_bytes()).collect();
    let view = b.view(bytes, None);
    let (lo, hi) = (times[0], times[keys - 1]);
    b.accessor(
        view,
        0,
        keys,
        ComponentType::F32,
        Type::Scalar,
        Some((vec![lo], vec![hi])),
    )
}

/// A linear sampler from key times to values.
fn linear_sampler(
    input: json::Index<json::Accessor>,
    output: json::Index<json::Accessor>,
) -> json::animation::Sampler {
    json::animation::Sampler {
        extensions: None,
        extras: Default::default(),
        input,
        interpolation: Valid(json::animation::Interpolation::Linear),
        output,
    }
}

/// What the animation's extras tell a viewer about the motion: its clock,
/// the bending law and how far the branches had to stretch (over every
/// tree of a forest: the largest change, and the mean over all nodes).
fn motion_extras(motions: &[&TreeMotion]) -> Result<Box<RawValue>> {
    let motion = motions[0];
    let stretch = combined_stretch(motions);
    raw(&serde_json::json!({
        "start_s": motion.start_s,
        "rate_hz": motion.rate_hz,
        "keys": motion.keys(),
        "bend_power": motion.bend_power,
        "stretch_max_pct": stretch.max_pct,
        "stretch_mean_pct": stretch.mean_pct,
        "cut_to_max_duration": motion.cut,
    }))
}

/// The branch-length change of several trees' motions: the largest, and the
/// mean weighted by node count (one tree: its own figures, unchanged).
pub(crate) fn combined_stretch(motions: &[&TreeMotion]) -> Stretch {
    if let [one] = motions {
        return one.stretch;
    }
    let mut out = Stretch::default();
    let (mut sum, mut nodes) = (0.0, 0usize);
    for m in motions {
        if m.stretch.max_pct > out.max_pct || out.worst_node.is_none() {
            out.max_pct = m.stretch.max_pct;
            out.worst_node = m.stretch.worst_node;
        }
        sum += m.stretch.mean_pct * m.nodes as f64;
        nodes += m.nodes;
    }
    out.mean_pct = if nodes == 0 { 0.0 } else { sum / nodes as f64 };
    out
}

/// `extras` of a captured tip's joint: its marker and, with a motion, the
/// runs of keys `[first, last]` in which its displacement was filled,
/// borrowed from its neighbours or held at rest.
fn tip_extras(marker: usize, node: usize, motion: Option<&TreeMotion>) -> Result<Box<RawValue>> {
    let mut v = serde_json::json!({ "marker": marker });
    if let Some(c) = motion.and_then(|m| m.captured.iter().find(|c| c.node == node)) {
        for (name, kind) in [
            ("filled", TipSource::Filled),
            ("borrowed", TipSource::Borrowed),
            ("rest", TipSource::Rest),
        ] {
            let runs = runs(&c.sources, kind);
            if !runs.is_empty() {
                v[name] = serde_json::json!(runs);
            }
        }
    }
    raw(&v)
}

/// Runs `[first, last]` of consecutive entries equal to `kind`.
fn runs(sources: &[TipSource], kind: TipSource) -> Vec<[usize; 2]> {
    let mut out: Vec<[usize; 2]> = Vec::new();
    for (k, s) in sources.iter().enumerate() {
        if *s != kind {
            continue;
        }
        match out.last_mut() {
            Some(run) if run[1] + 1 == k => run[1] = k,
            _ => out.push([k, k]),
        }
    }
    out
}

fn raw(v: &serde_json::Value) -> Result<Box<RawValue>> {
    Ok(serde_json::value::to_raw_value(v).map_err(RenderError::Json)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn runs_of_keys() {
        use TipSource::*;
        let s = [
            Measured, Filled, Filled, Measured, Filled, Borrowed, Borrowed,
        ];
        assert_eq!(runs(&s, Filled), vec![[1, 2], [4, 4]]);
        assert_eq!(runs(&s, Borrowed), vec![[5, 6]]);
        assert!(runs(&s, Rest).is_empty());
    }
}
