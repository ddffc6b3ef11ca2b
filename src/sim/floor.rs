//! The identity floor of a synthetic session: how many samples even an
//! oracle puts in the wrong tip where two markers pass within their noise.
//!
//! The oracle knows every tip's true path and gives each of a frame's
//! measured samples to a tip. Where two tips are both measured, the odds
//! between the two ways of giving their two samples depend on that frame's
//! samples alone, since the noise is drawn afresh for every frame and tip:
//! nothing before or after the frame can tell which is which better. With
//! noise σ per axis, the oracle errs where the difference of the two
//! samples' noise along the line between the tips exceeds their distance
//! `d`, with probability ½ erfc(d / 2σ), and each error puts two samples in
//! the wrong tip. A tracker that gives every sample a tip cannot expect
//! fewer wrong samples there; it gets below the floor only by giving
//! samples up. `examples/exchange_floor.rs` sums it over the stress sweep's
//! sessions (docs/tracking.md §4a, session 50).

use glam::DVec3;

use super::{Synthetic, Truth};

/// Tips farther apart than this many σ are left out: ½ erfc(5) is under
/// 10⁻¹¹ a frame.
const REACH_SIGMA: f64 = 10.0;

/// What [`floor`] found in a session.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Floor {
    /// Wrong samples the oracle is expected to make (two per exchange).
    pub expected: f64,
    /// Frames × pairs of tips both measured, by the distance between their
    /// true positions: under 3 mm, 3–6.4, 6.4–9.5 and 9.5–12.7 mm (the
    /// common marker diameters: two markers' centres closer than one
    /// diameter would have the balls overlap).
    pub close_frames: [usize; 4],
}

/// Upper bounds (m) of [`Floor::close_frames`]' bins.
pub const CLOSE_BINS_M: [f64; 4] = [0.003, 0.0064, 0.0095, 0.0127];

/// The oracle's expected wrong samples in `truth`'s session, and how often
/// two measured tips come close.
pub fn floor(truth: &Truth) -> Floor {
    let (sigma, reach) = noise_and_reach(truth);
    let seen = measured(truth);
    let n = truth.tips.len();
    let mut out = Floor::default();
    let mut at = vec![DVec3::ZERO; n];
    for (f, seen) in seen.iter().enumerate() {
        let t = truth.time_of(f as i64);
        for (k, p) in at.iter_mut().enumerate() {
            *p = truth.position(k, t);
        }
        for i in (0..n).filter(|&i| seen[i]) {
            for j in (i + 1..n).filter(|&j| seen[j]) {
                let d = at[i].distance(at[j]);
                if d >= reach {
                    continue;
                }
                if let Some(b) = CLOSE_BINS_M.iter().position(|&m| d < m) {
                    out.close_frames[b] += 1;
                }
                if sigma > 0.0 {
                    out.expected += erfc(d / (2.0 * sigma));
                }
            }
        }
    }
    out
}

/// Samples the oracle actually puts in the wrong tip in `syn`'s frames:
/// in each frame, for each two tips both measured within reach of each
/// other, whether their two samples lie nearer the other tip's true
/// position than their own, summed (two per exchange). Its mean over
/// sessions is [`floor`]'s `expected`.
pub fn oracle_wrong_samples(syn: &Synthetic) -> usize {
    let truth = &syn.truth;
    let (_, reach) = noise_and_reach(truth);
    let n = truth.tips.len();
    let mut wrong = 0;
    let mut sample: Vec<Option<DVec3>> = vec![None; n];
    for frame in &syn.frames {
        sample.iter_mut().for_each(|s| *s = None);
        for m in &frame.markers {
            let tip =
                m.id.and_then(|c| truth.columns.get(c as usize))
                    .and_then(|c| c.tip);
            if let Some(k) = tip {
                sample[k] = Some(m.position);
            }
        }
        let t = truth.time_of(frame.frame);
        // Each measured tip's sample and true position.
        let seen: Vec<(DVec3, DVec3)> = (0..n)
            .filter_map(|k| sample[k].map(|s| (s, truth.position(k, t))))
            .collect();
        for (a, &(xa, pa)) in seen.iter().enumerate() {
            for &(xb, pb) in &seen[a + 1..] {
                if pa.distance(pb) >= reach {
                    continue;
                }
                let kept = xa.distance_squared(pa) + xb.distance_squared(pb);
                let turned = xa.distance_squared(pb) + xb.distance_squared(pa);
                if turned < kept {
                    wrong += 2;
                }
            }
        }
    }
    wrong
}

/// The session's noise σ per axis (m) and how near two tips must be to be
/// looked at (m): [`REACH_SIGMA`] σ, and at least the last close bin.
fn noise_and_reach(truth: &Truth) -> (f64, f64) {
    let sigma = truth.options.noise_mm / 1000.0;
    (sigma, (REACH_SIGMA * sigma).max(CLOSE_BINS_M[3]))
}

/// Per frame and tip, whether the tip's marker is measured (no occlusion
/// of the truth covers it): [`Truth::is_gap`] as a table, which scans
/// every gap on each call, once per frame and tip here.
fn measured(truth: &Truth) -> Vec<Vec<bool>> {
    let mut seen = vec![vec![true; truth.tips.len()]; truth.frames];
    for g in &truth.gaps {
        let a = g.first_frame.max(0) as usize;
        let b = ((g.last_frame.max(-1) + 1) as usize).min(truth.frames);
        for row in seen.iter_mut().take(b).skip(a) {
            if let Some(s) = row.get_mut(g.tip) {
                *s = false;
            }
        }
    }
    seen
}

/// The complementary error function, to 1.2 × 10⁻⁷ relative (Numerical
/// Recipes' `erfcc`, a Chebyshev fit): enough for a sum of probabilities.
fn erfc(x: f64) -> f64 {
    let z = x.abs();
    let t = 1.0 / (1.0 + 0.5 * z);
    let poly = -z * z - 1.265_512_23
        + t * (1.000_023_68
            + t * (0.374_091_96
                + t * (0.096_784_18
                    + t * (-0.186_288_06
                        + t * (0.278_868_07
                            + t * (-1.135_203_98
                                + t * (1.488_515_87 + t * (-0.822_152_23 + t * 0.170_872_77))))))));
    let r = t * poly.exp();
    if x >= 0.0 {
        r
    } else {
        2.0 - r
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::{generate, stress};

    #[test]
    fn erfc_matches_known_values() {
        for (x, want) in [
            (0.0, 1.0),
            (0.5, 0.479_500_122_2),
            (1.0, 0.157_299_207_1),
            (2.0, 0.004_677_734_981),
            (3.0, 2.209_049_700e-5),
            (-1.0, 1.842_700_792_9),
        ] {
            let got = erfc(x);
            assert!(
                ((got - want) / want).abs() < 2e-7,
                "erfc({x}) = {got}, want {want}"
            );
        }
    }

    /// The oracle run on the samples of generated sessions exchanges about
    /// as many as the floor says: close pairs under 4 mm of noise, where
    /// the floor is tens of samples a session.
    #[test]
    fn the_oracle_exchanges_about_as_many_samples_as_the_floor_expects() {
        let (mut expected, mut counted, mut close) = (0.0, 0usize, 0usize);
        for seed in 1..=6 {
            let close_stress = stress::named(&stress::base(seed, 30, 2.0, 15.0), "close")
                .expect("the close stress");
            let opts = crate::sim::SynthOptions {
                noise_mm: 4.0,
                ..close_stress.options
            };
            let syn = generate(&opts).expect("valid options");
            let f = floor(&syn.truth);
            expected += f.expected;
            close += f.close_frames.iter().sum::<usize>();
            counted += oracle_wrong_samples(&syn);
        }
        assert!(close > 0, "the close pairs never came within 12.7 mm");
        assert!(expected > 50.0, "too few expected to test: {expected:.1}");
        // Two samples per exchange, each exchange about a Bernoulli draw:
        // the count's variance is at most twice its mean. Measured: 108.0
        // expected, 120 counted (sd 14.7); a floor off by a factor of two
        // would miss by over 4 sd.
        let sd = (2.0 * expected).sqrt();
        assert!(
            (counted as f64 - expected).abs() <= 3.0 * sd,
            "oracle {counted}, floor {expected:.1} (sd {sd:.1})"
        );
    }

    #[test]
    fn without_noise_there_is_no_floor() {
        let mut opts = stress::named(&stress::base(2, 30, 2.0, 6.0), "close")
            .expect("the close stress")
            .options;
        opts.noise_mm = 0.0;
        let syn = generate(&opts).expect("valid options");
        assert_eq!(floor(&syn.truth).expected, 0.0);
        assert_eq!(oracle_wrong_samples(&syn), 0);
    }
}
