//! Joining the pieces of one marker, then removing noise (paper §4 and §7,
//! spec §4).
//!
//! The tracker's identity layer joins the pieces of a marker on line from
//! its neighbours' motion. What it could not join (a marker hidden for
//! longer than `keep_lost_s`, a piece it did not trust) is joined here,
//! before the noise test, so that a marker hidden once is not thrown away
//! or counted twice:
//! - **by rest position** (spec): pieces that do not overlap in time and
//!   whose rest positions lie within `merge_radius` are one marker;
//! - **into a gap** (ours): a long piece without a rest position goes into
//!   the gap of the marker whose neighbourhood it occupies.
//!
//! Then the paper's rule: a trace measured in fewer than `noise_fraction`
//! (1/4) of the frames is noise (a spurious reflection, a marker on the
//! floor that flickered) and is dropped, with the reason recorded.

use glam::DVec3;
use serde::Serialize;

use super::assign::{Assigner, Edge};
use crate::model::trace::Trace;

/// A trace dropped as noise, and why.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DroppedTrace {
    /// Tracker id of the (joined) trace.
    pub id: usize,
    /// Frames in which it was measured.
    pub measured: usize,
    /// Those frames as a fraction of all frames of the session.
    pub fraction: f64,
    /// First and last internal frame.
    pub first_frame: i64,
    /// Last internal frame in which it was measured.
    pub last_frame: i64,
}

/// Joins pieces that do not overlap in time and whose rest positions (given
/// per trace, `None` when it has too few samples in the rest window) lie
/// within `merge_radius_m`, closest pairs first. Returns the traces and the
/// number of joins.
pub fn join_by_rest(
    traces: Vec<Trace>,
    rest: &[Option<DVec3>],
    merge_radius_m: f64,
) -> (Vec<Trace>, usize) {
    let mut pairs = Vec::new();
    let with_rest: Vec<(usize, DVec3)> = rest
        .iter()
        .enumerate()
        .filter_map(|(i, r)| r.map(|r| (i, r)))
        .collect();
    for (k, &(i, ri)) in with_rest.iter().enumerate() {
        for &(j, rj) in &with_rest[k + 1..] {
            let d = ri.distance(rj);
            if d <= merge_radius_m {
                pairs.push((d, i, j));
            }
        }
    }
    if pairs.is_empty() {
        return (traces, 0);
    }
    pairs.sort_by(|a, b| a.0.total_cmp(&b.0).then((a.1, a.2).cmp(&(b.1, b.2))));
    let n = traces.len();
    let mut group: Vec<usize> = (0..n).collect();
    let mut members: Vec<Vec<usize>> = (0..n).map(|i| vec![i]).collect();
    let span = |i: usize| (traces[i].first_frame(), traces[i].last_frame());
    let mut joins = 0;
    for (_, i, j) in pairs {
        let (gi, gj) = (group[i], group[j]);
        if gi == gj {
            continue;
        }
        let overlap = members[gi].iter().any(|&a| {
            members[gj].iter().any(|&b| {
                let (sa, ea) = span(a);
                let (sb, eb) = span(b);
                sa <= eb && sb <= ea
            })
        });
        if overlap {
            continue;
        }
        let moved = std::mem::take(&mut members[gj]);
        for &m in &moved {
            group[m] = gi;
        }
        members[gi].extend(moved);
        joins += 1;
    }
    let mut slots: Vec<Option<Trace>> = traces.into_iter().map(Some).collect();
    let mut out = Vec::new();
    for group_members in members.iter_mut() {
        let mut ids = std::mem::take(group_members);
        if ids.is_empty() {
            continue;
        }
        ids.sort_by_key(|&i| slots[i].as_ref().map_or(0, |t| t.first_frame()));
        let mut iter = ids.into_iter();
        let Some(mut joined) = iter.next().and_then(|i| slots[i].take()) else {
            continue;
        };
        for i in iter {
            if let Some(piece) = slots[i].take() {
                // An overlapping piece is dropped, as it always was.
                let _ = joined.append(piece);
            }
        }
        out.push(joined);
    }
    out.sort_by_key(|t| t.id);
    (out, joins)
}

/// Splits traces into those measured in at least `fraction` of `frames`
/// and the noise: (kept, what was dropped, the dropped traces themselves,
/// whose samples a tip may still take back).
pub fn drop_noise(
    traces: Vec<Trace>,
    frames: u64,
    fraction: f64,
) -> (Vec<Trace>, Vec<DroppedTrace>, Vec<Trace>) {
    let min = fraction * frames as f64;
    let mut kept = Vec::new();
    let mut dropped = Vec::new();
    let mut noise = Vec::new();
    for t in traces {
        if (t.measured() as f64) < min {
            dropped.push(DroppedTrace {
                id: t.id,
                measured: t.measured(),
                fraction: t.measured() as f64 / frames.max(1) as f64,
                first_frame: t.first_frame(),
                last_frame: t.last_frame(),
            });
            noise.push(t);
        } else {
            kept.push(t);
        }
    }
    (kept, dropped, noise)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn piece(id: usize, frames: std::ops::Range<i64>, f: impl Fn(i64) -> DVec3) -> Trace {
        let mut it = frames;
        let first = it.next().unwrap();
        let mut t = Trace::new(id, first, f(first), None);
        for n in it {
            t.push(n, f(n), None);
        }
        t
    }

    #[test]
    fn rest_join_needs_closeness_and_no_overlap() {
        let p = |_n: i64| DVec3::new(0.1, 1.0, 0.0);
        let traces = vec![
            piece(0, 0..100, p),
            piece(1, 150..300, p),
            piece(2, 50..60, p), // overlaps piece 0
            piece(3, 310..320, |_| DVec3::new(0.2, 1.0, 0.0)),
        ];
        let rest = vec![
            Some(DVec3::new(0.1, 1.0, 0.0)),
            Some(DVec3::new(0.1, 1.001, 0.0)),
            Some(DVec3::new(0.1, 1.0, 0.0005)),
            Some(DVec3::new(0.2, 1.0, 0.0)),
        ];
        let (out, joins) = join_by_rest(traces, &rest, 0.005);
        // 0 joins 2 first (closest) — no, they overlap; 0 + 1 join; 2 stays
        // apart (overlaps 0); 3 is too far.
        assert_eq!(joins, 1);
        let pieces: Vec<_> = out.iter().map(|t| t.pieces.clone()).collect();
        assert_eq!(pieces, vec![vec![0, 1], vec![2], vec![3]]);
    }

    #[test]
    fn quarter_rule() {
        let p = |_n: i64| DVec3::ZERO;
        let traces = vec![piece(0, 0..25, p), piece(1, 0..24, p)];
        let (kept, dropped, noise) = drop_noise(traces, 100, 0.25);
        assert_eq!(noise.len(), 1);
        assert_eq!(kept.len(), 1);
        assert_eq!(dropped.len(), 1);
        assert_eq!(dropped[0].id, 1);
        assert!((dropped[0].fraction - 0.24).abs() < 1e-12);
    }
}

/// Joins long fragments that have no rest position (a marker hidden for
/// seconds while the tree moved, ours) into the gap of the marker whose
/// neighbourhood they occupy: the host is not measured while the fragment
/// is, and on each side where the host has data the mean of its `context`
/// measurements nearest the fragment lies within `radius_m` of the mean of
/// the fragment's `context` measurements on that side. The fragment may
/// interleave with the host's pieces (no frame measured by both): then
/// every hand-over between them is checked the same way ([`switch_cost`]). Tips are
/// placed further apart than their sway, so the neighbourhood decides;
/// fragments shorter than `min_len` measurements (spurious reflections live
/// shorter) are left alone. Pairs are chosen by global assignment, repeated
/// while joins happen (one host may have several gaps). Returns the traces
/// and the number of joins.
pub fn join_into_gaps(
    traces: Vec<Trace>,
    has_rest: &[bool],
    min_len: usize,
    context: i64,
    radius_m: f64,
    assigner: &mut Assigner,
) -> (Vec<Trace>, usize) {
    let mut slots: Vec<Option<Trace>> = traces.into_iter().map(Some).collect();
    let hosts: Vec<usize> = (0..slots.len())
        .filter(|&i| has_rest.get(i).copied().unwrap_or(false))
        .collect();
    let mut joins = 0;
    loop {
        let fragments: Vec<usize> = slots
            .iter()
            .enumerate()
            .filter(|(i, _)| !has_rest.get(*i).copied().unwrap_or(false))
            .filter(|(_, t)| t.as_ref().is_some_and(|t| t.measured() >= min_len))
            .map(|(i, _)| i)
            .collect();
        let mut edges = Vec::new();
        for (row, &f) in fragments.iter().enumerate() {
            let Some(frag) = slots[f].as_ref() else {
                continue;
            };
            for (col, &h) in hosts.iter().enumerate() {
                let Some(host) = slots[h].as_ref() else {
                    continue;
                };
                let Some(cost) = switch_cost(host, frag, context as usize) else {
                    continue;
                };
                if cost <= radius_m {
                    edges.push(Edge { row, col, cost });
                }
            }
        }
        let mut out = Vec::new();
        assigner.solve(fragments.len(), hosts.len(), &edges, radius_m, &mut out);
        let mut joined_now = 0;
        for (row, col) in out.iter().enumerate() {
            let (Some(col), Some(&frag)) = (*col, fragments.get(row)) else {
                continue;
            };
            let h = hosts[col];
            let (Some(host), Some(piece)) = (slots[h].as_ref(), slots[frag].as_ref()) else {
                continue;
            };
            if let Some(m) = host.merged(piece) {
                slots[h] = Some(m);
                slots[frag] = None;
                joined_now += 1;
                // The merged copy was written while the host and the
                // fragment were alive, so their freed chunks are holes the
                // next copy only partly reuses: on an hour-long take the
                // joins left 55 MB of them resident (the marker stage's peak
                // was there and in gap filling, 348 MB against issue 14's
                // 300 MB, with never more than 284 MB in use).
                crate::memory::release_freed();
            }
        }
        joins += joined_now;
        if joined_now == 0 {
            break;
        }
    }
    (slots.into_iter().flatten().collect(), joins)
}

/// A trace's measurements read in order, with the running sum of their
/// positions, keeping only a window of them: the means [`switch_cost`]
/// compares reach `context` measurements back and `context` ahead of where
/// the walk is, nothing more.
///
/// Why a window: holding a trace's measurements with their prefix sums was
/// 32 bytes a sample, and on an hour-long take a fragment spanning most of
/// the hour and its host around it were 67 MB at once, the largest
/// transient of the marker stage (issue 14: the hour's peak 348 MB against
/// the 300 MB target). The window is `2 × context + 1` samples, whatever
/// the length of the traces.
///
/// The sums are accumulated from the trace's first measurement in the
/// same order as before, so every mean is the same, bit for bit, as one
/// taken from prefix sums of the whole trace.
struct Stream<I> {
    iter: I,
    /// `(frame, sum of every measurement before it)` of measurements
    /// `base..base + window.len()`.
    window: std::collections::VecDeque<(i64, DVec3)>,
    base: usize,
    /// The sum of every measurement read so far (the prefix sum at
    /// `base + window.len()`).
    acc: DVec3,
    /// The trace has no measurement left to read.
    done: bool,
}

impl<I: Iterator<Item = (i64, DVec3)>> Stream<I> {
    fn new(iter: I) -> Self {
        Stream {
            iter,
            window: Default::default(),
            base: 0,
            acc: DVec3::ZERO,
            done: false,
        }
    }

    /// Reads measurements until `k` of them are read or the trace ends.
    fn read_to(&mut self, k: usize) {
        while !self.done && self.base + self.window.len() < k {
            match self.iter.next() {
                Some((frame, p)) => {
                    self.window.push_back((frame, self.acc));
                    self.acc += p;
                }
                None => self.done = true,
            }
        }
    }

    /// Frame of measurement `k` (`None` past the end). `k` is never before
    /// the window: the walk only moves forward.
    fn frame(&mut self, k: usize) -> Option<i64> {
        self.read_to(k + 1);
        self.window.get(k.checked_sub(self.base)?).map(|w| w.0)
    }

    /// The sum of measurements before `k`; `k` at most the number read.
    fn prefix(&self, k: usize) -> DVec3 {
        self.window.get(k - self.base).map_or(self.acc, |w| w.1)
    }

    /// Mean of measurements `[lo, hi)` (clamped to the trace; `None` when
    /// empty), as `(prefix[hi] - prefix[lo]) / (hi - lo)`.
    fn mean(&mut self, lo: usize, hi: usize) -> Option<DVec3> {
        self.read_to(hi);
        let hi = hi.min(self.base + self.window.len());
        (hi > lo).then(|| (self.prefix(hi) - self.prefix(lo)) / (hi - lo) as f64)
    }

    /// Forgets measurements before `k` (no mean will start before it).
    fn forget_before(&mut self, k: usize) {
        while self.base < k && !self.window.is_empty() {
            self.window.pop_front();
            self.base += 1;
        }
    }
}

/// How far apart a host and a fragment are where one hands over to the
/// other: walking both in frame order, at every switch from one to the
/// other the mean of the last `context` measurements of the one that
/// stops is compared with the mean of the next `context` measurements of
/// the one that goes on; the largest distance is the cost. A fragment
/// inside one gap of the host has two such switches (the host's data
/// before the gap against the fragment's head, its tail against the host's
/// data after). The fragment may also interleave with the host's pieces
/// (the identity layer can hand the later pieces of one marker to two
/// identities): every hand-over is checked the same way. `None` when both
/// are measured in one frame (two markers) or there is no hand-over.
fn switch_cost(host: &Trace, frag: &Trace, context: usize) -> Option<f64> {
    let mut a = Stream::new(host.measurements());
    let mut b = Stream::new(frag.measurements());
    let (mut i, mut j) = (0usize, 0usize);
    let mut last: Option<bool> = None;
    let mut worst: Option<f64> = None;
    loop {
        let from_host = match (a.frame(i), b.frame(j)) {
            (Some(x), Some(y)) if x == y => return None,
            (Some(x), Some(y)) => x < y,
            // Only one trace is left: after this step, no hand-over can
            // follow, and reading the rest of it would change nothing.
            (Some(_), None) if last == Some(true) => break,
            (None, Some(_)) if last == Some(false) => break,
            (Some(_), None) => true,
            (None, Some(_)) => false,
            (None, None) => break,
        };
        if last.is_some_and(|l| l != from_host) {
            let (before, after) = if from_host {
                (b.mean(j.saturating_sub(context), j), a.mean(i, i + context))
            } else {
                (a.mean(i.saturating_sub(context), i), b.mean(j, j + context))
            };
            if let (Some(x), Some(y)) = (before, after) {
                let d = x.distance(y);
                worst = Some(worst.map_or(d, |w: f64| w.max(d)));
            }
        }
        last = Some(from_host);
        if from_host {
            i += 1;
            a.forget_before(i.saturating_sub(context));
        } else {
            j += 1;
            b.forget_before(j.saturating_sub(context));
        }
    }
    worst
}

#[cfg(test)]
mod gap_join_tests {
    use super::*;

    /// One marker whose later pieces the identity layer gave to two
    /// identities: the one with a rest position (host) got a piece in the
    /// middle of the other's span. The other (no rest position) still goes
    /// into the host's gaps; a marker 100 mm away does not.
    #[test]
    fn fragment_interleaving_with_its_host_joins_it() {
        let at = |x: f64| move |n: i64| DVec3::new(x + 0.02 * (n as f64 / 30.0).sin(), 1.0, 0.0);
        let mut host = Trace::new(0, 0, at(0.0)(0), None);
        for n in (1..1000).chain(1300..1350) {
            host.push(n, at(0.0)(n), None);
        }
        let mut frag = Trace::new(1, 1030, at(0.0)(1030), None);
        for n in (1031..1280).chain(1380..1600) {
            frag.push(n, at(0.0)(n), None);
        }
        let mut other = Trace::new(2, 1010, at(0.1)(1010), None);
        for n in (1011..1290).chain(1360..1600) {
            other.push(n, at(0.1)(n), None);
        }
        let mut asg = Assigner::default();
        let (out, joins) = join_into_gaps(
            vec![host, frag, other],
            &[true, false, false],
            100,
            100,
            0.04,
            &mut asg,
        );
        assert_eq!(joins, 1);
        assert_eq!(out.len(), 2);
        assert_eq!(out[0].pieces, vec![0, 1]);
        assert_eq!(out[0].measured(), 1000 + 50 + 250 + 220);
    }

    #[test]
    fn long_fragment_goes_into_the_gap_of_its_neighbourhood() {
        let at = |x: f64| move |n: i64| DVec3::new(x + 0.02 * (n as f64 / 30.0).sin(), 1.0, 0.0);
        let mut host_a = Trace::new(0, 0, at(0.0)(0), None);
        for n in (1..1000).chain(1400..2000) {
            host_a.push(n, at(0.0)(n), None);
        }
        let mut host_b = Trace::new(1, 0, at(0.1)(0), None);
        for n in 1..2000 {
            host_b.push(n, at(0.1)(n), None);
        }
        let mut frag = Trace::new(2, 1050, at(0.0)(1050), None);
        for n in 1051..1350 {
            frag.push(n, at(0.0)(n), None);
        }
        let spurious = Trace::new(3, 1100, DVec3::new(0.0, 1.0, 0.0), None);
        let mut asg = Assigner::default();
        let (out, joins) = join_into_gaps(
            vec![host_a, host_b, frag, spurious],
            &[true, true, false, false],
            100,
            200,
            0.04,
            &mut asg,
        );
        assert_eq!(joins, 1);
        assert_eq!(out.len(), 3);
        assert_eq!(out[0].pieces, vec![0, 2]);
        assert_eq!(out[0].measured(), 1600 + 300);
    }

    /// [`switch_cost`] as it was before it read the traces through a
    /// window: every measurement of both traces with their prefix sums,
    /// walked whole. The reference the windowed walk must equal bit for bit.
    fn switch_cost_whole(host: &Trace, frag: &Trace, context: usize) -> Option<f64> {
        let whole = |t: &Trace| {
            let mut frames = Vec::new();
            let mut prefix = vec![DVec3::ZERO];
            for (f, p) in t.measurements() {
                frames.push(f);
                prefix.push(prefix[prefix.len() - 1] + p);
            }
            (frames, prefix)
        };
        let mean = |(frames, prefix): &(Vec<i64>, Vec<DVec3>), lo: usize, hi: usize| {
            let hi = hi.min(frames.len());
            (hi > lo).then(|| (prefix[hi] - prefix[lo]) / (hi - lo) as f64)
        };
        let (a, b) = (whole(host), whole(frag));
        let (mut i, mut j) = (0usize, 0usize);
        let mut last: Option<bool> = None;
        let mut worst: Option<f64> = None;
        loop {
            let from_host = match (a.0.get(i), b.0.get(j)) {
                (Some(x), Some(y)) if x == y => return None,
                (Some(x), Some(y)) => x < y,
                (Some(_), None) => true,
                (None, Some(_)) => false,
                (None, None) => break,
            };
            if last.is_some_and(|l| l != from_host) {
                let (before, after) = if from_host {
                    (
                        mean(&b, j.saturating_sub(context), j),
                        mean(&a, i, i + context),
                    )
                } else {
                    (
                        mean(&a, i.saturating_sub(context), i),
                        mean(&b, j, j + context),
                    )
                };
                if let (Some(x), Some(y)) = (before, after) {
                    let d = x.distance(y);
                    worst = Some(worst.map_or(d, |w: f64| w.max(d)));
                }
            }
            last = Some(from_host);
            if from_host {
                i += 1;
            } else {
                j += 1;
            }
        }
        worst
    }

    /// The cost read through windows is the cost of the whole traces, bit
    /// for bit, wherever the fragment lies: before the host, inside a gap,
    /// interleaved, across the end, after it, sharing a frame, and with the
    /// two traces' roles swapped.
    #[test]
    fn windowed_cost_is_the_whole_traces_cost() {
        let at = |n: i64| DVec3::new(0.02 * (n as f64 / 30.0).sin(), 1.0, 0.001 * n as f64);
        let mut host = Trace::new(0, 40, at(40), None);
        for n in (41..700).chain(760..900).filter(|n| n % 7 != 3) {
            host.push(n, at(n), None);
        }
        // Half-open frame ranges of each fragment.
        let spans: [&[(i64, i64)]; 8] = [
            &[(0, 30)],
            &[(0, 45)],
            &[(700, 760)],
            &[(701, 740), (745, 759)],
            &[(850, 1000)],
            &[(910, 990)],
            &[(300, 302)],
            &[(0, 1000)],
        ];
        for (k, ranges) in spans.iter().enumerate() {
            let frames: Vec<i64> = ranges
                .iter()
                .flat_map(|&(a, b)| a..b)
                .filter(|&n| k == 6 || !host.is_measured(n))
                .collect();
            let mut frag = Trace::new(1, frames[0], at(frames[0]) + DVec3::X * 0.003, None);
            for &n in &frames[1..] {
                frag.push(n, at(n) + DVec3::X * 0.003, None);
            }
            for context in [1, 5, 50, 2000] {
                for (x, y) in [(&host, &frag), (&frag, &host)] {
                    let (whole, windowed) =
                        (switch_cost_whole(x, y, context), switch_cost(x, y, context));
                    assert_eq!(
                        whole.map(f64::to_bits),
                        windowed.map(f64::to_bits),
                        "span {k}, context {context}"
                    );
                    assert_eq!(whole.is_none(), k == 6, "span {k}");
                }
            }
        }
    }

    /// Walking a trace as [`switch_cost`] does keeps at most `2 × context
    /// + 1` measurements, however long the trace.
    #[test]
    fn stream_window_stays_bounded() {
        let mut t = Trace::new(0, 0, DVec3::ZERO, None);
        for n in 1..20_000 {
            t.push(n, DVec3::new(n as f64 * 1e-4, 1.0, 0.0), None);
        }
        let context = 24;
        let mut s = Stream::new(t.measurements());
        let mut i = 0;
        while s.frame(i).is_some() {
            s.mean(i.saturating_sub(context), i);
            s.mean(i, i + context);
            assert!(s.window.len() <= 2 * context + 1, "at {i}");
            i += 1;
            s.forget_before(i.saturating_sub(context));
        }
        assert_eq!(i, t.measured());
    }
}
