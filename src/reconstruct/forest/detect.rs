//! Finding the trees when no `[[trees]]` are configured: the smallest
//! number of crown surfaces that explains the tips (docs/forest.md, "Where
//! the trees stand").
//!
//! For K = 1, 2, … the tips are split by k-means on their horizontal
//! positions (several deterministic starts) and by the best split into
//! K − 1 with one of its crowns cut in two, then crowns are fitted with a
//! free axis and every tip goes to the nearest surface (in a swayed take,
//! less the trunk's pull of the crown whose tips it sways with), until the
//! split stands; a split counts when every tree has `min_tips` tips and every two
//! axes stand `min_spacing_m` apart, and the one with the least RMS is
//! kept. [`super::count`] then chooses K among them (by the fit alone, or
//! the fit and the sway) and says why.

use glam::DVec3;

use super::count::{self, Candidate, CountChoice};
use super::crown::{Crown, FitOptions};
use super::settings::ForestSettings;
use super::sway::Coherence;

/// A weak ridge: the tips place the axis.
const FREE: FitOptions = FitOptions {
    offset_ridge: 0.01,
    lean: false,
    weighted: true,
};
/// Deterministic k-means starts per K.
const STARTS: usize = 5;
/// Crown refit rounds per start.
const ROUNDS: usize = 10;

/// What the search found.
#[derive(Debug, Clone, PartialEq)]
pub struct Detection {
    /// Axis foot of every tree found (x, z; y is 0), ordered by x then z.
    pub centres: Vec<DVec3>,
    /// RMS surface distance (m) for each K tried that gave a valid split.
    pub rms: Vec<(usize, f64)>,
    /// False when no K fitted within the tolerance (the least penalised
    /// was taken).
    pub fits: bool,
    /// How the number of trees was chosen, for the operator to judge.
    pub count: CountChoice,
}

/// Searches for the trees among `tips`: by the sway when `sway` is given
/// (the take swayed), else by the crown fit alone.
pub fn find(tips: &[DVec3], s: &ForestSettings, sway: Option<&Coherence>) -> Detection {
    // A still take stops at the first K that fits: the fit alone takes it.
    let all = search(tips, s, sway, sway.is_none());
    let Some(choice) = count::choose(&all, s, sway.is_some()) else {
        return Detection {
            centres: vec![centroid(tips)],
            rms: Vec::new(),
            fits: false,
            count: CountChoice::unfitted(),
        };
    };
    let chosen = &all[choice.at];
    let mut centres = chosen.centres.clone();
    centres.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.z.total_cmp(&b.z)));
    Detection {
        centres,
        rms: all.iter().map(|c| (c.k, c.rms)).collect(),
        fits: chosen.rms <= s.fit_tolerance_m,
        count: choice.count,
    }
}

/// Every valid split for K = 1 ..= `max_trees` (the least RMS over the
/// starts), with its sway dependence: what the count chooses among.
pub fn candidates(tips: &[DVec3], s: &ForestSettings, sway: &Coherence) -> Vec<Candidate> {
    search(tips, s, Some(sway), false)
}

/// The valid splits for K = 1, 2, … (each K's starts include the best
/// split into K − 1 with one crown cut in two), with their sway dependence
/// when `sway` is given; `stop_at_fit` ends the search at the first K
/// within `fit_tolerance_m` (the fit alone takes it).
fn search(
    tips: &[DVec3],
    s: &ForestSettings,
    sway: Option<&Coherence>,
    stop_at_fit: bool,
) -> Vec<Candidate> {
    let mut out = Vec::new();
    let mut fewer = Crown::fit(tips, centroid(tips), FREE).map(|c| {
        let labels = vec![0; tips.len()];
        Split {
            crown_rms: crown_rms(tips, std::slice::from_ref(&c), &labels),
            centres: vec![c.axis_at(0.0)],
            labels,
        }
    });
    let mut k = 1;
    loop {
        if let Some(split) = &fewer {
            let (dependence, ratio) = match sway {
                Some(c) if k > 1 => c.dependence(&split.labels, k),
                _ => (f64::NEG_INFINITY, f64::NEG_INFINITY),
            };
            let (sway_ssr, sway_pairs, sway_blocks) = match sway {
                Some(c) => c.block_residual(&split.labels, k),
                None => (0.0, 0, 0),
            };
            out.push(Candidate {
                k,
                rms: split.rms(),
                rms_all: split.rms_all(),
                crown_rms: split.crown_rms.clone(),
                labels: split.labels.clone(),
                dependence,
                ratio,
                sway_ssr,
                sway_pairs,
                sway_blocks,
                centres: split.centres.clone(),
            });
            if stop_at_fit && split.rms() <= s.fit_tolerance_m {
                break;
            }
        }
        k += 1;
        if k > s.max_trees || tips.len() < k * s.min_tips {
            break;
        }
        fewer = best_split(tips, k, s, fewer.as_ref(), sway);
    }
    out
}

/// A valid split of the tips into crowns.
struct Split {
    /// Every crown's RMS surface distance (m).
    crown_rms: Vec<f64>,
    /// Axis foot of every crown.
    centres: Vec<DVec3>,
    /// Crown of every tip.
    labels: Vec<usize>,
}

/// The best valid split into `k` crowns: the least RMS over the k-means
/// starts; when none of them stands, over the best split into `k − 1`
/// (`fewer`) with each of its crowns cut in two. The k-means starts alone
/// can miss a count: where two of its seeds land in one crown, every split
/// leaves two axes too close and none stands, though cutting the one crown
/// of the fewer that holds two trees does. (Cutting in every case was
/// tried: right on more sessions of the seeds it was tried on, wrong on
/// more of the held-out ones — its better-fitting splits move the fit's
/// choice where the sway then errs.)
fn best_split(
    tips: &[DVec3],
    k: usize,
    s: &ForestSettings,
    fewer: Option<&Split>,
    sway: Option<&Coherence>,
) -> Option<Split> {
    let starts = (0..STARTS.min(tips.len())).filter_map(|start| {
        let first = start * tips.len() / STARTS.min(tips.len());
        let (centres, labels) = kmeans(tips, k, first);
        refine(tips, centres, labels, s, sway)
    });
    let best = least_rms(starts);
    if best.is_some() {
        return best;
    }
    let f = fewer.filter(|f| f.centres.len() + 1 == k)?;
    least_rms((0..f.centres.len()).filter_map(|t| {
        let (centres, labels) = cut(tips, f, t)?;
        refine(tips, centres, labels, s, sway)
    }))
}

/// The split of least RMS (the first on a tie).
fn least_rms(splits: impl Iterator<Item = Split>) -> Option<Split> {
    splits.fold(None, |best: Option<Split>, split| match best {
        Some(b) if b.rms() <= split.rms() => Some(b),
        _ => Some(split),
    })
}

/// `split` with crown `t` cut in two by 2-means on its tips' horizontal
/// positions (the second part becomes the last crown); `None` when the
/// crown has too few tips to cut.
fn cut(tips: &[DVec3], split: &Split, t: usize) -> Option<(Vec<DVec3>, Vec<usize>)> {
    let own: Vec<usize> = (0..tips.len()).filter(|&i| split.labels[i] == t).collect();
    if own.len() < 2 {
        return None;
    }
    let points: Vec<DVec3> = own.iter().map(|&i| tips[i]).collect();
    let (halves, parts) = kmeans(&points, 2, 0);
    let mut centres = split.centres.clone();
    centres[t] = halves[0];
    centres.push(halves[1]);
    let mut labels = split.labels.clone();
    for (&i, &part) in own.iter().zip(&parts) {
        if part == 1 {
            labels[i] = centres.len() - 1;
        }
    }
    Some((centres, labels))
}

/// Crowns with free axes fitted to the split until it stands; `None` when
/// a tree ends with too few tips or two axes too close.
fn refine(
    tips: &[DVec3],
    mut centres: Vec<DVec3>,
    mut labels: Vec<usize>,
    s: &ForestSettings,
    sway: Option<&Coherence>,
) -> Option<Split> {
    let mut crowns = Vec::new();
    for _ in 0..ROUNDS {
        crowns.clear();
        for (t, c) in centres.iter_mut().enumerate() {
            let own: Vec<DVec3> = (0..tips.len())
                .filter(|&i| labels[i] == t)
                .map(|i| tips[i])
                .collect();
            if own.len() < s.min_tips {
                return None;
            }
            let crown = Crown::fit(&own, *c, FREE)?;
            *c = crown.axis_at(0.0);
            crowns.push(crown);
        }
        // The trunk's pull, as when tips are given to trees (assign): a
        // tip's mean sway correlation with a crown's tips takes
        // `trunk_weight_m` per unit off its distance to that crown, so a
        // crown gathers the tips that sway with it and a split's crowns
        // are trees, not pieces cut by shape alone (docs/forest.md).
        let shared = sway.map(|co| co.means_with(&labels, crowns.len()));
        let next: Vec<usize> = tips
            .iter()
            .enumerate()
            .map(|(i, p)| {
                nearest(crowns.iter().enumerate().map(|(t, c)| {
                    let with = shared.as_ref().and_then(|m| m[i][t]).unwrap_or(0.0);
                    c.distance(*p) - s.trunk_weight_m * with
                }))
            })
            .collect();
        if next == labels {
            break;
        }
        labels = next;
    }
    for t in 0..centres.len() {
        if labels.iter().filter(|&&l| l == t).count() < s.min_tips {
            return None;
        }
        for u in 0..t {
            let d = (centres[t].x - centres[u].x).hypot(centres[t].z - centres[u].z);
            if d < s.min_spacing_m {
                return None;
            }
        }
    }
    Some(Split {
        crown_rms: crown_rms(tips, &crowns, &labels),
        centres,
        labels,
    })
}

/// k-means on the horizontal positions, seeded with tip `first` and then
/// the tip farthest from the centres so far.
fn kmeans(tips: &[DVec3], k: usize, first: usize) -> (Vec<DVec3>, Vec<usize>) {
    let flat = |p: DVec3| DVec3::new(p.x, 0.0, p.z);
    let mut centres = vec![flat(tips[first])];
    while centres.len() < k {
        let far = tips
            .iter()
            .enumerate()
            .map(|(i, p)| {
                (
                    i,
                    centres
                        .iter()
                        .map(|c| flat(*p).distance(*c))
                        .fold(f64::INFINITY, f64::min),
                )
            })
            .fold((0, -1.0), |a, b| if b.1 > a.1 { b } else { a })
            .0;
        centres.push(flat(tips[far]));
    }
    let mut labels = vec![0; tips.len()];
    for _ in 0..50 {
        let next: Vec<usize> = tips
            .iter()
            .map(|p| nearest(centres.iter().map(|c| flat(*p).distance(*c))))
            .collect();
        for (t, c) in centres.iter_mut().enumerate() {
            let own: Vec<DVec3> = (0..tips.len())
                .filter(|&i| next[i] == t)
                .map(|i| flat(tips[i]))
                .collect();
            if !own.is_empty() {
                *c = own.iter().sum::<DVec3>() / own.len() as f64;
            }
        }
        if next == labels {
            break;
        }
        labels = next;
    }
    (centres, labels)
}

impl Split {
    /// The worst crown's RMS surface distance (m): two trees taken for one
    /// make one bad crown among good ones, which the RMS over all tips
    /// would hide.
    fn rms(&self) -> f64 {
        self.crown_rms.iter().copied().fold(0.0, f64::max)
    }

    /// The RMS surface distance over all tips, each from its own crown
    /// (m): where cutting one crown in two helps that crown, this shows it
    /// though another crown stays the worst.
    fn rms_all(&self) -> f64 {
        let mut count = vec![0usize; self.crown_rms.len()];
        for &l in &self.labels {
            count[l] += 1;
        }
        let sum: f64 = count
            .iter()
            .zip(&self.crown_rms)
            .map(|(&n, r)| n as f64 * r * r)
            .sum();
        (sum / self.labels.len().max(1) as f64).sqrt()
    }
}

/// Every tree's root mean square distance of its tips from its crown.
fn crown_rms(tips: &[DVec3], crowns: &[Crown], labels: &[usize]) -> Vec<f64> {
    let mut sum = vec![0.0; crowns.len()];
    let mut count = vec![0usize; crowns.len()];
    for (p, &l) in tips.iter().zip(labels) {
        sum[l] += crowns[l].distance(*p).powi(2);
        count[l] += 1;
    }
    sum.iter()
        .zip(&count)
        .map(|(s, &n)| (s / n.max(1) as f64).sqrt())
        .collect()
}

fn centroid(tips: &[DVec3]) -> DVec3 {
    tips.iter().sum::<DVec3>() / tips.len().max(1) as f64
}

/// Index of the least value (ties to the lower index).
fn nearest(values: impl Iterator<Item = f64>) -> usize {
    values
        .enumerate()
        .fold(
            (0, f64::INFINITY),
            |a, (i, v)| if v < a.1 { (i, v) } else { a },
        )
        .0
}
