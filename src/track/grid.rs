//! A uniform grid over one frame's markers, for the tracker's gate search.
//!
//! Every frame the tracker asks, for each live trace, which markers lie
//! within the gate of its prediction. With 1 000 markers a k-d tree built
//! per frame answered that in about a third of the frame's cost: building
//! it sorts the points along every level, and each query walks and sorts.
//! The gate is one fixed radius, so a grid whose cells are twice the gate
//! wide answers a query from at most 2 × 2 × 2 cells, and it is built in
//! linear time, the points counted into a hash table of their cells. The
//! grid keeps its buffers across frames,
//! so a frame allocates nothing once the largest frame has been seen.

/// One frame's points bucketed by cell.
#[derive(Debug, Default)]
pub(crate) struct Grid {
    /// Cell width (m): twice the search radius.
    cell: f64,
    /// Point indices grouped by cell: a cell's points are one run, in
    /// index order.
    ///
    /// Each with a copy of its point: a query reads a cell's points in a
    /// row instead of looking each up among the frame's points (a load
    /// that depended on the index before it, a tenth of the search).
    entries: Vec<([f64; 3], u32)>,
    /// Open-addressing table of the occupied cells: `(key, start, end)`
    /// into `entries`; `EMPTY` keys are free slots.
    table: Vec<(u64, u32, u32)>,
    /// Per point, its cell's slot in `table` (`build`'s scratch).
    slot_of: Vec<u32>,
    /// `table.len() - 1` (a power of two minus one).
    mask: usize,
    /// One bit per hash of an occupied cell: most of a query's eight cells
    /// are empty, and a bit test in 8 KB (in L1) answers those without
    /// probing the table (a cache miss and a mispredicted branch each).
    occupied: Vec<u64>,
    /// A query's hits, reused.
    hits: Vec<(f64, u32)>,
}

/// A key no cell has: cell coordinates are clamped to 21 bits each, so
/// packed keys leave the top bit clear.
const EMPTY: u64 = u64::MAX;

/// Cell coordinates are kept in 21 bits (±1 048 575 cells): with the
/// smallest sensible gate (1 mm, cells of 2 mm) that is ±2 km, far beyond
/// any capture volume; a point beyond is clamped into the outermost cell,
/// which only costs a few extra distance checks.
const HALF_RANGE: i64 = (1 << 20) - 1;

fn coordinate(v: f64, inv: f64) -> i64 {
    // NaN never reaches here (the tracker drops non-finite markers);
    // `as` saturates infinities, and the clamp does the rest. The floor is
    // written out: the baseline x86-64 target has no rounding instruction,
    // and `f64::floor` was a call into libm for each of the 9 coordinates a
    // query and a point take (2 % of a live frame at 1 000 markers). The
    // result is the same: truncation rounds towards zero, so a negative
    // non-integer moves down by one.
    let x = v * inv;
    let t = x as i64;
    let floor = if (t as f64) > x { t - 1 } else { t };
    floor.clamp(-HALF_RANGE, HALF_RANGE)
}

fn pack(x: i64, y: i64, z: i64) -> u64 {
    let b = |c: i64| (c + HALF_RANGE) as u64;
    (b(x) << 42) | (b(y) << 21) | b(z)
}

/// Bits of the occupancy filter: 2^16, 8 KB.
const FILTER_BITS: u32 = 16;

fn filter_bit(key: u64) -> usize {
    (key.wrapping_mul(0xD6E8_FEB8_6659_FD93) >> (64 - FILTER_BITS)) as usize
}

fn slot(key: u64, mask: usize) -> usize {
    // Fibonacci hashing: the product's top bits depend on every bit of the
    // key (its low bits would ignore x, packed high), and neighbouring cells
    // land far apart in the table.
    let bits = mask.count_ones();
    (key.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> (64 - bits)) as usize
}

impl Grid {
    /// Buckets `points` for searches of radius up to `radius`: each point
    /// is counted in its cell's slot of the table, the counts become runs
    /// of `entries`, and the points are put in their runs in index order
    /// (a counting sort through the table: a comparison sort of the points
    /// by cell was a sixth of a live frame at 1 000 markers).
    pub(crate) fn build(&mut self, points: &[[f64; 3]], radius: f64) {
        self.cell = (2.0 * radius).max(1e-6);
        let inv = 1.0 / self.cell;
        let size = (2 * points.len()).next_power_of_two().max(16);
        self.table.clear();
        self.table.resize(size, (EMPTY, 0, 0));
        self.mask = size - 1;
        self.occupied.clear();
        self.occupied.resize(1 << (FILTER_BITS - 6), 0);
        self.slot_of.clear();
        for p in points {
            let key = pack(
                coordinate(p[0], inv),
                coordinate(p[1], inv),
                coordinate(p[2], inv),
            );
            let s = self.insert(key);
            self.table[s].2 += 1;
            self.slot_of.push(s as u32);
        }
        // Counts → starts (in table order; a run's place in `entries`
        // matters to no query).
        let mut start = 0;
        for e in self.table.iter_mut().filter(|e| e.0 != EMPTY) {
            let count = e.2;
            (e.1, e.2) = (start, start);
            start += count;
        }
        self.entries.clear();
        self.entries.resize(points.len(), ([0.0; 3], 0));
        for (i, &s) in self.slot_of.iter().enumerate() {
            let e = &mut self.table[s as usize];
            self.entries[e.2 as usize] = (points[i], i as u32);
            e.2 += 1;
        }
    }

    /// The table slot of cell `key`, taken (and marked in `occupied`) if
    /// the cell had none.
    fn insert(&mut self, key: u64) -> usize {
        let mut s = slot(key, self.mask);
        loop {
            let k = self.table[s].0;
            if k == key {
                return s;
            }
            if k == EMPTY {
                self.table[s].0 = key;
                let b = filter_bit(key);
                self.occupied[b >> 6] |= 1 << (b & 63);
                return s;
            }
            s = (s + 1) & self.mask;
        }
    }

    /// Prefetches the grid's buffers (`track::warm`).
    pub(crate) fn warm(&self) {
        use super::warm::prefetch;
        prefetch(&self.entries);
        prefetch(&self.table);
        prefetch(&self.occupied);
    }

    /// Whether cell `key` may hold points (a false positive now and then,
    /// never a false negative).
    fn maybe_occupied(&self, key: u64) -> bool {
        let b = filter_bit(key);
        self.occupied[b >> 6] & (1 << (b & 63)) != 0
    }

    /// The cell's points (a run of `entries`), empty if none.
    fn run(&self, key: u64) -> std::ops::Range<usize> {
        if !self.maybe_occupied(key) {
            return 0..0;
        }
        self.probe(key)
    }

    /// The cell's points, looked up in the table.
    fn probe(&self, key: u64) -> std::ops::Range<usize> {
        let (table, mask) = (&self.table, self.mask);
        let mut s = slot(key, mask);
        loop {
            let (k, a, b) = table[s];
            if k == key {
                return a as usize..b as usize;
            }
            if k == EMPTY {
                return 0..0;
            }
            s = (s + 1) & mask;
        }
    }

    /// The points within `radius` of `q` (`radius` at most the one the
    /// grid was built for), as `(squared distance, index)` nearest first,
    /// ties by index: the order a sorted k-d tree query gives.
    /// The points are those of the latest `build`.
    pub(crate) fn within(&mut self, q: [f64; 3], radius: f64) -> &[(f64, u32)] {
        self.hits.clear();
        if self.entries.is_empty() {
            return &self.hits;
        }
        let inv = 1.0 / self.cell;
        let r2 = radius * radius;
        // The cells the query's box touches, 1 or 2 along each axis; their
        // bounds are taken once (they were recomputed in every inner loop,
        // inclusive ranges at that, a fifth of the search's instructions).
        let lo = q.map(|c| coordinate(c - radius, inv));
        let hi = q.map(|c| coordinate(c + radius, inv));
        let scan = |grid: &mut Grid, run: std::ops::Range<usize>| {
            for &(p, i) in &grid.entries[run] {
                let d2 = (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2);
                if d2 <= r2 {
                    grid.hits.push((d2, i));
                }
            }
        };
        if (0..3).all(|a| hi[a] == lo[a] + 1) {
            // The usual box: 2 × 2 × 2 cells. Their filter bits are read
            // into one mask first and only the cells it marks are looked
            // up: a branch per cell on whether it is occupied (most are
            // not, at random) was mispredicted often enough to be a fifth
            // of the search. The cells are visited in the same order as
            // below, so the hits are the same.
            let mut keys = [0u64; 8];
            let mut occupied = 0u32;
            for (k, key) in keys.iter_mut().enumerate() {
                *key = pack(
                    lo[0] + (k >> 2) as i64,
                    lo[1] + ((k >> 1) & 1) as i64,
                    lo[2] + (k & 1) as i64,
                );
                occupied |= u32::from(self.maybe_occupied(*key)) << k;
            }
            while occupied != 0 {
                let k = occupied.trailing_zeros() as usize;
                occupied &= occupied - 1;
                let run = self.probe(keys[k]);
                scan(self, run);
            }
        } else {
            for x in lo[0]..hi[0] + 1 {
                for y in lo[1]..hi[1] + 1 {
                    for z in lo[2]..hi[2] + 1 {
                        let run = self.run(pack(x, y, z));
                        scan(self, run);
                    }
                }
            }
        }
        if self.hits.len() > 1 {
            self.hits
                .sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        }
        &self.hits
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    /// The grid finds exactly the points a brute-force scan finds, in
    /// distance order, including points on cell borders and far outside.
    #[test]
    fn the_grid_finds_what_a_scan_finds() {
        let mut rng = Rng::new(7);
        let mut points: Vec<[f64; 3]> = (0..2000)
            .map(|_| {
                [
                    rng.range(-2.0, 2.0),
                    rng.range(0.0, 3.0),
                    rng.range(-2.0, 2.0),
                ]
            })
            .collect();
        // On cell borders (cells of 0.1 m for a 0.05 m radius) and far away.
        points.push([0.1, 0.2, 0.3]);
        points.push([0.1, 0.2, 0.35]);
        points.push([1e9, -1e9, 0.0]);
        let mut grid = Grid::default();
        let radius = 0.05;
        grid.build(&points, radius);
        for k in 0..500 {
            let q = if k < 3 {
                points[2000 + k]
            } else {
                [
                    rng.range(-2.1, 2.1),
                    rng.range(-0.1, 3.1),
                    rng.range(-2.1, 2.1),
                ]
            };
            let mut want: Vec<(f64, u32)> = points
                .iter()
                .enumerate()
                .map(|(i, p)| {
                    let d2 = (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2);
                    (d2, i as u32)
                })
                .filter(|h| h.0 <= radius * radius)
                .collect();
            want.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            assert_eq!(grid.within(q, radius), &want[..], "query {k} at {q:?}");
        }
    }
}
