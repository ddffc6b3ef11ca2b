//! Issue 14's targets on short stress sessions (the full sweep is
//! `examples/track_stress.rs`): every stress alone and all combined give
//! the exact tip count, no sample of another tip or of a ghost in any tip,
//! one output tip per true tip, rest error < 0.5 mm, no fill bridging two
//! markers, and fills from the neighbours at least as good as PCHIP with
//! perfect identity.

use crate::common::fills;
use treemocap::sim::{self, score, stress};
use treemocap::track::{self, Tracker, TrackingSettings};

/// The stress named `name` on the sweep's session of `seed` (70 tips at
/// 240 Hz, 8 s still, 20 s of wind: `examples/track_stress.rs`).
fn sweep_stress(name: &str, seed: u64) -> stress::Stress {
    stress::named(&stress::base(seed, 70, 8.0, 20.0), name).unwrap()
}

/// The session tracked and cleaned as `replay` does, scored against its
/// truth.
fn scored(opts: &sim::SynthOptions) -> score::Score {
    let syn = sim::generate(opts).unwrap();
    let noise_mm = TrackingSettings::default().noise_mm;
    scored_under(&syn, opts.frame_rate, noise_mm).0
}

/// Session `syn` (at `frame_rate`) tracked and cleaned as `replay` does
/// with `tracking.noise_mm` set to `noise_mm`, scored against its truth,
/// with the cleaning's summary.
fn scored_under(
    syn: &sim::Synthetic,
    frame_rate: f64,
    noise_mm: f64,
) -> (score::Score, track::Summary) {
    let cfg = TrackingSettings {
        noise_mm,
        ..TrackingSettings::default()
    };
    let mut tracker = Tracker::new(&cfg, Some(frame_rate));
    for f in &syn.frames {
        tracker.push(f);
    }
    let (tips, summary) = track::clean(tracker.finish(), &cfg, "sim", frame_rate);
    (score::score(&tips, syn), summary)
}

/// Prints session `name`'s score and asserts the exact tip count and one
/// output tip per true tip.
fn one_tip_per_tip(name: &str, s: &score::Score) {
    println!(
        "{name}: tips {}/{} wrong {} fragments {} missed {} rest max {:.3} mm bridged {}",
        s.tips_found,
        s.tips_placed,
        s.wrong_samples,
        s.fragments,
        s.missed_tips,
        s.rest_max() * 1000.0,
        s.bridged
    );
    assert_eq!(s.tips_found, s.tips_placed, "{name}: tip count");
    assert_eq!(
        (s.fragments, s.missed_tips),
        (0, 0),
        "{name}: one tip per tip"
    );
}

fn check(name: &str, opts: &sim::SynthOptions) -> score::Score {
    let s = scored(opts);
    one_tip_per_tip(name, &s);
    assert_eq!(s.wrong_samples, 0, "{name}: samples of another marker");
    assert!(s.rest_max() < 0.0005, "{name}: rest error {}", s.rest_max());
    assert_eq!(s.bridged, 0, "{name}: fills bridging two markers");
    s
}

/// Each stress alone (all of them combined, on the sweep's sessions:
/// the README's tables from examples/track_stress.rs, and the `all`
/// cases below).
#[test]
fn every_stress_alone_holds_on_a_short_session() {
    let base = stress::base(14, 30, 4.0, 8.0);
    for st in stress::all(&base).into_iter().filter(|s| s.name != "all") {
        let s = check(st.name, &st.options);
        for (lo, hi) in score::fill_bins(240.0) {
            let (gaps, filled, ours, pchip) = s.fill_bin(lo, hi);
            println!(
                "  gaps {lo}-{hi} frames: {filled}/{gaps} filled, mean error {:.3} mm (PCHIP, perfect identity: {:.3} mm)",
                ours * 1000.0,
                pchip * 1000.0
            );
        }
    }
}

/// A tip at the turn of its swing sits still while its neighbours move
/// on, and looked like a reflection: `occlusion` with the long gaps,
/// seed 100, tip 30 seen for 5, 5 and 23 frames in a gap of 0.65 s,
/// each piece given to no tip and the gap filled from 156 frames (239
/// of the tips' own samples filled on this seed). A piece that continues
/// the tip's pieces on both sides stays with it, and the short gaps are
/// filled as well as PCHIP fills them with perfect identity.
#[test]
fn a_tip_at_the_turn_of_its_swing_keeps_its_own_marker() {
    let st = sweep_stress("occlusion", 100);
    let s = check("occlusion, long gaps", &stress::long_gaps(st.options));
    let own = s.own_filled.len();
    println!("occlusion, long gaps, seed 100: {own} of the tips' own samples filled");
    assert!(own <= 50, "{own} of the tips' own samples filled");
    let (_, _, ours, pchip) = s.fill_bin(1, 10);
    assert!(
        ours <= pchip,
        "gaps of 1-10 frames: {:.3} mm against PCHIP's {:.3}",
        ours * 1000.0,
        pchip * 1000.0
    );
}

/// Noise σ 1 mm, twice the `noise_mm` the filters are told, on the
/// sweep's 70-tip session of seed 101: the still phase is found despite the
/// noise, because it allows 3 σ of the noise the tracker measures on the
/// capture (third differences of the traces). Before, every 2 s window had
/// some marker whose noise passed `rest_motion_mm`, the whole take was
/// averaged and a rest position came out 9.2 mm off.
#[test]
fn the_still_phase_is_found_under_noise_above_noise_mm() {
    let st = sweep_stress("noise", 101);
    check("noise, seed 101", &st.options);
}

/// Ten close pairs passing within a few mm on the sweep's 70-tip session
/// of seed 104: every tip keeps its identity. Before, a tip hidden while
/// its pair swung towards each other kept coasting on its own
/// extrapolation, ran into its partner's marker and took it (71 tips, one
/// holding two); a coasting trace near another marker now ends once its
/// neighbours put it elsewhere (docs/tracking.md §4a).
#[test]
fn close_pairs_keep_their_identities_through_a_gap() {
    let st = sweep_stress("close", 104);
    check("close, seed 104", &st.options);
}

/// Close pairs on a seed held out of the tuning (109): every tip keeps its
/// identity. Before, the tracker gave tip 66's identity 72 samples of its
/// partner tip 8 (0.3 s fitting both tips' offsets) and then tip 66's own
/// marker for 1.7 s in the same frames; the later piece was dropped as a
/// ghost and the 72 samples stayed in tip 66, and a 93-sample piece of tip
/// 37 between two hidden stretches, never confirmed on line, was dropped
/// (its 4-frame gap filled 52 mm off). Both are now judged after the
/// session by their offset from their neighbours like any piece
/// (src/track/rejoin.rs).
#[test]
fn close_pairs_keep_their_identities_on_a_held_out_seed() {
    let st = sweep_stress("close", 109);
    let s = check("close, seed 109", &st.options);
    let (_, _, ours, pchip) = s.fill_bin(1, 10);
    assert!(
        ours <= pchip * 1.0001,
        "1–10 frames {ours} against PCHIP {pchip}"
    );
}

/// A tip hidden for about 45 frames in a gust comes back 55–121 mm from
/// where its neighbours' motion puts it: on line it became a second tip,
/// and its lost identity took another tip's marker seconds later (seed
/// 102: 71 tips, 1 569 samples of tip 20 in tip 39's; strong sway, seed
/// 102: 74 tips, 1 354 wrong samples). After the session every piece the
/// tracker joined across a gap is judged again by its mean offset from its
/// neighbours over the whole piece and by how its ends continue the tip's
/// pieces next to it (docs/tracking.md §4a), so every tip is one tip again.
#[test]
fn a_tip_hidden_in_a_gust_is_joined_to_its_own_identity_after_the_session() {
    let base = stress::base(102, 70, 8.0, 20.0);
    for st in stress::all(&base)
        .into_iter()
        .filter(|s| s.name == "gusts" || s.name == "sway")
    {
        check(&format!("{}, seed 102", st.name), &st.options);
    }
}

#[test]
fn rest_window_is_on_the_time_column_when_the_take_starts_late() {
    // A take exported from frame 1000 on, its Time column starting at 0:
    // `rest_window_s = [0, 1.8]` is the still phase on that clock.
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("late.csv");
    let opts = sim::SynthOptions {
        seed: 5,
        tips: 8,
        still_s: 2.0,
        wind_s: 2.0,
        ..Default::default()
    };
    treemocap::app::synth::write_session(&opts, &csv).unwrap();
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut shifted = String::new();
    let mut data = false;
    for line in text.lines() {
        if data {
            let (frame, rest) = line.split_once(',').unwrap();
            let f: i64 = frame.parse().unwrap();
            shifted.push_str(&format!("{},{rest}\n", f + 1000));
        } else {
            shifted.push_str(line);
            shifted.push('\n');
            data = line.starts_with("Frame,Time");
        }
    }
    std::fs::write(&csv, shifted).unwrap();
    let truth: sim::Truth =
        serde_json::from_str(&std::fs::read_to_string(sim::truth_path(&csv)).unwrap()).unwrap();
    let mut config = treemocap::config::Config::default();
    config.tracking.rest_window_s = vec![0.0, 1.8];
    let mut rec = treemocap::app::open::open_recording(&csv, &config).unwrap();
    let (tips, summary) = track::process(rec.as_mut(), &config.tracking).unwrap();
    assert_eq!(summary.rest_source, track::RestSource::Config);
    assert!(
        summary.warnings.iter().all(|w| !w.contains("outside")),
        "{:?}",
        summary.warnings
    );
    assert_eq!(tips.tips.len(), 8);
    for t in &tips.tips {
        let best = truth
            .tips
            .iter()
            .map(|k| k.rest.distance(t.rest))
            .fold(f64::INFINITY, f64::min);
        assert!(best < 0.0005, "rest error {best}");
    }
}

/// Every stress combined (`all`: sway up to 150 mm, gusts, 10 ghosts/s,
/// noise σ 1 mm, 25 % occluded, close pairs) on the sweep's 70-tip
/// sessions of seeds 100–102: every true tip is found once, no more tips
/// than markers, and every rest position within 0.5 mm. Before, 203 of
/// 210 were found and 4 rest positions were 14–18 mm off: under that noise
/// a still marker's trace ends at every gap of more than about 20 frames,
/// and some markers were never seen for `confirm_s` in a row in the whole
/// still phase, so they were dropped as ghosts. A still marker's pieces at
/// one place now count together towards its confirmation
/// (docs/tracking.md §2). Samples of another tip remain on `all` (3 on
/// these seeds, README); more than 6 fail: there were 236 before ghosts
/// measured for 0.25 s and an identity's pieces sharing frames were judged
/// by their neighbours after the session (113), before the seams alone
/// could take a piece from a tip its mean offset fits best (12), and
/// before a piece whose own tip's mean fits it worse than another's, or
/// whose ends miss its tip's pieces, stopped staying there by default (3).
///
/// The fills of all the true gaps in the wind phase, whatever the tracker
/// left around them, against PCHIP with perfect identity: 11–50 frames at
/// most 0.7 × (issue 14's target; measured 2.00 / 2.92 = 0.68 ×), 1–10
/// frames at most 0.8 × (1.13 / 1.50 = 0.75 ×). Before the samples the tracker left in
/// no tip were taken back into the gaps (`src/track/reclaim.rs`) they were
/// 0.87 × and 0.89 ×: the tip's hole was longer than the marker's gap;
/// before every trace never confirmed was judged by its neighbours, and
/// one near a single tip given to it while it moves (`src/track/
/// rejoin.rs`), 0.75 × and 0.81 ×.
#[test]
fn every_tip_is_found_once_with_its_rest_position_under_all_stresses() {
    let mut wrong = 0;
    let mut total = score::Score::default();
    for seed in 100..103 {
        let s = scored(&sweep_stress("all", seed).options);
        one_tip_per_tip(&format!("all, seed {seed}"), &s);
        assert!(
            s.rest_max() < 0.0005,
            "all, seed {seed}: rest error {}",
            s.rest_max()
        );
        wrong += s.wrong_samples;
        total.merge(&s);
    }
    assert!(
        wrong <= 6,
        "all, seeds 100–102: {wrong} samples of another tip"
    );
    for (b, limit) in fills::bins(&total).into_iter().zip([0.8, 0.7]) {
        b.assert_filled(99, 0);
        b.assert_within(limit, 0.0);
    }
}

/// All stresses on two seeds held out of the tuning, where a piece of a
/// tip was given to another after the session (docs/tracking.md §3 step 4):
/// seed 105, 121 samples moved to a tip 165 mm away whose own pieces next
/// to it were not placed yet when it was judged (now every piece is judged
/// a second time with all the others placed); seed 103, 98 samples kept in
/// another tip's hole of 3 s, where no seam could speak against them,
/// while their own tip's seams fitted (now a fitting seam speaks for a
/// tip). 136 and 111 samples of another tip before, 15 and 13 after, 14
/// and 13 since the seams are judged on the positions (a piece moved by
/// its mean alone, a 13-sample one whose tip was out of reach).
#[test]
fn a_piece_is_judged_with_its_neighbours_in_time_placed_on_held_out_seeds() {
    for seed in [103, 105] {
        let s = scored(&sweep_stress("all", seed).options);
        println!(
            "all, seed {seed}: tips {}/{} wrong {} fragments {}",
            s.tips_found, s.tips_placed, s.wrong_samples, s.fragments
        );
        assert_eq!(s.tips_found, s.tips_placed, "all, seed {seed}: tip count");
        assert!(
            s.wrong_samples <= 20,
            "all, seed {seed}: {} samples of another tip",
            s.wrong_samples
        );
    }
}

/// All stresses on seed 112, first looked at when the seams were judged
/// on the positions (docs/tracking.md §3 step 4): in a gust tip 56's
/// marker came back 35 frames after a gap as a new identity. Its offset from
/// its neighbours swung 40 mm off its mean, and the offsets, taken 20
/// times a second, missed the seam, so its last 1 886 samples became a
/// 71st tip. Carried across the gap on its positions at 240 Hz, the piece
/// continues its tip and every tip is one output tip.
#[test]
fn a_marker_back_in_a_gust_as_a_new_identity_joins_its_tip() {
    let s = scored(&sweep_stress("all", 112).options);
    one_tip_per_tip("all, seed 112", &s);
}

/// A marker hidden for a few frames in the wind that comes back as a new
/// trace and is hidden again before that trace is confirmed (13 samples
/// between gaps of 8 and 32 frames on `sway` seeds 101 and 102, 108
/// samples between 37 and 8 on `close` seed 100): the piece is the
/// marker's, since the motion at both edges of the short gap carries one
/// to the other (src/track/adopt.rs), so the short gap is filled as
/// itself. Before, the piece was dropped as a ghost and the 8 frames were
/// filled as part of a gap of 53 or 153 (2.3 mm off where PCHIP with
/// perfect identity is 0.3 mm): the gaps of 1–10 frames were worse than
/// PCHIP's. Every gap of 1–10 frames is now within 0.5 mm of PCHIP's
/// error, and all of them together no worse.
#[test]
fn a_marker_seen_between_two_gaps_keeps_its_short_gap() {
    for (name, seed) in [("sway", 101), ("sway", 102), ("close", 100)] {
        let st = sweep_stress(name, seed);
        let s = check(&format!("{name}, seed {seed}"), &st.options);
        let (mut ours, mut pchip) = (0.0, 0.0);
        for f in s.fills.iter().filter(|f| f.len <= 10) {
            let (Some(o), Some(p)) = (f.ours, f.pchip) else {
                continue;
            };
            assert!(
                o <= p + 0.0005,
                "{name}, seed {seed}: a gap of {} frames filled {:.2} mm off (PCHIP {:.2} mm)",
                f.len,
                o * 1000.0,
                p * 1000.0
            );
            ours += o * f.len as f64;
            pchip += p * f.len as f64;
        }
        assert!(
            ours <= pchip * 1.0001,
            "{name}, seed {seed}: 1–10 frames {ours} against PCHIP {pchip}"
        );
    }
}

/// Two tips passing within their noise of each other under every stress
/// at once (`all`, seed 101, both `noise_mm` settings): in one frame the
/// two markers were too close for either way round to be likelier, and
/// the tracker's choice there put one sample of each tip in the other
/// (2 wrong samples). Both samples are given up, and the tips' one-frame
/// gaps filled: no tip holds another's sample, and little else is given
/// up (since session 50, the samples of two close markers at log odds
/// down to −6, and those within 4 mm that cannot be weighed: 12 and 12
/// samples, 6 frames of two markers within a few millimetres, where 2
/// each were given up at −2 alone; since session 56, those within 8 mm
/// that cannot be weighed: 24 under the default `noise_mm`).
#[test]
fn samples_too_close_to_tell_apart_are_given_up_not_exchanged() {
    let st = sweep_stress("all", 101);
    let syn = sim::generate(&st.options).unwrap();
    for noise_mm in [TrackingSettings::default().noise_mm, 1.5] {
        let (s, summary) = scored_under(&syn, st.options.frame_rate, noise_mm);
        let name = format!("all, seed 101, noise_mm {noise_mm}");
        one_tip_per_tip(&name, &s);
        assert_eq!(s.wrong_samples, 0, "{name}: samples of another marker");
        assert!(
            (1..=32).contains(&summary.given_up),
            "{name}: {} samples given up",
            summary.given_up
        );
    }
}

/// Two tips' markers where both tips' neighbours say their tip is, both
/// hidden or one swinging off its neighbours' path to pass the other:
/// `all` seed 203, 86 samples of tip 24 in tip 64's identity, both tips
/// hidden for over a second around them (whole cost 16.2 there, 37.7 at
/// tip 24); seed 410, 36 samples of tip 45 in tip 68's (0.9 there, 21.3
/// at tip 45). A piece another tip takes about as well is left to no tip
/// in its round; once the other pieces are placed it may have one tip
/// left to go to (seed 410), else it is given up and its tip's gap
/// filled (seed 203): no sample of another marker, and little given up
/// (the count includes the pieces no tip takes, given up as well: 795
/// and 1 290 samples here, of some 360 000 in a session).
#[test]
fn a_piece_two_tips_fit_alike_is_given_up_not_placed() {
    let noise_mm = TrackingSettings::default().noise_mm;
    held_giving_up_little(&[(203, noise_mm), (410, noise_mm)]);
}

/// A piece of a close pair's partner that no tip takes, though a tip fits
/// it loosely, was left among the loose samples, and the walk that takes
/// such samples back into a tip's gap (`reclaim`) carried it into the
/// gap of whichever tip's last sample it continued: `all` seed 390, 35
/// samples of tip 62 in tip 39's gap (40 under `noise_mm` 1.5); seed 115,
/// 30 samples of another marker. Given up instead, the tips' gaps there
/// are filled from the neighbours: no sample of another marker, and
/// about a thousand samples given up in a session of some 360 000.
#[test]
fn a_piece_no_tip_takes_is_given_up_not_walked_into_a_gap() {
    let noise_mm = TrackingSettings::default().noise_mm;
    held_giving_up_little(&[(390, noise_mm), (390, 1.5), (115, noise_mm)]);
}

/// A long piece of a tip's marker the last round of placing found its tip
/// busy for, busy with a short piece that round then moved off: left to
/// no tip, 65 of its samples were walked into a close partner's gap (`all`
/// seed 296, a piece of 584 samples, the short one of 23). The pieces left
/// without a tip are judged once more with every other where the last
/// round put it: every tip's samples its own, no fill bridging two markers.
#[test]
fn a_piece_a_later_one_kept_from_its_tip_is_judged_again() {
    held_under_all(&[(296, TrackingSettings::default().noise_mm)]);
}

/// Two traces began 3 frames before their markers passed 4.2 mm apart,
/// and the tracker exchanged the two for one frame there: the straight
/// line through those 4 samples of the vector between the markers, bent
/// by the exchange, called the crossing a swap, and the traces' tails
/// were swapped (`all` seed 230: 16 samples of tip 61 in tip 52 under
/// both `noise_mm`). A swap of the tails is now looked for only where a
/// parabola fits each side: no sample of another marker.
#[test]
fn a_crossing_judged_on_four_samples_is_not_swapped() {
    held_under_all(&[(230, TrackingSettings::default().noise_mm), (230, 1.5)]);
}

/// A marker hidden for longer than the trace beside it still meets the
/// trace's gap where it was last seen near where the trace went on, however
/// long before the gap (up to 0.1 s): on `all` seed 353 tip 67's trace,
/// hidden for 15 frames, went on with tip 25's marker 3.9 mm from where it
/// had left off, and tip 25's own run had ended 18 frames before the gap,
/// 16.7 mm from there. Only a run ending 8 frames or less before the gap
/// met it by place: 7 samples of tip 25 stayed in tip 67.
#[test]
fn a_marker_hidden_before_a_gap_and_near_where_the_trace_went_on_meets_it() {
    held_under_all(&[(353, TrackingSettings::default().noise_mm)]);
}

/// A run of one to three samples a tip holds alone between two gaps,
/// beside another tip's marker, is given up and its gap filled: under
/// every stress at once, `all` seed 335, one sample of each of tips 48
/// and 60 was exchanged 3.6 mm apart between gaps of 2 and 7 frames.
/// Both go, and few others do: a run with no other marker near is the
/// tip's own. Since session 56 `untangle` gives them up first (the two
/// markers' vector cannot be weighed there, and they are measured within
/// 8 mm), so the samples given up by either step are counted.
#[test]
fn a_run_held_alone_between_two_gaps_beside_another_marker_is_given_up() {
    held_giving_up(
        &at_default_noise(&[335]),
        "held alone or where two markers could not be told apart",
        |s| s.lone + s.given_up,
        2..=100,
    );
}

/// A run of one or two samples a tip holds alone between two gaps, where
/// no marker is measured near but a tip hidden across it would be, by
/// its neighbours' motion, about as near as the tip's own: `all` seed
/// 216, one sample of tip 60's marker, hidden from 13 frames before to
/// 30 after, in tip 3's gap 6 mm from where tip 3 was; seed 331, one of
/// tip 65's in tip 26's gap, the two 2.1 mm apart. Each goes, and few
/// others do: with no partner hidden near the run is the tip's own.
#[test]
fn a_run_alone_where_a_hidden_partner_would_be_is_given_up() {
    held_giving_up(
        &at_default_noise(&[216, 331]),
        "held alone",
        |s| s.lone,
        1..=100,
    );
}

/// The last samples of a tip's run before its gap, measured in exactly
/// the frames another tip's marker went missing: `all` seed 363, tips 49
/// and 68 4.5 mm apart, tip 49 hidden from frame 4 941, and its trace
/// held tip 68's marker in 4 941 and 4 942, the two frames tip 68's own
/// trace missed. The pair's vector cannot be weighed beside the missing
/// frames and the markers are measured within 8 mm, so `untangle` gives
/// them up and both gaps are filled; few others go.
#[test]
fn a_runs_end_in_the_frames_another_marker_went_missing_is_given_up() {
    held_giving_up(
        &at_default_noise(&[363]),
        "where two markers could not be told apart",
        |s| s.given_up,
        2..=100,
    );
}

/// A reflection sitting still where a tip was hidden, taken for the tip
/// for a few frames with no other marker near and no tip hidden about it:
/// `all` seed 126, four samples between gaps of 30 and 9 frames in tip
/// 45's; seed 301, one between gaps of 10 and 31 in tip 1's. The course
/// the tip's own samples draw across the whole gap misses them by 25.7
/// and 28.7 mm; they are given up and the gaps filled.
#[test]
fn a_reflection_off_the_tips_course_across_its_gap_is_given_up() {
    held_giving_up(
        &at_default_noise(&[126, 301]),
        "off the tip's own course",
        |s| s.stray,
        1..=10,
    );
}

/// Two samples of one hidden tip the tracker gave to another, hidden
/// too, as the two passed: `all` seed 191, tip 9 seen at frames 5 286 and
/// 5 287 in a gap of 0.4 s, 8.3 mm from tip 62, itself hidden for 22
/// frames. The run lies 8.8 mm off tip 62's own course across its gap,
/// farther than 99 % of such courses miss, and within what tip 9's course
/// across its gap misses by; either could own it, and it is given up.
#[test]
fn a_run_either_of_two_hidden_tips_could_own_is_given_up() {
    held_giving_up(
        &at_default_noise(&[191]),
        "off the tip's own course",
        |s| s.stray,
        1..=10,
    );
}

/// A sample the tracker held right that `untangle` read as turned round
/// on weak odds: `all` seed 121, tips 0 and 69 3 mm apart at frame 6 426,
/// measured 1.8 mm apart, turned at log odds 3.5. Samples turned at odds
/// under 6 are given up with the unsure ones.
#[test]
fn a_sample_turned_round_on_weak_odds_is_given_up() {
    held_giving_up(
        &at_default_noise(&[121]),
        "where two markers could not be told apart",
        |s| s.given_up,
        2..=100,
    );
}

/// Two tips' markers came back from their gaps together and passed
/// closer than their noise tells, before the vector between them could be
/// weighed: `all` seed 278, tips 50 and 69 came back in the same frame
/// 4.9 mm apart and passed 2.4 mm apart, each new trace on the other's
/// marker until the tracker swapped them at their closest (measured 3.8–7.1
/// mm apart); seed 243, tips 28 and 63 came back 1 and 3 frames before
/// they passed 2.8 mm apart and their traces were swapped 3 frames after.
/// Both markers' samples there are given up and the gaps filled.
#[test]
fn markers_that_came_back_together_within_their_noise_are_given_up() {
    held_giving_up(
        &at_default_noise(&[243, 278]),
        "where two markers could not be told apart",
        |s| s.given_up,
        1..=200,
    );
}

/// Each of `seeds` with the tracker's default `noise_mm`: the cases
/// [`held_giving_up`] takes.
fn at_default_noise(seeds: &[u64]) -> Vec<(u64, f64)> {
    let noise_mm = TrackingSettings::default().noise_mm;
    seeds.iter().map(|&seed| (seed, noise_mm)).collect()
}

/// [`held_under_all`], and each case gives up some samples of pieces in
/// doubt, but no more than 3 000 (under 1 % of a session's).
fn held_giving_up_little(cases: &[(u64, f64)]) {
    held_giving_up(cases, "of pieces in doubt", |s| s.in_doubt, 1..=3_000);
}

/// [`held_under_all`], and each case gives up a number of samples in
/// `range`, counted by `given` (`what` names them in the messages).
fn held_giving_up(
    cases: &[(u64, f64)],
    what: &str,
    given: fn(&track::Summary) -> usize,
    range: std::ops::RangeInclusive<usize>,
) {
    for (summary, (seed, noise_mm)) in held_under_all(cases).iter().zip(cases) {
        let n = given(summary);
        println!("all, seed {seed}, noise_mm {noise_mm}: {n} samples {what} given up");
        assert!(
            range.contains(&n),
            "all, seed {seed}, noise_mm {noise_mm}: {n} samples {what} given up"
        );
    }
}

/// Runs the `all` stress of each (seed, `noise_mm`) and asserts what a
/// mended case must show: one output tip per true tip, no sample of
/// another marker in any tip, and no fill bridging two markers. Returns
/// each case's cleaning summary, for what a test asks besides.
fn held_under_all(cases: &[(u64, f64)]) -> Vec<track::Summary> {
    cases
        .iter()
        .map(|&(seed, noise_mm)| {
            let st = sweep_stress("all", seed);
            let syn = sim::generate(&st.options).unwrap();
            let (s, summary) = scored_under(&syn, st.options.frame_rate, noise_mm);
            let name = format!("all, seed {seed}, noise_mm {noise_mm}");
            one_tip_per_tip(&name, &s);
            assert_eq!(s.wrong_samples, 0, "{name}: samples of another marker");
            assert_eq!(s.bridged, 0, "{name}: fills bridging two markers");
            summary
        })
        .collect()
}

/// Two tips passing 1 mm apart under every stress at once (`all`, seed
/// 140): tip 61's marker was hidden for 3 frames as tip 52's came back
/// beside it, and the tracker went on with tip 52's marker in tip 61's
/// trace; tip 61's own came back 7 frames later as a trace of its own,
/// its line reaching back to where the first had left off. Cut there
/// (the gap is shorter than the 6 frames a meet needed before), each
/// piece goes to its tip: 43 samples of tip 52 in tip 61 before, and 135
/// of tip 61 in no tip. On held-out seed 338 under `noise_mm` 1.5 a
/// trace went on with tip 67's marker across 2 frames, and a run whose
/// line reached it began 16 frames later: the piece before the gap,
/// tip 29's, goes back to tip 29 only when that cut is as firm as a near
/// one (22 samples of tip 29 in tip 67 otherwise).
#[test]
fn a_trace_going_on_with_a_passing_marker_across_a_short_gap_is_cut_there() {
    held_under_all(&[(140, TrackingSettings::default().noise_mm), (338, 1.5)]);
}

/// In a gust a tip's offset from its neighbours drifts away from the one
/// learnt for it, and another tip's marker can sit where it drifted from:
/// the pieces then fit the wrong tips' means, and only the seams, how each
/// piece continues the pieces before and after it, tell them apart.
/// Held-out `all` seed 316: tip 33's marker, 57 samples, in tip 69's
/// identity (mean 5.2 there, 13.5 at its own tip, whose pieces it
/// continues on both sides) and 12 samples of tip 69's in tip 33's: 75
/// wrong samples, 57 under `noise_mm` 1.5. Seed 178 under `noise_mm` 1.5:
/// 15 samples of tip 10 in tip 63's identity, its seams there missing.
#[test]
fn a_tip_whose_offset_drifted_gets_its_marker_back_by_its_seams() {
    held_under_all(&[(316, TrackingSettings::default().noise_mm), (178, 1.5)]);
}

/// A reflection of a few dozen samples sits still but for its noise, and
/// its noise is measured from as few samples: `all` seed 227, 21 samples
/// spreading 1.33 times their noise, in tip 24's gap of 2.9 s, 32.4 mean
/// cost there (tip 24's offset spreads 49 mm); seed 242, 8 samples in tip
/// 22's gap of 27 frames, both seams missing. Seed 185: tip 65's own
/// marker, 11 samples turning while its neighbours moved on, quiet by the
/// bound for few samples, stays with tip 65.
#[test]
fn a_short_reflection_in_a_tips_gap_stays_out_of_the_tip() {
    let noise_mm = TrackingSettings::default().noise_mm;
    held_under_all(&[(227, noise_mm), (242, noise_mm), (185, noise_mm)]);
}
