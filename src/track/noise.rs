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
                joined.append(&piece);
            }
        }
        out.push(joined);
    }
    out.sort_by_key(|t| t.id);
    (out, joins)
}

/// Splits traces into those measured in at least `fraction` of `frames`
/// and the noise.
pub fn drop_noise(
    traces: Vec<Trace>,
    frames: u64,
    fraction: f64,
) -> (Vec<Trace>, Vec<DroppedTrace>) {
    let min = fraction * frames as f64;
    let mut kept = Vec::new();
    let mut dropped = Vec::new();
    for t in traces {
        if (t.measured() as f64) < min {
            dropped.push(DroppedTrace {
                id: t.id,
                measured: t.measured(),
                fraction: t.measured() as f64 / frames.max(1) as f64,
                first_frame: t.first_frame(),
                last_frame: t.last_frame(),
            });
        } else {
            kept.push(t);
        }
    }
    (kept, dropped)
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
        let (kept, dropped) = drop_noise(traces, 100, 0.25);
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
/// the fragment's `context` measurements on that side. Tips are
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
        let fragments: Vec<(usize, i64, i64, DVec3, DVec3)> = slots
            .iter()
            .enumerate()
            .filter(|(i, _)| !has_rest.get(*i).copied().unwrap_or(false))
            .filter_map(|(i, t)| {
                let t = t.as_ref()?;
                if t.measured() < min_len {
                    return None;
                }
                let (head, tail) = end_means(t.measurements(), context as usize);
                Some((i, t.first_frame(), t.last_frame(), head?, tail?))
            })
            .collect();
        let mut edges = Vec::new();
        for (row, &(_, s, e, head, tail)) in fragments.iter().enumerate() {
            for (col, &h) in hosts.iter().enumerate() {
                let Some(host) = slots[h].as_ref() else {
                    continue;
                };
                if host.measured_between(s, e) > 0 {
                    continue;
                }
                let before = end_means(
                    host.measurements().take_while(|m| m.0 < s),
                    context as usize,
                )
                .1;
                let after = end_means(
                    host.measurements().skip_while(|m| m.0 <= e),
                    context as usize,
                )
                .0;
                let cost = match (before, after) {
                    (Some(b), Some(a)) => b.distance(head).max(a.distance(tail)),
                    (Some(b), None) => b.distance(head),
                    (None, Some(a)) => a.distance(tail),
                    (None, None) => continue,
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
            let (Some(col), Some(&(frag, ..))) = (*col, fragments.get(row)) else {
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
            }
        }
        joins += joined_now;
        if joined_now == 0 {
            break;
        }
    }
    (slots.into_iter().flatten().collect(), joins)
}

/// Means of the first and of the last `n` positions of a sequence.
fn end_means(
    items: impl Iterator<Item = (i64, DVec3)>,
    n: usize,
) -> (Option<DVec3>, Option<DVec3>) {
    let n = n.max(1);
    let mut head = (0usize, DVec3::ZERO);
    let mut tail = std::collections::VecDeque::with_capacity(n + 1);
    let mut tail_sum = DVec3::ZERO;
    for (_, p) in items {
        if head.0 < n {
            head = (head.0 + 1, head.1 + p);
        }
        tail.push_back(p);
        tail_sum += p;
        if tail.len() > n {
            if let Some(old) = tail.pop_front() {
                tail_sum -= old;
            }
        }
    }
    if head.0 == 0 {
        return (None, None);
    }
    (
        Some(head.1 / head.0 as f64),
        Some(tail_sum / tail.len() as f64),
    )
}

#[cfg(test)]
mod gap_join_tests {
    use super::*;

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
}
