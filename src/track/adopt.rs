//! Ghost pieces that are pieces of a marker: after the identity
//! layer, traces it never confirmed are ghosts. Some of them are the
//! marker itself, in two cases the frame-to-frame tracker cannot follow:
//!
//! - **A marker seen as two blobs.** Its centroid flips, frame by frame,
//!   between two solutions a few millimetres apart (a real Motive take,
//!   tests/fixtures/motive/cmuphyscomp_sample_take_v1.21.csv: 9.5 mm).
//!   One trace keeps one solution; the other comes and goes as short
//!   traces, each measured exactly in the frames the first one misses.
//! - **A trace broken before it was confirmed.** Short pieces that hand the
//!   marker over to each other frame after frame, the last of which lives
//!   long enough to be confirmed.
//! - **A marker seen between two hidden stretches.** In the wind a marker
//!   hidden for a few frames often comes back as a new trace that is
//!   hidden again before it is confirmed (13 samples between gaps of 8 and
//!   32 frames; 108 between 37 and 8): left a ghost, it was dropped and the
//!   short gap next to it was filled as part of a long one.
//!
//! A ghost is adopted by a marker when the two are never measured in the
//! same frame and every run of the ghost's frames hands over to the marker
//! and back: on each side where the marker has data, its nearest
//! measurement is at most [`HANDOVER_FRAMES`] away and within `gate_mm` of
//! the ghost's sample there, and no other marker fits (where two hidden
//! markers pass close, the ghost stays one). Where the marker's nearest
//! measurement is further, across one of its gaps of at most
//! [`BRIDGE_FRAMES`], the motion at the gap's two edges must carry one to
//! the other (within a quarter of the gate), and on at least one side the
//! run must hand over or bridge. A spurious reflection would have to appear in
//! the very frame a marker is hidden, next to it, and vanish as it comes
//! back; a marker's pieces do exactly that. Adopting is repeated while it
//! succeeds, so a chain of hand-overs joins piece by piece.

use glam::DVec3;

use crate::model::trace::Trace;

/// Largest distance in frames between a ghost's run and the marker's
/// measurement on either side: the next frame, or one frame with neither.
pub const HANDOVER_FRAMES: i64 = 2;

/// Longest gap of a mark (frames) across which a ghost's run is compared
/// with the mark's motion (see [`hands_over`]): over 50 ms at 240 Hz the
/// mean of the two ends' velocities carries a swaying tip across to a few
/// millimetres (exact for a constant acceleration; a 150 mm swing at 3 Hz
/// leaves about 10 mm), well inside the gate; further apart it says
/// nothing.
pub const BRIDGE_FRAMES: i64 = 12;

/// A run bridges a gap when the motion carries it within the gate over
/// this: on `sway` and `close` a marker's own run lands within 3 mm, while
/// under 1 mm of noise and 10 reflections a second (`all`) reflections and
/// neighbours' pieces land 2–20 mm from most markers' gaps (the tight
/// bound leaves a noisy marker's run a ghost, as before).
const BRIDGE_TIGHTER: f64 = 4.0;

/// Fewest samples of a run for it to bridge a gap: a velocity of its own
/// (one or two samples carry none, or one from a single noisy step).
const BRIDGE_MIN_RUN: i64 = 3;

/// Joins into `marks` (the markers' traces) every ghost that interleaves
/// with or hands over to one of them (see the module doc). Returns the
/// ghosts left and the number adopted.
pub fn adopt_ghosts(marks: &mut [Trace], ghosts: Vec<Trace>, gate_m: f64) -> (Vec<Trace>, usize) {
    // A hand-over looks at a mark only within HANDOVER_FRAMES of a ghost's
    // runs: those frames' positions are all that is kept of each mark (its
    // whole list of measurements is 32 bytes a sample, 1.8 GB for an hour
    // of 70 markers at 240 Hz).
    // Each ghost's runs, found once: they do not change while marks adopt.
    let ghost_runs: Vec<Vec<Run>> = ghosts.iter().map(runs).collect();
    let all_runs = || ghost_runs.iter().flatten();
    let mut near: Vec<i64> = all_runs()
        .flat_map(|r| (1..=HANDOVER_FRAMES).flat_map(move |d| [r.a - d, r.b + d]))
        .collect();
    near.sort_unstable();
    near.dedup();
    // The ends of the ghosts' runs: a mark keeps the edges of its gaps
    // that hold one (for a run that lies inside a gap of the mark).
    let mut ends: Vec<i64> = all_runs().flat_map(|r| [r.a, r.b]).collect();
    ends.sort_unstable();
    ends.dedup();
    let of = |m: &Trace| Beside::of(m, &near, &ends);
    let mut cache: Vec<Beside> = marks.iter().map(of).collect();
    let mut left: Vec<Option<Trace>> = ghosts.into_iter().map(Some).collect();
    // The farthest a mark can begin after a ghost (or end before it) and
    // still continue it: across a gap it bridges.
    const REACH: i64 = BRIDGE_FRAMES + 1;
    let mut adopted = 0;
    loop {
        let mut changed = false;
        for (slot, runs) in left.iter_mut().zip(&ghost_runs) {
            let Some(ghost) = slot.as_ref() else {
                continue;
            };
            let mut fits = marks
                .iter()
                .zip(&cache)
                .enumerate()
                .filter(|(_, (m, _))| {
                    m.first_frame() <= ghost.last_frame() + REACH
                        && ghost.first_frame() <= m.last_frame() + REACH
                })
                .filter(|(_, (m, seen))| hands_over(m, seen, runs, gate_m))
                .map(|(k, _)| k);
            // Only a ghost that one marker alone could have handed over to:
            // where two hidden markers pass close, it stays a ghost.
            let (Some(k), None) = (fits.next(), fits.next()) else {
                continue;
            };
            if let Some(joined) = marks[k].merged(ghost) {
                cache[k] = of(&joined);
                marks[k] = joined;
                *slot = None;
                adopted += 1;
                changed = true;
            }
        }
        if !changed {
            break;
        }
    }
    (left.into_iter().flatten().collect(), adopted)
}

/// A run of consecutive measured frames of a ghost: its first frame `a`,
/// position `pa` and velocity `va` there (m per frame; zero for a run of
/// one sample), the same at its last frame `b`.
#[derive(Debug, Clone, Copy)]
struct Run {
    a: i64,
    pa: DVec3,
    va: DVec3,
    b: i64,
    pb: DVec3,
    vb: DVec3,
}

/// A ghost's runs, in order.
fn runs(t: &Trace) -> Vec<Run> {
    let mut out: Vec<Run> = Vec::new();
    // The run's last three positions, for the velocity at its end.
    let mut tail: Vec<DVec3> = Vec::new();
    for (f, p) in t.measurements() {
        match out.last_mut() {
            Some(r) if r.b + 1 == f => {
                r.b = f;
                r.pb = p;
                tail.push(p);
                if tail.len() == 2 || tail.len() == 3 {
                    // The velocity at the start from its first samples.
                    r.va = (p - r.pa) / (tail.len() - 1) as f64;
                }
            }
            _ => {
                if let Some(r) = out.last_mut() {
                    r.vb = end_velocity(&tail);
                }
                tail.clear();
                tail.push(p);
                out.push(Run {
                    a: f,
                    pa: p,
                    va: DVec3::ZERO,
                    b: f,
                    pb: p,
                    vb: DVec3::ZERO,
                });
            }
        }
    }
    if let Some(r) = out.last_mut() {
        r.vb = end_velocity(&tail);
    }
    out
}

/// The velocity at the last of `tail`'s consecutive positions, over up to
/// its last two frames (m per frame; zero for one position).
fn end_velocity(tail: &[DVec3]) -> DVec3 {
    match tail {
        [.., p, _, q] => (*q - *p) / 2.0,
        [p, q] => *q - *p,
        _ => DVec3::ZERO,
    }
}

/// One end of a mark's gap: the measured frame, its position and velocity.
#[derive(Debug, Clone, Copy)]
struct Edge {
    frame: i64,
    p: DVec3,
    v: DVec3,
}

/// A mark's measured positions at the frames next to the ghosts' runs (the
/// frames given to [`Beside::of`], in order), and the edges of its gaps
/// (its first and last measurements count) that a ghost run's end lies at
/// most [`BRIDGE_FRAMES`] beyond: the last measurement before a gap, and
/// the first after one, each in frame order.
struct Beside {
    seen: Vec<(i64, DVec3)>,
    before: Vec<Edge>,
    after: Vec<Edge>,
}

impl Beside {
    /// The measurements of `mark` at the sorted `frames`, and the edges of
    /// its gaps next to any of the sorted `ends`, in one pass.
    fn of(mark: &Trace, frames: &[i64], ends: &[i64]) -> Beside {
        // Whether a run's end lies in `lo..=hi`.
        let any_end = |lo: i64, hi: i64| {
            let k = ends.partition_point(|&e| e < lo);
            ends.get(k).is_some_and(|&e| e <= hi)
        };
        let mut k = 0;
        let mut out = Beside {
            seen: Vec::new(),
            before: Vec::new(),
            after: Vec::new(),
        };
        // The last three positions of the mark's current run, and how
        // many positions of the run after the latest kept after-edge are
        // still to come for its velocity.
        let mut tail: Vec<DVec3> = Vec::with_capacity(4);
        let mut last: Option<i64> = None;
        let mut pending = 0;
        for (f, p) in mark.measurements() {
            if last.is_none_or(|l| f != l + 1) {
                if let Some(l) = last {
                    if any_end(l + 1, l + 1 + BRIDGE_FRAMES) {
                        out.before.push(edge_at(l, &tail));
                    }
                }
                pending = 0;
                if any_end(f - 1 - BRIDGE_FRAMES, f - 1) {
                    out.after.push(Edge {
                        frame: f,
                        p,
                        v: DVec3::ZERO,
                    });
                    pending = 2;
                }
                tail.clear();
            } else if pending > 0 {
                // The velocity at the gap's far edge, forwards from it.
                if let Some(e) = out.after.last_mut() {
                    e.v = (p - e.p) / (f - e.frame) as f64;
                }
                pending -= 1;
            }
            if tail.len() == 3 {
                tail.remove(0);
            }
            tail.push(p);
            last = Some(f);
            while frames.get(k).is_some_and(|&n| n < f) {
                k += 1;
            }
            if frames.get(k) == Some(&f) {
                out.seen.push((f, p));
            }
        }
        if let Some(l) = last {
            if any_end(l + 1, l + 1 + BRIDGE_FRAMES) {
                out.before.push(edge_at(l, &tail));
            }
        }
        out
    }

    fn at(&self, frame: i64) -> Option<DVec3> {
        let k = self.seen.binary_search_by_key(&frame, |s| s.0).ok()?;
        Some(self.seen[k].1)
    }

    /// The kept edge nearest to frame `f` on one side (`step` -1: the last
    /// before-edge before it, 1: the first after-edge after it).
    fn edge(&self, f: i64, step: i64) -> Option<Edge> {
        if step < 0 {
            let k = self.before.partition_point(|e| e.frame < f);
            self.before.get(k.checked_sub(1)?).copied()
        } else {
            let k = self.after.partition_point(|e| e.frame <= f);
            self.after.get(k).copied()
        }
    }
}

/// The edge at frame `f`, the last of the consecutive positions `tail`.
fn edge_at(f: i64, tail: &[DVec3]) -> Edge {
    Edge {
        frame: f,
        p: tail.last().copied().unwrap_or(DVec3::NAN),
        v: end_velocity(tail),
    }
}

/// What a mark has next to one end of a ghost's run.
enum Side {
    /// A measurement within [`HANDOVER_FRAMES`]: the hand-over must fit it.
    Near(DVec3),
    /// Nothing on that side: the mark begins or ends there.
    Nothing,
    /// Measurements further than [`HANDOVER_FRAMES`].
    Gap,
}

/// The mark's measurement nearest to frame `f` on one side (`step` -1:
/// before, 1: after). The mark's first and last frames are measured.
fn nearest_beside(mark: &Trace, seen: &Beside, f: i64, step: i64) -> Side {
    for d in 1..=HANDOVER_FRAMES {
        let g = f + step * d;
        if mark.is_measured(g) {
            return seen.at(g).map_or(Side::Gap, Side::Near);
        }
    }
    let further = if step < 0 {
        mark.first_frame() < f
    } else {
        mark.last_frame() > f
    };
    if further {
        Side::Gap
    } else {
        Side::Nothing
    }
}

/// Whether a ghost's run continues the mark across the gap it lies in, on
/// one side: the mean of the velocities at the gap's edge (`e`) and at the
/// run's end (`f`, `p`, `v`) carries one to the other within `gate_m`.
/// `None` without an edge within [`BRIDGE_FRAMES`] (no evidence).
fn bridges(e: Option<Edge>, f: i64, p: DVec3, v: DVec3, gate_m: f64) -> Option<bool> {
    let e = e?;
    let dt = (f - e.frame) as f64;
    Some((e.p + (e.v + v) * (dt / 2.0)).distance(p) <= gate_m / BRIDGE_TIGHTER)
}

/// Whether `mark` (its measurements beside the ghosts, `seen`) and a ghost
/// with these runs hand over to each other: they share no frame, and every
/// run hands over within `HANDOVER_FRAMES` and `gate_m` on each side where
/// the mark has data (and the mark has data beside at least one run).
///
/// A run may instead lie inside one of the mark's gaps, the mark's
/// measurements further than `HANDOVER_FRAMES` from it: a marker seen
/// between two hidden stretches is often a new trace too short to be
/// confirmed (13 samples between gaps of 8 and 32 frames, issue 14 `sway`
/// seeds 101–102; dropped as a ghost, the short gap was filled as part of
/// a long one). It joins when, on each side no further than
/// [`BRIDGE_FRAMES`] across, the motion on both edges carries one to the
/// other ([`bridges`]) and on at least one side it hands over or bridges.
/// A reflection would have to move as the marker does at both edges.
fn hands_over(mark: &Trace, seen: &Beside, runs: &[Run], gate_m: f64) -> bool {
    // Cheap first: most marks are measured in the ghost's frames.
    if runs
        .iter()
        .any(|r| (r.a..=r.b).any(|f| mark.is_measured(f)))
    {
        return false;
    }
    let mut beside = false;
    for r in runs {
        // The mark's measurements before `a` and after `b`.
        for (f, p, step) in [(r.a, r.pa, -1), (r.b, r.pb, 1)] {
            match nearest_beside(mark, seen, f, step) {
                Side::Near(q) if q.distance(p) > gate_m => return false,
                Side::Near(_) => beside = true,
                Side::Nothing => {}
                Side::Gap if r.b - r.a + 1 < BRIDGE_MIN_RUN => return false,
                Side::Gap => {
                    // Across the gap, backwards from the run's start to
                    // the mark's edge before, or forwards from its end.
                    let v = if step < 0 { r.va } else { r.vb };
                    // Only the mark's own edge of this gap: nothing
                    // measured between it and the run.
                    let e = seen.edge(f, step).filter(|e| {
                        let (lo, hi) = (e.frame.min(f), e.frame.max(f));
                        hi - lo - 1 <= BRIDGE_FRAMES && (lo + 1..hi).all(|g| !mark.is_measured(g))
                    });
                    let across = bridges(e, f, p, v, gate_m);
                    match across {
                        Some(false) => return false,
                        Some(true) => beside = true,
                        None => {}
                    }
                }
            }
        }
    }
    beside
}

#[cfg(test)]
mod tests {
    use super::*;

    fn trace(id: usize, samples: &[(i64, DVec3)]) -> Trace {
        let mut t = Trace::new(id, samples[0].0, samples[0].1, None);
        for &(f, p) in &samples[1..] {
            t.push(f, p, None);
        }
        t
    }

    /// A marker flipping between two spots 9.5 mm apart: the pieces on the
    /// second spot are adopted, a reflection 40 mm away is not, nor one
    /// next to the marker but in frames where it is measured.
    #[test]
    fn interleaved_pieces_join_and_ghosts_elsewhere_stay() {
        let a = DVec3::new(0.0, 1.0, 0.0);
        let b = a + DVec3::X * 0.0095;
        let mut mark = Vec::new();
        let mut pieces = Vec::new();
        for f in 0..40 {
            if f % 5 == 2 || f % 5 == 3 {
                pieces.push((f, b));
            } else {
                mark.push((f, a));
            }
        }
        let mut ghosts: Vec<Trace> = pieces
            .chunks(2)
            .enumerate()
            .map(|(k, c)| trace(10 + k, c))
            .collect();
        let far = trace(30, &[(7, a + DVec3::Y * 0.04), (8, a + DVec3::Y * 0.04)]);
        let shared = trace(31, &[(10, b), (11, b)]);
        ghosts.push(far);
        ghosts.push(shared);
        let mut marks = vec![trace(0, &mark)];
        let (left, adopted) = adopt_ghosts(&mut marks, ghosts, 0.025);
        assert_eq!(adopted, 8);
        assert_eq!(marks[0].measured(), 40);
        let ids: Vec<usize> = left.iter().map(|t| t.id).collect();
        assert_eq!(ids, vec![30, 31]);
    }

    /// Short pieces handing over one after the other before the marker's
    /// confirmed trace begins join it piece by piece; a piece ending three
    /// frames before, 10 mm off the marker's path, does not (on its path
    /// it bridges the gap, see the next test), nor one 10 frames after.
    #[test]
    fn a_chain_of_hand_overs_joins_and_a_late_one_does_not() {
        let p = |f: i64| DVec3::new(0.001 * f as f64, 1.0, 0.0);
        let run =
            |id, r: std::ops::Range<i64>| trace(id, &r.map(|f| (f, p(f))).collect::<Vec<_>>());
        let off_path = |id, r: std::ops::Range<i64>| {
            trace(
                id,
                &r.map(|f| (f, p(f) + DVec3::Y * 0.01)).collect::<Vec<_>>(),
            )
        };
        let mut marks = vec![run(0, 20..60)];
        let ghosts = vec![
            run(1, 0..5),
            run(2, 5..12),
            run(3, 12..20),
            off_path(4, 70..75),
        ];
        let (left, adopted) = adopt_ghosts(&mut marks, ghosts, 0.025);
        assert_eq!(adopted, 3);
        assert_eq!(marks[0].first_frame(), 0);
        assert_eq!(marks[0].measured(), 60);
        assert_eq!(left.len(), 1);
        let mut marks = vec![run(0, 20..60)];
        let (left, adopted) = adopt_ghosts(&mut marks, vec![off_path(1, 0..17)], 0.025);
        assert_eq!((adopted, left.len()), (0, 1));
        // After the marker's last frame: one frame with neither joins, and
        // a piece 30 mm off does not.
        let mut marks = vec![run(0, 20..60)];
        let off = trace(2, &[(67, p(67) + DVec3::Y * 0.03), (68, p(68))]);
        let (left, adopted) = adopt_ghosts(&mut marks, vec![run(1, 61..66), off], 0.025);
        assert_eq!((adopted, marks[0].last_frame()), (1, 65));
        assert_eq!(left.iter().map(|t| t.id).collect::<Vec<_>>(), vec![2]);
    }

    /// A marker swinging (3 mm a frame, turning) seen for 13 frames between
    /// a gap of 8 frames and one of 32: the piece joins it across the short
    /// gap. The same piece 10 mm off its path, a 2-sample piece, and a piece
    /// that only a gap too long to judge separates from the marker stay
    /// ghosts.
    #[test]
    fn a_piece_between_two_gaps_joins_where_the_motion_carries_it() {
        let p = |f: i64| {
            let t = f as f64 / 240.0;
            DVec3::new(0.1 * (6.0 * t).sin(), 1.0, 0.05 * (4.0 * t).cos())
        };
        let run = |id, r: std::ops::Range<i64>, off: DVec3| {
            trace(id, &r.map(|f| (f, p(f) + off)).collect::<Vec<_>>())
        };
        let mark = || {
            let mut m = run(0, 0..100, DVec3::ZERO);
            for f in 155..200 {
                m.push(f, p(f), None);
            }
            m
        };
        let z = DVec3::ZERO;
        let mut marks = vec![mark()];
        let (left, adopted) = adopt_ghosts(&mut marks, vec![run(1, 109..122, z)], 0.025);
        assert_eq!((adopted, left.len(), marks[0].measured()), (1, 0, 158));
        let off = DVec3::Y * 0.01;
        for ghost in [
            run(1, 109..122, off),
            run(2, 109..111, z),
            run(3, 125..138, z),
        ] {
            let mut marks = vec![mark()];
            let (left, adopted) = adopt_ghosts(&mut marks, vec![ghost], 0.025);
            assert_eq!((adopted, left.len()), (0, 1));
        }
        // Before the marker's first frame, across a short gap, too.
        let mut marks = vec![run(0, 30..80, z)];
        let (_, adopted) = adopt_ghosts(&mut marks, vec![run(1, 5..21, z)], 0.025);
        assert_eq!((adopted, marks[0].first_frame()), (1, 5));
    }
}
