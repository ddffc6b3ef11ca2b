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
//!
//! A ghost is adopted by a marker when the two are never measured in the
//! same frame and every run of the ghost's frames hands over to the marker
//! and back: on each side where the marker has data, its nearest
//! measurement is at most [`HANDOVER_FRAMES`] away and within `gate_mm` of
//! the ghost's sample there, and no other marker fits (where two hidden
//! markers pass close, the ghost stays one). A spurious reflection would have to appear in
//! the very frame a marker is hidden, next to it, and vanish as it comes
//! back; a marker's pieces do exactly that. Adopting is repeated while it
//! succeeds, so a chain of hand-overs joins piece by piece.

use glam::DVec3;

use crate::model::trace::Trace;

/// Largest distance in frames between a ghost's run and the marker's
/// measurement on either side: the next frame, or one frame with neither.
pub const HANDOVER_FRAMES: i64 = 2;

/// Joins into `marks` (the markers' traces) every ghost that interleaves
/// with or hands over to one of them (see the module doc). Returns the
/// ghosts left and the number adopted.
pub fn adopt_ghosts(marks: &mut [Trace], ghosts: Vec<Trace>, gate_m: f64) -> (Vec<Trace>, usize) {
    // A hand-over looks at a mark only within HANDOVER_FRAMES of a ghost's
    // runs: those frames' positions are all that is kept of each mark (its
    // whole list of measurements is 32 bytes a sample, 1.8 GB for an hour
    // of 70 markers at 240 Hz).
    let mut near: Vec<i64> = ghosts
        .iter()
        .flat_map(|g| runs(g).into_iter())
        .flat_map(|(a, _, b, _)| (1..=HANDOVER_FRAMES).flat_map(move |d| [a - d, b + d]))
        .collect();
    near.sort_unstable();
    near.dedup();
    let mut cache: Vec<Beside> = marks.iter().map(|m| Beside::of(m, &near)).collect();
    let mut left: Vec<Option<Trace>> = ghosts.into_iter().map(Some).collect();
    let mut adopted = 0;
    loop {
        let mut changed = false;
        for slot in left.iter_mut() {
            let Some(ghost) = slot.as_ref() else {
                continue;
            };
            let runs = runs(ghost);
            let mut fits = marks
                .iter()
                .zip(&cache)
                .enumerate()
                .filter(|(_, (m, _))| {
                    m.first_frame() <= ghost.last_frame() + HANDOVER_FRAMES
                        && ghost.first_frame() <= m.last_frame() + HANDOVER_FRAMES
                })
                .filter(|(_, (m, seen))| hands_over(m, seen, &runs, gate_m))
                .map(|(k, _)| k);
            // Only a ghost that one marker alone could have handed over to:
            // where two hidden markers pass close, it stays a ghost.
            let (Some(k), None) = (fits.next(), fits.next()) else {
                continue;
            };
            if let Some(joined) = marks[k].merged(ghost) {
                cache[k] = Beside::of(&joined, &near);
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

/// Runs of consecutive measured frames: (first frame, its position, last
/// frame, its position).
fn runs(t: &Trace) -> Vec<(i64, DVec3, i64, DVec3)> {
    let mut out: Vec<(i64, DVec3, i64, DVec3)> = Vec::new();
    for (f, p) in t.measurements() {
        match out.last_mut() {
            Some(r) if r.2 + 1 == f => {
                r.2 = f;
                r.3 = p;
            }
            _ => out.push((f, p, f, p)),
        }
    }
    out
}

/// A mark's measured positions at the frames next to the ghosts' runs (the
/// frames given to [`Beside::of`], in order).
struct Beside(Vec<(i64, DVec3)>);

impl Beside {
    /// The measurements of `mark` at the sorted `frames`, in one pass.
    fn of(mark: &Trace, frames: &[i64]) -> Beside {
        let mut k = 0;
        let mut out = Vec::new();
        for (f, p) in mark.measurements() {
            while frames.get(k).is_some_and(|&n| n < f) {
                k += 1;
            }
            if k == frames.len() {
                break;
            }
            if frames[k] == f {
                out.push((f, p));
            }
        }
        Beside(out)
    }

    fn at(&self, frame: i64) -> Option<DVec3> {
        let k = self.0.binary_search_by_key(&frame, |s| s.0).ok()?;
        Some(self.0[k].1)
    }
}

/// The mark's measurement nearest to frame `f` on one side (`step` -1:
/// before, 1: after): `Some(None)` when there is none on that side,
/// `Some(Some(..))` when it is within `HANDOVER_FRAMES`, `None` when it is
/// further (no hand-over). The mark's first and last frames are measured.
fn nearest_beside(mark: &Trace, seen: &Beside, f: i64, step: i64) -> Option<Option<DVec3>> {
    for d in 1..=HANDOVER_FRAMES {
        let g = f + step * d;
        if mark.is_measured(g) {
            return seen.at(g).map(Some);
        }
    }
    let further = if step < 0 {
        mark.first_frame() < f
    } else {
        mark.last_frame() > f
    };
    (!further).then_some(None)
}

/// Whether `mark` (its measurements beside the ghosts, `seen`) and a ghost
/// with these runs hand over to each other: they share no frame, and every
/// run hands over within `HANDOVER_FRAMES` and `gate_m` on each side where
/// the mark has data (and the mark has data beside at least one run).
fn hands_over(mark: &Trace, seen: &Beside, runs: &[(i64, DVec3, i64, DVec3)], gate_m: f64) -> bool {
    // Cheap first: most marks are measured in the ghost's frames.
    if runs
        .iter()
        .any(|r| (r.0..=r.2).any(|f| mark.is_measured(f)))
    {
        return false;
    }
    let mut beside = false;
    for &(a, pa, b, pb) in runs {
        // The mark's measurements before `a` and after `b`.
        for (f, p, step) in [(a, pa, -1), (b, pb, 1)] {
            let Some(near) = nearest_beside(mark, seen, f, step) else {
                return false;
            };
            let Some(q) = near else {
                continue;
            };
            if q.distance(p) > gate_m {
                return false;
            }
            beside = true;
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
    /// frames before does not.
    #[test]
    fn a_chain_of_hand_overs_joins_and_a_late_one_does_not() {
        let p = |f: i64| DVec3::new(0.001 * f as f64, 1.0, 0.0);
        let run =
            |id, r: std::ops::Range<i64>| trace(id, &r.map(|f| (f, p(f))).collect::<Vec<_>>());
        let mut marks = vec![run(0, 20..60)];
        let ghosts = vec![run(1, 0..5), run(2, 5..12), run(3, 12..20), run(4, 70..75)];
        let (left, adopted) = adopt_ghosts(&mut marks, ghosts, 0.025);
        assert_eq!(adopted, 3);
        assert_eq!(marks[0].first_frame(), 0);
        assert_eq!(marks[0].measured(), 60);
        assert_eq!(left.len(), 1);
        let mut marks = vec![run(0, 20..60)];
        let (left, adopted) = adopt_ghosts(&mut marks, vec![run(1, 0..17)], 0.025);
        assert_eq!((adopted, left.len()), (0, 1));
        // After the marker's last frame: one frame with neither joins, and
        // a piece 30 mm off does not.
        let mut marks = vec![run(0, 20..60)];
        let off = trace(2, &[(67, p(67) + DVec3::Y * 0.03), (68, p(68))]);
        let (left, adopted) = adopt_ghosts(&mut marks, vec![run(1, 61..66), off], 0.025);
        assert_eq!((adopted, marks[0].last_frame()), (1, 65));
        assert_eq!(left.iter().map(|t| t.id).collect::<Vec<_>>(), vec![2]);
    }
}
