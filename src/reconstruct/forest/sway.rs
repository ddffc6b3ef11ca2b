//! Tips that sway together: in wind, the tips of one limb move as one
//! (Long & Jones §8 warn that tips sharing a parent must not move
//! independently), and every tip of a tree moves with its trunk, while two
//! trees sway independently. Where two crowns meet, a tip that shape alone
//! cannot place is pulled towards the tree of the tips it sways with, and
//! the number of trees is the number of crowns that sway independently
//! ([`Coherence`], docs/forest.md "The sway chooses the count").
//!
//! A tip's sway is its displacement from rest with a 2 s moving average
//! taken off: that removes the steady bend of a wind phase (which every
//! tip of every tree shares, and would correlate them all) and keeps the
//! limb and twig modes (0.5–3 Hz). Two tips are linked by the correlation
//! of their sway over the frames both were measured in.

use glam::DVec3;

use crate::model::tips::Tips;

/// The sway correlation of two tips.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SwayLink {
    /// Marker of one tip.
    pub a: usize,
    /// Marker of the other.
    pub b: usize,
    /// Correlation of their sway, 0–1.
    pub correlation: f64,
}

/// Tips farther apart than this are never pulled together as one limb (m):
/// one limb is not wider, and it keeps chance likenesses between trees out.
pub const MAX_LINK_M: f64 = 1.0;
/// A tip swaying less than this (RMS, m) is still: its correlations are
/// noise.
const MIN_SWAY_M: f64 = 0.002;
/// Length of the moving average taken off (s).
const HIGH_PASS_S: f64 = 2.0;
/// Frames used at most per tip (longer sessions are strided).
const MAX_FRAMES: usize = 4000;
/// Fewest common frames for a correlation.
const MIN_COMMON: usize = 100;

/// The sway correlation of every two swaying tips of `tips` (from the
/// measured samples of their traces); empty for a take without wind. The
/// limb pull keeps the strong, near ones (`forest.sway_correlation`,
/// [`MAX_LINK_M`]); the count and the trunk pull use them all.
pub fn links(tips: &Tips) -> Vec<SwayLink> {
    let frames = tips.timeline.len();
    let Some(dt) = tips.timeline.frame_interval() else {
        return Vec::new();
    };
    let stride = frames.div_ceil(MAX_FRAMES).max(1);
    let window = ((HIGH_PASS_S / (dt * stride as f64)).round() as usize).max(3);
    let series: Vec<Vec<Option<DVec3>>> = tips
        .tips
        .iter()
        .map(|t| {
            let mut s = vec![None; frames.div_ceil(stride)];
            for (f, p) in t.trace.measurements() {
                let f = f.max(0) as usize;
                if f.is_multiple_of(stride) {
                    if let Some(slot) = s.get_mut(f / stride) {
                        *slot = Some(p - t.rest);
                    }
                }
            }
            s
        })
        .collect();
    let markers: Vec<usize> = tips.tips.iter().map(|t| t.marker).collect();
    links_of_series(&series, &markers, window)
}

/// The core of [`links`] on plain series (one displacement per frame, `None`
/// where unmeasured), so it can be tested without a recording.
pub fn links_of_series(
    series: &[Vec<Option<DVec3>>],
    markers: &[usize],
    window: usize,
) -> Vec<SwayLink> {
    let sway: Vec<Vec<Option<DVec3>>> = series.iter().map(|s| high_pass(s, window)).collect();
    let swaying: Vec<bool> = sway.iter().map(|s| rms(s) >= MIN_SWAY_M).collect();
    let mut out = Vec::new();
    for i in 0..sway.len() {
        for j in i + 1..sway.len() {
            if !(swaying[i] && swaying[j]) {
                continue;
            }
            if let Some(c) = correlation(&sway[i], &sway[j]) {
                out.push(SwayLink {
                    a: markers[i],
                    b: markers[j],
                    correlation: c,
                });
            }
        }
    }
    out
}

/// The limb links among `links` (indices into `rests`): correlation at
/// least `threshold`, rests within [`MAX_LINK_M`].
pub fn limb_links(
    links: &[(usize, usize, f64)],
    rests: &[DVec3],
    threshold: f64,
) -> Vec<(usize, usize, f64)> {
    links
        .iter()
        .copied()
        .filter(|&(a, b, c)| c >= threshold && rests[a].distance(rests[b]) <= MAX_LINK_M)
        .collect()
}

/// Every two tips' sway correlation, by tip index (`None` where unknown: a
/// still tip, too few common frames): what tells one tree's crown (its
/// tips share the trunk's sway) from two trees (which sway independently).
#[derive(Debug, Clone, PartialEq)]
pub struct Coherence {
    /// Number of tips.
    n: usize,
    /// Row-major n × n correlations (the diagonal unknown).
    corr: Vec<Option<f64>>,
}

impl Coherence {
    /// The matrix of `n` tips from links between tip indices.
    pub fn new(n: usize, links: &[(usize, usize, f64)]) -> Self {
        let mut corr = vec![None; n * n];
        for &(a, b, c) in links {
            corr[a * n + b] = Some(c);
            corr[b * n + a] = Some(c);
        }
        Coherence { n, corr }
    }

    /// The correlation of tips `a` and `b`, when known.
    pub fn get(&self, a: usize, b: usize) -> Option<f64> {
        self.corr[a * self.n + b]
    }

    /// Share of the tips with a known correlation to some other tip: how
    /// much of the take swayed (0 for a take without wind).
    pub fn coverage(&self) -> f64 {
        if self.n == 0 {
            return 0.0;
        }
        let known = (0..self.n)
            .filter(|&a| (0..self.n).any(|b| self.get(a, b).is_some()))
            .count();
        known as f64 / self.n as f64
    }

    /// The mean correlation between the tips labelled `x` and those
    /// labelled `y` (`x == y`: within one group, each pair once), and how
    /// many pairs it is over.
    pub fn mean_between(&self, labels: &[usize], x: usize, y: usize) -> (f64, usize) {
        let (mut sum, mut count) = (0.0, 0usize);
        for a in (0..self.n).filter(|&a| labels[a] == x) {
            for b in (0..self.n).filter(|&b| labels[b] == y && (x != y || b > a)) {
                if let Some(c) = self.get(a, b) {
                    sum += c;
                    count += 1;
                }
            }
        }
        (if count == 0 { 0.0 } else { sum / count as f64 }, count)
    }

    /// The largest mean correlation between two of the `k` groups of
    /// `labels` (pairs of groups with fewer than [`MIN_PAIRS`] known
    /// correlations are not judged): near zero when every group is a tree
    /// of its own, near a tree's trunk share when one tree was cut in two;
    /// and the largest such mean over the geometric mean of the two groups'
    /// own (near 1 for one tree cut in two, whatever its trunk's share).
    /// −∞ for both when no pair is judged.
    pub fn dependence(&self, labels: &[usize], k: usize) -> (f64, f64) {
        let own: Vec<f64> = (0..k)
            .map(|x| self.mean_between(labels, x, x).0.max(OWN_FLOOR))
            .collect();
        let (mut worst, mut ratio) = (f64::NEG_INFINITY, f64::NEG_INFINITY);
        for x in 0..k {
            for y in 0..x {
                let (m, count) = self.mean_between(labels, x, y);
                if count >= MIN_PAIRS {
                    worst = worst.max(m);
                    ratio = ratio.max(m / (own[x] * own[y]).sqrt());
                }
            }
        }
        (worst, ratio)
    }

    /// How well a block model explains the correlations of the `k` groups
    /// of `labels` as `k` trees: every two tips of one group correlate
    /// about that group's mean (its trunk's share of the sway), tips of two
    /// groups about 0 (two trees sway independently). Returns the squared
    /// residuals' sum over every known pair, the number of pairs, and the
    /// number of groups with a pair inside (the block means fitted): what
    /// the count's criterion takes (docs/forest.md, "The count: one
    /// criterion for the fit and the sway").
    pub fn block_residual(&self, labels: &[usize], k: usize) -> (f64, usize, usize) {
        // Per group: pairs, sum and sum of squares inside; across groups:
        // the sum of squares (about 0).
        let mut inside = vec![(0usize, 0.0f64, 0.0f64); k];
        let (mut across, mut pairs) = (0.0, 0usize);
        for a in 0..self.n {
            for b in a + 1..self.n {
                let Some(c) = self.get(a, b) else { continue };
                pairs += 1;
                match (labels.get(a), labels.get(b)) {
                    (Some(&x), Some(&y)) if x == y && x < k => {
                        let g = &mut inside[x];
                        g.0 += 1;
                        g.1 += c;
                        g.2 += c * c;
                    }
                    _ => across += c * c,
                }
            }
        }
        let blocks = inside.iter().filter(|g| g.0 > 0).count();
        let within: f64 = inside
            .iter()
            .filter(|g| g.0 > 0)
            .map(|&(n, sum, sq)| sq - sum * sum / n as f64)
            .sum();
        ((within + across).max(0.0), pairs, blocks)
    }

    /// [`Coherence::mean_with`] for every tip and every group `x < k` at
    /// once (row `a`, column `x`): one pass over the pairs.
    pub fn means_with(&self, labels: &[usize], k: usize) -> Vec<Vec<Option<f64>>> {
        (0..self.n)
            .map(|a| {
                let mut sum = vec![(0.0, 0usize); k];
                for b in (0..self.n).filter(|&b| b != a) {
                    if let (Some(c), Some(&x)) = (self.get(a, b), labels.get(b)) {
                        if let Some(g) = sum.get_mut(x) {
                            g.0 += c;
                            g.1 += 1;
                        }
                    }
                }
                sum.iter()
                    .map(|&(s, n)| (n > 0).then(|| s / n as f64))
                    .collect()
            })
            .collect()
    }

    /// The mean correlation of tip `a` with the tips labelled `x` (other
    /// than itself), when any is known.
    pub fn mean_with(&self, labels: &[usize], a: usize, x: usize) -> Option<f64> {
        let (mut sum, mut count) = (0.0, 0usize);
        for b in (0..self.n).filter(|&b| b != a && labels[b] == x) {
            if let Some(c) = self.get(a, b) {
                sum += c;
                count += 1;
            }
        }
        (count > 0).then(|| sum / count as f64)
    }
}

/// A group's own mean correlation counts as at least this in
/// [`Coherence::dependence`]'s ratio, so two groups that hardly sway
/// together inside do not make a large ratio of noise.
const OWN_FLOOR: f64 = 0.1;

/// Fewest known correlations between two groups for [`Coherence::dependence`]
/// to judge them.
pub const MIN_PAIRS: usize = 10;

/// The series minus its centred moving average over `window` samples (the
/// average of the measured samples in the window).
fn high_pass(s: &[Option<DVec3>], window: usize) -> Vec<Option<DVec3>> {
    let mut sum = vec![DVec3::ZERO; s.len() + 1];
    let mut count = vec![0usize; s.len() + 1];
    for (i, v) in s.iter().enumerate() {
        sum[i + 1] = sum[i] + v.unwrap_or(DVec3::ZERO);
        count[i + 1] = count[i] + usize::from(v.is_some());
    }
    let half = window / 2;
    s.iter()
        .enumerate()
        .map(|(i, v)| {
            let v = (*v)?;
            let (lo, hi) = (i.saturating_sub(half), (i + half + 1).min(s.len()));
            let n = count[hi] - count[lo];
            Some(v - (sum[hi] - sum[lo]) / n as f64)
        })
        .collect()
}

/// Root mean square length of the measured samples (0 with none).
fn rms(s: &[Option<DVec3>]) -> f64 {
    let (sum, n) = s
        .iter()
        .flatten()
        .fold((0.0, 0usize), |(a, n), v| (a + v.length_squared(), n + 1));
    if n == 0 {
        0.0
    } else {
        (sum / n as f64).sqrt()
    }
}

/// Correlation of two 3D series over their common samples: the mean-free
/// inner product over the product of the norms. `None` with too few.
fn correlation(a: &[Option<DVec3>], b: &[Option<DVec3>]) -> Option<f64> {
    let pairs: Vec<(DVec3, DVec3)> = a
        .iter()
        .zip(b)
        .filter_map(|(x, y)| Some(((*x)?, (*y)?)))
        .collect();
    if pairs.len() < MIN_COMMON {
        return None;
    }
    let n = pairs.len() as f64;
    let ma = pairs.iter().map(|p| p.0).sum::<DVec3>() / n;
    let mb = pairs.iter().map(|p| p.1).sum::<DVec3>() / n;
    let (mut ab, mut aa, mut bb) = (0.0, 0.0, 0.0);
    for (x, y) in &pairs {
        let (x, y) = (*x - ma, *y - mb);
        ab += x.dot(y);
        aa += x.length_squared();
        bb += y.length_squared();
    }
    let d = (aa * bb).sqrt();
    (d > 0.0).then(|| ab / d)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    /// 20 s at 100 Hz: a still half, then a sway `amp·sin(2π f t + φ)`
    /// along x on top of a steady bend of 2 cm.
    fn tip(f: f64, phase: f64, amp: f64, twig: f64) -> Vec<Option<DVec3>> {
        (0..2000)
            .map(|i| {
                let t = i as f64 / 100.0;
                if i < 1000 {
                    return Some(DVec3::ZERO);
                }
                let s = amp * (TAU * f * t + phase).sin() + twig * (TAU * 2.3 * t).cos();
                Some(DVec3::new(0.02 + s, 0.0, 0.0))
            })
            .collect()
    }

    #[test]
    fn one_limb_links_and_the_shared_bend_does_not() {
        let series = vec![
            tip(0.8, 0.0, 0.015, 0.003),  // limb A
            tip(0.8, 0.0, 0.010, -0.004), // limb A, another twig
            tip(0.61, 1.0, 0.015, 0.003), // limb B: same bend, other sway
            tip(0.8, 0.0, 0.0005, 0.0),   // still tip: never linked
        ];
        let rests = vec![DVec3::ZERO, DVec3::X * 0.3, DVec3::X * 0.5, DVec3::X * 0.2];
        let all = links_of_series(&series, &[0, 1, 2, 3], 200);
        // The still tip has no correlation with anyone.
        assert_eq!(all.len(), 3, "{all:?}");
        let pairs: Vec<(usize, usize, f64)> =
            all.iter().map(|l| (l.a, l.b, l.correlation)).collect();
        let links = limb_links(&pairs, &rests, 0.7);
        assert_eq!(links.len(), 1, "{links:?}");
        assert_eq!((links[0].0, links[0].1), (0, 1));
        assert!(links[0].2 > 0.85, "{links:?}");
        // Too far apart: not linked.
        let far = vec![DVec3::ZERO, DVec3::X * 1.5, DVec3::X * 0.5, DVec3::X * 0.2];
        assert!(limb_links(&pairs, &far, 0.7).is_empty());
    }

    #[test]
    fn gaps_are_skipped() {
        let mut a = tip(0.8, 0.0, 0.015, 0.0);
        for s in a.iter_mut().skip(1200).take(300) {
            *s = None;
        }
        let b = tip(0.8, 0.0, 0.012, 0.0);
        let links = links_of_series(&[a, b], &[5, 9], 200);
        assert_eq!(links.len(), 1);
        assert_eq!((links[0].a, links[0].b), (5, 9));
        assert!(links[0].correlation > 0.7, "{links:?}");
    }

    /// Two trees of three tips each: every two tips of one tree correlate
    /// 0.6 (tree 0) or 0.4 (tree 1), tips of the two trees 0.
    fn two_trees() -> Coherence {
        let mut links = Vec::new();
        for a in 0..6 {
            for b in a + 1..6 {
                let c = match (a < 3, b < 3) {
                    (true, true) => 0.6,
                    (false, false) => 0.4,
                    _ => 0.0,
                };
                links.push((a, b, c));
            }
        }
        Coherence::new(6, &links)
    }

    #[test]
    fn the_block_model_fits_one_group_per_tree_and_no_other_split() {
        let c = two_trees();
        // One group per tree: every pair at its block's mean, none left.
        let (ssr, pairs, blocks) = c.block_residual(&[0, 0, 0, 1, 1, 1], 2);
        assert_eq!((pairs, blocks), (15, 2));
        assert!(ssr < 1e-12, "{ssr}");
        // Tree 0 cut in two: its pairs across the cut (2 × 0.6) are taken
        // for 0, as if two trees.
        let (cut, _, blocks) = c.block_residual(&[0, 0, 2, 1, 1, 1], 3);
        assert_eq!(blocks, 2, "a group of one tip has no pair inside");
        assert!((cut - 2.0 * 0.36).abs() < 1e-9, "{cut}");
        // The two trees as one: the mean 0.2 over all 15 pairs.
        let (merged, _, blocks) = c.block_residual(&[0; 6], 1);
        assert_eq!(blocks, 1);
        assert!(merged > cut, "{merged} {cut}");
        // Every tip's mean with every group, as one tip at a time gives it.
        let labels = [0, 0, 2, 1, 1, 1];
        let all = c.means_with(&labels, 3);
        for (a, row) in all.iter().enumerate() {
            for (x, m) in row.iter().enumerate() {
                assert_eq!(*m, c.mean_with(&labels, a, x), "tip {a} group {x}");
            }
        }
    }
}
