//! Issue 14's gap-filling targets on synthetic sessions with truth: in
//! the wind phase, the marker stage's fills are compared with PCHIP on the
//! true marker's own samples (perfect identity, same gaps). Gaps of 11–50
//! frames and of 51 frames–2 s: mean error at most 0.7 × PCHIP's (issue
//! 14's target), with the base noise (0.2 mm: 0.38 × and 0.35 × here) and
//! with noise σ 1 mm (0.61 × and 0.30 ×); 1–10 frames: never worse, and
//! with noise σ 1 mm at most 0.8 × (0.48 × here: the ends fitted over
//! 0.15 s instead of PCHIP's two noisy samples). No fill bridges two
//! markers, and every filled sample is flagged as filled.

use crate::common::fills;
use treemocap::model::trace::SampleKind;
use treemocap::sim::{self, score, stress};
use treemocap::track::{self, Tracker, TrackingSettings};

/// Tracks and cleans two seeds of a 30-tip session with long occlusions
/// (0.3–1.8 s, so the 51 f–2 s bin has gaps) and `noise_mm` of noise;
/// checks the flags and that the neighbours filled some gaps; returns the
/// merged score.
fn sessions(noise_mm: f64) -> score::Score {
    let mut total = score::Score::default();
    for seed in [14, 15] {
        let opts = sim::SynthOptions {
            long_gaps: Some(10),
            long_gap_min_s: 0.3,
            long_gap_max_s: 1.8,
            noise_mm,
            ..stress::base(seed, 30, 4.0, 12.0)
        };
        let syn = sim::generate(&opts).unwrap();
        let cfg = TrackingSettings::default();
        let mut tracker = Tracker::new(&cfg, Some(opts.frame_rate));
        for f in &syn.frames {
            tracker.push(f);
        }
        let (tips, summary) = track::clean(tracker.finish(), &cfg, "sim", opts.frame_rate);
        // Fills stay flagged: as many filled samples as the summary filled.
        let flagged: u64 = tips
            .tips
            .iter()
            .map(|t| {
                t.trace
                    .samples()
                    .filter(|s| s.kind == SampleKind::Filled)
                    .count() as u64
            })
            .sum();
        assert_eq!(flagged, summary.gaps.filled_frames, "seed {seed}");
        assert!(summary.gaps.from_neighbours > 0, "seed {seed}: {summary}");
        total.merge(&score::score(&tips, &syn));
    }
    total
}

/// Asserts each bin's share filled and our error against `limits` ×
/// PCHIP's (1–10, 11–50, 51 f–2 s).
fn check_bins(total: &score::Score, limits: [f64; 3]) {
    assert_eq!(total.bridged, 0, "fills bridging two markers");
    for (b, limit) in fills::bins(total).into_iter().zip(limits) {
        b.assert_filled(90, 3);
        b.assert_within(limit, 1e-6);
    }
}

#[test]
fn fills_beat_pchip_on_gaps_over_ten_frames_and_match_it_below() {
    // Never worse on 1–10, 0.7 × on 11–50 and on 51 f–2 s.
    check_bins(&sessions(0.2), [1.0, 0.7, 0.7]);
}

#[test]
fn under_noise_of_a_millimetre_fills_beat_pchip_on_every_gap_length() {
    // 1–10 frames: the ends fitted over 0.15 s instead of PCHIP's two
    // noisy samples (PCHIP itself before: 1.0 ×, which failed here);
    // 11–50 and 51 f–2 s: the target.
    check_bins(&sessions(1.0), [0.8, 0.7, 0.7]);
}

/// All of issue 14's stresses combined (noise σ 1 mm, ghosts, 25 %
/// occluded, sway and gusts up to 150 mm, close pairs) on a 30-tip
/// session: on the gaps whose tip holds the true marker's samples on both
/// sides (the fill model's own error; the others lie in holes the tracker
/// left longer than the true gap, see the README), the fills meet issue
/// 14's target: 1–10 frames better than PCHIP with perfect identity (the
/// ends fitted, not PCHIP's two noisy samples: 1.0 × on main's build),
/// 11–50 frames at most 0.7 ×. Over every gap, the others included, it
/// holds too (0.82 × and 0.65 ×).
#[test]
fn under_all_stresses_combined_fills_beside_the_true_marker_meet_the_target() {
    let mut total = score::Score::default();
    for seed in [14, 15] {
        let st = stress::named(&stress::base(seed, 30, 4.0, 10.0), "all").unwrap();
        let syn = sim::generate(&st.options).unwrap();
        let cfg = TrackingSettings::default();
        let mut tracker = Tracker::new(&cfg, Some(240.0));
        for f in &syn.frames {
            tracker.push(f);
        }
        let (tips, _) = track::clean(tracker.finish(), &cfg, "sim", 240.0);
        total.merge(&score::score(&tips, &syn));
    }
    for ((lo, hi), limit) in score::fill_bins(240.0).into_iter().zip([0.85, 0.7]) {
        let (n, ours, pchip, med_ours, med_pchip) = total.fill_bin_split(lo, hi, true);
        let (others, ..) = total.fill_bin_split(lo, hi, false);
        println!(
            "gaps {lo}-{hi} frames beside the true marker: {n} ({others} others), mean {:.3} mm (PCHIP {:.3}), median {:.3} ({:.3})",
            ours * 1000.0,
            pchip * 1000.0,
            med_ours * 1000.0,
            med_pchip * 1000.0
        );
        // The others (on this short session 4 of 254 short gaps, 24 of
        // 817 of 11–50 frames) are the identity's error, not the fill's:
        // their tip lacks the marker's samples beside the gap (a longer
        // hole) or holds another marker's there.
        assert!(n >= 20, "{lo}-{hi}: {n} gaps beside the true marker");
        assert!(
            ours <= limit * pchip + 1e-6,
            "{lo}-{hi}: {ours} > {limit} × PCHIP {pchip}"
        );
        let (_, _, every, pchip_every) = total.fill_bin(lo, hi);
        let limit = if lo == 1 { 1.0 } else { 0.7 };
        println!(
            "gaps {lo}-{hi} frames, every one: mean {:.3} mm (PCHIP {:.3})",
            every * 1000.0,
            pchip_every * 1000.0
        );
        assert!(
            every <= limit * pchip_every + 1e-6,
            "{lo}-{hi}, every gap: {every} > {limit} × PCHIP {pchip_every}"
        );
    }
}
