//! Live tip positions every frame: each tip of the current tree follows the
//! nearest marker within a gate of its last position. The full tracker runs
//! on the analysis window; this is the cheap per-frame step that feeds the
//! viewers, with memory that does not grow.

use glam::DVec3;

/// Follows a fixed set of tips frame to frame.
#[derive(Debug, Clone, Default)]
pub struct TipFollower {
    /// (marker index, rest position, last seen position).
    tips: Vec<(usize, DVec3, DVec3)>,
    gate_m: f64,
    /// Per marker of the last frame: claimed by a tip (for the live view's
    /// noise markers). Reused, so it costs no allocation per frame.
    claimed: Vec<bool>,
}

impl TipFollower {
    /// A follower with no tips yet; `gate_m` is `daemon.follow_gate_mm` in
    /// metres.
    pub fn new(gate_m: f64) -> Self {
        TipFollower {
            tips: Vec::new(),
            gate_m,
            claimed: Vec::new(),
        }
    }

    /// A new tree: follow its tips from their rest positions.
    pub fn set_tips(&mut self, tips: &[(usize, DVec3)]) {
        self.tips = tips.iter().map(|&(m, p)| (m, p, p)).collect();
    }

    /// True before the first tree: there is nothing to follow.
    pub fn is_empty(&self) -> bool {
        self.tips.is_empty()
    }

    /// Assigns markers to tips, closest pairs first (one marker per tip);
    /// returns `(marker index, position)` of the tips seen in this frame.
    pub fn update(&mut self, markers: &[DVec3]) -> Vec<(usize, DVec3)> {
        let mut pairs: Vec<(f64, usize, usize)> = Vec::new();
        for (ti, (_, _, last)) in self.tips.iter().enumerate() {
            for (mi, m) in markers.iter().enumerate() {
                let d = last.distance(*m);
                if d <= self.gate_m {
                    pairs.push((d, ti, mi));
                }
            }
        }
        pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut tip_taken = vec![false; self.tips.len()];
        let mut marker_taken = std::mem::take(&mut self.claimed);
        marker_taken.clear();
        marker_taken.resize(markers.len(), false);
        let mut seen = Vec::new();
        for (_, ti, mi) in pairs {
            if tip_taken[ti] || marker_taken[mi] {
                continue;
            }
            tip_taken[ti] = true;
            marker_taken[mi] = true;
            self.tips[ti].2 = markers[mi];
            seen.push((self.tips[ti].0, markers[mi]));
        }
        seen.sort_by_key(|s| s.0);
        self.claimed = marker_taken;
        seen
    }

    /// Per marker of the last frame given to [`Self::update`]: whether a
    /// tip took it.
    pub fn claimed(&self) -> &[bool] {
        &self.claimed
    }

    /// Displacements from rest of the tips seen (for the sway PCA).
    pub fn displacements<'a>(
        &'a self,
        seen: &'a [(usize, DVec3)],
    ) -> impl Iterator<Item = DVec3> + 'a {
        seen.iter()
            .filter_map(|(m, p)| self.tips.iter().find(|t| t.0 == *m).map(|t| *p - t.1))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn follows_nearest_within_the_gate() {
        let mut f = TipFollower::new(0.05);
        f.set_tips(&[(0, DVec3::ZERO), (1, DVec3::X)]);
        let seen = f.update(&[
            DVec3::new(1.01, 0.0, 0.0),
            DVec3::new(0.02, 0.0, 0.0),
            DVec3::Y,
        ]);
        assert_eq!(
            seen,
            vec![
                (0, DVec3::new(0.02, 0.0, 0.0)),
                (1, DVec3::new(1.01, 0.0, 0.0))
            ]
        );
        // Walks with the marker, step by step.
        let seen = f.update(&[DVec3::new(0.06, 0.0, 0.0)]);
        assert_eq!(seen, vec![(0, DVec3::new(0.06, 0.0, 0.0))]);
        let d: Vec<DVec3> = f.displacements(&seen).collect();
        assert_eq!(d, vec![DVec3::new(0.06, 0.0, 0.0)]);
        assert!(f.update(&[DVec3::splat(5.0)]).is_empty());
    }
}
