//! The reconstruction's settings (`[reconstruct]` in the config).

use serde::{Deserialize, Serialize};

use crate::error::{check_range, Result};

/// Which crown volume the random tips are placed in (paper §5, Figure 10).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum VolumeKind {
    /// A vertical stack of bounding boxes; looser, more random crowns.
    Boxes,
    /// The convex hull of the captured tips; follows the crown more closely.
    Hull,
}

/// Particle-flow reconstruction (paper §5–6, spec §6–7). Every flow parameter
/// of the paper is here so that a user can re-run the flow on saved tips.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReconstructSettings {
    /// Seed for every random choice; same tips + config + seed = same bytes.
    pub seed: u64,
    /// Crown volume for the random tips.
    pub volume: VolumeKind,
    /// Boxes in the vertical stack (volume = boxes).
    pub boxes: usize,
    /// Captured + random tips: about the real tree's number of tips.
    pub total_tips: usize,
    /// Nodes on the synthetic trunk (paper: 9–10).
    pub trunk_nodes: usize,
    /// Trunk length as a multiple of the crown height (paper: about 1.2).
    pub height_factor: f64,
    /// Largest random x/z offset of a trunk node (m).
    pub trunk_offset: f64,
    /// Ground height (m): trunk base, zero of the mean particle height.
    pub ground_height: f64,
    /// Shape-format attractor as a trunk node index; -1 = the paper's choice.
    pub attractor_node: i64,
    /// β: step length factor, L = β |S_p − S_t|.
    pub beta: f64,
    /// α: shape-format magnitude factor on the mean particle height.
    pub alpha: f64,
    /// ω1: gravity weight (negative gives a willow).
    pub gravity_weight: f64,
    /// ω2: shape-format weight.
    pub shape_weight: f64,
    /// ω3: wind weight.
    pub wind_weight: f64,
    /// Particles closer than this merge into a junction (m).
    pub merge_distance: f64,
    /// Particles closer than this to a trunk node join the trunk (m).
    pub trunk_distance: f64,
    /// Steps before the remaining particles are joined to the trunk directly.
    pub max_steps: usize,
    /// Radius of a branch tip (m).
    pub tip_radius: f64,
    /// Pipe-model exponent γ.
    pub gamma: f64,
    /// Vertices per cylinder ring.
    pub sides: usize,
    /// Whether to add leaves.
    pub leaves: bool,
    /// Leaves begin at this fraction of a branch's length.
    pub leaf_start: f64,
    /// Leaves per metre of leafy branch.
    pub leaf_density: f64,
    /// Leaf length (m).
    pub leaf_size: f64,
}

impl ReconstructSettings {
    /// Range checks for the `[reconstruct]` section, each naming its key.
    pub fn validate(&self) -> Result<()> {
        let r = |key: &str, v: f64, lo: f64, hi: f64| {
            check_range(&format!("reconstruct.{key}"), v, lo, hi)
        };
        r("boxes", self.boxes as f64, 1.0, 100.0)?;
        r("total_tips", self.total_tips as f64, 1.0, 1_000_000.0)?;
        r("trunk_nodes", self.trunk_nodes as f64, 2.0, 1000.0)?;
        r("height_factor", self.height_factor, 0.1, 10.0)?;
        r("trunk_offset", self.trunk_offset, 0.0, 1.0)?;
        r("ground_height", self.ground_height, -100.0, 100.0)?;
        r(
            "attractor_node",
            self.attractor_node as f64,
            -1.0,
            self.trunk_nodes as f64 - 1.0,
        )?;
        r("beta", self.beta, 0.01, 1.0)?;
        r("alpha", self.alpha, 0.0, 1.0)?;
        r("gravity_weight", self.gravity_weight, -10.0, 10.0)?;
        r("shape_weight", self.shape_weight, 0.0, 10.0)?;
        r("wind_weight", self.wind_weight, -10.0, 10.0)?;
        r("merge_distance", self.merge_distance, 1e-6, 1.0)?;
        r("trunk_distance", self.trunk_distance, 1e-6, 1.0)?;
        r("max_steps", self.max_steps as f64, 1.0, 100_000.0)?;
        r("tip_radius", self.tip_radius, 1e-5, 1.0)?;
        r("gamma", self.gamma, 1.0, 4.0)?;
        r("sides", self.sides as f64, 3.0, 64.0)?;
        r("leaf_start", self.leaf_start, 0.0, 1.0)?;
        r("leaf_density", self.leaf_density, 0.0, 10_000.0)?;
        r("leaf_size", self.leaf_size, 0.001, 1.0)?;
        Ok(())
    }
}
