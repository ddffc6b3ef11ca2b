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

use glam::DVec3;

use super::crown::{Crown, FitOptions};
use super::settings::ForestSettings;

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

/// Searches for the trees among `tips`.
pub fn find(tips: &[DVec3], s: &ForestSettings) -> Detection {
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
        let Some((r, mut centres)) = best_split(tips, k, s) else {
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

/// The best valid split into `k` crowns over the starts: (RMS, axis feet).
fn best_split(tips: &[DVec3], k: usize, s: &ForestSettings) -> Option<(f64, Vec<DVec3>)> {
    let mut best: Option<(f64, Vec<DVec3>)> = None;
    for start in 0..STARTS.min(tips.len()) {
        let first = start * tips.len() / STARTS.min(tips.len());
        let (centres, labels) = kmeans(tips, k, first);
        let Some((r, centres)) = refine(tips, centres, labels, s) else {
            continue;
        };
        if best.as_ref().is_none_or(|b| r < b.0) {
            best = Some((r, centres));
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
) -> Option<(f64, Vec<DVec3>)> {
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
    Some((rms_of(tips, &crowns, &labels), centres))
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
