//! Where the captured tips' motion comes from: the tracker's traces in
//! memory (`Tips`, what `replay` has) or the trajectories of a tips.json
//! (`TipTraces`, what `reconstruct` reads). The animation only needs each
//! tip's samples at the key frames.

use glam::DVec3;

use super::keys::choose_keys;
use super::AnimateSettings;
use crate::error::Result;
use crate::model::motion::TipSource;
use crate::model::tips::Tips;
use crate::model::tips_traces::TipTraces;
use crate::model::trace::{SampleKind, Trace};

/// A tip's sample at one key: where it was and whether that was measured
/// or filled; `None` where it is missing.
pub type Sampled = Option<(DVec3, TipSource)>;

/// The captured tips' paths over a session.
pub trait TipPaths {
    /// Time of every frame (s), not decreasing; frames are its indices.
    fn times(&self) -> &[f64];
    /// The samples of marker `marker` at `frames` (increasing); `None` when
    /// there is no such marker.
    fn sample(&self, marker: usize, frames: &[i64]) -> Option<Vec<Sampled>>;
}

impl TipPaths for Tips {
    fn times(&self) -> &[f64] {
        &self.timeline.times
    }

    fn sample(&self, marker: usize, frames: &[i64]) -> Option<Vec<Sampled>> {
        let tip = self.tips.iter().find(|t| t.marker == marker)?;
        Some(sample_trace(&tip.trace, frames))
    }
}

impl TipPaths for TipTraces {
    fn times(&self) -> &[f64] {
        &self.times_s
    }

    fn sample(&self, marker: usize, frames: &[i64]) -> Option<Vec<Sampled>> {
        let tip = self.tips.iter().find(|t| t.marker == marker)?;
        Some(
            frames
                .iter()
                .map(|&f| {
                    let i = usize::try_from(f).ok()?;
                    let p = (*tip.positions.get(i)?)?;
                    let filled = tip.filled.get(i).copied().unwrap_or(false);
                    Some((
                        p,
                        if filled {
                            TipSource::Filled
                        } else {
                            TipSource::Measured
                        },
                    ))
                })
                .collect(),
        )
    }
}

/// The captured tips' samples at the animation's key frames only, taken
/// from the traces once: `replay` builds it and drops the traces before the
/// animation and tree.glb (a key-frame sample per tip instead of the whole
/// take, so an hour-long replay holds the traces or the animation, never
/// both).
pub struct KeyPaths {
    /// Time of every frame, as the traces had it (the keys are chosen
    /// from it again by [`super::motion::animate`]).
    times: Vec<f64>,
    /// The key frames sampled, increasing.
    frames: Vec<i64>,
    /// (marker, its samples at `frames`), in tips order.
    tips: Vec<(usize, Vec<Sampled>)>,
}

impl KeyPaths {
    /// `tips` sampled at the keys `settings` chooses on their timeline.
    pub fn of(tips: &Tips, settings: &AnimateSettings) -> Result<KeyPaths> {
        let times = tips.timeline.times.clone();
        let frames = choose_keys(&times, settings)?.frames;
        let tips = tips
            .tips
            .iter()
            .map(|t| (t.marker, sample_trace(&t.trace, &frames)))
            .collect();
        Ok(KeyPaths {
            times,
            frames,
            tips,
        })
    }
}

impl TipPaths for KeyPaths {
    fn times(&self) -> &[f64] {
        &self.times
    }

    /// The samples at `frames`; a frame that is not a key it was built for
    /// has no sample (the keys of the same times and settings always are).
    fn sample(&self, marker: usize, frames: &[i64]) -> Option<Vec<Sampled>> {
        let (_, samples) = self.tips.iter().find(|t| t.0 == marker)?;
        if frames == self.frames.as_slice() {
            return Some(samples.clone());
        }
        Some(
            frames
                .iter()
                .map(|f| {
                    let k = self.frames.binary_search(f).ok()?;
                    samples.get(k).copied().flatten()
                })
                .collect(),
        )
    }
}

/// One trace at the (increasing) frames, read in one sequential pass.
fn sample_trace(trace: &Trace, frames: &[i64]) -> Vec<Sampled> {
    let mut out = vec![None; frames.len()];
    let mut k = frames.partition_point(|&f| f < trace.first_frame());
    let last = frames.last().copied().unwrap_or(i64::MIN);
    for s in trace.samples() {
        if s.frame > last || k >= frames.len() {
            break;
        }
        while k < frames.len() && frames[k] < s.frame {
            k += 1;
        }
        while k < frames.len() && frames[k] == s.frame {
            out[k] = match s.kind {
                SampleKind::Measured => Some((s.position, TipSource::Measured)),
                SampleKind::Filled => Some((s.position, TipSource::Filled)),
                SampleKind::Missing => None,
            };
            k += 1;
        }
    }
    out
}
