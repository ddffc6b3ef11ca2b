//! Frame-by-frame tracking (paper §4, spec §2), with a motion model.
//!
//! Each live trace predicts where its marker will be with a
//! constant-acceleration Kalman filter ([`motion`](super::motion)), which
//! also says how sure the prediction is; the paper's forward difference
//! `p̂(M) = 2p(M−1) − p(M−2)` is the same predictor without either. A trace
//! may take a marker within `gate_sigma` standard deviations of its
//! prediction and within `gate_mm`. Which trace takes which marker is
//! decided for all of them at once ([`assign`]): the cheapest total of
//! squared normalised distances plus the log of each prediction's
//! covariance, so that where two traces could take one marker, the surer
//! one does, and plus a cost for a marker coming back to a trace that
//! missed it, so that a marker measured in the frame before stays with its
//! trace rather than go to a neighbour's trace coasting through a gap.
//! Candidates come from a grid of the frame's markers (for small frames,
//! a direct scan of all pairs, which is cheaper). A trace that misses its
//! marker ends once its prediction is too unsure to pick the right one
//! again (the gate would exceed `gate_mm`), or after `max_gap` frames; a
//! trace seen once ends at its first miss, so a storm of stray reflections
//! cannot pile up live traces. Markers nobody took start new traces.
//!
//! Pieces of one marker are put back together on line by the identity
//! layer ([`identity`](super::identity)), from the motion of the marker's
//! neighbours; its identities are the tips the daemon shows live and the
//! replay reports.
//!
//! The tracker keeps only the traces and a per-frame time line, so the live
//! daemon can feed it for hours.
//!
//! Bad input rules (each counted in [`TrackStats`], none panics):
//! - a marker with a NaN or infinite coordinate is skipped;
//! - markers of one frame closer than `duplicate_mm` are one marker seen
//!   twice: the first is kept, the copies dropped;
//! - an empty frame is a frame in which every trace misses its marker;
//! - a frame number that does not increase (a restarted source) ends every
//!   trace; tracking starts afresh, and the internal frame index jumps by
//!   more than `max_gap` so nothing is bridged or filled across the restart;
//! - a jump forward longer than `max_gap` ends every trace the same way and
//!   is shortened in the internal frame index (so a corrupt frame number
//!   cannot make the time line huge).

use glam::DVec3;
use serde::Serialize;

use super::assign::{Assigner, Edge};
use super::grid::Grid;
use super::identity::{Identities, IdentitySettings, NO_MARKER};
use super::jitter::{third_difference, Jitter};
use super::motion::{Motion, MotionParams};
use super::radix;
use crate::model::frame::MarkerFrame;
use crate::model::trace::{Timeline, Trace};
use crate::track::TrackingSettings;

/// Counters of what the tracker saw, for the summary and the daemon's metrics.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct TrackStats {
    /// Frames received.
    pub frames: u64,
    /// Frames without a single usable marker.
    pub empty_frames: u64,
    /// Marker positions accepted.
    pub markers: u64,
    /// Markers skipped for a NaN or infinite coordinate.
    pub nonfinite_markers: u64,
    /// Markers dropped as copies of another marker of the same frame.
    pub duplicate_markers: u64,
    /// Times the frame number did not increase (source restarted).
    pub restarts: u64,
    /// Forward jumps in frame numbers (dropped frames).
    pub jumps: u64,
    /// Frame numbers skipped over by those jumps.
    pub skipped_frames: u64,
    /// Traces started.
    pub traces_started: u64,
    /// Assignment problems too large to solve exactly (gate far too wide).
    pub greedy_components: u64,
    /// The smallest distance seen between two established traces'
    /// predictions (m), when closer than twice the gate.
    pub closest_spacing_m: Option<f64>,
    /// Traces joined on line to an earlier piece of the same marker.
    pub joined: u64,
}

/// What the tracker hands on when the session is over.
#[derive(Debug, Clone, Default)]
pub struct Tracked {
    /// Every trace, in order of appearance (`trace.id` = index).
    pub traces: Vec<Trace>,
    /// The markers found: for each, the ids of its traces in time order.
    /// Traces in none are ghosts and fragments never confirmed.
    pub identities: Vec<Vec<usize>>,
    /// Internal frame index → source frame number and time.
    pub timeline: Timeline,
    /// What the tracker counted, including the bad input it skipped.
    pub stats: TrackStats,
}

/// A trace still looking for markers.
#[derive(Debug, Clone, Copy)]
struct Live {
    trace: usize,
    motion: Motion,
    measured: u32,
    /// Prediction for the current frame and its variance per axis.
    prediction: DVec3,
    variance: f64,
    /// Its last three measurements, oldest first, and how many of the
    /// latest frames in a row measured it (up to 3): the noise estimate's
    /// input ([`Jitter`]).
    recent: [DVec3; 3],
    run: u8,
}

impl Live {
    /// Whether it missed its marker in the frame before `t`: coasting
    /// through a gap, so taking a marker in `t` is a join across it.
    fn coasting(&self, t: i64) -> bool {
        self.motion.t() < t - 1
    }
}

/// Up to this many trace × marker pairs per frame, candidates are found by
/// comparing every pair; beyond, from a grid of the frame's markers
/// (src/track/grid.rs). Building the grid costs more than the whole scan for a
/// typical tree capture of 24–70 markers (see benches/tracking.rs).
const DIRECT_SCAN_MAX: usize = 4096;

/// Live, the spacing warning is looked for in one frame of this many.
const SPACING_EVERY_LIVE: i64 = 16;

/// Added to the miss cost of a trace, and the most the terms of a contested
/// marker add to an edge ([`DIMENSIONS`], [`COAST_COST`]): they decide
/// between traces and never refuse a marker inside the gate.
const LOG_VARIANCE_ALLOWANCE: f64 = 12.0;

/// Dimensions of a measurement: the log of an isotropic covariance's
/// determinant is this many times the log of its variance per axis. A
/// prediction's likelihood is `exp(−m/2) / √det`, so the cost of an edge
/// is `m + 3 ln(s/r)`; with `ln(s/r)` alone a trace coasting through a gap
/// paid a third of what its unsure prediction is worth, and took a
/// neighbour's marker from the trace measuring it in every frame (`all`
/// seed 220: tip 21's marker, 8 mm from its hidden neighbour tip 69,
/// went to tip 69's trace after 8 frames of coasting, 12.5 against 13.2:
/// 116 wrong samples). Measured on the sweep: docs/tracking.md §4a.
const DIMENSIONS: f64 = 3.0;

/// Cost (squared normalised distance) of a marker coming back to a trace
/// that missed it in the frame before, against one measured again: a
/// marker hidden for 10–50 frames comes back in a given frame of its gap
/// with odds of a few in a hundred, where a marker seen in the frame
/// before is seen again in nearly every frame. 4 is `−2 ln` of odds of
/// about 1/7, the side of that ratio the sweep chose: 8 (1/55) lost more
/// than it won, 2 gave the same but for single seeds flipping either way
/// (docs/tracking.md §4a). It counts only where a marker is
/// contested: in a component where every trace takes a marker it adds
/// the same to every choice.
const COAST_COST: f64 = 4.0;

/// The online tracker; feed it frames in order with [`Tracker::push`].
pub struct Tracker {
    gate_m: f64,
    gate_sigma: f64,
    noise_m: f64,
    /// The noise measured on the traces: the filters take the larger of it
    /// and `noise_m` (a filter told too little breaks its traces).
    jitter: Jitter,
    params: MotionParams,
    params_set: bool,
    identities: Identities,
    cfg: TrackingSettings,
    /// Keep every trace's samples (a replay) or only the live state (the
    /// daemon, whose memory must not grow with the session).
    record: bool,
    /// Id of the next trace.
    next_trace: usize,
    max_gap: i64,
    duplicate_m: f64,
    traces: Vec<Trace>,
    live: Vec<Live>,
    timeline: Timeline,
    stats: TrackStats,
    last_frame: Option<i64>,
    last_t: i64,
    time_offset: f64,
    dt: f64,
    warned: bool,
    assigner: Assigner,
    // Per-frame scratch, kept to avoid allocating on every frame.
    points: Vec<[f64; 3]>,
    ids: Vec<Option<i64>>,
    /// Each point's index among the frame's markers (points drop the
    /// non-finite and duplicate ones).
    src: Vec<usize>,
    /// (trace, index among the frame's markers) of every trace measured in
    /// the latest frame, by trace: which marker each identity took.
    measured_at: Vec<(usize, usize)>,
    order: Vec<usize>,
    /// `clean_markers`' and `check_spacing`'s sort keys, reused: (x as
    /// ordered bits, index).
    by_x: Vec<(u64, usize)>,
    /// The radix sort's second buffer.
    radix_scratch: Vec<(u64, usize)>,
    keep: Vec<bool>,
    edges: Vec<Edge>,
    /// Per marker of the frame, how many edges reach it (saturating).
    col_edges: Vec<u8>,
    /// The frame's markers bucketed for the gate search (beyond
    /// `DIRECT_SCAN_MAX` pairs).
    grid: Grid,
    out: Vec<Option<usize>>,
    taken: Vec<bool>,
}

impl Tracker {
    /// `frame_rate` (if known) gives the frame interval until two frames
    /// have been seen.
    pub fn new(cfg: &TrackingSettings, frame_rate: Option<f64>) -> Self {
        let known = frame_rate.filter(|r| r.is_finite() && *r > 0.0);
        let dt = known.map_or(0.01, |r| 1.0 / r);
        let noise_m = cfg.noise_mm / 1000.0;
        let identity_settings = identity_settings(cfg, dt);
        Tracker {
            gate_m: cfg.gate_mm / 1000.0,
            gate_sigma: cfg.gate_sigma,
            noise_m,
            jitter: Jitter::default(),
            params: MotionParams::new(noise_m, dt),
            params_set: known.is_some(),
            identities: Identities::new(identity_settings),
            cfg: cfg.clone(),
            record: true,
            next_trace: 0,
            max_gap: i64::from(cfg.max_gap),
            duplicate_m: cfg.duplicate_mm / 1000.0,
            traces: Vec::new(),
            live: Vec::new(),
            timeline: Timeline::default(),
            stats: TrackStats::default(),
            last_frame: None,
            last_t: -1,
            time_offset: 0.0,
            dt,
            warned: false,
            assigner: Assigner::default(),
            points: Vec::new(),
            ids: Vec::new(),
            src: Vec::new(),
            measured_at: Vec::new(),
            order: Vec::new(),
            by_x: Vec::new(),
            radix_scratch: Vec::new(),
            keep: Vec::new(),
            edges: Vec::new(),
            col_edges: Vec::new(),
            grid: Grid::default(),
            out: Vec::new(),
            taken: Vec::new(),
        }
    }

    /// A tracker for the live daemon: the same tracking, but the traces'
    /// samples are not kept (`traces()` stays empty), so memory stays flat.
    pub fn live(cfg: &TrackingSettings, frame_rate: Option<f64>) -> Self {
        let mut t = Tracker::new(cfg, frame_rate);
        t.record = false;
        t
    }

    /// Counters so far.
    pub fn stats(&self) -> &TrackStats {
        &self.stats
    }

    /// All traces so far (live ones still growing).
    pub fn traces(&self) -> &[Trace] {
        &self.traces
    }

    /// The markers (identities) measured in the latest frame:
    /// `(identity, position)`, identities numbered from 0 in the order they
    /// were confirmed. This is what the daemon shows live.
    pub fn current(&self) -> impl Iterator<Item = (usize, DVec3)> + '_ {
        self.identities.current()
    }

    /// Like [`Tracker::current`], with the index among the latest frame's
    /// markers of the marker each identity took: the daemon shows which
    /// markers are tips without searching the frame for their positions.
    ///
    /// An identity measured through its trace names its marker itself (the
    /// identity layer notes it as the trace is measured); one joined or
    /// confirmed in this very frame is looked up by its trace among the
    /// frame's measured traces, as every identity was before.
    pub fn current_markers(&self) -> impl Iterator<Item = (usize, DVec3, usize)> + '_ {
        self.identities
            .current_marked()
            .filter_map(|(i, p, marker)| {
                let by_trace = || {
                    let trace = self.identities.trace_of(i)?;
                    let k = self
                        .measured_at
                        .binary_search_by_key(&trace, |m| m.0)
                        .ok()?;
                    Some((i, p, self.measured_at[k].1))
                };
                if marker == NO_MARKER {
                    return by_trace();
                }
                // An identity measured in this frame has its trace, and the
                // trace's marker is the one noted.
                debug_assert_eq!(by_trace(), Some((i, p, marker as usize)));
                Some((i, p, marker as usize))
            })
    }

    /// Mean and spread (m) of the first second of identity `i`: where it
    /// was when first seen, for matching identities with a tree's tips.
    pub fn first_position(&self, i: usize) -> Option<(DVec3, f64)> {
        self.identities.first_position(i)
    }

    /// Prefetches the state the next frame reads: the live traces, the
    /// identities, the per-frame buffers (`track::warm`). The daemon calls
    /// it just before a frame is due; it reads and changes nothing.
    pub fn warm(&self) {
        use super::warm::prefetch;
        prefetch(&self.live);
        self.identities.warm();
        prefetch(&self.measured_at);
        prefetch(&self.points);
        prefetch(&self.src);
        prefetch(&self.edges);
        prefetch(&self.out);
        prefetch(&self.taken);
        prefetch(&self.by_x);
        prefetch(&self.order);
        self.grid.warm();
    }

    /// Ends the session and hands over the traces.
    pub fn finish(mut self) -> Tracked {
        self.stats.greedy_components = self.assigner.greedy_components;
        let identities = self.identities.finish();
        self.stats.joined = self.identities.joins as u64;
        for t in self.traces.iter_mut() {
            t.seal();
        }
        Tracked {
            traces: self.traces,
            identities,
            timeline: self.timeline,
            stats: self.stats,
        }
    }

    /// Processes one frame.
    pub fn push(&mut self, frame: &MarkerFrame) {
        self.stats.frames += 1;
        let t = self.advance(frame);
        self.identities.begin(t);
        self.clean_markers(frame);
        if self.points.is_empty() {
            self.stats.empty_frames += 1;
        }
        self.stats.markers += self.points.len() as u64;

        self.end_lost_traces(t);
        // The spacing check sorts every trace each frame, a sixth of a live
        // frame's cost at 1 000 markers, for a warning given once. Live, a
        // sample of one frame in SPACING_EVERY_LIVE finds a pair that stays
        // close; a replay checks every frame so that its summary names the
        // closest pair exactly. The tips are the same either way.
        if !self.warned && (self.record || t % SPACING_EVERY_LIVE == 0) {
            self.check_spacing();
        }
        self.find_edges(t);
        self.check_reacquired(t);
        self.assigner.solve(
            self.live.len(),
            self.points.len(),
            &self.edges,
            self.gate_sigma * self.gate_sigma + LOG_VARIANCE_ALLOWANCE,
            &mut self.out,
        );

        self.taken.clear();
        self.taken.resize(self.points.len(), false);
        self.measured_at.clear();
        let mut noise_changed = false;
        for (row, col) in self.out.iter().enumerate() {
            let (Some(col), Some(l)) = (*col, self.live.get_mut(row)) else {
                continue;
            };
            let Some(p) = self.points.get(col).map(|p| DVec3::from_array(*p)) else {
                continue;
            };
            self.taken[col] = true;
            self.measured_at.push((l.trace, self.src[col]));
            noise_changed |= note_jitter(l, p, t, &mut self.jitter);
            l.motion.update(p, t, &self.params);
            l.measured += 1;
            if self.record {
                if let Some(trace) = self.traces.get_mut(l.trace) {
                    trace.push(t, p, self.ids.get(col).copied().flatten());
                }
            }
            self.identities.measured(l.trace, p, self.src[col]);
        }
        for (col, p) in self.points.iter().enumerate() {
            if self.taken[col] {
                continue;
            }
            let id = self.next_trace;
            self.next_trace += 1;
            self.measured_at.push((id, self.src[col]));
            let p = DVec3::from_array(*p);
            if self.record {
                self.traces
                    .push(Trace::new(id, t, p, self.ids.get(col).copied().flatten()));
            }
            self.stats.traces_started += 1;
            let motion = Motion::new(p, t, &self.params);
            self.live.push(Live {
                trace: id,
                motion,
                measured: 1,
                prediction: p,
                variance: 0.0,
                recent: [p; 3],
                run: 1,
            });
            self.identities.started(id, p);
        }
        // Rows keep the traces' order of birth (`retain` keeps order, new
        // traces have the next ids): sorted by trace, as the lookup needs.
        debug_assert!(self.measured_at.is_sorted());
        self.identities.end();
        if noise_changed {
            // Only a capture noisier than `noise_mm` changes the filters:
            // on a capture within it the tracking is that of `noise_mm`.
            self.params.r = self.noise_m.max(self.jitter.sigma()).powi(2);
        }
    }

    /// Predicts every live trace for frame `t` and ends those that cannot
    /// find their marker again: missed for more than `max_gap` frames, or
    /// whose gate would have to exceed `gate_mm`.
    fn end_lost_traces(&mut self, t: i64) {
        let max_gap = self.max_gap;
        let gate = self.gate_m / self.gate_sigma;
        let gate_sigma = self.gate_sigma;
        let params = self.params;
        let traces = &mut self.traces;
        let identities = &mut self.identities;
        self.live.retain_mut(|l| {
            let (p, s) = l.motion.predict(t, &params);
            l.prediction = p;
            l.variance = s;
            let missed = t - l.motion.t() - 1;
            let alive = missed <= 0
                || (missed <= max_gap
                    && s <= gate * gate
                    && identities.coast_agrees(l.trace, p, gate_sigma * s.sqrt()));
            if !alive {
                if let Some(tr) = traces.get_mut(l.trace) {
                    tr.seal();
                }
                identities.ended(l.trace);
            }
            alive
        });
    }

    /// Drops the pairs of a trace coasting through a gap with a marker its
    /// identity's neighbours put elsewhere (`Identities::reacquire_agrees`).
    fn check_reacquired(&mut self, t: i64) {
        let live = &self.live;
        if !live.iter().any(|l| l.coasting(t)) {
            return;
        }
        let (points, identities) = (&self.points, &self.identities);
        self.edges.retain(|e| {
            let l = &live[e.row];
            !l.coasting(t) || identities.reacquire_agrees(l.trace, DVec3::from_array(points[e.col]))
        });
    }

    /// Candidate pairs (trace, marker) inside each trace's gate in frame
    /// `t`, costed by the squared normalised distance plus the log of the
    /// covariance and the [`COAST_COST`].
    fn find_edges(&mut self, t: i64) {
        self.edges.clear();
        let r2 = self.gate_m * self.gate_m;
        let g2 = self.gate_sigma * self.gate_sigma;
        let r = self.params.r.max(1e-12);
        // Within a fifth of the gate a marker is always a candidate, however
        // sure the prediction: real markers jitter in ways no model expects.
        let floor2 = r2 / 25.0;
        // An edge's cost is its normalised distance plus its trace's log
        // variance, the latter added below, only where it can matter.
        let row_variance = |l: &Live| l.variance.max(r);
        let edge = |row: usize, col: usize, s: f64, d2: f64| -> Option<Edge> {
            let m = d2 / s;
            (d2 <= r2 && (m <= g2 || d2 <= floor2)).then(|| Edge {
                row,
                col,
                cost: m.min(g2),
            })
        };
        if self.points.len() * self.live.len() <= DIRECT_SCAN_MAX {
            // Few markers: comparing every pair is cheaper than building a tree.
            for (row, l) in self.live.iter().enumerate() {
                let s = row_variance(l);
                for (col, p) in self.points.iter().enumerate() {
                    let d2 = l.prediction.distance_squared(DVec3::from_array(*p));
                    if let Some(e) = edge(row, col, s, d2) {
                        self.edges.push(e);
                    }
                }
            }
        } else if !self.points.is_empty() && !self.live.is_empty() {
            self.grid.build(&self.points, self.gate_m);
            for (row, l) in self.live.iter().enumerate() {
                let q = l.prediction.to_array();
                let hits = self.grid.within(q, self.gate_m);
                if hits.is_empty() {
                    continue;
                }
                let s = row_variance(l);
                for &(d2, col) in hits {
                    if let Some(e) = edge(row, col as usize, s, d2) {
                        self.edges.push(e);
                    }
                }
            }
        }
        self.add_contest_terms(r, t);
    }

    /// Adds each trace's log covariance ([`DIMENSIONS`]) and, when it
    /// missed its marker in the frame before `t`, the [`COAST_COST`] to the
    /// cost of its edges, wherever the cost can decide anything: in
    /// components of the candidate graph with more than one edge. An edge
    /// alone (its trace has no other marker, its marker no other trace:
    /// nearly every edge) is taken whatever its cost, which is at most
    /// `g2 + LOG_VARIANCE_ALLOWANCE`, the miss cost, with the added terms
    /// or without. The log was taken for every trace, 1 000 a frame at
    /// 1 000 markers (a twentieth of the frame), where a few are needed.
    /// Edges come grouped by row.
    fn add_contest_terms(&mut self, r: f64, t: i64) {
        let edges = &mut self.edges;
        self.col_edges.clear();
        self.col_edges.resize(self.points.len(), 0);
        for e in edges.iter() {
            if let Some(n) = self.col_edges.get_mut(e.col) {
                *n = n.saturating_add(1);
            }
        }
        let mut start = 0;
        while start < edges.len() {
            let row = edges[start].row;
            let end = start + edges[start..].iter().take_while(|e| e.row == row).count();
            let shared = end - start > 1
                || edges[start..end]
                    .iter()
                    .any(|e| self.col_edges.get(e.col).is_some_and(|&n| n > 1));
            if let (true, Some(l)) = (shared, self.live.get(row)) {
                let s = l.variance.max(r);
                let coasting = if l.coasting(t) { COAST_COST } else { 0.0 };
                let added = (DIMENSIONS * (s / r).ln() + coasting).min(LOG_VARIANCE_ALLOWANCE);
                for e in &mut edges[start..end] {
                    e.cost += added;
                }
            }
            start = end;
        }
    }

    /// Maps the frame to the internal frame index and extends the time line.
    fn advance(&mut self, frame: &MarkerFrame) -> i64 {
        let Some(last_frame) = self.last_frame else {
            let time = if frame.time_s.is_finite() {
                frame.time_s
            } else {
                0.0
            };
            self.time_offset = 0.0;
            self.last_frame = Some(frame.frame);
            self.last_t = 0;
            self.timeline.times.push(time);
            self.timeline.anchors.push((0, frame.frame));
            return 0;
        };
        let last_time = self.timeline.times.last().copied().unwrap_or(0.0);
        let d = frame.frame.checked_sub(last_frame);
        let restart = d.is_none_or(|d| d <= 0);
        let long_jump = d.is_some_and(|d| d > self.max_gap + 1);
        let t;
        let mut time;
        if restart || long_jump {
            // Nothing is bridged across: all traces end, and the internal
            // index moves on by more than max_gap.
            for l in self.live.drain(..) {
                if let Some(tr) = self.traces.get_mut(l.trace) {
                    tr.seal();
                }
            }
            self.identities.restart();
            t = self.last_t + self.max_gap + 2;
            self.timeline.anchors.push((t, frame.frame));
            if restart {
                self.stats.restarts += 1;
                // The source's clock restarted too: continue our own.
                time = last_time + self.dt * (t - self.last_t) as f64;
                self.time_offset = time - frame.time_s;
            } else {
                self.stats.jumps += 1;
                self.stats.skipped_frames += d.map_or(0, |d| (d - 1) as u64);
                time = frame.time_s + self.time_offset;
            }
        } else {
            let d = d.unwrap_or(1);
            t = self.last_t + d;
            if d > 1 {
                self.stats.jumps += 1;
                self.stats.skipped_frames += (d - 1) as u64;
            }
            time = frame.time_s + self.time_offset;
        }
        let steps = (t - self.last_t) as f64;
        if !time.is_finite() || time <= last_time {
            time = last_time + self.dt * steps;
        } else if !restart && !long_jump {
            self.dt = (time - last_time) / steps;
            if !self.params_set && self.dt > 0.0 {
                // The rate was not known: the first frame interval sets the
                // filters' priors.
                self.params = MotionParams::new(self.noise_m.max(self.jitter.sigma()), self.dt);
                self.identities
                    .set_settings(identity_settings(&self.cfg, self.dt));
                self.params_set = true;
            }
        }
        for k in 1..(t - self.last_t) {
            let f = k as f64 / steps;
            self.timeline.times.push(last_time + (time - last_time) * f);
        }
        self.timeline.times.push(time);
        self.last_frame = Some(frame.frame);
        self.last_t = t;
        t
    }

    /// Copies the usable markers of `frame` into `points`/`ids`.
    fn clean_markers(&mut self, frame: &MarkerFrame) {
        self.points.clear();
        self.ids.clear();
        self.src.clear();
        for (k, m) in frame.markers.iter().enumerate() {
            if m.position.is_finite() {
                self.points.push(m.position.to_array());
                self.ids.push(m.id);
                self.src.push(k);
            } else {
                self.stats.nonfinite_markers += 1;
            }
        }
        if self.points.len() < 2 || self.duplicate_m <= 0.0 {
            return;
        }
        // Sweep along x: only markers within duplicate_m in x can be copies.
        // Sorted as (x as an ordered integer, index) pairs: the same order
        // as comparing x by `total_cmp` then the index, without a lookup
        // into the points for every comparison (a tenth of a live frame),
        // and by a radix sort (`radix`), not by comparisons.
        self.by_x.clear();
        self.by_x.extend(
            self.points
                .iter()
                .enumerate()
                .map(|(i, p)| (ordered_bits(p[0]), i)),
        );
        radix::sort_pairs(&mut self.by_x, &mut self.radix_scratch);
        self.order.clear();
        self.order.extend(self.by_x.iter().map(|&(_, i)| i));
        let pts = &self.points;
        self.keep.clear();
        self.keep.resize(pts.len(), true);
        let r2 = self.duplicate_m * self.duplicate_m;
        for (k, &i) in self.order.iter().enumerate() {
            if !self.keep[i] {
                continue;
            }
            for &j in &self.order[k + 1..] {
                if pts[j][0] - pts[i][0] > self.duplicate_m {
                    break;
                }
                let d = DVec3::from_array(pts[j]) - DVec3::from_array(pts[i]);
                if self.keep[j] && d.length_squared() <= r2 {
                    // Keep the one that came first in the frame.
                    let drop = i.max(j);
                    self.keep[drop] = false;
                    if drop == i {
                        break;
                    }
                }
            }
        }
        let dropped = self.keep.iter().filter(|k| !**k).count();
        if dropped > 0 {
            self.stats.duplicate_markers += dropped as u64;
            let mut n = 0;
            for i in 0..self.points.len() {
                if self.keep[i] {
                    self.points[n] = self.points[i];
                    self.ids[n] = self.ids[i];
                    self.src[n] = self.src[i];
                    n += 1;
                }
            }
            self.points.truncate(n);
            self.ids.truncate(n);
            self.src.truncate(n);
        }
    }

    /// Warns (once) when two established traces are predicted closer than
    /// twice the gate: their gates overlap and their paths could swap.
    fn check_spacing(&mut self) {
        // Sorted by x as ordered integer keys (`radix`), equal x by row.
        self.by_x.clear();
        self.by_x.extend(
            self.live
                .iter()
                .enumerate()
                .filter(|(_, l)| l.measured >= 10 && l.motion.t() == self.last_t - 1)
                .map(|(i, l)| (ordered_bits(l.prediction.x), i)),
        );
        radix::sort_pairs(&mut self.by_x, &mut self.radix_scratch);
        self.order.clear();
        self.order.extend(self.by_x.iter().map(|&(_, i)| i));
        let live = &self.live;
        let limit = 2.0 * self.gate_m;
        let mut closest = f64::INFINITY;
        let mut pair = (0, 0);
        for (k, &i) in self.order.iter().enumerate() {
            for &j in &self.order[k + 1..] {
                let (a, b) = (live[i].prediction, live[j].prediction);
                if b.x - a.x >= limit.min(closest) {
                    break;
                }
                let d = a.distance(b);
                if d < closest {
                    closest = d;
                    pair = (live[i].trace, live[j].trace);
                }
            }
        }
        if closest < limit {
            self.warned = true;
            self.stats.closest_spacing_m = Some(closest);
            tracing::warn!(
                "tracking gate {:.1} mm is more than half the distance between traces {} and {} \
                 ({:.1} mm) at {:.2} s: their paths may swap; lower tracking.gate_mm",
                self.gate_m * 1000.0,
                pair.0,
                pair.1,
                closest * 1000.0,
                self.timeline.times.last().copied().unwrap_or(0.0)
            );
        }
    }
}

/// `x`'s bits as an unsigned integer that sorts as `f64::total_cmp` does.
fn ordered_bits(x: f64) -> u64 {
    let b = x.to_bits();
    // Negative numbers: every bit flipped (larger magnitude sorts first);
    // positive: the sign bit set, above all negatives.
    if b >> 63 == 1 {
        !b
    } else {
        b | (1 << 63)
    }
}

/// Feeds the third difference of `l`'s last measurements and `p` (frame
/// `t`) to the noise estimate when they are four frames in a row; keeps the
/// last three. Returns whether the estimate changed.
fn note_jitter(l: &mut Live, p: DVec3, t: i64, jitter: &mut Jitter) -> bool {
    let consecutive = l.motion.t() == t - 1;
    let mut changed = false;
    if consecutive && l.run >= 3 {
        changed = jitter.observe(third_difference([l.recent[0], l.recent[1], l.recent[2], p]));
    }
    l.run = if consecutive { (l.run + 1).min(3) } else { 1 };
    l.recent = [l.recent[1], l.recent[2], p];
    changed
}

/// The identity layer's settings for a frame interval `dt` (s).
fn identity_settings(cfg: &TrackingSettings, dt: f64) -> IdentitySettings {
    let frames = |s: f64| (s / dt).round().max(1.0);
    IdentitySettings {
        link_frames: frames(cfg.link_s).max(3.0) as usize,
        confirm_frames: frames(cfg.confirm_s).max(6.0) as usize,
        link_min_m: cfg.link_min_mm / 1000.0,
        link_max_m: cfg.link_max_mm / 1000.0,
        keep_lost_frames: frames(cfg.keep_lost_s) as i64,
        alpha: 1.0 / frames(2.0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::frame::Marker;

    fn cfg() -> TrackingSettings {
        TrackingSettings::default()
    }

    /// The duplicate sweep's integer keys sort exactly as `total_cmp`.
    #[test]
    fn ordered_bits_sort_as_total_cmp() {
        let mut rng = crate::rng::Rng::new(3);
        let mut xs: Vec<f64> = (0..2000).map(|_| rng.range(-3.0, 3.0)).collect();
        xs.extend([0.0, -0.0, 1e-300, -1e-300, f64::MAX, f64::MIN, 2.5, 2.5]);
        for (i, a) in xs.iter().enumerate() {
            let b = xs[(i * 7 + 1) % xs.len()];
            assert_eq!(
                ordered_bits(*a).cmp(&ordered_bits(b)),
                a.total_cmp(&b),
                "{a} against {b}"
            );
        }
    }

    fn frame(n: i64, pts: &[DVec3]) -> MarkerFrame {
        MarkerFrame::new(
            n,
            n as f64 / 100.0,
            pts.iter().map(|p| Marker::new(*p)).collect(),
        )
    }

    #[test]
    fn each_identity_names_the_frame_marker_it_took() {
        // A non-finite marker and a duplicate come first in the frame, so
        // the tracker's own point numbers differ from the frame's.
        let mut tr = Tracker::live(&cfg(), Some(100.0));
        let a = DVec3::new(0.0, 1.0, 0.0);
        let b = DVec3::new(0.3, 1.0, 0.0);
        for n in 0..300 {
            let d = DVec3::X * 0.0002 * n as f64;
            let mut f = frame(n, &[DVec3::NAN, a + d, a + d, b - d]);
            // Source order alternates, so order carries no identity.
            if n % 2 == 1 {
                f.markers.swap(1, 3);
            }
            tr.push(&f);
            for (_, p, index) in tr.current_markers() {
                assert_eq!(f.markers[index].position, p, "frame {n}");
            }
            // Every identity measured in the frame has its marker.
            assert_eq!(tr.current_markers().count(), tr.current().count());
        }
        assert_eq!(tr.current().count(), 2, "both markers confirmed");
    }

    #[test]
    fn two_crossing_paths_keep_their_identity() {
        // Two markers 60 mm apart moving toward each other at 4 mm/frame,
        // passing at 20 mm apart in y: forward differencing follows each.
        let mut tr = Tracker::new(&cfg(), Some(100.0));
        for n in 0..40 {
            let x = -0.08 + 0.004 * n as f64;
            let a = DVec3::new(x, 0.0, 0.0);
            let b = DVec3::new(-x, 0.02, 0.0);
            // Source order alternates, so order carries no identity.
            let pts = if n % 2 == 0 { [a, b] } else { [b, a] };
            tr.push(&frame(n, &pts));
        }
        let done = tr.finish();
        assert_eq!(done.traces.len(), 2);
        for t in &done.traces {
            let xs: Vec<f64> = t.measurements().map(|(_, p)| p.x).collect();
            assert_eq!(xs.len(), 40);
            // Monotone x: no swap.
            let up = xs[1] > xs[0];
            assert!(xs.windows(2).all(|w| (w[1] > w[0]) == up));
        }
    }

    #[test]
    fn prediction_bridges_a_gap_and_a_frame_jump() {
        let mut tr = Tracker::new(&cfg(), Some(100.0));
        // 2 mm per frame, the frame number jumping twice by 5 (4 frames
        // lost each time): the prediction carries the trace across both.
        for n in (0..20).chain(24..34).chain(38..48) {
            tr.push(&frame(n, &[DVec3::new(0.002 * n as f64, 0.0, 0.0)]));
        }
        let done = tr.finish();
        assert_eq!(done.traces.len(), 1);
        assert_eq!(done.stats.jumps, 2);
        assert_eq!(done.stats.skipped_frames, 8);
        assert_eq!(done.traces[0].measured(), 40);
        assert_eq!(done.traces[0].len(), 48);
        assert_eq!(done.timeline.len(), 48);
        assert!((done.timeline.time(22) - 0.22).abs() < 1e-9);
    }

    #[test]
    fn trace_ends_after_max_gap_and_leftovers_start_traces() {
        let mut c = cfg();
        c.max_gap = 3;
        let mut tr = Tracker::new(&c, Some(100.0));
        let p = DVec3::new(0.1, 1.0, 0.0);
        for n in 0..5 {
            tr.push(&frame(n, &[p]));
        }
        for n in 5..10 {
            tr.push(&frame(n, &[]));
        }
        tr.push(&frame(10, &[p, p + DVec3::X]));
        let done = tr.finish();
        assert_eq!(done.stats.empty_frames, 5);
        assert_eq!(done.traces.len(), 3);
        assert_eq!(done.traces[0].last_frame(), 4);
        assert_eq!(done.traces[1].first_frame(), 10);
    }

    #[test]
    fn global_assignment_not_first_come() {
        // Trace A (listed first) is predicted 10 mm from marker m1 and
        // 12 mm from m2; trace B is 20 mm from m1 and out of gate of m2.
        // Greedy would give m1 to A and leave B out.
        let mut tr = Tracker::new(&cfg(), Some(100.0));
        let a = DVec3::new(0.0, 0.0, 0.0);
        let b = DVec3::new(0.03, 0.0, 0.0);
        tr.push(&frame(0, &[a, b]));
        let m1 = DVec3::new(0.010, 0.0, 0.0);
        let m2 = DVec3::new(-0.012, 0.0, 0.0);
        tr.push(&frame(1, &[m1, m2]));
        let done = tr.finish();
        assert_eq!(done.traces.len(), 2);
        assert_eq!(done.traces[0].last_position(), m2);
        assert_eq!(done.traces[1].last_position(), m1);
    }

    #[test]
    fn a_marker_seen_in_the_frame_before_stays_with_its_trace() {
        // Two markers swaying together 4 mm apart (two tips on one twig),
        // 1.5 mm of noise, 100 Hz. B is hidden for 8 frames; in the eighth
        // A's marker is measured 2.6 mm towards B's: 1.4 mm from where B's
        // trace, coasting, predicts it. It is A's: A was measured in every
        // frame before, and B's marker comes back only in the next frame.
        // With the log of the variance alone and no cost for coming back,
        // B's trace took it from 2.0 mm on; now A's trace keeps it up to
        // 3.2 mm, and each trace holds its own marker afterwards.
        let noisy = TrackingSettings {
            noise_mm: 1.5,
            ..cfg()
        };
        let mut tr = Tracker::new(&noisy, Some(100.0));
        let sway = |n: i64| DVec3::new(0.0, 0.01 * (n as f64 * 0.02).sin(), 0.0);
        let (a, b) = (DVec3::new(0.0, 1.0, 0.0), DVec3::new(0.004, 1.0, 0.0));
        let hidden = 300..308;
        let towards_b = DVec3::X * 0.0026;
        for n in 0..400 {
            let s = sway(n);
            let mut pts = vec![a + s];
            if n == hidden.end - 1 {
                pts[0] += towards_b;
            }
            if !hidden.contains(&n) {
                pts.push(b + s);
            }
            tr.push(&frame(n, &pts));
        }
        let done = tr.finish();
        let holder = |n: i64, p: DVec3| {
            done.traces
                .iter()
                .find(|t| {
                    t.measurements()
                        .any(|(f, q)| f == n && q.distance(p) < 1e-5)
                })
                .map(|t| t.id)
        };
        let last_before = hidden.start - 1;
        let owner_a = holder(last_before, a + sway(last_before));
        assert!(owner_a.is_some(), "A's marker is tracked before the gap");
        let seen = hidden.end - 1;
        assert_eq!(holder(seen, a + sway(seen) + towards_b), owner_a);
        assert_eq!(holder(399, a + sway(399)), owner_a);
        assert_ne!(holder(399, b + sway(399)), owner_a);
    }

    #[test]
    fn bad_input_is_skipped_and_counted() {
        let mut tr = Tracker::new(&cfg(), Some(100.0));
        let p = DVec3::new(0.2, 1.0, 0.3);
        let q = DVec3::new(0.5, 1.0, 0.3);
        tr.push(&frame(100, &[p, q]));
        tr.push(&frame(101, &[p, DVec3::new(f64::NAN, 0.0, 0.0), q]));
        tr.push(&frame(
            102,
            &[p, p + DVec3::splat(1e-5), q, DVec3::INFINITY],
        ));
        tr.push(&frame(103, &[]));
        // Restart: frame numbers go back; new traces begin.
        tr.push(&frame(0, &[p, q]));
        tr.push(&frame(1, &[p, q]));
        // Extreme frame numbers must not overflow.
        tr.push(&frame(i64::MAX, &[p]));
        tr.push(&frame(i64::MIN, &[p]));
        let done = tr.finish();
        let s = &done.stats;
        assert_eq!(s.nonfinite_markers, 2);
        assert_eq!(s.duplicate_markers, 1);
        assert_eq!(s.empty_frames, 1);
        assert_eq!(s.restarts, 2);
        assert_eq!(s.jumps, 1);
        assert_eq!(done.traces.len(), 2 + 2 + 1 + 1);
        assert_eq!(done.traces[0].measured(), 3);
        // Times keep increasing across the restart (the absurd frame
        // numbers at the end give absurd but ordered, finite times).
        let times = &done.timeline.times;
        assert!(times.windows(2).all(|w| w[1] >= w[0] && w[1].is_finite()));
        let restart = (4 + 121) as usize;
        assert!(times[..restart + 2].windows(2).all(|w| w[1] > w[0]));
        assert_eq!(done.timeline.source_frame(0), Some(100));
    }

    #[test]
    fn kd_tree_path_tracks_many_markers() {
        // 100 markers (10 000 pairs: the grid path), 80 mm apart, each
        // moving 3 mm per frame in its own direction, listed in rotating
        // order; every marker must stay one trace.
        let mut tr = Tracker::new(&cfg(), Some(100.0));
        let start = |i: usize| DVec3::new((i % 10) as f64, (i / 10) as f64, 0.0) * 0.08;
        let dir =
            |i: usize| DVec3::new((i as f64).cos(), (i as f64).sin(), 0.5).normalize() * 0.003;
        for n in 0..50 {
            let mut pts: Vec<DVec3> = (0..100).map(|i| start(i) + dir(i) * n as f64).collect();
            pts.rotate_left(n as usize % 100);
            tr.push(&frame(n, &pts));
        }
        let done = tr.finish();
        assert_eq!(done.traces.len(), 100);
        for t in &done.traces {
            assert_eq!(t.measured(), 50);
            let ms: Vec<DVec3> = t.measurements().map(|m| m.1).collect();
            let step = ms[1] - ms[0];
            assert!(ms.windows(2).all(|w| (w[1] - w[0] - step).length() < 1e-4));
        }
    }

    #[test]
    fn warns_once_when_gate_is_wide_for_the_spacing() {
        let mut tr = Tracker::new(&cfg(), Some(100.0));
        let a = DVec3::ZERO;
        let b = DVec3::new(0.03, 0.0, 0.0);
        for n in 0..20 {
            tr.push(&frame(n, &[a, b]));
        }
        let s = tr.stats().closest_spacing_m.unwrap();
        assert!((s - 0.03).abs() < 1e-9);
        let mut tr = Tracker::new(&cfg(), Some(100.0));
        for n in 0..20 {
            tr.push(&frame(n, &[a, b * 3.0]));
        }
        assert_eq!(tr.stats().closest_spacing_m, None);
    }
}
