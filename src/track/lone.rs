//! Samples a tip holds alone between two gaps, beside another marker,
//! given up.
//!
//! Where a tip's marker is hidden on both sides of a run of one to three
//! samples, the run carries no motion of its own to judge it by: no line
//! through it, no seam to either side, nothing for the neighbours' model
//! to weigh but where it sits. With another tip's marker measured beside
//! it, the run may as well be that marker's: `all` seed 335, one sample
//! of each of two partner tips exchanged 3.6 mm apart between gaps of 2
//! and 7 frames. A fill across the gap misses by about the fill's error;
//! a sample of the other marker misses by the distance between the two
//! and counts against the tip's identity. `reclaim` asks as much of a
//! run it finds after frames without one ([`MIN_RUN`] samples).
//!
//! With no other marker measured near, the run may still be a hidden
//! partner's: `all` seed 216, one sample of tip 60's marker, hidden
//! from 13 frames before to 30 after, in tip 3's gap 6 mm from where
//! tip 3 was. Where the run is, by where each tip's neighbours went,
//! is weighed for the run's own tip carried across the run and for
//! every tip hidden across it ([`hidden_partner`]); where a hidden tip
//! would be about as near as the run's own, which is which is not
//! known, and the run goes. Giving up every lone run, a marker near or
//! not, cost the fills more than it saved: most are the tip's own
//! (docs/tracking.md §4a, session 54).

use glam::DVec3;

use super::places::Places;
use super::reclaim::MIN_RUN;
use super::rejoin::MEET;
use crate::model::trace::Trace;

/// Frames missing on the longer side of a lone run at least (s; 6 frames
/// at 240 Hz): a run between two gaps of a frame or two is the marker
/// flickering, its own as often as not.
const LONGER_GAP_S: f64 = 0.025;

/// Frames missing on the shorter side at least.
const SHORTER_GAP: i64 = 2;

/// A tip hidden across a lone run is weighed as its partner when it was
/// measured within this long (s) before the run and after it: a tip's
/// place across a gap is carried from both ends by its neighbours, and
/// over longer gaps two tips' motions part too far for it to tell
/// (`all` seed 191: tip 9, hidden for 0.4 s while it passed tip 62 and
/// the two drew 120 mm apart, carried 62 mm off its marker).
const PARTNER_REACH_S: f64 = 0.5;

/// Neighbours a tip's place is carried by across a gap: the tips
/// nearest it where the gap began that were measured at both its ends
/// and through the run.
const NEIGHBOURS: usize = 4;

/// A hidden partner carried to within this many times the run's own
/// tip's miss of the run (and within [`MEET`]) leaves the run in doubt.
/// Above one: `all` seed 331, two tips 2.1 mm apart where one's sample
/// fell in the other's gap, the partner carried to 2.9 mm of it and the
/// run's own tip to 1.4 mm; two markers that near are not told apart by
/// a few millimetres of carrying. Over seeds 216, 248, 301 and 331 (660
/// lone runs with no marker near) the three runs within 2.5 times were
/// the three hidden partners'; the next nearest partner was 30.4 mm off
/// (the run's own tip 16.0 mm).
const AS_NEAR: f64 = 2.5;

/// The samples of every run of fewer than [`MIN_RUN`] samples in
/// `traces` (one trace per tip) with at least [`SHORTER_GAP`] frames
/// missing on either side and [`LONGER_GAP_S`] on one, and another tip's
/// marker measured within [`MEET`] of it within `LONGER_GAP_S` of it in
/// time (`one_second`: frames per second), or a tip hidden across it
/// about as near by its neighbours' motion ([`hidden_partner`]). A
/// trace's first and last runs are never lone: on one side nothing says
/// the marker was hidden. With neither, the run can only be the tip's
/// own (or a reflection, which fits no tip): under occlusion alone,
/// giving up every such run made the fills of 1–10 frames worse than
/// PCHIP's (seeds 103–109, 0.32 against 0.31 mm), for the samples given
/// up split a hole the fill then spans whole.
pub(crate) fn lone_runs(traces: &[Trace], one_second: i64) -> Vec<(i64, DVec3)> {
    let longer = ((LONGER_GAP_S * one_second as f64).round() as i64).max(SHORTER_GAP);
    // The candidates, found on the measured flags alone: most captures
    // have none, and their samples are then never decoded here.
    let mut spans: Vec<Span> = Vec::new();
    for (k, t) in traces.iter().enumerate() {
        for r in t.inner_runs() {
            let (before, after) = (r.first - r.before - 1, r.after - r.last - 1);
            if ((r.last - r.first + 1) as usize) < MIN_RUN
                && before.min(after) >= SHORTER_GAP
                && before.max(after) >= longer
            {
                spans.push(Span {
                    trace: k,
                    before: r.before,
                    first: r.first,
                    last: r.last,
                    after: r.after,
                });
            }
        }
    }
    if spans.is_empty() {
        return Vec::new();
    }
    let partners = partners_of(traces, &spans, one_second);
    // Every trace's samples where a run's neighbourhood is looked at
    // (within `longer` of it), and where each tip's place is weighed:
    // its gap's ends and the run's frames. One pass decodes each trace
    // once, up to the last of these frames only (decoding every trace
    // twice cost the cleaning of pine-35 about 5 ms; an hour's take
    // never holds all its samples decoded at once).
    let mut frames: Vec<i64> = Vec::new();
    for s in &spans {
        frames.extend(s.first - longer..=s.last + longer);
        frames.extend([s.before, s.after]);
    }
    frames.extend(partners.iter().flat_map(|p| [p.before, p.after]));
    frames.sort_unstable();
    frames.dedup();
    let places = Places::shared(traces, &frames);
    let mut partners = partners.into_iter().peekable();
    let mut lone = Vec::new();
    for (r, s) in spans.iter().enumerate() {
        let run: Vec<(i64, DVec3)> = (s.first..=s.last)
            .filter_map(|f| Some((f, places.at(s.trace, f)?)))
            .collect();
        let mine: Vec<Partner> = std::iter::from_fn(|| partners.next_if(|p| p.run == r)).collect();
        if near(&places, s, &run, longer)
            || hidden_partner(&places, s.trace, &run, (s.before, s.after), &mine)
        {
            lone.extend(run);
        }
    }
    lone
}

/// A candidate run: one to three samples of a tip between two gaps.
struct Span {
    /// The tip's trace.
    trace: usize,
    /// The last frame measured before the run.
    before: i64,
    /// The run's first frame.
    first: i64,
    /// Its last frame.
    last: i64,
    /// The first frame measured after it.
    after: i64,
}

/// Whether another tip's marker was measured within [`MEET`] of the run
/// `run` of span `s` within `longer` frames of it.
fn near(places: &Places, s: &Span, run: &[(i64, DVec3)], longer: i64) -> bool {
    (0..places.len()).filter(|&k| k != s.trace).any(|k| {
        (s.first - longer..=s.last + longer)
            .filter_map(|f| places.at(k, f))
            .any(|p| run.iter().any(|q| q.1.distance(p) <= MEET))
    })
}

/// A tip hidden across a lone run, whose marker the run may be.
struct Partner {
    /// The run (its index among the spans).
    run: usize,
    /// The tip's trace.
    trace: usize,
    /// The last frame the tip was measured before the run.
    before: i64,
    /// The first frame it was measured after the run.
    after: i64,
}

/// The tips hidden across each run that were measured within
/// [`PARTNER_REACH_S`] on both sides of it, by run. Found on the
/// measured flags.
fn partners_of(traces: &[Trace], spans: &[Span], one_second: i64) -> Vec<Partner> {
    let reach = (PARTNER_REACH_S * one_second as f64).round() as i64;
    let mut partners = Vec::new();
    for (r, s) in spans.iter().enumerate() {
        let (first, last) = (s.first, s.last);
        for (p, t) in traces.iter().enumerate() {
            if p == s.trace || (first..=last).any(|f| t.is_measured(f)) {
                continue;
            }
            let a = (1..=reach).map(|d| first - d).find(|&f| t.is_measured(f));
            let b = (1..=reach).map(|d| last + d).find(|&f| t.is_measured(f));
            if let (Some(before), Some(after)) = (a, b) {
                partners.push(Partner {
                    run: r,
                    trace: p,
                    before,
                    after,
                });
            }
        }
    }
    partners
}

/// Whether a tip hidden across the run `run` of trace `k` (its gap
/// around the run from `before` to `after`) would be about as near the
/// run as `k`'s own tip, each carried across its gap by its neighbours
/// ([`carried_miss`]): a partner within [`MEET`] and [`AS_NEAR`] times
/// the own tip's miss.
fn hidden_partner(
    places: &Places,
    k: usize,
    run: &[(i64, DVec3)],
    (before, after): (i64, i64),
    partners: &[Partner],
) -> bool {
    if partners.is_empty() {
        return false;
    }
    let Some(own) = carried_miss(places, k, k, run, (before, after)) else {
        return false;
    };
    partners.iter().any(|p| {
        carried_miss(places, p.trace, k, run, (p.before, p.after))
            .is_some_and(|m| m < MEET && m < AS_NEAR * own)
    })
}

/// How far (m, mean over the run) trace `t`'s tip would be from the run
/// `run` of trace `holder`, carried across its gap from frame `a` to
/// frame `b` by its [`NEIGHBOURS`]: at each frame, a neighbour's
/// position plus the tip's offset from it, turned linearly from the one
/// at `a` to the one at `b`. The tips of a tree sway together; what
/// parts them changes slowly. `None` when `t` or no neighbour was
/// measured where needed.
fn carried_miss(
    places: &Places,
    t: usize,
    holder: usize,
    run: &[(i64, DVec3)],
    (a, b): (i64, i64),
) -> Option<f64> {
    let (ta, tb) = (places.at(t, a)?, places.at(t, b)?);
    // (distance at `a`, position at `a`, at `b`, through the run).
    let mut neighbours: Vec<(f64, DVec3, DVec3, Vec<DVec3>)> = (0..places.len())
        .filter(|&n| n != t && n != holder)
        .filter_map(|n| {
            let (na, nb) = (places.at(n, a)?, places.at(n, b)?);
            let through: Option<Vec<DVec3>> = run.iter().map(|s| places.at(n, s.0)).collect();
            Some((na.distance(ta), na, nb, through?))
        })
        .collect();
    if neighbours.is_empty() {
        return None;
    }
    neighbours.sort_by(|x, y| x.0.total_cmp(&y.0));
    neighbours.truncate(NEIGHBOURS);
    let span = (b - a) as f64;
    let miss: f64 = run
        .iter()
        .enumerate()
        .map(|(i, &(f, p))| {
            let w = (f - a) as f64 / span;
            let sum: DVec3 = neighbours
                .iter()
                .map(|(_, na, nb, through)| through[i] + (ta - *na).lerp(tb - *nb, w))
                .sum();
            (sum / neighbours.len() as f64).distance(p)
        })
        .sum();
    Some(miss / run.len() as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A trace measured in `frames`, moving 1 mm a frame in x, `off` (m)
    /// aside in y.
    fn trace(frames: &[i64], off: f64) -> Trace {
        let at = |f: i64| DVec3::new(f as f64 * 0.001, off, 0.0);
        let mut t = Trace::new(0, frames[0], at(frames[0]), None);
        for &f in &frames[1..] {
            t.push(f, at(f), None);
        }
        t
    }

    /// The frames given up of a tip measured in `frames`, beside a
    /// partner `off` (m) away measured up to frame 12 (hidden after it).
    fn lone_frames(frames: &[i64], off: f64) -> Vec<i64> {
        let partner: Vec<i64> = (0..=12).collect();
        let traces = [trace(frames, 0.0), trace(&partner, off)];
        lone_runs(&traces, 240).iter().map(|s| s.0).collect()
    }

    /// A tip measured up to frame 10, in `run`, then from frame 40.
    fn with(run: std::ops::RangeInclusive<i64>) -> Vec<i64> {
        let mut frames: Vec<i64> = (0..=10).collect();
        frames.extend(run);
        frames.extend(40..=60);
        frames
    }

    #[test]
    fn a_sample_alone_between_two_gaps_beside_another_marker_is_lone() {
        // 2 frames missing before 13, 7 after it, the partner 3.6 mm away
        // a frame before (`all` seed 335).
        let mut frames: Vec<i64> = (0..=10).collect();
        frames.push(13);
        frames.extend(21..=40);
        assert_eq!(lone_frames(&frames, 0.0036), vec![13]);
        // With no marker within 20 mm it can only be the tip's own.
        assert_eq!(lone_frames(&frames, 0.05), Vec::<i64>::new());
    }

    /// A tree swaying 50 mm at 1.5 Hz: four neighbours 0.1 m apart
    /// measured throughout, the tip at the origin measured up to frame
    /// 20, at 30 (the run, `run_at` off its own place) and from 40, and
    /// a partner `partner_off` (m) along x hidden from frame 15 to 50.
    /// The frames given up.
    fn in_a_swaying_tree(partner_off: f64, run_at: DVec3) -> Vec<i64> {
        let sway = |f: i64| {
            let s = (f as f64 / 240.0 * 1.5 * std::f64::consts::TAU).sin();
            DVec3::new(0.05 * s, 0.02 * s, 0.0)
        };
        let trace = |frames: Vec<i64>, off: DVec3| {
            let mut t = Trace::new(0, frames[0], sway(frames[0]) + off, None);
            for &f in &frames[1..] {
                t.push(f, sway(f) + off, None);
            }
            t
        };
        let mut tip = trace((0..=20).collect(), DVec3::ZERO);
        tip.push(30, sway(30) + run_at, None);
        for f in 40..=80 {
            tip.push(f, sway(f), None);
        }
        let hidden: Vec<i64> = (0..=14).chain(51..=80).collect();
        let mut traces = vec![tip, trace(hidden, DVec3::new(partner_off, 0.0, 0.0))];
        for i in 1..=4 {
            traces.push(trace(
                (0..=80).collect(),
                DVec3::new(0.1 * i as f64, 0.2, 0.0),
            ));
        }
        lone_runs(&traces, 240).iter().map(|s| s.0).collect()
    }

    #[test]
    fn a_sample_where_a_hidden_partner_would_be_is_lone() {
        // The partner's marker, 30 mm from where the tip was: no marker
        // is measured near, but the partner's neighbours put it there.
        assert_eq!(
            in_a_swaying_tree(0.03, DVec3::new(0.03, 0.0, 0.0)),
            vec![30]
        );
        // The tip's own marker, 30 mm from the partner: kept.
        assert_eq!(in_a_swaying_tree(0.03, DVec3::ZERO), Vec::<i64>::new());
        // Two tips 2 mm apart, the sample 1.2 mm from the tip's own place
        // and 0.8 mm from the partner's: neither is known.
        assert_eq!(
            in_a_swaying_tree(0.002, DVec3::new(0.0012, 0.0, 0.0)),
            vec![30]
        );
        // The tip hidden across it 0.5 m away: the run, 10 mm off the
        // tip's place, is its own.
        assert_eq!(
            in_a_swaying_tree(0.5, DVec3::new(0.01, 0.0, 0.0)),
            Vec::<i64>::new()
        );
    }

    #[test]
    fn three_samples_are_lone_four_are_not() {
        assert_eq!(lone_frames(&with(14..=16), 0.004), vec![14, 15, 16]);
        assert_eq!(lone_frames(&with(14..=17), 0.004), Vec::<i64>::new());
    }

    #[test]
    fn runs_between_short_gaps_or_at_the_ends_are_not_lone() {
        // A frame missing on one side, or 5 on both: the marker flickered.
        assert_eq!(lone_frames(&with(12..=12), 0.004), Vec::<i64>::new());
        let mut frames: Vec<i64> = (0..=6).collect();
        frames.push(12);
        frames.extend(18..=30);
        assert_eq!(lone_frames(&frames, 0.004), Vec::<i64>::new());
        // The first and last runs: nothing says the marker was hidden
        // on their outer side.
        assert_eq!(
            lone_frames(&[8, 20, 21, 22, 23, 24, 30], 0.004),
            Vec::<i64>::new()
        );
    }
}
