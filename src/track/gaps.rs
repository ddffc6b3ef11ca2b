//! Gap filling (paper §4, spec §3): from the neighbours' motion where they
//! predict it, by PCHIP where they do not.
//!
//! By the gap's length (missing time):
//! - under `MIN_OWN_S` (10 frames at 240 Hz): PCHIP (the cubic Hermite with
//!   Fritsch–Carlson slopes, which never overshoots), except where the
//!   marker is noisy (σ over `NOISY_M`), whose short gaps are filled as
//!   the next ones, between fitted ends (PCHIP starts from two noisy
//!   samples);
//! - up to `MAX_OWN_S` (50 frames at 240 Hz): a cubic Hermite between the
//!   ends of least-squares quadratics fitted to the marker's own samples
//!   over `END_FIT_S` each side (noise averaged out of the end values and
//!   slopes; PCHIP's three-sample slopes are noisy and its limiter flattens
//!   a twig's swing);
//! - longer, up to `max_fill_s`: the neighbours' local linear model (see
//!   [`model`], after Federolf 2013 and Gløersen & Federolf 2016) plus the
//!   tip's own swing, which the neighbours cannot know: the model's
//!   residual interpolated by its own autoregression ([`swing`], [`ar`]),
//!   tilted to meet the residual's fitted ends, so the fill meets the
//!   measured ends and in between follows the neighbours' coherent sway
//!   and the twig's own. Where the residual cannot be modelled, a Hermite
//!   of it between its fitted ends, the slopes fading towards the secant
//!   on long gaps.
//! - A gap whose residual changes across it by far more than it does over
//!   the same span beside it (`PLAUSIBLE` ×, at least 8 mm) is left open,
//!   whatever its length: its ends are most likely different markers, and
//!   no fill may bridge two markers.
//! - Without usable neighbours, gaps up to `max_pchip_s` are filled from
//!   the marker's own samples; longer ones stay open.
//!
//! Traces are read in one streaming pass with a window of a few seconds,
//! so memory does not grow with the session.

use glam::DVec3;
use serde::Serialize;

use super::jitter::third_difference;
use crate::model::trace::{Curve, Fill, Timeline, Trace};

mod ar;
mod model;
mod swing;
use model::Model;

/// What gap filling did, for the summary.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct GapStats {
    /// Gaps filled and the frames in them.
    pub filled: u64,
    /// Frames in those gaps.
    pub filled_frames: u64,
    /// Of those, gaps filled from the neighbours.
    pub from_neighbours: u64,
    /// Gaps left open because they were longer than the fill limits.
    pub too_long: u64,
    /// Frames in those gaps.
    pub too_long_frames: u64,
    /// Gaps left open because their far end does not continue the path the
    /// neighbours predict (two different markers on the two sides).
    pub rejected: u64,
    /// Frames in those gaps.
    pub rejected_frames: u64,
}

impl GapStats {
    fn add(&mut self, o: &GapStats) {
        self.filled += o.filled;
        self.filled_frames += o.filled_frames;
        self.from_neighbours += o.from_neighbours;
        self.too_long += o.too_long;
        self.too_long_frames += o.too_long_frames;
        self.rejected += o.rejected;
        self.rejected_frames += o.rejected_frames;
    }
}

/// Settings of gap filling, from `[tracking]`.
#[derive(Debug, Clone, Copy)]
pub struct GapSettings {
    /// Longest gap filled from the neighbours (s).
    pub max_fill_s: f64,
    /// Longest gap filled by PCHIP (s).
    pub max_pchip_s: f64,
    /// Use the neighbours at all (false: PCHIP only, for comparisons).
    pub neighbours: bool,
}

/// How many measured samples the one-sided slope is averaged over.
const SLOPE_SPAN: usize = 3;
/// Gaps shorter than this (s) are filled by PCHIP: 10 frames at 240 Hz,
/// where the sweep's fills were already as good as PCHIP and nothing
/// else did better, unless the ends are noisy (`NOISY_M`): PCHIP then
/// passes each end sample's noise into the whole fill, and the Hermite
/// between the ends fitted over `NOISY_END_FIT_S` is better (stress
/// sweep's `noise` row, 1–10 frames: 0.60 × PCHIP with the ends fitted
/// over 0.15 s; 0.66 × over 0.1 s, 0.75 × over 0.2 s, 1.00 × over 0.05 s,
/// where a quadratic's end value is as noisy as the sample).
const MIN_OWN_S: f64 = 0.044;
/// Gaps up to this (s, 50 frames at 240 Hz) are filled from the marker's
/// own samples: over a fifth of a second its own twig motion is most of
/// what an interpolation misses, and the neighbours' model, which cannot
/// know it, added their twigs' motion (measured on the stress sweep).
/// Longer gaps are filled from the neighbours.
pub(super) const MAX_OWN_S: f64 = 0.21;
/// Samples (s) each side of a gap that the end fits (value and slope of a
/// least-squares quadratic) use: long enough to average 0.2–1 mm of noise
/// away, short against a 3 Hz twig's period (chosen on the stress sweep
/// among 0.1, 0.125 and 0.15 s).
const END_FIT_S: f64 = 0.1;
/// Measurement noise (σ per axis, m, from the host's third differences
/// beside the gap) above which the gap's ends count as noisy: the stress
/// sweep's 1 mm, not a real system's 0.1–0.2 mm (whose fills stay as they
/// were, byte for byte).
const NOISY_M: f64 = 0.0005;
/// `END_FIT_S` under noise: with σ 1 mm the ends' noise, not the twig's
/// curvature, is most of the error (chosen on the stress sweep's noise
/// row among 0.1, 0.125, 0.15 and 0.2 s: 11–50 frames 0.73, 0.62, 0.57
/// and 0.65 × PCHIP).
const NOISY_END_FIT_S: f64 = 0.15;
/// Half-width (s) of the moving average of the neighbours' positions under
/// noise, where six noisy neighbours would add their noise to the fill;
/// the limb's sway they carry is slow (chosen on the stress sweep's noise
/// row among 0.05, 0.1, 0.15, 0.2 and 0.3 s: 51 f–2 s 0.78, 0.75, 0.72,
/// 0.69 and 0.65 × PCHIP, three gaps).
const NOISY_SMOOTH_S: f64 = 0.3;
/// Seconds each side of a long gap (over `MAX_OWN_S`) on which its model
/// is fitted (at least the gap's length): a 1 s window saw a limb's
/// 0.3–0.75 Hz sway over less than a period, and the weights followed
/// the twigs (long-gap sweep, 51 f–2 s, `base`: 0.74 → 0.71 × PCHIP
/// with the six nearest neighbours; see `model::LONG`).
const LONG_WINDOW_S: f64 = 2.0;
/// Gap length (s) at which the residual's end slopes are half faded
/// towards the secant (to the 4th power): across a long gap the
/// residual's own swing is unknown, and an extrapolated slope would carry
/// it far off.
const SLOPE_FADE_S: f64 = 1.0;
/// Samples a second of the grid the residual's autoregression runs on
/// (long-gap sweep, 51 f–2 s, order 8, forward prediction errors only and
/// one fit, as first built; `base` / `gusts` / `noise` /
/// `occlusion` in mm: 20 Hz 3.99 / 8.00 / 3.49 / 7.03, 30 Hz 3.62 /
/// 7.16 / 4.72 / 5.20, 60 Hz 5.56 / 10.87 / 5.20 / 5.57; PCHIP 12.67 /
/// 27.05 / 13.19 / 12.65, the Hermite of the residual 8.22 / 15.20 /
/// 7.91 / 8.12).
const AR_RATE_HZ: f64 = 30.0;
/// Order of that autoregression (same sweep, forward errors only, fitted
/// again with the holes beside the gap interpolated: order 8 `noise` /
/// `occlusion` 4.64 /
/// 4.31, 12 3.06 / 4.17, 16 2.48 / 3.80; but on a twig swinging as a
/// noise-driven damped oscillator, the test
/// `a_twig_swinging_on_its_own_is_carried_across_a_long_gap`, 8 and 12
/// give 2.59 mm, 16 2.71, 24 2.93: a high order fits the simulator's
/// steady sinusoids, not a real twig's narrow-band swing).
const AR_ORDER: usize = 12;

/// Fills every gap of every trace that qualifies; returns what it did.
/// The traces are the session's markers after joining (the neighbours).
pub fn fill_gaps(traces: &mut [Trace], timeline: &Timeline, settings: GapSettings) -> GapStats {
    let one_s = timeline
        .frame_interval()
        .map_or(100, |dt| (1.0 / dt).round().max(1.0) as i64);
    let last = traces.iter().map(|t| t.last_frame()).max().unwrap_or(0);
    let first = traces.iter().map(|t| t.first_frame()).min().unwrap_or(0);
    // No gap is longer than the session.
    let max_len = ((settings.max_fill_s.max(settings.max_pchip_s) * one_s as f64).min(1e12) as i64)
        .clamp(1, (last - first).max(1));
    let reach = one_s.max(3 * max_len) + 2;
    // Each trace's fills apart, in frame order, so that they become the
    // trace's own list as they are instead of being copied into it (on an
    // hour-long take, 114 504 fills: 16 MB held twice at the end).
    let mut fills: Vec<Vec<Fill>> = traces.iter().map(|_| Vec::new()).collect();
    let mut stats = GapStats::default();
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get().min(2));
    {
        let mut streams: Vec<Stream<'_>> = traces.iter().map(Stream::new).collect();
        let mut pending: Vec<(usize, i64, i64)> = Vec::new();
        let mut frontier = first;
        while frontier <= last + reach {
            frontier += 1024;
            for (k, s) in streams.iter_mut().enumerate() {
                s.ensure(frontier);
                s.scan(k, &mut pending);
            }
            let ready = |g: &(usize, i64, i64)| g.2 + reach <= frontier || frontier > last + reach;
            let (now, later): (Vec<_>, Vec<_>) = pending.into_iter().partition(ready);
            pending = later;
            let one = |&(k, a, b): &(usize, i64, i64)| {
                let ctx = Context {
                    streams: &streams,
                    host: k,
                    a,
                    b,
                    reach,
                };
                fill_one(&ctx, timeline, settings, one_s)
            };
            for ((k, _, _), (fill, st)) in now.iter().zip(on_cores(&now, cores, one)) {
                stats.add(&st);
                if let (Some(f), Some(list)) = (fill, fills.get_mut(*k)) {
                    list.push(f);
                }
            }
            let keep_from = pending.iter().map(|g| g.1).min().unwrap_or(frontier) - reach;
            for s in streams.iter_mut() {
                s.trim(keep_from.min(frontier - reach));
            }
        }
    }
    for (t, list) in traces.iter_mut().zip(fills) {
        t.add_fills(list);
    }
    stats
}

/// `f` of every item, on two threads when `cores` allows and there are a
/// few items, in the items' order whatever the threads did (the gaps of a
/// batch are independent: each reads the streams and makes its own fill).
/// The long gaps' model made gap filling the marker stage's largest step.
fn on_cores<T: Sync, R: Send>(items: &[T], cores: usize, f: impl Fn(&T) -> R + Sync) -> Vec<R> {
    if cores < 2 || items.len() < 4 {
        return items.iter().map(&f).collect();
    }
    // Alternate items, so the long gaps spread over both threads.
    let f = &f;
    let half = |odd: usize| {
        (items.iter().skip(odd).step_by(2))
            .map(f)
            .collect::<Vec<R>>()
    };
    let (evens, odds) = std::thread::scope(|scope| {
        let odds = scope.spawn(|| half(1));
        let evens = half(0);
        let odds = odds.join().unwrap_or_else(|e| std::panic::resume_unwind(e));
        (evens, odds)
    });
    let mut out = Vec::with_capacity(items.len());
    let mut odds = odds.into_iter();
    for e in evens {
        out.push(e);
        out.extend(odds.next());
    }
    out
}

/// One trace read sequentially into a window of frames.
struct Stream<'a> {
    /// The trace's measurements (frame, position): only they are decoded,
    /// the missing frames between them are written as `None` (reading
    /// every sample, missing ones included, through a boxed iterator of
    /// `Sample`s was a tenth of gap filling's time).
    it: Box<dyn Iterator<Item = (i64, DVec3)> + Sync + 'a>,
    /// The measurement read but not yet placed in `buf`.
    next: Option<(i64, DVec3)>,
    /// Frame of `buf[start]`.
    base: i64,
    /// The window's frames from `start` on: measured positions, NaN where
    /// the frame is missing (a trace's positions are decoded from integers,
    /// never NaN; 24 bytes a frame instead of an `Option`'s 32). A plain
    /// vector, compacted now and then, so a lookup is one index.
    buf: Vec<DVec3>,
    start: usize,
    /// Next frame to look at for gaps, and the last measured frame seen.
    scanned: i64,
    last_measured: Option<i64>,
}

impl<'a> Stream<'a> {
    fn new(t: &'a Trace) -> Self {
        Stream {
            it: Box::new(t.measurements()),
            next: None,
            base: t.first_frame(),
            buf: Vec::new(),
            start: 0,
            scanned: t.first_frame(),
            last_measured: None,
        }
    }

    fn ensure(&mut self, upto: i64) {
        loop {
            let end = self.base + (self.buf.len() - self.start) as i64;
            if end > upto {
                break;
            }
            let Some((f, p)) = self.next.take().or_else(|| self.it.next()) else {
                break;
            };
            if f > upto {
                // Missing frames up to `upto`; the measurement waits.
                self.buf
                    .resize(self.buf.len() + (upto + 1 - end) as usize, DVec3::NAN);
                self.next = Some((f, p));
                break;
            }
            self.buf
                .resize(self.buf.len() + (f - end) as usize, DVec3::NAN);
            self.buf.push(p);
        }
    }

    fn trim(&mut self, before: i64) {
        let drop = (before - self.base).clamp(0, (self.buf.len() - self.start) as i64);
        self.start += drop as usize;
        self.base += drop;
        // Compacted once a quarter of the vector is behind the window: the
        // vector stays within 4/3 of the window (at 1/2 the 70 windows of an
        // hour-long take held 36 MB, the largest part of gap filling's
        // memory); each frame of the window is then copied about three
        // times over the take instead of about once.
        if self.start >= 1024 && 4 * self.start >= self.buf.len() {
            self.buf.drain(..self.start);
            self.start = 0;
        }
    }

    fn at(&self, f: i64) -> Option<DVec3> {
        let k = f - self.base;
        if k < 0 {
            return None;
        }
        self.buf
            .get(self.start + k as usize)
            .copied()
            .filter(|p| !p.x.is_nan())
    }

    /// Adds the gaps completed in the newly read frames to `out`.
    fn scan(&mut self, k: usize, out: &mut Vec<(usize, i64, i64)>) {
        let end = self.base + (self.buf.len() - self.start) as i64;
        while self.scanned < end {
            let f = self.scanned;
            if self.at(f).is_some() {
                if let Some(a) = self.last_measured.filter(|a| f > a + 1) {
                    out.push((k, a, f));
                }
                self.last_measured = Some(f);
            }
            self.scanned += 1;
        }
    }
}

/// One gap to fill: trace `host`, measured at `a` and `b`, missing between.
struct Context<'s, 'a> {
    streams: &'s [Stream<'a>],
    host: usize,
    a: i64,
    b: i64,
    reach: i64,
}

impl Context<'_, '_> {
    fn host_at(&self, f: i64) -> Option<DVec3> {
        self.streams[self.host].at(f)
    }
}

/// How one gap is filled.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Choice {
    /// PCHIP of the marker's own samples (the shortest gaps).
    Pchip,
    /// A cubic Hermite whose ends are fitted to the marker's own samples.
    Own,
    /// The neighbours' model plus the Hermite of its residual.
    Model,
    /// Left open: the far end does not continue the neighbours' path.
    Reject,
    /// Left open: too long for any fill.
    TooLong,
}

/// Fills one gap; returns the fill (if any) and what happened.
fn fill_one(
    ctx: &Context<'_, '_>,
    timeline: &Timeline,
    settings: GapSettings,
    one_s: i64,
) -> (Option<Fill>, GapStats) {
    let (a, b) = (ctx.a, ctx.b);
    let missing = (b - a - 1) as u64;
    let mut st = GapStats::default();
    if ctx.host_at(a).is_none() || ctx.host_at(b).is_none() {
        return (None, st);
    }
    let dt = (timeline.time(b) - timeline.time(a)) / (b - a) as f64;
    let duration = missing as f64 * dt;
    // A long gap's model is fitted as `model::LONG` says, over 2 s each
    // side; the others' (their plausibility) as `model::CHECK`, over 1 s.
    let long = duration > MAX_OWN_S;
    let (fit, window) = if long {
        (model::LONG, (LONG_WINDOW_S * one_s as f64).round() as i64)
    } else {
        (model::CHECK, one_s)
    };
    let window = window.max(b - a).min(ctx.reach - 2);
    // Under noise of a millimetre the ends are fitted over longer spans and
    // the neighbours smoothed (their noise would pass into the fill).
    let (end_span, noisy) = end_fit(|f| ctx.host_at(f), a, b, dt);
    let smooth = if noisy {
        (NOISY_SMOOTH_S / dt).round() as usize
    } else {
        0
    };
    let model = if settings.neighbours && duration <= settings.max_fill_s + 1e-9 {
        Model::fit(ctx, window, smooth, fit)
    } else {
        None
    };
    let choice = choose(model.as_ref(), b - a, duration, noisy, settings);
    let pchip_ok = duration <= settings.max_pchip_s + 1e-9;
    // Where the model cannot be evaluated (a neighbour's hole, too few
    // residuals at an end), a gap PCHIP may fill is filled from the
    // marker's own samples.
    let own =
        || own_fill(|f| ctx.host_at(f), a, b, end_span).or_else(|| Some(pchip_between(ctx, a, b)));
    let fill = match (choice, &model) {
        (Choice::Model, Some(m)) => {
            neighbour_fill(ctx, m, end_span, duration)
                .or_else(|| if pchip_ok { own() } else { None })
        }
        (Choice::Own, _) => own(),
        (Choice::Pchip, _) => Some(pchip_between(ctx, a, b)),
        _ => None,
    };
    match (choice, fill) {
        (Choice::Reject, _) => {
            st.rejected = 1;
            st.rejected_frames = missing;
        }
        (_, Some(f)) => {
            st.filled = 1;
            st.filled_frames = missing;
            st.from_neighbours = u64::from(f.from_neighbours());
            return (Some(f), st);
        }
        _ => {
            st.too_long = 1;
            st.too_long_frames = missing;
        }
    }
    (None, st)
}

/// The host's measurement noise (σ per axis, m) from its third
/// differences over `span` frames at each end of the gap: white noise adds
/// 20 σ² to them, a tree's sway at 100–240 Hz next to nothing (a second
/// difference would count a 200 mm sway as noise).
fn noise_sigma(at: impl Fn(i64) -> Option<DVec3>, a: i64, b: i64, span: i64) -> Option<f64> {
    let (mut sum, mut n) = (0.0, 0usize);
    for f in (a - span..=a - 3).chain(b..=b + span - 3) {
        let p = |d: i64| at(f + d);
        if let (Some(p0), Some(p1), Some(p2), Some(p3)) = (p(0), p(1), p(2), p(3)) {
            sum += third_difference([p0, p1, p2, p3]).length_squared();
            n += 1;
        }
    }
    (n >= 4).then(|| (sum / n as f64 / 60.0).sqrt())
}

/// Decides one gap of `h` frames (`duration` s missing) with the fitted
/// model, if any; `noisy`: the host's ends are noisy (`NOISY_M`).
fn choose(
    model: Option<&Model>,
    h: i64,
    duration: f64,
    noisy: bool,
    settings: GapSettings,
) -> Choice {
    let pchip_ok = duration <= settings.max_pchip_s + 1e-9;
    if let Some(m) = model {
        if !m.plausible(h) {
            return Choice::Reject;
        }
    }
    match model {
        // PCHIP only: the baseline the fills are compared with.
        _ if !settings.neighbours => {
            if pchip_ok {
                Choice::Pchip
            } else {
                Choice::TooLong
            }
        }
        _ if pchip_ok && duration < MIN_OWN_S && !noisy => Choice::Pchip,
        _ if pchip_ok && duration <= MAX_OWN_S => Choice::Own,
        Some(_) => Choice::Model,
        None if pchip_ok => Choice::Own,
        None => Choice::TooLong,
    }
}

/// The model's fill: its positions plus its residual across the gap, by
/// the residual's own autoregression ([`swing`]) tilted to meet the
/// residual's fitted ends (value and slope of a quadratic over `span`
/// frames each side), or, where that cannot be modelled, by a cubic
/// Hermite between those ends whose slopes fade towards the secant on
/// long gaps.
fn neighbour_fill(ctx: &Context<'_, '_>, m: &Model, span: i64, duration: f64) -> Option<Fill> {
    let (a, b) = (ctx.a, ctx.b);
    let n = span as usize;
    let left = (m.before.iter().rev().take(n).enumerate())
        .filter_map(|(i, r)| r.map(|r| (-(i as f64), r)));
    let right = (m.after.iter().take(n).enumerate()).filter_map(|(i, r)| r.map(|r| (i as f64, r)));
    // The residual at the gap's ends (the host and every neighbour are
    // measured there); an end with too few residuals near it for a fit
    // keeps that value and the secant's slope.
    let (ra, rb) = ((*m.before.last()?)?, (*m.after.first()?)?);
    let h = (b - a) as f64;
    let raw = (rb - ra) / h;
    let (p0, s0) = quad_end(left).unwrap_or((ra, raw));
    let (p1, s1) = quad_end(right).unwrap_or((rb, raw));
    let t = duration / SLOPE_FADE_S;
    let keep = 1.0 / (1.0 + t * t * t * t);
    let secant = (p1 - p0) / h;
    // Frames per block of the residual's autoregression.
    let step = (((h - 1.0) / duration) / AR_RATE_HZ).round().max(1.0) as usize;
    // The residual on frames a ..= b: its swing tilted to meet the fitted
    // ends, or the Hermite between them where it cannot be modelled.
    let residual: Vec<DVec3> =
        match swing::across(&m.before, &m.after, (b - a) as usize, step, AR_ORDER) {
            Some(s) => {
                let (sa, sb) = (s[0], s[s.len() - 1]);
                (s.iter().enumerate())
                    .map(|(k, r)| {
                        let x = k as f64 / h;
                        *r + (p0 - sa) * (1.0 - x) + (p1 - sb) * x
                    })
                    .collect()
            }
            None => {
                let hermite = Fill {
                    from: a,
                    to: b,
                    curve: Curve::Hermite {
                        p0,
                        m0: secant + (s0 - secant) * keep,
                        p1,
                        m1: secant + (s1 - secant) * keep,
                    },
                };
                (a..=b).map(|f| hermite.at(f)).collect()
            }
        };
    let points = (a + 1..b)
        .map(|f| Some(m.at(f)? + residual[(f - a) as usize]))
        .collect::<Option<Vec<_>>>()?;
    Some(Fill {
        from: a,
        to: b,
        curve: Curve::Points(points),
    })
}

/// A cubic Hermite across the gap between quadratic fits of the host's
/// own samples over `span` frames at each end (value and slope there).
fn own_fill(at: impl Fn(i64) -> Option<DVec3>, a: i64, b: i64, span: i64) -> Option<Fill> {
    let pa = at(a)?;
    let left = (0..span).filter_map(|i| at(a - i).map(|p| (-(i as f64), p - pa)));
    let right = (0..span).filter_map(|i| at(b + i).map(|p| (i as f64, p - pa)));
    let (va, sa) = quad_end(left)?;
    let (vb, sb) = quad_end(right)?;
    Some(Fill {
        from: a,
        to: b,
        curve: Curve::Hermite {
            p0: pa + va,
            m0: sa,
            p1: pa + vb,
            m1: sb,
        },
    })
}

/// The marker's own course across frames `a` to `b` (both measured;
/// `at`: its samples, of which those between are not read), drawn as the
/// gap filler draws a gap of up to [`MAX_OWN_S`] from the marker's own
/// samples: a cubic Hermite between quadratic fits over
/// [`END_FIT_S`] each side, or [`NOISY_END_FIT_S`] where the samples
/// beside the gap are noisy. `dt`: seconds per frame. `None` where an end
/// has too few samples for a fit.
pub(super) fn own_course(
    at: impl Fn(i64) -> Option<DVec3>,
    a: i64,
    b: i64,
    dt: f64,
) -> Option<Fill> {
    let (span, _) = end_fit(&at, a, b, dt);
    own_fill(at, a, b, span)
}

/// Frames each side of the gap `a`..`b` the end fits use, and whether
/// the marker's samples there are noisy: [`END_FIT_S`], or
/// [`NOISY_END_FIT_S`] where their noise is over [`NOISY_M`]. `dt`:
/// seconds per frame.
fn end_fit(at: impl Fn(i64) -> Option<DVec3>, a: i64, b: i64, dt: f64) -> (i64, bool) {
    let base = ((END_FIT_S / dt).round() as i64).max(4);
    if noise_sigma(at, a, b, base).is_some_and(|s| s > NOISY_M) {
        (((NOISY_END_FIT_S / dt).round() as i64).max(4), true)
    } else {
        (base, false)
    }
}

/// The longest end fit [`own_course`] uses (s).
pub(super) const OWN_END_MAX_S: f64 = if END_FIT_S > NOISY_END_FIT_S {
    END_FIT_S
} else {
    NOISY_END_FIT_S
};

/// Least-squares quadratic through `(x, y)` samples (x in frames); its
/// value and slope (per frame) at `x = 0`. `None` with fewer than four
/// samples.
fn quad_end(samples: impl Iterator<Item = (f64, DVec3)>) -> Option<(DVec3, DVec3)> {
    let mut sx = [0.0f64; 5];
    let mut sy = [DVec3::ZERO; 3];
    let mut n = 0;
    for (x, y) in samples {
        let mut p = 1.0;
        for (k, s) in sx.iter_mut().enumerate() {
            if k < 3 {
                sy[k] += y * p;
            }
            *s += p;
            p *= x;
        }
        n += 1;
    }
    if n < 4 {
        return None;
    }
    // Normal equations [[s0 s1 s2] [s1 s2 s3] [s2 s3 s4]] c = sy, by Cramer.
    let m = [
        [sx[0], sx[1], sx[2]],
        [sx[1], sx[2], sx[3]],
        [sx[2], sx[3], sx[4]],
    ];
    let det3 = |m: &[[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let d = det3(&m);
    if d.abs() < 1e-9 {
        return None;
    }
    let coef = |c: usize| {
        let axis = |i: usize| {
            let mut mm = m;
            for (r, row) in mm.iter_mut().enumerate() {
                row[c] = sy[r][i];
            }
            det3(&mm) / d
        };
        DVec3::new(axis(0), axis(1), axis(2))
    };
    Some((coef(0), coef(1)))
}

/// PCHIP between the host's measured samples at `a` and `b`, with slopes
/// from up to `SLOPE_SPAN` contiguous measured samples on each side
/// (linear when a side has only one).
fn pchip_between(ctx: &Context<'_, '_>, a: i64, b: i64) -> Fill {
    let pa = ctx.host_at(a).unwrap_or(DVec3::NAN);
    let pb = ctx.host_at(b).unwrap_or(DVec3::NAN);
    let side = |from: i64, dir: i64| -> Option<(DVec3, f64)> {
        let mut far = from;
        for d in 1..=SLOPE_SPAN as i64 {
            if ctx.host_at(from + dir * d).is_some() {
                far = from + dir * d;
            } else {
                break;
            }
        }
        if far == from {
            return None;
        }
        let (p0, p1) = (ctx.host_at(from)?, ctx.host_at(far)?);
        let span = (far - from).abs() as f64;
        Some(if dir < 0 {
            ((p0 - p1) / span, span)
        } else {
            ((p1 - p0) / span, span)
        })
    };
    let h = (b - a) as f64;
    let secant = (pb - pa) / h;
    let (m0, m1) = match (side(a, -1), side(b, 1)) {
        (Some((dl, hl)), Some((dr, hr))) => (
            pchip_slope(dl, hl, secant, h),
            pchip_slope(secant, h, dr, hr),
        ),
        _ => (secant, secant),
    };
    Fill {
        from: a,
        to: b,
        curve: Curve::Hermite {
            p0: pa,
            m0,
            p1: pb,
            m1,
        },
    }
}

/// Fritsch–Carlson slope at the knot between an interval of width `h1`
/// with secant `d1` and one of width `h2` with secant `d2`, per axis.
fn pchip_slope(d1: DVec3, h1: f64, d2: DVec3, h2: f64) -> DVec3 {
    let axis = |a: f64, b: f64| {
        if a * b <= 0.0 {
            0.0
        } else {
            let w1 = 2.0 * h2 + h1;
            let w2 = h2 + 2.0 * h1;
            (w1 + w2) / (w1 / a + w2 / b)
        }
    };
    DVec3::new(axis(d1.x, d2.x), axis(d1.y, d2.y), axis(d1.z, d2.z))
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::model::trace::SampleKind;

    /// `n` frames at 100 Hz (also `reclaim`'s tests' clock).
    pub(crate) fn timeline(n: usize) -> Timeline {
        Timeline {
            times: (0..n).map(|i| i as f64 / 100.0).collect(),
            anchors: vec![(0, 0)],
        }
    }

    /// Fills up to 3 s, PCHIP up to 0.5 s, from the neighbours.
    pub(crate) fn settings() -> GapSettings {
        GapSettings {
            max_fill_s: 3.0,
            max_pchip_s: 0.5,
            neighbours: true,
        }
    }

    /// One marker's trace filled as the stage fills it and by PCHIP alone
    /// (the baseline), with the stage's statistics.
    fn ours_and_pchip(make: impl Fn() -> Trace, tl: &Timeline) -> (Trace, Trace, GapStats) {
        let mut ours = [make()];
        let st = fill_gaps(&mut ours, tl, settings());
        let mut base = [make()];
        let pchip_only = GapSettings {
            neighbours: false,
            ..settings()
        };
        fill_gaps(&mut base, tl, pchip_only);
        let [ours] = ours;
        let [base] = base;
        (ours, base, st)
    }

    fn trace_of(
        id: usize,
        f: impl Fn(i64) -> DVec3,
        frames: impl IntoIterator<Item = i64>,
    ) -> Trace {
        let mut it = frames.into_iter();
        let first = it.next().unwrap();
        let mut t = Trace::new(id, first, f(first), None);
        for n in it {
            t.push(n, f(n), None);
        }
        t
    }

    #[test]
    fn short_gaps_follow_smooth_motion_closely_and_are_flagged() {
        // 30 mm sway at 0.8 Hz, 100 Hz, a 10-frame and a 30-frame gap; no
        // neighbours: the marker's own samples.
        let f = |n: i64| {
            let t = n as f64 / 100.0;
            DVec3::new(0.03 * (5.0 * t).sin(), 1.0, 0.01 * (5.0 * t).cos())
        };
        let frames = (0..50).chain(60..100).chain(130..200);
        let mut tr = [trace_of(0, f, frames)];
        let st = fill_gaps(&mut tr, &timeline(200), settings());
        assert_eq!((st.filled, st.from_neighbours), (2, 0));
        assert_eq!(st.filled_frames, 10 + 30);
        for s in tr[0].samples() {
            if (50..60).contains(&s.frame) || (100..130).contains(&s.frame) {
                assert_eq!(s.kind, SampleKind::Filled);
                let err = s.position.distance(f(s.frame));
                let limit = if s.frame < 60 { 0.0005 } else { 0.005 };
                assert!(err < limit, "frame {}: {err}", s.frame);
            } else {
                assert_eq!(s.kind, SampleKind::Measured);
            }
        }
    }

    #[test]
    fn neighbours_fill_a_long_gap_in_a_sway_pchip_cannot_follow() {
        // Three tips on one limb swinging 80 mm at 1.3 Hz with small twig
        // motions of their own; tip 0 hidden for 1.2 s.
        let limb = |n: i64| 0.08 * (8.0 * n as f64 / 100.0).sin();
        let tip = |k: usize| {
            move |n: i64| {
                let t = n as f64 / 100.0;
                DVec3::new(
                    0.1 * k as f64 + limb(n),
                    1.0 + 0.002 * (17.0 * t + k as f64).sin(),
                    0.3 * limb(n),
                )
            }
        };
        let mut tr = [
            trace_of(0, tip(0), (0..300).chain(420..700)),
            trace_of(1, tip(1), 0..700),
            trace_of(2, tip(2), 0..700),
        ];
        let st = fill_gaps(&mut tr, &timeline(700), settings());
        assert_eq!((st.filled, st.from_neighbours), (1, 1));
        let worst = tr[0]
            .samples()
            .filter(|s| s.kind == SampleKind::Filled)
            .map(|s| s.position.distance(tip(0)(s.frame)))
            .fold(0.0, f64::max);
        assert!(worst < 0.005, "worst {worst}");
    }

    /// A twig swinging on its own as a damped oscillator driven by white
    /// noise (natural frequency `hz`, damping ratio `zeta`), sampled at
    /// 100 Hz for `n` frames on two axes: narrow-band and random, as a
    /// branch in turbulent wind, not a sinusoid of fixed phase.
    fn random_twig(seed: u64, hz: f64, zeta: f64, n: usize) -> Vec<DVec3> {
        let mut rng = crate::rng::Rng::new(seed);
        let w = std::f64::consts::TAU * hz / 100.0;
        let r = (-zeta * w).exp();
        let (c1, c2) = (2.0 * r * (w * (1.0 - zeta * zeta).sqrt()).cos(), -r * r);
        let mut x = vec![DVec3::ZERO; n + 500];
        for t in 2..x.len() {
            let e = DVec3::new(rng.normal(), 0.0, rng.normal());
            x[t] = x[t - 1] * c1 + x[t - 2] * c2 + e;
        }
        // Settled, scaled to 4 mm RMS per axis.
        let x = &x[500..];
        let rms = (x.iter().map(|p| p.x * p.x).sum::<f64>() / n as f64).sqrt();
        x.iter().map(|p| *p * (0.004 / rms)).collect()
    }

    #[test]
    fn a_twig_swinging_on_its_own_is_carried_across_a_long_gap() {
        // Three tips on a limb swaying 60 mm at 0.6 Hz; each twig also
        // swings on its own (1.8 Hz, 5 % of critical damping, 4 mm RMS),
        // which the neighbours cannot know; tip 0 hidden for 1 s every 4 s.
        let n = 4000;
        let twigs: Vec<Vec<DVec3>> = (0..3).map(|k| random_twig(7 + k, 1.8, 0.05, n)).collect();
        let tip = |k: usize| {
            let twig = twigs[k].clone();
            move |f: i64| {
                let limb = 0.06 * (std::f64::consts::TAU * 0.6 * f as f64 / 100.0).sin();
                DVec3::new(0.1 * k as f64 + limb, 1.0, 0.3 * limb) + twig[f as usize]
            }
        };
        let hidden = |f: i64| f >= 200 && f % 400 < 100;
        let frames = (0..n as i64).filter(|&f| !hidden(f));
        let mut tr = [
            trace_of(0, tip(0), frames),
            trace_of(1, tip(1), 0..n as i64),
            trace_of(2, tip(2), 0..n as i64),
        ];
        let st = fill_gaps(&mut tr, &timeline(n), settings());
        assert_eq!((st.filled, st.from_neighbours), (9, 9));
        let ours = fill_error(&tr[0], tip(0));
        // The twig's own swing is what a fill that only follows the
        // neighbours misses: with a Hermite of the model's residual across
        // the gap (before the residual's autoregression) the fills were
        // 7.7 mm off; 2.6 mm now.
        assert!(ours < 0.004, "mean fill error {ours}");
    }

    /// Mean distance from `truth` of trace 0's filled samples.
    fn fill_error(t: &Trace, truth: impl Fn(i64) -> DVec3) -> f64 {
        let e: Vec<f64> = t
            .samples()
            .filter(|s| s.kind == SampleKind::Filled)
            .map(|s| s.position.distance(truth(s.frame)))
            .collect();
        e.iter().sum::<f64>() / e.len().max(1) as f64
    }

    #[test]
    fn end_fitted_hermite_beats_pchip_on_a_noisy_twig() {
        // A twig swinging 5 mm at 2.5 Hz, measured at 240 Hz with ±0.3 mm
        // of deterministic noise; gaps of 20 and 40 frames.
        let truth = |n: i64| {
            let t = n as f64 / 240.0;
            DVec3::new(0.005 * (15.7 * t).sin(), 1.0, 0.002 * (15.7 * t).cos())
        };
        let noisy =
            move |n: i64| truth(n) + DVec3::splat(0.0003 * ((n * 7919) % 13 - 6) as f64 / 6.0);
        let frames = || (0..300).chain(321..600).chain(641..900);
        let tl = Timeline {
            times: (0..900).map(|i| i as f64 / 240.0).collect(),
            anchors: vec![(0, 0)],
        };
        let (ours, base, st) = ours_and_pchip(|| trace_of(0, noisy, frames()), &tl);
        assert_eq!((st.filled, st.from_neighbours), (2, 0));
        let (e, p) = (fill_error(&ours, truth), fill_error(&base, truth));
        assert!(e <= 0.7 * p, "ours {e} PCHIP {p}");
    }

    #[test]
    fn the_shortest_gaps_are_pchip() {
        // 4 missing frames at 100 Hz (0.04 s): PCHIP, exactly as the
        // baseline fills it.
        let f = |n: i64| DVec3::new(0.03 * (n as f64 / 7.0).sin(), 1.0, 0.0);
        let frames = || (0..50).chain(54..100);
        let (ours, base, _) = ours_and_pchip(|| trace_of(0, f, frames()), &timeline(100));
        assert_eq!(ours.fills(), base.fills());
    }

    #[test]
    fn short_gaps_of_a_noisy_marker_are_filled_between_fitted_ends() {
        // A twig swinging 5 mm at 2 Hz measured at 240 Hz with ±1.7 mm
        // (σ 1 mm) of deterministic noise, 8-frame gaps every 0.5 s: PCHIP
        // would start from two noisy samples; the fitted ends average the
        // noise out.
        let truth = |n: i64| {
            let t = n as f64 / 240.0;
            DVec3::new(0.005 * (12.6 * t).sin(), 1.0, 0.003 * (12.6 * t).cos())
        };
        let noise = |n: i64, k: i64| {
            let h = (n * 2_654_435_761 + k * 40_503).rem_euclid(1 << 20) as f64;
            0.0017 * (2.0 * h / (1 << 20) as f64 - 1.0)
        };
        let noisy = move |n: i64| truth(n) + DVec3::new(noise(n, 1), noise(n, 2), noise(n, 3));
        let frames = || (0..2400).filter(|n| n % 120 < 112 || *n < 120);
        let tl = Timeline {
            times: (0..2400).map(|i| i as f64 / 240.0).collect(),
            anchors: vec![(0, 0)],
        };
        let (ours, base, st) = ours_and_pchip(|| trace_of(0, noisy, frames()), &tl);
        assert_eq!(st.filled, 18);
        let (e, p) = (fill_error(&ours, truth), fill_error(&base, truth));
        assert!(e <= 0.8 * p, "ours {e} PCHIP {p}");
        // Measured samples stay as measured (stored to 0.01 mm).
        for s in ours.samples().filter(|s| s.kind == SampleKind::Measured) {
            assert!(s.position.distance(noisy(s.frame)) < 1e-5);
        }
    }

    #[test]
    fn a_gap_between_two_markers_stays_open() {
        // Tip 0's trace wrongly continues with a marker 70 mm away: the far
        // end does not follow the neighbours, so no fill bridges them.
        let limb = |n: i64| 0.05 * (6.0 * n as f64 / 100.0).sin();
        let at = |x: f64| move |n: i64| DVec3::new(x + limb(n), 1.0, 0.0);
        let mut wrong = trace_of(0, at(0.0), 0..300);
        for n in 330..600 {
            wrong.push(n, at(0.07)(n), None);
        }
        let mut tr = [
            wrong,
            trace_of(1, at(0.2), 0..600),
            trace_of(2, at(-0.2), 0..600),
        ];
        let st = fill_gaps(&mut tr, &timeline(600), settings());
        assert_eq!((st.filled, st.rejected), (0, 1));
    }

    #[test]
    fn long_gaps_without_neighbours_stay_open() {
        let f = |_n: i64| DVec3::ZERO;
        // 61 missing frames (5..=65) at 100 Hz > 0.5 s of PCHIP.
        let mut tr = [trace_of(0, f, (0..5).chain(66..70))];
        let st = fill_gaps(&mut tr, &timeline(70), settings());
        assert_eq!((st.filled, st.too_long, st.too_long_frames), (0, 1, 61));
        assert!(tr[0]
            .samples()
            .filter(|s| (5..66).contains(&s.frame))
            .all(|s| s.kind == SampleKind::Missing && s.position.is_nan()));
    }

    #[test]
    fn no_overshoot_on_monotone_data() {
        let f = |n: i64| DVec3::new(if n < 10 { 0.0 } else { 0.02 }, 0.0, 0.0);
        let mut tr = [trace_of(0, f, (0..5).chain(15..20))];
        let st = fill_gaps(&mut tr, &timeline(20), settings());
        assert_eq!(st.filled, 1);
        for s in tr[0].samples() {
            assert!(s.position.x >= -1e-12 && s.position.x <= 0.02 + 1e-12);
        }
    }
}
