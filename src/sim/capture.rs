//! What the cameras make of the moving tips: measurement noise, occlusion
//! gaps, spurious reflections, and Motive's habit of starting a new
//! `Unlabeled N` track every time a marker comes back after a gap.
//!
//! **ours**:
//! - The gap budget is `gap_fraction` × tips × frames samples. Long
//!   occlusions (a marker hidden for seconds: a branch in front of it) take at
//!   most half of it; the rest is bursts of 1–`max_burst_frames` frames (uniform
//!   length) spread over the tips with random weights 0.5–1.5, since some tips
//!   are harder to see than others; a tip too crowded to take its share
//!   hands the rest to the next tip. Two gaps of one tip are always separated
//!   by at least one visible frame (else they would be one gap).
//! - Spurious reflections arrive as a Poisson process at `spurious_per_s`,
//!   live 1–`spurious_max_frames` frames, sit still (plus noise) somewhere in the
//!   crown's bounding box grown by 10 cm, and never within 50 mm of a tip's
//!   rest position (Motive would merge such a blob with the marker's own).
//! - Noise is drawn for every frame of every tip, visible or not, so changing
//!   the gaps does not change the noise of the samples that remain.

use glam::DVec3;

use super::motion::stream;
use super::truth::{ColumnTruth, GapTruth, SpuriousTruth, Truth};
use super::SynthOptions;
use crate::model::frame::{Marker, MarkerFrame};
use crate::rng::Rng;

/// Stream labels under the capture stream.
const LONG_GAPS: u64 = 1;
const TIP_GAPS: u64 = 2;
const SPURIOUS: u64 = 3;
const NOISE: u64 = 4;
const SPURIOUS_NOISE: u64 = 5;

/// Closest a spurious reflection may sit to a tip's rest position (m).
const SPURIOUS_CLEARANCE: f64 = 0.05;

/// Gaps of one tip as inclusive frame ranges, kept apart by ≥ 1 visible frame.
#[derive(Default)]
struct TipGaps(Vec<(i64, i64)>);

impl TipGaps {
    fn fits(&self, a: i64, b: i64) -> bool {
        self.0.iter().all(|&(c, d)| b + 1 < c || d + 1 < a)
    }
}

/// Places every occlusion. Returns them sorted by tip, then frame.
pub(crate) fn gaps(opts: &SynthOptions, frames: i64, tips: usize, base: &Rng) -> Vec<GapTruth> {
    let mut per_tip: Vec<TipGaps> = (0..tips).map(|_| TipGaps::default()).collect();
    let budget = (opts.gap_fraction * tips as f64 * frames as f64).round() as i64;
    if budget <= 0 || frames < 3 || tips == 0 {
        return Vec::new();
    }

    let mut rng = stream(base, LONG_GAPS);
    let long_budget = budget / 2;
    let mut long_used = 0;
    let n_long = opts.long_gaps.unwrap_or(tips.div_ceil(12)).min(tips);
    let mut order: Vec<usize> = (0..tips).collect();
    for k in 0..n_long {
        let j = rng.int(k as i64, tips as i64 - 1) as usize;
        order.swap(k, j);
        let len_s = rng.range(opts.long_gap_min_s, opts.long_gap_max_s);
        let len = ((len_s * opts.frame_rate).round() as i64)
            .min(long_budget - long_used)
            .min(frames - 2);
        if len < 1 {
            break;
        }
        let start = rng.int(1, frames - 1 - len);
        per_tip[order[k]].0.push((start, start + len - 1));
        long_used += len;
    }

    let short_budget = budget - long_used;
    let tip_base = stream(base, TIP_GAPS);
    let mut rngs: Vec<Rng> = (0..tips).map(|t| stream(&tip_base, t as u64)).collect();
    let weights: Vec<f64> = rngs.iter_mut().map(|r| r.range(0.5, 1.5)).collect();
    let total_weight: f64 = weights.iter().sum();
    let max_burst = opts.max_burst_frames.max(1) as i64;
    // A tip that cannot take its share (too crowded) hands the rest on.
    let mut carry = 0;
    for (t, rng) in rngs.iter_mut().enumerate() {
        let mut left = (short_budget as f64 * weights[t] / total_weight).round() as i64 + carry;
        let mut failures = 0;
        while left > 0 && failures < 200 {
            let len = rng.int(1, max_burst).min(left).min(frames - 2);
            let start = rng.int(0, frames - len);
            if per_tip[t].fits(start, start + len - 1) {
                per_tip[t].0.push((start, start + len - 1));
                left -= len;
            } else {
                failures += 1;
            }
        }
        carry = left;
    }

    let mut out = Vec::new();
    for (tip, g) in per_tip.iter_mut().enumerate() {
        g.0.sort();
        out.extend(g.0.iter().map(|&(first_frame, last_frame)| GapTruth {
            tip,
            first_frame,
            last_frame,
        }));
    }
    out
}

/// A stretch of frames in which one tip is continuously visible, or one
/// spurious reflection lives: one CSV column each.
struct Track {
    tip: Option<usize>,
    first: i64,
    last: i64,
    /// For spurious reflections: index into the spurious list.
    spurious: usize,
}

/// Draws the spurious reflections (columns are filled in later).
pub(crate) fn spurious(
    opts: &SynthOptions,
    frames: i64,
    rests: &[DVec3],
    base: &Rng,
) -> Vec<SpuriousTruth> {
    let mut out = Vec::new();
    if opts.spurious_per_s <= 0.0 || rests.is_empty() {
        return out;
    }
    let (mut lo, mut hi) = (rests[0], rests[0]);
    for &r in rests {
        lo = lo.min(r);
        hi = hi.max(r);
    }
    let margin = DVec3::splat(0.1);
    let (lo, hi) = (lo - margin, hi + margin);
    let mut rng = stream(base, SPURIOUS);
    let duration = frames as f64 / opts.frame_rate;
    let mut t = 0.0;
    loop {
        t += -(1.0 - rng.f64()).ln() / opts.spurious_per_s;
        if t >= duration {
            break;
        }
        let first = ((t * opts.frame_rate) as i64).min(frames - 1);
        let life = rng.int(1, opts.spurious_max_frames.max(1) as i64);
        let last = (first + life - 1).min(frames - 1);
        let mut position = lo;
        for _ in 0..100 {
            position = DVec3::new(
                rng.range(lo.x, hi.x),
                rng.range(lo.y, hi.y),
                rng.range(lo.z, hi.z),
            );
            if rests
                .iter()
                .all(|r| r.distance(position) >= SPURIOUS_CLEARANCE)
            {
                break;
            }
        }
        out.push(SpuriousTruth {
            column: 0,
            first_frame: first,
            last_frame: last,
            position: DVec3::new(
                super::tree::q9(position.x),
                super::tree::q9(position.y),
                super::tree::q9(position.z),
            ),
        });
    }
    out
}

/// Cuts every tip's frames into visible runs and orders all tracks into CSV
/// columns: by first frame, tips before reflections, then by index — the
/// order in which Motive hands out new `Unlabeled` numbers.
pub(crate) fn columns(truth: &mut Truth, first_id: u64) {
    let frames = truth.frames as i64;
    let mut tracks = Vec::new();
    for tip in 0..truth.tips.len() {
        let mut next = 0;
        for g in truth.gaps.iter().filter(|g| g.tip == tip) {
            if g.first_frame > next {
                tracks.push(Track {
                    tip: Some(tip),
                    first: next,
                    last: g.first_frame - 1,
                    spurious: 0,
                });
            }
            next = g.last_frame + 1;
        }
        if next < frames {
            tracks.push(Track {
                tip: Some(tip),
                first: next,
                last: frames - 1,
                spurious: 0,
            });
        }
    }
    for (k, s) in truth.spurious.iter().enumerate() {
        tracks.push(Track {
            tip: None,
            first: s.first_frame,
            last: s.last_frame,
            spurious: k,
        });
    }
    tracks.sort_by_key(|t| (t.first, t.tip.is_none(), t.tip.unwrap_or(t.spurious)));
    truth.columns = tracks
        .iter()
        .enumerate()
        .map(|(c, t)| {
            if t.tip.is_none() {
                truth.spurious[t.spurious].column = c;
            }
            ColumnTruth {
                name: format!("Unlabeled {}", first_id + c as u64),
                tip: t.tip,
                first_frame: t.first,
                last_frame: t.last,
            }
        })
        .collect();
}

/// Rounds a position the way the CSV will carry it: Motive's single-precision
/// millimetres printed with 6 decimals, read back the way a reader does
/// (value × 0.001), so the frames equal what a reader gets from the file.
/// Going through f32 also makes the printed digits immune to last-bit
/// differences between maths libraries.
pub(crate) fn as_written(p: DVec3) -> DVec3 {
    let q = |v: f64| -> f64 {
        let mm = (v * 1000.0) as f32 as f64;
        format!("{mm:.6}").parse::<f64>().unwrap_or(mm) * 0.001
    };
    DVec3::new(q(p.x), q(p.y), q(p.z))
}

/// Samples every column in every frame: true position plus noise, rounded as
/// written. Markers of a frame are in column order, `id = Some(column)`.
pub(crate) fn frames(truth: &Truth, noise_sigma: f64, base: &Rng) -> Vec<MarkerFrame> {
    let n = truth.frames;
    let mut per_frame: Vec<Vec<Marker>> = vec![Vec::new(); n];
    let noise_base = stream(base, NOISE);
    let mut tip_noise: Vec<Vec<DVec3>> = Vec::with_capacity(truth.tips.len());
    for tip in 0..truth.tips.len() {
        let mut rng = stream(&noise_base, tip as u64);
        tip_noise.push(
            (0..n)
                .map(|_| DVec3::new(rng.normal(), rng.normal(), rng.normal()) * noise_sigma)
                .collect(),
        );
    }
    let spurious_base = stream(base, SPURIOUS_NOISE);
    for (c, col) in truth.columns.iter().enumerate() {
        // Keyed by the reflection's own index, not its column, so that other
        // columns coming and going does not change its noise.
        let spur = truth.spurious.iter().position(|s| s.column == c);
        let mut spur_rng = stream(&spurious_base, spur.unwrap_or(0) as u64);
        let spur = spur.map(|k| &truth.spurious[k]);
        for f in col.first_frame..=col.last_frame {
            let Some(slot) = per_frame.get_mut(f as usize) else {
                continue;
            };
            let p = match (col.tip, spur) {
                (Some(tip), _) => {
                    truth.position(tip, truth.time_of(f)) + tip_noise[tip][f as usize]
                }
                (None, Some(s)) => {
                    s.position
                        + DVec3::new(spur_rng.normal(), spur_rng.normal(), spur_rng.normal())
                            * noise_sigma
                }
                (None, None) => continue,
            };
            slot.push(Marker {
                position: as_written(p),
                id: Some(c as i64),
            });
        }
    }
    per_frame
        .into_iter()
        .enumerate()
        .map(|(f, markers)| MarkerFrame::new(f as i64, f as f64 / truth.frame_rate, markers))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gaps_fill_the_budget_without_touching() {
        for (fraction, frames, tips) in [
            (0.05, 4000, 24),
            (0.2, 1000, 70),
            (0.01, 500, 3),
            (0.3, 300, 10),
        ] {
            let opts = SynthOptions {
                gap_fraction: fraction,
                ..SynthOptions::default()
            };
            let gaps = gaps(&opts, frames, tips, &Rng::new(4));
            let mut missing = 0;
            for (k, g) in gaps.iter().enumerate() {
                assert!(g.tip < tips && 0 <= g.first_frame && g.first_frame <= g.last_frame);
                assert!(g.last_frame < frames);
                missing += g.last_frame - g.first_frame + 1;
                if let Some(next) = gaps.get(k + 1).filter(|n| n.tip == g.tip) {
                    assert!(
                        next.first_frame > g.last_frame + 1,
                        "{g:?} touches {next:?}"
                    );
                }
            }
            let asked = fraction * (frames * tips as i64) as f64;
            assert!(
                (missing as f64 - asked).abs() <= 0.02 * asked + tips as f64,
                "{fraction}: {missing} missing, asked {asked}"
            );
            let long = gaps
                .iter()
                .filter(|g| g.last_frame - g.first_frame + 1 > 50)
                .count();
            assert!(long <= tips.div_ceil(12), "{long} long gaps");
        }
        let none = SynthOptions {
            gap_fraction: 0.0,
            ..SynthOptions::default()
        };
        assert!(gaps(&none, 4000, 24, &Rng::new(4)).is_empty());
    }

    #[test]
    fn written_positions_are_what_a_reader_parses() {
        let p = DVec3::new(0.123_456_789, 2.5, -0.000_000_4);
        let q = as_written(p);
        let text = format!("{:.6}", q.x * 1000.0);
        assert_eq!(text, "123.456787"); // f32 of 123.456789 mm is 123.45678710…
        assert_eq!(q.x, "123.456787".parse::<f64>().unwrap() * 0.001);
        assert_eq!(q.y, 2.5);
        assert!((q.z - p.z).abs() < 1e-9);
    }
}
