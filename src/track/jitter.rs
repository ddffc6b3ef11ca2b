//! The capture's measurement noise, learnt on line from the traces.
//!
//! `tracking.noise_mm` tells the filters how much a marker jitters. A
//! filter told less than the truth reads the excess as motion: its process
//! noise grows, its prediction grows unsure within a few frames of a miss,
//! and traces break at every occlusion (σ 1 mm with 25 % occluded: tips
//! never confirmed). So the tracker measures the noise itself and uses the
//! larger of the two.
//!
//! The measure is the third difference of a trace's positions over four
//! consecutive frames, `z₃ − 3z₂ + 3z₁ − z₀`: white noise of σ per axis gives
//! it a variance of 20 σ², while a swaying tip's own motion adds
//! `A ω³ Δt³` (150 mm at 3 Hz, 240 Hz: 0.07 mm), far below the noise. Its
//! median absolute value per axis, 0.6745 × √20 σ for Gaussian noise, is
//! robust to the few frames where a trace took a wrong marker. Medians are
//! taken over batches of [`BATCH`] values, so the estimate changes a few
//! times a second at most and the same input gives the same estimate.

use glam::DVec3;

use crate::model::trace::Trace;

/// Values per median.
const BATCH: usize = 4096;
/// Median |third difference| per axis / σ for Gaussian noise: 0.6745 √20.
const MEDIAN_PER_SIGMA: f64 = 0.6745 * 4.472_135_955;

/// The running estimate and the batch being collected.
#[derive(Debug, Clone, Default)]
pub(crate) struct Jitter {
    /// Absolute third differences per axis (m) of the current batch.
    batch: Vec<f64>,
    /// σ per axis from the latest full batch (m); 0 until one is full.
    sigma: f64,
    /// The batch's bit patterns, for the median (reused).
    bits: Vec<u64>,
}

/// The median (the `len / 2`-th smallest) of `values`, which are absolute
/// values (non-negative, `+0.0` at the least; NaN never reaches here: the
/// tracker drops non-finite markers). Their bit patterns then sort as the
/// values do, so the median is selected among integers, compared in one
/// instruction each, not by `f64::total_cmp` (its bit twiddling on every
/// comparison was most of a median of 4 096 values, taken every frame or
/// two at 1 000 markers). The value selected is the same either way.
fn median_of_magnitudes(values: &[f64], bits: &mut Vec<u64>) -> f64 {
    bits.clear();
    bits.extend(values.iter().map(|v| v.to_bits()));
    let mid = bits.len() / 2;
    match bits.get(mid) {
        Some(_) => f64::from_bits(*bits.select_nth_unstable(mid).1),
        None => 0.0,
    }
}

impl Jitter {
    /// Notes the third difference of a trace measured in four consecutive
    /// frames; returns whether a batch completed (the estimate changed).
    pub(crate) fn observe(&mut self, d3: DVec3) -> bool {
        self.batch.extend([d3.x.abs(), d3.y.abs(), d3.z.abs()]);
        if self.batch.len() < BATCH {
            return false;
        }
        self.sigma = median_of_magnitudes(&self.batch, &mut self.bits) / MEDIAN_PER_SIGMA;
        self.batch.clear();
        true
    }

    /// Measurement noise σ per axis (m) seen in the latest batch.
    pub(crate) fn sigma(&self) -> f64 {
        self.sigma
    }
}

/// Values the after-the-session estimate ([`noise_of`]) looks at, at most.
const SAMPLE_MAX: usize = 30_000;

/// Measurement noise σ per axis (m) of recorded traces: the median of the
/// third differences of up to [`SAMPLE_MAX`] values, spread evenly over the
/// traces' runs of four consecutive measured frames; 0 when there are none.
pub(crate) fn noise_of(traces: &[Trace]) -> f64 {
    let runs: usize = traces.iter().map(|t| t.measured()).sum();
    let stride = (3 * runs).div_ceil(SAMPLE_MAX).max(1);
    let mut values = Vec::new();
    let mut k = 0usize;
    for t in traces {
        let mut last: [(i64, DVec3); 4] = [(i64::MIN, DVec3::ZERO); 4];
        for m in t.measurements() {
            last = [last[1], last[2], last[3], m];
            let consecutive = (1..4).all(|i| last[i].0 == last[i - 1].0 + 1);
            if !consecutive {
                continue;
            }
            k += 1;
            if k.is_multiple_of(stride) {
                let d = third_difference([last[0].1, last[1].1, last[2].1, last[3].1]);
                values.extend([d.x.abs(), d.y.abs(), d.z.abs()]);
            }
        }
    }
    if values.is_empty() {
        return 0.0;
    }
    let mid = values.len() / 2;
    let (_, median, _) = values.select_nth_unstable_by(mid, f64::total_cmp);
    *median / MEDIAN_PER_SIGMA
}

/// The third difference of four positions, oldest first.
pub(crate) fn third_difference(z: [DVec3; 4]) -> DVec3 {
    z[3] - z[2] * 3.0 + z[1] * 3.0 - z[0]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The median among bit patterns is the value `total_cmp` selects, on
    /// magnitudes with ties, zeros, subnormals and infinities.
    #[test]
    fn the_median_of_magnitudes_is_the_one_total_cmp_selects() {
        let mut rng = crate::rng::Rng::new(9);
        let mut bits = Vec::new();
        for n in [1usize, 2, 3, 10, 4096] {
            let mut v: Vec<f64> = (0..n)
                .map(|i| match i % 9 {
                    0 => 0.0,
                    1 => 1e-310,
                    2 => 2.5e-4,
                    3 => f64::INFINITY,
                    _ => rng.range(-1e-3, 1e-3).abs(),
                })
                .collect();
            let got = median_of_magnitudes(&v, &mut bits);
            let mid = v.len() / 2;
            let want = *v.select_nth_unstable_by(mid, f64::total_cmp).1;
            assert_eq!(got.to_bits(), want.to_bits(), "{n} values");
        }
        assert_eq!(median_of_magnitudes(&[], &mut bits), 0.0);
    }

    #[test]
    fn measures_the_noise_of_a_swaying_marker() {
        // 150 mm at 3 Hz, 240 Hz, 1 mm noise: σ within 10 %.
        let dt = 1.0 / 240.0;
        let mut rng = crate::rng::Rng::new(7);
        let mut j = Jitter::default();
        let mut z = Vec::new();
        for n in 0..4000 {
            let t = n as f64 * dt;
            let truth = DVec3::new(0.15 * (18.85 * t).sin(), 1.0, 0.05 * (4.0 * t).cos());
            z.push(truth + DVec3::new(rng.normal(), rng.normal(), rng.normal()) * 0.001);
            if z.len() >= 4 {
                let k = z.len();
                j.observe(third_difference([z[k - 4], z[k - 3], z[k - 2], z[k - 1]]));
            }
        }
        assert!((j.sigma() - 0.001).abs() < 0.0001, "{}", j.sigma());
    }
}
