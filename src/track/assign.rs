//! Global one-to-one assignment between traces and markers (or between
//! trace ends and trace starts): the cheapest total cost, where leaving a
//! row unassigned costs `miss`. First come, first served would let the
//! first trace steal the marker a second trace needs more.
//!
//! Candidate graphs in tracking fall apart into tiny connected components
//! (one trace, one marker, almost always), so each component is solved on
//! its own: exactly (Hungarian method) when small, greedily by cost when it
//! is implausibly large (a gate far too wide for the marker spacing).

/// A candidate pairing of row `row` with column `col` at `cost`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Edge {
    /// What seeks a partner: a trace (or a trace's end, when joining pieces).
    pub row: usize,
    /// What can be taken: a marker of the frame (or a later trace's start).
    pub col: usize,
    /// How far (m) the column lies from where the row predicts it; the
    /// assignment minimises the sum.
    pub cost: f64,
}

/// Components with more rows or columns than this are solved greedily.
pub const MAX_EXACT: usize = 48;

/// Reusable scratch space, so that per-frame tracking does not allocate.
#[derive(Debug, Default)]
pub struct Assigner {
    parent: Vec<usize>,
    /// The valid edges grouped by component, each group in the edges'
    /// order: one flat buffer (a counting sort), not a vector per
    /// component, whose thousand scattered allocations a frame at 1 000
    /// markers were each a cache miss once the caches had been evicted.
    by_comp: Vec<Edge>,
    /// Per valid edge, its component.
    comp_of_edge: Vec<u32>,
    /// Per component, its edge count, then where its group ends in
    /// `by_comp`.
    comp_end: Vec<usize>,
    comp_of_root: Vec<usize>,
    rows: Vec<usize>,
    cols: Vec<usize>,
    cost: Vec<f64>,
    /// Per row and per column, how many valid edges reach it (saturating).
    row_edges: Vec<u8>,
    col_edges: Vec<u8>,
    /// The valid edges not alone in their component.
    shared: Vec<Edge>,
    /// Components solved greedily because they were larger than `MAX_EXACT`.
    pub greedy_components: u64,
}

fn find(parent: &mut [usize], mut x: usize) -> usize {
    while parent[x] != x {
        parent[x] = parent[parent[x]];
        x = parent[x];
    }
    x
}

impl Assigner {
    /// Solves the assignment; writes `Some(col)` or `None` for each row into
    /// `out` (resized to `n_rows`). Edges must have `row < n_rows`,
    /// `col < n_cols`, finite costs; others are ignored.
    pub fn solve(
        &mut self,
        n_rows: usize,
        n_cols: usize,
        edges: &[Edge],
        miss: f64,
        out: &mut Vec<Option<usize>>,
    ) {
        out.clear();
        out.resize(n_rows, None);
        let valid = |e: &&Edge| e.row < n_rows && e.col < n_cols && e.cost.is_finite();
        // An edge whose row and column have no other edge is a component
        // of its own, solved on the spot: nearly every edge of a tracking
        // frame (a trace and its marker). Only the others go through the
        // union-find and the grouping below, which at 1 000 markers cost
        // a frame two passes over 2 000 rows and columns and every edge.
        // The result is the same: components are solved independently, and
        // the others keep their edges' order.
        self.row_edges.clear();
        self.row_edges.resize(n_rows, 0);
        self.col_edges.clear();
        self.col_edges.resize(n_cols, 0);
        for e in edges.iter().filter(valid) {
            self.row_edges[e.row] = self.row_edges[e.row].saturating_add(1);
            self.col_edges[e.col] = self.col_edges[e.col].saturating_add(1);
        }
        let mut shared = std::mem::take(&mut self.shared);
        shared.clear();
        for e in edges.iter().filter(valid) {
            if self.row_edges[e.row] == 1 && self.col_edges[e.col] == 1 {
                if e.cost <= miss {
                    out[e.row] = Some(e.col);
                }
            } else {
                shared.push(*e);
            }
        }
        if !shared.is_empty() {
            self.solve_shared(n_rows, n_cols, &shared, miss, out);
        }
        self.shared = shared;
    }

    /// Solves the components of more than one edge (`edges`, all valid).
    fn solve_shared(
        &mut self,
        n_rows: usize,
        n_cols: usize,
        edges: &[Edge],
        miss: f64,
        out: &mut [Option<usize>],
    ) {
        // Union-find over rows (0..n_rows) and columns (n_rows..).
        self.parent.clear();
        self.parent.extend(0..n_rows + n_cols);
        for e in edges {
            let a = find(&mut self.parent, e.row);
            let b = find(&mut self.parent, n_rows + e.col);
            if a != b {
                self.parent[a] = b;
            }
        }
        self.group(edges, n_rows, n_cols);
        let by_comp = std::mem::take(&mut self.by_comp);
        let mut start = 0;
        for c in 0..self.comp_end.len() {
            let end = self.comp_end[c];
            self.solve_component(&by_comp[start..end], miss, out);
            start = end;
        }
        self.by_comp = by_comp;
    }

    /// Groups the valid edges by component into `by_comp` (components
    /// numbered in the order of their first edge, each group in the edges'
    /// order), `comp_end` ending each group.
    fn group(&mut self, edges: &[Edge], n_rows: usize, n_cols: usize) {
        let valid = |e: &&Edge| e.row < n_rows && e.col < n_cols && e.cost.is_finite();
        self.comp_of_root.clear();
        self.comp_of_root.resize(n_rows + n_cols, usize::MAX);
        self.comp_of_edge.clear();
        self.comp_end.clear();
        for e in edges.iter().filter(valid) {
            let root = find(&mut self.parent, e.row);
            if self.comp_of_root[root] == usize::MAX {
                self.comp_of_root[root] = self.comp_end.len();
                self.comp_end.push(0);
            }
            let c = self.comp_of_root[root];
            self.comp_end[c] += 1;
            self.comp_of_edge.push(c as u32);
        }
        // Counts → each group's start, advanced to its end by the scatter.
        let mut start = 0;
        for n in self.comp_end.iter_mut() {
            let count = *n;
            *n = start;
            start += count;
        }
        self.by_comp.clear();
        self.by_comp.resize(
            start,
            Edge {
                row: 0,
                col: 0,
                cost: 0.0,
            },
        );
        for (e, &c) in edges.iter().filter(valid).zip(&self.comp_of_edge) {
            let at = &mut self.comp_end[c as usize];
            self.by_comp[*at] = *e;
            *at += 1;
        }
    }

    fn solve_component(&mut self, edges: &[Edge], miss: f64, out: &mut [Option<usize>]) {
        if let [e] = edges {
            if e.cost <= miss {
                out[e.row] = Some(e.col);
            }
            return;
        }
        self.rows.clear();
        self.cols.clear();
        for e in edges {
            self.rows.push(e.row);
            self.cols.push(e.col);
        }
        self.rows.sort_unstable();
        self.rows.dedup();
        self.cols.sort_unstable();
        self.cols.dedup();
        let (n, m) = (self.rows.len(), self.cols.len());
        if n > MAX_EXACT || m > MAX_EXACT {
            self.greedy_components += 1;
            greedy(edges, miss, out);
            return;
        }
        // Rows × (real columns + one "unassigned" column per row).
        let width = m + n;
        let forbidden = miss * 4.0 + 1.0;
        self.cost.clear();
        self.cost.resize(n * width, forbidden);
        for i in 0..n {
            for k in 0..n {
                self.cost[i * width + m + k] = miss;
            }
        }
        for e in edges {
            let (Ok(i), Ok(j)) = (
                self.rows.binary_search(&e.row),
                self.cols.binary_search(&e.col),
            ) else {
                continue;
            };
            let slot = &mut self.cost[i * width + j];
            *slot = slot.min(e.cost);
        }
        let assignment = hungarian(&self.cost, n, width);
        for (i, &j) in assignment.iter().enumerate() {
            if j < m && self.cost[i * width + j] <= miss {
                out[self.rows[i]] = Some(self.cols[j]);
            }
        }
    }
}

/// Cheapest edges first, each row and column used once.
fn greedy(edges: &[Edge], miss: f64, out: &mut [Option<usize>]) {
    let mut sorted: Vec<Edge> = edges.iter().copied().filter(|e| e.cost <= miss).collect();
    sorted.sort_by(|a, b| a.cost.total_cmp(&b.cost).then(a.row.cmp(&b.row)));
    let mut used_cols = std::collections::HashSet::new();
    for e in sorted {
        if out[e.row].is_none() && used_cols.insert(e.col) {
            out[e.row] = Some(e.col);
        }
    }
}

/// Hungarian method (Kuhn–Munkres with potentials, O(n²·m)) for an
/// `n × m` row-major cost matrix with `n <= m`; returns each row's column.
fn hungarian(cost: &[f64], n: usize, m: usize) -> Vec<usize> {
    // 1-based arrays as in the classic formulation; index 0 is a sentinel.
    let mut u = vec![0.0; n + 1];
    let mut v = vec![0.0; m + 1];
    let mut p = vec![0usize; m + 1];
    let mut way = vec![0usize; m + 1];
    for i in 1..=n {
        p[0] = i;
        let mut j0 = 0;
        let mut minv = vec![f64::INFINITY; m + 1];
        let mut used = vec![false; m + 1];
        loop {
            used[j0] = true;
            let i0 = p[j0];
            let mut delta = f64::INFINITY;
            let mut j1 = 0;
            for j in 1..=m {
                if !used[j] {
                    let cur = cost[(i0 - 1) * m + (j - 1)] - u[i0] - v[j];
                    if cur < minv[j] {
                        minv[j] = cur;
                        way[j] = j0;
                    }
                    if minv[j] < delta {
                        delta = minv[j];
                        j1 = j;
                    }
                }
            }
            for j in 0..=m {
                if used[j] {
                    u[p[j]] += delta;
                    v[j] -= delta;
                } else {
                    minv[j] -= delta;
                }
            }
            j0 = j1;
            if p[j0] == 0 {
                break;
            }
        }
        loop {
            let j1 = way[j0];
            p[j0] = p[j1];
            j0 = j1;
            if j0 == 0 {
                break;
            }
        }
    }
    let mut result = vec![0usize; n];
    for j in 1..=m {
        if p[j] != 0 {
            result[p[j] - 1] = j - 1;
        }
    }
    result
}

#[cfg(test)]
mod tests {
    use super::*;

    fn e(row: usize, col: usize, cost: f64) -> Edge {
        Edge { row, col, cost }
    }

    fn brute(n_rows: usize, n_cols: usize, edges: &[Edge], miss: f64) -> f64 {
        // Exhaustive search over all partial matchings.
        fn go(r: usize, n_rows: usize, used: &mut Vec<bool>, edges: &[Edge], miss: f64) -> f64 {
            if r == n_rows {
                return 0.0;
            }
            let mut best = miss + go(r + 1, n_rows, used, edges, miss);
            for ed in edges.iter().filter(|ed| ed.row == r && ed.cost <= miss) {
                if !used[ed.col] {
                    used[ed.col] = true;
                    best = best.min(ed.cost + go(r + 1, n_rows, used, edges, miss));
                    used[ed.col] = false;
                }
            }
            best
        }
        go(0, n_rows, &mut vec![false; n_cols], edges, miss)
    }

    fn total(out: &[Option<usize>], edges: &[Edge], miss: f64) -> f64 {
        out.iter()
            .enumerate()
            .map(|(r, c)| match c {
                None => miss,
                Some(c) => edges
                    .iter()
                    .filter(|e| e.row == r && e.col == *c)
                    .map(|e| e.cost)
                    .fold(f64::INFINITY, f64::min),
            })
            .sum()
    }

    #[test]
    fn global_beats_first_come_first_served() {
        // Row 0 is nearest to column 0, but row 1 can only take column 0;
        // greedy would leave row 1 out (total 1 + 10), the optimum is 2 + 3.
        let edges = [e(0, 0, 1.0), e(0, 1, 2.0), e(1, 0, 3.0)];
        let mut a = Assigner::default();
        let mut out = Vec::new();
        a.solve(2, 2, &edges, 10.0, &mut out);
        assert_eq!(out, vec![Some(1), Some(0)]);
    }

    #[test]
    fn leaving_a_row_out_can_be_cheapest() {
        let edges = [e(0, 0, 1.0), e(1, 0, 1.5), e(1, 1, 9.0)];
        let mut a = Assigner::default();
        let mut out = Vec::new();
        a.solve(2, 2, &edges, 5.0, &mut out);
        // 1 + 5 (row 1 unassigned) beats 1.5 + 5 and 1 + 9.
        assert_eq!(out, vec![Some(0), None]);
    }

    #[test]
    fn matches_exhaustive_search_on_random_graphs() {
        let mut rng = crate::rng::Rng::new(3);
        let mut a = Assigner::default();
        let mut out = Vec::new();
        for _ in 0..300 {
            let n = rng.int(1, 6) as usize;
            let m = rng.int(1, 6) as usize;
            let mut edges = Vec::new();
            for r in 0..n {
                for c in 0..m {
                    if rng.chance(0.5) {
                        edges.push(e(r, c, rng.range(0.0, 1.2)));
                    }
                }
            }
            a.solve(n, m, &edges, 1.0, &mut out);
            let mut cols: Vec<_> = out.iter().flatten().collect();
            let k = cols.len();
            cols.sort();
            cols.dedup();
            assert_eq!(cols.len(), k, "a column used twice");
            let got = total(&out, &edges, 1.0);
            let want = brute(n, m, &edges, 1.0);
            assert!((got - want).abs() < 1e-9, "{got} vs {want}");
        }
    }

    #[test]
    fn bad_edges_are_ignored() {
        let edges = [e(5, 0, 1.0), e(0, 9, 1.0), e(0, 0, f64::NAN), e(0, 1, 0.5)];
        let mut a = Assigner::default();
        let mut out = Vec::new();
        a.solve(1, 2, &edges, 1.0, &mut out);
        assert_eq!(out, vec![Some(1)]);
    }
}
