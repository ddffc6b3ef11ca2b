//! Least-squares autoregressive interpolation (Janssen, Veldhuis & Vries
//! 1986): the samples missing from a series are the ones that make the
//! series' own linear prediction errors smallest, on both sides of the
//! gap at once.
//!
//! What it is for: the part of a tip's motion its neighbours do not
//! explain (the residual of [`super::model`]) is the tip's own twig
//! swinging near its natural frequency. A branch is a damped oscillator
//! driven by turbulence, so its motion is narrow-band and an
//! autoregressive process describes it; a cubic between the gap's ends
//! knows nothing of a swing that lasts a second. The coefficients are
//! fitted on the measured samples around the gap, the three axes sharing
//! them (one twig swings along one direction at its own frequencies).
//!
//! Pure functions over a series of `Option<DVec3>` (`None`: missing); no
//! I/O, no clock.

use glam::DVec3;

/// The coefficients `a₁ … a_p` of `x_t ≈ Σ a_k x_{t−k}`, least squares
/// over every run of `p + 1` consecutive known samples of `series` (its
/// mean removed beforehand by the caller), all three axes together; a
/// ridge of `1e-6` of the mean diagonal keeps them finite on a series
/// that is nearly a pure sinusoid. `None` with fewer than `3 p` such runs.
pub(super) fn fit(series: &[Option<DVec3>], p: usize) -> Option<Vec<f64>> {
    if p == 0 || series.len() <= p {
        return None;
    }
    let mut ata = vec![0.0; p * p];
    let mut atb = vec![0.0; p];
    let mut runs = 0;
    // The series without holes (missing samples as zeros) and, for each
    // sample, how many known samples run up to it: a window is whole when
    // its last sample ends a run of p + 1.
    let x: Vec<DVec3> = series.iter().map(|s| s.unwrap_or(DVec3::ZERO)).collect();
    let mut run = 0;
    for t in 0..series.len() {
        run = if series[t].is_some() { run + 1 } else { 0 };
        if run <= p {
            continue;
        }
        runs += 1;
        // Lag k + 1 is `x[t − 1 − k]`.
        for i in 0..p {
            let xi = x[t - 1 - i];
            atb[i] += xi.dot(x[t]);
            for j in i..p {
                ata[i * p + j] += xi.dot(x[t - 1 - j]);
            }
        }
    }
    if runs < 3 * p {
        return None;
    }
    for i in 0..p {
        for j in 0..i {
            ata[i * p + j] = ata[j * p + i];
        }
    }
    let trace: f64 = (0..p).map(|i| ata[i * p + i]).sum();
    let ridge = 1e-6 * trace / p as f64 + 1e-30;
    for i in 0..p {
        ata[i * p + i] += ridge;
    }
    cholesky_solve(&mut ata, &mut [&mut atb], p, p)?;
    atb.iter().all(|a| a.is_finite()).then_some(atb)
}

/// The missing samples of `series` between its first and last known ones,
/// given the coefficients `a` ([`fit`]): those minimising the sum of the
/// squared prediction errors, forward (`x_t − Σ a_k x_{t−k}`) and backward
/// (`x_t − Σ a_k x_{t+k}`, the same coefficients for a stationary
/// process), over every prediction that touches a missing sample. Forward
/// errors alone reach a sample missing within `p` of the series' start only
/// through the smallest, longest-lag coefficients, and the least squares
/// made it up (3.7 m on a residual swinging 12 mm, `all` seed 118); the
/// backward ones predict it from the samples after it. Returns the index
/// in `series` of the first sample given (its first known one) and the
/// series from there to its last known sample, known samples as they
/// were; `None` when nothing is known or the system is singular.
pub(super) fn interpolate(series: &[Option<DVec3>], a: &[f64]) -> Option<(usize, Vec<DVec3>)> {
    let first = series.iter().position(Option::is_some)?;
    let last = series.iter().rposition(Option::is_some)?;
    let s = &series[first..=last];
    let p = a.len();
    // Index of each missing sample among the unknowns.
    let mut unknown = vec![usize::MAX; s.len()];
    let mut m = 0;
    for (i, x) in s.iter().enumerate() {
        if x.is_none() {
            unknown[i] = m;
            m += 1;
        }
    }
    let mut out: Vec<DVec3> = s.iter().map(|x| x.unwrap_or(DVec3::ZERO)).collect();
    if m == 0 {
        return Some((first, out));
    }
    // The prediction error at t is Σ_{k=0..p} c_k x_{t−k}, c₀ = 1,
    // c_k = −a_k; split into its unknown and known parts.
    let c: Vec<f64> = std::iter::once(1.0).chain(a.iter().map(|a| -a)).collect();
    let mut ata = vec![0.0; m * m];
    let (mut bx, mut by, mut bz) = (vec![0.0; m], vec![0.0; m], vec![0.0; m]);
    let mut touched: Vec<(usize, f64)> = Vec::with_capacity(p + 1);
    // Window i..=i+p: forward, position i + p − k weighs c_k; backward,
    // position i + k weighs c_k.
    for i in 0..s.len().saturating_sub(p) {
        for backward in [false, true] {
            touched.clear();
            let mut known = DVec3::ZERO;
            for (k, &ck) in c.iter().enumerate() {
                let j = if backward { i + k } else { i + p - k };
                match s[j] {
                    Some(x) => known += x * ck,
                    None => touched.push((unknown[j], ck)),
                }
            }
            for &(u, cu) in &touched {
                bx[u] -= cu * known.x;
                by[u] -= cu * known.y;
                bz[u] -= cu * known.z;
                for &(v, cv) in &touched {
                    ata[u * m + v] += cu * cv;
                }
            }
        }
    }
    let trace: f64 = (0..m).map(|i| ata[i * m + i]).sum();
    let ridge = 1e-9 * trace / m as f64 + 1e-30;
    for i in 0..m {
        ata[i * m + i] += ridge;
    }
    // Unknowns are numbered in the series' order, and one prediction
    // reaches p + 1 consecutive samples: the matrix is banded.
    cholesky_solve(&mut ata, &mut [&mut bx, &mut by, &mut bz], m, p)?;
    for (i, x) in s.iter().enumerate() {
        if x.is_none() {
            let u = unknown[i];
            out[i] = DVec3::new(bx[u], by[u], bz[u]);
        }
    }
    out.iter().all(|x| x.is_finite()).then_some((first, out))
}

/// Solves `M x = b` for each right-hand side in place (`M`: `n × n`,
/// symmetric positive definite, zero more than `band` off the diagonal,
/// overwritten by its Cholesky factor, which keeps the band): a 2 s gap's
/// 60 unknowns cost 60 × 12² steps instead of 60³ / 6.
fn cholesky_solve(mat: &mut [f64], rhs: &mut [&mut Vec<f64>], n: usize, band: usize) -> Option<()> {
    for j in 0..n {
        let lo = j.saturating_sub(band);
        let mut d = mat[j * n + j];
        for k in lo..j {
            d -= mat[j * n + k] * mat[j * n + k];
        }
        if d <= 0.0 || !d.is_finite() {
            return None;
        }
        let d = d.sqrt();
        mat[j * n + j] = d;
        for i in j + 1..n.min(j + band + 1) {
            let mut v = mat[i * n + j];
            for k in i.saturating_sub(band).max(lo)..j {
                v -= mat[i * n + k] * mat[j * n + k];
            }
            mat[i * n + j] = v / d;
        }
    }
    for b in rhs.iter_mut() {
        for i in 0..n {
            let mut v = b[i];
            for k in i.saturating_sub(band)..i {
                v -= mat[i * n + k] * b[k];
            }
            b[i] = v / mat[i * n + i];
        }
        for i in (0..n).rev() {
            let mut v = b[i];
            for k in i + 1..n.min(i + band + 1) {
                v -= mat[k * n + i] * b[k];
            }
            b[i] = v / mat[i * n + i];
        }
    }
    Some(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two swings of a twig (1.3 and 2.1 Hz at 30 samples a second) on
    /// two axes.
    fn twig(t: usize) -> DVec3 {
        let t = t as f64 / 30.0;
        let a = (std::f64::consts::TAU * 1.3 * t).sin();
        let b = (std::f64::consts::TAU * 2.1 * t + 0.7).sin();
        DVec3::new(0.004 * a + 0.002 * b, 0.0, 0.003 * b)
    }

    #[test]
    fn a_swing_is_carried_across_a_gap_a_cubic_cannot_follow() {
        // 2 s measured, 1.5 s missing, 2 s measured.
        let series: Vec<Option<DVec3>> = (0..165)
            .map(|t| (!(60..105).contains(&t)).then(|| twig(t)))
            .collect();
        let a = fit(&series, 8).expect("enough samples");
        let (start, filled) = interpolate(&series, &a).expect("solvable");
        assert_eq!(start, 0);
        let worst = (60..105)
            .map(|t| filled[t].distance(twig(t)))
            .fold(0.0, f64::max);
        // A straight line between the ends misses by about the swing.
        let line = (60..105)
            .map(|t| {
                let x = (t - 59) as f64 / 46.0;
                twig(59).lerp(twig(105), x).distance(twig(t))
            })
            .fold(0.0, f64::max);
        assert!(line > 0.004, "line {line}");
        assert!(worst < 0.0002, "worst {worst}");
        // Known samples are kept as they were.
        assert_eq!(filled[10], twig(10));
    }

    #[test]
    fn a_damped_oscillator_gives_its_own_coefficients() {
        // x_t = 2 r cos ω x_{t−1} − r² x_{t−2}: an AR(2) exactly.
        let (r, w) = (0.97f64, 0.4f64);
        let mut x = vec![DVec3::new(1.0, 0.5, 0.0), DVec3::new(0.8, 0.2, 0.1)];
        for t in 2..200 {
            let next = x[t - 1] * (2.0 * r * w.cos()) - x[t - 2] * (r * r);
            // Restart the swing now and then, as a gust would.
            x.push(if t % 50 == 0 { next + DVec3::X } else { next });
        }
        let series: Vec<Option<DVec3>> = x.iter().map(|&p| Some(p)).collect();
        let a = fit(&series, 2).expect("enough samples");
        // The kicks break the recursion on 3 of 198 steps.
        assert!((a[0] - 2.0 * r * w.cos()).abs() < 0.05, "{a:?}");
        assert!((a[1] + r * r).abs() < 0.05, "{a:?}");
    }

    #[test]
    fn samples_missing_near_the_start_are_predicted_backward() {
        // Two samples, ten missing, then the swing (with 0.1 mm of noise,
        // so no model is exact) and a gap: forward predictions reach the
        // ten only through their longest lags.
        let mut rng = crate::rng::Rng::new(5);
        let series: Vec<Option<DVec3>> = (0..165)
            .map(|t| {
                let noise = DVec3::new(rng.normal(), rng.normal(), rng.normal()) * 1e-4;
                let seen = t < 2 || (12..165).contains(&t) && !(80..110).contains(&t);
                seen.then(|| twig(t) + noise)
            })
            .collect();
        let a = fit(&series, 12).expect("enough samples");
        let (start, filled) = interpolate(&series, &a).expect("solvable");
        assert_eq!((start, filled.len()), (0, 165));
        let worst =
            |r: std::ops::Range<usize>| r.map(|t| filled[t].distance(twig(t))).fold(0.0, f64::max);

        // Forward errors alone: 1.0 mm at the start (and metres on a
        // real residual, where the model fits less well); with the
        // backward ones 0.39 mm, as good as inside the gap.
        assert!(worst(2..12) < 0.0007, "start {}", worst(2..12));
        assert!(worst(80..110) < 0.001, "gap {}", worst(80..110));
    }

    #[test]
    fn too_few_samples_give_no_model() {
        let series: Vec<Option<DVec3>> = (0..20).map(|t| Some(twig(t))).collect();
        assert!(fit(&series, 8).is_none());
        assert!(fit(&series, 0).is_none());
    }
}
