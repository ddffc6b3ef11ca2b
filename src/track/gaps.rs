//! Gap interpolation (paper §4, spec §3).
//!
//! A gap inside a trace (missing frames between two measurements) is filled
//! by a cubic Hermite segment whose end slopes are chosen as in PCHIP
//! (Fritsch–Carlson): per axis, the weighted harmonic mean of the secant
//! across the gap and the one-sided secant next to it, or zero where the two
//! disagree in sign. That curve never overshoots the end values where the
//! data are monotone, so a fill cannot invent a swing the marker did not
//! make. With fewer than two measurements on a side the fill is linear.
//!
//! Gaps longer than `max_fill_s` stay missing, and so does a gap whose far
//! end is implausible: further than `max_jump_mm` from a linear
//! extrapolation of the motion on *both* sides (a marker cannot teleport;
//! such a gap usually hides a wrong join).

use glam::DVec3;
use serde::Serialize;

use crate::model::trace::Timeline;
use crate::model::trace::{Fill, Trace};

/// What gap filling did, for the summary.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct GapStats {
    /// Gaps filled and the frames in them.
    pub filled: u64,
    /// Frames inside the filled gaps.
    pub filled_frames: u64,
    /// Gaps left open because they were longer than `max_fill_s`.
    pub too_long: u64,
    /// Frames inside the gaps left open as too long.
    pub too_long_frames: u64,
    /// Gaps left open because of an implausible jump across them.
    pub rejected_jump: u64,
    /// Frames inside the gaps left open for a jump.
    pub rejected_jump_frames: u64,
}

/// Settings of gap filling, from `[tracking]`.
#[derive(Debug, Clone, Copy)]
pub struct GapSettings {
    /// Longest gap filled (s); longer gaps stay missing and are reported.
    pub max_fill_s: f64,
    /// Largest distance (m) between the far side of a gap and a linear
    /// extrapolation from the near side; beyond it the two sides are taken
    /// for different markers and the gap is not filled.
    pub max_jump_m: f64,
}

/// How many measured neighbours the one-sided slope is averaged over:
/// a one-frame difference carries the full measurement noise.
const SLOPE_SPAN: usize = 3;

/// Fills every gap of `trace` that qualifies; returns what it did.
pub fn fill_gaps(trace: &mut Trace, timeline: &Timeline, settings: GapSettings) -> GapStats {
    let mut stats = GapStats::default();
    // Recent measurements before the current gap, newest last.
    let mut before: Vec<(i64, DVec3)> = Vec::with_capacity(SLOPE_SPAN + 2);
    let mut pending: Option<PendingGap> = None;
    let mut gaps: Vec<PendingGap> = Vec::new();
    // One pass collects each gap with up to SLOPE_SPAN + 1 contiguous
    // measurements on either side.
    for (f, p) in trace.measurements() {
        let is_gap = before.last().is_some_and(|l| f > l.0 + 1);
        if let Some(g) = pending.as_mut() {
            if is_gap || g.right.len() > SLOPE_SPAN {
                gaps.extend(pending.take());
            } else {
                g.right.push((f, p));
            }
        }
        if is_gap {
            pending = Some(PendingGap {
                left: std::mem::take(&mut before),
                right: vec![(f, p)],
            });
        }
        before.push((f, p));
        if before.len() > SLOPE_SPAN + 1 {
            before.remove(0);
        }
    }
    gaps.extend(pending.take());

    let mut fills = Vec::with_capacity(gaps.len());
    for g in gaps {
        let (Some(&(a, pa)), Some(&(b, pb))) = (g.left.last(), g.right.first()) else {
            continue;
        };
        let missing = (b - a - 1) as u64;
        let dt = (timeline.time(b) - timeline.time(a)) / (b - a) as f64;
        if missing as f64 * dt > settings.max_fill_s + 1e-9 {
            stats.too_long += 1;
            stats.too_long_frames += missing;
            continue;
        }
        let h = (b - a) as f64;
        let secant = (pb - pa) / h;
        let left = side_slope(&g.left);
        let right = side_slope(&g.right);
        // Linear extrapolations across the gap, from each side.
        let from_left = pa + left.map_or(DVec3::ZERO, |(v, _)| v) * h;
        let from_right = pb - right.map_or(DVec3::ZERO, |(v, _)| v) * h;
        if from_left.distance(pb) > settings.max_jump_m
            && from_right.distance(pa) > settings.max_jump_m
        {
            stats.rejected_jump += 1;
            stats.rejected_jump_frames += missing;
            continue;
        }
        let (m0, m1) = match (left, right) {
            (Some((dl, hl)), Some((dr, hr))) => (
                pchip_slope(dl, hl, secant, h),
                pchip_slope(secant, h, dr, hr),
            ),
            _ => (secant, secant),
        };
        fills.push(Fill {
            from: a,
            to: b,
            p0: pa,
            m0,
            p1: pb,
            m1,
        });
        stats.filled += 1;
        stats.filled_frames += missing;
    }
    for f in fills {
        trace.add_fill(f);
    }
    stats
}

struct PendingGap {
    left: Vec<(i64, DVec3)>,
    right: Vec<(i64, DVec3)>,
}

/// The secant over the contiguous measurements of one side (m per frame)
/// and the frame span it covers; `None` with fewer than two.
fn side_slope(side: &[(i64, DVec3)]) -> Option<(DVec3, f64)> {
    let (first, last) = (side.first()?, side.last()?);
    if side.len() < 2 || last.0 <= first.0 {
        return None;
    }
    let span = (last.0 - first.0) as f64;
    Some(((last.1 - first.1) / span, span))
}

/// Fritsch–Carlson slope at the knot between an interval of width `h1`
/// with secant `d1` and one of width `h2` with secant `d2`, per axis.
fn pchip_slope(d1: DVec3, h1: f64, d2: DVec3, h2: f64) -> DVec3 {
    let axis = |a: f64, b: f64| {
        if a * b <= 0.0 {
            0.0
        } else {
            let w1 = 2.0 * h2 + h1;
            let w2 = h2 + 2.0 * h1;
            (w1 + w2) / (w1 / a + w2 / b)
        }
    };
    DVec3::new(axis(d1.x, d2.x), axis(d1.y, d2.y), axis(d1.z, d2.z))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::trace::SampleKind;

    fn timeline(n: usize) -> Timeline {
        Timeline {
            times: (0..n).map(|i| i as f64 / 100.0).collect(),
            anchors: vec![(0, 0)],
        }
    }

    fn settings() -> GapSettings {
        GapSettings {
            max_fill_s: 0.5,
            max_jump_m: 0.04,
        }
    }

    fn trace_of(f: impl Fn(i64) -> DVec3, frames: impl IntoIterator<Item = i64>) -> Trace {
        let mut it = frames.into_iter();
        let first = it.next().unwrap();
        let mut t = Trace::new(0, first, f(first), None);
        for n in it {
            t.push(n, f(n), None);
        }
        t
    }

    #[test]
    fn fills_smooth_motion_closely_and_flags_it() {
        // 30 mm sway at 0.8 Hz, 100 Hz, a 10-frame and a 30-frame gap.
        let f = |n: i64| {
            let t = n as f64 / 100.0;
            DVec3::new(0.03 * (5.0 * t).sin(), 1.0, 0.01 * (5.0 * t).cos())
        };
        let frames = (0..50).chain(60..100).chain(130..200);
        let mut tr = trace_of(f, frames);
        let st = fill_gaps(&mut tr, &timeline(200), settings());
        assert_eq!(st.filled, 2);
        assert_eq!(st.filled_frames, 10 + 30);
        for s in tr.samples() {
            if (50..60).contains(&s.frame) || (100..130).contains(&s.frame) {
                assert_eq!(s.kind, SampleKind::Filled);
                let err = s.position.distance(f(s.frame));
                let limit = if s.frame < 60 { 0.0005 } else { 0.005 };
                assert!(err < limit, "frame {}: {err}", s.frame);
            } else {
                assert_eq!(s.kind, SampleKind::Measured);
            }
        }
    }

    #[test]
    fn no_overshoot_on_monotone_data() {
        // A step-like rise: the fill must stay between the end values.
        let f = |n: i64| DVec3::new(if n < 10 { 0.0 } else { 0.02 }, 0.0, 0.0);
        let mut tr = trace_of(f, (0..5).chain(15..20));
        let st = fill_gaps(&mut tr, &timeline(20), settings());
        assert_eq!(st.filled, 1);
        for s in tr.samples() {
            assert!(s.position.x >= -1e-12 && s.position.x <= 0.02 + 1e-12);
        }
    }

    #[test]
    fn linear_when_a_side_has_one_sample() {
        let f = |n: i64| DVec3::new(0.001 * (n * n) as f64, 0.0, 0.0);
        let mut tr = trace_of(f, [0, 1, 2, 3, 8]);
        fill_gaps(&mut tr, &timeline(10), settings());
        let fill = tr.fills()[0];
        let mid = fill.at(6);
        let linear = f(3) + (f(8) - f(3)) * (3.0 / 5.0);
        assert!(mid.distance(linear) < 1e-12);
    }

    #[test]
    fn long_gaps_and_jumps_stay_open() {
        let f = |_n: i64| DVec3::ZERO;
        // 61 missing frames (5..=65) at 100 Hz > 0.5 s.
        let mut tr = trace_of(f, (0..5).chain(66..70));
        let st = fill_gaps(&mut tr, &timeline(70), settings());
        assert_eq!((st.filled, st.too_long, st.too_long_frames), (0, 1, 61));
        // A 10 cm jump across a 5-frame gap.
        let g = |n: i64| DVec3::new(if n < 10 { 0.0 } else { 0.1 }, 0.0, 0.0);
        let mut tr = trace_of(g, (0..5).chain(10..15));
        let st = fill_gaps(&mut tr, &timeline(15), settings());
        assert_eq!((st.filled, st.rejected_jump), (0, 1));
        assert!(tr
            .samples()
            .filter(|s| (5..10).contains(&s.frame))
            .all(|s| s.kind == SampleKind::Missing && s.position.is_nan()));
    }
}
