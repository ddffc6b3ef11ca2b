//! The tree as a JSON skeleton (tree.json): parallel arrays indexed by node
//! (position, parent, radius, kind, marker), plus the parameters and seed
//! that produced it, so a result can be reproduced and other programs can
//! read the structure without a glTF library.
//!
//! ```json
//! {
//!   "version": 1,
//!   "seed": 1,
//!   "parameters": { ...the [reconstruct] section... },
//!   "wind": [x, y, z],
//!   "steps": 23, "forced_joins": 0, "root": 0, "attractor": 7,
//!   "nodes": [[x, y, z], ...],            metres, Y up
//!   "parents": [null, 0, ...],            null only for the root
//!   "radii": [0.05, ...],                 metres
//!   "kinds": ["trunk", "junction", "branch", "tip", "captured", ...],
//!   "markers": [null, ..., 4, ...]        tips.json marker of captured tips
//! }
//! ```

use serde_json::{json, Value};

use crate::error::Result;
use crate::model::tree::{Kind, Tree};
use crate::reconstruct::ReconstructSettings;
use crate::render::error::RenderError;

/// Version of the tree.json layout.
pub const VERSION: u32 = 1;

/// Encodes `tree` (reconstructed with `cfg`) as tree.json text: one key per
/// line, each array on a single line so the file stays small and diffable.
pub fn to_json(tree: &Tree, cfg: &ReconstructSettings) -> Result<String> {
    to_json_seeded(tree, cfg, cfg.seed)
}

/// [`to_json`] for a tree grown from `seed` (one tree of a forest, served
/// on its own as version 1).
pub fn to_json_seeded(tree: &Tree, cfg: &ReconstructSettings, seed: u64) -> Result<String> {
    let parameters = serde_json::to_value(cfg).map_err(RenderError::from)?;
    let mut fields: Vec<(&str, Value)> = vec![
        ("version", json!(VERSION)),
        ("seed", json!(seed)),
        ("parameters", parameters),
        ("wind", json!(tree.wind.to_array())),
    ];
    fields.extend(skeleton(tree));
    object(&fields, "")
}

/// Version of the tree.json layout with several trees.
pub const FOREST_VERSION: u32 = 2;

/// What tree.json says of one tree of a forest besides its skeleton.
pub struct ForestEntry<'a> {
    /// The tree's id.
    pub id: usize,
    /// Its name.
    pub name: &'a str,
    /// Its trunk base (m).
    pub base: [f64; 3],
    /// `configured` or `detected`.
    pub base_source: &'a str,
    /// The seed it was grown from.
    pub seed: u64,
    /// The tree.
    pub tree: &'a Tree,
}

/// Several trees as tree.json version 2 (docs/forest.md): the seed,
/// parameters and wind, then `trees` (each with its id, name, base and seed
/// and the version-1 skeleton keys), then `ambiguous` (the tips that were
/// close calls, as given), then `count` (how the number of trees was
/// chosen, as given; null when the trees were configured).
pub fn forest_json(
    trees: &[ForestEntry<'_>],
    ambiguous: Value,
    count: Value,
    wind: [f64; 3],
    cfg: &ReconstructSettings,
) -> Result<String> {
    let parameters = serde_json::to_value(cfg).map_err(RenderError::from)?;
    let mut text = String::from("{\n");
    for (key, value) in [
        ("version", json!(FOREST_VERSION)),
        ("seed", json!(cfg.seed)),
        ("parameters", parameters),
        ("wind", json!(wind)),
    ] {
        let v = serde_json::to_string(&value).map_err(RenderError::from)?;
        text.push_str(&format!("  \"{key}\": {v},\n"));
    }
    text.push_str("  \"trees\": [\n");
    for (i, t) in trees.iter().enumerate() {
        let mut fields: Vec<(&str, Value)> = vec![
            ("id", json!(t.id)),
            ("name", json!(t.name)),
            ("base", json!(t.base)),
            ("base_source", json!(t.base_source)),
            ("seed", json!(t.seed)),
        ];
        fields.extend(skeleton(t.tree));
        let body = object(&fields, "    ")?;
        text.push_str("    ");
        text.push_str(body.trim_end());
        text.push_str(if i + 1 < trees.len() { ",\n" } else { "\n" });
    }
    text.push_str("  ],\n");
    let v = serde_json::to_string(&ambiguous).map_err(RenderError::from)?;
    text.push_str(&format!("  \"ambiguous\": {v},\n"));
    let v = serde_json::to_string(&count).map_err(RenderError::from)?;
    text.push_str(&format!("  \"count\": {v}\n}}\n"));
    Ok(text)
}

/// The skeleton's keys, shared by both versions.
fn skeleton(tree: &Tree) -> Vec<(&'static str, Value)> {
    vec![
        ("steps", json!(tree.steps)),
        ("forced_joins", json!(tree.forced_joins)),
        ("root", json!(0)),
        ("attractor", json!(tree.attractor)),
        (
            "nodes",
            Value::from(
                tree.nodes
                    .iter()
                    .map(|n| json!(n.position.to_array()))
                    .collect::<Vec<_>>(),
            ),
        ),
        (
            "parents",
            json!(tree.nodes.iter().map(|n| n.parent).collect::<Vec<_>>()),
        ),
        (
            "radii",
            json!(tree.nodes.iter().map(|n| n.radius).collect::<Vec<_>>()),
        ),
        (
            "kinds",
            json!(tree.nodes.iter().map(|n| n.kind.name()).collect::<Vec<_>>()),
        ),
        (
            "markers",
            json!(tree
                .nodes
                .iter()
                .map(|n| match n.kind {
                    Kind::Captured { marker } => Some(marker),
                    _ => None,
                })
                .collect::<Vec<_>>()),
        ),
    ]
}

/// An object with one key per line, each line indented by `indent` more
/// than the braces.
fn object(fields: &[(&str, Value)], indent: &str) -> Result<String> {
    let mut out = String::from("{\n");
    for (i, (key, value)) in fields.iter().enumerate() {
        let v = serde_json::to_string(value).map_err(RenderError::from)?;
        out.push_str(&format!("{indent}  \"{key}\": {v}"));
        out.push_str(if i + 1 < fields.len() { ",\n" } else { "\n" });
    }
    out.push_str(indent);
    out.push_str("}\n");
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::tree::Node;
    use glam::DVec3;

    #[test]
    fn layout_reads_back() {
        let tree = Tree {
            nodes: vec![
                Node {
                    position: DVec3::ZERO,
                    parent: None,
                    radius: 0.02,
                    kind: Kind::Trunk,
                },
                Node {
                    position: DVec3::new(0.0, 1.0, 0.0),
                    parent: Some(0),
                    radius: 0.02,
                    kind: Kind::Trunk,
                },
                Node {
                    position: DVec3::new(0.5, 1.5, 0.25),
                    parent: Some(1),
                    radius: 0.003,
                    kind: Kind::Captured { marker: 7 },
                },
            ],
            trunk: vec![0, 1],
            attractor: 1,
            forced_joins: 0,
            steps: 3,
            wind: DVec3::new(0.0, 0.0, 2.0),
        };
        let cfg = ReconstructSettings::default();
        let text = to_json(&tree, &cfg).unwrap();
        let v: Value = serde_json::from_str(&text).unwrap();
        assert_eq!(v["seed"], json!(cfg.seed));
        assert_eq!(v["parents"], json!([null, 0, 1]));
        assert_eq!(v["kinds"], json!(["trunk", "trunk", "captured"]));
        assert_eq!(v["markers"], json!([null, null, 7]));
        assert_eq!(v["nodes"][2], json!([0.5, 1.5, 0.25]));
        assert_eq!(v["radii"][2], json!(0.003));
        assert_eq!(v["parameters"]["volume"], json!("boxes"));
        assert_eq!(v["parameters"]["beta"], json!(cfg.beta));
        assert_eq!(v["wind"], json!([0.0, 0.0, 2.0]));
    }
}
