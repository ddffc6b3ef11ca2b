//! The daemon's best knowledge of the tips' rest positions, across analyses.
//!
//! Every analysis finds the still phase inside the recent window and
//! averages the tips over it. While a still phase goes on, each analysis
//! sees more of it and its rest positions get better: the newest wins.
//! Once the window's start cuts into the phase (the window slides past it,
//! or wind follows), later analyses see less of it: the estimate made from
//! more of the phase is kept. A still phase that does not overlap the kept
//! one (the tree was moved, markers were added), or rests that no longer
//! match the kept ones, replace it. Pure logic, so each rule is tested.

use glam::DVec3;

use super::triggers::compare_tips;

/// Rest positions from one analysis and what they are worth.
#[derive(Debug, Clone)]
pub struct RestEstimate<T> {
    /// The tips' rest positions.
    pub positions: Vec<DVec3>,
    /// The still phase they were averaged over (s, capture clock).
    pub window_s: [f64; 2],
    /// What goes with them (the tips to build from, tips.json).
    pub payload: T,
}

impl<T> RestEstimate<T> {
    /// Seconds of still phase behind the positions.
    pub fn len_s(&self) -> f64 {
        self.window_s[1] - self.window_s[0]
    }
}

/// Keeps the best rest estimate seen.
#[derive(Debug, Clone)]
pub struct BestRest<T> {
    best: Option<RestEstimate<T>>,
    /// Tips closer than this are the same tip (`daemon.moved_mm`).
    moved_m: f64,
}

impl<T> BestRest<T> {
    /// No estimate yet; `moved_m` is the distance within which two rest
    /// positions count as the same tip.
    pub fn new(moved_m: f64) -> Self {
        BestRest {
            best: None,
            moved_m,
        }
    }

    /// Offers the rest positions of a new analysis; true when they are now
    /// the best estimate.
    pub fn offer(&mut self, new: RestEstimate<T>) -> bool {
        let keep_old = self.best.as_ref().is_some_and(|old| {
            let same_phase = new.window_s[0] < old.window_s[1];
            let shorter = new.len_s() < old.len_s();
            let same_tips = compare_tips(&old.positions, &new.positions, self.moved_m) == (0, 0, 0);
            same_phase && shorter && same_tips
        });
        if !keep_old {
            self.best = Some(new);
        }
        !keep_old
    }

    /// The best estimate so far.
    pub fn get(&self) -> Option<&RestEstimate<T>> {
        self.best.as_ref()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn est(a: f64, b: f64, x: f64) -> RestEstimate<()> {
        RestEstimate {
            positions: vec![DVec3::new(x, 1.5, 0.0), DVec3::new(0.5, 1.2, 0.0)],
            window_s: [a, b],
            payload: (),
        }
    }

    #[test]
    fn grows_with_the_still_phase_and_keeps_the_longest_view_of_it() {
        let mut b = BestRest::new(0.01);
        assert!(b.offer(est(0.0, 5.0, 0.0)));
        assert!(
            b.offer(est(0.0, 20.0, 0.0005)),
            "the phase went on: newer wins"
        );
        assert_eq!(b.get().unwrap().window_s, [0.0, 20.0]);
        // The window slid past the start of the phase: less of it is seen.
        assert!(!b.offer(est(8.0, 20.0, 0.0004)));
        assert_eq!(b.get().unwrap().window_s, [0.0, 20.0]);
        // A tip moved beyond the tolerance in that shorter view: take it.
        assert!(b.offer(est(8.0, 20.0, 0.05)));
        // A later still phase, after wind: newer wins even if shorter.
        assert!(b.offer(est(40.0, 45.0, 0.05)));
        assert_eq!(b.get().unwrap().window_s, [40.0, 45.0]);
    }
}
