//! The residual's own swing across a gap: the part of a hidden tip's
//! motion its neighbours do not explain, carried across by its own
//! autoregression ([`super::ar`]).
//!
//! At 100–240 frames a second a twig's 1–3 Hz swing spans hundreds of
//! frames, and an autoregression over single frames would model the noise
//! between them; the residual is therefore averaged over blocks of about
//! 1/30 s (a 3 Hz swing keeps 98 % of its amplitude, 1 mm of noise drops
//! to a third over 8 frames), the blocks the gap hides are interpolated on
//! that grid, and a Catmull–Rom spline brings the result back to every
//! frame.

use glam::DVec3;

use super::ar;

/// The residual on every frame `0 ..= h` of a gap (0 is its last measured
/// frame before, `h` its first after), from the residuals `before` (the
/// frames up to and including 0, oldest first) and `after` (from frame `h`
/// on), `None` where a residual is missing; blocks of `step` frames, an
/// autoregression of order `order`. `None` when the residual cannot be
/// modelled (too few samples, a singular system). No bound on the swing
/// it gives: falling back to a cubic where it swung over 2 or 4 times
/// the widest measured block made the fills worse (long-gap sweep, 51 f–2
/// s, `all`, forward errors only: 7.36 mm unbounded, 7.83 at 4 ×, 8.80 at
/// 2 ×; seeds 251–253 9.44, 9.70, 10.61): a gust grows the swing while
/// the tip is hidden.
pub(super) fn across(
    before: &[Option<DVec3>],
    after: &[Option<DVec3>],
    h: usize,
    step: usize,
    order: usize,
) -> Option<Vec<DVec3>> {
    let d = step.max(1) as i64;
    let (h, window) = (h as i64, before.len() as i64 - 1);
    if window < d || after.is_empty() {
        return None;
    }
    let residual_at = |f: i64| -> Option<DVec3> {
        if f <= 0 {
            before.get((f + window) as usize).copied().flatten()
        } else if f >= h {
            after.get((f - h) as usize).copied().flatten()
        } else {
            None
        }
    };
    // Block `j` covers frames `j d − d/2 .. j d − d/2 + d`, on one side of
    // the gap or it counts as hidden.
    let half = d / 2;
    let j_lo = -((window - d) / d);
    let j_hi = (h + after.len() as i64 - 1 - d) / d;
    let span = |j: i64| (j * d - half, j * d - half + d - 1);
    let in_gap = |j: i64| {
        let (from, to) = span(j);
        to > 0 && from < h
    };
    let block = |j: i64| -> Option<DVec3> {
        if in_gap(j) {
            return None;
        }
        let (from, to) = span(j);
        let (mut sum, mut n) = (DVec3::ZERO, 0);
        for r in (from..=to).filter_map(residual_at) {
            sum += r;
            n += 1;
        }
        (2 * n >= d).then(|| sum / n as f64)
    };
    let grid: Vec<Option<DVec3>> = (j_lo..=j_hi).map(block).collect();
    let known: Vec<DVec3> = grid.iter().flatten().copied().collect();
    if known.is_empty() {
        return None;
    }
    let mean = known.iter().copied().sum::<DVec3>() / known.len() as f64;
    let centred: Vec<Option<DVec3>> = grid.iter().map(|g| g.map(|g| g - mean)).collect();
    let first = centred.iter().position(Option::is_some)?;
    let last = centred.iter().rposition(Option::is_some)?;
    let gap_at = |i: usize| in_gap(j_lo + i as i64);
    // Holes beside the gap (a hidden neighbour, the host's own occlusion)
    // can leave too few complete runs for a fit: then a first fit on them
    // bridged by lines.
    let coefficients = ar::fit(&centred, order).or_else(|| {
        let mut lined = centred.clone();
        let mut prev: Option<usize> = None;
        for i in first..=last {
            let Some(x) = centred[i] else { continue };
            if let Some(p) = prev.filter(|&p| i > p + 1 && !(p + 1..i).any(gap_at)) {
                let x0 = centred[p].unwrap_or(x);
                for (k, l) in lined.iter_mut().enumerate().take(i).skip(p + 1) {
                    *l = Some(x0.lerp(x, (k - p) as f64 / (i - p) as f64));
                }
            }
            prev = Some(i);
        }
        ar::fit(&lined, order)
    })?;
    let (mut start, mut filled) = ar::interpolate(&centred, &coefficients)?;
    // Fitted again with the holes beside the gap interpolated, the gap
    // itself still missing: more of the measured swing in the fit
    // (long-gap sweep, 25 % occlusion, 51 f–2 s, forward errors only:
    // 7.06 → 4.17 mm).
    let again: Vec<Option<DVec3>> = (0..centred.len())
        .map(|i| {
            let k = i.checked_sub(start).filter(|&k| k < filled.len());
            k.filter(|_| !gap_at(i)).map(|k| filled[k])
        })
        .collect();
    if let Some(f) = ar::fit(&again, order).and_then(|c| ar::interpolate(&centred, &c)) {
        (start, filled) = f;
    }
    // The spline needs the blocks from one before the gap to two after.
    let (g0, g1) = (-1 - j_lo, h / d + 2 - j_lo);
    if g0 < start as i64 || g1 >= (start + filled.len()) as i64 {
        return None;
    }
    let value =
        |i: i64| filled[(i - start as i64).clamp(0, filled.len() as i64 - 1) as usize] + mean;
    Some(
        (0..=h)
            .map(|f| {
                let x = f as f64 / d as f64 - j_lo as f64;
                let i = x.floor() as i64;
                catmull_rom(
                    [value(i - 1), value(i), value(i + 1), value(i + 2)],
                    x - i as f64,
                )
            })
            .collect(),
    )
}

/// The Catmull–Rom spline through `q[1]` (u = 0) and `q[2]` (u = 1).
fn catmull_rom(q: [DVec3; 4], u: f64) -> DVec3 {
    let (u2, u3) = (u * u, u * u * u);
    (q[1] * 2.0
        + (q[2] - q[0]) * u
        + (q[0] * 2.0 - q[1] * 5.0 + q[2] * 4.0 - q[3]) * u2
        + (q[1] * 3.0 - q[0] - q[2] * 3.0 + q[3]) * u3)
        * 0.5
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A twig swinging at 1.7 Hz (8 mm) and 2.6 Hz (3 mm), at 240 Hz.
    fn twig(f: i64) -> DVec3 {
        let t = f as f64 / 240.0;
        let a = (std::f64::consts::TAU * 1.7 * t).sin();
        let b = (std::f64::consts::TAU * 2.6 * t + 1.0).sin();
        DVec3::new(0.008 * a, 0.003 * b, 0.002 * a)
    }

    fn sides(h: i64, window: i64, missing: impl Fn(i64) -> bool) -> [Vec<Option<DVec3>>; 2] {
        let at = |f: i64| (!missing(f)).then(|| twig(f));
        [
            (-window..=0).map(at).collect(),
            (h..=h + window).map(at).collect(),
        ]
    }

    #[test]
    fn a_swing_is_carried_through_a_second_long_gap_at_the_capture_rate() {
        let h = 241;
        let [before, after] = sides(h, 480, |_| false);
        let r = across(&before, &after, h as usize, 8, 12).expect("modelled");
        assert_eq!(r.len(), h as usize + 1);
        let worst = (0..=h)
            .map(|f| r[f as usize].distance(twig(f)))
            .fold(0.0, f64::max);
        assert!(worst < 0.0005, "worst {worst}");
    }

    #[test]
    fn holes_beside_the_gap_are_bridged_for_the_fit() {
        // Occluded a fifth of the time in bursts of 30 frames on both
        // sides: too few runs of 13 whole blocks are left for a fit on
        // them alone (it needs 36). A line across the gap misses by up to
        // 14 mm.
        let h = 300;
        let [before, after] = sides(h, 480, |f| f.rem_euclid(150) < 30);
        let r = across(&before, &after, h as usize, 8, 12).expect("modelled");
        let worst = (1..h)
            .map(|f| r[f as usize].distance(twig(f)))
            .fold(0.0, f64::max);
        assert!(worst < 0.0025, "worst {worst}");
    }

    #[test]
    fn nothing_measured_gives_no_swing() {
        let before = vec![None; 481];
        let after = vec![None; 481];
        assert!(across(&before, &after, 100, 8, 12).is_none());
    }
}
