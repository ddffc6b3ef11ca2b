//! Samples of a tip that ended up in no tip, taken back at the edges of its
//! gaps.
//!
//! Under strong sway with noise and ghosts the tracker sometimes loses a
//! marker for a few frames and follows it again as a new trace that is
//! never confirmed, or too short for its offset from the neighbours to say
//! whose it is. Those samples stay ghosts or are dropped as noise, and the
//! tip's gap becomes longer than the marker's real one: a fill across the
//! longer hole is worse than a fill across the true gap could be.
//!
//! The evidence that such a sample is the tip's is local: it continues the
//! tip's last measured sample by the step the neighbours' motion predicts
//! (the gap's fill), frame after frame from the gap's edge. So each gap is
//! walked from both ends through the samples no tip holds, one frame at a
//! time, taking the sample within the noise of that step and near the
//! fill; frames without one are passed over (the marker's real gap), but
//! a run found after them needs [`MIN_RUN`] samples. A sample two walks
//! want, or with another tip's position nearly as close as the fill
//! ([`VETO_RATIO`]), is not taken and ends its walk there (a close pair's
//! partner, which also has a gap, could own it). Gaps that got samples back are
//! shorter and their fills better: the passes repeat while they take
//! samples.

use std::collections::HashMap;

use glam::DVec3;

use super::gaps::{self, GapSettings, GapStats};
use crate::model::trace::{Timeline, Trace};

/// How far (in σ of the measurement noise per axis) a sample may lie from
/// the step the fill predicts: the 99.9 % quantile of the 3-D distance
/// between two noisy samples of one point (χ with 3 degrees of freedom,
/// √2 σ per axis).
const STEP_SIGMAS: f64 = 5.7;

/// Smallest step radius (m): noise measured on a quiet capture can be
/// far below what a marker does between two frames.
const MIN_STEP_M: f64 = 0.0015;

/// How far the fill itself may be off, per frame from the gap's edge (m);
/// a sample further than the step radius plus this from the fill is not
/// the tip's, however well it continues the previous one (a walk that
/// drifted).
const DRIFT_PER_FRAME_M: f64 = 0.0002;

/// The most [`DRIFT_PER_FRAME_M`] adds up to (m). Deep in a gap of a
/// second or two the fill is still within about 25 mm of the marker (runs
/// taken back on the long-gap sweep, seeds 110–112: 23 mm the furthest),
/// while the linear allowance reaches 70 mm by 1.5 s at 240 Hz: a still
/// reflection 56 mm from a hidden tip's fill passed it (seed 251, `ghosts`
/// with long gaps: 39 samples of a ghost in a tip). Held out, seeds
/// 110–116 with long gaps: `ghosts` 8 → 0 wrong samples, `all, noise_mm
/// 1.5` 175 → 145; 20 mm and 30 mm measured the same.
const MAX_DRIFT_M: f64 = 0.03;

/// Samples in a row a run needs when it starts after frames where the
/// walk found nothing; a tip's run of fewer between two gaps is given up
/// (`lone`).
pub(crate) const MIN_RUN: usize = 4;

/// Passes at most: each fills every gap (the last one's fills are kept).
/// Held out, `all`, 11–50 frame fills against PCHIP's: 0.79 × after one
/// pass, 0.74 × after 2, 0.73 × after 3, 0.72 × after 8 (measured without
/// the veto of [`VETO_RATIO`]).
const PASSES: usize = 8;

/// Frames a walk may pass over and still take the next sample alone,
/// when it lies within the step radius of the prediction.
const SHORT_SKIP: i64 = 10;

/// A sample is doubtful when another tip lies within this many times its
/// distance from the host's fill (or the step radius, if larger): in a long
/// hole the fill is some millimetres off, and a neighbour passing nearer
/// than three times that could as well own it (held-out sweep: ratio 0 or
/// 1.5 took 76 and 50 more samples of another tip than no reclaim at all,
/// 3 took 12, for a 11–50 frame fill of 0.72, 0.73 and 0.77 × PCHIP's).
const VETO_RATIO: f64 = 3.0;

/// One sample a walk wants to take.
#[derive(Clone, Copy)]
struct Claim {
    /// Index of the tip (into the traces given).
    host: usize,
    frame: i64,
    /// Distance from the host's fill at `frame`.
    off: f64,
    position: DVec3,
    source: Option<i64>,
    /// Index of the sample in the pool.
    slot: usize,
    /// Which walk took it, and its place in the walk.
    walk: usize,
    step: usize,
}

/// Takes samples of `pool` (traces no tip holds: ghosts, pieces nobody
/// fitted, traces dropped as noise) into the gaps of `tips` where they
/// continue a tip from a gap's edge (module docs), then fills the gaps
/// left. `noise_m`: the measurement noise per axis (m) the settings
/// assume; the noise measured on `tips` counts where it is larger. Returns
/// the number of samples taken and what the gap filling did.
pub(crate) fn reclaim(
    tips: &mut [Trace],
    pool: &[Trace],
    timeline: &Timeline,
    settings: GapSettings,
    noise_m: f64,
) -> (usize, GapStats) {
    // An hour's take: up to 8 fills of every gap cost 2.7 × the cleaning
    // (28 → 76 s) and 8 MB more at the peak, past its 300 MB; like the
    // identities decided again, it waits until something there can check
    // it.
    let take_s = timeline.time(timeline.len() as i64 - 1) - timeline.time(0);
    if take_s > super::rejoin::MAX_TAKE_S {
        return (0, gaps::fill_gaps(tips, timeline, settings));
    }
    let mut at = Pool::new(pool);
    if at.samples.is_empty() || tips.is_empty() {
        return (0, gaps::fill_gaps(tips, timeline, settings));
    }
    let sigma = super::jitter::noise_of(tips).max(noise_m);
    let r_step = (STEP_SIGMAS * std::f64::consts::SQRT_2 * sigma).max(MIN_STEP_M);
    // A gap that got samples back is shorter, and its fill closer to the
    // marker: the next pass may reach the pieces the first could not.
    let mut count = 0;
    for _ in 0..PASSES {
        // The walks follow the fills' steps; the gaps are filled in place
        // (a copy of the traces would double the hour's memory).
        let stats = gaps::fill_gaps(tips, timeline, settings);
        let n = pass(tips, &mut at, r_step);
        count += n;
        if n == 0 {
            return (count, stats);
        }
        for t in tips.iter_mut() {
            t.clear_fills();
        }
        // The fills just dropped would otherwise stay resident beside the
        // next pass's (an hour's 115 000 fills: 17 MB).
        crate::memory::release_freed();
    }
    (count, gaps::fill_gaps(tips, timeline, settings))
}

/// A sample of the pool: position and source ID, `None` once taken.
type PoolSample = Option<(DVec3, Option<i64>)>;

/// The pool's samples in frame order (one list, not a vector per frame).
struct Pool {
    /// Frame of each sample.
    frames: Vec<i64>,
    /// Each sample ([`PoolSample`]).
    samples: Vec<PoolSample>,
}

impl Pool {
    fn new(traces: &[Trace]) -> Self {
        let mut all: Vec<(i64, DVec3, Option<i64>)> = traces
            .iter()
            .flat_map(|t| t.measurements_with_source())
            .collect();
        // Stable: the samples of a frame stay in the traces' order.
        all.sort_by_key(|x| x.0);
        Pool {
            frames: all.iter().map(|x| x.0).collect(),
            samples: all.into_iter().map(|x| Some((x.1, x.2))).collect(),
        }
    }

    /// The index of the first sample at frame `f`, and the samples there.
    fn at(&self, f: i64) -> (usize, &[PoolSample]) {
        let a = self.frames.partition_point(|&x| x < f);
        let n = self.frames[a..].partition_point(|&x| x == f);
        (a, &self.samples[a..a + n])
    }
}

/// One pass of [`reclaim`] over `tips` with their gaps filled: walks
/// every gap, takes the samples no doubt falls on. Returns how many it
/// took.
fn pass(tips: &mut [Trace], at: &mut Pool, r_step: f64) -> usize {
    let mut claims: Vec<Claim> = Vec::new();
    let mut walks = 0usize;
    for (host, t) in tips.iter().enumerate() {
        let ends = edge_positions(t);
        for fill in t.fills() {
            let (Some(&a), Some(&b)) = (ends.get(&fill.from), ends.get(&fill.to)) else {
                continue;
            };
            let expect = |f: i64| match f {
                f if f == fill.from => a,
                f if f == fill.to => b,
                f => fill.at(f),
            };
            let forward = walk(fill.from, fill.to, 1, a, &expect, at, r_step);
            let reached = forward.last().map_or(fill.from, |c| c.0);
            let backward = walk(fill.to, reached, -1, b, &expect, at, r_step);
            for run in [forward, backward] {
                for (step, (frame, slot)) in run.into_iter().enumerate() {
                    let Some((position, source)) = at.samples[slot] else {
                        continue;
                    };
                    claims.push(Claim {
                        host,
                        frame,
                        off: position.distance(expect(frame)),
                        position,
                        source,
                        slot,
                        walk: walks,
                        step,
                    });
                }
                walks += 1;
            }
        }
    }
    if claims.is_empty() {
        return 0;
    }

    // A walk ends before its first doubtful sample.
    let mut cut: Vec<usize> = vec![usize::MAX; walks];
    // Walks wanted by each pool sample (a slot is unique in the pool).
    let mut wanted: Vec<u32> = vec![0; at.samples.len()];
    for c in &claims {
        wanted[c.slot] += 1;
    }
    let mut by_frame: HashMap<i64, Vec<usize>> = HashMap::new();
    for (k, c) in claims.iter().enumerate() {
        // Two walks want the sample: two tips with a gap at once, their
        // fills as near it (seen: 10 and 12 mm from it).
        if wanted[c.slot] > 1 {
            cut[c.walk] = cut[c.walk].min(c.step);
        }
        by_frame.entry(c.frame).or_default().push(k);
    }
    for (j, t) in tips.iter().enumerate() {
        for s in t.samples() {
            let Some(ks) = by_frame.get(&s.frame) else {
                continue;
            };
            for &k in ks {
                let c = &claims[k];
                let doubt = r_step.max(VETO_RATIO * c.off);
                if c.host != j && c.position.distance(s.position) < doubt {
                    cut[c.walk] = cut[c.walk].min(c.step);
                }
            }
        }
    }

    let mut taken: Vec<Vec<&Claim>> = vec![Vec::new(); tips.len()];
    for c in claims.iter().filter(|c| c.step < cut[c.walk]) {
        taken[c.host].push(c);
    }
    let mut count = 0;
    for (tip, mut mine) in tips.iter_mut().zip(taken) {
        if mine.is_empty() {
            continue;
        }
        mine.sort_by_key(|c| c.frame);
        let mut piece = Trace::new(tip.id, mine[0].frame, mine[0].position, mine[0].source);
        for c in &mine[1..] {
            piece.push(c.frame, c.position, c.source);
        }
        piece.pieces.clear();
        // The walks only enter frames the tip does not measure.
        if let Some(joined) = tip.merged(&piece) {
            count += mine.len();
            *tip = joined;
            for c in &mine {
                at.samples[c.slot] = None;
            }
        }
    }
    count
}

/// The measured positions of `t` at the ends of its fills. Decodes the
/// trace only up to its last fill, with no hashing per sample: this runs
/// on every tip in every pass.
fn edge_positions(t: &Trace) -> HashMap<i64, DVec3> {
    let mut ends: Vec<i64> = t.fills().iter().flat_map(|f| [f.from, f.to]).collect();
    ends.sort_unstable();
    ends.dedup();
    let mut out = HashMap::with_capacity(ends.len());
    let mut next = ends.iter().peekable();
    for (f, p) in t.measurements() {
        while next.next_if(|&&e| e < f).is_some() {}
        match next.peek() {
            None => break,
            Some(&&e) if e == f => {
                out.insert(f, p);
                next.next();
            }
            Some(_) => {}
        }
    }
    out
}

/// Walks from the measured frame `start` (position `p`) towards `stop`
/// (exclusive) in direction `dir`, taking at each frame the pool's sample
/// nearest the step `expect` predicts from the last sample taken. Frames
/// without one are passed over (the marker's real gap, before the piece
/// the tracker lost), but a run of samples that begins after such frames
/// is kept only once it is [`MIN_RUN`] frames long: one or two samples far
/// from the tip's last are as likely another marker's. (frame, slot) of
/// each sample taken.
fn walk(
    start: i64,
    stop: i64,
    dir: i64,
    p: DVec3,
    expect: &dyn Fn(i64) -> DVec3,
    at: &Pool,
    r_step: f64,
) -> Vec<(i64, usize)> {
    let mut out = Vec::new();
    // The last sample kept, and the run being tried after a skip.
    let (mut kept_p, mut kept_f) = (p, start);
    let mut run: Vec<(i64, usize, DVec3)> = Vec::new();
    let mut f = start + dir;
    while f != stop {
        let (p, last) = run.last().map_or((kept_p, kept_f), |r| (r.2, r.0));
        let e = expect(f);
        let predicted = p + (e - expect(last));
        let drift = |frames: i64| (DRIFT_PER_FRAME_M * frames as f64).min(MAX_DRIFT_M);
        let reach = r_step + drift((f - last).abs());
        let near_fill = r_step + drift((f - last).abs() + (f - start).abs());
        let (base, here) = at.at(f);
        let best = (here.iter().enumerate())
            .filter_map(|(k, x)| x.map(|(q, _)| (base + k, q.distance(predicted), q)))
            .filter(|(_, d, q)| *d < reach && q.distance(e) < near_fill)
            .min_by(|x, y| x.1.total_cmp(&y.1));
        match best {
            Some((k, d, q))
                if run.is_empty()
                    && (f == last + dir || (d < r_step && (f - last).abs() <= SHORT_SKIP)) =>
            {
                out.push((f, k));
                (kept_p, kept_f) = (q, f);
            }
            Some((k, _, q)) if run.is_empty() || f == last + dir => run.push((f, k, q)),
            // The run broke before it was long enough: not the tip's.
            _ => run.clear(),
        }
        if run.len() >= MIN_RUN {
            out.extend(run.iter().map(|r| (r.0, r.1)));
            (kept_p, kept_f) = (run[run.len() - 1].2, run[run.len() - 1].0);
            run.clear();
        }
        f += dir;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::track::gaps::tests::settings;

    /// 100 Hz, 3 s.
    fn timeline() -> Timeline {
        gaps::tests::timeline(300)
    }

    /// Tip `k` of a tree swaying 60 mm at 0.7 Hz, the tips 100 mm apart and
    /// moving more the higher they sit, with 0.2 mm of deterministic
    /// measurement noise.
    fn tip(k: usize, n: i64) -> DVec3 {
        let t = n as f64 / 100.0;
        let gain = 1.0 + 0.15 * k as f64;
        let sway = 0.06 * gain * (std::f64::consts::TAU * 0.7 * t).sin();
        let jitter = |s: f64| 0.0002 * ((n as f64 * 12.9898 + s).sin() * 43758.545).fract();
        DVec3::new(
            0.1 * k as f64 + sway + jitter(1.0),
            1.0 + 0.02 * k as f64 + jitter(2.0),
            0.3 * sway + jitter(3.0),
        )
    }

    fn trace(id: usize, f: impl Fn(i64) -> DVec3, frames: impl IntoIterator<Item = i64>) -> Trace {
        let mut it = frames.into_iter();
        let first = it.next().unwrap();
        let mut t = Trace::new(id, first, f(first), Some(id as i64));
        for n in it {
            t.push(n, f(n), Some(id as i64));
        }
        t
    }

    /// Four tips measured throughout and tip 0, which the tracker lost for
    /// frames 100..160 although its marker was only hidden for 100..110.
    fn tips() -> Vec<Trace> {
        let mut v = vec![trace(0, |n| tip(0, n), (0..100).chain(160..300))];
        v.extend((1..5).map(|k| trace(k, move |n| tip(k, n), 0..300)));
        v
    }

    #[test]
    fn a_lost_piece_after_the_true_gap_goes_back_to_its_tip() {
        let mut tips = tips();
        let pool = vec![trace(50, |n| tip(0, n), 110..160)];
        let (n, _) = reclaim(&mut tips, &pool, &timeline(), settings(), 0.0002);
        assert_eq!(n, 50);
        let t = &tips[0];
        assert_eq!(t.measured(), 290);
        assert!((100..110).all(|f| !t.is_measured(f)));
        assert!((110..160).all(|f| t.is_measured(f)));
        // The samples keep the marker they came from.
        assert!(t.sources().iter().any(|s| s.id == Some(50)));
        // The other tips are untouched.
        assert!(tips[1..].iter().all(|t| t.measured() == 300));
    }

    #[test]
    fn another_markers_piece_in_the_gap_is_left_alone() {
        let mut tips = tips();
        // A marker passing 25 mm from where tip 0 is, and a ghost of two
        // frames sitting on tip 0's path after the true gap: neither
        // continues the tip from the gap's edge for long enough.
        let passing = trace(60, |n| tip(0, n) + DVec3::new(0.0, 0.025, 0.0), 110..160);
        let blink = trace(61, |n| tip(0, n), 130..132);
        let pool = vec![passing, blink];
        let (n, _) = reclaim(&mut tips, &pool, &timeline(), settings(), 0.0002);
        assert_eq!(n, 0);
        assert_eq!(tips[0].measured(), 240);
    }

    #[test]
    fn a_sample_as_close_to_another_tip_is_not_taken() {
        // Tip 1's marker sits a millimetre from tip 0's all along (a
        // close pair): the piece in tip 0's gap could be either's and
        // stays in the pool.
        let mut tips = tips();
        tips[1] = trace(1, |n| tip(0, n) + DVec3::new(0.001, 0.0, 0.0), 0..300);
        let pool = vec![trace(50, |n| tip(0, n), 110..160)];
        let (n, _) = reclaim(&mut tips, &pool, &timeline(), settings(), 0.0002);
        assert_eq!(n, 0);
        assert_eq!(tips[0].measured(), 240);
    }

    #[test]
    fn deep_in_a_long_gap_only_a_piece_near_the_fill_is_taken() {
        // Tip 0 hidden for 2.4 s (100 Hz), its neighbours measured
        // throughout. Something moving like the tip but 35 mm beside it
        // 1.9 s into the gap is not the tip, however well it moves; the
        // tip's own marker seen there is.
        let tl = gaps::tests::timeline(400);
        let make = || {
            let mut v = vec![trace(0, |n| tip(0, n), (0..50).chain(290..400))];
            v.extend((1..5).map(|k| trace(k, move |n| tip(k, n), 0..400)));
            v
        };
        let beside = |n| tip(0, n) - DVec3::new(0.0, 0.035, 0.0);
        for (piece, taken) in [
            (trace(70, beside, 240..260), 0),
            (trace(71, |n| tip(0, n), 240..260), 20),
        ] {
            let mut tips = make();
            let (n, _) = reclaim(&mut tips, &[piece], &tl, settings(), 0.0002);
            assert_eq!(n, taken);
            assert_eq!(tips[0].measured(), 160 + taken);
        }
    }
}
