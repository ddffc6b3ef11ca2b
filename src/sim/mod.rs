//! Synthetic trees and capture sessions with ground truth: the project's own
//! test bench, since no public motion capture of trees exists.
//!
//! [`generate`] grows a seeded tree ([`tree`]), puts markers on its outermost
//! tips, moves them through a still phase and a wind phase ([`motion`]), and
//! simulates what Motive records ([`capture`]): noise, occlusion gaps,
//! spurious reflections and a new `Unlabeled N` column after every gap.
//! [`write_motive_csv`] writes the result as a Motive 1.23 export and
//! [`write_session`] writes that plus `NAME.truth.json` ([`Truth`]).
//!
//! Every random draw comes from [`crate::rng::Rng`] streams split by purpose
//! (tree, motion, wind, capture) and then by tip, so the same options give the
//! same bytes, and changing one option (say the gap fraction) leaves the
//! tree, the motion and the noise of the remaining samples as they were.

pub mod capture;
pub mod floor;
pub mod forest;
pub mod motion;
pub mod motive_writer;
pub mod score;
pub mod stress;
pub mod tree;
pub mod truth;

use std::f64::consts::TAU;
use std::fmt;
use std::path::{Path, PathBuf};

use glam::DVec3;
use serde::{Deserialize, Serialize};

// The same range rule and message as every config key.
use crate::error::check_range as check;
use crate::error::{Error, Result};
use crate::model::frame::MarkerFrame;
use crate::rng::Rng;

pub use forest::{ForestTruth, Layout, PlacedTree};
pub use motive_writer::write_motive_csv;
pub use tree::{CrownShape, TreeNode, TreeTruth};
pub use truth::{ColumnTruth, GapTruth, GustTruth, Sinusoid, SpuriousTruth, TipTruth, Truth};

/// Stream labels under the session seed.
const TREE: u64 = 1;
const MOTION: u64 = 2;
const WIND: u64 = 3;
const CAPTURE: u64 = 4;
const GUSTS: u64 = 5;
/// Where the trees of a forest stand.
const FOREST: u64 = 6;

/// Longest session `generate` makes (frames).
pub const MAX_FRAMES: usize = 360_000;

/// Number of the first `Unlabeled N` column (Motive's numbers are arbitrary).
const FIRST_UNLABELED: u64 = 1000;

/// Everything that shapes a synthetic session. Defaults follow the paper's
/// maple session (§7: 24 markers, 100 Hz, about 20 s still) plus a 20 s wind
/// phase and the imperfections of a real capture.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SynthOptions {
    /// Seed of every random draw.
    pub seed: u64,
    /// Markers placed on the tree (1–70; the paper uses 24 and 35).
    pub tips: usize,
    /// Crown form: round (maple) or conical (pine), the paper's two trees.
    pub shape: CrownShape,
    /// Frames per second (Hz).
    pub frame_rate: f64,
    /// Length of the still phase at the start of the take (s).
    pub still_s: f64,
    /// Length of the wind phase that follows (s).
    pub wind_s: f64,
    /// Time the fan takes to reach full strength (s).
    pub wind_ramp_s: f64,
    /// Measurement noise, standard deviation per axis (mm).
    pub noise_mm: f64,
    /// Largest peak amplitude of the tips' periodic motion without wind (mm);
    /// the paper sees motion within 1 mm (§7).
    pub still_motion_mm: f64,
    /// Scales every wind displacement (1 = sway up to a few cm).
    pub sway_scale: f64,
    /// Fraction of tip samples lost to occlusion (0–0.3).
    pub gap_fraction: f64,
    /// Longest short occlusion burst (frames); bursts are 1 to this long.
    pub max_burst_frames: u32,
    /// Number of long occlusions (a marker hidden for seconds); `None` = one
    /// per 12 tips, rounded up.
    pub long_gaps: Option<usize>,
    /// Shortest and longest long occlusion (s).
    pub long_gap_min_s: f64,
    /// Longest long occlusion (s).
    pub long_gap_max_s: f64,
    /// Mean number of spurious reflections appearing per second.
    pub spurious_per_s: f64,
    /// Longest life of a spurious reflection (frames); lives are 1 to this long.
    pub spurious_max_frames: u32,
    /// Least distance between two marked tips (mm), so tracking can be tested
    /// with a 25 mm gate without paths swapping at rest.
    pub min_spacing_mm: f64,
    /// `Take Name` in the CSV header; empty = the output file's stem.
    pub take_name: String,
    /// Stress: the band `[low, high]` (Hz) of the tree-like sway model
    /// (see `motion`): limb modes near `low`, twigs near `high`, with the
    /// modes shared by every tip on a limb and on a fork, as on a real
    /// tree. Empty (default) keeps the original three-mode sway.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub sway_hz: Vec<f64>,
    /// Stress: mean number of gusts per minute in the wind phase (each
    /// raises the wind's strength by 30–100 % for 1–5 s); 0 = steady wind.
    #[serde(skip_serializing_if = "is_zero")]
    pub gusts_per_min: f64,
    /// Stress: pairs of neighbouring tips made to swing towards each other
    /// in the wind, so that their markers pass close (see `close_mm`).
    #[serde(skip_serializing_if = "is_zero_usize")]
    pub close_pairs: usize,
    /// Closest approach the swing of a close pair aims at (mm), in the
    /// strongest gust of the session (the swing is sized for it, so that
    /// the two pass close and not through each other); the other modes
    /// move them too, so the truth's actual spacing is what counts.
    #[serde(skip_serializing_if = "is_default_close")]
    pub close_mm: f64,
    /// Trees in the session, 1–5 (docs/forest.md); `tips` markers each.
    /// The forest fields are left out of the truth file when at their
    /// defaults, so one-tree truth files read as before.
    #[serde(skip_serializing_if = "is_one")]
    pub trees: usize,
    /// How far neighbouring crowns overlap, as a fraction of the narrower
    /// crown's width (negative leaves a gap).
    #[serde(skip_serializing_if = "is_zero")]
    pub overlap: f64,
    /// Row or cluster.
    #[serde(skip_serializing_if = "Layout::is_row")]
    pub layout: Layout,
    /// The first crown leans towards its neighbour by this much per metre
    /// above its base (m/m).
    #[serde(skip_serializing_if = "is_zero")]
    pub lean: f64,
    /// Each tree's habit drawn at random (maple or pine) instead of `shape`.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub mixed: bool,
}

/// Default of `SynthOptions::close_mm`.
const CLOSE_MM: f64 = 20.0;

// Stress options at their defaults are left out of the truth file, so the
// shipped replays' truth stays byte-identical.
fn is_zero(v: &f64) -> bool {
    *v == 0.0
}
fn is_zero_usize(v: &usize) -> bool {
    *v == 0
}
fn is_default_close(v: &f64) -> bool {
    *v == CLOSE_MM
}
fn is_one(v: &usize) -> bool {
    *v == 1
}

impl Default for SynthOptions {
    fn default() -> Self {
        SynthOptions {
            seed: 1,
            tips: 24,
            shape: CrownShape::Maple,
            frame_rate: 100.0,
            still_s: 20.0,
            wind_s: 20.0,
            wind_ramp_s: 2.0,
            noise_mm: 0.2,
            still_motion_mm: 0.4,
            sway_scale: 1.0,
            gap_fraction: 0.05,
            max_burst_frames: 50,
            long_gaps: None,
            long_gap_min_s: 1.0,
            long_gap_max_s: 4.0,
            spurious_per_s: 0.5,
            spurious_max_frames: 50,
            min_spacing_mm: 60.0,
            take_name: String::new(),
            sway_hz: Vec::new(),
            gusts_per_min: 0.0,
            close_pairs: 0,
            close_mm: CLOSE_MM,
            trees: 1,
            overlap: 0.0,
            layout: Layout::Row,
            lean: 0.0,
            mixed: false,
        }
    }
}

impl SynthOptions {
    /// The forest sessions of the accuracy sweep (`examples/forest_accuracy`
    /// and the forest tests): `trees` trees of 14–30 tips of mixed shapes,
    /// in a row (even seeds) or a cluster (odd), 5 s still then 15 s of
    /// wind, without the capture's gaps and ghosts (the marker stage is
    /// measured on its own).
    pub fn forest_sweep(seed: u64, trees: usize, overlap: f64) -> SynthOptions {
        SynthOptions {
            seed,
            trees,
            overlap,
            tips: 14 + (seed as usize * 7) % 17,
            mixed: true,
            layout: if seed.is_multiple_of(2) {
                Layout::Row
            } else {
                Layout::Cluster
            },
            still_s: 5.0,
            wind_s: 15.0,
            gap_fraction: 0.0,
            spurious_per_s: 0.0,
            ..SynthOptions::default()
        }
    }

    /// Rejects options that make no session (errors name the option).
    pub fn validate(&self) -> Result<()> {
        check("tips", self.tips as f64, 1.0, 70.0)?;
        check("frame_rate", self.frame_rate, 1.0, 10_000.0)?;
        check("still_s", self.still_s, 0.0, 3600.0)?;
        check("wind_s", self.wind_s, 0.0, 3600.0)?;
        check("wind_ramp_s", self.wind_ramp_s, 0.001, 60.0)?;
        check("noise_mm", self.noise_mm, 0.0, 10.0)?;
        check("still_motion_mm", self.still_motion_mm, 0.0, 10.0)?;
        check("sway_scale", self.sway_scale, 0.0, 10.0)?;
        check("gap_fraction", self.gap_fraction, 0.0, 0.3)?;
        check(
            "max_burst_frames",
            self.max_burst_frames as f64,
            1.0,
            10_000.0,
        )?;
        check("long_gap_min_s", self.long_gap_min_s, 0.0, 600.0)?;
        check(
            "long_gap_max_s",
            self.long_gap_max_s,
            self.long_gap_min_s,
            600.0,
        )?;
        check("spurious_per_s", self.spurious_per_s, 0.0, 1000.0)?;
        check(
            "spurious_max_frames",
            self.spurious_max_frames as f64,
            1.0,
            10_000.0,
        )?;
        check("min_spacing_mm", self.min_spacing_mm, 0.0, 1000.0)?;
        match self.sway_hz[..] {
            [] => {}
            [lo, hi] if lo.is_finite() && hi.is_finite() && 0.05 <= lo && lo < hi && hi <= 20.0 => {
            }
            _ => {
                return Err(Error::config(
                    "sway_hz",
                    "must be [] or [low, high] with 0.05 <= low < high <= 20 (Hz)",
                ))
            }
        }
        check("gusts_per_min", self.gusts_per_min, 0.0, 60.0)?;
        check("close_pairs", self.close_pairs as f64, 0.0, 35.0)?;
        check("close_mm", self.close_mm, 1.0, 500.0)?;
        check("trees", self.trees as f64, 1.0, 5.0)?;
        if self.trees > 1 && self.close_pairs > 0 {
            return Err(Error::config(
                "close_pairs",
                "pairs of close tips are made on one tree only (trees = 1)",
            ));
        }
        check("overlap", self.overlap, -1.0, 0.5)?;
        check("lean", self.lean, -1.0, 1.0)?;
        // The whole session is held in memory (about 1 kB per frame at 35
        // tips), so the length is capped at an hour at 100 Hz.
        let frames = ((self.still_s + self.wind_s) * self.frame_rate).round();
        if !(1.0..=MAX_FRAMES as f64).contains(&frames) {
            return Err(Error::config(
                "still_s",
                format!(
                    "(still_s + wind_s) × frame_rate gives {frames} frames; need 1 to {MAX_FRAMES}"
                ),
            ));
        }
        Ok(())
    }
}

/// A generated session: what a capture would give, and the truth behind it.
#[derive(Debug, Clone, PartialEq)]
pub struct Synthetic {
    /// One frame per capture instant, frame numbers from 0. Each marker's
    /// `id` is `Some(column index)` into `columns`, markers in column order;
    /// positions are exactly what a reader gets back from the CSV.
    pub frames: Vec<MarkerFrame>,
    /// The CSV's columns (same as `truth.columns`).
    pub columns: Vec<ColumnTruth>,
    /// What the session was made from, to score every stage against.
    pub truth: Truth,
}

/// Generates a session. Same options → same session, bit for bit.
pub fn generate(opts: &SynthOptions) -> Result<Synthetic> {
    let truth = truth(opts)?;
    let capture_rng = motion::stream(&Rng::new(opts.seed), CAPTURE);
    let frames = capture::frames(&truth, opts.noise_mm / 1000.0, &capture_rng);
    Ok(Synthetic {
        frames,
        columns: truth.columns.clone(),
        truth,
    })
}

/// The truth of the session [`generate`] makes from `opts`, without its
/// frames: the tree, the motion, the gaps, the ghosts and the columns
/// (cheap enough to try options, as [`stress`] does to bound the sway).
pub fn truth(opts: &SynthOptions) -> Result<Truth> {
    opts.validate()?;
    let root = Rng::new(opts.seed);
    let mut wind_rng = motion::stream(&root, WIND);
    let angle = wind_rng.range(0.0, TAU);
    let wind_direction = DVec3::new(tree::q9(angle.cos()), 0.0, tree::q9(angle.sin()));
    // Gusts first (their own stream): a close pair's swing is sized for
    // the strongest wind, so that they pass close, not through each other.
    let gusts = motion::gusts(
        opts.gusts_per_min,
        (opts.still_s + opts.wind_ramp_s, opts.still_s + opts.wind_s),
        &motion::stream(&root, GUSTS),
    );
    let strongest = 1.0 + gusts.iter().map(|g| g.extra).fold(0.0, f64::max);
    let (tree, tips, forest, crown_centre) = if opts.trees > 1 {
        forest_tips(opts, &root, wind_direction)?
    } else {
        let tree = tree::grow(opts.shape, &mut motion::stream(&root, TREE));
        let nodes = tree.choose_tips(opts.tips, opts.min_spacing_mm / 1000.0)?;
        let crown_centre = DVec3::new(0.0, 0.5 * (tree.crown_base + tree.height), 0.0);
        let motion_rng = motion::stream(&root, MOTION);
        let mut tips = sway(opts, &tree, &nodes, wind_direction, &motion_rng);
        motion::close_pairs(
            &mut tips,
            opts.close_pairs,
            opts.close_mm / 1000.0,
            strongest,
            &tree,
            &motion::stream(&motion_rng, 3),
        );
        (tree, tips, None, crown_centre)
    };
    let fan = crown_centre - wind_direction * 2.0;
    let fan_position = DVec3::new(tree::q9(fan.x), tree::q9(fan.y), tree::q9(fan.z));

    let frames = ((opts.still_s + opts.wind_s) * opts.frame_rate).round() as usize;
    let capture_rng = motion::stream(&root, CAPTURE);
    let gaps = capture::gaps(opts, frames as i64, tips.len(), &capture_rng);
    let rests: Vec<DVec3> = tips.iter().map(|t| t.rest).collect();
    let spurious = capture::spurious(opts, frames as i64, &rests, &capture_rng);
    let mut truth = Truth {
        version: truth::TRUTH_VERSION,
        options: opts.clone(),
        frame_rate: opts.frame_rate,
        frames,
        still: (0.0, opts.still_s),
        wind: (opts.still_s, opts.still_s + opts.wind_s),
        wind_ramp_s: opts.wind_ramp_s,
        wind_direction,
        fan_position,
        tree,
        tips,
        gusts,
        gaps,
        columns: Vec::new(),
        spurious,
        forest,
    };
    capture::columns(&mut truth, FIRST_UNLABELED);
    Ok(truth)
}

/// The motion of the marked `nodes` of `tree`: the tree-like sway model
/// when `sway_hz` is set, else the original three-mode sway.
fn sway(
    opts: &SynthOptions,
    tree: &TreeTruth,
    nodes: &[usize],
    wind: DVec3,
    rng: &Rng,
) -> Vec<TipTruth> {
    match opts.sway_hz[..] {
        [lo, hi] => motion::tree_tips(
            tree,
            nodes,
            wind,
            opts.still_motion_mm / 1000.0,
            opts.sway_scale,
            (lo, hi),
            rng,
        ),
        _ => motion::tips(
            tree,
            nodes,
            wind,
            opts.still_motion_mm / 1000.0,
            opts.sway_scale,
            rng,
        ),
    }
}

/// The trees of a forest session, their tips' motion (each tree swaying on
/// its own trunk and limbs in the common wind, `motion::trunk_mode`) and the centre of the whole canopy.
fn forest_tips(
    opts: &SynthOptions,
    root: &Rng,
    wind: DVec3,
) -> Result<(TreeTruth, Vec<TipTruth>, Option<ForestTruth>, DVec3)> {
    let (placed, chosen) = forest::place(opts, root, TREE, FOREST)?;
    let motion_base = motion::stream(root, MOTION);
    let mut tips = Vec::with_capacity(chosen.len());
    for (k, p) in placed.iter().enumerate() {
        let nodes: Vec<usize> = chosen.iter().filter(|c| c.0 == k).map(|c| c.1).collect();
        let tree_motion = motion::stream(&motion_base, k as u64 + 1);
        let mut own = sway(opts, &p.tree, &nodes, wind, &tree_motion);
        motion::trunk_mode(
            &mut own,
            &p.tree,
            p.base.y,
            wind,
            opts.sway_scale,
            &tree_motion,
        );
        tips.extend(own);
    }
    let n = placed.len() as f64;
    let centre = placed.iter().map(|p| p.base).sum::<DVec3>() / n;
    let mid_height = placed
        .iter()
        .map(|p| 0.5 * (p.tree.crown_base + p.tree.height))
        .sum::<f64>()
        / n;
    let forest = ForestTruth {
        tip_tree: chosen.iter().map(|c| c.0).collect(),
        trees: placed,
    };
    let first = forest.trees[0].tree.clone();
    Ok((
        first,
        tips,
        Some(forest),
        DVec3::new(centre.x, mid_height, centre.z),
    ))
}

/// The truth file that belongs beside `csv`: `replays/x.csv` →
/// `replays/x.truth.json`.
pub fn truth_path(csv: &Path) -> PathBuf {
    csv.with_extension("truth.json")
}

/// What `write_session` wrote, for the CLI to print.
#[derive(Debug, Clone, Serialize)]
pub struct SessionSummary {
    /// The Motive CSV written.
    pub csv: PathBuf,
    /// The truth file beside it.
    pub truth: PathBuf,
    /// Size of the CSV.
    pub csv_bytes: u64,
    /// Frames in the session.
    pub frames: usize,
    /// Markers placed on the tree.
    pub tips: usize,
    /// `Unlabeled N` columns (one per marker appearance and reflection).
    pub columns: usize,
    /// Occlusions, short and long.
    pub gaps: usize,
    /// Fraction of tip samples missing.
    pub gap_fraction: f64,
    /// Spurious reflections added.
    pub spurious: usize,
    /// Height of the true tree (m).
    pub tree_height_m: f64,
    /// Nodes of the true tree.
    pub tree_nodes: usize,
    /// Unit vector the simulated wind blows towards.
    pub wind_direction: DVec3,
}

impl fmt::Display for SessionSummary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "wrote {} ({} bytes)", self.csv.display(), self.csv_bytes)?;
        writeln!(f, "wrote {}", self.truth.display())?;
        writeln!(
            f,
            "tree: {:.2} m tall, {} nodes; wind towards ({:.3}, {:.3}, {:.3})",
            self.tree_height_m,
            self.tree_nodes,
            self.wind_direction.x,
            self.wind_direction.y,
            self.wind_direction.z
        )?;
        writeln!(
            f,
            "{} frames, {} tips, {} columns, {} gaps ({:.1} % of tip samples), {} spurious reflections",
            self.frames,
            self.tips,
            self.columns,
            self.gaps,
            self.gap_fraction * 100.0,
            self.spurious
        )
    }
}
