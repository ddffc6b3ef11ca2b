//! The stress sweep's gap fills by length, scored and logged the one way
//! the tests that bound them read them.

use treemocap::sim::score::{self, Score};

/// One gap-length bin of a sweep's score.
pub struct Bin {
    /// Shortest and longest gap (frames).
    pub lo: i64,
    pub hi: i64,
    /// True gaps in the wind phase, and how many of them were filled.
    pub gaps: usize,
    pub filled: usize,
    /// Mean error of our fills and of PCHIP with perfect identity (m).
    pub ours: f64,
    pub pchip: f64,
}

/// The bins of `total` at 240 Hz (1–10, 11–50, 51 f–2 s), each printed so
/// a failing test's log shows all of them.
pub fn bins(total: &Score) -> Vec<Bin> {
    score::fill_bins(240.0)
        .into_iter()
        .map(|(lo, hi)| {
            let (gaps, filled, ours, pchip) = total.fill_bin(lo, hi);
            println!(
                "gaps {lo}-{hi} frames: {filled}/{gaps} filled, {:.3} mm (PCHIP, perfect identity: {:.3} mm)",
                ours * 1000.0,
                pchip * 1000.0
            );
            Bin {
                lo,
                hi,
                gaps,
                filled,
                ours,
                pchip,
            }
        })
        .collect()
}

impl Bin {
    /// Asserts that at least `min` gaps and `percent` % of them were filled.
    pub fn assert_filled(&self, percent: usize, min: usize) {
        assert!(
            self.filled >= min && self.filled * 100 >= self.gaps * percent,
            "{}-{}: {}/{} filled",
            self.lo,
            self.hi,
            self.filled,
            self.gaps
        );
    }

    /// Asserts that our mean error is at most `limit` × PCHIP's (plus
    /// `slack`, m).
    pub fn assert_within(&self, limit: f64, slack: f64) {
        assert!(
            self.ours <= limit * self.pchip + slack,
            "{}-{}: {} > {limit} × PCHIP {}",
            self.lo,
            self.hi,
            self.ours,
            self.pchip
        );
    }
}
