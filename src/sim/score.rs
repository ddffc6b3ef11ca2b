//! Scoring the marker stage against a synthetic session's truth: what the
//! accuracy tests assert and what `examples/track_stress.rs` tabulates.
//!
//! Identity comes from the source columns: every measured sample of an
//! output tip remembers the column it came from, and the truth says which
//! tip (or ghost) each column shows.

use std::collections::HashMap;

use glam::DVec3;

use super::truth::GapTruth;
use super::{Synthetic, Truth};
use crate::model::tips::{Tip, Tips};
use crate::model::trace::{SampleKind, Trace};
use crate::track::gaps::{self, GapSettings};

/// Gap-length bins of the fill table (frames), the last one ending at 2 s.
pub fn fill_bins(frame_rate: f64) -> [(i64, i64); 3] {
    [(1, 10), (11, 50), (51, (2.0 * frame_rate).round() as i64)]
}

/// One wind-phase gap of a true tip, filled by us and by PCHIP.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FillScore {
    /// Frames missing.
    pub len: i64,
    /// Mean distance (m) of our fill from the noiseless truth, when the
    /// whole gap was filled.
    pub ours: Option<f64>,
    /// The same for PCHIP on the true marker's own samples (perfect
    /// identity, no length limit).
    pub pchip: Option<f64>,
    /// Whether every measured sample of our tip within [`CLEAN_SPAN`]
    /// frames of the gap came from the true tip, and both bordering frames
    /// are measured: the gap we filled is the true one, with the true
    /// marker's samples around it. What separates the fill model's error
    /// from the identity's (a fill anchored on another marker's sample).
    pub clean: bool,
}

/// Frames each side of a gap that [`FillScore::clean`] checks: longer than
/// the fill's end fits (0.15 s at 240 Hz).
pub const CLEAN_SPAN: i64 = 48;

/// What one session scored.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Score {
    /// Tips the marker stage reported.
    pub tips_found: usize,
    /// Tips the simulator placed.
    pub tips_placed: usize,
    /// Measured samples inside an output tip that came from another tip's
    /// marker or from a ghost.
    pub wrong_samples: usize,
    /// Output tips beyond one per true tip: pieces of a marker left apart,
    /// or ghosts reported as tips.
    pub fragments: usize,
    /// True tips that no output tip follows.
    pub missed_tips: usize,
    /// Distance of each output tip's rest position from its true tip's (m).
    pub rest_errors: Vec<f64>,
    /// Every wind-phase gap of a followed tip, ours beside PCHIP.
    pub fills: Vec<FillScore>,
    /// Fills whose two ends are samples of different markers.
    pub bridged: usize,
    /// The error (m) of every sample a followed tip holds filled in a frame
    /// its own marker was measured: a sample given up where two markers
    /// passed within their noise of each other, or one left to another
    /// tip or to none. What giving up samples costs, which the wrong
    /// samples and the fills of true gaps do not show.
    pub own_filled: Vec<f64>,
}

impl Score {
    /// Largest rest error (m).
    pub fn rest_max(&self) -> f64 {
        self.rest_errors.iter().copied().fold(0.0, f64::max)
    }

    /// (gaps, gaps we filled, our mean error, PCHIP's mean error on those
    /// same gaps) for gaps of `lo..=hi` frames; errors weighted by frames.
    pub fn fill_bin(&self, lo: i64, hi: i64) -> (usize, usize, f64, f64) {
        let sel: Vec<&FillScore> = self
            .fills
            .iter()
            .filter(|f| (lo..=hi).contains(&f.len))
            .collect();
        let (mut ours, mut pchip, mut frames, mut filled) = (0.0, 0.0, 0.0, 0);
        for f in &sel {
            if let (Some(o), Some(p)) = (f.ours, f.pchip) {
                ours += o * f.len as f64;
                pchip += p * f.len as f64;
                frames += f.len as f64;
                filled += 1;
            }
        }
        let n = frames.max(1.0);
        (sel.len(), filled, ours / n, pchip / n)
    }

    /// (gaps, mean of ours, mean of PCHIP's, median of ours, median of
    /// PCHIP's) over the gaps of `lo..=hi` frames both filled and whose
    /// [`FillScore::clean`] is `clean`; means weighted by frames, medians
    /// per gap. The diagnosis of `track_stress` (`TRACK_FILL_DIAG`).
    pub fn fill_bin_split(&self, lo: i64, hi: i64, clean: bool) -> (usize, f64, f64, f64, f64) {
        let mut sel: Vec<(f64, f64, f64)> = (self.fills.iter())
            .filter(|f| (lo..=hi).contains(&f.len) && f.clean == clean)
            .filter_map(|f| Some((f.ours?, f.pchip?, f.len as f64)))
            .collect();
        let frames = sel.iter().map(|x| x.2).sum::<f64>().max(1.0);
        let ours = sel.iter().map(|x| x.0 * x.2).sum::<f64>() / frames;
        let pchip = sel.iter().map(|x| x.1 * x.2).sum::<f64>() / frames;
        let median = |v: &mut Vec<(f64, f64, f64)>, k: usize| {
            let key = |x: &(f64, f64, f64)| if k == 0 { x.0 } else { x.1 };
            v.sort_by(|x, y| key(x).total_cmp(&key(y)));
            v.get(v.len() / 2).map_or(0.0, key)
        };
        let (mo, mp) = (median(&mut sel, 0), median(&mut sel, 1));
        (sel.len(), ours, pchip, mo, mp)
    }

    /// Adds another session's score.
    pub fn merge(&mut self, o: &Score) {
        self.tips_found += o.tips_found;
        self.tips_placed += o.tips_placed;
        self.wrong_samples += o.wrong_samples;
        self.fragments += o.fragments;
        self.missed_tips += o.missed_tips;
        self.rest_errors.extend_from_slice(&o.rest_errors);
        self.fills.extend_from_slice(&o.fills);
        self.bridged += o.bridged;
        self.own_filled.extend_from_slice(&o.own_filled);
    }

    /// (samples, mean error in m) of [`Score::own_filled`].
    pub fn own_filled_mean(&self) -> (usize, f64) {
        let n = self.own_filled.len();
        // Summed from +0: an empty `sum` of floats is −0.
        let total = self.own_filled.iter().fold(0.0, |a, b| a + b);
        (n, total / n.max(1) as f64)
    }
}

/// Which true tip (`Some`) or ghost (`None`) each measured sample of a
/// trace came from, with its internal frame. Public for the diagnosis
/// example (`track_why`) and the accuracy tests, which ask the same.
pub fn owners<'a>(
    trace: &'a Trace,
    truth: &'a Truth,
) -> impl Iterator<Item = (i64, Option<usize>)> + 'a {
    let mut runs = trace.sources().iter().peekable();
    let mut col = None;
    trace.measurements().map(move |(frame, _)| {
        while let Some(r) = runs.next_if(|r| r.frame <= frame) {
            col = r.id;
        }
        let who = col
            .and_then(|c| truth.columns.get(c as usize))
            .and_then(|c| c.tip);
        (frame, who)
    })
}

/// The true tip (`Some`) or ghost (`None`) most of `trace`'s samples came
/// from, and how many; `None` for a trace with no sample. Public for the
/// diagnosis example (`track_why`), which names output tips the way the
/// score matches them.
pub fn main_owner(trace: &Trace, truth: &Truth) -> Option<(Option<usize>, usize)> {
    let mut counts: HashMap<Option<usize>, usize> = HashMap::new();
    for (_, who) in owners(trace, truth) {
        *counts.entry(who).or_default() += 1;
    }
    majority(&counts)
}

/// The owner with the most samples; on a tie the higher tip, any tip
/// before the ghosts (so the choice does not depend on the map's order).
fn majority(counts: &HashMap<Option<usize>, usize>) -> Option<(Option<usize>, usize)> {
    counts
        .iter()
        .max_by_key(|(k, n)| (**n, k.map_or(0, |v| v + 1)))
        .map(|(&k, &n)| (k, n))
}

/// Scores `tips` (the marker stage's output on `syn`'s frames).
pub fn score(tips: &Tips, syn: &Synthetic) -> Score {
    let truth = &syn.truth;
    let mut s = Score {
        tips_found: tips.tips.len(),
        tips_placed: truth.tips.len(),
        ..Score::default()
    };
    let ours = match_tips(tips, truth, &mut s);
    let baseline = pchip_baseline(tips, syn);
    for (k, tip) in ours.iter().enumerate() {
        let filled = tip.map(|t| filled_positions(tips, t)).unwrap_or_default();
        let owner: HashMap<i64, Option<usize>> = tip
            .map(|t| {
                owners(&t.trace, truth)
                    .map(|(f, who)| (tips.timeline.source_frame(f).unwrap_or(-1), who))
                    .collect()
            })
            .unwrap_or_default();
        let hidden: std::collections::HashSet<i64> = (truth.gaps.iter())
            .filter(|g| g.tip == k)
            .flat_map(|g| g.first_frame..=g.last_frame)
            .collect();
        let mut own: Vec<(i64, f64)> = filled
            .iter()
            .filter(|(f, _)| **f >= 0 && !hidden.contains(f))
            .map(|(&f, p)| (f, p.distance(truth.position(k, truth.time_of(f)))))
            .collect();
        // In frame order: the map's order would change the sum's last bits
        // from run to run.
        own.sort_by_key(|x| x.0);
        s.own_filled.extend(own.into_iter().map(|x| x.1));
        for g in truth.gaps.iter().filter(|g| g.tip == k) {
            if let Some(mut fill) = score_gap(truth, g, &filled, &baseline[k]) {
                let (a, b) = (g.first_frame - 1, g.last_frame + 1);
                let near = (a - CLEAN_SPAN..=a).chain(b..=b + CLEAN_SPAN);
                fill.clean = owner.get(&a) == Some(&Some(k))
                    && owner.get(&b) == Some(&Some(k))
                    && near.filter_map(|f| owner.get(&f)).all(|w| *w == Some(k));
                s.fills.push(fill);
            }
        }
    }
    s
}

/// Gives each output tip the true tip most of its samples came from; the
/// first tip to claim a true tip is its match, later ones and tips made
/// mostly of ghosts are fragments. Counts wrong samples, bridged fills,
/// rest errors and missed tips into `s`; returns the match of each true tip.
fn match_tips<'a>(tips: &'a Tips, truth: &Truth, s: &mut Score) -> Vec<Option<&'a Tip>> {
    let mut claimed = vec![0usize; truth.tips.len()];
    let mut ours: Vec<Option<&Tip>> = vec![None; truth.tips.len()];
    for tip in &tips.tips {
        let mut counts: HashMap<Option<usize>, usize> = HashMap::new();
        let mut owner_at: HashMap<i64, Option<usize>> = HashMap::new();
        for (frame, who) in owners(&tip.trace, truth) {
            *counts.entry(who).or_default() += 1;
            owner_at.insert(frame, who);
        }
        let Some((owner, n)) = majority(&counts) else {
            continue;
        };
        let total: usize = counts.values().sum();
        s.wrong_samples += total - n;
        // A fill whose two ends came from different tips bridges them.
        s.bridged += tip
            .trace
            .fills()
            .iter()
            .filter(|f| owner_at.get(&f.from) != owner_at.get(&f.to))
            .count();
        let Some(k) = owner else {
            s.fragments += 1;
            continue;
        };
        claimed[k] += 1;
        if claimed[k] > 1 {
            debug_fragment(tip, k, truth);
            s.fragments += 1;
            continue;
        }
        ours[k] = Some(tip);
        s.rest_errors.push(tip.rest.distance(truth.tips[k].rest));
    }
    s.missed_tips = claimed.iter().filter(|c| **c == 0).count();
    ours
}

/// With `TRACK_DEBUG` set, says which frames a second claim on true tip
/// `k` covers: what to look at when the tracker splits a tip.
fn debug_fragment(tip: &Tip, k: usize, truth: &Truth) {
    if std::env::var_os("TRACK_DEBUG").is_some() {
        eprintln!(
            "fragment of true tip {k}: frames {}..{} measured {} rest {:?} (true {:?})",
            tip.trace.first_frame(),
            tip.trace.last_frame(),
            tip.trace.measured(),
            tip.rest,
            truth.tips[k].rest
        );
    }
}

/// The positions our tracker filled in, by source frame.
fn filled_positions(tips: &Tips, tip: &Tip) -> HashMap<i64, DVec3> {
    tip.trace
        .samples()
        .filter(|x| x.kind == SampleKind::Filled)
        .map(|x| {
            (
                tips.timeline.source_frame(x.frame).unwrap_or(-1),
                x.position,
            )
        })
        .collect()
}

/// The mean error of our fill and of the PCHIP baseline over one true gap;
/// `None` for gaps neither could fairly fill (before the wind is up, or at
/// either end of the take).
fn score_gap(
    truth: &Truth,
    g: &GapTruth,
    filled: &HashMap<i64, DVec3>,
    base: &HashMap<i64, DVec3>,
) -> Option<FillScore> {
    if truth.time_of(g.first_frame) < truth.wind.0 + truth.wind_ramp_s
        || g.first_frame == 0
        || g.last_frame + 1 >= truth.frames as i64
    {
        return None;
    }
    let k = g.tip;
    let err = |get: &dyn Fn(i64) -> Option<DVec3>| -> Option<f64> {
        let mut sum = 0.0;
        for f in g.first_frame..=g.last_frame {
            sum += get(f)?.distance(truth.position(k, truth.time_of(f)));
        }
        Some(sum / (g.last_frame - g.first_frame + 1) as f64)
    };
    Some(FillScore {
        len: g.last_frame - g.first_frame + 1,
        ours: err(&|f| filled.get(&f).copied()),
        pchip: err(&|f| base.get(&f).copied()),
        clean: false,
    })
}

/// PCHIP fills of every true tip's own samples (perfect identity), by
/// source frame.
fn pchip_baseline(tips: &Tips, syn: &Synthetic) -> Vec<HashMap<i64, DVec3>> {
    let n = syn.truth.tips.len();
    let mut traces: Vec<Option<Trace>> = (0..n).map(|_| None).collect();
    for frame in &syn.frames {
        for m in &frame.markers {
            let Some(k) =
                m.id.and_then(|c| syn.truth.columns.get(c as usize))
                    .and_then(|c| c.tip)
            else {
                continue;
            };
            match traces[k].as_mut() {
                Some(t) => t.push(frame.frame, m.position, None),
                None => traces[k] = Some(Trace::new(k, frame.frame, m.position, None)),
            }
        }
    }
    let settings = GapSettings {
        max_fill_s: 0.0,
        max_pchip_s: 1e9,
        neighbours: false,
    };
    traces
        .into_iter()
        .map(|t| {
            let Some(t) = t else { return HashMap::new() };
            let mut one = [t];
            gaps::fill_gaps(&mut one, &tips.timeline, settings);
            one[0]
                .samples()
                .filter(|x| x.kind == SampleKind::Filled)
                .map(|x| (x.frame, x.position))
                .collect()
        })
        .collect()
}

/// Smallest distance between two true tips at any frame (noiseless).
pub fn smallest_spacing(truth: &Truth) -> f64 {
    let mut best = f64::INFINITY;
    let step = (truth.frame_rate / 50.0).max(1.0) as usize;
    for f in (0..truth.frames).step_by(step) {
        let t = truth.time_of(f as i64);
        let p: Vec<_> = (0..truth.tips.len())
            .map(|k| truth.position(k, t))
            .collect();
        for i in 0..p.len() {
            for j in i + 1..p.len() {
                best = best.min(p[i].distance(p[j]));
            }
        }
    }
    best
}

/// Largest displacement of any tip from its rest position (m), sampled.
pub fn largest_sway(truth: &Truth) -> f64 {
    let step = (truth.frame_rate / 50.0).max(1.0) as usize;
    let mut best: f64 = 0.0;
    for f in (0..truth.frames).step_by(step) {
        let t = truth.time_of(f as i64);
        for k in 0..truth.tips.len() {
            best = best.max(truth.position(k, t).distance(truth.tips[k].rest));
        }
    }
    best
}
