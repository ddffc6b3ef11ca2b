//! Short runs a tip holds alone between two gaps, far off the tip's own
//! course across them: given up.
//!
//! A reflection that sits still where a tip was hidden can be taken for
//! the tip for a frame or a few, with no other marker near it and no tip
//! hidden about it (`all` seed 301: one sample between gaps of 10 and 31
//! frames; seed 126: four between gaps of 30 and 9), so neither test of
//! `lone.rs` sees it. The tip went on swaying while it was hidden: the
//! course the gap filler draws across the whole gap from the tip's own
//! samples at its two ends misses the reflections by 28.7 and 25.7 mm.
//!
//! It does not tell them apart from every run of the tip's own. On
//! `all` seeds 100–139, of 8 543 runs of up to eight samples across gaps
//! the filler draws from the tip's own samples (up to 0.21 s), 99.8 %
//! lie within 20 mm of that course, but 13 of the tips' own lie farther
//! (up to 52.9 mm, a twig swinging fast through a gap of 0.2 s) beside
//! seed 126's reflection. Giving a run up costs little: its samples are
//! filled with the rest of the gap and flagged as filled, where a
//! reflection kept is a sample of no marker of the tip's, unflagged.
//! Over the 306 sweep seeds it took out the reflections of seeds 126 and
//! 301, and with them 410 of the tips' own samples, filled instead
//! (docs/tracking.md §4a, session 57).
//! Longer gaps are filled from the neighbours; there the test is not
//! made.

use glam::DVec3;

use super::gaps::{own_course, MAX_OWN_S, OWN_END_MAX_S};
use super::places::Places;
use crate::model::trace::{InnerRun, Timeline, Trace};

/// Samples a run holds at most to be weighed: a reflection the tracker
/// took for a hidden tip lives a few frames before the tip comes back.
const MOST: i64 = 8;

/// How far (m) a sample of the run may lie from the tip's own course
/// across the gap: 20 times the simulator's 1 mm of noise, under the
/// reflections' 25.7 and 28.7 mm; 0.2 % of the tips' own runs lie
/// farther.
const STRAY: f64 = 0.020;

/// The samples of every run of up to [`MOST`] samples between two gaps
/// of a trace in `traces` (one per tip) whose whole gap, the run left
/// out, is one the gap filler fills from the tip's own samples (at most
/// [`MAX_OWN_S`]), where a sample lies farther than [`STRAY`] from that
/// fill.
pub(crate) fn stray_runs(traces: &[Trace], timeline: &Timeline) -> Vec<(i64, DVec3)> {
    let dt = timeline.frame_interval().unwrap_or(1.0 / 100.0);
    let longest = (MAX_OWN_S / dt).round() as i64 + 1;
    let reach = (OWN_END_MAX_S / dt).round() as i64 + 1;
    let mut stray = Vec::new();
    let mut spans: Vec<InnerRun> = Vec::new();
    let mut frames = Vec::new();
    for t in traces {
        spans.clear();
        spans.extend(
            t.inner_runs()
                .filter(|r| r.last - r.first < MOST && r.after - r.before <= longest),
        );
        if spans.is_empty() {
            continue;
        }
        // The trace read once, at the frames its runs and their ends
        // need, and one trace at a time: an hour's take with a marker
        // hidden every few seconds holds tens of thousands of runs.
        frames.clear();
        for s in &spans {
            frames.extend(s.before - reach..=s.before);
            frames.extend(s.first..=s.last);
            frames.extend(s.after..=s.after + reach);
        }
        frames.sort_unstable();
        frames.dedup();
        let places = Places::at_frames(std::slice::from_ref(t), std::slice::from_ref(&frames));
        for s in &spans {
            let at = |f: i64| {
                (f <= s.before || f >= s.after)
                    .then(|| places.at(0, f))
                    .flatten()
            };
            let Some(course) = own_course(at, s.before, s.after, dt) else {
                continue;
            };
            let run: Vec<(i64, DVec3)> = (s.first..=s.last)
                .filter_map(|f| Some((f, places.at(0, f)?)))
                .collect();
            if run.iter().any(|&(f, p)| p.distance(course.at(f)) > STRAY) {
                stray.extend(run);
            }
        }
    }
    stray
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    /// A tip swinging 60 mm at 1.5 Hz, sampled at 240 Hz for 1 s under
    /// 0.5 mm of noise, hidden in frames 100–139 but for frame `held`,
    /// where the trace holds `at(held)` instead.
    fn swinging(held: i64, at: impl Fn(i64) -> DVec3) -> (Trace, Timeline) {
        let mut rng = Rng::new(7);
        let samples: Vec<(i64, DVec3, Option<i64>)> = (0..240i64)
            .filter(|f| !(100..140).contains(f) || *f == held)
            .map(|f| {
                let noise = DVec3::new(rng.normal(), rng.normal(), rng.normal()) * 0.0005;
                let p = if f == held { at(f) } else { place(f) };
                (f, p + noise, Some(0))
            })
            .collect();
        let trace = Trace::collected(0, samples).expect("samples");
        let timeline = Timeline {
            times: (0..240).map(|f| f as f64 / 240.0).collect(),
            anchors: vec![(0, 0)],
        };
        (trace, timeline)
    }

    fn place(f: i64) -> DVec3 {
        let t = f as f64 / 240.0;
        DVec3::new(
            1.0 + 0.06 * (std::f64::consts::TAU * 1.5 * t).sin(),
            1.5,
            0.2,
        )
    }

    #[test]
    fn a_still_reflection_where_the_tip_was_hidden_is_given_up() {
        // Still where the tip went hidden; by frame 120 the tip has swung
        // 31 mm on.
        let (trace, timeline) = swinging(120, |_| place(99));
        let stray = stray_runs(std::slice::from_ref(&trace), &timeline);
        assert_eq!(stray.iter().map(|s| s.0).collect::<Vec<_>>(), vec![120]);
    }

    #[test]
    fn the_tips_own_sample_in_its_gap_is_kept() {
        let (trace, timeline) = swinging(120, place);
        assert!(stray_runs(std::slice::from_ref(&trace), &timeline).is_empty());
    }
}
