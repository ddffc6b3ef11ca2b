//! Sorting a frame's `(key, index)` pairs by key in linear time.
//!
//! The tracker sorts every frame's markers along x (the duplicate sweep)
//! and, one frame in sixteen live, its traces' predictions (the spacing
//! check): a thousand pairs each at 1 000 markers, where a comparison sort
//! was a sixth of a live frame's instructions. The keys are x's bits made
//! to sort as `f64::total_cmp` does (`tracker::ordered_bits`), and the pairs
//! come in index order, so a stable least-significant-digit radix sort
//! gives exactly the comparison sort's order: by key, equal keys by index.
//! Bytes that every key shares (the sign and exponent of positions within
//! a capture volume, mostly) are skipped.

/// Sorts `items` (in increasing `.1` order) by `.0`, then `.1`; `scratch`
/// is reused across calls.
pub(crate) fn sort_pairs(items: &mut Vec<(u64, usize)>, scratch: &mut Vec<(u64, usize)>) {
    let n = items.len();
    if n < 64 {
        // Small: the standard sort is cheaper than eight histograms.
        items.sort_unstable();
        return;
    }
    let mut counts = [[0usize; 256]; 8];
    for &(k, _) in items.iter() {
        for (b, c) in counts.iter_mut().enumerate() {
            c[((k >> (8 * b)) & 0xFF) as usize] += 1;
        }
    }
    scratch.clear();
    scratch.resize(n, (0, 0));
    for (b, c) in counts.iter_mut().enumerate() {
        if c.contains(&n) {
            continue; // every key has this byte: the pass would move nothing
        }
        let mut start = 0;
        for slot in c.iter_mut() {
            let count = *slot;
            *slot = start;
            start += count;
        }
        for &item in items.iter() {
            let d = ((item.0 >> (8 * b)) & 0xFF) as usize;
            scratch[c[d]] = item;
            c[d] += 1;
        }
        std::mem::swap(items, scratch);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    /// The same order as the comparison sort, on keys with shared and
    /// varying bytes, duplicates, and small and large inputs.
    #[test]
    fn sorts_as_the_comparison_sort_does() {
        let mut rng = Rng::new(11);
        let mut scratch = Vec::new();
        for n in [0, 1, 5, 63, 64, 65, 1000, 3000] {
            for spread in [0u64, 0xFF, 0xFFFF_FFFF, u64::MAX] {
                let base = rng.next_u64();
                let mut items: Vec<(u64, usize)> = (0..n)
                    .map(|i| {
                        let r = rng.next_u64() & spread;
                        // A few repeated keys: ties keep index order.
                        let k = if i % 7 == 0 { base } else { base ^ r };
                        (k, i)
                    })
                    .collect();
                let mut want = items.clone();
                want.sort_unstable();
                sort_pairs(&mut items, &mut scratch);
                assert_eq!(items, want, "n {n}, spread {spread:x}");
            }
        }
    }
}
