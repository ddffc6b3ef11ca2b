//! Gap filling (paper §4, spec §3): from the neighbours' motion where they
//! predict it, by PCHIP where they do not.
//!
//! A tip hidden for a while keeps swinging with its limb. The frames of the
//! gap are predicted from the markers nearby that were measured through it
//! (a local linear model of the neighbours' trajectories, after Federolf
//! 2013 and Gløersen & Federolf 2016 for human markers):
//!
//! `p̂(t) = p(a) + Σ wⱼ (qⱼ(t) − qⱼ(a))`, with the weights fitted by least
//! squares (ridge) to the marker's own motion against theirs in the second
//! before and after the gap; the remaining mismatch at the far end `b` is
//! spread linearly over the gap, so the fill meets both measured ends.
//!
//! Whether to trust it is decided by the same model, on the marker's own
//! data: gaps of the same length are cut out of its measured stretches next
//! to the real gap, filled by the model and compared with what was measured.
//! - Gaps up to `max_pchip_s` are filled by PCHIP (the cubic Hermite with
//!   Fritsch–Carlson slopes, which never overshoots): on the stress sweep
//!   the neighbours' model did not beat it there. Longer gaps, up to
//!   `max_fill_s`, are filled from the neighbours.
//! - A gap whose far end misses the neighbours' prediction by far more than
//!   the model misses on those test gaps (`PLAUSIBLE` × their RMS end error,
//!   at least `MIN_MISMATCH_M`) is left open: its two ends are most likely
//!   different markers, and no fill may bridge two markers.
//! - Without usable neighbours, PCHIP fills gaps up to `max_pchip_s`.
//!
//! Traces are read in one streaming pass with a window of a few seconds,
//! so memory does not grow with the session.

use std::collections::VecDeque;

use glam::DVec3;
use serde::Serialize;

use crate::model::trace::{Curve, Fill, Sample, SampleKind, Timeline, Trace};

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
/// Neighbours used in one fill.
const MAX_NEIGHBOURS: usize = 6;
/// Longest hole inside a neighbour's own data across the gap (frames),
/// bridged linearly.
const NEIGHBOUR_HOLE: i64 = 5;
/// Frames of the velocity used to fit the weights.
const LAG: i64 = 4;
/// Test gaps per side.
const TESTS: usize = 3;
/// A far end beyond this many test RMS end errors is not the same marker.
const PLAUSIBLE: f64 = 6.0;
const MIN_MISMATCH_M: f64 = 0.008;

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
    let reach = one_s.max(3 * max_len) + LAG + 2;
    let mut fills: Vec<(usize, Fill)> = Vec::new();
    let mut stats = GapStats::default();
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
            for (k, a, b) in now {
                let ctx = Context {
                    streams: &streams,
                    host: k,
                    a,
                    b,
                    reach,
                };
                let (fill, st) = fill_one(&ctx, timeline, settings, one_s);
                stats.add(&st);
                if let Some(f) = fill {
                    fills.push((k, f));
                }
            }
            let keep_from = pending.iter().map(|g| g.1).min().unwrap_or(frontier) - reach;
            for s in streams.iter_mut() {
                s.trim(keep_from.min(frontier - reach));
            }
        }
    }
    for (k, f) in fills {
        if let Some(t) = traces.get_mut(k) {
            t.add_fill(f);
        }
    }
    stats
}

/// One trace read sequentially into a window of frames.
struct Stream<'a> {
    it: Box<dyn Iterator<Item = Sample> + 'a>,
    base: i64,
    buf: VecDeque<Option<DVec3>>,
    /// Next frame to look at for gaps, and the last measured frame seen.
    scanned: i64,
    last_measured: Option<i64>,
}

impl<'a> Stream<'a> {
    fn new(t: &'a Trace) -> Self {
        Stream {
            it: Box::new(t.samples()),
            base: t.first_frame(),
            buf: VecDeque::new(),
            scanned: t.first_frame(),
            last_measured: None,
        }
    }

    fn ensure(&mut self, upto: i64) {
        while self.base + (self.buf.len() as i64) <= upto {
            match self.it.next() {
                Some(s) => self
                    .buf
                    .push_back((s.kind == SampleKind::Measured).then_some(s.position)),
                None => break,
            }
        }
    }

    fn trim(&mut self, before: i64) {
        while self.base < before && !self.buf.is_empty() {
            self.buf.pop_front();
            self.base += 1;
        }
    }

    fn at(&self, f: i64) -> Option<DVec3> {
        let k = f - self.base;
        if k < 0 {
            return None;
        }
        self.buf.get(k as usize).copied().flatten()
    }

    /// Adds the gaps completed in the newly read frames to `out`.
    fn scan(&mut self, k: usize, out: &mut Vec<(usize, i64, i64)>) {
        let end = self.base + self.buf.len() as i64;
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

/// The neighbour model for one gap: who, with what weights.
struct Model {
    neighbours: Vec<usize>,
    weights: Vec<f64>,
}

impl Model {
    /// A neighbour's position at `f`, bridging its own short holes linearly.
    fn neighbour_at(s: &Stream<'_>, f: i64) -> Option<DVec3> {
        if let Some(p) = s.at(f) {
            return Some(p);
        }
        let before = (1..=NEIGHBOUR_HOLE).find_map(|d| s.at(f - d).map(|p| (f - d, p)))?;
        let after = (1..=NEIGHBOUR_HOLE).find_map(|d| s.at(f + d).map(|p| (f + d, p)))?;
        let x = (f - before.0) as f64 / (after.0 - before.0) as f64;
        Some(before.1.lerp(after.1, x))
    }

    /// The model's positions for frames `a+1 .. b` of a gap from `pa` at
    /// `a`, and its prediction for `b` (before the end correction).
    fn predict(
        &self,
        ctx: &Context<'_, '_>,
        a: i64,
        b: i64,
        pa: DVec3,
    ) -> Option<(Vec<DVec3>, DVec3)> {
        let q0: Vec<DVec3> = self
            .neighbours
            .iter()
            .map(|&j| Self::neighbour_at(&ctx.streams[j], a))
            .collect::<Option<_>>()?;
        let mut out = Vec::with_capacity((b - a) as usize);
        for f in a + 1..=b {
            let mut p = pa;
            for (n, &j) in self.neighbours.iter().enumerate() {
                let q = Self::neighbour_at(&ctx.streams[j], f)?;
                p += (q - q0[n]) * self.weights[n];
            }
            out.push(p);
        }
        let end = out.pop()?;
        Some((out, end))
    }
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
    let dt = (timeline.time(b) - timeline.time(a)) / (b - a) as f64;
    let duration = missing as f64 * dt;
    let (Some(pa), Some(pb)) = (ctx.host_at(a), ctx.host_at(b)) else {
        return (None, st);
    };
    let pchip_ok = duration <= settings.max_pchip_s + 1e-9;
    let model = if settings.neighbours && duration <= settings.max_fill_s + 1e-9 {
        fit(ctx, one_s)
    } else {
        None
    };
    let Some(model) = model else {
        if pchip_ok {
            st.filled = 1;
            st.filled_frames = missing;
            return (Some(pchip(ctx, a, b)), st);
        }
        st.too_long = 1;
        st.too_long_frames = missing;
        return (None, st);
    };
    let Some((points, end)) = model.predict(ctx, a, b, pa) else {
        if pchip_ok {
            st.filled = 1;
            st.filled_frames = missing;
            return (Some(pchip(ctx, a, b)), st);
        }
        st.too_long = 1;
        st.too_long_frames = missing;
        return (None, st);
    };
    let test = cross_validate(ctx, &model, b - a);
    // Plausibility: the far end must continue the predicted path about as
    // well as the model does on the marker's own data.
    let mismatch = pb - end;
    if let Some(t) = &test {
        if mismatch.length() > (PLAUSIBLE * t.end_rms).max(MIN_MISMATCH_M) {
            st.rejected = 1;
            st.rejected_frames = missing;
            return (None, st);
        }
    }
    // Where PCHIP may fill, it does: on the stress sweep the neighbours'
    // model did not beat it on gaps up to 0.5 s (test gaps chose it too
    // often); the model fills the longer gaps PCHIP cannot.
    let use_pchip = pchip_ok;
    st.filled = 1;
    st.filled_frames = missing;
    if use_pchip {
        return (Some(pchip(ctx, a, b)), st);
    }
    st.from_neighbours = 1;
    let h = (b - a) as f64;
    let points = points
        .into_iter()
        .enumerate()
        .map(|(k, p)| p + mismatch * ((k + 1) as f64 / h))
        .collect();
    (
        Some(Fill {
            from: a,
            to: b,
            curve: Curve::Points(points),
        }),
        st,
    )
}

/// Chooses the neighbours measured through the gap (nearest first) and
/// fits their weights to the host's motion around it.
fn fit(ctx: &Context<'_, '_>, one_s: i64) -> Option<Model> {
    let (a, b) = (ctx.a, ctx.b);
    let pa = ctx.host_at(a)?;
    let mut near: Vec<(f64, usize)> = Vec::new();
    for (j, s) in ctx.streams.iter().enumerate() {
        if j == ctx.host {
            continue;
        }
        let (Some(qa), Some(_)) = (s.at(a), s.at(b)) else {
            continue;
        };
        if (a + 1..b).all(|f| Model::neighbour_at(s, f).is_some()) {
            near.push((pa.distance_squared(qa), j));
        }
    }
    if near.is_empty() {
        return None;
    }
    near.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
    near.truncate(MAX_NEIGHBOURS);
    let neighbours: Vec<usize> = near.iter().map(|n| n.1).collect();
    let k = neighbours.len();
    // Normal equations of v_host ≈ Σ wⱼ vⱼ over the velocities (at LAG) of
    // the second before and after the gap.
    let mut ata = vec![0.0; k * k];
    let mut atb = vec![0.0; k];
    let mut rows = 0;
    let span = one_s.min(ctx.reach - LAG - 1);
    let frames = (a - span..=a).chain(b..=b + span);
    let mut v = vec![DVec3::ZERO; k];
    for f in frames {
        let (Some(h1), Some(h0)) = (ctx.host_at(f), ctx.host_at(f - LAG)) else {
            continue;
        };
        if f > a && f - LAG < b {
            continue;
        }
        let mut ok = true;
        for (n, &j) in neighbours.iter().enumerate() {
            match (ctx.streams[j].at(f), ctx.streams[j].at(f - LAG)) {
                (Some(q1), Some(q0)) => v[n] = q1 - q0,
                _ => {
                    ok = false;
                    break;
                }
            }
        }
        if !ok {
            continue;
        }
        let vh = h1 - h0;
        for r in 0..k {
            atb[r] += v[r].dot(vh);
            for c in 0..k {
                ata[r * k + c] += v[r].dot(v[c]);
            }
        }
        rows += 1;
    }
    if rows < 2 * k + 4 {
        return None;
    }
    let trace: f64 = (0..k).map(|r| ata[r * k + r]).sum();
    let ridge = 1e-3 * trace / k as f64 + 1e-12;
    for r in 0..k {
        ata[r * k + r] += ridge;
    }
    let weights = solve(&mut ata, &mut atb, k)?;
    Some(Model {
        neighbours,
        weights,
    })
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

/// Errors of both methods on test gaps cut from the host's own data.
struct Test {
    /// Mean distance over the test gaps' frames (m). Not used to choose
    /// any more (PCHIP fills up to `max_pchip_s`); kept for diagnostics.
    #[allow(dead_code)]
    model: f64,
    /// The same for PCHIP.
    #[allow(dead_code)]
    pchip: f64,
    /// RMS of the model's uncorrected error at the far end (m).
    end_rms: f64,
}

/// Cuts up to `TESTS` gaps of width `h` (frames between the two ends) from
/// each side of the real gap, where the host was measured throughout.
fn cross_validate(ctx: &Context<'_, '_>, model: &Model, h: i64) -> Option<Test> {
    let (a, b) = (ctx.a, ctx.b);
    let side = (ctx.reach - LAG - 2).max(h + 2);
    let mut starts = Vec::new();
    // Before the gap: windows [s, s + h] fully measured, ending by a − 1.
    let mut s = a - h - 1;
    while s >= a - side && starts.len() < TESTS {
        if (s..=s + h).all(|f| ctx.host_at(f).is_some()) {
            starts.push(s);
            s -= h + 1;
        } else {
            s -= 1;
        }
    }
    let mut s = b + 1;
    let mut after = 0;
    while s + h <= b + side && after < TESTS {
        if (s..=s + h).all(|f| ctx.host_at(f).is_some()) {
            starts.push(s);
            after += 1;
            s += h + 1;
        } else {
            s += 1;
        }
    }
    let (mut model_err, mut pchip_err, mut end2, mut n, mut tests) =
        (0.0, 0.0, 0.0, 0usize, 0usize);
    for s in starts {
        let e = s + h;
        let (Some(ps), Some(pe)) = (ctx.host_at(s), ctx.host_at(e)) else {
            continue;
        };
        let Some((points, end)) = model.predict(ctx, s, e, ps) else {
            continue;
        };
        let fill = pchip_between(ctx, s, e);
        let miss = pe - end;
        for (k, p) in points.iter().enumerate() {
            let f = s + 1 + k as i64;
            let Some(truth) = ctx.host_at(f) else {
                continue;
            };
            let corrected = *p + miss * ((k + 1) as f64 / h as f64);
            model_err += corrected.distance(truth);
            pchip_err += fill.at(f).distance(truth);
            n += 1;
        }
        end2 += miss.length_squared();
        tests += 1;
    }
    if tests == 0 || n == 0 {
        return None;
    }
    Some(Test {
        model: model_err / n as f64,
        pchip: pchip_err / n as f64,
        end_rms: (end2 / tests as f64).sqrt(),
    })
}

/// The PCHIP fill of the real gap.
fn pchip(ctx: &Context<'_, '_>, a: i64, b: i64) -> Fill {
    pchip_between(ctx, a, b)
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
mod tests {
    use super::*;

    fn timeline(n: usize) -> Timeline {
        Timeline {
            times: (0..n).map(|i| i as f64 / 100.0).collect(),
            anchors: vec![(0, 0)],
        }
    }

    fn settings() -> GapSettings {
        GapSettings {
            max_fill_s: 3.0,
            max_pchip_s: 0.5,
            neighbours: true,
        }
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
    fn pchip_fills_smooth_motion_closely_and_flags_it() {
        // 30 mm sway at 0.8 Hz, 100 Hz, a 10-frame and a 30-frame gap; no
        // neighbours: PCHIP.
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
