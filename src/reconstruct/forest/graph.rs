//! Livny et al. 2010's rule for several trees in one scan: a neighbourhood
//! graph over the points and the trees' roots, and every point given to the
//! root its shortest path reaches most cheaply.
//!
//! Our graph: every tip joined to its `k` nearest nodes (both ways); every
//! trunk base carries a vertical column of nodes 0.1 m apart up to the
//! highest tip, standing in for the wood a laser scan would show. Edges
//! cost their length squared, so a path prefers many short hops along a
//! crown to one long jump. A search from one base may not pass through
//! another tree's column.

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use glam::DVec3;

/// Spacing of the column nodes above a base (m).
const COLUMN_STEP: f64 = 0.1;

/// The cost of the cheapest path from every base to every tip:
/// `costs[tip][tree]` (infinite where no path exists).
pub fn path_costs(tips: &[DVec3], bases: &[DVec3], k: usize) -> Vec<Vec<f64>> {
    let top = tips.iter().map(|p| p.y).fold(f64::NEG_INFINITY, f64::max);
    let mut nodes: Vec<DVec3> = tips.to_vec();
    // owner[i]: the tree whose column node i is; None for tips.
    let mut owner: Vec<Option<usize>> = vec![None; tips.len()];
    for (b, base) in bases.iter().enumerate() {
        let rise = (top - base.y).max(0.0);
        let n = (rise / COLUMN_STEP).ceil() as usize + 1;
        for i in 0..n.max(2) {
            let f = i as f64 / (n.max(2) - 1) as f64;
            nodes.push(*base + DVec3::Y * (rise * f));
            owner.push(Some(b));
        }
    }
    let adjacency = neighbours(&nodes, &owner, tips.len(), k);
    let mut costs = vec![vec![f64::INFINITY; bases.len()]; tips.len()];
    for b in 0..bases.len() {
        let dist = dijkstra(&nodes, &owner, &adjacency, b);
        for (t, row) in costs.iter_mut().enumerate() {
            row[b] = dist[t];
        }
    }
    costs
}

/// Each tip's `k` nearest nodes, both ways, and each column node's
/// neighbours above and below it.
fn neighbours(nodes: &[DVec3], owner: &[Option<usize>], tips: usize, k: usize) -> Vec<Vec<usize>> {
    let mut adjacency = vec![Vec::new(); nodes.len()];
    let mut order: Vec<usize> = Vec::with_capacity(nodes.len());
    for i in 0..nodes.len() {
        order.clear();
        order.extend((0..nodes.len()).filter(|&j| j != i));
        order.sort_by(|&a, &b| {
            nodes[i]
                .distance_squared(nodes[a])
                .total_cmp(&nodes[i].distance_squared(nodes[b]))
                .then(a.cmp(&b))
        });
        for &j in order.iter().take(k) {
            adjacency[i].push(j);
            adjacency[j].push(i);
        }
    }
    for i in tips..nodes.len().saturating_sub(1) {
        if owner[i].is_some() && owner[i] == owner[i + 1] {
            adjacency[i].push(i + 1);
            adjacency[i + 1].push(i);
        }
    }
    for a in &mut adjacency {
        a.sort_unstable();
        a.dedup();
    }
    adjacency
}

/// A node of the search queue, cheapest first (ties to the lower index).
#[derive(PartialEq)]
struct Queued(f64, usize);

impl Eq for Queued {}

impl Ord for Queued {
    fn cmp(&self, other: &Self) -> Ordering {
        other.0.total_cmp(&self.0).then(other.1.cmp(&self.1))
    }
}

impl PartialOrd for Queued {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

/// Cheapest path cost from tree `b`'s column to every node.
fn dijkstra(
    nodes: &[DVec3],
    owner: &[Option<usize>],
    adjacency: &[Vec<usize>],
    b: usize,
) -> Vec<f64> {
    let mut dist = vec![f64::INFINITY; nodes.len()];
    let mut queue = BinaryHeap::new();
    for (i, o) in owner.iter().enumerate() {
        if *o == Some(b) {
            dist[i] = 0.0;
            queue.push(Queued(0.0, i));
        }
    }
    while let Some(Queued(d, i)) = queue.pop() {
        if d > dist[i] {
            continue;
        }
        for &j in &adjacency[i] {
            if matches!(owner[j], Some(o) if o != b) {
                continue;
            }
            let nd = d + nodes[i].distance_squared(nodes[j]);
            if nd < dist[j] {
                dist[j] = nd;
                queue.push(Queued(nd, j));
            }
        }
    }
    dist
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_separate_clumps_go_to_their_own_base() {
        let mut tips = Vec::new();
        for i in 0..10 {
            let a = i as f64 * 0.6;
            tips.push(DVec3::new(
                0.3 * a.cos(),
                1.0 + 0.05 * i as f64,
                0.3 * a.sin(),
            ));
            tips.push(DVec3::new(3.0 + 0.3 * a.cos(), 1.2, 0.3 * a.sin()));
        }
        let bases = [DVec3::ZERO, DVec3::new(3.0, 0.0, 0.0)];
        let costs = path_costs(&tips, &bases, 4);
        for (i, c) in costs.iter().enumerate() {
            let want = i % 2;
            assert!(c[want] < c[1 - want], "tip {i}: {c:?}");
        }
    }
}
