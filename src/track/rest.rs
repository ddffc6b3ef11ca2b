//! The still phase and the tips' rest positions (paper §7, spec §4).
//!
//! While the tree does not move, the samples of one marker form a tight
//! cluster; their mean is the marker's rest position, far more precise than
//! one frame (noise of 0.2 mm averages down to ~0.01 mm over 20 s at 100 Hz).
//!
//! The still phase is found automatically as the longest window in which
//! every marker present moves less than `rest_motion` (standard deviation
//! of its distance from its mean), unless the config names it. Motion is
//! summarised per block of frames with prefix sums, so the search is linear
//! in the number of blocks. **ours**: the found window is then trimmed by up
//! to 1 s (10 % of its length) at each end that borders motion, because the
//! first moments of wind are small enough to pass the test yet would shift
//! the mean by tenths of a millimetre.

use glam::DVec3;
use serde::Serialize;

use crate::model::trace::Timeline;
use crate::model::trace::Trace;

/// A marker whose samples cover at least this fraction of a window takes
/// part in deciding whether the window is still.
const PRESENT: f64 = 0.5;
/// Traces measured in fewer than this fraction of all frames are ignored
/// when looking for the still phase (spurious reflections, fragments).
const RELEVANT: f64 = 0.1;
/// Most blocks the search uses (bounds memory for hour-long sessions).
const MAX_BLOCKS: usize = 4000;
/// The shortest still phase worth calling one (s): shorter windows are the
/// slow turning points of a sway.
pub const MIN_REST_S: f64 = 1.0;
/// A trace needs this many measured samples in the rest window to get a
/// rest position from it.
pub const MIN_REST_SAMPLES: usize = 10;

/// Where the rest window came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum RestSource {
    /// Found automatically.
    Auto,
    /// Named in the config (`tracking.rest_window_s`).
    Config,
    /// No still phase found: the whole recording was used.
    WholeRecording,
}

/// The rest window in internal frames `[start, end)`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RestWindow {
    /// First internal frame of the window.
    pub start: i64,
    /// First internal frame after the window (exclusive).
    pub end: i64,
    /// Found, configured, or the whole recording as a fallback (reported,
    /// because rest positions from a moving tree are less precise).
    pub source: RestSource,
}

/// Per-trace prefix sums over blocks.
struct BlockSums {
    first_block: usize,
    /// Prefix sums (n, Σd, Σ|d|²) of d = p − origin, one entry per block
    /// boundary from `first_block`.
    prefix: Vec<(f64, DVec3, f64)>,
}

fn block_sums(trace: &Trace, block: i64) -> BlockSums {
    let first_block = (trace.first_frame() / block) as usize;
    let last_block = (trace.last_frame() / block) as usize;
    let mut per_block = vec![(0.0, DVec3::ZERO, 0.0); last_block - first_block + 1];
    let mut origin = None;
    // The block of each frame followed along, not divided out per sample
    // (the division was most of this loop's time).
    let (mut slot_at, mut block_end) = (0usize, (first_block as i64 + 1) * block);
    for (f, p) in trace.measurements() {
        let d = p - *origin.get_or_insert(p);
        while f >= block_end {
            slot_at += 1;
            block_end += block;
        }
        if let Some(slot) = per_block.get_mut(slot_at) {
            slot.0 += 1.0;
            slot.1 += d;
            slot.2 += d.length_squared();
        }
    }
    let mut prefix = Vec::with_capacity(per_block.len() + 1);
    let mut acc = (0.0, DVec3::ZERO, 0.0);
    prefix.push(acc);
    for b in per_block {
        acc = (acc.0 + b.0, acc.1 + b.1, acc.2 + b.2);
        prefix.push(acc);
    }
    BlockSums {
        first_block,
        prefix,
    }
}

impl BlockSums {
    /// (n, std) of the samples in blocks [a, b).
    fn window(&self, a: usize, b: usize) -> (f64, f64) {
        let last = self.first_block + self.prefix.len() - 1;
        let lo = a.clamp(self.first_block, last) - self.first_block;
        let hi = b.clamp(self.first_block, last) - self.first_block;
        let (p, q) = (self.prefix[lo], self.prefix[hi]);
        let n = q.0 - p.0;
        if n < 1.0 {
            return (0.0, 0.0);
        }
        let mean = (q.1 - p.1) / n;
        let var = ((q.2 - p.2) / n - mean.length_squared()).max(0.0);
        (n, var.sqrt())
    }
}

/// A still marker's spread (the standard deviation of its distance from
/// its mean) is √3 σ for noise σ per axis: a still phase is one where every
/// marker moves less than `rest_motion_mm` or, on a noisier capture, less
/// than this many σ (1 mm of noise read as motion made the whole take the
/// "still phase", rest positions 9 mm off).
const NOISE_SIGMAS: f64 = 3.0;

/// Finds the still phase: the longest window in which every marker present
/// moves less than `rest_motion_m` (or [`NOISE_SIGMAS`] times the capture's
/// measured noise, if larger). `None` when there is none.
pub fn find_rest_window(
    traces: &[Trace],
    timeline: &Timeline,
    rest_motion_m: f64,
) -> Option<RestWindow> {
    let rest_motion_m = rest_motion_m.max(NOISE_SIGMAS * super::jitter::noise_of(traces));
    let total = timeline.len() as i64;
    if total < 2 {
        return None;
    }
    let block = ((total as usize).div_ceil(MAX_BLOCKS)).max(8) as i64;
    let n_blocks = (total as usize).div_ceil(block as usize);
    let relevant: Vec<BlockSums> = traces
        .iter()
        .filter(|t| t.measured() as f64 >= RELEVANT * total as f64)
        .map(|t| block_sums(t, block))
        .collect();
    if relevant.is_empty() {
        return None;
    }
    let still = |a: usize, b: usize| {
        let frames = ((b - a) as i64 * block) as f64;
        let mut present = 0;
        for s in &relevant {
            let (n, std) = s.window(a, b);
            if n >= PRESENT * frames {
                if std >= rest_motion_m {
                    return false;
                }
                present += 1;
            }
        }
        present > 0
    };
    let mut best = (0, 0);
    let mut a = 0;
    for b in 1..=n_blocks {
        while a < b && !still(a, b) {
            a += 1;
        }
        if b - a > best.1 - best.0 {
            best = (a, b);
        }
    }
    let frames_per_s = one_second(timeline);
    if ((best.1 - best.0) as i64 * block) < (MIN_REST_S * frames_per_s as f64) as i64 {
        return None;
    }
    let mut start = best.0 as i64 * block;
    let mut end = (best.1 as i64 * block).min(total);
    let trim = (((end - start) as f64 * 0.1) as i64).min(frames_per_s);
    if start > 0 {
        start += trim;
    }
    if end < total {
        end -= trim;
    }
    Some(RestWindow {
        start,
        end,
        source: RestSource::Auto,
    })
}

fn one_second(timeline: &Timeline) -> i64 {
    timeline
        .frame_interval()
        .map_or(100, |dt| (1.0 / dt).round() as i64)
}

/// Mean, spread (root mean square distance from the mean) and count of a
/// trace's measured samples in `[start, end)`.
pub fn rest_of(trace: &Trace, start: i64, end: i64) -> Option<(DVec3, f64, usize)> {
    let origin = trace.measurements().next()?.1;
    let mut n = 0usize;
    let mut sum = DVec3::ZERO;
    let mut sq = 0.0;
    for (f, p) in trace.measurements() {
        if f >= end {
            break;
        }
        if f >= start {
            let d = p - origin;
            n += 1;
            sum += d;
            sq += d.length_squared();
        }
    }
    if n == 0 {
        return None;
    }
    let mean = sum / n as f64;
    let spread = (sq / n as f64 - mean.length_squared()).max(0.0).sqrt();
    Some((origin + mean, spread, n))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn timeline(n: usize) -> Timeline {
        Timeline {
            times: (0..n).map(|i| i as f64 / 100.0).collect(),
            anchors: vec![(0, 0)],
        }
    }

    #[test]
    fn finds_the_still_phase_before_the_wind() {
        // 10 s still (0.3 mm wobble), then 10 s of 20 mm sway.
        let mut traces = Vec::new();
        for k in 0..5 {
            let base = DVec3::new(0.1 * k as f64, 1.0, 0.0);
            let at = |n: i64| {
                let t = n as f64 / 100.0;
                let amp = if n < 1000 { 0.0003 } else { 0.02 };
                base + DVec3::X * amp * (3.0 * t + k as f64).sin()
            };
            let mut tr = Trace::new(k, 0, at(0), None);
            for n in 1..2000 {
                tr.push(n, at(n), None);
            }
            traces.push(tr);
        }
        let w = find_rest_window(&traces, &timeline(2000), 0.002).unwrap();
        assert_eq!(w.start, 0);
        // Ends just before the wind, trimmed by up to 1 s.
        assert!((850..=1000).contains(&w.end), "{w:?}");
        let (rest, spread, n) = rest_of(&traces[0], w.start, w.end).unwrap();
        assert!(rest.distance(DVec3::new(0.0, 1.0, 0.0)) < 0.0001);
        assert!(spread < 0.0003);
        assert_eq!(n as i64, w.end - w.start);
    }

    #[test]
    fn no_still_phase_is_none() {
        let at = |n: i64| DVec3::X * 0.05 * (n as f64 / 20.0).sin();
        let mut tr = Trace::new(0, 0, at(0), None);
        for n in 1..1000 {
            tr.push(n, at(n), None);
        }
        assert_eq!(find_rest_window(&[tr], &timeline(1000), 0.002), None);
    }
}
