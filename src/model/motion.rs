//! `TreeMotion`: the captured motion carried onto every node of a
//! reconstructed tree (issue 13, docs/animation.md), sampled at the keys of
//! the animation. `animate` makes it; the animated tree.glb and tree.png
//! show it.

use serde::Serialize;

/// Where a captured tip's displacement in one key came from, so that a
/// fill or a borrowed motion is never passed off as a measurement.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum TipSource {
    /// The marker was measured in the key's frame.
    Measured,
    /// The tracker filled a short gap there (spec §3).
    Filled,
    /// The marker was missing: the tip moved with its neighbours.
    Borrowed,
    /// No captured tip had a value in that frame: the tip stayed at rest.
    Rest,
}

impl TipSource {
    /// Measured or filled: the tip's position is the tracker's.
    pub fn is_tracked(self) -> bool {
        matches!(self, TipSource::Measured | TipSource::Filled)
    }
}

/// One captured tip's place in the motion.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CapturedMotion {
    /// Its node in the tree.
    pub node: usize,
    /// Its marker (tips.json `marker`).
    pub marker: usize,
    /// Where its displacement came from, one entry per key.
    pub sources: Vec<TipSource>,
}

/// How much the deformation changed the lengths of the branch segments,
/// over every segment and every key: the model keeps lengths by rotating
/// segments, and only the correction that puts captured tips exactly on
/// their tracked positions stretches them (docs/animation.md, step 4).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Stretch {
    /// Largest |length / rest length − 1| (%).
    pub max_pct: f64,
    /// Mean |length / rest length − 1| (%).
    pub mean_pct: f64,
    /// The node whose segment (to its parent) stretched most.
    pub worst_node: Option<usize>,
}

/// The tree's motion: node positions at every key.
#[derive(Debug, Clone, PartialEq)]
pub struct TreeMotion {
    /// Recording time (s, the timeline's clock) of the first key.
    pub start_s: f64,
    /// Key times in seconds after `start_s`, strictly increasing; the first
    /// is 0.
    pub times: Vec<f64>,
    /// The recorded (internal) frame each key shows: keys are captured
    /// instants, never interpolations between frames.
    pub frames: Vec<i64>,
    /// Nodes in the tree (the row length of `positions`).
    pub nodes: usize,
    /// Node positions (m, Y up), key after key: key `k`'s nodes are
    /// `positions[k * nodes..(k + 1) * nodes]`, in node index order. f32,
    /// as the glTF file stores them (0.2 µm at 3 m).
    pub positions: Vec<[f32; 3]>,
    /// The captured tips, in node index order.
    pub captured: Vec<CapturedMotion>,
    /// Length change of the branch segments.
    pub stretch: Stretch,
    /// The key rate asked for (Hz).
    pub rate_hz: f64,
    /// The bending power the profile used.
    pub bend_power: f64,
    /// The window asked for was longer than `animate.max_duration_s` and
    /// was cut to that length.
    pub cut: bool,
}

impl TreeMotion {
    /// Number of keys.
    pub fn keys(&self) -> usize {
        self.times.len()
    }

    /// The node positions of key `k` (empty when out of range).
    pub fn pose(&self, k: usize) -> &[[f32; 3]] {
        self.positions
            .get(k * self.nodes..(k + 1) * self.nodes)
            .unwrap_or(&[])
    }
}
