//! The ground truth of a synthetic session (`NAME.truth.json`): the tree, the
//! tips' rest positions and motion, the wind, every gap and every column.
//! It holds the motion's parameters rather than sampled positions, so
//! [`Truth::position`] gives the noiseless position at any time, which is what
//! gap fills, rest estimates and wind estimates are scored against.

use std::f64::consts::TAU;

use glam::DVec3;
use serde::{Deserialize, Serialize};

use super::tree::TreeTruth;
use super::SynthOptions;
use crate::model::tips::CapturedTip;

/// Version of the truth file's layout; bumped when fields change meaning.
pub const TRUTH_VERSION: u32 = 1;

/// One sinusoidal motion component of a tip: `direction · amplitude ·
/// sin(2π · frequency · t + phase)`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Sinusoid {
    /// Unit vector the component moves along.
    pub direction: DVec3,
    /// Peak displacement (m).
    pub amplitude: f64,
    /// Hz.
    pub frequency: f64,
    /// Radians at the component's time origin.
    pub phase: f64,
}

impl Sinusoid {
    /// Displacement at `t` seconds after the component's time origin.
    pub fn at(&self, t: f64) -> DVec3 {
        self.direction * (self.amplitude * (TAU * self.frequency * t + self.phase).sin())
    }
}

/// One marked branch tip.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TipTruth {
    /// The tip's node in `Truth::tree.nodes`.
    pub node: usize,
    /// Where the tip is when nothing moves it (m): what rest estimation must
    /// recover.
    pub rest: DVec3,
    /// Path length from the tip down to the trunk (m). The tip swings on an
    /// arc of this radius, so sideways sway also lowers it slightly.
    pub lever: f64,
    /// The tiny periodic motion seen even without wind (paper §7, Fig. 9:
    /// within 1 mm); time origin = the start of the take.
    pub wobble: Vec<Sinusoid>,
    /// Mean deflection under full wind (m), pointing downwind: a real branch
    /// bends with the wind, and the PCA wind estimator takes its sign from it.
    pub bend: DVec3,
    /// Sway around the bent position under full wind; time origin = the
    /// start of the wind phase.
    pub sway: Vec<Sinusoid>,
}

/// One gust: the wind's strength rises by `extra` (a fraction of the
/// steady wind) over `rise_s`, holds for `hold_s` and falls back over
/// `fall_s`, each change a smoothstep; bend and sway scale with it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GustTruth {
    /// Start of the rise (s on the take's clock).
    pub start_s: f64,
    /// Seconds of the rise, the hold and the fall.
    pub rise_s: f64,
    /// See `rise_s`.
    pub hold_s: f64,
    /// See `rise_s`.
    pub fall_s: f64,
    /// Extra strength at the hold, as a fraction of the steady wind.
    pub extra: f64,
}

impl GustTruth {
    /// The gust's extra strength at `time_s`.
    pub fn at(&self, time_s: f64) -> f64 {
        let smooth = |x: f64| {
            let x = x.clamp(0.0, 1.0);
            x * x * (3.0 - 2.0 * x)
        };
        let t = time_s - self.start_s;
        let up = smooth(t / self.rise_s);
        let down = smooth((t - self.rise_s - self.hold_s) / self.fall_s);
        self.extra * (up - down).max(0.0)
    }
}

/// One occlusion: the tip is missing from every frame in
/// `first_frame..=last_frame`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct GapTruth {
    /// The hidden tip (index into `Truth::tips`).
    pub tip: usize,
    /// First frame without it.
    pub first_frame: i64,
    /// Last frame without it.
    pub last_frame: i64,
}

/// One `Unlabeled N` column of the CSV (= `Marker.id` in the frames).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct ColumnTruth {
    /// The column's name in the CSV, `Unlabeled N`.
    pub name: String,
    /// The tip whose marker this column shows; `None` for a spurious
    /// reflection.
    pub tip: Option<usize>,
    /// First and last frame with data in this column (it is full in between).
    pub first_frame: i64,
    /// Last frame with data in this column.
    pub last_frame: i64,
}

/// One spurious reflection (a stray marker that is not on a tip).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SpuriousTruth {
    /// Its column in `Truth::columns`.
    pub column: usize,
    /// First frame it is seen in.
    pub first_frame: i64,
    /// Last frame it is seen in.
    pub last_frame: i64,
    /// Where it is (m); it does not move apart from measurement noise.
    pub position: DVec3,
}

/// Everything the simulator knows about a session.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Truth {
    /// Layout version of this file ([`TRUTH_VERSION`]).
    pub version: u32,
    /// The options the session was made with: rerunning `synth` with them
    /// gives the same bytes.
    pub options: SynthOptions,
    /// Frames per second of the CSV.
    pub frame_rate: f64,
    /// Number of frames; frame numbers are 0..frames, time = frame / rate.
    pub frames: usize,
    /// The still phase, [start, end) in seconds.
    pub still: (f64, f64),
    /// The wind phase, [start, end) in seconds.
    pub wind: (f64, f64),
    /// Seconds the fan takes to reach full strength after `wind.0`; the sway
    /// is scaled by a smoothstep over this time, so motion starts smoothly.
    pub wind_ramp_s: f64,
    /// Unit horizontal vector the wind blows towards.
    pub wind_direction: DVec3,
    /// Where a fan producing this wind would stand (2 m upwind of the crown's
    /// centre, at crown-centre height), for the fan-position wind source.
    pub fan_position: DVec3,
    /// The true tree the tips belong to.
    pub tree: TreeTruth,
    /// The marked tips, in tip-index order.
    pub tips: Vec<TipTruth>,
    /// Gusts of the wind phase (stress option `gusts_per_min`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub gusts: Vec<GustTruth>,
    /// Every occlusion, sorted by tip then frame.
    pub gaps: Vec<GapTruth>,
    /// Every CSV column, in CSV order: the column → tip map.
    pub columns: Vec<ColumnTruth>,
    /// Every stray reflection, which tracking must drop as noise.
    pub spurious: Vec<SpuriousTruth>,
    /// With several trees (docs/forest.md): every tree and the tree of every
    /// tip. Absent for one tree, so such truth files read as before.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub forest: Option<super::forest::ForestTruth>,
}

impl Truth {
    /// 0 before the wind phase, rising smoothly to 1 over `wind_ramp_s`, times
    /// 1 + the gusts blowing at `time_s`.
    pub fn wind_strength(&self, time_s: f64) -> f64 {
        let dt = time_s - self.wind.0;
        let ramp = if dt <= 0.0 {
            0.0
        } else if dt >= self.wind_ramp_s {
            1.0
        } else {
            let x = dt / self.wind_ramp_s;
            x * x * (3.0 - 2.0 * x)
        };
        if ramp == 0.0 || self.gusts.is_empty() {
            return ramp;
        }
        ramp * (1.0 + self.gusts.iter().map(|g| g.at(time_s)).sum::<f64>())
    }

    /// The close pairs the stress option `close_pairs` swings towards each
    /// other (tip indices, `i < j`); empty without the option. Taken from
    /// the rest positions as the simulator took them.
    pub fn close_pairs(&self) -> Vec<(usize, usize)> {
        pair_tips(
            &self.tips,
            self.options.close_pairs,
            self.options.close_mm / 1000.0,
        )
    }

    /// The noiseless true position of `tip` at `time_s` (m, Y up).
    ///
    /// # Panics
    /// If `tip >= self.tips.len()` (a caller's bug, like slice indexing).
    pub fn position(&self, tip: usize, time_s: f64) -> DVec3 {
        let t = &self.tips[tip];
        let mut p = t.rest;
        for s in &t.wobble {
            p += s.at(time_s);
        }
        let w = self.wind_strength(time_s);
        if w > 0.0 {
            let since = time_s - self.wind.0;
            let mut d = t.bend;
            for s in &t.sway {
                d += s.at(since);
            }
            d *= w;
            p += d;
            // Swinging on an arc of radius `lever` lowers the tip by about
            // h²/(2·lever) for a sideways displacement h.
            p.y -= (d.x * d.x + d.z * d.z) / (2.0 * t.lever.max(0.1));
        }
        p
    }

    /// The tips at their true rest positions, marker = tip index: what a
    /// perfect marker stage would hand to the reconstruction.
    pub fn rest_tips(&self) -> Vec<CapturedTip> {
        self.tips
            .iter()
            .enumerate()
            .map(|(i, x)| CapturedTip {
                marker: i,
                position: x.rest,
            })
            .collect()
    }

    /// Every tip's true displacement from rest over the wind phase, sampled
    /// at `rate_hz` (tip, then sample): the series the sway links of
    /// `reconstruct::forest::sway` are computed from.
    pub fn wind_sway(&self, rate_hz: f64) -> Vec<Vec<Option<DVec3>>> {
        let samples = ((self.wind.1 - self.wind.0) * rate_hz) as usize;
        (0..self.tips.len())
            .map(|i| {
                (0..samples)
                    .map(|f| {
                        let t = self.wind.0 + f as f64 / rate_hz;
                        Some(self.position(i, t) - self.tips[i].rest)
                    })
                    .collect()
            })
            .collect()
    }

    /// Frame number → seconds.
    pub fn time_of(&self, frame: i64) -> f64 {
        frame as f64 / self.frame_rate
    }

    /// Whether `tip` is occluded in `frame`.
    pub fn is_gap(&self, tip: usize, frame: i64) -> bool {
        self.gaps
            .iter()
            .any(|g| g.tip == tip && g.first_frame <= frame && frame <= g.last_frame)
    }
}

/// The `pairs` close pairs the simulator swings into each other
/// (`motion::close_pairs`), `(i, j)` with `i < j`:
/// nearest neighbours by rest position, closest first, each tip in at
/// most one pair, none already within `close` (m) at rest. Also what
/// [`Truth::close_pairs`] names, so that a tracking failure can be told
/// to lie between the partners of a pair. Here, beside the tips' truth,
/// so that the truth does not import the motion that reads it.
pub(crate) fn pair_tips(tips: &[TipTruth], pairs: usize, close: f64) -> Vec<(usize, usize)> {
    if pairs == 0 {
        return Vec::new();
    }
    let mut candidates = Vec::new();
    for i in 0..tips.len() {
        for j in i + 1..tips.len() {
            candidates.push((tips[i].rest.distance(tips[j].rest), i, j));
        }
    }
    candidates.sort_by(|a, b| a.0.total_cmp(&b.0).then((a.1, a.2).cmp(&(b.1, b.2))));
    let mut used = vec![false; tips.len()];
    let mut out = Vec::new();
    for (d, i, j) in candidates {
        if out.len() == pairs {
            break;
        }
        if used[i] || used[j] || d <= close {
            continue;
        }
        used[i] = true;
        used[j] = true;
        out.push((i, j));
    }
    out
}
