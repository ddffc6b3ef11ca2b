//! Accuracy of the marker stage against the simulator's truth (issue 3):
//! tip counts, rest-position error, gap-fill error, identity swaps, on the
//! shipped replays and on 20 generated sessions with fixed seeds.
//!
//! Run with `--nocapture` to see the figures per session and overall.

use std::collections::HashMap;
use std::path::Path;

use treemocap::config::Config;
use treemocap::model::tips::Tips;
use treemocap::model::trace::SampleKind;
use treemocap::sim::{self, CrownShape, SynthOptions, Truth};
use treemocap::track::TrackingSettings;
use treemocap::track::{self, Tracker};

/// What one session scored.
#[derive(Debug, Default)]
struct Score {
    tips_found: usize,
    tips_placed: usize,
    rest_errors: Vec<f64>,
    /// (gap length in frames, mean error over its frames, max error) for
    /// every wind-phase gap that was filled completely.
    fills: Vec<(i64, f64, f64)>,
    wind_gaps: usize,
    /// Samples in a tip's trace that came from another tip's (or a
    /// spurious) column.
    foreign_samples: usize,
    /// Tips whose trace holds samples of more than one true marker.
    impure_tips: usize,
    unmatched_tips: usize,
}

fn score(tips: &Tips, truth: &Truth) -> Score {
    let mut s = Score {
        tips_found: tips.tips.len(),
        tips_placed: truth.tips.len(),
        ..Score::default()
    };
    for tip in &tips.tips {
        // Which true marker each measured sample came from, via its column.
        let mut counts: HashMap<Option<usize>, usize> = HashMap::new();
        for (_, who) in sim::score::owners(&tip.trace, truth) {
            *counts.entry(who).or_default() += 1;
        }
        let Some((&owner, &n)) = counts
            .iter()
            .max_by_key(|(k, n)| (**n, k.map_or(0, |v| v + 1)))
        else {
            continue;
        };
        let total: usize = counts.values().sum();
        if total > n {
            println!(
                "  impure tip {}: samples by true tip {:?}, source runs {:?}",
                tip.marker,
                counts,
                tip.trace.sources()
            );
            s.impure_tips += 1;
            s.foreign_samples += total - n;
        }
        let Some(k) = owner else {
            s.unmatched_tips += 1;
            continue;
        };
        s.rest_errors.push(tip.rest.distance(truth.tips[k].rest));
        // Filled positions against the noiseless truth, per true gap.
        let filled: HashMap<i64, glam::DVec3> = tip
            .trace
            .samples()
            .filter(|x| x.kind == SampleKind::Filled)
            .map(|x| {
                (
                    tips.timeline.source_frame(x.frame).unwrap_or(-1),
                    x.position,
                )
            })
            .collect();
        for g in truth.gaps.iter().filter(|g| g.tip == k) {
            if truth.time_of(g.first_frame) < truth.wind.0 {
                continue;
            }
            s.wind_gaps += 1;
            let errs: Option<Vec<f64>> = (g.first_frame..=g.last_frame)
                .map(|f| {
                    filled
                        .get(&f)
                        .map(|p| p.distance(truth.position(k, truth.time_of(f))))
                })
                .collect();
            if let Some(errs) = errs {
                let mean = errs.iter().sum::<f64>() / errs.len() as f64;
                let max = errs.iter().cloned().fold(0.0, f64::max);
                s.fills.push((g.last_frame - g.first_frame + 1, mean, max));
            }
        }
    }
    s
}

fn run_frames(frames: &[treemocap::MarkerFrame], cfg: &TrackingSettings, rate: f64) -> Tips {
    let mut tracker = Tracker::new(cfg, Some(rate));
    for f in frames {
        tracker.push(f);
    }
    track::clean(tracker.finish(), cfg, "sim", rate).0
}

/// Per-frame-mean errors pooled over gaps in a length range: (gaps, mean of
/// per-gap means weighted by frames, max).
fn pooled(fills: &[(i64, f64, f64)], lo: i64, hi: i64) -> (usize, f64, f64) {
    let sel: Vec<_> = fills.iter().filter(|f| f.0 >= lo && f.0 <= hi).collect();
    let frames: i64 = sel.iter().map(|f| f.0).sum();
    let mean = sel.iter().map(|f| f.1 * f.0 as f64).sum::<f64>() / frames.max(1) as f64;
    let max = sel.iter().map(|f| f.2).fold(0.0, f64::max);
    (sel.len(), mean, max)
}

fn report_and_check(name: &str, all: &[(String, Score)]) {
    let mut rest = Vec::new();
    let mut fills = Vec::new();
    let (mut wind_gaps, mut swaps, mut impure) = (0, 0, 0);
    for (label, s) in all {
        let r_max = s.rest_errors.iter().cloned().fold(0.0, f64::max);
        println!(
            "{label}: tips {}/{} rest max {:.3} mm, wind gaps filled {}/{}, impure tips {} ({} foreign samples)",
            s.tips_found,
            s.tips_placed,
            r_max * 1000.0,
            s.fills.len(),
            s.wind_gaps,
            s.impure_tips,
            s.foreign_samples
        );
        rest.extend_from_slice(&s.rest_errors);
        fills.extend_from_slice(&s.fills);
        wind_gaps += s.wind_gaps;
        swaps += s.foreign_samples;
        impure += s.impure_tips;
    }
    let r_mean = rest.iter().sum::<f64>() / rest.len().max(1) as f64;
    let r_max = rest.iter().cloned().fold(0.0, f64::max);
    let short = pooled(&fills, 1, 10);
    let long = pooled(&fills, 11, 50);
    let longer = pooled(&fills, 51, i64::MAX);
    println!(
        "{name}: rest error mean {:.4} mm max {:.4} mm over {} tips",
        r_mean * 1000.0,
        r_max * 1000.0,
        rest.len()
    );
    println!(
        "{name}: fill error, gaps 1-10 frames: {} gaps, mean {:.3} mm, max {:.3} mm; \
         11-50 frames: {} gaps, mean {:.3} mm, max {:.3} mm; \
         longer: {} gaps, mean {:.3} mm, max {:.3} mm; filled {} of {} wind gaps",
        short.0,
        short.1 * 1000.0,
        short.2 * 1000.0,
        long.0,
        long.1 * 1000.0,
        long.2 * 1000.0,
        longer.0,
        longer.1 * 1000.0,
        longer.2 * 1000.0,
        fills.len(),
        wind_gaps
    );
    println!("{name}: {impure} impure tips, {swaps} samples from another marker");
    for (label, s) in all {
        assert_eq!(s.tips_found, s.tips_placed, "{label}: tip count");
        assert_eq!(s.unmatched_tips, 0, "{label}");
    }
    // Zero identity swaps: every tip's samples come from one true marker.
    assert_eq!(impure, 0, "impure tips");
    assert_eq!(swaps, 0, "samples from another marker");
    assert!(r_max < 0.0005, "rest error max {r_max}");
    assert!(r_mean < 0.0001, "rest error mean {r_mean}");
    assert!(short.0 > 0 && short.1 < 0.001, "short fills {short:?}");
    assert!(long.0 > 0 && long.1 < 0.005, "long fills {long:?}");
    // Most wind-phase gaps get filled (the rest are longer than max_fill).
    assert!(
        fills.len() * 10 >= wind_gaps * 7,
        "{} of {wind_gaps}",
        fills.len()
    );
}

#[test]
fn shipped_replays_match_their_truth() {
    let config = Config::default();
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("replays");
    let mut all = Vec::new();
    for name in ["maple-24", "pine-35"] {
        let csv = root.join(format!("{name}.csv"));
        let truth: Truth =
            serde_json::from_str(&std::fs::read_to_string(sim::truth_path(&csv)).unwrap()).unwrap();
        let mut rec = treemocap::app::open::open_with(
            &csv,
            &treemocap::app::open::ReplayOptions::from_config(&config),
        )
        .unwrap();
        let (tips, summary) = track::process(rec.as_mut(), &config.tracking).unwrap();
        assert!(summary.rest_window_s[0] <= truth.still.0 + 0.5);
        assert!(summary.rest_window_s[1] <= truth.still.1 + 0.5);
        assert!(
            summary.rest_window_s[1] - summary.rest_window_s[0]
                > 0.75 * (truth.still.1 - truth.still.0)
        );
        all.push((name.to_string(), score(&tips, &truth)));
    }
    report_and_check("replays", &all);
}

#[test]
fn twenty_generated_sessions_match_their_truth() {
    let cfg = TrackingSettings::default();
    let mut all = Vec::new();
    let only: Option<u64> = std::env::var("TRACK_SEED")
        .ok()
        .and_then(|s| s.parse().ok());
    for i in 0..20u64 {
        if only.is_some_and(|s| s != 1000 + i) {
            continue;
        }
        let opts = SynthOptions {
            seed: 1000 + i,
            tips: [24, 35, 50, 70][i as usize % 4],
            shape: if i % 2 == 0 {
                CrownShape::Maple
            } else {
                CrownShape::Pine
            },
            frame_rate: if i % 3 == 0 { 240.0 } else { 100.0 },
            still_s: 8.0,
            wind_s: 8.0,
            gap_fraction: 0.05 + 0.10 * (i as f64 / 19.0),
            spurious_per_s: 1.0,
            ..SynthOptions::default()
        };
        let syn = sim::generate(&opts).unwrap();
        // The condition for zero swaps: gate at most half the
        // smallest distance between true markers over the whole session.
        let spacing = treemocap::sim::score::smallest_spacing(&syn.truth);
        let mut cfg = cfg.clone();
        cfg.gate_mm = cfg.gate_mm.min(spacing * 1000.0 / 2.0);
        let tips = run_frames(&syn.frames, &cfg, opts.frame_rate);
        let label = format!(
            "seed {} {:?} {} tips {} Hz gaps {:.0} % spacing {:.1} mm gate {:.1} mm",
            opts.seed,
            opts.shape,
            opts.tips,
            opts.frame_rate,
            opts.gap_fraction * 100.0,
            spacing * 1000.0,
            cfg.gate_mm
        );
        all.push((label, score(&tips, &syn.truth)));
    }
    report_and_check("generated", &all);
}
