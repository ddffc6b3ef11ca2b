//! The forest's settings: `[forest]` (how trees are found and tips given to
//! them) and `[[trees]]` (trunk bases the operator pinned). See
//! docs/forest.md.

use glam::DVec3;
use serde::{Deserialize, Serialize};

use crate::error::{check_range, Error, Result};

/// How tips are given to trees once the bases are known.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum AssignRule {
    /// Shortest paths over a neighbourhood graph of tips and trunk bases
    /// (Livny et al. 2010) and nothing else: the baseline the crown rule is
    /// measured against.
    Livny,
    /// Crown surfaces fitted to each tree's tips, plus the sway of the limbs
    /// where the session has a wind phase (ours; docs/forest.md).
    Crown,
}

/// `[forest]`: finding several trees in one capture and giving every tip
/// to one of them.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ForestSettings {
    /// The rule that gives tips to trees.
    pub rule: AssignRule,
    /// Most trees the automatic search tries.
    pub max_trees: usize,
    /// Found trunk bases are at least this far apart (m): two crowns closer
    /// than this are taken for one tree.
    pub min_spacing_m: f64,
    /// Fewest tips a found tree may have: a crown surface needs a few tips
    /// to be fitted at all.
    pub min_tips: usize,
    /// RMS distance (m) of the tips from their crown surfaces (the worst
    /// tree's) that counts as explained: the smallest number of trees that
    /// reaches it is taken.
    pub fit_tolerance_m: f64,
    /// When no number of trees reaches `fit_tolerance_m`: the number taken
    /// is the one with the least RMS + this × the number (m per tree), so a
    /// tree more must buy a clearly better fit.
    pub count_penalty_m: f64,
    /// Neighbours of each tip in the shortest-path graph.
    pub neighbours: usize,
    /// A tip whose best cost is more than this fraction of its second best
    /// is reported as ambiguous.
    pub ambiguous_ratio: f64,
    /// Sway correlation above which two nearby tips count as one limb.
    pub sway_correlation: f64,
    /// How strongly such a partner pulls a tip into its tree (m of surface
    /// distance per partner); 0 turns the sway off.
    pub sway_weight_m: f64,
    /// No longer used (accepted so that configs which set it still load):
    /// the count's threshold on two crowns' mean sway correlation, replaced
    /// by one criterion for the fit and the sway (docs/forest.md, "The
    /// count: one criterion for the fit and the sway").
    pub trunk_coherence: f64,
    /// How strongly a tip's mean sway correlation with a tree's tips pulls
    /// it into that tree (m of surface distance per unit of correlation):
    /// when tips are given to trees, and when the search for the trees
    /// fits its crowns in a swayed take.
    pub trunk_weight_m: f64,
}

impl ForestSettings {
    /// Range checks, each naming its key.
    pub fn validate(&self) -> Result<()> {
        let r =
            |key: &str, v: f64, lo: f64, hi: f64| check_range(&format!("forest.{key}"), v, lo, hi);
        r("max_trees", self.max_trees as f64, 1.0, 20.0)?;
        r("min_spacing_m", self.min_spacing_m, 0.05, 100.0)?;
        r("min_tips", self.min_tips as f64, 3.0, 1000.0)?;
        r("fit_tolerance_m", self.fit_tolerance_m, 0.001, 10.0)?;
        r("count_penalty_m", self.count_penalty_m, 0.0, 10.0)?;
        r("neighbours", self.neighbours as f64, 1.0, 100.0)?;
        r("ambiguous_ratio", self.ambiguous_ratio, 0.0, 1.0)?;
        r("sway_correlation", self.sway_correlation, 0.0, 1.0)?;
        r("sway_weight_m", self.sway_weight_m, 0.0, 10.0)?;
        r("trunk_coherence", self.trunk_coherence, 0.0, 1.0)?;
        r("trunk_weight_m", self.trunk_weight_m, 0.0, 10.0)?;
        Ok(())
    }
}

/// One `[[trees]]` table: a trunk base the operator pinned.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ConfiguredTree {
    /// What the outputs call the tree; empty = `tree-N` by its place in the
    /// list.
    #[serde(default)]
    pub name: String,
    /// Where the trunk stands (m, Y up): `y` is the ground under it.
    pub base: [f64; 3],
}

impl ConfiguredTree {
    /// The base as a vector.
    pub fn base(&self) -> DVec3 {
        DVec3::from_array(self.base)
    }
}

/// Checks the `[[trees]]` list: finite bases within 10 km, names unique.
pub fn validate_trees(trees: &[ConfiguredTree]) -> Result<()> {
    if trees.len() > 20 {
        return Err(Error::config(
            "trees",
            format!("{} trees; at most 20 are supported", trees.len()),
        ));
    }
    for (i, t) in trees.iter().enumerate() {
        if !t.base.iter().all(|v| v.is_finite() && v.abs() <= 1e4) {
            return Err(Error::config(
                format!("trees[{i}].base"),
                "must be three finite numbers [x, y, z] in metres within 10 km",
            ));
        }
        let name = tree_name(trees, i);
        if let Some(j) = (0..i).find(|&j| tree_name(trees, j) == name) {
            return Err(Error::config(
                format!("trees[{i}].name"),
                format!("'{name}' is already the name of trees[{j}]"),
            ));
        }
    }
    Ok(())
}

/// The name of configured tree `i`: its own, or `tree-i`.
pub fn tree_name(trees: &[ConfiguredTree], i: usize) -> String {
    match trees.get(i) {
        Some(t) if !t.name.is_empty() => t.name.clone(),
        _ => default_name(i),
    }
}

/// `tree-i`: the name of a tree nobody named.
pub fn default_name(i: usize) -> String {
    format!("tree-{i}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_default_and_must_differ() {
        let mut trees = vec![
            ConfiguredTree {
                name: String::new(),
                base: [0.0, 0.0, 0.0],
            },
            ConfiguredTree {
                name: "pine".into(),
                base: [1.0, 0.0, 0.0],
            },
        ];
        assert!(validate_trees(&trees).is_ok());
        assert_eq!(tree_name(&trees, 0), "tree-0");
        assert_eq!(tree_name(&trees, 1), "pine");
        trees[1].name = "tree-0".into();
        let e = validate_trees(&trees).unwrap_err().to_string();
        assert!(e.contains("trees[1].name"), "{e}");
        trees[1].name = "b".into();
        trees[0].base[1] = f64::NAN;
        let e = validate_trees(&trees).unwrap_err().to_string();
        assert!(e.contains("trees[0].base"), "{e}");
    }
}
