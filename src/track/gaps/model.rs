//! The neighbours' local linear model of one gap (after Federolf 2013 and
//! Gløersen & Federolf 2016): the hidden tip's displacement regressed on
//! its neighbours' displacements around the gap, and the part of its own
//! motion the neighbours do not explain (the residual).
//!
//! `h(t) − h(a) ≈ c + Σ wⱼ (qⱼ(t) − qⱼ(a))`, one weight per neighbour for all
//! three axes (tips on one limb sway along the same directions, scaled by
//! their lever) and one offset `c`, fitted by ridge least squares on the
//! samples within `window` frames before and after the gap. The residual
//! `r(t) = h(t) − h(a) − c − Σ wⱼ (qⱼ(t) − qⱼ(a))` is what the fill
//! interpolates (by a cubic Hermite) across the gap: at the gap's ends the
//! fill is the measurement, in the middle it follows the neighbours' sway.

use glam::DVec3;

use super::{Context, Stream};

/// A neighbour's positions on consecutive frames (`None`: missing).
type Column = Vec<Option<DVec3>>;

/// Neighbours used in one fill.
const MAX_NEIGHBOURS: usize = 6;

/// How a gap's model is fitted: the plausibility check of every gap, and
/// the fill of the long ones, which need more of the neighbours.
#[derive(Debug, Clone, Copy)]
pub(super) struct Fit {
    /// Markers looked at, nearest first; the [`MAX_NEIGHBOURS`] whose
    /// displacement alone best explains the host's (R² around the gap)
    /// are kept.
    candidates: usize,
    /// Ridge of the normal equations, as a fraction of their mean
    /// diagonal: keeps the weights of two neighbours that move alike from
    /// growing large with opposite signs.
    ridge: f64,
    /// Shrink the weights towards the mean neighbour (each `1 / k`, summing
    /// to 1) instead of towards zero: a ridge towards zero also shrinks the
    /// weights' sum below 1, and the fill of a tip that sways with its limb
    /// then sways too little (with a ridge of 0.1 the unit test's limb was
    /// filled 8 mm off, its twigs move 2 mm).
    towards_mean: bool,
    /// Longest hole inside a neighbour's own data (frames) that is bridged.
    hole: i64,
    /// Bridge those holes by a cubic Hermite (slopes over 3 frames each
    /// side) instead of a straight line.
    cubic: bool,
}

/// Every gap's plausibility, and the fills up to `MAX_OWN_S`' length (which
/// only use the model for that): the six nearest neighbours through the
/// gap, holes of 5 frames bridged linearly, a light ridge. Cheap (every
/// gap of a session is checked), and what the shipped replays' outputs
/// were made with.
pub(super) const CHECK: Fit = Fit {
    candidates: MAX_NEIGHBOURS,
    ridge: 1e-3,
    towards_mean: false,
    hole: 5,
    cubic: false,
};

/// The fill of a long gap, chosen on the long-gap stress sweep
/// (`track_stress 3 20 base,gusts,noise,occlusion long`, 51 f–2 s, × PCHIP
/// for base / gusts / noise / occlusion): 0.74 / 0.66 / 0.66 / 1.03 with
/// `CHECK` on a 1 s window; 16 candidates ranked by R² 0.68 / 0.61 / 0.61
/// / 1.01 (more neighbours by distance, 10, made it worse: 0.80 / 0.70);
/// with a 2 s window and a ridge of 0.1 (fewer, steadier weights) 0.62 /
/// 0.57 / 0.62 / 0.96 (7 of 44 gaps left open under occlusion). Bridging
/// a neighbour's holes lets the neighbours of a 25 %-occluded tip through
/// (over a 1 s gap almost all of them have a hole longer than 5 frames):
/// up to 25 frames 0.80 (43/44 filled), up to 50 (0.21 s at 240 Hz, the
/// simulator's longest burst) by a cubic 0.63 / 0.55 / 0.59 / 0.64
/// (44/44). That ridge pulled the weights' sum below 1 (a tip swaying with
/// its limb filled too flat: the unit test's 8 mm); shrunk towards the mean
/// neighbour instead, 0.1 gave 0.63 / 0.55 / 0.59 / 0.64 and still 6 mm
/// there (so strong a ridge also keeps two neighbours from telling their
/// twigs apart), 0.01 0.64 / 0.56 / 0.60 / 0.66 and 6 mm, 0.001 0.65 /
/// 0.56 / 0.60 / 0.66 and under 5 mm (a ridge set by the fit's own
/// residual, Hoerl–Kennard–Baldwin, did the same: 0.65 / 0.56 / 0.60 /
/// 0.66).
pub(super) const LONG: Fit = Fit {
    candidates: 16,
    ridge: 1e-3,
    towards_mean: true,
    hole: 50,
    cubic: true,
};

/// A far end beyond this many RMS residual changes is not the same marker.
const PLAUSIBLE: f64 = 6.0;
/// The smallest mismatch that rejects a gap (m): below it two markers are
/// closer than the tracker's gate and the model could not tell them apart.
const MIN_MISMATCH_M: f64 = 0.008;

/// The fitted model of one gap `a .. b` of the host trace.
pub(super) struct Model {
    /// Weight of each neighbour's displacement.
    weights: Vec<f64>,
    /// Each neighbour's position at `a`, the origin of its displacement.
    origins: Vec<DVec3>,
    /// The host's position at `a` plus the fitted offset `c`.
    offset: DVec3,
    /// Each neighbour's positions (short holes bridged) on frames
    /// `lo ..= a + window + (b − a)`, decoded once for the fit, the
    /// residuals and the fill (a lookup per row and neighbour in the
    /// streams was most of gap filling's time).
    columns: Vec<Vec<Option<DVec3>>>,
    /// First frame of `columns`.
    lo: i64,
    /// Residuals on the measured samples before the gap, frames
    /// `a − window ..= a` (`None` where the host or a neighbour is missing).
    pub(super) before: Vec<Option<DVec3>>,
    /// The same for frames `b ..= b + window`.
    pub(super) after: Vec<Option<DVec3>>,
}

/// A neighbour's positions on frames `lo ..= hi`, each missing frame
/// bridged between the nearest measurements before and after it when both
/// lie within `fit.hole` frames of it (and within `lo − hole ..= hi + hole`).
/// One pass: each run of missing frames is bridged between its two ends
/// (looking up to `hole` frames around every missing frame, as this once
/// did, was a quarter of the marker stage's cleaning on pine-35).
fn column(s: &Stream<'_>, lo: i64, hi: i64, fit: Fit) -> Column {
    let h = fit.hole;
    let at = |f: i64| (f >= lo - h && f <= hi + h).then(|| s.at(f)).flatten();
    let mut out: Column = (lo..=hi).map(|f| s.at(f)).collect();
    let mut prev = (lo - h..lo).rev().find_map(|f| at(f).map(|p| (f, p)));
    let mut f = lo;
    while f <= hi {
        if let Some(p) = out[(f - lo) as usize] {
            prev = Some((f, p));
            f += 1;
            continue;
        }
        // A run of missing frames from `f` to the next measurement.
        let next = (f + 1..=hi + h).find_map(|g| at(g).map(|p| (g, p)));
        let end = next.map_or(hi + 1, |n| n.0.min(hi + 1));
        if let (Some(before), Some(after)) = (prev, next) {
            for g in f.max(after.0 - h)..end.min(before.0 + h + 1) {
                out[(g - lo) as usize] = Some(bridge(before, after, g, fit.cubic, &at));
            }
        }
        f = end;
    }
    out
}

/// The bridge at frame `f` of a neighbour's hole between its measurements
/// `before` and `after`: a cubic Hermite with slopes over 3 frames each
/// side (where measured) if `cubic`, else a straight line.
fn bridge(
    before: (i64, DVec3),
    after: (i64, DVec3),
    f: i64,
    cubic: bool,
    at: &impl Fn(i64) -> Option<DVec3>,
) -> DVec3 {
    let x = (f - before.0) as f64 / (after.0 - before.0) as f64;
    if cubic {
        let w = (after.0 - before.0) as f64;
        let sl = |f0: i64, p0: DVec3, dir: i64| {
            at(f0 + 3 * dir).map(|q| (p0 - q) * (-(dir as f64) / 3.0))
        };
        if let (Some(m0), Some(m1)) = (sl(before.0, before.1, -1), sl(after.0, after.1, 1)) {
            let (x2, x3) = (x * x, x * x * x);
            return before.1 * (2.0 * x3 - 3.0 * x2 + 1.0)
                + m0 * w * (x3 - 2.0 * x2 + x)
                + after.1 * (-2.0 * x3 + 3.0 * x2)
                + m1 * w * (x3 - x2);
        }
    }
    before.1.lerp(after.1, x)
}

/// A column averaged over `2 m + 1` frames where all are present (noisy
/// neighbours would carry their noise into the fill); `m = 0`: as is.
fn smoothed(c: Vec<Option<DVec3>>, m: usize) -> Vec<Option<DVec3>> {
    if m == 0 {
        return c;
    }
    (0..c.len())
        .map(|i| {
            let c0 = c[i]?;
            if i < m || i + m >= c.len() {
                return Some(c0);
            }
            let sum = c[i - m..=i + m]
                .iter()
                .try_fold(DVec3::ZERO, |acc, p| p.map(|p| acc + p));
            Some(sum.map_or(c0, |s| s / (2 * m + 1) as f64))
        })
        .collect()
}

/// The markers measured (up to short holes) from `a` to `b`, nearest to
/// the host at `a` first.
fn choose_neighbours(ctx: &Context<'_, '_>, pa: DVec3, fit: Fit) -> Vec<(usize, DVec3)> {
    let (a, b) = (ctx.a, ctx.b);
    let mut near: Vec<(f64, usize, DVec3)> = Vec::new();
    for (j, s) in ctx.streams.iter().enumerate() {
        if j == ctx.host {
            continue;
        }
        let (Some(qa), Some(_)) = (s.at(a), s.at(b)) else {
            continue;
        };
        // Cheap test first: a neighbour is only useful when every frame of
        // the gap is measured or a short hole.
        let mut hole = 0;
        let through = (a + 1..b).all(|f| {
            hole = if s.at(f).is_some() { 0 } else { hole + 1 };
            hole <= fit.hole
        });
        if through && s.at(b).is_some() {
            near.push((pa.distance_squared(qa), j, qa));
        }
    }
    near.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
    near.truncate(fit.candidates);
    near.into_iter().map(|(_, j, q)| (j, q)).collect()
}

/// The samples of the fit, flat: the host's displacement and, `k` per
/// row, the neighbours' displacements.
struct Rows {
    k: usize,
    host: Vec<DVec3>,
    neighbours: Vec<DVec3>,
}

impl Rows {
    fn len(&self) -> usize {
        self.host.len()
    }

    fn row(&self, i: usize) -> (DVec3, &[DVec3]) {
        (self.host[i], &self.neighbours[i * self.k..(i + 1) * self.k])
    }
}

impl Model {
    /// Fits the model of the context's gap on `window` frames each side,
    /// the neighbours averaged over `2 smooth + 1` frames, as `fit` says;
    /// `None` without neighbours or with too few samples to fit them.
    pub(super) fn fit(
        ctx: &Context<'_, '_>,
        window: i64,
        smooth: usize,
        fit: Fit,
    ) -> Option<Model> {
        let (a, b) = (ctx.a, ctx.b);
        let pa = ctx.host_at(a)?;
        let chosen = choose_neighbours(ctx, pa, fit);
        if chosen.is_empty() {
            return None;
        }
        let lo = a - window;
        let columns: Vec<Vec<Option<DVec3>>> = (chosen.iter())
            .map(|&(j, _)| smoothed(column(&ctx.streams[j], lo, b + window, fit), smooth))
            .collect();
        let (chosen, columns) = if chosen.len() > MAX_NEIGHBOURS {
            pick(ctx, chosen, columns, lo, window, pa)
        } else {
            (chosen, columns)
        };
        let mut model = Model {
            weights: Vec::new(),
            origins: chosen.into_iter().map(|(_, q)| q).collect(),
            offset: pa,
            columns,
            lo,
            before: Vec::new(),
            after: Vec::new(),
        };
        let k = model.origins.len();
        let mut rows = Rows {
            k,
            host: Vec::with_capacity(2 * window as usize + 2),
            neighbours: Vec::with_capacity((2 * window as usize + 2) * k),
        };
        let before = model.rows(ctx, lo, a, pa, &mut rows);
        let after = model.rows(ctx, b, b + window, pa, &mut rows);
        if rows.len() < 2 * k + 4 {
            return None;
        }
        let (weights, c) = regress(&rows, fit)?;
        model.weights = weights;
        model.offset = pa + c;
        model.before = model.residuals(&before, &rows, c);
        model.after = model.residuals(&after, &rows, c);
        Some(model)
    }

    /// The neighbours' positions at `f` (`None` where one is missing).
    fn neighbours_at(&self, f: i64) -> impl Iterator<Item = Option<DVec3>> + '_ {
        let i = (f - self.lo) as usize;
        self.columns
            .iter()
            .map(move |c| c.get(i).copied().flatten())
    }

    /// Appends the displacements of the host (from `pa`) and of the
    /// neighbours (from their origins) on frames `from ..= to` to `rows`;
    /// returns, per frame, the index of its row (`None` where the host or
    /// a neighbour is missing).
    fn rows(
        &self,
        ctx: &Context<'_, '_>,
        from: i64,
        to: i64,
        pa: DVec3,
        rows: &mut Rows,
    ) -> Vec<Option<usize>> {
        (from..=to)
            .map(|f| {
                let host = ctx.host_at(f)? - pa;
                let mark = rows.neighbours.len();
                for (q, o) in self.neighbours_at(f).zip(&self.origins) {
                    let Some(q) = q else {
                        rows.neighbours.truncate(mark);
                        return None;
                    };
                    rows.neighbours.push(q - *o);
                }
                rows.host.push(host);
                Some(rows.host.len() - 1)
            })
            .collect()
    }

    /// The residual of each row: what the model leaves of the host's
    /// displacement.
    fn residuals(&self, index: &[Option<usize>], rows: &Rows, c: DVec3) -> Vec<Option<DVec3>> {
        index
            .iter()
            .map(|i| {
                i.map(|i| {
                    let (host, d) = rows.row(i);
                    host - c - self.explained(d)
                })
            })
            .collect()
    }

    /// `Σ wⱼ dⱼ`: the part of the host's displacement the neighbours'
    /// displacements `d` explain.
    fn explained(&self, d: &[DVec3]) -> DVec3 {
        d.iter().zip(&self.weights).map(|(d, w)| *d * *w).sum()
    }

    /// Whether the far end continues the neighbours' path: across the gap
    /// of `h` frames the residual may change about as much as it does over
    /// `h` frames on either side of it (`PLAUSIBLE` × that RMS, at least
    /// `MIN_MISMATCH_M`); more, and the two ends are most likely different
    /// markers, which no fill may bridge.
    pub(super) fn plausible(&self, h: i64) -> bool {
        let (Some(Some(ra)), Some(Some(rb))) = (self.before.last(), self.after.first()) else {
            return true;
        };
        let lag = (h.max(1) as usize)
            .min(self.before.len().saturating_sub(1))
            .max(1);
        let (s1, n1) = drift(&self.before, lag);
        let (s2, n2) = drift(&self.after, lag);
        if n1 + n2 == 0 {
            return true;
        }
        let rms = ((s1 + s2) / (n1 + n2) as f64).sqrt();
        (*rb - *ra).length() <= (PLAUSIBLE * rms).max(MIN_MISMATCH_M)
    }

    /// The model's position of the host at `f` (no residual); `None` where
    /// a neighbour is missing.
    pub(super) fn at(&self, f: i64) -> Option<DVec3> {
        let mut p = self.offset;
        for ((q, o), w) in self.neighbours_at(f).zip(&self.origins).zip(&self.weights) {
            p += (q? - *o) * *w;
        }
        Some(p)
    }
}

/// Keeps the [`MAX_NEIGHBOURS`] candidates whose displacement alone best
/// explains the host's around the gap (R² of a one-neighbour fit, centred):
/// the nearest markers are not always on the host's limb, and a marker on
/// another limb adds its own sway to the fill.
fn pick(
    ctx: &Context<'_, '_>,
    chosen: Vec<(usize, DVec3)>,
    columns: Vec<Column>,
    lo: i64,
    window: i64,
    pa: DVec3,
) -> (Vec<(usize, DVec3)>, Vec<Column>) {
    let (a, b) = (ctx.a, ctx.b);
    let frames: Vec<i64> = (lo..=a).chain(b..=b + window).collect();
    let mut score: Vec<(f64, usize)> = Vec::new();
    for (i, (c, &(_, q0))) in columns.iter().zip(&chosen).enumerate() {
        let (mut n, mut sh, mut sq, mut shh, mut sqq, mut shq) =
            (0.0, DVec3::ZERO, DVec3::ZERO, 0.0, 0.0, 0.0);
        for &f in &frames {
            let (Some(h), Some(q)) = (ctx.host_at(f), c[(f - lo) as usize]) else {
                continue;
            };
            let (h, q) = (h - pa, q - q0);
            n += 1.0;
            sh += h;
            sq += q;
            shh += h.dot(h);
            sqq += q.dot(q);
            shq += h.dot(q);
        }
        if n < 8.0 {
            score.push((0.0, i));
            continue;
        }
        let chq = shq - sh.dot(sq) / n;
        let chh = shh - sh.dot(sh) / n;
        let cqq = sqq - sq.dot(sq) / n;
        let r2 = if chh > 0.0 && cqq > 0.0 {
            chq * chq / (chh * cqq)
        } else {
            0.0
        };
        score.push((r2, i));
    }
    score.sort_by(|x, y| y.0.total_cmp(&x.0).then(x.1.cmp(&y.1)));
    let mut keep = vec![false; chosen.len()];
    for &(_, i) in score.iter().take(MAX_NEIGHBOURS) {
        keep[i] = true;
    }
    // Nearest first, as they came.
    (chosen.into_iter().zip(columns).zip(keep))
        .filter_map(|(c, keep)| keep.then_some(c))
        .unzip()
}

/// Ridge least squares of the host's displacement on the neighbours' (all
/// three axes stacked), centred so the offset is free, the weights shrunk
/// as `fit` says: (weights, offset).
fn regress(rows: &Rows, fit: Fit) -> Option<(Vec<f64>, DVec3)> {
    let k = rows.k;
    let n = rows.len() as f64;
    let mean_h = rows.host.iter().copied().sum::<DVec3>() / n;
    let mean_q: Vec<DVec3> = (0..k)
        .map(|j| (0..rows.len()).map(|i| rows.row(i).1[j]).sum::<DVec3>() / n)
        .collect();
    let mut ata = vec![0.0; k * k];
    let mut atb = vec![0.0; k];
    let mut v = vec![DVec3::ZERO; k];
    for i in 0..rows.len() {
        let (host, d) = rows.row(i);
        for j in 0..k {
            v[j] = d[j] - mean_q[j];
        }
        let h = host - mean_h;
        for i in 0..k {
            atb[i] += v[i].dot(h);
            for j in i..k {
                ata[i * k + j] += v[i].dot(v[j]);
            }
        }
    }
    for i in 0..k {
        for j in 0..i {
            ata[i * k + j] = ata[j * k + i];
        }
    }
    let trace: f64 = (0..k).map(|i| ata[i * k + i]).sum();
    let ridge = fit.ridge * trace / k as f64 + 1e-15;
    let prior = if fit.towards_mean {
        1.0 / k as f64
    } else {
        0.0
    };
    // Minimising |A w − b|² + λ |w − w₀|²: (AᵀA + λ) w = Aᵀb + λ w₀.
    for i in 0..k {
        ata[i * k + i] += ridge;
        atb[i] += ridge * prior;
    }
    let w = solve(&mut ata, &mut atb, k)?;
    let c = mean_h - mean_q.iter().zip(&w).map(|(q, w)| *q * *w).sum::<DVec3>();
    Some((w, c))
}

/// Gauss–Jordan with partial pivoting on a small k × k system.
fn solve(m: &mut [f64], rhs: &mut [f64], k: usize) -> Option<Vec<f64>> {
    for c in 0..k {
        let p = (c..k).max_by(|&x, &y| m[x * k + c].abs().total_cmp(&m[y * k + c].abs()))?;
        if m[p * k + c].abs() < 1e-18 {
            return None;
        }
        for j in 0..k {
            m.swap(c * k + j, p * k + j);
        }
        rhs.swap(c, p);
        for r in 0..k {
            if r == c {
                continue;
            }
            let f = m[r * k + c] / m[c * k + c];
            for j in c..k {
                m[r * k + j] -= f * m[c * k + j];
            }
            rhs[r] -= f * rhs[c];
        }
    }
    let w: Vec<f64> = (0..k).map(|r| rhs[r] / m[r * k + r]).collect();
    w.iter().all(|x| x.is_finite()).then_some(w)
}

/// Sum of squared changes over `lag` frames of a series with holes, and
/// how many there were: how far the residual wanders across a gap.
fn drift(series: &[Option<DVec3>], lag: usize) -> (f64, usize) {
    let (mut sum, mut n) = (0.0, 0);
    if lag == 0 || series.len() <= lag {
        return (sum, n);
    }
    for i in 0..series.len() - lag {
        if let (Some(x0), Some(x1)) = (series[i], series[i + lag]) {
            sum += (x1 - x0).length_squared();
            n += 1;
        }
    }
    (sum, n)
}
