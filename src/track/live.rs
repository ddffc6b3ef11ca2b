//! Live tips: the tracker run frame by frame, its markers labelled with the
//! current tree's tips. The daemon shows these; they are the very samples a
//! replay of the same frames puts in its tips (same tracker, same
//! decisions), not a second, simpler follower.
//!
//! A tree names its captured tips by marker index and rest position. Each
//! marker the tracker confirms is matched to the nearest unclaimed tip whose
//! rest position lies within `match_radius` of where the marker was in its
//! first second (a marker seen from the still phase on matches its tip to
//! a fraction of a millimetre); markers that match no tip (first seen
//! in the wind, or not on the tree) are not shown.

use glam::DVec3;

use super::tracker::Tracker;
use super::TrackingSettings;
use crate::model::frame::MarkerFrame;

/// `LiveTips::label` of an identity not yet matched with a tip.
const UNTRIED: u32 = u32::MAX;
/// `LiveTips::label` of an identity tried and matched with no tip (not
/// retried every frame).
const UNMATCHED: u32 = u32::MAX - 1;

/// The tree's tips measured in one frame.
#[derive(Debug, Clone, Default)]
pub struct Seen {
    /// `(marker index, position)`, by marker index.
    pub tips: Vec<(usize, DVec3)>,
    /// Which of the frame's markers they are (indices into its `markers`,
    /// not in the order of `tips`), for the live page, which colours tips
    /// and noise apart.
    pub frame_markers: Vec<usize>,
}

/// The live tracker and its labels.
pub struct LiveTips {
    tracker: Tracker,
    match_radius: f64,
    /// The tree's tips: (marker index, rest position).
    tips: Vec<(usize, DVec3)>,
    /// Per tracker identity (identities are numbered densely from 0):
    /// its index into `tips`, [`UNTRIED`] or [`UNMATCHED`]. A flat array,
    /// 4 bytes an identity: it was a hash map, whose thousand lookups a
    /// frame at 1 000 markers each missed the cache once the daemon's
    /// other work had evicted it.
    label: Vec<u32>,
    /// Which of `tips` are claimed.
    claimed: Vec<bool>,
    /// Per tip, its marker's position and frame index in the frame being
    /// labelled; reused across frames.
    slots: Vec<Option<(DVec3, usize)>>,
}

impl LiveTips {
    /// A live tracker with the marker stage's settings; `frame_rate` when
    /// known.
    pub fn new(settings: &TrackingSettings, frame_rate: Option<f64>, match_radius_m: f64) -> Self {
        LiveTips {
            tracker: Tracker::live(settings, frame_rate),
            match_radius: match_radius_m,
            tips: Vec::new(),
            label: Vec::new(),
            claimed: Vec::new(),
            slots: Vec::new(),
        }
    }

    /// A new tree: label the markers with its tips.
    pub fn set_tips(&mut self, tips: &[(usize, DVec3)]) {
        self.tips = tips.to_vec();
        // By marker, so that `displacements` finds a tip by binary search:
        // a search per tip was 1 000 × 1 000 steps a frame at 1 000 tips.
        self.tips.sort_by_key(|t| t.0);
        self.label.clear();
        self.claimed = vec![false; tips.len()];
    }

    /// What the tracker counted so far (frames, markers, traces started):
    /// `examples/frame_cost` compares the work of two runs with it.
    pub fn stats(&self) -> &super::tracker::TrackStats {
        self.tracker.stats()
    }

    /// Prefetches the tracker's and the labels' state before a frame is
    /// due (`track::warm`): off the latency path, the frame then finds it
    /// in the caches. Reads and changes nothing.
    pub fn warm(&self) {
        use super::warm::prefetch;
        self.tracker.warm();
        prefetch(&self.tips);
        prefetch(&self.slots);
        prefetch(&self.claimed);
        prefetch(&self.label);
    }

    /// Whether there is a tree to label with.
    pub fn is_empty(&self) -> bool {
        self.tips.is_empty()
    }

    /// Tracks one frame; returns the tree's tips measured in it.
    pub fn update(&mut self, frame: &MarkerFrame) -> Seen {
        self.tracker.push(frame);
        // Each tip is claimed by one identity: the measured tips are put in
        // their tip's slot and read back in tip (marker) order, instead of
        // sorting a thousand of them every frame. The tracker's identities
        // are read in place (they were copied into a fresh 40 KB vector
        // every frame at 1 000 markers); only the labels change meanwhile.
        let mut slots = std::mem::take(&mut self.slots);
        slots.clear();
        slots.resize(self.tips.len(), None);
        let mut labels = Labels {
            tips: &self.tips,
            match_radius: self.match_radius,
            label: &mut self.label,
            claimed: &mut self.claimed,
        };
        let mut measured = 0;
        for (identity, p, index) in self.tracker.current_markers() {
            let k = match labels.label.get(identity).copied() {
                Some(UNMATCHED) => None,
                Some(k) if k != UNTRIED => Some(k as usize),
                _ => labels.match_identity(&self.tracker, identity),
            };
            if let Some(slot) = k.and_then(|k| slots.get_mut(k)) {
                *slot = Some((p, index));
                measured += 1;
            }
        }
        let mut seen = Seen {
            tips: Vec::with_capacity(measured),
            frame_markers: Vec::with_capacity(measured),
        };
        for (tip, slot) in self.tips.iter().zip(&slots) {
            if let Some((p, index)) = *slot {
                seen.tips.push((tip.0, p));
                seen.frame_markers.push(index);
            }
        }
        self.slots = slots;
        seen
    }

    /// Displacements from rest of the tips seen (for the sway PCA), in
    /// the order of `seen`. Both are by marker (`update` returns its tips
    /// so), so the tips are found by walking the two together, not by a
    /// search each; a tip out of order is still found, by a search.
    pub fn displacements<'a>(
        &'a self,
        seen: &'a [(usize, DVec3)],
    ) -> impl Iterator<Item = DVec3> + 'a {
        let mut at = 0;
        seen.iter().filter_map(move |(m, p)| {
            while self.tips.get(at).is_some_and(|t| t.0 < *m) {
                at += 1;
            }
            let k = match self.tips.get(at) {
                Some(t) if t.0 == *m => at,
                _ => self.tips.binary_search_by_key(m, |t| t.0).ok()?,
            };
            Some(*p - self.tips[k].1)
        })
    }
}

/// The labelling state `update` changes while it reads the tracker's
/// identities: the fields of [`LiveTips`] apart from the tracker, borrowed
/// on their own.
struct Labels<'a> {
    tips: &'a [(usize, DVec3)],
    match_radius: f64,
    label: &'a mut Vec<u32>,
    claimed: &'a mut Vec<bool>,
}

impl Labels<'_> {
    /// The tip identity `identity` (not tried before) is matched with,
    /// noted in `label`.
    fn match_identity(&mut self, tracker: &Tracker, identity: usize) -> Option<usize> {
        let (first, _) = tracker.first_position(identity)?;
        let best = self
            .tips
            .iter()
            .enumerate()
            .filter(|(k, _)| !self.claimed[*k])
            .map(|(k, t)| (t.1.distance(first), k))
            .filter(|(d, _)| *d <= self.match_radius)
            .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        match best {
            Some((_, k)) => {
                self.claimed[k] = true;
                self.set(identity, k as u32);
                Some(k)
            }
            None => {
                self.set(identity, UNMATCHED);
                None
            }
        }
    }
}

impl Labels<'_> {
    /// Notes identity `identity`'s label, growing the array to reach it.
    fn set(&mut self, identity: usize, value: u32) {
        if self.label.len() <= identity {
            self.label.resize(identity + 1, UNTRIED);
        }
        self.label[identity] = value;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::frame::Marker;
    use crate::rng::Rng;

    /// Prefetching the state before a frame (`warm`, what the daemon does
    /// with `daemon.warm_us`) changes nothing: the same tips, positions and
    /// frame markers as without, frame by frame, through births, occlusions
    /// and a new tree.
    #[test]
    fn warming_the_state_before_each_frame_changes_no_output() {
        let mut rng = Rng::new(3);
        let rest: Vec<DVec3> = (0..300)
            .map(|i| DVec3::new(i as f64 * 0.03, 1.0 + rng.f64(), rng.f64()))
            .collect();
        let tips: Vec<(usize, DVec3)> = rest.iter().copied().enumerate().collect();
        let settings = TrackingSettings::default();
        let (mut plain, mut warmed) = (
            LiveTips::new(&settings, Some(100.0), 0.05),
            LiveTips::new(&settings, Some(100.0), 0.05),
        );
        plain.set_tips(&tips);
        warmed.set_tips(&tips);
        let mut shown = 0;
        for f in 0..400 {
            let t = f as f64 / 100.0;
            let markers = rest
                .iter()
                .enumerate()
                .filter(|_| !rng.chance(0.05))
                .map(|(i, p)| Marker::new(*p + DVec3::X * 0.01 * (t + i as f64).sin()))
                .collect();
            let frame = MarkerFrame::new(f, t, markers);
            if f == 250 {
                plain.set_tips(&tips[..200]);
                warmed.set_tips(&tips[..200]);
            }
            warmed.warm();
            let (a, b) = (plain.update(&frame), warmed.update(&frame));
            assert_eq!(a.tips, b.tips, "frame {f}");
            assert_eq!(a.frame_markers, b.frame_markers, "frame {f}");
            shown += a.tips.len();
        }
        assert!(shown > 100 * 250, "the tips were followed: {shown}");
    }
}
