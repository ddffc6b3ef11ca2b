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
//!
//! Nearer the course, a run can still be another tip's: two tips passing
//! each other, both hidden, and the tracker gave the one's two samples to
//! the other (`all` seed 191: tip 9 seen for two frames in a gap of
//! 0.4 s, 8.3 mm from tip 62, which was hidden too, 22 frames). Such a
//! run is judged against both courses by how far a course across a gap
//! that long misses (the tip cut out of its own samples at the gap's
//! middle, [`MISS_99`]): a run beyond what the own course misses in 99 of
//! 100 gaps that long, and within it for another tip hidden right across
//! it, could be either and is given up (seed 191's: 8.8 mm off its own
//! course across 23 frames, where 99 % miss by less than 7.1 mm; 33.2
//! mm off tip 9's across 95 frames, where 99 % miss by less than 42 mm).
//! On `all` seeds 100–179 no run of a tip's own met both (176 lay beyond
//! the own bound: none had another tip's course within its bound).

use glam::DVec3;

use super::gaps::{own_course, MAX_OWN_S, OWN_END_MAX_S};
use super::places::Places;
use crate::model::trace::{Fill, InnerRun, Timeline, Trace};

/// Samples a run holds at most to be weighed: a reflection the tracker
/// took for a hidden tip lives a few frames before the tip comes back.
const MOST: i64 = 8;

/// How far (m) a sample of the run may lie from the tip's own course
/// across the gap: 20 times the simulator's 1 mm of noise, under the
/// reflections' 25.7 and 28.7 mm; 0.2 % of the tips' own runs lie
/// farther.
const STRAY: f64 = 0.020;

/// How far (m) a tip's own course misses the tip at the middle of a gap
/// of so many seconds, in 99 of 100 gaps: measured on `all` seeds
/// 100–105 (1 mm of noise, sway up to 150 mm at 0.3–3 Hz) by cutting
/// gaps of 12–120 frames at 240 Hz into every tip's own samples, about
/// 7 000 cuts for each length. A real rig's noise is 5–10 times less, so
/// there the bound is loose: it gives fewer runs up as off their own
/// tip's course and more as within another's.
const MISS_99: [(f64, f64); 7] = [
    (0.05, 0.0048),
    (0.10, 0.0072),
    (0.15, 0.0100),
    (0.20, 0.0127),
    (0.30, 0.0239),
    (0.40, 0.0424),
    (0.50, 0.0570),
];

/// [`MISS_99`] at a gap of `secs`, straight between its rows; `None`
/// past its last row, where no bound was measured.
fn miss_99(secs: f64) -> Option<f64> {
    let (s0, m0) = MISS_99[0];
    if secs <= s0 {
        return Some(m0);
    }
    MISS_99.windows(2).find_map(|w| {
        let ((s0, m0), (s1, m1)) = (w[0], w[1]);
        (secs <= s1).then(|| m0 + (m1 - m0) * (secs - s0) / (s1 - s0))
    })
}

/// The samples of every run of up to [`MOST`] samples between two gaps
/// of a trace in `traces` (one per tip) whose whole gap, the run left
/// out, is one the gap filler fills from the tip's own samples (at most
/// [`MAX_OWN_S`]), where a sample lies farther than [`STRAY`] from that
/// fill, or farther than [`MISS_99`] while another tip hidden right
/// across the run could own it ([`Partner`]).
pub(crate) fn stray_runs(traces: &[Trace], timeline: &Timeline) -> Vec<(i64, DVec3)> {
    let dt = timeline.frame_interval().unwrap_or(1.0 / 100.0);
    let longest = (MAX_OWN_S / dt).round() as i64 + 1;
    let reach = (OWN_END_MAX_S / dt).round() as i64 + 1;
    let mut stray = Vec::new();
    // Runs beyond their own bound, with the tips hidden across them, to
    // be weighed once every trace has been read.
    let mut doubtful: Vec<Doubtful> = Vec::new();
    let mut spans: Vec<InnerRun> = Vec::new();
    let mut frames = Vec::new();
    for (k, t) in traces.iter().enumerate() {
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
            let Some(course) = course_across(&places, 0, s.before, s.after, dt) else {
                continue;
            };
            let run: Vec<(i64, DVec3)> = (s.first..=s.last)
                .filter_map(|f| Some((f, places.at(0, f)?)))
                .collect();
            let off = run
                .iter()
                .map(|&(f, p)| p.distance(course.at(f)))
                .fold(0.0, f64::max);
            if off > STRAY {
                stray.extend(run);
            } else if miss_99((s.after - s.before) as f64 * dt).is_some_and(|m| off > m) {
                doubtful.push(Doubtful {
                    partners: partners(traces, k, s, dt),
                    run,
                });
            }
        }
    }
    // The tips hidden across them were found from the measured flags
    // alone; each is decoded once, at the frames all its gaps' ends need.
    let mut wanted: Vec<Vec<i64>> = vec![Vec::new(); traces.len()];
    for p in doubtful.iter().flat_map(|d| &d.partners) {
        wanted[p.trace].extend((p.before - reach..=p.before).chain(p.after..=p.after + reach));
    }
    for w in &mut wanted {
        w.sort_unstable();
        w.dedup();
    }
    let places = Places::at_frames(traces, &wanted);
    for Doubtful { partners, run } in doubtful {
        let fits = partners.iter().any(|p| {
            course_across(&places, p.trace, p.before, p.after, dt)
                .is_some_and(|c| run.iter().all(|&(f, q)| q.distance(c.at(f)) <= p.bound))
        });
        if fits {
            stray.extend(run);
        }
    }
    stray
}

/// A run off its tip's own course by more than [`MISS_99`], within
/// [`STRAY`].
struct Doubtful {
    /// The tips hidden right across it.
    partners: Vec<Partner>,
    /// Its samples.
    run: Vec<(i64, DVec3)>,
}

/// Another tip hidden right across a run: its trace, its gap
/// (`before`..`after`, the frames measured on each side) and how far its
/// own course across that gap may miss it ([`MISS_99`]).
struct Partner {
    trace: usize,
    before: i64,
    after: i64,
    bound: f64,
}

/// The traces of `traces` other than the `own`th measured in none of the
/// frames of run `s`, in a gap of at most [`MISS_99`]'s last row around it.
fn partners(traces: &[Trace], own: usize, s: &InnerRun, dt: f64) -> Vec<Partner> {
    let longest = (MISS_99[MISS_99.len() - 1].0 / dt).round() as i64;
    let gap_of = |u: &Trace| {
        if (s.first..=s.last).any(|f| u.is_measured(f)) {
            return None;
        }
        let before = (s.first - longest..s.first)
            .rev()
            .find(|&f| u.is_measured(f))?;
        let after = (s.last + 1..=before + longest).find(|&f| u.is_measured(f))?;
        Some((before, after, miss_99((after - before) as f64 * dt)?))
    };
    traces
        .iter()
        .enumerate()
        .filter(|&(k, _)| k != own)
        .filter_map(|(k, u)| {
            let (before, after, bound) = gap_of(u)?;
            Some(Partner {
                trace: k,
                before,
                after,
                bound,
            })
        })
        .collect()
}

/// The course the gap filler draws from the tip's own samples across the
/// gap `before`..`after` of trace `k` of `places`, from its samples
/// outside the gap alone (a run inside it left out).
fn course_across(places: &Places, k: usize, before: i64, after: i64, dt: f64) -> Option<Fill> {
    let at = |f: i64| {
        (f <= before || f >= after)
            .then(|| places.at(k, f))
            .flatten()
    };
    own_course(at, before, after, dt)
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

    /// A slow tip beside the swinging one, 10 mm off its course at frames
    /// 110–111 and hidden across them from frame 70 to 165 (0.4 s).
    fn hidden_partner() -> Trace {
        let mut rng = Rng::new(11);
        let samples: Vec<(i64, DVec3, Option<i64>)> = (0..240i64)
            .filter(|f| !(70..165).contains(f))
            .map(|f| {
                let noise = DVec3::new(rng.normal(), rng.normal(), rng.normal()) * 0.0005;
                (f, partner(f) + noise, Some(1))
            })
            .collect();
        Trace::collected(1, samples).expect("samples")
    }

    fn partner(f: i64) -> DVec3 {
        place(110) + DVec3::new(0.0, 0.0, 0.010) + DVec3::new(0.0001, 0.0, 0.0) * (f - 110) as f64
    }

    /// The swinging tip hidden in frames 100–122 but for 110 and 111,
    /// where the trace holds `at` instead.
    fn holding(at: impl Fn(i64) -> DVec3) -> Trace {
        let mut rng = Rng::new(7);
        let samples: Vec<(i64, DVec3, Option<i64>)> = (0..240i64)
            .filter(|f| !(100..123).contains(f) || *f == 110 || *f == 111)
            .map(|f| {
                let noise = DVec3::new(rng.normal(), rng.normal(), rng.normal()) * 0.0005;
                let p = if f == 110 || f == 111 {
                    at(f)
                } else {
                    place(f)
                };
                (f, p + noise, Some(0))
            })
            .collect();
        Trace::collected(0, samples).expect("samples")
    }

    fn second() -> Timeline {
        Timeline {
            times: (0..240).map(|f| f as f64 / 240.0).collect(),
            anchors: vec![(0, 0)],
        }
    }

    #[test]
    fn a_run_a_hidden_partner_could_own_is_given_up() {
        // Two samples of the partner, 10 mm off the tip's own course
        // across 23 frames (99 % of such courses miss by under 7 mm) and
        // on the partner's own course across its 0.4 s gap.
        let traces = [holding(partner), hidden_partner()];
        let frames: Vec<i64> = stray_runs(&traces, &second()).iter().map(|s| s.0).collect();
        assert_eq!(frames, vec![110, 111]);
    }

    #[test]
    fn a_run_near_its_own_course_is_kept_beside_a_hidden_partner() {
        let traces = [holding(place), hidden_partner()];
        assert!(stray_runs(&traces, &second()).is_empty());
    }

    #[test]
    fn a_run_off_its_own_course_with_no_partner_near_is_kept() {
        // 10 mm off is within the 20 mm a tip's own course may miss by.
        let traces = [holding(partner)];
        assert!(stray_runs(&traces, &second()).is_empty());
    }

    #[test]
    fn the_miss_bound_runs_between_its_rows_and_ends_at_the_last() {
        assert_eq!(miss_99(0.01), Some(0.0048));
        assert!((miss_99(0.35).unwrap() - 0.03315).abs() < 1e-9);
        assert_eq!(miss_99(0.5), Some(0.0570));
        assert_eq!(miss_99(0.51), None);
    }
}
