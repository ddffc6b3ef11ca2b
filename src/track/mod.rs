//! Marker processing (paper §4, spec/pipeline.md sections 2–4): unindexed
//! markers per frame in, one rest position per branch tip out.
//!
//! The steps, in order:
//! 1. [`tracker`]: frame by frame, markers become traces (a Kalman filter
//!    per trace, gates from its uncertainty, kd-tree candidates, global
//!    assignment), and [`identity`] joins the pieces of each marker on line
//!    from its neighbours' motion; traces never confirmed are ghosts;
//! 2. `untangle`: where two markers passed close, the traces the tracker
//!    swapped, for good or for a frame or two, are swapped back (the
//!    vector between them turns round), and the frames where they were
//!    too close to tell apart are named;
//!    [`rest`]: the still phase is found (or taken from the config);
//! 3. [`adopt`]: ghosts that are pieces of a marker (a marker seen as two
//!    blobs, a trace broken before it was confirmed) join it; `rejoin`:
//!    the joins across gaps are decided again with the whole take in view
//!    (each piece's offset from its neighbours, relative to the rest
//!    positions); [`noise`]:
//!    pieces of one marker still apart are joined by rest position;
//! 4. [`noise`]: traces measured in fewer than 1/4 of the frames are dropped;
//!    the samples `untangle` named go, from the tips and from the rest;
//!    `reclaim`: samples no tip holds (ghosts, loose pieces, the dropped
//!    traces) that continue a tip from a gap's edge go back into its gap;
//! 5. [`gaps`]: gaps are filled from the neighbours' motion, or by PCHIP,
//!    where plausible;
//! 6. [`rest`]: each remaining trace's rest position → [`Tips`].
//!
//! The live daemon runs step 1 as frames arrive and steps 2–6 ([`clean`])
//! when it wants tips; a replay does both in [`process`].

pub mod adopt;
pub mod assign;
pub mod gaps;
mod grid;
mod identity;
mod inline_vec;
mod jitter;
pub mod live;
mod lone;
mod motion;
pub mod noise;
mod places;
mod radix;
mod reclaim;
mod rejoin;
pub mod rest;
pub mod settings;
mod stray;
pub mod tracker;
mod untangle;
mod warm;

use crate::model::trace::{Timeline, Trace};
pub use settings::TrackingSettings;

use std::fmt;

use glam::DVec3;
use serde::Serialize;

pub use gaps::GapStats;
pub use noise::DroppedTrace;
pub use rest::{RestSource, RestWindow};
pub use tracker::{TrackStats, Tracked, Tracker};

use crate::error::Result;
use crate::model::recording::Recording;
use crate::model::tips::{Tip, Tips};

/// What the marker stage did, for the user (printed by `tips` and `replay`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Summary {
    /// Where the frames came from (the recording's `source`).
    pub source: String,
    /// Frames per second of the recording.
    pub frame_rate: f64,
    /// Frames received and the time they span (s).
    pub frames: u64,
    /// Seconds from the first to the last frame.
    pub duration_s: f64,
    /// Counters of the tracker, including the bad input it skipped.
    pub tracking: TrackStats,
    /// Traces the tracker made (before joining).
    pub traces: usize,
    /// Traces never confirmed as a marker (ghost reflections, flickers).
    pub ghosts: usize,
    /// Pieces joined to an earlier piece of the same marker on line, from
    /// the neighbours' motion.
    pub joined_on_line: usize,
    /// Traces never confirmed that were pieces of a marker: measured
    /// exactly in the frames it missed, handing over to it within a frame
    /// or two (a marker seen as two blobs, a trace broken before it was
    /// confirmed); not counted in `ghosts`.
    pub adopted: usize,
    /// Places where the tracker had swapped two markers passing close, for
    /// good or for a frame or two, and their traces were swapped back
    /// afterwards (`untangle`).
    pub untangled: usize,
    /// Samples of two markers that passed within their noise of each
    /// other, in the frames where which was which could not be told: taken
    /// out of both tips (and their gaps there filled) rather than risk
    /// each holding the other's (`untangle`).
    pub given_up: usize,
    /// Samples of pieces another tip would have taken about as well as
    /// the one they fitted best, or that no tip took though one fitted
    /// them loosely, after the session: given up with their tips' gaps
    /// there filled, rather than risk a piece of one marker in another's
    /// tip (`rejoin`).
    pub in_doubt: usize,
    /// Samples of runs of one to three a tip held alone between two gaps
    /// with another tip's marker beside them, or where a tip hidden
    /// across them would be about as near, which may as well be that
    /// marker's: given up with their tips' gaps there filled (`lone`).
    pub lone: usize,
    /// Samples of runs of up to eight a tip held between two gaps that
    /// lie more than 20 mm off the course its own samples draw across the
    /// whole gap, where the gap filler draws one (up to 0.21 s): a
    /// reflection sitting where the tip was hidden, or now and then the
    /// tip's own swinging fast; or off it by more than 99 % of such
    /// courses miss while another tip hidden across the run could own it
    /// (`stray`). Given up with the gap filled.
    pub stray: usize,
    /// Pieces joined afterwards by rest position.
    pub joined_by_rest: usize,
    /// Long fragments without a rest position put into a gap of the marker
    /// whose neighbourhood they occupy.
    pub joined_into_gaps: usize,
    /// Pieces the tracker joined across a gap that were given to another
    /// tip afterwards, from their offset to the neighbours over the whole
    /// take (`rejoin`).
    pub rejoined: usize,
    /// Samples of ghosts and dropped traces taken into a tip's gap, where
    /// they continue the tip from the gap's edge by the step its
    /// neighbours predict (`reclaim`).
    pub reclaimed: usize,
    /// Traces dropped as noise (measured in fewer than `noise_fraction` of
    /// the frames), longest first.
    pub dropped: Vec<DroppedTrace>,
    /// The noise threshold used (`tracking.noise_fraction`), for the report.
    pub noise_fraction: f64,
    /// What gap filling did.
    pub gaps: GapStats,
    /// The rest window (s) and where it came from.
    pub rest_window_s: [f64; 2],
    /// Whether the rest window was found, configured or the whole recording.
    pub rest_source: RestSource,
    /// Tips found.
    pub tips: usize,
    /// Things the user should look at.
    pub warnings: Vec<String>,
}

impl fmt::Display for Summary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let t = &self.tracking;
        writeln!(
            f,
            "{}: {} frames at {} Hz ({:.2} s), {} marker samples",
            self.source, self.frames, self.frame_rate, self.duration_s, t.markers
        )?;
        writeln!(
            f,
            "markers found: {} tips, from {} traces ({} ghosts never confirmed; pieces joined: {} from the neighbours' motion, {} handing over to their marker, {} by rest position, {} into a gap of their neighbourhood; {} given to another tip after the session; {} swaps undone where two markers passed close; samples given up: {} where two markers could not be told apart, {} of pieces whose tip was in doubt, {} held alone between gaps, {} off the tip's own course across a gap)",
            self.tips, self.traces, self.ghosts, self.joined_on_line, self.adopted, self.joined_by_rest, self.joined_into_gaps, self.rejoined, self.untangled, self.given_up, self.in_doubt, self.lone, self.stray
        )?;
        let longest = self.dropped.first().map_or(String::new(), |d| {
            format!(
                "; longest: trace {} measured in {} frames ({:.1} %)",
                d.id,
                d.measured,
                d.fraction * 100.0
            )
        });
        writeln!(
            f,
            "dropped as noise: {} traces measured in fewer than {:.0} % of the frames ({} samples){}",
            self.dropped.len(),
            self.noise_fraction * 100.0,
            self.dropped.iter().map(|d| d.measured).sum::<usize>(),
            longest
        )?;
        let g = &self.gaps;
        writeln!(
            f,
            "gaps: {} samples no tip held taken back into them; {} filled ({} frames, {} from the neighbours' motion); left open: {} too long ({} frames), {} whose ends are not one marker ({} frames)",
            self.reclaimed, g.filled, g.filled_frames, g.from_neighbours, g.too_long, g.too_long_frames, g.rejected, g.rejected_frames
        )?;
        let source = match self.rest_source {
            RestSource::Auto => "found automatically",
            RestSource::Config => "from the config",
            RestSource::WholeRecording => "no still phase found, whole recording used",
        };
        writeln!(
            f,
            "rest window: {:.2}–{:.2} s ({source})",
            self.rest_window_s[0], self.rest_window_s[1]
        )?;
        write!(
            f,
            "bad input: {} non-finite markers, {} duplicates, {} empty frames, {} restarts, {} jumps ({} frames skipped)",
            t.nonfinite_markers, t.duplicate_markers, t.empty_frames, t.restarts, t.jumps, t.skipped_frames
        )?;
        for w in &self.warnings {
            write!(f, "\nwarning: {w}")?;
        }
        Ok(())
    }
}

/// One trace per identity (its pieces appended in time order, or merged
/// where they interleave); returns them in order of first appearance, the
/// traces in none (ghosts), in order of id, and the pieces of an identity
/// that share a frame with its earlier pieces (loose; `clean` orders them
/// with the ghosts).
fn assemble(
    traces: Vec<crate::model::trace::Trace>,
    identities: &[Vec<usize>],
) -> (Vec<Trace>, Vec<Trace>, Vec<Trace>) {
    let mut slots: Vec<Option<Trace>> = traces.into_iter().map(Some).collect();
    let mut out = Vec::with_capacity(identities.len());
    let mut loose = Vec::new();
    for pieces in identities {
        let mut iter = pieces.iter();
        let Some(mut joined) = iter.next().and_then(|&i| slots.get_mut(i)?.take()) else {
            continue;
        };
        for &i in iter {
            if let Some(piece) = slots.get_mut(i).and_then(Option::take) {
                let Some(piece) = joined.append(piece) else {
                    continue;
                };
                // A piece judged on line while a later one was alive: it
                // interleaves; one sharing a frame stays a loose trace.
                match joined.merged(&piece) {
                    Some(m) => joined = m,
                    None => loose.push(piece),
                }
            }
        }
        out.push(joined);
    }
    let mut ghosts: Vec<Trace> = slots.into_iter().flatten().collect();
    ghosts.sort_by_key(|t| t.id);
    out.sort_by_key(|t| (t.first_frame(), t.id));
    (out, ghosts, loose)
}

/// Runs the whole marker stage over a recording: reads, tracks, joins,
/// drops noise, fills gaps, finds the rest phase and averages.
pub fn process(recording: &mut dyn Recording, cfg: &TrackingSettings) -> Result<(Tips, Summary)> {
    let frame_rate = recording.info().frame_rate;
    let source = recording.info().source.clone();
    let mut tracker = Tracker::new(cfg, Some(frame_rate));
    for frame in &mut *recording {
        tracker.push(&frame?);
    }
    let mut warnings: Vec<String> = recording.warnings().to_vec();
    let (tips, mut summary) = clean(tracker.finish(), cfg, &source, frame_rate);
    warnings.append(&mut summary.warnings);
    summary.warnings = warnings;
    Ok((tips, summary))
}

/// Steps 2–6 on the tracker's output.
pub fn clean(
    tracked: Tracked,
    cfg: &TrackingSettings,
    source: &str,
    frame_rate: f64,
) -> (Tips, Summary) {
    let Tracked {
        mut traces,
        identities,
        timeline,
        stats,
    } = tracked;
    let n_traces = traces.len();
    let joined_on_line = stats.joined as usize;
    // Where two markers passed close the tracker may have swapped them;
    // every later step builds on which marker each trace holds.
    let untangled = untangle::untangle(&mut traces, one_second(&timeline));
    let seams = rejoin::seams_of(&traces, &identities);
    let (mut traces, ghosts, mut loose) = assemble(traces, &identities);
    let frames = stats.frames;
    let mut warnings: Vec<String> = spacing_warning(&stats, cfg).into_iter().collect();

    let total = timeline.len() as i64;
    // The still phase is judged on the markers as the tracker followed
    // them: a marker seen as two blobs jumps by millimetres while still.
    let window = rest_window(cfg, &traces, &timeline, &mut warnings);
    let (ghosts, adopted) = adopt::adopt_ghosts(&mut traces, ghosts, cfg.gate_mm / 1000.0);
    // Every trace never confirmed, and an identity's loose pieces, go to
    // the tip whose neighbours they fit (rejoin.rs); the rest stay ghosts.
    // A reflection fits no tip's offset from its neighbours and sits
    // still while the tree sways; a marker seen between two gaps for less
    // than `confirm_s` is often a tip's own piece, which left among the
    // ghosts made the tip's hole longer than its true gap. Judging only
    // those measured for 0.25 s (a reflection's life, as before) left
    // such pieces of up to 59 samples out: `all`, 11–50 frame fills 2.20
    // → 2.09 mm with every trace judged (PCHIP 2.92; held out 2.35 →
    // 2.15 / 3.01), wrong samples 3 → 3 (389 → 395).
    loose.extend(ghosts);
    loose.sort_by_key(|t| t.id);
    let rejoin::Rejoined {
        traces,
        moved: rejoined,
        loose,
        in_doubt: doubtful,
    } = rejoin::rejoin(traces, loose, &seams, window, one_second(&timeline));
    let n_ghosts = loose.len();
    let (traces, joined_by_rest, joined_into_gaps) = join_pieces(traces, window, &timeline, cfg);
    let (mut kept, mut dropped, noise) = noise::drop_noise(traces, frames, cfg.noise_fraction);
    dropped.sort_by(|a, b| b.measured.cmp(&a.measured).then(a.id.cmp(&b.id)));

    let settings = gaps::GapSettings {
        max_fill_s: cfg.max_fill_s,
        max_pchip_s: cfg.max_pchip_s,
        neighbours: true,
    };
    let mut pool: Vec<Trace> = loose.into_iter().chain(noise).collect();
    // Once every piece has its tip, the samples of two markers in frames
    // where which was which cannot be told go: the tips' gaps there are
    // filled, and `reclaim` does not take them back.
    let given_up = untangle::give_up([&mut kept, &mut pool], &untangled.unsure);
    // So do the pieces two tips would take alike, and those no tip took
    // though one fitted them loosely (rejoin.rs, `in_doubt`, `claimable`).
    let in_doubt = untangle::give_up([&mut kept, &mut pool], &doubtful);
    // Then, found on the tips as the steps above left them, the runs of
    // one to three samples a tip holds alone between two gaps beside
    // another marker or where a hidden one would be (lone.rs).
    let alone = lone::lone_runs(&kept, one_second(&timeline));
    let lone = untangle::give_up([&mut kept], &alone);
    // And the short runs between two gaps far off the course the tip's
    // own samples draw across them (stray.rs).
    let strays = stray::stray_runs(&kept, &timeline);
    let stray = untangle::give_up([&mut kept], &strays);
    let (reclaimed, gap_stats) =
        reclaim::reclaim(&mut kept, &pool, &timeline, settings, cfg.noise_mm / 1000.0);
    drop(pool);

    kept.sort_by_key(|t| (t.first_frame(), t.id));
    let tips = tips_of(kept, window, total, frames, &mut warnings);

    let rest_window_s = [timeline.time(window.start), timeline.time(window.end - 1)];
    let summary = Summary {
        source: source.to_string(),
        frame_rate,
        frames,
        duration_s: duration_of(&timeline),
        tracking: stats,
        traces: n_traces,
        ghosts: n_ghosts,
        joined_on_line,
        adopted,
        untangled: untangled.places,
        given_up,
        in_doubt,
        lone,
        stray,
        joined_by_rest,
        joined_into_gaps,
        rejoined,
        reclaimed,
        dropped,
        noise_fraction: cfg.noise_fraction,
        gaps: gap_stats,
        rest_window_s,
        rest_source: window.source,
        tips: tips.len(),
        warnings,
    };
    let tips = Tips {
        version: 1,
        source: source.to_string(),
        frame_rate,
        rest_window_s,
        tips,
        wind: None,
        timeline,
    };
    (tips, summary)
}

/// Two markers that came closer than twice the gate may have swapped.
fn spacing_warning(stats: &TrackStats, cfg: &TrackingSettings) -> Option<String> {
    let d = stats.closest_spacing_m?;
    Some(format!(
        "two markers came within {:.1} mm of each other: more than half of that is less than \
         the gate ({:.1} mm), so their paths may have swapped; consider a smaller tracking.gate_mm",
        d * 1000.0,
        cfg.gate_mm
    ))
}

/// The recording's length: first to last frame plus one frame interval.
fn duration_of(timeline: &Timeline) -> f64 {
    match (timeline.times.first(), timeline.times.last()) {
        (Some(a), Some(b)) => b - a + timeline.frame_interval().unwrap_or(0.0),
        _ => 0.0,
    }
}

/// The still phase: `tracking.rest_window_s` when set (and inside the
/// recording), else found from the traces, else the whole recording, with
/// a warning naming what the user can do.
fn rest_window(
    cfg: &TrackingSettings,
    traces: &[Trace],
    timeline: &Timeline,
    warnings: &mut Vec<String>,
) -> RestWindow {
    let window = match cfg.rest_window_s.as_slice() {
        [a, b] => {
            let start = timeline.frame_at(*a);
            let end = timeline.frame_at(*b).max(start);
            if end <= start {
                warnings.push(format!(
                    "tracking.rest_window_s [{a}, {b}] lies outside the recording; whole recording used"
                ));
                None
            } else {
                Some(RestWindow {
                    start,
                    end,
                    source: RestSource::Config,
                })
            }
        }
        _ => rest::find_rest_window(traces, timeline, cfg.rest_motion_mm / 1000.0),
    };
    let window = window.unwrap_or(RestWindow {
        start: 0,
        end: timeline.len() as i64,
        source: RestSource::WholeRecording,
    });
    if window.source == RestSource::WholeRecording && cfg.rest_window_s.is_empty() {
        warnings.push(format!(
            "no still phase found (no window where every marker moved less than {} mm): \
             rest positions are means over the whole recording; name the still phase with \
             tracking.rest_window_s",
            cfg.rest_motion_mm
        ));
    }
    window
}

/// Pieces of one marker the tracker could not join on line: joined by rest
/// position, then long pieces without one put into a gap of the marker
/// whose neighbourhood they occupy; (traces, joined by rest, joined into gaps).
fn join_pieces(
    traces: Vec<Trace>,
    window: RestWindow,
    timeline: &Timeline,
    cfg: &TrackingSettings,
) -> (Vec<Trace>, usize, usize) {
    let rests: Vec<Option<DVec3>> = traces
        .iter()
        .map(|t| {
            rest::rest_of(t, window.start, window.end)
                .filter(|r| r.2 >= rest::MIN_REST_SAMPLES)
                .map(|r| r.0)
        })
        .collect();
    let rest_by_id: std::collections::HashMap<usize, bool> = traces
        .iter()
        .zip(&rests)
        .flat_map(|(t, r)| t.pieces.iter().map(move |p| (*p, r.is_some())))
        .collect();
    let (traces, joined_by_rest) =
        noise::join_by_rest(traces, &rests, cfg.merge_radius_mm / 1000.0);
    // After joining by rest, a trace has a rest position if any piece had.
    let has_rest: Vec<bool> = traces
        .iter()
        .map(|t| {
            t.pieces
                .iter()
                .any(|p| rest_by_id.get(p).copied().unwrap_or(false))
        })
        .collect();
    let one_second = one_second(timeline);
    let mut assigner = assign::Assigner::default();
    let (traces, joined_into_gaps) = noise::join_into_gaps(
        traces,
        &has_rest,
        one_second as usize,
        one_second,
        cfg.max_jump_mm / 1000.0,
        &mut assigner,
    );
    (traces, joined_by_rest, joined_into_gaps)
}

/// Frames in one second (100 when the timeline cannot say).
fn one_second(timeline: &Timeline) -> i64 {
    timeline
        .frame_interval()
        .map_or(100, |dt| (1.0 / dt).round().max(1.0) as i64)
}

/// One tip per kept trace, in order of first appearance: its mean over the
/// rest window, or over the whole recording (with a warning) when it has
/// too few samples there.
fn tips_of(
    kept: Vec<Trace>,
    window: RestWindow,
    total: i64,
    frames: u64,
    warnings: &mut Vec<String>,
) -> Vec<Tip> {
    let mut tips = Vec::with_capacity(kept.len());
    for trace in kept {
        let in_window = rest::rest_of(&trace, window.start, window.end)
            .filter(|r| r.2 >= rest::MIN_REST_SAMPLES);
        let (rest, spread, samples) = match in_window {
            Some(r) => r,
            None => {
                warnings.push(format!(
                    "trace {} has fewer than {} samples in the rest window; its rest position \
                     is its mean over the whole recording",
                    trace.id,
                    rest::MIN_REST_SAMPLES
                ));
                rest::rest_of(&trace, 0, total).unwrap_or((trace.last_position(), 0.0, 0))
            }
        };
        let gap_fraction = 1.0 - trace.measured() as f64 / frames.max(1) as f64;
        tips.push(Tip {
            marker: tips.len(),
            rest,
            samples,
            gap_fraction: gap_fraction.clamp(0.0, 1.0),
            spread_m: spread,
            trace,
        });
    }
    tips
}
