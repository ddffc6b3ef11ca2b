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
//! Runs with no other marker near stay, though some are a hidden
//! partner's (`all` seeds 216 and 331: a trace begun on the partner's
//! marker a frame before it found its own, 7 frames later; seed 248:
//! 3 samples of tip 63's marker inside tip 18's gap): giving up every
//! lone run cost the fills more than it saved (below, and
//! docs/tracking.md §4a, session 54).

use glam::DVec3;

use super::reclaim::MIN_RUN;
use super::rejoin::MEET;
use crate::model::trace::Trace;

/// Frames missing on the longer side of a lone run at least (s; 6 frames
/// at 240 Hz): a run between two gaps of a frame or two is the marker
/// flickering, its own as often as not.
const LONGER_GAP_S: f64 = 0.025;

/// Frames missing on the shorter side at least.
const SHORTER_GAP: i64 = 2;

/// The samples of every run of fewer than [`MIN_RUN`] samples in
/// `traces` (one trace per tip) with at least [`SHORTER_GAP`] frames
/// missing on either side and [`LONGER_GAP_S`] on one, and another tip's
/// marker measured within [`MEET`] of it within `LONGER_GAP_S` of it in
/// time (`one_second`: frames per second). A trace's first and last runs
/// are never lone: on one side nothing says the marker was hidden. With
/// no other marker near, the run can only be the tip's own (or a
/// reflection, which fits no tip): under occlusion alone, giving up
/// every such run made the fills of 1–10 frames worse than PCHIP's
/// (seeds 103–109, 0.32 against 0.31 mm), for the samples given up
/// split a hole the fill then spans whole.
pub(crate) fn lone_runs(traces: &[Trace], one_second: i64) -> Vec<(i64, DVec3)> {
    let longer = ((LONGER_GAP_S * one_second as f64).round() as i64).max(SHORTER_GAP);
    // The candidates' frames (trace, first, last), found on the
    // measured flags alone: most captures have none, and their samples
    // are then never decoded here (decoding every trace twice cost the
    // cleaning of pine-35 about 5 ms).
    let mut spans: Vec<(usize, i64, i64)> = Vec::new();
    for (k, t) in traces.iter().enumerate() {
        // The last frame of the run before the current one, and the
        // current run's first frame.
        let mut before_end: Option<i64> = None;
        let mut first = t.first_frame();
        loop {
            // The current run ends at the frame before the next missing.
            let mut last = first;
            while last < t.last_frame() && t.is_measured(last + 1) {
                last += 1;
            }
            let mut next = last + 1;
            while next <= t.last_frame() && !t.is_measured(next) {
                next += 1;
            }
            if next > t.last_frame() {
                break; // the last run: no gap after it
            }
            if let Some(end) = before_end {
                let (before, after) = (first - end - 1, next - last - 1);
                if ((last - first + 1) as usize) < MIN_RUN
                    && before.min(after) >= SHORTER_GAP
                    && before.max(after) >= longer
                {
                    spans.push((k, first, last));
                }
            }
            before_end = Some(last);
            first = next;
        }
    }
    if spans.is_empty() {
        return Vec::new();
    }
    // Their samples, with the trace that holds them.
    let mut runs: Vec<(usize, Vec<(i64, DVec3)>)> = Vec::with_capacity(spans.len());
    let mut by_trace = spans.iter().peekable();
    for (k, t) in traces.iter().enumerate() {
        if by_trace.peek().is_none_or(|s| s.0 != k) {
            continue;
        }
        let mine: Vec<(i64, i64)> = std::iter::from_fn(|| by_trace.next_if(|s| s.0 == k))
            .map(|s| (s.1, s.2))
            .collect();
        let mut at = 0;
        let mut held: Vec<(i64, DVec3)> = Vec::new();
        for (f, p) in t.measurements() {
            while at < mine.len() && f > mine[at].1 {
                runs.push((k, std::mem::take(&mut held)));
                at += 1;
            }
            if at == mine.len() {
                break;
            }
            if f >= mine[at].0 {
                held.push((f, p));
            }
        }
        if at < mine.len() {
            runs.push((k, held));
        }
    }
    // Each run's window of frames (first, last, run), by first frame; a
    // second pass over every trace's samples marks the runs another
    // marker came near (one trace decoded at a time, as above: an hour's
    // take never holds all its samples decoded at once).
    let mut windows: Vec<(i64, i64, usize)> = runs
        .iter()
        .enumerate()
        .map(|(r, (_, s))| (s[0].0 - longer, s[s.len() - 1].0 + longer, r))
        .collect();
    windows.sort_unstable();
    let widest = windows.iter().map(|w| w.1 - w.0).max().unwrap_or(0);
    // Past the last window no sample matters: each trace is decoded up to
    // there only.
    let end = windows.iter().map(|w| w.1).max().unwrap_or(i64::MIN);
    let mut near = vec![false; runs.len()];
    for (k, t) in traces.iter().enumerate() {
        for (f, p) in t.measurements().take_while(|s| s.0 <= end) {
            let first = windows.partition_point(|w| w.0 < f - widest);
            for &(_, to, r) in windows[first..].iter().take_while(|w| w.0 <= f) {
                let (holder, run) = &runs[r];
                if to >= f && *holder != k && !near[r] {
                    near[r] = run.iter().any(|s| s.1.distance(p) <= MEET);
                }
            }
        }
    }
    runs.into_iter()
        .zip(near)
        .filter(|(_, n)| *n)
        .flat_map(|((_, run), _)| run)
        .collect()
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
