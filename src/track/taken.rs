//! The last or first samples of a tip's run, next to its gap, measured in
//! exactly the frames another tip's marker went missing: given up.
//!
//! Where a tip's marker goes hidden beside another tip's, the tracker's
//! trace for it may take the other marker for a frame or two before it
//! coasts, and the other trace, its marker taken, coasts those frames
//! and finds it again (`all` seed 363: tips 49 and 68 4.5 mm apart, tip
//! 49 hidden from frame 4 941; its trace held tip 68's marker in 4 941
//! and 4 942, the frames tip 68's own trace missed between two samples).
//! The two markers were never both measured there, so the vector
//! between them (`untangle`) says nothing, and the run they ended is
//! long, so it is not lone (`lone`). What tells is the other trace's
//! gap: a tip's marker hidden for exactly the frames another trace's
//! run went on into its own gap, its line across those frames passing
//! nearer the samples than the run's own line carried on. Which marker
//! they are is not known for sure, two markers that close; given up,
//! both tips' gaps there are filled.

use glam::DVec3;

use super::places::Places;
use super::rejoin::MEET;
use crate::model::trace::Trace;

/// Samples at most at a run's end taken from another marker: the
/// tracker coasts a trace whose marker is taken for a frame or two.
const MOST: i64 = 3;

/// A candidate end: trace `run`'s samples `first..=last`, in the frames
/// trace `gap` missed between two samples.
struct End {
    /// The trace whose run ends (or begins) with the samples.
    run: usize,
    /// The trace missing exactly those frames.
    gap: usize,
    /// The samples' first frame.
    first: i64,
    /// Their last frame.
    last: i64,
    /// +1: the run's last samples, a gap after them; −1: its first, a
    /// gap before.
    side: i64,
}

/// The samples of every run's end of one to [`MOST`] samples, next to
/// the run's gap, measured in exactly the frames another trace missed
/// between two samples, where that trace's line across them passes
/// within [`MEET`] of them and nearer than the run's own line carried
/// on from its two samples before them (after them, at a run's first
/// samples). The run must be two samples longer than its end, for
/// its own line.
pub(crate) fn taken_ends(traces: &[Trace]) -> Vec<(i64, DVec3)> {
    let ends = candidates(traces);
    if ends.is_empty() {
        return Vec::new();
    }
    // The run's samples at each end and its two on the inner side; the
    // other trace's on each side of its gap. Only these traces are
    // decoded: most captures have few candidates.
    let mut frames: Vec<Vec<i64>> = vec![Vec::new(); traces.len()];
    for e in &ends {
        frames[e.run].extend(e.first - 2..=e.last + 2);
        frames[e.gap].extend([e.first - 1, e.last + 1]);
    }
    for f in &mut frames {
        f.sort_unstable();
        f.dedup();
    }
    let places = Places::at_frames(traces, &frames);
    let mut taken = Vec::new();
    for e in &ends {
        let (Some(a), Some(b)) = (places.at(e.gap, e.first - 1), places.at(e.gap, e.last + 1))
        else {
            continue;
        };
        // The run's own two samples on the end's inner side.
        let (near, far) = if e.side > 0 {
            (e.first - 1, e.first - 2)
        } else {
            (e.last + 1, e.last + 2)
        };
        let (Some(p1), Some(p2)) = (places.at(e.run, near), places.at(e.run, far)) else {
            continue;
        };
        let span = (e.last - e.first + 2) as f64;
        let (mut across, mut on) = (0.0, 0.0);
        let mut samples = Vec::new();
        for f in e.first..=e.last {
            let Some(p) = places.at(e.run, f) else {
                continue;
            };
            across += a.lerp(b, (f - e.first + 1) as f64 / span).distance(p);
            on += (p1 + (p1 - p2) * (f - near).abs() as f64).distance(p);
            samples.push((f, p));
        }
        let n = samples.len().max(1) as f64;
        if across / n < MEET && across < on {
            taken.extend(samples);
        }
    }
    taken
}

/// Every run's end of one to [`MOST`] samples next to its gap, with each
/// other trace that missed exactly those frames between two samples:
/// found on the measured flags alone.
fn candidates(traces: &[Trace]) -> Vec<End> {
    let mut ends = Vec::new();
    for (k, t) in traces.iter().enumerate() {
        for (first, last) in t.measured_runs() {
            for m in 1..=MOST {
                if last - first + 1 < m + 2 {
                    break;
                }
                // The run's last m samples, a gap (or the trace's end)
                // after them; its first m, a gap (or its start) before.
                for (side, from) in [(1, last - m + 1), (-1, first)] {
                    let to = from + m - 1;
                    for (g, u) in traces.iter().enumerate() {
                        if g != k
                            && u.is_measured(from - 1)
                            && u.is_measured(to + 1)
                            && (from..=to).all(|f| !u.is_measured(f))
                        {
                            ends.push(End {
                                run: k,
                                gap: g,
                                first: from,
                                last: to,
                                side,
                            });
                        }
                    }
                }
            }
        }
    }
    ends
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two tips 4 mm apart swaying together (40 mm at 1 Hz): tip a
    /// measured up to frame 20, then in 21 and 22 at `a_end` (its own
    /// place or tip b's), hidden until 41; tip b measured throughout
    /// but in `b_gap`. The frames given up.
    fn taken(a_end: char, b_gap: std::ops::RangeInclusive<i64>) -> Vec<i64> {
        let at = |f: i64, off: f64| {
            let s = (f as f64 / 240.0 * std::f64::consts::TAU).sin();
            DVec3::new(0.04 * s + off, 0.01 * s, 0.0)
        };
        let mut a = Trace::new(0, 0, at(0, 0.0), None);
        for f in 1..=22 {
            let off = if f > 20 && a_end == 'b' { 0.004 } else { 0.0 };
            a.push(f, at(f, off), None);
        }
        for f in 41..=60 {
            a.push(f, at(f, 0.0), None);
        }
        let mut b = Trace::new(1, 0, at(0, 0.004), None);
        for f in (1..=60).filter(|f| !b_gap.contains(f)) {
            b.push(f, at(f, 0.004), None);
        }
        let mut frames: Vec<i64> = taken_ends(&[a, b]).iter().map(|s| s.0).collect();
        frames.sort_unstable();
        frames
    }

    #[test]
    fn a_runs_end_in_exactly_the_frames_another_marker_went_missing_is_taken() {
        // Tip b's marker, in the two frames b's trace missed: given up.
        assert_eq!(taken('b', 21..=22), vec![21, 22]);
        // Tip a's own marker, b missing those frames by chance: a's own
        // line carried on fits it, b's misses by 4 mm.
        assert_eq!(taken('a', 21..=22), Vec::<i64>::new());
        // b missed a frame more than a's end holds: not those frames.
        assert_eq!(taken('b', 21..=23), Vec::<i64>::new());
        // b missed nothing: a's run ended with its own frames.
        assert_eq!(taken('b', 99..=99), Vec::<i64>::new());
    }
}
