//! Identities: which traces are pieces of one marker (ours; the paper
//! tracks frame to frame only, spec §4 joins pieces by rest position).
//!
//! The frame-to-frame tracker ends a trace as soon as its prediction is too
//! unsure to pick the right marker (a long occlusion in a strong wind).
//! Here, on line and frame by frame, such pieces are put back together:
//!
//! - Every marker of the tree moves with its neighbours (they hang on the
//!   same limb or fork). For each identity we keep its `NEIGHBOURS` nearest
//!   identities and, for each, how much their offset varies
//!   (`var_ij`, an exponential average): a neighbour that moves with it
//!   varies little.
//! - When an identity misses a frame, the positions of it and of its
//!   neighbours are noted. From then on its position is predicted from the
//!   neighbours' motion since: `p̂ = p₀ + Σ wⱼ (pⱼ − pⱼ₀)`, weights
//!   `1/var_ij` (a local linear model of the neighbours, after Federolf
//!   2013), which follows the sway of the tree through seconds of gap,
//!   where extrapolating the marker's own motion fails within a tenth.
//! - A new trace is only a *candidate*. After `link_frames` measurements
//!   (and again at 2×, 4×, … up to `confirm_frames`) its path is compared
//!   with the predicted paths of the identities whose traces ended before
//!   it began; the RMS distance, in units of the prediction's expected error,
//!   is the cost, and candidates and lost identities are paired by global
//!   assignment. So a piece is joined only when its motion over a tenth of
//!   a second and its neighbours agree.
//! - A candidate that nobody claims becomes a new identity once it has been
//!   measured in `confirm_frames` frames, unless it follows the predicted
//!   path of an identity whose trace still coasts (see `follows_coasting`). Ghost reflections live shorter
//!   (they are never confirmed, and a static ghost does not follow the
//!   predicted sway, so it is not joined); they stay loose traces and are
//!   dropped as noise.

use std::collections::{BTreeMap, VecDeque};

use glam::DVec3;
use kiddo::{ImmutableKdTree, SquaredEuclidean};

use super::assign::{Assigner, Edge};
use super::inline_vec::InlineVec;

/// Neighbours kept per identity.
const NEIGHBOURS: usize = 8;
/// Up to this many recent identities the neighbours are found by comparing
/// every pair (a tree capture: 24–70 tips); beyond, from a kd-tree, so that
/// the once-a-second refresh stays O(n log n): at 1 000 markers comparing
/// every pair took 13–26 ms in one frame, a stall of the live daemon.
const DIRECT_NEIGHBOURS_MAX: usize = 128;
/// Error of the neighbours' prediction per metre they moved since the gap
/// began (a tip swings further or less far than its neighbours).
const MOVED_ERROR: f64 = 0.3;
/// A candidate's match is ambiguous while another lost identity fits it,
/// or another candidate fits its identity, at a cost less than this above
/// its own (costs are negative log-likelihoods: within a factor e^0.5 ≈ 1.6).
const AMBIGUOUS: f64 = 1.0;
/// A coasting trace is checked against its neighbours' prediction only
/// while a neighbour's marker, measured in the last two frames, is within
/// this distance (m) of the trace's own prediction
/// ([`Identities::coast_agrees`]). 30 and 40 mm gave the same counts on the
/// stress sweep, 60 mm more wrong samples on `all`.
const COAST_NEAR_M: f64 = 0.04;
/// Variance a new neighbour pair starts with (m²): (50 mm)², unknown.
const VAR0: f64 = 0.05 * 0.05;

/// Settings of the identity layer, in frames and metres.
#[derive(Debug, Clone, Copy)]
pub(crate) struct IdentitySettings {
    /// Measurements of a new trace before it is first compared.
    pub(crate) link_frames: usize,
    /// Measurements after which an unclaimed trace is a marker of its own.
    pub(crate) confirm_frames: usize,
    /// Smallest and largest join radius (RMS distance to the predicted path).
    pub(crate) link_min_m: f64,
    pub(crate) link_max_m: f64,
    /// Frames a lost identity can still be joined.
    pub(crate) keep_lost_frames: i64,
    /// Weight of a new frame in the neighbour statistics (1 / frames).
    pub(crate) alpha: f64,
}

/// A neighbour of an identity and how much their offset varies.
///
/// 40 bytes (the identity as a `u32`): every frame reads and writes all
/// eight of every identity's, 320 KB at 1 000 markers.
#[derive(Debug, Clone, Copy, Default)]
struct Neighbour {
    mean: DVec3,
    var: f64,
    id: u32,
    seen: bool,
}

impl Neighbour {
    fn id(&self) -> usize {
        self.id as usize
    }
}

/// What an identity looked like when its current gap began.
#[derive(Debug, Clone)]
struct Gap {
    /// Last measured frame before the gap.
    from: i64,
    p0: DVec3,
    /// (neighbour, its position at `from`, weight).
    snap: Vec<(usize, DVec3, f64)>,
    /// Expected error of the prediction for a long gap (m).
    spread: f64,
    /// Predicted positions for the frames of the gap (the most recent).
    preds: VecDeque<(i64, DVec3)>,
    last_pred: DVec3,
    /// Largest predicted displacement since the gap began (m): the
    /// neighbours' model errs in proportion to how far they moved.
    moved: f64,
    /// The trace has ended: the identity waits for a candidate.
    ended: bool,
}

/// One marker's state as a frame sees it: where it was last measured, the
/// trace carrying it, its gap. 88 bytes: what a frame reads and writes of
/// every identity it measures lies in one or two cache lines. The rest of a
/// marker is kept in arrays of its own, by identity: its neighbours
/// (`Identities::neighbours`, walked by the statistics' update in order),
/// its pieces and its first position (`Identities::cold`, read only when a
/// piece is joined, at the end, and by the live tips' matching). Together
/// in one 536-byte record, every frame's measurements each missed the cache
/// on a record of their own once the daemon's other work had evicted it.
#[derive(Debug, Clone)]
struct Ident {
    /// The trace carrying it now, if any.
    trace: Option<usize>,
    last: (i64, DVec3),
    prev: (i64, DVec3),
    /// Boxed: few identities are in a gap, and inline it would double the
    /// stride of the array every frame walks.
    gap: Option<Box<Gap>>,
}

/// What a frame does not read of a marker.
#[derive(Debug, Clone)]
struct IdentCold {
    pieces: Vec<usize>,
    /// Mean and RMS spread of its first `confirm_frames` measurements: the
    /// live daemon matches identities to a tree's tips with it.
    first: (DVec3, f64),
}

/// A young trace waiting to be joined or confirmed.
#[derive(Debug, Clone)]
struct Candidate {
    samples: Vec<(i64, DVec3)>,
    next_eval: usize,
    /// The earlier pieces of a still marker never confirmed that this
    /// trace continues (see [`Chain`]).
    chain: Option<Chain>,
}

/// Pieces of a still marker that ended before any was confirmed: under
/// 1 mm of noise and 25 % occlusion a still marker's trace ends at every
/// gap of more than about 20 frames (its acceleration is too unsure to
/// coast), and some markers were never seen for `confirm_frames` in a row
/// during the whole still phase, so they were dropped as ghosts and had
/// no rest position (`all` on seeds 100–102: 7 of 210 tips missing, 4 with
/// a rest position 14–18 mm off, and their wind pieces joined to other
/// tips). A marker is something with a rest position: pieces measured at
/// one place, one after another, are one marker, and their measurements
/// together count towards its confirmation. A ghost reflection also sits
/// still, but where the next one appears is independent of where the last
/// one was (for the simulator, anywhere in the crown's box), and a ghost
/// lives at most a fraction of `confirm_frames`: it would take several
/// ghosts, each within `link_min` of the last, to be confirmed. A moving
/// marker's piece is not still and starts no chain.
#[derive(Debug, Clone)]
struct Chain {
    /// Its traces, oldest first.
    pieces: Vec<usize>,
    /// Measurements in them.
    samples: usize,
    /// Where it sits: the mean of its measurements.
    anchor: DVec3,
    /// Its last measured frame.
    last: i64,
}

/// Who a live trace belongs to.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Owner {
    Ident(usize),
    Candidate,
    /// The trace ended this frame: its entry is dropped at the end of the
    /// frame (see [`Owners`]).
    Gone,
}

/// `Identities::cur_marker` of an identity whose frame marker is not known
/// (it was joined or confirmed this frame, not measured through
/// [`Identities::measured`]): the tracker then looks it up by its trace.
pub(crate) const NO_MARKER: u32 = u32::MAX;

/// The owner of every live trace, by trace id: a vector sorted by trace.
///
/// It was a hash map, looked up once for every marker of every frame; its
/// probes landed anywhere in a 48 KB table, a cache miss each once the
/// daemon's other work had evicted it (a sixth of a live frame at 1 000
/// markers). The tracker hands its traces over in increasing id, frame after
/// frame (its live rows are in birth order, and new traces take the next
/// id), so a cursor walking this vector finds each owner in a step or two,
/// reading memory in order. Lookups out of that order fall back to a binary
/// search. An ended trace's entry is marked [`Owner::Gone`] and dropped at
/// the end of the frame, not removed from the middle one at a time.
#[derive(Debug, Default)]
struct Owners {
    /// `(trace, owner)`, increasing trace.
    entries: Vec<(usize, Owner)>,
    /// Where the previous lookup ended.
    cursor: usize,
    /// Entries marked `Gone` and not dropped yet.
    gone: usize,
}

impl Owners {
    /// The index of `trace`'s entry, if it has one (a `Gone` one included).
    fn find(&mut self, trace: usize) -> Option<usize> {
        let e = &self.entries;
        let mut k = self.cursor;
        // Forward from the previous lookup, a few steps at most (the
        // traces the tracker skips are those that missed the frame).
        if k < e.len() && e[k].0 <= trace {
            for _ in 0..8 {
                match e.get(k) {
                    Some(x) if x.0 < trace => k += 1,
                    Some(x) if x.0 == trace => {
                        self.cursor = k + 1;
                        return Some(k);
                    }
                    _ => break,
                }
            }
        }
        let found = e.binary_search_by_key(&trace, |x| x.0).ok()?;
        self.cursor = found + 1;
        Some(found)
    }

    /// `trace`'s owner, without moving the cursor.
    fn get(&self, trace: usize) -> Option<Owner> {
        let k = self.entries.binary_search_by_key(&trace, |x| x.0).ok()?;
        Some(self.entries[k].1).filter(|o| *o != Owner::Gone)
    }

    /// Sets `trace`'s owner; a trace new to the map is inserted in order
    /// (at the end, for a trace just started).
    fn insert(&mut self, trace: usize, owner: Owner) {
        if self.entries.last().is_none_or(|x| x.0 < trace) {
            self.entries.push((trace, owner));
            return;
        }
        match self.entries.binary_search_by_key(&trace, |x| x.0) {
            Ok(k) => {
                if self.entries[k].1 == Owner::Gone {
                    self.gone -= 1;
                }
                self.entries[k].1 = owner;
            }
            Err(k) => self.entries.insert(k, (trace, owner)),
        }
    }

    /// Takes `trace`'s owner out (its entry is marked, dropped by `compact`).
    fn remove(&mut self, trace: usize) -> Option<Owner> {
        let k = self.find(trace)?;
        let owner = std::mem::replace(&mut self.entries[k].1, Owner::Gone);
        if owner == Owner::Gone {
            return None;
        }
        self.gone += 1;
        Some(owner)
    }

    /// Drops the entries of ended traces; rewinds the cursor for the next
    /// frame.
    fn compact(&mut self) {
        if self.gone > 0 {
            self.entries.retain(|x| x.1 != Owner::Gone);
            self.gone = 0;
        }
        self.cursor = 0;
    }

    /// The traces owned, in increasing id.
    fn traces(&self) -> impl Iterator<Item = usize> + '_ {
        self.entries
            .iter()
            .filter(|x| x.1 != Owner::Gone)
            .map(|x| x.0)
    }
}

/// The identity layer; the tracker feeds it every frame.
#[derive(Debug)]
pub(crate) struct Identities {
    s: IdentitySettings,
    idents: Vec<Ident>,
    /// Per identity, its neighbours. Inline (see `InlineVec`), in an array
    /// apart from `idents`: the frame walks them all, in order.
    neighbours: Vec<InlineVec<Neighbour, NEIGHBOURS>>,
    /// Per identity, its pieces and first position.
    cold: Vec<IdentCold>,
    owner: Owners,
    /// By trace id (ordered, so that ties are broken the same every run).
    candidates: BTreeMap<usize, Candidate>,
    /// Candidates whose trace ended this frame, before they were judged.
    dying: Vec<(usize, Candidate)>,
    /// Identities whose trace ended, joinable for `keep_lost_frames`.
    lost: Vec<usize>,
    /// Still pieces never confirmed, waiting for their next piece (for
    /// `keep_lost_frames`).
    dormant: Vec<Chain>,
    /// Position of each identity measured in the current frame.
    cur: Vec<Option<DVec3>>,
    /// Per identity measured in the current frame, the index among the
    /// frame's markers of the marker it took ([`NO_MARKER`] if not known):
    /// the live tips read it here instead of finding the identity's trace
    /// and searching the tracker's list for it (two scattered reads per tip).
    cur_marker: Vec<u32>,
    /// Identities with a trace or a joinable gap: the only ones a frame
    /// looks at, so the cost does not grow with the session.
    active: Vec<usize>,
    frame: i64,
    next_refresh: i64,
    assigner: Assigner,
    edges: Vec<Edge>,
    out: Vec<Option<usize>>,
    /// Pieces joined to an earlier piece.
    pub(crate) joins: usize,
}

impl Identities {
    pub(crate) fn new(s: IdentitySettings) -> Self {
        Identities {
            s,
            idents: Vec::new(),
            neighbours: Vec::new(),
            cold: Vec::new(),
            owner: Owners::default(),
            candidates: BTreeMap::new(),
            dying: Vec::new(),
            lost: Vec::new(),
            dormant: Vec::new(),
            cur: Vec::new(),
            cur_marker: Vec::new(),
            active: Vec::new(),
            frame: 0,
            next_refresh: 0,
            assigner: Assigner::default(),
            edges: Vec::new(),
            out: Vec::new(),
            joins: 0,
        }
    }

    /// New settings (the frame rate became known).
    pub(crate) fn set_settings(&mut self, s: IdentitySettings) {
        self.s = s;
    }

    /// Starts frame `t`.
    pub(crate) fn begin(&mut self, t: i64) {
        self.frame = t;
        for &i in &self.active {
            self.cur[i] = None;
        }
    }

    /// A new trace began with `p` in this frame.
    pub(crate) fn started(&mut self, trace: usize, p: DVec3) {
        self.owner.insert(trace, Owner::Candidate);
        self.candidates.insert(
            trace,
            Candidate {
                samples: vec![(self.frame, p)],
                next_eval: self.s.link_frames.max(1),
                chain: None,
            },
        );
    }

    /// Trace `trace` was measured at `p` in this frame, the frame's marker
    /// `marker`.
    pub(crate) fn measured(&mut self, trace: usize, p: DVec3, marker: usize) {
        let owner = self.owner.find(trace).map(|k| self.owner.entries[k].1);
        match owner {
            Some(Owner::Ident(i)) => {
                self.cur[i] = Some(p);
                self.cur_marker[i] = u32::try_from(marker).unwrap_or(NO_MARKER);
                let id = &mut self.idents[i];
                id.prev = id.last;
                id.last = (self.frame, p);
                id.gap = None;
            }
            Some(Owner::Candidate) => {
                if let Some(c) = self.candidates.get_mut(&trace) {
                    c.samples.push((self.frame, p));
                }
            }
            Some(Owner::Gone) | None => {}
        }
    }

    /// Whether trace `trace`, coasting through a gap, may go on with its
    /// own prediction `p`: false once where the neighbours put its identity
    /// is outside the trace's `gate` (m) around `p` while a neighbour's
    /// marker is within `COAST_NEAR_M` of `p`. A coasting trace extrapolates
    /// the marker's last motion; when the marker swung back or towards a
    /// neighbour while hidden, that extrapolation runs into the neighbour's
    /// marker and takes it (a swap that lasts: what broke `close`). Ended
    /// instead, the identity is lost and its marker is joined again by the
    /// neighbours' prediction.
    pub(crate) fn coast_agrees(&self, trace: usize, p: DVec3, gate: f64) -> bool {
        let Some(Owner::Ident(i)) = self.owner.get(trace) else {
            return true;
        };
        let id = &self.idents[i];
        let Some(g) = id.gap.as_ref() else {
            return true;
        };
        // Only where the coasting prediction could take another marker:
        // away from every neighbour's marker a wrong extrapolation finds
        // nothing and the trace ends on its own gate, while in a gust the
        // marker's own motion can predict it better than its neighbours'
        // (checked everywhere, gusts and `all` lost more identities than
        // they kept: docs/tracking.md §4a).
        let near = self.neighbours[i].iter().any(|n| {
            self.idents
                .get(n.id())
                .is_some_and(|j| j.last.0 >= self.frame - 2 && j.last.1.distance(p) <= COAST_NEAR_M)
        });
        !near || g.preds.is_empty() || p.distance(g.last_pred) <= gate.max(self.s.link_min_m)
    }

    /// Whether trace `trace`, coasting through a gap, may take the marker at
    /// `p`: its identity's neighbours must agree, `p` within the join
    /// radius of where their motion since the gap began puts it (the radius
    /// a new piece would be joined within: `path_cost`). Taking a marker
    /// after a gap is a join across that gap, decided on the trace's own
    /// extrapolation alone: a tip hidden as its neighbour reappears 20 mm
    /// from that extrapolation (a gust, `all`) took the neighbour's marker
    /// and kept it for 158 samples, and the replay's second pass cuts only
    /// at gaps over 0.1 s. Refused, the trace coasts on or ends, and its
    /// marker is joined again by the neighbours' prediction. True when the
    /// trace is not in a gap of an identity or nothing predicts it.
    pub(crate) fn reacquire_agrees(&self, trace: usize, p: DVec3) -> bool {
        let Some(Owner::Ident(i)) = self.owner.get(trace) else {
            return true;
        };
        let Some(g) = self.idents[i].gap.as_ref() else {
            return true;
        };
        if g.preds.is_empty() || g.snap.is_empty() {
            return true;
        }
        p.distance(g.last_pred) <= join_radius(g, &self.s)
    }

    /// Trace `trace` ended (too long without a marker, or a restart).
    pub(crate) fn ended(&mut self, trace: usize) {
        match self.owner.remove(trace) {
            Some(Owner::Ident(i)) => {
                if self.idents[i].gap.is_none() {
                    self.open_gap(i);
                }
                let id = &mut self.idents[i];
                id.trace = None;
                if let Some(g) = id.gap.as_mut() {
                    g.ended = true;
                    self.lost.push(i);
                }
            }
            Some(Owner::Candidate) => {
                // A short piece between two occlusions: judged at the end
                // of the frame, so its samples are not lost.
                if let Some(c) = self.candidates.remove(&trace) {
                    if c.samples.len() >= 3 {
                        self.dying.push((trace, c));
                    } else if let Some(chain) = c.chain {
                        self.dormant.push(chain);
                    }
                }
            }
            Some(Owner::Gone) | None => {}
        }
    }

    /// Ends every trace and forgets the lost identities (a source restart:
    /// nothing may be joined across it).
    pub(crate) fn restart(&mut self) {
        let traces: Vec<usize> = self.owner.traces().collect();
        for t in traces {
            self.ended(t);
        }
        for &i in &self.lost {
            self.idents[i].gap = None;
        }
        self.lost.clear();
        self.dormant.clear();
        self.candidates.clear();
    }

    /// Finishes the frame: gaps, predictions, statistics, joins.
    pub(crate) fn end(&mut self) {
        let t = self.frame;
        self.note_gaps();
        self.predict(t);
        self.learn();
        self.judge_dying();
        self.evaluate(false);
        if t >= self.next_refresh {
            self.refresh_neighbours(t);
            self.next_refresh = t + (1.0 / self.s.alpha / 2.0).max(8.0) as i64;
        }
        let keep = self.s.keep_lost_frames;
        let idents = &mut self.idents;
        self.lost.retain(|&i| {
            let alive = idents[i].gap.as_ref().is_some_and(|g| t - g.from <= keep);
            if !alive {
                idents[i].gap = None;
            }
            alive
        });
        self.dormant.retain(|c| t - c.last <= keep);
        self.active
            .retain(|&i| idents[i].trace.is_some() || idents[i].gap.is_some());
        self.owner.compact();
    }

    /// At the end of the session: pending candidates get a last chance to
    /// be joined; returns the pieces of every identity.
    pub(crate) fn finish(&mut self) -> Vec<Vec<usize>> {
        self.evaluate(true);
        self.cold.iter().map(|c| c.pieces.clone()).collect()
    }

    /// Prefetches what a frame reads of the active identities
    /// (`track::warm`; reads and changes nothing).
    pub(crate) fn warm(&self) {
        use super::warm::{prefetch, prefetch_one};
        prefetch(&self.active);
        prefetch(&self.cur);
        prefetch(&self.owner.entries);
        prefetch(&self.cur_marker);
        for &i in &self.active {
            let Some(id) = self.idents.get(i) else {
                continue;
            };
            prefetch_one(id);
            if let Some(n) = self.neighbours.get(i) {
                prefetch_one(n);
            }
            if let Some(g) = &id.gap {
                prefetch(&g.snap);
            }
        }
    }

    /// Mean and spread of identity `i`'s first measurements.
    pub(crate) fn first_position(&self, i: usize) -> Option<(DVec3, f64)> {
        self.cold.get(i).map(|c| c.first)
    }

    /// The identities measured in this frame, where, and the index of the
    /// frame's marker they took ([`NO_MARKER`] when not known: see
    /// `cur_marker`).
    pub(crate) fn current_marked(&self) -> impl Iterator<Item = (usize, DVec3, u32)> + '_ {
        self.current().map(|(i, p)| (i, p, self.cur_marker[i]))
    }

    /// The trace carrying identity `i` now, if any.
    pub(crate) fn trace_of(&self, i: usize) -> Option<usize> {
        self.idents.get(i).and_then(|id| id.trace)
    }

    /// Identities measured in this frame, with their position.
    pub(crate) fn current(&self) -> impl Iterator<Item = (usize, DVec3)> + '_ {
        self.cur
            .iter()
            .enumerate()
            .filter_map(|(i, p)| p.map(|p| (i, p)))
    }

    /// Identities that missed this frame start a gap.
    fn note_gaps(&mut self) {
        for k in 0..self.active.len() {
            let i = self.active[k];
            let id = &self.idents[i];
            if self.cur[i].is_none() && id.gap.is_none() && id.trace.is_some() {
                self.open_gap(i);
            }
        }
    }

    /// Notes where identity `i` and its neighbours were at its last
    /// measurement: the origin of its predicted path.
    fn open_gap(&mut self, i: usize) {
        let id = &self.idents[i];
        let from = id.last.0;
        let mut snap = Vec::new();
        let mut wsum = 0.0;
        for n in self.neighbours[i].iter().filter(|n| n.seen) {
            let Some(j) = self.idents.get(n.id()) else {
                continue;
            };
            let pj = if j.last.0 == from {
                j.last.1
            } else if j.prev.0 == from {
                j.prev.1
            } else {
                continue;
            };
            let w = 1.0 / n.var.max(1e-8);
            wsum += w;
            snap.push((n.id(), pj, w));
        }
        let spread = if wsum > 0.0 {
            (2.0 / wsum).sqrt()
        } else {
            self.s.link_max_m
        };
        let p0 = id.last.1;
        self.idents[i].gap = Some(Box::new(Gap {
            from,
            p0,
            snap,
            spread,
            preds: VecDeque::new(),
            last_pred: p0,
            moved: 0.0,
            ended: false,
        }));
    }

    /// Predicts every identity in a gap from its neighbours' motion.
    fn predict(&mut self, t: i64) {
        let cap = self.s.confirm_frames + 2;
        for &i in &self.active {
            let Some(g) = self.idents[i].gap.as_ref() else {
                continue;
            };
            let (mut num, mut wsum) = (DVec3::ZERO, 0.0);
            for &(j, pj0, w) in &g.snap {
                if let Some(pj) = self.cur.get(j).copied().flatten() {
                    num += (pj - pj0) * w;
                    wsum += w;
                }
            }
            let pred = if wsum > 0.0 {
                g.p0 + num / wsum
            } else {
                g.last_pred
            };
            if let Some(g) = self.idents[i].gap.as_mut() {
                g.last_pred = pred;
                g.moved = g.moved.max(pred.distance(g.p0));
                g.preds.push_back((t, pred));
                if g.preds.len() > cap {
                    g.preds.pop_front();
                }
            }
        }
    }

    /// Updates the offset statistics of every pair measured in this frame.
    fn learn(&mut self) {
        let a = self.s.alpha;
        for &i in &self.active {
            let Some(pi) = self.cur[i] else { continue };
            let cur = &self.cur;
            for n in self.neighbours[i].iter_mut() {
                let Some(pj) = cur.get(n.id()).copied().flatten() else {
                    continue;
                };
                let o = pi - pj;
                if !n.seen {
                    n.mean = o;
                    n.seen = true;
                }
                let d = o - n.mean;
                n.mean += d * a;
                n.var = (1.0 - a) * (n.var + a * d.length_squared());
            }
        }
    }

    /// Each identity's nearest identities, keeping the statistics of the
    /// neighbours it already had.
    fn refresh_neighbours(&mut self, t: i64) {
        let horizon = (1.0 / self.s.alpha) as i64;
        let recent: Vec<(usize, DVec3)> = self
            .active
            .iter()
            .map(|&i| (i, &self.idents[i]))
            .filter(|(_, id)| t - id.last.0 <= horizon)
            .map(|(i, id)| (i, id.last.1))
            .collect();
        let finder = NearestFinder::new(&recent);
        let mut near = Vec::with_capacity(NEIGHBOURS + 1);
        for (k, &(i, _)) in recent.iter().enumerate() {
            if self.idents[i].gap.is_some() {
                continue;
            }
            finder.nearest(&recent, k, &mut near);
            if near.is_empty() {
                continue;
            }
            let old = std::mem::take(&mut self.neighbours[i]);
            // An identity past u32::MAX (four billion markers confirmed)
            // could not be a neighbour; none will ever be.
            self.neighbours[i] = near
                .iter()
                .filter_map(|&(_, j)| {
                    let id = u32::try_from(j).ok()?;
                    Some(
                        old.iter()
                            .find(|n| n.id == id)
                            .copied()
                            .unwrap_or(Neighbour {
                                id,
                                mean: DVec3::ZERO,
                                var: VAR0,
                                seen: false,
                            }),
                    )
                })
                .collect();
        }
    }

    /// Compares candidates due for it with the lost identities, joins the
    /// best pairs, and confirms candidates nobody claims. `all`: every
    /// candidate is due (end of session).
    ///
    /// Every candidate already watched for `link_frames` takes part in the
    /// assignment, due or not: two markers hidden together (a close pair)
    /// come back as two candidates a few frames apart, and the first must
    /// not take the other's identity only because it was judged alone. A
    /// due candidate whose match is ambiguous (another lost identity, or
    /// another candidate, fits nearly as well: see `AMBIGUOUS`) waits for
    /// more samples, until `confirm_frames`.
    fn evaluate(&mut self, all: bool) {
        let confirm_frames = self.s.confirm_frames;
        let link = self.s.link_frames.max(3);
        let mut any_due = false;
        let pool: Vec<(usize, bool)> = self
            .candidates
            .iter()
            .filter(|(_, c)| {
                c.samples.len() >= link.min(c.next_eval) || (all && c.samples.len() >= 3)
            })
            .map(|(t, c)| {
                let due = all || c.samples.len() >= c.next_eval;
                any_due |= due;
                (*t, due)
            })
            .collect();
        if !any_due {
            return;
        }
        self.pool_edges(&pool);
        let miss = join_miss(&self.s);
        self.assigner.solve(
            pool.len(),
            self.lost.len(),
            &self.edges,
            miss,
            &mut self.out,
        );
        let mut joined_ids = Vec::new();
        for (row, &(trace, due)) in pool.iter().enumerate() {
            if !due {
                continue;
            }
            let claimed = self.out.get(row).copied().flatten();
            let Some(cand) = self.candidates.get_mut(&trace) else {
                continue;
            };
            let mut last_chance = all || cand.samples.len() >= confirm_frames;
            if claimed.is_none() {
                if cand.chain.is_none() {
                    cand.chain = take_chain(&mut self.dormant, &cand.samples, self.s.link_min_m);
                }
                // A still marker's pieces count together (see `Chain`).
                if let Some(c) = &cand.chain {
                    last_chance |= c.samples + cand.samples.len() >= confirm_frames;
                }
            }
            let seen = cand.samples.len() + cand.chain.as_ref().map_or(0, |c| c.samples);
            match claimed {
                // An ambiguous candidate is neither joined nor confirmed: it
                // waits (and stays out of every tip) until one path wins or
                // the rival identity is no longer joinable.
                Some(col) if ambiguous(&self.edges, row, col) && !all => {
                    cand.next_eval = (cand.next_eval * 2).min(confirm_frames);
                }
                Some(col) => {
                    let i = self.lost[col];
                    joined_ids.push(i);
                    let Some(cand) = self.candidates.remove(&trace) else {
                        continue;
                    };
                    self.join(trace, cand, i);
                }
                None if last_chance
                    && seen >= confirm_frames / 2
                    && (all || !follows_coasting(&self.idents, &self.active, cand, &self.s)) =>
                {
                    let Some(cand) = self.candidates.remove(&trace) else {
                        continue;
                    };
                    self.confirm(trace, cand);
                }
                _ => cand.next_eval = (cand.next_eval * 2).min(confirm_frames),
            }
        }
        self.lost.retain(|i| !joined_ids.contains(i));
    }

    /// The edges (candidate row, lost identity column, path cost) of the
    /// candidates in `pool`.
    fn pool_edges(&mut self, pool: &[(usize, bool)]) {
        self.edges.clear();
        if self.lost.is_empty() {
            return;
        }
        let confirm_frames = self.s.confirm_frames;
        for (row, (trace, _)) in pool.iter().enumerate() {
            let Some(cand) = self.candidates.get(trace) else {
                continue;
            };
            let born = cand.samples[0].0;
            let recent = recent(&cand.samples, confirm_frames);
            for (col, &i) in self.lost.iter().enumerate() {
                let Some(g) = self.idents[i].gap.as_ref() else {
                    continue;
                };
                if g.from >= born {
                    continue;
                }
                if let Some(cost) = path_cost(recent, g, &self.s) {
                    self.edges.push(Edge { row, col, cost });
                }
            }
        }
    }

    /// Short pieces that ended go to the lost identity whose predicted path
    /// they follow best (within its radius); the identity stays lost.
    fn judge_dying(&mut self) {
        for (trace, cand) in std::mem::take(&mut self.dying) {
            let born = cand.samples[0].0;
            let best = self
                .lost
                .iter()
                .filter_map(|&i| {
                    let g = self.idents[i].gap.as_ref()?;
                    if g.from >= born {
                        return None;
                    }
                    path_cost(&cand.samples, g, &self.s).map(|c| (c, i))
                })
                .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            if let Some((_, i)) = best {
                self.cold[i].pieces.push(trace);
                let id = &mut self.idents[i];
                if let Some(&last) = cand.samples.last() {
                    id.prev = id.last;
                    id.last = last;
                }
                self.joins += 1;
            } else if let Some(chain) = extend_chain(trace, cand, &self.s) {
                self.dormant.push(chain);
            }
        }
    }

    /// Candidate `trace` is the next piece of identity `i`.
    fn join(&mut self, trace: usize, cand: Candidate, i: usize) {
        let last = *cand.samples.last().unwrap_or(&(self.frame, DVec3::ZERO));
        self.cold[i].pieces.push(trace);
        let id = &mut self.idents[i];
        id.trace = Some(trace);
        id.prev = id.last;
        id.last = last;
        id.gap = None;
        if last.0 == self.frame {
            self.cur[i] = Some(last.1);
            self.cur_marker[i] = NO_MARKER;
        }
        self.owner.insert(trace, Owner::Ident(i));
        self.joins += 1;
    }

    /// Candidate `trace` is a marker of its own, with the earlier pieces of
    /// its chain if it continues one.
    fn confirm(&mut self, trace: usize, cand: Candidate) {
        let i = self.idents.len();
        let n = cand.samples.len().max(1) as f64;
        let mean = cand.samples.iter().map(|s| s.1).sum::<DVec3>() / n;
        let spread = (cand
            .samples
            .iter()
            .map(|s| s.1.distance_squared(mean))
            .sum::<f64>()
            / n)
            .sqrt();
        let last = *cand.samples.last().unwrap_or(&(self.frame, mean));
        let prev = cand.samples.iter().rev().nth(1).copied().unwrap_or(last);
        let mut pieces = cand.chain.map_or_else(Vec::new, |c| c.pieces);
        pieces.push(trace);
        self.idents.push(Ident {
            trace: Some(trace),
            last,
            prev,
            gap: None,
        });
        self.neighbours.push(InlineVec::new());
        self.cold.push(IdentCold {
            pieces,
            first: (mean, spread),
        });
        self.cur.push((last.0 == self.frame).then_some(last.1));
        self.cur_marker.push(NO_MARKER);
        self.active.push(i);
        self.owner.insert(trace, Owner::Ident(i));
        // Neighbours at once, so that a marker hidden soon after it was
        // confirmed can already be predicted.
        self.next_refresh = self.frame;
    }
}

/// Whether row `row`'s match `col` has a rival: another column fitting the
/// row, or another row fitting the column, within `AMBIGUOUS` of its cost.
fn ambiguous(edges: &[Edge], row: usize, col: usize) -> bool {
    let Some(own) = edges
        .iter()
        .find(|e| e.row == row && e.col == col)
        .map(|e| e.cost)
    else {
        return false;
    };
    edges
        .iter()
        .any(|e| (e.row == row) != (e.col == col) && e.cost < own + AMBIGUOUS)
}

/// The dormant chain whose anchor `samples` (a new candidate) sit at: RMS
/// distance within `radius`, the nearest; removed from `dormant`.
fn take_chain(dormant: &mut Vec<Chain>, samples: &[(i64, DVec3)], radius: f64) -> Option<Chain> {
    let born = samples.first()?.0;
    let n = samples.len() as f64;
    let (k, _) = dormant
        .iter()
        .enumerate()
        .filter(|(_, c)| c.last < born)
        .map(|(k, c)| {
            let ss: f64 = samples.iter().map(|s| s.1.distance_squared(c.anchor)).sum();
            (k, (ss / n).sqrt())
        })
        .filter(|&(_, rms)| rms <= radius)
        .min_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)))?;
    Some(dormant.swap_remove(k))
}

/// The chain `cand` (a candidate that ended unclaimed) leaves: its own
/// chain with it appended, or a new one; `None` when it moved (RMS spread
/// about its mean beyond `link_min`: a moving marker's pieces are joined
/// by its neighbours' motion, not here) or was measured in fewer than
/// `link_frames` frames, in which case a chain it continued stays as it
/// was. Short pieces are left to the later steps: a marker seen as two
/// blobs flips between two traces a few millimetres apart every few frames
/// (the Motive fixture `cmuphyscomp_sample_take_v1.21.csv`), and its
/// flipping pieces, chained, became a marker of their own instead of being
/// adopted by the marker they hand over to (`adopt`).
fn extend_chain(trace: usize, cand: Candidate, s: &IdentitySettings) -> Option<Chain> {
    let radius = s.link_min_m;
    let n = cand.samples.len();
    if n < s.link_frames.max(3) {
        return cand.chain;
    }
    let last = cand.samples.last()?.0;
    let mean = cand.samples.iter().map(|s| s.1).sum::<DVec3>() / n as f64;
    let spread = (cand
        .samples
        .iter()
        .map(|s| s.1.distance_squared(mean))
        .sum::<f64>()
        / n as f64)
        .sqrt();
    if spread > radius {
        return cand.chain;
    }
    Some(match cand.chain {
        Some(mut c) => {
            let total = (c.samples + n) as f64;
            c.anchor = (c.anchor * c.samples as f64 + mean * n as f64) / total;
            c.samples += n;
            c.pieces.push(trace);
            c.last = last;
            c
        }
        None => Chain {
            pieces: vec![trace],
            samples: n,
            anchor: mean,
            last,
        },
    })
}

/// The latest `n` samples of a candidate: the stretch the predicted paths
/// of the lost identities still cover (they keep `confirm_frames + 2`
/// predictions), also for a candidate whose confirmation was put off.
fn recent(samples: &[(i64, DVec3)], n: usize) -> &[(i64, DVec3)] {
    &samples[samples.len().saturating_sub(n.max(1))..]
}

/// Whether a candidate follows the predicted path of an identity whose
/// trace is still coasting through a gap that began before the candidate
/// did. Such a trace ends only when its own prediction grows too unsure or
/// after `max_gap` frames, which for a marker that was still when it was
/// hidden can be longer than `confirm_frames`: confirming the candidate
/// then would make one marker two identities, the second without a rest
/// position. Its confirmation waits until the coasting trace has ended (the
/// identity is then lost and the candidate is joined to it) or found its
/// marker again.
fn follows_coasting(
    idents: &[Ident],
    active: &[usize],
    cand: &Candidate,
    s: &IdentitySettings,
) -> bool {
    let born = cand.samples[0].0;
    let samples = recent(&cand.samples, s.confirm_frames);
    active.iter().any(|&i| {
        let id = &idents[i];
        id.trace.is_some()
            && id
                .gap
                .as_ref()
                .is_some_and(|g| !g.ended && g.from < born && path_cost(samples, g, s).is_some())
    })
}

/// How well a candidate's samples follow a lost identity's predicted path:
/// the squared RMS distance in units of the join radius (the path's
/// expected error) plus the log of that radius squared, relative to
/// `link_min` (a likelihood, as for the tracker's gates: where a candidate
/// follows two paths, the surer one wins, and an identity lost long ago,
/// whose radius has grown, no longer draws the pieces of its neighbours);
/// `None` beyond the radius or when the prediction does not cover the
/// samples. At most [`join_miss`].
fn path_cost(samples: &[(i64, DVec3)], g: &Gap, s: &IdentitySettings) -> Option<f64> {
    let mut sum = 0.0;
    let mut n = 0usize;
    for &(t, p) in samples {
        if let Ok(k) = g.preds.binary_search_by_key(&t, |x| x.0) {
            sum += p.distance_squared(g.preds[k].1);
            n += 1;
        }
    }
    if n * 2 < samples.len() || n == 0 {
        return None;
    }
    let rms = (sum / n as f64).sqrt();
    let radius = join_radius(g, s);
    let c = rms / radius;
    (c <= 1.0).then(|| c * c + 2.0 * (radius / s.link_min_m.max(1e-6)).ln().max(0.0))
}

/// How far from its predicted path a piece of the identity in gap `g` may
/// be: the prediction's expected error (m).
fn join_radius(g: &Gap, s: &IdentitySettings) -> f64 {
    (s.link_min_m + 3.0 * g.spread + MOVED_ERROR * g.moved).min(s.link_max_m)
}

/// The cost of leaving a candidate unjoined: above every path cost.
fn join_miss(s: &IdentitySettings) -> f64 {
    1.0 + 2.0 * (s.link_max_m / s.link_min_m.max(1e-6)).ln().max(0.0)
}

/// Finds the `NEIGHBOURS` nearest of a set of identities' positions: by
/// comparing every pair for a few, from a kd-tree for many. Ties go to the
/// lower identity either way.
struct NearestFinder {
    tree: Option<ImmutableKdTree<f64, 3>>,
}

impl NearestFinder {
    fn new(recent: &[(usize, DVec3)]) -> Self {
        let tree = (recent.len() > DIRECT_NEIGHBOURS_MAX)
            .then(|| {
                let points: Vec<[f64; 3]> = recent.iter().map(|(_, p)| p.to_array()).collect();
                ImmutableKdTree::<f64, 3>::new_from_slice(&points).ok()
            })
            .flatten();
        NearestFinder { tree }
    }

    /// The nearest others of `recent[k]`, as (squared distance, identity),
    /// nearest first, into `near`.
    fn nearest(&self, recent: &[(usize, DVec3)], k: usize, near: &mut Vec<(f64, usize)>) {
        near.clear();
        let (i, pi) = recent[k];
        match (&self.tree, std::num::NonZeroUsize::new(NEIGHBOURS + 1)) {
            (Some(tree), Some(n)) => {
                let found = tree
                    .query(&pi.to_array())
                    .nearest_n::<SquaredEuclidean<f64>>(n)
                    .execute();
                near.extend(
                    found
                        .into_iter()
                        .map(|f| (f.distance, recent[f.item as usize].0))
                        .filter(|&(_, j)| j != i),
                );
            }
            _ => near.extend(
                recent
                    .iter()
                    .filter(|(j, _)| *j != i)
                    .map(|(j, pj)| (pi.distance_squared(*pj), *j)),
            ),
        }
        let keep = NEIGHBOURS.min(near.len());
        if keep == 0 {
            return;
        }
        near.select_nth_unstable_by(keep - 1, |a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        near.truncate(keep);
        near.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn settings() -> IdentitySettings {
        IdentitySettings {
            link_frames: 3,
            confirm_frames: 10,
            link_min_m: 0.005,
            link_max_m: 0.06,
            keep_lost_frames: 1000,
            alpha: 1.0 / 200.0,
        }
    }

    /// A still marker hidden for a while comes back as a new trace while
    /// its old trace still coasts on a prediction that learnt stillness
    /// (longer than `confirm_frames`). The new trace must wait and become
    /// the marker's next piece, not a second marker (which would have no
    /// rest position); a new marker elsewhere is confirmed as usual.
    #[test]
    fn a_candidate_waits_for_the_coasting_trace_it_follows() {
        let p = DVec3::new(0.1, 1.0, 0.0);
        let q = DVec3::new(0.3, 1.0, 0.0);
        let mut ids = Identities::new(settings());
        let mut seen_during_coast = 0;
        for t in 0..70 {
            ids.begin(t);
            if t == 50 {
                // The old trace's gate grew too wide, or max_gap: it ends.
                ids.ended(0);
            }
            match t {
                0 => ids.started(0, p),
                1..30 => ids.measured(0, p, 0),
                35 => {
                    ids.started(1, p + DVec3::X * 0.0004);
                    ids.started(2, q);
                }
                36.. => {
                    ids.measured(1, p + DVec3::X * 0.0004, 0);
                    ids.measured(2, q, 1);
                }
                _ => {}
            }
            ids.end();
            if t == 48 {
                seen_during_coast = ids.current().count();
            }
        }
        // At frame 48 both new traces have 14 samples: the one far away is
        // a marker of its own, the one on the coasting marker's path waits.
        assert_eq!(seen_during_coast, 1);
        assert_eq!(ids.finish(), vec![vec![0, 1], vec![2]]);
    }
}
