//! Finding the trees when no `[[trees]]` are configured: the smallest
//! number of crown surfaces that explains the tips (docs/forest.md, "Where
//! the trees stand").
//!
//! For K = 1, 2, … the tips are split by k-means on their horizontal
//! positions (several deterministic starts), then crowns are fitted with a
//! free axis and every tip goes to the nearest surface, until the split
//! stands; a split counts when every tree has `min_tips` tips and every two
//! axes stand `min_spacing_m` apart. The first K whose worst tree's RMS
//! surface distance is within `fit_tolerance_m` is taken; when none is, the
//! K with the least RMS + `count_penalty_m`·K (one crown of a forest that
//! fits badly must not make the search give up and take one tree).
//!
//! When the take swayed, the sway and the fit choose K together
//! ([`by_sway`]): a tree cut in two leaves two crowns sharing its trunk's
//! sway, two trees sway independently, and a split that fits clearly
//! better is taken unless its crowns sway as one.

use glam::DVec3;

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
    /// False when no K fitted within the tolerance (one tree was taken).
    pub fits: bool,
}

/// Searches for the trees among `tips`: by the sway when `sway` is given
/// (the take swayed), else by the crown fit alone.
pub fn find(tips: &[DVec3], s: &ForestSettings, sway: Option<&Coherence>) -> Detection {
    match sway {
        Some(c) => by_sway(tips, s, c),
        None => by_fit(tips, s),
    }
}

/// One number of trees tried, with how well its split fits and sways.
#[derive(Debug, Clone, PartialEq)]
pub struct Candidate {
    /// The number of crowns.
    pub k: usize,
    /// The worst crown's RMS surface distance (m).
    pub rms: f64,
    /// The largest mean sway correlation between two of its crowns
    /// ([`Coherence::dependence`]; −∞ for one crown).
    pub dependence: f64,
    /// The same pair's correlation over the geometric mean of the two
    /// crowns' own (1 for two halves of one tree's sway, near 0 for two
    /// trees).
    pub ratio: f64,
    /// Axis foot of every crown.
    pub centres: Vec<DVec3>,
}

/// Every valid split for K = 1 ..= `max_trees` (the least RMS over the
/// starts), with its sway dependence: what [`by_sway`] chooses among.
pub fn candidates(tips: &[DVec3], s: &ForestSettings, sway: &Coherence) -> Vec<Candidate> {
    let mut out = Vec::new();
    if let Some(c) = Crown::fit(tips, centroid(tips), FREE) {
        out.push(Candidate {
            k: 1,
            rms: rms_of(tips, std::slice::from_ref(&c), &vec![0; tips.len()]),
            dependence: f64::NEG_INFINITY,
            ratio: f64::NEG_INFINITY,
            centres: vec![c.axis_at(0.0)],
        });
    }
    for k in 2..=s.max_trees {
        if tips.len() < k * s.min_tips {
            break;
        }
        let Some(split) = best_split(tips, k, s) else {
            continue;
        };
        let (dependence, ratio) = sway.dependence(&split.labels, k);
        out.push(Candidate {
            k,
            rms: split.rms,
            dependence,
            ratio,
            centres: split.centres,
        });
    }
    out
}

/// The count by the sway and the fit together (docs/forest.md, "The sway
/// chooses the count"): start from the fit's K (the smallest that fits
/// within `fit_tolerance_m`, else the least penalised); refuse it while two
/// of its crowns sway as one tree (mean correlation at least
/// `trunk_coherence` and at least [`SAME_TREE_RATIO`] of their own) and a
/// K less still fits fairly (within [`MERGE_FIT`] × `fit_tolerance_m`:
/// two trees whose trunks happen to sway alike are not merged into a crown
/// no surface fits), and take a K more while that split's crowns all sway
/// independently (no two above [`APART_RATIO`] of their own correlation),
/// or it fits clearly better and no two of its crowns sway as one tree
/// ([`splits`]).
pub fn by_sway(tips: &[DVec3], s: &ForestSettings, sway: &Coherence) -> Detection {
    let all = candidates(tips, s, sway);
    let rms: Vec<(usize, f64)> = all.iter().map(|c| (c.k, c.rms)).collect();
    let Some(mut at) = fit_choice(&all, s) else {
        return by_fit(tips, s);
    };
    let same_tree = |c: &Candidate| c.dependence >= s.trunk_coherence && c.ratio >= SAME_TREE_RATIO;
    while at > 0 && same_tree(&all[at]) && all[at - 1].rms <= MERGE_FIT * s.fit_tolerance_m {
        at -= 1;
    }
    while at + 1 < all.len() && all[at + 1].k == all[at].k + 1 && splits(&all[at], &all[at + 1]) {
        at += 1;
    }
    let mut centres = all[at].centres.clone();
    centres.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.z.total_cmp(&b.z)));
    Detection {
        centres,
        rms,
        fits: all[at].rms <= s.fit_tolerance_m,
    }
}

/// Two crowns whose mean sway correlation is at least this fraction of
/// their own (geometric mean) are two parts of one tree.
pub const SAME_TREE_RATIO: f64 = 0.65;
/// How much worse than `fit_tolerance_m` the fewer crowns may fit for the
/// sway to merge two crowns into one tree.
pub const MERGE_FIT: f64 = 1.5;
/// A split whose crowns all correlate below this fraction of their own is
/// taken over fewer trees.
pub const APART_RATIO: f64 = 0.3;

/// A crown fitted well enough, its surface still improving by a factor
/// [`SPLIT_FIT`] or more when cut in two, is two trees unless its halves
/// sway as one: mean correlation at least this…
pub const SPLIT_DEPENDENCE: f64 = 0.25;
/// …or at least this fraction of their own.
pub const SPLIT_RATIO: f64 = 0.75;
/// The worst crown's RMS must fall to this fraction of the fewer crowns'
/// for [`SPLIT_DEPENDENCE`] and [`SPLIT_RATIO`] to decide the split.
pub const SPLIT_FIT: f64 = 0.8;

/// Whether `more` (one crown more than `fewer`) is taken over `fewer`:
/// its crowns all sway apart ([`APART_RATIO`]), or it fits clearly better
/// ([`SPLIT_FIT`]) and none of its pairs sways as one tree. The second
/// counts the trees whose trunk sways too little against their limbs for
/// the first (a cut tree's halves share their trunk's sway, so they reach
/// [`SPLIT_DEPENDENCE`] or [`SPLIT_RATIO`]; a tree cut too far barely fits
/// better), and undoes a merge of two trees whose trunks happened to sway
/// alike when the merged crown fits clearly worse than the two.
fn splits(fewer: &Candidate, more: &Candidate) -> bool {
    more.ratio < APART_RATIO
        || (more.rms <= SPLIT_FIT * fewer.rms
            && more.dependence < SPLIT_DEPENDENCE
            && more.ratio < SPLIT_RATIO)
}

/// The index in `all` of the fit's choice (see [`by_fit`]).
fn fit_choice(all: &[Candidate], s: &ForestSettings) -> Option<usize> {
    if let Some(i) = all.iter().position(|c| c.rms <= s.fit_tolerance_m) {
        return Some(i);
    }
    let penalised = |c: &Candidate| c.rms + s.count_penalty_m * c.k as f64;
    (0..all.len()).min_by(|&a, &b| {
        penalised(&all[a])
            .total_cmp(&penalised(&all[b]))
            .then(a.cmp(&b))
    })
}

/// The count by the crown fit alone (module comment).
fn by_fit(tips: &[DVec3], s: &ForestSettings) -> Detection {
    let mut rms = Vec::new();
    let one = Crown::fit(tips, centroid(tips), FREE);
    let one_rms = one
        .as_ref()
        .map(|c| rms_of(tips, std::slice::from_ref(c), &vec![0; tips.len()]));
    let single = Detection {
        centres: vec![one.map_or(centroid(tips), |c| c.axis_at(0.0))],
        rms: one_rms.map(|r| vec![(1, r)]).unwrap_or_default(),
        fits: false,
    };
    if let Some(r) = one_rms {
        rms.push((1, r));
        if r <= s.fit_tolerance_m {
            return Detection {
                fits: true,
                ..single
            };
        }
    }
    // Every valid split tried, for the fallback: (K, RMS, axis feet).
    let mut splits: Vec<(usize, f64, Vec<DVec3>)> = Vec::new();
    if let Some(r) = one_rms {
        splits.push((1, r, single.centres.clone()));
    }
    for k in 2..=s.max_trees {
        if tips.len() < k * s.min_tips {
            break;
        }
        let Some(Split {
            rms: r,
            mut centres,
            ..
        }) = best_split(tips, k, s)
        else {
            continue;
        };
        rms.push((k, r));
        centres.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.z.total_cmp(&b.z)));
        if r <= s.fit_tolerance_m {
            return Detection {
                centres,
                rms,
                fits: true,
            };
        }
        splits.push((k, r, centres));
    }
    // Nothing fitted within the tolerance: the least penalised RMS (the
    // first on a tie, so fewer trees win).
    let penalised = |&(k, r, _): &(usize, f64, Vec<DVec3>)| r + s.count_penalty_m * k as f64;
    let best = splits
        .iter()
        .min_by(|a, b| penalised(a).total_cmp(&penalised(b)).then(a.0.cmp(&b.0)));
    match best {
        Some((_, _, centres)) => Detection {
            centres: centres.clone(),
            rms,
            fits: false,
        },
        None => Detection { rms, ..single },
    }
}

/// A valid split of the tips into crowns.
struct Split {
    /// The worst crown's RMS surface distance (m).
    rms: f64,
    /// Axis foot of every crown.
    centres: Vec<DVec3>,
    /// Crown of every tip.
    labels: Vec<usize>,
}

/// The best valid split into `k` crowns over the starts: the least RMS.
fn best_split(tips: &[DVec3], k: usize, s: &ForestSettings) -> Option<Split> {
    let mut best: Option<Split> = None;
    for start in 0..STARTS.min(tips.len()) {
        let first = start * tips.len() / STARTS.min(tips.len());
        let (centres, labels) = kmeans(tips, k, first);
        let Some(split) = refine(tips, centres, labels, s) else {
            continue;
        };
        if best.as_ref().is_none_or(|b| split.rms < b.rms) {
            best = Some(split);
        }
    }
    best
}

/// Crowns with free axes fitted to the split until it stands; `None` when
/// a tree ends with too few tips or two axes too close.
fn refine(
    tips: &[DVec3],
    mut centres: Vec<DVec3>,
    mut labels: Vec<usize>,
    s: &ForestSettings,
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
        let next: Vec<usize> = tips
            .iter()
            .map(|p| nearest(crowns.iter().map(|c| c.distance(*p))))
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
        rms: rms_of(tips, &crowns, &labels),
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

/// The worst tree's root mean square distance of its tips from its crown:
/// two trees taken for one make one bad crown among good ones, which the
/// RMS over all tips would hide.
fn rms_of(tips: &[DVec3], crowns: &[Crown], labels: &[usize]) -> f64 {
    let mut sum = vec![0.0; crowns.len()];
    let mut count = vec![0usize; crowns.len()];
    for (p, &l) in tips.iter().zip(labels) {
        sum[l] += crowns[l].distance(*p).powi(2);
        count[l] += 1;
    }
    sum.iter()
        .zip(&count)
        .map(|(s, &n)| (s / n.max(1) as f64).sqrt())
        .fold(0.0, f64::max)
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
