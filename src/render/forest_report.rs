//! What the outputs say about several trees: each tree grown (`Member`)
//! and the forest's report (how the trees were found, the close calls).
//! Plain data, apart from `render/forest.rs` that grows the trees, so that
//! `render/outputs.rs` can carry them without depending on the growing.

use std::fmt;
use std::sync::Arc;

use glam::DVec3;
use serde::Serialize;

use crate::model::tree::Tree;
use crate::reconstruct::forest::{AssignRule, BaseSource, CountBasis, CountChoice};

/// One tree of the outputs.
#[derive(Debug, Clone)]
pub struct Member {
    /// Its id (tree.json `id`, the OSC `tree` argument, `/trees/{id}.json`).
    pub id: usize,
    /// Its name.
    pub name: String,
    /// Its trunk base (m).
    pub base: DVec3,
    /// Where the base came from.
    pub source: BaseSource,
    /// The seed it was grown from.
    pub seed: u64,
    /// The tree.
    pub tree: Arc<Tree>,
    /// Grown for these outputs (false: taken unchanged from the last ones).
    pub rebuilt: bool,
}

/// The forest's part of the report: the trees, how they were found, and
/// the tips that were close calls.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ForestReport {
    /// Per tree: id, name, base, where it came from, tips, nodes, forced
    /// joins, rebuilt.
    pub trees: Vec<TreeLine>,
    /// Configured trees that got no tip.
    pub empty: Vec<String>,
    /// The rule that gave tips to trees.
    pub rule: AssignRule,
    /// The automatic search's RMS crown fit per number of trees (empty for
    /// configured trees).
    pub fits: Vec<(usize, f64)>,
    /// False when no number of trees fitted within the tolerance.
    pub fits_well: bool,
    /// How the number of trees was chosen: by the crown fit or the sway,
    /// the rule and its margin (`None` for configured trees).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub count: Option<CountChoice>,
    /// Tips that were close calls: marker, its tree, the runner-up, costs.
    pub ambiguous: Vec<AmbiguousLine>,
    /// Captured tips beyond one of their tree's planes.
    pub beyond_planes: usize,
}

/// One tree in the report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TreeLine {
    /// Tree id.
    pub id: usize,
    /// Tree name.
    pub name: String,
    /// Trunk base (m).
    pub base: [f64; 3],
    /// `configured` or `detected`.
    pub source: BaseSource,
    /// Captured tips given to it.
    pub tips: usize,
    /// Nodes of its skeleton.
    pub nodes: usize,
    /// Its particles joined to the trunk after `max_steps`.
    pub forced_joins: usize,
    /// Grown for these outputs.
    pub rebuilt: bool,
}

/// An ambiguous tip in the report, trees by name.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AmbiguousLine {
    /// The marker.
    pub marker: usize,
    /// The tree it went to.
    pub tree: String,
    /// The runner-up.
    pub other: String,
    /// Its costs for both.
    pub costs: [f64; 2],
}

/// How a tree's base is named in the report and tree.json.
pub(super) fn source_name(s: BaseSource) -> &'static str {
    match s {
        BaseSource::Configured => "configured",
        BaseSource::Detected => "detected",
    }
}

/// The report's line on how the number of trees was chosen: by what, the
/// fit's own number when the sway changed it, the margin and the rule.
fn count_line(trees: usize, c: &CountChoice) -> String {
    let by = match c.basis {
        CountBasis::Fit => "the crown fit".to_string(),
        CountBasis::Sway => format!("the sway (the crown fit alone: {})", c.fit_trees),
    };
    let close = if c.margin < CLOSE_CALL {
        " — a close call, check them"
    } else {
        ""
    };
    format!(
        "count: {trees} by {by}, margin {:.0} %{close}: {}",
        100.0 * c.margin,
        c.reason
    )
}

/// Below this margin the count line calls the count a close call.
const CLOSE_CALL: f64 = 0.1;

impl fmt::Display for ForestReport {
    /// The trees (as `[[trees]]` tables to pin when they were found), the
    /// empty ones and the close calls.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let found = self.trees.iter().all(|t| t.source == BaseSource::Detected);
        if found {
            let fits: Vec<String> = self
                .fits
                .iter()
                .map(|(k, r)| format!("{k}: {:.3} m", r))
                .collect();
            writeln!(
                f,
                "trees: {} found from the tips (RMS crown fit by number of trees {}){}; to pin them, add to the config:",
                self.trees.len(),
                fits.join(", "),
                if self.fits_well { "" } else { " — no number fitted well, check them" }
            )?;
            if let Some(c) = &self.count {
                writeln!(f, "{}", count_line(self.trees.len(), c))?;
            }
            for t in &self.trees {
                writeln!(
                    f,
                    "[[trees]]\nname = \"{}\"\nbase = [{:.3}, {:.3}, {:.3}]",
                    t.name, t.base[0], t.base[1], t.base[2]
                )?;
            }
        }
        for t in &self.trees {
            writeln!(
                f,
                "{} ({}): {} tips, {} nodes, {} forced joins{}",
                t.name,
                source_name(t.source),
                t.tips,
                t.nodes,
                t.forced_joins,
                if t.rebuilt { "" } else { ", unchanged" }
            )?;
        }
        for e in &self.empty {
            writeln!(f, "{e}: no tips (not grown)")?;
        }
        if !self.ambiguous.is_empty() {
            let list: Vec<String> = self
                .ambiguous
                .iter()
                .map(|a| {
                    format!(
                        "marker {} ({} {:.3}, {} {:.3})",
                        a.marker, a.tree, a.costs[0], a.other, a.costs[1]
                    )
                })
                .collect();
            writeln!(f, "ambiguous tips: {}", list.join("; "))?;
        }
        if self.beyond_planes > 0 {
            writeln!(
                f,
                "{} captured tips lie beyond their tree's planes",
                self.beyond_planes
            )?;
        }
        Ok(())
    }
}
