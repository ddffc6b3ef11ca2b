//! A trace: the path of one marker over time, one entry per frame from its
//! first to its last measurement, each measured, filled or missing.
//!
//! Traces are the one thing the tracking stage keeps for a whole session
//! (a 1-hour take at 240 Hz with 70 markers is 60 million samples), so the
//! measured positions are stored compactly: quantized to [`QUANTUM_M`] and
//! written as the residual of the same forward-difference prediction the
//! tracker uses (`2p(M−1) − p(M−2)`), zig-zag varint coded. For a smoothly
//! moving marker that residual is about the size of the measurement noise,
//! so a sample takes 3–5 bytes instead of 24. Reading is sequential, which
//! is all the later steps (fill, rest, plots) need.
//!
//! Filled samples are not stored as positions: a fill is a cubic Hermite
//! segment ([`Fill`]) evaluated on demand, so a fill is always marked as a
//! fill and never passed off as a measurement.

use glam::DVec3;

/// Resolution of stored positions (m). 0.01 mm is ten times finer than an
/// optical system's accuracy (about 0.1 mm), and the rounding (at most
/// 0.005 mm per axis) averages away in rest positions.
pub const QUANTUM_M: f64 = 1e-5;

/// What one frame of a trace holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SampleKind {
    /// A marker of that frame was assigned to this trace.
    Measured,
    /// Interpolated across a gap (see `gaps.rs`); never a measurement.
    Filled,
    /// No marker, no fill.
    Missing,
}

/// One frame of a trace as read back.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// Internal frame index (monotonic over the session; see `Timeline`).
    pub frame: i64,
    /// Whether the position was measured, filled or is missing.
    pub kind: SampleKind,
    /// Metres, Y up; NaN when `kind` is `Missing`.
    pub position: DVec3,
}

/// A gap filled between two measured samples. Positions of the filled
/// frames are computed from it when read.
#[derive(Debug, Clone, PartialEq)]
pub struct Fill {
    /// Last measured frame before the gap.
    pub from: i64,
    /// First measured frame after the gap.
    pub to: i64,
    /// How the frames in between are filled.
    pub curve: Curve,
}

/// A run of measured frames `first..=last` with a gap on each side: the
/// steps after the session that weigh a few samples held between two
/// gaps (`lone`, `stray`) look at these.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct InnerRun {
    /// The last frame measured before the gap ahead of the run.
    pub before: i64,
    /// The run's first frame.
    pub first: i64,
    /// Its last frame.
    pub last: i64,
    /// The first frame measured after the gap behind it.
    pub after: i64,
}

/// The shape of a fill.
#[derive(Debug, Clone, PartialEq)]
pub enum Curve {
    /// A cubic Hermite segment (PCHIP slopes): position and velocity (m
    /// per frame) at `from` and at `to`.
    Hermite {
        /// Position at `from`.
        p0: DVec3,
        /// Velocity at `from` (m per frame).
        m0: DVec3,
        /// Position at `to`.
        p1: DVec3,
        /// Velocity at `to` (m per frame).
        m1: DVec3,
    },
    /// Positions for the frames `from + 1 .. to`, predicted from the
    /// motion of the marker's neighbours (see `gaps.rs`).
    Points(Vec<DVec3>),
}

impl Fill {
    /// The fill at frame `f` (`from <= f <= to`).
    pub fn at(&self, f: i64) -> DVec3 {
        match &self.curve {
            Curve::Hermite { p0, m0, p1, m1 } => {
                let h = (self.to - self.from) as f64;
                if h <= 0.0 {
                    return *p0;
                }
                let s = (f - self.from) as f64 / h;
                let s2 = s * s;
                let s3 = s2 * s;
                let h00 = 2.0 * s3 - 3.0 * s2 + 1.0;
                let h10 = s3 - 2.0 * s2 + s;
                let h01 = -2.0 * s3 + 3.0 * s2;
                let h11 = s3 - s2;
                *p0 * h00 + *m0 * (h10 * h) + *p1 * h01 + *m1 * (h11 * h)
            }
            Curve::Points(points) => {
                let k = (f - self.from - 1).clamp(0, points.len() as i64 - 1);
                points.get(k as usize).copied().unwrap_or(DVec3::NAN)
            }
        }
    }

    /// Whether the fill came from the neighbours (rather than PCHIP).
    pub fn from_neighbours(&self) -> bool {
        matches!(self.curve, Curve::Points(_))
    }
}

/// Where the measured samples of a trace came from: a run of frames in which
/// the source gave the same marker ID (a Motive column, a NatNet ID). Kept
/// so a user (and the tests) can see which source columns formed a tip.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct SourceRun {
    /// First frame of the run.
    pub frame: i64,
    /// The source's ID hint for the marker from this frame on.
    pub id: Option<i64>,
}

/// The path of one marker. `Default` is an empty trace (no frames): what a
/// replay's report keeps once the traces are no longer needed.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Trace {
    /// Number given by the tracker in order of appearance; stable in reports.
    pub id: usize,
    /// Ids of the tracker traces joined into this one (itself first).
    pub pieces: Vec<usize>,
    first: i64,
    len: usize,
    measured_bits: Vec<u64>,
    measured: usize,
    store: Store,
    fills: Vec<Fill>,
    sources: Vec<SourceRun>,
    last_position: DVec3,
}

impl Trace {
    /// A trace whose first measurement is `position` at `frame`.
    pub fn new(id: usize, frame: i64, position: DVec3, source: Option<i64>) -> Self {
        let mut t = Trace {
            id,
            pieces: vec![id],
            first: frame,
            len: 0,
            measured_bits: Vec::new(),
            measured: 0,
            store: Store::default(),
            fills: Vec::new(),
            sources: Vec::new(),
            last_position: position,
        };
        t.push(frame, position, source);
        t
    }

    /// Appends a measurement at `frame`, after the last one; the frames in
    /// between become missing. Earlier frames are ignored (the tracker never
    /// sends them).
    pub fn push(&mut self, frame: i64, position: DVec3, source: Option<i64>) {
        let offset = frame - self.first;
        if offset < self.len as i64 || offset < 0 {
            return;
        }
        let idx = offset as usize;
        self.len = idx + 1;
        let word = idx / 64;
        if self.measured_bits.len() <= word {
            self.measured_bits.resize(word + 1, 0);
        }
        self.measured_bits[word] |= 1 << (idx % 64);
        self.measured += 1;
        self.store.push(position);
        self.last_position = position;
        if self.sources.last().map(|r| r.id) != Some(source) {
            self.sources.push(SourceRun { frame, id: source });
        }
    }

    /// First frame (a measurement).
    pub fn first_frame(&self) -> i64 {
        self.first
    }

    /// Last frame (a measurement).
    pub fn last_frame(&self) -> i64 {
        self.first + self.len as i64 - 1
    }

    /// Frames covered from first to last measurement.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Only for the empty `Trace::default()`: a trace starts with a measurement.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Number of measured frames.
    pub fn measured(&self) -> usize {
        self.measured
    }

    /// Number of filled frames.
    pub fn filled(&self) -> usize {
        self.fills
            .iter()
            .map(|f| (f.to - f.from - 1).max(0) as usize)
            .sum()
    }

    /// The last measured position.
    pub fn last_position(&self) -> DVec3 {
        self.last_position
    }

    /// Whether `frame` holds a measurement.
    pub fn is_measured(&self, frame: i64) -> bool {
        let offset = frame - self.first;
        if offset < 0 || offset >= self.len as i64 {
            return false;
        }
        let idx = offset as usize;
        self.measured_bits
            .get(idx / 64)
            .is_some_and(|w| w & (1 << (idx % 64)) != 0)
    }

    /// The runs of consecutive measured frames, (first, last) in order,
    /// read from the measured flags: nothing is decoded.
    pub fn measured_runs(&self) -> impl Iterator<Item = (i64, i64)> + '_ {
        let end = self.last_frame();
        let mut next = self.first;
        std::iter::from_fn(move || {
            if self.is_empty() || next > end {
                return None;
            }
            let first = next;
            let mut last = first;
            while last < end && self.is_measured(last + 1) {
                last += 1;
            }
            next = last + 1;
            while next <= end && !self.is_measured(next) {
                next += 1;
            }
            Some((first, last))
        })
    }

    /// The runs of measured frames with a gap on each side, in order:
    /// the trace's first and last runs are never among them. Read from
    /// the measured flags: nothing is decoded.
    pub fn inner_runs(&self) -> impl Iterator<Item = InnerRun> + '_ {
        let mut runs = self.measured_runs();
        let (mut prev, mut this) = (runs.next(), runs.next());
        std::iter::from_fn(move || {
            let next = runs.next()?;
            let ((_, before), (first, last)) = (prev?, this?);
            (prev, this) = (this, Some(next));
            Some(InnerRun {
                before,
                first,
                last,
                after: next.0,
            })
        })
    }

    /// The gap fills, in frame order.
    pub fn fills(&self) -> &[Fill] {
        &self.fills
    }

    /// Records a fill; `gaps.rs` makes sure it spans a gap of this trace.
    pub(crate) fn add_fill(&mut self, fill: Fill) {
        let at = self.fills.partition_point(|f| f.from < fill.from);
        self.fills.insert(at, fill);
    }

    /// Forgets the fills: the trace's gaps are to be filled again (they
    /// changed, or its neighbours did).
    pub(crate) fn clear_fills(&mut self) {
        self.fills = Vec::new();
    }

    /// Records a trace's fills (see [`Trace::add_fill`]). A list in frame
    /// order given to a trace without fills becomes its list as it is: gap
    /// filling makes each trace's list whole, and copying it in held every
    /// fill twice.
    pub(crate) fn add_fills(&mut self, fills: Vec<Fill>) {
        if self.fills.is_empty() && fills.is_sorted_by_key(|f| f.from) {
            self.fills = fills;
            return;
        }
        for fill in fills {
            self.add_fill(fill);
        }
    }

    /// Which source IDs the measurements came from, as runs.
    pub fn sources(&self) -> &[SourceRun] {
        &self.sources
    }

    /// The measured positions in order with their frames.
    pub fn measurements(&self) -> impl Iterator<Item = (i64, DVec3)> + '_ {
        let mut decoder = self.store.decoder();
        (0..self.len).filter_map(move |idx| {
            let on = self
                .measured_bits
                .get(idx / 64)
                .is_some_and(|w| w & (1 << (idx % 64)) != 0);
            if on {
                decoder.next().map(|p| (self.first + idx as i64, p))
            } else {
                None
            }
        })
    }

    /// Every frame from first to last: measured, filled or missing.
    pub fn samples(&self) -> impl Iterator<Item = Sample> + '_ {
        let mut decoder = self.store.decoder();
        let mut fill = 0usize;
        (0..self.len).map(move |idx| {
            let frame = self.first + idx as i64;
            let on = self
                .measured_bits
                .get(idx / 64)
                .is_some_and(|w| w & (1 << (idx % 64)) != 0);
            if on {
                if let Some(p) = decoder.next() {
                    return Sample {
                        frame,
                        kind: SampleKind::Measured,
                        position: p,
                    };
                }
            }
            while fill < self.fills.len() && self.fills[fill].to <= frame {
                fill += 1;
            }
            match self.fills.get(fill) {
                Some(f) if f.from < frame && frame < f.to => Sample {
                    frame,
                    kind: SampleKind::Filled,
                    position: f.at(frame),
                },
                _ => Sample {
                    frame,
                    kind: SampleKind::Missing,
                    position: DVec3::NAN,
                },
            }
        })
    }

    /// Appends `other` (which must start after this trace ends) to this one:
    /// the frames between become a gap. Gives `other` back unchanged when
    /// they overlap (`None`: appended).
    ///
    /// The piece's stored samples are moved, not decoded and stored again:
    /// an hour-long take's markers are joined from thousands of pieces, and
    /// copying them held each marker twice while the freed pieces' small
    /// chunks could not take the joined trace's larger ones (the marker
    /// stage's peak memory was 1.7 times its traces).
    pub fn append(&mut self, other: Trace) -> Option<Trace> {
        if other.first_frame() <= self.last_frame() {
            return Some(other);
        }
        let offset = (other.first - self.first) as usize;
        self.len = offset + other.len;
        self.measured_bits.resize(self.len.div_ceil(64), 0);
        for (w, &word) in other.measured_bits.iter().enumerate() {
            let mut bits = word;
            while bits != 0 {
                let idx = offset + w * 64 + bits.trailing_zeros() as usize;
                self.measured_bits[idx / 64] |= 1 << (idx % 64);
                bits &= bits - 1;
            }
        }
        self.measured += other.measured;
        self.store.append(other.store);
        self.last_position = other.last_position;
        for run in other.sources {
            if self.sources.last().map(|r| r.id) != Some(run.id) {
                self.sources.push(run);
            }
        }
        self.fills.extend(other.fills);
        self.pieces.extend_from_slice(&other.pieces);
        None
    }

    /// Number of measured frames in `[from, to]`.
    pub fn measured_between(&self, from: i64, to: i64) -> usize {
        let lo = (from - self.first).max(0);
        let hi = (to - self.first).min(self.len as i64 - 1);
        if hi < lo {
            return 0;
        }
        (lo as usize..=hi as usize)
            .filter(|&i| {
                self.measured_bits
                    .get(i / 64)
                    .is_some_and(|w| w & (1 << (i % 64)) != 0)
            })
            .count()
    }

    /// The measurements (with their source IDs) in frame order.
    pub(crate) fn measurements_with_source(
        &self,
    ) -> impl Iterator<Item = (i64, DVec3, Option<i64>)> + '_ {
        let mut runs = self.sources.iter().peekable();
        let mut source = None;
        self.measurements().map(move |(frame, p)| {
            while let Some(r) = runs.next_if(|r| r.frame <= frame) {
                source = r.id;
            }
            (frame, p, source)
        })
    }

    /// A trace numbered `id` holding `samples` (frame, position, source
    /// id; in frame order, as [`Trace::push`] takes them); `None` when
    /// there are none.
    pub(crate) fn collected(
        id: usize,
        samples: impl IntoIterator<Item = (i64, DVec3, Option<i64>)>,
    ) -> Option<Trace> {
        let mut samples = samples.into_iter();
        let (frame, p, source) = samples.next()?;
        let mut out = Trace::new(id, frame, p, source);
        for (frame, p, source) in samples {
            out.push(frame, p, source);
        }
        Some(out)
    }

    /// One trace from two pieces that may interleave in time (one fills a
    /// gap of the other); `None` if both are measured in the same frame.
    /// Keeps this trace's id.
    pub fn merged(&self, other: &Trace) -> Option<Trace> {
        let mut a = self.measurements_with_source().peekable();
        let mut b = other.measurements_with_source().peekable();
        let mut clash = false;
        let both = std::iter::from_fn(|| match (a.peek(), b.peek()) {
            (Some(x), Some(y)) if x.0 == y.0 => {
                clash = true;
                None
            }
            (Some(x), Some(y)) => {
                if x.0 < y.0 {
                    a.next()
                } else {
                    b.next()
                }
            }
            (Some(_), None) => a.next(),
            (None, Some(_)) => b.next(),
            (None, None) => None,
        });
        let out = Trace::collected(self.id, both);
        if clash {
            return None;
        }
        let mut out = out?;
        out.pieces = self.pieces.clone();
        out.pieces.extend_from_slice(&other.pieces);
        out.fills = self.fills.clone();
        for f in &other.fills {
            out.add_fill(f.clone());
        }
        Some(out)
    }

    /// This trace without its measurements in `frames` (sorted); `None`
    /// when none would be left.
    pub(crate) fn without(&self, frames: &[i64]) -> Option<Trace> {
        let rest = self
            .measurements_with_source()
            .filter(|(frame, _, _)| frames.binary_search(frame).is_err());
        let mut out = Trace::collected(self.id, rest)?;
        out.pieces = self.pieces.clone();
        out.fills = self.fills.clone();
        Some(out)
    }

    /// Releases the spare capacity of the storage when the trace has ended
    /// (thousands of ended traces would otherwise each keep a half-empty
    /// chunk). Pushing later still works.
    pub fn seal(&mut self) {
        if let Some(c) = self.store.chunks.last_mut() {
            c.shrink_to_fit();
        }
        self.measured_bits.shrink_to_fit();
        self.sources.shrink_to_fit();
    }

    /// Bytes of heap this trace uses (for memory reports).
    pub fn heap_bytes(&self) -> usize {
        self.measured_bits.capacity() * 8
            + self.store.heap_bytes()
            + self.fills.capacity() * std::mem::size_of::<Fill>()
            + self.sources.capacity() * std::mem::size_of::<SourceRun>()
            + self.pieces.capacity() * 8
    }
}

/// Append-only compact storage of positions (see the module comment).
#[derive(Debug, Clone, Default, PartialEq)]
struct Store {
    /// Fixed-capacity chunks, so that growing never copies the whole store
    /// (a doubling `Vec` would briefly need twice the memory).
    chunks: Vec<Vec<u8>>,
    /// (sample, chunk) where an appended store's samples begin: its chunks
    /// were moved here as they were, so the prediction starts afresh there.
    restarts: Vec<(usize, usize)>,
    prev: [[i64; 3]; 2],
    count: usize,
    /// Samples since the last restart (what the prediction may use).
    run: usize,
}

const MAX_CHUNK: usize = 1 << 16;
/// Longest encoding of one position: three 10-byte varints.
const MAX_SAMPLE_BYTES: usize = 30;

fn quantize(v: f64) -> i64 {
    // Positions are finite (the tracker drops the rest) and within a capture
    // volume; clamp anyway so that a wild value cannot overflow.
    (v / QUANTUM_M).round().clamp(-1e15, 1e15) as i64
}

fn predict(prev: &[[i64; 3]; 2], count: usize, axis: usize) -> i64 {
    match count {
        0 => 0,
        1 => prev[1][axis],
        _ => prev[1][axis]
            .saturating_mul(2)
            .saturating_sub(prev[0][axis]),
    }
}

impl Store {
    fn push(&mut self, p: DVec3) {
        let q = [quantize(p.x), quantize(p.y), quantize(p.z)];
        let need_new = match self.chunks.last() {
            None => true,
            Some(c) => c.len() + MAX_SAMPLE_BYTES > c.capacity(),
        };
        if need_new {
            // Small first chunks keep thousands of short spurious traces cheap.
            let cap = self
                .chunks
                .last()
                .map_or(64, |c| (c.capacity() * 2).min(MAX_CHUNK));
            self.chunks.push(Vec::with_capacity(cap));
        }
        if let Some(chunk) = self.chunks.last_mut() {
            for (axis, &v) in q.iter().enumerate() {
                let r = v.wrapping_sub(predict(&self.prev, self.run, axis));
                let mut z = ((r << 1) ^ (r >> 63)) as u64;
                loop {
                    let byte = (z & 0x7f) as u8;
                    z >>= 7;
                    if z == 0 {
                        chunk.push(byte);
                        break;
                    }
                    chunk.push(byte | 0x80);
                }
            }
        }
        self.prev = [self.prev[1], q];
        self.count += 1;
        self.run += 1;
    }

    /// Moves `other`'s samples after this store's (see [`Trace::append`]).
    fn append(&mut self, other: Store) {
        if other.count == 0 {
            return;
        }
        if self.count == 0 {
            *self = other;
            return;
        }
        let (samples, chunks) = (self.count, self.chunks.len());
        self.restarts.push((samples, chunks));
        self.restarts.extend(
            other
                .restarts
                .iter()
                .map(|&(s, c)| (s + samples, c + chunks)),
        );
        self.chunks.extend(other.chunks);
        self.prev = other.prev;
        self.count += other.count;
        self.run = other.run;
    }

    fn decoder(&self) -> Decoder<'_> {
        Decoder {
            store: self,
            chunk: 0,
            pos: 0,
            prev: [[0; 3]; 2],
            count: 0,
            run: 0,
            restart: 0,
        }
    }

    fn heap_bytes(&self) -> usize {
        self.chunks.iter().map(Vec::capacity).sum::<usize>()
            + self.chunks.capacity() * 24
            + self.restarts.capacity() * 16
    }
}

struct Decoder<'a> {
    store: &'a Store,
    chunk: usize,
    pos: usize,
    prev: [[i64; 3]; 2],
    count: usize,
    /// Samples since the last restart, and the next restart.
    run: usize,
    restart: usize,
}

impl Iterator for Decoder<'_> {
    type Item = DVec3;
    fn next(&mut self) -> Option<DVec3> {
        if self.count >= self.store.count {
            return None;
        }
        if let Some(&(sample, chunk)) = self.store.restarts.get(self.restart) {
            if sample == self.count {
                self.restart += 1;
                self.chunk = chunk;
                self.pos = 0;
                self.prev = [[0; 3]; 2];
                self.run = 0;
            }
        }
        let mut chunk = self.store.chunks.get(self.chunk)?;
        if self.pos >= chunk.len() {
            self.chunk += 1;
            self.pos = 0;
            chunk = self.store.chunks.get(self.chunk)?;
        }
        // The prediction once per sample, and the bytes as one slice: the
        // later steps read every trace several times, and this loop was a
        // fifth of their time.
        let pred = [0, 1, 2].map(|axis| predict(&self.prev, self.run, axis));
        let bytes = chunk.get(self.pos..)?;
        let mut at = 0usize;
        let mut q = [0i64; 3];
        for (slot, pred) in q.iter_mut().zip(pred) {
            let mut z = 0u64;
            let mut shift = 0u32;
            loop {
                let byte = *bytes.get(at)?;
                at += 1;
                if shift < 64 {
                    z |= u64::from(byte & 0x7f) << shift;
                }
                shift += 7;
                if byte & 0x80 == 0 {
                    break;
                }
            }
            let r = ((z >> 1) as i64) ^ -((z & 1) as i64);
            *slot = r.wrapping_add(pred);
        }
        self.pos += at;
        self.prev = [self.prev[1], q];
        self.count += 1;
        self.run += 1;
        Some(DVec3::new(
            q[0] as f64 * QUANTUM_M,
            q[1] as f64 * QUANTUM_M,
            q[2] as f64 * QUANTUM_M,
        ))
    }
}

/// Time of every internal frame index, and where the source's frame
/// numbers map to it.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Timeline {
    /// Seconds for internal frames 0, 1, 2, … (skipped frames interpolated).
    pub times: Vec<f64>,
    /// `(internal index, source frame number)` at the first frame and after
    /// every discontinuity; in between the two advance together.
    pub anchors: Vec<(i64, i64)>,
}

impl Timeline {
    /// Number of internal frames.
    pub fn len(&self) -> usize {
        self.times.len()
    }

    /// True for a recording without frames (nothing to track).
    pub fn is_empty(&self) -> bool {
        self.times.is_empty()
    }

    /// Time of internal frame `t` (clamped to the recorded range; 0 if none).
    pub fn time(&self, t: i64) -> f64 {
        if self.times.is_empty() {
            return 0.0;
        }
        let i = t.clamp(0, self.times.len() as i64 - 1) as usize;
        self.times[i]
    }

    /// The first internal frame at or after `time_s`.
    pub fn frame_at(&self, time_s: f64) -> i64 {
        self.times.partition_point(|&t| t < time_s) as i64
    }

    /// Median frame interval (s), or `None` with fewer than two frames.
    pub fn frame_interval(&self) -> Option<f64> {
        if self.times.len() < 2 {
            return None;
        }
        let step = (self.times.len() / 2001).max(1);
        let mut d: Vec<f64> = self
            .times
            .windows(2)
            .step_by(step)
            .map(|w| w[1] - w[0])
            .filter(|d| *d > 0.0)
            .collect();
        if d.is_empty() {
            return None;
        }
        d.sort_by(f64::total_cmp);
        Some(d[d.len() / 2])
    }

    /// The source's frame number of internal frame `t`.
    pub fn source_frame(&self, t: i64) -> Option<i64> {
        let i = self.anchors.partition_point(|a| a.0 <= t);
        let (at, frame) = *self.anchors.get(i.checked_sub(1)?)?;
        frame.checked_add(t - at)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn measured_runs_are_read_from_the_flags() {
        let mut t = Trace::new(0, 5, DVec3::ZERO, None);
        for f in [6, 7, 9, 12, 13] {
            t.push(f, DVec3::ZERO, None);
        }
        let runs: Vec<(i64, i64)> = t.measured_runs().collect();
        assert_eq!(runs, vec![(5, 7), (9, 9), (12, 13)]);
        assert_eq!(Trace::default().measured_runs().count(), 0);
    }

    #[test]
    fn measurements_round_trip_to_the_quantum() {
        let mut rng = crate::rng::Rng::new(7);
        let mut truth = Vec::new();
        let mut t = Trace::new(0, 10, DVec3::new(0.5, 1.2, -0.3), Some(4));
        truth.push((10, DVec3::new(0.5, 1.2, -0.3)));
        let mut frame = 10;
        for i in 0..5000 {
            frame += if rng.chance(0.1) { rng.int(2, 40) } else { 1 };
            // Smooth sway plus noise plus the odd big jump.
            let s = i as f64 * 0.01;
            let mut p = DVec3::new(0.5 + 0.03 * s.sin(), 1.2 + 0.0002 * rng.normal(), -0.3);
            if rng.chance(0.01) {
                p.x += rng.range(-2.0, 2.0);
            }
            t.push(frame, p, Some(4 + i / 1000));
            truth.push((frame, p));
        }
        assert_eq!(t.measured(), truth.len());
        assert_eq!(t.last_frame(), frame);
        let got: Vec<_> = t.measurements().collect();
        assert_eq!(got.len(), truth.len());
        for ((fa, a), (fb, b)) in got.iter().zip(&truth) {
            assert_eq!(fa, fb);
            assert!((*a - *b).abs().max_element() <= QUANTUM_M / 2.0 + 1e-12);
        }
        // Compact: well under 24 bytes a sample.
        assert!(t.heap_bytes() < truth.len() * 8, "{} bytes", t.heap_bytes());
        // IDs 4 (first sample and i < 1000), 5, 6, 7, 8.
        assert_eq!(t.sources().len(), 5);
        let missing = t
            .samples()
            .filter(|s| s.kind == SampleKind::Missing)
            .count();
        assert_eq!(missing + t.measured(), t.len());
    }

    #[test]
    fn fills_are_flagged_and_follow_the_hermite_curve() {
        let mut t = Trace::new(1, 0, DVec3::ZERO, None);
        t.push(1, DVec3::X * 0.001, None);
        t.push(5, DVec3::X * 0.005, None);
        t.add_fill(Fill {
            from: 1,
            to: 5,
            curve: Curve::Hermite {
                p0: DVec3::X * 0.001,
                m0: DVec3::X * 0.001,
                p1: DVec3::X * 0.005,
                m1: DVec3::X * 0.001,
            },
        });
        let s: Vec<_> = t.samples().collect();
        assert_eq!(s.len(), 6);
        assert_eq!(s[2].kind, SampleKind::Filled);
        // A straight line at 1 mm per frame: the Hermite curve is exact.
        assert!((s[3].position.x - 0.003).abs() < 1e-12);
        assert_eq!(s[5].kind, SampleKind::Measured);
        assert_eq!(t.filled(), 3);
    }

    #[test]
    fn append_joins_later_pieces_only() {
        let mut a = Trace::new(0, 0, DVec3::ZERO, Some(1));
        a.push(3, DVec3::ONE, Some(1));
        let mut b = Trace::new(5, 10, DVec3::ONE, Some(2));
        b.push(11, DVec3::ONE, Some(3));
        assert!(b.clone().append(a.clone()).is_some());
        assert!(a.append(b).is_none());
        assert_eq!(a.pieces, vec![0, 5]);
        assert_eq!(a.len(), 12);
        assert_eq!(a.measured(), 4);
        assert!(a.is_measured(10) && !a.is_measured(5));
        let ids: Vec<_> = a.sources().iter().map(|r| r.id).collect();
        assert_eq!(ids, vec![Some(1), Some(2), Some(3)]);
    }

    /// Appending moves a piece's stored samples instead of storing them
    /// again: what reads back (positions, flags, sources) is what pushing
    /// every sample of the pieces gives, also for pushes after the append
    /// and for a piece that was itself appended to.
    #[test]
    fn appended_pieces_read_back_as_if_pushed() {
        let mut rng = crate::rng::Rng::new(11);
        let mut pushed: Option<Trace> = None;
        let mut pieces: Vec<Trace> = Vec::new();
        let mut frame = 5;
        for piece in 0..6 {
            let mut t: Option<Trace> = None;
            for i in 0..(200 + 900 * (piece % 2)) {
                frame += if rng.chance(0.05) { rng.int(2, 9) } else { 1 };
                let p = DVec3::new(
                    0.4 + 0.02 * (i as f64 * 0.03).sin(),
                    1.0,
                    rng.normal() * 3e-4,
                );
                let id = Some(piece as i64 / 2);
                match t.as_mut() {
                    None => t = Some(Trace::new(piece, frame, p, id)),
                    Some(t) => t.push(frame, p, id),
                }
                match pushed.as_mut() {
                    None => pushed = Some(Trace::new(0, frame, p, id)),
                    Some(all) => all.push(frame, p, id),
                }
            }
            frame += 30;
            pieces.push(t.unwrap());
        }
        let pushed = pushed.unwrap();
        let mut tail = pieces.split_off(3);
        let mut later = tail.remove(0);
        for t in tail {
            assert!(later.append(t).is_none());
        }
        let mut joined = pieces.remove(0);
        for t in pieces {
            assert!(joined.append(t).is_none());
        }
        assert!(joined.append(later).is_none());
        assert_eq!(joined.len(), pushed.len());
        assert_eq!(joined.measured(), pushed.measured());
        assert_eq!(joined.sources(), pushed.sources());
        assert_eq!(joined.last_position(), pushed.last_position());
        // (Missing frames' NaN positions compare unequal: kinds, then the
        // measured positions.)
        let kinds = |t: &Trace| t.samples().map(|s| s.kind).collect::<Vec<_>>();
        assert_eq!(kinds(&joined), kinds(&pushed));
        assert!(joined.measurements().eq(pushed.measurements()));
        // Pushing after an append continues the last piece's prediction.
        let mut a = joined.clone();
        let mut b = pushed.clone();
        for k in 1..50 {
            let p = DVec3::new(0.41, 1.0 + k as f64 * 1e-4, 0.0);
            a.push(frame + k, p, None);
            b.push(frame + k, p, None);
        }
        assert!(a.measurements().eq(b.measurements()));
        assert!(a.clone().append(b).is_some());
    }

    #[test]
    fn merged_interleaves_and_refuses_shared_frames() {
        let mut a = Trace::new(0, 0, DVec3::ZERO, Some(1));
        a.push(1, DVec3::X, Some(1));
        a.push(9, DVec3::Y, Some(1));
        let mut b = Trace::new(4, 4, DVec3::Z, Some(2));
        b.push(5, DVec3::Z, Some(2));
        let m = a.merged(&b).unwrap();
        assert_eq!(m.id, 0);
        assert_eq!(m.pieces, vec![0, 4]);
        let frames: Vec<i64> = m.measurements().map(|x| x.0).collect();
        assert_eq!(frames, vec![0, 1, 4, 5, 9]);
        let ids: Vec<_> = m.sources().iter().map(|r| (r.frame, r.id)).collect();
        assert_eq!(ids, vec![(0, Some(1)), (4, Some(2)), (9, Some(1))]);
        assert_eq!(m.measured_between(2, 8), 2);
        let c = Trace::new(7, 5, DVec3::ONE, None);
        assert!(m.merged(&c).is_none());
    }
}
