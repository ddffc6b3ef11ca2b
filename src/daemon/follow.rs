//! Live tip positions every frame: each tip of the current tree follows the
//! nearest marker within a gate of its last position. The full tracker runs
//! on the analysis window; this is the cheap per-frame step that feeds the
//! viewers, with memory that does not grow.

use std::collections::HashMap;

use glam::DVec3;

/// Follows a fixed set of tips frame to frame.
#[derive(Debug, Clone, Default)]
pub struct TipFollower {
    /// (marker index, rest position, last seen position).
    tips: Vec<(usize, DVec3, DVec3)>,
    gate_m: f64,
    /// Tip of each marker index, for the displacements.
    by_marker: HashMap<usize, usize>,
    /// The frame's markers bucketed by cell of side `gate_m`: (cell, marker)
    /// sorted by cell, so a tip looks at the markers of the 27 cells around
    /// it instead of every marker (1 000 tips × 1 000 markers would be a
    /// million distances per frame).
    cells: Vec<((i64, i64, i64), usize)>,
    pairs: Vec<(f64, usize, usize)>,
    /// Per marker of the last frame: claimed by a tip (for the live view's
    /// noise markers). Reused, so it costs no allocation per frame.
    claimed: Vec<bool>,
}

impl TipFollower {
    /// A follower with no tips yet; `gate_m` is `daemon.follow_gate_mm` in
    /// metres.
    pub fn new(gate_m: f64) -> Self {
        TipFollower {
            gate_m,
            ..TipFollower::default()
        }
    }

    /// A new tree: follow its tips from their rest positions.
    pub fn set_tips(&mut self, tips: &[(usize, DVec3)]) {
        self.tips = tips.iter().map(|&(m, p)| (m, p, p)).collect();
        self.by_marker = tips.iter().enumerate().map(|(i, t)| (t.0, i)).collect();
    }

    /// True before the first tree: there is nothing to follow.
    pub fn is_empty(&self) -> bool {
        self.tips.is_empty()
    }

    fn cell(&self, p: DVec3) -> (i64, i64, i64) {
        let c = (p / self.gate_m).floor();
        (c.x as i64, c.y as i64, c.z as i64)
    }

    /// Assigns markers to tips, closest pairs first (one marker per tip);
    /// returns `(marker index, position)` of the tips seen in this frame.
    pub fn update(&mut self, markers: &[DVec3]) -> Vec<(usize, DVec3)> {
        let mut cells = std::mem::take(&mut self.cells);
        cells.clear();
        let usable = self.gate_m > 0.0 && self.gate_m.is_finite();
        cells.extend(
            markers
                .iter()
                .enumerate()
                .filter(|(_, m)| usable && m.is_finite())
                .map(|(i, m)| (self.cell(*m), i)),
        );
        cells.sort_unstable();
        let mut pairs = std::mem::take(&mut self.pairs);
        pairs.clear();
        for (ti, (_, _, last)) in self.tips.iter().enumerate() {
            if !last.is_finite() || cells.is_empty() {
                continue;
            }
            let (cx, cy, cz) = self.cell(*last);
            for dx in -1..=1 {
                for dy in -1..=1 {
                    let key = (cx + dx, cy + dy, cz - 1);
                    let start = cells.partition_point(|c| c.0 < key);
                    let end_key = (cx + dx, cy + dy, cz + 1);
                    for &(_, mi) in cells[start..].iter().take_while(|c| c.0 <= end_key) {
                        let d = last.distance(markers[mi]);
                        if d <= self.gate_m {
                            pairs.push((d, ti, mi));
                        }
                    }
                }
            }
        }
        // Closest first; ties in tip then marker order (a total order, so
        // the result does not depend on how the pairs were found).
        pairs.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
        let mut tip_taken = vec![false; self.tips.len()];
        let mut marker_taken = std::mem::take(&mut self.claimed);
        marker_taken.clear();
        marker_taken.resize(markers.len(), false);
        let mut seen = Vec::new();
        for &(_, ti, mi) in &pairs {
            if tip_taken[ti] || marker_taken[mi] {
                continue;
            }
            tip_taken[ti] = true;
            marker_taken[mi] = true;
            self.tips[ti].2 = markers[mi];
            seen.push((self.tips[ti].0, markers[mi]));
        }
        self.cells = cells;
        self.pairs = pairs;
        self.claimed = marker_taken;
        seen.sort_by_key(|s| s.0);
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
            .filter_map(|(m, p)| self.by_marker.get(m).map(|&i| *p - self.tips[i].1))
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

    /// The bucketed search gives exactly what comparing every tip with
    /// every marker gives, including across cell borders and negative cells.
    #[test]
    fn same_assignment_as_the_exhaustive_search() {
        let mut rng = crate::rng::Rng::new(9);
        let gate = 0.05;
        let tips: Vec<(usize, DVec3)> = (0..300)
            .map(|i| {
                let p = DVec3::new(
                    rng.range(-1.0, 1.0),
                    rng.range(0.0, 2.0),
                    rng.range(-1.0, 1.0),
                );
                (i, p)
            })
            .collect();
        let mut f = TipFollower::new(gate);
        f.set_tips(&tips);
        for _ in 0..5 {
            let mut markers: Vec<DVec3> = tips
                .iter()
                .map(|t| t.1 + DVec3::new(rng.normal(), rng.normal(), rng.normal()) * 0.02)
                .collect();
            for _ in 0..200 {
                markers.push(DVec3::new(
                    rng.range(-1.0, 1.0),
                    rng.range(0.0, 2.0),
                    rng.range(-1.0, 1.0),
                ));
            }
            // Exhaustive reference on a copy.
            let mut pairs = Vec::new();
            for (ti, t) in f.tips.iter().enumerate() {
                for (mi, m) in markers.iter().enumerate() {
                    let d = t.2.distance(*m);
                    if d <= gate {
                        pairs.push((d, ti, mi));
                    }
                }
            }
            pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
            let (mut tt, mut mt) = (vec![false; 300], vec![false; markers.len()]);
            let mut want = Vec::new();
            for (_, ti, mi) in pairs {
                if !tt[ti] && !mt[mi] {
                    tt[ti] = true;
                    mt[mi] = true;
                    want.push((f.tips[ti].0, markers[mi]));
                }
            }
            want.sort_by_key(|s| s.0);
            assert_eq!(f.update(&markers), want);
        }
    }
}
